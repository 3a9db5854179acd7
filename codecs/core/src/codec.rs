use crate::sink::{FrameBufMut, FrameSink, ImageSink, RowSink};
use crate::{Channels, ColorInfo, ColorPrimaries, Error, HdrImage, Limits, Result, ThreadPool};
use std::io::Write;
use std::str::FromStr;

/// The one trait every codec of the family implements (object-safe), so that the CLI, the
/// container, fuzzers and benches can treat all codecs alike. Each codec crate also offers a
/// typed API of its own with an options struct.
///
/// Implementors provide [`decode_with`](ImageCodec::decode_with) and
/// [`encode_to`](ImageCodec::encode_to); [`decode`](ImageCodec::decode) and
/// [`encode`](ImageCodec::encode) are the short forms most callers use.
pub trait ImageCodec: Send + Sync {
    /// Short stable name: `"rgbe"`, `"logluv32"`, `"bc6h"`, `"exr"`, ...
    fn name(&self) -> &'static str;
    /// Stable four-byte id written into `.hdrc` files.
    fn id(&self) -> [u8; 4];
    /// File extensions (lower case, without the dot) this codec writes and reads.
    fn extensions(&self) -> &'static [&'static str];
    /// Cheap magic-number test on the first bytes of a file.
    fn sniff(&self, head: &[u8]) -> bool;
    /// What colour signalling the format's files carry. Tools convert an image once, before
    /// encoding, only into what the format can say (see [`ColorSignalling`]).
    fn color_signalling(&self) -> ColorSignalling;
    /// True when the format's files record the scale of their samples
    /// ([`ColorInfo::nits_per_unit`]: OpenEXR's `whiteLuminance`, TIFF's `STONITS`, the
    /// container's COLR), so that a decoded image's `nits_per_unit` is the one its file states,
    /// which may differ from the encoded image's when the encoder chose a scale for its range.
    /// False (the provided answer): decoding gives the family's default (100) whatever the
    /// writer had, and a caller that knows the scale (the `.hdrc` header) keeps its own.
    fn records_nits_per_unit(&self) -> bool {
        false
    }
    /// False for a codec that only decodes (its [`encode_to`](Self::encode_to) returns
    /// [`Error::Unsupported`]): tools list it as such and do not offer it as an output.
    fn can_encode(&self) -> bool {
        true
    }
    /// The `key=value` options its decoder understands (see [`DecodeOptions::options`]), for
    /// tools that split one list of options between a decoder and an encoder. Default: none.
    fn decode_option_keys(&self) -> &'static [&'static str] {
        &[]
    }
    /// Size, channels and colour of an encoded image, read from its header without decoding
    /// the pixels (for `info` and for planning the memory of a batch). Never panics.
    ///
    /// The provided version decodes the whole image; codecs whose header says all of this
    /// override it.
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        let image = self.decode(data, limits)?;
        Ok(ImageInfo::new(image.width(), image.height(), image.channels(), image.color.clone()))
    }
    /// [`probe`](Self::probe) from a source that reads and seeks (a file, from its current
    /// position): a codec whose layout allows it reads only what its header needs (OpenEXR its
    /// headers, JPEG XR its IFD and codestream header, `.hdrc` its chunks but DATA, Radiance,
    /// PFM and LogLuv TIFF their headers), so that inspecting a file costs little whatever its
    /// size. Same answer and the same kinds of errors as `probe` on the file's bytes.
    ///
    /// The provided version reads the rest of `input` into memory, charged to `limits` while
    /// it is held, and calls `probe`.
    fn probe_from(&self, input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
        let data = read_rest(input, limits)?;
        self.probe(&data, limits)
    }
    /// Decodes a whole file held in memory, with the caller's limits and threads. Never
    /// panics; checks (and charges) `options.limits` before allocating.
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage>;
    /// Decodes a whole file held in memory into `sink`, row band by row band, so that nothing
    /// of the image's size is allocated besides what the sink holds (see [`crate::sink`]).
    /// Calls [`RowSink::start`] with what [`probe`](Self::probe) returns, then delivers every
    /// row once. Never panics; charges its own working buffers to `options.limits`.
    ///
    /// The provided version decodes the whole image with [`decode_with`](Self::decode_with)
    /// and copies it out (holding it twice); every codec of the family overrides it, and then
    /// implements `decode_with` as [`decode_image`]`(self, ..)`.
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        let image = self.decode_with(data, options)?;
        sink.start(&ImageInfo::of(&image))?;
        sink.put_rows(0, image.samples())
    }
    /// Decodes into a caller's buffer of `f32` or `f16` samples with a stride (see
    /// [`FrameBufMut`]) and returns what the header says (size, channels, colour, metadata).
    /// Allocates nothing of the image's size; fails, writing nothing, if the buffer cannot hold
    /// the image [`probe`](Self::probe) describes.
    fn decode_into(&self, data: &[u8], options: &DecodeOptions, out: FrameBufMut<'_>) -> Result<ImageInfo> {
        let mut sink = FrameSink::new(out);
        self.decode_rows(data, options, &mut sink)?;
        sink.info().cloned().ok_or_else(|| Error::invalid("the decoder delivered no image (a bug in the decoder)"))
    }
    /// Encodes an image and writes the file to `out`, reporting what the caller should know
    /// (values clipped to the format's range, a scale chosen for it).
    fn encode_to(&self, image: &HdrImage, settings: &EncodeSettings, out: &mut dyn Write) -> Result<EncodeReport>;

    /// Decodes a whole file held in memory on the calling thread.
    fn decode(&self, data: &[u8], limits: &Limits) -> Result<HdrImage> {
        self.decode_with(data, &DecodeOptions::new(limits.clone()))
    }
    /// [`decode_rows`](Self::decode_rows) from a source that reads and seeks (a file, from its
    /// current position) instead of bytes held in memory: a codec whose layout allows it reads
    /// the file piece by piece as it decodes (OpenEXR: a batch of chunks at a time), so that the
    /// peak is the sink's storage and its working buffers, not also the whole file. Same rows,
    /// same errors (a file that ends early is [`Error::Truncated`]).
    ///
    /// The provided version reads the rest of `input` into memory, charged to
    /// `options.limits` while it is held, and calls `decode_rows`.
    fn decode_rows_from(
        &self,
        input: &mut dyn ReadSeek,
        options: &DecodeOptions,
        sink: &mut dyn RowSink,
    ) -> Result<()> {
        let data = read_rest(input, &options.limits)?;
        self.decode_rows(&data, options, sink)
    }
    /// [`decode_rows_from`](Self::decode_rows_from) into a whole image (an [`ImageSink`]
    /// charged to `options.limits`): [`decode_with`](Self::decode_with) for a file.
    fn decode_from(&self, input: &mut dyn ReadSeek, options: &DecodeOptions) -> Result<HdrImage> {
        let mut sink = ImageSink::new(&options.limits);
        self.decode_rows_from(input, options, &mut sink)?;
        sink.finish()
    }
    /// [`encode_to`](Self::encode_to) into a writer that can also seek (a file): formats whose
    /// index precedes the data it points at (OpenEXR's offset table, TIFF's IFD offset) fill it
    /// in by seeking back, instead of holding the encoded file whole. The provided version is
    /// `encode_to`.
    fn encode_to_seekable(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn WriteSeek,
    ) -> Result<EncodeReport> {
        self.encode_to(image, settings, out)
    }
    /// An encoder that takes the image `info` describes row band by row band, top to bottom,
    /// and writes the file as the rows come (see [`RowEncoder`]): what lets a tool convert a
    /// file without holding the decoded image. `None` (the provided answer, and the answer of a
    /// codec whose choices need the whole image, such as a mip chain or a scale chosen from the
    /// image's range) means: encode the whole image with
    /// [`encode_to_seekable`](Self::encode_to_seekable).
    ///
    /// The samples it is given are in `info`'s layout and colour; the bytes it writes are those
    /// `encode_to_seekable` writes for the same image and settings. Options are checked here.
    fn row_encoder(&self, info: &ImageInfo, settings: &EncodeSettings) -> Result<Option<Box<dyn RowEncoder>>> {
        let _ = (info, settings);
        Ok(None)
    }
    /// Encodes an image to a whole file in memory.
    fn encode(&self, image: &HdrImage, settings: &EncodeSettings) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        self.encode_to(image, settings, &mut out)?;
        Ok(out)
    }
}

