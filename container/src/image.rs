//! Whole images and frame sequences in `.hdrc`, with the tiles coded by another codec, in
//! parallel (rayon), and [`HdrcCodec`], the container as an [`ImageCodec`].

use crate::format::{DataHeader, Head, SIGNATURE};
use crate::raw::{RawF16Codec, RawF32Codec};
use crate::reader::{in_chunk, DataLoc, DataRef, HeadInfo, Reader};
use crate::stream::StreamFile;
use crate::writer::Writer;
use hdrcodec_core::color::{convert_primaries, mat_to_f32, rgb_to_rgb, Mat3, IDENTITY};
use hdrcodec_core::sink::{band_rows, fill_rows, ImageSink, RowSink, Scratch};
use hdrcodec_core::{
    Allocation, Channels, ColorInfo, ColorPrimaries, ColorSignalling, DecodeOptions, EncodeSettings, Error, HdrImage,
    ImageCodec, ImageInfo, Limits, ReadSeek, Result, RowCounter,
};
use std::borrow::Cow;
use std::sync::Arc;

/// The pixels of `image` inside the tile `t`, as an image of their own (same colour, no metadata).
pub(crate) fn crop(image: &HdrImage, t: &DataHeader) -> Result<HdrImage> {
    let c = image.channels().count();
    let mut samples = Vec::with_capacity(t.width as usize * t.height as usize * c);
    for y in t.y..t.y + t.height {
        samples.extend_from_slice(&image.row(y)[t.x as usize * c..(t.x + t.width) as usize * c]);
    }
    HdrImage::new(t.width, t.height, image.channels(), samples, image.color.clone())
}

/// The same primaries, allowing for chromaticities rounded on the way through a payload's
/// file (OpenEXR stores them as f32, COLR as f64).
fn same_primaries(a: &ColorPrimaries, b: &ColorPrimaries) -> bool {
    if a == b {
        return true;
    }
    let (a, b) = (a.chromaticities(), b.chromaticities());
    let pairs = [(a.red, b.red), (a.green, b.green), (a.blue, b.blue), (a.white, b.white)];
    pairs.iter().all(|(p, q)| (p[0] - q[0]).abs() < 1e-6 && (p[1] - q[1]).abs() < 1e-6)
}

/// Brings a decoded tile into the colour of the file's header (COLR), the colour it was
/// encoded from:
/// - a tile whose decoded primaries are specified and differ from the header's (LogLuv decodes
///   to BT.709) is converted into the header's primaries; a tile that decodes unspecified (raw,
///   PFM, DDS payloads) is taken as the header's: it was written from them. A header that says
///   unspecified keeps the samples as they are.
/// - a tile whose payload records its scale ([`ImageCodec::records_nits_per_unit`]) and decodes
///   with another `nits_per_unit` than the header's is rescaled into the header's units; the
///   scale of a payload that records none is the header's.
///
/// Alpha is untouched. One 3x3 matrix per tile, nothing is clipped.
fn to_header_colour(mut tile: HdrImage, header: &ColorInfo, records_scale: bool) -> HdrImage {
    if let Some(m) = header_matrix(&tile.color, header, records_scale) {
        let n = tile.channels().count();
        for px in tile.samples_mut().chunks_exact_mut(n) {
            let [r, g, b] = hdrcodec_core::color::mat_apply_f32s(&m, [px[0], px[1], px[2]]);
            px[..3].copy_from_slice(&[r, g, b]);
        }
    }
    tile.color = header.clone();
    tile
}

/// The matrix that brings the RGB of a tile decoded in colour `tile` into the header's colour
/// (primaries and, if the payload records it, scale), or `None` when the samples are already
/// in it: see [`to_header_colour`].
fn header_matrix(tile: &ColorInfo, header: &ColorInfo, records_scale: bool) -> Option<[[f32; 3]; 3]> {
    let from = tile.primaries;
    let to = header.primaries;
    let convert = from.is_specified() && to.is_specified() && !same_primaries(&from, &to);
    let (tile_nits, header_nits) = (tile.nits_per_unit, header.nits_per_unit);
    let rescale = records_scale && tile_nits != header_nits && tile_nits.is_finite() && tile_nits > 0.0;
    (convert || rescale).then(|| {
        let m: Mat3 = if convert { rgb_to_rgb(&from, &to) } else { IDENTITY };
        let k = if rescale { f64::from(tile_nits) / f64::from(header_nits) } else { 1.0 };
        mat_to_f32(&m.map(|row| row.map(|v| v * k)))
    })
}

/// The options a tile's payload decodes with: a clone shares the caller's allocation budget;
/// the tile's own size bounds the dimensions.
fn tile_options(options: &DecodeOptions, t: DataHeader) -> DecodeOptions {
    let mut tile_options = options.clone();
    tile_options.limits.max_width = t.width;
    tile_options.limits.max_height = t.height;
    tile_options.limits.max_pixels = u64::from(t.width) * u64::from(t.height);
    tile_options
}

/// The sink a frame's only tile (an untiled file) decodes into: its rows go straight to the
/// frame's sink, in place when the tile's channels and colour are the header's, else brought
/// into them (channels as [`HdrImage::with_channels`], colour as [`to_header_colour`]) a band
/// at a time. No tile image, no copy of the frame.
struct WholeFrameSink<'s> {
    inner: &'s mut dyn RowSink,
    info: &'s ImageInfo,
    records_scale: bool,
    /// The tile's channel count and matrix once started, when its rows need converting.
    convert: Option<(usize, Option<[[f32; 3]; 3]>)>,
    started: bool,
    buf: Vec<f32>,
}

