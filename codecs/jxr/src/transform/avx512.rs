//! The POT's interior 4×4 windows sixteen at a time in AVX-512 registers: the `avx2` module's
//! kernel with four 128-bit lanes a register instead of two. Its loads are whole registers,
//! so each 4×4 transpose serves twice as many windows; on a CPU that runs 512-bit operations
//! at full width (this project's Zen 5 machine) the inverse transform of a plane with overlap
//! takes about a fifth less time (`examples/transform_speed`: 12.9 → 10.4 ms for 16.7 M
//! samples, overlap one).
//!
//! The stage-1 PCT was tried the same way (four macroblocks a register, one per 128-bit
//! lane) and was 1.7× slower than the AVX2 kernel: its blocks are gathered four values at a
//! time, and the inserts and lane shuffles that takes outweigh the wider arithmetic.
//!
//! The operators are the portable ones ([`post4x4_g`], [`pre4x4_g`]), compiled here for
//! AVX-512; `avx512_twin_matches_the_portable_transform`
//! checks the results are the portable code's.

use super::{post4x4_g, pre4x4_g, Dir, Lane, Rect, Rows};
use std::arch::x86_64::{
    __m512i, _mm512_add_epi32, _mm512_loadu_si512, _mm512_mullo_epi32, _mm512_set1_epi32, _mm512_setzero_si512,
    _mm512_sra_epi32, _mm512_storeu_si512, _mm512_sub_epi32, _mm512_unpackhi_epi32, _mm512_unpackhi_epi64,
    _mm512_unpacklo_epi32, _mm512_unpacklo_epi64,
};
use std::ops::{Add, AddAssign, Mul, Neg, Shr, Sub, SubAssign};

// Sixteen lanes of the operators' arithmetic in one AVX-512 register.
simd_lane!(
    Z,
    __m512i,
    "avx512f",
    _mm512_add_epi32,
    _mm512_sub_epi32,
    _mm512_set1_epi32,
    _mm512_mullo_epi32,
    _mm512_sra_epi32,
    _mm512_setzero_si512,
    _mm512_unpacklo_epi32,
    _mm512_unpackhi_epi32,
    _mm512_unpacklo_epi64,
    _mm512_unpackhi_epi64
);

pot4_interior_kernel!(
    /// [`pot4_interior_kernel!`] with sixteen windows a step (four a register); the last
    /// `count mod 16` windows run in the AVX2 kernel.
    ///
    /// # Safety
    /// The CPU must support AVX-512F and AVX2.
    Z,
    16,
    "avx512f,avx2",
    _mm512_loadu_si512,
    _mm512_storeu_si512,
    _mm512_setzero_si512,
    // SAFETY: the caller guarantees AVX2.
    |p, rest, y, dir, cm| unsafe { super::avx2::pot4_interior_row(p, rest, y, dir, cm) }
);
