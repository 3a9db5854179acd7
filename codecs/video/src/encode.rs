//! HDR10 (PQ) and HLG encoding to AV1 with rav1e, written as IVF.
//!
//! The stream is 10-bit BT.2020 non-constant-luminance Y'CbCr (Main profile for 4:2:0, High for
//! 4:4:4). Its sequence header carries the colour description 9/16/9 (PQ) or 9/18/9 (HLG), the
//! range, and `chroma_sample_position` = colocated (what [`crate::hdr10`] downsamples to); each
//! key frame carries HDR_CLL and HDR_MDCV metadata OBUs (PQ only; rav1e repeats them on every key
//! frame). MaxCLL/MaxFALL must be known before the first frame is coded: [`encode_sequence`]
//! walks the frames twice (measure, then encode); the streaming [`Av1Encoder`] takes them as an
//! option.

use crate::hdr10::{content_light_level, frame_to_yuv, ClipReport, Range, Subsampling, Transfer, BIT_DEPTH};
use crate::ivf::{IvfHeader, IvfWriter};
use crate::lpuv_av1::{frame_to_lpuv_yuv, LpuvStreamInfo, T35_COUNTRY_CODE, T35_COUNTRY_CODE_EXTENSION};
use crate::mantiuk::Psi04;
use crate::mkv::MkvWriter;
use crate::mp4::Mp4Writer;
use crate::sdr::{SdrRendition, SDR_BIT_DEPTH};
use hdrcodec_core::{
    Allocation, ContentLightLevel, Error, HdrImage, Limits, MasteringDisplay, Result, StreamReport, ThreadPool,
    VideoEncoder,
};
use rav1e::color::{
    ChromaSamplePosition, ChromaSampling, ChromaticityPoint, ColorDescription, ColorPrimaries, ContentLight,
    MasteringDisplay as Rav1eMasteringDisplay, MatrixCoefficients, PixelRange, TransferCharacteristics,
};
use rav1e::config::{Config, EncoderConfig, RateControlConfig};
use rav1e::data::{EncoderStatus, FrameParameters, FrameType, Rational};
use rav1e::Context;
use std::io::{Cursor, Seek, Write};

/// An ITU-T T.35 message to attach to every frame (AV1 `metadata_itut_t35`, §5.8.2).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct T35Message {
    /// `itu_t_t35_country_code`.
    pub country_code: u8,
    /// `itu_t_t35_country_code_extension_byte`, written only when `country_code` is 0xFF.
    pub country_code_extension: u8,
    /// The payload (for most country codes it starts with a terminal provider code).
    pub payload: Vec<u8>,
}

/// How to encode. `Default` is HDR10: PQ, limited range, 4:2:0, quantizer 100 at speed 6,
/// mastering display BT.2020 D65 1000 / 0.0001 cd/m².
#[derive(Clone, Debug)]
pub struct Av1Options {
    /// PQ (HDR10) or HLG.
    pub transfer: Transfer,
    /// Limited (default) or full range.
    pub range: Range,
    /// 4:2:0 (default) or 4:4:4.
    pub subsampling: Subsampling,
    /// rav1e's base quantizer, 0 (best) to 255. Ignored when `bitrate_kbps` is set.
    pub quantizer: u8,
    /// Target bitrate in kbit/s (rav1e's rate control) instead of a fixed quantizer.
    pub bitrate_kbps: Option<u32>,
    /// rav1e speed preset, 0 (slowest, smallest) to 10 (fastest).
    pub speed: u8,
    /// Longest distance between key frames, in frames.
    pub keyframe_interval: u64,
    /// Tiles (rav1e rounds to a power-of-two grid); 0 lets rav1e choose.
    pub tiles: usize,
    /// Frames per second (the IVF and AV1 time base is 1/fps).
    pub fps: u32,
    /// No frame reordering: every frame is shown when coded. Needed for `t35` to reach every
    /// temporal unit (rav1e 0.8 drops the T.35 of frames it codes as hidden).
    pub low_latency: bool,
    /// `seq_level_idx` (AV1 Annex A: (major − 2)·4 + minor); `None` picks the smallest level
    /// whose picture size and display rate fit, or 31 (unconstrained) if none does.
    pub level_idx: Option<u8>,
    /// SMPTE ST 2086 mastering display (PQ only).
    pub mastering_display: MasteringDisplay,
    /// MaxCLL/MaxFALL. [`encode_sequence`] measures them when `None`; the streaming
    /// [`Av1Encoder`] then writes no HDR_CLL (0, 0 would mean "unknown" anyway).
    pub content_light: Option<ContentLightLevel>,
    /// A T.35 message for every frame (e.g. identifying the stream).
    pub t35: Option<T35Message>,
    /// Code L_p u'v' (Mantiuk et al. 2004) instead of Y'CbCr: planes of the curve, primaries
    /// and plane mapping given (12 bits, or 10 for [`LpuvStreamInfo::main10`]), no colour
    /// description, our T.35 on every frame ([`crate::lpuv_av1`]).
    /// `transfer`, `range`, the mastering display and the content light are then unused; set
    /// `low_latency` so that every frame keeps its T.35.
    pub lpuv: Option<LpuvStreamInfo>,
    /// Code an SDR rendition instead ([`crate::sdr`]): 8-bit BT.709 Y'CbCr on the sRGB transfer,
    /// colour description 1/13/1, limited range; `transfer`, `range`, `lpuv`, the mastering
    /// display and the content light are then unused.
    pub sdr: Option<SdrRendition>,
    /// The caller's worker threads, lent to rav1e.
    pub pool: ThreadPool,
}

