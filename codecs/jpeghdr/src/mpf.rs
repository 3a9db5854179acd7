//! The Multi-Picture Format index (CIPA DC-007) in the primary image's APP2 segment: where the
//! gain-map image sits in the file. Read in both byte orders (Pixel phones write little-endian,
//! everyone else big-endian); written big-endian with the primary marked as the baseline MP
//! primary image, as Skia requires.

use hdrcodec_core::{Error, Result};

/// The APP2 payload signature of an MPF segment.
pub const SIGNATURE: &[u8] = b"MPF\0";

const TAG_VERSION: u16 = 0xB000;
const TAG_NUMBER_OF_IMAGES: u16 = 0xB001;
const TAG_MP_ENTRY: u16 = 0xB002;
/// Attribute type of the primary image: baseline MP primary image (DC-007 5.2.3.3.1).
pub const TYPE_BASELINE_PRIMARY: u32 = 0x03_0000;

/// One MP entry: an image of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MpEntry {
    /// Flags and type (bit 31 dependent parent, 30 dependent child, 29 representative,
    /// 26-24 format, 23-0 type).
    pub attribute: u32,
    /// Size in bytes as the writer recorded it (not always right: see the notes).
    pub size: u32,
    /// Offset of the image's SOI in the file: the recorded offset made absolute (the first
    /// image's recorded 0 becomes the primary's own start).
    pub file_offset: usize,
}

fn invalid(what: &str) -> Error {
    Error::invalid(format!("MPF: {what}"))
}

/// Reads the MP index from an MPF payload (signature removed) that begins at `endian_offset`
/// in the file (offsets in the index are counted from there). `primary_start` is the primary
/// image's SOI offset.
pub fn parse(payload: &[u8], endian_offset: usize, primary_start: usize) -> Result<Vec<MpEntry>> {
    let big = match payload.get(..4) {
        Some([0x4D, 0x4D, 0x00, 0x2A]) => true,
        Some([0x49, 0x49, 0x2A, 0x00]) => false,
        _ => return Err(invalid("no TIFF byte-order header")),
    };
    let u16_at = |o: usize| {
        payload
            .get(o..o + 2)
            .map(|b| if big { u16::from_be_bytes([b[0], b[1]]) } else { u16::from_le_bytes([b[0], b[1]]) })
    };
    let u32_at = |o: usize| {
        payload.get(o..o + 4).map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            if big {
                u32::from_be_bytes(b)
            } else {
                u32::from_le_bytes(b)
            }
        })
    };
    let ifd = u32_at(4).ok_or_else(|| invalid("truncated header"))? as usize;
    let count = u16_at(ifd).ok_or_else(|| invalid("index IFD outside the segment"))? as usize;
    let (mut images, mut entries_at) = (None, None);
    for i in 0..count {
        let e = ifd + 2 + 12 * i;
        let (Some(tag), Some(n), Some(value)) = (u16_at(e), u32_at(e + 4), u32_at(e + 8)) else {
            return Err(invalid("index IFD entry outside the segment"));
        };
        match tag {
            TAG_NUMBER_OF_IMAGES => images = Some(value as usize),
            TAG_MP_ENTRY => entries_at = Some((value as usize, n as usize)),
            _ => {}
        }
    }
    let (images, (at, len)) = images.zip(entries_at).ok_or_else(|| invalid("no NumberOfImages or MPEntry"))?;
    if len != 16 * images || images == 0 {
        return Err(invalid("MPEntry size does not match NumberOfImages"));
    }
    (0..images)
        .map(|i| {
            let e = at + 16 * i;
            let (Some(attribute), Some(size), Some(offset)) = (u32_at(e), u32_at(e + 4), u32_at(e + 8)) else {
                return Err(invalid("MP entry outside the segment"));
            };
            let file_offset = if offset == 0 { primary_start } else { endian_offset + offset as usize };
            Ok(MpEntry { attribute, size, file_offset })
        })
        .collect()
}

/// Length of the APP2 payload [`write()`] produces (signature included): fixed for two images.
pub const PAYLOAD_LEN: usize = 4 + 8 + 2 + 3 * 12 + 4 + 2 * 16;

/// An MPF APP2 payload (signature included) for a primary image of `primary_size` bytes and one
/// more image of `second_size` bytes at `second_offset` bytes after the payload's byte-order
/// field (which is the APP2 marker's offset plus 8).
pub fn write(primary_size: u32, second_size: u32, second_offset: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity(PAYLOAD_LEN);
    out.extend(SIGNATURE);
    out.extend([0x4D, 0x4D, 0x00, 0x2A]);
    out.extend(8u32.to_be_bytes());
    out.extend(3u16.to_be_bytes());
    let entries_at = 8 + 2 + 3 * 12 + 4;
    for (tag, kind, count, value) in [
        (TAG_VERSION, 7u16, 4u32, u32::from_be_bytes(*b"0100")),
        (TAG_NUMBER_OF_IMAGES, 4, 1, 2),
        (TAG_MP_ENTRY, 7, 32, entries_at),
    ] {
        out.extend(tag.to_be_bytes());
        out.extend(kind.to_be_bytes());
        out.extend(count.to_be_bytes());
        out.extend(value.to_be_bytes());
    }
    out.extend(0u32.to_be_bytes()); // no attribute IFD
    for (attribute, size, offset) in [(TYPE_BASELINE_PRIMARY, primary_size, 0), (0, second_size, second_offset)] {
        out.extend(attribute.to_be_bytes());
        out.extend(size.to_be_bytes());
        out.extend(offset.to_be_bytes());
        out.extend([0u8; 4]); // no dependent images
    }
    debug_assert_eq!(out.len(), PAYLOAD_LEN);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_index_reads_back() {
        let payload = write(1000, 200, 5000);
        let entries = parse(&payload[4..], 100, 2).unwrap();
        assert_eq!(
            entries,
            [
                MpEntry { attribute: TYPE_BASELINE_PRIMARY, size: 1000, file_offset: 2 },
                MpEntry { attribute: 0, size: 200, file_offset: 5100 }
            ]
        );
        // (The last 4 bytes, the second entry's dependent images, are not read.)
        for n in 0..payload.len() - 8 {
            assert!(parse(&payload[4..4 + n], 100, 0).is_err(), "{n}");
        }
    }

    #[test]
    fn little_endian_index_reads() {
        let mut p = vec![0x49, 0x49, 0x2A, 0x00, 8, 0, 0, 0, 2, 0];
        for (tag, count, value) in [(TAG_NUMBER_OF_IMAGES, 1u32, 2u32), (TAG_MP_ENTRY, 32, 38)] {
            p.extend(tag.to_le_bytes());
            p.extend(7u16.to_le_bytes());
            p.extend(count.to_le_bytes());
            p.extend(value.to_le_bytes());
        }
        p.extend(0u32.to_le_bytes());
        for (a, s, o) in [(TYPE_BASELINE_PRIMARY, 10u32, 0u32), (0, 20, 300)] {
            p.extend(a.to_le_bytes());
            p.extend(s.to_le_bytes());
            p.extend(o.to_le_bytes());
            p.extend([0; 4]);
        }
        let e = parse(&p, 40, 0).unwrap();
        assert_eq!(e[1], MpEntry { attribute: 0, size: 20, file_offset: 340 });
    }
}
