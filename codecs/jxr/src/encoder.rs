//! The JPEG XR encoder: samples to integers (the inverse of output formatting, T.832 9.10),
//! the forward colour transform, the forward lapped transform, quantization, prediction and
//! entropy coding (the decoder's steps of clause 9 run backwards), then the codestream headers
//! and the file container.
//!
//! What it writes so far: tiles in spatial or frequency order, every band or fewer (trimmed
//! flexbits too), 4:4:4, 4:2:2 or 4:2:0 from RGB, the pixel formats of [`SampleFormat`] (half,
//! float, RGBE, fixed point, padded half, 8-, 16- and 10-bit integer codes of sRGB, PQ or
//! linear light; the samples to integers in `input`), RGBA with a planar alpha codestream
//! where the format has an alpha variant, overlap 0, 1 or 2, one quantizer set per band and
//! channel for the whole image, lossless (quantizer 1, unscaled arithmetic, as JxrEncApp does)
//! or lossy (scaled arithmetic). The quality → quantizer mapping is provisional.

use crate::bits::BitWriter;
use crate::container::{self, ContainerMeta};
use crate::header::{self, Bands, ClrFmt, ImageHeader, PlaneHeader, QpSet, QpSource};
use crate::input::{Clipped, SampleCoder};
use crate::macroblock::{flex_mb_encode, PlaneEncoder};
use crate::mb::{MbCoeffs, MB_COEFFS};
use crate::output::{forward_cc, half_rgb_yuv};
use crate::predict;
use crate::quant;
use crate::transform::{
    forward_plane, forward_plane_in_place, ForwardRows, OperatorSet, OverlapMode, Plane, PlaneKind, TransformParams,
};
use hdrcodec_core::{Channels, EncodeReport, EncodeSettings, Error, HdrImage, Result, ThreadPool};

pub use crate::input::SampleFormat;

/// Mantissa bits of the mini-float that float samples are coded as (LEN_MANTISSA, T.832
/// 8.3.2.x; JxrEncApp's default).
pub const FLOAT_MANTISSA: u8 = 13;
/// Exponent bias of that mini-float (EXP_BIAS; JxrEncApp's default): with 13 mantissa bits,
/// the smallest non-zero value is 2^−16.
pub const FLOAT_EXP_BIAS: u8 = 4;

/// Chroma sampling of the colour codestream (INTERNAL_CLR_FMT, T.832 8.3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subsampling {
    /// YUV444: chroma at full resolution.
    Yuv444,
    /// YUV422: chroma halved horizontally.
    Yuv422,
    /// YUV420: chroma halved both ways.
    Yuv420,
}

/// The order of a tile's data (FREQUENCY_MODE_CODESTREAM_FLAG, T.832 8.3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BitstreamOrder {
    /// One packet per tile, each macroblock's bands together (T.832 8.4.1).
    Spatial,
    /// Up to four packets per tile, DC, LP, HP and FLEXBITS (T.832 8.4.2): a decoder can stop
    /// after the bands it needs.
    Frequency,
}

/// Encoder options.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodeOptions {
    /// 0-100; 100 is lossless.
    pub quality: u8,
    /// OVERLAP_MODE; `None`: JxrEncApp's choice (1 from quality 50 up, 2 below).
    pub overlap: Option<OverlapMode>,
    /// The stored sample format.
    pub format: SampleFormat,
    /// Tile width and height in macroblocks (16 pixels); 0: one tile. Tiles are coded
    /// independently, so that decoders (ours) can decode them in parallel.
    pub tile_mbs: usize,
    /// Lossy only: choose each macroblock's LP and HP quantizers from its luminance (see
    /// [`QP_SET_OFFSETS`]).
    pub adaptive: bool,
    /// Rate control: the highest quality whose file has at most this many bits per pixel
    /// (`quality` is then ignored); `None`: `quality` as given.
    pub target_bpp: Option<f64>,
    /// 0-100, the quality of the alpha codestream (RGBA images); 100, lossless, is
    /// JxrEncApp's default for alpha.
    pub alpha_quality: u8,
    /// Chroma sampling of the colour; 4:2:2 and 4:2:0 are lossy (a contradiction with
    /// lossless).
    pub subsampling: Subsampling,
    /// Bitstream order.
    pub order: BitstreamOrder,
    /// BANDS_PRESENT of the colour codestream: the bands left out are not coded (and the
    /// decoder takes them as zero). Anything but [`Bands::All`] is lossy.
    pub bands: Bands,
    /// TRIM_FLEXBITS, 0-15: the lowest bits of the HP refinement ("flex") bits that are not
    /// coded. Lossy when above 0; no effect without flexbits.
    pub trim_flexbits: u8,
    /// Explicit quantizers of the colour codestream instead of those `quality` maps to (see
    /// [`Quantizers`]); `None`: `quality`'s. `quality` still chooses the default overlap.
    pub quantizers: Option<Quantizers>,
}

/// Explicit QP indices (T.832 9.4.2: 16 indices double the step; 0 is step 1) for each band
/// (DC, LP, HP) and channel (Y, U, V) of the colour codestream, written as they are: the
/// format's code scale does not move them (as it moves `quality`'s), and with
/// [`EncodeOptions::adaptive`] they are the finest set, the macroblocks' coarser sets
/// [`QP_SET_OFFSETS`] above them. All zero is lossless; otherwise lossy, in scaled arithmetic
/// where the format allows (as JxrEncApp). The plane header codes each band's set with
/// CHANNEL_MODE 0 (one index), 1 (luma, chroma) or 2 (three indices), whichever holds.
///
/// What JxrEncApp uses for a `-q` can be read from its file ([`Quantizers::of_file`]), so that
/// both encoders can be compared at equal settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quantizers {
    /// The DC band's indices: Y, U, V.
    pub dc: [u8; 3],
    /// The LP band's indices: Y, U, V.
    pub lp: [u8; 3],
    /// The HP band's indices: Y, U, V.
    pub hp: [u8; 3],
}

impl Quantizers {
    /// One index for every band and channel.
    pub fn uniform(index: u8) -> Self {
        Quantizers { dc: [index; 3], lp: [index; 3], hp: [index; 3] }
    }

    /// The quantizers of the option `qp=`: comma-separated indices 0-255, either one (every
    /// band and channel), six in JxrEncApp's order (Y, U, V for DC and LP, then Y, U, V for
    /// HP; its `uiDefaultQPIndex`, `…U`, `…V`, `…YHP`, `…UHP`, `…VHP`, the LP band taking the
    /// DC's as it does) or nine (DC, LP, HP, each Y, U, V).
    pub fn parse(text: &str) -> Result<Self> {
        let bad = || {
            Error::invalid(format!(
                "jxr: qp={text}: expected 1, 6 (Y,U,V,YHP,UHP,VHP) or 9 (DC, LP, HP of Y,U,V) QP indices 0-255"
            ))
        };
        let v: Vec<u8> = text.split(',').map(|t| t.trim().parse().map_err(|_| bad())).collect::<Result<_>>()?;
        let three = |i: usize| [v[i], v[i + 1], v[i + 2]];
        match v.len() {
            1 => Ok(Quantizers::uniform(v[0])),
            6 => Ok(Quantizers { dc: three(0), lp: three(0), hp: three(3) }),
            9 => Ok(Quantizers { dc: three(0), lp: three(3), hp: three(6) }),
            _ => Err(bad()),
        }
    }

    /// The quantizers of the colour codestream of a `.jxr` file, when its plane header gives
    /// one set per band for the whole image (as JxrEncApp writes it; a band left out takes the
    /// band below's); `None` when the tiles carry their own, or for fewer than three channels.
    pub fn of_file(data: &[u8]) -> Result<Option<Self>> {
        let container = container::parse_container(data)?;
        let plane = header::parse(container.image)?.primary;
        if plane.channels < 3 {
            return Ok(None);
        }
        let set = |source: QpSource| match source {
            QpSource::Uniform(set) => Some([set.index[0], set.index[1], set.index[2]]),
            QpSource::PerTile => None,
        };
        Ok((|| Some(Quantizers { dc: set(plane.dc)?, lp: set(plane.lp)?, hp: set(plane.hp)? }))())
    }

    /// Every index is 0: lossless.
    fn lossless(&self) -> bool {
        [self.dc, self.lp, self.hp].iter().flatten().all(|&i| i == 0)
    }
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions {
            quality: 90,
            overlap: None,
            format: SampleFormat::Half,
            tile_mbs: 0,
            adaptive: true,
            alpha_quality: 100,
            target_bpp: None,
            subsampling: Subsampling::Yuv444,
            order: BitstreamOrder::Spatial,
            bands: Bands::All,
            trim_flexbits: 0,
            quantizers: None,
        }
    }
}

