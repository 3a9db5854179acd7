//! Writing: one scan-line part, rows in, file out. [`ExrWriter`] writes the header and a
//! zeroed offset table, then takes rows top to bottom; each batch of blocks is cut from the rows
//! gathered (no per-channel copy of the image), compressed on the caller's pool (as in
//! decoding, a panic inside `exr` then reaches the caller instead of aborting `exr`'s own pool)
//! and written in order; at the end the offset table, which precedes the chunks, is filled in by
//! seeking back. The header and the compressed chunks are those `exr`'s image writer would
//! produce, except for the B44 chunks described at [`b44_overflows`]. A whole image is the same
//! writer given all its rows at once.

use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::{BlockIndex, UncompressedBlock};
use exr::compression::Compression;
use exr::math::Vec2;
use exr::meta::attribute::{
    ChannelDescription, Chromaticities as ExrChromaticities, IntegerBounds, LineOrder, SampleType, Text,
};
use exr::meta::header::{Header, ImageAttributes, LayerAttributes};
use exr::meta::{BlockDescription, Headers, MetaData};
use exr::prelude::{f16, SmallVec};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, EncodeReport, Error, HdrImage, ImageInfo, PendingHeader, RangeCount, Result,
    RowCounter, RowEncoder, ThreadPool, WriteSeek,
};
use std::io::{Cursor, SeekFrom};

use crate::decode::{guarded, map_err};
use crate::{ExrEncodeOptions, ExrPixelType};

/// Blocks compressed per parallel batch: bounds the uncompressed and compressed blocks held at
/// once while keeping every core busy.
const BATCH: usize = 32;

/// Encodes `image` as an OpenEXR file, compressing blocks in parallel on `pool` (on the calling
/// thread for a single-threaded handle).
pub fn encode_exr(image: &HdrImage, options: &ExrEncodeOptions, pool: &ThreadPool) -> Result<Vec<u8>> {
    let mut out = Cursor::new(Vec::new());
    write_exr(image, options, pool, &mut out)?;
    Ok(out.into_inner())
}

/// [`encode_exr`] streamed into `out`: each batch of blocks is cut straight from the image,
/// compressed and written, and the offset table, which precedes the chunks, is filled in by
/// seeking back at the end. Nothing of the image's size is held besides the image.
pub fn write_exr(
    image: &HdrImage,
    options: &ExrEncodeOptions,
    pool: &ThreadPool,
    out: &mut dyn WriteSeek,
) -> Result<()> {
    let writer = ExrWriter::new(&ImageInfo::of(image), options, pool)?;
    hdrcodec_core::encode_rows(Box::new(writer), image, out).map(drop)
}

/// The writer of one scan-line file: see the module's documentation.
pub(crate) struct ExrWriter {
    /// The header and the zeroed offset table, until they are written.
    head: PendingHeader,
    header: Header,
    pixel: ExrPixelType,
    pool: ThreadPool,
    width: usize,
    channels: Channels,
    rows: RowCounter,
    /// Lines per block, and the rows of whole blocks gathered per batch.
    block_lines: usize,
    batch_rows: usize,
    /// Rows gathered (interleaved samples), starting at row `band_y`.
    band: Vec<f32>,
    band_y: usize,
    /// Where the writer is and where the offset table is, from the start of the file.
    pos: u64,
    table_at: u64,
    offsets: Vec<u64>,
    /// For the report: unspecified primaries (written as BT.709), and samples beyond the half
    /// range.
    unlabelled: bool,
    outside: RangeCount,
}

