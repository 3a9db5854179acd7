//! `hdrcodec video encode|decode`, and `hdrcodec info` on an AV1 `.ivf` file: HDR10 (PQ), HLG
//! or L_p u'v' (Mantiuk 2004) AV1 through hdrcodec-video (rav1e to encode, libdav1d to decode).

use hdrcodec::core::{
    ContentLightLevel, DecodeOptions, EncodeSettings, Error, Hdr10Metadata, HdrImage, ImageInfo, Limits, Result,
    StreamReport, ThreadPool, VideoCodec, WriteSeek,
};
use hdrcodec_video::codec::Av1Codec;
use hdrcodec_video::decode::{probe_ivf, probe_stream};
use hdrcodec_video::hdr10::{content_light_level, Transfer};
use hdrcodec_video::lpuv_av1::LpuvStreamInfo;
use hdrcodec_video::mkv::MkvTrack;
use hdrcodec_video::mp4::probe_mp4;
use hdrcodec_video::obu::chroma_sample_position;
use hdrcodec_video::sdr::SdrRendition;
use hdrcodec_video::y4m::Y4mReader;
use indicatif::ProgressBar;
use serde_json::json;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What `video encode` was asked for.
pub struct VideoEncodeArgs<'a> {
    /// Frame image files in order; or one printf-style pattern (`f%05d.exr`), one directory,
    /// or one `.y4m` file.
    pub frames: &'a [PathBuf],
    /// The `.ivf`, `.mp4`, `.mkv` or `.webm` file to write.
    pub output: &'a Path,
    /// `pq`, `hlg` or `mantiuk`.
    pub transfer: &'a str,
    /// Plane bits for `mantiuk`: 10 or 12 (`None`: the codec's default, 12).
    pub bits: Option<u8>,
    /// The transfer of a Y4M input's Y'CbCr: `pq` or `hlg`.
    pub input_transfer: &'a str,
    /// `420` or `444`; `None`: 4:2:0 for PQ and HLG, 4:4:4 for Mantiuk.
    pub chroma: Option<&'a str>,
    /// 0-100, mapped onto rav1e's quantizer.
    pub quality: u8,
    /// rav1e speed preset 0-10.
    pub speed: u8,
    /// Worker threads (0 = one per core).
    pub threads: Option<usize>,
    /// Print a JSON summary, and no progress bar.
    pub json: bool,
    /// Also write an SDR rendition of the same frames here (`.ivf`, `.mp4`, `.mkv`, `.webm`).
    pub sdr: Option<&'a Path>,
    /// The SDR display's peak, cd/m².
    pub sdr_peak: f64,
}

/// The lower-case extension of `path`.
fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

fn is_ivf(path: &Path) -> bool {
    extension(path) == "ivf"
}

/// Matroska and WebM, which `info` and `video decode` read.
fn is_matroska(path: &Path) -> bool {
    matches!(extension(path).as_str(), "mkv" | "webm")
}

/// MP4 and its ISO base media siblings that `info` and `video decode` read.
fn is_mp4(path: &Path) -> bool {
    matches!(extension(path).as_str(), "mp4" | "m4v" | "mov")
}

/// Where `video encode` takes its frames from.
enum FrameSource {
    /// Image files, one per frame, in order.
    Files(Vec<PathBuf>),
    /// A YUV4MPEG2 file, whose Y'CbCr is BT.2020 on this transfer.
    Y4m { path: PathBuf, transfer: Transfer },
}

