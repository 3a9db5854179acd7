//! YUV4MPEG2 (`.y4m`) input, read one frame at a time from any reader.
//!
//! The format (as mjpegtools' `yuv4mpeg.h` defines it, with FFmpeg's high-bit-depth colour
//! spaces): a header line `YUV4MPEG2` followed by space-separated parameters, each a letter
//! and a value (`W` width, `H` height, `F` rate `n:d`, `I` interlacing, `A` aspect, `C` colour
//! space, `X` free-form such as `XCOLORRANGE=FULL`), ended by a line feed; then per frame a
//! line `FRAME` (optionally with parameters) and the planes Y, Cb, Cr, each row by row, one
//! byte per sample at 8 bits and two (little-endian) above.
//!
//! Read here: progressive (`Ip` or unsaid) 4:2:0 and 4:4:4 at 8, 10 and 12 bits: colour spaces
//! `420jpeg` (the default; chroma centred), `420mpeg2` (left), `420paldv` (top-left), `420`
//! (centred), `444`, and `420p10`, `420p12`, `444p10`, `444p12` (FFmpeg's; chroma taken as
//! left, H.273's default). The transfer and primaries are not in the file: the caller says
//! them ([`Y4mReader::frame_to_image`]). Every header and frame line is at most
//! [`MAX_LINE`] bytes, every frame is checked against [`Limits`] before it is allocated, a
//! sample above the bit depth's maximum is an error, and a file that ends inside a frame is
//! [`Error::Truncated`].

use crate::hdr10::{yuv_to_frame_bits, ChromaSiting, Range, Subsampling, Transfer, YuvFrame};
use hdrcodec_core::{Error, HdrImage, Limits, Result};
use std::io::{BufRead, ErrorKind, Read};

/// The longest header or frame line read (parameters included).
pub const MAX_LINE: usize = 4096;

const SIGNATURE: &str = "YUV4MPEG2";

/// What a Y4M stream header says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Y4mHeader {
    /// Luma width.
    pub width: u32,
    /// Luma height.
    pub height: u32,
    /// Bits per sample: 8, 10 or 12.
    pub bit_depth: u32,
    /// 4:2:0 or 4:4:4.
    pub subsampling: Subsampling,
    /// Where 4:2:0 chroma sits.
    pub siting: ChromaSiting,
    /// `XCOLORRANGE=FULL`; limited range otherwise.
    pub full_range: bool,
    /// Frame rate as `(numerator, denominator)`, if given and non-zero.
    pub frame_rate: Option<(u32, u32)>,
}

impl Y4mHeader {
    /// Parses a header line (without its line feed).
    pub fn parse(line: &[u8], limits: &Limits) -> Result<Self> {
        let text = std::str::from_utf8(line).map_err(|_| Error::invalid("a Y4M header that is not ASCII"))?;
        let mut words = text.split(' ').filter(|w| !w.is_empty());
        if words.next() != Some(SIGNATURE) {
            return Err(Error::invalid("not a Y4M file: it does not start with YUV4MPEG2"));
        }
        let (mut width, mut height, mut colour, mut rate, mut full_range) = (None, None, None, None, false);
        for word in words {
            // The tag is one character (maybe not ASCII, in a damaged file).
            let tag_len = word.chars().next().map_or(0, char::len_utf8);
            let (tag, value) = word.split_at(tag_len);
            let number = |what: &str| {
                value.parse::<u32>().map_err(|_| Error::invalid(format!("Y4M {what} '{value}' is not a number")))
            };
            match tag {
                "W" => width = Some(number("width")?),
                "H" => height = Some(number("height")?),
                "C" => colour = Some(value),
                "F" => {
                    let (n, d) = value
                        .split_once(':')
                        .and_then(|(n, d)| Some((n.parse::<u32>().ok()?, d.parse::<u32>().ok()?)))
                        .ok_or_else(|| Error::invalid(format!("Y4M frame rate '{value}' is not n:d")))?;
                    rate = (n > 0 && d > 0).then_some((n, d));
                }
                "I" if !matches!(value, "p" | "?") => {
                    return Err(Error::unsupported(format!(
                        "interlaced Y4M (I{value}): only progressive frames are read"
                    )));
                }
                "X" => match value.split_once('=') {
                    Some(("COLORRANGE", "FULL")) => full_range = true,
                    Some(("COLORRANGE", "LIMITED")) => full_range = false,
                    _ => {}
                },
                // Aspect ratio, and parameters this reader has no use for.
                _ => {}
            }
        }
        let width = width.ok_or_else(|| Error::invalid("a Y4M header without a width (W)"))?;
        let height = height.ok_or_else(|| Error::invalid("a Y4M header without a height (H)"))?;
        limits.check_dimensions(width.into(), height.into())?;
        use ChromaSiting::{Center, Colocated, Left};
        use Subsampling::{Yuv420, Yuv444};
        let (subsampling, bit_depth, siting) = match colour.unwrap_or("420jpeg") {
            "420jpeg" | "420" => (Yuv420, 8, Center),
            "420mpeg2" => (Yuv420, 8, Left),
            "420paldv" => (Yuv420, 8, Colocated),
            "444" => (Yuv444, 8, Colocated),
            "420p10" => (Yuv420, 10, Left),
            "420p12" => (Yuv420, 12, Left),
            "444p10" => (Yuv444, 10, Colocated),
            "444p12" => (Yuv444, 12, Colocated),
            other => {
                return Err(Error::unsupported(format!(
                    "Y4M colour space C{other} (read: 420jpeg, 420mpeg2, 420paldv, 420, 444, 420p10, 420p12, 444p10, 444p12)"
                )))
            }
        };
        Ok(Y4mHeader { width, height, bit_depth, subsampling, siting, full_range, frame_rate: rate })
    }

