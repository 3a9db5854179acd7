//! The inverse lapped transform of HD Photo 1.0 codestreams (sub-version 0, the `.wdp`/`.hdp`
//! files of Vista-era WIC), as jxrlib decodes them (its `invTransformMacroblock`; JXR-NOTES
//! §6). JPEG XR changed the overlap operators when it was standardised; jxrlib kept the old
//! ones for sub-version 0 and picks the set by that nibble alone: everything else (entropy
//! coding, prediction, quantization, output formatting) is shared.
//!
//! What is the same as JPEG XR: both PCT stages (and the chroma stage-2 transforms and the
//! doubling in scaled arithmetic), where the POT windows and seams lie, the 2×2 butterflies,
//! rotations and odd-odd step inside the 4×4 window. What differs:
//!
//! - **the 4×4 window's scaling step** lacks the two small correction terms JPEG XR added
//!   (`+a/128 − a/1024` on the second output);
//! - **the 4-point seam operator** along image edges is a different lifting network (the
//!   rotation of the differences first, then three lifting steps of about −29/32, 3/16 and
//!   3/32 between each pair's sum and difference, where JPEG XR scales with its 2-point
//!   scaling step);
//! - **the chroma 2-point and 2×2 operators** (DC planes of 4:2:0 and 4:2:2) use a coarser
//!   rotation (1/8, 1/4, 1/8 instead of JPEG XR's 1/4, 1/2 + 1/32 + …, 1/4);
//! - **no corner operators**: the 2×2 samples at each image corner are left alone, and 4:2:0 /
//!   4:2:2 chroma corners are not predicted from their neighbours;
//! - **a DC-leakage clamp** after each interior stage-1 window (not in stage 2, not on seams).
//!   Read as: without JPEG XR's scaling corrections, a small share (595/2^17 of half the
//!   sum, about 27/5947) of each group of four samples' mean leaks into the group's
//!   checkerboard component; when the HP band cannot have coded a correction (it is absent,
//!   or its step exceeds 20 and the estimated leak is below one step), jxrlib takes the
//!   estimate out again, clipped so that it never exceeds the checkerboard component itself.
//! - **no hard tiles**: jxrlib reads hard tiling only from sub-version 9, so a sub-version 0
//!   stream always filters across tile edges.
//!
//! The clamp compares with an HP quantizer step. jxrlib takes it from the macroblock it has
//! just decoded when it runs the window (the transform trails decoding by a macroblock), and
//! for 4:2:0 and 4:2:2 chroma from the wrong channel: U looks at luma's HP step, V at U's
//! (`pQuantizerHP[i]` with `i` counting chroma planes from 0). [`DcLeakage`] carries the step
//! of each channel with that shift already applied. With image-uniform HP quantizers (what
//! every known encoder writes) the macroblock does not matter; otherwise it holds the steps of
//! every macroblock, from a first entropy-decoding pass, and each stage-1 window looks up the
//! macroblock jxrlib has just decoded when it runs that window (`Stage1::window`).

use super::{inv_rotate, inv_t_odd_odd_post, ipct4x4_g};
use super::{stage2_band, t2x2h, t2x2h_post, BandRequest, BandScratch, Lane, OverlapMode, PlaneKind, Rect, Rows};
use super::{StageTwo, S};
use crate::header::{ClrFmt, Codestream, PlaneHeader, QpSource};
use crate::mb::hp;
use hdrcodec_core::{DecodeOptions, Error, Result};
use std::ops::RangeInclusive;
use std::sync::Arc;

/// What the DC-leakage clamp of one plane needs (module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DcLeakage {
    /// The plane has no HP band (BANDS_PRESENT NOHIGHPASS or DCONLY): the clamp runs in every
    /// interior stage-1 window.
    pub hp_absent: bool,
    /// Per channel index, the HP quantizer step the clamp compares with (jxrlib's, including
    /// its chroma shift for 4:2:0 and 4:2:2), when the HP quantizers are image-uniform.
    pub hp_step: Vec<i32>,
    /// Otherwise the same per macroblock: `channels` steps for each macroblock, in raster
    /// order (with the chroma shift applied).
    pub per_mb: Option<Arc<[i32]>>,
    /// Channels of the plane (the stride of `per_mb`).
    pub channels: usize,
}

