//! Writing: one scan-line part. `exr` builds the header and cuts the image into uncompressed
//! blocks; the blocks are compressed here, on rayon's pool (as in decoding, a panic inside
//! `exr` then reaches the caller instead of aborting `exr`'s own pool), and written in order with
//! `exr`'s chunk writer. The compressed chunks are those `exr`'s image writer would produce,
//! except for the B44 chunks described at [`b44_overflows`].

use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::ChunksWriter;
use exr::block::UncompressedBlock;
use exr::compression::Compression;
use exr::image::write::layers::{LayersWriter, WritableLayers};
use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{Chromaticities as ExrChromaticities, IntegerBounds, LineOrder, SampleType};
use exr::meta::header::{Header, LayerAttributes};
use exr::prelude::{f16, SmallVec};
use hdrcodec_core::{ColorPrimaries, Error, HdrImage, Result, ThreadPool};
use rayon::prelude::*;
use std::io::Cursor;

use crate::decode::{guarded, map_err};
use crate::{ExrEncodeOptions, ExrPixelType};

/// Blocks compressed per parallel batch: bounds the uncompressed and compressed blocks held at
/// once while keeping every core busy.
const BATCH: usize = 32;

type ExrImage = Image<Layer<AnyChannels<FlatSamples>>>;

/// Encodes `image` as an OpenEXR file, compressing blocks in parallel on `pool` (on the calling
/// thread for a single-threaded handle).
pub fn encode_exr(image: &HdrImage, options: &ExrEncodeOptions, pool: &ThreadPool) -> Result<Vec<u8>> {
    if image.width() == 0 || image.height() == 0 {
        return Err(Error::invalid(format!("cannot write an empty {}x{} image", image.width(), image.height())));
    }
    let n = image.channels().count();
    let names = ["R", "G", "B", "A"];
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (c, name) in names.iter().enumerate().take(n) {
        let plane = image.samples().iter().skip(c).step_by(n);
        let samples = match options.pixel {
            ExrPixelType::Half => FlatSamples::F16(plane.map(|&v| f16::from_f32(v)).collect()),
            ExrPixelType::Float => FlatSamples::F32(plane.copied().collect()),
        };
        list.push(AnyChannel::new(*name, samples));
    }
    let mut attributes = LayerAttributes::default();
    if image.color.nits_per_unit != 100.0 {
        attributes.white_luminance = Some(image.color.nits_per_unit);
    }
    let encoding = Encoding {
        compression: options.compression.to_exr(),
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let size = Vec2(image.width() as usize, image.height() as usize);
    let layer = Layer::new(size, attributes, encoding, AnyChannels::sort(list));
    let mut exr_image = Image::from_layer(layer);
    // Without the attribute OpenEXR means BT.709 primaries; unspecified samples are written that
    // way too (the attribute cannot say "unknown").
    if !matches!(image.color.primaries, ColorPrimaries::Bt709 | ColorPrimaries::Unspecified) {
        let c = image.color.primaries.chromaticities();
        let xy = |v: [f64; 2]| Vec2(v[0] as f32, v[1] as f32);
        exr_image.attributes.chromaticities =
            Some(ExrChromaticities { red: xy(c.red), green: xy(c.green), blue: xy(c.blue), white: xy(c.white) });
    }
    // No `exr` compressor is known to panic on our data; the guard stays so that an unknown
    // upstream bug becomes an error, not a crash of the caller.
    guarded("writing an OpenEXR file", || write_file(&exr_image, pool))
}

/// Writes `image` as `exr`'s `image.write().to_buffered(..)` does, compressing the blocks on
/// `pool`.
fn write_file(image: &ExrImage, pool: &ThreadPool) -> Result<Vec<u8>> {
    let headers = image.layer_data.infer_headers(&image.attributes);
    let layers = image.layer_data.create_writer(&headers);
    let mut out = Cursor::new(Vec::new());
    exr::block::write(&mut out, headers, true, |meta, chunk_writer| {
        let mut blocks =
            meta.collect_ordered_block_data(|index| layers.extract_uncompressed_block(&meta.headers, index));
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
    .map_err(map_err)?;
    Ok(out.into_inner())
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
