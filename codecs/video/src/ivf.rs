//! IVF, the minimal frame container of libvpx/libaom that FFmpeg and dav1d read.
//!
//! Layout (all little-endian): a 32-byte file header — `DKIF`, version (u16, 0), header length
//! (u16, 32), FourCC (`AV01`), width and height (u16 each), the time base as a rate
//! (denominator, u32) and a scale (numerator, u32), the frame count (u32) and 4 unused bytes —
//! then frames, each a 12-byte header (payload size u32, presentation time u64 in time-base
//! units) and the payload: for AV1 one temporal unit of OBUs.
//!
//! The reader borrows frames out of the input and allocates nothing per frame, so its memory
//! does not depend on what the file declares; sizes it cannot honour are errors, never panics.

use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::{Error, Limits, Result};
use std::io::Write;

/// The four bytes every IVF file starts with.
pub const SIGNATURE: [u8; 4] = *b"DKIF";
/// The FourCC of an AV1 stream.
pub const FOURCC_AV1: [u8; 4] = *b"AV01";
/// Bytes of the file header as this writer produces it.
pub const FILE_HEADER_LEN: usize = 32;
/// Bytes of each frame header.
pub const FRAME_HEADER_LEN: usize = 12;

/// The IVF file header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IvfHeader {
    /// Codec FourCC, `AV01` for AV1.
    pub fourcc: [u8; 4],
    /// Frame width in pixels (advisory: the bitstream's own header is authoritative).
    pub width: u16,
    /// Frame height in pixels.
    pub height: u16,
    /// Time base denominator: ticks per second (25 for 25 fps with `timebase_num` 1).
    pub timebase_den: u32,
    /// Time base numerator.
    pub timebase_num: u32,
    /// Frames in the file; 0 when the writer did not know (readers must not rely on it).
    pub frame_count: u32,
}

impl IvfHeader {
    /// An AV1 header for frames of `width` × `height` at `fps` frames per second (whole).
    pub fn av1(width: u16, height: u16, fps: u32, frame_count: u32) -> Self {
        IvfHeader { fourcc: FOURCC_AV1, width, height, timebase_den: fps.max(1), timebase_num: 1, frame_count }
    }

    /// The 32 header bytes.
    pub fn to_bytes(&self) -> [u8; FILE_HEADER_LEN] {
        let mut b = [0u8; FILE_HEADER_LEN];
        b[0..4].copy_from_slice(&SIGNATURE);
        b[4..6].copy_from_slice(&0u16.to_le_bytes());
        b[6..8].copy_from_slice(&(FILE_HEADER_LEN as u16).to_le_bytes());
        b[8..12].copy_from_slice(&self.fourcc);
        b[12..14].copy_from_slice(&self.width.to_le_bytes());
        b[14..16].copy_from_slice(&self.height.to_le_bytes());
        b[16..20].copy_from_slice(&self.timebase_den.to_le_bytes());
        b[20..24].copy_from_slice(&self.timebase_num.to_le_bytes());
        b[24..28].copy_from_slice(&self.frame_count.to_le_bytes());
        b
    }
}

/// Writes an IVF file frame by frame to any [`Write`].
pub struct IvfWriter<W: Write> {
    out: W,
    frames: u64,
    bytes: u64,
}

impl<W: Write> IvfWriter<W> {
    /// Writes the file header and returns a writer for the frames.
    pub fn new(mut out: W, header: &IvfHeader) -> Result<Self> {
        out.write_all(&header.to_bytes()).map_err(Error::Io)?;
        Ok(IvfWriter { out, frames: 0, bytes: FILE_HEADER_LEN as u64 })
    }

    /// Writes one frame (for AV1, one temporal unit) with presentation time `pts`.
    pub fn write_frame(&mut self, pts: u64, payload: &[u8]) -> Result<()> {
        let size = u32::try_from(payload.len())
            .map_err(|_| Error::unsupported(format!("an IVF frame of {} bytes (more than 4 GiB)", payload.len())))?;
        let mut head = [0u8; FRAME_HEADER_LEN];
        head[0..4].copy_from_slice(&size.to_le_bytes());
        head[4..12].copy_from_slice(&pts.to_le_bytes());
        self.out.write_all(&head).map_err(Error::Io)?;
        self.out.write_all(payload).map_err(Error::Io)?;
        self.frames += 1;
        self.bytes += (FRAME_HEADER_LEN + payload.len()) as u64;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.frames
    }

