//! Bad input never panics, and every damaged file gets a clear `Error`; hand-built files in each
//! scanline encoding decode to the pixels the format definition gives them.

use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, Error, HdrImage, ImageCodec, Limits};
use hdrcodec_rgbe::{
    decode, encode, read_header, MantissaDecode, PixelFormat, RgbeCodec, RgbeDecodeOptions, RgbeEncodeOptions, Rounding,
};
use std::path::PathBuf;

fn raw() -> RgbeDecodeOptions {
    RgbeDecodeOptions { apply_exposure: false, mantissa: MantissaDecode::Truncated }
}

fn dec(data: &[u8]) -> Result<HdrImage, Error> {
    decode(data, &Limits::default(), &RgbeDecodeOptions::default())
}

fn file(header: &str, pixels: &[u8]) -> Vec<u8> {
    let mut v = header.as_bytes().to_vec();
    v.extend_from_slice(pixels);
    v
}

/// The shared corpus (`$HDRCODEC_CORPUS` or ../shared/corpus); a failure under CI if missing.
fn corpus_hdr(name: &str) -> Option<Vec<u8>> {
    let dir = std::env::var_os("HDRCODEC_CORPUS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/corpus"));
    match std::fs::read(dir.join("hdr").join(name)) {
        Ok(d) => Some(d),
        Err(e) if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") => {
            panic!("corpus file hdr/{name} is missing in CI: {e}")
        }
        Err(e) => {
            eprintln!("SKIPPED: corpus file hdr/{name} missing ({e}); not a failure outside CI");
            None
        }
    }
}

fn sample_image(w: u32, h: u32) -> HdrImage {
    let s = (0..w * h * 3).map(|i| ((i * 7919) % 1000) as f32 * 0.013 + (i % 5 == 0) as u32 as f32 * 40.0).collect();
    HdrImage::new(w, h, Channels::Rgb, s, ColorInfo::default()).unwrap()
}

#[test]
fn truncation_sweep_over_a_corpus_file() {
    let Some(data) = corpus_hdr("mpi_atrium_3.hdr") else { return };
    let full = decode(&data, &Limits::default(), &raw()).unwrap();
    assert_eq!((full.width(), full.height()), (1024, 676));
    // Every cut inside the header and the first scanlines, then a cut every 997 bytes.
    let cuts = (0..2048).chain((2048..data.len()).step_by(997));
    let mut n = 0;
    for len in cuts {
        match decode(&data[..len], &Limits::default(), &raw()) {
            Err(Error::Truncated { .. }) => n += 1,
            Err(e) => panic!("cut at {len}: expected Truncated, got {e}"),
            Ok(_) => panic!("cut at {len} of {} decoded", data.len()),
        }
    }
    println!("{n} truncations of mpi_atrium_3.hdr, all reported as truncated");
}

#[test]
fn corruption_never_panics() {
    let mut files = vec![
        encode(&sample_image(40, 9), &RgbeEncodeOptions::default()).unwrap(),
        encode(&sample_image(40, 9), &RgbeEncodeOptions { rle: false, ..Default::default() }).unwrap(),
        encode(&sample_image(5, 9), &RgbeEncodeOptions::default()).unwrap(),
    ];
    if let Some(d) = corpus_hdr("hall.hdr") {
        files.push(d[..20_000].to_vec());
    }
    for data in files {
        for pos in 0..data.len().min(4000) {
            for v in [0u8, 1, 2, 0x7f, 0x80, 0x81, 0xff, b'\n'] {
                let mut d = data.clone();
                d[pos] = v;
                let _ = dec(&d);
                let _ = decode(&d, &Limits::fuzzing(), &raw());
            }
        }
    }
}

