//! Reading: the `exr` crate parses headers and decompresses chunks; this module checks the
//! declared sizes against [`Limits`] first, picks the R, G, B(, A) or Y channels, and copies the
//! samples of the largest resolution level of the first part into an [`HdrImage`].
//!
//! The block-level API of `exr` is used instead of its high-level image reader for three
//! reasons: only the chosen channels of level 0 are converted (no per-channel buffers of the
//! whole image), nothing is allocated before the limits are checked, and the parallel
//! decompression runs on the caller's pool where a panic inside `exr` is caught per chunk
//! (the high-level reader builds its own pool, in which a panicking task aborts the process).

use exr::block::chunk::{Chunk, CompressedBlock};
use exr::block::reader::ChunksReader;
use exr::block::UncompressedBlock;
use exr::meta::attribute::SampleType;
use exr::meta::header::{Header, ImageAttributes, LayerAttributes};
use exr::meta::MetaData;
use hdrcodec_core::sink::{band_rows, fill_rows, ImageSink, RowSink, Scratch};
use hdrcodec_core::{
    Allocation, Channels, Chromaticities, ColorInfo, ColorPrimaries, DecodeOptions, Error, HdrImage, ImageInfo, Limits,
    ReadSeek, Result, ThreadPool,
};
use std::collections::BTreeMap;
use std::io::{Cursor, Read, Seek, SeekFrom};
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::{compression_name, MAGIC};

/// Most chunks decompressed per parallel batch (four per thread up to this): bounds the memory
/// held in decompressed blocks to a few dozen blocks while keeping every core busy.
const BATCH: usize = 32;

/// Decodes an OpenEXR file held in memory. Never panics: a panic inside the `exr` crate is
/// turned into [`Error::Invalid`].
pub fn decode_exr(data: &[u8], limits: &Limits) -> Result<HdrImage> {
    decode_exr_with(data, &DecodeOptions::new(limits.clone()))
}

/// Size, channels, colour and stored format ("half, PIZ", "float, ZIP, tiles 64x64") of an
/// OpenEXR file, read from its headers without decoding a pixel: exactly what [`decode_exr`]
/// would return for them. Checks the size against the limits' dimensions (not the byte limit:
/// nothing of the image's size is allocated) and that the offset tables fit the file. Never
/// panics.
pub fn probe_exr(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    guarded("reading the OpenEXR header", || probe_inner(data, limits))
}

/// [`probe_exr`] from a file (any source that reads and seeks, positioned at the file's first
/// byte): only the magic number and the headers are read, not the offset tables or a chunk.
/// Same answer and errors as [`probe_exr`] on the file's bytes.
pub fn probe_exr_from(input: &mut dyn ReadSeek, limits: &Limits) -> Result<ImageInfo> {
    if input.stream_position()? != 0 {
        // The offset tables count from the file's first byte (as decode_exr_rows_from reads them).
        let data = hdrcodec_core::read_rest(input, limits)?;
        return probe_exr(&data, limits);
    }
    let (_, len) = hdrcodec_core::remaining_len(input)?;
    guarded("reading the OpenEXR header", || {
        let reader = read_meta(std::io::BufReader::new(input))?;
        probe_meta(reader.meta_data(), len, limits)
    })
}

/// [`decode_exr`] with the caller's threads: chunks decompress in parallel on `options.pool`.
pub fn decode_exr_with(data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
    let mut sink = ImageSink::new(&options.limits);
    decode_exr_rows(data, options, &mut sink)?;
    sink.finish()
}

/// Decodes an OpenEXR file into `sink`, block row by block row (in place when the sink allows
/// it); chunks decompress in parallel on `options.pool`, a batch of whole block rows at a time.
pub fn decode_exr_rows(data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    guarded("reading the OpenEXR file", || {
        decode_inner(Cursor::new(data), data.len() as u64, &options.limits, &options.pool, sink)
    })
}

