//! From a codestream to the dequantized, predicted coefficients of every macroblock: the
//! headers, then the macroblock rows of every tile column together ([`RowDecoder`]; the
//! tile columns in parallel on the caller's [`ThreadPool`]), collected by
//! [`decode_coefficients`] or consumed row by row.

use crate::header::{self, ClrFmt, Codestream};
use crate::mb::{MbCoeffs, MB_COEFFS};
use crate::source::Source;
use crate::tiles::{self, FlexStage, MbSide, TileDecoder};
use hdrcodec_core::{Allocation, DecodeOptions, Error, Result, ThreadPool};

/// The coefficients of one plane (primary or alpha), for the inverse transform.
#[derive(Debug)]
pub struct PlaneCoeffs {
    /// INTERNAL_CLR_FMT of the plane.
    pub fmt: ClrFmt,
    /// Channels of the plane.
    pub channels: usize,
    /// SCALED_FLAG of the plane.
    pub scaled: bool,
    mb_width: u32,
    mb_height: u32,
    /// Macroblocks in raster order, each `channels` arrays of [`MB_COEFFS`].
    coeffs: Vec<i32>,
}

impl PlaneCoeffs {
    /// Width in macroblocks (of the extended image).
    pub fn mb_width(&self) -> u32 {
        self.mb_width
    }

    /// Height in macroblocks.
    pub fn mb_height(&self) -> u32 {
        self.mb_height
    }

    /// The coefficients of channel `ch` of macroblock (`x`, `y`), in the layout of
    /// [`crate::mb`]: dequantized and predicted, the inverse transform's input.
    ///
    /// # Panics
    /// If the macroblock or channel is outside the plane.
    pub fn mb(&self, ch: usize, x: u32, y: u32) -> &MbCoeffs {
        assert!(x < self.mb_width && ch < self.channels);
        let i = y as usize * self.mb_width as usize + x as usize;
        let o = (i * self.channels + ch) * MB_COEFFS;
        self.coeffs[o..o + MB_COEFFS].try_into().expect("a macroblock is MB_COEFFS long")
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

/// Checks what can be checked before allocating: the size against the limits, and that the
/// codestream is long enough for its macroblocks (each takes at least one bit, its DC flags:
/// a short stream declaring a large image is truncated, whatever the limits allow).
pub(crate) fn check_size(cs: &Codestream, len: u64, options: &DecodeOptions) -> Result<()> {
    options.limits.check_dimensions(u64::from(cs.image.width), u64::from(cs.image.height))?;
    let mbs = u64::from(cs.image.mb_width) * u64::from(cs.image.mb_height);
    if mbs > len.saturating_mul(8) {
        return Err(Error::truncated(format!("the JPEG XR codestream ({len} bytes cannot hold {mbs} macroblocks)")));
    }
    Ok(())
}

/// Decodes a codestream one macroblock row at a time, all tile columns together (in parallel
/// on the caller's pool when there are several): the input of a band-by-band inverse
/// transform. Holds two macroblock rows per tile column and plane.
pub struct RowDecoder<'a> {
    cs: &'a Codestream,
    data: Source<'a>,
    pool: ThreadPool,
    /// The next tile row, the next macroblock row, and the rows left in the current tile row.
    ty: usize,
    my: u32,
    left: u32,
    /// The current tile row's decoders (`None` for the columns not decoded).
    tiles: Vec<Option<TileDecoder<'a>>>,
    /// Frequency order: how many of each tile's packets to read (DC, LP, HP, FLEXBITS).
    max_bands: usize,
    /// The tile columns to decode (`None`: all); the others' macroblocks are zero.
    columns: Option<Vec<bool>>,
    _charge: Allocation,
}

impl<'a> RowDecoder<'a> {
    /// Starts decoding `data`, whose headers are `cs` (from [`header::parse`]); charges its
    /// working memory to `options.limits`.
    pub fn new(cs: &'a Codestream, data: &'a [u8], options: &DecodeOptions) -> Result<Self> {
        Self::from_source(cs, Source::Memory(data), options)
    }

