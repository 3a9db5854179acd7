//! Float → RGBE conversion and the scanline writers (new-style RLE and flat).
//!
//! Each scanline is converted into four byte planes (R, G, B, E), which the RLE writer
//! ([`rle`]) compresses one by one. On x86-64 with AVX2 (detected at run time) the conversion
//! and the RLE writer's equality masks are intrinsic kernels, each tested against the portable
//! code.

mod rle;

use crate::decode::{MAX_RLE_LEN, MIN_RLE_LEN};
use crate::header::{self, PixelFormat, WriteHeader};
use crate::{RgbeEncodeOptions, Rounding};
use hdrcodec_core::{
    Channels, ColorPrimaries, EncodeReport, Error, HdrImage, ImageInfo, Mat3, RangeCount, Result, RowCounter,
    RowEncoder, WriteSeek,
};

/// Below this the pixel is written as zero, as rgbe.c does (`v < 1e-32`).
const ZERO_THRESHOLD: f64 = 1e-32;
/// The largest exponent byte is 255, i.e. a binary exponent of 127.
const MAX_EXP: i32 = 127;
/// The bits of the smallest `f32` that is not below [`ZERO_THRESHOLD`] (for `v >= 0`,
/// `f64::from(v) < 1e-32` exactly when `v.to_bits() < ZERO_BITS`).
const ZERO_BITS: u32 = {
    let t = ZERO_THRESHOLD as f32;
    if (t as f64) < ZERO_THRESHOLD {
        t.to_bits() + 1
    } else if (f32::from_bits(t.to_bits() - 1) as f64) >= ZERO_THRESHOLD {
        t.to_bits() - 1
    } else {
        t.to_bits()
    }
};

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

/// The largest value an RGBE component holds: mantissa 255 at exponent byte 255,
/// 255 · 2^(127 - 8) ≈ 1.69e38 (with the truncating decode).
pub const RGBE_MAX: f32 = 255.0 * (1u128 << 119) as f32;

/// Writes one scanline of RGBE pixels given as four planes (`stride` bytes apart), flat
/// (interleaved pixels).
///
/// Readers take a pixel (1, 1, 1, n) for an old-style repeat code and a scanline starting with
/// (2, 2, b < 128, e) for a new-style RLE marker; neither can come out of [`encode_pixel`],
/// whose largest mantissa is always at least 128 (zero pixels are all zero).
fn write_flat(planes: &[u8], n: usize, stride: usize, out: &mut Vec<u8>) {
    let [r, g, b, e] = [0, 1, 2, 3].map(|c| &planes[c * stride..][..n]);
    out.reserve(n * 4);
    for x in 0..n {
        out.extend_from_slice(&[r[x], g[x], b[x], e[x]]);
    }
}

/// Encodes a whole image.
pub fn encode(image: &HdrImage, opts: &RgbeEncodeOptions) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(image.pixel_count() * 4 + 256);
    write(image, opts, &mut out)?;
    Ok(out)
}

/// Bytes of scanlines gathered before they are written out.
const WRITE_BAND: usize = 1 << 20;

/// [`encode`] streamed into `sink` in bands of scanlines of about 1 MB: nothing of the file's
/// size is held.
pub fn write(image: &HdrImage, opts: &RgbeEncodeOptions, sink: &mut dyn std::io::Write) -> Result<()> {
    let mut writer = RgbeWriter::new(&ImageInfo::of(image), opts)?;
    writer.write_rows(image.samples(), sink)?;
    writer.finish(sink).map(drop)
}

/// The scanline writer: the header, then rows as they come, top to bottom, gathered into bands
/// of about 1 MB of encoded bytes before they go to the sink. Serves whole
/// images ([`write`]) and conversions that never hold the image ([`RgbeCodec`]'s row encoder).
///
/// [`RgbeCodec`]: crate::RgbeCodec
pub(crate) struct RgbeWriter {
    opts: RgbeEncodeOptions,
    width: usize,
    channels: Channels,
    stride: usize,
    rows: RowCounter,
    /// RGB → XYZ, for XYZE files.
    to_xyz: Option<Mat3>,
    /// The primaries were unspecified (written as Radiance's standard ones).
    unlabelled: bool,
    rle: bool,
    pstride: usize,
    planes: Vec<u8>,
    eq: Vec<u64>,
    line_bound: usize,
    xyz: Vec<f32>,
    out: Vec<u8>,
    /// Stored components outside what RGBE holds, for the report.
    outside: RangeCount,
}

