//! `hdrcodec video encode|decode`, and `hdrcodec info` on an AV1 `.ivf` file: HDR10 (PQ), HLG
//! or L_p u'v' (Mantiuk 2004) AV1 through hdrcodec-video (rav1e to encode, libdav1d to decode).

use hdrcodec::core::{Error, Hdr10Metadata, HdrImage, Limits, Result, ThreadPool};
use hdrcodec_video::decode::{probe_ivf, Av1DecodeOptions, Av1Decoder};
use hdrcodec_video::encode::{Av1Encoder, Av1Options, EncodeSummary, TemporalUnitSink};
use hdrcodec_video::hdr10::{content_light_level, Subsampling, Transfer};
use hdrcodec_video::lpuv_av1::LpuvStreamInfo;
use hdrcodec_video::mp4::probe_mp4;
use hdrcodec_video::obu::chroma_sample_position;
use serde_json::json;
use std::path::{Path, PathBuf};

/// What `video encode` was asked for.
pub struct VideoEncodeArgs<'a> {
    /// Frame image files, in order.
    pub frames: &'a [PathBuf],
    /// The `.ivf` or `.mp4` file to write.
    pub output: &'a Path,
    /// `pq`, `hlg` or `mantiuk`.
    pub transfer: &'a str,
    /// `420` or `444`; `None`: 4:2:0 for PQ and HLG, 4:4:4 for Mantiuk.
    pub chroma: Option<&'a str>,
    /// 0-100, mapped onto rav1e's quantizer.
    pub quality: Option<u8>,
    /// rav1e speed preset 0-10.
    pub speed: Option<u8>,
    /// Worker threads (0 = one per core).
    pub threads: Option<usize>,
}

/// The lower-case extension of `path`.
fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

fn is_ivf(path: &Path) -> bool {
    extension(path) == "ivf"
}

/// MP4 and its ISO base media siblings that `info` and `video decode` read.
fn is_mp4(path: &Path) -> bool {
    matches!(extension(path).as_str(), "mp4" | "m4v" | "mov")
}

/// Codes every frame after the first (already read) into `encoder` and completes the file.
fn encode_frames<S: TemporalUnitSink>(
    mut encoder: Av1Encoder<S>,
    head: &HdrImage,
    rest: &[PathBuf],
    read: impl Fn(&PathBuf) -> Result<HdrImage>,
) -> Result<EncodeSummary> {
    encoder.push_frame(head)?;
    for path in rest {
        encoder.push_frame(&read(path)?).map_err(|e| Error::invalid(format!("{}: {e}", path.display())))?;
    }
    Ok(encoder.finish()?.0)
}

/// `hdrcodec video encode FRAMES... OUT.ivf|OUT.mp4` (the container from the extension). Frames are decoded twice, once to measure
/// MaxCLL/MaxFALL (needed before the stream's first header) and once to encode, so that no
/// more than the first frame and one other are held at a time. The file is written atomically.
/// Returns notes for stderr (values the PQ or HLG signal could not hold).
pub fn encode(a: &VideoEncodeArgs) -> Result<Vec<String>> {
    let mp4 = match extension(a.output).as_str() {
        "ivf" => false,
        "mp4" => true,
        _ => return Err(Error::unsupported(format!("'{}': video is written as .ivf or .mp4", a.output.display()))),
    };
    let (transfer, mantiuk) = match a.transfer.to_ascii_lowercase().as_str() {
        "pq" => (Transfer::Pq, false),
        "hlg" => (Transfer::HLG_1000, false),
        "mantiuk" => (Transfer::Pq, true),
        other => return Err(Error::invalid(format!("--transfer {other}: expected pq, hlg or mantiuk"))),
    };
    // L_p u'v' chroma is nearly free at 4:4:4 (its codes span 0..255 of 4095) and keeps colour
    // edges: the crate's README has the measurements.
    let subsampling = match a.chroma {
        None if mantiuk => Subsampling::Yuv444,
        None | Some("420") => Subsampling::Yuv420,
        Some("444") => Subsampling::Yuv444,
        Some(other) => return Err(Error::invalid(format!("--chroma {other}: expected 420 or 444"))),
    };
    let first = a.frames.first().ok_or_else(|| Error::invalid("no frames to encode"))?;
    let reg = hdrcodec::registry();
    let limits = Limits::default();
    let read = |path: &PathBuf| reg.read(path, &limits).map(|(_, image)| image);
    let mut options =
        Av1Options { transfer, subsampling, pool: ThreadPool::new(a.threads.unwrap_or(0))?, ..Av1Options::default() };
    if let Some(q) = a.quality {
        options.quantizer = Av1Options::quantizer_for_quality(q);
    }
    if let Some(s) = a.speed {
        options.speed = s;
    }
    let head = read(first)?;
    if mantiuk {
        // The decoder returns the first frame's primaries; every T.35 must reach its frame.
        options.lpuv = Some(LpuvStreamInfo::for_primaries(head.color.primaries));
        options.low_latency = true;
    } else if transfer == Transfer::Pq {
        let mut cll = content_light_level([&head], transfer);
        for path in &a.frames[1..] {
            let next = content_light_level([&read(path)?], transfer);
            cll.max_cll = cll.max_cll.max(next.max_cll);
            cll.max_fall = cll.max_fall.max(next.max_fall);
        }
        options.content_light = Some(cll);
    }
    let count = u32::try_from(a.frames.len()).unwrap_or(0);
    let (w, h, rest) = (head.width(), head.height(), &a.frames[1..]);
    let summary = hdrcodec::write_atomic_with(a.output, |out| {
        if mp4 {
            encode_frames(Av1Encoder::begin_mp4(w, h, &options, out)?, &head, rest, read)
        } else {
            encode_frames(Av1Encoder::begin(w, h, count, &options, out)?, &head, rest, read)
        }
    })?;
    let c = summary.clipped;
    let mut notes = Vec::new();
    if !c.is_empty() {
        notes.push(format!(
            "{} components above {} cd/m² coded as the peak, {} negative and {} NaN coded as 0",
            c.above_peak,
            transfer.peak_nits(),
            c.negative,
            c.nan
        ));
    }
    Ok(notes)
}

