//! The example of README.md (the format's specification), built byte by byte from the page:
//! the writer must produce exactly these bytes and the reader must decode them.

use hdrcodec_container::{crc32c, decode_image, encode_image, RawF32Codec, Reader};
use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};

fn chunk(out: &mut Vec<u8>, ty: &[u8; 4], payload: &[u8]) {
    out.extend_from_slice(&(payload.len() as u32).to_be_bytes());
    let start = out.len();
    out.extend_from_slice(ty);
    out.extend_from_slice(payload);
    let crc = crc32c(&out[start..]);
    out.extend_from_slice(&crc.to_be_bytes());
}

fn readme_example() -> Vec<u8> {
    let mut f = vec![0x8B, 0x48, 0x44, 0x52, 0x43, 0x0D, 0x0A, 0x0A];
    #[rustfmt::skip]
    chunk(&mut f, b"HEAD", &[
        0x01, 0x03, 0x52, 0x46, 0x33, 0x32, 0, 0, 0, 1, 0, 0, 0, 1,
        0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1,
    ]);
    chunk(&mut f, b"COLR", &[0x01, 0x42, 0xC8, 0x00, 0x00]);
    assert_eq!(f.len(), 0x3F);
    #[rustfmt::skip]
    chunk(&mut f, b"DATA", &[
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 0, 1, 0, 0, 0, 1,
        0x52, 0x46, 0x33, 0x32, 0x01, 0, 0, 0, 0x01, 0, 0, 0, 0x03,
        0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00, 0x3F,
    ]);
    assert_eq!(f.len(), 0x78);
    #[rustfmt::skip]
    chunk(&mut f, b"INDX", &[
        0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0x3F,
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    ]);
    chunk(&mut f, b"END ", &[0, 0, 0, 0, 0, 0, 0, 0x78]);
    f
}

#[test]
fn the_readme_example_is_what_the_writer_writes_and_the_reader_reads() {
    let spec = readme_example();
    let img = HdrImage::new(1, 1, Channels::Rgb, vec![1.0, 2.0, 0.5], ColorInfo::default()).unwrap();
    let written = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), None).unwrap();
    assert_eq!(written, spec);
    let r = Reader::new(&spec, &Limits::default()).unwrap();
    assert_eq!((r.head().width, r.head().height, r.head().codec), (1, 1, *b"RF32"));
    let back = decode_image(&spec, &Limits::default().into(), &|_| Some(&RawF32Codec as &dyn ImageCodec)).unwrap();
    assert_eq!(back.samples(), &[1.0, 2.0, 0.5]);
}
