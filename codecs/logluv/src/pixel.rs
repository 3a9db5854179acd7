//! The three LogLuv pixel encodings (Larson 1998), both directions, with the quantisation,
//! rounding and clamping of libtiff's `tif_luv.c` in its no-dither mode
//! (`SGILOGENCODE_NODITHER`): encoders truncate toward zero, decoders return the centre of the
//! quantisation interval. Luminance is CIE Y in the file's units (multiply by STONITS for cd/m²).
//!
//! - **LogL16**: sign bit + 15-bit `Le = ⌊256·(log2 Y + 64)⌋`, i.e. 1/256-stop steps
//!   (0.27 %) from 2^-64 ≈ 5.4e-20 to 2^64 ≈ 1.8e19: 38 orders of magnitude.
//! - **LogLuv32**: LogL16 in the top 16 bits, then `⌊410·u'⌋` and `⌊410·v'⌋` in 8 bits each.
//! - **LogLuv24**: 10-bit `⌊64·(log2 Y + 12)⌋` (1/64-stop steps, 1.1 %, from 2^-12 to 2^4, about
//!   4.8 orders of magnitude) above a 14-bit index into the u'v' grid ([`crate::uvgrid`]).

use crate::uvgrid::{c_int, uv_decode, uv_encode, U_NEUTRAL, V_NEUTRAL};
use std::f64::consts::LN_2;
use std::sync::OnceLock;

/// `log2` as the reference computes it, `ln(x) / ln 2` (not the C99 `log2`): the last bit of the
/// result decides a truncation now and then, so the formula has to be the same.
#[inline]
fn log2(x: f64) -> f64 {
    (1.0 / LN_2) * x.ln()
}

/// Largest |Y| LogL16 represents (2^64 less half a step); beyond it the code saturates.
const L16_MAX: f64 = 1.8371976e19;
/// Smallest |Y| LogL16 represents; below it Y encodes as 0.
const L16_MIN: f64 = 5.4136769e-20;

/// Encodes luminance `y` as LogL16 (two's-complement-free sign-magnitude: bit 15 is the sign).
/// |Y| ≥ 1.8371976e19 saturates to 0x7fff (0xffff when negative); |Y| ≤ 5.4136769e-20 and NaN
/// give 0.
#[inline]
pub fn logl16_from_y(y: f64) -> u16 {
    logl16_code(y) as u16
}

/// The encoder as a C `int`, before it is stored in 16 bits (LogLuv32 shifts the whole int).
#[inline]
fn logl16_code(y: f64) -> i32 {
    if y >= L16_MAX {
        0x7fff
    } else if y <= -L16_MAX {
        0xffff
    } else if y > L16_MIN {
        c_int(256.0 * (log2(y) + 64.0))
    } else if y < -L16_MIN {
        !0x7fff | c_int(256.0 * (log2(-y) + 64.0))
    } else {
        0
    }
}

/// Decodes LogL16 to luminance (negative when bit 15 is set; 0 for a zero magnitude).
#[inline]
pub fn logl16_to_y(p: u16) -> f64 {
    let le = p & 0x7fff;
    if le == 0 {
        return 0.0;
    }
    let y = (LN_2 / 256.0 * (f64::from(le) + 0.5) - LN_2 * 64.0).exp();
    if p & 0x8000 != 0 {
        -y
    } else {
        y
    }
}

/// Encodes luminance as the 10-bit log code of LogLuv24: Y ≥ 15.742 saturates to 1023, Y ≤
/// 0.00024283 (and any negative Y) gives 0.
#[inline]
pub fn logl10_from_y(y: f64) -> u32 {
    logl10_code(y) as u32
}

#[inline]
fn logl10_code(y: f64) -> i32 {
    if y >= 15.742 {
        0x3ff
    } else if y <= 0.00024283 {
        0
    } else {
        c_int(64.0 * (log2(y) + 12.0))
    }
}

/// Decodes the 10-bit log code of LogLuv24 (0 is black).
#[inline]
pub fn logl10_to_y(p: u32) -> f64 {
    if p == 0 {
        return 0.0;
    }
    (LN_2 / 64.0 * (f64::from(p) + 0.5) - LN_2 * 12.0).exp()
}

/// CIE 1976 u'v' of XYZ as the encoders compute it, with the neutral point for black
/// (`luminance_code == 0`) and for a non-positive denominator.
#[inline]
fn xyz_to_uv(xyz: [f32; 3], luminance_code: i32) -> (f64, f64) {
    let [x, y, z] = xyz.map(f64::from);
    let s = x + 15.0 * y + 3.0 * z;
    if luminance_code == 0 || s <= 0.0 {
        (U_NEUTRAL, V_NEUTRAL)
    } else {
        (4.0 * x / s, 9.0 * y / s)
    }
}

