//! Decoding part of an image: at 1/4 or 1/16 of the resolution from the low bands alone, and
//! a rectangle of it, as jxrlib's JxrDecApp does with `-T 2`, `-T 4` and `-r`.
//!
//! **Reduced resolution** (jxrlib `strdec.c: setROI, decodeThumbnail`, worked out from its
//! code and checked against JxrDecApp's output). A 1:4 image is one sample per 4×4 block: the
//! block DCs after the second transform stage (the stage-2 PCT of the macroblock's DC and LP
//! coefficients and, with OVERLAP_MODE 2, the stage-2 POT across macroblock seams); the first
//! stage never runs, so HP and FLEXBITS do not matter. A 1:16 image is the macroblock DC
//! coefficients themselves (no transform at all). In frequency order the packets beyond LP
//! (1:4) or DC (1:16) are never read; spatial order has to parse them to reach the next
//! macroblock. jxrlib then scales each value by an approximate DC gain of the skipped stages,
//! `cMul / 256` (1:4: 64 without overlap, 93 with; 1:16: 16, 23 or 34 for OVERLAP_MODE 0, 1,
//! 2) with the output shift folded in (`(v · cMul) >> (8 + 3 when scaled)`), truncating; the
//! bit depth's bias enters as `(bias << shift) / cMul` added before the multiplication, not
//! after. Chroma of 4:4:4 images at 1:16 is not doubled as stage 2 would (scaled arithmetic),
//! so it is shifted one bit less (two for 4:2:0 and 4:2:2). The colour transform and the
//! final conversion are those of full-resolution output, on these already-shifted values.
//!
//! 4:2:0 and 4:2:2 chroma at 1:4: jxrlib puts each chroma block DC at the luma block at its
//! top-left, then fills the others inside each macroblock row: for 4:2:0 the block row between
//! two is their rounded-up mean and the last block row copies the one above (never looking
//! at the next macroblock row); then every other block column is the rounded-up mean of its
//! neighbours (across macroblocks), and the last one copies its left neighbour. At 1:16 the
//! chroma DC is taken as it is.
//!
//! Sizes: `ceil(width / s)` × `ceil(height / s)` for scale `s`; sample `(i, j)` is the block
//! or macroblock holding pixel `(s·i, s·j)` of the image (with windowing: the first multiple
//! of `s` at or after the top and left margins, then every `s`).
//!
//! **Regions** (see [`JxrDecodeRequest::region`]) are in the stored (codestream)
//! orientation, before any orientation the container asks for; for reduced resolutions they
//! are in the reduced image's coordinates, as JxrDecApp's `-r` with `-T`.

use crate::container::{parse_container, OutputBitDepth, OutputColorFormat, PixelFormat};
use crate::decoder::RowDecoder;
use crate::header::{self, ClrFmt, Codestream};
use crate::mb::{MbCoeffs, MB_COEFFS};
use crate::output::{AlphaParams, InternalColorFormat, OutputParams};
use crate::render::{clr_code, kind};
use crate::transform::{self, HardEdges, OperatorSet, OverlapMode, PlaneKind, TransformParams};
use hdrcodec_core::sink::{fill_rows, OrientSink, RowSink, Scratch};
use hdrcodec_core::{Channels, DecodeOptions, Error, ImageInfo, Result};

/// A rectangle of an image, in pixels: columns `x .. x + width`, rows `y .. y + height`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x: u32,
    /// First row.
    pub y: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

/// The resolution to decode at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Resolution {
    /// Every pixel (all bands).
    #[default]
    Full,
    /// 1/4 of the width and height (1/16 of the pixels): the DC and LP bands only, jxrlib's
    /// native `-T 2`.
    Quarter,
    /// 1/16 of the width and height: the DC band only, jxrlib's native `-T 4`.
    Sixteenth,
}

impl Resolution {
    /// Pixels per output sample, each way.
    pub fn scale(self) -> u32 {
        match self {
            Resolution::Full => 1,
            Resolution::Quarter => 4,
            Resolution::Sixteenth => 16,
        }
    }
}

/// What part of an image to decode, and at what resolution. The default is the whole image
/// at full resolution (what [`crate::decode_raw`] gives).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct JxrDecodeRequest {
    /// The rectangle to output, in the **stored (codestream) orientation** (before the
    /// container's SPATIAL_XFRM_PRIMARY is applied) and in the coordinates of the requested
    /// resolution (a region of a quarter-resolution decode is in quarter-resolution pixels).
    /// `None`: all of it. A rectangle that is empty or reaches outside the image is an error.
    pub region: Option<Rect>,
    /// The resolution.
    pub resolution: Resolution,
}

