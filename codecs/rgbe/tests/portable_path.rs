//! `HDRCODEC_CPU=scalar` reaches the codec, and the public API gives the same bytes and floats
//! on either path: this test binary, run again with the variable set, encodes and decodes the
//! same images on the portable path and must get what this process got (with the AVX2 kernels
//! where the CPU has them; the unit tests compare each kernel with its twin directly).

use hdrcodec_core::cpu;
use hdrcodec_core::{Channels, ColorInfo, HdrImage, Limits};
use hdrcodec_rgbe::{decode, encode, MantissaDecode, RgbeDecodeOptions, RgbeEncodeOptions, Rounding};

/// FNV-1a over the encoded files and the bits of the decoded floats.
fn digest() -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    // Widths with and without RLE (8 to 32767), with a tail after the 16-pixel and 8-pixel
    // vector steps; RGB and RGBA; flat stretches (runs), pixels at every scale 2^-150..2^150
    // (each exponent byte, the subnormal scales of 1..=9 included) and random bits (literals,
    // NaN, infinities, negatives).
    for (w, h, channels) in [(37u32, 5u32, Channels::Rgb), (300, 3, Channels::Rgba), (7, 4, Channels::Rgb)] {
        let c = channels.count();
        let n = (w * h) as usize * c;
        let samples: Vec<f32> = (0..n)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let scale = ((i / c * 7919) % 300) as f32 - 150.0;
                match (i / c / 8) % 3 {
                    0 => 1.5,
                    1 => (scale + (state >> 40) as f32 / (1u64 << 24) as f32).exp2(),
                    _ => f32::from_bits(state as u32),
                }
            })
            .collect();
        let image = HdrImage::new(w, h, channels, samples, ColorInfo::default()).unwrap();
        for rounding in [Rounding::Truncate, Rounding::Nearest] {
            let file = encode(&image, &RgbeEncodeOptions { rounding, ..Default::default() }).unwrap();
            eat(&file);
            for mantissa in [MantissaDecode::Truncated, MantissaDecode::Centred] {
                let opts = RgbeDecodeOptions { apply_exposure: false, mantissa };
                let decoded = decode(&file, &Limits::default(), &opts).unwrap();
                for v in decoded.samples() {
                    eat(&v.to_bits().to_le_bytes());
                }
            }
        }
    }
    // The encoder writes no exponent byte below about 30 (it flushes values under 1e-32 to the
    // zero pixel): a flat file by hand with every exponent byte, in rows with a tail.
    let (w, rows) = (261usize, 2usize);
    let mut file = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {rows} +X {w}\n").into_bytes();
    for x in 0..w * rows {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        // Mantissas from 3 up, so no pixel looks like a run-length marker.
        let m = state.to_le_bytes().map(|b| 3 + b % 253);
        file.extend_from_slice(&[m[0], m[1], m[2], (x % 256) as u8]);
    }
    for mantissa in [MantissaDecode::Truncated, MantissaDecode::Centred] {
        let opts = RgbeDecodeOptions { apply_exposure: false, mantissa };
        for v in decode(&file, &Limits::default(), &opts).unwrap().samples() {
            eat(&v.to_bits().to_le_bytes());
        }
    }
    h
}

#[test]
fn the_portable_path_gives_the_same_files_and_pixels() {
    cpu::check_portable_path_in_child("the_portable_path_gives_the_same_files_and_pixels", digest);
}
