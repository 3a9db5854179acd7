//! Gain-map JPEG decoding: find the gain-map image (MPF, GContainer, or the next JPEG after the
//! primary's EOI), read its metadata (ISO 21496-1 record, else Adobe `hdrgm` XMP, else Apple's
//! headroom), decode both JPEGs and apply the gain (ISO 21496-1 clause 7):
//!
//! `hdr = (base + k_base) · 2^(W · L) − k_alt`, `L = min·(1 − g) + max·g`, `g = (code/255)^(1/γ)`
//!
//! per channel, with `base` the sRGB-decoded primary in its own primaries, the map upsampled to
//! the base's size, and `W` the weight of the display headroom (1: full HDR).

use crate::markers::{self, JpegImage, APP1, APP2};
use crate::metadata::{GainMapMetadata, ISO_SIGNATURE};
use crate::xmp::{self, Xmp};
use crate::{exif, icc, mpf, ratio};
use hdrcodec_core::sink::{band_rows, fill_rows, ImageSink, RowSink, Scratch};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, DecodeOptions, Error, HdrImage, ImageInfo, Limits, Result, SrgbTransfer,
    ThreadPool,
};

/// The luminance of the base's (SDR) white, cd/m²: ITU-R BT.2408's reference white, which
/// libultrahdr and the Ultra HDR format use when they give gain-map output absolute units.
pub const SDR_WHITE_NITS: f32 = 203.0;

/// Which gain-map convention a file follows (the source of its metadata).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flavour {
    /// ISO 21496-1 binary metadata.
    Iso21496,
    /// Adobe's `hdrgm` XMP (Android Ultra HDR, Photoshop, Lightroom).
    AdobeXmp,
    /// Apple's HDR gain map (one channel, headroom in the map's XMP).
    Apple,
}

impl Flavour {
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Flavour::Iso21496 => "ISO 21496-1",
            Flavour::AdobeXmp => "Adobe hdrgm XMP",
            Flavour::Apple => "Apple HDR gain map",
        }
    }
}

/// A gain-map file taken apart: the primary image, the gain-map image and its metadata.
pub struct GainMapFile<'a> {
    /// The primary (base) image.
    pub primary: JpegImage<'a>,
    /// The gain-map image, or `None` for a plain JPEG (or one whose gain map is unusable; see
    /// `warning`).
    pub gain_map: Option<(JpegImage<'a>, GainMapMetadata, Flavour)>,
    /// Why a gain map that the file announces could not be used.
    pub warning: Option<String>,
}

impl<'a> GainMapFile<'a> {
    /// Reads the structure and metadata of a file (no pixels). Fails only if the primary image
    /// itself is broken; a damaged or missing gain map leaves `gain_map` empty with a warning.
    pub fn parse(data: &'a [u8]) -> Result<Self> {
        let primary = markers::parse_image(data, 0)?;
        match find_gain_map(data, &primary) {
            Ok(Some((map, meta, flavour))) => {
                Ok(GainMapFile { primary, gain_map: Some((map, meta, flavour)), warning: None })
            }
            Ok(None) => Ok(GainMapFile { primary, gain_map: None, warning: None }),
            Err(e) => Ok(GainMapFile { primary, gain_map: None, warning: Some(e.to_string()) }),
        }
    }
}

/// The primary's XMP, if it has one that parses.
fn xmp_of(image: &JpegImage<'_>) -> Option<Xmp> {
    image.app_payload(APP1, xmp::SIGNATURE).and_then(|(_, p)| Xmp::new(p).ok())
}