impl RgbeWriter {
    /// Checks the image `info` describes and writes the header into the first band.
    pub(crate) fn new(info: &ImageInfo, opts: &RgbeEncodeOptions) -> Result<Self> {
        let (w, h) = (info.width as usize, info.height as usize);
        if w == 0 || h == 0 {
            return Err(Error::invalid(format!("cannot write an empty {w}x{h} image as Radiance RGBE")));
        }
        let stride = info.channels.count();
        let primaries = info.color.primaries;
        // Without a PRIMARIES line a Radiance file means the standard primaries (BT.709/sRGB): unspecified
        // samples are written that way too, as no line can say "unknown".
        let declare = (!matches!(primaries, ColorPrimaries::Bt709 | ColorPrimaries::Unspecified))
            .then(|| primaries.chromaticities());
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
        let raw = info.metadata_value("exposure_in_pixels") == Some("true");
        let factor = |t: &str| t.parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0);
        let exposure = raw.then(|| info.metadata_value("exposure").and_then(|v| factor(v.trim()))).flatten();
        let colorcorr = raw
            .then(|| {
                let v: Vec<f64> =
                    info.metadata_value("colorcorr")?.split_ascii_whitespace().filter_map(factor).collect();
                <[f64; 3]>::try_from(v).ok()
            })
            .flatten();
        let mut out = Vec::with_capacity(WRITE_BAND + 4 * w + 256);
        header::write(
            &WriteHeader {
                format: opts.format,
                primaries: declare,
                exposure,
                colorcorr,
                metadata: &info.metadata,
                width: w as u32,
                height: h as u32,
            },
            &mut out,
        );
        let rle = opts.rle && (MIN_RLE_LEN..=MAX_RLE_LEN).contains(&w);
        // Four planes with room for the RLE writer's fixed-size reads past their ends, and the
        // writer's masks. Each RLE scanline is written in place: the output grows by the
        // scanline's worst case (reserved once for all), is written with plain indexing, and is
        // cut back to what was written.
        let pstride = w + rle::PAD;
        Ok(RgbeWriter {
            opts: *opts,
            width: w,
            channels: info.channels,
            stride,
            rows: RowCounter::new(w * stride, info.height),
            to_xyz,
            unlabelled: !primaries.is_specified(),
            rle,
            pstride,
            planes: vec![0u8; 4 * pstride],
            eq: vec![0u64; rle::mask_words(w)],
            line_bound: 4 + 4 * rle::plane_bound(w),
            xyz: Vec::new(),
            out,
            outside: RangeCount::default(),
        })
    }

    /// Encodes the next rows (whole rows, in the layout the header described).
    pub(crate) fn write_rows(&mut self, samples: &[f32], sink: &mut dyn std::io::Write) -> Result<()> {
        self.rows.take(samples)?;
        let (w, stride) = (self.width, self.stride);
        for row in samples.chunks_exact(w * stride) {
            let mut row = row;
            if let Some(m) = &self.to_xyz {
                self.xyz.clear();
                self.xyz.extend_from_slice(row);
                crate::apply_matrix(m, &mut self.xyz, stride);
                row = &self.xyz;
            }
            // Counted on the stored components: R, G, B, or X, Y, Z. Alpha is not stored.
            self.outside.add(row, self.channels, 0.0, RGBE_MAX, false);
            fill_planes(row, stride, self.opts.rounding, &mut self.planes, w, self.pstride);
            if self.rle {
                let start = self.out.len();
                self.out.resize(start + self.line_bound + rle::PAD, 0);
                let line = &mut self.out[start..];
                line[..4].copy_from_slice(&[2, 2, (w >> 8) as u8, (w & 0xff) as u8]);
                let mut o = 4;
                for plane in self.planes.chunks_exact(self.pstride) {
                    o = rle::write_channel(plane, w, &mut self.eq, line, o);
                }
                self.out.truncate(start + o);
            } else {
                write_flat(&self.planes, w, self.pstride, &mut self.out);
            }
            if self.out.len() >= WRITE_BAND {
                sink.write_all(&self.out)?;
                self.out.clear();
            }
        }
        Ok(())
    }

    /// Writes the last band once every row has come, and reports what RGBE could not hold:
    /// negative samples and NaN become 0 (RGBE has no sign), values above [`RGBE_MAX`] (+∞
    /// included) saturate to it; unspecified primaries are written as Radiance's standard ones.
    pub(crate) fn finish(self, sink: &mut dyn std::io::Write) -> Result<EncodeReport> {
        self.rows.check_complete()?;
        sink.write_all(&self.out)?;
        let mut report = EncodeReport::new();
        if self.unlabelled {
            // Without a PRIMARIES line Radiance means its standard primaries; no line says "unknown".
            report.note("the input records no primaries: Radiance stores them as its standard (BT.709) primaries (--opt primaries=NAME labels them)");
        }
        let (name, neg) = match self.opts.format {
            PixelFormat::Rgbe => ("Radiance RGBE", "0 (RGBE has no sign)"),
            PixelFormat::Xyze => ("Radiance XYZE", "0 (XYZE has no sign)"),
        };
        if let Some(note) = self.outside.describe(name, 0.0, RGBE_MAX, neg, &format!("{RGBE_MAX:e}"), "0") {
            report.note(note);
        }
        Ok(report)
    }
}