/// The files a printf-style pattern names (`dir/f%05d.exr`, `f%d.exr`): consecutive numbers
/// from the smallest that exists, up to the first missing one.
fn expand_pattern(pattern: &Path) -> Result<Vec<PathBuf>> {
    let name = pattern.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let bad =
        || Error::invalid(format!("'{}': a frame pattern has one %d or %0Nd, in the file name", pattern.display()));
    let at = name.find('%').ok_or_else(bad)?;
    let (prefix, rest) = name.split_at(at);
    let spec_end = rest.find('d').ok_or_else(bad)?;
    let spec = &rest[1..spec_end];
    let suffix = &rest[spec_end + 1..];
    let width = match spec {
        "" => 0,
        s if s.starts_with('0') && s.len() > 1 => s[1..].parse::<usize>().map_err(|_| bad())?,
        _ => return Err(bad()),
    };
    if suffix.contains('%') {
        return Err(bad());
    }
    let format = |n: u64| format!("{prefix}{n:0width$}{suffix}");
    let dir = pattern.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let entries = std::fs::read_dir(dir)
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", dir.display()))))?;
    // Every number whose name the pattern writes exactly, then the run from the smallest.
    let mut numbers = std::collections::BTreeSet::new();
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(file) = file.to_str() else { continue };
        let digits = file.strip_prefix(prefix).and_then(|f| f.strip_suffix(suffix));
        if let Some(n) = digits.filter(|d| !d.is_empty()).and_then(|d| d.parse::<u64>().ok()) {
            if format(n) == file {
                numbers.insert(n);
            }
        }
    }
    let first = *numbers.first().ok_or_else(|| Error::invalid(format!("no file matches '{}'", pattern.display())))?;
    Ok((first..).take_while(|n| numbers.contains(n)).map(|n| dir.join(format(n))).collect())
}

/// The image files of a directory that some codec reads (by extension), in name order;
/// hidden files are left out.
fn directory_frames(dir: &Path) -> Result<Vec<PathBuf>> {
    let known = hdrcodec::registry().extensions();
    let entries = std::fs::read_dir(dir)
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", dir.display()))))?;
    let mut files: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .filter(|p| !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
        .filter(|p| known.contains(&extension(p).as_str()))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::invalid(format!("{}: no image file in the directory", dir.display())));
    }
    Ok(files)
}

impl FrameSource {
    /// The frames `inputs` name: a list of files, or one pattern, directory or `.y4m` file.
    fn resolve(inputs: &[PathBuf], input_transfer: &str) -> Result<Self> {
        let transfer = match input_transfer.to_ascii_lowercase().as_str() {
            "pq" => Transfer::Pq,
            "hlg" => Transfer::HLG_1000,
            other => return Err(Error::invalid(format!("--input-transfer {other}: expected pq or hlg"))),
        };
        match inputs {
            [] => Err(Error::invalid("no frames to encode")),
            [one] if extension(one) == "y4m" => Ok(FrameSource::Y4m { path: one.clone(), transfer }),
            [one] if one.is_dir() => directory_frames(one).map(FrameSource::Files),
            [one] if !one.exists() && one.to_string_lossy().contains('%') => {
                expand_pattern(one).map(FrameSource::Files)
            }
            many => Ok(FrameSource::Files(many.to_vec())),
        }
    }

    /// Frames, when known without reading them all (a Y4M file's from its length).
    fn count(&self) -> Option<u64> {
        match self {
            FrameSource::Files(files) => Some(files.len() as u64),
            FrameSource::Y4m { path, .. } => {
                let reader = Y4mReader::new(BufReader::new(File::open(path).ok()?), &Limits::default()).ok()?;
                let len = std::fs::metadata(path).ok()?.len();
                // Header line, then per frame "FRAME\n" and the planes.
                Some(len / (6 + reader.header().frame_bytes()))
            }
        }
    }

