//! Y'CbCr planes of an HDR10 (PQ) or HLG stream back to scene-linear light, fast: what the
//! decoder runs on every sample of every frame.
//!
//! [`YuvToLight`] does what [`hdr10::yuv_to_frame_bits`](crate::hdr10::yuv_to_frame_bits) does
//! (that f64 routine stays the reference, and the tests hold the two together) in `f32`, with
//! no plane of the frame's size but the output: codes are dequantized through tables built once
//! per stream, 4:2:0 chroma is upsampled one row at a time into a buffer of a band's own, the
//! PQ EOTF is a table of 65 536 steps interpolated linearly, and bands of rows run in parallel
//! on the caller's [`ThreadPool`]. The loops are plain indexed `f32` arithmetic the compiler
//! vectorises for the baseline target; there is no hand-written SIMD, so there is no
//! run-time dispatch either.

use crate::hdr10::{dequantize_bits, ChromaSiting, Range, Subsampling, Transfer, YuvFrame};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, HlgTransfer, PqTransfer, Result};
use hdrcodec_core::{ThreadPool, YcbcrCoefficients};
use std::sync::OnceLock;

/// Steps of the signal in the PQ EOTF table.
const PQ_INTERVALS: usize = 1 << 16;

/// Rows converted by one task of the pool.
const BAND_ROWS: usize = 16;

/// The PQ EOTF table: ST 2084's EOTF at 65 537 equally spaced signals, in cd/m².
type PqTable = [f32; PQ_INTERVALS + 1];

/// The PQ EOTF table, built on first use (256 KiB).
fn pq_table() -> &'static PqTable {
    static TABLE: OnceLock<Box<PqTable>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut table = Box::new([0f32; PQ_INTERVALS + 1]);
        for (i, v) in table.iter_mut().enumerate() {
            *v = PqTransfer::decode(i as f64 / PQ_INTERVALS as f64) as f32;
        }
        table
    })
}

/// The PQ EOTF of `signal` (clamped to 0..1; NaN reads as 0) from `table`, linearly
/// interpolated.
#[inline]
fn pq_eotf(table: &PqTable, signal: f32) -> f32 {
    // Comparisons rather than `clamp` (which keeps NaN) or `max`/`min` (which take care over
    // NaN): one instruction each, NaN reads as 0, and the pair stays inside the table.
    let s = if signal > 0.0 { signal } else { 0.0 };
    let x = if s < 1.0 { s } else { 1.0 } * PQ_INTERVALS as f32;
    let i = (x as i32).min(PQ_INTERVALS as i32 - 1) as usize;
    let f = x - i as f32;
    let (a, b) = (table[i], table[i + 1]);
    a + (b - a) * f
}

/// Converts the planes of one stream (bit depth, transfer, range and chroma siting fixed) to
/// scene-linear BT.2020 frames. Build it once per stream and reuse it for every frame.
#[derive(Clone, Debug)]
pub struct YuvToLight {
    transfer: Transfer,
    siting: ChromaSiting,
    /// 1 / `nits_per_unit`.
    scale: f32,
    /// Y' of every code of the depth.
    luma: Box<[f32]>,
    /// Cb or Cr of every code of the depth.
    chroma: Box<[f32]>,
}

impl YuvToLight {
    /// A converter for planes of `bits` bits (8 to 16) per sample: BT.2020 non-constant
    /// luminance Y'CbCr on `transfer`, in `range`, 4:2:0 chroma sited at `siting`, to frames
    /// whose 1.0 is `nits_per_unit` cd/m².
    pub fn new(bits: u32, transfer: Transfer, range: Range, siting: ChromaSiting, nits_per_unit: f32) -> Result<Self> {
        if !(8..=16).contains(&bits) {
            return Err(Error::unsupported(format!("{bits}-bit Y'CbCr (8 to 16 bits are read)")));
        }
        if !(nits_per_unit.is_finite() && nits_per_unit > 0.0) {
            return Err(Error::invalid(format!("nits_per_unit {nits_per_unit}")));
        }
        let table =
            |chroma: bool| (0..1u32 << bits).map(move |d| dequantize_bits(d as u16, bits, chroma, range) as f32);
        if transfer == Transfer::Pq {
            pq_table();
        }
        Ok(YuvToLight {
            transfer,
            siting,
            scale: 1.0 / nits_per_unit,
            luma: table(false).collect(),
            chroma: table(true).collect(),
        })
    }