impl RowSink for WholeFrameSink<'_> {
    fn start(&mut self, tile: &ImageInfo) -> Result<()> {
        if (tile.width, tile.height) != (self.info.width, self.info.height) {
            return Err(Error::invalid(format!("the payload decodes to {}x{}", tile.width, tile.height)));
        }
        let m = header_matrix(&tile.color, &self.info.color, self.records_scale);
        self.convert = (m.is_some() || tile.channels != self.info.channels).then_some((tile.channels.count(), m));
        self.started = true;
        self.inner.start(self.info)
    }

    fn rows_mut(&mut self, y: u32, rows: u32) -> Option<&mut [f32]> {
        if self.convert.is_some() || !self.started {
            return None;
        }
        self.inner.rows_mut(y, rows)
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let Some((from, m)) = self.convert else { return self.inner.put_rows(y, samples) };
        let to = self.info.channels.count();
        // A band of about 1 MB at a time, whatever the payload delivers at once.
        let tile_row = self.info.width as usize * from;
        let band = band_rows(tile_row, 1 << 20) as usize;
        for (k, rows) in samples.chunks(band * tile_row).enumerate() {
            self.buf.clear();
            for px in rows.chunks_exact(from) {
                let rgb = [px[0], px[1], px[2]];
                let [r, g, b] = m.map_or(rgb, |m| hdrcodec_core::color::mat_apply_f32s(&m, rgb));
                self.buf.extend_from_slice(&[r, g, b]);
                if to == 4 {
                    self.buf.push(if from == 4 { px[3] } else { 1.0 });
                }
            }
            self.inner.put_rows(y + (k * band) as u32, &self.buf)?;
        }
        Ok(())
    }
}

/// The tile as the payload codec is given it: in primaries the payload can record as they are,
/// so that it neither converts nor notes anything about colour (the header's COLR says what the
/// samples are; [`to_header_colour`] brings each decoded tile back to it):
/// - a payload that records any primaries gets the tile as it is, or labelled BT.709 when the
///   frame's primaries are unspecified (the payload must write something; the header keeps
///   "unspecified" and decoding keeps the samples);
/// - one that records a fixed set gets the tile as it is when its primaries are in the set,
///   labelled unspecified when the set has that, else converted into BT.2020 (or the set's
///   first entry), which decoding converts back;
/// - one that records none gets the tile as it is.
fn for_payload(tile: HdrImage, signalling: ColorSignalling) -> HdrImage {
    let p = tile.color.primaries;
    let relabel = |mut tile: HdrImage, to: ColorPrimaries| {
        tile.color.primaries = to;
        tile
    };
    match signalling {
        ColorSignalling::Any if !p.is_specified() => relabel(tile, ColorPrimaries::Bt709),
        ColorSignalling::Only(set) if !set.contains(&p) => {
            if set.contains(&ColorPrimaries::Unspecified) {
                relabel(tile, ColorPrimaries::Unspecified)
            } else if let Some(&first) = set.first() {
                let to = if set.contains(&ColorPrimaries::Bt2020) { ColorPrimaries::Bt2020 } else { first };
                if p.is_specified() {
                    convert_primaries(&tile, to)
                } else {
                    relabel(tile, to)
                }
            } else {
                tile
            }
        }
        _ => tile,
    }
}

/// Encodes one still image: see [`encode_frames`].
pub fn encode_image(
    image: &HdrImage,
    payload_codec: &dyn ImageCodec,
    settings: &EncodeSettings,
    tile_size: Option<u32>,
) -> Result<Vec<u8>> {
    encode_frames(std::slice::from_ref(image), payload_codec, settings, tile_size)
}

/// Encodes a sequence of frames (all of one size and channel layout) into one `.hdrc` file.
///
/// Each frame is cut into tiles of `tile_size` × `tile_size` pixels (`None`: one tile per
/// frame); each tile is a complete stand-alone encoding by `payload_codec` with `settings`,
/// and the tiles are encoded in parallel on `settings.pool` (which the payload codec shares:
/// no second pool is started). COLR, HDRM and META come from the first frame.
pub fn encode_frames(
    frames: &[HdrImage],
    payload_codec: &dyn ImageCodec,
    settings: &EncodeSettings,
    tile_size: Option<u32>,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    write_frames_reporting(frames, payload_codec, settings, tile_size, &mut out)?;
    Ok(out)
}

/// At most this many different notes of the payload codec are kept (tiles clipped by
/// different amounts say different sentences); the rest are counted.
const MAX_TILE_NOTES: usize = 4;

/// [`encode_frames`] streamed into `out`, with what the payload codec reported for the tiles
/// (each distinct note once). The tiles are encoded a few at a time, in parallel on the
/// settings' pool, and written as soon as they are: only that batch of payloads is held.
///
/// Each tile goes to the payload codec in colour it can record ([`for_payload`]): a payload that
/// records primaries (OpenEXR, Radiance, LogLuv's XYZ, KTX2's set) records them, one that records
/// none stores the samples as they are, and the header's COLR says what they are either way
/// ([`decode_frames`] brings every tile back to it).
fn write_frames_reporting(
    frames: &[HdrImage],
    payload_codec: &dyn ImageCodec,
    settings: &EncodeSettings,
    tile_size: Option<u32>,
    out: &mut dyn std::io::Write,
) -> Result<Vec<String>> {
    let first = frames.first().ok_or_else(|| Error::invalid("no frames to encode"))?;
    if let Some(f) = frames
        .iter()
        .find(|f| (f.width(), f.height(), f.channels()) != (first.width(), first.height(), first.channels()))
    {
        return Err(Error::invalid(format!(
            "frames differ in size: {}x{} {:?} and {}x{} {:?}",
            first.width(),
            first.height(),
            first.channels(),
            f.width(),
            f.height(),
            f.channels()
        )));
    }
    let n = u32::try_from(frames.len()).map_err(|_| Error::invalid("more than 2^32 frames"))?;
    let mut head = Head::new(payload_codec.id(), first.width(), first.height(), first.channels()).with_frames(n);
    if let Some(t) = tile_size {
        if t == 0 {
            return Err(Error::invalid("tile size 0"));
        }
        head = head.with_tiles(t, t);
    }
    let tiles: Vec<(usize, DataHeader)> =
        frames.iter().enumerate().flat_map(|(i, _)| head.frame_tiles(i as u32).map(move |t| (i, t))).collect();
    let mut w = start_file(out, &head, &first.color, &first.metadata)?;
    let mut notes = TileNotes::default();
    let batch = settings.pool.threads().max(1) * 2;
    for group in tiles.chunks(batch) {
        let payloads: Vec<Result<(Vec<u8>, Vec<String>)>> = settings.pool.map(group.len(), |k| {
            let (i, t) = &group[k];
            encode_tile(&frames[*i], t, payload_codec, settings)
        });
        for ((_, t), p) in group.iter().zip(payloads) {
            let (bytes, tile_notes) = p?;
            w.write_data(t, &bytes)?;
            notes.add(tile_notes);
        }
    }
    w.finish()?;
    Ok(notes.finish(payload_codec.name()))
}