#[test]
fn bad_inputs_get_clear_errors() {
    let rle_head = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 8\n";
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty", vec![]),
        ("not radiance", b"P6\n1 1\n255\n".to_vec()),
        ("header without the empty line", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n-Y 1 +X 1\n".to_vec()),
        ("missing newline after the resolution", b"#?RADIANCE\n\n-Y 1 +X 1".to_vec()),
        ("bad resolution", b"#?RADIANCE\n\n-Y 1 +Q 1\n\0\0\0\0".to_vec()),
        ("non-ASCII resolution", "#?RADIANCE\n\n-Y 4 \u{567} 8\n\0\0\0\0".as_bytes().to_vec()),
        ("same axis twice", b"#?RADIANCE\n\n-Y 1 +Y 1\n\0\0\0\0".to_vec()),
        ("zero width", b"#?RADIANCE\n\n-Y 1 +X 0\n".to_vec()),
        ("absurd size", b"#?RADIANCE\n\n-Y 4000000000 +X 4000000000\n\0\0\0\0".to_vec()),
        ("lying dimensions", b"#?RADIANCE\n\n-Y 60000 +X 60000\n\0\0\0\0".to_vec()),
        ("unknown format", b"#?RADIANCE\nFORMAT=48-bit_rle_rgbe\n\n-Y 1 +X 1\n\0\0\0\0".to_vec()),
        ("bad exposure", b"#?RADIANCE\nEXPOSURE=-1\n\n-Y 1 +X 1\n\0\0\0\0".to_vec()),
        ("run overflows the scanline", file(rle_head, &[2, 2, 0, 8, 137, 5])),
        ("literal overflows the scanline", file(rle_head, &[2, 2, 0, 8, 9, 1, 2, 3, 4, 5, 6, 7, 8, 9])),
        ("zero-length literal", file(rle_head, &[2, 2, 0, 8, 0, 136, 5])),
        ("RLE length differs", file(rle_head, &[2, 2, 0, 9, 136, 5])),
        ("truncated RLE", file(rle_head, &[2, 2, 0, 8, 136, 5, 136])),
        ("repeat with no pixel before", file("#?RADIANCE\n\n-Y 1 +X 2\n", &[1, 1, 1, 2])),
        ("old-style repeat overflows", file("#?RADIANCE\n\n-Y 1 +X 2\n", &[9, 9, 9, 130, 1, 1, 1, 5])),
    ];
    for (what, data) in cases {
        let err = dec(&data).expect_err(what);
        let msg = err.to_string();
        println!("{what}: {msg}");
        assert!(!msg.contains('\n'), "{what}: error is not one line");
    }
    // Absurd sizes are refused before allocating, by the limits.
    let e = dec(b"#?RADIANCE\n\n-Y 4000000000 +X 4000000000\n\0\0\0\0").unwrap_err();
    assert!(matches!(e, Error::LimitExceeded { .. } | Error::Invalid { .. }), "{e}");
}

#[test]
fn scanline_encodings_decode_per_the_format_definition() {
    // Ward's RGBE: value = mantissa · 2^(exponent - 136); exponent 0 is black.
    let v = |m: u8, e: u8| if e == 0 { 0.0 } else { f32::from(m) * 2f32.powi(i32::from(e) - 136) };
    // Old-style RLE: (1,1,1,n) repeats the previous pixel n times; a second repeat code in a row
    // counts in units of 256 (Radiance's oldreadcolrs). 2 + 256·1 + 3 = 261 pixels, then one more.
    let mut px = vec![10, 20, 30, 130, 1, 1, 1, 3, 1, 1, 1, 1, 40, 50, 60, 129];
    let w = 1 + 3 + 256 + 1;
    let img = dec(&file(&format!("#?RADIANCE\n\n-Y 1 +X {w}\n"), &px)).unwrap();
    assert_eq!(img.width(), w);
    for x in 0..260 {
        assert_eq!(img.pixel(x, 0), &[v(10, 130), v(20, 130), v(30, 130)], "x={x}");
    }
    assert_eq!(img.pixel(260, 0), &[v(40, 129), v(50, 129), v(60, 129)]);
    // Flat pixels in a scanline shorter than 8 (never RLE).
    px = vec![1, 2, 3, 140, 0, 0, 0, 0, 255, 255, 255, 255];
    let img = dec(&file("#?RGBE\n\n-Y 1 +X 3\n", &px)).unwrap();
    assert_eq!(img.samples(), &[v(1, 140), v(2, 140), v(3, 140), 0.0, 0.0, 0.0, v(255, 255), v(255, 255), v(255, 255)]);
    // New-style RLE: per channel, count > 128 is a run, else a literal.
    let rle = [2, 2, 0, 8, 136, 7, 4, 1, 2, 3, 4, 132, 9, 136, 0, 136, 131];
    let img = dec(&file("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 8\n", &rle)).unwrap();
    for x in 0..8u32 {
        let g = if x < 4 { x as u8 + 1 } else { 9 };
        assert_eq!(img.pixel(x, 0), &[v(7, 131), v(g, 131), 0.0]);
    }
    // Centred mantissas add half a step.
    let img = decode(
        &file("#?RGBE\n\n-Y 1 +X 1\n", &[1, 2, 3, 137]),
        &Limits::default(),
        &RgbeDecodeOptions { mantissa: MantissaDecode::Centred, ..Default::default() },
    )
    .unwrap();
    assert_eq!(img.samples(), &[3.0, 5.0, 7.0]);
}

