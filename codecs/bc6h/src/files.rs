//! BC6H textures in DDS (with the DX10 header) and KTX2 files, with mip levels.
//!
//! DDS: Microsoft "DDS programming guide" (`DDS_HEADER`, `DDS_HEADER_DXT10`), formats
//! `DXGI_FORMAT_BC6H_UF16` (95) and `DXGI_FORMAT_BC6H_SF16` (96). KTX2: Khronos "KTX File Format
//! Specification 2.0" (header, level index, data format descriptor), formats
//! `VK_FORMAT_BC6H_UFLOAT_BLOCK` (143) and `VK_FORMAT_BC6H_SFLOAT_BLOCK` (144), no
//! supercompression. Parsers check every size against the data and the caller's [`Limits`]
//! before allocating and never panic.
use crate::decode::{decode_surface, surface_bytes};
use hdrcodec_core::{Error, Limits, Result};

/// `DXGI_FORMAT_BC6H_UF16`.
pub const DXGI_BC6H_UF16: u32 = 95;
/// `DXGI_FORMAT_BC6H_SF16`.
pub const DXGI_BC6H_SF16: u32 = 96;
/// `VK_FORMAT_BC6H_UFLOAT_BLOCK`.
pub const VK_BC6H_UFLOAT: u32 = 143;
/// `VK_FORMAT_BC6H_SFLOAT_BLOCK`.
pub const VK_BC6H_SFLOAT: u32 = 144;

/// The KTX2 file identifier `«KTX 20»\r\n\x1A\n`.
pub const KTX2_IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];

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

