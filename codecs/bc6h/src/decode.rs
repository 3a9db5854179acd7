//! The BC6H block decoder (D3D11 functional specification, "BC6H Format": decoding steps) and
//! the parallel whole-surface decoder.
use crate::modes::{Field, ANCHORS, MODES, MODE_FROM_BITS, PARTITIONS, WEIGHTS3, WEIGHTS4};
use hdrcodec_core::{Error, Result, ThreadPool};

/// Sign-extends the low `bits` bits of `v`.
#[inline(always)]
fn sign_extend(v: i32, bits: u32) -> i32 {
    let s = 32 - bits;
    (v << s) >> s
}

/// Spec `unquantize`: expands an endpoint of `bits` precision to 16 bits (UF16: 0..=0xFFFF;
/// SF16: -0x7FFF..=0x7FFF).
#[inline(always)]
pub(crate) fn unquantize<const SIGNED: bool>(v: i32, bits: u32) -> i32 {
    if !SIGNED {
        if bits >= 15 || v == 0 {
            v
        } else if v == (1 << bits) - 1 {
            0xFFFF
        } else {
            ((v << 16) + 0x8000) >> bits
        }
    } else {
        if bits >= 16 {
            return v;
        }
        let m = v.abs();
        let u = if m == 0 {
            0
        } else if m >= (1 << (bits - 1)) - 1 {
            0x7FFF
        } else {
            ((m << 15) + 0x4000) >> (bits - 1)
        };
        if v < 0 {
            -u
        } else {
            u
        }
    }
}

/// [`unquantize`] with the signedness chosen at run time (the encoder's entry point).
#[inline]
pub(crate) fn unquantize_endpoint(v: i32, bits: u32, signed: bool) -> i32 {
    if signed {
        unquantize::<true>(v, bits)
    } else {
        unquantize::<false>(v, bits)
    }
}

/// Spec `finish_unquantize`: scales an interpolated 16-bit value to the half-float bit pattern
/// (UF16 by 31/64, SF16 by 31/32 on the magnitude, with the sign in bit 15).
#[inline(always)]
fn finish<const SIGNED: bool>(v: i32) -> u16 {
    if !SIGNED {
        ((v * 31) >> 6) as u16
    } else {
        // The sign is applied after scaling, so a tiny negative value that scales to 0
        // becomes +0, never -0 (0x8000).
        let m = (v.abs() * 31) >> 5;
        (if v < 0 && m != 0 { 0x8000 | m } else { m }) as u16
    }
}

/// Decodes one 16-byte BC6H block into 16 texels (row-major) of half-float bit patterns
/// `[r, g, b]`. `signed` selects BC6H_SF16 over BC6H_UF16. Blocks with a reserved mode decode to
/// zero, as the D3D11 specification requires.
#[inline]
pub fn decode_block(block: &[u8; 16], signed: bool) -> [[u16; 3]; 16] {
    let bits = u128::from_le_bytes(*block);
    let planes = if signed {
        texel_halves::<true>(bits, &header::<true>(bits))
    } else {
        texel_halves::<false>(bits, &header::<false>(bits))
    };
    let mut out = [[0u16; 3]; 16];
    for (i, texel) in out.iter_mut().enumerate() {
        for (c, v) in texel.iter_mut().enumerate() {
            *v = planes[c][i] as u16;
        }
    }
    out
}

/// The decoded block as three channel planes of 16 half-float bit patterns (in `i32` lanes, so
/// that the per-texel arithmetic vectorises).
type Planes = [[i32; 16]; 3];

/// What the texel stage needs from a block's header, whatever its mode: the unquantized
/// endpoints and the partition. Reserved modes become an all-zero one-region header, which
/// decodes to zero in every channel without a path of its own.
#[derive(Clone, Copy, Debug, Default)]
struct Header {
    /// Unquantized endpoints `w, x, y, z`, each `[r, g, b]` (`y`, `z` are 0 in one-region modes).
    ep: [i32; 12],
    /// Region-1 texels (bit `i` = texel `i`), 0 in one-region modes.
    shape: u32,
    /// Region 1's anchor texel (two-region modes; 0 otherwise).
    anchor: u32,
    /// Two regions (3-bit indices) rather than one (4-bit indices).
    two: bool,
}

