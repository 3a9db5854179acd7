//! The variable-length codes of the macroblock layer and the adaptive state that chooses
//! between them: adaptive VLC table selection (T.832 5.5.5, with the delta ("deltaDisc")
//! tables of 5.6), adaptive coefficient scans (5.7), adaptive coefficient normalization
//! ("model bits", 5.5.6), CBPHP prediction state (5.5.7) and the CBPLP counters (5.5.8).
//!
//! Each code table below is transcribed from T.832's tables as the ITU reference software
//! T.835 lists them (`r_parse.c`, the comments above `get_is_dc_yuv`, `get_num_cbp`,
//! `get_num_blkcbp`, `dec_abslevel_index`, `dec_cbp_yuv_lp1`, `r_DECODE_FIRST_INDEX`
//! (T.832 Table 59), `r_DECODE_INDEX` (Tables 60 and 61), `r_DECODE_RUN`, `r_REFINE_CBP`,
//! `get_value_012`, `get_num_ch_blk`): one code string per symbol, symbol order. The tests
//! check that every table is a complete prefix code. All codes are at most 8 bits long, so
//! each table decodes with one lookup of the next 8 bits.

// Loops over channel, block and bit indices mirror the syntax of T.832 and T.835.
#![allow(clippy::needless_range_loop)]

use crate::bits::{BitReader, BitWriter};

/// A code table: for every 8-bit window, `symbol << 4 | length`.
pub type Lut = [u8; 256];

/// Builds the lookup table of a prefix code given as one bit string per symbol. A window no
/// code matches (none for the complete codes here) reads as symbol 0 of length 8, so that
/// every entry has a length.
pub(crate) const fn lut(codes: &[&str]) -> Lut {
    let mut t = [8u8; 256];
    let mut sym = 0;
    while sym < codes.len() {
        let bytes = codes[sym].as_bytes();
        let len = bytes.len();
        let mut code = 0usize;
        let mut i = 0;
        while i < len {
            code = (code << 1) | (bytes[i] - b'0') as usize;
            i += 1;
        }
        let first = code << (8 - len);
        let count = 1usize << (8 - len);
        let mut j = 0;
        while j < count {
            t[first + j] = ((sym as u8) << 4) | len as u8;
            j += 1;
        }
        sym += 1;
    }
    t
}

/// Decodes one symbol of `table`.
#[inline]
pub fn decode(r: &mut BitReader, table: &Lut) -> usize {
    let e = table[r.peek(8) as usize];
    r.skip(u32::from(e & 15));
    (e >> 4) as usize
}

/// IS_DC_YUV / DC_YUV (T.832 8.7.2, fixed): which of Y, U, V have a non-zero DC; symbol
/// bit 2 = Y, bit 1 = U, bit 0 = V.
pub const DC_YUV_CODES: [&str; 8] = ["10", "001", "00001", "0001", "11", "010", "00000", "011"];
/// ABSLEVEL_INDEX (T.832 8.7.x, two adaptive tables of 7 symbols).
pub const ABS_LEVEL_CODES: [[&str; 7]; 2] =
    [["01", "10", "11", "001", "0001", "00000", "00001"], ["1", "01", "001", "0001", "00001", "000000", "000001"]];
