//! L_p u'v': the colour space of Mantiuk et al. 2004. Luminance goes through a perceptual
//! curve ([`LumaCurve`], ψ in the paper) to an integer code; chromaticity is CIE 1976 u'v',
//! stored in 8 bits each as round(410·u') and round(410·v'), the scale of Ward's LogLuv
//! (`UVSCALE 410` in libtiff's tiffio.h; LumaHDRv uses it the same way, VIDEO-NOTES §1.4).
//! u'v' of visible colours stay below 0.62 and 0.59, so their codes fit in 255.
//!
//! Input rules, per RGB sample: NaN and negative values are taken as 0 (a negative sample
//! has no luminance of its own to keep, and clamping before the matrix keeps XYZ inside the
//! space's gamut), +∞ as `f32::MAX` (then the curve's top code). Luminance outside the
//! curve's range clamps to its end codes, so black comes back as the curve's lowest
//! luminance (10⁻⁴ cd/m² for the default ψ). Black has no chromaticity and gets D65's
//! (u' = 0.1978, v' = 0.4683: codes 81, 192). Chromaticities outside 0 ≤ 410·u', 410·v' ≤ 255
//! (only imaginary colours: the XYZ or ACES AP0 primaries themselves) clamp to that square.
//! Primaries that are [`Unspecified`](ColorPrimaries::Unspecified) are taken as BT.709.
//!
//! ```
//! use hdrcodec_core::ColorPrimaries;
//! use hdrcodec_video::curves::LumaCurve;
//! use hdrcodec_video::luv::{decode_pixel, encode_pixel, LinearRgb};
//! use hdrcodec_video::mantiuk::{Psi04, PsiOptions};
//!
//! let psi = Psi04::new(&PsiOptions::default())?; // 11 bits over 1e-4..1e8 cd/m²
//! assert_eq!(psi.encode(psi.decode(1000)), 1000);
//! let space = LinearRgb::new(ColorPrimaries::Bt709, 100.0)?; // 1.0 = 100 cd/m²
//! let pixel = encode_pixel(&psi, &space, [0.5, 0.25, 0.125]);
//! let rgb = decode_pixel(&psi, &space, pixel);
//! assert!((rgb[1] / 0.25 - 1.0).abs() < 0.05);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use hdrcodec_core::color::{luv_prime_to_xyz, mat_apply, mat_inverse, xyz_to_uv_prime, Mat3};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, Result};

use crate::curves::LumaCurve;

/// Codes per unit of u' and v' (Ward's LogLuv scale).
pub const UV_SCALE: f64 = 410.0;

/// One pixel in L_p u'v' codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LpuvPixel {
    /// Luminance code of the curve in use.
    pub luma: u16,
    /// round(410·u').
    pub u: u8,
    /// round(410·v').
    pub v: u8,
}

/// Linear RGB samples in absolute terms: primaries and the luminance of 1.0, as the two
/// matrices between samples and XYZ in cd/m².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearRgb {
    to_xyz_nits: Mat3,
    from_xyz_nits: Mat3,
}

impl LinearRgb {
    /// The space of samples in `primaries` where 1.0 is `nits_per_unit` cd/m². Errors:
    /// degenerate custom chromaticities, or `nits_per_unit` not finite and positive.
    pub fn new(primaries: ColorPrimaries, nits_per_unit: f32) -> Result<Self> {
        if !(nits_per_unit.is_finite() && nits_per_unit > 0.0) {
            return Err(Error::invalid(format!("L_p u'v': nits_per_unit {nits_per_unit} must be finite and positive")));
        }
        let matrix = primaries.or_bt709().chromaticities().try_rgb_to_xyz();
        let to_xyz = matrix.ok_or_else(|| Error::invalid(format!("L_p u'v': degenerate primaries {primaries:?}")))?;
        let scale = f64::from(nits_per_unit);
        let to_xyz_nits = to_xyz.map(|row| row.map(|v| v * scale));
        // Cannot fail: the matrix of valid chromaticities is invertible and the scale positive.
        let from_xyz_nits = mat_inverse(&to_xyz_nits).ok_or_else(|| Error::invalid("L_p u'v': singular RGB matrix"))?;
        Ok(LinearRgb { to_xyz_nits, from_xyz_nits })
    }

    /// The space an image's [`ColorInfo`] describes.
    pub fn of(color: &ColorInfo) -> Result<Self> {
        LinearRgb::new(color.primaries, color.nits_per_unit)
    }
}

