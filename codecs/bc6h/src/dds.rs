//! BC6H textures in DDS files (with the DX10 header), with mip levels.
//!
//! Microsoft "DDS programming guide" (`DDS_HEADER`, `DDS_HEADER_DXT10`), formats
//! `DXGI_FORMAT_BC6H_UF16` (95) and `DXGI_FORMAT_BC6H_SF16` (96). The parser checks every size
//! against the data and the caller's [`Limits`] before allocating and never panics.
use crate::decode::surface_bytes;
use crate::texture::{check_dims, level_size, u32_at, Bc6hTexture, TextureHeader};
use hdrcodec_core::{Error, Limits, Result};

/// `DXGI_FORMAT_BC6H_UF16`.
pub const DXGI_BC6H_UF16: u32 = 95;
/// `DXGI_FORMAT_BC6H_SF16`.
pub const DXGI_BC6H_SF16: u32 = 96;

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

/// Reads the header of a BC6H DDS file (DX10 header, 2D texture) and checks it as [`read_dds`]
/// does, without reading the blocks.
pub fn read_dds_header(data: &[u8], limits: &Limits) -> Result<TextureHeader> {
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
    Ok(TextureHeader { width, height, signed, levels })
}

/// Reads a BC6H DDS file (DX10 header, 2D texture, first array element, all mip levels).
pub fn read_dds(data: &[u8], limits: &Limits) -> Result<Bc6hTexture> {
    let TextureHeader { width, height, signed, levels } = read_dds_header(data, limits)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::tests::texture;

    #[test]
    fn dds_round_trip() {
        for (w, h, n, s) in [(644, 874, 10, false), (5, 3, 1, true), (1, 1, 1, false), (17, 4, 5, true)] {
            let tex = texture(w, h, n, s);
            let limits = Limits::default();
            assert_eq!(read_dds(&write_dds(&tex).unwrap(), &limits).unwrap(), tex);
            assert!(is_bc6h_dds(&write_dds(&tex).unwrap()));
        }
    }

    #[test]
    fn absurd_dds_mip_counts_and_formats_are_errors() {
        let tex = texture(8, 8, 1, false);
        let mut dds = write_dds(&tex).unwrap();
        dds[28..32].copy_from_slice(&1000u32.to_le_bytes());
        assert!(matches!(read_dds(&dds, &Limits::default()), Err(Error::Invalid { .. })));
        dds[28..32].copy_from_slice(&1u32.to_le_bytes());
        dds[128..132].copy_from_slice(&98u32.to_le_bytes()); // BC7
        assert!(matches!(read_dds(&dds, &Limits::default()), Err(Error::Unsupported { .. })));
    }
}
