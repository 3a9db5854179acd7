//! Random access to a file that is not in memory: END (at the end of the file) gives the INDX
//! offset, INDX gives every tile's offset, and one tile is read, CRC-checked, on demand.

use crate::crc::Crc32c;
use crate::format::{
    self, type_name, DataHeader, Head, IndexEntry, CHUNK_OVERHEAD, HEAD_LEN, MAX_CHUNK_LEN, SIGNATURE,
};
use crate::reader::in_chunk;
use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::{Error, Limits, Result};
use std::io::{Read, Seek, SeekFrom};

/// Reads single tiles of a `.hdrc` file from any [`Read`] + [`Seek`] (a file on disk) without
/// reading the rest: [`SeekReader::new`] reads the signature, HEAD, the END chunk at the end
/// of the file and the INDX it points to, and checks the index against the HEAD's tile grid;
/// [`SeekReader::read_tile`] then reads one DATA chunk and checks its CRC and rectangle.
///
/// Unlike [`Reader`](crate::Reader) it does not see the other chunks (COLR, HDRM, META) and
/// does not check the CRC of tiles it is not asked for.
pub struct SeekReader<R> {
    inner: R,
    head: Head,
    index: Vec<IndexEntry>,
    /// (grid key, position in `index`), sorted by key.
    grid: Vec<(u64, usize)>,
    /// Where INDX starts: every DATA chunk ends before it.
    indx_at: u64,
    limits: Limits,
}

impl<R: Read + Seek> SeekReader<R> {
    /// Opens a file: reads and checks its signature, HEAD, END and INDX.
    pub fn new(mut inner: R, limits: &Limits) -> Result<Self> {
        let file_len = inner.seek(SeekFrom::End(0))?;
        let mut sig = [0u8; 8];
        inner.seek(SeekFrom::Start(0))?;
        let n = read_up_to(&mut inner, &mut sig)?;
        format::check_signature(&sig[..n])?;
        let head_at = SIGNATURE.len() as u64;
        let (ty, payload) = read_chunk(&mut inner, head_at, file_len, Some(HEAD_LEN), limits, "HEAD")?;
        let ctx = format!("HEAD chunk #0 at offset {head_at}");
        if ty != format::HEAD {
            return Err(Error::invalid(format!("{ctx}: the first chunk is '{}'", type_name(ty))));
        }
        let head = Head::parse(&payload).map_err(|e| in_chunk(&ctx, e))?;
        let data_start = head_at + (CHUNK_OVERHEAD + HEAD_LEN) as u64;
        format::check_head(&head, limits, file_len - data_start).map_err(|e| in_chunk(&ctx, e))?;

        let end_at = file_len
            .checked_sub((CHUNK_OVERHEAD + 8) as u64)
            .filter(|&e| e >= data_start)
            .ok_or_else(|| Error::truncated("the END chunk (the file is too short)"))?;
        let (ty, payload) = read_chunk(&mut inner, end_at, file_len, Some(8), limits, "END ")?;
        if ty != format::END {
            return Err(Error::invalid(format!(
                "the file does not end with an END chunk that locates the index (found '{}' at offset {end_at})",
                type_name(ty)
            )));
        }
        let indx_at = ByteReader::be(&payload).u64("the END chunk's index offset")?;
        let ctx = format!("INDX chunk #0 at offset {indx_at}");
        if indx_at < data_start || indx_at >= end_at {
            return Err(Error::invalid(format!(
                "END chunk at offset {end_at}: INDX offset {indx_at} is outside the file"
            )));
        }
        let (ty, payload) = read_chunk(&mut inner, indx_at, end_at, None, limits, "INDX")?;
        if ty != format::INDX {
            return Err(Error::invalid(format!("{ctx}: the chunk there is '{}'", type_name(ty))));
        }
        let index = format::parse_index(&payload).map_err(|e| in_chunk(&ctx, e))?;
        if index.len() as u64 != head.total_tiles() {
            return Err(Error::invalid(format!("{ctx}: {} entries for {} tiles", index.len(), head.total_tiles())));
        }
        let mut grid = Vec::with_capacity(index.len());
        for (i, e) in index.iter().enumerate() {
            let bad = |what: &str| Error::invalid(format!("{ctx}: entry {i} ({e:?}): {what}"));
            if e.offset < data_start || e.offset >= indx_at {
                return Err(bad("the offset is outside the DATA chunks"));
            }
            if e.x >= head.width || e.y >= head.height || e.x % head.tile_width != 0 || e.y % head.tile_height != 0 {
                return Err(bad("not a tile of the grid"));
            }
            let t = head.tile(e.frame, e.x / head.tile_width, e.y / head.tile_height);
            grid.push((t.grid_key(&head).map_err(|err| bad(&err.to_string()))?, i));
        }
        grid.sort_unstable();
        if grid.windows(2).any(|w| w[0].0 == w[1].0) {
            return Err(Error::invalid(format!("{ctx}: a tile is listed twice")));
        }
        Ok(SeekReader { inner, head, index, grid, indx_at, limits: limits.clone() })
    }

