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

use hdrcodec::core::{metrics, Channels, DecodeOptions, EncodeSettings, HdrImage, ImageCodec, Limits, ThreadPool};
use hdrcodec::Registry;
use serde::Serialize;
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
}

/// Every configuration the bench runs, for the codecs present in `registry`. Each codec adds
/// its rows here, **one line per codec**.
pub fn configurations(registry: &Registry) -> Vec<Config> {
    let mut out = Vec::new();
    let mut add = |codec: &str, label: String, settings: EncodeSettings| {
        if let Ok(codec) = registry.by_name(codec) {
            out.push(Config { label, codec, settings });
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
    // Uncompressed half floats in the container: the size every lossy codec should beat.
    add("hdrc", "hdrc:raw-f16".into(), opts(&[("payload", "raw-f16")]));
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

/// Every file under `dir` (and its subdirectories, a few levels deep) that some codec of
/// `registry` decodes, sorted by path; files without a known extension or magic number are
/// ignored, and files that fail to decode are listed as skipped. Names are relative to `dir`.
pub fn dir_inputs(
    dir: &Path,
    registry: &Registry,
    limits: &Limits,
) -> hdrcodec::core::Result<(Vec<Input>, Vec<Skipped>)> {
    let mut paths = Vec::new();
    collect_files(dir, 4, &mut paths)
        .map_err(|e| hdrcodec::core::Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", dir.display()))))?;
    paths.sort();
    let (mut inputs, mut skipped) = (Vec::new(), Vec::new());
    for p in paths {
        let file = p.strip_prefix(dir).unwrap_or(&p).to_string_lossy().into_owned();
        let data = match hdrcodec::read_file(&p) {
            Ok(d) => d,
            Err(e) => {
                skipped.push(Skipped { file, reason: e.to_string() });
                continue;
            }
        };
        match registry.for_input(&p, &data) {
            // Not an image format we know (MANIFEST, README, ...): not worth a mention.
            Err(_) => continue,
            Ok(codec) => match codec.decode(&data, limits) {
                Ok(image) => inputs.push(Input { name: file, image }),
                Err(e) => skipped.push(Skipped { file, reason: e.to_string() }),
            },
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
    /// PU21-PSNR of the luminance, dB (infinite, `null` in JSON, when identical).
    pub pu21_psnr: f64,
    /// Mean ΔE ITP (BT.2124).
    pub de_itp_mean: f64,
    /// Root mean square of log2((test + 1) / (reference + 1)) over the RGB samples.
    pub log_rmse: f64,
    /// Encode speed on one thread, megapixels per second (median run).
    pub encode_mps: f64,
    /// Decode speed on one thread, megapixels per second (median run).
    pub decode_mps: f64,
    /// Encode speed on the report's pool of `threads` threads.
    pub encode_mps_all: f64,
    /// Decode speed on the report's pool of `threads` threads.
    pub decode_mps_all: f64,
    /// What the codec or the colour preparation said (a format without primaries, clipping).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Why this configuration failed on this image, if it did (then the numbers are zero).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
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
}

/// Once the runs of one measurement have taken this long, no further run is started: slow
/// configurations (a thorough encoder search) are timed once or twice instead of `runs` times.
const TIME_BUDGET: Duration = Duration::from_secs(2);

/// The median of up to `runs` timings of `f` (which must succeed every time; at least one run,
/// fewer than `runs` once [`TIME_BUDGET`] is spent), and its last result.
fn timed<T>(runs: usize, mut f: impl FnMut() -> hdrcodec::core::Result<T>) -> hdrcodec::core::Result<(Duration, T)> {
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

fn mps(pixels: usize, t: Duration) -> f64 {
    pixels as f64 / 1e6 / t.as_secs_f64().max(1e-9)
}

/// Runs one configuration on one image, timing it on one thread and on `pool`.
fn measure(config: &Config, input: &Input, runs: usize, pool: &ThreadPool) -> Row {
    let pixels = input.image.pixel_count();
    let mut row = Row {
        config: config.label.clone(),
        image: input.name.clone(),
        pixels,
        bytes: 0,
        bpp: 0.0,
        identical: false,
        pu21_psnr: 0.0,
        de_itp_mean: 0.0,
        log_rmse: 0.0,
        encode_mps: 0.0,
        decode_mps: 0.0,
        encode_mps_all: 0.0,
        decode_mps_all: 0.0,
        notes: Vec::new(),
        error: None,
    };
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
        row.bytes = bytes.len();
        row.bpp = bytes.len() as f64 * 8.0 / pixels as f64;
        row.identical = cmp.identical;
        row.pu21_psnr = cmp.pu21_psnr;
        row.de_itp_mean = cmp.de_itp_mean;
        row.log_rmse = cmp.log_rmse;
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

fn summarize(label: &str, rows: &[&Row]) -> Summary {
    let ok: Vec<&&Row> = rows.iter().filter(|r| r.error.is_none()).collect();
    let pixels: usize = ok.iter().map(|r| r.pixels).sum();
    let bytes: usize = ok.iter().map(|r| r.bytes).sum();
    let mean = |f: &dyn Fn(&Row) -> f64, rs: &[&&Row]| rs.iter().map(|r| f(r)).sum::<f64>() / rs.len().max(1) as f64;
    let lossy: Vec<&&Row> = ok.iter().copied().filter(|r| !r.identical).collect();
    let secs = |f: &dyn Fn(&Row) -> f64| ok.iter().map(|r| r.pixels as f64 / 1e6 / f(r).max(1e-12)).sum::<f64>();
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
        encode_mps: pixels as f64 / 1e6 / secs(&|r| r.encode_mps).max(1e-12),
        decode_mps: pixels as f64 / 1e6 / secs(&|r| r.decode_mps).max(1e-12),
        encode_mps_all: pixels as f64 / 1e6 / secs(&|r| r.encode_mps_all).max(1e-12),
        decode_mps_all: pixels as f64 / 1e6 / secs(&|r| r.decode_mps_all).max(1e-12),
    }
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
    let mut rows = Vec::with_capacity(total);
    for c in configs {
        for i in inputs {
            rows.push(measure(c, i, runs, pool));
            progress(rows.len(), total, &c.label);
        }
    }
    let summary = configs
        .iter()
        .map(|c| summarize(&c.label, &rows.iter().filter(|r| r.config == c.label).collect::<Vec<_>>()))
        .collect();
    Report { source: source.to_string(), runs, threads: pool.threads(), rows, summary, skipped }
}

fn fmt_db(v: f64) -> String {
    if v.is_infinite() {
        "lossless".to_string()
    } else {
        format!("{v:.2}")
    }
}

/// The speed column headers: one thread, then all threads of the report's pool.
fn speed_headers(report: &Report) -> (String, String, String, String) {
    let n = report.threads;
    ("enc 1T".into(), "dec 1T".into(), format!("enc {n}T"), format!("dec {n}T"))
}

/// One line per (configuration, image): the `--per-image` table.
pub fn per_image_table(report: &Report) -> String {
    let (e1, d1, en, dn) = speed_headers(report);
    let mut s = format!(
        "{:<20} {:<24} {:>10} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
        "config", "image", "bytes", "bpp", "PU21-PSNR", "dE-ITP", "log-RMSE", e1, d1, en, dn
    );
    for r in report.rows.iter().filter(|r| r.error.is_none()) {
        s.push_str(&format!(
            "{:<20} {:<24} {:>10} {:>8.3} {:>10} {:>9.4} {:>9.5} {:>9.1} {:>9.1} {:>9.1} {:>9.1}\n",
            r.config,
            r.image,
            r.bytes,
            r.bpp,
            if r.identical { "lossless".to_string() } else { fmt_db(r.pu21_psnr) },
            r.de_itp_mean,
            r.log_rmse,
            r.encode_mps,
            r.decode_mps,
            r.encode_mps_all,
            r.decode_mps_all
        ));
    }
    s.push('\n');
    s
}

/// The report as a plain-text table, one line per configuration.
pub fn table(report: &Report) -> String {
    let (e1, d1, en, dn) = speed_headers(report);
    let mut s = format!(
        "{:<20} {:>6} {:>10} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
        "config", "images", "bytes", "bpp", "PU21-PSNR", "dE-ITP", "log-RMSE", e1, d1, en, dn
    );
    for r in &report.summary {
        let images = if r.failed > 0 { format!("{}/{}", r.images, r.images + r.failed) } else { r.images.to_string() };
        s.push_str(&format!(
            "{:<20} {:>6} {:>10} {:>8.3} {:>10} {:>9.4} {:>9.5} {:>9.1} {:>9.1} {:>9.1} {:>9.1}\n",
            r.config,
            images,
            r.bytes,
            r.bpp,
            fmt_db(r.pu21_psnr),
            r.de_itp_mean,
            r.log_rmse,
            r.encode_mps,
            r.decode_mps,
            r.encode_mps_all,
            r.decode_mps_all
        ));
    }
    for r in report.rows.iter().filter(|r| r.error.is_some()) {
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
    for k in &report.skipped {
        s.push_str(&format!("skipped {}: {}\n", k.file, k.reason));
    }
    s
}
