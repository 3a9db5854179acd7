//! The JPEG XR encoder: samples to integers (the inverse of output formatting, T.832 9.10),
//! the forward colour transform, the forward lapped transform, quantization, prediction and
//! entropy coding (the decoder's steps of clause 9 run backwards), then the codestream headers
//! and the file container.
//!
//! What it writes so far: tiles in spatial order, every band, 4:4:4 from RGB, 48bppRGBHalf or
//! 128bppRGBFloat (64bppRGBAHalf or 128bppRGBAFloat with a planar alpha codestream for RGBA
//! images), overlap 0, 1 or 2, one quantizer set per band and
//! channel for the whole image, lossless (quantizer 1, unscaled arithmetic, as JxrEncApp does)
//! or lossy (scaled arithmetic). The quality → quantizer mapping is provisional.

use crate::bits::BitWriter;
use crate::container::{self, ContainerMeta, PixelFormat, PIXEL_FORMATS};
use crate::header::{self, Bands, ClrFmt, ImageHeader, PlaneHeader, QpSet, QpSource};
use crate::macroblock::PlaneEncoder;
use crate::mb::{MbCoeffs, MB_COEFFS};
use crate::output::{f32_to_half_bits, float_to_int, forward_cc, half_bits_to_int, half_codes};
use crate::predict;
use crate::quant;
use crate::transform::{forward_plane, OperatorSet, OverlapMode, Plane, PlaneKind, TransformParams};
use hdrcodec_core::{Channels, EncodeReport, EncodeSettings, Error, HdrImage, Result, ThreadPool};

/// How the samples are stored in the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFormat {
    /// 48bppRGBHalf: IEEE half floats (what Windows HDR screenshots use, without alpha).
    Half,
    /// 128bppRGBFloat: single floats, coded with [`FLOAT_MANTISSA`] mantissa bits.
    Float,
}

/// Mantissa bits of the mini-float that float samples are coded as (LEN_MANTISSA, T.832
/// 8.3.2.x; JxrEncApp's default).
pub const FLOAT_MANTISSA: u8 = 13;
/// Exponent bias of that mini-float (EXP_BIAS; JxrEncApp's default): with 13 mantissa bits,
/// the smallest non-zero value is 2^−16.
pub const FLOAT_EXP_BIAS: u8 = 4;

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
    /// Lossy only: choose each macroblock's HP quantizer from its luminance (see
    /// [`HP_SET_OFFSETS`]).
    pub adaptive: bool,
    /// Rate control: the highest quality whose file has at most this many bits per pixel
    /// (`quality` is then ignored); `None`: `quality` as given.
    pub target_bpp: Option<f64>,
    /// 0-100, the quality of the alpha codestream (RGBA images); 100, lossless, is
    /// JxrEncApp's default for alpha.
    pub alpha_quality: u8,
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
        }
    }
}

impl EncodeOptions {
    /// The options of `settings`: its quality, and the codec options `format` (`half` or
    /// `float`), `overlap` (0, 1 or 2), `lossless` (`true`: quality 100), `tile` (tile size
    /// in pixels, a multiple of 16; 0 for one tile), `adaptive` (`false`: one HP quantizer
    /// for every macroblock), `target_bpp` (rate control: bits per pixel) and
    /// `alpha_quality` (0-100).
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options(
            "jxr",
            &["format", "overlap", "lossless", "tile", "adaptive", "target_bpp", "alpha_quality"],
        )?;
        let mut o = EncodeOptions { quality: settings.quality.min(100), ..EncodeOptions::default() };
        if let Some(f) = settings.option("format") {
            o.format = match f {
                "half" => SampleFormat::Half,
                "float" => SampleFormat::Float,
                _ => return Err(Error::invalid(format!("jxr: format={f}: expected half or float"))),
            };
        }
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
            if px % 16 != 0 {
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
        if let Some(adaptive) = settings.bool_option("adaptive")? {
            o.adaptive = adaptive;
        }
        if settings.bool_option("lossless")? == Some(true) {
            if o.target_bpp.is_some() {
                return Err(Error::invalid("jxr: lossless=true and target_bpp contradict each other"));
            }
            o.quality = 100;
        }
        Ok(o)
    }

    fn lossless(&self) -> bool {
        self.quality >= 100
    }

    /// SCALED_FLAG: jxrlib codes floats in unscaled arithmetic always, and lossless images
    /// too (scaling would lose the low bits).
    fn scaled(&self) -> bool {
        !self.lossless() && self.format != SampleFormat::Float
    }

