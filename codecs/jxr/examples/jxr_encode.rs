//! Times the encoder on the image of a `.jxr` file: `jxr_encode IN.jxr [QUALITY [KEY=VALUE...]]`
//! (the `--opt` options of `EncodeOptions::from_settings`, e.g. `qp=97,118,120,109,137,144
//! order=frequency overlap=2` for JxrEncApp's settings at `-q 0.3`), with
//! `JXR_TIMES` (runs, the best is printed; 0 decodes only, for instruction counts of the
//! encode alone by difference), `JXR_THREADS` (a pool, tiles of 1024 pixels), `JXR_ADAPTIVE=0`
//! (one HP quantizer, as the criterion bench), `JXR_QP_FROM` (a `.jxr` file whose quantizers
//! are used, `Quantizers::of_file`: jxrlib's, for equal settings) and `JXR_OUT` (writes the
//! file there).
use hdrcodec_core::{EncodeSettings, ImageCodec, Limits, ThreadPool};
use hdrcodec_jxr::encoder::{encode, EncodeOptions, Quantizers};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = args.next().ok_or("usage: jxr_encode IN.jxr [QUALITY [KEY=VALUE...]]")?;
    let quality: u8 = args.next().map_or(Ok(90), |q| q.parse())?;
    let mut settings = EncodeSettings::default().with_quality(quality);
    for kv in args {
        let (k, v) = kv.split_once('=').ok_or_else(|| format!("{kv}: expected KEY=VALUE"))?;
        settings = settings.with_option(k, v);
    }
    let image = hdrcodec_jxr::JxrCodec.decode(&std::fs::read(input)?, &Limits::default())?;
    let threads: usize = std::env::var("JXR_THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let pool = ThreadPool::new(threads)?;
    let tile_mbs = if threads > 1 { 64 } else { 0 };
    let adaptive = std::env::var("JXR_ADAPTIVE").map_or(true, |v| v != "0");
    let mut options = EncodeOptions { tile_mbs, adaptive, ..EncodeOptions::from_settings(&settings)? };
    if let Ok(path) = std::env::var("JXR_QP_FROM") {
        let quantizers = Quantizers::of_file(&std::fs::read(&path)?)?;
        options.quantizers = Some(quantizers.ok_or_else(|| format!("{path}: no uniform quantizers"))?);
    }
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
