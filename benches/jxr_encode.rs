//! JPEG XR encode speed in one run: our encoder (`hdrcodec_jxr::encoder::encode`) against
//! jxrlib, the reference codec, called in-process through a small C shim over Debian
//! `libjxr-dev` (`jxrlib_shim_encode` in tests/peers/jxrlib_shim.c, built by tests/build.rs).
//!
//! Input: the GoldenGate corpus image (our decode of GoldenGate_48bppRGBHalf_lossless.jxr,
//! half floats), 1262x860; with `HDRCODEC_JXR_BENCH_MATRIX=1` also mirrored into a 4x3 mosaic
//! of 5048x2580 (13 MP), as benches/jxr_decode.rs makes it. Both sides write 48bppRGBHalf.
//! Each side is given the samples it takes and its timing includes its own conversion from
//! them: ours an `HdrImage` of f32 (what `encode` takes), made once outside the timing;
//! jxrlib the half floats in memory (rows packed), encoding into a memory stream over a buffer
//! allocated once outside the timing.
//!
//! Settings. jxrlib: JxrEncApp's for `-q` 1.0 (lossless), 0.9, 0.6 and 0.3: its QP tables
//! for half floats (six indices: Y, U, V for DC and LP, Y, U, V for HP), 4:4:4, overlap 1 (2
//! below 0.5), FREQUENCY bitstream order with progressive mode (JxrEncApp's default), one
//! tile. Ours at **equal settings** (`hdrcodec_1thread`, `hdrcodec_2threads`): the quantizers
//! read back from jxrlib's file (`Quantizers::of_file`: per band and channel), the same
//! overlap, FREQUENCY order, one quantizer set for every macroblock (`adaptive: false`, as
//! jxrlib), half format, 4:4:4, every band, one tile; the files are then about jxrlib's size
//! (printed in the setup with both files' PU21-PSNR against the input). Ours at our own
//! **quality** scale (`hdrcodec_1thread_quality`): quality 100 / 90 / 60 / 30 with the same
//! overlap and `adaptive: false`, SPATIAL order (our default); its quantizers are not
//! jxrlib's (ours: luma 0 / 10 / 52 / 94 for every band, chroma 24 more for DC and LP and 32
//! more for HP; jxrlib's at 0.3: 97, 118, 120 and HP 109, 137, 144), so those files are not
//! the same size as jxrlib's and those rows do not compare equal settings.
//!
//! Before timing, for every input and quality: our decoder must decode jxrlib's in-process
//! file (lossless: to the input's bits), and that file must be within 1% of the size JxrEncApp
//! (Debian `libjxr-tools`) gives for the same image as a TIFF and `-q` (the bench says whether
//! the codestreams are byte-identical: the file ends with its codestream).
//!
//! jxrlib is single-threaded: `jxrlib_1thread` and `hdrcodec_1thread` are the like-for-like
//! pair; `hdrcodec_2threads` is ours on a pool of two threads with tiles (64x64 macroblocks,
//! 5x3 tiles, on the mosaic; one tile, so no parallel entropy coding, on the small image).
//! Criterion's throughput is in pixels (elements), so Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
#[cfg(jxrlib)]
use hdrcodec_core::{metrics::pu21_psnr, ImageCodec};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, DecodeOptions, HdrImage, Limits, ThreadPool};
use hdrcodec_jxr::decode_raw;
use hdrcodec_jxr::encoder::{encode, BitstreamOrder, EncodeOptions, SampleFormat};
use hdrcodec_jxr::transform::OverlapMode;
#[cfg(jxrlib)]
use hdrcodec_jxr::{encoder::Quantizers, JxrCodec};
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
#[cfg(jxrlib)]
use common::tool;
use common::{corpus_dir, missing};
use std::hint::black_box;