impl EncodeOptions {
    /// The options of `settings`: its quality, and the codec options `format` (`half`,
    /// `float`, `rgbe`, `fixed`, `half4`, `rgb8`, `rgb16` or `rgb101010`; see [`SampleFormat`]),
    /// `transfer` (`srgb`, `pq` or `linear`, for the integer formats only), `overlap` (0, 1 or 2), `lossless` (`true`: quality 100), `tile` (tile size
    /// in pixels, a multiple of 16; 0 for one tile), `adaptive` (`false`: one HP quantizer
    /// for every macroblock), `target_bpp` (rate control: bits per pixel), `alpha_quality`
    /// (0-100), `subsampling` (`444`, `422` or `420`), `order` (`spatial` or `frequency`),
    /// `bands` (`all`, `noflex`, `nohp` or `dc`), `trim_flexbits` (0-15) and `qp` (explicit
    /// quantizers, see [`Quantizers::parse`]; they contradict `lossless` and `target_bpp`).
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options(
            "jxr",
            &[
                "format",
                "transfer",
                "overlap",
                "lossless",
                "tile",
                "adaptive",
                "target_bpp",
                "alpha_quality",
                "subsampling",
                "order",
                "bands",
                "trim_flexbits",
                "qp",
            ],
        )?;
        let mut o = EncodeOptions { quality: settings.quality.min(100), ..EncodeOptions::default() };
        o.format = SampleFormat::parse(settings.option("format"), settings.option("transfer"))?;
        if let Some(v) = settings.option("overlap") {
            o.overlap = Some(match v {
                "0" => OverlapMode::None,
                "1" => OverlapMode::One,
                "2" => OverlapMode::Two,
                _ => return Err(Error::invalid(format!("jxr: overlap={v}: expected 0, 1 or 2"))),
            });
        }
        if let Some(t) = settings.option("tile") {
            let px: usize =
                t.parse().map_err(|_| Error::invalid(format!("jxr: tile={t}: expected a number of pixels")))?;
            if !px.is_multiple_of(16) {
                return Err(Error::invalid(format!("jxr: tile={t}: tiles are whole macroblocks (a multiple of 16)")));
            }
            o.tile_mbs = px / 16;
        }
        if let Some(q) = settings.option("alpha_quality") {
            o.alpha_quality = q
                .parse()
                .ok()
                .filter(|&q| q <= 100)
                .ok_or_else(|| Error::invalid(format!("jxr: alpha_quality={q}: expected 0 to 100")))?;
        }
        if let Some(t) = settings.option("target_bpp") {
            let bpp: f64 = t.parse().map_err(|_| Error::invalid(format!("jxr: target_bpp={t}: expected a number")))?;
            if !(bpp > 0.0 && bpp.is_finite()) {
                return Err(Error::invalid(format!("jxr: target_bpp={t}: expected a positive number")));
            }
            o.target_bpp = Some(bpp);
        }
        if let Some(v) = settings.option("subsampling") {
            o.subsampling = match v {
                "444" => Subsampling::Yuv444,
                "422" => Subsampling::Yuv422,
                "420" => Subsampling::Yuv420,
                _ => return Err(Error::invalid(format!("jxr: subsampling={v}: expected 444, 422 or 420"))),
            };
        }
        if let Some(v) = settings.option("order") {
            o.order = match v {
                "spatial" => BitstreamOrder::Spatial,
                "frequency" => BitstreamOrder::Frequency,
                _ => return Err(Error::invalid(format!("jxr: order={v}: expected spatial or frequency"))),
            };
        }
        if let Some(v) = settings.option("bands") {
            o.bands = match v {
                "all" => Bands::All,
                "noflex" => Bands::NoFlexbits,
                "nohp" => Bands::NoHighpass,
                "dc" => Bands::DcOnly,
                _ => return Err(Error::invalid(format!("jxr: bands={v}: expected all, noflex, nohp or dc"))),
            };
        }
        if let Some(v) = settings.option("trim_flexbits") {
            o.trim_flexbits = v
                .parse()
                .ok()
                .filter(|&t| t <= 15)
                .ok_or_else(|| Error::invalid(format!("jxr: trim_flexbits={v}: expected 0 to 15")))?;
        }
        if let Some(qp) = settings.option("qp") {
            if o.target_bpp.is_some() {
                return Err(Error::invalid("jxr: qp= and target_bpp contradict each other"));
            }
            o.quantizers = Some(Quantizers::parse(qp)?);
        }
        if let Some(adaptive) = settings.bool_option("adaptive")? {
            o.adaptive = adaptive;
        }
        if settings.bool_option("lossless")? == Some(true) {
            if o.target_bpp.is_some() {
                return Err(Error::invalid("jxr: lossless=true and target_bpp contradict each other"));
            }
            if o.quantizers.is_some() {
                return Err(Error::invalid("jxr: lossless=true and qp= contradict each other"));
            }
            o.quality = 100;
        }
        o.check_lossless()?;
        Ok(o)
    }

    /// Lossless coding keeps every sample: chroma subsampling, bands left out and trimmed
    /// flexbits all lose some, so they contradict it.
    fn check_lossless(&self) -> Result<()> {
        if !self.lossless() {
            return Ok(());
        }
        let what = if self.subsampling != Subsampling::Yuv444 {
            "chroma subsampling"
        } else if self.bands != Bands::All {
            "leaving bands out"
        } else if self.trim_flexbits > 0 {
            "trimming flexbits"
        } else {
            return Ok(());
        };
        Err(Error::invalid(format!("jxr: lossless (quality 100) and {what} contradict each other")))
    }

    fn lossless(&self) -> bool {
        self.quantizers.map_or(self.quality >= 100, |q| q.lossless())
    }

    /// SCALED_FLAG: jxrlib codes the 32-bit formats (floats) in unscaled arithmetic always,
    /// and lossless images too (scaling would lose the low bits).
    fn scaled(&self) -> bool {
        !self.lossless() && !self.format.always_unscaled()
    }

    /// The options of the planar alpha codestream: its own quality, and the overlap asked
    /// for, or else the one its own quality calls for (the alpha codestream has its own
    /// OVERLAP_MODE: JxrEncApp below quality 0.5 writes colour with two stages and lossless
    /// alpha with one; lossless alpha here takes the smaller of none and one, see
    /// `encode_at`).
    ///
    /// No luminance-adaptive HP quantizers: alpha is not light.
    fn for_alpha(&self) -> EncodeOptions {
        EncodeOptions {
            quality: self.alpha_quality,
            // Alpha has its own quality; explicit quantizers are the colour's.
            quantizers: None,
            adaptive: false,
            // The colour's order; every band of alpha (lossless by default).
            bands: Bands::All,
            trim_flexbits: 0,
            ..self.clone()
        }
    }

    /// How many luminance-adaptive quantizer sets each macroblock chooses from (one, or
    /// [`QP_SET_OFFSETS`]' when adaptive and lossy, for the formats whose codes are
    /// logarithmic).
    fn adaptive_sets(&self) -> usize {
        if self.adaptive && !self.lossless() && self.format.log_coded() {
            QP_SET_OFFSETS.len()
        } else {
            1
        }
    }

    /// How many LP quantizer sets the codestream lists (the adaptive sets, with an LP band).
    fn lp_sets(&self) -> usize {
        if self.bands.has_lp() {
            self.adaptive_sets()
        } else {
            1
        }
    }

    /// How many HP quantizer sets the codestream lists (the adaptive sets, with an HP band).
    fn hp_sets(&self) -> usize {
        if self.bands.has_hp() {
            self.adaptive_sets()
        } else {
            1
        }
    }

    fn overlap(&self) -> OverlapMode {
        self.overlap.unwrap_or(if self.quality >= 50 { OverlapMode::One } else { OverlapMode::Two })
    }

    /// QP indices (T.832 9.4.2) of the DC, LP and HP bands, each for Y, U and V: the explicit
    /// [`Quantizers`], or those of `quality`:
    ///
    /// One base index falls linearly with quality (16 indices double the step): 10 at
    /// quality 90, 66 at 50, 136 at 0. Luma uses it for every band; chroma, which the eye
    /// resolves less finely, 24 indices more for DC and LP and 32 more for HP (2.8 and 4
    /// times the step; in scaled arithmetic chroma DC and LP steps are halved again). At
    /// equal quantizers our files are jxrlib's size; these choices put our curve of bytes
    /// against PU21-PSNR level with JxrEncApp's (see the crate README). Formats whose codes are
    /// coarser or finer than half's move the base index (`SampleFormat`'s QP offset).
    fn qp_indices(&self) -> [[u8; 3]; 3] {
        if let Some(q) = self.quantizers {
            return [q.dc, q.lp, q.hp];
        }
        if self.lossless() {
            return [[0; 3]; 3];
        }
        let base = 1.4 * f32::from(100 - self.quality.min(99)) - 4.0 + self.format.qp_offset();
        let idx = |offset: f32| (base + offset).round().clamp(1.0, 255.0) as u8;
        let (luma, chroma) = (idx(0.0), idx(24.0));
        [[luma, chroma, chroma], [luma, chroma, chroma], [luma, idx(32.0), idx(32.0)]]
    }
}

/// Encodes `image` (RGB, or RGBA with alpha as a planar alpha codestream) as a JPEG XR file.
pub fn encode(image: &HdrImage, options: &EncodeOptions, pool: &ThreadPool) -> Result<(Vec<u8>, EncodeReport)> {
    // On one of the pool's workers, the encoder's many small parallel steps (a few per
    // macroblock row) are work shared among the workers; from an outside thread each would be
    // handed to the pool and waited for, and that hand-off cost more than the step gained.
    pool.install(|| encode_rated(image, options, pool))
}

/// [`encode`] on the calling thread.
fn encode_rated(image: &HdrImage, options: &EncodeOptions, pool: &ThreadPool) -> Result<(Vec<u8>, EncodeReport)> {
    let Some(target) = options.target_bpp else { return encode_at(image, options, pool) };
    if options.quantizers.is_some() {
        return Err(Error::invalid("jxr: explicit quantizers and a target bits per pixel contradict each other"));
    }
    // Rate control: file size falls with quality, so bisect for the highest quality (0-99,
    // lossy) whose file fits, in at most 7 encodes.
    let pixels = f64::from(image.width()) * f64::from(image.height());
    let at = |quality: u8| encode_at(image, &EncodeOptions { quality, target_bpp: None, ..options.clone() }, pool);
    let bpp = |file: &[u8]| file.len() as f64 * 8.0 / pixels.max(1.0);
    let (mut lo, mut hi) = (0u8, 99u8);
    let mut best = at(lo)?;
    if bpp(&best.0) > target {
        best.1.note(format!("target {target} bits per pixel not reached: quality 0 gives {:.3}", bpp(&best.0)));
        return Ok(best);
    }
    let mut best_q = lo;
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        let attempt = at(mid)?;
        if bpp(&attempt.0) <= target {
            (lo, best, best_q) = (mid, attempt, mid);
        } else {
            hi = mid - 1;
        }
    }
    best.1.note(format!("quality {best_q} for at most {target} bits per pixel: {:.3}", bpp(&best.0)));
    Ok(best)
}

/// [`encode`] at `options.quality`.
fn encode_at(image: &HdrImage, options: &EncodeOptions, pool: &ThreadPool) -> Result<(Vec<u8>, EncodeReport)> {
    options.check_lossless()?;
    let mut report = EncodeReport::new();
    let (width, height) = (image.width() as usize, image.height() as usize);
    if width == 0 || height == 0 {
        return Err(Error::invalid("JPEG XR: an empty image"));
    }
    let spp = match image.channels() {
        Channels::Rgb => 3,
        Channels::Rgba => 4,
        other => return Err(Error::unsupported(format!("JPEG XR encoding of {other:?} images"))),
    };
    let alpha = spp == 4;
    // scRGB: 1.0 is 80 cd/m² (the family's images say what 1.0 is in `nits_per_unit`).
    let scale = image.color.nits_per_unit / crate::output::NITS_PER_UNIT;
    let ptm_color_info = colour_info(image, &mut report)?;
    let (mb_w, mb_h) = (width.div_ceil(16), height.div_ceil(16));
    // With alpha, the RGBA format of the same sample type (T.832 Table A.6), if there is one.
    let format = options.format.pixel_format(alpha)?;
    let alpha_options = options.for_alpha();
    // In scaled arithmetic the integers carry 3 more bits (T.832 9.10's right shift).
    let shift = if options.scaled() { 3 } else { 0 };
    let alpha_shift = if alpha_options.scaled() { 3 } else { 0 };

    // Samples to integers (T.832 9.10 backwards), then the forward colour transform, a row of
    // every channel at a time, on the macroblock grid (`pw` wide, `ph` high; the extension
    // repeats the last column and row, as jxrlib's encoder pads); alpha is a channel of its
    // own codestream. Rows past the image are converted again from its last row, their
    // clipping not counted twice.
    let (pw, ph) = (16 * mb_w, 16 * mb_h);
    let coder = SampleCoder::new(options.format, image.color.nits_per_unit);
    let half_rgb = matches!(options.format, SampleFormat::Half | SampleFormat::HalfPadded) && !alpha;
    let extend = |y: usize, out: &mut [&mut [i32]], clipped: Clipped| {
        for o in out.iter_mut() {
            let last = o[width - 1];
            o[width..pw].fill(last);
        }
        if y < height {
            clipped
        } else {
            Clipped::default()
        }
    };
    let colour_row = |y: usize, out: &mut [&mut [i32]]| -> Clipped {
        let mut clipped = Clipped::default();
        let row = image.row(y.min(height - 1) as u32);
        let [o0, o1, o2] = out else { unreachable!("three colour channels") };
        if half_rgb {
            // Half RGB: codes and colour transform in one vectorised pass.
            (clipped.nan, clipped.above) = half_rgb_yuv(&row[..width * 3], scale, shift, [o0, o1, o2]);
        } else {
            for (x, p) in row.chunks_exact(spp).take(width).enumerate() {
                let [r, g, b] = coder.colour([p[0], p[1], p[2]], &mut clipped).map(|c| c << shift);
                (o0[x], o1[x], o2[x]) = forward_cc(r, g, b);
            }
        }
        extend(y, out, clipped)
    };
    // Alpha is coded like a colour sample of the same format (the decoder's output formatting
    // treats it so, T.832 9.10), but it is not light: no scRGB scaling, no transfer function
    // and no colour transform.
    let alpha_row = |y: usize, out: &mut [&mut [i32]]| -> Clipped {
        let mut clipped = Clipped::default();
        let row = image.row(y.min(height - 1) as u32);
        for (o, p) in out[0].iter_mut().zip(row.chunks_exact(spp).take(width)) {
            *o = coder.alpha(p[3], &mut clipped) << alpha_shift;
        }
        extend(y, out, clipped)
    };

    // Colour as YUV 4:4:4 in an RGB (or RGBE) image (OUTPUT_CLR_FMT 7 or 8); alpha as a planar alpha
    // codestream of one YONLY plane (T.832 Table A.4: ALPHA_OFFSET), labelled OUTPUT_CLR_FMT
    // 0 with the colour's bit depth, as jxrlib writes it, on the same tile grid.
    // Each colour macroblock's HP quantizer set, from its luminance; alpha uses one set.
    let mb_set = macroblock_qp_sets(image, scale, mb_w, mb_h, options.lp_sets().max(options.hp_sets()));
    let fmt = match options.subsampling {
        Subsampling::Yuv444 => ClrFmt::Yuv444,
        Subsampling::Yuv422 => ClrFmt::Yuv422,
        Subsampling::Yuv420 => ClrFmt::Yuv420,
    };
    let code = |source: Source, fmt: ClrFmt, output_clr_fmt: u8, mb_set: &[u8], options: &EncodeOptions| {
        encode_codestream(source, (width, height), fmt, output_clr_fmt, mb_set, options, pool)
    };
    let (codestream, mut clipped) = if fmt == ClrFmt::Yuv444 {
        // 4:4:4: converted, transformed, quantized and coded a band of rows at a time.
        code(Source::Rows(3, &colour_row), fmt, format.color as u8, &mb_set, options)?
    } else {
        // Chroma downsampling filters whole planes: they are converted first. Each plane is
        // held in the macroblock array that the forward transform turns it into
        // (`forward_plane_in_place`; the array flattened is the plane, `pw` wide).
        let mut planes: Vec<Vec<MbCoeffs>> = vec![vec![[0; MB_COEFFS]; mb_w * mb_h]; 3];
        let clipped = {
            let mut chunks: Vec<_> = planes.iter_mut().map(|p| p.as_flattened_mut().chunks_mut(pw)).collect();
            let rows: Vec<Vec<&mut [i32]>> =
                (0..ph).map(|_| chunks.iter_mut().filter_map(|c| c.next()).collect()).collect();
            pool.map_vec(rows, |(y, mut out)| colour_row(y, &mut out))
                .into_iter()
                .fold(Clipped::default(), Clipped::merge)
        };
        let planes = pool.map_vec(planes, |(ch, p)| match ch {
            0 => PlaneData::Full(p),
            _ => PlaneData::Sub(downsample(p.as_flattened(), pw, ph, fmt == ClrFmt::Yuv420)),
        });
        let (codestream, _) = code(Source::Planes(planes), fmt, format.color as u8, &mb_set, options)?;
        (codestream, clipped)
    };
    let alpha_codestream = if alpha {
        let mb_set = vec![0; mb_w * mb_h];
        let code = |options: &EncodeOptions| code(Source::Rows(1, &alpha_row), ClrFmt::YOnly, 0, &mb_set, options);
        let (alpha_codestream, alpha_clipped) = if !alpha_options.lossless() || alpha_options.overlap.is_some() {
            code(&alpha_options)?
        } else {
            // Lossless alpha: overlap filtering only moves bits around (there are no block
            // edges to hide), and on a flat plane its rounding leaves a residue in every
            // block that costs 1-2 bits per pixel where no overlap costs almost nothing; on
            // varied alpha one stage can be a little smaller. Both are tried, the smaller
            // kept (the samples, and what they clipped, are the same).
            let with = |overlap| EncodeOptions { overlap: Some(overlap), ..alpha_options.clone() };
            let (none, clipped) = code(&with(OverlapMode::None))?;
            let (one, _) = code(&with(OverlapMode::One))?;
            (if none.len() <= one.len() { none } else { one }, clipped)
        };
        clipped = clipped.merge(alpha_clipped);
        Some(alpha_codestream)
    } else {
        None
    };
    for note in clipped.notes(options.format) {
        report.note(note);
    }
    let meta =
        ContainerMeta { ptm_color_info: options.format.ptm_color_info(ptm_color_info), ..ContainerMeta::default() };
    let file = container::write_container(
        format,
        width as u32,
        height as u32,
        &codestream,
        alpha_codestream.as_deref(),
        &meta,
    )?;
    Ok((file, report))
}

