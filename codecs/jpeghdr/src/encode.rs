//! Gain-map JPEG encoding: a tone-mapped sRGB base every viewer shows, a gain map that turns it
//! back into the HDR image, and the metadata every reader looks for (what
//! `../shared/HDRJPEG-NOTES.md` section 7 lists): in the primary, the hdrgm XMP version with a
//! GContainer directory, the ISO 21496-1 version record and an MPF index; in the gain map, the
//! nine hdrgm properties and the full ISO 21496-1 record.
//!
//! The gain: luminance is tone-mapped with the GT curve (1.0 = SDR white = 203 cd/m²; a linear
//! toe, see `base_curve`) and the colour scaled with it, desaturated towards grey where a
//! channel would leave [0, 1]; the log ratio of HDR to that is averaged over the map's pixels
//! and quantised; the map is JPEG-encoded and decoded again, and the base is the HDR image
//! divided by the gain decoders will apply (pre-correction, as JPEG-HDR's `cor=1`).

use crate::gainmap::SDR_WHITE_NITS;
use crate::markers::{self, APP1, APP2};
use crate::metadata::{GainMapMetadata, ISO_SIGNATURE};
use crate::{exif, icc, mpf, xmp};
use hdrcodec_core::color::{convert_primaries, luminance_weights};
use hdrcodec_core::tonemap::ToneOperator;
use hdrcodec_core::{ColorPrimaries, EncodeReport, EncodeSettings, Error, GtToneCurve, HdrImage, Result, SrgbTransfer};
use std::borrow::Cow;

/// How the map is raised where bright lights need more gain than the averaged map gives
/// (`map_raise=`): each way keeps every light under the base's white (before the map's JPEG),
/// and darkens the base around it by a different amount.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapRaise {
    /// Every map pixel of each base pixel's 2×2 map neighbourhood to that pixel's need, including
    /// a neighbour whose weight in its bilinear mix is zero (`neighbourhood`; Desk's base TMQI
    /// 0.876).
    Neighbourhood,
    /// The map pixels whose weight in a base pixel's mix is above zero, to its need
    /// (`contributing`, the default; Desk 0.894).
    Contributing,
    /// Those map pixels by what the mix lacks of the need, plus a margin of 0.1 stops
    /// (`deficit`; Desk 0.916): where a neighbouring map pixel already carries a brighter
    /// light's gain, the edge pixels between them need little or no raise. Not the default: the
    /// sharper map decodes less alike in libultrahdr, whose map upsampling differs from ours
    /// (MtTamWest crop, one-channel map: 48.2 dB PU21-PSNR between the two decodes against
    /// 51.3), and Desk's ΔE ITP rises by 0.13 to 0.23 at q85 to q50 (crate README).
    Deficit,
}

/// Options of the gain-map encoder (`--opt key=value`: `map_quality`, `map_scale=auto|N`,
/// `map_channels`, `base_chroma=420|444`, `bright_colours=desaturate|keep`, `tone=`,
/// `map_raise=contributing|deficit|neighbourhood`, `zero_gain=anywhere|on_code`, `black_level=fit|none`;
/// the base's quality is the settings' `quality`).
#[derive(Clone, Debug, PartialEq)]
pub struct GainMapEncodeOptions {
    /// JPEG quality of the base image (1-100).
    pub base_quality: u8,
    /// JPEG quality of the gain map (1-100). By default 85, or the base's quality when that is
    /// higher: at base quality 90 and 95 on the corpus photographs, a map at the base's quality
    /// costs 1-8 % more bytes for 0.1 to 3 dB more PU21-PSNR and lower ΔE ITP (Desk q95: 4.18
    /// bpp, 36.2 dB, ΔE 8.2 with the map at 85; 4.50 bpp, 39.2 dB, ΔE 7.3 at 95), far above
    /// what those bytes buy through the base's quality.
    pub map_quality: u8,
    /// The map is this many times smaller than the base on each axis (1-16; `map_scale=N`), or
    /// `None` (`map_scale=auto`, the default): chosen per image, full size where a half-size
    /// map would darken the base too much around its lights and the base is 4:4:4, else half
    /// size (crate README, "A full-size map where the raise would darken the base").
    pub map_scale: Option<u32>,
    /// 3: a gain per channel (colours the base had to desaturate come back); 1: one gain for
    /// all channels, of luminance (a smaller map; such colours stay desaturated).
    pub map_channels: u8,
    /// The base's chroma at full resolution (4:4:4) instead of 4:2:0. By default from base
    /// quality 90 up ([`Self::full_chroma_for`]): there 4:2:0's chroma error dominates colour
    /// error. On the corpus photographs at equal size, 4:4:4 has 0.0 to 0.6 lower mean ΔE ITP
    /// and 0.7 to 1.5 dB lower PU21-PSNR than 4:2:0; against libultrahdr 1.4 (4:2:0) the
    /// default is ahead on both at every quality from 50 to 97, and 4:2:0 alone was behind on
    /// ΔE ITP at 90 and above on Desk and at 95 and above on GoldenGate (crate README).
    pub base_full_chroma: bool,
    /// Bright saturated colours that the base cannot hold at their tone-mapped luminance are
    /// darkened until they fit (true: the SDR picture keeps their colour) instead of
    /// desaturated towards white (false, the default: the three-channel map brings the colour
    /// back). Keeping them raises the map's gain range, which coarsens the map everywhere: on
    /// the corpus photographs, Desk's stained glass keeps its colours in the base (TMQI 0.876
    /// to 0.887) for 0 to 6 % more bytes, but StillLife's mean ΔE ITP rises by 2.
    pub keep_bright_colours: bool,
    /// The tone-mapping operator applied to luminance for the base (core's; 1.0 = SDR white in,
    /// the base's white out): by default the GT curve with a linear toe (see `base_curve`).
    pub tone: ToneOperator,
    /// How the map is raised where bright lights need more gain than the averaged map gives
    /// (see [`MapRaise`]; by default [`MapRaise::Contributing`]). The narrower raises darken less of
    /// the base around lights; before the black level was fitted
    /// ([`Self::fit_black_level`]), the contributing raise moved where StillLife's darks' gain
    /// fell between map codes (ΔE ITP at q95 12.9 to 14.0; crate README).
    pub map_raise: MapRaise,
    /// Widen each channel's coded gain range by about a code at most so that gain 0 falls exactly
    /// on a map code (`zero_gain=on_code`; default false, `zero_gain=anywhere`): the darks,
    /// whose base is the HDR image, then decode to gain 0 exactly whatever the range, instead
    /// of to the nearest code's gain. Measured worse, not better, on StillLife's darks (crate
    /// README): an option to measure with.
    pub zero_gain_on_a_code: bool,
    /// Fit the HDR rendition's black level per channel (`black_level=fit`, the default; `none`
    /// writes equal offsets): once the base is JPEG-coded, the alternate offsets are moved by
    /// up to about a base code at black so that the darks, decoded as decoders will decode
    /// them, come closest to the source in ΔE ITP (BT.2124). Where a base code is as large as
    /// the signal (sRGB code 1 is 0.06 cd/m²), which code a dark pixel rounds to and what the
    /// base's JPEG does to a block of codes 0 to 3 bias the darks; without the fit, that bias
    /// rested on where the map's range happened to put gain 0 (crate README, StillLife q95 ΔE
    /// ITP 12.9 → 9.9).
    pub fit_black_level: bool,
}

impl Default for GainMapEncodeOptions {
    /// Base quality 90 (4:4:4), map quality 90 at half size per axis (on the corpus
    /// photographs against a quarter, the Ultra HDR format's recommendation: 1.3 to 2.9 dB more
    /// mean PU21-PSNR for 8 to 29% more bytes, ahead at equal size) or full size where the
    /// half-size map's raise would darken the base (`map_scale=auto`), three channels (on the
    /// generated corpus: ΔE ITP 3.6 against 24 on the sky scene for 5% more bytes).
    fn default() -> Self {
        GainMapEncodeOptions {
            base_quality: 90,
            map_quality: Self::map_quality_for(90),
            map_scale: None,
            map_channels: 3,
            base_full_chroma: Self::full_chroma_for(90),
            keep_bright_colours: false,
            tone: ToneOperator::Gt(base_curve()),
            map_raise: MapRaise::Contributing,
            zero_gain_on_a_code: false,
            fit_black_level: true,
        }
    }
}

impl GainMapEncodeOptions {
    /// The map's default quality for a base of quality `base` (see [`Self::map_quality`]).
    pub fn map_quality_for(base: u8) -> u8 {
        base.max(85)
    }

    /// Whether a base of quality `base` gets 4:4:4 chroma by default (see
    /// [`Self::base_full_chroma`]).
    pub fn full_chroma_for(base: u8) -> bool {
        base >= 90
    }

