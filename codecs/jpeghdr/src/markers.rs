//! The JPEG marker layer (ITU-T T.81 Annex B): where one JPEG image starts and ends inside a
//! file, and the marker segments it carries (APPn payloads hold every piece of HDR metadata:
//! MPF, XMP, ICC, ISO 21496-1, JPEG-HDR's ratio image).
//!
//! A gain-map file is two JPEG images back to back, so the reader walks the first one to its
//! EOI (through the entropy-coded data of every scan) to know where the second may begin. Only
//! the marker structure is read here; pixels are decoded by `zune-jpeg`.

use hdrcodec_core::{Error, Result};

/// Start of image.
pub const SOI: u8 = 0xD8;
/// End of image.
pub const EOI: u8 = 0xD9;
/// Start of scan.
pub const SOS: u8 = 0xDA;
/// APP1: EXIF and XMP.
pub const APP1: u8 = 0xE1;
/// APP2: ICC profile, MPF, ISO 21496-1.
pub const APP2: u8 = 0xE2;
/// APP11: JPEG-HDR ratio image, JUMBF boxes.
pub const APP11: u8 = 0xEB;

/// One marker segment with a length field: the marker's second byte and its payload (the bytes
/// after the two length bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segment<'a> {
    /// The marker code (the byte after 0xFF), e.g. [`APP2`].
    pub marker: u8,
    /// Offset in the file of the marker's 0xFF byte.
    pub offset: usize,
    /// The payload.
    pub payload: &'a [u8],
}

impl Segment<'_> {
    /// Offset in the file of the payload's first byte.
    pub fn payload_offset(&self) -> usize {
        self.offset + 4
    }
}

/// One JPEG image found in a file: its bytes from SOI to EOI and its marker segments (all of
/// them, including tables between scans; scan data is not listed).
#[derive(Clone, Debug)]
pub struct JpegImage<'a> {
    /// Offset of the SOI marker in the file.
    pub start: usize,
    /// Offset just past the EOI marker.
    pub end: usize,
    /// The segments in file order.
    pub segments: Vec<Segment<'a>>,
}

impl<'a> JpegImage<'a> {
    /// The image's bytes, SOI to EOI, out of the file they were found in.
    pub fn bytes<'f>(&self, file: &'f [u8]) -> &'f [u8] {
        &file[self.start..self.end]
    }

    /// The payloads of the `marker` segments whose payload begins with `signature`, signature
    /// removed, with their file offsets (of the byte after the signature).
    pub fn app_payloads(&self, marker: u8, signature: &'a [u8]) -> impl Iterator<Item = (usize, &'a [u8])> + '_ {
        self.segments
            .iter()
            .filter(move |s| s.marker == marker && s.payload.starts_with(signature))
            .map(move |s| (s.payload_offset() + signature.len(), &s.payload[signature.len()..]))
    }

    /// The first such payload.
    pub fn app_payload(&self, marker: u8, signature: &'a [u8]) -> Option<(usize, &'a [u8])> {
        self.app_payloads(marker, signature).next()
    }
}

fn truncated(what: &str) -> Error {
    Error::truncated(format!("JPEG: {what}"))
}

/// Reads the JPEG image that starts at `start` (which must hold an SOI marker) up to and
/// including its EOI. Fails on a truncated image or a broken marker structure.
pub fn parse_image(data: &[u8], start: usize) -> Result<JpegImage<'_>> {
    if data.get(start..start + 2) != Some(&[0xFF, SOI][..]) {
        return Err(Error::invalid("JPEG: no SOI marker where an image should start"));
    }
    let mut segments = Vec::new();
    let mut pos = start + 2;
    loop {
        // A marker is 0xFF, any number of 0xFF fill bytes, then its code (T.81 B.1.1.2).
        if data.get(pos) != Some(&0xFF) {
            return match data.get(pos) {
                None => Err(truncated("the file ends before the image's EOI")),
                Some(_) => Err(Error::invalid(format!("JPEG: a marker was expected at byte {pos}"))),
            };
        }
        let offset = pos;
        while data.get(pos) == Some(&0xFF) {
            pos += 1;
        }
        let Some(&marker) = data.get(pos) else { return Err(truncated("the file ends inside a marker")) };
        pos += 1;
        match marker {
            EOI => return Ok(JpegImage { start, end: pos, segments }),
            // Markers without a length: TEM and the restart markers (which belong inside scan
            // data, but some writers put one after it).
            0x01 | 0xD0..=0xD7 => continue,
            SOI | 0x00 => {
                return Err(Error::invalid(format!("JPEG: unexpected marker 0xFF{marker:02X} at byte {offset}")))
            }
            _ => {}
        }
        let Some(len) = data.get(pos..pos + 2).map(|b| u16::from_be_bytes([b[0], b[1]]) as usize) else {
            return Err(truncated("the file ends inside a segment's length"));
        };
        if len < 2 {
            return Err(Error::invalid(format!("JPEG: segment 0xFF{marker:02X} at byte {offset} has length {len}")));
        }
        let Some(payload) = data.get(pos + 2..pos + len) else {
            return Err(truncated(&format!("segment 0xFF{marker:02X} at byte {offset} runs past the end of the file")));
        };
        // The segment starts at its last 0xFF (fill bytes before it are not part of it).
        segments.push(Segment { marker, offset: pos - 2, payload });
        pos += len;
        if marker == SOS {
            pos = skip_entropy_coded_data(data, pos)?;
        }
    }
}

