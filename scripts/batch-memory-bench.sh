#!/usr/bin/env bash
# Peak resident memory of `hdrcodec batch` on N generated photographs (`hdrcodec corpus large`,
# 4 of 4000x3000 by default: the README's table, "hdrcodec batch"), unbounded and within
# memory budgets, against the budget.
#
#   scripts/batch-memory-bench.sh [--check] [N WIDTH HEIGHT] [FORMAT...]
#
# Prints a Markdown table: --to, --jobs / --threads, --memory, the files and the estimated cost
# in flight at the peak (from the batch's JSON summary), peak RSS (/usr/bin/time -f %M) and wall
# time. A budget bounds the files in flight, not the process: RSS also holds the binary, its
# pool and the next file read ahead, so with --check (a smaller run) a bounded run fails when
# its peak RSS passes the budget plus 64 MB, or when it ran more files at once than the budget
# lets in. FORMATs default to hdr and jxr. HDRCODEC_BIN names the binary to measure (default: a
# release build).
set -euo pipefail
cd "$(dirname "$0")/.."
check=false
case "${1:-}" in --check) check=true && shift ;; esac
count=${1:-4}
width=${2:-4000}
height=${3:-3000}
shift $(($# < 3 ? $# : 3))
formats=${*:-hdr jxr}
source scripts/bench-binary.sh
bin=$(hdrcodec_bin)
dir=$(mktemp -d "${TMPDIR:-/tmp}/hdrcodec-batch-mem.XXXXXX")
trap 'rm -rf "$dir"' EXIT
mkdir -p "$dir/in"
for i in $(seq 1 "$count"); do
  "$bin" corpus large "$dir/in/big$i.exr" --width "$width" --height "$height"
done

decoded=$((width * height * 3 * 4))
mib() { awk -v b="$1" 'BEGIN { printf "%.0f", b / 1048576 }'; }
field() { sed -n "s/.*\"$1\": *\([0-9.]*\).*/\1/p" "$dir/summary" | head -n 1; }
printf '%s\n' "$count images of ${width}x${height}, decoded RGB f32 $(mib $decoded) MiB each."
printf '\n| `--to` | `--jobs` / `--threads` | `--memory` | files in flight (peak) | estimated cost in flight | peak RSS | wall |\n'
printf '| --- | --- | --- | --- | --- | --- | --- |\n'
missed=0
run() {
  local to=$1 jobs=$2 threads=$3 memory=$4
  rm -rf "$dir/out"
  /usr/bin/time -f '%M %e' -o "$dir/time" "$bin" batch "$dir/in" "$dir/out" --to "$to" --json \
    --jobs "$jobs" --threads "$threads" --memory "$memory" >"$dir/summary"
  local kb wall
  read -r kb wall <"$dir/time"
  local peak=$((kb * 1024)) budget files cost
  budget=$(field memory_budget)
  files=$(field peak_in_flight_files)
  cost=$(field peak_in_flight_cost)
  printf '| `%s` | %s / %s | %s | %s | %s MiB | %s MiB | %s s |\n' "$to" "$jobs" "$threads" "$memory" "$files" \
    "$(mib "$cost")" "$(mib $peak)" "$wall"
  if [ "$memory" != 64G ] && { [ "$peak" -gt $((budget + 64 * 1048576)) ] || { [ "$cost" -gt "$budget" ] && [ "$files" -gt 1 ]; }; }; then
    echo "batch-memory-bench: --to $to --memory $memory: peak RSS $(mib $peak) MiB, budget $(mib "$budget") MiB" >&2
    missed=$((missed + 1))
  fi
}
# One file's estimated cost is its file plus 3x its decoded image: the budgets let in about two
# files, then one.
one=$((decoded * 3 + decoded / 4))
two=$(((one * 2 + one / 4) / 1048576))M
single=$(((one + one / 10) / 1048576))M
for to in $formats; do
  run "$to" "$count" "$count" 64G
  run "$to" "$count" "$count" "$two"
  run "$to" "$count" 2 "$single"
done
if $check && [ "$missed" -gt 0 ]; then
  echo "batch-memory-bench: $missed runs passed their budget" >&2
  exit 1
fi
