//! The macroblock layer (T.832 8.7, decoding per 9.2): DC, LP with CBPLP, CBPHP, HP with
//! run-level symbols, refinement bits and FLEXBITS, for one plane of one tile. The syntax
//! follows T.835's `r_parse.c` (`_jxr_r_MB_DC`, `_jxr_r_MB_LP`, `_jxr_r_MB_CBP`,
//! `_jxr_r_MB_HP`, `r_DECODE_BLOCK`, `r_BLOCK_FLEXBITS`), which matches jxrlib's
//! `segdec.c` on every stream checked.
//!
//! Values are written quantized (model bits and flexbits included) into a macroblock's
//! coefficient array (all channels, [`MB_COEFFS`] each, layout of [`crate::mb`]); prediction
//! and dequantization come later.

// Loops over channel, block and bit indices mirror the syntax of T.832 and T.835.
#![allow(clippy::needless_range_loop)]

use crate::bits::BitReader;
use crate::header::{ClrFmt, MAX_CHANNELS};
use crate::mb::{hp, MB_COEFFS};
use crate::predict;
use crate::vlc::{self, AdaptiveVlc, CbpModel, Model, Scan, BAND_DC, BAND_HP, BAND_LP, V, V_COUNT};
use hdrcodec_core::{Error, Result};

/// Refinement order of LP and flexbits: T.832's natural (column-major) order, `transpose444`.
const TRANSPOSE444: [usize; 16] = [0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15];
/// 420 chroma LP positions.
const TRANSPOSE420: [usize; 4] = [0, 2, 1, 3];
/// 422 chroma LP positions.
const TRANSPOSE422: [usize; 8] = [0, 2, 1, 3, 4, 6, 5, 7];
/// The order of a luma macroblock's blocks in the bitstream: 2×2 quads (T.835 `_jxr_hp_scan_map`).
const HP_BLOCK_ORDER: [usize; 16] = [0, 1, 4, 5, 2, 3, 6, 7, 8, 9, 12, 13, 10, 11, 14, 15];

fn corrupt(what: &str) -> Error {
    Error::invalid(format!("JPEG XR: corrupt macroblock data ({what})"))
}

/// The adaptive entropy-coding state of one plane in one tile (reset at each tile start).
#[derive(Clone, Debug)]
pub struct PlaneDecoder {
    /// INTERNAL_CLR_FMT.
    pub fmt: ClrFmt,
    /// Channels.
    pub channels: usize,
    /// TRIM_FLEXBITS of the tile.
    pub trim: u32,
    vlc: [AdaptiveVlc; V_COUNT],
    model: [Model; 3],
    cbplp_zero: i32,
    cbplp_max: i32,
    lp_scan: Scan,
    hp_hor: Scan,
    hp_ver: Scan,
    cbp_model: CbpModel,
}

/// One decoded run-level pair: zeros before the coefficient, and its value.
#[derive(Clone, Copy, Debug, Default)]
struct RunLevel {
    run: u32,
    level: i32,
}

impl PlaneDecoder {
    /// The state at the start of a tile.
    pub fn new(fmt: ClrFmt, channels: usize) -> Self {
        let mut vlc = [AdaptiveVlc::ONE; V_COUNT];
        for v in [
            V::FirstIndLpLum,
            V::IndLpLum0,
            V::IndLpLum1,
            V::FirstIndLpChr,
            V::IndLpChr0,
            V::IndLpChr1,
            V::FirstIndHpLum,
            V::IndHpLum0,
            V::IndHpLum1,
            V::FirstIndHpChr,
            V::IndHpChr0,
            V::IndHpChr1,
        ] {
            vlc[v as usize] = AdaptiveVlc::TWO;
        }
        PlaneDecoder {
            fmt,
            channels,
            trim: 0,
            vlc,
            model: [Model::new(BAND_DC), Model::new(BAND_LP), Model::new(BAND_HP)],
            cbplp_zero: 1,
            cbplp_max: 1,
            lp_scan: Scan::new(vlc::SCAN_HORIZONTAL),
            hp_hor: Scan::new(vlc::SCAN_HORIZONTAL),
            hp_ver: Scan::new(vlc::SCAN_VERTICAL),
            cbp_model: CbpModel::default(),
        }
    }

