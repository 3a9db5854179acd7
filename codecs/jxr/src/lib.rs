//! `hdrcodec-jxr`: JPEG XR (ITU-T T.832 | ISO/IEC 29199-2), the lossy HDR codec of the
//! hdrcodec family, decoded bit-exactly as jxrlib decodes it.
//!
//! Modules follow the bitstream's layers: [`container`] (Annex A), `bits` (bit reader and
//! variable-length words), `header` (image and plane headers, index table), `vlc` (the fixed
//! and adaptive code tables), `macroblock` (DC, LP, HP, CBP and flexbits), `predict` and
//! `quant` (prediction and quantization), `transform` (the inverse lapped transform), `output`
//! (colour conversion and output formatting, T.832 9.10), `tiles` and `decoder`.

#![forbid(unsafe_code)]

mod bits;
pub mod container;
pub mod decoder;
pub mod header;
mod macroblock;
pub mod mb;
mod predict;
mod quant;
mod tiles;
mod vlc;

pub use decoder::{decode_coefficients, file_layout, Coefficients, FileLayout, PlaneCoeffs};
