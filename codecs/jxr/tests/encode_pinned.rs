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

/// (case, FNV-1a of the file, its length), written by the encoder before the speed work was
/// merged (commit 2026-11-26 with adaptive LP quantizers, the last change of its choices).
const PINNED: &[(&str, u64, usize)] = &[
    ("rgb Half q100 olNone tile0 adaptive true", 0xaab9a7a0611780b2, 37703),
    ("rgba a100 Half q100 olNone tile0 adaptive true", 0xad94b2992739553b, 27182),
    ("rgba a50 Half q100 olNone tile0 adaptive true", 0x6b3e4ed25e83e62e, 25436),
    ("rgb Half q100 olNone tile2 adaptive false", 0x9e603cb225c571cb, 46042),
    ("rgb Half q100 olSome(None) tile0 adaptive true", 0xdbef9f992260a0ec, 35109),
    ("rgb Half q100 olSome(None) tile2 adaptive false", 0xf565fea60f1cf017, 40393),
    ("rgb Half q100 olSome(Two) tile0 adaptive true", 0x2e1c4b3290fa5bbe, 37618),
    ("rgb Half q100 olSome(Two) tile2 adaptive false", 0x4b9da1ff1c67c8f5, 46189),
    ("rgb Half q95 olNone tile0 adaptive true", 0xb9d98ed5d1e6c49a, 31654),
    ("rgba a100 Half q95 olNone tile0 adaptive true", 0x9ede812035ac7ac4, 23264),
    ("rgba a50 Half q95 olNone tile0 adaptive true", 0xec56ad7676d5f0c1, 21518),
    ("rgb Half q95 olNone tile2 adaptive false", 0x1e9f512fff11fadc, 40225),
    ("rgb Half q95 olSome(None) tile0 adaptive true", 0xec681805fe45757d, 29688),
    ("rgb Half q95 olSome(None) tile2 adaptive false", 0x12a646f5965983cf, 34515),
    ("rgb Half q95 olSome(Two) tile0 adaptive true", 0xfa92904acbacc4c8, 31671),
    ("rgb Half q95 olSome(Two) tile2 adaptive false", 0x0f09a17eaa337bdc, 40235),
    ("rgb Half q90 olNone tile0 adaptive true", 0xbf07641e2dfcb958, 28957),
    ("rgba a100 Half q90 olNone tile0 adaptive true", 0x7e2ade3f5e0f6f4d, 21480),
    ("rgba a50 Half q90 olNone tile0 adaptive true", 0xe5a1c8221791ac30, 19734),
    ("rgb Half q90 olNone tile2 adaptive false", 0xadfc847ea874d55b, 37617),
    ("rgb Half q90 olSome(None) tile0 adaptive true", 0x1e8d52e772296a90, 27039),
    ("rgb Half q90 olSome(None) tile2 adaptive false", 0x6e068dfeed32202e, 32035),
    ("rgb Half q90 olSome(Two) tile0 adaptive true", 0x9cad33f9b8d2012e, 28971),
    ("rgb Half q90 olSome(Two) tile2 adaptive false", 0xb6d90d0f9784ec20, 37645),
    ("rgb Half q60 olNone tile0 adaptive true", 0xe7e6cb7716979ef0, 20889),
    ("rgba a100 Half q60 olNone tile0 adaptive true", 0xa48ba8c28e52402c, 16013),
    ("rgba a50 Half q60 olNone tile0 adaptive true", 0xd34a999e780e7ad7, 14267),
    ("rgb Half q60 olNone tile2 adaptive false", 0x1f48d8621281c17a, 26520),
    ("rgb Half q60 olSome(None) tile0 adaptive true", 0xe04bf17a90e7b4e6, 19277),
    ("rgb Half q60 olSome(None) tile2 adaptive false", 0xf9c9bf744fd44aec, 22474),
    ("rgb Half q60 olSome(Two) tile0 adaptive true", 0x5888c62ef10cb96d, 20939),
    ("rgb Half q60 olSome(Two) tile2 adaptive false", 0x0df72b6ab1e3365d, 26614),
    ("rgb Half q30 olNone tile0 adaptive true", 0x43573781a9f9bc7c, 13612),
    ("rgba a100 Half q30 olNone tile0 adaptive true", 0x122e3b1dde4a286c, 10959),
    ("rgba a50 Half q30 olNone tile0 adaptive true", 0xec801b8908b11257, 9213),
    ("rgb Half q30 olNone tile2 adaptive false", 0xb7e370cda3f08ac3, 15260),
    ("rgb Half q30 olSome(None) tile0 adaptive true", 0x578cbf5278e2be51, 12358),
    ("rgb Half q30 olSome(None) tile2 adaptive false", 0x64ff343ddf96bed3, 13124),
    ("rgb Half q30 olSome(Two) tile0 adaptive true", 0x43573781a9f9bc7c, 13612),
    ("rgb Half q30 olSome(Two) tile2 adaptive false", 0xb7e370cda3f08ac3, 15260),
    ("rgb Half q5 olNone tile0 adaptive true", 0x6de8be179b8dfc99, 8084),
    ("rgba a100 Half q5 olNone tile0 adaptive true", 0x32425dc7ec9513e7, 7302),
    ("rgba a50 Half q5 olNone tile0 adaptive true", 0xc0c177342e0bc952, 5556),
    ("rgb Half q5 olNone tile2 adaptive false", 0xcf1bd4bb5164e02b, 8554),
    ("rgb Half q5 olSome(None) tile0 adaptive true", 0x54c706d3518c3673, 7168),
    ("rgb Half q5 olSome(None) tile2 adaptive false", 0x9e935392aa1c38c3, 7405),
    ("rgb Half q5 olSome(Two) tile0 adaptive true", 0x6de8be179b8dfc99, 8084),
    ("rgb Half q5 olSome(Two) tile2 adaptive false", 0xcf1bd4bb5164e02b, 8554),
    ("rgb Float q100 olNone tile0 adaptive true", 0x7062eede96771df0, 43268),
    ("rgba a100 Float q100 olNone tile0 adaptive true", 0x1e6dc537cda46fc5, 32357),
    ("rgba a50 Float q100 olNone tile0 adaptive true", 0x9ba81cc358e8b3ff, 29983),
    ("rgb Float q100 olNone tile2 adaptive false", 0x4ba056130944cc92, 50904),
    ("rgb Float q100 olSome(None) tile0 adaptive true", 0xa11c151d49603e1a, 40658),
    ("rgb Float q100 olSome(None) tile2 adaptive false", 0x09dfd9e8510fa550, 45821),
    ("rgb Float q100 olSome(Two) tile0 adaptive true", 0x99eb9ce7c1f4d0a0, 43263),
    ("rgb Float q100 olSome(Two) tile2 adaptive false", 0xf27b592b650a0182, 50837),
    ("rgb Float q95 olNone tile0 adaptive true", 0x551cb59eaa0b5019, 36828),
    ("rgba a100 Float q95 olNone tile0 adaptive true", 0x78551f51769c2240, 27876),
    ("rgba a50 Float q95 olNone tile0 adaptive true", 0x15c4242a53137fea, 25502),
    ("rgb Float q95 olNone tile2 adaptive false", 0x295a81a51b8126d1, 45356),
    ("rgb Float q95 olSome(None) tile0 adaptive true", 0x0873c00e7ddaf289, 34318),
    ("rgb Float q95 olSome(None) tile2 adaptive false", 0x046214bd30b1d2c8, 39661),
    ("rgb Float q95 olSome(Two) tile0 adaptive true", 0x8bfee16b5b126637, 36814),
    ("rgb Float q95 olSome(Two) tile2 adaptive false", 0x489f3e9eac7ed480, 45253),
    ("rgb Float q90 olNone tile0 adaptive true", 0x2c76f54c5e5f149c, 34485),
    ("rgba a100 Float q90 olNone tile0 adaptive true", 0x27a95882ac6e150e, 26307),
    ("rgba a50 Float q90 olNone tile0 adaptive true", 0x69694c832f114d7c, 23933),
    ("rgb Float q90 olNone tile2 adaptive false", 0x55df1f9c2eccbbe5, 43344),
    ("rgb Float q90 olSome(None) tile0 adaptive true", 0x65daefb22139499d, 31949),
    ("rgb Float q90 olSome(None) tile2 adaptive false", 0xaa03772be2ac3859, 37497),
    ("rgb Float q90 olSome(Two) tile0 adaptive true", 0x15ddbe0841f2c10d, 34422),
    ("rgb Float q90 olSome(Two) tile2 adaptive false", 0x12781b0524ded44d, 43257),
    ("rgb Float q60 olNone tile0 adaptive true", 0x622f9851dae80bf8, 26673),
    ("rgba a100 Float q60 olNone tile0 adaptive true", 0x248f4b904cd1c9a9, 21150),
    ("rgba a50 Float q60 olNone tile0 adaptive true", 0x6808f5dbf1a15d8b, 18776),
    ("rgb Float q60 olNone tile2 adaptive false", 0x2103aa4e73d7cbb5, 34786),
    ("rgb Float q60 olSome(None) tile0 adaptive true", 0xf0d686e80080f0b5, 24684),
    ("rgb Float q60 olSome(None) tile2 adaptive false", 0xf9e57a094084bf5e, 29225),
    ("rgb Float q60 olSome(Two) tile0 adaptive true", 0x5f88c7983bc83a44, 26671),
    ("rgb Float q60 olSome(Two) tile2 adaptive false", 0x89d6821d6005b5cb, 34781),
    ("rgb Float q30 olNone tile0 adaptive true", 0x2e9ea899a81eda47, 19078),
    ("rgba a100 Float q30 olNone tile0 adaptive true", 0x53b512654e82cc5c, 15980),
    ("rgba a50 Float q30 olNone tile0 adaptive true", 0xb3849e27dc0f2fa2, 13606),
    ("rgb Float q30 olNone tile2 adaptive false", 0x83c0f4e3280d1ef1, 23622),
    ("rgb Float q30 olSome(None) tile0 adaptive true", 0xcf18b1f5f3a88a18, 17447),
    ("rgb Float q30 olSome(None) tile2 adaptive false", 0x3d33924ffa4e32d5, 19831),
    ("rgb Float q30 olSome(Two) tile0 adaptive true", 0x2e9ea899a81eda47, 19078),
    ("rgb Float q30 olSome(Two) tile2 adaptive false", 0x83c0f4e3280d1ef1, 23622),
    ("rgb Float q5 olNone tile0 adaptive true", 0xc8f000d8af325bd7, 13051),
    ("rgba a100 Float q5 olNone tile0 adaptive true", 0xee26cf0df6578f09, 11913),
    ("rgba a50 Float q5 olNone tile0 adaptive true", 0x64aa7529d830f59b, 9539),
    ("rgb Float q5 olNone tile2 adaptive false", 0xa764770f5ab36b14, 14482),
    ("rgb Float q5 olSome(None) tile0 adaptive true", 0x41b66585c536284c, 11733),
    ("rgb Float q5 olSome(None) tile2 adaptive false", 0xedcaef7a0d6eb31b, 12244),
    ("rgb Float q5 olSome(Two) tile0 adaptive true", 0xc8f000d8af325bd7, 13051),
    ("rgb Float q5 olSome(Two) tile2 adaptive false", 0xa764770f5ab36b14, 14482),
];
