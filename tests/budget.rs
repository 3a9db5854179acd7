//! The allocation budget of `Limits` (shared by clones) bounds what decodes running at once may
//! hold: every decoder of the registry charges its image against it before allocating.

use hdrcodec::core::{Channels, ColorInfo, EncodeSettings, Error, HdrImage, Limits};

#[test]
fn every_decoder_charges_the_shared_budget() {
    let (w, h) = (48u32, 40u32);
    let samples: Vec<f32> = (0..w * h * 3).map(|i| 0.01 + (i % 97) as f32 * 0.37).collect();
    let image = HdrImage::new(w, h, Channels::Rgb, samples, ColorInfo::default()).unwrap();
    let decoded = u64::from(w * h) * 3 * 4;
    let registry = hdrcodec::registry();
    let mut checked = Vec::new();
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let settings = EncodeSettings::default().with_effort(0);
        let Ok((file, _)) = hdrcodec::encode_for(codec.as_ref(), &image, &settings) else { continue };
        // Room for the decoded image and the decoder's working set (at most a copy of the
        // file and a batch of blocks); with another decode's charge leaving less than one
        // image of it, the decode must fail.
        // JPEG XR entropy-decodes into rows of coefficients (as many values as samples, and
        // a halo) and transforms them in bands of 16-row macroblocks: a fixed working set
        // that on an image of 3×3 macroblocks is several times the image (on 13 MP, 3%).
        let working = if codec.name() == "jxr" { decoded * 7 } else { 0 };
        let room = decoded * 2 + working + file.len() as u64 * 2;
        let limits = Limits::default().with_max_alloc_bytes(room);
        let other = limits.charge(room - decoded / 2, "another decode in flight").unwrap();
        match codec.decode(&file, &limits) {
            Err(Error::LimitExceeded { what }) => assert!(what.contains("already in use"), "{}: {what}", codec.name()),
            other => panic!("{}: decoding beside another image's charge gave {other:?}", codec.name()),
        }
        drop(other);
        let back = codec.decode(&file, &limits).unwrap_or_else(|e| panic!("{}: {e}", codec.name()));
        assert_eq!((back.width(), back.height()), (w, h), "{}", codec.name());
        // Every charge was returned.
        assert_eq!(limits.in_use(), 0, "{}", codec.name());
        checked.push(codec.name());
    }
    for name in ["exr", "pfm", "rgbe", "logluv32", "logluv24", "logl16", "bc6h", "bc6h-ktx2", "hdrc", "jxr"] {
        assert!(checked.contains(&name), "{name} not checked: {checked:?}");
    }
}
