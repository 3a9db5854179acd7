//! Radiance RGBE / XYZE pictures (`.hdr`, `.pic`): Greg Ward's shared-exponent encoding
//! (Ward, "Real Pixels", Graphics Gems II, 1991) in the Radiance file format.
//!
//! Reads every variant in use: the `#?RADIANCE` / `#?RGBE` header with `FORMAT`
//! (`32-bit_rle_rgbe`, `32-bit_rle_xyze`), cumulative `EXPOSURE` and `COLORCORR`, `PRIMARIES`,
//! `PIXASPECT`, `SOFTWARE`, comments and command lines; the eight resolution-string orientations;
//! new-style adaptive run-length scanlines, old-style run-length encoding and flat pixels.
//! Writes new-style RLE (or flat) RGBE or XYZE with the standard `-Y H +X W` orientation.
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, HdrImage, Limits};
//! use hdrcodec_rgbe::{decode, encode, RgbeDecodeOptions, RgbeEncodeOptions};
//!
//! let img = HdrImage::new(2, 1, Channels::Rgb, vec![1.0, 0.5, 0.25, 1000.0, 2.0, 0.0], ColorInfo::default())?;
//! let file = encode(&img, &RgbeEncodeOptions::default())?;
//! let back = decode(&file, &Limits::default(), &RgbeDecodeOptions::default())?;
//! assert_eq!(back.pixel(0, 0), &[1.0, 0.5, 0.25]);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod decode;
mod encode;
mod header;

/// A xorshift64 generator for the unit tests' random planes and pixels (deterministic, so a
/// failure reproduces).
#[cfg(test)]
pub(crate) fn test_rng(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

pub use decode::decode_pixel;
pub use encode::{encode_pixel, RGBE_MAX};
pub use header::{Axis, Header, PixelFormat};

use hdrcodec_core::{EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits, Result};

/// How a mantissa byte becomes a float.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MantissaDecode {
    /// `m · 2^(e-136)`: Bruce Walter's rgbe.c, used by OpenImageIO, stb_image and most readers,
    /// so that [0, 1] values round-trip to [0, 1]. The default: it matches OpenImageIO bit for bit.
    #[default]
    Truncated,
    /// `(m + 0.5) · 2^(e-136)`: Radiance's own `colr_color`, the centre of the interval a
    /// truncating encoder maps to `m`.
    Centred,
}

impl MantissaDecode {
    pub(crate) fn bias(self) -> f32 {
        match self {
            MantissaDecode::Truncated => 0.0,
            MantissaDecode::Centred => 0.5,
        }
    }
}

/// Options of the decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RgbeDecodeOptions {
    /// Divide the values by the file's cumulative `EXPOSURE` (and `COLORCORR`) to get the
    /// original radiances, as Radiance's `pvalue -o` does. Default `true`. With `false` the
    /// stored values are returned (what OpenImageIO does) and the image metadata says
    /// `exposure_in_pixels=true`, so that writing it again keeps the `EXPOSURE` line.
    pub apply_exposure: bool,
    /// Mantissa interpretation. Default [`MantissaDecode::Truncated`].
    pub mantissa: MantissaDecode,
}

impl Default for RgbeDecodeOptions {
    fn default() -> Self {
        RgbeDecodeOptions { apply_exposure: true, mantissa: MantissaDecode::Truncated }
    }
}

/// How the encoder turns a float into a mantissa byte.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Rounding {
    /// Truncation, byte-identical to rgbe.c's `float2rgbe` and so to OpenImageIO's writer.
    /// Pairs with Radiance's centred decode; against a truncating reader its error is up to
    /// one mantissa step.
    Truncate,
    /// Round to nearest: half the error of [`Rounding::Truncate`] with the truncating readers
    /// that nearly everyone uses (OpenImageIO, stb_image, three.js, the `image` crate). The
    /// default, because it is the more accurate file for those readers.
    #[default]
    Nearest,
}

/// Options of the encoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RgbeEncodeOptions {
    /// Mantissa rounding. Default [`Rounding::Nearest`].
    pub rounding: Rounding,
    /// RGBE (default) or XYZE.
    pub format: PixelFormat,
    /// New-style run-length scanlines (default `true`; scanlines shorter than 8 or longer than
    /// 32767 pixels are always flat, as the format requires).
    pub rle: bool,
}

