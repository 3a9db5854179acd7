//! HDR10 and HLG sample conversion: scene-linear frames ↔ 10-bit BT.2020 non-constant-luminance
//! Y'CbCr planes (ITU-R BT.2100), the planes an AV1 Main-profile stream carries.
//!
//! Forward: primaries to BT.2020 (core's [`convert_primaries`]), samples to cd/m² through
//! `nits_per_unit`, PQ (SMPTE ST 2084) or the HLG inverse EOTF on each of R, G, B, Y'CbCr with
//! the BT.2020 weights (core's [`rgb_to_ycbcr`]), 10-bit quantization in limited or full range
//! (BT.2100 Table 9), and for 4:2:0 a chroma downsampling co-sited with the top-left luma sample.
//! Backward: the inverse of each step, with bilinear chroma upsampling from the same siting.
//!
//! Policy for samples a PQ signal cannot hold: NaN and negative components (negatives also arise
//! from out-of-BT.2020-gamut colours after the primaries conversion) become 0 cd/m²; components
//! above the peak (10 000 cd/m² for PQ, the nominal display peak for HLG), +∞ included, are
//! clipped to it. Every such sample is counted in a [`ClipReport`]; nothing is clipped silently.

use hdrcodec_core::color::{convert_primaries, rgb_to_ycbcr, ycbcr_to_rgb};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, ContentLightLevel, Error, HdrImage, HlgTransfer, PqTransfer, Result,
    YcbcrCoefficients,
};

/// The transfer function of the coded samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transfer {
    /// SMPTE ST 2084 (PQ): absolute, 0-10 000 cd/m². H.273 transfer 16.
    Pq,
    /// BT.2100 hybrid log-gamma, with the display-referred EOTF of a display of `peak_nits`
    /// (the BT.2100 reference display is 1000 cd/m², black 0). H.273 transfer 18.
    Hlg {
        /// Nominal peak luminance L_W of the display the signal is made for, cd/m².
        peak_nits: f64,
    },
}

impl Transfer {
    /// HLG for the BT.2100 reference display (1000 cd/m²).
    pub const HLG_1000: Transfer = Transfer::Hlg { peak_nits: 1000.0 };

    /// The H.273 TransferCharacteristics code.
    pub fn h273(&self) -> u8 {
        match self {
            Transfer::Pq => 16,
            Transfer::Hlg { .. } => 18,
        }
    }

    /// The brightest luminance the signal holds, cd/m².
    pub fn peak_nits(&self) -> f64 {
        match self {
            Transfer::Pq => PqTransfer::PEAK_NITS,
            Transfer::Hlg { peak_nits } => *peak_nits,
        }
    }
}

/// Quantization range of the coded samples (BT.2100 Table 9).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Range {
    /// "Narrow"/studio range: 10-bit Y' 64-940, Cb/Cr 64-960. What HDR10 players expect.
    #[default]
    Limited,
    /// Full range: 0-1023.
    Full,
}

/// Chroma resolution of the coded planes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Subsampling {
    /// Half width and half height (AV1 Main profile), chroma co-sited with the top-left luma
    /// sample of each 2x2 block (`chroma_sample_position` = CSP_COLOCATED).
    #[default]
    Yuv420,
    /// Full resolution (AV1 High profile).
    Yuv444,
}

/// The bit depth of the coded planes.
pub const BIT_DEPTH: u32 = 10;

/// Samples changed because the signal could not hold them (core's type, re-exported).
pub use hdrcodec_core::hdr10::ClipReport;

/// One frame's 10-bit planes, row-major without padding.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct YuvFrame {
    /// Luma width.
    pub width: usize,
    /// Luma height.
    pub height: usize,
    /// Chroma subsampling of `cb` and `cr`.
    pub subsampling: Subsampling,
    /// Y' codes, `width * height`.
    pub y: Vec<u16>,
    /// Cb codes, `chroma_width * chroma_height`.
    pub cb: Vec<u16>,
    /// Cr codes.
    pub cr: Vec<u16>,
}

impl YuvFrame {
    /// Chroma plane size for luma `width` × `height`.
    pub fn chroma_size(width: usize, height: usize, subsampling: Subsampling) -> (usize, usize) {
        match subsampling {
            Subsampling::Yuv420 => (width.div_ceil(2), height.div_ceil(2)),
            Subsampling::Yuv444 => (width, height),
        }
    }
}

