//! `hdrcodec batch` end to end on small generated images: folders kept, failures isolated,
//! reruns idempotent, shards disjoint and complete, a killed batch resumable.

#[path = "../../tests/common/mod.rs"]
mod common;
mod terminal;

use serde_json::Value;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

fn hdrcodec(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hdrcodec")).args(args.iter().map(|a| a.as_ref())).output().expect("run hdrcodec")
}

/// The summary of a `batch --json` run, with its exit status.
fn batch(args: &[&dyn AsRef<std::ffi::OsStr>]) -> (Value, bool, String) {
    let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"batch", &"--json"];
    all.extend_from_slice(args);
    let out = hdrcodec(&all);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let summary =
        serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("not one JSON object ({e}): {stdout} {stderr}"));
    (summary, out.status.success(), stderr)
}

fn count(summary: &Value, key: &str) -> u64 {
    summary[key].as_u64().unwrap_or_else(|| panic!("no {key} in {summary}"))
}

/// Several counts of a summary, in the order of `keys`.
fn counts(summary: &Value, keys: &[&str]) -> Vec<u64> {
    keys.iter().map(|k| count(summary, k)).collect()
}

/// What a rerun is judged by.
const RERUN_COUNTS: &[&str] = &["converted", "up_to_date", "measured_for_the_manifest"];

/// The generated scenes as float EXR files, written once.
fn scenes() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = common::temp_dir("batch-scenes");
        let out = hdrcodec(&[&"corpus", &"write", &dir]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        dir
    })
}

/// An input tree of the generated scenes in nested folders, plus a text file that is not an
/// image: 9 images in all.
fn input_tree(name: &str) -> PathBuf {
    let dir = common::temp_dir(name);
    let layout = [
        ("sun-sky.exr", "sun-sky.exr"),
        ("edges.exr", "a/edges.exr"),
        ("specular.exr", "a/specular.exr"),
        ("odd-257x129.exr", "a/b/odd.exr"),
        ("dark-noise.exr", "a/b/c/dark-noise.exr"),
        ("bt2020-ramps.exr", "ramps/bt2020.exr"),
        ("alpha.exr", "ramps/alpha.exr"),
        ("tiny-1x1.exr", "tiny/one.exr"),
        ("odd-3x5.exr", "tiny/odd.exr"),
    ];
    for (from, to) in layout {
        let to = dir.join(to);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(scenes().join(from), &to).unwrap();
    }
    std::fs::write(dir.join("a/notes.txt"), "not an image").unwrap();
    dir
}

/// Every file below `dir`, as relative paths with `/`.
fn files(dir: &Path) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out
}

/// The lines of a JSON-lines manifest.
fn manifest(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    text.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("bad line ({e}): {l}"))).collect()
}

fn images_below(dir: &Path) -> BTreeSet<String> {
    files(dir).into_iter().filter(|f| f.ends_with(".hdr")).collect()
}

const EXPECTED: [&str; 9] = [
    "a/b/c/dark-noise.hdr",
    "a/b/odd.hdr",
    "a/edges.hdr",
    "a/specular.hdr",
    "ramps/alpha.hdr",
    "ramps/bt2020.hdr",
    "sun-sky.hdr",
    "tiny/odd.hdr",
    "tiny/one.hdr",
];

