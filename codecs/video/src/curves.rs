//! The common interface of the luminance ↔ integer-code curves ([`LumaCurve`]) and the two
//! simple ones: PQ with full-range codes ([`PqCurve`]) and a plain logarithm ([`LogCurve`]).
//! The perceptual curves live in [`crate::mantiuk`] (ψ, 2004), [`crate::mantiuk06`] (2006) and
//! [`crate::gsdf`] (DICOM).

use std::fmt;

use hdrcodec_core::{Error, PqTransfer, Result};

/// The bit depths a curve can be built for. Below 8 bits none of these curves is of use
/// for images, and codes are `u16`.
pub const BITS: std::ops::RangeInclusive<u32> = 8..=16;

/// A luminance ↔ code mapping at a fixed bit depth: luminance in cd/m² to an integer code in
/// 0 ..= 2^bits − 1 and back.
///
/// Every implementation clamps: luminance below the curve's range (and NaN) encodes to code 0,
/// above it to the top code; a code above the top code decodes as the top code. Nothing
/// panics.
pub trait LumaCurve: Send + Sync + fmt::Debug {
    /// A short name for tables and messages ("psi04", "mantiuk06", "pq", "gsdf", "log").
    fn name(&self) -> &'static str;
    /// The bit depth the codes use.
    fn bits(&self) -> u32;
    /// Luminance (cd/m²) → code.
    fn encode(&self, nits: f64) -> u16;
    /// Code → luminance (cd/m²).
    fn decode(&self, code: u16) -> f64;
    /// The largest code, 2^bits − 1.
    fn max_code(&self) -> u16 {
        max_code(self.bits())
    }
}

/// 2^bits − 1 for a bit depth already checked by [`check_bits`].
pub(crate) fn max_code(bits: u32) -> u16 {
    ((1u32 << bits) - 1) as u16
}

/// `Ok(bits)` inside [`BITS`], an [`Error::Invalid`] naming the curve otherwise.
pub(crate) fn check_bits(curve: &str, bits: u32) -> Result<u32> {
    if BITS.contains(&bits) {
        Ok(bits)
    } else {
        Err(Error::invalid(format!(
            "{curve}: {bits} bits is outside the supported {}..={} bits",
            BITS.start(),
            BITS.end()
        )))
    }
}

/// `Ok` when `0 < min < max < ∞`, an [`Error::Invalid`] naming the curve otherwise.
pub(crate) fn check_range(curve: &str, min_nits: f64, max_nits: f64) -> Result<()> {
    if min_nits > 0.0 && max_nits > min_nits && max_nits.is_finite() {
        Ok(())
    } else {
        Err(Error::invalid(format!(
            "{curve}: the luminance range {min_nits}..{max_nits} cd/m² must satisfy 0 < min < max < ∞"
        )))
    }
}

/// Rounds a code already within 0 ..= max as a float (NaN → 0) to the nearest integer code.
pub(crate) fn round_code(code: f64, max: u16) -> u16 {
    if code.is_nan() {
        0
    } else {
        code.round().clamp(0.0, f64::from(max)) as u16
    }
}

/// SMPTE ST 2084 (PQ) with full-range codes: code = round(PQ⁻¹(L)·(2^bits − 1)), 0–10 000 cd/m².
/// The curve itself is core's [`PqTransfer`]; this only quantizes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PqCurve {
    bits: u32,
}

impl PqCurve {
    /// PQ at `bits` bits (8..=16).
    pub fn new(bits: u32) -> Result<Self> {
        Ok(PqCurve { bits: check_bits("pq", bits)? })
    }
}

impl LumaCurve for PqCurve {
    fn name(&self) -> &'static str {
        "pq"
    }
    fn bits(&self) -> u32 {
        self.bits
    }
    fn encode(&self, nits: f64) -> u16 {
        let max = self.max_code();
        round_code(PqTransfer::encode(nits) * f64::from(max), max)
    }
    fn decode(&self, code: u16) -> f64 {
        let max = self.max_code();
        PqTransfer::decode(f64::from(code.min(max)) / f64::from(max))
    }
}

