//! LogL16, LogLuv24 and LogLuv32 pixel encodings (Larson 1998, "LogLuv encoding for full-gamut,
//! high-dynamic-range images") and LogLuv TIFF files (Compression 34676 SGILOG and 34677
//! SGILOG24), bit-exact with libtiff's `tif_luv.c` in its no-dither mode.
//!
//! - [`pixel`]: the per-pixel encoders and decoders, CIE XYZ ↔ encoded word.
//! - [`uvgrid`]: the u'v' cell index of LogLuv24.
//! - [`LogLuvRaster`]: a decoded-but-not-converted image (one encoded word per pixel), read
//!   from and written to TIFF with [`read_tiff`] and [`LogLuvRaster::to_tiff`].
//! - [`decode`] / [`encode`]: [`HdrImage`] ↔ TIFF through XYZ, in any RGB primaries; the TIFF
//!   STONITS tag is the image's `nits_per_unit`.
//! - [`LogLuvTiffCodec`]: the [`ImageCodec`] for each encoding ("logluv32", "logluv24", "logl16").
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, HdrImage, Limits};
//! use hdrcodec_logluv::{decode, encode, DecodeOptions, EncodeOptions, Encoding};
//! let img = HdrImage::new(2, 1, Channels::Rgb, vec![1.0, 0.5, 0.25, 1e4, 2e4, 3e4], ColorInfo::default())?;
//! let tif = encode(&img, &EncodeOptions { encoding: Encoding::LogLuv32, ..Default::default() })?;
//! let back = decode(&tif, &Limits::default(), &DecodeOptions::default())?;
//! assert!((back.pixel(1, 0)[2] / 3e4 - 1.0).abs() < 0.01);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

#![forbid(unsafe_code)]

pub mod pixel;
mod rle;
pub mod tiff;
pub mod uvgrid;

use hdrcodec_core::color::{mat_inverse, mat_to_f32, Mat3};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, Error, HdrImage, ImageCodec, Limits, Result};
use pixel::Tables;

/// The three LogLuv pixel encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// Luminance only: sign + 15-bit log2 (1/256 stop), TIFF LogL + SGILOG.
    LogL16,
    /// 10-bit log2 luminance (1/64 stop) + 14-bit u'v' cell, TIFF LogLuv + SGILOG24.
    LogLuv24,
    /// Sign + 15-bit log2 luminance, 8-bit u' and v', TIFF LogLuv + SGILOG.
    LogLuv32,
}

impl Encoding {
    /// The codec name of this encoding: "logl16", "logluv24" or "logluv32".
    pub fn name(self) -> &'static str {
        match self {
            Encoding::LogL16 => "logl16",
            Encoding::LogLuv24 => "logluv24",
            Encoding::LogLuv32 => "logluv32",
        }
    }

    /// The bits of a word this encoding uses.
    pub fn word_mask(self) -> u32 {
        match self {
            Encoding::LogL16 => 0xffff,
            Encoding::LogLuv24 => 0xff_ffff,
            Encoding::LogLuv32 => u32::MAX,
        }
    }

    /// Floats per pixel in the XYZ form of [`LogLuvRaster::to_floats`]: 1 (Y) or 3 (XYZ).
    pub fn float_channels(self) -> usize {
        if self == Encoding::LogL16 {
            1
        } else {
            3
        }
    }

    /// Encodes one pixel from its XYZ form (`[Y]` for LogL16, `[X, Y, Z]` otherwise).
    #[inline]
    pub fn encode_pixel(self, xyz: &[f32]) -> u32 {
        match self {
            Encoding::LogL16 => u32::from(pixel::logl16_from_y(f64::from(xyz[0]))),
            Encoding::LogLuv24 => pixel::logluv24_from_xyz([xyz[0], xyz[1], xyz[2]]),
            Encoding::LogLuv32 => pixel::logluv32_from_xyz([xyz[0], xyz[1], xyz[2]]),
        }
    }
}

/// An image held as encoded LogLuv words, one per pixel, rows top to bottom (LogL16 in the low
/// 16 bits, LogLuv24 in the low 24 bits).
#[derive(Clone, Debug, PartialEq)]
pub struct LogLuvRaster {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The pixel encoding of `words`.
    pub encoding: Encoding,
    /// The encoded pixels.
    pub words: Vec<u32>,
    /// The TIFF STONITS value: cd/m² of Y = 1, if known.
    pub stonits: Option<f64>,
}

impl LogLuvRaster {
    /// Encodes XYZ floats (`[Y]` per pixel for LogL16, `[X, Y, Z]` otherwise: the layout of
    /// libtiff's `SGILOGDATAFMT_FLOAT`).
    pub fn from_floats(width: u32, height: u32, encoding: Encoding, floats: &[f32]) -> Result<Self> {
        let n = encoding.float_channels();
        if floats.len() as u64 != u64::from(width) * u64::from(height) * n as u64 {
            return Err(Error::invalid(format!("{width}x{height} {} needs {n} floats per pixel", encoding.name())));
        }
        let words = floats.chunks_exact(n).map(|p| encoding.encode_pixel(p)).collect();
        Ok(LogLuvRaster { width, height, encoding, words, stonits: None })
    }

