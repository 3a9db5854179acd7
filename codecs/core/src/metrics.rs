//! Image-quality metrics for HDR images, used by `hdrcodec compare`, `bench`, tests and benches.
//!
//! All perceptual metrics work on absolute luminance: a sample value `v` means
//! `v · ColorInfo::nits_per_unit` cd/m². Common rules:
//! - The two images must have the same width and height ([`Error::Invalid`] names both sizes).
//! - Alpha is ignored.
//! - NaN samples count as 0 and ±∞ as ±`f32::MAX`, so that one bad sample cannot turn a
//!   figure into NaN or panic; [`Comparison::identical`] still sees them as they are.
//! - When the test image has other primaries or another `nits_per_unit` than the reference,
//!   it is converted into the reference's primaries and units first (a 3x3 matrix per pixel,
//!   no allocation). ΔE ITP converts both images to BT.2020 cd/m² instead.
//! - A test image whose primaries are [unspecified](ColorPrimaries::Unspecified) (decoded from
//!   a format that records none) is taken to be in the reference's primaries: the figures then
//!   score the codec, not a conversion. An unspecified reference is taken as BT.709.
//! - No allocation per pixel; only ΔE ITP keeps one `f32` per pixel (for its percentile).

use crate::color::{mat_apply, mat_mul, rgb_to_rgb, Mat3, LMS_P_TO_ICTCP, RGB2020_TO_LMS};
use crate::transfer::PqTransfer;
use crate::{ColorPrimaries, Error, HdrImage, Result};

/// The PU21 "banding_glare" parameters p1..p7 (Mantiuk & Azimi 2021; pu21_encoder.m of the
/// authors' reference code, the variant they recommend).
pub const PU21_PARAMS: [f64; 7] =
    [0.353487901, 0.3734658629, 8.277049286e-05, 0.9062562627, 0.09150303166, 0.9099517204, 596.3148142];
/// The smallest luminance PU21 encodes, cd/m² (lower values are clamped to it).
pub const PU21_L_MIN: f64 = 0.005;
/// The largest luminance PU21 encodes, cd/m² (higher values are clamped to it).
pub const PU21_L_MAX: f64 = 10000.0;
/// The peak used for PSNR on PU21 values (pu21_metric.m: `psnr(T, R, 256)`).
pub const PU21_PEAK: f64 = 256.0;

/// PU21 encoding of a luminance in cd/m²: Y is clamped to [0.005, 10 000] (NaN → 0.005), then
/// V = p7·(((p1 + p2·Y^p4) / (1 + p3·Y^p4))^p5 − p6). V runs from 0 at 0.005 cd/m² to about
/// 595 at 10 000 cd/m²; 100 cd/m² encodes to about 256.
pub fn pu21_encode(y_nits: f64) -> f64 {
    let p = &PU21_PARAMS;
    // f64::clamp keeps NaN; NaN means "no light" here.
    let y = if y_nits.is_nan() { PU21_L_MIN } else { y_nits.clamp(PU21_L_MIN, PU21_L_MAX) };
    let yp = y.powf(p[3]);
    p[6] * (((p[0] + p[1] * yp) / (1.0 + p[2] * yp)).powf(p[4]) - p[5])
}

/// The inverse of [`pu21_encode`] (the `decode` of pu21_encoder.m), in cd/m².
pub fn pu21_decode(v: f64) -> f64 {
    let p = &PU21_PARAMS;
    let vp = (v / p[6] + p[5]).max(0.0).powf(1.0 / p[4]);
    ((vp - p[0]).max(0.0) / (p[1] - p[2] * vp)).powf(1.0 / p[3])
}

/// A table of `f` over a positive range, indexed by the bit pattern of an `f32` input: each
/// octave is split into 2^[`SEGMENT_BITS`] equal linear segments (the top mantissa bits) and
/// the value is interpolated linearly inside a segment. For the smooth, power-law-like curves
/// here (PU21, PQ) the interpolation error is below 1e-7 of the output range (see the tests),
/// far under any difference the metrics report, at the cost of a few nanoseconds per sample
/// instead of two `powf`.
struct OctaveLut {
    lo: f32,
    hi: f32,
    base_bits: u32,
    table: Vec<f64>,
}

/// Mantissa bits used for the segment index: 1024 segments per octave.
const SEGMENT_BITS: u32 = 10;
const SHIFT: u32 = 23 - SEGMENT_BITS;

