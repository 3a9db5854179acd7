//! Scanline decoding (new-style adaptive RLE, old-style RLE, flat) and the RGBE → float
//! conversion.

use crate::header::{self, Axis, Header, PixelFormat};
use crate::{MantissaDecode, RgbeDecodeOptions};
use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::sink::{band_rows, fill_rows, ImageSink, RowSink, Scratch};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, ImageInfo, Limits, ReadSeek, Result};

/// New-style RLE is used only for scanlines of 8 to 0x7fff pixels (Radiance's MINELEN and
/// MAXELEN); shorter or longer ones are always old-style or flat.
pub(crate) const MIN_RLE_LEN: usize = 8;
pub(crate) const MAX_RLE_LEN: usize = 0x7fff;

/// The 256 scale factors `2^(e - 136)` (index 0: the zero pixel), so that a sample is
/// `(mantissa + bias) * table[exponent]` with bias 0 (rgbe.c) or 0.5 (Radiance).
fn exponent_table() -> [f32; 256] {
    let mut t = [0.0f32; 256];
    for (e, v) in t.iter_mut().enumerate().skip(1) {
        // 2^(e-136) for e in 1..=255 spans 2^-135 .. 2^119: exact in f32 (2^-135 is subnormal
        // but a power of two, so still exact; every mantissa 0..=255 times it is exact too).
        *v = (2.0f64).powi(e as i32 - 136) as f32;
    }
    t
}

/// Decodes one RGBE pixel to floats, exactly as the bulk decoder does.
pub fn decode_pixel(rgbe: [u8; 4], mantissa: MantissaDecode) -> [f32; 3] {
    if rgbe[3] == 0 {
        return [0.0; 3];
    }
    let s = (2.0f64).powi(i32::from(rgbe[3]) - 136) as f32;
    let bias = mantissa.bias();
    [(f32::from(rgbe[0]) + bias) * s, (f32::from(rgbe[1]) + bias) * s, (f32::from(rgbe[2]) + bias) * s]
}

/// Converts one scanline held as four planes (R, G, B, E; `n` bytes each, `n + SLACK` apart)
/// to interleaved RGB in `out` (`3 * n` samples), with AVX2 when [`hdrcodec_core::cpu::avx2`] allows it.
fn planes_to_f32(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
        // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2` that
        // `planes_to_f32_avx2` requires (its vector loads and stores stay inside checked slices).
        unsafe { planes_to_f32_avx2(planes, n, table, bias, out) };
        return;
    }
    planes_to_f32_impl(planes, n, table, bias, out)
}

/// The AVX2 twin of [`planes_to_f32_impl`], 8 pixels per step: the scale `2^(e-136)` is
/// built from the exponent's bits instead of looked up (the same `f32` the table holds), and
/// the three channel vectors are interleaved with one permute each and two blends per
/// output vector.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn planes_to_f32_avx2(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    let stride = n + SLACK;
    let (r, g, b, e) = (&planes[..n], &planes[stride..][..n], &planes[2 * stride..][..n], &planes[3 * stride..][..n]);
    let out = &mut out[..3 * n];
    // Exponents 1..=9 (values below 2^-126) need subnormal scales; rows without any, nearly
    // all of them, take a shorter path.
    let subnormal = e.iter().fold(false, |any, &v| any | (v.wrapping_sub(1) < 9));
    let full = n - n % 8;
    let planes = [&r[..full], &g[..full], &b[..full], &e[..full]];
    let (groups_out, tail_out) = out.split_at_mut(3 * full);
    match (subnormal, bias != 0.0) {
        (false, false) => groups_to_f32_avx2::<false, false>(planes, bias, groups_out),
        (false, true) => groups_to_f32_avx2::<false, true>(planes, bias, groups_out),
        (true, false) => groups_to_f32_avx2::<true, false>(planes, bias, groups_out),
        (true, true) => groups_to_f32_avx2::<true, true>(planes, bias, groups_out),
    }
    planes_tail_to_f32(&r[full..], &g[full..], &b[full..], &e[full..], table, bias, tail_out);
}

