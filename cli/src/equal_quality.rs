//! Bytes at equal quality: how many bytes one family of bench configurations needs, against
//! another, where both reach the same PU21-PSNR on the same image.
//!
//! A family is the configurations whose label starts with a prefix (`jxr:` is our JPEG XR
//! encoder at every quality of the sweep; `jxr(jxrlib-enc):` is jxrlib's), lossless ones left
//! out. On each image the family with several lossy points is a rate-quality curve: the log of its bytes interpolated
//! linearly in PU21-PSNR between its two nearest points (no extrapolation: a point outside the
//! curve's range is counted, not scored). When the reference family is a curve, each lossy row
//! of the subject is placed on it (ratio = subject's bytes / the reference's at the subject's
//! PU21-PSNR); when the reference is a single configuration (BC6H at one effort), its point is
//! placed on the subject's curve (ratio = the subject's bytes at the reference's PU21-PSNR /
//! the reference's bytes). Ratios below 1: the subject needs fewer bytes.

use crate::bench::Row;
use serde::Serialize;

/// The comparisons the bench reports when both sides ran, **one line per comparison**:
/// (subject family, reference family or configuration).
pub const COMPARISONS: &[(&str, &str)] = &[
    // Issue 12: at least 10 % fewer bytes than jxrlib's encoder at equal PU21-PSNR...
    ("jxr:", "jxr(jxrlib-enc):"),
    // ... and at most 1/2 of BC6H's bytes at its PU21-PSNR on every photograph, 1/3 median.
    ("jxr:", "bc6h:effort2"),
    // Issue 13: our gain-map JPEG at least as small as libultrahdr's at equal PU21-PSNR.
    ("ultrahdr:", "ultrahdr(libultrahdr):"),
    // Issue 15: our JPEG XR against the outside peers that are not in the family (ratios above
    // 1: the peer needs fewer bytes at our PU21-PSNR).
    ("jxr:", "jxl(cjxl):"),
    ("jxr:", "avif(avifenc):10bit"),
    ("jxr:", "avif(avifenc):12bit"),
];

/// One subject row (or reference point) placed on the other side's curve.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    /// The image.
    pub image: String,
    /// The configuration whose row is placed (the subject's, or the single reference's).
    pub config: String,
    /// That row's PU21-PSNR, dB.
    pub pu21_psnr: f64,
    /// The subject's bytes at that PU21-PSNR (the row's own, or interpolated).
    pub bytes: f64,
    /// The reference's bytes at that PU21-PSNR (interpolated, or the row's own).
    pub reference_bytes: f64,
    /// `bytes / reference_bytes`.
    pub ratio: f64,
}

/// One comparison over a report.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// The subject family's label prefix.
    pub subject: String,
    /// The reference family's label prefix (or one configuration's label).
    pub reference: String,
    /// Every point that fell inside the curve it was placed on.
    pub points: Vec<Point>,
    /// Rows that fell outside that curve's range of PU21-PSNR (not scored).
    pub out_of_range: usize,
    /// Geometric mean of the ratios.
    pub geometric_mean: f64,
    /// Median of the per-image ratios (each image's geometric mean).
    pub median_image: f64,
    /// The largest per-image ratio.
    pub max_image: f64,
}

/// A family's lossy points on one image: (PU21-PSNR, bytes, config), by PU21-PSNR.
fn curve<'a>(rows: &[&'a Row], prefix: &str, image: &str) -> Vec<(f64, f64, &'a str)> {
    let mut c: Vec<(f64, f64, &str)> = rows
        .iter()
        .filter(|r| {
            r.image == image
                && r.config.starts_with(prefix)
                && r.error.is_none()
                && !r.identical
                && !r.lossless
                && r.pu21_psnr.is_finite()
                && r.bytes > 0
        })
        .map(|r| (r.pu21_psnr, r.bytes as f64, r.config.as_str()))
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    c
}

/// Bytes of `curve` at PU21-PSNR `psnr`, interpolated in log bytes; `None` outside its range.
fn bytes_at(curve: &[(f64, f64, &str)], psnr: f64) -> Option<f64> {
    curve.windows(2).find(|w| w[0].0 <= psnr && psnr <= w[1].0).map(|w| {
        let (p0, b0, p1, b1) = (w[0].0, w[0].1.ln(), w[1].0, w[1].1.ln());
        let t = if p1 > p0 { (psnr - p0) / (p1 - p0) } else { 0.0 };
        (b0 + t * (b1 - b0)).exp()
    })
}

fn geometric_mean(v: impl IntoIterator<Item = f64>) -> f64 {
    let (sum, n) = v.into_iter().fold((0.0, 0usize), |(s, n), r| (s + r.ln(), n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).exp()
    }
}

