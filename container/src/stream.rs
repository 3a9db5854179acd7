//! A `.hdrc` file read from a stream (a file on disk) instead of bytes in memory: the chunk
//! structure is read and checked first (every chunk but the DATA chunks whole and CRC-checked;
//! of each DATA chunk its tile header), then each DATA chunk is read when its tile is decoded,
//! its CRC checked as it is read. The file is never held whole.

use crate::crc::Crc32c;
use crate::format::{self, type_name, DataHeader, CHUNK_OVERHEAD, DATA_HEADER_LEN, MAX_CHUNK_LEN, SIGNATURE};
use crate::reader::{check_chunk, check_crc, chunk_crc, first_head, in_chunk, Counts, DataLoc, Layout, Step};
use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::sink::RowSink;
use hdrcodec_core::{Allocation, DecodeOptions, Error, ImageCodec, Limits, ReadSeek, Result};
use std::io::{Read, Seek, SeekFrom};

/// A `.hdrc` file in a stream, its structure read and checked ([`StreamFile::open`]).
pub(crate) struct StreamFile<'r> {
    src: Source<'r>,
    /// What the chunks say, checked as [`Reader::new`](crate::Reader::new) checks it.
    pub(crate) layout: Layout,
    /// The charge for what `layout` keeps per tile.
    _index_charge: Allocation,
}

/// The stream a file is read from.
struct Source<'r> {
    input: &'r mut dyn ReadSeek,
    /// Where the file starts in `input` (offsets in the file count from here).
    base: u64,
    /// The file's length.
    len: u64,
}

/// A chunk header read from the stream, with its payload (of a DATA chunk, its tile header).
struct Chunk {
    ty: [u8; 4],
    payload: Vec<u8>,
    offset: u64,
    len: u32,
    ctx: String,
}

/// [`probe`](crate::probe) from a stream (a file, from its position): the file's structure is
/// read and checked as [`StreamFile::open`] reads it (every chunk but DATA, of each DATA chunk
/// its tile header), not a tile, and HEAD with COLR and HDRM is returned. It checks what
/// decoding checks before the first tile (the tile grid and the index, too), so a file that
/// `probe` accepts with a damaged tile header is refused here.
pub(crate) fn probe(input: &mut dyn ReadSeek, limits: &Limits) -> Result<crate::HeadInfo> {
    let file = StreamFile::open(input, limits)?;
    Ok(crate::HeadInfo { head: file.layout.head, color: file.layout.color_info() })
}

