//! From a codestream to the dequantized, predicted coefficients of every macroblock: the
//! headers, then every tile entropy-decoded (tiles in parallel on the caller's
//! [`ThreadPool`](hdrcodec_core::ThreadPool)), each plane's coefficients held tile by tile.

use crate::header::{self, ClrFmt, Codestream};
use crate::mb::{MbCoeffs, MB_COEFFS};
use crate::tiles::{self, PlaneTile};
use hdrcodec_core::{Allocation, DecodeOptions, Error, Result};

/// The coefficients of one plane (primary or alpha), for the inverse transform.
#[derive(Debug)]
pub struct PlaneCoeffs {
    /// INTERNAL_CLR_FMT of the plane.
    pub fmt: ClrFmt,
    /// Channels of the plane.
    pub channels: usize,
    /// SCALED_FLAG of the plane.
    pub scaled: bool,
    /// First macroblock column of each tile column, then the extended width in macroblocks.
    pub tile_x0: Vec<u32>,
    /// First macroblock row of each tile row, then the extended height in macroblocks.
    pub tile_y0: Vec<u32>,
    /// Tile column of each macroblock column.
    col_of: Vec<u32>,
    /// Tile row of each macroblock row.
    row_of: Vec<u32>,
    /// Tiles in raster order.
    tiles: Vec<PlaneTile>,
}

impl PlaneCoeffs {
    /// Width in macroblocks (of the extended image).
    pub fn mb_width(&self) -> u32 {
        self.tile_x0.last().copied().unwrap_or(0)
    }

    /// Height in macroblocks.
    pub fn mb_height(&self) -> u32 {
        self.tile_y0.last().copied().unwrap_or(0)
    }

    /// The coefficients of channel `ch` of macroblock (`x`, `y`), in the layout of
    /// [`crate::mb`]: dequantized and predicted, the inverse transform's input.
    ///
    /// # Panics
    /// If the macroblock or channel is outside the plane.
    pub fn mb(&self, ch: usize, x: u32, y: u32) -> &MbCoeffs {
        let (tx, ty) = (self.col_of[x as usize] as usize, self.row_of[y as usize] as usize);
        let (x0, y0) = (self.tile_x0[tx], self.tile_y0[ty]);
        let w = (self.tile_x0[tx + 1] - x0) as usize;
        let i = (y - y0) as usize * w + (x - x0) as usize;
        let tile = &self.tiles[ty * (self.tile_x0.len() - 1) + tx];
        let o = (i * self.channels + ch) * MB_COEFFS;
        tile.coeffs[o..o + MB_COEFFS].try_into().expect("a macroblock is MB_COEFFS long")
    }
}

/// Everything entropy decoding gives the inverse transform: the headers and the coefficients
/// of the primary plane and of the alpha plane, if interleaved.
#[derive(Debug)]
pub struct Coefficients {
    /// The parsed headers.
    pub codestream: Codestream,
    /// The primary plane.
    pub primary: PlaneCoeffs,
    /// The interleaved alpha plane.
    pub alpha: Option<PlaneCoeffs>,
    _charge: Allocation,
}

fn index_of(starts: &[u32]) -> Vec<u32> {
    let mut v = Vec::with_capacity(starts.last().copied().unwrap_or(0) as usize);
    for (t, pair) in starts.windows(2).enumerate() {
        v.extend(std::iter::repeat_n(t as u32, (pair[1] - pair[0]) as usize));
    }
    v
}

/// Decodes every tile of the codestream `data` (which starts with `WMPHOTO`) to
/// coefficients. Checks the extended size against `options.limits` and charges the
/// coefficients (4 bytes per coefficient, one 16×16 macroblock of 256 per channel) before
/// allocating them.
pub fn decode_coefficients(data: &[u8], options: &DecodeOptions) -> Result<Coefficients> {
    let cs = header::parse(data)?;
    let limits = &options.limits;
    limits.check_dimensions(u64::from(cs.image.width), u64::from(cs.image.height))?;
    let (tcols, trows) = (cs.image.tile_widths.len(), cs.image.tile_heights.len());
    let mut total = 0u64;
    for ty in 0..trows {
        for tx in 0..tcols {
            total = total.saturating_add(tiles::tile_bytes(&cs, tx, ty));
        }
    }
    let charge = limits.charge(total, "the JPEG XR coefficients")?;
    let decoded = options.pool.map(tcols * trows, |t| tiles::decode_tile(&cs, data, t % tcols, t / tcols));
    let mut primary = Vec::with_capacity(decoded.len());
    let mut alpha = Vec::with_capacity(if cs.alpha.is_some() { decoded.len() } else { 0 });
    for tile in decoded {
        let mut planes = tile?.into_iter();
        primary.push(planes.next().ok_or_else(|| Error::invalid("JPEG XR: a tile without planes"))?);
        if let Some(a) = planes.next() {
            alpha.push(a);
        }
    }
    let tile_x0 = cs.image.tile_x0();
    let tile_y0 = cs.image.tile_y0();
    let plane = |hdr: &header::PlaneHeader, tiles: Vec<PlaneTile>| PlaneCoeffs {
        fmt: hdr.clr_fmt,
        channels: hdr.channels,
        scaled: hdr.scaled,
        col_of: index_of(&tile_x0),
        row_of: index_of(&tile_y0),
        tile_x0: tile_x0.clone(),
        tile_y0: tile_y0.clone(),
        tiles,
    };
    let primary = plane(&cs.primary, primary);
    let alpha = cs.alpha.as_ref().map(|a| plane(a, alpha));
    Ok(Coefficients { codestream: cs, primary, alpha, _charge: charge })
}

