//! `hdrcodec bench --video`: HDR10 AV1 rows. Ours (hdrcodec-video: rav1e to encode, the system
//! libdav1d to decode) against FFmpeg's SVT-AV1 ([`crate::peers::svtav1`]) on the same frames,
//! at a few quantizers each so that sizes can be matched.
//!
//! The sequences ([`sequences`]): a light moving over a dim scene (codecs/video's generator) and
//! a pan across a crop of the largest bench image (a corpus photograph when the bench runs on
//! the real corpus). Both encoders see the same Y'CbCr (our conversion: BT.2020, PQ, 10-bit
//! limited range, 4:2:0) and run on one thread; our decoder reads both streams, so bytes and
//! quality (PU21-PSNR and ΔE ITP of each decoded frame against the linear source frame, means
//! over the frames) compare the encoders alone. FFmpeg's libdav1d decoding each stream is the
//! peer decode, whose 10-bit planes must equal ours.

use crate::bench::{self, Input};
use crate::equal_quality;
use crate::jxrlib::{self, TempDir};
use crate::peers::svtav1;
use hdrcodec::core::{metrics, ColorPrimaries, Error, HdrImage, Result, ThreadPool};
use hdrcodec_video::decode::{decode_ivf, probe_ivf, Av1DecodeOptions, Av1Decoder};
use hdrcodec_video::encode::{encode_sequence, Av1Options};
use hdrcodec_video::hdr10::{content_light_level, Transfer};
use hdrcodec_video::sequences::{moving_light_frame, pan_frame};
use serde::Serialize;
use std::ffi::{OsStr, OsString};
use std::path::Path;
use std::time::Duration;

/// rav1e as hdrcodec-video links it (its version from Cargo.lock, checked by a test).
pub const RAV1E: &str = "rav1e 0.8.1";

/// Frames per second of the sequences (the streams' time base).
const FPS: u32 = 25;

/// A sequence of frames to encode.
#[derive(Clone, Debug)]
pub struct Sequence {
    /// "moving-light", or "pan:IMAGE".
    pub name: String,
    /// Scene-linear frames, all of one size.
    pub frames: Vec<HdrImage>,
}

/// The sequences of a run: the moving light (128x72, 4 frames with `quick`; 256x144, 12
/// frames otherwise; `size` when given) and a pan across the largest of `inputs` (a window of
/// at most half its size, and at most 128x72, 320x176 or `size`, widths and heights in
/// multiples of 8; none when that is smaller than 64x64). A pan source that records no
/// primaries is taken as BT.709.
pub fn sequences(inputs: &[Input], quick: bool, size: Option<(u32, u32)>) -> Result<Vec<Sequence>> {
    let (w, h, frames) = if quick { (128, 72, 4) } else { (256, 144, 12) };
    let (w, h) = size.unwrap_or((w, h));
    let light = (0..frames).map(|t| moving_light_frame(w, h, 4000.0, h as f32 / 6.0, t, frames)).collect();
    let mut out = vec![Sequence { name: "moving-light".into(), frames: light }];
    let (max_w, max_h) = size.unwrap_or(if quick { (128, 72) } else { (320, 176) });
    if let Some(largest) = inputs.iter().max_by_key(|i| i.image.pixel_count()) {
        let (pw, ph) =
            ((largest.image.width() / 2).min(max_w) / 8 * 8, (largest.image.height() / 2).min(max_h) / 8 * 8);
        if pw >= 64 && ph >= 64 {
            let mut source = largest.image.clone();
            if !source.color.primaries.is_specified() {
                source.color.primaries = ColorPrimaries::Bt709;
            }
            let frames = (0..frames).map(|t| pan_frame(&source, pw, ph, t, frames)).collect::<Result<_>>()?;
            out.push(Sequence { name: format!("pan:{}", largest.name), frames });
        }
    }
    Ok(out)
}

/// Who encodes a video row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VideoEncoder {
    /// hdrcodec-video (rav1e) at this base quantizer (0-255), speed 6, one thread.
    Ours(u8),
    /// FFmpeg's SVT-AV1 at this CRF (0-63; about a quarter of the quantizer index),
    /// preset [`svtav1::PRESET`], one thread.
    SvtAv1(u8),
}

