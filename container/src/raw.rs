//! The built-in payload codecs, so that the container works on its own: raw little-endian
//! `f32` (lossless) and IEEE binary16 (`half`) samples.
//!
//! Stand-alone form (the whole payload of a DATA chunk, or a file of its own):
//!
//! | bytes | field |
//! | --- | --- |
//! | 4 | id: `RF32` or `RF16` |
//! | 4 | width, u32 little-endian |
//! | 4 | height, u32 little-endian |
//! | 1 | channels: 3 (RGB) or 4 (RGBA) |
//! | w·h·c·4 or w·h·c·2 | interleaved samples, rows top to bottom, little-endian |
//!
//! Colour information is not stored: inside `.hdrc` it lives in COLR/HDRM.

use half::f16;
use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
use hdrcodec_core::sink::{band_rows, fill_rows, RowSink, Scratch};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits, ReadSeek,
    Result, StoredBytes,
};
use std::io::Read;

const HEADER_LEN: usize = 13;

/// Lossless raw `f32` samples, id `RF32`, name `raw-f32`. No encode options.
#[derive(Clone, Copy, Debug, Default)]
pub struct RawF32Codec;

/// Raw IEEE 754 binary16 samples, id `RF16`, name `raw-f16`: half the size of `raw-f32`,
/// 11 significant bits (relative error ≤ 2⁻¹¹ for normal values), range ±65504 (larger
/// values become infinity), subnormals down to 2⁻²⁴. No encode options.
#[derive(Clone, Copy, Debug, Default)]
pub struct RawF16Codec;

/// How one raw sample format is stored.
trait Sample {
    const ID: [u8; 4];
    const NAME: &'static str;
    /// The stored format for [`ImageCodec::probe`].
    const FORMAT: &'static str;
    const BYTES: usize;
    fn put(v: f32, out: &mut Vec<u8>);
    fn get(b: &[u8]) -> f32;
}

impl Sample for RawF32Codec {
    const ID: [u8; 4] = *b"RF32";
    const NAME: &'static str = "raw-f32";
    const FORMAT: &'static str = "raw f32 little-endian";
    const BYTES: usize = 4;
    fn put(v: f32, out: &mut Vec<u8>) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    fn get(b: &[u8]) -> f32 {
        f32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }
}

impl Sample for RawF16Codec {
    const ID: [u8; 4] = *b"RF16";
    const NAME: &'static str = "raw-f16";
    const FORMAT: &'static str = "raw binary16 little-endian";
    const BYTES: usize = 2;
    fn put(v: f32, out: &mut Vec<u8>) {
        out.extend_from_slice(&f16::from_f32(v).to_le_bytes());
    }
    fn get(b: &[u8]) -> f32 {
        f16::from_le_bytes([b[0], b[1]]).to_f32()
    }
}

fn encode<S: Sample>(image: &HdrImage, settings: &EncodeSettings) -> Result<Vec<u8>> {
    settings.check_options(S::NAME, &[])?;
    let out = Vec::with_capacity(HEADER_LEN + image.samples().len() * S::BYTES);
    let mut w = ByteWriter::from_vec(out, ByteOrder::Little);
    w.bytes(&S::ID);
    w.u32(image.width());
    w.u32(image.height());
    w.u8(image.channels().count() as u8);
    let out = w.as_mut_vec();
    for &v in image.samples() {
        S::put(v, out);
    }
    Ok(w.into_vec())
}

/// Parses the 13-byte header `h` (fewer bytes: truncated) of a payload whose samples are the
/// `body_len` bytes after it: checks the size against the limits' dimensions and the samples'
/// length against it; returns width, height, channels and the samples' length in bytes.
fn parse_header<S: Sample>(h: &[u8], body_len: u64, limits: &Limits) -> Result<(u32, u32, Channels, u64)> {
    // The whole header is there before any of it is judged.
    let mut h = ByteReader::le(h).sub(HEADER_LEN as u64, format_args!("the {HEADER_LEN}-byte {} header", S::NAME))?;
    if h.array::<4>("the id")? != S::ID {
        return Err(Error::invalid(format!("not a {} payload (wrong id)", S::NAME)));
    }
    let (width, height) = (h.u32("the width")?, h.u32("the height")?);
    let count = h.u8("the channel count")?;
    let channels = Channels::from_count(usize::from(count))
        .ok_or_else(|| Error::invalid(format!("{} header: {count} channels (expected 3 or 4)", S::NAME)))?;
    limits.check_dimensions(u64::from(width), u64::from(height))?;
    // Checked in u64 before any allocation: with `Limits::none()` the product may not fit.
    let need = (u64::from(width) * u64::from(height)).saturating_mul((channels.count() * S::BYTES) as u64);
    if need > body_len {
        return Err(Error::truncated(format!(
            "the {} samples of a {width}x{height} image ({need} bytes, {body_len} present)",
            S::NAME
        )));
    }
    if body_len > need {
        return Err(Error::invalid(format!("{} bytes after the {} samples", body_len - need, S::NAME)));
    }
    Ok((width, height, channels, need))
}

