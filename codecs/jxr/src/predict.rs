//! Coefficient prediction (T.832 9.3; T.835 `algo.c: _jxr_complete_cur_dclp`,
//! `r_parse.c: r_calculate_mbhp_mode, _jxr_propagate_hp_predictions`, jxrlib
//! `strPredQuant.c`, `strPredQuantDec.c`), on quantized values inside one tile.
//!
//! Coefficients are indexed as in [`crate::mb`]: `c[0]` DC, `c[k]` LP coefficient `k`,
//! `c[mb::hp(b, k)]` HP coefficient `k` of block `b` (raster order in the macroblock).

use crate::header::ClrFmt;
use crate::mb::{hp, MB_COEFFS};

/// DC prediction mode of a macroblock (T.832 9.3.1): 0 from the left, 1 from the top, 2
/// from both, 3 none. `left`, `top`, `top_left` are the neighbours' coefficient arrays
/// (all channels, [`MB_COEFFS`] each), present when inside the tile.
pub fn dc_mode(fmt: ClrFmt, left: Option<&[i32]>, top: Option<&[i32]>, top_left: Option<&[i32]>) -> u8 {
    let (l, t, tl) = match (left, top, top_left) {
        (None, None, _) => return 3,
        (None, Some(_), _) => return 1,
        (Some(_), None, _) => return 0,
        (Some(l), Some(t), Some(tl)) => (l, t, tl),
        // A macroblock with a left and a top neighbour always has a top-left one.
        (Some(_), Some(_), None) => return 2,
    };
    let d = |a: &[i32], b: &[i32], ch: usize| (i64::from(a[ch * MB_COEFFS]) - i64::from(b[ch * MB_COEFFS])).abs();
    let (hor, ver) = match fmt {
        ClrFmt::YOnly | ClrFmt::NComponent => (d(tl, l, 0), d(tl, t, 0)),
        _ => {
            let scale = match fmt {
                ClrFmt::Yuv422 => 4,
                ClrFmt::Yuv420 => 8,
                _ => 2,
            };
            (d(tl, l, 0) * scale + d(tl, l, 1) + d(tl, l, 2), d(tl, t, 0) * scale + d(tl, t, 1) + d(tl, t, 2))
        }
    };
    if hor * 4 < ver {
        1
    } else if ver * 4 < hor {
        0
    } else {
        2
    }
}

/// DC and LP prediction of one macroblock (`cur`: all channels), given its neighbours inside
/// the tile and whether each has the same LP QP index. Returns the DC mode.
#[allow(clippy::too_many_arguments)]
pub fn predict_dclp(
    fmt: ClrFmt,
    channels: usize,
    cur: &mut [i32],
    left: Option<&[i32]>,
    top: Option<&[i32]>,
    top_left: Option<&[i32]>,
    same_lp_qp_left: bool,
    same_lp_qp_top: bool,
) -> u8 {
    let mode = dc_mode(fmt, left, top, top_left);
    for ch in 0..channels {
        let o = ch * MB_COEFFS;
        let l = left.map_or(0, |m| i64::from(m[o]));
        let t = top.map_or(0, |m| i64::from(m[o]));
        let add = match mode {
            0 => l,
            1 => t,
            2 => {
                if ch > 0 && matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) {
                    (l + t + 1) >> 1
                } else {
                    (l + t) >> 1
                }
            }
            _ => 0,
        };
        cur[o] = cur[o].wrapping_add(add as i32);
    }
    let lp_mode = if mode == 0 && same_lp_qp_left {
        0
    } else if mode == 1 && same_lp_qp_top {
        1
    } else {
        2
    };
    for ch in 0..channels {
        let o = ch * MB_COEFFS;
        let c = &mut cur[o..o + MB_COEFFS];
        let l = left.map(|m| &m[o..o + MB_COEFFS]);
        let t = top.map(|m| &m[o..o + MB_COEFFS]);
        let add = |c: &mut [i32], i: usize, v: i32| c[i] = c[i].wrapping_add(v);
        match (fmt, ch > 0) {
            (ClrFmt::Yuv420, true) => match (lp_mode, l, t) {
                (0, Some(l), _) => add(c, 2, l[2]),
                (1, _, Some(t)) => add(c, 1, t[1]),
                _ => {}
            },
            (ClrFmt::Yuv422, true) => match (lp_mode, l, t) {
                (0, Some(l), _) => {
                    add(c, 4, l[4]);
                    add(c, 2, l[2]);
                    add(c, 6, l[6]);
                }
                (1, _, Some(t)) => {
                    add(c, 4, t[4]);
                    add(c, 1, t[5]);
                    let v = c[1];
                    add(c, 5, v);
                }
                (2, _, _) if mode == 1 => {
                    let v = c[1];
                    add(c, 5, v);
                }
                _ => {}
            },
            _ => match (lp_mode, l, t) {
                (0, Some(l), _) => {
                    for k in [4, 8, 12] {
                        add(c, k, l[k]);
                    }
                }
                (1, _, Some(t)) => {
                    for k in [1, 2, 3] {
                        add(c, k, t[k]);
                    }
                }
                _ => {}
            },
        }
    }
    mode
}

