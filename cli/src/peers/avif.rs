//! AVIF 10- and 12-bit PQ through libavif's command-line tools (Debian `libavif-bin`):
//! `avifenc` reads a 16-bit PNG whose samples we PQ-coded, `avifdec -d 16` writes one back
//! (`../shared/REFERENCES.md`, row "AVIF (peer)": no float input, so the transfer function is
//! applied here).
//!
//! The mapping: a linear sample x of the (BT.2020) image is x · `nits_per_unit` cd/m²; its PQ
//! signal (SMPTE ST 2084, core's [`PqTransfer`], 10000 cd/m² = 1.0) is stored as
//! round(signal · 65535). Luminance outside 0-10000 cd/m² (negative samples: out of BT.2020's
//! gamut) and NaN are clipped and counted. The file says so: `--cicp 9/16/9` (BT.2020
//! primaries, PQ, BT.2020 non-constant-luminance matrix), full range, 4:4:4.

use hdrcodec::core::transfer::PqTransfer;
use hdrcodec::core::{Channels, Error, HdrImage, Result};
use std::ffi::OsString;
use std::path::Path;

/// libavif's encoder program.
pub const ENCODER: &str = "avifenc";
/// libavif's decoder program.
pub const DECODER: &str = "avifdec";
/// Where the programs come from, for "not installed" messages.
pub const PACKAGE: &str = "Debian libavif-bin";
/// The AV1 encoder avifenc is asked to use.
pub const CODEC: &str = "aom";

/// "avifenc 0.11.1 (aom v3.6.0)" from `avifenc --version` ("Version: 0.11.1 (…, aom
/// [enc/dec]:v3.6.0, …)"); for the decoder, "avifdec 0.11.1 (dav1d 1.0.0)" (its default).
fn version(program: &str, codec: &str) -> String {
    let text = super::version_text(program, "--version").unwrap_or_default();
    let libavif =
        text.lines().find_map(|l| l.trim().strip_prefix("Version: ")).and_then(|v| v.split_whitespace().next());
    let codec_version = text
        .split([',', '('])
        .map(str::trim)
        .find(|part| part.starts_with(&format!("{codec} ")))
        .and_then(|part| part.rsplit(':').next())
        .map(str::trim);
    match (libavif, codec_version) {
        (Some(v), Some(c)) => format!("{program} {v} ({codec} {c})"),
        (Some(v), None) => format!("{program} {v}"),
        _ => format!("{program} (version unknown)"),
    }
}

/// The encoder, its version and its AV1 encoder's: "avifenc 0.11.1 (aom v3.6.0)".
pub fn encoder_version() -> String {
    version(ENCODER, CODEC)
}

/// The decoder, its version and its AV1 decoder's (avifdec's default, dav1d).
pub fn decoder_version() -> String {
    version(DECODER, "dav1d")
}

/// `image` (RGB or RGBA, BT.2020 primaries) as a 16-bit RGB PNG of PQ signals (see the module
/// notes), and the number of samples clipped.
pub fn pq_png(image: &HdrImage) -> Result<(Vec<u8>, usize)> {
    let nits = f64::from(image.color.nits_per_unit);
    let mut clipped = 0;
    let mut data = Vec::with_capacity(image.pixel_count() * 6);
    for px in image.rgb() {
        for v in px {
            let l = f64::from(v) * nits;
            clipped += usize::from(!(0.0..=PqTransfer::PEAK_NITS).contains(&l));
            let code = (PqTransfer::encode(l) * 65535.0).round() as u16;
            data.extend_from_slice(&code.to_be_bytes());
        }
    }
    let mut png = Vec::new();
    let mut enc = png::Encoder::new(&mut png, image.width(), image.height());
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Sixteen);
    let png_error = |e: png::EncodingError| Error::invalid(format!("cannot write avifenc's PNG input: {e}"));
    let mut writer = enc.write_header().map_err(png_error)?;
    writer.write_image_data(&data).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok((png, clipped))
}