/// The size (stored orientation) a request gives for an image of `width × height`.
pub fn output_size(width: u32, height: u32, request: &JxrDecodeRequest) -> Result<(u32, u32)> {
    let s = request.resolution.scale();
    let (w, h) = (width.div_ceil(s), height.div_ceil(s));
    match request.region {
        None => Ok((w, h)),
        Some(r) => {
            let fits = r.width > 0
                && r.height > 0
                && r.x.checked_add(r.width).is_some_and(|e| e <= w)
                && r.y.checked_add(r.height).is_some_and(|e| e <= h);
            if !fits {
                return Err(Error::invalid(format!(
                    "JPEG XR: the region {}x{} at ({}, {}) is empty or outside the {w}x{h} image",
                    r.width, r.height, r.x, r.y
                )));
            }
            Ok((r.width, r.height))
        }
    }
}

/// Decodes what `request` asks for to jxrlib's output samples (the pixel format's bytes, row
/// by row, in the stored orientation), as JxrDecApp writes them with `-T` and `-r`.
pub fn decode_raw_with(data: &[u8], options: &DecodeOptions, request: &JxrDecodeRequest) -> Result<Vec<u8>> {
    if *request == JxrDecodeRequest::default() {
        return crate::render::decode_raw(data, options);
    }
    let mut bytes = Vec::new();
    decode_request(data, options, request, None, &mut |_, raw| bytes.extend_from_slice(raw))?;
    Ok(bytes)
}

/// Decodes what `request` asks for into `sink` as linear `f32` rows, like
/// [`ImageCodec::decode_rows`](hdrcodec_core::ImageCodec::decode_rows): the result is then
/// given the container's orientation (the region is chosen before it, in stored orientation).
pub fn decode_rows_with(
    data: &[u8],
    options: &DecodeOptions,
    request: &JxrDecodeRequest,
    sink: &mut dyn RowSink,
) -> Result<()> {
    if *request == JxrDecodeRequest::default() {
        return crate::render::decode_rows(data, options, sink);
    }
    let o = crate::render::orientation(&parse_container(data)?);
    if o.is_identity() {
        return decode_request(data, options, request, Some(sink), &mut |_, _| {});
    }
    let mut oriented = OrientSink::new(sink, o, &options.limits);
    decode_request(data, options, request, Some(&mut oriented), &mut |_, _| {})?;
    oriented.finish()
}

/// The headers and everything derived from them that both paths need.
struct Setup<'a> {
    data: &'a [u8],
    alpha_data: Option<&'a [u8]>,
    cs: Codestream,
    planar_cs: Option<Codestream>,
    format: &'static PixelFormat,
    out: OutputParams,
    info: ImageInfo,
    channels: Channels,
    alpha_fmt: ClrFmt,
    alpha_scaled: bool,
    with_alpha: bool,
    overlap: OverlapMode,
    hard: Option<HardEdges>,
    /// Planar alpha's own (interleaved alpha: the primary's).
    alpha_overlap: OverlapMode,
    alpha_hard: Option<HardEdges>,
}

impl<'a> Setup<'a> {
    /// Reads the headers; `unscaled` builds output parameters without the 3-bit shift (the
    /// reduced paths fold it into their own scaling).
    fn new(data: &'a [u8], for_sink: bool, unscaled: bool) -> Result<Self> {
        let container = parse_container(data)?;
        let format = container.pixel_format;
        let cs = header::parse(container.image)?;
        let planar_cs = container.alpha.map(header::parse).transpose()?;
        let img = &cs.image;
        transform::check_operator_set(img.sub_version)?;
        if img.sub_version == 0 || planar_cs.as_ref().is_some_and(|p| p.image.sub_version == 0) {
            // Whole images of these decode (`render`); the region and reduced paths here run
            // JPEG XR's operators only.
            return Err(Error::unsupported(
                "regions and reduced resolutions of HD Photo 1.0 (sub-version 0) files; decode them whole",
            ));
        }
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
        let (alpha_fmt, alpha_scaled) = match (&cs.alpha, &planar_cs) {
            (Some(a), _) => (a.clr_fmt, a.scaled),
            (None, Some(p)) => (p.primary.clr_fmt, p.primary.scaled),
            (None, None) => (ClrFmt::YOnly, false),
        };
        let colour = crate::colour::file_colour(&container);
        let out_alpha = if format.alpha { alpha_params } else { None };
        let mut out = OutputParams::new(
            format,
            bit_depth,
            clr,
            internal,
            primary.scaled && !unscaled,
            primary.shift_or_mantissa,
            primary.exp_bias as i8,
            img.red_blue_not_swapped,
            out_alpha.map(|a| AlphaParams { scaled: a.scaled && !unscaled, ..a }),
        )?;
        let channels = match (for_sink, out.linear_channels()) {
            (true, n) => Channels::from_count(n?).ok_or_else(|| Error::unsupported("channels"))?,
            (false, _) => Channels::Rgb,
        };
        out.transfer = colour.transfer;
        let mut info = ImageInfo::new(img.width, img.height, channels, colour.color).with_format(format.name);
        info.metadata = colour.metadata;
        let (overlap, hard) = transform::image_geometry(img);
        let (alpha_overlap, alpha_hard) =
            planar_cs.as_ref().map_or((overlap, hard.clone()), |p| transform::image_geometry(&p.image));
        let with_alpha = format.alpha && (cs.alpha.is_some() || planar_cs.is_some());
        Ok(Setup {
            data: container.image,
            alpha_data: container.alpha,
            cs,
            planar_cs,
            format,
            out,
            info,
            channels,
            alpha_fmt,
            alpha_scaled,
            with_alpha,
            overlap,
            hard,
            alpha_overlap,
            alpha_hard,
        })
    }

