#!/bin/sh
# Regenerates codecs/jpeghdr/testdata/panlib/: JPEG-HDR files our encoder wrote from corpus
# crops, each beside the decode of Greg Ward's panlib (the format author's library,
# github.com/radiance-org/panlib, BSD-3-Clause), kept as a half-float EXR.
#
# Needs: a C compiler, libjpeg (Debian: apt-get install libjpeg-dev), a panlib checkout
# ($PANLIB, default ../panlib, a checkout or a bare clone; the files were made at commit
# 173fb3a), the shared corpus.
# Only panlib's JPEG-HDR sources are compiled (jhcomp.c, jhdecomp.c, jhresamp.c, jhtonemap.c),
# in a temporary directory, with a JMETHOD compatibility macro for libjpeg-turbo's headers;
# scripts/panlib/jhdecode.c (ours) calls jpeghdr_load_memory() and writes a PFM. Nothing of
# panlib is kept in the repository.
set -eu
cd "$(dirname "$0")/.."
PANLIB=${PANLIB:-../panlib}
OUT="$(pwd)/codecs/jpeghdr/testdata/panlib"
BUILD=$(mktemp -d)
trap 'rm -rf "$BUILD"' EXIT

for f in jhcomp.c jhdecomp.c jhresamp.c jhtonemap.c jpeghdr.h; do
    if [ -d "$PANLIB/src" ]; then
        cp "$PANLIB/src/$f" "$BUILD/"
    else # a bare clone
        git -C "$PANLIB" show "HEAD:src/$f" >"$BUILD/$f"
    fi
done
echo "panlib at $(git -C "$PANLIB" rev-parse --short HEAD 2>/dev/null || echo '(not a git checkout)')"
(cd "$BUILD" && for f in jhcomp.c jhdecomp.c jhresamp.c jhtonemap.c; do
    cc -O2 -w '-DJMETHOD(t,n,a)=t (*n) a' -c "$f"
done)
cc -O2 -w '-DJMETHOD(t,n,a)=t (*n) a' -I"$BUILD" scripts/panlib/jhdecode.c "$BUILD"/*.o -ljpeg -lm -o "$BUILD/jhdecode"

# Our files (the ignored test writes them with the encoder's current defaults).
mkdir -p "$OUT"
HDRCODEC_JPEGHDR_OUT="$OUT" cargo test -q -p hdrcodec-tests --test gainmap_reference \
    write_jpeg_hdr_files_for_panlib -- --ignored
cargo build -q -p hdrcodec-cli
for jpg in "$OUT"/*.jpg; do
    stem=${jpg%.jpg}
    "$BUILD/jhdecode" "$jpg" "$BUILD/out.pfm"
    "${CARGO_TARGET_DIR:-target}/debug/hdrcodec" convert "$BUILD/out.pfm" "$stem.panlib.exr" \
        --opt pixel=half --opt compression=zip --opt primaries=bt709
done
ls -l "$OUT"