    /// The frame of `yuv`, BT.2020, its bands of rows converted in parallel on `pool`.
    pub fn convert(&self, yuv: &YuvFrame, pool: &ThreadPool) -> Result<HdrImage> {
        let (w, h) = (yuv.width, yuv.height);
        let width = u32::try_from(w).map_err(|_| Error::unsupported("a frame wider than 2^32"))?;
        let height = u32::try_from(h).map_err(|_| Error::unsupported("a frame taller than 2^32"))?;
        let mut samples = vec![0f32; w * h * 3];
        self.convert_into(yuv, &mut samples, pool)?;
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 1.0 / self.scale, hdr10: None };
        HdrImage::new(width, height, Channels::Rgb, samples, color)
    }

    /// [`convert`](Self::convert) into `out`, `width × height × 3` interleaved RGB samples.
    pub fn convert_into(&self, yuv: &YuvFrame, out: &mut [f32], pool: &ThreadPool) -> Result<()> {
        let (w, h) = (yuv.width, yuv.height);
        let (cw, ch) = YuvFrame::chroma_size(w, h, yuv.subsampling);
        if yuv.y.len() != w * h || yuv.cb.len() != cw * ch || yuv.cr.len() != cw * ch || out.len() != w * h * 3 {
            return Err(Error::invalid(format!("Y'CbCr planes or output do not match a {w}x{h} frame")));
        }
        if w == 0 || h == 0 {
            return Ok(());
        }
        pool.for_each_chunk_mut(out, BAND_ROWS * w * 3, |band, rows| {
            // A band's own chroma rows: at chroma resolution (upsampled vertically), then at
            // luma resolution.
            let (mut cb, mut cr) = (vec![0f32; cw], vec![0f32; cw]);
            let (mut cb_full, mut cr_full) = (vec![0f32; w], vec![0f32; w]);
            for (i, row) in rows.chunks_exact_mut(w * 3).enumerate() {
                let y = band * BAND_ROWS + i;
                self.chroma_row(yuv, y, &yuv.cb, &mut cb);
                self.chroma_row(yuv, y, &yuv.cr, &mut cr);
                self.widen(&cb, yuv.subsampling, &mut cb_full);
                self.widen(&cr, yuv.subsampling, &mut cr_full);
                self.row(&yuv.y[y * w..(y + 1) * w], &cb_full, &cr_full, row);
            }
        });
        Ok(())
    }

    /// The chroma of luma row `y` at chroma resolution: the plane's row for 4:4:4; for 4:2:0 its
    /// two nearest chroma rows blended as the siting places them (edges repeat the last row).
    fn chroma_row(&self, yuv: &YuvFrame, y: usize, plane: &[u16], out: &mut [f32]) {
        let (cw, ch) = (out.len(), plane.len() / out.len().max(1));
        let code = |d: u16| self.chroma[usize::from(d).min(self.chroma.len() - 1)];
        let row = |cy: usize| &plane[cy * cw..(cy + 1) * cw];
        if yuv.subsampling == Subsampling::Yuv444 {
            out.iter_mut().zip(row(y)).for_each(|(o, &d)| *o = code(d));
            return;
        }
        let cy = y / 2;
        let (other, weight) = match (self.siting, y % 2) {
            (ChromaSiting::Colocated, 0) => (cy, 0.0),
            (ChromaSiting::Colocated, _) => ((cy + 1).min(ch - 1), 0.5),
            (ChromaSiting::Left | ChromaSiting::Center, 0) => (cy.saturating_sub(1), 0.25),
            (ChromaSiting::Left | ChromaSiting::Center, _) => ((cy + 1).min(ch - 1), 0.25),
        };
        for ((o, &a), &b) in out.iter_mut().zip(row(cy)).zip(row(other)) {
            let (a, b) = (code(a), code(b));
            *o = a + (b - a) * weight;
        }
    }

    /// A chroma row at chroma resolution → at luma resolution (`out.len()` samples): copied for
    /// 4:4:4; for 4:2:0 even columns take their sample and odd ones the mean of their two
    /// neighbours (chroma co-sited with even columns), or for centred chroma 3/4 of the nearest
    /// and 1/4 of the next (edges repeat the last sample).
    fn widen(&self, c: &[f32], subsampling: Subsampling, out: &mut [f32]) {
        if subsampling == Subsampling::Yuv444 {
            out.copy_from_slice(c);
            return;
        }
        let last = c[c.len() - 1];
        let (even, odd): (f32, f32) = if self.siting == ChromaSiting::Center { (0.25, 0.25) } else { (0.0, 0.5) };
        // Even column 2j: c[j] and (centred) a quarter of c[j − 1]; odd column 2j + 1: c[j]
        // and a quarter (centred) or a half of c[j + 1].
        let mut prev = c[0];
        for (j, pair) in out.chunks_mut(2).enumerate() {
            let here = c[j];
            let next = c.get(j + 1).copied().unwrap_or(last);
            pair[0] = here + (prev - here) * even;
            if let Some(o) = pair.get_mut(1) {
                *o = here + (next - here) * odd;
            }
            prev = here;
        }
    }

    /// The PQ row kernel's tables.
    fn pq_row(&self) -> PqRow<'_> {
        PqRow { luma_lut: &self.luma, table: pq_table(), scale: self.scale }
    }

    /// One row of light from its luma codes and its chroma at luma resolution.
    fn row(&self, luma: &[u16], cb: &[f32], cr: &[f32], out: &mut [f32]) {
        match self.transfer {
            Transfer::Pq => pq_row(self.pq_row(), luma, cb, cr, out),
            Transfer::Hlg { peak_nits } => {
                let top = self.luma.len() - 1;
                for (((px, &d), &cb), &cr) in out.chunks_exact_mut(3).zip(luma).zip(cb).zip(cr) {
                    let s = signals(self.luma[usize::from(d).min(top)], cb, cr);
                    let light = HlgTransfer::eotf(s.map(|v| f64::from(v).clamp(0.0, 1.0)), peak_nits, 0.0);
                    px.copy_from_slice(&light.map(|v| v as f32 * self.scale));
                }
            }
        }
    }
}

