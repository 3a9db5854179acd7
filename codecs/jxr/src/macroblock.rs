//! The macroblock layer (T.832 8.7, decoding per 9.2): DC, LP with CBPLP, CBPHP, HP with
//! run-level symbols, refinement bits and FLEXBITS, for one plane of one tile. The syntax
//! follows T.835's `r_parse.c` (`_jxr_r_MB_DC`, `_jxr_r_MB_LP`, `_jxr_r_MB_CBP`,
//! `_jxr_r_MB_HP`, `r_DECODE_BLOCK`, `r_BLOCK_FLEXBITS`), which matches jxrlib's
//! `segdec.c` on every stream checked.
//!
//! Values are written quantized (model bits and flexbits included) into a macroblock's
//! coefficient array (all channels, [`MB_COEFFS`] each, layout of [`crate::mb`]); prediction
//! and dequantization come later.
//!
//! [`PlaneEncoder`] is the exact mirror: it writes, from such arrays, what [`PlaneDecoder`]
//! reads back, with the same adaptive state ([`EntropyState`]) adapting at the same points.

// Loops over channel, block and bit indices mirror the syntax of T.832 and T.835.
#![allow(clippy::needless_range_loop)]

use crate::bits::{BitReader, BitWriter};
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
/// The 422 chroma CBP: block `blk` of the pattern coded per 8×8 quad holds bits
/// `SHIFT422[blk]` and `SHIFT422[blk] + 2` of the 8-block pattern; the coded value 0/1/2
/// selects `SHIFT422[v + 1]`: the first, the second, or both.
const SHIFT422: [u32; 4] = [0, 1, 4, 5];
/// The order of a luma macroblock's blocks in the bitstream: 2×2 quads (T.835 `_jxr_hp_scan_map`).
const HP_BLOCK_ORDER: [usize; 16] = [0, 1, 4, 5, 2, 3, 6, 7, 8, 9, 12, 13, 10, 11, 14, 15];
/// The order of the blocks of 420 and 422 chroma: their own.
const NATURAL_ORDER: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15];

fn corrupt(what: &str) -> Error {
    Error::invalid(format!("JPEG XR: corrupt macroblock data ({what})"))
}

/// The adaptive entropy-coding state of one plane in one tile (reset at each tile start):
/// VLC table choice (T.832 5.5.5), model bits (5.5.6), CBPHP prediction (5.5.7), CBPLP
/// counters (5.5.8) and adaptive scans (5.7). Decoder and encoder both hold one, so that
/// every adaptation rule exists once.
#[derive(Clone, Debug)]
struct EntropyState {
    fmt: ClrFmt,
    channels: usize,
    vlc: [AdaptiveVlc; V_COUNT],
    model: [Model; 3],
    cbplp_zero: i32,
    cbplp_max: i32,
    lp_scan: Scan,
    hp_hor: Scan,
    hp_ver: Scan,
    cbp_model: CbpModel,
}

/// The entropy decoder of one plane in one tile.
#[derive(Clone, Debug)]
pub struct PlaneDecoder {
    /// TRIM_FLEXBITS of the tile.
    pub trim: u32,
    st: EntropyState,
}

/// One run-level pair: zeros before the coefficient, and its value.
#[derive(Clone, Copy, Debug, Default)]
struct RunLevel {
    run: u32,
    level: i32,
}