impl Default for Av1Options {
    fn default() -> Self {
        Av1Options {
            transfer: Transfer::Pq,
            range: Range::Limited,
            subsampling: Subsampling::Yuv420,
            quantizer: 100,
            bitrate_kbps: None,
            speed: 6,
            keyframe_interval: 240,
            tiles: 0,
            fps: 25,
            low_latency: false,
            level_idx: None,
            mastering_display: MasteringDisplay::bt2020(1000.0, 0.0001),
            content_light: None,
            t35: None,
            lpuv: None,
            sdr: None,
            pool: ThreadPool::single(),
        }
    }
}

impl Av1Options {
    /// rav1e's quantizer for a 0-100 quality (100 best): linear, quality 100 → 0, 0 → 255.
    pub fn quantizer_for_quality(quality: u8) -> u8 {
        let q = u32::from(quality.min(100));
        ((100 - q) * 255).div_ceil(100) as u8
    }
}

/// What an encode did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EncodeSummary {
    /// Frames coded.
    pub frames: u64,
    /// Samples the clipping policy changed, over all frames.
    pub clipped: ClipReport,
    /// The content light level written, if any.
    pub content_light: Option<ContentLightLevel>,
    /// Bytes of the file written.
    pub bytes: u64,
}

/// AV1 Annex A.3 level limits: (seq_level_idx, MaxPicSize, MaxHSize, MaxVSize, MaxDisplayRate),
/// transcribed from the first table of A.3 (levels 2.0 to 6.3; the levels the table leaves
/// out, such as 2.2 and 7.0, are undefined and never chosen). MaxDisplayRate, not the table's
/// MaxDecodeRate column, bounds the shown-frame rate, which is what `fps` gives.
const LEVELS: [(u8, u64, u64, u64, u64); 14] = [
    (0, 147_456, 2048, 1152, 4_423_680),
    (1, 278_784, 2816, 1584, 8_363_520),
    (4, 665_856, 4352, 2448, 19_975_680),
    (5, 1_065_024, 5504, 3096, 31_950_720),
    (8, 2_359_296, 6144, 3456, 70_778_880),
    (9, 2_359_296, 6144, 3456, 141_557_760),
    (12, 8_912_896, 8192, 4352, 267_386_880),
    (13, 8_912_896, 8192, 4352, 534_773_760),
    (14, 8_912_896, 8192, 4352, 1_069_547_520),
    (15, 8_912_896, 8192, 4352, 1_069_547_520),
    (16, 35_651_584, 16384, 8704, 1_069_547_520),
    (17, 35_651_584, 16384, 8704, 2_139_095_040),
    (18, 35_651_584, 16384, 8704, 4_278_190_080),
    (19, 35_651_584, 16384, 8704, 4_278_190_080),
];