impl OctaveLut {
    fn new(lo: f32, hi: f32, f: impl Fn(f64) -> f64) -> Self {
        let base_bits = lo.to_bits() & !((1 << SHIFT) - 1);
        let n = ((hi.to_bits() - base_bits) >> SHIFT) as usize + 2;
        let table = (0..n).map(|i| f(f32::from_bits(base_bits + ((i as u32) << SHIFT)) as f64)).collect();
        OctaveLut { lo, hi, base_bits, table }
    }

    /// `f(x)` for `x` in [lo, hi] (the caller clamps).
    #[inline]
    fn eval(&self, x: f32) -> f64 {
        debug_assert!(x >= self.lo && x <= self.hi);
        let off = x.to_bits() - self.base_bits;
        let i = (off >> SHIFT) as usize;
        let frac = (off & ((1 << SHIFT) - 1)) as f64 * (1.0 / (1u32 << SHIFT) as f64);
        let (a, b) = (self.table[i], self.table[i + 1]);
        a + (b - a) * frac
    }
}

/// PU21 over [L_min, L_max] as an [`OctaveLut`], built once.
fn pu21_lut() -> &'static OctaveLut {
    static LUT: std::sync::OnceLock<OctaveLut> = std::sync::OnceLock::new();
    LUT.get_or_init(|| OctaveLut::new(PU21_L_MIN as f32, PU21_L_MAX as f32, pu21_encode))
}

/// [`pu21_encode`] through the table: the same clamp, NaN as L_min.
#[inline]
fn pu21_fast(y_nits: f64) -> f64 {
    let y = y_nits as f32;
    let y = if y.is_nan() { PU21_L_MIN as f32 } else { y.clamp(PU21_L_MIN as f32, PU21_L_MAX as f32) };
    pu21_lut().eval(y)
}

/// Below this many cd/m² the PQ curve is evaluated exactly instead of from the table.
const PQ_TABLE_MIN: f32 = 1.0 / (1u32 << 20) as f32;

/// PQ over [2^-20, 10 000] cd/m² as an [`OctaveLut`], built once.
fn pq_lut() -> &'static OctaveLut {
    static LUT: std::sync::OnceLock<OctaveLut> = std::sync::OnceLock::new();
    LUT.get_or_init(|| OctaveLut::new(PQ_TABLE_MIN, PqTransfer::PEAK_NITS as f32, PqTransfer::encode))
}

/// [`PqTransfer::encode`] through the table.
#[inline]
fn pq_fast(nits: f64) -> f64 {
    let x = nits as f32;
    if x >= PQ_TABLE_MIN {
        pq_lut().eval(x.min(PqTransfer::PEAK_NITS as f32))
    } else {
        PqTransfer::encode(nits)
    }
}

/// [`rgb2020_to_ictcp`](crate::color::rgb2020_to_ictcp) with the tabulated PQ curve.
#[inline]
fn ictcp_fast(rgb_nits: [f64; 3]) -> [f64; 3] {
    let lms = mat_apply(&RGB2020_TO_LMS, rgb_nits);
    mat_apply(&LMS_P_TO_ICTCP, lms.map(pq_fast))
}

/// Replaces NaN by 0 and ±∞ by ±`f32::MAX`.
#[inline]
fn clean(v: f32) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        v.clamp(-f32::MAX, f32::MAX) as f64
    }
}

fn check_sizes(reference: &HdrImage, test: &HdrImage) -> Result<()> {
    if reference.width() != test.width() || reference.height() != test.height() {
        return Err(Error::invalid(format!(
            "image sizes differ: reference is {}x{}, test is {}x{}",
            reference.width(),
            reference.height(),
            test.width(),
            test.height()
        )));
    }
    Ok(())
}

/// The matrix that takes the test image's samples into the reference's primaries and units,
/// or `None` when they already agree.
fn test_to_reference(reference: &HdrImage, test: &HdrImage) -> Option<Mat3> {
    let (rc, tc) = (&reference.color, &test.color);
    let tp = test_primaries(reference, test);
    if rc.primaries == tp && rc.nits_per_unit == tc.nits_per_unit {
        return None;
    }
    let scale = tc.nits_per_unit as f64 / rc.nits_per_unit as f64;
    let m = rgb_to_rgb(&tp, &rc.primaries);
    Some(m.map(|row| row.map(|v| v * scale)))
}

/// The primaries the test image's samples are taken to be in: its own, or the reference's when
/// its file recorded none.
pub fn test_primaries(reference: &HdrImage, test: &HdrImage) -> ColorPrimaries {
    match test.color.primaries {
        ColorPrimaries::Unspecified => reference.color.primaries,
        p => p,
    }
}

