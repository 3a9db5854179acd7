//! The family's decoders inside the `image` crate (feature `image`): after
//! [`register_image_decoding_hooks`], `image::open("shot.jxr")`, `("tex.dds")`, `("x.hdr")`,
//! `("y.tif")` and `image::load_from_memory(..)` decode through hdrcodec and return
//! `Rgb32F` / `Rgba32F` images, the way image-rs asks new formats to arrive (its `hooks`).
//!
//! The samples are what [`Registry::decode`](crate::Registry::decode) gives: scene-linear, in the
//! file's primaries, 1.0 = the file's `nits_per_unit` cd/m². `image` has no place for either, so
//! [`ImageDecoder::icc_profile`] describes the primaries in an ICC profile with a linear curve
//! (none when the file records no primaries).
//!
//! Where `image` has a decoder of its own for an extension (`.tif`, `.dds`, `.jpg`), the hook
//! takes only the files that decoder cannot give in HDR (LogLuv TIFFs, BC6H textures, gain-map
//! and JPEG-HDR JPEGs) and hands every other file to `image`'s decoder, as if no hook were there
//! (an 8-bit TIFF stays `Rgb8`). Radiance (`.hdr`, `.pic`) and OpenEXR files are always HDR, and
//! ours read every file `image`'s decoders of them read, so those extensions are ours.
//!
//! For what the family knows besides the pixels (primaries, `nits_per_unit`, metadata), make
//! an [`HdrDecoder`] and read [`HdrDecoder::info`] before handing it to
//! `image::DynamicImage::from_decoder`.

use crate::core::sink::RowSink;
use crate::core::{Channels, ColorPrimaries, DecodeOptions, Error, ImageCodec, ImageInfo, Limits, Result};
use crate::Registry;
use image::error::{DecodingError, ImageFormatHint, LimitError, LimitErrorKind};
use image::hooks::{register_decoding_hook, register_format_detection_hook, DecodingHook, GenericReader};
use image::{ColorType, ImageDecoder, ImageError, ImageFormat, ImageResult};
use std::io::{Cursor, Read};
use std::path::Path;
use std::sync::Arc;

/// The extensions hooked, with `image`'s own format for that extension where it has one (the
/// files our decoders do not take in HDR go there).
const HOOKED: &[(&str, Option<ImageFormat>)] = &[
    ("jxr", None),
    ("wdp", None),
    ("hdp", None),
    ("ktx2", None),
    ("hdrc", None),
    ("pfm", None),
    ("hdr", None),
    ("pic", None),
    ("exr", None),
    ("dds", Some(ImageFormat::Dds)),
    ("tif", Some(ImageFormat::Tiff)),
    ("tiff", Some(ImageFormat::Tiff)),
    ("jpg", Some(ImageFormat::Jpeg)),
    ("jpeg", Some(ImageFormat::Jpeg)),
];

/// Magic numbers of formats `image` does not detect itself (for `load_from_memory` and
/// `with_guessed_format`), or detects as a format whose decoder cannot read our files (BC6H
/// in DDS). TIFF and JPEG are left to `image`'s detection: most such files are not HDR.
const MAGIC: &[(&str, &[u8])] = &[
    ("jxr", b"II\xBC\x01"),
    ("jxr", b"II\xBC\x00"),
    ("ktx2", b"\xABKTX 20\xBB\r\n\x1A\n"),
    ("hdrc", b"\x8BHDRC\r\n\n"),
    ("pfm", b"PF\n"),
    ("pfm", b"Pf\n"),
    ("pfm", b"PF "),
    ("pfm", b"Pf "),
    ("dds", b"DDS "),
];

/// Registers a decoding hook for every extension of the family and a detection hook for the
/// magic numbers `image` does not know. Returns how many extensions were hooked (an extension
/// that already has a hook, ours or another crate's, keeps it). Call it once, early.
pub fn register_image_decoding_hooks() -> usize {
    let mut hooked = 0;
    for &(ext, builtin) in HOOKED {
        let hook: DecodingHook = Box::new(move |reader| open(ext, builtin, reader));
        if register_decoding_hook(ext.into(), hook) {
            hooked += 1;
        }
    }
    for &(ext, magic) in MAGIC {
        register_format_detection_hook(ext.into(), magic, None);
    }
    hooked
}

