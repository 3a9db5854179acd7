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
//!
//! [`write_codestream`] and [`write_qp_set`] are the inverses of [`parse`] and [`read_qp_set`]
//! for the encoder: they write what JxrEncApp writes (RESERVED_C, RESERVED_I and RESERVED_J
//! as jxrlib does, SUBSEQUENT_BYTES and the profile stamp as `strenc.c` does) and refuse any
//! header that [`parse`] would not read back as given.

use crate::bits::{BitReader, BitWriter};
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
    /// The header of a `width` × `height` image of one tile in spatial order, without
    /// windowing, in OUTPUT_CLR_FMT `output_clr_fmt` and OUTPUT_BITDEPTH `output_bitdepth`,
    /// with what JxrEncApp writes elsewhere (sub-version 1, overlap 1, LONG_WORD_FLAG; the
    /// short header when the sizes fit it). The macroblock grid extends the image right and
    /// down (the margins are what the extension adds).
    pub fn new(width: u32, height: u32, output_clr_fmt: u8, output_bitdepth: u8) -> Self {
        let (mb_width, mb_height) = (width.div_ceil(16), height.div_ceil(16));
        ImageHeader {
            sub_version: 1,
            hard_tiling: false,
            tiling: false,
            frequency_mode: false,
            orientation: 0,
            index_table: false,
            overlap: 1,
            // 16-bit sizes and 8-bit tile sizes (in macroblocks).
            short_header: width <= 1 << 16 && height <= 1 << 16 && mb_width <= 256 && mb_height <= 256,
            long_word: true,
            windowing: false,
            trim_flexbits: false,
            tile_stretch: false,
            red_blue_not_swapped: false,
            premultiplied_alpha: false,
            alpha_plane: false,
            output_clr_fmt,
            output_bitdepth,
            width,
            height,
            margins: [0, 0, mb_height * 16 - height, mb_width * 16 - width],
            tile_widths: vec![mb_width],
            tile_heights: vec![mb_height],
            mb_width,
            mb_height,
        }
    }

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
    parse_head(data, data.len() as u64)
}

