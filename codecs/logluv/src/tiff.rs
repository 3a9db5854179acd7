//! A small, bounded reader and writer of LogLuv TIFF files (TIFF 6.0 baseline structure plus
//! the SGILOG extensions): classic TIFF in either byte order, the first image of the file, strips,
//! Compression 34676 (SGILOG) / 34677 (SGILOG24), PhotometricInterpretation 32844 (LogL) / 32845
//! (LogLuv) and the STONITS tag (37439). Every offset and count is checked against the file and
//! the caller's [`Limits`] before it is used. The file structure (header, IFDs, entries) is
//! [`hdrcodec_core::tiff`]'s; this module adds what is LogLuv's.

use crate::rle;
use crate::{Encoding, LogLuvRaster};
use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
use hdrcodec_core::tiff::{self as core_tiff, tag, Entry, IfdWriter, Tiff, TiffParts, MAGIC_TIFF};
use hdrcodec_core::{Allocation, Error, Limits, ReadSeek, Result};

/// Sample-to-nits factor: the cd/m² of Y = 1 (an SGI private tag, from Larson's LogLuv TIFF
/// definition).
pub const TAG_STONITS: u16 = 37439;
/// Compression 34676: SGILOG (run-length coded LogL16 / LogLuv32).
pub const COMPRESSION_SGILOG: u16 = 34676;
/// Compression 34677: SGILOG24 (uncoded 3-byte LogLuv24).
pub const COMPRESSION_SGILOG24: u16 = 34677;
/// PhotometricInterpretation 32844: LogL (luminance only).
pub const PHOTOMETRIC_LOGL: u16 = 32844;
/// PhotometricInterpretation 32845: LogLuv.
pub const PHOTOMETRIC_LOGLUV: u16 = 32845;

/// True if `head` starts with a classic TIFF header in either byte order.
pub fn is_tiff(head: &[u8]) -> bool {
    core_tiff::sniff(head, MAGIC_TIFF)
}

/// Reads the first IFD of `t`, keeping the entries of known types whose values lie inside the
/// file (values past the end are an error only for the tags [`read`] uses); walks the rest of
/// the IFD chain only to reject loops and pointers past the end of the file.
fn read_ifd(t: Tiff<'_>) -> Result<(Tiff<'_>, Vec<Entry>)> {
    let mut chain = t.ifd_chain();
    let first = chain.next().ok_or_else(|| Error::invalid("the TIFF file has no image (first IFD offset is 0)"))??;
    let mut entries = Vec::new();
    for e in t.read_ifd(first.offset)?.entries {
        if e.field_type().is_none() {
            continue;
        }
        match e.value_bytes(&t) {
            Ok(_) => entries.push(e),
            Err(err) if is_needed(e.tag) => return Err(err),
            Err(_) => {}
        }
    }
    for ifd in chain {
        ifd?;
    }
    Ok((t, entries))
}

fn is_needed(tag: u16) -> bool {
    matches!(
        tag,
        tag::IMAGE_WIDTH
            | tag::IMAGE_LENGTH
            | tag::COMPRESSION
            | tag::PHOTOMETRIC_INTERPRETATION
            | tag::STRIP_OFFSETS
            | tag::SAMPLES_PER_PIXEL
            | tag::ROWS_PER_STRIP
            | tag::STRIP_BYTE_COUNTS
            | tag::PLANAR_CONFIGURATION
            | TAG_STONITS
    )
}

/// What the first IFD of a LogLuv TIFF says of its image, checked as [`read`] checks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiffInfo {
    /// ImageWidth.
    pub width: u32,
    /// ImageLength.
    pub height: u32,
    /// The pixel encoding (from PhotometricInterpretation and Compression).
    pub encoding: Encoding,
    /// The STONITS value, if the tag is present.
    pub stonits: Option<f64>,
}

/// Reads the TIFF header and the tags of the first IFD that describe the image (no strip
/// offsets, no pixels): allocates only the IFD's entry list.
pub fn read_info(data: &[u8]) -> Result<TiffInfo> {
    Ok(read_header(Tiff::parse(data, MAGIC_TIFF)?)?.2)
}

