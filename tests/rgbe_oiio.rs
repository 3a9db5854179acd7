//! Radiance RGBE against OpenImageIO (whose `.hdr` codec is Bruce Walter's rgbe.c) and
//! imagecodecs' `rgbe_decode`:
//! - every corpus `.hdr` decodes to exactly OIIO's floats (and imagecodecs');
//! - our truncating writer produces the same pixel bytes as OIIO's writer for the same floats;
//! - files we write (both roundings, RLE and flat) read back in OIIO to exactly our pixels;
//! - all eight resolution-string orientations match OIIO's `reorient`;
//! - the measured errors of both roundings, with nearest better than truncate.
mod common;

use common::{corpus_files, python, read_f32_raw, require, run_python, temp_dir};
use hdrcodec_core::{Channels, ColorInfo, HdrImage, ImageCodec, Limits};
use hdrcodec_rgbe::{decode, encode, MantissaDecode, RgbeCodec, RgbeDecodeOptions, RgbeEncodeOptions, Rounding};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// Reads an image with OIIO and, if `ic_out` is not "-", with imagecodecs' rgbe_decode;
/// writes both as raw little-endian f32 (height x width x 3, as stored: OIIO does not reorient).
const DUMP: &str = r#"
import sys, numpy as np, OpenImageIO as oiio
src, out, ic_out, reorient = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "1"
buf = oiio.ImageBuf(src)
if reorient:
    buf = oiio.ImageBufAlgo.reorient(buf)
px = buf.get_pixels(oiio.FLOAT)
if px is None:
    sys.exit("OIIO cannot read " + src + ": " + oiio.geterror())
s = buf.spec()
print(s.width, s.height, s.nchannels)
np.ascontiguousarray(px[..., :3], dtype="<f4").tofile(out)
if ic_out != "-":
    import imagecodecs
    imagecodecs.rgbe_decode(open(src, "rb").read()).astype("<f4").tofile(ic_out)
"#;

/// Writes raw f32 RGB (width, height given) as a Radiance file with OIIO.
const WRITE: &str = r#"
import sys, numpy as np, OpenImageIO as oiio
raw, w, h, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
a = np.fromfile(raw, dtype="<f4").reshape(h, w, 3)
buf = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.FLOAT))
buf.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, 3), a)
if not buf.write(out):
    sys.exit("OIIO cannot write " + out + ": " + oiio.geterror())
"#;

fn oiio_dump(
    py: &Path,
    file: &Path,
    dir: &Path,
    with_ic: bool,
    reorient: bool,
) -> (u32, u32, Vec<f32>, Option<Vec<f32>>) {
    let raw = dir.join("oiio.raw");
    let ic = dir.join("ic.raw");
    let ic_arg: &OsStr = if with_ic { ic.as_os_str() } else { OsStr::new("-") };
    let out = run_python(
        py,
        DUMP,
        &[file.as_os_str(), raw.as_os_str(), ic_arg, OsStr::new(if reorient { "1" } else { "0" })],
    );
    let dims: Vec<u32> = String::from_utf8_lossy(&out.stdout).split_whitespace().map(|t| t.parse().unwrap()).collect();
    (dims[0], dims[1], read_f32_raw(&raw), with_ic.then(|| read_f32_raw(&ic)))
}

fn oiio_write(py: &Path, samples: &[f32], w: u32, h: u32, dir: &Path) -> Vec<u8> {
    let raw = dir.join("in.raw");
    let out = dir.join("oiio.hdr");
    let bytes: Vec<u8> = samples.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&raw, bytes).unwrap();
    let (ws, hs) = (w.to_string(), h.to_string());
    run_python(py, WRITE, &[raw.as_os_str(), OsStr::new(&ws), OsStr::new(&hs), out.as_os_str()]);
    std::fs::read(&out).unwrap()
}

/// Splits a Radiance file into (header text including the resolution line, pixel bytes).
fn split_header(file: &[u8]) -> (String, &[u8]) {
    let blank = file.windows(2).position(|w| w == b"\n\n").expect("header end") + 2;
    let res_end = blank + file[blank..].iter().position(|&b| b == b'\n').expect("resolution line") + 1;
    (String::from_utf8_lossy(&file[..res_end]).into_owned(), &file[res_end..])
}

