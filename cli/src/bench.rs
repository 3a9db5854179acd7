//! The `hdrcodec bench` engine: every configuration of every codec on every image, measuring
//! size, quality and speed in one process.
//!
//! A [`Config`] is one row family of the table: a codec, the [`EncodeSettings`] it runs with
//! and a label (`"exr:piz-half"`). Each codec contributes its configurations in
//! [`configurations`] (one line per codec). Quality is measured with
//! [`hdrcodec_core::metrics::compare`] on the RGB channels (lossy codecs may drop alpha), speed
//! as the median wall time of a few runs, once on one thread and once on a pool of all threads
//! (both directions, labelled).
//!
//! Every codec sees the same samples: the image's colour is prepared for the codec once
//! ([`hdrcodec::prepare_colour`]), so a format without primaries stores the samples as they
//! are, reads them back unspecified, and is scored in the reference's primaries.
//!
//! JPEG XR has, beside our encoder's rows, peer rows of another kind ([`Encoder::Jxrlib`]):
//! jxrlib's `JxrEncApp` writes the file (an outside program, timed as such), our decoder reads it (quality and our decode speed, as in every row), and jxrlib's
//! `JxrDecApp` decoding the same file is the peer's decode speed and the check that our samples
//! equal jxrlib's. Without `JxrEncApp` on PATH those rows say "not installed".
//!
//! The gain-map JPEG has peer rows of the same kind ([`Encoder::Libultrahdr`]): libultrahdr 1.4
//! (through the reference venv's imagecodecs) writes the file, our decoder reads it.
//!
//! JPEG XL (`cjxl`/`djxl`), AVIF 10- and 12-bit PQ (`avifenc`/`avifdec`) and OpenEXR through
//! OpenImageIO (`oiiotool`) are peers of the same kind ([`Encoder::Cjxl`], [`Encoder::Avifenc`],
//! [`Encoder::Oiiotool`]; [`crate::peers`]): outside programs, "not installed" without them.

use crate::equal_quality;
use crate::jxrlib;
use crate::libultrahdr;
use crate::peers;
use crate::text_table::{Align, TextTable};
use hdrcodec::core::{metrics, Channels, DecodeOptions, EncodeSettings, HdrImage, ImageCodec, Limits, ThreadPool};
use hdrcodec::Registry;
use serde::Serialize;
use std::ffi::OsStr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// One codec with one set of settings: a row family of the bench table.
#[derive(Clone)]
pub struct Config {
    /// Row label, `codec:variant`.
    pub label: String,
    /// The codec.
    pub codec: Arc<dyn ImageCodec>,
    /// The settings it encodes with.
    pub settings: EncodeSettings,
    /// Who writes the files the rows decode.
    pub encoder: Encoder,
    /// The settings ask for lossless coding: its rows are not points of a rate-quality curve
    /// (even where the file differs from the input, e.g. by the rounding to half floats).
    pub lossless: bool,
}

