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
//! 1. **Stage-2 PCT** per macroblock: DC and LP coefficients (the [`crate::mb`] layout) to the
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

use crate::mb::{hp, lp, MbCoeffs, DC, MB_COEFFS};
use hdrcodec_core::{Error, Result};
use std::num::Wrapping;

type W = Wrapping<i32>;
const W1: W = Wrapping(1);
const W2: W = Wrapping(2);
const W3: W = Wrapping(3);
const W4: W = Wrapping(4);
const W6: W = Wrapping(6);

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

/// What the transform needs from the headers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TransformParams {
    /// OVERLAP_MODE.
    pub overlap: OverlapMode,
    /// SCALED_FLAG of the plane (doubles the stage-2 output of channels after the first).
    pub scaled: bool,
    /// `Some` for hard tiles.
    pub hard: Option<HardEdges>,
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
fn load<const N: usize>(p: &[i32], i: [usize; N]) -> [W; N] {
    i.map(|k| Wrapping(p[k]))
}

#[inline(always)]
fn store<const N: usize>(p: &mut [i32], i: [usize; N], v: [W; N]) {
    for (k, x) in i.into_iter().zip(v) {
        p[k] = x.0;
    }
}

/// The 2×2 Hadamard butterfly `_2x2T_h` (self-inverse).
#[inline(always)]
fn t2x2h(v: [W; 4], r: W) -> [W; 4] {
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

fn t2x2h_post(v: [W; 4]) -> [W; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b -= c;
    a += (d * W3 + W4) >> 3;
    d -= b >> 1;
    let t1 = ((a - b) >> 1) - c;
    c = d;
    d = t1;
    a -= d;
    b += c;
    [a, b, c, d]
}

fn t2x2h_enc(v: [W; 4]) -> [W; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    a += d;
    b -= c;
    let (t1, t2) = (d, c);
    c = ((a - b) >> 1) - t1;
    d = t2 + (b >> 1);
    b += c;
    a -= (d * W3 + W4) >> 3;
    [a, b, c, d]
}

fn inv_t_odd(v: [W; 4]) -> [W; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b += d;
    a -= c;
    d -= b >> 1;
    c += (a + W1) >> 1;
    a -= (b * W3 + W4) >> 3;
    b += (a * W3 + W4) >> 3;
    c -= (d * W3 + W4) >> 3;
    d += (c * W3 + W4) >> 3;
    c -= (b + W1) >> 1;
    d = ((a + W1) >> 1) - d;
    b += c;
    a -= d;
    [a, b, c, d]
}

fn fwd_t_odd(v: [W; 4]) -> [W; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    b -= c;
    a += d;
    c += (b + W1) >> 1;
    d = ((a + W1) >> 1) - d;
    b -= (a * W3 + W4) >> 3;
    a += (b * W3 + W4) >> 3;
    d -= (c * W3 + W4) >> 3;
    c += (d * W3 + W4) >> 3;
    d += b >> 1;
    c -= (a + W1) >> 1;
    b -= d;
    a += c;
    [a, b, c, d]
}

/// The odd-odd rotation shared by `_InvT_odd_odd` (rounding 3, 3; outputs b and c negated)
/// and `_InvT_odd_odd_POST` (rounding 6, 2).
fn inv_odd_odd(v: [W; 4], r1: W, r2: W, negate: bool) -> [W; 4] {
    let [mut a, mut b, mut c, mut d] = v;
    d += a;
    c -= b;
    let t1 = d >> 1;
    let t2 = c >> 1;
    a -= t1;
    b += t2;
    a -= (b * W3 + r1) >> 3;
    b += (a * W3 + r2) >> 2;
    a -= (b * W3 + W4) >> 3;
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
fn fwd_odd_odd(v: [W; 4], r1: W, r2: W, negate: bool) -> [W; 4] {
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
    a += (b * W3 + W4) >> 3;
    b -= (a * W3 + r2) >> 2;
    a += (b * W3 + r1) >> 3;
    b -= t2;
    a += t1;
    c += b;
    d -= a;
    [a, b, c, d]
}

fn inv_t_odd_odd(v: [W; 4]) -> [W; 4] {
    inv_odd_odd(v, W3, W3, true)
}

fn fwd_t_odd_odd(v: [W; 4]) -> [W; 4] {
    fwd_odd_odd(v, W3, W3, true)
}

fn inv_t_odd_odd_post(v: [W; 4]) -> [W; 4] {
    inv_odd_odd(v, W6, W2, false)
}

fn fwd_t_odd_odd_pre(v: [W; 4]) -> [W; 4] {
    fwd_odd_odd(v, W6, W2, false)
}

#[inline(always)]
fn inv_rotate([mut a, mut b]: [W; 2]) -> [W; 2] {
    a -= (b + W1) >> 1;
    b += (a + W1) >> 1;
    [a, b]
}

#[inline(always)]
fn fwd_rotate([mut a, mut b]: [W; 2]) -> [W; 2] {
    b -= (a + W1) >> 1;
    a += (b + W1) >> 1;
    [a, b]
}

#[inline(always)]
fn inv_scale([mut a, mut b]: [W; 2]) -> [W; 2] {
    a += b;
    b = (a >> 1) - b;
    a += (b * W3) >> 3;
    b -= a >> 10;
    b += a >> 7;
    b += (a * W3) >> 4;
    [a, b]
}

#[inline(always)]
fn fwd_scale([mut a, mut b]: [W; 2]) -> [W; 2] {
    b -= (a * W3) >> 4;
    b -= a >> 7;
    b += a >> 10;
    a -= (b * W3) >> 3;
    b = (a >> 1) - b;
    a -= b;
    [a, b]
}

/// Applies `f` to the samples at indices `i` of `p`.
#[inline(always)]
fn on<const N: usize>(p: &mut [i32], i: [usize; N], f: impl Fn([W; N]) -> [W; N]) {
    let v = load(p, i);
    store(p, i, f(v));
}

/// `_jxr_4x4IPCT`: 16 coefficients (DC first) to 16 samples in raster order.
fn ipct4x4(c: &mut [i32; 16]) {
    const INV_PERMUTE: [usize; 16] = [0, 8, 4, 13, 2, 15, 3, 14, 1, 12, 5, 9, 7, 11, 6, 10];
    let mut t = [0; 16];
    for (i, &v) in c.iter().enumerate() {
        t[INV_PERMUTE[i]] = v;
    }
    on(&mut t, [0, 1, 4, 5], |v| t2x2h(v, W1));
    on(&mut t, [2, 3, 6, 7], inv_t_odd);
    on(&mut t, [8, 12, 9, 13], inv_t_odd);
    on(&mut t, [10, 11, 14, 15], inv_t_odd_odd);
    on(&mut t, [0, 3, 12, 15], |v| t2x2h(v, Wrapping(0)));
    on(&mut t, [5, 6, 9, 10], |v| t2x2h(v, Wrapping(0)));
    on(&mut t, [1, 2, 13, 14], |v| t2x2h(v, Wrapping(0)));
    on(&mut t, [4, 7, 8, 11], |v| t2x2h(v, Wrapping(0)));
    *c = t;
}

/// `_jxr_4x4PCT`: the inverse of [`ipct4x4`].
fn pct4x4(c: &mut [i32; 16]) {
    const FWD_PERMUTE: [usize; 16] = [0, 8, 4, 6, 2, 10, 14, 12, 1, 11, 15, 13, 9, 3, 7, 5];
    let t = c;
    on(t, [0, 3, 12, 15], |v| t2x2h(v, Wrapping(0)));
    on(t, [5, 6, 9, 10], |v| t2x2h(v, Wrapping(0)));
    on(t, [1, 2, 13, 14], |v| t2x2h(v, Wrapping(0)));
    on(t, [4, 7, 8, 11], |v| t2x2h(v, Wrapping(0)));
    on(t, [0, 1, 4, 5], |v| t2x2h(v, W1));
    on(t, [2, 3, 6, 7], fwd_t_odd);
    on(t, [8, 12, 9, 13], fwd_t_odd);
    on(t, [10, 11, 14, 15], fwd_t_odd_odd);
    let mut out = [0; 16];
    for (i, &v) in t.iter().enumerate() {
        out[FWD_PERMUTE[i]] = v;
    }
    *t = out;
}

/// `_jxr_4x4OverlapFilter` on 16 samples in raster order of a 4×4 window.
fn post4x4(p: &mut [i32], i: [usize; 16]) {
    let [a, b, c, d, e, f, g, h, ii, j, k, l, m, n, o, pp] = i;
    let z = Wrapping(0);
    on(p, [a, d, m, pp], |v| t2x2h(v, z));
    on(p, [b, c, n, o], |v| t2x2h(v, z));
    on(p, [e, h, ii, l], |v| t2x2h(v, z));
    on(p, [f, g, j, k], |v| t2x2h(v, z));
    on(p, [n, m], inv_rotate);
    on(p, [j, ii], inv_rotate);
    on(p, [h, d], inv_rotate);
    on(p, [g, c], inv_rotate);
    on(p, [k, l, o, pp], inv_t_odd_odd_post);
    on(p, [a, pp], inv_scale);
    on(p, [b, o], inv_scale);
    on(p, [e, l], inv_scale);
    on(p, [f, k], inv_scale);
    on(p, [a, d, m, pp], t2x2h_post);
    on(p, [b, c, n, o], t2x2h_post);
    on(p, [e, h, ii, l], t2x2h_post);
    on(p, [f, g, j, k], t2x2h_post);
}

/// `_jxr_4x4PreFilter`: the inverse of [`post4x4`].
fn pre4x4(p: &mut [i32], i: [usize; 16]) {
    let [a, b, c, d, e, f, g, h, ii, j, k, l, m, n, o, pp] = i;
    let z = Wrapping(0);
    on(p, [a, d, m, pp], t2x2h_enc);
    on(p, [b, c, n, o], t2x2h_enc);
    on(p, [e, h, ii, l], t2x2h_enc);
    on(p, [f, g, j, k], t2x2h_enc);
    on(p, [a, pp], fwd_scale);
    on(p, [b, o], fwd_scale);
    on(p, [e, l], fwd_scale);
    on(p, [f, k], fwd_scale);
    on(p, [n, m], fwd_rotate);
    on(p, [j, ii], fwd_rotate);
    on(p, [h, d], fwd_rotate);
    on(p, [g, c], fwd_rotate);
    on(p, [k, l, o, pp], fwd_t_odd_odd_pre);
    on(p, [a, m, d, pp], |v| t2x2h(v, z));
    on(p, [b, c, n, o], |v| t2x2h(v, z));
    on(p, [e, h, ii, l], |v| t2x2h(v, z));
    on(p, [f, g, j, k], |v| t2x2h(v, z));
}

/// `_jxr_4OverlapFilter`: the 4-point POT across a seam along an edge (and on corners).
fn post4(p: &mut [i32], i: [usize; 4]) {
    let [mut a, mut b, mut c, mut d] = load(p, i);
    a += d;
    b += c;
    d -= (a + W1) >> 1;
    c -= (b + W1) >> 1;
    [a, d] = inv_scale([a, d]);
    [b, c] = inv_scale([b, c]);
    a += (d * W3 + W4) >> 3;
    b += (c * W3 + W4) >> 3;
    d -= a >> 1;
    c -= b >> 1;
    a += d;
    b += c;
    d = -d;
    c = -c;
    [c, d] = inv_rotate([c, d]);
    d += (a + W1) >> 1;
    c += (b + W1) >> 1;
    a -= d;
    b -= c;
    store(p, i, [a, b, c, d]);
}

/// `_jxr_4PreFilter`: the inverse of [`post4`].
fn pre4(p: &mut [i32], i: [usize; 4]) {
    let [mut a, mut b, mut c, mut d] = load(p, i);
    a += d;
    b += c;
    d -= (a + W1) >> 1;
    c -= (b + W1) >> 1;
    [c, d] = fwd_rotate([c, d]);
    d = -d;
    c = -c;
    a -= d;
    b -= c;
    d += a >> 1;
    c += b >> 1;
    a -= (d * W3 + W4) >> 3;
    b -= (c * W3 + W4) >> 3;
    [a, d] = fwd_scale([a, d]);
    [b, c] = fwd_scale([b, c]);
    d += (a + W1) >> 1;
    c += (b + W1) >> 1;
    a -= d;
    b -= c;
    store(p, i, [a, b, c, d]);
}

/// `_jxr_2x2OverlapFilter`: the chroma DC-domain POT on a 2×2 window.
fn post2x2(p: &mut [i32], i: [usize; 4]) {
    let [mut a, mut b, mut c, mut d] = load(p, i);
    a += d;
    b += c;
    d -= (a + W1) >> 1;
    c -= (b + W1) >> 1;
    b += (a + W2) >> 2;
    a += (b + W1) >> 1;
    a += b >> 5;
    a += b >> 9;
    a += b >> 13;
    b += (a + W2) >> 2;
    d += (a + W1) >> 1;
    c += (b + W1) >> 1;
    a -= d;
    b -= c;
    store(p, i, [a, b, c, d]);
}

/// `_jxr_2x2PreFilter`: the inverse of [`post2x2`].
fn pre2x2(p: &mut [i32], i: [usize; 4]) {
    let [mut a, mut b, mut c, mut d] = load(p, i);
    a += d;
    b += c;
    d -= (a + W1) >> 1;
    c -= (b + W1) >> 1;
    b -= (a + W2) >> 2;
    a -= b >> 5;
    a -= b >> 9;
    a -= b >> 13;
    a -= (b + W1) >> 1;
    b -= (a + W2) >> 2;
    d += (a + W1) >> 1;
    c += (b + W1) >> 1;
    a -= d;
    b -= c;
    store(p, i, [a, b, c, d]);
}

/// `_jxr_2OverlapFilter`: the chroma DC-domain POT across a seam along an edge.
fn post2(p: &mut [i32], i: [usize; 2]) {
    let [mut a, mut b] = load(p, i);
    b += (a + W2) >> 2;
    a += (b + W1) >> 1;
    a += b >> 5;
    a += b >> 9;
    a += b >> 13;
    b += (a + W2) >> 2;
    store(p, i, [a, b]);
}

/// `_jxr_2PreFilter`: the inverse of [`post2`].
fn pre2(p: &mut [i32], i: [usize; 2]) {
    let [mut a, mut b] = load(p, i);
    b -= (a + W2) >> 2;
    a -= b >> 13;
    a -= b >> 9;
    a -= b >> 5;
    a -= (b + W1) >> 1;
    b -= (a + W2) >> 2;
    store(p, i, [a, b]);
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
#[derive(Clone, Copy, PartialEq, Eq)]
enum Dir {
    Inverse,
    Forward,
}

/// The pitch-4 POT pattern (4×4 interior windows, 4-point edge seams, 2×2 corners) on `r`.
fn pot4_region(p: &mut [i32], stride: usize, r: Rect, dir: Dir) {
    let at = |x: usize, y: usize| y * stride + x;
    let f4 = |p: &mut [i32], i: [usize; 4]| if dir == Dir::Inverse { post4(p, i) } else { pre4(p, i) };
    let f16 = |p: &mut [i32], i: [usize; 16]| if dir == Dir::Inverse { post4x4(p, i) } else { pre4x4(p, i) };
    // Interior windows, row by row (each row of windows touches rows y-2..y+2 only).
    for y in (r.y0 + 4..r.y1).step_by(4) {
        for x in (r.x0 + 4..r.x1).step_by(4) {
            let i: [usize; 16] = std::array::from_fn(|k| at(x - 2 + k % 4, y - 2 + k / 4));
            f16(p, i);
        }
    }
    // Seams along the top and bottom edges (two rows each) and the left and right edges.
    for x in (r.x0 + 4..r.x1).step_by(4) {
        for y in [r.y0, r.y0 + 1, r.y1 - 2, r.y1 - 1] {
            f4(p, [at(x - 2, y), at(x - 1, y), at(x, y), at(x + 1, y)]);
        }
    }
    for y in (r.y0 + 4..r.y1).step_by(4) {
        for x in [r.x0, r.x0 + 1, r.x1 - 2, r.x1 - 1] {
            f4(p, [at(x, y - 2), at(x, y - 1), at(x, y), at(x, y + 1)]);
        }
    }
    // The corners.
    for (x, y) in [(r.x0, r.y0), (r.x1 - 2, r.y0), (r.x0, r.y1 - 2), (r.x1 - 2, r.y1 - 2)] {
        f4(p, [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)]);
    }
}

/// The pitch-2 POT of 4:2:0 and 4:2:2 chroma DC planes on `r` (T.835
/// `overlap_level1_up2_420/422`): 2×2 windows at interior grid corners, 2-point seams along
/// the outermost rows and columns, and corners kept as differences from their neighbour
/// while the filters run (jxrlib `COMPUTE_CORNER_PRED_DIFF/ADD`).
fn pot2_region(p: &mut [i32], stride: usize, r: Rect, dir: Dir) {
    let at = |x: usize, y: usize| y * stride + x;
    // Corner, neighbour; in T.835's order (top-left, top-right, bottom-left, bottom-right).
    let corners = [
        (at(r.x0, r.y0), at(r.x0 + 1, r.y0)),
        (at(r.x1 - 1, r.y0), at(r.x1 - 2, r.y0)),
        (at(r.x0, r.y1 - 1), at(r.x0 + 1, r.y1 - 1)),
        (at(r.x1 - 1, r.y1 - 1), at(r.x1 - 2, r.y1 - 1)),
    ];
    let filters = |p: &mut [i32]| {
        let f2 = |p: &mut [i32], i: [usize; 2]| if dir == Dir::Inverse { post2(p, i) } else { pre2(p, i) };
        let f4 = |p: &mut [i32], i: [usize; 4]| if dir == Dir::Inverse { post2x2(p, i) } else { pre2x2(p, i) };
        for y in (r.y0 + 2..r.y1).step_by(2) {
            for x in (r.x0 + 2..r.x1).step_by(2) {
                f4(p, [at(x - 1, y - 1), at(x, y - 1), at(x - 1, y), at(x, y)]);
            }
        }
        for x in (r.x0 + 2..r.x1).step_by(2) {
            for y in [r.y0, r.y1 - 1] {
                f2(p, [at(x - 1, y), at(x, y)]);
            }
        }
        for y in (r.y0 + 2..r.y1).step_by(2) {
            for x in [r.x0, r.x1 - 1] {
                f2(p, [at(x, y - 1), at(x, y)]);
            }
        }
    };
    match dir {
        Dir::Inverse => {
            for &(c, n) in &corners {
                p[c] = p[c].wrapping_sub(p[n]);
            }
            filters(p);
            for &(c, n) in &corners {
                p[c] = p[c].wrapping_add(p[n]);
            }
        }
        Dir::Forward => {
            for &(c, n) in corners.iter().rev() {
                p[c] = p[c].wrapping_sub(p[n]);
            }
            filters(p);
            for &(c, n) in corners.iter().rev() {
                p[c] = p[c].wrapping_add(p[n]);
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Stage 2: DC and LP of a macroblock to (or from) its block DCs.

/// The stage-2 inverse PCT of one macroblock: `c` (DC, LP...) to the block DCs in raster order
/// of the macroblock's blocks (16, 4 or 8 values in `out`).
fn stage2_inverse(kind: PlaneKind, double: bool, c: &MbCoeffs, out: &mut [i32; 16]) {
    let n = match kind {
        PlaneKind::Full => {
            out.copy_from_slice(&c[DC..=lp(15)]);
            ipct4x4(out);
            16
        }
        PlaneKind::Chroma420 => {
            out[..4].copy_from_slice(&c[DC..=lp(3)]);
            on(out, [0, 1, 2, 3], |v| t2x2h(v, Wrapping(0)));
            out.swap(1, 2);
            4
        }
        PlaneKind::Chroma422 => {
            out[..8].copy_from_slice(&c[DC..=lp(7)]);
            // _jxr_2ptT on DC and LP4, then two 2×2 transforms.
            on(out, [0, 4], |[mut a, mut b]| {
                a -= (b + W1) >> 1;
                b += a;
                [a, b]
            });
            on(out, [0, 1, 2, 3], |v| t2x2h(v, Wrapping(0)));
            on(out, [4, 5, 6, 7], |v| t2x2h(v, Wrapping(0)));
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
            on(&mut v, [0, 1, 2, 3], |x| t2x2h(x, Wrapping(0)));
        }
        PlaneKind::Chroma422 => {
            v.swap(1, 2);
            v.swap(5, 6);
            on(&mut v, [0, 1, 2, 3], |x| t2x2h(x, Wrapping(0)));
            on(&mut v, [4, 5, 6, 7], |x| t2x2h(x, Wrapping(0)));
            // _jxr_2ptFwdT.
            on(&mut v, [0, 4], |[mut a, mut b]| {
                b -= a;
                a += (b + W1) >> 1;
                [a, b]
            });
        }
    }
    c[DC..DC + n].copy_from_slice(&v[..n]);
}

// ---------------------------------------------------------------------------------------------
// Whole planes.

fn check_geometry(kind: PlaneKind, mb_w: usize, mb_h: usize, n: usize) -> Result<(usize, usize)> {
    if mb_w == 0 || mb_h == 0 {
        return Err(Error::invalid("an image of no macroblocks"));
    }
    let mbs = mb_w.checked_mul(mb_h).ok_or_else(|| Error::limit("macroblock count overflows"))?;
    if n != mbs {
        return Err(Error::invalid(format!("{n} macroblocks given for a {mb_w}×{mb_h} grid")));
    }
    let (bx, by) = kind.blocks();
    Ok((mb_w * bx * 4, mb_h * by * 4))
}

/// The inverse lapped transform of one channel.
///
/// `coeffs` holds the channel's macroblocks in raster order over the extended image
/// (`mb_w × mb_h`), each dequantized and predicted in the [`crate::mb`] layout: `[0]` DC,
/// `[1..16]` LP 1..15 (4:2:0 chroma: LP 1..3; 4:2:2 chroma: LP 1..7), `[16 + 15·b + k − 1]`
/// HP `k` of block `b`, blocks numbered in raster order inside the macroblock (`b = 4·by + bx`
/// for full planes, `2·by + bx` for 4:2:0 and 4:2:2 chroma). `channel` is the channel's index
/// (channels after the first are doubled after stage 2 in scaled arithmetic).
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
    let (width, height) = check_geometry(kind, mb_w, mb_h, coeffs.len())?;
    let (bx, by) = kind.blocks();
    let double = params.scaled && channel > 0;

    // Stage 2: the DC plane, bx·mb_w × by·mb_h.
    let (dw, dh) = (bx * mb_w, by * mb_h);
    let mut dc = vec![0i32; dw * dh];
    let mut v = [0i32; 16];
    for (m, c) in coeffs.iter().enumerate() {
        let (mx, my) = (m % mb_w, m / mb_w);
        stage2_inverse(kind, double, c, &mut v);
        for j in 0..by {
            let row = (my * by + j) * dw + mx * bx;
            dc[row..row + bx].copy_from_slice(&v[j * bx..(j + 1) * bx]);
        }
    }
    if params.overlap == OverlapMode::Two {
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx, by) {
            match kind {
                PlaneKind::Full => pot4_region(&mut dc, dw, r, Dir::Inverse),
                _ => pot2_region(&mut dc, dw, r, Dir::Inverse),
            }
        }
    }

    // Stage 1: every block's DC and HP to samples.
    let mut data = vec![0i32; width * height];
    for (m, c) in coeffs.iter().enumerate() {
        let (mx, my) = (m % mb_w, m / mb_w);
        for b in 0..bx * by {
            let (x, y) = (mx * bx + b % bx, my * by + b / bx);
            let mut t = [0i32; 16];
            t[0] = dc[y * dw + x];
            t[1..].copy_from_slice(&c[hp(b, 1)..=hp(b, 15)]);
            ipct4x4(&mut t);
            for j in 0..4 {
                let row = (y * 4 + j) * width + x * 4;
                data[row..row + 4].copy_from_slice(&t[j * 4..j * 4 + 4]);
            }
        }
    }
    if params.overlap != OverlapMode::None {
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx * 4, by * 4) {
            pot4_region(&mut data, width, r, Dir::Inverse);
        }
    }
    Ok(Plane { width, height, data })
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
    plane: &Plane,
) -> Result<Vec<MbCoeffs>> {
    let (bx, by) = kind.blocks();
    let (width, height) = (mb_w * bx * 4, mb_h * by * 4);
    if mb_w == 0 || mb_h == 0 || plane.width != width || plane.height != height || plane.data.len() != width * height {
        return Err(Error::invalid("plane size does not match the macroblock grid"));
    }
    let double = params.scaled && channel > 0;
    let mut data = plane.data.clone();
    if params.overlap != OverlapMode::None {
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx * 4, by * 4) {
            pot4_region(&mut data, width, r, Dir::Forward);
        }
    }
    let (dw, dh) = (bx * mb_w, by * mb_h);
    let mut dc = vec![0i32; dw * dh];
    let mut coeffs = vec![[0i32; MB_COEFFS]; mb_w * mb_h];
    for (m, c) in coeffs.iter_mut().enumerate() {
        let (mx, my) = (m % mb_w, m / mb_w);
        for b in 0..bx * by {
            let (x, y) = (mx * bx + b % bx, my * by + b / bx);
            let mut t = [0i32; 16];
            for j in 0..4 {
                let row = (y * 4 + j) * width + x * 4;
                t[j * 4..j * 4 + 4].copy_from_slice(&data[row..row + 4]);
            }
            pct4x4(&mut t);
            dc[y * dw + x] = t[0];
            c[hp(b, 1)..=hp(b, 15)].copy_from_slice(&t[1..]);
        }
    }
    if params.overlap == OverlapMode::Two {
        for r in regions(params.hard.as_ref(), mb_w, mb_h, bx, by) {
            match kind {
                PlaneKind::Full => pot4_region(&mut dc, dw, r, Dir::Forward),
                _ => pot2_region(&mut dc, dw, r, Dir::Forward),
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
    Ok(coeffs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift).
    fn rng(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    /// Random samples of about `bits` bits, signed.
    fn sample(r: &mut impl FnMut() -> u64, bits: u32) -> i32 {
        (r() as i32) >> (32 - bits)
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
                pre4x4(&mut v, idx16);
                post4x4(&mut v, idx16);
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
        let grids = [(1, 1), (1, 3), (3, 1), (2, 2), (3, 2), (5, 3)];
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
                            let params = TransformParams { overlap, scaled: false, hard: hard.clone() };
                            let plane = random_plane(&mut r, kind, mb_w, mb_h, bits);
                            let coeffs = forward_plane(&params, kind, 1, mb_w, mb_h, &plane).unwrap();
                            let back = inverse_plane(&params, kind, 1, mb_w, mb_h, &coeffs).unwrap();
                            assert_eq!(back, plane, "{kind:?} {overlap:?} {hard:?} {mb_w}x{mb_h}");
                            // And the coefficients survive the other way round.
                            let again = forward_plane(&params, kind, 1, mb_w, mb_h, &back).unwrap();
                            assert_eq!(again, coeffs);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn scaled_chroma_doubles_the_block_dcs() {
        // With DC and LP only, a scaled chroma channel decodes to twice the unscaled stage-2
        // output; channel 0 is not doubled.
        let params = |scaled| TransformParams { overlap: OverlapMode::None, scaled, hard: None };
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
        };
        let soft = TransformParams { hard: None, ..hard.clone() };
        for params in [&hard, &soft] {
            let mut c = forward_plane(params, PlaneKind::Full, 0, 4, 2, &plane).unwrap();
            let before = inverse_plane(params, PlaneKind::Full, 0, 4, 2, &c).unwrap();
            c[1][0] += 1000; // DC of MB (1, 0), left of the edge
            let after = inverse_plane(params, PlaneKind::Full, 0, 4, 2, &c).unwrap();
            let right_changed = (0..32).any(|y| (32..64).any(|x| before.data[y * 64 + x] != after.data[y * 64 + x]));
            assert_eq!(right_changed, params.hard.is_none(), "{params:?}");
        }
        // Overlap mode 0: a coefficient touches only its own macroblock.
        let none = TransformParams { overlap: OverlapMode::None, scaled: false, hard: None };
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
        let p = TransformParams { overlap: OverlapMode::One, scaled: false, hard: None };
        assert!(inverse_plane(&p, PlaneKind::Full, 0, 2, 2, &[[0; MB_COEFFS]; 3]).is_err());
        assert!(inverse_plane(&p, PlaneKind::Full, 0, 0, 2, &[]).is_err());
        let plane = Plane { width: 16, height: 16, data: vec![0; 256] };
        assert!(forward_plane(&p, PlaneKind::Full, 0, 2, 1, &plane).is_err());
        // Extreme coefficients wrap rather than panic.
        let mut c = [i32::MAX; MB_COEFFS];
        c[5] = i32::MIN;
        for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
            for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
                let p = TransformParams { overlap, scaled: true, hard: None };
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
        /// A second expected image (hard tiles: jxrlib's, after T.835's in `expected`).
        expected_jxrlib: Option<Vec<i32>>,
    }

    fn fixture(name: &str) -> Fixture {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata/t835").join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        let h: Vec<usize> = lines.next().unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect();
        let rows: Vec<Vec<i32>> = lines.map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect()).collect();
        let n = h[0] * h[1];
        let images = if (rows.len() - 1) % n == 0 { 1 } else { 2 };
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
            expected_jxrlib: expected.get(1).cloned(),
        }
    }

    /// The inverse transform reproduces T.835's and jxrlib's decoded 8-bit grey images
    /// exactly (lossless and QP 30; overlap 0, 1 and 2), formatted as BD8 output does.
    #[test]
    fn matches_t835_on_grey_streams() {
        for name in ["gray_g_l0", "gray_g_l1", "gray_g_l2", "gray_gq_l0", "gray_gq_l1", "gray_gq_l2"] {
            let f = fixture(&format!("{name}.txt"));
            let params = TransformParams { overlap: f.overlap, scaled: f.scaled, hard: None };
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
        use crate::output::{upsample_chroma_row, InternalColorFormat, OutputParams};
        let rgb = PIXEL_FORMATS.iter().find(|f| f.name == "24bppRGB").unwrap();
        for name in ["rgb_c_d1_l1", "rgb_c_d1_l2", "rgb_c_d2_l1", "rgb_c_d2_l2", "rgb_c_d3_l1", "rgb_c_d3_l2"] {
            let f = fixture(&format!("{name}.txt"));
            let (kind, internal) = match &name[6..8] {
                "d1" => (PlaneKind::Chroma420, InternalColorFormat::Yuv420),
                "d2" => (PlaneKind::Chroma422, InternalColorFormat::Yuv422),
                _ => (PlaneKind::Full, InternalColorFormat::Yuv444),
            };
            let params = TransformParams { overlap: f.overlap, scaled: f.scaled, hard: None };
            let planes: Vec<Plane> = (0..3)
                .map(|ch| {
                    let k = if ch == 0 { PlaneKind::Full } else { kind };
                    inverse_plane(&params, k, ch, f.mb_w, f.mb_h, &f.channels[ch]).unwrap()
                })
                .collect();
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
            let ext_w = planes[0].width;
            let mut got = Vec::new();
            let (mut u, mut v) = (vec![0; ext_w], vec![0; ext_w]);
            for y in 0..f.height {
                let c = &planes[1];
                upsample_chroma_row(internal, &c.data, c.width, c.height, y, &mut u).unwrap();
                upsample_chroma_row(internal, &planes[2].data, c.width, c.height, y, &mut v).unwrap();
                let yrow = &planes[0].data[y * ext_w..(y + 1) * ext_w];
                let mut row = vec![0u8; out.row_bytes(f.width)];
                out.format_row(&[yrow, &u, &v], None, f.width, &mut row).unwrap();
                got.extend(row.into_iter().map(i32::from));
            }
            assert_eq!(got.len(), f.expected.len());
            let diff = got.iter().zip(&f.expected).filter(|(a, b)| a != b).count();
            assert_eq!(diff, 0, "{name}: {diff} of {} samples differ", got.len());
        }
    }

    /// Hard tiles on a non-square grid (a 4×3-macroblock grey image, tile columns at MB 0, 1,
    /// 2 and rows at 0, 1, QP 30, overlap 2, written by T.835 `-h -U 2:3`): T.832's seams
    /// reproduce T.835's output, the swapped seams of JXR-NOTES §8 quirk 1 reproduce
    /// JxrDecApp's (which differs from T.835 on 1805 of 3072 samples).
    #[test]
    fn hard_tiles_match_t835_and_jxrlib() {
        let f = fixture("hard_gray.txt");
        for (swap, expected) in [(false, &f.expected), (true, f.expected_jxrlib.as_ref().unwrap())] {
            let hard = HardEdges::from_tiles(&[0, 1, 2], &[0, 1], swap);
            let params = TransformParams { overlap: f.overlap, scaled: f.scaled, hard: Some(hard) };
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
}
