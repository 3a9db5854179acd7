//! Colour conversion and output formatting (T.832 9.10; JXR-NOTES §7): from the inverse
//! transform's integer samples to the pixel format's samples, exactly as jxrlib's
//! `strdec.c: outputMBRow, outputNChannel, outputMBRowAlpha, interpolateUV` produce them.
//!
//! The work is done one image row at a time:
//! 1. [`upsample_chroma_row`]: a 4:2:0 or 4:2:2 chroma plane to a full-resolution row
//!    (jxrlib's `interpolateUV`: co-sited copies, rounded averages in between, the last row and
//!    column replicated; vertical first, then horizontal).
//! 2. [`OutputParams::format_row`]: bias, reversible colour transform (`_ICC`, `_ICC_CMYK`),
//!    the scaled-arithmetic rounding and 3-bit shift, then the bit depth's conversion, written
//!    as the pixel format lays out its samples (little-endian, padding bytes 0).
//! 3. [`OutputParams::row_to_f32`]: those samples to linear `f32` RGB or RGBA for an `HdrImage`.
//!
//! All integer steps wrap as jxrlib's C does (no input can make them panic); the deliberate
//! jxrlib behaviours kept here are quirks 2 (interleaved alpha rounding) and 3 (half wrapping)
//! of JXR-NOTES §8.

use crate::container::{OutputBitDepth, OutputColorFormat, PixelFormat};
use hdrcodec_core::transfer::{PqTransfer, SrgbTransfer};
use hdrcodec_core::{Error, Result};
use std::sync::OnceLock;

#[cfg(target_arch = "x86_64")]
mod avx2;

/// INTERNAL_CLR_FMT of the image plane header (T.832 Table 31): how the coded channels are
/// laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum InternalColorFormat {
    /// One luma channel.
    YOnly,
    /// Luma and two chroma channels subsampled 2× both ways.
    Yuv420,
    /// Luma and two chroma channels subsampled 2× horizontally.
    Yuv422,
    /// Luma and two full-resolution chroma channels.
    Yuv444,
    /// YUV 4:4:4 and a K channel (CMYK).
    Yuvk,
    /// `n` independent channels.
    NComponent(u8),
}

impl InternalColorFormat {
    /// The format with the 3-bit code `code` (0 YONLY, 1 YUV420, 2 YUV422, 3 YUV444, 4 YUVK,
    /// 6 NCOMPONENT with `channels` channels); `None` for reserved codes.
    pub fn from_code(code: u8, channels: u8) -> Option<Self> {
        Some(match code {
            0 => Self::YOnly,
            1 => Self::Yuv420,
            2 => Self::Yuv422,
            3 => Self::Yuv444,
            4 => Self::Yuvk,
            6 => Self::NComponent(channels),
            _ => return None,
        })
    }

    /// Coded channels (without a separate alpha plane).
    pub fn channels(self) -> usize {
        match self {
            Self::YOnly => 1,
            Self::Yuv420 | Self::Yuv422 | Self::Yuv444 => 3,
            Self::Yuvk => 4,
            Self::NComponent(n) => usize::from(n),
        }
    }
}

/// The scaled-arithmetic shift: SHIFTZERO (1) + QPFRACBITS (2) fraction bits the encoder adds
/// when SCALED_FLAG is set (jxrlib `strcodec.h`; T.832 9.10).
const SCALED_SHIFT: u32 = 3;

/// The reversible colour transform, decoder side (jxrlib `strdec.c: _ICC`; T.832 9.10.2):
/// from Y (with the output bias already added), U and V to R, G, B.
#[inline(always)]
pub fn inverse_cc(y: i32, u: i32, v: i32) -> (i32, i32, i32) {
    let r = u.wrapping_neg();
    let g = y.wrapping_sub(r >> 1);
    let r = r.wrapping_sub((v.wrapping_add(1) >> 1).wrapping_sub(g));
    let b = v.wrapping_add(r);
    (r, g, b)
}

/// The reversible colour transform, encoder side (jxrlib `strenc.c: _CC`): R, G, B to Y, U, V
/// (the output bias not yet subtracted). [`inverse_cc`] undoes it exactly.
#[inline(always)]
pub fn forward_cc(r: i32, g: i32, b: i32) -> (i32, i32, i32) {
    let b = b.wrapping_sub(r);
    let r = r.wrapping_add((b.wrapping_add(1) >> 1).wrapping_sub(g));
    let g = g.wrapping_add(r >> 1);
    (g, r.wrapping_neg(), b)
}

/// The CMYK colour transform, decoder side (jxrlib `_ICC_CMYK`): from the coded (Y, U, V, K)
/// with biases already applied as `outputMBRow` does (M = −Y + bias1, C = U, Y' = −V,
/// K = K + bias2) to C, M, Y, K.
#[inline(always)]
fn inverse_cc_cmyk(c: i32, m: i32, y: i32, k: i32) -> (i32, i32, i32, i32) {
    let k = k.wrapping_sub(m.wrapping_add(1) >> 1);
    let m = m.wrapping_sub((c >> 1).wrapping_sub(k));
    let c = c.wrapping_sub((y.wrapping_add(1) >> 1).wrapping_sub(m));
    let y = y.wrapping_add(c);
    (c, m, y, k)
}

/// The CMYK colour transform, encoder side (jxrlib `strenc.c: _CC_CMYK`), in place of
/// (c, m, y, k); the inverse of the decoder's `_ICC_CMYK`.
#[inline(always)]
pub fn forward_cc_cmyk(c: i32, m: i32, y: i32, k: i32) -> (i32, i32, i32, i32) {
    let y = y.wrapping_sub(c);
    let c = c.wrapping_add((y.wrapping_add(1) >> 1).wrapping_sub(m));
    let m = m.wrapping_add((c >> 1).wrapping_sub(k));
    let k = k.wrapping_add(m.wrapping_add(1) >> 1);
    (c, m, y, k)
}

/// The 16-bit half bit pattern of an integer sample (jxrlib `backwardHalf`): the low 15 bits
/// are the magnitude and the sign becomes the sign bit. The magnitude wraps modulo 2^15
/// (JXR-NOTES §8 quirk 3; T.835 saturates at 0x7FFF instead).
#[inline(always)]
pub fn int_to_half_bits(h: i32) -> u16 {
    let s = h >> 31;
    ((h & 0x7fff) ^ s).wrapping_sub(s) as u16
}

/// An IEEE half (its bits) as f32, exactly, without branches on the value so that a loop of
/// these vectorises: the exponent is rebiased in place; infinities and NaNs (exponent 31)
/// get the single-precision maximum exponent; denormals (exponent 0) are scaled by 2^-24 in
/// single precision, where they are normal.
#[inline(always)]
pub fn half_bits_to_f32(h: u16) -> f32 {
    let h = u32::from(h);
    let sign = (h & 0x8000) << 16;
    let exp = h & 0x7c00;
    let magnitude = (h & 0x7fff) << 13;
    let normal = magnitude + ((127 - 15) << 23);
    let special = magnitude | 0x7f80_0000;
    let denormal = (((h & 0x3ff) as f32) * f32::from_bits((127 - 24) << 23)).to_bits();
    let bits = if exp == 0x7c00 {
        special
    } else if exp == 0 {
        denormal
    } else {
        normal
    };
    f32::from_bits(sign | bits)
}

/// The IEEE single bit pattern of an integer sample coded as a mini-float with `len_mantissa`
/// mantissa bits and exponent bias `exp_bias` (jxrlib `pixel2float`; T.832 9.10.5). Exponent
/// overflow is not checked, as in jxrlib. `len_mantissa` must be at most 23.
#[inline(always)]
pub fn int_to_float_bits(h: i32, exp_bias: i8, len_mantissa: u32) -> u32 {
    // Without branches on the value (dark and bright samples mix in every row, and a
    // mispredicted branch per sample cost more than both paths): the normal and the
    // denormal result are both computed, then one is chosen.
    let lm = len_mantissa.min(23);
    let lmshift = 1i32 << lm;
    let s = h >> 31;
    let a = (h ^ s).wrapping_sub(s); // |h|, wrapping for i32::MIN as C does
    let e0 = ((a as u32) >> lm) as i32;
    let m0 = a & (lmshift - 1);
    let sign = (s as u32) & 0x8000_0000;
    // A normal mini-float: the hidden bit is dropped, the exponent rebiased (no overflow
    // check, as in jxrlib).
    let e_norm = e0.wrapping_add(127 - i32::from(exp_bias));
    let normal = sign | (e_norm as u32).wrapping_shl(23) | ((m0 as u32) << (23 - lm));
    // A denormal mini-float (exponent field 0, read as 1): jxrlib shifts the mantissa up one
    // bit at a time while the exponent stays above 1 (`while (m < lmshift && e > 1 && m > 0)
    // { e--; m <<= 1; }`), which is one shift by k = min(lm − floor(log2 m0), e − 1). If
    // that reaches the hidden bit, the result is normal: exponent e − k, and below the hidden
    // bit the bits of m0 under its leading one, which are the mantissa field of m0 as an f32
    // (exact: m0 < 2^23). Else it is an IEEE denormal, m0 << k placed at bit 23 − lm: an
    // integer below 2^23, made by scaling m0 as an f32 (exactly, by a power of two) and read
    // from the mantissa of its sum with 2^23. No shift by a per-sample count, no float to int
    // conversion (with its saturation), so that a loop of these vectorises; floor(log2 m0) is
    // the exponent of m0 as a float (−127 for 0, whose shift is then cut and changes nothing).
    let e_den = 128 - i32::from(exp_bias);
    let fm = m0 as f32;
    let log2 = (fm.to_bits() >> 23) as i32 - 127;
    let k = (lm as i32 - log2).min(e_den - 1).clamp(0, 24);
    let reached = log2 + k >= lm as i32;
    let full = ((e_den - k) as u32).wrapping_shl(23) | (fm.to_bits() & 0x7f_ffff);
    let scaled = fm * f32::from_bits(((k + 23 - lm as i32 + 127) as u32) << 23);
    let part = (scaled + 8_388_608.0).to_bits() - 0x4b00_0000;
    let denormal = sign | if reached { full } else { part };
    if e0 == 0 {
        denormal
    } else {
        normal
    }
}

/// An f32 as the bits of the nearest IEEE half (ties to even; beyond the largest half,
/// infinity; NaN stays NaN), exactly what `half::f16::from_f32` gives, without its run-time
/// CPU check per call and with few branches, so that the encoder's conversion loop stays
/// tight. Halves round at bit 13 of the f32 mantissa; below 2^-14 (subnormal halves) at a
/// bit that moves with the exponent.
#[inline(always)]
pub fn f32_to_half_bits(value: f32) -> u16 {
    let x = value.to_bits();
    let sign = ((x >> 16) & 0x8000) as u16;
    let abs = x & 0x7fff_ffff;
    if abs >= 0x4780_0000 {
        // 2^16 and above: infinity (as from 65520 up, by the rounding below), or NaN (quiet,
        // with the top mantissa bits kept).
        return sign | if abs > 0x7f80_0000 { 0x7e00 | ((abs >> 13) & 0x3ff) as u16 } else { 0x7c00 };
    }
    if abs < 0x3880_0000 {
        // Below 2^-14: a subnormal half (or zero), the mantissa with its hidden bit shifted
        // right by 14 − e, rounded to nearest even. Below 2^-25 everything rounds to zero.
        if abs < 0x3300_0000 {
            return sign;
        }
        let e = (abs >> 23) as i32 - 127 + 15;
        let m = (abs & 0x7f_ffff) | 0x80_0000;
        let shift = (14 - e) as u32; // 14..=24
        let h = m >> shift;
        let rem = m & ((1 << shift) - 1);
        let halfway = 1 << (shift - 1);
        let up = u32::from(rem > halfway || (rem == halfway && h & 1 != 0));
        return sign | (h + up) as u16;
    }
    // Normal: rebias the exponent, round the mantissa at bit 13 to nearest even (a carry
    // moves into the exponent, up to infinity, which is what the bits do).
    let h = (abs - ((127 - 15) << 23)) >> 13;
    let rem = abs & 0x1fff;
    let up = u32::from(rem > 0x1000 || (rem == 0x1000 && h & 1 != 0));
    sign | (h + up) as u16
}