impl<'r> StreamFile<'r> {
    /// Reads the file that starts at `input`'s position: its signature, every chunk's header,
    /// every chunk but DATA whole (each checked against `limits` before it is read, and its
    /// CRC), and the tile header of every DATA chunk; checks the HEAD against `limits`, the
    /// tile grid, the index and that END ends the file, as [`Reader::new`](crate::Reader::new)
    /// does. What it does not check is the DATA chunks' CRCs: [`StreamFile::read_tile`] and
    /// [`StreamFile::decode_tile_rows`] check each as they read it.
    pub(crate) fn open(input: &'r mut dyn ReadSeek, limits: &Limits) -> Result<Self> {
        let (base, len) = hdrcodec_core::remaining_len(input)?;
        let mut src = Source { input, base, len };
        let mut sig = vec![0; SIGNATURE.len().min(len as usize)];
        src.read_at(0, &mut sig)?;
        format::check_signature(&sig)?;
        let mut counts = Counts::default();
        let mut at = SIGNATURE.len() as u64;
        let Chunk { ty, payload, ctx, .. } = src.next_chunk(&mut at, &mut counts, limits)?;
        let head = first_head(ty, &payload, &ctx)?;
        // The whole image must fit the limits before anything of its size is allocated.
        format::check_head(&head, limits, len - at).map_err(|e| in_chunk(&ctx, e))?;
        // What is kept of each tile's chunk while the file is decoded (at most one per tile).
        let per_tile = (std::mem::size_of::<DataLoc>() + std::mem::size_of::<(u64, usize)>()) as u64;
        let index_charge = limits.charge(head.total_tiles().saturating_mul(per_tile), "the file's tile index")?;
        let mut layout = Layout::new(head);
        let end_index_offset = loop {
            let Chunk { ty, payload, offset, len: chunk_len, ctx } = src.next_chunk(&mut at, &mut counts, limits)?;
            let step = layout.take(ty, &payload, offset, chunk_len, &ctx);
            if step.is_err() && ty == format::DATA && !src.data_crc_ok(offset, chunk_len)? {
                // A tile header that makes no sense is damage, and the CRC says so.
                return Err(Error::invalid(format!("{ctx}: CRC mismatch")));
            }
            if let Step::End(end_index_offset) = step? {
                if at != len {
                    return Err(Error::invalid(format!("{ctx}: {} bytes follow the END chunk", len - at)));
                }
                break end_index_offset;
            }
        };
        if let Err(e) = layout.finish(end_index_offset) {
            // Tiles missing or twice, or an index that disagrees: a damaged tile header is the
            // likelier story, which the DATA chunks' CRCs tell.
            for (i, d) in layout.data.iter().enumerate() {
                if !src.data_crc_ok(d.offset, d.len)? {
                    return Err(Error::invalid(format!("DATA chunk #{i} at offset {}: CRC mismatch", d.offset)));
                }
            }
            return Err(e);
        }
        Ok(StreamFile { src, layout, _index_charge: index_charge })
    }

    /// The payload of the DATA chunk at `loc` (its tile header left out), read whole and its
    /// CRC checked before it is returned. Errors name no chunk: the caller knows which it asked
    /// for.
    pub(crate) fn read_tile(&mut self, loc: &DataLoc) -> Result<Vec<u8>> {
        let mut crc = self.src.start_tile(loc)?;
        let mut payload = vec![0; loc.len as usize - DATA_HEADER_LEN + 4];
        self.src.read_at(loc.offset + (8 + DATA_HEADER_LEN) as u64, &mut payload)?;
        let n = payload.len() - 4;
        let stored = u32::from_be_bytes([payload[n], payload[n + 1], payload[n + 2], payload[n + 3]]);
        payload.truncate(n);
        crc.update(&payload);
        check_crc(crc.finish(), stored)?;
        Ok(payload)
    }

    /// Decodes the payload of the DATA chunk at `loc` into `sink` with `codec`'s
    /// [`decode_rows_from`](ImageCodec::decode_rows_from), reading it from the file as the codec
    /// asks for it (a band at a time for the codecs that can) and passing every byte through the
    /// chunk's CRC the first time it is read. Once the codec is done, the bytes it did not read
    /// go through the CRC too, and the CRC is checked: a mismatch is the error, whatever the
    /// codec said, so that rows it delivered from a damaged chunk are never a result. Errors
    /// name no chunk: the caller knows which it asked for.
    pub(crate) fn decode_tile_rows(
        &mut self,
        loc: &DataLoc,
        codec: &dyn ImageCodec,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        let crc = self.src.start_tile(loc)?;
        let start = self.src.base + loc.offset + (8 + DATA_HEADER_LEN) as u64;
        let len = u64::from(loc.len) - DATA_HEADER_LEN as u64;
        let mut window = CrcWindow { input: &mut *self.src.input, start, len, pos: 0, crc, checked: 0 };
        let decoded = codec.decode_rows_from(&mut window, options, sink);
        let crc = window.finish()?;
        let mut stored = [0; 4];
        self.src.read_at(loc.offset + 8 + u64::from(loc.len), &mut stored)?;
        check_crc(crc, u32::from_be_bytes(stored))?;
        decoded
    }
}