/// [`ImageCodec::decode_with`] for a codec that implements
/// [`decode_rows`](ImageCodec::decode_rows): the rows go into an [`ImageSink`], which charges
/// the image to `options.limits` and lets the decoder write it in place.
pub fn decode_image<C: ImageCodec + ?Sized>(codec: &C, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
    let mut sink = ImageSink::new(&options.limits);
    codec.decode_rows(data, options, &mut sink)?;
    sink.finish()
}

/// [`ImageCodec::encode_to`] for a codec whose streaming writer needs to seek
/// ([`encode_to_seekable`](ImageCodec::encode_to_seekable)): the file is assembled in memory,
/// then written to `out`.
pub fn encode_via_seekable<C: ImageCodec + ?Sized>(
    codec: &C,
    image: &HdrImage,
    settings: &EncodeSettings,
    out: &mut dyn Write,
) -> Result<EncodeReport> {
    let mut file = std::io::Cursor::new(Vec::new());
    let report = codec.encode_to_seekable(image, settings, &mut file)?;
    out.write_all(file.get_ref())?;
    Ok(report)
}

/// An image being encoded a band of rows at a time ([`ImageCodec::row_encoder`]): rows arrive
/// top to bottom, each once, as interleaved `f32` samples (`width × channels` per row), and the
/// file goes to `out`, the same writer at every call, where the file starts at the position
/// `out` has at the first call. The encoder holds no borrow, so that a caller can decide how to
/// encode before it has somewhere to write.
pub trait RowEncoder: Send {
    /// Encodes the rows that follow the last ones given (any number of whole rows).
    fn write_rows(&mut self, samples: &[f32], out: &mut dyn WriteSeek) -> Result<()>;
    /// Writes what remains of the file once every row has been given (an error if some are
    /// missing), leaves `out` at its end, and reports what the whole image needed saying
    /// (values clipped, and so on).
    fn finish(self: Box<Self>, out: &mut dyn WriteSeek) -> Result<EncodeReport>;
}

