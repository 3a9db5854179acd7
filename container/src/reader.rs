//! The validating reader over a file held in memory.

use crate::crc::Crc32c;
use crate::format::{self, type_name, DataHeader, Head, IndexEntry, MAX_CHUNK_LEN, SIGNATURE};
use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::{ColorInfo, Error, Hdr10Metadata, Limits, Result};

/// One DATA chunk of a file: its tile header and the codec payload, borrowed from the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataRef<'a> {
    /// Frame and rectangle of the tile.
    pub header: DataHeader,
    /// Offset of the chunk (its length field) in the file.
    pub offset: u64,
    /// The stand-alone encoding of the tile by the HEAD's codec.
    pub payload: &'a [u8],
}

/// A validated `.hdrc` file.
///
/// [`Reader::new`] checks everything before returning: the signature, every chunk length
/// against the remaining bytes, every CRC, the HEAD dimensions against [`Limits`] (before any
/// allocation), that the DATA chunks are exactly the tiles of the HEAD's grid (each once, for
/// every frame), that INDX agrees with the DATA chunks, and that END ends the file. Errors name
/// the chunk, e.g. `DATA chunk #3 at offset 1234: CRC mismatch` (chunks are counted per type,
/// from 0).
#[derive(Clone, Debug)]
pub struct Reader<'a> {
    layout: Layout,
    data: Vec<DataRef<'a>>,
}

/// Where a DATA chunk is: its tile, the offset of the chunk (its length field) and the length
/// of its payload (tile header included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DataLoc {
    pub(crate) header: DataHeader,
    pub(crate) offset: u64,
    pub(crate) len: u32,
}

/// What the chunks of a file say, gathered as a reader walks them (in memory or from a
/// stream) and checked once END is met ([`Layout::finish`]).
#[derive(Clone, Debug)]
pub(crate) struct Layout {
    pub(crate) head: Head,
    color: Option<ColorInfo>,
    hdr10: Option<Hdr10Metadata>,
    metadata: Vec<(String, String)>,
    /// Every DATA chunk, in file order.
    pub(crate) data: Vec<DataLoc>,
    /// (grid key, position in `data`), sorted by key once finished: the random-access map.
    grid: Vec<(u64, usize)>,
    index: Option<(u64, Vec<IndexEntry>)>,
    has_index: bool,
}

/// What [`Layout::take`] found: more chunks to come, or END (with the index offset it holds).
pub(crate) enum Step {
    More,
    End(Option<u64>),
}

impl Layout {
    /// The layout of a file whose HEAD is `head`, before any other chunk.
    pub(crate) fn new(head: Head) -> Self {
        Layout {
            head,
            color: None,
            hdr10: None,
            metadata: Vec::new(),
            data: Vec::new(),
            grid: Vec::new(),
            index: None,
            has_index: false,
        }
    }

    /// Takes the chunk after HEAD of type `ty` at `offset` with a payload of `len` bytes, of
    /// which `payload` holds all, or of a DATA chunk at least its tile header (its CRC is the
    /// caller's to check). `ctx` names the chunk in errors.
    pub(crate) fn take(&mut self, ty: [u8; 4], payload: &[u8], offset: u64, len: u32, ctx: &str) -> Result<Step> {
        let dup = || Error::invalid(format!("{ctx}: a second chunk of this type"));
        let parsed = |r: Result<()>| r.map_err(|e| in_chunk(ctx, e));
        match ty {
            format::HEAD => return Err(dup()),
            format::DATA => {
                // Bounds what is kept per chunk by the HEAD's grid (and so by the file's size).
                if self.data.len() as u64 >= self.head.total_tiles() {
                    let tiles = self.head.total_tiles();
                    return Err(Error::invalid(format!("{ctx}: more DATA chunks than the {tiles} tiles of the grid")));
                }
                let (header, _) = DataHeader::parse(payload).map_err(|e| in_chunk(ctx, e))?;
                let key = header.grid_key(&self.head).map_err(|e| in_chunk(ctx, e))?;
                self.grid.push((key, self.data.len()));
                self.data.push(DataLoc { header, offset, len });
            }
            format::COLR if self.color.is_some() => return Err(dup()),
            format::COLR => parsed(format::parse_color(payload).map(|c| self.color = Some(c)))?,
            format::HDRM if self.hdr10.is_some() => return Err(dup()),
            format::HDRM => parsed(format::parse_hdr10(payload).map(|h| self.hdr10 = Some(h)))?,
            format::META if !self.metadata.is_empty() => return Err(dup()),
            format::META => parsed(format::parse_meta(payload).map(|m| self.metadata = m))?,
            format::INDX if self.index.is_some() => return Err(dup()),
            format::INDX => parsed(format::parse_index(payload).map(|i| self.index = Some((offset, i))))?,
            format::END => return end_index_offset_in(payload, ctx).map(Step::End),
            t if t[0].is_ascii_lowercase() => {} // unknown ancillary chunk: skipped
            _ => return Err(Error::unsupported(format!("{ctx}: unknown critical chunk type"))),
        }
        Ok(Step::More)
    }

