//! The `hdrcodec` binary against its contract (DESIGN.md, "The CLI"): round trips, `info`,
//! `compare`, `bench --json`, `corpus write`, and bad input that must give exactly one
//! `hdrcodec: ...` line on stderr, a non-zero exit and no output file.

#[path = "../../tests/common/mod.rs"]
mod common;
mod terminal;

use hdrcodec::core::Limits;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

fn hdrcodec(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hdrcodec")).args(args.iter().map(|a| a.as_ref())).output().expect("run hdrcodec")
}

fn ok(out: &Output) -> String {
    assert!(out.status.success(), "hdrcodec failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout.clone()).expect("utf-8 stdout")
}

fn json(out: &Output) -> Value {
    let s = ok(out);
    serde_json::from_str(&s).unwrap_or_else(|e| panic!("not one JSON object ({e}):\n{s}"))
}

/// The generated corpus written once by `hdrcodec corpus write` (float EXR files).
fn corpus() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = common::temp_dir("cli-corpus");
        ok(&hdrcodec(&[&"corpus", &"write", &dir]));
        dir
    })
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// Runs a command that must fail by the contract: non-zero exit (not a panic's 101), exactly
/// one stderr line starting "hdrcodec:", nothing on stdout, and `dir` unchanged.
fn must_fail(args: &[&dyn AsRef<std::ffi::OsStr>], dir: &Path, reason_contains: &str) {
    let before = names(dir);
    let out = hdrcodec(args);
    let err = String::from_utf8_lossy(&out.stderr);
    let shown: Vec<_> = args.iter().map(|a| a.as_ref().to_string_lossy().into_owned()).collect();
    assert!(!out.status.success(), "succeeded: {shown:?}");
    assert_ne!(out.status.code(), Some(101), "panicked: {err}");
    assert_eq!(err.lines().count(), 1, "stderr must be one line: {err:?}");
    assert!(err.starts_with("hdrcodec: "), "{err:?}");
    assert!(!err.contains("panicked") && !err.contains("internal error"), "{err:?}");
    assert!(
        err.to_lowercase().contains(&reason_contains.to_lowercase()),
        "{shown:?}: expected '{reason_contains}' in {err:?}"
    );
    assert!(out.stdout.is_empty(), "stdout: {}", String::from_utf8_lossy(&out.stdout));
    assert_eq!(names(dir), before, "the directory changed");
}

fn decode(path: &Path) -> hdrcodec::core::HdrImage {
    hdrcodec::registry().read(path, &Limits::default()).expect("decode").1
}

#[test]
fn exr_pfm_exr_round_trip_is_identical() {
    let dir = common::temp_dir("cli-roundtrip");
    let src = corpus().join("odd-257x129.exr");
    let pfm = dir.join("a.pfm");
    let back = dir.join("b.exr");
    ok(&hdrcodec(&[&"convert", &src, &pfm]));
    ok(&hdrcodec(&[&"convert", &pfm, &back, &"--opt", &"pixel=float", &"--opt", &"compression=piz"]));
    // The float samples survive both formats exactly (PFM and float EXR are lossless).
    let (a, b) = (decode(&src), decode(&back));
    assert_eq!((a.width(), a.height()), (257, 129));
    assert_eq!(a.samples(), b.samples());
    // And the written PFM is what the PFM codec itself reads (the header is the standard one).
    let pfm_bytes = std::fs::read(&pfm).unwrap();
    assert!(pfm_bytes.starts_with(b"PF"), "{:?}", &pfm_bytes[..8]);
    let v = json(&hdrcodec(&[&"compare", &src, &back, &"--json"]));
    assert_eq!(v["identical"], Value::Bool(true), "{v}");
}

#[test]
fn compare_of_a_file_with_itself_reports_identical() {
    let x = corpus().join("sun-sky.exr");
    let text = ok(&hdrcodec(&[&"compare", &x, &x]));
    assert!(text.starts_with("identical: the images are identical"), "{text}");
    let v = json(&hdrcodec(&[&"compare", &x, &x, &"--json"]));
    assert_eq!(v["identical"], Value::Bool(true));
    // Infinite PSNRs are null in JSON (documented in `hdrcodec compare --help`); errors are 0.
    assert_eq!(v["pu21_psnr"], Value::Null);
    assert_eq!(v["psnr"], Value::Null);
    for k in ["de_itp_mean", "de_itp_p99", "log_rmse", "max_rel_err"] {
        assert_eq!(v[k].as_f64(), Some(0.0), "{k}: {v}");
    }
}

#[test]
fn compare_of_a_half_float_copy_is_close_but_not_identical() {
    let dir = common::temp_dir("cli-compare-half");
    let src = corpus().join("specular.exr");
    let half = dir.join("half.exr");
    ok(&hdrcodec(&[&"convert", &src, &half, &"--opt", &"pixel=half"]));
    let v = json(&hdrcodec(&[&"compare", &src, &half, &"--json"]));
    assert_eq!(v["identical"], Value::Bool(false));
    // binary16 keeps 11 significant bits: relative error at most 2^-11 (IEEE 754-2008) for
    // these normal-range samples, far below one JND of ΔE ITP.
    let rel = v["max_rel_err"].as_f64().unwrap();
    assert!(rel > 0.0 && rel <= 1.0 / 2048.0 + 1e-9, "{v}");
    assert!(v["de_itp_mean"].as_f64().unwrap() < 0.5, "{v}");
    assert!(v["pu21_psnr"].as_f64().unwrap() > 50.0, "{v}");
}

#[test]
fn info_json_describes_the_image() {
    let v = json(&hdrcodec(&[&"info", &corpus().join("odd-257x129.exr"), &"--json"]));
    assert_eq!(v["width"], 257);
    assert_eq!(v["height"], 129);
    assert_eq!(v["channels"], 3);
    assert_eq!(v["primaries"], "BT.709");
    assert_eq!(v["codec"], "exr");
    // The corpus is written as float ZIP (`corpus write`), which the header probe reports.
    assert_eq!(v["format"], "float, ZIP");
    assert_eq!(v["frames"], 1);
    assert!(v["file_size"].as_u64().unwrap() > 0);
    assert!(v["luminance_nits"]["max"].as_f64().unwrap() > 5e3, "{v}");
    let v = json(&hdrcodec(&[&"info", &corpus().join("bt2020-ramps.exr"), &"--json"]));
    assert_eq!(v["primaries"], "BT.2020");
    assert_eq!(v["chromaticities"]["green"][1].as_f64(), Some(0.797));
    let v = json(&hdrcodec(&[&"info", &corpus().join("alpha.exr"), &"--json"]));
    assert_eq!(v["channels"], 4);
    let text = ok(&hdrcodec(&[&"info", &corpus().join("sun-sky.exr")]));
    for needle in ["512 x 256", "channels:", "BT.709", "HDR10:", "format:        float, ZIP"] {
        assert!(text.contains(needle), "{needle} missing from:\n{text}");
    }
}

#[test]
fn info_agrees_with_exrheader() {
    let Some(exrheader) = common::require(common::tool("exrheader"), "exrheader (Debian openexr)") else {
        return;
    };
    let file = corpus().join("odd-3x5.exr");
    let out = common::run_ok(Command::new(exrheader).arg(&file));
    let text = String::from_utf8_lossy(&out.stdout);
    // OpenEXR's own tool: data window (0 0) - (2 4), 32-bit float R, G, B, zip compression.
    assert!(text.contains("(0 0) - (2 4)"), "{text}");
    assert!(text.contains("32-bit floating-point"), "{text}");
    assert!(text.contains("zip"), "{text}");
    let v = json(&hdrcodec(&[&"info", &file, &"--json"]));
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(3), Some(5)));
}

#[test]
fn corpus_write_matches_the_committed_manifest() {
    let written = std::fs::read_to_string(corpus().join("MANIFEST.tsv")).unwrap();
    let committed = std::fs::read_to_string(common::workspace_root().join("corpus/MANIFEST.tsv")).unwrap();
    assert_eq!(written, committed, "regenerate corpus/MANIFEST.tsv with `hdrcodec corpus write` and review the change");
    // Every scene file decodes to exactly the generator's samples.
    for s in hdrcodec_cli::corpus::scenes() {
        let img = decode(&corpus().join(format!("{}.exr", s.name)));
        assert_eq!(img.samples(), s.image.samples(), "{}", s.name);
        assert_eq!(img.color.primaries, s.image.color.primaries, "{}", s.name);
    }
}

#[test]
fn bench_json_on_the_generated_corpus() {
    // The family's own rows and the jxrlib/libultrahdr ones; the outside peers that are not
    // formats of the family (cjxl, avifenc, oiiotool: minutes of outside processes) have
    // their own tests below.
    let ours = "exr:,rgbe,logluv,bc6h,ultrahdr,jpeg-hdr,hdrc:,jxr";
    let v = json(&hdrcodec(&[&"bench", &"--json", &"--quick", &"--filter", &ours]));
    let rows = v["rows"].as_array().expect("rows");
    let summary = v["summary"].as_array().expect("summary");
    assert!(!rows.is_empty() && !summary.is_empty());
    let by_label = |l: &str| summary.iter().find(|s| s["config"] == l).unwrap_or_else(|| panic!("{l} missing"));
    // OpenEXR's lossless compressions give the float samples back exactly (OpenEXR technical
    // introduction, "Data Compression": NONE, RLE, ZIPS, ZIP, PIZ are lossless).
    for c in ["none", "rle", "zips", "zip", "piz"] {
        let s = by_label(&format!("exr:{c}-float"));
        assert_eq!(s["failed"], 0, "{s}");
        assert_eq!(s["identical_images"], s["images"], "{s}");
        assert_eq!(s["pu21_psnr"], Value::Null, "lossless PSNR is infinite: {s}");
    }
    // Uncompressed float stores at least 32 bits per sample.
    for r in rows.iter().filter(|r| r["config"] == "exr:none-float") {
        assert!(r["bpp"].as_f64().unwrap() >= 96.0, "{r}");
    }
    // B44 on half is lossy with a fixed ratio; its rows still carry finite metrics. It writes
    // every image, odd-257x129 included (whose last line exr 1.74.2's B44 compressor cannot pack).
    let b44 = by_label("exr:b44-half");
    assert_eq!(b44["failed"], 0, "{b44}");
    assert!(b44["bpp"].as_f64().unwrap() < by_label("exr:none-half")["bpp"].as_f64().unwrap());
    // A configuration may fail on an image (the row says why); the others have speeds.
    for r in rows.iter().filter(|r| r.get("error").is_none()) {
        assert!(r["encode_mps"].as_f64().unwrap() > 0.0 && r["decode_mps"].as_f64().unwrap() > 0.0, "{r}");
    }
}

/// The JPEG XR rows' labels: JxrEncApp lossless and at three `-q` settings.
const JXR_ROWS: [&str; 8] = [
    "jxr(jxrlib-enc):lossless",
    "jxr(jxrlib-enc):q0.9",
    "jxr(jxrlib-enc):q0.8",
    "jxr(jxrlib-enc):q0.7",
    "jxr(jxrlib-enc):q0.6",
    "jxr(jxrlib-enc):q0.5",
    "jxr(jxrlib-enc):q0.4",
    "jxr(jxrlib-enc):q0.3",
];
/// Our encoder's JPEG XR rows.
const JXR_OUR_ROWS: [&str; 6] = ["jxr:q100", "jxr:q90", "jxr:q70", "jxr:q50", "jxr:q30", "jxr:q10"];