/// Feeds a whole image to a [`RowEncoder`] and finishes it: how a codec's
/// [`encode_to_seekable`](ImageCodec::encode_to_seekable) can share its row encoder.
pub fn encode_rows(
    mut encoder: Box<dyn RowEncoder>,
    image: &HdrImage,
    out: &mut dyn WriteSeek,
) -> Result<EncodeReport> {
    encoder.write_rows(image.samples(), out)?;
    encoder.finish(out)
}

/// The bytes a [`RowEncoder`] writes before its first rows (a header), kept until it has
/// somewhere to write them, with the position where they went (the start of the file, which
/// formats that seek count from).
#[derive(Clone, Debug, Default)]
pub struct PendingHeader {
    bytes: Option<Vec<u8>>,
    start: u64,
}

impl PendingHeader {
    /// `bytes`, to be written first.
    pub fn new(bytes: Vec<u8>) -> Self {
        PendingHeader { bytes: Some(bytes), start: 0 }
    }
    /// Writes the header to `out` if it has not been written yet; returns where the file starts.
    pub fn write(&mut self, out: &mut dyn WriteSeek) -> Result<u64> {
        if let Some(bytes) = self.bytes.take() {
            self.start = out.stream_position()?;
            out.write_all(&bytes)?;
        }
        Ok(self.start)
    }
}

/// Counts whole rows given to a [`RowEncoder`]: checks that `samples` holds whole rows that fit
/// in what remains of the image, and at the end that every row came.
#[derive(Clone, Copy, Debug)]
pub struct RowCounter {
    row_len: usize,
    height: u32,
    next: u32,
}

impl RowCounter {
    /// Rows of `row_len` samples, `height` of them.
    pub fn new(row_len: usize, height: u32) -> Self {
        RowCounter { row_len, height, next: 0 }
    }
    /// The first row `samples` holds, and how many rows that is.
    pub fn take(&mut self, samples: &[f32]) -> Result<(u32, u32)> {
        if self.row_len == 0 || !samples.len().is_multiple_of(self.row_len) {
            return Err(Error::invalid(format!(
                "{} samples given to an encoder are not whole rows of {}",
                samples.len(),
                self.row_len
            )));
        }
        let rows = samples.len() / self.row_len;
        if rows as u64 > u64::from(self.height - self.next) {
            return Err(Error::invalid(format!(
                "rows {}..{} given to an encoder of an image {} rows high",
                self.next,
                self.next as usize + rows,
                self.height
            )));
        }
        let first = self.next;
        self.next += rows as u32;
        Ok((first, rows as u32))
    }
    /// The next row expected.
    pub fn next(&self) -> u32 {
        self.next
    }
    /// An error unless every row has been given.
    pub fn check_complete(&self) -> Result<()> {
        if self.next == self.height {
            Ok(())
        } else {
            Err(Error::invalid(format!("the encoder was given {} of the image's {} rows", self.next, self.height)))
        }
    }
}