/// Chroma downsampling of a `pw` × `ph` plane (after the colour transform) to half its width
/// (4:2:2), and its height too (`vertical`, 4:2:0): the binomial low-pass [1 4 6 4 1]/16
/// each way, centred on the even samples, mirrored at the edges (whole-sample symmetric), as
/// jxrlib's encoder filters (`strenc.c: downsampleUV`). The decoders put chroma sample `i` at
/// luma sample `2i` (CHROMA_CENTERING 0, T.832 8.3.2: co-sited; jxrlib's and T.835's
/// upsampling copy it there and average between), which is where this filter centres it.
/// The sums are exact (64-bit) and rounded once (jxrlib rounds after each direction).
fn downsample(plane: &[i32], pw: usize, ph: usize, vertical: bool) -> Vec<i32> {
    const TAPS: [i64; 5] = [1, 4, 6, 4, 1];
    // Sample `i` of a line of `n` mirrored about its ends (−1 → 1, n → n − 2).
    let at = |i: isize, n: usize| -> usize {
        let n = n as isize;
        let i = if i < 0 { -i } else { i };
        (if i >= n { 2 * (n - 1) - i } else { i }).clamp(0, n - 1) as usize
    };
    let hw = pw / 2;
    let mut rows = vec![0i64; hw * ph];
    for y in 0..ph {
        let src = &plane[y * pw..(y + 1) * pw];
        for x in 0..hw {
            let c = 2 * x as isize;
            rows[y * hw + x] = (0..5).map(|k| TAPS[k] * i64::from(src[at(c + k as isize - 2, pw)])).sum();
        }
    }
    if !vertical {
        return rows.iter().map(|&v| ((v + 8) >> 4) as i32).collect();
    }
    let hh = ph / 2;
    let mut out = vec![0i32; hw * hh];
    for y in 0..hh {
        let c = 2 * y as isize;
        for x in 0..hw {
            let v: i64 = (0..5).map(|k| TAPS[k] * rows[at(c + k as isize - 2, ph) * hw + x]).sum();
            out[y * hw + x] = ((v + 128) >> 8) as i32;
        }
    }
    out
}

/// One channel's integer samples on the macroblock grid, as `encode_codestream` takes them.
enum PlaneData {
    /// At full resolution, held in the macroblock array the forward transform fills (the
    /// array flattened is the plane, 16 samples per macroblock across).
    Full(Vec<MbCoeffs>),
    /// Subsampled chroma (4:2:2, 4:2:0): the plane, rows packed.
    Sub(Vec<i32>),
}

/// Writes row `y` of every channel of a codestream (`16 · mb_w` samples each, the extension
/// included) into the slices given, and says what it clipped.
type RowFill<'a> = dyn Fn(usize, &mut [&mut [i32]]) -> Clipped + Sync + 'a;

/// Where `encode_codestream` takes its integer samples from.
enum Source<'a> {
    /// Whole planes, one per channel.
    Planes(Vec<PlaneData>),
    /// That many full-resolution channels, converted row by row as the transform asks for
    /// them ([`ForwardRows`]).
    Rows(usize, &'a RowFill<'a>),
}

/// The plane kind of channel `ch` in internal colour format `fmt`.
fn plane_kind(fmt: ClrFmt, ch: usize) -> PlaneKind {
    match (fmt, ch) {
        (ClrFmt::Yuv420, 1..) => PlaneKind::Chroma420,
        (ClrFmt::Yuv422, 1..) => PlaneKind::Chroma422,
        _ => PlaneKind::Full,
    }
}

