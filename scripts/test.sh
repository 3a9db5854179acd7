#!/usr/bin/env bash
# The whole test suite, from a fresh machine: installs the reference tools (Debian packages and
# the Python venv, see scripts/setup-reference-tools.sh), then formatting, lints, every test
# (unit, cross-crate, validation against the references) and a short run of every fuzz target.
# .ci/run calls exactly this.
set -euo pipefail
cd "$(dirname "$0")/.."

# Line tables only (backtraces keep file:line), not full debug info: the suite links dozens
# of test binaries against rav1e, dav1d and the codecs, and full DWARF makes every link slower.
export CARGO_PROFILE_DEV_DEBUG="${CARGO_PROFILE_DEV_DEBUG:-line-tables-only}"

step() { printf '\n== %s\n' "$*"; }

# Which SIMD kernels this machine's tests exercise: every level's twin tests must run under
# CI=true, except AVX-512's, which print SKIPPED on a CPU without it (hdrcodec_core::cpu).
step "CPU"
grep -m1 'model name' /proc/cpuinfo || true
for f in avx2 bmi2 avx512f; do
  if grep -qw "$f" /proc/cpuinfo; then echo "$f: yes"; else echo "$f: no"; fi
done

step "reference tools"
bash scripts/setup-reference-tools.sh

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy (all targets, warnings are errors)"
cargo clippy --workspace --all-targets -- -D warnings

# Every public item documented (`missing_docs` is denied workspace-wide), and no broken doc
# link (issue 16). The CLI's library is internal, and its binary's docs would collide with the
# facade's (both `hdrcodec`, cargo#6313).
step "cargo doc (warnings are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --exclude hdrcodec-cli --quiet

# A program that embeds the codecs must not pull the tool's dependencies (issue 9).
step "the hdrcodec library pulls no CLI or peer crates"
if cargo tree -p hdrcodec -e normal,build,dev --prefix none | sed 's/ .*//' | sort -u \
  | grep -E -x 'clap|indicatif|plotters|png|serde|serde_json|criterion|intel_tex_2|ispc_rt'; then
  echo "cargo tree -p hdrcodec lists the crates above" >&2
  exit 1
fi

step "cargo test (workspace)"
cargo test --workspace

# The same build (`--workspace` keeps the features of the step above, so nothing is rebuilt):
# every crate's unit tests, the codec crates' own test files and the cross-crate checks that
# drive the RGBE and BC6H kernels, on the portable code. A codec crate's new test file goes here.
step "cargo test on the portable path (HDRCODEC_CPU=scalar)"
HDRCODEC_CPU=scalar cargo test --workspace --lib \
    --test robustness --test portable_path --test bad_input --test mips \
    --test damage --test limits --test roundtrip --test seek --test spec \
    --test rgbe_oiio --test bc6h_decode --test bc6h_encode --test encode_pinned

# Peak resident memory of info and convert for every format, on a 3 MP generated image: each
# must stay within decoded image + input file + 64 MB (issue 10; the README has the 13 MP table).
step "peak memory (scripts/memory-bench.sh --check)"
cargo build --quiet -p hdrcodec-cli --bin hdrcodec
HDRCODEC_BIN=target/debug/hdrcodec bash scripts/memory-bench.sh --check 2048 1536
# A batch within --memory: 3 images of 3 MP to RGBE, unbounded, two and one in flight (issue 16;
# the README has the 12 MP table).
step "batch peak memory (scripts/batch-memory-bench.sh --check)"
HDRCODEC_BIN=target/debug/hdrcodec bash scripts/batch-memory-bench.sh --check 3 2048 1536 hdr

step "fuzz smoke run"
bash scripts/fuzz-smoke.sh