/// Converts whole groups of 8 pixels (the planes' lengths are multiples of 8) into `out`
/// (24 samples per group); `SUBNORMAL` handles exponents 1..=9, `CENTRED` adds `bias`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn groups_to_f32_avx2<const SUBNORMAL: bool, const CENTRED: bool>(
    [r, g, b, e]: [&[u8]; 4],
    bias: f32,
    out: &mut [f32],
) {
    use std::arch::x86_64::*;
    let bytes = |s: &[u8]| -> __m128i {
        let s: &[u8; 8] = s.try_into().expect("8 bytes");
        _mm_set_epi64x(0, i64::from_le_bytes(*s))
    };
    let vbias = _mm256_set1_ps(bias);
    let idx_r = _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5);
    let idx_g = _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2);
    let idx_b = _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7);
    let groups = r.chunks_exact(8).zip(g.chunks_exact(8)).zip(b.chunks_exact(8)).zip(e.chunks_exact(8));
    for ((((r, g), b), e), px) in groups.zip(out.chunks_exact_mut(24)) {
        let e = bytes(e);
        let bits = if SUBNORMAL {
            // 2^(e-136): exponent field e-9 from e = 10 up, the subnormal bit e+13 below, 0 at 0.
            let e = _mm256_cvtepu8_epi32(e);
            let normal = _mm256_slli_epi32::<23>(_mm256_sub_epi32(e, _mm256_set1_epi32(9)));
            let subnormal = _mm256_sllv_epi32(_mm256_set1_epi32(1), _mm256_add_epi32(e, _mm256_set1_epi32(13)));
            let small = _mm256_cmpgt_epi32(_mm256_set1_epi32(10), e);
            let bits = _mm256_blendv_epi8(normal, subnormal, small);
            _mm256_andnot_si256(_mm256_cmpeq_epi32(e, _mm256_setzero_si256()), bits)
        } else {
            // No exponent is 1..=9: the field e-9, saturating to 0 (the float 0) at e = 0.
            _mm256_slli_epi32::<23>(_mm256_cvtepu8_epi32(_mm_subs_epu8(e, _mm_set1_epi8(9))))
        };
        let scale = _mm256_castsi256_ps(bits);
        let channel = |m: &[u8], idx: __m256i| {
            let mut v = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(bytes(m)));
            if CENTRED {
                v = _mm256_add_ps(v, vbias);
            }
            _mm256_permutevar8x32_ps(_mm256_mul_ps(v, scale), idx)
        };
        let (rr, gg, bb) = (channel(r, idx_r), channel(g, idx_g), channel(b, idx_b));
        // Output k holds (r, g, b) at lanes where (k * 8 + lane) % 3 is (0, 1, 2).
        let o0 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(rr, gg), bb);
        let o1 = _mm256_blend_ps::<0b0100_1001>(_mm256_blend_ps::<0b0010_0100>(rr, gg), bb);
        let o2 = _mm256_blend_ps::<0b1001_0010>(_mm256_blend_ps::<0b0100_1001>(rr, gg), bb);
        // SAFETY: `px` is a chunk of exactly 24 floats: the three unaligned 8-float stores at
        // 0, 8 and 16 stay inside it.
        unsafe {
            _mm256_storeu_ps(px.as_mut_ptr(), o0);
            _mm256_storeu_ps(px.as_mut_ptr().add(8), o1);
            _mm256_storeu_ps(px.as_mut_ptr().add(16), o2);
        }
    }
}

/// Pixels converted per step by the portable conversion: built as one array and stored with
/// one copy.
const GROUP: usize = 8;

/// The portable conversion (and the scalar twin the AVX2 kernel is tested against).
#[inline(always)]
fn planes_to_f32_impl(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    let stride = n + SLACK;
    let (r, g, b, e) = (&planes[..n], &planes[stride..][..n], &planes[2 * stride..][..n], &planes[3 * stride..][..n]);
    let out = &mut out[..3 * n];
    let groups = r.chunks_exact(GROUP).zip(g.chunks_exact(GROUP)).zip(b.chunks_exact(GROUP)).zip(e.chunks_exact(GROUP));
    for ((((r, g), b), e), out) in groups.zip(out.chunks_exact_mut(3 * GROUP)) {
        let mut px = [0.0f32; 3 * GROUP];
        for (i, o) in px.chunks_exact_mut(3).enumerate() {
            o.copy_from_slice(&convert(r[i], g[i], b[i], e[i], table, bias));
        }
        out.copy_from_slice(&px);
    }
    let tail = n - n % GROUP;
    planes_tail_to_f32(&r[tail..], &g[tail..], &b[tail..], &e[tail..], table, bias, &mut out[3 * tail..]);
}

/// One pixel: `(mantissa + bias) * 2^(e-136)` per channel, the scale from the table.
#[inline(always)]
fn convert(r: u8, g: u8, b: u8, e: u8, table: &[f32; 256], bias: f32) -> [f32; 3] {
    let s = table[usize::from(e)];
    [(f32::from(r) + bias) * s, (f32::from(g) + bias) * s, (f32::from(b) + bias) * s]
}

/// Converts the pixels left after the whole groups, one at a time.
#[inline(always)]
fn planes_tail_to_f32(r: &[u8], g: &[u8], b: &[u8], e: &[u8], table: &[f32; 256], bias: f32, out: &mut [f32]) {
    for ((((&r, &g), &b), &e), o) in r.iter().zip(g).zip(b).zip(e).zip(out.chunks_exact_mut(3)) {
        o.copy_from_slice(&convert(r, g, b, e, table, bias));
    }
}

/// Bytes of slack after each plane: runs and literals are at most 128 bytes, so they can be
/// written with fixed-size copies (inlined vector moves instead of a `memcpy` call per run);
/// what lands past the run's end is overwritten by the next one or ignored.
const SLACK: usize = 128;

