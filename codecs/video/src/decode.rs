//! AV1 (in IVF, MP4 or Matroska/WebM) back to scene-linear frames, decoded by the system's libdav1d through
//! the safe `dav1d` crate. The colour description and HDR10 metadata come from our own OBU
//! parser ([`crate::obu`]): the `dav1d` 0.9 crate exposes neither.

use crate::hdr10::{yuv_to_frame, ChromaSiting, Range, Subsampling, Transfer, YuvFrame, BIT_DEPTH};
use crate::ivf::IvfReader;
use crate::light::YuvToLight;
use crate::lpuv_av1::{lpuv_yuv_to_frame, LpuvStreamInfo, LPUV_BIT_DEPTH};
use crate::mantiuk::Psi04;
use crate::mkv::{is_mkv, MkvBlocks, MkvColour, MkvTrack};
use crate::mp4::{is_mp4, Mp4Samples, Mp4Track};
use crate::obu::{chroma_sample_position, ColorDescription, SequenceHeader, StreamSummary};
use crate::sdr::{sdr_yuv_to_frame, SDR_BIT_DEPTH};
use dav1d::{PixelLayout, PlanarImageComponent};
use hdrcodec_core::{
    Allocation, Channels, ColorInfo, ColorPrimaries, ContentLightLevel, Error, HdrImage, ImageInfo, Limits, Result,
    ThreadPool,
};
use std::sync::Arc;

/// How to decode.
#[derive(Clone, Debug)]
pub struct Av1DecodeOptions {
    /// What decoders may allocate; the stream's declared frame size is checked against it.
    pub limits: Limits,
    /// cd/m² of a decoded sample value 1.0 (core's default convention: 100).
    pub nits_per_unit: f32,
    /// The display peak an HLG stream is rendered for, cd/m² (BT.2100 reference: 1000).
    pub hlg_peak_nits: f64,
    /// Worker threads for turning HDR10 and HLG planes into light, bands of rows at a time
    /// (libdav1d itself runs on one thread, so that each temporal unit gives its picture at
    /// once).
    pub pool: ThreadPool,
}

impl Default for Av1DecodeOptions {
    fn default() -> Self {
        Av1DecodeOptions {
            limits: Limits::default(),
            nits_per_unit: 100.0,
            hlg_peak_nits: 1000.0,
            pool: ThreadPool::single(),
        }
    }
}

/// The temporal units of an AV1 stream, from an IVF file or the video track of an MP4 file.
#[derive(Clone, Debug)]
pub enum TemporalUnits<'a> {
    /// IVF frames.
    Ivf(IvfReader<'a>),
    /// MP4 samples (temporal units without their delimiter).
    Mp4 {
        /// The track's samples.
        samples: Mp4Samples<'a>,
        /// The `av1C` configuration OBUs, sent first when the samples carry no sequence header.
        prefix: Option<&'a [u8]>,
        /// Samples read so far (their presentation index).
        index: u64,
    },
    /// Matroska or WebM blocks (temporal units without their delimiter).
    Mkv {
        /// The track's frames.
        blocks: MkvBlocks<'a>,
        /// The CodecPrivate configuration OBUs, sent first when the blocks carry no sequence
        /// header.
        prefix: Option<&'a [u8]>,
        /// The track's Colour element: its MaxCLL/MaxFALL and mastering display stand in for
        /// HDR metadata OBUs the stream lacks.
        colour: Option<Box<MkvColour>>,
        /// Blocks read so far (their presentation index).
        index: u64,
    },
}

