//! OpenEXR decoder on arbitrary bytes: must return `Ok` or `Err`, never panic, and never
//! allocate past `Limits::fuzzing()` (see `entry_points::exr`).
//!
//! A panic inside the `exr` crate is caught by the codec and returned as `Error::Invalid`
//! ("... panicked ..."); libfuzzer-sys's panic hook would abort on it all the same. So the
//! target's hook ignores panics raised in the `exr` crate's own source files and passes every
//! other panic on to libfuzzer's aborting hook. Set `HDRCODEC_FUZZ_STRICT=1` to keep the
//! aborting hook for all panics and find the `exr` ones, to report upstream (known: B44
//! `unpack14` subtracts with overflow on corrupt blocks, exr 1.74.2
//! src/compression/b44/mod.rs:186-204, with overflow checks on as in fuzz and test builds).
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/exr/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

use std::sync::Once;

static HOOK: Once = Once::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
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
    entry_points::exr(data);
});
