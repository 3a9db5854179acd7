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
//!
//! Reading ([`MkvTrack`]): the EBML header (DocType `matroska` or `webm`), the first video
//! track of `Tracks` (number, CodecID, CodecPrivate, pixel size, `Colour`), then its frames in
//! file order ([`MkvBlocks`]): `SimpleBlock`s and the `Block` of each `BlockGroup`, in Clusters of
//! known or unknown size (a live writer's), walked flat without recursion. Every element's
//! size is checked against its parent and the input; a block larger than
//! `Limits::max_alloc_bytes`, laced blocks, and elements of unknown size other than Segment
//! and Cluster are errors. Nothing is allocated per element: frames are borrowed.

use crate::mp4::{av1_config_record, StreamFacts};
use crate::obu::chroma_sample_position;
use hdrcodec_core::{Error, Limits, MasteringDisplay, Result};
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
    pub const BLOCK_GROUP: u32 = 0xA0;
    pub const BLOCK: u32 = 0xA1;
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

/// An EBML variable-size integer at the start of `data`: (value, length). `keep_marker` for
/// element IDs (which keep their length marker); a size of all ones is "unknown" (`None`).
fn read_vint(data: &[u8], keep_marker: bool) -> Result<(Option<u64>, usize)> {
    let first = *data.first().ok_or_else(|| Error::truncated("a Matroska element"))?;
    if first == 0 {
        return Err(Error::invalid("a Matroska variable-size integer longer than 8 bytes"));
    }
    let len = first.leading_zeros() as usize + 1;
    let bytes = data.get(..len).ok_or_else(|| Error::truncated("a Matroska element"))?;
    let marker = if keep_marker { 0 } else { 0x80u8 >> (len - 1) };
    let value = bytes[1..].iter().fold(u64::from(first & !marker), |v, &b| (v << 8) | u64::from(b));
    let all_ones = (1u64 << (7 * len)) - 1;
    Ok(((keep_marker || value != all_ones).then_some(value), len))
}

/// One element: its ID, its body (for an unknown size, the rest of the parent) and whether the
/// size was unknown.
struct Element<'a> {
    id: u32,
    body: &'a [u8],
    unknown_size: bool,
    /// Header and body length within the parent (for an unknown size, the header only).
    header_len: usize,
}

/// The element at the start of `data` (the rest of its parent).
fn read_element(data: &[u8]) -> Result<Element<'_>> {
    let (id, id_len) = read_vint(data, true)?;
    let id = id.unwrap_or(0);
    if id_len > 4 {
        return Err(Error::invalid("a Matroska element ID longer than 4 bytes"));
    }
    let (size, size_len) = read_vint(&data[id_len..], false)?;
    let header_len = id_len + size_len;
    let rest = &data[header_len..];
    let (body, unknown_size) = match size {
        Some(n) => {
            let n = usize::try_from(n).ok().filter(|&n| n <= rest.len());
            (
                rest.get(..n.ok_or_else(|| Error::truncated("a Matroska element (its size runs past its parent)"))?)
                    .unwrap_or(&[]),
                false,
            )
        }
        None => (rest, true),
    };
    Ok(Element { id: id as u32, body, unknown_size, header_len })
}

/// The children of `data`, each of known size (an unknown size is an error here).
fn children(mut data: &[u8]) -> impl Iterator<Item = Result<Element<'_>>> {
    std::iter::from_fn(move || {
        if data.is_empty() {
            return None;
        }
        let e = match read_element(data) {
            Ok(e) if e.unknown_size => Err(Error::unsupported("a Matroska element of unknown size inside a track")),
            other => other,
        };
        match &e {
            Ok(e) => data = &data[e.header_len + e.body.len()..],
            Err(_) => data = &[],
        }
        Some(e)
    })
}

/// An unsigned integer element's value (0 to 8 bytes).
fn read_uint(body: &[u8]) -> Result<u64> {
    if body.len() > 8 {
        return Err(Error::invalid("a Matroska unsigned integer of more than 8 bytes"));
    }
    Ok(body.iter().fold(0u64, |v, &b| (v << 8) | u64::from(b)))
}

