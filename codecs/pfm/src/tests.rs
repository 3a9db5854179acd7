//! The byte layouts below are written out by hand from the format's definition (Paul
//! Debevec's PFM page, as used by HDRShop and pfstools): "PF"/"Pf", width height, scale whose
//! sign gives the byte order, then rows of 32-bit floats from the bottom row up.

use super::*;

fn file(magic: &str, w: u32, h: u32, scale: &str, floats: &[f32], big_endian: bool) -> Vec<u8> {
    let mut v = format!("{magic}\n{w} {h}\n{scale}\n").into_bytes();
    for f in floats {
        v.extend_from_slice(&if big_endian { f.to_be_bytes() } else { f.to_le_bytes() });
    }
    v
}

#[test]
fn grey_big_endian_bottom_up() {
    // Stored rows: bottom (1, 2), then top (3, 4).
    let data = file("Pf", 2, 2, "1.0", &[1.0, 2.0, 3.0, 4.0], true);
    let img = PfmCodec.decode(&data, &Limits::default()).unwrap();
    assert_eq!((img.width(), img.height(), img.channels()), (2, 2, Channels::Rgb));
    assert_eq!(img.pixel(0, 0), &[3.0, 3.0, 3.0]);
    assert_eq!(img.pixel(1, 1), &[2.0, 2.0, 2.0]);
    assert!(img.metadata.is_empty());
}

#[test]
fn colour_little_endian_with_scale() {
    let data = file("PF", 1, 2, "-2.5", &[1.0, 2.0, 3.0, 1e30, -0.5, f32::INFINITY], false);
    let img = PfmCodec.decode(&data, &Limits::default()).unwrap();
    assert_eq!(img.pixel(0, 0), &[1e30, -0.5, f32::INFINITY]);
    assert_eq!(img.pixel(0, 1), &[1.0, 2.0, 3.0]);
    assert_eq!(img.metadata_value("pfm.scale"), Some("2.5"));
}

#[test]
fn writes_little_endian_pf_and_drops_alpha() {
    let img = HdrImage::new(2, 1, Channels::Rgba, vec![1.0, 2.0, 3.0, 0.5, 4.0, 5.0, 6.0, 0.25], ColorInfo::default())
        .unwrap();
    let bytes = PfmCodec.encode(&img, &EncodeSettings::default()).unwrap();
    assert_eq!(bytes, file("PF", 2, 1, "-1", &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], false));
    let back = PfmCodec.decode(&bytes, &Limits::default()).unwrap();
    assert_eq!(back.samples(), img.with_channels(Channels::Rgb).samples());
    // PFM records no primaries: they read back unspecified, whatever the writer had.
    assert_eq!(back.color.primaries, hdrcodec_core::ColorPrimaries::Unspecified);
    assert!(PfmCodec.encode(&img, &EncodeSettings::default().with_option("x", "1")).is_err());
}

#[test]
fn header_is_parsed_strictly() {
    let bad = |d: &[u8]| PfmCodec.decode(d, &Limits::default()).unwrap_err();
    for h in [
        &b"PF\n-1 2\n-1\n"[..],
        b"PF\n0 2\n-1\n",
        b"PF\n1x 2\n-1\n",
        b"PF\n1 2\n0\n",
        b"PF\n1 2\nnan\n",
        b"PF\n1 2\ninf\n",
        b"PF\n99999999999 2\n-1\n",
        b"P6\n1 1\n255\n",
        b"PFX\n1 1\n-1\n",
    ] {
        let e = bad(h);
        assert!(matches!(e, Error::Invalid { .. }), "{:?}: {e}", String::from_utf8_lossy(h));
    }
    let mut long = b"PF\n1 1\n-1".to_vec();
    long.extend(std::iter::repeat_n(b'0', 300));
    long.push(b'\n');
    assert!(matches!(bad(&long), Error::Invalid { .. }));
    // A header cut short names the field it ends in.
    for (h, field) in [(&b"PF\n12"[..], "the width"), (b"PF\n1 2", "the height"), (b"PF\n1 2\n-1", "the scale")] {
        let e = bad(h);
        assert!(matches!(e, Error::Truncated { .. }) && e.to_string().contains(field), "{e}");
    }
    // Whitespace variants that writers produce are accepted.
    let ok = b"PF\r\n1  1\r\n-1.000000\n\x00\x00\x80\x3f\x00\x00\x00\x40\x00\x00\x40\x40";
    assert_eq!(PfmCodec.decode(ok, &Limits::default()).unwrap().samples(), &[1.0, 2.0, 3.0]);
}