/// Where a `.jxr` file keeps its codestreams (T.832 Annex A; a minimal reading of the first
/// IFD until the container module's full one is merged): the primary image's byte range, the
/// planar alpha codestream's, and the pixel-format GUID.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileLayout {
    /// Byte range of the primary codestream (IMAGE_OFFSET, IMAGE_BYTE_COUNT).
    pub image: std::ops::Range<usize>,
    /// Byte range of the planar alpha codestream (ALPHA_OFFSET, ALPHA_BYTE_COUNT clamped to
    /// the file: jxrlib writes offset + length there).
    pub alpha: Option<std::ops::Range<usize>>,
    /// PIXEL_FORMAT, the 16 GUID bytes as stored.
    pub pixel_format: [u8; 16],
}

/// Reads the first IFD of a `.jxr` file (`II\xBC\x01`, or `\x00` for HD Photo).
pub fn file_layout(file: &[u8]) -> Result<FileLayout> {
    let u16_at = |o: usize| file.get(o..o + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    let u32_at = |o: usize| file.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if file.len() < 8 {
        return Err(Error::truncated("the JPEG XR file header"));
    }
    if &file[..3] != b"II\xBC" || file[3] > 1 {
        return Err(Error::invalid("not a JPEG XR file (no II BC 01 signature)"));
    }
    let ifd = u32_at(4).ok_or_else(|| Error::truncated("the JPEG XR file header"))? as usize;
    let count = u16_at(ifd).ok_or_else(|| Error::truncated("the JPEG XR IFD"))? as usize;
    let (mut image_off, mut image_len, mut alpha_off, mut alpha_len, mut guid) = (None, None, None, None, None);
    for e in 0..count {
        let at = ifd + 2 + 12 * e;
        let (Some(tag), Some(typ), Some(n), Some(value)) = (u16_at(at), u16_at(at + 2), u32_at(at + 4), u32_at(at + 8))
        else {
            return Err(Error::truncated("the JPEG XR IFD"));
        };
        let value = match (typ, n) {
            (3, 1) => value & 0xFFFF,
            (1, 1) => value & 0xFF,
            _ => value,
        };
        match tag {
            0xBC01 if n == 16 => {
                let o = value as usize;
                guid = file.get(o..o + 16).map(|g| <[u8; 16]>::try_from(g).expect("16 bytes"));
            }
            0xBCC0 => image_off = Some(value as usize),
            0xBCC1 => image_len = Some(value as usize),
            0xBCC2 => alpha_off = Some(value as usize),
            0xBCC3 => alpha_len = Some(value as usize),
            _ => {}
        }
    }
    let range = |off: Option<usize>, len: Option<usize>, what: &str| -> Result<std::ops::Range<usize>> {
        let off = off.ok_or_else(|| Error::invalid(format!("JPEG XR: the IFD has no {what} offset")))?;
        if off >= file.len() {
            return Err(Error::truncated(format!("the JPEG XR file ({what} offset past its end)")));
        }
        let len = len.unwrap_or(usize::MAX).min(file.len() - off);
        Ok(off..off + len)
    };
    let image = range(image_off, image_len, "image")?;
    let alpha = match alpha_off {
        Some(_) => Some(range(alpha_off, alpha_len, "alpha")?),
        None => None,
    };
    let pixel_format = guid.ok_or_else(|| Error::invalid("JPEG XR: the IFD has no pixel format"))?;
    Ok(FileLayout { image, alpha, pixel_format })
}
