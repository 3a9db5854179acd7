//! OpenEXR decode and encode speed in one run: ours (`hdrcodec-exr`, on one thread and on a
//! pool of two) against OpenEXR 3.1 itself in-process (the C++ library through
//! tests/peers/openexr_shim.cpp, built by tests/build.rs when Debian `libopenexr-dev` is
//! installed; `Imf::setGlobalThreadCount(0)` for one thread, 2 for two), the `exr` crate's own
//! reader and writer called directly (what our wrapper costs over it: `non_parallel()` for one
//! thread, its default parallel mode, a rayon pool of every core, for two), and OpenImageIO's
//! `oiiotool` out of process (`--threads 1` and `2`) on the large image only.
//!
//! Images: the corpus EXRs (decode only, their own compressions) and a 13 MP image, the
//! corpus's GoldenGate.exr mirrored into a 4x3 mosaic of 5048x2580 (half samples), written by
//! ours with each compression as half or float. By default: none, ZIP, PIZ and DWAA as half,
//! ZIP as float; with `HDRCODEC_EXR_BENCH_MATRIX=1` every compression `ExrEncodeOptions`
//! offers (none, RLE, ZIPS, ZIP, PIZ, PXR24, B44, B44A, DWAA, DWAB) × half and float.
//!
//! Decode: from the file in memory to interleaved f32 R, G, B(, A) (what `HdrImage` holds),
//! output allocated inside each call by every peer. oiiotool reads the file from disk (page
//! cache) and writes it to OIIO's `null` format; `exr_oiiotool/startup_1px_*` is oiiotool on a
//! 1-pixel file (written to a 1-pixel EXR: OIIO 2.4's null writer fails on small images).
//! Before timing, every peer's samples must equal ours bit for bit (half bit patterns equal;
//! oiiotool's through an uncompressed float file it writes).
//!
//! Encode: our f32 samples to a file in memory (OpenEXR's writer takes half samples for half
//! channels: the shim converts them, inside the timing, as ours does). oiiotool encodes from the
//! mosaic stored as an uncompressed float EXR on disk (`exr_oiiotool/read_none_float_*` is that
//! read alone, to null). Before timing, every peer's file is decoded (by ours): for a lossless
//! compression its samples must equal those of our file; for a lossy one (B44/B44A/DWA on half,
//! PXR24/DWA on float) both files must come within a mean relative error of 5% of the source
//! (DWAA at level 45 gives 1.2% on the mosaic, ours and OpenEXR alike). The file sizes are
//! printed.
//!
//! Run: `cargo bench -p hdrcodec-tests --bench exr` (about 10 minutes by default on two cores).
//! Criterion's throughput is in pixels (elements), so Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use hdrcodec_core::{DecodeOptions, HdrImage, Limits, ThreadPool};
use hdrcodec_exr::exr::prelude::{f16, ReadChannels, ReadLayers, ReadSpecificChannel, WritableImage};
use hdrcodec_exr::interop::{rgb_exr_image, rgba_exr_image};
use hdrcodec_exr::{decode_exr_with, encode_exr, ExrCompression, ExrEncodeOptions, ExrPixelType};
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_for, first_difference, missing, one_and_two_threads, run, tool};
use std::ffi::{OsStr, OsString};
use std::hint::black_box;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// OpenEXR through tests/peers/openexr_shim.cpp.
#[cfg(openexr)]
mod openexr {
    use std::os::raw::{c_char, c_int};

    extern "C" {
        fn openexr_shim_set_threads(threads: c_int);
        fn openexr_shim_info(
            data: *const u8,
            len: usize,
            width: *mut u32,
            height: *mut u32,
            alpha: *mut c_int,
            err: *mut c_char,
            err_len: usize,
        ) -> c_int;
        fn openexr_shim_decode(
            data: *const u8,
            len: usize,
            out: *mut f32,
            out_len: usize,
            channels: c_int,
            err: *mut c_char,
            err_len: usize,
        ) -> c_int;
        #[allow(clippy::too_many_arguments)]
        fn openexr_shim_encode(
            samples: *const f32,
            width: u32,
            height: u32,
            channels: c_int,
            compression: c_int,
            half: c_int,
            out: *mut u8,
            cap: usize,
            written: *mut usize,
            err: *mut c_char,
            err_len: usize,
        ) -> c_int;
    }