/// The qualities: name, jxrlib's `-q` (1.0 = lossless), ours, the overlap jxrlib uses.
const QUALITIES: [(&str, f32, u8, OverlapMode); 4] = [
    ("lossless", 1.0, 100, OverlapMode::One),
    ("q0.9", 0.9, 90, OverlapMode::One),
    ("q0.6", 0.6, 60, OverlapMode::One),
    ("q0.3", 0.3, 30, OverlapMode::Two),
];

/// jxrlib through tests/peers/jxrlib_shim.c.
#[cfg(jxrlib)]
mod jxrlib {
    use std::os::raw::{c_float, c_int};

    extern "C" {
        #[allow(clippy::too_many_arguments)]
        fn jxrlib_shim_encode(
            pixels: *const u8,
            stride: usize,
            width: u32,
            height: u32,
            format: c_int,
            quality: c_float,
            overlap: c_int,
            out: *mut u8,
            out_cap: usize,
            out_len: *mut usize,
        ) -> c_int;
    }

    /// Encodes 48bppRGBHalf pixels (rows packed) with JxrEncApp's settings for `quality` and
    /// its overlap for it into `out`; the file's length.
    pub fn encode_half(pixels: &[u8], width: u32, height: u32, quality: f32, out: &mut [u8]) -> Result<usize, i32> {
        let stride = width as usize * 6;
        assert_eq!(pixels.len(), stride * height as usize);
        let mut len = 0usize;
        // SAFETY: `pixels` is valid for reads of `stride * height` bytes (asserted) and only
        // read; `out` is valid for writes of `out.len()` bytes, which the memory stream never
        // writes past (it fails instead); `len` is a live local. The shim keeps no pointer
        // after it returns.
        let err = unsafe {
            jxrlib_shim_encode(
                pixels.as_ptr(),
                stride,
                width,
                height,
                0,
                quality,
                -1,
                out.as_mut_ptr(),
                out.len(),
                &mut len,
            )
        };
        if err == 0 {
            Ok(len)
        } else {
            Err(err)
        }
    }
}

/// An input: half-float pixels (rows packed, what jxrlib is given), the same as an f32 image
/// (what we are given), and the tile size of our two-thread encode.
struct Input {
    name: String,
    width: u32,
    height: u32,
    half: Vec<u8>,
    image: HdrImage,
    tile_mbs: usize,
}

impl Input {
    fn new(name: String, width: u32, height: u32, half: Vec<u8>, tile_mbs: usize) -> Self {
        let samples: Vec<f32> =
            half.chunks_exact(2).map(|b| half::f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32()).collect();
        // scRGB: 1.0 is 80 cd/m², so our encoder writes the half floats unchanged.
        let color = ColorInfo {
            primaries: ColorPrimaries::Bt709,
            nits_per_unit: hdrcodec_jxr::output::NITS_PER_UNIT,
            hdr10: None,
        };
        let image = HdrImage::new(width, height, Channels::Rgb, samples, color).expect("an RGB image");
        Input { name, width, height, half, image, tile_mbs }
    }
}

