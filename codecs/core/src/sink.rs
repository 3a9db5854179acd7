//! Where a decoder puts what it decodes: an [`HdrImage`] it builds, a caller's buffer of `f32`
//! or `f16` samples with a stride, or a consumer that keeps nothing (statistics, a streaming
//! encoder).
//!
//! Every decoder of the family writes rows into a [`RowSink`], so that one decoding routine
//! serves [`ImageCodec::decode_with`](crate::ImageCodec::decode_with) (the sink is an
//! [`ImageSink`] that allocates the image once and lets the decoder write into it in place) and
//! [`ImageCodec::decode_into`](crate::ImageCodec::decode_into) (a [`FrameSink`] over the
//! caller's buffer: nothing of the image's size is allocated; `f16` targets are converted band
//! by band from a bounded scratch buffer).
//!
//! ```
//! use hdrcodec_core::sink::{FrameBufMut, FrameSink, RowSink};
//! use hdrcodec_core::{Channels, ColorInfo, ImageInfo};
//! // A 2x2 RGB image into a buffer with a stride of 8 samples per row (2 of padding).
//! use hdrcodec_core::half::f16;
//! let mut buf = vec![f16::ZERO; 16];
//! let mut sink = FrameSink::new(FrameBufMut::f16(&mut buf, 8));
//! let info = ImageInfo::new(2, 2, Channels::Rgb, ColorInfo::default());
//! sink.start(&info)?;
//! sink.put_rows(1, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])?;
//! sink.put_rows(0, &[0.5; 6])?;
//! assert_eq!(buf[8].to_f32(), 1.0);
//! assert_eq!(buf[6], f16::ZERO); // padding is left alone
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use crate::{Allocation, Error, HdrImage, ImageInfo, Limits, Result};

/// Rows of a decoded image arrive here, as interleaved `f32` samples in the layout the header
/// announced ([`ImageInfo::channels`]), `width × channels` samples per row.
///
/// A decoder calls [`start`](Self::start) once, then delivers every row exactly once, in any
/// order (PFM stores rows bottom up, tiled formats finish bands out of order), either through
/// [`rows_mut`](Self::rows_mut) (writing in place) or [`put_rows`](Self::put_rows) (a copy).
/// [`fill_rows`] does the choosing.
pub trait RowSink {
    /// The image about to be delivered (from the header). A sink checks here that it can take
    /// it (a caller's buffer big enough, a budget that allows it) and fails otherwise.
    fn start(&mut self, info: &ImageInfo) -> Result<()>;

    /// Rows `y .. y + rows` as one mutable slice, when the sink stores them contiguously as
    /// `f32` (an [`HdrImage`], a caller's unpadded `f32` buffer): the decoder writes into it
    /// directly. `None` (the provided answer) means: use [`put_rows`](Self::put_rows). A
    /// decoder may ask for all rows once, after `start`, to learn whether the sink is written
    /// in place and size its batches accordingly.
    fn rows_mut(&mut self, y: u32, rows: u32) -> Option<&mut [f32]> {
        let _ = (y, rows);
        None
    }

    /// Takes rows `y ..` (as many as `samples` holds whole rows of).
    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()>;
}

/// Hands `f` the rows `y .. y + rows` to fill: the sink's own storage when it offers it, else
/// `scratch` (kept by the caller for the next band, and charged to its limits only then), whose
/// rows then go to [`RowSink::put_rows`]. `row_len` is the number of samples per row.
pub fn fill_rows<F>(
    sink: &mut dyn RowSink,
    y: u32,
    rows: u32,
    row_len: usize,
    scratch: &mut Scratch,
    f: F,
) -> Result<()>
where
    F: FnOnce(&mut [f32]) -> Result<()>,
{
    if let Some(direct) = sink.rows_mut(y, rows) {
        return f(direct);
    }
    let band = scratch.get(rows as usize * row_len)?;
    f(band)?;
    sink.put_rows(y, band)
}

