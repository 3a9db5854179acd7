//! One tile, end to end through entropy decoding: its packets (one in spatial order; DC, LP,
//! HP and FLEXBITS in frequency order, T.832 8.4), its tile headers and quantizers, the
//! macroblock layer, prediction and dequantization (T.835 `r_tile_spatial.c`,
//! `r_tile_frequency.c`; jxrlib `strdec.c: readPackets, readTileHeader*`).
//!
//! The adaptive coding state and every prediction stop at tile edges, so tiles decode
//! independently of each other. Inside a tile, decoding is serial in raster order; a
//! [`TileDecoder`] gives one macroblock row at a time (in frequency order, each packet's
//! reader advances by one row), holding only the row above for prediction.

use crate::bits::BitReader;
use crate::header::{read_qp_set, Bands, ClrFmt, Codestream, PlaneHeader, QpSet, QpSource};
use crate::macroblock::{self, PlaneDecoder};
use crate::mb::MB_COEFFS;
use crate::predict;
use crate::quant::{self, TileQp};
use crate::source::{Packet, Source};
use hdrcodec_core::{Error, Result};

/// Per-macroblock side information kept while a tile decodes (and handed to the FLEXBITS
/// stage when it runs apart, see [`FlexStage`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct MbSide {
    lp_qi: u8,
    hp_qi: u8,
    hp_mode: u8,
    hp_bits: [u32; 2],
}

/// One plane of a tile being decoded: its adaptive state, quantizers, and what prediction
/// needs of the row above. The row being decoded is the caller's (the plane's part of the
/// output row): macroblocks are decoded straight into it.
struct PlaneWork<'h> {
    hdr: &'h PlaneHeader,
    dec: PlaneDecoder,
    qp: TileQp,
    /// Macroblocks per row.
    w: usize,
    /// The DC and LP coefficients (indices 0..16 of each channel), quantized, of the row
    /// above, in the layout of a row (the rest is zero and never read).
    top: Vec<i32>,
    side: [Vec<MbSide>; 2],
    cbp: [Vec<u32>; 2],
    /// Clear each macroblock before decoding it: unless the bands decoded write every
    /// coefficient of it (see [`dc`](Self::dc)).
    clear: bool,
}

impl<'h> PlaneWork<'h> {
    fn new(hdr: &'h PlaneHeader, w: usize) -> Self {
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
        let row = || vec![0; w * hdr.channels * MB_COEFFS];
        PlaneWork {
            hdr,
            dec: PlaneDecoder::new(hdr.clr_fmt, hdr.channels),
            qp,
            w,
            top: row(),
            side: [vec![MbSide::default(); w], vec![MbSide::default(); w]],
            cbp: [vec![0; w * hdr.channels], vec![0; w * hdr.channels]],
            clear: true,
        }
    }

    fn stride(&self) -> usize {
        self.hdr.channels * MB_COEFFS
    }

    /// Clears the side information of row `my` before it is decoded (its coefficients are
    /// cleared a macroblock at a time, by [`dc`](Self::dc), while they are in cache).
    fn start_row(&mut self, my: usize) {
        let s = my % 2;
        self.side[s].fill(MbSide::default());
        self.cbp[s].fill(0);
    }

