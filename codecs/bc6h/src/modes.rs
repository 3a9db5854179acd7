//! The BC6H format tables: the 14 modes with their exact bit layouts, the 32 two-region
//! partitions, the anchor (fix-up) indices and the interpolation weights, plus a bit reader and
//! writer and the packing/unpacking of a block's fields.
//!
//! Sources: the Direct3D 11 functional specification, section "BC6H Format" (reproduced on
//! learn.microsoft.com as "BC6H format", with its "BC6H Compressed Endpoint Format" table), and the
//! Khronos Data Format Specification 1.3, section "BPTC Compressed Texture Image Formats"
//! (tables "Mode-dependent BPTC parameters", "Partition table for 2-subset BPTC" and
//! "BPTC anchor index values").
//!
//! Naming follows the D3D specification: the endpoints of a block are `w`, `x` (region 0, ends 0
//! and 1) and `y`, `z` (region 1, ends 0 and 1); in transformed modes `w` is the base and `x`,
//! `y`, `z` are signed deltas from it. `d` is the partition (shape) number.
//!
//! These tables are shared by the decoder and the encoder: [`pack_block`] writes a block from
//! quantized fields exactly as [`unpack_block`] reads it back.

/// One endpoint component or the partition number: a destination of header bits.
///
/// The numeric value is an index into [`BlockFields::values`]: `endpoint * 3 + channel`
/// (endpoints `w, x, y, z` = 0..4, channels `r, g, b` = 0..3), and 12 for the partition.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
#[allow(missing_docs)]
pub enum Field {
    Rw = 0,
    Gw = 1,
    Bw = 2,
    Rx = 3,
    Gx = 4,
    Bx = 5,
    Ry = 6,
    Gy = 7,
    By = 8,
    Rz = 9,
    Gz = 10,
    Bz = 11,
    /// Partition (shape) number, 5 bits, two-region modes only.
    D = 12,
}

/// A run of consecutive stream bits that fill bits of one [`Field`], written as in the
/// specification's tables: `rw[9:0]` is `FieldBits { field: Rw, first: 0, last: 9 }` (the first
/// stream bit is bit 0 of the field), and the reversed run `rw[10:15]` of modes 13 and 14 is
/// `FieldBits { field: Rw, first: 15, last: 10 }` (the first stream bit is bit 15).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldBits {
    /// The field the bits belong to.
    pub field: Field,
    /// Field bit that receives the first stream bit of the run.
    pub first: u8,
    /// Field bit that receives the last stream bit of the run.
    pub last: u8,
}

impl FieldBits {
    /// Number of stream bits in the run.
    pub const fn len(&self) -> u32 {
        if self.first <= self.last {
            (self.last - self.first + 1) as u32
        } else {
            (self.first - self.last + 1) as u32
        }
    }

    /// Whether the run stores the field bits from high to low (modes 13 and 14).
    pub const fn reversed(&self) -> bool {
        self.first > self.last
    }

    /// A run is never empty; present for clippy's `len_without_is_empty`.
    pub const fn is_empty(&self) -> bool {
        false
    }
}

/// Everything that characterises one of the 14 BC6H modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeInfo {
    /// Mode number as the specification counts them, 1..=14.
    pub number: u8,
    /// The mode field value, read LSB first from bit 0 of the block (2 bits for modes 1 and 2,
    /// 5 bits otherwise).
    pub mode_value: u8,
    /// Number of mode bits (2 or 5).
    pub mode_bits: u8,
    /// 1 or 2 regions (two-region modes carry a partition number and 3-bit indices; one-region
    /// modes 4-bit indices).
    pub regions: u8,
    /// Whether `x`, `y`, `z` are stored as deltas from `w` (the "transformed" endpoints).
    pub transformed: bool,
    /// Precision of the base endpoint `w` (and of every endpoint after the transform).
    pub endpoint_bits: u8,
    /// Bits of the stored `x`, `y`, `z` values per channel `[r, g, b]` (deltas if transformed).
    pub delta_bits: [u8; 3],
    /// The header bits after the mode bits, in stream order (ends with `d[4:0]` in two-region
    /// modes).
    pub layout: &'static [FieldBits],
}

impl ModeInfo {
    /// Bits per texel index (3 for two-region modes, 4 for one-region modes); anchor texels
    /// store one bit less.
    pub const fn index_bits(&self) -> u32 {
        if self.regions == 2 {
            3
        } else {
            4
        }
    }