fn bits_equal(a: &[f32], b: &[f32]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x.to_bits() == y.to_bits()).count()
}

fn hdr_files() -> Option<Vec<PathBuf>> {
    let files = corpus_files("hdr", "hdr")?;
    assert!(!files.is_empty(), "no .hdr files in the corpus");
    Some(files)
}

#[test]
fn corpus_decodes_bit_exactly_like_oiio_and_imagecodecs() {
    let Some(py) = require(python(), "the reference Python venv (OpenImageIO, imagecodecs)") else { return };
    let Some(files) = hdr_files() else { return };
    let dir = temp_dir("rgbe_decode_oiio");
    for f in files {
        let data = std::fs::read(&f).unwrap();
        // OIIO returns the stored values: EXPOSURE is reported ("hdr:exposure") but not applied.
        let ours = RgbeCodec::raw().decode(&data, &Limits::default()).unwrap();
        let (w, h, oiio, ic) = oiio_dump(&py, &f, &dir, true, false);
        assert_eq!((w, h), (ours.width(), ours.height()), "{}", f.display());
        let n = ours.samples().len();
        let same = bits_equal(ours.samples(), &oiio);
        let same_ic = bits_equal(ours.samples(), ic.as_ref().unwrap());
        println!("{}: {w}x{h}, {same}/{n} samples bit-identical to OIIO, {same_ic}/{n} to imagecodecs", f.display());
        assert_eq!((same, same_ic, oiio.len()), (n, n, n), "{}", f.display());
        // The default decode divides by EXPOSURE; files without it decode identically.
        let dflt = decode(&data, &Limits::default(), &RgbeDecodeOptions::default()).unwrap();
        match ours.metadata_value("exposure") {
            None => assert_eq!(dflt.samples(), ours.samples()),
            Some(e) => {
                let e: f64 = e.parse().unwrap();
                let i = ours.samples().iter().position(|&v| v > 0.0).unwrap();
                let want = ours.samples()[i] as f64 / e;
                assert!((dflt.samples()[i] as f64 - want).abs() <= want * 1e-6, "{}", f.display());
            }
        }
    }
}

/// A synthetic image that exercises every RLE decision: runs of every length up to and beyond
/// 127, short runs before long ones, literals longer than 128, zeros, tiny and huge values.
fn synthetic(w: u32, h: u32) -> HdrImage {
    let mut s = Vec::with_capacity((w * h * 3) as usize);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for y in 0..h {
        let mut x = 0;
        while x < w {
            let r = rnd();
            let len = [1, 2, 3, 4, 5, 130, 200, 1][(r % 8) as usize].min(w - x);
            let v = match (r >> 8) % 5 {
                0 => [0.0; 3],
                _ => {
                    let scale = 2f32.powi(((r >> 16) % 120) as i32 - 60);
                    let f = |k: u32| ((r >> k) & 0xffff) as f32 / 65536.0 * scale;
                    [f(20), f(30), f(40)]
                }
            };
            for i in 0..len {
                // Long literal stretches: vary one channel inside some spans.
                let jitter = if (r >> 60) & 1 == 1 { (i % 7) as f32 * 1e-3 * v[0] } else { 0.0 };
                s.extend_from_slice(&[v[0] + jitter, v[1], v[2] * (1.0 + (y % 3) as f32)]);
            }
            x += len;
        }
    }
    HdrImage::new(w, h, Channels::Rgb, s, ColorInfo::default()).unwrap()
}

