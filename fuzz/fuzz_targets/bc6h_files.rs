//! BC6H DDS and KTX2 parsing on arbitrary bytes: `Ok` or `Err`, never a panic, never an
//! allocation past `Limits::fuzzing()`. A file that parses is written back and must read back
//! identically.
#![no_main]

use hdrcodec_bc6h::ktx2::read_ktx2_primaries;
use hdrcodec_bc6h::{read_dds, read_ktx2, write_dds, write_ktx2, Bc6hDdsCodec, Bc6hKtx2Codec};
use hdrcodec_core::{ImageCodec, Limits};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let limits = Limits::fuzzing();
    let _ = Bc6hDdsCodec.decode(data, &limits);
    let _ = Bc6hKtx2Codec.decode(data, &limits);
    if let Ok(tex) = read_dds(data, &limits) {
        let again = read_dds(&write_dds(&tex).expect("a parsed texture writes"), &limits).expect("reads back");
        assert_eq!(again, tex);
    }
    if let Ok(tex) = read_ktx2(data, &limits) {
        let primaries = read_ktx2_primaries(data);
        let written = write_ktx2(&tex, primaries).expect("a parsed texture writes, with the primaries it read");
        let again = read_ktx2(&written, &limits).expect("reads back");
        assert_eq!(again, tex);
        assert_eq!(read_ktx2_primaries(&written), primaries);
    }
});
