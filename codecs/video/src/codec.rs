//! AV1 as the family's stream codec: [`Av1Codec`] implements core's [`VideoCodec`], so that
//! tools can start an encoder or a decoder of AV1 streams as they do for `.hdrc` frame
//! sequences, with core's [`EncodeSettings`] and [`DecodeOptions`].

use hdrcodec_core::{
    DecodeOptions, EncodeSettings, Error, ImageInfo, Result, VideoCodec, VideoDecoder, VideoEncoder, WriteSeek,
};
use std::io::Write;
use std::sync::Arc;

/// AV1 (rav1e to encode, libdav1d to decode) as a [`VideoCodec`]: name `av1`, extensions
/// `ivf` and `mp4`.
///
/// - [`begin_encode`](VideoCodec::begin_encode) writes the container of option `container`:
///   `ivf` (default) as it goes; `mp4`, `mkv` and `webm` into memory first, copied to the
///   writer when the stream finishes (their sizes are patched in place, which the trait's plain
///   `Write` cannot do), the memory bounded by option `max_memory` (a `LimitExceeded` error
///   past it, with nothing written). [`begin_encode_seekable`](VideoCodec::begin_encode_seekable) writes
///   every container straight to a writer that seeks (the CLI's atomic file). The stream's
///   frame count (`info.frames`, 0 when unknown) goes into the IVF header; its mastering
///   display and MaxCLL/MaxFALL are `info.color.hdr10`'s (an encoder that streams cannot
///   measure them before the first frame; none are written when absent).
///   [`finish_report`](VideoEncoder::finish_report) gives the frames, bytes, clipped samples
///   and content light written. Settings: see [`av1_options`](Av1Codec::av1_options).
/// - [`begin_decode`](VideoCodec::begin_decode) reads IVF or MP4; the decoder's
///   [`info`](VideoDecoder::info) gives the size, colour (BT.2020 with the stream's HDR10
///   metadata, or for L_p u'v' the primaries its T.35 names), `nits_per_unit` and the frame
///   count (always known: the temporal units are walked when decoding begins). Each
///   [`next_frame`](VideoDecoder::next_frame) charges its frame to `options.limits` before
///   dav1d decodes it. Options: [`DECODE_OPTIONS`](Av1Codec::DECODE_OPTIONS).
#[derive(Clone, Copy, Debug, Default)]
pub struct Av1Codec;

