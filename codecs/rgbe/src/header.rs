//! The Radiance header: the `#?` magic line, `NAME=value` variables, comments and command
//! lines up to an empty line, then the resolution string.
//!
//! Syntax from the Radiance reference manual ("Radiance File Formats", picture file format):
//! the header is a sequence of text lines ended by an empty line; `EXPOSURE` and `COLORCORR`
//! are cumulative (each occurrence multiplies), `PIXASPECT` too.

use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::{Chromaticities, Error, Result};

/// Longest header we accept: real headers are a few hundred bytes, and a bound keeps a file of
/// megabytes without a newline from being scanned as "header" forever.
pub(crate) const MAX_HEADER_BYTES: usize = 1 << 20;

/// The pixel encoding named by `FORMAT=`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// `32-bit_rle_rgbe`: red, green, blue mantissas and a shared exponent.
    Rgbe,
    /// `32-bit_rle_xyze`: CIE X, Y, Z mantissas and a shared exponent.
    Xyze,
}

impl PixelFormat {
    /// The `FORMAT=` value.
    pub fn format_string(self) -> &'static str {
        match self {
            PixelFormat::Rgbe => "32-bit_rle_rgbe",
            PixelFormat::Xyze => "32-bit_rle_xyze",
        }
    }
}

/// One axis of the resolution string: `+X`, `-Y`, ...
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Axis {
    /// True for the Y axis, false for X.
    pub is_y: bool,
    /// True for `+`: the coordinate increases along the file order.
    pub increasing: bool,
    /// Number of positions along the axis.
    pub len: u32,
}

/// What the header and resolution string say.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// The pixel encoding.
    pub format: PixelFormat,
    /// Product of all `EXPOSURE=` values (1 when absent).
    pub exposure: f64,
    /// Product of all `COLORCORR=` triples (1, 1, 1 when absent).
    pub colorcorr: [f64; 3],
    /// Product of all `PIXASPECT=` values (1 when absent).
    pub pixaspect: f64,
    /// `PRIMARIES=` when present and usable; `None` when absent, all zero (the Photoshop
    /// artefact) or degenerate.
    pub primaries: Option<Chromaticities>,
    /// Header lines kept as metadata (key, value), in file order.
    pub metadata: Vec<(String, String)>,
    /// The slow (scanline) axis, first in the resolution string.
    pub major: Axis,
    /// The fast axis, along one scanline.
    pub minor: Axis,
    /// Offset of the first pixel byte.
    pub data_start: usize,
}

impl Header {
    /// Image width (the X extent).
    pub fn width(&self) -> u32 {
        if self.major.is_y {
            self.minor.len
        } else {
            self.major.len
        }
    }
    /// Image height (the Y extent).
    pub fn height(&self) -> u32 {
        if self.major.is_y {
            self.major.len
        } else {
            self.minor.len
        }
    }
}

/// True if `head` starts like a Radiance picture: `#?` then a program name (`RADIANCE`,
/// `RGBE`, ...), as Radiance's own `checkheader` requires.
pub fn sniff(head: &[u8]) -> bool {
    head.starts_with(b"#?") && head.get(2).is_none_or(|&c| c.is_ascii_graphic() || c == b'\n')
}

/// The next header line (without its `\n`), within the [`MAX_HEADER_BYTES`] that the header
/// and the resolution string may take together, line ends included.
fn header_line<'a>(r: &mut ByteReader<'a>, what: &str) -> Result<&'a [u8]> {
    let too_long = || Error::invalid(format!("the Radiance header is longer than {MAX_HEADER_BYTES} bytes"));
    // The bytes the line may take before its `\n`; none, not even an empty line, once the
    // header has used them all (then the data must end there: a truncation).
    let room = match (MAX_HEADER_BYTES as u64).checked_sub(r.position() + 1) {
        Some(room) => room,
        None if r.remaining() > 0 => return Err(too_long()),
        None => 0,
    };
    r.line(room, what).map_err(|e| match e {
        Error::Invalid { .. } => too_long(),
        e => e,
    })
}