/// Where the gain map is and what it means: `Ok(None)` when the file announces none.
fn find_gain_map<'a>(
    data: &'a [u8],
    primary: &JpegImage<'a>,
) -> Result<Option<(JpegImage<'a>, GainMapMetadata, Flavour)>> {
    let primary_xmp = xmp_of(primary);
    let announces_iso = primary.app_payload(APP2, ISO_SIGNATURE).is_some();
    let announces_adobe = primary_xmp.as_ref().and_then(Xmp::hdrgm_version).is_some();
    // Candidates for the second image, most trusted first: MPF entries after the first, the
    // GContainer's GainMap item, the first image after the primary's EOI.
    let mut candidates = Vec::new();
    if let Some((offset, payload)) = primary.app_payload(APP2, mpf::SIGNATURE) {
        if let Ok(entries) = mpf::parse(payload, offset, primary.start) {
            candidates.extend(entries.iter().skip(1).map(|e| e.file_offset));
        }
    }
    if let Some(x) = &primary_xmp {
        let items = x.container_items();
        let mut at = primary.end;
        for (semantic, length) in items.iter().skip(1) {
            if semantic == "GainMap" {
                candidates.push(at);
            }
            at += length.unwrap_or(0) as usize;
        }
    }
    candidates.extend(markers::next_image_start(data, primary.end));
    let mut seen = Vec::new();
    let mut first_error = None;
    for start in candidates {
        if seen.contains(&start) {
            continue;
        }
        seen.push(start);
        let Ok(image) = markers::parse_image(data, start) else { continue };
        match metadata_of(&image, primary) {
            Ok(Some((meta, flavour))) => return Ok(Some((image, meta, flavour))),
            Ok(None) => {}
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    match first_error {
        Some(e) => Err(e),
        None if announces_iso || announces_adobe => {
            Err(Error::invalid("the file announces a gain map but none was found"))
        }
        None => Ok(None),
    }
}

/// The gain-map metadata an image carries, if it is a gain map: its ISO 21496-1 record first
/// (what libultrahdr and Skia prefer), else its hdrgm XMP, else Apple's.
fn metadata_of(image: &JpegImage<'_>, primary: &JpegImage<'_>) -> Result<Option<(GainMapMetadata, Flavour)>> {
    if let Some((_, record)) = image.app_payload(APP2, ISO_SIGNATURE) {
        if let Some(m) = GainMapMetadata::from_iso(record)? {
            return Ok(Some((m, Flavour::Iso21496)));
        }
    }
    let Some(x) = xmp_of(image) else { return Ok(None) };
    if let Some(m) = x.hdrgm_metadata()? {
        return Ok(Some((m, Flavour::AdobeXmp)));
    }
    if x.is_apple_gain_map() {
        // The XMP's HDRGainMapHeadroom, read as a linear ratio (Skia, libavif), else (older
        // files) the headroom in stops from the primary's EXIF maker note, as Apple documents.
        let stops = match x.apple_headroom()? {
            Some(headroom) if headroom >= 1.0 && headroom.is_finite() => headroom.log2(),
            Some(headroom) => return Err(Error::invalid(format!("Apple HDRGainMapHeadroom {headroom}"))),
            None => exif::apple_headroom_stops(primary)?.ok_or_else(|| {
                Error::invalid("Apple HDR gain map without a headroom (neither in its XMP nor in a maker note)")
            })?,
        };
        // Mapped to ISO terms as libavif does: a log-domain gain from 0 to `stops`, gamma 1,
        // no offsets.
        let m = GainMapMetadata {
            base_headroom: 0.0,
            alternate_headroom: stops,
            gain_min: [0.0; 3],
            gain_max: [stops; 3],
            gamma: [1.0; 3],
            base_offset: [0.0; 3],
            alternate_offset: [0.0; 3],
            multichannel: false,
            use_base_colour_space: true,
        };
        return Ok(Some((m, Flavour::Apple)));
    }
    Ok(None)
}

/// A decoded 8-bit JPEG: `channels` samples (1 or 3) per pixel.
pub(crate) struct Pixels {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub samples: Vec<u8>,
}

fn jpeg_options(limits: &Limits) -> zune_jpeg::zune_core::options::DecoderOptions {
    zune_jpeg::zune_core::options::DecoderOptions::default()
        .set_max_width(limits.max_width.min(65535) as usize)
        .set_max_height(limits.max_height.min(65535) as usize)
        .set_strict_mode(false)
}

/// Refuses frame layouts outside what cameras and encoders write (every component sampled
/// 1 or 2 times per axis, chroma at 1×1 or at the luma's rate): `zune-jpeg` 0.4 panics on some
/// others (a Cb component with four vertical samples, found by fuzzing).
fn check_sampling(bytes: &[u8], what: &str) -> Result<()> {
    let image = markers::parse_image(bytes, 0)?;
    let Some(sof) = image.segments.iter().find(|s| matches!(s.marker, 0xC0..=0xC2)) else {
        return Err(Error::unsupported(format!("{what}: not a baseline, extended or progressive JPEG")));
    };
    let p = sof.payload;
    let n = usize::from(*p.get(5).ok_or_else(|| Error::invalid(format!("{what}: short frame header")))?);
    let factors: Vec<(u8, u8)> = (0..n)
        .map(|k| p.get(7 + 3 * k).map(|&f| (f >> 4, f & 15)))
        .collect::<Option<_>>()
        .ok_or_else(|| Error::invalid(format!("{what}: short frame header")))?;
    let usual = factors.iter().all(|&(h, v)| (1..=2).contains(&h) && (1..=2).contains(&v))
        && factors.iter().skip(1).all(|&f| f == (1, 1) || f == factors[0]);
    if !usual || !(n == 1 || n == 3) {
        return Err(Error::unsupported(format!("{what}: {n} components sampled {factors:?}")));
    }
    Ok(())
}

/// Runs a call into `zune-jpeg`, turning a panic into an error (the fuzz-found layouts are
/// refused before; this is for the ones not found yet).
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|_| Err(Error::invalid(format!("{what}: the JPEG decoder failed on malformed data"))))
}