/// The encoder's colour rows from half RGB: the integer codes of the samples `src` (RGB,
/// interleaved) times `scale` as halves ([`half_bits_to_int`] of [`f32_to_half_bits`]; NaN
/// as 0 and magnitudes beyond the largest half, infinities included, as ±65504, each
/// counted), shifted left by `shift` and through [`forward_cc`] into the planes Y, U and V
/// (one value a pixel; as many pixels as the shortest). Returns (NaNs, clipped).
///
/// On x86-64 with AVX2 (and F16C, which [`hdrcodec_core::cpu`]'s AVX2 level includes) eight
/// pixels at a time: the channels gathered into vectors, converted by the CPU's own
/// float → half instruction (round to nearest even, as [`f32_to_half_bits`]), the colour
/// transform on the vectors; `half_rgb_yuv_twins_agree` checks it against the portable code.
#[allow(unsafe_code)]
pub fn half_rgb_yuv(src: &[f32], scale: f32, shift: u32, [y, u, v]: [&mut [i32]; 3]) -> (usize, usize) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C; the twin
        // needs AVX2 and F16C.
        return unsafe { half_rgb_yuv_avx2(src, scale, shift, [y, u, v]) };
    }
    half_rgb_yuv_portable(src, scale, shift, [y, u, v])
}

/// The portable [`half_rgb_yuv`]: [`half_code`] and [`forward_cc`] pixel by pixel.
fn half_rgb_yuv_portable(src: &[f32], scale: f32, shift: u32, [y, u, v]: [&mut [i32]; 3]) -> (usize, usize) {
    let (mut nans, mut clipped) = (0u32, 0u32);
    for (((p, y), u), v) in src.chunks_exact(3).zip(y.iter_mut()).zip(u.iter_mut()).zip(v.iter_mut()) {
        let mut code = [0i32; 3];
        for (c, &s) in code.iter_mut().zip(p) {
            let (h, nan, clip) = half_code(s * scale);
            *c = h << shift;
            nans += nan;
            clipped += clip;
        }
        (*y, *u, *v) = forward_cc(code[0], code[1], code[2]);
    }
    (nans as usize, clipped as usize)
}

/// The AVX2 + F16C twin of [`half_rgb_yuv_portable`], eight pixels a step; the pixels after
/// the last whole step go through the portable code.
///
/// # Safety
/// The CPU must support AVX2 and F16C.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
#[allow(unsafe_code)]
unsafe fn half_rgb_yuv_avx2(src: &[f32], scale: f32, shift: u32, [y, u, v]: [&mut [i32]; 3]) -> (usize, usize) {
    use std::arch::x86_64::*;
    let n = y.len().min(u.len()).min(v.len()).min(src.len() / 3);
    let full = n - n % 8;
    let load = |s: &[f32], k: usize| -> __m256 {
        let s: &[f32; 8] = s[8 * k..8 * k + 8].try_into().expect("8 floats");
        // SAFETY: `s` holds 8 floats, exactly what the unaligned load reads.
        unsafe { _mm256_loadu_ps(s.as_ptr()) }
    };
    let store = |d: &mut [i32], x: __m256i| {
        let d: &mut [i32; 8] = (&mut d[..8]).try_into().expect("8 values");
        // SAFETY: `d` holds 8 values, exactly what the unaligned store writes.
        unsafe { _mm256_storeu_si256(d.as_mut_ptr().cast(), x) }
    };
    let (scale_v, count) = (_mm256_set1_ps(scale), _mm_cvtsi32_si128(shift as i32));
    let (inf, max) = (_mm256_set1_epi32(0x7c00), _mm256_set1_epi32(0x7bff));
    let (mut nans, mut clipped) = (0u32, 0u32);
    // One channel of 8 pixels: its codes (shifted), counting NaNs and clipped values.
    let mut codes = |x: __m256| -> __m256i {
        // Round to nearest even (T.832's halves are IEEE's; the immediate overrides MXCSR).
        let h = _mm256_cvtepu16_epi32(_mm256_cvtps_ph::<_MM_FROUND_TO_NEAREST_INT>(_mm256_mul_ps(x, scale_v)));
        let abs = _mm256_and_si256(h, _mm256_set1_epi32(0x7fff));
        let nan = _mm256_cmpgt_epi32(abs, inf);
        let big = _mm256_cmpeq_epi32(abs, inf);
        nans += (_mm256_movemask_ps(_mm256_castsi256_ps(nan)) as u32).count_ones();
        clipped += (_mm256_movemask_ps(_mm256_castsi256_ps(big)) as u32).count_ones();
        let magnitude = _mm256_andnot_si256(nan, _mm256_min_epi32(abs, max));
        // The sign bit (bit 15) to a mask of 0 or −1, then (m ^ s) − s.
        let s = _mm256_srai_epi32::<31>(_mm256_slli_epi32::<16>(h));
        _mm256_sll_epi32(_mm256_sub_epi32(_mm256_xor_si256(magnitude, s), s), count)
    };
    for (i, px) in src[..3 * full].chunks_exact(24).enumerate() {
        // Lanes of (a0, a1, a2) hold samples 3i + c: blend each channel's lanes together (in
        // the order 0 3 6 1 4 7 2 5, rotated for G and B) and permute them into order.
        let (a0, a1, a2) = (load(px, 0), load(px, 1), load(px, 2));
        let rr = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(a0, a1), a2);
        let gg = _mm256_blend_ps::<0b0100_1001>(_mm256_blend_ps::<0b0010_0100>(a0, a1), a2);
        let bb = _mm256_blend_ps::<0b1001_0010>(_mm256_blend_ps::<0b0100_1001>(a0, a1), a2);
        let r = codes(_mm256_permutevar8x32_ps(rr, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5)));
        let g = codes(_mm256_permutevar8x32_ps(gg, _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6)));
        let b = codes(_mm256_permutevar8x32_ps(bb, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7)));
        // forward_cc on the vectors (wrapping adds, arithmetic shifts).
        let b = _mm256_sub_epi32(b, r);
        let r =
            _mm256_add_epi32(r, _mm256_sub_epi32(_mm256_srai_epi32::<1>(_mm256_add_epi32(b, _mm256_set1_epi32(1))), g));
        let g = _mm256_add_epi32(g, _mm256_srai_epi32::<1>(r));
        let at = 8 * i;
        store(&mut y[at..], g);
        store(&mut u[at..], _mm256_sub_epi32(_mm256_setzero_si256(), r));
        store(&mut v[at..], b);
    }
    let (tail_nans, tail_clipped) =
        half_rgb_yuv_portable(&src[3 * full..], scale, shift, [&mut y[full..], &mut u[full..], &mut v[full..]]);
    (nans as usize + tail_nans, clipped as usize + tail_clipped)
}

/// One sample of [`half_rgb_yuv`]: (code, NaN, clipped), every case computed and one selected.
#[inline(always)]
fn half_code(v: f32) -> (i32, u32, u32) {
    let x = v.to_bits();
    let abs = x & 0x7fff_ffff;
    // Normal halves: the exponent rebiased, the mantissa rounded at bit 13 to nearest even
    // (a carry moves into the exponent, up to infinity).
    let h = abs.wrapping_sub((127 - 15) << 23) >> 13;
    let rem = abs & 0x1fff;
    let normal = h + u32::from((rem > 0x1000) | ((rem == 0x1000) & (h & 1 != 0)));
    // Below 2^-14, subnormal halves: the mantissa with its hidden bit shifted right by
    // 126 − exponent (14..=24; from 25 on everything rounds to 0), rounded to nearest even.
    let shift = 126u32.saturating_sub(abs >> 23).min(31);
    let m = (abs & 0x7f_ffff) | 0x80_0000;
    let hs = m >> shift;
    let rs = m & ((1u32 << shift) - 1);
    let halfway = (1u32 << shift) >> 1;
    let subnormal = hs + u32::from((rs > halfway) | ((rs == halfway) & (hs & 1 != 0)));
    let bits = if abs < 0x3880_0000 { subnormal } else { normal };
    let nan = abs > 0x7f80_0000;
    let big = (abs >= 0x4780_0000) | (bits >= 0x7c00);
    let magnitude = if nan {
        0
    } else if big {
        0x7bff
    } else {
        bits as i32
    };
    let code = if x >> 31 != 0 { -magnitude } else { magnitude };
    (code, u32::from(nan), u32::from(big & !nan))
}

/// The encoder's side of [`int_to_half_bits`]: a half's bit pattern as the integer sample
/// that codes it (sign and magnitude; negative zero becomes zero).
#[inline(always)]
pub fn half_bits_to_int(h: u16) -> i32 {
    let magnitude = i32::from(h & 0x7fff);
    if h & 0x8000 != 0 {
        -magnitude
    } else {
        magnitude
    }
}