/// A frame's components in BT.2020 primaries, cd/m², after the NaN/negative/peak policy: the
/// values that are coded, and over which MaxCLL and MaxFALL are measured.
pub fn coded_light(frame: &HdrImage, transfer: Transfer) -> (HdrImage, ClipReport) {
    let mut bt2020 = convert_primaries(&frame.with_channels(Channels::Rgb), ColorPrimaries::Bt2020);
    let scale = frame.color.nits_per_unit;
    let peak = transfer.peak_nits() as f32;
    let mut report = ClipReport::default();
    for v in bt2020.samples_mut() {
        let nits = *v * scale;
        *v = if nits.is_nan() {
            report.nan += 1;
            0.0
        } else if nits < 0.0 {
            report.negative += 1;
            0.0
        } else if nits > peak {
            report.above_peak += 1;
            peak
        } else {
            nits
        };
    }
    bt2020.color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 1.0, hdr10: None };
    (bt2020, report)
}

/// MaxCLL and MaxFALL (core's CTA-861.3 definitions) of a sequence, measured on the values that
/// are coded: BT.2020 components in cd/m² after the clipping policy.
pub fn content_light_level<'a>(
    frames: impl IntoIterator<Item = &'a HdrImage>,
    transfer: Transfer,
) -> ContentLightLevel {
    let mut total = ContentLightLevel { max_cll: 0, max_fall: 0 };
    for frame in frames {
        let (light, _) = coded_light(frame, transfer);
        let one = ContentLightLevel::from_frames([&light]);
        total.max_cll = total.max_cll.max(one.max_cll);
        total.max_fall = total.max_fall.max(one.max_fall);
    }
    total
}

/// Quantizes a non-linear Y' (0..1) or a colour difference (−0.5..0.5) to a 10-bit code.
#[cfg(test)]
fn quantize(e: f64, chroma: bool, range: Range) -> u16 {
    quantize_bits(e, BIT_DEPTH, chroma, range)
}

/// [`quantize`] at `bits` (8 to 16).
fn quantize_bits(e: f64, bits: u32, chroma: bool, range: Range) -> u16 {
    let step = f64::from(1u32 << (bits - 8));
    let max = f64::from((1u32 << bits) - 1);
    let code = match (range, chroma) {
        // BT.2100 Table 9, narrow range: D = round((219·E' + 16)·2^(n−8)), chroma 224 and 128.
        (Range::Limited, false) => (219.0 * e + 16.0) * step,
        (Range::Limited, true) => (224.0 * e + 128.0) * step,
        // Full range: D = round((2^n − 1)·E'), chroma + 2^(n−1); ±0.5 lands outside, so clamp.
        (Range::Full, false) => max * e,
        (Range::Full, true) => max * e + f64::from(1u32 << (bits - 1)),
    };
    // Half up: floor(x + 0.5).
    (code + 0.5).floor().clamp(0.0, max) as u16
}

/// The inverse of [`quantize`].
#[cfg(test)]
fn dequantize(d: u16, chroma: bool, range: Range) -> f64 {
    dequantize_bits(d, BIT_DEPTH, chroma, range)
}

/// The inverse of BT.2100 Table 9's quantization at `bits` (8 to 16): limited range
/// E' = (D/2^(n−8) − 16)/219 for luma and (D/2^(n−8) − 128)/224 for chroma; full range
/// D/(2^n − 1) and (D − 2^(n−1))/(2^n − 1).
pub(crate) fn dequantize_bits(d: u16, bits: u32, chroma: bool, range: Range) -> f64 {
    let d = f64::from(d);
    let step = f64::from(1u32 << (bits - 8));
    let max = f64::from((1u32 << bits) - 1);
    match (range, chroma) {
        (Range::Limited, false) => (d / step - 16.0) / 219.0,
        (Range::Limited, true) => (d / step - 128.0) / 224.0,
        (Range::Full, false) => d / max,
        (Range::Full, true) => (d - f64::from(1u32 << (bits - 1))) / max,
    }
}

/// Light (cd/m², BT.2020, already clipped) → non-linear R'G'B'.
fn encode_rgb(rgb: [f64; 3], transfer: Transfer) -> [f64; 3] {
    match transfer {
        Transfer::Pq => rgb.map(PqTransfer::encode),
        Transfer::Hlg { peak_nits } => HlgTransfer::inverse_eotf(rgb, peak_nits, 0.0),
    }
}

