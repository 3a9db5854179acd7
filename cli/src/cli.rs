//! The commands of the `hdrcodec` binary. Each returns `Err` with a one-line reason; `main`
//! prints it as `hdrcodec: <reason>` and exits non-zero.

use hdrcodec::core::{
    metrics, DecodeOptions, EncodeSettings, Error, Hdr10Metadata, Limits, Result, ThreadPool, VideoCodec,
};
use hdrcodec_cli::conversion::ConversionSettings;
use hdrcodec_cli::{batch, bench, memory, real_corpus, video_bench};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{json, Map, Value};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Prints the one-line failure message: newlines in `reason` are folded so that the contract
/// "exactly one line on stderr" holds whatever a library put into its message.
pub fn fail(reason: &str) {
    let line = reason.split(['\n', '\r']).map(str::trim).filter(|s| !s.is_empty()).collect::<Vec<_>>().join("; ");
    eprintln!("hdrcodec: {line}");
}

/// The message of the last panic, kept by the hook for [`run_catching_panics`].
static LAST_PANIC: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Records panics instead of printing them: a library may catch its own panics (and turn them
/// into errors), and those must not put a second line on stderr. A panic that reaches `main`
/// is reported by [`run_catching_panics`] as one line.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown".into());
        let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = Some(format!("{msg}{at}"));
        }
    }));
}

/// Runs `f`; a panic that escapes it becomes the one-line failure with exit status 101.
pub fn run_catching_panics(f: impl FnOnce() -> ExitCode) -> ExitCode {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(code) => code,
        Err(_) => {
            let msg = LAST_PANIC.lock().ok().and_then(|m| m.clone()).unwrap_or_else(|| "unknown".into());
            // `hdrcodec info x | head`: the reader closed stdout, which is not a bug. Quiet, with
            // the status a shell gives a process that SIGPIPE ended (128 + 13).
            if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
                return ExitCode::from(141);
            }
            fail(&format!("internal error (a bug, please report it): {msg}"));
            ExitCode::from(101)
        }
    }
}

/// From now on SIGINT (Ctrl-C), SIGTERM (`kill`, a batch system stopping a job) and SIGHUP (the
/// terminal closed) remove the temporary files being written
/// ([`hdrcodec::remove_temp_files_in_flight`]) and then end the process by that same signal, as
/// if it had not been caught: the shell reports 130, 143 or 129 (128 + the signal), and a
/// script looping over `hdrcodec convert` stops too instead of going on to the next file.
/// SIGKILL cannot be caught; `batch` removes what a killed run left when it is run again.
pub fn remove_temp_files_on_signal() -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new().name("hdrcodec-signals".into()).spawn(move || {
        if let Some(signal) = signals.forever().next() {
            hdrcodec::remove_temp_files_in_flight();
            // Restores the default action and raises the signal again; it returns only if that
            // failed, and then the status says the same thing.
            let _ = signal_hook::low_level::emulate_default_handler(signal);
            std::process::exit(128 + signal);
        }
    })?;
    Ok(())
}

/// Help and version go to stdout as usual; a usage error becomes the one-line failure.
pub fn clap_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
            let _ = e.print();
            ExitCode::SUCCESS
        }
        // `hdrcodec` or `hdrcodec corpus` alone: a usage error like any other, in one line.
        ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            fail("a command is missing (see 'hdrcodec --help')");
            ExitCode::from(2)
        }
        _ => {
            let text = e.render().to_string();
            let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("invalid arguments");
            let first = first.trim().trim_start_matches("error:").trim();
            fail(&format!("{first} (see 'hdrcodec --help')"));
            ExitCode::from(2)
        }
    }
}

/// Whether progress is drawn: on stderr, so when stderr is a terminal (whatever stdout is:
/// `hdrcodec batch ... > summary.txt` still shows it, `2> log` keeps the log free of it), and
/// never with `--json`.
fn progress_visible(json: bool) -> bool {
    !json && std::io::stderr().is_terminal()
}

/// A progress bar on stderr when [`progress_visible`]; else hidden.
pub(crate) fn progress_bar(len: usize, json: bool) -> ProgressBar {
    if !progress_visible(json) {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} {elapsed} {msg}") {
        pb.set_style(style);
    }
    pb
}

/// Prints one JSON object on stdout.
fn print_json(v: &Value) -> Result<()> {
    let s = serde_json::to_string_pretty(v).map_err(|e| Error::invalid(format!("cannot format JSON: {e}")))?;
    println!("{s}");
    Ok(())
}