#[test]
fn limits_come_before_allocation() {
    let data = b"PF\n100000 100000\n-1\n";
    let e = PfmCodec.decode(data, &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
    let e = PfmCodec.decode(b"PF\n4000 4000\n-1\n", &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::Truncated { .. }), "{e}");
}

#[test]
fn every_truncation_is_an_error_and_flips_never_panic() {
    let img =
        HdrImage::new(3, 2, Channels::Rgb, (0..18).map(|i| i as f32 * 0.5).collect(), ColorInfo::default()).unwrap();
    let bytes = PfmCodec.encode(&img, &EncodeSettings::default()).unwrap();
    for len in 0..bytes.len() {
        assert!(PfmCodec.decode(&bytes[..len], &Limits::fuzzing()).is_err(), "truncated to {len}");
    }
    let mut data = bytes.clone();
    for i in 0..bytes.len() {
        for flip in [0x01u8, 0x20, 0x80, 0xff] {
            data[i] ^= flip;
            let _ = PfmCodec.decode(&data, &Limits::fuzzing());
            data[i] = bytes[i];
        }
    }
}

#[test]
fn codec_identity() {
    assert_eq!((PfmCodec.name(), PfmCodec.id(), PfmCodec.extensions()), ("pfm", *b"PFM ", &["pfm"][..]));
    assert!(PfmCodec.sniff(b"PF\n") && PfmCodec.sniff(b"Pf\n") && !PfmCodec.sniff(b"PFM") && !PfmCodec.sniff(b"P6\n"));
}

#[test]
fn probe_reads_the_header_as_decode_would() {
    for (magic, scale, big) in [("Pf", "1.0", true), ("PF", "-2.5", false)] {
        let n = if magic == "Pf" { 6 } else { 18 };
        let floats: Vec<f32> = (0..n).map(|i| i as f32).collect();
        let data = file(magic, 3, 2, scale, &floats, big);
        let info = PfmCodec.probe(&data, &Limits::default()).unwrap();
        let img = PfmCodec.decode(&data, &Limits::default()).unwrap();
        assert_eq!((info.width, info.height, info.channels, &info.color), (3, 2, img.channels(), &img.color));
        let want = if big { "grey f32 big-endian" } else { "RGB f32 little-endian" };
        assert_eq!(info.format, want);
        // The header alone does not hold the pixels: a short file is reported, not allocated.
        assert!(matches!(PfmCodec.probe(&data[..data.len() - 1], &Limits::default()), Err(Error::Truncated { .. })));
    }
    // Probing allocates nothing of the image's size: the byte limit does not apply.
    let big = file("PF", 300, 300, "-1", &vec![0.0; 300 * 300 * 3], false);
    let tiny = Limits::default().with_max_alloc_bytes(1 << 10);
    assert!(PfmCodec.decode(&big, &tiny).is_err());
    assert_eq!(PfmCodec.probe(&big, &tiny).unwrap().width, 300);
}

#[test]
fn decode_into_a_strided_f16_or_f32_buffer_gives_the_decoded_samples() {
    use hdrcodec_core::sink::FrameBufMut;
    // Tall enough for several 1 MB bands would be slow here; two rows show the bottom-up order.
    let samples: Vec<f32> = (0..3 * 2 * 3).map(|i| i as f32 * 0.5 - 2.0).collect();
    let image = HdrImage::new(3, 2, Channels::Rgb, samples, ColorInfo::default()).unwrap();
    let data = encode_pfm(&image).unwrap();
    let options = DecodeOptions::default();
    let decoded = PfmCodec.decode_with(&data, &options).unwrap();
    let stride = 3 * 3 + 2;
    let mut f32_buf = vec![7.0f32; stride * 2];
    let info = PfmCodec.decode_into(&data, &options, FrameBufMut::f32(&mut f32_buf, stride)).unwrap();
    assert_eq!((info.width, info.height), (3, 2));
    let mut f16_buf = vec![hdrcodec_core::half::f16::from_f32(7.0); stride * 2];
    PfmCodec.decode_into(&data, &options, FrameBufMut::f16(&mut f16_buf, stride)).unwrap();
    for y in 0..2 {
        let row = decoded.row(y as u32);
        assert_eq!(&f32_buf[y * stride..y * stride + 9], row);
        assert_eq!(&f32_buf[y * stride + 9..(y + 1) * stride], &[7.0, 7.0], "padding untouched");
        let halves: Vec<f32> = f16_buf[y * stride..y * stride + 9].iter().map(|h| h.to_f32()).collect();
        assert_eq!(halves, row, "these values are exact in half");
    }
    let mut small = vec![0.0f32; stride * 2 - 3];
    assert!(PfmCodec.decode_into(&data, &options, FrameBufMut::f32(&mut small, stride)).is_err());
}

