//! LogL16, LogLuv24 and LogLuv32 pixel encodings (Larson 1998, "LogLuv encoding for full-gamut,
//! high-dynamic-range images") and LogLuv TIFF files (Compression 34676 SGILOG and 34677
//! SGILOG24), bit-exact with libtiff's `tif_luv.c` in its no-dither mode.
//!
//! - [`pixel`]: the per-pixel encoders and decoders, CIE XYZ ↔ encoded word.
//! - [`uvgrid`]: the u'v' cell index of LogLuv24.
//! - [`LogLuvRaster`]: a decoded-but-not-converted image (one encoded word per pixel), read
//!   from and written to TIFF with [`read_tiff`] and [`LogLuvRaster::to_tiff`].
//! - [`decode`] / [`encode`]: [`HdrImage`] ↔ TIFF through XYZ, in any RGB primaries. The TIFF
//!   STONITS tag (cd/m² of file luminance 1) is chosen by [`Stonits`]: the image's
//!   `nits_per_unit` unless the encoding would clip the image at that scale, else the scale that
//!   puts the brightest pixel at the top of the code range; decoding gives `nits_per_unit` =
//!   STONITS, so the absolute luminance survives either way. [`encode_with_report`] says what
//!   was chosen and what was clipped.
//! - [`probe`]: size and colour from the TIFF header and first IFD alone ([`tiff::read_info`]).
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

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub mod pixel;
mod rle;
mod scale;
pub mod tiff;
pub mod uvgrid;

