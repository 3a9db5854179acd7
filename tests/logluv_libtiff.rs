//! hdrcodec-logluv against libtiff itself (tif_luv.c), through the C harness
//! tests/harness/logluv_libtiff.c compiled here with `cc ... -ltiff`:
//! - every LogLuv TIFF of the shared corpus decodes to the same words and bit-identical XYZ;
//! - files we write decode in libtiff to exactly our pixels (every LogL16 code, every LogLuv24
//!   u'v' cell, every LogLuv32 u'v' pair);
//! - our pixel encoders give libtiff's words (SGILOGENCODE_NODITHER) over a dense sweep of
//!   luminances 1e-20 .. 1e19 and chromaticities inside and outside the gamut;
//! - the luminance step and range of each encoding, against the published figures;
//! - a LogLuv24 file of the generated "sun-sky" scene, whose STONITS our encoder chose so that
//!   the sun is not clipped, gives in libtiff (Y in file units times the STONITS libtiff reads)
//!   exactly our decoded absolute luminance, and the sun's;
//! - truncated and corrupted corpus files give errors, never panics.

mod common;

use hdrcodec_core::{ColorPrimaries, EncodeSettings, ImageCodec, Limits};
use hdrcodec_logluv::{decode, read_tiff, DecodeOptions, Encoding, LogLuvRaster, LogLuvTiffCodec};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// The compiled harness, built once per test run; `None` (skip, or panic in CI) without cc/libtiff.
fn harness() -> Option<PathBuf> {
    static BIN: OnceLock<Option<PathBuf>> = OnceLock::new();
    BIN.get_or_init(|| {
        let cc = common::require(common::tool("cc"), "a C compiler (cc) for the libtiff harness")?;
        let dir = common::temp_dir("logluv_harness");
        let bin = dir.join("logluv_libtiff");
        let src = common::workspace_root().join("tests/harness/logluv_libtiff.c");
        let out = Command::new(cc).arg("-O2").arg("-o").arg(&bin).arg(&src).arg("-ltiff").output().ok()?;
        if !out.status.success() {
            eprintln!("{}", String::from_utf8_lossy(&out.stderr));
        }
        common::require(out.status.success().then_some(bin), "libtiff-dev (the harness did not build)")
    })
    .clone()
}

fn run(bin: &Path, args: &[&dyn AsRef<std::ffi::OsStr>]) -> String {
    let mut cmd = Command::new(bin);
    for a in args {
        cmd.arg(a);
    }
    String::from_utf8(common::run_ok(&mut cmd).stdout).unwrap()
}

fn read_u32_raw(path: &Path) -> Vec<u32> {
    std::fs::read(path).unwrap().chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap())).collect()
}

