//! Conversion band by band (`hdrcodec::convert_file`, `ImageCodec::row_encoder`): every encoder
//! that takes rows writes, from rows given in bands of any size, the bytes it writes for the
//! whole image, with the same notes; a conversion writes what decoding the whole image and
//! encoding it writes, whatever order the decoder delivers rows in, and holds less than the
//! decoded image.

use hdrcodec::core::sink::RowSink;
use hdrcodec::core::{
    Channels, ColorInfo, ColorPrimaries, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, HdrImage,
    ImageCodec, ImageInfo, Limits, Result,
};
use hdrcodec::Input;
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// A picture with negatives, NaN, huge values and a smooth part, so that every encoder has
/// something to clip and note.
fn picture(w: u32, h: u32, channels: Channels, primaries: ColorPrimaries) -> HdrImage {
    let n = channels.count() as u32;
    let samples = (0..w * h * n)
        .map(|i| {
            let (x, y, c) = ((i / n) % w, (i / n) / w, i % n);
            match (x * 31 + y * 17 + c) % 97 {
                0 => -0.5,
                1 => f32::NAN,
                2 => 1.0e5,
                _ => 0.01 + ((x * 7 + y * 13 + c * 5) % 101) as f32 * 0.05 * (1.0 + (y % 9) as f32),
            }
        })
        .collect();
    let color = ColorInfo { primaries, ..ColorInfo::default() };
    HdrImage::new(w, h, channels, samples, color).unwrap()
}

/// The encoders that take rows, with settings worth checking.
fn row_cases() -> Vec<(&'static str, EncodeSettings)> {
    let s = EncodeSettings::default;
    vec![
        ("pfm", s()),
        ("rgbe", s()),
        ("rgbe", s().with_option("format", "xyze")),
        ("rgbe", s().with_option("rle", "false")),
        ("exr", s()),
        ("exr", s().with_option("compression", "piz").with_option("pixel", "float")),
        ("exr", s().with_option("compression", "none")),
        ("exr", s().with_option("compression", "b44")),
        ("bc6h", s().with_effort(0)),
        ("bc6h", s().with_effort(0).with_option("signed", "true")),
        ("bc6h-ktx2", s().with_effort(0)),
        ("hdrc", s().with_option("tile", "32")),
        ("hdrc", s().with_effort(0).with_option("tile", "20").with_option("payload", "bc6h")),
        ("hdrc", s().with_option("tile", "48").with_option("payload", "rgbe")),
    ]
}

#[test]
fn row_encoders_write_the_whole_image_bytes_from_bands_of_any_size() {
    let registry = hdrcodec::registry();
    for (w, h) in [(67u32, 300u32), (5, 3), (1, 1)] {
        for channels in [Channels::Rgb, Channels::Rgba] {
            for primaries in [ColorPrimaries::Bt709, ColorPrimaries::Bt2020, ColorPrimaries::Unspecified] {
                let image = picture(w, h, channels, primaries);
                for (name, settings) in row_cases() {
                    let codec = registry.by_name(name).unwrap();
                    let what = format!("{name} {settings:?} {w}x{h} {channels:?} {}", primaries.name());
                    let mut whole = Cursor::new(Vec::new());
                    let report = codec.encode_to_seekable(&image, &settings, &mut whole).unwrap();
                    let row_len = w as usize * channels.count();
                    for band in [1usize, 7, 256, h as usize] {
                        let mut encoder = codec
                            .row_encoder(&ImageInfo::of(&image), &settings)
                            .unwrap_or_else(|e| panic!("{what}: {e}"))
                            .unwrap_or_else(|| panic!("{what}: no row encoder"));
                        // The file starts wherever the writer is.
                        let mut banded = Cursor::new(b"prefix".to_vec());
                        banded.set_position(6);
                        for rows in image.samples().chunks(band * row_len) {
                            encoder.write_rows(rows, &mut banded).unwrap();
                        }
                        let banded_report = encoder.finish(&mut banded).unwrap();
                        assert_eq!(banded.position() as usize, banded.get_ref().len(), "{what}: left at the end");
                        assert!(banded.get_ref()[6..] == whole.get_ref()[..], "{what}: bands of {band} rows");
                        assert_eq!(banded_report, report, "{what}: notes");
                    }
                }
            }
        }
    }
}