/// A writer that can also seek: what [`ImageCodec::encode_to_seekable`] writes into.
pub trait WriteSeek: Write + std::io::Seek {}

impl<T: Write + std::io::Seek + ?Sized> WriteSeek for T {}

/// A reader that can also seek: what [`ImageCodec::decode_rows_from`] reads (a file, a
/// `Cursor` over bytes). It is `Send`, so that a decoder may read it from its pool's threads
/// (behind a lock: JPEG XR refills the windows of tiles decoded in parallel that way).
pub trait ReadSeek: std::io::Read + std::io::Seek + Send {}

impl<T: std::io::Read + std::io::Seek + Send + ?Sized> ReadSeek for T {}

/// Where `input` is and how many bytes it has from there to its end (0 if its end is before
/// its position), leaving it where it was: what a decoder reading a file piece by piece
/// checks its offsets against.
pub fn remaining_len(input: &mut dyn ReadSeek) -> Result<(u64, u64)> {
    let at = input.stream_position()?;
    let end = input.seek(std::io::SeekFrom::End(0))?;
    input.seek(std::io::SeekFrom::Start(at))?;
    Ok((at, end.saturating_sub(at)))
}

/// Reads `out.len()` bytes of `input` at position `offset`: a source that ends first is
/// [`Error::Truncated`] naming `what` and the bytes asked for. What the decoders that read a
/// file piece by piece read each piece with.
pub fn read_exact_at(input: &mut dyn ReadSeek, offset: u64, out: &mut [u8], what: &str) -> Result<()> {
    input.seek(std::io::SeekFrom::Start(offset))?;
    input.read_exact(out).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => Error::truncated(format!(
            "{what} (the input ended inside bytes {offset}..{})",
            offset.saturating_add(out.len() as u64)
        )),
        _ => Error::Io(e),
    })
}

/// The bytes of `input` from its position to its end, their size charged to `limits` (checked
/// before anything is allocated) while the returned buffer lives. A source that ends before
/// the size it reported is [`Error::Truncated`].
pub fn read_rest(input: &mut dyn ReadSeek, limits: &Limits) -> Result<ChargedBytes> {
    let (_, len) = remaining_len(input)?;
    let charge = limits.charge(len, "the encoded file")?;
    let mut bytes = vec![0; usize::try_from(len).map_err(|_| Error::limit("the encoded file is too large"))?];
    input.read_exact(&mut bytes).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => Error::truncated(format!("the file (it ended before its {len} bytes)")),
        _ => Error::Io(e),
    })?;
    Ok(ChargedBytes { bytes, _charge: charge })
}

/// The stored samples of an image whose rows lie uncompressed at a known place (PFM, the raw
/// payloads of `.hdrc`): the file's bytes in memory, or a file read a band at a time into one
/// buffer charged to the limits while it is held, so that a decoder from a file never holds
/// the file whole.
pub struct StoredBytes<'a> {
    source: Stored<'a>,
    /// What the bytes are, for messages ("the PFM pixels").
    what: &'static str,
}

enum Stored<'a> {
    Memory(&'a [u8]),
    File {
        input: &'a mut dyn ReadSeek,
        /// The position of the first stored byte in `input`.
        start: u64,
        buf: Vec<u8>,
        charge: Option<crate::Allocation>,
        limits: &'a Limits,
    },
}

impl<'a> StoredBytes<'a> {
    /// Bytes held in memory.
    pub fn memory(bytes: &'a [u8], what: &'static str) -> Self {
        StoredBytes { source: Stored::Memory(bytes), what }
    }

    /// Bytes of `input` from position `start`, read as they are asked for; the buffer they are
    /// read into is charged to `limits`.
    pub fn file(input: &'a mut dyn ReadSeek, start: u64, limits: &'a Limits, what: &'static str) -> Self {
        StoredBytes { source: Stored::File { input, start, buf: Vec::new(), charge: None, limits }, what }
    }