    /// The options `settings` give (unknown keys are errors).
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options(
            "ultrahdr",
            &[
                "map_quality",
                "map_scale",
                "map_channels",
                "base_chroma",
                "bright_colours",
                "tone",
                "map_raise",
                "zero_gain",
                "black_level",
            ],
        )?;
        let d = Self::default();
        let base_quality = settings.quality.clamp(1, 100);
        let o = GainMapEncodeOptions {
            base_quality,
            map_quality: settings.parse_option("map_quality")?.unwrap_or(Self::map_quality_for(base_quality)),
            map_scale: match settings.option("map_scale") {
                None | Some("auto") => d.map_scale,
                Some(_) => settings.parse_option("map_scale")?,
            },
            map_channels: settings.parse_option("map_channels")?.unwrap_or(d.map_channels),
            base_full_chroma: match settings.option("base_chroma") {
                None => Self::full_chroma_for(base_quality),
                Some("420") => false,
                Some("444") => true,
                Some(other) => return Err(Error::invalid(format!("base_chroma={other} (420 or 444)"))),
            },
            keep_bright_colours: match settings.option("bright_colours") {
                None => d.keep_bright_colours,
                Some("desaturate") => false,
                Some("keep") => true,
                Some(other) => return Err(Error::invalid(format!("bright_colours={other} (desaturate or keep)"))),
            },
            tone: settings.option("tone").map(str::parse).transpose()?.unwrap_or(d.tone),
            map_raise: match settings.option("map_raise") {
                None => d.map_raise,
                Some("neighbourhood") => MapRaise::Neighbourhood,
                Some("contributing") => MapRaise::Contributing,
                Some("deficit") => MapRaise::Deficit,
                Some(other) => {
                    return Err(Error::invalid(format!("map_raise={other} (contributing, deficit or neighbourhood)")))
                }
            },
            zero_gain_on_a_code: match settings.option("zero_gain") {
                None => d.zero_gain_on_a_code,
                Some("anywhere") => false,
                Some("on_code") => true,
                Some(other) => return Err(Error::invalid(format!("zero_gain={other} (anywhere or on_code)"))),
            },
            fit_black_level: match settings.option("black_level") {
                None => d.fit_black_level,
                Some("fit") => true,
                Some("none") => false,
                Some(other) => return Err(Error::invalid(format!("black_level={other} (fit or none)"))),
            },
        };
        if !(1..=100).contains(&o.map_quality) {
            return Err(Error::invalid(format!("map_quality={} (1-100)", o.map_quality)));
        }
        if let Some(scale) = o.map_scale.filter(|s| !(1..=16).contains(s)) {
            return Err(Error::invalid(format!("map_scale={scale} (1-16 or auto)")));
        }
        if o.map_channels != 1 && o.map_channels != 3 {
            return Err(Error::invalid(format!("map_channels={} (1 or 3)", o.map_channels)));
        }
        Ok(o)
    }
}

/// The offset added on both sides of the gain (ISO 21496-1's k), so that black pixels keep a
/// finite gain: 1/256 of SDR white (0.8 cd/m²), not the Ultra HDR format's recommended 1/64
/// (3.2 cd/m²; libultrahdr 1.4 writes 0). A map code's error is an absolute error of about
/// k · 2% in the HDR rendition, colour-blind below k; on the corpus photographs at q85, 1/256
/// took mean ΔE ITP on StillLife from 17.3 to 15.0 and on GoldenGate from 4.7 to 4.3, PU21-PSNR
/// at equal size from −0.2 dB (Desk) to +0.5 dB (1/1024: about the same; StillLife 16.0).
const OFFSET: f64 = 1.0 / 256.0;

/// The base's tone curve: GT with a linear toe (black tightness 1 instead of the CEDEC 1.33),
/// the identity up to 0.53 of SDR white (108 cd/m²), then its shoulder. The default toe crushed
/// the darks (0.06 cd/m² to 0.007, sRGB code 0), so a dark scene's base held nothing below
/// 0.1 cd/m² and the gain carried it alone, as (0 + k)·G − k, where one map code is about
/// 0.07 cd/m² at k = 1/64: on StillLife (54% of it under 0.1 cd/m²) mean ΔE ITP 25.8 at q85, 17.3 with
/// this toe, in 6% fewer bytes (the map is flat where base and HDR agree).
fn base_curve() -> GtToneCurve {
    GtToneCurve { black: 1.0, ..GtToneCurve::default() }
}

/// Encodes `image` as a gain-map JPEG.
pub fn encode(image: &HdrImage, options: &GainMapEncodeOptions) -> Result<(Vec<u8>, EncodeReport)> {
    let mut report = EncodeReport::new();
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 || w > 65535 || h > 65535 {
        return Err(Error::invalid(format!("a JPEG is 1 to 65535 pixels on a side, not {w}x{h}")));
    }
    // The base is sRGB, or Display P3 with its ICC profile (what phones write).
    let (image, base_primaries) = base_image(image, &[ColorPrimaries::Bt709, ColorPrimaries::DisplayP3], &mut report);
    let image = image.as_ref();
    let profile = match base_primaries {
        ColorPrimaries::DisplayP3 => icc::rgb_profile(&base_primaries, "Display P3"),
        _ => None,
    };
    let weights = luminance_weights(&base_primaries);
    let scale = f64::from(image.color.nits_per_unit) / f64::from(SDR_WHITE_NITS);
    let channels = image.channels().count();
    let (tone_mapped, hdr, out_of_gamut) =
        tone_map(image.samples(), channels, scale, weights, &options.tone, options.keep_bright_colours);
    if out_of_gamut > 0 {
        report.note(format!("{out_of_gamut} pixels outside BT.709 were desaturated into it (luminance kept)"));
    }
    let map_channels = usize::from(options.map_channels);
    // The map's log2 gains at a scale, averaged and raised, the map's size, and how far the
    // raise lifted the map (`mean_lift`). A full-size map leaves no slack for its JPEG's errors
    // (`FULL_SIZE_RAISE_MARGIN`).
    let raised = |scale: usize| {
        let (mut gains, size) = averaged_gains(&tone_mapped, &hdr, (w, h), scale, map_channels, weights);
        let averaged = gains.clone();
        let margin = if scale == 1 { FULL_SIZE_RAISE_MARGIN } else { 0.0 };
        raise_to_fit(&mut gains, &hdr, (w, h), size, map_channels, options.map_raise, margin);
        let lift = mean_lift(&averaged, &gains, map_channels);
        (gains, size, lift)
    };
    let (gains, (mw, mh), _) = match options.map_scale {
        Some(s) => raised(s as usize),
        None => {
            // A half-size map, unless its raise would darken the base too much (see
            // `FULL_SIZE_MEAN_LIFT`) and the base's chroma is full.
            let half = raised(2);
            if options.base_full_chroma && half.2 > FULL_SIZE_MEAN_LIFT {
                report.note(format!(
                    "full-size gain map: a half-size one would darken the base by {:.2} stops on average around its lights",
                    half.2
                ));
                raised(1)
            } else {
                half
            }
        }
    };
    let mut gain_min = [f64::INFINITY; 3];
    let mut gain_max = [f64::NEG_INFINITY; 3];
    for px in gains.chunks_exact(map_channels) {
        for (c, &g) in px.iter().enumerate() {
            gain_min[c] = gain_min[c].min(g);
            gain_max[c] = gain_max[c].max(g);
        }
    }
    if map_channels == 1 {
        gain_min = [gain_min[0]; 3];
        gain_max = [gain_max[0]; 3];
    }
    for c in 0..3 {
        // A flat gain still needs a range to code it in.
        if gain_max[c] - gain_min[c] < 1e-3 {
            gain_max[c] = gain_min[c] + 0.1;
        }
        if options.zero_gain_on_a_code {
            (gain_min[c], gain_max[c]) = zero_on_a_code(gain_min[c], gain_max[c]);
        }
    }
    let map_codes: Vec<u8> = gains
        .chunks_exact(map_channels)
        .flat_map(|px| {
            px.iter().enumerate().map(|(c, &g)| {
                (255.0 * (g - gain_min[c]) / (gain_max[c] - gain_min[c])).round().clamp(0.0, 255.0) as u8
            })
        })
        .collect();
    let peak = gain_max.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut meta = GainMapMetadata {
        base_headroom: 0.0,
        alternate_headroom: peak.max(0.01),
        gain_min,
        gain_max,
        gamma: [1.0; 3],
        base_offset: [OFFSET; 3],
        alternate_offset: [OFFSET; 3],
        multichannel: map_channels == 3,
        use_base_colour_space: true,
    };
    let mut map_jpeg = gain_map_image(&map_codes, mw, mh, map_channels, options.map_quality, &meta)?;
    // The base is corrected for the map as decoders will see it, JPEG losses included.
    // (Our own JPEG, no larger than the image: trusted.) Against the codes before JPEG, on the
    // corpus photographs at q95, PU21-PSNR 0.0 to 2.4 dB higher (Desk 40.0 to 42.4), mean ΔE
    // ITP 0.0 to 1.0 lower, for 0 to 2 % more bytes.
    let decoded_map = crate::gainmap::decode_jpeg(&map_jpeg, &hdrcodec_core::Limits::none(), "gain map")?;
    let (base, clipped) = corrected_base(&hdr, &decoded_map.samples, (w, h), (mw, mh), &meta, weights);
    if clipped > 0 {
        report.note(format!(
            "{clipped} pixels were outside what the base and gain map can hold at the gain the map gives there (desaturated, luminance kept where it fits)"
        ));
    }
    // EXIF that came with the image (a gain-map JPEG decoded by us keeps it) goes back into the
    // base; a block that is not hexadecimal or too long for one segment is left out, and said.
    let exif_block = image.metadata_value(exif::METADATA_KEY).and_then(|hex| {
        let block = exif::from_hex(hex).filter(|b| b.len() <= exif::MAX_BLOCK);
        if block.is_none() {
            report.note("the image's EXIF metadata was not written (not hexadecimal, or over 64 KB)");
        }
        block
    });
    // The base is JPEG-coded once; its headers follow the map's length (`attach_map`).
    let primary = primary_image(&base, w, h, options, profile.as_deref(), exif_block.as_deref(), map_jpeg.len())?;
    let mut file = attach_map(&primary, &map_jpeg)?;
    if options.fit_black_level {
        // The base as decoders will decode it.
        let decoded_base = crate::gainmap::decode_jpeg(&primary, &hdrcodec_core::Limits::none(), "base image")?;
        let shift = fit_black_level(
            &hdr,
            &decoded_base.samples,
            &decoded_map.samples,
            (w, h),
            (mw, mh),
            &meta,
            &base_primaries,
        );
        if shift != [0.0; 3] {
            // Only the metadata changes: the map's codes, hence its JPEG's samples, and the
            // base stay as measured.
            meta.alternate_offset = std::array::from_fn(|c| OFFSET + shift[c]);
            map_jpeg = gain_map_image(&map_codes, mw, mh, map_channels, options.map_quality, &meta)?;
            file = attach_map(&primary, &map_jpeg)?;
        }
    }
    Ok((file, report))
}