/// What the hook for `ext` does with a file: decode it ourselves, or give it to `image`'s
/// `builtin` decoder.
fn open<'a>(
    ext: &'static str,
    builtin: Option<ImageFormat>,
    mut reader: GenericReader<'a>,
) -> ImageResult<Box<dyn ImageDecoder + 'a>> {
    let mut data = Vec::new();
    reader.read_to_end(&mut data).map_err(ImageError::IoError)?;
    match HdrDecoder::new(ext, data) {
        Ok(decoder) => Ok(Box::new(decoder)),
        Err((data, error)) => match builtin {
            Some(format) => {
                let decoder = image::ImageReader::with_format(Cursor::new(data), format).into_decoder()?;
                Ok(Box::new(decoder))
            }
            None => Err(decoding_error(ext, error)),
        },
    }
}

fn decoding_error(ext: &str, error: Error) -> ImageError {
    match error {
        // `image`'s limit errors carry no text; the kind says enough.
        Error::LimitExceeded { .. } => ImageError::Limits(LimitError::from_kind(LimitErrorKind::InsufficientMemory)),
        e => ImageError::Decoding(DecodingError::new(ImageFormatHint::Name(ext.to_ascii_uppercase()), e)),
    }
}

/// An `image` decoder over one file of the family, probed when made (size, channels, colour
/// from the header; no pixel decoded) and decoded when `image` asks for the pixels.
pub struct HdrDecoder {
    ext: &'static str,
    codec: Arc<dyn ImageCodec>,
    data: Vec<u8>,
    info: ImageInfo,
    limits: Limits,
}

impl HdrDecoder {
    /// A decoder for `data`, a file with extension `ext`; gives the data back with the reason
    /// when no decoder of the family takes it in HDR (a plain JPEG, an 8-bit TIFF, a DXT DDS).
    pub fn new(ext: &'static str, data: Vec<u8>) -> std::result::Result<Self, (Vec<u8>, Error)> {
        let limits = Limits::default();
        let registry = Registry::default();
        let path = format!("file.{ext}");
        let (codec, info) = match registry.probe(Path::new(&path), &data, &limits) {
            Ok((codec, info)) if takes_in_hdr(codec.name(), &info) => (codec, info),
            Ok((codec, _)) => {
                let why = Error::unsupported(format!("{}: not an HDR file (left to image's decoder)", codec.name()));
                return Err((data, why));
            }
            Err(e) => return Err((data, e)),
        };
        Ok(HdrDecoder { ext, codec, data, info, limits })
    }

    /// What the header says: size, channels, colour (primaries, `nits_per_unit`), metadata.
    pub fn info(&self) -> &ImageInfo {
        &self.info
    }
}

/// Whether `info`, which codec `codec` read, is a file we decode in HDR. A gain-map codec also
/// reads plain JPEGs (as SDR): those go to `image`.
fn takes_in_hdr(codec: &str, info: &ImageInfo) -> bool {
    match codec {
        "ultrahdr" | "jpeg-hdr" => {
            info.metadata_value("jpeg.gain_map").is_some() || info.format.starts_with("JPEG-HDR (")
        }
        _ => true,
    }
}

impl ImageDecoder for HdrDecoder {
    fn dimensions(&self) -> (u32, u32) {
        (self.info.width, self.info.height)
    }

    fn color_type(&self) -> ColorType {
        if self.info.channels.count() == 4 {
            ColorType::Rgba32F
        } else {
            ColorType::Rgb32F
        }
    }

    /// A profile of the file's primaries with a linear curve (the samples are linear); `None`
    /// when the file records no primaries or they have no chromaticities.
    fn icc_profile(&mut self) -> ImageResult<Option<Vec<u8>>> {
        let primaries = self.info.color.primaries;
        if primaries == ColorPrimaries::Unspecified {
            return Ok(None);
        }
        let description = format!("{} linear (hdrcodec)", primaries.name());
        Ok(crate::jpeghdr::icc::rgb_profile_with(&primaries, &description, crate::jpeghdr::icc::Curve::Linear))
    }

