//! Writing: one scan-line part. `exr` builds the header and cuts the image into uncompressed
//! blocks; the blocks are compressed here, on rayon's pool (as in decoding, a panic inside
//! `exr` then reaches the caller instead of aborting `exr`'s own pool), and written in order with
//! `exr`'s chunk writer. The compressed chunks are those `exr`'s image writer would produce.

use exr::block::chunk::Chunk;
use exr::block::writer::ChunksWriter;
use exr::block::UncompressedBlock;
use exr::image::write::layers::{LayersWriter, WritableLayers};
use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{Chromaticities as ExrChromaticities, LineOrder};
use exr::meta::header::LayerAttributes;
use exr::prelude::{f16, SmallVec};
use hdrcodec_core::{ColorPrimaries, Error, HdrImage, Result};
use rayon::prelude::*;
use std::io::Cursor;

use crate::decode::{guarded, map_err};
use crate::{ExrEncodeOptions, ExrPixelType};

/// Blocks compressed per parallel batch: bounds the uncompressed and compressed blocks held at
/// once while keeping every core busy.
const BATCH: usize = 32;

type ExrImage = Image<Layer<AnyChannels<FlatSamples>>>;

/// Encodes `image` as an OpenEXR file. `threads == 1` compresses on the calling thread, 0 on
/// every core (rayon's global pool), `n` on a pool of `n` threads.
pub fn encode_exr(image: &HdrImage, options: &ExrEncodeOptions, threads: usize) -> Result<Vec<u8>> {
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
    if image.color.primaries != ColorPrimaries::Bt709 {
        let c = image.color.primaries.chromaticities();
        let xy = |v: [f64; 2]| Vec2(v[0] as f32, v[1] as f32);
        exr_image.attributes.chromaticities =
            Some(ExrChromaticities { red: xy(c.red), green: xy(c.green), blue: xy(c.blue), white: xy(c.white) });
    }
    // exr 1.74's B44 compressor can panic (index out of range, e.g. at 257x129); `guarded`
    // turns that into an error. On rayon's pool the panic reaches this thread; on `exr`'s own
    // pool it aborted the process, which is why B44 used to be written on the calling thread.
    let write = |parallel: bool| guarded("writing an OpenEXR file", || write_file(&exr_image, parallel));
    match threads {
        1 => write(false),
        0 => write(true),
        n => match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
            Ok(pool) => pool.install(|| write(true)),
            // No threads to be had: the serial path gives the same bytes.
            Err(_) => write(false),
        },
    }
}

/// Writes `image` as `exr`'s `image.write().to_buffered(..)` does, compressing the blocks on
/// the current rayon pool when `parallel`.
fn write_file(image: &ExrImage, parallel: bool) -> Result<Vec<u8>> {
    let headers = image.layer_data.infer_headers(&image.attributes);
    let layers = image.layer_data.create_writer(&headers);
    let mut out = Cursor::new(Vec::new());
    exr::block::write(&mut out, headers, true, |meta, chunk_writer| {
        let mut blocks =
            meta.collect_ordered_block_data(|index| layers.extract_uncompressed_block(&meta.headers, index));
        let compress = |(i, block): (usize, UncompressedBlock)| block.compress_to_chunk(&meta.headers).map(|c| (i, c));
        loop {
            let batch: Vec<(usize, UncompressedBlock)> = blocks.by_ref().take(BATCH).collect();
            if batch.is_empty() {
                return Ok(());
            }
            let chunks: Vec<exr::error::Result<(usize, Chunk)>> = if parallel {
                batch.into_par_iter().map(compress).collect()
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
