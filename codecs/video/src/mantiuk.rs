//! ψ, the luma of Mantiuk, Krawczyk, Myszkowski & Seidel, "Perception-motivated High Dynamic
//! Range Video Encoding", SIGGRAPH 2004: the curve whose every code step is the same fraction
//! of the detection threshold of [`ferwerda_tvi`] at that luminance,
//!
//! > dψ/dl = k · tvi(ψ(l)),  ψ(0) = L_min,  ψ(2ⁿ − 1) = L_max,
//!
//! so that the quantization error is the same fraction of visibility everywhere. The paper
//! writes k = 2/f with a safety factor f (as recalled in VIDEO-NOTES §1.3; the paper's body
//! could not be read); here k follows from the bit depth and the range
//! instead, and [`Psi04::step_scale`] reports it (f = 2/k).
//!
//! ψ has no closed form. [`Psi04::new`] tabulates it once, 2ⁿ entries, by one of two
//! constructions ([`PsiIntegration`]): the continuous ODE (the definition above), or the
//! discrete recurrence ψ(l+1) = ψ(l) + k·tvi(ψ(l)) that LumaHDRv uses for its published tables
//! (Eilertsen, Mantiuk & Unger, `ptf_jnd_ferwerda_*bit.h`), which it reproduces.

use hdrcodec_core::Result;

use crate::curves::{check_bits, check_range, max_code, LumaCurve};
use crate::tvi::{ferwerda_tvi, BRANCH_ENDS_LOG10};

/// How the table of ψ is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PsiIntegration {
    /// The ODE dψ/dl = k·tvi(ψ) integrated accurately (Runge–Kutta in ln L), k chosen so that
    /// the last code lands on L_max: each step is k times the *average* threshold over it.
    #[default]
    Continuous,
    /// LumaHDRv's recurrence ψ(l+1) = ψ(l) + k·tvi(ψ(l)) (explicit Euler with one step per
    /// code), k chosen the same way: each step is exactly k times the threshold at its lower
    /// end. Use it with [`PsiOptions::lumahdrv`] to get LumaHDRv's tables.
    LumaHdrvRecurrence,
}

/// The parameters of ψ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PsiOptions {
    /// Bit depth of the codes, 8..=16. The paper's curve is 11 bits.
    pub bits: u32,
    /// Luminance of code 0, cd/m².
    pub min_nits: f64,
    /// Luminance of the top code, cd/m².
    pub max_nits: f64,
    /// Continuous ODE or LumaHDRv's recurrence.
    pub integration: PsiIntegration,
}

impl Default for PsiOptions {
    /// The paper's curve as its abstract states it: 11 bits over "12 orders of magnitude of
    /// visible luminance", taken as 10⁻⁴ … 10⁸ cd/m² (the exact endpoints are in the paper's
    /// body, which could not be read; VIDEO-NOTES §1.3).
    fn default() -> Self {
        PsiOptions { bits: 11, min_nits: 1e-4, max_nits: 1e8, integration: PsiIntegration::Continuous }
    }
}

impl PsiOptions {
    /// LumaHDRv's "PSI" transfer: 0.005 … 10 000 cd/m², the discrete recurrence. At 11 bits
    /// this is the table of its `ptf_jnd_ferwerda_11bit.h`.
    pub fn lumahdrv(bits: u32) -> Self {
        PsiOptions { bits, min_nits: 0.005, max_nits: 1e4, integration: PsiIntegration::LumaHdrvRecurrence }
    }
}

/// The tabulated ψ at one bit depth and range.
#[derive(Clone, Debug)]
pub struct Psi04 {
    bits: u32,
    /// ψ(l) for every code l, increasing.
    table: Vec<f64>,
    /// The decision points of the encoder: `midpoints[l]` = (ψ(l) + ψ(l+1)) / 2.
    midpoints: Vec<f64>,
    /// The k of dψ/dl = k·tvi(ψ).
    k: f64,
}

/// ln L advances by d(ln L)/ds = tvi(L)/L per unit of s, where s counts thresholds
/// (s = ∫ dL/tvi): ψ at code l is the luminance at s = k·l. Integrating in ln L keeps the
/// relative accuracy uniform over 15 decades.
fn ln_slope(ln_l: f64) -> f64 {
    let l = ln_l.exp();
    ferwerda_tvi(l) / l
}

/// One classical Runge–Kutta step of size `h` (in threshold units) on ln L.
fn rk4(ln_l: f64, h: f64) -> f64 {
    let k1 = ln_slope(ln_l);
    let k2 = ln_slope(ln_l + 0.5 * h * k1);
    let k3 = ln_slope(ln_l + 0.5 * h * k2);
    let k4 = ln_slope(ln_l + h * k3);
    ln_l + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
}