/// The encoder's side of [`int_to_float_bits`]: the integer sample whose mini-float (with
/// `len_mantissa` ≤ 23 mantissa bits and exponent bias `exp_bias`) is nearest to `f`, ties
/// away from zero (as jxrlib's `float2pixel` rounds). Values past the largest mini-float
/// that decodes to a finite single become the largest; `f` must be finite.
pub fn float_to_int(f: f32, exp_bias: i8, len_mantissa: u32) -> i32 {
    let lm = len_mantissa.min(23) as i32;
    let a = f64::from(f.abs());
    if a == 0.0 || !a.is_finite() {
        return 0;
    }
    let eb = i32::from(exp_bias);
    // Exponent field e0 ≥ 1: value (1 + m / 2^lm) · 2^(e0 − eb); e0 = 0: m · 2^(1 − eb − lm).
    let scale = |a: f64, e: i32| a * 2f64.powi(e);
    let e = ((a.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    let e0 = e + eb;
    let h: i64 = if e0 < 1 {
        scale(a, eb + lm - 1).round() as i64
    } else {
        // The fraction below the hidden bit, rounded; a carry moves to the exponent, which is
        // what adding to the integer does.
        (i64::from(e0) << lm) + (scale(a, lm - e) - f64::from(1 << lm)).round() as i64
    };
    // Largest exponent field whose IEEE exponent (e0 + 127 − eb) stays below 255.
    let max = ((i64::from(127 + eb)) << lm) | ((1 << lm) - 1);
    let h = h.min(max).min(i64::from(i32::MAX)) as i32;
    if f.is_sign_negative() {
        -h
    } else {
        h
    }
}

/// One channel of RGBE (jxrlib `inverseConvert`): (mantissa, exponent), each 0..=255: 0 and 0
/// for `v` ≤ 0, `v` and 1 below 256, else the 7 bits below the leading ones and `v >> 7` cast
/// to 8 bits. Selects, not branches, so that runs of pixels vectorise.
#[inline(always)]
fn rgbe_channel(v: i32) -> (i32, i32) {
    let big = v >= 256;
    let m = if big { (v & 0x7f) | 0x80 } else { v & 0xff };
    let e = if big { (v >> 7) & 0xff } else { 1 };
    let positive = -i32::from(v > 0);
    (m & positive, e & positive)
}

/// R, G, B integer samples to RGBE bytes (jxrlib `inverseConvertRGBE`): the largest exponent
/// is shared, the other mantissas shift right with rounding; E is an 8-bit cast (not clamped).
///
/// jxrlib's shift, `(2m + 1) >> (E − e + 1)`, is a C `int` shift that reaches 32 and more when
/// a channel is far below the largest (or zero, whose own exponent is 0); x86-64 and AArch64
/// take the count modulo 32, so jxrlib's mantissa is `(2m + 1) >> ((E − e + 1) mod 32)`, not 0.
/// We do the same, which is what jxrlib's files decode to (a zero channel under E = 31, 63, ...
/// 255 comes out as mantissa 1; a small one under a large E as a larger mantissa). Found with
/// lossy RGBE files of our encoder, whose ringing leaves such channels.
///
/// Without branches on the samples (a run of pixels vectorises, the shifts per lane in AVX2).
#[inline(always)]
pub fn int_to_rgbe(r: i32, g: i32, b: i32) -> [u8; 4] {
    u32::to_le_bytes(int_to_rgbe_word(r, g, b))
}

/// [`int_to_rgbe`]'s bytes as one little-endian word.
#[inline(always)]
fn int_to_rgbe_word(r: i32, g: i32, b: i32) -> u32 {
    let ch = [rgbe_channel(r), rgbe_channel(g), rgbe_channel(b)];
    let e = ch[0].1.max(ch[1].1).max(ch[2].1);
    let mant = |(m, ce): (i32, i32)| -> u32 {
        // e − ce + 1 is at least 2 where it is used; as a C int shift, modulo 32.
        let shifted = ((m * 2 + 1) as u32) >> ((e - ce + 1) & 31) as u32;
        (if e > ce { shifted } else { m as u32 }) & 0xff
    };
    mant(ch[0]) | mant(ch[1]) << 8 | mant(ch[2]) << 16 | (e as u32) << 24
}

/// One full-resolution row of a subsampled chroma plane, interpolated as jxrlib's
/// `interpolateUV` does (4:2:0 and 4:2:2 to 4:4:4): even columns (and for 4:2:0 even rows) are
/// copies, the others the rounded-up average of their two neighbours, the last odd row and
/// column replicate their neighbour. Vertical first, then horizontal.
///
/// `plane` is `src_w × src_h`, row-major (the subsampled size of the extended image: 4:2:0
/// `ext_w/2 × ext_h/2`, 4:2:2 `ext_w/2 × ext_h`); `out` receives `2 × src_w` samples of
/// full-resolution row `y` (`y < 2 × src_h` for 4:2:0, `y < src_h` for 4:2:2). Other internal
/// formats are not subsampled: the plane row is copied.
pub fn upsample_chroma_row(
    internal: InternalColorFormat,
    plane: &[i32],
    src_w: usize,
    src_h: usize,
    y: usize,
    out: &mut [i32],
) -> Result<()> {
    let bad = || Error::invalid("chroma plane smaller than its declared size");
    match internal {
        InternalColorFormat::Yuv422 => {
            let row = plane.get(y * src_w..(y + 1) * src_w).ok_or_else(bad)?;
            upsample_horizontal(row, out)
        }
        InternalColorFormat::Yuv420 => {
            let row = |r: usize| plane.get(r * src_w..(r + 1) * src_w).ok_or_else(bad);
            let mut vertical = vec![0i32; src_w];
            let top = row(y / 2)?;
            if y.is_multiple_of(2) || y / 2 + 1 >= src_h {
                vertical.copy_from_slice(top);
            } else {
                let bottom = row(y / 2 + 1)?;
                for ((v, &t), &b) in vertical.iter_mut().zip(top).zip(bottom) {
                    *v = t.wrapping_add(b).wrapping_add(1) >> 1;
                }
            }
            upsample_horizontal(&vertical, out)
        }
        _ => {
            let row = plane.get(y * src_w..(y + 1) * src_w).ok_or_else(bad)?;
            out.get_mut(..src_w).ok_or_else(bad)?.copy_from_slice(row);
            Ok(())
        }
    }
}

fn upsample_horizontal(row: &[i32], out: &mut [i32]) -> Result<()> {
    let n = row.len();
    let out = out.get_mut(..2 * n).ok_or_else(|| Error::invalid("chroma output row too short"))?;
    for (i, &c) in row.iter().enumerate() {
        out[2 * i] = c;
    }
    for i in 0..n.saturating_sub(1) {
        out[2 * i + 1] = row[i].wrapping_add(row[i + 1]).wrapping_add(1) >> 1;
    }
    if n > 0 {
        out[2 * n - 1] = row[n - 1];
    }
    Ok(())
}

/// How an alpha channel is rounded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlphaParams {
    /// SCALED_FLAG used for alpha. jxrlib uses the *primary* plane's flag for an interleaved
    /// alpha plane (JXR-NOTES §8 quirk 2) and the alpha codestream's own for planar alpha.
    pub scaled: bool,
    /// jxrlib's `outputMBRowAlpha` rounding (interleaved alpha, quirk 2): +4 before the 3-bit
    /// shift for every bit depth, and BD16's bias without SHIFT_BITS. `false`: the same rounding
    /// as the colour channels (planar alpha, and T.835 for interleaved alpha).
    pub jxrlib_interleaved: bool,
}

/// Everything output formatting needs from the headers. Build with [`OutputParams::new`],
/// which checks the combination is one this module implements.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputParams {
    /// The pixel format of the container (sample layout, order, padding).
    pub format: &'static PixelFormat,
    /// OUTPUT_BITDEPTH of the codestream.
    pub bit_depth: OutputBitDepth,
    /// OUTPUT_CLR_FMT of the codestream.
    pub color: OutputColorFormat,
    /// INTERNAL_CLR_FMT of the primary plane.
    pub internal: InternalColorFormat,
    /// SCALED_FLAG of the primary plane.
    pub scaled: bool,
    /// SHIFT_BITS (BD16, BD16S, BD32S) or LEN_MANTISSA (BD32F); 0 otherwise.
    pub shift: u8,
    /// EXP_BIAS (BD32F).
    pub exp_bias: i8,
    /// RED_BLUE_NOT_SWAPPED_FLAG (jxrlib's `bRBSwapped`): for BD5, BD565 and BD10, 0 puts the
    /// first channel (R) in the low field, 1 in the high field (JXR-NOTES §8 quirk 8).
    pub red_blue_flag: bool,
    /// The alpha channel's rounding, when the pixel format has alpha.
    pub alpha: Option<AlphaParams>,
    /// How the integer formats' colour samples become linear light in
    /// [`row_to_f32`](Self::row_to_f32) (sRGB unless the file says otherwise).
    pub transfer: SampleTransfer,
}

/// How the colour samples of the integer formats (BD1, BD8, BD16, BD5, BD565, BD10) map to
/// linear light. The half, float, fixed-point and RGBE formats are linear by definition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleTransfer {
    /// The sRGB EOTF (IEC 61966-2-1): WIC's convention for files that say nothing.
    Srgb,
    /// Code / maximum code, as it is: linear samples, or the signal of a transfer function
    /// this decoder does not apply (the caller says so).
    Linear,
    /// SMPTE ST 2084 (PQ), absolute, in units of 80 cd/m² (scRGB's 1.0).
    Pq,
}

/// The luminance of scRGB's 1.0, the unit of every linear sample this crate returns.
pub const NITS_PER_UNIT: f32 = 80.0;

impl SampleTransfer {
    /// Linear light of a signal in [0, 1].
    pub fn decode(self, signal: f64) -> f64 {
        match self {
            SampleTransfer::Srgb => SrgbTransfer::decode(signal),
            SampleTransfer::Linear => signal,
            SampleTransfer::Pq => PqTransfer::decode(signal) / f64::from(NITS_PER_UNIT),
        }
    }

    /// [`decode`](Self::decode) of every 16-bit code (8-bit codes use every 257th entry).
    fn table_u16(self) -> &'static [f32] {
        static TABLES: [OnceLock<Vec<f32>>; 3] = [OnceLock::new(), OnceLock::new(), OnceLock::new()];
        TABLES[self as usize]
            .get_or_init(|| (0..=65535u32).map(|c| self.decode(f64::from(c) / 65535.0) as f32).collect())
    }
}

