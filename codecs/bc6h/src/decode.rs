//! The BC6H block decoder (D3D11 functional specification, "BC6H Format": decoding steps) and
//! the parallel whole-surface decoder.
use crate::modes::{Field, ANCHORS, MODES, MODE_FROM_BITS, PARTITIONS, WEIGHTS3, WEIGHTS4};
use hdrcodec_core::{Error, Result};
use rayon::prelude::*;

/// Sign-extends the low `bits` bits of `v`.
#[inline(always)]
fn sign_extend(v: i32, bits: u32) -> i32 {
    let s = 32 - bits;
    (v << s) >> s
}

/// Spec `unquantize`: expands an endpoint of `bits` precision to 16 bits (UF16: 0..=0xFFFF;
/// SF16: -0x7FFF..=0x7FFF).
#[inline(always)]
pub(crate) fn unquantize<const SIGNED: bool>(v: i32, bits: u32) -> i32 {
    if !SIGNED {
        if bits >= 15 || v == 0 {
            v
        } else if v == (1 << bits) - 1 {
            0xFFFF
        } else {
            ((v << 16) + 0x8000) >> bits
        }
    } else {
        if bits >= 16 {
            return v;
        }
        let m = v.abs();
        let u = if m == 0 {
            0
        } else if m >= (1 << (bits - 1)) - 1 {
            0x7FFF
        } else {
            ((m << 15) + 0x4000) >> (bits - 1)
        };
        if v < 0 {
            -u
        } else {
            u
        }
    }
}

/// [`unquantize`] with the signedness chosen at run time (the encoder's entry point).
#[inline]
pub(crate) fn unquantize_endpoint(v: i32, bits: u32, signed: bool) -> i32 {
    if signed {
        unquantize::<true>(v, bits)
    } else {
        unquantize::<false>(v, bits)
    }
}

/// Spec `finish_unquantize`: scales an interpolated 16-bit value to the half-float bit pattern
/// (UF16 by 31/64, SF16 by 31/32 on the magnitude, with the sign in bit 15).
#[inline(always)]
fn finish<const SIGNED: bool>(v: i32) -> u16 {
    if !SIGNED {
        ((v * 31) >> 6) as u16
    } else {
        // The sign is applied after scaling, so a tiny negative value that scales to 0
        // becomes +0, never -0 (0x8000).
        let m = (v.abs() * 31) >> 5;
        (if v < 0 && m != 0 { 0x8000 | m } else { m }) as u16
    }
}

/// Decodes one 16-byte BC6H block into 16 texels (row-major) of half-float bit patterns
/// `[r, g, b]`. `signed` selects BC6H_SF16 over BC6H_UF16. Blocks with a reserved mode decode to
/// zero, as the D3D11 specification requires.
#[inline]
pub fn decode_block(block: &[u8; 16], signed: bool) -> [[u16; 3]; 16] {
    let planes = if signed { decode_planes::<true>(block) } else { decode_planes::<false>(block) };
    let mut out = [[0u16; 3]; 16];
    for (i, texel) in out.iter_mut().enumerate() {
        for (c, v) in texel.iter_mut().enumerate() {
            *v = planes[c][i] as u16;
        }
    }
    out
}

/// The decoded block as three channel planes of 16 half-float bit patterns (in `i32` lanes, so
/// that the per-texel arithmetic vectorises).
type Planes = [[i32; 16]; 3];

