//! `hdrcodec batch`: converts every image below a directory into one format, a bounded amount of
//! memory at a time, resumably, and optionally only a deterministic shard of the files.
//!
//! - **Files.** IN_DIR is walked recursively (symbolic links to directories are not followed);
//!   a file is an input when a codec of the family handles its extension or recognises its first
//!   bytes; other files are counted as skipped. Our own temporary files are never inputs. Each
//!   output keeps its source's relative folder under OUT_DIR, with the target's extension.
//! - **Memory.** Before a file starts, its header is probed from the file
//!   ([`Registry::probe_file`]: nothing of the image's size is allocated, and the file is not
//!   read whole by the codecs that can read their header alone) and its cost estimated by
//!   [`in_flight_cost`]; the source, and the output decoded back, are decoded from their files
//!   ([`ImageCodec::decode_from`]), so a codec that reads its file piece by piece never holds
//!   it. [`Admission`] starts a file only while the costs of the files in flight fit the budget
//!   (one file always runs, however large).
//! - **Threads.** One rayon pool: each admitted file is a task on it, and the same pool is the
//!   codecs' [`ThreadPool`], so a codec's parallel work runs on the workers the other files
//!   leave idle: never more threads than the pool has. `jobs` caps the files in flight.
//! - **Resuming.** Outputs are written to a temporary name and renamed when whole
//!   ([`hdrcodec::write_atomic_with`]); an output newer than its source is up to date and not
//!   redone (unless `force`); temporary files that a killed run left for this shard's outputs
//!   are removed first.
//! - **Manifest.** One JSON line per file converted or failed, appended as each file ends with
//!   one `write` of a whole line, so a run killed at any point leaves only whole lines (a torn
//!   last line, from a full disk or a power cut, is cut off by the next run). The manifest of
//!   several runs is their log: the last line of a source is the current one.
//! - **Shards.** [`Shard`] takes a file when the FNV-1a hash of its relative path (with `/`)
//!   modulo N is K: stable under additions, the same on every machine.

use crate::conversion::ConversionSettings;
use hdrcodec::core::{metrics, Error, ImageCodec, ImageInfo, Limits, Result, ThreadPool};
use hdrcodec::Registry;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc};
use std::time::{Instant, SystemTime};

/// FNV-1a, 64 bits (Fowler, Noll, Vo): a fixed, portable hash, unlike Rust's randomly keyed
/// default hasher, so that every machine and every run puts a file in the same shard.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    bytes.iter().fold(OFFSET_BASIS, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME))
}

/// One of N disjoint parts of the files: `index` in `0..count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which part, counting from 0.
    pub index: u64,
    /// How many parts (at least 1).
    pub count: u64,
}

/// The environment variable that gives the shard count next to Kubernetes'
/// `JOB_COMPLETION_INDEX` (which says only the index); set it to the Job's `completions`.
pub const SHARD_COUNT_VAR: &str = "HDRCODEC_SHARD_COUNT";

