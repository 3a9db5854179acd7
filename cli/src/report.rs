//! `hdrcodec bench --report FILE.md`: the bench run as a Markdown page, with the plots beside it.
//!
//! The page says where the figures come from (machine, date, load, hdrcodec's commit and build,
//! every peer tool the bench can call and its version or "not installed", the command that
//! regenerates the page) and then shows them: the rate-distortion plot and the speed chart
//! (`FILE-rd.png`, `FILE-rd-speed.png` beside `FILE.md`, [`crate::plot`]), the table and the
//! bytes-at-equal-quality summaries exactly as `hdrcodec bench` prints them, and the per-image
//! table. Nothing in it is typed by hand: every figure is the run's.

use crate::bench::{self, Report};
use crate::equal_quality;
use hdrcodec::core::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// What the report records about the run beside the [`Report`].
#[derive(Clone, Debug)]
pub struct Context {
    /// The command line, as typed (program name first).
    pub args: Vec<String>,
    /// The working directory the command ran in.
    pub cwd: PathBuf,
    /// `/proc/loadavg`'s three load averages before the run, if readable.
    pub load_before: Option<String>,
    /// The images: name, width, height.
    pub images: Vec<(String, u32, u32)>,
    /// `$HDRCODEC_VENV`, if set.
    pub venv: Option<String>,
}

impl Context {
    /// The current process's command line and directory, the load average now, and the sizes
    /// of `inputs`.
    pub fn now(inputs: &[bench::Input]) -> Context {
        Context {
            args: std::env::args_os().map(|a| a.to_string_lossy().into_owned()).collect(),
            cwd: std::env::current_dir().unwrap_or_default(),
            load_before: load_average(),
            images: inputs.iter().map(|i| (i.name.clone(), i.image.width(), i.image.height())).collect(),
            venv: std::env::var("HDRCODEC_VENV").ok(),
        }
    }
}

/// Checks, before any work, that a report can be written to `path` (a `.md` name) and its
/// plots drawn (a font, see [`crate::plot::prepare_png`]).
pub fn prepare(path: &Path) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("md")) {
        return Err(Error::unsupported(format!("--report writes Markdown; '{}' does not end in .md", path.display())));
    }
    crate::plot::prepare_png(&rd_path(path), "--report")
}

/// The rate-distortion plot beside the report `path`: `BENCH.md` → `BENCH-rd.png` (its speed
/// chart is [`crate::plot::speed_path`] of that: `BENCH-rd-speed.png`).
pub fn rd_path(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or_else(|| "report".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}-rd.png"))
}

/// Writes the plots beside `path`, then the page (each file through a temporary file and a
/// rename: the page's links exist once the page does).
pub fn write(report: &Report, context: &Context, path: &Path) -> Result<()> {
    let rd = rd_path(path);
    crate::plot::write(report, &rd)?;
    let page = markdown(report, context, path);
    hdrcodec::write_atomic(path, page.as_bytes())
}

/// The first line of a command's standard output (or error), if it runs and succeeds.
fn first_line(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = if out.stdout.is_empty() { out.stderr } else { out.stdout };
    String::from_utf8_lossy(&text).lines().map(str::trim).find(|l| !l.is_empty()).map(str::to_string)
}

/// `/proc/loadavg`'s 1-, 5- and 15-minute load averages.
fn load_average() -> Option<String> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(text.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

/// The CPU's model name (`/proc/cpuinfo`), the logical CPUs and the CPUs this process may use.
fn cpu() -> (String, String) {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = info
        .lines()
        .find_map(|l| l.strip_prefix("model name").and_then(|r| r.split_once(':')).map(|(_, m)| m.trim().to_string()))
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let logical = info.lines().filter(|l| l.starts_with("processor")).count();
    let usable = std::thread::available_parallelism().map_or(0, |n| n.get());
    (model, format!("{usable} usable ({logical} logical CPUs in /proc/cpuinfo)"))
}

/// The operating system: `/etc/os-release`'s PRETTY_NAME and the kernel's release.
fn os() -> String {
    let release = std::fs::read_to_string("/etc/os-release").unwrap_or_default();
    let name = release
        .lines()
        .find_map(|l| l.strip_prefix("PRETTY_NAME="))
        .map(|v| v.trim_matches('"').to_string())
        .unwrap_or_else(|| std::env::consts::OS.to_string());
    match std::fs::read_to_string("/proc/sys/kernel/osrelease") {
        Ok(k) => format!("{name}, kernel {}", k.trim()),
        Err(_) => name,
    }
}

/// The date and time now, UTC, as `YYYY-MM-DD HH:MM UTC`.
fn utc_now() -> String {
    let secs = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rest) = ((secs / 86_400) as i64, secs % 86_400);
    let (y, m, d) = civil_from_days(days);
    format!("{y:04}-{m:02}-{d:02} {:02}:{:02} UTC", rest / 3600, rest / 60 % 60)
}