    /// Once END is met (holding `end_index_offset`): every tile of every frame present exactly
    /// once, and the index (if any) agreeing with the DATA chunks.
    pub(crate) fn finish(&mut self, end_index_offset: Option<u64>) -> Result<()> {
        self.check_tiles()?;
        match (self.index.take(), end_index_offset) {
            (Some((at, entries)), end) => {
                if end.is_some_and(|e| e != at) {
                    return Err(Error::invalid(format!(
                        "END chunk: points at the index at offset {}, but INDX is at offset {at}",
                        end.unwrap_or(0)
                    )));
                }
                let ctx = format!("INDX chunk #0 at offset {at}");
                if entries.len() != self.data.len() {
                    return Err(Error::invalid(format!(
                        "{ctx}: {} entries for {} DATA chunks",
                        entries.len(),
                        self.data.len()
                    )));
                }
                for (i, (e, d)) in entries.iter().zip(&self.data).enumerate() {
                    let actual = IndexEntry { offset: d.offset, frame: d.header.frame, x: d.header.x, y: d.header.y };
                    if *e != actual {
                        return Err(Error::invalid(format!(
                            "{ctx}: entry {i} says {e:?}, the DATA chunk is {actual:?}"
                        )));
                    }
                }
                self.has_index = true;
            }
            (None, Some(e)) => {
                return Err(Error::invalid(format!(
                    "END chunk: points at an index at offset {e}, but there is no INDX"
                )))
            }
            (None, None) => {}
        }
        Ok(())
    }

    /// Every tile of every frame present exactly once.
    fn check_tiles(&mut self) -> Result<()> {
        let h = self.head;
        let expected = h.total_tiles();
        self.grid.sort_unstable();
        for w in self.grid.windows(2) {
            if w[0].0 == w[1].0 {
                let d = &self.data[w[1].1];
                return Err(Error::invalid(format!(
                    "DATA chunk at offset {}: tile ({}, {}) of frame {} appears twice",
                    d.offset, d.header.x, d.header.y, d.header.frame
                )));
            }
        }
        if self.grid.len() as u64 != expected {
            // Keys are unique and below `expected`, so the first gap names a missing tile.
            let missing = self
                .grid
                .iter()
                .enumerate()
                .find(|&(i, &(k, _))| i as u64 != k)
                .map_or(self.grid.len() as u64, |(i, _)| i as u64);
            let per = h.tiles_per_frame();
            let (frame, cell) = (missing / per, missing % per);
            let cols = u64::from(h.tile_columns());
            return Err(Error::invalid(format!(
                "the file has {} of its {expected} tiles; tile ({}, {}) of frame {frame} is missing",
                self.grid.len(),
                cell % cols * u64::from(h.tile_width),
                cell / cols * u64::from(h.tile_height)
            )));
        }
        Ok(())
    }