/// The encoder's side of [`predict_dclp`]: turns the quantized DC and LP coefficients of
/// `cur` into the residuals the bitstream carries, so that [`predict_dclp`] with the same
/// neighbours gives `cur` back. Every prediction adds a neighbour's value, except in 4:2:2
/// chroma, where coefficient 5 adds the macroblock's own (final) coefficient 1: that one is
/// undone first, while coefficient 1 still holds its final value. Only the predicted
/// coefficients are touched, in place. Returns the DC mode.
#[allow(clippy::too_many_arguments)]
pub fn unpredict_dclp(
    fmt: ClrFmt,
    channels: usize,
    cur: &mut [i32],
    left: Option<&[i32]>,
    top: Option<&[i32]>,
    top_left: Option<&[i32]>,
    same_lp_qp_left: bool,
    same_lp_qp_top: bool,
) -> u8 {
    let mode = dc_mode(fmt, left, top, top_left);
    let lp_mode = if mode == 0 && same_lp_qp_left {
        0
    } else if mode == 1 && same_lp_qp_top {
        1
    } else {
        2
    };
    let sub = |c: &mut [i32], i: usize, v: i32| c[i] = c[i].wrapping_sub(v);
    for ch in 0..channels {
        let o = ch * MB_COEFFS;
        let c = &mut cur[o..o + 16];
        let l = left.map(|m| &m[o..o + 16]);
        let t = top.map(|m| &m[o..o + 16]);
        let (lv, tv) = (l.map_or(0, |m| i64::from(m[0])), t.map_or(0, |m| i64::from(m[0])));
        let dc = match mode {
            0 => lv,
            1 => tv,
            2 => {
                if ch > 0 && matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) {
                    (lv + tv + 1) >> 1
                } else {
                    (lv + tv) >> 1
                }
            }
            _ => 0,
        };
        sub(c, 0, dc as i32);
        match (fmt, ch > 0) {
            (ClrFmt::Yuv420, true) => match (lp_mode, l, t) {
                (0, Some(l), _) => sub(c, 2, l[2]),
                (1, _, Some(t)) => sub(c, 1, t[1]),
                _ => {}
            },
            (ClrFmt::Yuv422, true) => match (lp_mode, l, t) {
                (0, Some(l), _) => {
                    sub(c, 4, l[4]);
                    sub(c, 2, l[2]);
                    sub(c, 6, l[6]);
                }
                (1, _, Some(t)) => {
                    // Coefficient 5 added the final coefficient 1, after that one's own
                    // prediction.
                    let v = c[1];
                    sub(c, 5, v);
                    sub(c, 4, t[4]);
                    sub(c, 1, t[5]);
                }
                (2, _, _) if mode == 1 => {
                    let v = c[1];
                    sub(c, 5, v);
                }
                _ => {}
            },
            _ => match (lp_mode, l, t) {
                (0, Some(l), _) => {
                    for k in [4, 8, 12] {
                        sub(c, k, l[k]);
                    }
                }
                (1, _, Some(t)) => {
                    for k in [1, 2, 3] {
                        sub(c, k, t[k]);
                    }
                }
                _ => {}
            },
        }
    }
    mode
}

