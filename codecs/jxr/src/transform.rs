//! The lapped transform of JPEG XR (T.832 clause 9.9 and Annex D; JXR-NOTES §6): the Photo
//! Core Transform (PCT) and the Photo Overlap Transform (POT), inverse for decoding and
//! forward for encoding, in the operator set of JPEG XR (codestream sub-versions 1 and 9).
//!
//! The operators are those of the ITU reference software T.835 (`algo.c`: `_jxr_4x4IPCT`,
//! `_jxr_4x4OverlapFilter`, `_jxr_4OverlapFilter`, `_jxr_2x2OverlapFilter`,
//! `_jxr_2OverlapFilter` and their encoder twins), which gives byte-identical output with
//! jxrlib's `strInvTransform.c` on JPEG XR streams (JXR-NOTES §8). Where T.835 applies them is
//! `r_strip.c`; here the same operations are laid out plane-wide, stage by stage:
//!
//! 1. **Stage-2 PCT** per macroblock: DC and LP coefficients (T.835's per-macroblock layout, see [`inverse_band`]) to the
//!    16 block DCs (4:2:0 chroma: a 2×2 transform to 4; 4:2:2 chroma: a 2-point Haar step and
//!    two 2×2 transforms to 8), doubled for every channel after the first in scaled
//!    arithmetic (T.835 `IPCT_level1_up1`). The DCs form a *DC plane* (4 per MB each way; 2
//!    across and 2 or 4 down for 4:2:0 / 4:2:2 chroma).
//! 2. **Stage-2 POT** (OVERLAP_MODE 2) on the DC plane across macroblock seams
//!    (`overlap_level1_up2_*`).
//! 3. **Stage-1 PCT** per 4×4 block: the block's DC and its 15 HP coefficients to 16 samples
//!    (`IPCT_level2_up2`).
//! 4. **Stage-1 POT** (OVERLAP_MODE ≥ 1) on the sample plane across block seams
//!    (`overlap_level2_up3_*`).
//!
//! Each POT stage is the same pattern on a grid of pitch 4 (or 2 for the chroma DC planes of
//! 4:2:0 and 4:2:2): a 4×4 (2×2) operator on the window centred on each interior grid corner,
//! a 4-point (2-point) operator across each seam along the two outermost rows and columns, and
//! at the four corners the 4-point operator on the 2×2 corner (chroma DC planes instead store
//! the corner as a difference from its neighbour before filtering and add it back after).
//! The windows of one stage are disjoint, so their order does not matter and every row of
//! windows is independent. With hard tiles each tile is treated as an image of its own.
//!
//! All arithmetic wraps like jxrlib's 32-bit C, so no input makes it panic.
//!
//! HD Photo 1.0 codestreams (sub-version 0) use older overlap operators, a DC-leakage clamp
//! and no corner operators: [`OperatorSet::HdPhoto`], implemented in the `legacy` submodule.

/// Applies the operator `$f` (a function or closure on an array) to the elements of the
/// array `$x` (a `&mut`) at the indices `$i`. A macro, so that `$f` is called directly: an
/// operator passed as `impl Fn` reached the AVX2 twins through a `Fn::call` shim that LLVM
/// did not inline, compiled without AVX2, its lanes passed through memory.
macro_rules! ap {
    ($x:expr, $i:expr, $f:expr) => {{
        let (x, i) = ($x, $i);
        let v = $f(i.map(|k: usize| x[k]));
        for (k, y) in i.into_iter().zip(v) {
            x[k] = y;
        }
    }};
}

/// A register of 32-bit lanes as a [`Lane`] for the operators, and the 4×4 transpose in each
/// of its 128-bit lanes, for the `avx2` and `avx512` modules: `simd_lane!(W, __m256i, "avx2",
/// _mm256_add_epi32, …)` declares `W` and `transpose` with the intrinsics it names. A value of the type
/// exists only inside that module's functions compiled for `$feature` (its one constructor is
/// theirs), so its operations, inlined there, run only on CPUs with the feature.
#[cfg(target_arch = "x86_64")]
macro_rules! simd_lane {
    ($name:ident, $reg:ty, $feature:literal,
     $add:ident, $sub:ident, $set1:ident, $mullo:ident, $sra:ident, $zero:ident,
     $lo32:ident, $hi32:ident, $lo64:ident, $hi64:ident) => {
        #[derive(Clone, Copy)]
        pub(super) struct $name($reg);

        macro_rules! lane_op {
            ($tr:ident, $f:ident, $rhs:ty, |$a:ident, $b:ident| $e:expr) => {
                impl $tr<$rhs> for $name {
                    type Output = $name;
                    #[inline(always)]
                    #[allow(unsafe_code)]
                    fn $f(self, o: $rhs) -> $name {
                        let ($a, $b) = (self.0, o);
                        // SAFETY: a value of this type exists only in code that runs on CPUs
                        // with the module's feature (see `simd_lane!`).
                        $name(unsafe { $e })
                    }
                }
            };
        }
        lane_op!(Add, add, $name, |a, b| $add(a, b.0));
        lane_op!(Sub, sub, $name, |a, b| $sub(a, b.0));
        lane_op!(Add, add, i32, |a, k| $add(a, $set1(k)));
        lane_op!(Mul, mul, i32, |a, k| $mullo(a, $set1(k)));
        lane_op!(Shr, shr, u32, |a, k| $sra(a, std::arch::x86_64::_mm_cvtsi32_si128(k as i32)));

        impl Neg for $name {
            type Output = $name;
            #[inline(always)]
            #[allow(unsafe_code)]
            fn neg(self) -> $name {
                // SAFETY: as in `lane_op`.
                $name(unsafe { $sub($zero(), self.0) })
            }
        }
        impl AddAssign for $name {
            #[inline(always)]
            fn add_assign(&mut self, o: $name) {
                *self = *self + o;
            }
        }
        impl SubAssign for $name {
            #[inline(always)]
            fn sub_assign(&mut self, o: $name) {
                *self = *self - o;
            }
        }
        impl Lane for $name {}

        /// The 4×4 transpose of the rows `m` in each 128-bit lane: lane `l` of `out[c]` holds
        /// element `c` of lane `l` of `m[0]`, `m[1]`, `m[2]`, `m[3]` (its own inverse).
        #[inline]
        #[target_feature(enable = $feature)]
        fn transpose(m: [$reg; 4]) -> [$reg; 4] {
            let (t0, t1) = ($lo32(m[0], m[1]), $lo32(m[2], m[3]));
            let (t2, t3) = ($hi32(m[0], m[1]), $hi32(m[2], m[3]));
            [$lo64(t0, t1), $hi64(t0, t1), $lo64(t2, t3), $hi64(t2, t3)]
        }
    };
}

/// The POT's interior 4×4 windows of the seam row `y` of `r` ([`pot4_interior_row_portable`]'s
/// windows) with a [`simd_lane!`] type of `$n` lanes, `$n` windows at a time straight from the
/// rows: the `4·$n` samples of a window row of `$n` windows are four registers of `$n / 4`
/// windows each, whose transpose gives each of the row's four samples for the windows in
/// some order (any will do: the transpose back restores it). The last `count mod $n`
/// windows run in `$rest_call`, given the rectangle `$rest` they start at.
#[cfg(target_arch = "x86_64")]
macro_rules! pot4_interior_kernel {
    ($(#[$doc:meta])* $lane:ident, $n:literal, $feature:literal, $load:ident, $store:ident, $zero:ident,
     |$p:ident, $rest:ident, $y:ident, $dir:ident, $cm:ident| $rest_call:expr) => {
        $(#[$doc])*
        #[target_feature(enable = $feature)]
        #[allow(unsafe_code)]
        pub(super) unsafe fn pot4_interior_row($p: &mut Rows, r: Rect, $y: usize, $dir: Dir, $cm: &mut Vec<i32>) {
            let count = ((r.x1 - r.x0) / 4).saturating_sub(1);
            let groups = count / $n;
            let top = $p.at(r.x0 + 2, $y - 2);
            let stride = $p.stride;
            // Every access below is inside `rows` (window row j of group g: 4·$n samples from
            // j·stride + 4·$n·g), checked once here rather than at each load and store.
            let rows = if groups > 0 { &mut $p.data[top..][..3 * stride + 4 * $n * groups] } else { &mut [] };
            let base = rows.as_mut_ptr();
            for g in 0..groups {
                let mut v = [$lane($zero()); 16];
                for j in 0..4 {
                    // SAFETY: j·stride + 4·$n·(g + 1) ≤ 3·stride + 4·$n·groups, the length of
                    // `rows`.
                    let at = unsafe { base.add(j * stride + 4 * $n * g) };
                    // SAFETY: the 4·$n samples from `at` are in `rows` (above); unaligned loads.
                    let x = unsafe { [0, $n, 2 * $n, 3 * $n].map(|o| $load(at.add(o).cast())) };
                    for (i, x) in transpose(x).into_iter().enumerate() {
                        v[4 * j + i] = $lane(x);
                    }
                }
                let v = match $dir {
                    Dir::Inverse => post4x4_g(v),
                    Dir::Forward => pre4x4_g(v),
                };
                for j in 0..4 {
                    let x = transpose([v[4 * j].0, v[4 * j + 1].0, v[4 * j + 2].0, v[4 * j + 3].0]);
                    for (o, x) in x.into_iter().enumerate() {
                        // SAFETY: as for the loads.
                        unsafe { $store(base.add(j * stride + 4 * $n * g + $n * o).cast(), x) };
                    }
                }
            }
            if groups * $n < count {
                let $rest = Rect { x0: r.x0 + 4 * $n * groups, ..r };
                $rest_call
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;
mod legacy;
pub use legacy::DcLeakage;

use crate::mb::{hp, lp, MbCoeffs, DC, MB_COEFFS};
use hdrcodec_core::{Error, Result};
use std::ops::{Add, AddAssign, Mul, Neg, Range, RangeInclusive, Shr, Sub, SubAssign};

/// The arithmetic the operators need: wrapping 32-bit integer lifting steps. Implemented for
/// one sample ([`S`]) and for [`LANES`] samples of as many independent windows or blocks
/// ([`V`]), whose lane-wise loops the compiler turns into SIMD instructions.
trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Neg<Output = Self>
    + Shr<u32, Output = Self>
    + Add<i32, Output = Self>
    + Mul<i32, Output = Self>
    + AddAssign
    + SubAssign
{
}

/// One sample, wrapping like 32-bit C.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct S(i32);

/// Samples processed together by the vector paths.
const LANES: usize = 8;

/// [`LANES`] samples, one per window or block, wrapping like 32-bit C.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct V([i32; LANES]);

macro_rules! lane_ops {
    ($t:ident, $map:ident) => {
        impl Add for $t {
            type Output = $t;
            #[inline(always)]
            fn add(self, o: $t) -> $t {
                $map!(self, o, |a: i32, b: i32| a.wrapping_add(b))
            }
        }
        impl Sub for $t {
            type Output = $t;
            #[inline(always)]
            fn sub(self, o: $t) -> $t {
                $map!(self, o, |a: i32, b: i32| a.wrapping_sub(b))
            }
        }
        impl AddAssign for $t {
            #[inline(always)]
            fn add_assign(&mut self, o: $t) {
                *self = *self + o;
            }
        }
        impl SubAssign for $t {
            #[inline(always)]
            fn sub_assign(&mut self, o: $t) {
                *self = *self - o;
            }
        }
        impl Lane for $t {}
    };
}

macro_rules! map_s {
    ($a:expr, $b:expr, $f:expr) => {
        S($f($a.0, $b.0))
    };
}

macro_rules! map_v {
    ($a:expr, $b:expr, $f:expr) => {{
        let (a, b) = ($a.0, $b.0);
        let mut r = [0i32; LANES];
        for i in 0..LANES {
            r[i] = $f(a[i], b[i]);
        }
        V(r)
    }};
}

lane_ops!(S, map_s);
lane_ops!(V, map_v);

impl Neg for S {
    type Output = S;
    #[inline(always)]
    fn neg(self) -> S {
        S(self.0.wrapping_neg())
    }
}
impl Shr<u32> for S {
    type Output = S;
    #[inline(always)]
    fn shr(self, k: u32) -> S {
        S(self.0 >> k)
    }
}
impl Add<i32> for S {
    type Output = S;
    #[inline(always)]
    fn add(self, k: i32) -> S {
        S(self.0.wrapping_add(k))
    }
}
impl Mul<i32> for S {
    type Output = S;
    #[inline(always)]
    fn mul(self, k: i32) -> S {
        S(self.0.wrapping_mul(k))
    }
}
impl Neg for V {
    type Output = V;
    #[inline(always)]
    fn neg(self) -> V {
        V(self.0.map(i32::wrapping_neg))
    }
}
impl Shr<u32> for V {
    type Output = V;
    #[inline(always)]
    fn shr(self, k: u32) -> V {
        V(self.0.map(|a| a >> k))
    }
}
impl Add<i32> for V {
    type Output = V;
    #[inline(always)]
    fn add(self, k: i32) -> V {
        V(self.0.map(|a| a.wrapping_add(k)))
    }
}
impl Mul<i32> for V {
    type Output = V;
    #[inline(always)]
    fn mul(self, k: i32) -> V {
        V(self.0.map(|a| a.wrapping_mul(k)))
    }
}

/// OVERLAP_MODE (T.832 8.3.2): which POT stages run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OverlapMode {
    /// No overlap filtering.
    None = 0,
    /// The stage-1 POT only (block seams in the sample domain).
    One = 1,
    /// Both stages (also macroblock seams in the DC domain).
    Two = 2,
}

/// How a channel's plane is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PlaneKind {
    /// Full resolution: 16×16 samples, 16 blocks per macroblock (every channel of YONLY,
    /// YUV444, YUVK and NCOMPONENT, and luma of 4:2:0 and 4:2:2).
    Full,
    /// 4:2:0 chroma: 8×8 samples, 2×2 blocks per macroblock.
    Chroma420,
    /// 4:2:2 chroma: 8 wide, 16 high, 2×4 blocks per macroblock.
    Chroma422,
}

impl PlaneKind {
    /// Blocks per macroblock across and down.
    pub fn blocks(self) -> (usize, usize) {
        match self {
            PlaneKind::Full => (4, 4),
            PlaneKind::Chroma420 => (2, 2),
            PlaneKind::Chroma422 => (2, 4),
        }
    }
}

/// Internal tile edges treated as image edges (hard tiles, T.832 HARD_TILING_FLAG).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HardEdges {
    /// Macroblock columns at which a vertical tile edge lies (a tile starts there).
    pub columns: Vec<usize>,
    /// Macroblock rows at which a horizontal tile edge lies.
    pub rows: Vec<usize>,
}

impl HardEdges {
    /// The edges of a tile grid given the first macroblock column of each tile column and
    /// the first macroblock row of each tile row. With `jxrlib_swap`, jxrlib's behaviour
    /// (JXR-NOTES §8 quirk 1, `invTransformMacroblock_alteredOperators_hard`): it finds
    /// vertical seams at the tile *row* positions and horizontal seams at the tile *column*
    /// positions, which differs from T.832 when the grid is not square.
    pub fn from_tiles(column_starts: &[usize], row_starts: &[usize], jxrlib_swap: bool) -> Self {
        let (c, r) = if jxrlib_swap { (row_starts, column_starts) } else { (column_starts, row_starts) };
        HardEdges { columns: c.to_vec(), rows: r.to_vec() }
    }
}

/// What a codestream's image header says about its transform: OVERLAP_MODE, and the tile
/// edges treated as image edges when HARD_TILING_FLAG is set. Each codestream has its own: a
/// planar alpha codestream can have another overlap than the colour's (JxrEncApp below
/// quality 0.5 writes the colour with two overlap stages and lossless alpha with one), and
/// jxrlib transforms each with its own.
pub fn image_geometry(img: &crate::header::ImageHeader) -> (OverlapMode, Option<HardEdges>) {
    let overlap = [OverlapMode::None, OverlapMode::One, OverlapMode::Two][usize::from(img.overlap.min(2))];
    let hard = img.hard_tiling.then(|| {
        let cols: Vec<usize> = img.tile_x0().iter().map(|&v| v as usize).collect();
        let rows: Vec<usize> = img.tile_y0().iter().map(|&v| v as usize).collect();
        HardEdges::from_tiles(&cols[..cols.len() - 1], &rows[..rows.len() - 1], true)
    });
    (overlap, hard)
}

/// Checks that the transform implements the operator set of a codestream's sub-version (the
/// 4 bits jxrlib reads as HARD_TILING_FLAG and RESERVED_C, JXR-NOTES §2 and §6): 1 (soft
/// tiles) and 9 (hard tiles) use the JPEG XR operators; 0 (HD Photo 1.0, `.wdp`/`.hdp` files
/// from Vista-era WIC) uses jxrlib's legacy operators ([`OperatorSet::HdPhoto`]); jxrlib
/// refuses every other value.
pub fn check_operator_set(sub_version: u8) -> Result<()> {
    match sub_version {
        0 | 1 | 9 => Ok(()),
        v => Err(Error::invalid(format!("codestream sub-version {v} (jxrlib accepts 0, 1 and 9)"))),
    }
}

/// Which overlap operators a plane's inverse transform uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OperatorSet {
    /// JPEG XR's (T.832; codestream sub-versions 1 and 9).
    JpegXr,
    /// HD Photo 1.0's (sub-version 0; jxrlib's `invTransformMacroblock`), with the plane's
    /// DC-leakage clamp parameters.
    HdPhoto(DcLeakage),
}

impl OperatorSet {
    /// The operator set of plane `plane` (0 primary, 1 interleaved alpha) of the codestream
    /// `data` whose headers are `cs` (see [`DcLeakage::for_codestream`]).
    pub fn for_plane(
        cs: &crate::header::Codestream,
        data: &[u8],
        plane: usize,
        options: &hdrcodec_core::DecodeOptions,
    ) -> Result<Self> {
        check_operator_set(cs.image.sub_version)?;
        Ok(match cs.image.sub_version {
            0 => OperatorSet::HdPhoto(DcLeakage::for_codestream(cs, data, plane, options)?),
            _ => OperatorSet::JpegXr,
        })
    }
}

/// What the transform needs from the headers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TransformParams {
    /// OVERLAP_MODE.
    pub overlap: OverlapMode,
    /// SCALED_FLAG of the plane (doubles the stage-2 output of channels after the first).
    pub scaled: bool,
    /// `Some` for hard tiles.
    pub hard: Option<HardEdges>,
    /// The overlap operators (by codestream sub-version).
    pub operators: OperatorSet,
}

/// One channel's samples after the inverse transform: `width × height` (the extended size,
/// subsampled for 4:2:0 and 4:2:2 chroma), row-major.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plane {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The samples.
    pub data: Vec<i32>,
}