    /// Reads every frame in order, one at a time, and hands each to `each`; stops after
    /// `limit` frames if given. Returns how many were read.
    fn for_each(&self, limit: Option<u64>, mut each: impl FnMut(HdrImage) -> Result<()>) -> Result<u64> {
        let limit = limit.unwrap_or(u64::MAX);
        let mut n = 0;
        match self {
            FrameSource::Files(files) => {
                let (reg, limits) = (hdrcodec::registry(), Limits::default());
                for path in files.iter().take(usize::try_from(limit).unwrap_or(usize::MAX)) {
                    let (_, frame) = reg.read(path, &limits)?;
                    each(frame).map_err(|e| Error::invalid(format!("{}: {e}", path.display())))?;
                    n += 1;
                }
            }
            FrameSource::Y4m { path, transfer } => {
                let file = File::open(path)
                    .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display()))))?;
                let mut reader = Y4mReader::new(BufReader::new(file), &Limits::default())
                    .map_err(|e| Error::invalid(format!("{}: {e}", path.display())))?;
                while n < limit {
                    let at = |e: Error| Error::invalid(format!("{} frame {n}: {e}", path.display()));
                    let Some(yuv) = reader.next_frame().map_err(at)? else { break };
                    each(reader.frame_to_image(&yuv, *transfer, 100.0).map_err(at)?)?;
                    n += 1;
                }
                if n == 0 {
                    return Err(Error::invalid(format!("{}: the Y4M file holds no frame", path.display())));
                }
            }
        }
        Ok(n)
    }
}

/// The `container` option of [`Av1Codec`] that `path`'s extension names; other extensions
/// are an error.
fn container_of(path: &Path) -> Result<&'static str> {
    match extension(path).as_str() {
        "ivf" => Ok("ivf"),
        "mp4" => Ok("mp4"),
        "mkv" => Ok("mkv"),
        "webm" => Ok("webm"),
        _ => Err(Error::unsupported(format!("'{}': video is written as .ivf, .mp4, .mkv or .webm", path.display()))),
    }
}

/// The frames of one `video encode`, encoded once per output.
struct Stream<'a> {
    info: &'a ImageInfo,
    source: &'a FrameSource,
    bar: &'a ProgressBar,
}

impl Stream<'_> {
    /// Encodes every frame through [`Av1Codec`] (the family's `VideoCodec`) with `settings`
    /// (its `container` option included) into `out`, ticking the bar.
    fn encode(&self, settings: &EncodeSettings, out: &mut (dyn WriteSeek + Send)) -> Result<StreamReport> {
        let mut encoder = Av1Codec.begin_encode_seekable(self.info, settings, Box::new(out))?;
        self.source.for_each(None, |frame| {
            encoder.push_frame(&frame)?;
            self.bar.inc(1);
            Ok(())
        })?;
        encoder.finish_report()
    }
}