/// R'G'B' of Y' and Cb, Cr (BT.2020 non-constant luminance, BT.2020 Table 4's weights).
#[inline(always)]
fn signals(yl: f32, cb: f32, cr: f32) -> [f32; 3] {
    let (kr, kb) = (YcbcrCoefficients::BT2020.kr as f32, YcbcrCoefficients::BT2020.kb as f32);
    let r = yl + 2.0 * (1.0 - kr) * cr;
    let b = yl + 2.0 * (1.0 - kb) * cb;
    [r, (yl - kr * r - kb * b) * (1.0 / (1.0 - kr - kb)), b]
}

/// What a row of PQ light is made with: Y' of each luma code (`luma_lut`; codes past its end
/// read its last entry), the EOTF `table`, and the `scale` of the output samples.
#[derive(Clone, Copy)]
struct PqRow<'a> {
    luma_lut: &'a [f32],
    table: &'a PqTable,
    scale: f32,
}

/// A row of PQ light: R'G'B' of the luma codes with the row's chroma, the EOTF, times the
/// scale, into `out` (interleaved RGB). The AVX2 kernel where the CPU has it, chosen at run
/// time, else the portable loop; both give the same bits.
#[allow(unsafe_code)]
fn pq_row(k: PqRow, luma: &[u16], cb: &[f32], cr: &[f32], out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
        return unsafe { pq_row_avx2(k, luma, cb, cr, out) };
    }
    pq_row_portable(k, luma, cb, cr, out)
}