#[test]
fn a_row_encoder_refuses_missing_and_extra_rows() {
    let image = picture(8, 4, Channels::Rgb, ColorPrimaries::Bt709);
    let registry = hdrcodec::registry();
    for (name, settings) in row_cases() {
        let codec = registry.by_name(name).unwrap();
        let info = ImageInfo::of(&image);
        let mut out = Cursor::new(Vec::new());
        let mut encoder = codec.row_encoder(&info, &settings).unwrap().unwrap();
        encoder.write_rows(&image.samples()[..24 * 3], &mut out).unwrap();
        assert!(encoder.finish(&mut out).is_err(), "{name}: a missing row");
        let mut encoder = codec.row_encoder(&info, &settings).unwrap().unwrap();
        assert!(encoder.write_rows(&image.samples()[..5], &mut out).is_err(), "{name}: part of a row");
        encoder.write_rows(image.samples(), &mut out).unwrap();
        assert!(encoder.write_rows(&image.samples()[..24], &mut out).is_err(), "{name}: a row too many");
    }
}

#[test]
fn formats_that_need_the_whole_image_say_so() {
    let info = ImageInfo::of(&picture(8, 8, Channels::Rgb, ColorPrimaries::Bt709));
    let registry = hdrcodec::registry();
    let mips = EncodeSettings::default().with_option("mips", "true");
    for name in ["bc6h", "bc6h-ktx2"] {
        assert!(registry.by_name(name).unwrap().row_encoder(&info, &mips).unwrap().is_none(), "{name} with mips");
    }
    // One tile is the whole image; LogLuv chooses its scale from the whole image.
    let hdrc = registry.by_name("hdrc").unwrap();
    assert!(hdrc.row_encoder(&info, &EncodeSettings::default()).unwrap().is_none(), "hdrc in one tile");
    for name in ["logluv32", "logluv24", "logl16"] {
        let codec = registry.by_name(name).unwrap();
        assert!(codec.row_encoder(&info, &EncodeSettings::default()).unwrap().is_none(), "{name}");
    }
    // Options are checked when the encoder is asked for.
    let bad = EncodeSettings::default().with_option("no-such-option", "1");
    for (name, _) in row_cases() {
        assert!(registry.by_name(name).unwrap().row_encoder(&info, &bad).is_err(), "{name}");
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("hdrcodec-convert-bands-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Converts `file` (decoded by `from`) into `to` both ways, band by band and whole, and checks
/// that the bytes and notes agree.
fn check_conversion(from: &dyn ImageCodec, file: &[u8], to: &dyn ImageCodec, settings: &EncodeSettings, dir: &Path) {
    let what = format!("{} -> {} {settings:?}", from.name(), to.name());
    let banded_path = dir.join("banded");
    let whole_path = dir.join("whole");
    let options = DecodeOptions::default();
    let notes = hdrcodec::convert_file(from, Input::Bytes(file), &options, to, settings, &banded_path)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let image = from.decode_with(file, &options).unwrap();
    let whole_notes = hdrcodec::encode_file(to, &image, settings, &whole_path).unwrap();
    assert!(std::fs::read(&banded_path).unwrap() == std::fs::read(&whole_path).unwrap(), "{what}: bytes");
    assert_eq!(notes, whole_notes, "{what}: notes");
    // The decoder reading the file itself gives the same file.
    let from_path = dir.join("from");
    let mut input = Cursor::new(file);
    let from_notes = hdrcodec::convert_file(from, Input::File(&mut input), &options, to, settings, &from_path)
        .unwrap_or_else(|e| panic!("{what}, from the file: {e}"));
    assert!(std::fs::read(&from_path).unwrap() == std::fs::read(&whole_path).unwrap(), "{what}: bytes from the file");
    assert_eq!(from_notes, whole_notes, "{what}: notes from the file");
}

#[test]
fn conversions_write_what_decoding_whole_and_encoding_writes() {
    let dir = temp_dir("formats");
    let registry = hdrcodec::registry();
    // Inputs whose colour each output keeps, converts or labels.
    let inputs = [
        ("exr", picture(61, 70, Channels::Rgba, ColorPrimaries::DisplayP3)),
        ("exr", picture(61, 70, Channels::Rgb, ColorPrimaries::Bt2020)),
        ("pfm", picture(61, 70, Channels::Rgb, ColorPrimaries::Unspecified)),
        ("rgbe", picture(61, 70, Channels::Rgb, ColorPrimaries::Bt709)),
        ("bc6h", picture(61, 70, Channels::Rgb, ColorPrimaries::Unspecified)),
        ("hdrc", picture(61, 70, Channels::Rgba, ColorPrimaries::Bt2020)),
    ];
    for (input, image) in inputs {
        let from = registry.by_name(input).unwrap();
        let file = from.encode(&image, &EncodeSettings::default().with_effort(0)).unwrap();
        for to in registry.codecs().iter().filter(|c| c.can_encode()) {
            let base = EncodeSettings::default().with_effort(0);
            check_conversion(from.as_ref(), &file, to.as_ref(), &base, &dir);
            if to.name() == "hdrc" {
                let tiled = base.clone().with_option("tile", "16");
                check_conversion(from.as_ref(), &file, to.as_ref(), &tiled, &dir);
            }
            if to.color_signalling() != ColorSignalling::Any || to.name() == "exr" {
                let convert = base.clone().with_option("primaries", "bt2020");
                let out = dir.join("refused");
                let _ = std::fs::remove_file(&out);
                let options = DecodeOptions::default();
                let refused =
                    hdrcodec::convert_file(from.as_ref(), Input::Bytes(&file), &options, to.as_ref(), &convert, &out)
                        .is_err();
                if refused {
                    // A format that cannot say BT.2020 (gain-map JPEG: sRGB or Display P3)
                    // refuses the conversion of an image it would have to relabel, writing
                    // nothing.
                    assert!(!to.color_signalling().can_record(&ColorPrimaries::Bt2020), "{}", to.name());
                    assert!(!out.exists(), "{}: a refused conversion left a file", to.name());
                } else {
                    check_conversion(from.as_ref(), &file, to.as_ref(), &convert, &dir);
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A decoder that delivers its image's rows in bands, last band first (as a tiled or bottom-up
/// format may).
struct BackwardsDecoder {
    image: HdrImage,
    band: usize,
}

impl ImageCodec for BackwardsDecoder {
    fn name(&self) -> &'static str {
        "backwards"
    }
    fn id(&self) -> [u8; 4] {
        *b"BACK"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &[]
    }
    fn sniff(&self, _: &[u8]) -> bool {
        false
    }
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::Any
    }
    fn can_encode(&self) -> bool {
        false
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec::core::decode_image(self, data, options)
    }
    fn decode_rows(&self, _: &[u8], _: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        sink.start(&ImageInfo::of(&self.image))?;
        let row_len = self.image.width() as usize * self.image.channels().count();
        let bands: Vec<_> = self.image.samples().chunks(self.band * row_len).enumerate().collect();
        for (i, rows) in bands.into_iter().rev() {
            sink.put_rows((i * self.band) as u32, rows)?;
        }
        Ok(())
    }
    fn encode_to(&self, _: &HdrImage, _: &EncodeSettings, _: &mut dyn std::io::Write) -> Result<EncodeReport> {
        Err(hdrcodec::core::Error::unsupported("decodes only"))
    }
}

#[test]
fn rows_delivered_out_of_order_wait_within_the_limits() {
    let dir = temp_dir("order");
    let image = picture(40, 90, Channels::Rgb, ColorPrimaries::Bt709);
    let decoder = BackwardsDecoder { image: image.clone(), band: 16 };
    let registry = hdrcodec::registry();
    for name in ["pfm", "rgbe", "exr", "bc6h"] {
        let to = registry.by_name(name).unwrap();
        check_conversion(&decoder, &[], to.as_ref(), &EncodeSettings::default().with_effort(0), &dir);
    }
    // Every band but the first waits: a budget smaller than that is an error, and no file is left.
    let decoded = 40 * 90 * 3 * 4;
    let options = DecodeOptions::new(Limits::default().with_max_alloc_bytes(decoded / 2));
    let path = dir.join("small");
    let pfm = registry.by_name("pfm").unwrap();
    let r =
        hdrcodec::convert_file(&decoder, Input::Bytes(&[]), &options, pfm.as_ref(), &EncodeSettings::default(), &path);
    assert!(r.is_err(), "the early rows must not fit half the image's size");
    assert!(!path.exists(), "no file is left behind");
    assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().starts_with('.')));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_conversion_in_order_holds_bands_not_the_image() {
    // 9.4 MB decoded, a budget of a third of it: a PFM → RGBE/EXR/BC6H conversion only holds bands.
    let (w, h) = (1024u32, 768u32);
    let image = picture(w, h, Channels::Rgb, ColorPrimaries::Bt709);
    let registry = hdrcodec::registry();
    let pfm = registry.by_name("pfm").unwrap();
    let file = pfm.encode(&image, &EncodeSettings::default()).unwrap();
    let dir = temp_dir("budget");
    for name in ["pfm", "rgbe", "exr", "bc6h", "bc6h-ktx2", "hdrc"] {
        let limits = Limits::default().with_max_alloc_bytes(u64::from(w * h) * 12 / 3);
        let options = DecodeOptions::new(limits.clone());
        let to = registry.by_name(name).unwrap();
        let path = dir.join(name);
        let settings = EncodeSettings::default().with_effort(0);
        let settings = if name == "hdrc" { settings.with_option("tile", "128") } else { settings };
        hdrcodec::convert_file(pfm.as_ref(), Input::Bytes(&file), &options, to.as_ref(), &settings, &path)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(limits.peak() < u64::from(w * h) * 12 / 3, "{name}: peak {}", limits.peak());
        // The whole-image route does not fit that budget.
        assert!(pfm.decode_with(&file, &options).is_err());
    }
    // From files on disk that the decoder reads itself, a PFM and an untiled `.hdrc` as large as
    // the image: the budget, a third of the file, holds neither the file nor the image.
    let hdrc = registry.by_name("hdrc").unwrap();
    let inputs = [("in.pfm", file.clone()), ("in.hdrc", hdrc.encode(&image, &EncodeSettings::default()).unwrap())];
    for (input, bytes) in inputs {
        let input_path = dir.join(input);
        std::fs::write(&input_path, &bytes).unwrap();
        for name in ["rgbe", "exr", "hdrc"] {
            let limits = Limits::default().with_max_alloc_bytes(u64::from(w * h) * 12 / 3);
            let options = DecodeOptions::new(limits.clone());
            let (from, mut opened) = registry.open(&input_path).unwrap();
            let to = registry.by_name(name).unwrap();
            let settings = EncodeSettings::default().with_effort(0);
            let settings = if name == "hdrc" { settings.with_option("tile", "128") } else { settings };
            hdrcodec::convert_file(
                from.as_ref(),
                Input::File(&mut opened),
                &options,
                to.as_ref(),
                &settings,
                &dir.join(name),
            )
            .unwrap_or_else(|e| panic!("{input} -> {name}: {e}"));
            assert!(limits.peak() < u64::from(w * h) * 12 / 3, "{input} -> {name}: peak {}", limits.peak());
            // Reading the file whole does not fit that budget.
            assert!(hdrcodec::core::read_rest(&mut std::fs::File::open(&input_path).unwrap(), &limits).is_err());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