fn parse_floats<const N: usize>(value: &str, what: &str) -> Result<[f64; N]> {
    let mut out = [0.0; N];
    let mut it = value.split_ascii_whitespace();
    for slot in &mut out {
        let tok = it.next().ok_or_else(|| Error::invalid(format!("{what}={value}: expected {N} numbers")))?;
        *slot = tok.parse().map_err(|_| Error::invalid(format!("{what}={value}: '{tok}' is not a number")))?;
    }
    Ok(out)
}

/// A positive, finite multiplier, as Radiance requires of EXPOSURE, COLORCORR and PIXASPECT.
fn check_factor(v: f64, what: &str) -> Result<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(Error::invalid(format!("{what}={v} must be a positive number")))
    }
}

/// PRIMARIES as chromaticities, or `None` for all zeros (written by Photoshop when it has no
/// primaries) and for values that cannot define RGB (a white or primary with y <= 0).
fn primaries_from(v: [f64; 8]) -> Option<Chromaticities> {
    if v.iter().any(|x| !x.is_finite()) || v.iter().all(|&x| x == 0.0) {
        return None;
    }
    let ch = Chromaticities { red: [v[0], v[1]], green: [v[2], v[3]], blue: [v[4], v[5]], white: [v[6], v[7]] };
    ch.is_valid().then_some(ch)
}

fn parse_axis(sign: &str, name: &str, len: &str, line: &str) -> Result<Axis> {
    let bad = || Error::invalid(format!("resolution string '{line}' is malformed"));
    let increasing = match sign {
        "+" => true,
        "-" => false,
        _ => return Err(bad()),
    };
    let is_y = match name {
        "X" => false,
        "Y" => true,
        _ => return Err(bad()),
    };
    let len: u32 = len.parse().map_err(|_| bad())?;
    Ok(Axis { is_y, increasing, len })
}

/// Parses the resolution string, e.g. `-Y 512 +X 1024`.
fn parse_resolution(line: &str) -> Result<(Axis, Axis)> {
    let toks: Vec<&str> = line.split_ascii_whitespace().collect();
    if !line.is_ascii() || toks.len() != 4 || toks[0].len() != 2 || toks[2].len() != 2 {
        return Err(Error::invalid(format!("resolution string '{line}' is malformed")));
    }
    let (s0, n0) = toks[0].split_at(1);
    let (s1, n1) = toks[2].split_at(1);
    let major = parse_axis(s0, n0, toks[1], line)?;
    let minor = parse_axis(s1, n1, toks[3], line)?;
    if major.is_y == minor.is_y {
        return Err(Error::invalid(format!("resolution string '{line}' names the same axis twice")));
    }
    Ok((major, minor))
}