/// Above this mean raise of a half-size map ([`mean_lift`]), `map_scale=auto` makes the map
/// full size when the base is 4:4:4.
///
/// The raise keeps a light under the base's white by darkening every base pixel that shares a
/// map pixel with it; where lights are many and textured (Desk's lamp, up to 99 SDR whites),
/// the base loses brightness and gains local contrast: its TMQI was 0.894 against libultrahdr's
/// 0.942, which codes a full-size map. A full-size map needs no such raise (0.948) but costs
/// about a quarter more bytes; with a 4:2:0 base it also loses on colour at equal size (Desk at
/// q85: ΔE ITP 8.84 against 8.34 at half size, behind libultrahdr's 7.87 at that size), as the
/// base's half-resolution chroma cannot carry the inverse of a full-size map's per-pixel colour
/// errors; with a 4:4:4 base it does not (6.96 against 6.73 for 26 % more bytes, ahead of
/// libultrahdr's 7.21). Mean lifts on the corpus photographs at base quality 90: Desk 0.278,
/// mpi_atrium_3 0.102, GoldenGate 0.007, StillLife 0.008, MtTamWest 0.001: a threshold from
/// five photographs, two of them above 0.1, and where between 0.10 and 0.28 it belongs is not
/// known.
const FULL_SIZE_MEAN_LIFT: f64 = 0.2;

/// How far above a base pixel's need a full-size map is raised (log2 stops): with one map pixel
/// per base pixel nothing else lifts a light's gain above its need, so the map's JPEG, lowering
/// some of those gains, would clip the base there. On Desk at base quality 90 (full-size map):
/// PU21-PSNR 37.6 dB without, 38.5, 39.1, 39.7, 39.9, 39.9 with 0.05, 0.1, 0.2, 0.3, 0.5; the
/// base's TMQI 0.950, 0.949, 0.949, 0.948, 0.948, 0.942 (the base's highlights end lower).
const FULL_SIZE_RAISE_MARGIN: f64 = 0.25;

/// How far [`raise_to_fit`] lifted the map, in log2 stops: the mean over the map's pixels of the
/// largest channel's rise from `averaged` to `raised`.
fn mean_lift(averaged: &[f64], raised: &[f64], map_channels: usize) -> f64 {
    let pixels = averaged.chunks_exact(map_channels).zip(raised.chunks_exact(map_channels));
    let total: f64 = pixels.map(|(a, r)| a.iter().zip(r).map(|(a, r)| r - a).fold(0.0, f64::max)).sum();
    total / (averaged.len() / map_channels).max(1) as f64
}

/// The map's log2 gains before any raise, at `scale` (map pixel m sits on base pixel m · w / mw,
/// the decoders' sampling, see `gainmap::axis`, and averages the log2 gain over a box one map
/// pixel wide centred there, each base pixel weighted by its overlap with the box), and the
/// map's size.
fn averaged_gains(
    tone_mapped: &[f64],
    hdr: &[f64],
    (w, h): (usize, usize),
    scale: usize,
    map_channels: usize,
    weights: [f64; 3],
) -> (Vec<f64>, (usize, usize)) {
    let (mw, mh) = (w.div_ceil(scale), h.div_ceil(scale));
    let (xs, ys) = (box_weights(w, mw), box_weights(h, mh));
    let mut gains = vec![0.0f64; mw * mh * map_channels];
    let mut weight_sums = vec![0.0f64; mw * mh];
    for (y, y_weights) in ys.iter().enumerate() {
        for (x, x_weights) in xs.iter().enumerate() {
            let i = y * w + x;
            let sdr = &tone_mapped[3 * i..3 * i + 3];
            let hdr = &hdr[3 * i..3 * i + 3];
            let gain: [f64; 3] = if map_channels == 1 {
                let y_sdr = weights[0] * sdr[0] + weights[1] * sdr[1] + weights[2] * sdr[2];
                let y_hdr = (weights[0] * hdr[0] + weights[1] * hdr[1] + weights[2] * hdr[2]).max(0.0);
                [((y_hdr + OFFSET) / (y_sdr + OFFSET)).log2(), 0.0, 0.0]
            } else {
                std::array::from_fn(|c| ((hdr[c].max(0.0) + OFFSET) / (sdr[c] + OFFSET)).log2())
            };
            for &(my, wy) in y_weights {
                for &(mx, wx) in x_weights {
                    let m = my * mw + mx;
                    weight_sums[m] += wy * wx;
                    for c in 0..map_channels {
                        gains[m * map_channels + c] += wy * wx * gain[c];
                    }
                }
            }
        }
    }
    for (m, &total) in weight_sums.iter().enumerate() {
        for g in &mut gains[m * map_channels..(m + 1) * map_channels] {
            *g /= total;
        }
    }
    (gains, (mw, mh))
}

/// Raises the map's log2 gains where the averaged gain would leave a base pixel above 1.0
/// (pre-correction would then clip it; next to a bright light, most of the light's pixels). A
/// decoded gain is a bilinear mix of the map pixels around it (`gainmap::axis`), so raising
/// every map pixel that enters a base pixel's mix to at least the gain that pixel needs,
/// log2((hdr + k) / (1 + k)) (of the brightest channel when one gain serves three), makes the
/// mix at least that need too. The base is then darker near such lights; the HDR rendition
/// keeps them.
///
/// [`MapRaise::Neighbourhood`] raises the 2×2 map neighbourhood of every base pixel,
/// including a neighbour whose weight in the mix is zero (every base pixel that sits on a map
/// column or row); the base is darkened up to two map pixels from a light.
/// [`MapRaise::Contributing`] (the default) raises only map pixels of weight above zero: the
/// same guarantee, within one map pixel. [`MapRaise::Deficit`] (`raise_by_deficit`) raises those by what the
/// mix lacks. On Desk, whose lamp-lit highlights the wider raises darken, the base's TMQI is
/// 0.876, 0.894 and 0.916 (crate README, "Where the base and the darks lose"). The first two
/// raise to the need plus `margin` stops (with a full-size map, [`FULL_SIZE_RAISE_MARGIN`]).
fn raise_to_fit(
    gains: &mut [f64],
    hdr: &[f64],
    (w, h): (usize, usize),
    (mw, mh): (usize, usize),
    map_channels: usize,
    raise: MapRaise,
    margin: f64,
) {
    if raise == MapRaise::Deficit {
        return raise_by_deficit(gains, hdr, (w, h), (mw, mh), map_channels);
    }
    let contributing_only = raise == MapRaise::Contributing;
    let (xs, ys) = (crate::gainmap::axis(w, mw), crate::gainmap::axis(h, mh));
    for (y, &(y0, y1, fy)) in ys.iter().enumerate() {
        // The map rows (and below, columns) whose weight in this pixel's mix is above zero, or
        // the lower neighbour and the next one.
        let rows = if contributing_only {
            [Some(y0), (fy > 0.0).then_some(y1)]
        } else {
            [Some(y0), (y0 + 1 < mh).then_some(y0 + 1)]
        };
        for (x, &(x0, x1, fx)) in xs.iter().enumerate() {
            let needs = fit_needs(&hdr[3 * (y * w + x)..3 * (y * w + x) + 3], map_channels).map(|n| n + margin);
            let columns = if contributing_only {
                [Some(x0), (fx > 0.0).then_some(x1)]
            } else {
                [Some(x0), (x0 + 1 < mw).then_some(x0 + 1)]
            };
            for j in rows.into_iter().flatten() {
                for i in columns.into_iter().flatten() {
                    let at = (j * mw + i) * map_channels;
                    for (g, &n) in gains[at..at + map_channels].iter_mut().zip(&needs) {
                        *g = g.max(n);
                    }
                }
            }
        }
    }
}

/// The log2 gain a base pixel of HDR value `px` needs to fit under 1.0 with the offsets,
/// per channel, or of its brightest channel (in all three) when one gain serves three.
fn fit_needs(px: &[f64], map_channels: usize) -> [f64; 3] {
    let need = |v: f64| ((v.max(0.0) + OFFSET) / (1.0 + OFFSET)).log2();
    if map_channels == 1 {
        [need(px[0].max(px[1]).max(px[2])); 3]
    } else {
        std::array::from_fn(|c| need(px[c]))
    }
}