/// A float element's value (4 or 8 bytes; 0 bytes is 0.0).
fn read_float(body: &[u8]) -> Result<f64> {
    match body.len() {
        0 => Ok(0.0),
        4 => Ok(f64::from(f32::from_be_bytes([body[0], body[1], body[2], body[3]]))),
        8 => Ok(f64::from_be_bytes(body.try_into().unwrap_or([0; 8]))),
        n => Err(Error::invalid(format!("a Matroska float of {n} bytes"))),
    }
}

/// The `Colour` element of a Matroska video track (RFC 9559 §5.1.4.1.28.15 ff.): H.273 code
/// points, range, content light and mastering metadata, where present.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MkvColour {
    /// MatrixCoefficients (H.273).
    pub matrix: Option<u64>,
    /// TransferCharacteristics (H.273).
    pub transfer: Option<u64>,
    /// Primaries (H.273).
    pub primaries: Option<u64>,
    /// Range: 1 limited ("broadcast"), 2 full.
    pub range: Option<u64>,
    /// BitsPerChannel.
    pub bits_per_channel: Option<u64>,
    /// ChromaSitingHorz / ChromaSitingVert (1 left/top, 2 half).
    pub siting: (Option<u64>, Option<u64>),
    /// MaxCLL, cd/m².
    pub max_cll: Option<u64>,
    /// MaxFALL, cd/m².
    pub max_fall: Option<u64>,
    /// MasteringMetadata: R, G, B, white x/y and luminance max, min (cd/m²), when all are there.
    pub mastering_display: Option<MasteringDisplay>,
}

impl MkvColour {
    fn parse(body: &[u8]) -> Result<Self> {
        let mut c = MkvColour::default();
        for e in children(body) {
            let e = e?;
            let v = || read_uint(e.body).map(Some);
            match e.id {
                id::MATRIX_COEFFICIENTS => c.matrix = v()?,
                id::TRANSFER_CHARACTERISTICS => c.transfer = v()?,
                id::PRIMARIES => c.primaries = v()?,
                id::RANGE => c.range = v()?,
                id::BITS_PER_CHANNEL => c.bits_per_channel = v()?,
                id::CHROMA_SITING_HORZ => c.siting.0 = v()?,
                id::CHROMA_SITING_VERT => c.siting.1 = v()?,
                id::MAX_CLL => c.max_cll = v()?,
                id::MAX_FALL => c.max_fall = v()?,
                id::MASTERING_METADATA => {
                    let mut f = [None::<f64>; 10];
                    for m in children(e.body) {
                        let m = m?;
                        let slot = match m.id {
                            id::LUMINANCE_MAX => Some(8),
                            id::LUMINANCE_MIN => Some(9),
                            i if (id::PRIMARY_R_CHROMATICITY_X..id::PRIMARY_R_CHROMATICITY_X + 8).contains(&i) => {
                                Some((i - id::PRIMARY_R_CHROMATICITY_X) as usize)
                            }
                            _ => None,
                        };
                        if let Some(slot) = slot {
                            f[slot] = Some(read_float(m.body)?);
                        }
                    }
                    if let [Some(rx), Some(ry), Some(gx), Some(gy), Some(bx), Some(by), Some(wx), Some(wy), Some(max), Some(min)] =
                        f
                    {
                        c.mastering_display = Some(MasteringDisplay {
                            primaries: [[rx, ry], [gx, gy], [bx, by]],
                            white: [wx, wy],
                            max_luminance: max,
                            min_luminance: min,
                        });
                    }
                }
                _ => {}
            }
        }
        Ok(c)
    }
}

