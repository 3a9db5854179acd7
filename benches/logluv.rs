//! LogLuv TIFF encode and decode speed (MP/s), single thread, on the corpus's LogLuv32
//! StillLife (1240x846) and its LogLuv24 / LogL16 re-encodings.
//!
//! Criterion measures our codec. libtiff (tif_luv.c, the reference) is timed in the same run
//! through tests/harness/logluv_libtiff.c (best of 15 full decodes of the same file to
//! `SGILOGDATAFMT_FLOAT` XYZ, and best of 15 encodes from float XYZ; its times include opening
//! the file from the page cache), next to a best-of-15 of ours measured the same way, and the
//! ratio is printed. `cargo bench -p hdrcodec-tests --bench logluv`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hdrcodec_core::{ColorPrimaries, Limits};
use hdrcodec_logluv::{decode, encode, read_tiff, DecodeOptions, EncodeOptions, Encoding, LogLuvRaster};
use std::hint::black_box;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn corpus_file() -> Option<PathBuf> {
    let f = common::corpus_dir()?.join("tiff/StillLife_logluv32.tif");
    f.is_file().then_some(f)
}

/// The libtiff harness, compiled into the target dir; `None` without cc or libtiff.
fn harness() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/logluv-bench");
    let dir = std::env::var_os("CARGO_TARGET_DIR").map(|d| PathBuf::from(d).join("logluv-bench")).unwrap_or(dir);
    std::fs::create_dir_all(&dir).ok()?;
    let bin = dir.join("logluv_libtiff");
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/harness/logluv_libtiff.c");
    let ok = Command::new("cc").arg("-O2").arg("-o").arg(&bin).arg(src).arg("-ltiff").status().ok()?.success();
    ok.then_some(bin)
}

fn harness_seconds(bin: &Path, args: &[&std::ffi::OsStr]) -> Option<f64> {
    let out = Command::new(bin).args(args).output().ok()?;
    String::from_utf8(out.stdout).ok()?.trim().parse().ok()
}

fn best_of<F: FnMut()>(n: usize, mut f: F) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn bench(c: &mut Criterion) {
    let Some(path) = corpus_file() else {
        eprintln!("SKIPPED: the shared corpus (tiff/StillLife_logluv32.tif) is missing");
        return;
    };
    let file32 = std::fs::read(&path).unwrap();
    let raster32 = read_tiff(&file32, &Limits::default()).unwrap();
    let xyz = raster32.to_floats();
    let (w, h) = (raster32.width, raster32.height);
    let mp = f64::from(w) * f64::from(h) / 1e6;
    let bin = harness();
    if bin.is_none() {
        eprintln!("libtiff harness unavailable (cc or libtiff-dev missing): no libtiff timings");
    }
    let tmp = std::env::temp_dir().join(format!("hdrcodec-logluv-bench-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();

    let mut g = c.benchmark_group("logluv");
    g.throughput(Throughput::Elements(u64::from(w) * u64::from(h)));
    g.sample_size(20);
    for enc in [Encoding::LogLuv32, Encoding::LogLuv24, Encoding::LogL16] {
        let floats: Vec<f32> = match enc {
            Encoding::LogL16 => xyz.chunks_exact(3).map(|p| p[1]).collect(),
            _ => xyz.clone(),
        };
        let mut raster = LogLuvRaster::from_floats(w, h, enc, &floats).unwrap();
        raster.stonits = Some(100.0);
        let file = raster.to_tiff().unwrap();
        let xyz_opts = DecodeOptions { primaries: ColorPrimaries::Xyz, ..Default::default() };
        let image = decode(&file, &Limits::default(), &DecodeOptions::default()).unwrap();
        let eopts = EncodeOptions { encoding: enc, ..Default::default() };

        g.bench_function(format!("{}/decode_xyz", enc.name()), |b| {
            b.iter(|| decode(black_box(&file), &Limits::default(), &xyz_opts).unwrap())
        });
        g.bench_function(format!("{}/decode_bt709", enc.name()), |b| {
            b.iter(|| decode(black_box(&file), &Limits::default(), &DecodeOptions::default()).unwrap())
        });
        g.bench_function(format!("{}/encode_from_xyz", enc.name()), |b| {
            b.iter(|| LogLuvRaster::from_floats(w, h, enc, black_box(&floats)).unwrap().to_tiff().unwrap())
        });
        g.bench_function(format!("{}/encode_bt709", enc.name()), |b| {
            b.iter(|| encode(black_box(&image), &eopts).unwrap())
        });

        let Some(bin) = &bin else { continue };
        let tif = tmp.join(format!("{}.tif", enc.name()));
        let raw = tmp.join(format!("{}.f32", enc.name()));
        std::fs::write(&tif, &file).unwrap();
        std::fs::write(&raw, floats.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
        let lt_dec = harness_seconds(bin, &["time-decode".as_ref(), tif.as_os_str(), "15".as_ref()]);
        let (ws, hs) = (w.to_string(), h.to_string());
        let lt_enc = harness_seconds(
            bin,
            &["time-encode".as_ref(), enc.name().as_ref(), ws.as_ref(), hs.as_ref(), raw.as_os_str(), "15".as_ref()],
        );
        // Ours, timed the same way (file read included, float XYZ out / in).
        let ours_dec = best_of(15, || {
            let data = std::fs::read(&tif).unwrap();
            black_box(read_tiff(&data, &Limits::default()).unwrap().to_floats());
        });
        let ours_enc = best_of(15, || {
            let f = LogLuvRaster::from_floats(w, h, enc, &floats).unwrap().to_tiff().unwrap();
            std::fs::write(tmp.join("ours.tif"), f).unwrap();
        });
        if let (Some(d), Some(e)) = (lt_dec, lt_enc) {
            println!(
                "{}: decode to float XYZ: ours {:.1} MP/s, libtiff {:.1} MP/s, ratio {:.2}x; \
                 encode from float XYZ: ours {:.1} MP/s, libtiff {:.1} MP/s, ratio {:.2}x",
                enc.name(),
                mp / ours_dec,
                mp / d,
                d / ours_dec,
                mp / ours_enc,
                mp / e,
                e / ours_enc
            );
        }
    }
    g.finish();
    let _ = std::fs::remove_dir_all(&tmp);
}

criterion_group!(benches, bench);
criterion_main!(benches);