/// How far above a base pixel's need [`MapRaise::Deficit`] lifts its mix (log2 stops): room
/// for the map's quantisation and JPEG, which lower some gains raised exactly to the need (the
/// base then clips there). Measured with an earlier form of the raise (all pixels' requests at
/// once, each map pixel rising by the largest): margins of 0.03, 0.1 and 0.25 gave Desk's base
/// TMQI 0.916–0.918 alike; with 0, StillLife's ΔE ITP at q95 was 10.8 against 10.0 with 0.05
/// and 0.1, and Desk's PU21-PSNR at q95 0.1 dB lower.
const RAISE_MARGIN: f64 = 0.1;

/// [`MapRaise::Deficit`]: each base pixel whose bilinear mix of the map's log2 gains is below
/// its need plus [`RAISE_MARGIN`] raises every map pixel of weight above zero in its mix by the
/// difference (the weights sum to 1, so the mix rises by that much). Pixels are taken brightest
/// need first, each against the gains as raised so far: raises only lift mixes, so every pixel
/// ends at least at its need, and a pixel beside a brighter light, whose map pixel has already
/// risen, asks for less than its full need, or nothing.
fn raise_by_deficit(
    gains: &mut [f64],
    hdr: &[f64],
    (w, h): (usize, usize),
    (mw, mh): (usize, usize),
    map_channels: usize,
) {
    let (xs, ys) = (crate::gainmap::axis(w, mw), crate::gainmap::axis(h, mh));
    let taps = |x: usize, y: usize| {
        let ((x0, x1, fx), (y0, y1, fy)) = (xs[x], ys[y]);
        let (fx, fy) = (f64::from(fx), f64::from(fy));
        [(x0, y0, (1.0 - fx) * (1.0 - fy)), (x1, y0, fx * (1.0 - fy)), (x0, y1, (1.0 - fx) * fy), (x1, y1, fx * fy)]
    };
    let lack = |gains: &[f64], x: usize, y: usize, c: usize, need: f64| {
        let mix: f64 = taps(x, y).iter().map(|&(i, j, wt)| wt * gains[(j * mw + i) * map_channels + c]).sum();
        need + RAISE_MARGIN - mix
    };
    for c in 0..map_channels {
        // The pixels short of their need before any raise; no other can fall short later.
        let mut short: Vec<(f64, usize)> = (0..w * h)
            .filter_map(|i| {
                let need = fit_needs(&hdr[3 * i..3 * i + 3], map_channels)[c];
                (lack(gains, i % w, i / w, c, need) > 0.0).then_some((need, i))
            })
            .collect();
        short.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for (need, i) in short {
            let (x, y) = (i % w, i / w);
            let lacking = lack(gains, x, y, c, need);
            if lacking > 0.0 {
                let mut raised: [Option<(usize, usize)>; 4] = [None; 4];
                for (n, &(i, j, _)) in taps(x, y).iter().enumerate().filter(|(_, t)| t.2 > 0.0) {
                    // A map pixel that appears twice (at the map's last column or row) rises once.
                    if !raised.contains(&Some((i, j))) {
                        raised[n] = Some((i, j));
                        gains[(j * mw + i) * map_channels + c] += lacking;
                    }
                }
            }
        }
    }
}

/// The range `[min, max]` of 8-bit map codes widened (by about a code at most) so that gain 0
/// falls exactly on a code, when it lies inside the range: pixels whose base is the HDR image
/// (the darks, under the tone curve's linear toe) then decode to gain 0 exactly, wherever the
/// range's ends happen to be, instead of to the nearest code's gain (up to half a code, each
/// channel its own).
fn zero_on_a_code(min: f64, max: f64) -> (f64, f64) {
    if !(min < 0.0 && max > 0.0) {
        return (min, max);
    }
    let at = 255.0 * -min / (max - min);
    if at.fract() == 0.0 {
        return (min, max);
    }
    // Either the next code up from 0 becomes it (min lowered) or the one below (max raised);
    // the narrower range wins.
    let up = at.ceil();
    let lowered = (up < 255.0).then(|| (-up * max / (255.0 - up), max));
    let down = at.floor();
    let raised = (down > 0.0).then(|| (min, min * (1.0 - 255.0 / down)));
    match (lowered, raised) {
        (Some(a), Some(b)) => {
            if a.1 - a.0 <= b.1 - b.0 {
                a
            } else {
                b
            }
        }
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => (min, max),
    }
}

/// For each of `len` base pixels along an axis, the map pixels (of `map_len`) whose box it
/// overlaps and by how much: map pixel m's box is one map pixel wide, centred on base
/// coordinate m · len / map_len.
fn box_weights(len: usize, map_len: usize) -> Vec<Vec<(usize, f64)>> {
    let spacing = len as f64 / map_len as f64;
    (0..len)
        .map(|x| {
            let (lo, hi) = (x as f64 - 0.5, x as f64 + 0.5);
            // The boxes that can overlap [lo, hi]: centres within half a box of it.
            let first = ((lo - spacing / 2.0) / spacing).ceil().max(0.0) as usize;
            let last = (((hi + spacing / 2.0) / spacing).floor() as usize).min(map_len - 1);
            (first..=last)
                .filter_map(|m| {
                    let c = m as f64 * spacing;
                    let overlap = hi.min(c + spacing / 2.0) - lo.max(c - spacing / 2.0);
                    (overlap > 1e-9).then_some((m, overlap))
                })
                .collect()
        })
        .collect()
}

/// The base's 8-bit sRGB codes, pre-corrected (as JPEG-HDR's `cor=1`): each pixel is the HDR
/// value divided by the gain decoders will apply there (`codes`: the map as decoders decode
/// it, JPEG losses included, upsampled as `gainmap::axis` does), so that the base carries the
/// detail a coarse map cannot and what the map's JPEG lost, and the reconstruction's only
/// errors are the base's own quantisation and what leaves [0, 1] (the second value: how many
/// samples were clamped).
fn corrected_base(
    hdr: &[f64],
    codes: &[u8],
    (w, h): (usize, usize),
    (mw, mh): (usize, usize),
    meta: &GainMapMetadata,
    weights: [f64; 3],
) -> (Vec<u8>, usize) {
    let (xs, ys) = (crate::gainmap::axis(w, mw), crate::gainmap::axis(h, mh));
    let mut base = Vec::with_capacity(w * h * 3);
    let mut clipped = 0;
    for &(y0, y1, fy) in &ys {
        for &(x0, x1, fx) in &xs {
            let i = base.len();
            let v: [f64; 3] = std::array::from_fn(|c| {
                let gain = decoded_gain(codes, mw, (x0, x1, fx), (y0, y1, fy), c, meta);
                (hdr[i + c] + meta.alternate_offset[c]) / gain - meta.base_offset[c]
            });
            // A code's worth of slack before calling it clipped; colours the base cannot hold
            // lose saturation, not luminance.
            if v.iter().any(|v| !(-1e-3..=1.0 + 1e-3).contains(v)) {
                clipped += 1;
            }
            // Below zero (a dark channel whose gain came out a little high), each channel is
            // clamped alone: pulling the colour towards grey instead would move its other
            // channels too (on StillLife's dark reds, mean ΔE ITP 13.9 against 12.9 at q95).
            let v = v.map(|x| x.max(0.0));
            let y = weights[0] * v[0] + weights[1] * v[1] + weights[2] * v[2];
            base.extend(into_unit_cube(v, y).map(|v| (SrgbTransfer::encode(v) * 255.0).round() as u8));
        }
    }
    (base, clipped)
}

/// The gain decoders apply to channel `c` of the base pixel whose map neighbours and weights
/// on each axis are `(x0, x1, fx)` and `(y0, y1, fy)` (`gainmap::axis`), from the map's decoded
/// `codes` (`mw` map pixels a row, one or three channels): the codes interpolated bilinearly,
/// then mapped through the channel's range (gamma 1).
fn decoded_gain(
    codes: &[u8],
    mw: usize,
    (x0, x1, fx): (usize, usize, f32),
    (y0, y1, fy): (usize, usize, f32),
    c: usize,
    meta: &GainMapMetadata,
) -> f64 {
    let map_channels = if meta.multichannel { 3 } else { 1 };
    let code = |x: usize, y: usize| f64::from(codes[(y * mw + x) * map_channels + c.min(map_channels - 1)]);
    let (fx, fy) = (f64::from(fx), f64::from(fy));
    let top = code(x0, y0) * (1.0 - fx) + code(x1, y0) * fx;
    let bottom = code(x0, y1) * (1.0 - fx) + code(x1, y1) * fx;
    let g = (top * (1.0 - fy) + bottom * fy) / 255.0;
    (meta.gain_min[c] + (meta.gain_max[c] - meta.gain_min[c]) * g).exp2()
}

/// Pixels the black-level fit looks at: those whose source and decoded channels are all under
/// this (SDR-white units; 2 cd/m²). Above it, a shift of a base code at black (0.06 cd/m²)
/// changes ΔE ITP by little.
const BLACK_FIT_BELOW: f64 = 2.0 / SDR_WHITE_NITS as f64;

/// At most this many pixels, evenly spread, enter the black-level fit.
const BLACK_FIT_SAMPLES: usize = 1 << 14;

