//! Mantiuk (L_p u'v' in 12- and 10-bit AV1) against HDR10 (PQ, 10-bit 4:2:0) at equal bitrate, issue 14:
//! rav1e quantizer sweeps of both on the same frames, PU21-PSNR and ΔE ITP per frame, and each
//! HDR10 point compared with the L_p u'v' curve interpolated (in log bytes) at the same size.
//!
//! `cargo run -j1 -p hdrcodec-tests --example mantiuk_vs_hdr10 [CORPUS_DIR]` (default
//! `../shared/corpus`). Sequences: the generated moving light, a fade and a pan over a crop of a
//! corpus photograph (`sequences`), 8 frames of 160x96 each, rav1e speed 6, one thread.
//! With `MAPPINGS=1` it also sweeps other u'v' plane mappings (the luma:chroma step ratio) and
//! version 1 planes (codes as they are).

use hdrcodec_core::metrics::{delta_e_itp, pu21_psnr};
use hdrcodec_core::{Channels, ColorInfo, HdrImage, ImageCodec, Limits};
use hdrcodec_video::decode::{decode_ivf, Av1DecodeOptions};
use hdrcodec_video::encode::{encode_sequence, Av1Options};
use hdrcodec_video::hdr10::Subsampling;
use hdrcodec_video::lpuv_av1::{LpuvPlaneMapping, LpuvStreamInfo};
use hdrcodec_video::sequences::{fade_frame, moving_light_frame, pan_frame};

const W: u32 = 160;
const H: u32 = 96;
const FRAMES: u32 = 8;

/// A centred `w` x `h` crop of a corpus EXR (our decode), 1.0 = 203 cd/m².
fn corpus_crop(path: &std::path::Path, w: u32, h: u32) -> HdrImage {
    let data = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let full = hdrcodec_exr::ExrCodec.decode(&data, &Limits::default()).unwrap();
    let n = full.channels().count();
    let (fw, x0, y0) = (full.width() as usize, (full.width() - w) as usize / 2, (full.height() - h) as usize / 2);
    let mut samples = Vec::with_capacity((w * h * 3) as usize);
    for y in y0..y0 + h as usize {
        let row = &full.samples()[(y * fw + x0) * n..(y * fw + x0 + w as usize) * n];
        samples.extend(row.chunks_exact(n).flat_map(|p| [p[0], p[1], p[2]]));
    }
    let color = ColorInfo { primaries: full.color.primaries, nits_per_unit: 203.0, hdr10: None };
    HdrImage::new(w, h, Channels::Rgb, samples, color).unwrap()
}

