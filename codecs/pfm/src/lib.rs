//! Portable float map (PFM) reading and writing for hdrcodec.
//!
//! PFM is the three-line ASCII header `PF` (RGB) or `Pf` (grey), `width height`, `scale`,
//! then raw 32-bit floats, rows **bottom to top**. The sign of `scale` gives the byte order
//! (negative: little-endian, positive: big-endian); its magnitude has no agreed meaning (some
//! tools store an exposure in it) and is kept, when it is not 1, as metadata `pfm.scale`
//! without touching the samples.
//!
//! - Reading: `PF` and `Pf` in either byte order; grey becomes R = G = B. The header is parsed
//!   strictly (one whitespace-separated token per field, decimal unsigned sizes, a finite
//!   non-zero scale, exactly one whitespace byte before the data); the size is checked against
//!   [`Limits`] before anything is allocated; short data is [`Error::Truncated`]. Bytes after
//!   the pixels are ignored (some writers pad).
//! - Writing: `PF`, little-endian (scale `-1`). PFM has no alpha channel: **alpha is dropped**.
//!   Samples are written as they are (NaN and infinities included).
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
//! use hdrcodec_pfm::PfmCodec;
//! let img = HdrImage::new(1, 2, Channels::Rgb, vec![1.0, 2.0, 3.0, 1e6, 0.0, -1.0], ColorInfo::default())?;
//! let bytes = PfmCodec.encode(&img, &EncodeSettings::default())?;
//! assert!(bytes.starts_with(b"PF\n1 2\n-1\n"));
//! // PFM records no primaries: the samples come back exactly, labelled "unspecified".
//! assert_eq!(PfmCodec.decode(&bytes, &Limits::default())?.samples(), img.samples());
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

#![forbid(unsafe_code)]

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::sink::{band_rows, fill_rows, RowSink, Scratch};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, DecodeOptions, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits,
    ReadSeek, Result, StoredBytes,
};
use std::io::Read;

/// The PFM codec of the family (`pfm`, id `PFM `).
#[derive(Clone, Copy, Debug, Default)]
pub struct PfmCodec;

/// The longest header accepted: three short lines. Anything longer is not a PFM header.
const MAX_HEADER: usize = 256;

/// A parsed header.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Header {
    grey: bool,
    width: u32,
    height: u32,
    little_endian: bool,
    scale: f32,
}

/// Reads one whitespace-separated token (after skipping whitespace); the token must end with a
/// whitespace byte within the first [`MAX_HEADER`] bytes, on which the reader stops.
fn token<'a>(r: &mut ByteReader<'a>, what: &str) -> Result<&'a [u8]> {
    let room = |r: &ByteReader<'_>| (MAX_HEADER as u64).saturating_sub(r.position());
    r.take_while(room(r), |b| b.is_ascii_whitespace());
    let token = r.take_while(room(r), |b| !b.is_ascii_whitespace());
    // The whitespace byte that ends the token: its absence is a truncation, unless the header
    // bound stopped the scan first.
    r.peek(1, format_args!("the {what} in the PFM header"))?;
    if room(r) == 0 {
        return Err(Error::invalid(format!(
            "PFM header: the {what} is missing or the header is longer than {MAX_HEADER} bytes"
        )));
    }
    Ok(token)
}

fn parse_size(t: &[u8], what: &str) -> Result<u32> {
    let s = std::str::from_utf8(t).ok().filter(|s| s.bytes().all(|b| b.is_ascii_digit()));
    s.and_then(|s| s.parse::<u32>().ok())
        .filter(|&v| v > 0)
        .ok_or_else(|| Error::invalid(format!("PFM header: {what} '{}' is not a positive integer", show(t))))
}

fn show(t: &[u8]) -> String {
    String::from_utf8_lossy(&t[..t.len().min(16)]).into_owned()
}

