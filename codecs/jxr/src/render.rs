//! From a `.jxr` file to rows of linear f32 samples: the container, entropy decoding to
//! coefficients, the inverse transform of each channel, chroma upsampling and output
//! formatting as jxrlib's (its raw samples), then the conversion to linear f32.

use crate::container::{parse_container, Container, OutputBitDepth, OutputColorFormat};
use crate::decoder::{RowCompleter, RowDecoder};
use crate::header;
use crate::header::{ClrFmt, Codestream};
use crate::output::{upsample_chroma_row, AlphaParams, InternalColorFormat, OutputParams};
use crate::source::{SharedFile, Source, Tuning};
use crate::tiles::MbSide;
use crate::transform::{
    self, BandRequest, BandScratch, HardEdges, MbRows, OperatorSet, OverlapMode, PlaneKind, TransformParams,
};
use hdrcodec_core::sink::{fill_rows, OrientSink, Orientation, RowSink, Scratch};
use hdrcodec_core::{Channels, DecodeOptions, Error, ImageInfo, ReadSeek, Result};
use std::collections::VecDeque;
use std::ops::Range;

/// INTERNAL_CLR_FMT's code.
pub(crate) fn clr_code(fmt: ClrFmt) -> u8 {
    match fmt {
        ClrFmt::YOnly => 0,
        ClrFmt::Yuv420 => 1,
        ClrFmt::Yuv422 => 2,
        ClrFmt::Yuv444 => 3,
        ClrFmt::Yuvk => 4,
        ClrFmt::NComponent => 6,
    }
}

/// How channel `ch` of an INTERNAL_CLR_FMT is sampled.
pub(crate) fn kind(fmt: ClrFmt, ch: usize) -> PlaneKind {
    match (fmt, ch) {
        (ClrFmt::Yuv420, 1..) => PlaneKind::Chroma420,
        (ClrFmt::Yuv422, 1..) => PlaneKind::Chroma422,
        _ => PlaneKind::Full,
    }
}

/// The decoded macroblock rows the band transform reads, `first ..` (each row as the entropy
/// decoder gave it: the transform reads the coefficients in place).
struct Window {
    first: usize,
    rows: VecDeque<Fetched>,
}

impl Window {
    /// Drops the rows before `row`, giving their buffers back to `spare`.
    fn drop_before(&mut self, row: usize, spare: &mut Vec<Fetched>) {
        while self.first < row {
            match self.rows.pop_front() {
                Some(r) => spare.push(r),
                None => break,
            }
            self.first += 1;
        }
    }

    /// The rows of one plane's coefficients: the primary codestream's (`Plane::Primary`), or
    /// the alpha channel's (interleaved in the primary codestream, or planar).
    fn plane_rows(&self, plane: WindowPlane) -> Result<Vec<&[i32]>> {
        self.rows
            .iter()
            .map(|row| {
                let r = match plane {
                    WindowPlane::Primary => row.planes.first(),
                    WindowPlane::Alpha => row.planar_alpha.as_ref().or(row.planes.get(1)),
                };
                r.map(|v| &v[..]).ok_or_else(|| Error::invalid("JPEG XR: an alpha row is missing (a bug)"))
            })
            .collect()
    }
}

/// Which coefficients of the window a transform reads.
#[derive(Clone, Copy, PartialEq, Eq)]
enum WindowPlane {
    Primary,
    Alpha,
}

/// Decodes a whole `.jxr` file into `sink`, in the orientation the container's
/// SPATIAL_XFRM_PRIMARY gives ([`orientation`]; as jxrlib's library and WIC do, the
/// codestream's own field is ignored). Flips cost nothing; a rotation holds the image once.
pub fn decode_rows(data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    decode_parsed(&Parsed::memory(data)?, options, sink)
}

/// [`decode_rows`] of a parsed file.
fn decode_parsed(parsed: &Parsed, options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    let o = orientation(&parsed.container);
    if o.is_identity() {
        return decode_impl(parsed, options, Output::Sink(sink));
    }
    let mut oriented = OrientSink::new(sink, o, &options.limits);
    decode_impl(parsed, options, Output::Sink(&mut oriented))?;
    oriented.finish()
}

/// [`decode_rows`] from a file (from `input`'s position to its end), read as it decodes: the
/// container and the codestream headers, then each packet through a window of the file (see
/// `source`), so that the file is never held whole. Same rows, same errors. HD Photo 1.0
/// codestreams (sub-version 0), whose transform may need every macroblock's quantizer first,
/// are read whole.
///
/// The option `window=N` sets the least bytes of the windows of the packets of a tile row,
/// together (default 65536, which keeps reads large; 0: only what the bound per macroblock
/// needs).
pub fn decode_rows_from(input: &mut dyn ReadSeek, options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    let mut tuning = Tuning::default();
    if let Some(n) = options.parse_option::<usize>("window")? {
        tuning.min_window = n;
    }
    decode_rows_from_tuned(input, options, sink, tuning)
}

