//! How a curve's code steps compare with visibility thresholds, and how many bits a curve
//! needs: the test of Mantiuk et al. 2004's claim that ψ needs "only 10–11 bits" for 12
//! decades, and of the other curves against it.
//!
//! The criterion (VIDEO-NOTES §2): a luminance L between codes ψ(l) and ψ(l+1) is quantized
//! with an error of at most half the step, and that error must stay below T(L)/f, T a
//! threshold model and f ≥ 1 a safety factor. The error reaches half a step in the middle of
//! the step, so a curve is good enough when, for every step,
//! step / T(middle of the step) ≤ 2/f. With f = 2 that is "every step at most one threshold".
//!
//! The notes (and ψ's own recurrence) judge a step by the threshold at its lower end instead.
//! That is the same for fine steps but overstates coarse ones where T grows fast: the GSDF at
//! 10 bits, one JND per code by construction, would come out at 1.027 JND at its dark end, and
//! ψ at 9 bits at 0.70 tvi instead of its 0.60. (The GSDF's darkest step still comes out at
//! 1.022 JND with the middle: its JND index is a function of ln j, which bends sharply there.)

use hdrcodec_core::Result;

use crate::curves::{LumaCurve, BITS};
use crate::gsdf;
use crate::tvi::ferwerda_tvi;

/// A model of the smallest visible luminance difference at an adaptation luminance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThresholdModel {
    /// Ferwerda et al. 1996, rods and cones combined ([`ferwerda_tvi`]); defined everywhere.
    FerwerdaTvi,
    /// One JND of the DICOM GSDF ([`gsdf::jnd_threshold`]); defined from 0.05 to 3993 cd/m².
    GsdfJnd,
}

impl ThresholdModel {
    /// A short name for tables.
    pub fn name(&self) -> &'static str {
        match self {
            ThresholdModel::FerwerdaTvi => "Ferwerda tvi",
            ThresholdModel::GsdfJnd => "GSDF JND",
        }
    }

    /// The threshold ΔL in cd/m² at `nits`, `None` outside the model's domain.
    pub fn threshold(&self, nits: f64) -> Option<f64> {
        match self {
            ThresholdModel::FerwerdaTvi => (nits > 0.0).then(|| ferwerda_tvi(nits)),
            ThresholdModel::GsdfJnd => gsdf::jnd_threshold(nits),
        }
    }

    /// The luminance range (cd/m²) where the model is defined.
    pub fn domain(&self) -> (f64, f64) {
        match self {
            ThresholdModel::FerwerdaTvi => (0.0, f64::INFINITY),
            ThresholdModel::GsdfJnd => (gsdf::luminance(gsdf::J_MIN), gsdf::luminance(gsdf::J_MAX)),
        }
    }
}

/// The worst step of `curve` over `min_nits..=max_nits` (narrowed to the model's domain), in
/// thresholds: max of (ψ(c+1) − ψ(c)) / T(m) over the steps that overlap the range, m the
/// middle of the step (ψ(c) + ψ(c+1))/2 kept inside the range. `None` when the curve does not reach both ends of the range or the
/// range and the model's domain do not overlap.
pub fn max_step_ratio(curve: &dyn LumaCurve, model: ThresholdModel, min_nits: f64, max_nits: f64) -> Option<f64> {
    let (lo, hi) = (min_nits.max(model.domain().0), max_nits.min(model.domain().1));
    // A curve whose end code is its range's end up to rounding (exp(ln L)) still covers it.
    let slack = 1e-9;
    if lo >= hi || curve.decode(0) > lo * (1.0 + slack) || curve.decode(curve.max_code()) < hi * (1.0 - slack) {
        return None;
    }
    let mut worst = 0f64;
    let mut lower = curve.decode(0);
    for c in 1..=curve.max_code() {
        let upper = curve.decode(c);
        if upper > lo && lower < hi {
            let middle = (0.5 * (lower + upper)).clamp(lo, hi);
            worst = worst.max((upper - lower) / model.threshold(middle)?);
        }
        if upper >= hi {
            break;
        }
        lower = upper;
    }
    Some(worst)
}

/// Builds a curve at a bit depth (over whatever range the caller fixed), so that
/// [`bits_needed`] can try several depths.
pub type CurveBuilder<'a> = dyn Fn(u32) -> Result<Box<dyn LumaCurve>> + 'a;

