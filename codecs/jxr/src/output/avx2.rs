//! The last step of the RGB output formats with AVX2 (SSSE3 byte shuffles and SSE2 unpacks,
//! VEX-encoded): a run's converted R, G and B samples interleaved into the pixels with
//! vector shuffles and 16-byte stores, where the portable loop moves every sample on its own
//! (about 12 instructions a pixel for 48bppRGBHalf, more than the colour transform and the
//! half conversion together). 48bppRGBHalf, the format of most half files, goes through one
//! pass from the coded rows instead ([`half_rgb48`]: colour transform, half patterns and
//! interleaving in 256-bit registers). Each function writes whole groups of pixels and returns
//! how many it wrote; the portable loop writes the rest. `format_row_twins_agree` checks the
//! bytes.

use std::arch::x86_64::{
    __m128i, __m256i, _mm256_add_epi32, _mm256_and_si256, _mm256_blend_epi32, _mm256_broadcastsi128_si256,
    _mm256_or_si256, _mm256_packs_epi32, _mm256_permute2x128_si256, _mm256_permute4x64_epi64, _mm256_set1_epi32,
    _mm256_setzero_si256, _mm256_shuffle_epi8, _mm256_sign_epi32, _mm256_sra_epi32, _mm256_srai_epi32,
    _mm256_sub_epi32, _mm_cvtsi32_si128, _mm_loadu_si128, _mm_or_si128, _mm_setzero_si128, _mm_shuffle_epi8,
    _mm_unpackhi_epi16, _mm_unpackhi_epi32, _mm_unpackhi_epi64, _mm_unpacklo_epi16, _mm_unpacklo_epi32,
    _mm_unpacklo_epi64,
};

/// The `pshufb` control that moves the 16-bit samples of channel `ch` of 8 pixels into the
/// 16-byte part `k` (0, 1 or 2) of those pixels' 48 bytes (3 samples a pixel): output word
/// `w` is sample `(8k + w) / 3` of channel `(8k + w) % 3`; other bytes zero (-128).
const fn control3(ch: usize, k: usize) -> [i8; 16] {
    let mut b = [-128i8; 16];
    let mut w = 0;
    while w < 8 {
        let g = 8 * k + w;
        if g % 3 == ch {
            b[2 * w] = (2 * (g / 3)) as i8;
            b[2 * w + 1] = (2 * (g / 3) + 1) as i8;
        }
        w += 1;
    }
    b
}

/// [`control3`] for each part `k` and channel `ch`, `[k][ch]`.
static CONTROLS3: [[[i8; 16]; 3]; 3] = {
    let mut c = [[[0i8; 16]; 3]; 3];
    let mut k = 0;
    while k < 3 {
        let mut ch = 0;
        while ch < 3 {
            c[k][ch] = control3(ch, k);
            ch += 1;
        }
        k += 1;
    }
    c
};

/// A control of [`CONTROLS3`] in a register.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn control(b: &[i8; 16]) -> __m128i {
    // SAFETY: `b` holds the 16 bytes the unaligned load reads.
    unsafe { _mm_loadu_si128(b.as_ptr().cast()) }
}

/// Checks once that `out` holds `groups` groups of `bytes` bytes and each of `c` `groups`
/// groups of `per` samples: the pointers the kernels read and write through from there.
#[inline(always)]
fn checked<T>(out: &mut [u8], c: [&[T]; 3], groups: usize, bytes: usize, per: usize) -> (*mut u8, [*const T; 3]) {
    let out = &mut out[..groups * bytes];
    (out.as_mut_ptr(), c.map(|c| c[..groups * per].as_ptr()))
}

/// A vector (`__m128i` or `__m256i`) from `p + at` (unaligned).
///
/// # Safety
/// The vector's bytes must be readable.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn load<T, V>(p: *const T, at: usize) -> V {
    // SAFETY: the caller guarantees the bytes.
    unsafe { p.add(at).cast::<V>().read_unaligned() }
}

/// Stores the vector `x` (`__m128i` or `__m256i`) to `p + at` (unaligned).
///
/// # Safety
/// The vector's bytes must be writable.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn store<V>(p: *mut u8, at: usize, x: V) {
    // SAFETY: the caller guarantees the bytes.
    unsafe { p.add(at).cast::<V>().write_unaligned(x) }
}

/// Stores the 64 bytes `x` to `p + at` (unaligned).
///
/// # Safety
/// The 64 bytes must be writable.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn store64(p: *mut u8, at: usize, x: [__m128i; 4]) {
    for (k, x) in x.into_iter().enumerate() {
        // SAFETY: the caller guarantees the 64 bytes.
        unsafe { store(p, at + 16 * k, x) };
    }
}

