//! jxrlib, the JPEG XR reference codec, reached as outside programs (Debian `libjxr-tools`:
//! `JxrEncApp`, `JxrDecApp`) for the bench's JPEG XR rows: jxrlib writes the file, our decoder
//! reads it, and jxrlib's own decode of the same file is the peer. Nothing here links jxrlib, so
//! the CLI builds without it; without the programs the rows say "not installed".
//!
//! Also the small TIFF pieces those programs need: an uncompressed little-endian float RGB
//! TIFF writer (what `JxrEncApp -c 12` reads as 48bppRGBHalf) and a reader of the sample bytes
//! of the TIFF `JxrDecApp` writes.

use hdrcodec::core::half::f16;
use hdrcodec::core::tiff::Tiff;
use hdrcodec::core::{ColorPrimaries, Error, HdrImage, Limits, Result};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// jxrlib's encoder program.
pub const ENCODER: &str = "JxrEncApp";
/// jxrlib's decoder program.
pub const DECODER: &str = "JxrDecApp";
/// Where the programs come from, for "not installed" messages.
pub const PACKAGE: &str = "Debian libjxr-tools";

/// The absolute luminance of a half-float JPEG XR sample 1.0 (scRGB, the WIC convention our
/// decoder follows for files without colour information, as JxrEncApp writes them).
pub const SCRGB_NITS_PER_UNIT: f32 = 80.0;

/// The largest finite half float.
const HALF_MAX: f32 = 65504.0;

/// A program on PATH, if present.
pub fn tool(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(name)).find(|p| p.is_file())
}

