//! The family's decoders through the `image` crate's public API (issue 16): after
//! `hdrcodec::register_image_decoding_hooks()`, `image::open` and `image::load_from_memory`
//! give every format of the family as `Rgb32F`/`Rgba32F` with exactly our decoders' samples;
//! files our hooks do not take in HDR (an 8-bit TIFF, a plain JPEG) still go to `image`'s own
//! decoders; limits and damage end in `image` errors, not panics.

use hdrcodec::core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, HdrImage, Limits};
use hdrcodec::image_hooks::{from_dynamic_image, to_dynamic_image, HdrDecoder};
use image::{ColorType, ImageDecoder};
use std::path::{Path, PathBuf};
use std::sync::Once;

fn register() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        assert!(hdrcodec::register_image_decoding_hooks() >= 10);
    });
}

fn scene(channels: Channels) -> HdrImage {
    let (w, h) = (40u32, 24u32);
    let n = channels.count() as u32;
    let samples = (0..w * h * n)
        .map(|i| {
            let (x, y, c) = ((i / n) % w, (i / n) / w, i % n);
            if c == 3 {
                (x as f32 / w as f32).min(1.0)
            } else {
                0.01 * 2f32.powf((x + y) as f32 / 6.0) * (1.0 + 0.3 * c as f32)
            }
        })
        .collect();
    HdrImage::new(w, h, channels, samples, ColorInfo { nits_per_unit: 100.0, ..ColorInfo::default() }).unwrap()
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hdrcodec-image-hooks-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A file of every format of the family that writes, named `CODEC.EXT` with its codec's first
/// extension (JPEG-HDR shares `.jpg` with the gain-map codec, LogLuv24 and LogL16 `.tif` with
/// LogLuv32: each has a file of its own).
fn family_files(dir: &Path) -> Vec<(String, PathBuf)> {
    let registry = hdrcodec::registry();
    let mut files = Vec::new();
    for codec in registry.codecs().iter().filter(|c| c.can_encode()) {
        let channels = if codec.name() == "exr" || codec.name() == "jxr" { Channels::Rgba } else { Channels::Rgb };
        let settings = EncodeSettings::default().with_effort(0);
        let (bytes, _) = hdrcodec::encode_for(codec.as_ref(), &scene(channels), &settings).unwrap();
        let path = dir.join(format!("{}.{}", codec.name(), codec.extensions()[0]));
        std::fs::write(&path, bytes).unwrap();
        files.push((format!("{}.{}", codec.name(), codec.extensions()[0]), path));
    }
    files
}

#[test]
fn image_open_reads_every_format_of_the_family_as_our_decoders_do() {
    register();
    let dir = scratch_dir("open");
    let files = family_files(&dir);
    let names: Vec<&str> = files.iter().map(|(n, _)| n.as_str()).collect();
    for ext in ["exr", "pfm", "hdr", "tif", "dds", "ktx2", "jxr", "jpg", "hdrc"] {
        assert!(names.iter().any(|n| n.ends_with(&format!(".{ext}"))), "no .{ext} among {names:?}");
    }
    for name in ["jpeg-hdr.jpg", "logluv24.tif", "logl16.tif"] {
        assert!(names.contains(&name), "no {name} among {names:?}");
    }
    let registry = hdrcodec::registry();
    for (name, path) in &files {
        let (_, ours) = registry.read(path, &Limits::default()).unwrap();
        let theirs = image::open(path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((theirs.width(), theirs.height()), (ours.width(), ours.height()), "{name}");
        let samples: &[f32] = match (&theirs, ours.channels().count()) {
            (image::DynamicImage::ImageRgb32F(b), 3) => b.as_raw(),
            (image::DynamicImage::ImageRgba32F(b), 4) => b.as_raw(),
            (other, n) => panic!("{name}: {:?} for {n} channels", other.color()),
        };
        // Bit for bit: the same decoder wrote both.
        assert!(samples.iter().zip(ours.samples()).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}");
        // And from memory, by magic number where `image` does not know the format.
        let data = std::fs::read(path).unwrap();
        if ["jxr", "ktx2", "dds", "pfm", "hdrc"].iter().any(|e| name.ends_with(&format!(".{e}"))) {
            let from_memory = image::load_from_memory(&data).unwrap_or_else(|e| panic!("{name} from memory: {e}"));
            assert_eq!(from_memory, theirs, "{name} from memory");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn files_our_hooks_do_not_take_in_hdr_stay_with_images_decoders() {
    register();
    let dir = scratch_dir("builtin");
    let rgb8 = image::RgbImage::from_fn(16, 8, |x, y| image::Rgb([(x * 16) as u8, (y * 32) as u8, 7]));
    for ext in ["tif", "jpg"] {
        let path = dir.join(format!("plain.{ext}"));
        rgb8.save(&path).unwrap();
        let back = image::open(&path).unwrap_or_else(|e| panic!("{ext}: {e}"));
        assert_eq!(back.color(), ColorType::Rgb8, "{ext}");
        let data = std::fs::read(&path).unwrap();
        let ext: &'static str = if ext == "tif" { "tif" } else { "jpg" };
        assert!(HdrDecoder::new(ext, data).is_err(), "{ext}: taken by hdrcodec");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_decoder_says_size_colour_type_and_primaries_and_honours_limits() {
    register();
    let mut image = scene(Channels::Rgb);
    image.color.primaries = ColorPrimaries::Bt2020;
    let codec = hdrcodec::registry().by_name("jxr").unwrap();
    let (bytes, _) = hdrcodec::encode_for(codec.as_ref(), &image, &EncodeSettings::default()).unwrap();
    let mut decoder = HdrDecoder::new("jxr", bytes.clone()).unwrap();
    assert_eq!(decoder.dimensions(), (40, 24));
    assert_eq!(decoder.color_type(), ColorType::Rgb32F);
    // JPEG XR files are scRGB (1.0 = 80 cd/m²): the scale `image` cannot carry is in the info.
    assert_eq!(decoder.info().color.nits_per_unit, 80.0);
    let icc = decoder.icc_profile().unwrap().expect("an ICC profile of the primaries");
    assert_eq!(hdrcodec::jpeghdr::icc::primaries(&icc), Some(ColorPrimaries::Bt2020));
    // A file that records no primaries gets no profile.
    let pfm = hdrcodec::registry().by_name("pfm").unwrap();
    let (bytes_pfm, _) = hdrcodec::encode_for(pfm.as_ref(), &scene(Channels::Rgb), &EncodeSettings::default()).unwrap();
    assert_eq!(HdrDecoder::new("pfm", bytes_pfm).unwrap().icc_profile().unwrap(), None);

    // `image`'s limits: too wide is refused before any pixel is decoded.
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(39);
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes.clone())).with_guessed_format().unwrap();
    reader.limits(limits);
    assert!(matches!(reader.decode(), Err(image::ImageError::Limits(_))));
    // A byte budget smaller than the image: refused too, not a panic.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(1000);
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().unwrap();
    reader.limits(limits);
    assert!(reader.decode().is_err());
}

#[test]
fn damaged_files_are_image_errors() {
    register();
    let dir = scratch_dir("damaged");
    for (name, path) in family_files(&dir) {
        let data = std::fs::read(&path).unwrap();
        for cut in [data.len() / 2, data.len() * 9 / 10] {
            std::fs::write(&path, &data[..cut]).unwrap();
            // An error or (for formats whose tail is padding) an image; never a panic.
            let outcome = std::panic::catch_unwind(|| image::open(&path));
            assert!(outcome.is_ok(), "{name} cut at {cut}: panicked");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn hdr_images_and_image_buffers_convert_without_guessing() {
    let image = scene(Channels::Rgba);
    let samples = image.samples().to_vec();
    let dynamic = to_dynamic_image(image.clone());
    assert_eq!(dynamic.as_rgba32f().unwrap().as_raw(), &samples);
    let back = from_dynamic_image(dynamic, image.color.clone()).unwrap();
    assert_eq!(back.samples(), &samples[..]);
    assert_eq!(back.channels(), Channels::Rgba);
    let rgb8 = image::DynamicImage::ImageRgb8(image::RgbImage::new(2, 2));
    let e = from_dynamic_image(rgb8, ColorInfo::default()).unwrap_err().to_string();
    assert!(e.contains("transfer curve"), "{e}");
}