fn labels(rows: &Value) -> Vec<String> {
    let mut v: Vec<String> =
        rows.as_array().unwrap().iter().map(|r| r["config"].as_str().unwrap().to_string()).collect();
    v.dedup();
    v
}

#[test]
fn bench_lists_jpeg_xr_rows_as_not_installed_without_jxrlib() {
    // An empty PATH: JxrEncApp cannot be found, and the rows say so instead of vanishing.
    let bench =
        |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_hdrcodec")).args(args).env("PATH", "").output().unwrap();
    let v = json(&bench(&["bench", "--quick", "--filter", "jxr(jxrlib", "--json"]));
    assert_eq!(labels(&v["rows"]), JXR_ROWS, "{v}");
    for r in v["rows"].as_array().unwrap() {
        assert!(r["error"].as_str().unwrap().starts_with("not installed: JxrEncApp"), "{r}");
    }
    for s in v["summary"].as_array().unwrap() {
        assert_eq!((s["images"].as_u64(), s["unavailable"].is_string()), (Some(0), true), "{s}");
    }
    let table = ok(&bench(&["bench", "--quick", "--filter", "jxr(jxrlib"]));
    for label in JXR_ROWS {
        let line = table.lines().find(|l| l.starts_with(label)).unwrap_or_else(|| panic!("no {label} in {table}"));
        assert!(line.contains("not installed: JxrEncApp (Debian libjxr-tools) is not on PATH"), "{line}");
    }
}

#[test]
fn bench_has_jpeg_xr_rows_encoded_by_jxrlib_and_decoded_by_us() {
    if common::require(
        common::tool("JxrEncApp").zip(common::tool("JxrDecApp")),
        "JxrEncApp and JxrDecApp (Debian libjxr-tools)",
    )
    .is_none()
    {
        return;
    }
    let v = json(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"jxr", &"--json"]));
    let all: Vec<&str> = JXR_OUR_ROWS.iter().chain(&JXR_ROWS).copied().collect();
    assert_eq!(labels(&v["rows"]), all, "--filter jxr keeps exactly the JPEG XR rows: {v}");
    let summary = v["summary"].as_array().unwrap();
    let s = |label: &str| summary.iter().find(|s| s["config"] == label).unwrap_or_else(|| panic!("{label}: {v}"));
    let bpp = |l: &str| s(l)["bpp"].as_f64().unwrap();
    let de = |l: &str| s(l)["de_itp_mean"].as_f64().unwrap();
    // Ours: lower quality, fewer bits, more loss; lossless as small as jxrlib's.
    for w in JXR_OUR_ROWS.windows(2) {
        assert!(bpp(w[1]) < bpp(w[0]) && de(w[1]) >= de(w[0]), "{w:?}: {v}");
    }
    // Lossless: as small as jxrlib's (both keep alpha, losslessly, on the image that has it).
    let bytes = |label: &str| -> u64 {
        v["rows"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["config"] == label)
            .map(|r| r["bytes"].as_u64().unwrap())
            .sum()
    };
    assert!(bytes(JXR_OUR_ROWS[0]) as f64 <= bytes(JXR_ROWS[0]) as f64 * 1.01, "{v}");
    for r in v["rows"].as_array().unwrap().iter().filter(|r| r["config"].as_str().unwrap().starts_with("jxr(")) {
        assert!(r["error"].is_null(), "{r}");
        assert!(r["bytes"].as_u64().unwrap() > 0 && r["bpp"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["encoder"].as_str().unwrap().contains("JxrEncApp"), "{r}");
        assert!(r["peer"]["decoder"].as_str().unwrap().contains("JxrDecApp"), "{r}");
        // jxrlib is the reference decoder: ours gives its samples, byte for byte.
        assert_eq!(r["peer"]["matches"], Value::Bool(true), "{r}");
        assert!(r["peer"]["decode_mps"].as_f64().unwrap() > 0.0, "{r}");
        for k in ["encode_mps", "decode_mps", "decode_mps_all"] {
            assert!(r[k].as_f64().unwrap() > 0.0, "{k}: {r}");
        }
        // JxrEncApp is an outside program on one thread: no pool figure.
        assert!(r["encode_mps_all"].is_null(), "{r}");
    }
    for label in JXR_ROWS {
        assert_eq!((s(label)["failed"].as_u64(), s(label)["peer"]["mismatches"].as_u64()), (Some(0), Some(0)), "{v}");
    }
    // Lower -q writes fewer bits and loses more (JxrEncApp's quality scale).
    for w in JXR_ROWS.windows(2) {
        assert!(bpp(w[1]) < bpp(w[0]) && de(w[1]) >= de(w[0]), "{w:?}: {v}");
    }
    // Lossless JPEG XR of half floats loses only the rounding to half (11 significant bits,
    // IEEE 754-2008): far below one JND of ΔE ITP.
    assert!(de(JXR_ROWS[0]) < 0.5, "{v}");
    // Bytes at equal PU21-PSNR, ours against jxrlib's: every lossy row of ours (not asked to
    // be lossless) is placed on jxrlib's curve of the same image, or counted as outside it.
    let eq = v["equal_quality"].as_array().unwrap();
    let c = eq.iter().find(|c| c["subject"] == "jxr:" && c["reference"] == "jxr(jxrlib-enc):").expect("comparison");
    let lossy = v["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["config"].as_str().unwrap().starts_with("jxr:"))
        .filter(|r| r["identical"] == Value::Bool(false) && r["lossless"] == Value::Bool(false));
    assert_eq!(c["points"].as_array().unwrap().len() + c["out_of_range"].as_u64().unwrap() as usize, lossy.count());
    for p in c["points"].as_array().unwrap() {
        let ratio = p["bytes"].as_f64().unwrap() / p["reference_bytes"].as_f64().unwrap();
        assert!((p["ratio"].as_f64().unwrap() - ratio).abs() < 1e-9 && ratio > 0.0, "{p}");
    }
    let table = ok(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"jxr"]));
    assert!(table.lines().next().unwrap().contains("peer dec"), "{table}");
    assert!(table.contains("bytes of jxr: / bytes of jxr(jxrlib-enc): at equal PU21-PSNR"), "{table}");
    for label in JXR_ROWS {
        assert!(table.lines().any(|l| l.starts_with(label)), "{table}");
    }
    assert!(!table.contains("DIFFERS") && !table.contains("not installed"), "{table}");
    assert!(table.contains("jxr(jxrlib-enc) rows: jxrlib's JxrEncApp writes the file"), "{table}");
}

/// The outside peers' row families (issue 15): label prefix, the programs each needs and the
/// "not installed" message without them.
const PEER_FAMILIES: [(&str, &[&str], &str); 3] = [
    ("jxl(cjxl):", &["cjxl", "djxl"], "not installed: cjxl and djxl (Debian libjxl-tools) are not on PATH"),
    (
        "avif(avifenc):",
        &["avifenc", "avifdec"],
        "not installed: avifenc and avifdec (Debian libavif-bin) are not on PATH",
    ),
    ("exr(oiiotool):", &["oiiotool"], "not installed: oiiotool (Debian openimageio-tools) is not on PATH"),
];
/// Every peer row's label: JPEG XL lossless and at a sweep of distances, AVIF at 10 and 12 bits
/// and a sweep of quantizers, OpenEXR written by oiiotool.
const PEER_ROWS: [&str; 23] = [
    "jxl(cjxl):lossless",
    "jxl(cjxl):d0.1",
    "jxl(cjxl):d0.25",
    "jxl(cjxl):d0.5",
    "jxl(cjxl):d1",
    "jxl(cjxl):d2",
    "jxl(cjxl):d4",
    "avif(avifenc):10bit-qp2",
    "avif(avifenc):10bit-qp10",
    "avif(avifenc):10bit-qp20",
    "avif(avifenc):10bit-qp30",
    "avif(avifenc):10bit-qp40",
    "avif(avifenc):12bit-qp2",
    "avif(avifenc):12bit-qp10",
    "avif(avifenc):12bit-qp20",
    "avif(avifenc):12bit-qp30",
    "avif(avifenc):12bit-qp40",
    "exr(oiiotool):zip-half",
    "exr(oiiotool):piz-half",
    "exr(oiiotool):b44-half",
    "exr(oiiotool):dwaa-half",
    "exr(oiiotool):zip-float",
    "exr(oiiotool):piz-float",
];
/// `--filter` for every peer row.
const PEER_FILTER: &str = "jxl(cjxl),avif(avifenc),exr(oiiotool)";

#[test]
fn bench_lists_the_outside_peers_as_not_installed_without_them() {
    let bench =
        |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_hdrcodec")).args(args).env("PATH", "").output().unwrap();
    let v = json(&bench(&["bench", "--quick", "--filter", PEER_FILTER, "--json"]));
    assert_eq!(labels(&v["rows"]), PEER_ROWS, "{v}");
    for r in v["rows"].as_array().unwrap() {
        let label = r["config"].as_str().unwrap();
        let (_, _, why) = PEER_FAMILIES.iter().find(|f| label.starts_with(f.0)).unwrap();
        assert_eq!(r["error"].as_str(), Some(*why), "{r}");
    }
    for s in v["summary"].as_array().unwrap() {
        assert_eq!((s["images"].as_u64(), s["unavailable"].is_string()), (Some(0), true), "{s}");
    }
    let table = ok(&bench(&["bench", "--quick", "--filter", PEER_FILTER]));
    for label in PEER_ROWS {
        let line = table.lines().find(|l| l.starts_with(label)).unwrap_or_else(|| panic!("no {label} in {table}"));
        assert!(line.contains("not installed: "), "{line}");
    }
}