/// How many bits a curve needs for step ≤ (2/f)·T everywhere in a range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BitsNeeded {
    /// The smallest depth in 8..=16 at which the curve, built at that depth, meets the
    /// criterion; `None` when even 16 bits do not.
    pub whole: Option<u32>,
    /// The fractional depth at which the worst step would just meet it, extrapolated from 16
    /// bits: the 16-bit curve's worst ratio r asks for (2¹⁶ − 1)·r·f/2 steps, log2(steps + 1)
    /// bits. This is the figure for a curve fine enough that its steps scale as 1/(2ⁿ − 1)
    /// (the limit the paper's "n bits" speaks of) and it can go below 8 bits, where the curves
    /// are not built. A coarse curve's worst step can be a little larger or smaller than this
    /// predicts, so `whole` can differ from ⌈estimate⌉ by one.
    pub estimate: f64,
}

/// The bits `build` needs over `min_nits..=max_nits` under `model` with safety factor f
/// (criterion step ≤ (2/f)·T; f = 2 is "each step at most one threshold"). `Ok(None)` where
/// [`max_step_ratio`] is `None`.
pub fn bits_needed(
    build: &CurveBuilder,
    model: ThresholdModel,
    min_nits: f64,
    max_nits: f64,
    safety_factor: f64,
) -> Result<Option<BitsNeeded>> {
    let limit = 2.0 / safety_factor;
    let finest = build(*BITS.end())?;
    let Some(ratio) = max_step_ratio(finest.as_ref(), model, min_nits, max_nits) else {
        return Ok(None);
    };
    let estimate = (f64::from(finest.max_code()) * ratio / limit + 1.0).log2();
    let mut whole = None;
    for bits in BITS {
        let curve = if bits == *BITS.end() { None } else { Some(build(bits)?) };
        let curve = curve.as_deref().unwrap_or(finest.as_ref());
        if max_step_ratio(curve, model, min_nits, max_nits).is_some_and(|r| r <= limit) {
            whole = Some(bits);
            break;
        }
    }
    Ok(Some(BitsNeeded { whole, estimate }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curves::{LogCurve, PqCurve};
    use crate::gsdf::GsdfCurve;

    #[test]
    fn a_log_curve_s_worst_step_is_its_ratio_over_the_weber_fraction() {
        // Above 10^1.9 cd/m² Ferwerda's tvi is w·L with w = 10^−1.255, so a log curve's steps,
        // from a to r·a, are (r − 1)·a against a threshold of w·(1 + r)·a/2 in their middle.
        let log = LogCurve::new(11, 100.0, 1e4).unwrap();
        let r = ((1e4f64 / 100.0).ln() / 2047.0).exp();
        let expected = 2.0 * (r - 1.0) / (10f64.powf(-1.255) * (1.0 + r));
        let got = max_step_ratio(&log, ThresholdModel::FerwerdaTvi, 100.0, 1e4).unwrap();
        assert!((got / expected - 1.0).abs() < 1e-9, "{got} vs {expected}");
    }

    #[test]
    fn the_gsdf_is_one_jnd_per_code_at_10_bits() {
        let gsdf = GsdfCurve::new(10).unwrap();
        let (lo, hi) = ThresholdModel::GsdfJnd.domain();
        let r = max_step_ratio(&gsdf, ThresholdModel::GsdfJnd, lo, hi).unwrap();
        // A 10-bit code is 1022/1023 of a JND index, but the threshold dL/dj in the middle of
        // a step is not the step's average slope where L(j) bends most: at the dark end, where
        // the standard's function of ln j advances by ln 2 from j = 1 to 2. There the worst
        // step is 1.022 JND.
        assert!(r > 1022.0 / 1023.0 && r < 1.025, "{r}");
    }

    #[test]
    fn curves_that_do_not_cover_the_range_have_no_ratio() {
        let pq = PqCurve::new(12).unwrap();
        assert_eq!(max_step_ratio(&pq, ThresholdModel::FerwerdaTvi, 1e-4, 1e8), None);
        assert!(max_step_ratio(&pq, ThresholdModel::FerwerdaTvi, 1e-4, 1e4).is_some());
        assert_eq!(max_step_ratio(&pq, ThresholdModel::GsdfJnd, 1e-4, 0.01), None);
        let build = |bits| Ok(Box::new(PqCurve::new(bits)?) as Box<dyn LumaCurve>);
        assert_eq!(bits_needed(&build, ThresholdModel::FerwerdaTvi, 1e-4, 1e8, 2.0).unwrap(), None);
    }
}