    fn params(&self, scaled: bool) -> TransformParams {
        TransformParams { overlap: self.overlap, scaled, hard: self.hard.clone(), operators: OperatorSet::JpegXr }
    }

    fn alpha_params(&self, scaled: bool) -> TransformParams {
        TransformParams { overlap: self.alpha_overlap, hard: self.alpha_hard.clone(), ..self.params(scaled) }
    }
}

/// Macroblock rows of coefficients, per channel (the primary's, then alpha's), from row
/// `first` on, filled by the entropy decoders as far as asked.
struct Rows<'a> {
    prim: RowDecoder<'a>,
    alpha: Option<RowDecoder<'a>>,
    interleaved_alpha: bool,
    with_alpha: bool,
    mb_w: usize,
    decoded: usize,
    first: usize,
    channels: Vec<Vec<MbCoeffs>>,
    buf: Vec<Vec<i32>>,
    abuf: Vec<Vec<i32>>,
}

impl<'a> Rows<'a> {
    /// The row the primary decoder gives next.
    fn prim_first_row(&self) -> u32 {
        self.prim.next_row_index()
    }

    /// Decodes rows until `end` (exclusive) is available.
    fn decode_to(&mut self, end: usize) -> Result<()> {
        let past = || Error::invalid("JPEG XR: rows past the image (a bug in the decoder)");
        let n = self.channels.len() - usize::from(self.with_alpha);
        while self.decoded < end {
            self.buf.resize_with(2, Vec::new);
            self.prim.next_row(&mut self.buf)?.ok_or_else(past)?;
            for (i, mb) in self.buf[0].chunks_exact(MB_COEFFS).enumerate() {
                self.channels[i % n].push(mb.try_into().expect("a macroblock"));
            }
            if self.with_alpha {
                let a = if self.interleaved_alpha {
                    &self.buf[1]
                } else {
                    self.abuf.resize_with(1, Vec::new);
                    let dec = self.alpha.as_mut().ok_or_else(past)?;
                    dec.next_row(&mut self.abuf)?.ok_or_else(past)?;
                    &self.abuf[0]
                };
                let last = self.channels.last_mut().ok_or_else(past)?;
                last.extend(a.chunks_exact(MB_COEFFS).map(|mb| -> MbCoeffs { mb.try_into().expect("a macroblock") }));
            }
            self.decoded += 1;
        }
        Ok(())
    }

    /// Forgets the rows before `row`.
    fn drop_before(&mut self, row: usize) {
        let k = row.saturating_sub(self.first).min(self.decoded - self.first);
        if k > 0 {
            for c in &mut self.channels {
                c.drain(..k * self.mb_w);
            }
            self.first += k;
        }
    }
}

/// The output columns (or rows) of a reduced decode: for each, the pixel it samples in
/// extended (codestream) coordinates; and jxrlib's `cWidth`, the end of the columns it
/// processes (which the chroma interpolation's right edge depends on). `coded` is the coded
/// width (or height) in pixels, 16 per macroblock: sampling at or past it is refused before the
/// positions are allocated, since a damaged header can ask for billions of them.
fn sample_positions(
    start: u32,
    count: u32,
    scale: u32,
    margin: u32,
    inscribed: u32,
    ext: u32,
    coded: usize,
) -> Result<(Vec<usize>, usize)> {
    // jxrlib: the region's first pixel in extended coordinates, rounded up to the scale.
    let roi0 = start as usize * scale as usize + margin as usize;
    let first = roi0.div_ceil(scale as usize) * scale as usize;
    if count > 0 && first + (count as usize - 1) * scale as usize >= coded {
        return Err(Error::unsupported("JPEG XR: a reduced decode sampling past the coded image (windowing)"));
    }
    let end = (roi0 + count as usize * scale as usize).min(inscribed as usize + ext as usize);
    Ok(((0..count as usize).map(|k| first + k * scale as usize).collect(), end))
}

fn decode_request(
    data: &[u8],
    options: &DecodeOptions,
    request: &JxrDecodeRequest,
    sink: Option<&mut dyn RowSink>,
    raw_rows: &mut dyn FnMut(usize, &[u8]),
) -> Result<()> {
    let setup = Setup::new(data, sink.is_some(), request.resolution != Resolution::Full)?;
    // The image's size against the limits and the codestream's length, before anything sized
    // by the header is allocated (a reduced or windowed decode is no exception).
    crate::decoder::check_size(&setup.cs, setup.data.len() as u64, options)?;
    let img = &setup.cs.image;
    let (ow, oh) = output_size(img.width, img.height, request)?;
    let region = request.region.unwrap_or(Rect { x: 0, y: 0, width: ow, height: oh });
    let mut info = setup.info.clone();
    (info.width, info.height) = (ow, oh);
    match request.resolution {
        Resolution::Full => crate::region::decode_region(&setup_parts(&setup), options, region, info, sink, raw_rows),
        r => decode_reduced(&setup, options, r, region, info, sink, raw_rows),
    }
}

