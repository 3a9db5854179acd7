//! Peak resident memory of decoding, per codec (`bench --memory`, and every `bench --report`).
//!
//! For each of our codecs in the run, the largest bench image is encoded with that codec's first
//! configuration and written to a temporary file; a child `hdrcodec memory-peak FILE` process
//! reads and decodes it into a whole image and reports its own peak resident set (Linux
//! `/proc/self/status`: `VmHWM`, the figure `getrusage`'s `ru_maxrss` and `/usr/bin/time -f %M`
//! give) and its resident set before reading the file (`VmRSS`: the program itself). The row
//! sets the growth, peak minus start, against the size of the decoded image (RGB or RGBA
//! `f32`), whose target is at most 1.5x. The child decodes from the open file
//! (`Registry::read`, `ImageCodec::decode_from`): a codec that reads its file piece by piece
//! (OpenEXR) holds none of it whole; the others read it into memory first, which is part of the
//! figure.

use crate::bench::{Config, Encoder, Input};
use crate::jxrlib::TempDir;
use crate::text_table::{Align, TextTable};
use hdrcodec::core::{Error, Limits, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::process::Command;

/// The target of the growth, as a multiple of the decoded image.
pub const TARGET: f64 = 1.5;

/// What `hdrcodec memory-peak FILE` prints (one JSON object).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DecodePeak {
    /// The codec that decoded the file.
    pub codec: String,
    /// Decoded width.
    pub width: u32,
    /// Decoded height.
    pub height: u32,
    /// Bytes of the decoded image's samples.
    pub decoded_bytes: u64,
    /// Resident set before the file was read, bytes.
    pub start_rss_bytes: u64,
    /// Peak resident set of the process, bytes.
    pub peak_rss_bytes: u64,
}

/// A field of `/proc/self/status` in bytes (`VmHWM`, `VmRSS`; the kernel gives kB).
pub fn status_bytes(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))?;
    let kb: u64 = line.split_whitespace().next()?.parse().ok()?;
    Some(kb * 1024)
}

/// `hdrcodec memory-peak FILE`: decodes `path` (the codec chosen as `convert` chooses it) and
/// measures this process.
pub fn decode_peak(path: &Path) -> Result<DecodePeak> {
    let unavailable = || Error::unsupported("peak memory is read from /proc/self/status (Linux only)");
    let start = status_bytes("VmRSS").ok_or_else(unavailable)?;
    let (codec, image) = hdrcodec::registry().read(path, &Limits::default())?;
    let peak = status_bytes("VmHWM").ok_or_else(unavailable)?;
    Ok(DecodePeak {
        codec: codec.name().to_string(),
        width: image.width(),
        height: image.height(),
        decoded_bytes: std::mem::size_of_val(image.samples()) as u64,
        start_rss_bytes: start,
        peak_rss_bytes: peak,
    })
}

/// One codec's figure.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryRow {
    /// The configuration whose file was decoded.
    pub config: String,
    /// The image.
    pub image: String,
    /// Bytes of the file.
    pub file_bytes: u64,
    /// The child's report.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub peak: Option<DecodePeak>,
    /// (peak − start) / decoded bytes.
    pub growth_ratio: f64,
    /// Why there is no figure, if so.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// For each codec of `configs` that we encode (the first configuration of each), the child
/// `exe memory-peak` decoding that codec's file of the largest of `inputs`.
pub fn measure(configs: &[Config], inputs: &[Input], exe: &Path) -> Vec<MemoryRow> {
    let Some(input) = inputs.iter().max_by_key(|i| i.image.pixel_count()) else { return Vec::new() };
    let mut seen: Vec<&str> = Vec::new();
    let mut rows = Vec::new();
    for config in configs.iter().filter(|c| c.encoder == Encoder::Hdrcodec) {
        let name = config.codec.name();
        if seen.contains(&name) {
            continue;
        }
        seen.push(name);
        let mut row = MemoryRow {
            config: config.label.clone(),
            image: input.name.clone(),
            file_bytes: 0,
            peak: None,
            growth_ratio: f64::NAN,
            error: None,
        };
        match measure_one(config, input, exe, &mut row) {
            Ok(peak) => {
                row.growth_ratio =
                    peak.peak_rss_bytes.saturating_sub(peak.start_rss_bytes) as f64 / peak.decoded_bytes.max(1) as f64;
                row.peak = Some(peak);
            }
            Err(e) => row.error = Some(e.to_string()),
        }
        rows.push(row);
    }
    rows
}

/// Encodes `input` with `config` into a temporary file and runs the child on it.
fn measure_one(config: &Config, input: &Input, exe: &Path, row: &mut MemoryRow) -> Result<DecodePeak> {
    let codec = config.codec.as_ref();
    let (bytes, _) = hdrcodec::encode_for(codec, &input.image, &config.settings)?;
    let dir = TempDir::new("bench-memory")?;
    let ext = codec.extensions().first().copied().unwrap_or("bin");
    let file = dir.path().join(format!("image.{ext}"));
    std::fs::write(&file, &bytes)?;
    row.file_bytes = bytes.len() as u64;
    let out = Command::new(exe).arg("memory-peak").arg(&file).output()?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(Error::invalid(format!("memory-peak failed: {}", err.trim())));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| Error::invalid(format!("memory-peak printed no report: {e}")))
}

/// The rows as a plain-text table.
pub fn table(rows: &[MemoryRow]) -> String {
    let mut t = TextTable::new(&[
        ("memory: config", Align::Left),
        ("image", Align::Left),
        ("file MB", Align::Right),
        ("decoded MB", Align::Right),
        ("start MB", Align::Right),
        ("peak MB", Align::Right),
        ("growth", Align::Right),
        ("met", Align::Right),
    ]);
    let mb = |b: u64| format!("{:.2}", b as f64 / 1e6);
    for r in rows {
        match (&r.peak, &r.error) {
            (Some(p), _) => t.row(
                vec![
                    r.config.clone(),
                    r.image.clone(),
                    mb(r.file_bytes),
                    mb(p.decoded_bytes),
                    mb(p.start_rss_bytes),
                    mb(p.peak_rss_bytes),
                    format!("{:.2}x", r.growth_ratio),
                    (if r.growth_ratio <= TARGET { "yes" } else { "no" }).to_string(),
                ],
                "",
            ),
            (None, e) => t.note_row(vec![r.config.clone(), r.image.clone()], e.as_deref().unwrap_or("")),
        }
    }
    let mut s = t.render();
    s.push_str(&format!(
        "memory rows: a child `hdrcodec memory-peak FILE` decodes the file from disk into a whole image; growth = (peak − \
         start) / decoded\n  (peak and start: its VmHWM and VmRSS before reading; decoded: the image's f32 samples); \
         target ≤ {TARGET}x\n"
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_has_a_peak_at_least_its_resident_set() {
        let (rss, hwm) = (status_bytes("VmRSS").unwrap(), status_bytes("VmHWM").unwrap());
        assert!(rss > 0 && hwm >= rss, "{rss} {hwm}");
        // 64 MB touched raise the peak by about that much (other tests of this process may
        // free some of theirs meanwhile: half of it is asked).
        let v = vec![1u8; 64 << 20];
        let after = status_bytes("VmHWM").unwrap();
        assert!(after >= rss + (32 << 20), "{rss} -> {after}");
        assert_eq!(v.iter().map(|&b| u64::from(b)).sum::<u64>(), 64 << 20);
        assert_eq!(status_bytes("NoSuchField"), None);
    }
}
