//! HDR10 static metadata: SMPTE ST 2086 mastering display colour volume and the CTA-861.3
//! content light level (MaxCLL, MaxFALL).

use crate::{ColorPrimaries, HdrImage};

/// SMPTE ST 2086 mastering display colour volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasteringDisplay {
    /// Display primaries (x, y) in the order red, green, blue.
    pub primaries: [[f64; 2]; 3],
    /// Display white point (x, y).
    pub white: [f64; 2],
    /// Maximum display luminance, cd/m².
    pub max_luminance: f64,
    /// Minimum display luminance, cd/m².
    pub min_luminance: f64,
}

/// CTA-861.3 content light level, in whole cd/m² as the standard carries them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ContentLightLevel {
    /// MaxCLL: the largest max(R,G,B) of any pixel of any frame, in nits.
    pub max_cll: u16,
    /// MaxFALL: the largest frame average of max(R,G,B), in nits.
    pub max_fall: u16,
}

/// HDR10 static metadata as carried by video and image containers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Hdr10Metadata {
    /// Mastering display colour volume, if known.
    pub mastering_display: Option<MasteringDisplay>,
    /// Content light level, if known.
    pub content_light_level: Option<ContentLightLevel>,
}

/// The brightest component of a pixel, with NaN and negatives as 0: the light level of a
/// pixel in sample units (CTA-861.3 Annex A).
#[inline]
pub fn max_component(p: [f32; 3]) -> f64 {
    // f32::max returns the non-NaN operand, so NaN components drop out.
    p[0].max(p[1]).max(p[2]).max(0.0) as f64
}

/// MaxCLL of one frame, cd/m²: the largest max(R, G, B) of any pixel times `nits_per_unit`.
///
/// CTA-861.3 (Annex A) defines the light level of a pixel as the maximum of its linear R, G
/// and B components; it does not ask for a conversion to other primaries, so the image's own
/// primaries are used. (An encoder that stores BT.2020 should convert the image first, e.g.
/// with [`convert_primaries`](crate::color::convert_primaries), and measure what it stores.)
/// NaN and negative components count as 0.
pub fn max_cll_nits(image: &HdrImage) -> f64 {
    image.rgb().map(max_component).fold(0.0, f64::max) * image.color.nits_per_unit as f64
}

/// The frame-average light level, cd/m²: the mean over pixels of max(R, G, B) times
/// `nits_per_unit` (CTA-861.3 Annex A); 0 for an empty image.
pub fn frame_average_light_level(image: &HdrImage) -> f64 {
    let n = image.pixel_count();
    if n == 0 {
        return 0.0;
    }
    let sum: f64 = image.rgb().map(max_component).sum();
    sum / n as f64 * image.color.nits_per_unit as f64
}

/// Whole cd/m² for the metadata: rounded up, so that the metadata never understates the
/// content (a display tone-maps against it), and saturated at 65 535, the largest value the
/// 16-bit fields of CTA-861.3 and HEVC/AV1 carry.
fn whole_nits(v: f64) -> u16 {
    if v.is_nan() || v <= 0.0 {
        0
    } else {
        v.ceil().min(u16::MAX as f64) as u16
    }
}

impl ContentLightLevel {
    /// MaxCLL and MaxFALL over a sequence of frames (a still image is a sequence of one):
    /// MaxCLL = max over frames of [`max_cll_nits`], MaxFALL = max over frames of
    /// [`frame_average_light_level`], each rounded up to whole cd/m² and saturated at 65 535.
    /// No frames gives 0, 0 (0 means "unknown" in CTA-861.3).
    pub fn from_frames<'a>(frames: impl IntoIterator<Item = &'a HdrImage>) -> ContentLightLevel {
        let (mut cll, mut fall) = (0.0f64, 0.0f64);
        for f in frames {
            cll = cll.max(max_cll_nits(f));
            fall = fall.max(frame_average_light_level(f));
        }
        ContentLightLevel { max_cll: whole_nits(cll), max_fall: whole_nits(fall) }
    }
}

impl MasteringDisplay {
    /// A display with the primaries and white of `primaries`, peak `max_nits` and black `min_nits`.
    pub fn from_primaries(primaries: ColorPrimaries, max_nits: f64, min_nits: f64) -> Self {
        let c = primaries.chromaticities();
        MasteringDisplay {
            primaries: [c.red, c.green, c.blue],
            white: c.white,
            max_luminance: max_nits,
            min_luminance: min_nits,
        }
    }

    /// The usual HDR10 grading monitor: P3 primaries, D65, 1000 cd/m² peak, 0.0001 cd/m² black.
    pub fn p3_d65_1000() -> Self {
        Self::from_primaries(ColorPrimaries::DisplayP3, 1000.0, 0.0001)
    }

    /// A BT.2020-primaries (D65) display with the given peak and black, e.g. 4000 and 0.005.
    pub fn bt2020(max_nits: f64, min_nits: f64) -> Self {
        Self::from_primaries(ColorPrimaries::Bt2020, max_nits, min_nits)
    }