/// [`decode_rows_from`] with windows sized and moved as `tuning` says (tests force them
/// small).
pub(crate) fn decode_rows_from_tuned(
    input: &mut dyn ReadSeek,
    options: &DecodeOptions,
    sink: &mut dyn RowSink,
    tuning: Tuning,
) -> Result<()> {
    let limits = &options.limits;
    let (start, _) = hdrcodec_core::remaining_len(input)?;
    let headers = crate::container::read_headers(input, limits, 64 << 10, true)?;
    let container = headers.head.container()?;
    if std::iter::once(&headers.image).chain(headers.alpha.as_ref()).any(|c| c.image.sub_version == 0) {
        input.seek(std::io::SeekFrom::Start(start))?;
        let data = hdrcodec_core::read_rest(input, limits)?;
        return decode_rows(&data, options, sink);
    }
    let mut ranges = headers.head.codestream_ranges();
    let (image, alpha) = (ranges.next(), ranges.next());
    let image = image.ok_or_else(|| Error::invalid("JPEG XR: no image codestream (a bug in the decoder)"))?;
    let file = SharedFile::new(input, limits, tuning);
    let source = |r: &Range<u64>| Source::File { file: &file, start: start + r.start, len: r.end - r.start };
    let parsed = Parsed {
        cs: headers.image,
        planar: headers.alpha,
        image: source(&image),
        alpha: alpha.as_ref().map(source),
        container,
    };
    decode_parsed(&parsed, options, sink)
}

/// A file's container and codestream headers, and where the codestreams' bytes are.
struct Parsed<'a> {
    container: Container<'a>,
    /// The primary codestream's headers.
    cs: Codestream,
    /// The planar alpha codestream's.
    planar: Option<Codestream>,
    image: Source<'a>,
    alpha: Option<Source<'a>>,
}

impl<'a> Parsed<'a> {
    /// A file held in memory.
    fn memory(data: &'a [u8]) -> Result<Self> {
        let container = parse_container(data)?;
        let cs = header::parse(container.image)?;
        let planar = container.alpha.map(header::parse).transpose()?;
        Ok(Parsed { image: container.image.into(), alpha: container.alpha.map(Source::Memory), container, cs, planar })
    }
}

/// The orientation a decoded image is given: the container's SPATIAL_XFRM_PRIMARY (bit 2
/// rotate 90° clockwise first, bit 1 flip horizontally, bit 0 flip vertically); none without
/// it. jxrlib's glue does the same (JXR-NOTES §7), though its JxrDecApp overrides the result
/// with its `-O` option (default none), and [`decode_raw`] keeps the stored orientation.
pub fn orientation(container: &Container) -> Orientation {
    let code = container.orientation.unwrap_or(0);
    Orientation { rotate_cw: code & 4 != 0, flip_h: code & 2 != 0, flip_v: code & 1 != 0 }
}

/// The size of [`decode_raw`]'s output: width, height and bytes per row (rows packed) of
/// the image in its own pixel format, from the headers alone.
pub fn raw_layout(data: &[u8]) -> Result<(u32, u32, usize)> {
    let container = parse_container(data)?;
    let cs = header::parse(container.image)?;
    let (width, height) = (cs.image.width, cs.image.height);
    let bits = u64::from(width) * u64::from(container.pixel_format.bits_per_pixel);
    let row = usize::try_from(bits.div_ceil(8)).map_err(|_| Error::limit("JPEG XR: a row's size overflows"))?;
    Ok((width, height, row))
}

/// Decodes a whole `.jxr` file to jxrlib's output samples (the pixel format's bytes, row by
/// row, in the stored orientation, as JxrDecApp writes them), for comparing with jxrlib.
pub fn decode_raw(data: &[u8], options: &DecodeOptions) -> Result<Vec<u8>> {
    let (_, height, row) = raw_layout(data)?;
    let size = row as u64 * u64::from(height);
    let _charge = options.limits.charge(size, "the decoded JPEG XR samples")?;
    let size = usize::try_from(size).map_err(|_| Error::limit("JPEG XR: the image's size overflows"))?;
    let mut bytes = vec![0; size];
    decode_impl(&Parsed::memory(data)?, options, Output::Raw { buf: &mut bytes, stride: row })?;
    Ok(bytes)
}

/// [`decode_raw`] into the caller's buffer: row `y` at `out[y · stride ..]`, [`raw_layout`]
/// giving the size to allocate. A buffer too small for the image is refused before any row
/// is written; bytes between rows are left as they are.
pub fn decode_raw_into(data: &[u8], options: &DecodeOptions, out: &mut [u8], stride: usize) -> Result<()> {
    let (_, height, row) = raw_layout(data)?;
    let needed = (height as usize).checked_sub(1).map_or(Some(0), |h| h.checked_mul(stride)?.checked_add(row));
    if stride < row || needed.is_none_or(|n| n > out.len()) {
        return Err(Error::invalid(format!(
            "a buffer of {} bytes with a stride of {stride} cannot hold {height} rows of {row} bytes",
            out.len()
        )));
    }
    decode_impl(&Parsed::memory(data)?, options, Output::Raw { buf: out, stride })
}

