//! A small, bounded reader and writer of LogLuv TIFF files (TIFF 6.0 baseline structure plus
//! the SGILOG extensions): classic TIFF in either byte order, the first image of the file, strips,
//! Compression 34676 (SGILOG) / 34677 (SGILOG24), PhotometricInterpretation 32844 (LogL) / 32845
//! (LogLuv) and the STONITS tag (37439). Every offset and count is checked against the file and
//! the caller's [`Limits`] before it is used.

use crate::rle;
use crate::{Encoding, LogLuvRaster};
use hdrcodec_core::{Error, Limits, Result};
use std::collections::HashSet;

/// TIFF tags this reader and writer know.
mod tag {
    pub const IMAGE_WIDTH: u16 = 256;
    pub const IMAGE_LENGTH: u16 = 257;
    pub const BITS_PER_SAMPLE: u16 = 258;
    pub const COMPRESSION: u16 = 259;
    pub const PHOTOMETRIC: u16 = 262;
    pub const STRIP_OFFSETS: u16 = 273;
    pub const SAMPLES_PER_PIXEL: u16 = 277;
    pub const ROWS_PER_STRIP: u16 = 278;
    pub const STRIP_BYTE_COUNTS: u16 = 279;
    pub const PLANAR_CONFIG: u16 = 284;
    pub const TILE_WIDTH: u16 = 322;
    pub const SAMPLE_FORMAT: u16 = 339;
    /// Sample-to-nits factor (SGI private tag; Larson's LogLuv TIFF definition).
    pub const STONITS: u16 = 37439;
}

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
    head.starts_with(b"II*\0") || head.starts_with(b"MM\0*")
}

/// Reads the file's bytes with the file's byte order, every access bounds-checked.
struct Reader<'a> {
    data: &'a [u8],
    big: bool,
}

impl Reader<'_> {
    fn bytes(&self, off: u64, len: u64, what: &str) -> Result<&[u8]> {
        let end = off.checked_add(len).filter(|&e| e <= self.data.len() as u64);
        match end {
            Some(end) => Ok(&self.data[off as usize..end as usize]),
            None => Err(Error::truncated(format!(
                "{what} (bytes {off}..{} of a {}-byte file)",
                off.saturating_add(len),
                self.data.len()
            ))),
        }
    }
    fn u16(&self, off: u64, what: &str) -> Result<u16> {
        let b = self.bytes(off, 2, what)?;
        Ok(if self.big { u16::from_be_bytes([b[0], b[1]]) } else { u16::from_le_bytes([b[0], b[1]]) })
    }
    fn u32(&self, off: u64, what: &str) -> Result<u32> {
        let b: [u8; 4] = self.bytes(off, 4, what)?.try_into().expect("4 bytes");
        Ok(if self.big { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) })
    }
    fn f64(&self, off: u64, what: &str) -> Result<f64> {
        let b: [u8; 8] = self.bytes(off, 8, what)?.try_into().expect("8 bytes");
        Ok(if self.big { f64::from_be_bytes(b) } else { f64::from_le_bytes(b) })
    }
}

/// One IFD entry: where its values are (inline or at an offset).
#[derive(Clone, Copy)]
struct Entry {
    tag: u16,
    typ: u16,
    count: u32,
    /// Offset of the value bytes in the file.
    at: u64,
}

/// Size in bytes of one value of TIFF field type `typ` (0 for types this reader does not know,
/// whose entries are ignored as TIFF 6.0 requires).
fn type_size(typ: u16) -> u64 {
    match typ {
        1 | 2 | 6 | 7 => 1,
        3 | 8 => 2,
        4 | 9 | 11 => 4,
        5 | 10 | 12 => 8,
        _ => 0,
    }
}

impl Entry {
    /// The values of a SHORT or LONG entry (at most `max` of them are read).
    fn uints(&self, r: &Reader, max: usize) -> Result<Vec<u32>> {
        let n = (self.count as usize).min(max);
        let what = format!("the values of TIFF tag {}", self.tag);
        match self.typ {
            3 => (0..n).map(|i| r.u16(self.at + 2 * i as u64, &what).map(u32::from)).collect(),
            4 => (0..n).map(|i| r.u32(self.at + 4 * i as u64, &what)).collect(),
            t => Err(Error::invalid(format!("TIFF tag {} has type {t}, expected SHORT or LONG", self.tag))),
        }
    }
    /// The first value of a SHORT or LONG entry.
    fn uint(&self, r: &Reader) -> Result<u32> {
        self.uints(r, 1)?.first().copied().ok_or_else(|| Error::invalid(format!("TIFF tag {} has no value", self.tag)))
    }
}