/// Parses the header and the resolution string at the start of `data`.
pub fn parse(data: &[u8]) -> Result<Header> {
    if !sniff(data) {
        return Err(if data.len() < 2 && b"#?".starts_with(data) {
            Error::truncated("the Radiance header")
        } else {
            Error::invalid("not a Radiance picture: it does not start with '#?'")
        });
    }
    let mut r = ByteReader::le(data);
    let mut format = None;
    let mut exposure = 1.0;
    let mut colorcorr = [1.0; 3];
    let mut pixaspect = 1.0;
    let mut primaries = None;
    let mut metadata = Vec::new();
    let mut first = true;
    loop {
        let raw = header_line(&mut r, "the Radiance header, before the empty line that must end it")?;
        // Text lines: tolerate a DOS line end, refuse bytes that are not text.
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let line = std::str::from_utf8(raw)
            .map_err(|_| Error::invalid("the Radiance header contains a line that is not text"))?;
        if first {
            // The magic line names the writing program (RADIANCE, RGBE, ...).
            first = false;
            continue;
        }
        if line.trim().is_empty() {
            break;
        }
        if let Some(comment) = line.strip_prefix('#') {
            // A repeated magic line (seen in the wild) is not a comment worth keeping.
            if !comment.starts_with('?') {
                metadata.push(("comment".to_string(), comment.trim().to_string()));
            }
            continue;
        }
        let Some((name, value)) = line.split_once('=').filter(|(n, _)| !n.contains(char::is_whitespace)) else {
            // Command lines of the programs that made the file (e.g. "pfilt -x 1024").
            metadata.push(("history".to_string(), line.trim().to_string()));
            continue;
        };
        let value = value.trim();
        match name {
            "FORMAT" => {
                format = Some(match value {
                    "32-bit_rle_rgbe" => PixelFormat::Rgbe,
                    "32-bit_rle_xyze" => PixelFormat::Xyze,
                    _ => return Err(Error::unsupported(format!("Radiance FORMAT={value}"))),
                })
            }
            "EXPOSURE" => exposure *= check_factor(parse_floats::<1>(value, name)?[0], name)?,
            "COLORCORR" => {
                let c = parse_floats::<3>(value, name)?;
                for (acc, v) in colorcorr.iter_mut().zip(c) {
                    *acc *= check_factor(v, name)?;
                }
            }
            "PIXASPECT" => pixaspect *= check_factor(parse_floats::<1>(value, name)?[0], name)?,
            "PRIMARIES" => {
                primaries = primaries_from(parse_floats::<8>(value, name)?);
                metadata.push(("primaries".to_string(), value.to_string()));
            }
            _ => metadata.push((name.to_ascii_lowercase(), value.to_string())),
        }
    }
    let line = header_line(&mut r, "the Radiance resolution string")?;
    let line = std::str::from_utf8(line).map_err(|_| Error::invalid("the Radiance resolution string is not text"))?;
    let (major, minor) = parse_resolution(line.trim_end_matches('\r'))?;
    if exposure != 1.0 {
        metadata.push(("exposure".to_string(), exposure.to_string()));
    }
    if colorcorr != [1.0; 3] {
        metadata.push(("colorcorr".to_string(), format!("{} {} {}", colorcorr[0], colorcorr[1], colorcorr[2])));
    }
    if pixaspect != 1.0 {
        metadata.push(("pixaspect".to_string(), pixaspect.to_string()));
    }
    Ok(Header {
        // Radiance assumes RGBE when FORMAT is missing, and so do other readers.
        format: format.unwrap_or(PixelFormat::Rgbe),
        exposure,
        colorcorr,
        pixaspect,
        primaries,
        metadata,
        major,
        minor,
        // The position is inside `data`, whose length is a usize.
        data_start: r.position() as usize,
    })
}

/// Replaces line breaks, which would end a header line early.
fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ")
}

/// What the writer puts into a header.
pub struct WriteHeader<'a> {
    /// Pixel encoding.
    pub format: PixelFormat,
    /// PRIMARIES to declare, if not BT.709.
    pub primaries: Option<Chromaticities>,
    /// EXPOSURE to declare (already in the pixel values), if any.
    pub exposure: Option<f64>,
    /// COLORCORR to declare, if any.
    pub colorcorr: Option<[f64; 3]>,
    /// Image metadata: comments, history, SOFTWARE, PIXASPECT, other variables.
    pub metadata: &'a [(String, String)],
    /// Width and height.
    pub width: u32,
    /// Height.
    pub height: u32,
}

/// Keys of [`Header::metadata`] that the writer produces itself (or must not copy).
const DERIVED_KEYS: [&str; 6] = ["primaries", "exposure", "colorcorr", "exposure_in_pixels", "format", "pixaspect"];

