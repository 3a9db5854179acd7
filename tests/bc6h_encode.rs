//! The BC6H encoder checked against independent code: every block it writes is decoded by
//! `bcdec_rs` and must give exactly the texels the encoder believed it encoded (all 14 modes,
//! UF16 and SF16, random and corpus content); bad inputs (NaN, Inf, negatives) give sane blocks;
//! and its quality (RMSLE, PU21-PSNR, ΔE ITP) is compared with Intel's ISPC compressor
//! (`intel_tex_2`) and the `block_compression` crate on the same images.
mod common;
#[path = "common/bc6h_peers.rs"]
mod peers;

// Linking the facade crate brings in its build script's `-lstdc++`, which intel_tex_2 needs.
use hdrcodec as _;
use hdrcodec_bc6h::encode::{encode_block, encode_block_in_mode, encode_surface, f32_to_bc6h_half, EncodeOptions};
use hdrcodec_core::{metrics, Channels, ColorInfo, HdrImage};

use common::Rng;

/// Random half-float blocks of several kinds: uniform over all finite halves, smooth blocks
/// (small variations around a base, which the delta modes can hold), and two-colour blocks.
fn random_block(rng: &mut Rng, kind: u32, signed: bool) -> [[u16; 3]; 16] {
    let sign = |rng: &mut Rng| if signed && rng.below(2) == 1 { 0x8000u16 } else { 0 };
    let mut block = [[0u16; 3]; 16];
    match kind {
        0 => {
            for t in block.iter_mut() {
                for v in t.iter_mut() {
                    *v = rng.below(0x7C00) as u16 | sign(rng);
                }
            }
        }
        1 => {
            let base: [u32; 3] = std::array::from_fn(|_| rng.below(0x7000) + 0x400);
            let spread = 1 << rng.below(10);
            let s = sign(rng);
            for t in block.iter_mut() {
                for (c, v) in t.iter_mut().enumerate() {
                    *v = (base[c] + rng.below(spread)).min(0x7BFF) as u16 | s;
                }
            }
        }
        _ => {
            let colours: [[u16; 3]; 2] = std::array::from_fn(|_| std::array::from_fn(|_| rng.below(0x7C00) as u16));
            let mask = rng.next() as u16;
            for (i, t) in block.iter_mut().enumerate() {
                let col = colours[((mask >> i) & 1) as usize];
                for c in 0..3 {
                    t[c] = (col[c] as u32 + rng.below(64)).min(0x7BFF) as u16;
                }
            }
        }
    }
    block
}

fn bcdec(bytes: &[u8; 16], signed: bool) -> [[u16; 3]; 16] {
    let mut out = [0u16; 48];
    bcdec_rs::bc6h_half(bytes, &mut out, 12, signed);
    std::array::from_fn(|i| [out[3 * i], out[3 * i + 1], out[3 * i + 2]])
}

/// The mode number in a block's first bits (2-bit modes 1 and 2, else a 5-bit value).
fn mode_of(bytes: &[u8; 16]) -> u8 {
    match bytes[0] & 3 {
        0 => 1,
        1 => 2,
        _ => match bytes[0] & 31 {
            0x02 => 3,
            0x06 => 4,
            0x0a => 5,
            0x0e => 6,
            0x12 => 7,
            0x16 => 8,
            0x1a => 9,
            0x1e => 10,
            0x03 => 11,
            0x07 => 12,
            0x0b => 13,
            0x0f => 14,
            _ => 0,
        },
    }
}

/// Forces every mode, UF16 and SF16, on random blocks: bcdec_rs must decode each block to
/// exactly what the encoder reported, and the block must carry the forced mode.
#[test]
fn every_mode_decodes_with_bcdec_as_the_encoder_believes() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut checked = 0;
    for signed in [false, true] {
        for mode in 1..=14u8 {
            for n in 0..150 {
                let block = random_block(&mut rng, n % 3, signed);
                let effort = [1, 4, 9][n as usize % 3];
                let enc = encode_block_in_mode(&block, signed, effort, mode).unwrap();
                assert_eq!(enc.mode, mode);
                assert_eq!(mode_of(&enc.bytes), mode, "mode field");
                assert_eq!(bcdec(&enc.bytes, signed), enc.decoded, "mode {mode} signed {signed} block {block:?}");
                checked += 1;
            }
        }
    }
    assert_eq!(encode_block_in_mode(&[[0; 3]; 16], false, 5, 15), None);
    eprintln!("{checked} forced-mode blocks decode identically in bcdec_rs");
}