/// A number for JSON: non-finite values (an infinite PSNR) become null, as documented.
fn num(v: f64) -> Value {
    serde_json::Number::from_f64(v).map(Value::Number).unwrap_or(Value::Null)
}

/// `hdrcodec convert`.
pub fn convert(
    input: &Path,
    output: &Path,
    codec: Option<&str>,
    quality: Option<u8>,
    effort: Option<u8>,
    threads: Option<usize>,
    opts: &[String],
) -> Result<()> {
    let reg = hdrcodec::registry();
    // Choose the output codec and check the options before reading anything.
    let out_codec = match codec {
        Some(name) => reg.by_name(name)?,
        None => reg.for_output(output)?,
    };
    // One pool for the whole command, decoding and encoding alike.
    let conversion = ConversionSettings::new(quality, effort, ThreadPool::new(threads.unwrap_or(0))?, opts)?;
    // The decoder reads the file itself (a codec that can reads it piece by piece), and band by
    // band when the output format allows it: neither the input file, nor the decoded image, nor
    // the encoded file is held whole.
    let (in_codec, mut file) = reg.open(input)?;
    let (options, settings) = conversion.for_decoder(in_codec.as_ref(), Limits::default());
    let notes = hdrcodec::convert_file(
        in_codec.as_ref(),
        hdrcodec::Input::File(&mut file),
        &options,
        out_codec.as_ref(),
        &settings,
        output,
    )?;
    for n in notes {
        note(&n);
    }
    Ok(())
}

/// A one-line remark on stderr after a successful command (colour kept or converted, values
/// clipped): `hdrcodec: note: ...`.
pub fn note(text: &str) {
    let line = text.split(['\n', '\r']).map(str::trim).filter(|s| !s.is_empty()).collect::<Vec<_>>().join("; ");
    eprintln!("hdrcodec: note: {line}");
}