impl ExrWriter {
    /// Prepares the header and a zeroed offset table (written with the first rows).
    pub(crate) fn new(info: &ImageInfo, options: &ExrEncodeOptions, pool: &ThreadPool) -> Result<Self> {
        if info.width == 0 || info.height == 0 {
            return Err(Error::invalid(format!("cannot write an empty {}x{} image", info.width, info.height)));
        }
        let header = header_for(info, options);
        let headers: Headers = SmallVec::from_elem(header.clone(), 1);
        // What `exr`'s own writer writes first: magic number, version and flags, the header.
        let mut head = Vec::new();
        let requirements = MetaData::validate(&headers, true).map_err(map_err)?;
        exr::meta::magic_number::write(&mut head).map_err(map_err)?;
        requirements.write(&mut head).map_err(map_err)?;
        Header::write_all(&headers, &mut head, requirements.has_multiple_layers).map_err(map_err)?;
        let chunks = header.chunk_count;
        let table_at = head.len() as u64;
        // The offset table, zero until the chunks are written.
        head.resize(head.len() + chunks * 8, 0);
        let block_lines = header.compression.scan_lines_per_block();
        Ok(ExrWriter {
            head: PendingHeader::new(head),
            pixel: options.pixel,
            pool: pool.clone(),
            width: info.width as usize,
            channels: info.channels,
            rows: RowCounter::new(info.width as usize * info.channels.count(), info.height),
            block_lines,
            batch_rows: block_lines * BATCH,
            band: Vec::new(),
            band_y: 0,
            pos: table_at + chunks as u64 * 8,
            table_at,
            offsets: Vec::with_capacity(chunks),
            unlabelled: !info.color.primaries.is_specified(),
            outside: RangeCount::default(),
            header,
        })
    }

    /// Cuts the gathered rows into blocks, compresses them and writes them in order.
    fn write_band(&mut self, samples: &[f32], y0: usize, out: &mut dyn WriteSeek) -> Result<()> {
        let row_len = self.width * self.channels.count();
        let rows = samples.len() / row_len;
        let headers: Headers = SmallVec::from_elem(self.header.clone(), 1);
        let blocks: Vec<UncompressedBlock> = (0..rows.div_ceil(self.block_lines))
            .map(|b| {
                let first = b * self.block_lines;
                let lines = self.block_lines.min(rows - first);
                let index = BlockIndex {
                    layer: 0,
                    pixel_position: Vec2(0, y0 + first),
                    pixel_size: Vec2(self.width, lines),
                    level: Vec2(0, 0),
                };
                let data = block_bytes(
                    &samples[first * row_len..(first + lines) * row_len],
                    self.channels,
                    self.pixel,
                    &self.header,
                );
                UncompressedBlock { index, data }
            })
            .collect();
        let compress = |block: UncompressedBlock| compress_block(block, &headers);
        // No `exr` compressor is known to panic on our data; the guard stays so that an unknown
        // upstream bug becomes an error, not a crash of the caller.
        let chunks: Vec<exr::error::Result<Chunk>> =
            guarded("writing an OpenEXR file", || Ok(self.pool.map_vec(blocks, |(_, block)| compress(block))))?;
        for chunk in chunks {
            let chunk = chunk.map_err(map_err)?;
            let mut bytes = Vec::new();
            chunk.write(&mut bytes, 1).map_err(map_err)?;
            self.offsets.push(self.pos);
            out.write_all(&bytes)?;
            self.pos += bytes.len() as u64;
        }
        Ok(())
    }
}

impl RowEncoder for ExrWriter {
    fn write_rows(&mut self, mut samples: &[f32], out: &mut dyn WriteSeek) -> Result<()> {
        self.head.write(out)?;
        self.rows.take(samples)?;
        if self.pixel == ExrPixelType::Half {
            count_beyond_half(&mut self.outside, samples, self.channels);
        }
        let row_len = self.width * self.channels.count();
        // Whole batches straight from the rows given when nothing is gathered; the rest gathered.
        while !samples.is_empty() {
            let rows = samples.len() / row_len;
            if self.band.is_empty() && rows >= self.batch_rows {
                let take = rows / self.batch_rows * self.batch_rows;
                let y0 = self.band_y;
                self.write_band(&samples[..take * row_len], y0, out)?;
                self.band_y += take;
                samples = &samples[take * row_len..];
                continue;
            }
            let gathered = self.band.len() / row_len;
            let take = (self.batch_rows - gathered).min(rows);
            self.band.extend_from_slice(&samples[..take * row_len]);
            samples = &samples[take * row_len..];
            if gathered + take == self.batch_rows {
                let band = std::mem::take(&mut self.band);
                let y0 = self.band_y;
                self.write_band(&band, y0, out)?;
                self.band_y += self.batch_rows;
                self.band = band;
                self.band.clear();
            }
        }
        Ok(())
    }