/// `hdrcodec video decode IN.ivf|IN.mp4 OUT_DIR` (AV1 only): every frame as `frame_NNNNN.exr` (float, linear
/// BT.2020, or for L_p u'v' the primaries its T.35 names; 1.0 = 100 cd/m²). On failure the frames written so far are removed.
pub fn decode(input: &Path, out_dir: &Path) -> Result<()> {
    let data = hdrcodec::read_file(input)?;
    let mut decoder = Av1Decoder::new(&data, &Av1DecodeOptions::default())?;
    let exr = hdrcodec::registry().by_name("exr")?;
    let settings = hdrcodec::core::EncodeSettings::default();
    std::fs::create_dir_all(out_dir)
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", out_dir.display()))))?;
    let mut written = Vec::new();
    let result = (|| {
        let mut index = 0u64;
        while let Some(frame) = decoder.next_frame()? {
            let path = out_dir.join(format!("frame_{index:05}.exr"));
            hdrcodec::encode_file(exr.as_ref(), &frame, &settings, &path)?;
            written.push(path);
            index += 1;
        }
        if index == 0 {
            return Err(Error::invalid(format!("{}: the stream holds no frame", input.display())));
        }
        Ok(())
    })();
    if result.is_err() {
        for path in &written {
            let _ = std::fs::remove_file(path);
        }
    }
    result
}

/// `hdrcodec info FILE.ivf|FILE.mp4`: the IVF header, the sequence header's colour signalling and the
/// HDR10 metadata, read by our own parsers without decoding.
pub fn info(file: &Path, as_json: bool) -> Result<()> {
    let data = hdrcodec::read_file(file)?;
    if is_mp4(file) {
        return mp4_info(file, &data, as_json);
    }
    let (header, summary) = probe_ivf(&data, &Limits::default())?;
    let seq = summary.sequence_header.ok_or_else(|| Error::invalid("an AV1 stream without a sequence header"))?;
    let c = seq.color;
    let subsampling = match (c.subsampling_x, c.subsampling_y) {
        (true, true) => "4:2:0",
        (true, false) => "4:2:2",
        _ => "4:4:4",
    };
    let siting = match c.chroma_sample_position {
        chroma_sample_position::VERTICAL => "vertical (left)",
        chroma_sample_position::COLOCATED => "colocated (top-left)",
        _ => "unknown",
    };
    let cicp = c.color_description.map(|d| [d.color_primaries, d.transfer_characteristics, d.matrix_coefficients]);
    let hdr10 = summary.hdr10();
    let lpuv = match &summary.first_t35 {
        Some((country_code, payload)) => LpuvStreamInfo::from_t35(*country_code, payload)?,
        None => None,
    };
    let lpuv_json = lpuv.map(|l| {
        json!({"curve": format!("{:?}", l.curve), "bits": l.bits, "min_nits": l.min_nits, "max_nits": l.max_nits, "primaries_h273": l.primaries_h273})
    });
    if as_json {
        let out = json!({
            "file": file.display().to_string(),
            "codec": "av1",
            "file_size": data.len(),
            "frames": summary.temporal_units,
            "width": seq.max_frame_width,
            "height": seq.max_frame_height,
            "ivf_frame_rate": [header.timebase_den, header.timebase_num],
            "profile": seq.profile,
            "level_idx": seq.level_idx,
            "bit_depth": c.bit_depth,
            "subsampling": subsampling,
            "chroma_sample_position": siting,
            "full_range": c.full_range,
            "color_description": cicp,
            "hdr10": hdr10.map(crate::cli::hdr10_json),
            "lpuv": lpuv_json,
            "t35_messages": summary.t35_per_temporal_unit.iter().map(|&n| u64::from(n)).sum::<u64>(),
        });
        println!("{out}");
        return Ok(());
    }
    println!("file:          {} ({} bytes, AV1 in IVF)", file.display(), data.len());
    println!("frames:        {}", summary.temporal_units);
    println!("dimensions:    {} x {}", seq.max_frame_width, seq.max_frame_height);
    println!("profile:       {} (level index {})", seq.profile, seq.level_idx);
    println!(
        "samples:       {}-bit {subsampling}, {} range",
        c.bit_depth,
        if c.full_range { "full" } else { "limited" }
    );
    println!("chroma siting: {siting}");
    match cicp {
        Some([p, t, m]) => println!("colour (H.273): primaries {p}, transfer {t}, matrix {m}"),
        None => println!("colour (H.273): not signalled"),
    }
    if let Some(l) = lpuv {
        println!(
            "planes:        L_p u'v' (Mantiuk 2004): luma {:?} at {} bits over {:e} … {:e} cd/m², u'v' ×410; RGB out in H.273 primaries {}",
            l.curve, l.bits, l.min_nits, l.max_nits, l.primaries_h273
        );
    }
    crate::cli::print_hdr10(hdr10);
    Ok(())
}