/// Where decoded rows go.
enum Output<'a> {
    /// jxrlib's raw samples, row `y` at `buf[y · stride ..]` (the caller checked the size).
    Raw { buf: &'a mut [u8], stride: usize },
    /// Linear f32 rows.
    Sink(&'a mut dyn RowSink),
}

/// Rows that formatting writes to (row `i` of them at `buf[i · stride ..]`): raw samples, or
/// linear f32 samples (each row formatted into a raw row first, then converted).
enum RowsOut<'d> {
    Raw { buf: &'d mut [u8], stride: usize },
    F32 { buf: &'d mut [f32], stride: usize },
}

impl<'d> RowsOut<'d> {
    /// Cut into pieces of `rows` rows each (the last may be shorter).
    fn split(self, rows: usize) -> Vec<RowsOut<'d>> {
        let rows = rows.max(1);
        match self {
            RowsOut::Raw { buf, stride } => {
                buf.chunks_mut((rows * stride).max(1)).map(|buf| RowsOut::Raw { buf, stride }).collect()
            }
            RowsOut::F32 { buf, stride } => {
                buf.chunks_mut((rows * stride).max(1)).map(|buf| RowsOut::F32 { buf, stride }).collect()
            }
        }
    }
}

/// The working buffers of one formatting job: the upsampled chroma rows (subsampled
/// channels only) and a raw row (f32 output).
#[derive(Default)]
struct FormatBufs {
    full: Vec<Vec<i32>>,
    raw: Vec<u8>,
}

fn decode_impl(parsed: &Parsed, options: &DecodeOptions, mut output: Output<'_>) -> Result<()> {
    let (container, cs, planar_cs) = (&parsed.container, &parsed.cs, &parsed.planar);
    let format = container.pixel_format;
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
    let colour = crate::colour::file_colour(container);
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
    let channels = match (&output, out.linear_channels()) {
        (Output::Sink(_), n) => Channels::from_count(n?).ok_or_else(|| Error::unsupported("channels"))?,
        (Output::Raw { .. }, _) => Channels::Rgb,
    };
    out.transfer = colour.transfer;
    let mut info = ImageInfo::new(img.width, img.height, channels, colour.color).with_format(format.name);
    info.metadata = colour.metadata;
    let (width, height) = (img.width as usize, img.height as usize);
    let (mb_w, mb_h) = (img.mb_width as usize, img.mb_height as usize);
    // Planar alpha is transformed as its own codestream says; interleaved alpha as the
    // primary.
    let (overlap, hard) = transform::image_geometry(img);
    let (alpha_overlap, alpha_hard) =
        planar_cs.as_ref().map_or((overlap, hard.clone()), |p| transform::image_geometry(&p.image));
    // The operators follow each codestream's sub-version (HD Photo 1.0: the legacy set).
    let params = |scaled: bool, operators: OperatorSet, (overlap, hard): (OverlapMode, &Option<HardEdges>)| {
        TransformParams { overlap, scaled, hard: hard.clone(), operators }
    };
    // The decoders: the primary's (which also gives an interleaved alpha plane), the planar
    // alpha codestream's; and the windows of coefficients each channel's transform reads.
    let mut prim_dec = RowDecoder::from_source(cs, parsed.image, options)?;
    let (alpha_fmt, alpha_scaled) = match (&cs.alpha, &planar_cs) {
        (Some(a), _) => (a.clr_fmt, a.scaled),
        (None, Some(p)) => (p.primary.clr_fmt, p.primary.scaled),
        (None, None) => (ClrFmt::YOnly, false),
    };
    let mut alpha_dec = match (planar_cs, parsed.alpha) {
        (Some(p), Some(bytes)) if format.alpha && cs.alpha.is_none() => {
            Some(RowDecoder::from_source(p, bytes, options)?)
        }
        _ => None,
    };
    let with_alpha = format.alpha && (cs.alpha.is_some() || alpha_dec.is_some());
    let prim_params =
        params(primary.scaled, OperatorSet::for_plane(cs, container.image, 0, options)?, (overlap, &hard));
    // (From a file, `container.image` and `alpha` hold only the first bytes of each codestream:
    // only HD Photo 1.0's operators read further, and such files are decoded from memory.)
    let alpha_ops = match (&cs.alpha, planar_cs) {
        (Some(_), _) if with_alpha => OperatorSet::for_plane(cs, container.image, 1, options)?,
        (None, Some(p)) if with_alpha => OperatorSet::for_plane(p, container.alpha.unwrap_or_default(), 0, options)?,
        _ => OperatorSet::JpegXr,
    };
    let alpha_params = params(alpha_scaled, alpha_ops, (alpha_overlap, &alpha_hard));
    // Working memory. One thread: the window (the band and its halo of coefficient rows),
    // one band of samples and, for a sink that takes copies, a few formatted rows; every step
    // of a band runs after the one before, so nothing else is held. Two threads: the next
    // band's rows being decoded too, a band of formatted rows for a sink that takes copies,
    // and each formatting job's rows. (A small image has fewer rows than that.)
    let parallel = options.pool.is_parallel();
    // A whole image on one thread, shorter than SHORT_IMAGE_MB_ROWS: bands of SHORT_BAND_MB_ROWS,
    // so that the working set (the band's coefficients and halo, its samples) stays a small
    // share of the image, at the cost of recomputing the transform's halo twice as often.
    let short = !parallel && matches!(output, Output::Sink(_)) && mb_h < SHORT_IMAGE_MB_ROWS;
    let band = if short { SHORT_BAND_MB_ROWS } else { transform::BAND_MB_ROWS }.min(mb_h);
    let halo_below = if primary.clr_fmt == ClrFmt::Yuv420 { 3 } else { 2 };
    let coeff_rows = (if parallel { 2 * band } else { band } + 2 + halo_below).min(mb_h + 2);
    let coeff_bytes = (coeff_rows * mb_w * (primary.channels + 1) * crate::mb::MB_COEFFS * 4) as u64;
    let sample_rows = ((band + 1) * 16).min(mb_h * 16 + 8);
    let full_rows = if parallel { FORMAT_JOBS } else { 1 } * primary.channels * 16 * mb_w * 4;
    let mut win = Window { first: 0, rows: VecDeque::with_capacity(band + 5) };
    if let Output::Sink(s) = &mut output {
        s.start(&info)?;
    }
    // Rows are formatted straight into the caller's rows where it can take them in place (a
    // raw buffer, or a sink of contiguous f32 rows).
    let in_place = match &mut output {
        Output::Raw { .. } => true,
        Output::Sink(s) => s.rows_mut(0, img.height).is_some(),
    };
    // Rows in the pixel format's bytes: in place, a row per formatting job (f32 rows are
    // formatted into one, then converted); else a band's of them (two threads) or a few.
    let raw_rows_held = match (in_place, parallel) {
        (true, true) => FORMAT_JOBS,
        (true, false) => 1,
        (false, true) => band * 16 + FORMAT_JOBS,
        (false, false) => FORMAT_CHUNK,
    };
    let sample_bytes = (sample_rows * mb_w * 16 * 4 * (primary.channels + 1) + full_rows) as u64
        + (raw_rows_held * out.row_bytes(width)) as u64;
    let _charge = options.limits.charge(coeff_bytes + sample_bytes, "the JPEG XR band buffers")?;
    let [top, left, _, _] = img.margins.map(|m| m as usize);
    let ext_w = 16 * mb_w;
    let row_len = width * channels.count();
    // The formatting jobs' buffers: upsampled chroma rows only where chroma is subsampled.
    let subsampled = |ch: usize| ch > 0 && kind(primary.clr_fmt, ch) != PlaneKind::Full;
    let format_bufs = || FormatBufs {
        full: (0..primary.channels).map(|ch| if subsampled(ch) { vec![0i32; ext_w] } else { Vec::new() }).collect(),
        raw: Vec::new(),
    };
    let mut job_bufs: Vec<FormatBufs> = Vec::new();
    let mut full = format_bufs();
    // For a sink that takes copies, rows in the pixel format's bytes: a few at a time (one
    // thread), or a band's (two threads: formatted in the pipeline step, handed out after it).
    let raw_row = out.row_bytes(width);
    let mut raw_band: Vec<u8> = Vec::new();
    let mut scratch = Scratch::new(&options.limits);
    // Coefficients of rows up to r1 + 2 for the band r0..r1 (the transform's halo), 4:2:0
    // one more (its chroma bands end a row lower).
    let need = |r1: usize| (r1 + halo_below).min(mb_h);
    // In frequency order with flexbits, the FLEXBITS packet is decoded with the transform
    // (thread B), a band behind the DC, LP and HP packets (thread A).
    let deferred = RowDecoder::can_defer_flex(cs);
    let mut completer = deferred.then(|| RowCompleter::new(cs, parsed.image, options.pool.clone()));
    // Row and sample buffers go back to these once used, so that a band reuses the memory of
    // the band before (fresh allocations of this size cost page faults and zeroing).
    let mut spare_rows: Vec<Fetched> = Vec::new();
    let mut spare_samples: Vec<BandScratch> = Vec::new();
    // The image rows of the band starting at macroblock row r0 (inside the window's margins).
    let band_rows = |r0: usize| {
        let (y_start, y_end) = ((r0 * 16).max(top), ((r0 + band).min(mb_h) * 16).min(top + height));
        (y_start, y_end.saturating_sub(y_start))
    };
    // Rows `part` of a band (counted from its first image row) in the pixel format's bytes.
    // Full-resolution channels are read where the transform left them; subsampled chroma is
    // upsampled into a row of its own (4:2:0: from the band's chroma rows and the next band's
    // first macroblock row).
    let out = &out;
    let format_rows = |t: &Transformed, part: Range<usize>, bufs: &mut FormatBufs, dst: &mut RowsOut| -> Result<()> {
        let (y_start, _) = band_rows(t.r0);
        let FormatBufs { full, raw: raw_f32 } = bufs;
        let bug = || Error::invalid("JPEG XR: a row past the output rows (a bug in the decoder)");
        for (n, i) in part.enumerate() {
            let local = y_start + i - t.r0 * 16;
            for (ch, p) in t.planes.iter().enumerate().filter(|&(ch, _)| subsampled(ch)) {
                upsample_chroma_row(internal, p.samples(), p.width, p.height, local, &mut full[ch])?;
            }
            let channels: Vec<&[i32]> = t
                .planes
                .iter()
                .zip(full.iter())
                .enumerate()
                .map(|(ch, (p, f))| if subsampled(ch) { &f[left..] } else { &p.row(local)[left..] })
                .collect();
            let a = t.alpha.as_ref().map(|p| &p.row(local)[left..]);
            match dst {
                RowsOut::Raw { buf, stride } => {
                    let raw = buf.get_mut(n * *stride..).and_then(|b| b.get_mut(..raw_row)).ok_or_else(bug)?;
                    out.format_row(&channels, a, width, raw)?;
                }
                RowsOut::F32 { buf, stride } => {
                    raw_f32.resize(raw_row, 0);
                    out.format_row(&channels, a, width, raw_f32)?;
                    let d = buf.get_mut(n * *stride..).and_then(|b| b.get_mut(..row_len)).ok_or_else(bug)?;
                    out.row_to_f32(raw_f32, width, d)?;
                }
            }
        }
        Ok(())
    };
    // Rows `part` of a band into `raw_band` (one thread).
    let format_band = |t: &Transformed, part: Range<usize>, full: &mut FormatBufs, raw_band: &mut Vec<u8>| {
        raw_band.resize(part.len() * raw_row, 0);
        format_rows(t, part, full, &mut RowsOut::Raw { buf: raw_band, stride: raw_row })
    };
    // A whole band into `dst` (two threads): jobs of FORMAT_JOB_ROWS rows each, which ever
    // thread is free takes.
    let format_jobs = |t: &Transformed, dst: RowsOut, bufs: &mut Vec<FormatBufs>| -> Result<()> {
        let rows = band_rows(t.r0).1;
        let pieces = dst.split(FORMAT_JOB_ROWS);
        if pieces.len() != rows.div_ceil(FORMAT_JOB_ROWS) {
            return Err(Error::invalid("JPEG XR: the output rows do not match the band (a bug in the decoder)"));
        }
        if bufs.len() < pieces.len() {
            bufs.resize_with(pieces.len(), format_bufs);
        }
        let mut jobs: Vec<(usize, RowsOut, &mut FormatBufs)> =
            pieces.into_iter().zip(bufs.iter_mut()).enumerate().map(|(i, (d, b))| (i, d, b)).collect();
        options.pool.try_for_each_chunk_mut(&mut jobs, 1, |_, j| {
            let (i, dst, bufs) = &mut j[0];
            let start = *i * FORMAT_JOB_ROWS;
            format_rows(t, start..(start + FORMAT_JOB_ROWS).min(rows), bufs, dst)
        })
    };
    // The image rows of the band from macroblock row `r0`.
    let row_sizes = (raw_row, row_len);
    let band_dst = |r0: usize| {
        let (y_start, rows) = band_rows(r0);
        (y_start - top)..(y_start - top + rows)
    };
    // Hands rows `part` of a band formatted into `raw_band` to the caller.
    let deliver = |t: &Transformed, part: Range<usize>, raw_band: &[u8], output: &mut Output, scratch: &mut Scratch| {
        if part.is_empty() {
            return Ok(());
        }
        let y0 = band_rows(t.r0).0 - top + part.start;
        let raws = raw_band.chunks_exact(raw_row.max(1)).take(part.len());
        match output {
            // Raw rows are always formatted in place.
            Output::Raw { .. } => {
                Err(Error::invalid("JPEG XR: raw rows handed out after a step (a bug in the decoder)"))
            }
            Output::Sink(s) => {
                fill_rows(&mut **s, y0 as u32, part.len() as u32, row_len, scratch, |dst: &mut [f32]| {
                    raws.zip(dst.chunks_exact_mut(row_len)).try_for_each(|(raw, d)| out.row_to_f32(raw, width, d))
                })
            }
        }
    };
    let mut decoded = need(band.min(mb_h));
    let mut pending = fetch(&mut prim_dec, alpha_dec.as_mut(), deferred, decoded, &mut spare_rows)?;
    for r0 in (0..mb_h).step_by(band) {
        let r1 = (r0 + band).min(mb_h);
        let next = need((r1 + band).min(mb_h));
        // The rows before r0 − 2 are no band's any more: their buffers take the next rows.
        win.drop_before(r0.saturating_sub(2), &mut spare_rows);
        let rows_in = std::mem::take(&mut pending);
        let mut sample_bufs = std::mem::take(&mut spare_samples);
        let (win_ref, completer_ref) = (&mut win, &mut completer);
        let (prim_params, alpha_params) = (&prim_params, &alpha_params);
        let pool = &options.pool;
        let transform_all = move || -> Result<Transformed> {
            // The rows this band needs: completed (flexbits) and appended to the window.
            for mut row in rows_in {
                if let Some(c) = completer_ref.as_mut() {
                    c.complete(&mut row.planes, &row.side)?;
                }
                win_ref.rows.push_back(row);
            }
            let win = &*win_ref;
            let prim_rows = win.plane_rows(WindowPlane::Primary)?;
            let prim_src = |ch: usize| {
                MbRows::new(&prim_rows, win.first, primary.channels * crate::mb::MB_COEFFS, ch * crate::mb::MB_COEFFS)
            };
            // Each channel's transform is a job of its own: on two threads, the channels of a
            // band share both cores with the other thread's work (entropy decoding of tile
            // columns, formatting).
            let mut jobs: Vec<BandJob> = (0..primary.channels)
                .map(|ch| {
                    let end = if ch > 0 && primary.clr_fmt == ClrFmt::Yuv420 { (r1 + 1).min(mb_h) } else { r1 };
                    let scratch = sample_bufs.pop().unwrap_or_default();
                    BandJob {
                        src: prim_src(ch),
                        params: prim_params,
                        fmt: primary.clr_fmt,
                        ch,
                        rows: r0..end,
                        scratch,
                        done: None,
                    }
                })
                .collect();
            let alpha_rows = if with_alpha { Some(win.plane_rows(WindowPlane::Alpha)?) } else { None };
            if let Some(rows) = &alpha_rows {
                let src = MbRows::new(rows, win.first, crate::mb::MB_COEFFS, 0);
                let scratch = sample_bufs.pop().unwrap_or_default();
                jobs.push(BandJob {
                    src,
                    params: alpha_params,
                    fmt: alpha_fmt,
                    ch: 0,
                    rows: r0..r1,
                    scratch,
                    done: None,
                });
            }
            let run = |job: &mut BandJob| -> Result<()> {
                let scratch = std::mem::take(&mut job.scratch);
                job.done =
                    Some(transform_band(&job.src, job.params, job.fmt, job.ch, mb_w, mb_h, job.rows.clone(), scratch)?);
                Ok(())
            };
            if parallel {
                pool.try_for_each_chunk_mut(&mut jobs, 1, |_, j| run(&mut j[0]))?;
            } else {
                jobs.iter_mut().try_for_each(run)?;
            }
            let mut planes = Vec::with_capacity(jobs.len());
            for job in jobs {
                planes.push(job.done.ok_or_else(|| Error::invalid("JPEG XR: a channel not transformed (a bug)"))?);
            }
            let alpha = if with_alpha { planes.pop() } else { None };
            Ok(Transformed { r0, planes, alpha, spare: sample_bufs })
        };
        let count = next - decoded;
        decoded = next;
        if !parallel {
            // One thread: transform the band, hand out its rows a few at a time, then decode
            // the next band's rows into the buffers of the rows it no longer needs.
            let t = transform_all()?;
            let rows = band_rows(r0).1;
            for start in (0..rows).step_by(FORMAT_CHUNK) {
                let part = start..(start + FORMAT_CHUNK).min(rows);
                if in_place {
                    // Straight into the caller's rows.
                    let y0 = band_dst(r0).start + start;
                    let mut dst = rows_out(&mut output, y0..y0 + part.len(), row_sizes, true, &mut raw_band)?;
                    format_rows(&t, part, &mut full, &mut dst)?;
                    continue;
                }
                format_band(&t, part.clone(), &mut full, &mut raw_band)?;
                deliver(&t, part, &raw_band, &mut output, &mut scratch)?;
            }
            spare_samples.extend(t.into_buffers());
            win.drop_before(r1.saturating_sub(2), &mut spare_rows);
            pending = fetch(&mut prim_dec, alpha_dec.as_mut(), deferred, count, &mut spare_rows)?;
            continue;
        }
        // One thread entropy-decodes the next band's rows; the other transforms this band and
        // then formats it, in jobs (channels, then pieces of rows) that the first takes once it
        // is done: the formatting jobs, short, come last and fill the end of the step.
        let spare = &mut spare_rows;
        let dst = rows_out(&mut output, band_dst(r0), row_sizes, in_place, &mut raw_band)?;
        let bufs = &mut job_bufs;
        let transform_and_format = || -> Result<Transformed> {
            let t = transform_all()?;
            format_jobs(&t, dst, bufs)?;
            Ok(t)
        };
        let fetch_next = || fetch(&mut prim_dec, alpha_dec.as_mut(), deferred, count, spare);
        let (fetched, this_band) = options.pool.join(fetch_next, transform_and_format);
        let t = this_band?;
        pending = fetched?;
        if !in_place {
            deliver(&t, 0..band_rows(t.r0).1, &raw_band, &mut output, &mut scratch)?;
        }
        spare_samples.extend(t.into_buffers());
    }
    Ok(())
}

/// Where two threads format image rows `rows`: the caller's rows when they can be written in
/// place (`in_place`), else `raw_band` (handed out after the pipeline step). `sizes`: the bytes
/// of a raw row and the samples of a linear row.
fn rows_out<'d>(
    output: &'d mut Output,
    rows: Range<usize>,
    (raw_row, row_len): (usize, usize),
    in_place: bool,
    raw_band: &'d mut Vec<u8>,
) -> Result<RowsOut<'d>> {
    let bug = || Error::invalid("JPEG XR: a band past the caller's buffer (a bug in the decoder)");
    let n = rows.len();
    Ok(match output {
        _ if n == 0 => RowsOut::Raw { buf: &mut [], stride: raw_row },
        Output::Raw { buf, stride } => {
            let range = rows.start * *stride..(rows.end - 1) * *stride + raw_row;
            RowsOut::Raw { buf: buf.get_mut(range).ok_or_else(bug)?, stride: *stride }
        }
        Output::Sink(s) if in_place => RowsOut::F32 {
            buf: s.rows_mut(rows.start as u32, n as u32).and_then(|b| b.get_mut(..n * row_len)).ok_or_else(bug)?,
            stride: row_len,
        },
        Output::Sink(_) => {
            raw_band.resize(n * raw_row, 0);
            RowsOut::Raw { buf: raw_band, stride: raw_row }
        }
    })
}

