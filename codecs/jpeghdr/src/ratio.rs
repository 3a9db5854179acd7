//! Ward & Simmons' JPEG-HDR (APGV 2004, CIC 2005): a tone-mapped JFIF base and a log-encoded
//! ratio image in APP11 `HDR_RI ` segments, `HDR = linear(base) × ratio`. Decoding follows
//! the format's author's library (panlib, as `../shared/HDRJPEG-NOTES.md` section 1 reads it):
//!
//! - the ratio JPEG is the concatenation of the segments' chunks; a code `c` means the ratio
//!   `exp(ln0 + (c + 0.5) / 256 · (ln1 − ln0))`;
//! - a ratio image smaller than the base is upsampled with Catmull-Rom weights, pixel centres
//!   aligned, edges clamped; with `cor=2` it is then post-corrected from the base's luma;
//! - the base's Y'CbCr becomes R'G'B' with the JFIF matrix *without clamping* (values from
//!   about −230 to +480), linearised with the sRGB curve applied to value / 256, mirrored below
//!   zero, and resaturated with `alp` and `bet`.

use crate::gainmap::{decode_jpeg_as, Pixels};
use crate::markers::{self, JpegImage, APP11};
use hdrcodec_core::sink::{band_rows, fill_rows, RowSink, Scratch};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, Error, ImageInfo, Limits, Result, SrgbTransfer};

/// The APP11 payload signature of a JPEG-HDR segment (with its trailing space).
pub const SIGNATURE: &[u8] = b"HDR_RI ";

/// The luminance weights of JPEG-HDR's desaturation and ratio (BT.709, to four decimals, as the
/// format's reference uses them): the decoder resaturates with them, the encoder measures with
/// them.
pub(crate) const LUMA_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// The luminance of `rgb` by [`LUMA_WEIGHTS`].
pub(crate) fn luma(rgb: [f64; 3]) -> f64 {
    LUMA_WEIGHTS[0] * rgb[0] + LUMA_WEIGHTS[1] * rgb[1] + LUMA_WEIGHTS[2] * rgb[2]
}

/// How the ratio image was made (`cor`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Correction {
    /// 0: a full-resolution ratio image.
    FullResolution,
    /// 1: the base was pre-corrected for the downsampled ratio image.
    Pre,
    /// 2: the decoder post-corrects the upsampled ratio image from the base.
    Post,
}

/// The parameters of a JPEG-HDR file's first `HDR_RI` segment.
#[derive(Clone, Debug, PartialEq)]
pub struct RatioHeader {
    /// `ver`: the writing library's version × 10 (11 for 1.1).
    pub version: u32,
    /// `ln0`, `ln1`: natural logs of the smallest and largest ratio.
    pub ln_range: [f64; 2],
    /// `s2n`: cd/m² per sample unit; 0 when unknown.
    pub samples_to_nits: f64,
    /// `alp`, `bet`: the desaturation applied to the base (1, 1: none).
    pub alpha: f64,
    /// See `alpha`.
    pub beta: f64,
    /// `cor`.
    pub correction: Correction,
}

impl RatioHeader {
    /// Parses the header text (what follows `HDR_RI ` up to the `~`): `key=value` pairs in any
    /// order, separated by white space or commas, as leniently as ExifTool reads them.
    pub fn parse(text: &str) -> Result<Self> {
        let bad = |what: String| Error::invalid(format!("JPEG-HDR header: {what}"));
        let mut values = std::collections::HashMap::new();
        for token in text.split(|c: char| c.is_whitespace() || c == ',').filter(|t| !t.is_empty()) {
            if token == "~" {
                break;
            }
            let (key, value) = token.split_once('=').ok_or_else(|| bad(format!("{token:?} is not key=value")))?;
            values.insert(key, value);
        }
        let number = |key: &str| -> Result<f64> {
            let v = values.get(key).ok_or_else(|| bad(format!("no {key}")))?;
            v.parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| bad(format!("{key}={v}")))
        };
        let version = number("ver")?;
        if !(10.0..20.0).contains(&version) {
            return Err(Error::unsupported(format!("JPEG-HDR version {version} (1.x is read)")));
        }
        let ln_range = [number("ln0")?, number("ln1")?];
        if ln_range[0] >= ln_range[1] {
            return Err(bad(format!("ln0 {} is not below ln1 {}", ln_range[0], ln_range[1])));
        }
        let correction = match number("cor")? as i64 {
            0 => Correction::FullResolution,
            1 => Correction::Pre,
            2 => Correction::Post,
            c => return Err(bad(format!("cor={c}"))),
        };
        let (alpha, beta) = (number("alp")?, number("bet")?);
        if alpha <= 0.0 || beta <= 0.0 {
            return Err(bad(format!("alp={alpha} bet={beta}")));
        }
        Ok(RatioHeader {
            version: version as u32,
            ln_range,
            samples_to_nits: number("s2n")?.max(0.0),
            alpha,
            beta,
            correction,
        })
    }

    /// The ratio a code means.
    fn ratio(&self, code: f64) -> f64 {
        let [ln0, ln1] = self.ln_range;
        (ln0 + (code + 0.5) / 256.0 * (ln1 - ln0)).exp()
    }
}

