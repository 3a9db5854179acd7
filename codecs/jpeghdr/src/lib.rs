//! Backward-compatible HDR JPEG: an ordinary JPEG every viewer shows as SDR, carrying what
//! rebuilds the HDR image.
//!
//! This first part decodes gain-map JPEGs in every flavour found in the wild: ISO 21496-1
//! (binary metadata), Android Ultra HDR and Adobe's gain map (`hdrgm` XMP, one or three
//! channels, MPF or GContainer), and Apple's HDR gain map; a plain JPEG decodes as SDR. The
//! output is linear, in the base image's primaries (read from its ICC profile; sRGB without
//! one), with SDR white = 1.0 = 203 cd/m² ([`gainmap::SDR_WHITE_NITS`]). The encoder writes
//! a GT-tone-mapped sRGB base and a gain map with ISO 21496-1 and hdrgm metadata together, MPF
//! and GContainer. Ward & Simmons' ratio-image JPEG-HDR is not written yet.

pub mod encode;
pub mod gainmap;
pub mod icc;
pub mod markers;
pub mod metadata;
pub mod mpf;
pub mod ratio;
pub mod xmp;

use hdrcodec_core::{
    ColorPrimaries, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, HdrImage, ImageCodec, Result,
};

pub use encode::{encode, GainMapEncodeOptions};
pub use gainmap::{decode, probe, Flavour, GainMapFile, Rendering};
pub use metadata::GainMapMetadata;

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
        &["jpg", "jpeg"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(&[0xFF, 0xD8, 0xFF])
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
        gainmap::decode_rows_on(data, &options.limits, Rendering::default(), &options.pool, sink)
    }
    /// A tone-mapped sRGB base with a gain map (see [`encode`]); options `map_quality`,
    /// `map_scale`, `map_channels`.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        let (file, report) = encode(image, &GainMapEncodeOptions::from_settings(settings)?)?;
        out.write_all(&file)?;
        Ok(report)
    }
}
