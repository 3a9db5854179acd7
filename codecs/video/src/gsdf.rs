//! The Grayscale Standard Display Function of DICOM PS3.14 (§7): luminance as a function of
//! the JND index j = 1 … 1023, one step of j being one just-noticeable difference of Barten's
//! model for a standard target, from 0.05 to about 4000 cd/m². Here it is a comparison curve
//! ([`GsdfCurve`]) and a second threshold model ([`jnd_threshold`]), the "exactly at threshold"
//! reference against which ψ and PQ are judged.

use hdrcodec_core::Result;

use crate::curves::{check_bits, round_code, LumaCurve};

/// The numerator coefficients of the GSDF (PS3.14 §7) for log10 L(j) as a rational function of
/// u = ln j: a, c, e, g, m (constants as in DCMTK's `DiGSDFunction`, VIDEO-NOTES §2.1).
const NUMERATOR: [f64; 5] = [-1.3011877, 8.0242636e-2, 1.3646699e-1, -2.5468404e-2, 1.3635334e-3];
/// The denominator coefficients of the GSDF: 1, b, d, f, h, k.
const DENOMINATOR: [f64; 6] = [1.0, -2.5840191e-2, -1.0320229e-1, 2.8745620e-2, -3.1978977e-3, 1.2992634e-4];
/// The standard's inverse (eq. 7-2 as VIDEO-NOTES §2.1 numbers it; same source): j(L) = A + B·t + … + I·t⁸ with t = log10 L.
const INVERSE: [f64; 9] =
    [71.498068, 94.593053, 41.912053, 9.8247004, 0.28175407, -1.1878455, -0.18014349, 0.14710899, -0.017046845];
/// The JND indices the GSDF is defined for.
pub const J_MIN: f64 = 1.0;
/// See [`J_MIN`].
pub const J_MAX: f64 = 1023.0;

/// A polynomial's value and derivative at `x` (Horner), coefficients from the constant term up.
fn polynomial(coefficients: &[f64], x: f64) -> (f64, f64) {
    coefficients.iter().rev().fold((0.0, 0.0), |(value, slope), &c| (value * x + c, slope * x + value))
}

/// log10 L(j) and its derivative with respect to j.
fn log_luminance_and_slope(j: f64) -> (f64, f64) {
    let u = j.ln();
    let (n, dn) = polynomial(&NUMERATOR, u);
    let (d, dd) = polynomial(&DENOMINATOR, u);
    (n / d, (dn * d - n * dd) / (d * d) / j)
}

/// L(j) in cd/m² for a JND index j (clamped to 1 … 1023; NaN as 1): the GSDF of PS3.14 §7.
pub fn luminance(j: f64) -> f64 {
    let j = if j.is_nan() { J_MIN } else { j.clamp(J_MIN, J_MAX) };
    10f64.powf(log_luminance_and_slope(j).0)
}

/// The JND index of `nits`, clamped to the GSDF's range: eq. 7-2 as the starting point, then
/// Newton steps on the GSDF itself so that it inverts [`luminance`] to 10⁻⁹ of a JND (eq. 7-2 alone
/// is a separate fit and is off by up to a few tenths).
pub fn jnd_index(nits: f64) -> f64 {
    let (lo, hi) = (luminance(J_MIN), luminance(J_MAX));
    let target = if nits.is_nan() { lo } else { nits.clamp(lo, hi) }.log10();
    let mut j = polynomial(&INVERSE, target).0.clamp(J_MIN, J_MAX);
    for _ in 0..6 {
        let (value, slope) = log_luminance_and_slope(j);
        j = (j - (value - target) / slope).clamp(J_MIN, J_MAX);
    }
    j
}

/// One JND at `nits` in cd/m², dL/dj at j(L): the DICOM threshold model. `None` outside the
/// GSDF's range, L(1) ≈ 0.05 … L(1023) ≈ 3993 cd/m².
pub fn jnd_threshold(nits: f64) -> Option<f64> {
    if !(luminance(J_MIN)..=luminance(J_MAX)).contains(&nits) {
        return None;
    }
    let (log_l, slope) = log_luminance_and_slope(jnd_index(nits));
    Some(10f64.powf(log_l) * std::f64::consts::LN_10 * slope)
}

/// The GSDF as a luma curve: the 1022 JND steps spread evenly over the codes,
/// j = 1 + code·1022/(2ⁿ − 1). At 10 bits a code is 1022/1023 of a JND.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GsdfCurve {
    bits: u32,
}

impl GsdfCurve {
    /// The GSDF at `bits` bits (8..=16).
    pub fn new(bits: u32) -> Result<Self> {
        Ok(GsdfCurve { bits: check_bits("gsdf", bits)? })
    }

    /// JND indices per code.
    fn jnds_per_code(&self) -> f64 {
        (J_MAX - J_MIN) / f64::from(self.max_code())
    }
}

impl LumaCurve for GsdfCurve {
    fn name(&self) -> &'static str {
        "gsdf"
    }
    fn bits(&self) -> u32 {
        self.bits
    }
    fn encode(&self, nits: f64) -> u16 {
        round_code((jnd_index(nits) - J_MIN) / self.jnds_per_code(), self.max_code())
    }
    fn decode(&self, code: u16) -> f64 {
        luminance(J_MIN + f64::from(code.min(self.max_code())) * self.jnds_per_code())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_of_the_standard() {
        // VIDEO-NOTES §2.1: j = 1 gives 0.04998 and j = 1023 gives 3993.33 cd/m².
        assert!((luminance(1.0) - 0.04998).abs() < 1e-5, "{}", luminance(1.0));
        assert!((luminance(1023.0) - 3993.33).abs() < 0.01, "{}", luminance(1023.0));
    }

    #[test]
    fn the_published_inverse_agrees_with_the_forward_curve() {
        // eq. 7-2 is a fit of the GSDF's inverse; a few tenths of a JND apart at most.
        for j in [1.0, 10.0, 100.0, 500.0, 1000.0, 1023.0] {
            let fit = polynomial(&INVERSE, luminance(j).log10()).0;
            assert!((fit - j).abs() < 0.5, "j = {j}: eq. 7-2 gives {fit}");
            assert!((jnd_index(luminance(j)) - j).abs() < 1e-9);
        }
    }

    #[test]
    fn one_jnd_is_one_step_of_j() {
        // dL/dj against a central difference of L(j) itself.
        for j in [2.0, 50.0, 400.0, 1000.0] {
            let h = 1e-3;
            let slope = (luminance(j + h) - luminance(j - h)) / (2.0 * h);
            let t = jnd_threshold(luminance(j)).unwrap();
            assert!((t / slope - 1.0).abs() < 1e-5, "j = {j}: {t} vs {slope}");
        }
        assert_eq!(jnd_threshold(0.01), None);
        assert_eq!(jnd_threshold(5000.0), None);
        assert_eq!(jnd_threshold(f64::NAN), None);
    }

    #[test]
    fn codes_round_trip() {
        let gsdf = GsdfCurve::new(10).unwrap();
        for c in 0..=gsdf.max_code() {
            assert_eq!(gsdf.encode(gsdf.decode(c)), c);
        }
        assert_eq!(gsdf.encode(0.0), 0);
        assert_eq!(gsdf.encode(f64::NAN), 0);
        assert_eq!(gsdf.encode(1e6), 1023);
    }
}
