//! The bench's outside peers beyond jxrlib and libultrahdr: JPEG XL through libjxl's `cjxl` /
//! `djxl` ([`jxl`]), AVIF 10- and 12-bit PQ through libavif's `avifenc` / `avifdec` ([`avif`]),
//! OpenEXR through OpenImageIO's `oiiotool` ([`oiio`]), AV1 HDR10 through FFmpeg's SVT-AV1
//! for the video rows ([`svtav1`]), and BC6H through Intel ISPC in process ([`ispc`], a cargo feature). All are reached as programs on
//! PATH (nothing is linked), in a temporary directory that is removed on return, also on
//! failure; without a program the rows say "not installed".
//!
//! JPEG XL and AVIF are not formats of the family: their rows' encode *and* decode speeds are
//! the wall times of the peer's processes (process start and file I/O included, one thread:
//! `--num_threads=1`, `-j 1`; no pool figure), bytes are the file the encoder wrote, and quality
//! is the decoder's output against the bench input. OpenEXR is ours too: oiiotool writes the
//! file, our decoder reads it (as for jxrlib's rows), and oiiotool decoding the same file is the
//! peer decode whose samples must equal ours.

pub mod avif;
pub mod ispc;
pub mod jxl;
pub mod oiio;
pub mod svtav1;

use crate::bench::{self, Config, Encoder, Input, PeerDecode, Row};
use crate::jxrlib::{self, TempDir};
use hdrcodec::core::{metrics, Channels, ColorPrimaries, HdrImage, Result, ThreadPool};
use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Mutex, OnceLock};

/// The first line of what `program` prints for `arg` (`--version`), stdout then stderr; `None`
/// when it cannot run. Asked once per program and process.
pub(crate) fn version_text(program: &str, arg: &str) -> Option<String> {
    /// (program and argument, what it printed).
    type Seen = Vec<(String, Option<String>)>;
    static SEEN: OnceLock<Mutex<Seen>> = OnceLock::new();
    let seen = SEEN.get_or_init(|| Mutex::new(Vec::new()));
    let key = format!("{program} {arg}");
    if let Some((_, v)) = seen.lock().ok()?.iter().find(|(k, _)| *k == key) {
        return v.clone();
    }
    let text = jxrlib::tool(program)
        .and_then(|p| Command::new(p).arg(arg).output().ok())
        .map(|out| String::from_utf8_lossy(&out.stdout).into_owned() + "\n" + &String::from_utf8_lossy(&out.stderr));
    seen.lock().ok()?.push((key, text.clone()));
    text
}

/// A command line from its words (strings and paths).
pub(crate) fn args(words: &[&dyn AsRef<OsStr>]) -> Vec<OsString> {
    words.iter().map(|w| w.as_ref().to_os_string()).collect()
}

/// The median wall time of up to `runs` runs of `program` with `args`, each of which must
/// write `output` ([`jxrlib::run`]).
fn timed_run(program: &Path, args: &[OsString], output: &Path, runs: usize) -> Result<std::time::Duration> {
    let args: Vec<&OsStr> = args.iter().map(OsString::as_os_str).collect();
    Ok(bench::timed(runs, || jxrlib::run(program, &args, output))?.0)
}

/// Whether `encoder` is one of this module's peers.
pub(crate) fn handles(encoder: Encoder) -> bool {
    matches!(encoder, Encoder::Cjxl(_) | Encoder::Avifenc { .. } | Encoder::Oiiotool { .. })
}

/// How a row names the encoder and the decoder of one of this module's peers.
pub(crate) fn describe(encoder: Encoder) -> (Option<String>, Option<String>) {
    let outside = |v: String| Some(format!("{v} (outside program)"));
    match encoder {
        Encoder::Cjxl(_) => (outside(jxl::encoder_version()), outside(jxl::decoder_version())),
        Encoder::Avifenc { .. } => (outside(avif::encoder_version()), outside(avif::decoder_version())),
        Encoder::Oiiotool { .. } => (outside(oiio::version()), None),
        _ => (None, None),
    }
}