/// [`parse_header`] on a payload held in memory; returns the samples' bytes.
fn header<'a, S: Sample>(data: &'a [u8], limits: &Limits) -> Result<(u32, u32, Channels, &'a [u8])> {
    let body = data.get(HEADER_LEN..).unwrap_or_default();
    let (width, height, channels, _) = parse_header::<S>(data, body.len() as u64, limits)?;
    Ok((width, height, channels, body))
}

/// No colour is stored: the samples are the writer's, in primaries the container's COLR says.
fn raw_color() -> ColorInfo {
    ColorInfo { primaries: ColorPrimaries::Unspecified, ..ColorInfo::default() }
}

/// Size and channels from the header; the colour is [`raw_color`] as decoding gives it.
fn probe<S: Sample>(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    let (width, height, channels, _) = header::<S>(data, limits)?;
    Ok(ImageInfo::new(width, height, channels, raw_color()).with_format(S::FORMAT))
}

/// Decodes into `sink` a band of rows at a time (in place when the sink allows it): nothing of
/// the image's size is held besides the sink's storage.
fn decode_rows<S: Sample>(data: &[u8], limits: &Limits, sink: &mut dyn RowSink) -> Result<()> {
    let (width, height, channels, body) = header::<S>(data, limits)?;
    decode_bands::<S>(width, height, channels, StoredBytes::memory(body, S::NAME), limits, sink)
}

/// [`decode_rows`] from a source that reads and seeks: the header is read, the source's length
/// checked against the samples it declares, then each band of about 1 MB is read as it is
/// converted, so that the payload is never held whole.
fn decode_rows_from<S: Sample>(input: &mut dyn ReadSeek, limits: &Limits, sink: &mut dyn RowSink) -> Result<()> {
    let (at, rest) = hdrcodec_core::remaining_len(input)?;
    let mut head = Vec::with_capacity(HEADER_LEN);
    input.take(HEADER_LEN as u64).read_to_end(&mut head)?;
    let body_len = rest.saturating_sub(HEADER_LEN as u64);
    let (width, height, channels, _) = parse_header::<S>(&head, body_len, limits)?;
    let samples = StoredBytes::file(input, at + HEADER_LEN as u64, limits, S::NAME);
    decode_bands::<S>(width, height, channels, samples, limits, sink)
}

/// Delivers the rows of a `width` × `height` image stored as `samples`, a band at a time. The
/// image's bytes are the sink's to charge (a sink that converts rows as they come holds none of
/// them); the header's dimensions were checked against the limits, and the samples' length
/// against the payload's, so the image is at most twice the payload.
fn decode_bands<S: Sample>(
    width: u32,
    height: u32,
    channels: Channels,
    mut samples: StoredBytes<'_>,
    limits: &Limits,
    sink: &mut dyn RowSink,
) -> Result<()> {
    sink.start(&ImageInfo::new(width, height, channels, raw_color()).with_format(S::FORMAT))?;
    let row_len = width as usize * channels.count();
    let band = band_rows(row_len, 1 << 20);
    let mut scratch = Scratch::new(limits);
    let mut y = 0;
    while y < height {
        let n = band.min(height - y);
        let rows = samples.band(y as usize * row_len * S::BYTES, n as usize * row_len * S::BYTES)?;
        fill_rows(sink, y, n, row_len, &mut scratch, |out| {
            out.iter_mut().zip(rows.chunks_exact(S::BYTES)).for_each(|(o, b)| *o = S::get(b));
            Ok(())
        })?;
        y += n;
    }
    Ok(())
}

