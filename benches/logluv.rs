//! Placeholder until this codec's bench lands; replaced by the codec's criterion bench.
fn main() {}