/// The portable decode writes runs and literals in blocks of this many bytes (rounded up
/// into the slack): one block covers most of them (measured on the corpus: faster than 16,
/// 32 or one 128-byte block there, where a branch picks run or literal; the AVX2 kernel
/// blends run and literal without a branch and writes 32 or `2 * CHUNK` bytes).
const CHUNK: usize = 64;

/// Decodes the four RLE channels of a scanline into `planes`, with AVX2 when
/// [`hdrcodec_core::cpu::avx2`] allows it.
///
/// Each kernel walks the bytes that follow the reader's position as a slice while a whole
/// operation is surely there, moves the reader past what it used, and leaves the rest (the
/// end of the data, bad codes) to [`read_rle_plane_checked`], which reads through the reader.
fn read_rle_planes(r: &mut ByteReader<'_>, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    if hdrcodec_core::cpu::avx2() {
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
        // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2` that
        // `read_rle_planes_avx2` requires (its vector loads and stores stay inside checked slices).
        return unsafe { read_rle_planes_avx2(r, planes, n, y) };
    }
    read_rle_planes_impl(r, planes, n, y)
}

/// The AVX2 twin of [`read_rle_planes_impl`]: the same operations, but each run or literal
/// is written as a block picked by a byte blend, so that the run/literal choice is not a
/// branch (the compiler turns the portable select into one, which the random mix of short
/// runs and literals mispredicts).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn read_rle_planes_avx2(r: &mut ByteReader<'_>, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    use std::arch::x86_64::{
        __m256i, _mm256_add_epi8, _mm256_blendv_epi8, _mm256_loadu_si256, _mm256_set1_epi8, _mm256_storeu_si256,
    };
    const BLOCK: usize = 2 * CHUNK;
    for plane in planes.chunks_exact_mut(n + SLACK) {
        // Walk the data and the plane as shrinking slices: one length check each per
        // operation instead of an overflow check and a bound check on an index.
        let start = r.peek_rest();
        let mut rest = start;
        let mut out = &mut plane[..];
        let mut left = n;
        while left > 0 {
            let Some(op) = rest.first_chunk::<{ BLOCK + 1 }>() else { break };
            // The position of the next operation is the critical path (a load, then this):
            // the step is picked from `code + 1` and 2 by one conditional move.
            let code = usize::from(op[0]);
            let is_run = code > 128;
            let step = if is_run { 2 } else { code + 1 };
            let count = if is_run { code - 128 } else { code };
            // A zero count (code 0) wraps round and leaves too.
            if count.wrapping_sub(1) >= left {
                break;
            }
            let Some(dst) = out.first_chunk_mut::<BLOCK>() else { break };
            let value = _mm256_set1_epi8(op[1] as i8);
            // Top bit set (blend picks the literal) for codes 1..=128: code + 127 wraps to
            // 0..=126 for runs.
            let literal_mask = _mm256_add_epi8(_mm256_set1_epi8(op[0] as i8), _mm256_set1_epi8(127));
            let (src, dst) = (op[1..].as_ptr(), dst.as_mut_ptr());
            // Most operations are short: one 32-byte store, and the whole 128-byte block only
            // past 32 bytes (measured on the corpus: faster than always 128 or 64, a 16-byte
            // first store, or steps of 32; a branch on the length is predicted far better than
            // one on run/literal). Written as below, the compiler keeps one branch.
            let blocks = if count > 32 { 4 } else { 1 };
            for k in 0..4 {
                if k == 1 && blocks == 1 {
                    break;
                }
                // SAFETY: `op` has BLOCK + 1 bytes, so `src` (`op[1..]`) holds BLOCK bytes and
                // these unaligned 32-byte loads stay inside it; `dst` is a BLOCK-byte slice of
                // the plane, so the unaligned stores stay inside it too.
                unsafe {
                    let literal = _mm256_loadu_si256(src.add(32 * k).cast::<__m256i>());
                    _mm256_storeu_si256(
                        dst.add(32 * k).cast::<__m256i>(),
                        _mm256_blendv_epi8(value, literal, literal_mask),
                    );
                }
            }
            rest = &rest[step..];
            out = &mut std::mem::take(&mut out)[count..];
            left -= count;
        }
        r.skip((start.len() - rest.len()) as u64, "an RLE channel")?;
        read_rle_plane_checked(r, plane, n - left, n, y)?;
    }
    Ok(())
}

/// The portable RLE decode of a scanline's four channels (and the AVX2 build's twin).
#[inline(always)]
fn read_rle_planes_impl(r: &mut ByteReader<'_>, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    for plane in planes.chunks_exact_mut(n + SLACK) {
        read_rle_plane(r, plane, n, y)?;
    }
    Ok(())
}