/// The band buffer [`fill_rows`] uses when a sink cannot be written in place, charged to the
/// decoder's [`Limits`] for as long as it is held (nothing is allocated or charged while every
/// band goes in place).
#[derive(Debug)]
pub struct Scratch {
    buf: Vec<f32>,
    limits: Limits,
    charge: Option<Allocation>,
}

impl Scratch {
    /// An empty buffer whose growth is charged to `limits`.
    pub fn new(limits: &Limits) -> Self {
        Scratch { buf: Vec::new(), limits: limits.clone(), charge: None }
    }

    /// `len` samples (zeroed when they are new), charged before they are allocated.
    fn get(&mut self, len: usize) -> Result<&mut [f32]> {
        if len > self.buf.len() {
            self.charge = None;
            self.charge = Some(self.limits.charge(len as u64 * 4, "a band of decoded rows")?);
            self.buf.resize(len, 0.0);
        }
        Ok(&mut self.buf[..len])
    }
}

/// The number of rows per band such that a band of `row_len` samples holds about
/// `target_bytes` bytes of `f32` (at least one row): the size of the scratch buffers decoders
/// use when a sink cannot be written in place.
pub fn band_rows(row_len: usize, target_bytes: usize) -> u32 {
    let row_bytes = (row_len * 4).max(1);
    (target_bytes / row_bytes).clamp(1, u32::MAX as usize) as u32
}

/// Checks that `samples` holds whole rows of `row_len`, lying inside `height`, and returns how
/// many rows that is.
fn whole_rows(y: u32, samples: usize, row_len: usize, height: u32) -> Result<u32> {
    if row_len == 0 || !samples.is_multiple_of(row_len) {
        return Err(Error::invalid(format!(
            "a decoder delivered {samples} samples, not whole rows of {row_len} (a bug in the decoder)"
        )));
    }
    let rows = samples / row_len;
    if u64::from(y) + rows as u64 > u64::from(height) {
        return Err(Error::invalid(format!(
            "a decoder delivered rows {y}..{} of an image {height} rows high (a bug in the decoder)",
            y as usize + rows
        )));
    }
    Ok(rows as u32)
}

/// Builds an [`HdrImage`]: allocates it at [`start`](RowSink::start) (charging it against the
/// limits' budget for as long as the sink lives) and lets the decoder write in place.
#[derive(Debug)]
pub struct ImageSink {
    limits: Limits,
    image: Option<HdrImage>,
    _charge: Option<Allocation>,
}

impl ImageSink {
    /// A sink that charges the image to `limits`.
    pub fn new(limits: &Limits) -> Self {
        ImageSink { limits: limits.clone(), image: None, _charge: None }
    }

    /// The image (with the colour and metadata of the header given to `start`). An error if
    /// the decoder never started.
    pub fn finish(self) -> Result<HdrImage> {
        self.image.ok_or_else(|| Error::invalid("the decoder delivered no image (a bug in the decoder)"))
    }

    /// The image being built, if started (decoders that compute a row from the ones above).
    pub fn image_mut(&mut self) -> Option<&mut HdrImage> {
        self.image.as_mut()
    }
}

impl RowSink for ImageSink {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        let charge = info.charge(&self.limits)?;
        let mut image = HdrImage::zeroed(info.width, info.height, info.channels);
        image.color = info.color.clone();
        image.metadata = info.metadata.clone();
        self.image = Some(image);
        self._charge = Some(charge);
        Ok(())
    }

    fn rows_mut(&mut self, y: u32, rows: u32) -> Option<&mut [f32]> {
        let image = self.image.as_mut()?;
        let row_len = image.width() as usize * image.channels().count();
        let start = y as usize * row_len;
        let end = (y as usize + rows as usize) * row_len;
        image.samples_mut().get_mut(start..end)
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let image = self.image.as_mut().ok_or_else(|| Error::invalid("rows before start (a bug in the decoder)"))?;
        let row_len = image.width() as usize * image.channels().count();
        whole_rows(y, samples.len(), row_len, image.height())?;
        let start = y as usize * row_len;
        image.samples_mut()[start..start + samples.len()].copy_from_slice(samples);
        Ok(())
    }
}