    /// Bytes written so far, the file header included.
    pub fn bytes_written(&self) -> u64 {
        self.bytes
    }

    /// Flushes and returns the output.
    pub fn finish(mut self) -> Result<W> {
        self.out.flush().map_err(Error::Io)?;
        Ok(self.out)
    }
}

/// Sets the frame count of an IVF file held in memory (a writer that did not know it up front).
pub fn patch_frame_count(file: &mut [u8], frames: u32) -> Result<()> {
    let field = file.get_mut(24..28).ok_or_else(|| Error::truncated("the IVF file header"))?;
    field.copy_from_slice(&frames.to_le_bytes());
    Ok(())
}

/// One frame of an IVF file, borrowed from the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IvfFrame<'a> {
    /// Presentation time in time-base units.
    pub pts: u64,
    /// The payload (for AV1, one temporal unit of OBUs).
    pub data: &'a [u8],
}

/// Reads an IVF file held in memory, frame by frame.
#[derive(Clone, Debug)]
pub struct IvfReader<'a> {
    header: IvfHeader,
    reader: ByteReader<'a>,
    index: u64,
    max_frame_bytes: u64,
}

impl<'a> IvfReader<'a> {
    /// Parses the file header. The declared frame size is checked against `limits` (it is
    /// advisory, so 0 is accepted), and no frame may be larger than `limits.max_alloc_bytes`.
    pub fn new(data: &'a [u8], limits: &Limits) -> Result<Self> {
        let mut r = ByteReader::le(data);
        let signature: [u8; 4] = r.array("the IVF signature")?;
        if signature != SIGNATURE {
            return Err(Error::invalid("not an IVF file: it does not start with DKIF"));
        }
        let version = r.u16("the IVF version")?;
        if version != 0 {
            return Err(Error::unsupported(format!("IVF version {version} (only version 0 exists)")));
        }
        let header_len = r.u16("the IVF header length")?;
        if (header_len as usize) < FILE_HEADER_LEN {
            return Err(Error::invalid(format!("IVF header length {header_len} is shorter than 32 bytes")));
        }
        let fourcc = r.array("the IVF FourCC")?;
        let width = r.u16("the IVF frame width")?;
        let height = r.u16("the IVF frame height")?;
        let timebase_den = r.u32("the IVF time base")?;
        let timebase_num = r.u32("the IVF time base")?;
        let frame_count = r.u32("the IVF frame count")?;
        // The unused word, and whatever a longer header holds.
        r.skip(header_len as u64 - 28, "the IVF file header")?;
        if width != 0 && height != 0 {
            limits.check_dimensions(width.into(), height.into())?;
        }
        let header = IvfHeader { fourcc, width, height, timebase_den, timebase_num, frame_count };
        Ok(IvfReader { header, reader: r, index: 0, max_frame_bytes: limits.max_alloc_bytes })
    }

    /// The file header.
    pub fn header(&self) -> &IvfHeader {
        &self.header
    }

    /// True when the stream is AV1 (FourCC `AV01`).
    pub fn is_av1(&self) -> bool {
        self.header.fourcc == FOURCC_AV1
    }