/// The smallest level whose picture-size and display-rate limits hold `width` × `height` at
/// `fps`; 31 (no level constraint) when none does.
pub fn level_for(width: u32, height: u32, fps: u32) -> u8 {
    let (w, h) = (u64::from(width), u64::from(height));
    let rate = w * h * u64::from(fps.max(1));
    LEVELS
        .iter()
        .find(|&&(_, pic, max_w, max_h, display)| w * h <= pic && w <= max_w && h <= max_h && rate <= display)
        .map_or(31, |l| l.0)
}

/// rav1e's mastering display from core's (AV1 units through core's conversion).
fn rav1e_mastering_display(md: &MasteringDisplay) -> Rav1eMasteringDisplay {
    let u = md.to_av1();
    let point = |xy: [u16; 2]| ChromaticityPoint { x: xy[0], y: xy[1] };
    Rav1eMasteringDisplay {
        primaries: u.primaries.map(point),
        white_point: point(u.white),
        max_luminance: u.luminance_max,
        min_luminance: u.luminance_min,
    }
}

fn rav1e_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::invalid(format!("rav1e {what}: {e}"))
}

/// Where coded temporal units go: an IVF file ([`IvfWriter`]) or an MP4 track ([`Mp4Writer`]).
pub trait TemporalUnitSink {
    /// What [`finish`](Self::finish) hands back (the writer's output).
    type Output;
    /// Stores one temporal unit shown at frame `pts`; `keyframe` when it starts with a key frame.
    fn write_temporal_unit(&mut self, pts: u64, data: &[u8], keyframe: bool) -> Result<()>;
    /// Completes the file; returns the output and the file's length in bytes.
    fn finish(self) -> Result<(Self::Output, u64)>;
}

impl<W: Write> TemporalUnitSink for IvfWriter<W> {
    type Output = W;
    fn write_temporal_unit(&mut self, pts: u64, data: &[u8], _keyframe: bool) -> Result<()> {
        self.write_frame(pts, data)
    }
    fn finish(self) -> Result<(W, u64)> {
        let bytes = self.bytes_written();
        Ok((IvfWriter::finish(self)?, bytes))
    }
}

impl<W: Write + Seek> TemporalUnitSink for Mp4Writer<W> {
    type Output = W;
    fn write_temporal_unit(&mut self, _pts: u64, data: &[u8], keyframe: bool) -> Result<()> {
        Mp4Writer::write_temporal_unit(self, data, keyframe)
    }
    fn finish(self) -> Result<(W, u64)> {
        Mp4Writer::finish(self)
    }
}

/// Encodes frames of scene-linear light as they come, to IVF (or any [`TemporalUnitSink`]).
pub struct Av1Encoder<S: TemporalUnitSink> {
    ctx: Context<u16>,
    sink: S,
    /// The luma curve when the planes are L_p u'v'.
    psi: Option<Psi04>,
    /// The T.35 messages every frame carries.
    t35: Vec<T35Message>,
    options: Av1Options,
    width: u32,
    height: u32,
    frames_in: u64,
    summary: EncodeSummary,
}

impl<W: Write> Av1Encoder<IvfWriter<W>> {
    /// Starts a stream of `width` × `height` frames to IVF; `frame_count` goes into the IVF
    /// header (0 when unknown). The content light level is `options.content_light` (none if `None`).
    pub fn begin(width: u32, height: u32, frame_count: u32, options: &Av1Options, out: W) -> Result<Self> {
        let (ivf_w, ivf_h) = match (u16::try_from(width), u16::try_from(height)) {
            (Ok(w), Ok(h)) => (w, h),
            _ => return Err(Error::unsupported(format!("{width}x{height}: IVF records at most 65535x65535"))),
        };
        let ivf = IvfWriter::new(out, &IvfHeader::av1(ivf_w, ivf_h, options.fps.max(1), frame_count))?;
        Self::with_sink(width, height, options, ivf)
    }
}

impl<W: Write + Seek> Av1Encoder<Mp4Writer<W>> {
    /// Starts a stream of `width` × `height` frames to an MP4 file with the HDR boxes.
    pub fn begin_mp4(width: u32, height: u32, options: &Av1Options, out: W) -> Result<Self> {
        let mp4 = Mp4Writer::new(out, options.fps.max(1))?;
        Self::with_sink(width, height, options, mp4)
    }
}