/// A sample as the input rules take it: NaN and negatives 0, +∞ the largest finite value.
fn sanitize(sample: f32) -> f64 {
    if sample.is_nan() || sample <= 0.0 {
        0.0
    } else {
        f64::from(sample.min(f32::MAX))
    }
}

/// A chromaticity coordinate's 8-bit code.
fn chroma_code(coordinate: f64) -> u8 {
    (coordinate * UV_SCALE).round().clamp(0.0, 255.0) as u8
}

/// Linear RGB in `space` → L_p u'v' codes with `curve` for luminance.
pub fn encode_pixel(curve: &dyn LumaCurve, space: &LinearRgb, rgb: [f32; 3]) -> LpuvPixel {
    let xyz = mat_apply(&space.to_xyz_nits, rgb.map(sanitize));
    // Black (and anything whose X + 15Y + 3Z is 0) gets the D65 chromaticity from core.
    let [u, v] = xyz_to_uv_prime(xyz);
    LpuvPixel { luma: curve.encode(xyz[1]), u: chroma_code(u), v: chroma_code(v) }
}

/// L_p u'v' codes → linear RGB in `space`. Colours near the gamut's edge can come back with a
/// slightly negative component (the chromaticity moved by up to half a code); they are kept as
/// they are, since linear samples may be negative.
pub fn decode_pixel(curve: &dyn LumaCurve, space: &LinearRgb, pixel: LpuvPixel) -> [f32; 3] {
    let luminance = curve.decode(pixel.luma);
    let u = f64::from(pixel.u) / UV_SCALE;
    // v' = 0 has no XYZ (core returns black); code 0 stands for v' in [0, 0.5/410), so decode it
    // at the top of that interval rather than lose the pixel's luminance.
    let v = f64::from(pixel.v).max(0.5) / UV_SCALE;
    let xyz = luv_prime_to_xyz([luminance, u, v]);
    mat_apply(&space.from_xyz_nits, xyz).map(|c| c as f32)
}

/// An image in L_p u'v': three full-resolution planes, row by row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LpuvPlanes {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Bit depth of the luma codes (that of the curve that made them).
    pub bits: u32,
    /// Luminance codes.
    pub luma: Vec<u16>,
    /// u' codes.
    pub u: Vec<u8>,
    /// v' codes.
    pub v: Vec<u8>,
}

/// Encodes an image (its own primaries and `nits_per_unit`; alpha is dropped).
pub fn encode_image(curve: &dyn LumaCurve, image: &HdrImage) -> Result<LpuvPlanes> {
    let space = LinearRgb::of(&image.color)?;
    let n = image.pixel_count();
    let mut planes = LpuvPlanes {
        width: image.width(),
        height: image.height(),
        bits: curve.bits(),
        luma: Vec::with_capacity(n),
        u: Vec::with_capacity(n),
        v: Vec::with_capacity(n),
    };
    for rgb in image.rgb() {
        let pixel = encode_pixel(curve, &space, rgb);
        planes.luma.push(pixel.luma);
        planes.u.push(pixel.u);
        planes.v.push(pixel.v);
    }
    Ok(planes)
}

