//! The luminance scale of a LogLuv TIFF (the STONITS tag, 37439) and what an encoding clips.
//!
//! A LogLuv file records CIE Y in file units: `Y_file · STONITS = cd/m²`. The encoder writes
//! `Y_file = Y_image · nits_per_unit / STONITS`, so the decoded image (samples in file units,
//! `nits_per_unit = STONITS`) has the same absolute luminance whatever STONITS was chosen.
//!
//! [`Stonits::Auto`] keeps STONITS = the image's `nits_per_unit` (the file is then the one
//! earlier versions wrote, byte for byte) when every finite luminance of the image codes without
//! clipping at that scale. Otherwise it chooses the STONITS that puts the image's brightest finite
//! luminance at the encoder's saturation point (the bottom of the top code, 15.742 for LogLuv24,
//! 1.837e19 for LogL16 / LogLuv32): no highlight is clipped, and whatever does not fit below goes
//! to black. Negative luminance (LogLuv24 has no sign, libtiff decodes a negative LogLuv32 as
//! black) and NaN are not helped by any scale; [`Clipped`] counts them for the encode report.

use crate::{pixel, Encoding};
use hdrcodec_core::color::Mat3;
use hdrcodec_core::{Error, HdrImage, Result};
use std::fmt::Write as _;
use std::str::FromStr;

/// How the encoder chooses the TIFF STONITS tag (cd/m² of a file luminance Y = 1).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Stonits {
    /// The image's `nits_per_unit` when the encoding holds every finite luminance of the image
    /// at that scale; otherwise the scale that puts the brightest finite luminance at the top of
    /// the code range (the darkest end is clipped, never the highlights). The default.
    #[default]
    Auto,
    /// This STONITS (a positive number): luminance outside the range it gives is clipped.
    Fixed(f64),
}

impl FromStr for Stonits {
    type Err = Error;
    /// `auto`, or a positive number of cd/m².
    fn from_str(s: &str) -> Result<Self> {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(Stonits::Auto);
        }
        let bad = || Error::invalid(format!("option stonits={s}: expected auto or a positive number of cd/m²"));
        let v: f64 = s.trim().parse().map_err(|_| bad())?;
        check_stonits(v).map_err(|_| bad())?;
        Ok(Stonits::Fixed(v))
    }
}

/// A STONITS the decoder can turn into a positive, finite `f32` `nits_per_unit`.
fn check_stonits(v: f64) -> Result<()> {
    let f = v as f32;
    if v.is_finite() && v > 0.0 && f.is_normal() {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "STONITS {v} is not a positive number between {:e} and {:e}",
            f32::MIN_POSITIVE,
            f32::MAX
        )))
    }
}

impl Encoding {
    /// The luminance magnitudes (file units) the encoding codes without clipping, `[lo, hi)`:
    /// below `lo` the luminance code is 0 (black); from `hi` up it saturates at the top code.
    /// LogLuv24: 2^(-12 + 1/64) ≈ 2.47e-4 to 2^4 = 16 (4.8 decades); LogL16 and LogLuv32:
    /// 2^(-64 + 1/256) ≈ 5.4e-20 to 2^64 ≈ 1.8e19 (38.5 decades).
    pub fn luminance_range(self) -> (f64, f64) {
        match self {
            Encoding::LogLuv24 => ((1.0f64 / 64.0 - 12.0).exp2(), 16.0),
            Encoding::LogL16 | Encoding::LogLuv32 => ((1.0f64 / 256.0 - 64.0).exp2(), 64f64.exp2()),
        }
    }

    /// The luminance from which the encoder writes the top code (libtiff's thresholds): where
    /// [`Stonits::Auto`] puts the image's brightest pixel when it has to scale.
    fn saturation(self) -> f64 {
        match self {
            Encoding::LogLuv24 => 15.742,
            Encoding::LogL16 | Encoding::LogLuv32 => 1.8371976e19,
        }
    }

    /// True when the encoding keeps the sign of a negative luminance in a way decoders return
    /// (LogL16 only: libtiff decodes a negative LogLuv32 luminance as black).
    fn keeps_sign(self) -> bool {
        self == Encoding::LogL16
    }

    /// The luminance code (magnitude, without LogL16's sign bit) of an encoded word.
    fn luminance_code(self, word: u32) -> u32 {
        match self {
            Encoding::LogL16 => word & 0x7fff,
            Encoding::LogLuv32 => word >> 16 & 0x7fff,
            Encoding::LogLuv24 => word >> 14 & 0x3ff,
        }
    }

    /// The luminance code of `y` as the pixel encoder computes it (`y` as the encoder sees it).
    fn code_of(self, y: f64) -> u32 {
        match self {
            Encoding::LogLuv24 => pixel::logl10_from_y(y),
            Encoding::LogL16 | Encoding::LogLuv32 => u32::from(pixel::logl16_from_y(y)) & 0x7fff,
        }
    }

    /// Luminance `y` (f64) as the pixel encoder receives it: LogLuv24 and LogLuv32 take XYZ as
    /// `f32`, LogL16 takes Y as `f64`.
    #[inline]
    pub(crate) fn as_encoded(self, y: f64) -> f64 {
        if self == Encoding::LogL16 {
            y
        } else {
            f64::from(y as f32)
        }
    }

