//! Float → RGBE conversion and the scanline writers (new-style RLE and flat).

use crate::decode::{MAX_RLE_LEN, MIN_RLE_LEN};
use crate::header::{self, PixelFormat, WriteHeader};
use crate::{RgbeEncodeOptions, Rounding};
use hdrcodec_core::{ColorPrimaries, Error, HdrImage, Result};

/// Below this the pixel is written as zero, as rgbe.c does (`v < 1e-32`).
const ZERO_THRESHOLD: f64 = 1e-32;
/// The largest exponent byte is 255, i.e. a binary exponent of 127.
const MAX_EXP: i32 = 127;
/// The shortest run the RLE writer encodes as a run (rgbe.c's MINRUNLENGTH).
const MIN_RUN: usize = 4;

/// NaN and negative samples become 0 (RGBE has no sign); infinity becomes the largest float,
/// which then saturates.
#[inline]
fn clean(v: f32) -> f32 {
    if v > 0.0 {
        v.min(f32::MAX)
    } else {
        0.0
    }
}

/// 2^k as an f32 for k in -126..=127.
#[inline]
fn pow2(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

/// Encodes one pixel.
///
/// `Truncate` is rgbe.c's `float2rgbe`: with `v` the largest component and `v = m · 2^e`
/// (`frexp`, `m` in [0.5, 1)), each mantissa byte is `floor(c · 2^(8 - e))` (rgbe.c computes the
/// scale as `m · 256 / v`, which is exactly that power of two) and the exponent byte `e + 128`.
/// `Nearest` rounds each mantissa to the nearest integer instead, moving to the next exponent
/// when the largest component rounds up to 256.
///
/// Both: components below 1e-32 overall give the zero pixel; NaN and negative components
/// count as 0; values of 2^127 and more saturate to mantissa 255 at exponent byte 255.
#[inline]
pub fn encode_pixel(rgb: [f32; 3], rounding: Rounding) -> [u8; 4] {
    let [r, g, b] = rgb.map(clean);
    let v = r.max(g).max(b);
    if f64::from(v) < ZERO_THRESHOLD {
        return [0; 4];
    }
    // frexp for a normal f32 (v >= 1e-32 is normal): v = m · 2^e with m in [0.5, 1).
    let mut e = ((v.to_bits() >> 23) & 0xff) as i32 - 126;
    match rounding {
        Rounding::Truncate => {
            if e > MAX_EXP {
                e = MAX_EXP;
            }
            let s = pow2(8 - e);
            // `as u8` truncates toward zero and saturates at 255 (only reached when saturating).
            [(r * s) as u8, (g * s) as u8, (b * s) as u8, (e + 128) as u8]
        }
        Rounding::Nearest => {
            let mut s = pow2(8 - e.min(MAX_EXP));
            if e <= MAX_EXP && (v * s + 0.5) >= 256.0 {
                e += 1;
                s *= 0.5;
            }
            if e > MAX_EXP {
                e = MAX_EXP;
                s = pow2(8 - MAX_EXP);
            }
            let q = |c: f32| (c * s + 0.5) as u8;
            [q(r), q(g), q(b), (e + 128) as u8]
        }
    }
}

/// Appends one channel of a scanline in new-style RLE, choosing runs and literals exactly as
/// rgbe.c's `RGBE_WriteBytes_RLE` does (so that our truncating output is byte-identical to
/// OpenImageIO's): look for the next run of at least 4 equal bytes; a short run (2-3 bytes)
/// directly before it is written as a run too; everything else as literals of up to 128.
pub(crate) fn rle_plane(data: &[u8], out: &mut Vec<u8>) {
    let n = data.len();
    let mut cur = 0;
    while cur < n {
        let mut beg = cur;
        let mut run = 0;
        let mut old_run = 0;
        while run < MIN_RUN && beg < n {
            beg += run;
            old_run = run;
            run = 1;
            if beg < n {
                let v = data[beg];
                run += data[beg + 1..n.min(beg + 127)].iter().take_while(|&&b| b == v).count();
            }
        }
        if old_run > 1 && old_run == beg - cur {
            out.push(128 + old_run as u8);
            out.push(data[cur]);
            cur = beg;
        }
        while cur < beg {
            let k = (beg - cur).min(128);
            out.push(k as u8);
            out.extend_from_slice(&data[cur..cur + k]);
            cur += k;
        }
        if run >= MIN_RUN {
            out.push(128 + run as u8);
            out.push(data[beg]);
            cur += run;
        }
    }
}

/// Writes one scanline of RGBE pixels given as four planes, flat (interleaved pixels).
///
/// Readers take a pixel (1, 1, 1, n) for an old-style repeat code and a scanline starting with
/// (2, 2, b < 128, e) for a new-style RLE marker; neither can come out of [`encode_pixel`],
/// whose largest mantissa is always at least 128 (zero pixels are all zero).
fn write_flat(planes: &[u8], n: usize, out: &mut Vec<u8>) {
    let (r, rest) = planes.split_at(n);
    let (g, rest) = rest.split_at(n);
    let (b, e) = rest.split_at(n);
    for x in 0..n {
        out.extend_from_slice(&[r[x], g[x], b[x], e[x]]);
    }
}

/// Encodes a whole image.
pub fn encode(image: &HdrImage, opts: &RgbeEncodeOptions) -> Result<Vec<u8>> {
    let (w, h) = (image.width() as usize, image.height() as usize);
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("cannot write an empty {w}x{h} image as Radiance RGBE")));
    }
    let stride = image.channels().count();
    let primaries = image.color.primaries;
    let declare = (primaries != ColorPrimaries::Bt709).then(|| primaries.chromaticities());
    let to_xyz = match opts.format {
        PixelFormat::Rgbe => None,
        PixelFormat::Xyze => {
            if let ColorPrimaries::Custom(ch) = primaries {
                if !ch.is_valid() {
                    return Err(Error::invalid("the image's custom primaries cannot be converted to XYZ"));
                }
            }
            Some(primaries.rgb_to_xyz())
        }
    };
    // Values decoded without undoing EXPOSURE still contain it: say so in the file.
    let raw = image.metadata_value("exposure_in_pixels") == Some("true");
    let factor = |t: &str| t.parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0);
    let exposure = raw.then(|| image.metadata_value("exposure").and_then(|v| factor(v.trim()))).flatten();
    let colorcorr = raw
        .then(|| {
            let v: Vec<f64> = image.metadata_value("colorcorr")?.split_ascii_whitespace().filter_map(factor).collect();
            <[f64; 3]>::try_from(v).ok()
        })
        .flatten();
    let mut out = Vec::with_capacity(w * h * 4 + 256);
    header::write(
        &WriteHeader {
            format: opts.format,
            primaries: declare,
            exposure,
            colorcorr,
            metadata: &image.metadata,
            width: w as u32,
            height: h as u32,
        },
        &mut out,
    );
    let rle = opts.rle && (MIN_RLE_LEN..=MAX_RLE_LEN).contains(&w);
    let mut planes = vec![0u8; w * 4];
    let mut xyz = Vec::new();
    for y in 0..h {
        let mut row = image.row(y as u32);
        if let Some(m) = &to_xyz {
            xyz.clear();
            xyz.extend_from_slice(row);
            crate::apply_matrix(m, &mut xyz, stride);
            row = &xyz;
        }
        fill_planes(row, stride, opts.rounding, &mut planes);
        if rle {
            out.extend_from_slice(&[2, 2, (w >> 8) as u8, (w & 0xff) as u8]);
            for c in 0..4 {
                rle_plane(&planes[c * w..(c + 1) * w], &mut out);
            }
        } else {
            write_flat(&planes, w, &mut out);
        }
    }
    Ok(out)
}