/// Starts a file: the signature, HEAD, and the COLR, HDRM and META of the (first) frame.
fn start_file<W: std::io::Write>(
    out: W,
    head: &Head,
    color: &ColorInfo,
    metadata: &[(String, String)],
) -> Result<Writer<W>> {
    let mut w = Writer::new(out, head)?;
    w.write_color(color)?;
    if let Some(h) = &color.hdr10 {
        w.write_hdr10(h)?;
    }
    if !metadata.is_empty() {
        w.write_meta(metadata)?;
    }
    Ok(w)
}

/// What the payload codec said about the tiles: each distinct note once, the first
/// [`MAX_TILE_NOTES`] kept, the rest counted.
#[derive(Default)]
struct TileNotes {
    notes: Vec<String>,
    more: Vec<String>,
}

impl TileNotes {
    fn add(&mut self, tile_notes: Vec<String>) {
        for n in tile_notes {
            if self.notes.contains(&n) || self.more.contains(&n) {
                continue;
            }
            if self.notes.len() < MAX_TILE_NOTES {
                self.notes.push(n);
            } else {
                self.more.push(n);
            }
        }
    }

    fn finish(mut self, payload: &str) -> Vec<String> {
        if !self.more.is_empty() {
            self.notes.push(format!("{} more notes of the {payload} payload on other tiles", self.more.len()));
        }
        self.notes
    }
}

/// A tiled still image encoded as its rows come: each row of tiles is gathered, its tiles
/// encoded in parallel on the settings' pool and written, in the order
/// [`write_frames_reporting`] writes them, so the file is the same. The chunks are assembled in
/// a buffer of one row of tiles' payloads and passed on to the caller's writer.
struct TiledRowEncoder {
    writer: Writer<Vec<u8>>,
    head: Head,
    payload_codec: Arc<dyn ImageCodec>,
    settings: EncodeSettings,
    color: ColorInfo,
    channels: Channels,
    rows: RowCounter,
    /// Rows of the row of tiles being gathered, which starts at row `band_y`.
    band: Vec<f32>,
    band_y: u32,
    notes: TileNotes,
}

impl TiledRowEncoder {
    /// Encodes and writes the tiles of the gathered rows.
    fn write_band(&mut self, out: &mut dyn hdrcodec_core::WriteSeek) -> Result<()> {
        let row_len = self.head.width as usize * self.channels.count();
        let rows = (self.band.len() / row_len) as u32;
        if rows > 0 {
            let band = HdrImage::new(
                self.head.width,
                rows,
                self.channels,
                std::mem::take(&mut self.band),
                self.color.clone(),
            )?;
            let tiles: Vec<DataHeader> = self.head.frame_tiles(0).filter(|t| t.y == self.band_y).collect();
            let payloads: Vec<Result<(Vec<u8>, Vec<String>)>> = self.settings.pool.map(tiles.len(), |k| {
                // The tile's place in the band.
                let within = DataHeader { y: 0, ..tiles[k] };
                encode_tile(&band, &within, self.payload_codec.as_ref(), &self.settings)
            });
            for (t, p) in tiles.iter().zip(payloads) {
                let (bytes, tile_notes) = p?;
                self.writer.write_data(t, &bytes)?;
                self.notes.add(tile_notes);
            }
            self.band = band.into_samples();
            self.band.clear();
            self.band_y += rows;
        }
        out.write_all(&std::mem::take(self.writer.output_mut()))?;
        Ok(())
    }
}

impl hdrcodec_core::RowEncoder for TiledRowEncoder {
    fn write_rows(&mut self, mut samples: &[f32], out: &mut dyn hdrcodec_core::WriteSeek) -> Result<()> {
        self.rows.take(samples)?;
        let row_len = self.head.width as usize * self.channels.count();
        let band_len = self.head.tile_height as usize * row_len;
        while !samples.is_empty() {
            let take = (band_len - self.band.len()).min(samples.len());
            self.band.extend_from_slice(&samples[..take]);
            samples = &samples[take..];
            if self.band.len() == band_len {
                self.write_band(out)?;
            }
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &mut dyn hdrcodec_core::WriteSeek) -> Result<hdrcodec_core::EncodeReport> {
        self.rows.check_complete()?;
        self.write_band(out)?;
        let TiledRowEncoder { writer, payload_codec, notes, .. } = *self;
        out.write_all(&writer.finish()?)?;
        let mut report = hdrcodec_core::EncodeReport::new();
        for n in notes.finish(payload_codec.name()) {
            report.note(format!("{} payload: {n}", payload_codec.name()));
        }
        Ok(report)
    }
}

/// Encodes the tile `t` of `frame` with the payload codec, in colour the payload can record
/// ([`for_payload`]); returns the payload and what the codec reported.
pub(crate) fn encode_tile(
    frame: &HdrImage,
    t: &DataHeader,
    payload_codec: &dyn ImageCodec,
    settings: &EncodeSettings,
) -> Result<(Vec<u8>, Vec<String>)> {
    let tile = for_payload(crop(frame, t)?, payload_codec.color_signalling());
    let mut out = Vec::new();
    let report = payload_codec.encode_to(&tile, settings, &mut out)?;
    Ok((out, report.notes))
}

/// Decodes a `.hdrc` file of one frame (use [`decode_frames`] for more). `resolve` gives the
/// codec for the HEAD's codec id.
pub fn decode_image<'c>(
    data: &[u8],
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<HdrImage> {
    let mut sink = ImageSink::new(&options.limits);
    decode_image_rows(data, options, resolve, &mut sink)?;
    sink.finish()
}

/// [`decode_image`] into `sink`, one row of tiles at a time.
pub fn decode_image_rows<'c>(
    data: &[u8],
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let r = Reader::new(data, &options.limits)?;
    let h = *r.head();
    let (info, codec) = single_frame_info(&h, r.color_info(), r.metadata(), resolve)?;
    let refs: Vec<_> = r.frame_tiles(0).copied().collect();
    decode_frame_rows(&h, 0, &refs, codec, options, &info, sink)
}

