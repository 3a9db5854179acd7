//! Encoding one 4x4 block: quantisation, index selection, packing and the mode and partition
//! search, on the texels of `texels.rs`, the lines of `fit.rs` and the partition ranking of
//! `partition.rs`.
//!
//! Working spaces. A texel is first a half float ("half-int": its 16 bits read as a
//! sign-magnitude integer), and the error is the squared difference of half-ints. Half bits grow
//! with log2 of the value (1024 steps per octave), so this is the log-like metric that BC6H
//! encoders traditionally minimise. Fitting happens in the decoder's *interpolation domain*:
//! the decoder unquantises endpoints to 16-bit integers `c`, interpolates, and maps the result to
//! half bits with `c * 31 >> 6` (UF16) or `c * 31 >> 5` (SF16 magnitudes). That map is linear, so
//! least squares in the interpolation domain is least squares in half-int space.
//!
//! Layout. The 16 texels are kept as channel planes of `f32` (`[[f32; 16]; 3]`), and every
//! per-texel step (moments, projections, the palette search, the partition ranking across 32
//! partitions) is a loop over plain arrays that the compiler turns into SIMD; `encode.rs`
//! compiles the same code a second time for AVX2 and picks the build at run time. Half-ints
//! (below 2^16 in magnitude) and palette entries are exact in `f32`; sums are reduced in a fixed
//! tree order so that both builds give the same bits. Every function here and in those
//! modules is `#[inline(always)]` so that the whole block encoder is compiled inside each build.
// Fixed-size index loops over texel lanes are the vectorisable form used throughout.
#![allow(clippy::needless_range_loop)]
// The decoder's endpoint unquantisation (Direct3D 11 specification, "Unquantization of Color
// Endpoints"): the encoder predicts exactly what the decoder will expand.
use crate::decode::{unquantize, unquantize_endpoint};
use crate::modes::{ModeInfo as Mode, ANCHORS as ANCHOR2, MODES, PARTITIONS, WEIGHTS3, WEIGHTS4};

use super::fit::{fit_line, line_through};
use super::partition::{partition_residuals, REGION1};
use super::texels::{dot16, sum16, Plane, Texels};

const ONES: Plane = [1.0; 16];
const ZEROS: Plane = [0.0; 16];

/// For each lane, the quantised endpoint whose unquantised value is nearest to `v[i]`
/// (interpolation domain), for `bits` of precision. Branch-free per lane, so that the endpoints
/// of a block are quantised together as SIMD.
#[inline(always)]
fn quantize<const S: bool, const L: usize>(v: &[f32; L], bits: u32) -> [i32; L] {
    let mut out = [0i32; L];
    if (S && bits >= 16) || (!S && bits >= 15) {
        // Unquantisation is the identity: round the magnitude (a tie to the lower).
        for i in 0..L {
            let m = if S { v[i].abs().min(32767.0) } else { v[i].clamp(0.0, 65535.0) };
            let q = integer_below(m + 0.5);
            out[i] = if S && v[i] < 0.0 { -q } else { q };
        }
        return out;
    }
    // Unquantised, magnitude q of `bits` precision is (q + 1/2) * step in the interior, 0 for
    // q = 0 and `full` for the top code (decode.rs, `unquantize`). So the nearest code is
    // floor(m / step), except near the two ends (0 against 1, max - 1 against max); ties go to
    // the lower code.
    let mag_bits = if S { bits - 1 } else { bits };
    let max = (1i32 << mag_bits) - 1;
    let full = if S { 32767.0 } else { 65535.0 };
    let step = (1u32 << (16 - bits)) as f32;
    let below_top = full + 1.0 - 1.5 * step; // the unquantised value of code max - 1
    for i in 0..L {
        let m = if S { v[i].abs().min(32767.0) } else { v[i].clamp(0.0, 65535.0) };
        // The largest integer below m / step, not floor: a value on a boundary is a tie.
        let q = integer_below(m * (1.0 / step)).clamp(0, max - 1);
        let q = if q == 0 && m > 0.75 * step { 1 } else { q };
        let q = if q == max - 1 && m - below_top > full - m { max } else { q };
        out[i] = if S && v[i] < 0.0 { -q } else { q };
    }
    out
}

