//! Quantization (T.832 9.4 and 8.3.5): QP index → step size, per-macroblock QP index coding,
//! and dequantization of a macroblock's coefficients.

use crate::bits::BitReader;
use crate::header::{ClrFmt, QpSet};
use crate::mb;
use hdrcodec_core::{Error, Result};

/// The quantization step of QP index `index` (T.832 9.4.2; T.835 `_jxr_quant_map`, jxrlib
/// `strPredQuant.c: remapQP`). `luma_like` is true for the first channel's DC and LP and for
/// every channel's HP; the other channels' DC and LP steps are halved in scaled mode. Index 0
/// is step 1 in both modes.
pub fn step(index: u8, scaled: bool, luma_like: bool) -> i32 {
    let x = i32::from(index);
    if x == 0 {
        return 1;
    }
    let shift = i32::from(luma_like);
    let (man, exp) = if scaled {
        if x < 16 {
            (x, shift)
        } else {
            (16 + x % 16, (x >> 4) - 1 + shift)
        }
    } else if x < 32 {
        ((x + 3) >> 2, 0)
    } else if x < 48 {
        ((16 + x % 16 + 1) >> 1, (x >> 4) - 2)
    } else {
        (16 + x % 16, (x >> 4) - 3)
    };
    man << exp
}

/// Bits of a macroblock's QP index after its first bit, by the number of sets (T.832 8.6.x:
/// enough for `count − 2`).
const QP_INDEX_BITS: [u32; 17] = [0, 0, 1, 1, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 4, 4, 4];

/// DECODE_QP_INDEX (T.832 8.6.x): which of a tile's `count` (> 1) LP or HP quantizer sets a
/// macroblock uses. An index past the last set is an error.
pub fn read_qp_index(r: &mut BitReader, count: usize) -> Result<u8> {
    if !r.bit() {
        return Ok(0);
    }
    let index = r.read(QP_INDEX_BITS[count.min(16)]) as usize + 1;
    if index >= count {
        return Err(Error::invalid(format!("JPEG XR: macroblock QP index {index} of {count} quantizer sets")));
    }
    Ok(index as u8)
}

/// The encoder's side of [`read_qp_index`]: set `index` of `count` (> 1).
pub fn write_qp_index(w: &mut crate::bits::BitWriter, index: u8, count: usize) {
    w.bit(index != 0);
    if index != 0 {
        w.write(u32::from(index) - 1, QP_INDEX_BITS[count.min(16)]);
    }
}

/// The quantizers of one tile and plane: the DC set, the LP sets and the HP sets.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileQp {
    /// DC indices.
    pub dc: QpSet,
    /// LP sets (at least one).
    pub lp: Vec<QpSet>,
    /// HP sets (at least one).
    pub hp: Vec<QpSet>,
    /// The LP band uses the DC set (USE_DC_QP): no per-macroblock LP index.
    pub lp_use_dc: bool,
    /// The HP band uses the LP sets (USE_LP_QP): the HP index is the LP index.
    pub hp_use_lp: bool,
}

/// Number of LP coefficients (with the DC) and of HP blocks of channel `ch` (T.832 6.5).
pub fn channel_shape(fmt: ClrFmt, ch: usize) -> (usize, usize) {
    match (fmt, ch) {
        (ClrFmt::Yuv420, 1..) => (4, 4),
        (ClrFmt::Yuv422, 1..) => (8, 8),
        _ => (16, 16),
    }
}

/// Multiplies one channel's quantized coefficients by their steps: DC by `dc`, LP by `lp`, the
/// HP of the coded blocks by `hp` (wrapping, as jxrlib's 32-bit arithmetic does).
///
/// On x86-64 with AVX2 (as [`hdrcodec_core::cpu`] allows) the same loops run compiled for
/// AVX2, eight multiplications an instruction (SSE2 has no 32-bit multiply to keep the low
/// half of); `dequantize_twins_agree` checks they give the same.
#[allow(unsafe_code)]
pub fn dequantize(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
        return unsafe { dequantize_avx2(c, shape, dc, lp, hp) };
    }
    dequantize_portable(c, shape, dc, lp, hp)
}

/// [`dequantize_portable`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn dequantize_avx2(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    dequantize_portable(c, shape, dc, lp, hp)
}

