//! Partition ranking: how well two lines fit the two regions of each of the 32 partitions,
//! estimated for all of them at once from moment sums, and the region membership tables.
// Fixed-size index loops over texel lanes are the vectorisable form used throughout.
#![allow(clippy::needless_range_loop)]
use super::fit::dominant_direction;
use super::texels::{sum16, Plane};
use crate::modes::PARTITIONS;

/// Region membership per partition and texel: 1.0 where the texel is in region 1.
pub(super) static REGION1: [Plane; 32] = region1_table();

/// The same table transposed: per texel, 1.0 in the lanes of the partitions that put it in
/// region 1 (the partition ranking works on 32 partitions at once).
static REGION1_BY_TEXEL: [[f32; 32]; 16] = {
    let by_partition = region1_table();
    let mut t = [[0f32; 32]; 16];
    let mut k = 0;
    while k < 32 * 16 {
        t[k % 16][k / 16] = by_partition[k / 16][k % 16];
        k += 1;
    }
    t
};

/// Per region (0, 1) and partition: the number of texels in the region.
static REGION_COUNTS: [[f32; 32]; 2] = {
    let mut t = [[0f32; 32]; 2];
    let mut p = 0;
    while p < 32 {
        let ones = PARTITIONS[p].count_ones() as f32;
        t[0][p] = 16.0 - ones;
        t[1][p] = ones;
        p += 1;
    }
    t
};

const fn region1_table() -> [Plane; 32] {
    let mut t = [[0f32; 16]; 32];
    let mut k = 0;
    while k < 32 * 16 {
        t[k / 16][k % 16] = ((PARTITIONS[k / 16] >> (k % 16)) & 1) as f32;
        k += 1;
    }
    t
}

/// For each of the 32 partitions, the sum over both regions of the texels' squared distance
/// from their region's principal line (from summed moments, without fitting endpoints). The
/// 32 partitions are the SIMD lanes.
#[inline(always)]
pub(super) fn partition_residuals(target: &[Plane; 3]) -> ([f32; 32], PartitionMoments) {
    // Per-texel moments about the block mean (which keeps f32 cancellation small): x, y, z,
    // xx, xy, xz, yy, yz, zz.
    let mut d = [[0f32; 16]; 3];
    let mut block_mean = [0f32; 3];
    for c in 0..3 {
        block_mean[c] = sum16(&target[c]) / 16.0;
        for i in 0..16 {
            d[c][i] = target[c][i] - block_mean[c];
        }
    }
    let mut moments = [[0f32; 16]; 9];
    for i in 0..16 {
        let t = [d[0][i], d[1][i], d[2][i]];
        let m = [t[0], t[1], t[2], t[0] * t[0], t[0] * t[1], t[0] * t[2], t[1] * t[1], t[1] * t[2], t[2] * t[2]];
        for k in 0..9 {
            moments[k][i] = m[k];
        }
    }
    let mut total = [0f32; 9];
    for k in 0..9 {
        total[k] = sum16(&moments[k]);
    }
    // Region-1 sums for every partition, one moment at a time (the 32 accumulators stay in
    // registers).
    let mut s1 = [[0f32; 32]; 9];
    for k in 0..9 {
        let mut acc = [0f32; 32];
        for i in 0..16 {
            let v = moments[k][i];
            let lanes = &REGION1_BY_TEXEL[i];
            for p in 0..32 {
                acc[p] += lanes[p] * v;
            }
        }
        s1[k] = acc;
    }
    let mut out = [0f32; 32];
    for region in 0..2 {
        let mut s = [[0f32; 32]; 9];
        let n = &REGION_COUNTS[region];
        for k in 0..9 {
            for p in 0..32 {
                s[k][p] = if region == 1 { s1[k][p] } else { total[k] - s1[k][p] };
            }
        }
        let residual = region_residuals(&s, n);
        for p in 0..32 {
            out[p] += residual[p];
        }
    }
    (out, PartitionMoments { block_mean, total, s1 })
}

/// The moment sums behind [`partition_residuals`], kept to fit the chosen partitions' lines
/// without summing again.
pub(super) struct PartitionMoments {
    block_mean: [f32; 3],
    /// Sums over the block (x, y, z, xx, xy, xz, yy, yz, zz about the block mean).
    total: [f32; 9],
    /// The same over region 1, per partition.
    s1: [[f32; 32]; 9],
}

impl PartitionMoments {
    /// Mean and covariance (upper triangle) of region `r` of partition `p`.
    #[inline(always)]
    pub(super) fn region(&self, p: usize, r: usize) -> ([f32; 3], [f32; 6]) {
        let n = REGION_COUNTS[r][p];
        let mut s = [0f32; 9];
        for k in 0..9 {
            s[k] = if r == 1 { self.s1[k][p] } else { self.total[k] - self.s1[k][p] };
        }
        let mu = [s[0] / n, s[1] / n, s[2] / n];
        let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let mut cov = [0f32; 6];
        for (k, &(x, y)) in pairs.iter().enumerate() {
            cov[k] = s[3 + k] - n * mu[x] * mu[y];
        }
        let mean = [self.block_mean[0] + mu[0], self.block_mean[1] + mu[1], self.block_mean[2] + mu[2]];
        (mean, cov)
    }
}