impl Shard {
    /// Parses `K/N` (K counted from 0, K < N).
    pub fn parse(text: &str) -> Result<Shard> {
        let bad = || Error::invalid(format!("--shard {text}: expected K/N with 0 <= K < N (K counts from 0)"));
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (k.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
        Shard::new(index, count).ok_or_else(bad)
    }

    fn new(index: u64, count: u64) -> Option<Shard> {
        (count > 0 && index < count).then_some(Shard { index, count })
    }

    /// The shard a batch engine assigned through the environment, if any: a Slurm job array
    /// (`SLURM_ARRAY_TASK_ID` - `SLURM_ARRAY_TASK_MIN`, divided by `SLURM_ARRAY_TASK_STEP`, of
    /// `SLURM_ARRAY_TASK_COUNT`, so `--array=1-8` and `--array=0-7` both work), else a Kubernetes
    /// indexed Job (`JOB_COMPLETION_INDEX` of [`SHARD_COUNT_VAR`], which must then be set).
    /// `var` looks a variable up (`std::env::var` in the tool; a map in tests).
    pub fn from_env(var: impl Fn(&str) -> Option<String>) -> Result<Option<Shard>> {
        let number = |name: &str| -> Result<Option<u64>> {
            match var(name) {
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<u64>()
                    .map(Some)
                    .map_err(|_| Error::invalid(format!("{name}={v} is not a whole number"))),
            }
        };
        if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let count = number("SLURM_ARRAY_TASK_COUNT")?
                .ok_or_else(|| Error::invalid("SLURM_ARRAY_TASK_ID is set but not SLURM_ARRAY_TASK_COUNT"))?;
            let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            let index = id.checked_sub(min).map(|d| d / step);
            return index.and_then(|i| Shard::new(i, count)).map(Some).ok_or_else(|| {
                Error::invalid(format!(
                    "SLURM_ARRAY_TASK_ID={id} is not one of {count} tasks from {min} in steps of {step}"
                ))
            });
        }
        if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            let count = number(SHARD_COUNT_VAR)?.ok_or_else(|| {
                Error::invalid(format!(
                    "JOB_COMPLETION_INDEX is set but not {SHARD_COUNT_VAR} (set it to the Job's completions, or pass --shard K/N)"
                ))
            })?;
            return Shard::new(index, count).map(Some).ok_or_else(|| {
                Error::invalid(format!("JOB_COMPLETION_INDEX={index} is not below {SHARD_COUNT_VAR}={count}"))
            });
        }
        Ok(None)
    }

    /// True when the file at `relative` (a path below IN_DIR) belongs to this shard.
    pub fn contains(&self, relative: &Path) -> bool {
        fnv1a64(portable_path(relative).as_bytes()) % self.count == self.index
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// `relative` with `/` between its parts, whatever the platform's separator.
fn portable_path(relative: &Path) -> String {
    relative.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/")
}

/// Parses a size in bytes: a number with an optional binary unit, `K`, `M`, `G` or `T`
/// (also `KB`, `KiB`, ...; 1G = 2^30 bytes), and a fraction if wanted (`1.5G`).
pub fn parse_bytes(text: &str) -> Result<u64> {
    let bad = || Error::invalid(format!("'{text}' is not a size (examples: 500M, 8G, 1073741824)"));
    let t = text.trim();
    let digits_end = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(digits_end);
    let number: f64 = number.parse().map_err(|_| bad())?;
    let unit = unit.trim().to_ascii_uppercase();
    let unit = unit.trim_end_matches('B').trim_end_matches('I');
    let scale = match unit {
        "" => 1u64,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        "T" => 1 << 40,
        _ => return Err(bad()),
    };
    let bytes = number * scale as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes > u64::MAX as f64 {
        return Err(bad());
    }
    Ok(bytes as u64)
}

/// The budget used without `--memory`: half of the memory this process may use, the smaller
/// of the machine's (`MemTotal` in /proc/meminfo) and the cgroup's limit (a container's or a
/// Slurm job's, /sys/fs/cgroup/memory.max); 2 GiB where neither can be read.
pub fn default_memory_budget() -> u64 {
    const FALLBACK: u64 = 2 << 30;
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| mem_total_bytes(&s));
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok().and_then(|s| s.trim().parse::<u64>().ok());
    match (total, cgroup) {
        (Some(t), Some(c)) => t.min(c) / 2,
        (Some(m), None) | (None, Some(m)) => m / 2,
        (None, None) => FALLBACK,
    }
}

/// `MemTotal` of a /proc/meminfo text, in bytes.
fn mem_total_bytes(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// What one file in flight is assumed to hold at its peak, in bytes: its encoded bytes (which
/// the decoders that cannot read a file piece by piece read whole), the decoded source (kept for the PU21-PSNR), the output decoded back, and as much again for the
/// encoder's working memory and the bytes it writes (measured peaks: README, "hdrcodec batch").
pub fn in_flight_cost(info: &ImageInfo, file_bytes: u64) -> u64 {
    file_bytes.saturating_add(info.decoded_bytes().saturating_mul(3))
}

/// Which files may start: at most `jobs` in flight, and their costs within `budget`, except
/// that a file starts alone when nothing else is in flight even if it is larger than the budget
/// (it cannot be made smaller; it runs by itself). First come, first served: a large file waits
/// until enough memory is free, and the smaller files behind it wait with it, so none starves.
#[derive(Clone, Debug)]
pub struct Admission {
    budget: u64,
    jobs: usize,
    in_flight_bytes: u64,
    in_flight: usize,
}

impl Admission {
    /// Nothing in flight yet; `jobs` is at least 1.
    pub fn new(budget: u64, jobs: usize) -> Self {
        Admission { budget, jobs: jobs.max(1), in_flight_bytes: 0, in_flight: 0 }
    }

    /// Starts a file of `cost` bytes if it may start now.
    pub fn try_admit(&mut self, cost: u64) -> bool {
        let fits = self.in_flight_bytes.saturating_add(cost) <= self.budget;
        if self.in_flight == 0 || (self.in_flight < self.jobs && fits) {
            self.in_flight += 1;
            self.in_flight_bytes = self.in_flight_bytes.saturating_add(cost);
            return true;
        }
        false
    }

    /// A file of `cost` bytes has finished.
    pub fn release(&mut self, cost: u64) {
        self.in_flight = self.in_flight.saturating_sub(1);
        self.in_flight_bytes = self.in_flight_bytes.saturating_sub(cost);
    }

    /// Files in flight.
    pub fn in_flight(&self) -> usize {
        self.in_flight
    }

    /// The summed cost of the files in flight.
    pub fn in_flight_bytes(&self) -> u64 {
        self.in_flight_bytes
    }
}

/// What `hdrcodec batch` was asked to do.
#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// The tree of sources.
    pub in_dir: PathBuf,
    /// Where the outputs go, in the same folders as their sources.
    pub out_dir: PathBuf,
    /// Codec name or file extension of the output format.
    pub to: String,
    /// `--quality` (the codec's default without it).
    pub quality: Option<u8>,
    /// `--effort` (the codec's default without it).
    pub effort: Option<u8>,
    /// `--opt key=value` options, to the decoder that knows the key, else the encoder.
    pub opts: Vec<String>,
    /// Files in flight at most (0: one per thread).
    pub jobs: usize,
    /// Worker threads of the one pool (0: one per core).
    pub threads: usize,
    /// Bytes the files in flight may hold ([`in_flight_cost`]).
    pub memory_budget: u64,
    /// Convert even where an up-to-date output exists.
    pub force: bool,
    /// Only this shard of the files (all without it).
    pub shard: Option<Shard>,
    /// The manifest file (default: OUT_DIR/manifest.jsonl, or manifest-K-of-N.jsonl for a shard).
    pub manifest: Option<PathBuf>,
}

