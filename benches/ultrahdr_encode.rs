//! HDR JPEG encode speed in one run.
//!
//! - Gain-map JPEG (`ultrahdr` group): our encoder (`GainMapJpegCodec`, through the trait, at its
//!   default quality 90 and at the sweep point 70) against libultrahdr 1.4's, called in-process
//!   through tests/peers/libultrahdr_shim.c (`uhdr_shim_encode`: the library of the reference
//!   venv's imagecodecs wheel; tests/build.rs links it when it finds it) with the settings of
//!   `hdrcodec bench`'s libultrahdr rows (imagecodecs' `ultrahdr_encode`: the best-quality
//!   preset, the same quality for base and map, a full-size map, the linear half-float RGBA HDR
//!   intent alone, libultrahdr tone-mapping its own SDR base). Each call is one whole encode
//!   from samples in memory to the file in memory. libultrahdr's input is converted to half
//!   RGBA before timing (the conversion is not in its time); ours reads the f32 image.
//! - JPEG-HDR (Ward & Simmons, `jpeg_hdr` group): our encoder (`JpegHdrCodec`, quality 90) and
//!   our decoder of its file. No other implementation exists as a library (the format's author's
//!   panlib is a source tree, not a package: the crate README's panlib section), so there is no
//!   peer row; the gain-map rows above are the closest comparison.
//!
//! Images: the HDR rendition of the corpus's sky_ultrahdr.jpg (our decode: 4080x3072 = 12.5 MP,
//! Display P3) and exr/StillLife.exr (1240x846 = 1.05 MP, BT.709). Before timing, each encoder's
//! file (ours and libultrahdr's) is decoded by our decoder and must agree with the source image:
//! PU21-PSNR (core's metrics, luminance) at least [`MIN_PU21_PSNR`] dB; the figures are printed.
//!
//! Threads: libultrahdr 1.4 computes and encodes the map on `std::thread`s of its own (as many
//! as `hardware_concurrency`), our encoders run on the calling thread (neither takes a pool), so
//! the like-for-like comparison pins the whole bench to one CPU:
//! `taskset -c 0 cargo bench -p hdrcodec-tests --bench ultrahdr_encode`; unpinned, libultrahdr
//! uses both cores and ours still one. Criterion's throughput is in pixels: Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
use hdrcodec_core::{metrics, ColorPrimaries, DecodeOptions, EncodeSettings, HdrImage, ImageCodec, Limits};
use hdrcodec_jpeghdr::{GainMapJpegCodec, JpegHdrCodec};
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_dir, missing};
use std::hint::black_box;

#[cfg(libultrahdr)]
#[path = "libultrahdr.rs"]
#[allow(dead_code)] // the decoder
mod libultrahdr;

/// The least PU21-PSNR (dB) of an encoder's file, decoded by our decoder, against the source.
/// Both encoders are far above it at these qualities (the run prints the figures); it catches a
/// wrong image (a swapped gamut, a wrong scale, a broken file), not a small loss.
const MIN_PU21_PSNR: f64 = 30.0;

/// The qualities timed: our default and one sweep point.
const QUALITIES: [u8; 2] = [90, 70];

