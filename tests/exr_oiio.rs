//! OpenEXR validated against OpenImageIO (which reads through the OpenEXR C++ library):
//! - every `*.exr` of the shared corpus decodes in hdrcodec-exr to exactly OIIO's `f32`
//!   samples (bitwise; any NaN matches any NaN) with the same size and channels;
//! - files hdrcodec-exr writes (every compression × half/float × RGB/RGBA, odd sizes) open in
//!   `exrheader` with the right compression and decode in OIIO to exactly our decoded pixels;
//! - B44/B44A at odd sizes (chunks of 1 to 3 lines, partial 4x4 blocks) decode in OIIO exactly
//!   as ours, and for RGB have the chunks OpenEXR itself writes.
//!
//! OIIO reads subimage 0, mip level 0 and returns the data window, as we do.

mod common;

use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, HdrImage, ImageCodec, Limits};
use hdrcodec_exr::{exr, ExrCodec, ExrCompression};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Reads each `IN` with OIIO and writes its R, G, B(, A) (or Y, Y, Y(, A)) channels (by name, in that order) as
/// raw float32 LE to `OUT`; prints `width height channel-count origin-x origin-y` per file.
const OIIO_DUMP: &str = r#"
import sys, numpy as np, OpenImageIO as oiio
args = sys.argv[1:]
for i in range(0, len(args), 2):
    buf = oiio.ImageBuf(args[i])
    spec = buf.spec()
    if buf.has_error:
        raise SystemExit(buf.geterror())
    px = buf.get_pixels(oiio.FLOAT)
    names = [n.upper() for n in spec.channelnames]
    want = [n for n in ("R", "G", "B", "A") if n in names]
    if not want and "Y" in names:  # luminance only: grey RGB, as hdrcodec-exr returns it
        want = ["Y", "Y", "Y"] + (["A"] if "A" in names else [])
    sel = np.ascontiguousarray(px[:, :, [names.index(n) for n in want]], dtype='<f4')
    sel.tofile(args[i + 1])
    print(spec.width, spec.height, len(want), spec.x, spec.y)
"#;

/// OIIO's view of each file: (width, height, channels, samples).
fn oiio_decode(py: &Path, files: &[PathBuf], dir: &Path) -> Vec<(u32, u32, usize, Vec<f32>)> {
    let mut args: Vec<&OsStr> = Vec::new();
    let outs: Vec<PathBuf> = (0..files.len()).map(|i| dir.join(format!("oiio_{i}.f32"))).collect();
    for (f, o) in files.iter().zip(&outs) {
        args.push(f.as_os_str());
        args.push(o.as_os_str());
    }
    let out = common::run_python(py, OIIO_DUMP, &args);
    let text = String::from_utf8(out.stdout).unwrap();
    text.lines()
        .zip(&outs)
        .map(|(line, o)| {
            let v: Vec<i64> = line.split_whitespace().map(|t| t.parse().unwrap()).collect();
            (v[0] as u32, v[1] as u32, v[2] as usize, common::read_f32_raw(o))
        })
        .collect()
}

/// Number of samples that differ (bitwise; NaN equals NaN).
fn mismatches(a: &[f32], b: &[f32]) -> usize {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).filter(|(x, y)| !(x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))).count()
}

fn is_dwa(p: &Path) -> bool {
    let name = p.file_name().unwrap().to_string_lossy().to_lowercase();
    name.contains("dwaa") || name.contains("dwab")
}

