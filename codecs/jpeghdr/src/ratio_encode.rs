//! Ward & Simmons' JPEG-HDR encoding (APGV 2004, CIC 2005), written as the format's author's
//! library (panlib) writes it and reads it back (`../shared/HDRJPEG-NOTES.md` section 1):
//!
//! - the luminance Y of the HDR image is tone-mapped with the GT curve (`t`, 1.0 = SDR white =
//!   203 cd/m², as the gain-map encoder does); the ratio image is `RI = Y / t`, its natural log
//!   optionally downsampled (Gaussian, as the reference) to `RI_d`, and coded in 8 bits between
//!   its minimum `ln0` and maximum `ln1`: code `i` decodes as `exp(ln0 + (i + 0.5)/256 · (ln1 −
//!   ln0))`;
//! - pre-correction (`cor=1`; `cor=0` at full resolution): the base is `HDR / RI'`, where `RI'`
//!   is the ratio image as decoders will see it (the ratio JPEG decoded and upsampled with
//!   Catmull-Rom weights), so the base carries what the ratio's resolution, its 8-bit coding and
//!   its JPEG lost; post-correction (`cor=2`): the base is the plain tone-mapped image and the
//!   decoder restores the ratio's detail from the base's luma, `RI' = RI_d · (T / T_d)^σ`;
//! - colours outside what the base's Y'CbCr cube holds (out of BT.709, or too bright for their
//!   luminance) are desaturated towards grey with `alp` (`C' = Y + α (C − Y)`, luminance kept,
//!   undone by decoders), α the largest that fits all but 0.01 % of the pixels, those clipped
//!   and counted in the report;
//! - the base's R'G'B' (sRGB curve mirrored below zero, scaled by 256 as the reference decodes
//!   it) becomes Y'CbCr with JFIF's matrix, unclamped until it is quantised: negative R'G'B'
//!   values are the format's wide gamut;
//! - the ratio JPEG (greyscale, baseline) is split over APP11 segments of at most 65 280 bytes
//!   of payload, each beginning `HDR_RI `: the first with the header `ver=11`, `ln0`, `ln1`,
//!   `s2n` (= `nits_per_unit`), `alp`, `bet`, `cor` in the reference's exact format, the next
//!   ones `ext=1`, `ext=2`, …, each ending `~` and a NUL before its chunk.

use crate::encode::{base_image, jpeg_error};
use crate::gainmap::{decode_jpeg_as, SDR_WHITE_NITS};
use crate::ratio::{gaussian_downsample, luma, upsample, Correction, RatioHeader, SIGNATURE};
use hdrcodec_core::tonemap::ToneOperator;
use hdrcodec_core::SrgbTransfer;
use hdrcodec_core::{ColorPrimaries, EncodeReport, EncodeSettings, Error, GtToneCurve, HdrImage, Limits, Result};

/// The most a segment's payload holds (the reference's limit: length field ≤ 65 282).
pub const MAX_PAYLOAD: usize = 0xFF00;

/// Luminance at or below this (in the image's units) is black: base black, smallest ratio.
const BLACK: f64 = 1e-10;

/// The widest ratio range coded (natural-log units), as the reference; wider ranges lose their
/// darkest ratios (the pre-corrected base takes them up where it can).
const MAX_LN_RANGE: f64 = 16.0;

/// The narrowest ratio range (a flat ratio still needs ln0 < ln1).
const MIN_LN_RANGE: f64 = 0.01;

/// The base's linear luminance above which colours are not considered in choosing α.
const HIGHLIGHT: f64 = 0.75;