/// `hdrcodec info`: the header facts (size, channels, colour, stored format, frames) from the
/// codec's header probe; the luminance statistics and metadata from a full decode into a
/// [`hdrcodec::StatsSink`], which keeps nothing of the image (the decoder holds a band of rows).
pub fn info(file: &Path, json: bool) -> Result<()> {
    if crate::video::handles(file) {
        return crate::video::info(file, json);
    }
    let reg = hdrcodec::registry();
    // The header and then the pixels are read from the file, never the file whole for the
    // codecs that read it piece by piece.
    let (codec, header, mut input) = reg.probe_file(file, &Limits::default())?;
    let file_size = input.metadata().map_err(Error::Io)?.len();
    // A sequence's statistics are its first frame's (decoded alone by the stream decoder).
    let (stats, metadata) = if header.frames > 1 && codec.name() == "hdrc" {
        let data = hdrcodec::read_file(file)?;
        let video = hdrcodec::container::HdrcVideoCodec::new(reg.codecs().to_vec());
        let mut frames = video.begin_decode(data.as_slice().into(), &DecodeOptions::new(Limits::default()))?;
        let image = frames.next_frame()?.ok_or_else(|| Error::invalid("the .hdrc sequence has no frame"))?;
        (hdrcodec::ImageStats::of(&image), image.metadata)
    } else {
        let mut sink = hdrcodec::StatsSink::new();
        codec.decode_rows_from(&mut input, &DecodeOptions::new(Limits::default()), &mut sink)?;
        let metadata = sink.info().map(|i| i.metadata.clone()).unwrap_or_default();
        (sink.stats(), metadata)
    };
    let c = &header.color;
    let ch = c.primaries.chromaticities();
    // A file without primaries (PFM, DDS): luminance needs some, BT.709 is assumed and said.
    let assumed = (!c.primaries.is_specified()).then(|| c.primaries.or_bt709());
    let hdrcodec::LuminanceStats { min, max, mean, non_finite_samples: nonfinite } = stats.luminance;
    // CTA-861.3 light levels of this one frame (MaxFALL of a single frame is its average).
    let (measured_cll, measured_fall) = (stats.max_cll_nits, stats.frame_average_nits);
    let hdr10 = c.hdr10.map(hdr10_json);
    let metadata_json: Map<String, Value> =
        metadata.iter().map(|(k, v)| (k.clone(), Value::String(v.clone()))).collect();
    if json {
        return print_json(&json!({
            "file": file.display().to_string(),
            "codec": codec.name(),
            "file_size": file_size,
            "format": header.format,
            "frames": header.frames,
            "width": header.width,
            "height": header.height,
            "channels": header.channels.count(),
            "layout": format!("{:?}", header.channels).to_uppercase(),
            "primaries": c.primaries.name(),
            "chromaticities": assumed.is_none().then(|| json!({"red": ch.red, "green": ch.green, "blue": ch.blue, "white": ch.white})),
            // The primaries the luminance figures took for a file that records none.
            "primaries_assumed": assumed.map(|p| p.name()),
            "nits_per_unit": num(f64::from(c.nits_per_unit)),
            "hdr10": hdr10,
            "luminance_nits": {"min": num(min), "max": num(max), "mean": num(mean)},
            "max_cll_measured_nits": num(measured_cll),
            "max_fall_measured_nits": num(measured_fall),
            "non_finite_samples": nonfinite,
            "metadata": metadata_json,
        }));
    }
    println!("file:          {} ({file_size} bytes, {})", file.display(), codec.name());
    println!("format:        {}", header.format);
    if header.frames != 1 {
        println!("frames:        {}", header.frames);
    }
    println!("dimensions:    {} x {}", header.width, header.height);
    println!("channels:      {} ({:?})", header.channels.count(), header.channels);
    match assumed {
        None => println!(
            "primaries:     {} (R {:?} G {:?} B {:?} W {:?})",
            c.primaries.name(),
            ch.red,
            ch.green,
            ch.blue,
            ch.white
        ),
        Some(_) => println!("primaries:     unspecified (the file records none)"),
    }
    println!("nits per unit: {}", c.nits_per_unit);
    let which = if header.frames > 1 { format!(", first of {} frames", header.frames) } else { String::new() };
    println!("luminance:     min {min:.4e}  max {max:.4e}  mean {mean:.4e} cd/m²{which}");
    if let Some(p) = assumed {
        println!("               (luminance taken as {}: assumed, the file records no primaries)", p.name());
    }
    println!("light level:   MaxCLL {measured_cll:.1}  MaxFALL {measured_fall:.1} cd/m² (measured{which})");
    if nonfinite > 0 {
        println!("non-finite samples: {nonfinite}");
    }
    print_hdr10(c.hdr10);
    if metadata.is_empty() {
        println!("metadata:      none");
    }
    for (k, v) in &metadata {
        if k == "exif" {
            // Binary metadata travels as hexadecimal (see hdrcodec_jpeghdr::exif).
            println!("metadata:      exif = {} bytes", v.len() / 2);
            continue;
        }
        // Long values (XMP packets) are cut; a codec's one-line descriptions fit.
        let short: String = v.chars().take(140).collect();
        let more = if v.chars().count() > 140 { "..." } else { "" };
        println!("metadata:      {k} = {}{more}", short.replace(['\n', '\r'], " "));
    }
    Ok(())
}

/// HDR10 static metadata as `info --json` shows it.
pub fn hdr10_json(h: Hdr10Metadata) -> Value {
    json!({
        "mastering_display": h.mastering_display.map(|m| json!({
            "primaries": m.primaries, "white": m.white,
            "max_luminance": m.max_luminance, "min_luminance": m.min_luminance,
        })),
        "content_light_level": h.content_light_level.map(|l| json!({"max_cll": l.max_cll, "max_fall": l.max_fall})),
    })
}

/// HDR10 static metadata as `info` prints it.
pub fn print_hdr10(hdr10: Option<Hdr10Metadata>) {
    match hdr10 {
        None => println!("HDR10:         none"),
        Some(h) => {
            if let Some(m) = h.mastering_display {
                println!(
                    "mastering display: R {:?} G {:?} B {:?} W {:?}, {}-{} cd/m²",
                    m.primaries[0], m.primaries[1], m.primaries[2], m.white, m.min_luminance, m.max_luminance
                );
            }
            if let Some(l) = h.content_light_level {
                println!("content light level: MaxCLL {} MaxFALL {} cd/m²", l.max_cll, l.max_fall);
            }
        }
    }
}

