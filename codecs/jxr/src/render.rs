//! From a `.jxr` file to rows of linear f32 samples: the container, entropy decoding to
//! coefficients, the inverse transform of each channel, chroma upsampling and output
//! formatting as jxrlib's (its raw samples), then the conversion to linear f32.

use crate::container::{parse_container, Container, OutputBitDepth, OutputColorFormat};
use crate::decoder::{RowCompleter, RowDecoder};
use crate::header;
use crate::header::ClrFmt;
use crate::mb::MbCoeffs;
use crate::output::{upsample_chroma_row, AlphaParams, InternalColorFormat, OutputParams};
use crate::tiles::MbSide;
use crate::transform::{self, HardEdges, OperatorSet, OverlapMode, PlaneKind, TransformParams};
use hdrcodec_core::sink::{fill_rows, OrientSink, Orientation, RowSink, Scratch};
use hdrcodec_core::{Channels, DecodeOptions, Error, ImageInfo, Result};

fn clr_code(fmt: ClrFmt) -> u8 {
    match fmt {
        ClrFmt::YOnly => 0,
        ClrFmt::Yuv420 => 1,
        ClrFmt::Yuv422 => 2,
        ClrFmt::Yuv444 => 3,
        ClrFmt::Yuvk => 4,
        ClrFmt::NComponent => 6,
    }
}

fn kind(fmt: ClrFmt, ch: usize) -> PlaneKind {
    match (fmt, ch) {
        (ClrFmt::Yuv420, 1..) => PlaneKind::Chroma420,
        (ClrFmt::Yuv422, 1..) => PlaneKind::Chroma422,
        _ => PlaneKind::Full,
    }
}

/// Macroblock rows of coefficients of one plane, kept per channel for the band transform:
/// rows `first .. first + n` (each `mb_width` macroblocks).
struct Window {
    first: usize,
    channels: Vec<Vec<MbCoeffs>>,
}

impl Window {
    /// A window of `channels` channels with room for `mbs` macroblocks each, allocated
    /// once: a window that grew by doubling would copy its rows at each step.
    fn new(channels: usize, mbs: usize) -> Self {
        Window { first: 0, channels: (0..channels).map(|_| Vec::with_capacity(mbs)).collect() }
    }

    /// Appends one decoded macroblock row (`mb_w × channels` arrays, channels inner).
    fn push(&mut self, row: &[i32]) {
        let n = self.channels.len();
        for (i, mb) in row.chunks_exact(crate::mb::MB_COEFFS).enumerate() {
            self.channels[i % n].push(mb.try_into().expect("a macroblock"));
        }
    }

    /// Drops the rows before `row`.
    fn drop_before(&mut self, row: usize, mb_w: usize) {
        let k = row.saturating_sub(self.first);
        if k > 0 {
            for c in &mut self.channels {
                c.drain(..(k * mb_w).min(c.len()));
            }
            self.first += k;
        }
    }
}

/// Decodes a whole `.jxr` file into `sink`, in the orientation the container's
/// SPATIAL_XFRM_PRIMARY gives ([`orientation`]; as jxrlib's library and WIC do, the
/// codestream's own field is ignored). Flips cost nothing; a rotation holds the image once.
pub fn decode_rows(data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    let o = orientation(&parse_container(data)?);
    if o.is_identity() {
        return decode_impl(data, options, Some(sink), &mut |_, _| {});
    }
    let mut oriented = OrientSink::new(sink, o, &options.limits);
    decode_impl(data, options, Some(&mut oriented), &mut |_, _| {})?;
    oriented.finish()
}

/// The orientation a decoded image is given: the container's SPATIAL_XFRM_PRIMARY (bit 2
/// rotate 90° clockwise first, bit 1 flip horizontally, bit 0 flip vertically); none without
/// it. jxrlib's glue does the same (JXR-NOTES §7), though its JxrDecApp overrides the result
/// with its `-O` option (default none), and [`decode_raw`] keeps the stored orientation.
pub fn orientation(container: &Container) -> Orientation {
    let code = container.orientation.unwrap_or(0);
    Orientation { rotate_cw: code & 4 != 0, flip_h: code & 2 != 0, flip_v: code & 1 != 0 }
}

/// Decodes a whole `.jxr` file to jxrlib's output samples (the pixel format's bytes, row by
/// row, in the stored orientation, as JxrDecApp writes them), for comparing with jxrlib.
pub fn decode_raw(data: &[u8], options: &DecodeOptions) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    decode_impl(data, options, None, &mut |_, raw| bytes.extend_from_slice(raw))?;
    Ok(bytes)
}

