//! BC6H encoder comparison helpers shared by `tests/bc6h_encode.rs` and `benches/bc6h_encode.rs`:
//! test images (corpus crops and synthetic HDR content), the peer encoders (Intel ISPC through
//! `intel_tex_2`, the `block_compression` crate), decoding with `bcdec_rs`, and RMSLE.
#![allow(dead_code)]

use std::path::Path;

/// An RGB `f32` test image.
pub struct Image {
    pub name: String,
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<f32>,
}

impl Image {
    /// The `w` x `h` window at (`x0`, `y0`).
    pub fn crop(&self, name: &str, x0: usize, y0: usize, w: usize, h: usize) -> Image {
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in y0..y0 + h {
            rgb.extend_from_slice(&self.rgb[(y * self.width + x0) * 3..(y * self.width + x0 + w) * 3]);
        }
        Image { name: name.to_string(), width: w, height: h, rgb }
    }
}

/// A Radiance .hdr file decoded by the `image` crate.
pub fn load_hdr(path: &Path) -> Image {
    let img = image::ImageReader::open(path).expect("open .hdr").decode().expect("decode .hdr").into_rgb32f();
    let name = path.file_stem().unwrap().to_string_lossy().into_owned();
    Image { name, width: img.width() as usize, height: img.height() as usize, rgb: img.into_raw() }
}

/// The top mip level of a BC6H DDS (DX10 header) decoded by `bcdec_rs`.
pub fn load_bc6h_dds(path: &Path) -> Image {
    let bytes = std::fs::read(path).expect("read .dds");
    assert_eq!(&bytes[0..4], b"DDS ", "{}", path.display());
    let u32_at = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let (height, width) = (u32_at(12) as usize, u32_at(16) as usize);
    let dxgi = u32_at(128);
    assert!(dxgi == 95 || dxgi == 96, "{}: not BC6H", path.display());
    let (bw, bh) = (width.div_ceil(4), height.div_ceil(4));
    let full = decode_blocks(bw * 4, bh * 4, &bytes[148..148 + bw * bh * 16], dxgi == 96);
    let name = path.file_stem().unwrap().to_string_lossy().into_owned();
    Image { name, width: bw * 4, height: bh * 4, rgb: full }.crop_to(width, height)
}

impl Image {
    fn crop_to(self, w: usize, h: usize) -> Image {
        let name = self.name.clone();
        self.crop(&name, 0, 0, w, h)
    }
}

/// Synthetic HDR content: a sky-like gradient over 16 stops, a few very bright "lights" with
/// sharp edges, saturated colour bars and fine noise, `size` x `size`.
pub fn synthetic(size: usize) -> Image {
    let mut rgb = Vec::with_capacity(size * size * 3);
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut noise = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    for y in 0..size {
        for x in 0..size {
            let u = x as f32 / size as f32;
            let v = y as f32 / size as f32;
            let base = (2.0f32).powf(16.0 * u - 10.0);
            let mut px = [base * (0.6 + 0.4 * v), base * 0.8, base * (1.2 - 0.5 * v)];
            if ((x / 24) + (y / 24)) % 7 == 0 {
                px = [px[0] * 300.0, px[1] * 200.0, px[2] * 50.0];
            }
            if y % 64 < 8 {
                let bar = (x / 32) % 3;
                px[bar] *= 20.0;
            }
            for p in &mut px {
                *p *= 0.9 + 0.2 * noise();
            }
            rgb.extend_from_slice(&px);
        }
    }
    Image { name: "synthetic".into(), width: size, height: size, rgb }
}

/// Edge-replicates an image to multiples of 4 and converts it to RGBA half floats with the
/// clamping ISPC needs (NaN and negatives to 0, overflow to 65504).
pub fn to_rgba_f16_padded(img: &Image) -> (usize, usize, Vec<block_compression::half::f16>) {
    use block_compression::half::f16;
    let (pw, ph) = (img.width.div_ceil(4) * 4, img.height.div_ceil(4) * 4);
    let mut out = Vec::with_capacity(pw * ph * 4);
    for y in 0..ph {
        for x in 0..pw {
            let p = (y.min(img.height - 1) * img.width + x.min(img.width - 1)) * 3;
            for c in 0..3 {
                let v = img.rgb[p + c];
                let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 65504.0) };
                out.push(f16::from_f32(v));
            }
            out.push(f16::ONE);
        }
    }
    (pw, ph, out)
}