/// Who writes the files a configuration's rows decode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoder {
    /// The codec's own encoder: encode, then decode, both timed on one thread and on the pool.
    Hdrcodec,
    /// jxrlib's `JxrEncApp` (Debian `libjxr-tools`), an outside program, with these options
    /// after `-i IN.tif -o OUT.jxr -c 12` (`-c 25` with alpha): the input goes in as scRGB half floats
    /// ([`jxrlib::scrgb_half_tiff`]). The encode speed is the wall time of the process (one
    /// thread; process start and TIFF reading included; no pool figure); the configuration's
    /// codec decodes the file; `JxrDecApp` decoding it is the peer.
    Jxrlib(&'static [&'static str]),
    /// libultrahdr 1.4's `ultrahdr_encode` (imagecodecs in the reference venv, an outside
    /// program) at this base quality, its other settings at the library's defaults; the input
    /// as linear half floats in SDR-white units. The encode speed is the wall time of the
    /// Python process (interpreter start included; no pool figure); the configuration's codec
    /// decodes the file; no peer decode (benches/ultrahdr_decode.rs times libultrahdr's).
    Libultrahdr(u8),
    /// libjxl's `cjxl` at this distance (`-d`; `"0"`: lossless) from linear PFM, `djxl` back to
    /// PFM ([`peers::jxl`]). Encode and decode speeds are the wall times of those processes
    /// (one thread; no pool figures); the configuration's codec (PFM) reads djxl's output.
    Cjxl(&'static str),
    /// libavif's `avifenc` at `depth` bits (10 or 12) and `quantizer` (0-63) from a 16-bit PQ
    /// PNG in BT.2020, `avifdec` back to a 16-bit PNG ([`peers::avif`]). Encode and decode
    /// speeds are the wall times of those processes (one thread; no pool figures).
    Avifenc {
        /// Bits per sample of the AV1 stream.
        depth: u8,
        /// `--min` and `--max` quantizer.
        quantizer: u8,
    },
    /// Intel ISPC's BC6H compressor (`intel_tex_2`, in process, behind the `ispc` cargo feature)
    /// at this profile ([`peers::ispc`]): the encode speed is its, with the padding and half
    /// conversion it needs (one thread; no pool figure); the configuration's codec (BC6H)
    /// decodes its DDS file.
    Ispc(&'static str),
    /// OpenImageIO's `oiiotool` re-writing the input (our uncompressed float EXR) with this
    /// OpenEXR compression and pixel type ([`peers::oiio`]): the encode speed is that process's
    /// wall time; the configuration's codec decodes the file; oiiotool decoding it is the peer.
    Oiiotool {
        /// OpenEXR's compression name.
        compression: &'static str,
        /// `half` or `float`.
        pixel: &'static str,
    },
}

impl Encoder {
    /// How a row names an encoder that is not ours.
    fn describe(self) -> Option<String> {
        match self {
            Encoder::Hdrcodec => None,
            Encoder::Jxrlib(_) => Some(format!("jxrlib {} (outside program)", jxrlib::ENCODER)),
            Encoder::Libultrahdr(_) => Some("libultrahdr 1.4 ultrahdr_encode (imagecodecs, outside program)".into()),
            Encoder::Ispc(profile) => Some(peers::ispc::describe(profile)),
            e => peers::describe(e).0,
        }
    }
}

/// The JPEG XR rows: a label suffix and JxrEncApp's options for each (no `-q`: lossless).
const JXRLIB_SETTINGS: [(&str, &[&str]); 8] = [
    ("lossless", &[]),
    ("q0.9", &["-q", "0.9"]),
    ("q0.8", &["-q", "0.8"]),
    ("q0.7", &["-q", "0.7"]),
    ("q0.6", &["-q", "0.6"]),
    ("q0.5", &["-q", "0.5"]),
    ("q0.4", &["-q", "0.4"]),
    ("q0.3", &["-q", "0.3"]),
];

/// The OpenEXR rows written by oiiotool: compression and pixel type.
const OIIOTOOL_SETTINGS: [(&str, &str); 6] =
    [("zip", "half"), ("piz", "half"), ("b44", "half"), ("dwaa", "half"), ("zip", "float"), ("piz", "float")];

/// Every configuration the bench runs, for the codecs present in `registry`. Each codec adds
/// its rows here, **one line per codec**.
pub fn configurations(registry: &Registry) -> Vec<Config> {
    let mut out = Vec::new();
    let mut add = |codec: &str, label: String, settings: EncodeSettings| {
        if let Ok(codec) = registry.by_name(codec) {
            let lossless = false;
            out.push(Config { label, codec, settings, encoder: Encoder::Hdrcodec, lossless });
        }
    };
    let opts = |kv: &[(&str, &str)]| kv.iter().fold(EncodeSettings::default(), |s, (k, v)| s.with_option(*k, *v));
    // OpenEXR baselines: every compression the codec writes, half and float samples.
    for c in hdrcodec::exr::ExrCompression::ALL.map(|c| c.name()) {
        for p in ["half", "float"] {
            add("exr", format!("exr:{c}-{p}"), opts(&[("compression", c), ("pixel", p)]));
        }
    }
    add("rgbe", "rgbe".into(), EncodeSettings::default());
    add("rgbe", "rgbe:truncate".into(), opts(&[("rounding", "truncate")]));
    add("logluv32", "logluv32".into(), EncodeSettings::default());
    add("logluv24", "logluv24".into(), EncodeSettings::default());
    // BC6H at its fast efforts: the thorough ones take minutes per megapixel and belong in
    // `cargo bench -p hdrcodec-tests --bench bc6h_encode`.
    for effort in [0, 2] {
        add("bc6h", format!("bc6h:effort{effort}"), EncodeSettings::default().with_effort(effort));
    }
    // Gain-map JPEG at three qualities of its base (the map's quality and scale at their
    // defaults).
    for q in [95, 85, 70, 50] {
        add("ultrahdr", format!("ultrahdr:q{q}"), EncodeSettings::default().with_quality(q));
    }
    // Ward & Simmons' JPEG-HDR beside it: the same base qualities (ratio image at its
    // defaults: half size, pre-corrected), and post-correction at q85.
    for q in [95, 85, 70] {
        add("jpeg-hdr", format!("jpeg-hdr:q{q}"), EncodeSettings::default().with_quality(q));
    }
    add("jpeg-hdr", "jpeg-hdr:q85-post".into(), opts(&[("correction", "post")]).with_quality(85));
    // Uncompressed half floats in the container: the size every lossy codec should beat.
    add("hdrc", "hdrc:raw-f16".into(), opts(&[("payload", "raw-f16")]));
    // Intel ISPC's BC6H encoder as the peer of the `bc6h:` rows (see `Encoder::Ispc`).
    if let Ok(codec) = registry.by_name("bc6h") {
        for profile in peers::ispc::PROFILES {
            let (label, settings) = (format!("bc6h(ispc):{profile}"), EncodeSettings::default());
            out.push(Config {
                label,
                codec: codec.clone(),
                settings,
                encoder: Encoder::Ispc(profile),
                lossless: false,
            });
        }
    }
    // libultrahdr's gain-map JPEG encoder as the peer of the `ultrahdr:` rows (see `Encoder::Libultrahdr`).
    if let Ok(codec) = registry.by_name("ultrahdr") {
        for q in [95, 85, 70, 50] {
            let (label, settings) = (format!("ultrahdr(libultrahdr):q{q}"), EncodeSettings::default());
            out.push(Config {
                label,
                codec: codec.clone(),
                settings,
                encoder: Encoder::Libultrahdr(q),
                lossless: false,
            });
        }
    }
    // JPEG XR: ours at a sweep of qualities (half samples), and jxrlib's encoder as the peer
    // (see `Encoder::Jxrlib`).
    if let Ok(codec) = registry.by_name("jxr") {
        for q in [100, 90, 70, 50, 30, 10] {
            let (label, settings) = (format!("jxr:q{q}"), EncodeSettings::default().with_quality(q));
            out.push(Config { label, codec: codec.clone(), settings, encoder: Encoder::Hdrcodec, lossless: q == 100 });
        }
        for (variant, args) in JXRLIB_SETTINGS {
            let (label, settings) = (format!("jxr(jxrlib-enc):{variant}"), EncodeSettings::default());
            let (encoder, lossless) = (Encoder::Jxrlib(args), args.is_empty());
            out.push(Config { label, codec: codec.clone(), settings, encoder, lossless });
        }
    }
    // Outside peers that are not formats of the family (see `crate::peers`): JPEG XL (lossless
    // and a sweep of distances; our PFM decoder reads djxl's output) and AVIF PQ at 10 and 12
    // bits (a sweep of quantizers).
    if let Ok(codec) = registry.by_name("pfm") {
        for d in ["0", "0.1", "0.25", "0.5", "1", "2", "4"] {
            let label = if d == "0" { "jxl(cjxl):lossless".to_string() } else { format!("jxl(cjxl):d{d}") };
            let (encoder, lossless, settings) = (Encoder::Cjxl(d), d == "0", EncodeSettings::default());
            out.push(Config { label, codec: codec.clone(), settings, encoder, lossless });
        }
        for (depth, quantizer) in [10, 12].into_iter().flat_map(|d| [2, 10, 20, 30, 40].map(|q| (d, q))) {
            let (label, settings) = (format!("avif(avifenc):{depth}bit-qp{quantizer}"), EncodeSettings::default());
            let encoder = Encoder::Avifenc { depth, quantizer };
            out.push(Config { label, codec: codec.clone(), settings, encoder, lossless: false });
        }
    }
    // OpenEXR written by OpenImageIO (OpenEXR's C++ library) as the peer of the `exr:` rows.
    if let Ok(codec) = registry.by_name("exr") {
        for (compression, pixel) in OIIOTOOL_SETTINGS {
            let (label, settings) = (format!("exr(oiiotool):{compression}-{pixel}"), EncodeSettings::default());
            let encoder = Encoder::Oiiotool { compression, pixel };
            let lossless = ["zip", "piz"].contains(&compression);
            out.push(Config { label, codec: codec.clone(), settings, encoder, lossless });
        }
    }
    out
}

/// An image to benchmark on.
#[derive(Clone, Debug)]
pub struct Input {
    /// Scene name or file name.
    pub name: String,
    /// The pixels.
    pub image: HdrImage,
}

/// The generated corpus as bench inputs.
pub fn generated_inputs() -> Vec<Input> {
    crate::corpus::scenes().into_iter().map(|s| Input { name: s.name.to_string(), image: s.image }).collect()
}

/// A file under a bench directory that could not be used, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    /// The file name.
    pub file: String,
    /// Why it was skipped.
    pub reason: String,
}