#[cfg(unix)]
#[test]
fn a_failing_peer_tool_makes_an_error_row_with_its_message() {
    use std::os::unix::fs::PermissionsExt;
    // Stand-ins on PATH that fail as cjxl does (a banner line, then the error) or exit with
    // success without writing the file.
    let bin = common::temp_dir("cli-bench-failing-tools");
    let stub = |name: &str, body: &str| {
        let path = bin.join(name);
        std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    };
    stub("cjxl", "echo 'JPEG XL encoder v0.0.0' >&2; echo 'Reading image data failed.' >&2; exit 1");
    ["djxl", "avifenc", "avifdec"].into_iter().for_each(|name| stub(name, "exit 0"));
    let child = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .args(["bench", "--quick", "--filter", "jxl(cjxl):d1,avif(avifenc):10bit-qp10", "--json"])
        .env("PATH", &bin)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let v = json(&child.wait_with_output().unwrap());
    let rows = v["rows"].as_array().unwrap();
    assert!(!rows.is_empty());
    for r in rows {
        let e = r["error"].as_str().unwrap_or_else(|| panic!("no error: {r}"));
        if r["config"].as_str().unwrap().starts_with("jxl") {
            let expected = "cjxl failed (exit status: 1): JPEG XL encoder v0.0.0 | Reading image data failed.";
            assert!(e.ends_with(expected), "{e}");
        } else {
            assert!(e.ends_with("avifenc wrote no file: no message"), "{r}");
        }
    }
    // The failed rows left no temporary directory behind (`hdrcodec-bench-<peer>-<pid>-<n>`).
    let left: Vec<String> = std::fs::read_dir(std::env::temp_dir())
        .unwrap()
        .filter_map(|e| Some(e.ok()?.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.starts_with("hdrcodec-bench-") && n.contains(&format!("-{pid}-")))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn bench_has_jpeg_xl_avif_and_openexr_peer_rows() {
    let tools: Option<Vec<PathBuf>> = PEER_FAMILIES.iter().flat_map(|f| f.1.iter()).map(|t| common::tool(t)).collect();
    if common::require(tools, "cjxl, djxl (libjxl-tools), avifenc, avifdec (libavif-bin) and oiiotool").is_none() {
        return;
    }
    // A BT.709 image with alpha and a BT.2020 one: the colour paths of every peer.
    let dir = common::temp_dir("cli-bench-peers");
    for name in ["alpha.exr", "bt2020-ramps.exr"] {
        std::fs::copy(corpus().join(name), dir.join(name)).unwrap();
    }
    let filter = format!("{PEER_FILTER},exr:piz-half,jxr:");
    let v = json(&hdrcodec(&[&"bench", &dir, &"--runs", &"1", &"--filter", &filter, &"--json"]));
    let rows = v["rows"].as_array().unwrap();
    let peer_rows: Vec<&Value> = rows.iter().filter(|r| PEER_ROWS.contains(&r["config"].as_str().unwrap())).collect();
    assert_eq!(peer_rows.len(), 2 * PEER_ROWS.len(), "{v}");
    for r in &peer_rows {
        assert!(r["error"].is_null(), "{r}");
        assert!(r["bytes"].as_u64().unwrap() > 0 && r["encode_mps"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["decode_mps"].as_f64().unwrap() > 0.0 && r["encode_mps_all"].is_null(), "{r}");
        let label = r["config"].as_str().unwrap();
        let (encoder, decoder) = (r["encoder"].as_str().unwrap(), r["decoder"].as_str());
        if label.starts_with("jxl(") {
            assert!(encoder.starts_with("cjxl v") && decoder.unwrap().starts_with("djxl v"), "{r}");
        } else if label.starts_with("avif(") {
            assert!(encoder.starts_with("avifenc 0.") && decoder.unwrap().starts_with("avifdec 0."), "{r}");
        } else {
            // OpenEXR: our decoder reads oiiotool's file; OpenEXR's decode of it is the peer,
            // and its samples are ours, bit for bit.
            assert!(encoder.starts_with("oiiotool ") && encoder.contains("OpenEXR "), "{r}");
            assert!(r["decode_mps_all"].as_f64().unwrap() > 0.0, "{r}");
            assert_eq!(r["peer"]["matches"], Value::Bool(true), "{r}");
        }
    }
    let row = |label: &str, image: &str| {
        rows.iter().find(|r| r["config"] == label && r["image"] == image).unwrap_or_else(|| panic!("{label} {image}"))
    };
    let summary = v["summary"].as_array().unwrap();
    let s = |label: &str| summary.iter().find(|s| s["config"] == label).unwrap_or_else(|| panic!("{label}: {v}"));
    let bpp = |l: &str| s(l)["bpp"].as_f64().unwrap();
    for image in ["alpha.exr", "bt2020-ramps.exr"] {
        // cjxl -d 0 is lossless on float input (libjxl: modular mode); zip and piz of float samples
        // are (OpenEXR technical introduction, "Data Compression").
        for label in ["jxl(cjxl):lossless", "exr(oiiotool):zip-float", "exr(oiiotool):piz-float"] {
            assert_eq!(row(label, image)["identical"], Value::Bool(true), "{label} {image}");
        }
        // OpenImageIO's PIZ of half samples: the same half rounding as ours, about our size.
        let (theirs, ours) = (row("exr(oiiotool):piz-half", image), row("exr:piz-half", image));
        assert_eq!(theirs["pu21_psnr"], ours["pu21_psnr"], "{image}");
        let ratio = theirs["bytes"].as_f64().unwrap() / ours["bytes"].as_f64().unwrap();
        assert!((0.98..1.02).contains(&ratio), "{image}: {ratio}");
    }
    // A coarser setting writes fewer bytes: a rate-quality curve per family.
    for family in [&PEER_ROWS[1..7], &PEER_ROWS[7..12], &PEER_ROWS[12..17]] {
        for w in family.windows(2) {
            assert!(bpp(w[1]) < bpp(w[0]), "{w:?}: {v}");
        }
    }
    // PQ in 12 bits at the finest quantizer: within a few ΔE ITP units of the input (one unit
    // ≈ one JND, BT.2124) on both images, the BT.2020 one included.
    for image in ["alpha.exr", "bt2020-ramps.exr"] {
        let de = row("avif(avifenc):12bit-qp2", image)["de_itp_mean"].as_f64().unwrap();
        assert!(de < 3.0, "{image}: {de}");
    }
    // Bytes at equal PU21-PSNR: our JPEG XR against each peer family.
    let eq = v["equal_quality"].as_array().unwrap();
    for reference in ["jxl(cjxl):", "avif(avifenc):10bit", "avif(avifenc):12bit"] {
        let c = eq.iter().find(|c| c["subject"] == "jxr:" && c["reference"] == reference).expect(reference);
        let lossy = rows
            .iter()
            .filter(|r| r["config"].as_str().unwrap().starts_with("jxr:"))
            .filter(|r| r["identical"] == Value::Bool(false) && r["lossless"] == Value::Bool(false))
            .count();
        assert_eq!(c["points"].as_array().unwrap().len() + c["out_of_range"].as_u64().unwrap() as usize, lossy);
    }
    // The table names the tools and explains the rows; --plot draws with the peers in it.
    let png = dir.join("rd.png");
    let font = std::path::Path::new("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf").is_file();
    let small = "jxl(cjxl):d1,avif(avifenc):10bit-qp20,exr(oiiotool):dwaa";
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"bench", &dir, &"--runs", &"1", &"--filter", &small];
    if font {
        args.extend([&"--plot" as &dyn AsRef<std::ffi::OsStr>, &png]);
    }
    let table = ok(&hdrcodec(&args));
    for text in ["jxl(cjxl) rows: cjxl v", "avif(avifenc) rows:", "--cicp 9/16/9", "exr(oiiotool) rows: oiiotool "] {
        assert!(table.contains(text), "{text}: {table}");
    }
    assert!(!table.contains("DIFFERS"), "{table}");
    if font {
        assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    }
    // A file that records no primaries (PFM): BT.709 is assumed for JPEG XL's and AVIF's input,
    // and the row says so instead of guessing silently.
    let pfm_dir = common::temp_dir("cli-bench-peers-pfm");
    ok(&hdrcodec(&[&"convert", &corpus().join("alpha.exr"), &pfm_dir.join("alpha.pfm")]));
    let filter = "jxl(cjxl):d1,avif(avifenc):10bit-qp10";
    let v = json(&hdrcodec(&[&"bench", &pfm_dir, &"--runs", &"1", &"--filter", &filter, &"--json"]));
    for r in v["rows"].as_array().unwrap() {
        assert!(r["error"].is_null() && r["pu21_psnr"].as_f64().unwrap() > 30.0, "{r}");
        let notes = r["notes"].as_array().unwrap();
        assert!(notes.iter().any(|n| n.as_str().unwrap().contains("no primaries: BT.709 assumed")), "{r}");
    }
}

#[test]
fn bench_on_a_directory_and_as_a_table() {
    let dir = common::temp_dir("cli-bench-dir");
    std::fs::copy(corpus().join("odd-3x5.exr"), dir.join("small.exr")).unwrap();
    std::fs::write(dir.join("notes.txt"), "not an image").unwrap();
    std::fs::write(dir.join("broken.exr"), [0x76, 0x2f, 0x31, 0x01, 2, 0]).unwrap();
    let v = json(&hdrcodec(&[&"bench", &dir, &"--json", &"--quick", &"--filter", &"exr:zip"]));
    let rows = v["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["image"] == "small.exr"), "{v}");
    assert_eq!(v["skipped"][0]["file"], "broken.exr", "{v}");
    let table = ok(&hdrcodec(&[&"bench", &dir, &"--quick", &"--filter", &"exr:zip-float"]));
    assert!(table.lines().next().unwrap().contains("PU21-PSNR"), "{table}");
    assert!(table.contains("exr:zip-float") && table.contains("lossless"), "{table}");
    let table = ok(&hdrcodec(&[&"bench", &dir, &"--quick", &"--filter", &"exr:zip-float", &"--per-image"]));
    assert!(table.lines().any(|l| l.starts_with("exr:zip-float") && l.contains("small.exr")), "{table}");
}

/// The tables size their columns to their content: an image name longer than the old fixed
/// 24 columns widens its column, and every row's figures end where their header ends.
#[test]
fn bench_table_columns_line_up_whatever_the_labels() {
    let dir = common::temp_dir("cli-bench-columns");
    let long = "an-image-name-much-longer-than-24-columns.exr";
    std::fs::copy(corpus().join("odd-3x5.exr"), dir.join(long)).unwrap();
    let filter = "exr:zip-float,exr:none-half";
    let text = ok(&hdrcodec(&[&"bench", &dir, &"--quick", &"--filter", &filter, &"--per-image"]));
    let mut tables = 0;
    let mut lines = text.lines().peekable();
    while let Some(header) = lines.next() {
        if !header.starts_with("config") {
            continue;
        }
        tables += 1;
        let (bpp, dec) = (header.find(" bpp").unwrap() + 4, header.find(" dec 1T").unwrap() + 7);
        let mut rows = 0;
        while let Some(row) = lines.next_if(|l| l.starts_with("exr:")) {
            let at = |end: usize| (row.as_bytes()[end - 1], row.as_bytes().get(end).copied().unwrap_or(b' '));
            for end in [bpp, dec] {
                let (last, next) = at(end);
                assert!(last.is_ascii_digit() && next == b' ', "{row:?} against {header:?}\n{text}");
            }
            rows += 1;
        }
        assert_eq!(rows, 2, "{text}");
    }
    assert_eq!(tables, 2, "the summary and the per-image table: {text}");
    assert!(text.contains(long), "{text}");
}

/// With `--crop`, the memory rows still decode the largest image whole.
#[test]
fn bench_memory_rows_decode_the_whole_largest_image_under_crop() {
    let dir = common::temp_dir("cli-bench-memory-crop");
    std::fs::copy(corpus().join("odd-3x5.exr"), dir.join("small.exr")).unwrap();
    let args: [&dyn AsRef<std::ffi::OsStr>; 9] =
        [&"bench", &dir, &"--quick", &"--filter", &"exr:none-half", &"--crop", &"2x2", &"--memory", &"--json"];
    let v = json(&hdrcodec(&args));
    assert_eq!(v["rows"][0]["image"], "small.exr@c2x2", "{v}");
    let m = &v["memory"][0];
    assert_eq!(
        (m["image"].as_str(), m["width"].as_u64(), m["height"].as_u64()),
        (Some("small.exr"), Some(3), Some(5)),
        "{v}"
    );
}

#[test]
fn bench_video_rows_compare_ours_with_svt_av1() {
    if common::require(common::tool("ffmpeg"), "ffmpeg (Debian ffmpeg, with libsvtav1 and libdav1d)").is_none() {
        return;
    }
    let dir = common::temp_dir("cli-bench-video-report");
    let md = dir.join("V.md");
    let filter = "av1:q100,av1(svt-av1):crf25";
    let v = json(&hdrcodec(&[&"bench", &"--video", &"--quick", &"--filter", &filter, &"--json", &"--report", &md]));
    assert_eq!(v["rows"].as_array().map(Vec::len), Some(0), "only video rows: {v}");
    let rows = v["video"].as_array().unwrap();
    let labels: Vec<(&str, &str)> =
        rows.iter().map(|r| (r["config"].as_str().unwrap(), r["sequence"].as_str().unwrap())).collect();
    // The moving light, then a pan across the largest of the --quick images.
    assert_eq!(labels.len(), 4, "{v}");
    assert_eq!(labels[0], ("av1:q100", "moving-light"));
    assert!(labels[1].1.starts_with("pan:") && labels[3].0 == "av1(svt-av1):crf25", "{v}");
    for r in rows {
        assert!(r["error"].is_null(), "{r}");
        assert_eq!((r["width"].as_u64(), r["height"].as_u64(), r["frames"].as_u64()), (Some(128), Some(72), Some(4)));
        let (bytes, bpp) = (r["bytes"].as_u64().unwrap(), r["bpp"].as_f64().unwrap());
        assert!(bytes > 100 && (bpp - bytes as f64 * 8.0 / (128.0 * 72.0 * 4.0)).abs() < 1e-9, "{r}");
        // Lossy but close: a coarse quantizer on small frames still gives the scene back.
        let psnr = r["pu21_psnr"].as_f64().unwrap();
        assert!(psnr.is_finite() && psnr > 25.0, "{r}");
        assert!(r["de_itp_mean"].as_f64().unwrap() > 0.0 && r["encode_fps"].as_f64().unwrap() > 0.0, "{r}");
        // Both streams say HDR10, with the same mastering display and content light level.
        let signalled = r["signalled"].as_str().unwrap();
        assert!(
            signalled.starts_with("cicp 9/16/9 limited, 10-bit, chroma colocated, MDCV 1000/0.0001 cd/m², CLL "),
            "{r}"
        );
        // FFmpeg's libdav1d decodes the same planes as ours.
        assert_eq!(r["peer"]["matches"], true, "{r}");
        let encoder = r["encoder"].as_str().unwrap();
        if r["config"].as_str().unwrap().starts_with("av1(svt-av1)") {
            assert!(encoder.starts_with("ffmpeg ") && encoder.contains("SVT-AV1 v"), "{encoder}");
        } else {
            assert!(encoder.starts_with("hdrcodec-video (rav1e 0."), "{encoder}");
        }
    }
    // The page has the video table, and its peer-tool table names the rows that used FFmpeg.
    let page = std::fs::read_to_string(&md).unwrap();
    assert!(
        page.contains("## Video: HDR10 AV1")
            && page.lines().any(|l| l.starts_with("av1(svt-av1):crf25") && l.contains(" pan:")),
        "{page}"
    );
    let tools = page.lines().find(|l| l.starts_with("| ffmpeg |")).unwrap();
    assert!(tools.ends_with("| `av1:q100`, `av1(svt-av1):crf25` |"), "{tools}");
    let table = ok(&hdrcodec(&[&"bench", &"--video", &"--quick", &"--filter", &"av1:q180"]));
    assert!(table.starts_with("video config") && table.contains("av1:q180") && !table.contains("DIFFERS"), "{table}");
}

#[test]
fn bench_video_rows_without_ffmpeg_say_not_installed() {
    let out = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .args(["bench", "--video", "--quick", "--filter", "av1:q180,av1(svt-av1):crf45", "--json"])
        .env("PATH", "")
        .output()
        .unwrap();
    let v = json(&out);
    for r in v["video"].as_array().unwrap() {
        if r["config"] == "av1(svt-av1):crf45" {
            assert_eq!(r["error"], "not installed: ffmpeg (Debian ffmpeg) is not on PATH", "{r}");
        } else {
            // Ours still runs; only its peer decode is missing, and the row says so.
            assert!(r["error"].is_null() && r["bytes"].as_u64().unwrap() > 0 && r["peer"].is_null(), "{r}");
            assert!(r["notes"][0].as_str().unwrap().contains("no peer decode"), "{r}");
        }
    }
    // Without --video, a filter that only names video rows matches nothing.
    let dir = common::temp_dir("cli-bench-video");
    must_fail(&[&"bench", &"--quick", &"--filter", &"av1:q180"], &dir, "no bench configuration matches");
}

#[test]
fn bench_on_the_shared_corpus_takes_its_stills_cropped() {
    let Some(dir) = common::require(common::corpus_dir(), "the shared HDR corpus (../shared/corpus)") else { return };
    let args: [&dyn AsRef<std::ffi::OsStr>; 9] =
        [&"bench", &"--corpus", &"shared", &"--crop", &"64x48", &"--filter", &"exr:zip-half", &"--quick", &"--json"];
    let out = Command::new(env!("CARGO_BIN_EXE_hdrcodec")).args(args).env("HDRCODEC_CORPUS", &dir).output().unwrap();
    let v = json(&out);
    assert!(v["source"].as_str().unwrap().starts_with("the shared corpus's original EXR and Radiance stills"), "{v}");
    let images: Vec<&str> = v["rows"].as_array().unwrap().iter().map(|r| r["image"].as_str().unwrap()).collect();
    // The MANIFEST's original exr/ and hdr/ files, each cropped (all are larger than 64x48);
    // not the corpus's own re-encodes.
    assert!(images.contains(&"Desk.exr@c64x48") && images.contains(&"mpi_atrium_3.hdr@c64x48"), "{images:?}");
    assert!(images.iter().all(|i| i.ends_with("@c64x48") && !i.contains("dwaa")), "{images:?}");
    assert!(v["rows"].as_array().unwrap().iter().all(|r| r["pixels"] == 64 * 48 && r["error"].is_null()), "{v}");
    // A missing corpus and a bad crop are one-line errors.
    let empty = common::temp_dir("cli-bench-no-corpus");
    let out = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .args(["bench", "--corpus", "shared", "--quick"])
        .env("HDRCODEC_CORPUS", &empty)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.starts_with("hdrcodec: ") && err.contains("HDRCODEC_CORPUS"), "{err}");
    must_fail(&[&"bench", &"--crop", &"0x5", &"--quick"], &empty, "--crop wants WIDTHxHEIGHT");
    must_fail(&[&"bench", &"--corpus", &"elsewhere", &"--quick"], &empty, "--corpus is 'shared' or 'generated'");
}

#[test]
fn bench_memory_rows_measure_a_child_decode_per_codec() {
    let v = json(&hdrcodec(&[
        &"bench",
        &"--memory",
        &"--quick",
        &"--filter",
        &"exr:zip-half,exr:piz-half,bc6h:effort0",
        &"--json",
    ]));
    let memory = v["memory"].as_array().unwrap();
    // One row per codec (its first configuration), on the largest image of the run.
    let configs: Vec<&str> = memory.iter().map(|r| r["config"].as_str().unwrap()).collect();
    assert_eq!(configs, ["exr:zip-half", "bc6h:effort0"], "{v}");
    let largest = v["rows"].as_array().unwrap().iter().max_by_key(|r| r["pixels"].as_u64().unwrap()).unwrap();
    for r in memory {
        assert!(r["error"].is_null(), "{r}");
        assert_eq!(r["image"], largest["image"], "{r}");
        let (w, h) = (r["width"].as_u64().unwrap(), r["height"].as_u64().unwrap());
        assert_eq!(w * h, largest["pixels"].as_u64().unwrap(), "{r}");
        let decoded = r["decoded_bytes"].as_u64().unwrap();
        assert!(decoded == w * h * 12 || decoded == w * h * 16, "{r}");
        // The decoded image was resident at the peak: the peak is above the start by at least
        // most of it, and the growth ratio is what the figures say.
        let (start, peak) = (r["start_rss_bytes"].as_u64().unwrap(), r["peak_rss_bytes"].as_u64().unwrap());
        assert!(start > 0 && peak as f64 >= start as f64 + 0.9 * decoded as f64, "{r}");
        let growth = r["growth_ratio"].as_f64().unwrap();
        assert!((growth - (peak - start) as f64 / decoded as f64).abs() < 1e-9, "{r}");
    }
    // The child on its own, and on a file that is not an image: one-line errors.
    let dir = common::temp_dir("cli-memory-peak");
    std::fs::write(dir.join("bad.exr"), b"not an exr").unwrap();
    must_fail(&[&"memory-peak", &dir.join("bad.exr")], &dir, "not an OpenEXR file");
    let one = json(&hdrcodec(&[&"memory-peak", &corpus().join("odd-3x5.exr")]));
    assert_eq!((one["codec"].as_str(), one["width"].as_u64(), one["height"].as_u64()), (Some("exr"), Some(3), Some(5)));
}

#[test]
fn bench_has_ispc_rows_or_says_they_are_not_installed() {
    // Without the `ispc` feature (the default) the rows say so; with it they are measured.
    let v = json(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"bc6h(ispc)", &"--json"]));
    assert_eq!(labels(&v["rows"]), ["bc6h(ispc):veryfast", "bc6h(ispc):fast", "bc6h(ispc):basic"], "{v}");
    for r in v["rows"].as_array().unwrap() {
        assert!(r["encoder"].as_str().unwrap().starts_with("Intel ISPC texcomp (intel_tex_2 0.5, "), "{r}");
        if cfg!(feature = "ispc") {
            assert!(r["error"].is_null() && r["bytes"].as_u64().unwrap() > 0, "{r}");
            // (odd-3x5 holds what BC6H cannot: ~7 dB from ours as from ISPC.)
            let floor = if r["image"] == "odd-3x5" { 0.0 } else { 40.0 };
            assert!(r["pu21_psnr"].as_f64().unwrap() > floor && r["encode_mps_all"].is_null(), "{r}");
        } else {
            let e = r["error"].as_str().unwrap();
            assert_eq!(e, "not installed: this build has no Intel ISPC (cargo feature `ispc`: intel_tex_2)", "{r}");
        }
    }
    let table = ok(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"bc6h(ispc)"]));
    let line = table.lines().find(|l| l.starts_with("bc6h(ispc):fast")).unwrap_or_else(|| panic!("{table}"));
    assert_eq!(line.contains("not installed: "), !cfg!(feature = "ispc"), "{table}");
}