impl RowEncoder for RgbeWriter {
    fn write_rows(&mut self, samples: &[f32], out: &mut dyn WriteSeek) -> Result<()> {
        RgbeWriter::write_rows(self, samples, out)
    }
    fn finish(self: Box<Self>, out: &mut dyn WriteSeek) -> Result<EncodeReport> {
        RgbeWriter::finish(*self, out)
    }
}

/// Converts one row of `n` pixels (`stride` samples each) into four byte planes (R, G, B, E)
/// starting `pstride` bytes apart in `planes`, with AVX2 when [`hdrcodec_core::cpu::avx2`]
/// allows it.
fn fill_planes(row: &[f32], stride: usize, rounding: Rounding, planes: &mut [u8], n: usize, pstride: usize) {
    let (r, rest) = planes.split_at_mut(pstride);
    let (g, rest) = rest.split_at_mut(pstride);
    let (b, e) = rest.split_at_mut(pstride);
    let planes = [&mut r[..n], &mut g[..n], &mut b[..n], &mut e[..n]];
    let row = &row[..n * stride];
    #[cfg(target_arch = "x86_64")]
    if (stride == 3 || stride == 4) && hdrcodec_core::cpu::avx2() {
        let nearest = rounding == Rounding::Nearest;
        // SAFETY: `cpu::avx2()` is true only when the CPU has AVX2, FMA and F16C (detected
        // once; `HDRCODEC_CPU` can only lower the level), which covers the `avx2` that
        // `fill_planes_avx2` requires (its loads and stores stay inside checked arrays).
        unsafe {
            match (stride, nearest) {
                (3, false) => fill_planes_avx2::<3, false>(row, planes),
                (3, true) => fill_planes_avx2::<3, true>(row, planes),
                (_, false) => fill_planes_avx2::<4, false>(row, planes),
                (_, true) => fill_planes_avx2::<4, true>(row, planes),
            }
        }
        return;
    }
    fill_planes_portable(row, stride, rounding, planes)
}

/// The portable conversion (and the twin the AVX2 kernel is tested against): [`encode_pixel`]
/// for every pixel.
fn fill_planes_portable(row: &[f32], stride: usize, rounding: Rounding, [r, g, b, e]: [&mut [u8]; 4]) {
    for ((((px, r), g), b), e) in row.chunks_exact(stride).zip(r).zip(g).zip(b).zip(e) {
        let q = encode_pixel([px[0], px[1], px[2]], rounding);
        (*r, *g, *b, *e) = (q[0], q[1], q[2], q[3]);
    }
}

