#!/usr/bin/env bash
# Instructions of one JPEG XR decode, ours against jxrlib's, like for like (callgrind, one
# thread): each file held in memory, decoded to its own pixel format into a buffer allocated
# before, counting only the decode call (`decode_raw_into`; jxrlib_shim.c's
# `jxrlib_shim_decode`, which the bench times: stream, decoder, copy, release). The bytes of
# the two decodes are compared.
#
#   scripts/jxr-callgrind.sh [FILE.jxr...]
#   scripts/jxr-callgrind.sh --encode [FILE.jxr]
#
# With --encode: instructions of one encode instead, of the image of FILE (a 48bppRGBHalf
# file; default the GoldenGate corpus file) to 48bppRGBHalf at JxrEncApp's settings for -q 1.0,
# 0.9, 0.6 and 0.3 (jxrlib_shim.c's `jxrlib_shim_encode` from half floats, what the encode
# bench times) against ours at quality 100 / 90 / 60 / 30 with one quantizer set
# (`examples/jxr_encode`, JXR_ADAPTIVE=0, `encoder::encode` from the f32 image, one thread);
# only the encode is counted on either side: jxrlib's call, and ours as the whole run minus a
# run that only decodes the input (JXR_TIMES=0; a toggle on `encoder::encode*` would switch
# collection off again in the nested functions of the same prefix). Ours twice: at our own
# quality scale (its quantizers are not jxrlib's), and at equal settings (the quantizers read
# from jxrlib's file, JXR_QP_FROM, and its frequency order: files of about jxrlib's size).
#
# Without files: the three corpus .jxr files and GoldenGate re-encoded by jxrlib with
# JxrEncApp's settings (tests/peers/jxrlib_shim.c's encoder) at q 0.3 and 0.6, as
# 48bppRGBHalf and as 128bppRGBFloat. Needs valgrind, a C compiler and libjxr-dev; builds the
# jxr_raw example (release, line tables) into $CARGO_TARGET_DIR. Work files go to
# $JXR_CALLGRIND_DIR (default /tmp/jxr-callgrind), callgrind's outputs too (for
# callgrind_annotate). Prints a table: file, ours, jxrlib, ratio (jxrlib / ours).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=${JXR_CALLGRIND_DIR:-/tmp/jxr-callgrind}
corpus=${HDRCODEC_CORPUS:-$root/../shared/corpus}
mkdir -p "$work"
# shellcheck disable=SC2046
cc -O2 -o "$work/jxrlib_driver" "$root/tests/peers/jxrlib_driver.c" "$root/tests/peers/jxrlib_shim.c" \
    $(pkg-config --cflags --libs libjxr)
count() { # callgrind output file -> instructions of the collected part
    awk '/^summary:/ { print $2 }' "$1"
}
if [ "${1:-}" = "--encode" ]; then
    (cd "$root" && CARGO_PROFILE_RELEASE_DEBUG=line-tables-only cargo build -q --release -j1 -p hdrcodec-jxr --example jxr_encode)
    ours="${CARGO_TARGET_DIR:-$root/target}/release/examples/jxr_encode"
    src=${2:-$corpus/jxr/GoldenGate_48bppRGBHalf_lossless.jxr}
    printf '| %s, 1 thread | ours at quality (M instructions) | jxrlib | jxrlib / ours | ours at equal settings | jxrlib / ours | bytes: ours equal / jxrlib |\n|---|---|---|---|---|---|---|\n' "$(basename "$src" .jxr)"
    JXR_TIMES=0 valgrind --tool=callgrind --callgrind-out-file="$work/ours.dec.cg" "$ours" "$src" 2>/dev/null
    decode=$(count "$work/ours.dec.cg")
    for q in 1.0 0.9 0.6 0.3; do
        quality=$(awk -v q="$q" 'BEGIN { printf "%.0f", q * 100 }')
        JXR_ADAPTIVE=0 JXR_OUT="$work/ours.enc.q$q.jxr" valgrind --tool=callgrind \
            --callgrind-out-file="$work/ours.enc.q$q.cg" "$ours" "$src" "$quality" 2>/dev/null
        valgrind --tool=callgrind --callgrind-out-file="$work/jxrlib.enc.q$q.cg" --toggle-collect=jxrlib_shim_encode \
            "$work/jxrlib_driver" encode "$src" "$work/jxrlib.enc.q$q.jxr" "$q" half 2>/dev/null
        JXR_ADAPTIVE=0 JXR_QP_FROM="$work/jxrlib.enc.q$q.jxr" JXR_OUT="$work/ours.equal.q$q.jxr" valgrind \
            --tool=callgrind --callgrind-out-file="$work/ours.equal.q$q.cg" "$ours" "$src" "$quality" order=frequency 2>/dev/null
        a=$(($(count "$work/ours.enc.q$q.cg") - decode))
        e=$(($(count "$work/ours.equal.q$q.cg") - decode))
        b=$(count "$work/jxrlib.enc.q$q.cg")
        sa=$(stat -c %s "$work/ours.equal.q$q.jxr")
        sb=$(stat -c %s "$work/jxrlib.enc.q$q.jxr")
        awk -v n="q $quality / $q" -v a="$a" -v b="$b" -v e="$e" -v sa="$sa" -v sb="$sb" \
            'BEGIN { printf "| %s | %.1f | %.1f | %.2f× | %.1f | %.2f× | %d / %d |\n", n, a / 1e6, b / 1e6, b / a, e / 1e6, b / e, sa, sb }'
    done
    exit 0
fi
(cd "$root" && CARGO_PROFILE_RELEASE_DEBUG=line-tables-only cargo build -q --release -j1 -p hdrcodec-jxr --example jxr_raw)
ours="${CARGO_TARGET_DIR:-$root/target}/release/examples/jxr_raw"
files=("$@")
if [ ${#files[@]} -eq 0 ]; then
    gg="$corpus/jxr/GoldenGate_48bppRGBHalf_lossless.jxr"
    files=("$gg" "$corpus/jxr/StillLife_128bppRGBAFloat_q0.9.jxr" "$corpus/jxr/venice_sunset_1k_32bppRGBE_lossless.jxr")
    for q in 0.3 0.6; do
        for f in half float; do
            out="$work/GoldenGate_${f}_q$q.jxr"
            [ -e "$out" ] || "$work/jxrlib_driver" encode "$gg" "$out" "$q" "$f"
            files+=("$out")
        done
    done
fi
printf '| file | ours (M instructions) | jxrlib | jxrlib / ours |\n|---|---|---|---|\n'
for f in "${files[@]}"; do
    name=$(basename "$f" .jxr)
    valgrind --tool=callgrind --callgrind-out-file="$work/ours.$name.cg" \
        --toggle-collect='hdrcodec_jxr::render::decode_raw_into*' "$ours" "$f" "$work/ours.$name.raw" 2>/dev/null
    valgrind --tool=callgrind --callgrind-out-file="$work/jxrlib.$name.cg" \
        --toggle-collect=jxrlib_shim_decode "$work/jxrlib_driver" decode "$f" "$work/jxrlib.$name.raw" 2>/dev/null
    cmp -s "$work/ours.$name.raw" "$work/jxrlib.$name.raw" || { echo "$name: the samples differ" >&2; exit 1; }
    a=$(count "$work/ours.$name.cg")
    b=$(count "$work/jxrlib.$name.cg")
    awk -v n="$name" -v a="$a" -v b="$b" 'BEGIN { printf "| %s | %.1f | %.1f | %.2f× |\n", n, a / 1e6, b / 1e6, b / a }'
done