    /// The coefficients of macroblock `mx` (all channels) in `row`.
    fn mb<'r>(&self, row: &'r mut [i32], mx: usize) -> &'r mut [i32] {
        let stride = self.stride();
        &mut row[mx * stride..(mx + 1) * stride]
    }

    /// MB_DC of macroblock `mx` of `row`, the first syntax element of a macroblock in either
    /// bitstream order: clears the macroblock's coefficients first, unless the bands decoded
    /// write each of them anyway ([`clear`](Self::clear) false): the DC of every channel, all
    /// 15 LP coefficients of every channel (zeros included), and every HP block, coded or not
    /// (`PlaneDecoder::hp` zeroes each before writing its levels). 4:2:0 and 4:2:2 macroblocks
    /// are always cleared: their chroma channels leave coefficients unwritten (LP past 3 or 7,
    /// HP blocks past 4 or 8), which must read as zero.
    fn dc(&mut self, row: &mut [i32], r: &mut BitReader, mx: usize) {
        let w = self.w as u32;
        let c = self.mb(row, mx);
        if self.clear {
            c.fill(0);
        }
        self.dec.dc(r, c, mx as u32, w);
    }

    /// MB_LP of macroblock `mx` of `row`.
    fn lp(&mut self, row: &mut [i32], r: &mut BitReader, mx: usize) -> Result<()> {
        let w = self.w as u32;
        let c = self.mb(row, mx);
        self.dec.lp(r, c, mx as u32, w)
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

    fn read_lp_index(&mut self, r: &mut BitReader, mx: usize, my: usize) -> Result<()> {
        if self.hdr.bands.has_lp() && self.qp.lp.len() > 1 && !self.qp.lp_use_dc {
            self.side[my % 2][mx].lp_qi = quant::read_qp_index(r, self.qp.lp.len())?;
        }
        Ok(())
    }

    fn read_hp_index(&mut self, r: &mut BitReader, mx: usize, my: usize) -> Result<()> {
        if self.hdr.bands.has_hp() && self.qp.hp.len() > 1 {
            let side = &mut self.side[my % 2][mx];
            side.hp_qi = if self.qp.hp_use_lp { side.lp_qi } else { quant::read_qp_index(r, self.qp.hp.len())? };
        }
        Ok(())
    }

    /// DC and LP prediction of macroblock (`mx`, `my`) of `row`.
    fn predict_dclp(&mut self, row: &mut [i32], mx: usize, my: usize) {
        let stride = self.stride();
        let (s, t) = (my % 2, 1 - my % 2);
        let prev_row = &self.top;
        let (before, rest) = row.split_at_mut(mx * stride);
        let cur = &mut rest[..stride];
        let left = (mx > 0).then(|| &before[(mx - 1) * stride..]);
        let top = (my > 0).then(|| &prev_row[mx * stride..(mx + 1) * stride]);
        let top_left = (mx > 0 && my > 0).then(|| &prev_row[(mx - 1) * stride..mx * stride]);
        let q = self.side[s][mx].lp_qi;
        let same_left = mx > 0 && self.side[s][mx - 1].lp_qi == q;
        let same_top = my > 0 && self.side[t][mx].lp_qi == q;
        predict::predict_dclp(self.hdr.clr_fmt, self.hdr.channels, cur, left, top, top_left, same_left, same_top);
    }

    /// MB_CBP and MB_HP of macroblock (`mx`, `my`) of `row`; with `flex_inline` the flexbits
    /// follow each block.
    fn cbp_hp(&mut self, row: &mut [i32], r: &mut BitReader, mx: usize, my: usize, flex_inline: bool) -> Result<()> {
        let ch = self.hdr.channels;
        let s = my % 2;
        let [c0, c1] = &mut self.cbp;
        let (cur_row, prev_row) = if s == 0 { (c0, &*c1) } else { (c1, &*c0) };
        let (before, rest) = cur_row.split_at_mut(mx * ch);
        let left = (mx > 0).then(|| &before[(mx - 1) * ch..]);
        let top = (my > 0).then(|| &prev_row[mx * ch..(mx + 1) * ch]);
        let cur_cbp = &mut rest[..ch];
        self.dec.cbp(r, left, top, cur_cbp)?;
        let stride = ch * MB_COEFFS;
        let c = &mut row[mx * stride..(mx + 1) * stride];
        let mode = predict::hp_mode(self.hdr.clr_fmt, c);
        let bits = self.dec.hp(r, c, cur_cbp, mode, mx as u32, self.w as u32, flex_inline)?;
        self.side[s][mx].hp_mode = mode;
        self.side[s][mx].hp_bits = bits;
        Ok(())
    }

    /// FLEXBITS of macroblock (`mx`, `my`) of `row` from a FLEXBITS packet.
    fn flex(&mut self, row: &mut [i32], r: &mut BitReader, mx: usize, my: usize) {
        let bits = self.side[my % 2][mx].hp_bits;
        let (fmt, channels, trim) = (self.hdr.clr_fmt, self.hdr.channels, self.dec.trim);
        macroblock::flex_mb(r, self.mb(row, mx), fmt, channels, trim, bits);
    }

    /// HP prediction of macroblock (`mx`, `my`) of `row` (after its flexbits).
    fn predict_hp(&mut self, row: &mut [i32], mx: usize, my: usize) {
        let (fmt, channels) = (self.hdr.clr_fmt, self.hdr.channels);
        let mode = self.side[my % 2][mx].hp_mode;
        predict_hp_mb(fmt, channels, self.mb(row, mx), mode);
    }

    /// The end of row `my` (decoded into `row`): keeps its DC and LP coefficients for the
    /// next row's prediction, then dequantizes it in place, unless (`quantized`) a FLEXBITS
    /// stage completes it.
    fn finish_row(&mut self, row: &mut [i32], my: usize, quantized: bool) -> Result<()> {
        if quantized {
            keep_dc_lp(&mut self.top, row);
            return Ok(());
        }
        let mbs = self.side[my % 2].len().min(row.len() / self.stride());
        (0..mbs).try_for_each(|mx| self.finish_mb(row, mx, my))
    }

    /// [`finish_row`](Self::finish_row), dequantizing, for macroblock `mx` alone (the row
    /// runs it on each macroblock): in
    /// frequency order the last packet's pass runs it on each macroblock while it is in cache
    /// (every DC and LP prediction of the row, which reads the row above and the macroblock to
    /// the left quantized, ran in an earlier pass).
    #[inline(always)]
    fn finish_mb(&mut self, row: &mut [i32], mx: usize, my: usize) -> Result<()> {
        let stride = self.stride();
        let c = &mut row[mx * stride..(mx + 1) * stride];
        keep_dc_lp(&mut self.top[mx * stride..(mx + 1) * stride], c);
        dequantize_mb(c, &self.side[my % 2][mx], &self.qp, self.hdr.clr_fmt, self.hdr.scaled)
    }
}

