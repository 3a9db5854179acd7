#!/usr/bin/env bash
# Installs the reference implementations the validation tests compare against
# (see ../shared/REFERENCES.md): Debian's OpenImageIO, OpenEXR, libtiff, jxrlib (its tools, and
# libjxr-dev: headers and libraries for the in-process peer of benches/jxr_decode.rs, which
# tests/build.rs compiles against, so it must be installed before cargo builds the benches;
# libopenexr-dev likewise for the in-process OpenEXR peer of benches/exr.rs),
# libjxl, libavif, FFmpeg, pfstools, the DejaVu font `bench --plot` labels with, and a Python venv with a pinned imagecodecs,
# libdav1d-dev (the system library hdrcodec-video decodes AV1 with, through the dav1d crate),
# nasm (rav1e's assembly kernels, its `asm` feature), GNU time (peak memory in scripts/memory-bench.sh), and (for the KTX2 reference) Node.js with the npm package ktx-parse pinned in tests/ktx2.
# Idempotent: re-running it on a prepared machine takes a few seconds.
set -euo pipefail

here=$(cd "$(dirname "$0")/.." && pwd)
venv="${HDRCODEC_VENV:-$here/.venv}"

packages=(openimageio-tools python3-openimageio python3-numpy openexr libtiff-tools libtiff-dev
          libjxr-tools libjxr-dev libopenexr-dev libjxl-tools libavif-bin ffmpeg dav1d libdav1d-dev nasm pfstools pkg-config
          fonts-dejavu-core time)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  echo "setup: installing Debian packages: ${missing[*]}" >&2
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The venv sits on Debian's python3 so that OpenImageIO's Python module is visible in it.
if [ ! -x "$venv/bin/python" ]; then
  echo "setup: creating Python venv at $venv" >&2
  /usr/bin/python3 -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -c 'import imagecodecs, sys; sys.exit(imagecodecs.__version__ != "2026.3.6")' 2>/dev/null; then
  echo "setup: installing imagecodecs==2026.3.6 into the venv" >&2
  "$venv/bin/pip" install -q --disable-pip-version-check "imagecodecs==2026.3.6"
fi
"$venv/bin/python" -c 'import imagecodecs, OpenImageIO, numpy' >/dev/null

# --- KTX2 reference (tests/bc6h_ktx2_reference.rs): Node.js and the pinned npm package ktx-parse.
if ! command -v node >/dev/null 2>&1; then
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  echo "setup: installing nodejs and npm" >&2
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
fi
if [ ! -f "$here/tests/ktx2/node_modules/ktx-parse/package.json" ] ||
   ! grep -q '"version": "2.0.0"' "$here/tests/ktx2/node_modules/ktx-parse/package.json"; then
  echo "setup: installing ktx-parse (tests/ktx2, npm ci)" >&2
  (cd "$here/tests/ktx2" && npm ci --silent --no-audit --no-fund >/dev/null)
fi
(cd "$here/tests/ktx2" && node --input-type=module -e 'await import("ktx-parse")')
echo "setup: reference tools ready (venv: $venv)" >&2
