//! HDR10 AV1 encode and decode speed in one run, at 1920x1080.
//!
//! Frames: the first [`FRAMES`] frames of the corpus's video/hdr10-video-with-sdr-container.mp4
//! (HEVC Main10, BT.2020 PQ, 1920x1080; FFmpeg decodes them to 10-bit planes once, before
//! timing, and `hdr10::yuv_to_frame` makes them linear light), or, without FFmpeg, the
//! generated moving light at 1920x1080 (codecs/video's `sequences`, what `hdrcodec bench --video
//! --video-size 1920x1080` used).
//!
//! - Encode (`video_encode`): ours (hdrcodec-video's `encode_sequence`: linear frames to 10-bit
//!   BT.2020 PQ 4:2:0 limited Y'CbCr, rav1e 0.8.1, IVF in memory; one thread, and a pool of two
//!   with two tiles) at `hdrcodec bench --video`'s pairings of a quantizer with an SVT-AV1 CRF
//!   ([`PAIRS`]), against FFmpeg's SVT-AV1 (`ffmpeg -c:v libsvtav1`, an outside program,
//!   hdrcodec-cli's `peers::svtav1` arguments: preset 8, `lp=1`, `-threads 1`, the same HDR10
//!   signalling) on the same Y'CbCr, our conversion of the frames, written to a raw file before
//!   timing (ours converts inside its time: the `convert_to_yuv` row is that conversion alone).
//!   Before timing, both streams are decoded by our decoder and scored against the linear
//!   frames: bytes and PU21-PSNR are printed, and each must be at least [`MIN_PU21_PSNR`] dB.
//! - Decode (`video_decode`): the streams of the first pair (ours at q100, SVT-AV1 at CRF 25),
//!   each played [`DECODE_ROUNDS`] times over as one stream ([`repeated`]: 100 frames), by ours
//!   to 10-bit planes (`Av1Decoder::next_planes`, libdav1d through the `dav1d` crate, one thread)
//!   and to linear light (`decode_ivf`, one thread and a pool of two), against FFmpeg's libdav1d
//!   (`-threads 1`, raw `yuv420p10le` to `/dev/null`). Before timing, FFmpeg's planes of one
//!   round must equal ours code for code.
//! - Process start-up: FFmpeg encoding and decoding a 64x64 one-frame stream (`*startup` rows),
//!   to set beside the 1080p rows (SVT-AV1 on 4 frames of 2 MP: start-up about a tenth of its
//!   time; a 100-frame decode: under a tenth).
//!
//! Run: `cargo bench -p hdrcodec-tests --bench video` (release; about ten minutes on the two
//! cores, most of it rav1e; `-- video_decode` runs the decode rows alone after the encode
//! checks). Criterion's throughput is in frames: "elem/s" is frames per second; MP/s is that
//! × 2.07.
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
use hdrcodec_cli::jxrlib::{run, TempDir};
use hdrcodec_cli::peers::svtav1;
use hdrcodec_core::{metrics, HdrImage, Limits, ThreadPool};
use hdrcodec_video::decode::{decode_ivf, Av1DecodeOptions, Av1Decoder};
use hdrcodec_video::encode::{encode_sequence, Av1Options};
use hdrcodec_video::hdr10::{content_light_level, yuv_to_frame, ChromaSiting, Range, Subsampling, Transfer, YuvFrame};
use hdrcodec_video::ivf::{IvfHeader, IvfReader, IvfWriter};
use hdrcodec_video::sequences::moving_light_frame;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use common::{corpus_dir, missing, tool};
use std::ffi::{OsStr, OsString};
use std::hint::black_box;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// Frames per sequence.
const FRAMES: usize = 4;
/// The frame size.
const SIZE: (u32, u32) = (1920, 1080);
/// The decode rows decode each stream this many times over (a longer stream, [`repeated`]), so
/// that FFmpeg's start-up is a small part of its time.
const DECODE_ROUNDS: usize = 25;
/// The streams' frame rate (time base).
const FPS: u32 = 25;
/// Our quantizer and SVT-AV1's CRF of each timed pair, from `hdrcodec bench --video`'s sweep
/// (cli/src/video_bench.rs: CRF N aims near quantizer index 4N): rav1e speed 6 (our default)
/// against SVT-AV1 preset 8 (the CLI bench's).
const PAIRS: [(u8, u8); 2] = [(100, 25), (140, 35)];
/// The least PU21-PSNR (dB) of a stream against the source frames (it catches a wrong
/// stream, not a small loss: both encoders are well above it at these settings).
const MIN_PU21_PSNR: f64 = 30.0;