/// FIRST_INDEX (T.832 Table 59: five adaptive tables of 12 symbols).
pub const FIRST_INDEX_CODES: [[&str; 12]; 5] = [
    ["00001", "000001", "0000000", "0000001", "00100", "010", "00101", "1", "00110", "0001", "00111", "011"],
    ["0010", "00010", "000000", "000001", "0011", "010", "00011", "11", "011", "100", "00001", "101"],
    ["11", "001", "0000000", "0000001", "00001", "010", "0000010", "011", "100", "101", "0000011", "0001"],
    ["001", "11", "0000000", "00001", "00010", "010", "0000001", "011", "00011", "100", "000001", "101"],
    ["010", "1", "0000001", "0001", "0000010", "011", "00000000", "0010", "0000011", "0011", "00000001", "00001"],
];
/// INDEX (T.832 Table 60: four adaptive tables of 6 symbols).
pub const INDEX_CODES: [[&str; 6]; 4] = [
    ["1", "00000", "001", "00001", "01", "0001"],
    ["01", "0000", "10", "0001", "11", "001"],
    ["0000", "0001", "01", "10", "11", "001"],
    ["00000", "00001", "01", "1", "0001", "001"],
];
/// INDEX at location 15 (T.832 Table 61, fixed, 4 symbols).
pub const INDEX2_CODES: [&str; 4] = ["0", "110", "10", "111"];
/// RUN_INDEX (fixed, 5 symbols).
pub const RUN_INDEX_CODES: [&str; 5] = ["1", "01", "001", "0000", "0001"];
/// NUM_CBP, and NUM_BLKCBP of YONLY/YUVK/NCOMPONENT (two adaptive tables of 5 symbols).
pub const NUM_CBP_CODES: [[&str; 5]; 2] = [["1", "01", "001", "0000", "0001"], ["1", "000", "001", "010", "011"]];
/// NUM_BLKCBP of YUV formats (two adaptive tables of 9 symbols).
pub const NUM_BLKCBP_YUV_CODES: [[&str; 9]; 2] = [
    ["010", "00000", "0010", "00001", "00010", "1", "011", "00011", "0011"],
    ["1", "001", "010", "0001", "000001", "011", "00001", "0000000", "0000001"],
];
/// NUM_CH_BLK (fixed, 4 symbols).
pub const NUM_CH_BLK_CODES: [&str; 4] = ["1", "01", "000", "001"];
/// The 0/1/2 code of CHR_CBP and the 422 chroma patterns (fixed, 3 symbols).
pub const VALUE_012_CODES: [&str; 3] = ["1", "01", "00"];
/// CBPLP of YUV444 when the counters say "code it" (fixed, 8 symbols).
pub const CBPLP_444_CODES: [&str; 8] = ["0", "100", "1010", "1011", "1100", "1101", "1110", "1111"];
/// CBPLP of YUV420/422 (fixed, 4 symbols).
pub const CBPLP_42X_CODES: [&str; 4] = ["0", "10", "110", "111"];
/// REFINE_CBP for two set bits: the patterns 3, 5, 6, 9, 10, 12 (fixed).
pub const REFINE_CBP2_CODES: [&str; 6] = ["00", "01", "100", "101", "110", "111"];
/// The values of [`REFINE_CBP2_CODES`]' symbols.
pub const REFINE_CBP2_VALUES: [u32; 6] = [3, 5, 6, 9, 10, 12];

/// Lookup tables of the codes above.
pub static DC_YUV: Lut = lut(&DC_YUV_CODES);
/// See [`INDEX2_CODES`].
pub static INDEX2: Lut = lut(&INDEX2_CODES);
/// See [`NUM_CBP_CODES`].
pub static NUM_CBP: [Lut; 2] = [lut(&NUM_CBP_CODES[0]), lut(&NUM_CBP_CODES[1])];
/// See [`NUM_BLKCBP_YUV_CODES`].
pub static NUM_BLKCBP_YUV: [Lut; 2] = [lut(&NUM_BLKCBP_YUV_CODES[0]), lut(&NUM_BLKCBP_YUV_CODES[1])];
/// See [`NUM_CH_BLK_CODES`].
pub static NUM_CH_BLK: Lut = lut(&NUM_CH_BLK_CODES);
/// See [`VALUE_012_CODES`].
pub static VALUE_012: Lut = lut(&VALUE_012_CODES);
/// See [`CBPLP_444_CODES`].
pub static CBPLP_444: Lut = lut(&CBPLP_444_CODES);
/// See [`CBPLP_42X_CODES`].
pub static CBPLP_42X: Lut = lut(&CBPLP_42X_CODES);
/// See [`REFINE_CBP2_CODES`].
pub static REFINE_CBP2: Lut = lut(&REFINE_CBP2_CODES);

/// One code of a table, for encoding: `len` bits, the value of which is `bits`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Code {
    /// The code, right-aligned.
    pub bits: u32,
    /// Its length.
    pub len: u32,
}