/// Free mode choice at every effort, random blocks: same check, and more effort never loses.
#[test]
fn free_search_decodes_with_bcdec_and_effort_helps() {
    let mut rng = Rng(42);
    for signed in [false, true] {
        let (mut err0, mut err9) = (0u64, 0u64);
        for n in 0..300 {
            let block = random_block(&mut rng, n % 3, signed);
            for effort in 0..=9 {
                let enc = encode_block(&block, signed, effort);
                assert_eq!(bcdec(&enc.bytes, signed), enc.decoded, "effort {effort} signed {signed}");
                if effort == 0 {
                    err0 += enc.error;
                }
                if effort == 9 {
                    err9 += enc.error;
                }
            }
        }
        assert!(err9 < err0, "signed {signed}: effort 9 error {err9} not below effort 0 error {err0}");
    }
}

/// Corpus content (Radiance .hdr decoded by the `image` crate), UF16 and SF16 (negated copies
/// for SF16), several efforts: bcdec_rs agrees with the encoder on every block, and
/// `encode_surface` writes the same blocks single- and multi-threaded.
#[test]
fn corpus_blocks_decode_with_bcdec_as_the_encoder_believes() {
    let Some(dir) = common::require(common::corpus_dir(), "the shared HDR corpus") else { return };
    let images = peers::quality_images(&dir, 3, 64);
    let mut blocks = 0;
    for img in &images {
        for signed in [false, true] {
            let rgb: Vec<f32> =
                img.rgb.iter().enumerate().map(|(i, &v)| if signed && i % 7 == 0 { -v } else { v }).collect();
            for effort in [0, 3, 6] {
                let opts = EncodeOptions { signed, effort, ..Default::default() };
                let serial = encode_surface(img.width as u32, img.height as u32, &rgb, &opts).unwrap();
                let parallel = encode_surface(
                    img.width as u32,
                    img.height as u32,
                    &rgb,
                    &EncodeOptions { pool: hdrcodec_core::ThreadPool::new(0).unwrap(), ..opts.clone() },
                )
                .unwrap();
                assert_eq!(serial, parallel, "{} effort {effort}", img.name);
                let bw = img.width / 4;
                for (b, bytes) in serial.chunks_exact(16).enumerate() {
                    let (bx, by) = (b % bw, b / bw);
                    let texels: [[u16; 3]; 16] = std::array::from_fn(|i| {
                        let p = ((by * 4 + i / 4) * img.width + bx * 4 + i % 4) * 3;
                        std::array::from_fn(|c| f32_to_bc6h_half(rgb[p + c], signed))
                    });
                    let enc = encode_block(&texels, signed, effort);
                    assert_eq!(&enc.bytes[..], bytes, "{} block {b}: surface and block encoders differ", img.name);
                    assert_eq!(bcdec(&enc.bytes, signed), enc.decoded, "{} block {b} effort {effort}", img.name);
                    blocks += 1;
                }
            }
        }
    }
    eprintln!("{blocks} corpus blocks decode identically in bcdec_rs");
}

/// NaN, ±Inf and negative inputs: the blocks decode (bcdec_rs) to finite values; UF16 has no
/// negatives; NaN comes back as 0 and +Inf as the largest finite half where they fill a block.
#[test]
fn nan_inf_and_negatives_never_produce_garbage() {
    let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0, -1e9, 1e9, -0.0, 0.5];
    let mut rng = Rng(7);
    for signed in [false, true] {
        // Whole blocks of one special value.
        for &v in &specials {
            let blocks =
                encode_surface(4, 4, &[v; 48], &EncodeOptions { signed, effort: 5, ..Default::default() }).unwrap();
            let out = peers::decode_blocks(4, 4, &blocks, signed);
            let expect = if v.is_nan() || (!signed && v < 0.0) { 0.0 } else { v.clamp(-65504.0, 65504.0) };
            for &o in &out {
                assert_eq!(o, expect, "value {v} signed {signed}");
            }
        }
        // Specials scattered among ordinary values.
        let mut rgb = vec![0f32; 16 * 16 * 3];
        for x in rgb.iter_mut() {
            *x = if rng.below(4) == 0 { specials[rng.below(8) as usize] } else { rng.below(1000) as f32 / 10.0 };
        }
        for effort in [0, 5, 9] {
            let blocks = encode_surface(16, 16, &rgb, &EncodeOptions { signed, effort, ..Default::default() }).unwrap();
            for (i, &o) in peers::decode_blocks(16, 16, &blocks, signed).iter().enumerate() {
                assert!(o.is_finite(), "sample {i}: {o}");
                assert!(signed || o >= 0.0, "sample {i}: {o} negative in UF16");
                assert!(o.abs() <= 65504.0);
            }
        }
    }
}

/// Odd sizes are padded by edge replication: a 5x3 image encodes to the same blocks as the
/// 8x4 image that repeats its last column and row.
#[test]
fn partial_blocks_replicate_edges() {
    let rgb: Vec<f32> = (0..5 * 3 * 3).map(|i| (i as f32 * 0.2).exp2()).collect();
    let mut padded = Vec::new();
    for y in 0..4usize {
        for x in 0..8usize {
            let p = (y.min(2) * 5 + x.min(4)) * 3;
            padded.extend_from_slice(&rgb[p..p + 3]);
        }
    }
    for effort in [0, 9] {
        let opts = EncodeOptions { effort, ..Default::default() };
        let blocks = encode_surface(5, 3, &rgb, &opts).unwrap();
        assert_eq!(blocks.len(), 32);
        assert_eq!(blocks, encode_surface(8, 4, &padded, &opts).unwrap());
    }
}