/// Non-linear R'G'B' → light in cd/m².
fn decode_rgb(signal: [f64; 3], transfer: Transfer) -> [f64; 3] {
    match transfer {
        // Tabulated: every sample of every frame comes through here (core's table is within
        // 1.2e-6 of the exact curve, under the f32 precision of the frame's samples).
        Transfer::Pq => signal.map(PqTransfer::decode_tabulated),
        Transfer::Hlg { peak_nits } => HlgTransfer::eotf(signal.map(|s| s.clamp(0.0, 1.0)), peak_nits, 0.0),
    }
}

/// The taps of the chroma downsampler: [1, 2, 1]/4 centred on the even (co-sited) sample, a
/// short low-pass that keeps the chroma sample's position at the top-left luma sample, which is
/// what CSP_COLOCATED declares. Edges repeat the last sample.
fn downsample_colocated(plane: &[f64], width: usize, height: usize) -> Vec<f64> {
    let (cw, ch) = YuvFrame::chroma_size(width, height, Subsampling::Yuv420);
    let at = |x: isize, y: isize| {
        let x = x.clamp(0, width as isize - 1) as usize;
        let y = y.clamp(0, height as isize - 1) as usize;
        plane[y * width + x]
    };
    let mut out = Vec::with_capacity(cw * ch);
    for cy in 0..ch as isize {
        for cx in 0..cw as isize {
            let (x, y) = (2 * cx, 2 * cy);
            let row = |y| (at(x - 1, y) + 2.0 * at(x, y) + at(x + 1, y)) / 4.0;
            out.push((row(y - 1) + 2.0 * row(y) + row(y + 1)) / 4.0);
        }
    }
    out
}

/// Where 4:2:0 chroma samples sit vertically, for upsampling (horizontally both are co-sited
/// with the even luma columns).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChromaSiting {
    /// With the even luma rows (AV1 CSP_COLOCATED, "top-left"): what this crate writes.
    #[default]
    Colocated,
    /// Midway between luma rows 2j and 2j+1 (AV1 CSP_VERTICAL, "left"; MPEG-2's siting and
    /// H.273's default, so also what an unsignalled stream most likely means).
    Left,
    /// Midway between luma rows and midway between luma columns (JPEG's and MPEG-1's siting,
    /// YUV4MPEG2's `420jpeg`; AV1 cannot signal it).
    Center,
}

/// Bilinear chroma upsampling: columns from chroma co-sited with the even luma columns (even
/// columns take the sample, odd ones the mean of their neighbours); rows the same for
/// [`ChromaSiting::Colocated`], or with weights 3/4 and 1/4 for chroma midway between rows
/// ([`ChromaSiting::Left`]). Edges repeat the last sample.
fn upsample_420(plane: &[f64], width: usize, height: usize, siting: ChromaSiting) -> Vec<f64> {
    let (cw, ch) = YuvFrame::chroma_size(width, height, Subsampling::Yuv420);
    let at = |cx: isize, cy: isize| {
        plane[(cy.clamp(0, ch as isize - 1) as usize) * cw + cx.clamp(0, cw as isize - 1) as usize]
    };
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        let cy = (y / 2) as isize;
        for x in 0..width {
            let cx = (x / 2) as isize;
            let h = |cy| match (siting, x % 2) {
                (ChromaSiting::Center, 0) => 0.75 * at(cx, cy) + 0.25 * at(cx - 1, cy),
                (ChromaSiting::Center, _) => 0.75 * at(cx, cy) + 0.25 * at(cx + 1, cy),
                (_, 0) => at(cx, cy),
                (_, _) => (at(cx, cy) + at(cx + 1, cy)) / 2.0,
            };
            out.push(match (siting, y % 2) {
                (ChromaSiting::Colocated, 0) => h(cy),
                (ChromaSiting::Colocated, _) => (h(cy) + h(cy + 1)) / 2.0,
                (ChromaSiting::Left | ChromaSiting::Center, 0) => 0.75 * h(cy) + 0.25 * h(cy - 1),
                (ChromaSiting::Left | ChromaSiting::Center, _) => 0.75 * h(cy) + 0.25 * h(cy + 1),
            });
        }
    }
    out
}

/// A frame's coded planes, and what the clipping policy changed.
pub fn frame_to_yuv(
    frame: &HdrImage,
    transfer: Transfer,
    range: Range,
    subsampling: Subsampling,
) -> (YuvFrame, ClipReport) {
    let (light, report) = coded_light(frame, transfer);
    let (width, height) = (light.width() as usize, light.height() as usize);
    let signals = light.rgb().map(|px| encode_rgb(px.map(f64::from), transfer));
    let yuv = signals_to_yuv(signals, width, height, YcbcrCoefficients::BT2020, BIT_DEPTH, range, subsampling);
    (yuv, report)
}

