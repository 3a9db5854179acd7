//! `ImageCodec::probe` against `decode`: for every codec of the registry, the header-only probe
//! must give exactly the size, channels and colour that decoding the whole file gives, on the
//! generated corpus (encoded by each codec) and on the shared corpus of real files; and it must
//! work where decoding is refused for want of memory, since it allocates nothing of the
//! image's size.

mod common;

use hdrcodec::core::{Channels, ColorInfo, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits};

/// Asserts that `probe` says what `decode` gives for `data`.
fn assert_probe_matches_decode(codec: &dyn ImageCodec, data: &[u8], what: &str) -> ImageInfo {
    let limits = Limits::default();
    let info = codec.probe(data, &limits).unwrap_or_else(|e| panic!("{what}: probe failed: {e}"));
    let image = codec.decode(data, &limits).unwrap_or_else(|e| panic!("{what}: decode failed: {e}"));
    let probed = (info.width, info.height, info.channels, &info.color, info.frames);
    let decoded = (image.width(), image.height(), image.channels(), &image.color, 1);
    assert_eq!(probed, decoded, "{what}: probe (left) and decode (right) disagree");
    assert!(!info.format.is_empty(), "{what}: the probe names no format");
    assert_eq!(probe_from(codec, data, 0, &limits).unwrap(), info, "{what}: probe_from (left) and probe disagree");
    assert_eq!(
        probe_from(codec, data, 5, &limits).unwrap(),
        info,
        "{what}: probe_from after 5 bytes of something else"
    );
    info
}

/// [`ImageCodec::probe_from`] of `data` in a stream, after `skip` bytes of something else.
fn probe_from(codec: &dyn ImageCodec, data: &[u8], skip: usize, limits: &Limits) -> hdrcodec::core::Result<ImageInfo> {
    let mut file = vec![0x55; skip];
    file.extend_from_slice(data);
    let mut input = std::io::Cursor::new(file);
    input.set_position(skip as u64);
    codec.probe_from(&mut input, limits)
}

/// The codecs whose `probe_from` reads only their headers from a file (the others read it
/// whole, the provided version).
const HEADER_FROM_A_FILE: [&str; 8] = ["exr", "pfm", "rgbe", "hdrc", "logluv32", "logluv24", "logl16", "jxr"];

/// Settings that keep the slow encoders quick (BC6H's search effort) on the big test images.
fn fast() -> EncodeSettings {
    EncodeSettings::default().with_effort(0)
}

#[test]
fn probe_equals_decode_on_the_generated_corpus_for_every_codec() {
    let registry = hdrcodec::registry();
    let scenes = hdrcodec_cli::corpus::scenes();
    // Decode-only codecs (JPEG XR, until its encoder lands) are checked on real files in
    // their own tests (tests/jxr_reference.rs).
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let mut encoded = 0;
        for scene in &scenes {
            // The facade's colour preparation, as `convert` does; a scene a codec cannot take
            // (none today) is skipped.
            let Ok((bytes, _notes)) = hdrcodec::encode_for(codec.as_ref(), &scene.image, &fast()) else {
                eprintln!("{}: cannot encode {}, skipped", codec.name(), scene.name);
                continue;
            };
            let what = format!("{} / {}", codec.name(), scene.name);
            let info = assert_probe_matches_decode(codec.as_ref(), &bytes, &what);
            assert_eq!((info.width, info.height), (scene.image.width(), scene.image.height()), "{what}");
            encoded += 1;
        }
        assert!(encoded > 0, "{} encoded none of the generated scenes", codec.name());
    }
}

/// A smooth 2048 x 2048 RGB(A) image: 48 MiB (64 MiB with alpha) of decoded samples.
fn large(channels: Channels) -> HdrImage {
    let (w, h) = (2048u32, 2048u32);
    let n = channels.count();
    let mut samples = Vec::with_capacity((w * h) as usize * n);
    for y in 0..h {
        for x in 0..w {
            let v = 0.01 + (x + y) as f32 / 64.0;
            samples.extend_from_slice(&[v, v * 0.5, 0.25]);
            if n == 4 {
                samples.push(1.0);
            }
        }
    }
    HdrImage::new(w, h, channels, samples, ColorInfo::default()).unwrap()
}