/// One video configuration.
#[derive(Clone, Debug)]
pub struct VideoConfig {
    /// Row label: `av1:qN` or `av1(svt-av1):crfN`.
    pub label: String,
    /// Who encodes.
    pub encoder: VideoEncoder,
}

/// Our quantizers and SVT-AV1's CRFs: CRF N aims near quantizer index 4N, so the two sweeps
/// cover the same sizes.
const SWEEP: [(u8, u8); 4] = [(60, 15), (100, 25), (140, 35), (180, 45)];

/// Every video configuration: ours, then SVT-AV1's, over [`SWEEP`].
pub fn configurations() -> Vec<VideoConfig> {
    let ours = SWEEP.map(|(q, _)| VideoConfig { label: format!("av1:q{q}"), encoder: VideoEncoder::Ours(q) });
    let svt =
        SWEEP.map(|(_, c)| VideoConfig { label: format!("av1(svt-av1):crf{c}"), encoder: VideoEncoder::SvtAv1(c) });
    ours.into_iter().chain(svt).collect()
}

/// FFmpeg's libdav1d decoding a row's stream.
#[derive(Clone, Debug, Serialize)]
pub struct VideoPeer {
    /// "ffmpeg 5.1.9 -c:v libdav1d (outside program)".
    pub decoder: String,
    /// Frames per second (the process's wall time: start and raw output included).
    pub decode_fps: f64,
    /// Whether its 10-bit planes equal our decoder's, code for code (`false` is a bug of ours).
    pub matches: bool,
}