/// Largest number of IFDs followed when checking the chain for loops.
const MAX_IFDS: usize = 65536;

/// Parses the header and the first IFD; walks the rest of the IFD chain only to reject loops
/// and pointers past the end of the file.
fn read_ifd(data: &[u8]) -> Result<(Reader<'_>, Vec<Entry>)> {
    if data.len() < 8 {
        return Err(Error::truncated("the 8-byte TIFF header"));
    }
    let big = match &data[..2] {
        b"II" => false,
        b"MM" => true,
        _ => return Err(Error::invalid("not a TIFF file (no II or MM byte-order mark)")),
    };
    let r = Reader { data, big };
    match r.u16(2, "the TIFF header")? {
        42 => {}
        43 => return Err(Error::unsupported("BigTIFF files (only classic TIFF holds LogLuv here)")),
        m => return Err(Error::invalid(format!("not a TIFF file (magic number {m}, expected 42)"))),
    }
    let first = u64::from(r.u32(4, "the TIFF header")?);
    let mut entries = Vec::new();
    let mut seen = HashSet::new();
    let mut off = first;
    let mut index = 0usize;
    while off != 0 {
        if !seen.insert(off) {
            return Err(Error::invalid(format!("the TIFF IFD chain loops back to offset {off}")));
        }
        if seen.len() > MAX_IFDS {
            return Err(Error::limit(format!("more than {MAX_IFDS} TIFF IFDs")));
        }
        let what = format!("TIFF IFD {index} at offset {off}");
        let n = u64::from(r.u16(off, &what)?);
        r.bytes(off + 2, n * 12 + 4, &what)?;
        if index == 0 {
            for k in 0..n {
                let e = off + 2 + 12 * k;
                let tag = r.u16(e, &what)?;
                let typ = r.u16(e + 2, &what)?;
                let count = r.u32(e + 4, &what)?;
                let size = type_size(typ) * u64::from(count);
                if type_size(typ) == 0 {
                    continue;
                }
                let at = if size <= 4 { e + 8 } else { u64::from(r.u32(e + 8, &what)?) };
                if at.checked_add(size).is_none_or(|end| end > data.len() as u64) {
                    // Values past the end matter only for the tags this reader uses.
                    if is_needed(tag) {
                        return Err(Error::truncated(format!(
                            "the values of TIFF tag {tag} ({size} bytes at offset {at}, file of {} bytes)",
                            data.len()
                        )));
                    }
                    continue;
                }
                entries.push(Entry { tag, typ, count, at });
            }
        }
        off = u64::from(r.u32(off + 2 + n * 12, &what)?);
        index += 1;
    }
    if index == 0 {
        return Err(Error::invalid("the TIFF file has no image (first IFD offset is 0)"));
    }
    Ok((r, entries))
}

fn is_needed(tag: u16) -> bool {
    matches!(
        tag,
        tag::IMAGE_WIDTH
            | tag::IMAGE_LENGTH
            | tag::COMPRESSION
            | tag::PHOTOMETRIC
            | tag::STRIP_OFFSETS
            | tag::SAMPLES_PER_PIXEL
            | tag::ROWS_PER_STRIP
            | tag::STRIP_BYTE_COUNTS
            | tag::PLANAR_CONFIG
            | tag::STONITS
    )
}