/// Converts one row of samples into four byte planes (R, G, B, E).
fn fill_planes(row: &[f32], stride: usize, rounding: Rounding, planes: &mut [u8]) {
    let n = planes.len() / 4;
    let (r, rest) = planes.split_at_mut(n);
    let (g, rest) = rest.split_at_mut(n);
    let (b, e) = rest.split_at_mut(n);
    for ((((px, r), g), b), e) in row.chunks_exact(stride).zip(r).zip(g).zip(b).zip(e) {
        let q = encode_pixel([px[0], px[1], px[2]], rounding);
        (*r, *g, *b, *e) = (q[0], q[1], q[2], q[3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rle_runs_and_literals() {
        // The encoding rules of the Radiance format (Ward, "Real Pixels", Graphics Gems II, and
        // the Radiance file-format notes): a count byte > 128 is a run of (count - 128) copies of
        // the next byte, a count of 1-128 is followed by that many literal bytes.
        let mut out = Vec::new();
        rle_plane(&[7; 10], &mut out);
        assert_eq!(out, [138, 7]);
        out.clear();
        rle_plane(&[1, 2, 3], &mut out);
        assert_eq!(out, [3, 1, 2, 3]);
        out.clear();
        rle_plane(&[5, 5, 9, 9, 9, 9, 9], &mut out);
        assert_eq!(out, [130, 5, 133, 9]);
    }

    #[test]
    fn saturates_and_zeroes() {
        assert_eq!(encode_pixel([f32::INFINITY, 0.0, 0.0], Rounding::Truncate), [255, 0, 0, 255]);
        assert_eq!(encode_pixel([f32::NAN, -1.0, 1e-33], Rounding::Nearest), [0; 4]);
        assert_eq!(encode_pixel([1.0, 0.5, 0.25], Rounding::Truncate), [128, 64, 32, 129]);
        // 0.999 rounds up to the next exponent: 128 · 2^(129-136) = 1.0.
        assert_eq!(encode_pixel([0.9999, 0.0, 0.0], Rounding::Nearest), [128, 0, 0, 129]);
    }
}