/// 16-bit samples, three a pixel (48bppRGBHalf, 48bppRGB, 48bppRGBFixedPoint): the first
/// `n` pixels of `c` (channels in pixel order) to `out`, 8 pixels at a time.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) fn interleave3x16(out: &mut [u8], c: [&[u16]; 3], n: usize) -> usize {
    let mut masks = [[_mm_setzero_si128(); 3]; 3];
    for (m, b) in masks.iter_mut().zip(&CONTROLS3) {
        for (m, b) in m.iter_mut().zip(b) {
            *m = control(b);
        }
    }
    let groups = n.min(out.len() / 6).min(c[0].len()).min(c[1].len()).min(c[2].len()) / 8;
    let (o, [p0, p1, p2]) = checked(out, c, groups, 48, 8);
    for g in 0..groups {
        // SAFETY: group g's 8 samples of each channel and 48 bytes of `out` are in the
        // slices `checked` cut (`groups` groups each).
        let x = unsafe { [load(p0, 8 * g), load(p1, 8 * g), load(p2, 8 * g)] };
        for (k, m) in masks.iter().enumerate() {
            let part = _mm_or_si128(
                _mm_or_si128(_mm_shuffle_epi8(x[0], m[0]), _mm_shuffle_epi8(x[1], m[1])),
                _mm_shuffle_epi8(x[2], m[2]),
            );
            // SAFETY: as above.
            unsafe { store(o, 48 * g + 16 * k, part) };
        }
    }
    8 * groups
}

/// 16-bit samples, four a pixel, the fourth 0 (64bppRGBHalf and the RGBA formats, whose
/// alpha is written after): as [`interleave3x16`].
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) fn interleave4x16(out: &mut [u8], c: [&[u16]; 3], n: usize) -> usize {
    let groups = n.min(out.len() / 8).min(c[0].len()).min(c[1].len()).min(c[2].len()) / 8;
    let (o, [p0, p1, p2]) = checked(out, c, groups, 64, 8);
    let zero = _mm_setzero_si128();
    for g in 0..groups {
        // SAFETY: as in `interleave3x16` (64 bytes a group).
        let (r, gg, b) = unsafe { (load(p0, 8 * g), load(p1, 8 * g), load(p2, 8 * g)) };
        let (rg_lo, rg_hi) = (_mm_unpacklo_epi16(r, gg), _mm_unpackhi_epi16(r, gg));
        let (b_lo, b_hi) = (_mm_unpacklo_epi16(b, zero), _mm_unpackhi_epi16(b, zero));
        let px = [
            _mm_unpacklo_epi32(rg_lo, b_lo),
            _mm_unpackhi_epi32(rg_lo, b_lo),
            _mm_unpacklo_epi32(rg_hi, b_hi),
            _mm_unpackhi_epi32(rg_hi, b_hi),
        ];
        // SAFETY: as above.
        unsafe { store64(o, 64 * g, px) };
    }
    8 * groups
}

/// 32-bit samples, four a pixel, the fourth 0 (128bppRGBFloat and the RGBA formats, whose
/// alpha is written after): a 4×4 transpose of 4 pixels at a time.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) fn interleave4x32(out: &mut [u8], c: [&[u32]; 3], n: usize) -> usize {
    let groups = n.min(out.len() / 16).min(c[0].len()).min(c[1].len()).min(c[2].len()) / 4;
    let (o, [p0, p1, p2]) = checked(out, c, groups, 64, 4);
    let zero = _mm_setzero_si128();
    for g in 0..groups {
        // SAFETY: as in `interleave3x16` (4 samples and 64 bytes a group).
        let (r, gg, b) = unsafe { (load(p0, 4 * g), load(p1, 4 * g), load(p2, 4 * g)) };
        let (t0, t1) = (_mm_unpacklo_epi32(r, gg), _mm_unpacklo_epi32(b, zero));
        let (t2, t3) = (_mm_unpackhi_epi32(r, gg), _mm_unpackhi_epi32(b, zero));
        let px = [
            _mm_unpacklo_epi64(t0, t1),
            _mm_unpackhi_epi64(t0, t1),
            _mm_unpacklo_epi64(t2, t3),
            _mm_unpackhi_epi64(t2, t3),
        ];
        // SAFETY: as above.
        unsafe { store64(o, 64 * g, px) };
    }
    4 * groups
}