/// avifdec's 16-bit PNG (`data`) as linear samples: inverse PQ, in `like`'s units (its
/// `nits_per_unit`) and BT.2020 primaries. The PNG must have `like`'s size and 16-bit RGB (or
/// RGBA, alpha ignored) samples; nothing beyond that size is allocated.
pub fn read_pq_png(data: &[u8], like: &HdrImage) -> Result<HdrImage> {
    let (w, h) = (like.width(), like.height());
    let png_error = |e: png::DecodingError| Error::invalid(format!("avifdec's PNG: {e}"));
    let limit = (w as usize).saturating_mul(h as usize).saturating_mul(8).saturating_add(1 << 16);
    let mut decoder = png::Decoder::new_with_limits(std::io::Cursor::new(data), png::Limits { bytes: limit });
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(png_error)?;
    let info = reader.info();
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        c => return Err(Error::unsupported(format!("avifdec's PNG has colour type {c:?}, not RGB"))),
    };
    if info.bit_depth != png::BitDepth::Sixteen || (info.width, info.height) != (w, h) {
        return Err(Error::invalid(format!(
            "avifdec wrote a {}x{} {:?}-bit PNG for a {w}x{h} input (16-bit expected)",
            info.width, info.height, info.bit_depth
        )));
    }
    let size = reader.output_buffer_size().ok_or_else(|| Error::limit("avifdec's PNG is too large"))?;
    let mut buf = vec![0; size];
    reader.next_frame(&mut buf).map_err(png_error)?;
    let nits = f64::from(like.color.nits_per_unit);
    let samples: Vec<f32> = buf
        .chunks_exact(2 * channels)
        .take(like.pixel_count())
        .flat_map(|px| {
            (0..3).map(move |c| {
                let code = u16::from_be_bytes([px[2 * c], px[2 * c + 1]]);
                (PqTransfer::decode(f64::from(code) / 65535.0) / nits) as f32
            })
        })
        .collect();
    let mut color = like.color.clone();
    color.primaries = hdrcodec::core::ColorPrimaries::Bt2020;
    HdrImage::new(w, h, Channels::Rgb, samples, color)
}

/// avifenc's arguments: the PNG `input` to `output` at `depth` bits, quantizer `quantizer`
/// (0-63, `--min` = `--max`), 4:4:4, full range, BT.2020 + PQ signalled, speed 6, one thread.
pub fn encode_args(input: &Path, output: &Path, depth: u8, quantizer: u8) -> Vec<OsString> {
    let (d, q) = (depth.to_string(), quantizer.to_string());
    let fixed = ["-c", CODEC, "-j", "1", "-s", "6", "-y", "444", "--cicp", "9/16/9", "-r", "full"];
    let mut args: Vec<OsString> = fixed.into_iter().map(OsString::from).collect();
    args.extend(super::args(&[&"-d", &d, &"--min", &q, &"--max", &q, &input, &output]));
    args
}

/// avifdec's arguments: `input` to a 16-bit PNG `output`, one thread.
pub fn decode_args(input: &Path, output: &Path) -> Vec<OsString> {
    super::args(&[&"-j", &"1", &"-d", &"16", &input, &output])
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::{ColorInfo, ColorPrimaries};

    #[test]
    fn pq_png_reads_back_within_a_16_bit_step() {
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None };
        // 0.01, 1, 100, 1000 cd/m²; then -1 and 200 units (20000 cd/m²) and NaN: clipped.
        let samples = vec![1e-4, 0.01, 1.0, 10.0, 0.5, 0.25, -1.0, 200.0, f32::NAN];
        let img = HdrImage::new(3, 1, Channels::Rgb, samples.clone(), color).unwrap();
        let (png, clipped) = pq_png(&img).unwrap();
        assert_eq!(clipped, 3);
        let back = read_pq_png(&png, &img).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::Bt2020);
        for (i, (&a, &b)) in samples.iter().zip(back.samples()).take(6).enumerate() {
            // One code of 65535 is at most ~0.02 % of the luminance above 1 cd/m² (PQ's slope).
            assert!(((b - a) / a).abs() < 2e-3, "{i}: {a} -> {b}");
        }
        assert_eq!(&back.samples()[6..], [0.0, 100.0, 0.0]);
        // A PNG of another size is refused.
        let other = HdrImage::new(1, 1, Channels::Rgb, vec![0.0; 3], img.color.clone()).unwrap();
        assert!(read_pq_png(&png, &other).is_err());
        assert!(read_pq_png(&png[..png.len() / 2], &img).is_err());
    }

    #[test]
    fn the_command_lines_say_what_the_rows_say() {
        let args = encode_args(Path::new("a.png"), Path::new("b.avif"), 12, 20);
        let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(
            args.join(" "),
            "-c aom -j 1 -s 6 -y 444 --cicp 9/16/9 -r full -d 12 --min 20 --max 20 a.png b.avif"
        );
    }
}
