//! The structure of TIFF files: the image file header, image file directories (IFDs) and
//! their entries, read and written with every offset and count checked before it is used.
//!
//! References are to the TIFF Revision 6.0 specification (Adobe, 3 June 1992). Its Section 2
//! ("TIFF Structure") defines everything here: an 8-byte header (byte order, a 16-bit magic
//! number, the offset of the first IFD), and a chain of IFDs, each a 2-byte entry count, 12-byte
//! entries sorted by tag and the 4-byte offset of the next IFD (0 after the last). An entry is
//! (tag, field type, count, value or offset): values of at most 4 bytes sit in the entry itself,
//! longer ones elsewhere in the file at the given offset.
//!
//! Other formats use the same structure with a magic number of their own, so the caller names
//! the magic: 42 for TIFF ([`MAGIC_TIFF`]), 0x01BC for JPEG XR's container (ITU-T T.832
//! Annex A: "II", 0xBC, version 1; [`MAGIC_JPEG_XR`]). Only the classic form with 32-bit
//! offsets is read: BigTIFF ([`MAGIC_BIGTIFF`]) is refused.
//!
//! Reading: [`Tiff::parse`] checks the header; [`Tiff::ifd_chain`] walks the IFDs with loop
//! protection without reading their entries; [`Tiff::read_ifd`] reads one IFD's [`Entry`]s, whose
//! values are read with the [`Entry`] methods, bounded by the data and by [`Limits`]. A file
//! that is not in memory is read in [`TiffParts`] (its header, IFDs and the values of the tags a
//! reader asks for, each read from the stream at its offset) and parsed by
//! [`Tiff::from_parts`]: the same reader, the same checks, without holding the file.
//! Writing: [`write_header`] and [`IfdWriter`].
//!
//! ```
//! use hdrcodec_core::bytes::{ByteOrder, ByteWriter};
//! use hdrcodec_core::tiff::{tag, write_header, IfdWriter, Tiff, MAGIC_TIFF};
//! use hdrcodec_core::Limits;
//! let mut w = ByteWriter::new(ByteOrder::Big);
//! let link = write_header(&mut w, MAGIC_TIFF);
//! let mut ifd = IfdWriter::new();
//! ifd.long(tag::IMAGE_WIDTH, 640);
//! ifd.shorts(tag::BITS_PER_SAMPLE, &[16, 16, 16]);
//! ifd.ascii(tag::SOFTWARE, "hdrcodec");
//! ifd.write(&mut w, link)?;
//! let file = w.into_vec();
//!
//! let tiff = Tiff::parse(&file, MAGIC_TIFF)?;
//! let first = tiff.first_ifd()?;
//! assert_eq!(first.get(tag::IMAGE_WIDTH).unwrap().first_u32(&tiff)?, 640);
//! let bits = first.get(tag::BITS_PER_SAMPLE).unwrap().u16s(&tiff, &Limits::default())?;
//! assert_eq!(bits, [16, 16, 16]);
//! assert_eq!(first.get(tag::SOFTWARE).unwrap().ascii(&tiff, &Limits::default())?, "hdrcodec");
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use crate::bytes::{ByteOrder, ByteReader, ByteWriter};
use crate::{Allocation, Error, Limits, ReadSeek, Result};
use std::collections::HashSet;

/// The magic number of TIFF (Section 2, "Image File Header", bytes 2-3).
pub const MAGIC_TIFF: u16 = 42;
/// The magic number of BigTIFF (64-bit offsets; not part of TIFF 6.0, refused here).
pub const MAGIC_BIGTIFF: u16 = 43;
/// The magic number of a JPEG XR file read as a 16-bit little-endian number: the bytes 0xBC,
/// 0x01 after "II" (ITU-T T.832 Annex A, FIXED_FILE_HEADER_0XBC_BYTE and FILE_VERSION_ID 1).
pub const MAGIC_JPEG_XR: u16 = 0x01BC;
/// The same with version byte 0: HD Photo, JPEG XR's predecessor, which jxrlib also reads.
/// Big-endian ("MM") is allowed for neither; their readers check [`Tiff::order`].
pub const MAGIC_HD_PHOTO: u16 = 0x00BC;
/// Length of the image file header.
pub const HEADER_LEN: usize = 8;
/// Most IFDs [`Tiff::ifd_chain`] follows before giving up with [`Error::LimitExceeded`].
pub const MAX_IFDS: usize = 65536;
/// Length of one IFD entry (Section 2, "IFD Entry").
pub const ENTRY_LEN: u64 = 12;

/// Tag numbers of TIFF 6.0 fields that any TIFF-structured format may use. Format-specific
/// tags stay in their codec crates.
pub mod tag {
    /// NewSubfileType (Section 8).
    pub const NEW_SUBFILE_TYPE: u16 = 254;
    /// ImageWidth (Section 8).
    pub const IMAGE_WIDTH: u16 = 256;
    /// ImageLength, the height (Section 8).
    pub const IMAGE_LENGTH: u16 = 257;
    /// BitsPerSample (Section 8).
    pub const BITS_PER_SAMPLE: u16 = 258;
    /// Compression (Section 8; 1 = none).
    pub const COMPRESSION: u16 = 259;
    /// PhotometricInterpretation (Section 8).
    pub const PHOTOMETRIC_INTERPRETATION: u16 = 262;
    /// ImageDescription, ASCII (Section 8).
    pub const IMAGE_DESCRIPTION: u16 = 270;
    /// Make, ASCII (Section 8).
    pub const MAKE: u16 = 271;
    /// Model, ASCII (Section 8).
    pub const MODEL: u16 = 272;
    /// StripOffsets (Section 8; strips are described in Section 3).
    pub const STRIP_OFFSETS: u16 = 273;
    /// Orientation (Section 8).
    pub const ORIENTATION: u16 = 274;
    /// SamplesPerPixel (Section 8).
    pub const SAMPLES_PER_PIXEL: u16 = 277;
    /// RowsPerStrip (Section 8).
    pub const ROWS_PER_STRIP: u16 = 278;
    /// StripByteCounts (Section 8).
    pub const STRIP_BYTE_COUNTS: u16 = 279;
    /// XResolution, RATIONAL (Section 8).
    pub const X_RESOLUTION: u16 = 282;
    /// YResolution, RATIONAL (Section 8).
    pub const Y_RESOLUTION: u16 = 283;
    /// PlanarConfiguration (Section 8; 1 = chunky, 2 = planar).
    pub const PLANAR_CONFIGURATION: u16 = 284;
    /// ResolutionUnit (Section 8).
    pub const RESOLUTION_UNIT: u16 = 296;
    /// Software, ASCII (Section 8).
    pub const SOFTWARE: u16 = 305;
    /// DateTime, ASCII "YYYY:MM:DD HH:MM:SS" (Section 8).
    pub const DATE_TIME: u16 = 306;
    /// Artist, ASCII (Section 8).
    pub const ARTIST: u16 = 315;
    /// Predictor (Section 14).
    pub const PREDICTOR: u16 = 317;
    /// TileWidth (Section 15).
    pub const TILE_WIDTH: u16 = 322;
    /// TileLength (Section 15).
    pub const TILE_LENGTH: u16 = 323;
    /// TileOffsets (Section 15).
    pub const TILE_OFFSETS: u16 = 324;
    /// TileByteCounts (Section 15).
    pub const TILE_BYTE_COUNTS: u16 = 325;
    /// ExtraSamples (Section 8).
    pub const EXTRA_SAMPLES: u16 = 338;
    /// SampleFormat (Section 19; 1 = unsigned, 2 = signed, 3 = IEEE float).
    pub const SAMPLE_FORMAT: u16 = 339;
    /// Copyright, ASCII (Section 8).
    pub const COPYRIGHT: u16 = 33432;
}