/// The images of `paths`: each a file, or a directory whose files (and its subdirectories', a
/// few levels deep) are taken in path order. Every file that some codec of `registry` decodes
/// is an input; files in a directory without a known extension or magic number are ignored,
/// a file named on its own that no codec knows, and files that fail to decode, are listed as
/// skipped. Names are relative to their directory (a file named on its own: its file name).
pub fn path_inputs(
    paths: &[std::path::PathBuf],
    registry: &Registry,
    limits: &Limits,
) -> hdrcodec::core::Result<(Vec<Input>, Vec<Skipped>)> {
    let (mut inputs, mut skipped) = (Vec::new(), Vec::new());
    for path in paths {
        let io_error = |e: std::io::Error| {
            hdrcodec::core::Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))
        };
        let (files, named) = if path.is_dir() {
            let mut files = Vec::new();
            collect_files(path, 4, &mut files).map_err(io_error)?;
            files.sort();
            (files, false)
        } else {
            std::fs::metadata(path).map_err(io_error)?;
            (vec![path.clone()], true)
        };
        for p in files {
            let file = if named {
                p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
            } else {
                p.strip_prefix(path).unwrap_or(&p).to_string_lossy().into_owned()
            };
            let data = match hdrcodec::read_file(&p) {
                Ok(d) => d,
                Err(e) => {
                    skipped.push(Skipped { file, reason: e.to_string() });
                    continue;
                }
            };
            match registry.for_input(&p, &data) {
                // In a directory, not an image format we know (MANIFEST, README, ...): not
                // worth a mention; named on its own, it is.
                Err(e) if named => skipped.push(Skipped { file, reason: e.to_string() }),
                Err(_) => continue,
                Ok(codec) => match codec.decode(&data, limits) {
                    Ok(image) => inputs.push(Input { name: file, image }),
                    Err(e) => skipped.push(Skipped { file, reason: e.to_string() }),
                },
            }
        }
    }
    Ok((inputs, skipped))
}

/// Appends the files under `dir` to `out`, descending at most `depth` more levels.
fn collect_files(dir: &Path, depth: usize, out: &mut Vec<std::path::PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            if depth > 0 {
                collect_files(&path, depth - 1, out)?;
            }
        } else if path.is_file() {
            out.push(path);
        }
    }
    Ok(())
}

/// One configuration on one image.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// The configuration label.
    pub config: String,
    /// The image name.
    pub image: String,
    /// Pixels in the image.
    pub pixels: usize,
    /// Encoded size in bytes.
    pub bytes: usize,
    /// Bits per pixel.
    pub bpp: f64,
    /// True if the decoded RGB equals the input exactly.
    pub identical: bool,
    /// The configuration asks for lossless coding ([`Config::lossless`]).
    pub lossless: bool,
    /// PU21-PSNR of the luminance, dB (infinite, `null` in JSON, when identical).
    pub pu21_psnr: f64,
    /// Mean ΔE ITP (BT.2124).
    pub de_itp_mean: f64,
    /// Root mean square of log2((test + 1) / (reference + 1)) over the RGB samples.
    pub log_rmse: f64,
    /// Encode speed on one thread, megapixels per second (median run); for a file written by
    /// an outside program (`encoder`), the wall time of that process.
    pub encode_mps: f64,
    /// Decode speed on one thread, megapixels per second (median run).
    pub decode_mps: f64,
    /// Encode speed on the report's pool of `threads` threads (`null` in JSON for an outside
    /// encoder).
    pub encode_mps_all: f64,
    /// Decode speed on the report's pool of `threads` threads.
    pub decode_mps_all: f64,
    /// The encoder, when it is not our codec's (then the encode speeds are that program's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder: Option<String>,
    /// The decoder, when it is not our codec's (JPEG XL, AVIF: then the decode speeds are that
    /// program's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decoder: Option<String>,
    /// The peer's decode of the same file, if the row has one (JPEG XR: jxrlib's JxrDecApp).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer: Option<PeerDecode>,
    /// What the codec or the colour preparation said (a format without primaries, clipping).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Why this configuration failed on this image, if it did (then the numbers are zero).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl Row {
    /// A row of `config` on `image` with nothing measured yet (zeros, no notes, no error).
    pub(crate) fn blank(config: String, image: String, pixels: usize, lossless: bool) -> Row {
        Row {
            config,
            image,
            pixels,
            bytes: 0,
            bpp: 0.0,
            identical: false,
            lossless,
            pu21_psnr: 0.0,
            de_itp_mean: 0.0,
            log_rmse: 0.0,
            encode_mps: 0.0,
            decode_mps: 0.0,
            encode_mps_all: 0.0,
            decode_mps_all: 0.0,
            encoder: None,
            decoder: None,
            peer: None,
            notes: Vec::new(),
            error: None,
        }
    }

    /// The file's size and its quality against the input.
    pub(crate) fn set_size_and_quality(&mut self, bytes: usize, pixels: usize, cmp: &metrics::Comparison) {
        self.bytes = bytes;
        self.bpp = bytes as f64 * 8.0 / pixels as f64;
        // A file in other units than the input (JPEG XR's scRGB: 80 nits per unit) that
        // decodes to the same light (every sample equal once in the input's units: zero
        // squared error) is lossless too.
        self.identical = cmp.identical || cmp.psnr.is_infinite();
        self.pu21_psnr = cmp.pu21_psnr;
        self.de_itp_mean = cmp.de_itp_mean;
        self.log_rmse = cmp.log_rmse;
    }
}