/// Decodes one new-style RLE channel of `n` bytes at the reader's position into `plane`, which
/// has `n + SLACK` bytes.
#[inline(always)]
fn read_rle_plane(r: &mut ByteReader<'_>, plane: &mut [u8], n: usize, y: usize) -> Result<()> {
    let mut x = 0;
    let data = r.peek_rest();
    let mut p = 0;
    // Fast path while a whole operation (at most 129 bytes) lies in `data`: one bounds
    // check per operation, the first block of a run or a literal picked by one select, a
    // second block only for longer ones. (A truly branch-free blend was measured slower.)
    // Anything odd (a bad code, the end of the data) leaves the operation to the checked
    // loop below, which reports it.
    while x < n {
        let Some(op) = data.get(p..p + 130) else { break };
        let code = op[0];
        let is_run = code > 128;
        let count = usize::from(if is_run { code - 128 } else { code });
        if count == 0 || count > n - x {
            break;
        }
        let value = op[1];
        let mask = 0u8.wrapping_sub(u8::from(is_run));
        let src: &[u8; CHUNK] = op[1..1 + CHUNK].try_into().expect("one block");
        let mut block = [0u8; CHUNK];
        for (b, &s) in block.iter_mut().zip(src) {
            *b = (s & !mask) | (value & mask);
        }
        plane[x..x + CHUNK].copy_from_slice(&block);
        if count > CHUNK {
            let dst = &mut plane[x + CHUNK..x + 2 * CHUNK];
            if is_run {
                dst.copy_from_slice(&block);
            } else {
                dst.copy_from_slice(&op[1 + CHUNK..1 + 2 * CHUNK]);
            }
        }
        p += if is_run { 2 } else { 1 + count };
        x += count;
    }
    r.skip(p as u64, "an RLE channel")?;
    read_rle_plane_checked(r, plane, x, n, y)
}

/// Finishes an RLE channel from pixel `x` at the reader's position with every read checked
/// (the end of the data, bad codes).
#[inline(always)]
fn read_rle_plane_checked(r: &mut ByteReader<'_>, plane: &mut [u8], mut x: usize, n: usize, y: usize) -> Result<()> {
    let what = format_args!("RLE scanline {y}");
    while x < n {
        let code = usize::from(r.u8(what)?);
        if code > 128 {
            let count = code - 128;
            let value = r.u8(what)?;
            if count > n - x {
                return Err(Error::invalid(format!("scanline {y}: a run of {count} overflows the {n}-pixel scanline")));
            }
            let m = count.next_multiple_of(CHUNK);
            for d in plane[x..x + m].chunks_exact_mut(CHUNK) {
                d.copy_from_slice(&[value; CHUNK]);
            }
            x += count;
        } else {
            if code == 0 {
                return Err(Error::invalid(format!("scanline {y}: zero-length literal in the RLE data")));
            }
            if code > n - x {
                return Err(Error::invalid(format!(
                    "scanline {y}: a literal of {code} bytes overflows the {n}-pixel scanline"
                )));
            }
            // Whole blocks when the data has them (the bytes past the literal land in the
            // slack or are overwritten next), else exactly the literal.
            let m = code.next_multiple_of(CHUNK);
            match r.peek_rest().get(..m) {
                Some(src) => {
                    for (d, s) in plane[x..x + m].chunks_exact_mut(CHUNK).zip(src.chunks_exact(CHUNK)) {
                        d.copy_from_slice(s);
                    }
                    r.skip(code as u64, what)?;
                }
                None => plane[x..x + code].copy_from_slice(r.bytes(code as u64, what)?),
            }
            x += code;
        }
    }
    Ok(())
}

/// Decodes a flat or old-style RLE scanline: plain RGBE pixels, where a pixel (1, 1, 1, c)
/// repeats the previous one `c << shift` times and consecutive repeat pixels shift by 8 more
/// bits each (Radiance's `oldreadcolrs`).
///
/// Like the RLE kernels it walks the bytes after the reader's position as a slice (a checked
/// read per pixel was measured 5-15% slower on flat files) and moves the reader past what it used.
fn read_old_scanline(r: &mut ByteReader<'_>, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    let what = format_args!("scanline {y}");
    let mut rest = r.peek_rest();
    let mut used = 0;
    let mut x = 0;
    let mut shift = 0u32;
    while x < n {
        let px: [u8; 4] = match rest.split_first_chunk::<4>() {
            Some((&px, tail)) => {
                rest = tail;
                used += 4;
                px
            }
            // Fewer than 4 bytes are left: the reader reads the pixel, which reports where
            // the data ends.
            None => {
                r.skip(std::mem::take(&mut used), what)?;
                r.array(what)?
            }
        };
        if px[0] == 1 && px[1] == 1 && px[2] == 1 {
            if x == 0 {
                return Err(Error::invalid(format!("scanline {y}: a repeat code with no pixel before it")));
            }
            if shift > 24 {
                return Err(Error::invalid(format!("scanline {y}: too many consecutive repeat codes")));
            }
            let count = (u64::from(px[3]) << shift) as usize;
            if count > n - x {
                return Err(Error::invalid(format!(
                    "scanline {y}: a repeat of {count} overflows the {n}-pixel scanline"
                )));
            }
            for c in 0..4 {
                let plane = &mut planes[c * (n + SLACK)..][..n];
                let v = plane[x - 1];
                plane[x..x + count].fill(v);
            }
            x += count;
            shift += 8;
        } else {
            for (c, &v) in px.iter().enumerate() {
                planes[c * (n + SLACK) + x] = v;
            }
            x += 1;
            shift = 0;
        }
    }
    r.skip(used, what)
}

