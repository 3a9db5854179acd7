//! A block's texels as the encoder works on them: channel planes of half-ints and of the same
//! values in the interpolation domain (see `block.rs` for both working spaces), the conversions
//! into them from half bits and from linear `f32`, and the fixed-order reductions over a plane
//! that the later steps share.
// Fixed-size index loops over texel lanes are the vectorisable form used throughout.
#![allow(clippy::needless_range_loop)]

/// One value per texel (row-major).
pub(super) type Plane = [f32; 16];

/// A block ready for encoding, as channel planes.
pub(crate) struct Texels {
    /// The source half floats as sign-magnitude integers (exact in `f32`).
    pub(super) half: [Plane; 3],
    /// The same values in the interpolation domain (the centre of the interval that decodes to
    /// each half).
    pub(super) target: [Plane; 3],
}

/// Reads half bits as a sign-magnitude integer.
#[inline(always)]
fn half_to_int(h: u16) -> i32 {
    if h & 0x8000 != 0 {
        -((h & 0x7FFF) as i32)
    } else {
        h as i32
    }
}

/// Replaces what BC6H cannot store, as the Direct3D specification advises: NaN becomes 0,
/// infinities the largest finite half of the same sign, and for UF16 any negative value 0.
pub(crate) fn sanitize_half(h: u16, signed: bool) -> u16 {
    let magnitude = h & 0x7FFF;
    let negative = h & 0x8000 != 0;
    if magnitude > 0x7C00 {
        return 0; // NaN
    }
    let magnitude = magnitude.min(0x7BFF);
    if negative {
        if signed && magnitude != 0 {
            0x8000 | magnitude
        } else {
            0
        }
    } else {
        magnitude
    }
}

/// Converts a linear `f32` straight to the sanitised half-int (see [`sanitize_half`]): NaN → 0,
/// negatives → 0 unless `S` (signed), magnitudes clamped to 65504, then IEEE round-to-nearest-
/// even to half precision. Branch-free bit arithmetic, so a loop over a block vectorises; the
/// unit tests compare it with the `half` crate on every class of input.
#[inline(always)]
pub(crate) fn f32_to_half_int<const S: bool>(v: f32) -> i32 {
    let v = if S {
        if v.is_nan() {
            0.0
        } else {
            v
        }
    } else if v > 0.0 {
        v
    } else {
        0.0 // negatives, -0.0 and NaN
    };
    let v = v.clamp(-65504.0, 65504.0);
    let bits = v.to_bits();
    let a = bits & 0x7FFF_FFFF;
    // Normal halves: rebias the exponent (15 - 127) and round the 13 dropped bits to nearest
    // even (add 0xFFF plus the lowest kept bit; a carry into the exponent is the right answer).
    let normal = a.wrapping_add(0xC800_0FFF).wrapping_add((a >> 13) & 1) >> 13;
    // Subnormal halves (below 2^-14): adding 0.5 puts the half ulp (2^-24) at the f32 ulp of 0.5,
    // so the FPU's own round-to-nearest-even does the work; the mantissa bits are the result.
    let sub = (f32::from_bits(a) + 0.5).to_bits().wrapping_sub(0x3F00_0000);
    let m = if a < 0x3880_0000 { sub } else { normal } as i32;
    if bits >> 31 != 0 {
        -m
    } else {
        m
    }
}

impl Texels {
    /// Prepares half texels (row-major `[r, g, b]` bits), sanitised first (see
    /// [`sanitize_half`]).
    #[inline(always)]
    pub(crate) fn new<const S: bool>(texels: &[[u16; 3]; 16]) -> Texels {
        let mut half = [[0f32; 16]; 3];
        for (i, t) in texels.iter().enumerate() {
            for c in 0..3 {
                half[c][i] = half_to_int(sanitize_half(t[c], S)) as f32;
            }
        }
        Texels::from_half_ints::<S>(half)
    }