    /// The next frame, `None` at the clean end of the file, an error for a frame cut short or
    /// larger than the limits allow.
    pub fn next_frame(&mut self) -> Result<Option<IvfFrame<'a>>> {
        if self.reader.remaining() == 0 {
            return Ok(None);
        }
        let index = self.index;
        let size = self.reader.u32(format_args!("the header of IVF frame {index}"))? as u64;
        let pts = self.reader.u64(format_args!("the header of IVF frame {index}"))?;
        if size > self.max_frame_bytes {
            return Err(Error::limit(format!(
                "IVF frame {index} declares {size} bytes, more than the limit of {}",
                self.max_frame_bytes
            )));
        }
        let data = self.reader.bytes(size, format_args!("IVF frame {index}"))?;
        self.index += 1;
        Ok(Some(IvfFrame { pts, data }))
    }

    /// All remaining frames, stopping at the first error.
    pub fn frames(mut self) -> impl Iterator<Item = Result<IvfFrame<'a>>> {
        let mut failed = false;
        std::iter::from_fn(move || {
            if failed {
                return None;
            }
            let next = self.next_frame().transpose();
            failed = matches!(next, Some(Err(_)));
            next
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_file() -> Vec<u8> {
        let mut w = IvfWriter::new(Vec::new(), &IvfHeader::av1(96, 64, 25, 2)).unwrap();
        w.write_frame(0, &[0x12, 0x00, 0xAA]).unwrap();
        w.write_frame(1, &[0x12, 0x00]).unwrap();
        w.finish().unwrap()
    }

    #[test]
    fn writes_the_layout_ffmpeg_writes() {
        let file = sample_file();
        // VIDEO-NOTES §5.2: DKIF, version 0, length 32, AV01, w, h, rate 25, scale 1, count.
        assert_eq!(&file[..12], b"DKIF\0\0\x20\0AV01");
        assert_eq!(&file[12..16], &[96, 0, 64, 0]);
        assert_eq!(&file[16..28], &[25, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
        assert_eq!(&file[32..44], &[3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(file.len(), 32 + 12 + 3 + 12 + 2);
    }

    #[test]
    fn reads_back_what_it_wrote() {
        let file = sample_file();
        let r = IvfReader::new(&file, &Limits::default()).unwrap();
        assert_eq!(*r.header(), IvfHeader::av1(96, 64, 25, 2));
        assert!(r.is_av1());
        let frames: Vec<_> = r.frames().collect::<Result<_>>().unwrap();
        assert_eq!(frames, [IvfFrame { pts: 0, data: &[0x12, 0, 0xAA] }, IvfFrame { pts: 1, data: &[0x12, 0] }]);
    }

    #[test]
    fn every_truncation_is_an_error_or_a_clean_end() {
        let file = sample_file();
        for len in 0..file.len() {
            let cut = &file[..len];
            match IvfReader::new(cut, &Limits::default()) {
                Err(e) => assert!(len < 32, "{len}: {e}"),
                Ok(r) => {
                    let results: Vec<_> = r.frames().collect();
                    let clean_end = len == 32 || len == 32 + 15;
                    assert_eq!(results.iter().any(|f| f.is_err()), !clean_end, "cut at {len}");
                }
            }
        }
    }

    #[test]
    fn garbage_and_oversized_frames_are_errors() {
        assert!(matches!(
            IvfReader::new(b"RIFF0000000000000000000000000000", &Limits::default()),
            Err(Error::Invalid { .. })
        ));
        let mut file = sample_file();
        file[6] = 4; // header length below 32
        assert!(IvfReader::new(&file, &Limits::default()).is_err());
        let mut file = sample_file();
        file[32..36].copy_from_slice(&u32::MAX.to_le_bytes());
        let limits = Limits::default().with_max_alloc_bytes(1 << 20);
        let mut r = IvfReader::new(&file, &limits).unwrap();
        assert!(matches!(r.next_frame(), Err(Error::LimitExceeded { .. })));
        let mut r = IvfReader::new(&file, &Limits::none()).unwrap();
        assert!(matches!(r.next_frame(), Err(Error::Truncated { .. })));
        // A header declaring a frame larger than the limits is refused before any frame.
        let mut file = sample_file();
        file[12..14].copy_from_slice(&u16::MAX.to_le_bytes());
        assert!(IvfReader::new(&file, &Limits::fuzzing()).is_err());
        let mut count = sample_file();
        patch_frame_count(&mut count, 7).unwrap();
        assert_eq!(IvfReader::new(&count, &Limits::default()).unwrap().header().frame_count, 7);
        assert!(patch_frame_count(&mut [0u8; 10], 1).is_err());
    }
}
