//! PFM decoder on arbitrary bytes: must return `Ok` or `Err`, never panic, and never allocate
//! past `Limits::fuzzing()`. A successful decode is re-encoded and must decode to the same
//! samples (bitwise: PFM stores `f32` exactly).
#![no_main]

use hdrcodec_core::{EncodeSettings, ImageCodec, Limits};
use hdrcodec_pfm::PfmCodec;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let limits = Limits::fuzzing();
    if let Ok(img) = PfmCodec.decode(data, &limits) {
        let bytes = PfmCodec.encode(&img, &EncodeSettings::default()).expect("a decoded image always encodes");
        let back = PfmCodec.decode(&bytes, &limits).expect("our own output always decodes");
        let same = img.samples().iter().zip(back.samples()).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same && img.samples().len() == back.samples().len(), "PFM round trip changed samples");
    }
});