/// A peer decoding the same file as our decoder.
#[derive(Clone, Debug, Serialize)]
pub struct PeerDecode {
    /// Who: "jxrlib JxrDecApp (outside program)".
    pub decoder: String,
    /// Its decode speed, megapixels per second (median run; for an outside program its wall
    /// time, process start and output file included).
    pub decode_mps: f64,
    /// Whether our decoded samples equal the peer's, byte for byte (`false` is a bug of ours).
    pub matches: bool,
}

/// A peer's figures over a configuration's images.
#[derive(Clone, Debug, Serialize)]
pub struct PeerSummary {
    /// Total pixels over total median decode time of the peer.
    pub decode_mps: f64,
    /// Images whose decoded samples differ from the peer's (should always be 0).
    pub mismatches: usize,
}

/// A configuration's figures over all images it could encode.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The configuration label.
    pub config: String,
    /// Images encoded without error.
    pub images: usize,
    /// Images that failed.
    pub failed: usize,
    /// Images decoded bit-identical (RGB).
    pub identical_images: usize,
    /// Total encoded bytes.
    pub bytes: usize,
    /// Total bits over total pixels.
    pub bpp: f64,
    /// Mean PU21-PSNR over the images that are not identical (infinite when all are).
    pub pu21_psnr: f64,
    /// Mean of the per-image mean ΔE ITP.
    pub de_itp_mean: f64,
    /// Mean of the per-image log-RMSE.
    pub log_rmse: f64,
    /// Total pixels over total median encode time.
    pub encode_mps: f64,
    /// Total pixels over total median decode time.
    pub decode_mps: f64,
    /// Total pixels over total median encode time, on all threads.
    pub encode_mps_all: f64,
    /// Total pixels over total median decode time, on all threads.
    pub decode_mps_all: f64,
    /// The encoder, when it is not our codec's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder: Option<String>,
    /// The decoder, when it is not our codec's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decoder: Option<String>,
    /// The peer's figures over the rows that have one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer: Option<PeerSummary>,
    /// Why the configuration could not run at all ("not installed: ..."), if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unavailable: Option<String>,
}

/// Everything one bench run measured.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Where the images came from: "generated corpus" or the directory.
    pub source: String,
    /// Timed runs per measurement, at most (the median is reported; a measurement whose runs
    /// have taken 2 s starts no further run).
    pub runs: usize,
    /// Threads of the pool behind the `*_all` speeds.
    pub threads: usize,
    /// One row per configuration and image.
    pub rows: Vec<Row>,
    /// One line per configuration.
    pub summary: Vec<Summary>,
    /// Directory files that were not used.
    pub skipped: Vec<Skipped>,
    /// Bytes at equal PU21-PSNR between families of configurations
    /// ([`equal_quality::COMPARISONS`] whose two sides ran).
    pub equal_quality: Vec<equal_quality::Comparison>,
    /// The HDR10 AV1 rows (`bench --video`; [`crate::video_bench`]), empty otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub video: Vec<crate::video_bench::VideoRow>,
    /// Peak memory of decoding the largest image, per codec (`bench --memory`, `--report`;
    /// [`crate::memory`]), empty otherwise.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub memory: Vec<crate::memory::MemoryRow>,
}

/// Once the runs of one measurement have taken this long, no further run is started: slow
/// configurations (a thorough encoder search) are timed once or twice instead of `runs` times.
const TIME_BUDGET: Duration = Duration::from_secs(2);

/// The median of up to `runs` timings of `f` (which must succeed every time; at least one run,
/// fewer than `runs` once [`TIME_BUDGET`] is spent), and its last result.
pub(crate) fn timed<T>(
    runs: usize,
    mut f: impl FnMut() -> hdrcodec::core::Result<T>,
) -> hdrcodec::core::Result<(Duration, T)> {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    let start = Instant::now();
    for _ in 0..runs.max(1) {
        if !times.is_empty() && start.elapsed() > TIME_BUDGET {
            break;
        }
        let t = Instant::now();
        let out = f()?;
        times.push(t.elapsed());
        last = Some(out);
    }
    times.sort();
    Ok((times[times.len() / 2], last.expect("at least one run")))
}

pub(crate) fn mps(pixels: usize, t: Duration) -> f64 {
    pixels as f64 / 1e6 / t.as_secs_f64().max(1e-9)
}

/// Runs one configuration on one image, timing it on one thread and on `pool`.
/// What the peers' rows make of one image before their tools run (the files the tools read,
/// the reference they are scored against), made by the first configuration that needs it and
/// shared by the others: each kind once per image, not once per configuration.
#[derive(Default)]
pub(crate) struct Prepared {
    items: std::cell::RefCell<std::collections::HashMap<&'static str, std::rc::Rc<dyn std::any::Any>>>,
}