/// A fresh directory under the system's temporary directory, removed with everything in it
/// when dropped (also when a measurement fails half way).
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// Creates `hdrcodec-<what>-<pid>-<n>` under [`std::env::temp_dir`].
    pub fn new(what: &str) -> Result<Self> {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        loop {
            let n = NEXT.fetch_add(1, Ordering::Relaxed);
            let dir = std::env::temp_dir().join(format!("hdrcodec-{what}-{}-{n}", std::process::id()));
            match std::fs::create_dir(&dir) {
                Ok(()) => return Ok(Self(dir)),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => {
                    return Err(Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", dir.display()))));
                }
            }
        }
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A little-endian, uncompressed, single-strip RGB TIFF of 16- or 32-bit IEEE floats (what
/// JxrEncApp reads as 48bppRGBHalf with `-c 12`, or as 96bppRGBFloat). `samples` are the
/// interleaved little-endian samples, rows packed.
pub fn float_rgb_tiff(width: u32, height: u32, bits: u16, samples: &[u8]) -> Result<Vec<u8>> {
    float_tiff(width, height, 3, bits, samples)
}

/// [`float_rgb_tiff`] with `channels` samples per pixel: 3 (RGB) or 4 (RGB and unassociated
/// alpha, what JxrEncApp reads as 64bppRGBAHalf with `-c 25`).
pub fn float_tiff(width: u32, height: u32, channels: u16, bits: u16, samples: &[u8]) -> Result<Vec<u8>> {
    if bits != 16 && bits != 32 {
        return Err(Error::invalid(format!("a float TIFF has 16- or 32-bit samples, not {bits}")));
    }
    if channels != 3 && channels != 4 {
        return Err(Error::invalid(format!("a float TIFF of RGB or RGBA, not {channels} channels")));
    }
    let expected = width as u64 * height as u64 * u64::from(channels) * u64::from(bits / 8);
    if samples.len() as u64 != expected {
        return Err(Error::invalid(format!(
            "{} sample bytes for a {width}x{height} image of {channels} {bits}-bit floats ({expected} expected)",
            samples.len()
        )));
    }
    let alpha = channels == 4;
    let entries = 11 + u32::from(alpha);
    let ifd_end = 8 + 2 + entries * 12 + 4;
    let per_sample = 2 * u32::from(channels);
    let (bits_at, format_at, data_at) = (ifd_end, ifd_end + per_sample, ifd_end + 2 * per_sample);
    let len = u32::try_from(samples.len())
        .ok()
        .filter(|n| n.checked_add(data_at).is_some())
        .ok_or_else(|| Error::limit(format!("{width}x{height} is too large for a TIFF with 32-bit offsets")))?;
    let mut t = Vec::with_capacity(data_at as usize + samples.len());
    t.extend_from_slice(b"II*\0");
    t.extend_from_slice(&8u32.to_le_bytes());
    t.extend_from_slice(&(entries as u16).to_le_bytes());
    // (tag, type: 3 SHORT / 4 LONG, count, value or offset), in tag order: width, height,
    // bits per sample, compression none, RGB, strip offset, samples per pixel, rows per
    // strip, strip bytes, chunky, (extra samples: unassociated alpha,) sample format IEEE
    // float.
    let c = u32::from(channels);
    let mut fields: Vec<(u16, u16, u32, u32)> = vec![
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, c, bits_at),
        (259, 3, 1, 1),
        (262, 3, 1, 2),
        (273, 4, 1, data_at),
        (277, 3, 1, c),
        (278, 4, 1, height),
        (279, 4, 1, len),
        (284, 3, 1, 1),
    ];
    if alpha {
        fields.push((338, 3, 1, 2));
    }
    fields.push((339, 3, c, format_at));
    for (tag, ty, count, value) in fields {
        t.extend_from_slice(&tag.to_le_bytes());
        t.extend_from_slice(&ty.to_le_bytes());
        t.extend_from_slice(&count.to_le_bytes());
        if ty == 3 && count == 1 {
            t.extend_from_slice(&(value as u16).to_le_bytes());
            t.extend_from_slice(&[0, 0]);
        } else {
            t.extend_from_slice(&value.to_le_bytes());
        }
    }
    t.extend_from_slice(&0u32.to_le_bytes());
    for v in std::iter::repeat_n(bits, channels.into()).chain(std::iter::repeat_n(3, channels.into())) {
        t.extend_from_slice(&v.to_le_bytes());
    }
    t.extend_from_slice(samples);
    Ok(t)
}

/// What JxrEncApp is given for `image`: its RGB as scRGB half floats (BT.709 primaries, 1.0 =
/// [`SCRGB_NITS_PER_UNIT`] cd/m², the convention our decoder reads such a file back in), and
/// its alpha if it has one (not scaled: alpha is not light), as a TIFF, and the number of
/// samples clipped to half's ±65504 (NaN is written as 0 and counted). Primaries are converted
/// only when the image has primaries other than BT.709. The TIFF has as many channels as the
/// image: JxrEncApp's `-c 12` for three, `-c 25` for four.
pub fn scrgb_half_tiff(image: &HdrImage) -> Result<(Vec<u8>, usize)> {
    let converted;
    let image = match image.color.primaries {
        p if p.is_specified() && p != ColorPrimaries::Bt709 => {
            converted = hdrcodec::core::color::convert_primaries(image, ColorPrimaries::Bt709);
            &converted
        }
        _ => image,
    };
    let scale = image.color.nits_per_unit / SCRGB_NITS_PER_UNIT;
    let channels = image.channels().count();
    let mut clipped = 0;
    let mut samples = Vec::with_capacity(image.pixel_count() * 2 * channels);
    for (i, &v) in image.samples().iter().enumerate() {
        let v = if i % channels < 3 { v * scale } else { v };
        let h = if v.is_nan() || v.abs() > HALF_MAX {
            clipped += 1;
            if v.is_nan() {
                0.0
            } else {
                v.clamp(-HALF_MAX, HALF_MAX)
            }
        } else {
            v
        };
        samples.extend_from_slice(&f16::from_f32(h).to_le_bytes());
    }
    Ok((float_tiff(image.width(), image.height(), channels as u16, 16, &samples)?, clipped))
}

/// The most of an outside program's message an error repeats, in characters.
pub const MESSAGE_CHARS: usize = 400;

/// Runs `program` with `args` and returns its wall time (process start included). A failure,
/// or an exit status of success without the expected `output` file, is an error with what the
/// program printed (stderr, then stdout; its lines joined, at most [`MESSAGE_CHARS`] characters:
/// cjxl prints a banner line before its error).
pub fn run(program: &Path, args: &[&std::ffi::OsStr], output: &Path) -> Result<Duration> {
    run_with_stderr(program, args, output).map(|(took, _)| took)
}

/// [`run`], also returning what the program printed on stderr (FFmpeg names its encoder
/// library's version there).
pub fn run_with_stderr(program: &Path, args: &[&std::ffi::OsStr], output: &Path) -> Result<(Duration, String)> {
    let name = program.file_name().map_or_else(|| program.display().to_string(), |n| n.to_string_lossy().into());
    let _ = std::fs::remove_file(output);
    let start = Instant::now();
    let out = Command::new(program)
        .args(args)
        .output()
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("cannot run {name}: {e}"))))?;
    let took = start.elapsed();
    let made = std::fs::metadata(output).is_ok_and(|m| m.len() > 0);
    if !out.status.success() || !made {
        let text = String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
        let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        let mut message = if lines.is_empty() { "no message".to_string() } else { lines.join(" | ") };
        if let Some((cut, _)) = message.char_indices().nth(MESSAGE_CHARS) {
            message.truncate(cut);
            message.push_str(" ...");
        }
        let what = if out.status.success() { "wrote no file".to_string() } else { format!("failed ({})", out.status) };
        return Err(Error::Io(std::io::Error::other(format!("{name} {what}: {message}"))));
    }
    Ok((took, String::from_utf8_lossy(&out.stderr).into_owned()))
}