    /// The `len` bytes from `offset` (counted from the first stored byte), which the caller
    /// has checked lie inside the stored bytes: a file that ends before them is
    /// [`Error::Truncated`].
    pub fn band(&mut self, offset: usize, len: usize) -> Result<&[u8]> {
        let what = self.what;
        match &mut self.source {
            Stored::Memory(bytes) => bytes.get(offset..offset.saturating_add(len)).ok_or_else(|| {
                Error::truncated(format!("{what} (bytes {offset}..{} of {})", offset.saturating_add(len), bytes.len()))
            }),
            Stored::File { input, start, buf, charge, limits } => {
                if len > buf.len() {
                    *charge = None;
                    *charge = Some(limits.charge(len as u64, "a band of rows read from the file")?);
                    buf.resize(len, 0);
                }
                read_exact_at(*input, *start + offset as u64, &mut buf[..len], what)?;
                Ok(&buf[..len])
            }
        }
    }
}

/// Bytes read by [`read_rest`], charged to the limits they were read under until dropped.
#[derive(Debug)]
pub struct ChargedBytes {
    bytes: Vec<u8>,
    _charge: crate::Allocation,
}

impl std::ops::Deref for ChargedBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes
    }
}

/// Which colour signalling a format's files carry.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ColorSignalling {
    /// Any primaries: the file records chromaticities (OpenEXR, Radiance `PRIMARIES`, `.hdrc`),
    /// or colour absolutely (LogLuv's CIE XYZ).
    Any,
    /// Only these named spaces (KTX2's data format descriptor).
    Only(&'static [ColorPrimaries]),
    /// None: the samples are stored as they are and read back with
    /// [`ColorPrimaries::Unspecified`] (PFM, DDS).
    None,
}

impl ColorSignalling {
    /// True when a file of this format can say that its samples are in `primaries`.
    pub fn can_record(&self, primaries: &ColorPrimaries) -> bool {
        match self {
            ColorSignalling::Any => true,
            ColorSignalling::Only(set) => set.contains(primaries),
            ColorSignalling::None => false,
        }
    }
}

/// What a decoder is given besides the data: the caller's [`Limits`] and threads, and
/// codec-specific `key=value` options that the codec parses itself (a gain-map JPEG's display
/// `headroom`); a codec ignores options it does not know, since one list may serve the decoders
/// of several formats ([`ImageCodec::decode_option_keys`] names each codec's).
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct DecodeOptions {
    /// What the decoder may allocate.
    pub limits: Limits,
    /// Worker threads the decoder may use (default: the calling thread only).
    pub pool: ThreadPool,
    /// Codec-specific options in the order given.
    pub options: Vec<(String, String)>,
}

impl DecodeOptions {
    /// These limits, on the calling thread.
    pub fn new(limits: Limits) -> Self {
        DecodeOptions { limits, pool: ThreadPool::single(), options: Vec::new() }
    }

    /// The same options with the threads of `pool`.
    pub fn with_pool(mut self, pool: ThreadPool) -> Self {
        self.pool = pool;
        self
    }

    /// Adds a codec-specific option.
    pub fn with_option(mut self, key: impl Into<String>, value: impl Into<String>) -> Self {
        self.options.push((key.into(), value.into()));
        self
    }

    /// The last value given for `key`, if any.
    pub fn option(&self, key: &str) -> Option<&str> {
        options::last(&self.options, key)
    }

    /// The value of `key` parsed as `T` (the last one given), with a clear error if it does
    /// not parse.
    pub fn parse_option<T: FromStr>(&self, key: &str) -> Result<Option<T>> {
        options::parse(&self.options, key)
    }
}

impl From<Limits> for DecodeOptions {
    /// These limits, on the calling thread.
    fn from(limits: Limits) -> Self {
        DecodeOptions::new(limits)
    }
}

/// What an encoder tells its caller besides the bytes: the choices it made for the format's
/// range and anything it could not keep, as sentences a user can read.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct EncodeReport {
    /// One sentence each, e.g. "12 samples above 65504 were clipped to 65504 (half float)".
    pub notes: Vec<String>,
}

impl EncodeReport {
    /// A report with no notes.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a note.
    pub fn note(&mut self, note: impl Into<String>) {
        self.notes.push(note.into());
    }
}

