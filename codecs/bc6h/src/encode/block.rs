//! Encoding one 4x4 block: endpoint fitting, quantisation, index selection and the mode and
//! partition search.
//!
//! Working spaces. A texel is first a half float ("half-int": its 16 bits read as a
//! sign-magnitude integer), and the error is the squared difference of half-ints. Half bits grow
//! with log2 of the value (1024 steps per octave), so this is the log-like metric that BC6H
//! encoders traditionally minimise. Fitting happens in the decoder's *interpolation domain*:
//! the decoder unquantises endpoints to 16-bit integers `c`, interpolates, and maps the result to
//! half bits with `c * 31 >> 6` (UF16) or `c * 31 >> 5` (SF16 magnitudes). That map is linear, so
//! least squares in the interpolation domain is least squares in half-int space.
// The decoder's endpoint unquantisation (Direct3D 11 specification, "Unquantization of Color
// Endpoints"): the encoder predicts exactly what the decoder will expand.
use crate::decode::unquantize_endpoint as unquantize;
use crate::modes::{
    pack_block, BlockFields, ModeInfo as Mode, ANCHORS as ANCHOR2, MODES, PARTITIONS, WEIGHTS3, WEIGHTS4,
};

/// A block ready for encoding.
pub(crate) struct Texels {
    signed: bool,
    /// The source half floats as sign-magnitude integers.
    half: [[i32; 3]; 16],
    /// The same values in the interpolation domain (the centre of the interval that decodes to
    /// each half).
    target: [[f32; 3]; 16],
}

/// Reads half bits as a sign-magnitude integer.
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

impl Texels {
    /// Prepares sanitised half texels (see [`sanitize_half`]).
    pub(crate) fn new(texels: &[[u16; 3]; 16], signed: bool) -> Texels {
        let mut half = [[0i32; 3]; 16];
        let mut target = [[0f32; 3]; 16];
        let scale = if signed { 32.0 / 31.0 } else { 64.0 / 31.0 };
        let limit = if signed { 32767.0 } else { 65535.0 };
        for i in 0..16 {
            for c in 0..3 {
                let h = half_to_int(sanitize_half(texels[i][c], signed));
                half[i][c] = h;
                target[i][c] = if h == 0 {
                    0.0
                } else {
                    let m = ((h.abs() as f32 + 0.5) * scale).min(limit);
                    if h < 0 {
                        -m
                    } else {
                        m
                    }
                };
            }
        }
        Texels { signed, half, target }
    }
}

/// The quantised endpoint whose unquantised value is nearest to `v` (interpolation domain).
fn quantize(v: f32, bits: u32, signed: bool) -> i32 {
    if !signed {
        let v = v.clamp(0.0, 65535.0);
        if bits >= 15 {
            // Non-negative: truncating v + 0.5 rounds, without a libm call on baseline x86-64.
            return (v + 0.5) as i32;
        }
        let max = (1i32 << bits) - 1;
        // floor(x) for x >= -0.5, by truncation of x + 1.
        let q = (((v * (1u32 << bits) as f32 / 65536.0 + 0.5) as i32) - 1).clamp(0, max);
        let q1 = (q + 1).min(max);
        if (unquantize(q1, bits, false) as f32 - v).abs() < (unquantize(q, bits, false) as f32 - v).abs() {
            q1
        } else {
            q
        }
    } else {
        let v = v.clamp(-32767.0, 32767.0);
        if bits >= 16 {
            return if v < 0.0 { -((0.5 - v) as i32) } else { (v + 0.5) as i32 };
        }
        let m = v.abs();
        let max = (1i32 << (bits - 1)) - 1;
        let q = (((m * (1u32 << (bits - 1)) as f32 / 32768.0 + 0.5) as i32) - 1).clamp(0, max);
        let q1 = (q + 1).min(max);
        let q = if (unquantize(q1, bits, true) as f32 - m).abs() < (unquantize(q, bits, true) as f32 - m).abs() {
            q1
        } else {
            q
        };
        if v < 0.0 {
            -q
        } else {
            q
        }
    }
}

