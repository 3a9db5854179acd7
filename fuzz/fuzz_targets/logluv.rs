//! Fuzz target for LogLuv TIFF: the bounded TIFF/IFD reader, the SGILOG run-length decoder and
//! the conversion to an image, with `Limits::fuzzing()`. Whatever decodes must re-encode and read
//! back to the same words (our writer and reader agree on every raster the reader accepts).
//!
//!   cd fuzz && cargo fuzz run -s none logluv -- -max_total_time=30
#![no_main]

use hdrcodec_core::{ImageCodec, Limits};
use hdrcodec_logluv::{raster_to_image, read_tiff, DecodeOptions, Encoding, LogLuvTiffCodec};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let limits = Limits::fuzzing();
    let _ = LogLuvTiffCodec::new(Encoding::LogLuv32).decode(data, &limits);
    if let Ok(raster) = read_tiff(data, &limits) {
        let img = raster_to_image(&raster, &DecodeOptions::default()).expect("a raster always converts");
        assert_eq!(img.pixel_count(), raster.words.len());
        let again = read_tiff(&raster.to_tiff().expect("a raster always writes"), &limits).expect("our file reads");
        assert_eq!(again.words, raster.words);
    }
});