/// The size and channels (1: grey, 3: colour) of one JPEG image, from its headers.
fn jpeg_header(bytes: &[u8], limits: &Limits, what: &str) -> Result<(usize, usize, usize)> {
    check_sampling(bytes, what)?;
    guarded(what, || jpeg_header_unchecked(bytes, limits, what))
}

fn jpeg_header_unchecked(bytes: &[u8], limits: &Limits, what: &str) -> Result<(usize, usize, usize)> {
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(bytes, jpeg_options(limits));
    decoder.decode_headers().map_err(|e| Error::invalid(format!("{what}: {e}")))?;
    let info = decoder.info().ok_or_else(|| Error::invalid(format!("{what}: no frame header")))?;
    let (width, height) = (usize::from(info.width), usize::from(info.height));
    let channels = match decoder.get_input_colorspace() {
        Some(ColorSpace::Luma) => 1,
        Some(ColorSpace::YCbCr | ColorSpace::RGB) => 3,
        other => return Err(Error::unsupported(format!("{what}: JPEG colour space {other:?}"))),
    };
    if (width as u64) * (height as u64) > limits.max_pixels {
        return Err(Error::limit(format!("{what}: {width}x{height} pixels")));
    }
    Ok((width, height, channels))
}

/// Decodes one JPEG image to grey (one-component files) or RGB, within `limits`.
pub(crate) fn decode_jpeg(bytes: &[u8], limits: &Limits, what: &str) -> Result<Pixels> {
    decode_jpeg_as(bytes, limits, what, false)
}

/// [`decode_jpeg`], colour images as Y'CbCr instead of RGB when `ycc`.
pub(crate) fn decode_jpeg_as(bytes: &[u8], limits: &Limits, what: &str, ycc: bool) -> Result<Pixels> {
    use zune_jpeg::zune_core::colorspace::ColorSpace;
    let (width, height, channels) = jpeg_header(bytes, limits, what)?;
    let _charge = limits.charge((width * height * channels) as u64, what)?;
    let out = match (channels, ycc) {
        (1, _) => ColorSpace::Luma,
        (_, true) => ColorSpace::YCbCr,
        _ => ColorSpace::RGB,
    };
    let samples = guarded(what, || {
        let mut decoder =
            zune_jpeg::JpegDecoder::new_with_options(bytes, jpeg_options(limits).jpeg_set_out_colorspace(out));
        decoder.decode().map_err(|e| Error::invalid(format!("{what}: {e}")))
    })?;
    if samples.len() != width * height * channels {
        return Err(Error::invalid(format!(
            "{what}: the JPEG decoder gave {} samples for {width}x{height}",
            samples.len()
        )));
    }
    Ok(Pixels { width, height, channels, samples })
}