/// The outcome of a batch (`--json` prints it).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    /// Inputs found below IN_DIR (all shards).
    pub inputs: usize,
    /// Inputs left to the other shards.
    pub other_shards: usize,
    /// Files converted in this run.
    pub converted: usize,
    /// Files no codec of the family recognises.
    pub skipped: usize,
    /// Files whose output was already newer than the source.
    pub up_to_date: usize,
    /// Up-to-date outputs that had no manifest line (their run was killed before writing it):
    /// measured and recorded now, not re-encoded; counted among `up_to_date` too.
    pub measured_for_the_manifest: usize,
    /// Files that failed (each reported on stderr and in the manifest).
    pub failed: usize,
    /// Bytes of the sources converted and of their outputs.
    pub bytes_in: u64,
    /// Bytes of the outputs written.
    pub bytes_out: u64,
    /// Wall-clock time of the batch.
    pub seconds: f64,
    /// Temporary files of an earlier, killed run that were removed.
    pub stale_temp_files_removed: usize,
    /// The manifest file appended to.
    pub manifest: String,
    /// The shard run, as `K/N`.
    pub shard: Option<String>,
    /// The memory budget of the files in flight, bytes.
    pub memory_budget: u64,
    /// Files in flight at most.
    pub jobs: usize,
    /// Worker threads of the pool.
    pub threads: usize,
    /// The largest summed [`in_flight_cost`] of the files in flight at once, and their most.
    pub peak_in_flight_cost: u64,
    /// The most files in flight at once.
    pub peak_in_flight_files: usize,
}

/// One line of the manifest.
#[derive(Clone, Debug, Serialize)]
pub struct ManifestLine {
    /// The source file.
    pub source: String,
    /// The output file.
    pub output: String,
    /// Bytes of the source.
    pub bytes_in: u64,
    /// Bytes of the output; null when it failed.
    pub bytes_out: Option<u64>,
    /// PU21-PSNR of the output decoded back against the source, dB; null when identical
    /// (infinite) or failed.
    pub pu21_psnr: Option<f64>,
    /// Whether the output decodes to exactly the source's samples.
    pub identical: Option<bool>,
    /// Seconds spent on this file.
    pub seconds: f64,
    /// Why it failed, if it did.
    pub error: Option<String>,
    /// What the conversion noted (colour kept or converted, values clipped).
    pub notes: Vec<String>,
    /// True when the output was found whole from an interrupted run and only measured now
    /// (`seconds` is then the measurement's; the notes of its encoding are lost).
    pub reused_output: bool,
}

/// What the caller hears while a batch runs: the number of files to convert once known, then
/// each file as it ends.
pub trait Progress {
    /// The number of files to convert.
    fn start(&mut self, files: usize);
    /// One file ended (converted or failed).
    fn finished(&mut self, line: &ManifestLine);
}