    /// A BT.709 (D65) display with the given peak and black (an SDR reference monitor is 100, 0.05).
    pub fn bt709(max_nits: f64, min_nits: f64) -> Self {
        Self::from_primaries(ColorPrimaries::Bt709, max_nits, min_nits)
    }

    /// The SMPTE ST 2086 / HEVC and H.264 mastering-display SEI integer units:
    /// chromaticity in 0.00002 (0-50 000), luminance in 0.0001 cd/m². Rounded to nearest and
    /// saturated to the field ranges.
    pub fn to_st2086(&self) -> St2086Units {
        let xy = |v: [f64; 2]| v.map(|c| fixed16(c, 50_000.0, 50_000));
        St2086Units {
            primaries: self.primaries.map(xy),
            white: xy(self.white),
            max_luminance: fixed(self.max_luminance, 10_000.0, u32::MAX),
            min_luminance: fixed(self.min_luminance, 10_000.0, u32::MAX),
        }
    }

    /// The inverse of [`to_st2086`](Self::to_st2086).
    pub fn from_st2086(u: &St2086Units) -> Self {
        let xy = |v: [u16; 2]| v.map(|c| c as f64 / 50_000.0);
        MasteringDisplay {
            primaries: u.primaries.map(xy),
            white: xy(u.white),
            max_luminance: u.max_luminance as f64 / 10_000.0,
            min_luminance: u.min_luminance as f64 / 10_000.0,
        }
    }

    /// The AV1 `metadata_hdr_mdcv` units (AV1 specification section 6.7.4): chromaticity as
    /// 0.16 fixed point, `luminance_max` as 24.8 and `luminance_min` as 18.14 fixed point.
    /// Rounded to nearest and saturated.
    pub fn to_av1(&self) -> Av1MdcvUnits {
        let xy = |v: [f64; 2]| v.map(|c| fixed16(c, 65_536.0, u16::MAX));
        Av1MdcvUnits {
            primaries: self.primaries.map(xy),
            white: xy(self.white),
            luminance_max: fixed(self.max_luminance, 256.0, u32::MAX),
            luminance_min: fixed(self.min_luminance, 16_384.0, u32::MAX),
        }
    }

    /// The inverse of [`to_av1`](Self::to_av1).
    pub fn from_av1(u: &Av1MdcvUnits) -> Self {
        let xy = |v: [u16; 2]| v.map(|c| c as f64 / 65_536.0);
        MasteringDisplay {
            primaries: u.primaries.map(xy),
            white: xy(u.white),
            max_luminance: u.luminance_max as f64 / 256.0,
            min_luminance: u.luminance_min as f64 / 16_384.0,
        }
    }
}

/// `round(v · scale)` clamped to [0, max]; NaN gives 0.
fn fixed(v: f64, scale: f64, max: u32) -> u32 {
    let r = (v * scale).round();
    if r.is_nan() || r <= 0.0 {
        0
    } else {
        r.min(max as f64) as u32
    }
}

/// [`fixed`] for a 16-bit field saturating at `max`.
fn fixed16(v: f64, scale: f64, max: u16) -> u16 {
    fixed(v, scale, max as u32) as u16
}

/// SMPTE ST 2086 values in the integer units of the HEVC / H.264 mastering display colour
/// volume SEI (and x265's `--master-display`). Primaries are in the order red, green, blue
/// here; the SEI writes them green, blue, red ([`St2086Units::sei_order`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct St2086Units {
    /// Red, green, blue (x, y), in units of 0.00002.
    pub primaries: [[u16; 2]; 3],
    /// White point (x, y), in units of 0.00002.
    pub white: [u16; 2],
    /// Maximum luminance in units of 0.0001 cd/m².
    pub max_luminance: u32,
    /// Minimum luminance in units of 0.0001 cd/m².
    pub min_luminance: u32,
}

impl St2086Units {
    /// The primaries in SEI order: green, blue, red.
    pub fn sei_order(&self) -> [[u16; 2]; 3] {
        [self.primaries[1], self.primaries[2], self.primaries[0]]
    }

    /// x265's `--master-display` string: `G(x,y)B(x,y)R(x,y)WP(x,y)L(max,min)`.
    pub fn x265_string(&self) -> String {
        let [g, b, r] = self.sei_order();
        format!(
            "G({},{})B({},{})R({},{})WP({},{})L({},{})",
            g[0], g[1], b[0], b[1], r[0], r[1], self.white[0], self.white[1], self.max_luminance, self.min_luminance
        )
    }
}

/// The AV1 `metadata_hdr_mdcv` fields (primaries in the order red, green, blue, as AV1 has them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Av1MdcvUnits {
    /// Red, green, blue (x, y) as 0.16 fixed point.
    pub primaries: [[u16; 2]; 3],
    /// White point (x, y) as 0.16 fixed point.
    pub white: [u16; 2],
    /// Maximum luminance, cd/m², as 24.8 fixed point.
    pub luminance_max: u32,
    /// Minimum luminance, cd/m², as 18.14 fixed point.
    pub luminance_min: u32,
}