/// [`decode_exr_rows`] from a file (any source that reads and seeks, positioned at the file's
/// first byte): the headers and offset tables are read first, then the chunks a batch at a
/// time as they are decoded, so that neither the file nor a copy of its chunks is held
/// (chunks stored out of top-to-bottom order wait, charged to `options.limits`, until their
/// turn). Same rows and errors as [`decode_exr_rows`] on the file's bytes.
pub fn decode_exr_rows_from(input: &mut dyn ReadSeek, options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
    if input.stream_position()? != 0 {
        // The offset tables count from the file's first byte.
        let data = hdrcodec_core::read_rest(input, &options.limits)?;
        return decode_exr_rows(&data, options, sink);
    }
    let (_, len) = hdrcodec_core::remaining_len(input)?;
    guarded("reading the OpenEXR file", || {
        decode_inner(std::io::BufReader::new(input), len, &options.limits, &options.pool, sink)
    })
}

/// Runs `f`, turning a panic into an `Invalid` error that names `what` and the panic message.
pub(crate) fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".to_string());
            Err(Error::invalid(format!("malformed OpenEXR data: the exr crate panicked while {what} ({msg})")))
        }
    }
}

/// Maps an error of the `exr` crate onto the family's error.
pub(crate) fn map_err(e: exr::error::Error) -> Error {
    use exr::error::Error as E;
    match e {
        E::NotSupported(what) => Error::unsupported(format!("OpenEXR: {what}")),
        E::Invalid(what) => Error::invalid(format!("OpenEXR: {what}")),
        E::Aborted => Error::invalid("OpenEXR: reading was aborted"),
        E::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => Error::truncated("the OpenEXR file"),
        E::Io(io) => Error::invalid(format!("OpenEXR: {io}")),
    }
}

/// Where one output sample comes from.
#[derive(Clone, Copy)]
struct Source {
    /// Byte offset of the channel's samples inside one line of a block, per pixel of block width.
    bytes_before: usize,
    sample_type: SampleType,
}

/// The channels chosen from the first part.
struct Selection {
    /// R, G, B (the same Y channel three times for a luminance image), then A if present.
    sources: Vec<Source>,
    channels: Channels,
}

/// Reads the magic number and the headers (the `exr` crate validates them), nothing else,
/// from `input` at the file's first byte.
fn read_meta<R: Read + Seek>(mut input: R) -> Result<exr::block::reader::Reader<R>> {
    let mut magic = [0; 4];
    input.read_exact(&mut magic).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => Error::truncated("the OpenEXR magic number"),
        _ => Error::Io(e),
    })?;
    if magic != MAGIC {
        return Err(Error::invalid("not an OpenEXR file (the magic number 76 2f 31 01 is missing)"));
    }
    input.seek(SeekFrom::Start(0))?;
    exr::block::read(input, false).map_err(map_err)
}

/// The first part's header, refused if deep, with the channels the decoder returns.
fn first_part(meta: &MetaData) -> Result<(&Header, Selection)> {
    let header = meta.headers.first().ok_or_else(|| Error::invalid("OpenEXR file without a header"))?;
    if header.deep {
        return Err(Error::unsupported("deep OpenEXR data (samples per pixel vary); only flat images are read"));
    }
    Ok((header, select_channels(header)?))
}

/// The offset tables of every part are read before any chunk: 8 bytes each in the file, so a
/// table longer than the file is a truncation, found before `exr` allocates it.
fn check_offset_tables(meta: &MetaData, file_len: u64) -> Result<()> {
    let offsets: u64 = meta.headers.iter().map(|h| h.chunk_count as u64).sum::<u64>().saturating_mul(8);
    if offsets > file_len {
        return Err(Error::truncated(format!("the OpenEXR offset tables ({offsets} bytes declared)")));
    }
    Ok(())
}

/// Size, channels, colour and stored format of an OpenEXR file, from its headers only: see
/// [`crate::probe_exr`].
fn probe_inner(data: &[u8], limits: &Limits) -> Result<ImageInfo> {
    let reader = read_meta(Cursor::new(data))?;
    probe_meta(reader.meta_data(), data.len() as u64, limits)
}

/// [`probe_inner`] from the headers of a file of `file_len` bytes.
fn probe_meta(meta: &MetaData, file_len: u64, limits: &Limits) -> Result<ImageInfo> {
    let (header, selection) = first_part(meta)?;
    let (w, h) = (header.layer_size.width() as u64, header.layer_size.height() as u64);
    limits.check_dimensions(w, h)?;
    check_offset_tables(meta, file_len)?;
    let mut types: Vec<&str> = selection.sources.iter().map(|s| type_name(s.sample_type)).collect();
    types.dedup();
    let mut format = format!("{}, {}", types.join("+"), compression_label(header.compression));
    if let exr::meta::BlockDescription::Tiles(t) = header.blocks {
        format += &format!(", tiles {}x{}", t.tile_size.x(), t.tile_size.y());
    }
    let mut info = ImageInfo::new(w as u32, h as u32, selection.channels, color_info(meta)).with_format(format);
    info.metadata = metadata(header);
    Ok(info)
}