/// The first video track of a Matroska or WebM file, and where its frames are.
#[derive(Clone, Debug)]
pub struct MkvTrack<'a> {
    /// `webm` or `matroska`.
    pub doc_type: String,
    /// TrackNumber (the blocks name it).
    pub number: u64,
    /// CodecID, e.g. `V_AV1`.
    pub codec_id: String,
    /// CodecPrivate (for AV1 the `AV1CodecConfigurationRecord`, as MP4's `av1C`).
    pub codec_private: Option<&'a [u8]>,
    /// PixelWidth, PixelHeight.
    pub pixel_size: (u64, u64),
    /// The Colour element, when there is one.
    pub colour: Option<MkvColour>,
    /// The Segment's body (Clusters are found in it).
    segment: &'a [u8],
    max_block: u64,
}

/// True when `data` starts with the EBML magic (a Matroska or WebM file, or another EBML type).
pub fn is_mkv(data: &[u8]) -> bool {
    data.starts_with(&[0x1A, 0x45, 0xDF, 0xA3])
}

impl<'a> MkvTrack<'a> {
    /// Reads the EBML header and the first video track (TrackType 1) of `data`. Blocks larger
    /// than `limits.max_alloc_bytes` will be refused by [`blocks`](Self::blocks).
    pub fn first_video(data: &'a [u8], limits: &Limits) -> Result<Self> {
        let header = read_element(data)?;
        if header.id != id::EBML || header.unknown_size {
            return Err(Error::invalid("not a Matroska file (no EBML header)"));
        }
        let mut doc_type = None;
        for e in children(header.body) {
            let e = e?;
            if e.id == id::DOC_TYPE {
                doc_type = Some(String::from_utf8_lossy(e.body).trim_end_matches('\0').to_string());
            }
        }
        let doc_type = doc_type.unwrap_or_else(|| "matroska".into());
        if doc_type != "matroska" && doc_type != "webm" {
            return Err(Error::unsupported(format!("EBML DocType '{doc_type}' (Matroska and WebM are read)")));
        }
        let after = &data[header.header_len + header.body.len()..];
        let segment = read_element(after)?;
        if segment.id != id::SEGMENT {
            return Err(Error::invalid(format!(
                "a Matroska file whose first element after the header is {:#x}, not a Segment",
                segment.id
            )));
        }
        // Level-1 elements up to Tracks; a Cluster of unknown size before Tracks ends the search.
        let mut rest = segment.body;
        while !rest.is_empty() {
            let e = read_element(rest)?;
            if e.id == id::TRACKS {
                for entry in children(e.body) {
                    let entry = entry?;
                    if entry.id != id::TRACK_ENTRY {
                        continue;
                    }
                    if let Some(track) = Self::track_entry(entry.body, &doc_type, segment.body, limits)? {
                        return Ok(track);
                    }
                }
                return Err(Error::invalid("a Matroska file without a video track"));
            }
            if e.unknown_size {
                break;
            }
            rest = &rest[e.header_len + e.body.len()..];
        }
        Err(Error::invalid("a Matroska file without Tracks before its frames"))
    }

    fn track_entry(body: &'a [u8], doc_type: &str, segment: &'a [u8], limits: &Limits) -> Result<Option<Self>> {
        let mut track = MkvTrack {
            doc_type: doc_type.to_string(),
            number: 0,
            codec_id: String::new(),
            codec_private: None,
            pixel_size: (0, 0),
            colour: None,
            segment,
            max_block: limits.max_alloc_bytes,
        };
        let mut video = false;
        for e in children(body) {
            let e = e?;
            match e.id {
                id::TRACK_NUMBER => track.number = read_uint(e.body)?,
                id::TRACK_TYPE => video = read_uint(e.body)? == 1,
                id::CODEC_ID => track.codec_id = String::from_utf8_lossy(e.body).trim_end_matches('\0').to_string(),
                id::CODEC_PRIVATE => track.codec_private = Some(e.body),
                id::VIDEO => {
                    for v in children(e.body) {
                        let v = v?;
                        match v.id {
                            id::PIXEL_WIDTH => track.pixel_size.0 = read_uint(v.body)?,
                            id::PIXEL_HEIGHT => track.pixel_size.1 = read_uint(v.body)?,
                            id::COLOUR => track.colour = Some(MkvColour::parse(v.body)?),
                            _ => {}
                        }
                    }
                }
                _ => {}
            }
        }
        if track.number == 0 && video {
            return Err(Error::invalid("a Matroska video track without a TrackNumber"));
        }
        Ok(video.then_some(track))
    }