/// The chromaticity factors (X/Y, Z/Y) of u'v': XYZ = (fx·Y, Y, fz·Y).
#[inline]
fn uv_factors(u: f64, v: f64) -> (f64, f64) {
    let s = 1.0 / (6.0 * u - 16.0 * v + 12.0);
    let x = 9.0 * u * s;
    let y = 4.0 * v * s;
    (x / y, (1.0 - x - y) / y)
}

#[inline]
fn scale_xyz(l: f64, (fx, fz): (f64, f64)) -> [f32; 3] {
    [(fx * l) as f32, l as f32, (fz * l) as f32]
}

/// Encodes CIE XYZ as LogLuv32: `Le << 16 | ue << 8 | ve`, where `ue = ⌊410·u'⌋` and
/// `ve = ⌊410·v'⌋` are clamped to 0..=255 and black or undefined chromaticity uses the neutral
/// point.
#[inline]
pub fn logluv32_from_xyz(xyz: [f32; 3]) -> u32 {
    let le = logl16_code(f64::from(xyz[1]));
    let (u, v) = xyz_to_uv(xyz, le);
    let quantise = |c: f64| if c <= 0.0 { 0 } else { (c_int(410.0 * c) as u32).min(255) };
    (le as u32) << 16 | quantise(u) << 8 | quantise(v)
}

/// Decodes LogLuv32 to CIE XYZ. Like libtiff, a negative or zero luminance decodes as black
/// (the sign survives only in the raw word and in [`logl16_to_y`]).
#[inline]
pub fn logluv32_to_xyz(p: u32) -> [f32; 3] {
    let l = logl16_to_y((p >> 16) as u16);
    if l <= 0.0 {
        return [0.0; 3];
    }
    let u = 1.0 / 410.0 * (f64::from(p >> 8 & 0xff) + 0.5);
    let v = 1.0 / 410.0 * (f64::from(p & 0xff) + 0.5);
    scale_xyz(l, uv_factors(u, v))
}

/// Encodes CIE XYZ as LogLuv24: `Le << 14 | uv index`.
#[inline]
pub fn logluv24_from_xyz(xyz: [f32; 3]) -> u32 {
    let le = logl10_code(f64::from(xyz[1]));
    let (u, v) = xyz_to_uv(xyz, le);
    // A NaN luminance makes C's `(int)` produce INT_MIN, whose shifted value is 0; wrapping
    // arithmetic reproduces that instead of panicking.
    (le as u32).wrapping_shl(14) | uv_encode(u, v)
}

/// Decodes LogLuv24 (the low 24 bits of `p`) to CIE XYZ; an index past the grid decodes as the
/// neutral colour.
#[inline]
pub fn logluv24_to_xyz(p: u32) -> [f32; 3] {
    let l = logl10_to_y(p >> 14 & 0x3ff);
    if l <= 0.0 {
        return [0.0; 3];
    }
    let (u, v) = uv_decode(p & 0x3fff).unwrap_or((U_NEUTRAL, V_NEUTRAL));
    scale_xyz(l, uv_factors(u, v))
}

/// Table-driven decoders that give exactly the values of the functions above: luminance and
/// chromaticity factors are looked up rather than recomputed (no `exp`, no divisions per pixel).
pub(crate) struct Tables {
    /// LogL16 magnitude code → Y (index 0 is 0).
    l16: Vec<f64>,
    /// LogLuv32 `ue << 8 | ve` → (X/Y, Z/Y).
    uv32: Vec<(f64, f64)>,
    /// LogLuv24 10-bit code → Y.
    l10: Vec<f64>,
    /// LogLuv24 14-bit chroma → (X/Y, Z/Y).
    uv24: Vec<(f64, f64)>,
}