    /// Total header bits (mode + endpoints + partition): 82 for two-region modes, 65 otherwise.
    pub const fn header_bits(&self) -> u32 {
        let mut n = self.mode_bits as u32;
        let mut i = 0;
        while i < self.layout.len() {
            n += self.layout[i].len();
            i += 1;
        }
        n
    }

    /// Stored precision of endpoint `e` (0 = `w`, 1..=3 = `x`, `y`, `z`) of channel `c`.
    pub const fn stored_bits(&self, e: usize, c: usize) -> u8 {
        if e == 0 {
            self.endpoint_bits
        } else {
            self.delta_bits[c]
        }
    }
}

const fn f(field: Field, last: u8, first: u8) -> FieldBits {
    FieldBits { field, first, last }
}

use Field::*;

// The layouts below transcribe the "BC6H Compressed Endpoint Format" table of the D3D11
// specification. Each `f(F, a, b)` is the spec's `F[a:b]`; single bits are `F[a]` = `f(F, a, a)`.
#[rustfmt::skip]
const L1: &[FieldBits] = &[
    f(Gy, 4, 4), f(By, 4, 4), f(Bz, 4, 4), f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 4, 0),
    f(Gz, 4, 4), f(Gy, 3, 0), f(Gx, 4, 0), f(Bz, 0, 0), f(Gz, 3, 0), f(Bx, 4, 0), f(Bz, 1, 1),
    f(By, 3, 0), f(Ry, 4, 0), f(Bz, 2, 2), f(Rz, 4, 0), f(Bz, 3, 3), f(D, 4, 0),
];
#[rustfmt::skip]
const L2: &[FieldBits] = &[
    f(Gy, 5, 5), f(Gz, 4, 4), f(Gz, 5, 5), f(Rw, 6, 0), f(Bz, 0, 0), f(Bz, 1, 1), f(By, 4, 4),
    f(Gw, 6, 0), f(By, 5, 5), f(Bz, 2, 2), f(Gy, 4, 4), f(Bw, 6, 0), f(Bz, 3, 3), f(Bz, 5, 5),
    f(Bz, 4, 4), f(Rx, 5, 0), f(Gy, 3, 0), f(Gx, 5, 0), f(Gz, 3, 0), f(Bx, 5, 0), f(By, 3, 0),
    f(Ry, 5, 0), f(Rz, 5, 0), f(D, 4, 0),
];
#[rustfmt::skip]
const L3: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 4, 0), f(Rw, 10, 10), f(Gy, 3, 0), f(Gx, 3, 0),
    f(Gw, 10, 10), f(Bz, 0, 0), f(Gz, 3, 0), f(Bx, 3, 0), f(Bw, 10, 10), f(Bz, 1, 1), f(By, 3, 0),
    f(Ry, 4, 0), f(Bz, 2, 2), f(Rz, 4, 0), f(Bz, 3, 3), f(D, 4, 0),
];
#[rustfmt::skip]
const L4: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 3, 0), f(Rw, 10, 10), f(Gz, 4, 4), f(Gy, 3, 0),
    f(Gx, 4, 0), f(Gw, 10, 10), f(Gz, 3, 0), f(Bx, 3, 0), f(Bw, 10, 10), f(Bz, 1, 1), f(By, 3, 0),
    f(Ry, 3, 0), f(Bz, 0, 0), f(Bz, 2, 2), f(Rz, 3, 0), f(Gy, 4, 4), f(Bz, 3, 3), f(D, 4, 0),
];
#[rustfmt::skip]
const L5: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 3, 0), f(Rw, 10, 10), f(By, 4, 4), f(Gy, 3, 0),
    f(Gx, 3, 0), f(Gw, 10, 10), f(Bz, 0, 0), f(Gz, 3, 0), f(Bx, 4, 0), f(Bw, 10, 10), f(By, 3, 0),
    f(Ry, 3, 0), f(Bz, 1, 1), f(Bz, 2, 2), f(Rz, 3, 0), f(Bz, 4, 4), f(Bz, 3, 3), f(D, 4, 0),
];
#[rustfmt::skip]
const L6: &[FieldBits] = &[
    f(Rw, 8, 0), f(By, 4, 4), f(Gw, 8, 0), f(Gy, 4, 4), f(Bw, 8, 0), f(Bz, 4, 4), f(Rx, 4, 0),
    f(Gz, 4, 4), f(Gy, 3, 0), f(Gx, 4, 0), f(Bz, 0, 0), f(Gz, 3, 0), f(Bx, 4, 0), f(Bz, 1, 1),
    f(By, 3, 0), f(Ry, 4, 0), f(Bz, 2, 2), f(Rz, 4, 0), f(Bz, 3, 3), f(D, 4, 0),
];
#[rustfmt::skip]
const L7: &[FieldBits] = &[
    f(Rw, 7, 0), f(Gz, 4, 4), f(By, 4, 4), f(Gw, 7, 0), f(Bz, 2, 2), f(Gy, 4, 4), f(Bw, 7, 0),
    f(Bz, 3, 3), f(Bz, 4, 4), f(Rx, 5, 0), f(Gy, 3, 0), f(Gx, 4, 0), f(Bz, 0, 0), f(Gz, 3, 0),
    f(Bx, 4, 0), f(Bz, 1, 1), f(By, 3, 0), f(Ry, 5, 0), f(Rz, 5, 0), f(D, 4, 0),
];
#[rustfmt::skip]
const L8: &[FieldBits] = &[
    f(Rw, 7, 0), f(Bz, 0, 0), f(By, 4, 4), f(Gw, 7, 0), f(Gy, 5, 5), f(Gy, 4, 4), f(Bw, 7, 0),
    f(Gz, 5, 5), f(Bz, 4, 4), f(Rx, 4, 0), f(Gz, 4, 4), f(Gy, 3, 0), f(Gx, 5, 0), f(Gz, 3, 0),
    f(Bx, 4, 0), f(Bz, 1, 1), f(By, 3, 0), f(Ry, 4, 0), f(Bz, 2, 2), f(Rz, 4, 0), f(Bz, 3, 3),
    f(D, 4, 0),
];
#[rustfmt::skip]
const L9: &[FieldBits] = &[
    f(Rw, 7, 0), f(Bz, 1, 1), f(By, 4, 4), f(Gw, 7, 0), f(By, 5, 5), f(Gy, 4, 4), f(Bw, 7, 0),
    f(Bz, 5, 5), f(Bz, 4, 4), f(Rx, 4, 0), f(Gz, 4, 4), f(Gy, 3, 0), f(Gx, 4, 0), f(Bz, 0, 0),
    f(Gz, 3, 0), f(Bx, 5, 0), f(By, 3, 0), f(Ry, 4, 0), f(Bz, 2, 2), f(Rz, 4, 0), f(Bz, 3, 3),
    f(D, 4, 0),
];
#[rustfmt::skip]
const L10: &[FieldBits] = &[
    f(Rw, 5, 0), f(Gz, 4, 4), f(Bz, 0, 0), f(Bz, 1, 1), f(By, 4, 4), f(Gw, 5, 0), f(Gy, 5, 5),
    f(By, 5, 5), f(Bz, 2, 2), f(Gy, 4, 4), f(Bw, 5, 0), f(Gz, 5, 5), f(Bz, 3, 3), f(Bz, 5, 5),
    f(Bz, 4, 4), f(Rx, 5, 0), f(Gy, 3, 0), f(Gx, 5, 0), f(Gz, 3, 0), f(Bx, 5, 0), f(By, 3, 0),
    f(Ry, 5, 0), f(Rz, 5, 0), f(D, 4, 0),
];
#[rustfmt::skip]
const L11: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 9, 0), f(Gx, 9, 0), f(Bx, 9, 0),
];
#[rustfmt::skip]
const L12: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 8, 0), f(Rw, 10, 10), f(Gx, 8, 0), f(Gw, 10, 10),
    f(Bx, 8, 0), f(Bw, 10, 10),
];
#[rustfmt::skip]
const L13: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 7, 0), f(Rw, 10, 11), f(Gx, 7, 0), f(Gw, 10, 11),
    f(Bx, 7, 0), f(Bw, 10, 11),
];
#[rustfmt::skip]
const L14: &[FieldBits] = &[
    f(Rw, 9, 0), f(Gw, 9, 0), f(Bw, 9, 0), f(Rx, 3, 0), f(Rw, 10, 15), f(Gx, 3, 0), f(Gw, 10, 15),
    f(Bx, 3, 0), f(Bw, 10, 15),
];

