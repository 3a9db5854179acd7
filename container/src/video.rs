//! Frame streams in `.hdrc`: [`HdrcVideoCodec`], the container as a [`VideoCodec`]. The encoder
//! writes each pushed frame's tiles as it comes, through the streaming [`Writer`]; the decoder
//! validates the file once and hands out one frame at a time.

use crate::format::{DataHeader, Head, DATA_HEADER_LEN};
use crate::image::{decode_frame, encode_tile, stored_format, HdrcCodec};
use crate::reader::{DataRef, Reader};
use crate::writer::Writer;
use hdrcodec_core::{
    ColorInfo, DecodeOptions, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Result, VideoCodec, VideoDecoder,
    VideoEncoder,
};
use std::io::Write;
use std::ops::Range;
use std::sync::Arc;

/// The `.hdrc` container as a [`VideoCodec`] (name `hdrc`, extension `hdrc`): a sequence of
/// frames, each cut into tiles coded by a payload codec, as [`encode_frames`](crate::encode_frames)
/// writes them, but streamed.
///
/// - Encoding: [`begin_encode`](VideoCodec::begin_encode) writes the signature, HEAD, COLR and
///   HDRM (from `info.color`) at once; each [`push_frame`](VideoEncoder::push_frame) encodes the
///   frame's tiles (in parallel on `settings.pool`) and writes them; `finish` writes INDX and END.
///   The options are [`HdrcCodec`]'s: `payload=<codec>`, `tile=<pixels>`, `payload.<key>=<value>`.
///   **HEAD records the frame count before the first tile**, and the writer never seeks back,
///   so `info.frames` must give it: 0 (unknown) is refused at `begin_encode`, a frame past the
///   count is refused by `push_frame`, and `finish` fails if fewer frames came. The META chunk
///   comes from the first frame's metadata. Every frame must have the stream's size, channels,
///   primaries and `nits_per_unit`. After a failed write the output is incomplete (it has no
///   END chunk, so every reader rejects it) and the encoder refuses further frames.
/// - Decoding: [`begin_decode`](VideoCodec::begin_decode) validates the whole file (every CRC,
///   the tile grid, the index) as [`Reader::new`] does and checks one frame's size against the
///   limits; each [`next_frame`](VideoDecoder::next_frame) then decodes one frame's tiles (in
///   parallel on `options.pool`) into a frame, so only one decoded frame is held at a time.
///
/// The output is byte for byte what [`encode_frames`](crate::encode_frames) writes for the same
/// frames when `info.color` is the first frame's colour.
pub struct HdrcVideoCodec {
    image: HdrcCodec,
}

impl Default for HdrcVideoCodec {
    /// Only the raw payload codecs.
    fn default() -> Self {
        HdrcVideoCodec { image: HdrcCodec::default() }
    }
}

impl HdrcVideoCodec {
    /// A stream codec that may use `codecs` for payloads (with the raw codecs always added, as
    /// [`HdrcCodec::new`] does).
    pub fn new(codecs: Vec<Arc<dyn ImageCodec>>) -> Self {
        HdrcVideoCodec { image: HdrcCodec::new(codecs) }
    }

    /// The payload codecs this codec can use.
    pub fn codecs(&self) -> &[Arc<dyn ImageCodec>] {
        self.image.codecs()
    }
}

impl From<HdrcCodec> for HdrcVideoCodec {
    fn from(image: HdrcCodec) -> Self {
        HdrcVideoCodec { image }
    }
}

impl VideoCodec for HdrcVideoCodec {
    fn name(&self) -> &'static str {
        "hdrc"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["hdrc"]
    }
    /// Fails unless `info.frames > 0` (HEAD records the count up front), and on the options'
    /// errors; writes the signature, HEAD, COLR and HDRM to `out`.
    fn begin_encode(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
        out: Box<dyn Write + Send>,
    ) -> Result<Box<dyn VideoEncoder>> {
        if info.frames == 0 {
            return Err(Error::invalid(
                "an .hdrc stream needs its frame count up front (HEAD records it before the first tile): set info.frames",
            ));
        }
        let payload = self.image.payload_settings(settings)?;
        let mut head = Head::new(payload.codec.id(), info.width, info.height, info.channels).with_frames(info.frames);
        if let Some(t) = payload.tile {
            head = head.with_tiles(t, t);
        }
        let mut writer = Writer::new(out, &head)?;
        writer.write_color(&info.color)?;
        if let Some(h) = &info.color.hdr10 {
            writer.write_hdr10(h)?;
        }
        Ok(Box::new(HdrcFrameEncoder {
            writer: Some(writer),
            head,
            color: info.color.clone(),
            codec: payload.codec,
            settings: payload.settings,
            pushed: 0,
        }))
    }

    /// Validates the whole stream (see [`Reader::new`]); fails if the payload codec is unknown.
    fn begin_decode(&self, data: Arc<[u8]>, options: &DecodeOptions) -> Result<Box<dyn VideoDecoder>> {
        let r = Reader::new(&data, &options.limits)?;
        let head = *r.head();
        let codec = self.image.payload_codec(head.codec)?;
        // Every tile's place in the file, frame by frame in grid order: a DATA payload follows
        // the chunk's length and type and the tile header.
        let tiles = (0..head.frames)
            .flat_map(|f| r.frame_tiles(f))
            .map(|d| {
                let at = d.offset as usize + 8 + DATA_HEADER_LEN;
                (d.header, d.offset, at..at + d.payload.len())
            })
            .collect();
        let format = stored_format(codec.name(), &head);
        let info = ImageInfo::new(head.width, head.height, head.channels, r.color_info())
            .with_frames(head.frames)
            .with_format(format);
        let metadata = r.metadata().to_vec();
        drop(r);
        Ok(Box::new(HdrcFrameDecoder { data, head, info, metadata, codec, options: options.clone(), tiles, next: 0 }))
    }
}

