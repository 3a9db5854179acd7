//! BC6H textures in KTX2 files, with mip levels.
//!
//! Khronos "KTX File Format Specification 2.0" (header, level index, data format descriptor),
//! formats `VK_FORMAT_BC6H_UFLOAT_BLOCK` (143) and `VK_FORMAT_BC6H_SFLOAT_BLOCK` (144), no
//! supercompression. The parser checks every size against the data and the caller's [`Limits`]
//! before allocating and never panics.
//!
//! The colour primaries live in the data format descriptor ([`KTX2_PRIMARIES`] lists those it
//! can name): [`write_ktx2`] records them and [`read_ktx2_primaries`] reads them back.
use crate::decode::surface_bytes;
use crate::texture::{check_dims, level_size, u32_at, Bc6hTexture, TextureHeader};
use hdrcodec_core::{ColorPrimaries, Error, Limits, Result};

/// `VK_FORMAT_BC6H_UFLOAT_BLOCK`.
pub const VK_BC6H_UFLOAT: u32 = 143;
/// `VK_FORMAT_BC6H_SFLOAT_BLOCK`.
pub const VK_BC6H_SFLOAT: u32 = 144;

/// The KTX2 file identifier `«KTX 20»\r\n\x1A\n`.
pub const KTX2_IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];

fn u64_at(d: &[u8], off: usize) -> Result<u64> {
    Ok(u32_at(d, off)? as u64 | (u32_at(d, off + 4)? as u64) << 32)
}

/// Header (48) + index (32).
const KTX2_LEVEL_INDEX: usize = 80;
/// KHR_DF_MODEL_BC6H (Khronos Data Format Specification 1.3, colorModel enumeration: 133;
/// 131 is KHR_DF_MODEL_BC4).
const KHR_DF_MODEL_BC6H: u32 = 133;
const KHR_DF_TRANSFER_LINEAR: u32 = 1;
const KHR_DF_SAMPLE_DATATYPE_FLOAT: u32 = 0x80;
const KHR_DF_SAMPLE_DATATYPE_SIGNED: u32 = 0x40;

/// The DFD's colorPrimaries values our named spaces have (Khronos Data Format Specification
/// 1.3, section 5.6 "colorPrimaries", enumeration `khr_df_primaries_e`; the same numbers in
/// KTX-Software's khr_df.h): UNSPECIFIED 0, BT709 1 (also sRGB), BT2020 4 (also BT.2100),
/// CIEXYZ 5, ACES 6 (AP0), ACESCC 7 (AP1, the primaries of ACEScc and ACEScg), DISPLAYP3 10,
/// ADOBERGB 11. The enumeration's other values (BT601_EBU 2, BT601_SMPTE 3, NTSC1953 8,
/// PAL525 9) name spaces the family does not, and DCI-P3 (DCI white) has no value.
const KHR_DF_PRIMARIES: [(u32, ColorPrimaries); 8] = [
    (0, ColorPrimaries::Unspecified),
    (1, ColorPrimaries::Bt709),
    (4, ColorPrimaries::Bt2020),
    (5, ColorPrimaries::Xyz),
    (6, ColorPrimaries::AcesAp0),
    (7, ColorPrimaries::AcesAp1),
    (10, ColorPrimaries::DisplayP3),
    (11, ColorPrimaries::AdobeRgb),
];

/// The primaries a KTX2 file's data format descriptor can say, [`ColorPrimaries::Unspecified`]
/// (colorPrimaries 0) included.
pub const KTX2_PRIMARIES: [ColorPrimaries; 8] = [
    ColorPrimaries::Unspecified,
    ColorPrimaries::Bt709,
    ColorPrimaries::Bt2020,
    ColorPrimaries::Xyz,
    ColorPrimaries::AcesAp0,
    ColorPrimaries::AcesAp1,
    ColorPrimaries::DisplayP3,
    ColorPrimaries::AdobeRgb,
];

/// The DFD colorPrimaries value of `primaries`, or `None` when KTX2 has none for them.
pub fn khr_df_primaries(primaries: &ColorPrimaries) -> Option<u32> {
    KHR_DF_PRIMARIES.iter().find(|(_, p)| p == primaries).map(|&(v, _)| v)
}

