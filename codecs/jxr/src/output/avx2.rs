//! The last step of the RGB output formats with AVX2 (SSSE3 byte shuffles and SSE2 unpacks,
//! VEX-encoded): a run's converted R, G and B samples interleaved into the pixels with
//! vector shuffles and 16-byte stores, where the portable loop moves every sample on its own
//! (about 12 instructions a pixel for 48bppRGBHalf, more than the colour transform and the
//! half conversion together). Each function writes whole groups of pixels and returns how many
//! it wrote; the portable loop writes the rest. `format_row_twins_agree` checks the bytes.

use std::arch::x86_64::{
    __m128i, _mm_loadu_si128, _mm_or_si128, _mm_setzero_si128, _mm_shuffle_epi8, _mm_storeu_si128, _mm_unpackhi_epi16,
    _mm_unpackhi_epi32, _mm_unpackhi_epi64, _mm_unpacklo_epi16, _mm_unpacklo_epi32, _mm_unpacklo_epi64,
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

/// 16 bytes from `p + at` (unaligned).
///
/// # Safety
/// The 16 bytes must be readable.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn load<T>(p: *const T, at: usize) -> __m128i {
    // SAFETY: the caller guarantees the 16 bytes.
    unsafe { _mm_loadu_si128(p.add(at).cast()) }
}

/// Stores 16 bytes to `p + at` (unaligned).
///
/// # Safety
/// The 16 bytes must be writable.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn store(p: *mut u8, at: usize, x: __m128i) {
    // SAFETY: the caller guarantees the 16 bytes.
    unsafe { _mm_storeu_si128(p.add(at).cast(), x) }
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