// ---------------------------------------------------------------------------------------------
// The operators (T.835 `algo.c`), on samples of a slice picked by index.

#[inline(always)]
fn load<const N: usize>(p: &[i32], i: [usize; N]) -> [S; N] {
    i.map(|k| S(p[k]))
}

#[inline(always)]
fn store<const N: usize>(p: &mut [i32], i: [usize; N], v: [S; N]) {
    for (k, x) in i.into_iter().zip(v) {
        p[k] = x.0;
    }
}

/// The 2×2 Hadamard butterfly `_2x2T_h` (self-inverse).
#[inline(always)]
fn t2x2h<T: Lane>(v: [T; 4], r: i32) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    a += d;
    b -= c;
    let t1 = (a - b + r) >> 1;
    let t2 = c;
    c = t1 - d;
    d = t1 - t2;
    a -= d;
    b += c;
    [a, b, c, d]
}

#[inline(always)]
fn t2x2h_post<T: Lane>(v: [T; 4]) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b -= c;
    a += (d * 3 + 4) >> 3;
    d -= b >> 1;
    let t1 = ((a - b) >> 1) - c;
    c = d;
    d = t1;
    a -= d;
    b += c;
    [a, b, c, d]
}

#[inline(always)]
fn t2x2h_enc<T: Lane>(v: [T; 4]) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    a += d;
    b -= c;
    let (t1, t2) = (d, c);
    c = ((a - b) >> 1) - t1;
    d = t2 + (b >> 1);
    b += c;
    a -= (d * 3 + 4) >> 3;
    [a, b, c, d]
}

#[inline(always)]
fn inv_t_odd<T: Lane>(v: [T; 4]) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b += d;
    a -= c;
    d -= b >> 1;
    c += (a + 1) >> 1;
    a -= (b * 3 + 4) >> 3;
    b += (a * 3 + 4) >> 3;
    c -= (d * 3 + 4) >> 3;
    d += (c * 3 + 4) >> 3;
    c -= (b + 1) >> 1;
    d = ((a + 1) >> 1) - d;
    b += c;
    a -= d;
    [a, b, c, d]
}

#[inline(always)]
fn fwd_t_odd<T: Lane>(v: [T; 4]) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b -= c;
    a += d;
    c += (b + 1) >> 1;
    d = ((a + 1) >> 1) - d;
    b -= (a * 3 + 4) >> 3;
    a += (b * 3 + 4) >> 3;
    d -= (c * 3 + 4) >> 3;
    c += (d * 3 + 4) >> 3;
    d += b >> 1;
    c -= (a + 1) >> 1;
    b -= d;
    a += c;
    [a, b, c, d]
}

/// The odd-odd rotation shared by `_InvT_odd_odd` (rounding 3, 3; outputs b and c negated)
/// and `_InvT_odd_odd_POST` (rounding 6, 2).
#[inline(always)]
fn inv_odd_odd<T: Lane>(v: [T; 4], r1: i32, r2: i32, negate: bool) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    d += a;
    c -= b;
    let t1 = d >> 1;
    let t2 = c >> 1;
    a -= t1;
    b += t2;
    a -= (b * 3 + r1) >> 3;
    b += (a * 3 + r2) >> 2;
    a -= (b * 3 + 4) >> 3;
    b -= t2;
    a += t1;
    c += b;
    d -= a;
    if negate {
        [a, -b, -c, d]
    } else {
        [a, b, c, d]
    }
}

/// The inverse of [`inv_odd_odd`] with the same parameters (`_T_odd_odd`,
/// `fwdT_Odd_Odd_PRE`).
#[inline(always)]
fn fwd_odd_odd<T: Lane>(v: [T; 4], r1: i32, r2: i32, negate: bool) -> [T; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    if negate {
        b = -b;
        c = -c;
    }
    d += a;
    c -= b;
    let t1 = d >> 1;
    let t2 = c >> 1;
    a -= t1;
    b += t2;
    a += (b * 3 + 4) >> 3;
    b -= (a * 3 + r2) >> 2;
    a += (b * 3 + r1) >> 3;
    b -= t2;
    a += t1;
    c += b;
    d -= a;
    [a, b, c, d]
}

#[inline(always)]
fn inv_t_odd_odd<T: Lane>(v: [T; 4]) -> [T; 4] {
    inv_odd_odd(v, 3, 3, true)
}

#[inline(always)]
fn fwd_t_odd_odd<T: Lane>(v: [T; 4]) -> [T; 4] {
    fwd_odd_odd(v, 3, 3, true)
}

#[inline(always)]
fn inv_t_odd_odd_post<T: Lane>(v: [T; 4]) -> [T; 4] {
    inv_odd_odd(v, 6, 2, false)
}

#[inline(always)]
fn fwd_t_odd_odd_pre<T: Lane>(v: [T; 4]) -> [T; 4] {
    fwd_odd_odd(v, 6, 2, false)
}

#[inline(always)]
fn inv_rotate<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    a -= (b + 1) >> 1;
    b += (a + 1) >> 1;
    [a, b]
}

#[inline(always)]
fn fwd_rotate<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    b -= (a + 1) >> 1;
    a += (b + 1) >> 1;
    [a, b]
}

#[inline(always)]
fn inv_scale<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    a += b;
    b = (a >> 1) - b;
    a += (b * 3) >> 3;
    b -= a >> 10;
    b += a >> 7;
    b += (a * 3) >> 4;
    [a, b]
}

#[inline(always)]
fn fwd_scale<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    b -= (a * 3) >> 4;
    b -= a >> 7;
    b += a >> 10;
    a -= (b * 3) >> 3;
    b = (a >> 1) - b;
    a -= b;
    [a, b]
}

/// `_jxr_4x4IPCT`: 16 coefficients (DC first) to 16 samples in raster order.
#[inline(always)]
fn ipct4x4_g<T: Lane>(c: [T; 16]) -> [T; 16] {
    const INV_PERMUTE: [usize; 16] = [0, 8, 4, 13, 2, 15, 3, 14, 1, 12, 5, 9, 7, 11, 6, 10];
    let mut t = c;
    for (i, &v) in c.iter().enumerate() {
        t[INV_PERMUTE[i]] = v;
    }
    ap!(&mut t, [0, 1, 4, 5], |v| t2x2h(v, 1));
    ap!(&mut t, [2, 3, 6, 7], inv_t_odd);
    ap!(&mut t, [8, 12, 9, 13], inv_t_odd);
    ap!(&mut t, [10, 11, 14, 15], inv_t_odd_odd);
    ap!(&mut t, [0, 3, 12, 15], |v| t2x2h(v, 0));
    ap!(&mut t, [5, 6, 9, 10], |v| t2x2h(v, 0));
    ap!(&mut t, [1, 2, 13, 14], |v| t2x2h(v, 0));
    ap!(&mut t, [4, 7, 8, 11], |v| t2x2h(v, 0));
    t
}

/// `_jxr_4x4PCT`: the inverse of [`ipct4x4_g`].
#[inline(always)]
fn pct4x4_g<T: Lane>(c: [T; 16]) -> [T; 16] {
    const FWD_PERMUTE: [usize; 16] = [0, 8, 4, 6, 2, 10, 14, 12, 1, 11, 15, 13, 9, 3, 7, 5];
    let mut t = c;
    ap!(&mut t, [0, 3, 12, 15], |v| t2x2h(v, 0));
    ap!(&mut t, [5, 6, 9, 10], |v| t2x2h(v, 0));
    ap!(&mut t, [1, 2, 13, 14], |v| t2x2h(v, 0));
    ap!(&mut t, [4, 7, 8, 11], |v| t2x2h(v, 0));
    ap!(&mut t, [0, 1, 4, 5], |v| t2x2h(v, 1));
    ap!(&mut t, [2, 3, 6, 7], fwd_t_odd);
    ap!(&mut t, [8, 12, 9, 13], fwd_t_odd);
    ap!(&mut t, [10, 11, 14, 15], fwd_t_odd_odd);
    let mut out = t;
    for (i, &v) in t.iter().enumerate() {
        out[FWD_PERMUTE[i]] = v;
    }
    out
}

#[inline(always)]
fn ipct4x4(c: &mut [i32; 16]) {
    *c = ipct4x4_g(c.map(S)).map(|v| v.0);
}

fn pct4x4(c: &mut [i32; 16]) {
    *c = pct4x4_g(c.map(S)).map(|v| v.0);
}

/// `_jxr_4x4OverlapFilter` on a 4×4 window in raster order (a..p).
#[inline(always)]
fn post4x4_g<T: Lane>(x: [T; 16]) -> [T; 16] {
    let mut x = x;
    ap!(&mut x, [0, 3, 12, 15], |v| t2x2h(v, 0));
    ap!(&mut x, [1, 2, 13, 14], |v| t2x2h(v, 0));
    ap!(&mut x, [4, 7, 8, 11], |v| t2x2h(v, 0));
    ap!(&mut x, [5, 6, 9, 10], |v| t2x2h(v, 0));
    ap!(&mut x, [13, 12], inv_rotate);
    ap!(&mut x, [9, 8], inv_rotate);
    ap!(&mut x, [7, 3], inv_rotate);
    ap!(&mut x, [6, 2], inv_rotate);
    ap!(&mut x, [10, 11, 14, 15], inv_t_odd_odd_post);
    ap!(&mut x, [0, 15], inv_scale);
    ap!(&mut x, [1, 14], inv_scale);
    ap!(&mut x, [4, 11], inv_scale);
    ap!(&mut x, [5, 10], inv_scale);
    ap!(&mut x, [0, 3, 12, 15], t2x2h_post);
    ap!(&mut x, [1, 2, 13, 14], t2x2h_post);
    ap!(&mut x, [4, 7, 8, 11], t2x2h_post);
    ap!(&mut x, [5, 6, 9, 10], t2x2h_post);
    x
}

/// `_jxr_4x4PreFilter`: the inverse of [`post4x4_g`].
#[inline(always)]
fn pre4x4_g<T: Lane>(x: [T; 16]) -> [T; 16] {
    let mut x = x;
    ap!(&mut x, [0, 3, 12, 15], t2x2h_enc);
    ap!(&mut x, [1, 2, 13, 14], t2x2h_enc);
    ap!(&mut x, [4, 7, 8, 11], t2x2h_enc);
    ap!(&mut x, [5, 6, 9, 10], t2x2h_enc);
    ap!(&mut x, [0, 15], fwd_scale);
    ap!(&mut x, [1, 14], fwd_scale);
    ap!(&mut x, [4, 11], fwd_scale);
    ap!(&mut x, [5, 10], fwd_scale);
    ap!(&mut x, [13, 12], fwd_rotate);
    ap!(&mut x, [9, 8], fwd_rotate);
    ap!(&mut x, [7, 3], fwd_rotate);
    ap!(&mut x, [6, 2], fwd_rotate);
    ap!(&mut x, [10, 11, 14, 15], fwd_t_odd_odd_pre);
    ap!(&mut x, [0, 12, 3, 15], |v| t2x2h(v, 0));
    ap!(&mut x, [1, 2, 13, 14], |v| t2x2h(v, 0));
    ap!(&mut x, [4, 7, 8, 11], |v| t2x2h(v, 0));
    ap!(&mut x, [5, 6, 9, 10], |v| t2x2h(v, 0));
    x
}

/// `_jxr_4OverlapFilter`: the 4-point POT across a seam along an edge (and on corners).
#[inline(always)]
fn post4_g<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    [a, d] = inv_scale([a, d]);
    [b, c] = inv_scale([b, c]);
    a += (d * 3 + 4) >> 3;
    b += (c * 3 + 4) >> 3;
    d -= a >> 1;
    c -= b >> 1;
    a += d;
    b += c;
    d = -d;
    c = -c;
    [c, d] = inv_rotate([c, d]);
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d;
    b -= c;
    [a, b, c, d]
}

/// `_jxr_4PreFilter`: the inverse of [`post4_g`].
#[inline(always)]
fn pre4_g<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    [c, d] = fwd_rotate([c, d]);
    d = -d;
    c = -c;
    a -= d;
    b -= c;
    d += a >> 1;
    c += b >> 1;
    a -= (d * 3 + 4) >> 3;
    b -= (c * 3 + 4) >> 3;
    [a, d] = fwd_scale([a, d]);
    [b, c] = fwd_scale([b, c]);
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d;
    b -= c;
    [a, b, c, d]
}