/// `subject` against `reference` over `rows`; `None` when either side has no lossy row.
pub fn compare(rows: &[Row], subject: &str, reference: &str) -> Option<Comparison> {
    let rows: Vec<&Row> = rows.iter().collect();
    let mut images: Vec<&str> = Vec::new();
    for r in &rows {
        if !images.contains(&r.image.as_str()) {
            images.push(&r.image);
        }
    }
    let (mut points, mut out_of_range) = (Vec::new(), 0);
    let mut any = (false, false);
    for image in images {
        let (s, r) = (curve(&rows, subject, image), curve(&rows, reference, image));
        any = (any.0 || !s.is_empty(), any.1 || !r.is_empty());
        // The reference is the curve when it has several points; else its point goes on ours.
        let placed: Vec<(f64, f64, f64, &str)> = if r.len() > 1 {
            s.iter().filter_map(|&(p, b, c)| Some((p, b, bytes_at(&r, p)?, c))).collect()
        } else {
            r.iter().filter_map(|&(p, b, c)| Some((p, bytes_at(&s, p)?, b, c))).collect()
        };
        out_of_range += if r.len() > 1 { s.len() } else { r.len() } - placed.len();
        points.extend(placed.into_iter().map(|(pu21_psnr, bytes, reference_bytes, config)| Point {
            image: image.to_string(),
            config: config.to_string(),
            pu21_psnr,
            bytes,
            reference_bytes,
            ratio: bytes / reference_bytes,
        }));
    }
    if !(any.0 && any.1) {
        return None;
    }
    let mut per_image: Vec<f64> = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for p in &points {
        if !seen.contains(&p.image.as_str()) {
            seen.push(&p.image);
            per_image.push(geometric_mean(points.iter().filter(|q| q.image == p.image).map(|q| q.ratio)));
        }
    }
    per_image.sort_by(f64::total_cmp);
    let median_image = match per_image.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => per_image[n / 2],
        n => (per_image[n / 2 - 1] * per_image[n / 2]).sqrt(),
    };
    Some(Comparison {
        subject: subject.to_string(),
        reference: reference.to_string(),
        geometric_mean: geometric_mean(points.iter().map(|p| p.ratio)),
        median_image,
        max_image: per_image.last().copied().unwrap_or(f64::NAN),
        points,
        out_of_range,
    })
}

/// Every comparison of [`COMPARISONS`] whose two sides are in `rows`.
pub fn comparisons(rows: &[Row]) -> Vec<Comparison> {
    COMPARISONS.iter().filter_map(|&(s, r)| compare(rows, s, r)).collect()
}

/// The comparisons as text: per subject configuration (or per image, when a single reference
/// point was placed on the subject's curve), then the totals.
pub fn table(comparisons: &[Comparison]) -> String {
    let mut s = String::new();
    for c in comparisons {
        s.push_str(&format!(
            "bytes of {} / bytes of {} at equal PU21-PSNR (below 1: {} is smaller)\n",
            c.subject, c.reference, c.subject
        ));
        let by_image = c.points.iter().all(|p| !p.config.starts_with(&c.subject));
        let mut keys: Vec<&str> = Vec::new();
        for p in &c.points {
            let k = if by_image { p.image.as_str() } else { p.config.as_str() };
            if !keys.contains(&k) {
                keys.push(k);
            }
        }
        for k in keys {
            let of = |p: &&Point| if by_image { p.image == k } else { p.config == k };
            let n = c.points.iter().filter(of).count();
            let psnr = c.points.iter().filter(of).map(|p| p.pu21_psnr).sum::<f64>() / n as f64;
            let r = geometric_mean(c.points.iter().filter(of).map(|p| p.ratio));
            s.push_str(&format!("  {k:<32} {r:>6.3}  ({n} point(s), PU21-PSNR {psnr:.1} dB)\n"));
        }
        s.push_str(&format!(
            "  {:<32} {:>6.3}  (geometric mean of {} point(s); per image: median {:.3}, max {:.3}; {} outside the curve's range)\n",
            "all",
            c.geometric_mean,
            c.points.len(),
            c.median_image,
            c.max_image,
            c.out_of_range
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(config: &str, image: &str, bytes: usize, psnr: f64) -> Row {
        let lossless = config.ends_with("lossless");
        Row {
            bytes,
            identical: psnr.is_infinite(),
            pu21_psnr: psnr,
            ..Row::blank(config.into(), image.into(), 100, lossless)
        }
    }

    #[test]
    fn subject_rows_on_the_reference_curve() {
        let rows = vec![
            row("ref:a", "x", 1000, 40.0),
            row("ref:b", "x", 4000, 50.0),
            row("ref:lossless", "x", 9000, 60.0),
            // Halfway in PU21-PSNR: the reference's log bytes halfway, 2000.
            row("ours:q1", "x", 1800, 45.0),
            // Outside the reference's range: counted, not scored.
            row("ours:q2", "x", 5000, 55.0),
        ];
        let c = compare(&rows, "ours:", "ref:").unwrap();
        assert_eq!(c.points.len(), 1);
        assert_eq!(c.out_of_range, 1);
        assert!((c.points[0].reference_bytes - 2000.0).abs() < 1e-6);
        assert!((c.geometric_mean - 0.9).abs() < 1e-9);
        assert!(table(&[c]).contains("ours:q1"));
    }

    #[test]
    fn a_single_reference_point_on_the_subject_curve() {
        let rows = vec![
            row("ours:q1", "x", 100, 30.0),
            row("ours:q2", "x", 400, 50.0),
            row("bc:e2", "x", 1000, 40.0),
            row("ours:q1", "y", 100, 30.0),
            row("ours:q2", "y", 100, 50.0),
            row("bc:e2", "y", 400, 35.0),
        ];
        let c = compare(&rows, "ours:", "bc:e2").unwrap();
        // x: ours at 40 dB is 200 bytes; y: 100.
        assert_eq!(c.points.len(), 2);
        assert!((c.points[0].ratio - 0.2).abs() < 1e-9);
        assert!((c.points[1].ratio - 0.25).abs() < 1e-9);
        assert!((c.max_image - 0.25).abs() < 1e-9);
        assert!((c.median_image - (0.2f64 * 0.25).sqrt()).abs() < 1e-9);
        assert!(table(&[c]).contains("x "));
    }

    #[test]
    fn nothing_to_compare_without_both_sides() {
        let rows = vec![row("ours:q1", "x", 100, 30.0)];
        assert!(compare(&rows, "ours:", "ref:").is_none());
        assert!(comparisons(&rows).is_empty());
    }
}