/// The proleptic Gregorian date of `days` since 1970-01-01 (H. Hinnant's days-to-civil).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// The commit of the source tree this binary was built from (asked of git at report time),
/// with "+ uncommitted changes" when the tree differs from it in other files than `own`, the
/// report's own outputs (a page regenerated in place is not a change to the source).
fn commit(own: &[&Path]) -> String {
    commit_of(env!("CARGO_MANIFEST_DIR"), own)
}

/// [`commit`] of the git work tree that holds `dir`.
fn commit_of(dir: &str, own: &[&Path]) -> String {
    let (Some(head), Some(root)) = (
        first_line("git", &["-C", dir, "rev-parse", "--short=12", "HEAD"]),
        first_line("git", &["-C", dir, "rev-parse", "--show-toplevel"]),
    ) else {
        return "unknown (no git repository at the build's source)".into();
    };
    let own: Vec<PathBuf> = own.iter().filter_map(|p| p.canonicalize().ok()).collect();
    let changed = Command::new("git").args(["-C", &root, "status", "--porcelain", "--untracked-files=no"]).output();
    // Porcelain lines are `XY path` (renames `XY old -> new`), paths relative to the root.
    let dirty = changed.is_ok_and(|o| {
        String::from_utf8_lossy(&o.stdout).lines().filter_map(|l| l.get(3..)).any(|path| {
            let path = path.rsplit(" -> ").next().unwrap_or(path).trim_matches('"');
            let full = Path::new(&root).join(path);
            !full.canonicalize().is_ok_and(|f| own.contains(&f))
        })
    });
    if dirty {
        format!("{head} + uncommitted changes")
    } else {
        head
    }
}

/// A peer tool the bench may call: its name as the rows' encoder and peer descriptions say it,
/// and how to ask for its version.
struct Tool {
    name: &'static str,
    version: fn() -> Option<String>,
}

/// The first line a program prints for its version argument (asked once per process, as the
/// peer rows ask it), if it is on PATH.
fn program_version(name: &str, arg: &str) -> Option<String> {
    crate::jxrlib::tool(name)?;
    let text = crate::peers::version_text(name, arg);
    let line = text.as_deref().and_then(|t| t.lines().map(str::trim).find(|l| !l.is_empty()));
    Some(line.map_or_else(|| "installed, version unknown".into(), str::to_string))
}

/// jxrlib's programs print no version: the Debian package's.
fn jxrlib_version(name: &str) -> Option<String> {
    crate::jxrlib::tool(name)?;
    let v = first_line("dpkg-query", &["-W", "-f", "${Version}", "libjxr-tools"]);
    Some(v.map_or_else(|| "installed, version unknown".into(), |v| format!("{} {v}", crate::jxrlib::PACKAGE)))
}

/// The peer tools `bench` can call, one line each. A tool whose name appears in no row's
/// encoder or peer is listed too: the page says which rows use each.
const TOOLS: &[Tool] = &[
    Tool { name: crate::jxrlib::ENCODER, version: || jxrlib_version(crate::jxrlib::ENCODER) },
    Tool { name: crate::jxrlib::DECODER, version: || jxrlib_version(crate::jxrlib::DECODER) },
    Tool {
        name: "libultrahdr",
        version: || {
            let python = crate::libultrahdr::python()?;
            let script = "import imagecodecs; print(imagecodecs.ultrahdr_version(), '(imagecodecs', imagecodecs.__version__ + ')')";
            first_line(&python.to_string_lossy(), &["-c", script])
        },
    },
    Tool { name: "cjxl", version: || program_version("cjxl", "--version") },
    Tool { name: "avifenc", version: || program_version("avifenc", "--version") },
    Tool { name: "oiiotool", version: || program_version("oiiotool", "--version") },
    Tool { name: "ffmpeg", version: || program_version("ffmpeg", "-version") },
    Tool {
        name: "ISPC",
        version: || {
            crate::peers::ispc::available()
                .then(|| "Intel ISPC texcomp through intel_tex_2 0.5 (in process; cargo feature `ispc`)".into())
        },
    },
];

