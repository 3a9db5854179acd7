//! Fuzz target for LogLuv TIFF (see `entry_points::logluv`).
//!
//!   cd fuzz && cargo fuzz run -s none logluv -- -max_total_time=30
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/logluv/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::logluv(data));