/// The name OpenEXR's tools print for a compression ("PIZ", "ZIP", "none").
fn compression_label(c: exr::compression::Compression) -> String {
    match c {
        exr::compression::Compression::Uncompressed => "uncompressed".to_string(),
        c => compression_name(c).to_ascii_uppercase(),
    }
}

fn type_name(t: SampleType) -> &'static str {
    match t {
        SampleType::F16 => "half",
        SampleType::F32 => "float",
        SampleType::U32 => "uint",
    }
}

/// The size of a chunk's compressed bytes (deep chunks are refused).
fn chunk_bytes(chunk: &Chunk) -> Result<usize> {
    match &chunk.compressed_block {
        CompressedBlock::ScanLine(b) => Ok(b.compressed_pixels_le.len()),
        CompressedBlock::Tile(b) => Ok(b.compressed_pixels_le.len()),
        _ => Err(Error::unsupported("deep OpenEXR chunks")),
    }
}

/// The chunks of the first part's full-resolution level, handed out in the order the decoder
/// asks for them (top to bottom) while they are read in the order the file stores them: a
/// chunk read before its turn waits in `pending`, charged to the limits, so that a file stored
/// top to bottom holds one chunk at a time and one stored otherwise at most its chunks.
struct ChunkSource<'l, I> {
    chunks: I,
    pending: BTreeMap<(i32, i32), Chunk>,
    pending_bytes: u64,
    charge: Option<Allocation>,
    limits: &'l Limits,
}

impl<I: Iterator<Item = exr::error::Result<Chunk>>> ChunkSource<'_, I> {
    /// The chunk of the block at `key` (data window row, column).
    fn take(&mut self, key: (i32, i32), header: &Header) -> Result<Chunk> {
        if let Some(chunk) = self.pending.remove(&key) {
            self.pending_bytes -= chunk_bytes(&chunk)? as u64;
            return Ok(chunk);
        }
        loop {
            let chunk = self
                .chunks
                .next()
                .ok_or_else(|| Error::invalid(format!("OpenEXR: no chunk holds the block at ({}, {})", key.1, key.0)))?
                .map_err(map_err)?;
            let bytes = chunk_bytes(&chunk)? as u64;
            let at = header
                .get_block_data_indices(&chunk.compressed_block)
                .and_then(|tile| header.get_block_data_window_pixel_coordinates(tile))
                .map_err(map_err)?
                .position;
            if (at.y(), at.x()) == key {
                return Ok(chunk);
            }
            if self.pending.insert((at.y(), at.x()), chunk).is_some() {
                return Err(Error::invalid("OpenEXR: the offset tables point at the same chunks more than once"));
            }
            self.pending_bytes += bytes;
            self.charge = None;
            self.charge = Some(self.limits.charge(self.pending_bytes, "the OpenEXR chunks read before their turn")?);
        }
    }
}

