//! Writing: one scan-line part. The blocks are cut straight from the image (no per-channel copy
//! of it), compressed here a batch at a time on rayon's pool (as in decoding, a panic inside
//! `exr` then reaches the caller instead of aborting `exr`'s own pool), and written in order with
//! `exr`'s chunk writer, which fills in the offset table by seeking back. The header and the
//! compressed chunks are those `exr`'s image writer would produce, except for the B44 chunks
//! described at [`b44_overflows`].

use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::ChunksWriter;
use exr::block::BlockIndex;
use exr::block::UncompressedBlock;
use exr::compression::Compression;
use exr::math::Vec2;
use exr::meta::attribute::{
    ChannelDescription, Chromaticities as ExrChromaticities, IntegerBounds, LineOrder, SampleType, Text,
};
use exr::meta::header::{Header, ImageAttributes, LayerAttributes};
use exr::meta::{BlockDescription, Headers};
use exr::prelude::{f16, SmallVec};
use hdrcodec_core::{ColorPrimaries, Error, HdrImage, Result, ThreadPool};
use rayon::prelude::*;
use std::io::Cursor;

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
    out: &mut dyn hdrcodec_core::WriteSeek,
) -> Result<()> {
    if image.width() == 0 || image.height() == 0 {
        return Err(Error::invalid(format!("cannot write an empty {}x{} image", image.width(), image.height())));
    }
    let header = header_for(image, options);
    // No `exr` compressor is known to panic on our data; the guard stays so that an unknown
    // upstream bug becomes an error, not a crash of the caller.
    guarded("writing an OpenEXR file", || write_blocks(image, options.pixel, header, pool, out))
}

/// The one scan-line header of the file: R, G, B (and A) as `exr`'s image writer names and
/// sorts them, the compression, `whiteLuminance` and the chromaticities.
fn header_for(image: &HdrImage, options: &ExrEncodeOptions) -> Header {
    let sample_type = match options.pixel {
        ExrPixelType::Half => SampleType::F16,
        ExrPixelType::Float => SampleType::F32,
    };
    let mut channels: SmallVec<[ChannelDescription; 5]> = ["R", "G", "B", "A"]
        .iter()
        .take(image.channels().count())
        .map(|n| ChannelDescription::named(*n, sample_type))
        .collect();
    // The file lists channels by name (A, B, G, R).
    channels.sort_unstable_by(|a, b| a.name.cmp(&b.name));
    let size = Vec2(image.width() as usize, image.height() as usize);
    let mut attributes = LayerAttributes::default();
    if image.color.nits_per_unit != 100.0 {
        attributes.white_luminance = Some(image.color.nits_per_unit);
    }
    let mut shared = ImageAttributes::with_size(size);
    // Without the attribute OpenEXR means BT.709 primaries; unspecified samples are written that
    // way too (the attribute cannot say "unknown").
    if !matches!(image.color.primaries, ColorPrimaries::Bt709 | ColorPrimaries::Unspecified) {
        let c = image.color.primaries.chromaticities();
        let xy = |v: [f64; 2]| Vec2(v[0] as f32, v[1] as f32);
        shared.chromaticities =
            Some(ExrChromaticities { red: xy(c.red), green: xy(c.green), blue: xy(c.blue), white: xy(c.white) });
    }
    Header::new(Text::default(), size, channels)
        .with_encoding(options.compression.to_exr(), BlockDescription::ScanLines, LineOrder::Increasing)
        .with_attributes(attributes)
        .with_shared_attributes(shared)
}

/// The uncompressed bytes of one block as `exr` lays them out: line by line, and in each line
/// channel by channel in the header's order (A, B, G, R), little-endian.
fn extract_block(image: &HdrImage, pixel: ExrPixelType, header: &Header, index: BlockIndex) -> Vec<u8> {
    let n = image.channels().count();
    let (x0, y0) = (index.pixel_position.x(), index.pixel_position.y());
    let (bw, bh) = (index.pixel_size.x(), index.pixel_size.y());
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
    let mut data = Vec::with_capacity(bw * bh * offsets.len() * bytes);
    for y in y0..y0 + bh {
        let row = &image.row(y as u32)[x0 * n..(x0 + bw) * n];
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

/// Writes the file as `exr`'s `image.write().to_buffered(..)` does, cutting and compressing
/// the blocks a batch at a time on `pool`.
fn write_blocks(
    image: &HdrImage,
    pixel: ExrPixelType,
    header: Header,
    pool: &ThreadPool,
    out: &mut dyn hdrcodec_core::WriteSeek,
) -> Result<()> {
    let headers: Headers = SmallVec::from_elem(header, 1);
    exr::block::write(out, headers, true, |meta, chunk_writer| {
        let header = &meta.headers[0];
        let mut blocks = meta.collect_ordered_block_data(|index| extract_block(image, pixel, header, index));
        let compress = |(i, block): (usize, UncompressedBlock)| compress_block(block, &meta.headers).map(|c| (i, c));
        loop {
            let batch: Vec<(usize, UncompressedBlock)> = blocks.by_ref().take(BATCH).collect();
            if batch.is_empty() {
                return Ok(());
            }
            let chunks: Vec<exr::error::Result<(usize, Chunk)>> = if pool.is_parallel() {
                pool.install(|| batch.into_par_iter().map(compress).collect())
            } else {
                batch.into_iter().map(compress).collect()
            };
            for chunk in chunks {
                let (index_in_header, chunk) = chunk?;
                chunk_writer.write_chunk(index_in_header, chunk)?;
            }
        }
    })
    .map_err(map_err)
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
