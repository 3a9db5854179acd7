use crate::{ColorPrimaries, Error, Hdr10Metadata, Result};

/// The channel layout of an [`HdrImage`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Channels {
    /// Red, green, blue.
    Rgb,
    /// Red, green, blue, straight (not premultiplied) alpha.
    Rgba,
}

impl Channels {
    /// Samples per pixel: 3 or 4.
    pub const fn count(self) -> usize {
        match self {
            Channels::Rgb => 3,
            Channels::Rgba => 4,
        }
    }

    /// The layout with `n` samples per pixel, if there is one.
    pub const fn from_count(n: usize) -> Option<Self> {
        match n {
            3 => Some(Channels::Rgb),
            4 => Some(Channels::Rgba),
            _ => None,
        }
    }
}

/// What the sample values of an [`HdrImage`] mean.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorInfo {
    /// The RGB primaries and white point of the samples.
    pub primaries: ColorPrimaries,
    /// The absolute luminance, in cd/m² (nits), of a sample value of 1.0. Default 100.
    pub nits_per_unit: f32,
    /// HDR10 static metadata (mastering display, content light level), if known.
    pub hdr10: Option<Hdr10Metadata>,
}

impl Default for ColorInfo {
    /// BT.709 primaries with a D65 white, 1.0 = 100 nits, no HDR10 metadata.
    fn default() -> Self {
        ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 100.0, hdr10: None }
    }
}

/// An image of scene-linear `f32` samples, interleaved, rows top to bottom.
///
/// Pixels in memory are always linear; transfer functions live at the edges (codecs, export).
/// The sample buffer always holds exactly `width * height * channels` values.
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    width: u32,
    height: u32,
    channels: Channels,
    samples: Vec<f32>,
    /// Colour interpretation of the samples.
    pub color: ColorInfo,
    /// Free-form key/value metadata carried from and to files (Radiance `EXPOSURE`, `SOFTWARE`,
    /// the container's `META` chunk, ...). Keys are lower-case by convention.
    pub metadata: Vec<(String, String)>,
}

impl HdrImage {
    /// An image from interleaved samples; fails if the buffer length does not match.
    pub fn new(width: u32, height: u32, channels: Channels, samples: Vec<f32>, color: ColorInfo) -> Result<Self> {
        let expected = (width as usize)
            .checked_mul(height as usize)
            .and_then(|p| p.checked_mul(channels.count()))
            .ok_or_else(|| Error::invalid(format!("image dimensions {width}x{height} overflow")))?;
        if samples.len() != expected {
            return Err(Error::invalid(format!(
                "{width}x{height} {channels:?} image needs {expected} samples, got {}",
                samples.len()
            )));
        }
        Ok(HdrImage { width, height, channels, samples, color, metadata: Vec::new() })
    }