/// One codestream (T.832 8.3) of the integer samples of `source`, on the macroblock grid of
/// a `width` × `height` image (after the colour transform, if any) in internal colour format
/// `fmt`, labelled OUTPUT_CLR_FMT `output_clr_fmt`: the forward transform, quantization,
/// prediction and entropy coding a macroblock row at a time, tiles side by side in parallel
/// on `pool`, and the headers; `mb_set` is each macroblock's HP quantizer set (raster order,
/// below `options.hp_sets()`). Used for the colour codestream and the planar alpha
/// codestream alike. Also returns what the conversion of a row source clipped.
#[allow(clippy::too_many_arguments)]
fn encode_codestream(
    source: Source,
    (width, height): (usize, usize),
    fmt: ClrFmt,
    output_clr_fmt: u8,
    mb_set: &[u8],
    options: &EncodeOptions,
    pool: &ThreadPool,
) -> Result<(Vec<u8>, Clipped)> {
    let (mb_w, mb_h) = (width.div_ceil(16), height.div_ceil(16));
    let scaled = options.scaled();
    let channels = match &source {
        Source::Planes(planes) => planes.len(),
        Source::Rows(n, _) => *n,
    };
    let (lp_sets, hp_sets) = (options.lp_sets(), options.hp_sets());
    let bands = options.bands;
    // The sets in the order the tile headers list them, and each macroblock's position in
    // that list.
    let (order, mb_set) = set_order(mb_set, lp_sets.max(hp_sets));
    let mb_set = &mb_set[..];
    let set_index = |q: u8, k: usize, n: usize| set_index(q, if n > 1 { order[k] } else { k });
    let bitdepth = options.format.bit_depth() as u8;

    let overlap = options.overlap();
    let params = TransformParams { overlap, scaled, hard: None, operators: OperatorSet::JpegXr };
    let [qdc, qlp, qhp] = options.qp_indices();
    // Channel 0 is luma, then U and V.
    let pick = |q: [u8; 3], ch: usize| q[ch.min(2)];
    // Each channel's quantizer steps: DC, LP and HP of every set.
    let steps: Vec<(i32, Vec<i32>, Vec<i32>)> = (0..channels)
        .map(|ch| {
            let luma = ch == 0;
            let dc = quant::step(pick(qdc, ch), scaled, luma);
            let lp = (0..lp_sets).map(|k| quant::step(set_index(pick(qlp, ch), k, lp_sets), scaled, luma)).collect();
            let hp = (0..hp_sets).map(|k| quant::step(set_index(pick(qhp, ch), k, hp_sets), scaled, true)).collect();
            (dc, lp, hp)
        })
        .collect();
    // Quantization of macroblock row `my` of channel `ch`.
    let quantize_row = |ch: usize, my: usize, row: &mut [MbCoeffs]| {
        let (dc, lp, hp) = &steps[ch];
        let shape = quant::channel_shape(fmt, ch);
        for (mb, &set) in row.iter_mut().zip(&mb_set[my * mb_w..]) {
            let (lp, hp) = (lp[usize::from(set).min(lp_sets - 1)], hp[usize::from(set).min(hp_sets - 1)]);
            quant::quantize(mb, shape, *dc, lp, hp);
            // The bands left out are zero for the decoder.
            if !bands.has_lp() {
                mb[1..16].fill(0);
            }
            if !bands.has_hp() {
                mb[16..].fill(0);
            }
        }
    };

    // CHANNEL_MODE 0 (one index) when the channels share it, else 1 (luma, chroma) when the
    // chroma channels do, else 2 (each its own); one channel (alpha) has no CHANNEL_MODE
    // (T.832 8.3.5), which is mode 0.
    let qp_set = |q: [u8; 3]| {
        let mut set = QpSet::default();
        for ch in 0..channels {
            set.index[ch] = pick(q, ch);
        }
        let used = &set.index[..channels];
        set.mode = if used.iter().all(|&i| i == used[0]) {
            0
        } else if used[1..].iter().all(|&i| i == used[1]) {
            1
        } else {
            2
        };
        set
    };
    let sets = |q: [u8; 3], n: usize| -> Vec<QpSet> { (0..n).map(|k| qp_set(q.map(|q| set_index(q, k, n)))).collect() };
    let (lp_qp_sets, hp_qp_sets) = (sets(qlp, lp_sets), sets(qhp, hp_sets));

    // Prediction and entropy coding, each tile on its own (its own adaptive state, predictions
    // stopping at its edges); the tiles of a macroblock row in parallel on the pool.
    let (tile_widths, tile_heights) = (tile_sizes(mb_w, options.tile_mbs), tile_sizes(mb_h, options.tile_mbs));
    let rects = tile_rects(&tile_widths, &tile_heights);
    let frequency = options.order == BitstreamOrder::Frequency;
    // TRIM_FLEXBITS matters only where flexbits are coded.
    let trim = if bands.has_flex() { u32::from(options.trim_flexbits.min(15)) } else { 0 };
    let coding = TileCoding {
        mb_set,
        lp_qp_sets: &lp_qp_sets,
        hp_qp_sets: &hp_qp_sets,
        mb_w,
        fmt,
        channels,
        bands,
        frequency,
        trim: (trim > 0).then_some(trim),
    };
    let tiling = rects.len() > 1;
    let mut tiles =
        rects.iter().enumerate().map(|(id, &rect)| coding.start_tile(rect, id)).collect::<Result<Vec<_>>>()?;
    // Codes macroblock row `my` (each channel's quantized row) in the tiles it crosses.
    let mut code_row = |my: usize, row: &[&[MbCoeffs]]| -> Result<()> {
        let crossing: Vec<&mut TileState> =
            tiles.iter_mut().filter(|t| (t.rect.y0..t.rect.y0 + t.rect.h).contains(&my)).collect();
        pool.map_vec(crossing, |(_, t)| coding.code_row(t, row)).into_iter().collect()
    };

    let mut clipped = Clipped::default();
    match source {
        Source::Planes(planes) => {
            // The forward transform of whole planes, channels one per thread of the pool.
            let transform_channel = |(ch, data): (usize, PlaneData)| -> Result<Vec<MbCoeffs>> {
                // 4:2:0 and 4:2:2 chroma planes are half as wide (and 4:2:0 half as high).
                let kind = plane_kind(fmt, ch);
                let (bx, by) = kind.blocks();
                let mut c = match (data, kind) {
                    (PlaneData::Full(mbs), PlaneKind::Full) => forward_plane_in_place(&params, ch, mb_w, mb_h, mbs)?,
                    (data, _) => {
                        let data = match data {
                            PlaneData::Full(mbs) => mbs.into_flattened(),
                            PlaneData::Sub(data) => data,
                        };
                        let plane = Plane { width: 4 * bx * mb_w, height: 4 * by * mb_h, data };
                        forward_plane(&params, kind, ch, mb_w, mb_h, plane)?
                    }
                };
                for (my, row) in c.chunks_exact_mut(mb_w).enumerate() {
                    quantize_row(ch, my, row);
                }
                Ok(c)
            };
            let coeffs = pool.map_vec(planes, transform_channel).into_iter().collect::<Result<Vec<_>>>()?;
            for my in 0..mb_h {
                let row: Vec<&[MbCoeffs]> = coeffs.iter().map(|c| &c[my * mb_w..][..mb_w]).collect();
                code_row(my, &row)?;
            }
        }
        Source::Rows(_, fill) => {
            // A band of macroblock rows at a time: samples converted into each channel's
            // window, its stage 1 a row ahead of its stage 2, quantized and coded as each row
            // is done. Channels one per thread of the pool, rows converted in parallel.
            let pw = 16 * mb_w;
            let mut rows =
                (0..channels).map(|ch| ForwardRows::new(&params, ch, mb_w, mb_h)).collect::<Result<Vec<_>>>()?;
            for step in 0..=mb_h {
                if step < mb_h {
                    let mut first = 0;
                    let mut chunks: Vec<_> = rows
                        .iter_mut()
                        .map(|r| {
                            let (y, data) = r.rows_to_fill(step);
                            first = y;
                            data.chunks_mut(pw)
                        })
                        .collect();
                    let lines: Vec<Vec<&mut [i32]>> = std::iter::from_fn(|| {
                        let line: Vec<&mut [i32]> = chunks.iter_mut().filter_map(|c| c.next()).collect();
                        (!line.is_empty()).then_some(line)
                    })
                    .collect();
                    clipped = pool
                        .map_vec(lines, |(i, mut line)| fill(first + i, &mut line))
                        .into_iter()
                        .fold(clipped, Clipped::merge);
                    pool.map_vec(rows.iter_mut().collect(), |(_, r)| r.stage1(step));
                }
                if let Some(my) = step.checked_sub(1) {
                    let row = pool.map_vec(rows.iter_mut().collect(), |(ch, r)| {
                        let row = r.stage2(my);
                        quantize_row(ch, my, row);
                        &*row
                    });
                    code_row(my, &row)?;
                }
            }
        }
    }
    // The index table lists the packets tile by tile, each tile's bands in order (T.832
    // 8.3.3); they are stored in that order too (JxrEncApp's `-p`).
    let packets: Vec<Vec<u8>> = tiles.into_iter().flat_map(TileState::finish).collect();

    let image_header = ImageHeader {
        tiling,
        frequency_mode: frequency,
        // Required with more than one tile and in frequency order (T.832 8.3.1); lets
        // decoders find each tile and band.
        index_table: tiling || frequency,
        overlap: overlap as u8,
        trim_flexbits: trim > 0,
        tile_widths: tile_widths.iter().map(|&w| w as u32).collect(),
        tile_heights: tile_heights.iter().map(|&h| h as u32).collect(),
        ..ImageHeader::new(width as u32, height as u32, output_clr_fmt, bitdepth)
    };
    let (mantissa, exp_bias) =
        if options.format == SampleFormat::Float { (FLOAT_MANTISSA, FLOAT_EXP_BIAS) } else { (0, 0) };
    // A band left out takes the quantizers of the band below (RESERVED_I / RESERVED_J 0: the
    // plane header codes none for it).
    let dc = QpSource::Uniform(qp_set(qdc));
    let lp = if !bands.has_lp() {
        dc
    } else if lp_sets > 1 {
        QpSource::PerTile
    } else {
        QpSource::Uniform(qp_set(qlp))
    };
    let hp = if !bands.has_hp() {
        lp
    } else if hp_sets > 1 {
        // Several sets: each tile header lists them, each macroblock picks one.
        QpSource::PerTile
    } else {
        QpSource::Uniform(qp_set(qhp))
    };
    let plane_header = PlaneHeader {
        clr_fmt: fmt,
        scaled,
        bands,
        channels,
        // Chroma sample i sits on luma sample 2i (see `downsample`).
        chroma_centering: (0, 0),
        shift_or_mantissa: mantissa,
        exp_bias,
        dc,
        lp,
        hp,
    };
    Ok((header::write_codestream(&image_header, &plane_header, None, &packets)?, clipped))
}

/// The LP and HP quantizer sets of adaptive quantization: QP index offsets from the base (16
/// double the step). A macroblock takes the set (the same for LP and HP; the DC quantizer is
/// one per tile in JPEG XR) whose step is nearest to the base step divided by
/// its luminance's PU21 sensitivity relative to the most sensitive luminance: PU21 (Mantiuk
/// et al. 2021, perceptually uniform luminance) values an error of a given ratio less in the
/// dark, and the samples' integer codes (half floats, mini-floats) are logarithmic, so one
/// step is one ratio. Coarser steps where the eye sees less spend the bits where it sees more.
/// (LP is predicted only between macroblocks of the same LP set: the set boundaries cost a
/// little prediction, less than the coarser LP saves, 0.6% of the bytes on the corpus
/// photographs.) Eleven sets reach 32 times the base step, for the darkest macroblocks PU21
/// still sees: on the dark StillLife that saves a quarter of the bytes at equal PU21-PSNR
/// (seven sets, up to 8 times: 0.77 of BC6H's bytes; eleven: 0.58; thirteen: 0.56), 1% on the
/// corpus photographs against JxrEncApp, and costs 2% in ΔE ITP at equal bytes (chroma in the
/// dark; capping chroma's sets loses the gain).
pub const QP_SET_OFFSETS: [u8; 11] = [0, 8, 16, 24, 32, 40, 48, 56, 64, 72, 80];

/// The order in which the tile headers list the first `sets` adaptive quantizer sets (list
/// position → set of [`QP_SET_OFFSETS`]), and each macroblock's position in that list.
/// DECODE_QP_INDEX codes position 0 in 1 bit and the others in 1 + 4 (11 sets), once for LP
/// and once for HP in every macroblock, so the set most macroblocks use goes first, the
/// others keep their order (1% of the bytes of the corpus photographs at quality 30, 0.1-0.5%
/// above; the quantizers and so the samples are the same).
fn set_order(mb_set: &[u8], sets: usize) -> (Vec<usize>, Vec<u8>) {
    let mut order: Vec<usize> = (0..QP_SET_OFFSETS.len()).collect();
    if sets > 1 {
        let mut count = vec![0usize; sets];
        for &s in mb_set {
            count[usize::from(s).min(sets - 1)] += 1;
        }
        // The most used; of equal counts, the finest.
        let most = (0..sets).max_by_key(|&k| (count[k], std::cmp::Reverse(k))).unwrap_or(0);
        order.remove(most);
        order.insert(0, most);
    }
    let mut position = vec![0u8; QP_SET_OFFSETS.len()];
    for (i, &k) in order.iter().enumerate() {
        position[k] = i as u8;
    }
    (order, mb_set.iter().map(|&s| position[usize::from(s).min(position.len() - 1)]).collect())
}

/// The QP index of adaptive set `k` for a base index.
fn set_index(base: u8, k: usize) -> u8 {
    base.saturating_add(QP_SET_OFFSETS[k])
}

/// The HP quantizer set (an index into the first `sets` of [`QP_SET_OFFSETS`]) of every
/// macroblock, raster order, from the mean luminance of its pixels (in cd/m²: scRGB samples
/// times 80, BT.709 luminance weights; the extension past the image repeats its edge).
fn macroblock_qp_sets(image: &HdrImage, scale: f32, mb_w: usize, mb_h: usize, sets: usize) -> Vec<u8> {
    if sets <= 1 {
        return vec![0; mb_w * mb_h];
    }
    let (width, height) = (image.width() as usize, image.height() as usize);
    let spp = image.channels().count();
    let mut sum = vec![0f64; mb_w * mb_h];
    // Each macroblock's pixels are summed in the same order as pixel by pixel (row by row,
    // left to right), a run of up to 16 at a time into a local sum.
    fn add_row<const SPP: usize>(row: &[f32], sums: &mut [f64], scale: f32) {
        for (s, run) in sums.iter_mut().zip(row.chunks(16 * SPP)) {
            let mut acc = *s;
            for p in run.chunks_exact(SPP) {
                let lum = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
                let lum = f64::from(lum * scale) * f64::from(crate::output::NITS_PER_UNIT);
                if lum.is_finite() {
                    acc += lum.max(0.0);
                }
            }
            *s = acc;
        }
    }
    for y in 0..height {
        let row = &image.row(y as u32)[..width * spp];
        let sums = &mut sum[(y / 16) * mb_w..][..mb_w];
        if spp == 4 {
            add_row::<4>(row, sums, scale);
        } else {
            add_row::<3>(row, sums, scale);
        }
    }
    // Pixels of the image in each macroblock.
    let count = |m: usize| ((width - (m % mb_w) * 16).min(16) * (height - (m / mb_w) * 16).min(16)) as u32;
    // PU21's slope per unit of log luminance; above a few thousand cd/m² it is taken as
    // constant (the metric stops at 10 000, the eye does not).
    let slope = |l: f64| {
        let l = l.clamp(0.005, 4000.0);
        (hdrcodec_core::metrics::pu21_encode(l * 1.05) - hdrcodec_core::metrics::pu21_encode(l / 1.05))
            / (2.0 * 1.05f64.ln())
    };
    let peak = (0..=70).map(|i| slope(0.005 * 10f64.powf(f64::from(i) / 10.0))).fold(0.0, f64::max);
    let mut sets_of = vec![0u8; mb_w * mb_h];
    for my in 0..mb_h {
        for mx in 0..mb_w {
            // Macroblocks past the image repeat its last row or column of macroblocks.
            let m = my.min((height - 1) / 16) * mb_w + mx.min((width - 1) / 16);
            let mean = sum[m] / f64::from(count(m).max(1));
            let offset = 16.0 * (peak / slope(mean).max(1e-9)).log2();
            let k = QP_SET_OFFSETS[..sets]
                .iter()
                .enumerate()
                .min_by(|a, b| (f64::from(*a.1) - offset).abs().total_cmp(&(f64::from(*b.1) - offset).abs()))
                .map_or(0, |(k, _)| k);
            sets_of[my * mb_w + mx] = k as u8;
        }
    }
    sets_of
}