    /// The options of the planar alpha codestream: its own quality, and the colour's overlap
    /// (JxrEncApp writes the primary's OVERLAP_MODE into the alpha codestream too, and our
    /// decoder transforms planar alpha with the primary's).
    ///
    /// No luminance-adaptive HP quantizers: alpha is not light.
    fn for_alpha(&self) -> EncodeOptions {
        EncodeOptions { quality: self.alpha_quality, overlap: Some(self.overlap()), adaptive: false, ..self.clone() }
    }

    /// How many HP quantizer sets the codestream lists (one, or [`HP_SET_OFFSETS`]' when
    /// adaptive and lossy).
    fn hp_sets(&self) -> usize {
        if self.adaptive && !self.lossless() {
            HP_SET_OFFSETS.len()
        } else {
            1
        }
    }

    fn overlap(&self) -> OverlapMode {
        self.overlap.unwrap_or(if self.quality >= 50 { OverlapMode::One } else { OverlapMode::Two })
    }

    /// QP indices (T.832 9.4.2) of the DC, LP and HP bands, each for luma and for chroma.
    ///
    /// One base index falls linearly with quality (16 indices double the step): 10 at
    /// quality 90, 66 at 50, 136 at 0. Luma uses it for every band; chroma, which the eye
    /// resolves less finely, 24 indices more for DC and LP and 32 more for HP (2.8 and 4
    /// times the step; in scaled arithmetic chroma DC and LP steps are halved again). At
    /// equal quantizers our files are jxrlib's size; these choices put our curve of bytes
    /// against PU21-PSNR level with JxrEncApp's (see the crate README).
    fn qp_indices(&self) -> [[u8; 2]; 3] {
        if self.lossless() {
            return [[0; 2]; 3];
        }
        let base = 1.4 * f32::from(100 - self.quality.min(99)) - 4.0;
        let idx = |offset: f32| (base + offset).round().clamp(1.0, 255.0) as u8;
        [[idx(0.0), idx(24.0)], [idx(0.0), idx(24.0)], [idx(0.0), idx(32.0)]]
    }
}

fn pixel_format(name: &str) -> Result<&'static PixelFormat> {
    PIXEL_FORMATS.iter().find(|f| f.name == name).ok_or_else(|| Error::invalid(format!("no pixel format {name}")))
}