impl Default for RgbeEncodeOptions {
    fn default() -> Self {
        RgbeEncodeOptions { rounding: Rounding::Nearest, format: PixelFormat::Rgbe, rle: true }
    }
}

/// The option keys [`RgbeEncodeOptions::from_settings`] understands.
pub const OPTION_KEYS: [&str; 3] = ["rounding", "format", "rle"];

impl RgbeEncodeOptions {
    /// Options from `key=value` settings: `rounding=truncate|nearest`, `format=rgbe|xyze`,
    /// `rle=true|false`. An unknown key or value is an error.
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options("rgbe", &OPTION_KEYS)?;
        let mut o = RgbeEncodeOptions::default();
        if let Some(v) = settings.option("rounding") {
            o.rounding = match v.to_ascii_lowercase().as_str() {
                "truncate" => Rounding::Truncate,
                "nearest" => Rounding::Nearest,
                _ => return Err(Error::invalid(format!("option rounding={v}: expected truncate or nearest"))),
            };
        }
        if let Some(v) = settings.option("format") {
            o.format = match v.to_ascii_lowercase().as_str() {
                "rgbe" => PixelFormat::Rgbe,
                "xyze" => PixelFormat::Xyze,
                _ => return Err(Error::invalid(format!("option format={v}: expected rgbe or xyze"))),
            };
        }
        if let Some(v) = settings.bool_option("rle")? {
            o.rle = v;
        }
        Ok(o)
    }
}

/// Decodes a Radiance picture held in memory. Never panics; checks `limits` before allocating.
pub fn decode(data: &[u8], limits: &Limits, options: &RgbeDecodeOptions) -> Result<HdrImage> {
    decode::decode(data, limits, options)
}

/// Size, channels (RGB), colour and pixel format of a Radiance picture, from its header and
/// resolution string (and the first bytes of the first scanline, which say whether the
/// scanlines are run-length coded). Checks the size against the limits' dimensions and that the
/// file can hold that many scanlines; allocates nothing of the image's size.
pub fn probe(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    decode::probe(data, limits)
}

/// Reads only the header and resolution string.
pub fn read_header(data: &[u8]) -> Result<Header> {
    header::parse(data)
}

/// Encodes an image (alpha, if any, is dropped) as a Radiance picture.
pub fn encode(image: &HdrImage, options: &RgbeEncodeOptions) -> Result<Vec<u8>> {
    encode::encode(image, options)
}

/// Applies a colour matrix to every RGB triple of interleaved samples (`stride` per pixel).
fn apply_matrix(m: &hdrcodec_core::color::Mat3, samples: &mut [f32], stride: usize) {
    let m = hdrcodec_core::color::mat_to_f32(m);
    for px in samples.chunks_exact_mut(stride) {
        let v = hdrcodec_core::color::mat_apply_f32s(&m, [px[0], px[1], px[2]]);
        px[..3].copy_from_slice(&v);
    }
}

/// The Radiance RGBE codec behind the family's [`ImageCodec`] trait.
#[derive(Clone, Copy, Debug, Default)]
pub struct RgbeCodec {
    decode: RgbeDecodeOptions,
}

impl RgbeCodec {
    /// The codec with default decode options (EXPOSURE applied, truncated mantissas).
    pub fn new() -> Self {
        RgbeCodec::default()
    }
    /// The codec with these decode options.
    pub fn with_decode_options(decode: RgbeDecodeOptions) -> Self {
        RgbeCodec { decode }
    }
    /// The codec that returns the stored values: EXPOSURE not applied, truncated mantissas
    /// (exactly what OpenImageIO returns).
    pub fn raw() -> Self {
        RgbeCodec { decode: RgbeDecodeOptions { apply_exposure: false, mantissa: MantissaDecode::Truncated } }
    }
    /// The decode options in use.
    pub fn decode_options(&self) -> RgbeDecodeOptions {
        self.decode
    }
}