/// The channel whose HP step jxrlib's clamp of channel `ch` reads (module docs).
fn step_source(fmt: ClrFmt, ch: usize) -> usize {
    match fmt {
        ClrFmt::Yuv420 | ClrFmt::Yuv422 => ch.saturating_sub(1),
        _ => ch,
    }
}

impl DcLeakage {
    /// The clamp's parameters for plane `plane` (0 primary, 1 interleaved alpha) of the
    /// sub-version 0 codestream `data` (headers `cs`). With HP quantizers set per tile, this
    /// entropy-decodes the codestream once more to learn every macroblock's step (the map's
    /// size checked against `options.limits`).
    pub fn for_codestream(cs: &Codestream, data: &[u8], plane: usize, options: &DecodeOptions) -> Result<Self> {
        let hdr = match plane {
            0 => &cs.primary,
            _ => cs.alpha.as_ref().ok_or_else(|| Error::invalid("JPEG XR: no alpha plane (a bug)"))?,
        };
        let channels = hdr.channels;
        let hp_absent = !hdr.bands.has_hp();
        let mut leak = DcLeakage { hp_absent, hp_step: Vec::new(), per_mb: None, channels };
        match (hp_absent, hdr.hp) {
            (true, _) => {}
            (false, QpSource::Uniform(set)) => {
                leak.hp_step = (0..channels)
                    .map(|ch| crate::quant::step(set.index[step_source(hdr.clr_fmt, ch)], hdr.scaled, true))
                    .collect();
            }
            (false, QpSource::PerTile) => leak.per_mb = Some(per_mb_steps(cs, data, plane, hdr, options)?),
        }
        Ok(leak)
    }

    /// The step the clamp of channel `ch` compares with in the window jxrlib runs at its
    /// position (`x`, `y`) (0 ..= `mb_w`, 0 ..= `mb_h`: one step past each edge). 255 without
    /// HP, as in jxrlib, where it is never read.
    fn step(&self, ch: usize, x: usize, y: usize, mb_w: usize, mb_h: usize) -> i32 {
        if self.hp_absent {
            return 255;
        }
        let Some(map) = &self.per_mb else { return self.hp_step.get(ch).copied().unwrap_or(255) };
        // jxrlib reads the macroblock it decoded last: at the extra column, the row's last;
        // on the extra row, the image's last.
        let mb = if y < mb_h { y * mb_w + x.min(mb_w - 1) } else { mb_w * mb_h - 1 };
        map.get(mb * self.channels + ch).copied().unwrap_or(255)
    }
}

