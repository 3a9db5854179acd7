//! One tile, end to end through entropy decoding: its packets (one in spatial order; DC, LP,
//! HP and FLEXBITS in frequency order, T.832 8.4), its tile headers and quantizers, the
//! macroblock layer, prediction and dequantization (T.835 `r_tile_spatial.c`,
//! `r_tile_frequency.c`; jxrlib `strdec.c: readPackets, readTileHeader*`).
//!
//! The adaptive coding state and every prediction stop at tile edges, so tiles decode
//! independently of each other ([`decode_tile`] needs only the codestream).

use crate::bits::BitReader;
use crate::header::{read_qp_set, Bands, ClrFmt, Codestream, PlaneHeader, QpSet, QpSource};
use crate::macroblock::PlaneDecoder;
use crate::mb::MB_COEFFS;
use crate::predict;
use crate::quant::{self, TileQp};
use hdrcodec_core::{Error, Result};

/// The coefficients of one plane of one tile: `w × h` macroblocks in raster order, each
/// `channels` arrays of [`MB_COEFFS`] (the layout of [`crate::mb`]), dequantized and predicted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PlaneTile {
    /// Coefficients.
    pub coeffs: Vec<i32>,
}

/// Per-macroblock side information kept while a tile decodes.
#[derive(Clone, Copy, Debug, Default)]
struct MbSide {
    lp_qi: u8,
    hp_qi: u8,
    hp_mode: u8,
    hp_bits: [u32; 2],
}

/// One plane of a tile being decoded.
struct PlaneWork<'h> {
    hdr: &'h PlaneHeader,
    dec: PlaneDecoder,
    qp: TileQp,
    coeffs: Vec<i32>,
    side: Vec<MbSide>,
    cbp: Vec<u32>,
}

impl<'h> PlaneWork<'h> {
    fn new(hdr: &'h PlaneHeader, mbs: usize) -> Self {
        let uniform = |s: QpSource| match s {
            QpSource::Uniform(set) => set,
            QpSource::PerTile => QpSet::default(),
        };
        let qp = TileQp {
            dc: uniform(hdr.dc),
            lp: vec![uniform(hdr.lp)],
            hp: vec![uniform(hdr.hp)],
            lp_use_dc: false,
            hp_use_lp: false,
        };
        PlaneWork {
            hdr,
            dec: PlaneDecoder::new(hdr.clr_fmt, hdr.channels),
            qp,
            coeffs: vec![0; mbs * hdr.channels * MB_COEFFS],
            side: vec![MbSide::default(); mbs],
            cbp: vec![0; mbs * hdr.channels],
        }
    }

    fn stride(&self) -> usize {
        self.hdr.channels * MB_COEFFS
    }

    /// MB_DC of macroblock `i` at column `mx` of a tile `w` wide.
    fn dc(&mut self, r: &mut BitReader, i: usize, mx: usize, w: usize) {
        let stride = self.stride();
        self.dec.dc(r, &mut self.coeffs[i * stride..(i + 1) * stride], mx as u32, w as u32);
    }

    /// MB_LP of macroblock `i`.
    fn lp(&mut self, r: &mut BitReader, i: usize, mx: usize, w: usize) -> Result<()> {
        let stride = self.stride();
        self.dec.lp(r, &mut self.coeffs[i * stride..(i + 1) * stride], mx as u32, w as u32)
    }

    /// TILE_HEADER_DC.
    fn header_dc(&mut self, r: &mut BitReader) {
        if self.hdr.dc == QpSource::PerTile {
            self.qp.dc = read_qp_set(r, self.hdr.channels);
        }
    }

    /// TILE_HEADER_LOWPASS.
    fn header_lp(&mut self, r: &mut BitReader) {
        if self.hdr.bands.has_lp() && self.hdr.lp == QpSource::PerTile {
            self.qp.lp_use_dc = r.bit();
            self.qp.lp = if self.qp.lp_use_dc {
                vec![self.qp.dc]
            } else {
                let n = r.read(4) as usize + 1;
                (0..n).map(|_| read_qp_set(r, self.hdr.channels)).collect()
            };
        }
    }

