#!/usr/bin/env bash
# The whole test suite, from a fresh machine: installs the reference tools (Debian packages and
# the Python venv, see scripts/setup-reference-tools.sh), then formatting, lints, every test
# (unit, cross-crate, validation against the references) and a short run of every fuzz target.
# .ci/run calls exactly this.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*"; }

step "reference tools"
bash scripts/setup-reference-tools.sh

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy (all targets, warnings are errors)"
cargo clippy --workspace --all-targets -- -D warnings

step "cargo test (workspace)"
cargo test --workspace

step "fuzz smoke run"
bash scripts/fuzz-smoke.sh