/// `_jxr_2x2OverlapFilter`: the chroma DC-domain POT on a 2×2 window.
#[inline(always)]
fn post2x2_g<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    b += (a + 2) >> 2;
    a += (b + 1) >> 1;
    a += b >> 5;
    a += b >> 9;
    a += b >> 13;
    b += (a + 2) >> 2;
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d;
    b -= c;
    [a, b, c, d]
}

/// `_jxr_2x2PreFilter`: the inverse of [`post2x2_g`].
#[inline(always)]
fn pre2x2_g<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    b -= (a + 2) >> 2;
    a -= b >> 5;
    a -= b >> 9;
    a -= b >> 13;
    a -= (b + 1) >> 1;
    b -= (a + 2) >> 2;
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d;
    b -= c;
    [a, b, c, d]
}

/// `_jxr_2OverlapFilter`: the chroma DC-domain POT across a seam along an edge.
#[inline(always)]
fn post2_g<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    b += (a + 2) >> 2;
    a += (b + 1) >> 1;
    a += b >> 5;
    a += b >> 9;
    a += b >> 13;
    b += (a + 2) >> 2;
    [a, b]
}

/// `_jxr_2PreFilter`: the inverse of [`post2_g`].
#[inline(always)]
fn pre2_g<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    b -= (a + 2) >> 2;
    a -= b >> 13;
    a -= b >> 9;
    a -= b >> 5;
    a -= (b + 1) >> 1;
    b -= (a + 2) >> 2;
    [a, b]
}

/// Applies the one-sample operator `f` to the samples of `p` at indices `i`.
#[inline(always)]
fn on<const N: usize>(p: &mut [i32], i: [usize; N], f: impl Fn([S; N]) -> [S; N]) {
    let v = load(p, i);
    store(p, i, f(v));
}

#[inline(always)]
fn post4(p: &mut [i32], i: [usize; 4]) {
    on(p, i, post4_g);
}
#[inline(always)]
fn pre4(p: &mut [i32], i: [usize; 4]) {
    on(p, i, pre4_g);
}
#[inline(always)]
fn post2x2(p: &mut [i32], i: [usize; 4]) {
    on(p, i, post2x2_g);
}
#[inline(always)]
fn pre2x2(p: &mut [i32], i: [usize; 4]) {
    on(p, i, pre2x2_g);
}
#[inline(always)]
fn post2(p: &mut [i32], i: [usize; 2]) {
    on(p, i, post2_g);
}
#[inline(always)]
fn pre2(p: &mut [i32], i: [usize; 2]) {
    on(p, i, pre2_g);
}

// ---------------------------------------------------------------------------------------------
// The POT pattern on a plane.

/// A rectangle of a plane, in samples: `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

/// The regions filtered independently: the whole plane, or each hard tile. `unit_x` and
/// `unit_y` are samples per macroblock in this plane.
fn regions(hard: Option<&HardEdges>, mb_w: usize, mb_h: usize, unit_x: usize, unit_y: usize) -> Vec<Rect> {
    let cuts = |edges: Option<&Vec<usize>>, n: usize| -> Vec<usize> {
        let mut v: Vec<usize> = edges.map_or(Vec::new(), |e| e.iter().copied().filter(|&c| c > 0 && c < n).collect());
        v.push(0);
        v.push(n);
        v.sort_unstable();
        v.dedup();
        v
    };
    let cols = cuts(hard.map(|h| &h.columns), mb_w);
    let rows = cuts(hard.map(|h| &h.rows), mb_h);
    let mut out = Vec::with_capacity((cols.len() - 1) * (rows.len() - 1));
    for r in rows.windows(2) {
        for c in cols.windows(2) {
            out.push(Rect { x0: c[0] * unit_x, x1: c[1] * unit_x, y0: r[0] * unit_y, y1: r[1] * unit_y });
        }
    }
    out
}

/// Which direction the POT runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dir {
    Inverse,
    Forward,
}

/// The row length of a coefficient-major scratch for `count` windows or blocks: whole lane
/// groups, plus one spare group so that a power-of-two image width does not make the 16 rows
/// map onto the same cache sets.
fn scratch_stride(count: usize) -> usize {
    count.next_multiple_of(LANES) + LANES
}

/// Runs `$f` on the first `$count` columns of `$cm`, a coefficient-major scratch of 16 rows
/// of `$n` values ([`scratch_stride`]): row `k` holds input `k` of every window or block. The
/// gather into `cm` and the scatter out of it are separate passes, so the vector loads here
/// never wait on the scalar stores that filled them. A macro rather than a function taking
/// `impl Fn`, so that `$f` is a direct call, inlined into the AVX2 twins with everything else.
macro_rules! run_lanes {
    ($cm:expr, $n:expr, $count:expr, $f:path) => {{
        let (cm, n, count): (&mut [i32], usize, usize) = ($cm, $n, $count);
        for x in (0..count).step_by(LANES) {
            let mut v = [V([0; LANES]); 16];
            for (k, lane) in v.iter_mut().enumerate() {
                lane.0.copy_from_slice(&cm[k * n + x..k * n + x + LANES]);
            }
            for (k, r) in $f(v).into_iter().enumerate() {
                cm[k * n + x..k * n + x + LANES].copy_from_slice(&r.0);
            }
        }
    }};
}

/// Rows `y_base..` of a plane: `data[(y - y_base) * stride + x]` is sample `(x, y)`.
struct Rows<'a> {
    data: &'a mut [i32],
    stride: usize,
    y_base: usize,
}

impl Rows<'_> {
    #[inline(always)]
    fn at(&self, x: usize, y: usize) -> usize {
        (y - self.y_base) * self.stride + x
    }
}

/// The pitch-4 POT pattern (4×4 interior windows, 4-point edge seams, 2×2 corners) on `r`,
/// limited to the operations keyed by a row in `keys`: a seam's operations by the seam's row,
/// the top edge's and top corners' by `r.y0`, the bottom's by `r.y1`. Operations with
/// different keys touch different samples, so any split of the keys gives the same result.
fn pot4_region(p: &mut Rows, r: Rect, keys: &RangeInclusive<usize>, dir: Dir, cm: &mut Vec<i32>) {
    let f4 = |p: &mut Rows, i: [usize; 4]| if dir == Dir::Inverse { post4(p.data, i) } else { pre4(p.data, i) };
    // Interior seams: rows r.y0 + 4, r.y0 + 8, … below r.y1 (regions start on a multiple
    // of 4), those in `keys`.
    debug_assert_eq!(r.y0 % 4, 0);
    let first = (r.y0 + 4).max(keys.start().next_multiple_of(4));
    let last = (r.y1 - 1).min(*keys.end());
    for y in (first..=last).step_by(4) {
        // Interior windows (LANES at once), and the seams along the left and right edges.
        pot4_interior_row(p, r, y, dir, cm);
        for x in [r.x0, r.x0 + 1, r.x1 - 2, r.x1 - 1] {
            f4(p, [p.at(x, y - 2), p.at(x, y - 1), p.at(x, y), p.at(x, y + 1)]);
        }
    }
    for (key, rows) in [(r.y0, [r.y0, r.y0 + 1]), (r.y1, [r.y1 - 2, r.y1 - 1])] {
        if !keys.contains(&key) {
            continue;
        }
        // The seams along the top (bottom) edge, two rows, and the two corners.
        for y in rows {
            for x in (r.x0 + 4..r.x1).step_by(4) {
                f4(p, [p.at(x - 2, y), p.at(x - 1, y), p.at(x, y), p.at(x + 1, y)]);
            }
        }
        let y = rows[0];
        for x in [r.x0, r.x1 - 2] {
            f4(p, [p.at(x, y), p.at(x + 1, y), p.at(x, y + 1), p.at(x + 1, y + 1)]);
        }
    }
}

/// The 4×4 windows centred on `(x, y)` for `x = r.x0 + 4, r.x0 + 8, … < r.x1`: gathered into
/// a coefficient-major scratch, filtered [`LANES`] at a time, scattered back.
#[allow(unsafe_code)]
fn pot4_interior_row(p: &mut Rows, r: Rect, y: usize, dir: Dir, cm: &mut Vec<i32>) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx512() {
        // SAFETY: `cpu::avx512()` is true only when the CPU has AVX-512F and AVX2.
        return unsafe { avx512::pot4_interior_row(p, r, y, dir, cm) };
    }
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
        return unsafe { pot4_interior_row_avx2(p, r, y, dir, cm) };
    }
    pot4_interior_row_portable(p, r, y, dir, cm)
}

/// [`pot4_interior_row_portable`] with AVX2 intrinsics (the `avx2` module's).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn pot4_interior_row_avx2(p: &mut Rows, r: Rect, y: usize, dir: Dir, cm: &mut Vec<i32>) {
    // SAFETY: the caller guarantees AVX2.
    unsafe { avx2::pot4_interior_row(p, r, y, dir, cm) }
}

#[inline(always)]
fn pot4_interior_row_portable(p: &mut Rows, r: Rect, y: usize, dir: Dir, cm: &mut Vec<i32>) {
    let count = ((r.x1 - r.x0) / 4).saturating_sub(1);
    if count == 0 {
        return;
    }
    let n = scratch_stride(count);
    cm.resize(16 * n, 0);
    let top = p.at(r.x0 + 2, y - 2);
    let stride = p.stride;
    // Scratch row 4j + i holds sample i of row j of every window.
    for (j, quad) in cm.chunks_exact_mut(4 * n).enumerate() {
        let [a, b, c, d] = four_rows(quad, n, count);
        deinterleave4(&p.data[top + j * stride..][..4 * count], [a, b, c, d]);
    }
    match dir {
        Dir::Inverse => run_lanes!(cm, n, count, post4x4_g),
        Dir::Forward => run_lanes!(cm, n, count, pre4x4_g),
    }
    for (j, quad) in cm.chunks_exact(4 * n).enumerate() {
        let rows: [&[i32]; 4] = std::array::from_fn(|i| &quad[i * n..][..count]);
        interleave4(rows, &mut p.data[top + j * stride..][..4 * count]);
    }
}

/// The first `count` values of each of the four rows of `n` in `quad`.
#[inline(always)]
fn four_rows(quad: &mut [i32], n: usize, count: usize) -> [&mut [i32]; 4] {
    let mut rows = quad.chunks_exact_mut(n).map(|r| &mut r[..count]);
    std::array::from_fn(|_| rows.next().unwrap_or_default())
}

/// The transpose of a 4×4 matrix in raster order: `out[4i + j] = m[4j + i]`. On x86-64 with
/// SSE2's unpack instructions (part of the architecture's baseline, so in the portable code
/// too): the compiler made the index-by-index version sixteen scalar loads and stores, which
/// cost the stage-1 gathers and scatters more than the transform's arithmetic.
#[inline(always)]
#[allow(unsafe_code)]
fn transpose4x4(m: &[i32; 16]) -> [i32; 16] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            __m128i, _mm_loadu_si128, _mm_storeu_si128, _mm_unpackhi_epi32, _mm_unpackhi_epi64, _mm_unpacklo_epi32,
            _mm_unpacklo_epi64,
        };
        let mut out = [0i32; 16];
        // SAFETY: SSE2 is part of x86-64; each load and store is of 4 values of the 16 of
        // `m` or `out` (unaligned accesses).
        unsafe {
            let row = |i: usize| _mm_loadu_si128(m.as_ptr().add(4 * i).cast::<__m128i>());
            let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
            let (t0, t1) = (_mm_unpacklo_epi32(r0, r1), _mm_unpacklo_epi32(r2, r3));
            let (t2, t3) = (_mm_unpackhi_epi32(r0, r1), _mm_unpackhi_epi32(r2, r3));
            let p = out.as_mut_ptr().cast::<__m128i>();
            _mm_storeu_si128(p, _mm_unpacklo_epi64(t0, t1));
            _mm_storeu_si128(p.add(1), _mm_unpackhi_epi64(t0, t1));
            _mm_storeu_si128(p.add(2), _mm_unpacklo_epi64(t2, t3));
            _mm_storeu_si128(p.add(3), _mm_unpackhi_epi64(t2, t3));
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    transpose4x4_scalar(m)
}

/// [`transpose4x4`] index by index (its twin on other architectures, and its test's reference).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn transpose4x4_scalar(m: &[i32; 16]) -> [i32; 16] {
    std::array::from_fn(|k| m[4 * (k % 4) + k / 4])
}

/// `dst[i][w] = src[4w + i]`: four interleaved streams split, four pixels (a 4×4 transpose,
/// which the compiler turns into vector shuffles) at a time.
#[inline(always)]
fn deinterleave4(src: &[i32], dst: [&mut [i32]; 4]) {
    let [d0, d1, d2, d3] = dst;
    let count = d0.len().min(d1.len()).min(d2.len()).min(d3.len()).min(src.len() / 4);
    let whole = count / 4 * 4;
    let dsts = d0[..whole].chunks_exact_mut(4).zip(d1[..whole].chunks_exact_mut(4));
    let dsts = dsts.zip(d2[..whole].chunks_exact_mut(4).zip(d3[..whole].chunks_exact_mut(4)));
    for (s, ((a, b), (c, d))) in src.chunks_exact(16).zip(dsts) {
        let t = transpose4x4(s.try_into().expect("16 values"));
        a.copy_from_slice(&t[0..4]);
        b.copy_from_slice(&t[4..8]);
        c.copy_from_slice(&t[8..12]);
        d.copy_from_slice(&t[12..16]);
    }
    for w in whole..count {
        d0[w] = src[4 * w];
        d1[w] = src[4 * w + 1];
        d2[w] = src[4 * w + 2];
        d3[w] = src[4 * w + 3];
    }
}

/// `dst[4w + i] = src[i][w]`: the inverse of [`deinterleave4`].
#[inline(always)]
fn interleave4(src: [&[i32]; 4], dst: &mut [i32]) {
    let [s0, s1, s2, s3] = src;
    let count = s0.len().min(s1.len()).min(s2.len()).min(s3.len()).min(dst.len() / 4);
    let whole = count / 4 * 4;
    let srcs = s0[..whole].chunks_exact(4).zip(s1[..whole].chunks_exact(4));
    let srcs = srcs.zip(s2[..whole].chunks_exact(4).zip(s3[..whole].chunks_exact(4)));
    for (d, ((a, b), (c, e))) in dst.chunks_exact_mut(16).zip(srcs) {
        let mut m = [0i32; 16];
        m[0..4].copy_from_slice(a);
        m[4..8].copy_from_slice(b);
        m[8..12].copy_from_slice(c);
        m[12..16].copy_from_slice(e);
        d.copy_from_slice(&transpose4x4(&m));
    }
    for w in whole..count {
        dst[4 * w..4 * w + 4].copy_from_slice(&[s0[w], s1[w], s2[w], s3[w]]);
    }
}