impl OutputParams {
    /// Checks the parameters: the bit depth must be the pixel format's, SHIFT_BITS and
    /// LEN_MANTISSA must be usable, and the combination one this module implements (RGB from
    /// YONLY/YUV420/YUV422/YUV444/NCOMPONENT(3), RGBE, CMYK from YUVK, and YONLY, YUV444,
    /// NCOMPONENT and CMYKDIRECT output of as many channels as coded).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        format: &'static PixelFormat,
        bit_depth: OutputBitDepth,
        color: OutputColorFormat,
        internal: InternalColorFormat,
        scaled: bool,
        shift: u8,
        exp_bias: i8,
        red_blue_flag: bool,
        alpha: Option<AlphaParams>,
    ) -> Result<Self> {
        use OutputBitDepth::*;
        use OutputColorFormat as C;
        let bd1 = |b| matches!(b, Bd1White1 | Bd1Black1);
        if bit_depth != format.bit_depth && !(bd1(bit_depth) && bd1(format.bit_depth)) {
            return Err(Error::invalid(format!(
                "OUTPUT_BITDEPTH {bit_depth:?} does not match pixel format {} ({:?})",
                format.name, format.bit_depth
            )));
        }
        if color != format.color {
            return Err(Error::invalid(format!(
                "OUTPUT_CLR_FMT {color:?} does not match pixel format {} ({:?})",
                format.name, format.color
            )));
        }
        let max_shift = match bit_depth {
            Bd16 | Bd16S => 16,
            Bd32S => 31,
            Bd32F => 23,
            _ => 255,
        };
        if shift > max_shift {
            return Err(Error::unsupported(format!("SHIFT_BITS or LEN_MANTISSA {shift} for {bit_depth:?}")));
        }
        let n = internal.channels();
        let ok = match color {
            C::Rgb => match internal {
                InternalColorFormat::YOnly => matches!(bit_depth, Bd8 | Bd16 | Bd16S | Bd16F | Bd32S | Bd32F),
                InternalColorFormat::Yuv420 | InternalColorFormat::Yuv422 | InternalColorFormat::Yuv444 => true,
                InternalColorFormat::NComponent(3) => true,
                _ => false,
            },
            C::Rgbe => bit_depth == Bd8 && n == 3 && !matches!(internal, InternalColorFormat::NComponent(_)),
            C::Cmyk => internal == InternalColorFormat::Yuvk && matches!(bit_depth, Bd8 | Bd16 | Bd16S),
            C::YOnly => n == 1,
            C::Yuv444 | C::NComponent | C::CmykDirect => {
                n == usize::from(format.channels) && !matches!(bit_depth, Bd5 | Bd565 | Bd10 | Bd1White1 | Bd1Black1)
            }
            C::Yuv420 | C::Yuv422 => false,
        };
        if !ok || (format.alpha && alpha.is_none()) {
            return Err(Error::unsupported(format!(
                "JPEG XR output of pixel format {} from internal format {internal:?}{}",
                format.name,
                if format.alpha && alpha.is_none() { " without an alpha plane" } else { "" }
            )));
        }
        if alpha.is_some() && !format.alpha {
            return Err(Error::unsupported(format!("an alpha plane with pixel format {}", format.name)));
        }
        if alpha.is_some() && !matches!(color, C::Rgb | C::Cmyk | C::NComponent | C::Yuv444 | C::CmykDirect) {
            return Err(Error::unsupported(format!("alpha with output colour format {color:?}")));
        }
        Ok(OutputParams {
            format,
            bit_depth,
            color,
            internal,
            scaled,
            shift,
            exp_bias,
            red_blue_flag,
            alpha,
            transfer: SampleTransfer::Srgb,
        })
    }

    /// Bytes one output row of `width` pixels takes.
    pub fn row_bytes(&self, width: usize) -> usize {
        (width * usize::from(self.format.bits_per_pixel)).div_ceil(8)
    }

    fn shift_amount(scaled: bool) -> u32 {
        if scaled {
            SCALED_SHIFT
        } else {
            0
        }
    }

    /// The value added to Y (or to every channel of N-channel output) before the colour
    /// transform: the bit depth's offset and, in scaled mode, the rounding (jxrlib
    /// `outputMBRow`; T.832 9.10.3).
    fn bias(&self) -> i32 {
        use OutputBitDepth::*;
        let s = Self::shift_amount(self.scaled);
        let round = if self.scaled { (1 << (s - 1)) - 1 } else { 0 };
        match self.bit_depth {
            Bd8 if self.color == OutputColorFormat::Rgbe => round,
            Bd8 => (128 << s) + round,
            Bd16 => (((1 << 15) >> self.shift) << s) + if self.scaled { 1 << (s - 1) } else { 0 },
            Bd5 => (16 << s) + round,
            Bd565 => (32 << s) + round,
            Bd10 => (512 << s) + round,
            Bd1White1 | Bd1Black1 => 0,
            Bd16S | Bd16F | Bd32S | Bd32F => round,
        }
    }

    /// Formats one row. `channels` holds the coded channels' full-resolution rows (Y, U, V
    /// [, K] or the N channels; 4:2:0 and 4:2:2 chroma already through
    /// [`upsample_chroma_row`]), each at least `width` long; `alpha` the alpha row if the
    /// format has one. Writes [`row_bytes`](Self::row_bytes)`(width)` bytes to `out`: the pixel
    /// format's samples, little-endian, in its channel order, padding channels 0.
    ///
    /// On x86-64 with AVX2 (as [`hdrcodec_core::cpu`] allows) the same code runs compiled for
    /// AVX2, where the colour transform and the sample conversions take eight pixels a step;
    /// the bytes are the same (`format_row_twins_agree`).
    #[allow(unsafe_code)]
    pub fn format_row(&self, channels: &[&[i32]], alpha: Option<&[i32]>, width: usize, out: &mut [u8]) -> Result<()> {
        #[cfg(target_arch = "x86_64")]
        if hdrcodec_core::cpu::avx2() {
            // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
            return unsafe { self.format_row_avx2((channels, alpha), width, out) };
        }
        self.format_row_portable((channels, alpha), width, out)
    }

    /// [`format_row_portable`](Self::format_row_portable) compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code)]
    unsafe fn format_row_avx2(&self, rows: RowSources, width: usize, out: &mut [u8]) -> Result<()> {
        self.format_row_body(rows, width, out, true)
    }

    /// The portable body of [`format_row`](Self::format_row).
    fn format_row_portable(&self, rows: RowSources, width: usize, out: &mut [u8]) -> Result<()> {
        self.format_row_body(rows, width, out, false)
    }

    /// The body of [`format_row`](Self::format_row); `avx2` (true only in
    /// [`format_row_avx2`](Self::format_row_avx2)) interleaves the RGB formats' samples with
    /// the `avx2` module's shuffles.
    #[inline(always)]
    #[allow(unsafe_code)]
    fn format_row_body(&self, (channels, alpha): RowSources, width: usize, out: &mut [u8], avx2: bool) -> Result<()> {
        let n = self.internal.channels();
        let short = || Error::invalid("output row shorter than the image width");
        if channels.len() < n || channels[..n].iter().any(|c| c.len() < width) {
            return Err(short());
        }
        let out = out.get_mut(..self.row_bytes(width)).ok_or_else(short)?;
        let alpha = match (self.alpha, alpha) {
            (Some(p), Some(a)) if a.len() >= width => Some((p, &a[..width])),
            (Some(_), _) => return Err(Error::invalid("the alpha row is missing or short")),
            (None, _) => None,
        };
        let s = Self::shift_amount(self.scaled);
        let bias = self.bias();
        let spp = usize::from(self.format.channels) + usize::from(self.format.alpha) + usize::from(self.format.padded);
        use OutputBitDepth::*;
        use OutputColorFormat as C;

        // Each pixel's colour channels, biased and colour-converted but not yet shifted; each
        // bit depth writes them with its own conversion (the per-sample work has no branch
        // on the format: `rgb!` instantiates one loop per conversion and colour source).
        let y = &channels[0][..width];
        let rgb_mode = self.color == C::Rgb || self.color == C::Rgbe;
        let gray_to_rgb = rgb_mode && self.internal == InternalColorFormat::YOnly;
        let (u, v) = if n >= 3 { (&channels[1][..width], &channels[2][..width]) } else { (y, y) };
        let grey = |x: usize| -> [i32; 3] {
            let g = y[x].wrapping_add(bias);
            [g, g, g]
        };
        let colour = |x: usize| -> [i32; 3] {
            let (r, g, b) = inverse_cc(y[x].wrapping_add(bias), u[x], v[x]);
            [r, g, b]
        };
        let convert = |x: usize| if gray_to_rgb { grey(x) } else { colour(x) };
        let (red, blue) = if self.format.bgr { (2, 0) } else { (0, 2) };
        let nl = u32::from(self.shift);
        let padded = self.format.padded;
        // The kernels write a pixel's fourth sample too: only where it is padding or alpha
        // (written after), as the portable code leaves it otherwise.
        let avx2 = avx2 && (spp == 3 || padded || alpha.is_some());
        let layout = RgbLayout { spp, padded, red, blue, avx2 };
        let yuv = [y, u, v];

        match (self.color, self.bit_depth) {
            (C::Rgb, Bd8) => write_rgb_runs(out, layout, yuv, bias, gray_to_rgb, |v| clip8(v >> s), |b| [b]),
            (C::Rgb, Bd16) => write_rgb_runs(
                out,
                layout,
                yuv,
                bias,
                gray_to_rgb,
                |v| (v >> s).wrapping_shl(nl).clamp(0, 65535) as u16,
                u16::to_le_bytes,
            ),
            (C::Rgb, Bd16S) => write_rgb_runs(
                out,
                layout,
                yuv,
                bias,
                gray_to_rgb,
                |v| (v >> s).wrapping_shl(nl).clamp(-32768, 32767) as i16 as u16,
                u16::to_le_bytes,
            ),
            (C::Rgb, Bd16F) => {
                // With AVX2, 48bppRGBHalf in groups of 16 pixels in one pass (`avx2::half_rgb48`); the
                // rest through the runs.
                #[allow(unused_mut)]
                let mut done = 0;
                #[cfg(target_arch = "x86_64")]
                if avx2 && spp == 3 && !gray_to_rgb {
                    // SAFETY: `avx2` is true only in `format_row_avx2`, which runs only when
                    // the CPU has AVX2.
                    done = unsafe { avx2::half_rgb48(out, yuv, bias, s, red != 0, width) };
                }
                let (out, yuv) = (&mut out[done * 2 * spp..], yuv.map(|p| &p[done..]));
                write_rgb_runs(out, layout, yuv, bias, gray_to_rgb, |v| int_to_half_bits(v >> s), u16::to_le_bytes)
            }
            (C::Rgb, Bd32S) => write_rgb_runs(
                out,
                layout,
                yuv,
                bias,
                gray_to_rgb,
                |v| (v >> s).wrapping_shl(nl) as u32,
                u32::to_le_bytes,
            ),
            (C::Rgb, Bd32F) => {
                let f = |v: i32| int_to_float_bits(v >> s, self.exp_bias, nl);
                write_rgb_runs(out, layout, yuv, bias, gray_to_rgb, f, u32::to_le_bytes)
            }
            (C::Rgb, Bd5 | Bd565 | Bd10) => {
                let (bits, gbits, shift_rb) = match self.bit_depth {
                    Bd5 => (5, 5, 0),
                    Bd565 => (5, 6, 1),
                    _ => (10, 10, 0),
                };
                let max = (1 << bits) - 1;
                let gmax = (1 << gbits) - 1;
                let bytes = if self.bit_depth == Bd10 { 4 } else { 2 };
                for (x, px) in out.chunks_exact_mut(bytes).enumerate() {
                    let [r, g, b] = convert(x);
                    let r = (r >> (s + shift_rb)).clamp(0, max) as u32;
                    let g = (g >> s).clamp(0, gmax) as u32;
                    let b = (b >> (s + shift_rb)).clamp(0, max) as u32;
                    let (lo, hi) = if self.red_blue_flag { (b, r) } else { (r, b) };
                    let v = lo | g << bits | hi << (bits + gbits);
                    px.copy_from_slice(&v.to_le_bytes()[..bytes]);
                }
            }
            (C::Rgbe, _) => write_rgbe_runs(out, yuv, bias, gray_to_rgb, s),
            (C::YOnly, Bd1White1 | Bd1Black1) => {
                let threshold = if self.scaled { 1 << (s - 1) } else { 1 };
                let invert = u8::from(self.bit_depth == Bd1Black1);
                out.fill(0);
                for (x, &v) in y.iter().enumerate() {
                    let bit = (invert ^ u8::from(v >= threshold)) & 1;
                    out[x / 8] |= bit << (7 - (x % 8));
                }
            }
            (C::Cmyk, _) => {
                let (bias1, bias2): (i32, i32) = match self.bit_depth {
                    Bd8 => (128 << s, bias - (128 << s)),
                    Bd16 => (((32768 >> self.shift) << s), bias - ((32768 >> self.shift) << s)),
                    _ => (0, bias),
                };
                let k = &channels[3][..width];
                let u = &channels[1][..width];
                let v = &channels[2][..width];
                let bytes = if self.bit_depth == Bd8 { 1 } else { 2 };
                for (x, px) in out.chunks_exact_mut(bytes * spp).enumerate() {
                    let (c, m, yy, kk) =
                        inverse_cc_cmyk(u[x], bias1.wrapping_sub(y[x]), v[x].wrapping_neg(), k[x].wrapping_add(bias2));
                    for (i, val) in [c, m, yy, kk].into_iter().enumerate() {
                        match self.bit_depth {
                            Bd8 => px[i] = clip8(val >> s),
                            Bd16 => put16(px, i, ((val >> s).wrapping_shl(nl)).clamp(0, 65535) as u16),
                            // jxrlib casts BD16S CMYK to I16 without clamping.
                            _ => put16(px, i, (val >> s).wrapping_shl(nl) as i16 as u16),
                        }
                    }
                }
            }
            // YONLY, YUV444, NCOMPONENT and CMYKDIRECT: each channel on its own
            // (`outputNChannel`).
            _ => {
                let planes = &channels[..n];
                let exp_bias = self.exp_bias;
                match self.bit_depth {
                    Bd8 => write_channels::<1>(out, spp, padded, planes, |v| [clip8(v.wrapping_add(bias) >> s)]),
                    Bd16 => write_channels::<2>(out, spp, padded, planes, |v| {
                        ((v.wrapping_add(bias) >> s).wrapping_shl(nl).clamp(0, 65535) as u16).to_le_bytes()
                    }),
                    Bd16S => write_channels::<2>(out, spp, padded, planes, |v| {
                        ((v.wrapping_add(bias) >> s).wrapping_shl(nl).clamp(-32768, 32767) as i16).to_le_bytes()
                    }),
                    Bd16F => write_channels::<2>(out, spp, padded, planes, |v| {
                        int_to_half_bits(v.wrapping_add(bias) >> s).to_le_bytes()
                    }),
                    Bd32S => write_channels::<4>(out, spp, padded, planes, |v| {
                        ((v.wrapping_add(bias) >> s).wrapping_shl(nl)).to_le_bytes()
                    }),
                    _ => write_channels::<4>(out, spp, padded, planes, |v| {
                        int_to_float_bits(v.wrapping_add(bias) >> s, exp_bias, nl).to_le_bytes()
                    }),
                }
            }
        }

        if let Some((params, a)) = alpha {
            self.format_alpha(params, a, spp, out);
        }
        Ok(())
    }

    /// Writes the alpha samples into the last channel of each pixel (inlined, so that the
    /// AVX2 twin of `format_row` has its own copy).
    #[inline(always)]
    fn format_alpha(&self, params: AlphaParams, a: &[i32], spp: usize, out: &mut [u8]) {
        use OutputBitDepth::*;
        let s = Self::shift_amount(params.scaled);
        let half = if params.scaled { 1 << (s - 1) } else { 0 };
        let round = if params.jxrlib_interleaved || self.bit_depth == Bd16 { half } else { (half - 1).max(0) };
        let nl = u32::from(self.shift);
        let pos = spp - 1;
        match self.bit_depth {
            Bd8 => {
                let bias = (128 << s) + round;
                for (x, &v) in a.iter().enumerate() {
                    out[x * spp + pos] = clip8(v.wrapping_add(bias) >> s);
                }
            }
            Bd16 => {
                let offset = if params.jxrlib_interleaved { 1 << 15 } else { (1 << 15) >> self.shift };
                let bias = (offset << s) + round;
                for (x, &v) in a.iter().enumerate() {
                    let p = (v.wrapping_add(bias) >> s).wrapping_shl(nl);
                    put16(&mut out[(x * spp + pos) * 2..], 0, p.clamp(0, 65535) as u16);
                }
            }
            Bd16S | Bd16F => {
                for (x, &v) in a.iter().enumerate() {
                    let p = v.wrapping_add(round) >> s;
                    let bits = if self.bit_depth == Bd16S {
                        p.wrapping_shl(nl).clamp(-32768, 32767) as i16 as u16
                    } else {
                        int_to_half_bits(p)
                    };
                    put16(&mut out[(x * spp + pos) * 2..], 0, bits);
                }
            }
            _ => {
                // In runs, so that the conversion loop vectorises (see `write_rgb_runs`).
                let float = self.bit_depth != Bd32S;
                let mut bits = [0u32; 64];
                for (run, samples) in a.chunks(64).enumerate() {
                    for (b, &v) in bits.iter_mut().zip(samples) {
                        let p = v.wrapping_add(round) >> s;
                        *b = if float { int_to_float_bits(p, self.exp_bias, nl) } else { p.wrapping_shl(nl) as u32 };
                    }
                    for (i, &b) in bits[..samples.len()].iter().enumerate() {
                        put32(&mut out[((run * 64 + i) * spp + pos) * 4..], 0, b);
                    }
                }
            }
        }
    }
}

/// What [`OutputParams::format_row`] formats: the coded channels' rows and the alpha row.
type RowSources<'a> = (&'a [&'a [i32]], Option<&'a [i32]>);

/// Where R, G and B go in a pixel of `spp` samples: R at sample `red`, G at 1, B at `blue`,
/// a padding sample after them zeroed when `padded`; `avx2` when the `avx2` module's
/// interleaving may run (only in `format_row_avx2`).
#[derive(Clone, Copy)]
struct RgbLayout {
    spp: usize,
    padded: bool,
    red: usize,
    blue: usize,
    avx2: bool,
}

/// A sample type of [`write_rgb_runs`], with the AVX2 interleaving of its runs where the
/// `avx2` module has one.
trait RunSample: Copy + Default {
    /// Writes the first of the `n` pixels of `out` (`spp` samples each; a fourth sample 0, or
    /// alpha's place, which `format_alpha` fills after) from the samples `c` in the pixel's
    /// order, as many as the kernel takes at once; returns how many pixels it wrote (none
    /// without a kernel for this sample type and layout). Call only when the CPU has AVX2.
    #[inline(always)]
    fn interleave_avx2(_out: &mut [u8], _spp: usize, _c: [&[Self]; 3], _n: usize) -> usize {
        0
    }
}