/// The header and the reassembled ratio JPEG of an image's `HDR_RI` segments; `Ok(None)` if it
/// has none. Segments after the first carry `ext=N` numbered from 1; a gap is an error, as in
/// the reference reader, which then stops treating the file as HDR.
pub fn ratio_image(image: &JpegImage<'_>) -> Result<Option<(RatioHeader, Vec<u8>)>> {
    let mut segments = image.app_payloads(APP11, SIGNATURE).map(|(_, p)| p);
    let Some(first) = segments.next() else { return Ok(None) };
    let split = |payload: &[u8]| -> Result<(String, usize)> {
        let end =
            payload.iter().position(|&b| b == 0).ok_or_else(|| Error::invalid("JPEG-HDR segment without its NUL"))?;
        Ok((String::from_utf8_lossy(&payload[..end]).into_owned(), end + 1))
    };
    let (text, start) = split(first)?;
    let header = RatioHeader::parse(&text)?;
    let mut jpeg = first[start..].to_vec();
    for (n, segment) in segments.enumerate() {
        let (text, start) = split(segment)?;
        let number =
            text.trim().strip_prefix("ext=").and_then(|t| t.trim_end_matches('~').trim().parse::<usize>().ok());
        if number != Some(n + 1) {
            return Err(Error::invalid(format!(
                "JPEG-HDR continuation {text:?} out of sequence (expected ext={})",
                n + 1
            )));
        }
        jpeg.extend_from_slice(&segment[start..]);
    }
    Ok(Some((header, jpeg)))
}

/// Catmull-Rom upsampling of an 8-bit plane, pixel centres aligned, edges clamped, a row at a
/// time; values in code units (not rounded).
pub(crate) struct Upsampler {
    xs: Vec<([usize; 4], [f32; 4])>,
    ys: Vec<([usize; 4], [f32; 4])>,
    source_width: usize,
}

impl Upsampler {
    pub(crate) fn new((sw, sh): (usize, usize), (dw, dh): (usize, usize)) -> Self {
        let taps = |d: usize, s: usize| -> Vec<([usize; 4], [f32; 4])> {
            (0..d)
                .map(|x| {
                    let u = (x as f64 + 0.5) * s as f64 / d as f64 - 0.5;
                    let i = u.floor();
                    let t = u - i;
                    let (t2, t3) = (t * t, t * t * t);
                    let w = [
                        (-t3 + 2.0 * t2 - t) / 2.0,
                        (3.0 * t3 - 5.0 * t2 + 2.0) / 2.0,
                        (-3.0 * t3 + 4.0 * t2 + t) / 2.0,
                        (t3 - t2) / 2.0,
                    ];
                    let at = |k: f64| (i + k).clamp(0.0, (s - 1) as f64) as usize;
                    ([at(-1.0), at(0.0), at(1.0), at(2.0)], w.map(|w| w as f32))
                })
                .collect()
        };
        Upsampler { xs: taps(dw, sw), ys: taps(dh, sh), source_width: sw }
    }

    /// Destination row `y` of `src` into `out` (the destination's width), using `column`
    /// (the source's width) as scratch.
    pub(crate) fn row(&self, src: &[u8], y: usize, column: &mut [f32], out: &mut [f32]) {
        let (yi, yw) = &self.ys[y];
        let sw = self.source_width;
        for (x, r) in column.iter_mut().enumerate() {
            *r = (0..4).map(|k| yw[k] * f32::from(src[yi[k] * sw + x])).sum();
        }
        for (o, (xi, xw)) in out.iter_mut().zip(&self.xs) {
            *o = (0..4).map(|k| xw[k] * column[xi[k]]).sum::<f32>().clamp(0.0, 255.0);
        }
    }
}