/// The pitch-2 POT of 4:2:0 and 4:2:2 chroma DC planes on `r` (T.835
/// `overlap_level1_up2_420/422`): 2×2 windows at interior grid corners, 2-point seams along
/// the outermost rows and columns, and corners kept as differences from their neighbour
/// while the filters run (jxrlib `COMPUTE_CORNER_PRED_DIFF/ADD`). Keys as in [`pot4_region`].
fn pot2_region(p: &mut Rows, r: Rect, keys: &RangeInclusive<usize>, dir: Dir) {
    let (top, bottom) = (keys.contains(&r.y0), keys.contains(&r.y1));
    // Corner, neighbour; in T.835's order (top-left, top-right, bottom-left, bottom-right).
    let mut corners = Vec::with_capacity(4);
    if top {
        corners.push((p.at(r.x0, r.y0), p.at(r.x0 + 1, r.y0)));
        corners.push((p.at(r.x1 - 1, r.y0), p.at(r.x1 - 2, r.y0)));
    }
    if bottom {
        corners.push((p.at(r.x0, r.y1 - 1), p.at(r.x0 + 1, r.y1 - 1)));
        corners.push((p.at(r.x1 - 1, r.y1 - 1), p.at(r.x1 - 2, r.y1 - 1)));
    }
    if dir == Dir::Forward {
        corners.reverse();
    }
    for &(c, n) in &corners {
        p.data[c] = p.data[c].wrapping_sub(p.data[n]);
    }
    let f2 = |p: &mut Rows, i: [usize; 2]| if dir == Dir::Inverse { post2(p.data, i) } else { pre2(p.data, i) };
    let f4 = |p: &mut Rows, i: [usize; 4]| if dir == Dir::Inverse { post2x2(p.data, i) } else { pre2x2(p.data, i) };
    for y in (r.y0 + 2..r.y1).step_by(2).filter(|y| keys.contains(y)) {
        for x in (r.x0 + 2..r.x1).step_by(2) {
            f4(p, [p.at(x - 1, y - 1), p.at(x, y - 1), p.at(x - 1, y), p.at(x, y)]);
        }
        for x in [r.x0, r.x1 - 1] {
            f2(p, [p.at(x, y - 1), p.at(x, y)]);
        }
    }
    for (key, y) in [(top, r.y0), (bottom, r.y1 - 1)] {
        if key {
            for x in (r.x0 + 2..r.x1).step_by(2) {
                f2(p, [p.at(x - 1, y), p.at(x, y)]);
            }
        }
    }
    for &(c, n) in &corners {
        p.data[c] = p.data[c].wrapping_add(p.data[n]);
    }
}

// ---------------------------------------------------------------------------------------------
// Stage 2: DC and LP of a macroblock to (or from) its block DCs.

/// The stage-2 inverse PCT of one macroblock: `c` (DC, LP...) to the block DCs in raster order
/// of the macroblock's blocks (16, 4 or 8 values in `out`).
#[inline(always)]
fn stage2_inverse(kind: PlaneKind, double: bool, c: &MbCoeffs, out: &mut [i32; 16]) {
    let n = match kind {
        PlaneKind::Full => {
            out.copy_from_slice(&c[DC..=lp(15)]);
            ipct4x4(out);
            16
        }
        PlaneKind::Chroma420 => {
            out[..4].copy_from_slice(&c[DC..=lp(3)]);
            on(out, [0, 1, 2, 3], |v| t2x2h(v, 0));
            out.swap(1, 2);
            4
        }
        PlaneKind::Chroma422 => {
            out[..8].copy_from_slice(&c[DC..=lp(7)]);
            // _jxr_2ptT on DC and LP4, then two 2×2 transforms.
            on(out, [0, 4], |[mut a, mut b]| {
                a -= (b + 1) >> 1;
                b += a;
                [a, b]
            });
            on(out, [0, 1, 2, 3], |v| t2x2h(v, 0));
            on(out, [4, 5, 6, 7], |v| t2x2h(v, 0));
            out.swap(1, 2);
            out.swap(5, 6);
            8
        }
    };
    if double {
        for v in &mut out[..n] {
            *v = v.wrapping_mul(2);
        }
    }
}

/// The stage-2 forward PCT: block DCs (raster order) to DC and LP in `c`.
fn stage2_forward(kind: PlaneKind, double: bool, dcs: &[i32; 16], c: &mut MbCoeffs) {
    let mut v = *dcs;
    let n = match kind {
        PlaneKind::Full => 16,
        PlaneKind::Chroma420 => 4,
        PlaneKind::Chroma422 => 8,
    };
    if double {
        for x in &mut v[..n] {
            *x >>= 1;
        }
    }
    match kind {
        PlaneKind::Full => pct4x4(&mut v),
        PlaneKind::Chroma420 => {
            v.swap(1, 2);
            on(&mut v, [0, 1, 2, 3], |x| t2x2h(x, 0));
        }
        PlaneKind::Chroma422 => {
            v.swap(1, 2);
            v.swap(5, 6);
            on(&mut v, [0, 1, 2, 3], |x| t2x2h(x, 0));
            on(&mut v, [4, 5, 6, 7], |x| t2x2h(x, 0));
            // _jxr_2ptFwdT.
            on(&mut v, [0, 4], |[mut a, mut b]| {
                b -= a;
                a += (b + 1) >> 1;
                [a, b]
            });
        }
    }
    c[DC..DC + n].copy_from_slice(&v[..n]);
}

// ---------------------------------------------------------------------------------------------
// Whole planes.

/// Macroblock rows per band in [`inverse_plane`] (the band's halo is recomputed, so longer
/// bands cost less extra work; 8 rows of a 4096-wide image keep a band's buffers in L2).
pub const BAND_MB_ROWS: usize = 8;

/// The size of a channel's plane, after checking the grid.
fn plane_size(kind: PlaneKind, mb_w: usize, mb_h: usize) -> Result<(usize, usize)> {
    if mb_w == 0 || mb_h == 0 {
        return Err(Error::invalid("an image of no macroblocks"));
    }
    let (bx, by) = kind.blocks();
    let w = mb_w.checked_mul(bx * 4).ok_or_else(|| Error::limit("plane width overflows"))?;
    let h = mb_h.checked_mul(by * 4).ok_or_else(|| Error::limit("plane height overflows"))?;
    w.checked_mul(h).ok_or_else(|| Error::limit("plane size overflows"))?;
    Ok((w, h))
}

/// The inverse lapped transform of the macroblock rows `rows` of one channel, written to
/// `out`: the plane rows `rows.start · H .. rows.end · H` (H = 16, or 8 for 4:2:0 chroma),
/// row-major, `W` samples each (`W` = 16·`mb_w`, or 8·`mb_w` for 4:2:0 and 4:2:2 chroma).
///
/// `coeffs` holds consecutive macroblock rows starting at row `coeffs_first_row`, `mb_w`
/// macroblocks each in raster order, each dequantized and predicted in the `mb.rs`
/// layout: `[0]` DC, `[1..16]` LP 1..15 (4:2:0 chroma: LP 1..3; 4:2:2 chroma: LP 1..7),
/// `[16 + 15·b + k − 1]` HP `k` of block `b`, blocks numbered in raster order inside the
/// macroblock (`b = 4·y + x` for full planes, `2·y + x` for 4:2:0 and 4:2:2 chroma). They
/// must cover the band and its halo: rows `rows.start − 2 .. rows.end + 2` (clipped to the
/// image). `channel` is the channel's index: channels after the first are doubled after stage
/// 2 in scaled arithmetic.
///
/// Bands are independent: a decoder can run them in any order or in parallel, and start a
/// band as soon as the macroblock rows of its halo are decoded. With
/// [`OperatorSet::HdPhoto`], the legacy operators run instead, on the same layouts and halo
/// (a window or block at a time; hard tiles are an error there).
#[allow(clippy::too_many_arguments)]
pub fn inverse_band(
    params: &TransformParams,
    kind: PlaneKind,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
    coeffs: &[MbCoeffs],
    coeffs_first_row: usize,
    rows: Range<usize>,
    out: &mut [i32],
) -> Result<()> {
    if mb_w == 0 || !coeffs.len().is_multiple_of(mb_w) {
        return Err(Error::invalid(format!("{} macroblocks given in rows of {mb_w}", coeffs.len())));
    }
    let row_slices: Vec<&[i32]> = coeffs.chunks_exact(mb_w).map(|r| r.as_flattened()).collect();
    let source = MbRows::new(&row_slices, coeffs_first_row, MB_COEFFS, 0);
    let mut scratch = BandScratch::default();
    let request = BandRequest { params, kind, channel, mb_w, mb_h, coeffs: &source, rows };
    let start = inverse_band_rows(&request, &mut scratch)?;
    let (bx, by) = kind.blocks();
    let band = &scratch.data[start..][..4 * bx * mb_w * 4 * by * request.rows.len()];
    out.get_mut(..band.len()).ok_or_else(|| Error::invalid("band output buffer too small"))?.copy_from_slice(band);
    Ok(())
}

/// Consecutive macroblock rows of one channel's coefficients, each row a slice of its own:
/// macroblock `mx` of a row at `mx · stride + offset` ([`MB_COEFFS`] values in the `mb.rs`
/// layout). The entropy decoder's rows hold every channel of a macroblock together (stride
/// `channels · MB_COEFFS`, offset `channel · MB_COEFFS`); the transform reads them in place.
#[derive(Clone, Copy, Debug)]
pub struct MbRows<'a> {
    rows: &'a [&'a [i32]],
    first: usize,
    stride: usize,
    offset: usize,
}

impl<'a> MbRows<'a> {
    /// Rows `first_row ..` of the image: `rows[i]` is macroblock row `first_row + i`.
    pub fn new(rows: &'a [&'a [i32]], first_row: usize, stride: usize, offset: usize) -> Self {
        MbRows { rows, first: first_row, stride, offset }
    }

    /// True when rows `need` are present, each with `mb_w` macroblocks.
    fn covers(&self, need: &Range<usize>, mb_w: usize) -> bool {
        let len = (mb_w.saturating_sub(1)).saturating_mul(self.stride).saturating_add(self.offset + MB_COEFFS);
        need.start >= self.first
            && need.end <= self.first + self.rows.len()
            && self.rows[need.start - self.first..need.end - self.first].iter().all(|r| r.len() >= len)
    }

    /// Macroblock (`mx`, `my`), which [`covers`](Self::covers) checked is there.
    #[inline(always)]
    fn mb(&self, mx: usize, my: usize) -> &'a MbCoeffs {
        let row: &'a [i32] = self.rows[my - self.first];
        row[mx * self.stride + self.offset..][..MB_COEFFS].try_into().expect("a checked macroblock")
    }
}

/// The working buffers of a band's inverse transform, kept from band to band (fresh buffers
/// of this size cost page faults and zeroing each time). After
/// [`inverse_band_rows`], `data` holds the band's samples.
#[derive(Clone, Debug, Default)]
pub struct BandScratch {
    dc: Vec<i32>,
    cm: Vec<i32>,
    /// The band's samples, with a halo of a block row above and below (and past them,
    /// whatever a longer band left there: the buffer only grows, so that a band does not
    /// zero what the band before it truncated).
    pub data: Vec<i32>,
}

/// Makes `buf` at least `len` long. Bands overwrite every sample they read, so the values a
/// reused buffer holds do not matter; only a first use (or a longer band) zero-fills.
pub(super) fn grow(buf: &mut Vec<i32>, len: usize) {
    if buf.len() < len {
        buf.resize(len, 0);
    }
}

/// One band of one channel to inverse-transform: what [`inverse_band_rows`] needs besides
/// its buffers (the arguments of [`inverse_band`], with the coefficients in rows).
#[derive(Clone, Debug)]
pub struct BandRequest<'a> {
    /// The transform's parameters.
    pub params: &'a TransformParams,
    /// The channel's sampling.
    pub kind: PlaneKind,
    /// The channel's index (channels after the first are doubled in scaled arithmetic).
    pub channel: usize,
    /// Macroblocks across.
    pub mb_w: usize,
    /// Macroblocks down.
    pub mb_h: usize,
    /// The coefficients: rows `rows.start − 2 .. rows.end + 2` (clipped to the image).
    pub coeffs: &'a MbRows<'a>,
    /// The macroblock rows of the band.
    pub rows: Range<usize>,
}

/// [`inverse_band`] over coefficients in rows of their own, into `scratch`: returns where
/// in `scratch.data` the band's first sample is (its rows follow, `W` samples each).
///
/// On x86-64 with AVX2 (as [`hdrcodec_core::cpu`] allows) this runs the same code compiled
/// for AVX2, where the lanes of eight blocks or windows are one register; the results are
/// the same (`avx2_twin_matches_the_portable_transform`).
#[allow(unsafe_code)]
pub fn inverse_band_rows(request: &BandRequest, scratch: &mut BandScratch) -> Result<usize> {
    if let OperatorSet::HdPhoto(leak) = &request.params.operators {
        return hd_photo_band(request, leak, scratch);
    }
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2 (detected once;
        // `HDRCODEC_CPU` can only lower the level), the one feature the twin is compiled for.
        return unsafe { inverse_band_rows_avx2(request, scratch) };
    }
    inverse_band_rows_portable(request, scratch)
}

/// What [`stage2_band`] found: the plane's width and the first macroblock row of `dc`.
pub(super) struct StageTwo {
    pub width: usize,
    pub s0: usize,
}

/// The steps every band transform shares (both operator sets, and the 1/4 resolution
/// path): checks `request`, then runs stage 2 (the PCT of each
/// macroblock's DC and LP) for the macroblock rows of the band and its halo,
/// `halo` macroblock rows each side (clipped; the first is `s0`), into `dc`: `by` rows of block DCs per
/// macroblock row, `bx · mb_w` wide. Every value of `dc` is written, so a reused buffer needs
/// no clearing.
#[inline(always)]
pub(super) fn stage2_band(request: &BandRequest, halo: usize, dc: &mut Vec<i32>) -> Result<StageTwo> {
    stage2_band_with::<false>(request, halo, dc)
}

/// [`stage2_band`]; with `AVX2` (only in [`inverse_band_rows_avx2`]) full planes run eight
/// macroblocks at a time in the `avx2` module.
#[inline(always)]
#[allow(unsafe_code)]
fn stage2_band_with<const AVX2: bool>(request: &BandRequest, halo: usize, dc: &mut Vec<i32>) -> Result<StageTwo> {
    let BandRequest { params, kind, channel, mb_w, mb_h, coeffs, ref rows } = *request;
    let (width, _) = plane_size(kind, mb_w, mb_h)?;
    let (bx, by) = kind.blocks();
    let (r0, r1) = (rows.start, rows.end);
    if r0 >= r1 || r1 > mb_h {
        return Err(Error::invalid(format!("macroblock rows {r0}..{r1} of an image of {mb_h}")));
    }
    let (s0, s1) = (r0.saturating_sub(halo), (r1 + halo).min(mb_h));
    if !coeffs.covers(&(s0..s1), mb_w) {
        return Err(Error::invalid(format!(
            "coefficients of macroblock rows {}..{} given, {s0}..{s1} needed",
            coeffs.first,
            coeffs.first + coeffs.rows.len()
        )));
    }
    let double = params.scaled && channel > 0;
    let dw = bx * mb_w;
    grow(dc, dw * by * (s1 - s0));
    let mut v = [0i32; 16];
    for my in s0..s1 {
        let mut done = 0;
        #[cfg(target_arch = "x86_64")]
        if AVX2 && kind == PlaneKind::Full {
            let rows = &mut dc[(my - s0) * 4 * dw..][..4 * dw];
            let mut rows = rows.chunks_exact_mut(dw);
            let rows: [&mut [i32]; 4] = std::array::from_fn(|_| rows.next().unwrap_or_default());
            // SAFETY: `AVX2` is true only in `inverse_band_rows_avx2`, which runs only when
            // the CPU has AVX2.
            done = unsafe { avx2::stage2_full_row(coeffs, my, mb_w, double, rows) };
        }
        for mx in done..mb_w {
            stage2_inverse(kind, double, coeffs.mb(mx, my), &mut v);
            for j in 0..by {
                let row = ((my - s0) * by + j) * dw + mx * bx;
                dc[row..row + bx].copy_from_slice(&v[j * bx..(j + 1) * bx]);
            }
        }
    }
    Ok(StageTwo { width, s0 })
}