/// Calls `f(reference_rgb, test_rgb)` for every pixel, both cleaned and in reference units.
fn for_each_pair(reference: &HdrImage, test: &HdrImage, mut f: impl FnMut([f64; 3], [f64; 3])) -> Result<()> {
    check_sizes(reference, test)?;
    let m = test_to_reference(reference, test);
    let (nr, nt) = (reference.channels().count(), test.channels().count());
    let rs = reference.samples().chunks_exact(nr);
    let ts = test.samples().chunks_exact(nt);
    for (r, t) in rs.zip(ts) {
        let r = [clean(r[0]), clean(r[1]), clean(r[2])];
        let mut t = [clean(t[0]), clean(t[1]), clean(t[2])];
        if let Some(m) = &m {
            t = mat_apply(m, t);
        }
        f(r, t);
    }
    Ok(())
}

/// 10·log10(peak² / MSE); infinite when the MSE is 0 (also for an empty image).
fn psnr_from(sum_sq: f64, count: usize, peak: f64) -> f64 {
    if sum_sq == 0.0 || count == 0 {
        return f64::INFINITY;
    }
    10.0 * (peak * peak / (sum_sq / count as f64)).log10()
}

/// What the per-sample metrics need to know about the reference.
struct Params {
    /// Luminance weights of the reference's primaries.
    w: [f64; 3],
    /// cd/m² per sample unit of the reference (the test is converted to it).
    nits: f64,
    /// The relative-error floor in sample units.
    floor: f64,
}

/// Running sums of the per-sample metrics; each `add_*` is one metric's per-pixel term, so
/// the single-metric functions and the fused [`compare`] share one definition of each.
#[derive(Default)]
struct Sums {
    pu21_y: f64,
    pu21_rgb: f64,
    log: f64,
    sq: f64,
    max_rel: f64,
}

impl Sums {
    #[inline]
    fn add_pu21_y(&mut self, p: &Params, r: [f64; 3], t: [f64; 3]) {
        let y = |v: [f64; 3]| (p.w[0] * v[0] + p.w[1] * v[1] + p.w[2] * v[2]) * p.nits;
        let d = pu21_fast(y(r)) - pu21_fast(y(t));
        self.pu21_y += d * d;
    }
    #[inline]
    fn add_pu21_rgb(&mut self, p: &Params, r: [f64; 3], t: [f64; 3]) {
        for c in 0..3 {
            let d = pu21_fast(r[c] * p.nits) - pu21_fast(t[c] * p.nits);
            self.pu21_rgb += d * d;
        }
    }
    #[inline]
    fn add_log(&mut self, r: [f64; 3], t: [f64; 3]) {
        for c in 0..3 {
            let d = ((t[c].max(0.0) + 1.0) / (r[c].max(0.0) + 1.0)).log2();
            self.log += d * d;
        }
    }
    #[inline]
    fn add_sq(&mut self, r: [f64; 3], t: [f64; 3]) {
        for c in 0..3 {
            let d = t[c] - r[c];
            self.sq += d * d;
        }
    }
    #[inline]
    fn add_rel(&mut self, p: &Params, r: [f64; 3], t: [f64; 3]) {
        for c in 0..3 {
            self.max_rel = self.max_rel.max((t[c] - r[c]).abs() / r[c].abs().max(p.floor));
        }
    }
}

/// Runs `add` over every pixel pair that differs (every metric's term is 0 for equal pixels).
fn accumulate(
    reference: &HdrImage,
    test: &HdrImage,
    mut add: impl FnMut(&mut Sums, &Params, [f64; 3], [f64; 3]),
) -> Result<Sums> {
    let nits = reference.color.nits_per_unit as f64;
    let p = Params {
        w: crate::color::luminance_weights(&reference.color.primaries),
        nits,
        floor: REL_ERR_FLOOR_NITS / nits,
    };
    let mut sums = Sums::default();
    for_each_pair(reference, test, |r, t| {
        if r != t {
            add(&mut sums, &p, r, t);
        }
    })?;
    Ok(sums)
}

