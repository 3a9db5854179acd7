//! Writing: one scan-line part through `exr`'s image writer.

use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{Chromaticities as ExrChromaticities, LineOrder};
use exr::meta::header::LayerAttributes;
use exr::prelude::{f16, SmallVec, WritableImage};
use hdrcodec_core::{ColorPrimaries, Error, HdrImage, Result, ThreadPool};
use std::io::Cursor;

use crate::decode::{guarded, map_err};
use crate::{ExrCompression, ExrEncodeOptions, ExrPixelType};

/// Encodes `image` as an OpenEXR file. A single-threaded `pool` compresses on the calling
/// thread; a parallel one lets `exr` compress blocks in parallel.
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
    let mut out = Cursor::new(Vec::new());
    guarded("writing an OpenEXR file", || {
        let writer = exr_image.write();
        // exr 1.74's B44 compressor can panic (index out of range, e.g. at width 257). A panic
        // on exr's own worker pool aborts the process, so B44 compresses on this thread, where
        // `guarded` turns the panic into an error.
        let b44 = matches!(options.compression, ExrCompression::B44 | ExrCompression::B44A);
        let result = if !pool.is_parallel() || b44 {
            writer.non_parallel().to_buffered(&mut out)
        } else {
            writer.to_buffered(&mut out)
        };
        result.map_err(map_err)
    })?;
    Ok(out.into_inner())
}