impl<'a> TemporalUnits<'a> {
    /// Opens `data` as IVF (`DKIF`), MP4 (`ftyp` first) or Matroska/WebM (EBML); anything else
    /// is an error.
    pub fn open(data: &'a [u8], limits: &Limits) -> Result<Self> {
        if is_mkv(data) {
            let track = MkvTrack::first_video(data, limits)?;
            if track.codec_id != "V_AV1" {
                return Err(Error::unsupported(format!(
                    "Matroska video of CodecID '{}': only AV1 ('V_AV1') is decoded",
                    track.codec_id
                )));
            }
            // The AV1CodecConfigurationRecord: 4 bytes of fields, then the configuration OBUs.
            let prefix = track.codec_private.and_then(|c| c.get(4..)).filter(|obus| !obus.is_empty());
            return Ok(TemporalUnits::Mkv {
                blocks: track.blocks(),
                prefix,
                colour: track.colour.map(Box::new),
                index: 0,
            });
        }
        if is_mp4(data) {
            let track = Mp4Track::first_video(data, limits)?;
            if &track.codec != b"av01" {
                return Err(Error::unsupported(format!(
                    "MP4 video of type '{}': only AV1 ('av01') is decoded",
                    String::from_utf8_lossy(&track.codec)
                )));
            }
            // av1C: 4 bytes of fields, then the configuration OBUs.
            let prefix = track.config.and_then(|c| c.get(4..)).filter(|obus| !obus.is_empty());
            return Ok(TemporalUnits::Mp4 { samples: track.samples(), prefix, index: 0 });
        }
        let reader = IvfReader::new(data, limits)?;
        if !reader.is_av1() {
            let f = reader.header().fourcc;
            return Err(Error::unsupported(format!("IVF FourCC {:?}: only AV01 is read", String::from_utf8_lossy(&f))));
        }
        Ok(TemporalUnits::Ivf(reader))
    }

    /// The next temporal unit and its presentation index, `None` at the end.
    pub fn next_unit(&mut self) -> Result<Option<(u64, &'a [u8])>> {
        match self {
            TemporalUnits::Ivf(reader) => Ok(reader.next_frame()?.map(|f| (f.pts, f.data))),
            TemporalUnits::Mp4 { samples, index, .. } => {
                let sample = samples.next_sample()?;
                let pts = *index;
                *index += sample.is_some() as u64;
                Ok(sample.map(|s| (pts, s)))
            }
            TemporalUnits::Mkv { blocks, index, .. } => {
                let frame = blocks.next_frame()?;
                let pts = *index;
                *index += frame.is_some() as u64;
                Ok(frame.map(|f| (pts, f)))
            }
        }
    }

    /// The MP4 or Matroska track's configuration OBUs, if this is one.
    fn config_obus(&self) -> Option<&'a [u8]> {
        match self {
            TemporalUnits::Mp4 { prefix, .. } | TemporalUnits::Mkv { prefix, .. } => *prefix,
            TemporalUnits::Ivf(_) => None,
        }
    }
}

/// Reads the colour signalling and HDR10 metadata of an AV1 stream in IVF, MP4 or Matroska
/// without decoding it. When MP4 samples or Matroska blocks carry no sequence header, the one of
/// `av1C` / CodecPrivate is taken; when a Matroska stream carries no HDR metadata OBUs, its
/// `Colour` element's MaxCLL/MaxFALL and MasteringMetadata are taken.
pub fn probe_stream(data: &[u8], limits: &Limits) -> Result<StreamSummary> {
    walk_stream(data, limits, |_, _| Ok(()))
}

/// [`probe_stream`], calling `each` with every temporal unit's presentation index and bytes.
fn walk_stream(data: &[u8], limits: &Limits, mut each: impl FnMut(u64, &[u8]) -> Result<()>) -> Result<StreamSummary> {
    let mut units = TemporalUnits::open(data, limits)?;
    let mut summary = StreamSummary::default();
    while let Some((pts, unit)) = units.next_unit()? {
        summary.add_temporal_unit(unit)?;
        each(pts, unit)?;
    }
    if summary.sequence_header.is_none() {
        if let Some(obus) = units.config_obus() {
            let mut config = StreamSummary::default();
            config.add_temporal_unit(obus)?;
            summary.sequence_header = config.sequence_header;
        }
    }
    if let TemporalUnits::Mkv { colour: Some(c), .. } = &units {
        if summary.content_light.is_none() {
            if let (Some(cll), Some(fall)) = (c.max_cll, c.max_fall) {
                let clamp = |v: u64| v.min(u64::from(u16::MAX)) as u16;
                summary.content_light = Some(ContentLightLevel { max_cll: clamp(cll), max_fall: clamp(fall) });
            }
        }
        if summary.mastering_display.is_none() {
            summary.mastering_display = c.mastering_display.map(|m| m.to_av1());
        }
    }
    Ok(summary)
}

