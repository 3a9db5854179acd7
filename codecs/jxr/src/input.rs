//! Samples to the integers a codestream codes: the encoder's side of output formatting
//! (T.832 9.10; the decoder's side is [`crate::output`]), one stored pixel format at a time.
//!
//! Every conversion here is the exact inverse of what the decoder does with the integers:
//! [`SampleCoder::colour`] gives R, G and B codes (before the reversible colour transform and
//! the scaled-arithmetic shift) that `output` turns back into the stored samples, and those
//! samples back into the light they came from (within the format's precision). What a format
//! cannot hold (NaN, negative light in RGBE or the integer formats, light above the format's
//! top) is clipped and counted ([`Clipped`]), never dropped silently.

use crate::container::{OutputBitDepth, PixelFormat, PIXEL_FORMATS};
use crate::output::{float_to_int, half_bits_to_int, SampleTransfer, NITS_PER_UNIT};
use hdrcodec_core::transfer::{PqTransfer, SrgbTransfer};
use hdrcodec_core::{Error, Result};

/// How the samples are stored in the file (the `format` option).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFormat {
    /// 48bppRGBHalf (64bppRGBAHalf with alpha): IEEE half floats, linear scRGB (what Windows
    /// HDR screenshots use).
    Half,
    /// 128bppRGBFloat (128bppRGBAFloat with alpha): single floats, coded with
    /// [`FLOAT_MANTISSA`](crate::encoder::FLOAT_MANTISSA) mantissa bits.
    Float,
    /// 32bppRGBE: Radiance's shared exponent (8-bit mantissas, one 8-bit exponent), linear
    /// scRGB; no negative values, no alpha.
    Rgbe,
    /// 48bppRGBFixedPoint (64bppRGBAFixedPoint with alpha): signed 16-bit fixed point with 13
    /// fraction bits (s2.13), linear scRGB, −4 to 4 − 2^−13.
    Fixed,
    /// 64bppRGBHalf: half floats with a fourth, padding channel (what some Windows tools
    /// write); the same codestream as [`Half`](Self::Half), three coded channels. No alpha.
    HalfPadded,
    /// 24bppRGB (32bppBGRA with alpha): 8-bit codes of a transfer function.
    Rgb8(SampleTransfer),
    /// 48bppRGB (64bppRGBA with alpha): 16-bit codes of a transfer function.
    Rgb16(SampleTransfer),
    /// 32bppRGB101010: 10-bit codes of a transfer function (R in the low bits, as jxrlib
    /// packs it), 2 bits unused; no alpha. The Xbox's HDR captures: PQ, BT.2020.
    Rgb101010(SampleTransfer),
}

/// The `format` option's values, in the order the error message lists them.
const FORMAT_NAMES: &str = "half, float, rgbe, fixed, half4, rgb8, rgb16 or rgb101010";

impl SampleFormat {
    /// The format named by the `format` option (default `half`) with the `transfer` option
    /// (`srgb`, `pq` or `linear`), which only the integer formats take; each has its own
    /// default (rgb8: srgb; rgb16 and rgb101010: pq). A transfer for a linear format is an error.
    pub fn parse(format: Option<&str>, transfer: Option<&str>) -> Result<Self> {
        let t = match transfer {
            None => None,
            Some("srgb") => Some(SampleTransfer::Srgb),
            Some("pq") => Some(SampleTransfer::Pq),
            Some("linear") => Some(SampleTransfer::Linear),
            Some(other) => return Err(Error::invalid(format!("jxr: transfer={other}: expected srgb, pq or linear"))),
        };
        let name = format.unwrap_or("half");
        let linear = match name {
            "half" => Some(SampleFormat::Half),
            "float" => Some(SampleFormat::Float),
            "rgbe" => Some(SampleFormat::Rgbe),
            "fixed" => Some(SampleFormat::Fixed),
            "half4" => Some(SampleFormat::HalfPadded),
            _ => None,
        };
        if let Some(f) = linear {
            if let Some(t) = transfer {
                return Err(Error::invalid(format!(
                    "jxr: transfer={t} contradicts format={name}: {name} samples are linear light (transfer= is for rgb8, rgb16 and rgb101010)"
                )));
            }
            return Ok(f);
        }
        Ok(match name {
            "rgb8" => SampleFormat::Rgb8(t.unwrap_or(SampleTransfer::Srgb)),
            "rgb16" => SampleFormat::Rgb16(t.unwrap_or(SampleTransfer::Pq)),
            "rgb101010" => SampleFormat::Rgb101010(t.unwrap_or(SampleTransfer::Pq)),
            _ => return Err(Error::invalid(format!("jxr: format={name}: expected {FORMAT_NAMES}"))),
        })
    }