fn decode_impl(
    data: &[u8],
    options: &DecodeOptions,
    sink: Option<&mut dyn RowSink>,
    raw_rows: &mut dyn FnMut(usize, &[u8]),
) -> Result<()> {
    let container = parse_container(data)?;
    let format = container.pixel_format;
    let cs = header::parse(container.image)?;
    let planar_cs = container.alpha.map(header::parse).transpose()?;
    let img = &cs.image;
    transform::check_operator_set(img.sub_version)?;
    if let Some(p) = &planar_cs {
        if (p.image.mb_width, p.image.mb_height) != (img.mb_width, img.mb_height) {
            return Err(Error::invalid("JPEG XR: the alpha codestream's size differs from the image's"));
        }
    }
    let bit_depth = OutputBitDepth::from_code(img.output_bitdepth)
        .ok_or_else(|| Error::invalid(format!("OUTPUT_BITDEPTH {}", img.output_bitdepth)))?;
    let clr = OutputColorFormat::from_code(img.output_clr_fmt)
        .ok_or_else(|| Error::invalid(format!("OUTPUT_CLR_FMT {}", img.output_clr_fmt)))?;
    let primary = &cs.primary;
    let internal = InternalColorFormat::from_code(clr_code(primary.clr_fmt), primary.channels as u8)
        .ok_or_else(|| Error::invalid("INTERNAL_CLR_FMT"))?;
    let alpha_params = match (&cs.alpha, &planar_cs) {
        (Some(_), _) => Some(AlphaParams { scaled: primary.scaled, jxrlib_interleaved: true }),
        (None, Some(p)) => Some(AlphaParams { scaled: p.primary.scaled, jxrlib_interleaved: false }),
        (None, None) => None,
    };
    let colour = crate::colour::file_colour(&container);
    let mut out = OutputParams::new(
        format,
        bit_depth,
        clr,
        internal,
        primary.scaled,
        primary.shift_or_mantissa,
        primary.exp_bias as i8,
        img.red_blue_not_swapped,
        if format.alpha { alpha_params } else { None },
    )?;
    // Linear RGB(A) rows for a sink; raw samples alone (decode_raw) for any format.
    let channels = match (&sink, out.linear_channels()) {
        (Some(_), n) => Channels::from_count(n?).ok_or_else(|| Error::unsupported("channels"))?,
        (None, _) => Channels::Rgb,
    };
    out.transfer = colour.transfer;
    let mut info = ImageInfo::new(img.width, img.height, channels, colour.color).with_format(format.name);
    info.metadata = colour.metadata;
    let (width, height) = (img.width as usize, img.height as usize);
    let (mb_w, mb_h) = (img.mb_width as usize, img.mb_height as usize);
    let overlap = [OverlapMode::None, OverlapMode::One, OverlapMode::Two][usize::from(img.overlap.min(2))];
    let hard = img.hard_tiling.then(|| {
        let cols: Vec<usize> = img.tile_x0().iter().map(|&v| v as usize).collect();
        let rows: Vec<usize> = img.tile_y0().iter().map(|&v| v as usize).collect();
        HardEdges::from_tiles(&cols[..cols.len() - 1], &rows[..rows.len() - 1], true)
    });
    // The operators follow each codestream's sub-version (HD Photo 1.0: the legacy set).
    let params =
        |scaled: bool, operators: OperatorSet| TransformParams { overlap, scaled, hard: hard.clone(), operators };
    // The decoders: the primary's (which also gives an interleaved alpha plane), the planar
    // alpha codestream's; and the windows of coefficients each channel's transform reads.
    let mut prim_dec = RowDecoder::new(&cs, container.image, options)?;
    let (alpha_fmt, alpha_scaled) = match (&cs.alpha, &planar_cs) {
        (Some(a), _) => (a.clr_fmt, a.scaled),
        (None, Some(p)) => (p.primary.clr_fmt, p.primary.scaled),
        (None, None) => (ClrFmt::YOnly, false),
    };
    let mut alpha_dec = match (&planar_cs, container.alpha) {
        (Some(p), Some(bytes)) if format.alpha && cs.alpha.is_none() => Some(RowDecoder::new(p, bytes, options)?),
        _ => None,
    };
    let with_alpha = format.alpha && (cs.alpha.is_some() || alpha_dec.is_some());
    let prim_params = params(primary.scaled, OperatorSet::for_plane(&cs, container.image, 0, options)?);
    let alpha_ops = match (&cs.alpha, &planar_cs, container.alpha) {
        (Some(_), _, _) if with_alpha => OperatorSet::for_plane(&cs, container.image, 1, options)?,
        (None, Some(p), Some(bytes)) if with_alpha => OperatorSet::for_plane(p, bytes, 0, options)?,
        _ => OperatorSet::JpegXr,
    };
    let alpha_params = params(alpha_scaled, alpha_ops);
    // Working memory: the windows (band + halo of coefficients) and the band's samples.
    let band = transform::BAND_MB_ROWS;
    let window_rows = band + 5;
    let coeff_bytes = (window_rows * mb_w * (primary.channels + 1) * crate::mb::MB_COEFFS * 4) as u64;
    let sample_bytes = ((band + 1) * 16 * mb_w * 16 * 4 * (primary.channels + 2)) as u64;
    let _charge = options.limits.charge(coeff_bytes + sample_bytes, "the JPEG XR band buffers")?;
    let window_mbs = window_rows.min(mb_h) * mb_w;
    let mut win = Window::new(primary.channels, window_mbs);
    let mut awin = with_alpha.then(|| Window::new(1, window_mbs));
    let mut sink = sink;
    if let Some(s) = sink.as_deref_mut() {
        s.start(&info)?;
    }
    let [top, left, _, _] = img.margins.map(|m| m as usize);
    let ext_w = 16 * mb_w;
    let row_len = width * channels.count();
    let mut full = vec![vec![0i32; ext_w]; primary.channels];
    let mut raw = vec![0u8; out.row_bytes(width)];
    let mut scratch = Scratch::new(&options.limits);
    // Coefficients of rows up to r1 + 3 for the band r0..r1 (the halo, and one more row for
    // 4:2:0 chroma). The next band's rows are entropy-decoded while this band transforms.
    let need = |r1: usize| (r1 + 3).min(mb_h);
    // In frequency order with flexbits, the FLEXBITS packet is decoded with the transform
    // (thread B), a band behind the DC, LP and HP packets (thread A).
    let deferred = RowDecoder::can_defer_flex(&cs);
    let mut completer = deferred.then(|| RowCompleter::new(&cs, container.image));
    // Row and sample buffers go back to these once used, so that a band reuses the memory of
    // the band before (fresh allocations of this size cost page faults and zeroing).
    let mut spare_rows: Vec<Fetched> = Vec::new();
    let mut spare_samples: Vec<Vec<i32>> = Vec::new();
    let mut decoded = need(band.min(mb_h));
    let mut pending = fetch(&mut prim_dec, alpha_dec.as_mut(), deferred, decoded, &mut spare_rows)?;
    for r0 in (0..mb_h).step_by(band) {
        let r1 = (r0 + band).min(mb_h);
        let next = need((r1 + band).min(mb_h));
        let rows_in = std::mem::take(&mut pending);
        let mut sample_bufs = std::mem::take(&mut spare_samples);
        let (win_ref, awin_ref, completer_ref) = (&mut win, &mut awin, &mut completer);
        let (prim_params, alpha_params) = (&prim_params, &alpha_params);
        let transform_all = move || -> Result<(Vec<transform::Plane>, Option<transform::Plane>, Vec<Fetched>)> {
            // The rows this band needs: completed (flexbits) and appended to the windows.
            win_ref.drop_before(r0.saturating_sub(2), mb_w);
            if let Some(a) = awin_ref.as_mut() {
                a.drop_before(r0.saturating_sub(2), mb_w);
            }
            let mut used = Vec::with_capacity(rows_in.len());
            for mut row in rows_in {
                if let Some(c) = completer_ref.as_mut() {
                    c.complete(&mut row.planes, &row.side)?;
                }
                win_ref.push(&row.planes[0]);
                if let Some(a) = awin_ref.as_mut() {
                    let alpha = row.planar_alpha.as_deref().or(row.planes.get(1).map(|v| &v[..]));
                    a.push(alpha.ok_or_else(|| Error::invalid("JPEG XR: an alpha row is missing (a bug)"))?);
                }
                used.push(row);
            }
            let (win, awin) = (&*win_ref, &*awin_ref);
            let planes = (0..primary.channels)
                .map(|ch| {
                    let end = if ch > 0 && primary.clr_fmt == ClrFmt::Yuv420 { (r1 + 1).min(mb_h) } else { r1 };
                    let buf = sample_bufs.pop().unwrap_or_default();
                    transform_band(win, prim_params, primary.clr_fmt, ch, mb_w, mb_h, r0..end, buf)
                })
                .collect::<Result<_>>()?;
            let alpha = awin
                .as_ref()
                .map(|a| {
                    let buf = sample_bufs.pop().unwrap_or_default();
                    transform_band(a, alpha_params, alpha_fmt, 0, mb_w, mb_h, r0..r1, buf)
                })
                .transpose()?;
            Ok((planes, alpha, used))
        };
        let count = next - decoded;
        let spare = &mut spare_rows;
        let mut fetch_next = || fetch(&mut prim_dec, alpha_dec.as_mut(), deferred, count, spare);
        let (fetched, transformed) = if options.pool.is_parallel() && count > 0 {
            options.pool.install(|| rayon::join(fetch_next, transform_all))
        } else {
            (fetch_next(), transform_all())
        };
        pending = fetched?;
        decoded = next;
        let (planes, alpha_plane, used) = transformed?;
        spare_rows.extend(used);
        // Output rows: the band's rows inside the window.
        let (y_start, y_end) = ((r0 * 16).max(top), (r1 * 16).min(top + height));
        if y_start < y_end {
            let (y0, rows) = ((y_start - top) as u32, (y_end - y_start) as u32);
            let mut render = |dst: &mut [f32]| -> Result<()> {
                for i in 0..rows as usize {
                    let y = y_start + i;
                    let local = y - r0 * 16;
                    for (ch, p) in planes.iter().enumerate() {
                        if ch == 0 || kind(primary.clr_fmt, ch) == PlaneKind::Full {
                            full[ch].copy_from_slice(&p.data[local * p.width..(local + 1) * p.width]);
                        } else {
                            // The band's chroma rows (4:2:0: half as many, and the next band's
                            // first macroblock row for the interpolation of the band's last row).
                            upsample_chroma_row(internal, &p.data, p.width, p.height, local, &mut full[ch])?;
                        }
                    }
                    let rows: Vec<&[i32]> = full.iter().map(|r| &r[left..]).collect();
                    let a = alpha_plane.as_ref().map(|p| &p.data[local * p.width + left..(local + 1) * p.width]);
                    out.format_row(&rows, a, width, &mut raw)?;
                    raw_rows(y - top, &raw);
                    if !dst.is_empty() {
                        out.row_to_f32(&raw, width, &mut dst[i * row_len..(i + 1) * row_len])?;
                    }
                }
                Ok(())
            };
            match sink.as_deref_mut() {
                Some(s) => fill_rows(s, y0, rows, row_len, &mut scratch, render)?,
                None => render(&mut [])?,
            }
        }
        spare_samples.extend(planes.into_iter().chain(alpha_plane).map(|p| p.data));
    }
    Ok(())
}