/// HP prediction direction of a macroblock from its (predicted) LP coefficients (T.832
/// 9.3.3): 0 from the left, 1 from the top, 2 none.
pub fn hp_mode(fmt: ClrFmt, cur: &[i32]) -> u8 {
    let a = |ch: usize, k: usize| i64::from(cur[ch * MB_COEFFS + k]).abs();
    let mut hor = a(0, 1) + a(0, 2) + a(0, 3);
    let mut ver = a(0, 4) + a(0, 8) + a(0, 12);
    match fmt {
        ClrFmt::YOnly | ClrFmt::NComponent => {}
        ClrFmt::Yuv444 | ClrFmt::Yuvk => {
            hor += a(1, 1) + a(2, 1);
            ver += a(1, 4) + a(2, 4);
        }
        ClrFmt::Yuv422 => {
            hor += a(1, 1) + a(2, 1) + a(1, 5) + a(2, 5);
            ver += a(1, 2) + a(2, 2) + a(1, 6) + a(2, 6);
        }
        ClrFmt::Yuv420 => {
            hor += a(1, 1) + a(2, 1);
            ver += a(1, 2) + a(2, 2);
        }
    }
    if hor * 4 < ver {
        0
    } else if ver * 4 < hor {
        1
    } else {
        2
    }
}

/// HP prediction inside one macroblock (`_jxr_propagate_hp_predictions`): with mode 0 the
/// left-column coefficients 4, 8, 12 of each block add those of the block to the left; with
/// mode 1 the top-row coefficients 1, 2, 3 add those of the block above. `c` holds all
/// channels; for 420 and 422 the call for channel 0 also predicts both chroma channels.
pub fn predict_hp(fmt: ClrFmt, c: &mut [i32], ch: usize, mode: u8) {
    fn step(c: &mut [i32], o: usize, to: usize, from: usize, ks: [usize; 3]) {
        for k in ks {
            let v = c[o + hp(from, k)];
            let d = &mut c[o + hp(to, k)];
            *d = d.wrapping_add(v);
        }
    }
    let o = ch * MB_COEFFS;
    match mode {
        0 => {
            for b in (1..16).filter(|b| b % 4 != 0) {
                step(c, o, b, b - 1, [4, 8, 12]);
            }
        }
        1 => {
            for b in 4..16 {
                step(c, o, b, b - 4, [1, 2, 3]);
            }
        }
        _ => {}
    }
    let (blocks_per_row, blocks) = match fmt {
        ClrFmt::Yuv420 => (2, 4),
        ClrFmt::Yuv422 => (2, 8),
        _ => return,
    };
    for chroma in [1, 2] {
        let o = chroma * MB_COEFFS;
        match mode {
            0 => {
                for b in (1..blocks).step_by(2) {
                    step(c, o, b, b - 1, [4, 8, 12]);
                }
            }
            1 => {
                for b in blocks_per_row..blocks {
                    step(c, o, b, b - blocks_per_row, [1, 2, 3]);
                }
            }
            _ => {}
        }
    }
}

/// The encoder's side of [`predict_hp`]: HP coefficients to residuals, in the reverse of
/// the decoder's order, so that each block subtracts its neighbour's final values.
pub fn unpredict_hp(fmt: ClrFmt, c: &mut [i32], ch: usize, mode: u8) {
    fn step(c: &mut [i32], o: usize, to: usize, from: usize, ks: [usize; 3]) {
        for k in ks {
            let v = c[o + hp(from, k)];
            let d = &mut c[o + hp(to, k)];
            *d = d.wrapping_sub(v);
        }
    }
    let (blocks_per_row, blocks) = match fmt {
        ClrFmt::Yuv420 => (2, 4),
        ClrFmt::Yuv422 => (2, 8),
        _ => (0, 0),
    };
    if blocks > 0 {
        for chroma in [2, 1] {
            let o = chroma * MB_COEFFS;
            match mode {
                0 => {
                    for b in (1..blocks).step_by(2).rev() {
                        step(c, o, b, b - 1, [4, 8, 12]);
                    }
                }
                1 => {
                    for b in (blocks_per_row..blocks).rev() {
                        step(c, o, b, b - blocks_per_row, [1, 2, 3]);
                    }
                }
                _ => {}
            }
        }
    }
    let o = ch * MB_COEFFS;
    match mode {
        0 => {
            for b in (1..16).filter(|b| b % 4 != 0).rev() {
                step(c, o, b, b - 1, [4, 8, 12]);
            }
        }
        1 => {
            for b in (4..16).rev() {
                step(c, o, b, b - 4, [1, 2, 3]);
            }
        }
        _ => {}
    }
}