/// Image rows formatted and handed out at a time on one thread.
const FORMAT_CHUNK: usize = 8;

/// Image rows of one formatting job on two threads.
const FORMAT_JOB_ROWS: usize = 16;

/// The most formatting jobs of a band on two threads.
const FORMAT_JOBS: usize = transform::BAND_MB_ROWS * 16 / FORMAT_JOB_ROWS;

/// Images shorter than this many macroblock rows (1024 pixels) decoded whole on one thread
/// ([`decode_rows`]) are transformed in bands of [`SHORT_BAND_MB_ROWS`]: on GoldenGate
/// (54 rows) the peak falls from 1.60x to 1.45x of the decoded image, for 1% more
/// instructions lossless and 3% at q 0.3. [`decode_raw`] and [`decode_raw_into`] (the
/// speed benchmark's path) and two threads keep bands of [`transform::BAND_MB_ROWS`].
const SHORT_IMAGE_MB_ROWS: usize = 64;

/// See [`SHORT_IMAGE_MB_ROWS`].
const SHORT_BAND_MB_ROWS: usize = 4;

/// The inverse transform of one channel of a band: its coefficients, parameters, channel and
/// macroblock rows, the buffers to write into, and what it gave.
struct BandJob<'w> {
    src: MbRows<'w>,
    params: &'w TransformParams,
    fmt: ClrFmt,
    ch: usize,
    rows: Range<usize>,
    scratch: BandScratch,
    done: Option<BandPlane>,
}

