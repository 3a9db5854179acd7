//! Scanline decoding (new-style adaptive RLE, old-style RLE, flat) and the RGBE → float
//! conversion.

use crate::header::{self, Axis, Header, PixelFormat};
use crate::{MantissaDecode, RgbeDecodeOptions};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, Limits, Result};

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
/// to interleaved RGB, with AVX2 when the CPU has it.
fn planes_to_f32(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement of
        // `planes_to_f32_avx2`; its body is the safe portable loop compiled for AVX2.
        unsafe { planes_to_f32_avx2(planes, n, table, bias, out) };
        return;
    }
    planes_to_f32_impl(planes, n, table, bias, out)
}

/// [`planes_to_f32_impl`] compiled with AVX2 (8 pixels per step instead of SSE2's 4).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn planes_to_f32_avx2(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    planes_to_f32_impl(planes, n, table, bias, out)
}

/// The portable conversion (and the twin the AVX2 build is tested against), written as a
/// plain zip so that the compiler can vectorise the arithmetic.
#[inline(always)]
fn planes_to_f32_impl(planes: &[u8], n: usize, table: &[f32; 256], bias: f32, out: &mut [f32]) {
    let stride = n + SLACK;
    let (r, g, b, e) = (&planes[..n], &planes[stride..][..n], &planes[2 * stride..][..n], &planes[3 * stride..][..n]);
    for ((((o, &r), &g), &b), &e) in out.chunks_exact_mut(3).zip(r).zip(g).zip(b).zip(e) {
        let s = table[usize::from(e)];
        o[0] = (f32::from(r) + bias) * s;
        o[1] = (f32::from(g) + bias) * s;
        o[2] = (f32::from(b) + bias) * s;
    }
}

/// Bytes of slack after each plane: runs and literals are at most 128 bytes, so they can be
/// written with fixed-size copies (inlined vector moves instead of a `memcpy` call per run);
/// what lands past the run's end is overwritten by the next one or ignored.
const SLACK: usize = 128;

/// Runs and literals are written in blocks of this many bytes (rounded up into the slack):
/// one block covers most of them (measured on the corpus: faster than 16, 32 or one 128-byte
/// block, which wastes stores on the many short runs).
const CHUNK: usize = 64;

/// Decodes the four RLE channels of a scanline into `planes`, with AVX2 when the CPU has it.
fn read_rle_planes(data: &[u8], pos: &mut usize, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement of
        // `read_rle_planes_avx2`; its body is the safe portable code compiled for AVX2.
        return unsafe { read_rle_planes_avx2(data, pos, planes, n, y) };
    }
    read_rle_planes_impl(data, pos, planes, n, y)
}

/// [`read_rle_planes_impl`] compiled with AVX2 (32-byte moves for the run and literal blocks).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn read_rle_planes_avx2(data: &[u8], pos: &mut usize, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    read_rle_planes_impl(data, pos, planes, n, y)
}

/// The portable RLE decode of a scanline's four channels (and the AVX2 build's twin).
#[inline(always)]
fn read_rle_planes_impl(data: &[u8], pos: &mut usize, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    for plane in planes.chunks_exact_mut(n + SLACK) {
        read_rle_plane(data, pos, plane, n, y)?;
    }
    Ok(())
}

/// Decodes one new-style RLE channel of `n` bytes starting at `*pos` into `plane`, which has
/// `n + SLACK` bytes.
#[inline(always)]
fn read_rle_plane(data: &[u8], pos: &mut usize, plane: &mut [u8], n: usize, y: usize) -> Result<()> {
    let mut x = 0;
    let mut p = *pos;
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
    while x < n {
        let code = usize::from(*data.get(p).ok_or_else(|| Error::truncated(format!("RLE scanline {y}")))?);
        p += 1;
        if code > 128 {
            let count = code - 128;
            let value = *data.get(p).ok_or_else(|| Error::truncated(format!("RLE scanline {y}")))?;
            p += 1;
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
            let m = code.next_multiple_of(CHUNK);
            match data.get(p..p + m) {
                Some(src) => {
                    for (d, s) in plane[x..x + m].chunks_exact_mut(CHUNK).zip(src.chunks_exact(CHUNK)) {
                        d.copy_from_slice(s);
                    }
                }
                None => {
                    let src = data.get(p..p + code).ok_or_else(|| Error::truncated(format!("RLE scanline {y}")))?;
                    plane[x..x + code].copy_from_slice(src);
                }
            }
            p += code;
            x += code;
        }
    }
    *pos = p;
    Ok(())
}

