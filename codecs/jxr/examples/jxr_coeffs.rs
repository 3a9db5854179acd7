//! Prints the dequantized, predicted coefficients of a `.jxr` file, one macroblock channel per
//! line: `L plane y x ch DC LP1..LP15` and `H plane y x ch block HP1..HP15` (the text the
//! project's instrumented build of T.835 prints, for comparing the two decoders).

use hdrcodec_core::{DecodeOptions, Limits};
use hdrcodec_jxr::container::parse_container;
use hdrcodec_jxr::{decode_coefficients, PlaneCoeffs};
use std::io::Write;

fn dump(out: &mut impl Write, plane: usize, p: &PlaneCoeffs) -> std::io::Result<()> {
    for y in 0..p.mb_height() {
        for x in 0..p.mb_width() {
            for ch in 0..p.channels {
                let c = p.mb(ch, x, y);
                write!(out, "L {plane} {y} {x} {ch}")?;
                for v in &c[..16] {
                    write!(out, " {v}")?;
                }
                writeln!(out)?;
                for b in 0..16 {
                    write!(out, "H {plane} {y} {x} {ch} {b}")?;
                    for v in &c[16 + 15 * b..31 + 15 * b] {
                        write!(out, " {v}")?;
                    }
                    writeln!(out)?;
                }
            }
        }
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: jxr_coeffs FILE.jxr")?;
    let file = std::fs::read(path)?;
    let container = parse_container(&file)?;
    // JXR_TIMES=n: time n decodes (the best one) and print nothing else.
    let times: usize = std::env::var("JXR_TIMES").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    let threads: usize = std::env::var("JXR_THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let options = DecodeOptions::new(Limits::default()).with_pool(hdrcodec_core::ThreadPool::new(threads)?);
    if times > 0 {
        let mut best = std::time::Duration::MAX;
        for _ in 0..times {
            let t = std::time::Instant::now();
            let c = decode_coefficients(container.image, &options)?;
            best = best.min(t.elapsed());
            std::hint::black_box(c);
        }
        let h = hdrcodec_jxr::header::parse(container.image)?.image;
        println!(
            "entropy decoding: best of {times}: {best:?} ({}x{} tiles)",
            h.tile_widths.len(),
            h.tile_heights.len()
        );
        return Ok(());
    }
    let c = decode_coefficients(container.image, &options)?;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    dump(&mut out, 0, &c.primary)?;
    if let Some(a) = &c.alpha {
        dump(&mut out, 1, a)?;
    }
    if let Some(alpha) = container.alpha {
        // A planar alpha codestream: plane 2.
        let a = decode_coefficients(alpha, &DecodeOptions::new(Limits::default()))?;
        dump(&mut out, 2, &a.primary)?;
    }
    Ok(())
}
