//! Tone mapping for SDR output and base layers: the GT tone curve (Uchimura, "HDR theory and
//! practice", CEDEC 2017), its 1-D LUT form with the square-root input mapping of the
//! Gran Turismo SPORT pipeline (Uchimura & Suzuki, "Practical HDR and Wide Color Techniques
//! in Gran Turismo SPORT", SIGGRAPH Asia 2018 course), and Reinhard's global operator.

use crate::HdrImage;

/// The GT tone curve: a power-law toe, a linear mid-section and an exponential shoulder that
/// approaches `max_brightness`, blended by a smoothstep (toe → linear) and a step
/// (linear → shoulder). Input and output are in the same relative unit (1.0 = paper white).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GtToneCurve {
    /// P: the maximum output (display peak relative to paper white).
    pub max_brightness: f64,
    /// a: the slope of the linear section.
    pub contrast: f64,
    /// m: where the linear section starts (end of the toe).
    pub linear_start: f64,
    /// l: the length of the linear section, as a fraction of (P − m).
    pub linear_length: f64,
    /// c: the toe's exponent ("black tightness").
    pub black: f64,
    /// b: the toe's pedestal (output at input 0).
    pub pedestal: f64,
}

impl Default for GtToneCurve {
    /// The CEDEC 2017 defaults: P = 1, a = 1, m = 0.22, l = 0.4, c = 1.33, b = 0.
    fn default() -> Self {
        GtToneCurve {
            max_brightness: 1.0,
            contrast: 1.0,
            linear_start: 0.22,
            linear_length: 0.4,
            black: 1.33,
            pedestal: 0.0,
        }
    }
}

impl GtToneCurve {
    /// The default curve for a display whose peak is `peak_nits`, with input and output in
    /// units of `paper_white_nits` (P = peak / paper white; e.g. 1000 / 250 = 4).
    pub fn for_display(peak_nits: f64, paper_white_nits: f64) -> Self {
        GtToneCurve { max_brightness: peak_nits / paper_white_nits, ..Self::default() }
    }

    /// Maps a scene value (≥ 0; negatives and NaN are taken as 0) to the display value.
    pub fn map(&self, x: f64) -> f64 {
        let x = if x.is_nan() { 0.0 } else { x.max(0.0) };
        let (p, a, m, l, c, b) =
            (self.max_brightness, self.contrast, self.linear_start, self.linear_length, self.black, self.pedestal);
        // The end of the linear section in input (s0) and output (s1), and the shoulder's rate
        // chosen so that its slope at s0 equals the linear section's slope a.
        let l0 = (p - m) * l / a;
        let s0 = m + l0;
        let s1 = m + a * l0;
        let rate = a / (p - s1);
        let toe_weight = 1.0 - smoothstep(0.0, m, x);
        let shoulder_weight = if x >= s0 { 1.0 } else { 0.0 };
        let linear_weight = 1.0 - toe_weight - shoulder_weight;
        let toe = m * (x / m).powf(c) + b;
        let linear = m + a * (x - m);
        let shoulder = p - (p - s1) * (-rate * (x - s0)).exp();
        toe * toe_weight + linear * linear_weight + shoulder * shoulder_weight
    }
}

/// Hermite smoothstep of GLSL: 0 below `e0`, 1 above `e1`, 3t² − 2t³ between.
fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Number of entries of [`GtToneLut`].
pub const GT_LUT_SIZE: usize = 8192;
/// The input range of [`GtToneLut`], cd/m².
pub const GT_LUT_MAX_NITS: f64 = 50_000.0;

/// The GT tone curve as a 1-D table of [`GT_LUT_SIZE`] entries over 0-50 000 cd/m², with the
/// square-root input mapping of the Gran Turismo SPORT course: entry i holds the curve at
/// 50 000·(i / 8191)² cd/m², so the table is dense in the shadows where the curve bends most
/// per nit. Lookup is by linear interpolation; inputs above 50 000 cd/m² clamp to the last entry.
#[derive(Clone, Debug, PartialEq)]
pub struct GtToneLut {
    table: Vec<f32>,
    nits_per_unit: f64,
}

impl GtToneLut {
    /// Tabulates `curve`, whose input 1.0 means `nits_per_unit` cd/m² (its paper white).
    pub fn new(curve: &GtToneCurve, nits_per_unit: f64) -> Self {
        let table = (0..GT_LUT_SIZE).map(|i| curve.map(Self::entry_nits(i) / nits_per_unit) as f32).collect();
        GtToneLut { table, nits_per_unit }
    }

