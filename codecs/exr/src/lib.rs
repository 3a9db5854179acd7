//! OpenEXR reading and writing for hdrcodec, through the [`exr`] crate.
//!
//! - Reading: the R, G, B(, A) channels (names matched case-insensitively; a `layer.R` prefix
//!   is accepted when there are no plain R, G, B) of the first part; a luminance-only `Y` file
//!   becomes grey RGB. Half, float and uint samples become `f32` (uint keeps its numeric value).
//!   Tiled files give their largest mip/rip level. The **data window** is returned (its size is
//!   the image size; like OpenImageIO, pixels are neither cropped nor padded to the display
//!   window); when the two windows differ, both are recorded in the metadata
//!   `exr.data_window` / `exr.display_window` as `xmin ymin xmax ymax`. The `chromaticities`
//!   attribute sets [`ColorInfo::primaries`](hdrcodec_core::ColorInfo) (absent: BT.709) and
//!   `whiteLuminance` sets `nits_per_unit`. Every compression `exr` decodes is read: none, RLE,
//!   ZIPS, ZIP, PIZ, PXR24, B44, B44A, DWAA, DWAB (not HTJ2K).
//! - Probing ([`probe_exr`], [`ImageCodec::probe`]): the same size, channels and colour from
//!   the headers alone, with the stored format ("half, PIZ").
//! - Writing: one scan-line part, `R, G, B(, A)`, half or float, any [`ExrCompression`];
//!   `chromaticities` is written when the primaries are not BT.709, `whiteLuminance` when
//!   `nits_per_unit` is not 100.
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
//! use hdrcodec_exr::ExrCodec;
//! let img = HdrImage::new(2, 1, Channels::Rgb, vec![0.5, 1.0, 2.0, 1000.0, 0.0, 0.25], ColorInfo::default())?;
//! let settings = EncodeSettings::default().with_option("compression", "piz").with_option("pixel", "float");
//! let bytes = ExrCodec.encode(&img, &settings)?;
//! let back = ExrCodec.decode(&bytes, &Limits::default())?;
//! assert_eq!(back.samples(), img.samples());
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

#![forbid(unsafe_code)]

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod decode;
mod encode;
pub mod interop;

/// The underlying `exr` crate, for callers who need multi-part, deep or arbitrary-channel files.
pub use exr;

pub use decode::{decode_exr, decode_exr_rows, decode_exr_rows_from, decode_exr_with, probe_exr, probe_exr_from};
pub use encode::{encode_exr, write_exr};

use exr::compression::Compression;
use hdrcodec_core::{EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Result};
use std::fmt;
use std::str::FromStr;

/// The OpenEXR magic number, the first four bytes of every file.
pub const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// How the pixels of a written file are compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ExrCompression {
    /// Uncompressed.
    None,
    /// Run-length encoding (lossless).
    Rle,
    /// Zlib, one scan line per block ("ZIPS", lossless).
    Zip1,
    /// Zlib, 16 scan lines per block ("ZIP", lossless). The default: the common VFX choice,
    /// fast to decode and, unlike PIZ, good on smooth renders as well as on grain.
    #[default]
    Zip16,
    /// Wavelet + Huffman, 32 lines per block (lossless; best on noisy photographs).
    Piz,
    /// 24-bit float + zlib: lossless for half, lossy (16-bit mantissa) for float.
    Pxr24,
    /// 4x4 blocks at a fixed ratio: lossy for half; float channels are stored uncompressed.
    B44,
    /// B44 with flat blocks stored in 3 bytes (lossy for half).
    B44A,
    /// Lossy DCT, 32 lines per block, at `exr`'s default level 45.
    Dwaa,
    /// Lossy DCT, 256 lines per block, at `exr`'s default level 45.
    Dwab,
}

impl ExrCompression {
    /// Every compression, in the order of the OpenEXR compression ids.
    pub const ALL: [ExrCompression; 10] = [
        ExrCompression::None,
        ExrCompression::Rle,
        ExrCompression::Zip1,
        ExrCompression::Zip16,
        ExrCompression::Piz,
        ExrCompression::Pxr24,
        ExrCompression::B44,
        ExrCompression::B44A,
        ExrCompression::Dwaa,
        ExrCompression::Dwab,
    ];