/// Reads a block's header with a reader specialised for each mode (the mode's bit layout,
/// region count and transform become constants there). Only this dispatch depends on the mode:
/// the texel stage after it is shared by all modes.
#[inline(always)]
fn header<const SIGNED: bool>(bits: u128) -> Header {
    match MODE_FROM_BITS[(bits & 31) as usize] {
        Some(0) => mode_header::<0, SIGNED>(bits),
        Some(1) => mode_header::<1, SIGNED>(bits),
        Some(2) => mode_header::<2, SIGNED>(bits),
        Some(3) => mode_header::<3, SIGNED>(bits),
        Some(4) => mode_header::<4, SIGNED>(bits),
        Some(5) => mode_header::<5, SIGNED>(bits),
        Some(6) => mode_header::<6, SIGNED>(bits),
        Some(7) => mode_header::<7, SIGNED>(bits),
        Some(8) => mode_header::<8, SIGNED>(bits),
        Some(9) => mode_header::<9, SIGNED>(bits),
        Some(10) => mode_header::<10, SIGNED>(bits),
        Some(11) => mode_header::<11, SIGNED>(bits),
        Some(12) => mode_header::<12, SIGNED>(bits),
        Some(13) => mode_header::<13, SIGNED>(bits),
        // Reserved mode values decode to zero: zero endpoints give zero texels.
        _ => Header::default(),
    }
}

/// The most layout runs any mode has (modes 2 and 10 have 24).
const MAX_RUNS: usize = 24;

/// Repeats `$body` once per listed value with `$k` bound to it as a `const`, so that table
/// lookups indexed by `$k` fold to constants (a loop over them is not reliably unrolled).
macro_rules! unroll {
    ($k:ident in [$($n:literal),*] $body:block) => {
        $( { const $k: usize = $n; $body } )*
    };
}

/// The header reader for mode `MODES[M]`.
#[inline(always)]
fn mode_header<const M: usize, const SIGNED: bool>(bits: u128) -> Header {
    let info = &MODES[M];
    let layout = info.layout;

    // Gather the header fields. `unroll!` repeats the body with `K` = 0..24 as constants, so
    // every run of this mode's (constant) layout becomes a fixed shift and mask.
    let mut f = [0i32; 13];
    let mut pos = info.mode_bits as u32;
    unroll!(K in [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23] {
        if K < layout.len() {
            let run = &layout[K];
            let n = run.len();
            let v = ((bits >> pos) as u32) & ((1u32 << n) - 1);
            if run.reversed() {
                f[run.field as usize] |= ((v.reverse_bits() >> (32 - n)) << run.last) as i32;
            } else {
                f[run.field as usize] |= (v << run.first) as i32;
            }
            pos += n;
        }
    });
    debug_assert!(layout.len() <= MAX_RUNS);
    let _ = pos;

    // Endpoints: sign extension, inverse transform, unquantize (constant bounds, so these
    // loops unroll for the mode).
    let ep = info.endpoint_bits as u32;
    let ends = info.regions as usize * 2;
    let mut h = Header { two: info.regions == 2, ..Header::default() };
    for c in 0..3 {
        let db = info.delta_bits[c] as u32;
        let w = if SIGNED { sign_extend(f[c], ep) } else { f[c] };
        h.ep[c] = unquantize::<SIGNED>(w, ep);
        for k in 1..4 {
            if k < ends {
                let mut v = f[k * 3 + c];
                if info.transformed || SIGNED {
                    v = sign_extend(v, db);
                }
                if info.transformed {
                    v = (v + w) & ((1 << ep) - 1);
                    if SIGNED {
                        v = sign_extend(v, ep);
                    }
                }
                h.ep[k * 3 + c] = unquantize::<SIGNED>(v, ep);
            }
        }
    }
    if h.two {
        let d = f[Field::D as usize] as usize & 31;
        h.shape = PARTITIONS[d] as u32;
        h.anchor = ANCHORS[d] as u32;
    }
    h
}

