//! PFM decode and encode speed in one run, single thread (every PFM reader and writer here is
//! single-threaded): ours (`hdrcodec-pfm`) against the crates.io readers and writers of PFM
//! called in-process (`zune-ppm` 0.5 reads PFM, it has no PFM writer; `pxm` 0.1 reads and writes
//! it) and OpenImageIO's `oiiotool` out of process (`--threads 1`), decode only: oiiotool
//! cannot write PFM (`../shared/REFERENCES.md`).
//!
//! Images: the corpus's GoldenGate.exr (1262x860 RGB, half samples) and its 4x3 mirrored mosaic
//! (5048x2580, 13.0 MP), each written by ours as a little-endian PFM. Decode: from the file in
//! memory to top-to-bottom interleaved f32 RGB, output allocated inside each call. Encode: from
//! f32 RGB in memory to a file in memory (`pxm` writes from its own `PFM` struct, built once
//! outside the timing; ours from the `HdrImage`). oiiotool reads the mosaic's file from disk
//! (page cache) and writes OIIO's `null` format; `pfm_oiiotool/startup_1px` is oiiotool on a
//! 1-pixel PFM (written to a 1-pixel EXR: OIIO 2.4's null writer fails on small images). Before
//! timing, every peer's samples must equal ours bit for bit (oiiotool's through an uncompressed
//! float EXR it writes), and `pxm`'s file must decode (by ours) to the source samples.
//!
//! Run: `cargo bench -p hdrcodec-tests --bench pfm` (about a minute). Criterion's throughput is
//! in pixels (elements), so Melem/s = MP/s.
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode, Throughput};
use hdrcodec_core::{HdrImage, Limits};
use hdrcodec_pfm::{decode_pfm, encode_pfm};
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_for, first_difference, missing, run, tool};
use std::ffi::OsStr;
use std::hint::black_box;
use std::io::Cursor;
use std::path::PathBuf;
use std::time::Duration;
use zune_ppm::zune_core::bytestream::ZCursor;
use zune_ppm::zune_core::result::DecodingResult;

fn zune_decode(data: &[u8]) -> Vec<f32> {
    match zune_ppm::PPMDecoder::new(ZCursor::new(data)).decode().expect("zune-ppm's decode") {
        DecodingResult::F32(samples) => samples,
        _ => panic!("zune-ppm did not decode a PFM to f32"),
    }
}

fn pxm_decode(data: &[u8]) -> Vec<f32> {
    pxm::PFM::read_from(&mut Cursor::new(data)).expect("pxm's decode").data
}

fn assert_same(what: &str, ours: &[f32], theirs: &[f32]) {
    if let Some(i) = first_difference(ours, theirs) {
        panic!("{what}: differs from ours at sample {i} (ours {:?}, theirs {:?})", ours.get(i), theirs.get(i));
    }
}