const fn m(
    number: u8,
    mode_value: u8,
    regions: u8,
    transformed: bool,
    endpoint_bits: u8,
    delta_bits: [u8; 3],
    layout: &'static [FieldBits],
) -> ModeInfo {
    ModeInfo {
        number,
        mode_value,
        mode_bits: if number <= 2 { 2 } else { 5 },
        regions,
        transformed,
        endpoint_bits,
        delta_bits,
        layout,
    }
}

/// The 14 modes in specification order (`MODES[i].number == i + 1`).
#[rustfmt::skip]
pub const MODES: [ModeInfo; 14] = [
    m(1, 0b00, 2, true, 10, [5, 5, 5], L1),
    m(2, 0b01, 2, true, 7, [6, 6, 6], L2),
    m(3, 0b00010, 2, true, 11, [5, 4, 4], L3),
    m(4, 0b00110, 2, true, 11, [4, 5, 4], L4),
    m(5, 0b01010, 2, true, 11, [4, 4, 5], L5),
    m(6, 0b01110, 2, true, 9, [5, 5, 5], L6),
    m(7, 0b10010, 2, true, 8, [6, 5, 5], L7),
    m(8, 0b10110, 2, true, 8, [5, 6, 5], L8),
    m(9, 0b11010, 2, true, 8, [5, 5, 6], L9),
    m(10, 0b11110, 2, false, 6, [6, 6, 6], L10),
    m(11, 0b00011, 1, false, 10, [10, 10, 10], L11),
    m(12, 0b00111, 1, true, 11, [9, 9, 9], L12),
    m(13, 0b01011, 1, true, 12, [8, 8, 8], L13),
    m(14, 0b01111, 1, true, 16, [4, 4, 4], L14),
];