/// The scanline length a new-style RLE scanline starts with (`2 2` and a 15-bit length), if
/// `rest` starts like one.
fn rle_length(rest: &[u8]) -> Option<usize> {
    match rest.first_chunk::<4>()? {
        [2, 2, hi, lo] if hi & 0x80 == 0 => Some(usize::from(*hi) << 8 | usize::from(*lo)),
        _ => None,
    }
}

/// Decodes the scanline at the reader's position into four planes of `n` bytes (R, G, B, E),
/// each followed by `SLACK` spare bytes.
fn read_scanline(r: &mut ByteReader<'_>, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    if (MIN_RLE_LEN..=MAX_RLE_LEN).contains(&n) {
        if let Some(len) = rle_length(r.peek_rest()) {
            if len != n {
                return Err(Error::invalid(format!(
                    "scanline {y}: RLE length {len} differs from the declared {n} pixels"
                )));
            }
            r.skip(4, format_args!("scanline {y}"))?;
            return read_rle_planes(r, planes, n, y);
        }
    }
    read_old_scanline(r, planes, n, y)
}

/// Where scanline `i`, element `j` lands: pixel index `base + j * step` (row-major, top row
/// first, x to the right).
fn placement(major: Axis, minor: Axis, width: usize, i: usize) -> (isize, isize) {
    // "Forward" when the file order runs with our memory order; along Y, '+' means bottom to
    // top while our rows go top to bottom.
    let forward = |a: Axis| if a.is_y { !a.increasing } else { a.increasing };
    let w = width as isize;
    let major_pos = if forward(major) { i } else { major.len as usize - 1 - i } as isize;
    let (j0, dir) = if forward(minor) { (0, 1) } else { (minor.len as isize - 1, -1) };
    if major.is_y {
        (major_pos * w + j0, dir)
    } else {
        (j0 * w + major_pos, dir * w)
    }
}

/// A reader at the first pixel byte, after checking that every scanline can take the 4 bytes
/// it takes at least whatever its encoding: refuses lying dimensions before anything of the
/// image's size is allocated.
fn pixel_reader<'a>(hdr: &Header, data: &'a [u8]) -> Result<ByteReader<'a>> {
    let r = ByteReader::le(data).at(hdr.data_start as u64);
    let (nscan, n) = (hdr.major.len, hdr.minor.len);
    r.check_remaining(u64::from(nscan), 4, format_args!("the {nscan} scanlines of {n} pixels, at least 4 bytes each"))?;
    Ok(r)
}

/// The primaries of the decoded image: `PRIMARIES`, else Radiance's standard (BT.709).
fn primaries(hdr: &Header) -> ColorPrimaries {
    match hdr.primaries {
        Some(ch) => ColorPrimaries::from_chromaticities(ch),
        None => ColorPrimaries::Bt709,
    }
}

/// Reads the header and resolution string only: see [`crate::probe`].
pub fn probe(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    probe_head(data, data.len() as u64, limits)
}

/// [`probe`] from a file (any source that reads and seeks, from its current position): reads
/// the first 4 KiB, or as much as the longest header accepted (1 MiB) if the header is longer,
/// and the first bytes of the first scanline. Same answer and the same kinds of errors as
/// [`probe`] on the file's bytes.
pub fn probe_from(input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
    use std::io::Read;
    let (at, len) = hdrcodec_core::remaining_len(input)?;
    // The header, its resolution string and the 4 bytes that say whether scanlines are coded.
    let most = (header::MAX_HEADER_BYTES as u64 + 4).min(len);
    // What is read is charged to `limits` while it is held.
    let mut read = |n: u64| -> Result<(Vec<u8>, hdrcodec_core::Allocation)> {
        let charge = limits.charge(n, "the Radiance header")?;
        input.seek(std::io::SeekFrom::Start(at))?;
        let mut head = Vec::new();
        (&mut *input).take(n).read_to_end(&mut head)?;
        Ok((head, charge))
    };
    let first = (4 << 10u64).min(most);
    let (head, charge) = read(first)?;
    // The first read is enough when it holds the whole header and the 4 bytes after it (a
    // header ending in the last 4 bytes of it would otherwise read as flat scanlines).
    let parsed = header::parse(&head);
    if first < most && !parsed.as_ref().is_ok_and(|h| h.data_start + 4 <= head.len()) {
        drop((head, charge));
        return probe_head(&read(most)?.0, len, limits);
    }
    probe_parsed(&parsed?, &head, len, limits)
}