#[test]
fn corpus_exr_matches_openimageio_bit_exactly() {
    let Some(files) = common::corpus_files("exr", "exr") else { return };
    let Some(py) = common::require(common::python(), "the reference venv (.venv with OpenImageIO)") else { return };
    assert!(!files.is_empty(), "no EXR files in the corpus");
    let dir = common::temp_dir("exr_oiio_corpus");
    let reference = oiio_decode(&py, &files, &dir);
    assert_eq!(reference.len(), files.len());
    let mut total = 0usize;
    for (path, (w, h, nch, want)) in files.iter().zip(reference) {
        let data = std::fs::read(path).unwrap();
        let ours = ExrCodec.decode(&data, &Limits::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!((ours.width(), ours.height()), (w, h), "{}: size", path.display());
        assert_eq!(ours.channels().count(), nch, "{}: channels", path.display());
        let bad = mismatches(ours.samples(), &want);
        eprintln!("{}: {w}x{h}x{nch}, {} samples, {bad} differ from OIIO", path.display(), want.len());
        assert_eq!(bad, 0, "{}: {bad} of {} samples differ from OpenImageIO", path.display(), want.len());
        if is_dwa(path) {
            eprintln!("  (DWA decoded by the exr crate's DWA decoder)");
        }
        total += want.len();
    }
    eprintln!("{} corpus files, {total} samples, all bit-exact with OpenImageIO", files.len());
}

#[test]
fn corpus_colour_attributes() {
    let Some(dir) = common::require(common::corpus_dir(), "the shared HDR corpus") else { return };
    let read = |name: &str| {
        let data = std::fs::read(dir.join("exr").join(name)).unwrap();
        ExrCodec.decode(&data, &Limits::default()).unwrap()
    };
    // The corpus manifest: XYZ.exr carries CIE XYZ chromaticities, Carrots.exr ACES AP0.
    assert_eq!(read("XYZ.exr").color.primaries, ColorPrimaries::Xyz);
    assert_eq!(read("Carrots.exr").color.primaries, ColorPrimaries::AcesAp0);
    assert_eq!(read("Desk.exr").color.primaries, ColorPrimaries::Bt709);
}

/// What `exrheader` prints for each compression.
fn exrheader_name(c: ExrCompression) -> &'static str {
    match c {
        ExrCompression::None => "compression (type compression): none",
        ExrCompression::Rle => "compression (type compression): run-length encoding",
        ExrCompression::Zip1 => "compression (type compression): zip, individual scanlines",
        ExrCompression::Zip16 => "compression (type compression): zip, multi-scanline blocks",
        ExrCompression::Piz => "compression (type compression): piz",
        ExrCompression::Pxr24 => "compression (type compression): pxr24",
        ExrCompression::B44 => "compression (type compression): b44\n",
        ExrCompression::B44A => "compression (type compression): b44a",
        ExrCompression::Dwaa => "compression (type compression): dwa, small scanline blocks",
        ExrCompression::Dwab => "compression (type compression): dwa, medium scanline blocks",
    }
}

/// A deterministic HDR test picture: values over ~9 orders of magnitude, negatives, and an
/// alpha ramp.
fn test_image(w: u32, h: u32, channels: Channels) -> HdrImage {
    let n = channels.count();
    let mut s = Vec::with_capacity((w * h) as usize * n);
    for y in 0..h {
        for x in 0..w {
            let t = (x as f32 + 0.37) / w as f32;
            let u = (y as f32 + 0.61) / h as f32;
            s.push(10f32.powf(9.0 * t - 4.0));
            s.push((u * 7.3).sin() * 3.0);
            s.push(t * u * 0.125 + ((x ^ y) % 7) as f32 * 0.01);
            if n == 4 {
                s.push(u);
            }
        }
    }
    HdrImage::new(w, h, channels, s, ColorInfo::default()).unwrap()
}