/// [`read_info`] from a file (any source that reads and seeks, from its current position):
/// the header, the first IFD and the values of the tags that describe the image are read from
/// the file (see [`StripRows::from_reader`]), not a strip.
pub fn read_info_from(input: &mut dyn ReadSeek, limits: &Limits) -> Result<TiffInfo> {
    let parts = read_parts(input, limits)?;
    Ok(read_header(Tiff::from_parts(&parts, MAGIC_TIFF)?)?.2)
}

/// What [`read_info_from`] and [`StripRows::from_reader`] read of a file: its header, IFDs and
/// the values of the tags the decoder uses ([`TiffParts`]).
fn read_parts(input: &mut dyn ReadSeek, limits: &Limits) -> Result<TiffParts> {
    // TileWidth's presence is read too (a tiled file is refused).
    TiffParts::read(input, MAGIC_TIFF, limits, &|t| is_needed(t) || t == tag::TILE_WIDTH)
}

/// The IFD and what it says of the image (the part of [`read`] before the strips).
fn read_header(t: Tiff<'_>) -> Result<(Tiff<'_>, Vec<Entry>, TiffInfo)> {
    let (r, entries) = read_ifd(t)?;
    let find = |t: u16| entries.iter().find(|e| e.tag == t);
    let required = |t: u16, name: &str| find(t).ok_or_else(|| Error::invalid(format!("the TIFF has no {name} tag")));
    let width = required(tag::IMAGE_WIDTH, "ImageWidth")?.first_u32(&r)?;
    let height = required(tag::IMAGE_LENGTH, "ImageLength")?.first_u32(&r)?;
    let compression = find(tag::COMPRESSION).map(|e| e.first_u32(&r)).transpose()?.unwrap_or(1);
    let photometric = required(tag::PHOTOMETRIC_INTERPRETATION, "PhotometricInterpretation")?.first_u32(&r)?;
    let encoding = match (photometric as u16, compression as u16) {
        (PHOTOMETRIC_LOGLUV, COMPRESSION_SGILOG) => Encoding::LogLuv32,
        (PHOTOMETRIC_LOGLUV, COMPRESSION_SGILOG24) => Encoding::LogLuv24,
        (PHOTOMETRIC_LOGL, COMPRESSION_SGILOG) => Encoding::LogL16,
        (PHOTOMETRIC_LOGL | PHOTOMETRIC_LOGLUV, c) => {
            return Err(Error::unsupported(format!(
                "LogLuv TIFF with Compression {c} (only 34676 SGILOG, and 34677 SGILOG24 for LogLuv)"
            )))
        }
        (p, _) if compression > 0xffff || photometric > 0xffff => {
            return Err(Error::invalid(format!("TIFF PhotometricInterpretation {p} / Compression {compression}")))
        }
        (p, _) => return Err(Error::unsupported(format!("TIFF PhotometricInterpretation {p} is not LogL or LogLuv"))),
    };
    if find(tag::TILE_WIDTH).is_some() {
        return Err(Error::unsupported("tiled LogLuv TIFF (only strips)"));
    }
    let planar = find(tag::PLANAR_CONFIGURATION).map(|e| e.first_u32(&r)).transpose()?.unwrap_or(1);
    if planar != 1 {
        return Err(Error::unsupported(format!("TIFF PlanarConfiguration {planar} (SGILOG needs contiguous samples)")));
    }
    let spp = find(tag::SAMPLES_PER_PIXEL).map(|e| e.first_u32(&r)).transpose()?.unwrap_or(1);
    let expected_spp = if encoding == Encoding::LogL16 { 1 } else { 3 };
    if spp != expected_spp {
        return Err(Error::unsupported(format!(
            "{} TIFF with SamplesPerPixel {spp} (expected {expected_spp})",
            encoding.name()
        )));
    }
    let stonits = match find(TAG_STONITS) {
        // FLOAT or DOUBLE (libtiff writes DOUBLE); an integer is accepted too.
        Some(e) if e.count >= 1 && matches!(e.typ, 11 | 12) => Some(e.first_f64(&r)?),
        Some(e) if e.count >= 1 && matches!(e.typ, 3 | 4) => Some(f64::from(e.first_u32(&r)?)),
        Some(e) if e.count >= 1 => {
            return Err(Error::invalid(format!("the STONITS tag has type {}, expected DOUBLE", e.typ)))
        }
        _ => None,
    };
    // STONITS becomes the image's nits_per_unit (an f32): it must be a positive finite number
    // there too (libtiff does not check it; a NaN or 0 would make every luminance meaningless).
    if let Some(s) = stonits {
        if !(s > 0.0 && (s as f32).is_finite() && s as f32 > 0.0) {
            return Err(Error::invalid(format!("STONITS {s} is not a positive finite number of cd/m² per unit")));
        }
    }
    Ok((r, entries, TiffInfo { width, height, encoding, stonits }))
}