#[test]
fn missing_and_unknown_files_fail_cleanly() {
    let dir = common::temp_dir("cli-missing");
    let good = corpus().join("tiny-1x1.exr");
    must_fail(&[&"info", &dir.join("nope.exr")], &dir, "nope.exr");
    must_fail(&[&"convert", &dir.join("nope.exr"), &dir.join("out.pfm")], &dir, "nope.exr");
    must_fail(&[&"convert", &good, &dir.join("out.xyz")], &dir, "unknown file extension '.xyz'");
    must_fail(&[&"convert", &good, &dir.join("out.exr"), &"--codec", &"nosuch"], &dir, "unknown codec 'nosuch'");
    must_fail(&[&"convert", &good, &dir.join("out.exr"), &"--opt", &"bogus=1"], &dir, "bogus");
    must_fail(&[&"convert", &good, &dir.join("out.exr"), &"--opt", &"novalue"], &dir, "key=value");
    std::fs::write(dir.join("junk.xyz"), b"0123456789").unwrap();
    must_fail(&[&"info", &dir.join("junk.xyz")], &dir, "unknown file extension '.xyz'");
    must_fail(&[&"convert", &good, &dir.join("no/such/dir/out.exr")], &dir, "out.exr");
    must_fail(&[&"compare", &good, &corpus().join("odd-3x5.exr")], &dir, "");
    // Usage errors follow the same one-line rule.
    must_fail(&[&"convert", &good], &dir, "");
    must_fail(&[&"frobnicate"], &dir, "");
}