/// One configuration on one sequence.
#[derive(Clone, Debug, Serialize)]
pub struct VideoRow {
    /// The configuration label.
    pub config: String,
    /// The sequence name.
    pub sequence: String,
    /// Frames.
    pub frames: usize,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Bytes of the IVF file.
    pub bytes: usize,
    /// Bits per pixel (all frames).
    pub bpp: f64,
    /// Mean over the frames of PU21-PSNR (luminance), dB.
    pub pu21_psnr: f64,
    /// Mean over the frames of the mean ΔE ITP.
    pub de_itp_mean: f64,
    /// Mean over the frames of the 99th percentile of ΔE ITP.
    pub de_itp_p99: f64,
    /// Encoded frames per second (median run; for SVT-AV1 FFmpeg's wall time, reading the raw
    /// input and process start included).
    pub encode_fps: f64,
    /// Frames per second of our decoder (libdav1d, then Y'CbCr to linear RGB), median run.
    pub decode_fps: f64,
    /// Who encoded, with what.
    pub encoder: String,
    /// Who decoded for the figures.
    pub decoder: String,
    /// What the stream signals (colour description, range, chroma position, HDR10 metadata).
    pub signalled: String,
    /// FFmpeg's decode of the same stream.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer: Option<VideoPeer>,
    /// What the run noticed (clipping, no peer decode).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Why the row failed ("not installed: ..."), if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Frames per second of `frames` frames in `t`.
fn fps(frames: usize, t: Duration) -> f64 {
    frames as f64 / t.as_secs_f64().max(1e-9)
}

/// Runs every configuration on every sequence (`runs` timed runs at most, as `bench`), calling
/// `progress` after each row.
pub fn run(
    configs: &[VideoConfig],
    sequences: &[Sequence],
    runs: usize,
    mut progress: impl FnMut(&str),
) -> Vec<VideoRow> {
    let mut rows = Vec::new();
    for c in configs {
        for s in sequences {
            rows.push(measure(c, s, runs));
            progress(&c.label);
        }
    }
    rows
}

/// One row.
fn measure(config: &VideoConfig, sequence: &Sequence, runs: usize) -> VideoRow {
    let first = &sequence.frames[0];
    let mut row = VideoRow {
        config: config.label.clone(),
        sequence: sequence.name.clone(),
        frames: sequence.frames.len(),
        width: first.width(),
        height: first.height(),
        bytes: 0,
        bpp: 0.0,
        pu21_psnr: 0.0,
        de_itp_mean: 0.0,
        de_itp_p99: 0.0,
        encode_fps: 0.0,
        decode_fps: 0.0,
        encoder: String::new(),
        decoder: "hdrcodec-video (system libdav1d through the dav1d crate, one thread)".into(),
        signalled: String::new(),
        peer: None,
        notes: Vec::new(),
        error: None,
    };
    let ffmpeg = jxrlib::tool(svtav1::PROGRAM);
    // FFmpeg with SVT-AV1 and libdav1d, or why not.
    let peer = match (&ffmpeg, svtav1::missing_codecs()) {
        (None, _) => Err(format!("{} ({}) is not on PATH", svtav1::PROGRAM, svtav1::PACKAGE)),
        (Some(_), Some(missing)) => Err(format!("the {} on PATH has no {missing}", svtav1::PROGRAM)),
        (Some(f), None) => Ok(f.as_path()),
    };
    let encoded = match (config.encoder, &peer) {
        (VideoEncoder::Ours(q), _) => encode_ours(q, sequence, runs, &mut row),
        (VideoEncoder::SvtAv1(crf), Ok(f)) => encode_svt(f, crf, sequence, runs, &mut row),
        (VideoEncoder::SvtAv1(_), Err(why)) => {
            row.error = Some(format!("{}: {why}", bench::NOT_INSTALLED));
            return row;
        }
    };
    let result = encoded.and_then(|(bytes, dir)| {
        score(&bytes, sequence, runs, &mut row)?;
        let note = match peer.map(|f| peer_decode(f, &bytes, &dir, sequence, runs)) {
            Ok(Ok(p)) => {
                let differs = (!p.matches).then(|| {
                    format!(
                        "{} on {}: our decoded planes DIFFER from FFmpeg's libdav1d (a bug of ours)",
                        row.config, row.sequence
                    )
                });
                row.peer = Some(p);
                differs
            }
            Ok(Err(e)) => Some(format!("{} on {}: no peer decode: {e}", row.config, row.sequence)),
            Err(why) => Some(format!("no peer decode of the video rows: {why}")),
        };
        row.notes.extend(note);
        Ok(())
    });
    if let Err(e) = result {
        row.error = Some(e.to_string());
    }
    row
}

/// Our encoder at quantizer `q`: the IVF bytes and a temporary directory for the peer decode.
fn encode_ours(q: u8, sequence: &Sequence, runs: usize, row: &mut VideoRow) -> Result<(Vec<u8>, TempDir)> {
    let options = Av1Options { quantizer: q, fps: FPS, pool: ThreadPool::single(), ..Av1Options::default() };
    let (t, (summary, bytes)) = bench::timed(runs, || encode_sequence(&sequence.frames, &options, Vec::new()))?;
    row.encode_fps = fps(sequence.frames.len(), t);
    row.encoder = format!(
        "hdrcodec-video ({RAV1E} at the labelled quantizer, speed {}, one thread; BT.2020 PQ 10-bit 4:2:0 limited)",
        options.speed
    );
    let clipped = summary.clipped;
    if !clipped.is_empty() {
        row.notes.push(format!(
            "{}: {} NaN, {} negative and {} above-peak components clipped by the PQ policy before coding (both encoders \
             code the same clipped values)",
            row.sequence, clipped.nan, clipped.negative, clipped.above_peak
        ));
    }
    Ok((bytes, TempDir::new("bench-av1")?))
}

/// FFmpeg's SVT-AV1 at `crf` on our Y'CbCr of the frames, HDR10 signalled with our encoder's
/// mastering display and the frames' MaxCLL/MaxFALL.
fn encode_svt(
    ffmpeg: &Path,
    crf: u8,
    sequence: &Sequence,
    runs: usize,
    row: &mut VideoRow,
) -> Result<(Vec<u8>, TempDir)> {
    let dir = TempDir::new("bench-svtav1")?;
    let (yuv, ivf) = (dir.path().join("in.yuv"), dir.path().join("out.ivf"));
    let (raw, _) = svtav1::raw_yuv(&sequence.frames);
    std::fs::write(&yuv, raw)?;
    let md = Av1Options::default().mastering_display;
    let cll = content_light_level(&sequence.frames, Transfer::Pq);
    let size = (row.width, row.height, FPS);
    let args = svtav1::encode_args(&yuv, &ivf, size, crf, &md, cll);
    let args: Vec<&OsStr> = args.iter().map(OsString::as_os_str).collect();
    let (t, (_, stderr)) = bench::timed(runs, || jxrlib::run_with_stderr(ffmpeg, &args, &ivf))?;
    row.encode_fps = fps(sequence.frames.len(), t);
    let svt = svtav1::svt_version(&stderr).unwrap_or_else(|| "(version unknown)".into());
    row.encoder = format!(
        "{} -c:v {} (SVT-AV1 {svt} at the labelled CRF, preset {}, lp=1; outside program) on our 10-bit PQ 4:2:0 planes",
        svtav1::ffmpeg_version(),
        svtav1::ENCODER,
        svtav1::PRESET
    );
    Ok((std::fs::read(&ivf)?, dir))
}

/// The row's size, what the stream signals, our decode's speed and its quality against the
/// source frames.
fn score(bytes: &[u8], sequence: &Sequence, runs: usize, row: &mut VideoRow) -> Result<()> {
    let options = Av1DecodeOptions::default();
    let (_, summary) = probe_ivf(bytes, &options.limits)?;
    row.signalled = signalled(&summary);
    let (t, decoded) = bench::timed(runs, || decode_ivf(bytes, &options))?;
    if decoded.len() != sequence.frames.len() {
        return Err(Error::invalid(format!("{} frames decoded of {}", decoded.len(), sequence.frames.len())));
    }
    let n = decoded.len() as f64;
    let (mut psnr, mut de, mut p99) = (0.0, 0.0, 0.0);
    for (source, back) in sequence.frames.iter().zip(&decoded) {
        let cmp = metrics::compare(source, back)?;
        psnr += cmp.pu21_psnr / n;
        de += cmp.de_itp_mean / n;
        p99 += cmp.de_itp_p99 / n;
    }
    let pixels = sequence.frames.iter().map(HdrImage::pixel_count).sum::<usize>();
    row.bytes = bytes.len();
    row.bpp = bytes.len() as f64 * 8.0 / pixels as f64;
    (row.pu21_psnr, row.de_itp_mean, row.de_itp_p99) = (psnr, de, p99);
    row.decode_fps = fps(decoded.len(), t);
    Ok(())
}

/// "cicp 9/16/9 limited, chroma colocated, MDCV 1000/0.0001 cd/m², CLL 4000/120".
fn signalled(summary: &hdrcodec_video::obu::StreamSummary) -> String {
    let Some(seq) = &summary.sequence_header else { return "no sequence header".into() };
    let c = &seq.color;
    let cicp = c.color_description.map_or_else(
        || "no colour description".to_string(),
        |d| format!("cicp {}/{}/{}", d.color_primaries, d.transfer_characteristics, d.matrix_coefficients),
    );
    let range = if c.full_range { "full" } else { "limited" };
    let position = match c.chroma_sample_position {
        hdrcodec_video::obu::chroma_sample_position::COLOCATED => "colocated",
        hdrcodec_video::obu::chroma_sample_position::VERTICAL => "vertical",
        _ => "unknown",
    };
    let md = summary.mastering_display.map_or_else(
        || "no MDCV".to_string(),
        |m| format!("MDCV {}/{:.4} cd/m²", f64::from(m.luminance_max) / 256.0, f64::from(m.luminance_min) / 16384.0),
    );
    let cll = summary.content_light.map_or_else(|| "no CLL".into(), |l| format!("CLL {}/{}", l.max_cll, l.max_fall));
    format!("{cicp} {range}, {}-bit, chroma {position}, {md}, {cll}", c.bit_depth)
}

/// FFmpeg's libdav1d decoding `bytes` (written to `dir`) to raw planes, timed, and compared
/// with our decoder's planes.
fn peer_decode(ffmpeg: &Path, bytes: &[u8], dir: &TempDir, sequence: &Sequence, runs: usize) -> Result<VideoPeer> {
    let (ivf, raw) = (dir.path().join("peer.ivf"), dir.path().join("peer.yuv"));
    std::fs::write(&ivf, bytes)?;
    let args = svtav1::decode_args(&ivf, &raw);
    let args: Vec<&OsStr> = args.iter().map(OsString::as_os_str).collect();
    let (t, _) = bench::timed(runs, || jxrlib::run(ffmpeg, &args, &raw))?;
    let theirs = std::fs::read(&raw)?;
    let first = &sequence.frames[0];
    let (w, h) = (first.width() as usize, first.height() as usize);
    svtav1::check_raw_size(&theirs, w, h, sequence.frames.len())?;
    let mut ours = Vec::with_capacity(theirs.len());
    let mut decoder = Av1Decoder::new(bytes, &Av1DecodeOptions::default())?;
    while let Some(planes) = decoder.next_planes()? {
        svtav1::push_planes(&planes, &mut ours);
    }
    Ok(VideoPeer {
        decoder: format!("{} -c:v {} (outside program)", svtav1::ffmpeg_version(), svtav1::DECODER),
        decode_fps: fps(sequence.frames.len(), t),
        matches: ours == theirs,
    })
}

/// Bytes of our rows against SVT-AV1's at equal PU21-PSNR, per sequence ([`equal_quality`]: each
/// of our points placed on SVT-AV1's curve of the same sequence); `None` without both sides.
pub fn equal_quality(rows: &[VideoRow]) -> Option<equal_quality::Comparison> {
    let as_rows: Vec<bench::Row> = rows
        .iter()
        .filter(|r| r.error.is_none())
        .map(|r| {
            let pixels = r.width as usize * r.height as usize * r.frames;
            let mut row = bench::Row::blank(r.config.clone(), r.sequence.clone(), pixels, false);
            (row.bytes, row.bpp, row.pu21_psnr) = (r.bytes, r.bpp, r.pu21_psnr);
            row
        })
        .collect();
    equal_quality::compare(&as_rows, "av1:", "av1(svt-av1):")
}

/// The rows as a plain-text table, then what each side did.
pub fn table(rows: &[VideoRow]) -> String {
    use crate::text_table::{Align, TextTable};
    let (l, r) = (Align::Left, Align::Right);
    let mut t = TextTable::new(&[
        ("video config", l),
        ("sequence", l),
        ("size", r),
        ("bytes", r),
        ("bpp", r),
        ("PU21-PSNR", r),
        ("dE-ITP", r),
        ("dE p99", r),
        ("enc fps", r),
        ("dec fps", r),
        ("peer dec", r),
    ]);
    for r in rows {
        if let Some(e) = &r.error {
            t.note_row(vec![r.config.clone(), r.sequence.clone()], e);
            continue;
        }
        let peer = r.peer.as_ref().map_or_else(|| "-".to_string(), |p| format!("{:.1}", p.decode_fps));
        let mark = if r.peer.as_ref().is_some_and(|p| !p.matches) { "  DIFFERS FROM PEER" } else { "" };
        let cells = vec![
            r.config.clone(),
            r.sequence.clone(),
            format!("{}x{}x{}", r.width, r.height, r.frames),
            r.bytes.to_string(),
            format!("{:.4}", r.bpp),
            format!("{:.2}", r.pu21_psnr),
            format!("{:.4}", r.de_itp_mean),
            format!("{:.3}", r.de_itp_p99),
            format!("{:.1}", r.encode_fps),
            format!("{:.1}", r.decode_fps),
            peer,
        ];
        t.row(cells, mark);
    }
    let mut s = t.render();
    let mut seen: Vec<&String> = Vec::new();
    for r in rows {
        for n in &r.notes {
            if !seen.contains(&n) {
                s.push_str(&format!("note: {n}\n"));
                seen.push(n);
            }
        }
    }
    for prefix in ["av1:", "av1(svt-av1)"] {
        if let Some(r) = rows.iter().find(|r| r.config.starts_with(prefix) && r.error.is_none()) {
            s.push_str(&format!(
                "{prefix} rows: encoded by {};\n  stream of the first row: {}\n",
                r.encoder, r.signalled
            ));
        }
    }
    if rows.iter().any(|r| r.error.is_none()) {
        s.push_str(
            "video rows: both encoders get the same 10-bit Y'CbCr; bytes are the IVF file; quality is our decoder's output \
             against the linear source frames\n  (means over the frames); enc and dec fps on one thread; peer dec is FFmpeg's \
             libdav1d on the same stream (process wall time),\n  whose planes must equal ours\n",
        );
    }
    if let Some(c) = equal_quality(rows) {
        s.push_str(&equal_quality::table(&[c]));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_named_rav1e_is_the_one_in_cargo_lock() {
        let lock = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../Cargo.lock")).unwrap();
        let version = lock.split("[[package]]").find_map(|p| {
            p.contains("name = \"rav1e\"\n").then(|| p.lines().find_map(|l| l.strip_prefix("version = \"")))?
        });
        assert_eq!(RAV1E, format!("rav1e {}", version.unwrap().trim_end_matches('"')));
    }

    #[test]
    fn our_points_are_placed_on_svt_av1s_curve() {
        let row = |config: &str, bytes: usize, pu21_psnr: f64| VideoRow {
            config: config.into(),
            sequence: "s".into(),
            frames: 1,
            width: 10,
            height: 10,
            bytes,
            bpp: bytes as f64 * 8.0 / 100.0,
            pu21_psnr,
            de_itp_mean: 1.0,
            de_itp_p99: 1.0,
            encode_fps: 1.0,
            decode_fps: 1.0,
            encoder: String::new(),
            decoder: String::new(),
            signalled: String::new(),
            peer: None,
            notes: Vec::new(),
            error: None,
        };
        let rows = [
            row("av1:q60", 2000, 44.0),
            row("av1:q100", 1000, 40.0),
            row("av1(svt-av1):crf15", 3000, 45.0),
            row("av1(svt-av1):crf25", 1500, 41.0),
        ];
        let c = equal_quality(&rows).unwrap();
        // 44 dB on SVT's curve: log bytes 3/4 of the way from 1500 to 3000, 1500·2^0.75; 40 dB
        // is below its range.
        assert_eq!((c.points.len(), c.out_of_range), (1, 1));
        assert!((c.geometric_mean - 2000.0 / (1500.0 * 2f64.powf(0.75))).abs() < 1e-9, "{}", c.geometric_mean);
        assert!(table(&rows).contains("bytes of av1: / bytes of av1(svt-av1): at equal PU21-PSNR"));
        assert!(equal_quality(&rows[..2]).is_none());
    }

    #[test]
    fn the_sequences_have_the_sizes_they_promise() {
        let color = hdrcodec::core::ColorInfo::default();
        let image = HdrImage::new(300, 150, hdrcodec::core::Channels::Rgb, vec![0.5; 300 * 150 * 3], color).unwrap();
        let small =
            HdrImage::new(100, 100, hdrcodec::core::Channels::Rgb, vec![0.5; 100 * 100 * 3], image.color.clone())
                .unwrap();
        let inputs = [Input { name: "small".into(), image: small }, Input { name: "big".into(), image }];
        let seqs = sequences(&inputs, true, None).unwrap();
        let sizes: Vec<(String, u32, u32, usize)> =
            seqs.iter().map(|s| (s.name.clone(), s.frames[0].width(), s.frames[0].height(), s.frames.len())).collect();
        assert_eq!(sizes, [("moving-light".into(), 128, 72, 4), ("pan:big".into(), 128, 72, 4)]);
        // Half of 100x100 is below 64x64 once rounded to multiples of 8: no pan.
        assert_eq!(sequences(&inputs[..1], false, None).unwrap().len(), 1);
        // A size given: the light at that size, the pan's window within half the image.
        let seqs = sequences(&inputs, true, Some((192, 96))).unwrap();
        let sizes: Vec<(u32, u32)> = seqs.iter().map(|s| (s.frames[0].width(), s.frames[0].height())).collect();
        assert_eq!(sizes, [(192, 96), (144, 72)]);
        let labels: Vec<String> = configurations().into_iter().map(|c| c.label).collect();
        assert_eq!(labels[0], "av1:q60");
        assert_eq!(labels[7], "av1(svt-av1):crf45");
    }
}