/// Every macroblock's HP steps of plane `plane` (channels inner, with the chroma shift), by
/// entropy-decoding every tile.
fn per_mb_steps(
    cs: &Codestream,
    data: &[u8],
    plane: usize,
    hdr: &PlaneHeader,
    options: &DecodeOptions,
) -> Result<Arc<[i32]>> {
    let (mb_w, mb_h) = (cs.image.mb_width as usize, cs.image.mb_height as usize);
    let n = mb_w * mb_h * hdr.channels;
    let _charge = options.limits.charge(n as u64 * 4, "the HD Photo HP quantizer map")?;
    let mut map = vec![0i32; n];
    let strides: Vec<usize> =
        std::iter::once(&cs.primary).chain(cs.alpha.as_ref()).map(|p| p.channels * crate::mb::MB_COEFFS).collect();
    let mut steps = Vec::new();
    for ty in 0..cs.image.tile_heights.len() {
        for tx in 0..cs.image.tile_widths.len() {
            let (x0, y0, w, h) = crate::tiles::tile_rect(cs, tx, ty);
            let (x0, y0, w) = (x0 as usize, y0 as usize, w as usize);
            let mut tile = crate::tiles::TileDecoder::new(cs, data.into(), tx, ty)?;
            let mut bufs: Vec<Vec<i32>> = strides.iter().map(|s| vec![0; w * s]).collect();
            for r in 0..h as usize {
                let mut rows: Vec<&mut [i32]> = bufs.iter_mut().map(|b| &mut b[..]).collect();
                tile.next_row(&mut rows)?;
                steps.clear();
                tile.last_row_hp_steps(plane, &mut steps)?;
                let c = hdr.channels;
                let row = map
                    .get_mut(((y0 + r) * mb_w + x0) * c..((y0 + r) * mb_w + x0 + w) * c)
                    .ok_or_else(|| Error::invalid("JPEG XR: tiles outside the image"))?;
                for (dst, src) in row.chunks_exact_mut(c).zip(steps.chunks_exact(c)) {
                    for (ch, d) in dst.iter_mut().enumerate() {
                        *d = src[step_source(hdr.clr_fmt, ch)];
                    }
                }
            }
        }
    }
    Ok(map.into())
}

// ---------------------------------------------------------------------------------------------
// The operators that differ from JPEG XR's.

/// The scaling step inside the 4×4 window (HD Photo's: without JPEG XR's `a >> 7` and
/// `a >> 10` corrections on the second value).
#[inline(always)]
fn scale_hdp<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    a += b;
    b = (a >> 1) - b;
    a += (b * 3) >> 3;
    b += (a * 3) >> 4;
    [a, b]
}

/// The 4×4 POT window (raster order), as JPEG XR's [`super::post4x4_g`] but with
/// [`scale_hdp`].
#[inline(always)]
fn post4x4_hdp<T: Lane>(x: [T; 16]) -> [T; 16] {
    let mut x = x;
    // The four groups of samples symmetric about the window's centre.
    for g in GROUPS {
        ap!(&mut x, g, |v| t2x2h(v, 0));
    }
    ap!(&mut x, [13, 12], inv_rotate);
    ap!(&mut x, [9, 8], inv_rotate);
    ap!(&mut x, [7, 3], inv_rotate);
    ap!(&mut x, [6, 2], inv_rotate);
    ap!(&mut x, [10, 11, 14, 15], inv_t_odd_odd_post);
    ap!(&mut x, [0, 15], scale_hdp);
    ap!(&mut x, [1, 14], scale_hdp);
    ap!(&mut x, [4, 11], scale_hdp);
    ap!(&mut x, [5, 10], scale_hdp);
    for g in GROUPS {
        ap!(&mut x, g, t2x2h_post);
    }
    x
}

/// The window's samples in groups of four: a position of the window's top-left quadrant and
/// its mirror images, as (top-left, top-right, bottom-left, bottom-right), the order the
/// butterflies take them in (a, b, c, d).
const GROUPS: [[usize; 4]; 4] = [[0, 3, 12, 15], [1, 2, 13, 14], [4, 7, 8, 11], [5, 6, 9, 10]];

/// The DC-leakage clamp on a stage-1 window that [`post4x4_hdp`] has filtered, with the HP
/// step `qp` (module docs). Per group (a, b, c, d): half the group's sum times 595/2^17
/// (≈ 27/5947) estimates the leak, half the checkerboard a − b − c + d bounds it; half the
/// clipped estimate comes off a and d and goes to b and c (the group's sum is kept).
#[inline(always)]
fn clamp_dc_leakage(x: &mut [S; 16], qp: i32, hp_absent: bool) {
    for [a, b, c, d] in GROUPS {
        let sum = (x[a] + x[b] + x[c] + x[d]).0 >> 1;
        let est = sum.wrapping_mul(595).wrapping_add(65536) >> 17;
        // C's abs of i32::MIN is i32::MIN (below any step): wrapping_abs agrees.
        if !(hp_absent || (est.wrapping_abs() < qp && qp > 20)) {
            continue;
        }
        let bound = (x[a] - x[b] - x[c] + x[d]).0 >> 1;
        let clipped = match (est > 0, est < 0) {
            (true, _) if bound > 0 => est.min(bound),
            (_, true) if bound < 0 => est.max(bound),
            _ => 0,
        };
        let h = S(clipped >> 1);
        x[a] -= h;
        x[d] -= h;
        x[b] += h;
        x[c] += h;
    }
}