/// The temporary-file name pattern of [`hdrcodec::write_atomic_with`] is `.NAME.PID.tmp`.
fn is_any_atomic_temp(name: &str) -> bool {
    name.starts_with('.')
        && name
            .strip_suffix(".tmp")
            .and_then(|rest| rest.rsplit_once('.'))
            .is_some_and(|(_, pid)| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}

/// The inputs below `in_dir` (relative paths, sorted) and how many other files were skipped.
/// `exclude` (OUT_DIR when it lies inside IN_DIR) is not entered.
pub fn find_inputs(in_dir: &Path, exclude: Option<&Path>, registry: &Registry) -> Result<(Vec<PathBuf>, usize)> {
    let mut inputs = Vec::new();
    let mut skipped = 0;
    let mut dirs = vec![PathBuf::new()];
    let io = |e: std::io::Error, p: &Path| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", p.display())));
    while let Some(rel_dir) = dirs.pop() {
        let dir = in_dir.join(&rel_dir);
        if exclude.is_some_and(|x| same_file(&dir, x)) {
            continue;
        }
        for entry in std::fs::read_dir(&dir).map_err(|e| io(e, &dir))? {
            let entry = entry.map_err(|e| io(e, &dir))?;
            let rel = rel_dir.join(entry.file_name());
            let kind = entry.file_type().map_err(|e| io(e, &entry.path()))?;
            if kind.is_dir() {
                dirs.push(rel);
                continue;
            }
            // A symbolic link counts when it points to a file; one to a directory is not
            // followed (no cycles).
            if !entry.path().is_file() {
                continue;
            }
            let name = entry.file_name().to_string_lossy().into_owned();
            if !is_any_atomic_temp(&name) && recognised(&entry.path(), registry) {
                inputs.push(rel);
            } else {
                skipped += 1;
            }
        }
    }
    inputs.sort();
    Ok((inputs, skipped))
}

/// True when a codec handles `path`'s extension or recognises its first bytes.
fn recognised(path: &Path, registry: &Registry) -> bool {
    let by_extension = path.extension().and_then(|e| e.to_str()).is_some_and(|e| !registry.by_extension(e).is_empty());
    if by_extension {
        return true;
    }
    let mut head = Vec::with_capacity(64);
    match std::fs::File::open(path) {
        Ok(f) => f.take(64).read_to_end(&mut head).is_ok() && registry.sniff(&head).is_some(),
        Err(_) => false,
    }
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// The output codec that `--to` names: a codec name, else a file extension.
pub fn output_codec(registry: &Registry, to: &str) -> Result<Arc<dyn ImageCodec>> {
    let codec = match registry.by_name(to) {
        Ok(c) => c,
        Err(_) => registry.by_extension(to).into_iter().next().ok_or_else(|| {
            Error::unsupported(format!(
                "--to {to}: neither a codec (known: {}) nor a file extension (known: {})",
                registry.names().join(", "),
                registry.extensions().join(", ")
            ))
        })?,
    };
    if !codec.can_encode() {
        return Err(Error::unsupported(format!("{} decodes only and cannot be a batch's output", codec.name())));
    }
    Ok(codec)
}

/// A file to convert: its paths, and whether its output is already there.
struct Job {
    source: PathBuf,
    output: PathBuf,
    /// The output is up to date but the manifest has no line for it (a run was killed between
    /// renaming it into place and writing its line): it is decoded and measured, not re-encoded.
    reuse_output: bool,
}

/// Runs the batch. Per-file failures are in the summary and the manifest, not in the result;
/// `Err` means the batch could not run at all (unreadable IN_DIR, bad options).
pub fn run(o: &BatchOptions, progress: &mut dyn Progress) -> Result<Summary> {
    let started = Instant::now();
    let registry = hdrcodec::registry();
    let out_codec = output_codec(&registry, &o.to)?;
    let extension = out_codec.extensions().first().copied().unwrap_or("out");
    if !o.in_dir.is_dir() {
        return Err(Error::invalid(format!("{} is not a directory", o.in_dir.display())));
    }
    std::fs::create_dir_all(&o.out_dir)
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", o.out_dir.display()))))?;
    if same_file(&o.in_dir, &o.out_dir) {
        return Err(Error::invalid("OUT_DIR must not be IN_DIR (outputs would be taken for inputs)"));
    }
    let threads = if o.threads == 0 { hdrcodec::core::threads::available_cores() } else { o.threads };
    let jobs = if o.jobs == 0 { threads } else { o.jobs };
    let rayon_pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("hdrcodec-batch-{i}"))
            .build()
            .map_err(|e| Error::Io(std::io::Error::other(format!("cannot start {threads} worker threads: {e}"))))?,
    );
    let conversion =
        Arc::new(ConversionSettings::new(o.quality, o.effort, ThreadPool::from_rayon(rayon_pool.clone()), &o.opts)?);
    let manifest_path = o.manifest.clone().unwrap_or_else(|| {
        o.out_dir.join(match o.shard {
            None => "manifest.jsonl".to_string(),
            Some(s) => format!("manifest-{}-of-{}.jsonl", s.index, s.count),
        })
    });
    let (mut manifest, recorded_outputs) = Manifest::open(&manifest_path)?;
    // The recorded outputs by file name, for [`recorded_in`].
    let mut recorded: HashMap<std::ffi::OsString, Vec<PathBuf>> = HashMap::new();
    for output in recorded_outputs.into_iter().map(PathBuf::from) {
        if let Some(name) = output.file_name() {
            recorded.entry(name.to_os_string()).or_default().push(output.clone());
        }
    }
    let mut summary = Summary {
        manifest: manifest_path.display().to_string(),
        shard: o.shard.map(|s| s.to_string()),
        memory_budget: o.memory_budget,
        jobs,
        threads,
        ..Default::default()
    };

    let (inputs, skipped) = find_inputs(&o.in_dir, Some(&o.out_dir), &registry)?;
    summary.inputs = inputs.len();
    summary.skipped = skipped;
    // Two sources that differ only by extension would write the same output: the first (in
    // path order, the same in every shard) gets it, the others fail.
    let mut claimed: HashMap<PathBuf, PathBuf> = HashMap::new();
    let mut pending = Vec::new();
    let mut collisions = Vec::new();
    for rel in inputs {
        let out_rel = rel.with_extension(extension);
        let mine = o.shard.is_none_or(|s| s.contains(&rel));
        match claimed.get(&out_rel) {
            Some(first) if mine => collisions.push((rel.clone(), out_rel.clone(), first.clone())),
            Some(_) => {}
            None => {
                claimed.insert(out_rel.clone(), rel.clone());
                if mine {
                    pending.push((rel, out_rel));
                }
            }
        }
        if !mine {
            summary.other_shards += 1;
        }
    }
    summary.stale_temp_files_removed = remove_stale_temps(&o.out_dir, pending.iter().map(|(_, out)| out.as_path()));
    let mut jobs_to_run = Vec::new();
    for (rel, out_rel) in pending {
        let mut job = Job { source: o.in_dir.join(&rel), output: o.out_dir.join(&out_rel), reuse_output: false };
        if !o.force && up_to_date(&job.source, &job.output) {
            summary.up_to_date += 1;
            if recorded_in(&recorded, &out_rel) {
                continue;
            }
            job.reuse_output = true;
        }
        jobs_to_run.push(job);
    }
    progress.start(jobs_to_run.len() + collisions.len());
    for (rel, out_rel, first) in collisions {
        let line = failed_line(
            &o.in_dir.join(&rel),
            &o.out_dir.join(&out_rel),
            0,
            0.0,
            &Error::invalid(format!("{} writes the same output", o.in_dir.join(first).display())),
        );
        record(&line, &mut summary, &mut manifest, progress)?;
    }

    let mut admission = Admission::new(o.memory_budget, jobs);
    let (done_tx, done_rx) = mpsc::channel::<(ManifestLine, u64)>();
    let mut queue = jobs_to_run.into_iter();
    let mut waiting: Option<(Job, Opened, u64)> = None;
    loop {
        // Start files while the budget allows, in order.
        loop {
            if waiting.is_none() {
                let Some(job) = queue.next() else { break };
                let t0 = Instant::now();
                match open_and_cost(&job, &registry) {
                    Ok((opened, cost)) => waiting = Some((job, opened, cost)),
                    Err(e) => {
                        let line = failed_line(&job.source, &job.output, 0, t0.elapsed().as_secs_f64(), &e);
                        record(&line, &mut summary, &mut manifest, progress)?;
                        continue;
                    }
                }
            }
            let Some((_, _, cost)) = &waiting else { break };
            if !admission.try_admit(*cost) {
                break;
            }
            summary.peak_in_flight_cost = summary.peak_in_flight_cost.max(admission.in_flight_bytes());
            summary.peak_in_flight_files = summary.peak_in_flight_files.max(admission.in_flight());
            let Some((job, opened, cost)) = waiting.take() else { break };
            let (tx, conversion, registry, out_codec) =
                (done_tx.clone(), conversion.clone(), registry.clone(), out_codec.clone());
            rayon_pool.spawn(move || {
                let line = convert_one(&job, opened, &registry, out_codec.as_ref(), &conversion);
                // The receiver lives until every file has reported.
                let _ = tx.send((line, cost));
            });
        }
        if admission.in_flight() == 0 {
            break;
        }
        let Ok((line, cost)) = done_rx.recv() else { break };
        admission.release(cost);
        record(&line, &mut summary, &mut manifest, progress)?;
    }
    summary.seconds = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// Counts a finished file and appends its manifest line.
fn record(
    line: &ManifestLine,
    summary: &mut Summary,
    manifest: &mut Manifest,
    progress: &mut dyn Progress,
) -> Result<()> {
    if line.error.is_some() {
        summary.failed += 1;
    } else if line.reused_output {
        summary.measured_for_the_manifest += 1;
    } else {
        summary.converted += 1;
        summary.bytes_in += line.bytes_in;
        summary.bytes_out += line.bytes_out.unwrap_or(0);
    }
    manifest.append(line)?;
    progress.finished(line);
    Ok(())
}

fn failed_line(source: &Path, output: &Path, bytes_in: u64, seconds: f64, e: &Error) -> ManifestLine {
    ManifestLine {
        source: source.display().to_string(),
        output: output.display().to_string(),
        bytes_in,
        bytes_out: None,
        pu21_psnr: None,
        identical: None,
        seconds,
        error: Some(e.to_string()),
        notes: Vec::new(),
        reused_output: false,
    }
}

/// True when the manifest's outputs (`recorded`) hold `out_rel` (a path below OUT_DIR): compared
/// by their last components, so that OUT_DIR spelt otherwise (`./out`, an absolute path) in an
/// earlier run still matches.
fn recorded_in(recorded: &HashMap<std::ffi::OsString, Vec<PathBuf>>, out_rel: &Path) -> bool {
    let Some(name) = out_rel.file_name() else { return false };
    recorded.get(name).is_some_and(|paths| paths.iter().any(|p| p.ends_with(out_rel)))
}

/// True when `output` exists and was written after `source` last changed.
fn up_to_date(source: &Path, output: &Path) -> bool {
    let modified = |p: &Path| -> Option<SystemTime> { std::fs::metadata(p).ok()?.modified().ok() };
    matches!((modified(source), modified(output)), (Some(s), Some(o)) if o > s)
}

/// Removes the temporary files that killed runs left for `outputs` (paths below `out_dir`):
/// only those of this run's own outputs, so that shards running at the same time in the same
/// OUT_DIR never remove each other's. Returns how many were removed.
fn remove_stale_temps<'a>(out_dir: &Path, outputs: impl Iterator<Item = &'a Path>) -> usize {
    let mut by_dir: BTreeMap<PathBuf, Vec<String>> = BTreeMap::new();
    for out in outputs {
        let dir = out.parent().map(Path::to_path_buf).unwrap_or_default();
        if let Some(name) = out.file_name() {
            by_dir.entry(dir).or_default().push(name.to_string_lossy().into_owned());
        }
    }
    let mut removed = 0;
    for (dir, names) in by_dir {
        let Ok(entries) = std::fs::read_dir(out_dir.join(&dir)) else { continue };
        for entry in entries.flatten() {
            let candidate = entry.file_name().to_string_lossy().into_owned();
            if names.iter().any(|n| hdrcodec::is_atomic_temp_name_of(n, &candidate))
                && std::fs::remove_file(entry.path()).is_ok()
            {
                removed += 1;
            }
        }
    }
    removed
}

