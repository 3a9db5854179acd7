//! [`HdrImage`] and the `exr` crate's own image types, both ways, for programs that already
//! use `exr`'s reader and writer. Colour travels as the codec records it: `chromaticities`
//! (absent: BT.709) and `whiteLuminance` (absent: 100 nits per unit).
//!
//! - **Writing without a copy**: [`RgbPixels`] and [`RgbaPixels`] implement `exr`'s
//!   [`GetPixel`] over a borrowed `HdrImage`, so `exr`'s writer reads each pixel straight from
//!   the image's buffer; [`rgb_exr_image`] and [`rgba_exr_image`] wrap them in the
//!   `exr::image::Image` that `exr`'s `write()` takes, and [`write_with_exr`] writes it.
//! - **Reading without an intermediate buffer**: [`HdrImageStorage`] is the pixel storage of
//!   `exr`'s `rgba_channels` / `rgb_channels` readers (its create and set functions fill an
//!   `HdrImage` directly, within [`Limits`]); [`into_hdr_image`] adds the colour; [`read_with_exr`]
//!   does both.
//! - **Converting** what `exr` users hold: `Image<Layer<SpecificChannels<_, _>>>` with any
//!   pixel storage ([`from_rgba_channels`], [`from_rgb_channels`]; `exr`'s `PixelVec` included)
//!   and `Image<Layer<AnyChannels<FlatSamples>>>` ([`from_flat_exr_image`],
//!   [`to_flat_exr_image`]). These layouts differ from the interleaved `f32` buffer (tuples,
//!   or one plane per channel), so these copy the samples once.
//!
//! For untrusted files [`crate::decode_exr`] is the safer reader: it checks every size against
//! [`Limits`] before `exr` allocates anything, which `exr`'s own reader does not.
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, HdrImage, Limits};
//! use hdrcodec_exr::interop::{read_with_exr, rgba_exr_image};
//! use hdrcodec_exr::{exr::prelude::WritableImage, ExrCompression};
//!
//! let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 203.0, hdr10: None };
//! let image = HdrImage::new(2, 1, Channels::Rgba, vec![0.5, 1.0, 2.0, 1.0, 4.0, 8.0, 16.0, 0.25], color)?;
//! // exr's own writer, reading the pixels from `image` as it goes; f32 samples ("FLOAT").
//! let mut file = std::io::Cursor::new(Vec::new());
//! rgba_exr_image::<f32>(&image, ExrCompression::Piz).write().non_parallel().to_buffered(&mut file).unwrap();
//! // exr's own reader, filling an HdrImage.
//! file.set_position(0);
//! let back = read_with_exr(file, &Limits::default())?;
//! assert_eq!(back, image);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use exr::block::samples::{FromNativeSample, IntoNativeSample};
use exr::image::write::channels::GetPixel;
use exr::image::{
    AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer, RgbaChannels, SpecificChannels,
};
use exr::image::{IntoSample, RgbChannels};
use exr::math::Vec2;
use exr::meta::attribute::{ChannelDescription, LineOrder};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::{f16, ReadChannels as _, ReadLayers as _, SmallVec, WritableImage};
use hdrcodec_core::{Channels, ColorInfo, Error, HdrImage, Limits, Result};
use std::io::{Read, Seek, Write};
use std::marker::PhantomData;

use crate::decode::{colour_from_attributes, guarded, map_err};
use crate::encode::set_colour_attributes;
use crate::{ExrCompression, ExrEncodeOptions, ExrPixelType};

/// The RGB samples of a borrowed [`HdrImage`] as `exr`'s writer asks for them (alpha, if any,
/// is left out). `T` is the stored type: `f32` writes FLOAT channels exactly, `f16` HALF ones
/// rounded to nearest.
#[derive(Debug)]
pub struct RgbPixels<'a, T> {
    image: &'a HdrImage,
    sample: PhantomData<fn() -> T>,
}