    /// Decodes to XYZ floats in the layout of [`from_floats`](Self::from_floats), bit-identical
    /// to libtiff's `SGILOGDATAFMT_FLOAT` output.
    pub fn to_floats(&self) -> Vec<f32> {
        let t = Tables::get();
        match self.encoding {
            Encoding::LogL16 => self.words.iter().map(|&p| t.l16(p as u16)).collect(),
            Encoding::LogLuv24 => self.words.iter().flat_map(|&p| t.luv24(p)).collect(),
            Encoding::LogLuv32 => self.words.iter().flat_map(|&p| t.luv32(p)).collect(),
        }
    }

    /// Writes a TIFF with about 64 KiB of pixels per strip.
    pub fn to_tiff(&self) -> Result<Vec<u8>> {
        let row_bytes = self.width.max(1).saturating_mul(4);
        tiff::write(self, (65536 / row_bytes).max(1))
    }
}

/// Reads the first image of a LogLuv TIFF as encoded words (no conversion).
pub fn read_tiff(data: &[u8], limits: &Limits) -> Result<LogLuvRaster> {
    tiff::read(data, limits)
}

/// How [`decode`] presents the pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodeOptions {
    /// The RGB primaries of the output (default BT.709). [`ColorPrimaries::Xyz`] gives the
    /// file's XYZ unchanged. LogL16 (grey) decodes to R = G = B = Y in any primaries.
    pub primaries: ColorPrimaries,
    /// `nits_per_unit` when the file has no STONITS tag (default 100, the family's default).
    pub default_nits_per_unit: f32,
}

impl Default for DecodeOptions {
    fn default() -> Self {
        DecodeOptions { primaries: ColorPrimaries::Bt709, default_nits_per_unit: ColorInfo::default().nits_per_unit }
    }
}

/// How [`encode`] writes the file.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodeOptions {
    /// The pixel encoding (default LogLuv32).
    pub encoding: Encoding,
    /// Rows per TIFF strip; 0 chooses about 64 KiB of pixels per strip.
    pub rows_per_strip: u32,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions { encoding: Encoding::LogLuv32, rows_per_strip: 0 }
    }
}

/// The RGB→XYZ matrix of `p` (white → Y = 1; identity for XYZ), refusing degenerate custom
/// chromaticities rather than silently using the identity.
fn rgb_to_xyz(p: &ColorPrimaries) -> Result<Mat3> {
    match p {
        ColorPrimaries::Xyz => Ok(p.rgb_to_xyz()),
        _ => p
            .chromaticities()
            .try_rgb_to_xyz()
            .ok_or_else(|| Error::invalid(format!("degenerate {} chromaticities", p.name()))),
    }
}

/// Decodes a LogLuv TIFF to an RGB image in `opts.primaries`.
pub fn decode(data: &[u8], limits: &Limits, opts: &DecodeOptions) -> Result<HdrImage> {
    raster_to_image(&read_tiff(data, limits)?, opts)
}

/// Converts encoded words to an RGB image in `opts.primaries`.
pub fn raster_to_image(raster: &LogLuvRaster, opts: &DecodeOptions) -> Result<HdrImage> {
    let t = Tables::get();
    let mut samples = Vec::with_capacity(raster.words.len() * 3);
    match raster.encoding {
        Encoding::LogL16 => samples.extend(raster.words.iter().flat_map(|&p| [t.l16(p as u16); 3])),
        enc => {
            let m = mat_to_f32(
                &mat_inverse(&rgb_to_xyz(&opts.primaries)?)
                    .ok_or_else(|| Error::invalid("singular RGB to XYZ matrix"))?,
            );
            let identity = opts.primaries == ColorPrimaries::Xyz;
            let mut push = |xyz: [f32; 3]| {
                if identity {
                    samples.extend_from_slice(&xyz);
                } else {
                    samples.extend(m.iter().map(|r| r[0] * xyz[0] + r[1] * xyz[1] + r[2] * xyz[2]));
                }
            };
            if enc == Encoding::LogLuv24 {
                raster.words.iter().for_each(|&p| push(t.luv24(p)));
            } else {
                raster.words.iter().for_each(|&p| push(t.luv32(p)));
            }
        }
    }
    let color = ColorInfo {
        primaries: opts.primaries,
        nits_per_unit: raster.stonits.map_or(opts.default_nits_per_unit, |s| s as f32),
        hdr10: None,
    };
    HdrImage::new(raster.width, raster.height, Channels::Rgb, samples, color)
}