/// A plain logarithm: code = round((2^bits − 1)·ln(L/L_min)/ln(L_max/L_min)), so that every
/// code step is the same luminance ratio. The reference point against which the perceptual
/// curves show what they save.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogCurve {
    bits: u32,
    ln_min: f64,
    ln_max: f64,
}

impl LogCurve {
    /// A logarithmic curve over `min_nits..=max_nits` at `bits` bits.
    pub fn new(bits: u32, min_nits: f64, max_nits: f64) -> Result<Self> {
        check_bits("log", bits)?;
        check_range("log", min_nits, max_nits)?;
        Ok(LogCurve { bits, ln_min: min_nits.ln(), ln_max: max_nits.ln() })
    }
}

impl LumaCurve for LogCurve {
    fn name(&self) -> &'static str {
        "log"
    }
    fn bits(&self) -> u32 {
        self.bits
    }
    fn encode(&self, nits: f64) -> u16 {
        let max = self.max_code();
        // ln of 0 or a negative is −∞ or NaN, both clamp to code 0.
        let ln = if nits > 0.0 { nits.ln() } else { f64::NEG_INFINITY };
        let t = ((ln - self.ln_min) / (self.ln_max - self.ln_min)).clamp(0.0, 1.0);
        round_code(t * f64::from(max), max)
    }
    fn decode(&self, code: u16) -> f64 {
        let max = self.max_code();
        let t = f64::from(code.min(max)) / f64::from(max);
        (self.ln_min + t * (self.ln_max - self.ln_min)).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_outside_the_range_are_an_error() {
        for bits in [0, 7, 17, 32] {
            assert!(matches!(PqCurve::new(bits), Err(Error::Invalid { .. })));
            assert!(LogCurve::new(bits, 0.005, 1e4).is_err());
        }
        assert!(LogCurve::new(11, 0.0, 1e4).is_err());
        assert!(LogCurve::new(11, 10.0, 1.0).is_err());
        assert!(LogCurve::new(11, 1.0, f64::INFINITY).is_err());
    }

    #[test]
    fn pq_codes_of_the_notes() {
        // VIDEO-NOTES §2.1: full-range 10-bit PQ puts 100 cd/m² at 519.8, 1000 at 769.1.
        let pq = PqCurve::new(10).unwrap();
        assert_eq!(pq.encode(100.0), 520);
        assert_eq!(pq.encode(1000.0), 769);
        assert_eq!(pq.encode(1e4), 1023);
        assert_eq!(pq.encode(f64::NAN), 0);
        assert_eq!(pq.encode(-1.0), 0);
        assert_eq!(pq.decode(0), 0.0);
        assert!((pq.decode(1023) - 1e4).abs() < 1e-6);
    }

    #[test]
    fn log_has_a_constant_ratio_step() {
        // VIDEO-NOTES §2.1: 0.71 % per code at 11 bits over 0.005–10⁴.
        let log = LogCurve::new(11, 0.005, 1e4).unwrap();
        for c in [0u16, 700, 2046] {
            let ratio = log.decode(c + 1) / log.decode(c) - 1.0;
            assert!((ratio - 0.0071).abs() < 0.0001, "{ratio}");
        }
        assert!((log.decode(0) - 0.005).abs() < 1e-12);
        assert!((log.decode(2047) / 1e4 - 1.0).abs() < 1e-12);
        assert_eq!(log.encode(0.0), 0);
        assert_eq!(log.encode(1e9), 2047);
        assert_eq!(log.decode(u16::MAX), log.decode(2047));
    }

    #[test]
    fn codes_round_trip() {
        let curves: [&dyn LumaCurve; 2] = [&PqCurve::new(12).unwrap(), &LogCurve::new(12, 1e-4, 1e8).unwrap()];
        for curve in curves {
            for c in 0..=curve.max_code() {
                assert_eq!(curve.encode(curve.decode(c)), c, "{} code {c}", curve.name());
            }
        }
    }
}