/// What a file says before its pixels are decoded: size, colour and the notes a decode
/// attaches (the flavour and size of the gain map, colour caveats, a damaged gain map).
pub fn probe(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    describe(&GainMapFile::parse(data)?, data, limits)
}

/// [`probe`] of a file already taken apart.
fn describe(file: &GainMapFile<'_>, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    let (width, height, _) = jpeg_header(file.primary.bytes(data), limits, "primary image")?;
    match ratio::ratio_image(&file.primary).and_then(|r| match r {
        Some((header, jpeg)) => jpeg_header(&jpeg, limits, "JPEG-HDR ratio image").map(|_| Some(header)),
        None => Ok(None),
    }) {
        Ok(Some(header)) => {
            let nits_per_unit = if header.samples_to_nits > 0.0 {
                header.samples_to_nits as f32
            } else {
                ColorInfo::default().nits_per_unit
            };
            let color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit, hdr10: None };
            let mut info = ImageInfo::new(width as u32, height as u32, Channels::Rgb, color);
            info.format =
                format!("JPEG-HDR (Ward & Simmons ratio image, ver={}, cor={:?})", header.version, header.correction);
            return Ok(info);
        }
        Ok(None) => {}
        Err(e) => {
            let mut info = ImageInfo::new(
                width as u32,
                height as u32,
                Channels::Rgb,
                ColorInfo { nits_per_unit: SDR_WHITE_NITS, ..ColorInfo::default() },
            );
            info.format = "JPEG-HDR with a damaged ratio image (SDR base)".into();
            info.metadata.push(("jpeg.warning".into(), format!("ratio image unusable, decoded as SDR: {e}")));
            return Ok(info);
        }
    }
    let (primaries, mut metadata) = primaries_of(&file.primary);
    if let Some(block) = exif::exif_block(&file.primary) {
        // Kept for an encoder to write back. The samples are as stored: a rotation EXIF asks
        // for is not applied (the gain map shares the base's orientation, so both agree).
        metadata.push((exif::METADATA_KEY.into(), exif::to_hex(block)));
        if let Some(o @ 2..) = exif::orientation(block) {
            metadata.push((
                "jpeg.orientation_note".into(),
                format!("EXIF orientation {o}: the samples are as stored, not rotated or mirrored"),
            ));
        }
    }
    match &file.gain_map {
        Some((map, meta, flavour)) => {
            let (w, h, c) = jpeg_header(map.bytes(data), limits, "gain-map image")?;
            metadata.push(("jpeg.gain_map".into(), format!("{} ({w}x{h}, {c} channel(s))", flavour.name())));
            let (headroom, gain) = meta.describe();
            metadata.push(("jpeg.headroom".into(), headroom));
            metadata.push(("jpeg.gain_range".into(), gain));
            if !meta.use_base_colour_space {
                metadata.push((
                    "jpeg.colour_note".into(),
                    "the metadata asks for the gain in the gain map's colour space; applied in the base's".into(),
                ));
            }
        }
        None => {
            if let Some(w) = &file.warning {
                metadata.push(("jpeg.warning".into(), format!("gain map unusable, decoded as SDR: {w}")));
            }
        }
    }
    let color = ColorInfo { primaries, nits_per_unit: SDR_WHITE_NITS, hdr10: None };
    let mut info = ImageInfo::new(width as u32, height as u32, Channels::Rgb, color);
    info.format = match &file.gain_map {
        Some((_, _, flavour)) => format!("JPEG with a gain map ({})", flavour.name()),
        None => "JPEG without HDR data (SDR)".into(),
    };
    info.metadata = metadata;
    Ok(info)
}

