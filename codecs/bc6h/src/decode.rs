//! The BC6H block decoder (D3D11 functional specification, "BC6H Format": decoding steps) and
//! the parallel whole-surface decoder.
use crate::modes::{Field, ANCHORS, MODES, MODE_FROM_BITS, PARTITIONS, WEIGHTS3, WEIGHTS4};
use half::f16;
use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
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
fn unquantize<const SIGNED: bool>(v: i32, bits: u32) -> i32 {
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
    if signed {
        decode_block_impl::<true>(block)
    } else {
        decode_block_impl::<false>(block)
    }
}

#[inline(always)]
fn decode_block_impl<const SIGNED: bool>(block: &[u8; 16]) -> [[u16; 3]; 16] {
    let bits = u128::from_le_bytes(*block);
    let Some(mode) = MODE_FROM_BITS[(bits & 31) as usize] else {
        return [[0; 3]; 16];
    };
    let info = &MODES[mode as usize];

    // Gather the header fields (the layout runs of the spec's endpoint table).
    let mut f = [0i32; 13];
    let mut pos = info.mode_bits as u32;
    for run in info.layout {
        let n = run.len();
        let v = ((bits >> pos) as u32) & ((1u32 << n) - 1);
        if run.reversed() {
            f[run.field as usize] |= ((v.reverse_bits() >> (32 - n)) << run.last) as i32;
        } else {
            f[run.field as usize] |= (v << run.first) as i32;
        }
        pos += n;
    }

    // Endpoints: sign extension, inverse transform, unquantize.
    let ep = info.endpoint_bits as u32;
    let ends = info.regions as usize * 2;
    let mut e = [[0i32; 3]; 4];
    for c in 0..3 {
        let db = info.delta_bits[c] as u32;
        let w = if SIGNED { sign_extend(f[c], ep) } else { f[c] };
        e[0][c] = unquantize::<SIGNED>(w, ep);
        for (k, ek) in e.iter_mut().enumerate().take(ends).skip(1) {
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
            ek[c] = unquantize::<SIGNED>(v, ep);
        }
    }

    // Texel weights and regions.
    let idx = bits >> pos;
    let mut weight = [0i32; 16];
    let mut region = [0usize; 16];
    if info.regions == 2 {
        let d = f[Field::D as usize] as usize;
        let anchor = ANCHORS[d] as usize;
        let shape = PARTITIONS[d];
        // Texel 0 has 2 bits, the anchor 2 bits, the rest 3 bits.
        let lo = idx as u64;
        let mut p = 0u32;
        for i in 0..16 {
            let n = if i == 0 || i == anchor { 2 } else { 3 };
            weight[i] = WEIGHTS3[((lo >> p) & ((1 << n) - 1)) as usize] as i32;
            region[i] = ((shape >> i) & 1) as usize * 2;
            p += n;
        }
    } else {
        weight[0] = WEIGHTS4[(idx & 7) as usize] as i32;
        let lo = (idx >> 3) as u64;
        for (i, w) in weight.iter_mut().enumerate().skip(1) {
            *w = WEIGHTS4[((lo >> (4 * (i - 1))) & 15) as usize] as i32;
        }
    }

    let mut out = [[0u16; 3]; 16];
    for i in 0..16 {
        let (a, b) = (&e[region[i]], &e[region[i] + 1]);
        let w = weight[i];
        for c in 0..3 {
            out[i][c] = finish::<SIGNED>((a[c] * (64 - w) + b[c] * w + 32) >> 6);
        }
    }
    out
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
    decode_surface_with(width, height, blocks, signed, true)
}

/// [`decode_surface`] on the calling thread only (for single-thread measurements and callers
/// that parallelise over surfaces themselves).
pub fn decode_surface_single_thread(width: u32, height: u32, blocks: &[u8], signed: bool) -> Result<Vec<f32>> {
    decode_surface_with(width, height, blocks, signed, false)
}

fn decode_surface_with(width: u32, height: u32, blocks: &[u8], signed: bool, parallel: bool) -> Result<Vec<f32>> {
    let need = surface_bytes(width, height).ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    if blocks.len() != need {
        let what = format!("BC6H data: {} bytes for a {width}x{height} surface that needs {need}", blocks.len());
        return Err(if blocks.len() < need { Error::truncated(what) } else { Error::invalid(what) });
    }
    let samples = (width as usize)
        .checked_mul(height as usize)
        .and_then(|n| n.checked_mul(3))
        .ok_or_else(|| Error::invalid("BC6H surface size overflows"))?;
    let mut out = vec![0f32; samples];
    if samples == 0 {
        return Ok(out);
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
    Ok(out)
}

/// Decodes one row of blocks into up to 4 rows of `width` RGB texels (`out.len()` decides how
/// many rows exist).
fn decode_block_row(width: usize, row_blocks: &[u8], out: &mut [f32], signed: bool) {
    let rows = out.len() / (width * 3);
    let mut texels = [0f32; 48];
    for (bxi, blk) in row_blocks.chunks_exact(16).enumerate() {
        let blk: &[u8; 16] = blk.try_into().expect("chunks_exact(16)");
        let halves = decode_block(blk, signed);
        let flat = halves.as_flattened();
        flat.reinterpret_cast::<f16>().convert_to_f32_slice(&mut texels);
        let x0 = bxi * 4;
        let cols = (width - x0).min(4);
        for y in 0..rows {
            let dst = &mut out[(y * width + x0) * 3..(y * width + x0 + cols) * 3];
            dst.copy_from_slice(&texels[y * 12..y * 12 + cols * 3]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modes::{pack_block, BlockFields};

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
    fn surface_size_mismatch_is_an_error() {
        assert!(matches!(decode_surface(5, 5, &[0; 63], false), Err(Error::Truncated { .. })));
        assert!(decode_surface(5, 5, &[0; 65], false).is_err());
        assert_eq!(decode_surface(5, 5, &[0; 64], false).unwrap().len(), 75);
        assert_eq!(decode_surface(0, 0, &[], false).unwrap().len(), 0);
    }
}