/// The field types of TIFF 6.0 (Section 2, "Types"; 6-12 were added in 6.0).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FieldType {
    /// 8-bit unsigned integer.
    Byte = 1,
    /// 8-bit bytes holding 7-bit ASCII; each string ends with NUL.
    Ascii = 2,
    /// 16-bit unsigned integer.
    Short = 3,
    /// 32-bit unsigned integer.
    Long = 4,
    /// Two LONGs: numerator, denominator.
    Rational = 5,
    /// 8-bit two's-complement integer.
    SByte = 6,
    /// 8-bit bytes whose meaning the field defines.
    Undefined = 7,
    /// 16-bit two's-complement integer.
    SShort = 8,
    /// 32-bit two's-complement integer.
    SLong = 9,
    /// Two SLONGs: numerator, denominator.
    SRational = 10,
    /// IEEE single precision.
    Float = 11,
    /// IEEE double precision.
    Double = 12,
}

impl FieldType {
    /// The type with code `code`, or `None` for codes TIFF 6.0 does not define (readers skip
    /// such entries: Section 2, "Types").
    pub fn from_code(code: u16) -> Option<Self> {
        use FieldType::*;
        Some(match code {
            1 => Byte,
            2 => Ascii,
            3 => Short,
            4 => Long,
            5 => Rational,
            6 => SByte,
            7 => Undefined,
            8 => SShort,
            9 => SLong,
            10 => SRational,
            11 => Float,
            12 => Double,
            _ => return None,
        })
    }

    /// The code stored in an IFD entry.
    pub fn code(self) -> u16 {
        self as u16
    }

    /// Bytes of one value.
    pub fn size(self) -> u32 {
        use FieldType::*;
        match self {
            Byte | Ascii | SByte | Undefined => 1,
            Short | SShort => 2,
            Long | SLong | Float => 4,
            Rational | SRational | Double => 8,
        }
    }

    /// The name the specification uses ("SHORT").
    pub fn name(self) -> &'static str {
        use FieldType::*;
        match self {
            Byte => "BYTE",
            Ascii => "ASCII",
            Short => "SHORT",
            Long => "LONG",
            Rational => "RATIONAL",
            SByte => "SBYTE",
            Undefined => "UNDEFINED",
            SShort => "SSHORT",
            SLong => "SLONG",
            SRational => "SRATIONAL",
            Float => "FLOAT",
            Double => "DOUBLE",
        }
    }
}

/// A RATIONAL value (Section 2): numerator / denominator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rational {
    /// The numerator.
    pub num: u32,
    /// The denominator.
    pub den: u32,
}

impl Rational {
    /// The quotient (infinite or NaN when the denominator is 0).
    pub fn to_f64(self) -> f64 {
        f64::from(self.num) / f64::from(self.den)
    }
}

/// True if `head` starts with a header of the given magic number in either byte order
/// ("II" and the magic little-endian, or "MM" and the magic big-endian).
pub fn sniff(head: &[u8], magic: u16) -> bool {
    match head {
        [b'I', b'I', a, b, ..] => [*a, *b] == magic.to_le_bytes(),
        [b'M', b'M', a, b, ..] => [*a, *b] == magic.to_be_bytes(),
        _ => false,
    }
}

/// Where a [`Tiff`]'s bytes are: the whole file in memory, or the parts of it read from a
/// stream ([`TiffParts`]).
#[derive(Clone, Copy, Debug)]
enum Source<'a> {
    Bytes(&'a [u8]),
    Parts(&'a TiffParts),
}

impl<'a> Source<'a> {
    /// The file's length.
    fn len(&self) -> u64 {
        match self {
            Source::Bytes(b) => b.len() as u64,
            Source::Parts(p) => p.len,
        }
    }

    /// The `len` bytes at `at`: `Ok(None)` when they are not all inside the file, an error when
    /// they are but were not read into the parts (a reader that did not ask for them).
    fn get(&self, at: u64, len: u64) -> Result<Option<&'a [u8]>> {
        if at.checked_add(len).is_none_or(|end| end > self.len()) {
            return Ok(None);
        }
        match self {
            Source::Bytes(b) => Ok(Some(&b[at as usize..(at + len) as usize])),
            Source::Parts(p) => {
                let holds = |(from, bytes): &(&u64, &Vec<u8>)| **from <= at && at + len <= **from + bytes.len() as u64;
                // The part that starts last at or before `at`, else (parts that overlap) any.
                let part = p.parts.range(..=at).next_back().filter(holds).or_else(|| p.parts.iter().find(holds));
                part.map(|(from, bytes)| Some(&bytes[(at - from) as usize..(at - from + len) as usize])).ok_or_else(
                    || Error::invalid(format!("bytes {at}..{} of the TIFF file were not read from it", at + len)),
                )
            }
        }
    }

    /// [`get`](Self::get), with bytes outside the file [`Error::Truncated`] naming `what`.
    fn bytes(&self, at: u64, len: u64, what: &str) -> Result<&'a [u8]> {
        self.get(at, len)?.ok_or_else(|| {
            Error::truncated(format!("{what} (bytes {at}..{} of a {}-byte file)", at.saturating_add(len), self.len()))
        })
    }
}

/// The parts of a TIFF-structured file that describe its first image, read from a stream (a
/// file on disk) at their own offsets, so that [`Tiff::from_parts`] reads them as it reads a
/// file in memory without the file being held: the header, the first IFD, the entry count and
/// next-IFD offset of every further IFD of the chain, and the values (longer than 4 bytes, so
/// stored elsewhere) of the first IFD's tags that the reader asks for. Values of other tags,
/// and other IFDs' entries, are not read: asking a [`Tiff`] over the parts for them is an
/// error. What is held is bounded by the file and charged to the caller's [`Limits`].
#[derive(Debug)]
pub struct TiffParts {
    /// The file's length, from the stream's position at [`TiffParts::read`].
    len: u64,
    /// The bytes read, by their offset in the file (of two parts read at one offset, the
    /// longer is kept; a range is found in the part that starts last at or before it).
    parts: std::collections::BTreeMap<u64, Vec<u8>>,
    _charge: Option<Allocation>,
}

impl TiffParts {
    /// Reads the parts of the TIFF-structured file that starts at `input`'s position (see
    /// [`TiffParts`]), with header magic number `magic`; `wanted` says which tags' values to
    /// read (values that do not lie inside the file are not read: the [`Entry`] methods report
    /// them). Checks only what it must to know what to read: the chain of IFDs is checked when
    /// [`Tiff::ifd_chain`] walks it, as for a file in memory.
    pub fn read(input: &mut dyn ReadSeek, magic: u16, limits: &Limits, wanted: &dyn Fn(u16) -> bool) -> Result<Self> {
        let (base, len) = crate::remaining_len(input)?;
        let mut reading = Reading { input, base, limits, held: 0 };
        let mut parts = TiffParts { len, parts: Default::default(), _charge: None };
        parts.add(&mut reading, 0, (HEADER_LEN as u64).min(len))?;
        let (order, first) = {
            let t = Tiff::from_parts(&parts, magic)?;
            (t.order, u64::from(t.first_ifd))
        };
        let u16_at = |parts: &TiffParts, at: u64| -> Result<u16> {
            ByteReader::new(Source::Parts(parts).bytes(at, 2, "a TIFF IFD")?, order).u16("a TIFF IFD")
        };
        // The chain: the first IFD whole, of the others their entry count and next offset, as
        // far as they lie in the file and the walk of `ifd_chain` would go.
        let (mut next, mut seen) = (first, HashSet::new());
        while next != 0 && next.saturating_add(2) <= len && seen.insert(next) && seen.len() <= MAX_IFDS {
            parts.add(&mut reading, next, 2)?;
            let link = next + 2 + u64::from(u16_at(&parts, next)?) * ENTRY_LEN;
            if link.saturating_add(4) > len {
                break;
            }
            if next == first {
                parts.add(&mut reading, next, link + 4 - next)?;
            } else {
                parts.add(&mut reading, link, 4)?;
            }
            let b = Source::Parts(&parts).bytes(link, 4, "a TIFF IFD")?;
            next = u64::from(ByteReader::new(b, order).u32("a TIFF IFD")?);
        }
        if first == 0 || first.saturating_add(2) > len {
            return Ok(parts);
        }
        let Ok(ifd) = Tiff::from_parts(&parts, magic)?.read_ifd(first) else { return Ok(parts) };
        for e in ifd.entries {
            let (Some(at), Some(n)) = (e.values_at(), e.byte_len()) else { continue };
            if n > 4 && wanted(e.tag) && at.saturating_add(n) <= len {
                parts.add(&mut reading, at, n)?;
            }
        }
        Ok(parts)
    }