/// The portable body of [`dequantize`].
#[inline(always)]
fn dequantize_portable(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    c[mb::DC] = c[mb::DC].wrapping_mul(dc);
    // A step of 1 (every band of a lossless file) changes nothing: its loop is skipped.
    if lp != 1 {
        for v in &mut c[1..shape.0] {
            *v = v.wrapping_mul(lp);
        }
    }
    if hp != 1 {
        for v in &mut c[16..16 + 15 * shape.1] {
            *v = v.wrapping_mul(hp);
        }
    }
}

/// The encoder's quantization of one value: sign and magnitude, the magnitude divided by
/// `step` after adding `offset` (jxrlib `strPredQuantEnc.c: quantizeMacroblock` uses
/// ⌊step/2⌋ for DC and ⌊(3·step + 1)/8⌋ for LP and HP, a dead zone that favours zero for the
/// bands where most values are small). The decoder only multiplies back, so the rounding is
/// the encoder's choice.
#[inline]
pub fn quantize_value(v: i32, step: i32, offset: i32) -> i32 {
    if step <= 1 {
        return v;
    }
    let q = ((i64::from(v).abs() + i64::from(offset)) / i64::from(step)) as i32;
    if v < 0 {
        -q
    } else {
        q
    }
}

/// The rounding offsets [`quantize_value`] uses for the DC and for the LP and HP bands.
pub fn offsets(dc: i32, lp: i32, hp: i32) -> (i32, i32, i32) {
    (dc / 2, (3 * lp + 1) / 8, (3 * hp + 1) / 8)
}

/// [`quantize_value`] for one step and offset, without a division, in 32-bit lanes that
/// vectorise: the dividend a = |v| + offset is below 2^32, and for a divisor 2 ≤ d < 2^32
/// with ℓ = ⌈log2 d⌉ and m = ⌊2^32 · (2^ℓ − d) / d⌋ + 1 (below 2^32), ⌊a / d⌋ is
/// (t + ((a − t) >> 1)) >> (ℓ − 1) with t the high half of the 64-bit product a · m
/// (Granlund and Montgomery, "Division by invariant integers using multiplication", PLDI
/// 1994, Figure 4.1 with N = 32: exact for every a below 2^N). A step of 1 or less keeps the
/// value (m = 0 and no shift would halve it, so those steps are left to the caller).
#[derive(Clone, Copy, Debug)]
struct Quantizer {
    /// m above; 0 for steps of 1 or less.
    magic: u32,
    /// ℓ − 1.
    shift: u32,
    offset: u32,
}

impl Quantizer {
    fn new(step: i32, offset: i32) -> Self {
        if step <= 1 {
            return Quantizer { magic: 0, shift: 0, offset: 0 };
        }
        let d = step as u64;
        // ℓ = ⌈log2 d⌉ (d ≥ 2, so ℓ ≥ 1).
        let l = 64 - (d - 1).leading_zeros();
        let magic = (((1u64 << l) - d) << 32) / d + 1;
        Quantizer { magic: magic as u32, shift: l - 1, offset: offset.max(0) as u32 }
    }

    /// Whether the step keeps every value (1 or less).
    fn keeps(self) -> bool {
        self.magic == 0
    }

    /// One value; the step must be 2 or more (not [`Quantizer::keeps`]).
    #[inline(always)]
    fn divide(self, v: i32) -> i32 {
        // |v| ≤ 2^31 and offset < step < 2^31: the dividend is below 2^32, and the quotient
        // (step ≥ 2) at most 2^31 − 1.
        let a = v.unsigned_abs() + self.offset;
        let t = ((u64::from(a) * u64::from(self.magic)) >> 32) as u32;
        let q = ((t + ((a - t) >> 1)) >> self.shift) as i32;
        // The sign put back without a branch (signs are random: a branch on them is
        // mispredicted half the time): s is 0 or −1, (q ^ s) − s is q or −q.
        let s = v >> 31;
        (q ^ s) - s
    }

    /// [`Quantizer::divide`] of every value, in place (any step).
    #[inline(always)]
    fn apply(self, values: &mut [i32]) {
        if !self.keeps() {
            for v in values {
                *v = self.divide(*v);
            }
        }
    }
}