/// Reads the first image of a LogLuv TIFF as its encoded words.
pub fn read(data: &[u8], limits: &Limits) -> Result<LogLuvRaster> {
    let (r, entries) = read_ifd(data)?;
    let find = |t: u16| entries.iter().find(|e| e.tag == t);
    let required = |t: u16, name: &str| find(t).ok_or_else(|| Error::invalid(format!("the TIFF has no {name} tag")));
    let width = required(tag::IMAGE_WIDTH, "ImageWidth")?.uint(&r)?;
    let height = required(tag::IMAGE_LENGTH, "ImageLength")?.uint(&r)?;
    let compression = find(tag::COMPRESSION).map(|e| e.uint(&r)).transpose()?.unwrap_or(1);
    let photometric = required(tag::PHOTOMETRIC, "PhotometricInterpretation")?.uint(&r)?;
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
    let planar = find(tag::PLANAR_CONFIG).map(|e| e.uint(&r)).transpose()?.unwrap_or(1);
    if planar != 1 {
        return Err(Error::unsupported(format!("TIFF PlanarConfiguration {planar} (SGILOG needs contiguous samples)")));
    }
    let spp = find(tag::SAMPLES_PER_PIXEL).map(|e| e.uint(&r)).transpose()?.unwrap_or(1);
    let expected_spp = if encoding == Encoding::LogL16 { 1 } else { 3 };
    if spp != expected_spp {
        return Err(Error::unsupported(format!(
            "{} TIFF with SamplesPerPixel {spp} (expected {expected_spp})",
            encoding.name()
        )));
    }
    limits.check_image(u64::from(width), u64::from(height), hdrcodec_core::Channels::Rgb)?;
    let pixels = u64::from(width) * u64::from(height);
    limits.check_alloc(pixels * 4, "the LogLuv pixel words")?;
    let rows_per_strip =
        find(tag::ROWS_PER_STRIP).map(|e| e.uint(&r)).transpose()?.unwrap_or(u32::MAX).clamp(1, height);
    let strips = height.div_ceil(rows_per_strip) as usize;
    let offsets = required(tag::STRIP_OFFSETS, "StripOffsets")?.uints(&r, strips)?;
    let counts = required(tag::STRIP_BYTE_COUNTS, "StripByteCounts")?.uints(&r, strips)?;
    if offsets.len() < strips || counts.len() < strips {
        return Err(Error::invalid(format!(
            "the TIFF lists {} strip offsets and {} byte counts for {strips} strips",
            offsets.len(),
            counts.len()
        )));
    }
    let stonits = match find(tag::STONITS) {
        Some(e) if e.typ == 12 && e.count >= 1 => Some(r.f64(e.at, "the STONITS value")?),
        Some(e) if e.count >= 1 && matches!(e.typ, 3 | 4) => Some(f64::from(e.uint(&r)?)),
        Some(e) if e.count >= 1 && e.typ == 11 => Some(f64::from(f32::from_bits(r.u32(e.at, "the STONITS value")?))),
        Some(e) if e.count >= 1 => {
            return Err(Error::invalid(format!("the STONITS tag has type {}, expected DOUBLE", e.typ)))
        }
        _ => None,
    };

    let w = width as usize;
    let mut words = vec![0u32; pixels as usize];
    for (s, rows) in words.chunks_mut(w * rows_per_strip as usize).enumerate() {
        let what = format!("strip {s}");
        let strip = r.bytes(u64::from(offsets[s]), u64::from(counts[s]), &what)?;
        let first_row = s as u32 * rows_per_strip;
        match encoding {
            Encoding::LogLuv24 => {
                for (k, row) in rows.chunks_mut(w).enumerate() {
                    let Some(src) = strip.get(k * 3 * w..(k + 1) * 3 * w) else {
                        return Err(Error::truncated(format!("the SGILOG24 data of row {}", first_row + k as u32)));
                    };
                    for (p, b) in row.iter_mut().zip(src.chunks_exact(3)) {
                        *p = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
                    }
                }
            }
            Encoding::LogLuv32 | Encoding::LogL16 => {
                let planes = if encoding == Encoding::LogL16 { 2 } else { 4 };
                let mut pos = 0;
                for (k, row) in rows.chunks_mut(w).enumerate() {
                    rle::decode_row(strip, &mut pos, row, planes, first_row + k as u32)?;
                }
            }
        }
    }
    Ok(LogLuvRaster { width, height, encoding, words, stonits })
}

