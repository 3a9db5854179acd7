//! AV1 in Matroska (`.mkv`) or WebM (`.webm`), with the colour elements: an EBML writer of our
//! own for one video track.
//!
//! Element IDs and value meanings are transcribed from the Matroska element table
//! (`ebml_matroska.xml` of the IETF CELLAR specification, RFC 9559 §5.1) and the EBML header
//! (RFC 8794 §11.2); the AV1 mapping (`codec/av1.md` of the same specification: `CodecID`
//! `V_AV1`, `CodecPrivate` the `AV1CodecConfigurationRecord` with the sequence header OBU, a
//! Block holding one temporal unit without its temporal delimiter) from that document.
//!
//! Layout: the EBML header; `Segment` (size patched at the end) with `Info` (millisecond
//! timestamps, `Duration` patched at the end), `Tracks` written when the first temporal unit
//! comes (its sequence header and HDR metadata OBUs give `CodecPrivate` and `Colour`), then one
//! `Cluster` per key frame (and at least every 30 s), each frame a `SimpleBlock`. Sizes are
//! 8-byte EBML numbers, so that a size can be patched in place. The `Colour` element holds the
//! sequence header's H.273 triple, range, subsampling and siting, `MaxCLL`/`MaxFALL` from
//! HDR_CLL and `MasteringMetadata` (floats, cd/m²) from HDR_MDCV; an L_p u'v' stream, which has
//! no colour description, gets no `Colour`.

use crate::mp4::{av1_config_record, StreamFacts};
use crate::obu::chroma_sample_position;
use hdrcodec_core::{Error, MasteringDisplay, Result};
use std::io::{Seek, SeekFrom, Write};

/// Matroska element IDs (RFC 9559 §5.1; EBML header RFC 8794 §11.2), with their marker bits.
mod id {
    pub const EBML: u32 = 0x1A45_DFA3;
    pub const EBML_VERSION: u32 = 0x4286;
    pub const EBML_READ_VERSION: u32 = 0x42F7;
    pub const EBML_MAX_ID_LENGTH: u32 = 0x42F2;
    pub const EBML_MAX_SIZE_LENGTH: u32 = 0x42F3;
    pub const DOC_TYPE: u32 = 0x4282;
    pub const DOC_TYPE_VERSION: u32 = 0x4287;
    pub const DOC_TYPE_READ_VERSION: u32 = 0x4285;
    pub const SEGMENT: u32 = 0x1853_8067;
    pub const INFO: u32 = 0x1549_A966;
    pub const TIMESTAMP_SCALE: u32 = 0x2A_D7B1;
    pub const DURATION: u32 = 0x4489;
    pub const MUXING_APP: u32 = 0x4D80;
    pub const WRITING_APP: u32 = 0x5741;
    pub const TRACKS: u32 = 0x1654_AE6B;
    pub const TRACK_ENTRY: u32 = 0xAE;
    pub const TRACK_NUMBER: u32 = 0xD7;
    pub const TRACK_UID: u32 = 0x73C5;
    pub const TRACK_TYPE: u32 = 0x83;
    pub const FLAG_LACING: u32 = 0x9C;
    pub const DEFAULT_DURATION: u32 = 0x23_E383;
    pub const CODEC_ID: u32 = 0x86;
    pub const CODEC_PRIVATE: u32 = 0x63A2;
    pub const VIDEO: u32 = 0xE0;
    pub const PIXEL_WIDTH: u32 = 0xB0;
    pub const PIXEL_HEIGHT: u32 = 0xBA;
    pub const COLOUR: u32 = 0x55B0;
    pub const MATRIX_COEFFICIENTS: u32 = 0x55B1;
    pub const BITS_PER_CHANNEL: u32 = 0x55B2;
    pub const CHROMA_SUBSAMPLING_HORZ: u32 = 0x55B3;
    pub const CHROMA_SUBSAMPLING_VERT: u32 = 0x55B4;
    pub const CHROMA_SITING_HORZ: u32 = 0x55B7;
    pub const CHROMA_SITING_VERT: u32 = 0x55B8;
    pub const RANGE: u32 = 0x55B9;
    pub const TRANSFER_CHARACTERISTICS: u32 = 0x55BA;
    pub const PRIMARIES: u32 = 0x55BB;
    pub const MAX_CLL: u32 = 0x55BC;
    pub const MAX_FALL: u32 = 0x55BD;
    pub const MASTERING_METADATA: u32 = 0x55D0;
    /// PrimaryRChromaticityX; R Y, G X, G Y, B X, B Y, white X, white Y follow (0x55D2..0x55D8).
    pub const PRIMARY_R_CHROMATICITY_X: u32 = 0x55D1;
    pub const LUMINANCE_MAX: u32 = 0x55D9;
    pub const LUMINANCE_MIN: u32 = 0x55DA;
    pub const CLUSTER: u32 = 0x1F43_B675;
    pub const TIMESTAMP: u32 = 0xE7;
    pub const SIMPLE_BLOCK: u32 = 0xA3;
}