/// [`decode_image_rows`] from a file in a stream (from its current position) instead of bytes
/// in memory, never holding the file whole: the chunk structure is read and checked first
/// (every chunk but DATA whole, with its CRC), then each row of tiles is read when it is
/// decoded, a few DATA chunks at a time, each CRC-checked before its tile is decoded; the one
/// tile of an untiled file is decoded by the payload codec from the file
/// ([`ImageCodec::decode_rows_from`]: the raw payloads a band at a time), its CRC checked as
/// it is read and before this returns. Same rows and the same kinds of errors as
/// [`decode_image_rows`] on the file's bytes.
pub fn decode_image_rows_from<'c>(
    input: &mut dyn ReadSeek,
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let mut file = StreamFile::open(input, &options.limits)?;
    let layout = &file.layout;
    let h = layout.head;
    let (info, codec) = single_frame_info(&h, layout.color_info(), layout.metadata(), resolve)?;
    let locs = layout.frame_positions(0).map(|i| layout.data[i]).collect();
    decode_tiles(&h, 0, Tiles::Stream(&mut file, locs), codec, options, &info, sink)
}

/// What decoding the only frame of a file with this HEAD, colour and metadata gives, and its
/// payload codec; an error for a file of many frames or an unknown payload codec.
fn single_frame_info<'c>(
    h: &Head,
    color: ColorInfo,
    metadata: &[(String, String)],
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<(ImageInfo, &'c dyn ImageCodec)> {
    if h.frames != 1 {
        return Err(Error::unsupported(format!(
            "the .hdrc file holds {} frames; decode it as a frame sequence",
            h.frames
        )));
    }
    let codec = resolve(h.codec).ok_or_else(|| unknown_payload(h.codec))?;
    let mut info = ImageInfo::new(h.width, h.height, h.channels, color).with_format(stored_format(codec.name(), h));
    info.metadata = metadata.to_vec();
    Ok((info, codec))
}

/// Decodes every frame of a `.hdrc` file. The tiles of each frame are decoded in parallel on
/// `options.pool` and each must decode to exactly its rectangle's size. A tile that decodes with a different
/// channel layout (a payload codec without alpha) is converted: alpha dropped or set to 1. A
/// tile that decodes in other primaries or units than the header's COLR is converted into them
/// (a LogLuv payload decodes to BT.709); one that decodes unspecified is taken as the header's.
pub fn decode_frames<'c>(
    data: &[u8],
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<Vec<HdrImage>> {
    decode_reader(&Reader::new(data, &options.limits)?, options, resolve)
}

/// The stored format of a file in a few words: "rgbe payload, 15 tiles of 64x64" or "raw-f32
/// payload, untiled".
pub(crate) fn stored_format(payload: &str, h: &Head) -> String {
    if h.tiles_per_frame() == 1 {
        format!("{payload} payload, untiled")
    } else {
        format!("{payload} payload, {} tiles of {}x{}", h.tiles_per_frame(), h.tile_width, h.tile_height)
    }
}

/// The error for a payload codec id that no codec given to the decoder has.
fn unknown_payload(id: [u8; 4]) -> Error {
    Error::unsupported(format!("the payload codec '{}' of this .hdrc file", crate::format::type_name(id)))
}

fn decode_reader<'c>(
    r: &Reader<'_>,
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<Vec<HdrImage>> {
    let h = *r.head();
    let codec = resolve(h.codec).ok_or_else(|| unknown_payload(h.codec))?;
    let frame_bytes = (u64::from(h.width) * u64::from(h.height)).saturating_mul(h.channels.count() as u64 * 4);
    let limits = &options.limits;
    limits.check_alloc(frame_bytes.saturating_mul(u64::from(h.frames)), "the decoded frames")?;
    let color = r.color_info();
    let mut out = Vec::with_capacity(h.frames as usize);
    for f in 0..h.frames {
        let refs: Vec<_> = r.frame_tiles(f).copied().collect();
        out.push(decode_frame(&h, f, &refs, codec, options, &color, r.metadata())?);
    }
    Ok(out)
}

/// Decodes frame `f` from its tiles (in grid order), batches of tiles in parallel on `options.pool`;
/// each must decode to exactly its rectangle, and is brought into the header's colour `color`
/// ([`to_header_colour`]). The frame gets `color` and `metadata`.
pub(crate) fn decode_frame(
    h: &Head,
    f: u32,
    refs: &[DataRef<'_>],
    codec: &dyn ImageCodec,
    options: &DecodeOptions,
    color: &ColorInfo,
    metadata: &[(String, String)],
) -> Result<HdrImage> {
    let mut info = ImageInfo::new(h.width, h.height, h.channels, color.clone());
    info.metadata = metadata.to_vec();
    let mut sink = ImageSink::new(&options.limits);
    decode_frame_rows(h, f, refs, codec, options, &info, &mut sink)?;
    sink.finish()
}

/// The payloads of a group of tiles, borrowed from memory or read from a stream, and the charge
/// for holding what was read.
type Payloads<'p> = (Vec<Cow<'p, [u8]>>, Option<Allocation>);

/// Where the tiles of a frame come from: a file in memory that [`Reader`] validated whole, or
/// a file read from a stream ([`StreamFile`]), each DATA chunk read and CRC-checked when its
/// tile is decoded.
enum Tiles<'t, 'a> {
    Memory(&'t [DataRef<'a>]),
    Stream(&'t mut StreamFile<'a>, Vec<DataLoc>),
}

impl Tiles<'_, '_> {
    /// The frame's tiles in grid order: rectangle, chunk offset and payload length.
    fn locs(&self) -> Vec<DataLoc> {
        match self {
            Tiles::Memory(refs) => refs
                .iter()
                .map(|d| DataLoc {
                    header: d.header,
                    offset: d.offset,
                    len: (d.payload.len() + crate::format::DATA_HEADER_LEN) as u32,
                })
                .collect(),
            Tiles::Stream(_, locs) => locs.clone(),
        }
    }

