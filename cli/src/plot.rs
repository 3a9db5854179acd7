//! `hdrcodec bench --plot FILE.png`: bits per pixel against PU21-PSNR, one labelled point per
//! configuration, drawn with plotters into a PNG (through a temporary file and a rename).

use crate::bench::Report;
use hdrcodec::core::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// Where Debian (fonts-dejavu-core) and other distributions keep a sans-serif TrueType font.
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

const SIZE: (u32, u32) = (1200, 800);

/// Checks, before any work, that a plot can be drawn into `path`: a `.png` name and a font for
/// the labels (registered with plotters once found).
pub fn prepare(path: &Path) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(Error::unsupported(format!("--plot writes PNG files; '{}' does not end in .png", path.display())));
    }
    let font = FONT_PATHS.iter().find_map(|p| std::fs::read(p).ok()).ok_or_else(|| {
        Error::unsupported(format!("--plot needs a TrueType font for its labels; none at {}", FONT_PATHS.join(", ")))
    })?;
    // plotters keeps registered fonts for the life of the process.
    let font: &'static [u8] = Box::leak(font.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, font)
        .map_err(|_| Error::unsupported("--plot: the system font cannot be read"))
}

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::invalid(format!("cannot draw the plot: {e}"))
}

/// Draws the configurations of `report` (lossy ones; lossless ones are listed in the caption)
/// and writes the PNG to `path`.
pub fn write(report: &Report, path: &Path) -> Result<()> {
    let points: Vec<(f64, f64, &str)> = report
        .summary
        .iter()
        .filter(|s| s.images > 0 && s.bpp > 0.0 && s.pu21_psnr.is_finite())
        .map(|s| (s.bpp, s.pu21_psnr, s.config.as_str()))
        .collect();
    let lossless = report.summary.iter().filter(|s| s.images > 0 && s.pu21_psnr.is_infinite()).count();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y, _) in &points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if points.is_empty() {
        (x0, x1, y0, y1) = (1.0, 100.0, 0.0, 100.0);
    }
    let mut buf = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let caption = format!(
            "hdrcodec bench on {}: {} configurations ({} lossless, not shown)",
            report.source,
            report.summary.len(),
            lossless
        );
        let mut chart = ChartBuilder::on(&root)
            .caption(caption, ("sans-serif", 24))
            .margin(30)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 / 1.3..x1 * 1.3).log_scale(), (y0 - 3.0)..(y1 + 3.0))
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("bits per pixel (log scale)")
            .y_desc("mean PU21-PSNR, dB")
            .label_style(("sans-serif", 16))
            .draw()
            .map_err(plot_error)?;
        chart
            .draw_series(points.iter().enumerate().map(|(i, &(x, y, label))| {
                let colour = Palette99::pick(i).to_rgba();
                EmptyElement::at((x, y))
                    + Circle::new((0, 0), 5, colour.filled())
                    + Text::new(label.to_string(), (8, -8), ("sans-serif", 14).into_font().color(&colour))
            }))
            .map_err(plot_error)?;
        root.present().map_err(plot_error)?;
    }
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, SIZE.0, SIZE.1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(plot_error)?;
        w.write_image_data(&buf).map_err(plot_error)?;
    }
    hdrcodec::write_atomic(path, &png_bytes)
}