/// Parses the header; the reader is left on the first pixel byte.
fn parse_header(r: &mut ByteReader<'_>) -> Result<Header> {
    let magic: [u8; 3] = r.array("the PFM magic")?;
    let grey = match &magic[..2] {
        b"PF" => false,
        b"Pf" => true,
        _ => return Err(Error::invalid("not a PFM file (it does not start with PF or Pf)")),
    };
    if !magic[2].is_ascii_whitespace() {
        return Err(Error::invalid("not a PFM file (no whitespace after PF/Pf)"));
    }
    // The whitespace after the magic also starts the first token's leading whitespace.
    r.seek(2);
    let width = parse_size(token(r, "width")?, "width")?;
    let height = parse_size(token(r, "height")?, "height")?;
    let scale_tok = token(r, "scale")?;
    let scale = std::str::from_utf8(scale_tok)
        .ok()
        .and_then(|s| s.parse::<f32>().ok())
        .filter(|s| s.is_finite() && *s != 0.0)
        .ok_or_else(|| {
            Error::invalid(format!("PFM header: scale '{}' is not a finite non-zero number", show(scale_tok)))
        })?;
    // `token` stopped on the single whitespace byte that ends the header.
    r.skip(1, "the PFM header")?;
    Ok(Header { grey, width, height, little_endian: scale < 0.0, scale: scale.abs() })
}

/// The colour of every decoded PFM image: PFM records none, so the samples are whatever the
/// writer had.
fn pfm_color() -> ColorInfo {
    ColorInfo { primaries: ColorPrimaries::Unspecified, ..ColorInfo::default() }
}

/// The pixel bytes the header declares, which must all follow the header (the reader is on
/// the first of them).
fn pixel_bytes<'a>(h: &Header, r: &mut ByteReader<'a>) -> Result<&'a [u8]> {
    let per_pixel = if h.grey { 1 } else { 3 };
    let what = "the PFM pixels";
    let need = r.check_remaining(u64::from(h.width) * u64::from(h.height), per_pixel * 4, what)?;
    r.bytes(need, what)
}

/// What the decoder returns for a file with header `h`.
fn header_info(h: &Header) -> ImageInfo {
    let format = format!(
        "{} f32 {}-endian",
        if h.grey { "grey" } else { "RGB" },
        if h.little_endian { "little" } else { "big" }
    );
    let info = ImageInfo::new(h.width, h.height, Channels::Rgb, pfm_color()).with_format(format);
    if h.scale != 1.0 {
        info.with_metadata("pfm.scale", h.scale.to_string())
    } else {
        info
    }
}

/// Reads the header of a PFM file: size, channels (always RGB: grey is returned as R = G = B),
/// colour (unspecified primaries) and the stored format ("RGB f32 little-endian"). Checks the
/// size against the limits' dimensions and that the file holds every pixel, allocating nothing.
pub fn probe_pfm(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    let mut r = ByteReader::le(data);
    let h = parse_header(&mut r)?;
    limits.check_dimensions(u64::from(h.width), u64::from(h.height))?;
    pixel_bytes(&h, &mut r)?;
    Ok(header_info(&h))
}

/// Decodes a PFM file held in memory.
pub fn decode_pfm(data: &[u8], limits: &Limits) -> Result<HdrImage> {
    hdrcodec_core::decode_image(&PfmCodec, data, &DecodeOptions::new(limits.clone()))
}

/// What the pixel bytes are called in messages.
const PIXELS: &str = "the PFM pixels";

/// Decodes a PFM file into `sink`, one band of rows at a time (PFM stores rows bottom up, so
/// the bands arrive from the bottom of the image). Holds nothing of the image's size when the
/// sink takes rows in place, and at most a 1 MB band otherwise.
pub fn decode_pfm_rows(data: &[u8], limits: &Limits, sink: &mut dyn RowSink) -> Result<()> {
    let info = probe_pfm(data, limits)?;
    let mut r = ByteReader::le(data);
    let h = parse_header(&mut r)?;
    let pixels = pixel_bytes(&h, &mut r)?;
    decode_bands(&h, &info, limits, sink, StoredBytes::memory(pixels, PIXELS))
}

/// [`decode_pfm_rows`] from a file (any source that reads and seeks, from its current
/// position): the header is read, the file's length checked against the pixels it declares,
/// then each band of rows is read where the file stores it, so that the file is never held
/// whole (at most a band of about 1 MB of its bytes, charged to `limits`). Same rows and the
/// same kinds of errors as [`decode_pfm_rows`] on the file's bytes.
pub fn decode_pfm_rows_from(input: &mut dyn ReadSeek, limits: &Limits, sink: &mut dyn RowSink) -> Result<()> {
    let (h, start) = read_header_from(input, limits)?;
    let info = header_info(&h);
    let pixels = StoredBytes::file(input, start, limits, PIXELS);
    decode_bands(&h, &info, limits, sink, pixels)
}