    /// The payloads of the tiles `range` (positions in [`Tiles::locs`]), each named by `ctx`
    /// in errors; what is read from a stream is charged to `limits` while the returned
    /// allocation lives.
    fn payloads(
        &mut self,
        range: std::ops::Range<usize>,
        limits: &Limits,
        ctx: &dyn Fn(&DataLoc) -> String,
    ) -> Result<Payloads<'_>> {
        match self {
            Tiles::Memory(refs) => Ok((refs[range].iter().map(|d| Cow::Borrowed(d.payload)).collect(), None)),
            Tiles::Stream(file, locs) => {
                let locs = &locs[range];
                let bytes = locs.iter().map(|l| u64::from(l.len)).sum();
                let charge = limits.charge(bytes, "DATA chunks read from the file")?;
                let payloads = locs
                    .iter()
                    .map(|l| file.read_tile(l).map(Cow::Owned).map_err(|e| in_chunk(&ctx(l), e)))
                    .collect::<Result<_>>()?;
                Ok((payloads, Some(charge)))
            }
        }
    }

    /// Decodes the tile at position `i` into `sink` with the payload codec's row decoder: from
    /// memory, or read from the stream as the codec asks for it (its CRC checked before this
    /// returns).
    fn decode_rows(
        &mut self,
        i: usize,
        codec: &dyn ImageCodec,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        match self {
            Tiles::Memory(refs) => codec.decode_rows(refs[i].payload, options, sink),
            Tiles::Stream(file, locs) => file.decode_tile_rows(&locs[i], codec, options, sink),
        }
    }
}

