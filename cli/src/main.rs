//! The `hdrcodec` command-line tool. Its interface is a contract (DESIGN.md, "The CLI"):
//! exit status 0 on success; otherwise exactly one line `hdrcodec: <reason>` on stderr, a
//! non-zero status and no output file. `--json` prints exactly one JSON object on stdout.

#![forbid(unsafe_code)]

mod cli;
mod video;

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// High-dynamic-range image codecs: convert, inspect, compare and benchmark HDR images.
#[derive(Parser, Debug)]
#[command(name = "hdrcodec", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Convert IN to OUT; formats are chosen by file extension, or OUT's by --codec.
    ///
    /// Colour is converted at most once, only into what OUT's format can record: a format with
    /// no primaries (PFM, DDS) keeps the samples as they are and a note on stderr says so;
    /// `--opt primaries=NAME` (bt709, bt2020, p3, dci-p3, aces, acescg, adobe-rgb, xyz)
    /// converts explicitly. Notes (colour, values clipped to the format's range) are printed
    /// as `hdrcodec: note: ...` lines on stderr after the file is written.
    Convert(ConvertArgs),
    /// Print what a file holds: stored format, size, channels and colour (read from the header),
    /// HDR10 metadata, luminance range (from the decoded pixels). The file is read as the codec
    /// needs it: its header alone, then its pixels as they are decoded (whole only for the codecs
    /// that cannot read a file piece by piece).
    Info {
        /// The image file.
        file: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Compare TEST against REFERENCE with HDR quality metrics.
    ///
    /// Metrics: pu21_psnr (PU21-encoded luminance, dB), pu21_psnr_rgb, de_itp_mean and
    /// de_itp_p99 (ΔE ITP, BT.2124; 1 ≈ one JND), log_rmse (RMS of log2((t+1)/(r+1))), psnr
    /// (linear, dB) and max_rel_err. Identical images are reported as identical; their PSNRs
    /// are infinite, printed as "inf" in text and as null in JSON (JSON has no infinity), with
    /// "identical": true. `--heatmap FILE.png` also draws the per-pixel ΔE ITP in false colour.
    Compare {
        /// The reference image.
        reference: PathBuf,
        /// The image under test.
        test: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Also draw the per-pixel ΔE ITP into this PNG (the image's size, viridis colours, a
        /// colour bar in ΔE ITP units).
        #[arg(long, value_name = "FILE.png")]
        heatmap: Option<PathBuf>,
        /// The ΔE ITP at the top of the heat map's scale (larger errors take its colour).
        #[arg(long, value_name = "DE", default_value_t = hdrcodec_cli::heatmap::DEFAULT_MAX)]
        heatmap_max: f64,
    },
    /// Benchmark every codec configuration on every image of DIR (default: the generated corpus).
    ///
    /// Reports bytes, bits per pixel, PU21-PSNR, ΔE ITP mean, log-RMSE and the median encode
    /// and decode speed in megapixels per second. Non-finite values are null in JSON. JPEG XR
    /// rows decode files written by jxrlib's JxrEncApp (if on PATH, else "not installed"), with
    /// jxrlib's JxrDecApp as the peer decoder.
    Bench(BenchArgs),
    /// Convert every image below IN_DIR into OUT_DIR, keeping the folders, in one format.
    ///
    /// Files no codec recognises are skipped; a file that fails is reported (one line on
    /// stderr, and in the manifest) and the batch goes on; the exit status is non-zero if any
    /// failed. Outputs newer than their source are up to date and kept (`--force` redoes them).
    /// Outputs are written under a temporary name and renamed when whole, so an interrupted
    /// batch leaves no partial output; the next run removes what it left and converts only the
    /// missing files. The manifest (default OUT_DIR/manifest.jsonl) gets one JSON line per file
    /// converted or failed: source, output, bytes_in, bytes_out, pu21_psnr (the output decoded
    /// back against the source), seconds, error.
    Batch(BatchArgs),
    /// The project's generated corpus of synthetic HDR scenes.
    #[command(subcommand)]
    Corpus(CorpusCommand),
    /// HDR video: frames to HDR10 (PQ), HLG or L_p u'v' AV1 in IVF or MP4 (rav1e), and back (libdav1d).
    #[command(subcommand)]
    Video(VideoCommand),
    /// Decode FILE into a whole image and print this process's peak resident memory as JSON
    /// (what `bench --memory` runs in a child process).
    #[command(hide = true)]
    MemoryPeak {
        /// The image file.
        file: PathBuf,
    },
    /// List the codecs of this build: name, file extensions, container id.
    Codecs {
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Args, Debug)]
struct ConvertArgs {
    /// Input image.
    input: PathBuf,
    /// Output image (written only if the whole conversion succeeds).
    output: PathBuf,
    /// Codec for OUT, overriding its extension (`hdrcodec codecs` lists them).
    #[arg(long)]
    codec: Option<String>,
    /// Quality 0-100 for lossy codecs.
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=100))]
    quality: Option<u8>,
    /// Encoder effort 0-9 (0 fastest).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=9))]
    effort: Option<u8>,
    /// Worker threads (0 = one per core).
    #[arg(long)]
    threads: Option<usize>,
    /// Codec-specific option key=value (repeatable). JPEG XR: format=half|float|rgbe|fixed|half4|
    /// rgb8|rgb16|rgb101010 (the stored pixel format), transfer=srgb|pq|linear (integer formats),
    /// lossless, overlap, tile, adaptive, alpha_quality, target_bpp (see codecs/jxr/README.md).
    /// Keys IN's decoder knows go to the decoder: a gain-map JPEG's headroom=H renders for a
    /// display whose HDR white is H times its SDR white (`hdrcodec codecs` lists each codec's).
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
}