/// The shift per channel (SDR-white units, subtracted from every decoded sample, i.e. added to
/// the alternate offsets) with which the HDR rendition decoded from `base` (the base's 8-bit
/// RGB as decoders decode its JPEG) and the map's decoded `codes` comes closest to `hdr` in
/// mean ΔE ITP over the dark pixels (BT.2124, both in cd/m², 1.0 = SDR white; `primaries` the
/// base's). A base code near black is about as large as the darks' signal (sRGB code 1 is 0.06
/// cd/m²): which pixels round to code 0, and the base's JPEG on blocks of codes 0 to 3, bias
/// the darks by a fraction of a code per channel, which no gain near 0 can undo but an offset
/// can. Coordinate descent per channel over ±1 code at black in quarter codes, then quarters of
/// that twice: 81 evaluations on at most [`BLACK_FIT_SAMPLES`] pixels.
fn fit_black_level(
    hdr: &[f64],
    base: &[u8],
    codes: &[u8],
    (w, h): (usize, usize),
    (mw, mh): (usize, usize),
    meta: &GainMapMetadata,
    primaries: &ColorPrimaries,
) -> [f64; 3] {
    use hdrcodec_core::color::{delta_e_itp_ictcp, mat_apply, rgb2020_to_ictcp, rgb_to_rgb};
    let to_nits = rgb_to_rgb(primaries, &ColorPrimaries::Bt2020).map(|row| row.map(|v| v * f64::from(SDR_WHITE_NITS)));
    let ictcp = |rgb: [f64; 3]| rgb2020_to_ictcp(mat_apply(&to_nits, rgb));
    let (xs, ys) = (crate::gainmap::axis(w, mw), crate::gainmap::axis(h, mh));
    let stride = (w * h).div_ceil(BLACK_FIT_SAMPLES).max(1);
    // (the source's ICtCp, the decoded sample) of each dark pixel looked at.
    let mut samples: Vec<([f64; 3], [f64; 3])> = Vec::new();
    for i in (0..w * h).step_by(stride) {
        let (x, y) = (i % w, i / w);
        let source: [f64; 3] = std::array::from_fn(|c| hdr[3 * i + c]);
        let decoded: [f64; 3] = std::array::from_fn(|c| {
            let gain = decoded_gain(codes, mw, xs[x], ys[y], c, meta);
            let b = SrgbTransfer::decode(f64::from(base[3 * i + c]) / 255.0);
            (b + meta.base_offset[c]) * gain - meta.alternate_offset[c]
        });
        if source.iter().chain(&decoded).all(|&v| v < BLACK_FIT_BELOW) {
            samples.push((ictcp(source), decoded));
        }
    }
    let mut shift = [0.0; 3];
    if samples.is_empty() {
        return shift;
    }
    let cost = |shift: &[f64; 3]| -> f64 {
        samples
            .iter()
            .map(|(reference, decoded)| {
                delta_e_itp_ictcp(*reference, ictcp(std::array::from_fn(|c| decoded[c] - shift[c])))
            })
            .sum()
    };
    // One base code at black, in linear units: sRGB's linear segment, 1/255 of full scale / 12.92.
    let mut step = 1.0 / (255.0 * 12.92) / 4.0;
    let mut best = cost(&shift);
    for _ in 0..3 {
        for c in 0..3 {
            let centre = shift[c];
            for k in -4..=4 {
                if k == 0 {
                    continue;
                }
                let mut trial = shift;
                trial[c] = centre + f64::from(k) * step;
                let e = cost(&trial);
                if e < best {
                    (best, shift) = (e, trial);
                }
            }
        }
        step /= 4.0;
    }
    shift
}

/// `rgb` pulled towards the grey of luminance `y` (kept; clamped to [0, 1]) until every
/// channel is in [0, 1]: how the base holds colours too saturated or too bright for sRGB.
fn into_unit_cube(rgb: [f64; 3], y: f64) -> [f64; 3] {
    let y = y.clamp(0.0, 1.0);
    let (hi, lo) = (rgb.iter().copied().fold(f64::MIN, f64::max), rgb.iter().copied().fold(f64::MAX, f64::min));
    let mut s: f64 = 1.0;
    if hi > 1.0 {
        s = s.min((1.0 - y) / (hi - y));
    }
    if lo < 0.0 {
        s = s.min(y / (y - lo));
    }
    if s < 1.0 {
        rgb.map(|v| (y + (v - y) * s.max(0.0)).clamp(0.0, 1.0))
    } else {
        rgb
    }
}

/// The tone-mapped base (linear, in [0, 1]) and the HDR samples, both RGB in SDR-white units,
/// and how many pixels were outside BT.709 (desaturated into it).
fn tone_map(
    samples: &[f32],
    channels: usize,
    scale: f64,
    weights: [f64; 3],
    tone: &ToneOperator,
    keep_bright_colours: bool,
) -> (Vec<f64>, Vec<f64>, usize) {
    let pixels = samples.len() / channels;
    let mut base = Vec::with_capacity(pixels * 3);
    let mut hdr = Vec::with_capacity(pixels * 3);
    let mut out_of_gamut = 0;
    for px in samples.chunks_exact(channels) {
        let rgb = [0, 1, 2].map(|c| if px[c].is_finite() { f64::from(px[c]) * scale } else { 0.0 });
        let y = (weights[0] * rgb[0] + weights[1] * rgb[1] + weights[2] * rgb[2]).max(0.0);
        // A gain cannot make a sample negative: colours outside BT.709 are pulled towards grey
        // (luminance kept) until they are inside.
        let lo = rgb.iter().copied().fold(f64::MAX, f64::min);
        let rgb = if lo < 0.0 {
            out_of_gamut += 1;
            let s = if y > 0.0 { y / (y - lo) } else { 0.0 };
            rgb.map(|v| (y + (v - y) * s).max(0.0))
        } else {
            rgb
        };
        hdr.extend(rgb);
        let t = tone.map(y).min(1.0);
        let sdr = if y <= 1e-12 {
            [t; 3]
        } else if keep_bright_colours {
            // Where the colour at luminance t leaves the cube, darken it until it fits.
            let hi = rgb.iter().copied().fold(0.0, f64::max);
            rgb.map(|v| v * (t / y).min(1.0 / hi))
        } else {
            into_unit_cube(rgb.map(|v| v * t / y), t)
        };
        base.extend(sdr.map(|v| v.clamp(0.0, 1.0)));
    }
    (base, hdr, out_of_gamut)
}

/// `image` in primaries a JPEG base can carry (`allowed`, BT.709 first): other primaries are
/// converted to BT.709 (linearly, before tone mapping), unspecified ones taken as BT.709; the
/// report says so, and that the alpha channel (if any) is dropped.
pub(crate) fn base_image<'a>(
    image: &'a HdrImage,
    allowed: &[ColorPrimaries],
    report: &mut EncodeReport,
) -> (Cow<'a, HdrImage>, ColorPrimaries) {
    if image.channels().count() == 4 {
        report.note("JPEG has no alpha: the alpha channel was dropped");
    }
    match image.color.primaries {
        ref p if allowed.contains(p) => (Cow::Borrowed(image), *p),
        ColorPrimaries::Unspecified => {
            report.note("the image records no primaries: its samples are written as BT.709 (sRGB)");
            (Cow::Borrowed(image), ColorPrimaries::Bt709)
        }
        ref p => {
            report.note(format!("converted from {} to BT.709 primaries (the base is sRGB)", p.name()));
            (Cow::Owned(convert_primaries(image, ColorPrimaries::Bt709)), ColorPrimaries::Bt709)
        }
    }
}

pub(crate) fn jpeg_error(what: &str, e: jpeg_encoder::EncodingError) -> Error {
    Error::invalid(format!("{what}: JPEG encoder: {e}"))
}

/// The gain-map image: a JPEG with its hdrgm XMP and full ISO 21496-1 record.
fn gain_map_image(
    codes: &[u8],
    w: usize,
    h: usize,
    channels: usize,
    quality: u8,
    meta: &GainMapMetadata,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, quality);
    if channels == 3 {
        encoder.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_4_4);
    }
    let app = |e: &mut jpeg_encoder::Encoder<&mut Vec<u8>>, n: u8, sig: &[u8], body: &[u8]| {
        e.add_app_segment(n, &[sig, body].concat()).map_err(|e| jpeg_error("gain map", e))
    };
    app(&mut encoder, 1, xmp::SIGNATURE, hdrgm_xmp(meta).as_bytes())?;
    app(&mut encoder, 2, ISO_SIGNATURE, &meta.to_iso())?;
    let color = if channels == 1 { jpeg_encoder::ColorType::Luma } else { jpeg_encoder::ColorType::Rgb };
    encoder.encode(codes, w as u16, h as u16, color).map_err(|e| jpeg_error("gain map", e))?;
    Ok(out)
}

