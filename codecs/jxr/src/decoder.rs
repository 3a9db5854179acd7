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

/// The starting value of [`PlaneCoeffs::digest`] (FNV-1a's offset basis).
pub const DIGEST_START: u64 = 0xcbf2_9ce4_8422_2325;

impl PlaneCoeffs {
    /// A 64-bit FNV-1a digest of the coefficients that exist (each channel's DC, its LP
    /// coefficients and its HP blocks: fewer for 4:2:0 and 4:2:2 chroma), macroblocks in
    /// raster order, channels in order, each as 4 little-endian bytes, continuing from `state`
    /// ([`DIGEST_START`] for the first plane). For comparing decoders coefficient for
    /// coefficient (the tests compare it with the reference software's).
    pub fn digest(&self, mut state: u64) -> u64 {
        for y in 0..self.mb_height() {
            for x in 0..self.mb_width() {
                for ch in 0..self.channels {
                    let m = self.mb(ch, x, y);
                    let (lp, blocks) = crate::quant::channel_shape(self.fmt, ch);
                    for v in m[..lp].iter().chain(&m[16..16 + 15 * blocks]) {
                        for b in v.to_le_bytes() {
                            state = (state ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
                        }
                    }
                }
            }
        }
        state
    }
}

impl Coefficients {
    /// [`PlaneCoeffs::digest`] of the primary plane, then of the interleaved alpha plane.
    pub fn digest(&self, state: u64) -> u64 {
        let state = self.primary.digest(state);
        self.alpha.as_ref().map_or(state, |a| a.digest(state))
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
    // Every macroblock takes at least one bit of the codestream (its DC flags): a short
    // stream declaring a large image is truncated, whatever the limits allow.
    let mbs = u64::from(cs.image.mb_width) * u64::from(cs.image.mb_height);
    if mbs > data.len() as u64 * 8 {
        return Err(Error::truncated(format!(
            "the JPEG XR codestream ({} bytes cannot hold {mbs} macroblocks)",
            data.len()
        )));
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

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::Limits;

    fn testdata(name: &str) -> Vec<u8> {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
        std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    fn hash(c: &Coefficients) -> u64 {
        c.digest(DIGEST_START)
    }

    fn coefficients(file: &[u8], pool: hdrcodec_core::ThreadPool) -> Result<Coefficients> {
        let layout = file_layout(file)?;
        decode_coefficients(&file[layout.image], &DecodeOptions::new(Limits::default()).with_pool(pool))
    }

    /// The coefficients T.835 reads into its inverse transform, hashed (testdata/README.md).
    const T835: [(&str, u64); 4] = [
        ("tiny_alpha_sp.jxr", 0xd4e4_baf3_bdb2_f132),
        ("tiny_tiles.jxr", 0xde2a_d77b_1d54_43bc),
        ("tiny_420_sp.jxr", 0xa046_70f4_d286_fe34),
        ("tiny_422.jxr", 0xb6ff_17cc_b011_8afa),
    ];

    #[test]
    fn coefficients_match_t835() {
        for (name, want) in T835 {
            let c = coefficients(&testdata(name), hdrcodec_core::ThreadPool::single()).unwrap();
            assert_eq!(hash(&c), want, "{name}");
        }
    }

    #[test]
    fn tiles_decode_the_same_in_parallel() {
        let file = testdata("tiny_tiles.jxr");
        let c = coefficients(&file, hdrcodec_core::ThreadPool::new(2).unwrap()).unwrap();
        assert_eq!(
            (c.codestream.image.tile_widths.clone(), c.codestream.image.tile_heights.clone()),
            (vec![1, 2], vec![1, 1, 1])
        );
        assert_eq!(hash(&c), T835[1].1);
    }

    /// Every truncation and a few hundred byte changes of each stream: an error or
    /// coefficients, never a panic, within a small allocation budget.
    #[test]
    fn truncated_and_corrupted_streams_never_panic() {
        let limits = Limits::default().with_max_alloc_bytes(64 << 20);
        for (name, _) in T835 {
            let file = testdata(name);
            let range = file_layout(&file).unwrap().image;
            let cs = &file[range];
            for n in 0..cs.len() {
                let _ = decode_coefficients(&cs[..n], &DecodeOptions::new(limits.clone()));
            }
            let mut state = 0x9E37_79B9_7F4A_7C15u64 ^ cs.len() as u64;
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state
            };
            let mut bad = cs.to_vec();
            for _ in 0..300 {
                bad.copy_from_slice(cs);
                for _ in 0..1 + next() % 3 {
                    let at = (next() % cs.len() as u64) as usize;
                    bad[at] ^= 1 << (next() % 8);
                }
                let _ = decode_coefficients(&bad, &DecodeOptions::new(limits.clone()));
            }
            let _ = file_layout(&file[..file.len() / 2]);
        }
    }

    #[test]
    fn huge_declared_sizes_are_refused_before_allocating() {
        let file = testdata("tiny_422.jxr");
        let range = file_layout(&file).unwrap().image;
        let mut cs = file[range].to_vec();
        assert!(header::parse(&cs).unwrap().image.short_header);
        // WMPHOTO (8 bytes) and 4 bytes of version and flags, then WIDTH_MINUS1 and
        // HEIGHT_MINUS1 (16 bits each): 16384 x 16384.
        cs[12..16].copy_from_slice(&[0x3F, 0xFF, 0x3F, 0xFF]);
        let limits = Limits::default().with_max_alloc_bytes(1 << 20);
        // A million macroblocks cannot fit in a few hundred bytes.
        let err = decode_coefficients(&cs, &DecodeOptions::new(limits.clone())).unwrap_err();
        assert!(matches!(err, Error::Truncated { .. }), "{err}");
        // With enough (padding) bytes, the budget refuses the coefficients.
        cs.resize(cs.len() + (1 << 18), 0);
        let err = decode_coefficients(&cs, &DecodeOptions::new(limits)).unwrap_err();
        assert!(matches!(err, Error::LimitExceeded { .. }), "{err}");
    }
}