/// Decodes a block into channel planes, dispatching to a decoder specialised for each mode (the
/// mode's bit layout, region count and transform become constants there).
#[inline(always)]
fn decode_planes<const SIGNED: bool>(block: &[u8; 16]) -> Planes {
    let bits = u128::from_le_bytes(*block);
    match MODE_FROM_BITS[(bits & 31) as usize] {
        Some(0) => decode_mode::<0, SIGNED>(bits),
        Some(1) => decode_mode::<1, SIGNED>(bits),
        Some(2) => decode_mode::<2, SIGNED>(bits),
        Some(3) => decode_mode::<3, SIGNED>(bits),
        Some(4) => decode_mode::<4, SIGNED>(bits),
        Some(5) => decode_mode::<5, SIGNED>(bits),
        Some(6) => decode_mode::<6, SIGNED>(bits),
        Some(7) => decode_mode::<7, SIGNED>(bits),
        Some(8) => decode_mode::<8, SIGNED>(bits),
        Some(9) => decode_mode::<9, SIGNED>(bits),
        Some(10) => decode_mode::<10, SIGNED>(bits),
        Some(11) => decode_mode::<11, SIGNED>(bits),
        Some(12) => decode_mode::<12, SIGNED>(bits),
        Some(13) => decode_mode::<13, SIGNED>(bits),
        // Reserved mode values decode to zero.
        _ => [[0; 16]; 3],
    }
}

/// The most layout runs any mode has (modes 2 and 10 have 24).
const MAX_RUNS: usize = 24;

/// Repeats `$body` once per listed value with `$k` bound to it as a `const`, so that table
/// lookups indexed by `$k` fold to constants (a loop over them is not reliably unrolled).
macro_rules! unroll {
    ($k:ident in [$($n:literal),*] $body:block) => {
        $( { const $k: usize = $n; $body } )*
    };
}

/// The decoder for mode `MODES[M]`.
#[inline(always)]
fn decode_mode<const M: usize, const SIGNED: bool>(bits: u128) -> Planes {
    let info = &MODES[M];
    let layout = info.layout;

    // Gather the header fields. `unroll!` repeats the body with `K` = 0..24 as constants, so
    // every run of this mode's (constant) layout becomes a fixed shift and mask.
    let mut f = [0i32; 13];
    let mut pos = info.mode_bits as u32;
    unroll!(K in [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23] {
        if K < layout.len() {
            let run = &layout[K];
            let n = run.len();
            let v = ((bits >> pos) as u32) & ((1u32 << n) - 1);
            if run.reversed() {
                f[run.field as usize] |= ((v.reverse_bits() >> (32 - n)) << run.last) as i32;
            } else {
                f[run.field as usize] |= (v << run.first) as i32;
            }
            pos += n;
        }
    });
    debug_assert!(layout.len() <= MAX_RUNS);
    let _ = pos;

    // Endpoints: sign extension, inverse transform, unquantize (constant bounds, so these
    // loops unroll for the mode).
    let ep = info.endpoint_bits as u32;
    let ends = info.regions as usize * 2;
    let mut e = [[0i32; 3]; 4];
    for c in 0..3 {
        let db = info.delta_bits[c] as u32;
        let w = if SIGNED { sign_extend(f[c], ep) } else { f[c] };
        e[0][c] = unquantize::<SIGNED>(w, ep);
        for k in 1..4 {
            if k < ends {
                let mut v = f[k * 3 + c];
                if info.transformed || SIGNED {
                    v = sign_extend(v, db);
                }
                if info.transformed {
                    v = (v + w) & ((1 << ep) - 1);
                    if SIGNED {
                        v = sign_extend(v, ep);
                    }
                }
                e[k][c] = unquantize::<SIGNED>(v, ep);
            }
        }
    }

    // Texel weights and regions (region 1 texels take endpoints y, z).
    let mut weight = [0i32; 16];
    let mut second = [false; 16];
    if info.regions == 2 {
        let d = f[Field::D as usize] as usize;
        let anchor = ANCHORS[d] as u32;
        let shape = PARTITIONS[d];
        let idx = (bits >> 82) as u64;
        // Texel 0 and the anchor have 2 index bits, the others 3: texel i > 0 starts at bit
        // 3i - 1, one bit earlier past the anchor.
        for i in 0..16u32 {
            let p = if i == 0 { 0 } else { 3 * i - 1 - (i > anchor) as u32 };
            let mask = if i == 0 || i == anchor { 3 } else { 7 };
            weight[i as usize] = WEIGHTS3[((idx >> p) & mask) as usize] as i32;
            second[i as usize] = (shape >> i) & 1 == 1;
        }
    } else {
        // Texel 0 has 3 index bits, the others 4 (texel i > 0 starts at bit 4i - 1).
        let idx = (bits >> 65) as u64;
        weight[0] = WEIGHTS4[(idx & 7) as usize] as i32;
        for i in 1..16 {
            weight[i] = WEIGHTS4[((idx >> (4 * i - 1)) & 15) as usize] as i32;
        }
    }

    let mut out = [[0i32; 16]; 3];
    for c in 0..3 {
        for i in 0..16 {
            let (a, b) = if second[i] { (e[2][c], e[3][c]) } else { (e[0][c], e[1][c]) };
            let w = weight[i];
            out[c][i] = finish::<SIGNED>((a * (64 - w) + b * w + 32) >> 6) as i32;
        }
    }
    out
}

