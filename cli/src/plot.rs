//! `hdrcodec bench --plot FILE.png`: rate-distortion curves and a speed chart, drawn with
//! plotters into PNGs (each through a temporary file and a rename).
//!
//! - `FILE.png`: two panels, bits per pixel (log scale) against mean PU21-PSNR and against mean
//!   ΔE ITP (log scale), one line per codec family across its quality sweep ([`series`]), single
//!   configurations as points, and a legend.
//! - `FILE-speed.png` beside it ([`speed_path`]): decode and encode megapixels per second on one
//!   thread, two bars per configuration (log scale).

use crate::bench::{Report, Summary};
use hdrcodec::core::{Error, Result};
use plotters::coord::ranged1d::SegmentValue;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Where Debian (fonts-dejavu-core) and other distributions keep a sans-serif TrueType font.
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// The rate-distortion figure: two panels and the legend's column.
const SIZE: (u32, u32) = (1800, 850);
/// The legend's column at the right of the rate-distortion figure, pixels.
const LEGEND_WIDTH: u32 = 330;

/// Checks, before any work, that a PNG can be drawn into `path` (`option` names the
/// command-line option in messages): a `.png` name and a font for the labels (registered with
/// plotters once found).
pub fn prepare_png(path: &Path, option: &str) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        return Err(Error::unsupported(format!(
            "{option} writes PNG files; '{}' does not end in .png",
            path.display()
        )));
    }
    let font = FONT_PATHS.iter().find_map(|p| std::fs::read(p).ok()).ok_or_else(|| {
        Error::unsupported(format!("{option} needs a TrueType font for its labels; none at {}", FONT_PATHS.join(", ")))
    })?;
    // plotters keeps registered fonts for the life of the process.
    let font: &'static [u8] = Box::leak(font.into_boxed_slice());
    plotters::style::register_font("sans-serif", FontStyle::Normal, font)
        .map_err(|_| Error::unsupported(format!("{option}: the system font cannot be read")))
}

/// [`prepare_png`] for `--plot`.
pub fn prepare(path: &Path) -> Result<()> {
    prepare_png(path, "--plot")
}

/// The error of a drawing operation.
pub(crate) fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::invalid(format!("cannot draw the plot: {e}"))
}

/// Encodes `rgb` (8-bit, rows packed, `size` pixels) as a PNG and writes it to `path` through a
/// temporary file and a rename.
pub(crate) fn write_png(path: &Path, size: (u32, u32), rgb: &[u8]) -> Result<()> {
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, size.0, size.1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(plot_error)?;
        w.write_image_data(rgb).map_err(plot_error)?;
    }
    hdrcodec::write_atomic(path, &png_bytes)
}

/// The speed chart's file beside the rate-distortion plot `path`: `rd.png` → `rd-speed.png`.
pub fn speed_path(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or_else(|| "plot".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}-speed.png"))
}

/// One line (or single point) of the rate-distortion plot.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// The legend's name: a family with its swept parameter (`jxr:qN`), or one configuration.
    pub name: String,
    /// (bits per pixel, mean PU21-PSNR, mean ΔE ITP, configuration), by bits per pixel.
    pub points: Vec<(f64, f64, f64, String)>,
}

/// The sweep a configuration label belongs to: `family:pN` for a variant that ends in letters
/// then a number (`jxr:q90` and `jxr:q10` → `jxr:qN`; `jxr(jxrlib-enc):q0.9` →
/// `jxr(jxrlib-enc):qN`; `bc6h:effort2` → `bc6h:effortN`), after a fixed part ending in `-` or
/// `_` if any (`avif(avifenc):10bit-qp20` → `avif(avifenc):10bit-qpN`); any other label is its
/// own. [`series`] draws a key with a single configuration as that configuration.
pub fn sweep_key(label: &str) -> String {
    if let Some((family, variant)) = label.rsplit_once(':') {
        let (head, number) = variant.split_at(variant.trim_end_matches(|c: char| c.is_ascii_digit() || c == '.').len());
        let (prefix, letters) = head.split_at(head.trim_end_matches(|c: char| c.is_ascii_alphabetic()).len());
        let fixed_part = prefix.is_empty() || prefix.ends_with(['-', '_']);
        if !letters.is_empty() && !number.is_empty() && number.parse::<f64>().is_ok() && fixed_part {
            return format!("{family}:{prefix}{letters}N");
        }
    }
    label.to_string()
}