/// PU21-PSNR on luminance: Y = the Y row of the reference's RGB→XYZ matrix (the test is in
/// the reference's primaries, see the module notes) times `nits_per_unit`, PU21-encoded,
/// PSNR with peak 256. Infinite for identical luminance.
pub fn pu21_psnr(reference: &HdrImage, test: &HdrImage) -> Result<f64> {
    let s = accumulate(reference, test, |s, p, r, t| s.add_pu21_y(p, r, t))?;
    Ok(psnr_from(s.pu21_y, reference.pixel_count(), PU21_PEAK))
}

/// PU21-PSNR per channel (the "PSNR (colour)" of the PU21 reference code): each of R, G and B
/// times `nits_per_unit` is PU21-encoded; the MSE is over all three channels.
pub fn pu21_psnr_rgb(reference: &HdrImage, test: &HdrImage) -> Result<f64> {
    let s = accumulate(reference, test, |s, p, r, t| s.add_pu21_rgb(p, r, t))?;
    Ok(psnr_from(s.pu21_rgb, 3 * reference.pixel_count(), PU21_PEAK))
}

/// The matrix from an image's samples to linear BT.2020 RGB in cd/m².
fn to_bt2020_nits(image: &HdrImage, primaries: &ColorPrimaries) -> Mat3 {
    let m = rgb_to_rgb(primaries, &ColorPrimaries::Bt2020);
    let s = image.color.nits_per_unit as f64;
    mat_mul(&[[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]], &m)
}

/// Calls `f` with the ΔE ITP of every pixel, in order (see [`delta_e_itp`]).
fn for_each_delta_e_itp(reference: &HdrImage, test: &HdrImage, mut f: impl FnMut(f64)) -> Result<()> {
    check_sizes(reference, test)?;
    let (mr, mt) =
        (to_bt2020_nits(reference, &reference.color.primaries), to_bt2020_nits(test, &test_primaries(reference, test)));
    let (nr, nt) = (reference.channels().count(), test.channels().count());
    for (r, t) in reference.samples().chunks_exact(nr).zip(test.samples().chunks_exact(nt)) {
        let r = [clean(r[0]), clean(r[1]), clean(r[2])];
        let t = [clean(t[0]), clean(t[1]), clean(t[2])];
        f(if r == t && mr == mt {
            0.0
        } else {
            crate::color::delta_e_itp_ictcp(ictcp_fast(mat_apply(&mr, r)), ictcp_fast(mat_apply(&mt, t)))
        });
    }
    Ok(())
}

/// ΔE ITP (ITU-R BT.2124) per pixel: both images are converted to linear BT.2020 in cd/m²
/// (their own primaries and `nits_per_unit`), then to ICtCp through PQ (BT.2100), and
/// ΔE = 720·√(ΔI² + (0.5·ΔCt)² + ΔCp²). Returns (mean, 99th percentile); the percentile is the
/// nearest-rank one (the ⌈0.99·N⌉-th smallest value). One unit is about one JND.
pub fn delta_e_itp(reference: &HdrImage, test: &HdrImage) -> Result<(f64, f64)> {
    let mut de: Vec<f32> = Vec::with_capacity(reference.pixel_count());
    let mut sum = 0.0;
    for_each_delta_e_itp(reference, test, |e| {
        sum += e;
        de.push(e as f32);
    })?;
    if de.is_empty() {
        return Ok((0.0, 0.0));
    }
    let mean = sum / de.len() as f64;
    let rank = ((0.99 * de.len() as f64).ceil() as usize).clamp(1, de.len()) - 1;
    let (_, p99, _) = de.select_nth_unstable_by(rank, f32::total_cmp);
    Ok((mean, *p99 as f64))
}

/// The ΔE ITP of every pixel, row by row (width × height values), as [`delta_e_itp`] computes
/// them: the map behind its mean and percentile (`hdrcodec compare --heatmap` draws it).
pub fn delta_e_itp_map(reference: &HdrImage, test: &HdrImage) -> Result<Vec<f32>> {
    let mut de: Vec<f32> = Vec::with_capacity(reference.pixel_count());
    for_each_delta_e_itp(reference, test, |e| de.push(e as f32))?;
    Ok(de)
}

/// RMSLE, the figure of the published BC6H comparisons: √(mean over all R, G, B samples of
/// log2((t + 1) / (r + 1))²), on the raw sample values (not cd/m²), as the BC6H literature
/// computes it on texture values. Negative samples are taken as 0.
pub fn log_rmse(reference: &HdrImage, test: &HdrImage) -> Result<f64> {
    let s = accumulate(reference, test, |s, _, r, t| s.add_log(r, t))?;
    Ok(rmsle_from(s.log, 3 * reference.pixel_count()))
}