/// The configurations whose rows name `tool` as their encoder or peer decoder.
fn rows_using(report: &Report, tool: &str) -> Vec<String> {
    let tool = tool.to_ascii_lowercase();
    let mut out: Vec<String> = Vec::new();
    for r in &report.rows {
        let named = |s: &Option<String>| s.as_ref().is_some_and(|s| s.to_ascii_lowercase().contains(&tool));
        let peer = r.peer.as_ref().map(|p| p.decoder.clone());
        let why = report.summary.iter().find(|s| s.config == r.config).and_then(|s| s.unavailable.clone());
        if (named(&r.encoder) || named(&peer) || named(&why)) && !out.contains(&r.config) {
            out.push(r.config.clone());
        }
    }
    for r in &report.video {
        let named = [Some(&r.encoder), r.peer.as_ref().map(|p| &p.decoder), r.error.as_ref()]
            .into_iter()
            .flatten()
            .any(|s| s.to_ascii_lowercase().contains(&tool));
        if named && !out.contains(&r.config) {
            out.push(r.config.clone());
        }
    }
    out
}

/// `text` as a Markdown code block.
fn code_block(text: &str) -> String {
    format!("```text\n{}\n```\n", text.trim_end())
}

/// A file name relative to the page (plots are written beside it).
fn link_name(path: &Path) -> String {
    path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The command line, each argument quoted for a POSIX shell where it needs it, the program
/// named `hdrcodec`.
fn command_line(args: &[String]) -> String {
    let quote = |a: &String| {
        if !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
            a.clone()
        } else {
            format!("'{}'", a.replace('\'', r"'\''"))
        }
    };
    std::iter::once("hdrcodec".to_string()).chain(args.iter().skip(1).map(quote)).collect::<Vec<_>>().join(" ")
}

/// The page.
pub fn markdown(report: &Report, context: &Context, path: &Path) -> String {
    let rd = rd_path(path);
    let speed = crate::plot::speed_path(&rd);
    let (model, cores) = cpu();
    let mut s = String::new();
    s.push_str("# hdrcodec benchmarks\n\n");
    s.push_str(&format!(
        "Written by `hdrcodec bench --report` on {}; every figure below is that run's, none typed by hand.\n\n",
        utc_now()
    ));
    s.push_str("## How to regenerate\n\n");
    let here = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let same_dir = here.canonicalize().ok().zip(context.cwd.canonicalize().ok()).is_some_and(|(a, b)| a == b);
    let place = if same_dir { "this file's directory".to_string() } else { format!("`{}`", context.cwd.display()) };
    s.push_str(&format!(
        "In {place}, with a release build (`cargo run --release -p hdrcodec-cli -- bench ...` runs the same) and the peer tools \
         of `scripts/setup-reference-tools.sh`:\n\n    {}\n\n",
        command_line(&context.args)
    ));
    if let Some(venv) = &context.venv {
        s.push_str(&format!(
            "The reference venv (libultrahdr's rows) was `HDRCODEC_VENV={venv}` (default: `./.venv`).\n\n"
        ));
    }
    s.push_str("## Machine and build\n\n| | |\n| --- | --- |\n");
    let build = if cfg!(debug_assertions) { "a debug build: speeds are not representative" } else { "release build" };
    let load_after = load_average().unwrap_or_else(|| "unknown".into());
    let load_before = context.load_before.clone().unwrap_or_else(|| "unknown".into());
    for (k, v) in [
        ("CPU", model),
        ("cores", cores),
        ("OS", os()),
        ("load average (1, 5, 15 min) before / after the run", format!("{load_before} / {load_after}")),
        ("hdrcodec", format!("{}, {build}, commit {}", env!("CARGO_PKG_VERSION"), commit(&[path, &rd, &speed]))),
        ("images", format!("{} from {}", images(report).len(), report.source)),
        ("timed runs per measurement (median)", format!("at most {}", report.runs)),
        ("threads of the all-thread columns", report.threads.to_string()),
    ] {
        s.push_str(&format!("| {k} | {} |\n", v.replace('|', "\\|")));
    }
    s.push_str("\n## Peer tools\n\n| tool | version | rows that use it |\n| --- | --- | --- |\n");
    for t in TOOLS {
        let version = (t.version)().unwrap_or_else(|| "not installed".into());
        let rows = rows_using(report, t.name);
        let rows = if rows.is_empty() { "none in this run".to_string() } else { format!("`{}`", rows.join("`, `")) };
        s.push_str(&format!("| {} | {} | {rows} |\n", t.name, version.replace('|', "\\|")));
    }
    s.push_str("\n## Images\n\n| image | width x height | megapixels |\n| --- | --- | --- |\n");
    for (name, pixels) in images(report) {
        s.push_str(&format!("| {name} | {} | {:.2} |\n", size_of(context, &name), pixels as f64 / 1e6));
    }
    for k in &report.skipped {
        s.push_str(&format!("\nSkipped {}: {}\n", k.file, k.reason));
    }
    s.push_str(&format!(
        "\n## Rate and distortion\n\nBits per pixel against mean PU21-PSNR (left) and mean ΔE ITP (right); one line per codec \
         family across its quality sweep, single configurations as points.\n\n![rate-distortion]({})\n",
        link_name(&rd)
    ));
    s.push_str(&format!(
        "\n## Speed\n\nDecode and encode megapixels per second on one thread.\n\n![speed]({})\n",
        link_name(&speed)
    ));
    let table = bench::table(report);
    let eq = equal_quality::table(&report.equal_quality);
    s.push_str(
        "\n## Table\n\nAs `hdrcodec bench` prints it: the means over the images per configuration, then its notes.\n\n",
    );
    s.push_str(&code_block(table.strip_suffix(&eq).unwrap_or(&table)));
    s.push_str("\n## Bytes at equal quality\n\n");
    if eq.is_empty() {
        s.push_str("No comparison of `cli/src/equal_quality.rs` had both of its sides in this run.\n");
    } else {
        s.push_str(&code_block(&eq));
    }
    if !report.video.is_empty() {
        s.push_str(
            "\n## Video: HDR10 AV1\n\nOurs (`av1:`, hdrcodec-video on rav1e) and FFmpeg's SVT-AV1 (`av1(svt-av1):`) on the same \
             10-bit Y'CbCr frames, as `hdrcodec bench --video` prints them.\n\n",
        );
        s.push_str(&code_block(&crate::video_bench::table(&report.video)));
    }
    if !report.memory.is_empty() {
        s.push_str(
            "\n## Peak memory of decoding\n\nPer codec, its first configuration's file of the largest image, decoded into a whole \
             image by a child `hdrcodec memory-peak` process that reads its own peak resident set.\n\n",
        );
        s.push_str(&code_block(&crate::memory::table(&report.memory)));
    }
    s.push_str("\n## Per image\n\n<details><summary>Every configuration on every image</summary>\n\n");
    s.push_str(&code_block(&bench::per_image_table(report)));
    s.push_str("\n</details>\n");
    s
}