    /// The length of the file the parts come from.
    pub fn file_len(&self) -> u64 {
        self.len
    }

    /// Reads the `n` bytes at `at` (inside the file) as one more part, charged to the limits.
    fn add(&mut self, reading: &mut Reading<'_>, at: u64, n: u64) -> Result<()> {
        reading.held = reading.held.saturating_add(n);
        self._charge = None;
        self._charge = Some(reading.limits.charge(reading.held, "the TIFF's IFDs and tag values")?);
        let mut bytes = vec![0; usize::try_from(n).map_err(|_| Error::limit("a TIFF tag's values are too large"))?];
        crate::codec::read_exact_at(reading.input, reading.base + at, &mut bytes, "the TIFF file")?;
        if self.parts.get(&at).is_none_or(|b| b.len() < bytes.len()) {
            self.parts.insert(at, bytes);
        }
        Ok(())
    }
}

/// The stream [`TiffParts::read`] reads from and what it holds so far.
struct Reading<'r> {
    input: &'r mut dyn ReadSeek,
    base: u64,
    limits: &'r Limits,
    held: u64,
}

/// A parsed TIFF-structured file: its bytes (in memory or [`TiffParts`]), byte order and the
/// offset of its first IFD.
#[derive(Clone, Debug)]
pub struct Tiff<'a> {
    data: Source<'a>,
    order: ByteOrder,
    magic: u16,
    first_ifd: u32,
}

impl<'a> Tiff<'a> {
    /// Checks the image file header (Section 2): "II" (little-endian) or "MM" (big-endian),
    /// the magic number `magic` in that order, and reads the first IFD's offset.
    pub fn parse(data: &'a [u8], magic: u16) -> Result<Self> {
        Self::from_source(Source::Bytes(data), magic)
    }

    /// [`parse`](Self::parse) over the parts of a file read from a stream: the methods of the
    /// `Tiff` and of its [`Entry`]s read the parts as they read a file in memory, with the same
    /// checks and errors, except that bytes inside the file which were not read are an error.
    pub fn from_parts(parts: &'a TiffParts, magic: u16) -> Result<Self> {
        Self::from_source(Source::Parts(parts), magic)
    }

    fn from_source(src: Source<'a>, magic: u16) -> Result<Self> {
        let Some(data) = src.get(0, HEADER_LEN as u64)? else {
            return Err(Error::truncated("the 8-byte TIFF header"));
        };
        let order = match &data[..2] {
            b"II" => ByteOrder::Little,
            b"MM" => ByteOrder::Big,
            _ => return Err(Error::invalid("not a TIFF file (no II or MM byte-order mark)")),
        };
        let mut r = ByteReader::new(data, order).at(2);
        match r.u16("the TIFF header")? {
            m if m == magic => {}
            MAGIC_BIGTIFF if magic == MAGIC_TIFF => {
                return Err(Error::unsupported("BigTIFF files (only classic TIFF is read here)"))
            }
            m if magic == MAGIC_TIFF => {
                return Err(Error::invalid(format!("not a TIFF file (magic number {m}, expected 42)")))
            }
            m => {
                return Err(Error::invalid(format!(
                    "wrong magic number {m:#06x} in the TIFF-structured header (expected {magic:#06x})"
                )))
            }
        }
        let first_ifd = r.u32("the TIFF header")?;
        Ok(Tiff { data: src, order, magic, first_ifd })
    }

    /// A region laid out as TIFF but without the image file header, in byte order `order`,
    /// whose offsets count from its own start: an EXIF maker note such as Apple's (its IFD
    /// offset is the caller's to know; [`first_ifd_offset`](Self::first_ifd_offset) is 0).
    pub fn without_header(data: &'a [u8], order: ByteOrder) -> Self {
        Tiff { data: Source::Bytes(data), order, magic: 0, first_ifd: 0 }
    }

    /// The length of the file.
    pub fn file_len(&self) -> u64 {
        self.data.len()
    }

    /// The byte order of the file.
    pub fn order(&self) -> ByteOrder {
        self.order
    }

    /// The magic number the file was parsed with.
    pub fn magic(&self) -> u16 {
        self.magic
    }

    /// The offset of the first IFD (0: the file has none).
    pub fn first_ifd_offset(&self) -> u32 {
        self.first_ifd
    }

    /// The IFDs of the file in chain order, located but not read. The walk stops after the
    /// first error: an offset seen before (a loop, which TIFF 6.0 does not allow but never
    /// says), more than [`MAX_IFDS`] IFDs, or an IFD that does not fit in the file.
    pub fn ifd_chain(&self) -> IfdChain<'a> {
        IfdChain {
            data: self.data,
            order: self.order,
            next: u64::from(self.first_ifd),
            index: 0,
            seen: HashSet::new(),
            done: false,
        }
    }

    /// The first IFD, read; an error if the file has none.
    pub fn first_ifd(&self) -> Result<Ifd> {
        match self.ifd_chain().next() {
            Some(loc) => self.read_ifd(loc?.offset),
            None => Err(Error::invalid("the TIFF file has no image (first IFD offset is 0)")),
        }
    }

    /// Reads the IFD at `offset`: its entries in file order and the next IFD's offset. The
    /// entries are checked to fit in the file (at most 65535 of 12 bytes each, so what this
    /// allocates is bounded by the file); their values are not read.
    pub fn read_ifd(&self, offset: u64) -> Result<Ifd> {
        let what = format!("the TIFF IFD at offset {offset}");
        let n = ByteReader::new(self.data.bytes(offset, 2, &what)?, self.order).u16(&what)?;
        let len = 2 + u64::from(n) * ENTRY_LEN + 4;
        let mut r = ByteReader::new(self.data.bytes(offset, len, &what)?, self.order).at(2);
        let mut entries = Vec::with_capacity(usize::from(n));
        for _ in 0..n {
            let tag = r.u16(&what)?;
            let typ = r.u16(&what)?;
            let count = r.u32(&what)?;
            let field_at = offset + r.position();
            let value_field = r.u32(&what)?;
            entries.push(Entry { tag, typ, count, value_field, field_at });
        }
        let next = r.u32(&what)?;
        Ok(Ifd { offset, entries, next })
    }
}

/// Where an IFD is, as found by [`Tiff::ifd_chain`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IfdLocation {
    /// Position in the chain, 0 for the first IFD.
    pub index: usize,
    /// Offset of the IFD in the file.
    pub offset: u64,
    /// Number of entries.
    pub entry_count: u16,
    /// Offset of the next IFD (0 after the last).
    pub next: u32,
}

/// The iterator of [`Tiff::ifd_chain`]. Each step is O(1): it reads the entry count, checks
/// that the entries and the next offset fit in the file and reads the next offset.
#[derive(Clone, Debug)]
pub struct IfdChain<'a> {
    data: Source<'a>,
    order: ByteOrder,
    next: u64,
    index: usize,
    seen: HashSet<u64>,
    done: bool,
}

impl IfdChain<'_> {
    fn locate(&mut self, offset: u64) -> Result<IfdLocation> {
        if !self.seen.insert(offset) {
            return Err(Error::invalid(format!("the TIFF IFD chain loops back to offset {offset}")));
        }
        if self.seen.len() > MAX_IFDS {
            return Err(Error::limit(format!("more than {MAX_IFDS} TIFF IFDs")));
        }
        let what = format!("TIFF IFD {} at offset {offset}", self.index);
        let entry_count = ByteReader::new(self.data.bytes(offset, 2, &what)?, self.order).u16(&what)?;
        let entries = u64::from(entry_count) * ENTRY_LEN;
        if offset.saturating_add(2 + entries + 4) > self.data.len() {
            return Err(Error::truncated(format!(
                "{what} ({} entries and the next offset, past the end of a {}-byte file)",
                entry_count,
                self.data.len()
            )));
        }
        let next = ByteReader::new(self.data.bytes(offset + 2 + entries, 4, &what)?, self.order).u32(&what)?;
        Ok(IfdLocation { index: self.index, offset, entry_count, next })
    }
}