/// `hdrcodec video encode FRAMES... OUT.ivf|.mp4|.mkv|.webm` (the container from the extension),
/// through [`Av1Codec`] as core's `VideoCodec` (`begin_encode_seekable`, `finish_report`), as
/// any caller of the codec would. Frames are
/// read twice for PQ, once to measure MaxCLL/MaxFALL (needed before the stream's first
/// header) and once to encode, one frame at a time. The file is written atomically. Returns
/// notes for stderr (values the PQ or HLG signal could not hold).
pub fn encode(a: &VideoEncodeArgs) -> Result<Vec<String>> {
    let container = container_of(a.output)?;
    let sdr = match a.sdr {
        // The peak is checked before any frame is read.
        Some(path) => Some((path, container_of(path)?, SdrRendition::new(a.sdr_peak)?)),
        None => None,
    };
    let source = FrameSource::resolve(a.frames, a.input_transfer)?;
    let mut settings = EncodeSettings::default()
        .with_quality(a.quality)
        .with_pool(ThreadPool::new(a.threads.unwrap_or(0))?)
        .with_option("transfer", a.transfer)
        .with_option("speed", a.speed.to_string());
    if let Some(chroma) = a.chroma {
        settings = settings.with_option("chroma", chroma);
    }
    if let Some(bits) = a.bits {
        settings = settings.with_option("bits", bits.to_string());
    }
    // The first frame's size and colour (its mastering display is kept, if it has one).
    let mut head = None;
    source.for_each(Some(1), |frame| {
        head = Some(ImageInfo::of(&frame));
        Ok(())
    })?;
    let mut info = head.ok_or_else(|| Error::invalid("no frames to encode"))?;
    let mut options = Av1Codec::av1_options(&info, &settings)?;
    if options.transfer == Transfer::Pq && options.lpuv.is_none() {
        let mut cll = ContentLightLevel { max_cll: 0, max_fall: 0 };
        source.for_each(None, |frame| {
            let next = content_light_level([&frame], Transfer::Pq);
            cll.max_cll = cll.max_cll.max(next.max_cll);
            cll.max_fall = cll.max_fall.max(next.max_fall);
            Ok(())
        })?;
        let mastering_display = info.color.hdr10.and_then(|h| h.mastering_display);
        info.color.hdr10 = Some(Hdr10Metadata { mastering_display, content_light_level: Some(cll) });
        options = Av1Codec::av1_options(&info, &settings)?;
    }
    let count = source.count();
    info.frames = count.and_then(|c| u32::try_from(c).ok()).unwrap_or(0);
    let passes = if sdr.is_some() { 2 } else { 1 };
    let bar = crate::cli::progress_bar(count.unwrap_or(0) as usize * passes, a.json);
    let stream = Stream { info: &info, source: &source, bar: &bar };
    // The SDR file is written inside the HDR file's atomic write: either both appear or neither.
    let summary = hdrcodec::write_atomic_with(a.output, |out| {
        let summary = stream.encode(&settings.clone().with_option("container", container), out)?;
        if let Some((path, sdr_container, _)) = &sdr {
            let sdr_settings = settings
                .clone()
                .with_option("container", *sdr_container)
                .with_option("sdr_peak", a.sdr_peak.to_string());
            hdrcodec::write_atomic_with(path, |sdr_out| stream.encode(&sdr_settings, sdr_out))?;
        }
        Ok(summary)
    });
    bar.finish_and_clear();
    let summary = summary?;
    let c = summary.clipped;
    let mut notes = Vec::new();
    if !c.is_empty() {
        notes.push(format!(
            "{} components above {} cd/m² coded as the peak, {} negative and {} NaN coded as 0",
            c.above_peak,
            options.transfer.peak_nits(),
            c.negative,
            c.nan
        ));
    }
    if a.json {
        let cll = summary.content_light.map(|c| json!({"max_cll": c.max_cll, "max_fall": c.max_fall}));
        let bytes = summary.bytes;
        println!(
            "{}",
            json!({
                "output": a.output.display().to_string(),
                "sdr_output": a.sdr.map(|p| p.display().to_string()),
                "frames": summary.frames,
                "bytes": bytes,
                "content_light": cll,
                "notes": notes,
            })
        );
    }
    Ok(notes)
}

/// The stream codec (from the facade's [`hdrcodec::video_codecs`]) that reads `path`, by its
/// extension (`.m4v` and `.mov` as `.mp4`).
fn video_codec_for(path: &Path) -> Result<Arc<dyn VideoCodec>> {
    let ext = match extension(path).as_str() {
        "m4v" | "mov" => "mp4".to_string(),
        other => other.to_string(),
    };
    let codecs = hdrcodec::video_codecs();
    let known: Vec<&str> = codecs.iter().flat_map(|c| c.extensions().iter().copied()).collect();
    codecs
        .iter()
        .find(|c| c.extensions().contains(&ext.as_str()))
        .cloned()
        .ok_or_else(|| Error::unsupported(format!("'{}': video is read from {}", path.display(), known.join(", "))))
}