/// A band after the inverse transform: its first macroblock row, each channel's samples, and
/// the sample buffers it did not use.
struct Transformed {
    r0: usize,
    planes: Vec<BandPlane>,
    alpha: Option<BandPlane>,
    spare: Vec<BandScratch>,
}

impl Transformed {
    /// Every sample buffer, for the next bands.
    fn into_buffers(self) -> impl Iterator<Item = BandScratch> {
        self.planes.into_iter().chain(self.alpha).map(|p| p.scratch).chain(self.spare)
    }
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
/// buffers of rows from `spare` while there are some; the tile columns of the primary
/// codestream each as one job of the pool.
fn fetch(
    prim: &mut RowDecoder,
    alpha: Option<&mut RowDecoder>,
    deferred: bool,
    n: usize,
    spare: &mut Vec<Fetched>,
) -> Result<Vec<Fetched>> {
    let mut rows: Vec<Fetched> = (0..n)
        .map(|_| spare.pop().unwrap_or_else(|| Fetched { planes: Vec::new(), side: Vec::new(), planar_alpha: None }))
        .collect();
    let mut outs = Vec::with_capacity(n);
    let mut sides = Vec::with_capacity(n);
    for Fetched { planes, side, .. } in rows.iter_mut() {
        planes.resize_with(2, Vec::new);
        side.resize_with(if deferred { 2 } else { 0 }, Vec::new);
        outs.push(&mut planes[..]);
        sides.push(&mut side[..]);
    }
    prim.next_rows(&mut outs, deferred.then_some(sides))?;
    if let Some(dec) = alpha {
        let past = || Error::invalid("JPEG XR: rows past the image (a bug in the decoder)");
        for row in &mut rows {
            let mut b = vec![row.planar_alpha.take().unwrap_or_default()];
            dec.next_row(&mut b)?.ok_or_else(past)?;
            row.planar_alpha = b.pop();
        }
    }
    Ok(rows)
}

/// A band's samples of one channel: `height` rows of `width` from `start` in the scratch.
struct BandPlane {
    width: usize,
    height: usize,
    start: usize,
    scratch: BandScratch,
}

impl BandPlane {
    /// The band's samples, row-major.
    fn samples(&self) -> &[i32] {
        &self.scratch.data[self.start..][..self.width * self.height]
    }

