//! The coefficients of one macroblock of one channel: what entropy decoding, prediction and
//! dequantization hand to the inverse transform (T.832 clause 9).
//!
//! The layout is the one T.832 numbers the coefficients by (and the ITU reference software
//! T.835 stores them in, `MACROBLK_CUR_DC/LP/HP` in its `jxr_priv.h`): index 0 the DC
//! coefficient, 1..=15 the lowpass coefficients 1..=15, then 15 highpass coefficients (1..=15)
//! for each of the 16 blocks, block `b` at `16 + 15 * b`. A 4:2:0 chroma macroblock uses DC,
//! LP 1..=3 and HP blocks 0..=3; 4:2:2 uses DC, LP 1..=7 and HP blocks 0..=7; the rest is zero.
//! Values are dequantized and predicted: exactly the inverse transform's input.

/// Coefficients per macroblock and channel: 1 DC + 15 LP + 16 × 15 HP.
pub const MB_COEFFS: usize = 256;

/// Index of the DC coefficient.
pub const DC: usize = 0;

/// Index of lowpass coefficient `k` (1..=15).
pub const fn lp(k: usize) -> usize {
    k
}

/// Index of highpass coefficient `k` (1..=15) of block `block` (0..16).
pub const fn hp(block: usize, k: usize) -> usize {
    16 + 15 * block + (k - 1)
}

/// One macroblock's coefficients for one channel.
pub type MbCoeffs = [i32; MB_COEFFS];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_cover_the_array_once() {
        let mut seen = [false; MB_COEFFS];
        seen[DC] = true;
        for k in 1..=15 {
            assert!(!seen[lp(k)]);
            seen[lp(k)] = true;
        }
        for b in 0..16 {
            for k in 1..=15 {
                assert!(!seen[hp(b, k)]);
                seen[hp(b, k)] = true;
            }
        }
        assert!(seen.iter().all(|&s| s));
    }
}
