//! The threshold-versus-intensity (tvi) function of Ferwerda, Pattanaik, Shirley & Greenberg,
//! "A model of visual adaptation for realistic image synthesis", SIGGRAPH 1996: the smallest
//! luminance increment ΔL an observer adapted to L can detect, for rods and for cones.
//!
//! Mantiuk et al. 2004 build their luma ψ on this function, rods and cones combined by taking
//! the smaller threshold (whichever mechanism is more sensitive at that adaptation level).
//! Both branches are fed photopic luminance, as LumaHDRv does; Ferwerda states the rod branch
//! in scotopic units, and what the 2004 paper did there is not known (VIDEO-NOTES §1.2).

/// log10 of the luminances (cd/m²) where a branch of either mechanism ends. The tvi is
/// continuous at −3.94 and −2.6 but drops by 2.8 % at −1.44 and by 0.7 % at 1.9 (Ferwerda's
/// segments do not quite meet), so integrators must not step across these points.
pub const BRANCH_ENDS_LOG10: [f64; 4] = [-3.94, -2.6, -1.44, 1.9];

/// log10 of the rod threshold (cd/m²) at adaptation log10 L = `x`.
///
/// Ferwerda et al. 1996, the rod tvi: a floor below 10^−3.94, a power-law knee, Weber
/// behaviour (ΔL ∝ L) above 10^−1.44. Constants transcribed from the paper's fit as given in
/// VIDEO-NOTES §1.2.
fn log_rod_threshold(x: f64) -> f64 {
    if x <= -3.94 {
        -2.86
    } else if x < -1.44 {
        (0.405 * x + 1.6).powf(2.18) - 2.86
    } else {
        x - 0.395
    }
}

/// log10 of the cone threshold (cd/m²) at adaptation log10 L = `x`.
///
/// Ferwerda et al. 1996, the cone tvi: a floor below 10^−2.6, a knee, Weber behaviour above
/// 10^1.9 (a Weber fraction of 10^−1.255 ≈ 5.6 %).
fn log_cone_threshold(x: f64) -> f64 {
    if x <= -2.6 {
        -0.72
    } else if x < 1.9 {
        (0.249 * x + 0.65).powf(2.7) - 0.72
    } else {
        x - 1.255
    }
}

/// The detection threshold ΔL in cd/m² for an eye adapted to `nits` cd/m², rods and cones
/// combined (the smaller of the two thresholds).
///
/// Zero, negative and NaN luminance are taken as total darkness: the rod floor,
/// 10^−2.86 ≈ 1.38·10⁻³ cd/m². +∞ gives +∞.
pub fn ferwerda_tvi(nits: f64) -> f64 {
    // log10 of 0 or a negative number is −∞ or NaN; both mean "below every knee".
    let x = if nits > 0.0 { nits.log10() } else { f64::NEG_INFINITY };
    10f64.powf(log_rod_threshold(x).min(log_cone_threshold(x)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weber_fractions_match_the_model_s_asymptotes() {
        // Above 10^1.9 cd/m² the cones are in their Weber range: ΔL/L = 10^−1.255.
        for l in [100.0, 1e4, 1e8] {
            assert!((ferwerda_tvi(l) / l - 10f64.powf(-1.255)).abs() < 1e-12);
        }
        // Below 10^−3.94 the rod floor holds.
        for l in [1e-5, 1e-4 * 1.1] {
            assert!((ferwerda_tvi(l) - 10f64.powf(-2.86)).abs() < 1e-15);
        }
    }

    #[test]
    fn rods_and_cones_cross_near_one_candela() {
        // VIDEO-NOTES §1.2: the branches cross at x ≈ −0.0184.
        let below = 10f64.powf(-0.03);
        let above = 10f64.powf(-0.005);
        assert!(log_rod_threshold(below.log10()) < log_cone_threshold(below.log10()));
        assert!(log_rod_threshold(above.log10()) > log_cone_threshold(above.log10()));
    }

    #[test]
    fn weber_fraction_table_of_the_notes() {
        // VIDEO-NOTES §2, column "Ferwerda tvi/L", computed there independently.
        for (l, fraction) in [(1e-4, 13.8), (1e-3, 1.84), (0.01, 0.547), (0.1, 0.403), (1.0, 0.391), (10.0, 0.107)] {
            let got = ferwerda_tvi(l) / l;
            assert!((got / fraction - 1.0).abs() < 0.01, "tvi({l})/L = {got}, notes say {fraction}");
        }
    }

    #[test]
    fn the_branch_ends_are_where_the_model_says() {
        // Just below and above each end, the threshold changes by under 3 %.
        for x in BRANCH_ENDS_LOG10 {
            let (below, above) = (ferwerda_tvi(10f64.powf(x - 1e-9)), ferwerda_tvi(10f64.powf(x + 1e-9)));
            assert!((above / below - 1.0).abs() < 0.03, "10^{x}: {below} → {above}");
        }
        let x = -1.44;
        let drop = ferwerda_tvi(10f64.powf(x + 1e-9)) / ferwerda_tvi(10f64.powf(x - 1e-9));
        assert!((drop - 10f64.powf(-1.835 + 1.823)).abs() < 0.001, "{drop}");
    }

    #[test]
    fn bad_input_is_darkness() {
        let floor = 10f64.powf(-2.86);
        assert_eq!(ferwerda_tvi(0.0), floor);
        assert_eq!(ferwerda_tvi(-5.0), floor);
        assert_eq!(ferwerda_tvi(f64::NAN), floor);
        assert_eq!(ferwerda_tvi(f64::INFINITY), f64::INFINITY);
    }
}