    /// TILE_HEADER_HIGHPASS.
    fn header_hp(&mut self, r: &mut BitReader) {
        if self.hdr.bands.has_hp() && self.hdr.hp == QpSource::PerTile {
            self.qp.hp_use_lp = r.bit();
            self.qp.hp = if self.qp.hp_use_lp {
                self.qp.lp.clone()
            } else {
                let n = r.read(4) as usize + 1;
                (0..n).map(|_| read_qp_set(r, self.hdr.channels)).collect()
            };
        }
    }

    fn read_lp_index(&mut self, r: &mut BitReader, i: usize) -> Result<()> {
        if self.hdr.bands.has_lp() && self.qp.lp.len() > 1 && !self.qp.lp_use_dc {
            self.side[i].lp_qi = quant::read_qp_index(r, self.qp.lp.len())?;
        }
        Ok(())
    }

    fn read_hp_index(&mut self, r: &mut BitReader, i: usize) -> Result<()> {
        if self.hdr.bands.has_hp() && self.qp.hp.len() > 1 {
            self.side[i].hp_qi =
                if self.qp.hp_use_lp { self.side[i].lp_qi } else { quant::read_qp_index(r, self.qp.hp.len())? };
        }
        Ok(())
    }

    /// DC and LP prediction of macroblock (`mx`, `my`) of a tile `w` wide.
    fn predict_dclp(&mut self, mx: usize, my: usize, w: usize) {
        let stride = self.stride();
        let i = my * w + mx;
        let (before, rest) = self.coeffs.split_at_mut(i * stride);
        let cur = &mut rest[..stride];
        let at = |j: usize| &before[j * stride..(j + 1) * stride];
        let left = (mx > 0).then(|| at(i - 1));
        let top = (my > 0).then(|| at(i - w));
        let top_left = (mx > 0 && my > 0).then(|| at(i - w - 1));
        let q = self.side[i].lp_qi;
        let same_left = mx > 0 && self.side[i - 1].lp_qi == q;
        let same_top = my > 0 && self.side[i - w].lp_qi == q;
        predict::predict_dclp(self.hdr.clr_fmt, self.hdr.channels, cur, left, top, top_left, same_left, same_top);
    }

    /// MB_CBP and MB_HP of macroblock `i`; with `flex_inline` the flexbits follow each block.
    fn cbp_hp(&mut self, r: &mut BitReader, mx: usize, my: usize, w: usize, flex_inline: bool) -> Result<()> {
        let ch = self.hdr.channels;
        let i = my * w + mx;
        let (before, rest) = self.cbp.split_at_mut(i * ch);
        let left = (mx > 0).then(|| &before[(i - 1) * ch..i * ch]);
        let top = (my > 0).then(|| &before[(i - w) * ch..(i - w + 1) * ch]);
        let cur_cbp = &mut rest[..ch];
        self.dec.cbp(r, left, top, cur_cbp)?;
        let stride = ch * MB_COEFFS;
        let c = &mut self.coeffs[i * stride..(i + 1) * stride];
        let mode = predict::hp_mode(self.hdr.clr_fmt, c);
        let bits = self.dec.hp(r, c, cur_cbp, mode, mx as u32, w as u32, flex_inline)?;
        self.side[i].hp_mode = mode;
        self.side[i].hp_bits = bits;
        Ok(())
    }