    /// A black (and, with alpha, transparent) image. Callers decoding untrusted input check
    /// [`Limits::check_image`](crate::Limits::check_image) first.
    pub fn zeroed(width: u32, height: u32, channels: Channels) -> Self {
        let n = width as usize * height as usize * channels.count();
        HdrImage { width, height, channels, samples: vec![0.0; n], color: ColorInfo::default(), metadata: Vec::new() }
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Channel layout.
    pub fn channels(&self) -> Channels {
        self.channels
    }
    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
    /// All samples, interleaved, rows top to bottom.
    pub fn samples(&self) -> &[f32] {
        &self.samples
    }
    /// All samples, mutable.
    pub fn samples_mut(&mut self) -> &mut [f32] {
        &mut self.samples
    }
    /// The sample buffer, consuming the image.
    pub fn into_samples(self) -> Vec<f32> {
        self.samples
    }
    /// The samples as half floats (IEEE 754 binary16, what OpenEXR's HALF, DXGI's R16G16B16A16
    /// and GPU upload paths take), rounded to nearest; beyond ±65504 they become infinite, as
    /// the conversion defines. To decode straight into a half buffer, see
    /// [`FrameBufMut::f16`](crate::sink::FrameBufMut::f16).
    pub fn to_f16(&self) -> Vec<half::f16> {
        self.samples.iter().map(|&v| half::f16::from_f32(v)).collect()
    }
    /// An image of half-float samples (interleaved as [`HdrImage::new`] takes them), widened
    /// exactly to `f32`.
    pub fn from_f16(
        width: u32,
        height: u32,
        channels: Channels,
        samples: &[half::f16],
        color: ColorInfo,
    ) -> Result<Self> {
        HdrImage::new(width, height, channels, samples.iter().map(|v| v.to_f32()).collect(), color)
    }
    /// Samples of row `y`. Panics if `y >= height`.
    pub fn row(&self, y: u32) -> &[f32] {
        let w = self.width as usize * self.channels.count();
        &self.samples[y as usize * w..(y as usize + 1) * w]
    }
    /// Samples of row `y`, mutable. Panics if `y >= height`.
    pub fn row_mut(&mut self, y: u32) -> &mut [f32] {
        let w = self.width as usize * self.channels.count();
        &mut self.samples[y as usize * w..(y as usize + 1) * w]
    }
    /// Samples of the pixel at (`x`, `y`). Panics if out of bounds.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let c = self.channels.count();
        let i = (y as usize * self.width as usize + x as usize) * c;
        &self.samples[i..i + c]
    }
    /// Iterates over the pixels' RGB triples (alpha, if any, is skipped).
    pub fn rgb(&self) -> impl Iterator<Item = [f32; 3]> + '_ {
        self.samples.chunks_exact(self.channels.count()).map(|p| [p[0], p[1], p[2]])
    }
    /// The same picture with `channels` samples per pixel: alpha is dropped, or added as 1.0.
    pub fn with_channels(&self, channels: Channels) -> HdrImage {
        if channels == self.channels {
            return self.clone();
        }
        let samples = match channels {
            Channels::Rgb => self.rgb().flatten().collect(),
            Channels::Rgba => self.rgb().flat_map(|[r, g, b]| [r, g, b, 1.0]).collect(),
        };
        HdrImage {
            width: self.width,
            height: self.height,
            channels,
            samples,
            color: self.color.clone(),
            metadata: self.metadata.clone(),
        }
    }
    /// How many samples fall outside `[lo, hi]` (and how many are NaN), over the RGB channels
    /// and, if `alpha`, the alpha channel too: what an encoder with a fixed range tells its
    /// caller it clipped (see [`RangeCount::describe`]).
    pub fn count_outside(&self, lo: f32, hi: f32, alpha: bool) -> RangeCount {
        let mut c = RangeCount::default();
        c.add(&self.samples, self.channels, lo, hi, alpha);
        c
    }

    /// The value of metadata `key`, if present.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }
    /// Sets metadata `key` to `value`, replacing an earlier value.
    pub fn set_metadata(&mut self, key: impl Into<String>, value: impl Into<String>) {
        let key = key.into();
        let value = value.into();
        match self.metadata.iter_mut().find(|(k, _)| *k == key) {
            Some(entry) => entry.1 = value,
            None => self.metadata.push((key, value)),
        }
    }
}

impl RangeCount {
    /// Adds the samples of `pixels` (interleaved, `channels` per pixel: an image or a band of
    /// its rows) outside `[lo, hi]`, as [`HdrImage::count_outside`] counts them.
    pub fn add(&mut self, pixels: &[f32], channels: Channels, lo: f32, hi: f32, alpha: bool) {
        let n = channels.count();
        let take = if alpha { n } else { 3 };
        for px in pixels.chunks_exact(n) {
            for &v in &px[..take] {
                if v < lo {
                    self.below += 1;
                } else if v > hi {
                    self.above += 1;
                } else if v.is_nan() {
                    self.nan += 1;
                }
            }
        }
    }
}

/// Samples outside a format's range, counted by [`HdrImage::count_outside`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RangeCount {
    /// Samples below the lower bound (−∞ included).
    pub below: u64,
    /// Samples above the upper bound (+∞ included).
    pub above: u64,
    /// NaN samples.
    pub nan: u64,
}

impl RangeCount {
    /// True when every sample was inside the range.
    pub fn is_empty(&self) -> bool {
        self.below == 0 && self.above == 0 && self.nan == 0
    }