#[test]
fn written_files_open_in_exrheader_and_openimageio() {
    let Some(exrheader) = common::require(common::tool("exrheader"), "exrheader (Debian openexr)") else { return };
    let Some(py) = common::require(common::python(), "the reference venv (.venv with OpenImageIO)") else { return };
    let dir = common::temp_dir("exr_oiio_written");
    let mut files = Vec::new();
    let mut ours = Vec::new();
    for (i, c) in ExrCompression::ALL.into_iter().enumerate() {
        for pixel in ["half", "float"] {
            for channels in [Channels::Rgb, Channels::Rgba] {
                // Odd sizes: partial 32- and 256-line blocks, partial B44/DWA 4x4 and 8x8 blocks.
                let (w, h) = (37 + 2 * i as u32, 45 + 26 * (i as u32 % 3));
                let img = test_image(w, h, channels);
                let settings =
                    EncodeSettings::default().with_option("compression", c.name()).with_option("pixel", pixel);
                let bytes = ExrCodec.encode(&img, &settings).unwrap();
                let path = dir.join(format!("{}_{pixel}_{}.exr", c.name(), channels.count()));
                std::fs::write(&path, &bytes).unwrap();
                let header = common::run_ok(Command::new(&exrheader).arg(&path));
                let text = String::from_utf8_lossy(&header.stdout);
                assert!(text.contains(exrheader_name(c)), "{}: exrheader shows\n{text}", path.display());
                let expected_type = if pixel == "half" { "16-bit floating-point" } else { "32-bit floating-point" };
                assert!(text.contains(expected_type), "{}: exrheader shows\n{text}", path.display());
                let back = ExrCodec.decode(&bytes, &Limits::default()).unwrap();
                let lossless = if pixel == "half" { c.is_lossless_for_half() } else { c.is_lossless_for_float() };
                if lossless {
                    // The input quantised to the written type is what must come back.
                    let q: Vec<f32> = img
                        .samples()
                        .iter()
                        .map(|&v| if pixel == "half" { exr::prelude::f16::from_f32(v).to_f32() } else { v })
                        .collect();
                    assert_eq!(mismatches(back.samples(), &q), 0, "{}: not lossless", path.display());
                }
                files.push(path);
                ours.push(back);
            }
        }
    }
    let reference = oiio_decode(&py, &files, &dir);
    for ((path, back), (w, h, nch, want)) in files.iter().zip(&ours).zip(reference) {
        assert_eq!((back.width(), back.height(), back.channels().count()), (w, h, nch), "{}", path.display());
        let bad = mismatches(back.samples(), &want);
        assert_eq!(bad, 0, "{}: {bad} of {} samples differ between OIIO and us", path.display(), want.len());
    }
    eprintln!("{} written files: exrheader OK, OIIO pixels identical to ours", files.len());
}

/// The pixel data of each scan-line chunk of `bytes`, in file order.
fn chunk_payloads(bytes: &[u8]) -> Vec<Vec<u8>> {
    use exr::block::chunk::CompressedBlock;
    let reader = exr::block::read(std::io::Cursor::new(bytes), true).unwrap();
    let chunks = reader.all_chunks(true).unwrap();
    chunks
        .map(|c| match c.unwrap().compressed_block {
            CompressedBlock::ScanLine(b) => b.compressed_pixels_le,
            other => panic!("not a scan-line chunk: {other:?}"),
        })
        .collect()
}