impl Prepared {
    /// The item `key` (of type `T`), made by `make` the first time it is asked for.
    pub(crate) fn get<T: 'static>(
        &self,
        key: &'static str,
        make: impl FnOnce() -> hdrcodec::core::Result<T>,
    ) -> hdrcodec::core::Result<std::rc::Rc<T>> {
        let held = self.items.borrow().get(key).cloned();
        if let Some(item) = held.and_then(|item| item.downcast::<T>().ok()) {
            return Ok(item);
        }
        let item = std::rc::Rc::new(make()?);
        self.items.borrow_mut().insert(key, item.clone());
        Ok(item)
    }
}

fn measure(config: &Config, input: &Input, runs: usize, pool: &ThreadPool, prepared: &Prepared) -> Row {
    let pixels = input.image.pixel_count();
    let mut row = Row::blank(config.label.clone(), input.name.clone(), pixels, config.lossless);
    row.encoder = config.encoder.describe();
    if peers::handles(config.encoder) {
        row.decoder = peers::describe(config.encoder).1;
        peers::measure(config, input, runs, pool, prepared, &mut row);
        return row;
    }
    if let Encoder::Jxrlib(args) = config.encoder {
        match jxrlib::tool(jxrlib::ENCODER) {
            None => {
                row.error = Some(format!("{NOT_INSTALLED}: {} ({}) is not on PATH", jxrlib::ENCODER, jxrlib::PACKAGE))
            }
            Some(enc) => {
                if let Err(e) = measure_jxrlib(config, &enc, args, input, runs, pool, prepared, &mut row) {
                    row.error = Some(e.to_string());
                }
            }
        }
        return row;
    }
    if let Encoder::Ispc(profile) = config.encoder {
        if !peers::ispc::available() {
            row.error = Some(format!(
                "{NOT_INSTALLED}: this build has no Intel ISPC (cargo feature `{}`: intel_tex_2)",
                peers::ispc::FEATURE
            ));
        } else {
            measure_ispc(config, profile, input, runs, pool, &mut row);
        }
        return row;
    }
    if let Encoder::Libultrahdr(quality) = config.encoder {
        match libultrahdr::python() {
            None => row.error = Some(format!("{NOT_INSTALLED}: {}", libultrahdr::PACKAGE)),
            Some(python) => {
                if let Err(e) = measure_libultrahdr(config, &python, quality, input, runs, pool, prepared, &mut row) {
                    row.error = Some(e.to_string());
                }
            }
        }
        return row;
    }
    let result = (|| -> hdrcodec::core::Result<()> {
        // The colour is prepared once, as `convert` does; only the codec is timed.
        let prepared = hdrcodec::prepare_colour(config.codec.as_ref(), &input.image, &config.settings)?;
        let codec = config.codec.as_ref();
        let one = prepared.settings.clone().with_pool(ThreadPool::single());
        let all = prepared.settings.clone().with_pool(pool.clone());
        let mut notes = prepared.notes.clone();
        let (enc_t, bytes) = timed(runs, || {
            let mut out = Vec::new();
            let report = codec.encode_to(&prepared.image, &one, &mut out)?;
            for n in report.notes {
                if !notes.contains(&n) {
                    notes.push(n);
                }
            }
            Ok(out)
        })?;
        let (enc_all_t, _) = timed(runs, || codec.encode(&prepared.image, &all))?;
        let dec_one = DecodeOptions::new(Limits::default());
        let dec_all = DecodeOptions::new(Limits::default()).with_pool(pool.clone());
        let (dec_t, decoded) = timed(runs, || codec.decode_with(&bytes, &dec_one))?;
        let (dec_all_t, _) = timed(runs, || codec.decode_with(&bytes, &dec_all))?;
        // Lossy codecs may drop alpha: quality is always measured on RGB.
        let cmp = metrics::compare(&input.image.with_channels(Channels::Rgb), &decoded.with_channels(Channels::Rgb))?;
        row.set_size_and_quality(bytes.len(), pixels, &cmp);
        row.encode_mps = mps(pixels, enc_t);
        row.decode_mps = mps(pixels, dec_t);
        row.encode_mps_all = mps(pixels, enc_all_t);
        row.decode_mps_all = mps(pixels, dec_all_t);
        row.notes = notes;
        Ok(())
    })();
    if let Err(e) = result {
        row.error = Some(e.to_string());
    }
    row
}

/// jxrlib's JxrDecApp (`dec`) decodes `jxr` (whose bytes are `bytes`) into the TIFF `out`:
/// its median wall time over `runs`, and whether its samples equal ours byte for byte.
fn peer_decode(
    dec: &Path,
    jxr: &Path,
    out: &Path,
    bytes: &[u8],
    runs: usize,
    pixels: usize,
) -> hdrcodec::core::Result<PeerDecode> {
    let args = ["-i".as_ref(), jxr.as_os_str(), "-o".as_ref(), out.as_os_str()];
    let (t, _) = timed(runs, || jxrlib::run(dec, &args, out))?;
    let theirs = jxrlib::tiff_samples(&std::fs::read(out)?)?;
    let ours = hdrcodec::jxr::decode_raw(bytes, &DecodeOptions::new(Limits::default()))?;
    Ok(PeerDecode {
        decoder: format!("jxrlib {} (outside program)", jxrlib::DECODER),
        decode_mps: mps(pixels, t),
        matches: theirs == ours,
    })
}

/// How a row whose encoder program is missing starts its error.
pub(crate) const NOT_INSTALLED: &str = "not installed";