    /// Bytes of one frame's planes.
    pub fn frame_bytes(&self) -> u64 {
        let (w, h) = (u64::from(self.width), u64::from(self.height));
        let (cw, ch) = match self.subsampling {
            Subsampling::Yuv420 => (w.div_ceil(2), h.div_ceil(2)),
            Subsampling::Yuv444 => (w, h),
        };
        let samples = (w * h).saturating_add((cw * ch).saturating_mul(2));
        samples.saturating_mul(if self.bit_depth > 8 { 2 } else { 1 })
    }
}

/// Reads a Y4M stream frame by frame.
pub struct Y4mReader<R: BufRead> {
    input: R,
    header: Y4mHeader,
    limits: Limits,
    frames: u64,
}

/// Reads a line of at most [`MAX_LINE`] bytes, without its line feed; `None` at a clean end
/// of the input (nothing read).
fn read_line(input: &mut impl BufRead, what: &str) -> Result<Option<Vec<u8>>> {
    let mut line = Vec::new();
    let n = input.by_ref().take(MAX_LINE as u64 + 1).read_until(b'\n', &mut line)?;
    if n == 0 {
        return Ok(None);
    }
    if line.last() != Some(&b'\n') {
        return Err(if line.len() > MAX_LINE {
            Error::invalid(format!("a Y4M {what} longer than {MAX_LINE} bytes"))
        } else {
            Error::truncated(format!("the Y4M {what}"))
        });
    }
    line.pop();
    Ok(Some(line))
}

impl<R: BufRead> Y4mReader<R> {
    /// Reads the stream header; the frame size is checked against `limits`.
    pub fn new(mut input: R, limits: &Limits) -> Result<Self> {
        let line = read_line(&mut input, "header")?.ok_or_else(|| Error::truncated("the Y4M header"))?;
        let header = Y4mHeader::parse(&line, limits)?;
        limits.check_alloc(header.frame_bytes(), "a Y4M frame")?;
        Ok(Y4mReader { input, header, limits: limits.clone(), frames: 0 })
    }

    /// The stream header.
    pub fn header(&self) -> &Y4mHeader {
        &self.header
    }