    /// The input luminance, cd/m², that entry `i` holds.
    pub fn entry_nits(i: usize) -> f64 {
        let t = i as f64 / (GT_LUT_SIZE - 1) as f64;
        GT_LUT_MAX_NITS * t * t
    }

    /// The curve's output (in paper-white units) for an input of `nits` cd/m².
    pub fn lookup(&self, nits: f32) -> f32 {
        let x = if nits.is_nan() { 0.0 } else { (nits / GT_LUT_MAX_NITS as f32).clamp(0.0, 1.0) };
        let pos = x.sqrt() * (GT_LUT_SIZE - 1) as f32;
        let i = (pos as usize).min(GT_LUT_SIZE - 2);
        let f = pos - i as f32;
        self.table[i] + (self.table[i + 1] - self.table[i]) * f
    }

    /// The cd/m² of the curve's input 1.0.
    pub fn nits_per_unit(&self) -> f64 {
        self.nits_per_unit
    }
}

/// Reinhard et al. 2002, eq. 3: x / (1 + x).
pub fn reinhard(x: f64) -> f64 {
    let x = x.max(0.0);
    x / (1.0 + x)
}

/// Reinhard et al. 2002, eq. 4: x·(1 + x / white²) / (1 + x); `white` maps to 1.
pub fn reinhard_extended(x: f64, white: f64) -> f64 {
    let x = x.max(0.0);
    x * (1.0 + x / (white * white)) / (1.0 + x)
}

/// A global tone-mapping operator for [`tonemap_to_sdr`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToneOperator {
    /// The GT curve; its output is divided by P so that the display peak is 1.
    Gt(GtToneCurve),
    /// [`reinhard`].
    Reinhard,
    /// [`reinhard_extended`] with this white point (in paper-white units).
    ReinhardExtended(f64),
}

impl ToneOperator {
    /// The display-linear value (1.0 = the display's peak) of scene value `x` (1.0 = paper
    /// white); not clamped.
    pub fn map(&self, x: f64) -> f64 {
        match self {
            ToneOperator::Gt(c) => c.map(x) / c.max_brightness,
            ToneOperator::Reinhard => reinhard(x),
            ToneOperator::ReinhardExtended(w) => reinhard_extended(x, *w),
        }
    }
}

impl std::str::FromStr for ToneOperator {
    type Err = crate::Error;

    /// `gt` (the default GT curve), `reinhard`, or `reinhard-extended:W` (white point W > 0,
    /// in paper-white units), as options on a command line name them.
    fn from_str(s: &str) -> crate::Result<Self> {
        match s.split_once(':') {
            None if s == "gt" => Ok(ToneOperator::Gt(GtToneCurve::default())),
            None if s == "reinhard" => Ok(ToneOperator::Reinhard),
            Some(("reinhard-extended", w)) => match w.parse::<f64>() {
                Ok(w) if w > 0.0 && w.is_finite() => Ok(ToneOperator::ReinhardExtended(w)),
                _ => Err(crate::Error::invalid(format!("tone operator {s}: the white point must be a number above 0"))),
            },
            _ => Err(crate::Error::invalid(format!("tone operator {s} (known: gt, reinhard, reinhard-extended:W)"))),
        }
    }
}