    /// HP prediction of macroblock `i` (after its flexbits).
    fn predict_hp(&mut self, i: usize) {
        let stride = self.stride();
        let c = &mut self.coeffs[i * stride..(i + 1) * stride];
        let fmt = self.hdr.clr_fmt;
        let channels = if matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) { 1 } else { self.hdr.channels };
        for ch in 0..channels {
            predict::predict_hp(fmt, c, ch, self.side[i].hp_mode);
        }
    }

    /// Dequantizes every macroblock of the tile.
    fn dequantize(&mut self) -> Result<()> {
        let stride = self.stride();
        let (fmt, scaled) = (self.hdr.clr_fmt, self.hdr.scaled);
        for (c, side) in self.coeffs.chunks_exact_mut(stride).zip(&self.side) {
            let lp = self.qp.lp.get(usize::from(side.lp_qi)).ok_or_else(|| Error::invalid("JPEG XR: LP QP index"))?;
            let hp = self.qp.hp.get(usize::from(side.hp_qi)).ok_or_else(|| Error::invalid("JPEG XR: HP QP index"))?;
            for (ch, cc) in c.chunks_exact_mut(MB_COEFFS).enumerate() {
                let luma = ch == 0;
                quant::dequantize(
                    cc,
                    quant::channel_shape(fmt, ch),
                    quant::step(self.qp.dc.index[ch], scaled, luma),
                    quant::step(lp.index[ch], scaled, luma),
                    quant::step(hp.index[ch], scaled, true),
                );
            }
        }
        Ok(())
    }
}

/// Runs `f` on every macroblock of a tile `w` × `h` in raster order, each plane in turn
/// (primary, then alpha), checking at the end of each row that the packet did not run out.
fn each_mb<F>(planes: &mut [PlaneWork], r: &mut BitReader, w: usize, h: usize, what: &str, mut f: F) -> Result<()>
where
    F: FnMut(&mut PlaneWork, &mut BitReader, usize, usize) -> Result<()>,
{
    for my in 0..h {
        for mx in 0..w {
            for p in planes.iter_mut() {
                f(p, r, mx, my)?;
            }
        }
        r.check(what)?;
    }
    Ok(())
}

/// Reads a packet's start code `00 00 01 xx` (`strict`: an error if it is wrong; jxrlib
/// tolerates a bad FLEXBITS packet header).
fn start_code(r: &mut BitReader, strict: bool) -> Result<()> {
    let code = r.read(24);
    r.read(8);
    if code != 1 && strict {
        return Err(Error::invalid("JPEG XR: a tile packet does not start with 00 00 01"));
    }
    Ok(())
}

/// Where tile (`tx`, `ty`) lies, in macroblocks: x0, y0, width, height.
pub fn tile_rect(cs: &Codestream, tx: usize, ty: usize) -> (u32, u32, u32, u32) {
    let x0: u32 = cs.image.tile_widths[..tx].iter().sum();
    let y0: u32 = cs.image.tile_heights[..ty].iter().sum();
    (x0, y0, cs.image.tile_widths[tx], cs.image.tile_heights[ty])
}