/// PTM_COLOR_INFO for the image's primaries (H.273 code points: the primaries, linear
/// transfer 8, matrix 0 (RGB), full range), or `None` for BT.709, which is what a half or
/// float file without it means (scRGB). Unspecified primaries are written as none, and said.
fn colour_info(image: &HdrImage, report: &mut EncodeReport) -> Result<Option<[u8; 4]>> {
    use hdrcodec_core::ColorPrimaries;
    match image.color.primaries {
        ColorPrimaries::Bt709 => Ok(None),
        ColorPrimaries::Unspecified => {
            report.note(
                "the image's primaries are unspecified: the file records none, so readers take them as scRGB (BT.709)",
            );
            Ok(None)
        }
        ref p => match p.h273() {
            Some(code) => Ok(Some([code, 8, 0, 1])),
            None => Err(Error::unsupported(format!(
                "JPEG XR: primaries {p:?} have no H.273 code for PTM_COLOR_INFO (convert the image first)"
            ))),
        },
    }
}

/// Tile sizes (in macroblocks) along an axis of `n` macroblocks: `size` each (0: one tile),
/// the last one taking the remainder. At most 4096 tiles (T.832's limit).
fn tile_sizes(n: usize, size: usize) -> Vec<usize> {
    let size = if size == 0 { n } else { size.max(n.div_ceil(4096)) };
    let mut v = vec![size; n / size];
    if !n.is_multiple_of(size) {
        v.push(n % size);
    }
    v
}

/// A tile: first macroblock column and row, width and height in macroblocks.
#[derive(Clone, Copy, Debug)]
struct TileRect {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
}

/// The tiles in raster order (the order of their packets).
fn tile_rects(widths: &[usize], heights: &[usize]) -> Vec<TileRect> {
    let mut out = Vec::with_capacity(widths.len() * heights.len());
    let mut y0 = 0;
    for &h in heights {
        let mut x0 = 0;
        for &w in widths {
            out.push(TileRect { x0, y0, w, h });
            x0 += w;
        }
        y0 += h;
    }
    out
}

/// What the tiles of one codestream share: the quantizers, and how they are coded.
struct TileCoding<'a> {
    /// Each macroblock's LP and HP quantizer set.
    mb_set: &'a [u8],
    lp_qp_sets: &'a [QpSet],
    hp_qp_sets: &'a [QpSet],
    mb_w: usize,
    fmt: ClrFmt,
    channels: usize,
    bands: Bands,
    frequency: bool,
    /// TRIM_FLEXBITS, when the image header flags it.
    trim: Option<u32>,
}

/// Packet types (jxrlib `writePacketHeader`): spatial, DC, LP, HP, FLEXBITS.
const PACKET_SPATIAL: u32 = 0;

/// One tile being coded, a macroblock row at a time.
struct TileState {
    rect: TileRect,
    /// Spatial: everything in writer 0. Frequency: DC, LP, HP, FLEXBITS in 0..=3.
    ws: Vec<BitWriter>,
    enc: PlaneEncoder,
    /// The rows coded so far.
    my: usize,
    /// Each macroblock's coded block patterns, this row and the one above (by `my % 2`).
    cbp_rows: [Vec<u32>; 2],
    /// The quantized macroblocks, each macroblock's channels together, this row and the one
    /// above (by `my % 2`).
    rows: [Vec<i32>; 2],
    /// The residuals of the macroblock being coded.
    res: Vec<i32>,
}

impl TileState {
    /// The tile's packets, each byte-aligned.
    fn finish(self) -> Vec<Vec<u8>> {
        self.ws
            .into_iter()
            .map(|mut w| {
                w.align();
                w.into_bytes()
            })
            .collect()
    }
}

impl TileCoding<'_> {
    /// The start of one tile's packets: in spatial order one (T.832 8.4.1, TILE_SPATIAL), in
    /// frequency order one per band present (8.4.2: TILE_DC, TILE_LOWPASS, TILE_HIGHPASS,
    /// TILE_FLEXBITS); each a packet header and the tile headers of its band. Its macroblocks
    /// follow row by row ([`TileCoding::code_row`]).
    fn start_tile(&self, tile: TileRect, id: usize) -> Result<TileState> {
        let (channels, bands) = (self.channels, self.bands);
        let count = if self.frequency { bands.count() } else { 1 };
        let mut ws: Vec<BitWriter> = (0..count).map(|_| BitWriter::new()).collect();
        let band_writer = |band: usize| if self.frequency { band } else { 0 };
        let (lp_w, hp_w, flex_w) = (band_writer(1), band_writer(2), band_writer(3));
        // The packet header: a start code, then the tile number modulo 32 and the packet
        // type.
        for (band, w) in ws.iter_mut().enumerate() {
            let kind = if self.frequency { band as u32 + 1 } else { PACKET_SPATIAL };
            w.write(1, 24);
            w.write(((id % 32) as u32) << 3 | kind, 8);
        }
        // Spatial: TRIM_FLEXBITS first, then the tile headers; frequency: TRIM_FLEXBITS in
        // the FLEXBITS packet. The DC quantizers are the image's (no DC tile header);
        // TILE_HEADER_LOWPASS and TILE_HEADER_HIGHPASS when the plane header left LP or HP
        // quantizers to the tiles: USE_DC_QP / USE_LP_QP 0, the number of sets, the sets.
        if let Some(trim) = self.trim {
            ws[flex_w].write(trim, 4);
        }
        for (present, w, sets) in [(bands.has_lp(), lp_w, self.lp_qp_sets), (bands.has_hp(), hp_w, self.hp_qp_sets)] {
            if present && sets.len() > 1 {
                let w = &mut ws[w];
                w.bit(false);
                w.write(sets.len() as u32 - 1, 4);
                for set in sets {
                    header::write_qp_set(w, set, channels)?;
                }
            }
        }
        let mut enc = PlaneEncoder::new(self.fmt, channels);
        enc.trim = self.trim.unwrap_or(0);
        let stride = channels * MB_COEFFS;
        Ok(TileState {
            rect: tile,
            ws,
            enc,
            my: 0,
            cbp_rows: [vec![0u32; tile.w * channels], vec![0u32; tile.w * channels]],
            rows: [vec![0i32; tile.w * stride], vec![0i32; tile.w * stride]],
            res: vec![0i32; stride],
        })
    }

    /// The tile's next macroblock row, from each channel's quantized row of the image
    /// (`image_row[ch]`, `mb_w` macroblocks): every macroblock of the tile in raster order,
    /// prediction, then entropy coding, exactly undoing `tiles.rs`.
    fn code_row(&self, t: &mut TileState, image_row: &[&[MbCoeffs]]) -> Result<()> {
        let (fmt, channels, bands) = (self.fmt, self.channels, self.bands);
        let (mb_w, lp_qp_sets, hp_qp_sets) = (self.mb_w, self.lp_qp_sets, self.hp_qp_sets);
        let tile = t.rect;
        let my = t.my;
        t.my += 1;
        let stride = channels * MB_COEFFS;
        let band_writer = |band: usize| if self.frequency { band } else { 0 };
        let (dc_w, lp_w, hp_w, flex_w) = (band_writer(0), band_writer(1), band_writer(2), band_writer(3));
        let (ws, enc, res) = (&mut t.ws, &mut t.enc, &mut t.res[..]);
        let trim = enc.trim;
        let tile_w = tile.w as u32;
        let [r0, r1] = &mut t.rows;
        let (row, prev_row) = if my.is_multiple_of(2) { (r0, &*r1) } else { (r1, &*r0) };
        // The row, each macroblock's channels together (`stride` values), as the decoder
        // holds them.
        for (mx, mb) in row.chunks_exact_mut(stride).enumerate() {
            for (c, dst) in image_row.iter().zip(mb.chunks_exact_mut(MB_COEFFS)) {
                dst.copy_from_slice(&c[tile.x0 + mx]);
            }
        }
        let row = &*row;
        let [a, b] = &mut t.cbp_rows;
        let (cur_cbp, top_cbp) = if my.is_multiple_of(2) { (a, &*b) } else { (b, &*a) };
        for mx in 0..tile.w {
            let cur = &row[mx * stride..(mx + 1) * stride];
            let left = (mx > 0).then(|| &row[(mx - 1) * stride..mx * stride]);
            let top = (my > 0).then(|| &prev_row[mx * stride..(mx + 1) * stride]);
            let top_left = (mx > 0 && my > 0).then(|| &prev_row[(mx - 1) * stride..mx * stride]);
            res.copy_from_slice(cur);
            if bands.has_hp() {
                // The HP bits the decoder will not read (all flexbits, or the trimmed
                // ones) are rounded away first: multiples of 2^d stay multiples of 2^d
                // through HP prediction, so the residuals lose nothing more.
                let bits = enc.hp_model_bits();
                for (ch, c) in res.chunks_exact_mut(MB_COEFFS).enumerate() {
                    let m = bits[usize::from(ch > 0)];
                    round_hp(c, if bands.has_flex() { trim.min(m) } else { m });
                }
            }
            // LP is predicted only from neighbours with the same LP quantizers.
            let set_at = |mx: usize, my: usize| self.mb_set[(tile.y0 + my) * mb_w + tile.x0 + mx];
            let set = set_at(mx, my);
            let lp_index = bands.has_lp() && lp_qp_sets.len() > 1;
            let same_left = !lp_index || (mx > 0 && set_at(mx - 1, my) == set);
            let same_top = !lp_index || (my > 0 && set_at(mx, my - 1) == set);
            predict::unpredict_dclp(fmt, channels, res, left, top, top_left, same_left, same_top);
            // The decoder chooses the HP prediction from the predicted (final) LP values.
            let mode = predict::hp_mode(fmt, cur);
            let hp_channels = if matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) { 1 } else { channels };
            for ch in 0..hp_channels {
                predict::unpredict_hp(fmt, res, ch, mode);
            }
            // Spatial order puts the LP and HP quantizer indices first, frequency order
            // each at the start of the macroblock's data in its band.
            let hp_index = bands.has_hp() && hp_qp_sets.len() > 1;
            if !self.frequency {
                if lp_index {
                    quant::write_qp_index(&mut ws[0], set, lp_qp_sets.len());
                }
                if hp_index {
                    quant::write_qp_index(&mut ws[0], set, hp_qp_sets.len());
                }
            }
            enc.dc(&mut ws[dc_w], res, mx as u32, tile_w)?;
            if bands.has_lp() {
                if lp_index && self.frequency {
                    quant::write_qp_index(&mut ws[lp_w], set, lp_qp_sets.len());
                }
                enc.lp(&mut ws[lp_w], res, mx as u32, tile_w)?;
            }
            if bands.has_hp() {
                if hp_index && self.frequency {
                    quant::write_qp_index(&mut ws[hp_w], set, hp_qp_sets.len());
                }
                let (before, rest) = cur_cbp.split_at_mut(mx * channels);
                let left_cbp = (mx > 0).then(|| &before[(mx - 1) * channels..]);
                let top_cbp = (my > 0).then(|| &top_cbp[mx * channels..(mx + 1) * channels]);
                let cbp = &mut rest[..channels];
                // Spatial order: each block's flexbits follow it; frequency order: in the
                // FLEXBITS packet.
                let inline = bands.has_flex() && !self.frequency;
                let bits = enc.cbp_hp(&mut ws[hp_w], res, left_cbp, top_cbp, cbp, mode, mx as u32, tile_w, inline)?;
                if bands.has_flex() && self.frequency {
                    flex_mb_encode(&mut ws[flex_w], res, fmt, channels, trim, bits)?;
                }
            }
        }
        Ok(())
    }
}

