//! BC6H textures in DDS files (with the DX10 header), with mip levels.
//!
//! Microsoft "DDS programming guide" (`DDS_HEADER`, `DDS_HEADER_DXT10`), formats
//! `DXGI_FORMAT_BC6H_UF16` (95) and `DXGI_FORMAT_BC6H_SF16` (96). The parser checks every size
//! against the data and the caller's [`Limits`] before allocating and never panics.
use crate::decode::surface_bytes;
use crate::texture::{check_dims, level_size, Bc6hTexture, TextureHeader};
use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
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
/// Offset of the FourCC in DDS_PIXELFORMAT.
const DDS_FOURCC_OFFSET: u64 = 84;
/// Offset of DDS_HEADER_DXT10 (its first field is the DXGI format).
const DDS_DXT10_OFFSET: u64 = 4 + 124;
/// Magic + DDS_HEADER (124) + DDS_HEADER_DXT10 (20).
const DDS_DATA_OFFSET: usize = 4 + 124 + 20;

/// True if `head` starts like a DDS file with a DX10 header and a BC6H format.
pub fn is_bc6h_dds(head: &[u8]) -> bool {
    let r = ByteReader::le(head);
    head.starts_with(DDS_MAGIC)
        && r.bytes_at(DDS_FOURCC_OFFSET, 4, "the DDS FourCC").is_ok_and(|f| f == b"DX10")
        && matches!(r.at(DDS_DXT10_OFFSET).u32("the DXGI format"), Ok(DXGI_BC6H_UF16 | DXGI_BC6H_SF16))
}

/// Reads the header of a BC6H DDS file (DX10 header, 2D texture) and checks it as [`read_dds`]
/// does, without reading the blocks.
pub fn read_dds_header(data: &[u8], limits: &Limits) -> Result<TextureHeader> {
    if !data.starts_with(DDS_MAGIC) {
        return Err(if data.len() < 4 { Error::truncated("the DDS magic") } else { Error::invalid("not a DDS file") });
    }
    // DDS_HEADER, after the magic: size, flags, height, width, pitch or linear size, depth,
    // mip count, 11 reserved words, then DDS_PIXELFORMAT (size, flags, FourCC, ...).
    let mut r = ByteReader::le(data).at(4);
    if r.u32("the DDS header size")? != 124 {
        return Err(Error::invalid("DDS header size is not 124"));
    }
    let flags = r.u32("the DDS header flags")?;
    let height = r.u32("the DDS height")?;
    let width = r.u32("the DDS width")?;
    r.skip(4, "the DDS pitch")?;
    let depth = r.u32("the DDS depth")?;
    let mips = r.u32("the DDS mip count")?;
    r.skip(11 * 4 + 4, "the DDS header")?;
    let pixel_format_flags = r.u32("the DDS pixel format")?;
    let four_cc = r.bytes(4, "the DDS pixel format")?;
    if pixel_format_flags & DDPF_FOURCC == 0 || four_cc != b"DX10" {
        return Err(Error::unsupported(format!(
            "DDS without a DX10 header (FourCC {:?}): BC6H needs DXGI_FORMAT 95 or 96",
            String::from_utf8_lossy(four_cc)
        )));
    }
    // DDS_HEADER_DXT10: DXGI format, resource dimension, misc flags, array size.
    r.seek(DDS_DXT10_OFFSET);
    let dxgi = r.u32("the DDS DXGI format")?;
    let signed = match dxgi {
        DXGI_BC6H_UF16 => false,
        DXGI_BC6H_SF16 => true,
        other => {
            return Err(Error::unsupported(format!(
                "DDS DXGI format {other}; only BC6H_UF16 (95) and BC6H_SF16 (96) are supported"
            )))
        }
    };
    let dimension = r.u32("the DDS resource dimension")?;
    let misc = r.u32("the DDS misc flags")?;
    let array_size = r.u32("the DDS array size")?;
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
    let (header, levels) = dds_levels(data, limits)?;
    Bc6hTexture::copied(header, &levels, limits)
}

