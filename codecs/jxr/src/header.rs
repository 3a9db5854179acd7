//! The codestream headers (T.832 8.3): IMAGE_HEADER, IMAGE_PLANE_HEADER (primary and alpha),
//! their quantizer sets, INDEX_TABLE, SUBSEQUENT_BYTES and PROFILE_LEVEL_INFO.
//!
//! Where jxrlib (`strdec.c: ReadWMIHeader, ReadImagePlaneHeader, readIndexTable`) reads the
//! syntax differently from T.832, this module follows jxrlib, which wrote and reads nearly
//! every JPEG XR file:
//! - the four bits HARD_TILING_FLAG + RESERVED_C are one "sub-version": 0 (HD Photo 1.0), 1
//!   (soft tiles) or 9 (hard tiles); anything else is rejected;
//! - RESERVED_D is "tile stretch": when set, 8 bits per tile follow the tile sizes;
//! - RESERVED_I = 1 means "the LP band uses the DC quantizers" (the LP uniform flag is then
//!   absent), RESERVED_J = 1 the same for HP and LP;
//! - PREMULTIPLIED_ALPHA_FLAG is read and ignored (premultiplication comes from the pixel
//!   format);
//! - NCOMPONENT reads 4 bits of channel count and 4 reserved bits (no 12-bit escape; jxrlib
//!   has at most 16 channels);
//! - a window whose extended size is not a multiple of 16 is the legacy layout in which the
//!   coded sizes already include the right and bottom margins.

use crate::bits::BitReader;
use hdrcodec_core::{Error, Result};

/// Most channels a plane may have (jxrlib's MAX_CHANNELS).
pub const MAX_CHANNELS: usize = 16;

/// Most tiles per row or column (12-bit counts).
const MAX_TILES: usize = 4096;

/// INTERNAL_CLR_FMT (T.832 Table 13).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClrFmt {
    /// One channel.
    YOnly,
    /// Luma and two chroma channels at half resolution both ways.
    Yuv420,
    /// Luma and two chroma channels at half horizontal resolution.
    Yuv422,
    /// Three full-resolution channels.
    Yuv444,
    /// Four channels (CMYK).
    Yuvk,
    /// N independent channels.
    NComponent,
}

impl ClrFmt {
    /// True for the formats whose chroma channels share one YUV coding path (420, 422, 444).
    pub fn is_yuv(self) -> bool {
        matches!(self, ClrFmt::Yuv420 | ClrFmt::Yuv422 | ClrFmt::Yuv444)
    }
}

/// BANDS_PRESENT (T.832 Table 15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Bands {
    /// DC, LP, HP and flexbits.
    All = 0,
    /// No flexbits.
    NoFlexbits = 1,
    /// DC and LP only.
    NoHighpass = 2,
    /// DC only.
    DcOnly = 3,
}

impl Bands {
    /// Packets per tile in frequency mode.
    pub fn count(self) -> usize {
        4 - self as usize
    }
    /// True when the LP band is coded.
    pub fn has_lp(self) -> bool {
        self != Bands::DcOnly
    }
    /// True when the HP band is coded.
    pub fn has_hp(self) -> bool {
        self <= Bands::NoFlexbits
    }
    /// True when flexbits are coded.
    pub fn has_flex(self) -> bool {
        self == Bands::All
    }
}

/// One quantizer set: a QP index for each channel (T.832 8.3.5, DC_QP / LP_QP / HP_QP).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct QpSet {
    /// The index of each channel.
    pub index: [u8; MAX_CHANNELS],
    /// CHANNEL_MODE as read (0 uniform, 1 separate, 2 independent, 3 read as independent).
    pub mode: u8,
}

/// Reads one quantizer set of a plane with `channels` channels (jxrlib `readQuantizer`).
pub fn read_qp_set(r: &mut BitReader, channels: usize) -> QpSet {
    let mut set = QpSet::default();
    if channels >= MAX_CHANNELS {
        // jxrlib's readQuantizerSB reads nothing for 16 channels; readQuantizer reads the mode.
        set.mode = r.read(2) as u8;
    } else if channels > 1 {
        set.mode = r.read(2) as u8;
    }
    set.index[0] = r.read(8) as u8;
    match set.mode {
        0 => {
            let y = set.index[0];
            set.index[1..channels].fill(y);
        }
        1 => {
            let uv = r.read(8) as u8;
            set.index[1..channels].fill(uv);
        }
        _ => {
            for i in 1..channels {
                set.index[i] = r.read(8) as u8;
            }
        }
    }
    set
}