impl<W: Write + Seek> TemporalUnitSink for MkvWriter<W> {
    type Output = W;
    fn write_temporal_unit(&mut self, pts: u64, data: &[u8], keyframe: bool) -> Result<()> {
        MkvWriter::write_temporal_unit(self, pts, data, keyframe)
    }
    fn finish(self) -> Result<(W, u64)> {
        MkvWriter::finish(self)
    }
}

/// A container that seeks (MP4, Matroska) built in memory, copied to a writer that need not
/// seek when the stream is complete: how [`Av1Codec`](crate::codec::Av1Codec)'s
/// `begin_encode` writes MP4 and Matroska to the trait's plain `Write`. The whole file is held
/// in memory until then (the coded stream, not the frames), charged to [`Limits`]: each
/// temporal unit's bytes and [`INDEX_BYTES_PER_UNIT`] for its entries in the container's index,
/// before it is stored. A stream that would exceed the budget fails with
/// [`Error::LimitExceeded`] and nothing reaches the output writer (it is written only at
/// `finish`); `begin_encode_seekable` writes straight to a file instead, with no such bound.
pub struct InMemory<S, W> {
    inner: S,
    out: W,
    limits: Limits,
    /// Bytes of the file held (an estimate from above: units and their index entries).
    held: u64,
    /// Bytes charged to `limits`, in steps.
    charged: u64,
    charges: Vec<Allocation>,
}

/// The bytes [`InMemory`] charges for a temporal unit's entries in the container's index,
/// above its own bytes (MP4: `stsz`, `stts`, `stss`, `stco`/`co64` entries, at most 28 bytes;
/// Matroska: a SimpleBlock's element header, track number and timecode, at most 16, and a
/// Cluster's header now and then).
pub const INDEX_BYTES_PER_UNIT: u64 = 32;

/// The bytes [`InMemory`] charges for a file's own boxes or elements (MP4 `ftyp`, `moov`
/// without its tables; Matroska's header, `Info` and `Tracks`), before any temporal unit.
const FILE_BYTES: u64 = 1024;

/// The smallest step in which [`InMemory`] charges its limits (so that a long stream holds a
/// few hundred charges, not one per frame).
const CHARGE_STEP: u64 = 1 << 20;

impl<S, W> InMemory<S, W> {
    /// `inner` writing into memory, then to `out`, within [`Limits::default`] (4 GiB).
    pub fn new(inner: S, out: W) -> Self {
        Self::with_limits(inner, out, &Limits::default())
    }

    /// `inner` writing into memory, then to `out`, the memory charged to `limits`.
    pub fn with_limits(inner: S, out: W, limits: &Limits) -> Self {
        InMemory { inner, out, limits: limits.clone(), held: FILE_BYTES, charged: 0, charges: Vec::new() }
    }

    /// Charges the limits for `bytes` more held in memory.
    fn hold(&mut self, bytes: u64) -> Result<()> {
        let need = self.held.saturating_add(bytes);
        if need > self.charged {
            let exact = need - self.charged;
            let what = "an MP4 or Matroska file built in memory (begin_encode to a writer that cannot seek; \
                        begin_encode_seekable has no such bound)";
            let charge = match self.limits.charge(exact.max(CHARGE_STEP), what) {
                Ok(c) => c,
                Err(_) => self.limits.charge(exact, what)?,
            };
            self.charged += charge.bytes();
            self.charges.push(charge);
        }
        self.held = need;
        Ok(())
    }
}

impl<S: TemporalUnitSink<Output = Cursor<Vec<u8>>>, W: Write> TemporalUnitSink for InMemory<S, W> {
    type Output = W;
    fn write_temporal_unit(&mut self, pts: u64, data: &[u8], keyframe: bool) -> Result<()> {
        self.hold(data.len() as u64 + INDEX_BYTES_PER_UNIT)?;
        self.inner.write_temporal_unit(pts, data, keyframe)
    }
    fn finish(self) -> Result<(W, u64)> {
        let (file, bytes) = self.inner.finish()?;
        let mut out = self.out;
        out.write_all(file.get_ref()).map_err(Error::Io)?;
        out.flush().map_err(Error::Io)?;
        Ok((out, bytes))
    }
}

