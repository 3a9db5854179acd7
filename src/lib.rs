//! hdrcodec: the facade of the hdrcodec family.
pub use hdrcodec_core as core;