/// FFmpeg with SVT-AV1 and libdav1d, or why not (printed as missing).
fn ffmpeg() -> Option<std::path::PathBuf> {
    let Some(ffmpeg) = tool(svtav1::PROGRAM) else {
        missing("video", "FFmpeg (Debian ffmpeg)");
        return None;
    };
    if let Some(lacks) = svtav1::missing_codecs() {
        missing("video", &format!("FFmpeg's {lacks}"));
        return None;
    }
    Some(ffmpeg)
}

/// The bench's frames and their name: the corpus's HDR10 clip through FFmpeg, else the
/// generated moving light.
fn frames(ffmpeg: Option<&Path>, dir: &TempDir) -> (String, Vec<HdrImage>) {
    let clip = corpus_dir().map(|d| d.join("video/hdr10-video-with-sdr-container.mp4")).filter(|p| p.is_file());
    if clip.is_none() {
        missing("video", "the shared corpus's HDR10 clip (../shared/corpus or $HDRCODEC_CORPUS)");
    }
    if let (Some(ffmpeg), Some(clip)) = (ffmpeg, clip) {
        let raw = dir.path().join("clip.yuv");
        let frames = FRAMES.to_string();
        let args: [&OsStr; 12] = [
            "-hide_banner".as_ref(),
            "-nostdin".as_ref(),
            "-i".as_ref(),
            clip.as_os_str(),
            "-frames:v".as_ref(),
            frames.as_ref(),
            "-f".as_ref(),
            "rawvideo".as_ref(),
            "-pix_fmt".as_ref(),
            "yuv420p10le".as_ref(),
            "-y".as_ref(),
            raw.as_os_str(),
        ];
        run(ffmpeg, &args, &raw).expect("FFmpeg decodes the corpus clip");
        let data = std::fs::read(&raw).expect("read the clip's planes");
        let (w, h) = (SIZE.0 as usize, SIZE.1 as usize);
        svtav1::check_raw_size(&data, w, h, FRAMES).expect("the clip is 1920x1080");
        let codes: Vec<u16> = data.chunks_exact(2).map(|b| u16::from_le_bytes([b[0], b[1]])).collect();
        let (cw, ch) = YuvFrame::chroma_size(w, h, Subsampling::Yuv420);
        let frames = codes
            .chunks_exact(w * h + 2 * cw * ch)
            .map(|f| {
                let (y, c) = f.split_at(w * h);
                let (cb, cr) = c.split_at(cw * ch);
                let yuv = YuvFrame {
                    width: w,
                    height: h,
                    subsampling: Subsampling::Yuv420,
                    y: y.to_vec(),
                    cb: cb.to_vec(),
                    cr: cr.to_vec(),
                };
                // HEVC's default chroma siting (the clip signals none): left.
                yuv_to_frame(&yuv, Transfer::Pq, Range::Limited, ChromaSiting::Left, 100.0).expect("clip to light")
            })
            .collect();
        return ("hdr10-clip".into(), frames);
    }
    let n = FRAMES as u32;
    let light = (0..n).map(|t| moving_light_frame(SIZE.0, SIZE.1, 4000.0, SIZE.1 as f32 / 6.0, t, n)).collect();
    ("moving-light".into(), light)
}

/// Our decode of `stream` scored against `source`: mean PU21-PSNR over the frames, asserted
/// above [`MIN_PU21_PSNR`].
fn score(source: &[HdrImage], stream: &[u8], who: &str) -> f64 {
    let back = decode_ivf(stream, &Av1DecodeOptions::default()).expect("our decode");
    assert_eq!(back.len(), source.len(), "{who}: frames decoded");
    let psnr = source.iter().zip(&back).map(|(s, b)| metrics::compare(s, b).expect("compare").pu21_psnr).sum::<f64>()
        / source.len() as f64;
    assert!(psnr >= MIN_PU21_PSNR, "{who}: its stream decodes {psnr:.1} dB from the source (< {MIN_PU21_PSNR})");
    psnr
}

/// Our decoder's 10-bit planes of `stream`, as raw `yuv420p10le`.
fn our_planes(stream: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut decoder = Av1Decoder::new(stream, &Av1DecodeOptions::default()).expect("our decoder");
    while let Some(planes) = decoder.next_planes().expect("our decode to planes") {
        svtav1::push_planes(&planes, &mut out);
    }
    out
}