/// One encode: bytes, PU21-PSNR per frame, mean ΔE ITP per frame.
struct Point {
    quantizer: u8,
    bytes: usize,
    pu21: Vec<f64>,
    de: Vec<f64>,
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn run(frames: &[HdrImage], options: &Av1Options) -> Point {
    let (_, ivf) = encode_sequence(frames, options, Vec::new()).unwrap();
    let decoded = decode_ivf(&ivf, &Av1DecodeOptions::default()).unwrap();
    let pu21 = frames.iter().zip(&decoded).map(|(a, b)| pu21_psnr(a, b).unwrap()).collect();
    let de = frames.iter().zip(&decoded).map(|(a, b)| delta_e_itp(a, b).unwrap().0).collect();
    Point { quantizer: options.quantizer, bytes: ivf.len(), pu21, de }
}

/// `f` of the curve `points` (sorted by bytes) at `bytes`, linear in log bytes; None outside.
fn at_bytes(points: &[Point], bytes: usize, f: impl Fn(&Point) -> f64) -> Option<f64> {
    let x = (bytes as f64).ln();
    points.windows(2).find_map(|w| {
        let (x0, x1) = ((w[0].bytes as f64).ln(), (w[1].bytes as f64).ln());
        (x0 <= x && x <= x1 && x1 > x0).then(|| f(&w[0]) + (f(&w[1]) - f(&w[0])) * (x - x0) / (x1 - x0))
    })
}

fn main() {
    let corpus = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "../shared/corpus".into()));
    let photo = corpus_crop(&corpus.join("exr/MtTamWest.exr"), 480, 288);
    let still = corpus_crop(&corpus.join("exr/GoldenGate.exr"), W, H);
    let sequences: Vec<(&str, Vec<HdrImage>)> = vec![
        ("moving light (4000 cd/m²)", (0..FRAMES).map(|t| moving_light_frame(W, H, 4000.0, 10.0, t, FRAMES)).collect()),
        ("fade of GoldenGate crop", (0..FRAMES).map(|t| fade_frame(&still, t + 1, FRAMES + 1)).collect()),
        ("pan over MtTamWest crop", (0..FRAMES).map(|t| pan_frame(&photo, W, H, t, FRAMES).unwrap()).collect()),
    ];
    let hdr10 = |q: u8| Av1Options { speed: 6, quantizer: q, ..Av1Options::default() };
    let bt2020 = hdrcodec_core::ColorPrimaries::Bt2020;
    let lpuv_info =
        move |mapping: LpuvPlaneMapping| LpuvStreamInfo { mapping, ..LpuvStreamInfo::for_primaries(bt2020) };
    let lpuv = move |q: u8, info: LpuvStreamInfo, subsampling| Av1Options {
        speed: 6,
        quantizer: q,
        low_latency: true,
        subsampling,
        lpuv: Some(info),
        ..Av1Options::default()
    };
    for (name, frames) in &sequences {
        println!("\n## {name}: {FRAMES} frames of {W}x{H}, rav1e speed 6");
        println!("| planes | q | bytes | PU21-PSNR mean / worst frame dB | mean ΔE ITP mean / worst frame |");
        println!("|---|---|---|---|---|");
        let mut curves: Vec<(&str, Vec<Point>)> = Vec::new();
        type Make = Box<dyn Fn(u8) -> Av1Options>;
        let qs: &[u8] = &[10, 20, 40, 60, 90, 120];
        let ratio = |uv_top| LpuvPlaneMapping { plane_bits: 12, luma_top: 4095, uv_top };
        let mut variants: Vec<(String, &[u8], Make)> = vec![
            ("HDR10 PQ 4:2:0".into(), &[10u8, 30, 50, 70, 90, 110, 140][..], Box::new(hdr10) as Make),
            (
                "L_p u'v' 12-bit 4:4:4 (Y ×2, u'v' ×4)".into(),
                qs,
                Box::new(move |q| lpuv(q, lpuv_info(LpuvPlaneMapping::default()), Subsampling::Yuv444)) as Make,
            ),
            (
                "L_p u'v' 12-bit 4:2:0 (Y ×2, u'v' ×4)".into(),
                qs,
                Box::new(move |q| lpuv(q, lpuv_info(LpuvPlaneMapping::default()), Subsampling::Yuv420)) as Make,
            ),
            (
                "L_p u'v' 10-bit 4:2:0, Main (10-bit ψ, u'v' ×1)".into(),
                qs,
                Box::new(move |q| lpuv(q, LpuvStreamInfo::main10(bt2020), Subsampling::Yuv420)) as Make,
            ),
            (
                "L_p u'v' 10-bit 4:4:4, High (10-bit ψ, u'v' ×1)".into(),
                qs,
                Box::new(move |q| lpuv(q, LpuvStreamInfo::main10(bt2020), Subsampling::Yuv444)) as Make,
            ),
        ];
        // The luma:chroma step ratio, the one thing a plane mapping changes at equal bytes.
        if std::env::var_os("MAPPINGS").is_some() {
            variants.push((
                "L_p u'v' 4:4:4, codes as they are (version 1)".into(),
                &[0, 5, 10, 20, 40, 60][..],
                Box::new(move |q| lpuv(q, lpuv_info(LpuvPlaneMapping::codes(11)), Subsampling::Yuv444)) as Make,
            ));
            for uv_top in [510u16, 1020] {
                let mapping = LpuvPlaneMapping { uv_top, ..LpuvPlaneMapping::main10() };
                let info = LpuvStreamInfo { mapping, ..LpuvStreamInfo::main10(bt2020) };
                let make: Make = Box::new(move |q| lpuv(q, info, Subsampling::Yuv420));
                variants.push((format!("L_p u'v' 10-bit 4:2:0, Main, u'v' top {uv_top}"), qs, make));
            }
            for uv_top in [255u16, 510, 2040, 4095] {
                let make: Make = Box::new(move |q| lpuv(q, lpuv_info(ratio(uv_top)), Subsampling::Yuv444));
                variants.push((format!("L_p u'v' 4:4:4, Y top 4095, u'v' top {uv_top}"), qs, make));
            }
        }
        // `ONLY=text`: HDR10 and the variants whose label contains the text.
        let only = std::env::var("ONLY").ok();
        variants.retain(|(label, _, _)| label.starts_with("HDR10") || only.as_ref().is_none_or(|o| label.contains(o)));
        for (label, qs, make) in &variants {
            let label = label.as_str();
            let mut points: Vec<Point> = qs.iter().map(|&q| run(frames, &make(q))).collect();
            for p in &points {
                let worst_pu = p.pu21.iter().copied().fold(f64::INFINITY, f64::min);
                let worst_de = p.de.iter().copied().fold(0.0, f64::max);
                println!(
                    "| {label} | {} | {} | {:.1} / {worst_pu:.1} | {:.2} / {worst_de:.2} |",
                    p.quantizer,
                    p.bytes,
                    mean(&p.pu21),
                    mean(&p.de)
                );
            }
            points.sort_by_key(|p| p.bytes);
            curves.push((label, points));
        }
        for (label, points) in &curves[1..] {
            println!("\n{label} at HDR10's sizes (interpolated in log bytes): ΔPU21-PSNR (L_p u'v' − HDR10), ΔE ITP (L_p u'v' − HDR10)");
            for h in &curves[0].1 {
                let pu = at_bytes(points, h.bytes, |p| mean(&p.pu21));
                let de = at_bytes(points, h.bytes, |p| mean(&p.de));
                if let (Some(pu), Some(de)) = (pu, de) {
                    println!(
                        "  {} bytes (HDR10 q{}): {:+.2} dB, {:+.2}",
                        h.bytes,
                        h.quantizer,
                        pu - mean(&h.pu21),
                        de - mean(&h.de)
                    );
                }
            }
        }
    }
}