macro_rules! raw_codec {
    ($t:ty) => {
        impl ImageCodec for $t {
            fn name(&self) -> &'static str {
                <$t as Sample>::NAME
            }
            fn id(&self) -> [u8; 4] {
                <$t as Sample>::ID
            }
            fn extensions(&self) -> &'static [&'static str] {
                &[]
            }
            fn sniff(&self, head: &[u8]) -> bool {
                head.starts_with(&<$t as Sample>::ID)
            }
            /// Raw samples carry no colour of their own: the container's COLR chunk does.
            fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
                hdrcodec_core::ColorSignalling::None
            }
            /// The 13-byte header (and the payload's length).
            fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
                probe::<$t>(data, limits)
            }
            fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
                hdrcodec_core::decode_image(self, data, options)
            }
            /// A band of rows at a time, converted straight into the sink.
            fn decode_rows(
                &self,
                data: &[u8],
                options: &hdrcodec_core::DecodeOptions,
                sink: &mut dyn RowSink,
            ) -> Result<()> {
                decode_rows::<$t>(data, &options.limits, sink)
            }
            /// A band of rows at a time, read from the source as it is converted.
            fn decode_rows_from(
                &self,
                input: &mut dyn hdrcodec_core::ReadSeek,
                options: &hdrcodec_core::DecodeOptions,
                sink: &mut dyn RowSink,
            ) -> Result<()> {
                decode_rows_from::<$t>(input, &options.limits, sink)
            }
            fn encode_to(
                &self,
                image: &HdrImage,
                settings: &EncodeSettings,
                out: &mut dyn std::io::Write,
            ) -> Result<hdrcodec_core::EncodeReport> {
                out.write_all(&encode::<$t>(image, settings)?)?;
                Ok(hdrcodec_core::EncodeReport::new())
            }
        }
    };
}

raw_codec!(RawF32Codec);
raw_codec!(RawF16Codec);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_bytes_are_ieee_binary16() {
        // IEEE 754-2008 binary16 encodings: 1.0 = 0x3C00, -2.0 = 0xC000, 65504 (largest finite)
        // = 0x7BFF, 2^-24 (smallest subnormal) = 0x0001, 0.5 = 0x3800.
        let img = HdrImage::new(1, 1, Channels::Rgba, vec![1.0, -2.0, 65504.0, 2f32.powi(-24)], ColorInfo::default())
            .unwrap();
        let b = RawF16Codec.encode(&img, &EncodeSettings::default()).unwrap();
        assert_eq!(&b[..13], &[b'R', b'F', b'1', b'6', 1, 0, 0, 0, 1, 0, 0, 0, 4]);
        assert_eq!(&b[13..], &[0x00, 0x3C, 0x00, 0xC0, 0xFF, 0x7B, 0x01, 0x00]);
        assert_eq!(RawF16Codec.decode(&b, &Limits::default()).unwrap().samples(), img.samples());
    }

    #[test]
    fn f32_is_lossless_and_little_endian() {
        let v = vec![1.0, f32::MIN_POSITIVE, 1e30, -0.0, 3.5, f32::INFINITY];
        let img = HdrImage::new(2, 1, Channels::Rgb, v.clone(), ColorInfo::default()).unwrap();
        let b = RawF32Codec.encode(&img, &EncodeSettings::default()).unwrap();
        // 1.0f32 is 0x3F800000 (IEEE 754 binary32), little-endian on disk.
        assert_eq!(&b[13..17], &[0x00, 0x00, 0x80, 0x3F]);
        let back = RawF32Codec.decode(&b, &Limits::default()).unwrap();
        assert!(back.samples().iter().zip(&v).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(back.color.primaries, ColorPrimaries::Unspecified, "raw samples record no colour");
    }

    #[test]
    fn bad_payloads_are_errors() {
        let img = HdrImage::zeroed(3, 2, Channels::Rgb);
        let b = RawF32Codec.encode(&img, &EncodeSettings::default()).unwrap();
        for n in 0..b.len() {
            assert!(RawF32Codec.decode(&b[..n], &Limits::default()).is_err(), "truncated to {n}");
        }
        let mut long = b.clone();
        long.push(0);
        assert!(RawF32Codec.decode(&long, &Limits::default()).is_err());
        assert!(RawF16Codec.decode(&b, &Limits::default()).is_err(), "wrong id");
        let mut huge = b[..13].to_vec();
        huge[4..8].copy_from_slice(&1_000_000u32.to_le_bytes());
        huge[8..12].copy_from_slice(&1_000_000u32.to_le_bytes());
        assert!(matches!(RawF32Codec.decode(&huge, &Limits::default()), Err(Error::LimitExceeded { .. })));
        let opts = EncodeSettings::default().with_option("bogus", "1");
        assert!(RawF32Codec.encode(&img, &opts).is_err());
    }
}