/// The largest step the integrator takes, in thresholds. In ln L that is at most 0.22 (on the
/// rod floor near 10⁻⁴ cd/m², where tvi/L ≈ 14) and under 0.01 above 0.1 cd/m²; the tests check
/// that the integration lands on L_max to 10⁻⁹.
const MAX_STEP_THRESHOLDS: f64 = 1.0 / 64.0;

/// The step `h` ≤ [`MAX_STEP_THRESHOLDS`] from `ln_l` that lands exactly on `ln_target`
/// (bisection; the caller knows a full step would pass it).
fn step_to(ln_l: f64, ln_target: f64, h: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, h);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if rk4(ln_l, mid) < ln_target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The ODE solved on a grid of s (thresholds counted from `min_nits`): pairs (s, ln L) from
/// `min_nits` to `max_nits`, steps of [`MAX_STEP_THRESHOLDS`] except that the grid stops
/// exactly on every branch end of the tvi and on `max_nits`. Runge–Kutta is only accurate on
/// a smooth right-hand side; the tvi jumps at two branch ends (2.8 % at 10^−1.44 cd/m²), and a
/// step across a jump would misplace the next codes by up to that fraction of a step.
fn trajectory(min_nits: f64, max_nits: f64) -> Vec<(f64, f64)> {
    let ln_end = max_nits.ln();
    let mut stops: Vec<f64> = BRANCH_ENDS_LOG10
        .iter()
        .map(|x| x * std::f64::consts::LN_10)
        .filter(|&k| k > min_nits.ln() && k < ln_end)
        .collect();
    stops.push(ln_end);
    let mut grid = vec![(0.0, min_nits.ln())];
    let (mut s, mut ln_l) = grid[0];
    for stop in stops {
        loop {
            let next = rk4(ln_l, MAX_STEP_THRESHOLDS);
            if next >= stop {
                s += step_to(ln_l, stop, MAX_STEP_THRESHOLDS);
                ln_l = stop;
                grid.push((s, ln_l));
                break;
            }
            s += MAX_STEP_THRESHOLDS;
            ln_l = next;
            grid.push((s, ln_l));
        }
    }
    grid
}

/// ln ψ(l) for l = 0 … `codes` − 1 by the continuous ODE, and its k. Each entry is one partial
/// Runge–Kutta step from the grid point below it, which never crosses a branch end of the tvi,
/// and the last code lands on L_max because the grid ends there. The last entry is the
/// integrator's own (not forced to L_max), so that tests can see how closely it lands.
fn continuous_ln_table(codes: usize, min_nits: f64, max_nits: f64) -> (Vec<f64>, f64) {
    let grid = trajectory(min_nits, max_nits);
    let total = grid[grid.len() - 1].0;
    let k = total / (codes - 1) as f64;
    let table = (0..codes)
        .map(|l| {
            let s = k * l as f64;
            let i = grid.partition_point(|&(at, _)| at <= s).saturating_sub(1);
            let (at, ln_l) = grid[i];
            if s >= total {
                ln_l
            } else {
                rk4(ln_l, s - at)
            }
        })
        .collect();
    (table, k)
}

/// The end of LumaHDRv's recurrence after `codes` − 1 steps of k, or `None` once it passes
/// `max_nits` (which is all the search for k needs to know, and keeps ψ finite).
fn recurrence_end(codes: usize, min_nits: f64, max_nits: f64, k: f64) -> Option<f64> {
    let mut l = min_nits;
    for _ in 1..codes {
        l += k * ferwerda_tvi(l);
        if l > max_nits {
            return None;
        }
    }
    Some(l)
}