#[test]
fn header_variables_and_metadata() {
    let head = "#?RADIANCE\n# a comment\npfilt -x 2 -y 1\nEXPOSURE=2\nEXPOSURE=4\nCOLORCORR=1 2 4\nPIXASPECT=1.5\n\
                SOFTWARE=test 1.0\nVIEW= -vtv -vh 45\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n";
    let data = file(head, &[128, 128, 128, 130]); // 2.0 2.0 2.0 stored
    let img = dec(&data).unwrap();
    // EXPOSURE multiplies (2·4 = 8) and so does COLORCORR per channel: original = stored / (8·cc).
    assert_eq!(img.samples(), &[0.25, 0.125, 0.0625]);
    let md = |k: &str| img.metadata_value(k).map(str::to_string);
    assert_eq!(md("exposure").as_deref(), Some("8"));
    assert_eq!(md("comment").as_deref(), Some("a comment"));
    assert_eq!(md("history").as_deref(), Some("pfilt -x 2 -y 1"));
    assert_eq!(md("software").as_deref(), Some("test 1.0"));
    assert_eq!(md("pixaspect").as_deref(), Some("1.5"));
    assert_eq!(md("view").as_deref(), Some("-vtv -vh 45"));
    // Raw values keep EXPOSURE, and writing them again declares it.
    let rawimg = decode(&data, &Limits::default(), &raw()).unwrap();
    assert_eq!(rawimg.samples(), &[2.0, 2.0, 2.0]);
    let again = encode(&rawimg, &RgbeEncodeOptions::default()).unwrap();
    let text = String::from_utf8_lossy(&again[..again.len() - 4]).into_owned();
    for line in ["EXPOSURE=8\n", "COLORCORR=1 2 4\n", "PIXASPECT=1.5\n", "SOFTWARE=test 1.0\n", "# a comment\n"] {
        assert!(text.contains(line), "{line:?} missing from {text:?}");
    }
    assert_eq!(dec(&again).unwrap().samples(), img.samples());
    // Lines kept as history must not come back as variables (a fuzz find): " FORMAT=x" is a
    // command line, and writing it trimmed would make it a FORMAT variable.
    let odd = file("#?RADIANCE\n FORMAT=junk\n#?RADIANCE\n\n-Y 1 +X 1\n", &[128, 0, 0, 129]);
    let odd_img = dec(&odd).unwrap();
    assert_eq!(odd_img.metadata_value("history"), Some("FORMAT=junk"));
    let back = encode(&odd_img, &RgbeEncodeOptions::default()).unwrap();
    assert_eq!(dec(&back).unwrap().samples(), odd_img.samples());
    // Photoshop's all-zero PRIMARIES mean "none": BT.709.
    let ps = file("#?RADIANCE\nGAMMA=1\nPRIMARIES=0 0 0 0 0 0 0 0\n\n-Y 1 +X 1\n", &[0, 0, 0, 0]);
    assert_eq!(dec(&ps).unwrap().color.primaries, ColorPrimaries::Bt709);
    assert!(read_header(&ps).unwrap().primaries.is_none());
}

#[test]
fn primaries_and_xyze_round_trip() {
    let mut img = sample_image(20, 3);
    img.color.primaries = ColorPrimaries::Bt2020;
    for format in [PixelFormat::Rgbe, PixelFormat::Xyze] {
        let bytes = encode(&img, &RgbeEncodeOptions { format, ..Default::default() }).unwrap();
        let h = read_header(&bytes).unwrap();
        assert_eq!(h.format, format);
        // BT.2020 is declared with its chromaticities (ITU-R BT.2020 Table 3).
        let p = h.primaries.unwrap();
        assert_eq!(
            (p.red, p.green, p.blue, p.white),
            ([0.708, 0.292], [0.170, 0.797], [0.131, 0.046], [0.3127, 0.329])
        );
        let back = dec(&bytes).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::Bt2020);
        for (o, d) in img.rgb().zip(back.rgb()) {
            let m = o.iter().fold(0.0f32, |a, &v| a.max(v));
            for c in 0..3 {
                // XYZE spreads one exponent over X, Y, Z: a few mantissa steps of the largest.
                assert!((o[c] - d[c]).abs() <= m * 0.02 + 1e-6, "{format:?} {o:?} {d:?}");
            }
        }
    }
    // BT.709 is the Radiance default and is not declared.
    let bytes = encode(&sample_image(3, 1), &RgbeEncodeOptions::default()).unwrap();
    assert!(read_header(&bytes).unwrap().primaries.is_none());
}