/// Converts an image (any primaries; alpha is dropped) to encoded words via CIE XYZ; the
/// image's `nits_per_unit` becomes STONITS.
pub fn image_to_raster(image: &HdrImage, encoding: Encoding) -> Result<LogLuvRaster> {
    let m = rgb_to_xyz(&image.color.primaries)?;
    let xyz = |[r, g, b]: [f32; 3]| -> [f32; 3] {
        let [r, g, b] = [r, g, b].map(f64::from);
        std::array::from_fn(|i| (m[i][0] * r + m[i][1] * g + m[i][2] * b) as f32)
    };
    let words = match encoding {
        Encoding::LogL16 => image
            .rgb()
            .map(|p| {
                let [r, g, b] = p.map(f64::from);
                u32::from(pixel::logl16_from_y(m[1][0] * r + m[1][1] * g + m[1][2] * b))
            })
            .collect(),
        Encoding::LogLuv24 => image.rgb().map(|p| pixel::logluv24_from_xyz(xyz(p))).collect(),
        Encoding::LogLuv32 => image.rgb().map(|p| pixel::logluv32_from_xyz(xyz(p))).collect(),
    };
    Ok(LogLuvRaster {
        width: image.width(),
        height: image.height(),
        encoding,
        words,
        stonits: Some(f64::from(image.color.nits_per_unit)),
    })
}

/// Encodes an image as a LogLuv TIFF.
pub fn encode(image: &HdrImage, opts: &EncodeOptions) -> Result<Vec<u8>> {
    let raster = image_to_raster(image, opts.encoding)?;
    if opts.rows_per_strip == 0 {
        raster.to_tiff()
    } else {
        tiff::write(&raster, opts.rows_per_strip)
    }
}

/// The [`ImageCodec`] of one LogLuv encoding. Each instance decodes any LogLuv TIFF; it
/// encodes with its own encoding. Option: `rows_per_strip=N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogLuvTiffCodec {
    /// The encoding this codec writes.
    pub encoding: Encoding,
}

impl LogLuvTiffCodec {
    /// The codec writing `encoding`.
    pub const fn new(encoding: Encoding) -> Self {
        LogLuvTiffCodec { encoding }
    }
}

impl ImageCodec for LogLuvTiffCodec {
    fn name(&self) -> &'static str {
        self.encoding.name()
    }
    fn id(&self) -> [u8; 4] {
        match self.encoding {
            Encoding::LogL16 => *b"LL16",
            Encoding::LogLuv24 => *b"LL24",
            Encoding::LogLuv32 => *b"LL32",
        }
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["tif", "tiff"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        tiff::is_tiff(head)
    }
    /// LogLuv records colour absolutely, as CIE XYZ: any primaries survive (decoding gives
    /// BT.709 samples, negative where a colour lies outside BT.709).
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::Any
    }
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        decode(data, &options.limits, &DecodeOptions::default())
    }
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        settings.check_options(self.name(), &["rows_per_strip"])?;
        let rows_per_strip = settings.parse_option::<u32>("rows_per_strip")?.unwrap_or(0);
        out.write_all(&encode(image, &EncodeOptions { encoding: self.encoding, rows_per_strip })?)?;
        Ok(hdrcodec_core::EncodeReport::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bt709_matrix_matches_the_srgb_standard() {
        // IEC 61966-2-1 (sRGB), the RGB→XYZ matrix to 4 decimals.
        let m = rgb_to_xyz(&ColorPrimaries::Bt709).unwrap();
        let want = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[i][j] - want[i][j]).abs() < 1e-4, "{m:?}");
            }
        }
    }

    #[test]
    fn image_round_trip_in_every_encoding() {
        let samples: Vec<f32> = (0..48).map(|i| 0.01 * 1.3f32.powi(i)).collect();
        let color = ColorInfo { nits_per_unit: 179.0, ..Default::default() };
        let img = HdrImage::new(4, 4, Channels::Rgb, samples, color).unwrap();
        for (enc, tol) in [(Encoding::LogLuv32, 0.01), (Encoding::LogLuv24, 0.05)] {
            let codec = LogLuvTiffCodec::new(enc);
            let file = codec.encode(&img, &EncodeSettings::default()).unwrap();
            assert!(codec.sniff(&file));
            let back = codec.decode(&file, &Limits::default()).unwrap();
            assert_eq!(back.color.nits_per_unit, 179.0);
            // Luminance survives within the encoding's precision (LogLuv24's range is 2^-12..2^4).
            for (a, b) in img.rgb().zip(back.rgb()) {
                let y = |p: [f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
                if (0.001..15.0).contains(&y(a)) {
                    assert!((y(b) / y(a) - 1.0).abs() < tol, "{enc:?} {a:?} → {b:?}");
                }
            }
        }
        let bad = EncodeSettings::default().with_option("dither", "1");
        assert!(LogLuvTiffCodec::new(Encoding::LogL16).encode(&img, &bad).is_err());
    }
}