/// Converts a finished half bit pattern to `f32` without branches, so that it vectorises:
/// normal halves re-bias the exponent, subnormal ones (exponent 0) are `mantissa * 2^-24`
/// exactly, and exponent 31 is infinity. BC6H never yields NaN; the one non-finite value it can
/// yield is -Inf (0xFC00), from an SF16 mode-14 endpoint of -32768 (see the tests).
#[inline(always)]
fn half_to_f32(h: i32) -> f32 {
    let mag = h & 0x7FFF;
    let normal = f32::from_bits(((mag << 13) + (112 << 23)) as u32);
    let subnormal = mag as f32 * (1.0 / 16_777_216.0);
    let v = if mag < 0x400 { subnormal } else { normal };
    let v = if mag >= 0x7C00 { f32::INFINITY } else { v };
    f32::from_bits(v.to_bits() | ((h as u32 & 0x8000) << 16))
}

/// Number of blocks across and down a `width` x `height` surface.
pub fn block_dims(width: u32, height: u32) -> (usize, usize) {
    (width.div_ceil(4) as usize, height.div_ceil(4) as usize)
}

/// Bytes of BC6H data for a `width` x `height` surface (16 per 4x4 block), `None` on overflow.
pub fn surface_bytes(width: u32, height: u32) -> Option<usize> {
    let (bx, by) = block_dims(width, height);
    bx.checked_mul(by)?.checked_mul(16)
}

/// Decodes a surface of BC6H blocks (block rows top to bottom) into interleaved linear RGB `f32`,
/// `width * height * 3` samples, cropping partial edge blocks. Block rows are decoded in parallel
/// on rayon's pool. `blocks` must hold exactly [`surface_bytes`] bytes.
pub fn decode_surface(width: u32, height: u32, blocks: &[u8], signed: bool) -> Result<Vec<f32>> {
    let need = surface_bytes(width, height).ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    if blocks.len() != need {
        let what = format!("BC6H data: {} bytes for a {width}x{height} surface that needs {need}", blocks.len());
        return Err(if blocks.len() < need { Error::truncated(what) } else { Error::invalid(what) });
    }
    // The block data bounds the allocation: 16 bytes of blocks per 16 texels of 12 bytes.
    let samples = (width as usize)
        .checked_mul(height as usize)
        .and_then(|n| n.checked_mul(3))
        .ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    let mut out = vec![0f32; samples];
    decode_surface_into(width, height, blocks, signed, true, &mut out)?;
    Ok(out)
}