impl<W: Write + Seek> Av1Encoder<MkvWriter<W>> {
    /// Starts a stream of `width` × `height` frames to a Matroska file (DocType `webm` when
    /// `webm`) with the colour elements.
    pub fn begin_mkv(width: u32, height: u32, options: &Av1Options, out: W, webm: bool) -> Result<Self> {
        let mkv = MkvWriter::new(out, options.fps.max(1), webm)?;
        Self::with_sink(width, height, options, mkv)
    }
}

impl<S: TemporalUnitSink> Av1Encoder<S> {
    /// Starts a stream of `width` × `height` frames whose temporal units go to `sink`.
    pub fn with_sink(width: u32, height: u32, options: &Av1Options, sink: S) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("frames of {width}x{height} pixels")));
        }
        let sdr = options.sdr.is_some();
        let lpuv_info = options.lpuv.as_ref().filter(|_| !sdr);
        if let Some(info) = lpuv_info {
            info.check()?;
        }
        let lpuv = lpuv_info.is_some();
        let pq = options.transfer == Transfer::Pq && !lpuv && !sdr;
        let fps = options.fps.max(1);
        let mut enc = EncoderConfig::with_speed_preset(options.speed.min(10));
        enc.width = width as usize;
        enc.height = height as usize;
        enc.time_base = Rational::new(1, u64::from(fps));
        enc.bit_depth = if sdr {
            SDR_BIT_DEPTH
        } else if let Some(info) = lpuv_info {
            u32::from(info.mapping.plane_bits)
        } else {
            BIT_DEPTH
        } as usize;
        enc.chroma_sampling = match options.subsampling {
            Subsampling::Yuv420 => ChromaSampling::Cs420,
            Subsampling::Yuv444 => ChromaSampling::Cs444,
        };
        enc.chroma_sample_position = match options.subsampling {
            // L_p u'v' averages each 2x2 block: centred, which AV1 cannot signal.
            Subsampling::Yuv420 if !lpuv => ChromaSamplePosition::Colocated,
            _ => ChromaSamplePosition::Unknown,
        };
        enc.pixel_range = match options.range {
            // L_p u'v' codes use the whole range from 0.
            _ if lpuv => PixelRange::Full,
            _ if sdr => PixelRange::Limited,
            Range::Limited => PixelRange::Limited,
            Range::Full => PixelRange::Full,
        };
        enc.color_description = if sdr {
            Some(ColorDescription {
                color_primaries: ColorPrimaries::BT709,
                transfer_characteristics: TransferCharacteristics::SRGB,
                matrix_coefficients: MatrixCoefficients::BT709,
            })
        } else if lpuv {
            // The planes are no CICP space.
            None
        } else {
            Some(ColorDescription {
                color_primaries: ColorPrimaries::BT2020,
                transfer_characteristics: if pq {
                    TransferCharacteristics::SMPTE2084
                } else {
                    TransferCharacteristics::HLG
                },
                matrix_coefficients: MatrixCoefficients::BT2020NCL,
            })
        };
        if pq {
            enc.mastering_display = Some(rav1e_mastering_display(&options.mastering_display));
            enc.content_light = options.content_light.map(|c| ContentLight {
                max_content_light_level: c.max_cll,
                max_frame_average_light_level: c.max_fall,
            });
        }
        enc.level_idx = Some(options.level_idx.unwrap_or_else(|| level_for(width, height, fps)));
        enc.max_key_frame_interval = options.keyframe_interval.max(1);
        enc.min_key_frame_interval = enc.min_key_frame_interval.min(enc.max_key_frame_interval);
        enc.low_latency = options.low_latency;
        enc.quantizer = usize::from(options.quantizer);
        enc.bitrate = options.bitrate_kbps.map_or(0, |k| i32::try_from(u64::from(k) * 1000).unwrap_or(i32::MAX));
        enc.tiles = options.tiles;
        let mut cfg = Config::new().with_encoder_config(enc).with_rate_control(RateControlConfig::new());
        if let Some(pool) = options.pool.rayon_pool() {
            cfg = cfg.with_thread_pool(pool.clone());
        } else {
            cfg = cfg.with_threads(1);
        }
        let ctx = cfg.new_context::<u16>().map_err(|e| rav1e_error("configuration", e))?;
        let summary =
            EncodeSummary { content_light: if pq { options.content_light } else { None }, ..EncodeSummary::default() };
        let psi = options.lpuv.as_ref().filter(|_| lpuv).map(LpuvStreamInfo::psi).transpose()?;
        let mut t35: Vec<T35Message> = options
            .lpuv
            .iter()
            .filter(|_| lpuv)
            .map(|info| T35Message {
                country_code: T35_COUNTRY_CODE,
                country_code_extension: T35_COUNTRY_CODE_EXTENSION,
                payload: info.to_t35_payload(),
            })
            .collect();
        t35.extend(options.t35.iter().cloned());
        Ok(Av1Encoder { ctx, sink, psi, t35, options: options.clone(), width, height, frames_in: 0, summary })
    }

    /// Codes one frame (same size as the stream's).
    pub fn push_frame(&mut self, frame: &HdrImage) -> Result<()> {
        if (frame.width(), frame.height()) != (self.width, self.height) {
            return Err(Error::invalid(format!(
                "frame {} is {}x{}, the stream {}x{}",
                self.frames_in,
                frame.width(),
                frame.height(),
                self.width,
                self.height
            )));
        }
        let yuv = match (&self.options.sdr, &self.psi) {
            (Some(sdr), _) => sdr.frame_to_yuv(frame, self.options.subsampling),
            (None, Some(psi)) => {
                let mapping = self.options.lpuv.as_ref().map(|l| l.mapping).unwrap_or_default();
                frame_to_lpuv_yuv(psi, frame, self.options.subsampling, mapping)?
            }
            (None, None) => {
                let (yuv, clipped) =
                    frame_to_yuv(frame, self.options.transfer, self.options.range, self.options.subsampling);
                self.summary.clipped.add(&clipped);
                yuv
            }
        };
        let mut f = self.ctx.new_frame();
        let (cw, _) = crate::hdr10::YuvFrame::chroma_size(yuv.width, yuv.height, yuv.subsampling);
        for (plane, (data, w)) in f.planes.iter_mut().zip([(&yuv.y, yuv.width), (&yuv.cb, cw), (&yuv.cr, cw)]) {
            if self.options.sdr.is_some() {
                // 8-bit samples, one byte each.
                let bytes: Vec<u8> = data.iter().map(|&v| v as u8).collect();
                plane.copy_from_raw_u8(&bytes, w, 1);
            } else {
                let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
                plane.copy_from_raw_u8(&bytes, 2 * w, 2);
            }
        }
        let t35 = self
            .t35
            .iter()
            .map(|m| rav1e::prelude::T35 {
                country_code: m.country_code,
                country_code_extension_byte: m.country_code_extension,
                data: m.payload.clone().into_boxed_slice(),
            })
            .collect();
        let params = FrameParameters { t35_metadata: t35, ..FrameParameters::default() };
        match self.ctx.send_frame((f, params)) {
            Ok(()) => {}
            Err(e) => return Err(rav1e_error("send_frame", e)),
        }
        self.frames_in += 1;
        self.drain()
    }

    /// Writes every packet rav1e has ready; returns at `NeedMoreData` or the end.
    fn drain(&mut self) -> Result<()> {
        loop {
            match self.ctx.receive_packet() {
                Ok(packet) => {
                    let keyframe = packet.frame_type == FrameType::KEY;
                    self.sink.write_temporal_unit(packet.input_frameno, &packet.data, keyframe)?;
                    self.summary.frames += 1;
                }
                Err(EncoderStatus::Encoded) => {}
                Err(EncoderStatus::NeedMoreData) | Err(EncoderStatus::LimitReached) => return Ok(()),
                Err(e) => return Err(rav1e_error("encoding", e)),
            }
        }
    }

    /// Flushes rav1e and returns the summary and the output.
    pub fn finish(mut self) -> Result<(EncodeSummary, S::Output)> {
        self.ctx.flush();
        self.drain()?;
        if self.summary.frames != self.frames_in {
            return Err(Error::invalid(format!(
                "rav1e returned {} frames for {} sent",
                self.summary.frames, self.frames_in
            )));
        }
        let (out, bytes) = self.sink.finish()?;
        self.summary.bytes = bytes;
        Ok((self.summary, out))
    }
}