impl Tables {
    /// The shared tables, built on first use (about 1.4 MB, a few milliseconds).
    pub(crate) fn get() -> &'static Tables {
        static T: OnceLock<Tables> = OnceLock::new();
        T.get_or_init(|| Tables {
            l16: (0..0x8000u16).map(logl16_to_y).collect(),
            uv32: (0..0x10000u32)
                .map(|c| {
                    let u = 1.0 / 410.0 * (f64::from(c >> 8) + 0.5);
                    let v = 1.0 / 410.0 * (f64::from(c & 0xff) + 0.5);
                    uv_factors(u, v)
                })
                .collect(),
            l10: (0..0x400u32).map(logl10_to_y).collect(),
            uv24: (0..0x4000u32)
                .map(|c| {
                    let (u, v) = uv_decode(c).unwrap_or((U_NEUTRAL, V_NEUTRAL));
                    uv_factors(u, v)
                })
                .collect(),
        })
    }

    /// [`logluv32_to_xyz`] by table.
    #[inline]
    pub(crate) fn luv32(&self, p: u32) -> [f32; 3] {
        if p & 0x8000_0000 != 0 {
            return [0.0; 3];
        }
        let l = self.l16[(p >> 16 & 0x7fff) as usize];
        if l <= 0.0 {
            return [0.0; 3];
        }
        scale_xyz(l, self.uv32[(p & 0xffff) as usize])
    }

    /// [`logluv24_to_xyz`] by table.
    #[inline]
    pub(crate) fn luv24(&self, p: u32) -> [f32; 3] {
        let l = self.l10[(p >> 14 & 0x3ff) as usize];
        if l <= 0.0 {
            return [0.0; 3];
        }
        scale_xyz(l, self.uv24[(p & 0x3fff) as usize])
    }

    /// [`logl16_to_y`] by table, as the `f32` a float decoder returns.
    #[inline]
    pub(crate) fn l16(&self, p: u16) -> f32 {
        let y = self.l16[(p & 0x7fff) as usize] as f32;
        // A zero magnitude is +0 whatever the sign bit.
        if p & 0x8000 != 0 && y != 0.0 {
            -y
        } else {
            y
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logl16_range_and_step_match_larson() {
        // Larson 1998: LogL16 covers 2^-64 .. 2^64 in steps of 1/256 stop.
        assert_eq!(logl16_from_y(1.0), 64 * 256);
        assert_eq!(logl16_from_y(2.0), 65 * 256);
        assert_eq!(logl16_from_y(1e30), 0x7fff);
        assert_eq!(logl16_from_y(-1e30), 0xffff);
        assert_eq!(logl16_from_y(1e-25), 0);
        assert_eq!(logl16_from_y(f64::NAN), 0);
        assert_eq!(logl16_from_y(-1.0), 0x8000 | (64 * 256));
        // Centre of the interval: 2^(0.5/256).
        let centre = (0.5f64 / 256.0).exp2();
        assert!((logl16_to_y(64 * 256) / centre - 1.0).abs() < 1e-14);
        assert!((logl16_to_y(0x8000 | (64 * 256)) / -centre - 1.0).abs() < 1e-14);
        assert_eq!(logl16_to_y(0x8000).to_bits(), 0.0f64.to_bits());
    }

    #[test]
    fn logluv32_white_round_trip() {
        // Equal-energy white: u' = 4/19, v' = 9/19 → ⌊410·u'⌋ = 86, ⌊410·v'⌋ = 194.
        let p = logluv32_from_xyz([1.0, 1.0, 1.0]);
        assert_eq!(p, (64 * 256) << 16 | 86 << 8 | 194);
        let xyz = logluv32_to_xyz(p);
        for c in xyz {
            assert!((c - 1.0).abs() < 0.01, "{xyz:?}");
        }
        assert_eq!(logluv32_to_xyz(logluv32_from_xyz([-1.0, -2.0, -1.0])), [0.0; 3]);
    }

    #[test]
    fn logluv24_clamps_its_luminance_range() {
        assert_eq!(logluv24_from_xyz([100.0, 100.0, 100.0]) >> 14, 0x3ff);
        assert_eq!(logluv24_from_xyz([1e-5, 1e-5, 1e-5]) >> 14, 0);
        assert_eq!(logl10_from_y(1.0), 12 * 64);
        // D65 white lands in the cell that contains it: u'v' within half a cell diagonal.
        let d65 = [0.9505f32, 1.0, 1.089];
        let xyz = logluv24_to_xyz(logluv24_from_xyz(d65));
        let uv = |p: [f32; 3]| xyz_to_uv(p, 1);
        let ((u0, v0), (u1, v1)) = (uv(d65), uv(xyz));
        assert!((u1 - u0).hypot(v1 - v0) <= 0.0035 * 0.5f64.sqrt(), "{xyz:?}");
        assert!((xyz[1] - 1.0).abs() < 0.006);
    }

    #[test]
    fn tables_agree_with_the_direct_decoders() {
        let t = Tables::get();
        for p in (0..=u32::MAX).step_by(65521) {
            assert_eq!(t.luv32(p).map(f32::to_bits), logluv32_to_xyz(p).map(f32::to_bits), "{p:#x}");
            let p24 = p & 0xff_ffff;
            assert_eq!(t.luv24(p24).map(f32::to_bits), logluv24_to_xyz(p24).map(f32::to_bits), "{p24:#x}");
        }
        for p in 0..=u16::MAX {
            assert_eq!(t.l16(p).to_bits(), (logl16_to_y(p) as f32).to_bits());
        }
    }
}