/// [`decode_frame`] into `sink`, one row of tiles at a time: the tiles of a row decode a few
/// at a time and are copied into the row's band (in place when the sink allows it) as soon as
/// they have decoded, so the peak is the sink's storage plus a row of tiles, not two frames.
/// The sink is started (the frame allocated) only once the first tiles have decoded, so a
/// file whose data cannot even deliver those costs nothing.
pub(crate) fn decode_frame_rows(
    h: &Head,
    f: u32,
    refs: &[DataRef<'_>],
    codec: &dyn ImageCodec,
    options: &DecodeOptions,
    info: &ImageInfo,
    sink: &mut dyn RowSink,
) -> Result<()> {
    decode_tiles(h, f, Tiles::Memory(refs), codec, options, info, sink)
}

/// [`decode_frame_rows`] from wherever the tiles come from.
fn decode_tiles(
    h: &Head,
    f: u32,
    mut tiles: Tiles<'_, '_>,
    codec: &dyn ImageCodec,
    options: &DecodeOptions,
    info: &ImageInfo,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let locs = tiles.locs();
    if locs.is_empty() {
        return Err(Error::invalid(format!("frame {f} has no tiles")));
    }
    let records_scale = codec.records_nits_per_unit();
    let c = h.channels.count();
    let row_len = h.width as usize * c;
    let batch = options.pool.threads().max(1) * 2;
    let ctx = |d: &DataLoc| {
        let t = d.header;
        format!("DATA chunk at offset {} (tile {}x{} at ({}, {}) of frame {f})", d.offset, t.width, t.height, t.x, t.y)
    };
    // One tile covering the frame (an untiled file): the payload decodes straight into the sink.
    if let [only] = locs[..] {
        let t = only.header;
        if (t.x, t.y, t.width, t.height) == (0, 0, h.width, h.height) {
            let mut whole =
                WholeFrameSink { inner: sink, info, records_scale, convert: None, started: false, buf: Vec::new() };
            let tile_options = tile_options(options, t);
            return tiles.decode_rows(0, codec, &tile_options, &mut whole).map_err(|e| in_chunk(&ctx(&only), e));
        }
    }
    // Decodes a few tiles in parallel, each checked against its rectangle and brought into the
    // header's channels and colour.
    let decode_group = |group: &[DataLoc], payloads: &[Cow<'_, [u8]>]| -> Result<Vec<HdrImage>> {
        let decoded: Vec<Result<HdrImage>> = options.pool.map(group.len(), |k| {
            let t = group[k].header;
            let ctx = ctx(&group[k]);
            let img = codec.decode_with(&payloads[k], &tile_options(options, t)).map_err(|e| in_chunk(&ctx, e))?;
            if (img.width(), img.height()) != (t.width, t.height) {
                return Err(Error::invalid(format!("{ctx}: the payload decodes to {}x{}", img.width(), img.height())));
            }
            // A tile already in the header's channels is kept as it is (no copy).
            let img = if img.channels() == h.channels { img } else { img.with_channels(h.channels) };
            Ok(to_header_colour(img, &info.color, records_scale))
        });
        decoded.into_iter().collect()
    };
    // Reads and decodes the tiles at `range` of `locs`.
    let mut read_group = |range: std::ops::Range<usize>| -> Result<Vec<HdrImage>> {
        let (payloads, _charge) = tiles.payloads(range.clone(), &options.limits, &ctx)?;
        decode_group(&locs[range], &payloads)
    };
    // Copies decoded tiles into the band of their row of tiles.
    let place = |band: &mut [f32], group: &[DataLoc], decoded: Vec<HdrImage>| -> Result<()> {
        for (d, tile) in group.iter().zip(decoded) {
            let t = d.header;
            for row in 0..t.height {
                let at = row as usize * row_len + t.x as usize * c;
                let dst = band.get_mut(at..at + t.width as usize * c).ok_or_else(|| {
                    Error::invalid(format!("frame {f}: a tile at ({}, {}) lies outside the frame", t.x, t.y))
                })?;
                dst.copy_from_slice(tile.row(row));
            }
        }
        Ok(())
    };
    let mut started = false;
    let mut scratch = Scratch::new(&options.limits);
    let mut next = 0;
    while let Some(first) = locs.get(next) {
        let (y, tile_height) = (first.header.y, first.header.height);
        let in_row = locs[next..].iter().take_while(|d| d.header.y == y).count();
        let row = next..next + in_row;
        next += in_row;
        if locs[row.clone()].iter().any(|d| d.header.height != tile_height)
            || y.checked_add(tile_height).is_none_or(|end| end > h.height)
        {
            return Err(Error::invalid(format!("frame {f}: the tiles at row {y} do not form a row of the grid")));
        }
        let first_end = row.start + batch.min(in_row);
        let first_tiles = read_group(row.start..first_end)?;
        if !started {
            sink.start(info)?;
            started = true;
        }
        fill_rows(sink, y, tile_height, row_len, &mut scratch, |band| {
            place(band, &locs[row.start..first_end], first_tiles)?;
            let mut at = first_end;
            while at < row.end {
                let end = (at + batch).min(row.end);
                place(band, &locs[at..end], read_group(at..end)?)?;
                at = end;
            }
            Ok(())
        })?;
    }
    Ok(())
}

/// The `.hdrc` container as an [`ImageCodec`] (name `hdrc`, id `HDRC`, extension `hdrc`).
///
/// Encode options: `payload=<codec name>` (default `raw-f32`, lossless), `tile=<pixels>`
/// (square tiles; absent or 0: one tile), and `payload.<key>=<value>`, passed to the payload
/// codec as `<key>=<value>`. Any other option is an error. Decoding finds the payload codec by
/// the id in HEAD among the codecs it was given. Multi-frame files are decoded by
/// [`decode_frames`]; `decode` accepts single-frame files.
pub struct HdrcCodec {
    codecs: Vec<Arc<dyn ImageCodec>>,
}

impl Default for HdrcCodec {
    /// Only the raw payload codecs.
    fn default() -> Self {
        HdrcCodec::new(Vec::new())
    }
}

impl HdrcCodec {
    /// A container codec that may use `codecs` for payloads; the raw codecs are always added,
    /// and an `.hdrc` codec in the list is ignored (no nested containers).
    pub fn new(codecs: Vec<Arc<dyn ImageCodec>>) -> Self {
        let mut all: Vec<Arc<dyn ImageCodec>> = Vec::new();
        let raw: [Arc<dyn ImageCodec>; 2] = [Arc::new(RawF32Codec), Arc::new(RawF16Codec)];
        for c in codecs.into_iter().chain(raw) {
            if c.id() != *b"HDRC" && !all.iter().any(|a| a.id() == c.id()) {
                all.push(c);
            }
        }
        HdrcCodec { codecs: all }
    }

    /// The payload codecs this codec can use.
    pub fn codecs(&self) -> &[Arc<dyn ImageCodec>] {
        &self.codecs
    }

    fn resolve(&self, id: [u8; 4]) -> Option<&dyn ImageCodec> {
        self.codecs.iter().find(|c| c.id() == id).map(|c| c.as_ref())
    }

    /// What [`probe`](ImageCodec::probe) says of a file with this HEAD and colour: an error if
    /// the payload codec is unknown.
    fn head_info(&self, HeadInfo { head: h, color }: HeadInfo) -> Result<ImageInfo> {
        let codec = self.resolve(h.codec).ok_or_else(|| unknown_payload(h.codec))?;
        let format = stored_format(codec.name(), &h);
        Ok(ImageInfo::new(h.width, h.height, h.channels, color).with_format(format).with_frames(h.frames))
    }
}

impl ImageCodec for HdrcCodec {
    fn name(&self) -> &'static str {
        "hdrc"
    }
    fn id(&self) -> [u8; 4] {
        *b"HDRC"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["hdrc"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(&SIGNATURE)
    }
    /// The COLR chunk records any primaries.
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::Any
    }
    /// The COLR chunk records `nits_per_unit`.
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    /// HEAD, COLR and HDRM only ([`crate::probe`]): the size, channels, colour and frame
    /// count of every frame, and the payload codec and tiling as the format ("rgbe payload,
    /// 15 tiles of 64x64"). Fails, as decoding would, if the payload codec is unknown.
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        self.head_info(crate::reader::probe(data, limits)?)
    }
    /// The file's chunks but DATA (and the tile header of each DATA chunk), read from the file
    /// as decoding reads them before the first tile: a tile is never read.
    fn probe_from(&self, input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        self.head_info(crate::stream::probe(input, limits)?)
    }
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        decode_image_rows(data, options, &|id| self.resolve(id), sink)
    }
    /// Reads the file's structure, then each DATA chunk as it is decoded, its CRC checked as it
    /// is read ([`decode_image_rows_from`]): the file is never held whole.
    fn decode_rows_from(
        &self,
        input: &mut dyn ReadSeek,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        decode_image_rows_from(input, options, &|id| self.resolve(id), sink)
    }
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        let p = self.payload_settings(settings)?;
        let (codec, inner, tile) = (p.codec, p.settings, p.tile);
        let notes = write_frames_reporting(std::slice::from_ref(image), codec.as_ref(), &inner, tile, out)?;
        let mut report = hdrcodec_core::EncodeReport::new();
        for n in notes {
            report.note(format!("{} payload: {n}", codec.name()));
        }
        Ok(report)
    }
    /// Tiled images, a row of tiles at a time; an image in one tile needs the whole image.
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        let p = self.payload_settings(settings)?;
        let Some(tile) = p.tile else { return Ok(None) };
        let head = Head::new(p.codec.id(), info.width, info.height, info.channels).with_tiles(tile, tile);
        let writer = start_file(Vec::new(), &head, &info.color, &info.metadata)?;
        Ok(Some(Box::new(TiledRowEncoder {
            writer,
            head,
            payload_codec: p.codec,
            settings: p.settings,
            color: info.color.clone(),
            channels: info.channels,
            rows: RowCounter::new(info.width as usize * info.channels.count(), info.height),
            band: Vec::new(),
            band_y: 0,
            notes: TileNotes::default(),
        })))
    }
}

/// What the container's encode options choose: the payload codec, its settings, the tiles.
pub(crate) struct PayloadSettings {
    pub(crate) codec: Arc<dyn ImageCodec>,
    /// The settings with the `payload.<key>` options as the payload codec's `<key>`.
    pub(crate) settings: EncodeSettings,
    /// Square tile size; `None`: one tile per frame.
    pub(crate) tile: Option<u32>,
}