/// A band with the HD Photo operators ([`OperatorSet::HdPhoto`]): the legacy module's
/// transform (not tuned: HD Photo files are rare).
fn hd_photo_band(request: &BandRequest, leak: &DcLeakage, scratch: &mut BandScratch) -> Result<usize> {
    if request.params.hard.is_some() {
        return Err(Error::invalid("hard tiles with HD Photo operators (jxrlib has none)"));
    }
    legacy::inverse_band(request, leak, scratch)
}

/// [`inverse_band_rows_portable`] compiled for AVX2 (everything it calls is inlined into it).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn inverse_band_rows_avx2(request: &BandRequest, scratch: &mut BandScratch) -> Result<usize> {
    inverse_band_rows_body::<true>(request, scratch)
}

/// The portable body of [`inverse_band_rows`].
fn inverse_band_rows_portable(request: &BandRequest, scratch: &mut BandScratch) -> Result<usize> {
    inverse_band_rows_body::<false>(request, scratch)
}

/// The body of [`inverse_band_rows`]; with `AVX2` (only in [`inverse_band_rows_avx2`]) the
/// stage-1 PCT of full planes runs the `avx2` module's intrinsics.
#[inline(always)]
#[allow(unsafe_code)]
fn inverse_band_rows_body<const AVX2: bool>(request: &BandRequest, scratch: &mut BandScratch) -> Result<usize> {
    let BandRequest { params, kind, mb_w, mb_h, coeffs, ref rows, .. } = *request;
    let BandScratch { dc, cm, data } = scratch;
    let StageTwo { width, s0 } = stage2_band_with::<AVX2>(request, 2, dc)?;
    let mb = |mx: usize, my: usize| coeffs.mb(mx, my);
    let (bx, by) = kind.blocks();
    let (r0, r1) = (rows.start, rows.end);
    let dw = bx * mb_w;
    // The stage-2 POT makes the DCs of macroblock rows r0 − 1 ..= r1 final.
    if params.overlap == OverlapMode::Two {
        let keys = by * r0.saturating_sub(1)..=by * (r1 + 1).min(mb_h);
        let mut p = Rows { data: dc, stride: dw, y_base: by * s0 };
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx, by) {
            match kind {
                PlaneKind::Full => pot4_region(&mut p, r, &keys, Dir::Inverse, cm),
                _ => pot2_region(&mut p, r, &keys, Dir::Inverse),
            }
        }
    }

    // Stage 1 for block rows b0..b1 (the band and one block row of halo each side): each
    // block row gathered coefficient-major, transformed LANES blocks at a time, scattered.
    // Every sample of `data` is written, so a reused buffer needs no clearing; the scratch's
    // padding lanes hold whatever they held (the arithmetic wraps, and they are not read).
    // The POT of the seams between block rows y − 1 and y follows the PCT of row y, while
    // those rows are still in cache: every POT operation touches samples no other one does,
    // so it only has to come after the PCT of the blocks it reads.
    let (b0, b1) = ((by * r0).saturating_sub(1), (by * r1 + 1).min(by * mb_h));
    grow(data, width * 4 * (b1 - b0));
    let n = scratch_stride(dw);
    let unit = 4 * by;
    let pot = if params.overlap == OverlapMode::None {
        Vec::new()
    } else {
        regions(params.hard.as_ref(), mb_w, mb_h, 4 * bx, unit)
    };
    // The seams from the band's top row to its bottom row are this band's.
    let band_keys = unit * r0..=unit * r1;
    let pot_seams = |data: &mut Vec<i32>, cm: &mut Vec<i32>, key: usize| {
        if band_keys.contains(&key) {
            let mut p = Rows { data, stride: width, y_base: 4 * b0 };
            for &r in &pot {
                pot4_region(&mut p, r, &(key..=key), Dir::Inverse, cm);
            }
        }
    };
    for y in b0..b1 {
        let (my, jy) = (y / by, y % by);
        #[cfg(target_arch = "x86_64")]
        if AVX2 && bx == 4 {
            let rows = &mut data[(y - b0) * 4 * width..][..4 * width];
            let mut rows = rows.chunks_exact_mut(width);
            let rows: [&mut [i32]; 4] = std::array::from_fn(|_| rows.next().unwrap_or_default());
            let dc_row = &dc[(y - by * s0) * dw..][..dw];
            // SAFETY: `AVX2` is true only in `inverse_band_rows_avx2`, which runs only when
            // the CPU has AVX2.
            unsafe { avx2::stage1_full_row(dc_row, coeffs, my, jy, mb_w, rows) };
            pot_seams(data, cm, 4 * y);
            continue;
        }
        cm.resize(16 * n, 0);
        {
            // The 16 rows of the scratch, each cut to the block row's width, so that the
            // loops below index them without bounds checks.
            let mut rows = cm.chunks_exact_mut(n).map(|r| &mut r[..dw]);
            let mut rows: [&mut [i32]; 16] = std::array::from_fn(|_| rows.next().unwrap_or_default());
            rows[0].copy_from_slice(&dc[(y - by * s0) * dw..][..dw]);
            if bx == 4 {
                // Full planes: a macroblock's four blocks of the block row are 60 consecutive
                // coefficients, transposed into four consecutive columns of each row.
                // A 4×15 transpose, as 4×4 ones: coefficients k0 .. k0 + 4 of the four blocks
                // (the last group overlaps the one before, k 11..15, rather than read past).
                for mx in 0..mb_w {
                    let quad: &[i32; 60] = mb(mx, my)[hp(4 * jy, 1)..][..60].try_into().expect("four blocks");
                    for k0 in [0, 4, 8, 11] {
                        let mut m = [0i32; 16];
                        for (b, part) in m.chunks_exact_mut(4).enumerate() {
                            part.copy_from_slice(&quad[15 * b + k0..][..4]);
                        }
                        let t = transpose4x4(&m);
                        for (row, part) in rows[1 + k0..1 + k0 + 4].iter_mut().zip(t.chunks_exact(4)) {
                            row[4 * mx..4 * mx + 4].copy_from_slice(part);
                        }
                    }
                }
            } else {
                for xb in 0..dw {
                    let b = jy * bx + xb % bx;
                    let block: &[i32; 15] =
                        mb(xb / bx, my)[hp(b, 1)..=hp(b, 15)].try_into().expect("a block is 15 coefficients");
                    for (row, &h) in rows[1..].iter_mut().zip(block) {
                        row[xb] = h;
                    }
                }
            }
        }
        run_lanes!(cm, n, dw, ipct4x4_g);
        for (j, quad) in cm.chunks_exact(4 * n).enumerate() {
            let rows: [&[i32]; 4] = std::array::from_fn(|i| &quad[i * n..][..dw]);
            interleave4(rows, &mut data[((y - b0) * 4 + j) * width..][..width]);
        }
        pot_seams(data, cm, 4 * y);
    }
    // The bottom edge of the image (or of a hard tile ending there).
    pot_seams(data, cm, 4 * b1);
    Ok((unit * r0 - 4 * b0) * width)
}

/// The second stage of the inverse transform alone for macroblock rows `rows` of one channel:
/// the stage-2 PCT and (OVERLAP_MODE 2) the stage-2 POT, giving the *DC plane* (one value per
/// 4×4 block: `bx·mb_w` wide, `by` rows per macroblock row, see [`PlaneKind::blocks`]) without
/// running stage 1. This is what jxrlib's 1:4 reduced-resolution decode samples (it skips the
/// first stage for a scale of 4 and more). `coeffs` as for [`inverse_band`], covering rows
/// `rows.start − 1 .. rows.end + 1` (clipped to the image); `out` gets the band's DC rows,
/// row-major.
#[allow(clippy::too_many_arguments)]
pub fn inverse_dc_band(
    params: &TransformParams,
    kind: PlaneKind,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
    coeffs: &[MbCoeffs],
    coeffs_first_row: usize,
    rows: Range<usize>,
    out: &mut [i32],
) -> Result<()> {
    if mb_w == 0 || !coeffs.len().is_multiple_of(mb_w) {
        return Err(Error::invalid(format!("{} macroblocks given in rows of {mb_w}", coeffs.len())));
    }
    let row_slices: Vec<&[i32]> = coeffs.chunks_exact(mb_w).map(|r| r.as_flattened()).collect();
    let source = MbRows::new(&row_slices, coeffs_first_row, MB_COEFFS, 0);
    let request = BandRequest { params, kind, channel, mb_w, mb_h, coeffs: &source, rows: rows.clone() };
    let (bx, by) = kind.blocks();
    let (r0, r1) = (rows.start, rows.end);
    let dw = bx * mb_w;
    // The POT windows on the band's outer seams reach two DC rows (half a macroblock) past
    // them, so one macroblock row of halo each side is enough.
    let mut dc = Vec::new();
    let StageTwo { s0, .. } = stage2_band(&request, 1, &mut dc)?;
    if params.overlap == OverlapMode::Two {
        // The seams from the band's top edge to its bottom edge touch its rows.
        let keys = by * r0..=by * r1;
        let mut p = Rows { data: &mut dc, stride: dw, y_base: by * s0 };
        let mut cm = Vec::new();
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx, by) {
            match kind {
                PlaneKind::Full => pot4_region(&mut p, r, &keys, Dir::Inverse, &mut cm),
                _ => pot2_region(&mut p, r, &keys, Dir::Inverse),
            }
        }
    }
    let band = &dc[(r0 - s0) * by * dw..][..(r1 - r0) * by * dw];
    out.get_mut(..band.len()).ok_or_else(|| Error::invalid("DC band output buffer too small"))?.copy_from_slice(band);
    Ok(())
}

/// The inverse lapped transform of one channel, band by band ([`inverse_band`] over
/// [`BAND_MB_ROWS`] macroblock rows at a time). `coeffs` holds all `mb_w × mb_h` macroblocks.
///
/// Returns the samples before colour conversion: `16·mb_w × 16·mb_h` for full planes,
/// `8·mb_w × 8·mb_h` (4:2:0) or `8·mb_w × 16·mb_h` (4:2:2) for chroma.
pub fn inverse_plane(
    params: &TransformParams,
    kind: PlaneKind,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
    coeffs: &[MbCoeffs],
) -> Result<Plane> {
    let (width, height) = plane_size(kind, mb_w, mb_h)?;
    if coeffs.len() != mb_w * mb_h {
        return Err(Error::invalid(format!("{} macroblocks given for a {mb_w}×{mb_h} grid", coeffs.len())));
    }
    let unit = kind.blocks().1 * 4;
    let mut data = vec![0i32; width * height];
    for r0 in (0..mb_h).step_by(BAND_MB_ROWS) {
        let r1 = (r0 + BAND_MB_ROWS).min(mb_h);
        inverse_band(params, kind, channel, mb_w, mb_h, coeffs, 0, r0..r1, &mut data[r0 * unit * width..])?;
    }
    Ok(Plane { width, height, data })
}

/// The stage-1 forward PCT of a whole plane (`data`, after the stage-1 POT): each 4×4 block's
/// DC into the DC plane `dc` (`bx·mb_w` wide) and its 15 HP coefficients into its macroblock
/// of `coeffs`. Block row by block row: the four sample rows are split coefficient-major into
/// the scratch `cm` (row `k` holds sample `k`, raster order, of every block), transformed
/// [`LANES`] blocks at a time and scattered: the decoder's stage 1 backwards. Compiled twice,
/// portable and for AVX2, chosen at run time.
#[allow(unsafe_code)]
fn forward_stage1(
    kind: PlaneKind,
    mb_w: usize,
    mb_h: usize,
    data: &[i32],
    dc: &mut [i32],
    coeffs: &mut [MbCoeffs],
    cm: &mut Vec<i32>,
) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
        return unsafe { forward_stage1_avx2(kind, mb_w, mb_h, data, dc, coeffs, cm) };
    }
    forward_stage1_portable(kind, mb_w, mb_h, data, dc, coeffs, cm)
}

/// [`forward_stage1_portable`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn forward_stage1_avx2(
    kind: PlaneKind,
    mb_w: usize,
    mb_h: usize,
    data: &[i32],
    dc: &mut [i32],
    coeffs: &mut [MbCoeffs],
    cm: &mut Vec<i32>,
) {
    forward_stage1_portable(kind, mb_w, mb_h, data, dc, coeffs, cm)
}

#[inline(always)]
fn forward_stage1_portable(
    kind: PlaneKind,
    mb_w: usize,
    mb_h: usize,
    data: &[i32],
    dc: &mut [i32],
    coeffs: &mut [MbCoeffs],
    cm: &mut Vec<i32>,
) {
    let (bx, by) = kind.blocks();
    let (dw, dh) = (bx * mb_w, by * mb_h);
    let width = 4 * dw;
    let n = scratch_stride(dw);
    cm.resize(16 * n, 0);
    for y in 0..dh {
        let (my, jy) = (y / by, y % by);
        // Scratch row 4j + i holds sample i of row j of every block.
        for (j, quad) in cm.chunks_exact_mut(4 * n).enumerate() {
            let [a, b, c, d] = four_rows(quad, n, dw);
            deinterleave4(&data[(4 * y + j) * width..][..width], [a, b, c, d]);
        }
        run_lanes!(cm, n, dw, pct4x4_g);
        let mut rows = cm.chunks_exact(n).map(|r| &r[..dw]);
        let rows: [&[i32]; 16] = std::array::from_fn(|_| rows.next().unwrap_or_default());
        dc[y * dw..][..dw].copy_from_slice(rows[0]);
        let mbs = &mut coeffs[my * mb_w..][..mb_w];
        if bx == 4 {
            // Full planes: the macroblock's four blocks of this block row are 60 consecutive
            // coefficients, coefficient k of block i at 15i + k − 1.
            for (mx, mb) in mbs.iter_mut().enumerate() {
                let quad: &mut [i32; 60] = (&mut mb[hp(4 * jy, 1)..][..60]).try_into().expect("four blocks");
                for (k, row) in rows[1..].iter().enumerate() {
                    let v: &[i32; 4] = row[4 * mx..4 * mx + 4].try_into().expect("four blocks");
                    quad[k] = v[0];
                    quad[15 + k] = v[1];
                    quad[30 + k] = v[2];
                    quad[45 + k] = v[3];
                }
            }
        } else {
            for xb in 0..dw {
                let b = jy * bx + xb % bx;
                let block: &mut [i32; 15] =
                    (&mut mbs[xb / bx][hp(b, 1)..=hp(b, 15)]).try_into().expect("a block is 15 coefficients");
                for (h, row) in block.iter_mut().zip(&rows[1..]) {
                    *h = row[xb];
                }
            }
        }
    }
}

/// The forward lapped transform of one channel: the exact inverse of [`inverse_plane`] (same
/// parameters, same layouts). In scaled arithmetic, channels after the first lose the lowest
/// bit of their block DCs (the decoder doubles them), as jxrlib's encoder does.
pub fn forward_plane(
    params: &TransformParams,
    kind: PlaneKind,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
    plane: Plane,
) -> Result<Vec<MbCoeffs>> {
    if params.operators != OperatorSet::JpegXr {
        return Err(Error::unsupported("the forward transform with HD Photo operators"));
    }
    let (width, height) = plane_size(kind, mb_w, mb_h)?;
    let (bx, by) = kind.blocks();
    if plane.width != width || plane.height != height || plane.data.len() != width * height {
        return Err(Error::invalid("plane size does not match the macroblock grid"));
    }
    let double = params.scaled && channel > 0;
    // The plane is the encoder's to overwrite.
    let mut data = plane.data;
    let mut cm = Vec::new();
    forward_overlap1(params, kind, mb_w, mb_h, &mut data, &mut cm);
    let (dw, dh) = (bx * mb_w, by * mb_h);
    let mut dc = vec![0i32; dw * dh];
    let mut coeffs = vec![[0i32; MB_COEFFS]; mb_w * mb_h];
    forward_stage1(kind, mb_w, mb_h, &data, &mut dc, &mut coeffs, &mut cm);
    forward_stage2(params, kind, double, mb_w, mb_h, dc, &mut coeffs, &mut cm);
    Ok(coeffs)
}