impl RunSample for u8 {}

impl RunSample for u16 {
    #[inline(always)]
    #[allow(unsafe_code)]
    fn interleave_avx2(out: &mut [u8], spp: usize, c: [&[u16]; 3], n: usize) -> usize {
        #[cfg(target_arch = "x86_64")]
        match spp {
            // SAFETY: the caller runs only when the CPU has AVX2 (`RgbLayout::avx2`).
            3 => return unsafe { avx2::interleave3x16(out, c, n) },
            // SAFETY: as above.
            4 => return unsafe { avx2::interleave4x16(out, c, n) },
            _ => {}
        }
        let _ = (out, spp, c, n);
        0
    }
}

impl RunSample for u32 {
    #[inline(always)]
    #[allow(unsafe_code)]
    fn interleave_avx2(out: &mut [u8], spp: usize, c: [&[u32]; 3], n: usize) -> usize {
        #[cfg(target_arch = "x86_64")]
        if spp == 4 {
            // SAFETY: the caller runs only when the CPU has AVX2 (`RgbLayout::avx2`).
            return unsafe { avx2::interleave4x32(out, c, n) };
        }
        let _ = (out, spp, c, n);
        0
    }
}

/// Writes the R, G, B samples of every pixel of `out` from the rows `yuv` (Y, U, V; with
/// `grey`, Y alone is each of R, G, B), Y biased by `bias`, each channel converted by `f` and
/// stored as the `B` little-endian bytes `bytes` gives. In runs: the colour transform of a run
/// of pixels, then `f` over each channel's run, then the bytes; the first two are lane-wise
/// loops without bounds checks, which the compiler vectorises when `f` has no branches.
#[inline(always)]
fn write_rgb_runs<T: RunSample, const B: usize>(
    out: &mut [u8],
    layout: RgbLayout,
    yuv: [&[i32]; 3],
    bias: i32,
    grey: bool,
    f: impl Fn(i32) -> T,
    bytes: impl Fn(T) -> [u8; B],
) {
    let RgbLayout { spp, padded, red, blue, avx2 } = layout;
    let mut ints = [[0i32; RUN]; 3];
    let mut converted = [[T::default(); RUN]; 3];
    for (run, chunk) in out.chunks_mut(B * spp * RUN).enumerate() {
        rgb_run(&mut ints, yuv, run * RUN, chunk.len() / (B * spp), bias, grey);
        for (src, dst) in ints.iter().zip(&mut converted) {
            for (d, &v) in dst.iter_mut().zip(src) {
                *d = f(v);
            }
        }
        let [rs, gs, bs] = &converted;
        let done = if avx2 && B == size_of::<T>() {
            let by_place: [&[T]; 3] = if red == 0 { [rs, gs, bs] } else { [bs, gs, rs] };
            T::interleave_avx2(chunk, spp, by_place, chunk.len() / (B * spp))
        } else {
            0
        };
        let pixels = chunk.chunks_exact_mut(B * spp).zip(rs.iter().zip(gs).zip(bs));
        for (p, ((&r, &g), &b)) in pixels.skip(done) {
            p[red * B..red * B + B].copy_from_slice(&bytes(r));
            p[B..2 * B].copy_from_slice(&bytes(g));
            p[blue * B..blue * B + B].copy_from_slice(&bytes(b));
            if padded {
                p[3 * B..4 * B].fill(0);
            }
        }
    }
}

/// Pixels a step of [`write_rgb_runs`] and [`write_rgbe_runs`] converts.
const RUN: usize = 64;

/// The R, G, B samples of pixels `start..start + n` (`n` ≤ [`RUN`]) of the rows `yuv` into
/// `ints` (see [`write_rgb_runs`]).
#[inline(always)]
fn rgb_run(ints: &mut [[i32; RUN]; 3], yuv: [&[i32]; 3], start: usize, n: usize, bias: i32, grey: bool) {
    let [ys, us, vs] = yuv.map(|plane| plane.get(start..).map_or(&[][..], |p| &p[..n.min(p.len())]));
    let [r_run, g_run, b_run] = ints;
    let rgb = r_run.iter_mut().zip(g_run.iter_mut()).zip(b_run.iter_mut());
    if grey {
        for (((r, g), b), &y) in rgb.zip(ys) {
            let v = y.wrapping_add(bias);
            [*r, *g, *b] = [v, v, v];
        }
    } else {
        for ((((r, g), b), &y), (&u, &v)) in rgb.zip(ys).zip(us.iter().zip(vs)) {
            (*r, *g, *b) = inverse_cc(y.wrapping_add(bias), u, v);
        }
    }
}

/// Writes the RGBE bytes of every pixel of `out` from the rows `yuv` (as [`write_rgb_runs`]),
/// each sample shifted right by `s` first ([`int_to_rgbe`]), in runs: the colour transform,
/// then the conversion of the run (lane-wise, branch-free), then the bytes.
#[inline(always)]
fn write_rgbe_runs(out: &mut [u8], yuv: [&[i32]; 3], bias: i32, grey: bool, s: u32) {
    let mut ints = [[0i32; RUN]; 3];
    let mut words = [0u32; RUN];
    for (run, chunk) in out.chunks_mut(4 * RUN).enumerate() {
        rgb_run(&mut ints, yuv, run * RUN, chunk.len() / 4, bias, grey);
        let [rs, gs, bs] = &ints;
        for (w, ((&r, &g), &b)) in words.iter_mut().zip(rs.iter().zip(gs).zip(bs)) {
            *w = int_to_rgbe_word(r >> s, g >> s, b >> s);
        }
        for (p, &w) in chunk.chunks_exact_mut(4).zip(&words) {
            p.copy_from_slice(&w.to_le_bytes());
        }
    }
}

/// Writes each plane of `planes` as one sample of every pixel (`outputNChannel`), converted by
/// `f`; a padding sample after them is zeroed.
#[inline(always)]
fn write_channels<const B: usize>(
    out: &mut [u8],
    spp: usize,
    padded: bool,
    planes: &[&[i32]],
    f: impl Fn(i32) -> [u8; B],
) {
    for (c, plane) in planes.iter().enumerate() {
        for (p, &v) in out.chunks_exact_mut(B * spp).zip(plane.iter()) {
            p[c * B..c * B + B].copy_from_slice(&f(v));
        }
    }
    if padded {
        let n = planes.len();
        for p in out.chunks_exact_mut(B * spp) {
            p[n * B..n * B + B].fill(0);
        }
    }
}

#[inline(always)]
fn clip8(v: i32) -> u8 {
    v.clamp(0, 255) as u8
}

#[inline(always)]
fn put16(px: &mut [u8], i: usize, v: u16) {
    px[2 * i..2 * i + 2].copy_from_slice(&v.to_le_bytes());
}