/// Reads the colour signalling and HDR10 metadata of an IVF/AV1 stream without decoding it.
pub fn probe_ivf(data: &[u8], limits: &Limits) -> Result<(crate::ivf::IvfHeader, StreamSummary)> {
    let mut reader = IvfReader::new(data, limits)?;
    if !reader.is_av1() {
        let f = reader.header().fourcc;
        return Err(Error::unsupported(format!("IVF FourCC {:?}: only AV01 is read", String::from_utf8_lossy(&f))));
    }
    let header = *reader.header();
    let mut summary = StreamSummary::default();
    while let Some(frame) = reader.next_frame()? {
        summary.add_temporal_unit(frame.data)?;
    }
    Ok((header, summary))
}

/// The L_p u'v' description of a stream, from the first of its T.35 messages that is ours (our own parser
/// reads it from the temporal units: dav1d 1.0.0 keeps only the last T.35 of a picture).
fn lpuv_info(summary: &StreamSummary) -> Result<LpuvStreamInfo> {
    let refuse = || {
        Error::unsupported(
            "a 12-bit AV1 stream without the hdrcodec-lpuv T.35 message: its planes are of an unknown kind",
        )
    };
    LpuvStreamInfo::from_summary(summary)?.ok_or_else(refuse)
}

/// The subsampling a sequence header declares, if we can decode it.
fn stream_subsampling(seq: &SequenceHeader) -> Result<Subsampling> {
    let c = &seq.color;
    if c.mono_chrome {
        return Err(Error::unsupported("monochrome AV1"));
    }
    match (c.subsampling_x, c.subsampling_y) {
        (true, true) => Ok(Subsampling::Yuv420),
        (false, false) => Ok(Subsampling::Yuv444),
        _ => Err(Error::unsupported("4:2:2 AV1")),
    }
}

/// The transfer, range and subsampling a sequence header declares, if we can decode it.
fn stream_format(seq: &SequenceHeader, hlg_peak_nits: f64) -> Result<(Transfer, Range, Subsampling)> {
    let c = &seq.color;
    if u32::from(c.bit_depth) != BIT_DEPTH {
        return Err(Error::unsupported(format!(
            "{}-bit AV1 (this decoder returns HDR10/HLG 10-bit, hdrcodec-lpuv 10- and 12-bit and SDR 8-bit)",
            c.bit_depth
        )));
    }
    let subsampling = stream_subsampling(seq)?;
    let transfer = match c.color_description {
        Some(ColorDescription { color_primaries: 9, transfer_characteristics: 16, matrix_coefficients: 9 }) => {
            Transfer::Pq
        }
        Some(ColorDescription { color_primaries: 9, transfer_characteristics: 18, matrix_coefficients: 9 }) => {
            Transfer::Hlg { peak_nits: hlg_peak_nits }
        }
        other => {
            return Err(Error::unsupported(format!(
                "AV1 colour description {other:?} (this decoder returns BT.2020 PQ or HLG, 9/16/9 or 9/18/9)"
            )))
        }
    };
    Ok((transfer, if c.full_range { Range::Full } else { Range::Limited }, subsampling))
}

/// What the decoded frames of a stream will be: size, colour, frame count, a few words on the
/// coded format.
fn stream_info(
    seq: &SequenceHeader,
    summary: &StreamSummary,
    transfer: Transfer,
    subsampling: Subsampling,
    lpuv: Option<&LpuvStreamInfo>,
    sdr: bool,
    options: &Av1DecodeOptions,
) -> Result<ImageInfo> {
    let chroma = match subsampling {
        Subsampling::Yuv420 => "4:2:0",
        Subsampling::Yuv444 => "4:4:4",
    };
    let (color, format) = match lpuv {
        None if sdr => (
            ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: options.nits_per_unit, hdr10: None },
            format!("AV1 8-bit {chroma} BT.709 sRGB (SDR)"),
        ),
        Some(info) => (
            ColorInfo { primaries: info.primaries()?, nits_per_unit: options.nits_per_unit, hdr10: None },
            format!("AV1 {}-bit {chroma} L_p u'v' (Mantiuk 2004, {} luma bits)", seq.color.bit_depth, info.bits),
        ),
        None => (
            ColorInfo {
                primaries: ColorPrimaries::Bt2020,
                nits_per_unit: options.nits_per_unit,
                hdr10: summary.hdr10(),
            },
            format!(
                "AV1 {}-bit {chroma} BT.2020 {}",
                seq.color.bit_depth,
                match transfer {
                    Transfer::Pq => "PQ",
                    Transfer::Hlg { .. } => "HLG",
                }
            ),
        ),
    };
    let frames = u32::try_from(summary.temporal_units).unwrap_or(u32::MAX);
    Ok(ImageInfo::new(seq.max_frame_width, seq.max_frame_height, Channels::Rgb, color)
        .with_frames(frames)
        .with_format(format))
}