/// Reads the first image of a LogLuv TIFF as its encoded words.
pub fn read(data: &[u8], limits: &Limits) -> Result<LogLuvRaster> {
    let mut rows = StripRows::new(data)?;
    let TiffInfo { width, height, encoding, stonits } = rows.info;
    limits.check_image(u64::from(width), u64::from(height), hdrcodec_core::Channels::Rgb)?;
    let pixels = u64::from(width) * u64::from(height);
    limits.check_alloc(pixels * 4, "the LogLuv pixel words")?;
    let mut words = vec![0u32; pixels as usize];
    for row in words.chunks_mut(width as usize) {
        rows.next_row(row)?;
    }
    Ok(LogLuvRaster { width, height, encoding, words, stonits })
}

/// The rows of a LogLuv TIFF's first image as encoded words, read one at a time from the
/// strips (nothing of the image's size is held).
pub struct StripRows<'a> {
    /// What the IFD says of the image.
    pub info: TiffInfo,
    rows_per_strip: u32,
    offsets: Vec<u32>,
    counts: Vec<u32>,
    /// The next row to read.
    row: u32,
    /// Where the strips are read from, and the strip holding `row`.
    source: StripSource<'a>,
    /// The position in the current strip.
    pos: usize,
}

/// Where [`StripRows`] reads its strips: the file's bytes in memory (the current strip is a
/// slice of them), or a file, each strip read into a buffer charged to the limits.
enum StripSource<'a> {
    Memory {
        file: ByteReader<'a>,
        strip: &'a [u8],
    },
    File {
        input: &'a mut dyn ReadSeek,
        base: u64,
        len: u64,
        strip: Vec<u8>,
        charge: Option<Allocation>,
        limits: Limits,
    },
}

/// What [`StripRows`] needs from the IFD: the image, the rows per strip and the strip tables
/// (at most one entry per strip of the checked height).
type StripTables = (TiffInfo, u32, Vec<u32>, Vec<u32>);

fn strip_tables(t: Tiff<'_>) -> Result<StripTables> {
    let (r, entries, info) = read_header(t)?;
    let find = |t: u16| entries.iter().find(|e| e.tag == t);
    let required = |t: u16, name: &str| find(t).ok_or_else(|| Error::invalid(format!("the TIFF has no {name} tag")));
    let height = info.height;
    if info.width == 0 || height == 0 {
        return Err(Error::invalid(format!("the TIFF image is empty ({}x{height})", info.width)));
    }
    let rows_per_strip =
        find(tag::ROWS_PER_STRIP).map(|e| e.first_u32(&r)).transpose()?.unwrap_or(u32::MAX).clamp(1, height);
    let strips = height.div_ceil(rows_per_strip) as usize;
    // At most `strips` values each (bounded by the height), read lazily from the file.
    let offsets: Vec<u32> = required(tag::STRIP_OFFSETS, "StripOffsets")?.uints(&r)?.take(strips).collect();
    let counts: Vec<u32> = required(tag::STRIP_BYTE_COUNTS, "StripByteCounts")?.uints(&r)?.take(strips).collect();
    if offsets.len() < strips || counts.len() < strips {
        return Err(Error::invalid(format!(
            "the TIFF lists {} strip offsets and {} byte counts for {strips} strips",
            offsets.len(),
            counts.len()
        )));
    }
    Ok((info, rows_per_strip, offsets, counts))
}

