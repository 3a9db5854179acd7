//! `HDRCODEC_CPU=scalar` reaches the codec, and the public API gives the same blocks and texels
//! on either path: this test binary, run again with the variable set, encodes and decodes the
//! same surfaces on the portable path and must get what this process got (with the AVX2 builds
//! where the CPU has them; the unit tests compare each kernel with its twin directly).

use hdrcodec_bc6h::decode_surface;
use hdrcodec_bc6h::encode::{encode_surface, EncodeOptions};
use hdrcodec_core::cpu;

/// FNV-1a over the encoded blocks and the bits of the decoded floats.
fn digest() -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    // A surface with partial edge blocks: gradients, octaves of noise, random bits (NaN,
    // infinities, negatives), zeros; encoded at three efforts, UF16 and SF16, and decoded.
    let (w, ht) = (22u32, 10u32);
    let rgb: Vec<f32> = (0..(w * ht * 3) as usize)
        .map(|i| {
            let s = next();
            let x = (i / 3) % w as usize;
            match (i / 3 / w as usize) % 4 {
                0 => (x as f32 * 0.3 + (i % 3) as f32).exp2() * 0.01,
                1 => ((s >> 40) as f32 / (1u64 << 24) as f32 * 40.0 - 20.0).exp2(),
                2 => f32::from_bits(s as u32),
                _ => [0.0, -3.5, 1e5, 7.25][(s % 4) as usize],
            }
        })
        .collect();
    for signed in [false, true] {
        for effort in [0, 4, 9] {
            let blocks = encode_surface(w, ht, &rgb, &EncodeOptions { signed, effort, ..Default::default() }).unwrap();
            eat(&blocks);
            for v in decode_surface(w, ht, &blocks, signed).unwrap() {
                eat(&v.to_bits().to_le_bytes());
            }
        }
    }
    // Random blocks, the mode bits cycling through all 32 values (the reserved ones too), as a
    // surface of 8 x 2 blocks cropped to 30 x 7 texels.
    let (w, ht) = (30u32, 7u32);
    let blocks: Vec<u8> = (0..8 * 2 * 4)
        .flat_map(|i| {
            let mut b = [0u8; 16];
            b[..8].copy_from_slice(&next().to_le_bytes());
            b[8..].copy_from_slice(&next().to_le_bytes());
            b[0] = (b[0] & !31) | (i % 32) as u8;
            b
        })
        .collect();
    for signed in [false, true] {
        for surface in blocks.chunks_exact(8 * 2 * 16) {
            for v in decode_surface(w, ht, surface, signed).unwrap() {
                eat(&v.to_bits().to_le_bytes());
            }
        }
    }
    h
}

#[test]
fn the_portable_path_gives_the_same_blocks_and_texels() {
    cpu::check_portable_path_in_child("the_portable_path_gives_the_same_blocks_and_texels", digest);
}