    /// COLR (or the default: BT.709, 100 nits per unit) with HDRM merged in.
    pub(crate) fn color_info(&self) -> ColorInfo {
        ColorInfo { hdr10: self.hdr10, ..self.color.clone().unwrap_or_default() }
    }

    /// The META pairs.
    pub(crate) fn metadata(&self) -> &[(String, String)] {
        &self.metadata
    }

    /// Positions in `data` of the tiles of `frame` in grid order (row by row), once finished.
    pub(crate) fn frame_positions(&self, frame: u32) -> impl Iterator<Item = usize> + '_ {
        let per = self.head.tiles_per_frame() as usize;
        let start = (frame as usize).saturating_mul(per).min(self.grid.len());
        let end = start.saturating_add(per).min(self.grid.len());
        self.grid[start..end].iter().map(|&(_, i)| i)
    }

    /// The position in `data` of the tile at grid position (`column`, `row`) of `frame`.
    fn position(&self, frame: u32, column: u32, row: u32) -> Option<usize> {
        let h = &self.head;
        if frame >= h.frames || column >= h.tile_columns() || row >= h.tile_rows() {
            return None;
        }
        let key =
            u64::from(frame) * h.tiles_per_frame() + u64::from(row) * u64::from(h.tile_columns()) + u64::from(column);
        let i = self.grid.binary_search_by_key(&key, |&(k, _)| k).ok()?;
        Some(self.grid[i].1)
    }
}

/// Prefixes an error's message with the chunk it concerns, keeping its kind.
pub(crate) fn in_chunk(ctx: &str, e: Error) -> Error {
    match e {
        Error::Truncated { what } => Error::truncated(format!("{ctx}: {what}")),
        Error::Unsupported { what } => Error::unsupported(format!("{ctx}: {what}")),
        Error::LimitExceeded { what } => Error::limit(format!("{ctx}: {what}")),
        Error::Invalid { what } => Error::invalid(format!("{ctx}: {what}")),
        other => Error::invalid(format!("{ctx}: {other}")),
    }
}

/// Chunks seen per type (a map: a file may hold many distinct ancillary types).
#[derive(Default)]
pub(crate) struct Counts {
    per_type: std::collections::HashMap<[u8; 4], usize>,
}

impl Counts {
    /// The 0-based number of this chunk among the chunks of its type.
    pub(crate) fn next(&mut self, t: [u8; 4]) -> usize {
        let n = self.per_type.entry(t).or_insert(0);
        *n += 1;
        *n - 1
    }
}

/// One chunk of a file, its CRC checked.
struct Chunk<'a> {
    ty: [u8; 4],
    payload: &'a [u8],
    /// Offset of the chunk (its length field).
    offset: u64,
    /// "DATA chunk #3 at offset 1234", for messages.
    ctx: String,
}

/// Reads the chunk at the reader's position and moves past it: checks its length against the
/// bytes that remain, its CRC (of a DATA chunk only if `check_data_crc`) and its type's letters.
fn next_chunk<'a>(file: &mut ByteReader<'a>, counts: &mut Counts, check_data_crc: bool) -> Result<Chunk<'a>> {
    let at = file.position();
    let what = format_args!("the chunk header at offset {at} (the file ends before the END chunk)");
    let len = file.u32(what)?;
    let ty: [u8; 4] = file.array(what)?;
    let ctx = format!("{} chunk #{} at offset {at}", type_name(ty), counts.next(ty));
    if len > MAX_CHUNK_LEN {
        return Err(Error::invalid(format!("{ctx}: length {len} exceeds the {MAX_CHUNK_LEN}-byte maximum")));
    }
    let payload = file.bytes(len.into(), format_args!("{ctx} (its {len}-byte payload)"))?;
    let stored = file.u32(format_args!("{ctx} (its CRC)"))?;
    let crc = (check_data_crc || ty != format::DATA).then(|| chunk_crc(ty, payload));
    check_chunk(ty, crc, stored, &ctx)?;
    Ok(Chunk { ty, payload, offset: at, ctx })
}