    /// The name used in options and by OpenEXR's tools (`none`, `rle`, `zips`, `zip`, `piz`,
    /// `pxr24`, `b44`, `b44a`, `dwaa`, `dwab`).
    pub fn name(self) -> &'static str {
        match self {
            ExrCompression::None => "none",
            ExrCompression::Rle => "rle",
            ExrCompression::Zip1 => "zips",
            ExrCompression::Zip16 => "zip",
            ExrCompression::Piz => "piz",
            ExrCompression::Pxr24 => "pxr24",
            ExrCompression::B44 => "b44",
            ExrCompression::B44A => "b44a",
            ExrCompression::Dwaa => "dwaa",
            ExrCompression::Dwab => "dwab",
        }
    }

    /// True when decoding gives back exactly the written half samples.
    pub fn is_lossless_for_half(self) -> bool {
        !matches!(self, ExrCompression::B44 | ExrCompression::B44A | ExrCompression::Dwaa | ExrCompression::Dwab)
    }

    /// True when decoding gives back exactly the written float samples.
    pub fn is_lossless_for_float(self) -> bool {
        // B44 leaves float channels uncompressed; DWA and PXR24 quantise them.
        !matches!(self, ExrCompression::Pxr24 | ExrCompression::Dwaa | ExrCompression::Dwab)
    }

    pub(crate) fn to_exr(self) -> Compression {
        match self {
            ExrCompression::None => Compression::Uncompressed,
            ExrCompression::Rle => Compression::RLE,
            ExrCompression::Zip1 => Compression::ZIP1,
            ExrCompression::Zip16 => Compression::ZIP16,
            ExrCompression::Piz => Compression::PIZ,
            ExrCompression::Pxr24 => Compression::PXR24,
            ExrCompression::B44 => Compression::B44,
            ExrCompression::B44A => Compression::B44A,
            ExrCompression::Dwaa => Compression::DWAA(None),
            ExrCompression::Dwab => Compression::DWAB(None),
        }
    }
}

impl fmt::Display for ExrCompression {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExrCompression {
    type Err = Error;
    /// Accepts the names of [`ExrCompression::name`], case-insensitively, plus `uncompressed`,
    /// `zip1`, `zip16`.
    fn from_str(s: &str) -> Result<Self> {
        let lower = s.to_ascii_lowercase();
        let alias = match lower.as_str() {
            "uncompressed" => "none",
            "zip1" => "zips",
            "zip16" => "zip",
            other => other,
        };
        ExrCompression::ALL.into_iter().find(|c| c.name() == alias).ok_or_else(|| {
            let names: Vec<&str> = ExrCompression::ALL.iter().map(|c| c.name()).collect();
            Error::invalid(format!("unknown OpenEXR compression '{s}' (known: {})", names.join(", ")))
        })
    }
}

/// The sample type of a written file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ExrPixelType {
    /// 16-bit half float (about 3.3 significant digits, range ±65504; values beyond become
    /// ±infinity). The default: what VFX pipelines exchange, half the size of float.
    #[default]
    Half,
    /// 32-bit float: exact.
    Float,
}

impl FromStr for ExrPixelType {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "half" | "f16" => Ok(ExrPixelType::Half),
            "float" | "f32" => Ok(ExrPixelType::Float),
            _ => Err(Error::invalid(format!("unknown OpenEXR pixel type '{s}' (known: half, float)"))),
        }
    }
}

/// Options of the OpenEXR writer. The default, ZIP (16 lines) + half, is the common VFX choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct ExrEncodeOptions {
    /// Pixel compression.
    pub compression: ExrCompression,
    /// Sample type.
    pub pixel: ExrPixelType,
}

impl ExrEncodeOptions {
    /// The options given in `settings` (`compression=...`, `pixel=half|float`); any other key
    /// is an error.
    pub fn from_settings(settings: &EncodeSettings) -> Result<Self> {
        settings.check_options("exr", &["compression", "pixel"])?;
        let mut o = ExrEncodeOptions::default();
        if let Some(c) = settings.option("compression") {
            o.compression = c.parse()?;
        }
        if let Some(p) = settings.option("pixel") {
            o.pixel = p.parse()?;
        }
        Ok(o)
    }
}