fn u32_at(d: &[u8], off: usize) -> Result<u32> {
    d.get(off..off + 4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .ok_or_else(|| Error::truncated("the file header"))
}

fn u64_at(d: &[u8], off: usize) -> Result<u64> {
    Ok(u32_at(d, off)? as u64 | (u32_at(d, off + 4)? as u64) << 32)
}

/// Checks the declared size against `limits` and the mip count against the size; returns the
/// number of levels to read (a declared 0 means 1).
fn check_dims(width: u32, height: u32, levels: u64, limits: &Limits) -> Result<usize> {
    limits.check_dimensions(width as u64, height as u64)?;
    let full = full_mip_count(width, height);
    if levels > full as u64 {
        return Err(Error::invalid(format!("{levels} mip levels for a {width}x{height} texture (at most {full})")));
    }
    Ok(levels.max(1) as usize)
}

// ---------------------------------------------------------------------------------------- DDS

const DDS_MAGIC: &[u8; 4] = b"DDS ";
const DDSD_CAPS: u32 = 0x1;
const DDSD_HEIGHT: u32 = 0x2;
const DDSD_WIDTH: u32 = 0x4;
const DDSD_PIXELFORMAT: u32 = 0x1000;
const DDSD_MIPMAPCOUNT: u32 = 0x20000;
const DDSD_LINEARSIZE: u32 = 0x80000;
const DDPF_FOURCC: u32 = 0x4;
const DDSCAPS_COMPLEX: u32 = 0x8;
const DDSCAPS_TEXTURE: u32 = 0x1000;
const DDSCAPS_MIPMAP: u32 = 0x40_0000;
const DDS_RESOURCE_DIMENSION_TEXTURE2D: u32 = 3;
const DDS_RESOURCE_MISC_TEXTURECUBE: u32 = 0x4;
/// Magic + DDS_HEADER (124) + DDS_HEADER_DXT10 (20).
const DDS_DATA_OFFSET: usize = 4 + 124 + 20;

/// True if `head` starts like a DDS file with a DX10 header and a BC6H format.
pub fn is_bc6h_dds(head: &[u8]) -> bool {
    head.starts_with(DDS_MAGIC)
        && head.get(84..88) == Some(b"DX10")
        && matches!(u32_at(head, 128), Ok(DXGI_BC6H_UF16 | DXGI_BC6H_SF16))
}

/// Reads a BC6H DDS file (DX10 header, 2D texture, first array element, all mip levels).
pub fn read_dds(data: &[u8], limits: &Limits) -> Result<Bc6hTexture> {
    if !data.starts_with(DDS_MAGIC) {
        return Err(if data.len() < 4 { Error::truncated("the DDS magic") } else { Error::invalid("not a DDS file") });
    }
    if u32_at(data, 4)? != 124 {
        return Err(Error::invalid("DDS header size is not 124"));
    }
    let flags = u32_at(data, 8)?;
    let height = u32_at(data, 12)?;
    let width = u32_at(data, 16)?;
    let depth = u32_at(data, 24)?;
    let mips = u32_at(data, 28)?;
    let four_cc = data.get(84..88).ok_or_else(|| Error::truncated("the DDS pixel format"))?;
    if u32_at(data, 80)? & DDPF_FOURCC == 0 || four_cc != b"DX10" {
        return Err(Error::unsupported(format!(
            "DDS without a DX10 header (FourCC {:?}): BC6H needs DXGI_FORMAT 95 or 96",
            String::from_utf8_lossy(four_cc)
        )));
    }
    let dxgi = u32_at(data, 128)?;
    let signed = match dxgi {
        DXGI_BC6H_UF16 => false,
        DXGI_BC6H_SF16 => true,
        other => {
            return Err(Error::unsupported(format!(
                "DDS DXGI format {other}; only BC6H_UF16 (95) and BC6H_SF16 (96) are supported"
            )))
        }
    };
    let dimension = u32_at(data, 132)?;
    let misc = u32_at(data, 136)?;
    let array_size = u32_at(data, 140)?;
    if dimension != DDS_RESOURCE_DIMENSION_TEXTURE2D || (flags & 0x80_0000 != 0 && depth > 1) {
        return Err(Error::unsupported(format!("DDS resource dimension {dimension}: only 2D textures are supported")));
    }
    if misc & DDS_RESOURCE_MISC_TEXTURECUBE != 0 {
        return Err(Error::unsupported("DDS cube maps"));
    }
    if array_size == 0 {
        return Err(Error::invalid("DDS array size 0"));
    }
    // DDSD_MIPMAPCOUNT is often missing from writers' flags; a count of 0 means one level.
    let levels = check_dims(width, height, mips as u64, limits)?;
    let mut pos = DDS_DATA_OFFSET;
    let mut out = Vec::with_capacity(levels);
    for i in 0..levels {
        let (w, h) = level_size(width, height, i);
        let n = surface_bytes(w, h).ok_or_else(|| Error::invalid("DDS level size overflows"))?;
        let level = data.get(pos..pos.saturating_add(n)).ok_or_else(|| {
            Error::truncated(format!("DDS mip level {i} ({w}x{h}: {n} bytes at offset {pos}, file has {})", data.len()))
        })?;
        limits.check_alloc(n as u64, "a DDS mip level")?;
        out.push(level.to_vec());
        pos += n;
    }
    Ok(Bc6hTexture { width, height, signed, levels: out })
}

/// Writes a BC6H DDS file (DDS_HEADER + DDS_HEADER_DXT10, 2D, one array element).
pub fn write_dds(tex: &Bc6hTexture) -> Result<Vec<u8>> {
    tex.validate()?;
    let total: usize = tex.levels.iter().map(Vec::len).sum();
    let mut out = Vec::with_capacity(DDS_DATA_OFFSET + total);
    let put = |v: u32, out: &mut Vec<u8>| out.extend_from_slice(&v.to_le_bytes());
    out.extend_from_slice(DDS_MAGIC);
    let mipmapped = tex.levels.len() > 1;
    let mut flags = DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | DDSD_LINEARSIZE;
    if mipmapped {
        flags |= DDSD_MIPMAPCOUNT;
    }
    put(124, &mut out);
    put(flags, &mut out);
    put(tex.height, &mut out);
    put(tex.width, &mut out);
    put(tex.levels[0].len() as u32, &mut out); // linear size of level 0
    put(0, &mut out); // depth
    put(tex.levels.len() as u32, &mut out);
    for _ in 0..11 {
        put(0, &mut out);
    }
    // DDS_PIXELFORMAT: size 32, FourCC "DX10".
    put(32, &mut out);
    put(DDPF_FOURCC, &mut out);
    out.extend_from_slice(b"DX10");
    for _ in 0..5 {
        put(0, &mut out);
    }
    let mut caps = DDSCAPS_TEXTURE;
    if mipmapped {
        caps |= DDSCAPS_COMPLEX | DDSCAPS_MIPMAP;
    }
    put(caps, &mut out);
    for _ in 0..4 {
        put(0, &mut out); // caps2..4, reserved2
    }
    put(if tex.signed { DXGI_BC6H_SF16 } else { DXGI_BC6H_UF16 }, &mut out);
    put(DDS_RESOURCE_DIMENSION_TEXTURE2D, &mut out);
    put(0, &mut out); // misc flags
    put(1, &mut out); // array size
    put(0, &mut out); // misc flags 2: DDS_ALPHA_MODE_UNKNOWN
    debug_assert_eq!(out.len(), DDS_DATA_OFFSET);
    for level in &tex.levels {
        out.extend_from_slice(level);
    }
    Ok(out)
}

// --------------------------------------------------------------------------------------- KTX2

/// Header (48) + index (32).
const KTX2_LEVEL_INDEX: usize = 80;
/// KHR_DF_MODEL_BC6H (Khronos Data Format Specification 1.3, colorModel enumeration: 133;
/// 131 is KHR_DF_MODEL_BC4).
const KHR_DF_MODEL_BC6H: u32 = 133;
const KHR_DF_PRIMARIES_BT709: u32 = 1;
const KHR_DF_TRANSFER_LINEAR: u32 = 1;
const KHR_DF_SAMPLE_DATATYPE_FLOAT: u32 = 0x80;
const KHR_DF_SAMPLE_DATATYPE_SIGNED: u32 = 0x40;

/// True if `head` starts with the KTX2 identifier and a BC6H vkFormat.
pub fn is_bc6h_ktx2(head: &[u8]) -> bool {
    head.starts_with(&KTX2_IDENTIFIER) && matches!(u32_at(head, 12), Ok(VK_BC6H_UFLOAT | VK_BC6H_SFLOAT))
}

/// Reads a BC6H KTX2 file (2D, one layer, one face, no supercompression, all mip levels).
pub fn read_ktx2(data: &[u8], limits: &Limits) -> Result<Bc6hTexture> {
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
/// "BC6H" descriptor: model 133, 4x4 texel blocks, 16 bytes, one 128-bit float sample).
fn ktx2_dfd(signed: bool) -> Vec<u8> {
    let mut qualifiers = KHR_DF_SAMPLE_DATATYPE_FLOAT;
    if signed {
        qualifiers |= KHR_DF_SAMPLE_DATATYPE_SIGNED;
    }
    let words: [u32; 11] = [
        4 + 24 + 16,         // dfdTotalSize
        0,                   // vendor Khronos, type basic
        2 | (24 + 16) << 16, // version 2, block size 40
        KHR_DF_MODEL_BC6H | KHR_DF_PRIMARIES_BT709 << 8 | KHR_DF_TRANSFER_LINEAR << 16,
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

/// Writes a BC6H KTX2 file: header, level index, DFD, a `KTXwriter` key, then the levels
/// (smallest first, each 16-byte aligned, as the KTX2 specification orders them).
pub fn write_ktx2(tex: &Bc6hTexture) -> Result<Vec<u8>> {
    tex.validate()?;
    let n = tex.levels.len();
    let dfd_offset = KTX2_LEVEL_INDEX + 24 * n;
    let dfd = ktx2_dfd(tex.signed);
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

    fn texture(width: u32, height: u32, levels: usize, signed: bool) -> Bc6hTexture {
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
    fn dds_and_ktx2_round_trip() {
        for (w, h, n, s) in [(644, 874, 10, false), (5, 3, 1, true), (1, 1, 1, false), (17, 4, 5, true)] {
            let tex = texture(w, h, n, s);
            let limits = Limits::default();
            assert_eq!(read_dds(&write_dds(&tex).unwrap(), &limits).unwrap(), tex);
            assert_eq!(read_ktx2(&write_ktx2(&tex).unwrap(), &limits).unwrap(), tex);
            assert!(is_bc6h_dds(&write_dds(&tex).unwrap()));
            assert!(is_bc6h_ktx2(&write_ktx2(&tex).unwrap()));
        }
    }

    #[test]
    fn absurd_mip_counts_and_formats_are_errors() {
        let tex = texture(8, 8, 1, false);
        let mut dds = write_dds(&tex).unwrap();
        dds[28..32].copy_from_slice(&1000u32.to_le_bytes());
        assert!(matches!(read_dds(&dds, &Limits::default()), Err(Error::Invalid { .. })));
        dds[28..32].copy_from_slice(&1u32.to_le_bytes());
        dds[128..132].copy_from_slice(&98u32.to_le_bytes()); // BC7
        assert!(matches!(read_dds(&dds, &Limits::default()), Err(Error::Unsupported { .. })));
        let mut ktx = write_ktx2(&tex).unwrap();
        ktx[40..44].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(read_ktx2(&ktx, &Limits::default()), Err(Error::Invalid { .. })));
        assert!(Bc6hTexture { levels: vec![], ..tex.clone() }.validate().is_err());
    }
}