/// One macroblock row as the entropy decoders give it: the primary codestream's planes
/// (primary, interleaved alpha), their side information when the flexbits are deferred, and
/// the planar alpha codestream's row.
struct Fetched {
    planes: Vec<Vec<i32>>,
    side: Vec<Vec<MbSide>>,
    planar_alpha: Option<Vec<i32>>,
}

/// Decodes the next `n` macroblock rows (without their flexbits when `deferred`), into the
/// buffers of rows from `spare` while there are some.
fn fetch(
    prim: &mut RowDecoder,
    alpha: Option<&mut RowDecoder>,
    deferred: bool,
    n: usize,
    spare: &mut Vec<Fetched>,
) -> Result<Vec<Fetched>> {
    let mut alpha = alpha;
    let mut rows = Vec::with_capacity(n);
    let past = || Error::invalid("JPEG XR: rows past the image (a bug in the decoder)");
    for _ in 0..n {
        let Fetched { mut planes, mut side, planar_alpha } =
            spare.pop().unwrap_or_else(|| Fetched { planes: Vec::new(), side: Vec::new(), planar_alpha: None });
        planes.resize_with(2, Vec::new);
        if deferred {
            side.resize_with(2, Vec::new);
            prim.next_row_deferred(&mut planes, &mut side)?.ok_or_else(past)?;
        } else {
            prim.next_row(&mut planes)?.ok_or_else(past)?;
        }
        let planar_alpha = match alpha.as_deref_mut() {
            Some(dec) => {
                let mut b = vec![planar_alpha.unwrap_or_default()];
                dec.next_row(&mut b)?.ok_or_else(past)?;
                b.pop()
            }
            None => None,
        };
        rows.push(Fetched { planes, side, planar_alpha });
    }
    Ok(rows)
}