/// Whether a configuration asks for lossless coding (any of its rows says so).
fn asks_lossless(report: &Report, config: &str) -> bool {
    report.rows.iter().any(|r| r.config == config && r.lossless)
}

/// The plotted configurations, grouped into lines: those that ran on some image and are lossy
/// (the lossless ones, and those whose every image decoded identical, are not rate-distortion
/// points; a configuration that asks for lossless coding is a point of its own even when the
/// rounding to its samples makes it lossy). In the order of the report.
pub fn series(report: &Report) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    let plotted = |s: &&Summary| s.images > 0 && s.bpp > 0.0 && s.pu21_psnr.is_finite();
    for s in report.summary.iter().filter(plotted) {
        let name = if asks_lossless(report, &s.config) { s.config.clone() } else { sweep_key(&s.config) };
        let point = (s.bpp, s.pu21_psnr, s.de_itp_mean, s.config.clone());
        match out.iter_mut().find(|x| x.name == name) {
            Some(x) => x.points.push(point),
            None => out.push(Series { name, points: vec![point] }),
        }
    }
    for s in &mut out {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
        // A line needs two points: a lone configuration keeps its own label (`hdrc:raw-f16`
        // has the shape of a sweep but is not one).
        if let [(.., config)] = s.points.as_slice() {
            s.name = config.clone();
        }
    }
    out
}

/// The range of `values` (finite and, for a log axis, positive) widened by `pad` on each side
/// (a factor for a log axis, an amount otherwise); `fallback` when there is none.
fn range(values: impl Iterator<Item = f64>, log: bool, pad: f64, fallback: (f64, f64)) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    match (lo <= hi, log) {
        (false, _) => fallback,
        (true, true) => (lo / pad, hi * pad),
        (true, false) => (lo - pad, hi + pad),
    }
}

/// The images' source for a caption: the report's, or how many files when that is too long.
fn short_source(report: &Report) -> String {
    if report.source.chars().count() <= 48 {
        return report.source.clone();
    }
    let mut images: Vec<&str> = report.rows.iter().map(|r| r.image.as_str()).collect();
    images.sort_unstable();
    images.dedup();
    format!("{} files", images.len())
}

/// Draws the rate-distortion panels of `report` into `path` and its speed chart into
/// [`speed_path`]`(path)`.
pub fn write(report: &Report, path: &Path) -> Result<()> {
    write_rd(report, path)?;
    write_speed(report, &speed_path(path))
}

/// The names of the configurations not on the plot, and why: (lossless or identical, did not run).
fn not_plotted(report: &Report) -> (Vec<&str>, Vec<&str>) {
    let lossless = report.summary.iter().filter(|s| s.images > 0 && s.pu21_psnr.is_infinite());
    let missing = report.summary.iter().filter(|s| s.images == 0);
    (lossless.map(|s| s.config.as_str()).collect(), missing.map(|s| s.config.as_str()).collect())
}