/// Encodes `image` (RGB, or RGBA with alpha as a planar alpha codestream) as a JPEG XR file.
pub fn encode(image: &HdrImage, options: &EncodeOptions, pool: &ThreadPool) -> Result<(Vec<u8>, EncodeReport)> {
    let Some(target) = options.target_bpp else { return encode_at(image, options, pool) };
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
    // With alpha, the RGBA format of the same sample type (T.832 Table A.6).
    let format = pixel_format(match (options.format, alpha) {
        (SampleFormat::Half, false) => "48bppRGBHalf",
        (SampleFormat::Half, true) => "64bppRGBAHalf",
        (SampleFormat::Float, false) => "128bppRGBFloat",
        (SampleFormat::Float, true) => "128bppRGBAFloat",
    })?;
    let alpha_options = options.for_alpha();
    // In scaled arithmetic the integers carry 3 more bits (T.832 9.10's right shift).
    let shift = if options.scaled() { 3 } else { 0 };
    let alpha_shift = if alpha_options.scaled() { 3 } else { 0 };

    // Samples to integers (T.832 9.10 backwards), then the forward colour transform, into
    // three planes the size of the macroblock grid, and alpha into a fourth; the extension
    // repeats the last column and row, as jxrlib's encoder pads.
    let (pw, ph) = (16 * mb_w, 16 * mb_h);
    let mut planes: Vec<Vec<i32>> = vec![vec![0; pw * ph]; spp];
    // One sample to its integer code: (code, was NaN, was clipped). NaN has no integer
    // coding that survives the transform: 0, counted (as BC6H does).
    let to_int = |v: f32| -> (i32, bool, bool) {
        if v.is_nan() {
            return (0, true, false);
        }
        match options.format {
            SampleFormat::Half => {
                let h = f32_to_half_bits(v);
                if h & 0x7fff == 0x7c00 {
                    let max = half::f16::MAX.to_bits();
                    (half_bits_to_int(if v < 0.0 { max | 0x8000 } else { max }), false, true)
                } else {
                    (half_bits_to_int(h), false, false)
                }
            }
            SampleFormat::Float => (
                float_to_int(v.clamp(f32::MIN, f32::MAX), FLOAT_EXP_BIAS as i8, u32::from(FLOAT_MANTISSA)),
                false,
                v.is_infinite(),
            ),
        }
    };
    // Rows in parallel on the pool; each returns its NaN and clipped counts.
    let convert_row = |(y, mut out): (usize, Vec<&mut [i32]>)| -> (usize, usize) {
        if options.format == SampleFormat::Half && !alpha {
            // Half RGB: the whole row's codes in one vectorised pass, then the colour
            // transform pixel by pixel.
            let mut codes = vec![0i32; width * 3];
            let counts = half_codes(&image.row(y as u32)[..width * 3], scale, &mut codes);
            let [o0, o1, o2] = &mut out[..] else { unreachable!("three planes without alpha") };
            for (((p, yy), u), v) in codes.chunks_exact(3).zip(o0.iter_mut()).zip(o1.iter_mut()).zip(o2.iter_mut()) {
                (*yy, *u, *v) = forward_cc(p[0] << shift, p[1] << shift, p[2] << shift);
            }
            return counts;
        }
        let (mut nans, mut clipped) = (0, 0);
        let mut code = |v: f32, shift: u32| {
            let (c, nan, clip) = to_int(v);
            nans += usize::from(nan);
            clipped += usize::from(clip);
            c << shift
        };
        let row = image.row(y as u32);
        for x in 0..width {
            let p = &row[x * spp..][..spp];
            let (r, g, b) = (code(p[0] * scale, shift), code(p[1] * scale, shift), code(p[2] * scale, shift));
            let (yy, u, v) = forward_cc(r, g, b);
            out[0][x] = yy;
            out[1][x] = u;
            out[2][x] = v;
            if alpha {
                // Alpha is coded like a colour sample of the same format (the decoder's
                // output formatting treats it so, T.832 9.10), but it is not light: no
                // scRGB scaling and no colour transform.
                out[3][x] = code(p[3], alpha_shift);
            }
        }
        (nans, clipped)
    };
    let (nans, clipped) = {
        let mut chunks: Vec<_> = planes.iter_mut().map(|p| p.chunks_mut(pw)).collect();
        let rows: Vec<Vec<&mut [i32]>> =
            (0..height).map(|_| chunks.iter_mut().filter_map(|c| c.next()).collect()).collect();
        pool.install(|| {
            use rayon::prelude::*;
            rows.into_par_iter().enumerate().map(convert_row).reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        })
    };
    for plane in &mut planes {
        for y in 0..ph {
            let src = y.min(height - 1) * pw;
            let last = plane[src + width - 1];
            if y >= height {
                plane.copy_within(src..src + width, y * pw);
            }
            plane[y * pw + width..(y + 1) * pw].fill(last);
        }
    }
    if nans > 0 {
        report.note(format!("{nans} NaN samples were written as 0"));
    }
    if clipped > 0 {
        let what = match options.format {
            SampleFormat::Half => "infinite or beyond ±65504 (half float) were clipped to ±65504",
            SampleFormat::Float => "infinite were clipped to the largest float",
        };
        report.note(format!("{clipped} samples {what}"));
    }

    // Colour as YUV 4:4:4 in an RGB image (OUTPUT_CLR_FMT 7); alpha as a planar alpha
    // codestream of one YONLY plane (T.832 Table A.4: ALPHA_OFFSET), labelled OUTPUT_CLR_FMT
    // 0 with the colour's bit depth, as jxrlib writes it, on the same tile grid.
    // Each colour macroblock's HP quantizer set, from its luminance; alpha uses one set.
    let mb_set = macroblock_hp_sets(image, scale, mb_w, mb_h, options.hp_sets());
    let alpha_plane = if alpha { planes.pop() } else { None };
    let codestream = encode_codestream(planes, (width, height), ClrFmt::Yuv444, 7, &mb_set, options, pool)?;
    let alpha_codestream = alpha_plane
        .map(|a| {
            let mb_set = vec![0; mb_w * mb_h];
            encode_codestream(vec![a], (width, height), ClrFmt::YOnly, 0, &mb_set, &alpha_options, pool)
        })
        .transpose()?;
    let meta = ContainerMeta { ptm_color_info, ..ContainerMeta::default() };
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

/// One codestream (T.832 8.3) of `planes`, integer samples on the macroblock grid of a
/// `width` × `height` image (after the colour transform, if any) in internal colour format
/// `fmt`, labelled OUTPUT_CLR_FMT `output_clr_fmt`: the forward transform, quantization,
/// tiles coded in parallel on `pool`, and the headers; `mb_set` is each macroblock's HP
/// quantizer set (raster order, below `options.hp_sets()`). Used for the colour codestream
/// and the planar alpha codestream alike.
#[allow(clippy::too_many_arguments)]
fn encode_codestream(
    planes: Vec<Vec<i32>>,
    (width, height): (usize, usize),
    fmt: ClrFmt,
    output_clr_fmt: u8,
    mb_set: &[u8],
    options: &EncodeOptions,
    pool: &ThreadPool,
) -> Result<Vec<u8>> {
    let (mb_w, mb_h) = (width.div_ceil(16), height.div_ceil(16));
    let (pw, ph) = (16 * mb_w, 16 * mb_h);
    let scaled = options.scaled();
    let channels = planes.len();
    let hp_sets = options.hp_sets();
    let bitdepth = match options.format {
        SampleFormat::Half => 4u8,
        SampleFormat::Float => 7u8,
    };

    // The forward transform, then quantization.
    let overlap = options.overlap();
    let params = TransformParams { overlap, scaled, hard: None, operators: OperatorSet::JpegXr };
    let [qdc, qlp, qhp] = options.qp_indices();
    // Channel 0 is luma, the others chroma.
    let pick = |q: [u8; 2], ch: usize| q[usize::from(ch > 0)];
    // Channels are independent here: one per thread of the pool.
    let transform_channel = |(ch, data): (usize, Vec<i32>)| -> Result<Vec<MbCoeffs>> {
        let plane = Plane { width: pw, height: ph, data };
        let mut c = forward_plane(&params, PlaneKind::Full, ch, mb_w, mb_h, plane)?;
        let luma = ch == 0;
        let (dc, lp) = (quant::step(pick(qdc, ch), scaled, luma), quant::step(pick(qlp, ch), scaled, luma));
        let hp: Vec<i32> = (0..hp_sets).map(|k| quant::step(hp_index(pick(qhp, ch), k), scaled, true)).collect();
        for (mb, &set) in c.iter_mut().zip(mb_set) {
            quant::quantize(mb, (16, 16), dc, lp, hp[usize::from(set)]);
        }
        Ok(c)
    };
    let coeffs: Vec<Result<Vec<MbCoeffs>>> = pool.install(|| {
        use rayon::prelude::*;
        planes.into_par_iter().enumerate().map(transform_channel).collect()
    });
    let coeffs = coeffs.into_iter().collect::<Result<Vec<_>>>()?;

    // CHANNEL_MODE 0 (one index) when luma and chroma share it, else 1 (luma, chroma); one
    // channel (alpha) has no CHANNEL_MODE (T.832 8.3.5), which is mode 0.
    let qp_set = |q: [u8; 2]| {
        let mut set = QpSet { mode: u8::from(channels > 1 && q[0] != q[1]), ..QpSet::default() };
        for ch in 0..channels {
            set.index[ch] = pick(q, ch);
        }
        set
    };
    let hp_qp_sets: Vec<QpSet> = (0..hp_sets).map(|k| qp_set([hp_index(qhp[0], k), hp_index(qhp[1], k)])).collect();

    // Prediction and entropy coding, each tile on its own (its own adaptive state, predictions
    // stopping at its edges), in parallel on the pool.
    let (tile_widths, tile_heights) = (tile_sizes(mb_w, options.tile_mbs), tile_sizes(mb_h, options.tile_mbs));
    let rects = tile_rects(&tile_widths, &tile_heights);
    let packets: Vec<Result<Vec<u8>>> = pool.install(|| {
        use rayon::prelude::*;
        rects
            .par_iter()
            .enumerate()
            .map(|(id, &rect)| encode_tile(&coeffs, mb_set, &hp_qp_sets, mb_w, rect, fmt, channels, id))
            .collect()
    });
    let packets = packets.into_iter().collect::<Result<Vec<_>>>()?;
    let tiling = packets.len() > 1;

    let image_header = ImageHeader {
        tiling,
        // Required with more than one tile (T.832 8.3.1); lets decoders find each tile.
        index_table: tiling,
        overlap: overlap as u8,
        tile_widths: tile_widths.iter().map(|&w| w as u32).collect(),
        tile_heights: tile_heights.iter().map(|&h| h as u32).collect(),
        ..ImageHeader::new(width as u32, height as u32, output_clr_fmt, bitdepth)
    };
    let (mantissa, exp_bias) =
        if options.format == SampleFormat::Float { (FLOAT_MANTISSA, FLOAT_EXP_BIAS) } else { (0, 0) };
    let plane_header = PlaneHeader {
        clr_fmt: fmt,
        scaled,
        bands: Bands::All,
        channels,
        chroma_centering: (0, 0),
        shift_or_mantissa: mantissa,
        exp_bias,
        dc: QpSource::Uniform(qp_set(qdc)),
        lp: QpSource::Uniform(qp_set(qlp)),
        // Several sets: each tile header lists them, each macroblock picks one.
        hp: if hp_sets > 1 { QpSource::PerTile } else { QpSource::Uniform(qp_set(qhp)) },
    };
    header::write_codestream(&image_header, &plane_header, None, &packets)
}

/// The HP quantizer sets of adaptive quantization: QP index offsets from the base (16 double
/// the step). A macroblock takes the set whose step is nearest to the base step divided by
/// its luminance's PU21 sensitivity relative to the most sensitive luminance: PU21 (Mantiuk
/// et al. 2021, perceptually uniform luminance) values an error of a given ratio less in the
/// dark, and the samples' integer codes (half floats, mini-floats) are logarithmic, so one
/// step is one ratio. Coarser steps where the eye sees less spend the bits where it sees more.
pub const HP_SET_OFFSETS: [u8; 7] = [0, 8, 16, 24, 32, 40, 48];

/// The HP QP index of set `k` for a base index.
fn hp_index(base: u8, k: usize) -> u8 {
    base.saturating_add(HP_SET_OFFSETS[k])
}

/// The HP quantizer set (an index into the first `sets` of [`HP_SET_OFFSETS`]) of every
/// macroblock, raster order, from the mean luminance of its pixels (in cd/m²: scRGB samples
/// times 80, BT.709 luminance weights; the extension past the image repeats its edge).
fn macroblock_hp_sets(image: &HdrImage, scale: f32, mb_w: usize, mb_h: usize, sets: usize) -> Vec<u8> {
    if sets <= 1 {
        return vec![0; mb_w * mb_h];
    }
    let (width, height) = (image.width() as usize, image.height() as usize);
    let spp = image.channels().count();
    let mut sum = vec![0f64; mb_w * mb_h];
    let mut count = vec![0u32; mb_w * mb_h];
    for y in 0..height {
        let row = image.row(y as u32);
        for x in 0..width {
            let p = &row[x * spp..][..3];
            let lum = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
            let lum = f64::from(lum * scale) * f64::from(crate::output::NITS_PER_UNIT);
            let m = (y / 16) * mb_w + x / 16;
            if lum.is_finite() {
                sum[m] += lum.max(0.0);
            }
            count[m] += 1;
        }
    }
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
            let mean = sum[m] / f64::from(count[m].max(1));
            let offset = 16.0 * (peak / slope(mean).max(1e-9)).log2();
            let k = HP_SET_OFFSETS[..sets]
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
    if n % size != 0 {
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

/// The spatial-order packet of one tile (T.832 8.4.x TILE_SPATIAL): the packet header, then
/// every macroblock of the tile in raster order (prediction, then entropy coding, exactly
/// undoing `tiles.rs`), byte-aligned. `coeffs` holds each channel's quantized macroblocks of
/// the whole image, `mb_w` across.
#[allow(clippy::too_many_arguments)]
fn encode_tile(
    coeffs: &[Vec<MbCoeffs>],
    mb_set: &[u8],
    hp_qp_sets: &[QpSet],
    mb_w: usize,
    tile: TileRect,
    fmt: ClrFmt,
    channels: usize,
    id: usize,
) -> Result<Vec<u8>> {
    let stride = channels * MB_COEFFS;
    // Row `my` of the tile into `row`: each macroblock's channels together (`stride` values),
    // as the decoder holds them.
    let fill_row = |my: usize, row: &mut [i32]| {
        for (mx, mb) in row.chunks_exact_mut(stride).enumerate() {
            for (c, dst) in coeffs.iter().zip(mb.chunks_exact_mut(MB_COEFFS)) {
                dst.copy_from_slice(&c[(tile.y0 + my) * mb_w + tile.x0 + mx]);
            }
        }
    };
    let mut w = BitWriter::new();
    // The packet header (jxrlib `writePacketHeader`): a start code, then the packet type
    // (0: spatial) and the tile number modulo 32.
    w.write(1, 24);
    w.write((id % 32) as u32, 8);
    // TILE_HEADER_HIGHPASS (T.832 8.4.x) when the plane header left HP quantizers to the
    // tiles: USE_LP_QP 0, the number of sets, the sets.
    if hp_qp_sets.len() > 1 {
        w.bit(false);
        w.write(hp_qp_sets.len() as u32 - 1, 4);
        for set in hp_qp_sets {
            header::write_qp_set(&mut w, set, channels)?;
        }
    }
    let tile_w = tile.w as u32;
    let mut enc = PlaneEncoder::new(fmt, channels);
    let mut cbp_rows = [vec![0u32; tile.w * channels], vec![0u32; tile.w * channels]];
    let mut rows = [vec![0i32; tile.w * stride], vec![0i32; tile.w * stride]];
    let mut res = vec![0i32; stride];
    for my in 0..tile.h {
        let [r0, r1] = &mut rows;
        let (row, prev_row) = if my % 2 == 0 { (r0, &*r1) } else { (r1, &*r0) };
        fill_row(my, row);
        let row = &*row;
        let [a, b] = &mut cbp_rows;
        let (cur_cbp, top_cbp) = if my % 2 == 0 { (a, &*b) } else { (b, &*a) };
        for mx in 0..tile.w {
            let cur = &row[mx * stride..(mx + 1) * stride];
            let left = (mx > 0).then(|| &row[(mx - 1) * stride..mx * stride]);
            let top = (my > 0).then(|| &prev_row[mx * stride..(mx + 1) * stride]);
            let top_left = (mx > 0 && my > 0).then(|| &prev_row[(mx - 1) * stride..mx * stride]);
            res.copy_from_slice(cur);
            predict::unpredict_dclp(fmt, channels, &mut res, left, top, top_left, true, true);
            // The decoder chooses the HP prediction from the predicted (final) LP values.
            let mode = predict::hp_mode(fmt, cur);
            let hp_channels = if matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) { 1 } else { channels };
            for ch in 0..hp_channels {
                predict::unpredict_hp(fmt, &mut res, ch, mode);
            }
            if hp_qp_sets.len() > 1 {
                quant::write_qp_index(&mut w, mb_set[(tile.y0 + my) * mb_w + tile.x0 + mx], hp_qp_sets.len());
            }
            enc.dc(&mut w, &res, mx as u32, tile_w)?;
            enc.lp(&mut w, &res, mx as u32, tile_w)?;
            let (before, rest) = cur_cbp.split_at_mut(mx * channels);
            let left_cbp = (mx > 0).then(|| &before[(mx - 1) * channels..]);
            let top_cbp = (my > 0).then(|| &top_cbp[mx * channels..(mx + 1) * channels]);
            enc.cbp_hp(&mut w, &res, left_cbp, top_cbp, &mut rest[..channels], mode, mx as u32, tile_w, true)?;
        }
    }
    w.align();
    Ok(w.into_bytes())
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
    fn dark_macroblocks_get_coarser_hp_quantizers() {
        // Left half at 0.01 cd/m², right half at 300 cd/m² (scRGB units of 80 cd/m²).
        let (w, h) = (64u32, 32u32);
        let samples = (0..w * h * 3).map(|i| if (i / 3) % w < w / 2 { 0.01 / 80.0 } else { 300.0 / 80.0 }).collect();
        let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 80.0, hdr10: None };
        let image = HdrImage::new(w, h, Channels::Rgb, samples, color).unwrap();
        let sets = macroblock_hp_sets(&image, 1.0, 4, 2, HP_SET_OFFSETS.len());
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

    #[test]
    fn options_come_from_the_settings() {
        let s = EncodeSettings::default().with_quality(70);
        assert_eq!(EncodeOptions::from_settings(&s).unwrap().quality, 70);
        let s = s.with_option("lossless", "true").with_option("format", "float").with_option("tile", "256");
        let o = EncodeOptions::from_settings(&s).unwrap();
        assert_eq!((o.quality, o.format, o.tile_mbs, o.alpha_quality), (100, SampleFormat::Float, 16, 100));
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
        for (k, v) in [
            ("tile", "100"),
            ("format", "rgbe"),
            ("overlap", "3"),
            ("lossless", "perhaps"),
            ("adaptive", "maybe"),
            ("alpha_quality", "101"),
            ("alpha_quality", "x"),
            ("no-such", "1"),
        ] {
            assert!(EncodeOptions::from_settings(&EncodeSettings::default().with_option(k, v)).is_err(), "{k}={v}");
        }
    }
}