    /// Writes the last blocks and the offset table, and reports what the caller should know.
    fn finish(mut self: Box<Self>, out: &mut dyn WriteSeek) -> Result<EncodeReport> {
        let base = self.head.write(out)?;
        self.rows.check_complete()?;
        if !self.band.is_empty() {
            let band = std::mem::take(&mut self.band);
            let y0 = self.band_y;
            self.write_band(&band, y0, out)?;
        }
        let mut table = Vec::with_capacity(self.offsets.len() * 8);
        for o in &self.offsets {
            table.extend_from_slice(&o.to_le_bytes());
        }
        out.seek(SeekFrom::Start(base + self.table_at))?;
        out.write_all(&table)?;
        out.seek(SeekFrom::Start(base + self.pos))?;
        let mut report = EncodeReport::new();
        if self.unlabelled {
            // Without a chromaticities attribute OpenEXR means BT.709; it cannot say "unknown".
            report.note("the input records no primaries: OpenEXR stores them as BT.709, its default (--opt primaries=NAME labels them)");
        }
        if let Some(note) = crate::describe_half_overflow(self.outside) {
            report.note(note);
        }
        Ok(report)
    }
}

/// Adds to `counts` the finite samples of `pixels` (alpha included) beyond ±65504, the largest
/// half float. Infinities and NaN are stored as they are, so they are not counted.
fn count_beyond_half(counts: &mut RangeCount, pixels: &[f32], channels: Channels) {
    let mut beyond = RangeCount::default();
    beyond.add(pixels, channels, -crate::HALF_MAX, crate::HALF_MAX, true);
    let mut infinite = RangeCount::default();
    infinite.add(pixels, channels, f32::MIN, f32::MAX, true);
    counts.below += beyond.below - infinite.below;
    counts.above += beyond.above - infinite.above;
}

/// The one scan-line header of the file: R, G, B (and A) as `exr`'s image writer names and
/// sorts them, the compression, `whiteLuminance` and the chromaticities.
fn header_for(info: &ImageInfo, options: &ExrEncodeOptions) -> Header {
    let sample_type = match options.pixel {
        ExrPixelType::Half => SampleType::F16,
        ExrPixelType::Float => SampleType::F32,
    };
    let mut channels: SmallVec<[ChannelDescription; 5]> = ["R", "G", "B", "A"]
        .iter()
        .take(info.channels.count())
        .map(|n| ChannelDescription::named(*n, sample_type))
        .collect();
    // The file lists channels by name (A, B, G, R).
    channels.sort_unstable_by(|a, b| a.name.cmp(&b.name));
    let size = Vec2(info.width as usize, info.height as usize);
    let mut attributes = LayerAttributes::default();
    let mut shared = ImageAttributes::with_size(size);
    set_colour_attributes(&info.color, &mut shared, &mut attributes);
    Header::new(Text::default(), size, channels)
        .with_encoding(options.compression.to_exr(), BlockDescription::ScanLines, LineOrder::Increasing)
        .with_attributes(attributes)
        .with_shared_attributes(shared)
}

/// Records `color` in a file's attributes: `whiteLuminance` when `nits_per_unit` is not 100,
/// `chromaticities` when the primaries are not BT.709 (what OpenEXR means without the
/// attribute; unspecified samples are written that way too, as the attribute cannot say
/// "unknown"). The inverse of [`crate::decode::colour_from_attributes`].
pub(crate) fn set_colour_attributes(color: &ColorInfo, shared: &mut ImageAttributes, layer: &mut LayerAttributes) {
    if color.nits_per_unit != 100.0 {
        layer.white_luminance = Some(color.nits_per_unit);
    }
    if !matches!(color.primaries, ColorPrimaries::Bt709 | ColorPrimaries::Unspecified) {
        let c = color.primaries.chromaticities();
        let xy = |v: [f64; 2]| Vec2(v[0] as f32, v[1] as f32);
        shared.chromaticities =
            Some(ExrChromaticities { red: xy(c.red), green: xy(c.green), blue: xy(c.blue), white: xy(c.white) });
    }
}