    /// The transfer function of an integer format; `None` for the linear formats.
    pub fn transfer(self) -> Option<SampleTransfer> {
        match self {
            SampleFormat::Rgb8(t) | SampleFormat::Rgb16(t) | SampleFormat::Rgb101010(t) => Some(t),
            _ => None,
        }
    }

    /// The pixel format written for an image with or without alpha (T.832 Table A.6); an
    /// error, before anything is written, for alpha in a format that has no alpha variant.
    pub fn pixel_format(self, alpha: bool) -> Result<&'static PixelFormat> {
        let name = match (self, alpha) {
            (SampleFormat::Half, false) => "48bppRGBHalf",
            (SampleFormat::Half, true) => "64bppRGBAHalf",
            (SampleFormat::Float, false) => "128bppRGBFloat",
            (SampleFormat::Float, true) => "128bppRGBAFloat",
            (SampleFormat::Rgbe, false) => "32bppRGBE",
            (SampleFormat::Fixed, false) => "48bppRGBFixedPoint",
            (SampleFormat::Fixed, true) => "64bppRGBAFixedPoint",
            (SampleFormat::HalfPadded, false) => "64bppRGBHalf",
            (SampleFormat::Rgb8(_), false) => "24bppRGB",
            (SampleFormat::Rgb8(_), true) => "32bppBGRA",
            (SampleFormat::Rgb16(_), false) => "48bppRGB",
            (SampleFormat::Rgb16(_), true) => "64bppRGBA",
            (SampleFormat::Rgb101010(_), false) => "32bppRGB101010",
            (f @ (SampleFormat::Rgbe | SampleFormat::HalfPadded | SampleFormat::Rgb101010(_)), true) => {
                return Err(Error::unsupported(format!(
                    "JPEG XR: format={} ({}) has no alpha channel; this image has one (choose half, float, fixed, rgb8 or rgb16, or drop the alpha first)",
                    f.option_name(),
                    f.pixel_format(false)?.name
                )))
            }
        };
        PIXEL_FORMATS.iter().find(|f| f.name == name).ok_or_else(|| Error::invalid(format!("no pixel format {name}")))
    }

    /// The `format` option's value for this format.
    pub fn option_name(self) -> &'static str {
        match self {
            SampleFormat::Half => "half",
            SampleFormat::Float => "float",
            SampleFormat::Rgbe => "rgbe",
            SampleFormat::Fixed => "fixed",
            SampleFormat::HalfPadded => "half4",
            SampleFormat::Rgb8(_) => "rgb8",
            SampleFormat::Rgb16(_) => "rgb16",
            SampleFormat::Rgb101010(_) => "rgb101010",
        }
    }

    /// OUTPUT_BITDEPTH of the codestream.
    pub fn bit_depth(self) -> OutputBitDepth {
        match self {
            SampleFormat::Half | SampleFormat::HalfPadded => OutputBitDepth::Bd16F,
            SampleFormat::Float => OutputBitDepth::Bd32F,
            SampleFormat::Rgbe | SampleFormat::Rgb8(_) => OutputBitDepth::Bd8,
            SampleFormat::Fixed => OutputBitDepth::Bd16S,
            SampleFormat::Rgb16(_) => OutputBitDepth::Bd16,
            SampleFormat::Rgb101010(_) => OutputBitDepth::Bd10,
        }
    }

    /// True for the 32-bit formats, which jxrlib always codes in unscaled arithmetic
    /// (`strenc.c`: no scaling for BD_32, BD_32S, BD_32F); we do the same.
    pub(crate) fn always_unscaled(self) -> bool {
        self == SampleFormat::Float
    }

    /// True when the integer codes are logarithmic in the light (half, float, RGBE: one code
    /// step is one ratio), which the luminance-adaptive HP quantizers assume. Fixed point is
    /// linear and the integer formats are already perceptual: one HP quantizer set for them.
    pub(crate) fn log_coded(self) -> bool {
        matches!(self, SampleFormat::Half | SampleFormat::HalfPadded | SampleFormat::Float | SampleFormat::Rgbe)
    }

    /// How many QP indices (16 per doubling of the step) to add to the quality's base index
    /// so that one quality means about the same error relative to the code range: 16·log2 of
    /// how much finer the format's codes are than half's around scRGB 1.0 (RGBE: 7 mantissa
    /// bits against 10, so −48; fixed point: 2^−13 against 2^−10, +48; 8-bit sRGB about a
    /// step of 1% near mid-grey against 0.1%, −48; 10-bit −16; 16-bit +80). Provisional.
    pub(crate) fn qp_offset(self) -> f32 {
        match self {
            SampleFormat::Half | SampleFormat::HalfPadded | SampleFormat::Float => 0.0,
            SampleFormat::Rgbe | SampleFormat::Rgb8(_) => -48.0,
            SampleFormat::Fixed => 48.0,
            SampleFormat::Rgb101010(_) => -16.0,
            SampleFormat::Rgb16(_) => 80.0,
        }
    }

    /// PTM_COLOR_INFO for this format, given what the primaries alone call for (`linear`:
    /// `[primaries, 8, 0, 1]` or `None` for BT.709): the integer formats always say their
    /// transfer (H.273: 13 sRGB, 16 PQ, 8 linear), so that a reader need not guess; the linear
    /// formats keep `linear`.
    pub(crate) fn ptm_color_info(self, linear: Option<[u8; 4]>) -> Option<[u8; 4]> {
        let Some(t) = self.transfer() else { return linear };
        let code = match t {
            SampleTransfer::Srgb => 13,
            SampleTransfer::Pq => 16,
            SampleTransfer::Linear => 8,
        };
        Some([linear.map_or(1, |p| p[0]), code, 0, 1])
    }
}

