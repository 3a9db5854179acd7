//! BC6H encoder: linear RGB `f32` (or half floats) in, 16-byte BC6H blocks out.
//!
//! Effort 0 is a real-time encoder (one region, the most precise mode whose delta range holds
//! the block, principal-axis endpoints); effort 9 searches all 14 modes and all 32 partitions
//! with iterated least-squares endpoint refinement. The error minimised is the squared
//! difference of half-float bit patterns, a log-like space (see `block.rs`).
//!
//! Values BC6H cannot store are replaced as the Direct3D specification advises: NaN becomes 0,
//! ±Inf the largest finite half of that sign, and negative values 0 in UF16 (unsigned) blocks.
use hdrcodec_core::{Error, Result};

mod block;

use block::{sanitize_half, BlockEncoder, Search, Texels};

/// Encoder options.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodeOptions {
    /// Produce BC6H_SF16 (signed) blocks instead of BC6H_UF16.
    pub signed: bool,
    /// 0 (fastest) to 9 (exhaustive search).
    pub effort: u8,
    /// Worker threads, 0 = one per core.
    pub threads: usize,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions { signed: false, effort: 5, threads: 0 }
    }
}

/// One encoded block and what the encoder expects a conforming decoder to produce from it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodedBlock {
    /// The 16 bytes of the block.
    pub bytes: [u8; 16],
    /// The mode used, numbered 1 to 14 as in the Direct3D specification.
    pub mode: u8,
    /// The two-region partition (0 to 31; 0 for one-region modes).
    pub partition: u8,
    /// The decoded texels as half-float bits (row-major), as the encoder computed them.
    pub decoded: [[u16; 3]; 16],
    /// Sum over texels and channels of the squared half-bit difference to the (sanitised) input.
    pub error: u64,
}

/// Converts a linear `f32` to half-float bits the way BC6H stores it: NaN → 0, ±Inf and
/// overflow → the largest finite half (±65504), negatives → 0 unless `signed`.
pub fn f32_to_bc6h_half(v: f32, signed: bool) -> u16 {
    if v.is_nan() {
        return 0;
    }
    let v = v.clamp(-65504.0, 65504.0);
    sanitize_half(half::f16::from_f32(v).to_bits(), signed)
}

/// Encodes one block of 16 texels given as half-float bits (row-major), searching as hard as
/// `effort` (0-9) says. Unstorable values are replaced first (see [`f32_to_bc6h_half`]).
pub fn encode_block(texels: &[[u16; 3]; 16], signed: bool, effort: u8) -> EncodedBlock {
    encode_block_impl(texels, signed, effort, None)
}

/// Like [`encode_block`] but restricted to one mode (1 to 14, as numbered in the Direct3D
/// specification); two-region modes search partitions as `effort` says. Returns `None` for a
/// mode number outside 1..=14.
pub fn encode_block_in_mode(texels: &[[u16; 3]; 16], signed: bool, effort: u8, mode: u8) -> Option<EncodedBlock> {
    if !(1..=14).contains(&mode) {
        return None;
    }
    Some(encode_block_impl(texels, signed, effort, Some(mode as usize - 1)))
}

fn encode_block_impl(texels: &[[u16; 3]; 16], signed: bool, effort: u8, mode: Option<usize>) -> EncodedBlock {
    let tex = Texels::new(texels, signed);
    let cand = BlockEncoder::new(&tex, Search::for_effort(effort)).encode(mode);
    EncodedBlock {
        bytes: cand.pack(),
        mode: cand.mode as u8 + 1,
        partition: if crate::modes::MODES[cand.mode].regions == 2 { cand.partition as u8 } else { 0 },
        decoded: cand.decoded_halves(signed),
        error: cand.err,
    }
}