    fn fmt_code(&self) -> u8 {
        match self.fmt {
            ClrFmt::Yuv420 => 1,
            ClrFmt::Yuv422 => 2,
            _ => 0,
        }
    }

    /// Adaptation of a band's tables (`_jxr_AdaptLP`, `_jxr_AdaptHP`): the first-index and
    /// index contexts of luma and chroma (5 and 4 tables), then the two-table contexts.
    fn adapt(&mut self, index: [V; 6], two_table: &[V]) {
        for (v, max) in index.into_iter().zip([4, 3, 3, 4, 3, 3]) {
            self.vlc[v as usize].adapt_two(max);
        }
        for &v in two_table {
            self.vlc[v as usize].adapt_one();
        }
    }

    fn update_model(&mut self, lap_mean: [i32; 2], band: usize) {
        let (fmt, channels, yonly) = (self.fmt_code(), self.channels, self.fmt == ClrFmt::YOnly);
        self.model[band].update(lap_mean, band, fmt, channels, yonly);
    }

    /// ABSLEVEL_INDEX and the level it codes (`r_DECODE_ABS_LEVEL`).
    #[inline(always)]
    fn abs_level(&mut self, r: &mut BitReader, v: V) -> u32 {
        let ctx = &mut self.vlc[v as usize];
        let index = vlc::decode(r, &vlc::ABS_LEVEL[ctx.table as usize]);
        ctx.disc += vlc::ABS_LEVEL_DELTA[index];
        const REMAP: [u32; 6] = [2, 3, 4, 6, 10, 14];
        const FIXED: [u32; 6] = [0, 0, 1, 2, 2, 2];
        if index < 6 {
            REMAP[index] + r.read(FIXED[index])
        } else {
            let mut fixed = 4 + r.read(4);
            if fixed == 19 {
                fixed += r.read(2);
                if fixed == 22 {
                    fixed += r.read(3);
                }
            }
            2u32.wrapping_add(1 << fixed).wrapping_add(r.read(fixed))
        }
    }

    /// A run of zeros when at most `max_run` positions remain (`r_DECODE_RUN`).
    #[inline(always)]
    fn run(r: &mut BitReader, max_run: i32) -> u32 {
        if max_run < 5 {
            // 1, 01, 001, ... with the last code of max_run - 1 zeros.
            if max_run <= 1 {
                return max_run.max(0) as u32;
            }
            let bits = (max_run - 1) as u32;
            let zeros = (r.peek(bits) << (32 - bits)).leading_zeros().min(bits);
            r.skip((zeros + 1).min(bits));
            return zeros + 1;
        }
        const RUN_BIN: [usize; 15] = [0, 0, 0, 0, 0, 2, 2, 1, 1, 1, 1, 0, 0, 0, 0];
        const FIXED: [u32; 15] = [0, 0, 1, 1, 3, 0, 0, 1, 1, 2, 0, 0, 0, 0, 1];
        const REMAP: [u32; 15] = [1, 2, 3, 5, 7, 1, 2, 3, 5, 7, 1, 2, 3, 4, 5];
        let index = vlc::decode(r, &vlc::RUN_INDEX) + 5 * RUN_BIN[max_run.min(14) as usize];
        REMAP[index] + r.read(FIXED[index])
    }

