//! Backward-compatible HDR JPEG: an ordinary JPEG every viewer shows as SDR, carrying what
//! rebuilds the HDR image.
//!
//! Decoding reads gain-map JPEGs in every flavour found in the wild: ISO 21496-1 (binary
//! metadata), Android Ultra HDR and Adobe's gain map (`hdrgm` XMP, one or three channels, MPF
//! or GContainer), and Apple's HDR gain map; and Ward & Simmons' ratio-image JPEG-HDR
//! ([`ratio`]); a plain JPEG decodes as SDR. The output is linear, in the base image's
//! primaries (read from its ICC profile; sRGB without one), with SDR white = 1.0 = 203 cd/m²
//! ([`gainmap::SDR_WHITE_NITS`]) for gain maps, and 1.0 = `s2n` cd/m² for JPEG-HDR.
//!
//! Two encoders: [`encode()`] writes a GT-tone-mapped sRGB (or Display P3) base and a gain map
//! with ISO 21496-1 and hdrgm metadata together, MPF and GContainer (codec `ultrahdr`);
//! [`encode_jpeg_hdr`] writes Ward & Simmons' JPEG-HDR, a GT-tone-mapped base and a log ratio
//! image in `HDR_RI` APP11 segments, pre- or post-corrected, which the format's author's
//! library (panlib) reads (codec `jpeg-hdr`, [`ratio_encode`]).

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub mod encode;
pub mod exif;
pub mod gainmap;
pub mod icc;
pub mod markers;
pub mod metadata;
pub mod mpf;
pub mod ratio;
pub mod ratio_encode;
pub mod xmp;

use hdrcodec_core::{
    ColorPrimaries, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, HdrImage, ImageCodec, Result,
};

pub use encode::{encode, GainMapEncodeOptions};
pub use gainmap::{decode, probe, Flavour, GainMapFile, Rendering};
pub use metadata::GainMapMetadata;
pub use ratio_encode::{encode_jpeg_hdr, RatioEncodeOptions};

/// The file extensions of both JPEG codecs.
const JPEG_EXTENSIONS: &[&str] = &["jpg", "jpeg"];

/// Writes an encoder's file to `out` and passes its report on.
fn write_encoded((file, report): (Vec<u8>, EncodeReport), out: &mut dyn std::io::Write) -> Result<EncodeReport> {
    out.write_all(&file)?;
    Ok(report)
}

/// The gain-map JPEG codec: `.jpg` files with or without a gain map.
#[derive(Clone, Copy, Debug, Default)]
pub struct GainMapJpegCodec;

impl ImageCodec for GainMapJpegCodec {
    fn name(&self) -> &'static str {
        "ultrahdr"
    }
    fn id(&self) -> [u8; 4] {
        *b"UHDR"
    }
    fn extensions(&self) -> &'static [&'static str] {
        JPEG_EXTENSIONS
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(&[0xFF, 0xD8, 0xFF])
    }
    /// `headroom=H`: render for a display whose HDR white is `H` times its SDR white
    /// ([`Rendering`]); the full HDR rendition by default.
    fn decode_option_keys(&self) -> &'static [&'static str] {
        Rendering::OPTION_KEYS
    }
    /// The base image's ICC profile: sRGB or Display P3, the spaces gain-map writers use.
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::Only(&[ColorPrimaries::Bt709, ColorPrimaries::DisplayP3])
    }
    /// The headers of both images and the metadata, without decoding pixels.
    fn probe(&self, data: &[u8], limits: &hdrcodec_core::Limits) -> Result<hdrcodec_core::ImageInfo> {
        gainmap::probe(data, limits)
    }
    /// The full HDR rendition (see [`decode`] for a display's headroom).
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(
        &self,
        data: &[u8],
        options: &DecodeOptions,
        sink: &mut dyn hdrcodec_core::sink::RowSink,
    ) -> Result<()> {
        gainmap::decode_rows_on(data, &options.limits, Rendering::from_options(options)?, &options.pool, sink)
    }
    /// A tone-mapped sRGB base with a gain map (see [`encode()`]); options `map_quality`,
    /// `map_scale`, `map_channels`.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        write_encoded(encode(image, &GainMapEncodeOptions::from_settings(settings)?)?, out)
    }
}

/// Ward & Simmons' JPEG-HDR, for writing (`--codec jpeg-hdr`; see [`encode_jpeg_hdr`]). Reading
/// any `.jpg`, JPEG-HDR included, is the [`GainMapJpegCodec`]'s: this codec sniffs nothing, so
/// that extension and byte dispatch pick that one, but decodes the same way when named.
#[derive(Clone, Copy, Debug, Default)]
pub struct JpegHdrCodec;

impl ImageCodec for JpegHdrCodec {
    fn name(&self) -> &'static str {
        "jpeg-hdr"
    }
    fn id(&self) -> [u8; 4] {
        *b"JHDR"
    }
    fn extensions(&self) -> &'static [&'static str] {
        JPEG_EXTENSIONS
    }
    fn sniff(&self, _head: &[u8]) -> bool {
        false
    }
    /// Those of [`GainMapJpegCodec`], which decodes for it.
    fn decode_option_keys(&self) -> &'static [&'static str] {
        GainMapJpegCodec.decode_option_keys()
    }
    /// BT.709 only (colours outside it travel in the unclamped Y'CbCr).
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::Only(&[ColorPrimaries::Bt709])
    }
    /// `s2n` records the image's `nits_per_unit`.
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    fn probe(&self, data: &[u8], limits: &hdrcodec_core::Limits) -> Result<hdrcodec_core::ImageInfo> {
        GainMapJpegCodec.probe(data, limits)
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        GainMapJpegCodec.decode_with(data, options)
    }
    fn decode_rows(
        &self,
        data: &[u8],
        options: &DecodeOptions,
        sink: &mut dyn hdrcodec_core::sink::RowSink,
    ) -> Result<()> {
        GainMapJpegCodec.decode_rows(data, options, sink)
    }
    /// A GT-tone-mapped sRGB base with a ratio image in APP11 (see [`encode_jpeg_hdr`]);
    /// options `ratio_quality`, `ratio_scale`, `correction=pre|post`, `alpha`,
    /// `tone=gt|reinhard|reinhard-extended:W`.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        write_encoded(encode_jpeg_hdr(image, &RatioEncodeOptions::from_settings(settings)?)?, out)
    }
}
