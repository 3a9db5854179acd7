//! HDR video: frames of scene-linear light to a compact AV1 stream and back.
//!
//! Two transfer paths on the same frames: HDR10 (PQ or HLG, BT.2020, with MaxCLL/MaxFALL and
//! the SMPTE ST 2086 mastering display) and Mantiuk et al.'s 2004 perception-motivated
//! luminance quantization (L_p u'v').
//!
//! The luminance curves ([`curves::LumaCurve`]): [`mantiuk::Psi04`] (the 2004 ψ, built on
//! [`tvi::ferwerda_tvi`]), [`mantiuk06::Mantiuk06`] (the 2006 closed form), core's PQ
//! ([`curves::PqCurve`]), the DICOM GSDF ([`gsdf::GsdfCurve`]) and a plain logarithm
//! ([`curves::LogCurve`]); how their steps compare with visibility thresholds
//! ([`thresholds`]); and the L_p u'v' colour space ([`luv`]).
//!
//! The AV1 path: HDR10 frames ([`hdr10`]: BT.2020 NCL Y'CbCr on PQ or HLG), encoded with rav1e
//! (`encode`, feature `encode`), stored as IVF ([`ivf`]), read back by our OBU parser ([`obu`]:
//! sequence header, HDR10 and T.35 metadata) and decoded with libdav1d (`decode`, feature
//! `decode`), the planes turned into light by [`light`]. The Mantiuk transfer in AV1
//! ([`lpuv_av1`]): L_p u'v' codes in 12-bit (or 10-bit, Main-profile) planes,
//! named by our own T.35 message on every frame. [`codec::Av1Codec`] is all of it as core's
//! `VideoCodec`.

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub mod codec;
pub mod curves;
#[cfg(feature = "decode")]
pub mod decode;
#[cfg(feature = "encode")]
pub mod encode;
pub mod gsdf;
pub mod hdr10;
pub mod hevc;
pub mod ivf;
pub mod light;
pub mod lpuv_av1;
pub mod lpuv_image;
pub mod luv;
pub mod mantiuk;
pub mod mantiuk06;
pub mod mkv;
pub mod mp4;
pub mod obu;
pub mod sdr;
pub mod sequences;
pub mod thresholds;
pub mod tvi;
pub mod y4m;