/// Writes a little-endian TIFF: header, the strips, then the IFD (tags in ascending order).
pub fn write(raster: &LogLuvRaster, rows_per_strip: u32) -> Result<Vec<u8>> {
    let (w, h) = (raster.width, raster.height);
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("cannot write an empty {w}x{h} LogLuv TIFF")));
    }
    if raster.words.len() as u64 != u64::from(w) * u64::from(h) {
        return Err(Error::invalid(format!("{}x{} raster with {} words", w, h, raster.words.len())));
    }
    let rps = rows_per_strip.clamp(1, h);
    let mut out = b"II*\0\0\0\0\0".to_vec();
    let mut offsets = Vec::new();
    let mut counts = Vec::new();
    for strip in raster.words.chunks(w as usize * rps as usize) {
        let start = out.len();
        for row in strip.chunks(w as usize) {
            match raster.encoding {
                Encoding::LogLuv24 => {
                    for &p in row {
                        out.extend_from_slice(&[(p >> 16) as u8, (p >> 8) as u8, p as u8]);
                    }
                }
                Encoding::LogLuv32 => rle::encode_row(row, 4, &mut out),
                Encoding::LogL16 => rle::encode_row(row, 2, &mut out),
            }
        }
        offsets.push(start);
        counts.push(out.len() - start);
    }
    if out.len() > u32::MAX as usize - 4096 - 8 * offsets.len() {
        return Err(Error::limit("the LogLuv TIFF would exceed 4 GiB (classic TIFF offsets are 32-bit)"));
    }
    let (compression, photometric, spp) = match raster.encoding {
        Encoding::LogLuv32 => (COMPRESSION_SGILOG, PHOTOMETRIC_LOGLUV, 3u16),
        Encoding::LogLuv24 => (COMPRESSION_SGILOG24, PHOTOMETRIC_LOGLUV, 3),
        Encoding::LogL16 => (COMPRESSION_SGILOG, PHOTOMETRIC_LOGL, 1),
    };
    // Entries: (tag, type, count, value bytes). Values over 4 bytes go after the IFD.
    let le16 = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let le32 = |v: &[usize]| v.iter().flat_map(|&x| (x as u32).to_le_bytes()).collect::<Vec<u8>>();
    let spp_list = vec![0u16; spp as usize];
    let mut tags: Vec<(u16, u16, u32, Vec<u8>)> = vec![
        (tag::IMAGE_WIDTH, 4, 1, w.to_le_bytes().to_vec()),
        (tag::IMAGE_LENGTH, 4, 1, h.to_le_bytes().to_vec()),
        // The stored samples are 16-bit signed integers (libtiff writes the same).
        (tag::BITS_PER_SAMPLE, 3, u32::from(spp), le16(&spp_list.iter().map(|_| 16).collect::<Vec<_>>())),
        (tag::COMPRESSION, 3, 1, le16(&[compression])),
        (tag::PHOTOMETRIC, 3, 1, le16(&[photometric])),
        (tag::STRIP_OFFSETS, 4, offsets.len() as u32, le32(&offsets)),
        (tag::SAMPLES_PER_PIXEL, 3, 1, le16(&[spp])),
        (tag::ROWS_PER_STRIP, 4, 1, rps.to_le_bytes().to_vec()),
        (tag::STRIP_BYTE_COUNTS, 4, counts.len() as u32, le32(&counts)),
        (tag::PLANAR_CONFIG, 3, 1, le16(&[1])),
        (tag::SAMPLE_FORMAT, 3, u32::from(spp), le16(&spp_list.iter().map(|_| 2).collect::<Vec<_>>())),
    ];
    if let Some(s) = raster.stonits {
        tags.push((tag::STONITS, 12, 1, s.to_le_bytes().to_vec()));
    }
    if out.len() % 2 == 1 {
        out.push(0); // IFDs start on a word boundary
    }
    let ifd = out.len();
    out[4..8].copy_from_slice(&(ifd as u32).to_le_bytes());
    let mut extra = ifd + 2 + tags.len() * 12 + 4;
    let mut tail = Vec::new();
    out.extend_from_slice(&(tags.len() as u16).to_le_bytes());
    for (t, typ, count, value) in &tags {
        out.extend_from_slice(&t.to_le_bytes());
        out.extend_from_slice(&typ.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        if value.len() <= 4 {
            let mut v = [0u8; 4];
            v[..value.len()].copy_from_slice(value);
            out.extend_from_slice(&v);
        } else {
            out.extend_from_slice(&(extra as u32).to_le_bytes());
            tail.extend_from_slice(value);
            if tail.len() % 2 == 1 {
                tail.push(0);
            }
            extra = ifd + 2 + tags.len() * 12 + 4 + tail.len();
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&tail);
    Ok(out)
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