fn write_rd(report: &Report, path: &Path) -> Result<()> {
    let series = series(report);
    let all = || series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = range(all().map(|p| p.0), true, 1.3, (0.1, 100.0));
    let (p0, p1) = range(all().map(|p| p.1), false, 2.0, (0.0, 100.0));
    let (d0, d1) = range(all().map(|p| p.2), true, 1.5, (0.01, 10.0));
    let (lossless, missing) = not_plotted(report);
    let mut buf = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let images = report.summary.iter().map(|s| s.images + s.failed).max().unwrap_or(0);
        let caption = format!(
            "hdrcodec bench on {}: means over {images} image(s); {} lossless or identical, {} did not run (not shown)",
            short_source(report),
            lossless.len(),
            missing.len()
        );
        let root = root.titled(&caption, ("sans-serif", 22)).map_err(plot_error)?;
        let (panels, legend) = root.split_horizontally(SIZE.0 - LEGEND_WIDTH);
        let (left, right) = panels.split_horizontally((SIZE.0 - LEGEND_WIDTH) / 2);
        let colour = |i: usize| Palette99::pick(i).to_rgba();
        let mut pu21 = ChartBuilder::on(&left)
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), p0..p1)
            .map_err(plot_error)?;
        pu21.configure_mesh()
            .x_desc("bits per pixel (log scale)")
            .y_desc("mean PU21-PSNR, dB (higher is better)")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(plot_error)?;
        let mut de = ChartBuilder::on(&right)
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d((x0..x1).log_scale(), (d0..d1).log_scale())
            .map_err(plot_error)?;
        de.configure_mesh()
            .x_desc("bits per pixel (log scale)")
            .y_desc("mean ΔE ITP, BT.2124 (log scale, lower is better)")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(plot_error)?;
        for (i, s) in series.iter().enumerate() {
            let c = colour(i);
            let pu: Vec<(f64, f64)> = s.points.iter().map(|p| (p.0, p.1)).collect();
            let dp: Vec<(f64, f64)> = s.points.iter().filter(|p| p.2 > 0.0).map(|p| (p.0, p.2)).collect();
            pu21.draw_series(LineSeries::new(pu.clone(), c.stroke_width(2))).map_err(plot_error)?;
            pu21.draw_series(pu.iter().map(|&p| Circle::new(p, 4, c.filled()))).map_err(plot_error)?;
            de.draw_series(LineSeries::new(dp.clone(), c.stroke_width(2))).map_err(plot_error)?;
            de.draw_series(dp.iter().map(|&p| Circle::new(p, 4, c.filled()))).map_err(plot_error)?;
        }
        draw_legend(&legend, &series, colour)?;
        root.present().map_err(plot_error)?;
    }
    write_png(path, SIZE, &buf)
}

/// The legend's column: one entry per series (a line for a sweep, a dot for a single point).
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    series: &[Series],
    colour: impl Fn(usize) -> RGBAColor,
) -> Result<()> {
    let (_, h) = area.dim_in_pixel();
    let step = ((h as i32 - 40) / (series.len() as i32).max(1)).clamp(8, 22);
    let size = (step - 4).clamp(8, 16);
    area.draw(&Text::new("legend (lines: quality sweeps)", (10, 10), ("sans-serif", 16))).map_err(plot_error)?;
    for (i, s) in series.iter().enumerate() {
        let y = 36 + i as i32 * step;
        let c = colour(i);
        if s.points.len() > 1 {
            area.draw(&PathElement::new(vec![(10, y + size / 2), (40, y + size / 2)], c.stroke_width(2)))
                .map_err(plot_error)?;
        }
        area.draw(&Circle::new((25, y + size / 2), 4, c.filled())).map_err(plot_error)?;
        area.draw(&Text::new(s.name.clone(), (48, y), ("sans-serif", size))).map_err(plot_error)?;
    }
    Ok(())
}