/// Reserved 5-bit mode values (`10011`, `10111`, `11011`, `11111`): such a block decodes to
/// zero in every channel (D3D11 spec: "the resulting decompressed block must contain all zeroes
/// in all channels").
pub const RESERVED_MODE_VALUES: [u8; 4] = [0b10011, 0b10111, 0b11011, 0b11111];

/// Maps the low 5 bits of a block to an index into [`MODES`] (`None` for reserved values).
/// Values whose low two bits are `00` or `01` are modes 1 and 2 whatever their next 3 bits are.
pub const MODE_FROM_BITS: [Option<u8>; 32] = {
    let mut t = [None; 32];
    let mut v = 0;
    while v < 32 {
        let mut i = 0;
        while i < 14 {
            let mode = &MODES[i];
            let mask = (1u8 << mode.mode_bits) - 1;
            if (v as u8) & mask == mode.mode_value {
                t[v] = Some(i as u8);
            }
            i += 1;
        }
        v += 1;
    }
    t
};

/// The 32 two-region partitions: bit `i` (texel `i`, row-major) is the region of that texel.
/// Khronos Data Format Specification, "Partition table for 2-subset BPTC" (the BC6H shapes are
/// the BC7 two-subset shapes 0..31).
pub const PARTITIONS: [u16; 32] = [
    0xCCCC, 0x8888, 0xEEEE, 0xECC8, 0xC880, 0xFEEC, 0xFEC8, 0xEC80, 0xC800, 0xFFEC, 0xFE80, 0xE800, 0xFFE8, 0xFF00,
    0xFFF0, 0xF000, 0xF710, 0x008E, 0x7100, 0x08CE, 0x008C, 0x7310, 0x3100, 0x8CCE, 0x088C, 0x3110, 0x6666, 0x366C,
    0x17E8, 0x0FF0, 0x718E, 0x399C,
];

/// The anchor (fix-up) texel of region 1 for each two-region partition; region 0's anchor is
/// always texel 0. An anchor texel's index is stored with one bit less (its top bit is 0).
/// Khronos Data Format Specification, "BPTC anchor index values" (second subset of two).
pub const ANCHORS: [u8; 32] =
    [15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 2, 8, 2, 2, 8, 8, 15, 2, 8, 2, 2, 8, 8, 2, 2];

/// Interpolation weights (out of 64) for 3-bit indices.
pub const WEIGHTS3: [u8; 8] = [0, 9, 18, 27, 37, 46, 55, 64];
/// Interpolation weights (out of 64) for 4-bit indices.
pub const WEIGHTS4: [u8; 16] = [0, 4, 9, 13, 17, 21, 26, 30, 34, 38, 43, 47, 51, 55, 60, 64];

/// Region (0 or 1) of texel `i` in two-region partition `d`.
#[inline]
pub const fn region_of(d: usize, i: usize) -> usize {
    ((PARTITIONS[d & 31] >> i) & 1) as usize
}

/// Whether texel `i` is an anchor (stores one index bit less) for `regions` and partition `d`.
#[inline]
pub const fn is_anchor(regions: u8, d: usize, i: usize) -> bool {
    i == 0 || (regions == 2 && i == ANCHORS[d & 31] as usize)
}