/// [`probe`] of a file of `len` bytes that starts with `head`, which holds at least the header,
/// the resolution string and the first 4 bytes of the pixels when the file has them.
fn probe_head(head: &[u8], len: u64, limits: &Limits) -> Result<ImageInfo> {
    probe_parsed(&header::parse(head)?, head, len, limits)
}

/// [`probe_head`] with `head`'s header already parsed (`hdr`).
fn probe_parsed(hdr: &Header, head: &[u8], len: u64, limits: &Limits) -> Result<ImageInfo> {
    limits.check_dimensions(u64::from(hdr.width()), u64::from(hdr.height()))?;
    let r = ByteReader::le(head).at(hdr.data_start as u64);
    let (nscan, n) = (hdr.major.len, hdr.minor.len);
    // As `pixel_reader` checks it, against the whole file's length.
    let need = u64::from(nscan) * 4;
    if need > len.saturating_sub(hdr.data_start as u64) {
        return Err(Error::truncated(format!(
            "the {nscan} scanlines of {n} pixels, at least 4 bytes each (bytes {}..{} of a {len}-byte input)",
            hdr.data_start,
            hdr.data_start as u64 + need
        )));
    }
    // The first scanline says how the pixels are stored (files use one encoding throughout).
    let n = hdr.minor.len as usize;
    let rle = (MIN_RLE_LEN..=MAX_RLE_LEN).contains(&n) && rle_length(r.peek_rest()).is_some();
    let name = match hdr.format {
        PixelFormat::Rgbe => "RGBE",
        PixelFormat::Xyze => "XYZE",
    };
    let format = format!("{name}, {}", if rle { "run-length scanlines" } else { "flat scanlines" });
    let color = ColorInfo { primaries: primaries(hdr), ..ColorInfo::default() };
    Ok(ImageInfo::new(hdr.width(), hdr.height(), Channels::Rgb, color).with_format(format))
}

/// Decodes a whole file.
pub fn decode(data: &[u8], limits: &Limits, opts: &RgbeDecodeOptions) -> Result<HdrImage> {
    let mut sink = ImageSink::new(limits);
    decode_rows(data, limits, opts, &mut sink)?;
    sink.finish()
}

/// Decodes a whole file into `sink`, one band of scanlines at a time (in place when the sink
/// allows it). Files whose scanlines are not rows top to bottom (a rotated or flipped
/// resolution string, which few writers produce) are assembled whole first.
pub fn decode_rows(data: &[u8], limits: &Limits, opts: &RgbeDecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    let hdr = header::parse(data)?;
    let info = image_info(&hdr, probe(data, limits)?, opts);
    let (width, height) = (hdr.width() as usize, hdr.height() as usize);
    let nscan = hdr.major.len as usize;
    let n = hdr.minor.len as usize;
    let _buffers = limits.charge((n as u64 + SLACK as u64) * 4, "the RGBE scanline buffers")?;
    let mut planes = vec![0u8; (n + SLACK) * 4];
    let table = exponent_table();
    let bias = opts.mantissa.bias();
    let mut r = pixel_reader(&hdr, data)?;
    let finish = finishing(&hdr, opts);
    sink.start(&info)?;
    let row_len = width * 3;
    if is_standard(&hdr) {
        // Rows in file order: each scanline converted straight into its row.
        let band = band_rows(row_len, 1 << 20).min(height as u32);
        let mut scratch = Scratch::new(limits);
        let mut y = 0;
        while (y as usize) < nscan {
            let rows = band.min((nscan - y as usize) as u32);
            fill_rows(sink, y, rows, row_len, &mut scratch, |out| {
                for (i, row) in out.chunks_exact_mut(row_len).enumerate() {
                    read_scanline(&mut r, &mut planes, n, y as usize + i)?;
                    planes_to_f32(&planes, n, &table, bias, row);
                }
                finish(out);
                Ok(())
            })?;
            y += rows;
        }
        return Ok(());
    }
    let _image = limits.charge((width * height * 3 * 4) as u64, "the reoriented RGBE image")?;
    let mut samples = vec![0.0f32; width * height * 3];
    let mut scratch = vec![0.0f32; n * 3];
    for i in 0..nscan {
        read_scanline(&mut r, &mut planes, n, i)?;
        planes_to_f32(&planes, n, &table, bias, &mut scratch);
        let (base, step) = placement(hdr.major, hdr.minor, width, i);
        for (j, px) in scratch.chunks_exact(3).enumerate() {
            let k = (base + j as isize * step) as usize * 3;
            samples[k..k + 3].copy_from_slice(px);
        }
    }
    finish(&mut samples);
    sink.put_rows(0, &samples)
}

/// True when the scanlines are the rows of the image top to bottom, each left to right
/// (`-Y height +X width`, what nearly every file says).
fn is_standard(hdr: &Header) -> bool {
    hdr.major.is_y && !hdr.major.increasing && !hdr.minor.is_y && hdr.minor.increasing
}