/// Copies the DC and LP coefficients (the first 16 of each block of [`MB_COEFFS`]) of the
/// macroblocks `cur` into `top`, for the next row's prediction.
#[inline(always)]
fn keep_dc_lp(top: &mut [i32], cur: &[i32]) {
    for (top, cur) in top.chunks_exact_mut(MB_COEFFS).zip(cur.chunks_exact(MB_COEFFS)) {
        top[..16].copy_from_slice(&cur[..16]);
    }
}

/// HP prediction of one macroblock (`c`: all channels); for 420 and 422 the luma call also
/// predicts the chroma channels.
fn predict_hp_mb(fmt: ClrFmt, channels: usize, c: &mut [i32], mode: u8) {
    let channels = if matches!(fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422) { 1 } else { channels };
    for ch in 0..channels {
        predict::predict_hp(fmt, c, ch, mode);
    }
}

/// The DC, LP and HP quantizer indices (per channel) of a macroblock.
fn mb_steps<'q>(side: &MbSide, qp: &'q TileQp) -> Result<(&'q [u8], &'q [u8], &'q [u8])> {
    let lp = qp.lp.get(usize::from(side.lp_qi)).ok_or_else(|| Error::invalid("JPEG XR: LP QP index"))?;
    let hp = qp.hp.get(usize::from(side.hp_qi)).ok_or_else(|| Error::invalid("JPEG XR: HP QP index"))?;
    Ok((&qp.dc.index[..], &lp.index[..], &hp.index[..]))
}

/// Dequantizes one macroblock (`c`: all channels) with the tile's quantizers.
fn dequantize_mb(c: &mut [i32], side: &MbSide, qp: &TileQp, fmt: ClrFmt, scaled: bool) -> Result<()> {
    let (dc, lp, hp) = mb_steps(side, qp)?;
    for (ch, cc) in c.chunks_exact_mut(MB_COEFFS).enumerate() {
        let luma = ch == 0;
        quant::dequantize(
            cc,
            quant::channel_shape(fmt, ch),
            quant::step(dc[ch], scaled, luma),
            quant::step(lp[ch], scaled, luma),
            quant::step(hp[ch], scaled, true),
        );
    }
    Ok(())
}