    fn message(err: &[u8]) -> String {
        let end = err.iter().position(|&b| b == 0).unwrap_or(err.len());
        format!("OpenEXR: {}", String::from_utf8_lossy(&err[..end]))
    }

    /// OpenEXR's global worker threads (0: the calling thread only).
    pub fn set_threads(threads: i32) {
        // SAFETY: sets a global of the library; no pointer is passed.
        unsafe { openexr_shim_set_threads(threads) }
    }

    /// The data window's width, height, and whether the file has an A channel.
    pub fn info(data: &[u8]) -> Result<(u32, u32, bool), String> {
        let (mut w, mut h, mut alpha) = (0u32, 0u32, 0 as c_int);
        let mut err = [0u8; 256];
        // SAFETY: `data` is valid for reads of `data.len()` bytes, the out-pointers point to live
        // locals and `err` to 256 writable bytes; the shim keeps no pointer after it returns.
        let rc = unsafe {
            openexr_shim_info(data.as_ptr(), data.len(), &mut w, &mut h, &mut alpha, err.as_mut_ptr().cast(), err.len())
        };
        if rc == 0 {
            Ok((w, h, alpha != 0))
        } else {
            Err(message(&err))
        }
    }

    /// Decodes R, G, B (and A when `channels` is 4) as interleaved f32, in a buffer allocated
    /// here for `pixels` pixels.
    pub fn decode(data: &[u8], pixels: usize, channels: usize) -> Result<Vec<f32>, String> {
        let mut out = vec![0f32; pixels * channels];
        let mut err = [0u8; 256];
        // SAFETY: `data` is valid for reads of `data.len()` bytes and `out` for writes of
        // `out.len()` floats; the shim refuses (before writing) an image larger than `out.len()`,
        // NUL-terminates `err` (256 bytes) and keeps no pointer after it returns.
        let rc = unsafe {
            openexr_shim_decode(
                data.as_ptr(),
                data.len(),
                out.as_mut_ptr(),
                out.len(),
                channels as c_int,
                err.as_mut_ptr().cast(),
                err.len(),
            )
        };
        if rc == 0 {
            Ok(out)
        } else {
            Err(message(&err))
        }
    }

    /// Encodes interleaved f32 samples as a scan-line file with OpenEXR compression id
    /// `compression`, half or float channels.
    pub fn encode(
        samples: &[f32],
        width: u32,
        height: u32,
        channels: usize,
        compression: usize,
        half: bool,
    ) -> Result<Vec<u8>, String> {
        assert_eq!(samples.len(), width as usize * height as usize * channels);
        // Room for the samples stored raw (at most 4 bytes each), the offset table and headers.
        let cap = samples.len() * 4 + height as usize * 8 + (1 << 16);
        let mut out = vec![0u8; cap];
        let mut written = 0usize;
        let mut err = [0u8; 256];
        // SAFETY: `samples` is valid for reads of width·height·channels floats (asserted above),
        // `out` for writes of `cap` bytes (the shim refuses to write past it), `written` is a
        // live local and `err` 256 writable bytes; the shim keeps no pointer after it returns.
        let rc = unsafe {
            openexr_shim_encode(
                samples.as_ptr(),
                width,
                height,
                channels as c_int,
                compression as c_int,
                c_int::from(half),
                out.as_mut_ptr(),
                cap,
                &mut written,
                err.as_mut_ptr().cast(),
                err.len(),
            )
        };
        if rc == 0 {
            out.truncate(written);
            Ok(out)
        } else {
            Err(message(&err))
        }
    }
}