/// The 4-point operator across a seam along an image edge, samples in order across it
/// (two before, two after). Lifting: a butterfly of the outer and inner pairs, a rotation of
/// the two differences, the butterfly undone, then three lifting steps between the outer
/// (inner) pair's two samples: −(1 − 3/32), +3/16, +3/32.
#[inline(always)]
fn post4_hdp<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    [c, d] = inv_rotate([c, d]);
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d - ((d * 3 + 16) >> 5);
    b -= c - ((c * 3 + 16) >> 5);
    d += (a * 3 + 8) >> 4;
    c += (b * 3 + 8) >> 4;
    a += (d * 3 + 16) >> 5;
    b += (c * 3 + 16) >> 5;
    [a, b, c, d]
}

/// The rotation of HD Photo's chroma DC-plane operators: 1/8, 1/4, 1/8 lifting steps.
#[inline(always)]
fn rotate2_hdp<T: Lane>([mut a, mut b]: [T; 2]) -> [T; 2] {
    b += (a + 4) >> 3;
    a += (b + 2) >> 2;
    b += (a + 4) >> 3;
    [a, b]
}

/// The 2-point operator across a chroma DC-plane seam along an image edge.
#[inline(always)]
fn post2_hdp<T: Lane>(v: [T; 2]) -> [T; 2] {
    rotate2_hdp(v)
}

/// The 2×2 chroma DC-plane window (top-left, top-right, bottom-left, bottom-right): a
/// butterfly, the rotation of the sums, the butterfly undone.
#[inline(always)]
fn post2x2_hdp<T: Lane>([mut a, mut b, mut c, mut d]: [T; 4]) -> [T; 4] {
    a += d;
    b += c;
    d -= (a + 1) >> 1;
    c -= (b + 1) >> 1;
    b += (a + 2) >> 2;
    a += (b + 1) >> 1;
    b += (a + 2) >> 2;
    d += (a + 1) >> 1;
    c += (b + 1) >> 1;
    a -= d;
    b -= c;
    [a, b, c, d]
}

// ---------------------------------------------------------------------------------------------
// The POT pattern without corners.

/// The operators of one POT stage: the window at an interior grid corner, the seam operator
/// along the edges.
trait Pattern {
    /// Grid pitch: 4 (4×4 windows, 4-point seams) or 2 (2×2, 2-point).
    const PITCH: usize;
    /// The window centred on grid corner (`x`, `y`) (plane samples), its samples at `i`.
    fn window(&self, p: &mut [i32], i: &[usize], x: usize, y: usize);
    fn seam(&self, p: &mut [i32], i: &[usize]);
}

/// Gathers `p[i]` into an array, runs `f`, scatters back.
#[inline(always)]
fn on_slice<const N: usize>(p: &mut [i32], i: &[usize], f: impl Fn([S; N]) -> [S; N]) {
    let idx: [usize; N] = std::array::from_fn(|k| i[k]);
    let v = f(idx.map(|k| S(p[k])));
    for (k, s) in idx.into_iter().zip(v) {
        p[k] = s.0;
    }
}

/// Stage 2 of a full plane: 4×4 windows and 4-point seams on the DC plane, no clamp.
struct Stage2Full;
impl Pattern for Stage2Full {
    const PITCH: usize = 4;
    fn window(&self, p: &mut [i32], i: &[usize], _: usize, _: usize) {
        on_slice::<16>(p, i, post4x4_hdp);
    }
    fn seam(&self, p: &mut [i32], i: &[usize]) {
        on_slice::<4>(p, i, post4_hdp);
    }
}