/// Per lane: the squared distance of `n` points with moment sums `s` (x, y, z, xx, xy, xz, yy,
/// yz, zz) from their principal line, i.e. the covariance trace minus its largest eigenvalue.
#[inline(always)]
fn region_residuals(s: &[[f32; 32]; 9], n: &[f32; 32]) -> [f32; 32] {
    let mut out = [0f32; 32];
    for p in 0..32 {
        let np = n[p];
        let inv_n = if np > 0.0 { 1.0 / np } else { 0.0 };
        let mu = [s[0][p] * inv_n, s[1][p] * inv_n, s[2][p] * inv_n];
        let cov = [
            s[3][p] - np * mu[0] * mu[0],
            s[4][p] - np * mu[0] * mu[1],
            s[5][p] - np * mu[0] * mu[2],
            s[6][p] - np * mu[1] * mu[1],
            s[7][p] - np * mu[1] * mu[2],
            s[8][p] - np * mu[2] * mu[2],
        ];
        // The variance along the dominant direction (Rayleigh quotient): no square roots.
        let v = dominant_direction(&cov);
        let cv = [
            cov[0] * v[0] + cov[1] * v[1] + cov[2] * v[2],
            cov[1] * v[0] + cov[3] * v[1] + cov[4] * v[2],
            cov[2] * v[0] + cov[4] * v[1] + cov[5] * v[2],
        ];
        let vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        let lambda = if vv > f32::MIN_POSITIVE { (v[0] * cv[0] + v[1] * cv[1] + v[2] * cv[2]) / vv } else { 0.0 };
        let r = cov[0] + cov[3] + cov[5] - lambda;
        out[p] = if n[p] < 2.0 || r < 0.0 { 0.0 } else { r };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::texels::{tests::xorshift32, Texels};

    /// The vectorised partition ranking matches a direct computation in f64: for each
    /// partition and region, the explicit covariance of the member texels, its trace minus its
    /// largest eigenvalue (power iteration run to convergence). The ranking's estimate (the
    /// variance along the direction of 8 power iterations) is never below the exact value and
    /// close to it; a wrong lane or region would be far off.
    #[test]
    fn partition_residuals_match_explicit_covariances() {
        let mut next = xorshift32(12345);
        for n in 0..200 {
            // Odd rounds: each region of a partition on its own line (random base and direction),
            // so that partition must rank first. Even rounds: noise over a wide range.
            let split = (next() % 32) as usize;
            let lines: [[[f32; 3]; 2]; 2] =
                std::array::from_fn(|_| std::array::from_fn(|_| std::array::from_fn(|_| (next() % 400) as f32 / 20.0)));
            let mut rgb = [[0f32; 16]; 3];
            for plane in rgb.iter_mut() {
                for v in plane.iter_mut() {
                    *v = (next() % 4000) as f32 / 100.0;
                }
            }
            let mut tex = Texels::from_f32::<false>(&rgb);
            if n % 2 == 1 {
                // Straight lines in the fitting domain itself.
                for i in 0..16 {
                    let line = &lines[((PARTITIONS[split] >> i) & 1) as usize];
                    let t = (next() % 1000) as f32;
                    for c in 0..3 {
                        tex.target[c][i] = line[0][c] * 1000.0 + line[1][c] * t;
                    }
                }
            }
            let fast = partition_residuals(&tex.target).0;
            // f32 sums cancel: allow an error relative to the block's whole spread.
            let spread: f64 = (0..3)
                .map(|c| {
                    let mean = tex.target[c].iter().map(|&v| v as f64).sum::<f64>() / 16.0;
                    tex.target[c].iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>()
                })
                .sum();
            let slack = 1e-5 * spread;
            if n % 2 == 1 {
                let best = (0..32).min_by(|&a, &b| fast[a].total_cmp(&fast[b])).unwrap();
                assert_eq!(best, split, "round {n}");
            }
            for p in 0..32 {
                let mut expect = 0f64;
                for r in 0..2 {
                    let members: Vec<[f64; 3]> = (0..16)
                        .filter(|&i| (PARTITIONS[p] >> i) & 1 == r)
                        .map(|i| std::array::from_fn(|c| tex.target[c][i] as f64))
                        .collect();
                    let n = members.len() as f64;
                    let mean: [f64; 3] = std::array::from_fn(|c| members.iter().map(|x| x[c]).sum::<f64>() / n);
                    let cov: [[f64; 3]; 3] = std::array::from_fn(|a| {
                        std::array::from_fn(|b| members.iter().map(|x| (x[a] - mean[a]) * (x[b] - mean[b])).sum())
                    });
                    let mut v = [1.0, 0.6, 0.3];
                    let mut lambda = 0.0;
                    for _ in 0..500 {
                        let w: [f64; 3] = std::array::from_fn(|a| (0..3).map(|b| cov[a][b] * v[b]).sum());
                        lambda = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
                        if lambda == 0.0 {
                            break;
                        }
                        v = w.map(|x| x / lambda);
                    }
                    expect += cov[0][0] + cov[1][1] + cov[2][2] - lambda;
                }
                let got = fast[p] as f64;
                assert!(got >= expect - slack && got <= expect * 1.05 + slack, "partition {p}: {got} vs {expect}");
            }
        }
    }
}
