# Sourced by the memory benches (run from the workspace root): `hdrcodec_bin` prints the path of
# the binary to measure, $HDRCODEC_BIN if set, else a release build made now.
hdrcodec_bin() {
  if [ -n "${HDRCODEC_BIN:-}" ]; then
    realpath "$HDRCODEC_BIN"
  else
    cargo build --release --quiet -p hdrcodec-cli --bin hdrcodec >&2
    echo "$PWD/target/release/hdrcodec"
  fi
}