/// 48bppRGBHalf in one pass from the coded rows: for 16 pixels at a time, Y + `bias`,
/// U and V to R, G, B ([`inverse_cc`](super::inverse_cc)), each shifted right by `s` and
/// folded into its half bit pattern ([`int_to_half_bits`](super::int_to_half_bits): the low
/// 15 bits as the magnitude, negated for a negative sample, which `vpsignd` does), packed to
/// 16 bits (exact: the patterns are within ±0x7FFF) and interleaved into the pixels, R and B
/// swapped with `swap`. The portable loop (`write_rgb_runs`) goes through three buffers of
/// 32-bit samples; this keeps everything in registers (48bppRGBHalf: about 4.6 instructions a
/// pixel, was 11.8). Writes whole groups of 16 pixels of the first `n` and returns how many
/// pixels it wrote; `format_row_twins_agree` and `half_rgb_fused_twins_agree` check the bytes.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) fn half_rgb48(out: &mut [u8], yuv: [&[i32]; 3], bias: i32, s: u32, swap: bool, n: usize) -> usize {
    let groups = n.min(out.len() / 6).min(yuv[0].len()).min(yuv[1].len()).min(yuv[2].len()) / 16;
    let (o, [py, pu, pv]) = checked(out, yuv, groups, 96, 16);
    let mut masks = [[_mm256_setzero_si256(); 3]; 3];
    for (m, b) in masks.iter_mut().zip(&CONTROLS3) {
        for (m, b) in m.iter_mut().zip(b) {
            *m = _mm256_broadcastsi128_si256(control(b));
        }
    }
    let (bias, one, low15) = (_mm256_set1_epi32(bias), _mm256_set1_epi32(1), _mm256_set1_epi32(0x7fff));
    let zero = _mm256_setzero_si256();
    let shift = _mm_cvtsi32_si128(s.min(31) as i32);
    // The half pattern of x >> s, within ±0x7FFF as an i32 (0 stays 0, as `vpsignd` gives).
    let half = |x: __m256i| {
        let h = _mm256_sra_epi32(x, shift);
        _mm256_sign_epi32(_mm256_and_si256(h, low15), h)
    };
    for g in 0..groups {
        let mut halves = [[zero; 3]; 2];
        for (i, h) in halves.iter_mut().enumerate() {
            let at = 16 * g + 8 * i;
            // SAFETY: the 8 samples at `at` of each row are in the slices `checked` cut
            // (`groups` groups of 16).
            let (y, u, v): (__m256i, __m256i, __m256i) = unsafe { (load(py, at), load(pu, at), load(pv, at)) };
            // `inverse_cc`, lane-wise (wrapping, as the scalar code).
            let y = _mm256_add_epi32(y, bias);
            let r = _mm256_sub_epi32(zero, u);
            let gg = _mm256_sub_epi32(y, _mm256_srai_epi32::<1>(r));
            let r = _mm256_sub_epi32(r, _mm256_sub_epi32(_mm256_srai_epi32::<1>(_mm256_add_epi32(v, one)), gg));
            let b = _mm256_add_epi32(v, r);
            let (first, last) = if swap { (b, r) } else { (r, b) };
            *h = [half(first), half(gg), half(last)];
        }
        // 16 samples of each channel, pixels 0-7 in the low lane and 8-15 in the high one
        // (`packs` takes the two halves' 64-bit quarters in turn; the permute sorts them).
        let [r, gg, b] = [0, 1, 2]
            .map(|c| _mm256_permute4x64_epi64::<0b11_01_10_00>(_mm256_packs_epi32(halves[0][c], halves[1][c])));
        // Part k of each lane's 8 pixels (48 bytes), as `interleave3x16` makes it.
        let p = masks.map(|m| {
            _mm256_or_si256(
                _mm256_or_si256(_mm256_shuffle_epi8(r, m[0]), _mm256_shuffle_epi8(gg, m[1])),
                _mm256_shuffle_epi8(b, m[2]),
            )
        });
        let parts = [
            _mm256_permute2x128_si256::<0x20>(p[0], p[1]),
            _mm256_blend_epi32::<0xf0>(p[2], p[0]),
            _mm256_permute2x128_si256::<0x31>(p[1], p[2]),
        ];
        for (k, x) in parts.into_iter().enumerate() {
            // SAFETY: group g's 96 bytes are in the slice `checked` cut.
            unsafe { store(o, 96 * g + 32 * k, x) };
        }
    }
    16 * groups
}