#[test]
fn corrupt_and_truncated_files_fail_cleanly() {
    let dir = common::temp_dir("cli-corrupt");
    let good = std::fs::read(corpus().join("edges.exr")).unwrap();
    let out = dir.join("out.pfm");
    // Truncated EXR: header complete, pixel data cut off.
    std::fs::write(dir.join("trunc.exr"), &good[..good.len() / 2]).unwrap();
    must_fail(&[&"convert", &dir.join("trunc.exr"), &out], &dir, "");
    // Only the magic number.
    std::fs::write(dir.join("magic.exr"), &good[..4]).unwrap();
    must_fail(&[&"convert", &dir.join("magic.exr"), &out], &dir, "");
    // Corrupt header: attribute names overwritten.
    let mut bad = good.clone();
    bad[8..40].fill(0xff);
    std::fs::write(dir.join("corrupt.exr"), &bad).unwrap();
    must_fail(&[&"convert", &dir.join("corrupt.exr"), &out], &dir, "");

    // .hdrc written by the CLI, then truncated and corrupted.
    let hdrc = dir.join("ok.hdrc");
    ok(&hdrcodec(&[&"convert", &corpus().join("edges.exr"), &hdrc]));
    let bytes = std::fs::read(&hdrc).unwrap();
    assert_eq!(decode(&hdrc).samples(), decode(&corpus().join("edges.exr")).samples());
    std::fs::write(dir.join("trunc.hdrc"), &bytes[..bytes.len() - 7]).unwrap();
    must_fail(&[&"convert", &dir.join("trunc.hdrc"), &out], &dir, "");
    let mut flipped = bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x10;
    std::fs::write(dir.join("crc.hdrc"), &flipped).unwrap();
    must_fail(&[&"info", &dir.join("crc.hdrc")], &dir, "");
    must_fail(&[&"convert", &dir.join("crc.hdrc"), &out], &dir, "");

    // A PFM header declaring 10^8 x 10^8 pixels must be refused before allocating.
    std::fs::write(dir.join("huge.pfm"), b"PF\n100000000 100000000\n-1.0\n\0\0\0\0").unwrap();
    must_fail(&[&"convert", &dir.join("huge.pfm"), &dir.join("out.exr")], &dir, "");
    must_fail(&[&"info", &dir.join("huge.pfm")], &dir, "");
}

#[test]
fn failed_overwrite_keeps_the_old_file() {
    let dir = common::temp_dir("cli-overwrite");
    let target = dir.join("keep.exr");
    std::fs::write(&target, b"precious").unwrap();
    std::fs::write(dir.join("bad.exr"), b"\x76\x2f\x31\x01garbage").unwrap();
    must_fail(&[&"convert", &dir.join("bad.exr"), &target], &dir, "");
    assert_eq!(std::fs::read(&target).unwrap(), b"precious");
}

#[test]
fn registry_reads_by_extension_and_by_bytes() {
    let dir = common::temp_dir("cli-sniff");
    // An EXR under a wrong name is still recognised by its magic number.
    std::fs::copy(corpus().join("odd-3x5.exr"), dir.join("mislabelled.pfm")).unwrap();
    let v = json(&hdrcodec(&[&"info", &dir.join("mislabelled.pfm"), &"--json"]));
    assert_eq!(v["codec"], "exr");
    let codec = hdrcodec::registry().by_name("exr").unwrap();
    assert!(codec.sniff(&hdrcodec::exr::MAGIC));
}

/// A sans-serif font for the plots' labels, or `None` (a skip with a printed reason, a failure in CI).
fn font() -> Option<PathBuf> {
    let font = ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/TTF/DejaVuSans.ttf"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.is_file());
    common::require(
        font,
        "a DejaVu Sans font (Debian fonts-dejavu-core) for bench --plot, --report and compare --heatmap",
    )
}

/// A PNG's size, 8-bit RGB checked (ISO/IEC 15948: signature, then IHDR).
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&bytes[12..16], b"IHDR");
    assert_eq!((bytes[24], bytes[25]), (8, 2), "8-bit RGB");
    let be = |at: usize| u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn bench_plot_writes_rate_distortion_curves_and_a_speed_chart() {
    if font().is_none() {
        return;
    }
    let dir = common::temp_dir("cli-plot");
    let png = dir.join("rd.png");
    ok(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"exr:b44,jxr:q50,jxr:q90", &"--plot", &png]));
    // The two rate-distortion panels and the legend; the speed chart beside it, one bar pair
    // per configuration (26 pixels each, 140 for the caption and axis): 4 exr:b44 rows, 2 jxr.
    assert_eq!(png_size(&std::fs::read(&png).unwrap()), (1800, 850));
    assert_eq!(png_size(&std::fs::read(dir.join("rd-speed.png")).unwrap()), (1400, 140 + 26 * 6));
    must_fail(&[&"bench", &"--quick", &"--plot", &dir.join("rd.jpg")], &dir, "PNG");
}

#[test]
fn bench_report_writes_a_page_whose_links_exist() {
    if font().is_none() {
        return;
    }
    let dir = common::temp_dir("cli-report");
    let md = dir.join("B.md");
    let table = ok(&hdrcodec(&[&"bench", &"--quick", &"--filter", &"exr:b44-half,jxr:q50,jxr:q90", &"--report", &md]));
    let page = std::fs::read_to_string(&md).unwrap();
    for section in [
        "# hdrcodec benchmarks",
        "## How to regenerate",
        "## Machine and build",
        "## Peer tools",
        "## Images",
        "## Rate and distortion",
        "## Speed",
        "## Table",
        "## Bytes at equal quality",
        "## Per image",
    ] {
        assert!(page.lines().any(|l| l == section), "no '{section}' in\n{page}");
    }
    // The command that regenerates it, every peer tool (a version or "not installed"), the
    // machine, and the table as the bench printed it.
    assert!(page.contains("    hdrcodec bench --quick --filter exr:b44-half,jxr:q50,jxr:q90 --report "), "{page}");
    for tool in ["JxrEncApp", "JxrDecApp", "libultrahdr", "cjxl", "avifenc", "oiiotool"] {
        assert!(page.lines().any(|l| l.starts_with(&format!("| {tool} | "))), "no line for {tool}");
    }
    assert!(page.contains("| CPU | ") && page.contains("| OS | ") && page.contains("| hdrcodec | 0.1.0"), "{page}");
    let first_row = table.lines().find(|l| l.starts_with("exr:b44-half")).expect("the table's row");
    assert!(page.contains(first_row), "the page lacks the table's row {first_row:?}");
    assert!(page.contains("| odd-257x129 | 257x129 | 0.03 |"), "{page}");
    // Every image or link of the page is a file beside it.
    let links: Vec<&str> = page.split("](").skip(1).filter_map(|rest| rest.split(')').next()).collect();
    assert_eq!(links, ["B-rd.png", "B-rd-speed.png"]);
    for l in links {
        png_size(&std::fs::read(dir.join(l)).unwrap());
    }
    must_fail(&[&"bench", &"--quick", &"--report", &dir.join("B.txt")], &dir, "Markdown");
}

/// Writes `pixels` (linear BT.2020, 1.0 = 100 cd/m², `width` per row) as a float EXR.
fn write_bt2020_exr(path: &Path, width: u32, pixels: &[[f32; 3]]) {
    use hdrcodec::core::{Channels, ColorInfo, ColorPrimaries, EncodeSettings, HdrImage};
    let color = ColorInfo { primaries: ColorPrimaries::Bt2020, ..ColorInfo::default() };
    let samples = pixels.iter().flatten().copied().collect();
    let image = HdrImage::new(width, pixels.len() as u32 / width, Channels::Rgb, samples, color).unwrap();
    let exr = hdrcodec::registry().by_name("exr").unwrap();
    std::fs::write(path, exr.encode(&image, &EncodeSettings::default().with_option("pixel", "float")).unwrap())
        .unwrap();
}

#[test]
fn compare_heatmap_colours_the_pixel_that_differs() {
    use hdrcodec::core::color::ictcp_to_rgb2020;
    if font().is_none() {
        return;
    }
    let dir = common::temp_dir("cli-heatmap");
    // colour-science's delta_E_ITP example: these two ICtCp colours are 1.42657228 apart.
    let px = |ictcp| ictcp_to_rgb2020(ictcp).map(|v| (v / 100.0) as f32);
    let a = px([0.488_546_807_2, -0.047_393_506_75, 0.074_754_013_02]);
    let b = px([0.489_920_323_1, -0.045_675_082_03, 0.073_613_417_75]);
    let (w, h) = (8u32, 6u32);
    let reference = vec![a; (w * h) as usize];
    let mut test = reference.clone();
    test[(2 * w + 5) as usize] = b;
    let (r, t) = (dir.join("r.exr"), dir.join("t.exr"));
    write_bt2020_exr(&r, w, &reference);
    write_bt2020_exr(&t, w, &test);
    let map = |reference: &Path, test: &Path, png: &Path| {
        ok(&hdrcodec(&[&"compare", &reference, &test, &"--heatmap", &png, &"--heatmap-max", &"5"]));
        let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        // The map at the image's size, the colour bar's column beside it, at least 280 high.
        assert_eq!((info.width, info.height), (w + 190, 280));
        let at = |x: u32, y: u32| {
            let i = (y * info.width + x) as usize * 3;
            [buf[i], buf[i + 1], buf[i + 2]]
        };
        (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| ((x, y), at(x, y))).collect::<Vec<_>>()
    };
    // Viridis (plotters' ViridisRGB): 0 is (68, 1, 84); 1.4266 of 5 is 0.2853, between its
    // second and third control points (70, 50, 127) and (54, 92, 141), 99.7 % of the way.
    for ((x, y), c) in map(&r, &t, &dir.join("diff.png")) {
        if (x, y) == (5, 2) {
            let want = [54, 92, 141];
            assert!(c.iter().zip(want).all(|(&g, w)| g.abs_diff(w) <= 1), "{c:?} at ({x}, {y})");
        } else {
            assert_eq!(c, [68, 1, 84], "at ({x}, {y})");
        }
    }
    assert!(map(&r, &r, &dir.join("same.png")).iter().all(|(_, c)| *c == [68, 1, 84]));
    must_fail(&[&"compare", &r, &t, &"--heatmap", &dir.join("d.jpg")], &dir, "PNG");
    let small = dir.join("small.exr");
    write_bt2020_exr(&small, 2, &[a; 4]);
    must_fail(&[&"compare", &r, &small, &"--heatmap", &dir.join("d2.png")], &dir, "sizes differ");
    must_fail(&[&"compare", &r, &t, &"--heatmap", &dir.join("d3.png"), &"--heatmap-max", &"0"], &dir, "positive");
    std::fs::remove_file(&small).unwrap();
}