fn bench(c: &mut Criterion) {
    let Some(dir) = corpus_for("pfm") else { return };
    let oiiotool = tool("oiiotool");
    if oiiotool.is_none() {
        missing("pfm", "oiiotool (Debian openimageio-tools)");
    }
    eprintln!("pfm bench: no out-of-process encode peer: oiiotool cannot write PFM");
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("pfm_bench");
    std::fs::create_dir_all(&tmp).expect("create the bench's temp dir");
    let null = tmp.join("out.null");

    let exr = std::fs::read(dir.join("exr/GoldenGate.exr")).expect("read the corpus's exr/GoldenGate.exr");
    let small = hdrcodec_exr::decode_exr(&exr, &Limits::default()).expect("decode GoldenGate.exr");
    let large = common::golden_gate_exr_mosaic(&dir);
    if let Some(oiiotool) = &oiiotool {
        let one_px = HdrImage::new(1, 1, small.channels(), small.samples()[..3].to_vec(), small.color.clone()).unwrap();
        let path = tmp.join("1px.pfm");
        std::fs::write(&path, encode_pfm(&one_px).unwrap()).unwrap();
        // OIIO 2.4's null writer fails on small images (64x64 does; 13 MP works): the
        // 1-pixel start-up writes an EXR of one pixel instead.
        let out = tmp.join("1px_out.exr");
        let args = [OsStr::new("--threads"), OsStr::new("1"), path.as_os_str(), OsStr::new("-o"), out.as_os_str()];
        let mut g = c.benchmark_group("pfm_oiiotool");
        g.sample_size(10).sampling_mode(SamplingMode::Flat).warm_up_time(Duration::from_millis(300));
        g.bench_function("startup_1px", |b| b.iter(|| run(oiiotool, &args)));
        g.finish();
    }
    for (name, img) in [("GoldenGate", &small), ("GoldenGate_mosaic_5048x2580", &large)] {
        let data = encode_pfm(img).expect("our encode");
        let ours = decode_pfm(&data, &Limits::default()).expect("our decode");
        assert_same(&format!("{name}: our round trip"), img.samples(), ours.samples());
        assert_same(&format!("{name}: zune-ppm"), ours.samples(), &zune_decode(&data));
        assert_same(&format!("{name}: pxm"), ours.samples(), &pxm_decode(&data));
        let pfm = pxm::PFMBuilder::new()
            .size(img.width() as usize, img.height() as usize)
            .color(true)
            .scale(-1.0)
            .data(img.samples().to_vec())
            .build()
            .expect("pxm's PFM");
        let mut theirs = Vec::new();
        pfm.write_into(&mut theirs).expect("pxm's encode");
        let back = decode_pfm(&theirs, &Limits::default()).expect("our decode of pxm's file");
        assert_same(&format!("{name}: pxm's file"), img.samples(), back.samples());
        let path = tmp.join(format!("{name}.pfm"));
        let oiio = oiiotool.as_ref().filter(|_| img.width() * img.height() >= 12_000_000);
        if let Some(oiiotool) = oiio {
            std::fs::write(&path, &data).expect("write the PFM");
            let back = tmp.join("oiiotool_decoded.exr");
            let args = ["--threads", "1"].map(OsStr::new);
            let rest = ["-d", "float", "--compression", "none", "-o"].map(OsStr::new);
            run(oiiotool, &[&args[..], &[path.as_os_str()], &rest[..], &[back.as_os_str()]].concat());
            let theirs = hdrcodec_exr::decode_exr(&std::fs::read(&back).unwrap(), &Limits::default()).unwrap();
            assert_same(&format!("{name}: oiiotool"), ours.samples(), theirs.samples());
        }
        drop(ours);

        let mut g = c.benchmark_group(format!("pfm/{name}"));
        g.sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_millis(300))
            .measurement_time(Duration::from_secs(2))
            .throughput(Throughput::Elements(u64::from(img.width()) * u64::from(img.height())));
        let limits = Limits::default();
        g.bench_function("decode/hdrcodec", |b| b.iter(|| decode_pfm(black_box(&data), &limits).unwrap()));
        g.bench_function("decode/zune-ppm", |b| b.iter(|| zune_decode(black_box(&data))));
        g.bench_function("decode/pxm", |b| b.iter(|| pxm_decode(black_box(&data))));
        if let Some(oiiotool) = oiio {
            let args = [OsStr::new("--threads"), OsStr::new("1"), path.as_os_str(), OsStr::new("-o"), null.as_os_str()];
            g.bench_function("decode/oiiotool", |b| b.iter(|| run(oiiotool, &args)));
        }
        g.bench_function("encode/hdrcodec", |b| b.iter(|| encode_pfm(black_box(img)).unwrap()));
        g.bench_function("encode/pxm", |b| {
            b.iter(|| {
                let mut out = Vec::new();
                black_box(&pfm).write_into(&mut out).unwrap();
                out
            })
        });
        g.finish();
        std::fs::remove_file(&path).ok();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