/// [`probe_pfm`] from a file (any source that reads and seeks, from its current position):
/// reads the header alone and checks the file's length against the pixels it declares. Same
/// answer and the same kinds of errors as [`probe_pfm`] on the file's bytes.
pub fn probe_pfm_from(input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
    Ok(header_info(&read_header_from(input, limits)?.0))
}

/// The header of the PFM file at `input`'s position, checked as [`probe_pfm`] checks it, and
/// where in `input` its pixels start.
fn read_header_from(input: &mut dyn ReadSeek, limits: &Limits) -> Result<(Header, u64)> {
    let (at, rest) = hdrcodec_core::remaining_len(input)?;
    // The header with a byte to spare past its longest accepted length (the parser looks at
    // the byte after the last token), or the whole file when it is shorter.
    let mut head = Vec::with_capacity(MAX_HEADER + 2);
    input.take(MAX_HEADER as u64 + 2).read_to_end(&mut head)?;
    let mut r = ByteReader::le(&head);
    let h = parse_header(&mut r)?;
    limits.check_dimensions(u64::from(h.width), u64::from(h.height))?;
    let start = at + r.position();
    let per_pixel = if h.grey { 1u64 } else { 3 };
    let need = (u64::from(h.width) * u64::from(h.height)).saturating_mul(per_pixel * 4);
    if need > rest.saturating_sub(start - at) {
        return Err(Error::truncated(format!(
            "the PFM pixels (bytes {}..{} of a {}-byte input)",
            start - at,
            (start - at).saturating_add(need),
            rest
        )));
    }
    Ok((h, start))
}

/// Delivers the rows of the image the header `h` describes, band by band from the top, each
/// band's bytes fetched from `pixels` (where the file stores them: bottom up).
fn decode_bands(
    h: &Header,
    info: &ImageInfo,
    limits: &Limits,
    sink: &mut dyn RowSink,
    mut pixels: StoredBytes<'_>,
) -> Result<()> {
    let w = h.width as usize;
    let per_pixel = if h.grey { 1 } else { 3 };
    let little_endian = h.little_endian;
    let read = |b: &[u8]| {
        let b = [b[0], b[1], b[2], b[3]];
        if little_endian {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    sink.start(info)?;
    let row_bytes = w * per_pixel * 4;
    let row_len = w * 3;
    let band = band_rows(row_len, 1 << 20);
    let mut scratch = Scratch::new(limits);
    let mut y = 0;
    while y < h.height {
        let rows = band.min(h.height - y);
        // Rows are stored bottom to top: the band's rows are the stored rows from
        // `height - y - rows`, last image row first.
        let first_stored = (h.height - y - rows) as usize;
        let bytes = pixels.band(first_stored * row_bytes, rows as usize * row_bytes)?;
        fill_rows(sink, y, rows, row_len, &mut scratch, |out| {
            for (out_row, row) in out.chunks_exact_mut(row_len).zip(bytes.chunks_exact(row_bytes).rev()) {
                if h.grey {
                    for (px, b) in out_row.chunks_exact_mut(3).zip(row.chunks_exact(4)) {
                        px.fill(read(b));
                    }
                } else {
                    for (d, b) in out_row.iter_mut().zip(row.chunks_exact(4)) {
                        *d = read(b);
                    }
                }
            }
            Ok(())
        })?;
        y += rows;
    }
    Ok(())
}

/// Encodes `image` as a little-endian `PF` file (alpha, if any, is dropped).
pub fn encode_pfm(image: &HdrImage) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(image.pixel_count() * 12 + 32);
    write_pfm(image, &mut out)?;
    Ok(out)
}

/// [`encode_pfm`] streamed into `out` one row at a time: nothing of the image's size is held
/// besides the image (one row of bytes).
pub fn write_pfm(image: &HdrImage, out: &mut dyn std::io::Write) -> Result<()> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("cannot write an empty {w}x{h} image")));
    }
    out.write_all(header(w, h).as_bytes())?;
    let n = image.channels().count();
    let mut bytes = Vec::with_capacity(w * 12);
    for y in (0..h).rev() {
        bytes.clear();
        push_row(image.row(y as u32), n, &mut bytes);
        out.write_all(&bytes)?;
    }
    Ok(())
}

