//! Every decoder of the registry writes into a caller's buffer (`ImageCodec::decode_into`):
//! `f32` or `f16`, with a stride, the same samples `decode` gives, allocating nothing of the
//! image's size: a decode into a caller's buffer fits a budget of a fraction of the image.

use hdrcodec::core::half::f16;
use hdrcodec::core::sink::FrameBufMut;
use hdrcodec::core::{Channels, ColorInfo, DecodeOptions, EncodeSettings, HdrImage, Limits};

fn photo(w: u32, h: u32) -> HdrImage {
    let samples = (0..w * h * 3)
        .map(|i| {
            let (x, y, c) = ((i / 3) % w, (i / 3) / w, i % 3);
            0.02 + ((x * 7 + y * 13 + c * 5) % 101) as f32 * 0.11 * (1.0 + (y % 17) as f32)
        })
        .collect();
    HdrImage::new(w, h, Channels::Rgb, samples, ColorInfo::default()).unwrap()
}

#[test]
fn every_decoder_fills_a_strided_f32_or_f16_buffer_within_a_small_budget() {
    // 9.4 MB decoded; the budget below is 6 MB: only band buffers may be allocated.
    let (w, h) = (1024u32, 768u32);
    let image = photo(w, h);
    let decoded = u64::from(w * h) * 3 * 4;
    let registry = hdrcodec::registry();
    let mut checked = Vec::new();
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let mut settings = EncodeSettings::default().with_effort(0);
        if codec.name() == "hdrc" {
            // Tiles bound what the container decodes at once.
            settings = settings.with_option("tile", "256");
        }
        let (file, _) = hdrcodec::encode_for(codec.as_ref(), &image, &settings).unwrap();
        let name = codec.name();
        let whole = codec.decode(&file, &Limits::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let row_len = w as usize * whole.channels().count();
        let stride = row_len + 5;
        // JPEG XR's band buffers are a fixed number of macroblock rows (about 21 rows of
        // coefficients and two 128-row bands of samples): on 768 rows, about the image's size
        // (on 13 MP, 3% of it). `decode` still needs more.
        let budget = if name == "jxr" { decoded * 5 / 4 } else { decoded * 2 / 3 };
        let limits = Limits::default().with_max_alloc_bytes(budget);
        let options = DecodeOptions::new(limits.clone());

        let mut f32_buf = vec![-7.0f32; stride * h as usize];
        let info = codec
            .decode_into(&file, &options, FrameBufMut::f32(&mut f32_buf, stride))
            .unwrap_or_else(|e| panic!("{name}: f32 into a caller's buffer: {e}"));
        assert_eq!((info.width, info.height, &info.color), (w, h, &whole.color), "{name}");
        assert_eq!(limits.in_use(), 0, "{name}: every charge returned");

        let mut f16_buf = vec![f16::from_f32(-7.0); stride * h as usize];
        codec
            .decode_into(&file, &options, FrameBufMut::f16(&mut f16_buf, stride))
            .unwrap_or_else(|e| panic!("{name}: f16 into a caller's buffer: {e}"));
        for y in 0..h as usize {
            let want = whole.row(y as u32);
            let got = &f32_buf[y * stride..y * stride + row_len];
            assert!(want.iter().zip(got).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}: row {y}");
            assert!(f32_buf[y * stride + row_len..(y + 1) * stride].iter().all(|&v| v == -7.0), "{name}: padding");
            let halves = &f16_buf[y * stride..y * stride + row_len];
            assert!(want.iter().zip(halves).all(|(a, b)| f16::from_f32(*a) == *b), "{name}: f16 row {y}");
        }
        // The same budget cannot hold the image that `decode` returns.
        assert!(codec.decode(&file, &limits).is_err(), "{name}: decode should not fit the budget");
        checked.push(name);
    }
    for name in [
        "exr",
        "pfm",
        "rgbe",
        "logluv32",
        "logluv24",
        "logl16",
        "bc6h",
        "bc6h-ktx2",
        "hdrc",
        "jxr",
        "ultrahdr",
        "jpeg-hdr",
    ] {
        assert!(checked.contains(&name), "{name} not checked: {checked:?}");
    }
}

#[test]
fn a_buffer_too_small_is_an_error_before_anything_is_written() {
    let image = photo(16, 8);
    for codec in hdrcodec::registry().codecs().iter().filter(|c| c.can_encode()) {
        let (file, _) = hdrcodec::encode_for(codec.as_ref(), &image, &EncodeSettings::default()).unwrap();
        let row_len = 16 * 3;
        let mut buf = vec![-1.0f32; row_len * 8 - 1];
        let r = codec.decode_into(&file, &DecodeOptions::default(), FrameBufMut::f32(&mut buf, row_len));
        assert!(r.is_err(), "{}", codec.name());
        assert!(buf.iter().all(|&v| v == -1.0), "{}: nothing written", codec.name());
    }
}
