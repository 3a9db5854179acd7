//! MP4 box, sample-table, AV1/HEVC header and SEI parsing on arbitrary bytes: must return `Ok`
//! or `Err`, never panic, and never allocate past `Limits::fuzzing()` (see
//! `entry_points::mp4`).
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/mp4/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::mp4(data));