/// What the conversion could not store as it was, counted over the image (colour and alpha).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Clipped {
    /// NaN samples, written as 0.
    pub nan: usize,
    /// Samples below the format's range (negative light in RGBE and the integer formats,
    /// below −4 in fixed point), written as its bottom.
    pub below: usize,
    /// Samples above the format's range (infinities included), written as its top.
    pub above: usize,
}

impl Clipped {
    /// Both counts together.
    pub fn merge(self, o: Clipped) -> Clipped {
        Clipped { nan: self.nan + o.nan, below: self.below + o.below, above: self.above + o.above }
    }

    /// One sentence per kind of clipping, for the encode report.
    pub fn notes(&self, format: SampleFormat) -> Vec<String> {
        let mut notes = Vec::new();
        if self.nan > 0 {
            notes.push(format!("{} NaN samples were written as 0", self.nan));
        }
        let (low, high) = match format {
            SampleFormat::Half | SampleFormat::HalfPadded => {
                ("", "infinite or beyond ±65504 (half float) were clipped to ±65504")
            }
            SampleFormat::Float => ("", "infinite were clipped to the largest float"),
            SampleFormat::Rgbe => (
                "negative (RGBE holds no negative light) were written as 0",
                "infinite or beyond RGBE's largest value (about 1.7e38) were clipped to it",
            ),
            SampleFormat::Fixed => (
                "below −4 (s2.13 fixed point) were clipped to −4",
                "infinite or at least 4 (s2.13 fixed point) were clipped to 4 − 2^−13",
            ),
            SampleFormat::Rgb8(t) | SampleFormat::Rgb16(t) | SampleFormat::Rgb101010(t) => match t {
                SampleTransfer::Srgb => (
                    "negative were written as 0",
                    "above the sRGB white (80 cd/m², scRGB 1.0; alpha above 1) were clipped to it",
                ),
                SampleTransfer::Linear => (
                    "negative were written as 0",
                    "above the linear maximum (80 cd/m², scRGB 1.0; alpha above 1) were clipped to it",
                ),
                SampleTransfer::Pq => {
                    ("negative were written as 0", "above PQ's peak (10 000 cd/m²; alpha above 1) were clipped to it")
                }
            },
        };
        if self.below > 0 {
            notes.push(format!("{} samples {low}", self.below));
        }
        if self.above > 0 {
            notes.push(format!("{} samples {high}", self.above));
        }
        notes
    }
}

