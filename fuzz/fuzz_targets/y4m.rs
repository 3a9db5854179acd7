//! YUV4MPEG2 header and frame parsing on arbitrary bytes: must return `Ok` or `Err`, never
//! panic, and never allocate past `Limits::fuzzing()` (see `entry_points::y4m`).
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/y4m/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::y4m(data));