use hdrcodec_core::color::{mat_inverse, mat_to_f32, Mat3};
use hdrcodec_core::sink::{band_rows, fill_rows, ImageSink, RowSink, Scratch};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, EncodeReport, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits,
    ReadSeek, Result,
};
use pixel::Tables;
pub use scale::{Clipped, Stonits};

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

    /// The encoding's name as Larson's paper writes it: "LogL16", "LogLuv24" or "LogLuv32".
    pub fn label(self) -> &'static str {
        match self {
            Encoding::LogL16 => "LogL16",
            Encoding::LogLuv24 => "LogLuv24",
            Encoding::LogLuv32 => "LogLuv32",
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
    /// How STONITS, the scale of the file's luminance, is chosen (default
    /// [`Stonits::Auto`]: the image's `nits_per_unit` unless that clips, see [`Stonits`]).
    pub stonits: Stonits,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions { encoding: Encoding::LogLuv32, rows_per_strip: 0, stonits: Stonits::Auto }
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

/// The colour of an image decoded with `opts` from a file with this STONITS value.
fn decoded_color(stonits: Option<f64>, opts: &DecodeOptions) -> ColorInfo {
    ColorInfo {
        primaries: opts.primaries,
        nits_per_unit: stonits.map_or(opts.default_nits_per_unit, |s| s as f32),
        hdr10: None,
    }
}

/// Size, channels (RGB), colour and encoding of a LogLuv TIFF as [`decode`] with `opts` would
/// return them, from the TIFF header and first IFD only ([`tiff::read_info`]): checks the size
/// against the limits' dimensions, allocates nothing of the image's size.
pub fn probe(data: &[u8], limits: &Limits, opts: &DecodeOptions) -> Result<ImageInfo> {
    image_info(&tiff::read_info(data)?, limits, opts)
}

/// [`probe`] from a file (any source that reads and seeks, from its current position): the
/// header, the first IFD and its tags' values are read from the file
/// ([`tiff::read_info_from`]), not a strip. Same answer and the same kinds of errors as
/// [`probe`] on the file's bytes.
pub fn probe_from(input: &mut dyn ReadSeek, limits: &Limits, opts: &DecodeOptions) -> Result<ImageInfo> {
    image_info(&tiff::read_info_from(input, limits)?, limits, opts)
}

/// What [`probe`] returns for the image the first IFD describes.
fn image_info(info: &tiff::TiffInfo, limits: &Limits, opts: &DecodeOptions) -> Result<ImageInfo> {
    limits.check_dimensions(u64::from(info.width), u64::from(info.height))?;
    let compression = if info.encoding == Encoding::LogLuv24 { "SGILOG24" } else { "SGILOG" };
    let mut format = format!("{}, {compression}", info.encoding.label());
    if let Some(s) = info.stonits {
        // As `nits_per_unit` holds it (f32): 179, 19280.361.
        format += &format!(", STONITS {}", s as f32);
    }
    Ok(ImageInfo::new(info.width, info.height, Channels::Rgb, decoded_color(info.stonits, opts)).with_format(format))
}

/// Decodes a LogLuv TIFF to an RGB image in `opts.primaries`.
pub fn decode(data: &[u8], limits: &Limits, opts: &DecodeOptions) -> Result<HdrImage> {
    let mut sink = ImageSink::new(limits);
    decode_rows(data, limits, opts, &mut sink)?;
    sink.finish()
}

/// Decodes a LogLuv TIFF into `sink`, one band of rows at a time: each row is read from its
/// strip and converted straight into the sink (in place when the sink allows it), so nothing
/// of the image's size is held besides the sink's own storage.
pub fn decode_rows(data: &[u8], limits: &Limits, opts: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    probe(data, limits, opts)?;
    decode_strip_rows(tiff::StripRows::new(data)?, limits, opts, sink)
}

/// [`decode_rows`] from a file (any source that reads and seeks, from its current position):
/// the header, the first IFD and its tags' values are read from the file, then each strip as
/// its rows are decoded ([`tiff::StripRows::from_reader`]), so that the file is never held
/// whole. Same rows and the same kinds of errors as [`decode_rows`] on the file's bytes.
pub fn decode_rows_from(
    input: &mut dyn ReadSeek,
    limits: &Limits,
    opts: &DecodeOptions,
    sink: &mut dyn RowSink,
) -> Result<()> {
    decode_strip_rows(tiff::StripRows::from_reader(input, limits)?, limits, opts, sink)
}

/// Converts the rows of `rows` into `sink`, a band at a time.
fn decode_strip_rows(
    mut rows: tiff::StripRows<'_>,
    limits: &Limits,
    opts: &DecodeOptions,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let info = image_info(&rows.info, limits, opts)?;
    let (width, height, encoding) = (rows.info.width, rows.info.height, rows.info.encoding);
    let to_rgb = WordsToRgb::new(encoding, opts)?;
    let row_len = width as usize * 3;
    let band = band_rows(row_len, 1 << 20).min(height);
    let _words = limits.charge(u64::from(width) * 4, "a row of LogLuv words")?;
    sink.start(&info)?;
    let mut words = vec![0u32; width as usize];
    let mut scratch = Scratch::new(limits);
    let mut y = 0;
    while y < height {
        let n = band.min(height - y);
        fill_rows(sink, y, n, row_len, &mut scratch, |out| {
            for row in out.chunks_exact_mut(row_len) {
                rows.next_row(&mut words)?;
                to_rgb.convert(&words, row);
            }
            Ok(())
        })?;
        y += n;
    }
    Ok(())
}

/// Converts encoded words to an RGB image in `opts.primaries`.
pub fn raster_to_image(raster: &LogLuvRaster, opts: &DecodeOptions) -> Result<HdrImage> {
    let mut samples = vec![0.0; raster.words.len() * 3];
    WordsToRgb::new(raster.encoding, opts)?.convert(&raster.words, &mut samples);
    HdrImage::new(raster.width, raster.height, Channels::Rgb, samples, decoded_color(raster.stonits, opts))
}

/// Encoded words → RGB samples in the decode options' primaries (through CIE XYZ).
struct WordsToRgb {
    encoding: Encoding,
    /// XYZ → RGB, or `None` when the primaries are XYZ itself.
    matrix: Option<[[f32; 3]; 3]>,
    tables: &'static Tables,
}

impl WordsToRgb {
    fn new(encoding: Encoding, opts: &DecodeOptions) -> Result<Self> {
        let matrix = if encoding == Encoding::LogL16 || opts.primaries == ColorPrimaries::Xyz {
            None
        } else {
            Some(mat_to_f32(
                &mat_inverse(&rgb_to_xyz(&opts.primaries)?)
                    .ok_or_else(|| Error::invalid("singular RGB to XYZ matrix"))?,
            ))
        };
        Ok(WordsToRgb { encoding, matrix, tables: Tables::get() })
    }

    /// Converts `words` into `out` (3 samples per word).
    fn convert(&self, words: &[u32], out: &mut [f32]) {
        let t = self.tables;
        let pixels = words.iter().zip(out.chunks_exact_mut(3));
        match self.encoding {
            Encoding::LogL16 => pixels.for_each(|(&p, o)| o.fill(t.l16(p as u16))),
            enc => {
                let decode = |p: u32| if enc == Encoding::LogLuv24 { t.luv24(p) } else { t.luv32(p) };
                for (&p, o) in pixels {
                    let xyz = decode(p);
                    match &self.matrix {
                        None => o.copy_from_slice(&xyz),
                        Some(m) => {
                            for (o, r) in o.iter_mut().zip(m) {
                                *o = r[0] * xyz[0] + r[1] * xyz[1] + r[2] * xyz[2];
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Converts an image (any primaries; alpha is dropped) to encoded words via CIE XYZ, with
/// STONITS chosen as `stonits` says, and reports the chosen scale (when [`Stonits::Auto`] moved
/// it away from the image's `nits_per_unit`) and the pixels whose luminance the encoding could
/// not hold. The file's luminance is `Y · nits_per_unit / STONITS`, so decoding gives the same
/// absolute luminance (samples in file units, `nits_per_unit` = STONITS).
pub fn image_to_raster(image: &HdrImage, encoding: Encoding, stonits: Stonits) -> Result<(LogLuvRaster, EncodeReport)> {
    let plan = Plan::new(image, encoding, stonits)?;
    let mut words = vec![0u32; image.pixel_count()];
    let mut clipped = Clipped::default();
    plan.encode(image.samples(), &mut words, &mut clipped);
    let raster = LogLuvRaster {
        width: image.width(),
        height: image.height(),
        encoding,
        words,
        stonits: Some(plan.choice.stonits),
    };
    Ok((raster, plan.report(&clipped)))
}

/// How an image is turned into words: its RGB → XYZ matrix and the scale chosen for it.
struct Plan {
    m: Mat3,
    encoding: Encoding,
    stonits: Stonits,
    choice: scale::Choice,
    channels: usize,
    nits_per_unit: f32,
}

impl Plan {
    /// The matrix, and STONITS as `stonits` says. With [`Stonits::Auto`] the scale moves only
    /// when the image would clip at its own (see [`scale::choose`]), so every file of an image
    /// that fits is written at the image's `nits_per_unit`.
    fn new(image: &HdrImage, encoding: Encoding, stonits: Stonits) -> Result<Self> {
        let m = rgb_to_xyz(&image.color.primaries)?;
        let choice = scale::choose(image, &m, encoding, stonits)?;
        Ok(Plan {
            m,
            encoding,
            stonits,
            choice,
            channels: image.channels().count(),
            nits_per_unit: image.color.nits_per_unit,
        })
    }

    /// Encodes interleaved `samples` (whole pixels of the image's layout) into `words`, one per
    /// pixel, tallying what the encoding could not hold.
    fn encode(&self, samples: &[f32], words: &mut [u32], clipped: &mut Clipped) {
        let (m, s, encoding) = (&self.m, self.choice.scale, self.encoding);
        let pixels = samples.chunks_exact(self.channels).zip(words.iter_mut());
        match encoding {
            Encoding::LogL16 => {
                for (p, w) in pixels {
                    let [r, g, b] = [p[0], p[1], p[2]].map(f64::from);
                    // `* s` is exact when s = 1: a file at the image's own scale is the same as ever.
                    let y = (m[1][0] * r + m[1][1] * g + m[1][2] * b) * s;
                    *w = u32::from(pixel::logl16_from_y(y));
                    clipped.tally(encoding, y, *w);
                }
            }
            Encoding::LogLuv24 | Encoding::LogLuv32 => {
                for (p, w) in pixels {
                    let [r, g, b] = [p[0], p[1], p[2]].map(f64::from);
                    let v: [f32; 3] = std::array::from_fn(|i| ((m[i][0] * r + m[i][1] * g + m[i][2] * b) * s) as f32);
                    *w = if encoding == Encoding::LogLuv24 {
                        pixel::logluv24_from_xyz(v)
                    } else {
                        pixel::logluv32_from_xyz(v)
                    };
                    clipped.tally(encoding, f64::from(v[1]), *w);
                }
            }
        }
    }

    /// The notes: the scale chosen (when it moved) and what clipped.
    fn report(&self, clipped: &Clipped) -> EncodeReport {
        let mut report = EncodeReport::new();
        if let Some(note) = scale::moved_note(self.encoding, &self.choice, self.nits_per_unit) {
            report.note(note);
        }
        if let Some(note) = clipped.note(self.encoding, &self.choice, matches!(self.stonits, Stonits::Fixed(_))) {
            report.note(note);
        }
        report
    }
}

/// Encodes an image as a LogLuv TIFF into `out`, strip by strip (see [`encode_with_report`]
/// for the report): the words and bytes of one strip are held at a time, and the IFD's offset
/// is filled in by seeking back.
pub fn write_with_report(
    image: &HdrImage,
    opts: &EncodeOptions,
    out: &mut dyn hdrcodec_core::WriteSeek,
) -> Result<EncodeReport> {
    let plan = Plan::new(image, opts.encoding, opts.stonits)?;
    let rows_per_strip = match opts.rows_per_strip {
        // About 64 KiB of pixels per strip, as `LogLuvRaster::to_tiff` writes.
        0 => (65536 / image.width().max(1).saturating_mul(4)).max(1),
        n => n,
    };
    let layout = tiff::Layout {
        width: image.width(),
        height: image.height(),
        encoding: opts.encoding,
        rows_per_strip,
        stonits: Some(plan.choice.stonits),
    };
    let row = image.width() as usize * plan.channels;
    let mut clipped = Clipped::default();
    tiff::write_streamed(out, &layout, |first_row, words| {
        let start = first_row as usize * row;
        plan.encode(&image.samples()[start..start + words.len() * plan.channels], words, &mut clipped);
        Ok(())
    })?;
    Ok(plan.report(&clipped))
}

/// Encodes an image as a LogLuv TIFF (the notes of [`encode_with_report`] are dropped).
pub fn encode(image: &HdrImage, opts: &EncodeOptions) -> Result<Vec<u8>> {
    Ok(encode_with_report(image, opts)?.0)
}

/// Encodes an image as a LogLuv TIFF, with the report of [`image_to_raster`]: the STONITS
/// chosen and what was clipped.
pub fn encode_with_report(image: &HdrImage, opts: &EncodeOptions) -> Result<(Vec<u8>, EncodeReport)> {
    let mut file = std::io::Cursor::new(Vec::new());
    let report = write_with_report(image, opts, &mut file)?;
    Ok((file.into_inner(), report))
}

/// The [`ImageCodec`] of one LogLuv encoding. Each instance decodes any LogLuv TIFF; it
/// encodes with its own encoding. Options: `rows_per_strip=N`, `stonits=auto|N` (see
/// [`Stonits`]; auto by default).
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
    /// The TIFF `STONITS` tag records `nits_per_unit`.
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    /// The TIFF header and first IFD only (see [`probe`]).
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        probe(data, limits, &DecodeOptions::default())
    }
    /// The TIFF header, first IFD and its tags' values, read from the file (see [`probe_from`]).
    fn probe_from(&self, input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        probe_from(input, limits, &DecodeOptions::default())
    }
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        decode_rows(data, &options.limits, &DecodeOptions::default(), sink)
    }
    /// Reads the strips from the file as they are decoded (see [`decode_rows_from`]).
    fn decode_rows_from(
        &self,
        input: &mut dyn ReadSeek,
        options: &hdrcodec_core::DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        decode_rows_from(input, &options.limits, &DecodeOptions::default(), sink)
    }
    /// Into a plain writer the file is assembled in memory first (the header points at the
    /// IFD, which follows the strips); [`encode_to_seekable`](ImageCodec::encode_to_seekable)
    /// streams it.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<EncodeReport> {
        hdrcodec_core::encode_via_seekable(self, image, settings, out)
    }
    fn encode_to_seekable(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn hdrcodec_core::WriteSeek,
    ) -> Result<EncodeReport> {
        settings.check_options(self.name(), &["rows_per_strip", "stonits"])?;
        let rows_per_strip = settings.parse_option::<u32>("rows_per_strip")?.unwrap_or(0);
        let stonits = settings.option("stonits").map(str::parse).transpose()?.unwrap_or_default();
        let mut report =
            write_with_report(image, &EncodeOptions { encoding: self.encoding, rows_per_strip, stonits }, out)?;
        if !image.color.primaries.is_specified() {
            // LogLuv stores CIE XYZ: the samples must be read in some primaries to get there.
            report.note(
                "the input records no primaries: LogLuv converted it to CIE XYZ as if it were BT.709 \
                 (--opt primaries=NAME labels them)",
            );
        }
        Ok(report)
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

    /// Absolute luminance (cd/m²) of every pixel of a BT.709 image.
    fn nits(img: &HdrImage) -> Vec<f64> {
        let k = f64::from(img.color.nits_per_unit);
        img.rgb().map(|[r, g, b]| k * (0.2126 * f64::from(r) + 0.7152 * f64::from(g) + 0.0722 * f64::from(b))).collect()
    }

    fn grey(width: u32, height: u32, nits_per_unit: f32, f: impl Fn(u32, u32) -> f32) -> HdrImage {
        let f = &f;
        let samples = (0..height).flat_map(|y| (0..width).flat_map(move |x| [f(x, y); 3])).collect::<Vec<f32>>();
        let color = ColorInfo { nits_per_unit, ..Default::default() };
        HdrImage::new(width, height, Channels::Rgb, samples, color).unwrap()
    }

    fn encode_report(img: &HdrImage, enc: Encoding, settings: &EncodeSettings) -> (HdrImage, Vec<String>) {
        let codec = LogLuvTiffCodec::new(enc);
        let mut file = Vec::new();
        let report = codec.encode_to(img, settings, &mut file).unwrap();
        assert!(codec.sniff(&file));
        (codec.decode(&file, &Limits::default()).unwrap(), report.notes)
    }

    /// `file` decoded by `decode_from`, from `at` bytes into a source that holds it.
    fn from_file(codec: &LogLuvTiffCodec, file: &[u8], at: usize, limits: &Limits) -> Result<HdrImage> {
        let mut padded = vec![0xAA; at];
        padded.extend_from_slice(file);
        let mut input = std::io::Cursor::new(padded);
        input.set_position(at as u64);
        codec.decode_from(&mut input, &hdrcodec_core::DecodeOptions::new(limits.clone()))
    }

    /// A noisy image (so that the run-length coded file is about as large as its words).
    fn noisy(width: u32, height: u32) -> HdrImage {
        let mut state = 12345u32;
        let samples = (0..width * height * 3)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                0.001 + (state >> 8) as f32 / (1u32 << 24) as f32 * 50.0
            })
            .collect();
        let color = ColorInfo { nits_per_unit: 179.0, ..Default::default() };
        HdrImage::new(width, height, Channels::Rgb, samples, color).unwrap()
    }

    #[test]
    fn decoding_from_a_file_gives_the_in_memory_samples() {
        let img = noisy(37, 23);
        for enc in [Encoding::LogLuv32, Encoding::LogL16, Encoding::LogLuv24] {
            let codec = LogLuvTiffCodec::new(enc);
            for rows_per_strip in [0, 1, 5] {
                let opts = EncodeOptions { encoding: enc, rows_per_strip, stonits: Stonits::Auto };
                let file = encode(&img, &opts).unwrap();
                let want = codec.decode(&file, &Limits::default()).unwrap();
                for at in [0, 3] {
                    let got = from_file(&codec, &file, at, &Limits::default()).unwrap();
                    assert_eq!(got.samples(), want.samples(), "{enc:?} {rows_per_strip} at {at}");
                    assert_eq!(got.color, want.color);
                }
            }
        }
    }

    #[test]
    fn decoding_from_a_file_does_not_hold_the_file() {
        let img = noisy(300, 200);
        let codec = LogLuvTiffCodec::new(Encoding::LogLuv32);
        let file = codec.encode(&img, &EncodeSettings::default()).unwrap();
        let image_bytes = 300 * 200 * 12;
        assert!(file.len() > 150_000, "{}", file.len());
        // Room for the image, a strip and a row of words, not for the image and the file.
        let limits = Limits::default().with_max_alloc_bytes(image_bytes + 100_000).with_own_budget();
        let whole_file = hdrcodec_core::read_rest(&mut std::io::Cursor::new(&file), &limits).unwrap();
        assert!(matches!(limits.charge(image_bytes, "the image"), Err(Error::LimitExceeded { .. })));
        drop(whole_file);
        let got = from_file(&codec, &file, 0, &limits).unwrap();
        assert_eq!(got.samples(), codec.decode(&file, &Limits::default()).unwrap().samples());
        assert!(limits.peak() < image_bytes + 100_000, "{}", limits.peak());
    }

    #[test]
    fn a_short_or_broken_file_is_the_same_kind_of_error_from_a_file() {
        let img = noisy(20, 9);
        let codec = LogLuvTiffCodec::new(Encoding::LogLuv32);
        let file = encode(&img, &EncodeOptions { rows_per_strip: 2, ..Default::default() }).unwrap();
        let kind = |r: Result<HdrImage>| std::mem::discriminant(&r.unwrap_err());
        for len in (0..file.len()).step_by(7).chain([1, 7, 8, 9, file.len() - 1]) {
            let mem = codec.decode(&file[..len], &Limits::default());
            assert_eq!(kind(from_file(&codec, &file[..len], 2, &Limits::default())), kind(mem), "{len}");
        }
        // A strip offset past the end of the file.
        let mut bad = file.clone();
        let t = hdrcodec_core::tiff::Tiff::parse(&file, hdrcodec_core::tiff::MAGIC_TIFF).unwrap();
        let e = t.first_ifd().unwrap();
        let offsets = e.get(hdrcodec_core::tiff::tag::STRIP_OFFSETS).unwrap();
        let at = offsets.values_at().unwrap() as usize + 4;
        bad[at..at + 4].copy_from_slice(&(file.len() as u32 - 2).to_le_bytes());
        let mem = codec.decode(&bad, &Limits::default()).unwrap_err();
        let got = from_file(&codec, &bad, 0, &Limits::default()).unwrap_err();
        assert!(matches!((&mem, &got), (Error::Truncated { .. }, Error::Truncated { .. })), "{mem} / {got}");
    }

    #[test]
    fn image_round_trip_in_every_encoding() {
        let samples: Vec<f32> = (0..48).map(|i| 0.01 * 1.3f32.powi(i)).collect();
        let color = ColorInfo { nits_per_unit: 179.0, ..Default::default() };
        let img = HdrImage::new(4, 4, Channels::Rgb, samples, color).unwrap();
        let want = nits(&img);
        for (enc, tol) in [(Encoding::LogLuv32, 0.01), (Encoding::LogL16, 0.01), (Encoding::LogLuv24, 0.05)] {
            let (back, notes) = encode_report(&img, enc, &EncodeSettings::default());
            // Luminance 1.8 .. 4.1e5 cd/m²: LogLuv32 / LogL16 keep STONITS = nits_per_unit;
            // LogLuv24 (4.8 decades from 0.043 cd/m² at that scale) moves its range up, so the
            // highlights survive and the darkest pixels are now below it.
            if enc == Encoding::LogLuv24 {
                assert!(back.color.nits_per_unit > 179.0, "{}", back.color.nits_per_unit);
                assert_eq!(notes.len(), 2, "{notes:?}");
            } else {
                assert_eq!(back.color.nits_per_unit, 179.0);
                assert!(notes.is_empty(), "{notes:?}");
            }
            let lo = enc.luminance_range().0 * f64::from(back.color.nits_per_unit);
            for (a, b) in want.iter().zip(nits(&back)) {
                if *a > lo * 1.1 {
                    assert!((b / a - 1.0).abs() < tol, "{enc:?} {a} → {b}");
                }
            }
        }
        // The probe reads the same size and colour from the IFD alone.
        for enc in [Encoding::LogL16, Encoding::LogLuv24, Encoding::LogLuv32] {
            let codec = LogLuvTiffCodec::new(enc);
            let file = codec.encode(&img, &EncodeSettings::default()).unwrap();
            let info = codec.probe(&file, &Limits::default()).unwrap();
            let back = codec.decode(&file, &Limits::default()).unwrap();
            assert_eq!((info.width, info.height, info.channels, &info.color), (4, 4, back.channels(), &back.color));
            // STONITS is the image's 179 unless the encoding chose another scale (stonits=auto).
            let label = format!(
                "{}, {}, STONITS {}",
                enc.label(),
                if enc == Encoding::LogLuv24 { "SGILOG24" } else { "SGILOG" },
                back.color.nits_per_unit
            );
            assert_eq!(info.format, label);
            let tiny = Limits::default().with_max_alloc_bytes(16);
            assert!(codec.decode(&file, &tiny).is_err() && codec.probe(&file, &tiny).is_ok());
        }
        let bad = EncodeSettings::default().with_option("dither", "1");
        assert!(LogLuvTiffCodec::new(Encoding::LogL16).encode(&img, &bad).is_err());
        let bad = EncodeSettings::default().with_option("stonits", "-3");
        assert!(LogLuvTiffCodec::new(Encoding::LogLuv24).encode(&img, &bad).is_err());
    }

    /// A 96x48 sun-and-sky scene like the generated corpus' "sun-sky" (nits_per_unit 100): a sky
    /// gradient of 500-2000 cd/m², a sun disk of about 1e5 cd/m² (radius 6) with a glow, ground of
    /// 20-80 cd/m², and a strip of deep shadow of 0.01-0.05 cd/m² along the bottom (4 rows).
    fn sun_sky() -> (HdrImage, usize) {
        let (w, h) = (96u32, 48u32);
        let img = grey(w, h, 100.0, |x, y| {
            let nits = if y >= h - 4 {
                0.01 + 0.04 * (x as f32 / w as f32)
            } else if y >= 36 {
                20.0 + 60.0 * (((x * 7 + y * 13) % 17) as f32 / 16.0)
            } else {
                let d = ((x as f32 - 60.0).powi(2) + (y as f32 - 12.0).powi(2)).sqrt();
                let sky = 2000.0 - 1500.0 * y as f32 / 36.0 + 5000.0 * (-d / 4.0).exp();
                if d < 6.0 {
                    1e5 * (1.0 - 0.3 * d / 6.0)
                } else {
                    sky
                }
            };
            nits / 100.0
        });
        (img, (4 * w) as usize)
    }

    #[test]
    fn logluv24_keeps_the_highlights_of_a_sun_and_clips_the_dark_end() {
        let (img, shadow) = sun_sky();
        let want = nits(&img);
        // At the image's own scale (STONITS 100) LogLuv24 codes 0.025 .. 1600 cd/m²: the sun
        // and the glow clip.
        let (fixed, notes) =
            encode_report(&img, Encoding::LogLuv24, &EncodeSettings::default().with_option("stonits", "100"));
        assert_eq!(fixed.color.nits_per_unit, 100.0);
        let brighter = want.iter().filter(|&&v| v >= 1600.0).count();
        assert!(brighter > 100, "{brighter}");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains(&format!("{brighter} brighter became 1591 cd/m²")), "{notes:?}");
        let worst = |back: &HdrImage, from: f64| {
            want.iter()
                .zip(nits(back))
                .filter(|(a, _)| **a >= from)
                .map(|(a, b)| (b / a - 1.0).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&fixed, 5e4) > 0.95, "the sun was clipped to 1.6e3 cd/m²");

        // Auto: the sun's peak (1e5 cd/m²) goes just below the top of the range, the shadow strip
        // below 1e5 / 10^4.8 ≈ 1.6 cd/m² becomes black, and both are said.
        let (back, notes) = encode_report(&img, Encoding::LogLuv24, &EncodeSettings::default());
        let stonits = f64::from(back.color.nits_per_unit);
        assert!((stonits / (100.0 * 1000.0 / (15.742 * (1.0 - 2f64.powi(-20)))) - 1.0).abs() < 1e-7, "{stonits}");
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(notes[0].contains("STONITS 6352") && notes[0].contains("100000 cd/m²"), "{notes:?}");
        assert!(notes[1].contains(&format!("{shadow} darker became black")), "{notes:?}");
        assert!(!notes[1].contains("brighter"), "{notes:?}");
        // Every pixel above the shadow keeps its luminance within LogLuv24's half step (0.55 %).
        assert!(worst(&back, 1e4) < 0.006, "{}", worst(&back, 1e4));
        assert!(worst(&back, 10.0) < 0.006, "{}", worst(&back, 10.0));
        let dark = nits(&back).iter().zip(&want).filter(|(b, a)| **a < 1.0 && **b == 0.0).count();
        assert_eq!(dark, shadow);

        // LogLuv32 holds it all at the image's own scale: the same file as before, no note.
        let (back32, notes) = encode_report(&img, Encoding::LogLuv32, &EncodeSettings::default());
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(back32.color.nits_per_unit, 100.0);
    }

    #[test]
    fn auto_keeps_the_images_scale_when_nothing_clips() {
        // 0.05 .. 1500 cd/m² at 100 cd/m² per unit fits LogLuv24 as it is: same bytes as with
        // STONITS forced to nits_per_unit (the file earlier versions wrote), no notes.
        let img = grey(32, 8, 100.0, |x, y| 5e-4 * 1.4f32.powi((x + 32 * y) as i32 % 30));
        for enc in [Encoding::LogLuv24, Encoding::LogLuv32, Encoding::LogL16] {
            let auto = encode_with_report(&img, &EncodeOptions { encoding: enc, ..Default::default() }).unwrap();
            let fixed = EncodeOptions { encoding: enc, stonits: Stonits::Fixed(100.0), ..Default::default() };
            assert_eq!(auto.0, encode(&img, &fixed).unwrap(), "{enc:?}");
            assert!(auto.1.notes.is_empty(), "{enc:?} {:?}", auto.1.notes);
            assert_eq!(read_tiff(&auto.0, &Limits::default()).unwrap().stonits, Some(100.0));
        }
        // An all-black image keeps the scale too.
        let black = grey(4, 4, 179.0, |_, _| 0.0);
        let (back, notes) = encode_report(&black, Encoding::LogLuv24, &EncodeSettings::default());
        assert_eq!((back.color.nits_per_unit, notes.len()), (179.0, 0));
    }

    #[test]
    fn a_forced_stonits_is_written_and_decodes_to_the_same_luminance() {
        let img = grey(8, 2, 100.0, |x, y| 0.5 * 2f32.powi((x + 8 * y) as i32 % 5));
        let want = nits(&img);
        for enc in [Encoding::LogLuv24, Encoding::LogLuv32, Encoding::LogL16] {
            let settings = EncodeSettings::default().with_option("stonits", "179");
            let (back, notes) = encode_report(&img, enc, &settings);
            assert!(notes.is_empty(), "{notes:?}");
            assert_eq!(back.color.nits_per_unit, 179.0);
            for (a, b) in want.iter().zip(nits(&back)) {
                assert!((b / a - 1.0).abs() < 0.006, "{enc:?} {a} → {b}");
            }
        }
    }

    #[test]
    fn logl16_and_logluv32_scale_only_at_their_extremes() {
        // 1e30 units (1e32 cd/m²) is past the 1.8e19 top of LogL16: auto moves the range up.
        let bright = grey(4, 1, 100.0, |x, _| [1e30, 3e29, 1e20, 1.0][x as usize]);
        // 1e-25 units is below the 5.4e-20 bottom: auto moves the range down.
        let dim = grey(4, 1, 100.0, |x, _| [1e-25, 3e-26, 1e-27, 0.0][x as usize]);
        for enc in [Encoding::LogL16, Encoding::LogLuv32] {
            for img in [&bright, &dim] {
                let (back, notes) = encode_report(img, enc, &EncodeSettings::default());
                assert_ne!(back.color.nits_per_unit, 100.0);
                assert_eq!(notes.len(), 1, "{enc:?} {notes:?}");
                assert!(notes[0].contains("stonits=auto"), "{notes:?}");
                for (a, b) in nits(img).iter().zip(nits(&back)) {
                    assert!((b / a - 1.0).abs() < 0.002 || (*a == 0.0 && b == 0.0), "{enc:?} {a:e} → {b:e}");
                }
                // Forced to the image's scale, the same pixels clip and the note says how many.
                let forced = EncodeSettings::default().with_option("stonits", "100");
                let (_, notes) = encode_report(img, enc, &forced);
                let n = if std::ptr::eq(img, &bright) { "3 brighter" } else { "3 darker became black" };
                assert!(notes.len() == 1 && notes[0].contains(n), "{enc:?} {notes:?}");
            }
        }
        // A STONITS outside f32 is never chosen: the decoder's nits_per_unit stays finite.
        let huge = grey(1, 1, 1e30, |_, _| 3e38);
        let (back, _) = encode_report(&huge, Encoding::LogL16, &EncodeSettings::default());
        assert!(back.color.nits_per_unit.is_finite());
    }

    #[test]
    fn negative_and_nan_luminance_are_reported() {
        let img = grey(5, 1, 100.0, |x, _| [1.0, -2.0, f32::NAN, -0.5, f32::INFINITY][x as usize]);
        let (_, notes) = encode_report(&img, Encoding::LogLuv24, &EncodeSettings::default());
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].contains("1 brighter became")
                && notes[0].contains("2 of negative luminance became black")
                && notes[0].contains("1 NaN became black"),
            "{notes:?}"
        );
        let (_, notes) = encode_report(&img, Encoding::LogLuv32, &EncodeSettings::default());
        assert!(notes[0].contains("2 of negative luminance keep their sign but decode as black"), "{notes:?}");
        // LogL16 returns negative luminance: only the NaN and the infinity are noted.
        let (back, notes) = encode_report(&img, Encoding::LogL16, &EncodeSettings::default());
        assert!(!notes[0].contains("negative") && notes[0].contains("1 NaN"), "{notes:?}");
        assert!(back.pixel(1, 0)[0] < -1.9);
    }

    #[test]
    fn unspecified_primaries_are_read_as_bt709_and_said() {
        let samples = vec![1.0, 0.5, 0.25, 4.0, 2.0, 0.1];
        let mut img = HdrImage::new(2, 1, Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let codec = LogLuvTiffCodec::new(Encoding::LogLuv32);
        let mut as709 = Vec::new();
        assert!(codec.encode_to(&img, &EncodeSettings::default(), &mut as709).unwrap().notes.is_empty());
        img.color.primaries = ColorPrimaries::Unspecified;
        let mut out = Vec::new();
        let report = codec.encode_to(&img, &EncodeSettings::default(), &mut out).unwrap();
        assert_eq!(out, as709, "the same XYZ as BT.709 samples");
        assert_eq!(report.notes.len(), 1);
        assert!(report.notes[0].contains("records no primaries") && report.notes[0].contains("as if it were BT.709"));
    }
}