/// The programs a peer needs, each with its path if it is on PATH.
fn programs(encoder: Encoder) -> (&'static str, Vec<(&'static str, Option<PathBuf>)>) {
    let found = |names: &[&'static str]| names.iter().map(|&n| (n, jxrlib::tool(n))).collect();
    match encoder {
        Encoder::Cjxl(_) => (jxl::PACKAGE, found(&[jxl::ENCODER, jxl::DECODER])),
        Encoder::Avifenc { .. } => (avif::PACKAGE, found(&[avif::ENCODER, avif::DECODER])),
        _ => (oiio::PACKAGE, found(&[oiio::PROGRAM])),
    }
}

/// Measures one row of a peer of this module into `row`: "not installed: ..." when one of
/// its programs is missing, the failure (with the program's message) when a step fails.
pub(crate) fn measure(
    config: &Config,
    input: &Input,
    runs: usize,
    pool: &ThreadPool,
    prepared: &bench::Prepared,
    row: &mut Row,
) {
    let (package, found) = programs(config.encoder);
    let missing: Vec<&str> = found.iter().filter(|(_, p)| p.is_none()).map(|(n, _)| *n).collect();
    if !missing.is_empty() {
        let verb = if missing.len() == 1 { "is" } else { "are" };
        row.error = Some(format!("{}: {} ({package}) {verb} not on PATH", bench::NOT_INSTALLED, missing.join(" and ")));
        return;
    }
    let paths: Vec<PathBuf> = found.into_iter().filter_map(|(_, p)| p).collect();
    let result = match config.encoder {
        Encoder::Cjxl(distance) => measure_jxl(&paths[0], &paths[1], distance, input, runs, prepared, row),
        Encoder::Avifenc { depth, quantizer } => {
            measure_avif(&paths[0], &paths[1], (depth, quantizer), input, runs, prepared, row)
        }
        Encoder::Oiiotool { compression, pixel } => {
            measure_oiio(config, &paths[0], (compression, pixel), input, runs, pool, prepared, row)
        }
        _ => return,
    };
    if let Err(e) = result {
        row.error = Some(e.to_string());
    }
}

/// The bench input as the peers' rows score it: the input's samples, labelled BT.709 when
/// they record no primaries (said in the returned note), RGB only.
fn reference(input: &Input) -> (HdrImage, Option<String>) {
    let mut reference = input.image.with_channels(Channels::Rgb);
    if reference.color.primaries.is_specified() {
        return (reference, None);
    }
    reference.color.primaries = ColorPrimaries::Bt709;
    let note = format!("{}: the image records no primaries: BT.709 assumed for the JPEG XL and AVIF input", input.name);
    (reference, Some(note))
}

/// The row's size and quality (`decoded` against `reference`) and the peer's process times.
fn score(
    reference: &HdrImage,
    decoded: &HdrImage,
    bytes: usize,
    (enc_t, dec_t): (std::time::Duration, std::time::Duration),
    row: &mut Row,
) -> Result<()> {
    let cmp = metrics::compare(reference, decoded)?;
    row.set_size_and_quality(bytes, row.pixels, &cmp);
    row.encode_mps = bench::mps(row.pixels, enc_t);
    row.decode_mps = bench::mps(row.pixels, dec_t);
    // One thread each (`--num_threads=1`, `-j 1`): no pool figure.
    row.encode_mps_all = f64::NAN;
    row.decode_mps_all = f64::NAN;
    Ok(())
}

/// Adds `note` to `notes` once.
fn note(notes: &mut Vec<String>, note: String) {
    if !notes.contains(&note) {
        notes.push(note);
    }
}

/// A JPEG XL row ([`Encoder::Cjxl`]): the input as linear PFM ([`jxl::prepare`]), `cjxl` at
/// `distance`, `djxl` back to PFM, read by our PFM decoder.
fn measure_jxl(
    cjxl: &Path,
    djxl: &Path,
    distance: &str,
    input: &Input,
    runs: usize,
    cache: &bench::Prepared,
    row: &mut Row,
) -> Result<()> {
    let made = cache.get("jxl", || {
        let (reference, assumed) = reference(input);
        let prepared = jxl::prepare(&reference)?;
        Ok((reference, assumed, prepared))
    })?;
    let (reference, assumed, prepared) = (&made.0, made.1.clone(), &made.2);
    let dir = TempDir::new("bench-jxl")?;
    let (pfm, jxl_path, back) = (dir.path().join("in.pfm"), dir.path().join("out.jxl"), dir.path().join("back.pfm"));
    std::fs::write(&pfm, &prepared.pfm)?;
    let enc_t = timed_run(cjxl, &jxl::encode_args(&pfm, &jxl_path, distance, prepared), &jxl_path, runs)?;
    let bytes = std::fs::read(&jxl_path)?.len();
    let dec_t = timed_run(djxl, &jxl::decode_args(&jxl_path, &back), &back, runs)?;
    let decoded = jxl::read_back(&std::fs::read(&back)?, prepared, reference)?;
    score(reference, &decoded, bytes, (enc_t, dec_t), row)?;
    let mut notes: Vec<String> = assumed.into_iter().collect();
    notes.extend(prepared.notes.iter().map(|n| format!("jxl(cjxl) on {}: {n}", input.name)));
    if distance == "0" && !row.identical {
        notes.push(format!(
            "{} on {}: cjxl -d 0 (lossless) did not give the samples back (PU21-PSNR {:.2} dB)",
            row.config, input.name, row.pu21_psnr
        ));
    }
    for n in notes {
        note(&mut row.notes, n);
    }
    Ok(())
}

/// An AVIF row ([`Encoder::Avifenc`]): the input in BT.2020, PQ-coded into a 16-bit PNG
/// ([`avif::pq_png`]), `avifenc` at `depth` bits and `quantizer`, `avifdec -d 16` back to PNG,
/// inverse PQ ([`avif::read_pq_png`]).
fn measure_avif(
    avifenc: &Path,
    avifdec: &Path,
    (depth, quantizer): (u8, u8),
    input: &Input,
    runs: usize,
    cache: &bench::Prepared,
    row: &mut Row,
) -> Result<()> {
    let made = cache.get("avif", || {
        let (reference, assumed) = reference(input);
        let bt2020 = hdrcodec::core::color::convert_primaries(&reference, ColorPrimaries::Bt2020);
        let (png, clipped) = avif::pq_png(&bt2020)?;
        Ok((reference, assumed, bt2020, png, clipped))
    })?;
    let (reference, assumed, bt2020, png, clipped) = (&made.0, made.1.clone(), &made.2, &made.3, made.4);
    let dir = TempDir::new("bench-avif")?;
    let (src, out, back) = (dir.path().join("in.png"), dir.path().join("out.avif"), dir.path().join("back.png"));
    std::fs::write(&src, png)?;
    let enc_t = timed_run(avifenc, &avif::encode_args(&src, &out, depth, quantizer), &out, runs)?;
    let bytes = std::fs::read(&out)?.len();
    let dec_t = timed_run(avifdec, &avif::decode_args(&out, &back), &back, runs)?;
    let decoded = avif::read_pq_png(&std::fs::read(&back)?, bt2020)?;
    score(reference, &decoded, bytes, (enc_t, dec_t), row)?;
    let mut notes: Vec<String> = assumed.into_iter().collect();
    if clipped > 0 {
        notes.push(format!(
            "avif(avifenc) on {}: {clipped} samples outside PQ's 0-10000 cd/m² (or NaN, or negative: outside BT.2020) clipped",
            input.name
        ));
    }
    for n in notes {
        note(&mut row.notes, n);
    }
    Ok(())
}

/// An OpenEXR row written by OpenImageIO ([`Encoder::Oiiotool`]): the input as an uncompressed
/// float EXR written by our codec, `oiiotool` re-writes it with `compression` and `pixel`
/// samples, our decoder reads that file; `oiiotool` decoding it to uncompressed float is the
/// peer decode, whose samples must equal ours.
#[allow(clippy::too_many_arguments)]
fn measure_oiio(
    config: &Config,
    oiiotool: &Path,
    (compression, pixel): (&str, &str),
    input: &Input,
    runs: usize,
    pool: &ThreadPool,
    cache: &bench::Prepared,
    row: &mut Row,
) -> Result<()> {
    let codec = config.codec.as_ref();
    let made = cache.get("oiio", || {
        let plain =
            hdrcodec::core::EncodeSettings::default().with_option("compression", "none").with_option("pixel", "float");
        hdrcodec::encode_for(codec, &input.image, &plain)
    })?;
    let (exr, mut notes) = (&made.0, made.1.clone());
    let dir = TempDir::new("bench-oiio")?;
    let (src, out, back) = (dir.path().join("in.exr"), dir.path().join("out.exr"), dir.path().join("back.exr"));
    std::fs::write(&src, exr)?;
    let enc_t = timed_run(oiiotool, &oiio::encode_args(&src, &out, compression, pixel), &out, runs)?;
    let bytes = std::fs::read(&out)?;
    bench::decode_peer_file(config, &bytes, input, runs, pool, enc_t, row)?;
    // The peer decode: OpenEXR (through OIIO) to uncompressed float, read back by our codec.
    let limits = hdrcodec::core::Limits::default();
    let peer = timed_run(oiiotool, &oiio::decode_args(&out, &back), &back, runs).and_then(|t| {
        let theirs = codec.decode(&std::fs::read(&back)?, &limits)?;
        let ours = codec.decode(&bytes, &limits)?;
        let same = |a: &f32, b: &f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let matches = theirs.channels() == ours.channels()
            && theirs.samples().len() == ours.samples().len()
            && theirs.samples().iter().zip(ours.samples()).all(|(a, b)| same(a, b));
        Ok(PeerDecode {
            decoder: format!("{} (outside program)", oiio::version()),
            decode_mps: bench::mps(row.pixels, t),
            matches,
        })
    });
    match peer {
        Ok(peer) => {
            if !peer.matches {
                notes.push(format!(
                    "{} on {}: our samples DIFFER from OpenEXR's decode (through oiiotool)",
                    config.label, input.name
                ));
            }
            row.peer = Some(peer);
        }
        Err(e) => notes.push(format!("{} on {}: no peer decode: {e}", config.label, input.name)),
    }
    for n in notes {
        note(&mut row.notes, n);
    }
    Ok(())
}

/// The lines that explain the peers' rows under the bench table, for the families present.
pub fn table_notes(report: &bench::Report) -> String {
    let has = |prefix: &str| report.rows.iter().any(|r| r.config.starts_with(prefix));
    let mut s = String::new();
    if has("jxl(cjxl)") {
        s.push_str(&format!(
            "jxl(cjxl) rows: {} writes the file from linear float PFM (-x color_space=RGB_D65_<primaries>_Rel_Lin,\n  \
             --intensity_target = the cd/m² of PFM sample 1.0), -d as labelled (d0: lossless), effort 7, one thread;\n  \
             {} decodes it to PFM, read by our PFM decoder; enc 1T and dec 1T are the wall times of those processes\n",
            jxl::encoder_version(),
            jxl::decoder_version()
        ));
    }
    if has("avif(avifenc)") {
        s.push_str(&format!(
            "avif(avifenc) rows: the input in BT.2020 (converted once from other primaries; scored in its own) and PQ\n  \
             (SMPTE ST 2084: sample x nits_per_unit = cd/m², 10000 cd/m² = 1.0) in a 16-bit PNG;\n  \
             {} -d 10|12 -y 444 --cicp 9/16/9 -r full --min Q --max Q (qpQ) -s 6 -j 1;\n  \
             {} -d 16 -j 1 back to PNG, inverse PQ; enc 1T and dec 1T are the wall times of those processes\n",
            avif::encoder_version(),
            avif::decoder_version()
        ));
    }
    if has("bc6h(ispc)") && ispc::available() {
        s.push_str(
            "bc6h(ispc) rows: Intel ISPC texcomp (intel_tex_2 0.5, in process) compresses the input as padded RGBA half floats \
             (NaN and negatives\n  to 0) at the labelled profile; enc 1T includes that conversion, enc all '-'; bytes, quality \
             and dec are our decoder on its DDS file\n",
        );
    }
    if has("exr(oiiotool)") {
        s.push_str(&format!(
            "exr(oiiotool) rows: {} re-writes our uncompressed float EXR with the labelled compression and pixel type;\n  \
             enc 1T is that process's wall time (reading the input included); bytes, quality and dec are our decoder on\n  \
             its file; peer dec is oiiotool decoding it to uncompressed float (writing included); its samples must equal ours\n",
            oiio::version()
        ));
    }
    s
}