/// The sample bytes of an uncompressed TIFF (its strips, in order), as JxrDecApp writes them.
pub fn tiff_samples(data: &[u8]) -> Result<Vec<u8>> {
    let tiff = Tiff::parse(data, 42)?;
    let ifd = tiff.first_ifd()?;
    let limits = Limits::default();
    if let Some(c) = ifd.get(259) {
        let c = c.first_u32(&tiff)?;
        if c != 1 {
            return Err(Error::unsupported(format!("TIFF compression {c} (only uncompressed strips are read)")));
        }
    }
    let field = |tag: u16, what: &str| {
        ifd.get(tag)
            .ok_or_else(|| Error::invalid(format!("the TIFF has no {what}")))
            .and_then(|e| e.u32s(&tiff, &limits))
    };
    let (offsets, counts) = (field(273, "StripOffsets")?, field(279, "StripByteCounts")?);
    if offsets.len() != counts.len() {
        return Err(Error::invalid("the TIFF's StripOffsets and StripByteCounts differ in length"));
    }
    let mut out = Vec::new();
    for (&o, &n) in offsets.iter().zip(&counts) {
        let strip = (o as usize)
            .checked_add(n as usize)
            .and_then(|end| data.get(o as usize..end))
            .ok_or_else(|| Error::truncated("a TIFF strip"))?;
        out.extend_from_slice(strip);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::{Channels, ColorInfo};

    #[test]
    fn the_tiff_written_reads_back_with_its_samples() {
        let samples: Vec<u8> = (0..2 * 3 * 3 * 2).map(|i| i as u8).collect();
        let tif = float_rgb_tiff(3, 2, 16, &samples).unwrap();
        assert_eq!(tiff_samples(&tif).unwrap(), samples);
        assert!(float_rgb_tiff(3, 2, 16, &samples[1..]).is_err());
        assert!(float_rgb_tiff(3, 2, 8, &samples).is_err());
        assert!(tiff_samples(&tif[..tif.len() - 1]).is_err());
        assert!(tiff_samples(b"II*\0").is_err());
    }

    #[test]
    fn half_input_is_scrgb_and_clips_what_half_cannot_hold() {
        // 100 nits per unit: a sample 0.8 is 80 nits, scRGB 1.0; 1e6 is beyond half's 65504.
        let color = ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() };
        let img = HdrImage::new(2, 1, Channels::Rgb, vec![0.8, 0.0, -0.8, 1e6, f32::NAN, 0.5], color.clone()).unwrap();
        let (tif, clipped) = scrgb_half_tiff(&img).unwrap();
        let halves: Vec<f32> =
            tiff_samples(&tif).unwrap().chunks_exact(2).map(|b| f16::from_le_bytes([b[0], b[1]]).to_f32()).collect();
        assert_eq!(halves, [1.0, 0.0, -1.0, 65504.0, 0.0, 0.625]);
        assert_eq!(clipped, 2);
        // Alpha goes in as it is, not scaled.
        let img = HdrImage::new(1, 1, Channels::Rgba, vec![0.8, 0.4, 0.0, 0.5], color).unwrap();
        let (tif, clipped) = scrgb_half_tiff(&img).unwrap();
        let halves: Vec<f32> =
            tiff_samples(&tif).unwrap().chunks_exact(2).map(|b| f16::from_le_bytes([b[0], b[1]]).to_f32()).collect();
        assert_eq!((halves, clipped), (vec![1.0, 0.5, 0.0, 0.5], 0));
    }

    #[test]
    fn temp_dirs_are_fresh_and_removed() {
        let (a, b) = (TempDir::new("test").unwrap(), TempDir::new("test").unwrap());
        assert_ne!(a.path(), b.path());
        std::fs::write(a.path().join("x"), b"x").unwrap();
        let p = a.path().to_path_buf();
        drop(a);
        assert!(!p.exists());
    }
}