/// The encoder's side of [`dequantize`]: quantizes one channel's coefficients (shape as
/// there) with the steps `dc`, `lp` and `hp` ([`quantize_value`] with the [`offsets`], the
/// divisions done as multiplications, a macroblock's LP and then its HP values in one run
/// each), and zeroes the HP blocks [`is_marginal`] finds not worth their bits.
///
/// On x86-64 with AVX2 (as [`hdrcodec_core::cpu`] allows) the same code runs compiled for
/// AVX2, eight values an instruction; `quantize_twins_agree` checks they give the same.
#[allow(unsafe_code)]
pub fn quantize(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, the twin's one feature.
        return unsafe { quantize_avx2(c, shape, dc, lp, hp) };
    }
    quantize_portable(c, shape, dc, lp, hp)
}

/// [`quantize_portable`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)]
unsafe fn quantize_avx2(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    quantize_portable(c, shape, dc, lp, hp)
}

/// The portable body of [`quantize`].
#[inline(always)]
fn quantize_portable(c: &mut [i32], shape: (usize, usize), dc: i32, lp: i32, hp: i32) {
    let (odc, olp, ohp) = offsets(dc, lp, hp);
    c[mb::DC] = quantize_value(c[mb::DC], dc, odc);
    Quantizer::new(lp, olp).apply(&mut c[1..shape.0]);
    let q = Quantizer::new(hp, ohp);
    if q.keeps() {
        return;
    }
    let values = &mut c[16..16 + 15 * shape.1];
    let mut unquantized = [0i32; 15 * 16];
    let unquantized = &mut unquantized[..values.len()];
    unquantized.copy_from_slice(values);
    q.apply(values);
    for (block, before) in values.chunks_exact_mut(15).zip(unquantized.chunks_exact(15)) {
        // Most blocks of a coarse quantizer are all zero: one OR over the block says so.
        if block.iter().fold(0, |a, &v| a | v) != 0 && is_marginal(before, block, hp) {
            block.fill(0);
        }
    }
}

/// The most nonzero HP coefficients (each ±1) of a 4×4 block that [`is_marginal`]
/// may drop.
const MARGINAL_MAX_COEFFS: usize = 2;

/// How far past the rounding threshold, in [`is_marginal`]'s measure, the
/// coefficients of a block may reach and still be dropped.
const MARGINAL_SLACK: i64 = 7;