/// The RGBA samples of a borrowed [`HdrImage`] as `exr`'s writer asks for them (alpha 1.0 for an
/// RGB image). `T` as for [`RgbPixels`].
#[derive(Debug)]
pub struct RgbaPixels<'a, T> {
    image: &'a HdrImage,
    sample: PhantomData<fn() -> T>,
}

impl<'a, T> RgbPixels<'a, T> {
    /// The pixels of `image`, borrowed.
    pub fn new(image: &'a HdrImage) -> Self {
        RgbPixels { image, sample: PhantomData }
    }
}

impl<'a, T> RgbaPixels<'a, T> {
    /// The pixels of `image`, borrowed.
    pub fn new(image: &'a HdrImage) -> Self {
        RgbaPixels { image, sample: PhantomData }
    }
}

/// The samples of the pixel at `position`, or black for a position outside the image (`exr`
/// asks only for positions inside the layer, whose size is the image's).
fn samples_at(image: &HdrImage, position: Vec2<usize>) -> &[f32] {
    let n = image.channels().count();
    let at = (position.y() * image.width() as usize + position.x()) * n;
    let inside = position.x() < image.width() as usize && position.y() < image.height() as usize;
    image.samples().get(at..at + n).filter(|_| inside).unwrap_or(&[0.0; 4][..n])
}

impl<T: FromNativeSample> GetPixel for RgbPixels<'_, T> {
    type Pixel = (T, T, T);
    fn get_pixel(&self, position: Vec2<usize>) -> (T, T, T) {
        let s = samples_at(self.image, position);
        (T::from_f32(s[0]), T::from_f32(s[1]), T::from_f32(s[2]))
    }
}

impl<T: FromNativeSample> GetPixel for RgbaPixels<'_, T> {
    type Pixel = (T, T, T, T);
    fn get_pixel(&self, position: Vec2<usize>) -> (T, T, T, T) {
        let s = samples_at(self.image, position);
        let alpha = s.get(3).copied().unwrap_or(1.0);
        (T::from_f32(s[0]), T::from_f32(s[1]), T::from_f32(s[2]), T::from_f32(alpha))
    }
}

/// An `exr` image of R, G, B channels read from a borrowed [`HdrImage`]: see [`rgb_exr_image`].
pub type RgbExrImage<'a, T> = Image<Layer<SpecificChannels<RgbPixels<'a, T>, RgbChannels>>>;

/// The channel descriptions of an RGBA layer that `exr`'s `SpecificChannels::rgba` makes.
pub type RgbaWriteChannels = (ChannelDescription, ChannelDescription, ChannelDescription, ChannelDescription);

/// An `exr` image of R, G, B, A channels read from a borrowed [`HdrImage`]: see
/// [`rgba_exr_image`].
pub type RgbaExrImage<'a, T> = Image<Layer<SpecificChannels<RgbaPixels<'a, T>, RgbaWriteChannels>>>;

/// The one-layer `exr` image whose pixels are those of `image` (borrowed, not copied), with its
/// colour attributes, in scan lines compressed with `compression`.
fn one_layer<C>(image: &HdrImage, compression: ExrCompression, channels: C) -> Image<Layer<C>> {
    let size = Vec2(image.width() as usize, image.height() as usize);
    let mut shared = ImageAttributes::with_size(size);
    let mut own = LayerAttributes::default();
    set_colour_attributes(&image.color, &mut shared, &mut own);
    let encoding =
        Encoding { compression: compression.to_exr(), blocks: Blocks::ScanLines, line_order: LineOrder::Increasing };
    Image { attributes: shared, layer_data: Layer { channel_data: channels, attributes: own, size, encoding } }
}