fn decode_inner<R: Read + Seek>(
    input: R,
    file_len: u64,
    limits: &Limits,
    pool: &ThreadPool,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let reader = read_meta(input)?;
    let meta = reader.meta_data().clone();
    let info = probe_meta(&meta, file_len, limits)?;
    let (header, selection) = first_part(&meta)?;
    let (w, h) = (header.layer_size.width() as u64, header.layer_size.height() as u64);
    // A block never exceeds the data window, whatever tile size the header declares.
    let block = header.max_block_pixel_size();
    let block_pixels = (block.width() as u64).min(w) * (block.height() as u64).min(h);
    let block_bytes = block_pixels * header.channels.bytes_per_pixel as u64;
    limits.check_alloc(block_bytes, "one decompressed OpenEXR block")?;
    // Four blocks per thread (one on a single thread, whose batches need no more), fewer when
    // they are large, so that a batch stays within the limit too.
    let per_pool = if pool.is_parallel() { pool.threads() * 4 } else { 1 };
    let batch_len = (limits.max_alloc_bytes / block_bytes.max(1)).clamp(1, per_pool.clamp(1, BATCH) as u64) as usize;

    let level0 = |level: exr::math::Vec2<usize>| level == exr::math::Vec2(0, 0);
    // Where each block of level 0 lies in the data window, top to bottom (files written with
    // a decreasing or random line order hold the same blocks in another order): the order in
    // which the rows are delivered, in whole bands. At most one per 8 bytes of the file
    // (checked with the offset tables).
    let mut order = header
        .blocks_increasing_y_order()
        .filter(|t| level0(t.location.level_index))
        .map(|t| header.get_block_data_window_pixel_coordinates(t.location).map(|b| (b.position.y(), b.position.x())))
        .collect::<exr::error::Result<Vec<_>>>()
        .map_err(map_err)?;
    order.sort_unstable();
    let chunks = reader.filter_chunks(false, |_, _, block| block.layer == 0 && level0(block.level)).map_err(map_err)?;
    if chunks.expected_chunk_count() != order.len() {
        return Err(Error::invalid(format!(
            "OpenEXR: {} chunks for the {} blocks of the image",
            chunks.expected_chunk_count(),
            order.len()
        )));
    }
    let mut source = ChunkSource { chunks, pending: BTreeMap::new(), pending_bytes: 0, charge: None, limits };

    let (w, h) = (w as usize, h as usize);
    let n = selection.channels.count();
    let row_len = w * n;
    sink.start(&info)?;
    // A batch of whole block rows: up to `BATCH` chunks when the sink takes them in place, at
    // most about 1 MB of rows when they need a scratch buffer (and always one block row).
    let in_place = sink.rows_mut(0, h as u32).is_some();
    let batch_rows = if in_place { h } else { band_rows(row_len, 1 << 20) as usize };
    let mut scratch = Scratch::new(limits);
    let mut covered = 0usize;
    let mut next_row = 0usize;
    let mut seen = std::collections::HashSet::new();
    // Large files decompress on the pool; small ones (most fuzz inputs) stay on this thread.
    let parallel = pool.is_parallel() && order.len() > 2 && file_len > 1 << 16;
    let mut iter = order.into_iter().peekable();
    while iter.peek().is_some() {
        let decompress = |c: Chunk| {
            guarded("decompressing a chunk", || UncompressedBlock::decompress_chunk(c, &meta, false).map_err(map_err))
        };
        // Chunks up to `batch_len` within `batch_rows`, then on to the end of the last block
        // row begun.
        let first_y = iter.peek().map_or(0, |(y, _)| i64::from(*y));
        let mut keys: Vec<(i32, i32)> = Vec::with_capacity(batch_len);
        while keys.len() < batch_len {
            match iter.next_if(|(y, _)| ((i64::from(*y) - first_y) as usize) < batch_rows) {
                Some(k) => keys.push(k),
                None => break,
            }
        }
        let last_y = keys.last().map_or(0, |(y, _)| *y);
        while let Some(k) = iter.next_if(|(y, _)| *y == last_y) {
            keys.push(k);
        }
        let _blocks = limits.charge(block_bytes * keys.len() as u64, "a batch of decompressed OpenEXR blocks")?;
        let batch = keys.into_iter().map(|k| source.take(k, header)).collect::<Result<Vec<Chunk>>>()?;
        let blocks: Vec<Result<UncompressedBlock>> = if parallel {
            pool.map_vec(batch, |(_, c)| decompress(c))
        } else {
            batch.into_iter().map(decompress).collect()
        };
        let blocks = blocks.into_iter().collect::<Result<Vec<_>>>()?;
        let top = blocks.iter().map(|b| b.index.pixel_position.y()).min().unwrap_or(0);
        let bottom = blocks.iter().map(|b| b.index.pixel_position.y() + b.index.pixel_size.y()).max().unwrap_or(0);
        if top != next_row || bottom > h {
            return Err(Error::invalid(format!(
                "OpenEXR: the chunks do not tile the data window (rows {top}..{bottom} after row {next_row})"
            )));
        }
        fill_rows(sink, top as u32, (bottom - top) as u32, row_len, &mut scratch, |band| {
            for block in &blocks {
                let idx = block.index;
                if !seen.insert((idx.pixel_position.x(), idx.pixel_position.y())) {
                    return Err(Error::invalid("OpenEXR: two chunks hold the same block"));
                }
                copy_block(block, header, &selection, w, top, band)?;
                covered += idx.pixel_size.area();
            }
            Ok(())
        })?;
        // Every pixel of the band must have come from a chunk (checked for the whole window
        // at the end; a band with a hole fails there).
        next_row = bottom;
    }
    if covered != w * h || next_row != h {
        return Err(Error::invalid(format!("OpenEXR: the chunks cover {covered} of {} pixels", w * h)));
    }
    Ok(())
}