/// [`Upsampler`] over a whole plane.
pub(crate) fn upsample(src: &[u8], from: (usize, usize), (dw, dh): (usize, usize)) -> Vec<f32> {
    let up = Upsampler::new(from, (dw, dh));
    let mut column = vec![0f32; from.0];
    let mut out = vec![0f32; dw * dh];
    for (y, row) in out.chunks_exact_mut(dw.max(1)).enumerate() {
        up.row(src, y, &mut column, row);
    }
    out
}

/// Gaussian downsampling of a plane (the reference's filter: weight exp(−(r / 0.6)²) at
/// distance r in destination pixels, out to 1.5 of them), unrounded.
pub(crate) fn gaussian_downsample<T: Copy + Into<f64>>(
    src: &[T],
    (sw, sh): (usize, usize),
    (dw, dh): (usize, usize),
) -> Vec<f64> {
    let taps = |d: usize, s: usize| -> Vec<Vec<(usize, f64)>> {
        let density = d as f64 / s as f64;
        let radius = (1.5 / density + 0.5) as i64;
        (0..d)
            .map(|x| {
                let centre = (x as f64 + 0.5) / density;
                let first = centre as i64;
                let mut w: Vec<(usize, f64)> = (-radius..=radius)
                    .map(|j| {
                        let r = ((first + j) as f64 + 0.5 - centre) * density;
                        ((first + j).clamp(0, s as i64 - 1) as usize, (-(r * r) / 0.36).exp())
                    })
                    .collect();
                let total: f64 = w.iter().map(|t| t.1).sum();
                w.iter_mut().for_each(|t| t.1 /= total);
                w
            })
            .collect()
    };
    let (xs, ys) = (taps(dw, sw), taps(dh, sh));
    let mut rows = vec![0f64; sw];
    let mut out = Vec::with_capacity(dw * dh);
    for yw in &ys {
        for (x, r) in rows.iter_mut().enumerate() {
            *r = yw.iter().map(|&(y, w)| w * src[y * sw + x].into()).sum();
        }
        out.extend(xs.iter().map(|xw| xw.iter().map(|&(x, w)| w * rows[x]).sum::<f64>()));
    }
    out
}

/// [`gaussian_downsample`] of an 8-bit plane truncated to codes, as the reference's
/// post-correction does it.
fn downsample(src: &[u8], from: (usize, usize), to: (usize, usize)) -> Vec<u8> {
    gaussian_downsample(src, from, to).iter().map(|&v| v.clamp(0.0, 255.0) as u8).collect()
}

/// Post-correction (CIC 2005; the reference decoder's `cor=2`, done on 8-bit codes): where the
/// base's luma varies within the ratio image's sample spacing, the ratio takes on the luma's
/// high frequencies, `m = T / T_lp` raised to `σ = (ΔR · T_lp) / (ΔT · R)` when σ < 1.
fn post_correct(ratio: &mut [u8], luma: &[u8], (w, h): (usize, usize), (rw, rh): (usize, usize)) {
    let low = upsample(&downsample(luma, (w, h), (rw, rh)), (rw, rh), (w, h));
    let low: Vec<u8> = low.iter().map(|&v| (v + 0.5) as u8).collect();
    let r = w / rw;
    if r == 0 || w <= 2 * r || h <= 2 * r {
        return;
    }
    let original = ratio.to_vec();
    for y in r..h - r {
        for x in r..w - r {
            let i = y * w + x;
            if original[i] == 0 {
                continue;
            }
            let (mut t_range, mut r_range) = ((255u8, 0u8), (255u8, 0u8));
            for j in [y - r, y, y + r] {
                for k in [x - r, x, x + r] {
                    let (t, q) = (low[j * w + k], original[j * w + k]);
                    t_range = (t_range.0.min(t), t_range.1.max(t));
                    r_range = (r_range.0.min(q), r_range.1.max(q));
                }
            }
            let dt = f64::from(t_range.1 - t_range.0);
            // Differences this small are the JPEG's own noise.
            if dt <= 3.0 || low[i] == 0 {
                continue;
            }
            let sigma = f64::from(r_range.1 - r_range.0) * f64::from(low[i]) / (dt * f64::from(original[i]));
            let mut m = f64::from(luma[i]) / f64::from(low[i]);
            if sigma < 1.0 {
                m = m.powf(sigma);
            }
            ratio[i] = (m * f64::from(original[i]) + 0.5).min(255.0) as u8;
        }
    }
}