impl ImageCodec for RgbeCodec {
    fn name(&self) -> &'static str {
        "rgbe"
    }
    fn id(&self) -> [u8; 4] {
        *b"RGBE"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["hdr", "pic"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        header::sniff(head)
    }
    /// The `PRIMARIES` header line records any chromaticities (XYZE files are CIE XYZ).
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::Any
    }
    /// The header only (see [`probe`]).
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        decode::probe(data, limits)
    }
    /// The header only, read from the file: at most 64 KiB of it, or 1 MiB for the longest
    /// header accepted.
    fn probe_from(&self, input: &mut dyn hdrcodec_core::ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        decode::probe_from(input, limits)
    }
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(
        &self,
        data: &[u8],
        options: &hdrcodec_core::DecodeOptions,
        sink: &mut dyn hdrcodec_core::sink::RowSink,
    ) -> Result<()> {
        decode::decode_rows(data, &options.limits, &self.decode, sink)
    }
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        let options = RgbeEncodeOptions::from_settings(settings)?;
        let mut writer = encode::RgbeWriter::new(&ImageInfo::of(image), &options)?;
        writer.write_rows(image.samples(), out)?;
        writer.finish(out)
    }
    /// Scanlines are written as they come (the header says everything before the first).
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        let options = RgbeEncodeOptions::from_settings(settings)?;
        Ok(Some(Box::new(encode::RgbeWriter::new(info, &options)?)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries};

    fn notes(img: &HdrImage, settings: &EncodeSettings) -> (Vec<String>, HdrImage) {
        let mut file = Vec::new();
        let report = RgbeCodec::new().encode_to(img, settings, &mut file).unwrap();
        (report.notes, RgbeCodec::new().decode(&file, &Limits::default()).unwrap())
    }

    #[test]
    fn negatives_nan_and_overflow_are_reported() {
        let s = vec![1.0, -0.5, 2.0, f32::NAN, 0.25, 3e38, f32::INFINITY, -1.0, 0.0, 4.0, 8.0, 0.5];
        let img = HdrImage::new(4, 1, Channels::Rgb, s, ColorInfo::default()).unwrap();
        let (n, back) = notes(&img, &EncodeSettings::default());
        assert_eq!(
            n,
            ["Radiance RGBE holds values from 0 to 1.6947657e38: of the samples, 2 below 0 became 0 (RGBE has no \
              sign), 2 above 1.6947657e38 became 1.6947657e38, 1 NaN became 0"]
        );
        // What the note says is what a reader gets back.
        let b = back.samples();
        assert_eq!([b[1], b[3], b[7]], [0.0; 3]);
        assert_eq!([b[5], b[6]], [RGBE_MAX; 2]);
        // Values it holds: no note. Alpha is dropped, not counted.
        let ok = HdrImage::new(1, 1, Channels::Rgba, vec![1.0, 2.0, 3.0, -1.0], ColorInfo::default()).unwrap();
        assert!(notes(&ok, &EncodeSettings::default()).0.is_empty());
    }

    #[test]
    fn xyze_counts_the_stored_xyz() {
        // A saturated BT.2020 green has negative BT.709 components but positive XYZ: nothing to
        // report in XYZE; a negative XYZ (an imaginary colour) is.
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, ..ColorInfo::default() };
        let img = HdrImage::new(2, 1, Channels::Rgb, vec![0.0, 1.0, 0.0, -1.0, 0.0, 0.0], color).unwrap();
        let xyze = EncodeSettings::default().with_option("format", "xyze");
        let (n, _) = notes(&img, &xyze);
        assert_eq!(n.len(), 1, "{n:?}");
        // X and Y of the negative red (Z is 0, give or take the matrix's last bit).
        assert!(n[0].starts_with("Radiance XYZE holds values from 0 to 1.6947657e38: of the samples, "), "{n:?}");
        assert!(n[0].contains(" below 0 became 0 (XYZE has no sign)") && !n[0].contains("above"), "{n:?}");
        let green = HdrImage::new(1, 1, Channels::Rgb, vec![0.0, 1.0, 0.0], img.color.clone()).unwrap();
        assert!(notes(&green, &xyze).0.is_empty());
    }
}