/// Decode and encode speeds on one thread, two bars per configuration that ran.
fn write_speed(report: &Report, path: &Path) -> Result<()> {
    let rows: Vec<&Summary> = report
        .summary
        .iter()
        .filter(|s| s.images > 0 && (s.decode_mps.is_finite() || s.encode_mps.is_finite()))
        .collect();
    let bar = 26u32;
    let size = (1400u32, 140 + bar * rows.len().max(1) as u32);
    let speeds = rows.iter().flat_map(|s| [s.decode_mps, s.encode_mps]);
    let (x0, x1) = range(speeds, true, 1.5, (0.1, 1000.0));
    let mut buf = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let caption = format!(
            "hdrcodec bench on {}: megapixels per second on one thread (blue: decode, orange: encode; \
             outside encoders: the process's wall time)",
            short_source(report)
        );
        let root = root.titled(&caption, ("sans-serif", 18)).map_err(plot_error)?;
        let n = rows.len().max(1);
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .x_label_area_size(40)
            .y_label_area_size(260)
            .build_cartesian_2d((x0..x1).log_scale(), (0..n - 1).into_segmented())
            .map_err(plot_error)?;
        // The first configuration at the top (plotters' integer ranges include their end: n segments).
        let label = |v: &SegmentValue<usize>| match v {
            SegmentValue::CenterOf(i) | SegmentValue::Exact(i) => {
                rows.get(n.wrapping_sub(1).wrapping_sub(*i)).map_or(String::new(), |s| s.config.clone())
            }
            SegmentValue::Last => String::new(),
        };
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(n)
            .y_label_formatter(&label)
            .x_labels(8)
            .x_desc("megapixels per second, one thread (log scale)")
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(plot_error)?;
        let (decode, encode) = (RGBColor(31, 119, 180), RGBColor(255, 127, 14));
        let half = (bar / 2) as i32;
        for (i, s) in rows.iter().enumerate() {
            let y = n - 1 - i;
            for (v, colour, top) in [(s.decode_mps, decode, true), (s.encode_mps, encode, false)] {
                if !(v.is_finite() && v > 0.0) {
                    continue;
                }
                let mut r =
                    Rectangle::new([(x0, SegmentValue::Exact(y)), (v, SegmentValue::Exact(y + 1))], colour.filled());
                // Top half decode, bottom half encode.
                if top {
                    r.set_margin(2, half as u32, 0, 0);
                } else {
                    r.set_margin(half as u32, 2, 0, 0);
                }
                chart.draw_series(std::iter::once(r)).map_err(plot_error)?;
            }
        }
        root.present().map_err(plot_error)?;
    }
    write_png(path, size, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_group_by_family_and_parameter() {
        assert_eq!(sweep_key("jxr:q90"), "jxr:qN");
        assert_eq!(sweep_key("jxr(jxrlib-enc):q0.9"), "jxr(jxrlib-enc):qN");
        assert_eq!(sweep_key("ultrahdr(libultrahdr):q50"), "ultrahdr(libultrahdr):qN");
        assert_eq!(sweep_key("bc6h:effort2"), "bc6h:effortN");
        assert_eq!(sweep_key("jxl(cjxl):d1.5"), "jxl(cjxl):dN");
        assert_eq!(sweep_key("avif(avifenc):10bit-qp20"), "avif(avifenc):10bit-qpN");
        assert_eq!(sweep_key("avif(avifenc):12bit-qp2"), "avif(avifenc):12bit-qpN");
        assert_ne!(sweep_key("avif(avifenc):10bit-qp2"), sweep_key("avif(avifenc):12bit-qp2"));
        // Not a sweep: each its own point.
        for label in ["exr:zip-half", "rgbe", "rgbe:truncate", "jpeg-hdr:q85-post", "x:1.2.3", "x:10bitq2"] {
            assert_eq!(sweep_key(label), label);
        }
    }

    #[test]
    fn a_quality_sweep_is_one_line_and_the_rest_are_points() {
        use crate::bench;
        let registry = hdrcodec::registry();
        let wanted = ["jxr:q100", "jxr:q90", "jxr:q50", "jxr:q10", "exr:b44-half", "exr:zip-float", "hdrc:raw-f16"];
        let configs: Vec<bench::Config> =
            bench::configurations(&registry).into_iter().filter(|c| wanted.contains(&c.label.as_str())).collect();
        assert_eq!(configs.len(), wanted.len());
        let scene = crate::corpus::scene("odd-257x129").unwrap();
        let inputs = [bench::Input { name: scene.name.to_string(), image: scene.image }];
        let pool = hdrcodec::core::ThreadPool::single();
        let report = bench::run(&configs, &inputs, 1, &pool, "test", Vec::new(), |_, _, _| {});
        let s = series(&report);
        let names: Vec<&str> = s.iter().map(|s| s.name.as_str()).collect();
        // exr:zip-float is lossless (identical: not a rate-distortion point); jxr:q100 asks for
        // lossless coding: a point of its own; hdrc:raw-f16 (half floats: lossy) is alone under
        // its sweep key, so it keeps its label.
        assert_eq!(names, ["exr:b44-half", "hdrc:raw-f16", "jxr:q100", "jxr:qN"], "{s:?}");
        let line: Vec<&str> = s[3].points.iter().map(|p| p.3.as_str()).collect();
        assert_eq!(line, ["jxr:q10", "jxr:q50", "jxr:q90"], "by bits per pixel");
        assert!(s[3].points.windows(2).all(|w| w[0].0 < w[1].0 && w[0].2 > w[1].2), "{s:?}");
    }

    #[test]
    fn speed_chart_sits_beside_the_plot() {
        assert_eq!(speed_path(Path::new("out/rd.png")), Path::new("out/rd-speed.png"));
    }
}