/// Copies a plane of `w` × `h` out of dav1d's strided buffer (one byte per sample at 8 bits,
/// two little-endian bytes above) into `out`, whose allocation is reused.
fn copy_plane(bytes: &[u8], stride: usize, w: usize, h: usize, bit_depth: u32, out: &mut Vec<u16>) -> Result<()> {
    let size = if bit_depth > 8 { 2 } else { 1 };
    out.clear();
    out.reserve(w * h);
    for y in 0..h {
        let row = bytes
            .get(y * stride..y * stride + size * w)
            .ok_or_else(|| Error::invalid("dav1d returned a plane smaller than the picture"))?;
        if size == 1 {
            out.extend(row.iter().map(|&b| u16::from(b)));
        } else {
            out.extend(row.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])));
        }
    }
    Ok(())
}

/// Where an [`Av1Decoder`] takes its temporal units from.
enum UnitSource<'a> {
    /// The container read as the decoder goes, in data the caller lends.
    Borrowed(TemporalUnits<'a>),
    /// Data the decoder shares ownership of, with every temporal unit's place in it (found
    /// when the decoder was made, and charged to the limits as long as it lives).
    Shared {
        data: Arc<[u8]>,
        /// (presentation index, start, end) of each temporal unit.
        units: Vec<(u64, usize, usize)>,
        next: usize,
        _charge: Allocation,
    },
}

impl UnitSource<'_> {
    fn next_unit(&mut self) -> Result<Option<(u64, &[u8])>> {
        match self {
            UnitSource::Borrowed(units) => units.next_unit(),
            UnitSource::Shared { data, units, next, .. } => {
                let Some(&(pts, start, end)) = units.get(*next) else { return Ok(None) };
                *next += 1;
                Ok(Some((pts, &data[start..end])))
            }
        }
    }
}

/// Decodes an AV1 stream in IVF or MP4 frame by frame.
pub struct Av1Decoder<'a> {
    units: UnitSource<'a>,
    /// MP4 configuration OBUs still to send before the first sample.
    prefix: Option<Vec<u8>>,
    decoder: dav1d::Decoder,
    summary: StreamSummary,
    transfer: Transfer,
    range: Range,
    subsampling: Subsampling,
    siting: ChromaSiting,
    /// The stream's L_p u'v' description and luma curve, when it is one (12-bit).
    lpuv: Option<(LpuvStreamInfo, Psi04)>,
    /// An 8-bit SDR stream (BT.709, sRGB).
    sdr: bool,
    /// HDR10 and HLG planes to light (built once for the stream).
    light: Option<YuvToLight>,
    /// The last picture's planes, whose buffers the next picture reuses.
    planes: Option<YuvFrame>,
    bit_depth: u32,
    options: Av1DecodeOptions,
    width: u32,
    height: u32,
    /// dav1d holds back part of the last temporal unit sent.
    pending: bool,
    flushed: bool,
    /// Frames returned so far.
    returned: u64,
    /// What [`info`](Self::info) returns.
    info: ImageInfo,
}

impl Av1Decoder<'static> {
    /// [`new`](Av1Decoder::new) on data the decoder keeps a share of (what
    /// [`Av1Codec`](crate::codec::Av1Codec)'s `begin_decode` is given): the places of the
    /// temporal units are found once, here, and charged to `options.limits` (24 bytes each)
    /// while the decoder lives.
    pub fn from_shared(data: Arc<[u8]>, options: &Av1DecodeOptions) -> Result<Self> {
        let base = data.as_ptr() as usize;
        let mut places = Vec::new();
        let summary = walk_stream(&data, &options.limits, |pts, unit| {
            let start = unit.as_ptr() as usize - base;
            places.push((pts, start, start + unit.len()));
            Ok(())
        })?;
        let entry = std::mem::size_of::<(u64, usize, usize)>() as u64;
        let charge = options.limits.charge(entry * places.len() as u64, "the index of the stream's temporal units")?;
        let config = TemporalUnits::open(&data, &options.limits)?.config_obus().map(<[u8]>::to_vec);
        let units = UnitSource::Shared { data: data.clone(), units: places, next: 0, _charge: charge };
        Self::with_units(&data, summary, units, config, options)
    }
}

