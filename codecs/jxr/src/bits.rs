//! MSB-first bit reading over a byte slice (T.832 clause 8 reads every syntax element most
//! significant bit first), its inverse [`BitWriter`], and the variable-length word VLW_ESC.
//!
//! The reader keeps up to 64 bits in a buffer, left-aligned, and refills a whole word at a time
//! while at least 8 bytes remain. Reading past the end never fails on the spot: the missing
//! bits read as zeros and [`BitReader::overrun`] turns true. Decoders check it at the end of a
//! packet (or of a macroblock row) and report [`Error::Truncated`]; every loop of the entropy
//! decoder is bounded by the block size, so zeros cannot make it run away.

use hdrcodec_core::{Error, Result};

/// An MSB-first bit reader.
#[derive(Clone, Debug)]
pub struct BitReader<'a> {
    data: &'a [u8],
    /// Next byte of `data` to load into `buf`.
    pos: usize,
    /// Bits not yet consumed, left-aligned (bit 63 is the next bit).
    buf: u64,
    /// Number of valid bits in `buf` (zeros past the end of the data count as valid).
    avail: u32,
    /// Zero bits appended past the end of the data that are in `buf` or were consumed.
    padded: u64,
}

/// Where a [`BitReader`] is in its data, without the data: what a reader over a window of a
/// file keeps between macroblocks, so that the window can move (see `source`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct ReaderState {
    pos: usize,
    buf: u64,
    avail: u32,
    padded: u64,
}