#[test]
fn info_shows_hdr10_metadata_carried_by_the_container() {
    use hdrcodec::core::{ContentLightLevel, EncodeSettings, Hdr10Metadata, MasteringDisplay};
    let dir = common::temp_dir("cli-hdr10");
    let mut img = hdrcodec_cli::corpus::scene("odd-257x129").unwrap().image;
    let md = MasteringDisplay::bt2020(1000.0, 0.0001);
    img.color.hdr10 = Some(Hdr10Metadata {
        mastering_display: Some(md),
        content_light_level: Some(ContentLightLevel { max_cll: 987, max_fall: 123 }),
    });
    let codec = hdrcodec::registry().by_name("hdrc").unwrap();
    let file = dir.join("hdr10.hdrc");
    std::fs::write(&file, codec.encode(&img, &EncodeSettings::default()).unwrap()).unwrap();
    let v = json(&hdrcodec(&[&"info", &file, &"--json"]));
    assert_eq!(v["codec"], "hdrc");
    assert_eq!(v["hdr10"]["content_light_level"]["max_cll"], 987, "{v}");
    assert_eq!(v["hdr10"]["content_light_level"]["max_fall"], 123, "{v}");
    assert_eq!(v["hdr10"]["mastering_display"]["max_luminance"].as_f64(), Some(1000.0), "{v}");
    // BT.2020 red primary (ITU-R BT.2020-2 Table 3) as the mastering display's.
    assert_eq!(v["hdr10"]["mastering_display"]["primaries"][0][0].as_f64(), Some(0.708), "{v}");
    // The measured MaxCLL is max(R,G,B) in nits over the pixels (CTA-861.3), here the
    // generator's brightest red sample times 100 nits.
    let max_r = img.samples().chunks(3).map(|p| p[0].max(p[1]).max(p[2])).fold(0.0f32, f32::max);
    let measured = v["max_cll_measured_nits"].as_f64().unwrap();
    assert!((measured - f64::from(max_r) * 100.0).abs() < 1e-6 * measured, "{measured}");
    assert_eq!(v["format"], "raw-f32 payload, untiled", "{v}");
    let text = ok(&hdrcodec(&[&"info", &file]));
    assert!(text.contains("MaxCLL 987 MaxFALL 123"), "{text}");
    assert!(text.contains("mastering display"), "{text}");
}

#[test]
fn info_describes_a_frame_sequence_by_its_header_and_first_frame() {
    use hdrcodec::core::{EncodeSettings, ImageInfo, VideoCodec};
    let dir = common::temp_dir("cli-frames");
    let frames: Vec<_> = ["odd-257x129", "odd-257x129", "odd-257x129"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut img = hdrcodec_cli::corpus::scene(name).unwrap().image;
            img.samples_mut().iter_mut().for_each(|v| *v *= (i + 1) as f32);
            img
        })
        .collect();
    let f = &frames[0];
    let info = ImageInfo::new(f.width(), f.height(), f.channels(), f.color.clone()).with_frames(3);
    let file = dir.join("seq.hdrc");
    let out = std::fs::File::create(&file).unwrap();
    let video = hdrcodec::container::HdrcVideoCodec::default();
    let settings = EncodeSettings::default().with_option("tile", "100");
    let mut enc = video.begin_encode(&info, &settings, Box::new(std::io::BufWriter::new(out))).unwrap();
    for f in &frames {
        enc.push_frame(f).unwrap();
    }
    enc.finish().unwrap();
    let v = json(&hdrcodec(&[&"info", &file, &"--json"]));
    assert_eq!((v["frames"].as_u64(), v["width"].as_u64()), (Some(3), Some(257)), "{v}");
    assert_eq!(v["format"], "raw-f32 payload, 6 tiles of 100x100", "{v}");
    // The luminance figures are the first frame's.
    let max = hdrcodec::luminance(f).into_iter().fold(f64::MIN, f64::max);
    let got = v["luminance_nits"]["max"].as_f64().unwrap();
    assert!((got - max).abs() <= 1e-9 * max, "{got} vs {max}");
    let text = ok(&hdrcodec(&[&"info", &file]));
    assert!(text.contains("frames:        3"), "{text}");
}

#[test]
fn no_command_is_a_one_line_usage_error() {
    let dir = common::temp_dir("cli-usage");
    must_fail(&[], &dir, "command is missing");
    must_fail(&[&"corpus"], &dir, "command is missing");
    let help = ok(&hdrcodec(&[&"--help"]));
    for cmd in ["convert", "info", "compare", "bench", "corpus"] {
        assert!(help.contains(cmd), "{help}");
    }
}

#[test]
fn convert_to_a_format_without_primaries_keeps_the_samples() {
    let dir = common::temp_dir("cli-primaries");
    let src = corpus().join("bt2020-ramps.exr");
    let pfm = dir.join("r.pfm");
    // PFM records no primaries: the BT.2020 samples are stored as they are (no gamut conversion,
    // nothing clipped), and one note on stderr says so.
    let out = hdrcodec(&[&"convert", &src, &pfm]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("hdrcodec: note: pfm records no primaries: the BT.2020 samples are stored as they are"),
        "{err}"
    );
    let v = json(&hdrcodec(&[&"info", &pfm, &"--json"]));
    assert_eq!(v["primaries"], "unspecified");
    // Luminance needs primaries: BT.709 is assumed, and said; no chromaticities are made up.
    assert_eq!(v["primaries_assumed"], "BT.709", "{v}");
    assert!(v["chromaticities"].is_null(), "{v}");
    assert!(v["luminance_nits"]["max"].as_f64().unwrap() > 0.0, "{v}");
    let text = ok(&hdrcodec(&[&"info", &pfm]));
    assert!(text.contains("primaries:     unspecified (the file records none)"), "{text}");
    assert!(text.contains("luminance taken as BT.709: assumed, the file records no primaries"), "{text}");
    let v = json(&hdrcodec(&[&"info", &src, &"--json"]));
    assert!(v["primaries_assumed"].is_null(), "a file with primaries assumes none: {v}");
    assert!(!ok(&hdrcodec(&[&"info", &src])).contains("assumed"));
    // The same samples as the source: compare takes the reference's primaries for a test file
    // that has none, so the figures score the format (lossless f32 here), not a conversion.
    let src_img = decode(&src);
    let pfm_img = decode(&pfm);
    assert_eq!(pfm_img.samples(), src_img.samples());
    let v = json(&hdrcodec(&[&"compare", &src, &pfm, &"--json"]));
    assert_eq!(v["identical"], true, "{v}");
    assert_eq!((v["test_primaries_from_reference"].as_bool(), v["primaries_assumed"].is_null()), (Some(true), true));
    let text = ok(&hdrcodec(&[&"compare", &src, &pfm]));
    assert!(text.contains("the test file records none: taken as the reference's (BT.2020)"), "{text}");
    let v = json(&hdrcodec(&[&"compare", &pfm, &pfm, &"--json"]));
    assert_eq!(
        (v["test_primaries_from_reference"].as_bool(), &v["primaries_assumed"]),
        (Some(false), &"BT.709".into())
    );
    // Back to OpenEXR, labelled as what the user knows they are: the source exactly.
    let back = dir.join("back.exr");
    ok(&hdrcodec(&[&"convert", &pfm, &back, &"--opt", &"pixel=float", &"--opt", &"primaries=bt2020"]));
    let back_img = decode(&back);
    assert_eq!((back_img.samples(), back_img.color.primaries), (src_img.samples(), src_img.color.primaries));
    // Asked to convert, a format without primaries stores the converted samples unlabelled.
    let conv = dir.join("709.pfm");
    ok(&hdrcodec(&[&"convert", &src, &conv, &"--opt", &"primaries=bt709"]));
    let v = json(&hdrcodec(&[&"compare", &src, &conv, &"--json"]));
    assert!(v["identical"] == false && v["de_itp_p99"].as_f64().unwrap() > 5.0, "read as BT.2020 they are off: {v}");
    let as709 = hdrcodec::core::color::convert_primaries(&src_img, hdrcodec::core::ColorPrimaries::Bt709);
    assert_eq!(decode(&conv).samples(), as709.samples());
    // Unknown primaries are an error naming the known ones.
    must_fail(&[&"convert", &src, &dir.join("x.pfm"), &"--opt", &"primaries=bt999"], &dir, "unknown primaries");
}

#[test]
fn convert_renders_a_gain_map_jpeg_for_a_display_headroom() {
    let Some(corpus) = common::require(common::corpus_dir(), "the shared corpus") else { return };
    let input = corpus.join("jpeg/moonless_golf_1k.ultrahdr.jpg");
    let dir = common::temp_dir("cli-headroom");
    let codecs = json(&hdrcodec(&[&"codecs", &"--json"]));
    let ultrahdr = codecs["codecs"].as_array().unwrap().iter().find(|c| c["name"] == "ultrahdr").unwrap();
    assert_eq!(ultrahdr["decode_options"], serde_json::json!(["headroom"]));
    // The largest sample of each rendition: full HDR, a display with 2x headroom, an SDR one.
    let peak = |args: &[&str]| {
        let out = dir.join(format!("out{}.exr", args.len()));
        let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"convert", &input, &out];
        all.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        ok(&hdrcodec(&all));
        decode(&out).samples().iter().fold(0f32, |m, &v| m.max(v))
    };
    let full = peak(&[]);
    let two = peak(&["--opt", "headroom=2"]);
    let sdr = peak(&["--opt", "headroom=1", "--opt", "compression=zip"]);
    // The file's HDR capacity is 13.4 stops: full HDR goes far above 2x SDR white.
    assert!(full > 8.0, "full HDR peak {full}");
    // (SDR white + the file's offset of 1/64) x 2 - 1/64 = 2.015625 at most.
    assert!(two > 1.5 && two <= 2.0157, "peak {two} for a display of headroom 2");
    assert!(sdr <= 1.0 * 1.001, "peak {sdr} for an SDR display");
    must_fail(&[&"convert", &input, &dir.join("bad.exr"), &"--opt", &"headroom=0.5"], &dir, "at least 1");
    must_fail(&[&"convert", &input, &dir.join("bad.exr"), &"--opt", &"headroom=x"], &dir, "headroom=x");
}

