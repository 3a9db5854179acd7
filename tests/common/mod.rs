//! Helpers shared by the cross-crate tests: where the shared corpus and the reference tools
//! are, and the rule for when they are missing (a failure under `CI=true`, a printed skip
//! elsewhere). Each test file does `mod common;` and uses what it needs.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The workspace root (where the root Cargo.toml is).
pub fn workspace_root() -> PathBuf {
    // The test packages (tests/, cli/) sit one level below the workspace root.
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).parent().expect("a package directory has a parent").to_path_buf()
}

/// True when running in CI, where a missing reference or corpus is a failure.
pub fn in_ci() -> bool {
    std::env::var("CI").map(|v| v == "true" || v == "1").unwrap_or(false)
}

/// Returns `Some(x)`; or, when `x` is `None`: panics under CI, else prints why the test is
/// skipped and returns `None`. Use as `let Some(py) = require(python(), "the venv") else { return };`.
pub fn require<T>(x: Option<T>, what: &str) -> Option<T> {
    if x.is_none() {
        if in_ci() {
            panic!("{what} is missing; CI must have it (run scripts/setup-reference-tools.sh)");
        }
        eprintln!("SKIPPED: {what} is missing (run scripts/setup-reference-tools.sh); not a failure outside CI");
    }
    x
}

/// The shared corpus of real HDR images: `$HDRCODEC_CORPUS`, else `../shared/corpus`.
pub fn corpus_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("HDRCODEC_CORPUS") {
        Some(d) => PathBuf::from(d),
        None => workspace_root().join("../shared/corpus"),
    };
    dir.join("MANIFEST.tsv").is_file().then_some(dir)
}

/// All corpus files under `sub` (e.g. "exr") with extension `ext`, sorted.
pub fn corpus_files(sub: &str, ext: &str) -> Option<Vec<PathBuf>> {
    let dir = require(corpus_dir(), "the shared HDR corpus (../shared/corpus or $HDRCODEC_CORPUS)")?;
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case(ext)))
        .collect();
    v.sort();
    Some(v)
}

/// The Python of the project's reference venv (`$HDRCODEC_VENV` or `.venv`), if set up.
pub fn python() -> Option<PathBuf> {
    let venv = std::env::var_os("HDRCODEC_VENV").map(PathBuf::from).unwrap_or_else(|| workspace_root().join(".venv"));
    let py = venv.join("bin/python");
    py.is_file().then_some(py)
}

/// A command on PATH, if present.
pub fn tool(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(name)).find(|p| p.is_file())
}

/// Runs a command and panics with its stderr if it fails.
pub fn run_ok(cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs a Python script in the reference venv with `args`; panics if it fails.
pub fn run_python(py: &Path, script: &str, args: &[&std::ffi::OsStr]) -> Output {
    let mut cmd = Command::new(py);
    cmd.arg("-c").arg(script).args(args);
    run_ok(&mut cmd)
}

/// A fresh temporary directory under the target dir, removed and recreated.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir
}

/// Reads a little-endian f32 raw file (as written by the Python helpers with `tofile`).
pub fn read_f32_raw(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).expect("read raw floats");
    bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
}

/// A small deterministic generator (xorshift64*), so that randomised tests reproduce.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// A number in `0..n`.
    pub fn below(&mut self, n: u32) -> u32 {
        (self.next() >> 33) as u32 % n
    }
    /// 16 random bytes (one BC-compressed block).
    pub fn block(&mut self) -> [u8; 16] {
        let mut b = [0u8; 16];
        b[..8].copy_from_slice(&self.next().to_le_bytes());
        b[8..].copy_from_slice(&self.next().to_le_bytes());
        b
    }
}