/// `image` as an `exr` image of R, G, B channels of type `T` (`f32` or `f16`) for `exr`'s
/// writer (`.write().to_file(path)`); the samples are read from `image` as the writer goes.
pub fn rgb_exr_image<T>(image: &HdrImage, compression: ExrCompression) -> RgbExrImage<'_, T>
where
    T: FromNativeSample + IntoSample,
{
    one_layer(image, compression, SpecificChannels::rgb(RgbPixels::new(image)))
}

/// `image` as an `exr` image of R, G, B, A channels of type `T` (`f32` or `f16`; alpha 1.0 for
/// an RGB image) for `exr`'s writer; the samples are read from `image` as the writer goes.
pub fn rgba_exr_image<T>(image: &HdrImage, compression: ExrCompression) -> RgbaExrImage<'_, T>
where
    T: FromNativeSample + IntoSample,
{
    one_layer(image, compression, SpecificChannels::rgba(RgbaPixels::new(image)))
}

/// Writes `image` with `exr`'s own writer (on the calling thread): R, G, B (and A when the image
/// has alpha), half or float and compressed as `options` say, with the colour attributes.
/// [`crate::write_exr`] writes the same channels and attributes faster and on the caller's
/// threads; this is for programs that want `exr`'s writer. A panic inside `exr` (its B44
/// compressor has one on some sizes, see the README) becomes an error.
pub fn write_with_exr(image: &HdrImage, options: &ExrEncodeOptions, out: impl Write + Seek) -> Result<()> {
    let c = options.compression;
    guarded("writing an OpenEXR file", || {
        let written = match (image.channels(), options.pixel) {
            (Channels::Rgba, ExrPixelType::Half) => {
                rgba_exr_image::<f16>(image, c).write().non_parallel().to_buffered(out)
            }
            (Channels::Rgba, ExrPixelType::Float) => {
                rgba_exr_image::<f32>(image, c).write().non_parallel().to_buffered(out)
            }
            (_, ExrPixelType::Half) => rgb_exr_image::<f16>(image, c).write().non_parallel().to_buffered(out),
            (_, ExrPixelType::Float) => rgb_exr_image::<f32>(image, c).write().non_parallel().to_buffered(out),
        };
        written.map_err(map_err)
    })
}

/// The pixel storage of `exr`'s `rgba_channels` and `rgb_channels` readers: an [`HdrImage`]
/// filled as `exr` decodes, with no buffer in between. Its size is checked against [`Limits`]
/// before it is allocated; when it does not fit, the pixels are ignored and
/// [`HdrImageStorage::into_image`] returns the error.
#[derive(Debug)]
pub struct HdrImageStorage {
    image: Result<HdrImage>,
}

impl HdrImageStorage {
    /// An image for a layer of `resolution`: RGBA when `channels` has alpha, else RGB. For
    /// `rgba_channels`' create function: `|size, channels| HdrImageStorage::for_rgba_layer(size,
    /// channels, &limits)`.
    pub fn for_rgba_layer(resolution: Vec2<usize>, channels: &RgbaChannels, limits: &Limits) -> Self {
        let layout = if channels.3.is_some() { Channels::Rgba } else { Channels::Rgb };
        Self::with_layout(resolution, layout, limits)
    }

    /// An RGB image for a layer of `resolution`. For `rgb_channels`' create function.
    pub fn for_rgb_layer(resolution: Vec2<usize>, _channels: &RgbChannels, limits: &Limits) -> Self {
        Self::with_layout(resolution, Channels::Rgb, limits)
    }

    fn with_layout(resolution: Vec2<usize>, layout: Channels, limits: &Limits) -> Self {
        let (w, h) = (resolution.width() as u64, resolution.height() as u64);
        let image = limits.check_image(w, h, layout).map(|()| HdrImage::zeroed(w as u32, h as u32, layout));
        HdrImageStorage { image }
    }

    /// Stores one pixel: `rgba_channels`' set function. The alpha is dropped when the layer has
    /// none (`exr` then passes 1.0).
    pub fn set_rgba(&mut self, position: Vec2<usize>, pixel: (f32, f32, f32, f32)) {
        self.set(position, [pixel.0, pixel.1, pixel.2, pixel.3]);
    }

