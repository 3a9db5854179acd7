//! Fuzz target for the `.hdrc` container: the validating `Reader` and the whole decode path
//! (`decode_frames` with the raw payload codecs, `HdrcCodec::decode`) and the index-driven
//! `SeekReader`, with `Limits::fuzzing()`.
//! Built with `--cfg fuzzing`, the reader accepts wrong CRCs so that mutations reach the chunk
//! parsers behind them (a real build rejects them).
//!
//!   cd fuzz && cargo fuzz run -s none container -- -max_total_time=30
#![no_main]

use hdrcodec_container::{decode_frames, HdrcCodec, RawF16Codec, RawF32Codec, Reader, SeekReader};
use hdrcodec_core::{ImageCodec, Limits};
use libfuzzer_sys::fuzz_target;

fn raw(id: [u8; 4]) -> Option<&'static dyn ImageCodec> {
    match &id {
        b"RF32" => Some(&RawF32Codec),
        b"RF16" => Some(&RawF16Codec),
        _ => None,
    }
}

fuzz_target!(|data: &[u8]| {
    let limits = Limits::fuzzing();
    if let Ok(r) = Reader::new(data, &limits) {
        let h = *r.head();
        let _ = (r.color(), r.hdr10(), r.metadata(), r.color_info());
        // Every tile the grid promises is there, and random access finds exactly it.
        for d in r.data_chunks() {
            let (c, row) = (d.header.x / h.tile_width, d.header.y / h.tile_height);
            assert_eq!(r.tile(d.header.frame, c, row).map(|t| t.offset), Some(d.offset));
        }
        assert_eq!(r.data_chunks().len() as u64, u64::from(h.frames) * h.tiles_per_frame());
        if let Ok(frames) = decode_frames(data, &limits.clone().into(), &raw) {
            assert_eq!(frames.len() as u64, u64::from(h.frames));
            for f in &frames {
                assert_eq!((f.width(), f.height(), f.channels()), (h.width, h.height, h.channels));
            }
        }
    }
    let _ = HdrcCodec::default().decode(data, &limits);
    if let Ok(mut s) = SeekReader::new(std::io::Cursor::new(data), &limits) {
        let h = *s.head();
        // Bounded: `new` checked that the file can hold a DATA chunk per tile.
        for f in 0..h.frames {
            for row in 0..h.tile_rows() {
                for c in 0..h.tile_columns() {
                    if let Ok((t, _)) = s.read_tile(f, c, row) {
                        assert_eq!(t, h.tile(f, c, row));
                    }
                }
            }
        }
    }
});