/// The encoding table of a prefix code given as one bit string per symbol: built from the
/// same strings as the decoder's [`Lut`], so that encoder and decoder cannot disagree.
pub(crate) const fn codes<const N: usize>(strings: &[&str; N]) -> [Code; N] {
    let mut t = [Code { bits: 0, len: 0 }; N];
    let mut sym = 0;
    while sym < N {
        let bytes = strings[sym].as_bytes();
        let mut bits = 0u32;
        let mut i = 0;
        while i < bytes.len() {
            bits = (bits << 1) | (bytes[i] - b'0') as u32;
            i += 1;
        }
        t[sym] = Code { bits, len: bytes.len() as u32 };
        sym += 1;
    }
    t
}

/// Encodes `symbol` with `table` (the inverse of [`decode`] with the matching [`Lut`]).
#[inline]
pub fn encode(w: &mut BitWriter, table: &[Code], symbol: usize) {
    let c = table[symbol];
    w.write(c.bits, c.len);
}

/// Encoding tables of the codes above (`*_CODES`), symbol-indexed.
pub static DC_YUV_ENC: [Code; 8] = codes(&DC_YUV_CODES);
/// See [`ABS_LEVEL_CODES`].
pub static ABS_LEVEL_ENC: [[Code; 7]; 2] = [codes(&ABS_LEVEL_CODES[0]), codes(&ABS_LEVEL_CODES[1])];
/// See [`FIRST_INDEX_CODES`].
pub static FIRST_INDEX_ENC: [[Code; 12]; 5] = [
    codes(&FIRST_INDEX_CODES[0]),
    codes(&FIRST_INDEX_CODES[1]),
    codes(&FIRST_INDEX_CODES[2]),
    codes(&FIRST_INDEX_CODES[3]),
    codes(&FIRST_INDEX_CODES[4]),
];
/// See [`INDEX_CODES`].
pub static INDEX_ENC: [[Code; 6]; 4] =
    [codes(&INDEX_CODES[0]), codes(&INDEX_CODES[1]), codes(&INDEX_CODES[2]), codes(&INDEX_CODES[3])];
/// See [`INDEX2_CODES`].
pub static INDEX2_ENC: [Code; 4] = codes(&INDEX2_CODES);
/// See [`RUN_INDEX_CODES`].
pub const RUN_INDEX_ENC: [Code; 5] = codes(&RUN_INDEX_CODES);
/// See [`NUM_CBP_CODES`].
pub static NUM_CBP_ENC: [[Code; 5]; 2] = [codes(&NUM_CBP_CODES[0]), codes(&NUM_CBP_CODES[1])];
/// See [`NUM_BLKCBP_YUV_CODES`].
pub static NUM_BLKCBP_YUV_ENC: [[Code; 9]; 2] = [codes(&NUM_BLKCBP_YUV_CODES[0]), codes(&NUM_BLKCBP_YUV_CODES[1])];
/// See [`NUM_CH_BLK_CODES`].
pub static NUM_CH_BLK_ENC: [Code; 4] = codes(&NUM_CH_BLK_CODES);
/// See [`VALUE_012_CODES`].
pub static VALUE_012_ENC: [Code; 3] = codes(&VALUE_012_CODES);
/// See [`CBPLP_444_CODES`].
pub static CBPLP_444_ENC: [Code; 8] = codes(&CBPLP_444_CODES);
/// See [`CBPLP_42X_CODES`].
pub static CBPLP_42X_ENC: [Code; 4] = codes(&CBPLP_42X_CODES);
/// See [`REFINE_CBP2_CODES`].
pub static REFINE_CBP2_ENC: [Code; 6] = codes(&REFINE_CBP2_CODES);

