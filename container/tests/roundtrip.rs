//! Round trips through the `.hdrc` container, the random-access index and the format rules.

mod common;

use common::pattern;
use hdrcodec_container::{
    crc32c, decode_frames, decode_image, encode_frames, encode_image, HdrcCodec, Head, RawF16Codec, RawF32Codec,
    Reader, Writer, SIGNATURE,
};
use hdrcodec_core::{
    Channels, Chromaticities, ColorInfo, ColorPrimaries, ContentLightLevel, EncodeSettings, Error, Hdr10Metadata,
    HdrImage, ImageCodec, Limits, MasteringDisplay,
};

fn raw(id: [u8; 4]) -> Option<&'static dyn ImageCodec> {
    match &id {
        b"RF32" => Some(&RawF32Codec),
        b"RF16" => Some(&RawF16Codec),
        _ => None,
    }
}

fn bits(img: &HdrImage) -> Vec<u32> {
    img.samples().iter().map(|v| v.to_bits()).collect()
}

#[test]
fn raw_f32_round_trips_are_bit_exact() {
    for ch in [Channels::Rgb, Channels::Rgba] {
        for (w, h, tile) in [(1, 1, None), (3, 5, None), (3, 5, Some(2)), (257, 129, Some(64)), (257, 129, None)] {
            let img = pattern(w, h, ch, w * 31 + h);
            let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), tile).unwrap();
            let back = decode_image(&file, &Limits::default().into(), &raw).unwrap();
            assert_eq!((back.width(), back.height(), back.channels()), (w, h, ch));
            assert_eq!(bits(&back), bits(&img), "{w}x{h} {ch:?} tile {tile:?}");
            let r = Reader::new(&file, &Limits::default()).unwrap();
            let expect_tiles = tile.map_or(1, |t| w.div_ceil(t) * h.div_ceil(t)) as usize;
            assert_eq!(r.data_chunks().len(), expect_tiles);
        }
    }
}

/// An untiled file decodes straight into the image: the budget's peak is the image, not also
/// a tile image of its size (and a copy of it) as before.
#[test]
fn an_untiled_file_decodes_into_the_image_alone() {
    let img = pattern(257, 129, Channels::Rgba, 3);
    for codec in [&RawF16Codec as &dyn ImageCodec, &RawF32Codec] {
        let file = encode_image(&img, codec, &EncodeSettings::default(), None).unwrap();
        let limits = Limits::default();
        let back = decode_image(&file, &limits.clone().into(), &raw).unwrap();
        assert_eq!((back.width(), back.height()), (257, 129));
        let image_bytes = 257 * 129 * 16;
        assert!(limits.peak() <= image_bytes, "{}: peak {} of {image_bytes}", codec.name(), limits.peak());
    }
}

#[test]
fn raw_f16_round_trip_equals_ieee_half_rounding() {
    // The reference is the `half` crate's IEEE 754 binary16 round-to-nearest-even conversion.
    let img = pattern(257, 129, Channels::Rgba, 7);
    let file = encode_image(&img, &RawF16Codec, &EncodeSettings::default(), Some(64)).unwrap();
    let back = decode_image(&file, &Limits::default().into(), &raw).unwrap();
    let expect: Vec<u32> = img.samples().iter().map(|&v| half::f16::from_f32(v).to_f32().to_bits()).collect();
    assert_eq!(bits(&back), expect);
    // About half the size of raw f32 (two bytes per sample plus headers).
    let f32_file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), Some(64)).unwrap();
    assert!(file.len() * 2 < f32_file.len() + 2000, "{} vs {}", file.len(), f32_file.len());
}

fn rich_color() -> ColorInfo {
    ColorInfo {
        primaries: ColorPrimaries::Custom(Chromaticities {
            red: [0.7, 0.3],
            green: [0.2, 0.75],
            blue: [0.14, 0.05],
            white: [0.3127, 0.329],
        }),
        nits_per_unit: 203.0,
        hdr10: Some(Hdr10Metadata {
            mastering_display: Some(MasteringDisplay {
                primaries: [[0.708, 0.292], [0.170, 0.797], [0.131, 0.046]],
                white: [0.3127, 0.3290],
                max_luminance: 1000.0,
                min_luminance: 0.0001,
            }),
            content_light_level: Some(ContentLightLevel { max_cll: 1000, max_fall: 400 }),
        }),
    }
}

