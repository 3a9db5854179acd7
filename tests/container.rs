//! The `.hdrc` container carrying other codecs of the family: each tile is a stand-alone file
//! of that codec, and the tiled result equals what the codec gives for the whole image.

use hdrcodec_container::{decode_image, encode_image, HdrcCodec, Reader};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, HdrImage, ImageCodec, Limits};
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

/// The registry's `.hdrc` codec with every payload codec of the family.
fn hdrc() -> Arc<dyn ImageCodec> {
    hdrcodec::registry().by_name("hdrc").unwrap()
}

#[test]
fn tiles_come_back_in_the_header_s_colour() {
    // A BT.2020 image with pure BT.2020 primaries (far outside BT.709) at 203 cd/m² per unit,
    // through the container with payloads of every kind of colour signalling: LogLuv (decodes to
    // BT.709 with its STONITS scale), RGBE (records the primaries, not the scale), PFM, BC6H and
    // raw (record neither). Each decoded tile must come back in the header's primaries and units,
    // as close to the source as the payload codec on its own gets (all of these code each pixel
    // or 4x4 block on its own, so tiling changes nothing but float rounding).
    let mut img = hdrcodec_cli::corpus::scene("bt2020-ramps").unwrap().image;
    img.color.nits_per_unit = 203.0;
    let codec = hdrc();
    let reg = hdrcodec::registry();
    let limits = Limits::default();
    for payload in ["logluv32", "rgbe", "pfm", "raw-f32", "raw-f16", "bc6h"] {
        let s = EncodeSettings::default().with_effort(0).with_option("payload", payload).with_option("tile", "128");
        let (bytes, notes) = hdrcodec::encode_for(codec.as_ref(), &img, &s).unwrap();
        assert!(notes.is_empty(), "{payload}: {notes:?}");
        let back = codec.decode(&bytes, &limits).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::Bt2020, "{payload}");
        assert_eq!(back.color.nits_per_unit, 203.0, "{payload}");
        let (mean, p99) = hdrcodec_core::metrics::delta_e_itp(&img, &back).unwrap();
        // The payload codec alone, on the whole image (the raw codecs have no file of their own:
        // they are lossless or binary16 per sample, as the container's README says).
        let alone = match reg.by_name(payload) {
            Ok(c) if !payload.starts_with("raw") => {
                let s = EncodeSettings::default().with_effort(0);
                let (b, _) = hdrcodec::encode_for(c.as_ref(), &img, &s).unwrap();
                let mut alone = c.decode(&b, &limits).unwrap();
                // A format that records no scale reads back at the default 100 cd/m² per unit;
                // its samples are in the writer's units (the container's header has them).
                if !c.records_nits_per_unit() {
                    alone.color.nits_per_unit = img.color.nits_per_unit;
                }
                hdrcodec_core::metrics::delta_e_itp(&img, &alone).unwrap()
            }
            _ => (0.0, 0.0),
        };
        eprintln!(
            "hdrc payload={payload}: ΔE ITP mean {mean:.4} p99 {p99:.4} (the codec alone: {:.4} / {:.4})",
            alone.0, alone.1
        );
        let slack = if payload == "raw-f16" { 0.5 } else { 1e-3 };
        assert!(mean <= alone.0 + slack && p99 <= alone.1 + slack, "{payload}: ΔE ITP mean {mean} p99 {p99}");
        // Same primaries and units on both sides: the samples themselves agree (not only the
        // colours after the conversion the metric makes). The error of each sample relative to
        // its pixel's largest channel (pure primaries have zero channels).
        let worst = img
            .rgb()
            .zip(back.rgb())
            .flat_map(|(a, b)| {
                let peak = a.iter().fold(1e-2f32, |m, v| m.max(v.abs()));
                (0..3).map(move |c| (a[c] - b[c]).abs() / peak)
            })
            .fold(0.0f32, f32::max);
        eprintln!("  worst sample error relative to its pixel's largest channel: {worst:.2e}");
        match payload {
            "pfm" | "raw-f32" => assert_eq!(back.samples(), img.samples(), "{payload} is lossless"),
            // BC6H at effort 0 errs more than that on single dark texels; ΔE above pins it.
            "bc6h" => {}
            _ => assert!(worst < 0.05, "{payload}: {worst}"),
        }
    }
}

