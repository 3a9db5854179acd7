//! `hdrcodec-jxr`: JPEG XR (ITU-T T.832 | ISO/IEC 29199-2), the lossy HDR codec of the
//! hdrcodec family, decoded bit-exactly as jxrlib decodes it, and encoded ([`encoder`]) into
//! files jxrlib decodes to exactly our decoder's samples.
//!
//! Modules follow the bitstream's layers: [`container`] (Annex A), `bits` (bit reader and
//! variable-length words), [`header`] (image and plane headers, index table), `vlc` (the fixed
//! and adaptive code tables), `macroblock` (DC, LP, HP, CBP and flexbits), `predict` and
//! `quant` (prediction and quantization), `transform` (the lapped transform), `output`
//! (colour conversion and output formatting, T.832 9.10), `tiles`, [`decoder`] and
//! [`encoder`]; the writing side of each layer sits next to its reading side.
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

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod bits;
mod colour;
pub mod container;
pub mod decoder;
pub mod encoder;
pub mod header;
mod input;
mod macroblock;
pub mod mb;
pub mod output;
mod predict;
mod quant;
mod reduced;
mod region;
mod render;
mod source;
mod tiles;
pub mod transform;
mod vlc;

pub use decoder::{decode_coefficients, Coefficients, PlaneCoeffs, RowDecoder};
pub use reduced::{decode_raw_with, decode_rows_with, output_size, JxrDecodeRequest, Rect, Resolution};
pub use render::{decode_raw, decode_raw_into, raw_layout};

use hdrcodec_core::sink::RowSink;
use hdrcodec_core::{
    Channels, ColorPrimaries, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, HdrImage, ImageCodec,
    ImageInfo, Limits, Result,
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
    probe_headers(&container, &cs, limits)
}

/// [`probe_jxr`] from a file (any source that reads and seeks, from its current position): the
/// container's IFD and tag values and the first 4 KiB of the codestream are read
/// ([`container::read_container`]), more of it only if its headers (the index table of a file
/// of many tiles) are longer. Same answer and the same kinds of errors as `probe_jxr` on the
/// file's bytes.
pub fn probe_jxr_from(input: &mut dyn hdrcodec_core::ReadSeek, limits: &Limits) -> Result<ImageInfo> {
    probe_from_reading(input, limits, 4 << 10)
}

/// [`probe_jxr_from`] reading first `head_len` bytes of the codestream, 16 times more each time
/// the headers need more.
fn probe_from_reading(input: &mut dyn hdrcodec_core::ReadSeek, limits: &Limits, head_len: u64) -> Result<ImageInfo> {
    // The header probe in memory reads the primary codestream's headers only.
    let file = container::read_headers(input, limits, head_len, false)?;
    probe_headers(&file.head.container()?, &file.image, limits)
}

/// What [`probe_jxr`] says of a file with this container and codestream headers.
fn probe_headers(container: &container::Container, cs: &header::Codestream, limits: &Limits) -> Result<ImageInfo> {
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
    let colour = colour::file_colour(container);
    let (width, height) = render::orientation(container).size(i.width, i.height);
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
    /// `window=N`: decoding from a file, the least bytes held for the packets of a tile row
    /// together (default 65536; 0: what one macroblock can take, a few KB a channel each).
    fn decode_option_keys(&self) -> &'static [&'static str] {
        &["window"]
    }
    /// Decoding reads PTM_COLOR_INFO (H.273 primaries); without it the samples are scRGB by
    /// convention (see the crate documentation). The encoder writes PTM_COLOR_INFO for the
    /// primaries H.273 names and none for BT.709.
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::Only(&[
            ColorPrimaries::Bt709,
            ColorPrimaries::Bt2020,
            ColorPrimaries::DisplayP3,
            ColorPrimaries::DciP3,
            ColorPrimaries::Xyz,
        ])
    }
    /// Half and float files are scRGB: 1.0 is 80 cd/m² (the encoder scales to it).
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        probe_jxr(data, limits)
    }
    /// The container's IFD and the codestream's headers, read from the file (see
    /// [`probe_jxr_from`]).
    fn probe_from(&self, input: &mut dyn hdrcodec_core::ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        probe_jxr_from(input, limits)
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        render::decode_rows(data, options, sink)
    }
    /// Reads the container and headers, then each packet through a window of the file: the
    /// file is never held whole (HD Photo 1.0 codestreams excepted).
    fn decode_rows_from(
        &self,
        input: &mut dyn hdrcodec_core::ReadSeek,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        render::decode_rows_from(input, options, sink)
    }
    /// See [`encoder`]: options `format`, `overlap`, `lossless`, `tile`.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        let options = encoder::EncodeOptions::from_settings(settings)?;
        let (file, report) = encoder::encode(image, &options, &settings.pool)?;
        out.write_all(&file)?;
        Ok(report)
    }
}

#[cfg(test)]
mod probe_tests {
    use super::*;

    /// A 512x256 file of 16x16-pixel tiles: 512 tiles, an index table of more than 512 bytes.
    fn tiled() -> Vec<u8> {
        let (w, h) = (512u32, 256u32);
        let samples = (0..w * h * 3).map(|i| (i % 97) as f32 / 50.0).collect();
        let image = HdrImage::new(w, h, Channels::Rgb, samples, Default::default()).unwrap();
        let settings = EncodeSettings::default().with_option("tile", "16");
        JxrCodec.encode(&image, &settings).unwrap()
    }

    fn from(file: &[u8], skip: usize, head_len: u64) -> Result<ImageInfo> {
        let mut bytes = vec![7; skip];
        bytes.extend_from_slice(file);
        let mut input = std::io::Cursor::new(bytes);
        input.set_position(skip as u64);
        probe_from_reading(&mut input, &Limits::default(), head_len)
    }

    #[test]
    fn headers_longer_than_what_is_read_first_are_read_in_more_steps() {
        let file = tiled();
        let info = probe_jxr(&file, &Limits::default()).unwrap();
        assert!(info.format.contains("32x16 tiles"), "{}", info.format);
        let cs = header::parse(container::parse_container(&file).unwrap().image).unwrap();
        assert!(cs.header_len > 512, "{}", cs.header_len);
        for head_len in [16, 100, 4096] {
            assert_eq!(from(&file, 3, head_len).unwrap(), info, "first {head_len} bytes");
        }
    }

    #[test]
    fn every_cut_of_a_tiled_file_is_the_same_kind_of_error_from_a_file() {
        let file = tiled();
        for cut in (0..file.len()).step_by(7) {
            let memory = probe_jxr(&file[..cut], &Limits::default());
            let streamed = from(&file[..cut], 1, 16);
            match (memory, streamed) {
                (Ok(m), Ok(s)) => assert_eq!(m, s, "cut {cut}"),
                (Err(m), Err(s)) => {
                    assert_eq!(std::mem::discriminant(&m), std::mem::discriminant(&s), "cut {cut}: {m} / {s}")
                }
                (m, s) => panic!("cut {cut}: in memory {m:?}, from a file {s:?}"),
            }
        }
    }
}

/// What the unit tests of several modules share.
#[cfg(test)]
mod testing {
    use crate::header::ClrFmt;

    /// Every internal colour format, with a channel count (NCOMPONENT twice).
    pub(crate) const FORMATS: [(ClrFmt, usize); 7] = [
        (ClrFmt::YOnly, 1),
        (ClrFmt::Yuv420, 3),
        (ClrFmt::Yuv422, 3),
        (ClrFmt::Yuv444, 3),
        (ClrFmt::Yuvk, 4),
        (ClrFmt::NComponent, 2),
        (ClrFmt::NComponent, 5),
    ];

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