    /// A sentence for an [`EncodeReport`](crate::EncodeReport) note, `None` when nothing was
    /// outside: "{format} stores [lo, hi]: 12 samples below were stored as {below_as}, ...".
    pub fn describe(
        &self,
        format: &str,
        lo: f32,
        hi: f32,
        below_as: &str,
        above_as: &str,
        nan_as: &str,
    ) -> Option<String> {
        if self.is_empty() {
            return None;
        }
        let (lo, hi) = (bound(lo), bound(hi));
        let mut parts = Vec::new();
        if self.below > 0 {
            parts.push(format!("{} below {lo} became {below_as}", self.below));
        }
        if self.above > 0 {
            parts.push(format!("{} above {hi} became {above_as}", self.above));
        }
        if self.nan > 0 {
            parts.push(format!("{} NaN became {nan_as}", self.nan));
        }
        Some(format!("{format} holds values from {lo} to {hi}: of the samples, {}", parts.join(", ")))
    }
}

/// A range bound as a note prints it: plain (`65504`, `0.5`), or in exponent form when very
/// large or small (`1.6947657e38`, where plain `{}` would print 39 digits).
fn bound(v: f32) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffer_length_is_checked() {
        assert!(HdrImage::new(2, 2, Channels::Rgb, vec![0.0; 11], ColorInfo::default()).is_err());
        assert!(HdrImage::new(2, 2, Channels::Rgba, vec![0.0; 16], ColorInfo::default()).is_ok());
    }

    #[test]
    fn samples_outside_a_range_are_counted() {
        let img = HdrImage::new(
            2,
            1,
            Channels::Rgba,
            vec![-1.0, 70000.0, f32::NAN, -5.0, f32::INFINITY, 1.0, 2.0, 0.5],
            ColorInfo::default(),
        )
        .unwrap();
        let rgb = img.count_outside(0.0, 65504.0, false);
        assert_eq!(rgb, RangeCount { below: 1, above: 2, nan: 1 });
        assert_eq!(img.count_outside(0.0, 65504.0, true).below, 2);
        let s = rgb.describe("BC6H UF16", 0.0, 65504.0, "0", "65504", "0").unwrap();
        assert_eq!(s, "BC6H UF16 holds values from 0 to 65504: of the samples, 1 below 0 became 0, 2 above 65504 became 65504, 1 NaN became 0");
        assert!(img
            .count_outside(f32::MIN, f32::MAX, true)
            .describe("x", 0.0, 1.0, "", "", "")
            .unwrap()
            .contains("1 above"));
        assert_eq!(
            HdrImage::zeroed(1, 1, Channels::Rgb).count_outside(0.0, 1.0, true).describe("x", 0.0, 1.0, "", "", ""),
            None
        );
        let huge = RangeCount { below: 0, above: 1, nan: 0 }.describe("x", 1e-30, 1.7e38, "", "y", "").unwrap();
        assert_eq!(huge, "x holds values from 1e-30 to 1.7e38: of the samples, 1 above 1.7e38 became y");
    }

    #[test]
    fn channel_conversion_keeps_colour() {
        let img = HdrImage::new(1, 2, Channels::Rgb, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], ColorInfo::default()).unwrap();
        let rgba = img.with_channels(Channels::Rgba);
        assert_eq!(rgba.samples(), &[1.0, 2.0, 3.0, 1.0, 4.0, 5.0, 6.0, 1.0]);
        assert_eq!(rgba.with_channels(Channels::Rgb), img);
    }

    #[test]
    fn half_float_buffers_convert_both_ways() {
        let image =
            HdrImage::new(2, 1, Channels::Rgb, vec![0.5, 1.0, 2.0, 65504.0, 1e6, -0.25], ColorInfo::default()).unwrap();
        let half = image.to_f16();
        assert_eq!(half[3].to_f32(), 65504.0);
        assert!(half[4].is_infinite());
        let back = HdrImage::from_f16(2, 1, Channels::Rgb, &half, ColorInfo::default()).unwrap();
        assert_eq!(&back.samples()[..4], &[0.5, 1.0, 2.0, 65504.0]);
        assert_eq!(back.samples()[5], -0.25);
        assert!(HdrImage::from_f16(3, 1, Channels::Rgb, &half, ColorInfo::default()).is_err());
    }
}
