//! RGB↔XYZ matrices computed from chromaticities (the standard derivation: the primaries'
//! XYZ columns scaled so that RGB (1, 1, 1) maps to the white point with Y = 1).
//!
//! Kept local until `hdrcodec_core::color` offers the same; CIE XYZ "primaries" are the
//! identity (their xy cannot go through the derivation: y = 0 for two of them).

use hdrcodec_core::{Chromaticities, ColorPrimaries};

/// A 3×3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

fn det(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// The inverse, or `None` for a (nearly) singular matrix.
pub fn invert(m: &Mat3) -> Option<Mat3> {
    let d = det(m);
    if !d.is_finite() || d.abs() < 1e-12 {
        return None;
    }
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            // Cofactor of (j, i): the adjugate is the transposed cofactor matrix.
            let (a0, a1) = ([1, 0, 0][j], [2, 2, 1][j]);
            let (b0, b1) = ([1, 0, 0][i], [2, 2, 1][i]);
            let minor = m[a0][b0] * m[a1][b1] - m[a0][b1] * m[a1][b0];
            *v = if (i + j) % 2 == 0 { minor } else { -minor } / d;
        }
    }
    Some(r)
}

fn xyz_of(xy: [f64; 2]) -> Option<[f64; 3]> {
    let [x, y] = xy;
    (y > 0.0 && x.is_finite() && y.is_finite()).then(|| [x / y, 1.0, (1.0 - x - y) / y])
}

/// RGB → XYZ for these chromaticities, or `None` if they cannot define an RGB space.
pub fn rgb_to_xyz(ch: &Chromaticities) -> Option<Mat3> {
    let (r, g, b, w) = (xyz_of(ch.red)?, xyz_of(ch.green)?, xyz_of(ch.blue)?, xyz_of(ch.white)?);
    let p = [[r[0], g[0], b[0]], [r[1], g[1], b[1]], [r[2], g[2], b[2]]];
    let inv = invert(&p)?;
    let s: Vec<f64> = inv.iter().map(|row| row[0] * w[0] + row[1] * w[1] + row[2] * w[2]).collect();
    Some([
        [p[0][0] * s[0], p[0][1] * s[1], p[0][2] * s[2]],
        [p[1][0] * s[0], p[1][1] * s[1], p[1][2] * s[2]],
        [p[2][0] * s[0], p[2][1] * s[1], p[2][2] * s[2]],
    ])
}

/// RGB → XYZ for a named or custom space (identity for [`ColorPrimaries::Xyz`]).
pub fn primaries_to_xyz(p: &ColorPrimaries) -> Option<Mat3> {
    match p {
        ColorPrimaries::Xyz => Some(IDENTITY),
        p => rgb_to_xyz(&p.chromaticities()),
    }
}

/// Applies `m` to every RGB triple of interleaved samples with `stride` samples per pixel.
pub fn apply(m: &Mat3, samples: &mut [f32], stride: usize) {
    let m: [[f32; 3]; 3] = m.map(|row| row.map(|v| v as f32));
    for px in samples.chunks_exact_mut(stride) {
        let (a, b, c) = (px[0], px[1], px[2]);
        for (o, row) in px.iter_mut().zip(&m) {
            *o = row[0] * a + row[1] * b + row[2] * c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bt709_matrix_matches_the_srgb_standard() {
        // IEC 61966-2-1 (sRGB), equation 5.8 / its inverse: the Y row 0.2126 0.7152 0.0722 and
        // X row 0.4124 0.3576 0.1805 (four decimals, as printed in the standard).
        let m = primaries_to_xyz(&ColorPrimaries::Bt709).unwrap();
        let want = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
        for (r, w) in m.iter().zip(want) {
            for (a, b) in r.iter().zip(w) {
                assert!((a - b).abs() < 1.5e-4, "{m:?}");
            }
        }
        let inv = invert(&m).unwrap();
        // sRGB's XYZ→RGB first row: 3.2406 -1.5372 -0.4986.
        assert!((inv[0][0] - 3.2406).abs() < 1e-3 && (inv[0][1] + 1.5372).abs() < 1e-3, "{inv:?}");
    }

    #[test]
    fn degenerate_primaries_are_refused() {
        let ch = Chromaticities { red: [0.3, 0.3], green: [0.3, 0.3], blue: [0.3, 0.3], white: [0.3, 0.3] };
        assert!(rgb_to_xyz(&ch).is_none());
    }
}