/// Arguments as `OsStr`s.
fn os(args: &[OsString]) -> Vec<&OsStr> {
    args.iter().map(OsString::as_os_str).collect()
}

/// `stream` (IVF) played `times` times over: its temporal units repeated, each round starting
/// again with its first one (sequence header and key frame, which resets every reference), times
/// restamped.
fn repeated(stream: &[u8], times: usize) -> Vec<u8> {
    let reader = IvfReader::new(stream, &Limits::default()).expect("our IVF");
    let header = *reader.header();
    let units: Vec<&[u8]> = reader.frames().map(|f| f.expect("an IVF frame").data).collect();
    let count = units.len() * times;
    let header = IvfHeader { frame_count: u32::try_from(count).expect("a frame count"), ..header };
    let mut out = IvfWriter::new(Vec::new(), &header).expect("an IVF writer");
    for (pts, unit) in units.iter().cycle().take(count).enumerate() {
        out.write_frame(pts as u64, unit).expect("an IVF frame");
    }
    out.finish().expect("an IVF file")
}

/// Runs FFmpeg's libdav1d on `ivf`, the raw planes to `/dev/null` (no file to write, as our
/// decoder keeps its planes in memory).
fn ffmpeg_decode_to_null(ffmpeg: &Path, ivf: &Path) {
    let args = svtav1::decode_args(ivf, Path::new("/dev/null"));
    let out = Command::new(ffmpeg).args(&args).output().expect("run FFmpeg");
    assert!(out.status.success(), "FFmpeg failed on {}: {}", ivf.display(), String::from_utf8_lossy(&out.stderr));
}

/// FFmpeg's libdav1d on `stream` (a round of the timed stream, written to `dir` as `name`):
/// its planes must equal ours.
fn check_peer_decode(ffmpeg: &Path, dir: &TempDir, stream: &[u8], name: &str) {
    let (ivf, raw) = (dir.path().join(format!("{name}.ivf")), dir.path().join(format!("{name}.yuv")));
    std::fs::write(&ivf, stream).expect("write a stream");
    run(ffmpeg, &os(&svtav1::decode_args(&ivf, &raw)), &raw).expect("FFmpeg decodes the stream");
    let theirs = std::fs::read(&raw).expect("read FFmpeg's planes");
    assert!(theirs == our_planes(stream), "{name}: FFmpeg's libdav1d planes differ from ours");
}