/// An element ID's bytes (the ID already holds its length marker).
fn id_bytes(id: u32) -> Vec<u8> {
    let bytes = id.to_be_bytes();
    let skip = bytes.iter().take_while(|&&b| b == 0).count();
    bytes[skip..].to_vec()
}

/// An element size as an 8-byte EBML variable-size integer (marker 0x01, then 7 bytes).
fn size8(size: u64) -> [u8; 8] {
    let mut b = size.to_be_bytes();
    b[0] = 0x01;
    b
}

/// A whole element: ID, 8-byte size, body.
fn element(id: u32, body: &[u8]) -> Vec<u8> {
    let mut e = id_bytes(id);
    e.extend_from_slice(&size8(body.len() as u64));
    e.extend_from_slice(body);
    e
}

/// An unsigned integer element in as few bytes as hold it (at least one).
fn uint(id: u32, v: u64) -> Vec<u8> {
    let bytes = v.to_be_bytes();
    let skip = bytes.iter().take_while(|&&b| b == 0).count().min(7);
    element(id, &bytes[skip..])
}

/// A float element (8-byte IEEE 754, big-endian).
fn float(id: u32, v: f64) -> Vec<u8> {
    element(id, &v.to_be_bytes())
}

/// The largest distance in milliseconds between a block and its cluster's timestamp (the
/// block's relative timestamp is a signed 16-bit number).
const MAX_CLUSTER_SPAN_MS: u64 = 30_000;

/// Writes one AV1 track to a Matroska or WebM file.
pub struct MkvWriter<W: Write + Seek> {
    out: W,
    fps: u32,
    /// Where the Segment's size field and its data start.
    segment: (u64, u64),
    /// Where the Duration float's value is.
    duration_at: u64,
    /// The open cluster: its size field, data start and timestamp (ms).
    cluster: Option<(u64, u64, u64)>,
    frames: u64,
    facts: StreamFacts,
}

impl<W: Write + Seek> MkvWriter<W> {
    /// Writes the EBML header (DocType `webm` when `webm`, else `matroska`), the start of the
    /// Segment and Info; the track runs at `fps` frames per second.
    pub fn new(mut out: W, fps: u32, webm: bool) -> Result<Self> {
        let io = Error::Io;
        let doc_type: &[u8] = if webm { b"webm" } else { b"matroska" };
        let header = [
            uint(id::EBML_VERSION, 1),
            uint(id::EBML_READ_VERSION, 1),
            uint(id::EBML_MAX_ID_LENGTH, 4),
            uint(id::EBML_MAX_SIZE_LENGTH, 8),
            element(id::DOC_TYPE, doc_type),
            uint(id::DOC_TYPE_VERSION, 4),
            uint(id::DOC_TYPE_READ_VERSION, 2),
        ]
        .concat();
        out.write_all(&element(id::EBML, &header)).map_err(io)?;
        let segment_size_at = out.stream_position().map_err(io)? + 4;
        out.write_all(&id_bytes(id::SEGMENT)).map_err(io)?;
        out.write_all(&size8(0)).map_err(io)?;
        let segment_start = out.stream_position().map_err(io)?;
        let info_start = [
            uint(id::TIMESTAMP_SCALE, 1_000_000), // timestamps in milliseconds
            element(id::MUXING_APP, b"hdrcodec"),
            element(id::WRITING_APP, b"hdrcodec"),
        ]
        .concat();
        let duration = float(id::DURATION, 0.0);
        let info = element(id::INFO, &[info_start.clone(), duration.clone()].concat());
        // The Duration's value: the last 8 bytes of Info.
        let duration_at = segment_start + info.len() as u64 - 8;
        out.write_all(&info).map_err(io)?;
        Ok(MkvWriter {
            out,
            fps: fps.max(1),
            segment: (segment_size_at, segment_start),
            duration_at,
            cluster: None,
            frames: 0,
            facts: StreamFacts::default(),
        })
    }