/// Stage 2 of 4:2:0 and 4:2:2 chroma: 2×2 windows and 2-point seams.
struct Stage2Chroma;
impl Pattern for Stage2Chroma {
    const PITCH: usize = 2;
    fn window(&self, p: &mut [i32], i: &[usize], _: usize, _: usize) {
        on_slice::<4>(p, i, post2x2_hdp);
    }
    fn seam(&self, p: &mut [i32], i: &[usize]) {
        on_slice::<2>(p, i, post2_hdp);
    }
}

/// Stage 1 of every plane: 4×4 windows followed by the DC-leakage clamp, 4-point seams.
struct Stage1<'a> {
    leak: &'a DcLeakage,
    kind: PlaneKind,
    channel: usize,
    mb_w: usize,
    mb_h: usize,
}
impl Pattern for Stage1<'_> {
    const PITCH: usize = 4;
    fn window(&self, p: &mut [i32], i: &[usize], x: usize, y: usize) {
        // jxrlib's position (X, Y) when it runs this window: after decoding macroblock (X, Y)
        // it filters the block corners around that macroblock's top-left corner: columns
        // 4X − 2 ..= 4X + 1 (in blocks; 4:2:0 and 4:2:2 chroma 2X − 1, 2X), rows likewise
        // (4:2:0 2Y − 1, 2Y; 4:2:2 4Y − 1 ..= 4Y + 2).
        let (cx, cy) = (x / 4, y / 4);
        let (mx, my) = match self.kind {
            PlaneKind::Full => ((cx + 2) / 4, (cy + 2) / 4),
            PlaneKind::Chroma420 => (cx.div_ceil(2), cy.div_ceil(2)),
            PlaneKind::Chroma422 => (cx.div_ceil(2), (cy + 1) / 4),
        };
        let qp = self.leak.step(self.channel, mx, my, self.mb_w, self.mb_h);
        on_slice::<16>(p, i, |v| {
            let mut w = post4x4_hdp(v);
            clamp_dc_leakage(&mut w, qp, self.leak.hp_absent);
            w
        });
    }
    fn seam(&self, p: &mut [i32], i: &[usize]) {
        on_slice::<4>(p, i, post4_hdp);
    }
}

/// One POT stage on the region `r` of `p`, limited (as `super::pot4_region`) to the
/// operations keyed by a row in `keys`: the windows and left/right seams centred on an
/// interior grid row by that row, the top edge's seams by `r.y0`, the bottom edge's by `r.y1`.
/// Windows sit on every interior grid corner; seams cross every interior grid line along the
/// outermost `PITCH / 2` rows and columns; the corners are not touched.
fn pot_region<P: Pattern>(op: &P, p: &mut Rows, r: Rect, keys: &RangeInclusive<usize>) {
    let (n, half) = (P::PITCH, P::PITCH / 2);
    let mut idx = Vec::with_capacity(n * n);
    for y in (r.y0 + n..r.y1).step_by(n).filter(|y| keys.contains(y)) {
        for x in (r.x0 + n..r.x1).step_by(n) {
            idx.clear();
            for yy in y - half..y + half {
                idx.extend((x - half..x + half).map(|xx| p.at(xx, yy)));
            }
            op.window(p.data, &idx, x, y);
        }
        for x in (r.x0..r.x0 + half).chain(r.x1 - half..r.x1) {
            idx.clear();
            idx.extend((y - half..y + half).map(|yy| p.at(x, yy)));
            op.seam(p.data, &idx);
        }
    }
    for (key, rows) in [(r.y0, r.y0..r.y0 + half), (r.y1, r.y1 - half..r.y1)] {
        if !keys.contains(&key) {
            continue;
        }
        for y in rows {
            for x in (r.x0 + n..r.x1).step_by(n) {
                idx.clear();
                idx.extend((x - half..x + half).map(|xx| p.at(xx, y)));
                op.seam(p.data, &idx);
            }
        }
    }
}