/// [`decode_surface`] into a caller's buffer of exactly `width * height * 3` samples (so that a
/// buffer can be reused), on rayon's pool if `parallel`, else on the calling thread only.
pub fn decode_surface_into(
    width: u32,
    height: u32,
    blocks: &[u8],
    signed: bool,
    parallel: bool,
    out: &mut [f32],
) -> Result<()> {
    let need = surface_bytes(width, height).ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    if blocks.len() != need {
        let what = format!("BC6H data: {} bytes for a {width}x{height} surface that needs {need}", blocks.len());
        return Err(if blocks.len() < need { Error::truncated(what) } else { Error::invalid(what) });
    }
    if Some(out.len()) != (width as usize).checked_mul(height as usize).and_then(|n| n.checked_mul(3)) {
        return Err(Error::invalid(format!(
            "output buffer of {} samples for a {width}x{height} RGB surface",
            out.len()
        )));
    }
    if out.is_empty() {
        return Ok(());
    }
    let (bx, _) = block_dims(width, height);
    let row_floats = width as usize * 3 * 4;
    let w = width as usize;
    if parallel {
        out.par_chunks_mut(row_floats)
            .zip(blocks.par_chunks(bx * 16))
            .for_each(|(rows, row_blocks)| decode_block_row(w, row_blocks, rows, signed));
    } else {
        for (rows, row_blocks) in out.chunks_mut(row_floats).zip(blocks.chunks(bx * 16)) {
            decode_block_row(w, row_blocks, rows, signed);
        }
    }
    Ok(())
}

/// Decodes one row of blocks into up to 4 rows of `width` RGB texels (`out.len()` decides how
/// many rows exist).
fn decode_block_row(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement of
        // `decode_block_row_avx2`; its body is the safe scalar code compiled for AVX2.
        unsafe { decode_block_row_avx2(width, row_blocks, out, signed) };
        return;
    }
    decode_block_row_scalar(width, row_blocks, out, signed)
}

/// The portable path (and the twin the AVX2 build is tested against).
fn decode_block_row_scalar(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    if signed {
        decode_block_row_impl::<true>(width, row_blocks, out)
    } else {
        decode_block_row_impl::<false>(width, row_blocks, out)
    }
}

/// The same code as [`decode_block_row_scalar`], compiled with AVX2 enabled so that the
/// 16-texel lanes use 8-wide integer multiplies and blends.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn decode_block_row_avx2(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    if signed {
        decode_block_row_impl::<true>(width, row_blocks, out)
    } else {
        decode_block_row_impl::<false>(width, row_blocks, out)
    }
}