impl<'a> Av1Decoder<'a> {
    /// Opens a stream (IVF or MP4): reads the container and every temporal unit's headers and
    /// metadata (cheap, no decoding), checks the frame size against the limits.
    pub fn new(data: &'a [u8], options: &Av1DecodeOptions) -> Result<Self> {
        let summary = probe_stream(data, &options.limits)?;
        let units = TemporalUnits::open(data, &options.limits)?;
        let config = units.config_obus().map(<[u8]>::to_vec);
        Self::with_units(data, summary, UnitSource::Borrowed(units), config, options)
    }

    /// The decoder of the stream in `data` that `summary` describes, reading `units`.
    fn with_units(
        data: &[u8],
        summary: StreamSummary,
        units: UnitSource<'a>,
        config: Option<Vec<u8>>,
        options: &Av1DecodeOptions,
    ) -> Result<Self> {
        let seq = summary.sequence_header.ok_or_else(|| Error::invalid("an AV1 stream without a sequence header"))?;
        if summary.changed_sequence_headers > 0 {
            return Err(Error::unsupported("an AV1 stream whose sequence header changes"));
        }
        let sdr = u32::from(seq.color.bit_depth) == SDR_BIT_DEPTH;
        // 12 bits are always L_p u'v' (refused without our T.35); 10 bits when the stream has
        // no colour description and carries our T.35 (else HDR10 or HLG).
        let lpuv_10 = u32::from(seq.color.bit_depth) != LPUV_BIT_DEPTH
            && seq.color.color_description.is_none()
            && LpuvStreamInfo::from_summary(&summary)?.is_some();
        let (transfer, range, subsampling, lpuv) = if u32::from(seq.color.bit_depth) == LPUV_BIT_DEPTH || lpuv_10 {
            let info = lpuv_info(&summary)?;
            if u32::from(info.mapping.plane_bits) != u32::from(seq.color.bit_depth) {
                return Err(Error::invalid(format!(
                    "an L_p u'v' description of {}-bit planes in a {}-bit AV1 stream",
                    info.mapping.plane_bits, seq.color.bit_depth
                )));
            }
            // Transfer and range are unused for L_p u'v' planes.
            (Transfer::Pq, Range::Full, stream_subsampling(&seq)?, Some((info, info.psi()?)))
        } else if sdr {
            let sdr_description =
                ColorDescription { color_primaries: 1, transfer_characteristics: 13, matrix_coefficients: 1 };
            if seq.color.color_description != Some(sdr_description) {
                return Err(Error::unsupported(format!(
                    "8-bit AV1 with colour description {:?} (this decoder returns 8-bit SDR as BT.709 sRGB, 1/13/1)",
                    seq.color.color_description
                )));
            }
            let range = if seq.color.full_range { Range::Full } else { Range::Limited };
            // The transfer is unused: sRGB is decoded by `sdr`.
            (Transfer::Pq, range, stream_subsampling(&seq)?, None)
        } else {
            let (transfer, range, subsampling) = stream_format(&seq, options.hlg_peak_nits)?;
            (transfer, range, subsampling, None)
        };
        let (width, height) = (seq.max_frame_width, seq.max_frame_height);
        options.limits.check_dimensions(width.into(), height.into())?;
        let info = stream_info(&seq, &summary, transfer, subsampling, lpuv.as_ref().map(|l| &l.0), sdr, options)?;
        // Our streams say colocated; VERTICAL and an unsignalled position (0, what SVT-AV1 and
        // libaom write) are taken as "left", H.273's default.
        let siting = if seq.color.chroma_sample_position == chroma_sample_position::COLOCATED {
            ChromaSiting::Colocated
        } else {
            ChromaSiting::Left
        };
        let light = match (&lpuv, sdr) {
            (None, false) => {
                Some(YuvToLight::new(seq.color.bit_depth.into(), transfer, range, siting, options.nits_per_unit)?)
            }
            _ => None,
        };
        let mut settings = dav1d::Settings::new();
        // One picture out per temporal unit in: frame threading would delay output.
        settings.set_n_threads(1);
        settings.set_max_frame_delay(1);
        settings.set_frame_size_limit(u32::try_from(options.limits.max_pixels).unwrap_or(u32::MAX));
        let decoder = dav1d::Decoder::with_settings(&settings).map_err(|e| Error::invalid(format!("dav1d: {e}")))?;
        // Samples that carry their own sequence header need no prefix.
        let prefix = config.filter(|_| !summary_has_inline_header(data, &options.limits));
        Ok(Av1Decoder {
            units,
            prefix,
            decoder,
            summary,
            transfer,
            range,
            subsampling,
            siting,
            lpuv,
            sdr,
            light,
            planes: None,
            bit_depth: seq.color.bit_depth.into(),
            options: options.clone(),
            width,
            height,
            pending: false,
            flushed: false,
            returned: 0,
            info,
        })
    }

