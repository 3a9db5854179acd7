//! The stage-1 inverse PCT of full planes and the POT's interior 4×4 windows with AVX2
//! intrinsics: each group of eight blocks (or windows) is loaded from its coefficients (or
//! samples) straight into the operator's sixteen vectors by 4×4 transposes in both 128-bit
//! lanes of a register, and the results are transposed back into the rows, with no
//! coefficient-major scratch in between (the portable code's gather, lanes and scatter are
//! three passes over memory, each with its own index arithmetic and bounds checks).
//!
//! The operators are the portable ones ([`ipct4x4_g`], [`post4x4_g`], [`pre4x4_g`] on
//! [`V`]), compiled here for AVX2; `avx2_twin_matches_the_portable_transform` checks the
//! results are the portable code's.

use super::{ipct4x4_g, post4x4_g, pot4_interior_row_portable, pre4x4_g, Dir, Lane, MbRows, Rect, Rows};
use crate::mb::hp;
use std::arch::x86_64::{
    __m128i, __m256i, _mm256_add_epi32, _mm256_loadu_si256, _mm256_mullo_epi32, _mm256_permute2x128_si256,
    _mm256_set1_epi32, _mm256_set_m128i, _mm256_setzero_si256, _mm256_sra_epi32, _mm256_storeu_si256, _mm256_sub_epi32,
    _mm256_unpackhi_epi32, _mm256_unpackhi_epi64, _mm256_unpacklo_epi32, _mm256_unpacklo_epi64, _mm_loadu_si128,
};
use std::ops::{Add, AddAssign, Mul, Neg, Shr, Sub, SubAssign};

// Eight lanes of the operators' arithmetic in one AVX2 register (the portable code's [`V`]
// as LLVM would keep it: built from lane arrays, it split the operators into 128-bit halves).
simd_lane!(
    W,
    __m256i,
    "avx2",
    _mm256_add_epi32,
    _mm256_sub_epi32,
    _mm256_set1_epi32,
    _mm256_mullo_epi32,
    _mm256_sra_epi32,
    _mm256_setzero_si256,
    _mm256_unpacklo_epi32,
    _mm256_unpackhi_epi32,
    _mm256_unpacklo_epi64,
    _mm256_unpackhi_epi64
);

/// Four values of `s` from `at` (unaligned).
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn load4(s: &[i32], at: usize) -> __m128i {
    let s: &[i32; 4] = s[at..at + 4].try_into().expect("4 values");
    // SAFETY: `s` holds the 4 values the unaligned load reads.
    unsafe { _mm_loadu_si128(s.as_ptr().cast()) }
}

/// Stores eight values to `d` from `at` (unaligned).
#[inline]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
fn store8(d: &mut [i32], at: usize, x: __m256i) {
    let d: &mut [i32; 8] = (&mut d[at..at + 8]).try_into().expect("8 values");
    // SAFETY: `d` holds the 8 values the unaligned store writes.
    unsafe { _mm256_storeu_si256(d.as_mut_ptr().cast(), x) }
}

/// The HP coefficients of the four blocks of block row `jy` of macroblock (`mx`, `my`).
#[inline(always)]
fn quad<'a>(coeffs: &MbRows<'a>, mx: usize, my: usize, jy: usize) -> &'a [i32; 60] {
    coeffs.mb(mx, my)[hp(4 * jy, 1)..][..60].try_into().expect("four blocks")
}

