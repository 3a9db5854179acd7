//! OpenEXR decoder on arbitrary bytes: must return `Ok` or `Err`, never panic, and never
//! allocate past `Limits::fuzzing()`. A successful decode is re-encoded with a compression
//! picked by the last input byte and decoded again.
//!
//! A panic inside the `exr` crate is caught by the codec and returned as `Error::Invalid`
//! ("... panicked ..."); libfuzzer-sys's panic hook would abort on it all the same. So the
//! target's hook ignores panics raised in the `exr` crate's own source files and passes every
//! other panic on to libfuzzer's aborting hook. Set `HDRCODEC_FUZZ_STRICT=1` to keep the
//! aborting hook for all panics and find the `exr` ones, to report upstream (known: B44
//! `unpack14` subtracts with overflow on corrupt blocks, exr 1.74.2
//! src/compression/b44/mod.rs:186-204, with overflow checks on as in fuzz and test builds).
#![no_main]

use hdrcodec_core::{EncodeSettings, ImageCodec, Limits};
use hdrcodec_exr::{ExrCodec, ExrCompression};
use libfuzzer_sys::fuzz_target;
use std::sync::Once;

static HOOK: Once = Once::new();

fuzz_target!(|data: &[u8]| {
    HOOK.call_once(|| {
        if std::env::var_os("HDRCODEC_FUZZ_STRICT").is_none() {
            let abort = std::panic::take_hook();
            std::panic::set_hook(Box::new(move |info| {
                let in_exr = info.location().is_some_and(|l| l.file().contains("/exr-1."));
                if !in_exr {
                    abort(info);
                }
            }));
        }
    });
    let limits = Limits::fuzzing();
    if let Ok(img) = ExrCodec.decode(data, &limits) {
        if img.pixel_count() <= 1 << 14 {
            let flags = data.last().copied().unwrap_or(0) as usize;
            let c = ExrCompression::ALL[flags % ExrCompression::ALL.len()];
            let pixel = if flags & 0x80 == 0 { "half" } else { "float" };
            let settings = EncodeSettings::default()
                .with_option("compression", c.name())
                .with_option("pixel", pixel);
            let bytes = ExrCodec.encode(&img, &settings).expect("a decoded image always encodes");
            let back = ExrCodec.decode(&bytes, &limits).expect("our own output always decodes");
            assert_eq!((back.width(), back.height(), back.channels()), (img.width(), img.height(), img.channels()));
        }
    }
});