impl Source<'_> {
    /// Reads `out.len()` bytes at `offset` in the file.
    fn read_at(&mut self, offset: u64, out: &mut [u8]) -> Result<()> {
        hdrcodec_core::read_exact_at(self.input, self.base + offset, out, "the .hdrc file")
    }

    /// Reads the chunk at `*at` and moves `*at` past it: its length checked against the bytes
    /// that remain, then its payload and CRC (checked), except for a DATA chunk, of which only
    /// the tile header is read.
    fn next_chunk(&mut self, at: &mut u64, counts: &mut Counts, limits: &Limits) -> Result<Chunk> {
        let offset = *at;
        let rest = self.len - offset;
        if rest < 8 {
            return Err(Error::truncated(format!(
                "the chunk header at offset {offset} (the file ends before the END chunk)"
            )));
        }
        let mut head = [0; 8];
        self.read_at(offset, &mut head)?;
        let mut h = ByteReader::be(&head);
        let (len, ty) = (h.u32("the chunk length")?, h.array::<4>("the chunk type")?);
        let ctx = format!("{} chunk #{} at offset {offset}", type_name(ty), counts.next(ty));
        if len > MAX_CHUNK_LEN {
            return Err(Error::invalid(format!("{ctx}: length {len} exceeds the {MAX_CHUNK_LEN}-byte maximum")));
        }
        if u64::from(len) > rest - 8 {
            return Err(Error::truncated(format!("{ctx} (its {len}-byte payload)")));
        }
        if u64::from(len) + 4 > rest - 8 {
            return Err(Error::truncated(format!("{ctx} (its CRC)")));
        }
        let payload = if ty == format::DATA {
            let mut tile = vec![0; (len as usize).min(DATA_HEADER_LEN)];
            self.read_at(offset + 8, &mut tile)?;
            check_chunk(ty, None, 0, &ctx)?;
            tile
        } else {
            limits.check_alloc(u64::from(len), &ctx)?;
            let mut payload = vec![0; len as usize + 4];
            self.read_at(offset + 8, &mut payload)?;
            let stored = ByteReader::be(&payload[len as usize..]).u32("the CRC")?;
            payload.truncate(len as usize);
            check_chunk(ty, Some(chunk_crc(ty, &payload)), stored, &ctx)?;
            payload
        };
        *at = offset + CHUNK_OVERHEAD as u64 + u64::from(len);
        Ok(Chunk { ty, payload, offset, len, ctx })
    }

    /// Whether the DATA chunk at `offset` with a payload of `len` bytes has the CRC it stores,
    /// read through the CRC a block at a time (holding nothing of the chunk's size).
    fn data_crc_ok(&mut self, offset: u64, len: u32) -> Result<bool> {
        let mut crc = Crc32c::new();
        crc.update(&format::DATA);
        let start = self.base + offset + 8;
        let window = CrcWindow { input: &mut *self.input, start, len: u64::from(len), pos: 0, crc, checked: 0 };
        let crc = window.finish()?;
        let mut stored = [0; 4];
        self.read_at(offset + 8 + u64::from(len), &mut stored)?;
        Ok(check_crc(crc, u32::from_be_bytes(stored)).is_ok())
    }

    /// The tile header of the DATA chunk at `loc`, read again, and the CRC of the chunk's type
    /// and tile header: where reading its payload starts.
    fn start_tile(&mut self, loc: &DataLoc) -> Result<Crc32c> {
        let mut header = [0; DATA_HEADER_LEN];
        self.read_at(loc.offset + 8, &mut header)?;
        if DataHeader::parse(&header)?.0 != loc.header {
            return Err(Error::invalid("the tile header changed while the file was read"));
        }
        let mut crc = Crc32c::new();
        crc.update(&format::DATA);
        crc.update(&header);
        Ok(crc)
    }
}