/// [`quantize`] of the endpoints of a block (`[end][channel]` flattened): 6 lanes for one
/// region, 12 for two.
#[inline(always)]
fn quantize_endpoints<const S: bool>(lanes: &[f32; 12], regions: u8, bits: u32) -> [i32; 12] {
    if regions == 2 {
        return quantize::<S, 12>(lanes, bits);
    }
    let mut six = [0f32; 6];
    six.copy_from_slice(&lanes[..6]);
    let mut out = [0i32; 12];
    out[..6].copy_from_slice(&quantize::<S, 6>(&six, bits));
    out
}

/// Interpolates two unquantised endpoints and maps the result to half-int (the decoder's final
/// unquantisation).
#[inline(always)]
fn interpolate<const S: bool>(a: i32, b: i32, w: i32) -> i32 {
    // a (64 - w) + b w with one multiplication.
    let c = ((a << 6) + (b - a) * w + 32) >> 6;
    if !S {
        (c * 31) >> 6
    } else if c < 0 {
        -(((-c) * 31) >> 5)
    } else {
        (c * 31) >> 5
    }
}

/// Continuous endpoints of up to two regions: `[region][end][channel]`.
type Ends = [[[f32; 3]; 2]; 2];

/// A fully specified block, with what it decodes to.
#[derive(Clone)]
pub(crate) struct Candidate {
    /// Sum of squared half-int differences (in `f32`: exact while each texel's error is below
    /// 2^24, which covers every fit worth comparing).
    pub err: f32,
    pub mode: usize,
    pub partition: usize,
    /// Quantised endpoints (absolute values, not deltas): `[endpoint][channel]`.
    pub q: [[i32; 3]; 4],
    pub indices: [u8; 16],
}

impl Candidate {
    fn worst() -> Candidate {
        Candidate { err: f32::INFINITY, mode: 10, partition: 0, q: [[0; 3]; 4], indices: [0; 16] }
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
        PACKERS[self.mode](&values, &self.indices)
    }

    /// The decoded texels as half bits, recomputed from the endpoints and indices the way a
    /// decoder does (this keeps the sign of a negative value that rounds to zero: -0.0).
    pub(crate) fn decoded_halves(&self, signed: bool) -> [[u16; 3]; 16] {
        let mode = &MODES[self.mode];
        let bits = mode.endpoint_bits as u32;
        let weights: &[u8] = if mode.regions == 2 { &WEIGHTS3 } else { &WEIGHTS4 };
        let mask = if mode.regions == 2 { PARTITIONS[self.partition] } else { 0 };
        let unq = |v: i32| unquantize_endpoint(v, bits, signed);
        let mut out = [[0u16; 3]; 16];
        for (i, texel) in out.iter_mut().enumerate() {
            let r = ((mask >> i) & 1) as usize;
            let w = weights[self.indices[i] as usize] as i32;
            for (c, v) in texel.iter_mut().enumerate() {
                let a = unq(self.q[2 * r][c]);
                let b = unq(self.q[2 * r + 1][c]);
                let x = (a * (64 - w) + b * w + 32) >> 6;
                *v = if x < 0 {
                    0x8000 | (((-x) * 31) >> 5) as u16
                } else if signed {
                    interpolate::<true>(x, x, 0) as u16
                } else {
                    interpolate::<false>(x, x, 0) as u16
                };
            }
        }
        out
    }
}

/// One specialised packer per mode: with the layout known at compile time the runs become
/// constant shifts and masks.
#[allow(clippy::type_complexity)]
static PACKERS: [fn(&[u32; 13], &[u8; 16]) -> [u8; 16]; 14] = [
    pack_mode::<0>,
    pack_mode::<1>,
    pack_mode::<2>,
    pack_mode::<3>,
    pack_mode::<4>,
    pack_mode::<5>,
    pack_mode::<6>,
    pack_mode::<7>,
    pack_mode::<8>,
    pack_mode::<9>,
    pack_mode::<10>,
    pack_mode::<11>,
    pack_mode::<12>,
    pack_mode::<13>,
];