/// Decodes planes to an RGB image in `color`'s primaries and units. Errors: planes whose
/// lengths are not width·height, or whose bit depth is not the curve's.
pub fn decode_image(curve: &dyn LumaCurve, planes: &LpuvPlanes, color: ColorInfo) -> Result<HdrImage> {
    let space = LinearRgb::of(&color)?;
    let n = u64::from(planes.width) * u64::from(planes.height);
    let lengths = [planes.luma.len(), planes.u.len(), planes.v.len()];
    if lengths.iter().any(|&len| len as u64 != n) {
        return Err(Error::invalid(format!(
            "L_p u'v' planes of {lengths:?} samples for a {}×{} image",
            planes.width, planes.height
        )));
    }
    if planes.bits != curve.bits() {
        return Err(Error::invalid(format!(
            "L_p u'v' planes of {}-bit luma decoded with a {}-bit {} curve",
            planes.bits,
            curve.bits(),
            curve.name()
        )));
    }
    let mut samples = Vec::with_capacity(3 * planes.luma.len());
    for ((&luma, &u), &v) in planes.luma.iter().zip(&planes.u).zip(&planes.v) {
        samples.extend_from_slice(&decode_pixel(curve, &space, LpuvPixel { luma, u, v }));
    }
    HdrImage::new(planes.width, planes.height, Channels::Rgb, samples, color)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mantiuk::{Psi04, PsiOptions};
    use hdrcodec_core::color::{xy_to_uv_prime, D65};
    use hdrcodec_core::Chromaticities;

    fn psi() -> Psi04 {
        Psi04::new(&PsiOptions::default()).unwrap()
    }

    #[test]
    fn black_is_the_lowest_code_with_d65_chromaticity() {
        let space = LinearRgb::new(ColorPrimaries::Bt709, 100.0).unwrap();
        let black = encode_pixel(&psi(), &space, [0.0; 3]);
        let [u, v] = xy_to_uv_prime(D65);
        assert_eq!(black, LpuvPixel { luma: 0, u: (u * 410.0).round() as u8, v: (v * 410.0).round() as u8 });
        assert_eq!((black.u, black.v), (81, 192));
        // It decodes to the curve's floor, neutral.
        let back = decode_pixel(&psi(), &space, black);
        let y = back[0] * 0.2126 + back[1] * 0.7152 + back[2] * 0.0722;
        assert!((f64::from(y) * 100.0 / 1e-4 - 1.0).abs() < 1e-3, "{back:?}");
    }

    #[test]
    fn bad_samples_follow_the_input_rules() {
        let space = LinearRgb::new(ColorPrimaries::Bt709, 100.0).unwrap();
        let curve = psi();
        let black = encode_pixel(&curve, &space, [0.0; 3]);
        assert_eq!(encode_pixel(&curve, &space, [f32::NAN; 3]), black);
        assert_eq!(encode_pixel(&curve, &space, [-1.0, -5.0, f32::NEG_INFINITY]), black);
        // A negative component counts as 0: only the others remain.
        assert_eq!(encode_pixel(&curve, &space, [1.0, -1.0, 0.0]), encode_pixel(&curve, &space, [1.0, 0.0, 0.0]));
        let bright = encode_pixel(&curve, &space, [f32::INFINITY, f32::INFINITY, f32::INFINITY]);
        assert_eq!(bright.luma, 2047);
        assert_eq!((bright.u, bright.v), (81, 192));
    }

    #[test]
    fn visible_colours_need_no_chroma_clamping_and_imaginary_ones_clamp() {
        // Each primary alone, at full strength: real primaries are inside the spectral locus,
        // so 410·u' and 410·v' stay within 255 without clamping.
        for primaries in
            [ColorPrimaries::Bt709, ColorPrimaries::Bt2020, ColorPrimaries::DisplayP3, ColorPrimaries::AcesAp1]
        {
            let space = LinearRgb::new(primaries, 100.0).unwrap();
            for rgb in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
                let xyz = mat_apply(&primaries.rgb_to_xyz(), rgb.map(f64::from));
                let [u, v] = xyz_to_uv_prime(xyz);
                assert!(u * 410.0 < 255.5 && v * 410.0 < 255.5 && u > 0.0 && v > 0.0, "{primaries:?} {rgb:?}");
                let p = encode_pixel(&psi(), &space, rgb);
                assert_eq!((p.u, p.v), ((u * 410.0).round() as u8, (v * 410.0).round() as u8));
            }
        }
        // X alone has u' = 4: clamped to 255. AP0's blue primary has v' < 0: clamped to 0.
        let xyz = LinearRgb::new(ColorPrimaries::Xyz, 100.0).unwrap();
        assert_eq!(encode_pixel(&psi(), &xyz, [1.0, 0.0, 0.0]).u, 255);
        let ap0 = LinearRgb::new(ColorPrimaries::AcesAp0, 100.0).unwrap();
        assert_eq!(encode_pixel(&psi(), &ap0, [0.0, 0.0, 1.0]).v, 0);
    }

    #[test]
    fn bad_spaces_and_planes_are_errors() {
        assert!(LinearRgb::new(ColorPrimaries::Bt709, 0.0).is_err());
        assert!(LinearRgb::new(ColorPrimaries::Bt709, f32::NAN).is_err());
        let collinear = Chromaticities { red: [0.1, 0.1], green: [0.2, 0.2], blue: [0.3, 0.3], white: D65 };
        assert!(LinearRgb::new(ColorPrimaries::Custom(collinear), 100.0).is_err());
        let curve = psi();
        let planes = LpuvPlanes { width: 2, height: 1, bits: 11, luma: vec![0; 2], u: vec![81; 2], v: vec![192] };
        assert!(decode_image(&curve, &planes, ColorInfo::default()).is_err());
        let planes = LpuvPlanes { v: vec![192; 2], bits: 12, ..planes };
        assert!(decode_image(&curve, &planes, ColorInfo::default()).is_err());
        let planes = LpuvPlanes { bits: 11, ..planes };
        assert!(decode_image(&curve, &planes, ColorInfo::default()).is_ok());
    }
}