/// Discriminant deltas of ABSLEVEL_INDEX (T.832 5.6).
pub const ABS_LEVEL_DELTA: [i32; 7] = [1, 0, -1, -1, -1, -1, -1];
/// Discriminant deltas of FIRST_INDEX, by delta table (T.832 5.6).
pub const FIRST_INDEX_DELTA: [[i32; 12]; 4] = [
    [1, 1, 1, 1, 1, 0, 0, -1, 2, 1, 0, 0],
    [2, 2, -1, -1, -1, 0, -2, -1, 0, 0, -2, -1],
    [-1, 1, 0, 2, 0, 0, 0, 0, -2, 0, 1, 1],
    [0, 1, 0, 1, -2, 0, -1, -1, -2, -1, -2, -2],
];
/// Discriminant deltas of INDEX, by delta table (T.832 5.6).
pub const INDEX_DELTA: [[i32; 6]; 3] = [[-1, 1, 1, 1, 0, 1], [-2, 0, 0, 2, 0, 0], [-1, -1, 0, 1, -2, 0]];
/// Discriminant deltas of NUM_CBP and of 5-symbol NUM_BLKCBP (T.832 5.6).
pub const NUM_CBP_DELTA: [i32; 5] = [0, -1, 0, 1, 1];
/// Discriminant deltas of 9-symbol NUM_BLKCBP (T.832 5.6).
pub const NUM_BLKCBP9_DELTA: [i32; 9] = [2, 2, 1, 1, -1, -2, -2, -2, -3];

/// The adaptive VLC contexts of a tile (T.835 `abs_level_vlc_index_t`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum V {
    AbsLevelDcLum,
    AbsLevelDcChr,
    AbsLevelLp0,
    AbsLevelLp1,
    AbsLevelHp0,
    AbsLevelHp1,
    FirstIndLpLum,
    IndLpLum0,
    IndLpLum1,
    FirstIndLpChr,
    IndLpChr0,
    IndLpChr1,
    FirstIndHpLum,
    IndHpLum0,
    IndHpLum1,
    FirstIndHpChr,
    IndHpChr0,
    IndHpChr1,
    NumCbp,
    NumBlkCbp,
}

/// Number of [`V`] contexts.
pub const V_COUNT: usize = 20;

/// The state of one adaptive VLC context (T.832 5.5.5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdaptiveVlc {
    /// The code table in use.
    pub table: u8,
    /// Delta table for the first discriminant.
    pub delta: u8,
    /// Delta table for the second discriminant (6- and 12-symbol alphabets).
    pub delta2: u8,
    /// First discriminant.
    pub disc: i32,
    /// Second discriminant.
    pub disc2: i32,
}

impl AdaptiveVlc {
    /// The start state of contexts with one discriminant (table 0).
    pub const ONE: AdaptiveVlc = AdaptiveVlc { table: 0, delta: 0, delta2: 0, disc: 0, disc2: 0 };
    /// The start state of the 6- and 12-symbol contexts (table 1, delta tables 0 and 1).
    pub const TWO: AdaptiveVlc = AdaptiveVlc { table: 1, delta: 0, delta2: 1, disc: 0, disc2: 0 };

    /// Counts a symbol of a context with one discriminant (T.832 5.6): the same update for
    /// decoder and encoder.
    #[inline(always)]
    pub fn count(&mut self, deltas: &[i32], symbol: usize) {
        self.disc += deltas[symbol];
    }

    /// Counts a symbol of a 6- or 12-symbol context: both discriminants, through the delta
    /// tables the context currently selects (T.832 5.6).
    #[inline(always)]
    pub fn count2<const N: usize>(&mut self, deltas: &[[i32; N]], symbol: usize) {
        self.disc += deltas[self.delta as usize][symbol];
        self.disc2 += deltas[self.delta2 as usize][symbol];
    }

    /// Adaptation of a two-table context (`_jxr_AdaptVLCTable`).
    pub fn adapt_one(&mut self) {
        self.delta = 0;
        if self.disc < -8 && self.table != 0 {
            self.table -= 1;
            self.disc = 0;
        } else if self.disc > 8 && self.table != 1 {
            self.table += 1;
            self.disc = 0;
        } else {
            self.disc = self.disc.clamp(-64, 64);
        }
    }