/// The primary image, JPEG-coded: XMP (hdrgm version and GContainer announcing a gain map of
/// `map_len` bytes), the ISO version record and an MPF index whose offsets are left 0 for
/// [`attach_map`].
fn primary_image(
    base: &[u8],
    w: usize,
    h: usize,
    options: &GainMapEncodeOptions,
    profile: Option<&[u8]>,
    exif_block: Option<&[u8]>,
    map_len: usize,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut encoder = jpeg_encoder::Encoder::new(&mut out, options.base_quality);
    encoder.set_sampling_factor(if options.base_full_chroma {
        jpeg_encoder::SamplingFactor::R_4_4_4
    } else {
        jpeg_encoder::SamplingFactor::R_4_2_0
    });
    if let Some(profile) = profile {
        encoder.add_icc_profile(profile).map_err(|e| jpeg_error("base image", e))?;
    }
    let app = |e: &mut jpeg_encoder::Encoder<&mut Vec<u8>>, n: u8, sig: &[u8], body: &[u8]| {
        e.add_app_segment(n, &[sig, body].concat()).map_err(|e| jpeg_error("base image", e))
    };
    if let Some(block) = exif_block {
        app(&mut encoder, 1, exif::SIGNATURE, block)?;
    }
    app(&mut encoder, 1, xmp::SIGNATURE, container_xmp(map_len).as_bytes())?;
    app(&mut encoder, 2, ISO_SIGNATURE, &GainMapMetadata::iso_version_record())?;
    // A placeholder of the final size; `attach_map` patches the offsets.
    encoder.add_app_segment(2, &mpf::write(0, 0, 0)).map_err(|e| jpeg_error("base image", e))?;
    encoder.encode(base, w as u16, h as u16, jpeg_encoder::ColorType::Rgb).map_err(|e| jpeg_error("base image", e))?;
    Ok(out)
}

/// The file: `primary` (from [`primary_image`]) with its GContainer XMP rewritten for `map`'s
/// length, its MPF offsets patched, and `map` appended. The base's scan is reused, not coded
/// again: the bytes are those of a primary image coded for this map's length.
fn attach_map(primary: &[u8], map: &[u8]) -> Result<Vec<u8>> {
    let xmp_segment = markers::parse_image(primary, 0)?
        .segments
        .into_iter()
        .find(|s| s.marker == APP1 && s.payload.starts_with(xmp::SIGNATURE))
        .map(|s| (s.offset, s.payload_offset() + s.payload.len()))
        .ok_or_else(|| Error::invalid("base image: the JPEG encoder dropped the XMP segment"))?;
    let body = [xmp::SIGNATURE, container_xmp(map.len()).as_bytes()].concat();
    let length = u16::try_from(body.len() + 2).map_err(|_| Error::invalid("base image: XMP over 64 KB"))?;
    let mut out = Vec::with_capacity(primary.len() + map.len() + 8);
    out.extend_from_slice(&primary[..xmp_segment.0]);
    out.extend_from_slice(&[0xFF, APP1]);
    out.extend_from_slice(&length.to_be_bytes());
    out.extend_from_slice(&body);
    out.extend_from_slice(&primary[xmp_segment.1..]);
    let (mpf_at, _) = markers::parse_image(&out, 0)?
        .app_payload(APP2, mpf::SIGNATURE)
        .ok_or_else(|| Error::invalid("base image: the JPEG encoder dropped the MPF segment"))?;
    let too_big = || Error::limit("a gain-map JPEG over 4 GiB");
    let primary_len = u32::try_from(out.len()).map_err(|_| too_big())?;
    let map_len = u32::try_from(map.len()).map_err(|_| too_big())?;
    // The MPF offsets count from the byte-order field, right after the signature.
    let second_offset = primary_len - u32::try_from(mpf_at).map_err(|_| too_big())?;
    let patched = mpf::write(primary_len, map_len, second_offset);
    out[mpf_at - mpf::SIGNATURE.len()..mpf_at - mpf::SIGNATURE.len() + patched.len()].copy_from_slice(&patched);
    out.extend_from_slice(map);
    Ok(out)
}

/// The primary's XMP: hdrgm:Version and the GContainer directory (Ultra HDR 1.0).
fn container_xmp(map_len: usize) -> String {
    format!(
        concat!(
            r#"<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">"#,
            r#"<rdf:Description xmlns:Container="http://ns.google.com/photos/1.0/container/" "#,
            r#"xmlns:Item="http://ns.google.com/photos/1.0/container/item/" xmlns:hdrgm="{hdrgm}" hdrgm:Version="1.0">"#,
            r#"<Container:Directory><rdf:Seq>"#,
            r#"<rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="Primary" Item:Mime="image/jpeg"/></rdf:li>"#,
            r#"<rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="GainMap" Item:Mime="image/jpeg" Item:Length="{len}"/></rdf:li>"#,
            r#"</rdf:Seq></Container:Directory></rdf:Description></rdf:RDF></x:xmpmeta>"#
        ),
        hdrgm = xmp::HDRGM,
        len = map_len
    )
}

