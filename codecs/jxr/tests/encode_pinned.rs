//! Pins the exact bytes the encoder writes: speed work on the encoder (entropy coder, bit
//! writer, transform, quantization, sample conversion) must not change a single output byte.
//! Each case encodes a synthetic image with wide dynamic range (deep darks, highlights near the
//! half-float maximum, negative samples, sharp edges, noise) and compares the FNV-1a hash and
//! length of the file with the values the encoder wrote before the speed work (commit 68f942c).
//! A deliberate change of the format or of the encoder's choices updates the table; the test
//! prints every case's new value.

use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, HdrImage, ThreadPool};
use hdrcodec_jxr::encoder::{encode, EncodeOptions, SampleFormat};
use hdrcodec_jxr::transform::OverlapMode;

/// A deterministic test image: smooth gradients, a checkerboard of large ratios, xorshift noise,
/// a few negative and very bright samples; alpha a ramp with steps.
fn image(width: u32, height: u32, alpha: bool) -> HdrImage {
    let spp = if alpha { 4 } else { 3 };
    let mut x = 0x9E37_79B9u32;
    let mut noise = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        (x >> 8) as f32 / (1u32 << 24) as f32
    };
    let mut samples = Vec::with_capacity((width * height) as usize * spp);
    for y in 0..height {
        for x in 0..width {
            let (fx, fy) = (x as f32 / width as f32, y as f32 / height as f32);
            let checker = if (x / 7 + y / 5) % 2 == 0 { 1.0 } else { 0.002 };
            let base =
                (fx * 9.0 + fy * 3.0).sin().abs() * 4.0 * checker + fy * fy * 30.0 * (x > width / 2) as u32 as f32;
            for c in 0..3 {
                let mut v = base * (1.0 + 0.3 * c as f32) + noise() * 0.05 * (1.0 + base);
                if (x * 31 + y * 17 + c) % 97 == 0 {
                    v = 20000.0 + noise() * 40000.0;
                }
                if (x * 13 + y * 7 + c) % 89 == 0 {
                    v = -noise() * 0.5;
                }
                if y < 3 {
                    v *= 1e-5;
                }
                samples.push(v);
            }
            if alpha {
                samples.push(if x < width / 3 { 1.0 } else { (x + 2 * y) as f32 / (width + 2 * height) as f32 });
            }
        }
    }
    let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 80.0, hdr10: None };
    HdrImage::new(width, height, if alpha { Channels::Rgba } else { Channels::Rgb }, samples, color).unwrap()
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// (name, options): qualities from lossless to very coarse, each overlap, tiles, adaptive
/// quantization on and off, half and float, lossy alpha.
fn cases() -> Vec<(String, EncodeOptions)> {
    let mut out = Vec::new();
    for format in [SampleFormat::Half, SampleFormat::Float] {
        for quality in [100u8, 95, 90, 60, 30, 5] {
            for overlap in [None, Some(OverlapMode::None), Some(OverlapMode::Two)] {
                for (tile_mbs, adaptive) in [(0, true), (2, false)] {
                    let o = EncodeOptions { quality, overlap, format, tile_mbs, adaptive, ..EncodeOptions::default() };
                    out.push((format!("{format:?} q{quality} ol{overlap:?} tile{tile_mbs} adaptive {adaptive}"), o));
                }
            }
        }
    }
    out
}

#[test]
fn encoded_bytes_are_pinned() {
    let pool = ThreadPool::new(2).unwrap();
    let rgb = image(83, 61, false);
    let rgba = image(70, 45, true);
    let mut got = Vec::new();
    for (name, options) in cases() {
        let (file, _) = encode(&rgb, &options, &pool).unwrap();
        got.push((format!("rgb {name}"), fnv1a(&file), file.len()));
        // RGBA (planar alpha) at a few settings, alpha lossless and lossy.
        if options.tile_mbs == 0 && options.overlap.is_none() {
            for alpha_quality in [100, 50] {
                let o = EncodeOptions { alpha_quality, ..options.clone() };
                let (file, _) = encode(&rgba, &o, &pool).unwrap();
                got.push((format!("rgba a{alpha_quality} {name}"), fnv1a(&file), file.len()));
            }
        }
    }
    let table: Vec<String> = got.iter().map(|(n, h, l)| format!("    ({n:?}, 0x{h:016x}, {l}),")).collect();
    let want: Vec<String> = PINNED.iter().map(|(n, h, l)| format!("    ({n:?}, 0x{h:016x}, {l}),")).collect();
    assert!(table == want, "encoded bytes changed; the new table:\n{}", table.join("\n"));
}