/// The header of a BC6H DDS file and its mip levels, borrowed from `data` (what decoding
/// reads, without a copy); checked as [`read_dds`] checks them.
pub fn dds_levels<'a>(data: &'a [u8], limits: &Limits) -> Result<(TextureHeader, Vec<&'a [u8]>)> {
    let header = read_dds_header(data, limits)?;
    let TextureHeader { width, height, levels, .. } = header;
    let mut r = ByteReader::le(data).at(DDS_DATA_OFFSET as u64);
    let mut out = Vec::with_capacity(levels);
    for i in 0..levels {
        let (w, h) = level_size(width, height, i);
        let n = surface_bytes(w, h).ok_or_else(|| Error::invalid("DDS level size overflows"))?;
        out.push(r.bytes(n as u64, format_args!("DDS mip level {i} ({w}x{h})"))?);
    }
    Ok((header, out))
}

/// Writes a BC6H DDS file (DDS_HEADER + DDS_HEADER_DXT10, 2D, one array element).
pub fn write_dds(tex: &Bc6hTexture) -> Result<Vec<u8>> {
    tex.validate()?;
    let total: usize = tex.levels.iter().map(Vec::len).sum();
    let mut w = ByteWriter::from_vec(Vec::with_capacity(DDS_DATA_OFFSET + total), ByteOrder::Little);
    dds_header(&mut w, tex.width, tex.height, tex.signed, tex.levels.len());
    for level in &tex.levels {
        w.bytes(level);
    }
    Ok(w.into_vec())
}

/// The DDS header (magic, DDS_HEADER, DDS_HEADER_DXT10) of a `width` x `height` BC6H texture
/// with `levels` mip levels: what precedes the levels, which follow largest first.
pub(crate) fn dds_header(w: &mut ByteWriter, width: u32, height: u32, signed: bool, levels: usize) {
    w.bytes(DDS_MAGIC);
    let mipmapped = levels > 1;
    let mut flags = DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | DDSD_LINEARSIZE;
    if mipmapped {
        flags |= DDSD_MIPMAPCOUNT;
    }
    w.u32(124);
    w.u32(flags);
    w.u32(height);
    w.u32(width);
    // Linear size of level 0 (a size over 4 GiB cannot be said; readers recompute it).
    w.u32(surface_bytes(width, height).unwrap_or(0).min(u32::MAX as usize) as u32);
    w.u32(0); // depth
    w.u32(levels as u32);
    w.zeros(11 * 4); // reserved1
                     // DDS_PIXELFORMAT: size 32, FourCC "DX10".
    w.u32(32);
    w.u32(DDPF_FOURCC);
    w.bytes(b"DX10");
    w.zeros(5 * 4); // bit count, masks
    let mut caps = DDSCAPS_TEXTURE;
    if mipmapped {
        caps |= DDSCAPS_COMPLEX | DDSCAPS_MIPMAP;
    }
    w.u32(caps);
    w.zeros(4 * 4); // caps2..4, reserved2
    debug_assert_eq!(w.len() as u64, DDS_DXT10_OFFSET);
    w.u32(if signed { DXGI_BC6H_SF16 } else { DXGI_BC6H_UF16 });
    w.u32(DDS_RESOURCE_DIMENSION_TEXTURE2D);
    w.u32(0); // misc flags
    w.u32(1); // array size
    w.u32(0); // misc flags 2: DDS_ALPHA_MODE_UNKNOWN
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
    fn a_cut_dds_names_the_field_or_level_it_ends_in() {
        let dds = write_dds(&texture(8, 8, 2, false)).unwrap();
        for (cut, what) in [
            (6, "the DDS header size"),
            (18, "the DDS width"),
            (86, "the DDS pixel format"),
            (130, "the DDS DXGI format"),
            (140, "the DDS array size"),
            (DDS_DATA_OFFSET + 10, "DDS mip level 0 (8x8) (bytes 148..212 of a 158-byte input)"),
            (dds.len() - 1, "DDS mip level 1 (4x4)"),
        ] {
            let e = read_dds(&dds[..cut], &Limits::default()).unwrap_err();
            assert!(matches!(e, Error::Truncated { .. }) && e.to_string().contains(what), "cut at {cut}: {e}");
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