/// How the coded-block pattern of a channel is laid out for its prediction (T.832 9.3.4;
/// T.835 `_jxr_PredCBP444/422/420`).
struct CbpLayout {
    /// The bit of the top neighbour's pattern that predicts block 0, and the left one's.
    top_bit: u32,
    left_bit: u32,
    /// Every block's bit.
    all: u32,
    /// Blocks counted for the model are scaled to 16 blocks.
    scale: i32,
    /// The spatial prediction's propagation from block to block, in order: each step is
    /// `cbp ^= (cbp << shift) & mask`. A step writes only bits it does not read, so it is its
    /// own inverse.
    steps: &'static [(u32, u32)],
}

fn cbp_layout(fmt: ClrFmt, ch: usize) -> CbpLayout {
    match (fmt, ch > 0) {
        (ClrFmt::Yuv420, true) => {
            CbpLayout { top_bit: 2, left_bit: 1, all: 0xF, scale: 4, steps: &[(1, 0x02), (2, 0x0C)] }
        }
        (ClrFmt::Yuv422, true) => CbpLayout {
            top_bit: 6,
            left_bit: 1,
            all: 0xFF,
            scale: 2,
            steps: &[(1, 0x02), (2, 0x0C), (2, 0x30), (2, 0xC0)],
        },
        _ => CbpLayout {
            top_bit: 10,
            left_bit: 5,
            all: 0xFFFF,
            scale: 1,
            steps: &[(1, 0x02), (3, 0x10), (1, 0x20), (2, 0xCC), (6, 0x3300), (2, 0xCC00)],
        },
    }
}

impl CbpLayout {
    /// The bit that predicts block 0: the neighbour's nearest block, or 1 at the tile corner.
    fn neighbour_bit(&self, left: Option<u32>, top: Option<u32>) -> u32 {
        match (left, top) {
            (Some(l), _) => (l >> self.left_bit) & 1,
            (None, Some(t)) => (t >> self.top_bit) & 1,
            (None, None) => 1,
        }
    }
}

/// The CBP prediction of one channel (T.832 9.3.4; T.835 `_jxr_PredCBP444/422/420`): turns
/// the decoded difference pattern `diff` into the coded-block pattern, given the prediction
/// state and the neighbours' patterns inside the tile (`None` outside). Returns the pattern
/// and the number of coded blocks scaled to 16 (what the model is updated with).
pub fn predict_cbp(fmt: ClrFmt, ch: usize, diff: u32, state: u8, left: Option<u32>, top: Option<u32>) -> (u32, i32) {
    let layout = cbp_layout(fmt, ch);
    let mut cbp = diff;
    if state == 0 {
        cbp ^= layout.neighbour_bit(left, top);
        for &(shift, mask) in layout.steps {
            cbp ^= (cbp << shift) & mask;
        }
    } else if state == 2 {
        cbp ^= layout.all;
    }
    cbp &= layout.all;
    (cbp, cbp.count_ones() as i32 * layout.scale)
}

