//! What the benches share (each uses some of it): finding the
//! corpus and tools, saying what is missing, the GoldenGate images and their 13 MP mosaics,
//! and timing a tool out of process.
use hdrcodec_core::{DecodeOptions, HdrImage, ImageCodec, Limits, ThreadPool};
use hdrcodec_jxr::{decode_raw, JxrCodec};
use std::path::{Path, PathBuf};
use std::process::Command;

/// In CI a missing peer or corpus is a failure; elsewhere the bench (`bench`) says what it
/// skips.
pub fn missing(bench: &str, what: &str) {
    if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") {
        panic!("{what} is missing; CI must have it (run scripts/setup-reference-tools.sh)");
    }
    eprintln!("{bench} bench: {what} is missing (run scripts/setup-reference-tools.sh); skipped");
}

/// The shared corpus, found as tests/common does: `$HDRCODEC_CORPUS`, else `../shared/corpus`
/// beside the workspace.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("HDRCODEC_CORPUS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/corpus"));
    dir.join("MANIFEST.tsv").is_file().then_some(dir)
}

/// [`corpus_dir`], or `None` after saying (through [`missing`]) that `bench` lacks it.
pub fn corpus_for(bench: &str) -> Option<PathBuf> {
    let dir = corpus_dir();
    if dir.is_none() {
        missing(bench, "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
    }
    dir
}

/// Decode options on one thread and on a pool of two (the decode benches' two rows of ours).
pub fn one_and_two_threads() -> (DecodeOptions, DecodeOptions) {
    let two = DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(2).expect("a pool of two threads"));
    (DecodeOptions::new(Limits::default()), two)
}

/// A program on PATH.
pub fn tool(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(name)).find(|p| p.is_file())
}

/// The corpus file GoldenGate_48bppRGBHalf_lossless.jxr (`data`) decoded: width, height and
/// its 48bppRGBHalf samples.
pub fn golden_gate_half(data: &[u8]) -> (usize, usize, Vec<u8>) {
    let info = JxrCodec.probe(data, &Limits::default()).expect("probe GoldenGate");
    let (w, h) = (info.width as usize, info.height as usize);
    let raw = decode_raw(data, &DecodeOptions::new(Limits::default())).expect("decode GoldenGate");
    assert_eq!(raw.len(), w * h * 6, "GoldenGate decodes to 48bppRGBHalf");
    (w, h, raw)
}

/// `w`×`h` 48bppRGBHalf samples mirrored into a 4×3 mosaic (every other copy flipped, so
/// that no seam is a hard edge): its width, height and samples.
pub fn mosaic(raw: &[u8], w: usize, h: usize) -> (usize, usize, Vec<u8>) {
    mosaic_of(raw, w, h, 6)
}

/// [`mosaic`] of `w`×`h` pixels of `per_pixel` values each.
pub fn mosaic_of<T: Copy + Default>(raw: &[T], w: usize, h: usize, per_pixel: usize) -> (usize, usize, Vec<T>) {
    let (tx, ty) = (4, 3);
    let (big_w, big_h) = (w * tx, h * ty);
    let mut out = vec![T::default(); big_w * big_h * per_pixel];
    for y in 0..big_h {
        let (ty_i, yy) = (y / h, y % h);
        let sy = if ty_i % 2 == 1 { h - 1 - yy } else { yy };
        for x in 0..big_w {
            let (tx_i, xx) = (x / w, x % w);
            let sx = if tx_i % 2 == 1 { w - 1 - xx } else { xx };
            let (s, d) = ((sy * w + sx) * per_pixel, (y * big_w + x) * per_pixel);
            out[d..d + per_pixel].copy_from_slice(&raw[s..s + per_pixel]);
        }
    }
    (big_w, big_h, out)
}

/// The corpus photograph exr/GoldenGate.exr (1262x860 RGB, half samples: exact in `f32`)
/// mirrored into a 4×3 mosaic of 5048x2580 = 13.0 MP, the large image of the EXR and PFM
/// benches.
pub fn golden_gate_exr_mosaic(corpus: &Path) -> HdrImage {
    let data = std::fs::read(corpus.join("exr/GoldenGate.exr")).expect("read the corpus's exr/GoldenGate.exr");
    let img = hdrcodec_exr::decode_exr(&data, &Limits::default()).expect("decode GoldenGate.exr");
    let per_pixel = img.channels().count();
    let (w, h, samples) = mosaic_of(img.samples(), img.width() as usize, img.height() as usize, per_pixel);
    HdrImage::new(w as u32, h as u32, img.channels(), samples, img.color.clone()).expect("the mosaic")
}

/// Runs `program` with `args`; panics with its standard error if it fails (a bench must not
/// time a failing command).
pub fn run<S: AsRef<std::ffi::OsStr>>(program: &Path, args: &[S]) {
    let out = Command::new(program).args(args).output().unwrap_or_else(|e| panic!("run {}: {e}", program.display()));
    if !out.status.success() {
        let args: Vec<_> = args.iter().map(|a| a.as_ref().to_string_lossy()).collect();
        panic!("{} {} failed: {}", program.display(), args.join(" "), String::from_utf8_lossy(&out.stderr));
    }
}

/// The index of the first sample where `a` and `b` differ (NaN equals NaN), or a length
/// mismatch as `Some(len)`.
pub fn first_difference(a: &[f32], b: &[f32]) -> Option<usize> {
    if a.len() != b.len() {
        return Some(a.len().min(b.len()));
    }
    a.iter().zip(b).position(|(x, y)| x.to_bits() != y.to_bits() && !(x.is_nan() && y.is_nan()))
}