#[derive(Args, Debug)]
struct BatchArgs {
    /// The directory of images to convert (walked recursively).
    in_dir: PathBuf,
    /// Where the outputs go (created if missing), in IN_DIR's folder structure.
    out_dir: PathBuf,
    /// Output format: a codec name (`hdrcodec codecs` lists them) or a file extension.
    #[arg(long, value_name = "FORMAT")]
    to: String,
    /// Quality 0-100 for lossy codecs.
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=100))]
    quality: Option<u8>,
    /// Encoder effort 0-9 (0 fastest).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..=9))]
    effort: Option<u8>,
    /// Codec-specific option key=value (repeatable), as for `convert`.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    opts: Vec<String>,
    /// Files converted at once at most (default: one per worker thread); the memory budget
    /// may allow fewer.
    #[arg(long, default_value_t = 0, hide_default_value = true)]
    jobs: usize,
    /// Worker threads of the one pool shared by files and codecs (0 = one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Memory the images in flight may take, e.g. 8G or 500M (default: half of the physical
    /// memory or of the cgroup's limit). A single image larger than this still runs, alone.
    #[arg(long, value_name = "BYTES")]
    memory: Option<String>,
    /// Convert again even when an output is newer than its source.
    #[arg(long)]
    force: bool,
    /// Convert only shard K of N (K from 0): the files whose path hash modulo N is K. Without
    /// it, SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT or JOB_COMPLETION_INDEX with
    /// HDRCODEC_SHARD_COUNT choose the shard when set.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Print the summary as one JSON object on stdout (and no progress bar).
    #[arg(long)]
    json: bool,
    /// The JSON-lines manifest (default: OUT_DIR/manifest.jsonl; OUT_DIR/manifest-K-of-N.jsonl
    /// for a shard).
    #[arg(long, value_name = "FILE")]
    manifest: Option<PathBuf>,
}

#[derive(Args, Debug)]
struct BenchArgs {
    /// Image files and directories of images (default: the generated corpus).
    paths: Vec<PathBuf>,
    /// `shared`: the shared corpus of real HDR images (`$HDRCODEC_CORPUS`, else
    /// `../shared/corpus`): the original OpenEXR and Radiance files its MANIFEST.tsv lists (13
    /// photographs, environment maps and test charts, 0.24-1.09 MP each, 8.4 MP in all: pair it
    /// with `--crop` or `--filter` on a small machine). `generated` (the default without PATHS):
    /// the project's own generated corpus.
    #[arg(long, value_name = "shared|generated", conflicts_with = "paths")]
    corpus: Option<String>,
    /// Bench the centre WIDTHxHEIGHT window of every larger image (its rows are named
    /// `NAME@cWxH`).
    #[arg(long, value_name = "WxH")]
    crop: Option<String>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
    /// Also draw rate-distortion curves into this PNG file (bits per pixel against PU21-PSNR and
    /// against ΔE ITP, one line per codec family's quality sweep), and the one-thread decode and
    /// encode speeds into FILE-speed.png beside it.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// Also write the run as a Markdown page (machine, date, commit, peer tools and versions, the
    /// command that regenerates it, the tables, the plots as FILE-rd.png and FILE-rd-speed.png
    /// beside it).
    #[arg(long, value_name = "FILE.md")]
    report: Option<PathBuf>,
    /// Threads of the pool behind the all-thread speed columns (0 = one per core); every
    /// measurement is also made on one thread.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Also print one line per configuration and image.
    #[arg(long)]
    per_image: bool,
    /// Only configurations whose label contains this text, or one of several separated by
    /// commas (`jxr,bc6h:effort2`).
    #[arg(long)]
    filter: Option<String>,
    /// Timed runs per measurement (the median is reported).
    #[arg(long, default_value_t = 3, hide = true)]
    runs: usize,
    /// One run per measurement and only the smaller images: for tests.
    #[arg(long, hide = true)]
    quick: bool,
    /// Also run the HDR10 AV1 video rows: ours (rav1e) and FFmpeg's SVT-AV1 at a sweep of
    /// quantizers, on a generated moving light (256x144, 12 frames) and a pan across a crop of
    /// the largest image (320x176 at most), decoded by libdav1d; FFmpeg's libdav1d decode is
    /// the peer. `--filter` applies to their labels too (`av1:q100`, `av1(svt-av1):crf25`).
    #[arg(long)]
    video: bool,
    /// The video rows' frame size (default 256x144; e.g. 1920x1080 for speeds at 1080p): the
    /// moving light at that size, the pan's window at most that and half the largest image.
    #[arg(long, value_name = "WxH", requires = "video")]
    video_size: Option<String>,
    /// Also measure, per codec, the peak resident memory of decoding the largest image (in a
    /// child process) against the decoded image's size; every --report does.
    #[arg(long)]
    memory: bool,
}