impl HdrcCodec {
    /// Parses the container's options (`payload`, `tile`, `payload.<key>`); any other key is
    /// an error.
    pub(crate) fn payload_settings(&self, settings: &EncodeSettings) -> Result<PayloadSettings> {
        let (inner, own): (Vec<_>, Vec<_>) =
            settings.options.iter().cloned().partition(|(k, _)| k.starts_with("payload."));
        let mut own_settings = settings.clone();
        own_settings.options = own;
        let own = own_settings;
        own.check_options("hdrc", &["payload", "tile", "payload.<key>"])?;
        let name = own.option("payload").unwrap_or("raw-f32");
        let codec = self.codecs.iter().find(|c| c.name() == name).ok_or_else(|| {
            let names: Vec<_> = self.codecs.iter().map(|c| c.name()).collect();
            Error::invalid(format!("option payload={name}: unknown codec (known: {})", names.join(", ")))
        })?;
        let tile = own.parse_option::<u32>("tile")?.filter(|&t| t > 0);
        let mut inner_settings = settings.clone();
        inner_settings.options = inner.into_iter().map(|(k, v)| (k["payload.".len()..].to_string(), v)).collect();
        Ok(PayloadSettings { codec: codec.clone(), settings: inner_settings, tile })
    }

    /// The payload codec with this id, shared.
    pub(crate) fn payload_codec(&self, id: [u8; 4]) -> Result<Arc<dyn ImageCodec>> {
        self.codecs.iter().find(|c| c.id() == id).cloned().ok_or_else(|| unknown_payload(id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::{Channels, Chromaticities, EncodeReport};

    fn tile(primaries: ColorPrimaries, nits_per_unit: f32) -> HdrImage {
        let samples = vec![1.0, 0.5, 0.25, 0.75, 2.0, 0.0, 4.0, 0.5];
        let color = ColorInfo { primaries, nits_per_unit, hdr10: None };
        HdrImage::new(2, 1, Channels::Rgba, samples, color).unwrap()
    }

    fn header(primaries: ColorPrimaries, nits_per_unit: f32) -> ColorInfo {
        ColorInfo { primaries, nits_per_unit, hdr10: None }
    }

    #[test]
    fn tiles_in_other_primaries_are_converted_to_the_header_s() {
        // LogLuv decodes to BT.709: a BT.2020 header gets BT.2020 samples back.
        let t = tile(ColorPrimaries::Bt709, 100.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Bt2020, 100.0), true);
        let want = convert_primaries(&t, ColorPrimaries::Bt2020);
        assert_eq!(out.color.primaries, ColorPrimaries::Bt2020);
        for (a, b) in out.samples().iter().zip(want.samples()) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
        assert_eq!((out.samples()[3], out.samples()[7]), (0.75, 0.5), "alpha untouched");
    }

    #[test]
    fn unspecified_tiles_and_headers_keep_the_samples() {
        // A raw, PFM or DDS tile was written from the header's primaries.
        let t = tile(ColorPrimaries::Unspecified, 100.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Bt2020, 100.0), false);
        assert_eq!((out.samples(), out.color.primaries), (t.samples(), ColorPrimaries::Bt2020));
        // A header that says unspecified: a payload that had to write something (RGBE's BT.709)
        // does not make the container guess.
        let t = tile(ColorPrimaries::Bt709, 100.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Unspecified, 100.0), false);
        assert_eq!((out.samples(), out.color.primaries), (t.samples(), ColorPrimaries::Unspecified));
        // Custom chromaticities rounded to f32 by a payload's file (OpenEXR) are the same.
        let ch = Chromaticities { red: [0.7, 0.29], green: [0.15, 0.8], blue: [0.13, 0.05], white: [0.3127, 0.329] };
        let rounded = ch.red.map(|v| f64::from(v as f32));
        let t = tile(ColorPrimaries::Custom(Chromaticities { red: rounded, ..ch }), 100.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Custom(ch), 100.0), true);
        assert_eq!(out.samples(), t.samples());
    }

    #[test]
    fn a_recorded_scale_is_brought_to_the_header_s_units() {
        // The payload recorded 50 cd/m² per unit (a scale its encoder chose): 2.0 of its units
        // is 1.0 of the header's 100.
        let t = tile(ColorPrimaries::Bt709, 50.0);
        let out = to_header_colour(t, &header(ColorPrimaries::Bt709, 100.0), true);
        assert_eq!(out.samples(), [0.5, 0.25, 0.125, 0.75, 1.0, 0.0, 2.0, 0.5]);
        assert_eq!(out.color.nits_per_unit, 100.0);
        // A payload that records no scale decodes at the default 100: its samples are in the
        // header's units already.
        let t = tile(ColorPrimaries::Bt709, 100.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Bt709, 203.0), false);
        assert_eq!((out.samples(), out.color.nits_per_unit), (t.samples(), 203.0));
        // Both at once: one matrix.
        let t = tile(ColorPrimaries::Bt709, 200.0);
        let out = to_header_colour(t.clone(), &header(ColorPrimaries::Bt2020, 100.0), true);
        let want = convert_primaries(&t, ColorPrimaries::Bt2020);
        for (i, (a, b)) in out.samples().iter().zip(want.samples()).enumerate() {
            let k = if i % 4 == 3 { 1.0 } else { 2.0 };
            assert!((a - k * b).abs() < 1e-5, "{i}: {a} vs {k} x {b}");
        }
    }

    #[test]
    fn payloads_get_tiles_in_colour_they_record() {
        let t = |p| tile(p, 100.0);
        let only: ColorSignalling = ColorSignalling::Only(&[ColorPrimaries::Bt709, ColorPrimaries::Bt2020]);
        let with_unspecified: ColorSignalling =
            ColorSignalling::Only(&[ColorPrimaries::Unspecified, ColorPrimaries::Bt709, ColorPrimaries::Bt2020]);
        let cases = [
            (ColorSignalling::Any, ColorPrimaries::DciP3, ColorPrimaries::DciP3, false),
            (ColorSignalling::Any, ColorPrimaries::Unspecified, ColorPrimaries::Bt709, false),
            (ColorSignalling::None, ColorPrimaries::DciP3, ColorPrimaries::DciP3, false),
            (only, ColorPrimaries::Bt709, ColorPrimaries::Bt709, false),
            (only, ColorPrimaries::DciP3, ColorPrimaries::Bt2020, true),
            (only, ColorPrimaries::Unspecified, ColorPrimaries::Bt2020, false),
            (with_unspecified, ColorPrimaries::DciP3, ColorPrimaries::Unspecified, false),
        ];
        for (signalling, from, to, converted) in cases {
            let out = for_payload(t(from), signalling);
            assert_eq!(out.color.primaries, to, "{signalling:?} {}", from.name());
            assert_eq!(out.samples() != t(from).samples(), converted, "{signalling:?} {}", from.name());
        }
    }

    /// Raw f32 samples. `Noisy` says, for every tile, how many of its samples exceed 1 (as a
    /// codec that clips would), and records no colour; `Elsewhere` decodes without alpha, in
    /// BT.709 at 200 nits per unit (a payload that records its own colour and scale in other
    /// terms than the header's).
    #[derive(Clone, Copy, PartialEq)]
    enum Test {
        Noisy,
        Elsewhere,
    }
    use Test::{Elsewhere, Noisy};
    impl ImageCodec for Test {
        fn name(&self) -> &'static str {
            if *self == Noisy {
                "noisy"
            } else {
                "elsewhere"
            }
        }
        fn id(&self) -> [u8; 4] {
            if *self == Noisy {
                *b"NOIS"
            } else {
                *b"ELSW"
            }
        }
        fn extensions(&self) -> &'static [&'static str] {
            &[]
        }
        fn sniff(&self, _: &[u8]) -> bool {
            false
        }
        fn color_signalling(&self) -> ColorSignalling {
            if *self == Noisy {
                ColorSignalling::None
            } else {
                ColorSignalling::Any
            }
        }
        fn records_nits_per_unit(&self) -> bool {
            *self == Elsewhere
        }
        fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
            let image = crate::RawF32Codec.decode_with(data, options)?;
            if *self == Noisy {
                return Ok(image);
            }
            let mut image = image.with_channels(Channels::Rgb);
            image.color = ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: 200.0, hdr10: None };
            Ok(image)
        }
        fn encode_to(
            &self,
            image: &HdrImage,
            settings: &EncodeSettings,
            out: &mut dyn std::io::Write,
        ) -> Result<EncodeReport> {
            let mut report = crate::RawF32Codec.encode_to(image, settings, out)?;
            if *self == Noisy {
                let n = image.samples().iter().filter(|&&v| v > 1.0).count();
                report.note(format!("{n} samples above 1"));
                report.note("the same sentence from every tile");
            }
            Ok(report)
        }
    }

    #[test]
    fn payload_notes_are_reported_once_each() {
        // 8 tiles of 2x1 pixels (6 samples), tile k with min(k, 6) samples above 1.
        let samples: Vec<f32> = (0..16 * 3).map(|i| if i % 6 < i / 6 { 2.0 } else { 0.5 }).collect();
        let img = HdrImage::new(16, 1, Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let notes = write_frames_reporting(
            std::slice::from_ref(&img),
            &Noisy,
            &EncodeSettings::default(),
            Some(2),
            &mut Vec::new(),
        )
        .unwrap();
        let want = [
            "0 samples above 1",
            "the same sentence from every tile",
            "1 samples above 1",
            "2 samples above 1",
            "4 more notes of the noisy payload on other tiles",
        ];
        assert_eq!(notes, want);
        let codec = HdrcCodec::new(vec![Arc::new(Noisy)]);
        let mut out = Vec::new();
        let s = EncodeSettings::default().with_option("payload", "noisy");
        let report = codec.encode_to(&img, &s, &mut out).unwrap();
        assert_eq!(
            report.notes,
            ["noisy payload: 27 samples above 1", "noisy payload: the same sentence from every tile"]
        );
        assert_eq!(codec.decode(&out, &Default::default()).unwrap(), img);
    }

    /// An untiled frame decodes straight into the frame's sink, converted there: the same
    /// samples as the same image in tiles, each tile converted on its own.
    #[test]
    fn an_untiled_frame_is_converted_as_tiles_are() {
        let samples: Vec<f32> = (0..13 * 9 * 4).map(|i| (i as f32 * 0.37).sin().abs() * 3.0).collect();
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None };
        let img = HdrImage::new(13, 9, Channels::Rgba, samples, color).unwrap();
        let resolve = |_: [u8; 4]| Some(&Elsewhere as &dyn ImageCodec);
        let decode = |tile| {
            let file = encode_image(&img, &Elsewhere, &EncodeSettings::default(), tile).unwrap();
            decode_image(&file, &Limits::default().into(), &resolve).unwrap()
        };
        let (whole, tiled) = (decode(None), decode(Some(4)));
        assert_eq!(whole.samples(), tiled.samples());
        // From a stream, both ways (the payload read whole by its default `decode_rows_from`).
        for tile in [None, Some(4)] {
            let file = encode_image(&img, &Elsewhere, &EncodeSettings::default(), tile).unwrap();
            let mut sink = ImageSink::new(&Limits::default());
            let options = DecodeOptions::new(Limits::default());
            decode_image_rows_from(&mut std::io::Cursor::new(file), &options, &resolve, &mut sink).unwrap();
            assert_eq!(sink.finish().unwrap().samples(), whole.samples(), "tile {tile:?}");
        }
        assert_eq!(whole.color, img.color);
        assert_eq!(whole.channels(), Channels::Rgba);
        // Converted: alpha set to 1, the colour brought to BT.2020 at 100 nits per unit.
        assert!(whole.samples().chunks_exact(4).all(|p| p[3] == 1.0));
        assert!(whole.samples().chunks_exact(4).zip(img.samples().chunks_exact(4)).any(|(a, b)| a[0] != b[0]));
    }
}
