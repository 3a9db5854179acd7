//! L_p u'v' round trips: chromaticity and luminance errors against the bounds the quantizers
//! imply, and ΔE ITP (core's metric) on a colour sweep.

use hdrcodec_core::color::{
    delta_e_itp_ictcp, luv_prime_to_xyz, mat_apply, rgb2020_to_ictcp, xyz_to_luv_prime, xyz_to_uv_prime,
};
use hdrcodec_core::metrics::delta_e_itp;
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, HdrImage};
use hdrcodec_video::curves::{LumaCurve, PqCurve};
use hdrcodec_video::luv::{decode_image, encode_image, UV_SCALE};
use hdrcodec_video::mantiuk::{Psi04, PsiOptions};
use hdrcodec_video::mantiuk06::Mantiuk06;

/// Every mix of R, G, B in quarters (no black), scaled to each luminance from 0.05 to
/// 5000 cd/m² in decades: 124 chromaticities × 6 levels.
fn sweep(primaries: ColorPrimaries) -> HdrImage {
    let color = ColorInfo { primaries, ..ColorInfo::default() };
    let weights = primaries.rgb_to_xyz()[1];
    let mut samples = Vec::new();
    for level in [0.05, 0.5, 5.0, 50.0, 500.0, 5000.0] {
        for i in 1..125 {
            let rgb = [i % 5, i / 5 % 5, i / 25].map(|q| f64::from(q) / 4.0);
            let y: f64 = (0..3).map(|c| weights[c] * rgb[c]).sum();
            let scale = level / f64::from(color.nits_per_unit) / y;
            samples.extend(rgb.map(|c| (c * scale) as f32));
        }
    }
    let width = (samples.len() / 3) as u32;
    HdrImage::new(width, 1, Channels::Rgb, samples, color).unwrap()
}

fn curves() -> Vec<(&'static str, Box<dyn LumaCurve>)> {
    vec![
        ("psi04 11-bit 1e-4..1e8", Box::new(Psi04::new(&PsiOptions::default()).unwrap())),
        ("psi04 11-bit LumaHDRv", Box::new(Psi04::new(&PsiOptions::lumahdrv(11)).unwrap())),
        ("pq 12-bit", Box::new(PqCurve::new(12).unwrap())),
        ("mantiuk06 12-bit", Box::new(Mantiuk06::new(12).unwrap())),
    ]
}

/// One pixel of a round trip: source and decoded XYZ in cd/m², and its luma code.
struct Trip {
    source: [f64; 3],
    decoded: [f64; 3],
    code: u16,
}

/// Encodes and decodes the sweep in BT.709 and BT.2020 with each curve, calls `check` on every
/// pixel, and returns "primaries curve", source and decoded image of each run.
fn round_trips(mut check: impl FnMut(&str, &dyn LumaCurve, Trip)) -> Vec<(String, HdrImage, HdrImage)> {
    let mut runs = Vec::new();
    for primaries in [ColorPrimaries::Bt709, ColorPrimaries::Bt2020] {
        let source = sweep(primaries);
        let to_xyz_nits = |rgb: [f32; 3]| {
            mat_apply(&primaries.rgb_to_xyz(), rgb.map(f64::from)).map(|c| c * f64::from(source.color.nits_per_unit))
        };
        for (label, curve) in curves() {
            let planes = encode_image(curve.as_ref(), &source).unwrap();
            let decoded = decode_image(curve.as_ref(), &planes, source.color.clone()).unwrap();
            for ((a, b), &code) in source.rgb().zip(decoded.rgb()).zip(&planes.luma) {
                check(label, curve.as_ref(), Trip { source: to_xyz_nits(a), decoded: to_xyz_nits(b), code });
            }
            runs.push((format!("{primaries:?} {label}"), source.clone(), decoded));
        }
    }
    runs
}

#[test]
fn chromaticity_and_luminance_stay_within_half_a_code() {
    round_trips(|label, curve, Trip { source, decoded, code }| {
        let (uv_a, uv_b) = (xyz_to_uv_prime(source), xyz_to_uv_prime(decoded));
        // Rounding to 1/410 moves u' and v' by at most half of that (plus f32 noise).
        for k in 0..2 {
            assert!((uv_a[k] - uv_b[k]).abs() <= 0.5 / UV_SCALE + 1e-6, "{label} {source:?} → {decoded:?}");
        }
        // Luminance: within half the step around the code, or clamped to the curve's ends.
        let (lo, hi) = (curve.decode(code.saturating_sub(1)), curve.decode((code + 1).min(curve.max_code())));
        let y = source[1].clamp(curve.decode(0), curve.decode(curve.max_code()));
        let half_step = 0.5 * if decoded[1] < y { hi - decoded[1] } else { decoded[1] - lo };
        assert!((decoded[1] - y).abs() <= half_step * 1.0001 + 1e-9, "{label} Y {y} → {}", decoded[1]);
    });
}

/// ICtCp of XYZ in cd/m², through BT.2020 RGB (core's BT.2100 conversion).
fn ictcp(xyz: [f64; 3]) -> [f64; 3] {
    rgb2020_to_ictcp(mat_apply(&ColorPrimaries::Bt2020.xyz_to_rgb(), xyz))
}

#[test]
fn delta_e_itp_stays_within_what_the_quantizers_allow() {
    // Per pixel, the bound is what the two quantizers alone can do to that colour: the worst
    // of moving u' and v' by half a code (±0.5/410 each, the four corners) at its own
    // luminance, plus what its luminance code alone does to it at its own chromaticity, 5 %
    // added for the non-linearity of combining them. Mean and 99th percentile (core's
    // metric) are printed for the README.
    let runs = round_trips(|label, curve, Trip { source, decoded, code }| {
        let [y, u, v] = xyz_to_luv_prime(source);
        let at = |y: f64, u: f64, v: f64| ictcp(luv_prime_to_xyz([y, u, v]));
        let half = 0.5 / UV_SCALE;
        let chroma = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
            .map(|(du, dv)| delta_e_itp_ictcp(at(y, u, v), at(y, u + du * half, v + dv * half)))
            .into_iter()
            .fold(0f64, f64::max);
        // The luminance error itself is checked against half a step by the test above.
        let luma = delta_e_itp_ictcp(at(y, u, v), at(curve.decode(code), u, v));
        let got = delta_e_itp_ictcp(ictcp(source), ictcp(decoded));
        assert!(
            got <= 1.05 * (chroma + luma) + 1e-6,
            "{label} {source:?} → {decoded:?}: ΔE {got}, bound {chroma} + {luma}"
        );
    });
    for (name, source, decoded) in runs {
        let (mean, p99) = delta_e_itp(&source, &decoded).unwrap();
        println!("{name}: ΔE ITP mean {mean:.3}, p99 {p99:.3}");
    }
}