/// Tone-maps every pixel, channel by channel, to display-linear values in [0, 1] (apply an
/// output transfer such as sRGB afterwards). The input is scaled so that 1.0 is
/// `paper_white_nits` cd/m².
pub fn tonemap_to_sdr(image: &HdrImage, op: ToneOperator, paper_white_nits: f64) -> Vec<[f32; 3]> {
    let scale = image.color.nits_per_unit as f64 / paper_white_nits;
    let f = |v: f32| -> f32 {
        let y = op.map(v as f64 * scale);
        if y.is_nan() {
            0.0
        } else {
            y.clamp(0.0, 1.0) as f32
        }
    };
    image.rgb().map(|p| p.map(f)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_operators_by_name() {
        assert_eq!("gt".parse::<ToneOperator>().unwrap(), ToneOperator::Gt(GtToneCurve::default()));
        assert_eq!("reinhard".parse::<ToneOperator>().unwrap(), ToneOperator::Reinhard);
        let ext = "reinhard-extended:4".parse::<ToneOperator>().unwrap();
        assert_eq!(ext, ToneOperator::ReinhardExtended(4.0));
        assert!((ext.map(4.0) - 1.0).abs() < 1e-12, "the white point maps to 1");
        assert_eq!(ToneOperator::Reinhard.map(1.0), 0.5);
        for bad in ["", "aces", "reinhard-extended", "reinhard-extended:0", "reinhard-extended:x", "gt:2"] {
            assert!(bad.parse::<ToneOperator>().is_err(), "{bad}");
        }
    }

    #[test]
    fn gt_curve_has_the_cedec_shape() {
        // Uchimura, CEDEC 2017: defaults P=1, a=1, m=0.22, l=0.4, c=1.33, b=0.
        let c = GtToneCurve::default();
        assert_eq!(
            (c.max_brightness, c.contrast, c.linear_start, c.linear_length, c.black, c.pedestal),
            (1.0, 1.0, 0.22, 0.4, 1.33, 0.0)
        );
        // Toe: starts at the pedestal, stays below the identity (c > 1 darkens shadows).
        assert_eq!(c.map(0.0), 0.0);
        assert!(c.map(0.1) < 0.1 && c.map(0.1) > 0.0);
        // Linear section from m to m + (P − m)·l/a = 0.532: exactly m + a(x − m).
        for x in [0.22, 0.3, 0.4, 0.5, 0.53] {
            assert!((c.map(x) - x).abs() < 1e-12, "{x}");
        }
        // Shoulder: continuous where it starts, approaches P, never exceeds it.
        let s0 = 0.22 + 0.78 * 0.4;
        assert!((c.map(s0) - c.map(s0 - 1e-9)).abs() < 1e-8);
        assert!(c.map(20.0) > 1.0 - 1e-9 && c.map(1e6) <= 1.0);
        // Monotonic everywhere.
        let mut prev = -1.0;
        for i in 0..100_000 {
            let y = c.map(i as f64 * 1e-4);
            assert!(y >= prev, "{i}");
            prev = y;
        }
        // A 1000-nit display with 250-nit paper white: P = 4, still linear at mid-grey.
        let hdr = GtToneCurve::for_display(1000.0, 250.0);
        assert_eq!(hdr.max_brightness, 4.0);
        assert!((hdr.map(1.0) - 1.0).abs() < 1e-12 && hdr.map(1e4) > 3.999);
        assert_eq!(c.map(f64::NAN), 0.0);
        assert_eq!(c.map(-3.0), 0.0);
    }

    #[test]
    fn gt_lut_error_against_the_analytic_curve() {
        for (curve, paper_white) in [(GtToneCurve::default(), 100.0), (GtToneCurve::for_display(1000.0, 250.0), 250.0)]
        {
            let lut = GtToneLut::new(&curve, paper_white);
            assert_eq!(lut.table.len(), 8192);
            assert_eq!(GtToneLut::entry_nits(8191), 50_000.0);
            // Sample densely in both the square-root domain and linearly in nits.
            let mut worst = (0.0f64, 0.0f64);
            let n = 400_000;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                for nits in [GT_LUT_MAX_NITS * t * t, 2000.0 * t] {
                    let e = (lut.lookup(nits as f32) as f64 - curve.map(nits / paper_white)).abs();
                    if e > worst.0 {
                        worst = (e, nits);
                    }
                }
            }
            let rel = worst.0 / curve.max_brightness;
            println!(
                "GT LUT (P = {}, paper white {paper_white} cd/m²): max error {:.3e} ({:.3e} of P) at {:.4} cd/m²",
                curve.max_brightness, worst.0, rel, worst.1
            );
            assert!(rel < 1e-5, "{rel}");
        }
    }

    #[test]
    fn reinhard_operators() {
        // Reinhard et al. 2002: eq. 3 maps 1 to 1/2; eq. 4 maps L_white to 1.
        assert_eq!(reinhard(1.0), 0.5);
        assert!((reinhard_extended(4.0, 4.0) - 1.0).abs() < 1e-15);
        assert!(reinhard_extended(1.0, 1e9) - reinhard(1.0) < 1e-9);
    }

    #[test]
    fn sdr_helper_clamps_to_display_range() {
        use crate::{Channels, ColorInfo};
        let img = HdrImage::new(
            3,
            1,
            Channels::Rgb,
            vec![0.0, 1.0, 1000.0, f32::NAN, 2.0, -1.0, 0.5, 0.5, 0.5],
            ColorInfo::default(),
        )
        .unwrap();
        let out = tonemap_to_sdr(&img, ToneOperator::Gt(GtToneCurve::default()), 100.0);
        assert_eq!(out.len(), 3);
        assert!(out.iter().flatten().all(|v| (0.0..=1.0).contains(v)));
        assert_eq!(out[0][1], 1.0f64.min(GtToneCurve::default().map(1.0)) as f32);
        let r = tonemap_to_sdr(&img, ToneOperator::Reinhard, 100.0);
        assert_eq!(r[2], [1.0 / 3.0; 3]);
    }
}
