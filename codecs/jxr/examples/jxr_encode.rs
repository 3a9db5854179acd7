//! Times the encoder on the image of a `.jxr` file: `jxr_encode IN.jxr [QUALITY]`, with
//! `JXR_TIMES` (runs, the best is printed; 0 decodes only, for instruction counts of the
//! encode alone by difference), `JXR_THREADS` (a pool, tiles of 1024 pixels), `JXR_ADAPTIVE=0`
//! (one HP quantizer, as the criterion bench) and `JXR_OUT` (writes the file there).
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
    let adaptive = std::env::var("JXR_ADAPTIVE").map_or(true, |v| v != "0");
    let options = EncodeOptions { quality, tile_mbs, adaptive, ..EncodeOptions::default() };
    let mut best = std::time::Duration::MAX;
    let mut file = Vec::new();
    for _ in 0..std::env::var("JXR_TIMES").ok().and_then(|v| v.parse().ok()).unwrap_or(1) {
        let t = std::time::Instant::now();
        file = encode(&image, &options, &pool)?.0;
        best = best.min(t.elapsed());
    }
    if let Ok(out) = std::env::var("JXR_OUT") {
        std::fs::write(out, &file)?;
    }
    eprintln!("encoded {} bytes in {best:?} (best)", file.len());
    Ok(())
}