/// Rounds the HP coefficients of one channel of a macroblock (quantized) to the nearest
/// multiples of 2^`d` (half away from zero): what a decoder that does not read their `d`
/// lowest bits can represent.
fn round_hp(c: &mut [i32], d: u32) {
    if d == 0 {
        return;
    }
    let half = 1i64 << (d - 1);
    for v in &mut c[16..] {
        let m = ((i64::from(*v).abs() + half) >> d) << d;
        *v = (if *v < 0 { -m } else { m }).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::{ColorInfo, ColorPrimaries};

    fn ramp(width: u32, height: u32, primaries: ColorPrimaries) -> HdrImage {
        let samples = (0..width * height * 3)
            .map(|i| {
                let (p, c) = (i / 3, i % 3);
                ((p % width) as f32 * 0.37 + (p / width) as f32 * 1.3 + c as f32).sin().abs() * 40.0 + 0.001
            })
            .collect();
        let color = ColorInfo { primaries, nits_per_unit: 80.0, hdr10: None };
        HdrImage::new(width, height, Channels::Rgb, samples, color).unwrap()
    }

    #[test]
    fn tile_grids_cover_the_image() {
        assert_eq!(tile_sizes(10, 0), vec![10]);
        assert_eq!(tile_sizes(10, 4), vec![4, 4, 2]);
        assert_eq!(tile_sizes(8, 4), vec![4, 4]);
        // At most 4096 tiles along an axis.
        assert_eq!(tile_sizes(10_000, 1).len(), 3334);
        let rects = tile_rects(&[4, 2], &[3, 3]);
        assert_eq!(rects.len(), 4);
        assert_eq!((rects[3].x0, rects[3].y0, rects[3].w, rects[3].h), (4, 3, 2, 3));
    }

    #[test]
    fn lossless_half_and_tiles_round_trip_through_the_decoder() {
        let image = ramp(45, 37, ColorPrimaries::Bt709);
        let pool = ThreadPool::new(2).unwrap();
        for tile_mbs in [0, 1, 2] {
            let options = EncodeOptions { quality: 100, tile_mbs, ..EncodeOptions::default() };
            let (file, report) = encode(&image, &options, &pool).unwrap();
            assert!(report.notes.is_empty(), "{:?}", report.notes);
            let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
            let want: Vec<u8> =
                image.samples().iter().flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes()).collect();
            assert!(raw == want, "tiles of {tile_mbs} macroblocks");
        }
    }

    /// `image` with an alpha channel: a ramp from 0 to 1 with some steps, as masks have.
    fn with_alpha(image: &HdrImage) -> HdrImage {
        let (w, h) = (image.width(), image.height());
        let samples = image
            .samples()
            .chunks(3)
            .enumerate()
            .flat_map(|(i, p)| {
                let (x, y) = (i as u32 % w, i as u32 / w);
                let a = if x < w / 3 { 1.0 } else { (x + 2 * y) as f32 / (w + 2 * h) as f32 };
                [p[0], p[1], p[2], a]
            })
            .collect();
        HdrImage::new(w, h, Channels::Rgba, samples, image.color.clone()).unwrap()
    }

    #[test]
    fn rgba_round_trips_through_the_decoder_with_planar_alpha() {
        let image = with_alpha(&ramp(45, 37, ColorPrimaries::Bt709));
        let pool = ThreadPool::new(2).unwrap();
        let half_bits =
            |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes()).collect() };
        for tile_mbs in [0, 2] {
            // Lossless half: every channel's half bits come back, alpha from its own codestream.
            let options = EncodeOptions { quality: 100, tile_mbs, ..EncodeOptions::default() };
            let (file, report) = encode(&image, &options, &pool).unwrap();
            assert!(report.notes.is_empty(), "{:?}", report.notes);
            let c = crate::container::parse_container(&file).unwrap();
            assert_eq!(c.pixel_format.name, "64bppRGBAHalf");
            let cs = header::parse(c.alpha.expect("a planar alpha codestream")).unwrap();
            assert_eq!((cs.primary.clr_fmt, cs.primary.channels, cs.image.output_clr_fmt), (ClrFmt::YOnly, 1, 0));
            assert!(cs.alpha.is_none() && !header::parse(c.image).unwrap().image.alpha_plane);
            let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
            assert!(raw == half_bits(image.samples()), "tiles of {tile_mbs} macroblocks");

            // Lossy colour keeps lossless alpha (the default); lossy alpha is close.
            for alpha_quality in [100, 60] {
                let options = EncodeOptions { quality: 60, tile_mbs, alpha_quality, ..EncodeOptions::default() };
                let (file, _) = encode(&image, &options, &pool).unwrap();
                let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
                let want = half_bits(image.samples());
                for (i, (got, want)) in raw.chunks(2).zip(want.chunks(2)).enumerate().skip(3).step_by(4) {
                    let (got, want) = (u16::from_le_bytes([got[0], got[1]]), u16::from_le_bytes([want[0], want[1]]));
                    if alpha_quality == 100 {
                        assert_eq!(got, want, "alpha of pixel {}", i / 4);
                    } else {
                        let (g, w) = (half::f16::from_bits(got).to_f32(), half::f16::from_bits(want).to_f32());
                        assert!((g - w).abs() < 0.05, "alpha of pixel {}: {g} for {w}", i / 4);
                    }
                }
            }
        }

        // Float: 128bppRGBAFloat, alpha in the colour's mini-float (13 mantissa bits).
        let options = EncodeOptions { quality: 100, format: SampleFormat::Float, ..EncodeOptions::default() };
        let (file, _) = encode(&image, &options, &pool).unwrap();
        assert_eq!(crate::container::parse_container(&file).unwrap().pixel_format.name, "128bppRGBAFloat");
        let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
        let got: Vec<f32> = raw.chunks(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        assert_eq!(got.len(), image.samples().len());
        for (g, w) in got.iter().zip(image.samples()) {
            assert!((g - w).abs() <= w.abs() / 8192.0 + 1e-4, "{g} for {w}");
        }
    }

    #[test]
    fn nan_and_infinite_alpha_are_counted_like_colour() {
        let mut image = with_alpha(&ramp(20, 9, ColorPrimaries::Bt709));
        image.samples_mut()[3] = f32::NAN;
        image.samples_mut()[7] = f32::INFINITY;
        image.samples_mut()[11] = f32::NEG_INFINITY;
        let (file, report) = encode(&image, &EncodeOptions::default(), &ThreadPool::single()).unwrap();
        assert!(report.notes.iter().any(|n| n.contains("1 NaN")), "{:?}", report.notes);
        assert!(report.notes.iter().any(|n| n.contains("2 samples infinite")), "{:?}", report.notes);
        // Lossless alpha: NaN as 0, infinities as ±65504.
        let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
        let alpha = |p: usize| half::f16::from_bits(u16::from_le_bytes([raw[8 * p + 6], raw[8 * p + 7]])).to_f32();
        assert_eq!([alpha(0), alpha(1), alpha(2)], [0.0, 65504.0, -65504.0]);
    }

    #[test]
    fn primaries_go_into_ptm_color_info_and_nan_is_counted() {
        let mut image = ramp(20, 9, ColorPrimaries::Bt2020);
        image.samples_mut()[4] = f32::NAN;
        image.samples_mut()[7] = f32::INFINITY;
        let (file, report) = encode(&image, &EncodeOptions::default(), &ThreadPool::single()).unwrap();
        let container = crate::container::parse_container(&file).unwrap();
        assert_eq!(container.ptm_color_info, Some([9, 8, 0, 1]));
        assert!(report.notes.iter().any(|n| n.contains("1 NaN")), "{:?}", report.notes);
        assert!(report.notes.iter().any(|n| n.contains("1 samples infinite")), "{:?}", report.notes);
        let bt709 = ramp(20, 9, ColorPrimaries::Bt709);
        let (file, _) = encode(&bt709, &EncodeOptions::default(), &ThreadPool::single()).unwrap();
        assert_eq!(crate::container::parse_container(&file).unwrap().ptm_color_info, None);
    }

    #[test]
    fn the_most_used_set_is_listed_first() {
        let (order, positions) = set_order(&[3, 0, 3, 5, 3, 0], 11);
        assert_eq!(order[..5], [3, 0, 1, 2, 4]);
        assert_eq!(positions, vec![0, 1, 0, 5, 0, 1]);
        // One set, or set 0 the most used: the order is the sets'.
        assert_eq!(set_order(&[0, 0], 1).1, vec![0, 0]);
        let (order, positions) = set_order(&[0, 2, 0], 11);
        assert_eq!((order[..3].to_vec(), positions), (vec![0, 1, 2], vec![0, 2, 0]));
    }

    #[test]
    fn dark_macroblocks_get_coarser_hp_quantizers() {
        // Left half at 0.01 cd/m², right half at 300 cd/m² (scRGB units of 80 cd/m²).
        let (w, h) = (64u32, 32u32);
        let samples = (0..w * h * 3).map(|i| if (i / 3) % w < w / 2 { 0.01 / 80.0 } else { 300.0 / 80.0 }).collect();
        let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 80.0, hdr10: None };
        let image = HdrImage::new(w, h, Channels::Rgb, samples, color).unwrap();
        let sets = macroblock_qp_sets(&image, 1.0, 4, 2, QP_SET_OFFSETS.len());
        assert!(sets[0] > sets[3] && sets[4] > sets[7], "{sets:?}");
        let (file, _) = encode(&image, &EncodeOptions::default(), &ThreadPool::single()).unwrap();
        let cs = crate::header::parse(crate::container::parse_container(&file).unwrap().image).unwrap();
        assert_eq!(cs.primary.hp, QpSource::PerTile);
        let plain = EncodeOptions { adaptive: false, ..EncodeOptions::default() };
        let (file, _) = encode(&image, &plain, &ThreadPool::single()).unwrap();
        let cs = crate::header::parse(crate::container::parse_container(&file).unwrap().image).unwrap();
        assert!(matches!(cs.primary.hp, QpSource::Uniform(_)));
        assert!(crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).is_ok());
    }

    #[test]
    fn rate_control_finds_the_highest_quality_under_the_target() {
        let image = ramp(64, 48, ColorPrimaries::Bt709);
        let pixels = 64.0 * 48.0;
        let size = |q: u8| {
            let o = EncodeOptions { quality: q, ..EncodeOptions::default() };
            encode(&image, &o, &ThreadPool::single()).unwrap().0.len() as f64 * 8.0 / pixels
        };
        let target = (size(40) + size(41)) / 2.0;
        let o = EncodeOptions { target_bpp: Some(target), ..EncodeOptions::default() };
        let (file, report) = encode(&image, &o, &ThreadPool::single()).unwrap();
        let bpp = file.len() as f64 * 8.0 / pixels;
        assert!(bpp <= target, "{bpp} > {target}");
        assert!(report.notes.iter().any(|n| n.starts_with("quality ")), "{:?}", report.notes);
        let tiny = EncodeOptions { target_bpp: Some(0.001), ..EncodeOptions::default() };
        let (_, report) = encode(&image, &tiny, &ThreadPool::single()).unwrap();
        assert!(report.notes.iter().any(|n| n.contains("not reached")), "{:?}", report.notes);
    }

    /// Mean absolute error of decoding `file` against `image`, in half-float integer codes
    /// (log-like: 1024 codes per factor 2).
    fn code_error(file: &[u8], image: &HdrImage) -> f64 {
        let raw = crate::decode_raw(file, &hdrcodec_core::DecodeOptions::default()).unwrap();
        let got = raw.chunks(2).map(|b| crate::output::half_bits_to_int(u16::from_le_bytes([b[0], b[1]])));
        let want = image.samples().iter().map(|&v| crate::output::half_bits_to_int(half::f16::from_f32(v).to_bits()));
        let n = image.samples().len() as f64;
        got.zip(want).map(|(g, w)| f64::from((g - w).abs())).sum::<f64>() / n
    }

    #[test]
    fn subsampling_orders_and_bands_round_trip_through_the_decoder() {
        // Smooth colour (chroma subsampling has little to lose) over a few decades.
        let (w, h) = (70u32, 45u32);
        let samples = (0..w * h * 3)
            .map(|i| {
                let (p, c) = (i / 3, (i % 3) as f32);
                let (x, y) = ((p % w) as f32 / w as f32, (p / w) as f32 / h as f32);
                10f32.powf(3.0 * x - 1.0) * (1.0 + 0.3 * (y * 3.0 + c).sin())
            })
            .collect();
        let color = hdrcodec_core::ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 80.0, hdr10: None };
        let image = HdrImage::new(w, h, Channels::Rgb, samples, color).unwrap();
        let pool = ThreadPool::new(2).unwrap();
        let encode_with = |o: EncodeOptions| encode(&image, &o, &pool).unwrap().0;
        let base = EncodeOptions { quality: 80, ..EncodeOptions::default() };
        let reference = code_error(&encode_with(base.clone()), &image);
        for subsampling in [Subsampling::Yuv444, Subsampling::Yuv422, Subsampling::Yuv420] {
            for order in [BitstreamOrder::Spatial, BitstreamOrder::Frequency] {
                for tile_mbs in [0, 2] {
                    let o = EncodeOptions { subsampling, order, tile_mbs, ..base.clone() };
                    let file = encode_with(o);
                    let cs = header::parse(crate::container::parse_container(&file).unwrap().image).unwrap();
                    assert_eq!(cs.image.frequency_mode, order == BitstreamOrder::Frequency);
                    let err = code_error(&file, &image);
                    // The chroma is smooth: subsampling costs little.
                    assert!(err < reference * 3.0 + 8.0, "{subsampling:?} {order:?}: {err} against {reference}");
                }
            }
        }
        // The same macroblock data in either order: identical samples.
        for bands in [Bands::All, Bands::NoFlexbits, Bands::NoHighpass, Bands::DcOnly] {
            let o = |order| EncodeOptions { bands, order, tile_mbs: 2, ..base.clone() };
            let (spatial, frequency) =
                (encode_with(o(BitstreamOrder::Spatial)), encode_with(o(BitstreamOrder::Frequency)));
            let decode = |f: &[u8]| crate::decode_raw(f, &hdrcodec_core::DecodeOptions::default()).unwrap();
            assert!(decode(&spatial) == decode(&frequency), "{bands:?}");
        }
        // Each band left out costs quality, each one a little more.
        let errors: Vec<f64> = [Bands::All, Bands::NoFlexbits, Bands::NoHighpass, Bands::DcOnly]
            .into_iter()
            .map(|bands| code_error(&encode_with(EncodeOptions { bands, quality: 95, ..base.clone() }), &image))
            .collect();
        assert!(errors.windows(2).all(|e| e[0] <= e[1]), "{errors:?}");
        // Trimmed flexbits: between all bands and none.
        let trimmed = code_error(&encode_with(EncodeOptions { trim_flexbits: 2, quality: 95, ..base.clone() }), &image);
        assert!(errors[0] <= trimmed && trimmed <= errors[1], "{trimmed} {errors:?}");
        // Lossless in frequency order gives the input back.
        let file = encode_with(EncodeOptions { quality: 100, order: BitstreamOrder::Frequency, ..base.clone() });
        assert_eq!(code_error(&file, &image), 0.0);
    }

    #[test]
    fn lossless_contradicts_subsampling_bands_and_trimming() {
        let image = ramp(20, 9, ColorPrimaries::Bt709);
        for o in [
            EncodeOptions { subsampling: Subsampling::Yuv420, ..EncodeOptions::default() },
            EncodeOptions { bands: Bands::NoFlexbits, ..EncodeOptions::default() },
            EncodeOptions { trim_flexbits: 1, ..EncodeOptions::default() },
        ] {
            assert!(encode(&image, &o, &ThreadPool::single()).is_ok());
            let lossless = EncodeOptions { quality: 100, ..o };
            let err = encode(&image, &lossless, &ThreadPool::single()).unwrap_err();
            assert!(err.to_string().contains("contradict"), "{err}");
        }
        let s = EncodeSettings::default().with_option("lossless", "true").with_option("subsampling", "422");
        assert!(EncodeOptions::from_settings(&s).is_err());
    }

    #[test]
    fn chroma_downsampling_is_a_centred_binomial_filter() {
        // A constant stays constant; mirrored edges keep a ramp a ramp at the left edge.
        let (pw, ph) = (16, 16);
        let flat = vec![-77; pw * ph];
        assert!(downsample(&flat, pw, ph, true).iter().all(|&v| v == -77));
        let ramp: Vec<i32> = (0..pw * ph).map(|i| 16 * (i % pw) as i32).collect();
        let half = downsample(&ramp, pw, ph, false);
        assert_eq!(half.len(), pw / 2 * ph);
        // Interior samples of a linear ramp are the ramp at the even positions.
        assert_eq!(&half[1..7], &[32, 64, 96, 128, 160, 192]);
        // Position 0 mirrored: (6·0 + 2·4·16 + 2·32)/16 = 12.
        assert_eq!(half[0], 12);
        // One impulse spreads [1 4 6 4 1] around its (even) position, both ways for 4:2:0.
        let mut impulse = vec![0; pw * ph];
        impulse[8 * pw + 8] = 256;
        let q = downsample(&impulse, pw, ph, true);
        assert_eq!((q[4 * 8 + 4], q[4 * 8 + 3], q[3 * 8 + 3]), (36, 6, 1));
    }

    #[test]
    fn hp_rounding_keeps_multiples() {
        let mut c = [0i32; MB_COEFFS];
        c[0] = 13;
        c[16..21].copy_from_slice(&[5, -5, 6, -1, -2]);
        round_hp(&mut c, 2);
        assert_eq!((c[0], &c[16..21]), (13, &[4, -4, 8, 0, -4][..]));
    }

    /// Our decoder's linear samples of `file` (the `ImageCodec` path, light in scRGB units).
    fn decode_light(file: &[u8]) -> HdrImage {
        use hdrcodec_core::ImageCodec;
        crate::JxrCodec.decode(file, &hdrcodec_core::Limits::default()).unwrap()
    }

    /// A picture in `nits_per_unit` 100 whose light spans 0.001 to 90 units (0.1 to 9000
    /// cd/m²), inside every format's range except sRGB's and linear's (80 cd/m²).
    fn bright_ramp(width: u32, height: u32, primaries: ColorPrimaries) -> HdrImage {
        let mut image = ramp(width, height, primaries);
        for v in image.samples_mut() {
            *v = (*v / 40.0).powi(3) * 90.0 + 0.001;
        }
        image.color.nits_per_unit = 100.0;
        image
    }

    #[test]
    fn rgbe_fixed_and_padded_half_round_trip_through_the_decoder() {
        use crate::input::{f32_to_rgbe, Clipped};
        let image = bright_ramp(45, 37, ColorPrimaries::Bt709);
        let pool = ThreadPool::new(2).unwrap();
        let scrgb: Vec<f32> = image.samples().iter().map(|v| v * 100.0 / 80.0).collect();
        for tile_mbs in [0, 2] {
            let lossless = |format| EncodeOptions { quality: 100, format, tile_mbs, ..EncodeOptions::default() };
            // RGBE: lossless gives back exactly Radiance's bytes of the (scRGB) input.
            let (file, report) = encode(&image, &lossless(SampleFormat::Rgbe), &pool).unwrap();
            assert!(report.notes.is_empty(), "{:?}", report.notes);
            assert_eq!(crate::container::parse_container(&file).unwrap().pixel_format.name, "32bppRGBE");
            let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
            let want: Vec<u8> =
                scrgb.chunks(3).flat_map(|p| f32_to_rgbe([p[0], p[1], p[2]], &mut Clipped::default())).collect();
            assert!(raw == want, "RGBE, tiles of {tile_mbs}");
            // Fixed point: the nearest s2.13 value; 4 and above clip (counted).
            let (file, report) = encode(&image, &lossless(SampleFormat::Fixed), &pool).unwrap();
            let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
            let want: Vec<u8> = scrgb
                .iter()
                .flat_map(|&v| ((f64::from(v) * 8192.0).round().clamp(-32768.0, 32767.0) as i16).to_le_bytes())
                .collect();
            assert!(raw == want, "fixed point, tiles of {tile_mbs}");
            let above = scrgb.iter().filter(|&&v| f64::from(v) * 8192.0 > 32767.5).count();
            assert!(above > 0 && report.notes.iter().any(|n| n.starts_with(&format!("{above} samples"))));
            // 64bppRGBHalf: the half bits and a zero padding sample.
            let (file, _) = encode(&image, &lossless(SampleFormat::HalfPadded), &pool).unwrap();
            assert_eq!(crate::container::parse_container(&file).unwrap().pixel_format.name, "64bppRGBHalf");
            let raw = crate::decode_raw(&file, &hdrcodec_core::DecodeOptions::default()).unwrap();
            let want: Vec<u8> = scrgb
                .chunks(3)
                .flat_map(|p| [p[0], p[1], p[2]].map(|v| half::f16::from_f32(v).to_bits()).into_iter().chain([0]))
                .flat_map(u16::to_le_bytes)
                .collect();
            assert!(raw == want, "64bppRGBHalf, tiles of {tile_mbs}");
        }
        // Lossy: close to the light. RGBE's error is relative to the pixel's largest channel
        // (the exponent is shared: 1/256 of it, half that for the decoder's +0.5, before any
        // quantization); fixed point's is absolute.
        for (format, rel, abs, max) in
            [(SampleFormat::Rgbe, 0.05, 0.0, f32::MAX), (SampleFormat::Fixed, 0.0, 0.05, 4.0)]
        {
            let fine = EncodeOptions { quality: 95, format, ..EncodeOptions::default() };
            let (file, _) = encode(&image, &fine, &pool).unwrap();
            let got = decode_light(&file);
            for (g, w) in got.samples().chunks(3).zip(scrgb.chunks(3)) {
                let top = w[0].max(w[1]).max(w[2]);
                for (g, w) in g.iter().zip(w) {
                    let w = w.min(max);
                    assert!((g - w).abs() <= rel * top + abs, "{format:?}: {g} for {w} (pixel maximum {top})");
                }
            }
        }
    }

    #[test]
    fn integer_formats_give_back_the_light_through_their_transfer() {
        use crate::output::SampleTransfer;
        let image = bright_ramp(40, 21, ColorPrimaries::Bt2020);
        let pool = ThreadPool::single();
        let scrgb: Vec<f32> = image.samples().iter().map(|v| v * 100.0 / 80.0).collect();
        for (format, name, ptm) in [
            (SampleFormat::Rgb8(SampleTransfer::Srgb), "24bppRGB", [9, 13, 0, 1]),
            (SampleFormat::Rgb8(SampleTransfer::Pq), "24bppRGB", [9, 16, 0, 1]),
            (SampleFormat::Rgb16(SampleTransfer::Pq), "48bppRGB", [9, 16, 0, 1]),
            (SampleFormat::Rgb16(SampleTransfer::Linear), "48bppRGB", [9, 8, 0, 1]),
            (SampleFormat::Rgb16(SampleTransfer::Srgb), "48bppRGB", [9, 13, 0, 1]),
            (SampleFormat::Rgb101010(SampleTransfer::Pq), "32bppRGB101010", [9, 16, 0, 1]),
            (SampleFormat::Rgb101010(SampleTransfer::Srgb), "32bppRGB101010", [9, 13, 0, 1]),
        ] {
            let t = format.transfer().unwrap();
            let bits = match format {
                SampleFormat::Rgb8(_) => 8,
                SampleFormat::Rgb16(_) => 16,
                _ => 10,
            };
            let options = EncodeOptions { quality: 100, format, ..EncodeOptions::default() };
            let (file, report) = encode(&image, &options, &pool).unwrap();
            let c = crate::container::parse_container(&file).unwrap();
            assert_eq!((c.pixel_format.name, c.ptm_color_info), (name, Some(ptm)), "{format:?}");
            let got = decode_light(&file);
            assert_eq!((got.color.primaries, got.color.nits_per_unit), (ColorPrimaries::Bt2020, 80.0));
            // What the top code holds, and half a code step of the signal around each value.
            let top = if t == SampleTransfer::Pq { 125.0 } else { 1.0 };
            let step = 0.5 / f64::from((1u32 << bits) - 1);
            let mut above = 0;
            for (&g, &w) in got.samples().iter().zip(&scrgb) {
                above += usize::from(w > top);
                let w = f64::from(w.min(top));
                let (lo, hi) = match t {
                    SampleTransfer::Srgb => (srgb_around(w, -step), srgb_around(w, step)),
                    SampleTransfer::Pq => (pq_around(w, -step), pq_around(w, step)),
                    SampleTransfer::Linear => (w - step, w + step),
                };
                let g = f64::from(g);
                assert!(g >= lo - 1e-6 * hi && g <= hi * (1.0 + 1e-6) + 1e-9, "{format:?}: {g} for {w} ({lo}..{hi})");
            }
            if above > 0 {
                assert!(
                    report.notes.iter().any(|n| n.starts_with(&format!("{above} samples above"))),
                    "{format:?}: {:?}",
                    report.notes
                );
            } else {
                assert!(report.notes.is_empty(), "{format:?}: {:?}", report.notes);
            }
            // Lossy files decode too, close to the lossless ones.
            let lossy = EncodeOptions { quality: 80, format, ..EncodeOptions::default() };
            let (file, _) = encode(&image, &lossy, &pool).unwrap();
            assert_eq!(decode_light(&file).samples().len(), scrgb.len());
        }
    }

    /// The linear light of the sRGB signal of `w` moved by `d`.
    fn srgb_around(w: f64, d: f64) -> f64 {
        use hdrcodec_core::transfer::SrgbTransfer;
        SrgbTransfer::decode((SrgbTransfer::encode(w) + d).clamp(0.0, 1.0))
    }

    /// The light (scRGB units) of the PQ signal of `w` scRGB units moved by `d`.
    fn pq_around(w: f64, d: f64) -> f64 {
        use hdrcodec_core::transfer::PqTransfer;
        PqTransfer::decode((PqTransfer::encode(w * 80.0) + d).clamp(0.0, 1.0)) / 80.0
    }

    #[test]
    fn rgba_in_integer_and_fixed_formats_keeps_alpha() {
        use crate::output::SampleTransfer;
        let image = with_alpha(&bright_ramp(45, 37, ColorPrimaries::Bt709));
        for (format, name, bytes) in [
            (SampleFormat::Rgb8(SampleTransfer::Srgb), "32bppBGRA", 1),
            (SampleFormat::Rgb16(SampleTransfer::Pq), "64bppRGBA", 2),
            (SampleFormat::Fixed, "64bppRGBAFixedPoint", 2),
        ] {
            let options = EncodeOptions { quality: 100, format, ..EncodeOptions::default() };
            let (file, _) = encode(&image, &options, &ThreadPool::single()).unwrap();
            assert_eq!(crate::container::parse_container(&file).unwrap().pixel_format.name, name);
            let got = decode_light(&file);
            let max = if format == SampleFormat::Fixed {
                8192.0
            } else {
                f32::from((1u16 << (8 * bytes - 1)) - 1) * 2.0 + 1.0
            };
            for (g, w) in got.samples().chunks(4).zip(image.samples().chunks(4)) {
                assert!((g[3] - w[3]).abs() <= 0.5 / max + 1e-6, "{format:?}: alpha {} for {}", g[3], w[3]);
            }
        }
        // Formats without alpha refuse an RGBA image before writing anything.
        for format in [SampleFormat::Rgbe, SampleFormat::HalfPadded, SampleFormat::Rgb101010(SampleTransfer::Pq)] {
            let options = EncodeOptions { format, ..EncodeOptions::default() };
            let e = encode(&image, &options, &ThreadPool::single()).unwrap_err().to_string();
            assert!(e.contains("no alpha channel"), "{e}");
        }
    }

    #[test]
    fn options_come_from_the_settings() {
        let s = EncodeSettings::default().with_quality(70);
        assert_eq!(EncodeOptions::from_settings(&s).unwrap().quality, 70);
        let s = s.with_option("lossless", "true").with_option("format", "float").with_option("tile", "256");
        let o = EncodeOptions::from_settings(&s).unwrap();
        assert_eq!((o.quality, o.format, o.tile_mbs, o.alpha_quality), (100, SampleFormat::Float, 16, 100));
        let pq10 = EncodeSettings::default().with_option("format", "rgb101010");
        assert_eq!(
            EncodeOptions::from_settings(&pq10).unwrap().format,
            SampleFormat::Rgb101010(crate::output::SampleTransfer::Pq)
        );
        let srgb = pq10.with_option("transfer", "srgb");
        assert_eq!(
            EncodeOptions::from_settings(&srgb).unwrap().format,
            SampleFormat::Rgb101010(crate::output::SampleTransfer::Srgb)
        );
        let contradiction = EncodeSettings::default().with_option("format", "float").with_option("transfer", "pq");
        assert!(EncodeOptions::from_settings(&contradiction).is_err());
        let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("alpha_quality", "40")).unwrap();
        assert_eq!(o.alpha_quality, 40);
        let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("overlap", "2")).unwrap();
        assert_eq!(o.overlap, Some(OverlapMode::Two));
        let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("adaptive", "false")).unwrap();
        assert!(!o.adaptive);
        let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("target_bpp", "2.5")).unwrap();
        assert_eq!(o.target_bpp, Some(2.5));
        assert!(EncodeOptions::from_settings(&EncodeSettings::default().with_option("target_bpp", "-1")).is_err());
        let both = EncodeSettings::default().with_option("target_bpp", "2").with_option("lossless", "true");
        assert!(EncodeOptions::from_settings(&both).is_err());
        let s = EncodeSettings::default()
            .with_option("subsampling", "420")
            .with_option("order", "frequency")
            .with_option("bands", "noflex")
            .with_option("trim_flexbits", "4");
        let o = EncodeOptions::from_settings(&s).unwrap();
        assert_eq!(
            (o.subsampling, o.order, o.bands, o.trim_flexbits),
            (Subsampling::Yuv420, BitstreamOrder::Frequency, Bands::NoFlexbits, 4)
        );
        for (v, bands) in [("all", Bands::All), ("nohp", Bands::NoHighpass), ("dc", Bands::DcOnly)] {
            let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("bands", v)).unwrap();
            assert_eq!(o.bands, bands);
        }
        let o = EncodeOptions::from_settings(&EncodeSettings::default().with_option("subsampling", "422")).unwrap();
        assert_eq!((o.subsampling, o.order), (Subsampling::Yuv422, BitstreamOrder::Spatial));
        for (k, v) in [
            ("subsampling", "411"),
            ("order", "progressive"),
            ("bands", "flex"),
            ("trim_flexbits", "16"),
            ("tile", "100"),
            ("format", "rgb12"),
            ("transfer", "pq"),
            ("overlap", "3"),
            ("lossless", "perhaps"),
            ("adaptive", "maybe"),
            ("alpha_quality", "101"),
            ("alpha_quality", "x"),
            ("no-such", "1"),
            ("qp", ""),
            ("qp", "1,2"),
            ("qp", "1,2,3,4,5,6,7"),
            ("qp", "256"),
            ("qp", "a,b,c,d,e,f"),
        ] {
            assert!(EncodeOptions::from_settings(&EncodeSettings::default().with_option(k, v)).is_err(), "{k}={v}");
        }
    }

    #[test]
    fn explicit_quantizers_come_from_the_settings() {
        let qp = |v: &str| EncodeOptions::from_settings(&EncodeSettings::default().with_option("qp", v));
        assert_eq!(qp("40").unwrap().quantizers, Some(Quantizers::uniform(40)));
        // JxrEncApp's order: Y, U, V for DC and LP, then the HP indices.
        let jxrencapp = Quantizers { dc: [97, 118, 120], lp: [97, 118, 120], hp: [109, 137, 144] };
        assert_eq!(qp("97,118,120,109,137,144").unwrap().quantizers, Some(jxrencapp));
        let nine = Quantizers { dc: [1, 2, 3], lp: [4, 5, 6], hp: [7, 8, 9] };
        assert_eq!(qp(" 1, 2,3,4,5,6,7,8,9").unwrap().quantizers, Some(nine));
        for other in [("lossless", "true"), ("target_bpp", "2")] {
            let s = EncodeSettings::default().with_option("qp", "40").with_option(other.0, other.1);
            assert!(EncodeOptions::from_settings(&s).is_err(), "{other:?}");
        }
        let both = EncodeOptions { quantizers: Some(jxrencapp), target_bpp: Some(2.0), ..EncodeOptions::default() };
        assert!(encode(&ramp(32, 32, ColorPrimaries::Bt709), &both, &ThreadPool::single()).is_err());
    }

    /// The quantizers given are the ones the plane header carries (each band's CHANNEL_MODE
    /// the one that holds them), whatever `quality` says; all zero is lossless.
    #[test]
    fn explicit_quantizers_are_written_as_given() {
        let image = ramp(70, 45, ColorPrimaries::Bt709);
        let cases = [
            Quantizers { dc: [97, 118, 120], lp: [97, 118, 120], hp: [109, 137, 144] },
            Quantizers { dc: [30, 30, 30], lp: [40, 50, 50], hp: [60, 60, 70] },
            Quantizers::uniform(20),
        ];
        for (i, q) in cases.into_iter().enumerate() {
            for adaptive in [false, true] {
                let o = EncodeOptions { quality: 95, quantizers: Some(q), adaptive, ..EncodeOptions::default() };
                let (file, _) = encode(&image, &o, &ThreadPool::single()).unwrap();
                let read = Quantizers::of_file(&file).unwrap();
                assert_eq!(read, (!adaptive).then_some(q), "case {i}, adaptive {adaptive}");
                let modes = |s: QpSource| match s {
                    QpSource::Uniform(set) => set.mode,
                    QpSource::PerTile => 255,
                };
                let plane = header::parse(container::parse_container(&file).unwrap().image).unwrap().primary;
                assert!(plane.scaled, "case {i}: lossy in scaled arithmetic");
                if !adaptive {
                    let want = [[2, 2, 2], [0, 1, 2], [0, 0, 0]][i];
                    assert_eq!([modes(plane.dc), modes(plane.lp), modes(plane.hp)], want, "case {i}");
                }
                // Coarser quantizers, larger error; and the quality asked for plays no part.
                let at_quality =
                    encode(&image, &EncodeOptions { quantizers: None, ..o.clone() }, &ThreadPool::single());
                assert_ne!(file, at_quality.unwrap().0, "case {i}");
            }
        }
        let lossless =
            EncodeOptions { quality: 30, quantizers: Some(Quantizers::uniform(0)), ..EncodeOptions::default() };
        let (file, _) = encode(&image, &lossless, &ThreadPool::single()).unwrap();
        assert_eq!(code_error(&file, &image), 0.0);
        let fine = code_error(
            &encode(
                &image,
                &EncodeOptions { quantizers: Some(Quantizers::uniform(30)), ..lossless.clone() },
                &ThreadPool::single(),
            )
            .unwrap()
            .0,
            &image,
        );
        let coarse = code_error(
            &encode(
                &image,
                &EncodeOptions { quantizers: Some(Quantizers::uniform(90)), ..lossless },
                &ThreadPool::single(),
            )
            .unwrap()
            .0,
            &image,
        );
        assert!(0.0 < fine && fine < coarse, "{fine} {coarse}");
    }
}
