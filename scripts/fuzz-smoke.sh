#!/usr/bin/env bash
# Builds every fuzz target with cargo-fuzz on the stable toolchain (no sanitizer: `-s none`, see
# ../shared/REFERENCES.md) and runs each for a short time, seeded with small valid files and the
# regression inputs of fuzz/regressions/<target>/. When a target fails, the input libFuzzer saved
# (fuzz/artifacts/<target>/crash-<sha1>, leak-, timeout-, oom-) is copied into
# fuzz/regressions/<target>/, where `cargo test` replays it (tests/fuzz_regressions.rs) once
# committed, and the script still fails.
# Usage: scripts/fuzz-smoke.sh [SECONDS_PER_TARGET]   (default 15)
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-15}"

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz" >&2
  cargo install cargo-fuzz --locked --quiet
fi

# Seeds: small valid files of every format, made by our own CLI from the generated corpus.
seeds=fuzz/seeds
bash scripts/make-fuzz-seeds.sh "$seeds"

cd fuzz
cargo fuzz build -s none -O
started=$(mktemp); trap 'rm -f "$started"' EXIT
for target in $(cargo fuzz list); do
  mkdir -p "corpus/$target"
  if [ -d "../$seeds/$target" ]; then cp -n "../$seeds/$target"/* "corpus/$target/" 2>/dev/null || true; fi
  # Past crashes seed the run too (every file but the README).
  find "regressions/$target" -maxdepth 1 -type f ! -name 'README*' -exec cp -n {} "corpus/$target/" \; 2>/dev/null || true
  echo "fuzz: $target for ${secs}s" >&2
  log="artifacts/$target.log"; mkdir -p "artifacts/$target"
  touch "$started"
  if ! cargo fuzz run -s none -O "$target" "corpus/$target" -- -max_total_time="$secs" -max_len=65536 \
      -rss_limit_mb=2048 >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    mkdir -p "regressions/$target"
    saved=0
    # The inputs libFuzzer wrote during this run, under their libFuzzer names.
    while IFS= read -r -d '' artifact; do
      cp "$artifact" "regressions/$target/"
      echo "fuzz: saved fuzz/regressions/$target/$(basename "$artifact") (replayed by tests/fuzz_regressions.rs; commit it with the fix)" >&2
      saved=$((saved + 1))
    done < <(find "artifacts/$target" -maxdepth 1 -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' \
      -o -name 'oom-*' \) -newer "$started" -print0)
    [ "$saved" -gt 0 ] || echo "fuzz: no input was saved; see the log above" >&2
    echo "fuzz: target $target found a failure" >&2
    exit 1
  fi
  grep -E '^Done [0-9]+ runs' "$log" | sed "s/^/fuzz: $target: /" >&2
done
echo "fuzz: every target ran ${secs}s without a failure" >&2