#[test]
fn colour_hdr10_and_metadata_are_preserved() {
    let mut img = pattern(3, 5, Channels::Rgb, 1);
    img.color = rich_color();
    img.set_metadata("software", "hdrcodec ✓");
    img.set_metadata("exposure", "");
    let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), None).unwrap();
    let back = decode_image(&file, &Limits::default().into(), &raw).unwrap();
    assert_eq!(back, img);

    for primaries in [ColorPrimaries::Bt2020, ColorPrimaries::AcesAp0, ColorPrimaries::Xyz, ColorPrimaries::Bt709] {
        let mut img = pattern(1, 1, Channels::Rgba, 2);
        img.color = ColorInfo { primaries, nits_per_unit: 1.0, hdr10: None };
        img.color.hdr10 = Some(Hdr10Metadata {
            mastering_display: None,
            content_light_level: Some(ContentLightLevel { max_cll: 7, max_fall: 3 }),
        });
        let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), None).unwrap();
        let r = Reader::new(&file, &Limits::default()).unwrap();
        assert_eq!(r.color().unwrap().primaries, primaries);
        assert_eq!(r.hdr10(), img.color.hdr10.as_ref());
        assert_eq!(decode_image(&file, &Limits::default().into(), &raw).unwrap(), img);
    }
}

#[test]
fn frames_round_trip_and_random_access_uses_the_index() {
    let frames: Vec<HdrImage> = (0..4).map(|i| pattern(70, 33, Channels::Rgb, i)).collect();
    let file = encode_frames(
        &frames,
        &RawF32Codec,
        &EncodeSettings::default().with_pool(hdrcodec_core::ThreadPool::new(2).unwrap()),
        Some(32),
    )
    .unwrap();
    let back = decode_frames(&file, &Limits::default().into(), &raw).unwrap();
    assert_eq!(back, frames);
    let err = decode_image(&file, &Limits::default().into(), &raw).unwrap_err().to_string();
    assert!(err.contains("4 frames"), "{err}");

    let r = Reader::new(&file, &Limits::default()).unwrap();
    let h = r.head();
    assert_eq!((h.frames, h.tile_columns(), h.tile_rows()), (4, 3, 2));
    assert!(r.has_index());
    // Frame 2, tile column 2 row 1: the 6x1 pixel corner at (64, 32).
    let d = r.tile(2, 2, 1).unwrap();
    assert_eq!((d.header.frame, d.header.x, d.header.y, d.header.width, d.header.height), (2, 64, 32, 6, 1));
    let tile = RawF32Codec.decode(d.payload, &Limits::default()).unwrap();
    assert_eq!(tile.row(0), &frames[2].row(32)[64 * 3..70 * 3]);
    // Each DATA chunk's offset points at its chunk in the file.
    for d in r.data_chunks() {
        let o = d.offset as usize;
        assert_eq!(&file[o + 4..o + 8], b"DATA");
    }
    assert!(r.tile(4, 0, 0).is_none() && r.tile(0, 3, 0).is_none());
    assert_eq!(r.frame_tiles(3).count(), 6);
}

#[test]
fn hdrc_codec_options() {
    let codec = HdrcCodec::default();
    assert_eq!((codec.name(), codec.id(), codec.extensions()), ("hdrc", *b"HDRC", &["hdrc"][..]));
    let img = pattern(257, 129, Channels::Rgba, 3);
    let f16 = EncodeSettings::default().with_option("payload", "raw-f16").with_option("tile", "64");
    let file = codec.encode(&img, &f16).unwrap();
    assert!(codec.sniff(&file) && !codec.sniff(b"#?RADIANCE\n"));
    let r = Reader::new(&file, &Limits::default()).unwrap();
    assert_eq!((r.head().codec, r.head().tile_width, r.data_chunks().len()), (*b"RF16", 64, 15));
    let default = codec.encode(&img, &EncodeSettings::default()).unwrap();
    assert_eq!(codec.decode(&default, &Limits::default()).unwrap(), img, "default payload is lossless raw-f32");

    for (k, v, msg) in [
        ("bogus", "1", "unknown option 'bogus'"),
        ("payload", "nope", "unknown codec"),
        ("tile", "x", "cannot parse"),
        ("payload.level", "3", "unknown option 'level' for codec raw-f32"),
    ] {
        let e = codec.encode(&img, &EncodeSettings::default().with_option(k, v)).unwrap_err().to_string();
        assert!(e.contains(msg), "{k}={v}: {e}");
    }
}