#[test]
fn payloads_say_nothing_about_colour_the_header_records() {
    // Colour the payload cannot record (unspecified for Radiance and LogLuv, DCI-P3 for KTX2)
    // is the header's business: no note, and the image comes back as it went in.
    let codec = hdrc();
    let limits = Limits::default();
    let base = scene(Channels::Rgb);
    for (primaries, payload) in [
        (ColorPrimaries::Unspecified, "rgbe"),
        (ColorPrimaries::Unspecified, "logluv32"),
        (ColorPrimaries::Unspecified, "exr"),
        (ColorPrimaries::DciP3, "bc6h-ktx2"),
        (ColorPrimaries::Unspecified, "bc6h-ktx2"),
        (ColorPrimaries::AcesAp1, "bc6h-ktx2"),
    ] {
        let mut img = base.clone();
        img.color.primaries = primaries;
        let s = EncodeSettings::default().with_effort(0).with_option("payload", payload).with_option("tile", "64");
        let (bytes, notes) = hdrcodec::encode_for(codec.as_ref(), &img, &s).unwrap();
        // (Notes about the range, such as BC6H's clipping above 65504, are not about colour.)
        assert!(notes.iter().all(|n| !n.contains("primaries")), "{} in {payload}: {notes:?}", primaries.name());
        let back = codec.decode(&bytes, &limits).unwrap();
        assert_eq!(back.color.primaries, primaries, "{payload}");
        // Read the unspecified samples as BT.709 on both sides for the metric.
        let label = |mut i: HdrImage| {
            i.color.primaries = i.color.primaries.or_bt709();
            i
        };
        let (mean, p99) = hdrcodec_core::metrics::delta_e_itp(&label(img.clone()), &label(back)).unwrap();
        // The payload codec alone on the whole image, as it is (a file it decodes unspecified
        // is scored in the reference's primaries).
        let alone = hdrcodec::registry().by_name(payload).unwrap();
        let file = alone.encode(&img, &EncodeSettings::default().with_effort(0)).unwrap();
        let alone = hdrcodec_core::metrics::delta_e_itp(&label(img.clone()), &alone.decode(&file, &limits).unwrap());
        let (alone_mean, alone_p99) = alone.unwrap();
        eprintln!(
            "{} in payload={payload}: ΔE ITP mean {mean:.4} p99 {p99:.4} (the codec alone: {alone_mean:.4} / \
             {alone_p99:.4})",
            primaries.name()
        );
        assert!(mean <= alone_mean + 1e-3 && p99 <= alone_p99 + 1e-3, "{} in {payload}", primaries.name());
    }
}

