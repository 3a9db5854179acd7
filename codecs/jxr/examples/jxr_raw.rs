//! Writes the raw output samples (jxrlib's pixel-format bytes) of a `.jxr` file to a file, or
//! with `JXR_F32` set the codec's linear f32 samples (with `JXR_STREAM` also set, decoded from
//! the open file, read as it decodes, instead of from its bytes in memory); `JXR_TIMES` and
//! `JXR_THREADS` time it.
use hdrcodec_core::{DecodeOptions, Limits};
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let (input, output) = (args.next().ok_or("usage: jxr_raw IN.jxr OUT.raw")?, args.next().ok_or("OUT.raw")?);
    let path = input;
    let file = std::fs::read(&path)?;
    let threads: usize = std::env::var("JXR_THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let options = DecodeOptions::new(Limits::default()).with_pool(hdrcodec_core::ThreadPool::new(threads)?);
    let mut best = std::time::Duration::MAX;
    let mut raw = Vec::new();
    for _ in 0..std::env::var("JXR_TIMES").ok().and_then(|v| v.parse().ok()).unwrap_or(1) {
        let t = std::time::Instant::now();
        if std::env::var_os("JXR_F32").is_some() && std::env::var_os("JXR_STREAM").is_some() {
            use hdrcodec_core::ImageCodec;
            let mut input = std::fs::File::open(&path)?;
            let image = hdrcodec_jxr::JxrCodec.decode_from(&mut input, &options)?;
            raw = image.samples().iter().flat_map(|v| v.to_le_bytes()).collect();
        } else if std::env::var_os("JXR_F32").is_some() {
            // The codec's own path: linear f32 rows into an image.
            use hdrcodec_core::ImageCodec;
            let image = hdrcodec_jxr::JxrCodec.decode_with(&file, &options)?;
            raw = image.samples().iter().flat_map(|v| v.to_le_bytes()).collect();
        } else {
            // Into a buffer allocated once, as the bench does (no page faults in the timing).
            let (_, height, row) = hdrcodec_jxr::raw_layout(&file)?;
            raw.resize(height as usize * row, 0);
            hdrcodec_jxr::decode_raw_into(&file, &options, &mut raw, row)?;
        }
        best = best.min(t.elapsed());
    }
    eprintln!("decoded in {best:?} (best)");
    std::fs::write(output, raw)?;
    Ok(())
}