#[test]
fn truncating_writer_is_byte_identical_to_oiio() {
    let Some(py) = require(python(), "the reference Python venv (OpenImageIO)") else { return };
    let Some(files) = hdr_files() else { return };
    let dir = temp_dir("rgbe_write_oiio");
    let opts = RgbeEncodeOptions { rounding: Rounding::Truncate, ..Default::default() };
    let mut images: Vec<(String, HdrImage)> = vec![("synthetic 517x9".into(), synthetic(517, 9))];
    for f in files {
        let img = RgbeCodec::raw().decode(&std::fs::read(&f).unwrap(), &Limits::default()).unwrap();
        images.push((f.display().to_string(), img));
    }
    for (name, mut img) in images {
        let theirs = oiio_write(&py, img.samples(), img.width(), img.height(), &dir);
        // Same pixels and no metadata: only the header text can differ.
        img.metadata.clear();
        let ours = encode(&img, &opts).unwrap();
        let (their_head, their_px) = split_header(&theirs);
        let (our_head, our_px) = split_header(&ours);
        println!(
            "{name}: pixel data {} bytes (ours) vs {} (OIIO), identical: {}; header OIIO {:?} / ours {:?}",
            our_px.len(),
            their_px.len(),
            our_px == their_px,
            their_head,
            our_head
        );
        assert!(our_px == their_px, "{name}: pixel bytes differ from OIIO's writer");
        // The headers differ only by our SOFTWARE line.
        let without_software: String =
            our_head.lines().filter(|l| !l.starts_with("SOFTWARE=")).map(|l| format!("{l}\n")).collect();
        assert_eq!(without_software, their_head, "{name}");
    }
}

#[test]
fn our_files_read_back_in_oiio_exactly() {
    let Some(py) = require(python(), "the reference Python venv (OpenImageIO)") else { return };
    let Some(files) = hdr_files() else { return };
    let dir = temp_dir("rgbe_readback_oiio");
    let mut images = vec![synthetic(300, 7), synthetic(5, 40)];
    // One corpus photograph, scaled off the RGBE grid so that rounding matters.
    let mut photo = RgbeCodec::new().decode(&std::fs::read(&files[0]).unwrap(), &Limits::default()).unwrap();
    photo.samples_mut().iter_mut().for_each(|v| *v *= 1.37);
    images.push(photo);
    let file = dir.join("ours.hdr");
    for img in &images {
        for rounding in [Rounding::Truncate, Rounding::Nearest] {
            for rle in [true, false] {
                let opts = RgbeEncodeOptions { rounding, rle, ..Default::default() };
                let bytes = encode(img, &opts).unwrap();
                std::fs::write(&file, &bytes).unwrap();
                let ours = decode(&bytes, &Limits::default(), &RgbeDecodeOptions::default()).unwrap();
                let (w, h, oiio, _) = oiio_dump(&py, &file, &dir, false, false);
                assert_eq!((w, h), (img.width(), img.height()));
                let same = bits_equal(ours.samples(), &oiio);
                println!("{}x{} {rounding:?} rle={rle}: {same}/{} samples identical in OIIO", w, h, oiio.len());
                assert_eq!((same, oiio.len()), (ours.samples().len(), ours.samples().len()));
            }
        }
    }
}

/// Where the pixel (x, y) of the displayed image (x to the right, y down) sits in the file
/// according to the Radiance resolution string (X grows to the right, Y grows upwards; the first
/// axis is the scanline axis, its sign the direction in which scanlines follow each other, the
/// second axis runs along a scanline): returns (scanline, index along it).
fn file_position(res: &str, x: u32, y: u32, w: u32, h: u32) -> (u32, u32) {
    let t: Vec<&str> = res.split(' ').collect();
    let along = |axis: &str| match axis {
        "+X" => x,
        "-X" => w - 1 - x,
        "-Y" => y,
        "+Y" => h - 1 - y,
        _ => unreachable!(),
    };
    (along(t[0]), along(t[2]))
}

