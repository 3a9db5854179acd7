//! BC6H block decoder on arbitrary bytes (see `entry_points::bc6h_block`).
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/bc6h_block/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::bc6h_block(data));
