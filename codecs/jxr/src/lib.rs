//! `hdrcodec-jxr`: JPEG XR (ITU-T T.832 | ISO/IEC 29199-2), the lossy HDR codec of the
//! hdrcodec family, decoded bit-exactly as jxrlib decodes it.
//!
//! Modules follow the bitstream's layers: [`container`] (Annex A), `bits` (bit reader and
//! variable-length words), [`header`] (image and plane headers, index table), `vlc` (the fixed
//! and adaptive code tables), `macroblock` (DC, LP, HP, CBP and flexbits), `predict` and
//! `quant` (prediction and quantization), `transform` (the inverse lapped transform), `output`
//! (colour conversion and output formatting, T.832 9.10), `tiles` and [`decoder`].
//! For the encoder, [`header::write_codestream`] and [`container::write_container`] write the
//! headers and the file around coded packets.
//!
//! Entropy decoding gives, for every macroblock and channel, the 256 dequantized and
//! predicted coefficients the inverse transform reads ([`decode_coefficients`], layout in
//! [`mb`]); it matches the ITU reference software T.835 coefficient for coefficient.
//!
//! Part of an image: [`decode_raw_with`] and [`decode_rows_with`] decode a rectangle
//! ([`Rect`], in the stored orientation) and/or at 1/4 or 1/16 resolution ([`Resolution`])
//! from the low bands alone, as jxrlib's JxrDecApp does with `-r`, `-T 2` and `-T 4`
//! (see the crate README for jxrlib's behaviour there).
//!
//! Colour: the primaries and transfer of PTM_COLOR_INFO when the container has it; else, by
//! the WIC convention, the fixed-point, half and float formats are linear scRGB (BT.709
//! primaries, 1.0 = 80 nits) and the integer formats sRGB-encoded (linearised when decoded to
//! `f32`, reference white 80 nits as sRGB's reference display). See the `colour` module.

// Unsafe code is confined to calling the AVX2 twin of a portable function after checking
// that the CPU has AVX2 (`transform::inverse_band_rows`).
#![deny(unsafe_code)]

mod bits;
mod colour;
pub mod container;
pub mod decoder;
pub mod header;
mod macroblock;
pub mod mb;
pub mod output;
mod predict;
mod quant;
mod reduced;
mod region;
mod render;
mod tiles;
pub mod transform;
mod vlc;

pub use decoder::{decode_coefficients, Coefficients, PlaneCoeffs, RowDecoder};
pub use reduced::{decode_raw_with, decode_rows_with, output_size, JxrDecodeRequest, Rect, Resolution};
pub use render::{decode_raw, decode_raw_into, raw_layout};

use hdrcodec_core::sink::RowSink;
use hdrcodec_core::{
    Channels, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo,
    Limits, Result,
};

/// The JPEG XR codec of the family (`jxr`, id `JXR `).
#[derive(Clone, Copy, Debug, Default)]
pub struct JxrCodec;

/// Reads the container and codestream headers of a `.jxr` file: size, channels, colour and a
/// description ("48bppRGBHalf, 1262x860, frequency order, OL1, 1x1 tiles"). Allocates
/// nothing of the image's size.
pub fn probe_jxr(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    let container = container::parse_container(data)?;
    let cs = header::parse(container.image)?;
    limits.check_dimensions(u64::from(cs.image.width), u64::from(cs.image.height))?;
    let format = container.pixel_format;
    let channels = if format.alpha { Channels::Rgba } else { Channels::Rgb };
    let i = &cs.image;
    let description = format!(
        "{}, {}x{}, {} order, OL{}, {}x{} tiles{}",
        format.name,
        i.width,
        i.height,
        if i.frequency_mode { "frequency" } else { "spatial" },
        i.overlap,
        i.tile_widths.len(),
        i.tile_heights.len(),
        if i.hard_tiling { " (hard)" } else { "" },
    );
    let description = match container.orientation {
        Some(o) if o != 0 => format!("{description}, orientation {o}"),
        _ => description,
    };
    let colour = colour::file_colour(&container);
    let (width, height) = render::orientation(&container).size(i.width, i.height);
    let mut info = ImageInfo::new(width, height, channels, colour.color).with_format(description);
    info.metadata = colour.metadata;
    Ok(info)
}

impl ImageCodec for JxrCodec {
    fn name(&self) -> &'static str {
        "jxr"
    }
    fn id(&self) -> [u8; 4] {
        *b"JXR "
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["jxr", "wdp", "hdp"]
    }
    /// `II BC 01` (JPEG XR) or `II BC 00` (HD Photo).
    fn sniff(&self, head: &[u8]) -> bool {
        head.len() >= 4 && head[..3] == *b"II\xBC" && head[3] <= 1
    }
    /// Decoding reads PTM_COLOR_INFO (H.273 primaries); without it the samples are scRGB by
    /// convention (see the crate documentation). Files are not written yet.
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::None
    }
    /// The headers only (see [`probe_jxr`]).
    /// Decoding only, for now: the encoder is the next issue.
    fn can_encode(&self) -> bool {
        false
    }
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        probe_jxr(data, limits)
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        render::decode_rows(data, options, sink)
    }
    /// The encoder is the next issue.
    fn encode_to(
        &self,
        _image: &HdrImage,
        _settings: &EncodeSettings,
        _out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        Err(Error::unsupported("JPEG XR encoding (not implemented yet)"))
    }
}

/// What the unit tests of several modules share.
#[cfg(test)]
mod testing {
    /// A small deterministic generator (xorshift) for the random tests.
    pub(crate) fn rng(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }
}
