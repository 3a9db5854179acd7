//! What the container's integration tests share.

use hdrcodec_core::{Channels, ColorInfo, HdrImage};

/// A deterministic HDR test pattern spanning many decades, with every sample distinct.
pub fn pattern(w: u32, h: u32, ch: Channels, seed: u32) -> HdrImage {
    let n = (w * h) as usize * ch.count();
    let samples = (0..n as u32)
        .map(|i| {
            let r = (i ^ seed).wrapping_mul(2_654_435_761) >> 8;
            (r % 10_000) as f32 * 10f32.powi((r % 9) as i32 - 4) / 7.0
        })
        .collect();
    HdrImage::new(w, h, ch, samples, ColorInfo::default()).unwrap()
}