/// Reads `len` bytes at `at` (from the file's start `base`) into `out`; a file that ends first
/// is [`Error::Truncated`] naming `what`.
fn read_at(input: &mut dyn ReadSeek, base: u64, at: u64, out: &mut [u8], what: &str) -> Result<()> {
    hdrcodec_core::read_exact_at(input, base + at, out, what)
}

impl<'a> StripRows<'a> {
    /// Reads the IFD and the strip tables (at most one entry per strip of the checked height).
    pub fn new(data: &'a [u8]) -> Result<Self> {
        let t = Tiff::parse(data, MAGIC_TIFF)?;
        let file = ByteReader::new(data, t.order());
        let (info, rows_per_strip, offsets, counts) = strip_tables(t)?;
        let source = StripSource::Memory { file, strip: &[] };
        Ok(StripRows { info, rows_per_strip, offsets, counts, row: 0, source, pos: 0 })
    }

    /// [`new`](Self::new) for a file (any source that reads and seeks, from its current
    /// position): the header, the IFDs and the values of the tags it uses are read from the file
    /// ([`TiffParts`]), then each strip when its first row is decoded, into a buffer charged to
    /// `limits` (the largest strip), so that the file is never held whole.
    pub fn from_reader(input: &'a mut dyn ReadSeek, limits: &Limits) -> Result<Self> {
        let (base, len) = hdrcodec_core::remaining_len(input)?;
        let parts = read_parts(input, limits)?;
        let (info, rows_per_strip, offsets, counts) = strip_tables(Tiff::from_parts(&parts, MAGIC_TIFF)?)?;
        drop(parts);
        let source = StripSource::File { input, base, len, strip: Vec::new(), charge: None, limits: limits.clone() };
        Ok(StripRows { info, rows_per_strip, offsets, counts, row: 0, source, pos: 0 })
    }

    /// Decodes the next row into `out` (`width` words).
    pub fn next_row(&mut self, out: &mut [u32]) -> Result<()> {
        let (row, w) = (self.row, self.info.width as usize);
        if row >= self.info.height {
            return Err(Error::invalid(format!("row {row} of an image {} rows high", self.info.height)));
        }
        let k = row % self.rows_per_strip;
        if k == 0 {
            let s = (row / self.rows_per_strip) as usize;
            let (offset, count) = (u64::from(self.offsets[s]), u64::from(self.counts[s]));
            match &mut self.source {
                StripSource::Memory { file, strip } => {
                    *strip = file.bytes_at(offset, count, format_args!("strip {s}"))?
                }
                StripSource::File { input, base, len, strip, charge, limits } => {
                    if offset.saturating_add(count) > *len {
                        return Err(Error::truncated(format!(
                            "strip {s} (bytes {offset}..{} of a {len}-byte input)",
                            offset.saturating_add(count)
                        )));
                    }
                    if count as usize > strip.len() {
                        *charge = None;
                        *charge = Some(limits.charge(count, "a TIFF strip read from the file")?);
                        strip.resize(count as usize, 0);
                    }
                    read_at(&mut **input, *base, offset, &mut strip[..count as usize], "a TIFF strip")?;
                    strip.truncate(count as usize);
                }
            }
            self.pos = 0;
        }
        let strip: &[u8] = match &self.source {
            StripSource::Memory { strip, .. } => strip,
            StripSource::File { strip, .. } => strip,
        };
        match self.info.encoding {
            Encoding::LogLuv24 => {
                let k = k as usize;
                let Some(src) = strip.get(k * 3 * w..(k + 1) * 3 * w) else {
                    return Err(Error::truncated(format!("the SGILOG24 data of row {row}")));
                };
                for (p, b) in out.iter_mut().zip(src.chunks_exact(3)) {
                    *p = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
                }
            }
            Encoding::LogLuv32 | Encoding::LogL16 => {
                let planes = if self.info.encoding == Encoding::LogL16 { 2 } else { 4 };
                rle::decode_row(strip, &mut self.pos, out, planes, row)?;
            }
        }
        self.row += 1;
        Ok(())
    }
}

