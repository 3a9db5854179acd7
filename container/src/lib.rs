//! `hdrcodec-container`: `.hdrc`, the chunked file format of the hdrcodec family, for streams
//! that have no standard file of their own (tiled payloads, frame sequences) and to carry colour
//! and HDR10 metadata uniformly. README.md is the byte-level specification.
//!
//! - [`Writer`] streams chunks to any `std::io::Write` (it never seeks); [`Reader`] validates a
//!   whole file in memory (every length, CRC-32C, tile and index) before handing anything out;
//!   [`SeekReader`] reads single tiles of a file on disk through the index; [`probe`] reads
//!   only HEAD, COLR and HDRM; [`decode_image_rows_from`] decodes a file from a stream, reading
//!   each DATA chunk (and checking its CRC) as it is decoded, never the whole file.
//! - [`encode_image`] / [`decode_image`] and [`encode_frames`] / [`decode_frames`] code whole
//!   images, each tile a stand-alone encoding by another codec, in parallel.
//! - [`RawF32Codec`] and [`RawF16Codec`]: built-in payload codecs; [`HdrcCodec`]: the
//!   container as an [`ImageCodec`](hdrcodec_core::ImageCodec); [`HdrcVideoCodec`]: the
//!   container as a [`VideoCodec`](hdrcodec_core::VideoCodec) of frame streams, written frame
//!   by frame and read one frame at a time.
//!
//! ```
//! use hdrcodec_container::{decode_image, encode_image, RawF32Codec};
//! use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
//! let samples = (0..5 * 3 * 3).map(|i| i as f32 * 0.5).collect();
//! let img = HdrImage::new(5, 3, Channels::Rgb, samples, ColorInfo::default())?;
//! let file = encode_image(&img, &RawF32Codec, &EncodeSettings::default(), Some(2))?;
//! let back = decode_image(&file, &Limits::default().into(), &|id| (id == *b"RF32").then_some(&RawF32Codec as &dyn ImageCodec))?;
//! assert_eq!(back, img);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

#![forbid(unsafe_code)]

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod crc;
mod format;
mod image;
mod raw;
mod reader;
mod seek;
mod stream;
mod video;
mod writer;

pub use crc::{crc32c, Crc32c};
pub use format::{DataHeader, Head, IndexEntry, SIGNATURE, VERSION};
pub use image::{
    decode_frames, decode_image, decode_image_rows, decode_image_rows_from, encode_frames, encode_image, HdrcCodec,
};
pub use raw::{RawF16Codec, RawF32Codec};
pub use reader::{probe, DataRef, HeadInfo, Reader};
pub use seek::SeekReader;
pub use video::HdrcVideoCodec;
pub use writer::Writer;
