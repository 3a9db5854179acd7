//! Fuzz target for the `.hdrc` container (see `entry_points::container`). Built with
//! `--cfg fuzzing`, the reader accepts wrong CRCs so that mutations reach the chunk parsers
//! behind them (a real build rejects them).
//!
//!   cd fuzz && cargo fuzz run -s none container -- -max_total_time=30
#![no_main]

// The body is shared with the regression test `tests/fuzz_regressions.rs`, which replays the
// inputs of `fuzz/regressions/container/` through the same function.
#[path = "../entry_points.rs"]
#[allow(dead_code)]
mod entry_points;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entry_points::container(data));