    /// Stores one pixel: `rgb_channels`' set function.
    pub fn set_rgb(&mut self, position: Vec2<usize>, pixel: (f32, f32, f32)) {
        self.set(position, [pixel.0, pixel.1, pixel.2, 1.0]);
    }

    fn set(&mut self, position: Vec2<usize>, pixel: [f32; 4]) {
        let Ok(image) = &mut self.image else { return };
        let n = image.channels().count();
        if position.x() >= image.width() as usize {
            return;
        }
        let at = (position.y() * image.width() as usize + position.x()) * n;
        if let Some(dst) = image.samples_mut().get_mut(at..at + n) {
            dst.copy_from_slice(&pixel[..n]);
        }
    }

    /// The image (with the default colour: [`into_hdr_image`] adds the file's), or why it could
    /// not be allocated.
    pub fn into_image(self) -> Result<HdrImage> {
        self.image
    }
}

/// The [`HdrImage`] that `exr`'s reader filled (the storage is moved, not copied), with the
/// colour of the image's and the layer's attributes.
pub fn into_hdr_image<C>(image: Image<Layer<SpecificChannels<HdrImageStorage, C>>>) -> Result<HdrImage> {
    let Image { attributes, layer_data } = image;
    let mut out = layer_data.channel_data.pixels.into_image()?;
    out.color = colour_from_attributes(&attributes, &layer_data.attributes);
    Ok(out)
}

/// Reads the first layer with R, G and B channels (and A, if it has one) of an OpenEXR file
/// with `exr`'s own reader (on the calling thread), straight into an [`HdrImage`] sized within
/// `limits`, with its colour. Half and float samples are exact; the largest resolution level
/// of a mip-mapped file is read. A panic inside `exr` becomes an error.
pub fn read_with_exr(reader: impl Read + Seek, limits: &Limits) -> Result<HdrImage> {
    let image = guarded("reading an OpenEXR file", || {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |size, channels| HdrImageStorage::for_rgba_layer(size, channels, limits),
                HdrImageStorage::set_rgba,
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(reader)
            .map_err(map_err)
    })?;
    into_hdr_image(image)
}

/// An `exr` image of R, G, B, A channels in any pixel storage (`exr`'s `PixelVec`, a closure,
/// one's own) as an [`HdrImage`]: RGBA when the layer has alpha, else RGB. Fails when the size
/// exceeds `limits`.
pub fn from_rgba_channels<S, R, G, B, A>(
    image: &Image<Layer<SpecificChannels<S, RgbaChannels>>>,
    limits: &Limits,
) -> Result<HdrImage>
where
    S: GetPixel<Pixel = (R, G, B, A)>,
    R: IntoNativeSample,
    G: IntoNativeSample,
    B: IntoNativeSample,
    A: IntoNativeSample,
{
    let layer = &image.layer_data;
    let layout = if layer.channel_data.channels.3.is_some() { Channels::Rgba } else { Channels::Rgb };
    let get = |p| {
        let (r, g, b, a) = layer.channel_data.pixels.get_pixel(p);
        [r.to_f32(), g.to_f32(), b.to_f32(), a.to_f32()]
    };
    collect_pixels(image.attributes.clone(), layer, layout, limits, get)
}

/// An `exr` image of R, G, B channels in any pixel storage as an RGB [`HdrImage`]. Fails when
/// the size exceeds `limits`.
pub fn from_rgb_channels<S, R, G, B>(
    image: &Image<Layer<SpecificChannels<S, RgbChannels>>>,
    limits: &Limits,
) -> Result<HdrImage>
where
    S: GetPixel<Pixel = (R, G, B)>,
    R: IntoNativeSample,
    G: IntoNativeSample,
    B: IntoNativeSample,
{
    let layer = &image.layer_data;
    let get = |p| {
        let (r, g, b) = layer.channel_data.pixels.get_pixel(p);
        [r.to_f32(), g.to_f32(), b.to_f32(), 1.0]
    };
    collect_pixels(image.attributes.clone(), layer, Channels::Rgb, limits, get)
}