/// Reads bits LSB first from a 128-bit block (bit 0 is the lowest bit of byte 0).
#[derive(Clone, Copy, Debug)]
pub struct BitReader {
    bits: u128,
    pos: u32,
}

impl BitReader {
    /// Starts reading at bit 0 of `block`.
    #[inline]
    pub fn new(block: &[u8; 16]) -> Self {
        BitReader { bits: u128::from_le_bytes(*block), pos: 0 }
    }

    /// Reads `n` (0..=32) bits; bits beyond the block read as 0.
    #[inline]
    pub fn read(&mut self, n: u32) -> u32 {
        let v = if self.pos >= 128 { 0 } else { (self.bits >> self.pos) as u32 };
        self.pos += n;
        if n >= 32 {
            v
        } else {
            v & ((1u32 << n) - 1)
        }
    }

    /// Current bit position.
    #[inline]
    pub fn position(&self) -> u32 {
        self.pos
    }
}

/// Writes bits LSB first into a 128-bit block, the inverse of [`BitReader`].
#[derive(Clone, Copy, Debug, Default)]
pub struct BitWriter {
    bits: u128,
    pos: u32,
}

impl BitWriter {
    /// An empty block.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends the low `n` (0..=32) bits of `v` (higher bits of `v` are ignored); bits past
    /// bit 127 are dropped.
    #[inline]
    pub fn write(&mut self, v: u32, n: u32) {
        let masked = if n >= 32 { v } else { v & ((1u32 << n) - 1) };
        if self.pos < 128 {
            self.bits |= (masked as u128) << self.pos;
        }
        self.pos += n;
    }

    /// Current bit position.
    pub fn position(&self) -> u32 {
        self.pos
    }

    /// The block bytes.
    pub fn finish(self) -> [u8; 16] {
        self.bits.to_le_bytes()
    }
}

/// The raw contents of a block as stored: mode, endpoint fields, partition and indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct BlockFields {
    /// Index into [`MODES`].
    pub mode: usize,
    /// Stored field values, indexed by `Field as usize`: endpoint components as stored (`w` at
    /// `endpoint_bits`, `x`/`y`/`z` at `delta_bits`, two's complement in that width where signed)
    /// and, at index 12, the partition number. Unused entries are 0.
    pub values: [u32; 13],
    /// Texel indices, row-major (anchor texels must have their top index bit clear).
    pub indices: [u8; 16],
}

impl BlockFields {
    /// Stored value of endpoint `e` (0..4 = w, x, y, z), channel `c` (0..3 = r, g, b).
    #[inline]
    pub fn endpoint(&self, e: usize, c: usize) -> u32 {
        self.values[e * 3 + c]
    }

    /// The partition number (0 for one-region modes).
    #[inline]
    pub fn partition(&self) -> usize {
        self.values[Field::D as usize] as usize
    }
}

#[inline]
fn reverse_low(v: u32, n: u32) -> u32 {
    v.reverse_bits() >> (32 - n)
}

/// Reads the mode, endpoint fields, partition and indices of a block; `None` for a reserved
/// mode.
#[inline]
pub fn unpack_block(block: &[u8; 16]) -> Option<BlockFields> {
    let bits = u128::from_le_bytes(*block);
    let mode = MODE_FROM_BITS[(bits & 31) as usize]? as usize;
    let info = &MODES[mode];
    let mut values = [0u32; 13];
    let mut pos = info.mode_bits as u32;
    for run in info.layout {
        let n = run.len();
        let mut v = ((bits >> pos) as u32) & ((1u32 << n) - 1);
        let shift = if run.reversed() {
            v = reverse_low(v, n);
            run.last
        } else {
            run.first
        };
        values[run.field as usize] |= v << shift;
        pos += n;
    }
    let mut indices = [0u8; 16];
    let ib = info.index_bits();
    let d = values[Field::D as usize] as usize;
    let mut idx = bits >> pos;
    for (i, out) in indices.iter_mut().enumerate() {
        let n = if is_anchor(info.regions, d, i) { ib - 1 } else { ib };
        *out = (idx as u8) & ((1u8 << n) - 1);
        idx >>= n;
    }
    Some(BlockFields { mode, values, indices })
}