/// [`parse`] of a codestream of `len` bytes of which `data` holds the first (all of its headers,
/// or the parse fails as on a codestream cut there): the sizes and offsets are checked against
/// `len`. What a caller that reads a file piece by piece parses.
pub fn parse_head(data: &[u8], len: u64) -> Result<Codestream> {
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
    if !(width + left + right).is_multiple_of(16) || !(height + top + bottom).is_multiple_of(16) {
        // jxrlib's legacy window: the sizes include the right and bottom margins.
        if !width.is_multiple_of(16)
            || !height.is_multiple_of(16)
            || left != 0
            || top != 0
            || width <= right
            || height <= bottom
        {
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
        if entries as u64 > len.saturating_sub(r.byte_pos() + 8) {
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
        // On the first bytes of a codestream (`parse_head`), not zeros read past them.
        r.check("the JPEG XR codestream's profile and level")?;
    }
    let header_len = after
        .checked_add(subsequent)
        .filter(|&l| l <= len)
        .ok_or_else(|| Error::truncated("the JPEG XR codestream (SUBSEQUENT_BYTES runs past its end)"))?;
    for p in &mut packets {
        *p = p
            .checked_add(header_len)
            .filter(|&o| o < len)
            .ok_or_else(|| Error::invalid("JPEG XR: an index table entry points past the end of the codestream"))?;
    }
    Ok(Codestream { image, primary, alpha, packets, profile_level, header_len })
}

// ---------------------------------------------------------------------------------------------
// Writing: the exact inverses of `parse`, `read_plane_header` and `read_qp_set`.
// ---------------------------------------------------------------------------------------------

/// Writes one quantizer set of a plane with `channels` channels (T.832 8.3.5; the inverse of
/// [`read_qp_set`]). The set must be one that reading gives back: mode 0 with every channel at
/// the luma index, mode 1 with every chroma channel at one index, mode 2 with any indices,
/// indices past `channels` zero, and mode 0 for a single channel (which codes no mode).
/// CHANNEL_MODE 3 is reserved (T.832 Table 34) and refused, although jxrlib reads it as 2.
pub fn write_qp_set(w: &mut BitWriter, set: &QpSet, channels: usize) -> Result<()> {
    if !(1..=MAX_CHANNELS).contains(&channels) {
        return Err(Error::invalid(format!("JPEG XR: a QP set for {channels} channels (1-16)")));
    }
    let (used, rest) = set.index.split_at(channels);
    if rest.iter().any(|&i| i != 0) {
        return Err(Error::invalid("JPEG XR: a QP set has indices past its plane's channels"));
    }
    let consistent = match set.mode {
        0 => used.iter().all(|&i| i == used[0]),
        1 => channels > 1 && used[1..].iter().all(|&i| i == used[1]),
        2 => channels > 1,
        _ => false,
    };
    if !consistent {
        return Err(Error::invalid(format!(
            "JPEG XR: QP set mode {} cannot code the indices {:?} of {channels} channel(s)",
            set.mode, used
        )));
    }
    // One channel codes no CHANNEL_MODE (T.832 8.3.5: only when NUM_CHANNELS > 1).
    if channels > 1 {
        w.write(u32::from(set.mode), 2);
    }
    w.write(u32::from(used[0]), 8);
    match set.mode {
        0 => {}
        1 => w.write(u32::from(used[1]), 8),
        _ => used[1..].iter().for_each(|&i| w.write(u32::from(i), 8)),
    }
    Ok(())
}

/// Writes a band's IMAGE_PLANE_UNIFORM flag and, for a uniform band, its QP set.
fn write_qp_source(w: &mut BitWriter, source: &QpSource, channels: usize) -> Result<()> {
    match source {
        QpSource::Uniform(set) => {
            w.bit(true);
            write_qp_set(w, set, channels)
        }
        QpSource::PerTile => {
            w.bit(false);
            Ok(())
        }
    }
}

/// Writes IMAGE_PLANE_HEADER (T.832 8.3.2; the inverse of `read_plane_header`).
fn write_plane_header(w: &mut BitWriter, p: &PlaneHeader, bitdepth: u8, alpha: bool) -> Result<()> {
    let what = if alpha { "alpha" } else { "primary" };
    let bad = |why: String| Err(Error::invalid(format!("JPEG XR {what} plane header: {why}")));
    if alpha && p.clr_fmt != ClrFmt::YOnly {
        return bad("the alpha plane must be YONLY (T.832 8.3.2)".into());
    }
    let (code, channels_ok) = match p.clr_fmt {
        ClrFmt::YOnly => (0, p.channels == 1),
        ClrFmt::Yuv420 => (1, p.channels == 3),
        ClrFmt::Yuv422 => (2, p.channels == 3),
        ClrFmt::Yuv444 => (3, p.channels == 3),
        ClrFmt::Yuvk => (4, p.channels == 4),
        // NUM_COMPONENTS_MINUS1 has 4 bits; its 12-bit escape is not read by jxrlib (16 max).
        ClrFmt::NComponent => (6, (1..=MAX_CHANNELS).contains(&p.channels)),
    };
    if !channels_ok {
        return bad(format!("{} channels for INTERNAL_CLR_FMT {:?}", p.channels, p.clr_fmt));
    }
    let (cx, cy) = p.chroma_centering;
    let centering_ok = match p.clr_fmt {
        ClrFmt::Yuv420 => cx < 8 && cy < 8,
        ClrFmt::Yuv422 => cx < 8 && cy == 0,
        _ => (cx, cy) == (0, 0),
    };
    if !centering_ok {
        return bad(format!("chroma centering {:?} cannot be coded for {:?}", p.chroma_centering, p.clr_fmt));
    }
    // SHIFT_BITS for BD16, BD16S, BD32 (reserved) and BD32S; LEN_MANTISSA and EXP_BIAS for
    // BD32F (T.832 8.3.2); nothing otherwise, so the fields must then be 0.
    let (has_shift, has_bias) = match bitdepth {
        2 | 3 | 5 | 6 => (true, false),
        7 => (true, true),
        _ => (false, false),
    };
    if (!has_shift && p.shift_or_mantissa != 0) || (!has_bias && p.exp_bias != 0) {
        return bad(format!("OUTPUT_BITDEPTH {bitdepth} codes no SHIFT_BITS / LEN_MANTISSA / EXP_BIAS"));
    }
    // With RESERVED_I and RESERVED_J written as 0 (as every encoder does: JXR-NOTES §8 quirk
    // 7), an absent band has its lower band's quantizers and nothing else can be coded.
    if !p.bands.has_lp() && p.lp != p.dc {
        return bad("DCONLY, but the LP quantizers differ from the DC ones".into());
    }
    if !p.bands.has_hp() && p.hp != p.lp {
        return bad("no HP band, but the HP quantizers differ from the LP ones".into());
    }
    w.write(code, 3);
    w.bit(p.scaled);
    w.write(p.bands as u32, 4);
    match p.clr_fmt {
        ClrFmt::Yuv420 => {
            // RESERVED_E, CHROMA_CENTERING_X, RESERVED_F, CHROMA_CENTERING_Y.
            w.write(0, 1);
            w.write(u32::from(cx), 3);
            w.write(0, 1);
            w.write(u32::from(cy), 3);
        }
        ClrFmt::Yuv422 => {
            w.write(0, 1);
            w.write(u32::from(cx), 3);
            w.write(0, 4);
        }
        ClrFmt::Yuv444 => w.write(0, 8),
        ClrFmt::NComponent => {
            w.write(p.channels as u32 - 1, 4);
            w.write(0, 4);
        }
        ClrFmt::YOnly | ClrFmt::Yuvk => {}
    }
    if has_shift {
        w.write(u32::from(p.shift_or_mantissa), 8);
    }
    if has_bias {
        w.write(u32::from(p.exp_bias), 8);
    }
    write_qp_source(w, &p.dc, p.channels)?;
    if p.bands.has_lp() {
        w.bit(false); // RESERVED_I
        write_qp_source(w, &p.lp, p.channels)?;
        if p.bands.has_hp() {
            w.bit(false); // RESERVED_J
            write_qp_source(w, &p.hp, p.channels)?;
        }
    }
    w.align();
    Ok(())
}

/// Checks that `image` describes a codestream [`parse`] reads back as `image`.
fn check_image_header(image: &ImageHeader) -> Result<()> {
    let bad = |why: String| Err(Error::invalid(format!("JPEG XR image header: {why}")));
    if !matches!(image.sub_version, 0 | 1 | 9) || image.hard_tiling != (image.sub_version == 9) {
        return bad(format!(
            "sub-version {} with hard tiling {} (0, 1 or 9 = hard tiles; jxrlib reads no other)",
            image.sub_version, image.hard_tiling
        ));
    }
    if image.orientation > 7 || image.overlap > 2 || image.output_clr_fmt > 15 || image.output_bitdepth > 15 {
        return bad(format!(
            "orientation {}, overlap {}, OUTPUT_CLR_FMT {} or OUTPUT_BITDEPTH {} out of range",
            image.orientation, image.overlap, image.output_clr_fmt, image.output_bitdepth
        ));
    }
    let max_size: u64 = if image.short_header { 1 << 16 } else { 1 << 32 };
    if image.width == 0 || image.height == 0 || u64::from(image.width) > max_size || u64::from(image.height) > max_size
    {
        return bad(format!(
            "{}x{} does not fit the {} header's size fields",
            image.width,
            image.height,
            if image.short_header { "short" } else { "long" }
        ));
    }
    let [top, left, bottom, right] = image.margins.map(u64::from);
    let (w, h) = (u64::from(image.width), u64::from(image.height));
    if image.windowing {
        if image.margins.iter().any(|&m| m >= 64) {
            return bad(format!("window margins {:?} exceed the 6-bit fields", image.margins));
        }
        if (w + left + right) % 16 != 0 || (h + top + bottom) % 16 != 0 {
            return bad(format!("window margins {:?} do not make whole macroblocks", image.margins));
        }
    } else if image.margins != [0, 0, ((16 - h % 16) % 16) as u32, ((16 - w % 16) % 16) as u32] {
        // Without WINDOWING_FLAG the margins are implied (T.832 8.3.1).
        return bad(format!("margins {:?} without WINDOWING_FLAG", image.margins));
    }
    if u64::from(image.mb_width) * 16 != w + left + right || u64::from(image.mb_height) * 16 != h + top + bottom {
        return bad(format!("{}x{} macroblocks for the extended size", image.mb_width, image.mb_height));
    }
    let tile_max: u32 = if image.short_header { 0xFF } else { 0xFFFF };
    for (sizes, total, what) in
        [(&image.tile_widths, image.mb_width, "column widths"), (&image.tile_heights, image.mb_height, "row heights")]
    {
        let sum: u64 = sizes.iter().map(|&s| u64::from(s)).sum();
        if sizes.is_empty() || sizes.len() > MAX_TILES || sizes.contains(&0) || sum != u64::from(total) {
            return bad(format!("tile {what} {sizes:?} do not make {total} macroblocks"));
        }
        // The last size is implied; the others have 8 or 16 bits.
        if sizes[..sizes.len() - 1].iter().any(|&s| s > tile_max) {
            return bad(format!("tile {what} {sizes:?} exceed the {}-bit fields", tile_max.count_ones()));
        }
        if !image.tiling && sizes.len() != 1 {
            return bad(format!("several tile {what} without TILING_FLAG"));
        }
    }
    if !image.index_table && (image.frequency_mode || image.tile_count() > 1) {
        return bad("frequency mode or several tiles need an index table (T.832 8.3.1)".into());
    }
    Ok(())
}

/// Writes a complete codestream (T.832 8.3): `WMPHOTO\0`, IMAGE_HEADER, the primary and
/// (when `alpha` is given) interleaved alpha IMAGE_PLANE_HEADERs, the INDEX_TABLE if
/// `image.index_table`, SUBSEQUENT_BYTES and PROFILE_LEVEL_INFO, then `packets` in the order
/// given: one per tile in spatial mode, one per tile and band (tile-major) in frequency mode,
/// exactly one without an index table.
///
/// As JxrEncApp (`strenc.c: writeIndexTable, writeIndexTableNull`): with an index table,
/// SUBSEQUENT_BYTES is the escape 0xFF and no profile is stamped (Annex B then infers
/// Advanced/255); without one, SUBSEQUENT_BYTES is 4 and a single PROFILE_LEVEL_INFO says
/// Advanced (111), level 255. An empty packet is written as the escape 0xFF, as jxrlib writes
/// a dropped packet ([`parse`] reads it as the first packet's offset); the others' index
/// entries are their offsets from the end of the headers, so that `parse(...).packets` are
/// their absolute offsets.
///
/// Every field is checked against its syntax element: a header that cannot be coded, or that
/// [`parse`] would not read back as given, is an [`Error`], never a panic.
pub fn write_codestream(
    image: &ImageHeader,
    primary: &PlaneHeader,
    alpha: Option<&PlaneHeader>,
    packets: &[Vec<u8>],
) -> Result<Vec<u8>> {
    check_image_header(image)?;
    if image.alpha_plane != alpha.is_some() {
        return Err(Error::invalid("JPEG XR: ALPHA_IMAGE_PLANE_FLAG disagrees with the alpha plane header given"));
    }
    if alpha.is_some_and(|a| a.bands != primary.bands) {
        // jxrlib decodes the alpha plane band by band with the primary's packets.
        return Err(Error::invalid("JPEG XR: the alpha plane has other bands than the primary plane"));
    }
    let per_tile = if image.frequency_mode { primary.bands.count() } else { 1 };
    let entries = if image.index_table { image.tile_count() * per_tile } else { 1 };
    if packets.len() != entries {
        return Err(Error::invalid(format!("JPEG XR: {} packets given, the headers need {entries}", packets.len())));
    }
    if !image.index_table && packets[0].is_empty() {
        return Err(Error::invalid("JPEG XR: the only packet is empty"));
    }

    let mut w = BitWriter::new();
    // IMAGE_HEADER (T.832 8.3.1).
    w.write(1, 4); // VERSION_INFO (RESERVED_B)
    w.write(u32::from(image.sub_version), 4); // HARD_TILING_FLAG + RESERVED_C
    w.bit(image.tiling);
    w.bit(image.frequency_mode);
    w.write(u32::from(image.orientation), 3);
    w.bit(image.index_table);
    w.write(u32::from(image.overlap), 2);
    w.bit(image.short_header);
    w.bit(image.long_word);
    w.bit(image.windowing);
    w.bit(image.trim_flexbits);
    w.bit(image.tile_stretch);
    w.bit(image.red_blue_not_swapped);
    w.bit(image.premultiplied_alpha);
    w.bit(image.alpha_plane);
    w.write(u32::from(image.output_clr_fmt), 4);
    w.write(u32::from(image.output_bitdepth), 4);
    let size_bits = if image.short_header { 16 } else { 32 };
    w.write(image.width - 1, size_bits);
    w.write(image.height - 1, size_bits);
    if image.tiling {
        // NUM_VER_TILES_MINUS1 counts tile columns, NUM_HOR_TILES_MINUS1 rows.
        w.write(image.tile_widths.len() as u32 - 1, 12);
        w.write(image.tile_heights.len() as u32 - 1, 12);
    }
    let tile_bits = if image.short_header { 8 } else { 16 };
    for sizes in [&image.tile_widths, &image.tile_heights] {
        for &s in &sizes[..sizes.len() - 1] {
            w.write(s, tile_bits);
        }
    }
    if image.tile_stretch {
        // jxrlib's "tile stretch" (RESERVED_D): 8 bits per tile, which it skips.
        for _ in 0..image.tile_count() {
            w.write(0, 8);
        }
    }
    if image.windowing {
        for m in image.margins {
            w.write(m, 6);
        }
    }
    w.align();
    write_plane_header(&mut w, primary, image.output_bitdepth, false)?;
    if let Some(a) = alpha {
        write_plane_header(&mut w, a, image.output_bitdepth, true)?;
    }

    if image.index_table {
        // INDEX_TABLE (T.832 8.3.3): 0x0001, then each packet's offset from the first byte
        // after the headers (after SUBSEQUENT_BYTES), which is where the packets start.
        w.write(1, 16);
        let mut offset = 0u64;
        for p in packets {
            if p.is_empty() {
                w.write(0xFF, 8);
            } else {
                w.vlw_esc(offset);
                offset += p.len() as u64;
            }
        }
        w.write(0xFF, 8); // SUBSEQUENT_BYTES: escaped, no profile (as JxrEncApp)
    } else {
        // SUBSEQUENT_BYTES = 4, then PROFILE_IDC 111 (Advanced), LEVEL_IDC 255, 15 reserved
        // bits and LAST_FLAG (T.832 8.3.4, B.2), as JxrEncApp stamps a file without a table.
        w.vlw_esc(4);
        w.write(111, 8);
        w.write(255, 8);
        w.write(1, 16);
    }

    let mut out = b"WMPHOTO\0".to_vec();
    let headers = w.into_bytes();
    out.reserve(headers.len() + packets.iter().map(Vec::len).sum::<usize>());
    out.extend_from_slice(&headers);
    for p in packets {
        out.extend_from_slice(p);
    }
    Ok(out)
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
                if self.1.is_multiple_of(8) {
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

    fn set(mode: u8, idx: &[u8]) -> QpSet {
        let mut s = QpSet { mode, ..QpSet::default() };
        s.index[..idx.len()].copy_from_slice(idx);
        s
    }

    /// A one-tile image header of `width` x `height` with the implied margins.
    fn image(width: u32, height: u32) -> ImageHeader {
        ImageHeader { short_header: true, ..ImageHeader::new(width, height, 7, 4) }
    }

    fn plane(clr_fmt: ClrFmt, channels: usize) -> PlaneHeader {
        PlaneHeader {
            clr_fmt,
            scaled: true,
            bands: Bands::All,
            channels,
            chroma_centering: (0, 0),
            shift_or_mantissa: 0,
            exp_bias: 0,
            dc: QpSource::Uniform(set(0, &vec![3; channels])),
            lp: QpSource::PerTile,
            hp: QpSource::PerTile,
        }
    }

    /// Packets of varied lengths (some empty when `holes`), each starting with its number.
    fn packets(n: usize, holes: bool) -> Vec<Vec<u8>> {
        (0..n)
            .map(|i| {
                if holes && i % 5 == 3 {
                    Vec::new()
                } else {
                    (0..(i * 37) % 300 + 1).map(|j| (i + j) as u8).collect()
                }
            })
            .collect()
    }

    /// Writes, parses, and checks that everything comes back.
    fn round_trip(image: &ImageHeader, primary: &PlaneHeader, alpha: Option<&PlaneHeader>, packets: &[Vec<u8>]) {
        let data = write_codestream(image, primary, alpha, packets).unwrap();
        let cs = parse(&data).unwrap_or_else(|e| panic!("{e}: {image:?} {primary:?}"));
        assert_eq!(&cs.image, image);
        assert_eq!(&cs.primary, primary);
        assert_eq!(cs.alpha.as_ref(), alpha);
        assert_eq!(cs.packets.len(), packets.len());
        assert_eq!(cs.profile_level, (!image.index_table).then_some((111, 255)));
        let mut end = cs.header_len as usize;
        for (p, &at) in packets.iter().zip(&cs.packets) {
            if p.is_empty() {
                assert_eq!(at, cs.header_len, "an empty packet reads as offset 0");
            } else {
                assert_eq!(at as usize, end);
                assert_eq!(&data[end..end + p.len()], &p[..]);
                end += p.len();
            }
        }
        assert_eq!(end, data.len());
    }

    #[test]
    fn qp_sets_read_back() {
        let cases: &[(usize, QpSet)] = &[
            (1, set(0, &[7])),
            (3, set(0, &[4, 4, 4])),
            (3, set(1, &[4, 9, 9])),
            (3, set(2, &[4, 9, 200])),
            (4, set(1, &[1, 2, 2, 2])),
            (16, set(2, &(0..16).collect::<Vec<u8>>())),
            (16, set(0, &[6; 16])),
        ];
        for &(channels, s) in cases {
            let mut w = BitWriter::new();
            write_qp_set(&mut w, &s, channels).unwrap();
            let bytes = w.into_bytes();
            assert_eq!(read_qp_set(&mut BitReader::new(&bytes), channels), s, "{channels} channels");
        }
        let bad: &[(usize, QpSet)] = &[
            (1, set(1, &[7])),
            (3, set(0, &[4, 5, 4])),
            (3, set(1, &[4, 9, 8])),
            (3, set(3, &[4, 9, 8])),
            (3, set(2, &[4, 9, 8, 1])),
            (1, set(2, &[4])),
            (0, set(0, &[])),
            (17, set(0, &[])),
        ];
        for &(channels, s) in bad {
            assert!(write_qp_set(&mut BitWriter::new(), &s, channels).is_err(), "{channels} {s:?}");
        }
    }

    #[test]
    fn codestreams_read_back() {
        // Every ClrFmt with its extra fields, every bit depth's fields, every band set, QPs
        // uniform and per tile, LP and HP separate and shared.
        let formats = [
            (ClrFmt::YOnly, 1, (0, 0)),
            (ClrFmt::Yuv420, 3, (3, 5)),
            (ClrFmt::Yuv422, 3, (4, 0)),
            (ClrFmt::Yuv444, 3, (0, 0)),
            (ClrFmt::Yuvk, 4, (0, 0)),
            (ClrFmt::NComponent, 7, (0, 0)),
            (ClrFmt::NComponent, 16, (0, 0)),
            (ClrFmt::NComponent, 1, (0, 0)),
        ];
        let depths = [(1u8, 0u8, 0u8), (2, 3, 0), (3, 0, 0), (4, 0, 0), (6, 10, 0), (7, 13, 4), (7, 23, 127)];
        let bands = [Bands::All, Bands::NoFlexbits, Bands::NoHighpass, Bands::DcOnly];
        let mut n = 0usize;
        for (fi, &(clr_fmt, channels, centering)) in formats.iter().enumerate() {
            for (di, &(depth, shift, bias)) in depths.iter().enumerate() {
                for (bi, &band) in bands.iter().enumerate() {
                    n += 1;
                    let k = fi + di + bi;
                    let mut p = plane(clr_fmt, channels);
                    p.chroma_centering = centering;
                    p.shift_or_mantissa = shift;
                    p.exp_bias = bias;
                    p.bands = band;
                    p.scaled = k % 2 == 0;
                    let idx: Vec<u8> = (0..channels as u8).map(|c| c * 11 + k as u8).collect();
                    let uni = |mode: u8| {
                        let mut s = set(2, &idx);
                        if channels == 1 || mode == 0 {
                            s = set(0, &vec![idx[0]; channels]);
                        } else if mode == 1 {
                            let mut v = vec![idx[1]; channels];
                            v[0] = idx[0];
                            s = set(1, &v);
                        }
                        QpSource::Uniform(s)
                    };
                    p.dc = if k % 3 == 0 { QpSource::PerTile } else { uni((k % 3) as u8) };
                    p.lp = match k % 4 {
                        0 => p.dc,
                        1 => QpSource::PerTile,
                        _ => uni((k / 2 % 3) as u8),
                    };
                    // HP: shared with LP (same source written twice) or separate.
                    p.hp = if k % 2 == 0 { p.lp } else { uni(((k + 1) % 3) as u8) };
                    if !band.has_lp() {
                        p.lp = p.dc;
                    }
                    if !band.has_hp() {
                        p.hp = p.lp;
                    }
                    let mut img = image(100 + k as u32, 40 + n as u32);
                    img.output_bitdepth = depth;
                    img.output_clr_fmt = (k % 9) as u8;
                    img.short_header = n.is_multiple_of(2);
                    img.orientation = (n % 8) as u8;
                    img.overlap = (n % 3) as u8;
                    img.trim_flexbits = n.is_multiple_of(5);
                    img.red_blue_not_swapped = n.is_multiple_of(7);
                    img.frequency_mode = n.is_multiple_of(3);
                    img.index_table = img.frequency_mode || n.is_multiple_of(4);
                    let count = if img.frequency_mode { band.count() } else { 1 };
                    round_trip(&img, &p, None, &packets(count, img.index_table));
                    // With an alpha plane of the same bands.
                    if clr_fmt == ClrFmt::Yuv444 {
                        let mut a = plane(ClrFmt::YOnly, 1);
                        a.bands = band;
                        a.scaled = false;
                        if !band.has_hp() {
                            (a.lp, a.hp) = (a.dc, a.dc);
                        }
                        img.alpha_plane = true;
                        round_trip(&img, &p, Some(&a), &packets(count, img.index_table));
                    }
                }
            }
        }
    }

    #[test]
    fn tiled_windowed_codestreams_read_back() {
        // Long header, 3 x 4 tiles, hard tiles, tile stretch, frequency mode with holes.
        let mut img = image(1000, 700);
        img.short_header = false;
        img.tiling = true;
        img.index_table = true;
        img.frequency_mode = true;
        img.sub_version = 9;
        img.hard_tiling = true;
        img.tile_stretch = true;
        img.tile_widths = vec![20, 1, 42];
        img.tile_heights = vec![10, 10, 10, 14];
        let mut p = plane(ClrFmt::Yuv444, 3);
        p.lp = QpSource::Uniform(set(1, &[5, 6, 6]));
        p.hp = QpSource::PerTile;
        round_trip(&img, &p, None, &packets(12 * 4, true));
        // Spatial, large packets (VLW_ESC 32-bit offsets).
        img.frequency_mode = false;
        let big: Vec<Vec<u8>> = (0..12).map(|i| vec![i as u8; 0x5000 + i]).collect();
        round_trip(&img, &p, None, &big);
        // Short header, windowing with all four margins, tiles in one direction, alpha.
        let mut img = image(20, 16);
        img.windowing = true;
        img.margins = [2, 3, 14, 9];
        img.mb_width = 2;
        img.mb_height = 2;
        img.tiling = true;
        img.index_table = true;
        img.tile_widths = vec![1, 1];
        img.tile_heights = vec![2];
        img.alpha_plane = true;
        let a = plane(ClrFmt::YOnly, 1);
        round_trip(&img, &plane(ClrFmt::Yuv420, 3), Some(&a), &packets(2, false));
        // A tiling flag with a single tile, and no index table.
        let mut img = image(33, 17);
        img.tiling = true;
        round_trip(&img, &plane(ClrFmt::YOnly, 1), None, &packets(1, false));
        // Largest sizes of the short header and of the 8-bit tile fields.
        let mut img = image(65536, 16);
        img.tiling = true;
        img.index_table = true;
        img.tile_widths = vec![255, 4096 - 255];
        round_trip(&img, &plane(ClrFmt::YOnly, 1), None, &packets(2, false));
    }

    #[test]
    fn uncodable_headers_are_errors() {
        let p = plane(ClrFmt::Yuv444, 3);
        let one = packets(1, false);
        let err = |img: &ImageHeader, p: &PlaneHeader, a: Option<&PlaneHeader>, n: usize| {
            assert!(write_codestream(img, p, a, &packets(n, false)).is_err(), "{img:?} {p:?}");
        };
        assert!(write_codestream(&image(17, 5), &p, None, &one).is_ok());
        // Sizes beyond the short header's fields.
        err(&image(65537, 16), &p, None, 1);
        let mut img = image(4000, 16);
        img.tiling = true;
        img.index_table = true;
        img.tile_widths = vec![256, 250 - 6];
        err(&img, &p, None, 2);
        // Tile sizes that do not sum to the macroblock size, zero tiles, tiles without TILING_FLAG.
        let mut img = image(64, 64);
        img.tiling = true;
        img.index_table = true;
        img.tile_widths = vec![1, 2];
        err(&img, &p, None, 2);
        img.tile_widths = vec![4, 0];
        err(&img, &p, None, 2);
        img.tile_widths = vec![];
        err(&img, &p, None, 0);
        img.tile_widths = vec![2, 2];
        img.tiling = false;
        err(&img, &p, None, 2);
        // Several tiles or frequency mode without an index table; a wrong packet count.
        img.tiling = true;
        img.index_table = false;
        err(&img, &p, None, 1);
        let mut img = image(64, 64);
        img.frequency_mode = true;
        err(&img, &p, None, 4);
        img.index_table = true;
        err(&img, &p, None, 3);
        err(&image(64, 64), &p, None, 2);
        assert!(write_codestream(&image(64, 64), &p, None, &[Vec::new()]).is_err());
        // Margins: too large, not whole macroblocks, given without windowing, wrong MB counts.
        let mut img = image(20, 16);
        img.windowing = true;
        img.margins = [0, 0, 0, 64 + 12];
        img.mb_width = 6;
        err(&img, &p, None, 1);
        img.margins = [0, 0, 0, 11];
        err(&img, &p, None, 1);
        let mut img = image(20, 16);
        img.margins = [1, 0, 15, 12];
        err(&img, &p, None, 1);
        let mut img = image(20, 16);
        img.mb_width = 3;
        img.tile_widths = vec![3];
        err(&img, &p, None, 1);
        // Zero size, bad sub-version, orientation, overlap.
        let mut img = image(16, 16);
        img.width = 0;
        err(&img, &p, None, 1);
        for f in [
            |i: &mut ImageHeader| i.sub_version = 2,
            |i: &mut ImageHeader| i.hard_tiling = true,
            |i: &mut ImageHeader| i.orientation = 8,
            |i: &mut ImageHeader| i.overlap = 3,
            |i: &mut ImageHeader| i.output_bitdepth = 16,
            |i: &mut ImageHeader| i.alpha_plane = true,
        ] {
            let mut img = image(16, 16);
            f(&mut img);
            err(&img, &p, None, 1);
        }
        // Channels the format does not allow, fields it does not code, QPs it cannot code.
        let img = image(16, 16);
        for f in [
            |p: &mut PlaneHeader| p.channels = 4,
            |p: &mut PlaneHeader| p.clr_fmt = ClrFmt::YOnly,
            |p: &mut PlaneHeader| p.clr_fmt = ClrFmt::Yuvk,
            |p: &mut PlaneHeader| {
                p.clr_fmt = ClrFmt::NComponent;
                p.channels = 17
            },
            |p: &mut PlaneHeader| p.chroma_centering = (1, 0),
            |p: &mut PlaneHeader| {
                p.clr_fmt = ClrFmt::Yuv422;
                p.chroma_centering = (1, 1)
            },
            |p: &mut PlaneHeader| {
                p.clr_fmt = ClrFmt::Yuv420;
                p.chroma_centering = (8, 1)
            },
            |p: &mut PlaneHeader| p.shift_or_mantissa = 1,
            |p: &mut PlaneHeader| p.exp_bias = 1,
            |p: &mut PlaneHeader| p.dc = QpSource::Uniform(set(0, &[1, 2, 3])),
            |p: &mut PlaneHeader| {
                p.bands = Bands::DcOnly;
                p.lp = p.dc
            },
            |p: &mut PlaneHeader| {
                p.bands = Bands::NoHighpass;
                p.hp = p.dc
            },
        ] {
            let mut q = p.clone();
            f(&mut q);
            err(&img, &q, None, 1);
        }
        // The alpha plane: YONLY only, same bands as the primary, flag and header agree.
        let mut img = image(16, 16);
        img.alpha_plane = true;
        let mut a = plane(ClrFmt::YOnly, 1);
        assert!(write_codestream(&img, &p, Some(&a), &one).is_ok());
        a.bands = Bands::DcOnly;
        a.lp = a.dc;
        a.hp = a.dc;
        err(&img, &p, Some(&a), 1);
        err(&img, &p, Some(&p), 1);
        err(&image(16, 16), &p, Some(&plane(ClrFmt::YOnly, 1)), 1);
    }

    #[test]
    fn rewriting_a_hand_made_header_keeps_it() {
        // The hand-made header sets RESERVED_J (jxrlib's "HP uses LP"); the rewrite codes HP
        // explicitly and reads back the same.
        for data in [header(17, 5, None), header(20, 16, Some([2, 3, 14, 9]))] {
            let cs = parse(&data).unwrap();
            let packet = data[cs.packets[0] as usize..].to_vec();
            let again = write_codestream(&cs.image, &cs.primary, cs.alpha.as_ref(), &[packet]).unwrap();
            let cs2 = parse(&again).unwrap();
            assert_eq!((cs2.image, cs2.primary, cs2.alpha), (cs.image, cs.primary, cs.alpha));
        }
    }
}