/// `hdrcodec compare`; with `heatmap` (FILE.png, the top of its scale) also the ΔE ITP map.
pub fn compare(reference: &Path, test: &Path, json: bool, heatmap: Option<(&Path, f64)>) -> Result<()> {
    if let Some((p, _)) = heatmap {
        hdrcodec_cli::plot::prepare_png(p, "--heatmap")?;
    }
    let reg = hdrcodec::registry();
    let (_, r) = reg.read(reference, &Limits::default())?;
    let (_, t) = reg.read(test, &Limits::default())?;
    let m = metrics::compare(&r, &t)?;
    if let Some((p, max)) = heatmap {
        hdrcodec_cli::heatmap::write(&r, &t, p, max, &Limits::default())?;
    }
    // What the metrics took for files that record no primaries (metrics module notes): a test
    // file's are the reference's; an unspecified reference is read as BT.709.
    let from_reference = !t.color.primaries.is_specified() && r.color.primaries.is_specified();
    let assumed = (!r.color.primaries.is_specified()).then(|| r.color.primaries.or_bt709());
    let fields: [(&str, f64, &str); 7] = [
        ("pu21_psnr", m.pu21_psnr, "dB"),
        ("pu21_psnr_rgb", m.pu21_psnr_rgb, "dB"),
        ("de_itp_mean", m.de_itp_mean, ""),
        ("de_itp_p99", m.de_itp_p99, ""),
        ("log_rmse", m.log_rmse, ""),
        ("psnr", m.psnr, "dB"),
        ("max_rel_err", m.max_rel_err, ""),
    ];
    if json {
        let mut obj = Map::new();
        obj.insert("reference".into(), Value::String(reference.display().to_string()));
        obj.insert("test".into(), Value::String(test.display().to_string()));
        obj.insert("identical".into(), Value::Bool(m.identical));
        for (k, v, _) in fields {
            obj.insert(k.into(), num(v));
        }
        obj.insert("test_primaries_from_reference".into(), Value::Bool(from_reference));
        obj.insert("primaries_assumed".into(), assumed.map_or(Value::Null, |p| Value::String(p.name().into())));
        return print_json(&Value::Object(obj));
    }
    if m.identical {
        println!("identical: the images are identical ({} x {})", r.width(), r.height());
    } else {
        println!("identical: no");
    }
    if from_reference {
        println!("primaries:     the test file records none: taken as the reference's ({})", r.color.primaries.name());
    }
    if let Some(p) = assumed {
        println!("primaries:     the reference records none: {} assumed", p.name());
    }
    for (k, v, unit) in fields {
        println!("{k:<14} {v:.6} {unit}");
    }
    Ok(())
}

/// What `hdrcodec bench` was asked to do.
pub struct BenchOptions {
    /// Image files and directories (none: the generated corpus).
    pub paths: Vec<PathBuf>,
    pub json: bool,
    pub plot: Option<PathBuf>,
    /// The Markdown report's file.
    pub report: Option<PathBuf>,
    /// Threads of the pool behind the all-thread speed columns (0: one per core).
    pub threads: usize,
    pub filter: Option<String>,
    pub per_image: bool,
    pub runs: usize,
    pub quick: bool,
    /// Also the HDR10 AV1 video rows.
    pub video: bool,
    /// `--corpus`: "shared" or "generated".
    pub corpus: Option<String>,
    /// `--crop WxH`.
    pub crop: Option<String>,
    /// `--video-size WxH`: the video rows' frame size.
    pub video_size: Option<String>,
    /// Also the peak memory of decoding (always with `report`).
    pub memory: bool,
}

/// Images at most this large are used by `bench --quick`.
const QUICK_MAX_PIXELS: usize = 70_000;