impl Iterator for IfdChain<'_> {
    type Item = Result<IfdLocation>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done || self.next == 0 {
            return None;
        }
        let loc = self.locate(self.next);
        match &loc {
            Ok(l) => {
                self.next = u64::from(l.next);
                self.index += 1;
            }
            Err(_) => self.done = true,
        }
        Some(loc)
    }
}

/// One image file directory: its entries in file order (Section 2 requires ascending tags;
/// this reader does not insist) and the offset of the next IFD.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Ifd {
    /// Offset of the IFD in the file.
    pub offset: u64,
    /// The entries, in file order, including those of unknown field types.
    pub entries: Vec<Entry>,
    /// Offset of the next IFD (0 after the last).
    pub next: u32,
}

impl Ifd {
    /// The first entry with tag `tag` and a field type TIFF 6.0 defines (entries of other
    /// types are skipped, as Section 2 "Types" asks of readers).
    pub fn get(&self, tag: u16) -> Option<&Entry> {
        self.entries.iter().find(|e| e.tag == tag && e.field_type().is_some())
    }
}

/// One IFD entry (Section 2, "IFD Entry"). The value methods read the entry's values from the
/// file they came from, passed as `tiff`; each checks the field type and that the values lie
/// inside the file, and those that allocate check the size against the [`Limits`] first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry {
    /// The tag.
    pub tag: u16,
    /// The field type code (see [`FieldType`]).
    pub typ: u16,
    /// The number of values (not bytes).
    pub count: u32,
    /// The 4-byte Value Offset field, read in the file's byte order: the offset of the values,
    /// or the values themselves when they fit in 4 bytes.
    pub value_field: u32,
    /// The offset in the file of the Value Offset field.
    pub field_at: u64,
}

/// The values of a SHORT or LONG entry as `u32`s, decoded as they are iterated (see
/// [`Entry::uints`]).
#[derive(Clone, Debug)]
pub struct Uints<'a> {
    reader: ByteReader<'a>,
    long: bool,
    left: u32,
}

impl Iterator for Uints<'_> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        self.left = self.left.checked_sub(1)?;
        // The bytes were checked when the iterator was made; a failure here cannot happen.
        if self.long {
            self.reader.u32("").ok()
        } else {
            self.reader.u16("").ok().map(u32::from)
        }
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.left as usize;
        (n, Some(n))
    }
}

impl ExactSizeIterator for Uints<'_> {}

impl Entry {
    /// The field type, `None` for a code TIFF 6.0 does not define.
    pub fn field_type(&self) -> Option<FieldType> {
        FieldType::from_code(self.typ)
    }

    /// Bytes of all the values (at most 2^35, so it cannot overflow); `None` for an unknown type.
    pub fn byte_len(&self) -> Option<u64> {
        self.field_type().map(|t| u64::from(t.size()) * u64::from(self.count))
    }

    /// Where the values start in the file: in the entry itself when they fit in 4 bytes,
    /// else at the offset the entry holds (Section 2, "Value Offset"). `None` for an unknown type.
    pub fn values_at(&self) -> Option<u64> {
        let len = self.byte_len()?;
        Some(if len <= 4 { self.field_at } else { u64::from(self.value_field) })
    }

    /// The bytes of the values, checked to lie inside the file (no allocation).
    pub fn value_bytes<'a>(&self, tiff: &Tiff<'a>) -> Result<&'a [u8]> {
        let (Some(at), Some(len)) = (self.values_at(), self.byte_len()) else {
            return Err(Error::unsupported(format!("TIFF tag {} has unknown field type {}", self.tag, self.typ)));
        };
        tiff.data.get(at, len)?.ok_or_else(|| {
            Error::truncated(format!(
                "the values of TIFF tag {} ({len} bytes at offset {at}, file of {} bytes)",
                self.tag,
                tiff.data.len()
            ))
        })
    }

    /// Checks the type is one of `types` and returns a reader over the values.
    fn values<'a>(&self, tiff: &Tiff<'a>, types: &[FieldType]) -> Result<ByteReader<'a>> {
        match self.field_type() {
            Some(t) if types.contains(&t) => Ok(ByteReader::new(self.value_bytes(tiff)?, tiff.order)),
            _ => {
                let names: Vec<_> = types.iter().map(|t| t.name()).collect();
                Err(Error::invalid(format!(
                    "TIFF tag {} has type {}, expected {}",
                    self.tag,
                    self.typ,
                    names.join(" or ")
                )))
            }
        }
    }

    /// Checks that a vector of `count` items of `T` is within the limits.
    fn check_alloc<T>(&self, limits: &Limits) -> Result<()> {
        let bytes = u64::from(self.count) * std::mem::size_of::<T>() as u64;
        limits.check_alloc(bytes, &format!("the values of TIFF tag {}", self.tag))
    }

    /// The values of a SHORT or LONG entry as `u32`s, decoded lazily: nothing is allocated,
    /// so a caller that needs only some of them (`.take(n)`) pays only for those.
    pub fn uints<'a>(&self, tiff: &Tiff<'a>) -> Result<Uints<'a>> {
        let reader = self.values(tiff, &[FieldType::Short, FieldType::Long])?;
        Ok(Uints { reader, long: self.typ == FieldType::Long.code(), left: self.count })
    }

    /// The first value of a SHORT or LONG entry; an error if it has none.
    pub fn first_u32(&self, tiff: &Tiff) -> Result<u32> {
        self.uints(tiff)?.next().ok_or_else(|| Error::invalid(format!("TIFF tag {} has no value", self.tag)))
    }

    /// The values of a SHORT entry.
    pub fn u16s(&self, tiff: &Tiff, limits: &Limits) -> Result<Vec<u16>> {
        let mut r = self.values(tiff, &[FieldType::Short])?;
        self.check_alloc::<u16>(limits)?;
        (0..self.count).map(|_| r.u16("")).collect()
    }

    /// The values of a SHORT or LONG entry as `u32`s.
    pub fn u32s(&self, tiff: &Tiff, limits: &Limits) -> Result<Vec<u32>> {
        let values = self.uints(tiff)?;
        self.check_alloc::<u32>(limits)?;
        Ok(values.collect())
    }

    /// The values of a SHORT or LONG entry as `u64`s (convenient for offsets and sizes).
    pub fn u64s(&self, tiff: &Tiff, limits: &Limits) -> Result<Vec<u64>> {
        let values = self.uints(tiff)?;
        self.check_alloc::<u64>(limits)?;
        Ok(values.map(u64::from).collect())
    }

    /// The values of a RATIONAL entry.
    pub fn rationals(&self, tiff: &Tiff, limits: &Limits) -> Result<Vec<Rational>> {
        let mut r = self.values(tiff, &[FieldType::Rational])?;
        self.check_alloc::<Rational>(limits)?;
        (0..self.count).map(|_| Ok(Rational { num: r.u32("")?, den: r.u32("")? })).collect()
    }

    /// The values of a FLOAT or DOUBLE entry as `f64`s.
    pub fn f64s(&self, tiff: &Tiff, limits: &Limits) -> Result<Vec<f64>> {
        let mut r = self.values(tiff, &[FieldType::Float, FieldType::Double])?;
        self.check_alloc::<f64>(limits)?;
        let double = self.typ == FieldType::Double.code();
        (0..self.count).map(|_| if double { r.f64("") } else { r.f32("").map(f64::from) }).collect()
    }

    /// The first value of a FLOAT or DOUBLE entry; an error if it has none.
    pub fn first_f64(&self, tiff: &Tiff) -> Result<f64> {
        let mut r = self.values(tiff, &[FieldType::Float, FieldType::Double])?;
        if self.count == 0 {
            return Err(Error::invalid(format!("TIFF tag {} has no value", self.tag)));
        }
        if self.typ == FieldType::Double.code() {
            r.f64("")
        } else {
            r.f32("").map(f64::from)
        }
    }

    /// The first value of a RATIONAL, SRATIONAL, FLOAT or DOUBLE entry as an `f64`; an error if
    /// it has none or a rational's denominator is 0.
    pub fn first_real(&self, tiff: &Tiff) -> Result<f64> {
        use FieldType::*;
        let mut r = self.values(tiff, &[Rational, SRational, Float, Double])?;
        if self.count == 0 {
            return Err(Error::invalid(format!("TIFF tag {} has no value", self.tag)));
        }
        let (num, den) = match self.field_type() {
            Some(Rational) => (f64::from(r.u32("")?), f64::from(r.u32("")?)),
            Some(SRational) => (f64::from(r.i32("")?), f64::from(r.i32("")?)),
            Some(Double) => return r.f64(""),
            _ => return r.f32("").map(f64::from),
        };
        if den == 0.0 {
            return Err(Error::invalid(format!("TIFF tag {}: a rational with denominator 0", self.tag)));
        }
        Ok(num / den)
    }

    /// The first string of an ASCII entry: the bytes up to the first NUL (or all of them if the
    /// writer forgot the NUL Section 2 requires), non-ASCII bytes replaced by U+FFFD.
    pub fn ascii(&self, tiff: &Tiff, limits: &Limits) -> Result<String> {
        let b = self.values(tiff, &[FieldType::Ascii])?.rest();
        let s = b.split(|&c| c == 0).next().unwrap_or_default();
        // Each replaced byte may take 3 bytes of UTF-8.
        limits.check_alloc(3 * s.len() as u64, &format!("the string of TIFF tag {}", self.tag))?;
        Ok(s.iter().map(|&c| if c.is_ascii() { char::from(c) } else { char::REPLACEMENT_CHARACTER }).collect())
    }
}