/// Picks R, G, B (and A) by name, case-insensitively, from the channels without a layer
/// prefix, else from the first prefix (`diffuse.R`, ...) that has all three; a luminance-only
/// image (Y, no RY/BY chroma) becomes grey RGB.
fn select_channels(header: &Header) -> Result<Selection> {
    let list = &header.channels.list;
    if let Some(c) = list.iter().find(|c| c.sampling != exr::math::Vec2(1, 1)) {
        return Err(Error::unsupported(format!(
            "OpenEXR channel {} is subsampled ({}x{}); luminance/chroma images are not supported",
            c.name,
            c.sampling.x(),
            c.sampling.y()
        )));
    }
    // Byte offset of each channel inside a line, per pixel of width (channels are stored in
    // the order of the list, which `exr` keeps sorted as the file has them).
    let mut before = Vec::with_capacity(list.len());
    let mut acc = 0usize;
    for c in list.iter() {
        before.push(acc);
        acc += c.sample_type.bytes_per_sample();
    }
    let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
    let split = |name: &str| match name.rfind('.') {
        Some(i) => (name[..i].to_string(), name[i + 1..].to_ascii_uppercase()),
        None => (String::new(), name.to_ascii_uppercase()),
    };
    let parts: Vec<(String, String)> = names.iter().map(|n| split(n)).collect();
    let find = |prefix: &str, base: &str| parts.iter().position(|(p, b)| p == prefix && b == base);
    let source = |i: usize| Source { bytes_before: before[i], sample_type: list[i].sample_type };

    // R, G, B (or Y three times) plus the alpha of the same prefix, if any.
    let select = |prefix: &str, rgb: [usize; 3]| {
        let mut sources: Vec<Source> = rgb.iter().map(|&i| source(i)).collect();
        let alpha = find(prefix, "A").map(|a| sources.push(source(a)));
        Selection { sources, channels: if alpha.is_some() { Channels::Rgba } else { Channels::Rgb } }
    };

    let mut prefixes: Vec<&str> = parts.iter().map(|(p, _)| p.as_str()).collect();
    prefixes.sort_unstable();
    prefixes.dedup(); // the empty prefix sorts first, so unprefixed channels win
    for prefix in &prefixes {
        if let (Some(r), Some(g), Some(b)) = (find(prefix, "R"), find(prefix, "G"), find(prefix, "B")) {
            return Ok(select(prefix, [r, g, b]));
        }
    }
    for prefix in &prefixes {
        if let Some(y) = find(prefix, "Y") {
            if find(prefix, "RY").is_some() || find(prefix, "BY").is_some() {
                return Err(Error::unsupported("OpenEXR luminance/chroma (Y, RY, BY) images are not supported"));
            }
            return Ok(select(prefix, [y; 3]));
        }
    }
    Err(Error::unsupported(format!("OpenEXR part without R, G, B or Y channels (it has: {})", names.join(", "))))
}

