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
    _mm256_unpackhi_epi32, _mm256_unpackhi_epi64, _mm256_unpacklo_epi32, _mm256_unpacklo_epi64, _mm_cvtsi32_si128,
    _mm_loadu_si128,
};
use std::ops::{Add, AddAssign, Mul, Neg, Shr, Sub, SubAssign};

/// The 4×4 transpose of the rows `m` in each 128-bit lane: lane `l` of `out[c]` holds element
/// `c` of lane `l` of `m[0]`, `m[1]`, `m[2]`, `m[3]` (its own inverse).
#[inline]
#[target_feature(enable = "avx2")]
fn transpose(m: [__m256i; 4]) -> [__m256i; 4] {
    let (t0, t1) = (_mm256_unpacklo_epi32(m[0], m[1]), _mm256_unpacklo_epi32(m[2], m[3]));
    let (t2, t3) = (_mm256_unpackhi_epi32(m[0], m[1]), _mm256_unpackhi_epi32(m[2], m[3]));
    [
        _mm256_unpacklo_epi64(t0, t1),
        _mm256_unpackhi_epi64(t0, t1),
        _mm256_unpacklo_epi64(t2, t3),
        _mm256_unpackhi_epi64(t2, t3),
    ]
}

/// Eight lanes of the operators' arithmetic in one AVX2 register (the portable code's [`V`]
/// as LLVM would keep it: built from lane arrays, it split the operators into 128-bit halves).
/// A `W` exists only inside this module's AVX2 functions (its one constructor is theirs), so
/// its operations, inlined there, run only on CPUs with AVX2.
#[derive(Clone, Copy)]
pub(super) struct W(__m256i);

macro_rules! w_op {
    ($tr:ident, $f:ident, $rhs:ty, |$a:ident, $b:ident| $e:expr) => {
        impl $tr<$rhs> for W {
            type Output = W;
            #[inline(always)]
            #[allow(unsafe_code)]
            fn $f(self, o: $rhs) -> W {
                let ($a, $b) = (self.0, o);
                // SAFETY: a `W` exists only in code that runs on CPUs with AVX2 (see `W`).
                W(unsafe { $e })
            }
        }
    };
}
w_op!(Add, add, W, |a, b| _mm256_add_epi32(a, b.0));
w_op!(Sub, sub, W, |a, b| _mm256_sub_epi32(a, b.0));
w_op!(Add, add, i32, |a, k| _mm256_add_epi32(a, _mm256_set1_epi32(k)));
w_op!(Mul, mul, i32, |a, k| _mm256_mullo_epi32(a, _mm256_set1_epi32(k)));
w_op!(Shr, shr, u32, |a, k| _mm256_sra_epi32(a, _mm_cvtsi32_si128(k as i32)));

impl Neg for W {
    type Output = W;
    #[inline(always)]
    #[allow(unsafe_code)]
    fn neg(self) -> W {
        // SAFETY: as in `w_op`.
        W(unsafe { _mm256_sub_epi32(_mm256_setzero_si256(), self.0) })
    }
}
impl AddAssign for W {
    #[inline(always)]
    fn add_assign(&mut self, o: W) {
        *self = *self + o;
    }
}
impl SubAssign for W {
    #[inline(always)]
    fn sub_assign(&mut self, o: W) {
        *self = *self - o;
    }
}
impl Lane for W {}

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

/// The POT's interior 4×4 windows of the seam row `y` of `r` ([`pot4_interior_row_portable`]'s
/// windows), eight at a time straight from the rows: the 32 samples of a window row of eight
/// windows are four registers of two windows each, whose transpose gives each of the row's
/// four samples for the windows in the order 0 2 4 6 | 1 3 5 7 (any order will do: the
/// transpose back restores it). The last `count mod 8` windows run in the portable code.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
pub(super) unsafe fn pot4_interior_row(p: &mut Rows, r: Rect, y: usize, dir: Dir, cm: &mut Vec<i32>) {
    let count = ((r.x1 - r.x0) / 4).saturating_sub(1);
    let groups = count / 8;
    let top = p.at(r.x0 + 2, y - 2);
    let stride = p.stride;
    // Every access below is inside `rows` (window row j of group g: 32 samples from
    // j·stride + 32·g), checked once here rather than at each load and store.
    let rows = if groups > 0 { &mut p.data[top..][..3 * stride + 32 * groups] } else { &mut [] };
    let base = rows.as_mut_ptr();
    for g in 0..groups {
        let mut v = [W(_mm256_setzero_si256()); 16];
        for j in 0..4 {
            // SAFETY: j·stride + 32·g + 32 ≤ 3·stride + 32·groups, the length of `rows`.
            let at = unsafe { base.add(j * stride + 32 * g) };
            // SAFETY: the 32 samples from `at` are in `rows` (above); unaligned loads.
            let x = unsafe { [0, 8, 16, 24].map(|o| _mm256_loadu_si256(at.add(o).cast())) };
            for (i, x) in transpose(x).into_iter().enumerate() {
                v[4 * j + i] = W(x);
            }
        }
        let v = match dir {
            Dir::Inverse => post4x4_g(v),
            Dir::Forward => pre4x4_g(v),
        };
        for j in 0..4 {
            let x = transpose([v[4 * j].0, v[4 * j + 1].0, v[4 * j + 2].0, v[4 * j + 3].0]);
            for (o, x) in x.into_iter().enumerate() {
                // SAFETY: as for the loads.
                unsafe { _mm256_storeu_si256(base.add(j * stride + 32 * g + 8 * o).cast(), x) };
            }
        }
    }
    if groups * 8 < count {
        let rest = Rect { x0: r.x0 + 32 * groups, ..r };
        pot4_interior_row_portable(p, rest, y, dir, cm);
    }
}
