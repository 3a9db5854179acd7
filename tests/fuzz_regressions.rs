//! Replays the fuzz regressions: every file under `fuzz/regressions/<target>/` goes through the
//! same function as the fuzz target `<target>` (`fuzz/entry_points.rs`, shared with the
//! targets), which must return without panicking (the decoders' results may be `Ok` or `Err`).
//! A crash the fuzzer finds is copied there by `scripts/fuzz-smoke.sh` (see
//! `fuzz/regressions/README.md`), so that once fixed it stays fixed in every `cargo test`.
//!
//! Fuzzing builds of the container skip its CRC check (`--cfg fuzzing`) and this test's build
//! does not, so container inputs are replayed twice: as they are, and with the CRC of every
//! chunk recomputed, so that a mutated chunk reaches the parser the fuzzer reached.

#[path = "../fuzz/entry_points.rs"]
mod entry_points;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

fn regressions_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions")
}

/// The `[[bin]]` names of `fuzz/Cargo.toml`: the fuzz targets.
fn fuzz_targets() -> Vec<String> {
    let manifest = std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/Cargo.toml"))
        .expect("fuzz/Cargo.toml");
    let mut names = Vec::new();
    let mut in_bin = false;
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            in_bin = line == "[[bin]]";
        } else if let Some(v) = line.strip_prefix("name").map(str::trim).and_then(|l| l.strip_prefix('=')) {
            if in_bin {
                names.push(v.trim().trim_matches('"').to_string());
            }
        }
    }
    names.sort();
    names
}

/// The inputs of one target's directory (every file but the README), sorted.
fn inputs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("README")))
        .collect();
    v.sort();
    v
}

/// The same `.hdrc` bytes with the CRC of every chunk recomputed, as far as the chunk lengths
/// lead (a length past the end stops the walk).
fn with_crcs_fixed(data: &[u8]) -> Vec<u8> {
    let mut out = data.to_vec();
    let mut pos = hdrcodec_container::SIGNATURE.len();
    while pos + 12 <= out.len() {
        let len = u32::from_be_bytes(out[pos..pos + 4].try_into().expect("4 bytes")) as usize;
        let Some(end) = pos.checked_add(12).and_then(|e| e.checked_add(len)).filter(|&e| e <= out.len()) else {
            break;
        };
        let crc = hdrcodec_container::crc32c(&out[pos + 4..pos + 8 + len]);
        out[pos + 8 + len..end].copy_from_slice(&crc.to_be_bytes());
        pos = end;
    }
    out
}

#[test]
fn every_fuzz_target_has_a_regression_directory() {
    let dirs: Vec<String> = {
        let mut v: Vec<String> = std::fs::read_dir(regressions_dir())
            .expect("fuzz/regressions")
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_dir())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(dirs, fuzz_targets(), "one directory per target of fuzz/Cargo.toml");
    let known: Vec<&str> = entry_points::TARGETS.iter().map(|(n, _)| *n).collect();
    assert_eq!(known, fuzz_targets(), "fuzz/entry_points.rs has one function per target");
}

#[test]
fn fuzz_regressions_replay_without_panics() {
    let mut failures = Vec::new();
    let mut replayed = 0;
    for (target, run) in entry_points::TARGETS {
        let dir = regressions_dir().join(target);
        let files = inputs(&dir);
        assert!(!files.is_empty(), "{} holds no input", dir.display());
        for file in files {
            let data = std::fs::read(&file).unwrap();
            let mut variants = vec![data.clone()];
            if target == "container" {
                variants.push(with_crcs_fixed(&data));
            }
            for (i, input) in variants.iter().enumerate() {
                replayed += 1;
                if let Err(panic) = catch_unwind(AssertUnwindSafe(|| run(input))) {
                    let msg = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_default();
                    let how = if i == 0 { "" } else { " (CRCs fixed)" };
                    failures.push(format!("{target}: {}{how}: {msg}", file.display()));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{} of {replayed} regression inputs panic:\n{}", failures.len(), failures.join("\n"));
}