/// The payload of one DATA chunk as a stream of its own (positions count from the payload's
/// first byte; it ends where the payload ends), whose bytes go through the chunk's CRC the
/// first time they are read, in order: a read beyond the bytes checked so far reads the gap
/// through the CRC first. [`CrcWindow::finish`] reads the rest and returns the CRC.
struct CrcWindow<'w> {
    input: &'w mut dyn ReadSeek,
    /// Where the payload starts in `input`.
    start: u64,
    len: u64,
    pos: u64,
    crc: Crc32c,
    /// Bytes `0..checked` of the payload have gone through `crc`.
    checked: u64,
}

impl CrcWindow<'_> {
    /// Reads bytes `checked..to` through the CRC.
    fn check_to(&mut self, to: u64) -> std::io::Result<()> {
        let mut buf = [0; 16 << 10];
        self.input.seek(SeekFrom::Start(self.start + self.checked))?;
        while self.checked < to {
            let n = (to - self.checked).min(buf.len() as u64) as usize;
            self.input.read_exact(&mut buf[..n])?;
            self.crc.update(&buf[..n]);
            self.checked += n as u64;
        }
        Ok(())
    }

    /// Reads what was not read through the CRC and returns the CRC of the whole chunk.
    fn finish(mut self) -> Result<u32> {
        self.check_to(self.len)?;
        Ok(self.crc.finish())
    }
}

impl Read for CrcWindow<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.pos >= self.len || buf.is_empty() {
            return Ok(0);
        }
        if self.pos > self.checked {
            self.check_to(self.pos)?;
        }
        let want = (self.len - self.pos).min(buf.len() as u64) as usize;
        self.input.seek(SeekFrom::Start(self.start + self.pos))?;
        let n = self.input.read(&mut buf[..want])?;
        let end = self.pos + n as u64;
        if end > self.checked {
            // `pos <= checked` here: the bytes past `checked` are new to the CRC.
            self.crc.update(&buf[(self.checked - self.pos) as usize..n]);
            self.checked = end;
        }
        self.pos = end;
        Ok(n)
    }
}

impl Seek for CrcWindow<'_> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        let to = match pos {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.len.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        let to = to.ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "a seek before the start of a DATA chunk's payload")
        })?;
        self.pos = to;
        Ok(to)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// Reads and seeks in any order still pass every byte through the CRC exactly once, in
    /// order: the CRC is that of the whole payload.
    #[test]
    fn the_window_crc_covers_the_payload_whatever_the_reading_order() {
        let file: Vec<u8> = (0..70_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let (start, len) = (100u64, 60_000u64);
        let payload = &file[start as usize..(start + len) as usize];
        let want = crate::crc32c(payload);
        // (seek to, read this many bytes) in the order a payload codec might ask.
        let orders: [&[(u64, usize)]; 4] = [
            &[],
            &[(0, 60_000)],
            &[(59_990, 100), (10, 5), (0, 20_000), (40_000, 3)],
            &[(30_000, 10), (29_000, 2_000), (0, 1), (70_000, 8)],
        ];
        for reads in orders {
            let mut input = Cursor::new(file.clone());
            let mut w = CrcWindow { input: &mut input, start, len, pos: 0, crc: Crc32c::new(), checked: 0 };
            for &(at, n) in reads {
                assert_eq!(w.seek(SeekFrom::Start(at)).unwrap(), at);
                let mut buf = vec![0; n];
                let mut got = 0;
                while got < n {
                    match w.read(&mut buf[got..]).unwrap() {
                        0 => break,
                        k => got += k,
                    }
                }
                let end = (at as usize + got).min(len as usize);
                assert_eq!(&buf[..got], &payload[(at as usize).min(end)..end], "{reads:?}");
            }
            assert_eq!(w.seek(SeekFrom::End(-5)).unwrap(), len - 5);
            assert!(w.seek(SeekFrom::Current(-(len as i64))).is_err(), "before the start");
            assert_eq!(w.finish().unwrap(), want, "{reads:?}");
        }
    }
}