/// The encoder's rate-distortion choice in [`quantize`]: an HP block (4×4, 15 coefficients)
/// whose quantized coefficients `q` are one or two ±1 that its values (`unquantized`) only
/// just reached is zeroed. Setting a value u steps large to 1 instead of 0 lowers its squared
/// error by (2u − 1) steps², while the block then costs its coded-block bit, a run and a level
/// (about 6 bits per coefficient), and at the slope of a uniform quantizer's rate-distortion
/// curve (2 ln 2 · step²/12 ≈ 0.12 step² a bit) that is worth about 0.7 step² per coefficient.
/// So a block goes when the sum of its (2u − 1) is below 0.7 per coefficient (as tenths:
/// [`MARGINAL_SLACK`]); measured on the corpus photographs, 1.5% fewer bytes at equal
/// PU21-PSNR. Never at step 1 (lossless).
fn is_marginal(unquantized: &[i32], q: &[i32], step: i32) -> bool {
    if step <= 1 {
        return false;
    }
    let mut n = 0;
    // Sum of (2u − 1) · step over the nonzero coefficients, u = |value| / step.
    let mut excess = 0i64;
    for (&q, &v) in q.iter().zip(unquantized) {
        if q != 0 {
            n += 1;
            if q.abs() > 1 || n > MARGINAL_MAX_COEFFS {
                return false;
            }
            excess += 2 * i64::from(v.unsigned_abs()) - i64::from(step);
        }
    }
    n != 0 && 10 * excess < MARGINAL_SLACK * n as i64 * i64::from(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 twin of [`dequantize`] multiplies as the portable code does, wrapping, for
    /// every channel shape.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn dequantize_twins_agree() {
        use hdrcodec_core::cpu::{self, CpuLevel};
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "dequantize_twins_agree") {
            return;
        }
        let mut x = 0x9e37_79b9u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as i32
        };
        for shape in [(16, 16), (4, 4), (8, 8)] {
            let c: Vec<i32> = (0..mb::MB_COEFFS).map(|_| next() >> 8).collect();
            let (dc, lp, hp) = (next() >> 12, next() >> 4, next());
            let (mut a, mut b) = (c.clone(), c.clone());
            dequantize_portable(&mut a, shape, dc, lp, hp);
            // SAFETY: the CPU has AVX2 (checked above).
            unsafe { dequantize_avx2(&mut b, shape, dc, lp, hp) };
            assert_eq!(a, b, "{shape:?}");
            assert_eq!(a[16], c[16].wrapping_mul(hp));
            assert_ne!(a, c);
            // Steps of 1 skip their band's loop: the same as multiplying.
            for (dc, lp, hp) in [(1, 1, 1), (dc, 1, hp), (dc, lp, 1)] {
                let (mut a, mut b) = (c.clone(), c.clone());
                dequantize_portable(&mut a, shape, dc, lp, hp);
                // SAFETY: the CPU has AVX2 (checked above).
                unsafe { dequantize_avx2(&mut b, shape, dc, lp, hp) };
                let want: Vec<i32> = c
                    .iter()
                    .enumerate()
                    .map(|(i, &v)| match i {
                        0 => v.wrapping_mul(dc),
                        _ if i < shape.0 => v.wrapping_mul(lp),
                        _ if (16..16 + 15 * shape.1).contains(&i) => v.wrapping_mul(hp),
                        _ => v,
                    })
                    .collect();
                assert!(a == want && b == want, "{shape:?} {dc} {lp} {hp}");
            }
        }
    }

    #[test]
    fn quantizers_divide_exactly() {
        // Every step kind (small, powers of two, the largest QP index's) at the values where
        // a multiplicative inverse would first go wrong: around multiples of the step and at
        // the ends of the range.
        let mut steps: Vec<i32> = (0..=255u8).flat_map(|i| [step(i, false, true), step(i, true, true)]).collect();
        steps.extend([2, 3, 7, (1 << 30) - 1, 1 << 30, i32::MAX]);
        let mut x = 0x1234_5678u32;
        for &s in &steps {
            for o in [0, s / 2, ((3 * i64::from(s) + 1) / 8) as i32] {
                let q = Quantizer::new(s, o);
                let mut values = vec![0, 1, -1, i32::MAX, i32::MIN, i32::MIN + 1, s, -s, s - 1, 1 - s];
                for k in [1i64, 2, 3, 1000, 65_537] {
                    for d in [-1i64, 0, 1] {
                        let v = k * i64::from(s) + d - i64::from(o);
                        if let Ok(v) = i32::try_from(v) {
                            values.extend([v, v.wrapping_neg()]);
                        }
                    }
                }
                for _ in 0..200 {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    values.push(x as i32);
                }
                for v in values {
                    let mut got = [v];
                    q.apply(&mut got);
                    assert_eq!(got[0], quantize_value(v, s, o), "{v} / {s} + {o}");
                }
            }
        }
    }

    /// The AVX2 twin of [`quantize`] gives the portable code's coefficients for every channel
    /// shape, steps of every size (1 included) and values of every magnitude, marginal blocks
    /// and all-zero blocks among them.
    #[test]
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    fn quantize_twins_agree() {
        if !hdrcodec_core::cpu::twin_test_can_run(hdrcodec_core::cpu::CpuLevel::Avx2, "quantize_twins_agree") {
            return;
        }
        let mut next = crate::testing::rng(0x9e37);
        let mut compared = 0;
        for shape in [(16, 16), (8, 8), (4, 4)] {
            for index in [0u8, 1, 8, 40, 97, 144, 200, 255] {
                for scaled in [false, true] {
                    let (dc, lp, hp) =
                        (step(index, scaled, true), step(index, scaled, false), step(index, scaled, true));
                    for round in 0..20 {
                        // Magnitudes from a fraction of the step to the whole i32 range.
                        let bits = [4u32, 8, 12, 16, 24, 31][round % 6];
                        let mut c = [0i32; mb::MB_COEFFS];
                        for v in &mut c {
                            let r = next();
                            *v = if r.is_multiple_of(3) { 0 } else { ((r >> 8) as i32) >> (31 - bits) };
                        }
                        if round == 7 {
                            c[16] = i32::MIN;
                            c[17] = i32::MAX;
                        }
                        let (mut a, mut b) = (c, c);
                        quantize_portable(&mut a, shape, dc, lp, hp);
                        // SAFETY: the CPU has AVX2 (checked above).
                        unsafe { quantize_avx2(&mut b, shape, dc, lp, hp) };
                        assert_eq!(a, b, "shape {shape:?}, index {index}, scaled {scaled}, round {round}");
                        // And both are the division's, marginal blocks aside.
                        let (odc, olp, ohp) = offsets(dc, lp, hp);
                        assert_eq!(a[0], quantize_value(c[0], dc, odc));
                        for i in 1..shape.0 {
                            assert_eq!(a[i], quantize_value(c[i], lp, olp));
                        }
                        for i in 16..16 + 15 * shape.1 {
                            assert!(a[i] == 0 || a[i] == quantize_value(c[i], hp, ohp), "{i}");
                        }
                        compared += 1;
                    }
                }
            }
        }
        assert_eq!(compared, 3 * 8 * 2 * 20);
    }

    #[test]
    fn quantization_is_within_a_step_and_lossless_at_step_one() {
        for v in -1000..1000 {
            assert_eq!(quantize_value(v, 1, 0), v);
            for step in [2, 3, 7, 16, 100] {
                let (o, _, _) = offsets(step, step, step);
                let q = quantize_value(v, step, o);
                assert!((q * step - v).abs() < step, "{v} {step}");
                assert_eq!(quantize_value(-v, step, o), -q);
            }
        }
    }

    #[test]
    fn marginal_hp_blocks_are_zeroed() {
        let step = 100;
        let block = |values: &[i32]| {
            let mut values_in = [0i32; mb::MB_COEFFS];
            values_in[16..16 + values.len()].copy_from_slice(values);
            let mut q = values_in;
            quantize(&mut q, (16, 1), step, step, step);
            q[16..31].to_vec()
        };
        // One value 0.7 steps large: 2u − 1 = 0.4 < 0.7, dropped.
        assert!(block(&[70]).iter().all(|&v| v == 0));
        // 0.9 steps: 0.8, kept; two at 0.7: 0.8 < 1.4, dropped; three: kept.
        assert_eq!(block(&[-90])[0], -1);
        assert!(block(&[70, -70]).iter().all(|&v| v == 0));
        assert_eq!(block(&[70, -70, 70])[..3], [1, -1, 1]);
        // A level of 2 keeps the block.
        assert_eq!(block(&[70, 180])[..2], [1, 2]);
        // Lossless steps are left alone.
        let mut q = [0i32; mb::MB_COEFFS];
        q[16] = 1;
        quantize(&mut q, (16, 16), 1, 1, 1);
        assert_eq!(q[16], 1);
    }

    #[test]
    fn steps_follow_the_tables() {
        // Unscaled (JXR-NOTES §5, T.832 9.4.2).
        let u: Vec<i32> =
            [0u8, 1, 4, 5, 15, 16, 31, 32, 47, 48, 63, 64, 255].iter().map(|&i| step(i, false, true)).collect();
        assert_eq!(u, vec![1, 1, 1, 2, 4, 4, 8, 8, 16, 16, 31, 32, 31 << 12]);
        // Scaled luma: 2i below 16, then (16 + i mod 16) << (i/16).
        let s: Vec<i32> = [1u8, 15, 16, 31, 32, 255].iter().map(|&i| step(i, true, true)).collect();
        assert_eq!(s, vec![2, 30, 32, 62, 64, 31 << 15]);
        // Scaled chroma DC/LP: half.
        let c: Vec<i32> = [1u8, 15, 16, 255].iter().map(|&i| step(i, true, false)).collect();
        assert_eq!(c, vec![1, 15, 16, 31 << 14]);
        // Unscaled does not depend on the channel.
        assert_eq!(step(100, false, false), step(100, false, true));
    }

    #[test]
    fn qp_indices_written_read_back() {
        for count in 2..=16usize {
            let mut w = crate::bits::BitWriter::new();
            for i in 0..count {
                write_qp_index(&mut w, i as u8, count);
            }
            let bytes = w.into_bytes();
            let mut r = BitReader::new(&bytes);
            for i in 0..count {
                assert_eq!(read_qp_index(&mut r, count).unwrap(), i as u8, "{i} of {count}");
            }
        }
    }

    #[test]
    fn qp_index_bounds() {
        // 1, then 3 bits "111" = 7 + 1 = 8 > 5 sets: an error.
        let mut r = BitReader::new(&[0b1111_0000]);
        assert!(read_qp_index(&mut r, 6).is_err());
        let mut r = BitReader::new(&[0b0100_0000]);
        assert_eq!(read_qp_index(&mut r, 2).unwrap(), 0);
        assert_eq!(read_qp_index(&mut r, 2).unwrap(), 1);
    }
}