/// Samples an encoder changed because its signal could not hold them (e.g. PQ above
/// 10 000 cd/m²), counted per component over a stream.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClipReport {
    /// Components that were NaN (coded as 0).
    pub nan: u64,
    /// Components below 0 cd/m² (coded as 0).
    pub negative: u64,
    /// Components above the transfer's peak, +∞ included (coded as the peak).
    pub above_peak: u64,
}

impl ClipReport {
    /// Adds another report's counts.
    pub fn add(&mut self, other: &ClipReport) {
        self.nan += other.nan;
        self.negative += other.negative;
        self.above_peak += other.above_peak;
    }

    /// True when nothing was changed.
    pub fn is_empty(&self) -> bool {
        *self == ClipReport::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channels, ColorInfo};

    fn frame(pixels: &[[f32; 3]], nits_per_unit: f32) -> HdrImage {
        let samples = pixels.iter().flatten().copied().collect();
        let color = ColorInfo { nits_per_unit, ..ColorInfo::default() };
        HdrImage::new(pixels.len() as u32, 1, Channels::Rgb, samples, color).unwrap()
    }

    #[test]
    fn content_light_level_of_a_synthetic_sequence() {
        // By hand, with 100 cd/m² per unit:
        // frame 1: max(R,G,B) per pixel = 2, 0.5, 1, 0.5 → MaxCLL 200, average 1.0 → 100;
        // frame 2: 7.005 (a NaN and a negative component drop out), 0, 0, 0 → 700.5, avg 175.125;
        // frame 3: all 1.5 → 150, average 150.
        // MaxCLL = ceil(700.5) = 701, MaxFALL = ceil(175.125) = 176.
        let f1 = frame(&[[2.0, 1.0, 0.0], [0.5, 0.5, 0.5], [0.0, 0.0, 1.0], [0.1, 0.5, 0.2]], 100.0);
        let f2 = frame(&[[f32::NAN, 7.005, -3.0], [0.0; 3], [0.0; 3], [-1.0, 0.0, 0.0]], 100.0);
        let f3 = frame(&[[1.5; 3]; 4], 100.0);
        assert_eq!(max_cll_nits(&f1), 200.0);
        assert!((frame_average_light_level(&f1) - 100.0).abs() < 1e-9);
        assert!((max_cll_nits(&f2) - 700.5).abs() < 1e-3);
        let cll = ContentLightLevel::from_frames([&f1, &f2, &f3]);
        assert_eq!(cll, ContentLightLevel { max_cll: 701, max_fall: 176 });
        assert_eq!(ContentLightLevel::from_frames([]), ContentLightLevel { max_cll: 0, max_fall: 0 });
        // A 10^5 cd/m² sun saturates the 16-bit field.
        let sun = frame(&[[1000.0, 900.0, 800.0]], 100.0);
        assert_eq!(ContentLightLevel::from_frames([&sun]).max_cll, 65_535);
    }

    #[test]
    fn st2086_units_match_the_x265_example() {
        // x265 documentation, --master-display: "Example for a P3D65 1000-nits monitor, where
        // G(x=0.265, y=0.690), B(x=0.150, y=0.060), R(x=0.680, y=0.320), WP(x=0.3127, y=0.3290),
        // L(max=1000, min=0.0001): G(13250,34500)B(7500,3000)R(34000,16000)WP(15635,16450)L(10000000,1)".
        let u = MasteringDisplay::p3_d65_1000().to_st2086();
        assert_eq!(u.x265_string(), "G(13250,34500)B(7500,3000)R(34000,16000)WP(15635,16450)L(10000000,1)");
        let back = MasteringDisplay::from_st2086(&u);
        assert_eq!(back.to_st2086(), u);
        assert!((back.max_luminance - 1000.0).abs() < 1e-9 && (back.min_luminance - 0.0001).abs() < 1e-12);
        // Out-of-range values saturate instead of wrapping.
        let odd = MasteringDisplay {
            primaries: [[2.0, -1.0]; 3],
            white: [f64::NAN; 2],
            max_luminance: 1e9,
            min_luminance: -1.0,
        };
        let u = odd.to_st2086();
        assert_eq!((u.primaries[0], u.white, u.max_luminance, u.min_luminance), ([50_000, 0], [0, 0], u32::MAX, 0));
    }

    #[test]
    fn av1_units_follow_the_fixed_point_formats() {
        // AV1 section 6.7.4: chromaticity 0.16 (×65536), luminance_max 24.8 (×256),
        // luminance_min 18.14 (×16384).
        let md = MasteringDisplay::bt2020(4000.0, 0.005);
        let u = md.to_av1();
        assert_eq!(u.luminance_max, 4000 * 256);
        assert_eq!(u.luminance_min, (0.005f64 * 16384.0).round() as u32); // 82
        assert_eq!(u.primaries[0], [(0.708f64 * 65536.0).round() as u16, (0.292f64 * 65536.0).round() as u16]);
        let back = MasteringDisplay::from_av1(&u);
        assert_eq!(back.to_av1(), u);
        for i in 0..3 {
            for j in 0..2 {
                assert!((back.primaries[i][j] - md.primaries[i][j]).abs() <= 0.5 / 65536.0);
            }
        }
        assert!((back.min_luminance - 0.005).abs() <= 0.5 / 16384.0);
    }
}