/// ψ(l) for l = 0 … `codes` − 1 by the recurrence, and its k: k is found by bisection so that
/// the last entry is `max_nits` (the recurrence's end grows monotonically with k).
fn recurrence_table(codes: usize, min_nits: f64, max_nits: f64) -> (Vec<f64>, f64) {
    let mut hi = 1e-3;
    while recurrence_end(codes, min_nits, max_nits, hi).is_some() {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if recurrence_end(codes, min_nits, max_nits, mid).is_some() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let k = lo;
    let mut table = Vec::with_capacity(codes);
    let mut l = min_nits;
    table.push(l);
    for _ in 1..codes {
        l += k * ferwerda_tvi(l);
        table.push(l);
    }
    (table, k)
}

impl Psi04 {
    /// Tabulates ψ. Costs a few milliseconds at 11 bits (about 10⁵ evaluations of the tvi);
    /// build it once and share it. Errors: bits outside 8..=16, or a range that is not
    /// 0 < min < max < ∞.
    pub fn new(options: &PsiOptions) -> Result<Self> {
        let bits = check_bits("psi04", options.bits)?;
        check_range("psi04", options.min_nits, options.max_nits)?;
        let codes = usize::from(max_code(bits)) + 1;
        let (mut table, k) = match options.integration {
            PsiIntegration::Continuous => {
                let (ln_table, k) = continuous_ln_table(codes, options.min_nits, options.max_nits);
                (ln_table.into_iter().map(f64::exp).collect::<Vec<_>>(), k)
            }
            PsiIntegration::LumaHdrvRecurrence => recurrence_table(codes, options.min_nits, options.max_nits),
        };
        // Both constructions land within 10⁻⁹ relative of the requested ends (see the tests);
        // pin them so that the range is exactly what was asked for.
        table[0] = options.min_nits;
        table[codes - 1] = options.max_nits;
        let midpoints = table.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        Ok(Psi04 { bits, table, midpoints, k })
    }

    /// ψ(l) for every code l (2^bits entries, increasing), cd/m².
    pub fn table(&self) -> &[f64] {
        &self.table
    }

    /// k of dψ/dl = k·tvi(ψ(l)): a code step is k thresholds, the worst-case error (half a
    /// step) k/2 thresholds. The paper's safety factor is f = 2/k.
    pub fn step_scale(&self) -> f64 {
        self.k
    }
}

impl LumaCurve for Psi04 {
    fn name(&self) -> &'static str {
        "psi04"
    }

    fn bits(&self) -> u32 {
        self.bits
    }

    /// The nearest table entry in *luminance*: the decision point between codes l and l+1 is
    /// their arithmetic mean. Why not the nearest in log luminance, which treats errors as
    /// contrast: the paper's criterion is that the error, at most half a step in cd/m², stays
    /// under the threshold of an eye adapted to that very pixel. Both candidates are judged
    /// against the same tvi(L), so the better one is the one nearer in cd/m², and only the
    /// arithmetic midpoint keeps every error within half a step (a geometric midpoint lies
    /// below it and sends some values to the upper entry from more than half a step away).
    /// The two midpoints are r/8 of a step apart for a relative step r: under 1 % of a step for
    /// the default 11-bit ψ above 0.01 cd/m², 14 % at 10⁻⁴ cd/m², where a step is twice its
    /// luminance.
    fn encode(&self, nits: f64) -> u16 {
        // `<=` is false for NaN, so NaN encodes as code 0, like any luminance below ψ(0).
        self.midpoints.partition_point(|&m| m <= nits) as u16
    }

    fn decode(&self, code: u16) -> f64 {
        self.table[usize::from(code.min(self.max_code()))]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_continuous_integration_lands_on_its_end() {
        for (min, max) in [(1e-4, 1e8), (0.005, 1e4), (1e-5, 1e10)] {
            for codes in [256, 2048, 65536] {
                let (table, _) = continuous_ln_table(codes, min, max);
                let end = table[codes - 1].exp();
                assert!((end / max - 1.0).abs() < 1e-9, "{codes} codes over {min}..{max} end at {end}");
            }
        }
    }

    #[test]
    fn the_recurrence_lands_on_its_end() {
        let (table, _) = recurrence_table(2048, 0.005, 1e4);
        assert!((table[2047] / 1e4 - 1.0).abs() < 1e-9, "{}", table[2047]);
    }

    #[test]
    fn bad_options_are_errors() {
        let bad = [
            PsiOptions { bits: 7, ..PsiOptions::default() },
            PsiOptions { bits: 17, ..PsiOptions::default() },
            PsiOptions { min_nits: 0.0, ..PsiOptions::default() },
            PsiOptions { min_nits: f64::NAN, ..PsiOptions::default() },
            PsiOptions { max_nits: 1e-5, ..PsiOptions::default() },
            PsiOptions { max_nits: f64::INFINITY, ..PsiOptions::default() },
        ];
        for options in bad {
            assert!(Psi04::new(&options).is_err(), "{options:?}");
        }
    }

    #[test]
    fn encode_clamps_and_takes_the_nearest_in_luminance() {
        let psi = Psi04::new(&PsiOptions::default()).unwrap();
        assert_eq!(psi.encode(0.0), 0);
        assert_eq!(psi.encode(-3.0), 0);
        assert_eq!(psi.encode(f64::NAN), 0);
        assert_eq!(psi.encode(f64::INFINITY), 2047);
        assert_eq!(psi.decode(u16::MAX), 1e8);
        let (a, b) = (psi.decode(300), psi.decode(301));
        assert_eq!(psi.encode(a + 0.49 * (b - a)), 300);
        assert_eq!(psi.encode(a + 0.51 * (b - a)), 301);
    }
}