/// [`forward_plane`] of a full-resolution plane ([`PlaneKind::Full`]) held in the macroblock
/// array that receives its coefficients: `mbs` flattened is the plane, `16 · mb_w` samples
/// wide and `16 · mb_h` high, and each macroblock row of coefficients takes the place of the
/// 16 sample rows it comes from (which are copied out first). The same coefficients as
/// [`forward_plane`] without a second array the size of the plane, whose fresh pages
/// (page faults, the kernel zeroing them) cost more than the copy.
pub fn forward_plane_in_place(
    params: &TransformParams,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
    mut mbs: Vec<MbCoeffs>,
) -> Result<Vec<MbCoeffs>> {
    if params.operators != OperatorSet::JpegXr {
        return Err(Error::unsupported("the forward transform with HD Photo operators"));
    }
    let kind = PlaneKind::Full;
    plane_size(kind, mb_w, mb_h)?;
    if mbs.len() != mb_w * mb_h {
        return Err(Error::invalid("plane size does not match the macroblock grid"));
    }
    let double = params.scaled && channel > 0;
    let mut cm = Vec::new();
    forward_overlap1(params, kind, mb_w, mb_h, mbs.as_flattened_mut(), &mut cm);
    let dw = 4 * mb_w;
    let mut dc = vec![0i32; dw * 4 * mb_h];
    let mut samples = vec![0i32; mb_w * MB_COEFFS];
    for (row, dc) in mbs.chunks_exact_mut(mb_w).zip(dc.chunks_exact_mut(4 * dw)) {
        samples.copy_from_slice(row.as_flattened());
        forward_stage1(kind, mb_w, 1, &samples, dc, row, &mut cm);
    }
    forward_stage2(params, kind, double, mb_w, mb_h, dc, &mut mbs, &mut cm);
    Ok(mbs)
}

/// The forward transform of a full-resolution plane ([`PlaneKind::Full`], no hard tiles) one
/// macroblock row at a time, from a window of its sample rows: the same coefficients as
/// [`forward_plane`] with buffers of a few macroblock rows instead of planes, so that an
/// encoder can convert, transform, quantize and code a band of rows while it is in cache.
///
/// Row `my`'s stage 1 ([`ForwardRows::stage1`]) needs sample rows `16·my .. 16·my + 18` (the
/// stage-1 POT across the next macroblock row's top edge reaches two rows into it); the
/// caller fills those not yet given ([`ForwardRows::rows_to_fill`]). Its stage 2
/// ([`ForwardRows::stage2`]) needs the stage 1 of row `my + 1` (the second overlap stage
/// reaches two block-DC rows into it), so an encoder runs stage 1 one row ahead. Operations
/// are split between rows by the keys of `pot4_region`, which give the whole plane's result
/// for any split.
#[derive(Debug)]
pub struct ForwardRows {
    overlap: OverlapMode,
    double: bool,
    mb_w: usize,
    mb_h: usize,
    /// Sample rows `16·my ..` of the row whose stage 1 is next, `16 · mb_w` wide.
    window: Vec<i32>,
    /// Block-DC rows `4·my .. 4·my + 8` of the row whose stage 2 is next, `4 · mb_w` wide.
    dc: Vec<i32>,
    /// The macroblock rows `my` and `my + 1` (by `my % 2`).
    mbs: [Vec<MbCoeffs>; 2],
    /// Coefficient-major scratch of the sample rows, and of the block-DC rows (apart, so that
    /// neither is resized, and zeroed again, on every row).
    cm: Vec<i32>,
    cm_dc: Vec<i32>,
}

/// Sample rows a [`ForwardRows`] window holds: a macroblock row and the two rows the
/// stage-1 POT reaches below it.
const WINDOW_ROWS: usize = 18;

impl ForwardRows {
    /// The streaming transform of channel `channel` of an `mb_w` × `mb_h` macroblock grid.
    pub fn new(params: &TransformParams, channel: usize, mb_w: usize, mb_h: usize) -> Result<Self> {
        if params.operators != OperatorSet::JpegXr || params.hard.is_some() {
            return Err(Error::unsupported("the row-by-row forward transform with HD Photo operators or hard tiles"));
        }
        plane_size(PlaneKind::Full, mb_w, mb_h)?;
        Ok(ForwardRows {
            overlap: params.overlap,
            double: params.scaled && channel > 0,
            mb_w,
            mb_h,
            window: vec![0; WINDOW_ROWS * 16 * mb_w],
            dc: vec![0; 8 * 4 * mb_w],
            mbs: [vec![[0; MB_COEFFS]; mb_w], vec![[0; MB_COEFFS]; mb_w]],
            cm: Vec::new(),
            cm_dc: Vec::new(),
        })
    }

    /// The first sample row the caller fills before [`ForwardRows::stage1`] of row `my`, and
    /// the rows to fill from there (`16 · mb_w` samples each, as many rows as the slice holds):
    /// rows `16·my + 2 ..` (from 0 for the first), up to `16·my + 18` or the plane's end.
    pub fn rows_to_fill(&mut self, my: usize) -> (usize, &mut [i32]) {
        let pw = 16 * self.mb_w;
        let first = if my == 0 { 0 } else { 16 * my + 2 };
        let end = (16 * my + WINDOW_ROWS).min(16 * self.mb_h);
        (first, &mut self.window[(first - 16 * my) * pw..(end - 16 * my) * pw])
    }

    /// Stage 1 of macroblock row `my` (rows in order, the window filled): the stage-1 POT
    /// operations keyed by its rows, then the stage-1 PCT of its blocks.
    pub fn stage1(&mut self, my: usize) {
        let (mb_w, mb_h) = (self.mb_w, self.mb_h);
        let (pw, ph) = (16 * mb_w, 16 * mb_h);
        let y0 = 16 * my;
        if self.overlap != OverlapMode::None {
            let keys = if my == 0 { 0..=16 } else { y0 + 1..=y0 + 16 };
            let end = (y0 + WINDOW_ROWS).min(ph);
            let mut p = Rows { data: &mut self.window[..(end - y0) * pw], stride: pw, y_base: y0 };
            pot4_region(&mut p, Rect { x0: 0, x1: pw, y0: 0, y1: ph }, &keys, Dir::Forward, &mut self.cm);
        }
        // The DC rows go after the four of the row before (still waiting for its stage 2).
        let dw = 4 * mb_w;
        let dc = &mut self.dc[if my == 0 { 0 } else { 4 * dw }..][..4 * dw];
        forward_stage1(PlaneKind::Full, mb_w, 1, &self.window[..16 * pw], dc, &mut self.mbs[my % 2], &mut self.cm);
        // The two rows below this macroblock row, already filtered across its edge, start
        // the next window.
        if y0 + 16 < ph {
            self.window.copy_within(16 * pw..WINDOW_ROWS * pw, 0);
        }
    }

    /// Stage 2 of macroblock row `my` (after the stage 1 of row `my + 1`, if there is one):
    /// the second overlap stage's operations keyed by its block-DC rows, each macroblock's
    /// DC/LP transform; its coefficients, `mb_w` macroblocks, are the caller's until the stage
    /// 1 of row `my + 2`.
    pub fn stage2(&mut self, my: usize) -> &mut [MbCoeffs] {
        let (mb_w, mb_h) = (self.mb_w, self.mb_h);
        let (dw, dh) = (4 * mb_w, 4 * mb_h);
        let d0 = 4 * my;
        if self.overlap == OverlapMode::Two {
            let keys = if my == 0 { 0..=4 } else { d0 + 1..=d0 + 4 };
            let end = (d0 + 8).min(dh);
            let mut p = Rows { data: &mut self.dc[..(end - d0) * dw], stride: dw, y_base: d0 };
            pot4_region(&mut p, Rect { x0: 0, x1: dw, y0: 0, y1: dh }, &keys, Dir::Forward, &mut self.cm_dc);
        }
        let mbs = &mut self.mbs[my % 2];
        for (mx, c) in mbs.iter_mut().enumerate() {
            let mut v = [0i32; 16];
            for (j, v) in v.chunks_exact_mut(4).enumerate() {
                v.copy_from_slice(&self.dc[j * dw + 4 * mx..][..4]);
            }
            stage2_forward(PlaneKind::Full, self.double, &v, c);
        }
        // The next row's block DCs move up.
        self.dc.copy_within(4 * dw.., 0);
        mbs
    }
}

/// The first overlap stage of [`forward_plane`] on the plane `data` (nothing without
/// overlap).
fn forward_overlap1(
    params: &TransformParams,
    kind: PlaneKind,
    mb_w: usize,
    mb_h: usize,
    data: &mut [i32],
    cm: &mut Vec<i32>,
) {
    if params.overlap == OverlapMode::None {
        return;
    }
    let (bx, by) = kind.blocks();
    let (width, height) = (4 * bx * mb_w, 4 * by * mb_h);
    let mut p = Rows { data, stride: width, y_base: 0 };
    for r in regions(params.hard.as_ref(), mb_w, mb_h, bx * 4, by * 4) {
        pot4_region(&mut p, r, &(0..=height), Dir::Forward, cm);
    }
}

