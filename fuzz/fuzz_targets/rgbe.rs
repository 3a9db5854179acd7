//! Radiance RGBE decoder on arbitrary bytes: must return `Ok` or `Err`, never panic, and never
//! allocate past `Limits::fuzzing()`. Both mantissa modes and the raw/exposure paths run, and a
//! successful decode is re-encoded (both roundings) and decoded again.
#![no_main]

use hdrcodec_core::Limits;
use hdrcodec_rgbe::{decode, encode, MantissaDecode, RgbeDecodeOptions, RgbeEncodeOptions, Rounding};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let limits = Limits::fuzzing();
    let flags = data.first().copied().unwrap_or(0);
    let opts = RgbeDecodeOptions {
        apply_exposure: flags & 1 == 1,
        mantissa: if flags & 2 == 2 { MantissaDecode::Centred } else { MantissaDecode::Truncated },
    };
    let _ = hdrcodec_rgbe::read_header(data);
    if let Ok(img) = decode(data, &limits, &opts) {
        if img.pixel_count() <= 1 << 16 {
            let rounding = if flags & 4 == 4 { Rounding::Nearest } else { Rounding::Truncate };
            let bytes = encode(&img, &RgbeEncodeOptions { rounding, rle: flags & 8 == 0, ..Default::default() })
                .expect("a decoded image always encodes");
            let back = decode(&bytes, &limits, &opts).expect("our own output always decodes");
            assert_eq!((back.width(), back.height()), (img.width(), img.height()));
        }
    }
});