/// The AVX2 twin of [`fill_planes_portable`] for `STRIDE` 3 (RGB) or 4 (RGBA) samples per
/// pixel, 16 pixels per step: the channels are gathered into vectors of 8 pixels, encoded
/// by [`encode8_avx2`], and each plane gets one 16-byte piece. The pixels after the last
/// whole step go through [`encode_pixel`].
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_planes_avx2<const STRIDE: usize, const NEAREST: bool>(row: &[f32], [r, g, b, e]: [&mut [u8]; 4]) {
    use std::arch::x86_64::*;
    const STEP: usize = 16;
    let n = r.len();
    let full = n - n % STEP;
    // Loads 8 floats from a chunk of the row.
    let load = |s: &[f32], k: usize| -> __m256 {
        let s: &[f32; 8] = s[8 * k..8 * k + 8].try_into().expect("8 floats");
        // SAFETY: `s` holds 8 floats, exactly what the unaligned load reads.
        unsafe { _mm256_loadu_ps(s.as_ptr()) }
    };
    // 8 pixels → one vector of bytes, qwords (R, G, B, E), pixels in order.
    let group = |px: &[f32]| -> __m256i {
        if STRIDE == 3 {
            // Lanes of (a0, a1, a2) hold samples 3i + c: blend each channel's lanes together
            // (in the order 0 3 6 1 4 7 2 5, rotated for G and B) and permute into order.
            let (a0, a1, a2) = (load(px, 0), load(px, 1), load(px, 2));
            let rr = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(a0, a1), a2);
            let gg = _mm256_blend_ps::<0b0100_1001>(_mm256_blend_ps::<0b0010_0100>(a0, a1), a2);
            let bb = _mm256_blend_ps::<0b1001_0010>(_mm256_blend_ps::<0b0100_1001>(a0, a1), a2);
            encode8_avx2::<NEAREST>(
                _mm256_permutevar8x32_ps(rr, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5)),
                _mm256_permutevar8x32_ps(gg, _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6)),
                _mm256_permutevar8x32_ps(bb, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7)),
            )
        } else {
            // Two RGBA pixels per load: a 4x4 transpose per 128-bit lane leaves the pixels
            // in the order 0 2 4 6 1 3 5 7 in every channel, put right in the bytes after.
            let (p0, p1, p2, p3) = (load(px, 0), load(px, 1), load(px, 2), load(px, 3));
            let (t0, t1) = (_mm256_unpacklo_ps(p0, p1), _mm256_unpackhi_ps(p0, p1));
            let (t2, t3) = (_mm256_unpacklo_ps(p2, p3), _mm256_unpackhi_ps(p2, p3));
            let lo =
                |a: __m256, b: __m256| _mm256_castpd_ps(_mm256_unpacklo_pd(_mm256_castps_pd(a), _mm256_castps_pd(b)));
            let hi =
                |a: __m256, b: __m256| _mm256_castpd_ps(_mm256_unpackhi_pd(_mm256_castps_pd(a), _mm256_castps_pd(b)));
            let bytes = encode8_avx2::<NEAREST>(lo(t0, t2), hi(t0, t2), lo(t1, t3));
            let order = _mm256_setr_epi8(
                0, 4, 1, 5, 2, 6, 3, 7, 8, 12, 9, 13, 10, 14, 11, 15, 0, 4, 1, 5, 2, 6, 3, 7, 8, 12, 9, 13, 10, 14, 11,
                15,
            );
            _mm256_shuffle_epi8(bytes, order)
        }
    };
    let steps = row[..full * STRIDE].chunks_exact(STEP * STRIDE);
    let planes = r
        .chunks_exact_mut(STEP)
        .zip(g.chunks_exact_mut(STEP))
        .zip(b.chunks_exact_mut(STEP))
        .zip(e.chunks_exact_mut(STEP));
    for (px, (((r, g), b), e)) in steps.zip(planes) {
        let (x, y) = (group(&px[..8 * STRIDE]), group(&px[8 * STRIDE..]));
        let mut bytes = [0u8; 64];
        // SAFETY: `bytes` holds 64 bytes: the two unaligned 32-byte stores at 0 and 32 stay
        // inside it.
        unsafe {
            _mm256_storeu_si256(bytes.as_mut_ptr().cast(), _mm256_unpacklo_epi64(x, y)); // R | B
            _mm256_storeu_si256(bytes.as_mut_ptr().add(32).cast(), _mm256_unpackhi_epi64(x, y));
            // G | E
        }
        r.copy_from_slice(&bytes[..16]);
        b.copy_from_slice(&bytes[16..32]);
        g.copy_from_slice(&bytes[32..48]);
        e.copy_from_slice(&bytes[48..]);
    }
    let rounding = if NEAREST { Rounding::Nearest } else { Rounding::Truncate };
    for x in full..n {
        let px = &row[x * STRIDE..];
        [r[x], g[x], b[x], e[x]] = encode_pixel([px[0], px[1], px[2]], rounding);
    }
}