#[inline(always)]
fn decode_block_row_impl<const SIGNED: bool>(width: usize, row_blocks: &[u8], out: &mut [f32]) {
    let rows = out.len() / (width * 3);
    for (bxi, blk) in row_blocks.chunks_exact(16).enumerate() {
        let blk: &[u8; 16] = blk.try_into().expect("chunks_exact(16)");
        let planes = decode_planes::<SIGNED>(blk);
        let mut texels = [[0f32; 16]; 3];
        for c in 0..3 {
            for i in 0..16 {
                texels[c][i] = half_to_f32(planes[c][i]);
            }
        }
        let x0 = bxi * 4;
        let cols = (width - x0).min(4);
        for y in 0..rows {
            let dst = &mut out[(y * width + x0) * 3..(y * width + x0 + cols) * 3];
            for (x, px) in dst.chunks_exact_mut(3).enumerate() {
                px.copy_from_slice(&[texels[0][y * 4 + x], texels[1][y * 4 + x], texels[2][y * 4 + x]]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modes::{pack_block, BlockFields};

    #[test]
    fn half_conversion_matches_the_half_crate_for_every_non_nan_half() {
        for h in 0..=0xFFFFu32 {
            if h & 0x7FFF <= 0x7C00 {
                let want = half::f16::from_bits(h as u16).to_f32();
                assert_eq!(half_to_f32(h as i32).to_bits(), want.to_bits(), "{h:#06x}");
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_build_matches_the_scalar_twin() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let blocks: Vec<u8> = (0..2 * 64 * 8)
            .flat_map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state.to_le_bytes()
            })
            .collect();
        for signed in [false, true] {
            // 7 texels wide (2 blocks per row, the second one cropped), 4 rows.
            for (w, n) in [(7usize, 2usize), (256, 64)] {
                let (mut a, mut b) = (vec![0f32; w * 12], vec![1f32; w * 12]);
                decode_block_row_scalar(w, &blocks[..n * 16], &mut a, signed);
                // SAFETY: AVX2 support was checked above.
                unsafe { decode_block_row_avx2(w, &blocks[..n * 16], &mut b, signed) };
                assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
            }
        }
    }

    #[test]
    fn reserved_modes_decode_to_zero() {
        for r in crate::modes::RESERVED_MODE_VALUES {
            let mut block = [0xFFu8; 16];
            block[0] = (block[0] & !31) | r;
            assert_eq!(decode_block(&block, false), [[0; 3]; 16]);
            assert_eq!(decode_block(&block, true), [[0; 3]; 16]);
        }
    }

    #[test]
    fn mode_11_endpoints_unquantize_as_the_spec_says() {
        // Mode 11 (10-bit endpoints, untransformed): w = 1023 (max) unquantizes to 0xFFFF and
        // finishes to 0xFFFF * 31 >> 6 = 0x7BFF, the largest finite half; x = 0 gives 0.
        let mut fields = BlockFields { mode: 10, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 1023;
        }
        // Texel 0 index 0 (weight 0) -> endpoint w; texel 1 index 15 (weight 64) -> x.
        fields.indices[1] = 15;
        let out = decode_block(&pack_block(&fields), false);
        assert_eq!(out[0], [0x7BFF; 3]);
        assert_eq!(out[1], [0; 3]);
    }

    #[test]
    fn tiny_negative_sf16_values_finish_as_positive_zero() {
        // D3D11 finish_unquantize for SF16: comp = -(((-comp) * 31) >> 5), and the sign bit is
        // set only if comp < 0 afterwards, so -1 becomes +0 (0x0000), never -0 (0x8000).
        // Mode 14 (16-bit, transformed): w = 0xFFFF is -1 after sign extension, delta 0.
        let mut fields = BlockFields { mode: 13, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 0xFFFF;
        }
        let out = decode_block(&pack_block(&fields), true);
        assert_eq!(out, [[0; 3]; 16]);
        // The same bits as UF16: 0xFFFF finishes to 0xFFFF * 31 >> 6 = 0x7BFF.
        assert_eq!(decode_block(&pack_block(&fields), false), [[0x7BFF; 3]; 16]);
    }

    #[test]
    fn sf16_mode_14_endpoint_of_minus_32768_is_minus_infinity() {
        // D3D11 spec, SF16: unquantize passes 16-bit endpoints through (prec >= 16), and
        // finish_unquantize gives -((32768 * 31) >> 5) = -31744 = -0x7C00, i.e. 0xFC00 = -Inf.
        // bcdec agrees (tests/bc6h_decode.rs); found by the bc6h_block fuzz target.
        let mut fields = BlockFields { mode: 13, ..Default::default() };
        for c in 0..3 {
            fields.values[c] = 0x8000;
        }
        let block = pack_block(&fields);
        assert_eq!(decode_block(&block, true), [[0xFC00; 3]; 16]);
        let rgb = decode_surface(4, 4, &block, true).unwrap();
        assert!(rgb.iter().all(|&v| v == f32::NEG_INFINITY));
    }

    #[test]
    fn surface_size_mismatch_is_an_error() {
        assert!(matches!(decode_surface(5, 5, &[0; 63], false), Err(Error::Truncated { .. })));
        assert!(decode_surface(5, 5, &[0; 65], false).is_err());
        assert_eq!(decode_surface(5, 5, &[0; 64], false).unwrap().len(), 75);
        assert_eq!(decode_surface(0, 0, &[], false).unwrap().len(), 0);
    }
}