    /// Row `y` of the band.
    fn row(&self, y: usize) -> &[i32] {
        &self.samples()[y * self.width..][..self.width]
    }
}

/// The samples of macroblock rows `rows` of channel `ch` of a plane, from the coefficients
/// `src`, in `scratch` (buffers to reuse; their contents do not matter).
#[allow(clippy::too_many_arguments)]
fn transform_band(
    src: &MbRows,
    params: &TransformParams,
    fmt: ClrFmt,
    ch: usize,
    mb_w: usize,
    mb_h: usize,
    rows: std::ops::Range<usize>,
    mut scratch: BandScratch,
) -> Result<BandPlane> {
    let k = kind(fmt, ch);
    let (bx, by) = k.blocks();
    let (width, height) = (bx * 4 * mb_w, by * 4 * rows.len());
    let request = BandRequest { params, kind: k, channel: ch, mb_w, mb_h, coeffs: src, rows };
    let start = transform::inverse_band_rows(&request, &mut scratch)?;
    Ok(BandPlane { width, height, start, scratch })
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

    /// Damaged files (truncated, bits flipped) give the same result on one thread and on two
    /// (where the band pipeline, the tile columns and the transform's channels run as jobs of
    /// the pool): the same samples, or an error on both, never a panic.
    #[test]
    fn damaged_files_decode_alike_on_one_and_two_threads() {
        let two = hdrcodec_core::ThreadPool::new(2).unwrap();
        for name in ["tiny_tiles.jxr", "tiny_420_sp.jxr", "t835_hard_2x2.jxr", "tiny_alpha_sp.jxr"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
            let file = std::fs::read(path).unwrap();
            let decode = |bytes: &[u8], pool: &hdrcodec_core::ThreadPool| {
                decode_raw(bytes, &DecodeOptions::new(Limits::default()).with_pool(pool.clone())).ok()
            };
            let mut next = crate::testing::rng(file.len() as u64);
            let mut bad = file.clone();
            let mut outcomes = [0; 2];
            for i in 0..120 {
                let damaged: &[u8] = if i % 3 == 0 {
                    &file[..(next() % file.len() as u64) as usize]
                } else {
                    bad.copy_from_slice(&file);
                    let at = (next() % file.len() as u64) as usize;
                    bad[at] ^= 1 << (next() % 8);
                    &bad
                };
                let one = decode(damaged, &hdrcodec_core::ThreadPool::single());
                outcomes[usize::from(one.is_some())] += 1;
                assert_eq!(one, decode(damaged, &two), "{name}, case {i}");
            }
            // Both kinds of outcome occur: samples from damaged data, and errors.
            assert!(outcomes[0] > 0 && outcomes[1] > 0, "{name}: {outcomes:?}");
        }
    }

    /// Two threads format each band straight into the caller's rows (a raw buffer with a
    /// stride, an image, an unpadded f32 buffer) or, for a sink that takes copies (a padded
    /// f32 or an f16 buffer), into a band handed out after each step: every way gives one
    /// thread's samples and leaves the padding alone. The image is several bands high, each
    /// several formatting jobs, with alpha; 4:4:4 in one tile and 4:2:0 in tiles.
    #[test]
    fn two_threads_deliver_every_way_as_one_thread() {
        use crate::encoder::{encode, EncodeOptions, Subsampling};
        use hdrcodec_core::sink::FrameBufMut;
        use hdrcodec_core::{ColorInfo, HdrImage, ImageCodec, ThreadPool};
        let (w, h) = (200usize, 300usize);
        let mut next = crate::testing::rng(11);
        let samples: Vec<f32> =
            (0..w * h * 4).map(|i| ((i % (w * 4)) as f32 / 300.0) + (next() % 1000) as f32 / 4000.0).collect();
        let image = HdrImage::new(w as u32, h as u32, Channels::Rgba, samples, ColorInfo::default()).unwrap();
        let one = DecodeOptions::new(Limits::default());
        let two = DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(2).unwrap());
        for (subsampling, tile_mbs) in [(Subsampling::Yuv444, 0), (Subsampling::Yuv420, 5)] {
            let options = EncodeOptions { quality: 70, subsampling, tile_mbs, ..EncodeOptions::default() };
            let file = encode(&image, &options, &ThreadPool::single()).unwrap().0;
            let raw = decode_raw(&file, &one).unwrap();
            assert_eq!(decode_raw(&file, &two).unwrap(), raw);
            let (_, height, row) = raw_layout(&file).unwrap();
            assert_eq!(height as usize, h);
            let stride = row + 5;
            let mut buf = vec![0xa5u8; stride * h];
            decode_raw_into(&file, &two, &mut buf, stride).unwrap();
            for (y, want) in raw.chunks_exact(row).enumerate() {
                assert_eq!(&buf[y * stride..][..row], want, "{subsampling:?}, raw row {y}");
                assert!(buf[y * stride + row..(y + 1) * stride].iter().all(|&b| b == 0xa5));
            }
            let bits = |v: &[f32]| v.iter().map(|s| s.to_bits()).collect::<Vec<_>>();
            let linear = crate::JxrCodec.decode_with(&file, &one).unwrap();
            assert_eq!(bits(crate::JxrCodec.decode_with(&file, &two).unwrap().samples()), bits(linear.samples()));
            for pad in [0, 3] {
                let stride = w * 4 + pad;
                let mut buf = vec![-1.0f32; stride * h];
                crate::JxrCodec.decode_into(&file, &two, FrameBufMut::f32(&mut buf, stride)).unwrap();
                for y in 0..h {
                    assert_eq!(bits(&buf[y * stride..][..w * 4]), bits(linear.row(y as u32)), "pad {pad}, row {y}");
                    assert!(buf[y * stride + w * 4..(y + 1) * stride].iter().all(|&v| v == -1.0));
                }
            }
            let mut halves = [vec![half::f16::ZERO; w * 4 * h], vec![half::f16::ZERO; w * 4 * h]];
            for (pool, buf) in [&one, &two].into_iter().zip(&mut halves) {
                crate::JxrCodec.decode_into(&file, pool, FrameBufMut::f16(buf, w * 4)).unwrap();
            }
            assert_eq!(halves[0], halves[1]);
        }
    }