/// The block's texel indices as 16 fields of equal width, texel `i` at bit `3 * i` (two
/// regions) or `4 * i` (one region). The stream stores the anchor texels' indices with one bit
/// less (their top bit is 0); putting that 0 back makes every field the same width, so that the
/// texel stage needs no per-texel position arithmetic or branches.
#[inline(always)]
fn index_fields(bits: u128, two: bool, anchor: u32) -> u64 {
    if two {
        // 46 index bits from bit 82: texel 0 and the anchor have 2 bits, the others 3.
        let x = (bits >> 82) as u64;
        let x = insert_zero_bit(x, 2);
        insert_zero_bit(x, 3 * anchor + 2)
    } else {
        // 63 index bits from bit 65: texel 0 has 3 bits, so texels 1..16 are exactly the
        // nibbles 1..16 of the block's upper half, and texel 0 is nibble 0 shifted down by one.
        let x = (bits >> 64) as u64;
        (x & !15) | ((x >> 1) & 7)
    }
}

/// `x` with a 0 bit inserted at bit `p` (the bits from `p` up move up by one).
#[inline(always)]
fn insert_zero_bit(x: u64, p: u32) -> u64 {
    let low = (1u64 << p) - 1;
    (x & low) | ((x & !low) << 1)
}

/// The texel stage of the portable decoder: the 16 texels' half-float bit patterns as channel
/// planes (the scalar twin of the AVX2 kernel).
#[inline(always)]
fn texel_halves<const SIGNED: bool>(bits: u128, h: &Header) -> Planes {
    let x = index_fields(bits, h.two, h.anchor);
    let mut weight = [0i32; 16];
    if h.two {
        for (i, w) in weight.iter_mut().enumerate() {
            *w = WEIGHTS3[((x >> (3 * i)) & 7) as usize] as i32;
        }
    } else {
        for (i, w) in weight.iter_mut().enumerate() {
            *w = WEIGHTS4[((x >> (4 * i)) & 15) as usize] as i32;
        }
    }
    let mut out = [[0i32; 16]; 3];
    for (c, plane) in out.iter_mut().enumerate() {
        // a * (64 - w) + b * w + 32 >> 6 is a + ((b - a) * w + 32 >> 6) exactly: 64 * a
        // passes the floor of the shift unchanged.
        let (a0, d0) = (h.ep[c], h.ep[3 + c] - h.ep[c]);
        let (a1, d1) = (h.ep[6 + c], h.ep[9 + c] - h.ep[6 + c]);
        for (i, v) in plane.iter_mut().enumerate() {
            let (a, d) = if (h.shape >> i) & 1 == 1 { (a1, d1) } else { (a0, d0) };
            *v = finish::<SIGNED>(a + ((d * weight[i] + 32) >> 6)) as i32;
        }
    }
    out
}

/// Converts a finished half bit pattern to `f32` without branches, so that it vectorises:
/// normal halves re-bias the exponent, subnormal ones (exponent 0) are `mantissa * 2^-24`
/// exactly, and exponent 31 is infinity. BC6H never yields NaN; the one non-finite value it can
/// yield is -Inf (0xFC00), from an SF16 mode-14 endpoint of -32768 (see the tests).
#[inline(always)]
fn half_to_f32(h: i32) -> f32 {
    let mag = h & 0x7FFF;
    let normal = f32::from_bits(((mag << 13) + (112 << 23)) as u32);
    let subnormal = mag as f32 * (1.0 / 16_777_216.0);
    let v = if mag < 0x400 { subnormal } else { normal };
    let v = if mag >= 0x7C00 { f32::INFINITY } else { v };
    f32::from_bits(v.to_bits() | ((h as u32 & 0x8000) << 16))
}