    /// What the stream's headers and metadata OBUs say.
    pub fn summary(&self) -> &StreamSummary {
        &self.summary
    }

    /// The transfer function the stream declares.
    pub fn transfer(&self) -> Transfer {
        self.transfer
    }

    /// The L_p u'v' description of the stream, if it is one.
    pub fn lpuv(&self) -> Option<&LpuvStreamInfo> {
        self.lpuv.as_ref().map(|(info, _)| info)
    }

    /// The next frame's planes as coded (10-bit; 10- or 12-bit for L_p u'v', 8-bit for SDR), or `None` after the last.
    pub fn next_planes(&mut self) -> Result<Option<YuvFrame>> {
        Ok(if self.decode_planes()? { self.planes.take() } else { None })
    }

    /// Decodes the next picture into `self.planes`; false after the last.
    fn decode_planes(&mut self) -> Result<bool> {
        // Each round either returns, takes input, or notices that neither side moves.
        let mut stalled = 0;
        loop {
            match self.decoder.get_picture() {
                Ok(picture) => {
                    let mut planes = self.planes.take();
                    self.planes_of(&picture, &mut planes)?;
                    self.planes = planes;
                    return Ok(true);
                }
                Err(e) if e.is_again() => {}
                Err(e) => return Err(Error::invalid(format!("dav1d: {e}"))),
            }
            if self.pending {
                // dav1d kept part of the last temporal unit until a picture came out.
                self.pending = false;
                let result = self.decoder.send_pending_data();
                self.pending = self.accepted(result)?;
                stalled += 1;
                if stalled > 2 {
                    return Err(Error::invalid("dav1d neither takes data nor returns a picture"));
                }
                continue;
            }
            if self.flushed {
                return Ok(false);
            }
            if let Some(obus) = self.prefix.take() {
                let result = self.decoder.send_data(obus, None, None, None);
                self.pending = self.accepted(result)?;
                continue;
            }
            match self.units.next_unit()? {
                Some((pts, data)) => {
                    let timestamp = i64::try_from(pts).ok();
                    let result = self.decoder.send_data(data.to_vec(), None, timestamp, None);
                    self.pending = self.accepted(result)?;
                }
                // No more input: what dav1d still holds comes out of get_picture.
                None => self.flushed = true,
            }
        }
    }

    /// Whether dav1d kept data back (`Again`), or the error it reported.
    fn accepted(&self, result: std::result::Result<(), dav1d::Error>) -> Result<bool> {
        match result {
            Ok(()) => Ok(false),
            Err(e) if e.is_again() => Ok(true),
            Err(e) => Err(Error::invalid(format!("dav1d cannot decode this temporal unit: {e}"))),
        }
    }

    /// Size, colour (with the stream's HDR10 metadata and `nits_per_unit`) and frame count
    /// of the decoded frames, as [`next_frame`](Self::next_frame) will return them.
    pub fn info(&self) -> &ImageInfo {
        &self.info
    }

    /// The next frame as scene-linear light: BT.2020 with the stream's HDR10 metadata, or for
    /// L_p u'v' the primaries its T.35 names. The frame is charged to the limits before dav1d
    /// decodes it, for as long as it is being made (the caller's frames are the caller's to
    /// count; [`decode_ivf`] keeps every frame's charge).
    pub fn next_frame(&mut self) -> Result<Option<HdrImage>> {
        let _charge = if self.returned < self.summary.temporal_units {
            Some(self.options.limits.charge_image(self.width.into(), self.height.into(), Channels::Rgb)?)
        } else {
            None
        };
        self.next_frame_uncharged()
    }