/// The primaries of an image's ICC profile (sRGB without one, as the gain-map formats say),
/// and a note when the profile names primaries the family does not know.
fn primaries_of(image: &JpegImage<'_>) -> (ColorPrimaries, Vec<(String, String)>) {
    match icc::assemble(image.app_payloads(APP2, icc::SIGNATURE).map(|(_, p)| p)) {
        None => (ColorPrimaries::Bt709, Vec::new()),
        Some(profile) => match icc::primaries(&profile) {
            Some(p) => (p, Vec::new()),
            None => (
                ColorPrimaries::Unspecified,
                vec![(
                    "jpeg.colour_note".into(),
                    "the ICC profile's primaries are not a known set: samples kept in its space".into(),
                )],
            ),
        },
    }
}

/// What a decode should render.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rendering {
    /// The display's headroom (linear ratio of HDR white to SDR white, ≥ 1); `None` for the
    /// full HDR rendition the file describes.
    pub headroom: Option<f64>,
}

impl Rendering {
    /// The decode option that sets [`Rendering::headroom`] (`--opt headroom=2.0`).
    pub const OPTION_KEYS: &'static [&'static str] = &["headroom"];

    /// The rendering asked for in a decoder's options: `headroom=H`, a linear ratio (the
    /// decode checks it is at least 1), or `headroom=full` (the default).
    pub fn from_options(options: &DecodeOptions) -> Result<Self> {
        match options.option("headroom") {
            None | Some("full") => Ok(Rendering::default()),
            Some(_) => Ok(Rendering { headroom: options.parse_option("headroom")? }),
        }
    }
}

/// Decodes a gain-map JPEG (or a plain JPEG, as SDR) to linear samples in the base image's
/// primaries, 1.0 = SDR white = [`SDR_WHITE_NITS`]. Notes what it found in the metadata.
pub fn decode(data: &[u8], limits: &Limits, rendering: Rendering) -> Result<HdrImage> {
    let mut sink = ImageSink::new(limits);
    decode_rows(data, limits, rendering, &mut sink)?;
    sink.finish()
}

/// [`decode`] into `sink`, a band of rows at a time: besides the sink, the decode holds the two
/// JPEGs' 8-bit samples and a band of output rows (JPEG-HDR files with post-correction: also
/// the whole image's corrected ratio codes).
pub fn decode_rows(data: &[u8], limits: &Limits, rendering: Rendering, sink: &mut dyn RowSink) -> Result<()> {
    decode_rows_on(data, limits, rendering, &ThreadPool::single(), sink)
}