    fn set_limits(&mut self, limits: image::Limits) -> ImageResult<()> {
        let (w, h) = self.dimensions();
        limits.check_dimensions(w, h)?;
        let mut ours = Limits::default();
        ours.max_width = ours.max_width.min(limits.max_image_width.unwrap_or(u32::MAX));
        ours.max_height = ours.max_height.min(limits.max_image_height.unwrap_or(u32::MAX));
        // `image` counts the output buffer itself; ours is what the decoder needs besides it.
        ours.max_alloc_bytes = ours.max_alloc_bytes.min(limits.max_alloc.unwrap_or(u64::MAX));
        self.limits = ours;
        Ok(())
    }

    fn read_image(self, buf: &mut [u8]) -> ImageResult<()> {
        let expected = self.total_bytes();
        if buf.len() as u64 != expected {
            return Err(decoding_error(
                self.ext,
                Error::invalid(format!("a buffer of {} bytes for an image of {expected}", buf.len())),
            ));
        }
        // The codec that probed the file decodes it.
        let options = DecodeOptions::new(self.limits.clone());
        let mut sink = ByteSink { buf, row_bytes: 0, info: &self.info };
        self.codec.decode_rows(&self.data, &options, &mut sink).map_err(|e| decoding_error(self.ext, e))
    }

    fn read_image_boxed(self: Box<Self>, buf: &mut [u8]) -> ImageResult<()> {
        (*self).read_image(buf)
    }
}

/// Rows from a decoder into `image`'s byte buffer as native-endian `f32` (band by band from
/// the decoder's bounded scratch: the image is never held twice).
struct ByteSink<'b, 'i> {
    buf: &'b mut [u8],
    row_bytes: usize,
    info: &'i ImageInfo,
}

impl RowSink for ByteSink<'_, '_> {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        if (info.width, info.height, info.channels) != (self.info.width, self.info.height, self.info.channels) {
            return Err(Error::invalid("the decoder's image differs from its header"));
        }
        self.row_bytes = info.width as usize * info.channels.count() * 4;
        Ok(())
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let start = y as usize * self.row_bytes;
        let out = self
            .buf
            .get_mut(start..start + samples.len() * 4)
            .ok_or_else(|| Error::invalid("rows beyond the image (a bug in the decoder)"))?;
        for (o, s) in out.chunks_exact_mut(4).zip(samples) {
            o.copy_from_slice(&s.to_ne_bytes());
        }
        Ok(())
    }
}

/// `image` moves the samples of `image` into an `Rgb32F` or `Rgba32F` image (no copy). The
/// colour (primaries, `nits_per_unit`) and metadata, which `image` has no place for, are
/// dropped: keep `image.color` if you need them back.
pub fn to_dynamic_image(image: crate::core::HdrImage) -> image::DynamicImage {
    let (w, h, channels) = (image.width(), image.height(), image.channels());
    let samples = image.into_samples();
    // `HdrImage::new` checked that the samples fill w × h × channels exactly.
    if channels.count() == 4 {
        image::DynamicImage::ImageRgba32F(
            image::ImageBuffer::from_raw(w, h, samples).expect("an HdrImage's samples fill its size"),
        )
    } else {
        image::DynamicImage::ImageRgb32F(
            image::ImageBuffer::from_raw(w, h, samples).expect("an HdrImage's samples fill its size"),
        )
    }
}

/// An `Rgb32F` or `Rgba32F` image as an [`HdrImage`](crate::core::HdrImage) with the colour
/// `color` (the samples are moved, not copied). Other pixel types are an error: their transfer
/// curve (sRGB? linear?) is not recorded, and guessing it is what the family never does;
/// convert them to linear `f32` yourself, saying which curve they had.
pub fn from_dynamic_image(image: image::DynamicImage, color: crate::core::ColorInfo) -> Result<crate::core::HdrImage> {
    let (w, h) = (image.width(), image.height());
    match image {
        image::DynamicImage::ImageRgb32F(b) => crate::core::HdrImage::new(w, h, Channels::Rgb, b.into_raw(), color),
        image::DynamicImage::ImageRgba32F(b) => crate::core::HdrImage::new(w, h, Channels::Rgba, b.into_raw(), color),
        other => Err(Error::unsupported(format!(
            "an image of {:?} samples: only Rgb32F and Rgba32F (linear light) convert without guessing a transfer curve",
            other.color()
        ))),
    }
}