/// (case, FNV-1a of the file, its length), written by the encoder at commit 68f942c.
const PINNED: &[(&str, u64, usize)] = &[
    ("rgb Half q100 olNone tile0 adaptive true", 0xaab9a7a0611780b2, 37703),
    ("rgba a100 Half q100 olNone tile0 adaptive true", 0xad94b2992739553b, 27182),
    ("rgba a50 Half q100 olNone tile0 adaptive true", 0x8870e0104ffa99e7, 25453),
    ("rgb Half q100 olNone tile2 adaptive false", 0x69a7d507e46c7a90, 46042),
    ("rgb Half q100 olSome(None) tile0 adaptive true", 0xdbef9f992260a0ec, 35109),
    ("rgb Half q100 olSome(None) tile2 adaptive false", 0x2b5bb784b3131f90, 40393),
    ("rgb Half q100 olSome(Two) tile0 adaptive true", 0x2e1c4b3290fa5bbe, 37618),
    ("rgb Half q100 olSome(Two) tile2 adaptive false", 0xe8959bb8279f154a, 46189),
    ("rgb Half q95 olNone tile0 adaptive true", 0x6b77748ce3f68832, 31638),
    ("rgba a100 Half q95 olNone tile0 adaptive true", 0x6e120befd51acca8, 23249),
    ("rgba a50 Half q95 olNone tile0 adaptive true", 0x974960d43331b496, 21520),
    ("rgb Half q95 olNone tile2 adaptive false", 0xaed289ff88a1b9c1, 40225),
    ("rgb Half q95 olSome(None) tile0 adaptive true", 0xd36b90aa6b5fff6f, 29672),
    ("rgb Half q95 olSome(None) tile2 adaptive false", 0xe1aa710e81e3ab6a, 34515),
    ("rgb Half q95 olSome(Two) tile0 adaptive true", 0x881c027e14024c4e, 31655),
    ("rgb Half q95 olSome(Two) tile2 adaptive false", 0x8058692e423c678b, 40235),
    ("rgb Half q90 olNone tile0 adaptive true", 0x33e30d7918b87480, 28940),
    ("rgba a100 Half q90 olNone tile0 adaptive true", 0x05eb1290c5a59975, 21465),
    ("rgba a50 Half q90 olNone tile0 adaptive true", 0x4b001fb9c37a6625, 19736),
    ("rgb Half q90 olNone tile2 adaptive false", 0x31e6f5969c3bb056, 37617),
    ("rgb Half q90 olSome(None) tile0 adaptive true", 0xa4bcdc253c2dc395, 27022),
    ("rgb Half q90 olSome(None) tile2 adaptive false", 0x046c2e89f9ecbebd, 32035),
    ("rgb Half q90 olSome(Two) tile0 adaptive true", 0x4fca2f6833f53561, 28955),
    ("rgb Half q90 olSome(Two) tile2 adaptive false", 0xa6bf039645c28187, 37645),
    ("rgb Half q60 olNone tile0 adaptive true", 0xa9ace1f0b38b69bd, 20873),
    ("rgba a100 Half q60 olNone tile0 adaptive true", 0xbd21fd412752a878, 15999),
    ("rgba a50 Half q60 olNone tile0 adaptive true", 0x77e3e5b9996939ae, 14270),
    ("rgb Half q60 olNone tile2 adaptive false", 0xac26c4c4a066585d, 26520),
    ("rgb Half q60 olSome(None) tile0 adaptive true", 0x19ce7becbbffaf97, 19265),
    ("rgb Half q60 olSome(None) tile2 adaptive false", 0x5d1832d71cff7a1d, 22480),
    ("rgb Half q60 olSome(Two) tile0 adaptive true", 0x2023feba02efb113, 20924),
    ("rgb Half q60 olSome(Two) tile2 adaptive false", 0xd065c0962c81a80c, 26613),
    ("rgb Half q30 olNone tile0 adaptive true", 0x8eb9822ed1ad7383, 13596),
    ("rgba a100 Half q30 olNone tile0 adaptive true", 0x21d0e3c7109a2acd, 10902),
    ("rgba a50 Half q30 olNone tile0 adaptive true", 0xb3354cbcea6d0da5, 9207),
    ("rgb Half q30 olNone tile2 adaptive false", 0xeea32a2668d6f0a5, 15260),
    ("rgb Half q30 olSome(None) tile0 adaptive true", 0x0be9bd0fce083734, 12342),
    ("rgb Half q30 olSome(None) tile2 adaptive false", 0xc293ec0eaec0aa8c, 13126),
    ("rgb Half q30 olSome(Two) tile0 adaptive true", 0x8eb9822ed1ad7383, 13596),
    ("rgb Half q30 olSome(Two) tile2 adaptive false", 0xeea32a2668d6f0a5, 15260),
    ("rgb Half q5 olNone tile0 adaptive true", 0x7983cf53f45b5c41, 8070),
    ("rgba a100 Half q5 olNone tile0 adaptive true", 0xb1dde5d2d58f45ef, 7247),
    ("rgba a50 Half q5 olNone tile0 adaptive true", 0x8e261fffc000cca5, 5552),
    ("rgb Half q5 olNone tile2 adaptive false", 0xf1acf3f2b69a72b1, 8554),
    ("rgb Half q5 olSome(None) tile0 adaptive true", 0xaaab5a59ad1a3ea3, 7162),
    ("rgb Half q5 olSome(None) tile2 adaptive false", 0x3e2f5adf1bca0250, 7418),
    ("rgb Half q5 olSome(Two) tile0 adaptive true", 0x7983cf53f45b5c41, 8070),
    ("rgb Half q5 olSome(Two) tile2 adaptive false", 0xf1acf3f2b69a72b1, 8554),
    ("rgb Float q100 olNone tile0 adaptive true", 0x7062eede96771df0, 43268),
    ("rgba a100 Float q100 olNone tile0 adaptive true", 0x1e6dc537cda46fc5, 32357),
    ("rgba a50 Float q100 olNone tile0 adaptive true", 0x9ba81cc358e8b3ff, 29983),
    ("rgb Float q100 olNone tile2 adaptive false", 0x4cd4609ceeff4e73, 50904),
    ("rgb Float q100 olSome(None) tile0 adaptive true", 0xa11c151d49603e1a, 40658),
    ("rgb Float q100 olSome(None) tile2 adaptive false", 0x2694adb2d1129aad, 45821),
    ("rgb Float q100 olSome(Two) tile0 adaptive true", 0x99eb9ce7c1f4d0a0, 43263),
    ("rgb Float q100 olSome(Two) tile2 adaptive false", 0x7ab71d5a8eeb0eef, 50837),
    ("rgb Float q95 olNone tile0 adaptive true", 0xf61491b115d6ef2d, 36812),
    ("rgba a100 Float q95 olNone tile0 adaptive true", 0xa1ede580481b4998, 27861),
    ("rgba a50 Float q95 olNone tile0 adaptive true", 0x34871786df6107d2, 25487),
    ("rgb Float q95 olNone tile2 adaptive false", 0x52290add2bd7068a, 45356),
    ("rgb Float q95 olSome(None) tile0 adaptive true", 0x13eaee6e2f319a2a, 34301),
    ("rgb Float q95 olSome(None) tile2 adaptive false", 0x34d99c89ba013d31, 39661),
    ("rgb Float q95 olSome(Two) tile0 adaptive true", 0x95b023725ab38143, 36797),
    ("rgb Float q95 olSome(Two) tile2 adaptive false", 0xe86cd929175692ff, 45253),
    ("rgb Float q90 olNone tile0 adaptive true", 0xaf6f4c9c4d3b958b, 34469),
    ("rgba a100 Float q90 olNone tile0 adaptive true", 0x854cf229505da40b, 26292),
    ("rgba a50 Float q90 olNone tile0 adaptive true", 0x3d8b237f09f54aad, 23918),
    ("rgb Float q90 olNone tile2 adaptive false", 0x0360752f8ae6737c, 43344),
    ("rgb Float q90 olSome(None) tile0 adaptive true", 0xae9b8ecfcf8402d4, 31932),
    ("rgb Float q90 olSome(None) tile2 adaptive false", 0xb72a65788240bf76, 37497),
    ("rgb Float q90 olSome(Two) tile0 adaptive true", 0x81db0876f1bcc923, 34405),
    ("rgb Float q90 olSome(Two) tile2 adaptive false", 0x9d61f922df57f1bc, 43257),
    ("rgb Float q60 olNone tile0 adaptive true", 0xb5ba518514d11ad8, 26657),
    ("rgba a100 Float q60 olNone tile0 adaptive true", 0x303fd7af6776d285, 21135),
    ("rgba a50 Float q60 olNone tile0 adaptive true", 0x4043bcde9b399e57, 18761),
    ("rgb Float q60 olNone tile2 adaptive false", 0x16f2645e74fb65a0, 34786),
    ("rgb Float q60 olSome(None) tile0 adaptive true", 0xd7b910b1530ff9aa, 24668),
    ("rgb Float q60 olSome(None) tile2 adaptive false", 0xfe6e3d21a2e9d9ed, 29225),
    ("rgb Float q60 olSome(Two) tile0 adaptive true", 0x56448af9b5547239, 26655),
    ("rgb Float q60 olSome(Two) tile2 adaptive false", 0x7c72a5a986f0e608, 34781),
    ("rgb Float q30 olNone tile0 adaptive true", 0x3b7581a02b4cada6, 19063),
    ("rgba a100 Float q30 olNone tile0 adaptive true", 0x3493e19db5dff3ab, 15897),
    ("rgba a50 Float q30 olNone tile0 adaptive true", 0xe7c96db0e691da70, 13575),
    ("rgb Float q30 olNone tile2 adaptive false", 0xc85066db14a4250a, 23624),
    ("rgb Float q30 olSome(None) tile0 adaptive true", 0xb1924a6d8b4d2154, 17434),
    ("rgb Float q30 olSome(None) tile2 adaptive false", 0xaccf08d4bfd4d9db, 19834),
    ("rgb Float q30 olSome(Two) tile0 adaptive true", 0x3b7581a02b4cada6, 19063),
    ("rgb Float q30 olSome(Two) tile2 adaptive false", 0xc85066db14a4250a, 23624),
    ("rgb Float q5 olNone tile0 adaptive true", 0x3048e2da2c814f23, 13035),
    ("rgba a100 Float q5 olNone tile0 adaptive true", 0x602c73fb7a462095, 11830),
    ("rgba a50 Float q5 olNone tile0 adaptive true", 0x0e1c318be6bcbca4, 9508),
    ("rgb Float q5 olNone tile2 adaptive false", 0x315852eea688a3bb, 14484),
    ("rgb Float q5 olSome(None) tile0 adaptive true", 0xae5ef6fe9852a49a, 11721),
    ("rgb Float q5 olSome(None) tile2 adaptive false", 0xf31dfada4d44ca37, 12249),
    ("rgb Float q5 olSome(Two) tile0 adaptive true", 0x3048e2da2c814f23, 13035),
    ("rgb Float q5 olSome(Two) tile2 adaptive false", 0x315852eea688a3bb, 14484),
];