    /// Adaptation of a context with `max + 1` tables and two discriminants (`AdaptVLCTable2`).
    pub fn adapt_two(&mut self, max: u8) {
        let changed = if self.disc < -8 && self.table > 0 {
            self.table -= 1;
            true
        } else if self.disc2 > 8 && self.table < max {
            self.table += 1;
            true
        } else {
            false
        };
        if changed {
            self.disc = 0;
            self.disc2 = 0;
            if self.table == max {
                self.delta = self.table - 1;
                self.delta2 = self.table - 1;
            } else if self.table == 0 {
                self.delta = 0;
                self.delta2 = 0;
            } else {
                self.delta = self.table - 1;
                self.delta2 = self.table;
            }
        } else {
            self.disc = self.disc.clamp(-64, 64);
            self.disc2 = self.disc2.clamp(-64, 64);
        }
    }
}

/// Adaptive coefficient normalization of one band (T.832 5.5.6): model bits and state for
/// luma (0) and chroma (1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Model {
    /// Raw low bits per coefficient.
    pub bits: [u32; 2],
    state: [i32; 2],
}

/// Bands for [`Model`]: DC 0, LP 1, HP 2.
pub const BAND_DC: usize = 0;
/// See [`BAND_DC`].
pub const BAND_LP: usize = 1;
/// See [`BAND_DC`].
pub const BAND_HP: usize = 2;

impl Model {
    /// The start state of `band` (bits 8, 4, 0).
    pub fn new(band: usize) -> Self {
        let b = ((2 - band) * 4) as u32;
        Model { bits: [b, b], state: [0, 0] }
    }

    /// Updates from the number of non-zero coefficients of the macroblock (`_jxr_UpdateModelMB`).
    /// `fmt` is 1 for 420, 2 for 422, 0 otherwise; `yonly` stops after luma.
    pub fn update(&mut self, mut lap_mean: [i32; 2], band: usize, fmt: u8, channels: usize, yonly: bool) {
        const WEIGHT0: [i32; 3] = [240, 12, 1];
        const WEIGHT1: [[i32; 16]; 3] = [
            [0, 240, 120, 80, 60, 48, 40, 34, 30, 27, 24, 22, 20, 18, 17, 16],
            [0, 12, 6, 4, 3, 2, 2, 2, 2, 1, 1, 1, 1, 1, 1, 1],
            [0, 16, 8, 5, 4, 3, 3, 2, 2, 2, 2, 1, 1, 1, 1, 1],
        ];
        const WEIGHT2: [i32; 6] = [120, 37, 2, 120, 18, 1];
        lap_mean[0] *= WEIGHT0[band];
        match fmt {
            1 => lap_mean[1] *= WEIGHT2[band],
            2 => lap_mean[1] *= WEIGHT2[3 + band],
            _ => {
                lap_mean[1] *= WEIGHT1[band][(channels - 1).min(15)];
                if band == BAND_HP {
                    lap_mean[1] >>= 4;
                }
            }
        }
        for j in 0..2 {
            let mut ms = self.state[j];
            let mut delta = (lap_mean[j] - 70) >> 2;
            if delta <= -8 {
                delta = (delta + 4).max(-16);
                ms += delta;
                if ms < -8 {
                    if self.bits[j] == 0 {
                        ms = -8;
                    } else {
                        ms = 0;
                        self.bits[j] -= 1;
                    }
                }
            } else if delta >= 8 {
                delta = (delta - 4).min(15);
                ms += delta;
                if ms > 8 {
                    if self.bits[j] >= 15 {
                        self.bits[j] = 15;
                        ms = 8;
                    } else {
                        ms = 0;
                        self.bits[j] += 1;
                    }
                }
            }
            self.state[j] = ms;
            if yonly {
                break;
            }
        }
    }
}