/// The header of a little-endian RGB file.
fn header(w: usize, h: usize) -> String {
    format!("PF\n{w} {h}\n-1\n")
}

/// Appends one row (`n` samples per pixel, alpha dropped) as the file stores it: RGB,
/// little-endian `f32`.
fn push_row(row: &[f32], n: usize, out: &mut Vec<u8>) {
    for px in row.chunks_exact(n) {
        for v in &px[..3] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// The rows of an image written as they come, top to bottom, into a file that stores them
/// bottom up: each band is reversed in a buffer of its size and written where it belongs (the
/// header's length and the row size give every row's place).
struct PfmRowEncoder {
    header: hdrcodec_core::PendingHeader,
    width: usize,
    channels: usize,
    rows: hdrcodec_core::RowCounter,
    height: u32,
    header_len: u64,
    bytes: Vec<u8>,
}

impl PfmRowEncoder {
    /// Where row `y` of the file (counted from the bottom) starts in `out`.
    fn file_row(&self, start: u64, y: u32) -> u64 {
        start + self.header_len + u64::from(y) * self.width as u64 * 12
    }
}

impl hdrcodec_core::RowEncoder for PfmRowEncoder {
    fn write_rows(&mut self, samples: &[f32], out: &mut dyn hdrcodec_core::WriteSeek) -> Result<()> {
        let start = self.header.write(out)?;
        let (y, rows) = self.rows.take(samples)?;
        if rows == 0 {
            return Ok(());
        }
        self.bytes.clear();
        for row in samples.chunks_exact(self.width * self.channels).rev() {
            push_row(row, self.channels, &mut self.bytes);
        }
        // The band's last row is the first of the rows it fills in the file.
        out.seek(std::io::SeekFrom::Start(self.file_row(start, self.height - y - rows)))?;
        out.write_all(&self.bytes)?;
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &mut dyn hdrcodec_core::WriteSeek) -> Result<hdrcodec_core::EncodeReport> {
        let start = self.header.write(out)?;
        self.rows.check_complete()?;
        // Leave the writer at the end of the file, as a writer that wrote it in order would.
        out.seek(std::io::SeekFrom::Start(self.file_row(start, self.height)))?;
        Ok(hdrcodec_core::EncodeReport::new())
    }
}

impl ImageCodec for PfmCodec {
    fn name(&self) -> &'static str {
        "pfm"
    }
    fn id(&self) -> [u8; 4] {
        *b"PFM "
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["pfm"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.len() >= 3 && (head.starts_with(b"PF") || head.starts_with(b"Pf")) && head[2].is_ascii_whitespace()
    }
    /// PFM records no colour at all: samples are stored as they are.
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::None
    }
    /// The header only (see [`probe_pfm`]).
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        probe_pfm(data, limits)
    }
    /// The header only, read from the file (see [`probe_pfm_from`]).
    fn probe_from(&self, input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        probe_pfm_from(input, limits)
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        decode_pfm_rows(data, &options.limits, sink)
    }
    /// Reads the file a band of rows at a time (see [`decode_pfm_rows_from`]).
    fn decode_rows_from(
        &self,
        input: &mut dyn ReadSeek,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        decode_pfm_rows_from(input, &options.limits, sink)
    }
    /// PFM has no options; any `key=value` is an error.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        settings.check_options("pfm", &[])?;
        write_pfm(image, out)?;
        Ok(hdrcodec_core::EncodeReport::new())
    }
    /// Rows are placed from the end of the file back, by seeking (the file stores them bottom
    /// up).
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        settings.check_options("pfm", &[])?;
        let (w, h) = (info.width as usize, info.height as usize);
        if w == 0 || h == 0 {
            return Err(Error::invalid(format!("cannot write an empty {w}x{h} image")));
        }
        let head = header(w, h);
        let channels = info.channels.count();
        Ok(Some(Box::new(PfmRowEncoder {
            header_len: head.len() as u64,
            header: hdrcodec_core::PendingHeader::new(head.into_bytes()),
            width: w,
            channels,
            rows: hdrcodec_core::RowCounter::new(w * channels, info.height),
            height: info.height,
            bytes: Vec::new(),
        })))
    }
}

#[cfg(test)]
mod tests;