/// Undoes the base's desaturation (`alp`, `bet`; CIC 2005, the reference's resaturation).
fn resaturate(rgb: &mut [f64; 3], alpha: f64, beta: f64) {
    if (alpha - 1.0).abs() <= 1e-4 && (beta - 1.0).abs() <= 1e-4 {
        return;
    }
    let y = luma(*rgb);
    if y <= 1e-10 {
        return;
    }
    if (beta - 1.0).abs() <= 1e-4 {
        let s = 1.0 / alpha;
        *rgb = rgb.map(|c| y * (1.0 - s) + s * c);
        return;
    }
    let min = (0..3).min_by(|&a, &b| rgb[a].total_cmp(&rgb[b])).unwrap_or(0);
    if y - rgb[min] <= 1e-4 {
        return;
    }
    let sat = (y - rgb[min]) / (alpha * y);
    let new_min = y * (1.0 - sat.powf(1.0 / beta));
    let s = (1.0 - new_min / y).powf(1.0 - beta) / alpha;
    for (c, v) in rgb.iter_mut().enumerate() {
        *v = if c == min { new_min } else { y * (1.0 - s) + s * *v };
    }
}

/// The ratio codes of every base pixel, as the decoder applies them.
enum Codes {
    /// A ratio image of the base's size: its own codes.
    Same(Vec<u8>),
    /// Upsampled a row at a time.
    Upsampled(Upsampler, Vec<u8>),
    /// Upsampled and post-corrected (`cor=2`), whole.
    PostCorrected(Vec<u8>),
}

/// A JPEG-HDR file ready to deliver its rows: both JPEGs decoded (their 8-bit samples held),
/// the ratio post-corrected if asked; what the rows will be described.
pub struct Prepared {
    base: crate::gainmap::Pixels,
    codes: Codes,
    header: RatioHeader,
    info: ImageInfo,
    _charge: Option<hdrcodec_core::Allocation>,
}

/// Decodes a JPEG-HDR file's two JPEGs (whose primary image is `primary` and ratio image
/// `ratio_jpeg`), ready for `Prepared::rows`. Samples are relative when `s2n` is 0 (then 1.0
/// is noted as unknown luminance and given the family's default scale), else 1.0 = `s2n`
/// cd/m².
pub fn prepare(
    data: &[u8],
    primary: &JpegImage<'_>,
    header: &RatioHeader,
    ratio_jpeg: &[u8],
    limits: &Limits,
) -> Result<Prepared> {
    markers::parse_image(ratio_jpeg, 0)?;
    let base = decode_jpeg_as(primary.bytes(data), limits, "JPEG-HDR base", true)?;
    if base.channels != 3 {
        return Err(Error::unsupported("JPEG-HDR with a greyscale base"));
    }
    let ratio = decode_jpeg_as(ratio_jpeg, limits, "JPEG-HDR ratio image", false)?;
    if ratio.channels != 1 {
        return Err(Error::invalid("JPEG-HDR ratio image is not greyscale"));
    }
    let Pixels { width: w, height: h, .. } = base;
    let (rw, rh) = (ratio.width, ratio.height);
    let mut charge = None;
    let codes = if (rw, rh) == (w, h) {
        Codes::Same(ratio.samples)
    } else if header.correction == Correction::Post && rw < w {
        // The luma, its low-pass (as floats, then codes) and the corrected codes, whole.
        charge = Some(limits.charge(w as u64 * h as u64 * 7, "JPEG-HDR post-correction")?);
        let mut up: Vec<u8> = upsample(&ratio.samples, (rw, rh), (w, h)).iter().map(|&v| (v + 0.5) as u8).collect();
        let luma: Vec<u8> = base.samples.iter().step_by(3).copied().collect();
        post_correct(&mut up, &luma, (w, h), (rw, rh));
        Codes::PostCorrected(up)
    } else {
        Codes::Upsampled(Upsampler::new((rw, rh), (w, h)), ratio.samples)
    };
    let nits_per_unit =
        if header.samples_to_nits > 0.0 { header.samples_to_nits as f32 } else { ColorInfo::default().nits_per_unit };
    let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit, hdr10: None };
    let mut info = ImageInfo::new(w as u32, h as u32, Channels::Rgb, color).with_metadata(
        "jpeg.ratio_image",
        format!(
            "JPEG-HDR ver={} ({rw}x{rh}, ln {:.4}..{:.4}, cor={:?}, alp={} bet={})",
            header.version, header.ln_range[0], header.ln_range[1], header.correction, header.alpha, header.beta
        ),
    );
    if header.samples_to_nits == 0.0 {
        info = info.with_metadata("jpeg.luminance_note", "s2n=0: the file does not say how bright its samples are");
    }
    Ok(Prepared { base, codes, header: header.clone(), info, _charge: charge })
}

