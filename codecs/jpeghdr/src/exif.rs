//! The EXIF block of a JPEG (APP1 `Exif\0\0`, then a TIFF-structured block: CIPA DC-008,
//! "Exif 2.3", 4.5.4), read with core's IFD reader for what gain-map decoding needs from it:
//! the headroom Apple's cameras record in their maker note.

use crate::markers::{JpegImage, APP1};
use hdrcodec_core::bytes::ByteOrder;
use hdrcodec_core::tiff::{tag, Ifd, Tiff, MAGIC_TIFF};
use hdrcodec_core::Result;

/// The APP1 payload signature of EXIF.
pub const SIGNATURE: &[u8] = b"Exif\0\0";
/// The Exif IFD pointer of IFD 0 (Exif 2.3, 4.6.3).
const EXIF_IFD_POINTER: u16 = 0x8769;
/// MakerNote, in the Exif IFD (Exif 2.3, 4.6.5).
const MAKER_NOTE: u16 = 0x927C;
/// How Apple's maker note begins: the name, a 16-bit version (1) and the byte order "MM"; its
/// IFD follows, and its offsets count from the maker note's first byte.
const APPLE_PREFIX: &[u8] = b"Apple iOS\0\0\x01MM";

/// The image's EXIF block (the TIFF-structured bytes after the signature), if it has one.
pub fn exif_block<'a>(image: &JpegImage<'a>) -> Option<&'a [u8]> {
    image.app_payload(APP1, SIGNATURE).map(|(_, block)| block)
}

/// The metadata key under which a decoded image keeps its EXIF block, in hexadecimal (the
/// encoder writes it back into the base image).
pub const METADATA_KEY: &str = "exif";

/// The most an APP1 segment holds after the signature (65535 − 2 length bytes − 6).
pub const MAX_BLOCK: usize = 65527;

/// The orientation EXIF records for the image (1-8, TIFF 6.0 Orientation), if any.
pub fn orientation(block: &[u8]) -> Option<u32> {
    let tiff = Tiff::parse(block, MAGIC_TIFF).ok()?;
    tiff.first_ifd().ok()?.get(tag::ORIENTATION)?.first_u32(&tiff).ok()
}

/// Lower-case hexadecimal of `bytes`, how binary metadata travels in `HdrImage::metadata`.
pub fn to_hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The bytes of a hexadecimal string; `None` if it is not one.
pub fn from_hex(text: &str) -> Option<Vec<u8>> {
    let digits = text.as_bytes();
    if !digits.len().is_multiple_of(2) {
        return None;
    }
    let nibble = |c: u8| (c as char).to_digit(16);
    digits.chunks_exact(2).map(|p| Some((nibble(p[0])? * 16 + nibble(p[1])?) as u8)).collect()
}

/// The headroom of an Apple HDR photograph, in stops, from its EXIF maker note (tags 33 and
/// 48, signed rationals), as Apple documents it for gain maps whose XMP does not carry
/// `HDRGainMapHeadroom`; `Ok(None)` when the image has no Apple maker note.
pub fn apple_headroom_stops(image: &JpegImage<'_>) -> Result<Option<f64>> {
    exif_block(image).map_or(Ok(None), apple_headroom_stops_in)
}

/// [`apple_headroom_stops`] of an EXIF block (the TIFF-structured bytes after `Exif\0\0`).
pub fn apple_headroom_stops_in(block: &[u8]) -> Result<Option<f64>> {
    let tiff = Tiff::parse(block, MAGIC_TIFF)?;
    let Some(pointer) = tiff.first_ifd()?.get(EXIF_IFD_POINTER).cloned() else { return Ok(None) };
    let exif_ifd = tiff.read_ifd(u64::from(pointer.first_u32(&tiff)?))?;
    let Some(note) = exif_ifd.get(MAKER_NOTE) else { return Ok(None) };
    let note = note.value_bytes(&tiff)?;
    if !note.starts_with(APPLE_PREFIX) {
        return Ok(None);
    }
    let apple = Tiff::without_header(note, ByteOrder::Big);
    let ifd = apple.read_ifd(APPLE_PREFIX.len() as u64)?;
    let value = |ifd: &Ifd, tag| ifd.get(tag).map(|e| e.first_real(&apple)).transpose();
    let (Some(m33), Some(m48)) = (value(&ifd, 33)?, value(&ifd, 48)?) else { return Ok(None) };
    Ok(Some(apple_stops(m33, m48)))
}

/// Apple's piecewise-linear headroom in stops from maker-note values 33 and 48 (never below
/// 0: an SDR photograph).
fn apple_stops(m33: f64, m48: f64) -> f64 {
    let stops = match (m33 < 1.0, m48 <= 0.01) {
        (true, true) => 1.8 - 20.0 * m48,
        (true, false) => 1.601 - 0.101 * m48,
        (false, true) => 3.0 - 70.0 * m48,
        (false, false) => 2.303 - 0.303 * m48,
    };
    stops.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trip() {
        let bytes: Vec<u8> = (0..=255).collect();
        assert_eq!(from_hex(&to_hex(&bytes)).unwrap(), bytes);
        assert_eq!(to_hex(&[0x0f, 0xa0]), "0fa0");
        assert_eq!(from_hex("0FA0").unwrap(), [0x0f, 0xa0]);
        assert!(from_hex("0fa").is_none() && from_hex("zz").is_none());
    }

    #[test]
    fn apple_formula_branches() {
        assert_eq!(apple_stops(0.5, 0.0), 1.8);
        assert!((apple_stops(0.5, 0.005) - 1.7).abs() < 1e-12);
        assert!((apple_stops(0.5, 1.0) - 1.5).abs() < 1e-12);
        assert_eq!(apple_stops(1.5, 0.0), 3.0);
        assert!((apple_stops(1.5, 1.0) - 2.0).abs() < 1e-12);
        assert_eq!(apple_stops(1.5, 100.0), 0.0);
    }
}