/// What [`ImageCodec::probe`] reads from a header.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct ImageInfo {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The channel layout [`ImageCodec::decode`] returns.
    pub channels: Channels,
    /// The colour the decoded image will carry.
    pub color: ColorInfo,
    /// Frames in the file (1 for a still image).
    pub frames: u32,
    /// The stored sample format in a few words ("half, PIZ", "BC6H UF16, 3 mips"), if known.
    pub format: String,
    /// What the file says besides its pixels (`key`, `value`), as [`HdrImage::metadata`]
    /// will hold it after decoding.
    pub metadata: Vec<(String, String)>,
}

impl ImageInfo {
    /// One frame of `width` × `height` with these channels and colour.
    pub fn new(width: u32, height: u32, channels: Channels, color: ColorInfo) -> Self {
        ImageInfo { width, height, channels, color, frames: 1, format: String::new(), metadata: Vec::new() }
    }

    /// What a header describing `image` says: its size, channels, colour and metadata.
    pub fn of(image: &HdrImage) -> Self {
        let mut info = ImageInfo::new(image.width(), image.height(), image.channels(), image.color.clone());
        info.metadata = image.metadata.clone();
        info
    }

    /// The value of metadata `key`, if present.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// The same with one more metadata entry.
    pub fn with_metadata(mut self, key: impl Into<String>, value: impl Into<String>) -> Self {
        self.metadata.push((key.into(), value.into()));
        self
    }

    /// The same with the sample format described as `format`.
    pub fn with_format(mut self, format: impl Into<String>) -> Self {
        self.format = format.into();
        self
    }

    /// The same with `frames` frames.
    pub fn with_frames(mut self, frames: u32) -> Self {
        self.frames = frames;
        self
    }

    /// Charges the decoded frame this header describes against `limits`' budget (see
    /// [`Limits::charge`]): what a decoder does, after probing, before it allocates the image.
    pub fn charge(&self, limits: &Limits) -> Result<crate::Allocation> {
        limits.check_dimensions(u64::from(self.width), u64::from(self.height))?;
        limits.charge(self.decoded_bytes(), "the decoded image")
    }

    /// Bytes of the `f32` samples of one decoded frame.
    pub fn decoded_bytes(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * self.channels.count() as u64 * 4
    }
}

/// A stream of frames being encoded (video, or frame sequences in a container): frames are
/// pushed one at a time and written as they come; `finish` completes the stream. Separate from
/// [`ImageCodec`] because an encoder of frames keeps state between them.
pub trait VideoEncoder: Send {
    /// Encodes the next frame (same size and channels as the first).
    fn push_frame(&mut self, frame: &HdrImage) -> Result<()>;
    /// Flushes what is buffered and completes the stream; returns how many frames it holds.
    fn finish(self: Box<Self>) -> Result<u64>;
    /// [`finish`](Self::finish), returning what the encoder knows of the stream it wrote: the
    /// frames, and where the encoder reports them, the bytes written, the samples its signal
    /// could not hold and the content light level it wrote. The default reports the frame
    /// count alone; encoders that know more override it.
    fn finish_report(self: Box<Self>) -> Result<StreamReport> {
        let frames = self.finish()?;
        Ok(StreamReport { frames, ..StreamReport::default() })
    }
}

/// What a [`VideoEncoder`] wrote ([`VideoEncoder::finish_report`]). Fields an encoder does not
/// know are `None` or empty.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct StreamReport {
    /// Frames in the stream.
    pub frames: u64,
    /// Bytes written to the output.
    pub bytes: Option<u64>,
    /// Samples changed because the stream's signal could not hold them.
    pub clipped: crate::hdr10::ClipReport,
    /// The content light level (MaxCLL, MaxFALL) written into the stream.
    pub content_light: Option<crate::ContentLightLevel>,
}

impl StreamReport {
    /// A report of `frames` frames, `bytes` bytes, `clipped` samples and `content_light`.
    pub fn new(
        frames: u64,
        bytes: Option<u64>,
        clipped: crate::hdr10::ClipReport,
        content_light: Option<crate::ContentLightLevel>,
    ) -> Self {
        StreamReport { frames, bytes, clipped, content_light }
    }
}