fn rmsle_from(sum: f64, n: usize) -> f64 {
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Linear PSNR over all R, G, B samples against `peak` (in sample units):
/// 10·log10(peak² / MSE). Infinite when the images agree.
pub fn psnr(reference: &HdrImage, test: &HdrImage, peak: f64) -> Result<f64> {
    let s = accumulate(reference, test, |s, _, r, t| s.add_sq(r, t))?;
    Ok(psnr_from(s.sq, 3 * reference.pixel_count(), peak))
}

/// The luminance below which relative errors are measured against a floor instead of the
/// reference value, cd/m²: PU21's L_min, below which differences are invisible.
pub const REL_ERR_FLOOR_NITS: f64 = PU21_L_MIN;

/// The largest relative error over all R, G, B samples: |t − r| / max(|r|, floor), where the
/// floor is [`REL_ERR_FLOOR_NITS`] (0.005 cd/m²) in the reference's sample units, so that
/// near-black samples do not make the figure explode.
pub fn max_rel_err(reference: &HdrImage, test: &HdrImage) -> Result<f64> {
    Ok(accumulate(reference, test, |s, p, r, t| s.add_rel(p, r, t))?.max_rel)
}

/// Every metric of this module for one pair of images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparison {
    /// PU21-PSNR on luminance, dB ([`pu21_psnr`]).
    pub pu21_psnr: f64,
    /// PU21-PSNR per channel, dB ([`pu21_psnr_rgb`]).
    pub pu21_psnr_rgb: f64,
    /// Mean ΔE ITP ([`delta_e_itp`]).
    pub de_itp_mean: f64,
    /// 99th percentile of ΔE ITP.
    pub de_itp_p99: f64,
    /// RMSLE ([`log_rmse`]).
    pub log_rmse: f64,
    /// Linear PSNR with the reference's largest sample as peak, dB ([`psnr`]).
    pub psnr: f64,
    /// Largest relative error ([`max_rel_err`]).
    pub max_rel_err: f64,
    /// Every R, G, B sample is equal (NaN equals NaN) and so are primaries and `nits_per_unit`.
    pub identical: bool,
}