/// The primaries a DFD colorPrimaries value names; a value without a named space of ours
/// (or not in the enumeration) is [`ColorPrimaries::Unspecified`]: never an error, never a guess.
pub fn primaries_from_khr_df(value: u32) -> ColorPrimaries {
    KHR_DF_PRIMARIES.iter().find(|&&(v, _)| v == value).map_or(ColorPrimaries::Unspecified, |&(_, p)| p)
}

/// The colour primaries a KTX2 file's data format descriptor records: the colorPrimaries of its
/// first descriptor block when that is a Khronos basic descriptor (vendorId 0, descriptorType 0),
/// else (no DFD, another kind of block, a DFD that does not fit the file)
/// [`ColorPrimaries::Unspecified`]. Never fails and never panics.
pub fn read_ktx2_primaries(data: &[u8]) -> ColorPrimaries {
    // KTX 2.0 "Index": dfdByteOffset at 48, dfdByteLength at 52. The DFD: dfdTotalSize, then
    // the block: word 0 vendorId (17 bits) | descriptorType (15 bits), word 1 version and
    // size, word 2 colorModel | colorPrimaries << 8 | transferFunction << 16 | flags << 24.
    let read = || -> Option<u32> {
        let offset = usize::try_from(u32_at(data, 48).ok()?).ok()?;
        let length = usize::try_from(u32_at(data, 52).ok()?).ok()?;
        let dfd = data.get(offset..offset.checked_add(length)?)?;
        if length < 16 || u32_at(dfd, 4).ok()? != 0 {
            return None;
        }
        Some(u32_at(dfd, 12).ok()? >> 8 & 0xFF)
    };
    read().map_or(ColorPrimaries::Unspecified, primaries_from_khr_df)
}

/// True if `head` starts with the KTX2 identifier and a BC6H vkFormat.
pub fn is_bc6h_ktx2(head: &[u8]) -> bool {
    head.starts_with(&KTX2_IDENTIFIER) && matches!(u32_at(head, 12), Ok(VK_BC6H_UFLOAT | VK_BC6H_SFLOAT))
}

/// Reads the header of a BC6H KTX2 file (2D, one layer, one face, no supercompression) and
/// checks it as [`read_ktx2`] does, without reading the level index or the blocks.
pub fn read_ktx2_header(data: &[u8], limits: &Limits) -> Result<TextureHeader> {
    if !data.starts_with(&KTX2_IDENTIFIER) {
        return Err(if data.len() < 12 {
            Error::truncated("the KTX2 identifier")
        } else {
            Error::invalid("not a KTX2 file")
        });
    }
    let vk = u32_at(data, 12)?;
    let signed = match vk {
        VK_BC6H_UFLOAT => false,
        VK_BC6H_SFLOAT => true,
        other => {
            return Err(Error::unsupported(format!(
                "KTX2 vkFormat {other}; only BC6H_UFLOAT (143) and BC6H_SFLOAT (144) are supported"
            )))
        }
    };
    let width = u32_at(data, 20)?;
    let height = u32_at(data, 24)?;
    let depth = u32_at(data, 28)?;
    let layers = u32_at(data, 32)?;
    let faces = u32_at(data, 36)?;
    let level_count = u32_at(data, 40)?;
    let supercompression = u32_at(data, 44)?;
    if depth != 0 || layers > 1 || faces != 1 {
        return Err(Error::unsupported(format!(
            "KTX2 with depth {depth}, {layers} layers, {faces} faces: only single 2D textures are supported"
        )));
    }
    if supercompression != 0 {
        return Err(Error::unsupported(format!("KTX2 supercompression scheme {supercompression}")));
    }
    let levels = check_dims(width, height, level_count as u64, limits)?;
    Ok(TextureHeader { width, height, signed, levels })
}