/// Writes an image file header (Section 2) in `w`'s byte order with the magic number `magic`
/// and a first-IFD offset of 0, and returns the position of that offset, for
/// [`IfdWriter::write`] to fill in.
pub fn write_header(w: &mut ByteWriter, magic: u16) -> usize {
    w.bytes(match w.order() {
        ByteOrder::Little => b"II",
        ByteOrder::Big => b"MM",
    });
    w.u16(magic);
    let link = w.len();
    w.u32(0);
    link
}

/// The values of one entry of an [`IfdWriter`], in units of the type's components.
#[derive(Clone, Debug)]
enum Values {
    Bytes(Vec<u8>),
    U16(Vec<u16>),
    U32(Vec<u32>),
    U64(Vec<u64>),
}

#[derive(Clone, Debug)]
struct WriterEntry {
    tag: u16,
    typ: FieldType,
    count: u64,
    values: Values,
}

impl WriterEntry {
    fn byte_len(&self) -> u64 {
        self.count * u64::from(self.typ.size())
    }
    /// Bytes the values take after the IFD: none when inline, else padded to a word boundary.
    fn out_of_line_len(&self) -> u64 {
        match self.byte_len() {
            n if n <= 4 => 0,
            n => n + n % 2,
        }
    }
}

/// Builds one IFD and writes it (Section 2): entries sorted by tag whatever order they were
/// added in (adding a tag again replaces its value), values of at most 4 bytes in the entry,
/// left-justified, the others after the IFD, each starting on a word boundary.
#[derive(Clone, Debug, Default)]
pub struct IfdWriter {
    entries: Vec<WriterEntry>,
}

impl IfdWriter {
    /// An IFD without entries.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True if no entry was added.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn set(&mut self, tag: u16, typ: FieldType, count: usize, values: Values) {
        let e = WriterEntry { tag, typ, count: count as u64, values };
        match self.entries.binary_search_by_key(&tag, |e| e.tag) {
            Ok(i) => self.entries[i] = e,
            Err(i) => self.entries.insert(i, e),
        }
    }

    /// Sets a BYTE entry.
    pub fn bytes(&mut self, tag: u16, v: &[u8]) {
        self.set(tag, FieldType::Byte, v.len(), Values::Bytes(v.to_vec()));
    }

    /// Sets an UNDEFINED entry.
    pub fn undefined(&mut self, tag: u16, v: &[u8]) {
        self.set(tag, FieldType::Undefined, v.len(), Values::Bytes(v.to_vec()));
    }

    /// Sets an ASCII entry: the bytes of `s` and a NUL (the count includes it). `s` should be
    /// 7-bit ASCII without NULs; the bytes are written as given.
    pub fn ascii(&mut self, tag: u16, s: &str) {
        let mut v = s.as_bytes().to_vec();
        v.push(0);
        self.set(tag, FieldType::Ascii, v.len(), Values::Bytes(v));
    }

    /// Sets a SHORT entry.
    pub fn shorts(&mut self, tag: u16, v: &[u16]) {
        self.set(tag, FieldType::Short, v.len(), Values::U16(v.to_vec()));
    }

    /// Sets a SHORT entry of one value.
    pub fn short(&mut self, tag: u16, v: u16) {
        self.shorts(tag, &[v]);
    }

    /// Sets a LONG entry.
    pub fn longs(&mut self, tag: u16, v: &[u32]) {
        self.set(tag, FieldType::Long, v.len(), Values::U32(v.to_vec()));
    }

    /// Sets a LONG entry of one value.
    pub fn long(&mut self, tag: u16, v: u32) {
        self.longs(tag, &[v]);
    }

    /// Sets a RATIONAL entry.
    pub fn rationals(&mut self, tag: u16, v: &[Rational]) {
        let words = v.iter().flat_map(|r| [r.num, r.den]).collect();
        self.set(tag, FieldType::Rational, v.len(), Values::U32(words));
    }

    /// Sets a FLOAT entry.
    pub fn floats(&mut self, tag: u16, v: &[f32]) {
        self.set(tag, FieldType::Float, v.len(), Values::U32(v.iter().map(|x| x.to_bits()).collect()));
    }

    /// Sets a DOUBLE entry.
    pub fn doubles(&mut self, tag: u16, v: &[f64]) {
        self.set(tag, FieldType::Double, v.len(), Values::U64(v.iter().map(|x| x.to_bits()).collect()));
    }

    /// Sets a DOUBLE entry of one value.
    pub fn double(&mut self, tag: u16, v: f64) {
        self.doubles(tag, &[v]);
    }

    /// Bytes [`write`](Self::write) appends after its alignment byte, if any: the IFD and the
    /// out-of-line values.
    pub fn size(&self) -> u64 {
        let n = self.entries.len() as u64;
        2 + ENTRY_LEN * n + 4 + self.entries.iter().map(WriterEntry::out_of_line_len).sum::<u64>()
    }

    /// Appends the IFD to `w` at the next word boundary, then the values that do not fit in
    /// their entries, and stores the IFD's offset at `link_at` (the header's first-IFD offset
    /// from [`write_header`], or the previous IFD's next-IFD offset). Returns the position of
    /// this IFD's next-IFD offset (written as 0), to link a following IFD.
    ///
    /// Errors if the file would outgrow 32-bit offsets, an entry has more than 2^32-1 values,
    /// there are more than 65535 entries, or `link_at` is not inside `w`.
    pub fn write(&self, w: &mut ByteWriter, link_at: usize) -> Result<usize> {
        let (ifd, next) = self.emit(w, 0)?;
        w.patch_u32(link_at, ifd as u32)?;
        Ok(next)
    }

    /// The bytes of this IFD in byte order `order` (from a word-alignment byte if needed, then
    /// the entries and the values that do not fit in them) for a file whose first `file_len`
    /// bytes are already
    /// written elsewhere (streamed): append them, then store the returned IFD offset at the
    /// link (the header's first-IFD offset). The IFD's next-IFD offset is 0.
    pub fn bytes_after(&self, order: ByteOrder, file_len: u64) -> Result<(Vec<u8>, u64)> {
        let mut w = ByteWriter::new(order);
        let (ifd, _) = self.emit(&mut w, file_len)?;
        Ok((w.into_vec(), ifd))
    }

    /// Appends the IFD to `w`, whose first byte lies at file offset `base`; returns the IFD's
    /// offset in the file and the position in `w` of its next-IFD offset.
    fn emit(&self, w: &mut ByteWriter, base: u64) -> Result<(u64, usize)> {
        if self.entries.len() > usize::from(u16::MAX) {
            return Err(Error::invalid(format!("{} entries in one TIFF IFD (at most 65535)", self.entries.len())));
        }
        if let Some(e) = self.entries.iter().find(|e| e.count > u64::from(u32::MAX)) {
            return Err(Error::invalid(format!("{} values in TIFF tag {} (at most 2^32-1)", e.count, e.tag)));
        }
        if (base + w.len() as u64) % 2 == 1 {
            w.u8(0);
        }
        let ifd = base + w.len() as u64;
        let end = ifd + self.size();
        if end > u64::from(u32::MAX) {
            return Err(Error::limit(format!(
                "the TIFF file would reach {end} bytes; classic TIFF offsets are 32-bit"
            )));
        }
        w.u16(self.entries.len() as u16);
        let mut extra = ifd + 2 + ENTRY_LEN * self.entries.len() as u64 + 4;
        for e in &self.entries {
            w.u16(e.tag);
            w.u16(e.typ.code());
            w.u32(e.count as u32);
            if e.byte_len() <= 4 {
                let start = w.len();
                write_values(w, &e.values);
                w.zeros(4 - (w.len() - start));
            } else {
                w.u32(extra as u32);
                extra += e.out_of_line_len();
            }
        }
        let next = w.len();
        w.u32(0);
        for e in self.entries.iter().filter(|e| e.byte_len() > 4) {
            write_values(w, &e.values);
            if (base + w.len() as u64) % 2 == 1 {
                w.u8(0);
            }
        }
        debug_assert_eq!(base + w.len() as u64, end);
        Ok((ifd, next))
    }
}

