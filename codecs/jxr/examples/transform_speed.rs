//! Times the inverse transform of one 4096×4096 channel, band by band into a reused buffer
//! (run with `cargo run --release -p hdrcodec-jxr --example transform_speed`).
use hdrcodec_jxr::container::{OutputBitDepth, OutputColorFormat, PIXEL_FORMATS};
use hdrcodec_jxr::output::{InternalColorFormat, OutputParams};
use hdrcodec_jxr::transform::{inverse_band, OperatorSet, OverlapMode, PlaneKind, TransformParams, BAND_MB_ROWS};

fn main() {
    let (mb_w, mb_h): (usize, usize) =
        std::env::args().nth(1).map_or((256, 256), |s| (s.parse().unwrap(), s.parse().unwrap()));
    let mut s = 1u64;
    let coeffs: Vec<[i32; 256]> = (0..mb_w * mb_h)
        .map(|_| {
            std::array::from_fn(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s as i32) >> 20
            })
        })
        .collect();
    let width = 16 * mb_w;
    let mut out = vec![0i32; width * 16 * mb_h];
    for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
        let p = TransformParams { overlap, scaled: true, hard: None, operators: OperatorSet::JpegXr };
        let mut best = f64::MAX;
        for _ in 0..7 {
            let t = std::time::Instant::now();
            for r0 in (0..mb_h).step_by(BAND_MB_ROWS) {
                let r1 = (r0 + BAND_MB_ROWS).min(mb_h);
                let band = &mut out[r0 * 16 * width..];
                inverse_band(&p, PlaneKind::Full, 0, mb_w, mb_h, &coeffs, 0, r0..r1, band).unwrap();
            }
            best = best.min(t.elapsed().as_secs_f64());
        }
        let sum = out.iter().fold(0i64, |a, &v| a.wrapping_add(i64::from(v)));
        println!(
            "{overlap:?}: best of 7 {:.1} ms, {:.0} Msamples/s (checksum {sum})",
            best * 1e3,
            (256.0 * (mb_w * mb_h) as f64) / best / 1e6
        );
    }

    // Output formatting of the plane as Y, U and V of 48bppRGBHalf and 128bppRGBFloat.
    for (name, bd, shift) in [("48bppRGBHalf", OutputBitDepth::Bd16F, 0), ("128bppRGBFloat", OutputBitDepth::Bd32F, 13)]
    {
        let f = PIXEL_FORMATS.iter().find(|f| f.name == name).unwrap();
        let p =
            OutputParams::new(f, bd, OutputColorFormat::Rgb, InternalColorFormat::Yuv444, true, shift, 4, false, None)
                .unwrap();
        let mut row = vec![0u8; p.row_bytes(width)];
        let mut best = f64::MAX;
        for _ in 0..7 {
            let t = std::time::Instant::now();
            for y in 0..16 * mb_h {
                let r = &out[y * width..(y + 1) * width];
                p.format_row(&[r, r, r], None, width, &mut row).unwrap();
            }
            best = best.min(t.elapsed().as_secs_f64());
        }
        println!(
            "{name} formatting: {:.1} ms, {:.0} Mpixels/s",
            best * 1e3,
            (256.0 * (mb_w * mb_h) as f64) / best / 1e6
        );
    }
}