/// The CRC-32C of a chunk: over its type and payload.
pub(crate) fn chunk_crc(ty: [u8; 4], payload: &[u8]) -> u32 {
    let mut crc = Crc32c::new();
    crc.update(&ty);
    crc.update(payload);
    crc.finish()
}

/// An error unless a chunk's CRC is the `stored` one. Fuzzing builds skip the CRC so that
/// mutations reach the parsers behind it.
pub(crate) fn check_crc(crc: u32, stored: u32) -> Result<()> {
    if crc != stored && !cfg!(fuzzing) {
        return Err(Error::invalid("CRC mismatch"));
    }
    Ok(())
}

/// Checks a chunk's `crc` (if computed) against the `stored` one and its type's letters.
pub(crate) fn check_chunk(ty: [u8; 4], crc: Option<u32>, stored: u32, ctx: &str) -> Result<()> {
    if let Some(crc) = crc {
        check_crc(crc, stored).map_err(|e| in_chunk(ctx, e))?;
    }
    if !ty.iter().all(|b| b.is_ascii_alphabetic() || *b == b' ') || !ty[0].is_ascii_alphabetic() {
        return Err(Error::invalid(format!("{ctx}: the chunk type is not ASCII letters")));
    }
    Ok(())
}

/// The index offset an END chunk's payload may hold.
pub(crate) fn end_index_offset_in(payload: &[u8], ctx: &str) -> Result<Option<u64>> {
    match payload.len() {
        0 => Ok(None),
        8 => ByteReader::be(payload).u64("the index offset").map(Some),
        n => Err(Error::invalid(format!("{ctx}: payload of {n} bytes (expected 0 or 8)"))),
    }
}

/// Parses the first chunk of a file, which must be HEAD.
pub(crate) fn first_head(ty: [u8; 4], payload: &[u8], ctx: &str) -> Result<Head> {
    if ty != format::HEAD {
        return Err(Error::invalid(format!("{ctx}: the first chunk must be HEAD")));
    }
    Head::parse(payload).map_err(|e| in_chunk(ctx, e))
}

/// What [`probe`] reads: HEAD, and the colour COLR and HDRM give the decoded frames.
#[derive(Clone, Debug, PartialEq)]
pub struct HeadInfo {
    /// The HEAD chunk.
    pub head: Head,
    /// COLR (or the default: BT.709, 100 nits per unit) with HDRM merged in, as
    /// [`Reader::color_info`] gives it.
    pub color: ColorInfo,
}

/// Reads HEAD, COLR and HDRM of a `.hdrc` file without touching a tile: walks the chunk
/// headers to END, checking every length and the CRC of every chunk but DATA, and the HEAD's
/// dimensions against the limits (not the byte limit: nothing of the image's size is
/// allocated, and nothing that grows with the number of tiles either). A file that probes
/// can still fail [`Reader::new`] on a damaged tile or a wrong tile grid.
pub fn probe(data: &[u8], limits: &Limits) -> Result<HeadInfo> {
    format::check_signature(data)?;
    let mut file = ByteReader::be(data).at(SIGNATURE.len() as u64);
    let mut counts = Counts::default();
    let Chunk { ty, payload, ctx, .. } = next_chunk(&mut file, &mut counts, false)?;
    let head = first_head(ty, payload, &ctx)?;
    let checked = limits
        .check_dimensions(u64::from(head.width), u64::from(head.height))
        .and_then(|()| format::check_room(&head, file.remaining()));
    checked.map_err(|e| in_chunk(&ctx, e))?;
    let (mut color, mut hdr10) = (None, None);
    loop {
        let Chunk { ty, payload, ctx, .. } = next_chunk(&mut file, &mut counts, false)?;
        let dup = |ctx: &str| Error::invalid(format!("{ctx}: a second chunk of this type"));
        match ty {
            format::HEAD => return Err(dup(&ctx)),
            format::COLR if color.is_some() => return Err(dup(&ctx)),
            format::COLR => color = Some(format::parse_color(payload).map_err(|e| in_chunk(&ctx, e))?),
            format::HDRM if hdr10.is_some() => return Err(dup(&ctx)),
            format::HDRM => hdr10 = Some(format::parse_hdr10(payload).map_err(|e| in_chunk(&ctx, e))?),
            format::END => {
                if file.remaining() != 0 {
                    return Err(Error::invalid(format!("{ctx}: {} bytes follow the END chunk", file.remaining())));
                }
                break;
            }
            format::DATA | format::INDX | format::META => {}
            t if t[0].is_ascii_lowercase() => {}
            _ => return Err(Error::unsupported(format!("{ctx}: unknown critical chunk type"))),
        }
    }
    let color: ColorInfo = color.unwrap_or_default();
    Ok(HeadInfo { head, color: ColorInfo { hdr10, ..color } })
}