/// A source opened for its decoder: the codec that reads it, the file (at its start) and its
/// size in bytes.
struct Opened {
    codec: Arc<dyn ImageCodec>,
    file: std::fs::File,
    bytes: u64,
}

/// Opens a source and estimates its cost from its header alone, read from the file
/// ([`Registry::probe_file`]): the file is not read whole here, and is decoded from the file
/// later ([`ImageCodec::decode_from`]).
fn open_and_cost(job: &Job, registry: &Registry) -> Result<(Opened, u64)> {
    let (codec, info, file) = registry.probe_file(&job.source, &Limits::default())?;
    let bytes = file.metadata().map_err(Error::Io)?.len();
    let cost = in_flight_cost(&info, bytes);
    Ok((Opened { codec, file, bytes }, cost))
}

/// Converts one file (on a worker of the pool) and measures the output against the source.
/// A panic in a codec (a bug) fails this file only.
fn convert_one(
    job: &Job,
    opened: Opened,
    registry: &Registry,
    out_codec: &dyn ImageCodec,
    conversion: &ConversionSettings,
) -> ManifestLine {
    let t0 = Instant::now();
    let bytes_in = opened.bytes;
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        convert_and_measure(job, opened, registry, out_codec, conversion)
    }))
    .unwrap_or_else(|_| Err(Error::invalid("internal error in a codec (a bug, please report it)")));
    let seconds = t0.elapsed().as_secs_f64();
    match result {
        Ok((bytes_out, psnr, notes)) => ManifestLine {
            source: job.source.display().to_string(),
            output: job.output.display().to_string(),
            bytes_in,
            bytes_out: Some(bytes_out),
            pu21_psnr: psnr.is_finite().then_some(psnr),
            identical: Some(psnr.is_infinite()),
            seconds,
            error: None,
            notes,
            reused_output: job.reuse_output,
        },
        Err(e) => failed_line(&job.source, &job.output, bytes_in, seconds, &e),
    }
}