impl Av1Codec {
    /// The `key=value` options of [`begin_encode`](VideoCodec::begin_encode).
    pub const ENCODE_OPTIONS: &'static [&'static str] = &[
        "transfer",
        "chroma",
        "bits",
        "range",
        "speed",
        "quantizer",
        "fps",
        "keyint",
        "tiles",
        "sdr_peak",
        "container",
        "max_memory",
    ];
    /// The `key=value` options of [`begin_decode`](VideoCodec::begin_decode): `nits_per_unit`
    /// (cd/m² of a decoded 1.0, default 100) and `hlg_peak` (the display an HLG stream is
    /// rendered for, cd/m², default 1000).
    pub const DECODE_OPTIONS: &'static [&'static str] = &["nits_per_unit", "hlg_peak"];

    /// The encoder options `settings` ask for, for frames that `info` describes:
    /// - `quality` 0-100 → rav1e's quantizer 255-0 ([`Av1Options::quantizer_for_quality`]),
    ///   unless `quantizer=Q` (0-255) is given;
    /// - `effort` 0-9 → rav1e speed 10 − effort, unless `speed=S` (0-10) is given;
    /// - `transfer=pq|hlg|mantiuk` (default pq; mantiuk codes L_p u'v' in the primaries of
    ///   `info.color`, every frame with its T.35 message), `chroma=420|444` (default 420, 444
    ///   for mantiuk), `bits=10|12` (mantiuk only: 10-bit ψ codes in 10-bit planes, with 4:2:0
    ///   AV1's Main profile, or 11-bit codes in 12-bit Professional-profile planes; default
    ///   12), `range=limited|full`, `fps=N` (default 25), `keyint=N` (frames between
    ///   key frames, default 240), `tiles=N`;
    /// - `sdr_peak=NITS`: code the SDR rendition of the frames for a display of that peak
    ///   instead ([`crate::sdr`]; 8-bit BT.709, sRGB transfer);
    /// - `container=ivf|mp4|mkv|webm` (default ivf): read by `begin_encode`, not here
    ///   ([`container`](Av1Codec::container));
    /// - `max_memory=BYTES`: the most an MP4 or Matroska file built in memory by `begin_encode`
    ///   may hold (default 4 GiB, [`Limits::default`](hdrcodec_core::Limits)'s); read by
    ///   `begin_encode` ([`memory_limits`](Av1Codec::memory_limits)), not here;
    /// - threads from `settings.pool`; mastering display and content light from
    ///   `info.color.hdr10` (PQ only).
    ///
    /// Unknown keys and values that do not parse are errors.
    ///
    /// [`Av1Options::quantizer_for_quality`]: crate::encode::Av1Options::quantizer_for_quality
    #[cfg(feature = "encode")]
    pub fn av1_options(info: &ImageInfo, settings: &EncodeSettings) -> Result<crate::encode::Av1Options> {
        use crate::encode::Av1Options;
        use crate::hdr10::{Range, Subsampling, Transfer};
        use crate::lpuv_av1::LpuvStreamInfo;
        settings.check_options("av1", Self::ENCODE_OPTIONS)?;
        let mut o = Av1Options { pool: settings.pool.clone(), ..Av1Options::default() };
        let mantiuk = match settings.option("transfer").map(str::to_ascii_lowercase).as_deref() {
            None | Some("pq") => false,
            Some("hlg") => {
                o.transfer = Transfer::HLG_1000;
                false
            }
            Some("mantiuk") => true,
            Some(other) => return Err(Error::invalid(format!("transfer={other}: expected pq, hlg or mantiuk"))),
        };
        o.subsampling = match settings.option("chroma") {
            None if mantiuk => Subsampling::Yuv444,
            None | Some("420") => Subsampling::Yuv420,
            Some("444") => Subsampling::Yuv444,
            Some(other) => return Err(Error::invalid(format!("chroma={other}: expected 420 or 444"))),
        };
        o.range = match settings.option("range").map(str::to_ascii_lowercase).as_deref() {
            None | Some("limited") => Range::Limited,
            Some("full") => Range::Full,
            Some(other) => return Err(Error::invalid(format!("range={other}: expected limited or full"))),
        };
        o.quantizer = match settings.parse_option::<u8>("quantizer")? {
            Some(q) => q,
            None => Av1Options::quantizer_for_quality(settings.quality),
        };
        o.speed = match settings.parse_option::<u8>("speed")? {
            Some(s) if s <= 10 => s,
            Some(s) => return Err(Error::invalid(format!("speed={s}: expected 0 (slowest) to 10 (fastest)"))),
            None => 10 - settings.effort.min(EncodeSettings::MAX_EFFORT),
        };
        if let Some(fps) = settings.parse_option::<u32>("fps")? {
            o.fps = fps.max(1);
        }
        if let Some(k) = settings.parse_option::<u64>("keyint")? {
            o.keyframe_interval = k.max(1);
        }
        if let Some(t) = settings.parse_option::<usize>("tiles")? {
            o.tiles = t;
        }
        if let Some(peak) = settings.parse_option::<f64>("sdr_peak")? {
            o.sdr = Some(crate::sdr::SdrRendition::new(peak)?);
        }
        let main10 = match settings.parse_option::<u8>("bits")? {
            None | Some(12) => false,
            Some(10) if mantiuk => true,
            Some(b) if mantiuk => return Err(Error::invalid(format!("bits={b}: expected 10 or 12"))),
            Some(_) => return Err(Error::invalid("bits= is for transfer=mantiuk (HDR10 and HLG are 10-bit)")),
        };
        if mantiuk {
            // The decoder returns the stream's primaries; every T.35 must reach its frame.
            let primaries = info.color.primaries;
            o.lpuv =
                Some(if main10 { LpuvStreamInfo::main10(primaries) } else { LpuvStreamInfo::for_primaries(primaries) });
            o.low_latency = true;
        } else if let Some(h) = &info.color.hdr10 {
            if let Some(md) = h.mastering_display {
                o.mastering_display = md;
            }
            o.content_light = h.content_light_level;
        }
        Ok(o)
    }

    /// The budget of an MP4 or Matroska file that `begin_encode` builds in memory: option
    /// `max_memory=BYTES`, else [`Limits::default`](hdrcodec_core::Limits).
    pub fn memory_limits(settings: &EncodeSettings) -> Result<hdrcodec_core::Limits> {
        let limits = hdrcodec_core::Limits::default();
        Ok(match settings.parse_option::<u64>("max_memory")? {
            Some(bytes) => limits.with_max_alloc_bytes(bytes),
            None => limits,
        })
    }

    /// The container option `container` names: `ivf` (default), `mp4`, `mkv` or `webm`.
    pub fn container(settings: &EncodeSettings) -> Result<Av1Container> {
        match settings.option("container").map(str::to_ascii_lowercase).as_deref() {
            None | Some("ivf") => Ok(Av1Container::Ivf),
            Some("mp4") => Ok(Av1Container::Mp4),
            Some("mkv") => Ok(Av1Container::Matroska),
            Some("webm") => Ok(Av1Container::WebM),
            Some(other) => Err(Error::invalid(format!("container={other}: expected ivf, mp4, mkv or webm"))),
        }
    }

    /// The decoder options `options` ask for (see [`DECODE_OPTIONS`](Self::DECODE_OPTIONS)).
    #[cfg(feature = "decode")]
    pub fn av1_decode_options(options: &DecodeOptions) -> Result<crate::decode::Av1DecodeOptions> {
        let mut o = crate::decode::Av1DecodeOptions {
            limits: options.limits.clone(),
            pool: options.pool.clone(),
            ..Default::default()
        };
        if let Some(n) = options.parse_option::<f32>("nits_per_unit")? {
            if !(n.is_finite() && n > 0.0) {
                return Err(Error::invalid(format!("nits_per_unit={n}: expected a positive number")));
            }
            o.nits_per_unit = n;
        }
        if let Some(p) = options.parse_option::<f64>("hlg_peak")? {
            if !(p.is_finite() && p > 0.0) {
                return Err(Error::invalid(format!("hlg_peak={p}: expected a positive number of cd/m²")));
            }
            o.hlg_peak_nits = p;
        }
        Ok(o)
    }
}

