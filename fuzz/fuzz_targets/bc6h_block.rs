//! BC6H block decoder on arbitrary bytes: every 16-byte block (both UF16 and SF16) must decode
//! without panicking, never to NaN, to +Inf never and to -Inf only in SF16 (a mode-14 endpoint of
//! -32768 finishes to 0xFC00, as the spec's arithmetic gives), and its fields must survive
//! unpack -> pack unchanged.
#![no_main]

use hdrcodec_bc6h::modes::{pack_block, unpack_block};
use hdrcodec_bc6h::{decode_block, decode_surface};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for chunk in data.chunks_exact(16) {
        let block: &[u8; 16] = chunk.try_into().unwrap();
        for signed in [false, true] {
            for texel in decode_block(block, signed) {
                for h in texel {
                    let finite = h & 0x7C00 != 0x7C00;
                    assert!(finite || (signed && h == 0xFC00), "half {h:#06x} from {block:02x?}");
                }
            }
        }
        if let Some(fields) = unpack_block(block) {
            assert_eq!(&pack_block(&fields), block);
        }
    }
    // The surface decoder with a width derived from the data: sizes that disagree are errors.
    if let Some(&w) = data.first() {
        let w = u32::from(w % 16) + 1;
        let blocks = data.len() / 16;
        let bx = w.div_ceil(4) as usize;
        let h = (blocks / bx.max(1)) as u32 * 4;
        let _ = decode_surface(w, h, &data[..data.len() - data.len() % 16], data.len() % 2 == 1);
    }
});