/// [`pack_block`] for mode `M` (an index into [`MODES`]): the same bits, written without a
/// bit writer, and the indices gathered with shifts (each anchor index drops its top bit, which
/// is 0). The tests compare it with `pack_block`.
fn pack_mode<const M: usize>(values: &[u32; 13], indices: &[u8; 16]) -> [u8; 16] {
    let info = &MODES[M];
    let mut bits = info.mode_value as u128;
    let mut pos = info.mode_bits as u32;
    for run in info.layout {
        let n = run.len();
        let lo = run.first.min(run.last) as u32;
        let mut v = (values[run.field as usize] >> lo) & ((1u32 << n) - 1);
        if run.reversed() {
            v = v.reverse_bits() >> (32 - n);
        }
        bits |= (v as u128) << pos;
        pos += n;
    }
    let ib = info.index_bits();
    let mut packed = 0u64;
    for &index in indices.iter().rev() {
        packed = (packed << ib) | index as u64;
    }
    let drop_bit = |packed: u64, bit: u32| (packed & ((1u64 << bit) - 1)) | ((packed >> (bit + 1)) << bit);
    if info.regions == 2 {
        // The second anchor first: it sits above texel 0's slot.
        packed = drop_bit(packed, ANCHOR2[(values[12] & 31) as usize] as u32 * ib + ib - 1);
    }
    packed = drop_bit(packed, ib - 1);
    (bits | (packed as u128) << pos).to_le_bytes()
}

/// How hard to search, derived from the effort level.
#[derive(Clone, Copy)]
pub(crate) struct Search {
    /// Try all four one-region modes (otherwise only the most precise one that fits).
    all_one_region: bool,
    /// Number of best-estimated partitions to encode with two-region modes (0 = none).
    partitions: usize,
    /// Try every two-region mode (otherwise the most precise one whose deltas fit, plus mode 10
    /// if `mode10_too`).
    all_two_region: bool,
    /// With `all_two_region` off, also try mode 10 when a transformed mode fits.
    mode10_too: bool,
    /// Least-squares refinement passes.
    iterations: u32,
    /// Compare every texel with every palette entry (otherwise only with the two entries around
    /// its projection onto the palette's line).
    exhaustive: bool,
}

impl Search {
    pub(crate) fn for_effort(effort: u8) -> Search {
        let (all1, partitions, all2, iterations, exhaustive) = match effort {
            0 => (false, 0, false, 0, false),
            1 => (false, 0, false, 1, false),
            2 => (false, 1, false, 1, false),
            3 => (false, 2, false, 2, false),
            4 => (true, 4, false, 2, false),
            5 => (true, 6, true, 2, true),
            6 => (true, 10, true, 3, true),
            7 => (true, 16, true, 4, true),
            8 => (true, 24, true, 6, true),
            _ => (true, 32, true, 8, true),
        };
        let mode10_too = effort >= 4;
        Search { all_one_region: all1, partitions, all_two_region: all2, mode10_too, iterations, exhaustive }
    }
}

/// The encoder for one block at one search setting; `S` selects SF16 (signed).
pub(crate) struct BlockEncoder<'a, const S: bool> {
    tex: &'a Texels,
    search: Search,
}

impl<'a, const S: bool> BlockEncoder<'a, S> {
    #[inline(always)]
    pub(crate) fn new(tex: &'a Texels, search: Search) -> Self {
        BlockEncoder { tex, search }
    }

