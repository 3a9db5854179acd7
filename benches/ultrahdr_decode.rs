//! Gain-map JPEG decode speed in one run: our decoder (`GainMapJpegCodec::decode_with`, linear
//! f32 RGB, full HDR rendition) against libultrahdr 1.4, called in-process through
//! tests/peers/libultrahdr_shim.c (the library of the reference venv's imagecodecs wheel;
//! tests/build.rs links it when it finds it), decoding the same bytes to linear half-float RGBA,
//! full HDR rendition. Each call is one whole decode from the file in memory (both JPEGs, the
//! map's upsampling and its application), output allocated inside it by each library.
//!
//! Files: the corpus's sky_ultrahdr.jpg (Pixel 6 Pro, 4080x3072 = 12.5 MP, one-channel map at
//! 1/4 scale, the speed target) and moonless_golf_1k.ultrahdr.jpg (1024x512, a
//! three-channel map at full size). Before timing, libultrahdr's decode must agree with ours
//! (median |log2 Y| below 0.02).
//!
//! Single thread: libultrahdr 1.4 applies the gain map on up to four `std::thread`s of its own
//! (it asks `hardware_concurrency`), so the like-for-like comparison is the whole bench pinned
//! to one CPU (`taskset -c 0 cargo bench ... --bench ultrahdr_decode`); the crate README says
//! how the numbers were taken. `hdrcodec_2threads` is ours on a pool of two threads (the gain's
//! rows in parallel; meaningful unpinned, against libultrahdr's own threads). Criterion's
//! throughput is in pixels: Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
use hdrcodec_core::ImageCodec;
use hdrcodec_jpeghdr::GainMapJpegCodec;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_dir, missing, one_and_two_threads};
use std::hint::black_box;

/// libultrahdr through tests/peers/libultrahdr_shim.c.
#[cfg(libultrahdr)]
#[path = "libultrahdr.rs"]
#[allow(dead_code)] // the encoder
mod libultrahdr;

/// The median |log2| of the ratio of two images' BT.709 luminances (RGB f32 and RGBA f32),
/// over pixels where both are above 1e-3.
#[cfg(libultrahdr)]
fn median_log2_luminance_error(rgb: &[f32], rgba: &[f32]) -> f64 {
    let y = |p: &[f32]| 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]);
    let mut e: Vec<f64> = rgb
        .chunks_exact(3)
        .zip(rgba.chunks_exact(4))
        .map(|(a, b)| (y(a), y(b)))
        .filter(|&(a, b)| a > 1e-3 && b > 1e-3)
        .map(|(a, b)| (a / b).log2().abs())
        .collect();
    e.sort_by(f64::total_cmp);
    e.get(e.len() / 2).copied().unwrap_or(f64::INFINITY)
}

fn bench(c: &mut Criterion) {
    let Some(dir) = corpus_dir() else {
        missing("ultrahdr_decode", "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
        return;
    };
    #[cfg(not(libultrahdr))]
    missing("ultrahdr_decode", "libultrahdr 1.4 (imagecodecs in the reference venv; tests/build.rs links it if found)");
    let (options, two) = one_and_two_threads();
    let mut group = c.benchmark_group("ultrahdr_decode");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for name in ["sky_ultrahdr.jpg", "moonless_golf_1k.ultrahdr.jpg"] {
        let data = std::fs::read(dir.join("jpeg").join(name)).expect("read a corpus gain-map JPEG");
        let ours = GainMapJpegCodec.decode_with(&data, &options).expect("our decode");
        let (w, h) = (ours.width(), ours.height());
        group.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
        #[cfg(libultrahdr)]
        {
            let mut bits = vec![0u16; w as usize * h as usize * 4];
            let size = libultrahdr::decode(&data, Some(&mut bits)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(size, (w, h), "{name}: libultrahdr's size");
            let theirs: Vec<f32> = bits.iter().map(|&b| half::f16::from_bits(b).to_f32()).collect();
            let err = median_log2_luminance_error(ours.samples(), &theirs);
            eprintln!("ultrahdr_decode bench: {name} ({w}x{h}): median |log2 Y| against libultrahdr {err:.4}");
            assert!(err < 0.02, "{name}: libultrahdr's decode differs from ours (median |log2 Y| {err})");
            group.bench_with_input(BenchmarkId::new("libultrahdr", name), &data, |b, d| {
                b.iter(|| libultrahdr::decode(black_box(d), None).unwrap())
            });
        }
        group.bench_with_input(BenchmarkId::new("hdrcodec", name), &data, |b, d| {
            b.iter(|| GainMapJpegCodec.decode_with(black_box(d), &options).unwrap())
        });
        let on_two = GainMapJpegCodec.decode_with(&data, &two).expect("our decode on two threads");
        assert_eq!(on_two.samples(), ours.samples(), "{name}: 1 vs 2 threads");
        group.bench_with_input(BenchmarkId::new("hdrcodec_2threads", name), &data, |b, d| {
            b.iter(|| GainMapJpegCodec.decode_with(black_box(d), &two).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