/// The family's stream-encoder trait (begin with [`Av1Encoder::begin`], push frames, finish).
impl<S: TemporalUnitSink + Send> VideoEncoder for Av1Encoder<S> {
    fn push_frame(&mut self, frame: &HdrImage) -> Result<()> {
        Av1Encoder::push_frame(self, frame)
    }

    fn finish(self: Box<Self>) -> Result<u64> {
        Av1Encoder::finish(*self).map(|(summary, _)| summary.frames)
    }

    /// Frames, bytes, the clipped samples and the content light level written.
    fn finish_report(self: Box<Self>) -> Result<StreamReport> {
        let (s, _) = Av1Encoder::finish(*self)?;
        Ok(StreamReport::new(s.frames, Some(s.bytes), s.clipped, s.content_light))
    }
}

/// `options` with MaxCLL and MaxFALL measured over `frames` when a PQ stream needs them and
/// they are not given (on the values that are coded: BT.2020, cd/m², after clipping).
fn with_content_light(frames: &[HdrImage], options: &Av1Options) -> Av1Options {
    let mut options = options.clone();
    if options.transfer == Transfer::Pq
        && options.lpuv.is_none()
        && options.sdr.is_none()
        && options.content_light.is_none()
    {
        options.content_light = Some(content_light_level(frames, options.transfer));
    }
    options
}