    /// [`new`](Self::new) for a codestream in memory or in a file.
    pub(crate) fn from_source(cs: &'a Codestream, data: Source<'a>, options: &DecodeOptions) -> Result<Self> {
        check_size(cs, data.len(), options)?;
        let bytes = (0..cs.image.tile_widths.len()).map(|tx| tiles::tile_bytes(cs, tx, 0) * 2).sum();
        let charge = options.limits.charge(bytes, "the JPEG XR entropy decoder's rows")?;
        Ok(RowDecoder {
            cs,
            data,
            pool: options.pool.clone(),
            ty: 0,
            my: 0,
            left: 0,
            tiles: Vec::new(),
            max_bands: 4,
            columns: None,
            _charge: charge,
        })
    }

    /// In frequency order, reads only the first `n` packets of each tile (1: DC only, 2: DC
    /// and LP); the coefficients of the bands not read stay zero. For reduced-resolution
    /// decoding, which needs no more. Spatial order must parse everything and ignores it.
    pub(crate) fn limit_bands(&mut self, n: usize) {
        self.max_bands = n;
    }

    /// The macroblock row [`next_row`](Self::next_row) gives next.
    pub(crate) fn next_row_index(&self) -> u32 {
        self.my
    }

    /// Decodes only the tile columns `keep` marks (one flag per tile column); the macroblocks
    /// of the others come out zero. For decoding a region.
    pub(crate) fn only_tile_columns(&mut self, keep: Vec<bool>) {
        self.columns = Some(keep);
    }

    /// Starts at tile row `ty` (before the first row is decoded): the rows above it are never
    /// read, and [`next_row`](Self::next_row) goes on from the tile row's first macroblock row.
    pub(crate) fn start_at_tile_row(&mut self, ty: usize) -> Result<()> {
        let img = &self.cs.image;
        if self.my != 0 || ty >= img.tile_heights.len() {
            return Err(Error::invalid("JPEG XR: a start past the last tile row (a bug in the decoder)"));
        }
        self.ty = ty;
        self.my = img.tile_heights[..ty].iter().sum();
        Ok(())
    }

    /// The next macroblock row (`None` after the last): for each plane (primary, then
    /// alpha), `mb_width × channels` arrays of [`MB_COEFFS`], dequantized and predicted.
    pub fn next_row(&mut self, out: &mut [Vec<i32>]) -> Result<Option<u32>> {
        if self.my >= self.cs.image.mb_height {
            return Ok(None);
        }
        self.next_rows(&mut [out], None)?;
        Ok(Some(self.my - 1))
    }

    /// True when the codestream's flexbits are in packets of their own (frequency order with
    /// flexbits): [`next_rows`](Self::next_rows) can leave them out and a [`RowCompleter`]
    /// then decode them on another thread, a row behind.
    pub(crate) fn can_defer_flex(cs: &Codestream) -> bool {
        cs.image.frequency_mode && cs.primary.bands.has_flex()
    }