/// Where a band's quantizers come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum QpSource {
    /// One set for the whole plane (the plane header's).
    Uniform(QpSet),
    /// Each tile header gives them. (When RESERVED_I or RESERVED_J says that a band uses the
    /// quantizers of the band below, jxrlib gives it the lower band's source: the same
    /// uniform set, or per-tile sets read from the tile header as usual.)
    PerTile,
}

/// IMAGE_HEADER (T.832 8.3.1) and what follows from it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImageHeader {
    /// HARD_TILING_FLAG and RESERVED_C as one nibble (0 HD Photo, 1 soft tiles, 9 hard tiles).
    pub sub_version: u8,
    /// Tile edges are treated as image edges by the transform.
    pub hard_tiling: bool,
    /// TILING_FLAG.
    pub tiling: bool,
    /// FREQUENCY_MODE_CODESTREAM_FLAG.
    pub frequency_mode: bool,
    /// SPATIAL_XFRM_SUBORDINATE (orientation, 0..=7).
    pub orientation: u8,
    /// INDEX_TABLE_PRESENT_FLAG.
    pub index_table: bool,
    /// OVERLAP_MODE (0, 1 or 2).
    pub overlap: u8,
    /// SHORT_HEADER_FLAG.
    pub short_header: bool,
    /// LONG_WORD_FLAG (jxrlib ignores it and always computes in 32 bits).
    pub long_word: bool,
    /// WINDOWING_FLAG.
    pub windowing: bool,
    /// TRIM_FLEXBITS_FLAG.
    pub trim_flexbits: bool,
    /// RESERVED_D, read by jxrlib as "tile stretch".
    pub tile_stretch: bool,
    /// RED_BLUE_NOT_SWAPPED_FLAG (jxrlib: "RB swapped"; the packing is the same either way).
    pub red_blue_not_swapped: bool,
    /// PREMULTIPLIED_ALPHA_FLAG (ignored by jxrlib).
    pub premultiplied_alpha: bool,
    /// ALPHA_IMAGE_PLANE_FLAG: an interleaved alpha plane follows.
    pub alpha_plane: bool,
    /// OUTPUT_CLR_FMT.
    pub output_clr_fmt: u8,
    /// OUTPUT_BITDEPTH (15, BD1BLACK1, is kept as 15).
    pub output_bitdepth: u8,
    /// Image width in pixels (after the legacy-window correction).
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Windowing margins: top, left, bottom, right.
    pub margins: [u32; 4],
    /// Width of each tile column in macroblocks.
    pub tile_widths: Vec<u32>,
    /// Height of each tile row in macroblocks.
    pub tile_heights: Vec<u32>,
    /// Extended width in macroblocks.
    pub mb_width: u32,
    /// Extended height in macroblocks.
    pub mb_height: u32,
}

impl ImageHeader {
    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.tile_widths.len() * self.tile_heights.len()
    }
    /// First macroblock column of each tile column (and the total at the end).
    pub fn tile_x0(&self) -> Vec<u32> {
        starts(&self.tile_widths)
    }
    /// First macroblock row of each tile row (and the total at the end).
    pub fn tile_y0(&self) -> Vec<u32> {
        starts(&self.tile_heights)
    }
}

fn starts(sizes: &[u32]) -> Vec<u32> {
    let mut v = Vec::with_capacity(sizes.len() + 1);
    let mut acc = 0;
    v.push(0);
    for &s in sizes {
        acc += s;
        v.push(acc);
    }
    v
}

