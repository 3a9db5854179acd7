//! Decoding a `.hdrc` file from a stream (`ImageCodec::decode_from`, `decode_image_rows_from`):
//! the same samples as the decode of the bytes in memory, every damage an error that names the
//! chunk, and the file never charged whole to the limits.

mod common;

use hdrcodec_container::{encode_image, HdrcCodec, RawF16Codec, RawF32Codec};
use hdrcodec_core::{Channels, ColorPrimaries, DecodeOptions, EncodeSettings, Error, HdrImage, ImageCodec, Limits};
use std::io::Cursor;

/// The shared pattern, in BT.2020 at 203 nits per unit, with metadata.
fn pattern(w: u32, h: u32, ch: Channels, seed: u32) -> HdrImage {
    let mut img = common::pattern(w, h, ch, seed);
    img.color.primaries = ColorPrimaries::Bt2020;
    img.color.nits_per_unit = 203.0;
    img.set_metadata("software", "stream test");
    img
}

fn bits(img: &HdrImage) -> Vec<u32> {
    img.samples().iter().map(|v| v.to_bits()).collect()
}

/// The file decoded from a stream that holds `prefix` other bytes before it.
fn from_stream(file: &[u8], prefix: usize, options: &DecodeOptions) -> hdrcodec_core::Result<HdrImage> {
    let mut bytes = vec![0x55; prefix];
    bytes.extend_from_slice(file);
    let mut input = Cursor::new(bytes);
    input.set_position(prefix as u64);
    HdrcCodec::default().decode_from(&mut input, options)
}

#[test]
fn the_stream_decode_gives_the_samples_of_the_in_memory_decode() {
    let codec = HdrcCodec::default();
    for payload in [&RawF32Codec as &dyn ImageCodec, &RawF16Codec] {
        for ch in [Channels::Rgb, Channels::Rgba] {
            for (w, h, tile) in [(1, 1, None), (3, 5, None), (3, 5, Some(2)), (257, 129, Some(64)), (257, 129, None)] {
                let img = pattern(w, h, ch, w * 31 + h);
                let file = encode_image(&img, payload, &EncodeSettings::default(), tile).unwrap();
                let options = DecodeOptions::new(Limits::default());
                let want = codec.decode_with(&file, &options).unwrap();
                for prefix in [0, 7] {
                    let what = format!("{} {w}x{h} {ch:?} tile {tile:?} at {prefix}", payload.name());
                    let got = from_stream(&file, prefix, &options).expect(&what);
                    assert_eq!(bits(&got), bits(&want), "{what}");
                    assert_eq!((got.width(), got.height(), got.channels()), (w, h, ch), "{what}");
                    assert_eq!((&got.color, &got.metadata), (&want.color, &want.metadata), "{what}");
                }
            }
        }
    }
}

/// A three-by-two grid of tiles and an untiled file, raw f16, with COLR and META.
fn files() -> Vec<(&'static str, Vec<u8>)> {
    let img = pattern(5, 3, Channels::Rgba, 9);
    let tiled = encode_image(&img, &RawF16Codec, &EncodeSettings::default(), Some(2)).unwrap();
    let untiled = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), None).unwrap();
    vec![("tiled", tiled), ("untiled", untiled)]
}

#[test]
fn every_truncation_is_an_error() {
    let options = DecodeOptions::new(Limits::fuzzing());
    for (name, file) in files() {
        from_stream(&file, 0, &options).unwrap();
        for n in 0..file.len() {
            let e = from_stream(&file[..n], 3, &options).expect_err(&format!("{name} cut to {n} bytes"));
            let m = e.to_string();
            assert!(m.contains("chunk") || m.contains("signature"), "{name} cut to {n}: {m}");
        }
    }
}

/// The DATA chunks of a file: (start of the payload, end of the CRC).
fn data_chunks(file: &[u8]) -> Vec<(usize, usize)> {
    let mut at = 8;
    let mut out = Vec::new();
    while at < file.len() {
        let len = u32::from_be_bytes(file[at..at + 4].try_into().unwrap()) as usize;
        if &file[at + 4..at + 8] == b"DATA" {
            out.push((at + 8, at + 12 + len));
        }
        at += 12 + len;
    }
    out
}

#[test]
fn every_single_byte_corruption_is_an_error_and_a_damaged_tile_is_a_crc_mismatch() {
    let options = DecodeOptions::new(Limits::fuzzing());
    for (name, file) in files() {
        let data = data_chunks(&file);
        assert_eq!(data.len(), if name == "tiled" { 6 } else { 1 });
        for i in 0..file.len() {
            for x in [0x01, 0x80, 0xFF] {
                let mut bad = file.clone();
                bad[i] ^= x;
                let what = format!("{name}: byte {i} ^ {x:#04x}");
                let m = from_stream(&bad, 0, &options).expect_err(&what).to_string();
                assert!(m.contains("chunk") || m.contains("signature"), "{what}: {m}");
                // A byte of a DATA chunk's payload or CRC: the tile is refused as damaged,
                // whatever its payload would have decoded to.
                if data.iter().any(|&(start, end)| (start..end).contains(&i)) {
                    assert!(m.contains("DATA chunk") && m.contains("CRC mismatch"), "{what}: {m}");
                }
            }
        }
    }
}

#[test]
fn the_file_is_never_charged_whole() {
    // 1024x600 RGBA: a 9.8 MB image from a 4.9 MB raw-f16 payload.
    let img = pattern(1024, 600, Channels::Rgba, 5);
    let image_bytes = (img.samples().len() * 4) as u64;
    for tile in [None, Some(256)] {
        let file = encode_image(&img, &RawF16Codec, &EncodeSettings::default(), tile).unwrap();
        let limits = Limits::default();
        let back = from_stream(&file, 0, &DecodeOptions::new(limits.clone())).unwrap();
        assert_eq!(back.samples().len(), img.samples().len());
        // The image and, untiled, a band of about 1 MB of the file; tiled, a row of four 256x256
        // tiles (0.5 MB of chunks) and their decoded images (1 MB each).
        let slack = if tile.is_none() { 1 << 20 } else { 6 << 20 };
        assert!(limits.peak() <= image_bytes + slack, "tile {tile:?}: peak {} of {image_bytes}", limits.peak());
        assert!(limits.peak() < image_bytes + file.len() as u64, "tile {tile:?}: peak {}", limits.peak());
        // Too small a budget for the image is a limit error, before anything is decoded.
        let small = Limits::new(1 << 14, 1 << 14, 1 << 28, image_bytes / 2);
        let e = from_stream(&file, 0, &DecodeOptions::new(small)).unwrap_err();
        assert!(matches!(e, Error::LimitExceeded { .. }), "tile {tile:?}: {e}");
    }
}

#[test]
fn a_data_chunk_beyond_the_grid_is_refused_before_it_is_kept() {
    // The untiled file with its one DATA chunk twice: what a reader keeps per chunk is bounded
    // by the HEAD's grid.
    let (_, file) = files().remove(1);
    let (start, end) = data_chunks(&file)[0];
    let mut bad = file[..end].to_vec();
    bad.extend_from_slice(&file[start - 8..end]);
    bad.extend_from_slice(&file[end..]);
    let options = DecodeOptions::new(Limits::fuzzing());
    let errors =
        [from_stream(&bad, 0, &options).unwrap_err(), HdrcCodec::default().decode_with(&bad, &options).unwrap_err()];
    for e in errors {
        assert!(
            e.to_string().contains("DATA chunk #1 at offset")
                && e.to_string().contains("more DATA chunks than the 1 tiles"),
            "{e}"
        );
    }
}