/// [`encode_pixel`] for 8 pixels given as channel vectors, returning the bytes as the qwords
/// (R, G, B, E). The exponent is read from the bits of the largest component (clamped to
/// the largest that RGBE holds) and the mantissa scale `2^(8-e)` built from it; the same
/// float operations as the scalar code in the same order, so the same bytes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn encode8_avx2<const NEAREST: bool>(
    r: std::arch::x86_64::__m256,
    g: std::arch::x86_64::__m256,
    b: std::arch::x86_64::__m256,
) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    // [`clean`]: `max` gives its second operand for NaN (and +0 for -0), `min` maps +inf.
    let clean = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(f32::MAX));
    let (r, g, b) = (clean(r), clean(g), clean(b));
    let v = _mm256_max_ps(_mm256_max_ps(r, g), b);
    let bits = _mm256_castps_si256(v);
    // All ones for pixels that are not written as zero (v >= 0, so the bits compare as ints).
    let nonzero = _mm256_cmpgt_epi32(bits, _mm256_set1_epi32(ZERO_BITS as i32 - 1));
    // The biased exponent, so frexp's e = biased - 126, clamped to e <= MAX_EXP.
    let max_biased = _mm256_set1_epi32(MAX_EXP + 126);
    let mut biased = _mm256_min_epi32(_mm256_srli_epi32::<23>(bits), max_biased);
    // 2^(8 - e) has the biased exponent 8 - e + 127 = 261 - biased; 0 for zero pixels.
    let mut scale =
        _mm256_and_si256(_mm256_slli_epi32::<23>(_mm256_sub_epi32(_mm256_set1_epi32(261), biased)), nonzero);
    let half = _mm256_set1_ps(0.5);
    if NEAREST {
        // The largest component rounds up to 256: next exponent, half the scale (not past
        // MAX_EXP, where the scalar code moves up and back again).
        let top = _mm256_add_ps(_mm256_mul_ps(v, _mm256_castsi256_ps(scale)), half);
        let up = _mm256_and_si256(
            _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(top, _mm256_set1_ps(256.0))),
            _mm256_cmpgt_epi32(max_biased, biased),
        );
        biased = _mm256_sub_epi32(biased, up);
        scale = _mm256_sub_epi32(scale, _mm256_and_si256(up, _mm256_set1_epi32(1 << 23)));
    }
    let scale = _mm256_castsi256_ps(scale);
    // Truncation toward zero as `as u8` does; the packs saturate 256..511 to 255 as it does.
    let mantissa = |c: __m256| {
        let x = _mm256_mul_ps(c, scale);
        _mm256_cvttps_epi32(if NEAREST { _mm256_add_ps(x, half) } else { x })
    };
    // e + 128 = biased + 2.
    let exponent = _mm256_and_si256(_mm256_add_epi32(biased, _mm256_set1_epi32(2)), nonzero);
    let rg = _mm256_packus_epi32(mantissa(r), mantissa(g));
    let be = _mm256_packus_epi32(mantissa(b), exponent);
    // Per 128-bit lane the dwords are (R, G, B, E) of 4 pixels: gather the two lanes' halves.
    _mm256_permutevar8x32_epi32(_mm256_packus_epi16(rg, be), _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7))
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(target_arch = "x86_64")]
    use hdrcodec_core::cpu::{self, CpuLevel};

    #[test]
    fn rgbe_max_is_the_saturated_pixel() {
        // Mantissa 255 at exponent byte 255, decoded by truncation: 255 · 2^(255 - 136).
        assert_eq!(encode_pixel([RGBE_MAX, 0.0, 0.0], Rounding::Truncate), [255, 0, 0, 255]);
        assert_eq!(encode_pixel([f32::MAX, 0.0, 0.0], Rounding::Nearest), [255, 0, 0, 255]);
        assert_eq!(f64::from(RGBE_MAX), 255.0 * 2f64.powi(119));
    }

    #[test]
    fn saturates_and_zeroes() {
        assert_eq!(encode_pixel([f32::INFINITY, 0.0, 0.0], Rounding::Truncate), [255, 0, 0, 255]);
        assert_eq!(encode_pixel([f32::NAN, -1.0, 1e-33], Rounding::Nearest), [0; 4]);
        assert_eq!(encode_pixel([1.0, 0.5, 0.25], Rounding::Truncate), [128, 64, 32, 129]);
        // 0.999 rounds up to the next exponent: 128 · 2^(129-136) = 1.0.
        assert_eq!(encode_pixel([0.9999, 0.0, 0.0], Rounding::Nearest), [128, 0, 0, 129]);
    }

    #[test]
    fn zero_threshold_bits() {
        // rgbe.c writes the zero pixel for v < 1e-32 (compared in double precision).
        let below = f32::from_bits(ZERO_BITS - 1);
        let at = f32::from_bits(ZERO_BITS);
        assert!(f64::from(below) < 1e-32 && f64::from(at) >= 1e-32);
        for rounding in [Rounding::Truncate, Rounding::Nearest] {
            assert_eq!(encode_pixel([below, 0.0, 0.0], rounding), [0; 4]);
            assert_ne!(encode_pixel([at, 0.0, 0.0], rounding), [0; 4]);
        }
    }

    /// Float bit patterns where the conversion can go wrong: every exponent field (zero and
    /// subnormal, the 1e-32 threshold, the normal range, the saturating top, inf and NaN)
    /// with mantissas at the ends of the field and around the round-up point
    /// (`m · 256 = 255.5`), both signs, and the neighbours of the zero threshold.
    fn interesting_floats() -> Vec<f32> {
        let mut v = Vec::new();
        for field in 0..=255u32 {
            for frac in [0, 1, 2, 0x40_0000, 0x7f_7fff, 0x7f_8000, 0x7f_8001, 0x7f_c000, 0x7f_fffe, 0x7f_ffff] {
                for sign in [0, 1u32 << 31] {
                    v.push(f32::from_bits(sign | field << 23 | frac));
                }
            }
        }
        v.extend([ZERO_BITS - 1, ZERO_BITS, ZERO_BITS + 1].map(f32::from_bits));
        v.extend([1.0, 0.5, 0.25, 0.9999, 255.5 / 256.0, 2f32.powi(127), f32::MAX, f32::MIN_POSITIVE]);
        v
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_conversion_matches_the_portable_twin() {
        if !cpu::twin_test_can_run(CpuLevel::Avx2, "avx2_conversion_matches_the_portable_twin") {
            return;
        }
        let vals = interesting_floats();
        let len = vals.len();
        // Each interesting value as each channel, with other interesting values (and copies
        // of itself, halved, a mantissa step below) beside it, then random bit patterns.
        let mut pixels: Vec<[f32; 3]> = Vec::new();
        for (i, &x) in vals.iter().enumerate() {
            let (y, z) = (vals[(i * 7 + 3) % len], vals[(i * 13 + 5) % len]);
            pixels.extend([[x, y, z], [y, x, z], [y, z, x], [x, x, x], [x, x * 0.5, x / 256.0], [x, 0.0, 0.0]]);
        }
        let mut next = crate::test_rng(0x9E37_79B9_7F4A_7C15u64);
        for _ in 0..50_000 {
            let r = next();
            pixels.push([r as u32, (r >> 32) as u32, next() as u32].map(f32::from_bits));
        }
        for (stride, rounding) in [3, 4].into_iter().flat_map(|s| [(s, Rounding::Truncate), (s, Rounding::Nearest)]) {
            let mut start = 0;
            // Rows of 1 to 40 pixels, so that most end in pixels after the 16-pixel steps.
            for n in (1..=40).cycle() {
                if start >= pixels.len() {
                    break;
                }
                let row_px = &pixels[start..pixels.len().min(start + n)];
                start += n;
                let n = row_px.len();
                let row: Vec<f32> =
                    row_px.iter().flat_map(|p| p[..].iter().copied().chain([7.5; 1]).take(stride)).collect();
                let (mut a, mut b) = (vec![1u8; 4 * n], vec![2u8; 4 * n]);
                fn split(p: &mut [u8]) -> [&mut [u8]; 4] {
                    let n = p.len() / 4;
                    let (r, rest) = p.split_at_mut(n);
                    let (g, rest) = rest.split_at_mut(n);
                    let (b, e) = rest.split_at_mut(n);
                    [r, g, b, e]
                }
                fill_planes_portable(&row, stride, rounding, split(&mut a));
                // SAFETY: `twin_test_can_run` above found AVX2 (with FMA and F16C) in the hardware.
                unsafe {
                    match (stride, rounding) {
                        (3, Rounding::Truncate) => fill_planes_avx2::<3, false>(&row, split(&mut b)),
                        (3, Rounding::Nearest) => fill_planes_avx2::<3, true>(&row, split(&mut b)),
                        (_, Rounding::Truncate) => fill_planes_avx2::<4, false>(&row, split(&mut b)),
                        (_, Rounding::Nearest) => fill_planes_avx2::<4, true>(&row, split(&mut b)),
                    }
                }
                for x in 0..n {
                    let (pa, pb) = ([0, 1, 2, 3].map(|c| a[c * n + x]), [0, 1, 2, 3].map(|c| b[c * n + x]));
                    let bits = row_px[x].map(f32::to_bits);
                    assert_eq!(pa, pb, "stride {stride}, {rounding:?}, pixel {bits:08x?}");
                }
            }
        }
    }
}