/// Decodes `data` with the `exr` crate's own reader (the first layer's R, G, B and optional A,
/// largest level) into interleaved f32 of `channels` (3 or 4) per pixel.
fn exr_crate_decode(data: &[u8], channels: usize, parallel: bool) -> Vec<f32> {
    let reader = hdrcodec_exr::exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("R")
        .required("G")
        .required("B")
        .optional("A", 1.0f32)
        .collect_pixels(
            move |size, _| (size.width(), vec![0f32; size.area() * channels]),
            move |(width, samples): &mut (usize, Vec<f32>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
                let at = (pos.y() * *width + pos.x()) * channels;
                samples[at..at + 3].copy_from_slice(&[r, g, b]);
                if channels == 4 {
                    samples[at + 3] = a;
                }
            },
        )
        .first_valid_layer()
        .all_attributes();
    let image = if parallel {
        reader.from_buffered(Cursor::new(data))
    } else {
        reader.non_parallel().from_buffered(Cursor::new(data))
    };
    image.expect("the exr crate's decode").layer_data.channel_data.pixels.1
}

/// Writes an `exr` image with the `exr` crate's writer, in parallel or not, to a file in memory.
macro_rules! write_with_exr_crate {
    ($image:expr, $parallel:expr) => {{
        let image = $image;
        let mut out = Cursor::new(Vec::new());
        let writer = image.write();
        if $parallel { writer.to_buffered(&mut out) } else { writer.non_parallel().to_buffered(&mut out) }
            .expect("the exr crate's encode");
        out.into_inner()
    }};
}

/// Encodes `img` with the `exr` crate's own writer (through our zero-copy `interop` pixel
/// adapters, which read the samples as the writer asks), scan lines as ours writes them.
fn exr_crate_encode(img: &HdrImage, options: &ExrEncodeOptions, parallel: bool) -> Vec<u8> {
    let c = options.compression;
    match (img.channels().count(), options.pixel) {
        (3, ExrPixelType::Half) => write_with_exr_crate!(rgb_exr_image::<f16>(img, c), parallel),
        (3, ExrPixelType::Float) => write_with_exr_crate!(rgb_exr_image::<f32>(img, c), parallel),
        (_, ExrPixelType::Half) => write_with_exr_crate!(rgba_exr_image::<f16>(img, c), parallel),
        (_, ExrPixelType::Float) => write_with_exr_crate!(rgba_exr_image::<f32>(img, c), parallel),
    }
}

/// The large files: every compression × pixel type under `HDRCODEC_EXR_BENCH_MATRIX=1`, else
/// the default few (see the top of this file).
fn configurations() -> Vec<ExrEncodeOptions> {
    let opts = |compression, pixel| ExrEncodeOptions { compression, pixel };
    if std::env::var("HDRCODEC_EXR_BENCH_MATRIX").is_ok_and(|v| v == "1") {
        let pixels = [ExrPixelType::Half, ExrPixelType::Float];
        return pixels.iter().flat_map(|&p| ExrCompression::ALL.map(|c| opts(c, p))).collect();
    }
    let half = [ExrCompression::None, ExrCompression::Zip16, ExrCompression::Piz, ExrCompression::Dwaa];
    let mut v: Vec<_> = half.iter().map(|&c| opts(c, ExrPixelType::Half)).collect();
    v.push(opts(ExrCompression::Zip16, ExrPixelType::Float));
    v
}

fn pixel_name(pixel: ExrPixelType) -> &'static str {
    match pixel {
        ExrPixelType::Half => "half",
        ExrPixelType::Float => "float",
    }
}

/// The mean of |a − s| / (|s| + 0.01) over the samples where the source `s` is finite.
fn mean_relative_error(a: &[f32], source: &[f32]) -> f64 {
    let (sum, n) = a.iter().zip(source).filter(|(_, s)| s.is_finite()).fold((0f64, 0usize), |(sum, n), (&a, &s)| {
        (sum + f64::from((a - s).abs()) / (f64::from(s.abs()) + 0.01), n + 1)
    });
    sum / n.max(1) as f64
}