/// Writes a little-endian TIFF: header, the strips, then the IFD (tags in ascending order,
/// values over 4 bytes after it).
pub fn write(raster: &LogLuvRaster, rows_per_strip: u32) -> Result<Vec<u8>> {
    let (w, h) = (raster.width, raster.height);
    if raster.words.len() as u64 != u64::from(w) * u64::from(h) {
        return Err(Error::invalid(format!("{}x{} raster with {} words", w, h, raster.words.len())));
    }
    let layout = Layout { width: w, height: h, encoding: raster.encoding, rows_per_strip, stonits: raster.stonits };
    let mut out = std::io::Cursor::new(Vec::new());
    write_streamed(&mut out, &layout, |first_row, words| {
        let at = first_row as usize * w as usize;
        words.copy_from_slice(&raster.words[at..at + words.len()]);
        Ok(())
    })?;
    Ok(out.into_inner())
}

/// What the IFD of a LogLuv TIFF says.
pub(crate) struct Layout {
    pub width: u32,
    pub height: u32,
    pub encoding: Encoding,
    pub rows_per_strip: u32,
    pub stonits: Option<f64>,
}

/// Writes a little-endian TIFF strip by strip into `out`: the header, each strip as soon as
/// `fill(first_row, words)` has given the encoded words of its rows, then the IFD, whose offset
/// is stored in the header by seeking back. Holds one strip of words and bytes at a time.
pub(crate) fn write_streamed(
    out: &mut dyn hdrcodec_core::WriteSeek,
    layout: &Layout,
    mut fill: impl FnMut(u32, &mut [u32]) -> Result<()>,
) -> Result<()> {
    let Layout { width: w, height: h, encoding, .. } = *layout;
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("cannot write an empty {w}x{h} LogLuv TIFF")));
    }
    let rps = layout.rows_per_strip.clamp(1, h);
    let mut header = ByteWriter::new(ByteOrder::Little);
    let link = core_tiff::write_header(&mut header, MAGIC_TIFF);
    out.write_all(header.as_slice())?;
    let mut pos = header.len() as u64;
    let mut offsets = Vec::new();
    let mut counts = Vec::new();
    let mut words = vec![0u32; w as usize * rps as usize];
    let mut bytes = Vec::new();
    let mut first_row = 0;
    while first_row < h {
        let rows = rps.min(h - first_row);
        let words = &mut words[..rows as usize * w as usize];
        fill(first_row, words)?;
        bytes.clear();
        for row in words.chunks(w as usize) {
            match encoding {
                Encoding::LogLuv24 => {
                    for &p in row {
                        bytes.extend_from_slice(&[(p >> 16) as u8, (p >> 8) as u8, p as u8]);
                    }
                }
                Encoding::LogLuv32 => rle::encode_row(row, 4, &mut bytes),
                Encoding::LogL16 => rle::encode_row(row, 2, &mut bytes),
            }
        }
        // Every offset and count stays below this, so the casts cannot wrap.
        if pos + bytes.len() as u64 > u64::from(u32::MAX) - 4096 - 8 * (offsets.len() as u64 + 1) {
            return Err(Error::limit("the LogLuv TIFF would exceed 4 GiB (classic TIFF offsets are 32-bit)"));
        }
        out.write_all(&bytes)?;
        offsets.push(pos as u32);
        counts.push(bytes.len() as u32);
        pos += bytes.len() as u64;
        first_row += rows;
    }
    let (compression, photometric, spp) = match encoding {
        Encoding::LogLuv32 => (COMPRESSION_SGILOG, PHOTOMETRIC_LOGLUV, 3),
        Encoding::LogLuv24 => (COMPRESSION_SGILOG24, PHOTOMETRIC_LOGLUV, 3),
        Encoding::LogL16 => (COMPRESSION_SGILOG, PHOTOMETRIC_LOGL, 1),
    };
    let mut ifd = IfdWriter::new();
    ifd.long(tag::IMAGE_WIDTH, w);
    ifd.long(tag::IMAGE_LENGTH, h);
    // The stored samples are 16-bit signed integers (libtiff writes the same).
    ifd.shorts(tag::BITS_PER_SAMPLE, &[16; 3][..spp]);
    ifd.short(tag::COMPRESSION, compression);
    ifd.short(tag::PHOTOMETRIC_INTERPRETATION, photometric);
    ifd.longs(tag::STRIP_OFFSETS, &offsets);
    ifd.short(tag::SAMPLES_PER_PIXEL, spp as u16);
    ifd.long(tag::ROWS_PER_STRIP, rps);
    ifd.longs(tag::STRIP_BYTE_COUNTS, &counts);
    ifd.short(tag::PLANAR_CONFIGURATION, 1);
    ifd.shorts(tag::SAMPLE_FORMAT, &[2; 3][..spp]);
    if let Some(s) = layout.stonits {
        ifd.double(TAG_STONITS, s);
    }
    let (ifd_bytes, ifd_offset) = ifd.bytes_after(ByteOrder::Little, pos)?;
    out.write_all(&ifd_bytes)?;
    out.seek(std::io::SeekFrom::Start(link as u64))?;
    out.write_all(&(ifd_offset as u32).to_le_bytes())?;
    out.seek(std::io::SeekFrom::End(0))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raster(encoding: Encoding) -> LogLuvRaster {
        let words = (0..35u32).map(|i| (i * 0x0101_0307) & encoding.word_mask()).collect();
        LogLuvRaster { width: 7, height: 5, encoding, words, stonits: Some(179.0) }
    }

    #[test]
    fn write_then_read_gives_the_same_words() {
        for e in [Encoding::LogL16, Encoding::LogLuv24, Encoding::LogLuv32] {
            for rps in [1, 2, 5, 100] {
                let r = raster(e);
                let file = write(&r, rps).unwrap();
                let back = read(&file, &Limits::default()).unwrap();
                assert_eq!(back, r, "{e:?} rows/strip {rps}");
            }
        }
    }

    #[test]
    fn a_stonits_that_is_no_scale_is_an_error() {
        // Found by the fuzzer (fuzz/regressions/logluv/crash-4348...): a NaN STONITS made probe
        // and decode report a NaN nits_per_unit.
        for s in [f64::NAN, 0.0, -179.0, f64::INFINITY, 1e300, 1e-300] {
            let file = write(&LogLuvRaster { stonits: Some(s), ..raster(Encoding::LogLuv32) }, 5).unwrap();
            let e = read(&file, &Limits::default()).unwrap_err().to_string();
            assert!(e.contains("is not a positive finite number"), "{s}: {e}");
        }
    }

    #[test]
    fn ifd_loops_and_bad_offsets_are_errors() {
        let mut file = write(&raster(Encoding::LogLuv32), 2).unwrap();
        let ifd = u32::from_le_bytes(file[4..8].try_into().unwrap()) as usize;
        let n = u16::from_le_bytes([file[ifd], file[ifd + 1]]) as usize;
        let next = ifd + 2 + 12 * n;
        // The next-IFD pointer points back at the first IFD.
        file[next..next + 4].copy_from_slice(&(ifd as u32).to_le_bytes());
        let e = read(&file, &Limits::default()).unwrap_err().to_string();
        assert!(e.contains("loops"), "{e}");
        // A next-IFD pointer past the end.
        file[next..next + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(read(&file, &Limits::default()).is_err());
        // The first IFD past the end.
        let past = file.len() as u32 + 10;
        file[4..8].copy_from_slice(&past.to_le_bytes());
        assert!(read(&file, &Limits::default()).is_err());
    }

    #[test]
    fn absurd_dimensions_hit_the_limits_before_allocating() {
        let mut r = raster(Encoding::LogLuv24);
        r.width = 1;
        r.height = 35;
        let mut file = write(&r, 100).unwrap();
        // Patch ImageWidth (the first entry's inline value) to 2^31.
        let ifd = u32::from_le_bytes(file[4..8].try_into().unwrap()) as usize;
        file[ifd + 2 + 8..ifd + 2 + 12].copy_from_slice(&(1u32 << 31).to_le_bytes());
        let e = read(&file, &Limits::default()).unwrap_err();
        assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
    }
}