/// L_p u'v' frames in a `.hdrc` sequence (`payload=lpuv`, through the facade's stream codec):
/// every tile carries the same description as the AV1 stream's T.35 message (curve, bits,
/// range, primaries), and the frames decode back to linear light within what the L_p u'v'
/// quantizers do (11-bit ψ, 8-bit u'v').
#[test]
fn lpuv_frames_in_hdrc_carry_their_description_and_decode_to_linear() {
    use hdrcodec_core::metrics::{delta_e_itp, pu21_psnr};
    use hdrcodec_core::{DecodeOptions, ImageInfo};
    use hdrcodec_video::lpuv_av1::{LpuvStreamInfo, T35_COUNTRY_CODE};
    use hdrcodec_video::sequences::moving_light_frame;
    let frames: Vec<HdrImage> = (0..3).map(|t| moving_light_frame(64, 48, 4000.0, 6.0, t, 3)).collect();
    let codec = hdrcodec::video_codecs().into_iter().find(|c| c.name() == "hdrc").unwrap();
    let out = std::env::temp_dir().join(format!("hdrcodec-lpuv-{}.hdrc", std::process::id()));
    let settings = EncodeSettings::default().with_option("payload", "lpuv").with_option("tile", "32");
    let file = std::io::BufWriter::new(std::fs::File::create(&out).unwrap());
    let mut enc = codec.begin_encode(&ImageInfo::of(&frames[0]).with_frames(3), &settings, Box::new(file)).unwrap();
    for f in &frames {
        enc.push_frame(f).unwrap();
    }
    assert_eq!(enc.finish().unwrap(), 3);
    let bytes = std::fs::read(&out).unwrap();
    std::fs::remove_file(&out).unwrap();
    // Every tile (2x2 per frame) starts with the description: the T.35 payload's bytes.
    let at: Vec<usize> = bytes.windows(13).enumerate().filter(|(_, w)| w == b"hdrcodec-lpuv").map(|(i, _)| i).collect();
    assert_eq!(at.len(), 12);
    let info = LpuvStreamInfo::from_t35(T35_COUNTRY_CODE, &bytes[at[0]..]).unwrap().unwrap();
    assert_eq!((info.bits, info.primaries().unwrap()), (11, ColorPrimaries::Bt2020));
    assert_eq!((info.min_nits, info.max_nits), (1e-4, 1e8));
    let mut dec = codec.begin_decode(bytes.into(), &DecodeOptions::new(Limits::default())).unwrap();
    for source in &frames {
        let back = dec.next_frame().unwrap().unwrap();
        assert_eq!((back.color.primaries, back.color.nits_per_unit), (ColorPrimaries::Bt2020, 100.0));
        let (pu21, (de, _)) = (pu21_psnr(source, &back).unwrap(), delta_e_itp(source, &back).unwrap());
        eprintln!("L_p u'v' in .hdrc: PU21-PSNR {pu21:.1} dB, mean ΔE ITP {de:.2}");
        assert!(pu21 > 57.0 && de < 0.8, "PU21-PSNR {pu21}, ΔE ITP {de}");
    }
    assert!(dec.next_frame().unwrap().is_none());
}

/// Decoded from the file in a stream (`decode_from`: the chunks read as they are decoded, an
/// untiled payload read by its codec from the file), every payload codec of the family, tiled
/// and untiled, gives the samples of the decode of the bytes in memory.
#[test]
fn every_payload_decodes_from_a_stream_as_from_memory() {
    let hdrc = hdrc();
    let img = scene(Channels::Rgba);
    let reg = hdrcodec::registry();
    let mut payloads: Vec<&str> =
        reg.names().into_iter().filter(|&n| n != "hdrc" && reg.by_name(n).is_ok_and(|c| c.can_encode())).collect();
    payloads.extend(["raw-f32", "raw-f16"]);
    assert!(payloads.len() >= 8, "{payloads:?}");
    for payload in payloads {
        for tile in [None, Some(64)] {
            let mut s = EncodeSettings::default().with_effort(0).with_option("payload", payload);
            if let Some(t) = tile {
                s = s.with_option("tile", t.to_string());
            }
            let what = format!("payload {payload}, tile {tile:?}");
            let file = match hdrc.encode(&img, &s) {
                Ok(f) => f,
                Err(e) => panic!("{what}: {e}"),
            };
            let options = hdrcodec_core::DecodeOptions::new(Limits::default());
            let want = hdrc.decode_with(&file, &options).unwrap_or_else(|e| panic!("{what}: {e}"));
            let got =
                hdrc.decode_from(&mut std::io::Cursor::new(&file), &options).unwrap_or_else(|e| panic!("{what}: {e}"));
            let bits = |i: &HdrImage| i.samples().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "{what}");
            assert_eq!((&got.color, &got.metadata), (&want.color, &want.metadata), "{what}");
        }
    }
}