/// Reads a BC6H KTX2 file (2D, one layer, one face, no supercompression, all mip levels).
pub fn read_ktx2(data: &[u8], limits: &Limits) -> Result<Bc6hTexture> {
    let TextureHeader { width, height, signed, levels } = read_ktx2_header(data, limits)?;
    let mut out = Vec::with_capacity(levels);
    for i in 0..levels {
        let entry = KTX2_LEVEL_INDEX + 24 * i;
        let offset = u64_at(data, entry)?;
        let length = u64_at(data, entry + 8)?;
        let (w, h) = level_size(width, height, i);
        let need = surface_bytes(w, h).ok_or_else(|| Error::invalid("KTX2 level size overflows"))?;
        if length != need as u64 {
            return Err(Error::invalid(format!("KTX2 level {i} ({w}x{h}) declares {length} bytes, expected {need}")));
        }
        let start = usize::try_from(offset).map_err(|_| Error::invalid("KTX2 level offset too large"))?;
        let level = data.get(start..start.saturating_add(need)).ok_or_else(|| {
            Error::truncated(format!("KTX2 level {i}: {need} bytes at offset {offset}, file has {}", data.len()))
        })?;
        limits.check_alloc(need as u64, "a KTX2 mip level")?;
        out.push(level.to_vec());
    }
    Ok(Bc6hTexture { width, height, signed, levels: out })
}

fn align(v: usize, to: usize) -> usize {
    v.div_ceil(to) * to
}

