//! Times the encoder on the image of a `.jxr` file: `jxr_encode IN.jxr [QUALITY]`, with
//! `JXR_TIMES` (runs, the best is printed) and `JXR_THREADS` (a pool, tiles of 1024 pixels).
use hdrcodec_core::{ImageCodec, Limits, ThreadPool};
use hdrcodec_jxr::encoder::{encode, EncodeOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = args.next().ok_or("usage: jxr_encode IN.jxr [QUALITY]")?;
    let quality: u8 = args.next().map_or(Ok(90), |q| q.parse())?;
    let image = hdrcodec_jxr::JxrCodec.decode(&std::fs::read(input)?, &Limits::default())?;
    let threads: usize = std::env::var("JXR_THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let pool = ThreadPool::new(threads)?;
    let tile_mbs = if threads > 1 { 64 } else { 0 };
    let options = EncodeOptions { quality, tile_mbs, ..EncodeOptions::default() };
    let mut best = std::time::Duration::MAX;
    let mut size = 0;
    for _ in 0..std::env::var("JXR_TIMES").ok().and_then(|v| v.parse().ok()).unwrap_or(1) {
        let t = std::time::Instant::now();
        size = encode(&image, &options, &pool)?.0.len();
        best = best.min(t.elapsed());
    }
    eprintln!("encoded {} bytes in {best:?} (best)", size);
    Ok(())
}