/// [`pq_row_portable`] with AVX2 intrinsics, eight pixels at a time (the compiler does not
/// gather by itself): the same operations in the same order on each lane, so the same bits;
/// the last pixels (fewer than eight) go through the portable loop.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn pq_row_avx2(k: PqRow, luma: &[u16], cb: &[f32], cr: &[f32], out: &mut [f32]) {
    use std::arch::x86_64::*;
    let PqRow { luma_lut, table, scale } = k;
    let n = luma.len().min(cb.len()).min(cr.len()).min(out.len() / 3);
    if luma_lut.is_empty() || luma_lut.len() > i32::MAX as usize {
        return pq_row_portable(k, luma, cb, cr, out);
    }
    let (kr, kb) = (YcbcrCoefficients::BT2020.kr as f32, YcbcrCoefficients::BT2020.kb as f32);
    let set = |v: f32| _mm256_set1_ps(v);
    let (r_cr, b_cb, inv_kg) = (set(2.0 * (1.0 - kr)), set(2.0 * (1.0 - kb)), set(1.0 / (1.0 - kr - kb)));
    let (vkr, vkb, zero, one, steps, vscale) =
        (set(kr), set(kb), set(0.0), set(1.0), set(PQ_INTERVALS as f32), set(scale));
    let top = _mm256_set1_epi32(luma_lut.len() as i32 - 1);
    let last_step = _mm256_set1_epi32(PQ_INTERVALS as i32 - 1);
    let eotf = |s: __m256| {
        // max(s, 0) gives 0 for NaN and −0, min(·, 1) then s or 1: `pq_eotf`'s comparisons.
        let xf = _mm256_mul_ps(_mm256_min_ps(_mm256_max_ps(s, zero), one), steps);
        let i = _mm256_min_epi32(_mm256_cvttps_epi32(xf), last_step);
        let f = _mm256_sub_ps(xf, _mm256_cvtepi32_ps(i));
        // SAFETY: 0 <= i <= PQ_INTERVALS − 1, so i and i + 1 index the table's
        // PQ_INTERVALS + 1 entries.
        let (a, b) = unsafe {
            (_mm256_i32gather_ps::<4>(table.as_ptr(), i), _mm256_i32gather_ps::<4>(table.as_ptr().add(1), i))
        };
        _mm256_mul_ps(_mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), f)), vscale)
    };
    let mut x = 0;
    while x + 8 <= n {
        // SAFETY: x + 8 <= n, and n is at most the length of `luma`, `cb` and `cr`; each
        // luma index is at most the table's last (min with `top`).
        let (yl, vcb, vcr) = unsafe {
            let codes = _mm_loadu_si128(luma.as_ptr().add(x).cast::<__m128i>());
            let idx = _mm256_min_epi32(_mm256_cvtepu16_epi32(codes), top);
            (
                _mm256_i32gather_ps::<4>(luma_lut.as_ptr(), idx),
                _mm256_loadu_ps(cb.as_ptr().add(x)),
                _mm256_loadu_ps(cr.as_ptr().add(x)),
            )
        };
        let r = _mm256_add_ps(yl, _mm256_mul_ps(r_cr, vcr));
        let b = _mm256_add_ps(yl, _mm256_mul_ps(b_cb, vcb));
        let g = _mm256_mul_ps(_mm256_sub_ps(_mm256_sub_ps(yl, _mm256_mul_ps(vkr, r)), _mm256_mul_ps(vkb, b)), inv_kg);
        let mut planar = [[0f32; 8]; 3];
        // SAFETY: each store writes the 8 floats of one array of `planar`.
        unsafe {
            _mm256_storeu_ps(planar[0].as_mut_ptr(), eotf(r));
            _mm256_storeu_ps(planar[1].as_mut_ptr(), eotf(g));
            _mm256_storeu_ps(planar[2].as_mut_ptr(), eotf(b));
        }
        for (l, px) in out[3 * x..3 * x + 24].chunks_exact_mut(3).enumerate() {
            px.copy_from_slice(&[planar[0][l], planar[1][l], planar[2][l]]);
        }
        x += 8;
    }
    pq_row_portable(k, &luma[x..n], &cb[x..n], &cr[x..n], &mut out[3 * x..3 * n]);
}

