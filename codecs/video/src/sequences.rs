//! Test sequences the project generates, so that video tests and measurements need no large
//! files: a pan across a still image (a corpus photograph), a bright light moving over a dim
//! scene, and a fade. Every frame is scene-linear BT.2020 (the pan: the source's primaries)
//! with `nits_per_unit` 100, built on demand from its index.

use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, Result};

/// The colour of generated frames: BT.2020, 1.0 = 100 cd/m².
fn bt2020() -> ColorInfo {
    ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None }
}

/// Frame `t` of `frames` of a pan: a `width` × `height` window moving in a straight line from
/// the top-left corner of `source` to its bottom-right corner (whole pixels, nearest position).
/// Fails if the window is larger than the source or empty.
pub fn pan_frame(source: &HdrImage, width: u32, height: u32, t: u32, frames: u32) -> Result<HdrImage> {
    if width == 0 || height == 0 || width > source.width() || height > source.height() {
        return Err(Error::invalid(format!(
            "a {width}x{height} window does not fit in a {}x{} image",
            source.width(),
            source.height()
        )));
    }
    let along = if frames > 1 { f64::from(t.min(frames - 1)) / f64::from(frames - 1) } else { 0.0 };
    let x0 = (along * f64::from(source.width() - width)).round() as usize;
    let y0 = (along * f64::from(source.height() - height)).round() as usize;
    let rgb = source.with_channels(Channels::Rgb);
    let row = source.width() as usize * 3;
    let mut samples = Vec::with_capacity(width as usize * height as usize * 3);
    for y in y0..y0 + height as usize {
        samples.extend_from_slice(&rgb.samples()[y * row + x0 * 3..y * row + (x0 + width as usize) * 3]);
    }
    HdrImage::new(width, height, Channels::Rgb, samples, source.color.clone())
}

/// Frame `t` of `frames` of a moving light: a dim scene (a ramp from 0.1 to 200 cd/m² with a
/// colour wash) and a white disc of `radius` pixels at exactly `peak_nits` on R, G and B,
/// moving left to right along the middle row. Its MaxCLL (CTA-861.3) is `peak_nits` for any
/// peak above 200.
pub fn moving_light_frame(width: u32, height: u32, peak_nits: f32, radius: f32, t: u32, frames: u32) -> HdrImage {
    let along = if frames > 1 { t.min(frames - 1) as f32 / (frames - 1) as f32 } else { 0.5 };
    let (cx, cy) = (radius + along * (width as f32 - 2.0 * radius).max(0.0), height as f32 / 2.0);
    let mut samples = Vec::with_capacity(width as usize * height as usize * 3);
    for y in 0..height {
        for x in 0..width {
            let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
            if dx * dx + dy * dy <= radius * radius {
                samples.extend([peak_nits / 100.0; 3]);
                continue;
            }
            let ramp = 10f32.powf(-3.0 + 3.3 * (x + y) as f32 / (width + height) as f32); // 0.001..2
            let hue = y as f32 / height as f32;
            samples.extend([ramp * (0.5 + 0.5 * hue), ramp * 0.8, ramp * (1.0 - 0.5 * hue)]);
        }
    }
    HdrImage::new(width, height, Channels::Rgb, samples, bt2020()).expect("sizes match")
}

/// Frame `t` of `frames` of a fade from black: `image` scaled by t / (frames − 1).
pub fn fade_frame(image: &HdrImage, t: u32, frames: u32) -> HdrImage {
    let gain = if frames > 1 { t.min(frames - 1) as f32 / (frames - 1) as f32 } else { 1.0 };
    let mut out = image.clone();
    out.samples_mut().iter_mut().for_each(|v| *v *= gain);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pan_moves_corner_to_corner_and_the_light_has_its_peak() {
        let samples: Vec<f32> = (0..10 * 6).flat_map(|i| [i as f32; 3]).collect();
        let src = HdrImage::new(10, 6, Channels::Rgb, samples, bt2020()).unwrap();
        let first = pan_frame(&src, 4, 2, 0, 3).unwrap();
        let last = pan_frame(&src, 4, 2, 2, 3).unwrap();
        assert_eq!(first.samples()[0], 0.0);
        assert_eq!(last.samples()[0], (4 * 10 + 6) as f32); // (6, 4)
        assert!(pan_frame(&src, 11, 2, 0, 3).is_err());
        let light = moving_light_frame(64, 32, 20_000.0, 5.0, 1, 3);
        let max = light.samples().iter().fold(0f32, |m, &v| m.max(v));
        assert_eq!(max * 100.0, 20_000.0);
        assert_eq!(hdrcodec_core::hdr10::max_cll_nits(&light), 20_000.0);
        let faded = fade_frame(&light, 1, 5);
        assert_eq!(faded.samples()[0], light.samples()[0] * 0.25);
    }
}
