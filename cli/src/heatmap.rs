//! `hdrcodec compare A B --heatmap FILE.png`: a false-colour map of the per-pixel ΔE ITP
//! (BT.2124, [`metrics::delta_e_itp_map`]) with a colour bar in ΔE ITP units.
//!
//! The map is the image at its own size, one PNG pixel per image pixel, on the left; the colour
//! bar is on the right. Colours follow the viridis scale (plotters' `ViridisRGB`), linear from
//! ΔE 0 (dark purple) to the scale's top (yellow); larger values take the top colour. The PNG is
//! written through a temporary file and a rename; its size is checked against [`Limits`] first.

use crate::plot::{plot_error, write_png};
use hdrcodec::core::{metrics, Error, HdrImage, Limits, Result};
use plotters::prelude::*;
use std::path::Path;

/// The default top of the colour scale, ΔE ITP: a few just-noticeable differences.
pub const DEFAULT_MAX: f64 = 5.0;
/// The colour bar's column, pixels.
const BAR_COLUMN: u32 = 190;
/// The smallest height of the picture (room for the colour bar), pixels.
const MIN_HEIGHT: u32 = 280;

/// The colour of ΔE ITP `de` on a scale whose top is `max` (values beyond the top, and NaN as
/// the top: no error goes unseen, take the top colour; negative values 0).
pub fn colour(de: f32, max: f64) -> [u8; 3] {
    let top = max.max(f64::MIN_POSITIVE);
    let v = if de.is_nan() { top } else { (de as f64).clamp(0.0, top) };
    let c = ViridisRGB::get_color_normalized(v, 0.0, top);
    [c.0, c.1, c.2]
}

/// The picture's size for an image of `width` x `height`: the map and the colour bar's column.
pub fn picture_size(width: u32, height: u32) -> (u32, u32) {
    (width.saturating_add(BAR_COLUMN), height.max(MIN_HEIGHT))
}

/// Checks that the picture for an image of `width` x `height` (8-bit RGB, and the map's `f32`
/// per pixel) stays within `limits`.
fn check_size(width: u32, height: u32, limits: &Limits) -> Result<()> {
    let (w, h) = picture_size(width, height);
    let pixels = w as u64 * h as u64;
    let bytes = pixels * 3 + width as u64 * height as u64 * 4;
    if w > limits.max_width || h > limits.max_height || pixels > limits.max_pixels || bytes > limits.max_alloc_bytes {
        return Err(Error::limit(format!(
            "a ΔE ITP heat map of {width}x{height} is a {w}x{h} picture ({bytes} bytes): beyond the limits \
             ({}x{}, {} pixels, {} bytes)",
            limits.max_width, limits.max_height, limits.max_pixels, limits.max_alloc_bytes
        )));
    }
    Ok(())
}

/// Draws the ΔE ITP of `test` against `reference`, per pixel, into the PNG `path` with a colour
/// bar from 0 to `max`. The file is written only when whole.
pub fn write(reference: &HdrImage, test: &HdrImage, path: &Path, max: f64, limits: &Limits) -> Result<()> {
    if !(max.is_finite() && max > 0.0) {
        return Err(Error::invalid(format!("the heat map's top must be a positive number of ΔE ITP, not {max}")));
    }
    let (width, height) = (reference.width(), reference.height());
    check_size(width, height, limits)?;
    let map = metrics::delta_e_itp_map(reference, test)?;
    let size = picture_size(width, height);
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    let stride = size.0 as usize * 3;
    for (y, row) in map.chunks_exact(width.max(1) as usize).enumerate() {
        for (x, &de) in row.iter().enumerate() {
            let at = y * stride + x * 3;
            buf[at..at + 3].copy_from_slice(&colour(de, max));
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        let (_, bar) = root.split_horizontally(width);
        draw_bar(&bar, size.1, max)?;
        root.present().map_err(plot_error)?;
    }
    write_png(path, size, &buf)
}

/// The colour bar: a gradient from 0 (bottom) to `max` (top) with five labelled ticks.
fn draw_bar<DB: DrawingBackend>(area: &DrawingArea<DB, plotters::coord::Shift>, height: u32, max: f64) -> Result<()> {
    let (top, bottom) = (40i32, height as i32 - 20);
    let (x0, x1) = (20i32, 50i32);
    let font = ("sans-serif", 15);
    area.draw(&Text::new("ΔE ITP (BT.2124)", (8, 10), font)).map_err(plot_error)?;
    let span = (bottom - top).max(1);
    for y in top..=bottom {
        let v = max * (bottom - y) as f64 / span as f64;
        let [r, g, b] = colour(v as f32, max);
        area.draw(&PathElement::new(vec![(x0, y), (x1, y)], RGBColor(r, g, b))).map_err(plot_error)?;
    }
    area.draw(&Rectangle::new([(x0, top), (x1, bottom)], BLACK)).map_err(plot_error)?;
    for k in 0..=4 {
        let v = max * k as f64 / 4.0;
        let y = bottom - span * k / 4;
        let label = if k == 4 { format!("≥ {v:.2}") } else { format!("{v:.2}") };
        area.draw(&PathElement::new(vec![(x1, y), (x1 + 6, y)], BLACK)).map_err(plot_error)?;
        area.draw(&Text::new(label, (x1 + 10, y - 7), font)).map_err(plot_error)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_runs_from_dark_purple_to_yellow() {
        // Viridis' ends (plotters' ViridisRGB, matplotlib's scale).
        assert_eq!(colour(0.0, 5.0), [68, 1, 84]);
        assert_eq!(colour(5.0, 5.0), [254, 232, 37]);
        assert_eq!(colour(50.0, 5.0), [254, 232, 37]);
        assert_eq!(colour(f32::NAN, 5.0), [254, 232, 37]);
        assert_eq!(colour(-1.0, 5.0), [68, 1, 84]);
        assert_ne!(colour(2.5, 5.0), colour(0.0, 5.0));
    }

    #[test]
    fn pictures_beyond_the_limits_are_refused_before_any_work() {
        let limits = Limits::new(1 << 16, 1 << 16, 1000, 1 << 32);
        assert!(matches!(check_size(100, 100, &limits), Err(Error::LimitExceeded { .. })));
        assert!(check_size(100, 100, &Limits::default()).is_ok());
    }
}
