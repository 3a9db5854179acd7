//! BC6H encoder: linear RGB `f32` (or half floats) in, 16-byte BC6H blocks out.
//!
//! Effort 0 is a real-time encoder (one region, the most precise mode whose delta range holds
//! the block, principal-axis endpoints); effort 9 searches all 14 modes and all 32 partitions
//! with iterated least-squares endpoint refinement. The error minimised is the squared
//! difference of half-float bit patterns, a log-like space (see `block.rs`).
//!
//! Values BC6H cannot store are replaced as the Direct3D specification advises: NaN becomes 0,
//! ±Inf the largest finite half of that sign, and negative values 0 in UF16 (unsigned) blocks.
use hdrcodec_core::{Error, Result, ThreadPool};

mod block;
mod fit;
mod partition;
mod texels;

use block::{BlockEncoder, Search};
use texels::{sanitize_half, Texels};

/// Encoder options.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodeOptions {
    /// Produce BC6H_SF16 (signed) blocks instead of BC6H_UF16.
    pub signed: bool,
    /// 0 (fastest) to 9 (exhaustive search).
    pub effort: u8,
    /// Worker threads (block rows are shared out among them); default the calling thread.
    pub pool: ThreadPool,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions { signed: false, effort: 5, pool: ThreadPool::single() }
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
    let search = Search::for_effort(effort);
    let cand = if signed {
        BlockEncoder::<true>::new(&Texels::new::<true>(texels), search).encode(mode)
    } else {
        BlockEncoder::<false>::new(&Texels::new::<false>(texels), search).encode(mode)
    };
    let decoded = cand.decoded_halves(signed);
    // The exact error (the search ranks candidates by an f32 sum).
    let mut error = 0u64;
    for (t, d) in texels.iter().zip(&decoded) {
        for c in 0..3 {
            let diff = (half_int(sanitize_half(t[c], signed)) - half_int(d[c])) as i64;
            error += (diff * diff) as u64;
        }
    }
    EncodedBlock {
        bytes: cand.pack(),
        mode: cand.mode as u8 + 1,
        partition: if crate::modes::MODES[cand.mode].regions == 2 { cand.partition as u8 } else { 0 },
        decoded,
        error,
    }
}

/// Half bits as a sign-magnitude integer.
fn half_int(h: u16) -> i32 {
    let m = (h & 0x7FFF) as i32;
    if h & 0x8000 != 0 {
        -m
    } else {
        m
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
    let surface =
        Surface { rgb, width: w, height: h, search: Search::for_effort(options.effort), signed: options.signed };
    options.pool.for_each_chunk_mut(&mut out, bw * 16, |by, row| surface.encode_row(by, row));
    Ok(out)
}

/// A surface being encoded.
struct Surface<'a> {
    rgb: &'a [f32],
    width: usize,
    height: usize,
    search: Search,
    signed: bool,
}

impl Surface<'_> {
    /// Encodes block row `by` into `row` (16 bytes per block), with the AVX2 build of the block
    /// encoder when [`hdrcodec_core::cpu::avx2`] allows it.
    fn encode_row(&self, by: usize, row: &mut [u8]) {
        #[cfg(target_arch = "x86_64")]
        if hdrcodec_core::cpu::avx2() {
            // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
            // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2` that
            // `encode_row_avx2` requires; its body is the safe portable code compiled for AVX2.
            unsafe { self.encode_row_avx2(by, row) };
            return;
        }
        self.encode_row_portable(by, row);
    }

    /// The block encoder built for the baseline target (inlined, so that `encode_row_avx2`
    /// compiles the same code for AVX2).
    #[inline(always)]
    fn encode_row_portable(&self, by: usize, row: &mut [u8]) {
        if self.signed {
            self.encode_row_impl::<true>(by, row)
        } else {
            self.encode_row_impl::<false>(by, row)
        }
    }

    /// The same code compiled with AVX2 enabled (everything below is `#[inline(always)]`).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn encode_row_avx2(&self, by: usize, row: &mut [u8]) {
        self.encode_row_portable(by, row)
    }

    #[inline(always)]
    fn encode_row_impl<const S: bool>(&self, by: usize, row: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        for (bx, dst) in row.chunks_exact_mut(16).enumerate() {
            let mut planes = [[0f32; 16]; 3];
            let x0 = bx * 4;
            for row_in_block in 0..4 {
                // Edge replication for the partial blocks on the right and bottom.
                let y = (by * 4 + row_in_block).min(h - 1);
                let line = &self.rgb[y * w * 3..(y + 1) * w * 3];
                for col in 0..4 {
                    let x = (x0 + col).min(w - 1);
                    let texel = &line[x * 3..x * 3 + 3];
                    for (plane, &v) in planes.iter_mut().zip(texel) {
                        plane[row_in_block * 4 + col] = v;
                    }
                }
            }
            let tex = Texels::from_f32::<S>(&planes);
            dst.copy_from_slice(&BlockEncoder::<S>::new(&tex, self.search).encode(None).pack());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use hdrcodec_core::cpu::{self, CpuLevel};

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

    /// The AVX2 build of the block encoder writes the same bytes as the portable build, at
    /// every effort, UF16 and SF16, on content with every kind of value (smooth gradients, edges,
    /// noise over many octaves, negatives, zeros, NaN and infinities).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_build_matches_portable_build() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_build_matches_portable_build") {
            return;
        }
        let (w, h) = (36usize, 12usize);
        let mut next = texels::tests::xorshift32(0x2545_F491);
        let mut rgb = vec![0f32; w * h * 3];
        for (i, v) in rgb.iter_mut().enumerate() {
            let state = next();
            let x = (i / 3) % w;
            *v = match (i / 3 / w) % 4 {
                0 => (x as f32 * 0.3 + (i % 3) as f32).exp2() * 0.01,
                1 => ((state >> 8) as f32 / (1u32 << 24) as f32 * 40.0 - 20.0).exp2(),
                2 => f32::from_bits(state),
                _ => [0.0, -3.5, 1e5, f32::NAN, f32::INFINITY, 7.25][(state % 6) as usize],
            };
        }
        for signed in [false, true] {
            for effort in 0..=9 {
                let surface = Surface { rgb: &rgb, width: w, height: h, search: Search::for_effort(effort), signed };
                for by in 0..h / 4 {
                    let mut portable = vec![0u8; w / 4 * 16];
                    let mut avx2 = vec![0u8; w / 4 * 16];
                    surface.encode_row_portable(by, &mut portable);
                    // SAFETY: `twin_test_can_run` at the top found AVX2 (with FMA and F16C) in the
                    // hardware.
                    unsafe { surface.encode_row_avx2(by, &mut avx2) };
                    assert_eq!(portable, avx2, "signed {signed} effort {effort} block row {by}");
                }
            }
        }
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
