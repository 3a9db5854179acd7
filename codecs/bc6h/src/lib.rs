//! BC6H (BPTC float) GPU texture codec: bit-exact decoder, format tables, DDS and KTX2 files.
//!
//! - [`decode_block`] / [`decode_surface`]: the decoder (all 14 modes, UF16 and SF16),
//!   bit-exact with the D3D11 specification and bcdec.
//! - [`modes`]: the format tables and block packing shared with the encoder.
//! - [`dds`] (DX10 header) and [`ktx2`]: the two files, with mip levels, holding a
//!   [`Bc6hTexture`] ([`texture`]); [`Bc6hDdsCodec`] and [`Bc6hKtx2Codec`] implement
//!   [`hdrcodec_core::ImageCodec`].
//! - [`encode`]: the encoder.

/// The README's example is compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;

mod codec;
pub mod dds;
mod decode;
pub mod encode;
pub mod ktx2;
pub mod modes;
pub mod texture;

pub use codec::{downsample_box, encode_texture, Bc6hDdsCodec, Bc6hKtx2Codec};
pub use dds::{dds_levels, read_dds, read_dds_header, write_dds};
pub use decode::{block_dims, decode_block, decode_surface, decode_surface_into, surface_bytes};
pub use ktx2::{ktx2_levels, read_ktx2, read_ktx2_header, write_ktx2};
pub use texture::{Bc6hTexture, TextureHeader};