/// What the region decoder takes from the setup.
pub(crate) struct SetupParts<'s, 'a> {
    pub data: &'a [u8],
    pub alpha_data: Option<&'a [u8]>,
    pub cs: &'s Codestream,
    pub planar_cs: Option<&'s Codestream>,
    pub out: &'s OutputParams,
    pub channels: Channels,
    pub alpha_fmt: ClrFmt,
    pub prim_params: TransformParams,
    pub alpha_params: TransformParams,
    pub with_alpha: bool,
}

fn setup_parts<'s, 'a>(s: &'s Setup<'a>) -> SetupParts<'s, 'a> {
    SetupParts {
        data: s.data,
        alpha_data: s.alpha_data,
        cs: &s.cs,
        planar_cs: s.planar_cs.as_ref(),
        out: &s.out,
        channels: s.channels,
        alpha_fmt: s.alpha_fmt,
        prim_params: s.params(s.cs.primary.scaled),
        alpha_params: s.alpha_params(s.alpha_scaled),
        with_alpha: s.with_alpha,
    }
}

/// The entropy decoders and the coefficient rows of a decode, charged to the limits.
pub(crate) fn row_source<'a>(
    cs: &'a Codestream,
    data: &'a [u8],
    planar: Option<(&'a Codestream, &'a [u8])>,
    with_alpha: bool,
    options: &DecodeOptions,
    max_bands: usize,
) -> Result<RowsHandle<'a>> {
    let mut prim = RowDecoder::new(cs, data, options)?;
    prim.limit_bands(max_bands);
    let interleaved_alpha = cs.alpha.is_some();
    let alpha = match planar {
        Some((p, bytes)) if with_alpha && !interleaved_alpha => {
            let mut d = RowDecoder::new(p, bytes, options)?;
            d.limit_bands(max_bands);
            Some(d)
        }
        _ => None,
    };
    let n = cs.primary.channels + usize::from(with_alpha);
    Ok(RowsHandle(Rows {
        prim,
        alpha,
        interleaved_alpha,
        with_alpha,
        mb_w: cs.image.mb_width as usize,
        decoded: 0,
        first: 0,
        channels: (0..n).map(|_| Vec::new()).collect(),
        buf: Vec::new(),
        abuf: Vec::new(),
    }))
}

/// The coefficient rows for another module (the region decoder).
pub(crate) struct RowsHandle<'a>(Rows<'a>);

impl RowsHandle<'_> {
    /// Decodes only the tile columns `keep` marks, from tile row `ty` on (before any row).
    pub fn start(&mut self, keep: Vec<bool>, ty: usize) -> Result<()> {
        let r = &mut self.0;
        r.prim.only_tile_columns(keep.clone());
        r.prim.start_at_tile_row(ty)?;
        if let Some(a) = r.alpha.as_mut() {
            a.only_tile_columns(keep);
            a.start_at_tile_row(ty)?;
        }
        let first: u32 = r.prim_first_row();
        r.decoded = first as usize;
        r.first = first as usize;
        Ok(())
    }
    /// Makes rows `.. end` available.
    pub fn decode_to(&mut self, end: usize) -> Result<()> {
        self.0.decode_to(end)
    }
    /// Forgets the rows before `row`.
    pub fn drop_before(&mut self, row: usize) {
        self.0.drop_before(row)
    }
    /// The first row held.
    pub fn first(&self) -> usize {
        self.0.first
    }
    /// Channel `ch`'s rows (alpha is the last channel).
    pub fn channel(&self, ch: usize) -> &[MbCoeffs] {
        &self.0.channels[ch]
    }
}

/// The constants of jxrlib's reduced-resolution output (see the module documentation).
struct Scaling {
    mul: i32,
    /// Alpha's: planar alpha has its own overlap.
    mul_alpha: i32,
    shift_y: u32,
    shift_uv: u32,
    shift_alpha: u32,
}