/// Options of the JPEG-HDR encoder (`--opt key=value`: `ratio_quality`, `ratio_scale`,
/// `correction=pre|post`, `alpha=auto|0.5..1`; the base's quality is the settings' `quality`).
#[derive(Clone, Debug, PartialEq)]
pub struct RatioEncodeOptions {
    /// JPEG quality of the base image (1-100).
    pub base_quality: u8,
    /// JPEG quality of the ratio image (1-100).
    pub ratio_quality: u8,
    /// The ratio image is this many times smaller than the base on each axis (1-16; 1 writes
    /// `cor=0`).
    pub ratio_scale: u32,
    /// How the downsampled ratio's lost detail comes back: [`Correction::Pre`] (the base
    /// carries it) or [`Correction::Post`] (decoders rebuild it from the base's luma).
    pub correction: Correction,
    /// The desaturation `alp` (β is 1); `None`: the largest with which all but 0.01 % of the
    /// pixels below the base's highlights fit (not below 0.5).
    pub alpha: Option<f64>,
    /// The tone-mapping operator applied to luminance for the base (core's; 1.0 = SDR white
    /// in, the base's white out): the GT curve by default.
    pub tone: ToneOperator,
}

impl Default for RatioEncodeOptions {
    /// Base quality 90 (4:2:0, the reference's default), ratio image at half size per axis,
    /// quality 90, pre-corrected, α chosen for the image.
    fn default() -> Self {
        RatioEncodeOptions {
            base_quality: 90,
            ratio_quality: 90,
            ratio_scale: 2,
            correction: Correction::Pre,
            alpha: None,
            tone: ToneOperator::Gt(GtToneCurve::default()),
        }
    }
}

impl RatioEncodeOptions {
    /// The options `settings` give (unknown keys are errors).
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options("jpeg-hdr", &["ratio_quality", "ratio_scale", "correction", "alpha", "tone"])?;
        let d = Self::default();
        let correction = match settings.option("correction") {
            None => d.correction,
            Some("pre") => Correction::Pre,
            Some("post") => Correction::Post,
            Some(v) => return Err(Error::invalid(format!("correction={v} (pre or post)"))),
        };
        let alpha = match settings.option("alpha") {
            None | Some("auto") => None,
            Some(_) => settings.parse_option::<f64>("alpha")?,
        };
        let o = RatioEncodeOptions {
            base_quality: settings.quality.clamp(1, 100),
            ratio_quality: settings.parse_option("ratio_quality")?.unwrap_or(d.ratio_quality),
            ratio_scale: settings.parse_option("ratio_scale")?.unwrap_or(d.ratio_scale),
            correction,
            alpha,
            tone: settings.option("tone").map(str::parse).transpose()?.unwrap_or(d.tone),
        };
        o.check()?;
        Ok(o)
    }

    fn check(&self) -> Result<()> {
        if !(1..=100).contains(&self.ratio_quality) || !(1..=100).contains(&self.base_quality) {
            return Err(Error::invalid(format!("quality {} / {} (1-100)", self.base_quality, self.ratio_quality)));
        }
        if !(1..=16).contains(&self.ratio_scale) {
            return Err(Error::invalid(format!("ratio_scale={} (1-16)", self.ratio_scale)));
        }
        if self.correction == Correction::FullResolution {
            return Err(Error::invalid("correction: pre or post (full resolution is ratio_scale=1)"));
        }
        if let Some(a) = self.alpha {
            if !(0.5..=1.0).contains(&a) {
                return Err(Error::invalid(format!("alpha={a} (0.5 to 1)")));
            }
        }
        Ok(())
    }
}

