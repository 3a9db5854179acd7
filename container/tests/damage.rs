//! Every truncation and a sweep of single-byte corruptions of valid `.hdrc` files: each must
//! be an error that names where it failed, never a panic, never an image.

use hdrcodec_container::{decode_frames, encode_frames, RawF16Codec, RawF32Codec, Reader};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, ContentLightLevel, EncodeSettings, Hdr10Metadata, HdrImage, ImageCodec, Limits,
};

fn raw(id: [u8; 4]) -> Option<&'static dyn ImageCodec> {
    match &id {
        b"RF32" => Some(&RawF32Codec),
        b"RF16" => Some(&RawF16Codec),
        _ => None,
    }
}

/// Two frames of 5x3 RGBA in 2x2 tiles (12 DATA chunks) with COLR, HDRM and META.
fn sample_file(codec: &dyn ImageCodec) -> Vec<u8> {
    let frames: Vec<HdrImage> = (0..2)
        .map(|f| {
            let s = (0..5 * 3 * 4).map(|i| (i + f * 100) as f32 * 0.37).collect();
            let mut img = HdrImage::new(5, 3, Channels::Rgba, s, ColorInfo::default()).unwrap();
            img.color = ColorInfo {
                primaries: ColorPrimaries::Bt2020,
                nits_per_unit: 203.0,
                hdr10: Some(Hdr10Metadata {
                    mastering_display: None,
                    content_light_level: Some(ContentLightLevel { max_cll: 4000, max_fall: 300 }),
                }),
            };
            img.set_metadata("software", "damage test");
            img
        })
        .collect();
    encode_frames(&frames, codec, &EncodeSettings::default(), Some(2)).unwrap()
}

fn assert_rejected(data: &[u8], what: &str) {
    let e = match Reader::new(data, &Limits::fuzzing()) {
        Ok(_) => panic!("{what}: the reader accepted it"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("chunk") || e.contains("signature"), "{what}: the error does not say where: {e}");
    assert!(decode_frames(data, &Limits::fuzzing().into(), &raw).is_err(), "{what}: decode_frames accepted it");
}

#[test]
fn every_truncation_is_an_error() {
    for codec in [&RawF32Codec as &dyn ImageCodec, &RawF16Codec] {
        let file = sample_file(codec);
        assert_eq!(Reader::new(&file, &Limits::fuzzing()).unwrap().data_chunks().len(), 12);
        assert_eq!(decode_frames(&file, &Limits::fuzzing().into(), &raw).unwrap().len(), 2);
        for n in 0..file.len() {
            assert_rejected(&file[..n], &format!("{} truncated to {n} of {} bytes", codec.name(), file.len()));
        }
    }
}

#[test]
fn every_single_byte_corruption_is_an_error() {
    let file = sample_file(&RawF16Codec);
    let mut count = 0;
    for i in 0..file.len() {
        for x in [0x01u8, 0x02, 0x10, 0x80, 0xFF] {
            let mut bad = file.clone();
            bad[i] ^= x;
            assert_rejected(&bad, &format!("byte {i} ^ 0x{x:02X}"));
            count += 1;
        }
    }
    assert_eq!(count, file.len() * 5);
}
