//! BC6H encode speed and quality: our effort levels against Intel ISPC (`intel_tex_2`, the five
//! profiles) and the `block_compression` crate, single-threaded, on the same images in the same
//! run. Criterion measures every encoder; then a summary table pairs each ISPC profile with our
//! effort level of equal or better RMSLE and shows both speeds (median of timed runs) and the
//! ratio.
#[path = "../tests/common/bc6h_peers.rs"]
mod peers;

use std::hint::black_box;
#[path = "common.rs"]
#[allow(dead_code)] // each bench uses some of the shared helpers
mod common;
use std::time::{Duration, Instant};

// Linking the facade crate brings in its build script's `-lstdc++`, which intel_tex_2 needs.
use criterion::{Criterion, Throughput};
use hdrcodec as _;
use hdrcodec_bc6h::encode::{encode_surface, EncodeOptions};

/// The images: corpus crops when the corpus is present, always the synthetic image.
fn images() -> Vec<peers::Image> {
    if let Some(corpus) = common::corpus_dir() {
        peers::quality_images(&corpus, 2, 128)
    } else {
        eprintln!("corpus not found: benchmarking the synthetic image only");
        vec![peers::synthetic(128)]
    }
}

/// An encoder under test: name and a function from image to blocks.
type Encoder = (String, Box<dyn Fn(&peers::Image) -> Vec<u8>>);

fn ours(effort: u8) -> Encoder {
    (
        format!("hdrcodec-e{effort}"),
        Box::new(move |img: &peers::Image| {
            let opts = EncodeOptions { signed: false, effort, ..Default::default() };
            encode_surface(img.width as u32, img.height as u32, &img.rgb, &opts).unwrap()
        }),
    )
}

fn ispc(index: usize) -> Encoder {
    let (name, settings) = peers::ispc_profiles()[index];
    (
        format!("ispc-{name}"),
        Box::new(move |img: &peers::Image| {
            // Padding and half conversion are part of the job for ISPC's input format.
            let (pw, ph, rgba) = peers::to_rgba_f16_padded(img);
            peers::ispc_encode(pw, ph, &rgba, &settings)
        }),
    )
}

fn block_compression() -> Encoder {
    (
        "block_compression-veryslow".into(),
        Box::new(|img: &peers::Image| {
            let (pw, ph, rgba) = peers::to_rgba_f16_padded(img);
            peers::block_compression_encode(pw, ph, &rgba)
        }),
    )
}

/// Pooled RMSLE over all images, and the median seconds of encoding all images once.
fn measure(encoder: &Encoder, images: &[peers::Image]) -> (f64, f64) {
    let (mut sq, mut n) = (0.0, 0usize);
    for img in images {
        let decoded = peers::decode_blocks(img.width, img.height, &(encoder.1)(img), false);
        let r = peers::rmsle(&img.rgb, &decoded);
        sq += r * r * img.rgb.len() as f64;
        n += img.rgb.len();
    }
    let mut times = Vec::new();
    let start = Instant::now();
    while times.is_empty() || (start.elapsed() < Duration::from_secs(2) && times.len() < 15) {
        let t = Instant::now();
        for img in images {
            black_box((encoder.1)(img));
        }
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    ((sq / n as f64).sqrt(), times[times.len() / 2])
}

fn main() {
    let images = images();
    let pixels: usize = images.iter().map(|i| i.width * i.height).sum();
    let mut encoders: Vec<Encoder> = (0..=9).map(ours).collect();
    encoders.extend((0..5).map(ispc));
    encoders.push(block_compression());

    let mut c = Criterion::default()
        .configure_from_args()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    {
        let mut group = c.benchmark_group("bc6h_encode_1thread");
        group.throughput(Throughput::Elements(pixels as u64));
        for (name, f) in &encoders {
            group.bench_function(name.as_str(), |b| {
                b.iter(|| {
                    for img in &images {
                        black_box(f(img));
                    }
                })
            });
        }
        group.finish();
    }
    c.final_summary();

    // The summary table.
    let names: Vec<&str> = images.iter().map(|i| i.name.as_str()).collect();
    println!(
        "\nBC6H UF16 encode, single thread, {} images ({}), {:.2} MP",
        images.len(),
        names.join(", "),
        pixels as f64 / 1e6
    );
    let results: Vec<(f64, f64)> = encoders.iter().map(|e| measure(e, &images)).collect();
    let mps = |secs: f64| pixels as f64 / secs / 1e6;
    println!("{:<28} {:>9} {:>9}", "encoder", "RMSLE", "MP/s");
    for (e, r) in encoders.iter().zip(&results) {
        println!("{:<28} {:>9.5} {:>9.3}", e.0, r.0, mps(r.1));
    }
    println!(
        "\n{:<10} {:>6} {:>11} {:>11} {:>10} {:>10} {:>12}",
        "ISPC", "effort", "RMSLE ispc", "RMSLE ours", "MP/s ispc", "MP/s ours", "speed ratio"
    );
    for p in 0..5 {
        let (ispc_rmsle, ispc_secs) = results[10 + p];
        // Our fastest effort with RMSLE no worse than this profile's.
        let pick =
            (0..10).filter(|&e| results[e].0 <= ispc_rmsle).max_by(|&a, &b| results[b].1.total_cmp(&results[a].1));
        let name = encoders[10 + p].0.trim_start_matches("ispc-");
        match pick {
            Some(e) => println!(
                "{:<10} {:>6} {:>11.5} {:>11.5} {:>10.3} {:>10.3} {:>11.2}x",
                name,
                e,
                ispc_rmsle,
                results[e].0,
                mps(ispc_secs),
                mps(results[e].1),
                ispc_secs / results[e].1
            ),
            None => println!("{:<10} {:>6} {:>11.5} {:>11} {:>10.3}", name, "-", ispc_rmsle, "none", mps(ispc_secs)),
        }
    }
}