    /// Quantises continuous endpoints for `mode`, orienting each region so that its anchor texel
    /// sits nearer the first endpoint and clamping deltas into the mode's range.
    #[inline(always)]
    fn quantize_ends(&self, mode: &Mode, partition: usize, ends: &Ends) -> [[i32; 3]; 4] {
        let bits = mode.endpoint_bits as u32;
        // The oriented endpoints, [end][channel] flattened.
        let mut lanes = [0f32; 12];
        for r in 0..mode.regions as usize {
            let anchor = if r == 0 { 0 } else { ANCHOR2[partition] as usize };
            let (a, b) = (ends[r][0], ends[r][1]);
            let mut along = 0.0;
            let mut len2 = 0.0;
            for c in 0..3 {
                along += (self.tex.target[c][anchor] - a[c]) * (b[c] - a[c]);
                len2 += (b[c] - a[c]) * (b[c] - a[c]);
            }
            let (a, b) = if along > 0.5 * len2 { (b, a) } else { (a, b) };
            for c in 0..3 {
                lanes[6 * r + c] = a[c];
                lanes[6 * r + 3 + c] = b[c];
            }
        }
        let quantized = quantize_endpoints::<S>(&lanes, mode.regions, bits);
        let mut q = [[0i32; 3]; 4];
        for e in 0..4 {
            for c in 0..3 {
                q[e][c] = quantized[3 * e + c];
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
    #[inline(always)]
    fn fits(&self, mode: &Mode, ends: &Ends) -> bool {
        if !mode.transformed {
            return true;
        }
        let bits = mode.endpoint_bits as u32;
        // Quick rejection without quantising: a quantised endpoint is within one step of
        // value / step, so a delta is within two steps of the continuous one.
        let step = (1u32 << (16 - bits)) as f32;
        for region in ends.iter().take(mode.regions as usize) {
            for end in region {
                for c in 0..3 {
                    let limit = ((1u32 << (mode.delta_bits[c] - 1)) + 2) as f32 * step;
                    if (end[c] - ends[0][0][c]).abs() > limit {
                        return false;
                    }
                }
            }
        }
        let mut lanes = [0f32; 12];
        for e in 0..4 {
            for c in 0..3 {
                lanes[3 * e + c] = ends[e / 2][e % 2][c];
            }
        }
        let q = quantize_endpoints::<S>(&lanes, mode.regions, bits);
        for e in 1..mode.regions as usize * 2 {
            for c in 0..3 {
                let half_range = 1i32 << (mode.delta_bits[c] - 1);
                let d = q[3 * e + c] - q[c];
                // Either end may become the base after orientation: require the range to fit
                // from both sides.
                if d < -half_range + 1 || d > half_range - 2 {
                    return false;
                }
            }
        }
        true
    }

    /// Chooses indices for quantised endpoints and computes the error.
    #[inline(always)]
    fn evaluate(&self, m: usize, partition: usize, q: [[i32; 3]; 4]) -> Candidate {
        if MODES[m].regions == 2 {
            self.evaluate_n::<8, true>(m, partition, q)
        } else {
            self.evaluate_n::<16, false>(m, 0, q)
        }
    }

    /// [`Self::evaluate`] for a palette of `N` entries, two regions if `TWO`. Every texel is
    /// compared with every palette entry (16 texels at once, entry by entry), which as SIMD
    /// costs less than projecting and searching neighbours texel by texel.
    #[inline(always)]
    fn evaluate_n<const N: usize, const TWO: bool>(&self, m: usize, partition: usize, q: [[i32; 3]; 4]) -> Candidate {
        let bits = MODES[m].endpoint_bits as u32;
        // Unquantised endpoints, ends[region][end][channel].
        let mut ends = [[[0i32; 3]; 2]; 2];
        for r in 0..1 + TWO as usize {
            for c in 0..3 {
                ends[r][0][c] = unquantize::<S>(q[2 * r][c], bits);
                ends[r][1][c] = unquantize::<S>(q[2 * r + 1][c], bits);
            }
        }
        // palette[region][channel][entry] as half-ints (only the first and last entries when
        // searching by projection).
        let mut palette = [[[0f32; N]; 3]; 2];
        for r in 0..1 + TWO as usize {
            for c in 0..3 {
                let (a, b) = (ends[r][0][c], ends[r][1][c]);
                if self.search.exhaustive {
                    for k in 0..N {
                        palette[r][c][k] = interpolate::<S>(a, b, weight_of(k as i32, N)) as f32;
                    }
                } else {
                    palette[r][c][0] = interpolate::<S>(a, b, 0) as f32;
                    palette[r][c][N - 1] = interpolate::<S>(a, b, 64) as f32;
                }
            }
        }
        let region = if TWO { &REGION1[partition] } else { &ZEROS };
        let anchor2 = if TWO { ANCHOR2[partition] as usize } else { 0 };
        let h = &self.tex.half;
        let mut best = [f32::INFINITY; 16];
        let mut best_k = [0i32; 16];
        if self.search.exhaustive {
            // Anchor texels (whose index has one bit less) may only use the first half.
            nearest_entries::<N, TWO>(&palette, region, h, 0..N / 2, &mut best, &mut best_k);
            let anchors = [(best[0], best_k[0]), (best[anchor2], best_k[anchor2])];
            nearest_entries::<N, TWO>(&palette, region, h, N / 2..N, &mut best, &mut best_k);
            (best[anchor2], best_k[anchor2]) = anchors[1];
            (best[0], best_k[0]) = anchors[0];
        } else {
            let mut last = [N as i32 - 1; 16];
            last[anchor2] = N as i32 / 2 - 1;
            last[0] = N as i32 / 2 - 1;
            nearest_by_projection::<S, N, TWO>(&palette, &ends, region, &last, h, &mut best, &mut best_k);
        }
        let mut indices = [0u8; 16];
        for i in 0..16 {
            indices[i] = best_k[i] as u8;
        }
        Candidate { err: sum16(&best), mode: m, partition, q, indices }
    }

    /// Least-squares endpoints for fixed indices, per region and channel.
    #[inline(always)]
    fn least_squares(&self, cand: &Candidate, previous: &Ends) -> Ends {
        let mode = &MODES[cand.mode];
        let weights: &[u8] = if mode.regions == 2 { &WEIGHTS3 } else { &WEIGHTS4 };
        let region1 = if mode.regions == 2 { &REGION1[cand.partition] } else { &ZEROS };
        let mut w = [0f32; 16];
        for i in 0..16 {
            w[i] = weights[cand.indices[i] as usize] as f32 / 64.0;
        }
        let mut ends = *previous;
        for (r, region_ends) in ends.iter_mut().enumerate().take(mode.regions as usize) {
            // Weights of the two endpoints for the texels of this region (0 elsewhere).
            let mut wa = [0f32; 16];
            let mut wb = [0f32; 16];
            for i in 0..16 {
                let member = if r == 0 { 1.0 - region1[i] } else { region1[i] };
                wa[i] = (1.0 - w[i]) * member;
                wb[i] = w[i] * member;
            }
            let (aa, ab, bb) = (dot16(&wa, &wa), dot16(&wa, &wb), dot16(&wb, &wb));
            let det = aa * bb - ab * ab;
            if det.abs() < 1e-6 {
                continue;
            }
            for c in 0..3 {
                let ax = dot16(&wa, &self.tex.target[c]);
                let bx = dot16(&wb, &self.tex.target[c]);
                region_ends[0][c] = (ax * bb - bx * ab) / det;
                region_ends[1][c] = (bx * aa - ax * ab) / det;
            }
        }
        ends
    }

    /// Encodes with one mode and partition from starting endpoints, refining by least squares.
    #[inline(always)]
    fn encode_mode(&self, m: usize, partition: usize, start: &Ends) -> Candidate {
        let mode = &MODES[m];
        let mut best = self.evaluate(m, partition, self.quantize_ends(mode, partition, start));
        let mut ends = *start;
        for _ in 0..self.search.iterations {
            if best.err == 0.0 {
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

    /// Encodes with each mode in the bit set `modes` (over `MODES` indices), keeping the best.
    #[inline(always)]
    fn try_modes(&self, modes: u16, partition: usize, ends: &Ends, best: &mut Candidate) {
        for m in 0..14 {
            if modes & (1 << m) != 0 {
                let cand = self.encode_mode(m, partition, ends);
                if cand.err < best.err {
                    *best = cand;
                }
            }
        }
    }

    /// The first mode (by `MODES` index) in `order` whose deltas hold `ends`. (A loop, not
    /// `Iterator::find`: a closure would not be inlined into the AVX2 build.)
    #[inline(always)]
    #[allow(clippy::manual_find)]
    fn first_fitting(&self, order: &[usize], ends: &Ends) -> Option<usize> {
        for &m in order {
            if self.fits(&MODES[m], ends) {
                return Some(m);
            }
        }
        None
    }

    /// Searches modes (all of them, or only `only_mode`) and returns the best candidate.
    #[inline(always)]
    pub(crate) fn encode(&self, only_mode: Option<usize>) -> Candidate {
        let mut best = Candidate::worst();
        // Candidate modes as bit sets over MODES indices.
        let allowed: u16 = only_mode.map_or(0x3FFF, |m| 1 << m);
        let target = &self.tex.target;
        // One region.
        if allowed & 0x3C00 != 0 {
            let start1: Ends = [fit_line(target, &ONES, 0), [[0.0; 3]; 2]];
            let modes = if self.search.all_one_region || only_mode.is_some() {
                0x3C00
            } else {
                // The most precise mode whose deltas hold the block's range.
                let m = self.first_fitting(&[13, 12, 11], &start1).unwrap_or(10);
                1 << m
            };
            self.try_modes(modes & allowed, 0, &start1, &mut best);
        }
        if best.err == 0.0 {
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
        let (mut residuals, moments) = partition_residuals(target);
        for _ in 0..partitions {
            // The best remaining partition (selection, not a sort: few are taken).
            let mut p = 0;
            for (j, &r) in residuals.iter().enumerate() {
                if r < residuals[p] {
                    p = j;
                }
            }
            residuals[p] = f32::INFINITY;
            let region1 = &REGION1[p];
            let mut region0 = [0f32; 16];
            for i in 0..16 {
                region0[i] = 1.0 - region1[i];
            }
            let (mean0, cov0) = moments.region(p, 0);
            let (mean1, cov1) = moments.region(p, 1);
            let ends: Ends =
                [line_through(target, &region0, &mean0, &cov0), line_through(target, region1, &mean1, &cov1)];
            let modes = if self.search.all_two_region || only_mode.is_some() {
                0x03FF
            } else {
                // The most precise transformed mode whose deltas hold this partition's
                // endpoints, and untransformed mode 10 (which always fits) if none does or if
                // asked to.
                let fitting = self.first_fitting(&[2, 3, 4, 0, 5, 6, 7, 8, 1], &ends);
                match fitting {
                    Some(m) if !self.search.mode10_too => 1 << m,
                    _ => (1 << 9) | fitting.map_or(0, |m| 1 << m),
                }
            };
            self.try_modes(modes & allowed, p, &ends, &mut best);
        }
        best
    }
}

/// For each texel, the nearest of the palette entries `entries` if nearer than `best` (updating
/// `best` and `best_k`). `palette[region][channel][entry]`; `region1` is each texel's region.
#[inline(always)]
fn nearest_entries<const N: usize, const TWO: bool>(
    palette: &[[[f32; N]; 3]; 2],
    region1: &Plane,
    half: &[Plane; 3],
    entries: std::ops::Range<usize>,
    best: &mut Plane,
    best_k: &mut [i32; 16],
) {
    // Local copies, so that the updates stay in registers rather than becoming masked stores.
    let (mut b, mut bk) = (*best, *best_k);
    for k in entries {
        let p0 = [palette[0][0][k], palette[0][1][k], palette[0][2][k]];
        let dp = [palette[1][0][k] - p0[0], palette[1][1][k] - p0[1], palette[1][2][k] - p0[2]];
        let kf = k as i32;
        for i in 0..16 {
            let mut d = 0.0;
            for c in 0..3 {
                // Exact: entries are integers and the region weight is 0 or 1.
                let p = if TWO { p0[c] + region1[i] * dp[c] } else { p0[c] };
                let e = half[c][i] - p;
                d += e * e;
            }
            // Selects rather than a branch, so that the loop becomes blends.
            let nearer = d < b[i];
            b[i] = if nearer { d } else { b[i] };
            bk[i] = if nearer { kf } else { bk[i] };
        }
    }
    (*best, *best_k) = (b, bk);
}

/// The largest integer strictly below x, for 0 <= x < 2^22 (see [`floor_small`]).
#[inline(always)]
fn integer_below(x: f32) -> i32 {
    let f = floor_small(x);
    if (f as f32) < x {
        f
    } else {
        f - 1
    }
}

/// floor(x) for 0 <= x < 2^22 without a float-to-int cast (Rust's saturating casts are not
/// vectorised): adding 2^23 leaves round(x) in the low mantissa bits.
#[inline(always)]
fn floor_small(x: f32) -> i32 {
    let r = ((x + 8_388_608.0).to_bits() as i32) - 0x4B00_0000;
    if r as f32 > x {
        r - 1
    } else {
        r
    }
}

/// The interpolation weight of palette entry `k` of `n`: `round(64 k / (n - 1))`, which is what
/// the specification's weight tables hold (checked in the tests).
#[inline(always)]
fn weight_of(k: i32, n: usize) -> i32 {
    // round(64 k / 15) = floor((64 k + 7) / 15) and round(64 k / 7) = floor((64 k + 3) / 7), the
    // divisions as multiply-and-shift (exact for k < 16), which vectorise.
    if n == 16 {
        ((64 * k + 7) * 4370) >> 16
    } else {
        ((64 * k + 3) * 9363) >> 16
    }
}

/// For each texel, the nearer of the two palette entries around its projection onto the line
/// from the first to the last entry of its region (`best`, `best_k`). The entries are computed
/// arithmetically from the unquantised endpoints `ends[region][end][channel]` exactly as the
/// decoder does, so no table is gathered; `last[i]` is the highest index texel `i` may use.
#[inline(always)]
fn nearest_by_projection<const S: bool, const N: usize, const TWO: bool>(
    palette: &[[[f32; N]; 3]; 2],
    ends: &[[[i32; 3]; 2]; 2],
    region1: &Plane,
    last: &[i32; 16],
    half: &[Plane; 3],
    best: &mut Plane,
    best_k: &mut [i32; 16],
) {
    // Per region: first entry, direction to the last, and (N - 1) / |direction|^2.
    let mut first = [[0f32; 3]; 2];
    let mut dir = [[0f32; 3]; 2];
    let mut scale = [0f32; 2];
    for r in 0..1 + TWO as usize {
        let mut len2 = 0.0;
        for c in 0..3 {
            first[r][c] = palette[r][c][0];
            dir[r][c] = palette[r][c][N - 1] - palette[r][c][0];
            len2 += dir[r][c] * dir[r][c];
        }
        scale[r] = if len2 > 0.0 { (N - 1) as f32 / len2 } else { 0.0 };
    }
    // Per-texel copies of its region's line and endpoints (selects, so that it vectorises).
    let mut lane_first = [[0f32; 16]; 3];
    let mut lane_dir = [[0f32; 16]; 3];
    let mut lane_a = [[0i32; 16]; 3];
    let mut lane_b = [[0i32; 16]; 3];
    let mut lane_scale = [0f32; 16];
    for i in 0..16 {
        let in1 = TWO && region1[i] != 0.0;
        for c in 0..3 {
            lane_first[c][i] = if in1 { first[1][c] } else { first[0][c] };
            lane_dir[c][i] = if in1 { dir[1][c] } else { dir[0][c] };
            lane_a[c][i] = if in1 { ends[1][0][c] } else { ends[0][0][c] };
            lane_b[c][i] = if in1 { ends[1][1][c] } else { ends[0][1][c] };
        }
        lane_scale[i] = if in1 { scale[1] } else { scale[0] };
    }
    let mut k0 = [0i32; 16];
    for i in 0..16 {
        let mut t = 0.0;
        for c in 0..3 {
            t += (half[c][i] - lane_first[c][i]) * lane_dir[c][i];
        }
        let t = t * lane_scale[i];
        let t = t.clamp(0.0, 16.0);
        let hi = last[i] - 1;
        let k = floor_small(t);
        k0[i] = if k < hi { k } else { hi };
    }
    let mut d = [[0f32; 16]; 2];
    for (j, dj) in d.iter_mut().enumerate() {
        for i in 0..16 {
            let w = weight_of(k0[i] + j as i32, N);
            let mut sum = 0.0;
            for c in 0..3 {
                let v = interpolate::<S>(lane_a[c][i], lane_b[c][i], w) as f32;
                let e = half[c][i] - v;
                sum += e * e;
            }
            dj[i] = sum;
        }
    }
    for i in 0..16 {
        let second = d[1][i] < d[0][i];
        best[i] = if second { d[1][i] } else { d[0][i] };
        best_k[i] = k0[i] + second as i32;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::texels::tests::xorshift32;
    use crate::modes::{pack_block, BlockFields};

    /// `quantize` picks the code whose unquantised value (the decoder's `unquantize`) is nearest,
    /// the lower one on a tie: checked against a search over every code, for every precision
    /// the modes use, on values around every code's unquantised value and at random.
    #[test]
    fn quantize_finds_the_nearest_code() {
        fn check<const S: bool>(bits: u32, values: &[f32]) {
            let mag_bits = if S { bits - 1 } else { bits };
            let got = values.iter().map(|&v| quantize::<S, 1>(&[v], bits)[0]);
            for (&v, q) in values.iter().zip(got) {
                let m = if S { v.abs().min(32767.0) } else { v.clamp(0.0, 65535.0) };
                let mut best = 0;
                for c in 0..1i32 << mag_bits {
                    if (unquantize::<S>(c, bits) as f32 - m).abs() < (unquantize::<S>(best, bits) as f32 - m).abs() {
                        best = c;
                    }
                }
                let want = if S && v < 0.0 { -best } else { best };
                assert_eq!(q, want, "value {v} bits {bits} signed {S}");
            }
        }
        let mut next = xorshift32(77);
        for bits in [6, 7, 8, 9, 10, 11, 12] {
            let mut values = Vec::new();
            for c in 0..1i32 << bits {
                let u = unquantize::<false>(c, bits) as f32;
                values.extend([u - 0.75, u - 0.5, u, u + 0.25, u + 0.5, u + 1.0]);
            }
            for _ in 0..2000 {
                values.push((next() % 6_600_000) as f32 / 100.0 - 5.0);
            }
            check::<false>(bits, &values);
            let signed: Vec<f32> =
                values.iter().map(|&v| if next().is_multiple_of(2) { v / 2.0 } else { -v / 2.0 }).collect();
            check::<true>(bits, &signed);
        }
        check::<false>(16, &[0.0, 0.4, 0.5, 0.6, 1000.49, 65534.6, 70000.0]);
        check::<true>(16, &[-0.6, -0.5, 0.49, 31000.5, -40000.0]);
    }

    /// The per-mode packers write exactly what the general `pack_block` writes.
    #[test]
    fn pack_mode_matches_pack_block() {
        let mut next = xorshift32(0x1234_5678);
        for m in 0..14 {
            for _ in 0..2000 {
                let mut fields = BlockFields { mode: m, values: [0; 13], indices: [0; 16] };
                for v in fields.values.iter_mut() {
                    *v = next();
                }
                let info = &MODES[m];
                fields.values[12] = if info.regions == 2 { next() % 32 } else { 0 };
                let ib = info.index_bits();
                let partition = fields.values[12] as usize;
                for (i, index) in fields.indices.iter_mut().enumerate() {
                    let anchor = i == 0 || (info.regions == 2 && i == ANCHOR2[partition] as usize);
                    *index = (next() % (1 << (ib - anchor as u32))) as u8;
                }
                assert_eq!(PACKERS[m](&fields.values, &fields.indices), pack_block(&fields), "mode {}", m + 1);
            }
        }
    }

    /// The arithmetic weights are the specification's tables.
    #[test]
    fn weight_formula_matches_the_tables() {
        for (k, &w) in WEIGHTS4.iter().enumerate() {
            assert_eq!(weight_of(k as i32, 16), w as i32);
        }
        for (k, &w) in WEIGHTS3.iter().enumerate() {
            assert_eq!(weight_of(k as i32, 8), w as i32);
        }
    }
}