    /// The millisecond timestamp of frame `pts`.
    fn millis(&self, pts: u64) -> u64 {
        (pts.saturating_mul(1000) + u64::from(self.fps) / 2) / u64::from(self.fps)
    }

    /// Writes one temporal unit shown at frame `pts` as a SimpleBlock, starting a cluster at
    /// each key frame; the first one also writes Tracks.
    pub fn write_temporal_unit(&mut self, pts: u64, data: &[u8], keyframe: bool) -> Result<()> {
        let first = self.facts.sequence_header.is_none();
        let block = self.facts.observe(data)?;
        let io = Error::Io;
        if first {
            let tracks = self.tracks()?;
            self.out.write_all(&tracks).map_err(io)?;
        }
        let ms = self.millis(pts);
        let span_ok = self.cluster.is_some_and(|(_, _, start)| ms >= start && ms - start <= MAX_CLUSTER_SPAN_MS);
        if keyframe || !span_ok {
            self.close_cluster()?;
            let size_at = self.out.stream_position().map_err(io)? + 4;
            self.out.write_all(&id_bytes(id::CLUSTER)).map_err(io)?;
            self.out.write_all(&size8(0)).map_err(io)?;
            let start = self.out.stream_position().map_err(io)?;
            self.out.write_all(&uint(id::TIMESTAMP, ms)).map_err(io)?;
            self.cluster = Some((size_at, start, ms));
        }
        let (_, _, cluster_ms) = self.cluster.ok_or_else(|| Error::invalid("no open cluster (a bug)"))?;
        let relative =
            i16::try_from(ms - cluster_ms).map_err(|_| Error::invalid("a block too far from its cluster"))?;
        let mut body = vec![0x81]; // track number 1 as a 1-byte EBML number
        body.extend_from_slice(&relative.to_be_bytes());
        body.push(if keyframe { 0x80 } else { 0 });
        body.extend_from_slice(&block);
        self.out.write_all(&element(id::SIMPLE_BLOCK, &body)).map_err(io)?;
        self.frames += 1;
        Ok(())
    }

    /// Patches the open cluster's size.
    fn close_cluster(&mut self) -> Result<()> {
        if let Some((size_at, start, _)) = self.cluster.take() {
            self.patch_size(size_at, start)?;
        }
        Ok(())
    }

    /// Writes the size of the element whose size field is at `size_at` and whose data runs
    /// from `start` to the current position.
    fn patch_size(&mut self, size_at: u64, start: u64) -> Result<()> {
        let io = Error::Io;
        let end = self.out.stream_position().map_err(io)?;
        self.out.seek(SeekFrom::Start(size_at)).map_err(io)?;
        self.out.write_all(&size8(end - start)).map_err(io)?;
        self.out.seek(SeekFrom::Start(end)).map_err(io)?;
        Ok(())
    }