    /// What [`Stonits::Auto`] may scale: the magnitude of a luminance the encoding can return.
    #[inline]
    fn magnitude(self, y: f64) -> f64 {
        if self.keeps_sign() {
            y.abs()
        } else {
            y
        }
    }
}

/// The scale the encoder uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Choice {
    /// The STONITS written.
    pub stonits: f64,
    /// The factor from image samples to file units: `nits_per_unit / stonits` (exactly 1 when
    /// STONITS is the image's `nits_per_unit`).
    pub scale: f64,
    /// The image's brightest finite luminance in cd/m², when [`Stonits::Auto`] moved the scale.
    pub moved_for: Option<f64>,
}

/// STONITS = the image's `nits_per_unit`, scale 1.
pub(crate) fn keep(image: &HdrImage) -> Choice {
    Choice { stonits: f64::from(image.color.nits_per_unit), scale: 1.0, moved_for: None }
}

/// Chooses STONITS for `image` (RGB → XYZ matrix `m`) in `encoding`.
pub(crate) fn choose(image: &HdrImage, m: &Mat3, encoding: Encoding, stonits: Stonits) -> Result<Choice> {
    let nits = f64::from(image.color.nits_per_unit);
    let nits_ok = nits.is_finite() && nits > 0.0;
    let keep = keep(image);
    match stonits {
        Stonits::Fixed(v) => {
            check_stonits(v)?;
            if !nits_ok {
                return Err(Error::invalid(format!("the image's nits_per_unit {nits} is not a positive number")));
            }
            Ok(Choice { stonits: v, scale: nits / v, moved_for: None })
        }
        Stonits::Auto => {
            if !nits_ok {
                return Ok(keep);
            }
            // The brightest and the dimmest non-zero finite magnitude, as the encoder sees them.
            let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
            for [r, g, b] in image.rgb() {
                let y = m[1][0] * f64::from(r) + m[1][1] * f64::from(g) + m[1][2] * f64::from(b);
                let y = encoding.magnitude(encoding.as_encoded(y));
                if y > 0.0 && y.is_finite() {
                    lo = lo.min(y);
                    hi = hi.max(y);
                }
            }
            let (_, top) = encoding.luminance_range();
            if hi == 0.0 || (hi < top && encoding.code_of(lo) != 0) {
                return Ok(keep);
            }
            // Brightest pixel just below the saturation point, in the code under the top one
            // (libtiff's threshold lies inside that code's interval: at or above it, the top
            // code would be a whole step off). STONITS is rounded to an f32 (the decoder's
            // `nits_per_unit` is one) and kept within f32's normal range; the scale is derived
            // from the rounded value, so file and decoder agree exactly. The rounding moves the
            // brightest pixel by at most 6e-8 of itself, less than the margin of 2^-20.
            let wanted = nits * hi / (encoding.saturation() * (1.0 - 1.0 / f64::from(1u32 << 20)));
            let s = (wanted as f32).clamp(f32::MIN_POSITIVE, f32::MAX);
            let stonits = f64::from(s);
            if stonits == nits {
                return Ok(keep);
            }
            Ok(Choice { stonits, scale: nits / stonits, moved_for: Some(hi * nits) })
        }
    }
}

/// Pixels whose luminance the encoding could not hold, counted while encoding.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Clipped {
    /// Positive luminance below the lowest code: stored as black.
    pub dark: u64,
    /// Luminance at or above the top of the code range (+∞ included): stored as the top code.
    pub bright: u64,
    /// Negative luminance, where the encoding cannot return it (LogLuv24: stored as black;
    /// LogLuv32: stored with its sign, decoded as black by libtiff and by us).
    pub negative: u64,
    /// NaN luminance: stored as black.
    pub nan: u64,
}

impl Clipped {
    /// Counts one pixel of file luminance `y` (as the encoder saw it) encoded as `word`.
    #[inline]
    pub(crate) fn tally(&mut self, encoding: Encoding, y: f64, word: u32) {
        // Fast path, nearly every pixel: a luminance code strictly inside the range (and, for
        // LogLuv32, no sign bit) is a positive finite luminance that fits (LogL16: of either
        // sign). NaN and negatives (where there is no sign) give code 0.
        let (code, top_code) = match encoding {
            Encoding::LogL16 => (word & 0x7fff, 0x7fff),
            Encoding::LogLuv32 => (word >> 16, 0x7fff),
            Encoding::LogLuv24 => (word >> 14 & 0x3ff, 0x3ff),
        };
        if code != 0 && code < top_code {
            return;
        }
        self.tally_edge(encoding, y, word);
    }

    /// [`tally`](Self::tally) for a pixel at either end of the code range.
    #[cold]
    fn tally_edge(&mut self, encoding: Encoding, y: f64, word: u32) {
        if y.is_nan() {
            self.nan += 1;
        } else if y < 0.0 && !encoding.keeps_sign() {
            self.negative += 1;
        } else if y != 0.0 {
            let (_, top) = encoding.luminance_range();
            if y.abs() >= top {
                self.bright += 1;
            } else if encoding.luminance_code(word) == 0 {
                self.dark += 1;
            }
        }
    }

