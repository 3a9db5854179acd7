//! Decoding a rectangle of an image at full resolution: entropy decoding of the tiles the
//! rectangle needs (from the first tile row it touches to its last macroblock row, and only
//! the tile columns within reach), the inverse transform of the macroblock rows it covers,
//! and output formatting of its pixels only.
//!
//! Reach: a pixel depends on the coefficients of its own macroblock and of the macroblocks
//! next to it (the stage-2 POT straddles macroblock seams by 8 pixels, the stage-1 POT block
//! seams by 2); 4:2:0 and 4:2:2 chroma upsampling interpolates with the next chroma sample,
//! one macroblock further. So the tile columns decoded are those within two macroblocks of
//! the rectangle, and the rows those `transform::inverse_band` asks for. The result equals
//! the same rectangle of a whole decode.

use crate::header::ClrFmt;
use crate::output::upsample_chroma_row;
use crate::reduced::{row_source, Rect, SetupParts};
use crate::render::kind;
use crate::transform::{self, PlaneKind};
use hdrcodec_core::sink::{fill_rows, RowSink, Scratch};
use hdrcodec_core::{DecodeOptions, Error, ImageInfo, Result};

/// Decodes `region` (image coordinates, checked by the caller) into `sink` and `raw_rows`.
pub(crate) fn decode_region(
    setup: &SetupParts,
    options: &DecodeOptions,
    region: Rect,
    info: ImageInfo,
    mut sink: Option<&mut dyn RowSink>,
    raw_rows: &mut dyn FnMut(usize, &[u8]),
) -> Result<()> {
    let cs = setup.cs;
    let img = &cs.image;
    let primary = &cs.primary;
    let out = setup.out;
    let (mb_w, mb_h) = (img.mb_width as usize, img.mb_height as usize);
    let [top, left, _, _] = img.margins.map(|m| m as usize);
    // The rectangle in extended (codestream) coordinates, and its macroblock rows and columns.
    let (x0, y0) = (left + region.x as usize, top + region.y as usize);
    let (w, h) = (region.width as usize, region.height as usize);
    let (ra, rb) = (y0 / 16, (y0 + h).div_ceil(16));
    let (ca, cb) = (x0 / 16, (x0 + w).div_ceil(16));
    if rb > mb_h || cb > mb_w {
        return Err(Error::invalid("JPEG XR: the region is outside the coded image"));
    }
    let planar = setup.planar_cs.zip(setup.alpha_data);
    let mut rows = row_source(cs, setup.data, planar, setup.with_alpha, options, 4)?;
    // Tile columns within two macroblocks of the rectangle; the first tile row that holds a
    // row the transform reads.
    let (reach0, reach1) = (ca.saturating_sub(2), (cb + 2).min(mb_w));
    let x_starts = img.tile_x0();
    let keep: Vec<bool> = (0..img.tile_widths.len())
        .map(|t| {
            let s = x_starts[t] as usize;
            let e = s + img.tile_widths[t] as usize;
            s < reach1 && e > reach0
        })
        .collect();
    let first_row = ra.saturating_sub(2);
    let y_starts = img.tile_y0();
    let ty = y_starts.iter().rposition(|&s| s as usize <= first_row).unwrap_or(0);
    rows.start(keep, ty)?;

    let n_prim = primary.channels;
    let internal = out.internal;
    let band = transform::BAND_MB_ROWS;
    let ext_w = 16 * mb_w;
    let coeff_bytes = ((band + 5) * mb_w * (n_prim + 1) * crate::mb::MB_COEFFS * 4) as u64;
    let sample_bytes = ((band + 1) * 16 * ext_w * 4 * (n_prim + 2)) as u64;
    let _charge = options.limits.charge(coeff_bytes + sample_bytes, "the JPEG XR region buffers")?;
    if let Some(s) = sink.as_deref_mut() {
        s.start(&info)?;
    }
    let row_len = w * setup.channels.count();
    let mut full = vec![vec![0i32; ext_w]; n_prim];
    let mut raw = vec![0u8; out.row_bytes(w)];
    let mut scratch = Scratch::new(&options.limits);
    let mut r0 = ra;
    while r0 < rb {
        let r1 = (r0 + band).min(rb);
        // inverse_band reads rows r0 − 2 .. r1 + 2; 4:2:0 chroma one more.
        rows.decode_to((r1 + 3).min(mb_h))?;
        rows.drop_before(r0.saturating_sub(2));
        let mut planes = Vec::with_capacity(n_prim);
        for ch in 0..n_prim {
            let k = kind(primary.clr_fmt, ch);
            let end = if ch > 0 && primary.clr_fmt == ClrFmt::Yuv420 { (r1 + 1).min(mb_h) } else { r1 };
            planes.push(transform_rows(&rows, &setup.prim_params, k, ch, ch, mb_w, mb_h, r0..end)?);
        }
        let alpha = if setup.with_alpha {
            let k = kind(setup.alpha_fmt, 0);
            Some(transform_rows(&rows, &setup.alpha_params, k, 0, n_prim, mb_w, mb_h, r0..r1)?)
        } else {
            None
        };
        let (ys, ye) = ((r0 * 16).max(y0), (r1 * 16).min(y0 + h));
        for y in ys..ye {
            let local = y - r0 * 16;
            for (ch, p) in planes.iter().enumerate() {
                if ch == 0 || kind(primary.clr_fmt, ch) == PlaneKind::Full {
                    full[ch].copy_from_slice(&p.data[local * p.width..(local + 1) * p.width]);
                } else {
                    upsample_chroma_row(internal, &p.data, p.width, p.height, local, &mut full[ch])?;
                }
            }
            let refs: Vec<&[i32]> = full.iter().map(|r| &r[x0..]).collect();
            let a = alpha.as_ref().map(|p| &p.data[local * p.width + x0..(local + 1) * p.width]);
            out.format_row(&refs, a, w, &mut raw)?;
            let oy = y - y0;
            raw_rows(oy, &raw);
            if let Some(s) = sink.as_deref_mut() {
                let raw = &raw;
                fill_rows(s, oy as u32, 1, row_len, &mut scratch, |dst| out.row_to_f32(raw, w, dst))?;
            }
        }
        r0 = r1;
    }
    Ok(())
}

/// The samples of macroblock rows `rows` of channel `ch` of a plane (its window channel
/// `win_ch`).
#[allow(clippy::too_many_arguments)]
fn transform_rows(
    rows: &crate::reduced::RowsHandle,
    params: &transform::TransformParams,
    k: PlaneKind,
    ch: usize,
    win_ch: usize,
    mb_w: usize,
    mb_h: usize,
    range: std::ops::Range<usize>,
) -> Result<transform::Plane> {
    let (bx, by) = k.blocks();
    let (w, unit) = (bx * 4 * mb_w, by * 4);
    let mut data = vec![0i32; w * unit * range.len()];
    transform::inverse_band(params, k, ch, mb_w, mb_h, rows.channel(win_ch), rows.first(), range.clone(), &mut data)?;
    Ok(transform::Plane { width: w, height: unit * range.len(), data })
}