fn write_f32_raw(path: &Path, v: &[f32]) {
    std::fs::write(path, v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
}

/// libtiff's FLOAT decode of a file: the floats.
fn libtiff_floats(bin: &Path, tif: &Path, dir: &Path) -> Vec<f32> {
    let raw = dir.join(format!("{}.f32", tif.file_name().unwrap().to_string_lossy()));
    run(bin, &[&"decode", &tif, &raw]);
    common::read_f32_raw(&raw)
}

/// libtiff's raw words of a file.
fn libtiff_words(bin: &Path, tif: &Path, dir: &Path) -> Vec<u32> {
    let raw = dir.join(format!("{}.u32", tif.file_name().unwrap().to_string_lossy()));
    run(bin, &[&"words", &tif, &raw]);
    read_u32_raw(&raw)
}

/// Number of positions where the bit patterns differ, and the first few of them.
fn bit_mismatches(a: &[f32], b: &[f32]) -> (usize, Vec<(usize, f32, f32)>) {
    assert_eq!(a.len(), b.len());
    let bad: Vec<_> = a.iter().zip(b).enumerate().filter(|(_, (x, y))| x.to_bits() != y.to_bits()).collect();
    (bad.len(), bad.iter().take(5).map(|(i, (x, y))| (*i, **x, **y)).collect())
}

#[test]
fn corpus_logluv_tiffs_decode_bit_identically_to_libtiff() {
    let Some(bin) = harness() else { return };
    let Some(files) = common::corpus_files("tiff", "tif") else { return };
    let dir = common::temp_dir("logluv_corpus");
    let logluv: Vec<_> =
        files.iter().filter(|f| read_tiff(&std::fs::read(f).unwrap(), &Limits::none()).is_ok()).collect();
    assert!(logluv.len() >= 4, "expected the 4 LogLuv TIFFs of the corpus, found {logluv:?}");
    for f in files {
        let ours = read_tiff(&std::fs::read(&f).unwrap(), &Limits::default())
            .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let words = libtiff_words(&bin, &f, &dir);
        let floats = libtiff_floats(&bin, &f, &dir);
        let word_diff = ours.words.iter().zip(&words).filter(|(a, b)| a != b).count();
        let (n, first) = bit_mismatches(&ours.to_floats(), &floats);
        println!(
            "{}: {:?} {}x{} STONITS {:?}: {} words, {word_diff} differ; {} floats, {n} differ bitwise",
            f.file_name().unwrap().to_string_lossy(),
            ours.encoding,
            ours.width,
            ours.height,
            ours.stonits,
            words.len(),
            floats.len()
        );
        assert_eq!(words.len(), ours.words.len());
        assert_eq!(word_diff, 0, "{}", f.display());
        assert_eq!(n, 0, "{}: first mismatches (index, ours, libtiff) {first:?}", f.display());
        // The HdrImage path in XYZ gives the same floats (LogL: R = G = B = Y).
        let img = decode(
            &std::fs::read(&f).unwrap(),
            &Limits::default(),
            &DecodeOptions { primaries: ColorPrimaries::Xyz, ..Default::default() },
        )
        .unwrap();
        let c = ours.encoding.float_channels();
        let from_img: Vec<f32> = img.rgb().flat_map(|p| p[..c].to_vec()).collect();
        assert_eq!(bit_mismatches(&from_img, &floats).0, 0);
        if let Some(s) = ours.stonits {
            assert_eq!(img.color.nits_per_unit, s as f32);
        }
    }
}

/// A raster of all the given words, `width` wide (the last row padded with its first word).
fn raster_of(encoding: Encoding, mut words: Vec<u32>, width: u32) -> LogLuvRaster {
    let w = width as usize;
    let pad = (w - words.len() % w) % w;
    words.extend(std::iter::repeat_n(words[0], pad));
    let height = (words.len() / w) as u32;
    LogLuvRaster { width, height, encoding, words, stonits: Some(179.0) }
}

/// Every LogL16 code, every LogLuv24 u'v' cell (and the invalid indices past the grid) at
/// several luminances plus every 10-bit luminance, every LogLuv32 (u', v') pair at several
/// luminances plus every 16-bit luminance code.
fn code_sweeps() -> Vec<LogLuvRaster> {
    let l16: Vec<u32> = (0..=0xffff).collect();
    let mut l24: Vec<u32> = (0..0x400).map(|l| l << 14 | 8000).collect();
    for l in [1, 300, 768, 1023] {
        l24.extend((0..0x4000).map(|c| l << 14 | c));
    }
    let mut l32: Vec<u32> = (0..=0xffff).map(|l| l << 16 | 0x56c2).collect();
    for l in [1u32, 0x3000, 0x4000, 0x7fff, 0x8000 | 0x4000] {
        l32.extend((0..=0xffff).map(|c| l << 16 | c));
    }
    vec![
        raster_of(Encoding::LogL16, l16, 509),
        raster_of(Encoding::LogLuv24, l24, 333),
        raster_of(Encoding::LogLuv32, l32, 1024),
    ]
}

#[test]
fn files_we_write_decode_in_libtiff_to_exactly_our_pixels() {
    let Some(bin) = harness() else { return };
    let dir = common::temp_dir("logluv_ours_in_libtiff");
    for raster in code_sweeps() {
        let path = dir.join(format!("{}.tif", raster.encoding.name()));
        std::fs::write(&path, raster.to_tiff().unwrap()).unwrap();
        let theirs = libtiff_floats(&bin, &path, &dir);
        let (n, first) = bit_mismatches(&raster.to_floats(), &theirs);
        println!(
            "{:?}: {} pixels written by us, {} floats decoded by libtiff, {n} differ bitwise",
            raster.encoding,
            raster.words.len(),
            theirs.len()
        );
        assert_eq!(n, 0, "{:?}: first mismatches (index, ours, libtiff) {first:?}", raster.encoding);
        assert_eq!(libtiff_words(&bin, &path, &dir), raster.words, "{:?} words", raster.encoding);
    }
}

/// A small deterministic generator (SplitMix64) for the sweeps.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// XYZ of luminance `y` at CIE 1976 chromaticity (u', v').
fn xyz_of(y: f64, u: f64, v: f64) -> [f32; 3] {
    [(y * 9.0 * u / (4.0 * v)) as f32, y as f32, (y * (12.0 - 3.0 * u - 20.0 * v) / (4.0 * v)) as f32]
}

/// The sweep: luminances log-spaced from 1e-20 to 1e19 (8 per LogL16 step) and their negatives,
/// the exact clamping thresholds and their f32 neighbours, then a u'v' grid of 0.0007 steps over
/// [-0.05, 0.7] x [-0.05, 0.65] (in and out of gamut) at random luminances, then random XYZ with
/// negative components.
fn xyz_sweep() -> Vec<f32> {
    let mut rng = Rng(0x1098);
    let mut out = Vec::new();
    let (lo, hi) = (1e-20f64.log2(), 1e19f64.log2());
    let steps = ((hi - lo) * 256.0 * 8.0) as usize;
    for k in 0..=steps {
        let y = (lo + (hi - lo) * k as f64 / steps as f64).exp2();
        let (u, v) = (0.15 + 0.1 * rng.unit(), 0.4 + 0.1 * rng.unit());
        out.extend(xyz_of(y, u, v));
        out.extend(xyz_of(-y, u, v));
    }
    for t in [1.8371976e19f32, 5.4136769e-20, 15.742, 0.00024283, 0.0, 1.0, 2.0, 0.5] {
        for y in [t, f32::from_bits(t.to_bits() + 1), f32::from_bits(t.to_bits().saturating_sub(1)), -t] {
            out.extend([y, y, y]);
        }
    }
    let n = (0.75f64 / 0.0007) as usize;
    for i in 0..=n {
        for j in 0..=n {
            let (u, v) = (-0.05 + 0.0007 * i as f64, -0.05 + 0.0007 * j as f64);
            let y = (-12.0 + 16.0 * rng.unit()).exp2();
            let p = xyz_of(y, u, v);
            if p.iter().all(|c| c.is_finite()) {
                out.extend(p);
            }
        }
    }
    for _ in 0..200_000 {
        let mut c = || ((rng.unit() - 0.2) * (-30.0 + 40.0 * rng.unit()).exp2()) as f32;
        out.extend([c(), c(), c()]);
    }
    out
}

#[test]
fn pixel_encoders_match_libtiff_bit_exactly_over_a_dense_sweep() {
    let Some(bin) = harness() else { return };
    let dir = common::temp_dir("logluv_encode_sweep");
    let xyz = xyz_sweep();
    for encoding in [Encoding::LogL16, Encoding::LogLuv24, Encoding::LogLuv32] {
        let floats: Vec<f32> = match encoding {
            Encoding::LogL16 => xyz.chunks_exact(3).map(|p| p[1]).collect(),
            _ => xyz.clone(),
        };
        let c = encoding.float_channels();
        let width = 1000u32;
        let pixels = floats.len() / c / width as usize * width as usize;
        let floats = &floats[..pixels * c];
        let height = (pixels / width as usize) as u32;
        let raw = dir.join(format!("{}.f32", encoding.name()));
        let tif = dir.join(format!("{}.tif", encoding.name()));
        write_f32_raw(&raw, floats);
        run(&bin, &[&"encode", &encoding.name(), &width.to_string(), &height.to_string(), &raw, &tif]);
        let theirs = libtiff_words(&bin, &tif, &dir);
        // A big-endian file (libtiff's "wb"): our reader gives libtiff's words. (They are not
        // the words above: libtiff byte-swaps the caller's float scanlines of a byte-swapped
        // file before its LogLuv encoder sees them, so it encodes other numbers.)
        let tif_be = dir.join(format!("{}_be.tif", encoding.name()));
        run(&bin, &[&"encode", &encoding.name(), &width.to_string(), &height.to_string(), &raw, &tif_be, &"big"]);
        let be = std::fs::read(&tif_be).unwrap();
        assert!(be.starts_with(b"MM\0*"));
        let be_words = read_tiff(&be, &Limits::default()).unwrap();
        assert_eq!(be_words.words, libtiff_words(&bin, &tif_be, &dir), "{encoding:?} big-endian");
        assert_eq!(bit_mismatches(&be_words.to_floats(), &libtiff_floats(&bin, &tif_be, &dir)).0, 0);
        let ours = LogLuvRaster::from_floats(width, height, encoding, floats).unwrap();
        let bad: Vec<usize> = (0..pixels).filter(|&i| ours.words[i] != theirs[i]).collect();
        let code = |w: &u32| match encoding {
            Encoding::LogL16 => w & 0x7fff,
            Encoding::LogLuv24 => w >> 14,
            Encoding::LogLuv32 => w >> 16 & 0x7fff,
        };
        println!(
            "{encoding:?}: {pixels} pixels encoded by both, {} words differ (luminance codes {} .. {} used)",
            bad.len(),
            ours.words.iter().map(code).min().unwrap(),
            ours.words.iter().map(code).max().unwrap()
        );
        let show: Vec<_> = bad.iter().take(5).map(|&i| (&floats[i * c..i * c + c], ours.words[i], theirs[i])).collect();
        assert!(bad.is_empty(), "{encoding:?}: (xyz, ours, libtiff) {show:x?}");
        // Our reader parses libtiff's file to the same words.
        let parsed = read_tiff(&std::fs::read(&tif).unwrap(), &Limits::default()).unwrap();
        assert_eq!(parsed.words, theirs);
    }
}

#[test]
fn luminance_steps_and_ranges_match_the_published_figures() {
    let Some(bin) = harness() else { return };
    let dir = common::temp_dir("logluv_steps");
    // Decoded luminance of every valid luminance code, as libtiff decodes our code sweeps.
    let sweeps = code_sweeps();
    let mut y_of = Vec::new();
    for r in [&sweeps[0], &sweeps[1]] {
        let path = dir.join(format!("{}.tif", r.encoding.name()));
        std::fs::write(&path, r.to_tiff().unwrap()).unwrap();
        y_of.push(libtiff_floats(&bin, &path, &dir));
    }
    // LogL16 (the luminance of LogLuv32): codes 1 ..= 0x7fff are pixels 1 ..= 0x7fff.
    let l16: Vec<f64> = (1..=0x7fff).map(|k| f64::from(y_of[0][k])).collect();
    // LogLuv24: codes 1 ..= 1023 are the first 1024 pixels (Y is the middle float).
    let l10: Vec<f64> = (1..0x400).map(|k| f64::from(y_of[1][3 * k + 1])).collect();
    let report = |name: &str, ys: &[f64]| {
        let step = ys.windows(2).map(|w| w[1] / w[0] - 1.0).fold(0.0, f64::max);
        let orders = (ys[ys.len() - 1] / ys[0]).log10();
        println!(
            "{name}: max relative luminance step {:.4} %, range {:.2} orders of magnitude ({:.3e} .. {:.3e})",
            100.0 * step,
            orders,
            ys[0],
            ys[ys.len() - 1]
        );
        (step, orders)
    };
    // Seed course / Larson 1998: LogLuv32 has 0.3 % steps over 36+ orders of magnitude
    // (1/256 stop = 0.27 %, 2^-64 .. 2^64 ≈ 38 orders).
    let (step32, orders32) = report("LogLuv32 / LogL16", &l16);
    assert!(step32 < 0.003 && (step32 - 0.0027).abs() < 0.0001, "{step32}");
    assert!(orders32 > 36.0, "{orders32}");
    // LogLuv24 by its definition (Larson 1998, 10-bit log2 in 1/64 stops): steps of
    // 2^(1/64) - 1 = 1.09 % over 1023/64 stops = 4.8 orders of magnitude.
    let (step24, orders24) = report("LogLuv24", &l10);
    assert!((step24 - 0.011).abs() < 0.0005, "{step24}");
    assert!((orders24 - 4.8).abs() < 0.05, "{orders24}");
}

/// libtiff's reading of the STONITS tag of a file.
fn libtiff_stonits(bin: &Path, tif: &Path) -> Option<f64> {
    let out = run(bin, &[&"stonits", &tif]);
    let t = out.trim();
    (t != "none").then(|| t.parse().unwrap_or_else(|_| panic!("harness printed {t:?}")))
}

#[test]
fn an_auto_scaled_logluv24_file_gives_libtiff_our_absolute_luminance() {
    let Some(bin) = harness() else { return };
    let dir = common::temp_dir("logluv_stonits");
    let scene = hdrcodec_cli::corpus::scene("sun-sky").expect("the generated corpus has sun-sky");
    let img = scene.image;
    let codec = LogLuvTiffCodec::new(Encoding::LogLuv24);
    let mut file = Vec::new();
    let report = codec.encode_to(&img, &EncodeSettings::default(), &mut file).unwrap();
    let path = dir.join("sun-sky.tif");
    std::fs::write(&path, &file).unwrap();
    let stonits = libtiff_stonits(&bin, &path).expect("STONITS written");
    println!("sun-sky as LogLuv24: libtiff reads STONITS {stonits}; our notes: {:?}", report.notes);
    // The scale was moved away from the image's 100 cd/m² per unit, and said so.
    assert!(stonits > 1000.0, "{stonits}");
    assert!(report.notes.iter().any(|n| n.contains("stonits=auto")), "{:?}", report.notes);
    let ours = codec.decode(&file, &Limits::default()).unwrap();
    assert_eq!(f64::from(ours.color.nits_per_unit), stonits);
    // libtiff's FLOAT decode is XYZ in file units; times its STONITS, cd/m².
    let theirs = libtiff_floats(&bin, &path, &dir);
    let xyz =
        decode(&file, &Limits::default(), &DecodeOptions { primaries: ColorPrimaries::Xyz, ..Default::default() })
            .unwrap();
    let ours_xyz: Vec<f32> = xyz.rgb().flatten().collect();
    assert_eq!(bit_mismatches(&ours_xyz, &theirs).0, 0);
    let their_nits: Vec<f64> = theirs.chunks_exact(3).map(|p| f64::from(p[1]) * stonits).collect();
    let our_nits = hdrcodec::luminance(&ours);
    let source_nits = hdrcodec::luminance(&img);
    let (mut worst_vs_libtiff, mut worst_vs_source, mut bright) = (0.0f64, 0.0f64, 0);
    for ((t, o), s) in their_nits.iter().zip(&our_nits).zip(&source_nits) {
        // Ours goes through BT.709 and back to Y: equal to a few f32 ulps.
        worst_vs_libtiff = worst_vs_libtiff.max((o - t).abs() / t.max(1e-30));
        if *s > 1e4 {
            bright += 1;
            worst_vs_source = worst_vs_source.max((t / s - 1.0).abs());
        }
    }
    println!(
        "{bright} pixels above 1e4 cd/m² (peak {:.4e}): libtiff's luminance within {:.3} % of the source; \
         ours within {:.1e} of libtiff's",
        source_nits.iter().copied().fold(0.0, f64::max),
        100.0 * worst_vs_source,
        worst_vs_libtiff
    );
    assert!(bright > 50, "{bright}");
    assert!(worst_vs_libtiff < 1e-5, "{worst_vs_libtiff}");
    // LogLuv24 codes luminance in 1/64-stop steps: within half a step, 0.55 %.
    assert!(worst_vs_source < 0.0055, "{worst_vs_source}");
}

/// Prefix lengths for the truncation sweep of a file of `len` bytes: every length up to 2048,
/// then 1500 spread over the rest, plus the end itself minus a few bytes.
fn cut_points(len: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..len.min(2048)).collect();
    v.extend((0..1500).map(|k| 2048 + (len.saturating_sub(2048)) * k / 1500).filter(|&c| c < len));
    v.extend(len.saturating_sub(16)..len);
    v
}