    /// Tracks with the one AV1 track, from the stream's first temporal unit.
    fn tracks(&self) -> Result<Vec<u8>> {
        let f = &self.facts;
        let seq = f.sequence_header.as_ref().ok_or_else(|| Error::invalid("no sequence header"))?;
        let c = &seq.color;
        let mut video =
            [uint(id::PIXEL_WIDTH, seq.max_frame_width.into()), uint(id::PIXEL_HEIGHT, seq.max_frame_height.into())]
                .concat();
        if let Some(d) = c.color_description {
            // ChromaSitingHorz/Vert: 1 = left / top collocated, 2 = half (RFC 9559 §5.1).
            let (siting_h, siting_v) = match c.chroma_sample_position {
                chroma_sample_position::COLOCATED => (1, 1),
                chroma_sample_position::VERTICAL => (1, 2),
                _ => (0, 0),
            };
            let mut colour = [
                uint(id::MATRIX_COEFFICIENTS, d.matrix_coefficients.into()),
                uint(id::BITS_PER_CHANNEL, c.bit_depth.into()),
                uint(id::CHROMA_SUBSAMPLING_HORZ, c.subsampling_x.into()),
                uint(id::CHROMA_SUBSAMPLING_VERT, c.subsampling_y.into()),
                uint(id::CHROMA_SITING_HORZ, siting_h),
                uint(id::CHROMA_SITING_VERT, siting_v),
                // Range: 1 broadcast, 2 full.
                uint(id::RANGE, if c.full_range { 2 } else { 1 }),
                uint(id::TRANSFER_CHARACTERISTICS, d.transfer_characteristics.into()),
                uint(id::PRIMARIES, d.color_primaries.into()),
            ]
            .concat();
            if let Some(cll) = f.content_light {
                colour.extend(uint(id::MAX_CLL, cll.max_cll.into()));
                colour.extend(uint(id::MAX_FALL, cll.max_fall.into()));
            }
            if let Some(units) = &f.mastering_display {
                let md = MasteringDisplay::from_av1(units);
                let mut mm = Vec::new();
                let values = [md.primaries[0], md.primaries[1], md.primaries[2], md.white];
                for (k, v) in values.iter().flatten().enumerate() {
                    mm.extend(float(id::PRIMARY_R_CHROMATICITY_X + k as u32, *v));
                }
                mm.extend(float(id::LUMINANCE_MAX, md.max_luminance));
                mm.extend(float(id::LUMINANCE_MIN, md.min_luminance));
                colour.extend(element(id::MASTERING_METADATA, &mm));
            }
            video.extend(element(id::COLOUR, &colour));
        }
        let seq_obu = f.sequence_header_obu.as_deref().unwrap_or_default();
        let entry = [
            uint(id::TRACK_NUMBER, 1),
            uint(id::TRACK_UID, 1),
            uint(id::TRACK_TYPE, 1), // video
            uint(id::FLAG_LACING, 0),
            element(id::CODEC_ID, b"V_AV1"),
            uint(id::DEFAULT_DURATION, 1_000_000_000 / u64::from(self.fps)),
            element(id::CODEC_PRIVATE, &av1_config_record(seq, seq_obu)),
            element(id::VIDEO, &video),
        ]
        .concat();
        Ok(element(id::TRACKS, &element(id::TRACK_ENTRY, &entry)))
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> u64 {
        self.frames
    }

    /// Closes the last cluster, writes the duration and the Segment's size; returns the output
    /// and the file's length in bytes.
    pub fn finish(mut self) -> Result<(W, u64)> {
        if self.frames == 0 {
            return Err(Error::invalid("a Matroska track without frames"));
        }
        self.close_cluster()?;
        let io = Error::Io;
        let end = self.out.stream_position().map_err(io)?;
        let duration = self.frames as f64 * 1000.0 / f64::from(self.fps);
        self.out.seek(SeekFrom::Start(self.duration_at)).map_err(io)?;
        self.out.write_all(&duration.to_be_bytes()).map_err(io)?;
        self.out.seek(SeekFrom::Start(end)).map_err(io)?;
        let (size_at, start) = self.segment;
        self.patch_size(size_at, start)?;
        self.out.flush().map_err(io)?;
        Ok((self.out, end))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ebml_ids_sizes_and_elements() {
        assert_eq!(id_bytes(id::EBML), [0x1A, 0x45, 0xDF, 0xA3]);
        assert_eq!(id_bytes(id::TIMESTAMP), [0xE7]);
        assert_eq!(size8(300), [1, 0, 0, 0, 0, 0, 1, 0x2C]);
        assert_eq!(uint(id::TRACK_NUMBER, 1), [0xD7, 1, 0, 0, 0, 0, 0, 0, 1, 1]);
        assert_eq!(uint(id::TIMESTAMP, 0), [0xE7, 1, 0, 0, 0, 0, 0, 0, 1, 0]);
        assert_eq!(float(id::DURATION, 1.0)[10..], 1.0f64.to_be_bytes()); // 2-byte ID, 8-byte size
                                                                          // A file begins with the EBML header naming its DocType; one without frames is refused.
        let w = MkvWriter::new(std::io::Cursor::new(Vec::new()), 25, true).unwrap();
        assert!(w.finish().is_err());
        let mut out = std::io::Cursor::new(Vec::new());
        drop(MkvWriter::new(&mut out, 25, true).unwrap());
        let bytes = out.into_inner();
        assert_eq!(bytes[..4], [0x1A, 0x45, 0xDF, 0xA3]);
        assert!(bytes.windows(4).any(|w| w == b"webm"));
    }
}