/// Converts samples (linear light, in units of `nits_per_unit`) to the integer codes of a
/// format.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleCoder {
    format: SampleFormat,
    /// The image's samples to scRGB (1.0 = 80 cd/m²).
    scale: f32,
}

/// The largest value an RGBE pixel holds: mantissa 255 with exponent 255, as the decoder
/// reads it, (255 + 0.5) · 2^(255 − 136).
const RGBE_MAX: f64 = 255.5 * (1u128 << 119) as f64;

impl SampleCoder {
    /// A coder for `format` and an image whose 1.0 is `nits_per_unit` cd/m².
    pub fn new(format: SampleFormat, nits_per_unit: f32) -> Self {
        SampleCoder { format, scale: nits_per_unit / NITS_PER_UNIT }
    }

    /// The R, G, B integer codes of one pixel: what the decoder's output formatting turns
    /// back into the stored samples. The integer formats' codes are centred (the bias the
    /// decoder adds, 128, 512 or 32768, taken off); not yet shifted for scaled arithmetic.
    pub fn colour(&self, rgb: [f32; 3], clipped: &mut Clipped) -> [i32; 3] {
        let s = self.scale;
        match self.format {
            SampleFormat::Rgbe => rgbe_to_int(f32_to_rgbe(rgb.map(|v| v * s), clipped)),
            _ => rgb.map(|v| self.sample(v, true, clipped)),
        }
    }

    /// The integer code of an alpha sample: coded like a colour sample of the format, but
    /// not light (no scaling, no transfer function: 0-1 over the code range for the integer
    /// formats).
    pub fn alpha(&self, a: f32, clipped: &mut Clipped) -> i32 {
        self.sample(a, false, clipped)
    }

    fn sample(&self, v: f32, light: bool, clipped: &mut Clipped) -> i32 {
        if v.is_nan() {
            clipped.nan += 1;
            return 0;
        }
        let v = if light { v * self.scale } else { v };
        match self.format {
            SampleFormat::Half | SampleFormat::HalfPadded => {
                let h = crate::output::f32_to_half_bits(v);
                if h & 0x7fff == 0x7c00 {
                    clipped.above += 1;
                    let max = half::f16::MAX.to_bits();
                    half_bits_to_int(if v < 0.0 { max | 0x8000 } else { max })
                } else {
                    half_bits_to_int(h)
                }
            }
            SampleFormat::Float => {
                clipped.above += usize::from(v.is_infinite());
                float_to_int(
                    v.clamp(f32::MIN, f32::MAX),
                    crate::encoder::FLOAT_EXP_BIAS as i8,
                    u32::from(crate::encoder::FLOAT_MANTISSA),
                )
            }
            SampleFormat::Fixed => {
                let code = (f64::from(v) * 8192.0).round();
                if code < -32768.0 {
                    clipped.below += 1;
                } else if code > 32767.0 {
                    clipped.above += 1;
                }
                code.clamp(-32768.0, 32767.0) as i32
            }
            SampleFormat::Rgbe => unreachable!("RGBE is coded a pixel at a time"),
            SampleFormat::Rgb8(t) => unsigned_code(v, light.then_some(t), 8, clipped) - 128,
            SampleFormat::Rgb16(t) => unsigned_code(v, light.then_some(t), 16, clipped) - 32768,
            SampleFormat::Rgb101010(t) => unsigned_code(v, light.then_some(t), 10, clipped) - 512,
        }
    }
}