impl EntropyState {
    /// The state at the start of a tile.
    fn new(fmt: ClrFmt, channels: usize) -> Self {
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
        EntropyState {
            fmt,
            channels,
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

    /// The end of MB_DC: model update and, at an adaptation point, the DC tables.
    #[inline]
    fn end_dc(&mut self, lap_mean: [i32; 2], mx: u32, tile_w: u32) {
        self.update_model(lap_mean, BAND_DC);
        if reset_context(mx, tile_w) {
            self.vlc[V::AbsLevelDcLum as usize].adapt_one();
            self.vlc[V::AbsLevelDcChr as usize].adapt_one();
        }
    }

    /// The start of MB_LP: the LP scan totals restart every 16 macroblocks.
    #[inline]
    fn start_lp(&mut self, mx: u32) {
        if mx.is_multiple_of(16) {
            self.lp_scan.reset_totals();
        }
    }

    /// The end of MB_LP: model update and, at an adaptation point, the LP tables.
    #[inline]
    fn end_lp(&mut self, lap_mean: [i32; 2], mx: u32, tile_w: u32) {
        self.update_model(lap_mean, BAND_LP);
        if reset_context(mx, tile_w) {
            self.adapt(
                [V::FirstIndLpLum, V::IndLpLum0, V::IndLpLum1, V::FirstIndLpChr, V::IndLpChr0, V::IndLpChr1],
                &[V::AbsLevelLp0, V::AbsLevelLp1],
            );
        }
    }

    /// The start of MB_HP: the HP scan totals restart every 16 macroblocks.
    #[inline]
    fn start_hp(&mut self, mx: u32) {
        if mx.is_multiple_of(16) {
            self.hp_hor.reset_totals();
            self.hp_ver.reset_totals();
        }
    }

    /// The end of MB_HP: model update and, at an adaptation point, the HP and CBP tables.
    #[inline]
    fn end_hp(&mut self, lap_mean: [i32; 2], mx: u32, tile_w: u32) {
        self.update_model(lap_mean, BAND_HP);
        if reset_context(mx, tile_w) {
            self.adapt(
                [V::FirstIndHpLum, V::IndHpLum0, V::IndHpLum1, V::FirstIndHpChr, V::IndHpChr0, V::IndHpChr1],
                &[V::AbsLevelHp0, V::AbsLevelHp1, V::NumCbp, V::NumBlkCbp],
            );
        }
    }

    /// CBPLP of a YUV format (T.832 5.5.8): the largest value, whether the counters say it
    /// is VLC-coded (else `full_planes` raw bits), and whether the VLC symbol is inverted
    /// (`max − cbplp`).
    #[inline]
    fn cbplp_coding(&self, full_planes: usize) -> (u32, bool, bool) {
        let max = full_planes as u32 * 4 - 5;
        (max, self.cbplp_zero <= 0 || self.cbplp_max < 0, self.cbplp_max < self.cbplp_zero)
    }

    /// Counts a YUV CBPLP value (T.832 5.5.8).
    #[inline]
    fn count_cbplp(&mut self, cbplp: u32, max: u32) {
        self.cbplp_zero = (self.cbplp_zero + 1 - if cbplp == 0 { 4 } else { 0 }).clamp(-8, 7);
        self.cbplp_max = (self.cbplp_max + 1 - if cbplp == max { 4 } else { 0 }).clamp(-8, 7);
    }

    /// The CBP of channel `ch` from its coded difference (`r_PredCBP`), and the model update.
    #[inline]
    fn predict_cbp(&mut self, ch: usize, diff: u32, left: Option<&[u32]>, top: Option<&[u32]>) -> u32 {
        let chroma = usize::from(ch > 0);
        let state = self.cbp_model.state[chroma];
        let (cbp, n) = predict::predict_cbp(self.fmt, ch, diff, state, left.map(|l| l[ch]), top.map(|t| t[ch]));
        self.cbp_model.update(chroma, n);
        cbp
    }
}

/// The contexts of a block of run-level symbols: first index, index (by context), absolute
/// level (by context).
#[inline(always)]
fn block_contexts(band: usize, chroma: bool) -> (V, [V; 2], [V; 2]) {
    match (band, chroma) {
        (BAND_LP, false) => (V::FirstIndLpLum, [V::IndLpLum0, V::IndLpLum1], [V::AbsLevelLp0, V::AbsLevelLp1]),
        (BAND_LP, true) => (V::FirstIndLpChr, [V::IndLpChr0, V::IndLpChr1], [V::AbsLevelLp0, V::AbsLevelLp1]),
        (_, false) => (V::FirstIndHpLum, [V::IndHpLum0, V::IndHpLum1], [V::AbsLevelHp0, V::AbsLevelHp1]),
        (_, true) => (V::FirstIndHpChr, [V::IndHpChr0, V::IndHpChr1], [V::AbsLevelHp0, V::AbsLevelHp1]),
    }
}

/// ABSLEVEL_INDEX: the smallest level of each of the first six symbols, and the raw bits
/// that follow it (`r_DECODE_ABS_LEVEL`); symbol 6 escapes to a coded width.
const ABS_REMAP: [u32; 6] = [2, 3, 4, 6, 10, 14];
/// See [`ABS_REMAP`].
const ABS_FIXED: [u32; 6] = [0, 0, 1, 2, 2, 2];
/// The largest absolute level the escape codes: width 29, all ones.
const MAX_ABS_LEVEL: u32 = 2 + (1 << 29) + ((1 << 29) - 1);

/// The encoder's ABSLEVEL_INDEX of each level from 2 to 17 (18 and up take the escape, 6).
const ABS_INDEX: [usize; 18] = {
    let mut t = [0; 18];
    let mut level = 2;
    while level < 18 {
        let mut index = 0;
        while index + 1 < 6 && ABS_REMAP[index + 1] <= level as u32 {
            index += 1;
        }
        t[level] = index;
        level += 1;
    }
    t
};

/// Each level from 2 to 17 written whole for each of the two ABSLEVEL_INDEX tables: the
/// index's code followed by its raw bits, in one code.
const ABS_CODES: [[vlc::Code; 18]; 2] = {
    let tables = [vlc::codes(&vlc::ABS_LEVEL_CODES[0]), vlc::codes(&vlc::ABS_LEVEL_CODES[1])];
    let mut t = [[vlc::Code { bits: 0, len: 0 }; 18]; 2];
    let mut table = 0;
    while table < 2 {
        let mut level = 2;
        while level < 18 {
            let index = ABS_INDEX[level];
            let code = tables[table][index];
            let fixed = ABS_FIXED[index];
            let raw = level as u32 - ABS_REMAP[index];
            t[table][level] = vlc::Code { bits: (code.bits << fixed) | raw, len: code.len + fixed };
            level += 1;
        }
        table += 1;
    }
    t
};

/// The length that marks "no code" in [`RUN_CODES`].
const NO_CODE: u32 = u32::MAX;

/// Every run written whole, by the largest run possible (0..=14) and the run (0..=14):
/// RUN_INDEX's code followed by its raw bits, or the unary codes of a maximum below 5 (the
/// longest run drops its final 1; nothing at all for a maximum of 1). Run 0 is no code at all
/// (zero bits: the coder writes every pair's run without testing whether there is one, a
/// branch on the data that is mispredicted often); [`NO_CODE`] for runs past the maximum.
const RUN_CODES: [[vlc::Code; 15]; 15] = {
    let index = vlc::RUN_INDEX_ENC;
    let mut t = [[vlc::Code { bits: 0, len: NO_CODE }; 15]; 15];
    let mut max_run = 0;
    while max_run < 15 {
        t[max_run][0] = vlc::Code { bits: 0, len: 0 };
        max_run += 1;
    }
    let mut max_run = 1;
    while max_run < 15 {
        let mut run = 1;
        while run <= max_run {
            let r = run as u32;
            t[max_run][run] = if max_run == 1 {
                vlc::Code { bits: 0, len: 0 }
            } else if max_run < 5 {
                if run < max_run {
                    vlc::Code { bits: 1, len: r }
                } else {
                    vlc::Code { bits: 0, len: r - 1 }
                }
            } else {
                let bin = 5 * RUN_BIN[max_run];
                let mut code = vlc::Code { bits: 0, len: NO_CODE };
                let mut i = 0;
                while i < 5 {
                    let (low, bits) = (RUN_REMAP[bin + i], RUN_FIXED[bin + i]);
                    if r >= low && r - low < 1 << bits {
                        code = vlc::Code { bits: (index[i].bits << bits) | (r - low), len: index[i].len + bits };
                        break;
                    }
                    i += 1;
                }
                code
            };
            run += 1;
        }
        max_run += 1;
    }
    t
};

/// RUN_INDEX (`r_DECODE_RUN`): the symbol set (bin) by the largest run possible, and each
/// symbol's smallest run and raw bits.
const RUN_BIN: [usize; 15] = [0, 0, 0, 0, 0, 2, 2, 1, 1, 1, 1, 0, 0, 0, 0];
/// See [`RUN_BIN`].
const RUN_FIXED: [u32; 15] = [0, 0, 1, 1, 3, 0, 0, 1, 1, 2, 0, 0, 0, 0, 1];
/// See [`RUN_BIN`].
const RUN_REMAP: [u32; 15] = [1, 2, 3, 5, 7, 1, 2, 3, 5, 7, 1, 2, 3, 4, 5];

/// ABSLEVEL_INDEX and the raw bits after it in one lookup of the next 8 bits (no code and its
/// bits take more), for each of the two tables: `level << 8 | symbol << 4 | length`. The
/// escape (symbol 6) has level 0 and the length of its code alone.
static ABS_LEVEL_LUT: [[u16; 256]; 2] = [abs_level_lut(0), abs_level_lut(1)];

const fn abs_level_lut(table: usize) -> [u16; 256] {
    let codes = vlc::lut(&vlc::ABS_LEVEL_CODES[table]);
    let mut t = [0u16; 256];
    let mut w = 0;
    while w < 256 {
        let (sym, len) = ((codes[w] >> 4) as usize, (codes[w] & 15) as u32);
        t[w] = if sym < 6 {
            let fixed = ABS_FIXED[sym];
            let raw = (((w as u32) << len) & 0xff) >> (8 - fixed);
            (((ABS_REMAP[sym] + raw) as u16) << 8) | ((sym as u16) << 4) | (len + fixed) as u16
        } else {
            ((sym as u16) << 4) | len as u16
        };
        w += 1;
    }
    t
}

/// [`vlc::ABS_LEVEL_DELTA`] padded to 8 symbols.
const ABS_LEVEL_DELTA8: [i32; 8] = {
    let mut t = [0; 8];
    let mut i = 0;
    while i < 7 {
        t[i] = vlc::ABS_LEVEL_DELTA[i];
        i += 1;
    }
    t
};

/// RUN_INDEX, its raw bits, or the unary code of a short run, in one lookup of the next 8
/// bits, by the largest run possible (0..=14; below 1, a run of 0 in no bits): `run << 4 |
/// length`, exactly what [`PlaneDecoder::run`] reads for every window, codes or not.
static RUN_LUT: [[u8; 256]; 15] = {
    let index = vlc::lut(&vlc::RUN_INDEX_CODES);
    let mut t = [[0u8; 256]; 15];
    let mut max_run = 1;
    while max_run < 15 {
        let mut w = 0;
        while w < 256 {
            let (run, len) = if max_run == 1 {
                (1, 0)
            } else if max_run < 5 {
                // 1, 01, 001, ... with the last code of max_run - 1 zeros.
                let bits = max_run as u32 - 1;
                let mut zeros = 0;
                while zeros < bits && (w >> (7 - zeros)) & 1 == 0 {
                    zeros += 1;
                }
                (zeros + 1, if zeros + 1 < bits { zeros + 1 } else { bits })
            } else {
                let (sym, len) = ((index[w] >> 4) as usize, (index[w] & 15) as u32);
                let i = sym + 5 * RUN_BIN[max_run];
                let fixed = RUN_FIXED[i];
                (RUN_REMAP[i] + ((((w as u32) << len) & 0xff) >> (8 - fixed)), len + fixed)
            };
            t[max_run][w] = ((run << 4) | len) as u8;
            w += 1;
        }
        max_run += 1;
    }
    t
};

/// [`RUN_LUT`] by the location before the run in an HP block after its first symbol (2..=16,
/// the 1-based position after the last coefficient; the largest run is 15 − location, none
/// from 15 on), padded to 32 so that a mask, not a comparison, keeps the index in bounds.
///
/// Entries are `run << 8 | length` (the length in the low 6 bits: a shift by the whole entry
/// shifts by it).
static RUN_AT: [[u16; 256]; 32] = {
    let mut t = [[0u16; 256]; 32];
    let mut location = 1;
    while location < 15 {
        let mut w = 0;
        while w < 256 {
            let e = RUN_LUT[15 - location][w] as u16;
            t[location][w] = (e >> 4) << 8 | (e & 15);
            w += 1;
        }
        location += 1;
    }
    t
};

/// FIRST_INDEX (5 tables) and INDEX (4 tables) with the discriminant deltas of each symbol:
/// `symbol | length << 4 | delta << 8 | delta2 << 16` (deltas as `i8` bytes), by table. The
/// delta tables are the ones the table selects (`AdaptiveVlc::adapt_two` sets them from the
/// table alone: table − 1 and table, both table − 1 at the last, both 0 at the first; the
/// start state, table 1 with delta tables 0 and 1, agrees).
static FIRST_INDEX_LUT: [[u32; 256]; 5] = index_luts(&vlc::FIRST_INDEX_CODES, &vlc::FIRST_INDEX_DELTA);

/// See [`FIRST_INDEX_LUT`].
static INDEX_LUT: [[u32; 256]; 4] = index_luts(&vlc::INDEX_CODES, &vlc::INDEX_DELTA);

/// Every table of [`FIRST_INDEX_LUT`] or [`INDEX_LUT`].
const fn index_luts<const N: usize, const T: usize>(codes: &[[&str; N]; T], deltas: &[[i32; N]]) -> [[u32; 256]; T] {
    let mut t = [[0; 256]; T];
    let mut table = 0;
    while table < T {
        t[table] = index_lut(&codes[table], deltas, table, T - 1);
        table += 1;
    }
    t
}

/// The delta tables (first and second discriminant) that table `table` of `max + 1` selects.
const fn index_deltas(table: usize, max: usize) -> (usize, usize) {
    if table == max {
        (table - 1, table - 1)
    } else if table == 0 {
        (0, 0)
    } else {
        (table - 1, table)
    }
}

const fn index_lut<const N: usize>(codes: &[&str; N], deltas: &[[i32; N]], table: usize, max: usize) -> [u32; 256] {
    let lut = vlc::lut(codes);
    let (d1, d2) = index_deltas(table, max);
    let mut t = [0u32; 256];
    let mut w = 0;
    while w < 256 {
        let (sym, len) = ((lut[w] >> 4) as usize, (lut[w] & 15) as u32);
        let (a, b) = (deltas[d1][sym] as i8 as u8 as u32, deltas[d2][sym] as i8 as u8 as u32);
        t[w] = sym as u32 | (len << 4) | (a << 8) | (b << 16);
        w += 1;
    }
    t
}

/// One symbol of [`FIRST_INDEX_LUT`] or [`INDEX_LUT`] (`table`, at least 8 bits buffered),
/// counted in `ctx`.
#[inline(always)]
fn index_symbol(ctx: &mut AdaptiveVlc, r: &mut BitReader, table: &[u32; 256], max: u8) -> usize {
    debug_assert_eq!(
        (usize::from(ctx.delta), usize::from(ctx.delta2)),
        index_deltas(usize::from(ctx.table), usize::from(max))
    );
    let e = table[r.peek_buffered(8) as usize];
    r.skip((e >> 4) & 15);
    ctx.disc += i32::from((e >> 8) as u8 as i8);
    ctx.disc2 += i32::from((e >> 16) as u8 as i8);
    (e & 15) as usize
}

/// Bits a run-level symbol, its sign, run and level take at most, unless its level escapes
/// (8 + 1 + 8 + 8).
const SYMBOL_BITS: u32 = 25;

/// FIRST_INDEX (T.832 Table 59) or INDEX (Table 60) of MB_HP, the sign bit after it and,
/// when they fit in the same 8 bits, ABSLEVEL_INDEX and its raw bits: one lookup of the next
/// 8 bits for a whole symbol (a symbol of level 1 is the index and the sign alone), and the
/// run that follows it when that fits too and its code does not depend on where it is:
/// after FIRST_INDEX the run before the first coefficient (always at location 1), after INDEX
/// of context 0 (the "folding" tables) a run of 1 or 2, coded `1` and `01` at every location
/// up to 12. One table for each index table, each pair of ABSLEVEL_INDEX tables (of contexts
/// 0 and 1) and, for INDEX, the context, which with the symbol chooses the level's context
/// (`context & (index >> 1)`; after FIRST_INDEX, `index & (index >> 2) & 1`).
#[derive(Clone, Copy)]
struct HpIndexTable {
    /// `value << 20 | RUN_PENDING | run << 12 | pending | symbol << 6 | length`: `length` the
    /// bits the entry consumes (index, sign, level and run; 6 bits with the top two clear, so
    /// that a shift by the whole entry shifts by it), `value` the signed level; when what
    /// follows is `pending` ([`LEVEL_PENDING`]: the level is not within the 8 bits, or
    /// escapes), only its sign (±1), and with [`SIGN_PENDING`] (an index of 8 bits) not even
    /// that (+1). `run`: the run the entry read (0: none); a folding table's entry that read
    /// one gives the symbol as if no run followed (`srn` 1). [`RUN_PENDING`]: after
    /// FIRST_INDEX, a run follows that the entry did not read.
    info: [u32; 256],
    /// The discriminant deltas of the entry, as 16-bit fields of one number (see
    /// [`unpack_fields`]): INDEX's two, then ABSLEVEL_INDEX's of context 0 and of context 1.
    deltas: [u64; 256],
}

/// See [`HpIndexTable::info`].
const LEVEL_PENDING: u32 = 1 << 10;
/// See [`HpIndexTable::info`]; always with [`LEVEL_PENDING`].
const SIGN_PENDING: u32 = 1 << 11;
/// Where [`HpIndexTable::info`] keeps the symbol.
const SYMBOL_SHIFT: u32 = 6;
/// Where [`HpIndexTable::info`] keeps the signed level.
const VALUE_SHIFT: u32 = 20;
/// Where [`HpIndexTable::info`] keeps the run it read.
const RUN_SHIFT: u32 = 12;
/// See [`HpIndexTable::info`].
const RUN_PENDING: u32 = 1 << 16;
/// The largest location at which a folding table's runs are what the entries say (at 13 the
/// code `0` alone is a run of 2; at 14 a run of 1 takes no bits).
const FOLD_LOCATIONS: u32 = 12;

/// An [`HpIndexTable`] that [`hp_index_tables`] overwrites.
const EMPTY_INDEX_TABLE: HpIndexTable = HpIndexTable { info: [0; 256], deltas: [0; 256] };

/// [`HpIndexTable`]s of FIRST_INDEX, by table and the ABSLEVEL_INDEX tables of contexts 0
/// and 1.
static HP_FIRST_TABLES: [[[HpIndexTable; 2]; 2]; 5] = {
    let mut t = [[[EMPTY_INDEX_TABLE; 2]; 2]; 5];
    let mut table = 0;
    while table < 5 {
        let index = index_lut(&vlc::FIRST_INDEX_CODES[table], &vlc::FIRST_INDEX_DELTA, table, 4);
        t[table] = hp_index_tables(&index, None, false);
        table += 1;
    }
    t
};

/// Every [`HpIndexTable`] of INDEX, by context, INDEX table and the ABSLEVEL_INDEX tables of
/// contexts 0 and 1 (the tables of context 0 do not depend on context 1's, and repeat).
static HP_INDEX_TABLES: [[[[HpIndexTable; 2]; 2]; 4]; 2] = {
    let mut t = [[[[EMPTY_INDEX_TABLE; 2]; 2]; 4]; 2];
    let mut table = 0;
    while table < 4 {
        let index = index_lut(&vlc::INDEX_CODES[table], &vlc::INDEX_DELTA, table, 3);
        t[0][table] = hp_index_tables(&index, Some(0), false);
        t[1][table] = hp_index_tables(&index, Some(1), false);
        table += 1;
    }
    t
};

/// The folding [`HpIndexTable`]s of INDEX (context 0, see [`HpIndexTable`]), by INDEX table
/// and the ABSLEVEL_INDEX table of context 0.
static HP_FOLD_TABLES: [[HpIndexTable; 2]; 4] = {
    let mut t = [[EMPTY_INDEX_TABLE; 2]; 4];
    let mut table = 0;
    while table < 4 {
        let index = index_lut(&vlc::INDEX_CODES[table], &vlc::INDEX_DELTA, table, 3);
        let pairs = hp_index_tables(&index, Some(0), true);
        t[table] = [pairs[0][0], pairs[1][0]];
        table += 1;
    }
    t
};

/// [`hp_index_table`] for each pair of ABSLEVEL_INDEX tables.
const fn hp_index_tables(index: &[u32; 256], context: Option<u32>, fold: bool) -> [[HpIndexTable; 2]; 2] {
    let abs = [abs_level_lut(0), abs_level_lut(1)];
    let mut t = [[EMPTY_INDEX_TABLE; 2]; 2];
    let mut a0 = 0;
    while a0 < 2 {
        let mut a1 = 0;
        while a1 < 2 {
            t[a0][a1] = hp_index_table(index, [&abs[a0], &abs[a1]], context, fold);
            a1 += 1;
        }
        a0 += 1;
    }
    t
}

/// One [`HpIndexTable`] from a [`FIRST_INDEX_LUT`] table (`context` `None`) or an
/// [`INDEX_LUT`] table and its context, with the [`ABS_LEVEL_LUT`] tables of the two level
/// contexts; with `fold`, a folding table (of context 0).
const fn hp_index_table(index: &[u32; 256], abs: [&[u16; 256]; 2], context: Option<u32>, fold: bool) -> HpIndexTable {
    let mut out = HpIndexTable { info: [0; 256], deltas: [0; 256] };
    let mut w = 0;
    while w < 256 {
        let e = index[w];
        let (symbol, len) = (e & 15, (e >> 4) & 15);
        let mut fields = [(e >> 8) as u8 as i8 as i64, (e >> 16) as u8 as i8 as i64, 0, 0];
        let (has_level, level_context) = match context {
            None => (symbol & 2 != 0, (symbol & (symbol >> 2) & 1) as usize),
            Some(c) => (symbol & 1 != 0, (c & (symbol >> 1)) as usize),
        };
        let (mut value, mut used, mut pending) = (1i32, len, 0u32);
        if len < 8 {
            if (w << len) & 0x80 != 0 {
                value = -1;
            }
            used += 1;
        } else {
            pending = LEVEL_PENDING | SIGN_PENDING;
        }
        if has_level && pending == 0 {
            let a = abs[level_context][(w << used) & 0xFF];
            let (a_symbol, a_len) = (((a >> 4) & 7) as usize, (a & 15) as u32);
            if a_symbol < 6 && used + a_len <= 8 {
                value *= (a >> 8) as i32;
                used += a_len;
                fields[2 + level_context] = vlc::ABS_LEVEL_DELTA[a_symbol] as i64;
            } else {
                pending = LEVEL_PENDING;
            }
        }
        // The run after the symbol, when the entry reads it.
        let (mut symbol, mut run) = (symbol, 0);
        let rest = (w << used) & 0xFF;
        match context {
            None if symbol & 1 == 0 => {
                let e = RUN_LUT[14][rest];
                let run_len = (e & 15) as u32;
                if pending == 0 && used + run_len <= 8 {
                    run = (e >> 4) as u32;
                    used += run_len;
                } else {
                    pending |= RUN_PENDING;
                }
            }
            Some(_) if fold && pending == 0 && symbol >> 1 == 2 => {
                if used < 8 && rest & 0x80 != 0 {
                    (run, used) = (1, used + 1);
                } else if used + 2 <= 8 && rest >> 6 == 1 {
                    (run, used) = (2, used + 2);
                }
                if run != 0 {
                    symbol = 2 | (symbol & 1);
                }
            }
            _ => {}
        }
        out.info[w] = ((value as u32) << VALUE_SHIFT) | (run << RUN_SHIFT) | pending | (symbol << SYMBOL_SHIFT) | used;
        out.deltas[w] = pack_fields(fields);
        w += 1;
    }
    out
}

/// Four signed numbers as 16-bit fields of one: sums of such numbers are the numbers of the
/// sums, as long as each stays within ±2^15 ([`unpack_fields`]).
const fn pack_fields(f: [i64; 4]) -> u64 {
    (f[0] + (f[1] << 16) + (f[2] << 32) + (f[3] << 48)) as u64
}

/// The four sums in a (wrapping) sum of [`pack_fields`] numbers. Exact while each sum stays
/// within ±2^15: one macroblock has at most 16 × 16 × 14 symbols after a first (16 channels),
/// each changing a sum by at most 2.
#[inline]
fn unpack_fields(sum: u64) -> [i32; 4] {
    let mut rest = sum as i64;
    let mut out = [0; 4];
    for f in &mut out {
        let low = rest as i16;
        *f = i32::from(low);
        rest = (rest - i64::from(low)) >> 16;
    }
    out
}

/// The HP contexts of one MB_HP: the tables of every context (adaptation happens after the
/// macroblock, so they stay fixed through it) and the discriminant sums since its start,
/// written back by [`HpContexts::finish`].
struct HpContexts {
    /// FIRST_INDEX, sign and level by luma (0) and chroma (1).
    first: [&'static HpIndexTable; 2],
    /// INDEX, sign and level by luma/chroma and context.
    index: [[&'static HpIndexTable; 2]; 2],
    /// The folding tables of context 0 by luma/chroma.
    fold: [&'static HpIndexTable; 2],
    /// ABSLEVEL_INDEX by context.
    abs: [&'static [u16; 256]; 2],
    /// Packed sums of the FIRST_INDEX [`HpIndexTable`]s, luma and chroma.
    first_sums: [u64; 2],
    /// Packed sums of the [`HpIndexTable`]s, by 2 × chroma + context.
    index_sums: [u64; 4],
    /// Discriminant sums of ABSLEVEL_INDEX by context (levels outside [`HpIndexTable`]s).
    abs_sums: [i32; 2],
}

/// The VLC contexts of a band's run-level symbols: FIRST_INDEX of luma and chroma, INDEX of
/// luma by context, of chroma by context, and ABSLEVEL_INDEX by context.
type BandContexts = [V; 8];

/// [`BandContexts`] of HP.
const HP_CONTEXTS: BandContexts = [
    V::FirstIndHpLum,
    V::FirstIndHpChr,
    V::IndHpLum0,
    V::IndHpLum1,
    V::IndHpChr0,
    V::IndHpChr1,
    V::AbsLevelHp0,
    V::AbsLevelHp1,
];

/// [`BandContexts`] of LP.
const LP_CONTEXTS: BandContexts = [
    V::FirstIndLpLum,
    V::FirstIndLpChr,
    V::IndLpLum0,
    V::IndLpLum1,
    V::IndLpChr0,
    V::IndLpChr1,
    V::AbsLevelLp0,
    V::AbsLevelLp1,
];

impl HpContexts {
    /// The tables of the contexts `band` of a macroblock (MB_HP's, or MB_LP's full-resolution
    /// blocks: the same codes).
    fn new(vlc: &[AdaptiveVlc; V_COUNT], band: &BandContexts) -> Self {
        let t = |v: V| usize::from(vlc[v as usize].table);
        let [first_lum, first_chr, lum0, lum1, chr0, chr1, abs0, abs1] = *band;
        let (a0, a1) = (t(abs0) & 1, t(abs1) & 1);
        let index = |v: V, context: usize| &HP_INDEX_TABLES[context][t(v)][a0][a1];
        HpContexts {
            first: [&HP_FIRST_TABLES[t(first_lum)][a0][a1], &HP_FIRST_TABLES[t(first_chr)][a0][a1]],
            index: [[index(lum0, 0), index(lum1, 1)], [index(chr0, 0), index(chr1, 1)]],
            fold: [&HP_FOLD_TABLES[t(lum0)][a0], &HP_FOLD_TABLES[t(chr0)][a0]],
            abs: [&ABS_LEVEL_LUT[a0], &ABS_LEVEL_LUT[a1]],
            first_sums: [0; 2],
            index_sums: [0; 4],
            abs_sums: [0; 2],
        }
    }

    /// Adds the sums to the discriminants of the contexts `band` (those of [`new`](Self::new)).
    fn finish(self, vlc: &mut [AdaptiveVlc; V_COUNT], band: &BandContexts) {
        let [first_lum, first_chr, lum0, lum1, chr0, chr1, abs0, abs1] = *band;
        let contexts = [first_lum, first_chr, lum0, lum1, chr0, chr1];
        for (i, (v, sum)) in contexts.into_iter().zip(self.first_sums.into_iter().chain(self.index_sums)).enumerate() {
            debug_assert!({
                let ctx = &vlc[v as usize];
                let max = if i < 2 { 4 } else { 3 };
                (usize::from(ctx.delta), usize::from(ctx.delta2)) == index_deltas(usize::from(ctx.table), max)
            });
            let [d, d2, level0, level1] = unpack_fields(sum);
            let ctx = &mut vlc[v as usize];
            ctx.disc += d;
            ctx.disc2 += d2;
            vlc[abs0 as usize].disc += level0;
            vlc[abs1 as usize].disc += level1;
        }
        vlc[abs0 as usize].disc += self.abs_sums[0];
        vlc[abs1 as usize].disc += self.abs_sums[1];
    }

    /// One entry of `table` (index, sign and perhaps level), its deltas added to `sum`, with
    /// at least 8 bits buffered: [`HpIndexTable::info`].
    #[inline(always)]
    fn index(sum: &mut u64, r: &mut BitReader, table: &HpIndexTable) -> u32 {
        let w = r.peek_buffered(8) as usize;
        let info = table.info[w];
        // The length is the low 6 bits: a shift by `info & 63` needs no masking.
        r.skip(info & 63);
        *sum = sum.wrapping_add(table.deltas[w]);
        info
    }

    /// ABSLEVEL_INDEX of `context` and the level it codes, with at least 8 bits buffered (as
    /// [`PlaneDecoder::abs_level_buffered`]).
    #[inline(always)]
    fn abs_level(&mut self, r: &mut BitReader, context: usize) -> u32 {
        abs_level_in(self.abs[context], &mut self.abs_sums[context], r)
    }

    /// The signed level of an entry whose `info` has [`LEVEL_PENDING`]: the sign bit when it
    /// is pending too, then the level of `context` when the symbol has one.
    #[inline(always)]
    fn pending(&mut self, r: &mut BitReader, info: u32, has_level: bool, context: usize) -> i32 {
        let s = if info & SIGN_PENDING != 0 {
            let bit = r.peek_buffered(1);
            r.skip(1);
            bit.wrapping_neg() as i32
        } else {
            info as i32 >> 31
        };
        let level = if has_level { self.abs_level(r, context) } else { 1 };
        (level as i32 ^ s).wrapping_sub(s)
    }
}

/// ABSLEVEL_INDEX of [`ABS_LEVEL_LUT`] table `table` and the level it codes
/// (`r_DECODE_ABS_LEVEL`), counted in `disc`, with at least 8 bits buffered; the buffer is
/// topped up again after an escape.
#[inline(always)]
fn abs_level_in(table: &[u16; 256], disc: &mut i32, r: &mut BitReader) -> u32 {
    let e = table[r.peek_buffered(8) as usize];
    let index = usize::from((e >> 4) & 7);
    *disc += ABS_LEVEL_DELTA8[index];
    r.skip(u32::from(e & 15));
    if index < 6 {
        return u32::from(e >> 8);
    }
    let level;
    (level, *r) = escaped_level(r.clone());
    level
}

/// The level after the escape symbol of ABSLEVEL_INDEX (`r_DECODE_ABS_LEVEL`) and the reader
/// after it, its bit buffer topped up again. The reader goes in and out by value, so that the
/// address of the caller's (kept in registers through a block) is not taken.
#[cold]
#[inline(never)]
fn escaped_level(mut reader: BitReader) -> (u32, BitReader) {
    let r = &mut reader;
    let mut fixed = 4 + r.read(4);
    if fixed == 19 {
        fixed += r.read(2);
        if fixed == 22 {
            fixed += r.read(3);
        }
    }
    let level = 2u32.wrapping_add(1 << fixed).wrapping_add(r.read(fixed));
    r.fill();
    (level, reader)
}

/// INDEX of the last two positions of a block (`r_DECODE_BLOCK`), with at least 8 bits
/// buffered: after `location` 15, Table 61's code ([`vlc::INDEX2`]); after 16, one bit.
#[inline(always)]
fn end_index(r: &mut BitReader, location: u32) -> u32 {
    if location > 15 {
        let bit = r.peek_buffered(1);
        r.skip(1);
        bit
    } else {
        let e = vlc::INDEX2[r.peek_buffered(8) as usize];
        r.skip(u32::from(e & 15));
        u32::from(e >> 4)
    }
}

/// The tables and sums of one channel's HP blocks (luma or chroma), taken from
/// [`HpContexts`] for the channel and given back after it, so that they stay in registers.
struct ChannelTables {
    /// FIRST_INDEX, sign and level.
    first: &'static HpIndexTable,
    /// INDEX, sign and level by context.
    index: [&'static HpIndexTable; 2],
    /// The folding table of context 0.
    fold: &'static HpIndexTable,
    /// Packed sums of `first`.
    first_sum: u64,
    /// Packed sums of `index` by context.
    sums: [u64; 2],
}

impl HpContexts {
    /// The tables and sums of luma (`chroma` 0) or chroma (1).
    #[inline(always)]
    fn channel(&self, chroma: usize) -> ChannelTables {
        ChannelTables {
            first: self.first[chroma],
            index: self.index[chroma],
            fold: self.fold[chroma],
            first_sum: self.first_sums[chroma],
            sums: [self.index_sums[2 * chroma], self.index_sums[2 * chroma + 1]],
        }
    }

    /// Takes back the sums of [`channel`](Self::channel).
    #[inline(always)]
    fn end_channel(&mut self, chroma: usize, tables: ChannelTables) {
        self.first_sums[chroma] = tables.first_sum;
        self.index_sums[2 * chroma] = tables.sums[0];
        self.index_sums[2 * chroma + 1] = tables.sums[1];
    }
}

/// One HP block of run-level symbols (`r_DECODE_BLOCK` at location 1), each level written
/// (shifted by `model_bits`) straight into `block` (the block's 15 coefficients with the slot
/// before it) where the adaptive `scan` puts it. Returns the number of symbols.
///
/// The INDEX context is 1 only while no run has been coded (it is the first symbol's, then
/// `context & srn`: a run ends it for the rest of the block), so the block runs in two loops:
/// context 1 without runs, then context 0 through the folding table (most runs read with
/// their symbol), each with its table in a register (a table chosen by the context of the
/// previous symbol would put a load of the table's address between one symbol and the
/// next). Locations from 13 on (past [`FOLD_LOCATIONS`], and INDEX2 and one bit at 15 and 16)
/// come after both, symbol by symbol.
#[inline(always)]
fn hp_block(
    r: &mut BitReader,
    t: &mut HpContexts,
    ct: &mut ChannelTables,
    block: &mut [i32; 16],
    scan: &mut Scan,
    model_bits: u32,
) -> Result<i32> {
    r.ensure(SYMBOL_BITS);
    let info = HpContexts::index(&mut ct.first_sum, r, ct.first);
    let index = (info >> SYMBOL_SHIFT) & 15;
    let mut srn = index >> 2;
    let context = ((index & 1) & srn) as usize;
    let mut value = info as i32 >> VALUE_SHIFT;
    if info & LEVEL_PENDING != 0 {
        value = t.pending(r, info, index & 2 != 0, context);
    }
    // location: the 1-based position after the coefficient; the run (read by the entry or
    // now) is at most 14 here.
    let mut location = 2 + ((info >> RUN_SHIFT) & 15);
    if info & RUN_PENDING != 0 {
        let e = RUN_LUT[14][r.peek_buffered(8) as usize];
        r.skip(u32::from(e & 15));
        location += u32::from(e >> 4);
    }
    // Scan entries are 1..=15: the mask only spares a bounds check.
    block[scan.hit(location as usize - 2) & 15] = value.wrapping_shl(model_bits);
    let mut n = 1;
    // Every symbol moves `location` on, and the loops hand over to the end before 16: at
    // most 15 symbols.
    let context = 'end: {
        if context != 0 {
            // Context 1: srn is 1 (the next coefficient follows without a run) until it is not.
            while srn == 1 {
                r.ensure(SYMBOL_BITS);
                location += 1;
                if location >= 15 {
                    break 'end 1;
                }
                let info = HpContexts::index(&mut ct.sums[1], r, ct.index[1]);
                srn = (info >> (SYMBOL_SHIFT + 1)) & 3;
                // The signed level, or its sign alone when the level follows (of context
                // `1 & srn`).
                let value = if info & LEVEL_PENDING != 0 {
                    t.pending(r, info, true, (srn & 1) as usize)
                } else {
                    info as i32 >> VALUE_SHIFT
                };
                block[scan.hit(location as usize - 2) & 15] = value.wrapping_shl(model_bits);
                n += 1;
            }
        }
        // Context 0: srn 2 is a run the entry did not read.
        while srn != 0 {
            r.ensure(SYMBOL_BITS);
            if srn & 1 == 0 {
                location += run_at(r, location);
            }
            location += 1;
            if location > FOLD_LOCATIONS {
                break 'end 0;
            }
            let info = HpContexts::index(&mut ct.sums[0], r, ct.fold);
            srn = (info >> (SYMBOL_SHIFT + 1)) & 3;
            let value =
                if info & LEVEL_PENDING != 0 { t.pending(r, info, true, 0) } else { info as i32 >> VALUE_SHIFT };
            block[scan.hit(location as usize - 2) & 15] = value.wrapping_shl(model_bits);
            // The run the entry read, before the next coefficient.
            location += (info >> RUN_SHIFT) & 15;
            n += 1;
        }
        return Ok(n);
    };
    // From location 13 on, the run before it read (at most four symbols).
    let mut context = context;
    loop {
        if location > 16 {
            return Err(corrupt("a coefficient past the end of a block"));
        }
        let value = if location >= 15 {
            let index = end_index(r, location);
            srn = index >> 1;
            context &= srn as usize;
            let sign = r.peek_buffered(1);
            r.skip(1);
            let level = if index & 1 != 0 { t.abs_level(r, context) } else { 1 };
            let s = sign.wrapping_neg() as i32;
            (level as i32 ^ s).wrapping_sub(s)
        } else {
            let info = HpContexts::index(&mut ct.sums[context & 1], r, ct.index[context & 1]);
            srn = (info >> (SYMBOL_SHIFT + 1)) & 3;
            context &= srn as usize;
            if info & LEVEL_PENDING != 0 {
                t.pending(r, info, true, context)
            } else {
                info as i32 >> VALUE_SHIFT
            }
        };
        block[scan.hit(location as usize - 2) & 15] = value.wrapping_shl(model_bits);
        n += 1;
        if srn == 0 {
            return Ok(n);
        }
        // From location 15 on the largest run is 0 and the table reads nothing; after 16 no
        // position remains, and the check above fails.
        r.ensure(SYMBOL_BITS);
        if srn & 1 == 0 {
            location += run_at(r, location);
        }
        location += 1;
    }
}

/// The run of zeros after `location` in an HP block ([`RUN_AT`]), with at least 8 bits
/// buffered.
#[inline(always)]
fn run_at(r: &mut BitReader, location: u32) -> u32 {
    let e = u32::from(RUN_AT[location as usize & 31][r.peek_buffered(8) as usize]);
    r.skip(e & 63);
    e >> 8
}

/// NUM_BLKCBP's luma classes (`_jxr_r_MB_CBP`): class `val` codes `FLC[val]` raw bits that
/// select `OUT[OFF[val] + bits]`.
const CBP_FLC: [u32; 6] = [0, 2, 1, 2, 2, 0];
/// See [`CBP_FLC`].
const CBP_OFF: [usize; 6] = [0, 4, 2, 8, 12, 1];
/// See [`CBP_FLC`].
const CBP_OUT: [u32; 16] = [0, 15, 3, 12, 1, 2, 4, 8, 5, 6, 9, 10, 7, 11, 13, 14];

impl PlaneDecoder {
    /// The state at the start of a tile.
    pub fn new(fmt: ClrFmt, channels: usize) -> Self {
        PlaneDecoder { trim: 0, st: EntropyState::new(fmt, channels) }
    }

    /// ABSLEVEL_INDEX and the level it codes (`r_DECODE_ABS_LEVEL`).
    #[inline(always)]
    fn abs_level(&mut self, r: &mut BitReader, v: V) -> u32 {
        r.fill();
        Self::abs_level_buffered(&mut self.st.vlc[v as usize], r)
    }

    /// [`abs_level`](Self::abs_level) with at least 8 bits buffered; the buffer is topped up
    /// again after an escape.
    #[inline(always)]
    fn abs_level_buffered(ctx: &mut AdaptiveVlc, r: &mut BitReader) -> u32 {
        abs_level_in(&ABS_LEVEL_LUT[usize::from(ctx.table & 1)], &mut ctx.disc, r)
    }

    /// A run of zeros when at most `max_run` positions remain (`r_DECODE_RUN`), with at least
    /// 8 bits buffered.
    #[inline(always)]
    fn run(r: &mut BitReader, max_run: i32) -> u32 {
        let e = RUN_LUT[max_run.clamp(0, 14) as usize][r.peek_buffered(8) as usize];
        r.skip(u32::from(e & 15));
        u32::from(e >> 4)
    }

    /// One block of run-level symbols (`r_DECODE_BLOCK`), starting at coefficient position
    /// `location` (1 for LP and HP, 10 for 420 chroma LP, 2 for 422 chroma LP). Returns the
    /// number of pairs written to `out`. The bit buffer is topped up once per symbol.
    #[inline(always)]
    fn block(
        &mut self,
        r: &mut BitReader,
        chroma: bool,
        band: usize,
        mut location: u32,
        out: &mut [RunLevel; 16],
    ) -> Result<usize> {
        let (first_v, ind_v, abs_v) = block_contexts(band, chroma);
        let vlc = &mut self.st.vlc;
        r.ensure(SYMBOL_BITS);
        let ctx = &mut vlc[first_v as usize];
        let index = index_symbol(ctx, r, &FIRST_INDEX_LUT[usize::from(ctx.table)], 4);
        let mut srn = index >> 2;
        let mut context = (index & 1) & srn;
        let sign = r.peek_buffered(1);
        r.skip(1);
        let mut level =
            if index & 2 != 0 { Self::abs_level_buffered(&mut vlc[abs_v[context] as usize], r) as i32 } else { 1 };
        if sign != 0 {
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
            r.ensure(SYMBOL_BITS);
            let run = if srn & 1 != 0 { 0 } else { Self::run(r, 15 - location as i32) };
            location += run + 1;
            if location > 16 {
                return Err(corrupt("a coefficient past the end of a block"));
            }
            let index = if location >= 15 {
                end_index(r, location) as usize
            } else {
                let ctx = &mut vlc[ind_v[context] as usize];
                index_symbol(ctx, r, &INDEX_LUT[usize::from(ctx.table)], 3)
            };
            srn = index >> 1;
            context &= srn;
            let sign = r.peek_buffered(1);
            r.skip(1);
            let mut level =
                if index & 1 != 0 { Self::abs_level_buffered(&mut vlc[abs_v[context] as usize], r) as i32 } else { 1 };
            if sign != 0 {
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
        let bits = self.st.model[BAND_DC].bits;
        if self.st.fmt.is_yuv() {
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
            for ch in 0..self.st.channels {
                let chroma = ch > 0;
                let coded = r.bit();
                lap_mean[usize::from(chroma)] += i32::from(coded);
                c[ch * MB_COEFFS] = self.dc_value(r, bits[usize::from(chroma)], false, coded);
            }
        }
        self.st.end_dc(lap_mean, mx, tile_w);
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
    pub fn lp(&mut self, reader: &mut BitReader, c: &mut [i32], mx: u32, tile_w: u32) -> Result<()> {
        // A local copy of the reader stays in registers (see `hp`).
        let mut local = reader.clone();
        let result = self.lp_from(&mut local, c, mx, tile_w);
        *reader = local;
        result
    }

    /// [`lp`](Self::lp) from a reader of its own.
    #[inline(always)]
    fn lp_from(&mut self, r: &mut BitReader, c: &mut [i32], mx: u32, tile_w: u32) -> Result<()> {
        self.st.start_lp(mx);
        let fmt = self.st.fmt;
        let sub = matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
        let full_planes = if sub { 2 } else { self.st.channels };
        let cbplp = if fmt.is_yuv() {
            let (max, coded, inverted) = self.st.cbplp_coding(full_planes);
            let cbplp = if coded {
                let table = if sub { &vlc::CBPLP_42X } else { &vlc::CBPLP_444 };
                let v = vlc::decode(r, table) as u32;
                if inverted {
                    max - v
                } else {
                    v
                }
            } else {
                r.read(full_planes as u32)
            };
            self.st.count_cbplp(cbplp, max);
            cbplp
        } else {
            let mut cbplp = 0;
            for ch in 0..self.st.channels {
                cbplp |= r.read(1) << ch;
            }
            cbplp
        };
        let mut input = [[0i32; 16]; MAX_CHANNELS];
        let mut lap_mean = [0i32; 2];
        let mut pairs = [RunLevel::default(); 16];
        // Full-resolution blocks decode as HP blocks do (the same codes, LP's contexts, the
        // levels unshifted: REFINE_LP follows).
        let mut t = HpContexts::new(&self.st.vlc, &LP_CONTEXTS);
        for ndx in 0..full_planes {
            let chroma = ndx > 0;
            let mut nonzero = 0;
            if (cbplp >> ndx) & 1 != 0 && !(sub && chroma) {
                let mut tables = t.channel(usize::from(chroma));
                nonzero = hp_block(r, &mut t, &mut tables, &mut input[ndx], &mut self.st.lp_scan, 0)? as usize;
                t.end_channel(usize::from(chroma), tables);
            } else if (cbplp >> ndx) & 1 != 0 {
                let location = match fmt {
                    ClrFmt::Yuv420 => 10,
                    _ => 2,
                };
                nonzero = self.block(r, chroma, BAND_LP, location, &mut pairs)?;
                let mut temp = [0i32; 16];
                let mut i = 0usize;
                for p in &pairs[..nonzero] {
                    i += p.run as usize;
                    *temp.get_mut(i).ok_or_else(|| corrupt("chroma LP past the end"))? = p.level;
                    i += 1;
                }
                for (k, &v) in temp[..sub_chroma_lp_len(fmt)].iter().enumerate() {
                    input[(k & 1) + 1][sub_chroma_lp_pos(fmt, k)] = v;
                }
            }
            let model_bits = self.st.model[BAND_LP].bits[usize::from(chroma)];
            lap_mean[usize::from(chroma)] += nonzero as i32;
            if model_bits > 0 {
                match (fmt, chroma) {
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
                        let block: &mut [i32; 15] = (&mut input[ndx][1..16]).try_into().expect("15 LP coefficients");
                        refine_lp_block(r, block, model_bits);
                    }
                }
            }
            match (fmt, chroma) {
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
        t.finish(&mut self.st.vlc, &LP_CONTEXTS);
        self.st.end_lp(lap_mean, mx, tile_w);
        Ok(())
    }

    /// MB_CBP (`_jxr_r_MB_CBP` and `r_PredCBP`): the coded-block patterns of every channel,
    /// predicted from the neighbours' (`left`/`top`: their patterns, inside the tile).
    pub fn cbp(&mut self, r: &mut BitReader, left: Option<&[u32]>, top: Option<&[u32]>, out: &mut [u32]) -> Result<()> {
        let fmt = self.st.fmt;
        let mut diff = [0u32; MAX_CHANNELS];
        let per_channel = matches!(fmt, ClrFmt::Yuvk | ClrFmt::NComponent);
        let coded_channels = if per_channel { self.st.channels } else { 1 };
        let five = matches!(fmt, ClrFmt::YOnly | ClrFmt::Yuvk | ClrFmt::NComponent);
        for chan in 0..coded_channels {
            let ctx = &mut self.st.vlc[V::NumCbp as usize];
            let num = vlc::decode(r, &vlc::NUM_CBP[ctx.table as usize]);
            ctx.count(&vlc::NUM_CBP_DELTA, num);
            let cbp = refine_cbp(r, num);
            for blk in 0..4 {
                if cbp & (1 << blk) == 0 {
                    continue;
                }
                let ctx = &mut self.st.vlc[V::NumBlkCbp as usize];
                let num_blk = if five {
                    let n = vlc::decode(r, &vlc::NUM_CBP[ctx.table as usize]);
                    ctx.count(&vlc::NUM_CBP_DELTA, n);
                    n
                } else {
                    let n = vlc::decode(r, &vlc::NUM_BLKCBP_YUV[ctx.table as usize]);
                    ctx.count(&vlc::NUM_BLKCBP9_DELTA, n);
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
                let code = CBP_OFF[val] + r.read(CBP_FLC[val]) as usize;
                blkcbp += CBP_OUT[code];
                match fmt {
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
                        diff[0] |= (blkcbp & 0xF) << (blk * 4);
                        for (bit, ch) in [(0x10, 1), (0x20, 2)] {
                            if blkcbp & bit != 0 {
                                let v = vlc::decode(r, &vlc::VALUE_012);
                                diff[ch] |= SHIFT422[v + 1] << SHIFT422[blk];
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
        for ch in 0..self.st.channels {
            out[ch] = self.st.predict_cbp(ch, diff[ch], left, top);
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
        self.st.start_hp(mx);
        let bits = self.st.model[BAND_HP].bits;
        // A local copy of the reader stays in registers.
        let mut local = reader.clone();
        // Two copies: the one without flexbits has fewer values to keep in registers.
        let lap_mean = if flex_inline {
            self.hp_blocks::<true>(&mut local, c, cbp, mode, bits)?
        } else {
            self.hp_blocks::<false>(&mut local, c, cbp, mode, bits)?
        };
        *reader = local;
        self.st.end_hp(lap_mean, mx, tile_w);
        Ok(bits)
    }

    /// The blocks of [`hp`](Self::hp) with the model bits `bits`, with the flexbits after
    /// each block when `FLEX`; returns the numbers of coded coefficients (luma, chroma).
    fn hp_blocks<const FLEX: bool>(
        &mut self,
        r: &mut BitReader,
        c: &mut [i32],
        cbp: &[u32],
        mode: u8,
        bits: [u32; 2],
    ) -> Result<[i32; 2]> {
        let mut lap_mean = [0i32; 2];
        let mut t = HpContexts::new(&self.st.vlc, &HP_CONTEXTS);
        let scan = if mode == 1 { &mut self.st.hp_ver } else { &mut self.st.hp_hor };
        for ch in 0..self.st.channels {
            let chroma = usize::from(ch > 0);
            let blocks = predict_blocks(self.st.fmt, ch);
            let model_bits = bits[chroma];
            let mut pattern = cbp[ch];
            let mut tables = t.channel(chroma);
            let chan: &mut [i32; MB_COEFFS] =
                (&mut c[ch * MB_COEFFS..][..MB_COEFFS]).try_into().expect("a channel's coefficients");
            // Every block of the channel is written here, coded or not: the macroblock is not
            // cleared before it is decoded (see `PlaneWork::dc`).
            chan[hp(0, 1)..hp(blocks, 1)].fill(0);
            let order = if blocks == 16 { &HP_BLOCK_ORDER } else { &NATURAL_ORDER };
            let mut count = 0;
            if FLEX {
                for block in 0..blocks {
                    // Below 16: the mask lets the compiler see that the block is in `chan`.
                    let b = order[block] & 15;
                    if pattern & 1 != 0 {
                        let at = hp(b, 1) - 1;
                        let block: &mut [i32; 16] =
                            (&mut chan[at..at + 16]).try_into().expect("a block and the slot before it");
                        count += hp_block(r, &mut t, &mut tables, block, scan, model_bits)?;
                    }
                    block_flex(r, chan, 0, b, model_bits, self.trim);
                    pattern >>= 1;
                }
            } else {
                // The coded blocks alone, in their order.
                pattern &= (1 << blocks) - 1;
                while pattern != 0 {
                    let b = order[pattern.trailing_zeros() as usize & 15] & 15;
                    pattern &= pattern - 1;
                    let at = hp(b, 1) - 1;
                    let block: &mut [i32; 16] =
                        (&mut chan[at..at + 16]).try_into().expect("a block and the slot before it");
                    count += hp_block(r, &mut t, &mut tables, block, scan, model_bits)?;
                }
            }
            lap_mean[chroma] += count;
            t.end_channel(chroma, tables);
        }
        t.finish(&mut self.st.vlc, &HP_CONTEXTS);
        Ok(lap_mean)
    }
}

fn uncodable(what: &str) -> Error {
    Error::invalid(format!("JPEG XR encoder: {what} cannot be coded"))
}

/// The absolute value of a coefficient split at `model_bits` (T.832 5.5.6): the level the
/// run-level symbols code, and the raw low bits (refinement or flexbits).
#[inline]
fn split(v: i32, model_bits: u32) -> (u32, u32) {
    let a = v.unsigned_abs();
    (a >> model_bits, a & ((1u32 << model_bits) - 1))
}

/// The signed level of a coefficient, checked against what ABSLEVEL_INDEX can code.
#[inline]
fn signed_level(v: i32, model_bits: u32) -> Result<i32> {
    let (level, _) = split(v, model_bits);
    if level > MAX_ABS_LEVEL {
        return Err(uncodable("a coefficient this large for its model bits"));
    }
    // level <= 2^30 + 1: fits. The sign without a branch: s is 0 or −1.
    let s = v >> 31;
    Ok(((level as i32) ^ s) - s)
}

/// [`CBP_OUT`] inverted: the code of each 4-block pattern.
const CBP_CODE: [usize; 16] = {
    let mut t = [0; 16];
    let mut c = 0;
    while c < 16 {
        t[CBP_OUT[c] as usize] = c;
        c += 1;
    }
    t
};

/// The class (`val` of `_jxr_r_MB_CBP`) of each code of [`CBP_OUT`].
const CBP_CLASS: [usize; 16] = {
    let mut t = [0; 16];
    let mut c = 0;
    while c < 16 {
        let mut val = 0;
        while !(CBP_OFF[val] <= c && c < CBP_OFF[val] + (1 << CBP_FLC[val])) {
            val += 1;
        }
        t[c] = val;
        c += 1;
    }
    t
};

/// REFINE_CBP written (the inverse of [`refine_cbp`]): a 4-bit pattern whose number of set
/// bits was coded before.
fn refine_cbp_encode(w: &mut BitWriter, pattern: u32) {
    match pattern.count_ones() {
        1 => w.write(pattern.trailing_zeros(), 2),
        2 => {
            let sym = vlc::REFINE_CBP2_VALUES.iter().position(|&p| p == pattern).expect("two of four bits");
            vlc::encode(w, &vlc::REFINE_CBP2_ENC, sym);
        }
        3 => w.write((!pattern & 0xF).trailing_zeros(), 2),
        _ => {}
    }
}

/// REFINE_LP written (the inverse of [`refine`]): the `model_bits` low bits of `v`, and its
/// sign when its level is zero and those bits are not.
#[inline]
fn refine_encode(w: &mut BitWriter, v: i32, model_bits: u32) {
    let (level, fine) = split(v, model_bits);
    // The sign bit, when there is one, goes out with the bits in one write (no branch on the
    // data).
    let e = u32::from(level == 0 && fine != 0);
    w.write((fine << e) | (u32::from(v < 0) & e), model_bits + e);
}

/// The 2-bit part of the 422 chroma pattern `d` that 8×8 quad `blk` holds (see [`SHIFT422`]):
/// bit 0 its first block, bit 1 its second.
#[inline]
fn pair422(d: u32, blk: usize) -> u32 {
    ((d >> SHIFT422[blk]) & 1) | (((d >> (SHIFT422[blk] + 2)) & 1) << 1)
}

/// Run-level pairs of `levels` (in coding order). Returns the count.
#[inline]
fn run_levels(levels: impl Iterator<Item = i32>, out: &mut [RunLevel; 16]) -> usize {
    let (mut n, mut run) = (0, 0);
    for level in levels {
        if level == 0 {
            run += 1;
        } else {
            out[n] = RunLevel { run, level };
            n += 1;
            run = 0;
        }
    }
    n
}

/// The run-level pairs of an HP block (`block[k]` is coefficient `k`, 1..=15, in T.832's
/// numbering) read through the adaptive `scan`, which every non-zero level updates. A hit
/// reorders only the position hit and the one before it, so the positions still to visit keep
/// the coefficients they had at the block's start (what the decoder sees): the levels are
/// taken in that order into a mask of the non-zero positions first (a pass without branches),
/// then one step per set bit. A branch per position on whether its level is zero is
/// mispredicted often (about 0.9 M times in a GoldenGate q 90 encode, callgrind's branch
/// simulation), which costs more time than the mask's extra instructions. Returns the number
/// of pairs.
#[inline(always)]
fn scan_pairs(block: &[i32; 16], scan: &mut vlc::Scan, model_bits: u32, out: &mut [RunLevel; 16]) -> Result<usize> {
    let order = scan.order();
    let (mut mask, mut max) = (0u32, 0u32);
    for (p, &k) in order.iter().enumerate() {
        let level = block[usize::from(k) & 15].unsigned_abs() >> model_bits;
        mask |= u32::from(level != 0) << p;
        max = max.max(level);
    }
    if max > MAX_ABS_LEVEL {
        return Err(uncodable("a coefficient this large for its model bits"));
    }
    let (mut n, mut next) = (0usize, 0u32);
    while mask != 0 {
        let p = mask.trailing_zeros();
        mask &= mask - 1;
        let v = block[usize::from(order[p as usize]) & 15];
        let level = (v.unsigned_abs() >> model_bits) as i32;
        scan.hit(p as usize);
        // The sign without a branch: s is 0 or −1, (level ^ s) − s is level or −level.
        let s = v >> 31;
        out[n & 15] = RunLevel { run: p - next, level: (level ^ s).wrapping_sub(s) };
        n += 1;
        next = p + 1;
    }
    Ok(n)
}

/// Masks out the slot before an HP block's 15 coefficients (a DC or LP coefficient) in passes
/// over 16 values.
const SLOT_MASK: [u32; 16] = {
    let mut m = [u32::MAX; 16];
    m[0] = 0;
    m
};

/// The entropy encoder of one plane in one tile (reset at each tile start): writes what
/// [`PlaneDecoder`] reads, from the same coefficient arrays, adapting its [`EntropyState`] at
/// the same points. After an error, the writer and the state are not usable.
#[derive(Clone, Debug)]
pub struct PlaneEncoder {
    /// TRIM_FLEXBITS of the tile.
    pub trim: u32,
    st: EntropyState,
}

impl PlaneEncoder {
    /// The state at the start of a tile.
    pub fn new(fmt: ClrFmt, channels: usize) -> Self {
        PlaneEncoder { trim: 0, st: EntropyState::new(fmt, channels) }
    }

    /// The HP model bits (luma, chroma) the next macroblock's HP band will be coded with:
    /// its coefficients' lowest bits that become flexbits.
    pub fn hp_model_bits(&self) -> [u32; 2] {
        self.st.model[BAND_HP].bits
    }

    /// ABSLEVEL_INDEX and its raw bits for `level` ≥ 2 (the inverse of `r_DECODE_ABS_LEVEL`):
    /// one write from [`ABS_CODES`] below 18, the escape above.
    #[inline(always)]
    fn abs_level(&mut self, w: &mut BitWriter, v: V, level: u32) -> Result<()> {
        debug_assert!(level >= 2);
        let ctx = &mut self.st.vlc[v as usize];
        if let Some(&index) = ABS_INDEX.get(level as usize) {
            let code = ABS_CODES[usize::from(ctx.table & 1)][level as usize];
            w.put(code.bits, code.len);
            ctx.count(&vlc::ABS_LEVEL_DELTA, index);
            return Ok(());
        }
        self.abs_escape(w, v, level)
    }

    /// [`abs_level`](Self::abs_level) from 18 up: ABSLEVEL_INDEX 6 and a coded width.
    #[inline(never)]
    fn abs_escape(&mut self, w: &mut BitWriter, v: V, level: u32) -> Result<()> {
        if level > MAX_ABS_LEVEL {
            return Err(uncodable("a level this large"));
        }
        let ctx = &mut self.st.vlc[v as usize];
        vlc::encode(w, &vlc::ABS_LEVEL_ENC[ctx.table as usize], 6);
        ctx.count(&vlc::ABS_LEVEL_DELTA, 6);
        // A width of 4..=29 bits, coded in 4 bits, then 2 more from 19 on, then 3 more from
        // 22 on; then level − 2 − 2^width in that width.
        let m = level - 2;
        let fixed = 31 - m.leading_zeros();
        w.write((fixed - 4).min(15), 4);
        if fixed >= 19 {
            w.write((fixed - 19).min(3), 2);
            if fixed >= 22 {
                w.write(fixed - 22, 3);
            }
        }
        w.write(m - (1 << fixed), fixed);
        Ok(())
    }

    /// A run of `run` zeros when at most `max_run` positions remain (the inverse of
    /// `r_DECODE_RUN`; run 0 writes nothing): one write from [`RUN_CODES`].
    #[inline(always)]
    fn run(w: &mut BitWriter, run: u32, max_run: i32) -> Result<()> {
        let code = usize::try_from(max_run)
            .ok()
            .and_then(|m| RUN_CODES.get(m.min(14))?.get(run as usize))
            .filter(|c| c.len != NO_CODE && run as i32 <= max_run)
            .ok_or_else(|| uncodable("a run past the end of a block"))?;
        w.put(code.bits, code.len);
        Ok(())
    }

    /// One block of run-level symbols (the inverse of `r_DECODE_BLOCK`) starting at position
    /// `location`; `pairs` is not empty and ends inside the block. Each index code goes out
    /// with the sign bit that follows it in one write.
    #[inline(always)]
    fn block(
        &mut self,
        w: &mut BitWriter,
        chroma: bool,
        band: usize,
        mut location: u32,
        pairs: &[RunLevel],
    ) -> Result<()> {
        let (first_v, ind_v, abs_v) = block_contexts(band, chroma);
        let n = pairs.len();
        // What follows pair i: 0 nothing, 1 a coefficient right after, 2 one after a run.
        let srn = |i: usize| match pairs.get(i + 1) {
            None => 0usize,
            Some(p) if p.run == 0 => 1,
            Some(_) => 2,
        };
        let first = *pairs.first().ok_or_else(|| uncodable("an empty coded block"))?;
        let mag = first.level.unsigned_abs();
        let next = srn(0);
        let index = (next << 2) | (usize::from(mag > 1) << 1) | usize::from(first.run == 0);
        let ctx = &mut self.st.vlc[first_v as usize];
        let code = vlc::FIRST_INDEX_ENC[ctx.table as usize][index];
        ctx.count2(&vlc::FIRST_INDEX_DELTA, index);
        w.put((code.bits << 1) | u32::from(first.level < 0), code.len + 1);
        let mut context = (index & 1) & next;
        if mag > 1 {
            self.abs_level(w, abs_v[context], mag)?;
        }
        Self::run(w, first.run, 15 - location as i32)?;
        location += first.run + 1;
        for i in 1..n {
            let p = pairs[i];
            Self::run(w, p.run, 15 - location as i32)?;
            location += p.run + 1;
            if location > 16 {
                return Err(uncodable("a coefficient past the end of a block"));
            }
            let next = srn(i);
            let mag = p.level.unsigned_abs();
            let index = (next << 1) | usize::from(mag > 1);
            let sign = u32::from(p.level < 0);
            if location > 15 {
                // The last position: nothing can follow, one bit says whether level > 1.
                w.put(((index as u32 & 1) << 1) | sign, 2);
            } else if location == 15 {
                let code = vlc::INDEX2_ENC[index];
                w.put((code.bits << 1) | sign, code.len + 1);
            } else {
                let ctx = &mut self.st.vlc[ind_v[context] as usize];
                let code = vlc::INDEX_ENC[ctx.table as usize][index];
                ctx.count2(&vlc::INDEX_DELTA, index);
                w.put((code.bits << 1) | sign, code.len + 1);
            }
            context &= next;
            if mag > 1 {
                self.abs_level(w, abs_v[context], mag)?;
            }
        }
        Ok(())
    }

    /// MB_DC (the inverse of `_jxr_r_MB_DC`): the DC of every channel, unpredicted.
    pub fn dc(&mut self, w: &mut BitWriter, c: &[i32], mx: u32, tile_w: u32) -> Result<()> {
        let bits = self.st.model[BAND_DC].bits;
        let channels = self.st.channels;
        // Checked first: nothing is written for a macroblock that cannot be coded.
        for ch in 0..channels {
            let (level, _) = split(c[ch * MB_COEFFS], bits[usize::from(ch > 0)]);
            if level >= MAX_ABS_LEVEL {
                return Err(uncodable("a DC value this large for its model bits"));
            }
        }
        let coded = |ch: usize| split(c[ch * MB_COEFFS], bits[usize::from(ch > 0)]).0 != 0;
        let mut lap_mean = [0i32; 2];
        if self.st.fmt.is_yuv() {
            let flags = (usize::from(coded(0)) << 2) | (usize::from(coded(1)) << 1) | usize::from(coded(2));
            vlc::encode(w, &vlc::DC_YUV_ENC, flags);
            for ch in 0..3 {
                let chroma = ch > 0;
                lap_mean[usize::from(chroma)] += i32::from(coded(ch));
                self.dc_value(w, c[ch * MB_COEFFS], bits[usize::from(chroma)], chroma)?;
            }
        } else {
            for ch in 0..channels {
                let chroma = ch > 0;
                w.bit(coded(ch));
                lap_mean[usize::from(chroma)] += i32::from(coded(ch));
                self.dc_value(w, c[ch * MB_COEFFS], bits[usize::from(chroma)], false)?;
            }
        }
        self.st.end_dc(lap_mean, mx, tile_w);
        Ok(())
    }

    /// DEC_DC written: level + 1 when coded, the raw low bits, the sign of a non-zero value.
    fn dc_value(&mut self, w: &mut BitWriter, v: i32, model_bits: u32, chroma: bool) -> Result<()> {
        let (level, fine) = split(v, model_bits);
        if level != 0 {
            let v_ctx = if chroma { V::AbsLevelDcChr } else { V::AbsLevelDcLum };
            self.abs_level(w, v_ctx, level + 1)?;
        }
        if model_bits > 0 {
            w.write(fine, model_bits);
        }
        if v != 0 {
            w.bit(v < 0);
        }
        Ok(())
    }

    /// MB_LP (the inverse of `_jxr_r_MB_LP`): CBPLP, the LP run-level blocks through the
    /// adaptive LP scan (or the joint U/V block of 420/422 chroma), and the refinement bits.
    pub fn lp(&mut self, w: &mut BitWriter, c: &[i32], mx: u32, tile_w: u32) -> Result<()> {
        self.st.start_lp(mx);
        let fmt = self.st.fmt;
        let sub = matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
        let full_planes = if sub { 2 } else { self.st.channels };
        // The pairs of every plane first (CBPLP precedes them), hitting the scan in the
        // decoder's order: a hit only reorders the position hit and the one before it, so the
        // positions still to visit keep their coefficients.
        let mut pairs = [[RunLevel::default(); 16]; MAX_CHANNELS];
        let mut counts = [0usize; MAX_CHANNELS];
        let mut cbplp = 0u32;
        for ndx in 0..full_planes {
            let chroma = ndx > 0;
            let model_bits = self.st.model[BAND_LP].bits[usize::from(chroma)];
            let mut levels = [0i32; 15];
            if sub && chroma {
                let len = sub_chroma_lp_len(fmt);
                for k in 0..len {
                    levels[k] = signed_level(c[((k & 1) + 1) * MB_COEFFS + sub_chroma_lp_pos(fmt, k)], model_bits)?;
                }
                counts[ndx] = run_levels(levels[..len].iter().copied(), &mut pairs[ndx]);
            } else {
                // The levels in the scan order at the start, a mask of the non-zero ones, then
                // the hits and pairs one set bit at a time (as `scan_pairs` for HP: no branch
                // per position on whether its level is zero).
                let order = self.st.lp_scan.order();
                let mut mask = 0u32;
                for (p, &k) in order.iter().enumerate() {
                    levels[p] = signed_level(c[ndx * MB_COEFFS + usize::from(k)], model_bits)?;
                    mask |= u32::from(levels[p] != 0) << p;
                }
                let (mut n, mut next) = (0usize, 0u32);
                while mask != 0 {
                    let p = mask.trailing_zeros();
                    mask &= mask - 1;
                    self.st.lp_scan.hit(p as usize);
                    pairs[ndx][n & 15] = RunLevel { run: p - next, level: levels[p as usize] };
                    n += 1;
                    next = p + 1;
                }
                counts[ndx] = n;
            }
            cbplp |= u32::from(counts[ndx] > 0) << ndx;
        }
        if fmt.is_yuv() {
            let (max, coded, inverted) = self.st.cbplp_coding(full_planes);
            if coded {
                let table: &[vlc::Code] = if sub { &vlc::CBPLP_42X_ENC } else { &vlc::CBPLP_444_ENC };
                vlc::encode(w, table, (if inverted { max - cbplp } else { cbplp }) as usize);
            } else {
                w.write(cbplp, full_planes as u32);
            }
            self.st.count_cbplp(cbplp, max);
        } else {
            for ch in 0..self.st.channels {
                w.bit((cbplp >> ch) & 1 != 0);
            }
        }
        let mut lap_mean = [0i32; 2];
        for ndx in 0..full_planes {
            let chroma = ndx > 0;
            if counts[ndx] > 0 {
                let location = match (fmt, chroma) {
                    (ClrFmt::Yuv420, true) => 10,
                    (ClrFmt::Yuv422, true) => 2,
                    _ => 1,
                };
                self.block(w, chroma, BAND_LP, location, &pairs[ndx][..counts[ndx]])?;
            }
            lap_mean[usize::from(chroma)] += counts[ndx] as i32;
            let model_bits = self.st.model[BAND_LP].bits[usize::from(chroma)];
            if model_bits > 0 {
                match (fmt, chroma) {
                    (ClrFmt::Yuv420, true) => {
                        for &k in &TRANSPOSE420[1..4] {
                            refine_encode(w, c[MB_COEFFS + k], model_bits);
                            refine_encode(w, c[2 * MB_COEFFS + k], model_bits);
                        }
                    }
                    (ClrFmt::Yuv422, true) => {
                        for &k in &TRANSPOSE422[1..8] {
                            refine_encode(w, c[MB_COEFFS + k], model_bits);
                            refine_encode(w, c[2 * MB_COEFFS + k], model_bits);
                        }
                    }
                    _ => {
                        for &k in &TRANSPOSE444[1..16] {
                            refine_encode(w, c[ndx * MB_COEFFS + k], model_bits);
                        }
                    }
                }
            }
        }
        self.st.end_lp(lap_mean, mx, tile_w);
        Ok(())
    }

    /// MB_CBP and MB_HP: computes each channel's coded-block pattern (bit `j`: the `j`-th
    /// block in bitstream order, [`HP_BLOCK_ORDER`] for 16-block channels) from the HP levels
    /// at the current HP model bits, writes it predicted from the neighbours' patterns
    /// (`left`/`top`, inside the tile) and then the HP blocks, each followed by its flexbits
    /// when `flex_inline`. `cbp_out` receives the patterns (what [`PlaneDecoder::cbp`]
    /// outputs). Returns the HP model bits used, as [`PlaneDecoder::hp`] does.
    #[allow(clippy::too_many_arguments, unsafe_code)]
    pub fn cbp_hp(
        &mut self,
        w: &mut BitWriter,
        c: &[i32],
        left: Option<&[u32]>,
        top: Option<&[u32]>,
        cbp_out: &mut [u32],
        mode: u8,
        mx: u32,
        tile_w: u32,
        flex_inline: bool,
    ) -> Result<[u32; 2]> {
        #[cfg(target_arch = "x86_64")]
        if hdrcodec_core::cpu::avx2() {
            // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
            return unsafe { self.cbp_hp_avx2(w, c, left, top, cbp_out, mode, mx, tile_w, flex_inline) };
        }
        self.cbp_hp_portable(w, c, left, top, cbp_out, mode, mx, tile_w, flex_inline)
    }

    /// [`cbp_hp_portable`](Self::cbp_hp_portable) compiled for AVX2 (the blocks' level masks
    /// and flexbit codes vectorise eight coefficients at a time).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(unsafe_code, clippy::too_many_arguments)]
    unsafe fn cbp_hp_avx2(
        &mut self,
        w: &mut BitWriter,
        c: &[i32],
        left: Option<&[u32]>,
        top: Option<&[u32]>,
        cbp_out: &mut [u32],
        mode: u8,
        mx: u32,
        tile_w: u32,
        flex_inline: bool,
    ) -> Result<[u32; 2]> {
        self.cbp_hp_portable(w, c, left, top, cbp_out, mode, mx, tile_w, flex_inline)
    }

    /// [`cbp_hp`](Self::cbp_hp) for any CPU.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn cbp_hp_portable(
        &mut self,
        w: &mut BitWriter,
        c: &[i32],
        left: Option<&[u32]>,
        top: Option<&[u32]>,
        cbp_out: &mut [u32],
        mode: u8,
        mx: u32,
        tile_w: u32,
        flex_inline: bool,
    ) -> Result<[u32; 2]> {
        let bits = self.st.model[BAND_HP].bits;
        for ch in 0..self.st.channels {
            let model_bits = bits[usize::from(ch > 0)];
            let blocks = predict_blocks(self.st.fmt, ch);
            let mut pattern = 0;
            for j in 0..blocks {
                let b = if blocks == 16 { HP_BLOCK_ORDER[j] } else { j };
                let base = ch * MB_COEFFS + hp(b, 1) - 1;
                let block: &[i32; 16] = c[base..base + 16].try_into().expect("a slot and 15 coefficients");
                // Any level (magnitude above the model bits) not zero: an or of all 15, which
                // vectorises (16 values, the slot before the block masked), instead of a search.
                let any =
                    block.iter().zip(SLOT_MASK).fold(0u32, |a, (&v, m)| a | ((v.unsigned_abs() >> model_bits) & m));
                pattern |= u32::from(any != 0) << j;
            }
            cbp_out[ch] = pattern;
        }
        self.cbp(w, left, top, cbp_out)?;
        self.hp(w, c, cbp_out, mode, mx, tile_w, flex_inline)
    }

    /// MB_CBP (the inverse of `_jxr_r_MB_CBP` and `r_PredCBP`) of the patterns `cbp`.
    fn cbp(&mut self, w: &mut BitWriter, left: Option<&[u32]>, top: Option<&[u32]>, cbp: &[u32]) -> Result<()> {
        let fmt = self.st.fmt;
        let mut diff = [0u32; MAX_CHANNELS];
        // Channel by channel, as the decoder predicts: the chroma state channel 2 sees is
        // the one channel 1 left.
        for ch in 0..self.st.channels {
            let state = self.st.cbp_model.state[usize::from(ch > 0)];
            diff[ch] = predict::unpredict_cbp(fmt, ch, cbp[ch], state, left.map(|l| l[ch]), top.map(|t| t[ch]));
            if self.st.predict_cbp(ch, diff[ch], left, top) != cbp[ch] {
                return Err(uncodable("a coded-block pattern outside the macroblock"));
            }
        }
        let per_channel = matches!(fmt, ClrFmt::Yuvk | ClrFmt::NComponent);
        let coded_channels = if per_channel { self.st.channels } else { 1 };
        let five = matches!(fmt, ClrFmt::YOnly | ClrFmt::Yuvk | ClrFmt::NComponent);
        for chan in 0..coded_channels {
            // Each 8×8 quad: its 4 luma bits and its U and V parts.
            let mut parts = [(0u32, 0u32, 0u32); 4];
            let mut quads = 0u32;
            for blk in 0..4 {
                let y = (diff[chan] >> (blk * 4)) & 0xF;
                let (u, v) = match fmt {
                    ClrFmt::Yuv444 => ((diff[1] >> (blk * 4)) & 0xF, (diff[2] >> (blk * 4)) & 0xF),
                    ClrFmt::Yuv422 => (pair422(diff[1], blk), pair422(diff[2], blk)),
                    ClrFmt::Yuv420 => ((diff[1] >> blk) & 1, (diff[2] >> blk) & 1),
                    _ => (0, 0),
                };
                parts[blk] = (y, u, v);
                if y | u | v != 0 {
                    quads |= 1 << blk;
                }
            }
            let num = quads.count_ones() as usize;
            let ctx = &mut self.st.vlc[V::NumCbp as usize];
            vlc::encode(w, &vlc::NUM_CBP_ENC[ctx.table as usize], num);
            ctx.count(&vlc::NUM_CBP_DELTA, num);
            refine_cbp_encode(w, quads);
            for blk in 0..4 {
                if quads & (1 << blk) == 0 {
                    continue;
                }
                let (y, u, v) = parts[blk];
                let code = CBP_CODE[y as usize];
                let class = CBP_CLASS[code];
                let chr = usize::from(u != 0) | (usize::from(v != 0) << 1);
                // Classes 0..=5 of luma alone are 1..=5 (never 0: the quad is coded); with
                // chroma, 6.. (the last symbol escapes to 9 + a 0/1/2 code).
                let val = if chr == 0 { class } else { class + 6 };
                let num_blk = val.min(9) - 1;
                let ctx = &mut self.st.vlc[V::NumBlkCbp as usize];
                if five {
                    vlc::encode(w, &vlc::NUM_CBP_ENC[ctx.table as usize], num_blk);
                    ctx.count(&vlc::NUM_CBP_DELTA, num_blk);
                } else {
                    vlc::encode(w, &vlc::NUM_BLKCBP_YUV_ENC[ctx.table as usize], num_blk);
                    ctx.count(&vlc::NUM_BLKCBP9_DELTA, num_blk);
                }
                if val >= 6 {
                    vlc::encode(w, &vlc::VALUE_012_ENC, chr - 1);
                    if val >= 9 {
                        vlc::encode(w, &vlc::VALUE_012_ENC, val - 9);
                    }
                }
                w.write((code - CBP_OFF[class]) as u32, CBP_FLC[class]);
                match fmt {
                    ClrFmt::Yuv444 => {
                        for x in [u, v] {
                            if x != 0 {
                                vlc::encode(w, &vlc::NUM_CH_BLK_ENC, x.count_ones() as usize - 1);
                                refine_cbp_encode(w, x);
                            }
                        }
                    }
                    ClrFmt::Yuv422 => {
                        for x in [u, v] {
                            if x != 0 {
                                vlc::encode(w, &vlc::VALUE_012_ENC, x as usize - 1);
                            }
                        }
                    }
                    _ => {}
                }
            }
        }
        Ok(())
    }

    /// MB_HP (the inverse of `_jxr_r_MB_HP`) of the coded blocks of `cbp`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn hp(
        &mut self,
        w: &mut BitWriter,
        c: &[i32],
        cbp: &[u32],
        mode: u8,
        mx: u32,
        tile_w: u32,
        flex_inline: bool,
    ) -> Result<[u32; 2]> {
        self.st.start_hp(mx);
        let bits = self.st.model[BAND_HP].bits;
        let mut lap_mean = [0i32; 2];
        let mut pairs = [RunLevel::default(); 16];
        for ch in 0..self.st.channels {
            let chroma = ch > 0;
            let blocks = predict_blocks(self.st.fmt, ch);
            let model_bits = bits[usize::from(chroma)];
            let mut pattern = cbp[ch];
            for j in 0..blocks {
                let b = if blocks == 16 { HP_BLOCK_ORDER[j] } else { j };
                if pattern & 1 != 0 {
                    let block: &[i32; 16] =
                        c[ch * MB_COEFFS + hp(b, 1) - 1..][..16].try_into().expect("DC slot and 15 coefficients");
                    let scan = if mode == 1 { &mut self.st.hp_ver } else { &mut self.st.hp_hor };
                    let n = scan_pairs(block, scan, model_bits, &mut pairs)?;
                    self.block(w, chroma, BAND_HP, 1, &pairs[..n])?;
                    lap_mean[usize::from(chroma)] += n as i32;
                }
                if flex_inline {
                    block_flex_encode(w, c, ch, b, model_bits, self.trim)?;
                }
                pattern >>= 1;
            }
        }
        self.st.end_hp(lap_mean, mx, tile_w);
        Ok(bits)
    }
}

/// BLOCK_FLEXBITS written (the inverse of [`block_flex`]): for each HP coefficient of block
/// `b` of channel `ch`, in refinement order, its low `model_bits` bits without the `trim`
/// lowest (which must be zero), and the sign of a coefficient whose level is zero.
#[inline(always)]
pub fn block_flex_encode(w: &mut BitWriter, c: &[i32], ch: usize, b: usize, model_bits: u32, trim: u32) -> Result<()> {
    // The block with the slot before it (the DC or LP coefficient the block's position
    // holds), 16 values, so that the passes below are two vectors of eight; `LANES` masks
    // that slot out.
    let base = ch * MB_COEFFS + hp(b, 1) - 1;
    let block: &[i32; 16] = c[base..base + 16].try_into().expect("a slot and 15 coefficients");
    if trim >= model_bits {
        if trim > 0 && block[1..].iter().any(|&v| split(v, model_bits).1 != 0) {
            return Err(uncodable("a flexbit below TRIM_FLEXBITS"));
        }
        return Ok(());
    }
    let mask = (1u32 << model_bits) - 1;
    if trim > 0 {
        let lost = (1u32 << trim) - 1;
        if block[1..].iter().fold(0, |a, &v| a | v.unsigned_abs()) & lost != 0 {
            return Err(uncodable("a flexbit below TRIM_FLEXBITS"));
        }
    }
    let n = model_bits - trim;
    // Every coefficient's code in one branch-free pass (it vectorises): its bits and, for a
    // level of zero with non-zero bits (0 < |v| ≤ mask; the trimmed bits are zero), its
    // sign: at most 16 bits, as model bits are at most 15. Slot 0 is computed and unused.
    let mut codes = [0u32; 16];
    let mut signed = [0u32; 16];
    for ((code, s), &v) in codes.iter_mut().zip(signed.iter_mut()).zip(block) {
        let a = v.unsigned_abs();
        let sg = u32::from(a.wrapping_sub(1) < mask);
        let fine = (a & mask) >> trim;
        *code = (fine + (fine & sg.wrapping_neg())) | (sg & ((v as u32) >> 31));
        *s = sg;
    }
    if n <= 3 {
        // At most 15 · 4 = 60 bits: the whole block in a local accumulator, then two writes.
        let (mut acc, mut len) = (0u64, 0u32);
        for &i in &FLEX_ORDER_SLOT {
            let l = n + signed[usize::from(i)];
            acc = (acc << l) | u64::from(codes[usize::from(i)]);
            len += l;
        }
        if len > 32 {
            w.put((acc >> 32) as u32, len - 32);
            w.put(acc as u32, 32);
        } else {
            w.put(acc as u32, len);
        }
        return Ok(());
    }
    // Two coefficients (at most 32 bits) per write.
    for pair in FLEX_ORDER_SLOT[..14].chunks_exact(2) {
        let (i, j) = (usize::from(pair[0]), usize::from(pair[1]));
        let lb = n + signed[j];
        w.put((codes[i] << lb) | codes[j], n + signed[i] + lb);
    }
    let i = usize::from(FLEX_ORDER_SLOT[14]);
    w.put(codes[i], n + signed[i]);
    Ok(())
}

/// The HP coefficients of a block in refinement order ([`TRANSPOSE444`] without the DC), as
/// indices into the block's 15 coefficients.
const FLEX_ORDER_FLAT: [u8; 15] = {
    let mut order = [0; 15];
    let mut i = 0;
    while i < 15 {
        order[i] = (TRANSPOSE444[i + 1] - 1) as u8;
        i += 1;
    }
    order
};

/// [`FLEX_ORDER_FLAT`] as indices into a block with the slot before it (one more).
const FLEX_ORDER_SLOT: [u8; 15] = {
    let mut order = FLEX_ORDER_FLAT;
    let mut i = 0;
    while i < 15 {
        order[i] += 1;
        i += 1;
    }
    order
};

/// MB_FLEXBITS written (the inverse of [`flex_mb`]): the flexbits of every block of a
/// macroblock for a FLEXBITS packet, with the HP model bits the macroblock was coded with
/// (what [`PlaneEncoder::cbp_hp`] returned).
pub fn flex_mb_encode(
    w: &mut BitWriter,
    c: &[i32],
    fmt: ClrFmt,
    channels: usize,
    trim: u32,
    model_bits: [u32; 2],
) -> Result<()> {
    for ch in 0..channels {
        let blocks = predict_blocks(fmt, ch);
        for j in 0..blocks {
            let b = if blocks == 16 { HP_BLOCK_ORDER[j] } else { j };
            block_flex_encode(w, c, ch, b, model_bits[usize::from(ch > 0)], trim)?;
        }
    }
    Ok(())
}

/// BLOCK_FLEXBITS (`r_BLOCK_FLEXBITS`): the refinement bits of all 15 HP coefficients of block
/// `b` of channel `ch`, coded or not, `model_bits − trim` each (none when trim ≥ model bits).
#[inline(always)]
pub fn block_flex(r: &mut BitReader, c: &mut [i32], ch: usize, b: usize, model_bits: u32, trim: u32) {
    if trim >= model_bits {
        return;
    }
    let at = ch * MB_COEFFS + hp(b, 1);
    let block: &mut [i32; 15] = (&mut c[at..at + 15]).try_into().expect("a block");
    let n = flex_width(model_bits, trim);
    let mut raw = [0u32; 15];
    match n {
        0..=2 => block_flex_raw::<15>(r, block, &mut raw, n),
        3..=6 => block_flex_raw::<8>(r, block, &mut raw, n),
        7..=10 => block_flex_raw::<5>(r, block, &mut raw, n),
        _ => block_flex_raw::<3>(r, block, &mut raw, n),
    }
    // `raw` holds n + 1 bits: as if at the top of n + 1 of 32.
    flex_apply(block, &raw, 31, trim);
}

/// The serial half of [`block_flex`], inside MB_HP: one coefficient at a time on the shared
/// reader (its buffer topped up before every `GROUP`, `GROUP × (n + 1)` ≤ 56), the `n` raw
/// bits and the bit after them right-aligned in `raw` (what [`flex_apply`] reads with a width
/// of 31: constant shifts). For a single block this costs fewer instructions than
/// [`flex_raw_blocks`]' limits, group loads and seek (by 9.6 M on GoldenGate lossless in
/// spatial order).
#[inline(always)]
fn block_flex_raw<const GROUP: usize>(r: &mut BitReader, block: &[i32; 15], raw: &mut [u32; 15], n: u32) {
    debug_assert!(GROUP * (n as usize + 1) <= 56 && (1..=15).contains(&n));
    macro_rules! coefficients {
        ($($k:literal $i:literal),*) => {$({
            if $k % GROUP == 0 {
                r.fill();
            }
            // n raw bits and the bit after them; that bit is the sign only for a zero
            // coefficient with non-zero bits (v ≥ 2).
            let v = r.peek_buffered(n + 1);
            let signed = u32::from(block[$i] == 0) & u32::from(v >= 2);
            r.skip(n + signed);
            raw[$i] = v;
        })*};
    }
    // Position in refinement order, and FLEX_ORDER_FLAT's index there.
    coefficients!(0 3, 1 7, 2 11, 3 0, 4 4, 5 8, 6 12, 7 1, 8 5, 9 9, 10 13, 11 2, 12 6, 13 10, 14 14);
}

/// The flexbits of each coefficient, `model_bits − trim` (1..=15: model bits are at most 15),
/// for `trim < model_bits`.
#[inline(always)]
fn flex_width(model_bits: u32, trim: u32) -> u32 {
    model_bits.saturating_sub(trim).clamp(1, 15)
}

/// The flexbits of one channel of a macroblock (`c`: its coefficients from HP block 0 on, as
/// many blocks as `blocks` names, read in that order), with the channel's model bits: the
/// sign-bit limits of every coefficient ([`flex_limits`]), the raw bits of every block
/// ([`flex_raw_blocks`]), then all of them applied at once ([`flex_apply`]). `scratch` holds
/// the limits and the raw bits (every entry the channel uses is written before it is read).
#[inline(always)]
fn flex_channel(
    r: &mut BitReader,
    c: &mut [i32],
    blocks: &[u8],
    model_bits: u32,
    trim: u32,
    scratch: &mut FlexScratch,
) {
    if trim >= model_bits {
        return;
    }
    let len = 15 * blocks.len();
    debug_assert!(blocks.iter().all(|&b| usize::from(b) < blocks.len()));
    let n = flex_width(model_bits, trim);
    let (limit, raw) = scratch;
    flex_limits(&c[..len], &mut limit[..len], n);
    flex_raw_blocks(r, &limit[..len], &mut raw[..len], blocks, n);
    flex_apply(&mut c[..len], &raw[..len], n, trim);
}

/// [`flex_channel`]'s limits and raw bits, for a macroblock's channels in turn (zeroed once).
type FlexScratch = ([u32; 15 * 16], [u32; 15 * 16]);

/// For each coefficient of `c`, what the top 32 bits of [`flex_raw`]'s bit buffer, as an
/// unsigned number, must exceed for the coefficient to take a sign bit after its `n` (1..=15)
/// flexbits: only a zero coefficient whose flexbits are not all zero does, that is one whose
/// bits exceed `2^(32 − n) − 1`; a non-zero coefficient's limit is `u32::MAX`, which nothing
/// exceeds. A pass of its own, so that it runs in vectors.
#[inline(always)]
fn flex_limits(c: &[i32], limit: &mut [u32], n: u32) {
    // 1 ≤ n ≤ 15: the shift is defined.
    let signed_above = (1u32 << ((32 - n) & 31)) - 1;
    for (l, &x) in limit.iter_mut().zip(c) {
        *l = signed_above | u32::from(x != 0).wrapping_neg();
    }
}

/// The serial half of BLOCK_FLEXBITS for the blocks `blocks` (in that order; block `b` is
/// `limit[15 * b..][..15]`, the limits of [`flex_limits`]), `n` (1..=15) bits a coefficient:
/// for every coefficient, the next 32 bits of the stream at its position into `raw` at its
/// index (its `n` bits at the top, then the bit after them, then whatever follows). Only a
/// coefficient that is zero and gets non-zero bits has a sign bit (the bit after them), so
/// that bit is consumed then and only then; everything else is [`flex_apply`]'s. The
/// coefficients go in refinement order ([`FLEX_ORDER_FLAT`], unrolled so that every index is
/// a constant), the bit buffer topped up once per group of as many as fit in 56 bits.
#[inline(always)]
fn flex_raw_blocks(r: &mut BitReader, limit: &[u32], raw: &mut [u32], blocks: &[u8], n: u32) {
    debug_assert!((1..=15).contains(&n));
    // A coefficient takes at most 16 bits (15 and a sign).
    let n = n.clamp(1, 15);
    // The groups read the stream at their own bit position, handed back at the end.
    let mut bit = r.bit_pos();
    macro_rules! each_block {
        ($group:literal) => {
            for &b in blocks {
                let at = 15 * usize::from(b & 15);
                let (Some(block), Some(out)) = (limit.get(at..at + 15), raw.get_mut(at..at + 15)) else {
                    continue;
                };
                let block: &[u32; 15] = block.try_into().expect("15");
                let out: &mut [u32; 15] = out.try_into().expect("15");
                bit = flex_raw::<$group>(r, bit, block, out, n);
            }
        };
    }
    match n {
        0..=2 => each_block!(15),
        3..=6 => each_block!(8),
        7..=10 => each_block!(5),
        _ => each_block!(3),
    }
    r.seek(bit);
}

/// [`flex_raw_blocks`] of one block, the bit buffer topped up before every `GROUP`
/// coefficients (`GROUP × (n + 1)` ≤ 56).
///
/// The only serial dependency is the sign bit, and the loop keeps it short: the buffer's top
/// 32 bits (what goes to `raw`) are compared with the coefficient's limit ([`flex_limits`])
/// while the buffer is shifted by `n`, and it is shifted once more by the compare's result.
/// From one coefficient's buffer to the next: a shift, a compare, a flag to a register and a
/// shift (`shrx`/`shlx`, no `cl` juggling, where the twin has BMI2). Each group reads the 64
/// bits at its bit position `bit` straight from the data ([`BitReader::bits_at`]) and works
/// on their first 56 followed by a marker bit, whose position at the end tells how many bits
/// the group consumed, so that nothing else is counted per coefficient. Returns the bit
/// position after the block.
#[inline(always)]
fn flex_raw<const GROUP: usize>(r: &BitReader, mut bit: u64, limit: &[u32; 15], raw: &mut [u32; 15], n: u32) -> u64 {
    debug_assert!(GROUP * (n as usize + 1) <= 56 && (1..=15).contains(&n));
    const MARKER: u64 = 0x80;
    let mut buf = 0u64;
    macro_rules! coefficients {
        ($($k:literal $i:literal),*) => {$({
            if $k % GROUP == 0 {
                if $k != 0 {
                    bit += flex_used(buf);
                }
                buf = (r.bits_at(bit) & !0xFF) | MARKER;
            }
            let top = (buf >> 32) as u32;
            raw[$i] = top;
            let sign = u64::from(top > limit[$i]);
            // n ≤ 15 and sign ≤ 1: the shifts are defined.
            buf = (buf << n) << sign;
        })*};
    }
    // Position in refinement order, and FLEX_ORDER_FLAT's index there.
    coefficients!(0 3, 1 7, 2 11, 3 0, 4 4, 5 8, 6 12, 7 1, 8 5, 9 9, 10 13, 11 2, 12 6, 13 10, 14 14);
    bit + flex_used(buf)
}

/// The bits a group of [`flex_raw`] consumed: how far the marker bit of its buffer `buf` moved.
#[inline(always)]
fn flex_used(buf: u64) -> u64 {
    // The marker started at bit 7 and moved at most 56 places.
    u64::from((buf.trailing_zeros() & 63).saturating_sub(7))
}

/// The other half of BLOCK_FLEXBITS: each coefficient of `c` refined by its `n` (1..=15) raw
/// bits from [`flex_raw_blocks`] (the top `n` of 32, shifted by `trim`; `n` = 31 reads the
/// right-aligned bits of [`block_flex_raw`]), with the
/// coefficient's own sign, or for a zero coefficient the sign bit read after them. Lane by
/// lane, without branches, so that it runs in vectors. A zero coefficient whose bits are zero
/// stays zero whatever its sign bit holds.
#[inline(always)]
fn flex_apply(c: &mut [i32], raw: &[u32], n: u32, trim: u32) {
    // 1 ≤ n ≤ 31: both shifts are below 32.
    let (fine_shift, sign_shift) = ((32 - n) & 31, (31 - n) & 31);
    for (x, &v) in c.iter_mut().zip(raw) {
        let cur = *x;
        let fine = ((v >> fine_shift) as i32).wrapping_shl(trim);
        // The sign as a mask: the coefficient's own, or for a zero coefficient the bit read.
        let zero = -i32::from(cur == 0);
        let mask = (cur >> 31) | (zero & -(((v >> sign_shift) & 1) as i32));
        *x = cur.wrapping_add((fine ^ mask).wrapping_sub(mask));
    }
}

/// The order of a luma macroblock's blocks in the bitstream ([`HP_BLOCK_ORDER`]), and that of
/// 420 (the first 4) and 422 (the first 8) chroma.
const FLEX_BLOCKS: [[u8; 16]; 2] = {
    let mut t = [[0; 16]; 2];
    let mut i = 0;
    while i < 16 {
        t[0][i] = HP_BLOCK_ORDER[i] as u8;
        t[1][i] = i as u8;
        i += 1;
    }
    t
};

/// MB_FLEXBITS (`_jxr_r_MB_FLEXBITS`): the flexbits of every block of a macroblock (`c`, all
/// `channels`), from a FLEXBITS packet, with the HP model bits the macroblock was coded with.
/// With BMI2 when [`hdrcodec_core::cpu::bmi2`] allows it.
pub fn flex_mb(reader: &mut BitReader, c: &mut [i32], fmt: ClrFmt, channels: usize, trim: u32, model_bits: [u32; 2]) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::bmi2() {
        // SAFETY: `cpu::bmi2()` is true only when the CPU has AVX2, BMI1, BMI2 and LZCNT
        // (detected at run time), the twin's features.
        #[allow(unsafe_code)]
        unsafe {
            flex_mb_bmi2(reader, c, fmt, channels, trim, model_bits)
        };
        return;
    }
    flex_mb_portable(reader, c, fmt, channels, trim, model_bits);
}

/// [`flex_mb`] compiled for BMI2 (`shlx`: shifts by any register, which the serial pass's
/// variable shifts need; `tzcnt`) and AVX2 (the limits and the refinement, eight lanes at a time).
///
/// # Safety
/// The CPU must support AVX2, BMI1, BMI2 and LZCNT.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt")]
#[allow(unsafe_code)]
unsafe fn flex_mb_bmi2(r: &mut BitReader, c: &mut [i32], fmt: ClrFmt, channels: usize, trim: u32, bits: [u32; 2]) {
    flex_mb_portable(r, c, fmt, channels, trim, bits);
}

/// [`flex_mb`]'s portable twin, also the body compiled into the BMI2 one.
#[inline(always)]
fn flex_mb_portable(reader: &mut BitReader, c: &mut [i32], fmt: ClrFmt, channels: usize, trim: u32, bits: [u32; 2]) {
    if trim >= bits[0].max(bits[1]) {
        // No flexbits in any channel (and no scratch to clear).
        return;
    }
    // A local copy of the reader stays in registers.
    let mut local = reader.clone();
    let r = &mut local;
    let mut scratch = ([0; 15 * 16], [0; 15 * 16]);
    for (ch, cc) in c.chunks_exact_mut(MB_COEFFS).take(channels).enumerate() {
        let blocks = predict_blocks(fmt, ch);
        let order = &FLEX_BLOCKS[usize::from(blocks != 16)][..blocks];
        flex_channel(r, &mut cc[hp(0, 1)..], order, bits[usize::from(ch > 0)], trim, &mut scratch);
    }
    *reader = local;
}

/// Coefficients of the joint U/V LP block of 420 (6) and 422 (14) chroma.
#[inline(always)]
fn sub_chroma_lp_len(fmt: ClrFmt) -> usize {
    if fmt == ClrFmt::Yuv420 {
        6
    } else {
        14
    }
}

/// The LP coefficient (of U for even `k`, V for odd) at position `k` of the joint U/V LP
/// block of 420 or 422 chroma (`_jxr_r_MB_LP`'s remapping).
#[inline(always)]
fn sub_chroma_lp_pos(fmt: ClrFmt, k: usize) -> usize {
    const REMAP: [usize; 7] = [4, 1, 2, 3, 5, 6, 7];
    if fmt == ClrFmt::Yuv420 {
        TRANSPOSE420[REMAP[(k >> 1) + 1]]
    } else {
        TRANSPOSE422[REMAP[k >> 1]]
    }
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
    mx.is_multiple_of(16) || mx + 1 == tile_w
}

/// REFINE_LP (`r_REFINE_LP`): `model_bits` raw low bits, and a sign for a value that was zero.
#[inline(always)]
fn refine(r: &mut BitReader, coeff: i32, model_bits: u32) -> i32 {
    debug_assert!((1..=15).contains(&model_bits));
    // The bits and the sign bit that may follow them, with one check of the buffer.
    r.ensure(model_bits + 1);
    let fine = r.peek_buffered(model_bits) as i32;
    r.skip(model_bits);
    if coeff > 0 {
        coeff.wrapping_shl(model_bits).wrapping_add(fine)
    } else if coeff < 0 {
        coeff.wrapping_shl(model_bits).wrapping_sub(fine)
    } else if fine != 0 {
        let negative = r.peek_buffered(1) != 0;
        r.skip(1);
        if negative {
            -fine
        } else {
            fine
        }
    } else {
        fine
    }
}

/// REFINE_LP of the 15 LP coefficients of a full-resolution channel (`block`: coefficients
/// 1..=15), in [`TRANSPOSE444`] order: [`refine`] of each, read as FLEXBITS are
/// ([`flex_raw`]: `model_bits` bits a coefficient, then a sign bit for a zero coefficient
/// whose bits are not all zero), without a branch on any coefficient.
fn refine_lp_block(r: &mut BitReader, block: &mut [i32; 15], model_bits: u32) {
    debug_assert!((1..=15).contains(&model_bits));
    let n = model_bits.clamp(1, 15);
    let mut limit = [0u32; 15];
    flex_limits(block, &mut limit, n);
    let mut raw = [0u32; 15];
    let bit = r.bit_pos();
    let bit = match n {
        0..=2 => flex_raw::<15>(r, bit, &limit, &mut raw, n),
        3..=6 => flex_raw::<8>(r, bit, &limit, &mut raw, n),
        7..=10 => flex_raw::<5>(r, bit, &limit, &mut raw, n),
        _ => flex_raw::<3>(r, bit, &limit, &mut raw, n),
    };
    r.seek(bit);
    // As `refine`: the coefficient shifted, plus or minus its bits by its own sign, or for a
    // zero coefficient by the sign bit read (1 ≤ n ≤ 15: the shifts are below 32).
    let (fine_shift, sign_shift) = (32 - n, 31 - n);
    for (x, &v) in block.iter_mut().zip(&raw) {
        let cur = *x;
        let fine = (v >> fine_shift) as i32;
        let zero = -i32::from(cur == 0);
        let mask = (cur >> 31) | (zero & -(((v >> sign_shift) & 1) as i32));
        *x = cur.wrapping_shl(n).wrapping_add((fine ^ mask).wrapping_sub(mask));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        fn below(&mut self, n: u32) -> u32 {
            (self.next() % u64::from(n.max(1))) as u32
        }

        /// ±(`low` + a value below `n`).
        fn pm(&mut self, low: u32, n: u32) -> i32 {
            let m = (low + self.below(n)) as i32;
            if self.next() & 1 != 0 {
                -m
            } else {
                m
            }
        }
    }

    /// True for the coefficients the decoder writes: all but the unused LP and HP positions
    /// of 420 and 422 chroma.
    fn meaningful(fmt: ClrFmt, ch: usize, i: usize) -> bool {
        match (fmt, ch) {
            (ClrFmt::Yuv420, 1..) => i < 4 || (16..hp(4, 1)).contains(&i),
            (ClrFmt::Yuv422, 1..) => i < 8 || (16..hp(8, 1)).contains(&i),
            _ => true,
        }
    }

    /// One macroblock of pseudo-random coefficients: `profile` 0 sparse and small, 1 mixed,
    /// 2 dense and large (model bits grow), 3 mixed with occasional large values; whole
    /// channels and whole HP blocks zero now and then. HP values are multiples of 2^`trim`
    /// (so that flexbits trimmed by `trim` lose nothing).
    fn random_mb(rng: &mut Rng, fmt: ClrFmt, channels: usize, profile: u32, trim: u32) -> Vec<i32> {
        let mut c = vec![0i32; channels * MB_COEFFS];
        for ch in 0..channels {
            if rng.below(10) == 0 {
                continue;
            }
            let zero_blocks: Vec<bool> = (0..16).map(|_| rng.below(3) == 0).collect();
            for i in 0..MB_COEFFS {
                if !meaningful(fmt, ch, i) || (i >= 16 && zero_blocks[(i - 16) / 15]) {
                    continue;
                }
                let v = match profile {
                    0 => {
                        if rng.below(8) == 0 {
                            rng.pm(1, 20)
                        } else {
                            0
                        }
                    }
                    2 => rng.pm(0, 1 << 18),
                    _ => match rng.below(16) {
                        0..=5 => 0,
                        6..=10 => rng.pm(1, 3),
                        11..=13 => rng.pm(0, if profile == 1 { 300 } else { 5000 }),
                        14 => rng.pm(0, 64),
                        _ => rng.pm(0, 1 << 18),
                    },
                };
                c[ch * MB_COEFFS + i] = if i >= 16 { v & !((1 << trim) - 1) } else { v };
            }
        }
        c
    }

    /// Encodes `rows` × `width` macroblocks of one tile with [`PlaneEncoder`] (flexbits inline
    /// or in a separate packet), decodes them with [`PlaneDecoder`] and checks every value,
    /// pattern and model bit, and the bit positions. Returns the largest DC and HP model bits.
    fn round_trip(
        fmt: ClrFmt,
        channels: usize,
        (width, rows): (usize, usize),
        flex_inline: bool,
        trim: u32,
        mut gen: impl FnMut(usize, usize) -> Vec<i32>,
    ) -> (u32, u32) {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ (width * 31 + channels) as u64);
        let mbs: Vec<Vec<i32>> = (0..rows * width).map(|i| gen(i % width, i / width)).collect();
        let modes: Vec<u8> = (0..rows * width).map(|_| rng.below(3) as u8).collect();
        let mut enc = PlaneEncoder::new(fmt, channels);
        enc.trim = trim;
        let (mut w, mut wf) = (BitWriter::new(), BitWriter::new());
        let mut cbp_rows = [vec![0u32; width * channels], vec![0u32; width * channels]];
        let mut patterns = Vec::new();
        let mut hp_bits = Vec::new();
        let (mut max_dc, mut max_hp) = (0, 0);
        for my in 0..rows {
            for mx in 0..width {
                let i = my * width + mx;
                let c = &mbs[i];
                let (x, tw) = (mx as u32, width as u32);
                enc.dc(&mut w, c, x, tw).unwrap();
                enc.lp(&mut w, c, x, tw).unwrap();
                // The neighbours' patterns as tiles.rs passes them: two rows, alternating.
                let [c0, c1] = &mut cbp_rows;
                let (cur_row, prev_row) = if my % 2 == 0 { (c0, &*c1) } else { (c1, &*c0) };
                let (before, rest) = cur_row.split_at_mut(mx * channels);
                let left = (mx > 0).then(|| &before[(mx - 1) * channels..]);
                let top = (my > 0).then(|| &prev_row[mx * channels..(mx + 1) * channels]);
                let cur = &mut rest[..channels];
                let bits = enc.cbp_hp(&mut w, c, left, top, cur, modes[i], x, tw, flex_inline).unwrap();
                if !flex_inline {
                    flex_mb_encode(&mut wf, c, fmt, channels, trim, bits).unwrap();
                }
                patterns.push(cur.to_vec());
                hp_bits.push(bits);
                max_dc = max_dc.max(enc.st.model[BAND_DC].bits[0]);
                max_hp = max_hp.max(bits[0]).max(bits[1]);
            }
        }
        let (len, flen) = (w.bit_len(), wf.bit_len());
        let (bytes, fbytes) = (w.into_bytes(), wf.into_bytes());
        let mut dec = PlaneDecoder::new(fmt, channels);
        dec.trim = trim;
        let (mut r, mut rf) = (BitReader::new(&bytes), BitReader::new(&fbytes));
        let mut cbp_rows = [vec![0u32; width * channels], vec![0u32; width * channels]];
        for my in 0..rows {
            for mx in 0..width {
                let i = my * width + mx;
                let (x, tw) = (mx as u32, width as u32);
                let mut d = vec![0i32; channels * MB_COEFFS];
                dec.dc(&mut r, &mut d, x, tw);
                dec.lp(&mut r, &mut d, x, tw).unwrap();
                let [c0, c1] = &mut cbp_rows;
                let (cur_row, prev_row) = if my % 2 == 0 { (c0, &*c1) } else { (c1, &*c0) };
                let (before, rest) = cur_row.split_at_mut(mx * channels);
                let left = (mx > 0).then(|| &before[(mx - 1) * channels..]);
                let top = (my > 0).then(|| &prev_row[mx * channels..(mx + 1) * channels]);
                let cur = &mut rest[..channels];
                dec.cbp(&mut r, left, top, cur).unwrap();
                assert_eq!(cur, &patterns[i][..], "{fmt:?} CBP of macroblock ({mx}, {my})");
                let bits = dec.hp(&mut r, &mut d, cur, modes[i], x, tw, flex_inline).unwrap();
                assert_eq!(bits, hp_bits[i]);
                if !flex_inline {
                    flex_mb(&mut rf, &mut d, fmt, channels, trim, bits);
                }
                if d != mbs[i] {
                    let k = (0..d.len()).find(|&k| d[k] != mbs[i][k]).unwrap();
                    panic!(
                        "{fmt:?}/{channels} flex_inline {flex_inline}: macroblock ({mx}, {my}) channel {} coefficient {}: {} != {}",
                        k / MB_COEFFS,
                        k % MB_COEFFS,
                        d[k],
                        mbs[i][k]
                    );
                }
            }
        }
        assert_eq!(r.bit_pos(), len);
        assert_eq!(rf.bit_pos(), flen);
        assert!(!r.overrun() && !rf.overrun());
        (max_dc, max_hp)
    }

    use crate::testing::FORMATS;

    #[test]
    fn encoder_round_trips_through_the_decoder_for_every_format() {
        for (n, &(fmt, channels)) in FORMATS.iter().enumerate() {
            for (flex_inline, trim) in [(true, 0), (false, 0), (true, 2), (false, 1)] {
                let mut rng = Rng(0x2545_F491_4F6C_DD1D + n as u64 * 977 + u64::from(trim));
                round_trip(fmt, channels, (71, 3), flex_inline, trim, |mx, my| {
                    let profile = ((mx + my * 5) / 9 % 4) as u32;
                    random_mb(&mut rng, fmt, channels, profile, trim)
                });
            }
        }
    }

    /// The AVX2 twin of [`PlaneEncoder::cbp_hp`] writes the bits and leaves the state and
    /// patterns the portable code does, macroblock after macroblock.
    #[test]
    #[allow(unsafe_code)]
    fn cbp_hp_twins_agree() {
        #[cfg(target_arch = "x86_64")]
        if hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Avx2, "cbp_hp") {
            for (n, &(fmt, channels)) in FORMATS.iter().enumerate() {
                for (flex_inline, trim) in [(true, 0), (false, 0), (true, 2)] {
                    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 + n as u64 * 131 + u64::from(trim));
                    let (width, rows) = (37, 3);
                    let mut encs = [PlaneEncoder::new(fmt, channels), PlaneEncoder::new(fmt, channels)];
                    let mut ws = [BitWriter::new(), BitWriter::new()];
                    let mut cbps = [vec![0u32; width * rows * channels], vec![0u32; width * rows * channels]];
                    for e in &mut encs {
                        e.trim = trim;
                    }
                    for i in 0..width * rows {
                        let (mx, my) = (i % width, i / width);
                        let c = random_mb(&mut rng, fmt, channels, ((mx + my * 5) / 9 % 4) as u32, trim);
                        let mode = rng.below(3) as u8;
                        let mut bits = [[0; 2]; 2];
                        for t in 0..2 {
                            let (done, rest) = cbps[t].split_at_mut(i * channels);
                            let left = (mx > 0).then(|| &done[(i - 1) * channels..]);
                            let top = (my > 0).then(|| &done[(i - width) * channels..(i - width + 1) * channels]);
                            let cur = &mut rest[..channels];
                            let (e, w, x, tw) = (&mut encs[t], &mut ws[t], mx as u32, width as u32);
                            e.dc(w, &c, x, tw).unwrap();
                            e.lp(w, &c, x, tw).unwrap();
                            bits[t] = if t == 0 {
                                e.cbp_hp_portable(w, &c, left, top, cur, mode, x, tw, flex_inline).unwrap()
                            } else {
                                // SAFETY: the CPU has AVX2 (checked above).
                                unsafe { e.cbp_hp_avx2(w, &c, left, top, cur, mode, x, tw, flex_inline) }.unwrap()
                            };
                        }
                        assert_eq!(bits[0], bits[1], "{fmt:?} macroblock {i}");
                        assert_eq!(ws[0].bit_len(), ws[1].bit_len(), "{fmt:?} macroblock {i}");
                    }
                    assert_eq!(cbps[0], cbps[1]);
                    assert_eq!(format!("{:?}", encs[0].st), format!("{:?}", encs[1].st));
                    let [a, b] = ws;
                    assert!(a.into_bytes() == b.into_bytes(), "{fmt:?} flex_inline {flex_inline} trim {trim}");
                }
            }
        }
    }

    #[test]
    fn model_bits_reach_their_maximum() {
        for &(fmt, channels) in &FORMATS {
            let mut rng = Rng(0xDEAD_BEEF_CAFE_F00D);
            // 30 dense, large macroblocks (every level non-zero: the model bits climb to 15),
            // then sparse ones (they fall back).
            let (max_dc, max_hp) = round_trip(fmt, channels, (80, 2), true, 0, |mx, _| {
                if mx < 30 {
                    let mut c = random_mb(&mut rng, fmt, channels, 2, 0);
                    for ch in 0..channels {
                        c[ch * MB_COEFFS] = rng.pm((1 << 18) - 999, 1000);
                        for i in 1..MB_COEFFS {
                            if meaningful(fmt, ch, i) {
                                c[ch * MB_COEFFS + i] = rng.pm((1 << 18) - (1 << 16), 1 << 16);
                            }
                        }
                    }
                    c
                } else {
                    random_mb(&mut rng, fmt, channels, 0, 0)
                }
            });
            assert_eq!(max_dc, 15, "{fmt:?}");
            assert!(max_hp >= 12, "{fmt:?}: {max_hp}");
        }
    }

    #[test]
    fn extreme_values_round_trip_or_fail_cleanly() {
        for &(fmt, channels) in &FORMATS {
            // At the tile start the model bits are DC 8, LP 4, HP 0: DC and LP take any i32,
            // HP levels up to 2^30 + 1.
            let max_hp = MAX_ABS_LEVEL as i32;
            let mut c = vec![0i32; channels * MB_COEFFS];
            for ch in 0..channels {
                c[ch * MB_COEFFS] = if ch % 2 == 0 { i32::MIN } else { i32::MAX };
                c[ch * MB_COEFFS + 1] = i32::MAX;
                c[ch * MB_COEFFS + 2] = i32::MIN;
                c[ch * MB_COEFFS + hp(0, 1)] = max_hp;
                c[ch * MB_COEFFS + hp(1, 15)] = -max_hp;
            }
            let mbs = [c.clone(), vec![0; c.len()]];
            round_trip(fmt, channels, (2, 1), true, 0, |mx, _| mbs[mx].clone());
            // Beyond: an error, not a panic.
            let mut cbp = vec![0u32; channels];
            for bad in [i32::MIN, i32::MAX, max_hp + 1] {
                let mut c = c.clone();
                c[hp(0, 1)] = bad;
                let mut enc = PlaneEncoder::new(fmt, channels);
                let mut w = BitWriter::new();
                enc.dc(&mut w, &c, 0, 1).unwrap();
                enc.lp(&mut w, &c, 0, 1).unwrap();
                assert!(enc.cbp_hp(&mut w, &c, None, None, &mut cbp, 0, 0, 1, true).is_err());
            }
            // Flexbits below TRIM_FLEXBITS cannot be coded.
            let mut c = vec![0i32; channels * MB_COEFFS];
            c[hp(3, 4)] = 1;
            let mut w = BitWriter::new();
            assert!(flex_mb_encode(&mut w, &c, fmt, channels, 1, [2, 2]).is_err());
            assert!(flex_mb_encode(&mut w, &c, fmt, channels, 0, [1, 1]).is_ok());
        }
    }

    #[test]
    fn runs_and_levels_round_trip_for_every_length() {
        // Every run at every maximum, and levels around every ABSLEVEL_INDEX boundary.
        let mut enc = PlaneEncoder::new(ClrFmt::YOnly, 1);
        let mut w = BitWriter::new();
        let mut want = Vec::new();
        for max_run in 1..=14 {
            for run in 1..=max_run as u32 {
                PlaneEncoder::run(&mut w, run, max_run).unwrap();
                want.push((Some(max_run), run));
            }
        }
        let mut levels: Vec<u32> = (2..40).collect();
        for e in 4..30 {
            levels.extend([(1 << e) + 1, (1 << e) + 2, (1 << e) + 3, (2 << e) + 1]);
        }
        levels.push(MAX_ABS_LEVEL);
        for &l in &levels {
            enc.abs_level(&mut w, V::AbsLevelHp1, l).unwrap();
            want.push((None, l));
        }
        assert!(enc.abs_level(&mut w, V::AbsLevelHp1, MAX_ABS_LEVEL + 1).is_err());
        assert!(PlaneEncoder::run(&mut w, 5, 4).is_err());
        let bytes = w.into_bytes();
        let mut r = BitReader::new(&bytes);
        let mut dec = PlaneDecoder::new(ClrFmt::YOnly, 1);
        for (max_run, v) in want {
            match max_run {
                Some(m) => {
                    r.fill();
                    assert_eq!(PlaneDecoder::run(&mut r, m), v, "run {v} of at most {m}");
                }
                None => assert_eq!(dec.abs_level(&mut r, V::AbsLevelHp1), v),
            }
        }
        assert_eq!(dec.st.vlc, enc.st.vlc);
    }

    /// ABSLEVEL_INDEX of `table` and the level it codes, read symbol by symbol
    /// (`r_DECODE_ABS_LEVEL`): the index and the level.
    fn read_level(r: &mut BitReader, table: usize) -> (usize, u32) {
        let index = vlc::decode(r, &vlc::lut(&vlc::ABS_LEVEL_CODES[table]));
        if index < 6 {
            return (index, ABS_REMAP[index] + r.read(ABS_FIXED[index]));
        }
        let mut fixed = 4 + r.read(4);
        if fixed == 19 {
            fixed += r.read(2);
            if fixed == 22 {
                fixed += r.read(3);
            }
        }
        (index, 2u32.wrapping_add(1 << fixed).wrapping_add(r.read(fixed)))
    }

    /// RUN_INDEX, its bits and the unary codes, read symbol by symbol (`r_DECODE_RUN`).
    fn read_run(r: &mut BitReader, max_run: i32) -> u32 {
        if max_run <= 1 {
            return max_run.max(0) as u32;
        }
        if max_run < 5 {
            let mut zeros = 0;
            while zeros < max_run as u32 - 1 && !r.bit() {
                zeros += 1;
            }
            return zeros + 1;
        }
        let index = vlc::decode(r, &vlc::lut(&vlc::RUN_INDEX_CODES)) + 5 * RUN_BIN[max_run.min(14) as usize];
        RUN_REMAP[index] + r.read(RUN_FIXED[index])
    }

    #[test]
    fn hp_index_tables_decode_as_index_sign_and_level_do() {
        // (codes, their delta tables, INDEX context or None for FIRST_INDEX, folding, the
        // entries).
        type Case<'a> = (&'a [&'a str], [&'a [i32]; 2], Option<usize>, bool, &'a HpIndexTable);
        let mut cases: Vec<Case> = Vec::new();
        let mut folded = 0;
        for a in [[0usize, 0], [0, 1], [1, 0], [1, 1]] {
            for table in 0..5 {
                let (d1, d2) = index_deltas(table, 4);
                let deltas = [&vlc::FIRST_INDEX_DELTA[d1][..], &vlc::FIRST_INDEX_DELTA[d2][..]];
                cases.push((&vlc::FIRST_INDEX_CODES[table], deltas, None, false, &HP_FIRST_TABLES[table][a[0]][a[1]]));
            }
            for table in 0..4 {
                let (d1, d2) = index_deltas(table, 3);
                let deltas = [&vlc::INDEX_DELTA[d1][..], &vlc::INDEX_DELTA[d2][..]];
                for context in 0..2 {
                    let entries = &HP_INDEX_TABLES[context][table][a[0]][a[1]];
                    cases.push((&vlc::INDEX_CODES[table], deltas, Some(context), false, entries));
                }
                cases.push((&vlc::INDEX_CODES[table], deltas, Some(0), true, &HP_FOLD_TABLES[table][a[0]]));
            }
            for (i, &(codes, deltas, context, fold, entries)) in cases.iter().enumerate() {
                for w in 0..1u32 << 16 {
                    let bytes = [(w >> 8) as u8, w as u8, 0xA5, 0x3C, 0x96, 0x0F, 0xF0, 0x69, 0x11];
                    // Symbol by symbol: the index, the sign bit, ABSLEVEL_INDEX and its bits.
                    let mut r = BitReader::new(&bytes);
                    let symbol = vlc::decode(&mut r, &vlc::lut(codes));
                    let negative = r.bit();
                    let (has_level, level_context) = match context {
                        None => (symbol & 2 != 0, symbol & (symbol >> 2) & 1),
                        Some(c) => (symbol & 1 != 0, c & (symbol >> 1)),
                    };
                    let mut want_fields = [deltas[0][symbol], deltas[1][symbol], 0, 0];
                    let mut level = 1;
                    if has_level {
                        let index;
                        (index, level) = read_level(&mut r, a[level_context]);
                        want_fields[2 + level_context] = vlc::ABS_LEVEL_DELTA[index];
                    }
                    let want = if negative { (level as i32).wrapping_neg() } else { level as i32 };
                    // One entry, and what follows it when that is pending.
                    let mut t = BitReader::new(&bytes);
                    t.fill();
                    let mut contexts = HpContexts {
                        first: [entries; 2],
                        index: [[entries; 2]; 2],
                        fold: [entries; 2],
                        abs: [&ABS_LEVEL_LUT[a[0]], &ABS_LEVEL_LUT[a[1]]],
                        first_sums: [0; 2],
                        index_sums: [0; 4],
                        abs_sums: [0; 2],
                    };
                    let info = HpContexts::index(&mut contexts.index_sums[0], &mut t, entries);
                    let at = (i, a, w);
                    let run = (info >> RUN_SHIFT) & 15;
                    // A folding entry that read its run gives the symbol without it.
                    let shown = if fold && run != 0 { 2 | (symbol & 1) } else { symbol };
                    assert_eq!((info >> SYMBOL_SHIFT) & 15, shown as u32, "{at:?}");
                    let mut value = info as i32 >> VALUE_SHIFT;
                    if info & LEVEL_PENDING != 0 {
                        assert_eq!(value, if info & SIGN_PENDING != 0 { 1 } else { value.signum() }, "{at:?}");
                        assert_eq!(run, 0, "{at:?}");
                        value = contexts.pending(&mut t, info, has_level, level_context);
                    } else {
                        assert_eq!(info & SIGN_PENDING, 0);
                    }
                    let mut fields = unpack_fields(contexts.index_sums[0]);
                    fields[2] += contexts.abs_sums[0];
                    fields[3] += contexts.abs_sums[1];
                    assert_eq!(value, want, "{at:?}");
                    assert_eq!(fields, want_fields, "{at:?}");
                    // The run after the symbol: read by the entry, or read now, as symbol by
                    // symbol (FIRST_INDEX's before the first coefficient, at location 1; a
                    // folding entry's at every location it is used at).
                    match context {
                        None if symbol & 1 == 0 => {
                            assert_eq!(info & RUN_PENDING != 0, run == 0, "{at:?}");
                            let want_run = read_run(&mut r, 14);
                            let got = if run == 0 { PlaneDecoder::run(&mut t, 14) } else { run };
                            assert_eq!(got, want_run, "{at:?}");
                        }
                        Some(_) if fold && symbol >> 1 == 2 => {
                            assert_eq!(info & RUN_PENDING, 0, "{at:?}");
                            let (r0, t0) = (r.clone(), t.clone());
                            for location in 2..=FOLD_LOCATIONS {
                                let (mut r, mut t) = (r0.clone(), t0.clone());
                                let want_run = read_run(&mut r, 15 - location as i32);
                                let got = if run == 0 {
                                    let e = u32::from(RUN_AT[location as usize][t.peek_buffered(8) as usize]);
                                    t.skip(e & 63);
                                    e >> 8
                                } else {
                                    folded += 1;
                                    run
                                };
                                assert_eq!((got, t.bit_pos()), (want_run, r.bit_pos()), "{at:?} at {location}");
                            }
                            if run != 0 {
                                read_run(&mut r, 13);
                            }
                        }
                        _ => assert_eq!((run, info & RUN_PENDING), (0, 0), "{at:?}"),
                    }
                    assert_eq!(t.bit_pos(), r.bit_pos(), "{at:?}");
                }
            }
            cases.clear();
        }
        // The folding tables read runs.
        assert!(folded > 0);
        // Sums of many entries (more than a macroblock holds) unpack to the four sums.
        let mut rng = Rng(11);
        let entries = &HP_INDEX_TABLES[1][3][0][1];
        let (mut sum, mut want) = (0u64, [0i32; 4]);
        for _ in 0..(16 * 16 * 14 * 4) {
            let w = rng.below(256) as usize;
            sum = sum.wrapping_add(entries.deltas[w]);
            let e = INDEX_LUT[3][w];
            let one = unpack_fields(entries.deltas[w]);
            assert_eq!(one[..2], [i32::from((e >> 8) as u8 as i8), i32::from((e >> 16) as u8 as i8)]);
            for (w, d) in want.iter_mut().zip(one) {
                *w += d;
            }
            assert_eq!(unpack_fields(sum), want);
        }
    }

    #[test]
    fn run_and_level_tables_decode_as_the_symbols_do() {
        let run = read_run;
        for max_run in -1..=16i32 {
            for w in 0..256usize {
                let bytes = [w as u8, 0x5A];
                let mut r = BitReader::new(&bytes);
                let want = run(&mut r, max_run);
                let mut t = BitReader::new(&bytes);
                t.fill();
                assert_eq!(PlaneDecoder::run(&mut t, max_run), want, "max_run {max_run}, window {w:08b}");
                assert_eq!(t.bit_pos(), r.bit_pos(), "max_run {max_run}, window {w:08b}");
            }
        }
        for location in 1..=16 {
            let want = RUN_LUT[15 - location.min(15)].map(|e| u16::from(e >> 4) << 8 | u16::from(e & 15));
            assert_eq!(RUN_AT[location], want, "location {location}");
        }
        // ABSLEVEL_INDEX and its bits, escapes included, for both tables.
        for table in 0..2u8 {
            for w in 0..1u32 << 16 {
                let bytes = [(w >> 8) as u8, w as u8, 0xA5, 0x3C, 0x96, 0x0F, 0xF0, 0x69, 0x11];
                let mut r = BitReader::new(&bytes);
                let (index, want) = read_level(&mut r, usize::from(table));
                let mut ctx = AdaptiveVlc { table, ..AdaptiveVlc::ONE };
                let mut t = BitReader::new(&bytes);
                t.fill();
                assert_eq!(PlaneDecoder::abs_level_buffered(&mut ctx, &mut t), want, "table {table}, {w:016b}");
                assert_eq!(t.bit_pos(), r.bit_pos(), "table {table}, {w:016b}");
                assert_eq!(ctx.disc, vlc::ABS_LEVEL_DELTA[index]);
            }
        }
    }

    #[test]
    fn lp_blocks_refine_as_each_coefficient_does() {
        let mut rng = Rng(0x5DEE_CE66_D1CE_4E5B);
        for model_bits in 1..=15 {
            for case in 0..200 {
                let block: [i32; 15] = std::array::from_fn(|_| match rng.below(4) {
                    0 | 1 => 0,
                    2 => rng.pm(1, 40),
                    _ => rng.pm(0, 1 << 20),
                });
                // Streams long enough, and streams that end inside the block.
                let len = if case % 4 == 0 { rng.below(30) as usize } else { 40 + rng.below(20) as usize };
                let bytes: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();
                let skip = rng.below(8);
                let (mut r, mut t) = (BitReader::new(&bytes), BitReader::new(&bytes));
                r.read(skip);
                t.read(skip);
                let mut want = [0i32; 16];
                want[1..].copy_from_slice(&block);
                for &k in &TRANSPOSE444[1..16] {
                    want[k] = refine(&mut r, want[k], model_bits);
                }
                let mut got = block;
                refine_lp_block(&mut t, &mut got, model_bits);
                let at = (model_bits, case, block);
                assert_eq!(got[..], want[1..], "{at:?}");
                assert_eq!((t.bit_pos(), t.overrun()), (r.bit_pos(), r.overrun()), "{at:?}");
                // The reader goes on as the other does.
                assert_eq!(t.read(13), r.read(13), "{at:?}");
            }
        }
    }

    #[test]
    fn cbp_classes_invert_the_decoder_tables() {
        for nibble in 0..16u32 {
            let code = CBP_CODE[nibble as usize];
            assert_eq!(CBP_OUT[code], nibble);
            let class = CBP_CLASS[code];
            assert!(CBP_OFF[class] <= code && code < CBP_OFF[class] + (1 << CBP_FLC[class]));
            // The class is the number of coded blocks' code group: 0 only for nothing coded.
            assert_eq!(class == 0, nibble == 0);
        }
    }

    /// BLOCK_FLEXBITS read the plain way, one coefficient at a time (T.835's
    /// `r_BLOCK_FLEXBITS`): `n` bits, refined into the coefficient shifted by `trim`, and a
    /// sign bit only for a zero coefficient whose bits are not zero.
    fn flex_plain(r: &mut BitReader, c: &mut [i32], blocks: &[u8], n: u32, trim: u32) {
        for &b in blocks {
            for &k in &FLEX_ORDER_FLAT {
                let x = &mut c[15 * usize::from(b) + usize::from(k)];
                let fine = (r.read(n) as i32) << trim;
                *x = match *x {
                    0 if fine != 0 && r.bit() => -fine,
                    0 => fine,
                    v if v < 0 => v - fine,
                    v => v + fine,
                };
            }
        }
    }

    /// MB_FLEXBITS of both twins (the BMI2 one where the CPU has it) against the plain
    /// reading, on random coefficients (most of them zero, as in real streams) and random
    /// bits, for every width, with and without trimmed bits, for every chroma layout, down
    /// to streams that end inside the macroblock (the reader pads with zeros).
    #[test]
    fn flexbits_twins_match_the_plain_reading_at_every_width() {
        let bmi2 = hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Bmi2, "flexbits_twins");
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for n in 1..=15u32 {
            for trim in [0u32, 1, 3] {
                for fmt in [ClrFmt::Yuv444, ClrFmt::Yuv420, ClrFmt::Yuv422, ClrFmt::YOnly] {
                    let channels = if fmt == ClrFmt::YOnly { 1 } else { 3 };
                    let model_bits = [n + trim, (n + trim).saturating_sub(rng.below(2)).max(trim + 1)];
                    let mut c = vec![0i32; MAX_CHANNELS * MB_COEFFS];
                    for v in c.iter_mut() {
                        // About two in three zero, the rest of either sign.
                        *v = if rng.below(3) < 2 { 0 } else { rng.pm(1, 1 << 10) };
                    }
                    // Enough bits for the whole macroblock, or (one time in four) fewer.
                    let full = channels * 16 * 15 * 16 / 8 + 8;
                    let len = if rng.below(4) == 0 { rng.below(full as u32) as usize } else { full };
                    let data: Vec<u8> = (0..len).map(|_| rng.next() as u8).collect();

                    let mut want = c.clone();
                    let mut r = BitReader::new(&data);
                    for ch in 0..channels {
                        let blocks = predict_blocks(fmt, ch);
                        let order = &FLEX_BLOCKS[usize::from(blocks != 16)][..blocks];
                        let bits = flex_width(model_bits[usize::from(ch > 0)], trim);
                        flex_plain(&mut r, &mut want[ch * MB_COEFFS + hp(0, 1)..], order, bits, trim);
                    }
                    let what = format!("n {n} trim {trim} {fmt:?} len {len}");
                    let mut got = c.clone();
                    let mut p = BitReader::new(&data);
                    flex_mb_portable(&mut p, &mut got, fmt, channels, trim, model_bits);
                    assert!(got == want, "portable: {what}");
                    assert_eq!((p.bit_pos(), p.overrun()), (r.bit_pos(), r.overrun()), "portable: {what}");
                    #[cfg(target_arch = "x86_64")]
                    if bmi2 {
                        let mut got = c.clone();
                        let mut b = BitReader::new(&data);
                        // SAFETY: `twin_test_can_run` checked that the CPU has the BMI2 level
                        // (AVX2, BMI1, BMI2, LZCNT).
                        #[allow(unsafe_code)]
                        unsafe {
                            flex_mb_bmi2(&mut b, &mut got, fmt, channels, trim, model_bits)
                        };
                        assert!(got == want, "bmi2: {what}");
                        assert_eq!((b.bit_pos(), b.overrun()), (r.bit_pos(), r.overrun()), "bmi2: {what}");
                    }
                    // BLOCK_FLEXBITS of single blocks (the spatial order's inline flexbits).
                    let mut got = c.clone();
                    let mut s = BitReader::new(&data);
                    let mut want = c.clone();
                    let mut r = BitReader::new(&data);
                    for b in [0usize, 5, 15] {
                        block_flex(&mut s, &mut got, 0, b, model_bits[0], trim);
                        flex_plain(&mut r, &mut want[hp(0, 1)..], &[b as u8], flex_width(model_bits[0], trim), trim);
                    }
                    assert!(got == want, "block_flex: {what}");
                    assert_eq!(s.bit_pos(), r.bit_pos(), "block_flex: {what}");
                }
            }
        }
    }
}