/// Writes a block from its fields, the inverse of [`unpack_block`].
///
/// Field values are masked to their stored width (so negative deltas may be passed as two's
/// complement `u32`); an anchor texel's top index bit must be 0 (it is not stored; in debug builds
/// this is asserted).
pub fn pack_block(fields: &BlockFields) -> [u8; 16] {
    let info = &MODES[fields.mode];
    let mut w = BitWriter::new();
    w.write(info.mode_value as u32, info.mode_bits as u32);
    for run in info.layout {
        let n = run.len();
        let lo = run.first.min(run.last) as u32;
        let mut v = (fields.values[run.field as usize] >> lo) & ((1u32 << n) - 1);
        if run.reversed() {
            v = reverse_low(v, n);
        }
        w.write(v, n);
    }
    let ib = info.index_bits();
    let d = fields.partition();
    for (i, &ix) in fields.indices.iter().enumerate() {
        let n = if is_anchor(info.regions, d, i) { ib - 1 } else { ib };
        debug_assert!((ix as u32) < (1 << n), "anchor index {i} has its top bit set");
        w.write(ix as u32, n);
    }
    debug_assert_eq!(w.position(), 128);
    w.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_mode_fills_exactly_128_bits() {
        for mode in &MODES {
            let header = if mode.regions == 2 { 82 } else { 65 };
            assert_eq!(mode.header_bits(), header, "mode {}", mode.number);
            let index_bits = if mode.regions == 2 { 46 } else { 63 };
            assert_eq!(header + index_bits, 128);
        }
    }

    #[test]
    fn layouts_cover_each_field_bit_once() {
        for mode in &MODES {
            let mut seen = [0u32; 13];
            for run in mode.layout {
                let lo = run.first.min(run.last) as u32;
                let mask = ((1u32 << run.len()) - 1) << lo;
                assert_eq!(seen[run.field as usize] & mask, 0, "mode {} {:?}", mode.number, run);
                seen[run.field as usize] |= mask;
            }
            let full = |b: u8| (1u32 << b) - 1;
            for c in 0..3 {
                assert_eq!(seen[c], full(mode.endpoint_bits), "mode {} w{c}", mode.number);
                let ends = if mode.regions == 2 { 4 } else { 2 };
                for e in 1..4 {
                    let want = if e < ends { full(mode.delta_bits[c]) } else { 0 };
                    assert_eq!(seen[e * 3 + c], want, "mode {} e{e} c{c}", mode.number);
                }
            }
            assert_eq!(seen[12], if mode.regions == 2 { 31 } else { 0 });
        }
    }

    #[test]
    fn mode_values_match_the_spec_table() {
        // D3D11 "BC6H format" table: modes 1..14 and the four reserved values.
        assert_eq!(MODE_FROM_BITS[0b00000], Some(0));
        assert_eq!(MODE_FROM_BITS[0b11100], Some(0));
        assert_eq!(MODE_FROM_BITS[0b10101], Some(1));
        assert_eq!(MODE_FROM_BITS[0b01111], Some(13));
        for r in RESERVED_MODE_VALUES {
            assert_eq!(MODE_FROM_BITS[r as usize], None);
        }
        let valid = MODE_FROM_BITS.iter().filter(|m| m.is_some()).count();
        assert_eq!(valid, 32 - 4);
    }

    #[test]
    fn partitions_and_anchors_agree() {
        for d in 0..32 {
            // Texel 0 is always region 0, and the anchor always lies in region 1.
            assert_eq!(region_of(d, 0), 0, "partition {d}");
            assert_eq!(region_of(d, ANCHORS[d] as usize), 1, "partition {d}");
            let ones = PARTITIONS[d].count_ones();
            assert!((1..16).contains(&ones));
        }
    }

    #[test]
    fn pack_unpack_round_trip() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..20_000 {
            let mut block = [0u8; 16];
            block[..8].copy_from_slice(&next().to_le_bytes());
            block[8..].copy_from_slice(&next().to_le_bytes());
            if let Some(fields) = unpack_block(&block) {
                let packed = pack_block(&fields);
                // Modes 1 and 2 use 2 mode bits; the rest of the block round-trips exactly.
                assert_eq!(packed, block, "mode {}", MODES[fields.mode].number);
            }
        }
    }

    #[test]
    fn bit_writer_matches_reader() {
        let mut w = BitWriter::new();
        for n in 1..=15u32 {
            w.write(n * 3 + 1, n);
        }
        let block = w.finish();
        let mut r = BitReader::new(&block);
        for n in 1..=15u32 {
            assert_eq!(r.read(n), (n * 3 + 1) & ((1 << n) - 1));
        }
        assert_eq!(r.position(), 120);
    }
}