/// Runs `f` on every macroblock of row `my` (`w` wide), each plane in turn (primary, then
/// alpha, with that plane's row), then checks that the packet did not run out. Before each
/// macroblock the packet's window is made to hold what a macroblock can consume.
fn each_mb<F>(
    planes: &mut [PlaneWork],
    rows: &mut [&mut [i32]],
    packet: &mut Packet,
    w: usize,
    my: usize,
    what: &str,
    mut f: F,
) -> Result<()>
where
    F: FnMut(&mut PlaneWork, &mut [i32], &mut BitReader, usize, usize) -> Result<()>,
{
    if let Some(mut r) = packet.memory_reader() {
        // In memory: one reader through the row.
        for mx in 0..w {
            #[cfg(test)]
            packet.note(r.bit_pos());
            for (p, row) in planes.iter_mut().zip(rows.iter_mut()) {
                f(p, row, &mut r, mx, my)?;
            }
        }
        packet.set_state(r.state());
        return packet.check(what);
    }
    // From a file: before each macroblock, the window is made to hold what a macroblock can
    // consume.
    for mx in 0..w {
        packet.reserve()?;
        let mut r = packet.window_reader();
        for (p, row) in planes.iter_mut().zip(rows.iter_mut()) {
            f(p, row, &mut r, mx, my)?;
        }
        let state = r.state();
        packet.set_state(state);
    }
    packet.check(what)
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

/// Decodes one tile macroblock row at a time: entropy decoding, prediction and
/// dequantization of tile (`tx`, `ty`). Its state (readers of its packets, adaptive
/// contexts, the row above) is its own, so the tiles of a tile row decode independently.
pub struct TileDecoder<'a> {
    w: usize,
    h: usize,
    my: usize,
    bands: Bands,
    frequency: bool,
    /// Spatial: the tile's packet. Frequency: DC, LP, HP and FLEXBITS, as many as coded.
    readers: Vec<Packet<'a>>,
    planes: Vec<PlaneWork<'a>>,
    /// Leave the FLEXBITS packet, HP prediction and dequantization to a [`FlexStage`].
    defer_flex: bool,
}

impl<'a> TileDecoder<'a> {
    /// Locates the tile's packets and reads their start codes and tile headers.
    pub(crate) fn new(cs: &'a Codestream, data: Source<'a>, tx: usize, ty: usize) -> Result<Self> {
        Self::with_bands(cs, data, tx, ty, 4)
    }

