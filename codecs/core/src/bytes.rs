//! Bounded reading and writing of binary structures, for every parser of the family.
//!
//! [`ByteReader`] is a cursor over a byte slice with a byte order. Every read checks the bounds
//! and, when the data ends, returns [`Error::Truncated`] naming what was being read and where;
//! no input makes it panic, and it never allocates (reads return values or sub-slices of the
//! input), so a declared size can cost nothing until the bytes are really there.
//! [`ByteWriter`] is its counterpart: a growable buffer written in one byte order.
//!
//! ```
//! use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
//! let mut w = ByteWriter::new(ByteOrder::Big);
//! w.u16(0x0102);
//! w.u32(7);
//! w.bytes(b"abc");
//! let data = w.into_vec();
//! assert_eq!(data[..2], [1, 2]);
//!
//! let mut r = ByteReader::new(&data, ByteOrder::Big);
//! assert_eq!(r.u16("the tag")?, 0x0102);
//! let n = r.u32("the length")?;
//! assert!(r.bytes(u64::from(n), "the name").is_err()); // 7 bytes declared, 3 present
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use crate::{Error, Result};
use std::fmt::Display;

/// The order of the bytes of multi-byte numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ByteOrder {
    /// Least significant byte first (Intel; TIFF "II").
    #[default]
    Little,
    /// Most significant byte first (Motorola; TIFF "MM").
    Big,
}

/// A bounds-checked cursor over `&'a [u8]` that reads numbers in one [`ByteOrder`], and text
/// lines ([`line`](Self::line)).
///
/// The position is a `u64` and may be [`seek`](Self::seek)ed anywhere, even past the end: reads
/// from there fail with [`Error::Truncated`]. Each read takes `what`, a description of the
/// structure being read ("the TIFF header", "strip 3"), which the error repeats together with the
/// byte range that was missing. `what` is anything that displays: a `&str`, or
/// `format_args!("scanline {y}")`, which costs nothing unless the read fails.
#[derive(Clone, Debug)]
pub struct ByteReader<'a> {
    data: &'a [u8],
    pos: u64,
    order: ByteOrder,
}