#[test]
fn jpeg_hdr_is_written_by_name_and_read_back_as_a_jpg() {
    let dir = common::temp_dir("cli-jpeg-hdr");
    let src = corpus().join("specular.exr");
    let jpg = dir.join("out.jpg");
    let back = dir.join("back.exr");
    ok(&hdrcodec(&[
        &"convert",
        &src,
        &jpg,
        &"--codec",
        &"jpeg-hdr",
        &"--quality",
        &"85",
        &"--opt",
        &"correction=post",
    ]));
    assert!(std::fs::read(&jpg).unwrap().windows(7).any(|w| w == b"HDR_RI "));
    // Reading dispatches .jpg to one codec (ultrahdr, which decodes JPEG-HDR too).
    let v = json(&hdrcodec(&[&"info", &jpg, &"--json"]));
    assert_eq!(v["codec"], "ultrahdr", "{v}");
    ok(&hdrcodec(&[&"convert", &jpg, &back]));
    let q = json(&hdrcodec(&[&"compare", &src, &back, &"--json"]));
    assert!(q["pu21_psnr"].as_f64().unwrap() > 35.0, "{q}");
    // Writing a .jpg without --codec stays the gain map; options of the other codec are refused.
    let plain = dir.join("plain.jpg");
    ok(&hdrcodec(&[&"convert", &src, &plain]));
    assert!(!std::fs::read(&plain).unwrap().windows(7).any(|w| w == b"HDR_RI "));
    let listed = ok(&hdrcodec(&[&"codecs"]));
    assert!(listed.lines().any(|l| l.starts_with("jpeg-hdr")), "{listed}");
    must_fail(
        &[&"convert", &src, &dir.join("x.jpg"), &"--codec", &"jpeg-hdr", &"--opt", &"map_scale=2"],
        &dir,
        "map_scale",
    );
}

#[test]
fn a_closed_stdout_is_not_an_internal_error() {
    // `hdrcodec codecs | head -0`: the reader is gone before anything is written.
    let mut child = Command::new(env!("CARGO_BIN_EXE_hdrcodec"))
        .arg("codecs")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run hdrcodec");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for hdrcodec");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("internal error"), "{stderr}");
    assert!(matches!(out.status.code(), Some(0) | Some(141)), "{:?}", out.status);
}

#[test]
fn video_encode_info_decode_round_trip() {
    let dir = common::temp_dir("cli-video");
    let frame = corpus().join("odd-257x129.exr");
    let ivf = dir.join("clip.ivf");
    ok(&hdrcodec(&[&"video", &"encode", &frame, &frame, &frame, &ivf, &"--quality", &"80", &"--speed", &"10"]));
    // info reads the stream's own headers: 3 frames, HDR10 signalling, MaxCLL/MaxFALL of the
    // frames (the same frame three times) as hdrcodec-video measures them.
    let v = json(&hdrcodec(&[&"info", &ivf, &"--json"]));
    assert_eq!((v["codec"].as_str(), v["frames"].as_u64()), (Some("av1"), Some(3)), "{v}");
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(257), Some(129)), "{v}");
    assert_eq!(v["color_description"], serde_json::json!([9, 16, 9]), "{v}");
    let cll = hdrcodec_video::hdr10::content_light_level([&decode(&frame)], hdrcodec_video::hdr10::Transfer::Pq);
    assert_eq!(v["hdr10"]["content_light_level"]["max_cll"].as_u64(), Some(cll.max_cll.into()), "{v}");
    assert_eq!(v["hdr10"]["content_light_level"]["max_fall"].as_u64(), Some(cll.max_fall.into()), "{v}");
    let frames = dir.join("frames");
    ok(&hdrcodec(&[&"video", &"decode", &ivf, &frames]));
    assert_eq!(names(&frames), ["frame_00000.exr", "frame_00001.exr", "frame_00002.exr"]);
    let c = json(&hdrcodec(&[&"compare", &frame, &frames.join("frame_00002.exr"), &"--json"]));
    let psnr = c["pu21_psnr"].as_f64().unwrap();
    eprintln!("257x129 corpus frame, quality 80, speed 10: PU21-PSNR {psnr:.2} dB");
    assert!(psnr > 35.0, "{c}");

    // The same frames in MP4: the container follows the extension, and info reads it alike.
    let mp4 = dir.join("clip.mp4");
    ok(&hdrcodec(&[&"video", &"encode", &frame, &frame, &frame, &mp4, &"--quality", &"80", &"--speed", &"10"]));
    let m = json(&hdrcodec(&[&"info", &mp4, &"--json"]));
    assert_eq!((m["container"].as_str(), m["frames"].as_u64()), (Some("mp4"), Some(3)), "{m}");
    assert_eq!(m["color_description"], v["color_description"], "{m}");
    assert_eq!(m["hdr10"]["content_light_level"], v["hdr10"]["content_light_level"], "{m}");
    // The mdcv box counts in 0.00002 (chromaticity) and 0.0001 cd/m², AV1's metadata OBU in
    // 2^-16 and 2^-14 (minimum) steps: the same display within the coarser of the two.
    let (box_md, obu_md) = (&m["hdr10"]["mastering_display"], &v["hdr10"]["mastering_display"]);
    let numbers = |j: &serde_json::Value| -> Vec<f64> {
        let p = &j["primaries"];
        [&p[0][0], &p[0][1], &p[1][0], &p[1][1], &p[2][0], &p[2][1], &j["white"][0], &j["white"][1]]
            .into_iter()
            .chain([&j["max_luminance"], &j["min_luminance"]])
            .map(|n| n.as_f64().unwrap())
            .collect()
    };
    for (a, b) in numbers(box_md).into_iter().zip(numbers(obu_md)) {
        assert!((a - b).abs() <= 1e-4, "mdcv {box_md} against the bitstream's {obu_md}");
    }

    // Bad input: one stderr line, no output file.
    must_fail(&[&"video", &"encode", &frame, &dir.join("clip.avi")], &dir, ".ivf, .mp4, .mkv or .webm");
    must_fail(&[&"video", &"encode", &frame, &dir.join("x.ivf"), &"--transfer", &"log"], &dir, "pq, hlg or mantiuk");
    let other = corpus().join("sun-sky.exr");
    must_fail(&[&"video", &"encode", &frame, &other, &dir.join("y.ivf")], &dir, "512x256");
    let cut = dir.join("cut.ivf");
    let bytes = std::fs::read(&ivf).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() - 20]).unwrap();
    let empty = dir.join("none");
    must_fail(&[&"video", &"decode", &cut, &empty], &dir, "truncated");
    must_fail(&[&"info", &cut], &dir, "truncated");
}

#[test]
fn video_mantiuk_encode_info_decode_round_trip() {
    let dir = common::temp_dir("cli-video-mantiuk");
    let frame = corpus().join("odd-257x129.exr");
    let ivf = dir.join("lpuv.ivf");
    ok(&hdrcodec(&[
        &"video",
        &"encode",
        &frame,
        &frame,
        &ivf,
        &"--transfer",
        &"mantiuk",
        &"--quality",
        &"96",
        &"--speed",
        &"10",
    ]));
    let v = json(&hdrcodec(&[&"info", &ivf, &"--json"]));
    assert_eq!((v["profile"].as_u64(), v["bit_depth"].as_u64()), (Some(2), Some(12)), "{v}");
    assert_eq!((v["subsampling"].as_str(), v["color_description"].is_null()), (Some("4:4:4"), true), "{v}");
    assert_eq!((v["lpuv"]["bits"].as_u64(), v["lpuv"]["max_nits"].as_f64()), (Some(11), Some(1e8)), "{v}");
    assert_eq!(v["t35_messages"].as_u64(), Some(2), "{v}");
    let frames = dir.join("frames");
    ok(&hdrcodec(&[&"video", &"decode", &ivf, &frames]));
    assert_eq!(names(&frames), ["frame_00000.exr", "frame_00001.exr"]);
    let c = json(&hdrcodec(&[&"compare", &frame, &frames.join("frame_00001.exr"), &"--json"]));
    let psnr = c["pu21_psnr"].as_f64().unwrap();
    eprintln!("257x129 corpus frame, mantiuk, quality 96, speed 10: PU21-PSNR {psnr:.2} dB");
    assert!(psnr > 35.0, "{c}");
    must_fail(&[&"video", &"encode", &frame, &dir.join("z.ivf"), &"--chroma", &"422"], &dir, "420 or 444");
    // --bits 10 --chroma 420: a Main-profile stream of 10-bit ψ codes, decoded alike.
    let main = dir.join("main10.ivf");
    ok(&hdrcodec(&[
        &"video",
        &"encode",
        &frame,
        &main,
        &"--transfer",
        &"mantiuk",
        &"--bits",
        &"10",
        &"--chroma",
        &"420",
        &"--speed",
        &"10",
    ]));
    let v = json(&hdrcodec(&[&"info", &main, &"--json"]));
    assert_eq!((v["profile"].as_u64(), v["bit_depth"].as_u64()), (Some(0), Some(10)), "{v}");
    assert_eq!((v["lpuv"]["bits"].as_u64(), v["subsampling"].as_str()), (Some(10), Some("4:2:0")), "{v}");
    let frames = dir.join("frames10");
    ok(&hdrcodec(&[&"video", &"decode", &main, &frames]));
    let c = json(&hdrcodec(&[&"compare", &frame, &frames.join("frame_00000.exr"), &"--json"]));
    assert!(c["pu21_psnr"].as_f64().unwrap() > 30.0, "{c}");
    must_fail(&[&"video", &"encode", &frame, &dir.join("b.ivf"), &"--bits", &"10"], &dir, "bits=");
}

/// Writes `frames` of the generated moving light (64x48, 4000 cd/m²) as float EXR files
/// `dir/NAME(t)`; returns the frames.
fn write_light_frames(dir: &Path, frames: u32, name: impl Fn(u32) -> String) -> Vec<hdrcodec::core::HdrImage> {
    let exr = hdrcodec::registry().by_name("exr").unwrap();
    std::fs::create_dir_all(dir).unwrap();
    (0..frames)
        .map(|t| {
            let f = hdrcodec_video::sequences::moving_light_frame(64, 48, 4000.0, 6.0, t, frames);
            hdrcodec::encode_file(exr.as_ref(), &f, &Default::default(), &dir.join(name(t))).unwrap();
            f
        })
        .collect()
}

/// The frames as a 10-bit 4:2:0 limited-range PQ Y4M file (hdrcodec-video's planes).
fn y4m_of(frames: &[hdrcodec::core::HdrImage]) -> Vec<u8> {
    use hdrcodec_video::hdr10::{frame_to_yuv, Range, Subsampling, Transfer};
    let (w, h) = (frames[0].width(), frames[0].height());
    let mut out = format!("YUV4MPEG2 W{w} H{h} F25:1 Ip A1:1 C420p10 XYSCSS=420P10\n").into_bytes();
    for f in frames {
        let (yuv, _) = frame_to_yuv(f, Transfer::Pq, Range::Limited, Subsampling::Yuv420);
        out.extend_from_slice(b"FRAME\n");
        for plane in [&yuv.y, &yuv.cb, &yuv.cr] {
            out.extend(plane.iter().flat_map(|v| v.to_le_bytes()));
        }
    }
    out
}