/// The stage-1 inverse PCT of block row `jy` of macroblock row `my` of a full plane: the
/// block DCs `dc` (`4·mb_w`) and each block's 15 HP coefficients to the four sample rows
/// `out` (`16·mb_w` each). Two macroblocks (eight blocks) at a time, the blocks of the
/// first in the low 128-bit lane; an odd last macroblock fills both lanes and stores one.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) unsafe fn stage1_full_row(
    dc: &[i32],
    coeffs: &MbRows,
    my: usize,
    jy: usize,
    mb_w: usize,
    mut out: [&mut [i32]; 4],
) {
    for ma in (0..mb_w).step_by(2) {
        let pair = ma + 1 < mb_w;
        let mb = if pair { ma + 1 } else { ma };
        let (qa, qb) = (quad(coeffs, ma, my, jy), quad(coeffs, mb, my, jy));
        let mut c = [W(_mm256_setzero_si256()); 16];
        c[0] = W(_mm256_set_m128i(load4(dc, 4 * mb), load4(dc, 4 * ma)));
        // HP 1..4, 5..8, 9..12 and 12..15 (the last group overlaps the one before rather
        // than read past the four blocks): row i of each lane is block i's four values.
        for k0 in [0, 4, 8, 11] {
            let mut rows = [_mm256_setzero_si256(); 4];
            for (i, row) in rows.iter_mut().enumerate() {
                *row = _mm256_set_m128i(load4(qb, 15 * i + k0), load4(qa, 15 * i + k0));
            }
            for (k, x) in transpose(rows).into_iter().enumerate() {
                c[1 + k0 + k] = W(x);
            }
        }
        let t = ipct4x4_g(c);
        // Row j of each lane's four blocks, block by block: the rows of a transpose, whose
        // low lanes (the first macroblock) and high lanes (the second) go to their places.
        for (j, row) in out.iter_mut().enumerate() {
            let [x0, x1, x2, x3] = transpose([t[4 * j].0, t[4 * j + 1].0, t[4 * j + 2].0, t[4 * j + 3].0]);
            store8(row, 16 * ma, _mm256_permute2x128_si256::<0x20>(x0, x1));
            store8(row, 16 * ma + 8, _mm256_permute2x128_si256::<0x20>(x2, x3));
            if pair {
                store8(row, 16 * ma + 16, _mm256_permute2x128_si256::<0x31>(x0, x1));
                store8(row, 16 * ma + 24, _mm256_permute2x128_si256::<0x31>(x2, x3));
            }
        }
    }
}

/// The stage-2 inverse PCT of macroblock row `my` of a full plane ([`stage2_inverse`]'s
/// `PlaneKind::Full` case), eight macroblocks at a time: their DC and LP coefficients
/// transposed into the operator's sixteen registers (two 8×8 transposes), the block DCs
/// (doubled with `double`) transposed back into the four DC rows `out` (`4·mb_w` each).
/// Returns how many macroblocks it did (whole groups of eight); the caller does the rest.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) unsafe fn stage2_full_row(
    coeffs: &MbRows,
    my: usize,
    mb_w: usize,
    double: bool,
    mut out: [&mut [i32]; 4],
) -> usize {
    for g in 0..mb_w / 8 {
        let mut c = [W(_mm256_setzero_si256()); 16];
        for half in 0..2 {
            let mut m = [_mm256_setzero_si256(); 8];
            for (i, m) in m.iter_mut().enumerate() {
                let mb: &[i32; 8] = coeffs.mb(8 * g + i, my)[8 * half..][..8].try_into().expect("8 coefficients");
                // SAFETY: `mb` holds the 8 values the unaligned load reads.
                *m = unsafe { _mm256_loadu_si256(mb.as_ptr().cast()) };
            }
            // An 8×8 transpose: 4×4 ones in each lane of macroblocks i and i + 4, then the
            // lanes exchanged.
            let lo = transpose([m[0], m[1], m[2], m[3]]);
            let hi = transpose([m[4], m[5], m[6], m[7]]);
            for k in 0..4 {
                c[8 * half + k] = W(_mm256_permute2x128_si256::<0x20>(lo[k], hi[k]));
                c[8 * half + 4 + k] = W(_mm256_permute2x128_si256::<0x31>(lo[k], hi[k]));
            }
        }
        let mut t = ipct4x4_g(c);
        if double {
            for x in &mut t {
                *x = *x + *x;
            }
        }
        // Row j of the block DCs: the transpose gives lanes (i, i + 4) of column i.
        for (j, row) in out.iter_mut().enumerate() {
            let [x0, x1, x2, x3] = transpose([t[4 * j].0, t[4 * j + 1].0, t[4 * j + 2].0, t[4 * j + 3].0]);
            store8(row, 32 * g, _mm256_permute2x128_si256::<0x20>(x0, x1));
            store8(row, 32 * g + 8, _mm256_permute2x128_si256::<0x20>(x2, x3));
            store8(row, 32 * g + 16, _mm256_permute2x128_si256::<0x31>(x0, x1));
            store8(row, 32 * g + 24, _mm256_permute2x128_si256::<0x31>(x2, x3));
        }
    }
    mb_w / 8 * 8
}

pot4_interior_kernel!(
    /// [`pot4_interior_kernel!`] with eight windows a step (two a register); the last
    /// `count mod 8` windows run in the portable code.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    W,
    8,
    "avx2",
    _mm256_loadu_si256,
    _mm256_storeu_si256,
    _mm256_setzero_si256,
    |p, rest, y, dir, cm| pot4_interior_row_portable(p, rest, y, dir, cm)
);