/// A JPEG XR row ([`Encoder::Jxrlib`]): JxrEncApp (`enc`, with `args`) writes the input as a
/// `.jxr` file in a temporary directory (removed on return, also on failure); our codec decodes
/// it (quality, speed on one thread and on `pool`); JxrDecApp, if installed, decodes it too
/// (the peer's speed and the check that its samples equal ours).
#[allow(clippy::too_many_arguments)]
fn measure_jxrlib(
    config: &Config,
    enc: &Path,
    args: &[&str],
    input: &Input,
    runs: usize,
    pool: &ThreadPool,
    prepared: &Prepared,
    row: &mut Row,
) -> hdrcodec::core::Result<()> {
    let pixels = row.pixels;
    let dir = jxrlib::TempDir::new("bench-jxr")?;
    let (tif, jxr, peer_tif) = (dir.path().join("in.tif"), dir.path().join("out.jxr"), dir.path().join("jxrlib.tif"));
    let tiff_and_clipped = prepared.get("jxrlib", || jxrlib::scrgb_half_tiff(&input.image))?;
    let (tiff, clipped) = (&tiff_and_clipped.0, tiff_and_clipped.1);
    std::fs::write(&tif, tiff)?;
    let mut notes = Vec::new();
    if clipped > 0 {
        notes.push(format!(
            "{} on {}: {clipped} samples beyond half's ±65504 (or NaN) clipped in {}'s input",
            config.label,
            input.name,
            jxrlib::ENCODER
        ));
    }
    let mut enc_args: Vec<&OsStr> = ["-i".as_ref(), tif.as_os_str(), "-o".as_ref(), jxr.as_os_str()].into();
    // 48bppRGBHalf, or 64bppRGBAHalf with planar alpha (lossless by default, as ours).
    let format = if input.image.channels() == Channels::Rgba { "25" } else { "12" };
    let format_args = ["-c", format];
    enc_args.extend(format_args.iter().chain(args).map(OsStr::new));
    let (enc_t, _) = timed(runs, || jxrlib::run(enc, &enc_args, &jxr))?;
    let bytes = std::fs::read(&jxr)?;
    decode_peer_file(config, &bytes, input, runs, pool, enc_t, row)?;
    match jxrlib::tool(jxrlib::DECODER) {
        None => notes.push(format!(
            "{} ({}) is not installed: the JPEG XR rows have no peer decode",
            jxrlib::DECODER,
            jxrlib::PACKAGE
        )),
        // A failing peer is said in a note; our figures stand.
        Some(dec) => match peer_decode(&dec, &jxr, &peer_tif, &bytes, runs, pixels) {
            Ok(peer) => {
                if !peer.matches {
                    notes.push(format!(
                        "{} on {}: our samples DIFFER from {}'s (a bug of ours)",
                        config.label,
                        input.name,
                        jxrlib::DECODER
                    ));
                }
                row.peer = Some(peer);
            }
            Err(e) => notes.push(format!("{} on {}: no peer decode: {e}", config.label, input.name)),
        },
    }
    row.notes = notes;
    Ok(())
}

/// Our decoder (`config`'s codec) on `bytes`, a file an outside encoder wrote in `enc_t`: the
/// row's size, quality against the input, and speeds (the encoder's on one thread only).
pub(crate) fn decode_peer_file(
    config: &Config,
    bytes: &[u8],
    input: &Input,
    runs: usize,
    pool: &ThreadPool,
    enc_t: Duration,
    row: &mut Row,
) -> hdrcodec::core::Result<()> {
    let codec = config.codec.as_ref();
    let dec_one = DecodeOptions::new(Limits::default());
    let dec_all = DecodeOptions::new(Limits::default()).with_pool(pool.clone());
    let (dec_t, decoded) = timed(runs, || codec.decode_with(bytes, &dec_one))?;
    let (dec_all_t, _) = timed(runs, || codec.decode_with(bytes, &dec_all))?;
    let cmp = metrics::compare(&input.image.with_channels(Channels::Rgb), &decoded.with_channels(Channels::Rgb))?;
    row.set_size_and_quality(bytes.len(), row.pixels, &cmp);
    row.encode_mps = mps(row.pixels, enc_t);
    row.decode_mps = mps(row.pixels, dec_t);
    // The outside encoders run on one thread: there is no pool figure.
    row.encode_mps_all = f64::NAN;
    row.decode_mps_all = mps(row.pixels, dec_all_t);
    Ok(())
}

/// A gain-map JPEG row written by libultrahdr ([`Encoder::Libultrahdr`]): the input, its colour
/// prepared as for our encoder (BT.709 or Display P3), goes to `python`'s imagecodecs as linear
/// half floats; our decoder reads the file.
#[allow(clippy::too_many_arguments)]
fn measure_libultrahdr(
    config: &Config,
    python: &Path,
    quality: u8,
    input: &Input,
    runs: usize,
    pool: &ThreadPool,
    cache: &Prepared,
    row: &mut Row,
) -> hdrcodec::core::Result<()> {
    // The rows differ by quality only: the colour and the half-float input are the same.
    let made = cache.get("libultrahdr", || {
        let prepared = hdrcodec::prepare_colour(config.codec.as_ref(), &input.image, &config.settings)?;
        let gamut = libultrahdr::gamut(prepared.image.color.primaries)?;
        let (rgba, clipped) = libultrahdr::linear_half_rgba(&prepared.image);
        Ok((gamut, rgba, clipped, prepared.notes))
    })?;
    let (gamut, rgba, clipped) = (made.0, &made.1, made.2);
    let mut notes = made.3.clone();
    if clipped > 0 {
        notes.push(format!(
            "{} on {}: {clipped} negative, NaN or beyond-half samples clipped in libultrahdr's input",
            config.label, input.name
        ));
    }
    let dir = jxrlib::TempDir::new("bench-uhdr")?;
    let (w, h) = (input.image.width(), input.image.height());
    let (enc_t, bytes) = timed(runs, || libultrahdr::encode(python, &dir, rgba, w, h, quality, gamut))?;
    decode_peer_file(config, &bytes, input, runs, pool, enc_t, row)?;
    row.notes = notes;
    Ok(())
}

