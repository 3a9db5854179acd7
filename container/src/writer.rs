//! The streaming writer: chunks go out in the order they are written, nothing is ever revisited.

use crate::crc::Crc32c;
use crate::format::{self, DataHeader, Head, IndexEntry, MAX_CHUNK_LEN, SIGNATURE};
use hdrcodec_core::{ColorInfo, Error, Hdr10Metadata, Result};
use std::collections::HashSet;
use std::io::Write;

/// Writes a `.hdrc` stream to any [`Write`]: the signature and HEAD on [`Writer::new`], then
/// ancillary chunks and DATA chunks in any order, then INDX and END on [`Writer::finish`].
///
/// The writer checks what the reader will check: every DATA rectangle must be one tile of the
/// HEAD's grid, each tile of each frame must be written exactly once, COLR, HDRM and META at
/// most once each.
///
/// ```
/// use hdrcodec_container::{Head, Reader, Writer};
/// use hdrcodec_core::{Channels, Limits};
/// let head = Head::new(*b"RF32", 2, 1, Channels::Rgb);
/// let mut w = Writer::new(Vec::new(), &head)?;
/// w.write_meta(&[("software".into(), "doc test".into())])?;
/// w.write_data(&head.tile(0, 0, 0), b"tile payload")?;
/// let file = w.finish()?;
/// let r = Reader::new(&file, &Limits::default())?;
/// assert_eq!(r.data_chunks()[0].payload, b"tile payload");
/// # Ok::<(), hdrcodec_core::Error>(())
/// ```
pub struct Writer<W: Write> {
    out: W,
    head: Head,
    offset: u64,
    index: Vec<IndexEntry>,
    written: HashSet<u64>,
    wrote: [bool; 3],
}

impl<W: Write> Writer<W> {
    /// Starts a file: writes the signature and the HEAD chunk.
    pub fn new(out: W, head: &Head) -> Result<Self> {
        head.check()?;
        let mut w =
            Writer { out, head: *head, offset: 0, index: Vec::new(), written: HashSet::new(), wrote: [false; 3] };
        w.out.write_all(&SIGNATURE)?;
        w.offset = SIGNATURE.len() as u64;
        w.chunk(format::HEAD, &[&head.to_bytes()])?;
        Ok(w)
    }

    /// The HEAD this file was started with.
    pub fn head(&self) -> &Head {
        &self.head
    }

    fn once(&mut self, which: usize, name: &str) -> Result<()> {
        if std::mem::replace(&mut self.wrote[which], true) {
            return Err(Error::invalid(format!("the {name} chunk was already written")));
        }
        Ok(())
    }

    /// Writes COLR: the primaries and `nits_per_unit` of `color` (its `hdr10` goes in HDRM,
    /// see [`Writer::write_hdr10`]).
    pub fn write_color(&mut self, color: &ColorInfo) -> Result<()> {
        self.once(0, "COLR")?;
        if !(color.nits_per_unit.is_finite() && color.nits_per_unit > 0.0) {
            return Err(Error::invalid(format!("nits_per_unit {} is not a positive number", color.nits_per_unit)));
        }
        self.chunk(format::COLR, &[&format::color_bytes(color)])
    }

    /// Writes HDRM: HDR10 mastering display and content light level.
    pub fn write_hdr10(&mut self, hdr10: &Hdr10Metadata) -> Result<()> {
        self.once(1, "HDRM")?;
        self.chunk(format::HDRM, &[&format::hdr10_bytes(hdr10)])
    }

    /// Writes META: UTF-8 key/value pairs (keys non-empty).
    pub fn write_meta(&mut self, pairs: &[(String, String)]) -> Result<()> {
        self.once(2, "META")?;
        self.chunk(format::META, &[&format::meta_bytes(pairs)?])
    }

    /// Writes one DATA chunk: the tile `header` (one tile of the HEAD's grid) and its payload,
    /// a complete stand-alone encoding by the HEAD's codec.
    pub fn write_data(&mut self, header: &DataHeader, payload: &[u8]) -> Result<()> {
        let key = header.grid_key(&self.head)?;
        if !self.written.insert(key) {
            return Err(Error::invalid(format!(
                "the tile at ({}, {}) of frame {} was already written",
                header.x, header.y, header.frame
            )));
        }
        self.index.push(IndexEntry { offset: self.offset, frame: header.frame, x: header.x, y: header.y });
        self.chunk(format::DATA, &[&header.to_bytes(), payload])
    }

    /// Writes an ancillary chunk of a type this crate does not define (first letter lower case,
    /// all four ASCII letters), which readers that do not know it skip.
    pub fn write_private(&mut self, chunk_type: [u8; 4], payload: &[u8]) -> Result<()> {
        if !chunk_type[0].is_ascii_lowercase() || !chunk_type.iter().all(u8::is_ascii_alphabetic) {
            return Err(Error::invalid(format!(
                "private chunk type '{}' must be four ASCII letters starting lower case",
                format::type_name(chunk_type)
            )));
        }
        self.chunk(chunk_type, &[payload])
    }

    /// The output written so far (for a writer into a buffer that is passed on as it fills).
    pub(crate) fn output_mut(&mut self) -> &mut W {
        &mut self.out
    }

    /// Writes INDX and END and returns the output. Fails if a tile of a frame is missing.
    pub fn finish(mut self) -> Result<W> {
        let expected = self.head.total_tiles();
        if self.written.len() as u64 != expected {
            return Err(Error::invalid(format!(
                "{} of the {expected} tiles ({} frames x {} tiles) were written",
                self.written.len(),
                self.head.frames,
                self.head.tiles_per_frame()
            )));
        }
        let index_offset = self.offset;
        self.chunk(format::INDX, &[&format::index_bytes(&self.index)])?;
        self.chunk(format::END, &[&index_offset.to_be_bytes()])?;
        self.out.flush()?;
        Ok(self.out)
    }

    fn chunk(&mut self, chunk_type: [u8; 4], parts: &[&[u8]]) -> Result<()> {
        let len: usize = parts.iter().map(|p| p.len()).sum();
        let len = u32::try_from(len).ok().filter(|&l| l <= MAX_CHUNK_LEN).ok_or_else(|| {
            Error::invalid(format!(
                "{} chunk payload of {len} bytes exceeds the {MAX_CHUNK_LEN}-byte limit (use smaller tiles)",
                format::type_name(chunk_type)
            ))
        })?;
        let mut crc = Crc32c::new();
        crc.update(&chunk_type);
        self.out.write_all(&len.to_be_bytes())?;
        self.out.write_all(&chunk_type)?;
        for p in parts {
            crc.update(p);
            self.out.write_all(p)?;
        }
        self.out.write_all(&crc.finish().to_be_bytes())?;
        self.offset += u64::from(len) + format::CHUNK_OVERHEAD as u64;
        Ok(())
    }
}