/// Decodes a flat or old-style RLE scanline: plain RGBE pixels, where a pixel (1, 1, 1, c)
/// repeats the previous one `c << shift` times and consecutive repeat pixels shift by 8 more
/// bits each (Radiance's `oldreadcolrs`).
fn read_old_scanline(data: &[u8], pos: &mut usize, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    let mut x = 0;
    let mut shift = 0u32;
    let mut p = *pos;
    while x < n {
        let px = data.get(p..p + 4).ok_or_else(|| Error::truncated(format!("scanline {y}")))?;
        p += 4;
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
    *pos = p;
    Ok(())
}

/// Decodes the scanline at `*pos` into four planes of `n` bytes (R, G, B, E), each followed
/// by `SLACK` spare bytes.
fn read_scanline(data: &[u8], pos: &mut usize, planes: &mut [u8], n: usize, y: usize) -> Result<()> {
    if (MIN_RLE_LEN..=MAX_RLE_LEN).contains(&n) {
        if let Some(h) = data.get(*pos..*pos + 4) {
            if h[0] == 2 && h[1] == 2 && h[2] & 0x80 == 0 {
                let len = usize::from(h[2]) << 8 | usize::from(h[3]);
                if len != n {
                    return Err(Error::invalid(format!(
                        "scanline {y}: RLE length {len} differs from the declared {n} pixels"
                    )));
                }
                *pos += 4;
                return read_rle_planes(data, pos, planes, n, y);
            }
        }
    }
    read_old_scanline(data, pos, planes, n, y)
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

/// Decodes a whole file.
pub fn decode(data: &[u8], limits: &Limits, opts: &RgbeDecodeOptions) -> Result<HdrImage> {
    let hdr = header::parse(data)?;
    let (width, height) = (hdr.width() as usize, hdr.height() as usize);
    limits.check_image(width as u64, height as u64, Channels::Rgb)?;
    let nscan = hdr.major.len as usize;
    let n = hdr.minor.len as usize;
    // Every scanline takes at least 4 bytes whatever its encoding: refuse lying dimensions
    // before allocating the image.
    let available = data.len() - hdr.data_start;
    if available / 4 < nscan {
        return Err(Error::truncated(format!(
            "the pixel data ({available} bytes cannot hold {nscan} scanlines of {n} pixels)"
        )));
    }
    limits.check_alloc((n as u64 + SLACK as u64) * 4 + n as u64 * 12, "the RGBE scanline buffers")?;
    let mut planes = vec![0u8; (n + SLACK) * 4];
    let table = exponent_table();
    let bias = opts.mantissa.bias();
    let mut pos = hdr.data_start;
    let standard = hdr.major.is_y && !hdr.major.increasing && !hdr.minor.is_y && hdr.minor.increasing;
    let mut samples = vec![0.0f32; width * height * 3];
    if standard {
        // Rows in file order: convert each scanline straight into its place.
        for (i, row) in samples.chunks_exact_mut(n * 3).enumerate() {
            read_scanline(data, &mut pos, &mut planes, n, i)?;
            planes_to_f32(&planes, n, &table, bias, row);
        }
    } else {
        let mut scratch = vec![0.0f32; n * 3];
        for i in 0..nscan {
            read_scanline(data, &mut pos, &mut planes, n, i)?;
            planes_to_f32(&planes, n, &table, bias, &mut scratch);
            let (base, step) = placement(hdr.major, hdr.minor, width, i);
            for (j, px) in scratch.chunks_exact(3).enumerate() {
                let k = (base + j as isize * step) as usize * 3;
                samples[k..k + 3].copy_from_slice(px);
            }
        }
    }
    finish(hdr, width as u32, height as u32, samples, opts)
}

/// Colour conversion, exposure and metadata.
fn finish(hdr: Header, width: u32, height: u32, mut samples: Vec<f32>, opts: &RgbeDecodeOptions) -> Result<HdrImage> {
    let primaries = match hdr.primaries {
        Some(ch) => ColorPrimaries::from_chromaticities(ch),
        None => ColorPrimaries::Bt709,
    };
    if hdr.format == PixelFormat::Xyze {
        // The header parser accepted only valid PRIMARIES, so this is a true inverse.
        crate::apply_matrix(&primaries.xyz_to_rgb(), &mut samples, 3);
    }
    let factors = [0, 1, 2].map(|c| hdr.exposure * hdr.colorcorr[c]);
    let scaled = factors != [1.0; 3];
    if opts.apply_exposure && scaled {
        // EXPOSURE and COLORCORR record multipliers already applied to the values: divide
        // them out to get the original radiances (what Radiance's `pvalue -o` does).
        let inv = factors.map(|f| (1.0 / f) as f32);
        for px in samples.chunks_exact_mut(3) {
            for (v, f) in px.iter_mut().zip(inv) {
                *v *= f;
            }
        }
    }
    let mut image =
        HdrImage::new(width, height, Channels::Rgb, samples, ColorInfo { primaries, ..ColorInfo::default() })?;
    image.metadata = hdr.metadata;
    if hdr.format == PixelFormat::Xyze {
        image.set_metadata("format", PixelFormat::Xyze.format_string());
    }
    if !opts.apply_exposure && scaled {
        image.set_metadata("exposure_in_pixels", "true");
    }
    let standard = hdr.major.is_y && !hdr.major.increasing && !hdr.minor.is_y && hdr.minor.increasing;
    if !standard {
        let ax =
            |a: Axis| format!("{}{} {}", if a.increasing { '+' } else { '-' }, if a.is_y { 'Y' } else { 'X' }, a.len);
        image.set_metadata("orientation", format!("{} {}", ax(hdr.major), ax(hdr.minor)));
    }
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in [8usize, 100, 1024] {
            // Four channels of random runs (1..=127) and literals (1..=128), then the same
            // data cut short and with one byte corrupted, so the error paths are compared too.
            let mut data = Vec::new();
            for _ in 0..4 {
                let mut x = 0;
                while x < n {
                    let left = n - x;
                    let count = (next() as usize % 128 + 1).min(left);
                    if next() % 2 == 0 && count < 128 {
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
                let (mut pa, mut pb) = (0, 0);
                let ra = read_rle_planes_impl(input, &mut pa, &mut a, n, 0);
                // SAFETY: AVX2 support was checked above.
                let rb = unsafe { read_rle_planes_avx2(input, &mut pb, &mut b, n, 0) };
                assert_eq!(ra.as_ref().map_err(|e| e.to_string()), rb.as_ref().map_err(|e| e.to_string()));
                if ra.is_ok() {
                    assert_eq!(pa, pb);
                    for c in 0..4 {
                        let plane = c * (n + SLACK)..c * (n + SLACK) + n;
                        assert_eq!(a[plane.clone()], b[plane], "n = {n}, channel {c}");
                    }
                }
            }
            // The valid data decodes whole.
            let mut planes = vec![0u8; (n + SLACK) * 4];
            let mut pos = 0;
            read_rle_planes(&data, &mut pos, &mut planes, n, 0).unwrap();
            assert_eq!(pos, data.len());
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_conversion_matches_the_portable_twin() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let table = exponent_table();
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        // Odd widths leave a tail after the 8-pixel vector steps.
        for n in [1usize, 7, 8, 9, 100, 1023] {
            let planes: Vec<u8> = (0..(n + SLACK) * 4)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    state as u8
                })
                .collect();
            for bias in [0.0, 0.5] {
                let (mut a, mut b) = (vec![0f32; n * 3], vec![1f32; n * 3]);
                planes_to_f32_impl(&planes, n, &table, bias, &mut a);
                // SAFETY: AVX2 support was checked above.
                unsafe { planes_to_f32_avx2(&planes, n, &table, bias, &mut b) };
                assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()), "n = {n}, bias = {bias}");
            }
        }
    }
}