    /// The next frame's planes as stored, `None` at the end of the input.
    pub fn next_frame(&mut self) -> Result<Option<YuvFrame>> {
        let Some(line) = read_line(&mut self.input, "frame header")? else { return Ok(None) };
        if !(line.starts_with(b"FRAME") && matches!(line.get(5), None | Some(b' '))) {
            return Err(Error::invalid(format!("Y4M frame {}: its header does not start with FRAME", self.frames)));
        }
        let h = self.header;
        // The bytes read, and the planes as 16-bit samples.
        let _charge = self.limits.charge(h.frame_bytes().saturating_mul(3), "a Y4M frame")?;
        let (w, ht) = (h.width as usize, h.height as usize);
        let (cw, ch) = YuvFrame::chroma_size(w, ht, h.subsampling);
        let frame = self.frames;
        let y = self.read_plane(w * ht, frame)?;
        let cb = self.read_plane(cw * ch, frame)?;
        let cr = self.read_plane(cw * ch, frame)?;
        self.frames += 1;
        Ok(Some(YuvFrame { width: w, height: ht, subsampling: h.subsampling, y, cb, cr }))
    }

    fn read_plane(&mut self, samples: usize, frame: u64) -> Result<Vec<u16>> {
        let wide = self.header.bit_depth > 8;
        let mut bytes = vec![0u8; samples * if wide { 2 } else { 1 }];
        self.input.read_exact(&mut bytes).map_err(|e| match e.kind() {
            ErrorKind::UnexpectedEof => Error::truncated(format!("Y4M frame {frame}: the file ends inside it")),
            _ => Error::Io(e),
        })?;
        if !wide {
            return Ok(bytes.into_iter().map(u16::from).collect());
        }
        let max = (1u16 << self.header.bit_depth) - 1;
        let plane: Vec<u16> = bytes.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect();
        if let Some(bad) = plane.iter().find(|&&v| v > max) {
            return Err(Error::invalid(format!(
                "Y4M frame {frame}: sample {bad} above the {}-bit maximum {max}",
                self.header.bit_depth
            )));
        }
        Ok(plane)
    }

    /// Frames read so far.
    pub fn frames_read(&self) -> u64 {
        self.frames
    }