    /// The next `outs.len()` rows at once, each as [`next_row`](Self::next_row) gives it; with
    /// `sides` (one per row), without their flexbits: quantized, before HP prediction, with
    /// the side information (one per plane, `mb_width` long) that [`RowCompleter::complete`]
    /// needs. On a pool, each tile column decodes its part of [`PARALLEL_ROUND_ROWS`] rows as
    /// one job (see there). An error past the last row.
    pub(crate) fn next_rows(
        &mut self,
        outs: &mut [&mut [Vec<i32>]],
        sides: Option<Vec<&mut [Vec<MbSide>]>>,
    ) -> Result<()> {
        let (cs, data) = (self.cs, self.data);
        let img = &cs.image;
        if sides.as_ref().is_some_and(|s| s.len() != outs.len())
            || self.my as usize + outs.len() > img.mb_height as usize
        {
            return Err(Error::invalid("JPEG XR: rows past the image (a bug in the decoder)"));
        }
        let planes: Vec<&header::PlaneHeader> = std::iter::once(&cs.primary).chain(cs.alpha.as_ref()).collect();
        let mb_w = img.mb_width as usize;
        let short = || Error::invalid("JPEG XR: the tile widths exceed the image width");
        let mut sides = sides.map(|s| s.into_iter());
        let mut outs = outs.iter_mut();
        while outs.len() > 0 {
            if self.left == 0 {
                let ty = self.ty;
                let keep = |tx: usize| self.columns.as_ref().is_none_or(|k| k.get(tx).copied().unwrap_or(true));
                self.tiles = (0..img.tile_widths.len())
                    .map(|tx| keep(tx).then(|| TileDecoder::with_bands(cs, data, tx, ty, self.max_bands)).transpose())
                    .collect::<Result<_>>()?;
                self.left = img.tile_heights[ty];
                self.ty += 1;
            }
            let round = if self.pool.is_parallel() { PARALLEL_ROUND_ROWS } else { usize::MAX };
            let seg = (self.left as usize).min(outs.len()).min(round);
            // Every tile column decodes straight into its part of each row (a tile column's
            // macroblocks are contiguous in it): no row buffers per tile to copy from.
            let mut jobs: Vec<TileJob<'_, 'a>> =
                self.tiles.iter_mut().map(|t| (t.as_mut(), Vec::new(), Vec::new())).collect();
            for _ in 0..seg {
                let (out, side) = (outs.next().ok_or_else(short)?, sides.as_mut().and_then(|s| s.next()));
                for job in jobs.iter_mut() {
                    job.1.push(Vec::new());
                    job.2.push(side.is_some().then(Vec::new));
                }
                for (o, hdr) in out.iter_mut().zip(&planes) {
                    let stride = hdr.channels * MB_COEFFS;
                    if o.capacity() < mb_w * stride {
                        // A fresh allocation, zeroed by the allocator (fresh pages need no clearing).
                        *o = vec![0; mb_w * stride];
                    } else {
                        o.resize(mb_w * stride, 0);
                    }
                    let mut rest = &mut o[..];
                    for (job, &w) in jobs.iter_mut().zip(&img.tile_widths) {
                        let (part, tail) =
                            std::mem::take(&mut rest).split_at_mut_checked(w as usize * stride).ok_or_else(short)?;
                        job.1.last_mut().ok_or_else(short)?.push(part);
                        rest = tail;
                    }
                }
                if let Some(side) = side {
                    for s in side.iter_mut().take(planes.len()) {
                        s.resize(mb_w, MbSide::default());
                        let mut rest = &mut s[..];
                        for (job, &w) in jobs.iter_mut().zip(&img.tile_widths) {
                            let (part, tail) =
                                std::mem::take(&mut rest).split_at_mut_checked(w as usize).ok_or_else(short)?;
                            job.2.last_mut().and_then(Option::as_mut).ok_or_else(short)?.push(part);
                            rest = tail;
                        }
                    }
                }
            }
            let decode = |job: &mut TileJob<'_, 'a>| {
                job.1.iter_mut().zip(job.2.iter_mut()).try_for_each(|(row, sides)| match (&mut job.0, sides) {
                    (Some(t), Some(sides)) => t.next_row_deferred(row, sides),
                    (Some(t), None) => t.next_row(row),
                    (None, sides) => {
                        row.iter_mut().for_each(|p| p.fill(0));
                        sides.iter_mut().flatten().for_each(|s| s.fill(MbSide::default()));
                        Ok(())
                    }
                })
            };
            if jobs.len() > 1 && self.pool.is_parallel() {
                self.pool.try_for_each_chunk_mut(&mut jobs, 1, |_, j| decode(&mut j[0]))?;
            } else {
                jobs.iter_mut().try_for_each(decode)?;
            }
            self.left -= seg as u32;
            self.my += seg as u32;
        }
        Ok(())
    }
}

/// The rows a tile column decodes as one job of the pool in [`RowDecoder::next_rows`]: one.
/// The two-thread decoder runs the next band's entropy decoding beside this band's transform
/// and formatting, and whichever side finishes first takes the other's jobs; a step then ends
/// with the last job started. Tile columns a whole band long (8 rows, 0.4–0.7 ms each on the
/// 13 MP files of 4×4 tiles) left one thread idle for up to that long at the end of each
/// band: 10–15% of the two threads' time, measured with timestamps of every job. Jobs a row
/// long cost a hand-over per row (a few µs) and cut that idle time by half (lossless and q 0.6)
/// or a quarter (q 0.3).
const PARALLEL_ROUND_ROWS: usize = 1;

/// One tile column's share of rows in [`RowDecoder::next_rows`]: its decoder and, for each row,
/// its part of each plane's row and (deferred flexbits) of each plane's side information.
#[allow(clippy::type_complexity)]
type TileJob<'t, 'a> = (Option<&'t mut TileDecoder<'a>>, Vec<Vec<&'t mut [i32]>>, Vec<Option<Vec<&'t mut [MbSide]>>>);

/// The FLEXBITS half of a deferred [`RowDecoder`]: completes its rows (flexbits, HP
/// prediction, dequantization), in order, the tile columns of a row in parallel on the pool
/// (each has its own FLEXBITS packet).
pub(crate) struct RowCompleter<'a> {
    cs: &'a Codestream,
    data: Source<'a>,
    pool: ThreadPool,
    ty: usize,
    left: u32,
    stages: Vec<FlexStage<'a>>,
}