/// IMAGE_PLANE_HEADER (T.832 8.3.2).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlaneHeader {
    /// INTERNAL_CLR_FMT.
    pub clr_fmt: ClrFmt,
    /// SCALED_FLAG.
    pub scaled: bool,
    /// BANDS_PRESENT.
    pub bands: Bands,
    /// Channels of the plane.
    pub channels: usize,
    /// CHROMA_CENTERING_X and _Y (420 and 422).
    pub chroma_centering: (u8, u8),
    /// SHIFT_BITS (BD16, BD16S, BD32S) or LEN_MANTISSA (BD32F).
    pub shift_or_mantissa: u8,
    /// EXP_BIAS (BD32F).
    pub exp_bias: u8,
    /// DC quantizers: uniform, or per tile.
    pub dc: QpSource,
    /// LP quantizers.
    pub lp: QpSource,
    /// HP quantizers.
    pub hp: QpSource,
}

fn read_plane_header(r: &mut BitReader, bitdepth: u8, alpha: bool) -> Result<PlaneHeader> {
    let clr_fmt = match r.read(3) {
        0 => ClrFmt::YOnly,
        1 => ClrFmt::Yuv420,
        2 => ClrFmt::Yuv422,
        3 => ClrFmt::Yuv444,
        4 => ClrFmt::Yuvk,
        6 => ClrFmt::NComponent,
        v => return Err(Error::invalid(format!("JPEG XR: reserved INTERNAL_CLR_FMT {v}"))),
    };
    if alpha && clr_fmt != ClrFmt::YOnly {
        return Err(Error::invalid("JPEG XR: the alpha plane is not YONLY"));
    }
    let scaled = r.bit();
    let bands = match r.read(4) {
        0 => Bands::All,
        1 => Bands::NoFlexbits,
        2 => Bands::NoHighpass,
        3 => Bands::DcOnly,
        4 => return Err(Error::unsupported("JPEG XR: BANDS_PRESENT = ISOLATED (jxrlib cannot decode it either)")),
        v => return Err(Error::invalid(format!("JPEG XR: reserved BANDS_PRESENT {v}"))),
    };
    let mut chroma_centering = (0, 0);
    let channels = match clr_fmt {
        ClrFmt::YOnly => 1,
        ClrFmt::Yuv420 => {
            r.read(1);
            let x = r.read(3) as u8;
            r.read(1);
            chroma_centering = (x, r.read(3) as u8);
            3
        }
        ClrFmt::Yuv422 => {
            r.read(1);
            chroma_centering = (r.read(3) as u8, 0);
            r.read(4);
            3
        }
        ClrFmt::Yuv444 => {
            r.read(8);
            3
        }
        ClrFmt::Yuvk => 4,
        ClrFmt::NComponent => {
            let n = r.read(4) as usize + 1;
            r.read(4);
            n
        }
    };
    let (mut shift_or_mantissa, mut exp_bias) = (0, 0);
    match bitdepth {
        // BD16, BD16S, BD32 (reserved), BD32S: SHIFT_BITS.
        2 | 3 | 5 | 6 => shift_or_mantissa = r.read(8) as u8,
        // BD32F: LEN_MANTISSA, EXP_BIAS.
        7 => {
            shift_or_mantissa = r.read(8) as u8;
            exp_bias = r.read(8) as u8;
        }
        _ => {}
    }
    let dc = if r.bit() { QpSource::Uniform(read_qp_set(r, channels)) } else { QpSource::PerTile };
    let mut lp = dc;
    let mut hp = dc;
    let mut lp_separate = bands == Bands::DcOnly;
    let mut hp_separate = bands >= Bands::NoHighpass;
    if bands.has_lp() {
        // RESERVED_I: jxrlib's "LP uses the DC quantizers".
        if !r.bit() {
            lp_separate = true;
            lp = if r.bit() { QpSource::Uniform(read_qp_set(r, channels)) } else { QpSource::PerTile };
        }
        hp = lp;
        // RESERVED_J: jxrlib's "HP uses the LP quantizers".
        if bands.has_hp() && !r.bit() {
            hp_separate = true;
            hp = if r.bit() { QpSource::Uniform(read_qp_set(r, channels)) } else { QpSource::PerTile };
        }
    }
    if !lp_separate && !hp_separate {
        // jxrlib: "frame level QPs must be specified independently".
        return Err(Error::invalid("JPEG XR: both RESERVED_I and RESERVED_J are set"));
    }
    r.align();
    Ok(PlaneHeader { clr_fmt, scaled, bands, channels, chroma_centering, shift_or_mantissa, exp_bias, dc, lp, hp })
}