    /// A frame of this stream as scene-linear light in BT.2020 primaries: the planes taken as
    /// BT.2020 non-constant-luminance Y'CbCr on `transfer`, in the header's range and siting,
    /// `nits_per_unit` cd/m² per 1.0.
    pub fn frame_to_image(&self, yuv: &YuvFrame, transfer: Transfer, nits_per_unit: f32) -> Result<HdrImage> {
        let h = &self.header;
        let range = if h.full_range { Range::Full } else { Range::Limited };
        yuv_to_frame_bits(yuv, h.bit_depth, transfer, range, h.siting, nits_per_unit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(header: &str, frames: &[&[u8]]) -> Vec<u8> {
        let mut v = format!("{header}\n").into_bytes();
        for f in frames {
            v.extend_from_slice(b"FRAME\n");
            v.extend_from_slice(f);
        }
        v
    }

    #[test]
    fn header_parameters_are_read() {
        let l = Limits::default();
        let h = Y4mHeader::parse(b"YUV4MPEG2 W64 H32 F25:1 Ip A1:1 C420p10 XYSCSS=420P10", &l).unwrap();
        assert_eq!((h.width, h.height, h.bit_depth, h.subsampling), (64, 32, 10, Subsampling::Yuv420));
        assert_eq!((h.siting, h.full_range, h.frame_rate), (ChromaSiting::Left, false, Some((25, 1))));
        assert_eq!(h.frame_bytes(), 2 * (64 * 32 + 2 * 32 * 16));
        let h = Y4mHeader::parse(b"YUV4MPEG2 W3 H3 XCOLORRANGE=FULL", &l).unwrap();
        assert_eq!((h.bit_depth, h.siting, h.full_range), (8, ChromaSiting::Center, true));
        assert_eq!(h.frame_bytes(), 9 + 2 * 4);
        for (bad, says) in [
            (&b"YUV4MPEG W2 H2"[..], "YUV4MPEG2"),
            (b"YUV4MPEG2 H2", "width"),
            (b"YUV4MPEG2 W2 Hx", "height 'x'"),
            (b"YUV4MPEG2 W2 H2 C422", "C422"),
            (b"YUV4MPEG2 W2 H2 It", "interlaced"),
            (b"YUV4MPEG2 W0 H2", "empty"),
            (b"YUV4MPEG2 W2 H2 F25", "n:d"),
        ] {
            let e = Y4mHeader::parse(bad, &l).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
        assert!(Y4mHeader::parse(b"YUV4MPEG2 W99999 H99999", &Limits::fuzzing()).is_err());
        // A tag that is not ASCII is one character, skipped like any unknown one.
        assert!(Y4mHeader::parse("YUV4MPEG2 W2 H2 éx".as_bytes(), &l).is_ok());
        let huge = Y4mHeader::parse(b"YUV4MPEG2 W4294967295 H4294967295", &Limits::none()).unwrap();
        assert_eq!(huge.frame_bytes(), u64::MAX);
    }

    #[test]
    fn frames_stream_and_truncation_is_an_error() {
        // 2x2 4:2:0 10-bit: 4 luma + 1 + 1 chroma samples, 12 bytes a frame.
        let frame: Vec<u8> = [64u16, 940, 502, 64, 512, 512].iter().flat_map(|v| v.to_le_bytes()).collect();
        let data = file("YUV4MPEG2 W2 H2 C420p10", &[&frame, &frame]);
        let mut r = Y4mReader::new(&data[..], &Limits::default()).unwrap();
        let f = r.next_frame().unwrap().unwrap();
        assert_eq!(
            (f.y.as_slice(), f.cb.as_slice(), f.cr.as_slice()),
            (&[64, 940, 502, 64][..], &[512][..], &[512][..])
        );
        let img = r.frame_to_image(&f, Transfer::Pq, 100.0).unwrap();
        // Code 940 is PQ 1.0 (10 000 cd/m²), 64 is 0; grey (no colour difference).
        assert!((img.samples()[3] - 100.0).abs() < 1e-3 && img.samples()[0] == 0.0, "{:?}", img.samples());
        assert!(r.next_frame().unwrap().is_some());
        assert!(r.next_frame().unwrap().is_none());
        assert_eq!(r.frames_read(), 2);
        // Cut anywhere inside the second frame: truncated, after a whole first frame.
        let first_end = data.len() - frame.len() - 6;
        for cut in first_end + 1..data.len() {
            let mut r = Y4mReader::new(&data[..cut], &Limits::default()).unwrap();
            assert!(r.next_frame().unwrap().is_some());
            let e = r.next_frame().unwrap_err();
            assert!(matches!(e, Error::Truncated { .. }), "cut at {cut}: {e}");
        }
        // A sample above 1023, and a frame line that is not one.
        let mut hot = frame.clone();
        hot[0..2].copy_from_slice(&1024u16.to_le_bytes());
        let data = file("YUV4MPEG2 W2 H2 C420p10", &[&hot]);
        let e = Y4mReader::new(&data[..], &Limits::default()).unwrap().next_frame().unwrap_err().to_string();
        assert!(e.contains("1024 above the 10-bit maximum 1023"), "{e}");
        let mut data = file("YUV4MPEG2 W2 H2 C420p10", &[&frame]);
        data[27] = b'X';
        assert!(Y4mReader::new(&data[..], &Limits::default()).unwrap().next_frame().is_err());
        // An endless header line stops at MAX_LINE.
        let long = vec![b'Y'; MAX_LINE * 2];
        let e = Y4mReader::new(&long[..], &Limits::default()).err().unwrap().to_string();
        assert!(e.contains("longer than"), "{e}");
    }

    #[test]
    fn eight_and_twelve_bit_full_and_limited_range() {
        // 8-bit limited: Y' 235 is E' = 1; 12-bit full: 4095 is E' = 1. Both PQ 10 000 cd/m².
        for (header, frame) in [
            ("YUV4MPEG2 W2 H2 C444", [235u8, 235, 235, 235, 128, 128, 128, 128, 128, 128, 128, 128].to_vec()),
            (
                "YUV4MPEG2 W2 H2 C444p12 XCOLORRANGE=FULL",
                [4095u16, 4095, 4095, 4095, 2048, 2048, 2048, 2048, 2048, 2048, 2048, 2048]
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect(),
            ),
        ] {
            let data = file(header, &[&frame]);
            let mut r = Y4mReader::new(&data[..], &Limits::default()).unwrap();
            let f = r.next_frame().unwrap().unwrap();
            let img = r.frame_to_image(&f, Transfer::Pq, 100.0).unwrap();
            assert!(img.samples().iter().all(|&v| (v - 100.0).abs() < 1e-3), "{header}: {:?}", img.samples());
        }
    }
}