#[test]
fn probe_needs_no_memory_of_the_image_size() {
    let registry = hdrcodec::registry();
    let image = large(Channels::Rgba);
    let tight = Limits::default().with_max_alloc_bytes(1 << 16);
    // Decode-only codecs (JPEG XR, until its encoder lands) are checked on real files in
    // their own tests (tests/jxr_reference.rs).
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let (bytes, _) = hdrcodec::encode_for(codec.as_ref(), &image, &fast())
            .unwrap_or_else(|e| panic!("{}: cannot encode 2048x2048: {e}", codec.name()));
        let e = codec.decode(&bytes, &tight).expect_err(codec.name());
        assert!(
            matches!(e, Error::LimitExceeded { .. }),
            "{}: decode failed with {e}, not LimitExceeded",
            codec.name()
        );
        let info = codec.probe(&bytes, &tight).unwrap_or_else(|e| panic!("{}: probe failed: {e}", codec.name()));
        assert_eq!((info.width, info.height), (2048, 2048), "{}", codec.name());
        // From a file, the codecs that read only their headers need no memory of the file's
        // size either.
        if HEADER_FROM_A_FILE.contains(&codec.name()) {
            assert!(bytes.len() > 1 << 16, "{}: the file is small", codec.name());
            let from = probe_from(codec.as_ref(), &bytes, 0, &tight)
                .unwrap_or_else(|e| panic!("{}: probe_from within 64 KiB failed: {e}", codec.name()));
            assert_eq!(from, info, "{}", codec.name());
        }
        // With room to decode, the two agree.
        assert_probe_matches_decode(codec.as_ref(), &bytes, codec.name());
    }
}

#[test]
fn probe_equals_decode_on_the_shared_corpus() {
    let Some(dir) =
        common::require(common::corpus_dir(), "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)")
    else {
        return;
    };
    let registry = hdrcodec::registry();
    let mut checked = 0;
    for sub in ["exr", "hdr", "tiff", "dds"] {
        let mut files: Vec<_> = std::fs::read_dir(dir.join(sub))
            .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        files.sort();
        for path in files {
            let data = std::fs::read(&path).unwrap();
            let what = path.strip_prefix(&dir).unwrap_or(&path).display().to_string();
            let Ok(codec) = registry.for_input(&path, &data) else { continue };
            // Only what decodes is compared (a header-only probe cannot know that a variant's
            // pixels are unsupported).
            match codec.decode(&data, &Limits::default()) {
                Ok(_) => {
                    let info = assert_probe_matches_decode(codec.as_ref(), &data, &what);
                    eprintln!("{what}: {} x {} {:?}, {}", info.width, info.height, info.channels, info.format);
                    checked += 1;
                }
                Err(e) => eprintln!("{what}: not decoded ({e}), not compared"),
            }
        }
    }
    assert!(checked >= 10, "only {checked} corpus files were compared");
}

#[test]
fn probe_never_panics_on_damaged_files_and_agrees_with_decode_where_both_succeed() {
    let registry = hdrcodec::registry();
    let scene = hdrcodec_cli::corpus::scene("odd-3x5").expect("the odd-3x5 scene");
    let limits = Limits::default();
    // Decode-only codecs (JPEG XR, until its encoder lands) are checked on real files in
    // their own tests (tests/jxr_reference.rs).
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let (file, _) = hdrcodec::encode_for(codec.as_ref(), &scene.image, &fast()).unwrap();
        let mut damaged: Vec<Vec<u8>> = (0..file.len()).map(|n| file[..n].to_vec()).collect();
        for at in 0..file.len() {
            for x in [0x01, 0x80, 0xFF] {
                let mut d = file.clone();
                d[at] ^= x;
                damaged.push(d);
            }
        }
        for d in &damaged {
            let probed = codec.probe(d, &limits);
            // From a file: the same answer, or an error of the same kind; `.hdrc` checks its
            // tile headers and index there as decoding does, so it may refuse what `probe` takes,
            // and reports the first problem of that walk (fuzz/entry_points.rs says the same).
            match (&probed, probe_from(codec.as_ref(), d, 3, &limits)) {
                (Ok(p), Ok(f)) => assert_eq!(p, &f, "{}", codec.name()),
                (Err(_), Err(_)) if codec.name() == "hdrc" => {}
                (Err(p), Err(f)) => assert_eq!(
                    std::mem::discriminant(p),
                    std::mem::discriminant(&f),
                    "{}: probe said {p}, probe_from {f}",
                    codec.name()
                ),
                (Ok(_), Err(f)) if codec.name() == "hdrc" => assert!(codec.decode(d, &limits).is_err(), "{f}"),
                (p, f) => panic!("{}: probe said {p:?}, probe_from {f:?}", codec.name()),
            }
            if let Ok(img) = codec.decode(d, &limits) {
                let info = probed.unwrap_or_else(|e| panic!("{}: decode succeeds, probe fails: {e}", codec.name()));
                assert_eq!(
                    (info.width, info.height, info.channels, &info.color),
                    (img.width(), img.height(), img.channels(), &img.color),
                    "{}",
                    codec.name()
                );
            }
        }
    }
}