/// Number of blocks across and down a `width` x `height` surface.
pub fn block_dims(width: u32, height: u32) -> (usize, usize) {
    (width.div_ceil(4) as usize, height.div_ceil(4) as usize)
}

/// Bytes of BC6H data for a `width` x `height` surface (16 per 4x4 block), `None` on overflow.
pub fn surface_bytes(width: u32, height: u32) -> Option<usize> {
    let (bx, by) = block_dims(width, height);
    bx.checked_mul(by)?.checked_mul(16)
}

/// Decodes a surface of BC6H blocks (block rows top to bottom) into interleaved linear RGB `f32`,
/// `width * height * 3` samples, cropping partial edge blocks, on the calling thread.
/// `blocks` must hold exactly [`surface_bytes`] bytes.
pub fn decode_surface(width: u32, height: u32, blocks: &[u8], signed: bool) -> Result<Vec<f32>> {
    let need = surface_bytes(width, height).ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    if blocks.len() != need {
        let what = format!("BC6H data: {} bytes for a {width}x{height} surface that needs {need}", blocks.len());
        return Err(if blocks.len() < need { Error::truncated(what) } else { Error::invalid(what) });
    }
    // The block data bounds the allocation: 16 bytes of blocks per 16 texels of 12 bytes.
    let samples = (width as usize)
        .checked_mul(height as usize)
        .and_then(|n| n.checked_mul(3))
        .ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    let mut out = vec![0f32; samples];
    decode_surface_into(width, height, blocks, signed, &ThreadPool::single(), &mut out)?;
    Ok(out)
}

/// [`decode_surface`] into a caller's buffer of exactly `width * height * 3` samples (so that a
/// buffer can be reused), block rows in parallel on `pool`.
pub fn decode_surface_into(
    width: u32,
    height: u32,
    blocks: &[u8],
    signed: bool,
    pool: &ThreadPool,
    out: &mut [f32],
) -> Result<()> {
    let need = surface_bytes(width, height).ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    if blocks.len() != need {
        let what = format!("BC6H data: {} bytes for a {width}x{height} surface that needs {need}", blocks.len());
        return Err(if blocks.len() < need { Error::truncated(what) } else { Error::invalid(what) });
    }
    if Some(out.len()) != (width as usize).checked_mul(height as usize).and_then(|n| n.checked_mul(3)) {
        return Err(Error::invalid(format!(
            "output buffer of {} samples for a {width}x{height} RGB surface",
            out.len()
        )));
    }
    if out.is_empty() {
        return Ok(());
    }
    let (bx, _) = block_dims(width, height);
    let row_floats = width as usize * 3 * 4;
    let w = width as usize;
    pool.for_each_chunk_mut(out, row_floats, |by, rows| {
        decode_block_row(w, &blocks[by * bx * 16..(by + 1) * bx * 16], rows, signed)
    });
    Ok(())
}

/// Decodes one row of blocks into up to 4 rows of `width` RGB texels (`out.len()` decides how
/// many rows exist), with the AVX2/F16C kernel when [`hdrcodec_core::cpu::avx2`] allows it.
fn decode_block_row(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
        // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2,f16c` that
        // `decode_block_row_avx2` requires.
        unsafe { decode_block_row_avx2(width, row_blocks, out, signed) };
        return;
    }
    decode_block_row_scalar(width, row_blocks, out, signed)
}

/// The portable path (and the twin the AVX2 kernel is tested against).
fn decode_block_row_scalar(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    if signed {
        block_loop::<true>(width, row_blocks, out, block_scalar::<true>)
    } else {
        block_loop::<false>(width, row_blocks, out, block_scalar::<false>)
    }
}