    /// [`new`](Self::new), reading in frequency order only the first `max_bands` packets of
    /// the tile (1: DC; 2: DC and LP): a reduced-resolution decode never opens the others.
    /// Spatial order has one packet and ignores the limit.
    pub(crate) fn with_bands(
        cs: &'a Codestream,
        data: Source<'a>,
        tx: usize,
        ty: usize,
        max_bands: usize,
    ) -> Result<Self> {
        let (_, _, w, h) = tile_rect(cs, tx, ty);
        let (w, h) = (w as usize, h as usize);
        let mut planes = vec![PlaneWork::new(&cs.primary, w)];
        if let Some(a) = &cs.alpha {
            planes.push(PlaneWork::new(a, w));
        }
        let tile = ty * cs.image.tile_widths.len() + tx;
        let bands = cs.primary.bands;
        let frequency = cs.image.frequency_mode;
        let per_tile = if frequency { bands.count() } else { 1 };
        let mut readers = Vec::with_capacity(per_tile);
        // What a macroblock consumes at most, for the packets' windows of a file (the tile
        // headers take less).
        let bound = crate::source::mb_bound(cs);
        let bands_read = per_tile.min(max_bands.max(1));
        let open = bands_read * cs.image.tile_widths.len();
        for band in 0..bands_read {
            let entry = cs.packets.get(tile * per_tile + band).ok_or_else(|| Error::invalid("JPEG XR: index table"))?;
            let mut packet = data.packet(*entry, bound, open)?;
            // jxrlib tolerates a bad FLEXBITS start code.
            packet.run(|r| start_code(r, band < 3))?;
            readers.push(packet);
        }
        let trim_flag = cs.image.trim_flexbits;
        if !frequency {
            readers[0].run(|r| {
                let trim = if trim_flag { r.read(4) } else { 0 };
                for p in &mut planes {
                    p.dec.trim = trim;
                    p.header_dc(r);
                    p.header_lp(r);
                    p.header_hp(r);
                }
            });
        } else {
            readers[0].run(|r| planes.iter_mut().for_each(|p| p.header_dc(r)));
            if let Some(packet) = readers.get_mut(1) {
                packet.run(|r| planes.iter_mut().for_each(|p| p.header_lp(r)));
            }
            if let Some(packet) = readers.get_mut(2) {
                packet.run(|r| planes.iter_mut().for_each(|p| p.header_hp(r)));
            }
            if let Some(packet) = readers.get_mut(3) {
                let trim = packet.run(|r| if trim_flag { r.read(4) } else { 0 });
                planes.iter_mut().for_each(|p| p.dec.trim = trim);
            }
        }
        for r in &readers {
            r.check("a JPEG XR tile header")?;
        }
        // Every coefficient is written when LP and HP are decoded (in frequency order, their
        // packets read) and no channel is subsampled.
        let hp_read = !frequency || readers.len() >= 3;
        for p in &mut planes {
            let subsampled = matches!(p.hdr.clr_fmt, ClrFmt::Yuv420 | ClrFmt::Yuv422);
            p.clear = !(hp_read && p.hdr.bands.has_hp() && !subsampled);
        }
        Ok(TileDecoder { w, h, my: 0, bands, frequency, readers, planes, defer_flex: false })
    }

    /// Decodes the next macroblock row into `out` (one buffer per plane: primary, then
    /// alpha; each exactly `width × channels` arrays of [`MB_COEFFS`] long), dequantized and
    /// predicted. An error after the last row.
    pub fn next_row(&mut self, out: &mut [&mut [i32]]) -> Result<()> {
        self.decode_row(out, None)
    }

    /// Appends to `out` the HP quantizer step of every channel of every macroblock of the row
    /// [`next_row`](Self::next_row) last decoded, plane `plane` (0 primary, 1 interleaved
    /// alpha): macroblocks in order, channels inner. Needs the HP band.
    pub(crate) fn last_row_hp_steps(&self, plane: usize, out: &mut Vec<i32>) -> Result<()> {
        let p = self.planes.get(plane).ok_or_else(|| Error::invalid("JPEG XR: no such plane (a bug)"))?;
        let row = self.my.checked_sub(1).ok_or_else(|| Error::invalid("JPEG XR: no row decoded yet (a bug)"))?;
        for side in &p.side[row % 2] {
            let set = p.qp.hp.get(usize::from(side.hp_qi)).ok_or_else(|| Error::invalid("JPEG XR: HP QP index"))?;
            out.extend(set.index[..p.hdr.channels].iter().map(|&i| quant::step(i, p.hdr.scaled, true)));
        }
        Ok(())
    }

    /// True when the codestream has a FLEXBITS packet that a [`FlexStage`] can decode apart
    /// (frequency order with flexbits).
    pub fn has_flex_packet(&self) -> bool {
        self.readers.len() == 4
    }

    /// Decodes the next row without its FLEXBITS (which must be in a packet of their own):
    /// `out` gets the row quantized, without HP prediction, and `side` (one per plane, a row
    /// long) what [`FlexStage::complete_row`] needs.
    pub(crate) fn next_row_deferred(&mut self, out: &mut [&mut [i32]], side: &mut [&mut [MbSide]]) -> Result<()> {
        if !self.has_flex_packet() {
            return Err(Error::invalid("JPEG XR: deferred flexbits without a FLEXBITS packet (a bug)"));
        }
        self.defer_flex = true;
        self.decode_row(out, Some(side))
    }