/// A stream of frames being decoded, one at a time.
pub trait VideoDecoder: Send {
    /// Size, channels, colour and frame count of the stream.
    fn info(&self) -> &ImageInfo;
    /// The next frame, or `None` after the last.
    fn next_frame(&mut self) -> Result<Option<HdrImage>>;
}

/// A codec of frame sequences: starts encoders and decoders of streams.
pub trait VideoCodec: Send + Sync {
    /// Short stable name.
    fn name(&self) -> &'static str;
    /// File extensions (lower case, without the dot).
    fn extensions(&self) -> &'static [&'static str];
    /// Starts a stream of frames described by `info` (size, channels, colour; `frames` may be 0
    /// when unknown) written to `out`.
    fn begin_encode(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
        out: Box<dyn Write + Send>,
    ) -> Result<Box<dyn VideoEncoder>>;
    /// Starts decoding the stream in `data`.
    fn begin_decode(&self, data: std::sync::Arc<[u8]>, options: &DecodeOptions) -> Result<Box<dyn VideoDecoder>>;
    /// [`begin_encode`](Self::begin_encode) to a writer that seeks and may borrow (a file being
    /// written atomically): for containers whose sizes and indexes are patched in place once
    /// the stream is complete (MP4, Matroska). The default is `Unsupported`: codecs whose
    /// files never seek need only [`begin_encode`](Self::begin_encode).
    fn begin_encode_seekable<'a>(
        &self,
        _info: &ImageInfo,
        _settings: &EncodeSettings,
        _out: Box<dyn WriteSeek + Send + 'a>,
    ) -> Result<Box<dyn VideoEncoder + 'a>> {
        Err(Error::unsupported(format!("{}: no encoder to a seekable writer (use begin_encode)", self.name())))
    }
}

/// What every encoder understands, plus codec-specific `key=value` options that the codec
/// parses itself (an unknown key is an error, see [`EncodeSettings::check_options`]).
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct EncodeSettings {
    /// 0-100; each lossy codec maps it onto its own quantiser. Lossless codecs ignore it.
    pub quality: u8,
    /// 0-9: 0 is the fastest encode, 9 the most thorough search. Default 5.
    pub effort: u8,
    /// Worker threads the encoder may use (default: the calling thread only).
    pub pool: ThreadPool,
    /// Codec-specific options in the order given.
    pub options: Vec<(String, String)>,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings { quality: 90, effort: 5, pool: ThreadPool::single(), options: Vec::new() }
    }
}

impl EncodeSettings {
    /// Largest `effort` value.
    pub const MAX_EFFORT: u8 = 9;

    /// The same settings with this quality (0-100).
    pub fn with_quality(mut self, quality: u8) -> Self {
        self.quality = quality.min(100);
        self
    }

    /// The same settings with this effort (0-9).
    pub fn with_effort(mut self, effort: u8) -> Self {
        self.effort = effort.min(Self::MAX_EFFORT);
        self
    }

    /// The same settings with the threads of `pool`.
    pub fn with_pool(mut self, pool: ThreadPool) -> Self {
        self.pool = pool;
        self
    }

    /// The same settings without the options named `key` (a tool that handles an option
    /// itself, such as the facade's `primaries`, removes it before the codec sees it).
    pub fn without_option(mut self, key: &str) -> Self {
        self.options.retain(|(k, _)| k != key);
        self
    }

    /// Adds a codec-specific option.
    pub fn with_option(mut self, key: impl Into<String>, value: impl Into<String>) -> Self {
        self.options.push((key.into(), value.into()));
        self
    }

    /// Parses `key=value` as given on a command line.
    pub fn push_option_str(&mut self, kv: &str) -> Result<()> {
        self.options.push(split_option(kv)?);
        Ok(())
    }

    /// Fails with a clear error naming the codec and its known keys if any option is unknown.
    pub fn check_options(&self, codec: &str, known: &[&str]) -> Result<()> {
        for (k, _) in &self.options {
            if !known.contains(&k.as_str()) {
                let list = if known.is_empty() { "none".to_string() } else { known.join(", ") };
                return Err(Error::invalid(format!("unknown option '{k}' for codec {codec} (known options: {list})")));
            }
        }
        Ok(())
    }

    /// The last value given for `key`, if any.
    pub fn option(&self, key: &str) -> Option<&str> {
        options::last(&self.options, key)
    }