#[allow(clippy::too_many_arguments)]
fn decode_reduced(
    setup: &Setup,
    options: &DecodeOptions,
    resolution: Resolution,
    region: Rect,
    info: ImageInfo,
    mut sink: Option<&mut dyn RowSink>,
    raw_rows: &mut dyn FnMut(usize, &[u8]),
) -> Result<()> {
    use OutputBitDepth::*;
    use OutputColorFormat as C;
    let cs = &setup.cs;
    let img = &cs.image;
    let primary = &cs.primary;
    let out = &setup.out;
    let quarter = resolution == Resolution::Quarter;
    let scale = resolution.scale();
    let (mb_w, mb_h) = (img.mb_width as usize, img.mb_height as usize);
    let [top, left, bottom, right] = img.margins;
    let (xs, c_width) = sample_positions(region.x, region.width, scale, left, img.width, left + right, 16 * mb_w)?;
    let (ys, _) = sample_positions(region.y, region.height, scale, top, img.height, top + bottom, 16 * mb_h)?;
    // jxrlib has a reduced path for CMYK, which this does not implement (yet); CMYKDIRECT and
    // YCC output it asserts against.
    if matches!(out.color, C::Cmyk | C::CmykDirect | C::Yuv420 | C::Yuv422) {
        return Err(Error::unsupported(format!("JPEG XR: reduced-resolution output of {}", setup.format.name)));
    }
    let mul_of = |ol: OverlapMode| match (quarter, ol) {
        (true, OverlapMode::None) => 64,
        (true, _) => 93,
        (false, OverlapMode::None) => 16,
        (false, OverlapMode::One) => 23,
        (false, OverlapMode::Two) => 34,
    };
    let (mul, mul_alpha) = (mul_of(setup.overlap), mul_of(setup.alpha_overlap));
    let shift_y = 8 + if primary.scaled { 3 } else { 0 };
    let sub = matches!(primary.clr_fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
    let shift_uv = shift_y
        - if primary.scaled && !quarter {
            if sub {
                2
            } else {
                1
            }
        } else {
            0
        };
    // Interleaved alpha is shifted as the primary plane (jxrlib `decodeThumbnailAlpha`),
    // planar alpha as its own codestream says.
    let alpha_scaled = match (&cs.alpha, &setup.planar_cs) {
        (Some(_), _) => primary.scaled,
        (None, Some(p)) => p.primary.scaled,
        _ => false,
    };
    let sc = Scaling { mul, mul_alpha, shift_y, shift_uv, shift_alpha: 8 + if alpha_scaled { 3 } else { 0 } };

    // Frequency order: the DC (1:16) or DC and LP (1:4) packets only.
    let max_bands = if quarter { 2 } else { 1 };
    let planar = setup.planar_cs.as_ref().zip(setup.alpha_data);
    let mut rows = row_source(cs, setup.data, planar, setup.with_alpha, options, max_bands)?.0;
    let n_prim = primary.channels;
    let n_all = n_prim + usize::from(setup.with_alpha);
    // Memory: about three macroblock rows of coefficients, and the DC rows of one.
    let bytes = (4 * mb_w * n_all * MB_COEFFS * 4 + 16 * mb_w * n_all * 4) as u64;
    let _charge = options.limits.charge(bytes, "the JPEG XR reduced-resolution rows")?;

    let prim_params = setup.params(primary.scaled);
    let alpha_params = setup.alpha_params(setup.alpha_scaled);
    let ow = region.width as usize;
    let row_len = ow * setup.channels.count();
    let mut raw = vec![0u8; out.row_bytes(ow)];
    let mut scratch = Scratch::new(&options.limits);
    if let Some(s) = sink.as_deref_mut() {
        s.start(&info)?;
    }
    // Per channel, one macroblock row's values at the output's block resolution (4 block rows
    // of 4·mb_w for 1:4, one row of mb_w for 1:16).
    let (per_row, width_b) = if quarter { (4, 4 * mb_w) } else { (1, mb_w) };
    let mut vals = vec![vec![0i32; per_row * width_b]; n_all];
    let mut dcband = Vec::new();
    let mut planes_out: Vec<Vec<i32>> = vec![vec![0; ow]; n_prim.max(3)];
    let mut alpha_out = vec![0i32; ow];
    let biases = Biases::new(out);
    let mut oy = 0usize;
    while oy < ys.len() {
        let my = ys[oy] / 16;
        let need_end = if quarter { (my + 2).min(mb_h) } else { my + 1 };
        rows.decode_to(need_end)?;
        rows.drop_before(my.saturating_sub(1));
        // This macroblock row's values.
        for (ch, v) in vals.iter_mut().enumerate() {
            let is_alpha = ch >= n_prim;
            let (fmt, c, params) =
                if is_alpha { (setup.alpha_fmt, 0, &alpha_params) } else { (primary.clr_fmt, ch, &prim_params) };
            let k = kind(fmt, c);
            let coeffs = &rows.channels[ch];
            if !quarter {
                let row = &coeffs[(my - rows.first) * mb_w..][..mb_w];
                for (d, mb) in v.iter_mut().zip(row) {
                    *d = mb[0];
                }
                continue;
            }
            let (bx, by) = k.blocks();
            dcband.resize(bx * mb_w * by, 0);
            transform::inverse_dc_band(params, k, c, mb_w, mb_h, coeffs, rows.first, my..my + 1, &mut dcband)?;
            match k {
                PlaneKind::Full => v.copy_from_slice(&dcband),
                _ => spread_chroma(&dcband, k, mb_w, c_width, v),
            }
        }
        // The output rows in this macroblock row.
        while oy < ys.len() && ys[oy] / 16 == my {
            let by = if quarter { (ys[oy] % 16) / 4 } else { 0 };
            let at = |ch: usize, x: usize| vals[ch][by * width_b + x / scale as usize];
            let rgb = matches!(out.color, C::Rgb | C::Rgbe) && n_prim >= 3;
            for (j, &x) in xs.iter().enumerate() {
                if rgb {
                    let (y, u, v) = (at(0, x), at(1, x), at(2, x));
                    let m = sc.mul;
                    let g = y.wrapping_add(biases.rgb_offset(&sc)).wrapping_mul(m) >> sc.shift_y;
                    let (r, b) = if out.color == C::Rgbe {
                        (-(u.wrapping_mul(m) >> sc.shift_uv), v.wrapping_mul(m) >> sc.shift_uv)
                    } else {
                        (u.wrapping_mul(m).wrapping_neg() >> sc.shift_uv, v.wrapping_mul(m) >> sc.shift_uv)
                    };
                    planes_out[0][j] = g.wrapping_sub(biases.format);
                    planes_out[1][j] = r.wrapping_neg();
                    planes_out[2][j] = b;
                } else if matches!(out.bit_depth, Bd1White1 | Bd1Black1) {
                    // jxrlib thresholds the raw value at zero, unscaled.
                    planes_out[0][j] = at(0, x);
                } else {
                    for (ch, p) in planes_out.iter_mut().enumerate().take(n_prim) {
                        let t = at(ch, x).wrapping_add(biases.nchannel_offset(sc.mul, sc.shift_y)).wrapping_mul(sc.mul)
                            >> sc.shift_y;
                        p[j] = t.wrapping_sub(biases.format);
                    }
                }
                if setup.with_alpha {
                    let offset = biases.nchannel_offset(sc.mul_alpha, sc.shift_alpha);
                    let t = at(n_prim, x).wrapping_add(offset).wrapping_mul(sc.mul_alpha) >> sc.shift_alpha;
                    alpha_out[j] = t.wrapping_sub(biases.alpha);
                }
            }
            let refs: Vec<&[i32]> = planes_out.iter().map(|p| &p[..]).collect();
            out.format_row(&refs, setup.with_alpha.then_some(&alpha_out[..]), ow, &mut raw)?;
            raw_rows(oy, &raw);
            if let Some(s) = sink.as_deref_mut() {
                let raw = &raw;
                fill_rows(s, oy as u32, 1, row_len, &mut scratch, |dst| out.row_to_f32(raw, ow, dst))?;
            }
            oy += 1;
        }
    }
    Ok(())
}

/// jxrlib's 4:2:0 and 4:2:2 chroma at 1:4 (`decodeThumbnail`): the chroma block DCs of one
/// macroblock row (`dc`: 2 per macroblock across, 2 or 4 rows) spread to luma block
/// resolution (`v`: 4 rows of `4·mb_w`). `c_width` is jxrlib's `cWidth`, the end of the
/// columns it processes, which places the right edge.
fn spread_chroma(dc: &[i32], k: PlaneKind, mb_w: usize, c_width: usize, v: &mut [i32]) {
    let k_kind = k;
    let w = 4 * mb_w;
    let dw = 2 * mb_w;
    let avg = |a: i32, b: i32| a.wrapping_add(b).wrapping_add(1) >> 1;
    let cols = c_width.div_ceil(4).min(w);
    v.fill(0);
    for r in 0..4 {
        for c in (0..cols).step_by(2) {
            v[r * w + c] = match k {
                PlaneKind::Chroma420 if r % 2 == 0 => dc[(r / 2) * dw + c / 2],
                PlaneKind::Chroma420 => 0,
                _ => dc[r * dw + c / 2],
            };
        }
    }
    if k == PlaneKind::Chroma420 {
        // Block rows 1 and 3, inside the macroblock row only.
        for c in (0..cols).step_by(2) {
            v[w + c] = avg(v[c], v[2 * w + c]);
            v[3 * w + c] = v[2 * w + c];
        }
    }
    // Odd block columns. jxrlib walks columns 8k while 8k < cWidth − 8, setting 8k + 4 to the
    // rounded-up mean of 8k and 8k + 8, but finds 8k + 8 inside the macroblock of 8k
    // (modulo 16): in the right half of a macroblock the "right neighbour" is the
    // macroblock's own first block column. After the loop it copies the last right neighbour
    // it read into the next odd column: the left neighbour when the loop ended in a left
    // half, else the previous macroblock's first block column; when the loop never ran
    // (cWidth 8: block row 2 of column 0 for 4:2:0, block (0, 0) for 4:2:2; below 8 jxrlib's
    // unsigned bound wraps and it runs off its buffer, which this does not copy).
    let right = |k: usize| 4 * (k / 2) + (2 * k + 2) % 4;
    for r in 0..4 {
        let row = r * w;
        let mut k = 0;
        while 8 * k + 8 < c_width {
            v[row + 2 * k + 1] = avg(v[row + 2 * k], v[row + right(k)]);
            k += 1;
        }
        let src = match (k, kind_is_420(k_kind)) {
            (0, true) => 2 * w,
            (0, false) => 0,
            _ => row + right(k - 1),
        };
        if 2 * k + 1 < w {
            v[row + 2 * k + 1] = v[src];
        }
    }
}

fn kind_is_420(k: PlaneKind) -> bool {
    k == PlaneKind::Chroma420
}

/// The bias terms of reduced-resolution output.
struct Biases {
    /// What the (unscaled) [`OutputParams::format_row`] adds to Y or to each channel: the
    /// reduced path hands it values with that taken off.
    format: i32,
    /// The same for alpha.
    alpha: i32,
    /// jxrlib's bias before scaling for RGB output.
    rgb: i32,
    /// jxrlib's bias before scaling for N-channel output and alpha.
    nchannel: i32,
}

impl Biases {
    fn new(out: &OutputParams) -> Self {
        use OutputBitDepth::*;
        let s = out.shift;
        let rgbe = out.color == OutputColorFormat::Rgbe;
        let format = match out.bit_depth {
            Bd8 if rgbe => 0,
            Bd8 => 128,
            Bd16 => (1 << 15) >> s,
            Bd5 => 16,
            Bd565 => 32,
            Bd10 => 512,
            _ => 0,
        };
        let alpha = match (out.bit_depth, out.alpha) {
            (Bd8, _) => 128,
            (Bd16, Some(a)) if a.jxrlib_interleaved => 1 << 15,
            (Bd16, _) => (1 << 15) >> s,
            _ => 0,
        };
        let nchannel = match out.bit_depth {
            Bd8 => 128,
            Bd16 => 1 << 15,
            _ => 0,
        };
        Biases { format, alpha, rgb: format, nchannel }
    }

    fn rgb_offset(&self, sc: &Scaling) -> i32 {
        (self.rgb << sc.shift_y) / sc.mul
    }

    fn nchannel_offset(&self, mul: i32, shift: u32) -> i32 {
        (self.nchannel << shift) / mul
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::Limits;

    fn testdata(name: &str) -> Vec<u8> {
        std::fs::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name)).unwrap()
    }

    fn fnv(bytes: &[u8]) -> u64 {
        bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
    }

    fn opts() -> DecodeOptions {
        DecodeOptions::new(Limits::default())
    }

    /// JxrDecApp's `-T 2` and `-T 4` samples (its TIFF's sample bytes, which are the pixel
    /// format's), hashed (testdata/README.md): spatial 4:2:0 with OL2, 4:2:2 without
    /// flexbits, interleaved alpha (half, spatial, trimmed), frequency order with tiles,
    /// hard tiles on a non-square grid, windowing with 4:4:4 and 4:2:0.
    #[test]
    fn reduced_resolution_matches_jxrdecapp() {
        let cases = [
            ("tiny_420_sp.jxr", Resolution::Quarter, (10, 10), 0x6f48_b6a0_17ff_5e70u64),
            ("tiny_420_sp.jxr", Resolution::Sixteenth, (3, 3), 0x94a0_1498_e19a_b130),
            ("tiny_422.jxr", Resolution::Quarter, (10, 10), 0xf059_78e2_fbbe_4771),
            ("tiny_422.jxr", Resolution::Sixteenth, (3, 3), 0xf609_532b_2d96_7ac2),
            ("tiny_alpha_sp.jxr", Resolution::Quarter, (10, 6), 0x5178_c3df_7453_3c10),
            ("tiny_alpha_sp.jxr", Resolution::Sixteenth, (3, 2), 0xe442_681f_26da_f570),
            ("tiny_tiles.jxr", Resolution::Quarter, (12, 10), 0x24ff_dbe1_af83_d6b6),
            ("tiny_tiles.jxr", Resolution::Sixteenth, (3, 3), 0x2741_32c7_7294_40a1),
            ("t835_hard_2x3.jxr", Resolution::Quarter, (12, 10), 0x1ec7_af99_5130_1529),
            ("t835_window.jxr", Resolution::Quarter, (23, 17), 0x7f11_53a7_33f0_ed52),
            ("t835_window_420.jxr", Resolution::Quarter, (22, 14), 0xac04_cce7_a194_a3a9),
        ];
        for (name, resolution, size, want) in cases {
            let file = testdata(name);
            let request = JxrDecodeRequest { region: None, resolution };
            let info = crate::probe_jxr(&file, &Limits::default()).unwrap();
            assert_eq!(output_size(info.width, info.height, &request).unwrap(), size, "{name}");
            for threads in [1, 2] {
                let pool = hdrcodec_core::ThreadPool::new(threads).unwrap();
                let raw = decode_raw_with(&file, &opts().with_pool(pool), &request).unwrap();
                assert_eq!(fnv(&raw), want, "{name} {resolution:?}");
            }
            // A region of the reduced image is the same region of it.
            let full = decode_raw_with(&file, &opts(), &request).unwrap();
            let (w, h) = size;
            let r = Rect { x: 1, y: 1, width: w - 2, height: h - 1 };
            let part = decode_raw_with(&file, &opts(), &JxrDecodeRequest { region: Some(r), resolution }).unwrap();
            let bpp = full.len() / (w * h) as usize;
            let crop: Vec<u8> = (1..h as usize)
                .flat_map(|y| full[(y * w as usize + 1) * bpp..(y * w as usize + w as usize - 1) * bpp].to_vec())
                .collect();
            // 4:2:0 and 4:2:2 chroma depend on the region's right edge (jxrlib's cWidth).
            if !name.contains("42") {
                assert_eq!(part, crop, "{name} {resolution:?} region");
            }
        }
    }

    /// A region at full resolution is the same rectangle of the whole decode, for every kind
    /// of stream at hand (tiles, 4:2:0 with OL2, 4:2:2, alpha, hard tiles, windowing), and
    /// for rectangles at the corners, across tiles and one pixel big.
    #[test]
    fn regions_are_crops_of_the_whole_image() {
        for name in [
            "tiny_420_sp.jxr",
            "tiny_422.jxr",
            "tiny_alpha_sp.jxr",
            "tiny_tiles.jxr",
            "t835_hard_2x3.jxr",
            "t835_window.jxr",
            "t835_window_420.jxr",
            "t835_tile_qps.jxr",
        ] {
            let file = testdata(name);
            let full = crate::decode_raw(&file, &opts()).unwrap();
            let info = crate::probe_jxr(&file, &Limits::default()).unwrap();
            let (w, h) = (info.width, info.height);
            let bpp = full.len() / (w * h) as usize;
            let rects = [
                Rect { x: 0, y: 0, width: w, height: h },
                Rect { x: 0, y: 0, width: 1, height: 1 },
                Rect { x: w - 1, y: h - 1, width: 1, height: 1 },
                Rect { x: 5, y: 17, width: w - 9, height: h - 20 },
                Rect { x: 17, y: 3, width: 15, height: 16 },
            ];
            for r in rects {
                let request = JxrDecodeRequest { region: Some(r), resolution: Resolution::Full };
                let part = decode_raw_with(&file, &opts(), &request).unwrap();
                let crop: Vec<u8> = (r.y..r.y + r.height)
                    .flat_map(|y| {
                        let at = (y * w + r.x) as usize * bpp;
                        full[at..at + r.width as usize * bpp].to_vec()
                    })
                    .collect();
                assert_eq!(part, crop, "{name} {r:?}");
            }
        }
    }

    /// Empty rectangles and rectangles reaching outside are errors, at every resolution.
    #[test]
    fn bad_regions_are_errors() {
        let file = testdata("tiny_tiles.jxr");
        for resolution in [Resolution::Full, Resolution::Quarter, Resolution::Sixteenth] {
            for r in [
                Rect { x: 0, y: 0, width: 0, height: 1 },
                Rect { x: 0, y: 0, width: 1, height: 0 },
                Rect { x: 48, y: 0, width: 1, height: 1 },
                Rect { x: 0, y: 0, width: 49, height: 1 },
                Rect { x: u32::MAX, y: 0, width: 2, height: 1 },
            ] {
                let request = JxrDecodeRequest { region: Some(r), resolution };
                let err = decode_raw_with(&file, &opts(), &request).unwrap_err();
                assert!(matches!(err, Error::Invalid { .. }), "{r:?}: {err}");
            }
        }
    }

    /// The sink path gives the raw path's samples as f32 and honours the budget; damaged
    /// files give errors, not panics.
    #[test]
    fn rows_and_damaged_files() {
        use hdrcodec_core::sink::ImageSink;
        let file = testdata("tiny_alpha_sp.jxr");
        for resolution in [Resolution::Quarter, Resolution::Sixteenth, Resolution::Full] {
            let request = JxrDecodeRequest { region: Some(Rect { x: 1, y: 0, width: 2, height: 2 }), resolution };
            let mut sink = ImageSink::new(&Limits::default());
            decode_rows_with(&file, &opts(), &request, &mut sink).unwrap();
            let image = sink.finish().unwrap();
            assert_eq!((image.width(), image.height()), (2, 2));
            let raw = decode_raw_with(&file, &opts(), &request).unwrap();
            let halves: Vec<f32> =
                raw.chunks_exact(2).map(|b| half::f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32()).collect();
            assert!(image.samples().iter().zip(&halves).all(|(a, b)| a.to_bits() == b.to_bits()));
            let tight = DecodeOptions::new(Limits::default().with_max_alloc_bytes(1000));
            assert!(decode_raw_with(&file, &tight, &request).is_err());
            let mut bad = file.clone();
            for i in (0..file.len()).step_by(5) {
                let _ = decode_raw_with(&file[..i], &opts(), &request);
                bad.copy_from_slice(&file);
                bad[i] ^= 0x5a;
                let _ = decode_raw_with(&bad, &opts(), &request);
            }
        }
    }
}