    /// True when nothing was clipped.
    pub fn is_empty(&self) -> bool {
        *self == Clipped::default()
    }

    /// A sentence for the encode report, `None` when nothing was clipped.
    pub(crate) fn note(&self, encoding: Encoding, choice: &Choice, fixed: bool) -> Option<String> {
        if self.is_empty() {
            return None;
        }
        let (lo, hi) = encoding.luminance_range();
        let s = choice.stonits;
        let mut parts = Vec::new();
        if self.dark > 0 {
            parts.push(format!("{} darker became black", self.dark));
        }
        if self.bright > 0 {
            let top = pixel_top(encoding) * s;
            parts.push(format!("{} brighter became {} cd/m²", self.bright, num(top)));
        }
        if self.negative > 0 {
            parts.push(match encoding {
                Encoding::LogLuv32 => {
                    format!("{} of negative luminance keep their sign but decode as black (libtiff)", self.negative)
                }
                _ => format!("{} of negative luminance became black", self.negative),
            });
        }
        if self.nan > 0 {
            parts.push(format!("{} NaN became black", self.nan));
        }
        let mut out = format!(
            "{} at STONITS {} holds luminance from {} to {} cd/m²: of the pixels, {}",
            encoding.label(),
            num(s),
            num(lo * s),
            num(hi * s),
            parts.join(", ")
        );
        let mut hints = Vec::new();
        if fixed && self.bright > 0 {
            hints.push("--opt stonits=auto moves the range to the image's highlights");
        }
        if encoding == Encoding::LogLuv24 && (self.dark > 0 || (fixed && self.bright > 0)) {
            hints.push("logluv32 holds 38 decades");
        }
        if !hints.is_empty() {
            let _ = write!(out, " ({})", hints.join("; "));
        }
        Some(out)
    }
}

/// The decoded value of the top luminance code, in file units.
fn pixel_top(encoding: Encoding) -> f64 {
    match encoding {
        Encoding::LogLuv24 => pixel::logl10_to_y(0x3ff),
        Encoding::LogL16 | Encoding::LogLuv32 => pixel::logl16_to_y(0x7fff),
    }
}

/// The note of an automatically moved scale.
pub(crate) fn moved_note(encoding: Encoding, choice: &Choice, nits_per_unit: f32) -> Option<String> {
    let brightest = choice.moved_for?;
    let (lo, hi) = encoding.luminance_range();
    let s = choice.stonits;
    let mut out = String::new();
    let _ = write!(
        out,
        "{} codes {:.1} decades of luminance: STONITS {} (stonits=auto; the image's nits_per_unit is {}) \
         puts the brightest pixel, {} cd/m², just below the top of the range, {} to {} cd/m²",
        encoding.label(),
        (hi / lo).log10(),
        num(s),
        num(f64::from(nits_per_unit)),
        num(brightest),
        num(lo * s),
        num(hi * s),
    );
    Some(out)
}

/// A number with about 4 significant digits, plain in 0.001 .. 1e6, scientific outside.
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e6).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.3e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_agree_with_the_pixel_encoders() {
        for e in [Encoding::LogLuv24, Encoding::LogL16, Encoding::LogLuv32] {
            let (lo, hi) = e.luminance_range();
            // The lowest non-zero code starts at lo (up to the encoder's rounding of log2).
            assert_eq!(e.code_of(lo * (1.0 + 1e-12)), 1, "{e:?}");
            assert_eq!(e.code_of(lo * (1.0 - 1e-12)), 0, "{e:?}");
            // The top code saturates from `saturation` up; its interval ends at hi.
            let top = if e == Encoding::LogLuv24 { 0x3ff } else { 0x7fff };
            assert_eq!(e.code_of(e.saturation()), top, "{e:?}");
            assert_eq!(e.code_of(e.saturation() * (1.0 - 1e-6)), top - 1, "{e:?}");
            assert!(pixel_top(e) < hi && pixel_top(e) > e.saturation());
        }
    }

    #[test]
    fn stonits_option_parses() {
        assert_eq!("auto".parse::<Stonits>().unwrap(), Stonits::Auto);
        assert_eq!("AUTO".parse::<Stonits>().unwrap(), Stonits::Auto);
        assert_eq!("179".parse::<Stonits>().unwrap(), Stonits::Fixed(179.0));
        for bad in ["0", "-1", "nan", "inf", "1e40", "1e-50", "x"] {
            assert!(bad.parse::<Stonits>().is_err(), "{bad}");
        }
    }

    #[test]
    fn numbers_read_well() {
        assert_eq!(num(100.0), "100");
        assert_eq!(num(15.742), "15.74");
        assert_eq!(num(0.0246799), "0.02468");
        assert_eq!(num(6103.5156), "6104");
        assert_eq!(num(1.5e5), "150000");
        assert_eq!(num(1.8e21), "1.800e21");
        assert_eq!(num(5.4e-20), "5.400e-20");
    }
}