fn assert_same(what: &str, ours: &[f32], theirs: &[f32]) {
    if let Some(i) = first_difference(ours, theirs) {
        panic!("{what}: differs from ours at sample {i} (ours {:?}, theirs {:?})", ours.get(i), theirs.get(i));
    }
}

/// What every decode and encode row needs.
struct Setup {
    one: DecodeOptions,
    two: DecodeOptions,
    oiiotool: Option<PathBuf>,
    tmp: PathBuf,
}

type Group<'a> = criterion::BenchmarkGroup<'a, criterion::measurement::WallTime>;

fn group<'a>(c: &'a mut Criterion, name: String, pixels: u64) -> Group<'a> {
    let mut g = c.benchmark_group(name);
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2))
        .throughput(Throughput::Elements(pixels));
    g
}

/// Checks every decoder against ours on `data` (also at `path` on disk for oiiotool, the large
/// files only), then times them.
fn decode_rows(c: &mut Criterion, s: &Setup, name: &str, data: &[u8], path: Option<&Path>) {
    let ours = decode_exr_with(data, &s.one).unwrap_or_else(|e| panic!("{name}: our decode: {e}"));
    let ch = ours.channels().count();
    let pixels = ours.width() as usize * ours.height() as usize;
    let on_two = decode_exr_with(data, &s.two).expect("our decode on two threads");
    assert_same(&format!("{name}: ours on two threads"), ours.samples(), on_two.samples());
    for parallel in [false, true] {
        assert_same(&format!("{name}: the exr crate"), ours.samples(), &exr_crate_decode(data, ch, parallel));
    }
    #[cfg(openexr)]
    for threads in [0, 2] {
        openexr::set_threads(threads);
        let (w, h, _) = openexr::info(data).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((w, h), (ours.width(), ours.height()), "{name}: OpenEXR's size");
        let theirs = openexr::decode(data, pixels, ch).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_same(&format!("{name}: OpenEXR, {threads} threads"), ours.samples(), &theirs);
    }
    let oiio = path.zip(s.oiiotool.as_deref());
    if let Some((path, oiiotool)) = oiio {
        let back = s.tmp.join("oiiotool_decoded.exr");
        let args = ["--threads", "1"].map(OsStr::new);
        let rest = ["-d", "float", "--compression", "none", "-o"].map(OsStr::new);
        run(oiiotool, &[&args[..], &[path.as_os_str()], &rest[..], &[back.as_os_str()]].concat());
        let theirs = hdrcodec_exr::decode_exr(&std::fs::read(&back).unwrap(), &Limits::default()).unwrap();
        assert_same(&format!("{name}: oiiotool"), ours.samples(), theirs.samples());
    }
    drop((ours, on_two));

    let mut g = group(c, format!("exr_decode/{name}"), pixels as u64);
    g.bench_function("hdrcodec_1thread", |b| b.iter(|| decode_exr_with(black_box(data), &s.one).unwrap()));
    g.bench_function("hdrcodec_2threads", |b| b.iter(|| decode_exr_with(black_box(data), &s.two).unwrap()));
    g.bench_function("exr_crate_1thread", |b| b.iter(|| exr_crate_decode(black_box(data), ch, false)));
    g.bench_function("exr_crate_parallel", |b| b.iter(|| exr_crate_decode(black_box(data), ch, true)));
    #[cfg(openexr)]
    for (label, threads) in [("openexr_1thread", 0), ("openexr_2threads", 2)] {
        g.bench_function(label, |b| {
            openexr::set_threads(threads);
            b.iter(|| openexr::decode(black_box(data), pixels, ch).unwrap())
        });
    }
    if let Some((path, oiiotool)) = oiio {
        let null = s.tmp.join("out.null");
        for (label, threads) in [("oiiotool_1thread", "1"), ("oiiotool_2threads", "2")] {
            let args =
                [OsStr::new("--threads"), OsStr::new(threads), path.as_os_str(), OsStr::new("-o"), null.as_os_str()];
            g.bench_function(label, |b| b.iter(|| run(oiiotool, &args)));
        }
    }
    g.finish();
}