    /// The HEAD chunk.
    pub fn head(&self) -> &Head {
        &self.head
    }

    /// The INDX entries, in file order.
    pub fn index(&self) -> &[IndexEntry] {
        &self.index
    }

    /// Reads the tile at grid position (`column`, `row`) of `frame`: its header and payload.
    pub fn read_tile(&mut self, frame: u32, column: u32, row: u32) -> Result<(DataHeader, Vec<u8>)> {
        let h = self.head;
        if frame >= h.frames || column >= h.tile_columns() || row >= h.tile_rows() {
            return Err(Error::invalid(format!("tile ({column}, {row}) of frame {frame} is outside the file's grid")));
        }
        let want = h.tile(frame, column, row);
        let key = want.grid_key(&h)?;
        // `new` checked that the index lists every tile of the grid exactly once.
        let pos = self.grid.binary_search_by_key(&key, |&(k, _)| k).map_err(|_| Error::invalid("tile not indexed"))?;
        let at = self.index[self.grid[pos].1].offset;
        let ctx = format!("DATA chunk at offset {at}");
        let (ty, mut payload) = read_chunk(&mut self.inner, at, self.indx_at, None, &self.limits, "DATA")?;
        if ty != format::DATA {
            return Err(Error::invalid(format!("{ctx}: the index points at a '{}' chunk", type_name(ty))));
        }
        let (header, _) = DataHeader::parse(&payload).map_err(|e| in_chunk(&ctx, e))?;
        if header != want {
            return Err(Error::invalid(format!("{ctx}: holds {header:?}, the index says {want:?}")));
        }
        payload.drain(..format::DATA_HEADER_LEN);
        Ok((header, payload))
    }
}

/// Reads as many bytes as are there, up to `buf.len()`.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// Reads the chunk at `at`, which must end by `limit` and have at most `max_len` payload bytes;
/// checks its CRC. Returns its type and payload.
fn read_chunk(
    r: &mut (impl Read + Seek),
    at: u64,
    limit: u64,
    expect_len: Option<usize>,
    limits: &Limits,
    what: &str,
) -> Result<([u8; 4], Vec<u8>)> {
    let ctx = format!("{what} chunk at offset {at}");
    let mut hdr = [0u8; 8];
    r.seek(SeekFrom::Start(at))?;
    if limit.saturating_sub(at) < CHUNK_OVERHEAD as u64 || read_up_to(r, &mut hdr)? < 8 {
        return Err(Error::truncated(ctx));
    }
    let mut h = ByteReader::be(&hdr);
    let (len, ty) = (h.u32(&ctx)?, h.array(&ctx)?);
    if expect_len.is_some_and(|e| e as u64 != u64::from(len)) || len > MAX_CHUNK_LEN {
        return Err(Error::invalid(format!("{ctx}: payload length {len}")));
    }
    if at + u64::from(len) + CHUNK_OVERHEAD as u64 > limit {
        return Err(Error::truncated(format!("{ctx} (the chunk needs {} bytes)", u64::from(len) + 12)));
    }
    // `len` fits the file (checked above); it must also fit the caller's allocation limit.
    limits.check_alloc(u64::from(len), &ctx)?;
    let mut rest = vec![0u8; len as usize + 4];
    r.read_exact(&mut rest).map_err(|_| Error::truncated(ctx.clone()))?;
    let mut r = ByteReader::be(&rest);
    let payload = r.bytes(len.into(), &ctx)?;
    let stored = r.u32(&ctx)?;
    let mut c = Crc32c::new();
    c.update(&ty);
    c.update(payload);
    if c.finish() != stored && !cfg!(fuzzing) {
        return Err(Error::invalid(format!("{ctx}: CRC mismatch")));
    }
    rest.truncate(len as usize);
    Ok((ty, rest))
}