impl Prepared {
    /// What the rows will be.
    pub fn info(&self) -> &ImageInfo {
        &self.info
    }

    /// Rows `y0 ..` into `out` (whole RGB rows), `column` and `codes` being scratch of the
    /// ratio image's width and of the base's.
    fn rows(&self, y0: usize, out: &mut [f32], column: &mut [f32], codes: &mut [f32]) {
        let w = self.base.width;
        for (r, out_row) in out.chunks_exact_mut(w * 3).enumerate() {
            let y = y0 + r;
            match &self.codes {
                Codes::Same(c) | Codes::PostCorrected(c) => {
                    codes.iter_mut().zip(&c[y * w..(y + 1) * w]).for_each(|(o, &c)| *o = f32::from(c));
                }
                Codes::Upsampled(up, small) => up.row(small, y, column, codes),
            }
            let base_row = &self.base.samples[y * w * 3..(y + 1) * w * 3];
            for ((o, ycc), &code) in out_row.chunks_exact_mut(3).zip(base_row.chunks_exact(3)).zip(codes.iter()) {
                // JFIF's Y'CbCr → R'G'B' (T.871 7) in 16-bit fixed point, rounded down as the
                // reference's libjpeg arithmetic does (rounding to nearest decodes about 1%
                // brighter on average), kept outside [0, 255]: the format's wide gamut.
                let (y, cb, cr) = (i32::from(ycc[0]), i32::from(ycc[1]) - 128, i32::from(ycc[2]) - 128);
                let srgb =
                    [y + ((91881 * cr) >> 16), y + ((-22553 * cb - 46818 * cr) >> 16), y + ((116130 * cb) >> 16)];
                let mut rgb = srgb.map(|v| SrgbTransfer::decode(f64::from(v) / 256.0));
                resaturate(&mut rgb, self.header.alpha, self.header.beta);
                let ratio = self.header.ratio(f64::from(code));
                for c in 0..3 {
                    o[c] = (rgb[c] * ratio) as f32;
                }
            }
        }
    }