/// Checks every encoder's file against ours (see the top of this file), then times them.
fn encode_rows(c: &mut Criterion, s: &Setup, name: &str, img: &HdrImage, options: &ExrEncodeOptions, src: &Path) {
    let single = ThreadPool::single();
    let pool = ThreadPool::new(2).expect("a pool of two threads");
    let (w, h) = (img.width(), img.height());
    let half = options.pixel == ExrPixelType::Half;
    let (compression, pixel) = (options.compression.name(), pixel_name(options.pixel));
    // OpenEXR's compression id: `ALL` is in the order of the ids.
    #[cfg(openexr)]
    let (ch, id) = (
        img.channels().count(),
        ExrCompression::ALL.iter().position(|&c| c == options.compression).expect("a compression"),
    );
    let lossless =
        if half { options.compression.is_lossless_for_half() } else { options.compression.is_lossless_for_float() };
    let ours_file = encode_exr(img, options, &single).unwrap();
    assert_eq!(encode_exr(img, options, &pool).unwrap(), ours_file, "{name}: ours on two threads");
    let decode = |file: &[u8]| hdrcodec_exr::decode_exr(file, &Limits::default()).expect("decode a peer's file");
    let ours = decode(&ours_file);
    let mut files = vec![("exr crate", exr_crate_encode(img, options, false))];
    #[cfg(openexr)]
    {
        openexr::set_threads(0);
        files.push((
            "OpenEXR",
            openexr::encode(img.samples(), w, h, ch, id, half).unwrap_or_else(|e| panic!("{name}: {e}")),
        ));
    }
    let oiio_out = s.tmp.join("oiiotool_encoded.exr");
    let oiio_args = |threads: &str| -> Vec<OsString> {
        let mut args: Vec<OsString> = vec!["--threads".into(), threads.into(), "--nosoftwareattrib".into(), src.into()];
        args.extend(["--compression", compression, "-d", pixel, "-o"].map(OsString::from));
        args.push(oiio_out.clone().into());
        args
    };
    if let Some(oiiotool) = &s.oiiotool {
        run(oiiotool, &oiio_args("1"));
        files.push(("oiiotool", std::fs::read(&oiio_out).unwrap()));
    }
    let mut sizes = format!("ours {}", ours_file.len());
    for (peer, file) in &files {
        let theirs = decode(file);
        assert_eq!((theirs.width(), theirs.height()), (w, h), "{name}: {peer}'s size");
        if lossless {
            assert_same(&format!("{name}: {peer}'s file"), ours.samples(), theirs.samples());
        } else {
            let (e_ours, e_theirs) = (
                mean_relative_error(ours.samples(), img.samples()),
                mean_relative_error(theirs.samples(), img.samples()),
            );
            eprintln!("exr bench: {name}: mean relative error of ours {e_ours:.5}, {peer} {e_theirs:.5}");
            assert!(e_ours < 0.05 && e_theirs < 0.05, "{name}: {peer}'s lossy file or ours is too far from the source");
        }
        sizes += &format!(", {peer} {}", file.len());
    }
    eprintln!("exr bench: {name}: file sizes in bytes: {sizes}");
    drop((ours_file, ours, files));

    let mut g = group(c, format!("exr_encode/{name}"), u64::from(w) * u64::from(h));
    g.bench_function("hdrcodec_1thread", |b| b.iter(|| encode_exr(black_box(img), options, &single).unwrap()));
    g.bench_function("hdrcodec_2threads", |b| b.iter(|| encode_exr(black_box(img), options, &pool).unwrap()));
    g.bench_function("exr_crate_1thread", |b| b.iter(|| exr_crate_encode(black_box(img), options, false)));
    g.bench_function("exr_crate_parallel", |b| b.iter(|| exr_crate_encode(black_box(img), options, true)));
    #[cfg(openexr)]
    for (label, threads) in [("openexr_1thread", 0), ("openexr_2threads", 2)] {
        g.bench_function(label, |b| {
            openexr::set_threads(threads);
            b.iter(|| openexr::encode(black_box(img.samples()), w, h, ch, id, half).unwrap())
        });
    }
    if let Some(oiiotool) = &s.oiiotool {
        for (label, threads) in [("oiiotool_1thread", "1"), ("oiiotool_2threads", "2")] {
            let args = oiio_args(threads);
            g.bench_function(label, |b| b.iter(|| run(oiiotool, &args)));
        }
    }
    g.finish();
}