/// B44/B44A at sizes whose 4x4 blocks are cut by the image edges, including those with a chunk
/// exr 1.74.2 cannot pack (fewer than 4 lines wide enough to pass 2048 bytes, e.g. the last
/// line of 257x129; hdrcodec-exr stores such a chunk raw, as OpenEXR does). Each file shows the
/// true data window in `exrheader` and decodes in OIIO exactly as in hdrcodec-exr. For RGB, the
/// chunks are byte-identical to those OpenEXR itself writes for the same half pixels (`oiiotool
/// --compression`; with alpha they differ because OIIO drops the `pLinear` flag `exr` sets on A).
#[test]
fn b44_at_odd_sizes_matches_openimageio() {
    let Some(exrheader) = common::require(common::tool("exrheader"), "exrheader (Debian openexr)") else { return };
    let Some(oiiotool) = common::require(common::tool("oiiotool"), "oiiotool (Debian openimageio-tools)") else {
        return;
    };
    let Some(py) = common::require(common::python(), "the reference venv (.venv with OpenImageIO)") else { return };
    let dir = common::temp_dir("exr_oiio_b44");
    let sizes = [(1, 1), (3, 5), (2, 97), (19, 33), (257, 13), (257, 129), (145, 65), (1000, 7), (1000, 33)];
    let (mut files, mut ours, mut identical) = (Vec::new(), Vec::new(), 0);
    for (w, h) in sizes {
        for channels in [Channels::Rgb, Channels::Rgba] {
            let img = test_image(w, h, channels);
            let n = channels.count();
            let half = |c: ExrCompression| {
                EncodeSettings::default().with_option("compression", c.name()).with_option("pixel", "half")
            };
            let none = dir.join(format!("none_{w}x{h}_{n}.exr"));
            std::fs::write(&none, ExrCodec.encode(&img, &half(ExrCompression::None)).unwrap()).unwrap();
            for c in [ExrCompression::B44, ExrCompression::B44A] {
                let bytes = ExrCodec.encode(&img, &half(c)).unwrap_or_else(|e| panic!("{c} {w}x{h}x{n}: {e}"));
                let path = dir.join(format!("{c}_{w}x{h}_{n}.exr"));
                std::fs::write(&path, &bytes).unwrap();
                let header = common::run_ok(Command::new(&exrheader).arg(&path));
                let text = String::from_utf8_lossy(&header.stdout);
                assert!(text.contains(exrheader_name(c)), "{}: exrheader shows\n{text}", path.display());
                let window = format!("dataWindow (type box2i): (0 0) - ({} {})", w - 1, h - 1);
                assert!(text.contains(&window), "{}: exrheader shows\n{text}", path.display());
                if channels == Channels::Rgb {
                    let theirs = dir.join(format!("openexr_{c}_{w}x{h}_{n}.exr"));
                    common::run_ok(
                        Command::new(&oiiotool).arg(&none).args(["--compression", c.name(), "-o"]).arg(&theirs),
                    );
                    let theirs = chunk_payloads(&std::fs::read(&theirs).unwrap());
                    assert!(chunk_payloads(&bytes) == theirs, "{}: chunks differ from OpenEXR's", path.display());
                    identical += 1;
                }
                ours.push(ExrCodec.decode(&bytes, &Limits::default()).unwrap());
                files.push(path);
            }
        }
    }
    let reference = oiio_decode(&py, &files, &dir);
    for ((path, back), (w, h, nch, want)) in files.iter().zip(&ours).zip(reference) {
        assert_eq!((back.width(), back.height(), back.channels().count()), (w, h, nch), "{}", path.display());
        let bad = mismatches(back.samples(), &want);
        assert_eq!(bad, 0, "{}: {bad} of {} samples differ between OIIO and us", path.display(), want.len());
    }
    eprintln!(
        "{} B44/B44A files: OIIO pixels identical to ours; {identical} RGB files chunk-identical to OpenEXR's",
        files.len()
    );
}

/// PFM, checked against OpenImageIO's PFM reader: a PFM written by pfstools (`pfsinexr |
/// pfsoutpfm`) decodes in hdrcodec-pfm exactly as OIIO reads it, and the PFM we write from a
/// corpus EXR reads in OIIO exactly as our EXR decode (the `convert a.exr b.pfm` path).
#[test]
fn pfm_matches_openimageio() {
    use hdrcodec_pfm::PfmCodec;
    let Some(dir) = common::require(common::corpus_dir(), "the shared HDR corpus") else { return };
    let Some(py) = common::require(common::python(), "the reference venv (.venv with OpenImageIO)") else { return };
    let Some(pfsinexr) = common::require(common::tool("pfsinexr"), "pfsinexr (Debian pfstools)") else { return };
    let Some(pfsoutpfm) = common::require(common::tool("pfsoutpfm"), "pfsoutpfm (Debian pfstools)") else { return };
    let tmp = common::temp_dir("exr_oiio_pfm");
    let src = dir.join("exr/XYZ.exr");
    let theirs = tmp.join("pfstools.pfm");
    let pipe =
        format!("'{}' '{}' | '{}' '{}'", pfsinexr.display(), src.display(), pfsoutpfm.display(), theirs.display());
    common::run_ok(Command::new("sh").arg("-c").arg(pipe));
    let exr = ExrCodec.decode(&std::fs::read(&src).unwrap(), &Limits::default()).unwrap();
    let ours = tmp.join("ours.pfm");
    std::fs::write(&ours, PfmCodec.encode(&exr, &EncodeSettings::default()).unwrap()).unwrap();
    let reference = oiio_decode(&py, &[theirs.clone(), ours], &tmp);

    let (w, h, nch, want) = &reference[0];
    let got = PfmCodec.decode(&std::fs::read(&theirs).unwrap(), &Limits::default()).unwrap();
    assert_eq!((got.width(), got.height(), got.channels().count()), (*w, *h, *nch));
    assert_eq!(mismatches(got.samples(), want), 0, "pfstools PFM: our decode differs from OIIO");

    let (w, h, nch, want) = &reference[1];
    assert_eq!((exr.width(), exr.height(), 3), (*w, *h, *nch));
    assert_eq!(mismatches(exr.samples(), want), 0, "our PFM read by OIIO differs from our EXR decode");
    eprintln!("PFM: pfstools file ({w}x{h}) and our file both bit-exact with OIIO");
}