/// [`super::inverse_band_rows`] with HD Photo's operators (same request, same layouts, same
/// halo); `leak` is the plane's clamp parameters. Scalar: a window or block at a time.
pub(super) fn inverse_band(request: &BandRequest, leak: &DcLeakage, scratch: &mut BandScratch) -> Result<usize> {
    let BandRequest { params, kind, channel, mb_w, mb_h, coeffs, ref rows } = *request;
    let overlap = params.overlap;
    // Stage 2 is the same PCT as JPEG XR's.
    let BandScratch { dc, data, .. } = scratch;
    let StageTwo { width, s0 } = stage2_band(request, 2, dc)?;
    let mb = |mx: usize, my: usize| coeffs.mb(mx, my);
    let (bx, by) = kind.blocks();
    let (r0, r1) = (rows.start, rows.end);
    let dw = bx * mb_w;
    let whole = |ux: usize, uy: usize| Rect { x0: 0, x1: mb_w * ux, y0: 0, y1: mb_h * uy };
    if overlap == OverlapMode::Two {
        // The DCs of macroblock rows r0 − 1 ..= r1 become final (as in the JPEG XR path).
        let keys = by * r0.saturating_sub(1)..=by * (r1 + 1).min(mb_h);
        let mut p = Rows { data: dc, stride: dw, y_base: by * s0 };
        match kind {
            PlaneKind::Full => pot_region(&Stage2Full, &mut p, whole(bx, by), &keys),
            _ => pot_region(&Stage2Chroma, &mut p, whole(bx, by), &keys),
        }
    }

    // Stage-1 PCT of block rows b0..b1 (the band and a block row of halo each side).
    let (b0, b1) = ((by * r0).saturating_sub(1), (by * r1 + 1).min(by * mb_h));
    super::grow(data, width * 4 * (b1 - b0));
    for y in b0..b1 {
        let (my, jy) = (y / by, y % by);
        for xb in 0..dw {
            let b = jy * bx + xb % bx;
            let c = mb(xb / bx, my);
            let mut t = [S(0); 16];
            t[0] = S(dc[(y - by * s0) * dw + xb]);
            for k in 1..16 {
                t[k] = S(c[hp(b, k)]);
            }
            let px = ipct4x4_g(t);
            for j in 0..4 {
                let row = ((y - b0) * 4 + j) * width + xb * 4;
                for i in 0..4 {
                    data[row + i] = px[j * 4 + i].0;
                }
            }
        }
    }
    let unit = 4 * by;
    if overlap != OverlapMode::None {
        let keys = unit * r0..=unit * r1;
        let stage1 = Stage1 { leak, kind, channel, mb_w, mb_h };
        let mut p = Rows { data, stride: width, y_base: 4 * b0 };
        pot_region(&stage1, &mut p, whole(4 * bx, unit), &keys);
    }
    Ok((unit * r0 - 4 * b0) * width)
}

#[cfg(test)]
mod tests {
    use super::super::plane_size;
    use super::*;
    use crate::mb::MbCoeffs;

    /// With the HP band present and a small step, the clamp never runs; without HP it moves
    /// half the clipped estimate between the diagonal pairs, keeping every group's sum.
    #[test]
    fn the_clamp_keeps_group_sums() {
        let base: [S; 16] = std::array::from_fn(|k| S(4000 + 37 * k as i32 - if k % 3 == 0 { 900 } else { 0 }));
        let mut x = base;
        clamp_dc_leakage(&mut x, 10, false);
        assert_eq!(x, base);
        clamp_dc_leakage(&mut x, 255, true);
        assert_ne!(x, base);
        for g in GROUPS {
            let sum = |v: &[S; 16]| g.iter().map(|&k| v[k].0).sum::<i32>();
            assert_eq!(sum(&x), sum(&base));
        }
    }