/// The row decoder with the AVX2/F16C texel kernel (the header readers are the same safe code,
/// compiled for AVX2).
///
/// # Safety
/// The CPU must support AVX2 and F16C.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
unsafe fn decode_block_row_avx2(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    // The closures inherit this function's target features, so the kernel inlines into them.
    if signed {
        block_loop::<true>(width, row_blocks, out, |bits, h, o, stride| avx2::block::<true>(bits, h, o, stride))
    } else {
        block_loop::<false>(width, row_blocks, out, |bits, h, o, stride| avx2::block::<false>(bits, h, o, stride))
    }
}

/// Runs `kernel` over a row of blocks. A kernel writes texel `(x, y)` of the block as RGB `f32`
/// at `out[y * stride + 3 * x..][..3]`; whole blocks go straight into the surface, partial edge
/// blocks through a scratch block of which only the part inside the surface is kept.
#[inline(always)]
fn block_loop<const SIGNED: bool>(
    width: usize,
    row_blocks: &[u8],
    out: &mut [f32],
    mut kernel: impl FnMut(u128, &Header, &mut [f32], usize),
) {
    let stride = width * 3;
    let rows = out.len() / stride;
    for (bxi, blk) in row_blocks.chunks_exact(16).enumerate() {
        let bits = u128::from_le_bytes(blk.try_into().expect("chunks_exact(16)"));
        let h = header::<SIGNED>(bits);
        let x0 = bxi * 4;
        if rows == 4 && x0 + 4 <= width {
            kernel(bits, &h, &mut out[x0 * 3..], stride);
        } else {
            let mut scratch = [0f32; 48];
            kernel(bits, &h, &mut scratch, 12);
            let cols = (width - x0).min(4) * 3;
            for y in 0..rows {
                out[y * stride + x0 * 3..][..cols].copy_from_slice(&scratch[y * 12..][..cols]);
            }
        }
    }
}

/// The portable texel kernel (see [`block_loop`] for the output layout).
#[inline(always)]
fn block_scalar<const SIGNED: bool>(bits: u128, h: &Header, out: &mut [f32], stride: usize) {
    // Widen whole planes first (that vectorises), then interleave.
    let planes = texel_halves::<SIGNED>(bits, h).map(|p| p.map(half_to_f32));
    for y in 0..4 {
        let row = &mut out[y * stride..][..12];
        for x in 0..4 {
            row[x * 3..x * 3 + 3].copy_from_slice(&[planes[0][y * 4 + x], planes[1][y * 4 + x], planes[2][y * 4 + x]]);
        }
    }
}