/// A file of `w`×`h` pixels whose samples all differ, so that a row read from the wrong place
/// shows.
fn numbered(magic: &str, w: u32, h: u32, big_endian: bool) -> Vec<u8> {
    let n = (w * h) as usize * if magic == "Pf" { 1 } else { 3 };
    let floats: Vec<f32> = (0..n).map(|i| i as f32 * 0.25 - 7.0).collect();
    file(magic, w, h, if big_endian { "1" } else { "-1" }, &floats, big_endian)
}

fn from_file(data: &[u8], at: usize, limits: &Limits) -> Result<HdrImage> {
    let mut padded = vec![b'x'; at];
    padded.extend_from_slice(data);
    let mut input = std::io::Cursor::new(padded);
    input.set_position(at as u64);
    PfmCodec.decode_from(&mut input, &DecodeOptions::new(limits.clone()))
}

#[test]
fn decoding_from_a_file_gives_the_in_memory_samples() {
    // 40000 RGB pixels a row: two rows a band, so 5 rows make three bands (the last short).
    for (magic, w, h, big) in [("PF", 40000, 5, false), ("Pf", 40000, 7, true), ("PF", 3, 2, true), ("Pf", 1, 1, false)]
    {
        let data = numbered(magic, w, h, big);
        let want = PfmCodec.decode(&data, &Limits::default()).unwrap();
        for at in [0, 5] {
            let got = from_file(&data, at, &Limits::default()).unwrap();
            assert_eq!((got.width(), got.height()), (w, h));
            assert_eq!(got.samples(), want.samples(), "{magic} {w}x{h} at {at}");
            assert_eq!(got.metadata, want.metadata);
        }
    }
}

#[test]
fn decoding_from_a_file_does_not_hold_the_file() {
    let data = numbered("PF", 40000, 20, false);
    let image_bytes = 40000 * 20 * 12;
    // Room for the image and a band, not for the image and the file (as large as the image).
    let limits = Limits::default().with_max_alloc_bytes(image_bytes + (1 << 20) + (1 << 16)).with_own_budget();
    // What holding the file would need: the file and the image together do not fit.
    let whole_file = hdrcodec_core::read_rest(&mut std::io::Cursor::new(&data), &limits).unwrap();
    assert!(matches!(limits.charge(image_bytes, "the image"), Err(Error::LimitExceeded { .. })));
    drop(whole_file);
    let got = from_file(&data, 0, &limits).unwrap();
    assert_eq!(got.samples(), PfmCodec.decode(&data, &Limits::default()).unwrap().samples());
    assert!(limits.peak() <= image_bytes + (1 << 20), "peak {} for a {image_bytes}-byte image", limits.peak());
    // A band that does not fit is refused, not allocated.
    let tight = Limits::default().with_max_alloc_bytes(image_bytes + 1000).with_own_budget();
    assert!(matches!(from_file(&data, 0, &tight), Err(Error::LimitExceeded { .. })));
}

#[test]
fn a_short_file_is_truncated_when_decoded_from_a_file() {
    let data = numbered("PF", 40000, 5, false);
    let header_len = data.len() - 40000 * 5 * 12;
    for len in [0, 2, 4, header_len - 1, header_len, header_len + 7, data.len() - 1] {
        let err = from_file(&data[..len], 3, &Limits::default()).unwrap_err();
        assert!(matches!(err, Error::Truncated { .. }), "{len}: {err}");
        let mem = PfmCodec.decode(&data[..len], &Limits::default()).unwrap_err();
        assert!(matches!(mem, Error::Truncated { .. }), "{len}: {mem}");
    }
    // Declared sizes the file cannot hold are refused before anything is read or allocated.
    let huge = b"PF\n4000000000 4000000000\n-1\n";
    let err = from_file(huge, 0, &Limits::none()).unwrap_err();
    assert!(matches!(err, Error::Truncated { .. } | Error::LimitExceeded { .. }), "{err}");
}

#[test]
fn a_bad_header_is_the_same_error_from_a_file() {
    for h in [&b"PF\n-1 2\n-1\n"[..], b"P6\n1 1\n255\n", b"PF\n1 2\n-1", &[b' '; 300][..]] {
        let mem = PfmCodec.decode(h, &Limits::default()).unwrap_err().to_string();
        assert_eq!(from_file(h, 0, &Limits::default()).unwrap_err().to_string(), mem);
    }
}