/// The five ISPC BC6H profiles, fastest first.
pub fn ispc_profiles() -> [(&'static str, intel_tex_2::bc6h::EncodeSettings); 5] {
    use intel_tex_2::bc6h;
    [
        ("veryfast", bc6h::very_fast_settings()),
        ("fast", bc6h::fast_settings()),
        ("basic", bc6h::basic_settings()),
        ("slow", bc6h::slow_settings()),
        ("veryslow", bc6h::very_slow_settings()),
    ]
}

/// Intel ISPC (`intel_tex_2`) BC6H UF16 from already padded RGBA half data.
pub fn ispc_encode(
    pw: usize,
    ph: usize,
    rgba: &[block_compression::half::f16],
    settings: &intel_tex_2::bc6h::EncodeSettings,
) -> Vec<u8> {
    let bytes: Vec<u8> = rgba.iter().flat_map(|h| h.to_bits().to_le_bytes()).collect();
    let surface = intel_tex_2::RgbaSurface { data: &bytes, width: pw as u32, height: ph as u32, stride: pw as u32 * 8 };
    intel_tex_2::bc6h::compress_blocks(settings, &surface)
}

/// The `block_compression` crate's BC6H encoder (a Rust port of ISPC's) at its "very slow"
/// setting, from already padded RGBA half data.
pub fn block_compression_encode(pw: usize, ph: usize, rgba: &[block_compression::half::f16]) -> Vec<u8> {
    use block_compression::{encode::compress_rgba16, BC6HSettings, CompressionVariant};
    let variant = CompressionVariant::BC6H(BC6HSettings::very_slow());
    let mut out = vec![0u8; variant.blocks_byte_size(pw as u32, ph as u32)];
    compress_rgba16(variant, rgba, &mut out, pw as u32, ph as u32, pw as u32 * 4);
    out
}

/// Decodes BC6H blocks (block rows top to bottom) to an RGB `f32` image of `width` x `height`
/// with `bcdec_rs`, dropping the padding.
pub fn decode_blocks(width: usize, height: usize, blocks: &[u8], signed: bool) -> Vec<f32> {
    let bw = width.div_ceil(4);
    let mut out = vec![0f32; width * height * 3];
    let mut texels = [0f32; 48];
    for (b, block) in blocks.chunks_exact(16).enumerate() {
        let (bx, by) = (b % bw, b / bw);
        bcdec_rs::bc6h_float(block, &mut texels, 12, signed);
        for i in 0..16 {
            let (x, y) = (bx * 4 + i % 4, by * 4 + i / 4);
            if x < width && y < height {
                out[(y * width + x) * 3..][..3].copy_from_slice(&texels[i * 3..i * 3 + 3]);
            }
        }
    }
    out
}

/// RMSLE: √(mean over all samples of log2((decoded + 1) / (original + 1))²), negatives as 0.
pub fn rmsle(original: &[f32], decoded: &[f32]) -> f64 {
    let sum: f64 = original
        .iter()
        .zip(decoded)
        .map(|(&o, &d)| {
            let e = ((d.max(0.0) as f64 + 1.0) / (o.max(0.0) as f64 + 1.0)).log2();
            e * e
        })
        .sum();
    (sum / original.len() as f64).sqrt()
}

/// The test images of the quality comparison: `count` crops of `size` x `size` from the corpus
/// .hdr files (and the UF16 Desk DDS), plus the synthetic image. `None` when the corpus is absent.
pub fn quality_images(corpus: &Path, count: usize, size: usize) -> Vec<Image> {
    let mut images = Vec::new();
    let mut files: Vec<_> = std::fs::read_dir(corpus.join("hdr"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p: &std::path::PathBuf| p.extension().is_some_and(|e| e == "hdr"));
    files.sort();
    for path in files {
        let img = load_hdr(&path);
        // A window from the middle of the frame, where the detail is.
        let (x0, y0) = ((img.width - size) / 2, (img.height - size) / 2);
        images.push(img.crop(&img.name, x0, y0, size, size));
    }
    let dds = corpus.join("dds/Desk_BC6H_UF16_mips.dds");
    if dds.is_file() {
        let img = load_bc6h_dds(&dds);
        let (x0, y0) = ((img.width - size) / 2, (img.height - size) / 2);
        images.push(img.crop("Desk_dds", x0, y0, size, size));
    }
    images.truncate(count);
    images.push(synthetic(size));
    images
}