/// An image of `layer`'s size, pixel by pixel from `get`, with the colour of the attributes.
fn collect_pixels<C>(
    shared: ImageAttributes,
    layer: &Layer<C>,
    layout: Channels,
    limits: &Limits,
    get: impl Fn(Vec2<usize>) -> [f32; 4],
) -> Result<HdrImage> {
    let (w, h) = (layer.size.width(), layer.size.height());
    limits.check_image(w as u64, h as u64, layout)?;
    let n = layout.count();
    let mut samples = Vec::with_capacity(w * h * n);
    for y in 0..h {
        for x in 0..w {
            samples.extend_from_slice(&get(Vec2(x, y))[..n]);
        }
    }
    HdrImage::new(w as u32, h as u32, layout, samples, colour_from_attributes(&shared, &layer.attributes))
}

/// An `exr` image of one layer whose channels each hold one plane of samples: what `exr`'s
/// `read_all_flat_layers` and `read_first_flat_layer` give.
pub type FlatExrImage = Image<Layer<AnyChannels<FlatSamples>>>;

/// A flat `exr` image (its R, G, B and, if present, A channels, names matched
/// case-insensitively; other channels are ignored) as an [`HdrImage`] with the colour of its
/// attributes. Half and float samples are exact; uint samples keep their numeric value, as the
/// decoder does. Fails when a channel is missing, subsampled or of the wrong length.
pub fn from_flat_exr_image(image: &FlatExrImage) -> Result<HdrImage> {
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let find = |name: &str| layer.channel_data.list.iter().find(|c| c.name.to_string().eq_ignore_ascii_case(name));
    let mut planes = Vec::with_capacity(4);
    for name in ["R", "G", "B"] {
        planes.push(find(name).ok_or_else(|| Error::invalid(format!("the OpenEXR layer has no {name} channel")))?);
    }
    planes.extend(find("A"));
    let layout = if planes.len() == 4 { Channels::Rgba } else { Channels::Rgb };
    let n = layout.count();
    let mut samples = vec![0.0f32; w * h * n];
    for (c, channel) in planes.iter().enumerate() {
        if channel.sampling != Vec2(1, 1) || channel.sample_data.len() != w * h {
            return Err(Error::invalid(format!(
                "OpenEXR channel {} holds {} samples for {w}x{h} pixels (sampling {}x{})",
                channel.name,
                channel.sample_data.len(),
                channel.sampling.x(),
                channel.sampling.y()
            )));
        }
        let dst = samples.iter_mut().skip(c).step_by(n);
        match &channel.sample_data {
            FlatSamples::F16(v) => dst.zip(v).for_each(|(d, s)| *d = s.to_f32()),
            FlatSamples::F32(v) => dst.zip(v).for_each(|(d, s)| *d = *s),
            FlatSamples::U32(v) => dst.zip(v).for_each(|(d, s)| *d = *s as f32),
        }
    }
    HdrImage::new(w as u32, h as u32, layout, samples, colour_from_attributes(&image.attributes, &layer.attributes))
}

/// `image` as a flat `exr` image, one plane per channel (R, G, B and A if the image has alpha),
/// half or float, with its colour attributes: ready for `exr`'s writer, or for code that takes
/// `exr`'s flat images.
pub fn to_flat_exr_image(image: &HdrImage, pixel: ExrPixelType, compression: ExrCompression) -> FlatExrImage {
    let n = image.channels().count();
    let plane = |c: usize| {
        let samples = image.samples().iter().skip(c).step_by(n);
        match pixel {
            ExrPixelType::Half => FlatSamples::F16(samples.map(|&v| f16::from_f32(v)).collect()),
            ExrPixelType::Float => FlatSamples::F32(samples.copied().collect()),
        }
    };
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
        ["R", "G", "B", "A"].iter().take(n).enumerate().map(|(c, name)| AnyChannel::new(*name, plane(c))).collect();
    one_layer(image, compression, AnyChannels::sort(list))
}