/// Non-linear R'G'B' (row by row, `width` × `height`) to Y'CbCr planes of `bits` bits with the
/// weights `k`; 4:2:0 chroma co-sited with the top-left luma sample.
pub(crate) fn signals_to_yuv(
    signals: impl Iterator<Item = [f64; 3]>,
    width: usize,
    height: usize,
    k: YcbcrCoefficients,
    bits: u32,
    range: Range,
    subsampling: Subsampling,
) -> YuvFrame {
    let n = width * height;
    let mut y = Vec::with_capacity(n);
    let (mut cb, mut cr) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for signal in signals {
        let [luma, b, r] = rgb_to_ycbcr(signal, k);
        y.push(quantize_bits(luma, bits, false, range));
        cb.push(b);
        cr.push(r);
    }
    if subsampling == Subsampling::Yuv420 {
        cb = downsample_colocated(&cb, width, height);
        cr = downsample_colocated(&cr, width, height);
    }
    let q = |plane: Vec<f64>| plane.into_iter().map(|c| quantize_bits(c, bits, true, range)).collect();
    YuvFrame { width, height, subsampling, y, cb: q(cb), cr: q(cr) }
}

/// Y'CbCr planes of `bits` bits back to non-linear R'G'B' with the weights `k`, row by row;
/// 4:2:0 chroma upsampled from `siting`.
pub(crate) fn yuv_to_signals(
    yuv: &YuvFrame,
    bits: u32,
    k: YcbcrCoefficients,
    range: Range,
    siting: ChromaSiting,
) -> Result<Vec<[f64; 3]>> {
    if !(8..=16).contains(&bits) {
        return Err(Error::unsupported(format!("{bits}-bit Y'CbCr (8 to 16 bits are read)")));
    }
    let (width, height) = (yuv.width, yuv.height);
    let (cw, ch) = YuvFrame::chroma_size(width, height, yuv.subsampling);
    if yuv.y.len() != width * height || yuv.cb.len() != cw * ch || yuv.cr.len() != cw * ch {
        return Err(Error::invalid(format!("Y'CbCr planes do not match a {width}x{height} frame")));
    }
    let dq = |plane: &[u16]| plane.iter().map(|&d| dequantize_bits(d, bits, true, range)).collect::<Vec<_>>();
    let (mut cb, mut cr) = (dq(&yuv.cb), dq(&yuv.cr));
    if yuv.subsampling == Subsampling::Yuv420 {
        cb = upsample_420(&cb, width, height, siting);
        cr = upsample_420(&cr, width, height, siting);
    }
    Ok((0..width * height)
        .map(|i| ycbcr_to_rgb([dequantize_bits(yuv.y[i], bits, false, range), cb[i], cr[i]], k))
        .collect())
}

/// Planes back to a scene-linear frame in BT.2020 primaries with `nits_per_unit` cd/m² per 1.0;
/// 4:2:0 chroma is upsampled from `siting`.
pub fn yuv_to_frame(
    yuv: &YuvFrame,
    transfer: Transfer,
    range: Range,
    siting: ChromaSiting,
    nits_per_unit: f32,
) -> Result<HdrImage> {
    yuv_to_frame_bits(yuv, BIT_DEPTH, transfer, range, siting, nits_per_unit)
}

