//! Writing through the codecs with `mips=true`: a full chain whose every level decodes to the
//! linear-light box average of the source (a smooth image, so BC6H's error is small next to
//! the check), in DDS and KTX2, UF16 and SF16.
use hdrcodec_bc6h::texture::full_mip_count;
use hdrcodec_bc6h::{read_dds, read_ktx2, Bc6hDdsCodec, Bc6hKtx2Codec};
use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};

/// A smooth HDR gradient (0.01 to ~40), negative in the blue channel when `signed`.
fn image(w: u32, h: u32, signed: bool) -> HdrImage {
    let mut v = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let t = (x as f32 / w as f32 + y as f32 / h as f32) * 0.5;
            let b = if signed { -0.5 - t } else { 0.5 + t };
            v.extend_from_slice(&[0.01 + 40.0 * t * t, 1.0 + t, b]);
        }
    }
    HdrImage::new(w, h, Channels::Rgb, v, ColorInfo::default()).unwrap()
}

fn mean(v: &[f32], c: usize) -> f64 {
    v.chunks_exact(3).map(|p| p[c] as f64).sum::<f64>() / (v.len() / 3) as f64
}

#[test]
fn mip_chains_average_the_source_in_linear_light() {
    let (w, h) = (37u32, 22u32); // odd sizes on purpose
    for signed in [false, true] {
        let img = image(w, h, signed);
        let settings = EncodeSettings::default()
            .with_effort(2)
            .with_option("mips", "true")
            .with_option("signed", if signed { "true" } else { "false" });
        let dds = Bc6hDdsCodec.encode(&img, &settings).unwrap();
        let ktx = Bc6hKtx2Codec.encode(&img, &settings).unwrap();
        let limits = Limits::default();
        for tex in [read_dds(&dds, &limits).unwrap(), read_ktx2(&ktx, &limits).unwrap()] {
            assert_eq!(tex.signed, signed);
            assert_eq!(tex.levels.len(), full_mip_count(w, h));
            assert_eq!(tex.level_size(tex.levels.len() - 1), (1, 1));
            for level in 0..tex.levels.len() {
                let rgb = tex.decode_level(level, &limits).unwrap();
                for c in 0..3 {
                    // An area-weighted box filter preserves the mean exactly; the tolerance is
                    // for BC6H's quantisation.
                    let (want, got) = (mean(img.samples(), c), mean(&rgb, c));
                    assert!(
                        (got - want).abs() <= 0.06 * want.abs() + 0.01,
                        "signed={signed} level {level} channel {c}: mean {got} vs source {want}"
                    );
                }
            }
        }
        // The trait decode gives level 0 at full size.
        let back = Bc6hDdsCodec.decode(&dds, &limits).unwrap();
        assert_eq!((back.width(), back.height()), (w, h));
        assert_eq!(Bc6hKtx2Codec.decode(&ktx, &limits).unwrap().samples(), back.samples());
    }
}