    /// Prepares linear `f32` channel planes (converted by [`f32_to_half_int`]).
    #[inline(always)]
    pub(crate) fn from_f32<const S: bool>(rgb: &[Plane; 3]) -> Texels {
        let mut half = [[0f32; 16]; 3];
        for c in 0..3 {
            for i in 0..16 {
                half[c][i] = f32_to_half_int::<S>(rgb[c][i]) as f32;
            }
        }
        Texels::from_half_ints::<S>(half)
    }

    #[inline(always)]
    fn from_half_ints<const S: bool>(half: [Plane; 3]) -> Texels {
        let mut target = [[0f32; 16]; 3];
        let scale = if S { 32.0 / 31.0 } else { 64.0 / 31.0 };
        let limit = if S { 32767.0 } else { 65535.0 };
        for c in 0..3 {
            for i in 0..16 {
                let h = half[c][i];
                let a = if h < 0.0 { -h } else { h };
                let m = (a + 0.5) * scale;
                let m = if m < limit { m } else { limit };
                target[c][i] = if h == 0.0 {
                    0.0
                } else if h < 0.0 {
                    -m
                } else {
                    m
                };
            }
        }
        Texels { half, target }
    }
}

/// The sum of 16 values in a fixed tree order (vectorises, and is the same in every build).
#[inline(always)]
pub(super) fn sum16(x: &Plane) -> f32 {
    let mut s8 = [0f32; 8];
    for j in 0..8 {
        s8[j] = x[j] + x[j + 8];
    }
    let mut s4 = [0f32; 4];
    for j in 0..4 {
        s4[j] = s8[j] + s8[j + 4];
    }
    (s4[0] + s4[2]) + (s4[1] + s4[3])
}

/// `sum16` of the elementwise product.
#[inline(always)]
pub(super) fn dot16(a: &Plane, b: &Plane) -> f32 {
    let mut p = [0f32; 16];
    for i in 0..16 {
        p[i] = a[i] * b[i];
    }
    sum16(&p)
}

/// Minimum and maximum of 16 values (no NaNs).
#[inline(always)]
pub(super) fn min_max16(x: &Plane, y: &Plane) -> (f32, f32) {
    let mut lo = [0f32; 8];
    let mut hi = [0f32; 8];
    for j in 0..8 {
        lo[j] = if x[j] < x[j + 8] { x[j] } else { x[j + 8] };
        hi[j] = if y[j] > y[j + 8] { y[j] } else { y[j + 8] };
    }
    let (mut l, mut h) = (lo[0], hi[0]);
    for j in 1..8 {
        l = if lo[j] < l { lo[j] } else { l };
        h = if hi[j] > h { hi[j] } else { h };
    }
    (l, h)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Marsaglia's xorshift32: test data.
    pub(crate) fn xorshift32(mut state: u32) -> impl FnMut() -> u32 {
        move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        }
    }

    /// The branch-free conversion agrees with the `half` crate (IEEE round-to-nearest-even)
    /// plus the specification's clamping, on the boundaries of every half and on random bits.
    #[test]
    fn f32_to_half_int_matches_the_half_crate() {
        let reference = |v: f32, signed: bool| -> i32 {
            let h = if v.is_nan() { 0 } else { half::f16::from_f32(v.clamp(-65504.0, 65504.0)).to_bits() };
            half_to_int(sanitize_half(h, signed))
        };
        let mut values = vec![0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 65504.0, 65519.0, 65520.0, 1e30];
        // Every half, and the f32 values just around each midpoint between neighbouring halves.
        for h in 0..0x7C00u16 {
            let a = half::f16::from_bits(h).to_f32();
            let b = half::f16::from_bits(h + 1).to_f32();
            let mid = ((a as f64 + b as f64) / 2.0) as f32;
            for v in [a, mid, f32::from_bits(mid.to_bits() - 1), f32::from_bits(mid.to_bits() + 1)] {
                values.push(v);
                values.push(-v);
            }
        }
        let mut next = xorshift32(0x9E37_79B9);
        for _ in 0..1_000_000 {
            values.push(f32::from_bits(next()));
        }
        for &v in &values {
            assert_eq!(f32_to_half_int::<false>(v), reference(v, false), "{v:e} unsigned");
            assert_eq!(f32_to_half_int::<true>(v), reference(v, true), "{v:e} signed");
        }
    }
}