/// [`yuv_to_frame`] for planes of `bits` bits (8 to 16) per sample.
pub fn yuv_to_frame_bits(
    yuv: &YuvFrame,
    bits: u32,
    transfer: Transfer,
    range: Range,
    siting: ChromaSiting,
    nits_per_unit: f32,
) -> Result<HdrImage> {
    let signals = yuv_to_signals(yuv, bits, YcbcrCoefficients::BT2020, range, siting)?;
    let scale = 1.0 / f64::from(nits_per_unit);
    let samples: Vec<f32> =
        signals.into_iter().flat_map(|s| decode_rgb(s, transfer).map(|v| (v * scale) as f32)).collect();
    let (width, height) = (yuv.width, yuv.height);
    let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit, hdr10: None };
    let w = u32::try_from(width).map_err(|_| Error::unsupported("a frame wider than 2^32"))?;
    let h = u32::try_from(height).map_err(|_| Error::unsupported("a frame taller than 2^32"))?;
    HdrImage::new(w, h, Channels::Rgb, samples, color)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantization_follows_bt2100_table_9() {
        // Narrow range 10-bit: black 64, nominal peak 940, chroma 64..960 centred on 512.
        assert_eq!(quantize(0.0, false, Range::Limited), 64);
        assert_eq!(quantize(1.0, false, Range::Limited), 940);
        assert_eq!(quantize(-0.5, true, Range::Limited), 64);
        assert_eq!(quantize(0.5, true, Range::Limited), 960);
        assert_eq!(quantize(0.0, true, Range::Limited), 512);
        assert_eq!(quantize(1.0, false, Range::Full), 1023);
        assert_eq!(quantize(0.5, true, Range::Full), 1023); // 1023.5 clamps
        assert_eq!(quantize(-0.5, true, Range::Full), 1); // 0.5 rounds half up
                                                          // PQ of 100 cd/m² is 0.5081; full-range code 519.8 → 520 (VIDEO-NOTES §2.1).
        assert_eq!(quantize(PqTransfer::encode(100.0), false, Range::Full), 520);
        for range in [Range::Limited, Range::Full] {
            for d in 64..=940u16 {
                assert_eq!(quantize(dequantize(d, false, range), false, range), d);
            }
        }
    }

    #[test]
    fn nan_negative_and_overbright_samples_are_counted() {
        let samples = vec![f32::NAN, -1.0, 200.0, f32::INFINITY, 1.0, 0.5];
        let img = HdrImage::new(
            2,
            1,
            Channels::Rgb,
            samples,
            ColorInfo { primaries: ColorPrimaries::Bt2020, ..ColorInfo::default() },
        )
        .unwrap();
        let (light, report) = coded_light(&img, Transfer::Pq);
        assert_eq!(report, ClipReport { nan: 1, negative: 1, above_peak: 1 + 1 });
        assert_eq!(light.samples(), &[0.0, 0.0, 10_000.0, 10_000.0, 100.0, 50.0]);
        let cll = content_light_level([&img], Transfer::Pq);
        assert_eq!(cll, ContentLightLevel { max_cll: 10_000, max_fall: 10_000 });
    }

    #[test]
    fn grey_round_trips_through_the_planes() {
        for (transfer, range) in [(Transfer::Pq, Range::Limited), (Transfer::HLG_1000, Range::Full)] {
            let samples: Vec<f32> = (0..6 * 4).flat_map(|i| [i as f32 * 0.3; 3]).collect();
            let color = ColorInfo { primaries: ColorPrimaries::Bt2020, ..ColorInfo::default() };
            let img = HdrImage::new(6, 4, Channels::Rgb, samples, color).unwrap();
            let (yuv, _) = frame_to_yuv(&img, transfer, range, Subsampling::Yuv420);
            // Grey has no colour difference: every chroma code is the centre.
            assert!(yuv.cb.iter().chain(&yuv.cr).all(|&c| c == 512));
            let back = yuv_to_frame(&yuv, transfer, range, ChromaSiting::Colocated, 100.0).unwrap();
            for (a, b) in img.samples().iter().zip(back.samples()) {
                // Half a 10-bit step of either curve is below 1 % above 1 cd/m².
                assert!((a - b).abs() <= 0.01 * a + 0.002, "{transfer:?}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn chroma_upsampling_follows_the_siting() {
        // One chroma column, two chroma rows 0 and 1, for a 2x4 luma frame.
        let plane = [0.0, 1.0];
        let colocated = upsample_420(&plane, 2, 4, ChromaSiting::Colocated);
        assert_eq!(colocated, [0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0]);
        // Chroma rows at luma 0.5 and 2.5: luma rows 0..3 sit at chroma -0.25, 0.25, 0.75, 1.25.
        let left = upsample_420(&plane, 2, 4, ChromaSiting::Left);
        assert_eq!(left, [0.0, 0.0, 0.25, 0.25, 0.75, 0.75, 1.0, 1.0]);
        // Two chroma columns, one row, for a 4x2 frame: centred chroma sits at luma x 0.5 and
        // 2.5, so luma columns 0..3 sit at chroma -0.25, 0.25, 0.75, 1.25.
        let center = upsample_420(&plane, 4, 2, ChromaSiting::Center);
        assert_eq!(center, [0.0, 0.25, 0.75, 1.0, 0.0, 0.25, 0.75, 1.0]);
        assert_eq!(upsample_420(&plane, 4, 2, ChromaSiting::Colocated), [0.0, 0.5, 1.0, 1.0, 0.0, 0.5, 1.0, 1.0]);
    }
}