/// [`decode_rows`] with the gain applied to the rows of each band in parallel on `pool` (the
/// two JPEGs are decoded on the calling thread). The samples do not depend on the pool.
pub fn decode_rows_on(
    data: &[u8],
    limits: &Limits,
    rendering: Rendering,
    pool: &ThreadPool,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let file = GainMapFile::parse(data)?;
    let mut info = describe(&file, data, limits)?;
    if let Ok(Some((header, ratio_jpeg))) = ratio::ratio_image(&file.primary) {
        match ratio::prepare(data, &file.primary, &header, &ratio_jpeg, limits) {
            Ok(prepared) => return prepared.deliver(limits, sink),
            Err(e @ Error::LimitExceeded { .. }) => return Err(e),
            // Ratio pixels that do not decode (headers that do: `probe` has promised this
            // file's colour): the base, as SDR in the file's units, with a warning.
            Err(e) => {
                info.metadata.push(("jpeg.warning".into(), format!("ratio image unusable, decoded as SDR: {e}")));
            }
        }
    }
    let base = decode_jpeg(file.primary.bytes(data), limits, "primary image")?;
    let gain = match &file.gain_map {
        None => None,
        Some((map_image, meta, _)) => {
            let map = decode_jpeg(map_image.bytes(data), limits, "gain-map image")?;
            let weight = match rendering.headroom {
                None => meta.full_hdr_weight(),
                Some(h) if h >= 1.0 && h.is_finite() => meta.weight(h.log2()),
                Some(h) => return Err(Error::invalid(format!("display headroom {h} (must be at least 1)"))),
            };
            Some(GainApplier::new(&base, map, meta, weight))
        }
    };
    sink.start(&info)?;
    // The sRGB EOTF of every code, once (the base is always sRGB-encoded, ISO 21496-1 6.2).
    let eotf: [f32; 256] = std::array::from_fn(|c| SrgbTransfer::decode(c as f64 / 255.0) as f32);
    let row_len = base.width * 3;
    let band = band_rows(row_len, 1 << 20) as usize;
    let mut scratch = Scratch::new(limits);
    // Rows per task of the pool: enough to amortise a task's working rows.
    const TASK_ROWS: usize = 16;
    for y0 in (0..base.height).step_by(band) {
        let rows = band.min(base.height - y0);
        fill_rows(sink, y0 as u32, rows as u32, row_len, &mut scratch, |out| {
            pool.for_each_chunk_mut(out, row_len * TASK_ROWS, |task, chunk| {
                let mut buffers = RowBuffers::default();
                for (r, out_row) in chunk.chunks_exact_mut(row_len).enumerate() {
                    let y = y0 + task * TASK_ROWS + r;
                    let base_row = &base.samples[y * base.width * base.channels..(y + 1) * base.width * base.channels];
                    match &gain {
                        None => {
                            for (o, p) in out_row.chunks_exact_mut(3).zip(base_row.chunks_exact(base.channels)) {
                                for c in 0..3 {
                                    o[c] = eotf[usize::from(p[c.min(base.channels - 1)])];
                                }
                            }
                        }
                        Some(g) => g.row(y, base_row, base.channels, &eotf, out_row, &mut buffers),
                    }
                }
            });
            Ok(())
        })?;
    }
    Ok(())
}

/// One axis of the map's bilinear upsampling: for each output coordinate, the two map
/// coordinates and the weight of the second. Output pixel `x` samples the map at
/// `x · map_len / out_len`, as libultrahdr does (map pixel `m` sits on base pixel `m · scale`;
/// on the corpus's Pixel file this agrees with libultrahdr better than centre alignment, p99
/// 0.037 against 0.042 stops). Skia samples centre-aligned, half a map pixel away.
pub(crate) fn axis(out_len: usize, map_len: usize) -> Vec<(usize, usize, f32)> {
    let scale = map_len as f64 / out_len as f64;
    (0..out_len)
        .map(|x| {
            let u = (x as f64 * scale).min((map_len - 1) as f64);
            let i = u.floor() as usize;
            (i, (i + 1).min(map_len - 1), (u - i as f64) as f32)
        })
        .collect()
}

/// The gain map, upsampled and applied a row at a time.
struct GainApplier {
    map: Pixels,
    xs: Vec<(usize, usize, f32)>,
    ys: Vec<(usize, usize, f32)>,
    inv_gamma: [f32; 3],
    lo: [f32; 3],
    span: [f32; 3],
    k_base: [f32; 3],
    k_alt: [f32; 3],
    /// One gain serves the three channels: a one-channel map whose channels' parameters agree.
    shared: bool,
}

/// The working rows of [`GainApplier::row`], kept from row to row.
#[derive(Default)]
struct RowBuffers {
    /// The map's codes interpolated to the output row (vertically), map pixels × map channels.
    codes: Vec<f32>,
    /// Per output pixel, one (shared) or three log2 gains, then the gains.
    gains: Vec<f32>,
}