fn bench(c: &mut Criterion) {
    let ffmpeg = ffmpeg();
    let dir = TempDir::new("video-bench").expect("a temporary directory");
    let (name, frames) = frames(ffmpeg.as_deref(), &dir);
    let (w, h) = (frames[0].width(), frames[0].height());
    let single = Av1Options { fps: FPS, pool: ThreadPool::single(), ..Av1Options::default() };
    let two = Av1Options { pool: ThreadPool::new(2).expect("a pool of two threads"), tiles: 2, ..single.clone() };
    let raw = dir.path().join("in.yuv");
    let (yuv, _) = svtav1::raw_yuv(&frames);
    std::fs::write(&raw, &yuv).expect("write the raw planes");
    // A 64x64 one-frame input for FFmpeg's start-up time.
    let tiny = [moving_light_frame(64, 64, 1000.0, 8.0, 0, 1)];
    let tiny_raw = dir.path().join("tiny.yuv");
    std::fs::write(&tiny_raw, svtav1::raw_yuv(&tiny).0).expect("write the tiny planes");
    let md = single.mastering_display;
    let cll = content_light_level(&frames, Transfer::Pq);
    eprintln!("video bench: {name}, {FRAMES} frames of {w}x{h}; MaxCLL/MaxFALL {}/{}", cll.max_cll, cll.max_fall);

    let mut streams = Vec::new();
    let mut enc = c.benchmark_group("video_encode");
    enc.sample_size(10).sampling_mode(SamplingMode::Flat).throughput(Throughput::Elements(FRAMES as u64));
    enc.warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    enc.bench_function(BenchmarkId::new("convert_to_yuv", &name), |b| b.iter(|| svtav1::raw_yuv(black_box(&frames))));
    for (q, crf) in PAIRS {
        for (label, options) in [("hdrcodec_rav1e_s6", &single), ("hdrcodec_rav1e_s6_2threads", &two)] {
            let options = Av1Options { quantizer: q, ..options.clone() };
            let (_, ours) = encode_sequence(&frames, &options, Vec::new()).expect("our encode");
            let psnr = score(&frames, &ours, label);
            eprintln!("video bench: {label} q{q} (tiles {}): {} bytes, {psnr:.2} dB", options.tiles, ours.len());
            let id = format!("{name}/q{q}");
            enc.bench_function(BenchmarkId::new(label, &id), |b| {
                b.iter(|| encode_sequence(black_box(&frames), &options, Vec::new()).unwrap())
            });
            if options.tiles == 0 {
                streams.push((format!("hdrcodec_q{q}"), ours));
            }
        }
        let Some(ffmpeg) = &ffmpeg else { continue };
        let ivf = dir.path().join(format!("svt_crf{crf}.ivf"));
        let args = svtav1::encode_args(&raw, &ivf, (w, h, FPS), crf, &md, cll);
        run(ffmpeg, &os(&args), &ivf).expect("SVT-AV1 encodes");
        let theirs = std::fs::read(&ivf).expect("read SVT-AV1's stream");
        let psnr = score(&frames, &theirs, "SVT-AV1");
        eprintln!("video bench: svt-av1 preset {} crf{crf}: {} bytes, {psnr:.2} dB", svtav1::PRESET, theirs.len());
        enc.bench_function(BenchmarkId::new(format!("svtav1_p{}", svtav1::PRESET), format!("{name}/crf{crf}")), |b| {
            b.iter(|| run(ffmpeg, &os(&args), &ivf).unwrap())
        });
        streams.push((format!("svtav1_crf{crf}"), theirs));
    }
    if let Some(ffmpeg) = &ffmpeg {
        let ivf = dir.path().join("tiny.ivf");
        let args = svtav1::encode_args(&tiny_raw, &ivf, (64, 64, FPS), PAIRS[0].1, &md, cll);
        run(ffmpeg, &os(&args), &ivf).expect("SVT-AV1 encodes the tiny frame");
        enc.throughput(Throughput::Elements(1));
        enc.bench_function(BenchmarkId::new("svtav1_startup", "64x64x1"), |b| {
            b.iter(|| run(ffmpeg, &os(&args), &ivf).unwrap())
        });
    }
    enc.finish();

    let mut dec = c.benchmark_group("video_decode");
    let frames_decoded = FRAMES * DECODE_ROUNDS;
    dec.sample_size(10).sampling_mode(SamplingMode::Flat).throughput(Throughput::Elements(frames_decoded as u64));
    dec.warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    let light_two = Av1DecodeOptions { pool: ThreadPool::new(2).expect("a pool of two threads"), ..Default::default() };
    for (stream_name, stream) in streams.iter().take(2) {
        let id = format!("{name}/{stream_name}x{DECODE_ROUNDS}");
        let long = repeated(stream, DECODE_ROUNDS);
        assert_eq!(our_planes(&long).len(), our_planes(stream).len() * DECODE_ROUNDS, "{id}: frames of the rounds");
        dec.bench_function(BenchmarkId::new("hdrcodec_planes", &id), |b| b.iter(|| our_planes(black_box(&long))));
        dec.bench_function(BenchmarkId::new("hdrcodec_light", &id), |b| {
            b.iter(|| decode_ivf(black_box(&long), &Av1DecodeOptions::default()).unwrap())
        });
        dec.bench_function(BenchmarkId::new("hdrcodec_light_2threads", &id), |b| {
            b.iter(|| decode_ivf(black_box(&long), &light_two).unwrap())
        });
        if let Some(ffmpeg) = &ffmpeg {
            check_peer_decode(ffmpeg, &dir, stream, stream_name);
            let ivf = dir.path().join(format!("{stream_name}x{DECODE_ROUNDS}.ivf"));
            std::fs::write(&ivf, &long).expect("write a stream");
            dec.bench_function(BenchmarkId::new("ffmpeg_libdav1d", &id), |b| {
                b.iter(|| ffmpeg_decode_to_null(ffmpeg, &ivf))
            });
        }
    }
    if let Some(ffmpeg) = &ffmpeg {
        let tiny_options = Av1Options { quantizer: 100, ..single.clone() };
        let (_, stream) = encode_sequence(&tiny, &tiny_options, Vec::new()).expect("our encode of the tiny frame");
        check_peer_decode(ffmpeg, &dir, &stream, "tiny");
        let ivf = dir.path().join("tiny.ivf");
        dec.throughput(Throughput::Elements(1));
        dec.bench_function(BenchmarkId::new("ffmpeg_libdav1d_startup", "64x64x1"), |b| {
            b.iter(|| ffmpeg_decode_to_null(ffmpeg, &ivf))
        });
    }
    dec.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
