//! Times the inverse transform of one 4096×4096 channel (run with `--release`).
use hdrcodec_jxr::transform::{inverse_plane, OverlapMode, PlaneKind, TransformParams};

fn main() {
    let (mb_w, mb_h) = (256, 256);
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
    for overlap in [OverlapMode::None, OverlapMode::One, OverlapMode::Two] {
        let p = TransformParams { overlap, scaled: true, hard: None };
        let mut dt = f64::MAX;
        let mut plane = None;
        for _ in 0..7 {
            let t = std::time::Instant::now();
            plane = Some(inverse_plane(&p, PlaneKind::Full, 0, mb_w, mb_h, &coeffs).unwrap());
            dt = dt.min(t.elapsed().as_secs_f64());
        }
        let plane = plane.unwrap();
        println!(
            "{overlap:?}: best of 7 {:.1} ms, {:.0} MP/s (checksum {})",
            dt * 1e3,
            16.777216 / dt,
            plane.data.iter().fold(0i64, |a, &v| a.wrapping_add(v as i64))
        );
    }
}
