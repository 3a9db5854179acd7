#!/usr/bin/env bash
# Builds every fuzz target with cargo-fuzz on the stable toolchain (no sanitizer: `-s none`, see
# ../shared/REFERENCES.md) and runs each for a short time, seeded with small valid files.
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
for target in $(cargo fuzz list); do
  mkdir -p "corpus/$target"
  if [ -d "../$seeds/$target" ]; then cp -n "../$seeds/$target"/* "corpus/$target/" 2>/dev/null || true; fi
  echo "fuzz: $target for ${secs}s" >&2
  log="artifacts/$target.log"; mkdir -p artifacts
  if ! cargo fuzz run -s none -O "$target" "corpus/$target" -- -max_total_time="$secs" -max_len=65536 \
      -rss_limit_mb=2048 >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "fuzz: target $target found a failure (input saved under fuzz/artifacts/$target)" >&2
    exit 1
  fi
  grep -E '^Done [0-9]+ runs' "$log" | sed "s/^/fuzz: $target: /" >&2
done
echo "fuzz: every target ran ${secs}s without a failure" >&2
