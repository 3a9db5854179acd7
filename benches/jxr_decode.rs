//! JPEG XR decode speed in one run: our decoder (`hdrcodec_jxr::decode_raw_into`) against
//! jxrlib, the reference codec, called in-process through a small C shim over Debian
//! `libjxr-dev` (tests/peers/jxrlib_shim.c, built by tests/build.rs). Both decode a file held
//! in memory to the file's own pixel format (jxrlib's raw samples) into a buffer allocated
//! once, outside the timing; each does its own working allocations inside it.
//!
//! Files: the three corpus `.jxr` files and, if JxrEncApp (Debian `libjxr-tools`) is on PATH,
//! larger ones made at bench time from the GoldenGate corpus image (our decode, half floats)
//! mirrored into a 4x3 mosaic of 5048x2580 (13 MP), written as a TIFF and encoded by JxrEncApp.
//! By default one of them: quality 0.6, 48bppRGBHalf, one tile. With
//! `HDRCODEC_JXR_BENCH_MATRIX=1`, the matrix instead: lossless and qualities 0.9, 0.6
//! and 0.3, × 48bppRGBHalf and 128bppRGBFloat, × one tile and 4x4 tiles (16 files; about 15
//! minutes). Before anything is timed, jxrlib's samples must equal ours, byte for byte, on
//! every file. `HDRCODEC_JXR_BENCH_KEEP=1` keeps the encoded files in the bench's temp
//! directory (for profiling).
//!
//! jxrlib is single-threaded: `jxrlib_1thread` and `hdrcodec_1thread` are the like-for-like
//! pair; `hdrcodec_2threads` is ours on a pool of two threads. Criterion's throughput is in
//! pixels (elements), so Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
use hdrcodec_cli::jxrlib::float_rgb_tiff;
use hdrcodec_core::{ImageCodec, Limits};
use hdrcodec_jxr::{decode_raw, decode_raw_into, raw_layout, JxrCodec};
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_dir, missing, tool};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;

/// jxrlib through tests/peers/jxrlib_shim.c.
#[cfg(jxrlib)]
mod jxrlib {
    use std::os::raw::c_int;

    extern "C" {
        fn jxrlib_shim_info(data: *const u8, len: usize, width: *mut u32, height: *mut u32, bits: *mut u32) -> c_int;
        fn jxrlib_shim_decode(data: *const u8, len: usize, out: *mut u8, out_len: usize, stride: usize) -> c_int;
    }

    /// The size of a file's image in its own pixel format, rows packed.
    pub struct Layout {
        pub width: u32,
        pub height: u32,
        pub stride: usize,
    }

    impl Layout {
        pub fn bytes(&self) -> usize {
            self.stride * self.height as usize
        }
    }

    /// Reads the header (jxrlib's error code on failure).
    pub fn layout(data: &[u8]) -> Result<Layout, i32> {
        let (mut width, mut height, mut bits) = (0u32, 0u32, 0u32);
        // SAFETY: `data` is valid for `data.len()` bytes and only read; the three out-pointers
        // point to live locals. The shim keeps no pointer after it returns.
        let err = unsafe { jxrlib_shim_info(data.as_ptr(), data.len(), &mut width, &mut height, &mut bits) };
        if err != 0 {
            return Err(err);
        }
        let stride = (width as usize * bits as usize).div_ceil(8);
        Ok(Layout { width, height, stride })
    }

    /// Decodes the whole image into `out` (at least `layout.bytes()` long).
    pub fn decode(data: &[u8], layout: &Layout, out: &mut [u8]) -> Result<(), i32> {
        assert!(out.len() >= layout.bytes());
        // SAFETY: `data` is valid for reads of `data.len()` bytes and `out` for writes of
        // `out.len()` bytes for the whole call; the shim refuses (before writing) an image whose
        // `height` rows of `stride` bytes do not fit in `out.len()`, and keeps no pointer after
        // it returns.
        let err = unsafe { jxrlib_shim_decode(data.as_ptr(), data.len(), out.as_mut_ptr(), out.len(), layout.stride) };
        if err == 0 {
            Ok(())
        } else {
            Err(err)
        }
    }
}

struct File {
    name: String,
    data: Vec<u8>,
}

fn corpus_files() -> Vec<File> {
    let Some(dir) = corpus_dir() else {
        missing("jxr_decode", "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)");
        return Vec::new();
    };
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir.join("jxr"))
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    paths.retain(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("jxr")));
    paths.sort();
    paths
        .iter()
        .map(|p| File {
            name: p.file_stem().unwrap().to_string_lossy().into_owned(),
            data: std::fs::read(p).expect("read a corpus .jxr"),
        })
        .collect()
}

