//! A BC6H texture (the block data of each mip level), the mip-level arithmetic, and the header
//! reading and checks that the DDS and KTX2 parsers share.
use crate::decode::{decode_surface, surface_bytes};
use hdrcodec_core::{Error, Limits, Result};

/// A BC6H texture: the block data of each mip level, level 0 (full size) first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bc6hTexture {
    /// Width of level 0 in texels.
    pub width: u32,
    /// Height of level 0 in texels.
    pub height: u32,
    /// BC6H_SF16 (signed) rather than BC6H_UF16.
    pub signed: bool,
    /// Block data of each level (16 bytes per 4x4 block, block rows top to bottom).
    pub levels: Vec<Vec<u8>>,
}

/// What a DDS or KTX2 header says of its BC6H texture, checked (size against the limits'
/// dimensions, mip count against the size) but without reading any block data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextureHeader {
    /// Width of level 0 in texels.
    pub width: u32,
    /// Height of level 0 in texels.
    pub height: u32,
    /// BC6H_SF16 (signed) rather than BC6H_UF16.
    pub signed: bool,
    /// Mip levels in the file (at least 1).
    pub levels: usize,
}

impl TextureHeader {
    /// The stored format in a few words: "BC6H UF16, 1 mip level", "BC6H SF16, 10 mip levels".
    pub fn format(&self) -> String {
        let kind = if self.signed { "SF16" } else { "UF16" };
        let s = if self.levels == 1 { "" } else { "s" };
        format!("BC6H {kind}, {} mip level{s}", self.levels)
    }
}

/// Width and height of mip `level` of a `width` x `height` texture (halved, at least 1).
pub fn level_size(width: u32, height: u32, level: usize) -> (u32, u32) {
    let s = level.min(31) as u32;
    ((width >> s).max(1), (height >> s).max(1))
}

/// Number of levels of a full mip chain down to 1x1.
pub fn full_mip_count(width: u32, height: u32) -> usize {
    (32 - width.max(height).max(1).leading_zeros()) as usize
}

impl Bc6hTexture {
    /// A texture holding copies of `levels` (as a file's reader found them), each checked
    /// against the limits first.
    pub(crate) fn copied(header: TextureHeader, levels: &[&[u8]], limits: &Limits) -> Result<Self> {
        let mut out = Vec::with_capacity(levels.len());
        for level in levels {
            limits.check_alloc(level.len() as u64, "a BC6H mip level")?;
            out.push(level.to_vec());
        }
        Ok(Bc6hTexture { width: header.width, height: header.height, signed: header.signed, levels: out })
    }

    /// Size of mip `level`.
    pub fn level_size(&self, level: usize) -> (u32, u32) {
        level_size(self.width, self.height, level)
    }

    /// Checks that the level count and each level's data length agree with the size.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid(format!("BC6H texture size {}x{} is empty", self.width, self.height)));
        }
        if self.levels.is_empty() || self.levels.len() > full_mip_count(self.width, self.height) {
            return Err(Error::invalid(format!(
                "{} mip levels for a {}x{} texture (1 to {} allowed)",
                self.levels.len(),
                self.width,
                self.height,
                full_mip_count(self.width, self.height)
            )));
        }
        for (i, data) in self.levels.iter().enumerate() {
            let (w, h) = self.level_size(i);
            let need = surface_bytes(w, h).ok_or_else(|| Error::invalid("BC6H level size overflows"))?;
            if data.len() != need {
                return Err(Error::invalid(format!(
                    "mip level {i} ({w}x{h}) has {} bytes of blocks, expected {need}",
                    data.len()
                )));
            }
        }
        Ok(())
    }

    /// Decodes mip `level` to interleaved RGB `f32` (checking `limits` first).
    pub fn decode_level(&self, level: usize, limits: &Limits) -> Result<Vec<f32>> {
        let data = self.levels.get(level).ok_or_else(|| {
            Error::invalid(format!("mip level {level} does not exist ({} levels)", self.levels.len()))
        })?;
        let (w, h) = self.level_size(level);
        limits.check_image(w as u64, h as u64, hdrcodec_core::Channels::Rgb)?;
        decode_surface(w, h, data, self.signed)
    }
}

/// Checks the declared size against `limits` and the mip count against the size; returns the
/// number of levels to read (a declared 0 means 1).
pub(crate) fn check_dims(width: u32, height: u32, levels: u64, limits: &Limits) -> Result<usize> {
    limits.check_dimensions(width as u64, height as u64)?;
    let full = full_mip_count(width, height);
    if levels > full as u64 {
        return Err(Error::invalid(format!("{levels} mip levels for a {width}x{height} texture (at most {full})")));
    }
    Ok(levels.max(1) as usize)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A texture of `levels` levels filled with a byte pattern.
    pub(crate) fn texture(width: u32, height: u32, levels: usize, signed: bool) -> Bc6hTexture {
        let levels = (0..levels)
            .map(|i| {
                let (w, h) = level_size(width, height, i);
                (0..surface_bytes(w, h).unwrap()).map(|b| (b * 7 + i) as u8).collect()
            })
            .collect();
        Bc6hTexture { width, height, signed, levels }
    }

    #[test]
    fn mip_counts() {
        assert_eq!(full_mip_count(644, 874), 10);
        assert_eq!(full_mip_count(1, 1), 1);
        assert_eq!(level_size(644, 874, 9), (1, 1));
        assert_eq!(level_size(5, 3, 1), (2, 1));
    }

    #[test]
    fn a_texture_without_levels_is_invalid() {
        assert!(Bc6hTexture { levels: vec![], ..texture(8, 8, 1, false) }.validate().is_err());
    }
}
