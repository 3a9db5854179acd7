//! The `.hdrc` container carrying other codecs of the family: each tile is a stand-alone file
//! of that codec, and the tiled result equals what the codec gives for the whole image.

use hdrcodec_container::{decode_image, encode_image, HdrcCodec, Reader};
use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
use hdrcodec_pfm::PfmCodec;
use hdrcodec_rgbe::RgbeCodec;
use std::sync::Arc;

/// Values from 10^-3 to 10^5 over a 257x129 frame (odd size: partial edge tiles).
fn scene(channels: Channels) -> HdrImage {
    let (w, h) = (257u32, 129u32);
    let n = channels.count();
    let mut s = Vec::with_capacity((w * h) as usize * n);
    for y in 0..h {
        for x in 0..w {
            let e = (x as f32 / w as f32) * 8.0 - 3.0;
            let v = 10f32.powf(e) * (1.0 + 0.3 * ((x * 7 + y * 13) % 11) as f32 / 11.0);
            s.extend_from_slice(&[v, v * 0.5, v * (y as f32 / h as f32)]);
            if n == 4 {
                s.push((x % 5) as f32 / 4.0);
            }
        }
    }
    HdrImage::new(w, h, channels, s, ColorInfo::default()).unwrap()
}

#[test]
fn rgbe_tiles_decode_exactly_like_the_whole_image() {
    // RGBE is a per-pixel code, so cutting the image into tiles must not change a single value:
    // the reference is the RGBE codec's own round trip of the untiled image.
    let rgbe = RgbeCodec::new();
    let img = scene(Channels::Rgb);
    let s = EncodeSettings::default();
    let whole = rgbe.decode(&rgbe.encode(&img, &s).unwrap(), &Limits::default()).unwrap();
    let file = encode_image(&img, &rgbe, &s, Some(64)).unwrap();
    let resolve = |id: [u8; 4]| (id == rgbe.id()).then_some(&rgbe as &dyn ImageCodec);
    let back = decode_image(&file, &Limits::default().into(), &resolve).unwrap();
    assert_eq!(back.samples(), whole.samples());
    let r = Reader::new(&file, &Limits::default()).unwrap();
    assert_eq!(r.data_chunks().len(), 15);
    assert!(r.data_chunks().iter().all(|d| rgbe.sniff(d.payload)), "each tile is a Radiance file");
}

#[test]
fn hdrc_codec_with_pfm_and_rgbe_payloads() {
    let codec = HdrcCodec::new(vec![Arc::new(PfmCodec), Arc::new(RgbeCodec::new())]);
    let names: Vec<_> = codec.codecs().iter().map(|c| c.name()).collect();
    assert_eq!(names, ["pfm", "rgbe", "raw-f32", "raw-f16"]);

    // PFM stores f32: lossless through the container.
    let img = scene(Channels::Rgb);
    let pfm = EncodeSettings::default().with_option("payload", "pfm").with_option("tile", "100");
    let back = codec.decode(&codec.encode(&img, &pfm).unwrap(), &Limits::default()).unwrap();
    assert_eq!(back, img);

    // RGBE has no alpha: the documented conversion sets alpha to 1 on decode.
    let rgba = scene(Channels::Rgba);
    let rgbe = EncodeSettings::default().with_option("payload", "rgbe").with_option("tile", "64");
    let back = codec.decode(&codec.encode(&rgba, &rgbe).unwrap(), &Limits::default()).unwrap();
    assert_eq!(back.channels(), Channels::Rgba);
    assert!(back.samples().chunks_exact(4).all(|p| p[3] == 1.0));
    let rgb_only = scene(Channels::Rgb);
    let expect = RgbeCodec::new()
        .decode(&RgbeCodec::new().encode(&rgb_only, &EncodeSettings::default()).unwrap(), &Limits::default())
        .unwrap();
    assert_eq!(back.with_channels(Channels::Rgb).samples(), expect.samples());
}