/// The colour the file's attributes give, as [`into_hdr_image`] reads it: for callers that build
/// their own reader with `exr` and keep its attributes.
pub fn colour_of(shared: &ImageAttributes, layer: &LayerAttributes) -> ColorInfo {
    colour_from_attributes(shared, layer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{decode_exr, ExrCodec};
    use exr::image::pixel_vec::PixelVec;
    use hdrcodec_core::{Chromaticities, ColorPrimaries, EncodeSettings, ImageCodec};
    use std::io::Cursor;

    /// Custom chromaticities (no named space has them) and 203 nits per unit, so that both
    /// attributes are written and read back.
    fn colour() -> ColorInfo {
        let primaries = ColorPrimaries::Custom(Chromaticities {
            red: [0.69, 0.3],
            green: [0.2, 0.74],
            blue: [0.14, 0.05],
            white: [0.3127, 0.329],
        });
        ColorInfo { primaries, nits_per_unit: 203.0, hdr10: None }
    }

    /// An odd-sized image whose samples survive `pixel` exactly: any finite float (tiny,
    /// huge, negative, subnormal) for float; for half, values that are halves (the finite
    /// half bit patterns spread over the whole range).
    fn picture(channels: Channels, pixel: ExrPixelType) -> HdrImage {
        let (w, h) = (37u32, 21u32);
        let count = (w * h) as usize * channels.count();
        let samples = (0..count as u32)
            .map(|i| match pixel {
                ExrPixelType::Float => f32::from_bits(i.wrapping_mul(0x9e37_79b9) & 0xfeff_ffff),
                ExrPixelType::Half => {
                    let v = f16::from_bits((i.wrapping_mul(40503) & 0xffff) as u16);
                    if v.is_finite() {
                        v.to_f32()
                    } else {
                        1.5
                    }
                }
            })
            .collect();
        HdrImage::new(w, h, channels, samples, colour()).unwrap()
    }

    fn bits(image: &HdrImage) -> Vec<u32> {
        image.samples().iter().map(|v| v.to_bits()).collect()
    }

    fn assert_same(a: &HdrImage, b: &HdrImage, what: &str) {
        assert_eq!((a.width(), a.height(), a.channels()), (b.width(), b.height(), b.channels()), "{what}");
        assert!(bits(a) == bits(b), "{what}: samples differ");
        assert_eq!(a.color, b.color, "{what}");
    }

    const LAYOUTS: [(Channels, ExrPixelType); 4] = [
        (Channels::Rgb, ExrPixelType::Float),
        (Channels::Rgba, ExrPixelType::Float),
        (Channels::Rgb, ExrPixelType::Half),
        (Channels::Rgba, ExrPixelType::Half),
    ];

    #[test]
    fn exr_writer_and_reader_round_trip_bit_exactly_with_colour() {
        for (channels, pixel) in LAYOUTS {
            let image = picture(channels, pixel);
            let what = format!("{channels:?} {pixel:?}");
            let options = ExrEncodeOptions { compression: ExrCompression::Piz, pixel };
            let mut file = Cursor::new(Vec::new());
            write_with_exr(&image, &options, &mut file).unwrap();
            let file = file.into_inner();
            // exr's writer, read by the codec's own decoder; and exr's reader into an HdrImage.
            assert_same(&decode_exr(&file, &Limits::default()).unwrap(), &image, &what);
            assert_same(&read_with_exr(Cursor::new(&file), &Limits::default()).unwrap(), &image, &what);
            // The codec's writer, read by exr's reader.
            let settings = EncodeSettings::default()
                .with_option("pixel", if pixel == ExrPixelType::Half { "half" } else { "float" });
            let ours = ExrCodec.encode(&image, &settings).unwrap();
            assert_same(&read_with_exr(Cursor::new(&ours), &Limits::default()).unwrap(), &image, &what);
        }
    }

    #[test]
    fn flat_images_convert_both_ways_bit_exactly() {
        for (channels, pixel) in LAYOUTS {
            let image = picture(channels, pixel);
            let what = format!("{channels:?} {pixel:?}");
            let flat = to_flat_exr_image(&image, pixel, ExrCompression::Zip16);
            assert_eq!(flat.layer_data.channel_data.list.len(), channels.count());
            assert_same(&from_flat_exr_image(&flat).unwrap(), &image, &what);
            // Written by exr as it is, and read back by exr as a flat image.
            let mut file = Cursor::new(Vec::new());
            flat.write().non_parallel().to_buffered(&mut file).unwrap();
            let file = file.into_inner();
            assert_same(&decode_exr(&file, &Limits::default()).unwrap(), &image, &what);
            let read: FlatExrImage = exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .all_channels()
                .first_valid_layer()
                .all_attributes()
                .from_buffered(Cursor::new(&file))
                .unwrap();
            assert_same(&from_flat_exr_image(&read).unwrap(), &image, &what);
        }
    }

    #[test]
    fn pixel_vec_layers_convert_with_their_alpha() {
        for (channels, pixel) in LAYOUTS {
            let image = picture(channels, pixel);
            let what = format!("{channels:?} {pixel:?}");
            let file = ExrCodec.encode(&image, &EncodeSettings::default().with_option("pixel", "float")).unwrap();
            let read = exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .rgba_channels(PixelVec::<(f32, f32, f32, f32)>::constructor, PixelVec::set_pixel)
                .first_valid_layer()
                .all_attributes()
                .from_buffered(Cursor::new(&file))
                .unwrap();
            assert_same(&from_rgba_channels(&read, &Limits::default()).unwrap(), &image, &what);
            let rgb = exr::prelude::read()
                .no_deep_data()
                .largest_resolution_level()
                .rgb_channels(PixelVec::<(f16, f32, f32)>::constructor, PixelVec::set_pixel)
                .first_valid_layer()
                .all_attributes()
                .from_buffered(Cursor::new(&file))
                .unwrap();
            let back = from_rgb_channels(&rgb, &Limits::default()).unwrap();
            assert_eq!(back.channels(), Channels::Rgb);
            // Green and blue are exact; red went through half on the way.
            let expected: Vec<f32> = image.rgb().flat_map(|[r, g, b]| [f16::from_f32(r).to_f32(), g, b]).collect();
            assert_eq!(back.samples(), &expected[..], "{what}");
            assert_eq!(back.color, image.color);
        }
    }

    #[test]
    fn the_limits_bound_what_exr_reader_allocates() {
        let image = picture(Channels::Rgba, ExrPixelType::Float);
        let file = ExrCodec.encode(&image, &EncodeSettings::default()).unwrap();
        let small = Limits::default().with_max_pixels(100);
        let e = read_with_exr(Cursor::new(&file), &small).unwrap_err();
        assert!(matches!(e, Error::LimitExceeded { .. }), "{e}");
        let flat = to_flat_exr_image(&image, ExrPixelType::Float, ExrCompression::None);
        let mut short = flat.clone();
        if let FlatSamples::F32(v) = &mut short.layer_data.channel_data.list[0].sample_data {
            v.pop();
        }
        assert!(from_flat_exr_image(&short).is_err());
        let mut no_green = flat;
        no_green.layer_data.channel_data.list.retain(|c| c.name.to_string() != "G");
        assert!(from_flat_exr_image(&no_green).unwrap_err().to_string().contains("no G channel"));
    }
}