/// Copies the chosen channels of one decompressed block (lines of `width` samples per channel,
/// channel after channel) into the interleaved output.
fn copy_block(
    block: &UncompressedBlock,
    header: &Header,
    sel: &Selection,
    w: usize,
    top: usize,
    out: &mut [f32],
) -> Result<()> {
    let idx = block.index;
    let (bx, bw, bh) = (idx.pixel_position.x(), idx.pixel_size.x(), idx.pixel_size.y());
    let n = sel.channels.count();
    // Rows of `out` (a band starting at image row `top`).
    let by = idx.pixel_position.y().wrapping_sub(top);
    if bx + bw > w || by.saturating_add(bh) > out.len() / (w * n).max(1) {
        return Err(Error::invalid("OpenEXR: a chunk lies outside the data window"));
    }
    let line = bw * header.channels.bytes_per_pixel;
    if block.data.len() != line * bh {
        return Err(Error::invalid("OpenEXR: a decompressed chunk has the wrong size"));
    }
    for (row, src_line) in block.data.chunks_exact(line).enumerate() {
        let dst = &mut out[((by + row) * w + bx) * n..((by + row) * w + bx + bw) * n];
        for (c, s) in sel.sources.iter().enumerate() {
            let start = s.bytes_before * bw;
            let size = s.sample_type.bytes_per_sample();
            let src = &src_line[start..start + size * bw];
            let dst = dst.iter_mut().skip(c).step_by(n);
            match s.sample_type {
                SampleType::F16 => {
                    let table = half_table();
                    for (d, b) in dst.zip(src.chunks_exact(2)) {
                        *d = table[usize::from(u16::from_ne_bytes([b[0], b[1]]))];
                    }
                }
                SampleType::F32 => {
                    for (d, b) in dst.zip(src.chunks_exact(4)) {
                        *d = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
                    }
                }
                // Unsigned integers (object ids, counts) keep their numeric value.
                SampleType::U32 => {
                    for (d, b) in dst.zip(src.chunks_exact(4)) {
                        *d = u32::from_ne_bytes([b[0], b[1], b[2], b[3]]) as f32;
                    }
                }
            }
        }
    }
    Ok(())
}

/// Every half value as `f32` (exact: each entry is `f16::to_f32`, NaN payloads included).
/// One table lookup per sample is several times faster than converting sample by sample.
fn half_table() -> &'static [f32; 65536] {
    static TABLE: std::sync::OnceLock<Box<[f32; 65536]>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = Box::new([0.0f32; 65536]);
        for (i, v) in t.iter_mut().enumerate() {
            *v = exr::prelude::f16::from_bits(i as u16).to_f32();
        }
        t
    })
}

/// An `f32` attribute value as the decimal number it was written as (0.64f32 → 0.64f64, not
/// 0.63999998569...), so that named colour spaces and custom ones read back cleanly.
fn clean(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(v as f64)
}

fn color_info(meta: &MetaData) -> ColorInfo {
    let header = &meta.headers[0];
    colour_from_attributes(&header.shared_attributes, &header.own_attributes)
}

/// The colour that a file's attributes record: `chromaticities` (absent: BT.709) and
/// `whiteLuminance` (absent, zero or not finite: 100 nits per unit).
pub(crate) fn colour_from_attributes(shared: &ImageAttributes, layer: &LayerAttributes) -> ColorInfo {
    let mut color = ColorInfo::default();
    if let Some(c) = shared.chromaticities {
        let xy = |v: exr::math::Vec2<f32>| [clean(v.x()), clean(v.y())];
        color.primaries = ColorPrimaries::from_chromaticities(Chromaticities {
            red: xy(c.red),
            green: xy(c.green),
            blue: xy(c.blue),
            white: xy(c.white),
        });
    }
    if let Some(l) = layer.white_luminance {
        if l.is_finite() && l > 0.0 {
            color.nits_per_unit = l;
        }
    }
    color
}

/// What `hdrcodec info` shows and the pixels alone do not say.
fn metadata(header: &Header) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut set = |k: &str, v: String| out.push((k.to_string(), v));
    set("exr.compression", compression_name(header.compression).to_string());
    let types: Vec<&str> = header.channels.list.iter().map(|c| type_name(c.sample_type)).collect();
    let mut dedup = types.clone();
    dedup.dedup();
    set("exr.pixel", if dedup.len() == 1 { dedup[0].to_string() } else { types.join(",") });
    let data = header.data_window();
    let display = header.shared_attributes.display_window;
    if data != display {
        let rect = |b: exr::meta::attribute::IntegerBounds| {
            let end = b.max();
            format!("{} {} {} {}", b.position.x(), b.position.y(), end.x(), end.y())
        };
        set("exr.data_window", rect(data));
        set("exr.display_window", rect(display));
    }
    if let exr::meta::BlockDescription::Tiles(t) = header.blocks {
        set("exr.tiles", format!("{}x{}", t.tile_size.x(), t.tile_size.y()));
    }
    out
}