    /// The value of `key` parsed as `T`, with a clear error if it does not parse.
    pub fn parse_option<T: FromStr>(&self, key: &str) -> Result<Option<T>> {
        options::parse(&self.options, key)
    }

    /// A boolean option: `true/false`, `yes/no`, `on/off`, `1/0`.
    pub fn bool_option(&self, key: &str) -> Result<Option<bool>> {
        match self.option(key) {
            None => Ok(None),
            Some(v) => match v.to_ascii_lowercase().as_str() {
                "true" | "yes" | "on" | "1" => Ok(Some(true)),
                "false" | "no" | "off" | "0" => Ok(Some(false)),
                _ => Err(Error::invalid(format!("option {key}={v}: expected true or false"))),
            },
        }
    }
}

/// Splits `key=value` as given on a command line (both sides trimmed).
pub fn split_option(kv: &str) -> Result<(String, String)> {
    let (k, v) =
        kv.split_once('=').ok_or_else(|| Error::invalid(format!("option '{kv}' is not of the form key=value")))?;
    Ok((k.trim().to_string(), v.trim().to_string()))
}

/// Lookups over a list of `key=value` options, shared by [`EncodeSettings`] and
/// [`DecodeOptions`].
mod options {
    use crate::{Error, Result};
    use std::str::FromStr;

    /// The last value given for `key`, if any.
    pub(super) fn last<'a>(options: &'a [(String, String)], key: &str) -> Option<&'a str> {
        options.iter().rev().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// The last value of `key` parsed as `T`.
    pub(super) fn parse<T: FromStr>(options: &[(String, String)], key: &str) -> Result<Option<T>> {
        match last(options, key) {
            None => Ok(None),
            Some(v) => {
                v.parse().map(Some).map_err(|_| Error::invalid(format!("option {key}={v}: cannot parse the value")))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source that claims `extra` more bytes than it holds (a file cut while it was read).
    struct Shrunk(std::io::Cursor<Vec<u8>>, u64);
    impl std::io::Read for Shrunk {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.0.read(buf)
        }
    }
    impl std::io::Seek for Shrunk {
        fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
            match pos {
                std::io::SeekFrom::End(d) => Ok((self.0.get_ref().len() as u64 + self.1).saturating_add_signed(d)),
                p => self.0.seek(p),
            }
        }
    }

    #[test]
    fn remaining_len_gives_position_and_rest_and_leaves_the_position() {
        let mut c = std::io::Cursor::new(vec![0u8; 100]);
        c.set_position(30);
        assert_eq!(remaining_len(&mut c).unwrap(), (30, 70));
        assert_eq!(c.position(), 30);
        c.set_position(120);
        assert_eq!(remaining_len(&mut c).unwrap(), (120, 0));
        assert_eq!(c.position(), 120);
    }

    #[test]
    fn read_rest_charges_the_bytes_and_reports_a_short_source() {
        let mut c = std::io::Cursor::new((0..100u8).collect::<Vec<u8>>());
        c.set_position(30);
        let limits = Limits::default();
        let rest = read_rest(&mut c, &limits).unwrap();
        assert_eq!(&rest[..], &(30..100u8).collect::<Vec<u8>>()[..]);
        assert_eq!(limits.peak(), 70);
        drop(rest);
        c.set_position(0);
        let small = Limits::new(16, 16, 256, 50);
        assert!(matches!(read_rest(&mut c, &small), Err(Error::LimitExceeded { .. })));
        let mut short = Shrunk(std::io::Cursor::new(vec![1; 20]), 5);
        assert!(matches!(read_rest(&mut short, &limits), Err(Error::Truncated { .. })));
    }

    #[test]
    fn unknown_options_are_named() {
        let s = EncodeSettings::default().with_option("mips", "true").with_option("bogus", "1");
        let err = s.check_options("bc6h", &["mips", "signed"]).unwrap_err().to_string();
        assert!(err.contains("'bogus'") && err.contains("bc6h") && err.contains("mips, signed"), "{err}");
        assert_eq!(s.bool_option("mips").unwrap(), Some(true));
        assert!(s.parse_option::<u32>("bogus").unwrap() == Some(1));
    }

    #[test]
    fn trait_is_object_safe() {
        fn _takes(_: &dyn ImageCodec) {}
    }
}