/// Our effort level that is set against each ISPC profile: the fastest one with RMSLE no worse
/// in `benches/bc6h_encode.rs`, which shows that it also encodes faster.
const MATCHING_EFFORT: [(&str, u8); 5] = [("veryfast", 0), ("fast", 2), ("basic", 3), ("slow", 3), ("veryslow", 3)];

fn hdr_image(w: usize, h: usize, rgb: Vec<f32>) -> HdrImage {
    HdrImage::new(w as u32, h as u32, Channels::Rgb, rgb, ColorInfo::default()).unwrap()
}

/// Quality against Intel ISPC (UF16) and `block_compression` on corpus crops and synthetic HDR
/// content: prints RMSLE, PU21-PSNR and ΔE ITP per encoder, and asserts that for each ISPC
/// profile our matching effort has RMSLE ≤ ISPC's and a mean ΔE ITP no worse, and that our top
/// effort beats ISPC veryslow.
#[test]
fn quality_against_ispc_and_block_compression() {
    let Some(dir) = common::require(common::corpus_dir(), "the shared HDR corpus") else { return };
    let images = peers::quality_images(&dir, 3, 128);
    // Pool all images into one figure per encoder (sums over samples).
    let score = |encode: &dyn Fn(&peers::Image) -> Vec<u8>| -> (f64, f64, f64) {
        let (mut sq, mut n, mut pu, mut de) = (0.0, 0usize, 0.0, 0.0);
        for img in &images {
            let decoded = peers::decode_blocks(img.width, img.height, &encode(img), false);
            let r = peers::rmsle(&img.rgb, &decoded);
            sq += r * r * img.rgb.len() as f64;
            n += img.rgb.len();
            let (a, b) = (hdr_image(img.width, img.height, img.rgb.clone()), hdr_image(img.width, img.height, decoded));
            pu += metrics::pu21_psnr(&a, &b).unwrap();
            de += metrics::delta_e_itp(&a, &b).unwrap().0;
        }
        let k = images.len() as f64;
        ((sq / n as f64).sqrt(), pu / k, de / k)
    };
    let ours = |effort: u8| {
        move |img: &peers::Image| {
            encode_surface(
                img.width as u32,
                img.height as u32,
                &img.rgb,
                &EncodeOptions { signed: false, effort, pool: hdrcodec_core::ThreadPool::new(0).unwrap() },
            )
            .unwrap()
        }
    };
    println!("images: {}", images.iter().map(|i| i.name.as_str()).collect::<Vec<_>>().join(", "));
    println!("{:<26} {:>9} {:>10} {:>9}", "encoder", "RMSLE", "PU21-PSNR", "dE-ITP");
    let mut ours_scores = [(0.0, 0.0, 0.0); 10];
    for effort in 0..=9u8 {
        ours_scores[effort as usize] = score(&ours(effort));
        let s = ours_scores[effort as usize];
        println!("{:<26} {:>9.5} {:>10.3} {:>9.4}", format!("hdrcodec effort {effort}"), s.0, s.1, s.2);
    }
    let bc = score(&|img: &peers::Image| {
        let (pw, ph, rgba) = peers::to_rgba_f16_padded(img);
        peers::block_compression_encode(pw, ph, &rgba)
    });
    println!("{:<26} {:>9.5} {:>10.3} {:>9.4}", "block_compression veryslow", bc.0, bc.1, bc.2);
    let mut ispc_veryslow = (0.0, 0.0, 0.0);
    for ((name, settings), (pname, effort)) in peers::ispc_profiles().iter().zip(MATCHING_EFFORT) {
        assert_eq!(*name, pname);
        let s = score(&|img: &peers::Image| {
            let (pw, ph, rgba) = peers::to_rgba_f16_padded(img);
            peers::ispc_encode(pw, ph, &rgba, settings)
        });
        let o = ours_scores[effort as usize];
        println!(
            "{:<26} {:>9.5} {:>10.3} {:>9.4}   vs effort {effort}: {:.5}",
            format!("ISPC {name}"),
            s.0,
            s.1,
            s.2,
            o.0
        );
        assert!(o.0 <= s.0, "effort {effort} RMSLE {} > ISPC {name} {}", o.0, s.0);
        assert!(o.2 <= s.2, "effort {effort} mean dE ITP {} > ISPC {name} {}", o.2, s.2);
        ispc_veryslow = s;
    }
    assert!(ours_scores[9].0 < ispc_veryslow.0, "effort 9 does not beat ISPC veryslow");
    assert!(ours_scores[9].0 < bc.0, "effort 9 does not beat block_compression");
}