    /// HD Photo 1.0 streams (JxrEncApp's, with the sub-version nibble cleared; see
    /// `testdata/README.md`) decode to exactly jxrlib's samples (imagecodecs' `jpegxr_decode`,
    /// FNV-1a 64 over the sample bytes): 4:4:4, 4:2:0, 4:2:2, Y-only and interleaved alpha;
    /// OL 1 and 2; half, 8-bit and 16-bit; lossless, lossy with the clamp's step test, and
    /// without HP (the clamp everywhere); tiles, spatial order, odd sizes; HP quantizers per
    /// tile and per macroblock (4:4:4, 4:2:0, 4:2:2). With the nibble
    /// set back to 1, the same coefficients give other samples (the JPEG XR operators).
    #[test]
    fn hd_photo_streams_decode_as_jxrlib_does() {
        use hdrcodec_core::{DecodeOptions, Limits};
        let cases = [
            ("hdp_half_ol2.jxr", 0x024a_aaca_8366_545bu64),
            ("hdp_half_tiles.jxr", 0x89bc_d804_2ac6_2d62),
            ("hdp_420_q08.jxr", 0x3834_f460_4cd9_8a83),
            ("hdp_422_nohp.jxr", 0x8181_324e_7149_1fc7),
            ("hdp_rgb8_lossless.jxr", 0x20d3_9f6a_205a_b600),
            ("hdp_gray8_17x5.jxr", 0x376c_d3c9_f2f2_2cd3),
            ("hdp_rgba_half_inter.jxr", 0x6502_6010_27c4_b42d),
            ("hdp_rgb16_33x20_dc.jxr", 0x7511_5827_0a99_53dd),
            // Written by T.835 with HP quantizers per tile and macroblock: the step each
            // window compares with follows jxrlib's decoding position.
            ("hdp_t835_qp_stale.jxr", 0x9a02_c139_1a32_3a2a),
            ("hdp_t835_qp_420.jxr", 0x32aa_bec3_f5eb_bea4),
            ("hdp_t835_qp_422.jxr", 0xb88d_4d2c_9e1c_b3b1),
            ("hdp_t835_tile_qps.jxr", 0x5d87_1913_4e65_cdd3),
            // A hard-tile stream (sub-version 9) set to 0: jxrlib filters across its tile
            // edges, as HD Photo has no hard tiles.
            ("hdp_t835_hard_2x2.jxr", 0x57eb_3e07_9235_1298),
        ];
        let fnv = |raw: &[u8]| {
            raw.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
        };
        for (name, want) in cases {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
            let file = std::fs::read(&path).unwrap();
            for threads in [1, 2] {
                let pool = hdrcodec_core::ThreadPool::new(threads).unwrap();
                let raw = crate::decode_raw(&file, &DecodeOptions::new(Limits::default()).with_pool(pool)).unwrap();
                assert_eq!(fnv(&raw), want, "{name} on {threads} threads");
            }
            // The sub-version nibble follows the 8-byte signature and the version nibble.
            let container = crate::container::parse_container(&file).unwrap();
            let at = container.image.as_ptr() as usize - file.as_ptr() as usize + 8;
            assert_eq!(file[at], 0x10, "{name}: version 1, sub-version 0");
            // HD Photo's container version byte 0 changes nothing (jxrlib accepts 0 and 1).
            let mut version0 = file.clone();
            version0[3] = 0;
            let raw = crate::decode_raw(&version0, &DecodeOptions::new(Limits::default())).unwrap();
            assert_eq!(fnv(&raw), want, "{name} in a version 0 container");
            let mut jpeg_xr = file.clone();
            jpeg_xr[at] = 0x11;
            let raw = crate::decode_raw(&jpeg_xr, &DecodeOptions::new(Limits::default())).unwrap();
            assert_ne!(fnv(&raw), want, "{name} with the JPEG XR operators");
        }
    }