/// The data format descriptor of a BC6H texture (Khronos Data Format Specification 1.3,
/// "BC6H" descriptor: model 133, 4x4 texel blocks, 16 bytes, one 128-bit float sample) with
/// the colorPrimaries value `primaries`.
fn ktx2_dfd(signed: bool, primaries: u32) -> Vec<u8> {
    let mut qualifiers = KHR_DF_SAMPLE_DATATYPE_FLOAT;
    if signed {
        qualifiers |= KHR_DF_SAMPLE_DATATYPE_SIGNED;
    }
    let words: [u32; 11] = [
        4 + 24 + 16,         // dfdTotalSize
        0,                   // vendor Khronos, type basic
        2 | (24 + 16) << 16, // version 2, block size 40
        KHR_DF_MODEL_BC6H | primaries << 8 | KHR_DF_TRANSFER_LINEAR << 16,
        3 | 3 << 8,                                   // texel block 4x4x1x1
        16,                                           // bytesPlane0
        0,                                            // bytesPlane4..7
        127 << 16 | qualifiers << 24,                 // offset 0, 128 bits, colour
        0,                                            // sample position
        if signed { (-1.0f32).to_bits() } else { 0 }, // sampleLower
        1.0f32.to_bits(),                             // sampleUpper
    ];
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// Writes a BC6H KTX2 file: header, level index, DFD (recording `primaries`, one of
/// [`KTX2_PRIMARIES`]: any other is an error), a `KTXwriter` key, then the levels (smallest
/// first, each 16-byte aligned, as the KTX2 specification orders them).
pub fn write_ktx2(tex: &Bc6hTexture, primaries: ColorPrimaries) -> Result<Vec<u8>> {
    tex.validate()?;
    let primaries = khr_df_primaries(&primaries).ok_or_else(|| {
        Error::unsupported(format!("a KTX2 data format descriptor cannot record {} primaries", primaries.name()))
    })?;
    let n = tex.levels.len();
    let dfd_offset = KTX2_LEVEL_INDEX + 24 * n;
    let dfd = ktx2_dfd(tex.signed, primaries);
    let kvd_offset = dfd_offset + dfd.len();
    let mut kvd = Vec::new();
    let entry = b"KTXwriter\0hdrcodec-bc6h\0";
    kvd.extend_from_slice(&(entry.len() as u32).to_le_bytes());
    kvd.extend_from_slice(entry);
    kvd.resize(align(kvd.len(), 4), 0);
    let mut pos = align(kvd_offset + kvd.len(), 16);
    // Offsets: the smallest level comes first in the file.
    let mut offsets = vec![0usize; n];
    for i in (0..n).rev() {
        pos = align(pos, 16);
        offsets[i] = pos;
        pos += tex.levels[i].len();
    }
    let mut out = Vec::with_capacity(pos);
    out.extend_from_slice(&KTX2_IDENTIFIER);
    let vk = if tex.signed { VK_BC6H_SFLOAT } else { VK_BC6H_UFLOAT };
    for v in [vk, 1, tex.width, tex.height, 0, 0, 1, n as u32, 0] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [dfd_offset as u32, dfd.len() as u32, kvd_offset as u32, kvd.len() as u32] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&[0u8; 16]); // no supercompression global data
    for (i, level) in tex.levels.iter().enumerate() {
        for v in [offsets[i] as u64, level.len() as u64, level.len() as u64] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&kvd);
    for i in (0..n).rev() {
        out.resize(offsets[i], 0);
        out.extend_from_slice(&tex.levels[i]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::tests::texture;

    #[test]
    fn ktx2_round_trip() {
        for (w, h, n, s) in [(644, 874, 10, false), (5, 3, 1, true), (1, 1, 1, false), (17, 4, 5, true)] {
            let tex = texture(w, h, n, s);
            let limits = Limits::default();
            let ktx = write_ktx2(&tex, ColorPrimaries::Bt709).unwrap();
            assert_eq!(read_ktx2(&ktx, &limits).unwrap(), tex);
            assert!(is_bc6h_ktx2(&ktx));
        }
    }

    /// The colorPrimaries byte of the DFD our writer puts right after the level index.
    fn dfd_primaries_byte(ktx: &[u8], levels: usize) -> u8 {
        ktx[KTX2_LEVEL_INDEX + 24 * levels + 4 + 8 + 1]
    }

    #[test]
    fn primaries_are_written_and_read_back() {
        // Khronos Data Format Specification 1.3, section 5.6, khr_df_primaries_e.
        let want = [
            (ColorPrimaries::Unspecified, 0),
            (ColorPrimaries::Bt709, 1),
            (ColorPrimaries::Bt2020, 4),
            (ColorPrimaries::Xyz, 5),
            (ColorPrimaries::AcesAp0, 6),
            (ColorPrimaries::AcesAp1, 7),
            (ColorPrimaries::DisplayP3, 10),
            (ColorPrimaries::AdobeRgb, 11),
        ];
        assert_eq!(want.len(), KTX2_PRIMARIES.len());
        let tex = texture(5, 3, 2, false);
        for (p, v) in want {
            assert!(KTX2_PRIMARIES.contains(&p));
            let ktx = write_ktx2(&tex, p).unwrap();
            assert_eq!(dfd_primaries_byte(&ktx, 2), v, "{}", p.name());
            assert_eq!(read_ktx2_primaries(&ktx), p);
            assert_eq!(read_ktx2(&ktx, &Limits::default()).unwrap(), tex);
        }
        for p in [ColorPrimaries::DciP3, ColorPrimaries::Custom(ColorPrimaries::Bt709.chromaticities())] {
            assert!(matches!(write_ktx2(&tex, p), Err(Error::Unsupported { .. })), "{}", p.name());
        }
    }

    #[test]
    fn unknown_or_missing_primaries_read_as_unspecified() {
        let tex = texture(8, 8, 1, false);
        let ktx = write_ktx2(&tex, ColorPrimaries::Bt2020).unwrap();
        // The enumeration's spaces we do not name, values past its end, and a damaged DFD.
        for v in [2u8, 3, 8, 9, 12, 200, 255] {
            let mut bad = ktx.clone();
            bad[KTX2_LEVEL_INDEX + 24 + 13] = v;
            assert_eq!(read_ktx2_primaries(&bad), ColorPrimaries::Unspecified, "{v}");
            assert_eq!(read_ktx2(&bad, &Limits::default()).unwrap(), tex, "{v}: still a texture");
        }
        let mut vendor = ktx.clone();
        vendor[KTX2_LEVEL_INDEX + 24 + 4] = 1; // vendorId 1: not a Khronos basic descriptor
        assert_eq!(read_ktx2_primaries(&vendor), ColorPrimaries::Unspecified);
        let mut outside = ktx.clone();
        outside[48..52].copy_from_slice(&u32::MAX.to_le_bytes()); // dfdByteOffset past the end
        assert_eq!(read_ktx2_primaries(&outside), ColorPrimaries::Unspecified);
        let mut short = ktx.clone();
        short[52..56].copy_from_slice(&8u32.to_le_bytes()); // dfdByteLength too small
        assert_eq!(read_ktx2_primaries(&short), ColorPrimaries::Unspecified);
        for n in 0..60 {
            assert_eq!(read_ktx2_primaries(&ktx[..n]), ColorPrimaries::Unspecified, "cut at {n}");
        }
        assert_eq!(read_ktx2_primaries(&ktx), ColorPrimaries::Bt2020);
    }

    #[test]
    fn absurd_ktx2_mip_counts_are_errors() {
        let tex = texture(8, 8, 1, false);
        let mut ktx = write_ktx2(&tex, ColorPrimaries::Bt709).unwrap();
        ktx[40..44].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(read_ktx2(&ktx, &Limits::default()), Err(Error::Invalid { .. })));
    }
}