#[derive(Subcommand, Debug)]
enum CorpusCommand {
    /// Write every generated scene as a 32-bit float OpenEXR file, plus MANIFEST.tsv.
    Write {
        /// Output directory (created if missing).
        dir: PathBuf,
    },
    /// Write one large photograph-like image (half-precision samples, a sky, a ground, light
    /// sources, grain) for memory and speed measurements; the format follows FILE's extension.
    Large {
        /// Output file (e.g. big.exr: half float, ZIP).
        file: PathBuf,
        /// Width in pixels.
        #[arg(long, default_value_t = 3712)]
        width: u32,
        /// Height in pixels.
        #[arg(long, default_value_t = 3624)]
        height: u32,
    },
}

#[derive(Subcommand, Debug)]
enum VideoCommand {
    /// Encode frames to OUT.ivf, OUT.mp4, OUT.mkv or OUT.webm (Matroska with the colour elements): BT.2020, 10-bit 4:2:0 limited range, PQ with
    /// MaxCLL/MaxFALL (measured over all frames) and a BT.2020 1000 cd/m² mastering display (or
    /// the first frame's own), or HLG for a 1000 cd/m² display; or L_p u'v' (Mantiuk 2004, ψ at
    /// 11 bits) in 12-bit 4:4:4 planes, named by an hdrcodec-lpuv T.35 message.
    ///
    /// FRAMES is a list of image files (one per frame, in order), or one of: a printf-style
    /// pattern such as `frames/f%05d.exr` (consecutive numbers from the smallest that exists),
    /// a directory (its image files in name order), or a YUV4MPEG2 file (`.y4m`: 8, 10 or
    /// 12-bit 4:2:0 or 4:4:4, read one frame at a time). Y4M does not say its colour: its
    /// Y'CbCr is taken as BT.2020 non-constant-luminance on --input-transfer (PQ unless told),
    /// limited range unless the header says XCOLORRANGE=FULL.
    ///
    /// A progress bar is drawn on stderr when it is a terminal (not with --json).
    Encode {
        /// The frames (files, or one pattern, directory or .y4m), then the output .ivf, .mp4, .mkv or .webm.
        #[arg(required = true, num_args = 2.., value_name = "FRAMES... OUT.ivf")]
        paths: Vec<PathBuf>,
        /// Transfer function: pq (HDR10), hlg, or mantiuk (L_p u'v', 12-bit AV1 profile 2).
        #[arg(long, default_value = "pq")]
        transfer: String,
        /// Bits of the planes for --transfer mantiuk: 12 (default; 11-bit luma, AV1 profile 2) or
        /// 10 (10-bit luma; with --chroma 420 AV1's Main profile, which hardware decoders play).
        #[arg(long)]
        bits: Option<u8>,
        /// The transfer a .y4m input's Y'CbCr is on (Y4M cannot say): pq or hlg (BT.2020).
        #[arg(long, default_value = "pq")]
        input_transfer: String,
        /// Chroma planes: 420 or 444 (default: 420 for pq and hlg, 444 for mantiuk).
        #[arg(long)]
        chroma: Option<String>,
        /// Quality 0-100 (mapped linearly onto rav1e's quantizer 255-0; 61 is quantizer 100).
        #[arg(long, default_value_t = 61, value_parser = clap::value_parser!(u8).range(0..=100))]
        quality: u8,
        /// rav1e speed preset 0-10 (10 fastest).
        #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u8).range(0..=10))]
        speed: u8,
        /// Worker threads (0 = one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Print one JSON object (output, frames, bytes, content light, notes) and no progress bar.
        #[arg(long)]
        json: bool,
        /// Also write an SDR rendition of the same frames to this .ivf, .mp4, .mkv or .webm: core's GT tone
        /// curve for an SDR display of --sdr-peak cd/m² (scene 100 cd/m² is paper white), through
        /// its LUT form, in BT.709, the sRGB OETF, 8-bit 4:2:0 limited range, signalled as
        /// BT.709 primaries and matrix with the sRGB transfer (H.273 1/13/1).
        #[arg(long, value_name = "OUT")]
        sdr: Option<PathBuf>,
        /// The SDR display's peak for --sdr, cd/m² (50 to 1000).
        #[arg(long, default_value_t = 100.0)]
        sdr_peak: f64,
    },
    /// Decode IN (.ivf, .mp4 or an .hdrc sequence) into OUT_DIR as frame_00000.exr, ... (linear;
    /// AV1 in BT.2020, 1.0 = 100 cd/m²). A progress bar is drawn on stderr when it is a terminal.
    Decode {
        /// The stream.
        input: PathBuf,
        /// Output directory (created if missing).
        out_dir: PathBuf,
        /// Print one JSON object (frames, codec) and no progress bar.
        #[arg(long)]
        json: bool,
    },
}

