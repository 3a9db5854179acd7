//! BC6H decode speed, single thread, in one run: our decoder against `bcdec_rs` and the
//! `block_compression` crate's decoder, on the corpus Desk DDS (UF16 and SF16, level 0) and a
//! larger synthetic 2048x2048 surface of random blocks (every mode, UF16). All three write
//! RGB `f32` into a buffer allocated once; criterion's throughput is in texels (elements), so MP/s = Melem/s.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use hdrcodec_bc6h::{block_dims, decode_surface_into, read_dds, Bc6hTexture};
use hdrcodec_core::Limits;
use std::hint::black_box;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;

struct Surface {
    name: String,
    width: u32,
    height: u32,
    signed: bool,
    blocks: Vec<u8>,
}

fn surfaces() -> Vec<Surface> {
    let mut v = Vec::new();
    let corpus = common::corpus_dir().unwrap_or_default();
    for name in ["Desk_BC6H_UF16_mips.dds", "Desk_BC6H_SF16_mips.dds"] {
        match std::fs::read(corpus.join("dds").join(name)) {
            Ok(data) => {
                let Bc6hTexture { width, height, signed, levels } =
                    read_dds(&data, &Limits::default()).expect("corpus DDS parses");
                let blocks = levels.into_iter().next().unwrap();
                v.push(Surface { name: name.trim_end_matches("_mips.dds").into(), width, height, signed, blocks });
            }
            Err(e) => eprintln!("bc6h_decode bench: {name} not available ({e}); synthetic surface only"),
        }
    }
    // Synthetic: random 128-bit blocks, mode bits cycling over every value (reserved ones too).
    let (w, h) = (2048u32, 2048u32);
    let mut state = 0x0123_4567_89AB_CDEFu64;
    let mut blocks = Vec::with_capacity((w * h) as usize);
    for i in 0..(w / 4 * h / 4) as usize {
        for _ in 0..2 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            blocks.extend_from_slice(&state.to_le_bytes());
        }
        let b = blocks.len() - 16;
        blocks[b] = (blocks[b] & !31) | (i % 32) as u8;
    }
    v.push(Surface { name: "random_2048".into(), width: w, height: h, signed: false, blocks });
    v
}

/// A peer's per-block decoder writing RGB f32 with a row pitch in floats, run over a surface
/// into a buffer padded to whole blocks (plus one row of slack that the peers' pitch stepping
/// needs after the last block row).
fn peer_surface(s: &Surface, out: &mut [f32], decode: impl Fn(&[u8], &mut [f32], usize, bool)) {
    let (bx, _) = block_dims(s.width, s.height);
    let pitch = bx * 4 * 3;
    for (i, blk) in s.blocks.chunks_exact(16).enumerate() {
        let (x, y) = (i % bx, i / bx);
        decode(blk, &mut out[y * 4 * pitch + x * 12..], pitch, s.signed);
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("bc6h_decode");
    group.sample_size(20);
    for s in surfaces() {
        group.throughput(Throughput::Elements(s.width as u64 * s.height as u64));
        let (bx, by) = block_dims(s.width, s.height);
        let mut padded = vec![0f32; (by * 4 + 1) * bx * 4 * 3];
        let mut ours = vec![0f32; s.width as usize * s.height as usize * 3];
        group.bench_with_input(BenchmarkId::new("hdrcodec", &s.name), &s, |b, s| {
            b.iter(|| {
                decode_surface_into(
                    s.width,
                    s.height,
                    black_box(&s.blocks),
                    s.signed,
                    &hdrcodec_core::ThreadPool::single(),
                    black_box(&mut ours),
                )
                .unwrap()
            })
        });
        group.bench_with_input(BenchmarkId::new("bcdec_rs", &s.name), &s, |b, s| {
            b.iter(|| peer_surface(s, black_box(&mut padded), bcdec_rs::bc6h_float))
        });
        group.bench_with_input(BenchmarkId::new("block_compression", &s.name), &s, |b, s| {
            b.iter(|| peer_surface(s, black_box(&mut padded), block_compression::decode::decode_block_bc6h_float))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