/// Decodes the source once, encodes it into the output (atomically), decodes the output back
/// and returns its size, the PU21-PSNR and the conversion's notes.
fn convert_and_measure(
    job: &Job,
    opened: Opened,
    registry: &Registry,
    out_codec: &dyn ImageCodec,
    conversion: &ConversionSettings,
) -> Result<(u64, f64, Vec<String>)> {
    let Opened { codec: in_codec, mut file, .. } = opened;
    let (options, settings) = conversion.for_decoder(in_codec.as_ref(), Limits::default());
    let source = in_codec.decode_from(&mut file, &options)?;
    drop(file);
    if let Some(dir) = job.output.parent() {
        std::fs::create_dir_all(dir)
            .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", dir.display()))))?;
    }
    let notes =
        if job.reuse_output { Vec::new() } else { hdrcodec::encode_file(out_codec, &source, &settings, &job.output)? };
    let back_options = hdrcodec::core::DecodeOptions::new(Limits::default()).with_pool(settings.pool.clone());
    let (back_codec, mut written) = registry.open(&job.output)?;
    let bytes_out = written.metadata().map_err(Error::Io)?.len();
    let back = back_codec.decode_from(&mut written, &back_options)?;
    drop(written);
    let psnr = metrics::pu21_psnr(&source, &back)?;
    Ok((bytes_out, psnr, notes))
}

