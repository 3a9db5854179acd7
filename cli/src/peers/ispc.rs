//! BC6H through Intel's ISPC texture compressor (`intel_tex_2`, in process), the peer of our
//! `bc6h:` rows, behind the `ispc` cargo feature (`cargo build -p hdrcodec-cli --features ispc`):
//! without it the `bc6h(ispc):` rows say "not installed".
//!
//! ISPC takes padded RGBA half floats (`../shared/REFERENCES.md`, row "BC6H DDS": UF16 only, pad
//! to multiples of 4, clamp NaN and negatives): the image, its colour prepared as for our
//! encoder, is converted here (timed with the encode, as it is part of the job), edges repeated
//! into the padding, NaN and negative samples set to 0 and samples beyond half's 65504 to 65504
//! (counted). The blocks go into a BC6H_UF16 DDS file that our decoder reads.

use hdrcodec::core::{HdrImage, Result};

/// The cargo feature that links ISPC.
pub const FEATURE: &str = "ispc";

/// The ISPC profiles in the bench, fastest first (the slow ones take seconds per megapixel:
/// `cargo bench -p hdrcodec-tests --bench bc6h_encode` has all five).
pub const PROFILES: [&str; 3] = ["veryfast", "fast", "basic"];

/// Whether this build links ISPC.
pub const fn available() -> bool {
    cfg!(feature = "ispc")
}

/// How the rows name the encoder.
pub fn describe(profile: &str) -> String {
    format!("Intel ISPC texcomp (intel_tex_2 0.5, {profile} profile, BC6H UF16, one thread, in process)")
}

/// `image` as RGBA half-float bytes padded to multiples of 4 (edges repeated), NaN and
/// negatives clamped to 0 and values beyond 65504 to 65504: (padded width, padded height,
/// bytes, samples clamped beyond half's range).
pub fn rgba_half_padded(image: &HdrImage) -> (usize, usize, Vec<u8>, usize) {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let (pw, ph) = (w.div_ceil(4) * 4, h.div_ceil(4) * 4);
    let rgb = image.with_channels(hdrcodec::core::Channels::Rgb);
    let samples = rgb.samples();
    let mut clipped = 0;
    let mut out = Vec::with_capacity(pw * ph * 8);
    for y in 0..ph {
        for x in 0..pw {
            let at = (y.min(h - 1) * w + x.min(w - 1)) * 3;
            for &v in &samples[at..at + 3] {
                let inside = x < w && y < h;
                clipped += usize::from(inside && v > 65504.0);
                let v = if v.is_nan() || v < 0.0 { 0.0 } else { v.min(65504.0) };
                out.extend(half::f16::from_f32(v).to_bits().to_le_bytes());
            }
            out.extend(half::f16::ONE.to_bits().to_le_bytes());
        }
    }
    (pw, ph, out, clipped)
}

/// `image` compressed by ISPC with `profile` ([`PROFILES`]) into a BC6H_UF16 DDS file, and the
/// samples clamped beyond half's range.
#[cfg(feature = "ispc")]
pub fn encode_dds(image: &HdrImage, profile: &str) -> Result<(Vec<u8>, usize)> {
    use intel_tex_2::bc6h;
    let settings = match profile {
        "veryfast" => bc6h::very_fast_settings(),
        "fast" => bc6h::fast_settings(),
        "basic" => bc6h::basic_settings(),
        "slow" => bc6h::slow_settings(),
        "veryslow" => bc6h::very_slow_settings(),
        p => return Err(hdrcodec::core::Error::invalid(format!("no ISPC BC6H profile '{p}'"))),
    };
    let (pw, ph, bytes, clipped) = rgba_half_padded(image);
    let surface = intel_tex_2::RgbaSurface { data: &bytes, width: pw as u32, height: ph as u32, stride: pw as u32 * 8 };
    let blocks = bc6h::compress_blocks(&settings, &surface);
    let texture = hdrcodec::bc6h::Bc6hTexture {
        width: image.width(),
        height: image.height(),
        signed: false,
        levels: vec![blocks],
    };
    Ok((hdrcodec::bc6h::write_dds(&texture)?, clipped))
}

/// Without the `ispc` feature there is no ISPC to call.
#[cfg(not(feature = "ispc"))]
pub fn encode_dds(_image: &HdrImage, _profile: &str) -> Result<(Vec<u8>, usize)> {
    Err(hdrcodec::core::Error::unsupported(format!("this build has no ISPC (cargo feature `{FEATURE}`)")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::{Channels, ColorInfo};

    #[test]
    fn the_padding_repeats_edges_and_clamps() {
        // 5x1: padded to 8x4; -1 and NaN become 0, 70000 becomes 65504 (one sample counted).
        let samples = vec![1.0, 2.0, 3.0, -1.0, f32::NAN, 70000.0, 0.5, 0.5, 0.5, 0.25, 0.25, 0.25, 4.0, 5.0, 6.0];
        let img = HdrImage::new(5, 1, Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let (pw, ph, bytes, clipped) = rgba_half_padded(&img);
        assert_eq!((pw, ph, bytes.len(), clipped), (8, 4, 8 * 4 * 8, 1));
        let px = |x: usize, y: usize| -> [f32; 4] {
            let at = (y * pw + x) * 8;
            std::array::from_fn(|c| {
                half::f16::from_bits(u16::from_le_bytes([bytes[at + 2 * c], bytes[at + 2 * c + 1]])).to_f32()
            })
        };
        assert_eq!(px(0, 0), [1.0, 2.0, 3.0, 1.0]);
        assert_eq!(px(1, 0), [0.0, 0.0, 65504.0, 1.0]);
        assert_eq!(px(7, 3), [4.0, 5.0, 6.0, 1.0], "the last column and row repeat");
    }

    #[cfg(feature = "ispc")]
    #[test]
    fn ispc_writes_a_dds_that_our_decoder_reads_back_close() {
        let samples: Vec<f32> = (0..16 * 8).flat_map(|i| [i as f32 / 16.0, 1.0, 0.5]).collect();
        let img = HdrImage::new(16, 8, Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let (dds, clipped) = encode_dds(&img, "fast").unwrap();
        assert_eq!((dds.len(), clipped), (148 + 8 * 16, 0));
        let back = hdrcodec::registry().by_name("bc6h").unwrap().decode(&dds, &Default::default()).unwrap();
        let cmp = hdrcodec::core::metrics::compare(&img, &back).unwrap();
        assert!(cmp.pu21_psnr > 40.0, "{}", cmp.pu21_psnr);
    }
}