/// True for a file `info` reads through [`info`] rather than the image registry.
pub fn handles(file: &Path) -> bool {
    is_ivf(file) || is_mp4(file)
}

/// H.273 code points with their names, as `info` prints them.
fn cicp_text([p, t, m]: [u8; 3]) -> String {
    let primaries = match p {
        1 => "BT.709",
        9 => "BT.2020",
        12 => "P3-D65",
        2 => "unspecified",
        _ => "other",
    };
    let transfer = match t {
        1 => "BT.709",
        16 => "PQ (SMPTE ST 2084)",
        18 => "HLG",
        2 => "unspecified",
        _ => "other",
    };
    let matrix = match m {
        1 => "BT.709",
        9 => "BT.2020 NCL",
        0 => "identity",
        2 => "unspecified",
        _ => "other",
    };
    format!("primaries {p} ({primaries}), transfer {t} ({transfer}), matrix {m} ({matrix})")
}

/// `hdrcodec info FILE.mp4`: the first video track, from the boxes and the bitstream's headers
/// (AV1 or HEVC), without decoding; a mastering display that cannot be right is reported.
fn mp4_info(file: &Path, data: &[u8], as_json: bool) -> Result<()> {
    let info = probe_mp4(data, &Limits::default())?;
    let codec = String::from_utf8_lossy(&info.codec).into_owned();
    let lpuv = match info.av1.as_ref().and_then(|s| s.first_t35.as_ref()) {
        Some((country_code, payload)) => LpuvStreamInfo::from_t35(*country_code, payload)?,
        None => None,
    };
    if as_json {
        let out = json!({
            "file": file.display().to_string(),
            "container": "mp4",
            "codec": codec,
            "file_size": data.len(),
            "frames": info.frames,
            "frame_rate": info.frame_rate,
            "width": info.width,
            "height": info.height,
            "bit_depth": info.bit_depth,
            "color_description": info.colour.map(|(c, _)| c),
            "color_description_source": info.colour.map(|(_, s)| s),
            "full_range": info.full_range,
            "hdr10": crate::cli::hdr10_json(Hdr10Metadata {
                mastering_display: info.mastering_display.map(|(m, _)| m),
                content_light_level: info.content_light.map(|(c, _)| c),
            }),
            "mastering_display_source": info.mastering_display.map(|(_, s)| s),
            "content_light_source": info.content_light.map(|(_, s)| s),
            "lpuv": lpuv.map(|l| json!({"curve": format!("{:?}", l.curve), "bits": l.bits})),
            "problems": info.problems,
        });
        println!("{out}");
        return Ok(());
    }
    println!("file:          {} ({} bytes, {codec} in MP4)", file.display(), data.len());
    println!("frames:        {}", info.frames);
    if let Some(rate) = info.frame_rate {
        println!("frame rate:    {rate:.3} per second (mean)");
    }
    println!("dimensions:    {} x {}", info.width, info.height);
    if let Some(bits) = info.bit_depth {
        println!("bit depth:     {bits}");
    }
    match info.colour {
        Some((c, source)) => println!(
            "colour (H.273): {} ({}, {source})",
            cicp_text(c),
            if info.full_range == Some(true) { "full range" } else { "limited range" }
        ),
        None => println!("colour (H.273): not signalled"),
    }
    if let Some(l) = lpuv {
        println!("planes:        L_p u'v' (Mantiuk 2004): luma {:?} at {} bits", l.curve, l.bits);
    }
    match info.mastering_display {
        Some((m, source)) => println!(
            "mastering display: R {:?} G {:?} B {:?} W {:?}, {}-{} cd/m² ({source})",
            m.primaries[0], m.primaries[1], m.primaries[2], m.white, m.min_luminance, m.max_luminance
        ),
        None => println!("mastering display: none"),
    }
    match info.content_light {
        Some((l, source)) => {
            println!("content light level: MaxCLL {} MaxFALL {} cd/m² ({source})", l.max_cll, l.max_fall)
        }
        None => println!("content light level: none"),
    }
    for p in &info.problems {
        println!("malformed:     {p}");
    }
    Ok(())
}