/// Human-readable name of an `exr` compression, for metadata.
pub(crate) fn compression_name(c: Compression) -> &'static str {
    match c {
        Compression::Uncompressed => "none",
        Compression::RLE => "rle",
        Compression::ZIP1 => "zips",
        Compression::ZIP16 => "zip",
        Compression::PIZ => "piz",
        Compression::PXR24 => "pxr24",
        Compression::B44 => "b44",
        Compression::B44A => "b44a",
        Compression::DWAA(_) => "dwaa",
        Compression::DWAB(_) => "dwab",
        Compression::HTJ2K32 => "htj2k32",
        Compression::HTJ2K256 => "htj2k256",
    }
}

/// The OpenEXR codec of the family (`exr`, id `OEXR`).
#[derive(Clone, Copy, Debug, Default)]
pub struct ExrCodec;

impl ImageCodec for ExrCodec {
    fn name(&self) -> &'static str {
        "exr"
    }
    fn id(&self) -> [u8; 4] {
        *b"OEXR"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["exr"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(&MAGIC)
    }
    /// The `chromaticities` attribute records any primaries (absent means BT.709, by the
    /// OpenEXR specification).
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::Any
    }
    /// `whiteLuminance` records `nits_per_unit` (written when it is not 100, the default).
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    /// The headers only (see [`probe_exr`]).
    fn probe(&self, data: &[u8], limits: &hdrcodec_core::Limits) -> Result<hdrcodec_core::ImageInfo> {
        probe_exr(data, limits)
    }
    /// The headers only, read from the file (see [`probe_exr_from`]).
    fn probe_from(
        &self,
        input: &mut dyn hdrcodec_core::ReadSeek,
        limits: &hdrcodec_core::Limits,
    ) -> Result<hdrcodec_core::ImageInfo> {
        probe_exr_from(input, limits)
    }
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        decode_exr_with(data, options)
    }
    fn decode_rows(
        &self,
        data: &[u8],
        options: &hdrcodec_core::DecodeOptions,
        sink: &mut dyn hdrcodec_core::sink::RowSink,
    ) -> Result<()> {
        decode_exr_rows(data, options, sink)
    }
    /// Reads the chunks a batch at a time as they decode (see [`decode_exr_rows_from`]).
    fn decode_rows_from(
        &self,
        input: &mut dyn hdrcodec_core::ReadSeek,
        options: &hdrcodec_core::DecodeOptions,
        sink: &mut dyn hdrcodec_core::sink::RowSink,
    ) -> Result<()> {
        decode_exr_rows_from(input, options, sink)
    }
    /// Into a plain writer the file is assembled in memory first (the offset table precedes
    /// the chunks); [`encode_to_seekable`](ImageCodec::encode_to_seekable) streams it.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        hdrcodec_core::encode_via_seekable(self, image, settings, out)
    }
    fn encode_to_seekable(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn hdrcodec_core::WriteSeek,
    ) -> Result<hdrcodec_core::EncodeReport> {
        let options = ExrEncodeOptions::from_settings(settings)?;
        let writer = encode::ExrWriter::new(&ImageInfo::of(image), &options, &settings.pool)?;
        hdrcodec_core::encode_rows(Box::new(writer), image, out)
    }
    /// Blocks are compressed and written as their rows come; the offset table is filled in last.
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        let options = ExrEncodeOptions::from_settings(settings)?;
        Ok(Some(Box::new(encode::ExrWriter::new(info, &options, &settings.pool)?)))
    }
}

/// The largest finite half float.
const HALF_MAX: f32 = 65504.0;

/// The samples (alpha included) found beyond ±65504, the largest half float, as a sentence for
/// the encode report, if any. Rounding to nearest makes those from ±65520 on ±infinity and those
/// between ±65504 (IEEE 754 binary16). Infinities and NaN are stored as they are, so they are
/// not counted.
fn describe_half_overflow(counts: hdrcodec_core::RangeCount) -> Option<String> {
    counts
        .describe(
            "OpenEXR half",
            -HALF_MAX,
            HALF_MAX,
            "-infinity (-65504 above -65520)",
            "+infinity (65504 below 65520)",
            "NaN",
        )
        .map(|s| format!("{s}; --opt pixel=float keeps them"))
}

#[cfg(test)]
mod tests;