/// A BC6H row written by ISPC ([`Encoder::Ispc`]): the input, its colour prepared as for our
/// encoder, compressed at `profile`; our decoder reads the DDS file. A failure is the row's error.
fn measure_ispc(config: &Config, profile: &str, input: &Input, runs: usize, pool: &ThreadPool, row: &mut Row) {
    let ispc = |row: &mut Row| -> hdrcodec::core::Result<()> {
        let prepared = hdrcodec::prepare_colour(config.codec.as_ref(), &input.image, &config.settings)?;
        let (enc_t, (bytes, clipped)) = timed(runs, || peers::ispc::encode_dds(&prepared.image, profile))?;
        decode_peer_file(config, &bytes, input, runs, pool, enc_t, row)?;
        row.notes = prepared.notes.clone();
        if clipped > 0 {
            let (label, image) = (&config.label, &input.name);
            row.notes
                .push(format!("{label} on {image}: {clipped} samples beyond half's 65504 clamped in ISPC's input"));
        }
        Ok(())
    };
    if let Err(e) = ispc(row) {
        row.error = Some(e.to_string());
    }
}

fn summarize(label: &str, rows: &[&Row]) -> Summary {
    let ok: Vec<&&Row> = rows.iter().filter(|r| r.error.is_none()).collect();
    let pixels: usize = ok.iter().map(|r| r.pixels).sum();
    let bytes: usize = ok.iter().map(|r| r.bytes).sum();
    let mean = |f: &dyn Fn(&Row) -> f64, rs: &[&&Row]| rs.iter().map(|r| f(r)).sum::<f64>() / rs.len().max(1) as f64;
    let lossy: Vec<&&Row> = ok.iter().copied().filter(|r| !r.identical).collect();
    let secs = |f: &dyn Fn(&Row) -> f64| ok.iter().map(|r| r.pixels as f64 / 1e6 / f(r).max(1e-12)).sum::<f64>();
    // A speed no row has (an outside encoder's pool figure, NaN) stays NaN: `-`, `null`.
    let speed = |f: &dyn Fn(&Row) -> f64| {
        if ok.iter().any(|r| f(r).is_nan()) {
            f64::NAN
        } else {
            pixels as f64 / 1e6 / secs(f).max(1e-12)
        }
    };
    Summary {
        config: label.to_string(),
        images: ok.len(),
        failed: rows.len() - ok.len(),
        identical_images: ok.len() - lossy.len(),
        bytes,
        bpp: bytes as f64 * 8.0 / pixels.max(1) as f64,
        pu21_psnr: if lossy.is_empty() { f64::INFINITY } else { mean(&|r| r.pu21_psnr, &lossy) },
        de_itp_mean: mean(&|r| r.de_itp_mean, &ok),
        log_rmse: mean(&|r| r.log_rmse, &ok),
        encode_mps: speed(&|r| r.encode_mps),
        decode_mps: speed(&|r| r.decode_mps),
        encode_mps_all: speed(&|r| r.encode_mps_all),
        decode_mps_all: speed(&|r| r.decode_mps_all),
        encoder: rows.first().and_then(|r| r.encoder.clone()),
        decoder: rows.first().and_then(|r| r.decoder.clone()),
        peer: peer_summary(&ok),
        unavailable: rows
            .first()
            .and_then(|r| r.error.clone())
            .filter(|e| e.starts_with(NOT_INSTALLED) && rows.iter().all(|r| r.error.as_deref() == Some(e.as_str()))),
    }
}

/// The peer's figures over the rows that have one.
fn peer_summary(rows: &[&&Row]) -> Option<PeerSummary> {
    let peers: Vec<(usize, &PeerDecode)> = rows.iter().filter_map(|r| Some((r.pixels, r.peer.as_ref()?))).collect();
    if peers.is_empty() {
        return None;
    }
    let pixels: usize = peers.iter().map(|p| p.0).sum();
    let secs: f64 = peers.iter().map(|&(n, p)| n as f64 / 1e6 / p.decode_mps.max(1e-12)).sum();
    Some(PeerSummary {
        decode_mps: pixels as f64 / 1e6 / secs.max(1e-12),
        mismatches: peers.iter().filter(|p| !p.1.matches).count(),
    })
}

/// Runs every configuration on every input, `runs` timed runs each on one thread and on `pool`,
/// calling `progress` after each (configuration, image) pair with the number done and the total.
pub fn run(
    configs: &[Config],
    inputs: &[Input],
    runs: usize,
    pool: &ThreadPool,
    source: &str,
    skipped: Vec<Skipped>,
    mut progress: impl FnMut(usize, usize, &str),
) -> Report {
    let total = configs.len() * inputs.len();
    // Image by image, so that what the peers make of an image (their input files) is made once
    // and shared by their configurations; the rows are kept configuration by configuration.
    let mut slots: Vec<Option<Row>> = (0..total).map(|_| None).collect();
    let mut done = 0;
    for (k, i) in inputs.iter().enumerate() {
        let prepared = Prepared::default();
        for (j, c) in configs.iter().enumerate() {
            slots[j * inputs.len() + k] = Some(measure(c, i, runs, pool, &prepared));
            done += 1;
            progress(done, total, &c.label);
        }
    }
    let rows: Vec<Row> = slots.into_iter().flatten().collect();
    let summary = configs
        .iter()
        .map(|c| summarize(&c.label, &rows.iter().filter(|r| r.config == c.label).collect::<Vec<_>>()))
        .collect();
    let equal_quality = equal_quality::comparisons(&rows);
    let (video, memory) = (Vec::new(), Vec::new());
    Report {
        source: source.to_string(),
        runs,
        threads: pool.threads(),
        rows,
        summary,
        skipped,
        equal_quality,
        video,
        memory,
    }
}

fn fmt_db(v: f64) -> String {
    if v.is_infinite() {
        "lossless".to_string()
    } else {
        format!("{v:.2}")
    }
}

/// A speed column: `-` where there is no figure (an outside encoder's pool speed, no peer).
fn fmt_mps(v: Option<f64>) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v:.1}"),
        _ => "-".to_string(),
    }
}

/// The marker after a line whose decoded samples differ from the peer's.
const DIFFERS: &str = "  DIFFERS FROM PEER";