/// The samples of macroblock rows `rows` of channel `ch` of a plane, from its window, in
/// `data` (a buffer to reuse; its contents do not matter).
#[allow(clippy::too_many_arguments)]
fn transform_band(
    win: &Window,
    params: &TransformParams,
    fmt: ClrFmt,
    ch: usize,
    mb_w: usize,
    mb_h: usize,
    rows: std::ops::Range<usize>,
    mut data: Vec<i32>,
) -> Result<transform::Plane> {
    let k = kind(fmt, ch);
    let (bx, by) = k.blocks();
    let (w, unit) = (bx * 4 * mb_w, by * 4);
    // inverse_band writes every sample: only a buffer that grows needs its new part zeroed.
    data.resize(w * unit * rows.len(), 0);
    transform::inverse_band(params, k, ch, mb_w, mb_h, &win.channels[ch], win.first, rows.clone(), &mut data)?;
    Ok(transform::Plane { width: w, height: unit * rows.len(), data })
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::Limits;

    /// The codec decodes to linear f32 (half samples exactly), into an image or a caller's
    /// strided buffer alike, within a budget far below the image's coefficients.
    #[test]
    fn decode_and_decode_into_agree() {
        use hdrcodec_core::sink::FrameBufMut;
        use hdrcodec_core::ImageCodec;
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata/tiny_alpha_sp.jxr");
        let file = std::fs::read(path).unwrap();
        let image = crate::JxrCodec.decode(&file, &Limits::default()).unwrap();
        assert_eq!((image.width(), image.height(), image.channels()), (40, 24, Channels::Rgba));
        assert_eq!((image.color.primaries, image.color.nits_per_unit), (hdrcodec_core::ColorPrimaries::Bt709, 80.0));
        // 64bppRGBAHalf: the f32 samples are jxrlib's halves.
        let raw = decode_raw(&file, &DecodeOptions::new(Limits::default())).unwrap();
        let halves: Vec<f32> =
            raw.chunks_exact(2).map(|b| half::f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32()).collect();
        assert_eq!(image.samples().len(), halves.len());
        assert!(image.samples().iter().zip(&halves).all(|(a, b)| a.to_bits() == b.to_bits()));
        let stride = 40 * 4 + 3;
        let mut buf = vec![-1.0f32; stride * 24];
        let info = crate::JxrCodec
            .decode_into(&file, &DecodeOptions::new(Limits::default()), FrameBufMut::f32(&mut buf, stride))
            .unwrap();
        assert_eq!((info.width, info.height), (40, 24));
        for y in 0..24 {
            assert_eq!(&buf[y * stride..y * stride + 160], image.row(y as u32));
            assert_eq!(&buf[y * stride + 160..(y + 1) * stride], &[-1.0; 3]);
        }
    }

    /// jxrlib's samples (imagecodecs `jpegxr_decode`) of streams T.835 wrote, hashed
    /// (testdata/README.md): hard tiles, a non-square hard grid, windowing.
    #[test]
    fn t835_streams_decode_as_jxrlib_does() {
        let cases = [
            ("t835_hard_2x2.jxr", 0xdb29_3636_f37c_9fd4u64),
            ("t835_hard_2x3.jxr", 0x98c0_2dc3_32cc_91d2),
            ("t835_window.jxr", 0x9939_afc3_c4ad_8d00),
            ("t835_window_420.jxr", 0x6dad_2b1b_2362_3b77),
            ("t835_qp_map.jxr", 0x45eb_d8d1_d290_0b95),
            ("t835_tile_qps.jxr", 0x3516_de69_6aec_84bc),
            // 32bppCMYK (YUVK), as JxrDecApp's TIFF holds it.
            ("t835_cmyk.jxr", 0xddb1_23c6_b29a_8e24),
        ];
        for (name, want) in cases {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
            let file = std::fs::read(&path).unwrap();
            for threads in [1, 2] {
                let pool = hdrcodec_core::ThreadPool::new(threads).unwrap();
                let raw = decode_raw(&file, &DecodeOptions::new(Limits::default()).with_pool(pool)).unwrap();
                let h =
                    raw.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3));
                assert_eq!(h, want, "{name} on {threads} threads");
            }
        }
    }
}