/// `hdrcodec video decode IN.ivf|IN.mp4|IN.mkv|IN.webm|IN.hdrc OUT_DIR`, through the facade's stream codecs:
/// every frame as `frame_NNNNN.exr` (float, linear; AV1 gives BT.2020, or for L_p u'v' the
/// primaries its T.35 names; 1.0 = 100 cd/m²). On failure the frames written so far are
/// removed. Returns the number of frames.
pub fn decode(input: &Path, out_dir: &Path, json: bool) -> Result<()> {
    let codec = video_codec_for(input)?;
    let data: Arc<[u8]> = hdrcodec::read_file(input)?.into();
    let mut decoder = codec.begin_decode(data, &DecodeOptions::new(Limits::default()))?;
    let exr = hdrcodec::registry().by_name("exr")?;
    let settings = EncodeSettings::default();
    std::fs::create_dir_all(out_dir)
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", out_dir.display()))))?;
    let bar = crate::cli::progress_bar(decoder.info().frames as usize, json);
    let mut written = Vec::new();
    let result = (|| {
        let mut index = 0u64;
        while let Some(frame) = decoder.next_frame()? {
            let path = out_dir.join(format!("frame_{index:05}.exr"));
            hdrcodec::encode_file(exr.as_ref(), &frame, &settings, &path)?;
            written.push(path);
            index += 1;
            bar.inc(1);
        }
        if index == 0 {
            return Err(Error::invalid(format!("{}: the stream holds no frame", input.display())));
        }
        Ok(index)
    })();
    bar.finish_and_clear();
    if result.is_err() {
        for path in &written {
            let _ = std::fs::remove_file(path);
        }
    }
    let frames = result?;
    if json {
        println!(
            "{}",
            json!({"input": input.display().to_string(), "output_dir": out_dir.display().to_string(), "frames": frames, "codec": codec.name()})
        );
    }
    Ok(())
}

/// `hdrcodec info FILE.ivf|FILE.mkv|FILE.webm|FILE.mp4`: the IVF header (or the Matroska Colour element), the sequence header's colour signalling and the
/// HDR10 metadata, read by our own parsers without decoding.
pub fn info(file: &Path, as_json: bool) -> Result<()> {
    let data = hdrcodec::read_file(file)?;
    if is_mp4(file) {
        return mp4_info(file, &data, as_json);
    }
    // Matroska: the stream through its blocks, and the track's Colour element as written.
    let (container, ivf_rate, colour, summary) = if is_matroska(file) {
        let track = MkvTrack::first_video(&data, &Limits::default())?;
        let colour = track.colour.map(|c| {
            json!({"matrix": c.matrix, "transfer": c.transfer, "primaries": c.primaries, "range": c.range,
                "bits_per_channel": c.bits_per_channel, "max_cll": c.max_cll, "max_fall": c.max_fall,
                "mastering_display": c.mastering_display.is_some()})
        });
        let container = if track.doc_type == "webm" { "WebM" } else { "Matroska" };
        (container, None, colour, probe_stream(&data, &Limits::default())?)
    } else {
        let (header, summary) = probe_ivf(&data, &Limits::default())?;
        ("IVF", Some([header.timebase_den, header.timebase_num]), None, summary)
    };
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
    let lpuv = LpuvStreamInfo::from_summary(&summary)?;
    let lpuv_json = lpuv.map(|l| {
        json!({"curve": format!("{:?}", l.curve), "bits": l.bits, "min_nits": l.min_nits, "max_nits": l.max_nits, "primaries_h273": l.primaries_h273, "plane_mapping": format!("{:?}", l.mapping)})
    });
    if as_json {
        let out = json!({
            "file": file.display().to_string(),
            "codec": "av1",
            "file_size": data.len(),
            "frames": summary.temporal_units,
            "width": seq.max_frame_width,
            "height": seq.max_frame_height,
            "container": container,
            "ivf_frame_rate": ivf_rate,
            "matroska_colour": colour,
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
    println!("file:          {} ({} bytes, AV1 in {container})", file.display(), data.len());
    if let Some(colour) = colour {
        println!("Matroska Colour: {colour}");
    }
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
            "planes:        L_p u'v' (Mantiuk 2004): luma {:?} at {} bits over {:e} … {:e} cd/m², u'v' ×410, codes in the planes: {:?}; RGB out in H.273 primaries {}",
            l.curve, l.bits, l.min_nits, l.max_nits, l.mapping, l.primaries_h273
        );
    }
    crate::cli::print_hdr10(hdr10);
    Ok(())
}

/// True for a file `info` reads through [`info`] rather than the image registry.
pub fn handles(file: &Path) -> bool {
    is_ivf(file) || is_mp4(file) || is_matroska(file)
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
    let lpuv = match &info.av1 {
        Some(summary) => LpuvStreamInfo::from_summary(summary)?,
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
