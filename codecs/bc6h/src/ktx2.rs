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
use crate::texture::{check_dims, level_size, Bc6hTexture, TextureHeader};
use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
use hdrcodec_core::{ColorPrimaries, Error, Limits, Result};

/// `VK_FORMAT_BC6H_UFLOAT_BLOCK`.
pub const VK_BC6H_UFLOAT: u32 = 143;
/// `VK_FORMAT_BC6H_SFLOAT_BLOCK`.
pub const VK_BC6H_SFLOAT: u32 = 144;

/// The KTX2 file identifier `«KTX 20»\r\n\x1A\n`.
pub const KTX2_IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];

/// Offset of vkFormat, the first field after the identifier.
const KTX2_VK_FORMAT: u64 = 12;
/// Offset of the index (dfdByteOffset, dfdByteLength, kvd..., sgd...).
const KTX2_INDEX: u64 = 48;
/// Header (48) + index (32).
const KTX2_LEVEL_INDEX: usize = 80;
/// Bytes of one level index entry: byteOffset, byteLength, uncompressedByteLength (u64 each).
const KTX2_LEVEL_ENTRY: usize = 24;
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
    let read = || -> Result<Option<u32>> {
        let mut index = ByteReader::le(data).at(KTX2_INDEX);
        let offset = index.u32("the KTX2 dfdByteOffset")?;
        let length = index.u32("the KTX2 dfdByteLength")?;
        let mut dfd = ByteReader::le(index.bytes_at(offset.into(), length.into(), "the KTX2 DFD")?);
        if length < 16 || dfd.at(4).u32("the DFD block's vendor and type")? != 0 {
            return Ok(None);
        }
        dfd.seek(12);
        Ok(Some(dfd.u32("the DFD's colour model and primaries")? >> 8 & 0xFF))
    };
    read().ok().flatten().map_or(ColorPrimaries::Unspecified, primaries_from_khr_df)
}

/// True if `head` starts with the KTX2 identifier and a BC6H vkFormat.
pub fn is_bc6h_ktx2(head: &[u8]) -> bool {
    head.starts_with(&KTX2_IDENTIFIER)
        && matches!(ByteReader::le(head).at(KTX2_VK_FORMAT).u32("the vkFormat"), Ok(VK_BC6H_UFLOAT | VK_BC6H_SFLOAT))
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
    let mut r = ByteReader::le(data).at(KTX2_VK_FORMAT);
    let vk = r.u32("the KTX2 vkFormat")?;
    let signed = match vk {
        VK_BC6H_UFLOAT => false,
        VK_BC6H_SFLOAT => true,
        other => {
            return Err(Error::unsupported(format!(
                "KTX2 vkFormat {other}; only BC6H_UFLOAT (143) and BC6H_SFLOAT (144) are supported"
            )))
        }
    };
    r.skip(4, "the KTX2 typeSize")?;
    let width = r.u32("the KTX2 pixelWidth")?;
    let height = r.u32("the KTX2 pixelHeight")?;
    let depth = r.u32("the KTX2 pixelDepth")?;
    let layers = r.u32("the KTX2 layerCount")?;
    let faces = r.u32("the KTX2 faceCount")?;
    let level_count = r.u32("the KTX2 levelCount")?;
    let supercompression = r.u32("the KTX2 supercompressionScheme")?;
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
    let (header, levels) = ktx2_levels(data, limits)?;
    Bc6hTexture::copied(header, &levels, limits)
}

/// The header of a BC6H KTX2 file and its mip levels (level 0 first), borrowed from `data`
/// (what decoding reads, without a copy); checked as [`read_ktx2`] checks them.
pub fn ktx2_levels<'a>(data: &'a [u8], limits: &Limits) -> Result<(TextureHeader, Vec<&'a [u8]>)> {
    let header = read_ktx2_header(data, limits)?;
    let TextureHeader { width, height, levels, .. } = header;
    let file = ByteReader::le(data);
    let mut out = Vec::with_capacity(levels);
    for i in 0..levels {
        // The entry's byteOffset and byteLength (its uncompressedByteLength is not needed).
        let mut entry = file.at((KTX2_LEVEL_INDEX + KTX2_LEVEL_ENTRY * i) as u64);
        let offset = entry.u64(format_args!("the KTX2 level index entry {i}"))?;
        let length = entry.u64(format_args!("the KTX2 level index entry {i}"))?;
        let (w, h) = level_size(width, height, i);
        let need = surface_bytes(w, h).ok_or_else(|| Error::invalid("KTX2 level size overflows"))?;
        if length != need as u64 {
            return Err(Error::invalid(format!("KTX2 level {i} ({w}x{h}) declares {length} bytes, expected {need}")));
        }
        out.push(file.bytes_at(offset, length, format_args!("KTX2 level {i} ({w}x{h})"))?);
    }
    Ok((header, out))
}

fn align(v: usize, to: usize) -> usize {
    v.div_ceil(to) * to
}

/// Words of the data format descriptor [`ktx2_dfd`] writes.
const KTX2_DFD_WORDS: usize = 11;

/// The data format descriptor of a BC6H texture (Khronos Data Format Specification 1.3,
/// "BC6H" descriptor: model 133, 4x4 texel blocks, 16 bytes, one 128-bit float sample) with
/// the colorPrimaries value `primaries`.
fn ktx2_dfd(signed: bool, primaries: u32) -> [u32; KTX2_DFD_WORDS] {
    let mut qualifiers = KHR_DF_SAMPLE_DATATYPE_FLOAT;
    if signed {
        qualifiers |= KHR_DF_SAMPLE_DATATYPE_SIGNED;
    }
    [
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
    ]
}