/// The files [`Av1Codec`] writes (its option `container`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Av1Container {
    /// IVF: written as the stream goes, no seeking.
    Ivf,
    /// MP4 (`av01` with `av1C`, `colr`, `mdcv`, `clli`).
    Mp4,
    /// Matroska (DocType `matroska`) with the colour elements.
    Matroska,
    /// WebM (Matroska with DocType `webm`).
    WebM,
}

impl VideoCodec for Av1Codec {
    fn name(&self) -> &'static str {
        "av1"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["ivf", "mp4", "mkv", "webm"]
    }

    fn begin_encode(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
        out: Box<dyn Write + Send>,
    ) -> Result<Box<dyn VideoEncoder>> {
        #[cfg(feature = "encode")]
        {
            use crate::encode::{Av1Encoder, InMemory};
            use crate::mkv::MkvWriter;
            use crate::mp4::Mp4Writer;
            use std::io::Cursor;
            let options = Self::av1_options(info, settings)?;
            let limits = Self::memory_limits(settings)?;
            let (w, h, fps) = (info.width, info.height, options.fps.max(1));
            let memory = || Cursor::new(Vec::new());
            Ok(match Self::container(settings)? {
                Av1Container::Ivf => Box::new(Av1Encoder::begin(w, h, info.frames, &options, out)?),
                Av1Container::Mp4 => {
                    let sink = InMemory::with_limits(Mp4Writer::new(memory(), fps)?, out, &limits);
                    Box::new(Av1Encoder::with_sink(w, h, &options, sink)?)
                }
                c @ (Av1Container::Matroska | Av1Container::WebM) => {
                    let sink =
                        InMemory::with_limits(MkvWriter::new(memory(), fps, c == Av1Container::WebM)?, out, &limits);
                    Box::new(Av1Encoder::with_sink(w, h, &options, sink)?)
                }
            })
        }
        #[cfg(not(feature = "encode"))]
        {
            let _ = (info, settings, out);
            Err(Error::unsupported("AV1 encoding: hdrcodec-video was built without its `encode` feature"))
        }
    }

    fn begin_encode_seekable<'a>(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
        out: Box<dyn WriteSeek + Send + 'a>,
    ) -> Result<Box<dyn VideoEncoder + 'a>> {
        #[cfg(feature = "encode")]
        {
            use crate::encode::Av1Encoder;
            let options = Self::av1_options(info, settings)?;
            let (w, h) = (info.width, info.height);
            Ok(match Self::container(settings)? {
                Av1Container::Ivf => Box::new(Av1Encoder::begin(w, h, info.frames, &options, out)?),
                Av1Container::Mp4 => Box::new(Av1Encoder::begin_mp4(w, h, &options, out)?),
                c @ (Av1Container::Matroska | Av1Container::WebM) => {
                    Box::new(Av1Encoder::begin_mkv(w, h, &options, out, c == Av1Container::WebM)?)
                }
            })
        }
        #[cfg(not(feature = "encode"))]
        {
            let _ = (info, settings, out);
            Err(Error::unsupported("AV1 encoding: hdrcodec-video was built without its `encode` feature"))
        }
    }

    fn begin_decode(&self, data: Arc<[u8]>, options: &DecodeOptions) -> Result<Box<dyn VideoDecoder>> {
        #[cfg(feature = "decode")]
        {
            let options = Self::av1_decode_options(options)?;
            Ok(Box::new(crate::decode::Av1Decoder::from_shared(data, &options)?))
        }
        #[cfg(not(feature = "decode"))]
        {
            let _ = (data, options);
            Err(Error::unsupported("AV1 decoding: hdrcodec-video was built without its `decode` feature"))
        }
    }
}
