//! BC6H decoder validation: a differential test against `bcdec_rs` over random blocks, and
//! (below) the corpus DDS files against imagecodecs (bcdec 0.98) and the EXR they came from.
mod common;

use hdrcodec_bc6h::encode::EncodeOptions;
use hdrcodec_bc6h::{
    block_dims, decode_block, decode_surface, decode_surface_into, encode_texture, read_dds, write_dds, Bc6hTexture,
};
use hdrcodec_core::metrics::log_rmse;
use hdrcodec_core::{Channels, ColorInfo, HdrImage, Limits};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use common::Rng;

fn bcdec(block: &[u8; 16], signed: bool) -> [u16; 48] {
    let mut out = [0u16; 48];
    bcdec_rs::bc6h_half(block, &mut out, 12, signed);
    out
}

/// Random blocks per variant. The low 5 bits cycle through all 32 values so every mode (and
/// every reserved value) gets 1/32 of the blocks; the other 123 bits are random.
const RANDOM_BLOCKS: u64 = 10_000_000;

fn differential(signed: bool, seed: u64) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    let per = RANDOM_BLOCKS.div_ceil(threads);
    let start = std::time::Instant::now();
    let checked: u64 = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    let mut rng = Rng(seed ^ (t + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
                    let mut n = 0u64;
                    for i in 0..per.min(RANDOM_BLOCKS.saturating_sub(t * per)) {
                        let mut block = rng.block();
                        block[0] = (block[0] & !31) | (i % 32) as u8;
                        let ours = decode_block(&block, signed);
                        let theirs = bcdec(&block, signed);
                        assert_eq!(
                            ours.as_flattened(),
                            &theirs[..],
                            "block {block:02x?} (signed={signed}) differs from bcdec_rs"
                        );
                        n += 1;
                    }
                    n
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).sum()
    });
    assert_eq!(checked, RANDOM_BLOCKS);
    println!(
        "bc6h differential ({}): {checked} random blocks bit-identical to bcdec_rs in {:.2} s",
        if signed { "SF16" } else { "UF16" },
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn random_blocks_match_bcdec_rs_uf16() {
    differential(false, 0x5EED_0001);
}

#[test]
fn random_blocks_match_bcdec_rs_sf16() {
    differential(true, 0x5EED_0002);
}

/// The surface decoder (on x86-64 with AVX2 and F16C its SIMD texel kernel, elsewhere the
/// portable one) against `bcdec_rs`'s own `f32` output, on as many random blocks per variant as
/// the block-level test. The surfaces are 1021x1022 texels, so partial edge blocks (cropped
/// columns and rows) are covered too; single-threaded, so exactly the path the bench times.
fn differential_surface(signed: bool, seed: u64) {
    const BX: usize = 256;
    const BY: usize = 256;
    let (w, h) = (BX * 4 - 3, BY * 4 - 2);
    let pitch = BX * 4 * 3;
    let mut rng = Rng(seed);
    // One spare row: bcdec_rs steps its row pitch past the last block row.
    let mut theirs = vec![0f32; (BY * 4 + 1) * pitch];
    let mut ours = vec![0f32; w * h * 3];
    let mut checked = 0u64;
    let start = std::time::Instant::now();
    while checked < RANDOM_BLOCKS {
        let blocks: Vec<u8> = (0..BX * BY)
            .flat_map(|i| {
                let mut block = rng.block();
                block[0] = (block[0] & !31) | (i % 32) as u8;
                block
            })
            .collect();
        for (i, blk) in blocks.chunks_exact(16).enumerate() {
            let (x, y) = (i % BX, i / BX);
            bcdec_rs::bc6h_float(blk, &mut theirs[y * 4 * pitch + x * 12..], pitch, signed);
        }
        decode_surface_into(w as u32, h as u32, &blocks, signed, &hdrcodec_core::ThreadPool::single(), &mut ours)
            .unwrap();
        for y in 0..h {
            let (a, b) = (&ours[y * w * 3..][..w * 3], &theirs[y * pitch..][..w * 3]);
            if let Some(k) = a.iter().zip(b).position(|(p, q)| p.to_bits() != q.to_bits()) {
                let blk = &blocks[((y / 4) * BX + k / 12) * 16..][..16];
                panic!("texel ({}, {y}) of block {blk:02x?} (signed={signed}): {} vs bcdec_rs {}", k / 3, a[k], b[k]);
            }
        }
        checked += (BX * BY) as u64;
    }
    println!(
        "bc6h surface differential ({}): {checked} random blocks bit-identical to bcdec_rs f32 in {:.2} s",
        if signed { "SF16" } else { "UF16" },
        start.elapsed().as_secs_f64()
    );
}

#[test]
fn random_surfaces_match_bcdec_rs_f32_uf16() {
    differential_surface(false, 0x5EED_0003);
}

#[test]
fn random_surfaces_match_bcdec_rs_f32_sf16() {
    differential_surface(true, 0x5EED_0004);
}

// ------------------------------------------------------------------ corpus and file references

/// Decodes raw BC6H block files with imagecodecs' `bcn_decode` (bcdec 0.98). Arguments are
/// groups of (blocks file, padded height, padded width, signed 0/1); each result is written
/// next to its input as raw little-endian half floats (`.half`).
const BCN_DECODE: &str = r#"
import sys, numpy as np, imagecodecs
a = sys.argv[1:]
for i in range(0, len(a), 4):
    path, h, w, signed = a[i], int(a[i+1]), int(a[i+2]), a[i+3] == '1'
    fmt = imagecodecs.BCN.FORMAT.BC6HS if signed else imagecodecs.BCN.FORMAT.BC6HU
    out = imagecodecs.bcn_decode(open(path, 'rb').read(), fmt, shape=(h, w, 3))
    assert out.dtype == np.float16, out.dtype
    out.tofile(path + '.half')
"#;

/// Decodes whole DDS files with imagecodecs' `dds_decode` and OpenImageIO, writing raw float32
/// RGB files `<path>.imagecodecs.f32` and `<path>.oiio.f32`.
const DDS_DECODE: &str = r#"
import sys, numpy as np, imagecodecs, OpenImageIO as oiio
for path in sys.argv[1:]:
    a = imagecodecs.dds_decode(open(path, 'rb').read())
    np.ascontiguousarray(a[..., :3], dtype=np.float32).tofile(path + '.imagecodecs.f32')
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    assert px is not None and px.size > 0, buf.geterror()
    np.ascontiguousarray(px[..., :3], dtype=np.float32).tofile(path + '.oiio.f32')
"#;

fn read_u16_raw(path: &Path) -> Vec<u16> {
    let bytes = std::fs::read(path).expect("read raw halves");
    bytes.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect()
}

/// Our decode of one level as the half bit patterns of a padded (multiple of 4) RGB image.
fn our_halves_padded(w: u32, h: u32, blocks: &[u8], signed: bool) -> Vec<u16> {
    let (bx, by) = block_dims(w, h);
    let pw = bx * 4;
    let mut out = vec![0u16; bx * by * 16 * 3];
    for (i, blk) in blocks.chunks_exact(16).enumerate() {
        let texels = decode_block(blk.try_into().unwrap(), signed);
        let (x0, y0) = ((i % bx) * 4, (i / bx) * 4);
        for (t, px) in texels.iter().enumerate() {
            let o = ((y0 + t / 4) * pw + x0 + t % 4) * 3;
            out[o..o + 3].copy_from_slice(px);
        }
    }
    out
}

fn corpus_dds() -> Option<Vec<PathBuf>> {
    let files = common::corpus_files("dds", "dds")?;
    assert!(files.len() >= 2, "the corpus should hold the UF16 and SF16 Desk DDS files");
    Some(files)
}

#[test]
fn every_corpus_dds_block_matches_imagecodecs() {
    let Some(files) = corpus_dds() else { return };
    let Some(py) = common::require(common::python(), "the reference python venv (imagecodecs)") else { return };
    let dir = common::temp_dir("bc6h_corpus_blocks");
    let mut args = Vec::new();
    let mut jobs = Vec::new();
    for (fi, path) in files.iter().enumerate() {
        let tex = read_dds(&std::fs::read(path).unwrap(), &Limits::default()).expect("read corpus DDS");
        assert!(tex.levels.len() > 1, "{path:?} should carry mips");
        for (li, level) in tex.levels.iter().enumerate() {
            let (w, h) = tex.level_size(li);
            let (bx, by) = block_dims(w, h);
            let file = dir.join(format!("f{fi}_l{li}.bc6h"));
            std::fs::write(&file, level).unwrap();
            args.extend([file.clone().into_os_string(), (by * 4).to_string().into(), (bx * 4).to_string().into()]);
            args.push(if tex.signed { "1" } else { "0" }.into());
            jobs.push((path.clone(), li, file, w, h, tex.signed));
        }
    }
    let refs: Vec<&OsStr> = args.iter().map(|a| a.as_os_str()).collect();
    common::run_python(&py, BCN_DECODE, &refs);
    let mut blocks = 0;
    for (path, li, file, w, h, signed) in jobs {
        let level = std::fs::read(&file).unwrap();
        let theirs = read_u16_raw(&PathBuf::from(format!("{}.half", file.display())));
        let ours = our_halves_padded(w, h, &level, signed);
        assert_eq!(ours.len(), theirs.len());
        let diff = ours.iter().zip(&theirs).filter(|(a, b)| a != b).count();
        assert_eq!(diff, 0, "{path:?} level {li} ({w}x{h}): {diff} half values differ from imagecodecs");
        blocks += level.len() / 16;
    }
    println!(
        "bc6h corpus: {blocks} blocks of {} DDS files (all mips) bit-identical to imagecodecs bcn_decode",
        files.len()
    );
}

#[test]
fn desk_dds_against_its_exr_source() {
    let Some(files) = corpus_dds() else { return };
    let Some(py) = common::require(common::python(), "the reference python venv (OpenImageIO)") else { return };
    let exr = common::corpus_dir().unwrap().join("exr/Desk.exr");
    let dir = common::temp_dir("bc6h_desk_exr");
    let raw = dir.join("desk.f32");
    let script = "import sys, numpy as np, OpenImageIO as oiio\n\
                  b = oiio.ImageBuf(sys.argv[1]); p = b.get_pixels(oiio.FLOAT)\n\
                  np.ascontiguousarray(p[..., :3], dtype=np.float32).tofile(sys.argv[2])";
    common::run_python(&py, script, &[exr.as_os_str(), raw.as_os_str()]);
    let reference = common::read_f32_raw(&raw);
    for path in files.iter().filter(|p| p.file_name().unwrap().to_string_lossy().starts_with("Desk_")) {
        let tex = read_dds(&std::fs::read(path).unwrap(), &Limits::default()).unwrap();
        let ours = tex.decode_level(0, &Limits::default()).unwrap();
        let img = |v: Vec<f32>| HdrImage::new(tex.width, tex.height, Channels::Rgb, v, ColorInfo::default()).unwrap();
        let e = log_rmse(&img(reference.clone()), &img(ours)).unwrap();
        println!("bc6h {}: RMSLE vs exr/Desk.exr = {e:.5}", path.file_name().unwrap().to_string_lossy());
        // A BC6H encode of a photo lands around 0.03-0.05 (REFERENCES.md baselines); a
        // mis-decoded block pattern or swapped channel would be far above 0.1.
        assert!(e < 0.1, "RMSLE {e}");
    }
}

/// A texture with blocks taken from a corpus file, rearranged into a new size (not a multiple
/// of 4) with two mip levels, so that the written file is not a copy of the corpus file.
fn texture_from_corpus_blocks(src: &Bc6hTexture, width: u32, height: u32) -> Bc6hTexture {
    let pool = &src.levels[0];
    let pick = |n: usize, salt: usize| -> Vec<u8> {
        (0..n).flat_map(|i| pool[((i * 7919 + salt) % (pool.len() / 16)) * 16..][..16].to_vec()).collect()
    };
    let (b0x, b0y) = block_dims(width, height);
    let (b1x, b1y) = block_dims(width / 2, height / 2);
    Bc6hTexture { width, height, signed: src.signed, levels: vec![pick(b0x * b0y, 11), pick(b1x * b1y, 5)] }
}

/// Files we write, decoded by imagecodecs `dds_decode` and OpenImageIO, must equal our decode
/// bit for bit. Two sizes per variant: 124x76 (whole blocks) for both peers, and 123x77
/// (partial edge blocks) for OpenImageIO only: imagecodecs 2026.3.6 `dds_decode` mis-places
/// partial blocks (with a width that is not a multiple of 4 every texel row after the first is
/// garbled, and with such a height the last partial rows are wrong, e.g. rows 872-873 of the
/// corpus Desk DDS), while its `bcn_decode`, OpenImageIO and we agree on those files.
#[test]
fn dds_we_write_decodes_identically_in_imagecodecs_and_openimageio() {
    let Some(files) = corpus_dds() else { return };
    let Some(py) = common::require(common::python(), "the reference python venv (imagecodecs, OpenImageIO)") else {
        return;
    };
    let dir = common::temp_dir("bc6h_written_dds");
    let mut written = Vec::new();
    for (i, path) in files.iter().enumerate() {
        let src = read_dds(&std::fs::read(path).unwrap(), &Limits::default()).unwrap();
        for (w, h, peers) in [(124, 76, &["imagecodecs", "oiio"][..]), (123, 77, &["oiio"][..])] {
            let tex = texture_from_corpus_blocks(&src, w, h);
            let out = dir.join(format!("written{i}_{w}x{h}.dds"));
            std::fs::write(&out, write_dds(&tex).unwrap()).unwrap();
            written.push((out, tex, peers));
        }
        // And a file from our encoder (a 124x76 crop of the decoded corpus image, full mips).
        let full = src.decode_level(0, &Limits::default()).unwrap();
        let crop: Vec<f32> = (0..76).flat_map(|y| full[y * 644 * 3..(y * 644 + 124) * 3].to_vec()).collect();
        let options = EncodeOptions { signed: src.signed, effort: 1, ..Default::default() };
        let tex = encode_texture(124, 76, &crop, &options, true).expect("encode");
        let out = dir.join(format!("encoded{i}.dds"));
        std::fs::write(&out, write_dds(&tex).unwrap()).unwrap();
        written.push((out, tex, &["imagecodecs", "oiio"][..]));
    }
    let refs: Vec<&OsStr> = written.iter().map(|(p, _, _)| p.as_os_str()).collect();
    common::run_python(&py, DDS_DECODE, &refs);
    for (path, tex, peers) in &written {
        let ours = decode_surface(tex.width, tex.height, &tex.levels[0], tex.signed).unwrap();
        for peer in peers.iter() {
            let theirs = common::read_f32_raw(&PathBuf::from(format!("{}.{peer}.f32", path.display())));
            assert_eq!(theirs.len(), ours.len(), "{peer} decoded {path:?} to a different size");
            let diff = ours.iter().zip(&theirs).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
            assert_eq!(diff, 0, "{peer}: {diff} samples of {path:?} differ from our decode");
        }
        println!(
            "bc6h written DDS ({}, {}x{}, {} mips): identical in {}",
            if tex.signed { "SF16" } else { "UF16" },
            tex.width,
            tex.height,
            tex.levels.len(),
            peers.join(" and ")
        );
    }
}

/// The one non-finite value BC6H can produce: an SF16 mode-14 endpoint of -32768 finishes to
/// 0xFC00 (-Inf) under the D3D11 arithmetic; bcdec computes the same, in halves and in floats.
#[test]
fn sf16_minus_infinity_agrees_with_bcdec_rs() {
    use hdrcodec_bc6h::modes::{pack_block, BlockFields};
    let mut fields = BlockFields { mode: 13, ..Default::default() };
    fields.values[..3].copy_from_slice(&[0x8000; 3]);
    let block = pack_block(&fields);
    assert_eq!(decode_block(&block, true).as_flattened(), &bcdec(&block, true)[..]);
    let mut theirs = [0f32; 48];
    bcdec_rs::bc6h_float(&block, &mut theirs, 12, true);
    assert!(theirs.iter().all(|&v| v == f32::NEG_INFINITY));
    assert_eq!(decode_surface(4, 4, &block, true).unwrap(), theirs.to_vec());
}