/// The gain map's XMP: the nine hdrgm properties, as attributes when the channels share their
/// values (what libultrahdr 1.4 reads), else per channel as `rdf:Seq` (Adobe's form).
fn hdrgm_xmp(m: &GainMapMetadata) -> String {
    let (mut attributes, mut elements) = (String::new(), String::new());
    for (name, v) in [
        ("GainMapMin", m.gain_min),
        ("GainMapMax", m.gain_max),
        ("Gamma", m.gamma),
        ("OffsetSDR", m.base_offset),
        ("OffsetHDR", m.alternate_offset),
    ] {
        if v[0] == v[1] && v[1] == v[2] {
            attributes += &format!(r#" hdrgm:{name}="{}""#, v[0]);
        } else {
            elements += &format!("<hdrgm:{name}><rdf:Seq><rdf:li>{}</rdf:li><rdf:li>{}</rdf:li><rdf:li>{}</rdf:li></rdf:Seq></hdrgm:{name}>", v[0], v[1], v[2]);
        }
    }
    format!(
        concat!(
            r#"<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">"#,
            r#"<rdf:Description xmlns:hdrgm="{hdrgm}" hdrgm:Version="1.0" hdrgm:BaseRenditionIsHDR="False" "#,
            r#"hdrgm:HDRCapacityMin="{cmin}" hdrgm:HDRCapacityMax="{cmax}"{attributes}>{elements}</rdf:Description></rdf:RDF></x:xmpmeta>"#
        ),
        hdrgm = xmp::HDRGM,
        cmin = m.base_headroom,
        cmax = m.alternate_headroom,
        attributes = attributes,
        elements = elements
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gainmap::{decode, GainMapFile, Rendering};
    use hdrcodec_core::{Channels, ColorInfo, Limits};

    /// A 96x64 ramp over four decades with a saturated red highlight.
    fn scene() -> HdrImage {
        let (w, h) = (96u32, 64u32);
        let mut s = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let l = 10f32.powf(-1.5 + 4.0 * x as f32 / w as f32);
                let red = if (30..40).contains(&y) && (60..80).contains(&x) { 3.0 } else { 1.0 };
                s.extend([l * red, l * (0.6 + 0.4 * y as f32 / h as f32), l * 0.8]);
            }
        }
        HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() }).unwrap()
    }

    #[test]
    fn exif_travels_through_encode_and_decode() {
        use hdrcodec_core::bytes::{ByteOrder, ByteWriter};
        use hdrcodec_core::tiff::{tag, write_header, IfdWriter, MAGIC_TIFF};
        let mut w = ByteWriter::new(ByteOrder::Little);
        let link = write_header(&mut w, MAGIC_TIFF);
        let mut ifd = IfdWriter::new();
        ifd.ascii(tag::MAKE, "hdrcodec");
        ifd.short(tag::ORIENTATION, 6);
        ifd.write(&mut w, link).unwrap();
        let block = w.into_vec();
        let mut image = scene();
        image.metadata.push((exif::METADATA_KEY.into(), exif::to_hex(&block)));
        let (file, report) = encode(&image, &GainMapEncodeOptions::default()).unwrap();
        assert!(report.notes.iter().all(|n| !n.contains("EXIF")), "{:?}", report.notes);
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        assert_eq!(back.metadata_value(exif::METADATA_KEY), Some(exif::to_hex(&block).as_str()));
        assert!(back.metadata_value("jpeg.orientation_note").unwrap().contains("orientation 6"));
        // Not hexadecimal: left out, and said.
        image.metadata.retain(|(k, _)| k != exif::METADATA_KEY);
        image.metadata.push((exif::METADATA_KEY.into(), "not hex".into()));
        let (file, report) = encode(&image, &GainMapEncodeOptions::default()).unwrap();
        assert!(report.notes.iter().any(|n| n.contains("EXIF")), "{:?}", report.notes);
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        assert_eq!(back.metadata_value(exif::METADATA_KEY), None);
    }

    #[test]
    fn encoded_files_decode_back_to_the_hdr_image() {
        let image = scene();
        for channels in [1u8, 3] {
            let options = GainMapEncodeOptions { map_channels: channels, map_scale: Some(2), ..Default::default() };
            let (file, _) = encode(&image, &options).unwrap();
            let parsed = GainMapFile::parse(&file).unwrap();
            assert!(parsed.gain_map.is_some(), "{:?}", parsed.warning);
            let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            assert_eq!((back.width(), back.height(), back.color.nits_per_unit), (96, 64, SDR_WHITE_NITS));
            // Luminance within a few percent (JPEG quantisation of base and map), in nits.
            let mut errors: Vec<f64> = image
                .samples()
                .chunks_exact(3)
                .zip(back.samples().chunks_exact(3))
                .map(|(a, b)| {
                    let y =
                        |p: &[f32], n: f64| (0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64) * n;
                    (y(a, 100.0).max(0.1).log2() - y(b, 203.0).max(0.1).log2()).abs()
                })
                .collect();
            errors.sort_by(f64::total_cmp);
            let (median, p99) = (errors[errors.len() / 2], errors[errors.len() * 99 / 100]);
            assert!(median < 0.03 && p99 < 0.2, "channels {channels}: {median} {p99}");
        }
    }

    #[test]
    fn the_base_makes_up_for_what_the_maps_jpeg_loses() {
        // A coarse map (quality 20) under a fine base: the base is corrected for the map as
        // decoded, so the HDR rendition keeps the base's accuracy.
        let image = scene();
        let options = GainMapEncodeOptions { base_quality: 95, map_quality: 20, ..Default::default() };
        let (file, _) = encode(&image, &options).unwrap();
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        let mut errors: Vec<f64> = image
            .samples()
            .iter()
            .zip(back.samples())
            .map(|(&a, &b)| ((f64::from(a) * 100.0).max(1.0).log2() - (f64::from(b) * 203.0).max(1.0).log2()).abs())
            .collect();
        errors.sort_by(f64::total_cmp);
        let (median, p99) = (errors[errors.len() / 2], errors[errors.len() * 99 / 100]);
        // Corrected for the map as coded instead: median 0.041, p99 0.41 stops.
        assert!(median < 0.025 && p99 < 0.3, "{median} {p99}");
    }

    #[test]
    fn attaching_a_map_gives_the_bytes_of_a_primary_coded_for_it() {
        // The base is coded once for a first map's length; attached to a map of another length
        // (here 999 and 1000 bytes: the XMP's length field grows by a digit), the file is byte
        // for byte what coding the primary for that length gives.
        let options = GainMapEncodeOptions::default();
        let base: Vec<u8> = (0..32 * 16 * 3).map(|i| (i * 7 % 251) as u8).collect();
        let exif = [b'M', b'M', 0, 42, 0, 0, 0, 8, 0, 0];
        for (first, second) in [(999, 1000), (1000, 999), (1000, 1000), (5, 123_456)] {
            let map = vec![0xA5u8; second];
            let coded_once = primary_image(&base, 32, 16, &options, None, Some(&exif), first).unwrap();
            let coded_for_it = primary_image(&base, 32, 16, &options, None, Some(&exif), second).unwrap();
            let file = attach_map(&coded_once, &map).unwrap();
            assert_eq!(file, attach_map(&coded_for_it, &map).unwrap(), "{first} then {second}");
            // The MPF index and the GContainer XMP both find the map.
            let parsed = markers::parse_image(&file, 0).unwrap();
            assert_eq!(parsed.end, file.len() - second);
            let (_, xmp_payload) = parsed.app_payload(APP1, xmp::SIGNATURE).unwrap();
            let text = std::str::from_utf8(xmp_payload).unwrap();
            assert!(text.contains(&format!("Item:Length=\"{second}\"")), "{text}");
            let (mpf_at, mpf_payload) = parsed.app_payload(APP2, mpf::SIGNATURE).unwrap();
            let entries = mpf::parse(mpf_payload, mpf_at, 0).unwrap();
            assert_eq!((entries[1].file_offset, entries[1].size as usize), (file.len() - second, second));
        }
    }

    #[test]
    fn display_p3_images_keep_their_primaries() {
        let mut image = scene();
        image.color.primaries = ColorPrimaries::DisplayP3;
        let (file, report) = encode(&image, &GainMapEncodeOptions::default()).unwrap();
        assert!(report.notes.iter().all(|n| !n.contains("converted")), "{:?}", report.notes);
        let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::DisplayP3);
        assert!(back.metadata_value("jpeg.colour_note").is_none());
    }

    #[test]
    fn options_are_checked() {
        let bad = |k: &str, v: &str| {
            GainMapEncodeOptions::from_settings(&EncodeSettings::default().with_option(k, v)).is_err()
        };
        assert!(bad("map_scale", "0") && bad("map_scale", "17") && bad("map_channels", "2") && bad("map_quality", "0"));
        assert!(bad("unknown", "1"));
        assert!(!bad("map_channels", "3") && !bad("map_scale", "auto") && !bad("map_scale", "1"));
        let scale = |v: &str| {
            GainMapEncodeOptions::from_settings(&EncodeSettings::default().with_option("map_scale", v))
                .unwrap()
                .map_scale
        };
        assert_eq!((scale("auto"), scale("3")), (None, Some(3)));
        assert!(bad("base_chroma", "422") && bad("bright_colours", "vivid") && bad("tone", "aces"));
        assert!(!bad("base_chroma", "420") && !bad("bright_colours", "keep") && !bad("tone", "reinhard"));
        assert!(bad("map_raise", "all") && bad("zero_gain", "0"));
        assert!(!bad("map_raise", "contributing") && !bad("map_raise", "deficit") && !bad("zero_gain", "on_code"));
    }

    /// The horizontal and vertical sampling factors of the first component of the file's first
    /// frame (the primary image's luma): 2x2 for 4:2:0, 1x1 for 4:4:4.
    fn luma_sampling(file: &[u8]) -> u8 {
        let image = markers::parse_image(file, 0).unwrap();
        let sof = image.segments.iter().find(|s| matches!(s.marker, 0xC0..=0xC2)).unwrap();
        // precision, height, width, component count, then id, sampling, table per component.
        sof.payload[7]
    }

    #[test]
    fn the_base_has_full_chroma_from_quality_90() {
        for (quality, chroma, sampling) in
            [(85, None, 0x22), (90, None, 0x11), (95, Some("420"), 0x22), (50, Some("444"), 0x11)]
        {
            let mut settings = EncodeSettings::default().with_quality(quality);
            if let Some(c) = chroma {
                settings = settings.with_option("base_chroma", c);
            }
            let options = GainMapEncodeOptions::from_settings(&settings).unwrap();
            let (file, _) = encode(&scene(), &options).unwrap();
            assert_eq!(luma_sampling(&file), sampling, "quality {quality} {chroma:?}");
        }
    }

    #[test]
    fn bright_colours_can_keep_their_colour_in_the_base() {
        // A saturated yellow at 8x SDR white: its tone-mapped luminance is near the base's white.
        let (w, h) = (32u32, 16u32);
        let s: Vec<f32> = (0..w * h).flat_map(|_| [20.0f32, 14.0, 0.5]).collect();
        let image =
            HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() }).unwrap();
        let saturation = |keep: bool| {
            let options = GainMapEncodeOptions { keep_bright_colours: keep, ..Default::default() };
            let (file, _) = encode(&image, &options).unwrap();
            // The SDR picture (display headroom 1) and the HDR one.
            let base = decode(&file, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
            let hdr = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            let p = &base.samples()[3 * (8 * w as usize + 16)..][..3];
            let q = &hdr.samples()[3 * (8 * w as usize + 16)..][..3];
            // HDR red back within 3 % (1.0 = 203 cd/m² there, 100 in the source).
            assert!((q[0] * 203.0 / 2000.0 - 1.0).abs() < 0.03, "keep {keep}: {q:?}");
            (p[0] - p[2]) / p[0]
        };
        let (desaturated, kept) = (saturation(false), saturation(true));
        assert!(desaturated < 0.5 && kept > 0.9, "{desaturated} {kept}");
    }

    #[test]
    fn a_light_does_not_darken_a_neighbour_it_does_not_reach() {
        // Mid-grey (0.2 of SDR white, under the tone curve's linear toe: gain 0) with one
        // light at 40 SDR whites on base pixel (8, 8), which sits exactly on map pixel (4, 4)
        // (half-size map): only that map pixel enters its mix. Base pixel (10, 10) sits
        // exactly on map pixel (5, 5), which the 2×2 neighbourhood raise also lifts (to 40×);
        // the map's JPEG spreads a little of the light's gain there either way (0.171 here).
        let (w, h) = (32u32, 32u32);
        let mut s: Vec<f32> = vec![0.2; (w * h * 3) as usize];
        s[3 * (8 * w as usize + 8)..][..3].copy_from_slice(&[40.0; 3]);
        let image =
            HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: SDR_WHITE_NITS, ..ColorInfo::default() })
                .unwrap();
        let at = |img: &HdrImage, x: usize, y: usize| img.samples()[3 * (y * w as usize + x) + 1];
        for raise in [MapRaise::Neighbourhood, MapRaise::Contributing, MapRaise::Deficit] {
            let options = GainMapEncodeOptions { map_raise: raise, map_scale: Some(2), ..Default::default() };
            let (file, _) = encode(&image, &options).unwrap();
            let hdr = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            let base = decode(&file, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
            // The light fits in both: the HDR rendition has it back.
            assert!((at(&hdr, 8, 8) / 40.0 - 1.0).abs() < 0.05, "{raise:?}: {}", at(&hdr, 8, 8));
            let neighbour = at(&base, 10, 10);
            if raise == MapRaise::Neighbourhood {
                assert!(neighbour < 0.05, "{neighbour}");
            } else {
                assert!(neighbour > 0.15 && neighbour < 0.21, "{raise:?}: {neighbour}");
            }
        }
    }

    /// The width of the gain map in an encoded file.
    fn map_width(file: &[u8]) -> usize {
        let (map, _, _) = GainMapFile::parse(file).unwrap().gain_map.unwrap();
        crate::gainmap::decode_jpeg(map.bytes(file), &Limits::default(), "gain map").unwrap().width
    }

    /// Grey (0.2 of SDR white) with a textured lamp: a 24×24 block whose pixels alternate, in a
    /// checkerboard, between 40 and 4 SDR whites, so that every half-size map pixel on it
    /// averages a bright and a dim pixel and must be raised to the bright one's need.
    fn lamp_scene() -> HdrImage {
        let (w, h) = (48usize, 48usize);
        let mut s = vec![0.2f32; w * h * 3];
        for y in 12..36 {
            for x in 12..36 {
                let v = if (x + y) % 2 == 0 { 40.0 } else { 4.0 };
                s[3 * (y * w + x)..][..3].copy_from_slice(&[v; 3]);
            }
        }
        HdrImage::new(48, 48, Channels::Rgb, s, ColorInfo { nits_per_unit: SDR_WHITE_NITS, ..ColorInfo::default() })
            .unwrap()
    }

    #[test]
    fn the_map_is_full_size_where_the_half_size_raise_would_darken_the_base() {
        let lamp = lamp_scene();
        let at = |img: &HdrImage, x: usize, y: usize| img.samples()[3 * (y * 48 + x) + 1];
        // The dim pixels of the lamp in the base: darkened about 10x by a half-size map's raise
        // (their map pixels carry the bright neighbours' need), not by a full-size map.
        let dim_in_base = |options: &GainMapEncodeOptions| {
            let (file, report) = encode(&lamp, options).unwrap();
            let base = decode(&file, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
            let hdr = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            // The HDR rendition has both back either way (the base's JPEG rings on the
            // checkerboard).
            assert!((at(&hdr, 20, 20) / 40.0 - 1.0).abs() < 0.1, "{}", at(&hdr, 20, 20));
            assert!((at(&hdr, 21, 20) / 4.0 - 1.0).abs() < 0.1, "{}", at(&hdr, 21, 20));
            (map_width(&file), at(&base, 21, 20), report.notes.iter().any(|n| n.contains("full-size gain map")))
        };
        let (width, auto, said) = dim_in_base(&GainMapEncodeOptions::default());
        assert!(width == 48 && said, "{width} {said}");
        let (width, half, said) = dim_in_base(&GainMapEncodeOptions { map_scale: Some(2), ..Default::default() });
        assert!(width == 24 && !said, "{width} {said}");
        assert!(auto > 0.5 && half < 0.15, "{auto} {half}");
        // With a 4:2:0 base (below quality 90) the map stays half size.
        let (width, _, said) = dim_in_base(&GainMapEncodeOptions {
            base_quality: 85,
            base_full_chroma: false,
            map_quality: 85,
            ..Default::default()
        });
        assert!(width == 24 && !said, "{width} {said}");
        // A scene whose raise is small keeps the half-size map.
        let (file, _) = encode(&scene(), &GainMapEncodeOptions::default()).unwrap();
        assert_eq!(map_width(&file), 48);
    }

    #[test]
    fn a_full_size_map_leaves_room_for_its_jpeg() {
        // Bright ripples at 5 to 45 SDR whites: the tone-mapped base sits near white, where a
        // gain the map's JPEG lowers would clip the pre-corrected base. With the margin the
        // base stays about 0.25 stops under white and nothing clips.
        let (w, h) = (64usize, 64usize);
        let mut s = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let v = 25.0 + 20.0 * ((x as f32 * 0.7).sin() * (y as f32 * 0.5).cos());
                s.extend([v, v * 0.9, v * 0.8]);
            }
        }
        let image = HdrImage::new(
            64,
            64,
            Channels::Rgb,
            s,
            ColorInfo { nits_per_unit: SDR_WHITE_NITS, ..ColorInfo::default() },
        )
        .unwrap();
        let options = GainMapEncodeOptions { map_scale: Some(1), ..Default::default() };
        let (file, report) = encode(&image, &options).unwrap();
        assert!(report.notes.iter().all(|n| !n.contains("outside what the base")), "{:?}", report.notes);
        let base = decode(&file, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
        let brightest = base.samples().iter().copied().fold(0.0f32, f32::max);
        assert!(brightest < 0.9, "{brightest}");
    }

    #[test]
    fn the_deficit_raise_leaves_a_lights_edge_to_the_brighter_neighbour() {
        // Grey (0.2 of SDR white) with a light at 100 on base pixel (8, 8), which sits on map
        // pixel (4, 4), and a dimmer one at 8 on (9, 8), halfway to map pixel (5, 4): its mix
        // is half of each. The contributing raise lifts map pixel (5, 4) to the dim light's
        // full need (3 stops), darkening grey base pixel (10, 8), which sits on it, 8×; the
        // deficit raise finds the mix already high enough from the bright light's map pixel.
        let (w, h) = (32u32, 32u32);
        let mut s: Vec<f32> = vec![0.2; (w * h * 3) as usize];
        s[3 * (8 * w as usize + 8)..][..3].copy_from_slice(&[100.0; 3]);
        s[3 * (8 * w as usize + 9)..][..3].copy_from_slice(&[8.0; 3]);
        let image =
            HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: SDR_WHITE_NITS, ..ColorInfo::default() })
                .unwrap();
        let at = |img: &HdrImage, x: usize, y: usize| img.samples()[3 * (y * w as usize + x) + 1];
        let mut greys = Vec::new();
        for raise in [MapRaise::Contributing, MapRaise::Deficit] {
            let options = GainMapEncodeOptions { map_raise: raise, map_scale: Some(2), ..Default::default() };
            let (file, _) = encode(&image, &options).unwrap();
            let hdr = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            let base = decode(&file, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
            // Both lights come back; the dim one, raised only to its need plus the margin,
            // loses a little to the map's JPEG ringing beside the bright light's spike (7.38:
            // 0.12 stops, more than the margin).
            assert!((at(&hdr, 8, 8) / 100.0 - 1.0).abs() < 0.05, "{raise:?}: {}", at(&hdr, 8, 8));
            assert!((at(&hdr, 9, 8) / 8.0 - 1.0).abs() < 0.1, "{raise:?}: {}", at(&hdr, 9, 8));
            greys.push(at(&base, 10, 8));
        }
        assert!(greys[0] < 0.05 && greys[1] > 0.15, "{greys:?}");
    }

    #[test]
    fn zero_gain_lands_on_a_code() {
        for (min, max) in [(-0.5, 7.3), (-2.51, 3.0), (-0.001, 9.0), (-9.0, 0.001), (-1.0, 1.0), (0.2, 4.0)] {
            let (lo, hi) = zero_on_a_code(min, max);
            assert!(lo <= min && hi >= max, "{min} {max}: {lo} {hi}");
            // About a code wider at most.
            assert!((hi - lo) - (max - min) < 1.01 * (max - min) / 255.0, "{min} {max}: {lo} {hi}");
            if min < 0.0 {
                let code = 255.0 * -lo / (hi - lo);
                assert!((code - code.round()).abs() < 1e-9, "{min} {max}: {code}");
                // Decoded as decoders do, that code gives gain 0.
                assert!((lo + (hi - lo) * code.round() / 255.0).abs() < 1e-12);
            } else {
                assert_eq!((lo, hi), (min, max));
            }
        }
    }

    #[test]
    fn the_black_level_fit_brings_the_darks_closer() {
        // A dim, noisy red scene (red 0 to 0.06 cd/m², green and blue a tenth of it: sRGB codes
        // 0 to 1 in the base) with a light, so the map has a range: the fit moves the red
        // channel's offset, and the darks decode closer to the source in ΔE ITP.
        let (w, h) = (64u32, 64u32);
        let mut seed = 1u32;
        let mut s = Vec::new();
        for y in 0..h {
            for x in 0..w {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let r = 0.0006 * f32::from((seed >> 24) as u8) / 255.0;
                let light = if (20..24).contains(&x) && (20..24).contains(&y) { 50.0 } else { 0.0 };
                s.extend([r + light, 0.1 * r + light, 0.1 * r + light]);
            }
        }
        let image =
            HdrImage::new(w, h, Channels::Rgb, s, ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() }).unwrap();
        let run = |fit: bool| {
            let options = GainMapEncodeOptions { fit_black_level: fit, ..Default::default() };
            let (file, _) = encode(&image, &options).unwrap();
            let meta = GainMapFile::parse(&file).unwrap().gain_map.unwrap().1;
            let back = decode(&file, &Limits::default(), Rendering::default()).unwrap();
            (meta.alternate_offset, hdrcodec_core::metrics::delta_e_itp(&image, &back).unwrap().0)
        };
        let ((plain, plain_error), (fitted, fitted_error)) = (run(false), run(true));
        assert_eq!(plain, [OFFSET; 3]);
        // Within about a base code at black (1/(255 · 12.92) of SDR white) of the plain offset.
        assert!(fitted.iter().all(|&k| (k - OFFSET).abs() < 1.5 / (255.0 * 12.92)), "{fitted:?}");
        assert_ne!(fitted[0], OFFSET);
        assert!(fitted_error < 0.8 * plain_error, "{plain_error} -> {fitted_error} ({fitted:?})");
    }

    #[test]
    fn any_core_tone_operator_makes_the_base() {
        let settings = EncodeSettings::default().with_option("tone", "reinhard");
        let options = GainMapEncodeOptions::from_settings(&settings).unwrap();
        assert_eq!(options.tone, ToneOperator::Reinhard);
        let (reinhard, _) = encode(&scene(), &options).unwrap();
        let (default, _) = encode(&scene(), &GainMapEncodeOptions::default()).unwrap();
        assert_ne!(reinhard, default);
        let back = decode(&reinhard, &Limits::default(), Rendering::default()).unwrap();
        assert_eq!(back.width(), 96);
    }
}