/// Initial scan totals (T.832 5.7).
const SCAN_TOTALS: [u32; 15] = [32, 30, 28, 26, 24, 22, 20, 18, 16, 14, 12, 10, 8, 6, 4];
/// Initial LP scan and horizontal HP scan: coefficient indices 1..=15 in the T.832 numbering
/// (T.832 5.7, as T.835 `_jxr_InitializeAdaptiveScanLP/HP` lists them).
pub const SCAN_HORIZONTAL: [u8; 15] = [4, 1, 5, 8, 2, 9, 6, 12, 3, 10, 13, 7, 14, 11, 15];
/// Initial vertical HP scan (T.832 5.7).
pub const SCAN_VERTICAL: [u8; 15] = [1, 2, 5, 4, 3, 6, 9, 8, 7, 12, 15, 13, 10, 11, 14];

/// An adaptive scan order (T.832 5.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scan {
    /// Scan position `i` at `i + 1`: its total (the count that orders positions) times 16
    /// plus its coefficient index (1..=15), so that one load gives both. Entry 0 is a
    /// sentinel larger than any total: position 0 has no predecessor to swap with, without a
    /// test of the position.
    entries: [u32; 16],
}

impl Scan {
    /// A scan starting from `order`.
    pub fn new(order: [u8; 15]) -> Self {
        let mut entries = [u32::MAX; 16];
        for (e, (&k, &total)) in entries[1..].iter_mut().zip(order.iter().zip(&SCAN_TOTALS)) {
            *e = total << 4 | u32::from(k);
        }
        Scan { entries }
    }

    /// The coefficient index at each scan position.
    pub fn order(&self) -> [u8; 15] {
        std::array::from_fn(|i| (self.entries[i + 1] & 15) as u8)
    }

    /// Resets the totals (every 16 macroblocks from a tile's left edge). Totals stay far
    /// below 2^28 between resets (16 macroblocks of 16 channels of 16 blocks hit 61 440
    /// times at most).
    pub fn reset_totals(&mut self) {
        for (e, &total) in self.entries[1..].iter_mut().zip(&SCAN_TOTALS) {
            *e = total << 4 | (*e & 15);
        }
    }

    /// The coefficient at scan position `i` (0-based) receives a value: returns its index and
    /// adapts the order (a position whose total exceeds its predecessor's swaps with it).
    #[inline]
    pub fn hit(&mut self, i: usize) -> usize {
        let e = self.entries[i + 1] + 16;
        self.entries[i + 1] = e;
        let before = self.entries[i];
        // Totals compare as the entries with the predecessor's index bits all set.
        if e > before | 15 {
            self.entries[i] = e;
            self.entries[i + 1] = before;
        }
        (e & 15) as usize
    }
}

/// The CBPHP prediction model (T.832 5.5.7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CbpModel {
    /// Prediction state for luma (0) and chroma (1): 0 spatial, 1 none, 2 inverted.
    pub state: [u8; 2],
    count0: [i32; 2],
    count1: [i32; 2],
}

impl Default for CbpModel {
    fn default() -> Self {
        CbpModel { state: [0, 0], count0: [-4, -4], count1: [4, 4] }
    }
}