/// The two source images: name and linear image.
fn images() -> Option<Vec<(&'static str, HdrImage)>> {
    let Some(dir) = corpus_dir() else {
        missing("ultrahdr_encode", "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
        return None;
    };
    let sky = std::fs::read(dir.join("jpeg/sky_ultrahdr.jpg")).expect("read sky_ultrahdr.jpg");
    let sky = GainMapJpegCodec.decode_with(&sky, &DecodeOptions::new(Limits::default())).expect("decode the sky");
    let (_, mut still) =
        hdrcodec::registry().read(&dir.join("exr/StillLife.exr"), &Limits::default()).expect("read StillLife.exr");
    if !still.color.primaries.is_specified() {
        // OpenEXR without chromaticities means BT.709 (Rec. ITU-R BT.709, the format's default).
        still.color.primaries = ColorPrimaries::Bt709;
    }
    Some(vec![("sky_ultrahdr.jpg (HDR rendition)", sky), ("StillLife.exr", still)])
}

/// Our decode of `file` against `source`: PU21-PSNR (dB), asserted above [`MIN_PU21_PSNR`].
fn check(source: &HdrImage, file: &[u8], who: &str) -> f64 {
    let back = GainMapJpegCodec.decode_with(file, &DecodeOptions::new(Limits::default())).expect("decode a file");
    let psnr = metrics::compare(source, &back).expect("compare").pu21_psnr;
    assert!(psnr >= MIN_PU21_PSNR, "{who}: its file decodes {psnr:.1} dB from the source (< {MIN_PU21_PSNR})");
    psnr
}

fn gain_map(c: &mut Criterion, images: &[(&str, HdrImage)]) {
    #[cfg(not(libultrahdr))]
    missing("ultrahdr_encode", "libultrahdr 1.4 (imagecodecs in the reference venv; tests/build.rs links it if found)");
    let mut group = c.benchmark_group("ultrahdr_encode");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for (name, image) in images {
        let (w, h) = (image.width(), image.height());
        group.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
        #[cfg(libultrahdr)]
        let rgba: Vec<u16> = {
            let (bytes, clipped) = hdrcodec_cli::libultrahdr::linear_half_rgba(image);
            if clipped > 0 {
                eprintln!("ultrahdr_encode bench: {name}: {clipped} samples clipped to half's range for libultrahdr");
            }
            bytes.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect()
        };
        for q in QUALITIES {
            let settings = EncodeSettings::default().with_quality(q);
            let ours = GainMapJpegCodec.encode(image, &settings).expect("our encode");
            let psnr = check(image, &ours, "hdrcodec");
            eprintln!("ultrahdr_encode bench: {name} ({w}x{h}) q{q}: hdrcodec {} bytes, {psnr:.2} dB", ours.len());
            #[cfg(libultrahdr)]
            {
                let gamut = hdrcodec_cli::libultrahdr::gamut(image.color.primaries).expect("a gamut libultrahdr takes");
                let s = libultrahdr::EncodeSettings { gamut, quality: q, scale: 1 };
                let mut out = vec![0u8; ours.len() * 2];
                let len = libultrahdr::encode(&rgba, (w, h), s, &mut out).unwrap_or_else(|e| panic!("{name}: {e}"));
                let psnr = check(image, &out[..len], "libultrahdr");
                eprintln!("ultrahdr_encode bench: {name} ({w}x{h}) q{q}: libultrahdr {len} bytes, {psnr:.2} dB");
                group.bench_function(BenchmarkId::new(format!("libultrahdr_q{q}"), name), |b| {
                    b.iter(|| libultrahdr::encode(black_box(&rgba), (w, h), s, &mut out).unwrap())
                });
            }
            group.bench_function(BenchmarkId::new(format!("hdrcodec_q{q}"), name), |b| {
                b.iter(|| GainMapJpegCodec.encode(black_box(image), &settings).unwrap())
            });
        }
    }
    group.finish();
}

fn jpeg_hdr(c: &mut Criterion, images: &[(&str, HdrImage)]) {
    eprintln!("ultrahdr_encode bench: JPEG-HDR has no peer (no other implementation exists as a library); ours alone");
    let mut group = c.benchmark_group("jpeg_hdr");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    let options = DecodeOptions::new(Limits::default());
    for (name, image) in images {
        let (w, h) = (image.width(), image.height());
        group.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
        let settings = EncodeSettings::default().with_quality(90);
        let file = JpegHdrCodec.encode(image, &settings).expect("our JPEG-HDR encode");
        let psnr = check(image, &file, "hdrcodec jpeg-hdr");
        eprintln!("ultrahdr_encode bench: {name} ({w}x{h}) jpeg-hdr q90: {} bytes, {psnr:.2} dB", file.len());
        group.bench_function(BenchmarkId::new("hdrcodec_encode_q90", name), |b| {
            b.iter(|| JpegHdrCodec.encode(black_box(image), &settings).unwrap())
        });
        group.bench_function(BenchmarkId::new("hdrcodec_decode_q90", name), |b| {
            b.iter(|| JpegHdrCodec.decode_with(black_box(&file), &options).unwrap())
        });
    }
    group.finish();
}

fn bench(c: &mut Criterion) {
    let Some(images) = images() else { return };
    gain_map(c, &images);
    jpeg_hdr(c, &images);
}

criterion_group!(benches, bench);
criterion_main!(benches);
