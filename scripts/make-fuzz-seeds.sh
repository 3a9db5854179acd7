#!/usr/bin/env bash
# Writes small valid files of every format into DIR/<fuzz target>/, as seeds for the fuzzers:
# the generated corpus's small scenes, converted by our own CLI.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:?usage: make-fuzz-seeds.sh DIR}"
rm -rf "$out"; mkdir -p "$out"
cargo build --release --quiet -p hdrcodec-cli --bin hdrcodec
bin=target/release/hdrcodec
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
"$bin" corpus write "$work/scenes" >/dev/null
seed() { # TARGET EXT [convert args...]
  local target=$1 ext=$2; shift 2
  mkdir -p "$out/$target"
  for f in "$work"/scenes/*.exr; do
    local name; name=$(basename "$f" .exr)
    # Only the small scenes: libFuzzer works best on inputs of a few KiB.
    [ "$(stat -c %s "$f")" -lt 200000 ] || continue
    "$bin" convert "$f" "$out/$target/$name.$ext" "$@" >/dev/null 2>&1 || true
  done
}
seed exr exr --opt compression=piz
seed pfm pfm
seed container hdrc
seed rgbe hdr
seed logluv tif --codec logluv32
seed bc6h_files dds --effort 0
# JPEG XR: our encoder's files (one tiled, one lossless) and the crate's test streams, which
# JxrEncApp and T.835 wrote (other writers, other choices).
seed jxr q60.jxr --quality 60 --opt tile=64
seed jxr lossless.jxr --opt lossless=true
cp codecs/jxr/testdata/*.jxr "$out/jxr/"
# Gain-map JPEG (the target reads JPEG-HDR too): our two encoders' files and a small file
# libultrahdr wrote.
seed gainmap_jpeg jpg --quality 70 --opt map_scale=4
seed gainmap_jpeg jpeg-hdr.jpg --codec jpeg-hdr --quality 70 --opt correction=post
cp codecs/jpeghdr/testdata/*.jpg "$out/gainmap_jpeg/"
# Y4M: FFmpeg's test pattern in the colour spaces the reader takes (when FFmpeg is installed).
mkdir -p "$out/y4m"
if command -v ffmpeg >/dev/null; then
  for fmt in yuv420p yuv420p10le yuv444p12le; do
    ffmpeg -v error -y -f lavfi -i testsrc=size=16x12:rate=1 -frames:v 2 -pix_fmt "$fmt" -strict -1 \
      "$out/y4m/testsrc-$fmt.y4m" || true
  done
fi
echo "seeds: $(find "$out" -type f | wc -l) files in $out" >&2
