#!/usr/bin/env bash
# Size of an HDR10 AV1 stream against the same frames as OpenEXR (PIZ, half), and its quality
# per frame (issue 14's "≥ 30x smaller at PU21-PSNR ≥ 45 dB"). The frames: a 640x360 window
# panning across a corpus photograph in 24 steps, written as half-float PIZ EXR by OpenImageIO
# (the reference venv's Python). Each quality is encoded, decoded and compared frame by frame.
# Usage: scripts/video-vs-exr.sh [SOURCE.exr] [QUALITIES...]   (run from the repository root)
set -euo pipefail
src="${1:-../shared/corpus/exr/MtTamWest.exr}"; shift || true
qualities=("${@:-85 92 95 97}")
py="${HDRCODEC_VENV:-.venv}/bin/python"
bin="${HDRCODEC_BIN:-target/release/hdrcodec}"
[ -x "$bin" ] || cargo build --release -q -p hdrcodec-cli
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
"$py" - "$src" "$work/frames" <<'PY'
import os, sys
import OpenImageIO as oiio
src, out = sys.argv[1], sys.argv[2]
os.makedirs(out)
px = oiio.ImageBuf(src).get_pixels(oiio.FLOAT)[..., :3]
H, W = px.shape[:2]
w, h = 640, 360
for i in range(24):
    x0, y0 = int(i * (W - w) / 23), (H - h) // 2
    spec = oiio.ImageSpec(w, h, 3, oiio.HALF)
    spec.attribute("compression", "piz")
    path = f"{out}/f{i:03d}.exr"
    o = oiio.ImageOutput.create(path)
    o.open(path, spec)
    o.write_image(px[y0:y0 + h, x0:x0 + w].copy())
    o.close()
PY
exr_bytes=$(cat "$work"/frames/*.exr | wc -c)
echo "24 frames of 640x360 from $src: OpenEXR PIZ half $exr_bytes bytes"
for q in ${qualities[*]}; do
  "$bin" video encode "$work"/frames/*.exr "$work/q$q.ivf" --quality "$q" --speed 6 2>/dev/null
  "$bin" video decode "$work/q$q.ivf" "$work/dec$q" >/dev/null
  for i in $(seq 0 23); do
    "$bin" compare "$work/frames/f$(printf %03d "$i").exr" "$work/dec$q/frame_$(printf %05d "$i").exr" --json
  done | "$py" -c '
import json, sys
text, rows, dec, at = sys.stdin.read(), [], json.JSONDecoder(), 0
while text[at:].strip():
    at += len(text[at:]) - len(text[at:].lstrip())
    row, at = dec.raw_decode(text, at)
    rows.append(row)
ivf, exr, q = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
p = [r["pu21_psnr"] for r in rows]
d = [r["de_itp_mean"] for r in rows]
print(f"quality {q}: {ivf} bytes, {exr / ivf:.0f}x smaller; PU21-PSNR mean {sum(p) / len(p):.2f} min {min(p):.2f} dB; mean dE ITP {sum(d) / len(d):.2f}")
' "$(wc -c < "$work/q$q.ivf")" "$exr_bytes" "$q"
done