/// `x` in C's `%e` form (`1.790000e+02`), as the reference writes `s2n`.
pub fn c_exponential(x: f64) -> String {
    let s = format!("{x:.6e}");
    match s.split_once('e') {
        Some((mantissa, exp)) => {
            let e: i32 = exp.parse().unwrap_or(0);
            format!("{mantissa}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
        }
        None => s,
    }
}

/// The first segment's header text (without `HDR_RI ` and the NUL), as the reference writes it.
pub fn header_text(ln: [f64; 2], s2n: f64, alpha: f64, beta: f64, correction: Correction) -> String {
    let cor = match correction {
        Correction::FullResolution => 0,
        Correction::Pre => 1,
        Correction::Post => 2,
    };
    format!(
        "ver=11\n ln0={:.6}, ln1={:.6}, s2n={} alp={alpha:.6} bet={beta:.6} cor={cor}\n~",
        ln[0],
        ln[1],
        c_exponential(s2n)
    )
}

/// The APP11 payloads that carry `ratio_jpeg` after `header`: `HDR_RI ` + text + NUL + chunk,
/// each at most [`MAX_PAYLOAD`] bytes; the first with `header`, the next `ext=1`, `ext=2`, …
pub fn segments(header: &str, ratio_jpeg: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut rest = ratio_jpeg;
    while out.is_empty() || !rest.is_empty() {
        let text = if out.is_empty() { header.to_string() } else { format!("ext={}\n~", out.len()) };
        let room = MAX_PAYLOAD - SIGNATURE.len() - text.len() - 1;
        let (chunk, tail) = rest.split_at(room.min(rest.len()));
        out.push([SIGNATURE, text.as_bytes(), &[0], chunk].concat());
        rest = tail;
    }
    out
}

/// Each destination pixel of a `(dw, dh)` plane: the largest source value within 1.5
/// destination pixels of its centre (the footprint of [`gaussian_downsample`]).
fn max_downsample(src: &[f32], (sw, sh): (usize, usize), (dw, dh): (usize, usize)) -> Vec<f64> {
    let spans = |d: usize, s: usize| -> Vec<(usize, usize)> {
        let ratio = s as f64 / d as f64;
        (0..d)
            .map(|x| {
                let centre = (x as f64 + 0.5) * ratio;
                let lo = (centre - 1.5 * ratio).floor().max(0.0) as usize;
                let hi = ((centre + 1.5 * ratio).ceil() as usize).min(s);
                (lo.min(s - 1), hi.max(lo + 1).min(s))
            })
            .collect()
    };
    let (xs, ys) = (spans(dw, sw), spans(dh, sh));
    // Rows first: each source row reduced to the destination's columns.
    let mut cols = Vec::with_capacity(sh * dw);
    for row in src.chunks_exact(sw) {
        cols.extend(xs.iter().map(|&(a, b)| row[a..b].iter().copied().fold(f32::NEG_INFINITY, f32::max)));
    }
    let mut out = Vec::with_capacity(dw * dh);
    for &(a, b) in &ys {
        for x in 0..dw {
            out.push(f64::from((a..b).map(|y| cols[y * dw + x]).fold(f32::NEG_INFINITY, f32::max)));
        }
    }
    out
}

/// The sRGB code (× 256, as decoders divide by 256) of linear `v`, mirrored below zero.
fn code(v: f64) -> f64 {
    256.0 * SrgbTransfer::encode(v)
}

/// JFIF's R'G'B' → Y'CbCr (T.871), unclamped.
fn ycc(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb;
    [
        0.299 * r + 0.587 * g + 0.114 * b,
        -0.168_735_892 * r - 0.331_264_108 * g + 0.5 * b + 128.0,
        0.5 * r - 0.418_687_589 * g - 0.081_312_411 * b + 128.0,
    ]
}

/// The Y'CbCr of linear `rgb` (luminance `y`) desaturated by `alpha`, and whether it fits.
fn base_ycc(rgb: [f64; 3], y: f64, alpha: f64) -> ([f64; 3], bool) {
    let v = ycc(rgb.map(|c| code(y + alpha * (c - y))));
    (v, v.iter().all(|c| (-0.5..255.5).contains(c)))
}

/// The largest α (to 1/1024) that brings `rgb` into the cube, 0 if even grey does not fit.
fn alpha_needed(rgb: [f64; 3], y: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    if !base_ycc(rgb, y, lo).1 {
        return 0.0;
    }
    for _ in 0..10 {
        let mid = (lo + hi) / 2.0;
        if base_ycc(rgb, y, mid).1 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The tone-mapped luminance `t` of the colour `rgb` (luminance `y`), lowered (to a quarter at
/// most) until the colour fits the base's Y'CbCr undesaturated: near the base's white, the luma
/// of a saturated colour exceeds the cube; the ratio then carries the difference, and the colour
/// stays (on a 128x96 test scene with saturated highlights, 3627 pixels clipped without this).
fn fitting(rgb: [f64; 3], y: f64, t: f64, alpha: f64) -> f64 {
    let at = |l: f64| base_ycc(rgb.map(|c| c * l / y), l, alpha).1;
    let (mut lo, mut hi) = (t / 4.0, t);
    if at(hi) || !at(lo) {
        return t;
    }
    for _ in 0..12 {
        let mid = (lo + hi) / 2.0;
        if at(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Encodes `image` as a JPEG-HDR file.
pub fn encode_jpeg_hdr(image: &HdrImage, options: &RatioEncodeOptions) -> Result<(Vec<u8>, EncodeReport)> {
    options.check()?;
    let mut report = EncodeReport::new();
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 || w > 65535 || h > 65535 {
        return Err(Error::invalid(format!("a JPEG is 1 to 65535 pixels on a side, not {w}x{h}")));
    }
    // JPEG-HDR is BT.709 only: its wide gamut is the unclamped Y'CbCr.
    let (image, _) = base_image(image, &[ColorPrimaries::Bt709], &mut report);
    let image = image.as_ref();
    let channels = image.channels().count();
    let nits = f64::from(image.color.nits_per_unit);
    let s2n = if nits.is_finite() && nits > 0.0 { nits } else { 0.0 };
    let to_sdr = if s2n > 0.0 { s2n / f64::from(SDR_WHITE_NITS) } else { 1.0 };
    let pixel = |i: usize| -> [f64; 3] {
        let p = &image.samples()[i * channels..i * channels + 3];
        [0, 1, 2].map(|c| if p[c].is_finite() { f64::from(p[c]) } else { 0.0 })
    };
    // The tone-mapped luminance (linear, 1.0 = the base's white) of HDR luminance y.
    // (At most the brightest grey the base codes: 255.5 / 256 of the sRGB curve.)
    let white = SrgbTransfer::decode(255.4 / 256.0);
    // (At least the grey of sRGB code 16, as the reference raises its codes below 20: the
    // ratio, not the base's few darkest codes, carries the deep shadows.)
    let shadow = SrgbTransfer::decode(16.0 / 256.0);
    let tone_map = |y: f64| {
        let t = options.tone.map(y * to_sdr);
        (if t.is_nan() { 0.0 } else { t }).clamp(shadow, white)
    };

    // The log ratio at full resolution; black pixels take the smallest ratio around.
    let mut ln_ratio: Vec<f32> = (0..w * h)
        .map(|i| {
            let rgb = pixel(i);
            let y = luma(rgb);
            if y > BLACK {
                (y / fitting(rgb, y, tone_map(y), 1.0)).ln() as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let darkest = ln_ratio.iter().copied().filter(|v| v.is_finite()).fold(f32::INFINITY, f32::min);
    let darkest = if darkest.is_finite() { darkest } else { 0.0 };
    ln_ratio.iter_mut().filter(|v| !v.is_finite()).for_each(|v| *v = darkest);

    let scale = options.ratio_scale as usize;
    let (rw, rh) = (w.div_ceil(scale), h.div_ceil(scale));
    let correction = if (rw, rh) == (w, h) { Correction::FullResolution } else { options.correction };
    let small: Vec<f64> = match correction {
        Correction::FullResolution => ln_ratio.iter().map(|&v| f64::from(v)).collect(),
        // The reference's Gaussian: what post-correction's decoder side expects.
        Correction::Post => gaussian_downsample(&ln_ratio, (w, h), (rw, rh)),
        // The largest ratio around (the Gaussian's footprint): the pre-corrected base is the
        // HDR image over the upsampled ratio, and where that ratio fell short of a highlight's
        // the base could not hold it (on a 384x256 crop of Desk, 25.5 against 34 dB).
        Correction::Pre => max_downsample(&ln_ratio, (w, h), (rw, rh)),
    };
    drop(ln_ratio);
    let lo = small.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = small.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    // Six decimals, as written, rounded outwards.
    let mut ln = [(lo * 1e6).floor() / 1e6, (hi * 1e6).ceil() / 1e6];
    if ln[1] - ln[0] < MIN_LN_RANGE {
        let mid = (ln[0] + ln[1]) / 2.0;
        ln = [((mid - MIN_LN_RANGE / 2.0) * 1e6).floor() / 1e6, ((mid + MIN_LN_RANGE / 2.0) * 1e6).ceil() / 1e6];
    }
    if ln[1] - ln[0] > MAX_LN_RANGE {
        report.note(format!(
            "ratios span {:.1} natural-log units: the darkest below e^{:.2} are coded at it",
            ln[1] - ln[0],
            ln[1] - MAX_LN_RANGE
        ));
        ln[0] = ln[1] - MAX_LN_RANGE;
    }
    let span = ln[1] - ln[0];
    let codes: Vec<u8> =
        small.iter().map(|&v| (256.0 * (v - ln[0]) / span - 0.5).round().clamp(0.0, 255.0) as u8).collect();
    drop(small);
    let mut ratio_jpeg = Vec::new();
    jpeg_encoder::Encoder::new(&mut ratio_jpeg, options.ratio_quality)
        .encode(&codes, rw as u16, rh as u16, jpeg_encoder::ColorType::Luma)
        .map_err(|e| jpeg_error("ratio image", e))?;

    // The ratio decoders will apply (for pre-correction): our decoder's reading of the JPEG.
    let decoded = if correction == Correction::Post {
        None
    } else {
        // (Our own JPEG, no larger than the image being encoded: trusted.)
        let got = decode_jpeg_as(&ratio_jpeg, &Limits::none(), "JPEG-HDR ratio image", false)?;
        Some(if correction == Correction::FullResolution {
            got.samples.iter().map(|&c| f32::from(c)).collect::<Vec<f32>>()
        } else {
            upsample(&got.samples, (rw, rh), (w, h))
        })
    };
    let ratio_of = |code: f32| (ln[0] + (f64::from(code) + 0.5) / 256.0 * span).exp();
    // The base's linear colour at pixel i, before desaturation, and its luminance.
    let base_linear = |i: usize| -> ([f64; 3], f64) {
        let rgb = pixel(i);
        let y = luma(rgb);
        if y <= BLACK {
            return ([0.0; 3], 0.0);
        }
        let yb = match &decoded {
            Some(r) => (y / ratio_of(r[i])).min(white),
            None => fitting(rgb, y, tone_map(y), 1.0),
        };
        (rgb.map(|c| c * yb / y), yb)
    };

    // α: the largest that fits all but 0.01 % of the pixels below the base's highlights (near
    // its white, the luma of a saturated colour exceeds the cube at any α worth having: those
    // are clipped, and counted).
    let alpha = match options.alpha {
        Some(a) => a,
        None => {
            let mut needed: Vec<f64> = (0..w * h)
                .filter_map(|i| {
                    let (rgb, y) = base_linear(i);
                    (y <= HIGHLIGHT && !base_ycc(rgb, y, 1.0).1).then(|| alpha_needed(rgb, y))
                })
                .collect();
            needed.sort_by(f64::total_cmp);
            let allowed = w * h / 10_000;
            if needed.len() > allowed {
                needed[allowed].clamp(0.5, 1.0)
            } else {
                1.0
            }
        }
    };
    // Six decimals, as written (and rounded down: a little more desaturation, never less).
    let alpha = (alpha * 1e6).floor() / 1e6;

    let mut base = Vec::with_capacity(w * h * 3);
    let (mut clipped, mut darkened) = (0usize, 0usize);
    for i in 0..w * h {
        let (rgb, y) = base_linear(i);
        let (mut v, fits) = base_ycc(rgb, y, alpha);
        if !fits {
            // Darker (a luminance error) rather than clipped (a colour error too), where a
            // quarter of the luminance suffices.
            let l = fitting(rgb, y, y, alpha);
            let (w, fits) = base_ycc(rgb.map(|c| c * l / y), l, alpha);
            if fits {
                darkened += 1;
            } else {
                clipped += 1;
            }
            v = w;
        }
        base.extend(v.map(|c| c.round().clamp(0.0, 255.0) as u8));
    }
    if alpha < 1.0 {
        report.note(format!("colours desaturated by alp={alpha:.3} in the base (decoders resaturate them)"));
    }
    if darkened > 0 {
        report.note(format!("{darkened} pixels were darkened (at most to a quarter) to fit the base's Y'CbCr"));
    }
    if clipped > 0 {
        report.note(format!("{clipped} pixels outside what the base's Y'CbCr holds were clipped"));
    }

    let header = header_text(ln, s2n, alpha, 1.0, correction);
    debug_assert!(RatioHeader::parse(&header).is_ok());
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, options.base_quality);
    encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
    for segment in segments(&header, &ratio_jpeg) {
        encoder.add_app_segment(11, &segment).map_err(|e| jpeg_error("base image", e))?;
    }
    encoder
        .encode(&base, w as u16, h as u16, jpeg_encoder::ColorType::Ycbcr)
        .map_err(|e| jpeg_error("base image", e))?;
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gainmap::{decode, Rendering};
    use crate::markers::{self, APP11};
    use crate::ratio::ratio_image;
    use hdrcodec_core::metrics::pu21_psnr;
    use hdrcodec_core::{Channels, ColorInfo};

    /// A w x h ramp over four decades with a saturated red patch and a green one outside
    /// BT.709 (a negative blue), in cd/m² / 100.
    fn scene(w: u32, h: u32) -> HdrImage {
        let mut s = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let l = 10f32.powf(-1.5 + 4.0 * x as f32 / w as f32);
                let mut p = [l, l * (0.6 + 0.4 * y as f32 / h as f32), l * 0.8];
                if y * 4 / h == 1 && x * 4 / w == 2 {
                    p = [3.0 * l, 0.5 * l, 0.4 * l];
                }
                if y * 4 / h == 2 && x * 4 / w == 1 {
                    p = [0.1 * l, 1.2 * l, -0.05 * l];
                }
                s.extend(p);
            }
        }
        HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() }).unwrap()
    }

    fn pu21(a: &HdrImage, b: &HdrImage) -> f64 {
        pu21_psnr(a, b).unwrap()
    }

    #[test]
    fn round_trips_through_our_decoder() {
        let image = scene(128, 96);
        for (scale, correction, floor) in [
            (1, Correction::Pre, 42.0),
            (2, Correction::Pre, 42.0),
            (2, Correction::Post, 40.0),
            (4, Correction::Pre, 42.0),
        ] {
            let options = RatioEncodeOptions { ratio_scale: scale, correction, ..Default::default() };
            let (file, report) = encode_jpeg_hdr(&image, &options).unwrap();
            let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            let note = back.metadata_value("jpeg.ratio_image").unwrap().to_string();
            assert!(note.starts_with("JPEG-HDR ver=11"), "{note}");
            assert_eq!((back.width(), back.height(), back.color.nits_per_unit), (128, 96, 100.0));
            let q = pu21(&image, &back);
            eprintln!("scale {scale} {correction:?}: {} bytes, PU21-PSNR {q:.1} dB, {:?}", file.len(), report.notes);
            assert!(q >= floor, "scale {scale} {correction:?}: {q}");
            // The green outside BT.709 comes back with its negative blue (through alp).
            let i = (96 * 5 / 8 * 128 + 128 * 3 / 8) * 3;
            assert!(back.samples()[i + 2] < 0.0, "{:?}", &back.samples()[i..i + 3]);
        }
    }

    #[test]
    fn header_is_written_as_the_reference_writes_it() {
        assert_eq!(c_exponential(179.0), "1.790000e+02");
        assert_eq!(c_exponential(0.0), "0.000000e+00");
        assert_eq!(c_exponential(2.5e-3), "2.500000e-03");
        let text = header_text([0.0, 4.997205], 179.0, 1.0, 1.0, Correction::Pre);
        assert_eq!(text, "ver=11\n ln0=0.000000, ln1=4.997205, s2n=1.790000e+02 alp=1.000000 bet=1.000000 cor=1\n~");
        let h = RatioHeader::parse(&text).unwrap();
        assert_eq!((h.ln_range, h.correction, h.samples_to_nits), ([0.0, 4.997205], Correction::Pre, 179.0));
    }

    #[test]
    fn codes_decode_by_the_formula() {
        // A flat image: ratio range widened to MIN_LN_RANGE around its ratio; every code then
        // decodes as exp(ln0 + (i + 0.5)/256 · (ln1 − ln0)) within half a step of the ratio.
        let image = HdrImage::new(
            16,
            16,
            Channels::Rgb,
            vec![2.0; 16 * 16 * 3],
            ColorInfo { nits_per_unit: 203.0, ..Default::default() },
        )
        .unwrap();
        let options = RatioEncodeOptions { ratio_scale: 1, ..Default::default() };
        let (file, _) = encode_jpeg_hdr(&image, &options).unwrap();
        let parsed = markers::parse_image(&file, 0).unwrap();
        let (header, _) = ratio_image(&parsed).unwrap().unwrap();
        let [ln0, ln1] = header.ln_range;
        assert!((ln1 - ln0 - MIN_LN_RANGE).abs() < 2e-6, "{ln0} {ln1}");
        let ratio = 2.0 / curve_at(2.0);
        assert!(ln0 <= ratio.ln() && ratio.ln() <= ln1, "{ln0} {ln1} {ratio}");
        assert_eq!(header.correction, Correction::FullResolution);
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        assert!(back.samples().iter().all(|&v| (v - 2.0).abs() < 0.03), "{:?}", &back.samples()[..3]);
    }

    fn curve_at(y: f64) -> f64 {
        GtToneCurve::default().map(y).clamp(1e-6, SrgbTransfer::decode(255.4 / 256.0))
    }

    #[test]
    fn big_ratio_images_span_several_segments() {
        // Noise: a ratio JPEG far over 64 KB.
        let (w, h) = (512u32, 384u32);
        let mut state = 12345u32;
        let samples: Vec<f32> = (0..w * h)
            .flat_map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let l = 10f32.powf((state >> 8) as f32 / (1u32 << 24) as f32 * 5.0 - 2.0);
                [l, l, l]
            })
            .collect();
        let image = HdrImage::new(w, h, Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let options = RatioEncodeOptions { ratio_scale: 1, ratio_quality: 100, ..Default::default() };
        let (file, _) = encode_jpeg_hdr(&image, &options).unwrap();
        let parsed = markers::parse_image(&file, 0).unwrap();
        let payloads: Vec<&[u8]> = parsed.app_payloads(APP11, SIGNATURE).map(|(_, p)| p).collect();
        assert!(payloads.len() >= 3, "{}", payloads.len());
        // (The payloads come without the signature.)
        assert!(payloads.iter().all(|p| SIGNATURE.len() + p.len() <= MAX_PAYLOAD));
        for (n, p) in payloads.iter().enumerate().skip(1) {
            assert!(p.starts_with(format!("ext={n}\n~\0").as_bytes()));
        }
        let (_, jpeg) = ratio_image(&parsed).unwrap().unwrap();
        assert!(jpeg.len() > 2 * 65536 && jpeg.starts_with(&[0xFF, 0xD8]) && jpeg.ends_with(&[0xFF, 0xD9]));
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        let q = pu21(&image, &back);
        assert!(q > 30.0, "{q}");
    }

    #[test]
    fn foreign_app11_segments_beside_ours_stay_and_do_not_matter() {
        let image = scene(64, 48);
        let (file, _) = encode_jpeg_hdr(&image, &RatioEncodeOptions::default()).unwrap();
        let clean = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        // Two JUMBF (C2PA) packets, one before and one after our segments: `JP`, box instance,
        // sequence number, box header, content.
        let jumbf = |seq: u8| -> Vec<u8> {
            let mut p = b"JP\x00\x01\x00\x00\x00".to_vec();
            p.push(seq);
            p.extend_from_slice(&[0, 0, 0, 40]);
            p.extend_from_slice(b"jumbc2pa");
            p.extend((0..32).map(|i| i as u8 ^ seq));
            p
        };
        let segment = |p: &[u8]| [&[0xFF, 0xEB], &((p.len() + 2) as u16).to_be_bytes()[..], p].concat();
        let ours = file.windows(9).position(|w| w[0] == 0xFF && w[1] == 0xEB && &w[4..9] == b"HDR_R").unwrap();
        let mut mixed = file[..ours].to_vec();
        mixed.extend(segment(&jumbf(1)));
        let after = ours + 2 + usize::from(u16::from_be_bytes([file[ours + 2], file[ours + 3]]));
        mixed.extend_from_slice(&file[ours..after]);
        mixed.extend(segment(&jumbf(2)));
        mixed.extend_from_slice(&file[after..]);
        let back = decode(&mixed, &Limits::default(), Rendering::default()).unwrap();
        assert_eq!(back.samples(), clean.samples());
        let parsed = markers::parse_image(&mixed, 0).unwrap();
        let kept: Vec<&[u8]> = parsed.app_payloads(APP11, b"JP").map(|(_, p)| p).collect();
        assert_eq!(kept, [&jumbf(1)[2..], &jumbf(2)[2..]]);
    }

    #[test]
    fn odd_images_encode_and_decode() {
        let odd = |w: u32, h: u32, f: &dyn Fn(u32) -> f32| {
            let s: Vec<f32> = (0..w * h * 3).map(f).collect();
            HdrImage::new(w, h, Channels::Rgb, s, ColorInfo::default()).unwrap()
        };
        let images = [
            odd(1, 1, &|_| 0.5),
            odd(3, 5, &|i| i as f32),
            odd(17, 9, &|_| 0.0),
            odd(17, 9, &|i| [f32::NAN, f32::INFINITY, -1.0, 1e30, 1e-30][i as usize % 5]),
            odd(40, 2, &|i| if i % 7 == 0 { -5.0 } else { 1e4 }),
        ];
        for image in &images {
            for correction in [Correction::Pre, Correction::Post] {
                let options = RatioEncodeOptions { correction, ..Default::default() };
                let (file, _) = encode_jpeg_hdr(image, &options).unwrap();
                let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
                assert_eq!((back.width(), back.height()), (image.width(), image.height()));
                assert!(back.metadata_value("jpeg.ratio_image").is_some(), "{:?}", back.metadata);
            }
        }
    }

    #[test]
    fn options_are_checked() {
        let bad =
            |k: &str, v: &str| RatioEncodeOptions::from_settings(&EncodeSettings::default().with_option(k, v)).is_err();
        assert!(bad("ratio_scale", "0") && bad("ratio_scale", "17") && bad("correction", "none"));
        assert!(bad("alpha", "0.2") && bad("ratio_quality", "0") && bad("map_scale", "2"));
        assert!(!bad("alpha", "auto") && !bad("alpha", "0.8") && !bad("correction", "post"));
        assert!(bad("tone", "aces") && !bad("tone", "reinhard") && !bad("tone", "reinhard-extended:4"));
    }

    #[test]
    fn any_core_tone_operator_makes_the_base() {
        // Another operator gives another SDR base; the ratio image still restores the HDR image.
        let image = scene(128, 96);
        let (gt, _) = encode_jpeg_hdr(&image, &RatioEncodeOptions::default()).unwrap();
        for tone in ["reinhard", "reinhard-extended:8"] {
            let options = RatioEncodeOptions { tone: tone.parse().unwrap(), ..Default::default() };
            let (file, _) = encode_jpeg_hdr(&image, &options).unwrap();
            assert_ne!(file, gt, "{tone}");
            let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            let q = pu21(&image, &back);
            assert!(q >= 40.0, "{tone}: {q}");
        }
    }
}