    /// One block of run-level symbols (`r_DECODE_BLOCK`), starting at coefficient position
    /// `location` (1 for LP and HP, 10 for 420 chroma LP, 2 for 422 chroma LP). Returns the
    /// number of pairs written to `out`.
    #[inline(always)]
    fn block(
        &mut self,
        r: &mut BitReader,
        chroma: bool,
        band: usize,
        mut location: u32,
        out: &mut [RunLevel; 16],
    ) -> Result<usize> {
        let (first_v, ind_v, abs_v) = match (band, chroma) {
            (BAND_LP, false) => (V::FirstIndLpLum, [V::IndLpLum0, V::IndLpLum1], [V::AbsLevelLp0, V::AbsLevelLp1]),
            (BAND_LP, true) => (V::FirstIndLpChr, [V::IndLpChr0, V::IndLpChr1], [V::AbsLevelLp0, V::AbsLevelLp1]),
            (_, false) => (V::FirstIndHpLum, [V::IndHpLum0, V::IndHpLum1], [V::AbsLevelHp0, V::AbsLevelHp1]),
            (_, true) => (V::FirstIndHpChr, [V::IndHpChr0, V::IndHpChr1], [V::AbsLevelHp0, V::AbsLevelHp1]),
        };
        let ctx = &mut self.vlc[first_v as usize];
        let index = vlc::decode(r, &vlc::FIRST_INDEX[ctx.table as usize]);
        ctx.disc += vlc::FIRST_INDEX_DELTA[ctx.delta as usize][index];
        ctx.disc2 += vlc::FIRST_INDEX_DELTA[ctx.delta2 as usize][index];
        let mut srn = index >> 2;
        let mut context = (index & 1) & srn;
        let sign = r.bit();
        let mut level = if index & 2 != 0 { self.abs_level(r, abs_v[context]) as i32 } else { 1 };
        if sign {
            level = level.wrapping_neg();
        }
        let run = if index & 1 != 0 {
            0
        } else {
            if location >= 15 {
                return Err(corrupt("a run past the end of a block"));
            }
            Self::run(r, 15 - location as i32)
        };
        out[0] = RunLevel { run, level };
        location += run + 1;
        let mut n = 1;
        while srn != 0 {
            if n >= 16 {
                return Err(corrupt("more than 16 coefficients in a block"));
            }
            let run = if srn & 1 != 0 { 0 } else { Self::run(r, 15 - location as i32) };
            location += run + 1;
            if location > 16 {
                return Err(corrupt("a coefficient past the end of a block"));
            }
            let index = if location > 15 {
                r.read(1) as usize
            } else if location == 15 {
                vlc::decode(r, &vlc::INDEX2)
            } else {
                let ctx = &mut self.vlc[ind_v[context] as usize];
                let index = vlc::decode(r, &vlc::INDEX[ctx.table as usize]);
                ctx.disc += vlc::INDEX_DELTA[ctx.delta as usize][index];
                ctx.disc2 += vlc::INDEX_DELTA[ctx.delta2 as usize][index];
                index
            };
            srn = index >> 1;
            context &= srn;
            let sign = r.bit();
            let mut level = if index & 1 != 0 { self.abs_level(r, abs_v[context]) as i32 } else { 1 };
            if sign {
                level = level.wrapping_neg();
            }
            out[n] = RunLevel { run, level };
            n += 1;
        }
        Ok(n)
    }

    /// MB_DC (`_jxr_r_MB_DC`): the DC of every channel, unpredicted.
    pub fn dc(&mut self, r: &mut BitReader, c: &mut [i32], mx: u32, tile_w: u32) {
        let mut lap_mean = [0i32; 2];
        let bits = self.model[BAND_DC].bits;
        if self.fmt.is_yuv() {
            let flags = vlc::decode(r, &vlc::DC_YUV);
            for (ch, flag) in [(0usize, 4usize), (1, 2), (2, 1)] {
                let chroma = ch > 0;
                let coded = flags & flag != 0;
                lap_mean[usize::from(chroma)] += i32::from(coded);
                c[ch * MB_COEFFS] = self.dc_value(r, bits[usize::from(chroma)], chroma, coded);
            }
        } else {
            // YONLY, YUVK and NCOMPONENT: every channel's level uses the luma DC table (T.835
            // `_jxr_r_MB_DC`, jxrlib `m_pAHexpt[3]`); only the model bits are chroma's.
            for ch in 0..self.channels {
                let chroma = ch > 0;
                let coded = r.bit();
                lap_mean[usize::from(chroma)] += i32::from(coded);
                c[ch * MB_COEFFS] = self.dc_value(r, bits[usize::from(chroma)], false, coded);
            }
        }
        self.update_model(lap_mean, BAND_DC);
        if reset_context(mx, tile_w) {
            self.vlc[V::AbsLevelDcLum as usize].adapt_one();
            self.vlc[V::AbsLevelDcChr as usize].adapt_one();
        }
    }

    /// DEC_DC (`r_DEC_DC`).
    fn dc_value(&mut self, r: &mut BitReader, model_bits: u32, chroma: bool, coded: bool) -> i32 {
        let mut v: i32 = 0;
        if coded {
            let v_ctx = if chroma { V::AbsLevelDcChr } else { V::AbsLevelDcLum };
            v = self.abs_level(r, v_ctx).wrapping_sub(1) as i32;
        }
        if model_bits > 0 {
            v = v.wrapping_shl(model_bits) | r.read(model_bits) as i32;
        }
        if v != 0 && r.bit() {
            v = v.wrapping_neg();
        }
        v
    }