/// Files with what the corpus lacks, written by `oiiotool` (OpenEXR's own writer): data windows
/// away from the origin (positive and negative), a luminance-only Y file, a tiled mip-map of
/// odd size (levels rounded down), ZIP/PIZ/none, half and float. Each must decode exactly as OIIO
/// reads it (the data window, mip level 0).
#[test]
fn oiiotool_variants_match_openimageio() {
    let Some(oiiotool) = common::require(common::tool("oiiotool"), "oiiotool (Debian openimageio-tools)") else {
        return;
    };
    let Some(py) = common::require(common::python(), "the reference venv (.venv with OpenImageIO)") else { return };
    let dir = common::temp_dir("exr_oiio_variants");
    let fill = "fill:top=0.1,0.2,0.3,1:bottom=5,6,700,0.5";
    let variants: [(&str, &[&str]); 4] = [
        ("window.exr", &["--pattern", fill, "21x13", "3", "-d", "half", "--origin", "+5+3", "--fullsize", "40x30"]),
        ("negative.exr", &["--pattern", fill, "21x13", "4", "-d", "float", "--origin", "-4-7", "--compression", "piz"]),
        ("luminance.exr", &["--pattern", "fill:top=0.01:bottom=300", "9x7", "1", "--chnames", "Y", "-d", "float"]),
        (
            "mipmap.exr",
            &[
                "--pattern",
                "checker:color1=0.1,0.5,2:color2=9,0.01,0",
                "37x23",
                "3",
                "-d",
                "half",
                "--tile",
                "16",
                "16",
            ],
        ),
    ];
    let mut files = Vec::new();
    for (name, args) in variants {
        let path = dir.join(name);
        let mut cmd = Command::new(&oiiotool);
        cmd.args(args);
        if name == "mipmap.exr" {
            cmd.arg("-otex:fileformatname=openexr");
        } else {
            cmd.arg("-o");
        }
        common::run_ok(cmd.arg(&path));
        files.push(path);
    }
    let reference = oiio_decode(&py, &files, &dir);
    for (path, (w, h, nch, want)) in files.iter().zip(reference) {
        let ours = ExrCodec.decode(&std::fs::read(path).unwrap(), &Limits::default()).unwrap();
        assert_eq!((ours.width(), ours.height(), ours.channels().count()), (w, h, nch), "{}", path.display());
        assert_eq!(mismatches(ours.samples(), &want), 0, "{}: differs from OIIO", path.display());
    }
    let window = ExrCodec.decode(&std::fs::read(&files[0]).unwrap(), &Limits::default()).unwrap();
    assert_eq!(window.metadata_value("exr.data_window"), Some("5 3 25 15"));
    assert_eq!(window.metadata_value("exr.display_window"), Some("0 0 39 29"));
    eprintln!("{} oiiotool variants bit-exact with OIIO", files.len());
}