    /// Delivers the image to `sink` a band of rows at a time.
    pub fn deliver(&self, limits: &Limits, sink: &mut dyn RowSink) -> Result<()> {
        sink.start(&self.info)?;
        let (w, h) = (self.base.width, self.base.height);
        let row_len = w * 3;
        let band = band_rows(row_len, 1 << 20) as usize;
        let mut scratch = Scratch::new(limits);
        let column_len = match &self.codes {
            Codes::Upsampled(up, _) => up.source_width,
            _ => 0,
        };
        let _charge = limits.charge((column_len + w) as u64 * 4, "JPEG-HDR ratio rows")?;
        let (mut column, mut codes) = (vec![0f32; column_len], vec![0f32; w]);
        for y0 in (0..h).step_by(band.max(1)) {
            let rows = band.min(h - y0);
            fill_rows(sink, y0 as u32, rows as u32, row_len, &mut scratch, |out| {
                self.rows(y0, out, &mut column, &mut codes);
                Ok(())
            })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gainmap::{decode as decode_file, Rendering};

    /// A small JPEG-HDR file: a 32x24 colour base and an 8x6 ratio image in two `HDR_RI`
    /// segments (the second `ext=1`), with `cor`.
    fn small_file(cor: u8) -> Vec<u8> {
        let mut ratio = Vec::new();
        let codes: Vec<u8> = (0..48).map(|i| (i * 5) as u8).collect();
        jpeg_encoder::Encoder::new(&mut ratio, 95).encode(&codes, 8, 6, jpeg_encoder::ColorType::Luma).unwrap();
        let (a, b) = ratio.split_at(ratio.len() / 2);
        let head =
            format!("ver=11\n ln0=-1.000000, ln1=3.000000, s2n=1.790000e+02 alp=0.800000 bet=1.000000 cor={cor}\n~");
        let mut file = Vec::new();
        let mut encoder = jpeg_encoder::Encoder::new(&mut file, 90);
        encoder.add_app_segment(11, &[SIGNATURE, head.as_bytes(), &[0], a].concat()).unwrap();
        encoder.add_app_segment(11, &[SIGNATURE, b"ext=1\n~\0", b].concat()).unwrap();
        let base: Vec<u8> = (0..32 * 24).flat_map(|i| [(i % 32 * 8) as u8, (i / 32 * 10) as u8, 128]).collect();
        encoder.encode(&base, 32, 24, jpeg_encoder::ColorType::Rgb).unwrap();
        file
    }

    #[test]
    fn small_files_decode_and_damage_falls_back_to_sdr() {
        for cor in [1, 2] {
            let file = small_file(cor);
            let image = decode_file(&file, &Limits::default(), Rendering::default()).unwrap();
            assert_eq!((image.width(), image.height(), image.color.nits_per_unit), (32, 24, 179.0));
            assert!(image.metadata_value("jpeg.ratio_image").is_some(), "{:?}", image.metadata);
            // Ratios run from e^-1 to e^3 across the image.
            let peak = image.samples().iter().copied().fold(0.0f32, f32::max);
            assert!(peak > 5.0, "{peak}");
            for n in 0..file.len() {
                let _ = decode_file(&file[..n], &Limits::default(), Rendering::default());
            }
        }
        // The second segment numbered 2: the base alone, with a warning.
        let file = small_file(1);
        let at = file.windows(5).position(|w| w == b"ext=1").unwrap();
        let mut broken = file.clone();
        broken[at + 4] = b'2';
        let image = decode_file(&broken, &Limits::default(), Rendering::default()).unwrap();
        assert!(image.metadata_value("jpeg.warning").is_some() && image.metadata_value("jpeg.ratio_image").is_none());
    }

    #[test]
    fn header_text_parses_as_written_and_leniently() {
        let h = RatioHeader::parse(
            "ver=11\n ln0=-0.230798, ln1=3.211873, s2n=1.790000e+02 alp=0.800000 bet=0.900000 cor=2\n~",
        )
        .unwrap();
        assert_eq!(
            h,
            RatioHeader {
                version: 11,
                ln_range: [-0.230798, 3.211873],
                samples_to_nits: 179.0,
                alpha: 0.8,
                beta: 0.9,
                correction: Correction::Post
            }
        );
        assert!(RatioHeader::parse("cor=1 bet=1 alp=1 s2n=0 ln1=2 ln0=0 ver=10").is_ok());
        for bad in
            ["ver=11 ln0=1 ln1=0 s2n=0 alp=1 bet=1 cor=1", "ver=21 ln0=0 ln1=1 s2n=0 alp=1 bet=1 cor=1", "ver=11 ln0=0"]
        {
            assert!(RatioHeader::parse(bad).is_err(), "{bad}");
        }
        // Code 255 is half a step below e^ln1, code 0 half a step above e^ln0.
        let step = (h.ln_range[1] - h.ln_range[0]) / 256.0;
        assert!((h.ratio(255.0).ln() - (h.ln_range[1] - step / 2.0)).abs() < 1e-12);
    }

    #[test]
    fn resampling_keeps_flat_planes_flat() {
        let flat = vec![100u8; 12 * 8];
        assert!(upsample(&flat, (12, 8), (40, 30)).iter().all(|&v| (v - 100.0).abs() < 1e-3));
        assert!(downsample(&flat, (12, 8), (5, 3)).iter().all(|&v| v == 99 || v == 100));
    }

    #[test]
    fn resaturation_inverts_desaturation() {
        let (alpha, beta) = (0.8, 1.0);
        let c = [0.9, 0.3, 0.1];
        let y = luma(c);
        let mut d = c.map(|v| y * (1.0 - alpha) + alpha * v);
        resaturate(&mut d, alpha, beta);
        assert!((0..3).all(|k| (d[k] - c[k]).abs() < 1e-12));
    }
}