/// A caller's buffer of decoded samples: rows of `stride` samples, the first `width × channels`
/// of each row holding the pixels (the rest is left untouched).
#[derive(Debug)]
pub struct FrameBufMut<'a> {
    samples: SamplesMut<'a>,
    stride: usize,
}

#[derive(Debug)]
enum SamplesMut<'a> {
    F32(&'a mut [f32]),
    F16(&'a mut [half::f16]),
}

impl<'a> FrameBufMut<'a> {
    /// `f32` samples, `stride` samples from the start of one row to the next.
    pub fn f32(samples: &'a mut [f32], stride: usize) -> Self {
        FrameBufMut { samples: SamplesMut::F32(samples), stride }
    }

    /// `f16` samples (converted from the decoder's `f32` with rounding to nearest; values
    /// beyond 65504 become infinite, as IEEE conversion defines), `stride` samples per row.
    pub fn f16(samples: &'a mut [half::f16], stride: usize) -> Self {
        FrameBufMut { samples: SamplesMut::F16(samples), stride }
    }

    /// Samples from the start of one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    fn len(&self) -> usize {
        match &self.samples {
            SamplesMut::F32(s) => s.len(),
            SamplesMut::F16(s) => s.len(),
        }
    }
}

/// Writes rows into a caller's [`FrameBufMut`]; it allocates nothing.
#[derive(Debug)]
pub struct FrameSink<'a> {
    buf: FrameBufMut<'a>,
    info: Option<ImageInfo>,
}

impl<'a> FrameSink<'a> {
    /// A sink over `buf`.
    pub fn new(buf: FrameBufMut<'a>) -> Self {
        FrameSink { buf, info: None }
    }

    /// What the decoder announced (size, channels, colour, metadata), once started.
    pub fn info(&self) -> Option<&ImageInfo> {
        self.info.as_ref()
    }

    fn row_len(&self) -> usize {
        self.info.as_ref().map_or(0, |i| i.width as usize * i.channels.count())
    }
}

impl RowSink for FrameSink<'_> {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        let row_len = info.width as usize * info.channels.count();
        let stride = self.buf.stride;
        if stride < row_len {
            return Err(Error::invalid(format!(
                "the buffer's stride of {stride} samples is less than a row of the image ({} x {} = {row_len} samples)",
                info.width,
                info.channels.count()
            )));
        }
        let need = (info.height as usize).saturating_sub(1).saturating_mul(stride).saturating_add(row_len);
        if self.buf.len() < need {
            return Err(Error::invalid(format!(
                "the buffer holds {} samples; a {}x{} image with {} channels and a stride of {stride} needs {need}",
                self.buf.len(),
                info.width,
                info.height,
                info.channels.count()
            )));
        }
        self.info = Some(info.clone());
        Ok(())
    }

    fn rows_mut(&mut self, y: u32, rows: u32) -> Option<&mut [f32]> {
        let row_len = self.row_len();
        let height = self.info.as_ref()?.height;
        if row_len == 0 || self.buf.stride != row_len || u64::from(y) + u64::from(rows) > u64::from(height) {
            return None;
        }
        match &mut self.buf.samples {
            SamplesMut::F32(s) => s.get_mut(y as usize * row_len..(y as usize + rows as usize) * row_len),
            SamplesMut::F16(_) => None,
        }
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let row_len = self.row_len();
        let height =
            self.info.as_ref().ok_or_else(|| Error::invalid("rows before start (a bug in the decoder)"))?.height;
        whole_rows(y, samples.len(), row_len, height)?;
        let stride = self.buf.stride;
        for (i, row) in samples.chunks_exact(row_len).enumerate() {
            let at = (y as usize + i) * stride;
            match &mut self.buf.samples {
                SamplesMut::F32(s) => s[at..at + row_len].copy_from_slice(row),
                SamplesMut::F16(s) => {
                    for (d, &v) in s[at..at + row_len].iter_mut().zip(row) {
                        *d = half::f16::from_f32(v);
                    }
                }
            }
        }
        Ok(())
    }
}