/// The images of the run, in order, with their pixel counts.
fn images(report: &Report) -> Vec<(String, usize)> {
    let mut out: Vec<(String, usize)> = Vec::new();
    for r in &report.rows {
        if !out.iter().any(|(n, _)| *n == r.image) {
            out.push((r.image.clone(), r.pixels));
        }
    }
    out
}

/// An image's width x height, as the context recorded it.
fn size_of(context: &Context, image: &str) -> String {
    context.images.iter().find(|i| i.0 == image).map_or_else(|| "?".into(), |i| format!("{}x{}", i.1, i.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pages_own_files_do_not_make_the_tree_dirty() {
        let dir = std::env::temp_dir().join(format!("hdrcodec-report-git-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let git = |args: &[&str]| {
            let ok = Command::new("git")
                .args(["-C", dir.to_str().unwrap(), "-c", "user.name=t", "-c", "user.email=t@t"])
                .args(args)
                .output()
                .is_ok_and(|o| o.status.success());
            assert!(ok, "git {args:?}");
        };
        let (page, source) = (dir.join("PAGE.md"), dir.join("source.rs"));
        std::fs::write(&page, "old").unwrap();
        std::fs::write(&source, "old").unwrap();
        git(&["init", "-q"]);
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "x"]);
        let d = dir.to_str().unwrap();
        assert!(!commit_of(d, &[&page]).contains("uncommitted"));
        std::fs::write(&page, "regenerated").unwrap();
        assert!(!commit_of(d, &[&page]).contains("uncommitted"), "the page itself");
        assert!(commit_of(d, &[]).contains("uncommitted"), "the page, when it is not ours");
        std::fs::write(&source, "changed").unwrap();
        assert!(commit_of(d, &[&page]).contains("uncommitted"), "a source file");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn dates_from_days() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        assert_eq!(civil_from_days(20_418), (2025, 11, 26));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
    }

    #[test]
    fn commands_are_quoted_for_a_shell() {
        let args: Vec<String> =
            ["target/x", "bench", "a b.exr", "--filter", "jxr,bc6h:effort2", "it's"].map(String::from).into();
        assert_eq!(command_line(&args), r"hdrcodec bench 'a b.exr' --filter jxr,bc6h:effort2 'it'\''s'");
    }

    #[test]
    fn plots_sit_beside_the_page() {
        assert_eq!(rd_path(Path::new("d/BENCHMARKS.md")), Path::new("d/BENCHMARKS-rd.png"));
        assert_eq!(crate::plot::speed_path(&rd_path(Path::new("B.md"))), Path::new("B-rd-speed.png"));
    }
}