/// The streaming encoder of [`HdrcVideoCodec`].
struct HdrcFrameEncoder {
    /// `None` once a write failed: the output is broken and no frame may follow.
    writer: Option<Writer<Box<dyn Write + Send>>>,
    head: Head,
    color: ColorInfo,
    codec: Arc<dyn ImageCodec>,
    settings: EncodeSettings,
    pushed: u32,
}

impl HdrcFrameEncoder {
    /// Refuses a frame that does not fit the stream, before anything is written.
    fn check(&self, frame: &HdrImage) -> Result<()> {
        let h = &self.head;
        if self.pushed >= h.frames {
            return Err(Error::invalid(format!(
                "the stream was begun for {} frames; frame {} is one too many",
                h.frames, self.pushed
            )));
        }
        if (frame.width(), frame.height(), frame.channels()) != (h.width, h.height, h.channels) {
            return Err(Error::invalid(format!(
                "frame {} is {}x{} {:?}; the stream is {}x{} {:?}",
                self.pushed,
                frame.width(),
                frame.height(),
                frame.channels(),
                h.width,
                h.height,
                h.channels
            )));
        }
        let (c, s) = (&frame.color, &self.color);
        if c.primaries != s.primaries || c.nits_per_unit != s.nits_per_unit {
            return Err(Error::invalid(format!(
                "frame {} is in {} primaries at {} nits per unit; the stream's COLR says {} at {}",
                self.pushed,
                c.primaries.name(),
                c.nits_per_unit,
                s.primaries.name(),
                s.nits_per_unit
            )));
        }
        Ok(())
    }
}

impl VideoEncoder for HdrcFrameEncoder {
    fn push_frame(&mut self, frame: &HdrImage) -> Result<()> {
        if self.writer.is_none() {
            return Err(Error::invalid("an earlier write to this .hdrc stream failed; the output is incomplete"));
        }
        self.check(frame)?;
        let f = self.pushed;
        let tiles: Vec<DataHeader> = self.head.frame_tiles(f).collect();
        let (codec, settings) = (&self.codec, &self.settings);
        // As `encode_frames` does: each tile in colour the payload can record. The payload's
        // notes (values it clipped) have no way out of `push_frame` and are dropped.
        let payloads: Vec<Result<(Vec<u8>, Vec<String>)>> =
            settings.pool.map(tiles.len(), |k| encode_tile(frame, &tiles[k], codec.as_ref(), settings));
        let payloads: Vec<Vec<u8>> =
            payloads.into_iter().map(|p| p.map(|(bytes, _notes)| bytes)).collect::<Result<_>>()?;
        let mut writer = self.writer.take().expect("checked above");
        let written = (|| {
            if f == 0 && !frame.metadata.is_empty() {
                writer.write_meta(&frame.metadata)?;
            }
            for (t, p) in tiles.iter().zip(&payloads) {
                writer.write_data(t, p)?;
            }
            Ok::<(), Error>(())
        })();
        written?;
        self.writer = Some(writer);
        self.pushed += 1;
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<u64> {
        let writer = self
            .writer
            .ok_or_else(|| Error::invalid("an earlier write to this .hdrc stream failed; the output is incomplete"))?;
        if self.pushed != self.head.frames {
            return Err(Error::invalid(format!(
                "{} of the {} frames the stream was begun for were pushed (HEAD records the count)",
                self.pushed, self.head.frames
            )));
        }
        writer.finish()?;
        Ok(u64::from(self.pushed))
    }
}

/// The frame-at-a-time decoder of [`HdrcVideoCodec`].
struct HdrcFrameDecoder {
    data: Arc<[u8]>,
    head: Head,
    info: ImageInfo,
    metadata: Vec<(String, String)>,
    codec: Arc<dyn ImageCodec>,
    options: DecodeOptions,
    /// (tile, chunk offset, payload bytes in `data`), frame by frame in grid order.
    tiles: Vec<(DataHeader, u64, Range<usize>)>,
    next: u32,
}

impl VideoDecoder for HdrcFrameDecoder {
    fn info(&self) -> &ImageInfo {
        &self.info
    }

    /// The next frame. A frame whose tiles fail to decode is an error, and the following call
    /// goes on with the frame after it.
    fn next_frame(&mut self) -> Result<Option<HdrImage>> {
        if self.next >= self.head.frames {
            return Ok(None);
        }
        let f = self.next;
        self.next += 1;
        let per = self.head.tiles_per_frame() as usize;
        let start = f as usize * per;
        let refs: Vec<DataRef<'_>> = self.tiles[start..start + per]
            .iter()
            .map(|(header, offset, range)| DataRef {
                header: *header,
                offset: *offset,
                payload: &self.data[range.clone()],
            })
            .collect();
        decode_frame(&self.head, f, &refs, self.codec.as_ref(), &self.options, &self.info.color, &self.metadata)
            .map(Some)
    }
}