impl<'a> BitReader<'a> {
    /// A reader at the first bit of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        BitReader { data, pos: 0, buf: 0, avail: 0, padded: 0 }
    }

    /// A reader over `data` where [`state`](Self::state) left one over the same bytes.
    #[inline(always)]
    pub(crate) fn resume(data: &'a [u8], state: ReaderState) -> Self {
        let ReaderState { pos, buf, avail, padded } = state;
        BitReader { data, pos, buf, avail, padded }
    }

    /// Where the reader is (see [`resume`](Self::resume)).
    #[inline(always)]
    pub(crate) fn state(&self) -> ReaderState {
        ReaderState { pos: self.pos, buf: self.buf, avail: self.avail, padded: self.padded }
    }

    /// Tops the buffer up to at least 56 bits: one unaligned 8-byte load while 8 bytes
    /// remain (the bits of the loaded word past `avail` are the stream's next bits, so loads
    /// may overlap), byte by byte with zero padding at the end.
    #[inline]
    fn refill(&mut self) {
        if let Some(chunk) = self.data.get(self.pos..self.pos + 8) {
            let mut word = [0u8; 8];
            word.copy_from_slice(chunk);
            self.buf |= u64::from_be_bytes(word) >> self.avail;
            self.pos += ((63 - self.avail) >> 3) as usize;
            // avail + 8 * ((63 - avail) / 8) for avail <= 56.
            self.avail |= 56;
        } else {
            *self = self.clone().refilled_tail();
        }
    }

    /// [`refill`](Self::refill) near the end of the data. It takes the reader by value and
    /// returns it: a `&mut self` would hand the address of the caller's reader to a call that
    /// is not inlined, and the hot loops that keep the reader in registers (the entropy
    /// decoder's local copies) would have to keep it in memory instead.
    #[cold]
    #[inline(never)]
    fn refilled_tail(mut self) -> Self {
        while self.avail <= 56 {
            let byte = match self.data.get(self.pos) {
                Some(&b) => {
                    self.pos += 1;
                    b
                }
                None => {
                    self.padded += 8;
                    0
                }
            };
            self.buf |= u64::from(byte) << (56 - self.avail);
            self.avail += 8;
        }
        self
    }

    /// The next `n` bits (`n` ≤ 32) without consuming them.
    #[inline]
    pub fn peek(&mut self, n: u32) -> u32 {
        debug_assert!(n <= 32);
        if self.avail < n {
            self.refill();
        }
        if n == 0 {
            0
        } else {
            (self.buf >> (64 - n)) as u32
        }
    }

    /// Tops the buffer up to at least 56 bits, so that the next reads, up to 56 bits in all,
    /// can use [`peek_buffered`](Self::peek_buffered) instead of checking for a refill each.
    #[inline]
    pub fn fill(&mut self) {
        if self.avail < 56 {
            self.refill();
        }
    }

    /// Makes sure that at least `n` (≤ 56) bits are buffered, for
    /// [`peek_buffered`](Self::peek_buffered): a compare when they are.
    #[inline(always)]
    pub fn ensure(&mut self, n: u32) {
        debug_assert!(n <= 56);
        if self.avail < n {
            self.refill();
        }
    }

    /// The next `n` bits (1 ≤ `n` ≤ 32) without consuming them, from the buffer alone: the
    /// caller made sure, with [`fill`](Self::fill), that at least `n` bits are buffered.
    #[inline]
    pub fn peek_buffered(&self, n: u32) -> u32 {
        debug_assert!((1..=32).contains(&n) && n <= self.avail);
        (self.buf >> ((64 - n) & 63)) as u32
    }

    /// The bits of the stream from bit `bit` on (counted from the start of the data, as
    /// [`bit_pos`](Self::bit_pos) counts), left-aligned, most significant first, without moving
    /// the reader: at least the first 57 are the stream's (zeros past the end of the data), the
    /// others may read as zeros. For a serial loop that keeps its own bit position and hands it
    /// back with [`seek`](Self::seek).
    #[inline(always)]
    pub fn bits_at(&self, bit: u64) -> u64 {
        let byte = (bit >> 3) as usize;
        match self.data.get(byte..byte.wrapping_add(8)) {
            Some(chunk) => {
                let mut word = [0u8; 8];
                word.copy_from_slice(chunk);
                // bit & 7 < 64: the shift is defined.
                u64::from_be_bytes(word) << (bit & 7)
            }
            None => Self::bits_at_tail(self.data, bit),
        }
    }

    /// [`bits_at`](Self::bits_at) within 8 bytes of the end of the data, or past it.
    #[cold]
    #[inline(never)]
    fn bits_at_tail(data: &[u8], bit: u64) -> u64 {
        let mut word = [0u8; 8];
        let byte = bit >> 3;
        for (i, w) in word.iter_mut().enumerate() {
            if let Some(&b) = usize::try_from(byte + i as u64).ok().and_then(|at| data.get(at)) {
                *w = b;
            }
        }
        u64::from_be_bytes(word) << (bit & 7)
    }

    /// Moves the reader to bit `bit` of the stream (as [`bit_pos`](Self::bit_pos) counts;
    /// past the end of the data the bits read as zeros and [`overrun`](Self::overrun) is
    /// true).
    pub fn seek(&mut self, bit: u64) {
        let len = self.data.len() as u64;
        let byte = bit >> 3;
        self.buf = 0;
        self.avail = 0;
        if byte <= len {
            self.pos = byte as usize;
            self.padded = 0;
        } else {
            self.pos = self.data.len();
            self.padded = (byte - len) * 8;
        }
        self.refill();
        self.skip((bit & 7) as u32);
    }

    /// Consumes `n` bits (`n` ≤ 32) that were peeked.
    #[inline]
    pub fn skip(&mut self, n: u32) {
        debug_assert!(n <= self.avail);
        // n <= 32 < 64: the shift is defined.
        self.buf <<= n & 63;
        self.avail -= n;
    }

    /// Reads `n` bits (`n` ≤ 32) as an unsigned number.
    #[inline]
    pub fn read(&mut self, n: u32) -> u32 {
        let v = self.peek(n);
        self.skip(n);
        v
    }

    /// Reads one bit.
    #[inline]
    pub fn bit(&mut self) -> bool {
        self.read(1) != 0
    }

    /// Reads `n` bits (`n` ≤ 64).
    pub fn read_u64(&mut self, n: u32) -> u64 {
        if n <= 32 {
            u64::from(self.read(n))
        } else {
            let hi = u64::from(self.read(n - 32));
            (hi << 32) | u64::from(self.read(32))
        }
    }

    /// Bits consumed so far (counting zeros read past the end).
    pub fn bit_pos(&self) -> u64 {
        self.pos as u64 * 8 + self.padded - u64::from(self.avail)
    }

    /// True when more bits were consumed than the data holds.
    pub fn overrun(&self) -> bool {
        self.bit_pos() > self.data.len() as u64 * 8
    }

    /// Skips to the next byte boundary.
    pub fn align(&mut self) {
        let rem = (self.bit_pos() % 8) as u32;
        if rem != 0 {
            self.peek(8);
            self.skip(8 - rem);
        }
    }

    /// The byte offset of the next bit (after [`align`](Self::align), the next byte).
    pub fn byte_pos(&self) -> u64 {
        self.bit_pos().div_ceil(8)
    }

    /// [`Error::Truncated`] naming `what` if the reader ran past the end of its data.
    pub fn check(&self, what: &str) -> Result<()> {
        if self.overrun() {
            Err(Error::truncated(what.to_string()))
        } else {
            Ok(())
        }
    }

    /// Reads a byte-aligned VLW_ESC word (T.832 8.2, used by the index table): a first byte
    /// below 0xFB starts a 16-bit value; 0xFB is followed by a 32-bit and 0xFC by a 64-bit
    /// value; 0xFD..=0xFF are escapes without a value (`None`).
    pub fn vlw_esc(&mut self) -> Option<u64> {
        let first = self.read(8);
        match first {
            0..=0xFA => Some(u64::from((first << 8) | self.read(8))),
            0xFB => Some(u64::from(self.read(32))),
            0xFC => Some(self.read_u64(64)),
            _ => None,
        }
    }
}

