//! `hdrcodec-core`: what every codec of the hdrcodec family shares.
//!
//! - [`HdrImage`]: interleaved scene-linear `f32` pixels (RGB or RGBA) with their [`ColorInfo`].
//! - [`ImageCodec`]: the one object-safe trait every codec implements, so that the CLI, the
//!   container, fuzzers and benches can treat all codecs alike.
//! - [`Limits`]: what a decoder may allocate; checked before every allocation, with a budget
//!   that decoders charge as they allocate.
//! - [`sink`]: where decoders put rows: an [`HdrImage`], a caller's `f32`/`f16` buffer with a
//!   stride ([`ImageCodec::decode_into`]), or a consumer that keeps nothing.
//! - [`RowEncoder`] ([`ImageCodec::row_encoder`]): encoders that take rows band by band, so
//!   that a conversion holds neither the decoded image nor the encoded file.
//! - [`ThreadPool`]: the one handle to worker threads, passed down through encode and decode.
//! - [`cpu`]: CPU features detected once; `HDRCODEC_CPU=scalar` selects the portable kernels.
//! - [`Error`]: the one error enum of the family.
//! - [`color`], [`transfer`], [`metrics`], [`tonemap`], [`hdr10`]: colour science services.
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, HdrImage};
//! let img = HdrImage::new(2, 1, Channels::Rgb, vec![1.0, 0.5, 0.25, 4.0, 2.0, 1.0], ColorInfo::default())?;
//! assert_eq!(img.pixel(1, 0), &[4.0, 2.0, 1.0]);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

#![forbid(unsafe_code)]

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

pub mod bytes;
mod codec;
pub mod color;
pub mod cpu;
mod error;
pub mod hdr10;
mod image;
mod limits;
pub mod metrics;
pub mod sink;
/// The `half` crate, whose `f16` is the sample type of half-float buffers ([`sink::FrameBufMut::f16`]).
pub use half;
pub mod threads;
pub mod tiff;
pub mod tonemap;
pub mod transfer;

pub use codec::{
    decode_image, encode_rows, encode_via_seekable, read_exact_at, read_rest, remaining_len, split_option,
    ChargedBytes, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, ImageCodec, ImageInfo, PendingHeader,
    ReadSeek, RowCounter, RowEncoder, StoredBytes, StreamReport, VideoCodec, VideoDecoder, VideoEncoder, WriteSeek,
};
pub use color::{Chromaticities, ColorPrimaries, Mat3, YcbcrCoefficients};
pub use error::{Error, Result};
pub use hdr10::{Av1MdcvUnits, ClipReport, ContentLightLevel, Hdr10Metadata, MasteringDisplay, St2086Units};
pub use image::{Channels, ColorInfo, HdrImage, RangeCount};
pub use limits::{Allocation, Limits};
pub use metrics::Comparison;
pub use threads::ThreadPool;
pub use tonemap::{GtToneCurve, GtToneLut};
pub use transfer::{Bt1886Transfer, HlgTransfer, PqTransfer, SrgbTransfer};