/// The texel stage in AVX2 and F16C: 16 texels as two 8-lane vectors per channel, weights
/// looked up with in-register permutes, half floats widened by `vcvtph2ps`, and the channel
/// planes interleaved to RGB with in-lane shuffles. [`block_scalar`] is its twin.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{index_fields, Header};
    use crate::modes::{WEIGHTS3, WEIGHTS4};
    use std::arch::x86_64::*;

    /// An 8-lane vector of the `i32` values `t[base..base + 8]` of a weight table.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn table8(t: &[u8], base: usize) -> __m256i {
        let v: [i32; 8] = std::array::from_fn(|i| t[base + i] as i32);
        _mm256_setr_epi32(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7])
    }

    /// Interpolation weights of texels 0..8 and 8..16.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn weights(x: u64, two: bool) -> [__m256i; 2] {
        if two {
            // 3-bit fields: texels 0..8 in bits 0..24, texels 8..16 in bits 24..48.
            let shifts = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
            let t = table8(&WEIGHTS3, 0);
            // vpermd uses the low 3 bits of each lane as the table index.
            let lookup =
                |half: u64| _mm256_permutevar8x32_epi32(t, _mm256_srlv_epi32(_mm256_set1_epi32(half as i32), shifts));
            [lookup(x), lookup(x >> 24)]
        } else {
            // 4-bit fields: texels 0..8 in the low 32 bits, 8..16 in the high 32.
            let shifts = _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28);
            let (t0, t1) = (table8(&WEIGHTS4, 0), table8(&WEIGHTS4, 8));
            let lookup = |half: u64| {
                let idx = _mm256_srlv_epi32(_mm256_set1_epi32(half as i32), shifts);
                // Bit 3 of the index (moved to the sign bit) picks the upper half of the table.
                let pick = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(idx));
                let lo = _mm256_castsi256_ps(_mm256_permutevar8x32_epi32(t0, idx));
                let hi = _mm256_castsi256_ps(_mm256_permutevar8x32_epi32(t1, idx));
                _mm256_castps_si256(_mm256_blendv_ps(lo, hi, pick))
            };
            [lookup(x), lookup(x >> 32)]
        }
    }

    /// Spec `finish_unquantize` on 8 lanes (see `super::finish`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn finish<const SIGNED: bool>(v: __m256i) -> __m256i {
        if !SIGNED {
            // (v * 31) >> 6 with v in 0..=0xFFFF.
            _mm256_srli_epi32::<6>(_mm256_sub_epi32(_mm256_slli_epi32::<5>(v), v))
        } else {
            let a = _mm256_abs_epi32(v);
            let m = _mm256_srli_epi32::<5>(_mm256_sub_epi32(_mm256_slli_epi32::<5>(a), a));
            let zero = _mm256_setzero_si256();
            // The sign only where the scaled magnitude is not 0 (never -0).
            let neg = _mm256_and_si256(_mm256_cmpgt_epi32(zero, v), _mm256_cmpgt_epi32(m, zero));
            _mm256_or_si256(m, _mm256_and_si256(neg, _mm256_set1_epi32(0x8000)))
        }
    }

    /// Writes 4 RGB texels (12 floats) per 128-bit lane of `r`, `g`, `b` (one row in each
    /// lane): the low lanes to `lo`, the high lanes to `hi`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn store_rows(r: __m256, g: __m256, b: __m256, lo: &mut [f32], hi: &mut [f32]) {
        // With r' = r0 r3 r2 r1, g' = g1 g0 g3 g2, b' = b2 b1 b0 b3 (per lane), the outputs
        // r0 g0 b0 r1 | g1 b1 r2 g2 | b2 r3 g3 b3 each take lane k of one of them.
        let r = _mm256_permute_ps::<0b01_10_11_00>(r);
        let g = _mm256_permute_ps::<0b10_11_00_01>(g);
        let b = _mm256_permute_ps::<0b11_00_01_10>(b);
        let o0 = _mm256_blend_ps::<0x44>(_mm256_blend_ps::<0x22>(r, g), b);
        let o1 = _mm256_blend_ps::<0x44>(_mm256_blend_ps::<0x22>(g, b), r);
        let o2 = _mm256_blend_ps::<0x44>(_mm256_blend_ps::<0x22>(b, r), g);
        let (lo, hi) = (&mut lo[..12], &mut hi[..12]);
        // SAFETY: `lo` and `hi` hold 12 floats each (sliced above); every store writes 4
        // floats at offset 0, 4 or 8.
        unsafe {
            _mm_storeu_ps(lo.as_mut_ptr(), _mm256_castps256_ps128(o0));
            _mm_storeu_ps(lo.as_mut_ptr().add(4), _mm256_castps256_ps128(o1));
            _mm_storeu_ps(lo.as_mut_ptr().add(8), _mm256_castps256_ps128(o2));
            _mm_storeu_ps(hi.as_mut_ptr(), _mm256_extractf128_ps::<1>(o0));
            _mm_storeu_ps(hi.as_mut_ptr().add(4), _mm256_extractf128_ps::<1>(o1));
            _mm_storeu_ps(hi.as_mut_ptr().add(8), _mm256_extractf128_ps::<1>(o2));
        }
    }

    /// The texel kernel (output layout as in `super::block_loop`).
    #[inline]
    #[target_feature(enable = "avx2,f16c")]
    pub(super) fn block<const SIGNED: bool>(bits: u128, h: &Header, out: &mut [f32], stride: usize) {
        let w = weights(index_fields(bits, h.two, h.anchor), h.two);
        // Region-1 lanes: bit i of the shape for texel i.
        let shape = _mm256_set1_epi32(h.shape as i32);
        let sel = [
            _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128),
            _mm256_setr_epi32(256, 512, 1024, 2048, 4096, 8192, 16384, 32768),
        ];
        let region: [__m256i; 2] = std::array::from_fn(|k| _mm256_cmpeq_epi32(_mm256_and_si256(shape, sel[k]), sel[k]));
        let round = _mm256_set1_epi32(32);
        // Per channel: texel rows 0 and 2 in one vector's lanes, rows 1 and 3 in another's.
        let mut rows02 = [_mm256_setzero_ps(); 3];
        let mut rows13 = [_mm256_setzero_ps(); 3];
        for c in 0..3 {
            let e = |k: usize| _mm256_set1_epi32(h.ep[k * 3 + c]);
            let (a0, a1) = (e(0), e(2));
            let (d0, d1) = (_mm256_sub_epi32(e(1), a0), _mm256_sub_epi32(e(3), a1));
            let texels: [__m256i; 2] = std::array::from_fn(|k| {
                let a = _mm256_blendv_epi8(a0, a1, region[k]);
                let d = _mm256_blendv_epi8(d0, d1, region[k]);
                let v =
                    _mm256_add_epi32(a, _mm256_srai_epi32::<6>(_mm256_add_epi32(_mm256_mullo_epi32(d, w[k]), round)));
                finish::<SIGNED>(v)
            });
            // Halves as u16: texels 0-3, 8-11 in the low 128 bits, 4-7, 12-15 in the high.
            let halves = _mm256_packus_epi32(texels[0], texels[1]);
            rows02[c] = _mm256_cvtph_ps(_mm256_castsi256_si128(halves));
            rows13[c] = _mm256_cvtph_ps(_mm256_extracti128_si256::<1>(halves));
        }
        let (r01, r23) = out.split_at_mut(2 * stride);
        let (r0, r1) = r01.split_at_mut(stride);
        let (r2, r3) = r23.split_at_mut(stride);
        store_rows(rows02[0], rows02[1], rows02[2], r0, r2);
        store_rows(rows13[0], rows13[1], rows13[2], r1, r3);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modes::{pack_block, BlockFields};
    #[cfg(target_arch = "x86_64")]
    use hdrcodec_core::cpu::{self, CpuLevel};

    #[test]
    fn half_conversion_matches_the_half_crate_for_every_non_nan_half() {
        for h in 0..=0xFFFFu32 {
            if h & 0x7FFF <= 0x7C00 {
                let want = half::f16::from_bits(h as u16).to_f32();
                assert_eq!(half_to_f32(h as i32).to_bits(), want.to_bits(), "{h:#06x}");
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_kernel_matches_the_scalar_twin() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_kernel_matches_the_scalar_twin") {
            return;
        }
        // 4096 random blocks, the mode bits cycling through all 32 values, plus the SF16
        // -Inf block (mode 14, endpoints -32768).
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut blocks: Vec<u8> = (0..4096)
            .flat_map(|i| {
                let mut b = [0u8; 16];
                for half in b.chunks_exact_mut(8) {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    half.copy_from_slice(&state.to_le_bytes());
                }
                b[0] = (b[0] & !31) | (i % 32) as u8;
                b
            })
            .collect();
        let mut fields = BlockFields { mode: 13, ..Default::default() };
        fields.values[..3].copy_from_slice(&[0x8000; 3]);
        blocks[..16].copy_from_slice(&pack_block(&fields));
        for signed in [false, true] {
            // Whole blocks (1024 blocks per row), a row cropped to 7 texels (the second block
            // partial), and rows of 1 to 3 texel rows (the last block row of a surface).
            for (w, n, rows) in [(4096usize, 1024usize, 4usize), (7, 2, 4), (10, 3, 3), (5, 2, 1)] {
                for chunk in blocks.chunks_exact(n * 16) {
                    let (mut a, mut b) = (vec![0f32; w * rows * 3], vec![1f32; w * rows * 3]);
                    decode_block_row_scalar(w, chunk, &mut a, signed);
                    // SAFETY: `twin_test_can_run` above found AVX2, FMA and F16C in the hardware.
                    unsafe { decode_block_row_avx2(w, chunk, &mut b, signed) };
                    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()), "w {w} rows {rows}");
                }
            }
        }
    }

    #[test]
    fn reserved_modes_decode_to_zero() {
        for r in crate::modes::RESERVED_MODE_VALUES {
            let mut block = [0xFFu8; 16];
            block[0] = (block[0] & !31) | r;
            assert_eq!(decode_block(&block, false), [[0; 3]; 16]);
            assert_eq!(decode_block(&block, true), [[0; 3]; 16]);
        }
    }

    #[test]
    fn mode_11_endpoints_unquantize_as_the_spec_says() {
        // Mode 11 (10-bit endpoints, untransformed): w = 1023 (max) unquantizes to 0xFFFF and
        // finishes to 0xFFFF * 31 >> 6 = 0x7BFF, the largest finite half; x = 0 gives 0.
        let mut fields = BlockFields { mode: 10, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 1023;
        }
        // Texel 0 index 0 (weight 0) -> endpoint w; texel 1 index 15 (weight 64) -> x.
        fields.indices[1] = 15;
        let out = decode_block(&pack_block(&fields), false);
        assert_eq!(out[0], [0x7BFF; 3]);
        assert_eq!(out[1], [0; 3]);
    }

    #[test]
    fn tiny_negative_sf16_values_finish_as_positive_zero() {
        // D3D11 finish_unquantize for SF16: comp = -(((-comp) * 31) >> 5), and the sign bit is
        // set only if comp < 0 afterwards, so -1 becomes +0 (0x0000), never -0 (0x8000).
        // Mode 14 (16-bit, transformed): w = 0xFFFF is -1 after sign extension, delta 0.
        let mut fields = BlockFields { mode: 13, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 0xFFFF;
        }
        let out = decode_block(&pack_block(&fields), true);
        assert_eq!(out, [[0; 3]; 16]);
        // The same bits as UF16: 0xFFFF finishes to 0xFFFF * 31 >> 6 = 0x7BFF.
        assert_eq!(decode_block(&pack_block(&fields), false), [[0x7BFF; 3]; 16]);
    }

    #[test]
    fn sf16_mode_14_endpoint_of_minus_32768_is_minus_infinity() {
        // D3D11 spec, SF16: unquantize passes 16-bit endpoints through (prec >= 16), and
        // finish_unquantize gives -((32768 * 31) >> 5) = -31744 = -0x7C00, i.e. 0xFC00 = -Inf.
        // bcdec agrees (tests/bc6h_decode.rs); found by the bc6h_block fuzz target.
        let mut fields = BlockFields { mode: 13, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 0x8000;
        }
        let block = pack_block(&fields);
        assert_eq!(decode_block(&block, true), [[0xFC00; 3]; 16]);
        let rgb = decode_surface(4, 4, &block, true).unwrap();
        assert!(rgb.iter().all(|&v| v == f32::NEG_INFINITY));
    }

    #[test]
    fn surface_size_mismatch_is_an_error() {
        assert!(matches!(decode_surface(5, 5, &[0; 63], false), Err(Error::Truncated { .. })));
        assert!(decode_surface(5, 5, &[0; 65], false).is_err());
        assert_eq!(decode_surface(5, 5, &[0; 64], false).unwrap().len(), 75);
        assert_eq!(decode_surface(0, 0, &[], false).unwrap().len(), 0);
    }
}