#[test]
fn truncated_and_corrupted_corpus_tiffs_are_errors_not_panics() {
    let Some(files) = common::corpus_files("tiff", "tif") else { return };
    let limits = Limits::fuzzing();
    let mut rng = Rng(7);
    for f in files {
        let data = std::fs::read(&f).unwrap();
        let full = read_tiff(&data, &limits).unwrap();
        // Read from the file (libtiff's layout: the IFD before the strips) instead of from
        // its bytes: the same image, and on a sample of prefixes the same outcome.
        let whole = decode(&data, &limits, &DecodeOptions::default()).unwrap();
        let from_file = |d: &[u8]| {
            let mut sink = hdrcodec_core::sink::ImageSink::new(&limits);
            hdrcodec_logluv::decode_rows_from(
                &mut std::io::Cursor::new(d),
                &limits,
                &DecodeOptions::default(),
                &mut sink,
            )
            .and_then(|()| sink.finish())
        };
        assert_eq!(from_file(&data).unwrap().samples(), whole.samples(), "{}", f.display());
        for cut in cut_points(data.len()).into_iter().step_by(50) {
            let mem = decode(&data[..cut], &limits, &DecodeOptions::default()).map(|i| i.samples().to_vec());
            let file = from_file(&data[..cut]).map(|i| i.samples().to_vec());
            assert_eq!(file.is_ok(), mem.is_ok(), "{}: {cut}-byte prefix", f.display());
            if let (Ok(a), Ok(b)) = (&mem, &file) {
                assert!(a == b, "{}: {cut}-byte prefix decoded to something else", f.display());
            }
        }
        let (mut errors, mut same) = (0, 0);
        for cut in cut_points(data.len()) {
            // A prefix is an error, unless all it lost is bytes the decoder does not use (the
            // last values of an unused tag, say): then it must give exactly the full image.
            match read_tiff(&data[..cut], &limits) {
                Err(_) => errors += 1,
                Ok(r) => {
                    assert_eq!(r, full, "{}: a {cut}-byte prefix decoded to something else", f.display());
                    same += 1;
                }
            }
        }
        // Each corrupted copy is decoded in full: fewer copies of the megapixel file.
        let copies = if data.len() > 1 << 20 { 200 } else { 3000 };
        let mut corrupted_ok = 0;
        for _ in 0..copies {
            let mut d = data.clone();
            for _ in 0..1 + rng.next() % 4 {
                let i = (rng.next() % d.len() as u64) as usize;
                d[i] = rng.next() as u8;
            }
            // Corruption anywhere: an error or some image, never a panic.
            if decode(&d, &limits, &DecodeOptions::default()).is_ok() {
                corrupted_ok += 1;
            }
        }
        println!(
            "{}: {errors} truncated prefixes rejected, {same} lost only unused bytes and decoded identically; \
             {corrupted_ok}/{copies} corrupted copies still decoded",
            f.display()
        );
        assert!(errors > same, "{}", f.display());
    }
}
