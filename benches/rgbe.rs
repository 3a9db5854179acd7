//! Radiance RGBE speed against the Rust peers, single thread, in one run: RLE decode of the
//! corpus `.hdr` images (ours, zune-hdr, the `image` crate) and RLE encode (ours in both
//! roundings, the `image` crate). Throughput is in pixels, so criterion's "Melem/s" is MP/s.
//!
//! Images: `$HDRCODEC_CORPUS/hdr` or `../shared/corpus/hdr`.
//! Run: `cargo bench -p hdrcodec-tests --bench rgbe`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use hdrcodec_core::Limits;
use hdrcodec_rgbe::{decode, encode, RgbeDecodeOptions, RgbeEncodeOptions, Rounding};
use image::ImageDecoder;
use std::hint::black_box;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use std::path::PathBuf;
use std::time::Duration;

fn corpus() -> Vec<(String, Vec<u8>)> {
    let Some(corpus) = common::corpus_dir() else {
        common::missing("rgbe", "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
        return Vec::new();
    };
    let dir = corpus.join("hdr");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("the RGBE bench needs the corpus's .hdr files at {}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "hdr"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| (p.file_stem().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect()
}

fn bench(c: &mut Criterion) {
    let limits = Limits::default();
    let raw = RgbeDecodeOptions { apply_exposure: false, ..Default::default() };
    for (name, data) in corpus() {
        let img = decode(&data, &limits, &raw).unwrap();
        let (w, h) = (img.width(), img.height());
        let mut g = c.benchmark_group(format!("rgbe/{name}"));
        g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
        g.sample_size(20).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));

        g.bench_function(BenchmarkId::new("decode", "hdrcodec"), |b| {
            b.iter(|| decode(black_box(&data), &limits, &raw).unwrap())
        });
        g.bench_function(BenchmarkId::new("decode", "zune-hdr"), |b| {
            b.iter(|| zune_hdr::HdrDecoder::new(std::io::Cursor::new(black_box(&data[..]))).decode().unwrap())
        });
        g.bench_function(BenchmarkId::new("decode", "image"), |b| {
            b.iter(|| {
                let d = image::codecs::hdr::HdrDecoder::new(std::io::Cursor::new(black_box(&data[..]))).unwrap();
                let mut buf = vec![0u8; d.total_bytes() as usize];
                d.read_image(&mut buf).unwrap();
                buf
            })
        });

        for (label, rounding) in [("hdrcodec-nearest", Rounding::Nearest), ("hdrcodec-truncate", Rounding::Truncate)] {
            let opts = RgbeEncodeOptions { rounding, ..Default::default() };
            g.bench_function(BenchmarkId::new("encode", label), |b| b.iter(|| encode(black_box(&img), &opts).unwrap()));
        }
        let pixels: Vec<image::Rgb<f32>> = img.rgb().map(image::Rgb).collect();
        g.bench_function(BenchmarkId::new("encode", "image"), |b| {
            b.iter(|| {
                let mut out = Vec::with_capacity(data.len());
                image::codecs::hdr::HdrEncoder::new(&mut out)
                    .encode(black_box(&pixels), w as usize, h as usize)
                    .unwrap();
                out
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