impl GainApplier {
    fn new(base: &Pixels, map: Pixels, meta: &GainMapMetadata, weight: f64) -> Self {
        let inv_gamma = std::array::from_fn(|c| (1.0 / meta.gamma[c]) as f32);
        let lo: [f32; 3] = std::array::from_fn(|c| (weight * meta.gain_min[c]) as f32);
        let span: [f32; 3] = std::array::from_fn(|c| (weight * (meta.gain_max[c] - meta.gain_min[c])) as f32);
        let same = |v: &[f32; 3]| v[1] == v[0] && v[2] == v[0];
        GainApplier {
            xs: axis(base.width, map.width),
            ys: axis(base.height, map.height),
            shared: map.channels == 1 && same(&inv_gamma) && same(&lo) && same(&span),
            map,
            inv_gamma,
            lo,
            span,
            k_base: std::array::from_fn(|c| meta.base_offset[c] as f32),
            k_alt: std::array::from_fn(|c| meta.alternate_offset[c] as f32),
        }
    }

    /// Output row `y` from the base's row (`channels` samples per pixel). The map is
    /// interpolated bilinearly on its codes (vertically once per row, then across), the codes
    /// become log2 gains, and the gains come from [`exp2_all`] in one pass over the row.
    fn row(
        &self,
        y: usize,
        base_row: &[u8],
        channels: usize,
        eotf: &[f32; 256],
        out: &mut [f32],
        buf: &mut RowBuffers,
    ) {
        let map = &self.map;
        let (mc, row_len) = (map.channels, map.width * map.channels);
        let (y0, y1, fy) = self.ys[y];
        let (top, bottom) = (&map.samples[y0 * row_len..][..row_len], &map.samples[y1 * row_len..][..row_len]);
        buf.codes.clear();
        buf.codes.extend(top.iter().zip(bottom).map(|(&t, &b)| f32::from(t) * (1.0 - fy) + f32::from(b) * fy));
        let n = if self.shared { 1 } else { 3 };
        let codes = &buf.codes;
        buf.gains.resize(self.xs.len() * n, 0.0);
        for (gains, &(x0, x1, fx)) in buf.gains.chunks_exact_mut(n).zip(&self.xs) {
            for (c, gain) in gains.iter_mut().enumerate() {
                let m = c.min(mc - 1);
                let g = (codes[x0 * mc + m] * (1.0 - fx) + codes[x1 * mc + m] * fx) / 255.0;
                let g = if self.inv_gamma[c] == 1.0 { g } else { g.powf(self.inv_gamma[c]) };
                *gain = self.lo[c] + self.span[c] * g;
            }
        }
        exp2_all(&mut buf.gains);
        for ((o, p), gain) in
            out.chunks_exact_mut(3).zip(base_row.chunks_exact(channels)).zip(buf.gains.chunks_exact(n))
        {
            for c in 0..3 {
                let b = eotf[usize::from(p[c.min(channels - 1)])];
                o[c] = (b + self.k_base[c]) * gain[c.min(n - 1)] - self.k_alt[c];
            }
        }
    }
}