/// A table whose first columns are `first`, then sizes, quality, our speeds (one thread, then
/// all threads of the report's pool) and the peer's decode speed.
fn bench_table(report: &Report, first: &[(&str, Align)]) -> TextTable {
    let n = report.threads;
    let (enc, dec) = (format!("enc {n}T"), format!("dec {n}T"));
    let figures = ["bytes", "bpp", "PU21-PSNR", "dE-ITP", "log-RMSE", "enc 1T", "dec 1T", &enc, &dec, "peer dec"];
    let columns: Vec<(&str, Align)> = first.iter().copied().chain(figures.iter().map(|h| (*h, Align::Right))).collect();
    TextTable::new(&columns)
}

/// The figures of one line, in the order of [`bench_table`]'s columns after the first ones.
#[allow(clippy::too_many_arguments)]
fn figures(bytes: usize, bpp: f64, psnr: &str, de: f64, log: f64, speeds: [f64; 4], peer: Option<f64>) -> Vec<String> {
    let [e1, d1, en, dn] = speeds.map(|v| fmt_mps(Some(v)));
    vec![
        bytes.to_string(),
        format!("{bpp:.3}"),
        psnr.to_string(),
        format!("{de:.4}"),
        format!("{log:.5}"),
        e1,
        d1,
        en,
        dn,
        fmt_mps(peer),
    ]
}

/// One line per (configuration, image): the `--per-image` table.
pub fn per_image_table(report: &Report) -> String {
    let mut t = bench_table(report, &[("config", Align::Left), ("image", Align::Left)]);
    for r in report.rows.iter().filter(|r| r.error.is_none()) {
        let psnr = if r.identical { "lossless".to_string() } else { fmt_db(r.pu21_psnr) };
        let speeds = [r.encode_mps, r.decode_mps, r.encode_mps_all, r.decode_mps_all];
        let peer = r.peer.as_ref().map(|p| p.decode_mps);
        let cells = [r.config.clone(), r.image.clone()].into_iter();
        let cells = cells.chain(figures(r.bytes, r.bpp, &psnr, r.de_itp_mean, r.log_rmse, speeds, peer)).collect();
        let mark = if r.peer.as_ref().is_some_and(|p| !p.matches) { DIFFERS } else { "" };
        t.row(cells, mark);
    }
    let mut s = t.render();
    s.push('\n');
    s
}

/// The report as a plain-text table, one line per configuration.
pub fn table(report: &Report) -> String {
    let mut t = bench_table(report, &[("config", Align::Left), ("images", Align::Right)]);
    for r in &report.summary {
        if let Some(why) = &r.unavailable {
            t.note_row(vec![r.config.clone()], why);
            continue;
        }
        let images = if r.failed > 0 { format!("{}/{}", r.images, r.images + r.failed) } else { r.images.to_string() };
        let speeds = [r.encode_mps, r.decode_mps, r.encode_mps_all, r.decode_mps_all];
        let peer = r.peer.as_ref().map(|p| p.decode_mps);
        let line = figures(r.bytes, r.bpp, &fmt_db(r.pu21_psnr), r.de_itp_mean, r.log_rmse, speeds, peer);
        let mark = if r.peer.as_ref().is_some_and(|p| p.mismatches > 0) { DIFFERS } else { "" };
        t.row([r.config.clone(), images].into_iter().chain(line).collect(), mark);
    }
    let mut s = t.render();
    let unavailable = |label: &str| report.summary.iter().any(|r| r.config == label && r.unavailable.is_some());
    for r in report.rows.iter().filter(|r| r.error.is_some() && !unavailable(&r.config)) {
        s.push_str(&format!("{} on {}: {}\n", r.config, r.image, r.error.as_deref().unwrap_or("")));
    }
    let mut seen = Vec::new();
    for r in &report.rows {
        for n in &r.notes {
            if !seen.contains(&n) {
                s.push_str(&format!("note: {n}\n"));
                seen.push(n);
            }
        }
    }
    s.push_str(&format!(
        "speeds in MP/s: 1T on one thread, {}T on a pool of {} threads (--threads)\n",
        report.threads, report.threads
    ));
    if report.rows.iter().any(|r| r.config.starts_with("ultrahdr(libultrahdr)")) {
        s.push_str(
            "ultrahdr(libultrahdr) rows: libultrahdr 1.4's ultrahdr_encode (imagecodecs, Python) writes the file at the labelled \
             base quality,\n  the rest at the library's defaults; enc 1T is the wall time of that process (interpreter start \
             included), enc all '-';\n  bytes, quality and dec are our decoder on libultrahdr's file\n",
        );
    }
    if report.rows.iter().any(|r| r.config.starts_with("jxr(jxrlib-enc)")) {
        s.push_str(&format!(
            "jxr(jxrlib-enc) rows: jxrlib's {enc} writes the file (the input as scRGB half floats, -c 12, or -c 25 with alpha, -q as \
             labelled);\n  enc 1T is the wall time of that process (start and TIFF reading included), enc {n}T '-';\n  \
             bytes, quality and dec are our decoder on jxrlib's file; peer dec is jxrlib's {dec} on the same file,\n  \
             out of process (start and TIFF writing included: meaningful on large images only); its samples must equal ours\n",
            enc = jxrlib::ENCODER,
            dec = jxrlib::DECODER,
            n = report.threads
        ));
    }
    s.push_str(&peers::table_notes(report));
    for k in &report.skipped {
        s.push_str(&format!("skipped {}: {}\n", k.file, k.reason));
    }
    s.push_str(&equal_quality::table(&report.equal_quality));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peer_inputs_are_made_once_per_kind() {
        let prepared = Prepared::default();
        let made = std::cell::Cell::new(0);
        let make = |v: u32| {
            made.set(made.get() + 1);
            Ok(v)
        };
        assert_eq!(*prepared.get("a", || make(1)).unwrap(), 1);
        assert_eq!(*prepared.get("a", || make(2)).unwrap(), 1, "the first one is kept");
        assert_eq!(*prepared.get("b", || make(3)).unwrap(), 3);
        assert_eq!(made.get(), 2);
        // A failure is not kept: the next asker makes it again.
        assert!(prepared.get::<u32>("c", || Err(hdrcodec::core::Error::invalid("no"))).is_err());
        assert_eq!(*prepared.get("c", || make(4)).unwrap(), 4);
    }
}
