//! The banding proxy of VIDEO-NOTES §2.2 (recipe 5): slow grey gradients quantized by each
//! curve at 10, 11 and 12 bits, scored by PU21-PSNR (core's metric) against the float source.
//! PQ at 12 bits and the GSDF are the controls.

use hdrcodec_core::metrics::pu21_psnr;
use hdrcodec_core::{Channels, ColorInfo, HdrImage};
use hdrcodec_video::curves::{LogCurve, LumaCurve, PqCurve};
use hdrcodec_video::gsdf::GsdfCurve;
use hdrcodec_video::mantiuk::{Psi04, PsiOptions};
use hdrcodec_video::mantiuk06::Mantiuk06;

const WIDTH: usize = 4096;

/// A grey ramp, linear in luminance from `from` to `to` cd/m², one row (1.0 = 1 cd/m²).
fn ramp(from: f64, to: f64) -> Vec<f64> {
    (0..WIDTH).map(|i| from + (to - from) * i as f64 / (WIDTH - 1) as f64).collect()
}

fn grey(luminance: impl Iterator<Item = f64>) -> HdrImage {
    let samples: Vec<f32> = luminance.flat_map(|y| [y as f32; 3]).collect();
    let color = ColorInfo { nits_per_unit: 1.0, ..ColorInfo::default() };
    HdrImage::new((samples.len() / 3) as u32, 1, Channels::Rgb, samples, color).unwrap()
}

fn curve(name: &str, bits: u32) -> Box<dyn LumaCurve> {
    match name {
        "psi04" => Box::new(Psi04::new(&PsiOptions { bits, ..PsiOptions::default() }).unwrap()),
        "psi04 LumaHDRv" => Box::new(Psi04::new(&PsiOptions::lumahdrv(bits)).unwrap()),
        "mantiuk06" => Box::new(Mantiuk06::new(bits).unwrap()),
        "pq" => Box::new(PqCurve::new(bits).unwrap()),
        "gsdf" => Box::new(GsdfCurve::new(bits).unwrap()),
        _ => Box::new(LogCurve::new(bits, 0.005, 1e4).unwrap()),
    }
}

#[test]
fn slow_gradients_through_each_curve() {
    // 20 % ramps at three levels over 4096 pixels: every curve here takes dozens to hundreds of
    // pixels per code step on them (PQ at 12 bits and 1000 cd/m², 0.22 % a step, about 45), so
    // the error is a sawtooth and halving the step (one more bit) should gain
    // 20·log10(2) ≈ 6 dB of PSNR.
    let ramps = [(1.0, 1.2), (100.0, 120.0), (1000.0, 1200.0)];
    let names = ["psi04", "psi04 LumaHDRv", "mantiuk06", "pq", "gsdf", "log 0.005..1e4"];
    println!("| curve | bits | {} |\n|---|---|---|---|---|", ramps.map(|(a, b)| format!("{a}..{b} cd/m²")).join(" | "));
    for name in names {
        let mut previous: Option<[f64; 3]> = None;
        for bits in [10, 11, 12] {
            let c = curve(name, bits);
            let psnr = ramps.map(|(from, to)| {
                let source = ramp(from, to);
                let quantized = source.iter().map(|&y| c.decode(c.encode(y)));
                pu21_psnr(&grey(source.iter().copied()), &grey(quantized)).unwrap()
            });
            println!("| {name} | {bits} | {} |", psnr.map(|p| format!("{p:.1} dB")).join(" | "));
            if let Some(before) = previous {
                for (gain, (from, _)) in psnr.iter().zip(before).map(|(now, then)| now - then).zip(ramps) {
                    assert!((5.0..7.0).contains(&gain), "{name} at {bits} bits on the {from} ramp gains {gain:.2} dB");
                }
            }
            previous = Some(psnr);
        }
    }
}