/// `2^x` for every element, within 3·10⁻⁷ of the exact value (relative; `f32::exp2`'s
/// rounding is 6·10⁻⁸), for x in [−126, 126] (clamped there): the integer part goes to the
/// exponent, the fraction in [−½, ½] through the degree-7 Taylor polynomial of `2^f`
/// (truncation error 5·10⁻⁹). Plain arithmetic on each element, which the compiler vectorises
/// with the baseline instruction set (SSE2 on x86-64), where a call to libm's `exp2f` per
/// sample took half of the decode of a 12.5 MP photo.
pub(crate) fn exp2_all(values: &mut [f32]) {
    // Adding 1.5·2²³ rounds a float of magnitude below 2²² to an integer, kept in the low
    // mantissa bits.
    const ROUND: f32 = 12_582_912.0;
    const C: [f32; 7] = [
        std::f32::consts::LN_2,
        0.240_226_5,
        0.055_504_11,
        0.009_618_129,
        0.001_333_355_8,
        0.000_154_035_3,
        0.000_015_252_734,
    ];
    for v in values {
        let x = v.clamp(-126.0, 126.0);
        let shifted = x + ROUND;
        let whole = shifted - ROUND;
        let f = x - whole;
        let p = 1.0 + f * (C[0] + f * (C[1] + f * (C[2] + f * (C[3] + f * (C[4] + f * (C[5] + f * C[6]))))));
        let exponent = (shifted.to_bits().wrapping_sub(ROUND.to_bits()) as i32 + 127) << 23;
        *v = p * f32::from_bits(exponent as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 64x48, written by libultrahdr 1.4 (imagecodecs `ultrahdr_encode`, level 90, map scale 2)
    /// from a ramp with a highlight 8x brighter: ISO 21496-1 metadata only, MPF.
    const RAMP: &[u8] = include_bytes!("../testdata/ramp_libultrahdr.jpg");

    #[test]
    fn libultrahdr_file_decodes_with_its_gain_map() {
        let file = GainMapFile::parse(RAMP).unwrap();
        let (map, meta, flavour) = file.gain_map.as_ref().unwrap();
        assert_eq!(flavour, &Flavour::Iso21496);
        assert!(meta.alternate_headroom > meta.base_headroom && map.start == file.primary.end);
        let hdr = decode(RAMP, &Limits::default(), Rendering::default()).unwrap();
        let sdr = decode(RAMP, &Limits::default(), Rendering { headroom: Some(1.0) }).unwrap();
        assert_eq!((hdr.width(), hdr.height(), hdr.color.nits_per_unit), (64, 48, SDR_WHITE_NITS));
        let peak = |i: &HdrImage| i.samples().iter().copied().fold(0.0f32, f32::max);
        // The highlight goes well past SDR white only with the gain applied.
        assert!(peak(&hdr) > 4.0 && peak(&sdr) <= 1.1, "{} {}", peak(&hdr), peak(&sdr));
        let mut on_two = ImageSink::new(&Limits::default());
        let pool = ThreadPool::new(2).unwrap();
        decode_rows_on(RAMP, &Limits::default(), Rendering::default(), &pool, &mut on_two).unwrap();
        assert_eq!(on_two.finish().unwrap().samples(), hdr.samples(), "the pool changes no sample");
        let too_small = Limits::default().with_max_alloc_bytes(10_000);
        assert!(decode(RAMP, &too_small, Rendering::default()).is_err());
        assert!(decode(RAMP, &Limits::default(), Rendering { headroom: Some(0.5) }).is_err());
    }

    #[test]
    fn exp2_all_is_exp2_within_float_rounding() {
        let xs: Vec<f32> = (-60_000..=60_000).map(|i| i as f32 * 0.001).chain([-125.9, -100.3, 99.7, 125.9]).collect();
        let mut ys = xs.clone();
        exp2_all(&mut ys);
        for (&x, &y) in xs.iter().zip(&ys) {
            let exact = f64::from(x).exp2();
            assert!((f64::from(y) / exact - 1.0).abs() < 3e-7, "2^{x}: {y} against {exact}");
        }
        let mut edges = [-1000.0f32, 1000.0, 0.0];
        exp2_all(&mut edges);
        assert_eq!(edges, [2f32.powi(-126), 2f32.powi(126), 1.0]);
    }

    #[test]
    fn truncated_or_corrupted_files_fail_cleanly_or_fall_back_to_sdr() {
        let primary_end = GainMapFile::parse(RAMP).unwrap().primary.end;
        for n in (0..RAMP.len()).step_by(7) {
            match decode(&RAMP[..n], &Limits::default(), Rendering::default()) {
                // With the primary whole and the gain map cut, the SDR base comes back with a
                // warning.
                Ok(image) => {
                    assert!(n >= primary_end, "{n}");
                    assert!(image.metadata_value("jpeg.warning").is_some() || n == RAMP.len());
                }
                Err(_) => assert!(n < primary_end || n < RAMP.len(), "{n}"),
            }
        }
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..300 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut data = RAMP.to_vec();
            let at = (state % data.len() as u64) as usize;
            data[at] ^= (state >> 32) as u8 | 1;
            let _ = decode(&data, &Limits::default(), Rendering::default());
        }
    }
}