/// `hdrcodec bench`.
pub fn bench(o: &BenchOptions) -> Result<()> {
    if let Some(p) = &o.plot {
        hdrcodec_cli::plot::prepare(p)?;
    }
    if let Some(p) = &o.report {
        hdrcodec_cli::report::prepare(p)?;
    }
    let reg = hdrcodec::registry();
    let mut configs = bench::configurations(&reg);
    let mut video_configs = if o.video { video_bench::configurations() } else { Vec::new() };
    if let Some(f) = &o.filter {
        let wanted = |label: &str| f.split(',').any(|part| label.contains(part));
        configs.retain(|c| wanted(&c.label));
        video_configs.retain(|c| wanted(&c.label));
        if configs.is_empty() && video_configs.is_empty() {
            return Err(Error::invalid(format!("no bench configuration matches '{f}'")));
        }
    }
    let crop = o.crop.as_deref().map(|t| real_corpus::parse_size("--crop", t)).transpose()?;
    let (mut inputs, skipped, source) = match o.corpus.as_deref() {
        Some("shared") => {
            let dir = real_corpus::dir()?;
            let (i, s) = bench::path_inputs(&real_corpus::still_files(&dir)?, &reg, &Limits::default())?;
            (i, s, format!("the shared corpus's original EXR and Radiance stills ({})", dir.display()))
        }
        Some(other) if other != "generated" => {
            return Err(Error::invalid(format!("--corpus is 'shared' or 'generated', not '{other}'")))
        }
        _ if o.paths.is_empty() => (bench::generated_inputs(), Vec::new(), "generated corpus".to_string()),
        _ => {
            let (i, s) = bench::path_inputs(&o.paths, &reg, &Limits::default())?;
            (i, s, o.paths.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(" "))
        }
    };
    let mut source = source;
    // The memory rows decode the largest image whole, also when the others are cropped: their
    // figure is that of the largest image (a crop's would be mostly the process's fixed costs).
    let largest = crop.and_then(|_| inputs.iter().max_by_key(|i| i.image.pixel_count()).cloned());
    if let Some(size) = crop {
        real_corpus::crop_inputs(&mut inputs, size)?;
        source.push_str(&format!(", centre {}x{} crops of larger images", size.0, size.1));
    }
    if o.quick {
        inputs.retain(|i| i.image.pixel_count() <= QUICK_MAX_PIXELS);
    }
    if inputs.is_empty() {
        return Err(Error::invalid(format!("no image that hdrcodec can decode in {source}")));
    }
    let context = hdrcodec_cli::report::Context::now(&inputs);
    let video_size = o.video_size.as_deref().map(|t| real_corpus::parse_size("--video-size", t)).transpose()?;
    let sequences =
        if video_configs.is_empty() { Vec::new() } else { video_bench::sequences(&inputs, o.quick, video_size)? };
    let pb = progress_bar(configs.len() * inputs.len() + video_configs.len() * sequences.len(), o.json);
    let pool = ThreadPool::new(o.threads)?;
    let mut report = bench::run(&configs, &inputs, o.runs, &pool, &source, skipped, |done, _, label| {
        pb.set_position(done as u64);
        pb.set_message(label.to_string());
    });
    report.video = video_bench::run(&video_configs, &sequences, o.runs, |label| {
        pb.inc(1);
        pb.set_message(label.to_string());
    });
    if o.memory || o.report.is_some() {
        pb.set_message("peak memory of decoding");
        let memory_inputs = largest.as_ref().map_or(&inputs[..], std::slice::from_ref);
        report.memory = memory::measure(&configs, memory_inputs, &std::env::current_exe()?);
    }
    pb.finish_and_clear();
    if let Some(p) = &o.plot {
        hdrcodec_cli::plot::write(&report, p)?;
    }
    if let Some(p) = &o.report {
        hdrcodec_cli::report::write(&report, &context, p)?;
    }
    if o.json {
        let v = serde_json::to_value(&report).map_err(|e| Error::invalid(format!("cannot format JSON: {e}")))?;
        return print_json(&v);
    }
    if o.per_image {
        print!("{}", bench::per_image_table(&report));
    }
    if !configs.is_empty() {
        print!("{}", bench::table(&report));
    }
    if !report.video.is_empty() {
        print!("{}", video_bench::table(&report.video));
    }
    if !report.memory.is_empty() {
        print!("{}", memory::table(&report.memory));
    }
    Ok(())
}

/// `hdrcodec memory-peak FILE` (hidden; `bench --memory`'s child): one JSON object.
pub fn memory_peak(file: &Path) -> Result<()> {
    let peak = memory::decode_peak(file)?;
    let v = serde_json::to_value(&peak).map_err(|e| Error::invalid(format!("cannot format JSON: {e}")))?;
    print_json(&v)
}

/// The batch's progress bar on stderr (with an ETA), when [`progress_visible`]; per-file failures as `hdrcodec: FILE: reason` lines above it.
struct BatchProgress {
    bar: ProgressBar,
    visible: bool,
}

impl batch::Progress for BatchProgress {
    fn start(&mut self, files: usize) {
        if self.visible {
            self.bar = ProgressBar::new(files as u64);
            if let Ok(style) = ProgressStyle::with_template("{bar:40.cyan/blue} {pos}/{len} {elapsed} ETA {eta} {msg}")
            {
                self.bar.set_style(style);
            }
        }
    }