/// The `bits`-bit code of a scRGB sample `v` through transfer `t` (sRGB and linear: 1.0 is
/// the top code; PQ: absolute, 80 cd/m² per unit, 10 000 cd/m² the top code), or of an alpha
/// sample (`t` None: 0-1 linearly). Rounded to the nearest code of the signal, the inverse of
/// the decoder's code / maximum.
fn unsigned_code(v: f32, t: Option<SampleTransfer>, bits: u32, clipped: &mut Clipped) -> i32 {
    let v = f64::from(v);
    let max = f64::from((1u32 << bits) - 1);
    let top = match t {
        Some(SampleTransfer::Pq) => PqTransfer::PEAK_NITS / f64::from(NITS_PER_UNIT),
        _ => 1.0,
    };
    if v < 0.0 {
        clipped.below += 1;
    } else if v > top {
        clipped.above += 1;
    }
    let v = v.clamp(0.0, top);
    let signal = match t {
        Some(SampleTransfer::Srgb) => SrgbTransfer::encode(v),
        Some(SampleTransfer::Pq) => PqTransfer::encode(v * f64::from(NITS_PER_UNIT)),
        Some(SampleTransfer::Linear) | None => v,
    };
    (signal * max).round().clamp(0.0, max) as i32
}

/// Radiance's RGBE of a linear RGB triple, as the decoder reads it back:
/// `(m + 0.5) · 2^(E − 136)`, so the mantissas are truncated (the largest in 128-255).
/// NaN and negative samples become 0, values above [`RGBE_MAX`] (infinities included) that;
/// each counted. Values whose largest channel is below 2^−128 become black.
pub(crate) fn f32_to_rgbe(rgb: [f32; 3], clipped: &mut Clipped) -> [u8; 4] {
    let v = rgb.map(|c| {
        if c.is_nan() {
            clipped.nan += 1;
            0.0
        } else if c < 0.0 {
            clipped.below += 1;
            0.0
        } else if f64::from(c) > RGBE_MAX {
            clipped.above += 1;
            RGBE_MAX
        } else {
            f64::from(c)
        }
    });
    let m = v[0].max(v[1]).max(v[2]);
    if m == 0.0 {
        return [0; 4];
    }
    // m = f · 2^e with f in [0.5, 1): the largest mantissa floor(f · 256) is 128-255.
    let e = ((m.to_bits() >> 52) & 0x7ff) as i32 - 1022;
    if e + 128 < 1 {
        return [0; 4];
    }
    let scale = 2f64.powi(8 - e);
    let mant = v.map(|c| (c * scale).floor().min(255.0) as u8);
    [mant[0], mant[1], mant[2], (e + 128) as u8]
}

