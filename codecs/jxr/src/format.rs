//! A minimal pixel-format table (T.832 Annex A, jxrlib `JXRGlue.c: pixelInfo`): what `probe`
//! needs (name, alpha, number kind). Only until the container module's full table is merged.

/// How a format's samples are numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Unsigned integers, sRGB-encoded by WIC convention.
    Int,
    /// Half floats (BD16F).
    Half,
    /// 32-bit floats (BD32F).
    Float,
    /// Fixed point (BD16S, BD32S).
    Fixed,
    /// Radiance RGBE.
    Rgbe,
}

/// One pixel format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelFormat {
    /// The WIC name.
    pub name: &'static str,
    /// Has an alpha channel.
    pub alpha: bool,
    /// Number kind.
    pub kind: Kind,
}

/// The common stem of almost every JPEG XR pixel-format GUID, as stored
/// ({6FDDC324-4E03-4BFE-B185-3D77768DC9xx}).
const STEM: [u8; 15] = [0x24, 0xC3, 0xDD, 0x6F, 0x03, 0x4E, 0xFE, 0x4B, 0xB1, 0x85, 0x3D, 0x77, 0x76, 0x8D, 0xC9];

/// The format of a stored GUID, if it is one of the formats listed here.
pub fn lookup(guid: &[u8; 16]) -> Option<PixelFormat> {
    if guid[..15] != STEM {
        return None;
    }
    use Kind::*;
    let (name, alpha, kind) = match guid[15] {
        0x3B => ("48bppRGBHalf", false, Half),
        0x42 => ("64bppRGBHalf", false, Half),
        0x3A => ("64bppRGBAHalf", true, Half),
        0x3E => ("16bppGrayHalf", false, Half),
        0x1B => ("128bppRGBFloat", false, Float),
        0x19 => ("128bppRGBAFloat", true, Float),
        0x1A => ("128bppPRGBAFloat", true, Float),
        0x11 => ("32bppGrayFloat", false, Float),
        0x3D => ("32bppRGBE", false, Rgbe),
        0x12 => ("48bppRGBFixedPoint", false, Fixed),
        0x40 => ("64bppRGBFixedPoint", false, Fixed),
        0x1D => ("64bppRGBAFixedPoint", true, Fixed),
        0x18 => ("96bppRGBFixedPoint", false, Fixed),
        0x41 => ("128bppRGBFixedPoint", false, Fixed),
        0x1E => ("128bppRGBAFixedPoint", true, Fixed),
        0x13 => ("16bppGrayFixedPoint", false, Fixed),
        0x3F => ("32bppGrayFixedPoint", false, Fixed),
        0x14 => ("32bppRGB101010", false, Int),
        0x0D => ("24bppRGB", false, Int),
        0x0C => ("24bppBGR", false, Int),
        0x0E => ("32bppBGR", false, Int),
        0x0F => ("32bppBGRA", true, Int),
        0x10 => ("32bppPBGRA", true, Int),
        0x15 => ("48bppRGB", false, Int),
        0x16 => ("64bppRGBA", true, Int),
        0x17 => ("64bppPRGBA", true, Int),
        0x08 => ("8bppGray", false, Int),
        0x0B => ("16bppGray", false, Int),
        0x09 => ("16bppBGR555", false, Int),
        0x0A => ("16bppBGR565", false, Int),
        0x05 => ("BlackWhite", false, Int),
        _ => return None,
    };
    Some(PixelFormat { name, alpha, kind })
}
