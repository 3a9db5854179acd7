//! JPEG XL through libjxl's command-line tools (Debian `libjxl-tools`): `cjxl` encodes the
//! bench input from a linear float PFM, `djxl` decodes the file back to PFM, which our PFM
//! decoder reads (`../shared/REFERENCES.md`, row "JPEG XL (peer)").
//!
//! - PFM is cjxl's only HDR input; without `-x color_space=RGB_D65_<P>_Rel_Lin` it is taken as
//!   sRGB-encoded. `<P>` is the input's primaries where JPEG XL names them (`SRG` BT.709, `202`
//!   BT.2020, `DCI` with D65: Display P3); other primaries are converted to BT.2020 once, with
//!   a note.
//! - `--intensity_target` is the luminance of PFM sample 1.0 in cd/m². The samples are scaled by
//!   a power of two (exact in binary floating point) so that this is an upper bound of the image
//!   where it can be: the field holds at most 65504 (a half float in the codestream), so a
//!   brighter image keeps samples above 1.0 (float PFM carries them).

use hdrcodec::core::{Channels, ColorPrimaries, EncodeSettings, Error, HdrImage, ImageCodec, Limits, Result};
use std::ffi::OsString;
use std::path::Path;

/// libjxl's encoder program.
pub const ENCODER: &str = "cjxl";
/// libjxl's decoder program.
pub const DECODER: &str = "djxl";
/// Where the programs come from, for "not installed" messages.
pub const PACKAGE: &str = "Debian libjxl-tools";

/// The largest `--intensity_target` a codestream records (a half float).
const MAX_INTENSITY_TARGET: f64 = 65504.0;

/// "cjxl v0.7.0" from `program --version`'s first line, or the name and "(version unknown)".
fn version(program: &str) -> String {
    super::version_text(program, "--version")
        .and_then(|t| {
            let mut words = t.split_whitespace();
            let (name, v) = (words.next()?, words.next()?);
            (name == program && v.starts_with('v')).then(|| format!("{name} {v}"))
        })
        .unwrap_or_else(|| format!("{program} (version unknown)"))
}

/// The encoder and its version: "cjxl v0.7.0".
pub fn encoder_version() -> String {
    version(ENCODER)
}

/// The decoder and its version: "djxl v0.7.0".
pub fn decoder_version() -> String {
    version(DECODER)
}

/// The bench input as cjxl is given it.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The PFM file (RGB, little-endian floats).
    pub pfm: Vec<u8>,
    /// JPEG XL's name of the primaries the PFM samples are in: `SRG`, `202` or `DCI`.
    pub primaries: &'static str,
    /// The primaries of the PFM samples.
    pub written_primaries: ColorPrimaries,
    /// The PFM samples are the image's times 2^-`exponent`.
    pub exponent: i32,
    /// cd/m² of PFM sample 1.0 (`--intensity_target`).
    pub intensity_target: f64,
    /// What was done to the samples, one sentence each.
    pub notes: Vec<String>,
}

/// JPEG XL's name for `p` in a `-x color_space=RGB_D65_<name>_Rel_Lin` description, if it has one.
fn jxl_primaries(p: ColorPrimaries) -> Option<&'static str> {
    match p {
        ColorPrimaries::Bt709 => Some("SRG"),
        ColorPrimaries::Bt2020 => Some("202"),
        ColorPrimaries::DisplayP3 => Some("DCI"),
        _ => None,
    }
}

/// The power of two by which samples up to `peak` (the largest finite |sample|) are divided so
/// that PFM sample 1.0 = `nits_per_unit` · 2^exponent cd/m² bounds the image, within
/// [`MAX_INTENSITY_TARGET`]: (exponent, intensity target).
pub fn exponent_for(peak: f32, nits_per_unit: f32) -> Result<(i32, f64)> {
    let nits = f64::from(nits_per_unit);
    if !(nits.is_finite() && nits > 0.0) {
        return Err(Error::invalid(format!("nits_per_unit {nits_per_unit} cannot be a JPEG XL intensity target")));
    }
    let mut e: i32 = if peak > 0.0 { f64::from(peak).log2().ceil().clamp(-60.0, 60.0) as i32 } else { 0 };
    while nits * 2f64.powi(e) > MAX_INTENSITY_TARGET {
        e -= 1;
    }
    if e < -100 {
        return Err(Error::unsupported(format!("nits_per_unit {nits_per_unit} is beyond JPEG XL's intensity target")));
    }
    Ok((e, nits * 2f64.powi(e)))
}

/// `image` (RGB; its primaries specified) as cjxl's linear PFM input: converted to BT.2020 when
/// JPEG XL names no primaries of its, scaled by a power of two ([`exponent_for`]), NaN and
/// infinities written as 0 (counted in a note).
pub fn prepare(image: &HdrImage) -> Result<Prepared> {
    let mut notes = Vec::new();
    let converted;
    let (image, primaries) = match jxl_primaries(image.color.primaries) {
        Some(p) => (image, p),
        None => {
            notes.push(format!(
                "converted from {} to BT.2020 (cjxl's colour descriptions name no such primaries)",
                image.color.primaries.name()
            ));
            converted = hdrcodec::core::color::convert_primaries(image, ColorPrimaries::Bt2020);
            (&converted, "202")
        }
    };
    let rgb = image.with_channels(Channels::Rgb);
    let peak = rgb.samples().iter().filter(|v| v.is_finite()).fold(0f32, |m, v| m.max(v.abs()));
    let (exponent, intensity_target) = exponent_for(peak, image.color.nits_per_unit)?;
    let scale = 2f32.powi(-exponent);
    let mut cleaned = 0;
    let samples: Vec<f32> = rgb
        .samples()
        .iter()
        .map(|&v| {
            if v.is_finite() {
                v * scale
            } else {
                cleaned += 1;
                0.0
            }
        })
        .collect();
    if cleaned > 0 {
        notes.push(format!("{cleaned} NaN or infinite samples written as 0 in cjxl's input"));
    }
    let scaled = HdrImage::new(rgb.width(), rgb.height(), Channels::Rgb, samples, rgb.color.clone())?;
    let pfm = hdrcodec::pfm::PfmCodec.encode(&scaled, &EncodeSettings::default())?;
    Ok(Prepared { pfm, primaries, written_primaries: image.color.primaries, exponent, intensity_target, notes })
}