/// A change of orientation applied to a decoded image: a rotation by 90° clockwise first (if
/// `rotate_cw`), then flips of the result. The eight combinations are the orientations JPEG XR
/// (T.832 SPATIAL_XFRM) and EXIF name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Orientation {
    /// Rotate by 90° clockwise (the width and height swap).
    pub rotate_cw: bool,
    /// Then mirror left to right.
    pub flip_h: bool,
    /// Then mirror top to bottom.
    pub flip_v: bool,
}

impl Orientation {
    /// True when nothing changes.
    pub fn is_identity(&self) -> bool {
        *self == Orientation::default()
    }

    /// The size of an image of `width` × `height` once oriented.
    pub fn size(&self, width: u32, height: u32) -> (u32, u32) {
        if self.rotate_cw {
            (height, width)
        } else {
            (width, height)
        }
    }
}

/// Orients the rows a decoder delivers before passing them on to `inner`. Flips go band by
/// band (a flipped band is written where it belongs, rows in any order being allowed); a
/// rotation needs the whole image first: it is held (charged to the limits) until
/// [`finish`](Self::finish), then delivered in bands.
pub struct OrientSink<'a> {
    inner: &'a mut dyn RowSink,
    orientation: Orientation,
    limits: Limits,
    /// The source's size and channels (from `start`).
    width: usize,
    height: usize,
    channels: usize,
    /// The whole source image, for a rotation.
    held: Vec<f32>,
    _charge: Option<Allocation>,
    band: Vec<f32>,
}

impl<'a> OrientSink<'a> {
    /// Rows oriented by `orientation` go to `inner`; what is held is charged to `limits`.
    pub fn new(inner: &'a mut dyn RowSink, orientation: Orientation, limits: &Limits) -> Self {
        OrientSink {
            inner,
            orientation,
            limits: limits.clone(),
            width: 0,
            height: 0,
            channels: 0,
            held: Vec::new(),
            _charge: None,
            band: Vec::new(),
        }
    }

    /// Delivers a rotated image once every row has come (nothing to do otherwise).
    pub fn finish(mut self) -> Result<()> {
        if !self.orientation.rotate_cw {
            return Ok(());
        }
        let Orientation { flip_h, flip_v, .. } = self.orientation;
        let (w, h, n) = (self.width, self.height, self.channels);
        // The rotated image is h wide and w high; its pixel (u, v) is the source's (v, h-1-u)
        // before the flips.
        let rows = band_rows(h * n, 1 << 20) as usize;
        let _charge = self.limits.charge((rows.min(w) * h * n * 4) as u64, "a band of oriented rows")?;
        let mut v0 = 0;
        while v0 < w {
            let count = rows.min(w - v0);
            self.band.clear();
            for v_out in v0..v0 + count {
                let v = if flip_v { w - 1 - v_out } else { v_out };
                for u_out in 0..h {
                    let u = if flip_h { h - 1 - u_out } else { u_out };
                    let (x, y) = (v, h - 1 - u);
                    let at = (y * w + x) * n;
                    self.band.extend_from_slice(&self.held[at..at + n]);
                }
            }
            self.inner.put_rows(v0 as u32, &self.band)?;
            v0 += count;
        }
        Ok(())
    }
}