#[test]
fn batch_keeps_the_folders_and_skips_what_is_not_an_image() {
    let input = input_tree("batch-tree-in");
    let out = common::temp_dir("batch-tree-out");
    let (s, ok, stderr) = batch(&[&input, &out, &"--to", &"rgbe"]);
    assert!(ok, "{stderr}");
    assert_eq!((count(&s, "converted"), count(&s, "skipped"), count(&s, "failed")), (9, 1, 0), "{s}");
    assert!(count(&s, "bytes_in") > 0 && count(&s, "bytes_out") > 0);
    let mut expected: BTreeSet<String> = EXPECTED.iter().map(|s| s.to_string()).collect();
    expected.insert("manifest.jsonl".into());
    assert_eq!(files(&out), expected);
    let lines = manifest(&out.join("manifest.jsonl"));
    assert_eq!(lines.len(), 9);
    for l in &lines {
        assert!(l["error"].is_null(), "{l}");
        // RGBE keeps about 1 % per sample: high, finite PU21-PSNR (the 1x1 may be exact).
        let psnr = l["pu21_psnr"].as_f64();
        assert!(psnr.is_some_and(|p| p > 30.0) || l["identical"] == true, "{l}");
        assert!(l["bytes_in"].as_u64().unwrap() > 0 && l["bytes_out"].as_u64().unwrap() > 0, "{l}");
        assert!(Path::new(l["output"].as_str().unwrap()).is_file(), "{l}");
    }
}

#[test]
fn a_corrupt_file_fails_alone() {
    let input = input_tree("batch-corrupt-in");
    let mut bytes = std::fs::read(input.join("a/edges.exr")).unwrap();
    bytes.truncate(bytes.len() / 3);
    std::fs::write(input.join("a/edges.exr"), &bytes).unwrap();
    std::fs::write(input.join("a/b/garbage.exr"), b"this is not an OpenEXR file at all").unwrap();
    let out = common::temp_dir("batch-corrupt-out");
    let (s, ok, stderr) = batch(&[&input, &out, &"--to", &"hdr"]);
    assert!(!ok, "a failed file makes the exit status non-zero");
    assert_eq!((count(&s, "converted"), count(&s, "failed")), (8, 2), "{s}");
    // One line per failed file, then the summary's line.
    assert!(stderr.contains("edges.exr: ") && stderr.contains("garbage.exr: "), "{stderr}");
    assert_eq!(stderr.lines().count(), 3, "{stderr}");
    let outputs = images_below(&out);
    assert!(!outputs.contains("a/edges.hdr") && !outputs.contains("a/b/garbage.hdr"), "{outputs:?}");
    assert_eq!(outputs.len(), 8);
    let failed: Vec<_> = manifest(&out.join("manifest.jsonl")).into_iter().filter(|l| !l["error"].is_null()).collect();
    assert_eq!(failed.len(), 2);
    assert!(failed.iter().all(|l| l["bytes_out"].is_null() && l["pu21_psnr"].is_null()));
}

#[test]
fn a_rerun_skips_up_to_date_outputs_and_force_redoes_them() {
    let input = input_tree("batch-rerun-in");
    let out = common::temp_dir("batch-rerun-out");
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr"]);
    assert!(ok && count(&s, "converted") == 9);
    // A run killed after renaming two outputs into place but before their manifest lines: the
    // rerun measures those two for the manifest and re-encodes nothing.
    let manifest_path = out.join("manifest.jsonl");
    let text = std::fs::read_to_string(&manifest_path).unwrap();
    let kept: Vec<&str> = text.lines().take(7).collect();
    std::fs::write(&manifest_path, kept.join("\n") + "\n").unwrap();
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr"]);
    assert!(ok);
    assert_eq!(counts(&s, RERUN_COUNTS), [0, 9, 2], "{s}");
    let lines = manifest(&manifest_path);
    assert_eq!(lines.len(), 9);
    assert!(
        lines[7..].iter().all(|l| l["reused_output"] == true && (l["pu21_psnr"].is_f64() || l["identical"] == true)),
        "{lines:?}"
    );
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr"]);
    assert!(ok);
    assert_eq!(counts(&s, RERUN_COUNTS), [0, 9, 0], "{s}");
    // A source changed after its output: that one file is redone.
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::copy(scenes().join("edges.exr"), input.join("sun-sky.exr")).unwrap();
    let (s, _, _) = batch(&[&input, &out, &"--to", &"hdr"]);
    assert_eq!((count(&s, "converted"), count(&s, "up_to_date")), (1, 8), "{s}");
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr", &"--force"]);
    assert!(ok);
    assert_eq!((count(&s, "converted"), count(&s, "up_to_date")), (9, 0), "{s}");
    // The manifest is the log of the runs: 9 + 1 + 9 lines.
    assert_eq!(manifest(&out.join("manifest.jsonl")).len(), 19);
}

