//! Whole images and frame sequences in `.hdrc`, with the tiles coded by another codec, in
//! parallel (rayon), and [`HdrcCodec`], the container as an [`ImageCodec`].

use crate::format::{DataHeader, Head, SIGNATURE};
use crate::raw::{RawF16Codec, RawF32Codec};
use crate::reader::{in_chunk, Reader};
use crate::writer::Writer;
use hdrcodec_core::{DecodeOptions, EncodeSettings, Error, HdrImage, ImageCodec, Result};
use std::sync::Arc;

/// The pixels of `image` inside the tile `t`, as an image of their own (same colour, no metadata).
fn crop(image: &HdrImage, t: &DataHeader) -> Result<HdrImage> {
    let c = image.channels().count();
    let mut samples = Vec::with_capacity(t.width as usize * t.height as usize * c);
    for y in t.y..t.y + t.height {
        samples.extend_from_slice(&image.row(y)[t.x as usize * c..(t.x + t.width) as usize * c]);
    }
    HdrImage::new(t.width, t.height, image.channels(), samples, image.color.clone())
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
    let payloads: Vec<Result<Vec<u8>>> = settings.pool.map(tiles.len(), |k| {
        let (i, t) = &tiles[k];
        let tile = crop(&frames[*i], t)?;
        payload_codec.encode(&tile, settings)
    });
    let mut w = Writer::new(Vec::new(), &head)?;
    w.write_color(&first.color)?;
    if let Some(h) = &first.color.hdr10 {
        w.write_hdr10(h)?;
    }
    if !first.metadata.is_empty() {
        w.write_meta(&first.metadata)?;
    }
    for ((_, t), p) in tiles.iter().zip(payloads) {
        w.write_data(t, &p?)?;
    }
    w.finish()
}

/// Decodes a `.hdrc` file of one frame (use [`decode_frames`] for more). `resolve` gives the
/// codec for the HEAD's codec id.
pub fn decode_image<'c>(
    data: &[u8],
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<HdrImage> {
    let r = Reader::new(data, &options.limits)?;
    if r.head().frames != 1 {
        return Err(Error::unsupported(format!(
            "the .hdrc file holds {} frames; decode it as a frame sequence",
            r.head().frames
        )));
    }
    let mut v = decode_reader(&r, options, resolve)?;
    Ok(v.remove(0))
}

/// Decodes every frame of a `.hdrc` file. The tiles of each frame are decoded in parallel on
/// `options.pool` and each must decode to exactly its rectangle's size. A tile that decodes with a different
/// channel layout (a payload codec without alpha) is converted: alpha dropped or set to 1.
pub fn decode_frames<'c>(
    data: &[u8],
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<Vec<HdrImage>> {
    decode_reader(&Reader::new(data, &options.limits)?, options, resolve)
}

fn decode_reader<'c>(
    r: &Reader<'_>,
    options: &DecodeOptions,
    resolve: &dyn Fn([u8; 4]) -> Option<&'c dyn ImageCodec>,
) -> Result<Vec<HdrImage>> {
    let h = *r.head();
    let codec = resolve(h.codec).ok_or_else(|| {
        Error::unsupported(format!("the payload codec '{}' of this .hdrc file", crate::format::type_name(h.codec)))
    })?;
    let frame_bytes = (u64::from(h.width) * u64::from(h.height)).saturating_mul(h.channels.count() as u64 * 4);
    let limits = &options.limits;
    limits.check_alloc(frame_bytes.saturating_mul(u64::from(h.frames)), "the decoded frames")?;
    let color = r.color_info();
    let c = h.channels.count();
    let mut out = Vec::with_capacity(h.frames as usize);
    for f in 0..h.frames {
        let refs: Vec<_> = r.frame_tiles(f).collect();
        let tiles: Vec<Result<HdrImage>> = options.pool.map(refs.len(), |k| {
            let d = &refs[k];
            let t = d.header;
            // A clone shares the caller's allocation budget; the tile's own size bounds it.
            let mut tile_options = options.clone();
            tile_options.limits.max_width = t.width;
            tile_options.limits.max_height = t.height;
            tile_options.limits.max_pixels = u64::from(t.width) * u64::from(t.height);
            let ctx = format!(
                "DATA chunk at offset {} (tile {}x{} at ({}, {}) of frame {f})",
                d.offset, t.width, t.height, t.x, t.y
            );
            let img = codec.decode_with(d.payload, &tile_options).map_err(|e| in_chunk(&ctx, e))?;
            if (img.width(), img.height()) != (t.width, t.height) {
                return Err(Error::invalid(format!("{ctx}: the payload decodes to {}x{}", img.width(), img.height())));
            }
            Ok(img.with_channels(h.channels))
        });
        let tiles = tiles.into_iter().collect::<Result<Vec<_>>>()?;
        // Allocated only once every tile has decoded to its rectangle.
        let mut frame = HdrImage::zeroed(h.width, h.height, h.channels);
        for (d, tile) in refs.iter().zip(tiles) {
            let t = d.header;
            for row in 0..t.height {
                let dst = &mut frame.row_mut(t.y + row)[t.x as usize * c..(t.x + t.width) as usize * c];
                dst.copy_from_slice(tile.row(row));
            }
        }
        frame.color = color.clone();
        frame.metadata = r.metadata().to_vec();
        out.push(frame);
    }
    Ok(out)
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
    fn decode_with(&self, data: &[u8], options: &hdrcodec_core::DecodeOptions) -> Result<HdrImage> {
        decode_image(data, options, &|id| self.resolve(id))
    }
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
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
        let inner = inner_settings;
        out.write_all(&encode_image(image, codec.as_ref(), &inner, tile)?)?;
        Ok(hdrcodec_core::EncodeReport::new())
    }
}