/// The second stage of [`forward_plane`]: the second overlap stage on the block DCs `dc`
/// (with overlap 2), then each macroblock's DC/LP transform into `coeffs`.
#[allow(clippy::too_many_arguments)]
fn forward_stage2(
    params: &TransformParams,
    kind: PlaneKind,
    double: bool,
    mb_w: usize,
    mb_h: usize,
    mut dc: Vec<i32>,
    coeffs: &mut [MbCoeffs],
    cm: &mut Vec<i32>,
) {
    let (bx, by) = kind.blocks();
    let (dw, dh) = (bx * mb_w, by * mb_h);
    if params.overlap == OverlapMode::Two {
        let mut p = Rows { data: &mut dc, stride: dw, y_base: 0 };
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx, by) {
            match kind {
                PlaneKind::Full => pot4_region(&mut p, r, &(0..=dh), Dir::Forward, cm),
                _ => pot2_region(&mut p, r, &(0..=dh), Dir::Forward),
            }
        }
    }
    for (m, c) in coeffs.iter_mut().enumerate() {
        let (mx, my) = (m % mb_w, m / mb_w);
        let mut v = [0i32; 16];
        for j in 0..by {
            let row = (my * by + j) * dw + mx * bx;
            v[j * bx..(j + 1) * bx].copy_from_slice(&dc[row..row + bx]);
        }
        stage2_forward(kind, double, &v, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::rng;

    /// Random samples of about `bits` bits, signed.
    fn sample(r: &mut impl FnMut() -> u64, bits: u32) -> i32 {
        (r() as i32) >> (32 - bits)
    }

    /// The AVX2 twins compute what the portable code computes, on random coefficients of
    /// every plane kind, overlap mode and tiling (CI also runs every decoder test with
    /// `HDRCODEC_CPU=scalar`, against jxrlib's samples).
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn avx2_twin_matches_the_portable_transform() {
        use hdrcodec_core::cpu::{self, CpuLevel};
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_twin_matches_the_portable_transform") {
            return;
        }
        let mut r = rng(31);
        // 7 macroblocks across: an odd last one in stage 1; 19: two groups of eight in stage
        // 2 and three left over.
        for (mb_w, mb_h) in [(7, 5), (19, 5)] {
            band_twins_agree(&mut r, mb_w, mb_h);
        }
        let (mb_w, mb_h) = (7, 5);
        // The forward stage-1 PCT's twin, on planes of random samples of every kind.
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            let (bx, by) = kind.blocks();
            let (dw, dh) = (bx * mb_w, by * mb_h);
            let plane: Vec<i32> = (0..16 * dw * dh).map(|_| sample(&mut r, 20)).collect();
            let mut a = (vec![0; dw * dh], vec![[0; MB_COEFFS]; mb_w * mb_h], Vec::new());
            let mut b = (vec![1; dw * dh], vec![[0; MB_COEFFS]; mb_w * mb_h], Vec::new());
            forward_stage1_portable(kind, mb_w, mb_h, &plane, &mut a.0, &mut a.1, &mut a.2);
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { forward_stage1_avx2(kind, mb_w, mb_h, &plane, &mut b.0, &mut b.1, &mut b.2) };
            assert_eq!((a.0, a.1), (b.0, b.1), "{kind:?}");
        }
        // The stage-1 overlap filter's own twin, on a plane of random samples.
        for dir in [Dir::Inverse, Dir::Forward] {
            let (w, h) = (16 * mb_w, 16 * mb_h);
            let plane: Vec<i32> = (0..w * h).map(|_| sample(&mut r, 16)).collect();
            let (mut a, mut b) = (plane.clone(), plane);
            let rect = Rect { x0: 0, x1: w, y0: 0, y1: h };
            let (mut ca, mut cb) = (Vec::new(), Vec::new());
            for y in (4..h).step_by(4) {
                pot4_interior_row_portable(&mut Rows { data: &mut a, stride: w, y_base: 0 }, rect, y, dir, &mut ca);
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe {
                    pot4_interior_row_avx2(&mut Rows { data: &mut b, stride: w, y_base: 0 }, rect, y, dir, &mut cb)
                };
            }
            assert_eq!(a, b, "{dir:?}");
        }
    }

    /// The AVX-512 POT kernel filters what the portable code filters: both directions, rows
    /// of 1 to 4 groups of sixteen windows with every remainder (which the AVX2 kernel and
    /// then the portable code take), regions starting past the left edge (hard tile edges).
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn avx512_twin_matches_the_portable_transform() {
        use hdrcodec_core::cpu::{self, CpuLevel};
        if !cpu::twin_test_can_run(CpuLevel::Avx512, "avx512_twin_matches_the_portable_transform") {
            return;
        }
        let mut r = rng(37);
        let h = 16;
        for w in [64, 68, 96, 112, 128, 132, 192, 260, 304] {
            for x0 in [0, 16, 32] {
                let rect = Rect { x0, x1: w, y0: 0, y1: h };
                for dir in [Dir::Inverse, Dir::Forward] {
                    let plane: Vec<i32> = (0..w * h).map(|_| sample(&mut r, 16)).collect();
                    let (mut a, mut b) = (plane.clone(), plane);
                    let (mut ca, mut cb) = (Vec::new(), Vec::new());
                    for y in (4..h).step_by(4) {
                        let mut pa = Rows { data: &mut a, stride: w, y_base: 0 };
                        pot4_interior_row_portable(&mut pa, rect, y, dir, &mut ca);
                        // SAFETY: the CPU has AVX-512F and AVX2 (checked above).
                        unsafe {
                            avx512::pot4_interior_row(
                                &mut Rows { data: &mut b, stride: w, y_base: 0 },
                                rect,
                                y,
                                dir,
                                &mut cb,
                            )
                        };
                    }
                    assert_eq!(a, b, "{dir:?} width {w} from {x0}");
                }
            }
        }
    }

    /// [`inverse_band_rows_avx2`] gives [`inverse_band_rows_portable`]'s samples on random
    /// coefficients of `mb_w × mb_h` macroblocks, every plane kind, overlap mode and tiling.
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn band_twins_agree(r: &mut impl FnMut() -> u64, mb_w: usize, mb_h: usize) {
        let coeffs: Vec<MbCoeffs> = (0..mb_w * mb_h).map(|_| std::array::from_fn(|_| sample(r, 14))).collect();
        let rows: Vec<&[i32]> = coeffs.chunks_exact(mb_w).map(|c| c.as_flattened()).collect();
        let source = MbRows::new(&rows, 0, MB_COEFFS, 0);
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
                for hard in [None, Some(HardEdges::from_tiles(&[3], &[2], true))] {
                    let params = TransformParams { overlap, scaled: true, hard, operators: OperatorSet::JpegXr };
                    for (band, channel) in [0..mb_h, 1..3, 4..5].into_iter().zip([1, 0, 1]) {
                        let (mut a, mut b) = (BandScratch::default(), BandScratch::default());
                        let request = BandRequest {
                            params: &params,
                            kind,
                            channel,
                            mb_w,
                            mb_h,
                            coeffs: &source,
                            rows: band.clone(),
                        };
                        let sa = inverse_band_rows_portable(&request, &mut a);
                        // SAFETY: the CPU has AVX2 (the caller checked).
                        let sb = unsafe { inverse_band_rows_avx2(&request, &mut b) };
                        assert_eq!(sa.unwrap(), sb.unwrap());
                        assert_eq!(a.data, b.data, "{kind:?} {overlap:?} {band:?}");
                    }
                }
            }
        }
    }

    /// The SSE2 transpose is the index-by-index one (and its own inverse).
    #[test]
    fn transpose_twins_agree() {
        let mut r = rng(7);
        for _ in 0..100 {
            let m: [i32; 16] = std::array::from_fn(|_| sample(&mut r, 31));
            let t = transpose4x4(&m);
            assert_eq!(t, transpose4x4_scalar(&m));
            assert_eq!((t[1], t[4], t[7], t[13]), (m[4], m[1], m[13], m[7]));
            assert_eq!(transpose4x4(&t), m);
        }
    }

    /// The row-wise stage-1 forward PCT gives each block what [`pct4x4`] gives it alone.
    #[test]
    fn forward_stage1_is_the_blockwise_pct() {
        let mut r = rng(41);
        let (mb_w, mb_h) = (5, 3);
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            let (bx, by) = kind.blocks();
            let (dw, dh) = (bx * mb_w, by * mb_h);
            let width = 4 * dw;
            let plane: Vec<i32> = (0..16 * dw * dh).map(|_| sample(&mut r, 24)).collect();
            let (mut dc, mut coeffs) = (vec![0; dw * dh], vec![[0; MB_COEFFS]; mb_w * mb_h]);
            forward_stage1(kind, mb_w, mb_h, &plane, &mut dc, &mut coeffs, &mut Vec::new());
            for (m, c) in coeffs.iter().enumerate() {
                let (mx, my) = (m % mb_w, m / mb_w);
                for b in 0..bx * by {
                    let (x, y) = (mx * bx + b % bx, my * by + b / bx);
                    let mut t = [0i32; 16];
                    for j in 0..4 {
                        t[j * 4..j * 4 + 4].copy_from_slice(&plane[(y * 4 + j) * width + x * 4..][..4]);
                    }
                    pct4x4(&mut t);
                    assert_eq!(dc[y * dw + x], t[0], "{kind:?} block {b} of macroblock {m}");
                    assert_eq!(c[hp(b, 1)..=hp(b, 15)], t[1..], "{kind:?} block {b} of macroblock {m}");
                }
            }
        }
    }

    #[test]
    fn operators_invert_exactly() {
        let mut r = rng(7);
        for bits in [4, 12, 20, 26] {
            for _ in 0..20_000 {
                let orig: [i32; 16] = std::array::from_fn(|_| sample(&mut r, bits));
                let idx16: [usize; 16] = std::array::from_fn(|k| k);
                let mut v = orig;
                pct4x4(&mut v);
                ipct4x4(&mut v);
                assert_eq!(v, orig, "PCT");
                let mut v = orig;
                on(&mut v, idx16, pre4x4_g);
                on(&mut v, idx16, post4x4_g);
                assert_eq!(v, orig, "4x4 POT");
                let mut v = orig;
                pre4(&mut v, [0, 1, 2, 3]);
                post4(&mut v, [0, 1, 2, 3]);
                assert_eq!(v, orig, "4-point POT");
                let mut v = orig;
                pre2x2(&mut v, [0, 1, 2, 3]);
                post2x2(&mut v, [0, 1, 2, 3]);
                assert_eq!(v, orig, "2x2 POT");
                let mut v = orig;
                pre2(&mut v, [0, 1]);
                post2(&mut v, [0, 1]);
                assert_eq!(v, orig, "2-point POT");
                for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
                    let mut c = [0i32; MB_COEFFS];
                    let n = kind.blocks().0 * kind.blocks().1;
                    c[..n].copy_from_slice(&orig[..n]);
                    let mut dcs = [0; 16];
                    stage2_inverse(kind, false, &c, &mut dcs);
                    let mut back = [0i32; MB_COEFFS];
                    stage2_forward(kind, false, &dcs, &mut back);
                    assert_eq!(back[..n], orig[..n], "{kind:?} stage 2");
                }
            }
        }
    }

    fn random_plane(r: &mut impl FnMut() -> u64, kind: PlaneKind, mb_w: usize, mb_h: usize, bits: u32) -> Plane {
        let (bx, by) = kind.blocks();
        let (width, height) = (mb_w * bx * 4, mb_h * by * 4);
        Plane { width, height, data: (0..width * height).map(|_| sample(r, bits)).collect() }
    }

    #[test]
    fn forward_then_inverse_is_the_identity() {
        let mut r = rng(11);
        let grids = [(1, 1), (1, 3), (3, 1), (2, 2), (3, 2), (5, 3), (2, 17)];
        let edges = [
            None,
            Some(HardEdges { columns: vec![1, 3], rows: vec![1] }),
            Some(HardEdges::from_tiles(&[0, 2], &[0, 1, 2], true)),
        ];
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
                for hard in &edges {
                    for &(mb_w, mb_h) in &grids {
                        for bits in [9, 17] {
                            let params = TransformParams {
                                overlap,
                                scaled: false,
                                hard: hard.clone(),
                                operators: OperatorSet::JpegXr,
                            };
                            let plane = random_plane(&mut r, kind, mb_w, mb_h, bits);
                            let coeffs = forward_plane(&params, kind, 1, mb_w, mb_h, plane.clone()).unwrap();
                            let back = inverse_plane(&params, kind, 1, mb_w, mb_h, &coeffs).unwrap();
                            assert_eq!(back, plane, "{kind:?} {overlap:?} {hard:?} {mb_w}x{mb_h}");
                            // And the coefficients survive the other way round.
                            let again = forward_plane(&params, kind, 1, mb_w, mb_h, back.clone()).unwrap();
                            assert_eq!(again, coeffs);
                        }
                    }
                }
            }
        }
    }

    /// The in-place forward transform (the plane held in the coefficient array) gives
    /// `forward_plane`'s coefficients, for every overlap mode, hard edges, scaled or not,
    /// luma and chroma; a wrong array size is an error.
    #[test]
    fn forward_in_place_matches_forward_plane() {
        let mut r = rng(12);
        let edges = [None, Some(HardEdges::from_tiles(&[0, 2], &[0, 1, 2], true))];
        for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
            for hard in &edges {
                for &(mb_w, mb_h) in &[(1, 1), (3, 2), (5, 3), (2, 17)] {
                    for (scaled, channel) in [(false, 0), (true, 0), (true, 1)] {
                        let params =
                            TransformParams { overlap, scaled, hard: hard.clone(), operators: OperatorSet::JpegXr };
                        let plane = random_plane(&mut r, PlaneKind::Full, mb_w, mb_h, 17);
                        let mbs: Vec<MbCoeffs> =
                            plane.data.chunks_exact(MB_COEFFS).map(|c| c.try_into().expect("256 samples")).collect();
                        let want = forward_plane(&params, PlaneKind::Full, channel, mb_w, mb_h, plane).unwrap();
                        let got = forward_plane_in_place(&params, channel, mb_w, mb_h, mbs).unwrap();
                        assert!(got == want, "{overlap:?} {hard:?} {mb_w}x{mb_h} scaled {scaled} channel {channel}");
                    }
                }
            }
        }
        let params =
            TransformParams { overlap: OverlapMode::One, scaled: false, hard: None, operators: OperatorSet::JpegXr };
        assert!(forward_plane_in_place(&params, 0, 2, 2, vec![[0; MB_COEFFS]; 3]).is_err());
    }

    /// The row-by-row forward transform (a window of sample rows filled as it asks, stage 1
    /// a row ahead of stage 2) gives `forward_plane`'s coefficients, for every overlap mode,
    /// scaled or not, luma and chroma, one macroblock row or many; hard edges are refused.
    #[test]
    fn forward_rows_match_forward_plane() {
        let mut r = rng(13);
        for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
            for &(mb_w, mb_h) in &[(1, 1), (3, 1), (3, 2), (5, 3), (2, 17)] {
                for (scaled, channel) in [(false, 0), (true, 0), (true, 1)] {
                    let params = TransformParams { overlap, scaled, hard: None, operators: OperatorSet::JpegXr };
                    let plane = random_plane(&mut r, PlaneKind::Full, mb_w, mb_h, 17);
                    let pw = plane.width;
                    let mut rows = ForwardRows::new(&params, channel, mb_w, mb_h).unwrap();
                    let mut got = Vec::new();
                    let mut filled = 0;
                    for step in 0..=mb_h {
                        if step < mb_h {
                            let (first, data) = rows.rows_to_fill(step);
                            assert_eq!(first, filled, "rows asked for in order");
                            data.copy_from_slice(&plane.data[first * pw..][..data.len()]);
                            filled += data.len() / pw;
                            rows.stage1(step);
                        }
                        if step > 0 {
                            got.extend_from_slice(rows.stage2(step - 1));
                        }
                    }
                    assert_eq!(filled, plane.height);
                    let want = forward_plane(&params, PlaneKind::Full, channel, mb_w, mb_h, plane).unwrap();
                    assert!(got == want, "{overlap:?} {mb_w}x{mb_h} scaled {scaled} channel {channel}");
                }
            }
        }
        let hard = Some(HardEdges::from_tiles(&[0, 1], &[0], true));
        let params = TransformParams { overlap: OverlapMode::One, scaled: false, hard, operators: OperatorSet::JpegXr };
        assert!(ForwardRows::new(&params, 0, 2, 2).is_err());
    }

    #[test]
    fn scaled_chroma_doubles_the_block_dcs() {
        // With DC and LP only, a scaled chroma channel decodes to twice the unscaled stage-2
        // output; channel 0 is not doubled.
        let params =
            |scaled| TransformParams { overlap: OverlapMode::None, scaled, hard: None, operators: OperatorSet::JpegXr };
        let mut c = [0i32; MB_COEFFS];
        c[0] = 1000;
        c[3] = -77;
        let plain = inverse_plane(&params(false), PlaneKind::Full, 1, 1, 1, &[c]).unwrap();
        let luma = inverse_plane(&params(true), PlaneKind::Full, 0, 1, 1, &[c]).unwrap();
        assert_eq!(plain, luma);
        let mut doubled = [0i32; 16];
        stage2_inverse(PlaneKind::Full, true, &c, &mut doubled);
        let mut single = [0i32; 16];
        stage2_inverse(PlaneKind::Full, false, &c, &mut single);
        assert_eq!(doubled, single.map(|v| 2 * v));
    }

    #[test]
    fn edges_and_hard_tiles_change_what_they_should() {
        // A hard tile edge makes the two sides independent: changing a coefficient on the left
        // of it changes no sample on the right.
        let mut r = rng(3);
        let plane = random_plane(&mut r, PlaneKind::Full, 4, 2, 12);
        let hard = TransformParams {
            overlap: OverlapMode::Two,
            scaled: false,
            hard: Some(HardEdges { columns: vec![2], rows: vec![] }),
            operators: OperatorSet::JpegXr,
        };
        let soft = TransformParams { hard: None, ..hard.clone() };
        for params in [&hard, &soft] {
            let mut c = forward_plane(params, PlaneKind::Full, 0, 4, 2, plane.clone()).unwrap();
            let before = inverse_plane(params, PlaneKind::Full, 0, 4, 2, &c).unwrap();
            c[1][0] += 1000; // DC of MB (1, 0), left of the edge
            let after = inverse_plane(params, PlaneKind::Full, 0, 4, 2, &c).unwrap();
            let right_changed = (0..32).any(|y| (32..64).any(|x| before.data[y * 64 + x] != after.data[y * 64 + x]));
            assert_eq!(right_changed, params.hard.is_none(), "{params:?}");
        }
        // Overlap mode 0: a coefficient touches only its own macroblock.
        let none =
            TransformParams { overlap: OverlapMode::None, scaled: false, hard: None, operators: OperatorSet::JpegXr };
        let mut c = vec![[0i32; MB_COEFFS]; 4];
        c[0][hp(5, 3)] = 500;
        let out = inverse_plane(&none, PlaneKind::Full, 0, 2, 2, &c).unwrap();
        for y in 0..32 {
            for x in 0..32 {
                let inside = (4..8).contains(&x) && (4..8).contains(&y);
                if !inside {
                    assert_eq!(out.data[y * 32 + x], 0, "({x}, {y}) outside block 5");
                }
            }
        }
        assert!((4..8).any(|y| (4..8).any(|x| out.data[y * 32 + x] != 0)));
    }

    #[test]
    fn bad_geometry_is_an_error() {
        let p =
            TransformParams { overlap: OverlapMode::One, scaled: false, hard: None, operators: OperatorSet::JpegXr };
        assert!(inverse_plane(&p, PlaneKind::Full, 0, 2, 2, &[[0; MB_COEFFS]; 3]).is_err());
        assert!(inverse_plane(&p, PlaneKind::Full, 0, 0, 2, &[]).is_err());
        let plane = Plane { width: 16, height: 16, data: vec![0; 256] };
        assert!(forward_plane(&p, PlaneKind::Full, 0, 2, 1, plane.clone()).is_err());
        // Extreme coefficients wrap rather than panic.
        let mut c = [i32::MAX; MB_COEFFS];
        c[5] = i32::MIN;
        for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
            for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
                let p = TransformParams { overlap, scaled: true, hard: None, operators: OperatorSet::JpegXr };
                let _ = inverse_plane(&p, kind, 1, 2, 2, &[c; 4]).unwrap();
            }
        }
    }

    /// A fixture made with T.835 (built with `-DDETAILED_DEBUG` in `r_strip.c`) decoding a
    /// JxrEncApp stream: the dequantized DC/LP (`Dequant:` lines) and HP (`pre-IPCT` levels
    /// times `hp_quant`) of every macroblock, and the decoded image (JxrDecApp and T.835
    /// agree). See `testdata/t835/README.md`.
    struct Fixture {
        mb_w: usize,
        mb_h: usize,
        overlap: OverlapMode,
        scaled: bool,
        width: usize,
        height: usize,
        channels: Vec<Vec<MbCoeffs>>,
        expected: Vec<i32>,
        /// A second expected image (see the fixture README: hard tiles, interleaved alpha).
        expected_second: Option<Vec<i32>>,
    }

    fn fixture(name: &str) -> Fixture {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata/t835").join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        let h: Vec<usize> = lines.next().unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect();
        let rows: Vec<Vec<i32>> =
            lines.map(|l| l.split_whitespace().map(|v| v.parse::<i64>().unwrap() as i32).collect()).collect();
        let n = h[0] * h[1];
        let images = if (rows.len() - 1).is_multiple_of(n) { 1 } else { 2 };
        let (mbs, expected) = rows.split_at(rows.len() - images);
        let channels = mbs
            .chunks(n)
            .map(|ch| ch.iter().map(|r| std::array::from_fn(|k| r.get(k).copied().unwrap_or(0))).collect())
            .collect();
        let overlap = [OverlapMode::None, OverlapMode::One, OverlapMode::Two][h[2]];
        Fixture {
            mb_w: h[0],
            mb_h: h[1],
            overlap,
            scaled: h[3] == 1,
            width: h[4],
            height: h[5],
            channels,
            expected: expected[0].clone(),
            expected_second: expected.get(1).cloned(),
        }
    }

    /// Decodes a three-channel fixture through the transform, chroma upsampling and `out`'s
    /// formatting: the raw output bytes of the `width × height` image.
    fn render(f: &Fixture, internal: crate::output::InternalColorFormat, out: &crate::output::OutputParams) -> Vec<u8> {
        use crate::output::{upsample_chroma_row, InternalColorFormat};
        let kind = match internal {
            InternalColorFormat::Yuv420 => PlaneKind::Chroma420,
            InternalColorFormat::Yuv422 => PlaneKind::Chroma422,
            _ => PlaneKind::Full,
        };
        let params =
            TransformParams { overlap: f.overlap, scaled: f.scaled, hard: None, operators: OperatorSet::JpegXr };
        let planes: Vec<Plane> = (0..3)
            .map(|ch| {
                let k = if ch == 0 { PlaneKind::Full } else { kind };
                inverse_plane(&params, k, ch, f.mb_w, f.mb_h, &f.channels[ch]).unwrap()
            })
            .collect();
        let w = planes[0].width;
        let (mut u, mut v) = (vec![0; w], vec![0; w]);
        let mut bytes = Vec::new();
        for y in 0..f.height {
            let c = &planes[1];
            upsample_chroma_row(internal, &c.data, c.width, c.height, y, &mut u).unwrap();
            upsample_chroma_row(internal, &planes[2].data, c.width, c.height, y, &mut v).unwrap();
            let mut row = vec![0u8; out.row_bytes(f.width)];
            out.format_row(&[&planes[0].data[y * w..(y + 1) * w], &u, &v], None, f.width, &mut row).unwrap();
            bytes.extend(row);
        }
        bytes
    }

    /// The inverse transform reproduces T.835's and jxrlib's decoded 8-bit grey images
    /// exactly (lossless and QP 30; overlap 0, 1 and 2), formatted as BD8 output does.
    #[test]
    fn matches_t835_on_grey_streams() {
        for name in ["gray_g_l0", "gray_g_l1", "gray_g_l2", "gray_gq_l0", "gray_gq_l1", "gray_gq_l2"] {
            let f = fixture(&format!("{name}.txt"));
            let params =
                TransformParams { overlap: f.overlap, scaled: f.scaled, hard: None, operators: OperatorSet::JpegXr };
            let plane = inverse_plane(&params, PlaneKind::Full, 0, f.mb_w, f.mb_h, &f.channels[0]).unwrap();
            let s = if f.scaled { 3 } else { 0 };
            let bias = (128 << s) + if f.scaled { 3 } else { 0 };
            let mut got = Vec::new();
            for y in 0..f.height {
                for x in 0..f.width {
                    got.push((plane.data[y * plane.width + x] + bias) >> s);
                }
            }
            let got: Vec<i32> = got.into_iter().map(|v| v.clamp(0, 255)).collect();
            assert_eq!(got.len(), f.expected.len());
            let diff = got.iter().zip(&f.expected).filter(|(a, b)| a != b).count();
            assert_eq!(diff, 0, "{name}: {diff} samples differ");
            // The fixture is sensitive to the overlap mode.
            let other = TransformParams { overlap: OverlapMode::None, ..params.clone() };
            let wrong = inverse_plane(&other, PlaneKind::Full, 0, f.mb_w, f.mb_h, &f.channels[0]).unwrap();
            assert_eq!(wrong == plane, f.overlap == OverlapMode::None, "{name}");
        }
    }

    /// 24bppRGB at QP 30 (scaled arithmetic) with 4:2:0, 4:2:2 and 4:4:4 internal formats and
    /// overlap 1 and 2: transform, chroma upsampling, colour conversion and BD8 formatting
    /// together reproduce JxrDecApp's (and T.835's) output exactly.
    #[test]
    fn matches_t835_on_colour_streams() {
        use crate::container::{OutputBitDepth, OutputColorFormat, PIXEL_FORMATS};
        use crate::output::{InternalColorFormat, OutputParams};
        let rgb = PIXEL_FORMATS.iter().find(|f| f.name == "24bppRGB").unwrap();
        for name in ["rgb_c_d1_l1", "rgb_c_d1_l2", "rgb_c_d2_l1", "rgb_c_d2_l2", "rgb_c_d3_l1", "rgb_c_d3_l2"] {
            let f = fixture(&format!("{name}.txt"));
            let internal = match &name[6..8] {
                "d1" => InternalColorFormat::Yuv420,
                "d2" => InternalColorFormat::Yuv422,
                _ => InternalColorFormat::Yuv444,
            };
            let out = OutputParams::new(
                rgb,
                OutputBitDepth::Bd8,
                OutputColorFormat::Rgb,
                internal,
                f.scaled,
                0,
                0,
                false,
                None,
            )
            .unwrap();
            let got: Vec<i32> = render(&f, internal, &out).into_iter().map(i32::from).collect();
            assert_eq!(got, f.expected, "{name}");
        }
    }

    /// Hard tiles on a non-square grid (a 4×3-macroblock grey image, tile columns at MB 0, 1,
    /// 2 and rows at 0, 1, QP 30, overlap 2, written by T.835 `-h -U 2:3`): T.832's seams
    /// reproduce T.835's output, the swapped seams of JXR-NOTES §8 quirk 1 reproduce
    /// JxrDecApp's (which differs from T.835 on 1805 of 3072 samples).
    #[test]
    fn hard_tiles_match_t835_and_jxrlib() {
        let f = fixture("hard_gray.txt");
        for (swap, expected) in [(false, &f.expected), (true, f.expected_second.as_ref().unwrap())] {
            let hard = HardEdges::from_tiles(&[0, 1, 2], &[0, 1], swap);
            let params = TransformParams {
                overlap: f.overlap,
                scaled: f.scaled,
                hard: Some(hard),
                operators: OperatorSet::JpegXr,
            };
            let plane = inverse_plane(&params, PlaneKind::Full, 0, f.mb_w, f.mb_h, &f.channels[0]).unwrap();
            let mut got = Vec::new();
            for y in 0..f.height {
                for x in 0..f.width {
                    got.push(((plane.data[y * plane.width + x] + 1024 + 3) >> 3).clamp(0, 255));
                }
            }
            let diff = got.iter().zip(expected).filter(|(a, b)| a != b).count();
            assert_eq!((got.len(), diff), (expected.len(), 0), "jxrlib swap {swap}");
        }
    }

    /// Every split into bands, and coefficient windows holding only a band's halo, give the
    /// same samples as one band over the whole image.
    #[test]
    fn bands_agree_with_the_whole_image() {
        let mut r = rng(21);
        let (mb_w, mb_h) = (3, 11);
        let hard = [None, Some(HardEdges { columns: vec![2], rows: vec![4, 5, 9] })];
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
                for h in &hard {
                    let params =
                        TransformParams { overlap, scaled: true, hard: h.clone(), operators: OperatorSet::JpegXr };
                    let coeffs: Vec<MbCoeffs> =
                        (0..mb_w * mb_h).map(|_| std::array::from_fn(|_| sample(&mut r, 14))).collect();
                    let whole = assert_bands_match_whole(&params, kind, 2, mb_w, mb_h, &coeffs, &format!("{h:?}"));
                    assert_eq!(inverse_plane(&params, kind, 2, mb_w, mb_h, &coeffs).unwrap().data, whole);
                    // A window one row short of a band's halo is refused.
                    for r0 in 1..mb_h {
                        let (s0, s1) = (r0.saturating_sub(2), (r0 + 3).min(mb_h));
                        let mut out = vec![0; whole.len()];
                        let short = &coeffs[(s0 + 1) * mb_w..s1 * mb_w];
                        assert!(
                            inverse_band(&params, kind, 2, mb_w, mb_h, short, s0 + 1, r0..r0 + 1, &mut out).is_err()
                        );
                    }
                }
            }
        }
    }

    /// Decodes `coeffs` as one band, then in bands of 1, 2, 3 and 5 macroblock rows each given
    /// only its halo's coefficients, asserts that they agree, and returns the whole plane.
    pub(super) fn assert_bands_match_whole(
        params: &TransformParams,
        kind: PlaneKind,
        channel: usize,
        mb_w: usize,
        mb_h: usize,
        coeffs: &[MbCoeffs],
        what: &str,
    ) -> Vec<i32> {
        let (width, height) = plane_size(kind, mb_w, mb_h).unwrap();
        let unit = height / mb_h;
        let mut whole = vec![0; width * height];
        inverse_band(params, kind, channel, mb_w, mb_h, coeffs, 0, 0..mb_h, &mut whole).unwrap();
        for band in [1, 2, 3, 5] {
            for r0 in (0..mb_h).step_by(band) {
                let r1 = (r0 + band).min(mb_h);
                let (s0, s1) = (r0.saturating_sub(2), (r1 + 2).min(mb_h));
                let window = &coeffs[s0 * mb_w..s1 * mb_w];
                let mut out = vec![0; (r1 - r0) * unit * width];
                inverse_band(params, kind, channel, mb_w, mb_h, window, s0, r0..r1, &mut out).unwrap();
                let overlap = params.overlap;
                assert_eq!(out, whole[r0 * unit * width..r1 * unit * width], "{kind:?} {overlap:?} {what} {r0}..{r1}");
            }
        }
        whole
    }

    /// 48bppRGBHalf (scaled) and 96bppRGBFloat (unscaled, LEN_MANTISSA 13, EXP_BIAS 4) at
    /// quality 0.6, written by imagecodecs' `jpegxr_encode` (jxrlib; overlap 0, 4:4:4): the
    /// transform and BD16F / BD32F formatting give jxrlib's exact half and float bit patterns
    /// (including -1.5, 65504 and 1e-6 in the source).
    #[test]
    fn matches_jxrlib_half_and_float_output() {
        use crate::container::{OutputBitDepth, OutputColorFormat, PIXEL_FORMATS};
        use crate::output::{InternalColorFormat, OutputParams};
        for (name, format, bd, shift) in [
            ("half_q06", "48bppRGBHalf", OutputBitDepth::Bd16F, 0),
            ("float_q06", "96bppRGBFloat", OutputBitDepth::Bd32F, 13),
        ] {
            let f = fixture(&format!("{name}.txt"));
            let pf = PIXEL_FORMATS.iter().find(|p| p.name == format).unwrap();
            let out = OutputParams::new(
                pf,
                bd,
                OutputColorFormat::Rgb,
                InternalColorFormat::Yuv444,
                f.scaled,
                shift,
                4,
                false,
                None,
            )
            .unwrap();
            let bytes = render(&f, InternalColorFormat::Yuv444, &out);
            let got: Vec<i32> = if bd == OutputBitDepth::Bd16F {
                bytes.chunks(2).map(|b| i32::from(u16::from_le_bytes([b[0], b[1]]))).collect()
            } else {
                bytes.chunks(4).map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
            };
            assert_eq!(got, f.expected, "{name}");
        }
    }

    /// 32bppRGBE written by JxrEncApp from a flat Radiance file, lossless (unscaled) and QP 40
    /// (scaled), overlap 1: the RGBE bytes of JxrDecApp's `.hdr` output, exactly.
    #[test]
    fn matches_jxrlib_rgbe_output() {
        use crate::container::{OutputBitDepth, OutputColorFormat, PIXEL_FORMATS};
        use crate::output::{InternalColorFormat, OutputParams};
        let pf = PIXEL_FORMATS.iter().find(|p| p.name == "32bppRGBE").unwrap();
        for name in ["rgbe_e_ll", "rgbe_e_q"] {
            let f = fixture(&format!("{name}.txt"));
            let (bd, cf, internal) = (OutputBitDepth::Bd8, OutputColorFormat::Rgbe, InternalColorFormat::Yuv444);
            let out = OutputParams::new(pf, bd, cf, internal, f.scaled, 0, 0, false, None).unwrap();
            let got: Vec<i32> = render(&f, internal, &out).into_iter().map(i32::from).collect();
            assert_eq!(got, f.expected, "{name}");
        }
    }

    #[test]
    fn operator_sets() {
        assert!(check_operator_set(1).is_ok() && check_operator_set(9).is_ok() && check_operator_set(0).is_ok());
        assert!(matches!(check_operator_set(5), Err(Error::Invalid { .. })));
    }

    /// 32bppBGRA with an interleaved alpha plane (`JxrEncApp -c 22 -a 3 -q 40 -Q 40`), overlap
    /// 1, scaled: the colour channels match both decoders; alpha matches JxrDecApp with
    /// jxrlib's +4 rounding and T.835 with +3 (JXR-NOTES §8 quirk 2; they differ on 113 of 960
    /// samples here).
    #[test]
    fn interleaved_alpha_matches_jxrlib_and_t835() {
        use crate::container::{OutputBitDepth, OutputColorFormat, PIXEL_FORMATS};
        use crate::output::{AlphaParams, InternalColorFormat, OutputParams};
        let f = fixture("alpha_interleaved.txt");
        let pf = PIXEL_FORMATS.iter().find(|p| p.name == "32bppBGRA").unwrap();
        let params =
            TransformParams { overlap: f.overlap, scaled: f.scaled, hard: None, operators: OperatorSet::JpegXr };
        // T.835 logs the alpha plane's macroblocks first, then the primary channels.
        let plane = |i: usize| {
            inverse_plane(&params, PlaneKind::Full, i.saturating_sub(1), f.mb_w, f.mb_h, &f.channels[i]).unwrap()
        };
        let (alpha, y, u, v) = (plane(0), plane(1), plane(2), plane(3));
        let w = y.width;
        for (jxrlib, expected) in [(true, &f.expected), (false, f.expected_second.as_ref().unwrap())] {
            let a = AlphaParams { scaled: f.scaled, jxrlib_interleaved: jxrlib };
            let out = OutputParams::new(
                pf,
                OutputBitDepth::Bd8,
                OutputColorFormat::Rgb,
                InternalColorFormat::Yuv444,
                f.scaled,
                0,
                0,
                false,
                Some(a),
            )
            .unwrap();
            let mut got = Vec::new();
            for r in 0..f.height {
                let rows = [&y, &u, &v, &alpha].map(|p| &p.data[r * w..(r + 1) * w]);
                let mut bytes = vec![0u8; out.row_bytes(f.width)];
                out.format_row(&rows[..3], Some(rows[3]), f.width, &mut bytes).unwrap();
                // BGRA to the RGBA of the TIFF files.
                got.extend(bytes.chunks(4).flat_map(|p| [p[2], p[1], p[0], p[3]]).map(i32::from));
            }
            assert_eq!(&got, expected, "jxrlib rounding {jxrlib}");
        }
    }
}
