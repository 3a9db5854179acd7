//! Throughput of the container around its raw payloads: tiled parallel encode and decode of a
//! 4096x2048 RGB frame (8 MP) in 256-pixel tiles, and the CRC-32C that guards every chunk.
//!   cargo bench -p hdrcodec-container

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hdrcodec_container::{crc32c, decode_image, encode_image, RawF16Codec, RawF32Codec};
use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
use std::hint::black_box;

fn frame() -> HdrImage {
    let (w, h) = (4096u32, 2048u32);
    let s = (0..w * h * 3).map(|i| ((i.wrapping_mul(2_654_435_761) >> 12) % 50_000) as f32 * 0.01).collect();
    HdrImage::new(w, h, Channels::Rgb, s, ColorInfo::default()).unwrap()
}

fn bench(c: &mut Criterion) {
    let img = frame();
    let mut g = c.benchmark_group("container");
    g.sample_size(10);
    g.throughput(Throughput::Elements(u64::from(img.width()) * u64::from(img.height())));
    let codecs: [&dyn ImageCodec; 2] = [&RawF32Codec, &RawF16Codec];
    for codec in codecs {
        let s = EncodeSettings::default();
        g.bench_function(format!("encode {} tiles 256", codec.name()), |b| {
            b.iter(|| encode_image(black_box(&img), codec, &s, Some(256)).unwrap())
        });
        let file = encode_image(&img, codec, &s, Some(256)).unwrap();
        g.bench_function(format!("decode {} tiles 256", codec.name()), |b| {
            b.iter(|| decode_image(black_box(&file), &Limits::default().into(), &|_| Some(codec)).unwrap())
        });
    }
    let data = vec![0xA5u8; 64 << 20];
    g.throughput(Throughput::Bytes(data.len() as u64));
    g.bench_function("crc32c 64 MiB", |b| b.iter(|| crc32c(black_box(&data))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