/// The uncompressed bytes of one block of whole rows as `exr` lays them out: line by line, and
/// in each line channel by channel in the header's order (A, B, G, R), little-endian.
fn block_bytes(rows: &[f32], channels: Channels, pixel: ExrPixelType, header: &Header) -> Vec<u8> {
    let n = channels.count();
    // Interleaved sample offset of each listed channel (R 0, G 1, B 2, A 3).
    let offsets: SmallVec<[usize; 4]> = header
        .channels
        .list
        .iter()
        .map(|c| ["R", "G", "B", "A"].iter().position(|n| c.name.eq(n)).unwrap_or(0))
        .collect();
    let bytes = match pixel {
        ExrPixelType::Half => 2,
        ExrPixelType::Float => 4,
    };
    let width = header.layer_size.width();
    let mut data = Vec::with_capacity(rows.len() / n * offsets.len() * bytes);
    for row in rows.chunks_exact(width * n) {
        for &c in &offsets {
            let samples = row.iter().skip(c).step_by(n);
            match pixel {
                ExrPixelType::Half => samples.for_each(|&v| data.extend_from_slice(&f16::from_f32(v).to_le_bytes())),
                ExrPixelType::Float => samples.for_each(|&v| data.extend_from_slice(&v.to_le_bytes())),
            }
        }
    }
    data
}

/// Compresses one block with the header's compression, or stores it raw (see
/// [`b44_overflows`]).
fn compress_block(block: UncompressedBlock, headers: &[Header]) -> exr::error::Result<Chunk> {
    let header = &headers[block.index.layer];
    if !b44_overflows(header, block.index.pixel_size) {
        return block.compress_to_chunk(headers);
    }
    // The chunk's raw bytes, little-endian, line by line and channel by channel: what
    // `Compression::compress_image_section_to_le` returns for a chunk that does not shrink.
    let UncompressedBlock { data, index } = block;
    let section = IntegerBounds::new(index.pixel_position.to_i32(), index.pixel_size);
    let raw_le = Compression::Uncompressed.compress_image_section_to_le(header, data, section)?;
    Ok(Chunk {
        layer_index: index.layer,
        compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock {
            y_coordinate: section.position.y() + header.own_attributes.layer_position.y(),
            compressed_pixels_le: raw_le,
        }),
    })
}

/// True when `exr`'s B44/B44A compressor could overflow its output buffer on a block of `size`
/// pixels; such a block is stored raw instead, which is what OpenEXR itself writes for it.
///
/// The upstream bug (exr 1.74.2, `src/compression/b44/mod.rs`, `fn compress`): the output
/// buffer is `vec![0; max(2048, uncompressed_le.len())]` and every 4x4 block is packed into
/// `b44_compressed[b44_end..b44_end + 14]`. A block takes 14 bytes however few of its 16
/// samples exist, so a chunk less than 4 lines high (or narrower than 4 pixels) packs into more
/// than its raw size: when the output passes 2048 bytes the slice is out of range and
/// `compress` panics. With 32-line B44 chunks this is the last chunk when `height % 32 == 1`
/// and the width is at least 197 (RGB half) or 145 (RGBA half): 257x129 RGB ends in a
/// 257x1 chunk of 65 blocks x 14 bytes x 3 channels = 2730 bytes (raw: 1542). The upstream fix
/// is to size the buffer for the worst case computed here.
///
/// A chunk whose worst case exceeds its raw size cannot shrink under B44 (every block is 14
/// bytes), so OpenEXR's writer, and `exr`'s own `compress_image_section_to_le` when it does not
/// panic, store it uncompressed; readers recognise such a chunk by its size being the raw size.
/// For B44 the chunks written here are therefore the ones a fixed `exr` would write. Under
/// B44A, flat blocks take 3 bytes, so a few of these chunks could have shrunk; storing them
/// raw (lossless) is still a valid B44A file.
fn b44_overflows(header: &Header, size: Vec2<usize>) -> bool {
    if !matches!(header.compression, Compression::B44 | Compression::B44A) {
        return false;
    }
    let pixels = size.area();
    let blocks = size.width().div_ceil(4) * size.height().div_ceil(4);
    let worst: usize = header
        .channels
        .list
        .iter()
        .map(|c| match c.sample_type {
            // Only half channels are B44-packed; the others are copied raw.
            SampleType::F16 => blocks * 14,
            other => pixels * other.bytes_per_sample(),
        })
        .sum();
    worst > pixels * header.channels.bytes_per_pixel
}
