//! What the JPEG XR benches (jxr_decode, jxr_encode) share: finding the corpus and tools,
//! saying what is missing, and the GoldenGate half floats and their 13 MP mosaic.
use hdrcodec_core::{DecodeOptions, ImageCodec, Limits, ThreadPool};
use hdrcodec_jxr::{decode_raw, JxrCodec};
use std::path::PathBuf;

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

/// Decode options on one thread and on a pool of two (the decode benches' two rows of ours).
#[allow(dead_code)] // jxr_encode has no decode rows.
pub fn one_and_two_threads() -> (DecodeOptions, DecodeOptions) {
    let two = DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(2).expect("a pool of two threads"));
    (DecodeOptions::new(Limits::default()), two)
}

/// A program on PATH.
#[allow(dead_code)] // jxr_encode uses it only with jxrlib.
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
    let (tx, ty) = (4, 3);
    let (big_w, big_h) = (w * tx, h * ty);
    let mut half = vec![0u8; big_w * big_h * 6];
    for y in 0..big_h {
        let (ty_i, yy) = (y / h, y % h);
        let sy = if ty_i % 2 == 1 { h - 1 - yy } else { yy };
        for x in 0..big_w {
            let (tx_i, xx) = (x / w, x % w);
            let sx = if tx_i % 2 == 1 { w - 1 - xx } else { xx };
            let (s, d) = ((sy * w + sx) * 6, (y * big_w + x) * 6);
            half[d..d + 6].copy_from_slice(&raw[s..s + 6]);
        }
    }
    (big_w, big_h, half)
}