/// The JSON-lines manifest, appended one whole line per `write`.
struct Manifest {
    file: std::fs::File,
    path: PathBuf,
}

impl Manifest {
    /// Opens `path` for appending; a last line without its newline (torn by a full disk or a
    /// power cut) is cut off first, so that the file holds only whole lines. Also returns the
    /// outputs whose last line says they were written without error.
    fn open(path: &Path) -> Result<(Manifest, HashSet<String>)> {
        let io = |e: std::io::Error| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display())));
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        let mut file = std::fs::OpenOptions::new().read(true).append(true).create(true).open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len > 0 {
            let mut tail = Vec::new();
            let from = len.saturating_sub(64 << 10);
            file.seek(std::io::SeekFrom::Start(from)).map_err(io)?;
            file.read_to_end(&mut tail).map_err(io)?;
            if tail.last() != Some(&b'\n') {
                let keep = match tail.iter().rposition(|&b| b == b'\n') {
                    Some(i) => from + i as u64 + 1,
                    None if from == 0 => 0,
                    // A line longer than the tail read: not ours; leave the file alone.
                    None => len,
                };
                file.set_len(keep).map_err(io)?;
            }
        }
        file.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
        let mut recorded = HashSet::new();
        for line in std::io::BufRead::lines(std::io::BufReader::new(&mut file)) {
            let Ok(value) = serde_json::from_str::<serde_json::Value>(&line.map_err(io)?) else { continue };
            if let Some(output) = value["output"].as_str() {
                if value["error"].is_null() {
                    recorded.insert(output.to_string());
                } else {
                    recorded.remove(output);
                }
            }
        }
        Ok((Manifest { file, path: path.to_path_buf() }, recorded))
    }

    fn append(&mut self, line: &ManifestLine) -> Result<()> {
        let mut text = serde_json::to_string(line).map_err(|e| Error::invalid(format!("cannot format JSON: {e}")))?;
        text.push('\n');
        self.file
            .write_all(text.as_bytes())
            .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", self.path.display()))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        // From the FNV reference test suite (Noll, "FNV-1a 64 bit" test vectors).
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn shards_split_every_path_exactly_once() {
        let paths: Vec<PathBuf> = (0..200).map(|i| PathBuf::from(format!("dir{}/img{i}.exr", i % 7))).collect();
        for n in 1..=5 {
            let mut counts = vec![0; paths.len()];
            for k in 0..n {
                let s = Shard::parse(&format!("{k}/{n}")).unwrap();
                for (i, p) in paths.iter().enumerate() {
                    counts[i] += usize::from(s.contains(p));
                }
            }
            assert!(counts.iter().all(|&c| c == 1), "n = {n}");
        }
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn shard_from_slurm_and_kubernetes_variables() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        assert_eq!(Shard::from_env(env(&[])).unwrap(), None);
        let s = Shard::from_env(env(&[("SLURM_ARRAY_TASK_ID", "2"), ("SLURM_ARRAY_TASK_COUNT", "4")])).unwrap();
        assert_eq!(s, Some(Shard { index: 2, count: 4 }));
        // --array=1-4: ids 1..4 are shards 0..3.
        let one_based =
            env(&[("SLURM_ARRAY_TASK_ID", "4"), ("SLURM_ARRAY_TASK_COUNT", "4"), ("SLURM_ARRAY_TASK_MIN", "1")]);
        assert_eq!(Shard::from_env(one_based).unwrap(), Some(Shard { index: 3, count: 4 }));
        // --array=0-12:4: ids 0, 4, 8, 12.
        let stepped = env(&[
            ("SLURM_ARRAY_TASK_ID", "8"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_STEP", "4"),
        ]);
        assert_eq!(Shard::from_env(stepped).unwrap(), Some(Shard { index: 2, count: 4 }));
        let k8s = env(&[("JOB_COMPLETION_INDEX", "1"), ("HDRCODEC_SHARD_COUNT", "3")]);
        assert_eq!(Shard::from_env(k8s).unwrap(), Some(Shard { index: 1, count: 3 }));
        let e = Shard::from_env(env(&[("JOB_COMPLETION_INDEX", "1")])).unwrap_err().to_string();
        assert!(e.contains("HDRCODEC_SHARD_COUNT"), "{e}");
        assert!(Shard::from_env(env(&[("SLURM_ARRAY_TASK_ID", "5"), ("SLURM_ARRAY_TASK_COUNT", "4")])).is_err());
        assert!(Shard::from_env(env(&[("SLURM_ARRAY_TASK_ID", "x"), ("SLURM_ARRAY_TASK_COUNT", "4")])).is_err());
    }

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_bytes("1048576").unwrap(), 1 << 20);
        assert_eq!(parse_bytes("8G").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("512m").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("1.5GiB").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("2KB").unwrap(), 2048);
        for bad in ["", "G", "1X", "0", "-1G", "1e400"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
        assert_eq!(mem_total_bytes("MemTotal:       24531104 kB\nMemFree: 1 kB\n"), Some(24531104 * 1024));
        assert!(default_memory_budget() > 0);
    }

    /// Runs files of these costs through [`Admission`] the way [`run`] does (start in order
    /// while admitted; otherwise the oldest file in flight ends) and returns the largest summed
    /// cost and count in flight.
    fn simulate(costs: &[u64], budget: u64, jobs: usize) -> (u64, usize) {
        let mut a = Admission::new(budget, jobs);
        let mut in_flight = std::collections::VecDeque::new();
        let (mut peak_bytes, mut peak_files) = (0, 0);
        let mut next = costs.iter().copied().peekable();
        while next.peek().is_some() || !in_flight.is_empty() {
            while let Some(&c) = next.peek() {
                if !a.try_admit(c) {
                    break;
                }
                in_flight.push_back(c);
                next.next();
                peak_bytes = peak_bytes.max(a.in_flight_bytes());
                peak_files = peak_files.max(a.in_flight());
            }
            if let Some(c) = in_flight.pop_front() {
                a.release(c);
            }
        }
        (peak_bytes, peak_files)
    }

    #[test]
    fn memory_budget_limits_the_images_in_flight() {
        const MB: u64 = 1 << 20;
        // Forty 40-megapixel float RGB images (480 MB each decoded, ~1.5 GB in flight) on 16 jobs:
        // a 4 GB budget lets two run at once, never more.
        let big = 3 * 480 * MB;
        let (bytes, files) = simulate(&[big; 40], 4096 * MB, 16);
        assert_eq!(files, 2);
        assert!(bytes <= 4096 * MB);
        // Small images: the job count is the limit.
        let (bytes, files) = simulate(&[10 * MB; 100], 4096 * MB, 8);
        assert_eq!((bytes, files), (80 * MB, 8));
        // Mixed sizes never exceed the budget.
        let mixed: Vec<u64> = (0..60).map(|i| (1 + (i * 37) % 11) * 100 * MB).collect();
        let (bytes, _) = simulate(&mixed, 1500 * MB, 6);
        assert!(bytes <= 1500 * MB, "{bytes}");
        // An image larger than the whole budget still runs, alone.
        let (bytes, files) = simulate(&[100 * MB, 5000 * MB, 100 * MB], 1000 * MB, 4);
        assert_eq!((bytes, files), (5000 * MB, 1));
        let mut a = Admission::new(1000 * MB, 4);
        assert!(a.try_admit(5000 * MB));
        assert!(!a.try_admit(MB), "nothing joins a file over the budget");
    }

    #[test]
    fn cost_comes_from_the_header() {
        let info = ImageInfo::new(4000, 3000, hdrcodec::core::Channels::Rgb, Default::default());
        assert_eq!(in_flight_cost(&info, 1000), 1000 + 3 * 4000 * 3000 * 3 * 4);
    }

    #[test]
    fn our_temporary_files_are_recognised() {
        assert!(is_any_atomic_temp(&hdrcodec::atomic_temp_name("x.exr", 17)));
        assert!(!is_any_atomic_temp("x.exr") && !is_any_atomic_temp(".x.tmp") && !is_any_atomic_temp("x.1.tmp"));
    }

    #[test]
    fn a_torn_manifest_line_is_cut_off() {
        let dir = std::env::temp_dir().join(format!("hdrcodec-manifest-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("m.jsonl");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(&path, "{\"a\":1}\n{\"b\":").unwrap();
        drop(Manifest::open(&path).unwrap());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "{\"a\":1}\n");
        // The outputs written without error, by their last line.
        let log = "{\"output\":\"x\",\"error\":null}\n{\"output\":\"y\",\"error\":null}\n{\"output\":\"y\",\"error\":\"bad\"}\n";
        std::fs::write(&path, log).unwrap();
        let (_, recorded) = Manifest::open(&path).unwrap();
        assert_eq!(recorded, HashSet::from(["x".to_string()]));
        std::fs::write(&path, "{\"b\":").unwrap();
        drop(Manifest::open(&path).unwrap());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