#[inline(always)]
fn pq_row_portable(k: PqRow, luma: &[u16], cb: &[f32], cr: &[f32], out: &mut [f32]) {
    let PqRow { luma_lut, table, scale } = k;
    let n = luma.len().min(cb.len()).min(cr.len()).min(out.len() / 3);
    let (luma, cb, cr, out) = (&luma[..n], &cb[..n], &cr[..n], &mut out[..3 * n]);
    let top = luma_lut.len().saturating_sub(1);
    if luma_lut.is_empty() {
        return;
    }
    for x in 0..n {
        let [r, g, b] = signals(luma_lut[usize::from(luma[x]).min(top)], cb[x], cr[x]);
        out[3 * x] = pq_eotf(table, r) * scale;
        out[3 * x + 1] = pq_eotf(table, g) * scale;
        out[3 * x + 2] = pq_eotf(table, b) * scale;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hdr10::yuv_to_frame_bits;

    /// Planes of pseudo-random codes of `bits` bits (a fixed LCG), in range for `range`.
    fn planes(w: usize, h: usize, subsampling: Subsampling, bits: u32, range: Range, seed: u32) -> YuvFrame {
        let mut state = seed;
        let (lo, hi) = match range {
            Range::Limited => (16u32 << (bits - 8), 240u32 << (bits - 8)),
            Range::Full => (0, (1 << bits) - 1),
        };
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (lo + (state >> 8) % (hi - lo + 1)) as u16
        };
        let (cw, ch) = YuvFrame::chroma_size(w, h, subsampling);
        YuvFrame {
            width: w,
            height: h,
            subsampling,
            y: (0..w * h).map(|_| next()).collect(),
            cb: (0..cw * ch).map(|_| next()).collect(),
            cr: (0..cw * ch).map(|_| next()).collect(),
        }
    }

    #[test]
    fn the_fast_path_matches_the_f64_reference() {
        let pool = ThreadPool::new(3).unwrap();
        let mut worst = 0f64;
        for (w, h) in [(1, 1), (2, 3), (7, 5), (33, 37)] {
            for subsampling in [Subsampling::Yuv420, Subsampling::Yuv444] {
                for siting in [ChromaSiting::Colocated, ChromaSiting::Left, ChromaSiting::Center] {
                    for (bits, transfer, range) in [
                        (10, Transfer::Pq, Range::Limited),
                        (10, Transfer::Pq, Range::Full),
                        (12, Transfer::Pq, Range::Limited),
                        (10, Transfer::HLG_1000, Range::Limited),
                    ] {
                        let yuv = planes(w, h, subsampling, bits, range, (w * h) as u32);
                        let reference = yuv_to_frame_bits(&yuv, bits, transfer, range, siting, 100.0).unwrap();
                        let fast = YuvToLight::new(bits, transfer, range, siting, 100.0).unwrap();
                        for p in [&ThreadPool::single(), &pool] {
                            let ours = fast.convert(&yuv, p).unwrap();
                            assert_eq!(ours.color, reference.color);
                            for (a, b) in ours.samples().iter().zip(reference.samples()) {
                                let (a, b) = (f64::from(*a), f64::from(*b));
                                // 2·10⁻⁵ of the value, or 10⁻⁶ cd/m² (10⁻⁸ of 1.0) near black,
                                // where PQ's relative slope is steepest.
                                let ok = (a - b).abs() <= 2e-5 * b.abs() + 1e-8;
                                assert!(ok, "{w}x{h} {subsampling:?} {siting:?} {transfer:?}: {a} vs {b}");
                                if b > 1e-5 {
                                    worst = worst.max((a - b).abs() / b);
                                }
                            }
                        }
                    }
                }
            }
        }
        eprintln!("worst relative difference from the f64 path above 10⁻³ cd/m²: {worst:.2e}");
    }

    #[test]
    fn the_avx2_row_gives_the_portable_row_s_bits() {
        let fast = YuvToLight::new(10, Transfer::Pq, Range::Full, ChromaSiting::Colocated, 100.0).unwrap();
        let n = 1003; // 125 blocks of eight and a tail of three
                      // Every luma code (and past the top), chroma from −0.6 to 0.6 (beyond the signal range)
                      // and NaN: every clamp taken.
        let luma: Vec<u16> = (0..n).map(|i| (i * 37 % 1100) as u16).collect();
        let mut cb: Vec<f32> = (0..n).map(|i| ((i * 13 % 97) as f32 / 96.0 - 0.5) * 1.2).collect();
        let cr: Vec<f32> = (0..n).map(|i| ((i * 29 % 89) as f32 / 88.0 - 0.5) * 1.2).collect();
        cb[5] = f32::NAN;
        let mut portable = vec![0f32; 3 * n];
        pq_row_portable(fast.pq_row(), &luma, &cb, &cr, &mut portable);
        assert!(portable.iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(portable.contains(&100.0) && portable.contains(&0.0), "both ends reached");
        #[cfg(target_arch = "x86_64")]
        if hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Avx2, "pq_row") {
            let mut twin = vec![0f32; 3 * n];
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { pq_row_avx2(fast.pq_row(), &luma, &cb, &cr, &mut twin) };
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&twin), bits(&portable));
        }
    }

    #[test]
    fn planes_that_do_not_match_the_frame_are_an_error() {
        let fast = YuvToLight::new(10, Transfer::Pq, Range::Limited, ChromaSiting::Colocated, 100.0).unwrap();
        let mut yuv = planes(4, 4, Subsampling::Yuv420, 10, Range::Limited, 1);
        yuv.cb.pop();
        assert!(fast.convert(&yuv, &ThreadPool::single()).is_err());
        let yuv = planes(4, 4, Subsampling::Yuv420, 10, Range::Limited, 1);
        assert!(fast.convert_into(&yuv, &mut [0.0; 47], &ThreadPool::single()).is_err());
        assert!(YuvToLight::new(7, Transfer::Pq, Range::Full, ChromaSiting::Left, 100.0).is_err());
        assert!(YuvToLight::new(10, Transfer::Pq, Range::Full, ChromaSiting::Left, 0.0).is_err());
    }
}