/// The batch engine's options from the command line; the shard from `--shard`, else from the
/// batch system's environment variables.
fn batch_options(a: BatchArgs) -> hdrcodec::core::Result<(hdrcodec_cli::batch::BatchOptions, bool)> {
    use hdrcodec_cli::batch::{self, Shard};
    let shard = match &a.shard {
        Some(text) => Some(Shard::parse(text)?),
        None => Shard::from_env(|name| std::env::var(name).ok())?,
    };
    let memory_budget = match &a.memory {
        Some(text) => batch::parse_bytes(text)?,
        None => batch::default_memory_budget(),
    };
    let options = batch::BatchOptions {
        in_dir: a.in_dir,
        out_dir: a.out_dir,
        to: a.to,
        quality: a.quality,
        effort: a.effort,
        opts: a.opts,
        jobs: a.jobs,
        threads: a.threads,
        memory_budget,
        force: a.force,
        shard,
        manifest: a.manifest,
    };
    Ok((options, a.json))
}

fn main() -> ExitCode {
    cli::install_panic_hook();
    cli::run_catching_panics(run)
}

fn run() -> ExitCode {
    let args = match Cli::try_parse() {
        Ok(a) => a,
        Err(e) => return cli::clap_error(e),
    };
    if let Err(e) = cli::remove_temp_files_on_signal() {
        cli::fail(&format!("cannot install the signal handler: {e}"));
        return ExitCode::FAILURE;
    }
    let result = match args.command {
        Command::Convert(a) => {
            cli::convert(&a.input, &a.output, a.codec.as_deref(), a.quality, a.effort, a.threads, &a.opts)
        }
        Command::Info { file, json } => cli::info(&file, json),
        Command::Compare { reference, test, json, heatmap, heatmap_max } => {
            cli::compare(&reference, &test, json, heatmap.as_deref().map(|p| (p, heatmap_max)))
        }
        Command::Bench(a) => cli::bench(&cli::BenchOptions {
            paths: a.paths,
            json: a.json,
            plot: a.plot,
            report: a.report,
            threads: a.threads,
            filter: a.filter,
            per_image: a.per_image,
            runs: if a.quick { 1 } else { a.runs.max(1) },
            quick: a.quick,
            video: a.video,
            corpus: a.corpus,
            crop: a.crop,
            video_size: a.video_size,
            memory: a.memory,
        }),
        Command::MemoryPeak { file } => cli::memory_peak(&file),
        Command::Batch(a) => batch_options(a).and_then(|(options, json)| cli::batch(&options, json)),
        Command::Corpus(CorpusCommand::Write { dir }) => cli::corpus_write(&dir),
        Command::Corpus(CorpusCommand::Large { file, width, height }) => cli::corpus_large(&file, width, height),
        Command::Video(VideoCommand::Encode {
            paths,
            transfer,
            bits,
            input_transfer,
            chroma,
            quality,
            speed,
            threads,
            json,
            sdr,
            sdr_peak,
        }) => match paths.split_last() {
            Some((output, frames)) => {
                let args = video::VideoEncodeArgs {
                    frames,
                    output,
                    transfer: &transfer,
                    bits,
                    input_transfer: &input_transfer,
                    chroma: chroma.as_deref(),
                    quality,
                    speed,
                    threads,
                    json,
                    sdr: sdr.as_deref(),
                    sdr_peak,
                };
                video::encode(&args).map(|notes| notes.iter().for_each(|n| cli::note(n)))
            }
            None => Err(hdrcodec::core::Error::invalid("video encode needs FRAMES... OUT.ivf")),
        },
        Command::Video(VideoCommand::Decode { input, out_dir, json }) => video::decode(&input, &out_dir, json),
        Command::Codecs { json } => cli::codecs(json),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            cli::fail(&e.to_string());
            ExitCode::FAILURE
        }
    }
}