fn bench(c: &mut Criterion) {
    let Some(dir) = corpus_for("exr") else { return };
    #[cfg(not(openexr))]
    missing("exr", "OpenEXR (Debian libopenexr-dev; tests/build.rs builds the shim only if it is installed)");
    let oiiotool = tool("oiiotool");
    if oiiotool.is_none() {
        missing("exr", "oiiotool (Debian openimageio-tools)");
    }
    let (one, two) = one_and_two_threads();
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("exr_bench");
    std::fs::create_dir_all(&tmp).expect("create the bench's temp dir");
    let s = Setup { one, two, oiiotool, tmp };

    let mut corpus: Vec<PathBuf> = std::fs::read_dir(dir.join("exr"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    corpus.retain(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")));
    corpus.sort();
    for path in &corpus {
        let data = std::fs::read(path).expect("read a corpus EXR");
        decode_rows(c, &s, &path.file_stem().unwrap().to_string_lossy(), &data, None);
    }

    let img = common::golden_gate_exr_mosaic(&dir);
    let (w, h) = (img.width(), img.height());
    // oiiotool's encode input, and its start-up on a 1-pixel file.
    let none_float = ExrEncodeOptions { compression: ExrCompression::None, pixel: ExrPixelType::Float };
    let src = s.tmp.join("mosaic_none_float.exr");
    std::fs::write(&src, encode_exr(&img, &none_float, &ThreadPool::single()).unwrap()).expect("write the mosaic");
    if let Some(oiiotool) = &s.oiiotool {
        let one_px =
            HdrImage::new(1, 1, img.channels(), img.samples()[..img.channels().count()].to_vec(), img.color.clone())
                .unwrap();
        let one_px_path = s.tmp.join("1px.exr");
        std::fs::write(&one_px_path, encode_exr(&one_px, &none_float, &ThreadPool::single()).unwrap()).unwrap();
        let null = s.tmp.join("out.null");
        let mut g = group(c, "exr_oiiotool".into(), u64::from(w) * u64::from(h));
        for threads in ["1", "2"] {
            let args = |input: &Path, output: &Path| -> Vec<OsString> {
                vec!["--threads".into(), threads.into(), input.into(), "-o".into(), output.into()]
            };
            // OIIO 2.4's null writer fails on small images (64x64 does; 13 MP works): the
            // 1-pixel start-up writes an EXR of one pixel instead.
            let (startup, read) = (args(&one_px_path, &s.tmp.join("1px_out.exr")), args(&src, &null));
            g.throughput(Throughput::Elements(1));
            g.bench_function(format!("startup_1px_{threads}thread"), |b| b.iter(|| run(oiiotool, &startup)));
            g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
            g.bench_function(format!("read_none_float_{threads}thread"), |b| b.iter(|| run(oiiotool, &read)));
        }
        g.finish();
    }
    for options in configurations() {
        let name = format!("GoldenGate_mosaic_{w}x{h}_{}_{}", options.compression.name(), pixel_name(options.pixel));
        let data = encode_exr(&img, &options, &ThreadPool::single()).expect("our encode");
        let path = s.tmp.join(format!("{name}.exr"));
        std::fs::write(&path, &data).expect("write a large file");
        decode_rows(c, &s, &name, &data, Some(&path));
        encode_rows(c, &s, &name, &img, &options, &src);
        std::fs::remove_file(&path).ok();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
