//! Line fitting: the principal axis of a set of texels (the dominant eigenvector of their
//! covariance) and the endpoints of their extent along it, the starting endpoints of every mode.
// Fixed-size index loops over texel lanes are the vectorisable form used throughout.
#![allow(clippy::needless_range_loop)]
use super::texels::{dot16, min_max16, sum16, Plane};

/// Principal-axis endpoints of the texels weighted by `member` (1.0 in, 0.0 out): the mean,
/// the dominant eigenvector of the covariance, and the extreme projections. `reference` is a
/// member texel.
#[inline(always)]
pub(super) fn fit_line(target: &[Plane; 3], member: &Plane, reference: usize) -> [[f32; 3]; 2] {
    let n = sum16(member);
    if n == 0.0 {
        return [[0.0; 3]; 2];
    }
    // Moments of the offsets from a member texel (small numbers, so the one-pass covariance
    // does not cancel), all nine reduced independently.
    let mut d = [[0f32; 16]; 3];
    for c in 0..3 {
        let origin = target[c][reference];
        for i in 0..16 {
            d[c][i] = (target[c][i] - origin) * member[i];
        }
    }
    let mut offset = [0f32; 3];
    for c in 0..3 {
        offset[c] = sum16(&d[c]) / n;
    }
    let products = [
        dot16(&d[0], &d[0]),
        dot16(&d[0], &d[1]),
        dot16(&d[0], &d[2]),
        dot16(&d[1], &d[1]),
        dot16(&d[1], &d[2]),
        dot16(&d[2], &d[2]),
    ];
    // Covariance (upper triangle): xx, xy, xz, yy, yz, zz.
    let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
    let mut cov = [0f32; 6];
    for (k, &(x, y)) in pairs.iter().enumerate() {
        cov[k] = products[k] - n * offset[x] * offset[y];
    }
    let mut mean = [0f32; 3];
    for c in 0..3 {
        mean[c] = target[c][reference] + offset[c];
    }
    line_through(target, member, &mean, &cov)
}

/// The endpoints of the member texels' extent along the principal axis of `cov` through `mean`.
#[inline(always)]
pub(super) fn line_through(target: &[Plane; 3], member: &Plane, mean: &[f32; 3], cov: &[f32; 6]) -> [[f32; 3]; 2] {
    let axis = principal_axis(cov);
    let mut lo = [0f32; 16];
    let mut hi = [0f32; 16];
    for i in 0..16 {
        let p = (target[0][i] - mean[0]) * axis[0]
            + (target[1][i] - mean[1]) * axis[1]
            + (target[2][i] - mean[2]) * axis[2];
        lo[i] = if member[i] != 0.0 { p } else { f32::INFINITY };
        hi[i] = if member[i] != 0.0 { p } else { f32::NEG_INFINITY };
    }
    let (lo, hi) = min_max16(&lo, &hi);
    let mut ends = [[0f32; 3]; 2];
    for c in 0..3 {
        ends[0][c] = mean[c] + lo * axis[c];
        ends[1][c] = mean[c] + hi * axis[c];
    }
    ends
}

/// An unnormalised dominant eigenvector of a symmetric 3x3 matrix (upper triangle xx, xy, xz,
/// yy, yz, zz): eight power iterations as three squarings of the matrix (short dependency
/// chains, no division), scaled by about 1 / trace first so that C^8 stays in range (every
/// entry of the scaled matrix is at most 2 and its largest eigenvalue at least 1/3). C^8 applied to the unit
/// vector of its largest diagonal entry (never orthogonal to the answer unless the matrix is
/// degenerate) is that column. Zero for a zero matrix. Branch-free, so it vectorises over lanes.
#[inline(always)]
pub(super) fn dominant_direction(cov: &[f32; 6]) -> [f32; 3] {
    let trace = cov[0] + cov[3] + cov[5];
    // A power of two within a factor 2 of 1 / trace, from the exponent bits (no division).
    let inv =
        if trace > f32::MIN_POSITIVE { f32::from_bits(0x7F00_0000 - (trace.to_bits() & 0x7F80_0000)) } else { 0.0 };
    let mut m = [cov[0] * inv, cov[1] * inv, cov[2] * inv, cov[3] * inv, cov[4] * inv, cov[5] * inv];
    for _ in 0..3 {
        m = [
            m[0] * m[0] + m[1] * m[1] + m[2] * m[2],
            m[0] * m[1] + m[1] * m[3] + m[2] * m[4],
            m[0] * m[2] + m[1] * m[4] + m[2] * m[5],
            m[1] * m[1] + m[3] * m[3] + m[4] * m[4],
            m[1] * m[2] + m[3] * m[4] + m[4] * m[5],
            m[2] * m[2] + m[4] * m[4] + m[5] * m[5],
        ];
    }
    let first_xx = m[0] >= m[3] && m[0] >= m[5];
    let first_yy = m[3] >= m[5];
    [
        if first_xx {
            m[0]
        } else if first_yy {
            m[1]
        } else {
            m[2]
        },
        if first_xx {
            m[1]
        } else if first_yy {
            m[3]
        } else {
            m[4]
        },
        if first_xx {
            m[2]
        } else if first_yy {
            m[4]
        } else {
            m[5]
        },
    ]
}

/// Unit dominant eigenvector of a symmetric 3x3 matrix (upper triangle).
#[inline(always)]
fn principal_axis(cov: &[f32; 6]) -> [f32; 3] {
    let v = dominant_direction(cov);
    let norm2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if norm2 <= f32::MIN_POSITIVE {
        return [0.577_350_3; 3];
    }
    let inv = 1.0 / norm2.sqrt();
    [v[0] * inv, v[1] * inv, v[2] * inv]
}
