//! The closed-form HDR luma of Mantiuk, Efremov, Myszkowski & Seidel, "Backward compatible
//! high dynamic range MPEG video compression", SIGGRAPH 2006 (the l_hdr of its residual
//! stream): linear, then power, then logarithmic in luminance, 12 bits over 10⁻⁵ … 10¹⁰ cd/m²,
//! with a published closed-form inverse.
//!
//! This is the curve that often circulates as "Mantiuk's luma"; it is not the 2004 ψ
//! ([`crate::mantiuk::Psi04`]): it comes from a CSF-based threshold rather than Ferwerda's tvi,
//! spans 15 decades in 12 bits, and its linear toe takes 0.057 cd/m² steps (everything below
//! 0.028 cd/m² is code 0). Only the constant set with a published inverse ("set A" in
//! VIDEO-NOTES §1.6) is implemented; a second set that circulates could not be tied to a paper.
//! The attribution of set A to the 2006 paper is from recollection (VIDEO-NOTES §1.6) and
//! still to be confirmed against the PDF.

use hdrcodec_core::Result;

use crate::curves::{check_bits, round_code, LumaCurve};

// The forward curve l(y), y in cd/m², l in 12-bit codes: Mantiuk et al. 2006, constants as
// transcribed in VIDEO-NOTES §1.6 (set A).
/// Slope of the linear segment, codes per cd/m².
const A: f64 = 17.554;
/// Scale of the power segment.
const B: f64 = 826.81;
/// Exponent of the power segment.
const C: f64 = 0.10013;
/// Offset of the power segment.
const D: f64 = -884.17;
/// Scale of the logarithmic segment (natural log).
const E: f64 = 209.16;
/// Offset of the logarithmic segment.
const F: f64 = -731.28;
/// Luminance where the linear segment ends, cd/m².
const Y_L: f64 = 5.6046;
/// Luminance where the logarithmic segment starts, cd/m².
const Y_H: f64 = 10469.0;

// The published inverse y(l), same source.
/// Slope of the inverse's linear segment, cd/m² per code.
const A_INV: f64 = 0.056968;
/// Scale of the inverse's power segment.
const B_INV: f64 = 7.3014e-30;
/// Exponent of the inverse's power segment.
const C_INV: f64 = 9.9872;
/// Offset of the inverse's power segment.
const D_INV: f64 = 884.17;
/// Scale of the inverse's exponential segment, cd/m².
const E_INV: f64 = 32.994;
/// Rate of the inverse's exponential segment, per code.
const F_INV: f64 = 0.0047811;
/// Code where the inverse's linear segment ends.
const L_L: f64 = 98.381;
/// Code where the inverse's exponential segment starts.
const L_H: f64 = 1204.7;

/// The paper's luma in 12-bit code units (not rounded): l(y) for y in cd/m².
/// Zero, negative and NaN luminance give 0.
pub fn luma_12bit(nits: f64) -> f64 {
    if nits.is_nan() || nits <= 0.0 {
        0.0
    } else if nits < Y_L {
        A * nits
    } else if nits < Y_H {
        B * nits.powf(C) + D
    } else {
        E * nits.ln() + F
    }
}

/// The paper's inverse: luminance in cd/m² of a 12-bit luma value (not necessarily an
/// integer). It inverts [`luma_12bit`] to 0.045 % (worst just below y_h = 10 469 cd/m²), not exactly: both are fits.
pub fn nits_of_luma_12bit(luma: f64) -> f64 {
    if luma.is_nan() || luma <= 0.0 {
        0.0
    } else if luma < L_L {
        A_INV * luma
    } else if luma < L_H {
        B_INV * (luma + D_INV).powf(C_INV)
    } else {
        E_INV * (F_INV * luma).exp()
    }
}

/// The 2006 luma quantized at `bits` bits: the 12-bit curve scaled by (2ⁿ − 1)/4095, so that
/// 12 bits is the paper's curve and other depths keep its shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mantiuk06 {
    bits: u32,
}

impl Mantiuk06 {
    /// The curve at `bits` bits (8..=16); the paper's is 12.
    pub fn new(bits: u32) -> Result<Self> {
        Ok(Mantiuk06 { bits: check_bits("mantiuk06", bits)? })
    }

    /// Codes of this depth per 12-bit code unit.
    fn scale(&self) -> f64 {
        f64::from(self.max_code()) / 4095.0
    }
}

impl LumaCurve for Mantiuk06 {
    fn name(&self) -> &'static str {
        "mantiuk06"
    }
    fn bits(&self) -> u32 {
        self.bits
    }
    fn encode(&self, nits: f64) -> u16 {
        round_code(luma_12bit(nits) * self.scale(), self.max_code())
    }
    fn decode(&self, code: u16) -> f64 {
        nits_of_luma_12bit(f64::from(code.min(self.max_code())) / self.scale())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_join_at_the_breakpoints() {
        // Forward: both sides of y_l and y_h agree to a hundredth of a code (VIDEO-NOTES §1.6).
        assert!((A * Y_L - (B * Y_L.powf(C) + D)).abs() < 0.02);
        assert!((B * Y_H.powf(C) + D - (E * Y_H.ln() + F)).abs() < 0.02);
        // Inverse: both sides of l_l and l_h agree to 0.05 %.
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(A_INV * L_L, B_INV * (L_L + D_INV).powf(C_INV)) < 5e-4);
        assert!(rel(B_INV * (L_H + D_INV).powf(C_INV), E_INV * (F_INV * L_H).exp()) < 5e-4);
        // And the breakpoints correspond: l(y_l) = l_l, l(y_h) = l_h.
        assert!((luma_12bit(Y_L) - L_L).abs() < 0.02);
        assert!((luma_12bit(Y_H) - L_H).abs() < 0.1);
    }

    #[test]
    fn covers_fifteen_decades_in_twelve_bits() {
        assert!(luma_12bit(1e-5) < 0.001);
        // VIDEO-NOTES §1.6: l(10¹⁰) ≈ 4085 for set A.
        assert!((luma_12bit(1e10) - 4085.0).abs() < 1.0, "{}", luma_12bit(1e10));
    }

    #[test]
    fn the_inverse_undoes_the_forward_curve() {
        let mut y = 0.03;
        while y < 1e10 {
            let back = nits_of_luma_12bit(luma_12bit(y));
            assert!((back / y - 1.0).abs() < 4.5e-4, "{y} → {back}");
            y *= 1.07;
        }
    }

    #[test]
    fn codes_round_trip_and_bad_input_clamps() {
        for bits in [10, 12, 14] {
            let curve = Mantiuk06::new(bits).unwrap();
            for c in 0..=curve.max_code() {
                assert_eq!(curve.encode(curve.decode(c)), c, "{bits} bits, code {c}");
            }
        }
        let curve = Mantiuk06::new(12).unwrap();
        assert_eq!(curve.encode(0.02), 0);
        assert_eq!(curve.encode(f64::NAN), 0);
        assert_eq!(curve.encode(-1.0), 0);
        assert_eq!(curve.encode(f64::INFINITY), 4095);
        assert!(Mantiuk06::new(6).is_err());
    }
}