/// One tile column's share of a row in [`RowCompleter::complete`]: its stage, its part of each
/// plane's row and of each plane's side information.
type FlexJob<'t, 'a> = (&'t mut FlexStage<'a>, Vec<&'t mut [i32]>, Vec<&'t [MbSide]>);

impl<'a> RowCompleter<'a> {
    /// The completer of the rows a deferred [`RowDecoder`] of the same codestream gives, on
    /// `pool`'s threads.
    pub fn new(cs: &'a Codestream, data: Source<'a>, pool: ThreadPool) -> Self {
        RowCompleter { cs, data, pool, ty: 0, left: 0, stages: Vec::new() }
    }

    /// Completes the next row (`out` and `side` as [`RowDecoder::next_rows`] gave them).
    pub fn complete(&mut self, out: &mut [Vec<i32>], side: &[Vec<MbSide>]) -> Result<()> {
        let img = &self.cs.image;
        if self.left == 0 {
            let (cs, data, ty) = (self.cs, self.data, self.ty);
            if ty >= img.tile_heights.len() {
                return Err(Error::invalid("JPEG XR: rows past the image (a bug in the decoder)"));
            }
            self.stages =
                (0..img.tile_widths.len()).map(|tx| FlexStage::new(cs, data, tx, ty)).collect::<Result<_>>()?;
            self.left = img.tile_heights[ty];
            self.ty += 1;
        }
        let strides: Vec<usize> =
            std::iter::once(&self.cs.primary).chain(self.cs.alpha.as_ref()).map(|p| p.channels * MB_COEFFS).collect();
        let mut jobs: Vec<FlexJob<'_, 'a>> =
            self.stages.iter_mut().map(|stage| (stage, Vec::new(), Vec::new())).collect();
        // Each plane's row (and side information) cut into the tile columns' parts.
        for (o, &stride) in out.iter_mut().zip(&strides) {
            let mut rest = &mut o[..];
            for (job, &w) in jobs.iter_mut().zip(&img.tile_widths) {
                let (part, tail) =
                    std::mem::take(&mut rest).split_at_mut_checked(w as usize * stride).unwrap_or_default();
                job.1.push(part);
                rest = tail;
            }
        }
        for s in side.iter().take(strides.len()) {
            let mut rest = &s[..];
            for (job, &w) in jobs.iter_mut().zip(&img.tile_widths) {
                let (part, tail) = rest.split_at_checked(w as usize).unwrap_or_default();
                job.2.push(part);
                rest = tail;
            }
        }
        let complete = |job: &mut FlexJob<'_, 'a>| job.0.complete_row(&mut job.1, &job.2);
        if jobs.len() > 1 && self.pool.is_parallel() {
            self.pool.try_for_each_chunk_mut(&mut jobs, 1, |_, j| complete(&mut j[0]))?;
        } else {
            jobs.iter_mut().try_for_each(complete)?;
        }
        self.left -= 1;
        Ok(())
    }
}

