//! Pins the exact bytes the encoder writes: speed work on the encoder (entropy coder, bit
//! writer, transform, quantization, sample conversion) must not change a single output byte.
//! Each case encodes a synthetic image with wide dynamic range (deep darks, highlights near the
//! half-float maximum, negative samples, sharp edges, noise) and compares the FNV-1a hash and
//! length of the file with the values the encoder wrote before the speed work was merged.
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

/// (case, FNV-1a of the file, its length), written by the encoder since its last deliberate
/// change (the most used adaptive quantizer set listed first, and lossless alpha coded with
/// no overlap or one stage, the smaller, 2026-11-26; the speed work before it was checked
/// against the table of the encoder it started from).
const PINNED: &[(&str, u64, usize)] = &[
    ("rgb Half q100 olNone tile0 adaptive true", 0xaab9a7a0611780b2, 37703),
    ("rgba a100 Half q100 olNone tile0 adaptive true", 0xd1d76335fa76d317, 27167),
    ("rgba a50 Half q100 olNone tile0 adaptive true", 0x6b3e4ed25e83e62e, 25436),
    ("rgb Half q100 olNone tile2 adaptive false", 0x9e603cb225c571cb, 46042),
    ("rgb Half q100 olSome(None) tile0 adaptive true", 0xdbef9f992260a0ec, 35109),
    ("rgb Half q100 olSome(None) tile2 adaptive false", 0xf565fea60f1cf017, 40393),
    ("rgb Half q100 olSome(Two) tile0 adaptive true", 0x2e1c4b3290fa5bbe, 37618),
    ("rgb Half q100 olSome(Two) tile2 adaptive false", 0x4b9da1ff1c67c8f5, 46189),
    ("rgb Half q95 olNone tile0 adaptive true", 0xdb49c0ad71aebc53, 31672),
    ("rgba a100 Half q95 olNone tile0 adaptive true", 0xf05d6d5f4c193b63, 23267),
    ("rgba a50 Half q95 olNone tile0 adaptive true", 0xb8d8d64ab9f71d7e, 21536),
    ("rgb Half q95 olNone tile2 adaptive false", 0x1e9f512fff11fadc, 40225),
    ("rgb Half q95 olSome(None) tile0 adaptive true", 0x37a383e83617e298, 29706),
    ("rgb Half q95 olSome(None) tile2 adaptive false", 0x12a646f5965983cf, 34515),
    ("rgb Half q95 olSome(Two) tile0 adaptive true", 0x979e06da5e848603, 31689),
    ("rgb Half q95 olSome(Two) tile2 adaptive false", 0x0f09a17eaa337bdc, 40235),
    ("rgb Half q90 olNone tile0 adaptive true", 0x684e5aed0e4c3ad0, 28975),
    ("rgba a100 Half q90 olNone tile0 adaptive true", 0xfd6b35bf24d1b83b, 21483),
    ("rgba a50 Half q90 olNone tile0 adaptive true", 0x09f64bcf6c660ea2, 19752),
    ("rgb Half q90 olNone tile2 adaptive false", 0xadfc847ea874d55b, 37617),
    ("rgb Half q90 olSome(None) tile0 adaptive true", 0xf60c8fb281b5ecc0, 27057),
    ("rgb Half q90 olSome(None) tile2 adaptive false", 0x6e068dfeed32202e, 32035),
    ("rgb Half q90 olSome(Two) tile0 adaptive true", 0x319b4fddbdcfd41e, 28989),
    ("rgb Half q90 olSome(Two) tile2 adaptive false", 0xb6d90d0f9784ec20, 37645),
    ("rgb Half q60 olNone tile0 adaptive true", 0x98e2ddaca811ed4a, 20907),
    ("rgba a100 Half q60 olNone tile0 adaptive true", 0x731311b2bbe492d0, 16016),
    ("rgba a50 Half q60 olNone tile0 adaptive true", 0x841159575e8ccb67, 14285),
    ("rgb Half q60 olNone tile2 adaptive false", 0x1f48d8621281c17a, 26520),
    ("rgb Half q60 olSome(None) tile0 adaptive true", 0x5018b190a5efd7b8, 19295),
    ("rgb Half q60 olSome(None) tile2 adaptive false", 0xf9c9bf744fd44aec, 22474),
    ("rgb Half q60 olSome(Two) tile0 adaptive true", 0x2b86ec1308fbec4f, 20957),
    ("rgb Half q60 olSome(Two) tile2 adaptive false", 0x0df72b6ab1e3365d, 26614),
    ("rgb Half q30 olNone tile0 adaptive true", 0x2a41db68ef969dd0, 13630),
    ("rgba a100 Half q30 olNone tile0 adaptive true", 0x90c4c453b902fc2a, 10962),
    ("rgba a50 Half q30 olNone tile0 adaptive true", 0x54250204fa8865b9, 9231),
    ("rgb Half q30 olNone tile2 adaptive false", 0xb7e370cda3f08ac3, 15260),
    ("rgb Half q30 olSome(None) tile0 adaptive true", 0x565550d319918b91, 12376),
    ("rgb Half q30 olSome(None) tile2 adaptive false", 0x64ff343ddf96bed3, 13124),
    ("rgb Half q30 olSome(Two) tile0 adaptive true", 0x2a41db68ef969dd0, 13630),
    ("rgb Half q30 olSome(Two) tile2 adaptive false", 0xb7e370cda3f08ac3, 15260),
    ("rgb Half q5 olNone tile0 adaptive true", 0x691eee6a7fb0cd70, 8102),
    ("rgba a100 Half q5 olNone tile0 adaptive true", 0x42e8fb334f17d37a, 7305),
    ("rgba a50 Half q5 olNone tile0 adaptive true", 0xc30becc48e8bcaed, 5574),
    ("rgb Half q5 olNone tile2 adaptive false", 0xcf1bd4bb5164e02b, 8554),
    ("rgb Half q5 olSome(None) tile0 adaptive true", 0x9e141eabe482fafe, 7186),
    ("rgb Half q5 olSome(None) tile2 adaptive false", 0x9e935392aa1c38c3, 7405),
    ("rgb Half q5 olSome(Two) tile0 adaptive true", 0x691eee6a7fb0cd70, 8102),
    ("rgb Half q5 olSome(Two) tile2 adaptive false", 0xcf1bd4bb5164e02b, 8554),
    ("rgb Float q100 olNone tile0 adaptive true", 0x7062eede96771df0, 43268),
    ("rgba a100 Float q100 olNone tile0 adaptive true", 0xa61eee1a215d0e7a, 31871),
    ("rgba a50 Float q100 olNone tile0 adaptive true", 0x9ba81cc358e8b3ff, 29983),
    ("rgb Float q100 olNone tile2 adaptive false", 0x4ba056130944cc92, 50904),
    ("rgb Float q100 olSome(None) tile0 adaptive true", 0xa11c151d49603e1a, 40658),
    ("rgb Float q100 olSome(None) tile2 adaptive false", 0x09dfd9e8510fa550, 45821),
    ("rgb Float q100 olSome(Two) tile0 adaptive true", 0x99eb9ce7c1f4d0a0, 43263),
    ("rgb Float q100 olSome(Two) tile2 adaptive false", 0xf27b592b650a0182, 50837),
    ("rgb Float q95 olNone tile0 adaptive true", 0x573c373902e7e028, 36846),
    ("rgba a100 Float q95 olNone tile0 adaptive true", 0x975735240ac9df08, 27408),
    ("rgba a50 Float q95 olNone tile0 adaptive true", 0x5871871b27b0b839, 25520),
    ("rgb Float q95 olNone tile2 adaptive false", 0x295a81a51b8126d1, 45356),
    ("rgb Float q95 olSome(None) tile0 adaptive true", 0x1d3377eecd409a78, 34336),
    ("rgb Float q95 olSome(None) tile2 adaptive false", 0x046214bd30b1d2c8, 39661),
    ("rgb Float q95 olSome(Two) tile0 adaptive true", 0x51e6ee01733713ee, 36832),
    ("rgb Float q95 olSome(Two) tile2 adaptive false", 0x489f3e9eac7ed480, 45253),
    ("rgb Float q90 olNone tile0 adaptive true", 0xb4cc7f037bf87594, 34503),
    ("rgba a100 Float q90 olNone tile0 adaptive true", 0x474a1600b40c86eb, 25839),
    ("rgba a50 Float q90 olNone tile0 adaptive true", 0x77b52a8a97dae1f6, 23951),
    ("rgb Float q90 olNone tile2 adaptive false", 0x55df1f9c2eccbbe5, 43344),
    ("rgb Float q90 olSome(None) tile0 adaptive true", 0x8924034b2e1e0e3d, 31967),
    ("rgb Float q90 olSome(None) tile2 adaptive false", 0xaa03772be2ac3859, 37497),
    ("rgb Float q90 olSome(Two) tile0 adaptive true", 0x7959b66ce20fce84, 34440),
    ("rgb Float q90 olSome(Two) tile2 adaptive false", 0x12781b0524ded44d, 43257),
    ("rgb Float q60 olNone tile0 adaptive true", 0x62dc38d14b13a602, 26691),
    ("rgba a100 Float q60 olNone tile0 adaptive true", 0x2d037241c3f93912, 20682),
    ("rgba a50 Float q60 olNone tile0 adaptive true", 0x23221acb05dd40f7, 18794),
    ("rgb Float q60 olNone tile2 adaptive false", 0x2103aa4e73d7cbb5, 34786),
    ("rgb Float q60 olSome(None) tile0 adaptive true", 0x00dc5e86a2f3354a, 24702),
    ("rgb Float q60 olSome(None) tile2 adaptive false", 0xf9e57a094084bf5e, 29225),
    ("rgb Float q60 olSome(Two) tile0 adaptive true", 0xc6df51a7137c329a, 26689),
    ("rgb Float q60 olSome(Two) tile2 adaptive false", 0x89d6821d6005b5cb, 34781),
    ("rgb Float q30 olNone tile0 adaptive true", 0x512da88e1c634933, 19096),
    ("rgba a100 Float q30 olNone tile0 adaptive true", 0x2dae0a138f91823d, 15512),
    ("rgba a50 Float q30 olNone tile0 adaptive true", 0xd694dc6b64b8e184, 13624),
    ("rgb Float q30 olNone tile2 adaptive false", 0x83c0f4e3280d1ef1, 23622),
    ("rgb Float q30 olSome(None) tile0 adaptive true", 0x084238185832ced8, 17465),
    ("rgb Float q30 olSome(None) tile2 adaptive false", 0x3d33924ffa4e32d5, 19831),
    ("rgb Float q30 olSome(Two) tile0 adaptive true", 0x512da88e1c634933, 19096),
    ("rgb Float q30 olSome(Two) tile2 adaptive false", 0x83c0f4e3280d1ef1, 23622),
    ("rgb Float q5 olNone tile0 adaptive true", 0xe82c66a68e3cc998, 13069),
    ("rgba a100 Float q5 olNone tile0 adaptive true", 0x611d4e98452bfe0f, 11445),
    ("rgba a50 Float q5 olNone tile0 adaptive true", 0x455b96717910e702, 9557),
    ("rgb Float q5 olNone tile2 adaptive false", 0xa764770f5ab36b14, 14482),
    ("rgb Float q5 olSome(None) tile0 adaptive true", 0x80eb41f6840dacfb, 11751),
    ("rgb Float q5 olSome(None) tile2 adaptive false", 0xedcaef7a0d6eb31b, 12244),
    ("rgb Float q5 olSome(Two) tile0 adaptive true", 0xe82c66a68e3cc998, 13069),
    ("rgb Float q5 olSome(Two) tile2 adaptive false", 0xa764770f5ab36b14, 14482),
];