/// Recomputes the CRC of the chunk at `at` after a deliberate edit.
fn fix_crc(file: &mut [u8], at: usize) {
    let len = u32::from_be_bytes(file[at..at + 4].try_into().unwrap()) as usize;
    let crc = crc32c(&file[at + 4..at + 8 + len]);
    file[at + 8 + len..at + 12 + len].copy_from_slice(&crc.to_be_bytes());
}

fn with_private(first_letter: u8) -> Vec<u8> {
    let head = Head::new(*b"RF32", 1, 1, Channels::Rgb);
    let mut w = Writer::new(Vec::new(), &head).unwrap();
    w.write_private(*b"zzzz", b"private data").unwrap();
    let img = pattern(1, 1, Channels::Rgb, 9);
    w.write_data(&head.tile(0, 0, 0), &RawF32Codec.encode(&img, &EncodeSettings::default()).unwrap()).unwrap();
    let mut file = w.finish().unwrap();
    // The private chunk follows the signature (8) and HEAD (12 + 26).
    let at = 8 + 12 + 26;
    assert_eq!(&file[at + 4..at + 8], b"zzzz");
    file[at + 4] = first_letter;
    fix_crc(&mut file, at);
    file
}

#[test]
fn unknown_ancillary_chunks_are_skipped_and_unknown_critical_ones_rejected() {
    let ok = with_private(b'z');
    assert_eq!(decode_image(&ok, &Limits::default().into(), &raw).unwrap(), pattern(1, 1, Channels::Rgb, 9));
    let bad = with_private(b'Z');
    let e = Reader::new(&bad, &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::Unsupported { .. }), "{e}");
    assert!(e.to_string().contains("Zzzz chunk #0 at offset 46: unknown critical chunk"), "{e}");
    let mut w = Writer::new(Vec::new(), &Head::new(*b"RF32", 1, 1, Channels::Rgb)).unwrap();
    assert!(w.write_private(*b"ABCD", b"").is_err(), "critical private chunks cannot be written");
}

#[test]
fn errors_name_the_chunk() {
    let img = pattern(8, 8, Channels::Rgb, 5);
    let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), Some(4)).unwrap();
    let r = Reader::new(&file, &Limits::default()).unwrap();
    let third = r.data_chunks()[3].offset as usize;
    let mut bad = file.clone();
    bad[third + 40] ^= 4;
    let e = Reader::new(&bad, &Limits::default()).unwrap_err().to_string();
    assert_eq!(e, format!("invalid input: DATA chunk #3 at offset {third}: CRC mismatch"));
    let e = Reader::new(&file[..third + 30], &Limits::default()).unwrap_err().to_string();
    assert!(e.starts_with(&format!("truncated input: the data ends inside DATA chunk #3 at offset {third}")), "{e}");

    // A text-mode transfer that turned CR LF into LF.
    let mut text = file.clone();
    text.remove(5);
    assert!(Reader::new(&text, &Limits::default()).unwrap_err().to_string().contains("line endings"));
    let mut seven = file.clone();
    seven[0] &= 0x7F;
    assert!(Reader::new(&seven, &Limits::default()).unwrap_err().to_string().contains("high bit"));
    assert!(Reader::new(b"#?RADIANCE\n", &Limits::default()).unwrap_err().to_string().contains("not an .hdrc"));
    assert_eq!(&file[..8], &SIGNATURE);

    let mut trailing = file.clone();
    trailing.push(0);
    assert!(Reader::new(&trailing, &Limits::default()).unwrap_err().to_string().contains("follow the END chunk"));
}