fn inputs() -> Vec<Input> {
    let Some(dir) = corpus_dir() else {
        missing("jxr_encode", "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
        return Vec::new();
    };
    let data = std::fs::read(dir.join("jxr/GoldenGate_48bppRGBHalf_lossless.jxr")).expect("read GoldenGate");
    let (w, h, raw) = common::golden_gate_half(&data);
    let mut inputs = Vec::new();
    if std::env::var("HDRCODEC_JXR_BENCH_MATRIX").is_ok_and(|v| v == "1") {
        let (big_w, big_h, half) = common::mosaic(&raw, w, h);
        let name = format!("GoldenGate_mosaic_{big_w}x{big_h}");
        // 316x162 macroblocks in tiles of 64: 5x3 tiles.
        inputs.insert(0, Input::new(name, big_w as u32, big_h as u32, half, 64));
    }
    inputs.insert(0, Input::new(format!("GoldenGate_{w}x{h}"), w as u32, h as u32, raw, 0));
    inputs
}

/// JxrEncApp's file for `input` at `-q quality` (from a TIFF of its half floats), or `None`
/// without JxrEncApp.
#[cfg(jxrlib)]
fn jxrencapp(input: &Input, quality: f32) -> Option<Vec<u8>> {
    use std::process::Command;
    let enc = tool("JxrEncApp")?;
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("jxr_encode_bench");
    std::fs::create_dir_all(&dir).expect("create the bench's temp dir");
    let tif = dir.join(format!("{}.tif", input.name));
    if !tif.is_file() {
        let bytes = hdrcodec_cli::jxrlib::float_rgb_tiff(input.width, input.height, 16, &input.half).expect("a TIFF");
        std::fs::write(&tif, bytes).expect("write the TIFF");
    }
    let jxr = dir.join(format!("{}_{quality}.jxr", input.name));
    let mut cmd = Command::new(enc);
    cmd.arg("-i").arg(&tif).arg("-o").arg(&jxr).args(["-c", "12"]);
    if quality < 1.0 {
        cmd.args(["-q", &quality.to_string()]);
    }
    let out = cmd.output().expect("run JxrEncApp");
    assert!(out.status.success() && jxr.is_file(), "JxrEncApp failed: {}", String::from_utf8_lossy(&out.stderr));
    let data = std::fs::read(&jxr).expect("read JxrEncApp's file");
    let _ = std::fs::remove_file(&jxr);
    Some(data)
}

fn bench(c: &mut Criterion) {
    let inputs = inputs();
    #[cfg(not(jxrlib))]
    missing("jxr_encode", "jxrlib (Debian libjxr-dev; tests/build.rs builds the shim only if it is installed)");
    #[cfg(jxrlib)]
    if tool("JxrEncApp").is_none() {
        missing(
            "jxr_encode",
            "JxrEncApp (Debian libjxr-tools), against whose file sizes the in-process encoder is checked",
        );
    }

    let single = ThreadPool::single();
    let two = ThreadPool::new(2).expect("a pool of two threads");
    let decode_opts = DecodeOptions::new(Limits::default());
    let mut group = c.benchmark_group("jxr_encode");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for input in &inputs {
        group.throughput(Throughput::Elements(u64::from(input.width) * u64::from(input.height)));
        for &(qname, jxr_q, our_q, overlap) in &QUALITIES {
            let id = format!("{}_{qname}", input.name);
            // At our own quality scale (not jxrlib's quantizers).
            let opts = EncodeOptions {
                quality: our_q,
                overlap: Some(overlap),
                format: SampleFormat::Half,
                tile_mbs: 0,
                adaptive: false,
                ..EncodeOptions::default()
            };
            // Checked before timing, since criterion's --list runs no iterations.
            let (ours, _) = encode(&input.image, &opts, &single).expect("our encode");
            let ours_raw = decode_raw(&ours, &decode_opts).expect("our decode of our file");
            if our_q == 100 {
                assert!(ours_raw == input.half, "{id}: our lossless file gives back the input");
            }
            #[cfg(jxrlib)]
            {
                let mut out = vec![0u8; input.half.len() * 2 + (1 << 16)];
                let len = jxrlib::encode_half(&input.half, input.width, input.height, jxr_q, &mut out)
                    .unwrap_or_else(|e| panic!("{id}: jxrlib error {e}"));
                let theirs = &out[..len];
                let theirs_raw = decode_raw(theirs, &decode_opts)
                    .unwrap_or_else(|e| panic!("{id}: our decoder fails on jxrlib's in-process file: {e}"));
                assert_eq!(theirs_raw.len(), input.half.len(), "{id}: jxrlib's file decodes to the input's size");
                if jxr_q >= 1.0 {
                    assert!(theirs_raw == input.half, "{id}: jxrlib's lossless file gives back the input");
                }
                // Equal settings: jxrlib's quantizers, overlap and bitstream order.
                let quantizers = Quantizers::of_file(theirs)
                    .expect("jxrlib's file parses")
                    .unwrap_or_else(|| panic!("{id}: jxrlib's file has one quantizer set per band"));
                let equal =
                    EncodeOptions { quantizers: Some(quantizers), order: BitstreamOrder::Frequency, ..opts.clone() };
                let tiled = EncodeOptions { tile_mbs: input.tile_mbs, ..equal.clone() };
                let (ours_equal, _) = encode(&input.image, &equal, &single).expect("our encode at equal settings");
                assert_eq!(Quantizers::of_file(&ours_equal).unwrap(), Some(quantizers), "{id}: the same quantizers");
                let (ours_tiled, _) = encode(&input.image, &tiled, &two).expect("our tiled encode");
                let ours_equal_raw = decode_raw(&ours_equal, &decode_opts).expect("our decode of our file");
                if jxr_q >= 1.0 {
                    assert!(ours_equal_raw == input.half, "{id}: our lossless file gives back the input");
                }
                assert_eq!(
                    decode_raw(&ours_tiled, &decode_opts).expect("our tiled file decodes").len(),
                    ours_raw.len()
                );
                // PU21-PSNR against the input, each file decoded by our decoder (which gives
                // jxrlib's samples: tests/jxr_reference.rs).
                let psnr = |file: &[u8]| {
                    let decoded = JxrCodec.decode(file, &Limits::default()).expect("our decoder");
                    pu21_psnr(&input.image, &decoded).expect("PU21-PSNR")
                };
                let mut line = format!(
                    "jxr_encode bench: {id}: jxrlib in-process {len} bytes ({:.2} dB PU21-PSNR); ours at equal \
                     settings {} bytes ({:+.2}%, {:.2} dB; quantizers {quantizers:?}; tiled {} bytes); ours at \
                     quality {our_q} {} bytes ({:.2} dB)",
                    psnr(theirs),
                    ours_equal.len(),
                    100.0 * (ours_equal.len() as f64 / len as f64 - 1.0),
                    psnr(&ours_equal),
                    ours_tiled.len(),
                    ours.len(),
                    psnr(&ours),
                );
                if let Some(app) = jxrencapp(input, jxr_q) {
                    let common = theirs.iter().rev().zip(app.iter().rev()).take_while(|(a, b)| a == b).count();
                    let ratio = len as f64 / app.len() as f64;
                    line += &format!(
                        ", JxrEncApp {} bytes ({:+.3}%), {}",
                        app.len(),
                        100.0 * (ratio - 1.0),
                        if theirs == app.as_slice() {
                            "files byte-identical".to_string()
                        } else {
                            format!("last {common} bytes identical")
                        }
                    );
                    assert!((ratio - 1.0).abs() <= 0.01, "{line}: not within 1% of JxrEncApp's size");
                }
                eprintln!("{line}");
                group.bench_function(BenchmarkId::new("jxrlib_1thread", &id), |b| {
                    b.iter(|| {
                        jxrlib::encode_half(
                            black_box(&input.half),
                            input.width,
                            input.height,
                            jxr_q,
                            black_box(&mut out),
                        )
                        .unwrap()
                    })
                });
                group.bench_function(BenchmarkId::new("hdrcodec_1thread", &id), |b| {
                    b.iter(|| encode(black_box(&input.image), &equal, &single).unwrap())
                });
                group.bench_function(BenchmarkId::new("hdrcodec_2threads", &id), |b| {
                    b.iter(|| encode(black_box(&input.image), &tiled, &two).unwrap())
                });
            }
            #[cfg(not(jxrlib))]
            let _ = (jxr_q, &two);
            group.bench_function(BenchmarkId::new("hdrcodec_1thread_quality", &id), |b| {
                b.iter(|| encode(black_box(&input.image), &opts, &single).unwrap())
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