#[test]
fn video_encode_reads_a_pattern_a_directory_and_y4m() {
    let dir = common::temp_dir("cli-video-inputs");
    let fast = [&"--speed" as &dyn AsRef<std::ffi::OsStr>, &"10", &"--quality", &"85"];
    let run = |args: &[&dyn AsRef<std::ffi::OsStr>]| {
        let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&"video", &"encode"];
        all.extend_from_slice(args);
        all.extend_from_slice(&fast);
        hdrcodec(&all)
    };
    // A pattern: f00001..f00003 are taken, f00005 (after the gap) and other names are not.
    let seq = dir.join("seq");
    let frames = write_light_frames(&seq, 3, |t| format!("f{:05}.exr", t + 1));
    write_light_frames(&seq, 1, |_| "f00005.exr".into());
    write_light_frames(&seq, 1, |_| "f1.exr".into());
    let ivf = dir.join("pattern.ivf");
    ok(&run(&[&seq.join("f%05d.exr"), &ivf]));
    assert_eq!(json(&hdrcodec(&[&"info", &ivf, &"--json"]))["frames"].as_u64(), Some(3));
    // f%d takes f1 alone (f2 does not exist); no match at all is an error.
    let ivf = dir.join("pattern-d.ivf");
    ok(&run(&[&seq.join("f%d.exr"), &ivf]));
    assert_eq!(json(&hdrcodec(&[&"info", &ivf, &"--json"]))["frames"].as_u64(), Some(1));
    must_fail(&[&"video", &"encode", &seq.join("g%03d.exr"), &dir.join("none.ivf")], &dir, "no file matches");
    must_fail(&[&"video", &"encode", &seq.join("f%5d.exr"), &dir.join("none.ivf")], &dir, "%0Nd");

    // A directory: its image files in name order (the text file is not a frame).
    let in_dir = dir.join("in-dir");
    write_light_frames(&in_dir, 2, |t| format!("frame-{t}.exr"));
    std::fs::write(in_dir.join("README.txt"), "not a frame").unwrap();
    let ivf = dir.join("directory.ivf");
    ok(&run(&[&in_dir, &ivf]));
    assert_eq!(json(&hdrcodec(&[&"info", &ivf, &"--json"]))["frames"].as_u64(), Some(2));

    // Y4M, 10-bit 4:2:0 PQ: streamed, encoded, decoded back close to the source frames.
    let y4m = dir.join("light.y4m");
    std::fs::write(&y4m, y4m_of(&frames)).unwrap();
    let ivf = dir.join("y4m.ivf");
    let v = json(&run(&[&y4m, &ivf, &"--json"]));
    assert_eq!(v["frames"].as_u64(), Some(3), "{v}");
    assert_eq!(v["bytes"].as_u64(), Some(std::fs::metadata(&ivf).unwrap().len()), "{v}");
    // MaxCLL/MaxFALL of the frames as the Y4M reader gives them (PQ, limited range, 4:2:0
    // taken as left-sited: 4000 cd/m² at the disc's centre, a little more at its edges).
    let y4m_bytes = std::fs::read(&y4m).unwrap();
    let mut reader = hdrcodec_video::y4m::Y4mReader::new(&y4m_bytes[..], &Limits::default()).unwrap();
    let mut read = Vec::new();
    while let Some(yuv) = reader.next_frame().unwrap() {
        read.push(reader.frame_to_image(&yuv, hdrcodec_video::hdr10::Transfer::Pq, 100.0).unwrap());
    }
    let cll = hdrcodec_video::hdr10::content_light_level(&read, hdrcodec_video::hdr10::Transfer::Pq);
    assert_eq!(v["content_light"], serde_json::json!({"max_cll": cll.max_cll, "max_fall": cll.max_fall}), "{v}");
    assert!((4000..4200).contains(&cll.max_cll), "{cll:?}");
    let out = dir.join("y4m-frames");
    let d = json(&hdrcodec(&[&"video", &"decode", &ivf, &out, &"--json"]));
    assert_eq!((d["frames"].as_u64(), d["codec"].as_str()), (Some(3), Some("av1")), "{d}");
    let psnr = hdrcodec::core::metrics::pu21_psnr(&frames[2], &decode(&out.join("frame_00002.exr"))).unwrap();
    eprintln!("moving light through Y4M (10-bit 4:2:0 PQ), quality 85, speed 10: PU21-PSNR {psnr:.2} dB");
    assert!(psnr > 38.0, "{psnr}");
    // HLG planes read as HLG say a different light than as PQ: the option reaches the reader.
    let hlg = json(&run(&[&y4m, &dir.join("as-hlg.ivf"), &"--json", &"--input-transfer", &"hlg"]));
    assert_ne!(hlg["content_light"], v["content_light"], "{hlg}");

    // Bad Y4M: one line, no output file.
    let bytes = std::fs::read(&y4m).unwrap();
    let cut = dir.join("cut.y4m");
    std::fs::write(&cut, &bytes[..bytes.len() - 100]).unwrap();
    must_fail(&[&"video", &"encode", &cut, &dir.join("cut.ivf")], &dir, "ends inside");
    let bad = dir.join("bad.y4m");
    std::fs::write(&bad, b"YUV4MPEG2 W64 H48 C422p10\nFRAME\n").unwrap();
    must_fail(&[&"video", &"encode", &bad, &dir.join("bad.ivf")], &dir, "C422p10");
    must_fail(&[&"video", &"encode", &y4m, &dir.join("x.ivf"), &"--input-transfer", &"srgb"], &dir, "pq or hlg");
    must_fail(&[&"video", &"decode", &y4m, &dir.join("out")], &dir, "video is read from");
}

#[test]
fn video_encode_writes_an_sdr_rendition_beside_the_hdr_stream() {
    let dir = common::temp_dir("cli-video-sdr");
    let seq = dir.join("seq");
    write_light_frames(&seq, 2, |t| format!("f{t}.exr"));
    let (hdr, sdr) = (dir.join("hdr.mp4"), dir.join("sdr.ivf"));
    let v = json(&hdrcodec(&[
        &"video",
        &"encode",
        &seq,
        &hdr,
        &"--sdr",
        &sdr,
        &"--sdr-peak",
        &"200",
        &"--speed",
        &"10",
        &"--json",
    ]));
    assert_eq!(v["sdr_output"].as_str(), Some(sdr.to_str().unwrap()), "{v}");
    let h = json(&hdrcodec(&[&"info", &hdr, &"--json"]));
    assert_eq!(h["color_description"], serde_json::json!([9, 16, 9]), "{h}");
    let s = json(&hdrcodec(&[&"info", &sdr, &"--json"]));
    assert_eq!((s["frames"].as_u64(), s["bit_depth"].as_u64()), (Some(2), Some(8)), "{s}");
    assert_eq!(s["color_description"], serde_json::json!([1, 13, 1]), "{s}");
    assert!(s["hdr10"].is_null(), "an SDR stream carries no HDR10 metadata: {s}");
    let out = dir.join("sdr-frames");
    ok(&hdrcodec(&[&"video", &"decode", &sdr, &out]));
    let frame = decode(&out.join("frame_00001.exr"));
    assert_eq!(frame.color.primaries, hdrcodec::core::ColorPrimaries::Bt709);
    assert!(frame.samples().iter().all(|v| (0.0..=1.0).contains(v)), "display-linear, 1.0 = the peak");
    // Matroska and WebM by extension (FFmpeg checks them in tests/video_ffmpeg.rs).
    for name in ["clip.mkv", "clip.webm"] {
        ok(&hdrcodec(&[&"video", &"encode", &seq, &dir.join(name), &"--speed", &"10"]));
        let bytes = std::fs::read(dir.join(name)).unwrap();
        assert_eq!(bytes[..4], [0x1A, 0x45, 0xDF, 0xA3], "{name}: the EBML header");
        let doc_type: &[u8] = if name.ends_with("webm") { b"webm" } else { b"matroska" };
        assert!(bytes.windows(doc_type.len()).any(|w| w == doc_type), "{name}");
        // Read back: `info` (the stream and the track's Colour element) and `video decode`.
        let i = json(&hdrcodec(&[&"info", &dir.join(name), &"--json"]));
        let container = if name.ends_with("webm") { "WebM" } else { "Matroska" };
        assert_eq!((i["container"].as_str(), i["frames"].as_u64()), (Some(container), Some(2)), "{i}");
        assert_eq!(i["color_description"], serde_json::json!([9, 16, 9]), "{i}");
        assert_eq!(
            (i["matroska_colour"]["transfer"].as_u64(), i["matroska_colour"]["range"].as_u64()),
            (Some(16), Some(1))
        );
        assert_eq!(
            i["hdr10"]["content_light_level"], v["content_light"],
            "{name}: the content light of the same frames"
        );
        let out = dir.join(format!("{name}-frames"));
        ok(&hdrcodec(&[&"video", &"decode", &dir.join(name), &out]));
        assert!(out.join("frame_00001.exr").exists() && !out.join("frame_00002.exr").exists());
    }
    // Bad SDR options: one line, neither file written.
    let (hdr2, sdr2) = (dir.join("hdr2.ivf"), dir.join("sdr2.ivf"));
    must_fail(&[&"video", &"encode", &seq, &hdr2, &"--sdr", &dir.join("sdr.avi")], &dir, ".mkv or .webm");
    must_fail(&[&"video", &"encode", &seq, &hdr2, &"--sdr", &sdr2, &"--sdr-peak", &"5"], &dir, "50 to 1000");
}

#[test]
fn video_progress_bars_are_drawn_on_a_terminal_only() {
    use terminal::run_on_terminal;
    let dir = common::temp_dir("cli-video-progress");
    let seq = dir.join("seq");
    write_light_frames(&seq, 3, |t| format!("f{t:03}.exr"));
    let ivf = dir.join("clip.ivf");
    let (screen, stdout) = run_on_terminal(&[&"video", &"encode", &seq, &ivf, &"--speed", &"10"]);
    assert!((1..=3).any(|k| screen.contains(&format!(" {k}/3 "))), "no count of 3 frames: {screen:?}");
    assert_eq!(stdout, "");
    let (screen, _) = run_on_terminal(&[&"video", &"decode", &ivf, &dir.join("out")]);
    assert!((1..=3).any(|k| screen.contains(&format!(" {k}/3 "))), "no count of 3 frames: {screen:?}");
    // --json: nothing on the terminal, one JSON object on stdout.
    let (screen, stdout) = run_on_terminal(&[&"video", &"encode", &seq, &ivf, &"--speed", &"10", &"--json"]);
    assert_eq!(screen, "", "--json drew on the terminal");
    assert_eq!(serde_json::from_str::<Value>(&stdout).unwrap()["frames"].as_u64(), Some(3));
    let (screen, _) = run_on_terminal(&[&"video", &"decode", &ivf, &dir.join("out2"), &"--json"]);
    assert_eq!(screen, "", "--json drew on the terminal");
    // stderr a pipe: nothing of the bar.
    let o = hdrcodec(&[&"video", &"encode", &seq, &ivf, &"--speed", &"10"]);
    assert!(o.status.success());
    assert_eq!(String::from_utf8_lossy(&o.stderr), "", "stderr is not a terminal");
}