/// Compresses a `width` x `height` surface of interleaved linear RGB `f32` samples into BC6H
/// blocks (16 bytes each, block rows top to bottom, partial blocks padded by edge replication).
pub fn encode_surface(width: u32, height: u32, rgb: &[f32], options: &EncodeOptions) -> Result<Vec<u8>> {
    let (w, h) = (width as usize, height as usize);
    let expected = w.checked_mul(h).and_then(|n| n.checked_mul(3));
    if expected != Some(rgb.len()) {
        return Err(Error::invalid(format!(
            "BC6H encoder: {width}x{height} RGB needs {} samples, got {}",
            w.saturating_mul(h).saturating_mul(3),
            rgb.len()
        )));
    }
    let (bw, bh) = (w.div_ceil(4), h.div_ceil(4));
    let mut out = vec![0u8; bw * bh * 16];
    if bw == 0 || bh == 0 {
        return Ok(out);
    }
    let search = Search::for_effort(options.effort);
    let signed = options.signed;
    let encode_row = |by: usize, row: &mut [u8]| {
        for (bx, dst) in row.chunks_exact_mut(16).enumerate() {
            let mut texels = [[0u16; 3]; 16];
            for (i, t) in texels.iter_mut().enumerate() {
                // Edge replication for the partial blocks on the right and bottom.
                let x = (bx * 4 + i % 4).min(w - 1);
                let y = (by * 4 + i / 4).min(h - 1);
                let p = (y * w + x) * 3;
                for c in 0..3 {
                    t[c] = f32_to_bc6h_half(rgb[p + c], signed);
                }
            }
            let tex = Texels::new(&texels, signed);
            dst.copy_from_slice(&BlockEncoder::new(&tex, search).encode(None).pack());
        }
    };
    let row_bytes = bw * 16;
    let serial = |out: &mut [u8]| {
        for (by, row) in out.chunks_exact_mut(row_bytes).enumerate() {
            encode_row(by, row);
        }
    };
    let parallel = |out: &mut [u8]| {
        use rayon::prelude::*;
        out.par_chunks_exact_mut(row_bytes).enumerate().for_each(|(by, row)| encode_row(by, row));
    };
    match options.threads {
        1 => serial(&mut out),
        0 => parallel(&mut out),
        n => match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
            Ok(pool) => pool.install(|| parallel(&mut out)),
            // No threads to be had: the serial path gives the same bytes.
            Err(_) => serial(&mut out),
        },
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The clamping the Direct3D specification asks for, on the IEEE half encodings.
    #[test]
    fn half_conversion_clamps_like_the_spec() {
        assert_eq!(f32_to_bc6h_half(f32::NAN, false), 0);
        assert_eq!(f32_to_bc6h_half(f32::NAN, true), 0);
        assert_eq!(f32_to_bc6h_half(f32::INFINITY, false), 0x7BFF);
        assert_eq!(f32_to_bc6h_half(f32::NEG_INFINITY, true), 0xFBFF);
        assert_eq!(f32_to_bc6h_half(f32::NEG_INFINITY, false), 0);
        assert_eq!(f32_to_bc6h_half(-1.0, false), 0);
        assert_eq!(f32_to_bc6h_half(-1.0, true), 0xBC00);
        assert_eq!(f32_to_bc6h_half(1.0, false), 0x3C00);
        assert_eq!(f32_to_bc6h_half(1e6, false), 0x7BFF);
        assert_eq!(f32_to_bc6h_half(65519.0, false), 0x7BFF);
    }

    #[test]
    fn surface_size_mismatch_is_an_error() {
        assert!(encode_surface(4, 4, &[0.0; 47], &EncodeOptions::default()).is_err());
        assert_eq!(encode_surface(0, 7, &[], &EncodeOptions::default()).unwrap().len(), 0);
        assert_eq!(encode_surface(5, 3, &[0.5; 45], &EncodeOptions::default()).unwrap().len(), 32);
    }

    /// A constant block must come back exactly: any mode can represent one colour, and the
    /// search must find it.
    #[test]
    fn constant_blocks_are_exact() {
        for &(signed, v) in &[(false, 0x3C00u16), (false, 0x0001), (false, 0x7BFF), (true, 0xC500), (true, 0x4900)] {
            for effort in [0, 5, 9] {
                let b = encode_block(&[[v, v, v]; 16], signed, effort);
                assert_eq!(b.error, 0, "value {v:#x} signed {signed} effort {effort} mode {}", b.mode);
                assert_eq!(b.decoded, [[v, v, v]; 16]);
            }
        }
    }
}
