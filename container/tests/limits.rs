//! A HEAD declaring 10^6 x 10^6 pixels fails with LimitExceeded without allocating: this test
//! binary counts every allocation made while the reader and the decoder look at such a file.

use hdrcodec_container::{crc32c, decode_image, RawF32Codec, Reader, SIGNATURE};
use hdrcodec_core::{Error, ImageCodec, Limits};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only records the largest request.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        LARGEST.fetch_max(l.size(), Ordering::Relaxed);
        // SAFETY: the caller's layout contract is passed on to the system allocator as is.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: `p` came from `alloc` above, i.e. from the system allocator, with layout `l`.
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn chunk(ty: &[u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut c = (payload.len() as u32).to_be_bytes().to_vec();
    c.extend_from_slice(ty);
    c.extend_from_slice(payload);
    let mut body = ty.to_vec();
    body.extend_from_slice(payload);
    c.extend_from_slice(&crc32c(&body).to_be_bytes());
    c
}

#[test]
fn a_million_by_a_million_head_fails_before_allocating() {
    // HEAD by hand, per README.md: version 1, 3 channels, codec RF32, 1e6 x 1e6, 1 frame,
    // one 1e6 x 1e6 tile; then a tiny DATA chunk and END, as a complete-looking file.
    let mut head = vec![1u8, 3];
    head.extend_from_slice(b"RF32");
    for v in [1_000_000u32, 1_000_000, 1, 1_000_000, 1_000_000] {
        head.extend_from_slice(&v.to_be_bytes());
    }
    let mut file = SIGNATURE.to_vec();
    file.extend(chunk(b"HEAD", &head));
    let mut data = [0u32, 0, 0, 1_000_000, 1_000_000].iter().flat_map(|v| v.to_be_bytes()).collect::<Vec<u8>>();
    data.extend_from_slice(b"RF32");
    file.extend(chunk(b"DATA", &data));
    file.extend(chunk(b"END ", &[]));

    LARGEST.store(0, Ordering::Relaxed);
    let e = Reader::new(&file, &Limits::default()).unwrap_err();
    assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
    let e = decode_image(&file, &Limits::none().into(), &|_| Some(&RawF32Codec as &dyn ImageCodec)).unwrap_err();
    // Without limits the 4-byte payload is what stops it, still before the frame is allocated.
    assert!(matches!(e, Error::Truncated { .. }), "{e}");
    let largest = LARGEST.load(Ordering::Relaxed);
    assert!(largest < 4096, "the largest allocation was {largest} bytes");
}
