//! An SDR rendition of HDR frames, the course's "single source, multiple outputs": core's GT
//! tone curve for an SDR display's peak, applied through its LUT form ([`GtToneLut`], the
//! square-root-indexed table of the Gran Turismo pipeline) to each of R, G, B in BT.709
//! primaries, then the sRGB OETF, then 8-bit BT.709 Y'CbCr, limited range. The AV1 stream says
//! so with the H.273 triple primaries 1 (BT.709), transfer 13 (sRGB, IEC 61966-2-1), matrix 1
//! (BT.709).
//!
//! Scene values are taken relative to a paper white of [`PAPER_WHITE_NITS`] (the family's
//! default `nits_per_unit`), and the curve's maximum P is the display peak over paper white, so
//! that a 100 cd/m² display gets the CEDEC curve as published (P = 1) and a brighter one keeps
//! scene white where it was and spends the rest on highlights.

use crate::hdr10::{signals_to_yuv, yuv_to_signals, ChromaSiting, Range, Subsampling, YuvFrame};
use hdrcodec_core::color::convert_primaries;
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, Error, GtToneCurve, GtToneLut, HdrImage, Result, SrgbTransfer,
    YcbcrCoefficients,
};

/// The bits per sample of SDR streams.
pub const SDR_BIT_DEPTH: u32 = 8;
/// cd/m² of scene paper white: the tone curve's input 1.0.
pub const PAPER_WHITE_NITS: f64 = 100.0;

/// The tone mapping and signal of an SDR rendition for a display of a given peak.
#[derive(Clone, Debug, PartialEq)]
pub struct SdrRendition {
    lut: GtToneLut,
    /// The curve's maximum P (display peak / paper white).
    max_brightness: f32,
    peak_nits: f64,
}

impl SdrRendition {
    /// The rendition for an SDR display of `peak_nits` (50 to 1000 cd/m²).
    pub fn new(peak_nits: f64) -> Result<Self> {
        if !(50.0..=1000.0).contains(&peak_nits) {
            return Err(Error::invalid(format!("an SDR display peak of {peak_nits} cd/m² (50 to 1000 are taken)")));
        }
        let curve = GtToneCurve::for_display(peak_nits, PAPER_WHITE_NITS);
        Ok(SdrRendition {
            lut: GtToneLut::new(&curve, PAPER_WHITE_NITS),
            max_brightness: curve.max_brightness as f32,
            peak_nits,
        })
    }

    /// The display peak, cd/m².
    pub fn peak_nits(&self) -> f64 {
        self.peak_nits
    }

    /// The tone-mapped frame: display-linear BT.709, 1.0 = the display's peak (so
    /// `nits_per_unit` is the peak), every sample in [0, 1]; NaN and negatives become 0.
    pub fn display_light(&self, frame: &HdrImage) -> HdrImage {
        let mut out = convert_primaries(&frame.with_channels(Channels::Rgb), ColorPrimaries::Bt709);
        let scale = frame.color.nits_per_unit;
        for v in out.samples_mut() {
            let shown = self.lut.lookup(*v * scale) / self.max_brightness;
            *v = if shown.is_nan() { 0.0 } else { shown.clamp(0.0, 1.0) };
        }
        out.color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: self.peak_nits as f32, hdr10: None };
        out
    }

    /// The frame's 8-bit BT.709 limited-range planes (4:2:0 chroma co-sited with the top-left
    /// luma sample).
    pub fn frame_to_yuv(&self, frame: &HdrImage, subsampling: Subsampling) -> YuvFrame {
        let shown = self.display_light(frame);
        let signals = shown.rgb().map(|p| p.map(|v| SrgbTransfer::encode(f64::from(v))));
        let (w, h) = (shown.width() as usize, shown.height() as usize);
        signals_to_yuv(signals, w, h, YcbcrCoefficients::BT709, SDR_BIT_DEPTH, Range::Limited, subsampling)
    }
}

/// 8-bit BT.709 Y'CbCr on the sRGB transfer back to display-linear BT.709 (1.0 = the display's
/// peak, which is `nits_per_unit` cd/m²).
pub fn sdr_yuv_to_frame(yuv: &YuvFrame, range: Range, siting: ChromaSiting, nits_per_unit: f32) -> Result<HdrImage> {
    let signals = yuv_to_signals(yuv, SDR_BIT_DEPTH, YcbcrCoefficients::BT709, range, siting)?;
    let samples = signals.into_iter().flat_map(|s| s.map(|v| SrgbTransfer::decode(v.clamp(0.0, 1.0)) as f32)).collect();
    let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit, hdr10: None };
    let w = u32::try_from(yuv.width).map_err(|_| Error::unsupported("a frame wider than 2^32"))?;
    let h = u32::try_from(yuv.height).map_err(|_| Error::unsupported("a frame taller than 2^32"))?;
    HdrImage::new(w, h, Channels::Rgb, samples, color)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_white_and_highlights_on_a_100_nit_display() {
        let sdr = SdrRendition::new(100.0).unwrap();
        let grey = |nits: f32| {
            let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 100.0, hdr10: None };
            HdrImage::new(1, 1, Channels::Rgb, vec![nits / 100.0; 3], color).unwrap()
        };
        // The CEDEC curve (P = 1) through the LUT: what the curve itself gives, within the
        // table's interpolation.
        let curve = GtToneCurve::default();
        for nits in [0.0f32, 5.0, 18.0, 100.0, 1000.0, 40_000.0] {
            let shown = sdr.display_light(&grey(nits)).samples()[0];
            assert!((f64::from(shown) - curve.map(f64::from(nits) / 100.0)).abs() < 1e-3, "{nits}: {shown}");
        }
        // Black is code 16, the brightest highlights approach 235; grey has no colour.
        let yuv = sdr.frame_to_yuv(&grey(0.0), Subsampling::Yuv444);
        assert_eq!((yuv.y[0], yuv.cb[0], yuv.cr[0]), (16, 128, 128));
        let yuv = sdr.frame_to_yuv(&grey(40_000.0), Subsampling::Yuv444);
        assert!(yuv.y[0] >= 234 && yuv.cb[0] == 128, "{yuv:?}");
        // Back through the sRGB EOTF: the display light within an 8-bit step.
        let back = sdr_yuv_to_frame(&yuv, Range::Limited, ChromaSiting::Colocated, 100.0).unwrap();
        let want = sdr.display_light(&grey(40_000.0)).samples()[0];
        assert!((back.samples()[0] - want).abs() < 0.01, "{} vs {want}", back.samples()[0]);
        assert!(SdrRendition::new(10.0).is_err() && SdrRendition::new(f64::NAN).is_err());
    }
}