/// The integers that output formatting (`output::int_to_rgbe`) turns into these RGBE bytes:
/// the inverse of jxrlib's `inverseConvertRGBE`. An integer `v` codes a mini-float with 7
/// mantissa bits: below 256 the value `v` at exponent 1, above it exponent `v >> 7` and
/// mantissa `128 + (v & 127)`. A channel's mantissa `t` at the shared exponent `e` is the
/// value `t · 2^(e − 1)` in that scale, which such an integer holds exactly (t has at most 8
/// significant bits), and the decoder's rounding shift (by at most 9) gives `t` back from
/// it. Exponent 0 is black. Exact for normalized RGBE (the largest mantissa at least 128 when E > 1, as
/// [`f32_to_rgbe`] writes).
pub(crate) fn rgbe_to_int(rgbe: [u8; 4]) -> [i32; 3] {
    let e = i32::from(rgbe[3]);
    if e == 0 {
        return [0; 3];
    }
    [0, 1, 2].map(|c| {
        let t = i32::from(rgbe[c]);
        if t == 0 {
            // 0 has exponent 0, so the decoder shifts by e + 1, modulo 32 as jxrlib's C shift
            // runs (`output::int_to_rgbe`): a shift of 0 when e + 1 is a multiple of 32 would
            // give mantissa 1. Then the value with mantissa 128 at exponent e − 8 instead,
            // which a shift by 9 takes to 0.
            return if (e + 1) % 32 == 0 { (e - 8) * 128 } else { 0 };
        }
        let top = 31 - t.leading_zeros() as i32; // floor(log2 t), 0-7
        if top + e - 1 < 8 {
            // Below 256: exponent 1, the value itself.
            t << (e - 1)
        } else {
            // Normalize the mantissa to 128-255 and move the rest into the exponent.
            let m = t << (7 - top);
            let exp = top + e - 7;
            (exp - 1) * 128 + m
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::int_to_rgbe;
    use crate::testing::rng;

    #[test]
    fn rgbe_integers_give_the_bytes_back() {
        // Every exponent with every mantissa in each position, the largest normalized.
        for e in 1..=255u8 {
            for t in 0..=255u8 {
                for top in [128u8, 200, 255] {
                    let top = if e == 1 { top.max(t) } else { top };
                    for bytes in [[top, t, 0, e], [t, top, 1, e], [2, t.min(top), top, e]] {
                        if t > top && e > 1 {
                            continue;
                        }
                        let [r, g, b] = rgbe_to_int(bytes);
                        assert_eq!(int_to_rgbe(r, g, b), bytes, "{bytes:?} -> {:?}", [r, g, b]);
                    }
                }
            }
        }
        // Random normalized pixels from floats.
        let mut r = rng(7);
        for _ in 0..200_000 {
            let mut f = || f32::from_bits((r() as u32 & 0x7fff_ffff) % 0x7f00_0000);
            let mut clipped = Clipped::default();
            let bytes = f32_to_rgbe([f(), f(), f()], &mut clipped);
            let [r, g, b] = rgbe_to_int(bytes);
            assert_eq!(int_to_rgbe(r, g, b), bytes);
        }
        assert_eq!(rgbe_to_int([9, 9, 9, 0]), [0; 3]);
    }

    #[test]
    fn rgbe_bytes_decode_to_the_light_within_a_mantissa_step() {
        let mut clipped = Clipped::default();
        for v in [[1.0f32, 0.5, 0.25], [1e-20, 3e-21, 0.0], [6.5e4, 1.0, 1e3], [1e30, 1e29, 1e-5]] {
            let [r, g, b, e] = f32_to_rgbe(v, &mut clipped);
            let scale = 2f64.powi(i32::from(e) - 136);
            let m = f64::from(v[0].max(v[1]).max(v[2]));
            for (byte, want) in [r, g, b].into_iter().zip(v) {
                let got = (f64::from(byte) + 0.5) * scale;
                assert!((got - f64::from(want)).abs() <= m / 256.0, "{v:?}: {got} for {want}");
            }
        }
        assert_eq!(clipped, Clipped::default());
        let bytes = f32_to_rgbe([f32::NAN, -1.0, f32::INFINITY], &mut clipped);
        assert_eq!(clipped, Clipped { nan: 1, below: 1, above: 1 });
        assert_eq!(bytes, [0, 0, 255, 255]);
        assert_eq!(f32_to_rgbe([1e-39, 0.0, 0.0], &mut Clipped::default()), [0; 4]);
    }

    #[test]
    fn options_name_the_formats_and_transfers() {
        let p = |f: Option<&str>, t: Option<&str>| SampleFormat::parse(f, t);
        assert_eq!(p(None, None).unwrap(), SampleFormat::Half);
        assert_eq!(p(Some("rgbe"), None).unwrap(), SampleFormat::Rgbe);
        assert_eq!(p(Some("half4"), None).unwrap(), SampleFormat::HalfPadded);
        assert_eq!(p(Some("rgb8"), None).unwrap(), SampleFormat::Rgb8(SampleTransfer::Srgb));
        assert_eq!(p(Some("rgb16"), None).unwrap(), SampleFormat::Rgb16(SampleTransfer::Pq));
        assert_eq!(p(Some("rgb101010"), None).unwrap(), SampleFormat::Rgb101010(SampleTransfer::Pq));
        assert_eq!(p(Some("rgb8"), Some("pq")).unwrap(), SampleFormat::Rgb8(SampleTransfer::Pq));
        assert_eq!(p(Some("rgb16"), Some("linear")).unwrap(), SampleFormat::Rgb16(SampleTransfer::Linear));
        for (f, t) in
            [(Some("half"), Some("pq")), (None, Some("srgb")), (Some("rgb8"), Some("hlg")), (Some("rgb12"), None)]
        {
            assert!(p(f, t).is_err(), "{f:?} {t:?}");
        }
        let e = p(Some("float"), Some("pq")).unwrap_err().to_string();
        assert!(e.contains("contradicts"), "{e}");
        assert!(SampleFormat::Rgbe.pixel_format(true).is_err());
        assert!(SampleFormat::Rgb101010(SampleTransfer::Pq).pixel_format(true).is_err());
        assert_eq!(SampleFormat::Rgb8(SampleTransfer::Srgb).pixel_format(true).unwrap().name, "32bppBGRA");
        assert_eq!(SampleFormat::Fixed.pixel_format(true).unwrap().name, "64bppRGBAFixedPoint");
        // Every format's pixel format has the bit depth the codestream is written with.
        for f in [
            SampleFormat::Half,
            SampleFormat::Float,
            SampleFormat::Rgbe,
            SampleFormat::Fixed,
            SampleFormat::HalfPadded,
            SampleFormat::Rgb8(SampleTransfer::Srgb),
            SampleFormat::Rgb16(SampleTransfer::Srgb),
            SampleFormat::Rgb101010(SampleTransfer::Srgb),
        ] {
            assert_eq!(f.pixel_format(false).unwrap().bit_depth, f.bit_depth(), "{f:?}");
            assert_eq!(SampleFormat::parse(Some(f.option_name()), None).unwrap().option_name(), f.option_name());
        }
    }

    #[test]
    fn integer_codes_clip_and_count() {
        let coder = SampleCoder::new(SampleFormat::Rgb8(SampleTransfer::Srgb), 80.0);
        let mut c = Clipped::default();
        // Linear 0.5 is sRGB signal 0.7354 (code 187.5); white is scRGB 1.0.
        assert_eq!(coder.colour([0.0, 1.0, 0.5], &mut c), [-128, 127, 188 - 128]);
        assert_eq!(c, Clipped::default());
        assert_eq!(coder.colour([-0.5, 2.0, f32::NAN], &mut c), [-128, 127, 0]);
        assert_eq!(c, Clipped { nan: 1, below: 1, above: 1 });
        // PQ: 10 000 cd/m² is the top code, 100 cd/m² about 0.508.
        let pq = SampleCoder::new(SampleFormat::Rgb101010(SampleTransfer::Pq), 100.0);
        let mut c = Clipped::default();
        assert_eq!(
            pq.colour([100.0, 1.0, 0.0], &mut c),
            [1023 - 512, (0.508_078 * 1023.0f64).round() as i32 - 512, -512]
        );
        assert_eq!(c, Clipped::default());
        // Fixed point: 13 fraction bits, −4 to 4.
        let fixed = SampleCoder::new(SampleFormat::Fixed, 80.0);
        assert_eq!(fixed.colour([1.0, -0.5, 5.0], &mut c), [8192, -4096, 32767]);
        assert_eq!(fixed.alpha(-9.0, &mut c), -32768);
        assert_eq!(c, Clipped { nan: 0, below: 1, above: 1 });
        // Alpha is linear, not through the transfer.
        assert_eq!(SampleCoder::new(SampleFormat::Rgb16(SampleTransfer::Pq), 80.0).alpha(0.5, &mut c), 0);
    }
}