/// The key/value data: one `KTXwriter` entry (its u32 length, then key and value, each ended by
/// NUL), padded to 4 bytes.
const KTX2_KVD: &[u8] = b"KTXwriter\0hdrcodec-bc6h\0";
const KTX2_KVD_LEN: usize = (4 + KTX2_KVD.len()).next_multiple_of(4);

/// Writes a BC6H KTX2 file: header, level index, DFD (recording `primaries`, one of
/// [`KTX2_PRIMARIES`]: any other is an error), a `KTXwriter` key, then the levels (smallest
/// first, each 16-byte aligned, as the KTX2 specification orders them).
pub fn write_ktx2(tex: &Bc6hTexture, primaries: ColorPrimaries) -> Result<Vec<u8>> {
    tex.validate()?;
    let primaries = khr_df_primaries(&primaries).ok_or_else(|| {
        Error::unsupported(format!("a KTX2 data format descriptor cannot record {} primaries", primaries.name()))
    })?;
    let n = tex.levels.len();
    let (header, offsets) = ktx2_header(tex.width, tex.height, tex.signed, n, primaries)?;
    let mut w = ByteWriter::from_vec(header, ByteOrder::Little);
    for i in (0..n).rev() {
        w.align(16);
        debug_assert_eq!(w.len() as u64, offsets[i]);
        w.bytes(&tex.levels[i]);
    }
    Ok(w.into_vec())
}

/// The KTX2 header, level index, DFD (with colorPrimaries `primaries`) and key/value data of a
/// `width` x `height` BC6H texture with `levels` mip levels, and where each level goes: the
/// smallest level comes first in the file, each at a multiple of 16.
pub(crate) fn ktx2_header(
    width: u32,
    height: u32,
    signed: bool,
    levels: usize,
    primaries: u32,
) -> Result<(Vec<u8>, Vec<u64>)> {
    let n = levels;
    let dfd_offset = KTX2_LEVEL_INDEX + KTX2_LEVEL_ENTRY * n;
    let dfd_len = 4 * KTX2_DFD_WORDS;
    let kvd_offset = dfd_offset + dfd_len;
    let sizes = (0..n)
        .map(|i| {
            let (w, h) = level_size(width, height, i);
            surface_bytes(w, h).map(|b| b as u64).ok_or_else(|| Error::invalid("KTX2 level size overflows"))
        })
        .collect::<Result<Vec<u64>>>()?;
    let mut pos = align(kvd_offset + KTX2_KVD_LEN, 16) as u64;
    let mut offsets = vec![0u64; n];
    for i in (0..n).rev() {
        pos = pos.div_ceil(16) * 16;
        offsets[i] = pos;
        pos += sizes[i];
    }
    let mut w = ByteWriter::new(ByteOrder::Little);
    w.bytes(&KTX2_IDENTIFIER);
    let vk = if signed { VK_BC6H_SFLOAT } else { VK_BC6H_UFLOAT };
    for v in [vk, 1, width, height, 0, 0, 1, n as u32, 0] {
        w.u32(v);
    }
    for v in [dfd_offset, dfd_len, kvd_offset, KTX2_KVD_LEN] {
        w.u32(v as u32);
    }
    w.zeros(16); // no supercompression global data
    for i in 0..n {
        for v in [offsets[i], sizes[i], sizes[i]] {
            w.u64(v);
        }
    }
    for v in ktx2_dfd(signed, primaries) {
        w.u32(v);
    }
    w.u32(KTX2_KVD.len() as u32);
    w.bytes(KTX2_KVD);
    w.align(4);
    debug_assert_eq!(w.len(), kvd_offset + KTX2_KVD_LEN);
    Ok((w.into_vec(), offsets))
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
    fn a_cut_ktx2_names_the_field_or_level_it_ends_in() {
        let ktx = write_ktx2(&texture(8, 8, 2, false), ColorPrimaries::Bt709).unwrap();
        // Index at 80, DFD at 128, key/value data at 172; level 1 (4x4, 16 bytes) comes first,
        // at 208, level 0 (8x8, 64 bytes) last, at 224.
        assert_eq!(ktx.len(), 224 + 64);
        for (cut, what) in [
            (14, "the KTX2 vkFormat"),
            (30, "the KTX2 pixelDepth"),
            (46, "the KTX2 supercompressionScheme"),
            (90, "the KTX2 level index entry 0"),
            (250, "KTX2 level 0 (8x8) (bytes 224..288 of a 250-byte input)"),
            (215, "KTX2 level 0 (8x8)"),
        ] {
            let e = read_ktx2(&ktx[..cut], &Limits::default()).unwrap_err();
            assert!(matches!(e, Error::Truncated { .. }) && e.to_string().contains(what), "cut at {cut}: {e}");
        }
    }

    #[test]
    fn absurd_ktx2_mip_counts_are_errors() {
        let tex = texture(8, 8, 1, false);
        let mut ktx = write_ktx2(&tex, ColorPrimaries::Bt709).unwrap();
        ktx[40..44].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(read_ktx2(&ktx, &Limits::default()), Err(Error::Invalid { .. })));
    }
}