/// An MSB-first bit writer: the exact inverse of [`BitReader`] (what one writes with
/// `write(v, n)` the other reads back with `read(n)`).
///
/// Bits gather in a 64-bit accumulator and go to the byte vector 32 at a time, so that most
/// writes are a shift, an or and one compare.
#[derive(Clone, Debug, Default)]
pub struct BitWriter {
    bytes: Vec<u8>,
    /// Bits not yet in `bytes`, right-aligned: the low `pending` bits of `acc` (the bits above
    /// them are stale and never read).
    acc: u64,
    /// Fewer than 32 between calls.
    pending: u32,
}

impl BitWriter {
    /// An empty writer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes the low `n` bits of `value` (`n` ≤ 32), most significant first.
    #[inline]
    pub fn write(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 32);
        // n <= 32 < 64: the shifts are defined; pending < 32 and n <= 32, so no pending bit
        // is shifted out of the accumulator.
        let v = u64::from(value) & ((1u64 << (n & 63)) - 1);
        self.acc = (self.acc << (n & 63)) | v;
        self.pending += n;
        if self.pending >= 32 {
            self.pending -= 32;
            self.bytes.extend_from_slice(&((self.acc >> self.pending) as u32).to_be_bytes());
        }
    }

    /// [`write`](Self::write) of a `value` that has no bits at or above bit `n` (codes from
    /// the tables, which are built so): no masking.
    #[inline]
    pub fn put(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 32 && u64::from(value) >> n == 0);
        // As in `write`: n <= 32, pending < 32.
        self.acc = (self.acc << (n & 63)) | u64::from(value);
        self.pending += n;
        if self.pending >= 32 {
            self.pending -= 32;
            self.bytes.extend_from_slice(&((self.acc >> self.pending) as u32).to_be_bytes());
        }
    }

    /// Writes one bit.
    #[inline]
    pub fn bit(&mut self, b: bool) {
        self.write(u32::from(b), 1);
    }

    /// Writes zero bits up to the next byte boundary (what [`BitReader::align`] skips).
    pub fn align(&mut self) {
        let rem = self.pending % 8;
        if rem != 0 {
            self.write(0, 8 - rem);
        }
    }

    /// Bits written so far.
    pub fn bit_len(&self) -> u64 {
        self.bytes.len() as u64 * 8 + u64::from(self.pending)
    }

    /// The bytes written, the last one padded with zero bits.
    pub fn into_bytes(mut self) -> Vec<u8> {
        self.align();
        while self.pending >= 8 {
            self.pending -= 8;
            self.bytes.push((self.acc >> self.pending) as u8);
        }
        self.bytes
    }

    /// Writes `v` as VLW_ESC (T.832 8.2; the inverse of [`BitReader::vlw_esc`]): 16 bits when
    /// the first byte stays below 0xFB, else 0xFB and 32 bits, else 0xFC and 64 bits.
    pub fn vlw_esc(&mut self, v: u64) {
        if v < 0xFB00 {
            self.write(v as u32, 16);
        } else if let Ok(v) = u32::try_from(v) {
            self.write(0xFB, 8);
            self.write(v, 32);
        } else {
            self.write(0xFC, 8);
            self.write((v >> 32) as u32, 32);
            self.write(v as u32, 32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_msb_first_across_refills() {
        let data: Vec<u8> = (0..40u8).map(|i| i.wrapping_mul(37).wrapping_add(11)).collect();
        // Reference: a naive bit iterator.
        let bits: Vec<u32> = data.iter().flat_map(|b| (0..8).rev().map(move |i| u32::from((b >> i) & 1))).collect();
        for widths in [[1u32, 3, 7, 13, 32, 2, 17, 5], [8, 8, 8, 8, 8, 8, 8, 8], [32, 31, 30, 1, 1, 29, 9, 4]] {
            let mut r = BitReader::new(&data);
            let mut at = 0usize;
            'outer: loop {
                for &w in &widths {
                    if at + w as usize > bits.len() {
                        break 'outer;
                    }
                    let want = bits[at..at + w as usize].iter().fold(0u32, |a, &b| (a << 1) | b);
                    assert_eq!(r.read(w), want, "at bit {at}, width {w}");
                    at += w as usize;
                    assert_eq!(r.bit_pos(), at as u64);
                }
            }
            assert!(!r.overrun());
        }
    }

    #[test]
    fn bits_at_and_seek_agree_with_reading() {
        let data: Vec<u8> = (0..40u8).map(|i| i.wrapping_mul(91).wrapping_add(7)).collect();
        for bit in 0..(data.len() as u64 * 8 + 80) {
            let mut r = BitReader::new(&data);
            let _ = r.read_u64(0);
            let mut at = bit;
            while at > 0 {
                let n = at.min(32) as u32;
                r.read(n);
                at -= u64::from(n);
            }
            let want = r.clone().read_u64(64);
            assert_eq!(r.bits_at(bit) >> 7, want >> 7, "bit {bit}");
            let mut s = BitReader::new(&data);
            s.read(5);
            s.seek(bit);
            assert_eq!((s.bit_pos(), s.overrun()), (r.bit_pos(), r.overrun()), "bit {bit}");
            assert_eq!(s.read_u64(64), want, "bit {bit}");
            assert_eq!((s.bit_pos(), s.overrun()), (bit + 64, bit + 64 > data.len() as u64 * 8), "bit {bit}");
        }
    }

    #[test]
    fn past_the_end_reads_zeros_and_flags_overrun() {
        let mut r = BitReader::new(&[0xFF, 0x80]);
        assert_eq!(r.read(9), 0x1FF);
        assert!(!r.overrun());
        assert_eq!(r.read(7), 0);
        assert!(!r.overrun());
        assert!(r.check("x").is_ok());
        assert_eq!(r.read(32), 0);
        assert!(r.overrun());
        assert!(matches!(r.check("the tile"), Err(Error::Truncated { .. })));
        // Long after the end: still zeros, still no panic.
        for _ in 0..100 {
            assert_eq!(r.read(32), 0);
        }
        let mut e = BitReader::new(&[]);
        assert_eq!(e.read(1), 0);
        assert!(e.overrun());
    }

    #[test]
    fn align_and_vlw_esc() {
        let data = [0b1010_0000, 0x12, 0x34, 0xFB, 0, 1, 0, 2, 0xFF, 0xFC, 0, 0, 0, 1, 0, 0, 0, 3];
        let mut r = BitReader::new(&data);
        assert_eq!(r.read(3), 0b101);
        r.align();
        assert_eq!(r.byte_pos(), 1);
        assert_eq!(r.vlw_esc(), Some(0x1234));
        assert_eq!(r.vlw_esc(), Some(0x0001_0002));
        assert_eq!(r.vlw_esc(), None);
        assert_eq!(r.vlw_esc(), Some((1 << 32) | 3));
        assert_eq!(r.byte_pos(), data.len() as u64);
        assert!(!r.overrun());
    }

    #[test]
    fn writer_is_the_inverse_of_the_reader() {
        // xorshift32: random widths (0..=32) and values, including the bits above the width.
        let mut x = 0x2545_F491u32;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        };
        let mut w = BitWriter::new();
        let mut items = Vec::new();
        for _ in 0..5000 {
            let n = next() % 33;
            let v = next();
            w.write(v, n);
            items.push((v, n));
            if next() % 97 == 0 {
                w.align();
                items.push((0, u32::MAX));
            }
        }
        let len = w.bit_len();
        let bytes = w.into_bytes();
        assert_eq!(bytes.len() as u64, len.div_ceil(8));
        let mut r = BitReader::new(&bytes);
        for (v, n) in items {
            if n == u32::MAX {
                r.align();
                continue;
            }
            let mask = if n == 32 { u32::MAX } else { (1u32 << n) - 1 };
            assert_eq!(r.read(n), v & mask, "width {n}");
        }
        assert_eq!(r.bit_pos(), len);
        assert!(!r.overrun());
    }

    #[test]
    fn writer_bits_align_and_vlw_esc() {
        let mut w = BitWriter::new();
        w.bit(true);
        w.bit(false);
        w.bit(true);
        assert_eq!(w.bit_len(), 3);
        w.align();
        assert_eq!(w.bit_len(), 8);
        w.align();
        assert_eq!(w.bit_len(), 8);
        let values = [0u64, 0x1234, 0xFAFF, 0xFB00, 0x0001_0002, u64::from(u32::MAX), 1 << 32, u64::MAX];
        for v in values {
            w.vlw_esc(v);
        }
        w.write(0b101, 3);
        let bytes = w.into_bytes();
        assert_eq!(bytes[0], 0b1010_0000);
        let mut r = BitReader::new(&bytes);
        r.align();
        assert_eq!(r.read(8), 0b1010_0000);
        for v in values {
            assert_eq!(r.vlw_esc(), Some(v));
        }
        assert_eq!(r.read(3), 0b101);
        assert_eq!(*bytes.last().unwrap() & 0x1F, 0);
    }
}