/// cjxl's arguments: `input` (PFM) to `output` at distance `distance` (`0`: lossless), linear in
/// the prepared primaries, one thread.
pub fn encode_args(input: &Path, output: &Path, distance: &str, prepared: &Prepared) -> Vec<OsString> {
    let colour = format!("color_space=RGB_D65_{}_Rel_Lin", prepared.primaries);
    let intensity = format!("--intensity_target={}", prepared.intensity_target);
    super::args(&[&input, &output, &"-d", &distance, &"-x", &colour, &intensity, &"--num_threads=1"])
}

/// djxl's arguments: `input` to the PFM `output`, one thread.
pub fn decode_args(input: &Path, output: &Path) -> Vec<OsString> {
    super::args(&[&input, &output, &"--num_threads=1"])
}

/// djxl's PFM (`pfm`) read by our PFM decoder, scaled back and labelled as `reference` (its
/// size, primaries as written, `nits_per_unit`).
pub fn read_back(pfm: &[u8], prepared: &Prepared, reference: &HdrImage) -> Result<HdrImage> {
    let limits = Limits::default();
    let mut decoded = hdrcodec::pfm::PfmCodec.decode(pfm, &limits)?;
    if (decoded.width(), decoded.height()) != (reference.width(), reference.height()) {
        return Err(Error::invalid(format!(
            "djxl wrote a {}x{} image for a {}x{} input",
            decoded.width(),
            decoded.height(),
            reference.width(),
            reference.height()
        )));
    }
    let scale = 2f32.powi(prepared.exponent);
    decoded.samples_mut().iter_mut().for_each(|v| *v *= scale);
    decoded.color = reference.color.clone();
    decoded.color.primaries = prepared.written_primaries;
    Ok(decoded)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::ColorInfo;

    #[test]
    fn the_intensity_target_bounds_the_image_within_a_half_float() {
        // 100 cd/m² per unit, peak 3.0: samples / 4, 1.0 = 400 cd/m².
        assert_eq!(exponent_for(3.0, 100.0).unwrap(), (2, 400.0));
        // Exactly a power of two stays.
        assert_eq!(exponent_for(4.0, 100.0).unwrap(), (2, 400.0));
        // Dim images are scaled up: 1.0 = 100 · 2^-3.
        assert_eq!(exponent_for(0.1, 100.0).unwrap(), (-3, 12.5));
        // 1.6e5 units of 100 cd/m² would need 2^18 · 100: capped at 2^9 · 100 = 51200 ≤ 65504.
        assert_eq!(exponent_for(1.6e5, 100.0).unwrap(), (9, 51200.0));
        assert_eq!(exponent_for(0.0, 80.0).unwrap(), (0, 80.0));
        assert!(exponent_for(1.0, 0.0).is_err());
    }

    #[test]
    fn the_pfm_reads_back_to_the_same_samples() {
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 203.0, hdr10: None };
        let img = HdrImage::new(2, 1, Channels::Rgb, vec![0.5, 3.0, -0.25, 1e-3, f32::NAN, 7.0], color).unwrap();
        let p = prepare(&img).unwrap();
        assert_eq!((p.primaries, p.exponent, p.intensity_target), ("202", 3, 203.0 * 8.0));
        assert_eq!(p.notes.len(), 1, "{:?}", p.notes);
        let back = read_back(&p.pfm, &p, &img).unwrap();
        assert_eq!(back.samples(), [0.5, 3.0, -0.25, 1e-3, 0.0, 7.0]);
        assert_eq!(back.color.primaries, ColorPrimaries::Bt2020);
        let args = encode_args(Path::new("a.pfm"), Path::new("b.jxl"), "1", &p);
        let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(
            args,
            [
                "a.pfm",
                "b.jxl",
                "-d",
                "1",
                "-x",
                "color_space=RGB_D65_202_Rel_Lin",
                "--intensity_target=1624",
                "--num_threads=1"
            ]
        );
    }

    #[test]
    fn primaries_jpeg_xl_cannot_name_are_converted_to_bt2020() {
        let color = ColorInfo { primaries: ColorPrimaries::AcesAp0, ..ColorInfo::default() };
        let img = HdrImage::new(1, 1, Channels::Rgb, vec![1.0, 0.5, 0.25], color).unwrap();
        let p = prepare(&img).unwrap();
        assert_eq!((p.primaries, p.written_primaries), ("202", ColorPrimaries::Bt2020));
        assert!(p.notes[0].contains("to BT.2020"), "{:?}", p.notes);
    }
}