/// All metrics at once. The linear PSNR's peak is the largest R, G or B sample of the reference
/// (1.0 if it has no positive sample). Identical images give infinite PSNRs, zero errors and
/// `identical = true`.
pub fn compare(reference: &HdrImage, test: &HdrImage) -> Result<Comparison> {
    check_sizes(reference, test)?;
    let peak = reference.rgb().flatten().map(clean).fold(0.0f64, f64::max);
    let peak = if peak > 0.0 { peak } else { 1.0 };
    let (de_itp_mean, de_itp_p99) = delta_e_itp(reference, test)?;
    let same = |a: f32, b: f32| a == b || (a.is_nan() && b.is_nan());
    let identical = reference.color.primaries == test_primaries(reference, test)
        && reference.color.nits_per_unit == test.color.nits_per_unit
        && reference.rgb().zip(test.rgb()).all(|(r, t)| (0..3).all(|c| same(r[c], t[c])));
    let s = accumulate(reference, test, |s, p, r, t| {
        s.add_pu21_y(p, r, t);
        s.add_pu21_rgb(p, r, t);
        s.add_log(r, t);
        s.add_sq(r, t);
        s.add_rel(p, r, t);
    })?;
    let n = reference.pixel_count();
    Ok(Comparison {
        pu21_psnr: psnr_from(s.pu21_y, n, PU21_PEAK),
        pu21_psnr_rgb: psnr_from(s.pu21_rgb, 3 * n, PU21_PEAK),
        de_itp_mean,
        de_itp_p99,
        log_rmse: rmsle_from(s.log, 3 * n),
        psnr: psnr_from(s.sq, 3 * n, peak),
        max_rel_err: s.max_rel,
        identical,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::ictcp_to_rgb2020;
    use crate::{Channels, ColorInfo};

    fn grey(w: u32, h: u32, v: f32) -> HdrImage {
        HdrImage::new(w, h, Channels::Rgb, vec![v; (w * h * 3) as usize], ColorInfo::default()).unwrap()
    }

    fn from_pixels(pixels: &[[f32; 3]], color: ColorInfo) -> HdrImage {
        let samples = pixels.iter().flatten().copied().collect();
        HdrImage::new(pixels.len() as u32, 1, Channels::Rgb, samples, color).unwrap()
    }

    #[test]
    fn pu21_encoding_properties() {
        // No input/output pair is published for PU21 (neither the PCS 2021 paper nor the
        // gfxdisp/pu21 repository lists one), so this pins the properties the reference code
        // (pu21_encoder.m) defines: the clamp to [0.005, 10000], monotonicity, its own decode
        // as the inverse, V = 0 at L_min, and ~256 at 100 cd/m² (why pu21_metric.m uses
        // PSNR peak 256: an SDR display's white lands on the 8-bit range).
        assert!(pu21_encode(PU21_L_MIN).abs() < 1e-6);
        let v100 = pu21_encode(100.0);
        assert!((255.0..258.0).contains(&v100), "V(100) = {v100}");
        assert_eq!(pu21_encode(0.0), pu21_encode(PU21_L_MIN));
        assert_eq!(pu21_encode(-5.0), pu21_encode(PU21_L_MIN));
        assert_eq!(pu21_encode(f64::NAN), pu21_encode(PU21_L_MIN));
        assert_eq!(pu21_encode(1e6), pu21_encode(PU21_L_MAX));
        let vmax = pu21_encode(PU21_L_MAX);
        assert!((590.0..600.0).contains(&vmax), "V(10000) = {vmax}");
        let mut prev = f64::NEG_INFINITY;
        for i in 0..=600 {
            let y = PU21_L_MIN * 10f64.powf(i as f64 * (PU21_L_MAX / PU21_L_MIN).log10() / 600.0);
            let v = pu21_encode(y);
            assert!(v > prev, "not increasing at {y}");
            prev = v;
            let back = pu21_decode(v);
            assert!((back - y).abs() <= 1e-8 * y, "{y} -> {v} -> {back}");
        }
    }

    #[test]
    fn tables_follow_the_exact_curves() {
        // The octave tables used per pixel against the exact formulas, densely (every 997th f32
        // in range, so every 8192-value segment is hit at several offsets).
        let check = |lo: f32, hi: f32, fast: &dyn Fn(f64) -> f64, exact: &dyn Fn(f64) -> f64, tol: f64| {
            let mut worst = 0.0f64;
            let mut b = lo.to_bits();
            while b <= hi.to_bits() {
                let x = f32::from_bits(b) as f64;
                worst = worst.max((fast(x) - exact(x)).abs());
                b += 997;
            }
            assert!(worst < tol, "worst {worst}");
            worst
        };
        let pu = check(0.005, 10000.0, &pu21_fast, &pu21_encode, 1e-4);
        let pq = check(PQ_TABLE_MIN, 10000.0, &pq_fast, &PqTransfer::encode, 5e-8);
        println!("table error: PU21 {pu:.2e} (of ~600), PQ {pq:.2e} (of 1)");
        assert_eq!(pq_fast(1e-9), PqTransfer::encode(1e-9));
        assert!((pu21_fast(f64::NAN) - pu21_encode(f64::NAN)).abs() < 1e-4);
        assert!((pu21_fast(1e9) - pu21_encode(1e9)).abs() < 1e-4);
    }

    #[test]
    fn pu21_psnr_of_a_one_unit_shift() {
        // A test image whose PU21 value is the reference's plus exactly 1 everywhere has
        // MSE 1, so PSNR = 20·log10(256) = 48.1648 dB (pu21_metric.m's psnr(T, R, 256)).
        let reference = grey(4, 3, 1.0); // 100 cd/m² grey
        let shifted = (pu21_decode(pu21_encode(100.0) + 1.0) / 100.0) as f32;
        let test = grey(4, 3, shifted);
        let want = 20.0 * 256f64.log10();
        assert!((pu21_psnr(&reference, &test).unwrap() - want).abs() < 1e-3);
        assert!((pu21_psnr_rgb(&reference, &test).unwrap() - want).abs() < 1e-3);
        assert_eq!(pu21_psnr(&reference, &reference).unwrap(), f64::INFINITY);
    }

    #[test]
    fn delta_e_itp_matches_the_reference_example_on_images() {
        // colour-science delta_E_ITP docs example: these two ICtCp values differ by 1.42657228.
        let a = ictcp_to_rgb2020([0.488_546_807_2, -0.047_393_506_75, 0.074_754_013_02]);
        let b = ictcp_to_rgb2020([0.489_920_323_1, -0.045_675_082_03, 0.073_613_417_75]);
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 1.0, hdr10: None };
        let px = |v: [f64; 3]| v.map(|c| c as f32);
        let reference = from_pixels(&[px(a)], color.clone());
        let test = from_pixels(&[px(b)], color.clone());
        let (mean, p99) = delta_e_itp(&reference, &test).unwrap();
        assert!((mean - 1.426_572_28).abs() < 2e-3, "{mean}");
        assert_eq!(mean as f32, p99 as f32);
        // Nearest-rank 99th percentile of 100 pixels is the 99th smallest: with one differing
        // pixel it is 0, with two it is that pixel's ΔE.
        let mut r = vec![px(a); 100];
        let mut t = r.clone();
        t[7] = px(b);
        let (mean1, p99_1) = delta_e_itp(&from_pixels(&r, color.clone()), &from_pixels(&t, color.clone())).unwrap();
        assert!((mean1 - mean / 100.0).abs() < 1e-9 && p99_1 == 0.0);
        t[50] = px(b);
        r[0] = px(a);
        let (_, p99_2) = delta_e_itp(&from_pixels(&r, color.clone()), &from_pixels(&t, color)).unwrap();
        assert_eq!(p99_2 as f32, p99 as f32);
    }

    #[test]
    fn the_delta_e_itp_map_is_what_the_mean_and_percentile_summarise() {
        // The colour-science example pair of the test above at pixel 7 of 10: 1.42657228 there,
        // 0 elsewhere, and the map's mean is delta_e_itp's.
        let a = ictcp_to_rgb2020([0.488_546_807_2, -0.047_393_506_75, 0.074_754_013_02]).map(|c| c as f32);
        let b = ictcp_to_rgb2020([0.489_920_323_1, -0.045_675_082_03, 0.073_613_417_75]).map(|c| c as f32);
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 1.0, hdr10: None };
        let r = vec![a; 10];
        let mut t = r.clone();
        t[7] = b;
        let (reference, test) = (from_pixels(&r, color.clone()), from_pixels(&t, color));
        let map = delta_e_itp_map(&reference, &test).unwrap();
        assert_eq!(map.len(), 10);
        assert!((map[7] as f64 - 1.426_572_28).abs() < 2e-3, "{}", map[7]);
        assert!(map.iter().enumerate().all(|(i, &e)| i == 7 || e == 0.0));
        let (mean, _) = delta_e_itp(&reference, &test).unwrap();
        assert!((map.iter().map(|&e| e as f64).sum::<f64>() / 10.0 - mean).abs() < 1e-7);
        assert!(delta_e_itp_map(&reference, &grey(3, 3, 1.0)).is_err());
    }

    #[test]
    fn delta_e_itp_sees_through_primaries() {
        // The same colours stored in BT.709 and in BT.2020 are (nearly) the same colours.
        let reference = from_pixels(&[[1.0, 0.2, 0.05], [0.1, 0.5, 3.0]], ColorInfo::default());
        let test = crate::color::convert_primaries(&reference, ColorPrimaries::Bt2020);
        let (mean, p99) = delta_e_itp(&reference, &test).unwrap();
        assert!(mean < 0.01 && p99 < 0.01, "{mean} {p99}");
        let c = compare(&reference, &test).unwrap();
        assert!(!c.identical && c.psnr > 100.0, "{c:?}");
    }

    #[test]
    fn an_unspecified_test_image_is_scored_in_the_reference_s_primaries() {
        // Pure BT.2020 green and red, as a PFM or DDS of these samples reads back: the same
        // samples, primaries unspecified. Scored as what they are, the reference's colours.
        let bt2020 = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None };
        let pixels = [[0.0, 5.0, 0.0], [2.0, 0.0, 0.0], [0.3, 0.3, 0.3]];
        let reference = from_pixels(&pixels, bt2020.clone());
        let unspecified = ColorInfo { primaries: ColorPrimaries::Unspecified, ..bt2020.clone() };
        let test = from_pixels(&pixels, unspecified);
        assert_eq!(test_primaries(&reference, &test), ColorPrimaries::Bt2020);
        let c = compare(&reference, &test).unwrap();
        assert!(c.identical, "{c:?}");
        assert_eq!((c.de_itp_mean, c.de_itp_p99, c.max_rel_err), (0.0, 0.0, 0.0));
        assert_eq!((c.pu21_psnr, c.psnr), (f64::INFINITY, f64::INFINITY));
        // Read as BT.709 instead (what a tool that guessed would do) they are other colours.
        let guessed = compare(&reference, &from_pixels(&pixels, ColorInfo::default())).unwrap();
        assert!(!guessed.identical && guessed.de_itp_mean > 10.0, "{guessed:?}");
        // One code step off in the test image: the same figure as a BT.2020-labelled test.
        let mut off = pixels;
        off[0][1] = 5.01;
        let as_unspecified = compare(&reference, &from_pixels(&off, test.color.clone())).unwrap();
        let as_bt2020 = compare(&reference, &from_pixels(&off, bt2020)).unwrap();
        assert_eq!(as_unspecified, as_bt2020);
        // An unspecified reference is taken as BT.709 (and so is an unspecified test against it).
        let unspecified_ref = from_pixels(&pixels, test.color.clone());
        let c = compare(&unspecified_ref, &from_pixels(&pixels, ColorInfo::default())).unwrap();
        assert_eq!((c.de_itp_mean, c.psnr), (0.0, f64::INFINITY));
        assert!(compare(&unspecified_ref, &test).unwrap().identical);
    }

    #[test]
    fn log_rmse_psnr_and_relative_error_by_hand() {
        // RMSLE: one of three samples goes 1 → 3, log2(4/2) = 1, so √(1/3).
        let reference = from_pixels(&[[1.0, 1.0, 1.0]], ColorInfo::default());
        let test = from_pixels(&[[3.0, 1.0, 1.0]], ColorInfo::default());
        assert!((log_rmse(&reference, &test).unwrap() - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
        // PSNR: one of 12 samples off by 0.5 against peak 1: MSE = 0.25/12, 10·log10(48).
        let reference = grey(2, 2, 1.0);
        let mut test = reference.clone();
        test.samples_mut()[5] = 1.5;
        assert!((psnr(&reference, &test, 1.0).unwrap() - 10.0 * 48f64.log10()).abs() < 1e-12);
        assert!((max_rel_err(&reference, &test).unwrap() - 0.5).abs() < 1e-12);
        // Near zero the floor (0.005 cd/m² = 5e-5 at 100 cd/m² per unit) is the denominator.
        let reference = grey(1, 1, 0.0);
        let test = grey(1, 1, 1e-5);
        assert!((max_rel_err(&reference, &test).unwrap() - 0.2).abs() < 1e-6);
    }

    #[test]
    fn identical_images_compare_perfectly() {
        let samples: Vec<f32> = (0..24).map(|i| i as f32 * 0.37).collect();
        let a = HdrImage::new(3, 2, Channels::Rgba, samples.clone(), ColorInfo::default()).unwrap();
        let mut b = a.clone();
        b.samples_mut()[3] = 0.123; // alpha is ignored
        let c = compare(&a, &b).unwrap();
        assert!(c.identical);
        assert_eq!((c.pu21_psnr, c.pu21_psnr_rgb, c.psnr), (f64::INFINITY, f64::INFINITY, f64::INFINITY));
        assert_eq!((c.de_itp_mean, c.de_itp_p99, c.log_rmse, c.max_rel_err), (0.0, 0.0, 0.0, 0.0));
        // RGB against RGBA of the same picture is still identical.
        assert!(compare(&a, &a.with_channels(Channels::Rgb)).unwrap().identical);
    }

    #[test]
    fn sizes_units_and_nan() {
        let e = compare(&grey(2, 2, 1.0), &grey(3, 2, 1.0)).unwrap_err();
        assert!(matches!(e, Error::Invalid { .. }));
        let msg = e.to_string();
        assert!(msg.contains("2x2") && msg.contains("3x2"), "{msg}");
        // The same light at 100 and at 200 cd/m² per unit: not identical, but no error.
        let a = grey(2, 2, 1.0);
        let mut b = grey(2, 2, 0.5);
        b.color.nits_per_unit = 200.0;
        let c = compare(&a, &b).unwrap();
        assert!(!c.identical && c.psnr == f64::INFINITY && c.de_itp_mean == 0.0, "{c:?}");
        // NaN and infinity neither panic nor poison the figures.
        let mut n = grey(2, 2, 1.0);
        n.samples_mut()[0] = f32::NAN;
        n.samples_mut()[4] = f32::INFINITY;
        let c = compare(&a, &n).unwrap();
        assert!(!c.identical);
        for v in [c.pu21_psnr, c.pu21_psnr_rgb, c.de_itp_mean, c.de_itp_p99, c.log_rmse, c.psnr, c.max_rel_err] {
            assert!(!v.is_nan(), "{c:?}");
        }
        assert!(compare(&n, &n).unwrap().identical);
    }
}