impl RowSink for OrientSink<'_> {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        self.width = info.width as usize;
        self.height = info.height as usize;
        self.channels = info.channels.count();
        let mut oriented = info.clone();
        (oriented.width, oriented.height) = self.orientation.size(info.width, info.height);
        if self.orientation.rotate_cw {
            self._charge = Some(info.charge(&self.limits)?);
            self.held = vec![0.0; self.width * self.height * self.channels];
        }
        self.inner.start(&oriented)
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let row_len = self.width * self.channels;
        let rows = whole_rows(y, samples.len(), row_len, self.height as u32)?;
        let y = y as usize;
        if self.orientation.rotate_cw {
            self.held[y * row_len..y * row_len + samples.len()].copy_from_slice(samples);
            return Ok(());
        }
        let Orientation { flip_h, flip_v, .. } = self.orientation;
        self.band.clear();
        let source: Box<dyn Iterator<Item = &[f32]>> = if flip_v {
            Box::new(samples.chunks_exact(row_len).rev())
        } else {
            Box::new(samples.chunks_exact(row_len))
        };
        for row in source {
            if flip_h {
                for px in row.chunks_exact(self.channels).rev() {
                    self.band.extend_from_slice(px);
                }
            } else {
                self.band.extend_from_slice(row);
            }
        }
        let to = if flip_v { self.height - y - rows as usize } else { y };
        self.inner.put_rows(to as u32, &self.band)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channels, ColorInfo};

    /// Rotates a grid of pixel numbers by 90° clockwise, then flips it, step by step.
    fn reference(grid: Vec<Vec<u32>>, o: Orientation) -> Vec<Vec<u32>> {
        let mut g = grid;
        if o.rotate_cw {
            let (h, w) = (g.len(), g[0].len());
            // Clockwise: the new first row is the old first column read bottom up.
            g = (0..w).map(|x| (0..h).rev().map(|y| g[y][x]).collect()).collect();
        }
        if o.flip_h {
            g.iter_mut().for_each(|row| row.reverse());
        }
        if o.flip_v {
            g.reverse();
        }
        g
    }

    #[test]
    fn every_orientation_places_every_pixel() {
        let (w, h) = (5u32, 3u32);
        let info = ImageInfo::new(w, h, Channels::Rgb, ColorInfo::default());
        let pixels: Vec<f32> = (0..w * h).flat_map(|p| [p as f32, 0.5, -1.0]).collect();
        let grid: Vec<Vec<u32>> = (0..h).map(|y| (0..w).map(|x| y * w + x).collect()).collect();
        for code in 0..8u8 {
            let o = Orientation { rotate_cw: code & 4 != 0, flip_h: code & 2 != 0, flip_v: code & 1 != 0 };
            let want = reference(grid.clone(), o);
            let limits = Limits::default();
            let mut image = ImageSink::new(&limits);
            let mut sink = OrientSink::new(&mut image, o, &limits);
            sink.start(&info).unwrap();
            // Bands of two rows, last band first.
            sink.put_rows(2, &pixels[2 * 15..]).unwrap();
            sink.put_rows(0, &pixels[..2 * 15]).unwrap();
            sink.finish().unwrap();
            let got = image.finish().unwrap();
            assert_eq!((got.width(), got.height()), o.size(w, h), "{o:?}");
            let got: Vec<Vec<u32>> =
                (0..got.height()).map(|y| got.row(y).chunks_exact(3).map(|p| p[0] as u32).collect()).collect();
            assert_eq!(got, want, "{o:?}");
        }
    }

    fn info(w: u32, h: u32) -> ImageInfo {
        ImageInfo::new(w, h, Channels::Rgb, ColorInfo::default())
    }

    #[test]
    fn image_sink_takes_rows_in_place_and_by_copy_in_any_order() {
        let mut sink = ImageSink::new(&Limits::default());
        sink.start(&info(2, 3).with_metadata("k", "v")).unwrap();
        let limits = Limits::default();
        let mut scratch = Scratch::new(&limits);
        fill_rows(&mut sink, 2, 1, 6, &mut scratch, |r| {
            r.fill(3.0);
            Ok(())
        })
        .unwrap();
        sink.put_rows(0, &[1.0; 12]).unwrap();
        let image = sink.finish().unwrap();
        assert_eq!(image.row(0), &[1.0; 6]);
        assert_eq!(image.row(1), &[1.0; 6]);
        assert_eq!(image.row(2), &[3.0; 6]);
        assert_eq!(image.metadata_value("k"), Some("v"));
        assert!(scratch.buf.is_empty(), "written in place, no scratch needed");
        assert_eq!(limits.in_use(), 0);
    }

    #[test]
    fn image_sink_charges_the_budget_while_it_lives() {
        let limits = Limits::default().with_max_alloc_bytes(100);
        assert!(ImageSink::new(&limits).start(&info(10, 10)).is_err(), "1200 bytes > 100");
        let limits = Limits::default();
        let mut sink = ImageSink::new(&limits);
        sink.start(&info(2, 2)).unwrap();
        assert_eq!(limits.in_use(), 48);
        drop(sink);
        assert_eq!(limits.in_use(), 0);
    }

    #[test]
    fn frame_sink_f32_with_stride_leaves_padding_alone() {
        let mut buf = vec![-1.0f32; 2 * 8];
        let mut sink = FrameSink::new(FrameBufMut::f32(&mut buf, 8));
        sink.start(&info(2, 2)).unwrap();
        assert!(sink.rows_mut(0, 1).is_none(), "padded: not contiguous");
        let limits = Limits::default();
        let mut scratch = Scratch::new(&limits);
        fill_rows(&mut sink, 0, 2, 6, &mut scratch, |r| {
            for (i, v) in r.iter_mut().enumerate() {
                *v = i as f32;
            }
            Ok(())
        })
        .unwrap();
        assert_eq!(limits.in_use(), 48, "the band buffer is charged while held");
        drop(scratch);
        assert_eq!(limits.in_use(), 0);
        assert_eq!(&buf[..8], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, -1.0, -1.0]);
        assert_eq!(&buf[8..], &[6.0, 7.0, 8.0, 9.0, 10.0, 11.0, -1.0, -1.0]);
    }

    #[test]
    fn frame_sink_unpadded_f32_is_written_in_place() {
        let mut buf = vec![0.0f32; 12];
        let mut sink = FrameSink::new(FrameBufMut::f32(&mut buf, 6));
        sink.start(&info(2, 2)).unwrap();
        sink.rows_mut(1, 1).unwrap().fill(2.0);
        assert!(sink.rows_mut(1, 2).is_none(), "past the last row");
        assert_eq!(&buf[6..], &[2.0; 6]);
    }

    #[test]
    fn frame_sink_rejects_small_buffers_and_bad_rows() {
        let mut buf = vec![0.0f32; 11];
        assert!(FrameSink::new(FrameBufMut::f32(&mut buf, 6)).start(&info(2, 2)).is_err(), "11 < 12");
        let mut buf = vec![0.0f32; 12];
        assert!(FrameSink::new(FrameBufMut::f32(&mut buf, 5)).start(&info(2, 2)).is_err(), "stride < row");
        let mut sink = FrameSink::new(FrameBufMut::f32(&mut buf, 6));
        sink.start(&info(2, 2)).unwrap();
        assert!(sink.put_rows(0, &[0.0; 5]).is_err(), "not a whole row");
        assert!(sink.put_rows(1, &[0.0; 12]).is_err(), "past the end");
    }

    #[test]
    fn f16_rounds_to_nearest() {
        let mut buf = vec![half::f16::ZERO; 3];
        let mut sink = FrameSink::new(FrameBufMut::f16(&mut buf, 3));
        sink.start(&info(1, 1)).unwrap();
        sink.put_rows(0, &[1.0 + 1.0 / 4096.0, 70000.0, -0.25]).unwrap();
        assert_eq!(buf[0].to_f32(), 1.0);
        assert!(buf[1].is_infinite());
        assert_eq!(buf[2].to_f32(), -0.25);
    }

    #[test]
    fn band_rows_is_at_least_one() {
        assert_eq!(band_rows(1 << 30, 1 << 20), 1);
        assert_eq!(band_rows(1024, 1 << 20), 256);
    }
}