#[inline(always)]
fn put32(px: &mut [u8], i: usize, v: u32) {
    px[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
}

impl OutputParams {
    /// Channels of the linear rows [`row_to_f32`](Self::row_to_f32) produces: 3 (RGB) or 4
    /// (RGBA); an error for formats with no linear RGB meaning here (CMYK, N-channel, YCC).
    pub fn linear_channels(&self) -> Result<usize> {
        let format = self.format;
        match format.color {
            OutputColorFormat::Rgb | OutputColorFormat::Rgbe | OutputColorFormat::YOnly => {
                Ok(3 + usize::from(format.alpha))
            }
            _ => Err(Error::unsupported(format!("pixel format {} as linear RGB", format.name))),
        }
    }

    /// Converts one row of `width` pixels written by [`format_row`](Self::format_row) to
    /// linear-light f32, RGB or RGBA interleaved ([`linear_channels`](Self::linear_channels)); grey is replicated and BGR
    /// reordered. Half and float are taken as they are; fixed point s2.13 (BD16S) and s7.24
    /// (BD32S) scaled by 2^-13 and 2^-24; RGBE as Radiance decodes it, `(m + 0.5) · 2^(E − 136)`
    /// (0 when E = 0); the colour of integer formats (BD8, BD16, BD5, BD565, BD10) through
    /// [`transfer`](Self::transfer) (sRGB by the WIC convention, JXR-NOTES §7, unless the file
    /// says otherwise) and alpha linearly.
    pub fn row_to_f32(&self, raw: &[u8], width: usize, out: &mut [f32]) -> Result<()> {
        use OutputBitDepth::*;
        let format = self.format;
        let lc = self.linear_channels()?;
        let bytes = (width * usize::from(format.bits_per_pixel)).div_ceil(8);
        let short = || Error::invalid("row buffer shorter than the image width");
        let raw = raw.get(..bytes).ok_or_else(short)?;
        let out = out.get_mut(..width * lc).ok_or_else(short)?;
        let gray = format.color == OutputColorFormat::YOnly;
        let colour = if gray { 1 } else { 3 };
        let spp = colour + usize::from(format.alpha) + usize::from(format.padded);
        let order: [usize; 3] = if format.bgr { [2, 1, 0] } else { [0, 1, 2] };
        let table = self.transfer.table_u16();
        // Sample `i` of pixel `x` (stored order) as a linear f32; `alpha` selects linear scaling.
        let sample = |x: usize, i: usize, alpha: bool| -> f32 {
            let k = x * spp + i;
            match format.bit_depth {
                Bd8 if alpha => f32::from(raw[k]) / 255.0,
                Bd8 => table[usize::from(raw[k]) * 257],
                Bd16 => {
                    let v = u16::from_le_bytes([raw[2 * k], raw[2 * k + 1]]);
                    if alpha {
                        f32::from(v) / 65535.0
                    } else {
                        table[usize::from(v)]
                    }
                }
                Bd16S => f32::from(i16::from_le_bytes([raw[2 * k], raw[2 * k + 1]])) / 8192.0,
                Bd16F => half_bits_to_f32(u16::from_le_bytes([raw[2 * k], raw[2 * k + 1]])),
                Bd32S => {
                    i32::from_le_bytes([raw[4 * k], raw[4 * k + 1], raw[4 * k + 2], raw[4 * k + 3]]) as f32
                        / 16_777_216.0
                }
                Bd32F => {
                    f32::from_bits(u32::from_le_bytes([raw[4 * k], raw[4 * k + 1], raw[4 * k + 2], raw[4 * k + 3]]))
                }
                _ => 0.0,
            }
        };
        // Half and float rows stored as the output's layout (RGB, RGBA, no padding, no BGR):
        // one contiguous conversion that the compiler vectorises.
        let same_layout = !gray && spp == lc && order == [0, 1, 2];
        match format.bit_depth {
            Bd16F if same_layout => {
                for (o, b) in out.iter_mut().zip(raw.chunks_exact(2)) {
                    *o = half_bits_to_f32(u16::from_le_bytes([b[0], b[1]]));
                }
                return Ok(());
            }
            Bd32F if same_layout => {
                for (o, b) in out.iter_mut().zip(raw.chunks_exact(4)) {
                    *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
                return Ok(());
            }
            _ => {}
        }
        match format.bit_depth {
            Bd1White1 | Bd1Black1 => {
                // BD1WHITE1: a set bit is white; BD1BLACK1: a set bit is black.
                let black1 = u8::from(self.bit_depth == Bd1Black1);
                for (x, px) in out.chunks_exact_mut(lc).enumerate() {
                    let v = f32::from(((raw[x / 8] >> (7 - x % 8)) & 1) ^ black1);
                    px[..3].fill(v);
                }
            }
            Bd5 | Bd565 | Bd10 => {
                let (bits, gbits, n) = match format.bit_depth {
                    Bd5 => (5u32, 5u32, 2),
                    Bd565 => (5, 6, 2),
                    _ => (10, 10, 4),
                };
                for (x, px) in out.chunks_exact_mut(lc).enumerate() {
                    let mut b = [0u8; 4];
                    b[..n].copy_from_slice(&raw[x * n..x * n + n]);
                    let v = u32::from_le_bytes(b);
                    let field = |shift: u32, w: u32| {
                        let max = (1u32 << w) - 1;
                        let c = (v >> shift) & max;
                        self.transfer.decode(f64::from(c) / f64::from(max)) as f32
                    };
                    // The first channel (R) sits in the low field when the RED_BLUE flag is 0.
                    let (r, b) = if self.red_blue_flag { (2, 0) } else { (0, 2) };
                    px[r] = field(0, bits);
                    px[1] = field(bits, gbits);
                    px[b] = field(bits + gbits, bits);
                }
            }
            Bd8 if format.color == OutputColorFormat::Rgbe => {
                for (x, px) in out.chunks_exact_mut(3).enumerate() {
                    let e = raw[4 * x + 3];
                    let scale = if e == 0 { 0.0 } else { (2.0f64).powi(i32::from(e) - 136) as f32 };
                    for c in 0..3 {
                        px[c] = if e == 0 { 0.0 } else { (f32::from(raw[4 * x + c]) + 0.5) * scale };
                    }
                }
            }
            _ => {
                for (x, px) in out.chunks_exact_mut(lc).enumerate() {
                    if gray {
                        px[..3].fill(sample(x, 0, false));
                    } else {
                        for c in 0..3 {
                            px[c] = sample(x, order[c], false);
                        }
                    }
                    if format.alpha {
                        px[3] = sample(x, colour, true);
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_to_half_bits_is_the_half_crates_rounding() {
        let check = |bits: u32| {
            let v = f32::from_bits(bits);
            let want = half::f16::from_f32(v).to_bits();
            let got = f32_to_half_bits(v);
            if v.is_nan() {
                assert!(got & 0x7c00 == 0x7c00 && got & 0x3ff != 0, "{bits:#x}: {got:#x}");
            } else {
                assert_eq!(got, want, "{bits:#x} ({v:e})");
            }
        };
        // Around every exponent boundary and rounding point of the half range, both signs,
        // and a spread of all the rest.
        for e in 0..256u32 {
            for m in
                [0u32, 1, 0xfff, 0x1000, 0x1001, 0x1fff, 0x2000, 0x3000, 0x7f_e000, 0x7f_efff, 0x7f_f000, 0x7f_ffff]
            {
                for s in [0, 0x8000_0000] {
                    check(s | (e << 23) | m);
                }
            }
        }
        for e in 102..=113u32 {
            for shift in 0..24 {
                for d in [0u32, 1, 2] {
                    let m = (1u32 << shift).wrapping_sub(d) & 0x7f_ffff;
                    check((e << 23) | m);
                    check((e << 23) | (m ^ 0x40_0000));
                }
            }
        }
        let mut x = 0x2545_F491u32;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            check(x);
        }
    }

    /// [`half_rgb_yuv`] (and its AVX2 twin) against the per-sample conversion it replaces:
    /// `half::f16::from_f32`, infinities clipped to ±65504, NaN as 0, then the shift and
    /// [`forward_cc`]; lengths with and without a tail of fewer than 8 pixels.
    #[test]
    #[allow(unsafe_code)]
    fn half_rgb_yuv_twins_agree() {
        let mut src = Vec::new();
        for e in 0..256u32 {
            for m in [0u32, 1, 0xfff, 0x1000, 0x1001, 0x3000, 0x40_0000, 0x7f_f000, 0x7f_ffff] {
                src.extend([f32::from_bits((e << 23) | m), f32::from_bits(0x8000_0000 | (e << 23) | m)]);
            }
        }
        for e in 102..=113u32 {
            for shift in 0..24 {
                for d in [0u32, 1, 2] {
                    src.push(f32::from_bits((e << 23) | ((1u32 << shift).wrapping_sub(d) & 0x7f_ffff)));
                }
            }
        }
        let mut x = 0x9E37_79B9u32;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            src.push(f32::from_bits(x));
        }
        src.extend([65504.0, 65519.99, 65520.0, -65520.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -0.0]);
        src.truncate(src.len() - src.len() % 3);
        for scale in [1.0f32, 0.37, 3.0] {
            // Each sample's code, and whether it was NaN and clipped.
            let mut want = Vec::new();
            let mut flags = Vec::new();
            for &v in &src {
                let v = v * scale;
                if v.is_nan() {
                    flags.push((1, 0));
                    want.push(0);
                    continue;
                }
                let h = half::f16::from_f32(v);
                if h.is_infinite() {
                    flags.push((0, 1));
                    want.push(if v < 0.0 { -0x7bff } else { 0x7bff });
                } else {
                    flags.push((0, 0));
                    want.push(half_bits_to_int(h.to_bits()));
                }
            }
            for (shift, drop) in [(0u32, 0usize), (3, 5), (3, 3 * 8 + 2)] {
                // Drop a few pixels at the end so the twin has a tail (the counts then come
                // from the pixels kept).
                let (src, want) = (&src[..src.len() - 3 * drop], &want[..want.len() - 3 * drop]);
                let n = src.len() / 3;
                let (mut yw, mut uw, mut vw) = (vec![0; n], vec![0; n], vec![0; n]);
                for (i, p) in want.chunks_exact(3).enumerate() {
                    (yw[i], uw[i], vw[i]) = forward_cc(p[0] << shift, p[1] << shift, p[2] << shift);
                }
                let expected = flags[..src.len()].iter().fold((0, 0), |(n, c), &(a, b)| (n + a, c + b));
                assert!(drop > 0 || (expected.0 > 100 && expected.1 > 100), "{expected:?}");
                let (mut y, mut u, mut v) = (vec![0; n], vec![0; n], vec![0; n]);
                assert_eq!(half_rgb_yuv_portable(src, scale, shift, [&mut y, &mut u, &mut v]), expected);
                assert!(y == yw && u == uw && v == vw, "scale {scale}, shift {shift}");
                #[cfg(target_arch = "x86_64")]
                if hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Avx2, "half_rgb_yuv") {
                    let (mut y, mut u, mut v) = (vec![0; n], vec![0; n], vec![0; n]);
                    // SAFETY: the CPU has AVX2 and F16C (checked above: the AVX2 level has both).
                    let got = unsafe { half_rgb_yuv_avx2(src, scale, shift, [&mut y, &mut u, &mut v]) };
                    assert_eq!(got, expected);
                    assert!(y == yw && u == uw && v == vw, "AVX2, scale {scale}, shift {shift}");
                }
            }
        }
    }
    use crate::container::PIXEL_FORMATS;
    use crate::testing::rng;

    fn format(name: &str) -> &'static PixelFormat {
        PIXEL_FORMATS.iter().find(|f| f.name == name).unwrap()
    }

    fn params(
        name: &str,
        internal: InternalColorFormat,
        scaled: bool,
        shift: u8,
        alpha: Option<AlphaParams>,
    ) -> OutputParams {
        let f = format(name);
        OutputParams::new(f, f.bit_depth, f.color, internal, scaled, shift, 4, false, alpha).unwrap()
    }

    #[test]
    fn colour_transforms_invert_exactly() {
        let mut r = rng(1);
        for _ in 0..100_000 {
            let v = |r: &mut dyn FnMut() -> u64| (r() as i32) >> 3;
            let (a, b, c, d) = (v(&mut r), v(&mut r), v(&mut r), v(&mut r));
            let (y, u, w) = forward_cc(a, b, c);
            assert_eq!(inverse_cc(y, u, w), (a, b, c));
            let (c1, m1, y1, k1) = forward_cc_cmyk(a, b, c, d);
            assert_eq!(inverse_cc_cmyk(c1, m1, y1, k1), (a, b, c, d));
        }
        // Hand-computed: grey stays grey; pure red.
        assert_eq!(forward_cc(7, 7, 7), (7, 0, 0));
        // b = 0 - 10; r = 10 + ((-10 + 1) >> 1) - 0 = 5; g = 0 + (5 >> 1) = 2; U = -r.
        assert_eq!(forward_cc(10, 0, 0), (2, -5, -10));
        assert_eq!(inverse_cc(2, -5, -10), (10, 0, 0));
    }

    #[test]
    fn encoder_sample_conversions_invert_the_decoder_ones() {
        for h in 0..=u16::MAX {
            if h != 0x8000 {
                assert_eq!(int_to_half_bits(half_bits_to_int(h)), h, "{h:#06x}");
            }
        }
        for (eb, lm) in [(4i8, 13u32), (0, 23), (127, 10), (1, 5)] {
            let max = ((127 + i32::from(eb)) << lm) | ((1 << lm) - 1);
            let check = |h: i32| {
                if h.abs() > max {
                    return;
                }
                let f = f32::from_bits(int_to_float_bits(h, eb, lm));
                assert_eq!(float_to_int(f, eb, lm), h, "h {h} eb {eb} lm {lm} f {f:e}");
            };
            for h in (-70_000..70_000).chain((1 << 20)..(1 << 20) + 5000) {
                check(h);
            }
            // The largest finite mini-float.
            check(max);
            // Halfway between two mini-floats rounds away from zero; beyond the largest clamps.
            let (a, b) = (int_to_float_bits(9000, eb, lm), int_to_float_bits(9001, eb, lm));
            let mid = (f64::from(f32::from_bits(a)) + f64::from(f32::from_bits(b))) / 2.0;
            if 9001 <= max && mid as f32 as f64 == mid {
                assert_eq!(float_to_int(mid as f32, eb, lm), 9001);
            }
        }
        assert_eq!(float_to_int(f32::MAX, 4, 13), ((127 + 4) << 13) | 0x1fff);
    }

    #[test]
    fn half_bit_patterns() {
        assert_eq!(int_to_half_bits(0), 0);
        assert_eq!(int_to_half_bits(0x3C00), 0x3C00, "1.0");
        assert_eq!(int_to_half_bits(-0x3C00), 0xBC00, "-1.0");
        assert_eq!(int_to_half_bits(1), 0x0001, "smallest denormal");
        assert_eq!(int_to_half_bits(-1), 0x8001);
        assert_eq!(int_to_half_bits(0x03FF), 0x03FF, "largest denormal");
        assert_eq!(int_to_half_bits(0x7BFF), 0x7BFF, "65504");
        assert_eq!(int_to_half_bits(0x7C00), 0x7C00, "+Inf");
        assert_eq!(int_to_half_bits(-0x7C00), 0xFC00, "-Inf");
        // Quirk 3: the magnitude wraps modulo 2^15, and -2^15 loses its sign (negative zero
        // is coded as 0x8000 by encoders: its magnitude 0 gives +0 here).
        assert_eq!(int_to_half_bits(0x8000 + 5), 5);
        assert_eq!(int_to_half_bits(-0x8000), 0);
        assert_eq!(int_to_half_bits(-0x8005), 0x8005 - 0x8000 + 0x8000);
        assert_eq!(int_to_half_bits(i32::MIN), 0);
    }

    /// The AVX2 kernel of the half formats (colour transform, shift, half fold, interleave in
    /// one pass) against the scalar definition, sample by sample, on the edge values: half
    /// overshoot (magnitudes past 0x7BFF and past 0x7FFF, which wrap), the patterns around
    /// negative zero (−1, −0x8000, −0x8001 after the shift), samples whose colour transform
    /// wraps (`i32::MIN`, `i32::MAX`), and random values of every magnitude.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(unsafe_code)]
    fn half_rgb_fused_twins_agree() {
        if !hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Avx2, "half_rgb_fused_twins_agree") {
            return;
        }
        let edges = [
            0,
            1,
            -1,
            2,
            -2,
            0x3C00,
            -0x3C00,
            0x7BFF,
            0x7C00,
            0x7FFF,
            0x8000,
            0x8001,
            0xFFFF,
            0x1_0000,
            -0x7BFF,
            -0x7C00,
            -0x7FFF,
            -0x8000,
            -0x8001,
            -0xFFFF,
            -0x1_0000,
            i32::MAX,
            i32::MIN,
            i32::MAX - 1,
            i32::MIN + 1,
        ];
        let mut r = rng(21);
        let width = 16 * 40 + 7;
        let mut pick = |i: usize| -> i32 {
            match i % 3 {
                0 => edges[(r() % edges.len() as u64) as usize],
                1 => edges[(r() % edges.len() as u64) as usize].wrapping_shl((r() % 4) as u32),
                _ => r() as i32 >> (r() % 32),
            }
        };
        let rows: [Vec<i32>; 3] = std::array::from_fn(|_| (0..width).map(&mut pick).collect());
        let yuv = [&rows[0][..], &rows[1][..], &rows[2][..]];
        for s in [0, 3] {
            for bias in [0, 3, -0x7FFF, i32::MAX] {
                for swap in [false, true] {
                    let mut out = vec![0xAAu8; width * 6];
                    // SAFETY: the CPU has AVX2 (checked above).
                    let done = unsafe { avx2::half_rgb48(&mut out, yuv, bias, s, swap, width) };
                    assert_eq!(done, width / 16 * 16);
                    for x in 0..width {
                        let (red, g, b) = inverse_cc(rows[0][x].wrapping_add(bias), rows[1][x], rows[2][x]);
                        let (first, last) = if swap { (b, red) } else { (red, b) };
                        let want = [first, g, last].map(|v| int_to_half_bits(v >> s));
                        let px = &out[x * 6..][..6];
                        if x < done {
                            let got: Vec<u16> = px.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect();
                            assert_eq!(got, want, "pixel {x}, s {s}, bias {bias}, swap {swap}");
                        } else {
                            assert!(px.iter().all(|&b| b == 0xAA), "pixel {x} past the groups written");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn half_conversion_is_exact_for_every_half() {
        for bits in 0..=u16::MAX {
            let want = half::f16::from_bits(bits).to_f32();
            let got = half_bits_to_f32(bits);
            if want.is_nan() {
                assert!(got.is_nan() && got.is_sign_negative() == want.is_sign_negative(), "{bits:#06x}");
                assert_eq!(got.to_bits() & 0x007f_ffff, u32::from(bits & 0x3ff) << 13, "{bits:#06x}: payload kept");
            } else {
                assert_eq!(got.to_bits(), want.to_bits(), "{bits:#06x}");
            }
        }
    }

    #[test]
    fn float_bit_patterns() {
        let f = |v, bias, len| f32::from_bits(int_to_float_bits(v, bias, len));
        // JxrEncApp's defaults (13, 4): exponent field 1 is 2^-3, the smallest step 2^-16.
        assert_eq!(f(1 << 13, 4, 13), 0.125);
        assert_eq!(f(1, 4, 13), 2f32.powi(-16));
        assert_eq!(f(-(1 << 13), 4, 13), -0.125);
        assert_eq!(f((1 << 13) | 1, 4, 13), 0.125 * (1.0 + 2f32.powi(-13)));
        assert_eq!(f(4 << 13, 4, 13), 1.0);
        assert_eq!(f(0, 4, 13), 0.0);
        assert_eq!(int_to_float_bits(0, 4, 13), 0);
        // Identity-like (23, 127): the integer is the IEEE pattern for positive values.
        for bits in [0x3F80_0000u32, 0x0000_0001, 0x007F_FFFF, 0x0080_0000, 0x7F7F_FFFF] {
            assert_eq!(int_to_float_bits(bits as i32, 127, 23), bits, "{bits:#x}");
            assert_eq!(int_to_float_bits(-(bits as i32), 127, 23), bits | 0x8000_0000);
        }
        // IEEE denormals from a small exponent bias.
        assert_eq!(int_to_float_bits(1, 127, 1), 0x0040_0000, "2^-127");
        assert_eq!(int_to_float_bits(1, 127, 0), 0x0080_0000, "2^-126");
        // No overflow check: the exponent runs into the sign bit as jxrlib's does.
        assert_eq!(int_to_float_bits(0x7FFF_FFFF, -128, 23), ((0xFFu32 + 255) << 23) | 0x7F_FFFF);
        let _ = int_to_float_bits(i32::MIN, 127, 0);
    }

    /// jxrlib's `inverseConvertRGBE` as it reads, with its branches (the model of the
    /// branch-free [`int_to_rgbe`]).
    fn rgbe_reference(r: i32, g: i32, b: i32) -> [u8; 4] {
        let channel = |v: i32| -> (u8, u8) {
            if v <= 0 {
                (0, 0)
            } else if (v >> 7) > 1 {
                (((v & 0x7f) | 0x80) as u8, (v >> 7) as u8)
            } else {
                (v as u8, 1)
            }
        };
        let ch = [channel(r), channel(g), channel(b)];
        let e = ch[0].1.max(ch[1].1).max(ch[2].1);
        let mant = |(m, ce): (u8, u8)| -> u8 {
            if e > ce {
                ((i32::from(m) * 2 + 1) >> ((u32::from(e - ce) + 1) & 31)) as u8
            } else {
                m
            }
        };
        [mant(ch[0]), mant(ch[1]), mant(ch[2]), e]
    }

    #[test]
    fn rgbe_matches_the_branching_reference() {
        // Every exponent and mantissa edge (0, 1, 255, 256, powers of two and their
        // neighbours, the 8-bit wrap of the exponent, negatives), in every combination.
        let mut values = vec![i32::MIN, -70000, -256, -1, 0, 1, 2, 127, 128, 255, 256, 257, 383, 384, i32::MAX];
        for k in 8..31 {
            values.extend([(1 << k) - 1, 1 << k, (1 << k) + 77]);
        }
        for e in [31, 32, 63, 64, 255, 256, 257] {
            values.extend([e << 7, (e << 7) + 127]);
        }
        for &r in &values {
            for &g in &values {
                for &b in &values {
                    assert_eq!(int_to_rgbe(r, g, b), rgbe_reference(r, g, b), "{r} {g} {b}");
                }
            }
        }
        // xorshift32 triples over the whole range and near the small exponents.
        let mut x = 0x9E37_79B9u32;
        for i in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            let v = |k: u32| -> i32 {
                let w = x.rotate_left(k * 11);
                if i % 2 == 0 {
                    w as i32
                } else {
                    (w % 70_000) as i32 - 1000
                }
            };
            let (r, g, b) = (v(0), v(1), v(2));
            assert_eq!(int_to_rgbe(r, g, b), rgbe_reference(r, g, b), "{r} {g} {b}");
        }
    }

    #[test]
    fn rgbe_bytes() {
        assert_eq!(int_to_rgbe(0, -5, 0), [0, 0, 0, 0]);
        assert_eq!(int_to_rgbe(200, 0, 0), [200, 0, 0, 1]);
        assert_eq!(int_to_rgbe(256, 0, 0), [128, 0, 0, 2]);
        // 300 → (172, 2); 100 → (100, 1) → (2·100 + 1) >> 2 = 50; 0 → (1 >> 3) = 0.
        assert_eq!(int_to_rgbe(300, 100, 0), [172, 50, 0, 2]);
        // E is an 8-bit cast: 2^15 >> 7 = 256 wraps to 0.
        assert_eq!(int_to_rgbe(1 << 15, 0, 0)[3], 0);
        assert_eq!(int_to_rgbe(i32::MAX, 1, 1)[3], 0xFF);
        // jxrlib's shift count is taken modulo 32 (x86-64): under E = 127 a zero channel is
        // shifted by 128 ≡ 0 and keeps (2·0 + 1) = 1; under E = 130 a channel 6 (exponent 1)
        // by 130 ≡ 2, giving 13 >> 2 = 3, and a zero one by 131 ≡ 3, giving 0. jxrlib
        // (imagecodecs) decodes lossy RGBE files of our encoder to exactly such values.
        assert_eq!(int_to_rgbe(127 << 7, 0, 0), [128, 1, 1, 127]);
        assert_eq!(int_to_rgbe(130 << 7, 6, 0), [128, 3, 0, 130]);
    }

    #[test]
    fn chroma_upsampling() {
        let mut out = [0; 6];
        upsample_chroma_row(InternalColorFormat::Yuv422, &[10, 20, 31], 3, 1, 0, &mut out).unwrap();
        assert_eq!(out, [10, 15, 20, 26, 31, 31]);
        let plane = [0, 10, 100, 110];
        let rows: Vec<[i32; 4]> = (0..4)
            .map(|y| {
                let mut o = [0; 4];
                upsample_chroma_row(InternalColorFormat::Yuv420, &plane, 2, 2, y, &mut o).unwrap();
                o
            })
            .collect();
        assert_eq!(rows, [[0, 5, 10, 10], [50, 55, 60, 60], [100, 105, 110, 110], [100, 105, 110, 110]]);
        assert!(upsample_chroma_row(InternalColorFormat::Yuv420, &plane, 2, 3, 5, &mut [0; 4]).is_err());
        assert!(upsample_chroma_row(InternalColorFormat::Yuv422, &plane, 2, 2, 0, &mut [0; 3]).is_err());
    }

    #[test]
    fn bd8_rgb_scaled_and_unscaled() {
        let p = params("24bppRGB", InternalColorFormat::Yuv444, false, 0, None);
        let mut out = [0u8; 6];
        // Y 0 is mid-grey; U = -10, V = 4: r = 10 + 128 - ... computed by hand from _ICC.
        p.format_row(&[&[0, 0], &[0, -10], &[0, 4]], None, 2, &mut out).unwrap();
        // Pixel 1: r = 10, g = 128 - 5 = 123, r = 10 - (2 - 123) = 131, b = 4 + 131 = 135.
        assert_eq!(out, [128, 128, 128, 131, 123, 135]);
        let p = params("24bppBGR", InternalColorFormat::Yuv444, true, 0, None);
        // Scaled: (80 + 1024 + 3) >> 3 = 138 (the +3 rounding); 4 more gives 138 too, 5 → 139.
        let mut out = [0u8; 9];
        p.format_row(&[&[80, 84, 85], &[0; 3], &[0; 3]], None, 3, &mut out).unwrap();
        assert_eq!(out, [138, 138, 138, 138, 138, 138, 139, 139, 139]);
        // Clamping.
        p.format_row(&[&[-5000, 5000, 0], &[0; 3], &[0; 3]], None, 3, &mut out).unwrap();
        assert_eq!(out[..6], [0, 0, 0, 255, 255, 255]);
        // BGR order: red 20 above mid-grey lands in the last byte.
        let (y, u, v) = forward_cc(8 * 20, 0, 0);
        p.format_row(&[&[y, 0, 0], &[u, 0, 0], &[v, 0, 0]], None, 3, &mut out).unwrap();
        assert_eq!(out[..3], [128, 128, 148]);
    }

    #[test]
    fn interleaved_alpha_rounding_quirk() {
        let mut out = [0u8; 4];
        let a = |jxrlib| Some(AlphaParams { scaled: true, jxrlib_interleaved: jxrlib });
        // Alpha 4: jxrlib (4 + 1024 + 4) >> 3 = 129; the spec (4 + 1024 + 3) >> 3 = 128.
        params("32bppBGRA", InternalColorFormat::Yuv444, true, 0, a(true))
            .format_row(&[&[0], &[0], &[0]], Some(&[4]), 1, &mut out)
            .unwrap();
        assert_eq!(out[3], 129);
        params("32bppBGRA", InternalColorFormat::Yuv444, true, 0, a(false))
            .format_row(&[&[0], &[0], &[0]], Some(&[4]), 1, &mut out)
            .unwrap();
        assert_eq!(out[3], 128);
        // Half alpha: (v + 4) >> 3 against (v + 3) >> 3.
        let mut out = [0u8; 8];
        params("64bppRGBAHalf", InternalColorFormat::Yuv444, true, 0, a(true))
            .format_row(&[&[0], &[0], &[0]], Some(&[0x3C00 * 8 + 4]), 1, &mut out)
            .unwrap();
        assert_eq!(u16::from_le_bytes([out[6], out[7]]), 0x3C01);
        params("64bppRGBAHalf", InternalColorFormat::Yuv444, true, 0, a(false))
            .format_row(&[&[0], &[0], &[0]], Some(&[0x3C00 * 8 + 4]), 1, &mut out)
            .unwrap();
        assert_eq!(u16::from_le_bytes([out[6], out[7]]), 0x3C00);
        assert!(
            OutputParams::new(
                format("32bppBGRA"),
                OutputBitDepth::Bd8,
                OutputColorFormat::Rgb,
                InternalColorFormat::Yuv444,
                true,
                0,
                0,
                false,
                None
            )
            .is_err(),
            "alpha format without alpha plane"
        );
    }

    #[test]
    fn every_bit_depth_on_grey() {
        let one = |name: &str, scaled, shift, v: i32| -> Vec<u8> {
            let p = params(name, InternalColorFormat::YOnly, scaled, shift, None);
            let mut out = vec![0u8; p.row_bytes(1)];
            p.format_row(&[&[v]], None, 1, &mut out).unwrap();
            out
        };
        assert_eq!(one("8bppGray", false, 0, 10), [138]);
        // BD16 with SHIFT_BITS 2: bias (2^15 >> 2) = 8192, ((v + 8192) >> 0) << 2.
        assert_eq!(one("16bppGray", false, 2, 100), ((100u16 + 8192) << 2).to_le_bytes());
        // Scaled BD16 rounds with +4: (8·100 + 4 + 8·8192) >> 3 = 8292 (+4 reaches it, +3 not).
        assert_eq!(one("16bppGray", true, 2, 8 * 100 - 4), ((100u16 + 8192) << 2).to_le_bytes());
        assert_eq!(one("16bppGray", false, 0, 40000), 65535u16.to_le_bytes(), "clamped");
        assert_eq!(one("16bppGrayFixedPoint", false, 0, -40000), (-32768i16).to_le_bytes());
        assert_eq!(one("16bppGrayFixedPoint", true, 1, 8 * 100 + 5), 202i16.to_le_bytes());
        assert_eq!(one("16bppGrayHalf", false, 0, -0x3C00), 0xBC00u16.to_le_bytes());
        assert_eq!(one("16bppGrayHalf", true, 0, 8 * 0x3C00 + 5), 0x3C01u16.to_le_bytes());
        // BD32S shifts left without clamping (wraps).
        assert_eq!(one("32bppGrayFixedPoint", false, 10, 1 << 22), 0i32.to_le_bytes(), "2^32 wraps to 0");
        assert_eq!(one("32bppGrayFixedPoint", false, 10, 3), (3i32 << 10).to_le_bytes());
        assert_eq!(one("32bppGrayFloat", false, 13, 4 << 13), 1.0f32.to_le_bytes());
        // BD1: threshold 1 unscaled, 4 scaled; BLACK1 inverts.
        let p = params("BlackWhite", InternalColorFormat::YOnly, true, 0, None);
        let mut out = [0u8; 2];
        p.format_row(&[&[0, 4, 3, 100, -1, 4, 4, 4, 9]], None, 9, &mut out).unwrap();
        assert_eq!(out, [0b0101_0111, 0b1000_0000]);
        let p = OutputParams::new(
            format("BlackWhite"),
            OutputBitDepth::Bd1Black1,
            OutputColorFormat::YOnly,
            InternalColorFormat::YOnly,
            false,
            0,
            0,
            false,
            None,
        )
        .unwrap();
        p.format_row(&[&[0, 1, 0, 0, 0, 0, 0, 0, 1]], None, 9, &mut out).unwrap();
        assert_eq!(out, [0b1011_1111, 0b0000_0000]);
        let mut lin = [0f32; 27];
        p.row_to_f32(&out, 9, &mut lin).unwrap();
        assert_eq!(lin[..6], [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    }

    #[test]
    fn packed_formats() {
        // Unscaled Y 0, U 0, V 0 is mid-grey: 16 (BD5), 32 → 16/32/16 (BD565), 512 (BD10).
        let row = |name: &str, rb: bool| -> Vec<u8> {
            let f = format(name);
            let p =
                OutputParams::new(f, f.bit_depth, f.color, InternalColorFormat::Yuv444, false, 0, 0, rb, None).unwrap();
            let mut out = vec![0u8; p.row_bytes(2)];
            // Pixel 1 is a saturated colour whose R and B differ.
            p.format_row(&[&[0, 0], &[0, -100], &[0, -100]], None, 2, &mut out).unwrap();
            out
        };
        assert_eq!(row("16bppRGB555", false)[..2], (16u16 | 16 << 5 | 16 << 10).to_le_bytes());
        assert_eq!(row("16bppRGB565", false)[..2], (16u16 | 32 << 5 | 16 << 11).to_le_bytes());
        assert_eq!(row("32bppRGB101010", false)[..4], (512u32 | 512 << 10 | 512 << 20).to_le_bytes());
        // The R/B flag moves R to the high field and B to the low one.
        let (a, b) = (row("16bppRGB555", false), row("16bppRGB555", true));
        let v = |b: &[u8]| u16::from_le_bytes([b[2], b[3]]);
        assert_eq!(v(&a) & 31, (v(&b) >> 10) & 31);
        assert_eq!((v(&a) >> 10) & 31, v(&b) & 31);
    }

    #[test]
    fn linear_conversion() {
        let conv = |name: &str, raw: &[u8]| -> Vec<f32> {
            let f = format(name);
            let p = OutputParams::new(
                f,
                f.bit_depth,
                f.color,
                InternalColorFormat::Yuv444,
                false,
                0,
                0,
                false,
                f.alpha.then_some(AlphaParams { scaled: false, jxrlib_interleaved: true }),
            )
            .unwrap();
            let mut out = vec![0f32; p.linear_channels().unwrap()];
            p.row_to_f32(raw, 1, &mut out).unwrap();
            out
        };
        let h = |v: u16| v.to_le_bytes();
        let half: Vec<u8> = [h(0x3C00), h(0xC000), h(0x0001), h(0x3800)].concat();
        assert_eq!(conv("64bppRGBAHalf", &half), [1.0, -2.0, 2f32.powi(-24), 0.5]);
        let fixed: Vec<u8> = [8192i16, -4096, 1].iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(conv("48bppRGBFixedPoint", &fixed), [1.0, -0.5, 1.0 / 8192.0]);
        let fixed32: Vec<u8> = [1i32 << 24, 3 << 23, -(1 << 24), 0].iter().flat_map(|v| v.to_le_bytes()).collect();
        assert_eq!(conv("128bppRGBFixedPoint", &fixed32), [1.0, 1.5, -1.0]);
        assert_eq!(conv("32bppRGBE", &[128, 64, 0, 129]), [128.5 / 128.0, 64.5 / 128.0, 0.5 / 128.0]);
        assert_eq!(conv("32bppRGBE", &[128, 64, 9, 0]), [0.0; 3]);
        let bgra = conv("32bppBGRA", &[0, 255, 255, 51]);
        assert_eq!(bgra, [1.0, 1.0, 0.0, 0.2]);
        let g = conv("24bppRGB", &[128, 128, 128]);
        assert!((g[0] - 0.2158605).abs() < 1e-6, "sRGB 128 → {}", g[0]);
        let f = format("32bppCMYK");
        let p =
            OutputParams::new(f, f.bit_depth, f.color, InternalColorFormat::Yuvk, false, 0, 0, false, None).unwrap();
        assert!(p.linear_channels().is_err());
    }

    #[test]
    fn cmyk_round_trip() {
        // The encoder's _CC_CMYK on (c, m, y, k) with its offsets, then the decoder's output.
        let f = format("32bppCMYK");
        let p =
            OutputParams::new(f, f.bit_depth, f.color, InternalColorFormat::Yuvk, false, 0, 0, false, None).unwrap();
        let mut r = rng(5);
        for _ in 0..1000 {
            let px: [i32; 4] = std::array::from_fn(|_| (r() % 256) as i32);
            let (c, m, y, k) = forward_cc_cmyk(px[0], px[1], px[2], px[3]);
            // The coded channels as outputMBRow reads them: Y = bias1 − M, U = C, V = −Y, K.
            let (yy, uu, vv, kk) = (128 - m, c, -y, k);
            let mut out = [0u8; 4];
            p.format_row(&[&[yy], &[uu], &[vv], &[kk]], None, 1, &mut out).unwrap();
            assert_eq!(out.map(i32::from), px);
        }
    }

    #[test]
    fn bad_parameters_are_errors() {
        let f = format("48bppRGBHalf");
        let new = |bd, cf, internal, shift| OutputParams::new(f, bd, cf, internal, false, shift, 0, false, None);
        assert!(new(OutputBitDepth::Bd16, OutputColorFormat::Rgb, InternalColorFormat::Yuv444, 0).is_err());
        assert!(new(OutputBitDepth::Bd16F, OutputColorFormat::YOnly, InternalColorFormat::Yuv444, 0).is_err());
        assert!(new(OutputBitDepth::Bd16F, OutputColorFormat::Rgb, InternalColorFormat::Yuvk, 0).is_err());
        let f = format("32bppGrayFloat");
        assert!(
            OutputParams::new(f, f.bit_depth, f.color, InternalColorFormat::YOnly, false, 24, 0, false, None).is_err()
        );
        let p = params("48bppRGBHalf", InternalColorFormat::Yuv444, false, 0, None);
        let mut out = [0u8; 12];
        assert!(p.format_row(&[&[0, 0], &[0, 0]], None, 2, &mut out).is_err(), "a channel missing");
        assert!(p.format_row(&[&[0], &[0], &[0]], None, 2, &mut out).is_err(), "rows too short");
        assert!(p.format_row(&[&[0, 0], &[0, 0], &[0, 0]], None, 2, &mut out[..11]).is_err(), "output too short");
    }

    /// Every pixel format, with every internal format and extreme samples: either a clean
    /// parameter error or rows written without a panic.
    #[test]
    fn every_format_formats_without_panicking() {
        every_format_combination(|_, _| ());
    }

    /// The AVX2 twin of `format_row` writes the portable code's bytes, for every pixel
    /// format, internal format and shift, on rows longer than two runs of the RGB path.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn format_row_twins_agree() {
        use hdrcodec_core::cpu::{self, CpuLevel};
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "format_row_twins_agree") {
            return;
        }
        let mut compared = 0;
        every_format_combination(|p, rows| {
            let width = rows[0].len();
            let (mut a, mut b) = (vec![0u8; p.row_bytes(width)], vec![1u8; p.row_bytes(width)]);
            p.format_row_portable((rows, Some(rows[7])), width, &mut a).unwrap();
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { p.format_row_avx2((rows, Some(rows[7])), width, &mut b) }.unwrap();
            assert_eq!(a, b, "{} {:?}", p.format.name, p.internal);
            compared += 1;
        });
        assert!(compared > 150, "{compared} combinations compared");
    }

    /// Runs `each` on every combination of pixel format, internal format and shift that
    /// `OutputParams::new` accepts, with 8 rows of 150 samples (extremes and random values of
    /// every magnitude), then formats the row and converts it to linear f32.
    fn every_format_combination(mut each: impl FnMut(&OutputParams, &[&[i32]])) {
        let internals = [
            InternalColorFormat::YOnly,
            InternalColorFormat::Yuv420,
            InternalColorFormat::Yuv422,
            InternalColorFormat::Yuv444,
            InternalColorFormat::Yuvk,
            InternalColorFormat::NComponent(3),
            InternalColorFormat::NComponent(8),
        ];
        let mut r = rng(9);
        let width = 150;
        let rows: Vec<Vec<i32>> = (0..8)
            .map(|_| {
                (0..width)
                    .map(|i| match i % 4 {
                        0 => i32::MIN,
                        1 => i32::MAX,
                        _ => r() as i32 >> (r() % 31),
                    })
                    .collect()
            })
            .collect();
        let refs: Vec<&[i32]> = rows.iter().map(|v| v.as_slice()).collect();
        let mut made = 0;
        for f in PIXEL_FORMATS {
            for &internal in &internals {
                for (scaled, shift) in [(false, 0), (true, 0), (true, 13), (false, 31)] {
                    let alpha = f.alpha.then_some(AlphaParams { scaled, jxrlib_interleaved: scaled });
                    let Ok(p) = OutputParams::new(f, f.bit_depth, f.color, internal, scaled, shift, -128, true, alpha)
                    else {
                        continue;
                    };
                    made += 1;
                    each(&p, &refs);
                    let mut out = vec![0u8; p.row_bytes(width)];
                    p.format_row(&refs, Some(refs[7]), width, &mut out).unwrap();
                    if let Ok(n) = p.linear_channels() {
                        let mut lin = vec![0f32; n * width];
                        p.row_to_f32(&out, width, &mut lin).unwrap();
                    }
                }
            }
        }
        assert!(made > 150, "{made} combinations formatted");
    }

    /// jxrlib's `pixel2float` transcribed loop for loop, to check the branch-free conversion.
    fn pixel2float_reference(h: i32, c: i8, lm: u32) -> u32 {
        let lmshift = 1i32 << lm;
        let s = h >> 31;
        let a = (h ^ s).wrapping_sub(s);
        let mut e = ((a as u32) >> lm) as i32;
        let mut m = (a & (lmshift - 1)) | lmshift;
        if e == 0 {
            m ^= lmshift;
            e = 1;
        }
        e = e.wrapping_add(127 - i32::from(c));
        while m < lmshift && e > 1 && m > 0 {
            e -= 1;
            m <<= 1;
        }
        if m < lmshift {
            e = 0;
        } else {
            m ^= lmshift;
        }
        ((s as u32) & 0x8000_0000) | (e as u32).wrapping_shl(23) | ((m as u32) << (23 - lm))
    }

    #[test]
    fn float_conversion_matches_the_loop() {
        let mut r = rng(13);
        for lm in 0..=23 {
            for c in [-128i8, -5, 0, 4, 60, 120, 127] {
                for _ in 0..3000 {
                    let h = (r() as i32) >> (r() % 32);
                    assert_eq!(int_to_float_bits(h, c, lm), pixel2float_reference(h, c, lm), "{h} {c} {lm}");
                }
                for h in [0, 1, -1, 2, 3, 1 << lm, (1 << lm) - 1, i32::MAX, i32::MIN, i32::MIN + 1] {
                    assert_eq!(int_to_float_bits(h, c, lm), pixel2float_reference(h, c, lm), "{h} {c} {lm}");
                }
            }
        }
    }
}