#[test]
fn all_eight_orientations() {
    let Some(py) = require(python(), "the reference Python venv (OpenImageIO)") else { return };
    let dir = temp_dir("rgbe_orient_oiio");
    // A 9x4 image stored as 4 scanlines of 9 pixels, then relabelled with each orientation.
    let img = synthetic(9, 4);
    let bytes = encode(&img, &RgbeEncodeOptions { rle: false, ..Default::default() }).unwrap();
    let stored = decode(&bytes, &Limits::default(), &RgbeDecodeOptions::default()).unwrap();
    let (head, px) = split_header(&bytes);
    let head = head.replace("-Y 4 +X 9\n", "");
    let file = dir.join("o.hdr");
    for res in ["-Y 4 +X 9", "-Y 4 -X 9", "+Y 4 -X 9", "+Y 4 +X 9", "+X 4 -Y 9", "-X 4 -Y 9", "-X 4 +Y 9", "+X 4 +Y 9"]
    {
        let mut f = format!("{head}{res}\n").into_bytes();
        f.extend_from_slice(px);
        let ours = RgbeCodec::new().decode(&f, &Limits::default()).unwrap();
        let transposed = res.starts_with(['+', '-']) && res.as_bytes()[1] == b'X';
        assert_eq!((ours.width(), ours.height()), if transposed { (4, 9) } else { (9, 4) }, "{res}");
        for y in 0..ours.height() {
            for x in 0..ours.width() {
                let (scan, i) = file_position(res, x, y, ours.width(), ours.height());
                assert_eq!(ours.pixel(x, y), stored.pixel(i, scan), "{res} ({x}, {y})");
            }
        }
        // OIIO 2.4 reports the orientation as an EXIF Orientation and `reorient` applies it;
        // it maps all four transposed strings to Orientation 5 (a bug), so only the four
        // row-major ones can be checked against it.
        if transposed {
            continue;
        }
        std::fs::write(&file, &f).unwrap();
        let (w, h, oiio, _) = oiio_dump(&py, &file, &dir, false, true);
        assert_eq!((w, h), (ours.width(), ours.height()), "{res}");
        let same = bits_equal(ours.samples(), &oiio);
        println!("{res}: {w}x{h}, {same}/{} samples as OIIO reorients them", oiio.len());
        assert_eq!(same, ours.samples().len(), "{res}");
    }
}

/// Max and mean of the per-pixel relative error |decoded - original| / max(original RGB).
fn rel_errors(orig: &HdrImage, dec: &HdrImage) -> (f64, f64) {
    let (mut max, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
    for (o, d) in orig.rgb().zip(dec.rgb()) {
        let m = o.iter().fold(0.0f32, |a, &v| a.max(v)) as f64;
        if m < 1e-30 {
            continue;
        }
        let e = o.iter().zip(&d).map(|(&a, &b)| (a as f64 - b as f64).abs()).fold(0.0, f64::max) / m;
        max = max.max(e);
        sum += e;
        n += 1;
    }
    (max, sum / n as f64)
}

#[test]
fn nearest_rounding_has_lower_error_than_truncation() {
    let Some(py) = require(python(), "the reference Python venv (OpenImageIO)") else { return };
    let Some(exrs) = corpus_files("exr", "exr") else { return };
    let dir = temp_dir("rgbe_errors");
    // Real photographs with finer-than-RGBE values: the corpus EXRs as OIIO reads them.
    for f in exrs.iter().filter(|p| p.file_name().is_some_and(|n| n == "StillLife.exr" || n == "GoldenGate.exr")) {
        let (w, h, px, _) = oiio_dump(&py, f, &dir, false, false);
        let px: Vec<f32> = px.into_iter().map(|v| v.max(0.0)).collect();
        let img = HdrImage::new(w, h, Channels::Rgb, px, ColorInfo::default()).unwrap();
        let mut errs = Vec::new();
        for (rounding, mantissa) in [
            (Rounding::Truncate, MantissaDecode::Truncated),
            (Rounding::Nearest, MantissaDecode::Truncated),
            (Rounding::Truncate, MantissaDecode::Centred),
        ] {
            let bytes = encode(&img, &RgbeEncodeOptions { rounding, ..Default::default() }).unwrap();
            let dec =
                decode(&bytes, &Limits::default(), &RgbeDecodeOptions { mantissa, ..Default::default() }).unwrap();
            let (max, mean) = rel_errors(&img, &dec);
            println!(
                "{}: encode {rounding:?} / decode {mantissa:?}: max rel err {max:.5}, mean {mean:.6}",
                f.file_name().unwrap().to_string_lossy()
            );
            errs.push((max, mean));
        }
        // Truncation loses up to one step of the largest mantissa (>= 128): < 1/128; nearest
        // half a step (1/256 of the largest when it does not round up; when it rounds up to the
        // next exponent, at most 1/255.5 of it).
        assert!(errs[0].0 < 1.0 / 128.0 && errs[1].0 <= 1.0 / 255.5, "{errs:?}");
        assert!(errs[1].0 < errs[0].0 && errs[1].1 < errs[0].1, "nearest must beat truncate: {errs:?}");
    }
}