macro_rules! read_numbers {
    ($($(#[$doc:meta])* $name:ident -> $t:ty;)*) => {$(
        $(#[$doc])*
        pub fn $name(&mut self, what: impl Display) -> Result<$t> {
            let b = self.array(what)?;
            Ok(match self.order {
                ByteOrder::Little => <$t>::from_le_bytes(b),
                ByteOrder::Big => <$t>::from_be_bytes(b),
            })
        }
    )*};
}

impl<'a> ByteReader<'a> {
    /// A reader at position 0 of `data`.
    pub fn new(data: &'a [u8], order: ByteOrder) -> Self {
        ByteReader { data, pos: 0, order }
    }

    /// A little-endian reader at position 0 of `data`.
    pub fn le(data: &'a [u8]) -> Self {
        Self::new(data, ByteOrder::Little)
    }

    /// A big-endian reader at position 0 of `data`.
    pub fn be(data: &'a [u8]) -> Self {
        Self::new(data, ByteOrder::Big)
    }

    /// All the bytes, whatever the position.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Length of the whole input in bytes.
    pub fn len(&self) -> u64 {
        self.data.len() as u64
    }

    /// True if the input has no bytes at all.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// The byte order of the number reads.
    pub fn order(&self) -> ByteOrder {
        self.order
    }

    /// Changes the byte order of the following reads.
    pub fn set_order(&mut self, order: ByteOrder) {
        self.order = order;
    }

    /// The position of the next read.
    pub fn position(&self) -> u64 {
        self.pos
    }

    /// Moves to `pos` (from the start of the input). Any position is accepted; reads past the end fail.
    pub fn seek(&mut self, pos: u64) {
        self.pos = pos;
    }

    /// This reader moved to `pos`, leaving `self` where it is.
    pub fn at(&self, pos: u64) -> Self {
        ByteReader { pos, ..self.clone() }
    }

    /// Bytes left after the position (0 when the position is at or past the end).
    pub fn remaining(&self) -> u64 {
        self.len().saturating_sub(self.pos)
    }

    /// The range `off..off + len` of the input, if it is inside it.
    #[inline]
    fn range(&self, off: u64, len: u64) -> Option<&'a [u8]> {
        // Two comparisons, no overflow to handle: `off` within the input, then `len` within what
        // follows it (a number that does not fit in usize cannot be either).
        self.data.get(usize::try_from(off).ok()?..)?.get(..usize::try_from(len).ok()?)
    }

    /// The error of a read that found the input too short: built only then, out of the way of
    /// the reads that succeed.
    #[cold]
    #[inline(never)]
    fn truncated(&self, off: u64, len: u64, what: impl Display) -> Error {
        Error::truncated(format!(
            "{what} (bytes {off}..{} of a {}-byte input)",
            off.saturating_add(len),
            self.data.len()
        ))
    }

    /// Checks, without reading or allocating, that `count` items of `size` bytes each follow
    /// the position, and returns their total size. Use it on a declared count before
    /// allocating for it; a product that overflows is reported as truncated data.
    pub fn check_remaining(&self, count: u64, size: u64, what: impl Display) -> Result<u64> {
        match count.checked_mul(size) {
            Some(n) if n <= self.remaining() => Ok(n),
            Some(n) => Err(self.truncated(self.pos, n, what)),
            None => Err(Error::truncated(format!(
                "{what} ({count} items of {size} bytes at offset {}, more than any input holds)",
                self.pos
            ))),
        }
    }

    /// The next `n` bytes, as a sub-slice of the input.
    #[inline]
    pub fn bytes(&mut self, n: u64, what: impl Display) -> Result<&'a [u8]> {
        match self.range(self.pos, n) {
            Some(b) => {
                self.pos += n;
                Ok(b)
            }
            None => Err(self.truncated(self.pos, n, what)),
        }
    }

    /// The `n` bytes at `off`, without moving the position.
    pub fn bytes_at(&self, off: u64, n: u64, what: impl Display) -> Result<&'a [u8]> {
        self.range(off, n).ok_or_else(|| self.truncated(off, n, what))
    }

    /// The next `n` bytes without moving the position.
    pub fn peek(&self, n: u64, what: impl Display) -> Result<&'a [u8]> {
        self.bytes_at(self.pos, n, what)
    }

    /// The bytes from the position to the end (empty past the end), without moving: for a
    /// loop that walks them as a slice and then [`skip`](Self::skip)s what it used.
    pub fn peek_rest(&self) -> &'a [u8] {
        self.range(self.pos, self.remaining()).unwrap_or_default()
    }

    /// The bytes from the position to the end (empty past the end); moves to the end.
    pub fn rest(&mut self) -> &'a [u8] {
        let b = self.peek_rest();
        self.pos = self.pos.max(self.len());
        b
    }

    /// The next bytes for which `pred` holds, at most `max_len` of them; moves past them. Never
    /// fails: the caller looks at what follows (the end of the data, the bound, another byte).
    /// Scans at most `max_len` bytes.
    pub fn take_while(&mut self, max_len: u64, mut pred: impl FnMut(u8) -> bool) -> &'a [u8] {
        let rest = self.peek_rest();
        let max = usize::try_from(max_len).unwrap_or(usize::MAX).min(rest.len());
        let n = rest[..max].iter().position(|&b| !pred(b)).unwrap_or(max);
        self.pos += n as u64;
        &rest[..n]
    }

    /// A text line: the bytes before the next `\n` (a `\r` before it is kept), moving past the
    /// `\n`. The line may hold at most `max_len` bytes, so at most `max_len + 1` are scanned:
    /// when the data ends first without a `\n` the error is [`Error::Truncated`]; when
    /// `max_len` bytes pass without one, [`Error::Invalid`] (a line too long to be what the
    /// caller reads). Either way the position does not move.
    pub fn line(&mut self, max_len: u64, what: impl Display) -> Result<&'a [u8]> {
        let start = self.pos;
        let line = self.take_while(max_len, |b| b != b'\n');
        if self.peek_rest().first() == Some(&b'\n') {
            self.pos += 1;
            return Ok(line);
        }
        self.pos = start;
        let len = self.len();
        Err(if line.len() as u64 == max_len && start.saturating_add(max_len) < len {
            Error::invalid(format!("{what}: the line at offset {start} is longer than {max_len} bytes"))
        } else {
            Error::truncated(format!("{what} (no line end after offset {start} of a {len}-byte input)"))
        })
    }

    /// Skips `n` bytes, which must be present.
    pub fn skip(&mut self, n: u64, what: impl Display) -> Result<()> {
        self.bytes(n, what).map(|_| ())
    }

    /// A reader over the next `n` bytes (same byte order, its positions start at 0); moves past them.
    pub fn sub(&mut self, n: u64, what: impl Display) -> Result<ByteReader<'a>> {
        let data = self.bytes(n, what)?;
        Ok(ByteReader { data, pos: 0, order: self.order })
    }

    /// The next `N` bytes as an array.
    #[inline]
    pub fn array<const N: usize>(&mut self, what: impl Display) -> Result<[u8; N]> {
        match self.range(self.pos, N as u64).and_then(<[u8]>::first_chunk::<N>) {
            Some(&a) => {
                self.pos += N as u64;
                Ok(a)
            }
            None => Err(self.truncated(self.pos, N as u64, what)),
        }
    }

    /// The next byte.
    pub fn u8(&mut self, what: impl Display) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }

    /// The next byte as a signed number.
    pub fn i8(&mut self, what: impl Display) -> Result<i8> {
        Ok(self.array::<1>(what)?[0] as i8)
    }

    read_numbers! {
        /// The next 2 bytes as an unsigned number.
        u16 -> u16;
        /// The next 2 bytes as a two's-complement number.
        i16 -> i16;
        /// The next 4 bytes as an unsigned number.
        u32 -> u32;
        /// The next 4 bytes as a two's-complement number.
        i32 -> i32;
        /// The next 8 bytes as an unsigned number.
        u64 -> u64;
        /// The next 8 bytes as a two's-complement number.
        i64 -> i64;
        /// The next 4 bytes as an IEEE 754 binary32.
        f32 -> f32;
        /// The next 8 bytes as an IEEE 754 binary64.
        f64 -> f64;
    }
}