    /// [`next_frame`](Self::next_frame) without charging the limits.
    fn next_frame_uncharged(&mut self) -> Result<Option<HdrImage>> {
        if !self.decode_planes()? {
            return Ok(None);
        }
        let Some(yuv) = self.planes.as_ref() else { return Ok(None) };
        self.returned += 1;
        if let Some((info, psi)) = &self.lpuv {
            let color = ColorInfo {
                primaries: info.primaries()?,
                nits_per_unit: self.options.nits_per_unit,
                ..ColorInfo::default()
            };
            return lpuv_yuv_to_frame(psi, yuv, color, info.mapping).map(Some);
        }
        if self.sdr {
            return sdr_yuv_to_frame(yuv, self.range, self.siting, self.options.nits_per_unit).map(Some);
        }
        let mut image = match &self.light {
            Some(light) => light.convert(yuv, &self.options.pool)?,
            None => yuv_to_frame(yuv, self.transfer, self.range, self.siting, self.options.nits_per_unit)?,
        };
        image.color.primaries = ColorPrimaries::Bt2020;
        image.color.hdr10 = self.summary.hdr10();
        Ok(Some(image))
    }

    /// The planes of `picture` in `planes` (reusing its buffers when there are some).
    fn planes_of(&self, picture: &dav1d::Picture, planes: &mut Option<YuvFrame>) -> Result<()> {
        let (w, h) = (picture.width() as usize, picture.height() as usize);
        if (w as u32, h as u32) != (self.width, self.height) {
            return Err(Error::unsupported(format!(
                "a {w}x{h} frame in a {}x{} stream (frame size changes)",
                self.width, self.height
            )));
        }
        let layout = match picture.pixel_layout() {
            PixelLayout::I420 => Subsampling::Yuv420,
            PixelLayout::I444 => Subsampling::Yuv444,
            other => return Err(Error::unsupported(format!("dav1d picture layout {other:?}"))),
        };
        if layout != self.subsampling || picture.bit_depth() != self.bit_depth as usize {
            return Err(Error::invalid("a decoded picture does not match the sequence header"));
        }
        let (cw, ch) = YuvFrame::chroma_size(w, h, layout);
        let out = planes.get_or_insert_with(|| YuvFrame {
            width: w,
            height: h,
            subsampling: layout,
            y: Vec::new(),
            cb: Vec::new(),
            cr: Vec::new(),
        });
        let plane = |c: PlanarImageComponent, pw: usize, ph: usize, out: &mut Vec<u16>| {
            copy_plane(&picture.plane(c), picture.stride(c) as usize, pw, ph, self.bit_depth, out)
        };
        plane(PlanarImageComponent::Y, w, h, &mut out.y)?;
        plane(PlanarImageComponent::U, cw, ch, &mut out.cb)?;
        plane(PlanarImageComponent::V, cw, ch, &mut out.cr)?;
        (out.width, out.height, out.subsampling) = (w, h, layout);
        Ok(())
    }
}

/// True when the first temporal unit of the stream holds a sequence header.
fn summary_has_inline_header(data: &[u8], limits: &Limits) -> bool {
    let first = TemporalUnits::open(data, limits).ok().and_then(|mut u| u.next_unit().ok().flatten());
    first.is_some_and(|(_, unit)| {
        crate::obu::ObuReader::new(unit).flatten().any(|o| o.obu_type == crate::obu::obu_type::SEQUENCE_HEADER)
    })
}

/// Decodes every frame of an AV1 stream in IVF or MP4.
pub fn decode_ivf(data: &[u8], options: &Av1DecodeOptions) -> Result<Vec<HdrImage>> {
    let mut decoder = Av1Decoder::new(data, options)?;
    let (mut frames, mut charges) = (Vec::new(), Vec::new());
    loop {
        // Charged before dav1d decodes the frame, so a long stream stops at the budget.
        let charge = options.limits.charge_image(decoder.width.into(), decoder.height.into(), Channels::Rgb)?;
        match decoder.next_frame_uncharged()? {
            Some(frame) => {
                frames.push(frame);
                charges.push(charge);
            }
            None => return Ok(frames),
        }
    }
}

/// The family's stream-decoder trait, for a decoder that owns its share of the data
/// ([`Av1Decoder::from_shared`]).
impl hdrcodec_core::VideoDecoder for Av1Decoder<'static> {
    fn info(&self) -> &ImageInfo {
        Av1Decoder::info(self)
    }

    fn next_frame(&mut self) -> Result<Option<HdrImage>> {
        Av1Decoder::next_frame(self)
    }
}