    /// Truncated and damaged HD Photo streams (also the per-macroblock quantizer pass) give
    /// errors or images, never panics.
    #[test]
    fn damaged_streams_never_panic() {
        use hdrcodec_core::{DecodeOptions, Limits};
        for name in ["hdp_t835_tile_qps.jxr", "hdp_t835_qp_420.jxr", "hdp_half_tiles.jxr"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
            let file = std::fs::read(&path).unwrap();
            let options = DecodeOptions::new(Limits::fuzzing());
            for n in 0..file.len() {
                let _ = crate::decode_raw(&file[..n], &options);
            }
            let mut bad = file.clone();
            for i in 0..file.len() {
                for bit in [0, 3, 7] {
                    bad[i] ^= 1 << bit;
                    let _ = crate::decode_raw(&bad, &options);
                    bad[i] = file[i];
                }
            }
        }
    }

    /// Every split into bands, with coefficient windows holding only a band's halo, gives the
    /// samples of one band over the whole image (HD Photo operators, with the clamp on, off,
    /// or per macroblock).
    #[test]
    fn bands_agree_with_the_whole_image() {
        use crate::transform::{inverse_band, OperatorSet, TransformParams};
        let mut r = crate::testing::rng(5);
        let (mb_w, mb_h) = (3, 11);
        for kind in [PlaneKind::Full, PlaneKind::Chroma420, PlaneKind::Chroma422] {
            let per_mb: Arc<[i32]> = (0..mb_w * mb_h * 3).map(|_| [10, 24, 200][(r() % 3) as usize]).collect();
            let leaks = [
                DcLeakage { hp_absent: true, hp_step: Vec::new(), per_mb: None, channels: 3 },
                DcLeakage { hp_absent: false, hp_step: vec![40, 40, 40], per_mb: None, channels: 3 },
                DcLeakage { hp_absent: false, hp_step: Vec::new(), per_mb: Some(per_mb), channels: 3 },
            ];
            for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
                for leak in &leaks {
                    let params = TransformParams {
                        overlap,
                        scaled: true,
                        hard: None,
                        operators: OperatorSet::HdPhoto(leak.clone()),
                    };
                    // Small coefficients (as after dequantization of smooth content), so that
                    // the clamp's step test goes both ways.
                    let coeffs: Vec<MbCoeffs> = (0..mb_w * mb_h)
                        .map(|_| std::array::from_fn(|k| (r() as i32) >> if k < 16 { 18 } else { 26 }))
                        .collect();
                    let whole = super::super::tests::assert_bands_match_whole(
                        &params,
                        kind,
                        1,
                        mb_w,
                        mb_h,
                        &coeffs,
                        &format!("{leak:?}"),
                    );
                    let (width, height) = plane_size(kind, mb_w, mb_h).unwrap();
                    // The JPEG XR operators give other samples (with overlap).
                    let xr = TransformParams { operators: OperatorSet::JpegXr, ..params.clone() };
                    let mut other = vec![0; width * height];
                    inverse_band(&xr, kind, 1, mb_w, mb_h, &coeffs, 0, 0..mb_h, &mut other).unwrap();
                    assert_eq!(other == whole, overlap == OverlapMode::None, "{kind:?} {overlap:?}");
                }
            }
        }
    }

    /// Extreme values wrap rather than panic.
    #[test]
    fn extremes_wrap() {
        let mut x = [S(i32::MAX); 16];
        x[3] = S(i32::MIN);
        let mut w = post4x4_hdp(x);
        clamp_dc_leakage(&mut w, 255, true);
        let _ = post4_hdp([S(i32::MIN), S(i32::MAX), S(-1), S(7)]);
        let _ = post2x2_hdp([S(i32::MIN), S(i32::MAX), S(-1), S(7)]);
    }
}