/// A parsed codestream: headers and where each packet starts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Codestream {
    /// IMAGE_HEADER.
    pub image: ImageHeader,
    /// The primary plane's header.
    pub primary: PlaneHeader,
    /// The interleaved alpha plane's header, if any.
    pub alpha: Option<PlaneHeader>,
    /// Absolute byte offset (in the codestream) of each packet: one per tile in spatial mode,
    /// one per tile and band (tile-major) in frequency mode (an escaped entry is offset 0, as
    /// jxrlib reads it).
    pub packets: Vec<u64>,
    /// PROFILE_IDC and LEVEL_IDC of the first PROFILE_LEVEL_INFO entry, if present.
    pub profile_level: Option<(u8, u8)>,
    /// Size of the headers (offset of the first byte after them and SUBSEQUENT_BYTES).
    pub header_len: u64,
}

/// Parses the headers of a codestream (`data` starts with `WMPHOTO\0`). Checks the sizes it
/// reads for consistency; allocates only the tile and index tables (bounded by 4096 × 4096
/// tiles, and by the data's length for the index table).
pub fn parse(data: &[u8]) -> Result<Codestream> {
    if data.len() < 8 || &data[..8] != b"WMPHOTO\0" {
        return Err(if data.len() < 8 && b"WMPHOTO\0".starts_with(data) {
            Error::truncated("the JPEG XR codestream signature")
        } else {
            Error::invalid("the JPEG XR codestream does not start with WMPHOTO")
        });
    }
    let mut r = BitReader::new(&data[8..]);
    let version = r.read(4);
    if version != 1 {
        return Err(Error::unsupported(format!("JPEG XR codestream version {version} (only 1 exists)")));
    }
    let sub_version = r.read(4) as u8;
    if !matches!(sub_version, 0 | 1 | 9) {
        return Err(Error::unsupported(format!("JPEG XR codestream sub-version {sub_version} (jxrlib reads 0, 1, 9)")));
    }
    // Sub-version 0 (HD Photo 1.0) codes coefficients the same way; only its inverse
    // transform differs (jxrlib `strdec.c`: `cSubVersion` selects the transform alone).
    let tiling = r.bit();
    let frequency_mode = r.bit();
    let orientation = r.read(3) as u8;
    let index_table = r.bit();
    let overlap = r.read(2) as u8;
    if overlap == 3 {
        return Err(Error::invalid("JPEG XR: OVERLAP_MODE 3 is reserved"));
    }
    let short_header = r.bit();
    let long_word = r.bit();
    let windowing = r.bit();
    let trim_flexbits = r.bit();
    let tile_stretch = r.bit();
    let red_blue_not_swapped = r.bit();
    let premultiplied_alpha = r.bit();
    let alpha_plane = r.bit();
    let output_clr_fmt = r.read(4) as u8;
    let output_bitdepth = r.read(4) as u8;
    let size_bits = if short_header { 16 } else { 32 };
    let mut width = r.read(size_bits) as u64 + 1;
    let mut height = r.read(size_bits) as u64 + 1;
    let (cols, rows) = if tiling { (r.read(12) as usize + 1, r.read(12) as usize + 1) } else { (1, 1) };
    debug_assert!(cols <= MAX_TILES && rows <= MAX_TILES);
    if !index_table && (frequency_mode || cols * rows > 1) {
        return Err(Error::invalid("JPEG XR: frequency mode or several tiles without an index table"));
    }
    let tile_bits = if short_header { 8 } else { 16 };
    let mut tile_widths: Vec<u32> = (0..cols - 1).map(|_| r.read(tile_bits)).collect();
    let mut tile_heights: Vec<u32> = (0..rows - 1).map(|_| r.read(tile_bits)).collect();
    if tile_stretch {
        for _ in 0..cols * rows {
            r.read(8);
        }
    }
    let mut margins = [0u32; 4];
    if windowing {
        for m in &mut margins {
            *m = r.read(6);
        }
    } else {
        margins[2] = ((16 - height % 16) % 16) as u32;
        margins[3] = ((16 - width % 16) % 16) as u32;
    }
    let [top, left, bottom, right] = margins.map(u64::from);
    if (width + left + right) % 16 != 0 || (height + top + bottom) % 16 != 0 {
        // jxrlib's legacy window: the sizes include the right and bottom margins.
        if width % 16 != 0 || height % 16 != 0 || left != 0 || top != 0 || width <= right || height <= bottom {
            return Err(Error::invalid("JPEG XR: the window margins do not make whole macroblocks"));
        }
        width -= right;
        height -= bottom;
    }
    r.check("the JPEG XR image header")?;
    r.align();
    let ext_w = width + left + right;
    let ext_h = height + top + bottom;
    let (mb_width, mb_height) = ((ext_w / 16) as u32, (ext_h / 16) as u32);
    for (sizes, total, what) in
        [(&mut tile_widths, mb_width, "column widths"), (&mut tile_heights, mb_height, "row heights")]
    {
        let sum: u64 = sizes.iter().map(|&s| u64::from(s)).sum();
        if sizes.contains(&0) || sum >= u64::from(total) {
            return Err(Error::invalid(format!("JPEG XR: the tile {what} do not fit the image")));
        }
        sizes.push(total - sum as u32);
    }
    let image = ImageHeader {
        sub_version,
        hard_tiling: sub_version == 9,
        tiling,
        frequency_mode,
        orientation,
        index_table,
        overlap,
        short_header,
        long_word,
        windowing,
        trim_flexbits,
        tile_stretch,
        red_blue_not_swapped,
        premultiplied_alpha,
        alpha_plane,
        output_clr_fmt,
        output_bitdepth,
        width: width as u32,
        height: height as u32,
        margins,
        tile_widths,
        tile_heights,
        mb_width,
        mb_height,
    };
    let primary = read_plane_header(&mut r, output_bitdepth, false)?;
    let alpha = if alpha_plane { Some(read_plane_header(&mut r, output_bitdepth, true)?) } else { None };
    if let Some(a) = &alpha {
        if a.bands != primary.bands {
            // T.835 and jxrlib decode the alpha plane band by band with the primary's packets.
            return Err(Error::unsupported("JPEG XR: an alpha plane with other bands than the primary plane"));
        }
    }
    r.check("the JPEG XR plane headers")?;
    let tiles = image.tile_count();
    let per_tile = if frequency_mode { primary.bands.count() } else { 1 };
    let mut packets = Vec::new();
    if index_table {
        if r.read(16) != 1 {
            return Err(Error::invalid("JPEG XR: the index table does not start with 0x0001"));
        }
        let entries = tiles * per_tile;
        // Each entry takes at least one byte.
        if entries as u64 > (data.len() as u64).saturating_sub(r.byte_pos() + 8) {
            return Err(Error::truncated("the JPEG XR index table"));
        }
        packets.reserve(entries);
        for _ in 0..entries {
            // jxrlib (`GetVLWordEsc`) and T.835 read an escaped entry as offset 0, and T.835's
            // encoder writes offset 0 as the escape 0xFE. jxrlib writes 0xFF for an empty
            // FLEXBITS packet, which is then read from offset 0 like the others.
            packets.push(r.vlw_esc().unwrap_or(0));
        }
    } else {
        packets.push(0);
    }
    let subsequent = r.vlw_esc().unwrap_or(0);
    r.check("the JPEG XR index table")?;
    let after = r.byte_pos() + 8;
    let mut profile_level = None;
    if subsequent >= 4 {
        profile_level = Some((r.read(8) as u8, r.read(8) as u8));
    }
    let header_len = after
        .checked_add(subsequent)
        .filter(|&l| l <= data.len() as u64)
        .ok_or_else(|| Error::truncated("the JPEG XR codestream (SUBSEQUENT_BYTES runs past its end)"))?;
    for p in &mut packets {
        *p = p
            .checked_add(header_len)
            .filter(|&o| o < data.len() as u64)
            .ok_or_else(|| Error::invalid("JPEG XR: an index table entry points past the end of the codestream"))?;
    }
    Ok(Codestream { image, primary, alpha, packets, profile_level, header_len })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bits written MSB first, for hand-made headers.
    struct W(Vec<u8>, u32);
    impl W {
        fn new() -> Self {
            W(b"WMPHOTO\0".to_vec(), 0)
        }
        fn put(&mut self, v: u64, n: u32) {
            for i in (0..n).rev() {
                if self.1 % 8 == 0 {
                    self.0.push(0);
                }
                let bit = ((v >> i) & 1) as u8;
                let last = self.0.last_mut().unwrap();
                *last |= bit << (7 - self.1 % 8);
                self.1 += 1;
            }
        }
        fn align(&mut self) {
            self.1 = self.1.div_ceil(8) * 8;
        }
    }

    fn header(width: u64, height: u64, windowing: Option<[u64; 4]>) -> Vec<u8> {
        let mut w = W::new();
        w.put(1, 4); // version
        w.put(1, 4); // sub-version
        w.put(0, 1); // tiling
        w.put(0, 1); // frequency
        w.put(0, 3); // orientation
        w.put(0, 1); // index table
        w.put(1, 2); // overlap
        w.put(1, 1); // short header
        w.put(1, 1); // long word
        w.put(u64::from(windowing.is_some()), 1);
        w.put(0, 5); // trim, tile stretch, R/B, premultiplied, alpha
        w.put(7, 4); // RGB
        w.put(4, 4); // BD16F
        w.put(width - 1, 16);
        w.put(height - 1, 16);
        if let Some(m) = windowing {
            for v in m {
                w.put(v, 6);
            }
        }
        w.align();
        // Plane: YUV444, unscaled, all bands, 8 reserved bits.
        w.put(3, 3);
        w.put(0, 1);
        w.put(0, 4);
        w.put(0, 8);
        w.put(1, 1); // DC uniform
        w.put(2, 2); // independent
        w.put(0, 8);
        w.put(5, 8);
        w.put(6, 8);
        w.put(0, 1); // RESERVED_I
        w.put(1, 1); // LP uniform
        w.put(0, 2);
        w.put(9, 8);
        w.put(1, 1); // RESERVED_J: HP uses LP
        w.align();
        w.put(0xFF, 8); // SUBSEQUENT_BYTES escaped
        w.0.extend_from_slice(&[0, 0, 1, 0]);
        w.0
    }

    #[test]
    fn hand_made_header() {
        let cs = parse(&header(17, 5, None)).unwrap();
        assert_eq!((cs.image.width, cs.image.height, cs.image.mb_width, cs.image.mb_height), (17, 5, 2, 1));
        assert_eq!(cs.image.margins, [0, 0, 11, 15]);
        assert_eq!(cs.primary.clr_fmt, ClrFmt::Yuv444);
        assert_eq!(cs.primary.channels, 3);
        let QpSource::Uniform(dc) = cs.primary.dc else { panic!() };
        assert_eq!(&dc.index[..3], &[0, 5, 6]);
        let QpSource::Uniform(lp) = cs.primary.lp else { panic!() };
        assert_eq!(&lp.index[..3], &[9, 9, 9]);
        assert_eq!(cs.primary.hp, cs.primary.lp);
        assert_eq!(cs.packets, vec![cs.header_len]);
        assert_eq!(cs.image.tile_widths, vec![2]);
    }

    #[test]
    fn windowing_and_legacy_window() {
        let cs = parse(&header(20, 16, Some([2, 3, 14, 9]))).unwrap();
        assert_eq!((cs.image.mb_width, cs.image.mb_height), (2, 2));
        // Legacy: 32x16 coded with a right margin of 7 that the size includes.
        let cs = parse(&header(32, 16, Some([0, 0, 0, 7]))).unwrap();
        assert_eq!((cs.image.width, cs.image.mb_width), (25, 2));
        assert!(parse(&header(20, 16, Some([1, 3, 14, 9]))).is_err());
    }

    #[test]
    fn every_truncation_is_an_error() {
        let full = header(40, 40, None);
        for n in 0..full.len() - 4 {
            assert!(parse(&full[..n]).is_err(), "prefix of {n} bytes");
        }
    }
}