/// The offset of the first marker after the entropy-coded data that starts at `pos`: the
/// first 0xFF not followed by a stuffed zero or a restart marker (T.81 B.1.1.5, F.1.2.3).
fn skip_entropy_coded_data(data: &[u8], mut pos: usize) -> Result<usize> {
    loop {
        let Some(found) = data[pos.min(data.len())..].iter().position(|&b| b == 0xFF) else {
            return Err(truncated("the file ends inside a scan's entropy-coded data"));
        };
        pos += found;
        match data.get(pos + 1) {
            None => return Err(truncated("the file ends inside a scan's entropy-coded data")),
            Some(0x00) | Some(0xD0..=0xD7) => pos += 2,
            // Fill bytes before a marker: the marker starts at the last of them.
            Some(0xFF) => pos += 1,
            Some(_) => return Ok(pos),
        }
    }
}

/// Offset of the next SOI marker at or after `from` that starts an image that parses, looking
/// only between images: after `from`, bytes that are not 0xFF 0xD8 are skipped (padding some
/// writers put between the primary image and the next).
pub fn next_image_start(data: &[u8], from: usize) -> Option<usize> {
    let rest = data.get(from..)?;
    rest.windows(2).position(|w| w == [0xFF, SOI]).map(|p| from + p)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A minimal JPEG-shaped byte string: SOI, the given segments, an SOS with `scan` as
    /// entropy-coded data, EOI.
    pub(crate) fn fake_jpeg(segments: &[(u8, &[u8])], scan: &[u8]) -> Vec<u8> {
        let mut out = vec![0xFF, SOI];
        for (marker, payload) in segments {
            out.extend([0xFF, *marker]);
            out.extend(((payload.len() + 2) as u16).to_be_bytes());
            out.extend(*payload);
        }
        out.extend([0xFF, SOS, 0, 3, 0]);
        out.extend(scan);
        out.extend([0xFF, EOI]);
        out
    }

    #[test]
    fn walks_segments_and_scan_data_to_the_eoi() {
        // Scan data with a stuffed 0xFF00, a restart marker and fill bytes before EOI.
        let jpeg = fake_jpeg(&[(APP1, b"Exif\0\0abc"), (APP2, b"MPF\0xyz")], &[1, 0xFF, 0, 2, 0xFF, 0xD3, 4, 0xFF]);
        let mut file = jpeg.clone();
        file.extend([0, 0]);
        file.extend(&jpeg);
        let first = parse_image(&file, 0).unwrap();
        assert_eq!(first.end, jpeg.len());
        assert_eq!(first.segments.len(), 3);
        assert_eq!(first.app_payload(APP2, b"MPF\0").unwrap(), (first.segments[1].offset + 8, &b"xyz"[..]));
        let second = next_image_start(&file, first.end).unwrap();
        assert_eq!(second, jpeg.len() + 2);
        assert_eq!(parse_image(&file, second).unwrap().end, file.len());
    }

    #[test]
    fn every_truncation_is_an_error() {
        let jpeg = fake_jpeg(&[(APP1, b"Exif\0\0abc")], &[1, 2, 0xFF, 0, 3]);
        for n in 0..jpeg.len() {
            assert!(parse_image(&jpeg[..n], 0).is_err(), "{n}");
        }
        assert!(parse_image(&jpeg, 1).is_err());
    }
}