/// Decodes every macroblock of the codestream `data` (which starts with `WMPHOTO`) to
/// coefficients: every tile in parallel on the caller's pool, each straight into its part of
/// the planes. Checks the size against `options.limits` and charges the coefficients (4 bytes
/// per coefficient, 256 per macroblock and channel) before allocating them.
pub fn decode_coefficients(data: &[u8], options: &DecodeOptions) -> Result<Coefficients> {
    let cs = header::parse(data)?;
    check_size(&cs, data.len() as u64, options)?;
    let img = &cs.image;
    let mbs = u64::from(img.mb_width) * u64::from(img.mb_height);
    let headers: Vec<&header::PlaneHeader> = std::iter::once(&cs.primary).chain(cs.alpha.as_ref()).collect();
    let channels: usize = headers.iter().map(|h| h.channels).sum();
    let charge = options.limits.charge(mbs * channels as u64 * MB_COEFFS as u64 * 4, "the JPEG XR coefficients")?;
    let (cols, rows) = (img.tile_widths.len(), img.tile_heights.len());
    let tile_bytes: u64 =
        (0..rows).flat_map(|ty| (0..cols).map(move |tx| (tx, ty))).map(|(tx, ty)| tiles::tile_bytes(&cs, tx, ty)).sum();
    let _work = options.limits.charge(tile_bytes, "the JPEG XR entropy decoder's rows")?;
    let mut planes: Vec<PlaneCoeffs> = headers
        .iter()
        .map(|hdr| PlaneCoeffs {
            fmt: hdr.clr_fmt,
            channels: hdr.channels,
            scaled: hdr.scaled,
            mb_width: img.mb_width,
            mb_height: img.mb_height,
            coeffs: vec![0; mbs as usize * hdr.channels * MB_COEFFS],
        })
        .collect();
    // Each tile's row segments of each plane: disjoint parts of the planes.
    let mut segments: Vec<Vec<Vec<&mut [i32]>>> = (0..cols * rows).map(|_| Vec::new()).collect();
    for plane in &mut planes {
        let stride = plane.channels * MB_COEFFS;
        let mut rest = &mut plane.coeffs[..];
        for seg in &mut segments {
            seg.push(Vec::new());
        }
        for (ty, &h) in img.tile_heights.iter().enumerate() {
            for _ in 0..h {
                for (tx, &w) in img.tile_widths.iter().enumerate() {
                    let (row, tail) = std::mem::take(&mut rest).split_at_mut(w as usize * stride);
                    segments[ty * cols + tx].last_mut().expect("a plane's segments").push(row);
                    rest = tail;
                }
            }
        }
    }
    let decode_tile = |t: usize, segs: &mut Vec<Vec<&mut [i32]>>| -> Result<()> {
        let mut tile = TileDecoder::new(&cs, data.into(), t % cols, t / cols)?;
        let h = img.tile_heights[t / cols] as usize;
        for r in 0..h {
            let mut row: Vec<&mut [i32]> = segs.iter_mut().map(|p| &mut *p[r]).collect();
            tile.next_row(&mut row)?;
        }
        Ok(())
    };
    if segments.len() > 1 && options.pool.is_parallel() {
        options.pool.try_for_each_chunk_mut(&mut segments, 1, |t, s| decode_tile(t, &mut s[0]))?;
    } else {
        segments.iter_mut().enumerate().try_for_each(|(t, s)| decode_tile(t, s))?;
    }
    drop(segments);
    let mut planes = planes.into_iter();
    let primary = planes.next().expect("the primary plane");
    Ok(Coefficients { codestream: cs, primary, alpha: planes.next(), _charge: charge })
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
        let container = crate::container::parse_container(file)?;
        decode_coefficients(container.image, &DecodeOptions::new(Limits::default()).with_pool(pool))
    }

    /// The coefficients T.835 reads into its inverse transform, hashed (testdata/README.md).
    const T835: [(&str, u64); 4] = [
        ("tiny_alpha_sp.jxr", 0xd4e4_baf3_bdb2_f132),
        ("tiny_tiles.jxr", 0xde2a_d77b_1d54_43bc),
        ("tiny_420_sp.jxr", 0xa046_70f4_d286_fe34),
        ("tiny_422.jxr", 0xb6ff_17cc_b011_8afa),
    ];

    /// Streams T.835's encoder wrote (testdata/README.md), with T.835's coefficient digests.
    const T835_WRITTEN: [(&str, u64); 5] = [
        ("t835_tile_qps.jxr", 0x5b2d_4590_ebf4_d5d8),
        ("t835_cmyk.jxr", 0x055b_88b4_b4cf_9d61),
        ("t835_qp_map.jxr", 0xf224_4214_b491_1af4),
        ("t835_ncomponent5.jxr", 0x7b4d_12b7_f1d9_f9eb),
        ("t835_ncomponent5_ol2.jxr", 0x4ea6_c787_3192_477c),
    ];

    #[test]
    fn t835_written_streams_match_t835() {
        for (name, want) in T835_WRITTEN {
            let c = coefficients(&testdata(name), hdrcodec_core::ThreadPool::single()).unwrap();
            assert_eq!(hash(&c), want, "{name}");
        }
    }

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

    /// The row decoder gives the same rows as the whole-image decode, tile rows included.
    #[test]
    fn row_decoder_gives_the_same_rows() {
        for (name, _) in T835 {
            let file = testdata(name);
            let cs_bytes = crate::container::parse_container(&file).unwrap().image;
            for pool in [hdrcodec_core::ThreadPool::single(), hdrcodec_core::ThreadPool::new(2).unwrap()] {
                let options = DecodeOptions::new(Limits::default()).with_pool(pool);
                let all = decode_coefficients(cs_bytes, &options).unwrap();
                let cs = header::parse(cs_bytes).unwrap();
                let mut rows = RowDecoder::new(&cs, cs_bytes, &options).unwrap();
                let mut out = vec![Vec::new(); 1 + usize::from(cs.alpha.is_some())];
                let mut n = 0;
                while let Some(y) = rows.next_row(&mut out).unwrap() {
                    assert_eq!(y, n);
                    for (plane, o) in std::iter::once(&all.primary).chain(all.alpha.as_ref()).zip(&out) {
                        let len = plane.mb_width() as usize * plane.channels * MB_COEFFS;
                        assert_eq!(&plane.coeffs[y as usize * len..][..len], &o[..], "{name} row {y}");
                    }
                    n += 1;
                }
                assert_eq!(n, cs.image.mb_height);
            }
        }
    }

    /// Row buffers full of garbage give the same rows: every coefficient of a macroblock is
    /// written (the decoder clears a macroblock only where its bands leave some unwritten).
    #[test]
    fn garbage_row_buffers_give_the_same_rows() {
        for (name, _) in T835.iter().chain(&T835_WRITTEN) {
            let file = testdata(name);
            let cs_bytes = crate::container::parse_container(&file).unwrap().image;
            let options = DecodeOptions::new(Limits::default());
            let all = decode_coefficients(cs_bytes, &options).unwrap();
            let cs = header::parse(cs_bytes).unwrap();
            let mut rows = RowDecoder::new(&cs, cs_bytes, &options).unwrap();
            let planes: Vec<&PlaneCoeffs> = std::iter::once(&all.primary).chain(all.alpha.as_ref()).collect();
            let lens: Vec<usize> = planes.iter().map(|p| p.mb_width() as usize * p.channels * MB_COEFFS).collect();
            let mut out: Vec<Vec<i32>> = lens.iter().map(|&n| vec![0; n]).collect();
            loop {
                out.iter_mut().for_each(|o| o.fill(0x5A5A_5A5A));
                let Some(y) = rows.next_row(&mut out).unwrap() else { break };
                for ((plane, o), &len) in planes.iter().zip(&out).zip(&lens) {
                    assert_eq!(&plane.coeffs[y as usize * len..][..len], &o[..], "{name} row {y}");
                }
            }
        }
    }

    /// Rows decoded a few at a time (each tile column's share of them one job, on one thread
    /// and on two), with the flexbits decoded apart (a deferred row decoder and its completer)
    /// or not, give the same rows as the decoder that does one row at a time.
    #[test]
    fn deferred_flexbits_give_the_same_rows() {
        let file = testdata("tiny_tiles.jxr");
        let bytes = crate::container::parse_container(&file).unwrap().image;
        let cs = header::parse(bytes).unwrap();
        assert!(RowDecoder::can_defer_flex(&cs));
        assert_eq!(cs.image.tile_widths.len(), 2);
        // Groups of three rows cross the tile rows' boundaries.
        assert!(cs.image.tile_heights.len() > 1 && cs.image.tile_heights.iter().any(|&h| h % 3 != 0));
        let mut whole = RowDecoder::new(&cs, bytes, &DecodeOptions::new(Limits::default())).unwrap();
        let mut rows = Vec::new();
        let mut a = vec![Vec::new()];
        while whole.next_row(&mut a).unwrap().is_some() {
            rows.push(a.clone());
        }
        assert_eq!(rows.len(), cs.image.mb_height as usize);
        for pool in [hdrcodec_core::ThreadPool::single(), hdrcodec_core::ThreadPool::new(2).unwrap()] {
            let options = DecodeOptions::new(Limits::default()).with_pool(pool.clone());
            let mut first = RowDecoder::new(&cs, bytes, &options).unwrap();
            let mut plain = RowDecoder::new(&cs, bytes, &options).unwrap();
            let mut completer = RowCompleter::new(&cs, bytes.into(), pool);
            for (g, group) in rows.chunks(3).enumerate() {
                let n = group.len();
                let (mut b, mut c) = (vec![vec![Vec::new()]; n], vec![vec![Vec::new()]; n]);
                let mut side = vec![vec![Vec::new()]; n];
                let mut outs: Vec<&mut [Vec<i32>]> = b.iter_mut().map(|r| &mut r[..]).collect();
                first.next_rows(&mut outs, Some(side.iter_mut().map(|s| &mut s[..]).collect())).unwrap();
                let mut outs: Vec<&mut [Vec<i32>]> = c.iter_mut().map(|r| &mut r[..]).collect();
                plain.next_rows(&mut outs, None).unwrap();
                for (i, want) in group.iter().enumerate() {
                    completer.complete(&mut b[i], &side[i]).unwrap();
                    assert_eq!((&b[i], &c[i]), (want, want), "row {}", g * 3 + i);
                }
            }
            let mut past = [vec![Vec::new()]];
            let mut outs: Vec<&mut [Vec<i32>]> = past.iter_mut().map(|r| &mut r[..]).collect();
            assert!(first.next_rows(&mut outs, None).is_err());
        }
    }

    /// Every truncation and a few hundred byte changes of each stream: an error or
    /// coefficients, never a panic, within a small allocation budget.
    #[test]
    fn truncated_and_corrupted_streams_never_panic() {
        let limits = Limits::default().with_max_alloc_bytes(64 << 20);
        for (name, _) in T835 {
            let file = testdata(name);
            let cs = crate::container::parse_container(&file).unwrap().image;
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
            let _ = crate::container::parse_container(&file[..file.len() / 2]);
            // The whole decoder (container, transform, output) on damaged files.
            let mut bad = file.clone();
            for n in (0..file.len()).step_by(7) {
                let _ = crate::render::decode_raw(&file[..n], &DecodeOptions::new(limits.clone()));
            }
            for _ in 0..200 {
                bad.copy_from_slice(&file);
                let at = (next() % file.len() as u64) as usize;
                bad[at] ^= 1 << (next() % 8);
                let _ = crate::render::decode_raw(&bad, &DecodeOptions::new(limits.clone()));
            }
        }
    }

    #[test]
    fn huge_declared_sizes_are_refused_before_allocating() {
        let file = testdata("tiny_422.jxr");
        let mut cs = crate::container::parse_container(&file).unwrap().image.to_vec();
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