    /// The track's frames in file order.
    pub fn blocks(&self) -> MkvBlocks<'a> {
        MkvBlocks { rest: self.segment, track: self.number, max_block: self.max_block }
    }
}

/// The frames of one Matroska track ([`MkvTrack::blocks`]).
#[derive(Clone, Debug)]
pub struct MkvBlocks<'a> {
    rest: &'a [u8],
    track: u64,
    max_block: u64,
}

impl<'a> MkvBlocks<'a> {
    /// The next frame of the track (a block's data), `None` at the end of the Segment.
    pub fn next_frame(&mut self) -> Result<Option<&'a [u8]>> {
        while !self.rest.is_empty() {
            let e = match read_element(self.rest) {
                Ok(e) => e,
                Err(err) => {
                    self.rest = &[];
                    return Err(err);
                }
            };
            // Clusters and BlockGroups are entered (their children follow in the same walk, so a
            // Cluster of unknown size works); other elements are stepped over whole.
            let (step, block) = match e.id {
                id::CLUSTER | id::BLOCK_GROUP => (e.header_len, None),
                id::SIMPLE_BLOCK | id::BLOCK if !e.unknown_size => (e.header_len + e.body.len(), Some(e.body)),
                _ if e.unknown_size => {
                    self.rest = &[];
                    return Err(Error::unsupported(format!("a Matroska element {:#x} of unknown size", e.id)));
                }
                _ => (e.header_len + e.body.len(), None),
            };
            self.rest = &self.rest[step..];
            if let Some(body) = block {
                if body.len() as u64 > self.max_block {
                    self.rest = &[];
                    return Err(Error::limit(format!("a Matroska block of {} bytes", body.len())));
                }
                let (track, n) = read_vint(body, false)?;
                let flags = *body.get(n + 2).ok_or_else(|| Error::truncated("a Matroska block header"))?;
                if track != Some(self.track) {
                    continue;
                }
                if flags & 0x06 != 0 {
                    return Err(Error::unsupported("laced Matroska blocks"));
                }
                return Ok(Some(&body[n + 3..]));
            }
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variable_size_integers_and_hostile_blocks() {
        assert_eq!(read_vint(&[0x81], false).unwrap(), (Some(1), 1));
        assert_eq!(read_vint(&[0x40, 0x02], false).unwrap(), (Some(2), 2));
        assert_eq!(read_vint(&[0x1A, 0x45, 0xDF, 0xA3], true).unwrap(), (Some(0x1A45_DFA3), 4));
        assert_eq!(read_vint(&[0xFF], false).unwrap(), (None, 1)); // unknown size
        assert!(read_vint(&[0x00, 1, 2, 3, 4, 5, 6, 7, 8], false).is_err());
        assert!(read_vint(&[0x10, 0x00], false).is_err()); // cut short
                                                           // The fuzz seed: an unknown-size Cluster with a laced block, then one declaring 2^40 bytes.
        let data = include_bytes!("../../../fuzz/regressions/ivf_obu/hostile-laced-and-huge-blocks.webm");
        let track = MkvTrack::first_video(data, &Limits::default()).unwrap();
        assert_eq!((track.number, track.codec_id.as_str(), track.doc_type.as_str()), (1, "V_AV1", "webm"));
        let mut blocks = track.blocks();
        assert!(matches!(blocks.next_frame(), Err(Error::Unsupported { .. })));
        assert!(matches!(blocks.next_frame(), Err(Error::Truncated { .. })));
        assert_eq!(blocks.next_frame().unwrap(), None);
        // Not Matroska, or another EBML document type.
        assert!(MkvTrack::first_video(b"DKIF", &Limits::default()).is_err());
        let mut other = data.to_vec();
        other[..40].iter_mut().filter(|b| **b == b'w').for_each(|b| *b = b'x');
        assert!(MkvTrack::first_video(&other, &Limits::default()).is_err());
    }

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