#[test]
fn shards_together_convert_every_file_exactly_once() {
    let input = input_tree("batch-shards-in");
    for n in 1..=3u32 {
        let out = common::temp_dir(&format!("batch-shards-out-{n}"));
        let mut sources = Vec::new();
        for k in 0..n {
            let shard = format!("{k}/{n}");
            let (s, ok, stderr) = batch(&[&input, &out, &"--to", &"hdr", &"--shard", &shard, &"--jobs", &"1"]);
            assert!(ok, "{stderr}");
            assert_eq!(count(&s, "converted") + count(&s, "other_shards"), 9, "{s}");
            let m = out.join(format!("manifest-{k}-of-{n}.jsonl"));
            sources.extend(manifest(&m).into_iter().map(|l| l["source"].as_str().unwrap().to_string()));
        }
        let unique: BTreeSet<_> = sources.iter().cloned().collect();
        assert_eq!((sources.len(), unique.len()), (9, 9), "n = {n}: {sources:?}");
        assert_eq!(images_below(&out), EXPECTED.iter().map(|s| s.to_string()).collect());
    }
}

#[test]
fn the_shard_comes_from_slurm_or_kubernetes_variables() {
    let input = input_tree("batch-env-in");
    let run = |out: &Path, vars: &[(&str, &str)]| -> Value {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_hdrcodec"));
        cmd.args(["batch", "--json", "--to", "hdr"]).arg(&input).arg(out);
        for v in ["SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT", "SLURM_ARRAY_TASK_MIN", "JOB_COMPLETION_INDEX"] {
            cmd.env_remove(v);
        }
        cmd.envs(vars.iter().copied());
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    // Slurm `--array=1-2`: tasks 1 and 2 are shards 0/2 and 1/2.
    let slurm = common::temp_dir("batch-env-slurm");
    let mut total = 0;
    for id in ["1", "2"] {
        let s =
            run(&slurm, &[("SLURM_ARRAY_TASK_ID", id), ("SLURM_ARRAY_TASK_COUNT", "2"), ("SLURM_ARRAY_TASK_MIN", "1")]);
        let index = id.parse::<u32>().unwrap() - 1;
        assert_eq!(s["shard"], format!("{index}/2"), "{s}");
        total += count(&s, "converted");
    }
    assert_eq!(total, 9);
    // The same split as --shard: the same files in the same shard's manifest.
    let flag = common::temp_dir("batch-env-flag");
    let o = hdrcodec(&[&"batch", &"--json", &input, &flag, &"--to", &"hdr", &"--shard", &"1/2"]);
    assert!(o.status.success());
    let sources = |p: PathBuf| -> BTreeSet<String> {
        manifest(&p).into_iter().map(|l| l["source"].as_str().unwrap().to_string()).collect()
    };
    assert_eq!(sources(slurm.join("manifest-1-of-2.jsonl")), sources(flag.join("manifest-1-of-2.jsonl")));
    // Kubernetes: the index, and the count from HDRCODEC_SHARD_COUNT.
    let k8s = common::temp_dir("batch-env-k8s");
    let s = run(&k8s, &[("JOB_COMPLETION_INDEX", "2"), ("HDRCODEC_SHARD_COUNT", "3")]);
    assert_eq!(s["shard"], "2/3");
    assert_eq!(count(&s, "converted") + count(&s, "other_shards"), 9);
}

#[test]
fn a_killed_batch_resumes_with_only_the_missing_files_and_leaves_no_partial_file() {
    // Larger images, one at a time, so that the batch is surely stopped half-way.
    let input = common::temp_dir("batch-kill-in");
    for i in 0..10 {
        let f = input.join(format!("d{}/big{i}.exr", i % 3));
        std::fs::create_dir_all(f.parent().unwrap()).unwrap();
        let o = hdrcodec(&[&"corpus", &"large", &f, &"--width", &"640", &"--height", &"480"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // kill -9 ends the process at once: its temporary file stays, and the rerun removes it.
    // A batch system's SIGTERM and Ctrl-C's SIGINT are caught: the temporary files in flight
    // are removed before the process ends by that signal.
    for signal in ["KILL", "TERM", "INT"] {
        stop_and_resume(&input, signal);
    }
}

/// Our temporary files below `dir` (`.NAME.PID.tmp`).
fn temp_files(dir: &Path) -> BTreeSet<String> {
    files(dir)
        .into_iter()
        .filter(|f| f.rsplit('/').next().is_some_and(|name| name.starts_with('.') && name.ends_with(".tmp")))
        .collect()
}

/// Waits until `child` is writing a temporary file below `out` (after `ready` holds), then
/// stops it with `signal` (a `kill` name) and returns how it ended.
fn stop_while_writing(
    child: &mut std::process::Child,
    out: &Path,
    signal: &str,
    ready: impl Fn() -> bool,
) -> std::process::ExitStatus {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while !ready() || temp_files(out).is_empty() {
        assert!(std::time::Instant::now() < deadline, "nothing written after 60 s");
        assert!(child.try_wait().unwrap().is_none(), "finished before it could be stopped while writing");
    }
    let killed = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
    assert!(killed.success());
    child.wait().unwrap()
}

/// The signal number of a `kill` name.
fn signal_number(signal: &str) -> i32 {
    match signal {
        "INT" => 2,
        "KILL" => 9,
        "TERM" => 15,
        other => panic!("no number for SIG{other}"),
    }
}

/// Starts a batch of the 10 images of `input`, stops it with `signal` once it has converted a
/// file and is writing the next, resumes it, and checks what each run did and what it left.
fn stop_and_resume(input: &Path, signal: &str) {
    let out = common::temp_dir(&format!("batch-kill-out-{signal}"));
    let manifest_path = out.join("manifest.jsonl");
    let mut child = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .args(["batch", "--json", "--to", "exr", "--jobs", "1", "--threads", "1"])
        .arg(input)
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let status = stop_while_writing(&mut child, &out, signal, || !manifest(&manifest_path).is_empty());
    // Ended by the signal itself (a shell shows 128 + its number), not by an exit status.
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(signal_number(signal)), "{status:?}");
    let left = temp_files(&out);
    if signal != "KILL" {
        assert!(left.is_empty(), "SIG{signal} left {left:?}");
    }
    let done_before: BTreeSet<String> =
        files(&out).into_iter().filter(|f| f.ends_with(".exr") && !f.starts_with('.') && !f.contains("/.")).collect();
    assert!(
        !done_before.is_empty() && done_before.len() < 10,
        "SIG{signal} came too late to test resuming: {done_before:?}"
    );
    // Every output there is whole (the atomic rename); the manifest has only whole lines.
    for f in &done_before {
        hdrcodec::registry().read(&out.join(f), &hdrcodec::core::Limits::default()).expect("a whole output");
    }
    let lines_before = manifest(&manifest_path).len();

    let (s, ok, stderr) = batch(&[&input, &out, &"--to", &"exr"]);
    assert!(ok, "{stderr}");
    assert_eq!(count(&s, "stale_temp_files_removed") as usize, left.len(), "{s}");
    assert_eq!(count(&s, "up_to_date") as usize, done_before.len(), "{s}");
    assert_eq!(count(&s, "converted") as usize, 10 - done_before.len(), "{s}");
    // The resumed run's conversions are exactly the missing files (an output renamed into place
    // just before the kill, without its manifest line, is only measured: reused_output).
    let resumed: BTreeSet<String> = manifest(&manifest_path)[lines_before..]
        .iter()
        .filter(|l| l["reused_output"] == false)
        .map(|l| {
            Path::new(l["output"].as_str().unwrap()).strip_prefix(&out).unwrap().to_string_lossy().replace('\\', "/")
        })
        .collect();
    assert!(resumed.is_disjoint(&done_before), "{resumed:?} redone");
    assert_eq!(resumed.len(), 10 - done_before.len());
    // No temporary file remains: only the outputs and the manifest.
    let mut expected: BTreeSet<String> = (0..10).map(|i| format!("d{}/big{i}.exr", i % 3)).collect();
    expected.insert("manifest.jsonl".into());
    assert_eq!(files(&out), expected);
}

#[test]
fn a_stopped_convert_leaves_no_temporary_file() {
    let dir = common::temp_dir("convert-stop");
    let source = dir.join("big.exr");
    let o = hdrcodec(&[&"corpus", &"large", &source, &"--width", &"1536", &"--height", &"1024"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for signal in ["TERM", "INT"] {
        let out = dir.join(format!("out-{signal}"));
        std::fs::create_dir_all(&out).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
            .args(["convert", "--threads", "1"])
            .arg(&source)
            .arg(out.join("big.jxr"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let status = stop_while_writing(&mut child, &out, signal, || true);
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(status.signal(), Some(signal_number(signal)), "{status:?}");
        assert_eq!(files(&out), BTreeSet::new(), "SIG{signal}");
    }
}

#[test]
fn a_tiny_memory_budget_runs_one_image_at_a_time() {
    let input = input_tree("batch-memory-in");
    let out = common::temp_dir("batch-memory-out");
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr", &"--memory", &"1K", &"--jobs", &"4", &"--threads", &"2"]);
    assert!(ok);
    assert_eq!((count(&s, "converted"), count(&s, "peak_in_flight_files")), (9, 1), "{s}");
    let out = common::temp_dir("batch-memory-out-large");
    let (s, ok, _) = batch(&[&input, &out, &"--to", &"hdr", &"--memory", &"1G", &"--jobs", &"4", &"--threads", &"2"]);
    assert!(ok);
    assert!(count(&s, "peak_in_flight_files") > 1, "{s}");
    assert!(count(&s, "peak_in_flight_cost") <= 1 << 30, "{s}");
}

#[test]
fn the_progress_bar_is_drawn_on_a_terminal_only() {
    use terminal::run_on_terminal;
    let input = input_tree("batch-progress-in");
    // stderr a terminal, stdout a pipe: the bar, its ETA and its count are drawn on stderr.
    let out = common::temp_dir("batch-progress-out-terminal");
    let (screen, stdout) = run_on_terminal(&[&"batch", &input, &out, &"--to", &"hdr", &"--jobs", &"1"]);
    assert!(screen.contains("ETA "), "no ETA on the terminal: {screen:?}");
    assert!((1..=9).any(|k| screen.contains(&format!(" {k}/9 "))), "no count of 9 files: {screen:?}");
    assert!(stdout.contains("converted:   9") && !stdout.contains("ETA"), "{stdout}");
    // --json: nothing on the terminal, one JSON object on stdout.
    let out = common::temp_dir("batch-progress-out-json");
    let (screen, stdout) = run_on_terminal(&[&"batch", &"--json", &input, &out, &"--to", &"hdr", &"--jobs", &"1"]);
    assert_eq!(screen, "", "--json drew on the terminal");
    let summary: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(count(&summary, "converted"), 9);
    // stderr a pipe: nothing of the bar.
    let out = common::temp_dir("batch-progress-out-pipe");
    let o = hdrcodec(&[&"batch", &input, &out, &"--to", &"hdr", &"--jobs", &"1"]);
    assert!(o.status.success());
    assert_eq!(String::from_utf8_lossy(&o.stderr), "", "stderr is not a terminal");
}

/// Crops of at most 48x40 pixels from the middle of images of the shared corpus, one per kind
/// (wide-gamut ACES with alpha, CIE XYZ, negative values over 8 decades, RGBE, JPEG XR float
/// with alpha, an Ultra HDR gain map), written as float OpenEXR (exact, colour kept), plus
/// the generated 1x1 and 3x5 scenes; `None` (skipped, or a failure in CI) without the corpus.
fn corpus_crops() -> Option<&'static Path> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        let corpus = common::require(common::corpus_dir(), "the shared HDR corpus")?;
        let dir = common::temp_dir("batch-corpus-crops");
        let registry = hdrcodec::registry();
        let exr = registry.by_name("exr").unwrap();
        let float = hdrcodec::core::EncodeSettings::default().with_option("pixel", "float");
        for source in [
            "exr/Carrots.exr",
            "exr/XYZ.exr",
            "exr/Desk.exr",
            "hdr/hall.hdr",
            "jxr/StillLife_128bppRGBAFloat_q0.9.jxr",
            "jpeg/sky_ultrahdr.jpg",
        ] {
            let (_, image) = registry.read(&corpus.join(source), &hdrcodec::core::Limits::default()).unwrap();
            let (w, h) = (image.width().min(48), image.height().min(40));
            let (x0, y0) = ((image.width() - w) / 2, (image.height() - h) / 2);
            let n = image.channels().count();
            let samples: Vec<f32> =
                (y0..y0 + h).flat_map(|y| image.row(y)[x0 as usize * n..(x0 + w) as usize * n].to_vec()).collect();
            let crop = hdrcodec::core::HdrImage::new(w, h, image.channels(), samples, image.color.clone()).unwrap();
            let to = dir.join(source).with_extension("exr");
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::write(&to, exr.encode(&crop, &float).unwrap()).unwrap();
        }
        for (from, to) in [("tiny-1x1.exr", "tiny/one.exr"), ("odd-3x5.exr", "tiny/odd.exr")] {
            std::fs::create_dir_all(dir.join("tiny")).unwrap();
            std::fs::copy(scenes().join(from), dir.join(to)).unwrap();
        }
        Some(dir)
    })
    .as_deref()
}

#[test]
fn a_batch_runs_through_every_output_format() {
    let Some(crops) = corpus_crops() else { return };
    let registry = hdrcodec::registry();
    let limits = hdrcodec::core::Limits::default();
    let formats: Vec<&str> = registry.codecs().iter().filter(|c| c.can_encode()).map(|c| c.name()).collect();
    assert!(formats.len() >= 10, "{formats:?}");
    for name in formats {
        let out = common::temp_dir(&format!("batch-every-{name}"));
        let (s, ok, stderr) = batch(&[&crops, &out, &"--to", &name]);
        assert!(ok, "--to {name}: {stderr}");
        assert_eq!((count(&s, "converted"), count(&s, "failed")), (8, 0), "--to {name}: {s}");
        for line in manifest(&out.join("manifest.jsonl")) {
            // Every output is a whole file of the format, of its source's size, measured.
            let output = Path::new(line["output"].as_str().unwrap());
            let extension = output.extension().unwrap().to_str().unwrap();
            assert!(registry.by_name(name).unwrap().extensions().contains(&extension), "--to {name}: {line}");
            let (_, back) = registry.read(output, &limits).unwrap();
            let (_, source) = registry.read(Path::new(line["source"].as_str().unwrap()), &limits).unwrap();
            assert_eq!((back.width(), back.height()), (source.width(), source.height()), "--to {name}: {line}");
            assert!(line["pu21_psnr"].is_f64() || line["identical"] == true, "--to {name}: {line}");
        }
    }
}