    fn decode_row(&mut self, out: &mut [&mut [i32]], side: Option<&mut [&mut [MbSide]]>) -> Result<()> {
        let (w, my, bands) = (self.w, self.my, self.bands);
        if my >= self.h {
            return Err(Error::invalid("JPEG XR: a tile read past its last row (a bug in the decoder)"));
        }
        for p in &mut self.planes {
            p.start_row(my);
        }
        if out.len() < self.planes.len() {
            return Err(Error::invalid("JPEG XR: too few row buffers (a bug in the decoder)"));
        }
        let mut rows = Vec::with_capacity(self.planes.len());
        for (p, o) in self.planes.iter().zip(out.iter_mut()) {
            let len = w * p.stride();
            rows.push(
                o.get_mut(..len).ok_or_else(|| Error::invalid("JPEG XR: a short row buffer (a bug in the decoder)"))?,
            );
        }
        let rows = &mut rows[..];
        let planes = &mut self.planes;
        let mut finished = false;
        if !self.frequency {
            let r = &mut self.readers[0];
            each_mb(planes, rows, r, w, my, "a JPEG XR tile", |p, row, r, mx, my| {
                p.read_lp_index(r, mx, my)?;
                p.read_hp_index(r, mx, my)?;
                p.dc(row, r, mx);
                if p.hdr.bands.has_lp() {
                    p.lp(row, r, mx)?;
                }
                p.predict_dclp(row, mx, my);
                if p.hdr.bands.has_hp() {
                    p.cbp_hp(row, r, mx, my, p.hdr.bands.has_flex())?;
                    p.predict_hp(row, mx, my);
                }
                Ok(())
            })?;
        } else {
            let [dc, rest @ ..] = &mut self.readers[..] else { unreachable!("a DC packet") };
            let r = dc;
            // The last pass (FLEXBITS, or HP when there is no FLEXBITS packet) dequantizes
            // each macroblock as it goes ([`PlaneWork::finish_mb`]). Deferred flexbits leave
            // only the copy of DC and LP, which stays a pass after the row.
            let flex_last = rest.len() >= 3 && !self.defer_flex;
            let hp_last = rest.len() == 2;
            finished = flex_last || hp_last;
            // Without an LP packet (coded but not read), DC prediction runs here.
            let lp_read = !rest.is_empty();
            each_mb(planes, rows, r, w, my, "a JPEG XR DC packet", |p, row, r, mx, my| {
                p.dc(row, r, mx);
                if !p.hdr.bands.has_lp() || !lp_read {
                    p.predict_dclp(row, mx, my);
                }
                Ok(())
            })?;
            if let Some(r) = rest.get_mut(0) {
                each_mb(planes, rows, r, w, my, "a JPEG XR LP packet", |p, row, r, mx, my| {
                    p.read_lp_index(r, mx, my)?;
                    p.lp(row, r, mx)?;
                    p.predict_dclp(row, mx, my);
                    Ok(())
                })?;
            }
            if let Some(r) = rest.get_mut(1) {
                each_mb(planes, rows, r, w, my, "a JPEG XR HP packet", |p, row, r, mx, my| {
                    p.read_hp_index(r, mx, my)?;
                    p.cbp_hp(row, r, mx, my, false)?;
                    if bands == Bands::NoFlexbits {
                        p.predict_hp(row, mx, my);
                    }
                    if hp_last {
                        p.finish_mb(row, mx, my)?;
                    }
                    Ok(())
                })?;
            }
            if let Some(r) = rest.get_mut(2).filter(|_| !self.defer_flex) {
                each_mb(planes, rows, r, w, my, "a JPEG XR FLEXBITS packet", |p, row, r, mx, my| {
                    p.flex(row, r, mx, my);
                    p.predict_hp(row, mx, my);
                    if flex_last {
                        p.finish_mb(row, mx, my)?;
                    }
                    Ok(())
                })?;
            }
        }
        if !finished {
            for (p, row) in self.planes.iter_mut().zip(rows.iter_mut()) {
                p.finish_row(row, my, self.defer_flex)?;
            }
        }
        if let Some(side) = side {
            for (p, s) in self.planes.iter().zip(side.iter_mut()) {
                s.get_mut(..w)
                    .ok_or_else(|| Error::invalid("JPEG XR: a short side buffer (a bug in the decoder)"))?
                    .copy_from_slice(&p.side[my % 2]);
            }
        }
        self.my += 1;
        Ok(())
    }
}