#[test]
fn the_index_and_the_tile_grid_are_checked() {
    let img = pattern(8, 8, Channels::Rgb, 6);
    let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), Some(4)).unwrap();
    let r = Reader::new(&file, &Limits::default()).unwrap();
    let offsets: Vec<usize> = r.data_chunks().iter().map(|d| d.offset as usize).collect();
    let indx = file.windows(4).rposition(|w| w == b"INDX").unwrap() - 4;

    // An INDX entry pointing elsewhere, with a valid CRC.
    let mut bad = file.clone();
    bad[indx + 8 + 4 + 7] ^= 1;
    fix_crc(&mut bad, indx);
    let e = Reader::new(&bad, &Limits::default()).unwrap_err().to_string();
    assert!(e.contains("INDX chunk #0") && e.contains("entry 0"), "{e}");

    // A DATA rectangle moved off the grid (x = 1), and one moved onto another tile (duplicate).
    for (x, msg) in [(1u32, "not a tile"), (4, "appears twice")] {
        let mut bad = file.clone();
        let at = offsets[2]; // the tile at (0, 4)
        bad[at + 8 + 4..at + 8 + 8].copy_from_slice(&x.to_be_bytes());
        fix_crc(&mut bad, at);
        let e = Reader::new(&bad, &Limits::default()).unwrap_err().to_string();
        assert!(e.contains(msg), "{e}");
    }

    // A missing tile: the writer refuses to finish, the reader names the gap.
    let head = Head::new(*b"RF32", 8, 8, Channels::Rgb).with_tiles(4, 4);
    let mut w = Writer::new(Vec::new(), &head).unwrap();
    w.write_data(&head.tile(0, 0, 0), b"x").unwrap();
    assert!(w.write_data(&head.tile(0, 0, 0), b"x").is_err(), "duplicate tile");
    assert!(w.finish().is_err());
    let mut short = file[..offsets[1]].to_vec();
    short.extend_from_slice(&file[offsets[2]..indx]);
    // END without an index.
    let mut end = vec![0, 0, 0, 0];
    end.extend_from_slice(b"END ");
    end.extend_from_slice(&crc32c(b"END ").to_be_bytes());
    short.extend_from_slice(&end);
    let e = Reader::new(&short, &Limits::default()).unwrap_err().to_string();
    assert!(e.contains("tile (4, 0) of frame 0 is missing"), "{e}");
}

