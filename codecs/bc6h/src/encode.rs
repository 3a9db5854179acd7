//! BC6H encoder (being written by the encoder owner; the signatures below are the contract
//! between the encoder and the rest of the crate).
use hdrcodec_core::{Error, Result};

/// Encoder options.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodeOptions {
    /// Produce BC6H_SF16 (signed) blocks instead of BC6H_UF16.
    pub signed: bool,
    /// 0 (fastest) to 9 (exhaustive search).
    pub effort: u8,
    /// Worker threads, 0 = one per core.
    pub threads: usize,
}

impl Default for EncodeOptions {
    fn default() -> Self {
        EncodeOptions { signed: false, effort: 5, threads: 0 }
    }
}

/// Compresses a `width` x `height` surface of interleaved linear RGB `f32` samples into BC6H
/// blocks (16 bytes each, block rows top to bottom, partial blocks padded by edge replication).
pub fn encode_surface(width: u32, height: u32, rgb: &[f32], options: &EncodeOptions) -> Result<Vec<u8>> {
    let _ = (width, height, rgb, options);
    Err(Error::unsupported("the BC6H encoder is not written yet"))
}