/// The FLEXBITS packet of a tile in frequency order, decoded apart from the other packets
/// (so that it can run on another thread than the DC, LP and HP packets, a row behind them):
/// completes the rows [`TileDecoder::next_row_deferred`] gives with their flexbits, HP
/// prediction and dequantization.
pub(crate) struct FlexStage<'a> {
    w: usize,
    reader: Packet<'a>,
    trim: u32,
    /// Per plane: INTERNAL_CLR_FMT, channels, SCALED_FLAG and the tile's quantizers.
    planes: Vec<(ClrFmt, usize, bool, TileQp)>,
}

impl<'a> FlexStage<'a> {
    /// The FLEXBITS stage of tile (`tx`, `ty`) (the tile headers are read again for its
    /// quantizers).
    pub fn new(cs: &'a Codestream, data: Source<'a>, tx: usize, ty: usize) -> Result<Self> {
        let mut t = TileDecoder::new(cs, data, tx, ty)?;
        let reader = t.readers.pop().filter(|_| t.readers.len() == 3).ok_or_else(|| {
            Error::invalid("JPEG XR: a FLEXBITS stage without a FLEXBITS packet (a bug in the decoder)")
        })?;
        let trim = t.planes[0].dec.trim;
        let planes = t.planes.iter().map(|p| (p.hdr.clr_fmt, p.hdr.channels, p.hdr.scaled, p.qp.clone())).collect();
        Ok(FlexStage { w: t.w, reader, trim, planes })
    }

    /// Completes one row (per plane: the row, and its side information).
    pub fn complete_row(&mut self, rows: &mut [&mut [i32]], side: &[&[MbSide]]) -> Result<()> {
        if rows.len() < self.planes.len() || side.len() < self.planes.len() {
            return Err(Error::invalid("JPEG XR: a FLEXBITS stage given too few planes (a bug)"));
        }
        // In memory one reader runs through the row; a window is checked before each
        // macroblock.
        let mut memory = self.reader.memory_reader();
        for mx in 0..self.w {
            match &memory {
                None => self.reader.reserve()?,
                #[cfg(test)]
                Some(r) => self.reader.note(r.bit_pos()),
                #[cfg(not(test))]
                Some(_) => {}
            }
            for (i, (fmt, channels, scaled, qp)) in self.planes.iter().enumerate() {
                let stride = channels * MB_COEFFS;
                let c = rows[i]
                    .get_mut(mx * stride..(mx + 1) * stride)
                    .ok_or_else(|| Error::invalid("JPEG XR: a short row (a bug)"))?;
                let s = side[i].get(mx).ok_or_else(|| Error::invalid("JPEG XR: a short side row (a bug)"))?;
                match &mut memory {
                    Some(r) => macroblock::flex_mb(r, c, *fmt, *channels, self.trim, s.hp_bits),
                    None => self.reader.run(|r| macroblock::flex_mb(r, c, *fmt, *channels, self.trim, s.hp_bits)),
                }
                predict_hp_mb(*fmt, *channels, c, s.hp_mode);
                // Dequantized while in cache.
                dequantize_mb(c, s, qp, *fmt, *scaled)?;
            }
        }
        if let Some(r) = memory {
            self.reader.set_state(r.state());
        }
        self.reader.check("a JPEG XR FLEXBITS packet")
    }
}

/// Bytes a [`TileDecoder`] holds: two rows of coefficients and side information per plane.
pub fn tile_bytes(cs: &Codestream, tx: usize, ty: usize) -> u64 {
    let (_, _, w, _) = tile_rect(cs, tx, ty);
    let channels = cs.primary.channels + cs.alpha.as_ref().map_or(0, |a| a.channels);
    2 * u64::from(w) * (channels as u64 * (MB_COEFFS as u64 * 4 + 4) + 32)
}