#[test]
fn absurd_dimensions_hit_the_limits() {
    let head = Head::new(*b"RF32", 1_000_000, 1_000_000, Channels::Rgb);
    let mut file = Vec::new();
    // Only the signature and HEAD: the reader must stop there.
    drop(Writer::new(&mut file, &head).unwrap());
    let e = Reader::new(&file, &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
    assert!(e.to_string().contains("HEAD chunk #0 at offset 8"), "{e}");
}

#[test]
fn the_largest_declared_sizes_fail_cleanly_even_without_limits() {
    // 2^32-1 x 2^32-1 pixels in 1x1 tiles: the byte count and the tile count overflow u64
    // arithmetic unless checked; with no limits at all the reader must still refuse it.
    let m = u32::MAX;
    for (tile, frames) in [(1, 1), (m, m), (1, m)] {
        let head = Head::new(*b"RF32", m, m, Channels::Rgba).with_tiles(tile, tile).with_frames(frames);
        let mut file = Vec::new();
        match Writer::new(&mut file, &head) {
            Ok(w) => drop(w),
            Err(e) => {
                assert!(e.to_string().contains("too many"), "{e}");
                continue;
            }
        }
        let e = Reader::new(&file, &Limits::none()).unwrap_err().to_string();
        assert!(e.contains("HEAD chunk #0"), "{e}");
        assert!(decode_image(&file, &Limits::none().into(), &raw).is_err());
    }
    // A raw payload that declares the same, decoded without limits: refused before allocating.
    let mut payload = b"RF32".to_vec();
    payload.extend_from_slice(&m.to_le_bytes());
    payload.extend_from_slice(&m.to_le_bytes());
    payload.push(4);
    assert!(matches!(RawF32Codec.decode(&payload, &Limits::none()), Err(Error::Truncated { .. })));
}

#[test]
fn probe_reads_head_colr_and_hdrm_only() {
    // COLR and HDRM after the tiles, which the format allows: the probe walks every chunk header.
    let head = Head::new(*b"RF32", 70, 33, Channels::Rgba).with_tiles(32, 32).with_frames(2);
    let mut w = Writer::new(Vec::new(), &head).unwrap();
    for f in 0..2 {
        for t in head.frame_tiles(f) {
            let tile = pattern(t.width, t.height, Channels::Rgba, f);
            w.write_data(&t, &RawF32Codec.encode(&tile, &EncodeSettings::default()).unwrap()).unwrap();
        }
    }
    let color = rich_color();
    w.write_color(&color).unwrap();
    w.write_hdr10(color.hdr10.as_ref().unwrap()).unwrap();
    let file = w.finish().unwrap();
    let info = hdrcodec_container::probe(&file, &Limits::default()).unwrap();
    assert_eq!(info.head, head);
    assert_eq!(info.color, color);
    assert_eq!(info.color, Reader::new(&file, &Limits::default()).unwrap().color_info());
    let codec = HdrcCodec::default();
    let i = codec.probe(&file, &Limits::default()).unwrap();
    assert_eq!((i.width, i.height, i.channels, i.frames), (70, 33, Channels::Rgba, 2));
    assert_eq!(i.format, "raw-f32 payload, 6 tiles of 32x32");
    // Nothing of the image's size is needed.
    let tiny = Limits::default().with_max_alloc_bytes(1 << 10);
    assert!(hdrcodec_container::probe(&file, &tiny).is_ok());
    // Nor to index the tiles; decoding the frames is what needs room for them.
    assert!(Reader::new(&file, &tiny).is_ok());
    let resolve = |_| Some(&RawF32Codec as &dyn ImageCodec);
    assert!(hdrcodec_container::decode_frames(&file, &tiny.clone().into(), &resolve).is_err());
    // A truncated file always lacks its END chunk: an error, never a panic.
    for n in 0..file.len() {
        assert!(hdrcodec_container::probe(&file[..n], &Limits::default()).is_err(), "{n}");
    }
    // A damaged tile is not the probe's business; a damaged COLR is.
    let mut bad_tile = file.clone();
    bad_tile[8 + 12 + 26 + 40] ^= 1;
    assert!(Reader::new(&bad_tile, &Limits::default()).is_err());
    assert_eq!(hdrcodec_container::probe(&bad_tile, &Limits::default()).unwrap().head, head);
    let colr = file.windows(4).position(|w| w == b"COLR").unwrap();
    let mut bad_colr = file.clone();
    bad_colr[colr + 5] ^= 1;
    let e = hdrcodec_container::probe(&bad_colr, &Limits::default()).unwrap_err().to_string();
    assert!(e.contains("COLR chunk #0") && e.contains("CRC mismatch"), "{e}");
    // An unknown payload codec fails as decoding does.
    let e = HdrcCodec::default().probe(&with_codec(with_private(b'z'), *b"QQQQ"), &Limits::default());
    assert!(matches!(e, Err(Error::Unsupported { .. })), "{e:?}");
    // The raw payloads' own probe: their 13-byte header.
    let tile = RawF16Codec.encode(&pattern(5, 3, Channels::Rgb, 1), &EncodeSettings::default()).unwrap();
    let i = RawF16Codec.probe(&tile, &Limits::default()).unwrap();
    assert_eq!((i.width, i.height, i.channels, i.format.as_str()), (5, 3, Channels::Rgb, "raw binary16 little-endian"));
    assert!(RawF16Codec.probe(&tile[..tile.len() - 1], &Limits::default()).is_err());
}

/// The same file with another payload codec id in HEAD (its CRC fixed).
fn with_codec(mut file: Vec<u8>, id: [u8; 4]) -> Vec<u8> {
    file[8 + 8 + 2..8 + 8 + 6].copy_from_slice(&id);
    fix_crc(&mut file, 8);
    file
}