fn write_values(w: &mut ByteWriter, v: &Values) {
    match v {
        Values::Bytes(b) => w.bytes(b),
        Values::U16(v) => v.iter().for_each(|&x| w.u16(x)),
        Values::U32(v) => v.iter().for_each(|&x| w.u32(x)),
        Values::U64(v) => v.iter().for_each(|&x| w.u64(x)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of two IFDs in byte order `order`, with values inline and out of line.
    fn two_ifds(order: ByteOrder, magic: u16) -> Vec<u8> {
        let mut w = ByteWriter::new(order);
        let link = write_header(&mut w, magic);
        w.bytes(b"pixels!"); // odd length: the IFD must be word-aligned after it
        let mut a = IfdWriter::new();
        // Added out of order; written sorted.
        a.doubles(40000, &[179.0]);
        a.long(tag::IMAGE_LENGTH, 5);
        a.long(tag::IMAGE_WIDTH, 7);
        a.shorts(tag::BITS_PER_SAMPLE, &[16, 16, 16]);
        a.short(tag::COMPRESSION, 1);
        a.longs(tag::STRIP_OFFSETS, &[8, 9]);
        a.ascii(tag::SOFTWARE, "hdrcodec");
        a.ascii(tag::ARTIST, "abc");
        a.rationals(tag::X_RESOLUTION, &[Rational { num: 72, den: 1 }]);
        a.floats(40001, &[0.5, 2.0]);
        a.bytes(40002, &[1, 2, 3, 4, 5]);
        a.undefined(40003, &[9]);
        a.short(tag::COMPRESSION, 32773); // replaces the first value
        assert_eq!(a.len(), 12);
        let next = a.write(&mut w, link).unwrap();
        let mut b = IfdWriter::new();
        b.long(tag::NEW_SUBFILE_TYPE, 1);
        b.write(&mut w, next).unwrap();
        w.into_vec()
    }

    #[test]
    fn reals_of_a_headerless_region() {
        // A maker-note-like region: a prefix, then an IFD whose offsets count from the start.
        let mut w = ByteWriter::new(ByteOrder::Big);
        w.bytes(b"Maker\0");
        let ifd_at = w.len() as u32;
        w.u16(4);
        for (tag, typ, at) in [(33u16, 10u16, 60u32), (48, 5, 68), (50, 11, 0), (51, 10, 76)] {
            w.u16(tag);
            w.u16(typ);
            w.u32(1);
            w.u32(if typ == 11 { 0.25f32.to_bits() } else { at });
        }
        w.u32(0);
        w.zeros(60 - w.len());
        for v in [-3i32, 2, 1, 4, 7, 0] {
            w.i32(v);
        }
        let data = w.into_vec();
        let tiff = Tiff::without_header(&data, ByteOrder::Big);
        let ifd = tiff.read_ifd(u64::from(ifd_at)).unwrap();
        let real = |tag| ifd.get(tag).unwrap().first_real(&tiff);
        assert_eq!(real(33).unwrap(), -1.5);
        assert_eq!(real(48).unwrap(), 0.25);
        assert_eq!(real(50).unwrap(), 0.25);
        assert!(real(51).unwrap_err().to_string().contains("denominator 0"));
    }

    #[test]
    fn writer_then_reader_round_trip_in_both_byte_orders() {
        let l = Limits::default();
        for (order, magic) in
            [(ByteOrder::Little, MAGIC_TIFF), (ByteOrder::Big, MAGIC_TIFF), (ByteOrder::Little, MAGIC_JPEG_XR)]
        {
            let file = two_ifds(order, magic);
            assert!(sniff(&file, magic));
            assert!(!sniff(&file, magic + 1));
            let t = Tiff::parse(&file, magic).unwrap();
            assert_eq!((t.order(), t.magic(), t.first_ifd_offset()), (order, magic, 16));
            let locs: Vec<_> = t.ifd_chain().collect::<Result<_>>().unwrap();
            assert_eq!(locs.len(), 2);
            assert_eq!((locs[0].entry_count, locs[1].entry_count, locs[1].next), (12, 1, 0));
            let ifd = t.first_ifd().unwrap();
            assert_eq!(ifd.next as u64, locs[1].offset);
            assert_eq!(locs[1].offset % 2, 0);
            let tags: Vec<u16> = ifd.entries.iter().map(|e| e.tag).collect();
            assert!(tags.windows(2).all(|w| w[0] < w[1]), "{tags:?}");
            let get = |tag| ifd.get(tag).unwrap();
            assert_eq!(get(tag::IMAGE_WIDTH).first_u32(&t).unwrap(), 7);
            assert_eq!(get(tag::IMAGE_LENGTH).u64s(&t, &l).unwrap(), [5]);
            assert_eq!(get(tag::BITS_PER_SAMPLE).u16s(&t, &l).unwrap(), [16, 16, 16]);
            assert_eq!(get(tag::BITS_PER_SAMPLE).u32s(&t, &l).unwrap(), [16, 16, 16]);
            assert_eq!(get(tag::COMPRESSION).first_u32(&t).unwrap(), 32773);
            assert_eq!(get(tag::STRIP_OFFSETS).uints(&t).unwrap().collect::<Vec<_>>(), [8, 9]);
            assert_eq!(get(tag::SOFTWARE).ascii(&t, &l).unwrap(), "hdrcodec");
            assert_eq!(get(tag::ARTIST).ascii(&t, &l).unwrap(), "abc");
            assert_eq!(get(tag::ARTIST).values_at(), Some(get(tag::ARTIST).field_at), "4 bytes are inline");
            assert_eq!(get(tag::X_RESOLUTION).rationals(&t, &l).unwrap()[0].to_f64(), 72.0);
            assert_eq!(get(40000).first_f64(&t).unwrap(), 179.0);
            assert_eq!(get(40001).f64s(&t, &l).unwrap(), [0.5, 2.0]);
            assert_eq!(get(40002).value_bytes(&t).unwrap(), [1, 2, 3, 4, 5]);
            assert_eq!(get(40003).value_bytes(&t).unwrap(), [9]);
            // Out-of-line values start on word boundaries.
            for e in &ifd.entries {
                assert_eq!(e.values_at().unwrap() % 2, 0, "tag {}", e.tag);
            }
            // Wrong types are errors naming the tag.
            let e = get(tag::SOFTWARE).u32s(&t, &l).unwrap_err().to_string();
            assert!(e.contains("TIFF tag 305 has type 2, expected SHORT or LONG"), "{e}");
            assert!(get(tag::IMAGE_WIDTH).u16s(&t, &l).is_err());
            assert!(get(tag::IMAGE_WIDTH).f64s(&t, &l).is_err());
            let second = t.read_ifd(locs[1].offset).unwrap();
            assert_eq!(second.get(tag::NEW_SUBFILE_TYPE).unwrap().first_u32(&t).unwrap(), 1);
        }
    }

    #[test]
    fn exact_bytes_of_a_small_ifd() {
        let mut w = ByteWriter::new(ByteOrder::Little);
        let link = write_header(&mut w, MAGIC_TIFF);
        w.u8(0xaa);
        let mut ifd = IfdWriter::new();
        ifd.shorts(tag::BITS_PER_SAMPLE, &[8, 8, 8]);
        ifd.short(tag::COMPRESSION, 1);
        assert_eq!(ifd.size(), 2 + 24 + 4 + 6);
        let next = ifd.write(&mut w, link).unwrap();
        assert_eq!(next, 10 + 2 + 24);
        #[rustfmt::skip]
        let want = [
            b'I', b'I', 42, 0, 10, 0, 0, 0, 0xaa, 0, // header, 1 byte, alignment
            2, 0,
            2, 1, 3, 0, 3, 0, 0, 0, 40, 0, 0, 0, // BitsPerSample SHORT x3 at 40
            3, 1, 3, 0, 1, 0, 0, 0, 1, 0, 0, 0, // Compression SHORT 1, left-justified
            0, 0, 0, 0, // no next IFD
            8, 0, 8, 0, 8, 0,
        ];
        assert_eq!(w.as_slice(), want);
    }

    #[test]
    fn headers() {
        assert!(matches!(Tiff::parse(b"II*\0\x08\0\0", MAGIC_TIFF), Err(Error::Truncated { .. })));
        assert!(matches!(Tiff::parse(b"XX*\0\x08\0\0\0", MAGIC_TIFF), Err(Error::Invalid { .. })));
        assert!(matches!(Tiff::parse(b"II+\0\x08\0\0\0", MAGIC_TIFF), Err(Error::Unsupported { .. })));
        assert!(matches!(Tiff::parse(b"MM*\0\x08\0\0\0", MAGIC_TIFF), Err(Error::Invalid { .. })));
        assert!(matches!(Tiff::parse(b"II*\0\x08\0\0\0", MAGIC_JPEG_XR), Err(Error::Invalid { .. })));
        assert!(matches!(Tiff::parse(b"II\xbc\x00\x08\0\0\0", MAGIC_JPEG_XR), Err(Error::Invalid { .. })));
        assert!(Tiff::parse(b"II\xbc\x00\x08\0\0\0", MAGIC_HD_PHOTO).is_ok());
        let t = Tiff::parse(b"II\xbc\x01\x08\0\0\0", MAGIC_JPEG_XR).unwrap();
        assert_eq!(t.first_ifd_offset(), 8);
        let t = Tiff::parse(b"MM\0*\0\0\0\x08", MAGIC_TIFF).unwrap();
        assert_eq!((t.order(), t.first_ifd_offset()), (ByteOrder::Big, 8));
        // The IFD itself is missing.
        assert!(matches!(t.first_ifd(), Err(Error::Truncated { .. })));
        let t = Tiff::parse(b"II*\0\0\0\0\0", MAGIC_TIFF).unwrap();
        assert!(t.ifd_chain().next().is_none());
        assert!(matches!(t.first_ifd(), Err(Error::Invalid { .. })));
        assert!(sniff(b"II*\0", MAGIC_TIFF) && sniff(b"MM\0*", MAGIC_TIFF) && sniff(b"II\xbc\x01", MAGIC_JPEG_XR));
        assert!(!sniff(b"II*", MAGIC_TIFF) && !sniff(b"MM*\0", MAGIC_TIFF));
    }

    fn next_ifd_at(t: &Tiff, index: usize) -> usize {
        let loc = t.ifd_chain().nth(index).unwrap().unwrap();
        (loc.offset + 2 + 12 * u64::from(loc.entry_count)) as usize
    }

    #[test]
    fn loops_in_the_chain_are_errors() {
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let file = two_ifds(order, MAGIC_TIFF);
            let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
            let first = t.first_ifd_offset();
            let second_next = next_ifd_at(&t, 1);
            for target in [first, t.first_ifd().unwrap().next] {
                let mut f = file.clone();
                let b = match order {
                    ByteOrder::Little => target.to_le_bytes(),
                    ByteOrder::Big => target.to_be_bytes(),
                };
                f[second_next..second_next + 4].copy_from_slice(&b);
                let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
                let results: Vec<_> = t.ifd_chain().collect();
                assert_eq!(results.len(), 3, "two IFDs, then the error, then nothing");
                let e = results[2].as_ref().unwrap_err();
                assert!(matches!(e, Error::Invalid { .. }) && e.to_string().contains("loops"), "{e}");
            }
        }
        // An IFD whose next offset is itself.
        let mut w = ByteWriter::new(ByteOrder::Little);
        let link = write_header(&mut w, MAGIC_TIFF);
        let next = IfdWriter::new().write(&mut w, link).unwrap();
        w.patch_u32(next, 8).unwrap();
        let f = w.into_vec();
        let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
        assert!(t.ifd_chain().any(|r| r.is_err()));
    }

    #[test]
    fn too_many_ifds_is_a_limit() {
        // MAX_IFDS + 1 empty IFDs of 6 bytes each, chained.
        let mut w = ByteWriter::new(ByteOrder::Little);
        let mut link = write_header(&mut w, MAGIC_TIFF);
        for _ in 0..=MAX_IFDS {
            link = IfdWriter::new().write(&mut w, link).unwrap();
        }
        let f = w.into_vec();
        let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
        let last = t.ifd_chain().last().unwrap();
        assert!(matches!(last, Err(Error::LimitExceeded { .. })), "{last:?}");
    }

    #[test]
    fn counts_past_the_end_or_overflowing_are_errors_before_allocating() {
        let l = Limits::default();
        let file = two_ifds(ByteOrder::Little, MAGIC_TIFF);
        let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
        let ifd = t.first_ifd().unwrap();
        for (tag, new_count) in [(tag::STRIP_OFFSETS, u32::MAX), (tag::BITS_PER_SAMPLE, 1 << 30), (tag::SOFTWARE, 100)]
        {
            let e = ifd.get(tag).unwrap();
            let mut f = file.clone();
            let at = e.field_at as usize - 4;
            f[at..at + 4].copy_from_slice(&new_count.to_le_bytes());
            let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
            let ifd = t.first_ifd().unwrap();
            let e = ifd.get(tag).unwrap();
            assert!(matches!(e.value_bytes(&t), Err(Error::Truncated { .. })));
            assert!(matches!(e.uints(&t), Err(Error::Truncated { .. }) | Err(Error::Invalid { .. })));
            assert!(e.u32s(&t, &l).is_err() && e.u64s(&t, &l).is_err() && e.ascii(&t, &l).is_err());
        }
        // A value offset past the end.
        let e = ifd.get(tag::SOFTWARE).unwrap();
        let mut f = file.clone();
        let at = e.field_at as usize;
        f[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
        let e = *t.first_ifd().unwrap().get(tag::SOFTWARE).unwrap();
        let err = e.ascii(&t, &l).unwrap_err();
        assert!(matches!(err, Error::Truncated { .. }) && err.to_string().contains("TIFF tag 305"), "{err}");
        // Values present but over the allocation limit.
        let tight = Limits::default().with_max_alloc_bytes(4);
        let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
        let bits = ifd.get(tag::BITS_PER_SAMPLE).unwrap();
        assert!(matches!(bits.u32s(&t, &tight), Err(Error::LimitExceeded { .. })));
        assert!(bits.uints(&t).is_ok(), "the lazy reader allocates nothing");
        // An entry count that runs past the end of the file.
        let mut f = file.clone();
        let off = t.first_ifd_offset() as usize;
        f[off..off + 2].copy_from_slice(&u16::MAX.to_le_bytes());
        let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
        assert!(matches!(t.first_ifd(), Err(Error::Truncated { .. })));
        assert!(matches!(t.ifd_chain().next(), Some(Err(Error::Truncated { .. }))));
        // An IFD offset past the end, and one whose next offset is cut off.
        for first in [u32::MAX, file.len() as u32 - 5] {
            let mut f = file.clone();
            f[4..8].copy_from_slice(&first.to_le_bytes());
            let t = Tiff::parse(&f, MAGIC_TIFF).unwrap();
            assert!(matches!(t.ifd_chain().next(), Some(Err(Error::Truncated { .. }))));
        }
    }

    #[test]
    fn every_prefix_of_a_file_gives_errors_never_panics() {
        let l = Limits::default();
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let file = two_ifds(order, MAGIC_TIFF);
            for cut in 0..file.len() {
                let f = &file[..cut];
                let Ok(t) = Tiff::parse(f, MAGIC_TIFF) else { continue };
                let chain: Vec<_> = t.ifd_chain().collect();
                assert!(chain.iter().any(|r| r.is_err()), "cut {cut}: the last IFD's next offset is missing");
                if let Ok(ifd) = t.first_ifd() {
                    for e in &ifd.entries {
                        let _ = (e.value_bytes(&t), e.u32s(&t, &l), e.f64s(&t, &l), e.ascii(&t, &l));
                        let _ = (e.rationals(&t, &l), e.u16s(&t, &l), e.first_f64(&t), e.first_u32(&t));
                    }
                }
            }
        }
    }

    /// What a reader sees of a file's first IFD: the entries and, for each, its values as
    /// every typed method reads them (errors by kind), and the IFD chain.
    fn seen(t: &Tiff) -> Vec<String> {
        let l = Limits::default();
        let kind = |r: Result<String>| match r {
            Ok(v) => v,
            Err(e) => format!("error {}", e.to_string().split(':').next().unwrap_or_default()),
        };
        let mut out: Vec<String> = t.ifd_chain().map(|r| kind(r.map(|l| format!("{l:?}")))).collect();
        match t.first_ifd() {
            Err(e) => out.push(kind(Err(e))),
            Ok(ifd) => {
                out.push(format!("next {}", ifd.next));
                for e in &ifd.entries {
                    out.push(format!("{e:?}"));
                    out.push(kind(e.value_bytes(t).map(|b| format!("{b:?}"))));
                    out.push(kind(e.u32s(t, &l).map(|v| format!("{v:?}"))));
                    out.push(kind(e.f64s(t, &l).map(|v| format!("{v:?}"))));
                    out.push(kind(e.ascii(t, &l)));
                    out.push(kind(e.rationals(t, &l).map(|v| format!("{v:?}"))));
                }
            }
        }
        out
    }

    #[test]
    fn parts_read_from_a_stream_read_as_the_file_in_memory() {
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let mut file = b"junk".to_vec();
            file.extend(two_ifds(order, MAGIC_TIFF));
            let mut input = std::io::Cursor::new(file.clone());
            input.set_position(4);
            let parts = TiffParts::read(&mut input, MAGIC_TIFF, &Limits::default(), &|_| true).unwrap();
            assert_eq!(parts.file_len(), file.len() as u64 - 4);
            let (memory, streamed) =
                (Tiff::parse(&file[4..], MAGIC_TIFF).unwrap(), Tiff::from_parts(&parts, MAGIC_TIFF).unwrap());
            assert_eq!(seen(&memory), seen(&streamed));
            // Less than the file: the values of the tags not asked for are not read.
            let held: usize = parts.parts.values().map(Vec::len).sum();
            let some =
                TiffParts::read(&mut input_at(&file, 4), MAGIC_TIFF, &Limits::default(), &|t| t == tag::SOFTWARE)
                    .unwrap();
            let t = Tiff::from_parts(&some, MAGIC_TIFF).unwrap();
            let ifd = t.first_ifd().unwrap();
            assert_eq!(ifd.get(tag::SOFTWARE).unwrap().ascii(&t, &Limits::default()).unwrap(), "hdrcodec");
            assert!(
                matches!(ifd.get(tag::ARTIST).unwrap().ascii(&t, &Limits::default()), Ok(s) if s == "abc"),
                "inline"
            );
            assert!(matches!(ifd.get(40002).unwrap().value_bytes(&t), Err(Error::Invalid { .. })));
            assert!(some.parts.values().map(Vec::len).sum::<usize>() < held);
            // What is held is charged to the limits.
            let tight = Limits::new(1 << 20, 1 << 20, 1 << 40, 40);
            assert!(matches!(
                TiffParts::read(&mut input_at(&file, 4), MAGIC_TIFF, &tight, &|_| true),
                Err(Error::LimitExceeded { .. })
            ));
        }
    }

    fn input_at(file: &[u8], at: u64) -> std::io::Cursor<Vec<u8>> {
        let mut c = std::io::Cursor::new(file.to_vec());
        c.set_position(at);
        c
    }

    #[test]
    fn every_prefix_read_in_parts_gives_the_errors_of_the_prefix_in_memory() {
        for order in [ByteOrder::Little, ByteOrder::Big] {
            let file = two_ifds(order, MAGIC_TIFF);
            for cut in 0..file.len() {
                let f = &file[..cut];
                let parts = TiffParts::read(&mut input_at(f, 0), MAGIC_TIFF, &Limits::default(), &|_| true);
                match (Tiff::parse(f, MAGIC_TIFF), parts) {
                    (Ok(memory), Ok(parts)) => {
                        assert_eq!(seen(&memory), seen(&Tiff::from_parts(&parts, MAGIC_TIFF).unwrap()), "cut {cut}")
                    }
                    (Err(m), parts) => {
                        let s = parts.and_then(|p| Tiff::from_parts(&p, MAGIC_TIFF).map(|_| ())).unwrap_err();
                        assert_eq!(std::mem::discriminant(&m), std::mem::discriminant(&s), "cut {cut}: {m} / {s}");
                    }
                    (Ok(_), Err(e)) => panic!("cut {cut}: reading the parts failed: {e}"),
                }
            }
        }
    }

    #[test]
    fn a_chain_that_loops_is_read_once_and_reported() {
        let mut file = two_ifds(ByteOrder::Little, MAGIC_TIFF);
        let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
        let second = t.ifd_chain().nth(1).unwrap().unwrap();
        // The second IFD's next offset points back at the first.
        let link = (second.offset + 2 + u64::from(second.entry_count) * ENTRY_LEN) as usize;
        let first = t.first_ifd_offset();
        file[link..link + 4].copy_from_slice(&first.to_le_bytes());
        let parts = TiffParts::read(&mut input_at(&file, 0), MAGIC_TIFF, &Limits::default(), &|_| true).unwrap();
        let t = Tiff::from_parts(&parts, MAGIC_TIFF).unwrap();
        assert!(matches!(t.ifd_chain().last(), Some(Err(Error::Invalid { .. }))));
    }

    #[test]
    fn unknown_field_types_are_skipped() {
        let mut file = two_ifds(ByteOrder::Little, MAGIC_TIFF);
        let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
        let at = t.first_ifd().unwrap().get(tag::IMAGE_WIDTH).unwrap().field_at as usize - 6;
        file[at..at + 2].copy_from_slice(&99u16.to_le_bytes());
        let t = Tiff::parse(&file, MAGIC_TIFF).unwrap();
        let ifd = t.first_ifd().unwrap();
        assert!(ifd.get(tag::IMAGE_WIDTH).is_none());
        let e = ifd.entries.iter().find(|e| e.tag == tag::IMAGE_WIDTH).unwrap();
        assert_eq!((e.field_type(), e.byte_len(), e.values_at()), (None, None, None));
        assert!(matches!(e.value_bytes(&t), Err(Error::Unsupported { .. })));
        assert!(matches!(e.first_u32(&t), Err(Error::Invalid { .. })));
    }

    #[test]
    fn writer_limits() {
        let mut w = ByteWriter::new(ByteOrder::Little);
        let link = write_header(&mut w, MAGIC_TIFF);
        assert!(IfdWriter::new().write(&mut w, 100).is_err(), "link outside the buffer");
        let mut ifd = IfdWriter::new();
        ifd.long(tag::IMAGE_WIDTH, 1);
        ifd.write(&mut w, link).unwrap();
        let file = w.into_vec();
        assert_eq!(Tiff::parse(&file, MAGIC_TIFF).unwrap().first_ifd().unwrap().entries.len(), 1);
    }
}