    /// MB_LP (`_jxr_r_MB_LP`): the LP coefficients of every channel, unpredicted.
    pub fn lp(&mut self, r: &mut BitReader, c: &mut [i32], mx: u32, tile_w: u32) -> Result<()> {
        if mx % 16 == 0 {
            self.lp_scan.reset_totals();
        }
        let sub = matches!(self.fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
        let full_planes = if sub { 2 } else { self.channels };
        let cbplp = if self.fmt.is_yuv() {
            let max = full_planes as u32 * 4 - 5;
            let cbplp = if self.cbplp_zero <= 0 || self.cbplp_max < 0 {
                let table = if sub { &vlc::CBPLP_42X } else { &vlc::CBPLP_444 };
                let v = vlc::decode(r, table) as u32;
                if self.cbplp_max < self.cbplp_zero {
                    max - v
                } else {
                    v
                }
            } else {
                r.read(full_planes as u32)
            };
            self.cbplp_zero = (self.cbplp_zero + 1 - if cbplp == 0 { 4 } else { 0 }).clamp(-8, 7);
            self.cbplp_max = (self.cbplp_max + 1 - if cbplp == max { 4 } else { 0 }).clamp(-8, 7);
            cbplp
        } else {
            let mut cbplp = 0;
            for ch in 0..self.channels {
                cbplp |= r.read(1) << ch;
            }
            cbplp
        };
        let mut input = [[0i32; 16]; MAX_CHANNELS];
        let mut lap_mean = [0i32; 2];
        let mut pairs = [RunLevel::default(); 16];
        for ndx in 0..full_planes {
            let chroma = ndx > 0;
            let mut nonzero = 0;
            if (cbplp >> ndx) & 1 != 0 {
                let location = match (self.fmt, chroma) {
                    (ClrFmt::Yuv420, true) => 10,
                    (ClrFmt::Yuv422, true) => 2,
                    _ => 1,
                };
                nonzero = self.block(r, chroma, BAND_LP, location, &mut pairs)?;
                if sub && chroma {
                    let mut temp = [0i32; 16];
                    let mut i = 0usize;
                    for p in &pairs[..nonzero] {
                        i += p.run as usize;
                        *temp.get_mut(i).ok_or_else(|| corrupt("chroma LP past the end"))? = p.level;
                        i += 1;
                    }
                    const REMAP: [usize; 7] = [4, 1, 2, 3, 5, 6, 7];
                    let (off, count) = if self.fmt == ClrFmt::Yuv420 { (1, 6) } else { (0, 14) };
                    for (k, &t) in temp[..count].iter().enumerate() {
                        let remap = REMAP[(k >> 1) + off];
                        let remap = if self.fmt == ClrFmt::Yuv420 { TRANSPOSE420[remap] } else { TRANSPOSE422[remap] };
                        input[(k & 1) + 1][remap] = t;
                    }
                } else {
                    let mut i = 1usize;
                    for p in &pairs[..nonzero] {
                        i += p.run as usize;
                        if i > 15 {
                            return Err(corrupt("LP past the end"));
                        }
                        let k = self.lp_scan.hit(i - 1);
                        input[ndx][k] = p.level;
                        i += 1;
                    }
                }
            }
            let model_bits = self.model[BAND_LP].bits[usize::from(chroma)];
            lap_mean[usize::from(chroma)] += nonzero as i32;
            if model_bits > 0 {
                match (self.fmt, chroma) {
                    (ClrFmt::Yuv420, true) => {
                        for &k in &TRANSPOSE420[1..4] {
                            input[1][k] = refine(r, input[1][k], model_bits);
                            input[2][k] = refine(r, input[2][k], model_bits);
                        }
                    }
                    (ClrFmt::Yuv422, true) => {
                        for &k in &TRANSPOSE422[1..8] {
                            input[1][k] = refine(r, input[1][k], model_bits);
                            input[2][k] = refine(r, input[2][k], model_bits);
                        }
                    }
                    _ => {
                        for &k in &TRANSPOSE444[1..16] {
                            input[ndx][k] = refine(r, input[ndx][k], model_bits);
                        }
                    }
                }
            }
            match (self.fmt, chroma) {
                (ClrFmt::Yuv420, true) => {
                    for ch in 1..3 {
                        c[ch * MB_COEFFS + 1..ch * MB_COEFFS + 4].copy_from_slice(&input[ch][1..4]);
                    }
                }
                (ClrFmt::Yuv422, true) => {
                    for ch in 1..3 {
                        c[ch * MB_COEFFS + 1..ch * MB_COEFFS + 8].copy_from_slice(&input[ch][1..8]);
                    }
                }
                _ => c[ndx * MB_COEFFS + 1..ndx * MB_COEFFS + 16].copy_from_slice(&input[ndx][1..16]),
            }
        }
        self.update_model(lap_mean, BAND_LP);
        if reset_context(mx, tile_w) {
            self.adapt(
                [V::FirstIndLpLum, V::IndLpLum0, V::IndLpLum1, V::FirstIndLpChr, V::IndLpChr0, V::IndLpChr1],
                &[V::AbsLevelLp0, V::AbsLevelLp1],
            );
        }
        Ok(())
    }

    /// MB_CBP (`_jxr_r_MB_CBP` and `r_PredCBP`): the coded-block patterns of every channel,
    /// predicted from the neighbours' (`left`/`top`: their patterns, inside the tile).
    pub fn cbp(&mut self, r: &mut BitReader, left: Option<&[u32]>, top: Option<&[u32]>, out: &mut [u32]) -> Result<()> {
        const FLC: [u32; 6] = [0, 2, 1, 2, 2, 0];
        const OFF: [usize; 6] = [0, 4, 2, 8, 12, 1];
        const OUT: [u32; 16] = [0, 15, 3, 12, 1, 2, 4, 8, 5, 6, 9, 10, 7, 11, 13, 14];
        let mut diff = [0u32; MAX_CHANNELS];
        let per_channel = matches!(self.fmt, ClrFmt::Yuvk | ClrFmt::NComponent);
        let coded_channels = if per_channel { self.channels } else { 1 };
        let five = matches!(self.fmt, ClrFmt::YOnly | ClrFmt::Yuvk | ClrFmt::NComponent);
        for chan in 0..coded_channels {
            let ctx = &mut self.vlc[V::NumCbp as usize];
            let num = vlc::decode(r, &vlc::NUM_CBP[ctx.table as usize]);
            ctx.disc += vlc::NUM_CBP_DELTA[num];
            let cbp = refine_cbp(r, num);
            for blk in 0..4 {
                if cbp & (1 << blk) == 0 {
                    continue;
                }
                let ctx = &mut self.vlc[V::NumBlkCbp as usize];
                let num_blk = if five {
                    let n = vlc::decode(r, &vlc::NUM_CBP[ctx.table as usize]);
                    ctx.disc += vlc::NUM_CBP_DELTA[n];
                    n
                } else {
                    let n = vlc::decode(r, &vlc::NUM_BLKCBP_YUV[ctx.table as usize]);
                    ctx.disc += vlc::NUM_BLKCBP9_DELTA[n];
                    n
                };
                let mut val = num_blk + 1;
                let mut blkcbp = 0u32;
                if val >= 6 {
                    let chr = vlc::decode(r, &vlc::VALUE_012) as u32;
                    blkcbp = 0x10 * (chr + 1);
                    if val >= 9 {
                        val += vlc::decode(r, &vlc::VALUE_012);
                    }
                    val -= 6;
                }
                let code = OFF[val] + r.read(FLC[val]) as usize;
                blkcbp += OUT[code];
                match self.fmt {
                    ClrFmt::Yuv444 => {
                        diff[0] |= (blkcbp & 0xF) << (blk * 4);
                        for (bit, ch) in [(0x10, 1), (0x20, 2)] {
                            if blkcbp & bit != 0 {
                                let n = vlc::decode(r, &vlc::NUM_CH_BLK);
                                diff[ch] |= refine_cbp(r, n + 1) << (blk * 4);
                            }
                        }
                    }
                    ClrFmt::Yuv422 => {
                        const SHIFT: [u32; 4] = [0, 1, 4, 5];
                        diff[0] |= (blkcbp & 0xF) << (blk * 4);
                        for (bit, ch) in [(0x10, 1), (0x20, 2)] {
                            if blkcbp & bit != 0 {
                                let v = vlc::decode(r, &vlc::VALUE_012);
                                diff[ch] |= SHIFT[v + 1] << SHIFT[blk];
                            }
                        }
                    }
                    ClrFmt::Yuv420 => {
                        diff[0] |= (blkcbp & 0xF) << (blk * 4);
                        diff[1] |= ((blkcbp >> 4) & 1) << blk;
                        diff[2] += ((blkcbp >> 5) & 1) << blk;
                    }
                    _ => diff[chan] |= blkcbp << (blk * 4),
                }
            }
        }
        for ch in 0..self.channels {
            let chroma = usize::from(ch > 0);
            let state = self.cbp_model.state[chroma];
            let (cbp, n) = predict::predict_cbp(self.fmt, ch, diff[ch], state, left.map(|l| l[ch]), top.map(|t| t[ch]));
            self.cbp_model.update(chroma, n);
            out[ch] = cbp;
        }
        Ok(())
    }

    /// MB_HP (`_jxr_r_MB_HP`): the HP coefficients of every channel given the coded-block
    /// patterns and the HP prediction mode; with `flex_inline` (spatial mode with flexbits)
    /// each block's flexbits follow it. Returns the model bits used (what the flexbits of a
    /// separate FLEXBITS packet need).
    #[allow(clippy::too_many_arguments)]
    pub fn hp(
        &mut self,
        reader: &mut BitReader,
        c: &mut [i32],
        cbp: &[u32],
        mode: u8,
        mx: u32,
        tile_w: u32,
        flex_inline: bool,
    ) -> Result<[u32; 2]> {
        if mx % 16 == 0 {
            self.hp_hor.reset_totals();
            self.hp_ver.reset_totals();
        }
        let bits = self.model[BAND_HP].bits;
        // A local copy of the reader stays in registers.
        let mut local = reader.clone();
        let r = &mut local;
        let mut lap_mean = [0i32; 2];
        let mut pairs = [RunLevel::default(); 16];
        for ch in 0..self.channels {
            let chroma = ch > 0;
            let blocks = predict_blocks(self.fmt, ch);
            let model_bits = bits[usize::from(chroma)];
            let mut pattern = cbp[ch];
            for block in 0..blocks {
                let b = if blocks == 16 { HP_BLOCK_ORDER[block] } else { block };
                if pattern & 1 != 0 {
                    let n = self.block(r, chroma, BAND_HP, 1, &mut pairs)?;
                    // The block's coefficients are zero until here (the row was cleared):
                    // write each level where the adaptive scan puts it.
                    let block = &mut c[ch * MB_COEFFS + hp(b, 1) - 1..][..16];
                    let scan = if mode == 1 { &mut self.hp_ver } else { &mut self.hp_hor };
                    let mut k = 1usize;
                    for p in &pairs[..n] {
                        k += p.run as usize;
                        if k >= 16 {
                            return Err(corrupt("HP past the end"));
                        }
                        block[scan.hit(k - 1)] = p.level.wrapping_shl(model_bits);
                        k += 1;
                    }
                    lap_mean[usize::from(chroma)] += n as i32;
                }
                if flex_inline {
                    self.block_flex(r, c, ch, b, model_bits);
                }
                pattern >>= 1;
            }
        }
        *reader = local;
        self.update_model(lap_mean, BAND_HP);
        if reset_context(mx, tile_w) {
            self.adapt(
                [V::FirstIndHpLum, V::IndHpLum0, V::IndHpLum1, V::FirstIndHpChr, V::IndHpChr0, V::IndHpChr1],
                &[V::AbsLevelHp0, V::AbsLevelHp1, V::NumCbp, V::NumBlkCbp],
            );
        }
        Ok(bits)
    }

    /// BLOCK_FLEXBITS of block `b` of channel `ch` (see [`block_flex`]).
    #[inline]
    pub fn block_flex(&mut self, r: &mut BitReader, c: &mut [i32], ch: usize, b: usize, model_bits: u32) {
        block_flex(r, c, ch, b, model_bits, self.trim);
    }
}

/// BLOCK_FLEXBITS (`r_BLOCK_FLEXBITS`): the refinement bits of all 15 HP coefficients of block
/// `b` of channel `ch`, coded or not, `model_bits − trim` each (none when trim ≥ model bits).
#[inline(always)]
pub fn block_flex(r: &mut BitReader, c: &mut [i32], ch: usize, b: usize, model_bits: u32, trim: u32) {
    if trim >= model_bits {
        return;
    }
    // Model bits are at most 15: a coefficient takes at most 16 bits (15 and a sign), so one
    // refill to 56 bits serves three coefficients.
    let n = (model_bits - trim).min(15);
    let base = ch * MB_COEFFS + hp(b, 1);
    let block: &mut [i32; 15] = (&mut c[base..base + 15]).try_into().expect("a block is 15 coefficients");
    for group in &FLEX_ORDER {
        r.fill();
        for &i in group {
            let cur = block[usize::from(i)];
            // n raw bits, then (for a coefficient that was zero and gets a non-zero value) a
            // sign bit: peek both, consume what is there.
            let v = r.peek_buffered(n + 1);
            let fine = (v >> 1) as i32;
            let signed = u32::from(cur == 0) & u32::from(fine != 0);
            r.skip(n + signed);
            // The sign to apply, as a mask: the coefficient's own (zero for a zero coefficient),
            // or the bit read (only read for a zero coefficient).
            let mask = (cur >> 31) | -((signed & v & 1) as i32);
            let f = fine.wrapping_shl(trim);
            block[usize::from(i)] = cur.wrapping_add((f ^ mask).wrapping_sub(mask));
        }
    }
}

/// The HP coefficients of a block in refinement order ([`TRANSPOSE444`] without the DC), as
/// indices into the block's 15 coefficients, in groups of three (one refill each).
const FLEX_ORDER: [[u8; 3]; 5] = {
    let mut order = [[0; 3]; 5];
    let mut i = 0;
    while i < 15 {
        order[i / 3][i % 3] = (TRANSPOSE444[i + 1] - 1) as u8;
        i += 1;
    }
    order
};

/// MB_FLEXBITS (`_jxr_r_MB_FLEXBITS`): the flexbits of every block of a macroblock (`c`, all
/// `channels`), from a FLEXBITS packet, with the HP model bits the macroblock was coded with.
pub fn flex_mb(reader: &mut BitReader, c: &mut [i32], fmt: ClrFmt, channels: usize, trim: u32, model_bits: [u32; 2]) {
    // A local copy of the reader stays in registers.
    let mut local = reader.clone();
    let r = &mut local;
    for ch in 0..channels {
        let blocks = predict_blocks(fmt, ch);
        for block in 0..blocks {
            let b = if blocks == 16 { HP_BLOCK_ORDER[block] } else { block };
            block_flex(r, c, ch, b, model_bits[usize::from(ch > 0)], trim);
        }
    }
    *reader = local;
}

/// HP blocks of channel `ch`.
fn predict_blocks(fmt: ClrFmt, ch: usize) -> usize {
    match (fmt, ch) {
        (ClrFmt::Yuv420, 1..) => 4,
        (ClrFmt::Yuv422, 1..) => 8,
        _ => 16,
    }
}

/// Adaptation point: every 16th macroblock of a tile row, and its last one (`_jxr_ResetContext`).
#[inline]
fn reset_context(mx: u32, tile_w: u32) -> bool {
    mx % 16 == 0 || mx + 1 == tile_w
}

/// REFINE_LP (`r_REFINE_LP`): `model_bits` raw low bits, and a sign for a value that was zero.
#[inline]
fn refine(r: &mut BitReader, coeff: i32, model_bits: u32) -> i32 {
    let fine = r.read(model_bits) as i32;
    if coeff > 0 {
        coeff.wrapping_shl(model_bits).wrapping_add(fine)
    } else if coeff < 0 {
        coeff.wrapping_shl(model_bits).wrapping_sub(fine)
    } else if fine != 0 && r.bit() {
        -fine
    } else {
        fine
    }
}

/// REFINE_CBP (`r_REFINE_CBP`): a 4-bit pattern with `num` bits set.
fn refine_cbp(r: &mut BitReader, num: usize) -> u32 {
    match num {
        1 => 1 << r.read(2),
        2 => vlc::REFINE_CBP2_VALUES[vlc::decode(r, &vlc::REFINE_CBP2)],
        3 => 0xF ^ (1 << r.read(2)),
        4 => 0xF,
        _ => 0,
    }
}