/// The conversion every decoded sample goes through after RGBE → float: XYZ → RGB for XYZE
/// files, and EXPOSURE/COLORCORR divided out when the options say so.
fn finishing(hdr: &Header, opts: &RgbeDecodeOptions) -> impl Fn(&mut [f32]) {
    let xyz_to_rgb = (hdr.format == PixelFormat::Xyze).then(|| primaries(hdr).xyz_to_rgb());
    let factors = [0, 1, 2].map(|c| hdr.exposure * hdr.colorcorr[c]);
    // EXPOSURE and COLORCORR record multipliers already applied to the values: divide them out
    // to get the original radiances (what Radiance's `pvalue -o` does).
    let inverse = (opts.apply_exposure && factors != [1.0; 3]).then(|| factors.map(|f| (1.0 / f) as f32));
    move |samples: &mut [f32]| {
        if let Some(m) = &xyz_to_rgb {
            // The header parser accepted only valid PRIMARIES, so this is a true inverse.
            crate::apply_matrix(m, samples, 3);
        }
        if let Some(inv) = inverse {
            for px in samples.chunks_exact_mut(3) {
                for (v, f) in px.iter_mut().zip(inv) {
                    *v *= f;
                }
            }
        }
    }
}

/// What the decoded image says besides its pixels: the header's metadata, and how the file
/// stored them when that is not the usual.
fn image_info(hdr: &Header, mut info: ImageInfo, opts: &RgbeDecodeOptions) -> ImageInfo {
    info.metadata = hdr.metadata.clone();
    if hdr.format == PixelFormat::Xyze {
        info = info.with_metadata("format", PixelFormat::Xyze.format_string());
    }
    let scaled = [0, 1, 2].map(|c| hdr.exposure * hdr.colorcorr[c]) != [1.0; 3];
    if !opts.apply_exposure && scaled {
        info = info.with_metadata("exposure_in_pixels", "true");
    }
    if !is_standard(hdr) {
        let ax =
            |a: Axis| format!("{}{} {}", if a.increasing { '+' } else { '-' }, if a.is_y { 'Y' } else { 'X' }, a.len);
        info = info.with_metadata("orientation", format!("{} {}", ax(hdr.major), ax(hdr.minor)));
    }
    info
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use hdrcodec_core::cpu::{self, CpuLevel};

    #[test]
    fn probe_from_reads_past_4_kib_when_the_header_ends_near_it() {
        // Headers ending so that the first scanline's 4 bytes straddle, start at or follow the
        // 4 KiB first read: probe_from must still see they are run-length coded (a fuzz find).
        let line = [2, 2, 0, 8, 136, 1, 136, 2, 8, 1, 2, 3, 4, 5, 6, 7, 8, 136, 4];
        for end in 4086..4102 {
            let tail = b"\n\n-Y 1 +X 8\n";
            let pad = end - b"#?RGBE\n#".len() - tail.len();
            let file = [b"#?RGBE\n#".as_slice(), &vec![b'x'; pad], tail, &line].concat();
            assert_eq!(header::parse(&file).unwrap().data_start, end);
            let limits = Limits::default();
            let from = probe_from(&mut std::io::Cursor::new(&file), &limits).unwrap();
            assert_eq!(from, probe(&file, &limits).unwrap(), "header of {end} bytes");
            assert_eq!(from.format, "RGBE, run-length scanlines", "header of {end} bytes");
        }
    }

    #[test]
    fn every_cut_of_the_pixels_is_truncated_and_names_the_scanline() {
        // Flat (3 pixels: never RLE) then old-style with a repeat, and new-style RLE scanlines;
        // with the bytes of the first scanline.
        let flat = [b"#?RGBE\n\n-Y 2 +X 3\n".as_slice(), &[9; 12], &[1, 2, 3, 140, 1, 1, 1, 2]].concat();
        let line = [2, 2, 0, 8, 136, 1, 136, 2, 8, 1, 2, 3, 4, 5, 6, 7, 8, 136, 4];
        let rle = [b"#?RGBE\n\n-Y 2 +X 8\n".as_slice(), &line, &line].concat();
        for (data, first) in [(flat, 12), (rle, line.len())] {
            let opts = RgbeDecodeOptions::default();
            let start = header::parse(&data).unwrap().data_start;
            let img = decode(&data, &Limits::default(), &opts).unwrap();
            assert_eq!(img.height(), 2);
            // (Fewer than 8 bytes fail the check that every scanline has at least 4.)
            for cut in start + 8..data.len() {
                let e = decode(&data[..cut], &Limits::default(), &opts).unwrap_err();
                let scanline = if cut - start < first { "scanline 0" } else { "scanline 1" };
                assert!(matches!(e, Error::Truncated { .. }) && e.to_string().contains(scanline), "cut at {cut}: {e}");
                assert!(e.to_string().contains(&format!("of a {cut}-byte input")), "cut at {cut}: {e}");
            }
        }
    }

    #[test]
    fn table_is_exact_powers_of_two() {
        let t = exponent_table();
        assert_eq!(t[0], 0.0);
        assert_eq!(t[136], 1.0);
        assert_eq!(t[128 + 1], 1.0 / 128.0);
        assert_eq!(t[1], f32::from_bits(1 << 14)); // 2^-135 = 2^14 * 2^-149, the subnormal unit
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_rle_decode_matches_the_portable_twin() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_rle_decode_matches_the_portable_twin") {
            return;
        }
        let mut next = crate::test_rng(0x2545_F491_4F6C_DD1Du64);
        for n in [8usize, 100, 1024] {
            // Four channels of random runs (1..=127) and literals (1..=128), then the same
            // data cut short and with one byte corrupted, so the error paths are compared too.
            let mut data = Vec::new();
            for _ in 0..4 {
                let mut x = 0;
                while x < n {
                    let left = n - x;
                    let count = (next() as usize % 128 + 1).min(left);
                    if next().is_multiple_of(2) && count < 128 {
                        data.extend([128 + count as u8, next() as u8]);
                    } else {
                        data.push(count as u8);
                        data.extend((0..count).map(|_| next() as u8));
                    }
                    x += count;
                }
            }
            let mut corrupt = data.clone();
            let k = next() as usize % corrupt.len();
            corrupt[k] = 0;
            for input in [&data[..], &data[..data.len() / 2], &corrupt[..]] {
                let (mut a, mut b) = (vec![0u8; (n + SLACK) * 4], vec![1u8; (n + SLACK) * 4]);
                let (mut pa, mut pb) = (ByteReader::le(input), ByteReader::le(input));
                let ra = read_rle_planes_impl(&mut pa, &mut a, n, 0);
                // SAFETY: `twin_test_can_run` above found AVX2 (with FMA and F16C) in the hardware.
                let rb = unsafe { read_rle_planes_avx2(&mut pb, &mut b, n, 0) };
                assert_eq!(ra.as_ref().map_err(|e| e.to_string()), rb.as_ref().map_err(|e| e.to_string()));
                if ra.is_ok() {
                    assert_eq!(pa.position(), pb.position());
                    for c in 0..4 {
                        let plane = c * (n + SLACK)..c * (n + SLACK) + n;
                        assert_eq!(a[plane.clone()], b[plane], "n = {n}, channel {c}");
                    }
                }
            }
            // The valid data decodes whole.
            let mut planes = vec![0u8; (n + SLACK) * 4];
            let mut r = ByteReader::le(&data);
            read_rle_planes(&mut r, &mut planes, n, 0).unwrap();
            assert_eq!(r.remaining(), 0);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_conversion_matches_the_portable_twin() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_conversion_matches_the_portable_twin") {
            return;
        }
        let table = exponent_table();
        let mut next = crate::test_rng(0x9E37_79B9_7F4A_7C15u64);
        // Odd widths leave a tail after the 8-pixel vector steps; n = 256 also gets every
        // exponent 0..=255 (zero, the subnormal scales below 10, the normal ones) with
        // mantissas 0 and 255 besides random ones. Each row once as drawn (the kernel's path
        // for rows with subnormal scales) and once with exponents 1..=9 moved to 0 or 10 (its
        // shorter path for the other rows).
        for (n, subnormal) in [1usize, 7, 8, 9, 100, 256, 1023].into_iter().flat_map(|n| [(n, true), (n, false)]) {
            let mut planes: Vec<u8> = (0..(n + SLACK) * 4).map(|_| next() as u8).collect();
            if n == 256 {
                for x in 0..n {
                    planes[3 * (n + SLACK) + x] = x as u8;
                    planes[x] = if x % 2 == 0 { 255 } else { 0 };
                }
            }
            if !subnormal {
                for (x, v) in planes[3 * (n + SLACK)..][..n].iter_mut().enumerate() {
                    if (1..10).contains(v) {
                        *v = if x % 2 == 0 { 0 } else { 10 };
                    }
                }
            }
            for bias in [0.0, 0.5] {
                // Both write exactly 3n samples and leave what follows alone.
                let (mut a, mut b) = (vec![7.0f32; n * 3 + 1], vec![7.0f32; n * 3 + 1]);
                planes_to_f32_impl(&planes, n, &table, bias, &mut a);
                // SAFETY: `twin_test_can_run` above found AVX2 (with FMA and F16C) in the hardware.
                unsafe { planes_to_f32_avx2(&planes, n, &table, bias, &mut b) };
                assert_eq!((a[n * 3], b[n * 3]), (7.0, 7.0));
                assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()), "n = {n}, bias = {bias}");
                // And the portable one is the per-pixel definition.
                for (x, px) in a[..n * 3].chunks_exact(3).enumerate() {
                    let rgbe = [0, 1, 2, 3].map(|c| planes[c * (n + SLACK) + x]);
                    let mode = if bias == 0.0 { MantissaDecode::Truncated } else { MantissaDecode::Centred };
                    assert_eq!(px, decode_pixel(rgbe, mode), "n = {n}, x = {x}");
                }
            }
        }
    }
}
