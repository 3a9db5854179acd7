//! Decode speed of an AV1 stream, to planes (libdav1d alone) and to linear light (the f64
//! reference conversion, `hdr10::yuv_to_frame`, against the decoder's own, `light::YuvToLight`,
//! on one thread and on a pool), each the median of `RUNS` passes, interleaved so that all see
//! the same machine load. A measurement, not a test.
//!
//! `cargo run --release -j1 -p hdrcodec-video --no-default-features --features decode --example
//! decode_speed -- STREAM.ivf [RUNS] [MODES]`, MODES a comma list of `planes`, `f64`, `light`,
//! `light2` (default all). Under `valgrind --tool=callgrind` give one run and one mode.

use hdrcodec_core::ThreadPool;
use hdrcodec_video::decode::{Av1DecodeOptions, Av1Decoder};
use hdrcodec_video::hdr10::yuv_to_frame;
use std::hint::black_box;
use std::time::Instant;

/// Decodes the whole stream once in `mode`; returns the frame count.
fn pass(data: &[u8], mode: &str) -> usize {
    let pool = if mode == "light2" { ThreadPool::new(2).unwrap() } else { ThreadPool::single() };
    let options = Av1DecodeOptions { pool, ..Av1DecodeOptions::default() };
    let mut decoder = Av1Decoder::new(data, &options).unwrap();
    let (transfer, siting) = (decoder.transfer(), hdrcodec_video::hdr10::ChromaSiting::Colocated);
    let mut frames = 0;
    match mode {
        "planes" => {
            while let Some(planes) = decoder.next_planes().unwrap() {
                black_box(planes);
                frames += 1;
            }
        }
        "f64" => {
            let range = if decoder.summary().sequence_header.as_ref().unwrap().color.full_range {
                hdrcodec_video::hdr10::Range::Full
            } else {
                hdrcodec_video::hdr10::Range::Limited
            };
            while let Some(planes) = decoder.next_planes().unwrap() {
                black_box(yuv_to_frame(&planes, transfer, range, siting, 100.0).unwrap());
                frames += 1;
            }
        }
        "light" | "light2" => {
            while let Some(frame) = decoder.next_frame().unwrap() {
                black_box(frame);
                frames += 1;
            }
        }
        other => panic!("mode {other}: expected planes, f64, light or light2"),
    }
    frames
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let data = std::fs::read(args.get(1).expect("usage: decode_speed STREAM.ivf [RUNS] [MODES]")).unwrap();
    let runs: usize = args.get(2).map_or(5, |r| r.parse().unwrap());
    let modes: Vec<&str> = args.get(3).map_or("planes,f64,light,light2", String::as_str).split(',').collect();
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); modes.len()];
    let mut frames = 0;
    for _ in 0..runs {
        for (mode, t) in modes.iter().zip(&mut times) {
            let start = Instant::now();
            frames = pass(&data, mode);
            t.push(start.elapsed().as_secs_f64());
        }
    }
    for (mode, mut t) in modes.iter().zip(times) {
        t.sort_by(f64::total_cmp);
        let median = t[t.len() / 2];
        println!("{mode:7} {frames} frames: median {:.3} s, {:.1} frames/s", median, frames as f64 / median);
    }
}