#[test]
fn writer_output_decodes_to_the_encoded_values() {
    let img = sample_image(300, 5);
    for rounding in [Rounding::Truncate, Rounding::Nearest] {
        for rle in [true, false] {
            let bytes = encode(&img, &RgbeEncodeOptions { rounding, rle, ..Default::default() }).unwrap();
            let back = dec(&bytes).unwrap();
            for (o, d) in img.rgb().zip(back.rgb()) {
                let want =
                    hdrcodec_rgbe::decode_pixel(hdrcodec_rgbe::encode_pixel(o, rounding), MantissaDecode::Truncated);
                assert_eq!(d, want);
            }
        }
    }
    // Normalised mantissas: the largest is always 128..=255, so flat files can never contain
    // the (1,1,1,n) repeat code or a (2,2,b<128,e) RLE marker.
    let mut state = 12345u32;
    for _ in 0..100_000 {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let v = f32::from_bits(state & 0x7fff_ffff);
        for rounding in [Rounding::Truncate, Rounding::Nearest] {
            let p = hdrcodec_rgbe::encode_pixel([v, v * 0.5, v * 0.01], rounding);
            assert!(p == [0; 4] || p[0] >= 128, "{v} -> {p:?}");
        }
    }
}

#[test]
fn codec_trait_and_options() {
    let c = RgbeCodec::new();
    assert_eq!((c.name(), c.id(), c.extensions()), ("rgbe", *b"RGBE", &["hdr", "pic"][..]));
    assert!(c.sniff(b"#?RADIANCE\n") && c.sniff(b"#?RGBE\n") && !c.sniff(b"\x76\x2f\x31\x01"));
    let img = sample_image(16, 2);
    let s = EncodeSettings::default().with_option("rounding", "truncate").with_option("rle", "false");
    let a = c.encode(&img, &s).unwrap();
    let b =
        encode(&img, &RgbeEncodeOptions { rounding: Rounding::Truncate, rle: false, ..Default::default() }).unwrap();
    assert_eq!(a, b);
    let x = c.encode(&img, &EncodeSettings::default().with_option("format", "xyze")).unwrap();
    assert_eq!(read_header(&x).unwrap().format, PixelFormat::Xyze);
    for bad in [("bogus", "1"), ("rounding", "up"), ("format", "rgb"), ("rle", "maybe")] {
        let e = c.encode(&img, &EncodeSettings::default().with_option(bad.0, bad.1)).unwrap_err();
        assert!(e.to_string().contains(bad.0), "{e}");
    }
}

#[test]
fn probe_reads_the_header_as_decode_would() {
    let mut img = sample_image(20, 3);
    img.color.primaries = ColorPrimaries::Bt2020;
    for (format, rle, want) in [
        (PixelFormat::Rgbe, true, "RGBE, run-length scanlines"),
        (PixelFormat::Rgbe, false, "RGBE, flat scanlines"),
        (PixelFormat::Xyze, true, "XYZE, run-length scanlines"),
    ] {
        let bytes = encode(&img, &RgbeEncodeOptions { format, rle, ..Default::default() }).unwrap();
        let info = RgbeCodec::new().probe(&bytes, &Limits::default()).unwrap();
        let back = dec(&bytes).unwrap();
        assert_eq!((info.width, info.height, info.channels, &info.color), (20, 3, back.channels(), &back.color));
        assert_eq!((info.format.as_str(), info.frames), (want, 1));
        // Probing needs only the header: the byte limit does not apply to it.
        let tiny = Limits::default().with_max_alloc_bytes(64);
        assert!(RgbeCodec::new().decode(&bytes, &tiny).is_err());
        assert!(hdrcodec_rgbe::probe(&bytes, &tiny).is_ok());
    }
    // A header that promises more scanlines than the file can hold.
    let short = file("#?RADIANCE\n\n-Y 100 +X 8\n", &[0; 40]);
    assert!(matches!(hdrcodec_rgbe::probe(&short, &Limits::default()), Err(Error::Truncated { .. })));
    let huge = file("#?RADIANCE\n\n-Y 4000000000 +X 4000000000\n", &[0; 4]);
    assert!(matches!(hdrcodec_rgbe::probe(&huge, &Limits::default()), Err(Error::LimitExceeded { .. })));
}