/// Entropy-decodes, predicts and dequantizes tile (`tx`, `ty`) of the codestream `data`;
/// returns the primary plane's coefficients and the alpha plane's, if any. The caller has
/// charged the memory (see [`tile_bytes`]).
pub fn decode_tile(cs: &Codestream, data: &[u8], tx: usize, ty: usize) -> Result<Vec<PlaneTile>> {
    let (_, _, w, h) = tile_rect(cs, tx, ty);
    let (w, h) = (w as usize, h as usize);
    let mbs = w * h;
    let mut planes = vec![PlaneWork::new(&cs.primary, mbs)];
    if let Some(a) = &cs.alpha {
        planes.push(PlaneWork::new(a, mbs));
    }
    let tile = ty * cs.image.tile_widths.len() + tx;
    let bands = cs.primary.bands;
    let per_tile = if cs.image.frequency_mode { bands.count() } else { 1 };
    // The packet of `band`, after its start code (`None` when escaped in the index table).
    let packet = |band: usize, strict: bool| -> Result<Option<BitReader<'_>>> {
        let entry = cs.packets.get(tile * per_tile + band).ok_or_else(|| Error::invalid("JPEG XR: index table"))?;
        let Some(off) = *entry else { return Ok(None) };
        let mut r = BitReader::new(&data[off as usize..]);
        start_code(&mut r, strict)?;
        Ok(Some(r))
    };
    let escaped = |what: &str| Error::invalid(format!("JPEG XR: the {what} packet of a tile is escaped"));
    if !cs.image.frequency_mode {
        let mut r = packet(0, true)?.ok_or_else(|| escaped("spatial"))?;
        let trim = if cs.image.trim_flexbits { r.read(4) } else { 0 };
        for p in &mut planes {
            p.dec.trim = trim;
            p.header_dc(&mut r);
            p.header_lp(&mut r);
            p.header_hp(&mut r);
        }
        each_mb(&mut planes, &mut r, w, h, "a JPEG XR tile", |p, r, mx, my| {
            let i = my * w + mx;
            p.read_lp_index(r, i)?;
            p.read_hp_index(r, i)?;
            p.dc(r, i, mx, w);
            if p.hdr.bands.has_lp() {
                p.lp(r, i, mx, w)?;
            }
            p.predict_dclp(mx, my, w);
            if p.hdr.bands.has_hp() {
                p.cbp_hp(r, mx, my, w, p.hdr.bands.has_flex())?;
                p.predict_hp(i);
            }
            Ok(())
        })?;
    } else {
        let mut r = packet(0, true)?.ok_or_else(|| escaped("DC"))?;
        for p in &mut planes {
            p.header_dc(&mut r);
        }
        each_mb(&mut planes, &mut r, w, h, "a JPEG XR DC packet", |p, r, mx, my| {
            p.dc(r, my * w + mx, mx, w);
            if !p.hdr.bands.has_lp() {
                p.predict_dclp(mx, my, w);
            }
            Ok(())
        })?;
        if bands.has_lp() {
            let mut r = packet(1, true)?.ok_or_else(|| escaped("LP"))?;
            for p in &mut planes {
                p.header_lp(&mut r);
            }
            each_mb(&mut planes, &mut r, w, h, "a JPEG XR LP packet", |p, r, mx, my| {
                let i = my * w + mx;
                p.read_lp_index(r, i)?;
                p.lp(r, i, mx, w)?;
                p.predict_dclp(mx, my, w);
                Ok(())
            })?;
        }
        if bands.has_hp() {
            let mut r = packet(2, true)?.ok_or_else(|| escaped("HP"))?;
            for p in &mut planes {
                p.header_hp(&mut r);
            }
            each_mb(&mut planes, &mut r, w, h, "a JPEG XR HP packet", |p, r, mx, my| {
                let i = my * w + mx;
                p.read_hp_index(r, i)?;
                p.cbp_hp(r, mx, my, w, false)?;
                if bands == Bands::NoFlexbits {
                    p.predict_hp(i);
                }
                Ok(())
            })?;
        }
        if bands.has_flex() {
            // jxrlib tolerates a bad FLEXBITS start code; an escaped packet means no flexbits.
            match packet(3, false)? {
                Some(mut r) => {
                    let trim = if cs.image.trim_flexbits { r.read(4) } else { 0 };
                    for p in &mut planes {
                        p.dec.trim = trim;
                    }
                    each_mb(&mut planes, &mut r, w, h, "a JPEG XR FLEXBITS packet", |p, r, mx, my| {
                        let i = my * w + mx;
                        let bits = p.side[i].hp_bits;
                        let stride = p.stride();
                        p.dec.flex(r, &mut p.coeffs[i * stride..(i + 1) * stride], bits);
                        p.predict_hp(i);
                        Ok(())
                    })?;
                }
                None => {
                    for p in &mut planes {
                        for i in 0..mbs {
                            p.predict_hp(i);
                        }
                    }
                }
            }
        }
    }
    let mut out = Vec::with_capacity(planes.len());
    for mut p in planes {
        p.dequantize()?;
        out.push(PlaneTile { coeffs: p.coeffs });
    }
    Ok(out)
}

/// Bytes [`decode_tile`] holds for tile (`tx`, `ty`) at its peak: the coefficients and the
/// side information of every plane.
pub fn tile_bytes(cs: &Codestream, tx: usize, ty: usize) -> u64 {
    let (_, _, w, h) = tile_rect(cs, tx, ty);
    let mbs = u64::from(w) * u64::from(h);
    let channels = cs.primary.channels + cs.alpha.as_ref().map_or(0, |a| a.channels);
    mbs * (channels as u64 * (MB_COEFFS as u64 * 4 + 4) + 32)
}