/// Interpolates two unquantised endpoints and maps the result to half-int (the decoder's final
/// unquantisation).
#[inline(always)]
fn interpolate(a: i32, b: i32, w: i32, signed: bool) -> i32 {
    let c = (a * (64 - w) + b * w + 32) >> 6;
    if !signed {
        (c * 31) >> 6
    } else if c < 0 {
        -(((-c) * 31) >> 5)
    } else {
        (c * 31) >> 5
    }
}

/// Squared half-int distance of two colours.
#[inline(always)]
fn dist(a: &[i32; 3], b: &[i32; 3]) -> u64 {
    let d0 = (a[0] - b[0]) as i64;
    let d1 = (a[1] - b[1]) as i64;
    let d2 = (a[2] - b[2]) as i64;
    (d0 * d0 + d1 * d1 + d2 * d2) as u64
}

/// Continuous endpoints of up to two regions: `[region][end][channel]`.
type Ends = [[[f32; 3]; 2]; 2];

/// A fully specified block, with what it decodes to.
#[derive(Clone)]
pub(crate) struct Candidate {
    pub err: u64,
    pub mode: usize,
    pub partition: usize,
    /// Quantised endpoints (absolute values, not deltas): `[endpoint][channel]`.
    pub q: [[i32; 3]; 4],
    pub indices: [u8; 16],
}

impl Candidate {
    fn worst() -> Candidate {
        Candidate { err: u64::MAX, mode: 10, partition: 0, q: [[0; 3]; 4], indices: [0; 16] }
    }

    /// The 16 bytes of this block.
    pub(crate) fn pack(&self) -> [u8; 16] {
        let mode = &MODES[self.mode];
        let mut values = [0u32; 13];
        for e in 0..mode.regions as usize * 2 {
            for c in 0..3 {
                let stored = if mode.transformed && e > 0 { self.q[e][c] - self.q[0][c] } else { self.q[e][c] };
                // Two's complement; pack_block keeps the low bits of the stored width.
                values[e * 3 + c] = stored as u32;
            }
        }
        if mode.regions == 2 {
            values[12] = self.partition as u32;
        }
        pack_block(&BlockFields { mode: self.mode, values, indices: self.indices })
    }

    /// The decoded texels as half bits, recomputed from the endpoints and indices the way a
    /// decoder does (this keeps the sign of a negative value that rounds to zero: -0.0).
    pub(crate) fn decoded_halves(&self, signed: bool) -> [[u16; 3]; 16] {
        let mode = &MODES[self.mode];
        let bits = mode.endpoint_bits as u32;
        let weights: &[u8] = if mode.regions == 2 { &WEIGHTS3 } else { &WEIGHTS4 };
        let mask = if mode.regions == 2 { PARTITIONS[self.partition] } else { 0 };
        let mut out = [[0u16; 3]; 16];
        for (i, texel) in out.iter_mut().enumerate() {
            let r = ((mask >> i) & 1) as usize;
            let w = weights[self.indices[i] as usize] as i32;
            for (c, v) in texel.iter_mut().enumerate() {
                let a = unquantize(self.q[2 * r][c], bits, signed);
                let b = unquantize(self.q[2 * r + 1][c], bits, signed);
                let x = (a * (64 - w) + b * w + 32) >> 6;
                *v = if x < 0 { 0x8000 | (((-x) * 31) >> 5) as u16 } else { interpolate(x, x, 0, signed) as u16 };
            }
        }
        out
    }
}

/// How hard to search, derived from the effort level.
#[derive(Clone, Copy)]
pub(crate) struct Search {
    /// Try all four one-region modes (otherwise only the most precise one that fits).
    all_one_region: bool,
    /// Number of best-estimated partitions to encode with two-region modes (0 = none).
    partitions: usize,
    /// Try every two-region mode (otherwise mode 10 plus the most precise fitting one).
    all_two_region: bool,
    /// Least-squares refinement passes.
    iterations: u32,
    /// Test every palette entry for every texel (otherwise the projection and its neighbours).
    exhaustive_indices: bool,
}

