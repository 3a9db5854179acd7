//! BC6H (BPTC float) GPU texture codec: bit-exact decoder, format tables, DDS and KTX2 files.
//!
//! - [`decode_block`] / [`decode_surface`]: the decoder (all 14 modes, UF16 and SF16),
//!   bit-exact with the D3D11 specification and bcdec.
//! - [`modes`]: the format tables and block packing shared with the encoder.
//! - [`files`]: DDS (DX10 header) and KTX2 with mip levels; [`Bc6hDdsCodec`] and
//!   [`Bc6hKtx2Codec`] implement [`hdrcodec_core::ImageCodec`].
//! - [`encode`]: the encoder.

mod codec;
mod decode;
pub mod encode;
pub mod files;
pub mod modes;

pub use codec::{downsample_box, encode_texture, Bc6hDdsCodec, Bc6hKtx2Codec};
pub use decode::{block_dims, decode_block, decode_surface, decode_surface_into, surface_bytes};
pub use files::{read_dds, read_ktx2, write_dds, write_ktx2, Bc6hTexture};