/// Codes every frame into `encoder` and completes its file.
fn encode_all<S: TemporalUnitSink>(
    mut encoder: Av1Encoder<S>,
    frames: &[HdrImage],
) -> Result<(EncodeSummary, S::Output)> {
    for f in frames {
        encoder.push_frame(f)?;
    }
    encoder.finish()
}

/// Encodes a whole sequence to IVF. When `options.content_light` is `None` (and the transfer is
/// PQ) MaxCLL and MaxFALL are first measured over all frames on the values that are coded
/// (BT.2020, cd/m², after clipping).
pub fn encode_sequence<W: Write>(frames: &[HdrImage], options: &Av1Options, out: W) -> Result<(EncodeSummary, W)> {
    let first = frames.first().ok_or_else(|| Error::invalid("no frames to encode"))?;
    let options = with_content_light(frames, options);
    let count = u32::try_from(frames.len()).unwrap_or(0);
    encode_all(Av1Encoder::begin(first.width(), first.height(), count, &options, out)?, frames)
}

/// [`encode_sequence`] to an MP4 file (`av01` with `av1C`, `colr`, `mdcv`, `clli`).
pub fn encode_sequence_mp4<W: Write + Seek>(
    frames: &[HdrImage],
    options: &Av1Options,
    out: W,
) -> Result<(EncodeSummary, W)> {
    let first = frames.first().ok_or_else(|| Error::invalid("no frames to encode"))?;
    let options = with_content_light(frames, options);
    encode_all(Av1Encoder::begin_mp4(first.width(), first.height(), &options, out)?, frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_follow_annex_a() {
        assert_eq!(level_for(96, 64, 25), 0);
        assert_eq!(level_for(1920, 1080, 30), 8); // 4.0
        assert_eq!(level_for(1920, 1080, 60), 9); // 4.1
        assert_eq!(level_for(3840, 2160, 60), 13); // 5.1
                                                   // Past a level's MaxDisplayRate (not its larger MaxDecodeRate) the next level is needed:
                                                   // 1920x1080 at 70 frames/s is 145 152 000 samples/s, over 4.1's 141 557 760.
        assert_eq!(level_for(1920, 1080, 68), 9); // 141 004 800: still 4.1
        assert_eq!(level_for(1920, 1080, 70), 12); // 5.0
                                                   // 1 078 272 000 samples/s: over 5.3's and 6.0's 1 069 547 520 (the same), so 6.1.
        assert_eq!(level_for(3840, 2160, 130), 17);
        assert_eq!(level_for(100_000, 10, 1), 31);
        assert_eq!(Av1Options::quantizer_for_quality(100), 0);
        assert_eq!(Av1Options::quantizer_for_quality(0), 255);
    }
}