impl Search {
    pub(crate) fn for_effort(effort: u8) -> Search {
        let (all1, partitions, all2, iterations, exhaustive) = match effort {
            0 => (false, 0, false, 0, false),
            1 => (false, 0, false, 1, false),
            2 => (false, 1, false, 1, false),
            3 => (false, 2, false, 2, false),
            4 => (true, 4, false, 2, false),
            5 => (true, 6, true, 2, false),
            6 => (true, 10, true, 3, false),
            7 => (true, 16, true, 4, false),
            8 => (true, 24, true, 6, true),
            _ => (true, 32, true, 8, true),
        };
        Search { all_one_region: all1, partitions, all_two_region: all2, iterations, exhaustive_indices: exhaustive }
    }
}

/// Principal-axis endpoints of the texels selected by `members` (a bit set): the mean, the
/// dominant eigenvector of the covariance (power iteration), and the extreme projections.
/// Also returns the squared distance of the texels from that line (the fit residual).
fn fit_line(target: &[[f32; 3]; 16], members: u16) -> ([[f32; 3]; 2], f32) {
    let mut n = 0f32;
    let mut mean = [0f32; 3];
    for (i, t) in target.iter().enumerate() {
        if members & (1 << i) != 0 {
            n += 1.0;
            for c in 0..3 {
                mean[c] += t[c];
            }
        }
    }
    if n == 0.0 {
        return ([[0.0; 3]; 2], 0.0);
    }
    for m in &mut mean {
        *m /= n;
    }
    // Covariance (upper triangle): xx, xy, xz, yy, yz, zz.
    let mut cov = [0f32; 6];
    for (i, t) in target.iter().enumerate() {
        if members & (1 << i) != 0 {
            let d = [t[0] - mean[0], t[1] - mean[1], t[2] - mean[2]];
            cov[0] += d[0] * d[0];
            cov[1] += d[0] * d[1];
            cov[2] += d[0] * d[2];
            cov[3] += d[1] * d[1];
            cov[4] += d[1] * d[2];
            cov[5] += d[2] * d[2];
        }
    }
    let (axis, lambda) = principal_axis(&cov);
    let trace = cov[0] + cov[3] + cov[5];
    let residual = (trace - lambda).max(0.0);
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for (i, t) in target.iter().enumerate() {
        if members & (1 << i) != 0 {
            let p = (t[0] - mean[0]) * axis[0] + (t[1] - mean[1]) * axis[1] + (t[2] - mean[2]) * axis[2];
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let mut ends = [[0f32; 3]; 2];
    for c in 0..3 {
        ends[0][c] = mean[c] + lo * axis[c];
        ends[1][c] = mean[c] + hi * axis[c];
    }
    (ends, residual)
}

/// Unit dominant eigenvector of a symmetric 3x3 matrix (upper triangle) and its eigenvalue.
fn principal_axis(cov: &[f32; 6]) -> ([f32; 3], f32) {
    // Start from the column with the largest diagonal entry: never orthogonal to the answer
    // unless the matrix is degenerate.
    let cols = [[cov[0], cov[1], cov[2]], [cov[1], cov[3], cov[4]], [cov[2], cov[4], cov[5]]];
    let k = if cov[0] >= cov[3] && cov[0] >= cov[5] {
        0
    } else if cov[3] >= cov[5] {
        1
    } else {
        2
    };
    let mut v = cols[k];
    let mut norm = 0.0;
    for _ in 0..4 {
        let w = [
            cov[0] * v[0] + cov[1] * v[1] + cov[2] * v[2],
            cov[1] * v[0] + cov[3] * v[1] + cov[4] * v[2],
            cov[2] * v[0] + cov[4] * v[1] + cov[5] * v[2],
        ];
        norm = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        if norm <= f32::MIN_POSITIVE {
            return ([0.577_350_3; 3], 0.0);
        }
        v = [w[0] / norm, w[1] / norm, w[2] / norm];
    }
    // After normalisation, |C v| approximates the eigenvalue.
    (v, norm)
}

/// The encoder for one block at one search setting.
pub(crate) struct BlockEncoder<'a> {
    tex: &'a Texels,
    search: Search,
}

impl<'a> BlockEncoder<'a> {
    pub(crate) fn new(tex: &'a Texels, search: Search) -> Self {
        BlockEncoder { tex, search }
    }

    /// Quantises continuous endpoints for `mode`, orienting each region so that its anchor texel
    /// sits nearer the first endpoint and clamping deltas into the mode's range.
    fn quantize_ends(&self, mode: &Mode, partition: usize, ends: &Ends) -> [[i32; 3]; 4] {
        let signed = self.tex.signed;
        let bits = mode.endpoint_bits as u32;
        let mut q = [[0i32; 3]; 4];
        for r in 0..mode.regions as usize {
            let anchor = if r == 0 { 0 } else { ANCHOR2[partition] as usize };
            let (a, b) = (ends[r][0], ends[r][1]);
            let x = self.tex.target[anchor];
            let mut along = 0.0;
            let mut len2 = 0.0;
            for c in 0..3 {
                along += (x[c] - a[c]) * (b[c] - a[c]);
                len2 += (b[c] - a[c]) * (b[c] - a[c]);
            }
            let (a, b) = if along > 0.5 * len2 { (b, a) } else { (a, b) };
            for c in 0..3 {
                q[2 * r][c] = quantize(a[c], bits, signed);
                q[2 * r + 1][c] = quantize(b[c], bits, signed);
            }
        }
        if mode.transformed {
            let base = q[0];
            for end in q.iter_mut().take(mode.regions as usize * 2).skip(1) {
                for c in 0..3 {
                    let half_range = 1i32 << (mode.delta_bits[c] - 1);
                    end[c] = base[c] + (end[c] - base[c]).clamp(-half_range, half_range - 1);
                }
            }
        }
        q
    }

    /// Whether the endpoints fit the mode's deltas without clamping.
    fn fits(&self, mode: &Mode, partition: usize, ends: &Ends) -> bool {
        if !mode.transformed {
            return true;
        }
        let signed = self.tex.signed;
        let bits = mode.endpoint_bits as u32;
        let base: [i32; 3] = std::array::from_fn(|c| quantize(ends[0][0][c], bits, signed));
        let _ = partition;
        for (r, region) in ends.iter().enumerate().take(mode.regions as usize) {
            for (k, end) in region.iter().enumerate() {
                if r == 0 && k == 0 {
                    continue;
                }
                for c in 0..3 {
                    let half_range = 1i32 << (mode.delta_bits[c] - 1);
                    let d = quantize(end[c], bits, signed) - base[c];
                    // Either end may become the base after orientation: require the
                    // range to fit from both sides.
                    if d < -half_range + 1 || d > half_range - 2 {
                        return false;
                    }
                }
            }
        }
        true
    }

    /// Chooses indices for quantised endpoints and computes the error.
    fn evaluate(&self, m: usize, partition: usize, q: [[i32; 3]; 4]) -> Candidate {
        let mode = &MODES[m];
        let signed = self.tex.signed;
        let bits = mode.endpoint_bits as u32;
        let weights: &[u8] = if mode.regions == 2 { &WEIGHTS3 } else { &WEIGHTS4 };
        let n = weights.len();
        let mask = if mode.regions == 2 { PARTITIONS[partition] } else { 0 };
        let mut palettes = [[[0i32; 3]; 16]; 2];
        for r in 0..mode.regions as usize {
            let a: [i32; 3] = std::array::from_fn(|c| unquantize(q[2 * r][c], bits, signed));
            let b: [i32; 3] = std::array::from_fn(|c| unquantize(q[2 * r + 1][c], bits, signed));
            for (k, &w) in weights.iter().enumerate() {
                for c in 0..3 {
                    palettes[r][k][c] = interpolate(a[c], b[c], w as i32, signed);
                }
            }
        }
        let anchor2 = ANCHOR2[partition] as usize;
        let mut cand = Candidate { err: 0, mode: m, partition, q, indices: [0; 16] };
        // Projection set-up per region: direction and squared length in half-int space.
        let mut dir = [[0f32; 3]; 2];
        let mut inv_len2 = [0f32; 2];
        for r in 0..mode.regions as usize {
            let p = &palettes[r];
            let mut l2 = 0.0;
            for c in 0..3 {
                dir[r][c] = (p[n - 1][c] - p[0][c]) as f32;
                l2 += dir[r][c] * dir[r][c];
            }
            inv_len2[r] = if l2 > 0.0 { (n - 1) as f32 / l2 } else { 0.0 };
        }
        for i in 0..16 {
            let r = ((mask >> i) & 1) as usize;
            let limit = if i == 0 || (mode.regions == 2 && i == anchor2) { n / 2 } else { n };
            let h = &self.tex.half[i];
            let p = &palettes[r];
            let (lo, hi) = if self.search.exhaustive_indices {
                (0, limit)
            } else {
                // Project onto the palette line; the weights are nearly uniform, so the nearest
                // uniform step and its neighbours contain the best entry.
                let t = ((h[0] - p[0][0]) as f32 * dir[r][0]
                    + (h[1] - p[0][1]) as f32 * dir[r][1]
                    + (h[2] - p[0][2]) as f32 * dir[r][2])
                    * inv_len2[r];
                let k = ((t.max(0.0) + 0.5) as usize).min(limit - 1);
                (k.saturating_sub(1), (k + 2).min(limit))
            };
            let mut best = (u64::MAX, 0usize);
            for (k, entry) in p.iter().enumerate().take(hi).skip(lo) {
                let d = dist(entry, h);
                if d < best.0 {
                    best = (d, k);
                }
            }
            cand.err += best.0;
            cand.indices[i] = best.1 as u8;
        }
        cand
    }

    /// Least-squares endpoints for fixed indices, per region and channel.
    fn least_squares(&self, cand: &Candidate, previous: &Ends) -> Ends {
        let mode = &MODES[cand.mode];
        let weights: &[u8] = if mode.regions == 2 { &WEIGHTS3 } else { &WEIGHTS4 };
        let mask = if mode.regions == 2 { PARTITIONS[cand.partition] } else { 0 };
        let mut ends = *previous;
        for (r, region_ends) in ends.iter_mut().enumerate().take(mode.regions as usize) {
            let (mut aa, mut ab, mut bb) = (0f32, 0f32, 0f32);
            let mut ax = [0f32; 3];
            let mut bx = [0f32; 3];
            for i in 0..16 {
                if ((mask >> i) & 1) as usize != r {
                    continue;
                }
                let w = weights[cand.indices[i] as usize] as f32 / 64.0;
                let v = 1.0 - w;
                aa += v * v;
                ab += v * w;
                bb += w * w;
                for c in 0..3 {
                    ax[c] += v * self.tex.target[i][c];
                    bx[c] += w * self.tex.target[i][c];
                }
            }
            let det = aa * bb - ab * ab;
            if det.abs() < 1e-6 {
                continue;
            }
            for c in 0..3 {
                region_ends[0][c] = (ax[c] * bb - bx[c] * ab) / det;
                region_ends[1][c] = (bx[c] * aa - ax[c] * ab) / det;
            }
        }
        ends
    }

    /// Encodes with one mode and partition from starting endpoints, refining by least squares.
    fn encode_mode(&self, m: usize, partition: usize, start: &Ends) -> Candidate {
        let mode = &MODES[m];
        let mut best = self.evaluate(m, partition, self.quantize_ends(mode, partition, start));
        let mut ends = *start;
        for _ in 0..self.search.iterations {
            if best.err == 0 {
                break;
            }
            ends = self.least_squares(&best, &ends);
            let cand = self.evaluate(m, partition, self.quantize_ends(mode, partition, &ends));
            if cand.err < best.err {
                best = cand;
            } else {
                break;
            }
        }
        best
    }

    /// Searches modes (all of them, or only `only_mode`) and returns the best candidate.
    pub(crate) fn encode(&self, only_mode: Option<usize>) -> Candidate {
        let mut best = Candidate::worst();
        // Candidate modes as bit sets over MODES indices.
        let allowed: u16 = only_mode.map_or(0x3FFF, |m| 1 << m);
        let try_modes = |modes: u16, partition: usize, ends: &Ends, best: &mut Candidate| {
            for m in 0..14 {
                if modes & allowed & (1 << m) != 0 {
                    let cand = self.encode_mode(m, partition, ends);
                    if cand.err < best.err {
                        *best = cand;
                    }
                }
            }
        };
        // One region.
        if allowed & 0x3C00 != 0 {
            let (ends1, _) = fit_line(&self.tex.target, 0xFFFF);
            let start1: Ends = [ends1, [[0.0; 3]; 2]];
            let modes = if self.search.all_one_region || only_mode.is_some() {
                0x3C00
            } else {
                // The most precise mode whose deltas hold the block's range.
                let m = [13, 12, 11].into_iter().find(|&m| self.fits(&MODES[m], 0, &start1)).unwrap_or(10);
                1 << m
            };
            try_modes(modes, 0, &start1, &mut best);
        }
        if best.err == 0 {
            return best;
        }
        // Two regions: rank the partitions by how well two lines fit them.
        let partitions = match only_mode {
            Some(m) if MODES[m].regions == 2 => self.search.partitions.max(1),
            Some(_) => 0,
            None => self.search.partitions,
        };
        if partitions == 0 {
            return best;
        }
        let mut ranked = partition_residuals(&self.tex.target);
        ranked.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for &(_, p) in ranked.iter().take(partitions) {
            let mask = PARTITIONS[p];
            let ends: Ends = [fit_line(&self.tex.target, !mask).0, fit_line(&self.tex.target, mask).0];
            let modes = if self.search.all_two_region || only_mode.is_some() {
                0x03FF
            } else {
                // Untransformed mode 10 always fits; add the most precise transformed mode
                // whose deltas hold this partition's endpoints.
                let fitting = [2, 3, 4, 0, 5, 6, 7, 8, 1].into_iter().find(|&m| self.fits(&MODES[m], p, &ends));
                (1 << 9) | fitting.map_or(0, |m| 1 << m)
            };
            try_modes(modes, p, &ends, &mut best);
        }
        best
    }
}

/// For each of the 32 partitions, the sum over both regions of the texels' squared distance
/// from their region's principal line (from summed moments, without fitting endpoints).
fn partition_residuals(target: &[[f32; 3]; 16]) -> [(f32, usize); 32] {
    // Per-texel moments about the block mean (which keeps f32 cancellation small): x, y, z,
    // xx, xy, xz, yy, yz, zz.
    let mut mean = [0f32; 3];
    for t in target {
        for c in 0..3 {
            mean[c] += t[c] / 16.0;
        }
    }
    let mut moments = [[0f32; 9]; 16];
    let mut total = [0f32; 9];
    for (m, t) in moments.iter_mut().zip(target) {
        let t = [t[0] - mean[0], t[1] - mean[1], t[2] - mean[2]];
        *m = [t[0], t[1], t[2], t[0] * t[0], t[0] * t[1], t[0] * t[2], t[1] * t[1], t[1] * t[2], t[2] * t[2]];
        for k in 0..9 {
            total[k] += m[k];
        }
    }
    let residual = |s: &[f32; 9], n: f32| -> f32 {
        if n < 2.0 {
            return 0.0;
        }
        let mu = [s[0] / n, s[1] / n, s[2] / n];
        let cov = [
            s[3] - n * mu[0] * mu[0],
            s[4] - n * mu[0] * mu[1],
            s[5] - n * mu[0] * mu[2],
            s[6] - n * mu[1] * mu[1],
            s[7] - n * mu[1] * mu[2],
            s[8] - n * mu[2] * mu[2],
        ];
        let (_, lambda) = principal_axis(&cov);
        (cov[0] + cov[3] + cov[5] - lambda).max(0.0)
    };
    std::array::from_fn(|p| {
        let mask = PARTITIONS[p];
        let mut s1 = [0f32; 9];
        for (i, m) in moments.iter().enumerate() {
            if mask & (1 << i) != 0 {
                for k in 0..9 {
                    s1[k] += m[k];
                }
            }
        }
        let s0: [f32; 9] = std::array::from_fn(|k| total[k] - s1[k]);
        let n1 = mask.count_ones() as f32;
        (residual(&s0, 16.0 - n1) + residual(&s1, n1), p)
    })
}
