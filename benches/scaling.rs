//! Decode scaling: megapixels per second against the threads of the decoder's pool (1, 2 and
//! all the machine's, without repeats) for every codec that decodes in parallel through core's
//! `ThreadPool`: OpenEXR (chunks of ZIP and PIZ), BC6H (block rows), JPEG XR (tiles, here
//! 512x512), the `.hdrc` container (tiles, here 512x512 of raw half floats) and the gain-map JPEG
//! (the map's application). Each file is encoded once, outside the timing, from the project's
//! large generated photograph (2048x1536, half-precision samples, `corpus::large_photo`); every
//! pool must give the samples of one thread. Criterion's throughput is in pixels (elements), so
//! Melem/s = MP/s; quote ratios between thread counts of one run (`cargo bench -p
//! hdrcodec-tests --bench scaling`).
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput};
use hdrcodec_core::{DecodeOptions, EncodeSettings, Limits, ThreadPool};
use std::hint::black_box;
use std::time::Duration;

/// The codecs and settings whose decoders use the pool: label, codec name, settings.
fn configurations() -> Vec<(&'static str, &'static str, EncodeSettings)> {
    let opts = |kv: &[(&str, &str)]| kv.iter().fold(EncodeSettings::default(), |s, (k, v)| s.with_option(*k, *v));
    vec![
        ("exr-zip-half", "exr", opts(&[("compression", "zip"), ("pixel", "half")])),
        ("exr-piz-half", "exr", opts(&[("compression", "piz"), ("pixel", "half")])),
        ("bc6h-effort0", "bc6h", EncodeSettings::default().with_effort(0)),
        ("jxr-q50-tile512", "jxr", opts(&[("tile", "512")]).with_quality(50)),
        ("hdrc-raw-f16-tile512", "hdrc", opts(&[("payload", "raw-f16"), ("tile", "512")])),
        ("ultrahdr-q85", "ultrahdr", EncodeSettings::default().with_quality(85)),
    ]
}

/// 1, 2 and every thread of the machine, each once.
fn thread_counts() -> Vec<usize> {
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut counts = vec![1, 2, all];
    counts.sort_unstable();
    counts.dedup();
    counts
}

fn scaling(c: &mut Criterion) {
    let image = hdrcodec_cli::corpus::large_photo(2048, 1536);
    let registry = hdrcodec::registry();
    let pools: Vec<(usize, DecodeOptions)> = thread_counts()
        .into_iter()
        .map(|n| (n, DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(n).expect("a pool"))))
        .collect();
    for (label, name, settings) in configurations() {
        let codec = registry.by_name(name).expect("the codec is built in");
        let (data, _) = hdrcodec::encode_for(codec.as_ref(), &image, &settings).expect("encode");
        let one = codec.decode_with(&data, &pools[0].1).expect("decode on one thread");
        for (n, options) in &pools[1..] {
            let many = codec.decode_with(&data, options).expect("decode on a pool");
            assert_eq!(many.samples(), one.samples(), "{label}: {n} threads differ from one");
        }
        let mut group = c.benchmark_group(format!("scaling/{label}"));
        group.sampling_mode(SamplingMode::Flat);
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(3));
        group.throughput(Throughput::Elements(image.pixel_count() as u64));
        for (n, options) in &pools {
            group.bench_with_input(BenchmarkId::new("threads", n), options, |b, options| {
                b.iter(|| codec.decode_with(black_box(&data), options).expect("decode"))
            });
        }
        group.finish();
    }
}

criterion_group!(benches, scaling);
criterion_main!(benches);