    /// The two-thread pipeline (a band transformed and formatted while the next is decoded)
    /// ends as one thread's bands do whatever the image's height: one macroblock row, less
    /// than a band, exactly one or two bands, a band and one row; in one tile and in tiles, in
    /// 4:4:4, 4:2:2 and 4:2:0 (whose chroma reaches a row into the next band), with and
    /// without the flexbits in packets of their own (frequency order, completed on the
    /// transform's side).
    #[test]
    fn two_threads_end_every_band_count_as_one_thread() {
        use crate::encoder::{encode, BitstreamOrder, EncodeOptions, Subsampling};
        use hdrcodec_core::{ColorInfo, HdrImage, ThreadPool};
        let one = DecodeOptions::new(Limits::default());
        let two = DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(2).unwrap());
        let w = 72usize;
        let mut next = crate::testing::rng(7);
        for h in [9usize, 16, 100, 128, 136, 256, 270] {
            let samples: Vec<f32> =
                (0..w * h * 3).map(|i| (i % (w * 3)) as f32 / 150.0 + (next() % 1000) as f32 / 3000.0).collect();
            let image = HdrImage::new(w as u32, h as u32, Channels::Rgb, samples, ColorInfo::default()).unwrap();
            for (subsampling, tile_mbs, order) in [
                (Subsampling::Yuv444, 0, BitstreamOrder::Spatial),
                (Subsampling::Yuv422, 3, BitstreamOrder::Frequency),
                (Subsampling::Yuv420, 2, BitstreamOrder::Spatial),
                (Subsampling::Yuv420, 0, BitstreamOrder::Frequency),
            ] {
                let options = EncodeOptions { quality: 80, subsampling, tile_mbs, order, ..EncodeOptions::default() };
                let file = encode(&image, &options, &ThreadPool::single()).unwrap().0;
                let raw = decode_raw(&file, &one).unwrap();
                assert_eq!(raw.len(), raw_layout(&file).unwrap().2 * h);
                assert_eq!(decode_raw(&file, &two).unwrap(), raw, "height {h}, {subsampling:?}, tiles {tile_mbs}");
            }
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