impl<'a> Reader<'a> {
    /// Parses and validates a whole file.
    pub fn new(data: &'a [u8], limits: &Limits) -> Result<Self> {
        format::check_signature(data)?;
        Self::chunks(data, limits)
    }

    fn chunks(data: &'a [u8], limits: &Limits) -> Result<Self> {
        let mut file = ByteReader::be(data).at(SIGNATURE.len() as u64);
        let mut counts = Counts::default();
        let Chunk { ty, payload, ctx, .. } = next_chunk(&mut file, &mut counts, true)?;
        let head = first_head(ty, payload, &ctx)?;
        // The whole image must fit the limits before anything of its size is allocated.
        format::check_head(&head, limits, file.remaining()).map_err(|e| in_chunk(&ctx, e))?;
        let mut layout = Layout::new(head);
        let mut refs = Vec::new();
        let end_index_offset = loop {
            let Chunk { ty, payload, offset, ctx } = next_chunk(&mut file, &mut counts, true)?;
            let len = payload.len() as u32;
            match layout.take(ty, payload, offset, len, &ctx)? {
                Step::More if ty == format::DATA => {
                    let header = layout.data[layout.data.len() - 1].header;
                    refs.push(DataRef { header, offset, payload: &payload[format::DATA_HEADER_LEN..] });
                }
                Step::More => {}
                Step::End(end_index_offset) => {
                    if file.remaining() != 0 {
                        return Err(Error::invalid(format!("{ctx}: {} bytes follow the END chunk", file.remaining())));
                    }
                    break end_index_offset;
                }
            }
        };
        layout.finish(end_index_offset)?;
        Ok(Reader { layout, data: refs })
    }

    /// The HEAD chunk.
    pub fn head(&self) -> &Head {
        &self.layout.head
    }

    /// The COLR chunk, if present (its `hdr10` is always `None`: see [`Reader::hdr10`]).
    pub fn color(&self) -> Option<&ColorInfo> {
        self.layout.color.as_ref()
    }

    /// The HDRM chunk, if present.
    pub fn hdr10(&self) -> Option<&Hdr10Metadata> {
        self.layout.hdr10.as_ref()
    }

    /// COLR (or the default: BT.709, 100 nits per unit) with HDRM merged in.
    pub fn color_info(&self) -> ColorInfo {
        self.layout.color_info()
    }

    /// The META pairs (empty without a META chunk).
    pub fn metadata(&self) -> &[(String, String)] {
        self.layout.metadata()
    }

    /// Every DATA chunk, in file order.
    pub fn data_chunks(&self) -> &[DataRef<'a>] {
        &self.data
    }

    /// True if the file had an INDX chunk (it then agreed with the DATA chunks).
    pub fn has_index(&self) -> bool {
        self.layout.has_index
    }

    /// Random access: the tile at grid position (`column`, `row`) of `frame`.
    pub fn tile(&self, frame: u32, column: u32, row: u32) -> Option<&DataRef<'a>> {
        self.layout.position(frame, column, row).map(|i| &self.data[i])
    }

    /// The tiles of `frame` in grid order (row by row).
    pub fn frame_tiles(&self, frame: u32) -> impl Iterator<Item = &DataRef<'a>> + '_ {
        self.layout.frame_positions(frame).map(|i| &self.data[i])
    }
}
