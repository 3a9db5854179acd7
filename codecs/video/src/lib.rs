//! HDR video: frames of scene-linear light to a compact AV1 stream and back.
//!
//! Two transfer paths on the same frames: HDR10 (PQ or HLG, BT.2020, with MaxCLL/MaxFALL and
//! the SMPTE ST 2086 mastering display) and Mantiuk et al.'s 2004 perception-motivated
//! luminance quantization (L_p u'v').

#[cfg(feature = "decode")]
pub mod decode;
#[cfg(feature = "encode")]
pub mod encode;
pub mod hdr10;
pub mod ivf;
pub mod obu;