/// A growable buffer that writes numbers in one [`ByteOrder`], the counterpart of [`ByteReader`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ByteWriter {
    buf: Vec<u8>,
    order: ByteOrder,
}

macro_rules! write_numbers {
    ($($(#[$doc:meta])* $name:ident($t:ty);)*) => {$(
        $(#[$doc])*
        pub fn $name(&mut self, v: $t) {
            match self.order {
                ByteOrder::Little => self.buf.extend_from_slice(&v.to_le_bytes()),
                ByteOrder::Big => self.buf.extend_from_slice(&v.to_be_bytes()),
            }
        }
    )*};
}

impl ByteWriter {
    /// An empty writer.
    pub fn new(order: ByteOrder) -> Self {
        ByteWriter { buf: Vec::new(), order }
    }

    /// A writer that appends to `buf`.
    pub fn from_vec(buf: Vec<u8>, order: ByteOrder) -> Self {
        ByteWriter { buf, order }
    }

    /// The byte order of the number writes.
    pub fn order(&self) -> ByteOrder {
        self.order
    }

    /// Bytes written so far (the position of the next write).
    pub fn len(&self) -> usize {
        self.buf.len()
    }

    /// True if nothing was written.
    pub fn is_empty(&self) -> bool {
        self.buf.is_empty()
    }

    /// The bytes written so far.
    pub fn as_slice(&self) -> &[u8] {
        &self.buf
    }

    /// The buffer, for code that appends to a `Vec<u8>` directly.
    pub fn as_mut_vec(&mut self) -> &mut Vec<u8> {
        &mut self.buf
    }

    /// The bytes written.
    pub fn into_vec(self) -> Vec<u8> {
        self.buf
    }

    /// Appends raw bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        self.buf.extend_from_slice(b);
    }

    /// Appends `n` zero bytes.
    pub fn zeros(&mut self, n: usize) {
        self.buf.resize(self.buf.len() + n, 0);
    }

    /// Appends zero bytes until the length is a multiple of `align` (0 and 1 do nothing).
    pub fn align(&mut self, align: usize) {
        if align > 1 {
            self.zeros((align - self.buf.len() % align) % align);
        }
    }

    /// Appends one byte.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    write_numbers! {
        /// Appends 2 bytes.
        u16(u16);
        /// Appends 2 bytes.
        i16(i16);
        /// Appends 4 bytes.
        u32(u32);
        /// Appends 4 bytes.
        i32(i32);
        /// Appends 8 bytes.
        u64(u64);
        /// Appends 8 bytes.
        i64(i64);
        /// Appends an IEEE 754 binary32.
        f32(f32);
        /// Appends an IEEE 754 binary64.
        f64(f64);
    }

    /// Overwrites the bytes at `at` (already written) with `b`.
    pub fn patch(&mut self, at: usize, b: &[u8]) -> Result<()> {
        let len = self.buf.len();
        match at.checked_add(b.len()).and_then(|end| self.buf.get_mut(at..end)) {
            Some(dst) => {
                dst.copy_from_slice(b);
                Ok(())
            }
            None => Err(Error::invalid(format!("patching bytes {at}..+{} of a {len}-byte buffer", b.len()))),
        }
    }

    /// Overwrites the 2 bytes at `at` with `v` in the writer's order.
    pub fn patch_u16(&mut self, at: usize, v: u16) -> Result<()> {
        let b = match self.order {
            ByteOrder::Little => v.to_le_bytes(),
            ByteOrder::Big => v.to_be_bytes(),
        };
        self.patch(at, &b)
    }

    /// Overwrites the 4 bytes at `at` with `v` in the writer's order.
    pub fn patch_u32(&mut self, at: usize, v: u32) -> Result<()> {
        let b = match self.order {
            ByteOrder::Little => v.to_le_bytes(),
            ByteOrder::Big => v.to_be_bytes(),
        };
        self.patch(at, &b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small structure: magic u16, count u8, f32, i64, then `count` bytes of name.
    fn parse(data: &[u8], order: ByteOrder) -> Result<(u16, f32, i64, &[u8])> {
        let mut r = ByteReader::new(data, order);
        let magic = r.u16("the magic")?;
        let count = r.u8("the count")?;
        let x = r.f32("the scale")?;
        let y = r.i64("the offset")?;
        let name = r.bytes(u64::from(count), "the name")?;
        Ok((magic, x, y, name))
    }

    fn sample(order: ByteOrder) -> Vec<u8> {
        let mut w = ByteWriter::new(order);
        w.u16(0xbeef);
        w.u8(5);
        w.f32(1.5);
        w.i64(-3);
        w.bytes(b"hello");
        w.into_vec()
    }

    #[test]
    fn every_truncation_point_is_truncated_never_a_panic() {
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let data = sample(order);
            assert_eq!(data.len(), 2 + 1 + 4 + 8 + 5);
            assert_eq!(parse(&data, order).unwrap(), (0xbeef, 1.5, -3, &b"hello"[..]));
            for cut in 0..data.len() {
                let e = parse(&data[..cut], order).unwrap_err();
                assert!(matches!(e, Error::Truncated { .. }), "cut {cut}: {e}");
                let what = match cut {
                    0..=1 => "the magic",
                    2 => "the count",
                    3..=6 => "the scale",
                    7..=14 => "the offset",
                    _ => "the name",
                };
                assert!(e.to_string().contains(what), "cut {cut}: {e}");
            }
        }
    }

    #[test]
    fn byte_orders() {
        let data = [1u8, 2, 3, 4, 5, 6, 7, 8];
        assert_eq!(ByteReader::le(&data).u16("x").unwrap(), 0x0201);
        assert_eq!(ByteReader::be(&data).u16("x").unwrap(), 0x0102);
        assert_eq!(ByteReader::le(&data).u32("x").unwrap(), 0x0403_0201);
        assert_eq!(ByteReader::be(&data).u32("x").unwrap(), 0x0102_0304);
        assert_eq!(ByteReader::le(&data).u64("x").unwrap(), 0x0807_0605_0403_0201);
        assert_eq!(ByteReader::be(&data).u64("x").unwrap(), 0x0102_0304_0506_0708);
        assert_eq!(ByteReader::be(&[0xff, 0xfe]).i16("x").unwrap(), -2);
        assert_eq!(ByteReader::be(&[0x80]).i8("x").unwrap(), -128);
        let mut r = ByteReader::le(&data);
        r.set_order(ByteOrder::Big);
        assert_eq!(r.order(), ByteOrder::Big);
        assert_eq!(r.u16("x").unwrap(), 0x0102);
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let mut w = ByteWriter::new(order);
            w.f64(-2.25);
            w.i32(-7);
            w.u64(u64::MAX - 1);
            w.f32(f32::MIN_POSITIVE);
            w.i16(-300);
            let d = w.into_vec();
            let mut r = ByteReader::new(&d, order);
            assert_eq!(r.f64("a").unwrap(), -2.25);
            assert_eq!(r.i32("b").unwrap(), -7);
            assert_eq!(r.u64("c").unwrap(), u64::MAX - 1);
            assert_eq!(r.f32("d").unwrap(), f32::MIN_POSITIVE);
            assert_eq!(r.i16("e").unwrap(), -300);
            assert_eq!(r.remaining(), 0);
        }
    }

    #[test]
    fn positions_past_the_end_and_huge_sizes_are_errors() {
        let data = [0u8; 10];
        let mut r = ByteReader::le(&data);
        r.seek(u64::MAX);
        assert_eq!(r.remaining(), 0);
        assert!(matches!(r.u8("x"), Err(Error::Truncated { .. })));
        assert!(r.rest().is_empty());
        assert!(r.bytes_at(u64::MAX, 2, "x").is_err());
        assert!(r.bytes_at(9, u64::MAX, "x").is_err());
        assert!(r.bytes_at(11, 0, "x").is_err());
        assert_eq!(r.bytes_at(10, 0, "x").unwrap(), &[] as &[u8]);
        r.seek(4);
        assert_eq!(r.check_remaining(3, 2, "x").unwrap(), 6);
        assert!(r.check_remaining(7, 1, "x").is_err());
        let e = r.check_remaining(u64::MAX, 8, "the entries").unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }) && e.to_string().contains("the entries"), "{e}");
        assert!(r.bytes(u64::MAX, "x").is_err());
        assert_eq!(r.position(), 4, "a failed read does not move the position");
        let mut s = r.sub(4, "x").unwrap();
        assert_eq!((s.position(), s.len(), r.position()), (0, 4, 8));
        assert!(s.u64("x").is_err());
        assert_eq!(s.at(2).u16("x").unwrap(), 0);
        assert_eq!(s.position(), 0);
        assert_eq!(r.peek(2, "x").unwrap().len(), 2);
        assert_eq!(r.rest().len(), 2);
        assert_eq!(r.position(), 10);
        assert!(r.skip(1, "x").is_err());
    }

    #[test]
    fn lines_are_bounded_and_never_scan_past_the_bound() {
        let data = b"#?RADIANCE\r\nFORMAT=x\n\n-Y 1 +X 2";
        let mut r = ByteReader::le(data);
        assert_eq!(r.line(64, "the header").unwrap(), b"#?RADIANCE\r");
        assert_eq!(r.line(8, "the header").unwrap(), b"FORMAT=x", "exactly max_len bytes fit");
        assert_eq!(r.line(0, "the header").unwrap(), b"", "an empty line fits any bound");
        assert_eq!(r.position(), 22);
        // The data ends before a line end: truncated, naming what and where; the position stays.
        let e = r.line(64, "the resolution string").unwrap_err();
        assert!(matches!(e, Error::Truncated { .. }), "{e}");
        assert!(
            e.to_string().contains("the resolution string (no line end after offset 22 of a 31-byte input)"),
            "{e}"
        );
        assert_eq!(r.position(), 22);
        // Exactly max_len bytes, then the end of the data: still truncated (a line end may follow).
        assert!(matches!(r.line(9, "x"), Err(Error::Truncated { .. })));
        // More than max_len bytes without a line end: invalid, however much data follows.
        let e = r.line(8, "the resolution string").unwrap_err();
        assert!(matches!(e, Error::Invalid { .. }), "{e}");
        assert!(e.to_string().contains("at offset 22 is longer than 8 bytes"), "{e}");
        assert_eq!(r.position(), 22);
        let e = ByteReader::le(b"abc\n").line(2, "x").unwrap_err();
        assert!(matches!(e, Error::Invalid { .. }), "{e}");
        // Past the end, and a bound larger than any input.
        r.seek(u64::MAX);
        assert!(matches!(r.line(u64::MAX, "x"), Err(Error::Truncated { .. })));
        assert_eq!(ByteReader::le(b"a\nb").line(u64::MAX, "x").unwrap(), b"a");
    }

    #[test]
    fn take_while_stops_at_the_predicate_the_bound_or_the_end() {
        let mut r = ByteReader::le(b"  12 x");
        assert_eq!(r.take_while(10, |b| b == b' '), b"  ");
        assert_eq!(r.take_while(1, |b| b.is_ascii_digit()), b"1", "the bound");
        assert_eq!(r.take_while(10, |b| b.is_ascii_digit()), b"2", "the predicate");
        assert_eq!(r.peek_rest(), b" x");
        assert_eq!(r.take_while(u64::MAX, |_| true), b" x", "the end");
        assert_eq!(r.position(), 6);
        assert_eq!(r.take_while(5, |_| true), b"");
        r.seek(100);
        assert_eq!((r.take_while(5, |_| true), r.peek_rest(), r.position()), (&b""[..], &b""[..], 100));
    }

    #[test]
    fn what_may_be_formatted_lazily() {
        let mut r = ByteReader::le(&[1, 2, 3]);
        let y = 7;
        assert_eq!(r.u16(format_args!("scanline {y}")).unwrap(), 0x0201);
        let e = r.u16(format_args!("scanline {y}")).unwrap_err();
        assert!(e.to_string().contains("scanline 7 (bytes 2..4 of a 3-byte input)"), "{e}");
    }

    #[test]
    fn writer_alignment_and_patches() {
        let mut w = ByteWriter::new(ByteOrder::Big);
        w.u8(1);
        w.align(2);
        assert_eq!(w.len(), 2);
        w.align(2);
        assert_eq!(w.len(), 2);
        w.align(0);
        w.zeros(3);
        w.align(4);
        assert_eq!(w.len(), 8);
        w.patch_u32(4, 0x0102_0304).unwrap();
        w.patch_u16(0, 0xabcd).unwrap();
        assert_eq!(w.as_slice(), &[0xab, 0xcd, 0, 0, 1, 2, 3, 4]);
        assert!(w.patch_u32(6, 0).is_err());
        assert!(w.patch(usize::MAX, &[0]).is_err());
        let mut w = ByteWriter::from_vec(vec![9], ByteOrder::Little);
        w.as_mut_vec().push(8);
        w.u16(0x0102);
        assert_eq!(w.into_vec(), [9, 8, 2, 1]);
    }
}