impl CbpModel {
    /// Updates context `c` (0 luma, 1 chroma) with the number of coded blocks `n` (scaled to 16).
    pub fn update(&mut self, c: usize, n: i32) {
        self.count0[c] = (self.count0[c] + n - 3).clamp(-16, 15);
        self.count1[c] = (self.count1[c] + 16 - n - 3).clamp(-16, 15);
        self.state[c] = if self.count0[c] < 0 {
            if self.count0[c] < self.count1[c] {
                1
            } else {
                2
            }
        } else if self.count1[c] < 0 {
            2
        } else {
            0
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// True when `codes` is a prefix code whose lengths satisfy Kraft's equality.
    fn complete_prefix_code(codes: &[&str]) -> bool {
        let kraft: f64 = codes.iter().map(|c| 0.5f64.powi(c.len() as i32)).sum();
        let prefix_free =
            codes.iter().enumerate().all(|(i, a)| codes.iter().enumerate().all(|(j, b)| i == j || !b.starts_with(a)));
        prefix_free && (kraft - 1.0).abs() < 1e-12 && codes.iter().all(|c| !c.is_empty() && c.len() <= 8)
    }

    #[test]
    fn every_code_table_is_a_complete_prefix_code() {
        let mut all: Vec<&[&str]> = vec![
            &DC_YUV_CODES,
            &INDEX2_CODES,
            &RUN_INDEX_CODES,
            &NUM_CH_BLK_CODES,
            &VALUE_012_CODES,
            &CBPLP_444_CODES,
            &CBPLP_42X_CODES,
            &REFINE_CBP2_CODES,
        ];
        all.extend(ABS_LEVEL_CODES.iter().map(|t| &t[..]));
        all.extend(FIRST_INDEX_CODES.iter().map(|t| &t[..]));
        all.extend(INDEX_CODES.iter().map(|t| &t[..]));
        all.extend(NUM_CBP_CODES.iter().map(|t| &t[..]));
        all.extend(NUM_BLKCBP_YUV_CODES.iter().map(|t| &t[..]));
        for codes in all {
            assert!(complete_prefix_code(codes), "{codes:?}");
        }
    }

    #[test]
    fn lookup_tables_decode_every_code() {
        let (first4, first0, index3) = (lut(&FIRST_INDEX_CODES[4]), lut(&FIRST_INDEX_CODES[0]), lut(&INDEX_CODES[3]));
        let cases: Vec<(&[&str], &Lut)> = vec![
            (&FIRST_INDEX_CODES[4], &first4),
            (&FIRST_INDEX_CODES[0], &first0),
            (&NUM_BLKCBP_YUV_CODES[1], &NUM_BLKCBP_YUV[1]),
            (&DC_YUV_CODES, &DC_YUV),
            (&INDEX_CODES[3], &index3),
        ];
        for (codes, table) in cases {
            for (sym, code) in codes.iter().enumerate() {
                // The code followed by ones, then a marker byte.
                let mut bits: String = code.to_string();
                while bits.len() < 16 {
                    bits.push('1');
                }
                let bytes = [u8::from_str_radix(&bits[..8], 2).unwrap(), u8::from_str_radix(&bits[8..16], 2).unwrap()];
                let mut r = BitReader::new(&bytes);
                assert_eq!(decode(&mut r, table), sym, "{code}");
                assert_eq!(r.bit_pos(), code.len() as u64);
            }
        }
    }

    #[test]
    fn delta_tables_have_one_entry_per_symbol() {
        assert_eq!(FIRST_INDEX_DELTA[0].len(), FIRST_INDEX_CODES[0].len());
        assert_eq!(INDEX_DELTA[0].len(), INDEX_CODES[0].len());
        assert_eq!(ABS_LEVEL_DELTA.len(), ABS_LEVEL_CODES[0].len());
        assert_eq!(NUM_BLKCBP9_DELTA.len(), NUM_BLKCBP_YUV_CODES[0].len());
        assert_eq!(NUM_CBP_DELTA.len(), NUM_CBP_CODES[0].len());
    }

    #[test]
    fn scans_are_permutations_and_adapt_by_swapping() {
        for scan in [SCAN_HORIZONTAL, SCAN_VERTICAL] {
            let mut s: Vec<u8> = scan.to_vec();
            s.sort_unstable();
            assert_eq!(s, (1..=15).collect::<Vec<u8>>());
        }
        let mut s = Scan::new(SCAN_HORIZONTAL);
        // Position 1 (coefficient 1) hit twice: 30 -> 32 ties, 33 > 32 swaps.
        assert_eq!(s.hit(1), 1);
        assert_eq!(s.order()[..2], [4, 1]);
        assert_eq!(s.hit(1), 1);
        assert_eq!(s.hit(1), 1);
        assert_eq!(s.order()[..2], [1, 4]);
    }

    #[test]
    fn packed_scan_adapts_as_orders_and_totals_do() {
        // T.832 5.7 as written: an order and its totals, side by side.
        let (mut order, mut totals) = (SCAN_VERTICAL, SCAN_TOTALS);
        let mut s = Scan::new(SCAN_VERTICAL);
        let mut x = 0x9E37_79B9u32;
        for step in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            if x.is_multiple_of(5000) {
                totals = SCAN_TOTALS;
                s.reset_totals();
            }
            // Early positions more often, as in coded blocks.
            let i = ((x >> 8) % 15).min((x >> 16) % 15) as usize;
            let k = order[i] as usize;
            totals[i] += 1;
            if i > 0 && totals[i] > totals[i - 1] {
                totals.swap(i, i - 1);
                order.swap(i, i - 1);
            }
            assert_eq!(s.hit(i), k, "step {step}");
            assert_eq!(s.order(), order, "step {step}");
        }
    }

    #[test]
    fn model_and_vlc_adaptation() {
        let mut m = Model::new(BAND_LP);
        assert_eq!(m.bits, [4, 4]);
        // (0 - 70) >> 2 = -18, +4 = -14: the state drops below -8 and the bits by one.
        m.update([0, 0], BAND_LP, 0, 3, false);
        assert_eq!(m.bits, [3, 3]);
        // 2 non-zero luma coefficients weigh 24: (24 - 70) >> 2 = -12 -> -8, state -8: no change.
        m.update([2, 6], BAND_LP, 0, 3, false);
        assert_eq!(m.bits, [3, 3]);
        let mut v = AdaptiveVlc::TWO;
        v.disc2 = 9;
        v.adapt_two(4);
        assert_eq!((v.table, v.delta, v.delta2), (2, 1, 2));
        let mut v = AdaptiveVlc::ONE;
        v.disc = 100;
        v.adapt_one();
        assert_eq!((v.table, v.disc), (1, 0));
        v.disc = 100;
        v.adapt_one();
        assert_eq!((v.table, v.disc), (1, 64));
    }

    #[test]
    fn every_encoding_table_round_trips_through_its_decoding_table() {
        // The decoder reads these through combined tables (`macroblock`), built from these.
        let run_index = lut(&RUN_INDEX_CODES);
        let abs_level = [lut(&ABS_LEVEL_CODES[0]), lut(&ABS_LEVEL_CODES[1])];
        let first_index = FIRST_INDEX_CODES.map(|c| lut(&c));
        let index = INDEX_CODES.map(|c| lut(&c));
        let mut cases: Vec<(&[Code], &Lut)> = vec![
            (&DC_YUV_ENC, &DC_YUV),
            (&INDEX2_ENC, &INDEX2),
            (&RUN_INDEX_ENC, &run_index),
            (&NUM_CH_BLK_ENC, &NUM_CH_BLK),
            (&VALUE_012_ENC, &VALUE_012),
            (&CBPLP_444_ENC, &CBPLP_444),
            (&CBPLP_42X_ENC, &CBPLP_42X),
            (&REFINE_CBP2_ENC, &REFINE_CBP2),
        ];
        cases.extend(ABS_LEVEL_ENC.iter().map(|t| &t[..]).zip(abs_level.iter()));
        cases.extend(FIRST_INDEX_ENC.iter().map(|t| &t[..]).zip(first_index.iter()));
        cases.extend(INDEX_ENC.iter().map(|t| &t[..]).zip(index.iter()));
        cases.extend(NUM_CBP_ENC.iter().map(|t| &t[..]).zip(NUM_CBP.iter()));
        cases.extend(NUM_BLKCBP_YUV_ENC.iter().map(|t| &t[..]).zip(NUM_BLKCBP_YUV.iter()));
        assert_eq!(cases.len(), 8 + 2 + 5 + 4 + 2 + 2);
        for (enc, lut) in cases {
            for sym in 0..enc.len() {
                // Each code, followed by every other code as a tail: the decoder must stop
                // exactly at the end of the first.
                for tail in 0..enc.len() {
                    let mut w = BitWriter::new();
                    encode(&mut w, enc, sym);
                    let len = w.bit_len();
                    assert_eq!(len, u64::from(enc[sym].len));
                    encode(&mut w, enc, tail);
                    let bytes = w.into_bytes();
                    let mut r = BitReader::new(&bytes);
                    assert_eq!(decode(&mut r, lut), sym);
                    assert_eq!(r.bit_pos(), len);
                    assert_eq!(decode(&mut r, lut), tail);
                }
            }
        }
    }
}