/// The inverse of [`predict_cbp`] (what an encoder codes): the difference pattern that
/// `predict_cbp` turns into `cbp`, given the same state and neighbours: the propagation steps
/// undone in reverse order, then the neighbour's bit.
pub fn unpredict_cbp(fmt: ClrFmt, ch: usize, cbp: u32, state: u8, left: Option<u32>, top: Option<u32>) -> u32 {
    let layout = cbp_layout(fmt, ch);
    let mut d = cbp & layout.all;
    if state == 0 {
        for &(shift, mask) in layout.steps.iter().rev() {
            d ^= (d << shift) & mask;
        }
        d ^= layout.neighbour_bit(left, top);
    } else if state == 2 {
        d ^= layout.all;
    }
    d & layout.all
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mb(channels: usize, f: impl Fn(usize, usize) -> i32) -> Vec<i32> {
        (0..channels * MB_COEFFS).map(|i| f(i / MB_COEFFS, i % MB_COEFFS)).collect()
    }

    #[test]
    fn dc_modes() {
        let z = mb(3, |_, _| 0);
        assert_eq!(dc_mode(ClrFmt::Yuv444, None, None, None), 3);
        assert_eq!(dc_mode(ClrFmt::Yuv444, None, Some(&z), None), 1);
        assert_eq!(dc_mode(ClrFmt::Yuv444, Some(&z), None, None), 0);
        // Left differs strongly from top-left (an edge between the rows): the current
        // macroblock is predicted from its left neighbour, below the same edge.
        let l = mb(3, |ch, k| if ch == 0 && k == 0 { 100 } else { 0 });
        assert_eq!(dc_mode(ClrFmt::Yuv444, Some(&l), Some(&z), Some(&z)), 0);
        assert_eq!(dc_mode(ClrFmt::Yuv444, Some(&z), Some(&l), Some(&z)), 1);
        assert_eq!(dc_mode(ClrFmt::Yuv444, Some(&z), Some(&z), Some(&z)), 2);
    }

    #[test]
    fn dc_average_rounds_down_for_luma_and_up_for_subsampled_chroma() {
        let l = mb(3, |_, k| if k == 0 { -3 } else { 0 });
        let t = mb(3, |_, _| 0);
        let tl = mb(3, |_, k| if k == 0 { -1 } else { 0 });
        let mut cur = mb(3, |_, _| 0);
        assert_eq!(predict_dclp(ClrFmt::Yuv420, 3, &mut cur, Some(&l), Some(&t), Some(&tl), true, true), 2);
        assert_eq!((cur[0], cur[MB_COEFFS]), (-2, -1));
    }

    #[test]
    fn unprediction_inverts_prediction() {
        let mut next = crate::testing::rng(7);
        for (fmt, channels) in crate::testing::FORMATS {
            for case in 0..400 {
                let mut rand_mb = || -> Vec<i32> {
                    let v: Vec<i32> = (0..channels * MB_COEFFS).map(|_| (next() % 41) as i32 - 20).collect();
                    v
                };
                let (l, t, tl, cur) = (rand_mb(), rand_mb(), rand_mb(), rand_mb());
                let left = (case & 1 == 1).then_some(l.as_slice());
                let top = (case >> 1 & 1 == 1).then_some(t.as_slice());
                let top_left = (left.is_some() && top.is_some()).then_some(tl.as_slice());
                let (same_left, same_top) = (case >> 2 & 1 == 1, case >> 3 & 1 == 1);
                let mut res = cur.clone();
                let mode = unpredict_dclp(fmt, channels, &mut res, left, top, top_left, same_left, same_top);
                let mut back = res.clone();
                let mode2 = predict_dclp(fmt, channels, &mut back, left, top, top_left, same_left, same_top);
                assert_eq!((mode, &back), (mode2, &cur), "{fmt:?} case {case}");
                let hp_mode = (case % 3) as u8;
                let subsampled = matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
                let mut res = cur.clone();
                for ch in 0..if subsampled { 1 } else { channels } {
                    unpredict_hp(fmt, &mut res, ch, hp_mode);
                }
                for ch in 0..if subsampled { 1 } else { channels } {
                    predict_hp(fmt, &mut res, ch, hp_mode);
                }
                assert_eq!(res, cur, "{fmt:?} HP case {case}");
            }
        }
    }

    #[test]
    fn cbp_prediction_at_the_tile_corner() {
        // State 0, no neighbours: bit 0 flips, then propagates through the quads.
        let (cbp, n) = predict_cbp(ClrFmt::Yuv444, 0, 0, 0, None, None);
        assert_eq!(cbp, 0xFFFF);
        assert_eq!(n, 16);
        assert_eq!(predict_cbp(ClrFmt::Yuv444, 0, 0x0F0F, 1, None, None), (0x0F0F, 8));
        assert_eq!(predict_cbp(ClrFmt::Yuv420, 1, 0, 2, None, None), (0xF, 16));
    }

    #[test]
    fn unpredict_cbp_inverts_predict_cbp_exhaustively() {
        let cases = [
            (ClrFmt::YOnly, 0),
            (ClrFmt::Yuv444, 1),
            (ClrFmt::Yuv420, 0),
            (ClrFmt::Yuv420, 1),
            (ClrFmt::Yuv422, 2),
            (ClrFmt::NComponent, 3),
        ];
        for (fmt, ch) in cases {
            let all: u32 = match (fmt, ch) {
                (ClrFmt::Yuv420, 1..) => 0xF,
                (ClrFmt::Yuv422, 1..) => 0xFF,
                _ => 0xFFFF,
            };
            // Neighbour patterns with the bit predict_cbp reads clear and set.
            let neighbours = [None, Some(0), Some(all)];
            for state in 0..3u8 {
                for &left in &neighbours {
                    for &top in &neighbours {
                        for cbp in 0..=all {
                            let diff = unpredict_cbp(fmt, ch, cbp, state, left, top);
                            let (back, _) = predict_cbp(fmt, ch, diff, state, left, top);
                            assert_eq!(back, cbp, "{fmt:?} ch {ch} state {state} {left:?} {top:?}");
                        }
                    }
                }
            }
        }
    }
}