/// The larger files (see the top of this file), if JxrEncApp is there.
fn large_files(corpus: &[File]) -> Vec<File> {
    let Some(enc) = tool("JxrEncApp") else {
        missing("jxr_decode", "JxrEncApp (Debian libjxr-tools), which makes the 13 MP files");
        return Vec::new();
    };
    let Some(src) = corpus.iter().find(|f| f.name.starts_with("GoldenGate_48bppRGBHalf")) else {
        return Vec::new();
    };
    let (w, h, raw) = common::golden_gate_half(&src.data);
    let (big_w, big_h, half) = common::mosaic(&raw, w, h);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("jxr_decode_bench");
    std::fs::create_dir_all(&dir).expect("create the bench's temp dir");
    let matrix = std::env::var("HDRCODEC_JXR_BENCH_MATRIX").is_ok_and(|v| v == "1");
    let qualities: &[&str] = if matrix { &["lossless", "0.9", "0.6", "0.3"] } else { &["0.6"] };
    let formats: &[&str] = if matrix { &["48bppRGBHalf", "128bppRGBFloat"] } else { &["48bppRGBHalf"] };
    // For profiling outside the bench: keep the encoded files.
    let keep = std::env::var("HDRCODEC_JXR_BENCH_KEEP").is_ok_and(|v| v == "1");
    let tilings: &[&str] = if matrix { &["1tile", "4x4tiles"] } else { &["1tile"] };
    let mut files = Vec::new();
    for &format in formats {
        let (code, tif) = if format == "48bppRGBHalf" {
            ("12", float_rgb_tiff(big_w as u32, big_h as u32, 16, &half).expect("a TIFF"))
        } else {
            let floats: Vec<u8> = half
                .chunks_exact(2)
                .flat_map(|b| half::f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32().to_le_bytes())
                .collect();
            ("15", float_rgb_tiff(big_w as u32, big_h as u32, 32, &floats).expect("a TIFF"))
        };
        let tif_path = dir.join(format!("mosaic_{format}.tif"));
        std::fs::write(&tif_path, tif).expect("write the mosaic TIFF");
        for &quality in qualities {
            for &tiling in tilings {
                let name = format!("GoldenGate_mosaic_{big_w}x{big_h}_{format}_{quality}_{tiling}");
                let jxr = dir.join(format!("{name}.jxr"));
                let mut args = vec!["-c", code];
                if quality != "lossless" {
                    args.extend(["-q", quality]);
                }
                if tiling == "4x4tiles" {
                    args.extend(["-U", "4", "4"]);
                }
                encode(&enc, &tif_path, &jxr, &args);
                files.push(File { name, data: std::fs::read(&jxr).expect("read an encoded mosaic") });
                if keep {
                    eprintln!("jxr_decode bench: kept {}", jxr.display());
                } else {
                    let _ = std::fs::remove_file(&jxr);
                }
            }
        }
        let _ = std::fs::remove_file(&tif_path);
    }
    files
}

fn encode(enc: &Path, tif: &Path, jxr: &Path, args: &[&str]) {
    let out = Command::new(enc).arg("-i").arg(tif).arg("-o").arg(jxr).args(args).output().expect("run JxrEncApp");
    assert!(out.status.success() && jxr.is_file(), "JxrEncApp failed: {}", String::from_utf8_lossy(&out.stderr));
}

fn bench(c: &mut Criterion) {
    let mut files = corpus_files();
    if !files.is_empty() {
        let large = large_files(&files);
        files.extend(large);
    }
    #[cfg(not(jxrlib))]
    missing("jxr_decode", "jxrlib (Debian libjxr-dev; tests/build.rs builds the shim only if it is installed)");

    let (single, two) = common::one_and_two_threads();
    let mut group = c.benchmark_group("jxr_decode");
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for f in &files {
        let info = JxrCodec.probe(&f.data, &Limits::default()).expect("probe");
        group.throughput(Throughput::Elements(info.width as u64 * info.height as u64));
        let ours = decode_raw(&f.data, &single).expect("our decode");
        assert_eq!(decode_raw(&f.data, &two).expect("our decode on two threads"), ours, "{}: 1 vs 2 threads", f.name);
        #[cfg(jxrlib)]
        {
            let layout = jxrlib::layout(&f.data).unwrap_or_else(|e| panic!("{}: jxrlib error {e}", f.name));
            assert_eq!((layout.width, layout.height), (info.width, info.height), "{}", f.name);
            let mut theirs = vec![0u8; layout.bytes()];
            jxrlib::decode(&f.data, &layout, &mut theirs).unwrap_or_else(|e| panic!("{}: jxrlib error {e}", f.name));
            assert_eq!(theirs.len(), ours.len(), "{}: jxrlib's and our raw sizes", f.name);
            let differ = theirs.iter().zip(&ours).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{}: {differ} bytes of jxrlib's samples differ from ours", f.name);
            eprintln!("jxr_decode bench: {} ({}x{}): jxrlib's samples equal ours", f.name, info.width, info.height);
            group.bench_with_input(BenchmarkId::new("jxrlib_1thread", &f.name), f, |b, f| {
                b.iter(|| jxrlib::decode(black_box(&f.data), &layout, black_box(&mut theirs)).unwrap())
            });
        }
        let (_, _, row) = raw_layout(&f.data).expect("our layout");
        let mut buf = vec![0u8; ours.len()];
        // Checked before timing, since criterion's --list runs no iterations.
        decode_raw_into(&f.data, &single, &mut buf, row).expect("our decode into a buffer");
        assert_eq!(buf, ours, "{}: decode_raw_into gives decode_raw's bytes", f.name);
        group.bench_with_input(BenchmarkId::new("hdrcodec_1thread", &f.name), f, |b, f| {
            b.iter(|| decode_raw_into(black_box(&f.data), &single, black_box(&mut buf), row).unwrap())
        });
        group.bench_with_input(BenchmarkId::new("hdrcodec_2threads", &f.name), f, |b, f| {
            b.iter(|| decode_raw_into(black_box(&f.data), &two, black_box(&mut buf), row).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