    fn finished(&mut self, line: &batch::ManifestLine) {
        self.bar.inc(1);
        self.bar.set_message(line.source.clone());
        if let Some(e) = &line.error {
            self.bar.suspend(|| fail(&format!("{}: {e}", line.source)));
        }
    }
}

/// `hdrcodec batch`: prints the summary (text, or one JSON object); fails when a file failed.
pub fn batch(options: &batch::BatchOptions, json: bool) -> Result<()> {
    let mut progress = BatchProgress { bar: ProgressBar::hidden(), visible: progress_visible(json) };
    let summary = batch::run(options, &mut progress);
    progress.bar.finish_and_clear();
    let s = summary?;
    if json {
        let v = serde_json::to_value(&s).map_err(|e| Error::invalid(format!("cannot format JSON: {e}")))?;
        print_json(&v)?;
    } else {
        let shard =
            s.shard.as_ref().map(|k| format!(" (shard {k}; {} in other shards)", s.other_shards)).unwrap_or_default();
        println!("inputs:      {}{shard}", s.inputs);
        println!("converted:   {}", s.converted);
        println!("up to date:  {}", s.up_to_date);
        if s.measured_for_the_manifest > 0 {
            println!(
                "             ({} of them measured for the manifest, which had no line)",
                s.measured_for_the_manifest
            );
        }
        println!("skipped:     {} (not an image of the family)", s.skipped);
        println!("failed:      {}", s.failed);
        println!("bytes:       {} in, {} out", s.bytes_in, s.bytes_out);
        println!("time:        {:.2} s ({} jobs, {} threads)", s.seconds, s.jobs, s.threads);
        println!("manifest:    {}", s.manifest);
        if s.stale_temp_files_removed > 0 {
            println!("removed:     {} temporary files of an interrupted run", s.stale_temp_files_removed);
        }
    }
    if s.failed > 0 {
        return Err(Error::invalid(format!(
            "{} of {} files failed (see {})",
            s.failed,
            s.failed + s.converted,
            s.manifest
        )));
    }
    Ok(())
}

/// `hdrcodec corpus write`.
pub fn corpus_write(dir: &Path) -> Result<()> {
    let reg = hdrcodec::registry();
    let pb = progress_bar(hdrcodec_cli::corpus::scene_names().len(), false);
    let written = hdrcodec_cli::corpus::write(dir, &reg, |name| {
        pb.inc(1);
        pb.set_message(name.to_string());
    });
    pb.finish_and_clear();
    let written = written?;
    println!("wrote {} files to {}", written.len(), dir.display());
    Ok(())
}

/// `hdrcodec corpus large`.
pub fn corpus_large(file: &Path, width: u32, height: u32) -> Result<()> {
    Limits::default().check_image(u64::from(width), u64::from(height), hdrcodec::core::Channels::Rgb)?;
    let reg = hdrcodec::registry();
    let codec = reg.for_output(file)?;
    let mut settings = EncodeSettings::default();
    if codec.name() == "exr" {
        settings = settings.with_option("pixel", "half").with_option("compression", "zip");
    }
    let image = hdrcodec_cli::corpus::large_photo(width, height);
    let (bytes, notes) = hdrcodec::encode_for(codec.as_ref(), &image, &settings)?;
    hdrcodec::write_atomic(file, &bytes)?;
    for n in notes {
        note(&n);
    }
    Ok(())
}

/// `hdrcodec codecs`.
pub fn codecs(json: bool) -> Result<()> {
    let reg = hdrcodec::registry();
    let list: Vec<Value> = reg
        .codecs()
        .iter()
        .map(|c| {
            json!({
                "name": c.name(), "extensions": c.extensions(), "id": String::from_utf8_lossy(&c.id()),
                "encodes": c.can_encode(), "decode_options": c.decode_option_keys(),
            })
        })
        .collect();
    if json {
        return print_json(&json!({ "codecs": list }));
    }
    for c in reg.codecs() {
        let only = if c.can_encode() { "" } else { "  (decodes only)" };
        let keys = c.decode_option_keys();
        let decode = if keys.is_empty() { String::new() } else { format!("  (decode options: {})", keys.join(", ")) };
        println!(
            "{:<10} {:<6} .{}{only}{decode}",
            c.name(),
            String::from_utf8_lossy(&c.id()),
            c.extensions().join(" .")
        );
    }
    Ok(())
}