/// Writes the header and the resolution string `-Y height +X width`.
pub fn write(h: &WriteHeader<'_>, out: &mut Vec<u8>) {
    let mut s = String::from("#?RADIANCE\n");
    let mut software = false;
    for (k, v) in h.metadata {
        let v = one_line(v);
        match k.as_str() {
            "comment" => s.push_str(&format!("# {v}\n")),
            // A command line is kept only if it will read back as one (not a variable, a
            // comment or the empty line that ends the header).
            "history" => {
                let v = v.trim();
                let variable = v.split_once('=').is_some_and(|(n, _)| !n.contains(char::is_whitespace));
                if !v.is_empty() && !v.starts_with('#') && !variable {
                    s.push_str(&format!("{v}\n"));
                }
            }
            k if DERIVED_KEYS.contains(&k.to_ascii_lowercase().as_str()) => {}
            k if k.is_empty() || !k.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') => {}
            k => {
                software |= k == "software";
                s.push_str(&format!("{}={v}\n", k.to_ascii_uppercase()));
            }
        }
    }
    if let Some(p) = h.metadata.iter().find(|(k, _)| k == "pixaspect") {
        if let Ok(v) = p.1.trim().parse::<f64>() {
            if v.is_finite() && v > 0.0 && v != 1.0 {
                s.push_str(&format!("PIXASPECT={v}\n"));
            }
        }
    }
    if !software {
        s.push_str(concat!("SOFTWARE=hdrcodec-rgbe ", env!("CARGO_PKG_VERSION"), "\n"));
    }
    if let Some(e) = h.exposure {
        s.push_str(&format!("EXPOSURE={e}\n"));
    }
    if let Some(c) = h.colorcorr {
        s.push_str(&format!("COLORCORR={} {} {}\n", c[0], c[1], c[2]));
    }
    if let Some(p) = h.primaries {
        s.push_str(&format!(
            "PRIMARIES={} {} {} {} {} {} {} {}\n",
            p.red[0], p.red[1], p.green[0], p.green[1], p.blue[0], p.blue[1], p.white[0], p.white[1]
        ));
    }
    s.push_str(&format!("FORMAT={}\n\n-Y {} +X {}\n", h.format.format_string(), h.height, h.width));
    out.extend_from_slice(s.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_header_is_bounded_and_a_short_one_is_truncated() {
        let ok = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\r\n\n-Y 2 +X 3\n\x01\x02";
        let h = parse(ok).unwrap();
        assert_eq!((h.width(), h.height(), h.data_start), (3, 2, ok.len() - 2));
        for cut in 0..ok.len() - 2 {
            let e = parse(&ok[..cut]).unwrap_err();
            assert!(matches!(e, Error::Truncated { .. }), "cut at {cut}: {e}");
        }
        let e = parse(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n").unwrap_err();
        assert!(e.to_string().contains("before the empty line"), "{e}");
        let e = parse(b"#?RADIANCE\n\n-Y 2 +X 3").unwrap_err();
        assert!(e.to_string().contains("resolution string"), "{e}");

        // A header of exactly MAX_HEADER_BYTES, line ends included, is read; one byte more is
        // too long, whether in one line or spread over many, and is not scanned further.
        let fill = |len: usize, line: usize| {
            let mut v = b"#?RADIANCE\n".to_vec();
            let tail = b"\n-Y 1 +X 1\n";
            while v.len() + tail.len() < len {
                let n = (len - tail.len() - v.len()).min(line);
                v.push(b'#');
                v.extend(std::iter::repeat_n(b'x', n.saturating_sub(2)));
                v.push(b'\n');
            }
            v.extend_from_slice(tail);
            v.extend_from_slice(&[0; 4]);
            v
        };
        for line in [80, MAX_HEADER_BYTES] {
            let exact = fill(MAX_HEADER_BYTES, line);
            assert_eq!(parse(&exact).unwrap().data_start, MAX_HEADER_BYTES, "lines of {line}");
            let e = parse(&fill(MAX_HEADER_BYTES + 1, line)).unwrap_err();
            assert!(matches!(e, Error::Invalid { .. }) && e.to_string().contains("longer than"), "{e}");
        }
        // Lines that fill the bound exactly, then one more line, however short: too long.
        let mut full = b"#?RADIANCE\n".to_vec();
        while full.len() < MAX_HEADER_BYTES {
            let n = (MAX_HEADER_BYTES - full.len()).min(80);
            full.push(b'#');
            full.extend(std::iter::repeat_n(b'x', n - 2));
            full.push(b'\n');
        }
        assert_eq!((full.len(), full[MAX_HEADER_BYTES - 1]), (MAX_HEADER_BYTES, b'\n'));
        full.extend_from_slice(b"\n-Y 1 +X 1\n\0\0\0\0");
        let e = parse(&full).unwrap_err();
        assert!(e.to_string().contains("longer than"), "{e}");
        let mut endless = b"#?RADIANCE\n".to_vec();
        endless.resize(3 * MAX_HEADER_BYTES, b'x');
        assert!(matches!(parse(&endless), Err(Error::Invalid { .. })));
        // Cut inside the bound: truncated.
        assert!(matches!(parse(&endless[..MAX_HEADER_BYTES - 1]), Err(Error::Truncated { .. })));
    }
}
