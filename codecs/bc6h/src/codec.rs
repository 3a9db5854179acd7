//! The [`ImageCodec`] implementations (`bc6h` for DDS, `bc6h-ktx2` for KTX2), encoding with
//! optional mip chains.
use crate::dds::{dds_header, dds_levels, is_bc6h_dds, read_dds_header};
use crate::decode::{decode_surface_into, surface_bytes};
use crate::encode::{encode_surface, EncodeOptions};
use crate::ktx2::{
    is_bc6h_ktx2, khr_df_primaries, ktx2_header, ktx2_levels, read_ktx2_header, read_ktx2_primaries, KTX2_PRIMARIES,
};
use crate::texture::{full_mip_count, level_size, Bc6hTexture, TextureHeader};
use hdrcodec_core::bytes::{ByteOrder, ByteWriter};
use hdrcodec_core::sink::{band_rows, fill_rows, RowSink, Scratch};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, DecodeOptions, EncodeReport, EncodeSettings, HdrImage, ImageCodec, ImageInfo,
    Limits, PendingHeader, RangeCount, Result, RowCounter, WriteSeek,
};
use std::borrow::Cow;

/// The options both codecs understand.
const OPTIONS: &[&str] = &["signed", "mips"];

/// Downsamples an interleaved RGB surface to `dw` x `dh` with a box filter in linear light:
/// each output texel is the area-weighted mean of the source texels its footprint covers, so odd
/// sizes (a 5-wide row halving to 2) weight the shared middle texel by half on each side.
pub fn downsample_box(src: &[f32], sw: u32, sh: u32, dw: u32, dh: u32) -> Vec<f32> {
    let (sw, sh, dw, dh) = (sw as usize, sh as usize, dw as usize, dh as usize);
    let (tx, ty) = (box_taps(sw, dw), box_taps(sh, dh));
    // Separable: rows first (sw -> dw), then columns (sh -> dh).
    let mut horiz = vec![0f32; dw * sh * 3];
    for y in 0..sh {
        for (x, taps) in tx.iter().enumerate() {
            for &(i, w) in taps {
                for c in 0..3 {
                    horiz[(y * dw + x) * 3 + c] += w * src[(y * sw + i) * 3 + c];
                }
            }
        }
    }
    let mut out = vec![0f32; dw * dh * 3];
    for (y, taps) in ty.iter().enumerate() {
        for &(i, w) in taps {
            for x in 0..dw * 3 {
                out[y * dw * 3 + x] += w * horiz[i * dw * 3 + x];
            }
        }
    }
    out
}

/// For each of `m` outputs, the source samples its footprint `[j*n/m, (j+1)*n/m)` overlaps and
/// the overlap fractions (summing to 1).
fn box_taps(n: usize, m: usize) -> Vec<Vec<(usize, f32)>> {
    let scale = n as f64 / m as f64;
    (0..m)
        .map(|j| {
            let (a, b) = (j as f64 * scale, (j + 1) as f64 * scale);
            (a.floor() as usize..(b.ceil() as usize).min(n))
                .filter_map(|i| {
                    let w = (b.min(i as f64 + 1.0) - a.max(i as f64)) / scale;
                    (w > 0.0).then_some((i, w as f32))
                })
                .collect()
        })
        .collect()
}

/// Encodes `rgb` (level 0) and, if `mips`, every smaller level down to 1x1.
pub fn encode_texture(
    width: u32,
    height: u32,
    rgb: &[f32],
    options: &EncodeOptions,
    mips: bool,
) -> Result<Bc6hTexture> {
    let mut levels = vec![encode_surface(width, height, rgb, options)?];
    if mips {
        let mut prev = rgb.to_vec();
        let mut size = (width, height);
        for i in 1..full_mip_count(width, height) {
            let (w, h) = level_size(width, height, i);
            prev = downsample_box(&prev, size.0, size.1, w, h);
            size = (w, h);
            levels.push(encode_surface(w, h, &prev, options)?);
        }
    }
    Ok(Bc6hTexture { width, height, signed: options.signed, levels })
}

/// Rows of blocks encoded and written at a time (a multiple of 4): bounds what is held of the
/// encoded file while leaving each band thousands of blocks to spread over the threads.
const BAND_ROWS: u32 = 256;

/// The levels of a texture as the writers stream them: level 0 is the image's own samples (no
/// copy when it is RGB), the mip chain (at most a third of level 0) is computed ahead; each level
/// is encoded and written a band of block rows at a time.
struct Levels<'a> {
    width: u32,
    height: u32,
    level0: Cow<'a, [f32]>,
    mips: Vec<Vec<f32>>,
    options: EncodeOptions,
}

impl<'a> Levels<'a> {
    /// Checks the options, and reports the samples BC6H cannot hold (see [`clip_note`]).
    fn new(image: &'a HdrImage, settings: &EncodeSettings, codec: &str) -> Result<(Self, EncodeReport)> {
        let (options, mips) = encode_options(settings, codec)?;
        let signed = options.signed;
        let (width, height) = (image.width(), image.height());
        check_size(width, height)?;
        let level0: Cow<'a, [f32]> = match image.channels() {
            Channels::Rgb => Cow::Borrowed(image.samples()),
            _ => Cow::Owned(image.with_channels(Channels::Rgb).into_samples()),
        };
        let mut chain: Vec<Vec<f32>> = Vec::new();
        if mips {
            for i in 1..full_mip_count(width, height) {
                let (pw, ph) = level_size(width, height, i - 1);
                let (w, h) = level_size(width, height, i);
                let next = downsample_box(chain.last().map_or(&level0[..], |v| &v[..]), pw, ph, w, h);
                chain.push(next);
            }
        }
        let mut report = EncodeReport::new();
        if let Some(note) = clip_note(image, signed) {
            report.note(note);
        }
        Ok((Levels { width, height, level0, mips: chain, options }, report))
    }

    fn count(&self) -> usize {
        1 + self.mips.len()
    }

    /// Encodes level `i` into `out`, a band of block rows at a time.
    fn write_level(&self, i: usize, out: &mut dyn std::io::Write) -> Result<()> {
        let (w, h) = level_size(self.width, self.height, i);
        let rgb = if i == 0 { &self.level0[..] } else { &self.mips[i - 1][..] };
        let row = w as usize * 3;
        let mut y = 0;
        while y < h {
            let rows = BAND_ROWS.min(h - y);
            let band = &rgb[y as usize * row..(y + rows) as usize * row];
            out.write_all(&encode_surface(w, rows, band, &self.options)?)?;
            y += rows;
        }
        Ok(())
    }
}

/// The encoder options of `settings` (checked against what `codec` understands), and whether
/// a mip chain was asked for.
fn encode_options(settings: &EncodeSettings, codec: &str) -> Result<(EncodeOptions, bool)> {
    settings.check_options(codec, OPTIONS)?;
    let signed = settings.bool_option("signed")?.unwrap_or(false);
    let mips = settings.bool_option("mips")?.unwrap_or(false);
    let options =
        EncodeOptions { signed, effort: settings.effort.min(EncodeSettings::MAX_EFFORT), pool: settings.pool.clone() };
    Ok((options, mips))
}

/// The encoder options for a texture encoded from its rows, `None` when a mip chain is asked
/// for (it needs the whole image).
fn row_options(info: &ImageInfo, settings: &EncodeSettings, codec: &str) -> Result<Option<EncodeOptions>> {
    let (options, mips) = encode_options(settings, codec)?;
    check_size(info.width, info.height)?;
    Ok((!mips).then_some(options))
}

/// An error for an empty texture.
fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(hdrcodec_core::Error::invalid(format!("BC6H texture size {width}x{height} is empty")));
    }
    Ok(())
}

/// The largest value BC6H holds (the largest finite half).
const HALF_MAX: f32 = 65504.0;

/// The range BC6H holds with or without a sign.
fn range(signed: bool) -> (f32, f32) {
    (if signed { -HALF_MAX } else { 0.0 }, HALF_MAX)
}

/// What the encoder replaced (NaN by 0, values beyond the half range by ±65504, negatives in
/// UF16 by 0; Direct3D 11 functional specification, BC6H), as a sentence, if anything.
fn clip_note(image: &HdrImage, signed: bool) -> Option<String> {
    let (lo, hi) = range(signed);
    describe_clipped(&image.count_outside(lo, hi, false), signed)
}

/// [`clip_note`] from samples counted (over the whole image, or band by band).
fn describe_clipped(counts: &RangeCount, signed: bool) -> Option<String> {
    let (lo, hi) = range(signed);
    let below_as = if signed { "-65504" } else { "0 (--opt signed=true keeps negatives)" };
    counts.describe(if signed { "BC6H SF16" } else { "BC6H UF16" }, lo, hi, below_as, "65504", "0")
}

/// Level 0 of a texture without mips encoded as its rows come, a band of [`BAND_ROWS`] rows at
/// a time (the same bands [`Levels::write_level`] cuts from a whole image, so the bytes are the
/// same), after the header its container wrote.
struct RowWriter {
    header: PendingHeader,
    width: u32,
    channels: Channels,
    options: EncodeOptions,
    rows: RowCounter,
    /// RGB rows of the band being gathered.
    band: Vec<f32>,
    outside: RangeCount,
    report: EncodeReport,
}

impl RowWriter {
    fn new(info: &ImageInfo, options: EncodeOptions, header: Vec<u8>, report: EncodeReport) -> Self {
        RowWriter {
            header: PendingHeader::new(header),
            width: info.width,
            channels: info.channels,
            options,
            rows: RowCounter::new(info.width as usize * info.channels.count(), info.height),
            band: Vec::new(),
            outside: RangeCount::default(),
            report,
        }
    }

    /// Encodes and writes the gathered band.
    fn flush(&mut self, out: &mut dyn WriteSeek) -> Result<()> {
        self.header.write(out)?;
        let rows = (self.band.len() / (self.width as usize * 3)) as u32;
        if rows > 0 {
            out.write_all(&encode_surface(self.width, rows, &self.band, &self.options)?)?;
            self.band.clear();
        }
        Ok(())
    }
}

impl hdrcodec_core::RowEncoder for RowWriter {
    fn write_rows(&mut self, samples: &[f32], out: &mut dyn WriteSeek) -> Result<()> {
        self.rows.take(samples)?;
        let (lo, hi) = range(self.options.signed);
        self.outside.add(samples, self.channels, lo, hi, false);
        let n = self.channels.count();
        let band_len = BAND_ROWS as usize * self.width as usize * 3;
        for px in samples.chunks_exact(n) {
            self.band.extend_from_slice(&px[..3]);
            if self.band.len() == band_len {
                self.flush(out)?;
            }
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>, out: &mut dyn WriteSeek) -> Result<EncodeReport> {
        self.rows.check_complete()?;
        self.flush(out)?;
        if let Some(note) = describe_clipped(&self.outside, self.options.signed) {
            self.report.note(note);
        }
        Ok(self.report)
    }
}

/// Level 0 of `tex` as an image in `primaries`, block rows decoded on `options.pool`.
/// Decodes mip level 0 of `tex` into `sink`: in place in one pass when the sink allows it,
/// else in bands of block rows (about 4 MB of rows), the block rows of a band in parallel on
/// `options.pool`.
fn texture_rows(
    (header, levels): (TextureHeader, Vec<&[u8]>),
    info: &ImageInfo,
    options: &DecodeOptions,
    sink: &mut dyn RowSink,
) -> Result<()> {
    let (w, h) = (header.width, header.height);
    let level0 = levels.first().ok_or_else(|| hdrcodec_core::Error::invalid("the texture has no mip level"))?;
    let row_len = w as usize * 3;
    sink.start(info)?;
    // Whole block rows per band.
    let band = if sink.rows_mut(0, h).is_some() { h } else { (band_rows(row_len, 4 << 20) / 4).max(1) * 4 };
    let blocks_across = w.div_ceil(4) as usize;
    let mut scratch = Scratch::new(&options.limits);
    let mut y = 0;
    while y < h {
        let rows = band.min(h - y);
        let first = (y / 4) as usize * blocks_across * 16;
        let last = ((y + rows).div_ceil(4) as usize * blocks_across * 16).min(level0.len());
        let blocks = level0.get(first..last).unwrap_or_default();
        fill_rows(sink, y, rows, row_len, &mut scratch, |out| {
            decode_surface_into(w, rows, blocks, header.signed, &options.pool, out)
        })?;
        y += rows;
    }
    Ok(())
}

/// The colour of a decoded texture: the primaries its file records (DDS: none), at the
/// family's default scale.
fn texture_color(primaries: ColorPrimaries) -> ColorInfo {
    ColorInfo { primaries, ..ColorInfo::default() }
}

/// What [`ImageCodec::probe`] returns for a texture with this header: level 0, RGB.
fn texture_info(header: &TextureHeader, primaries: ColorPrimaries) -> ImageInfo {
    ImageInfo::new(header.width, header.height, Channels::Rgb, texture_color(primaries)).with_format(header.format())
}

/// BC6H in a DDS file (DX10 header, DXGI 95/96). Decoding returns mip level 0.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bc6hDdsCodec;

impl ImageCodec for Bc6hDdsCodec {
    fn name(&self) -> &'static str {
        "bc6h"
    }
    fn id(&self) -> [u8; 4] {
        *b"BC6H"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["dds"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        is_bc6h_dds(head)
    }
    /// DDS records no colour: samples are stored as they are.
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::None
    }
    /// The header only: level 0's size, "BC6H UF16, 3 mip levels".
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        Ok(texture_info(&read_dds_header(data, limits)?, ColorPrimaries::Unspecified))
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        let info = self.probe(data, &options.limits)?;
        texture_rows(dds_levels(data, &options.limits)?, &info, options, sink)
    }
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        let (levels, report) = Levels::new(image, settings, self.name())?;
        let mut header = ByteWriter::new(ByteOrder::Little);
        dds_header(&mut header, levels.width, levels.height, levels.options.signed, levels.count());
        out.write_all(header.as_slice())?;
        for i in 0..levels.count() {
            levels.write_level(i, out)?;
        }
        Ok(report)
    }
    /// Without mips: the header, then level 0 a band of rows at a time. A mip chain needs the
    /// whole image.
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        let Some(options) = row_options(info, settings, self.name())? else { return Ok(None) };
        let mut header = ByteWriter::new(ByteOrder::Little);
        dds_header(&mut header, info.width, info.height, options.signed, 1);
        Ok(Some(Box::new(RowWriter::new(info, options, header.as_slice().to_vec(), EncodeReport::new()))))
    }
}

/// BC6H in a KTX2 file (vkFormat 143/144). Decoding returns mip level 0.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bc6hKtx2Codec;

impl ImageCodec for Bc6hKtx2Codec {
    fn name(&self) -> &'static str {
        "bc6h-ktx2"
    }
    fn id(&self) -> [u8; 4] {
        *b"BC6K"
    }
    fn extensions(&self) -> &'static [&'static str] {
        &["ktx2"]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        is_bc6h_ktx2(head)
    }
    /// The data format descriptor names a fixed set of primaries ([`KTX2_PRIMARIES`]),
    /// "unspecified" (colorPrimaries 0) among them.
    fn color_signalling(&self) -> hdrcodec_core::ColorSignalling {
        hdrcodec_core::ColorSignalling::Only(&KTX2_PRIMARIES)
    }
    /// The header and the DFD's primaries only: level 0's size, "BC6H UF16, 3 mip levels".
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        Ok(texture_info(&read_ktx2_header(data, limits)?, read_ktx2_primaries(data)))
    }
    /// The image carries the primaries the DFD names; 0 or a value without a named space of
    /// ours gives [`ColorPrimaries::Unspecified`].
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        hdrcodec_core::decode_image(self, data, options)
    }
    fn decode_rows(&self, data: &[u8], options: &DecodeOptions, sink: &mut dyn RowSink) -> Result<()> {
        let info = self.probe(data, &options.limits)?;
        texture_rows(ktx2_levels(data, &options.limits)?, &info, options, sink)
    }
    /// Records the image's primaries in the DFD. Primaries it cannot name (the facade converts
    /// before calling, but a direct caller or the container may not) are stored as they are
    /// with colorPrimaries 0 (unspecified), and the report says so.
    fn encode_to(
        &self,
        image: &HdrImage,
        settings: &EncodeSettings,
        out: &mut dyn std::io::Write,
    ) -> Result<hdrcodec_core::EncodeReport> {
        let (levels, mut report) = Levels::new(image, settings, self.name())?;
        let primaries = ktx2_primaries(&image.color.primaries, &mut report);
        let n = levels.count();
        let (header, offsets) = ktx2_header(levels.width, levels.height, levels.options.signed, n, primaries)?;
        out.write_all(&header)?;
        // The smallest level first, each at its offset (a multiple of 16).
        let mut pos = header.len() as u64;
        for i in (0..n).rev() {
            out.write_all(&[0; 16][..(offsets[i] - pos) as usize])?;
            levels.write_level(i, out)?;
            let (w, h) = level_size(levels.width, levels.height, i);
            pos = offsets[i] + surface_bytes(w, h).unwrap_or(0) as u64;
        }
        Ok(report)
    }
    /// Without mips: the header, then level 0 a band of rows at a time. A mip chain needs the
    /// whole image.
    fn row_encoder(
        &self,
        info: &ImageInfo,
        settings: &EncodeSettings,
    ) -> Result<Option<Box<dyn hdrcodec_core::RowEncoder>>> {
        let Some(options) = row_options(info, settings, self.name())? else { return Ok(None) };
        let mut report = EncodeReport::new();
        let primaries = ktx2_primaries(&info.color.primaries, &mut report);
        let (mut header, offsets) = ktx2_header(info.width, info.height, options.signed, 1, primaries)?;
        // Level 0 starts at its offset (a multiple of 16).
        header.resize(offsets[0] as usize, 0);
        Ok(Some(Box::new(RowWriter::new(info, options, header, report))))
    }
}

/// The DFD's colorPrimaries code for `primaries`: 0 (unspecified) for primaries KTX2 cannot
/// name (the facade converts before calling, but a direct caller or the container may not),
/// whose samples are then stored as they are, and `report` says so.
fn ktx2_primaries(primaries: &ColorPrimaries, report: &mut EncodeReport) -> u32 {
    match khr_df_primaries(primaries) {
        Some(code) => code,
        None => {
            report.note(format!(
                "KTX2 cannot record {} primaries: the samples are stored as they are and the file says \
                 unspecified (--opt primaries=NAME converts them)",
                primaries.name()
            ));
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec_core::Error;

    #[test]
    fn box_filter_handles_odd_sizes() {
        // A 5x1 row halving to 2x1: footprints of 2.5 texels, the middle one shared.
        let src: Vec<f32> = [1.0f32, 2.0, 3.0, 4.0, 5.0].iter().flat_map(|&v| [v, 2.0 * v, 0.0]).collect();
        let out = downsample_box(&src, 5, 1, 2, 1);
        let left = (1.0 + 2.0 + 0.5 * 3.0) / 2.5;
        let right = (0.5 * 3.0 + 4.0 + 5.0) / 2.5;
        assert!((out[0] - left).abs() < 1e-6 && (out[3] - right).abs() < 1e-6, "{out:?}");
        assert!((out[1] - 2.0 * left).abs() < 1e-5);
        // 3x3 -> 1x1 is the plain mean; a constant stays constant in any size.
        let sq: Vec<f32> = (0..9).flat_map(|i| [i as f32, 1.0, 7.0]).collect();
        let one = downsample_box(&sq, 3, 3, 1, 1);
        assert!((one[0] - 4.0).abs() < 1e-5 && (one[1] - 1.0).abs() < 1e-6 && (one[2] - 7.0).abs() < 1e-5);
        let flat = vec![0.25f32; 7 * 5 * 3];
        assert!(downsample_box(&flat, 7, 5, 3, 2).iter().all(|&v| (v - 0.25).abs() < 1e-6));
    }

    #[test]
    fn clipped_samples_are_reported() {
        let img =
            HdrImage::new(2, 1, Channels::Rgb, vec![-1.0, 1e6, 0.5, 1.0, f32::NAN, 2.0], ColorInfo::default()).unwrap();
        let mut out = Vec::new();
        let report = Bc6hDdsCodec.encode_to(&img, &EncodeSettings::default(), &mut out).unwrap();
        assert_eq!(report.notes.len(), 1, "{report:?}");
        let n = &report.notes[0];
        assert!(
            n.starts_with("BC6H UF16 holds values from 0 to 65504")
                && n.contains("1 below 0")
                && n.contains("1 above 65504")
                && n.contains("1 NaN"),
            "{n}"
        );
        let signed = EncodeSettings::default().with_option("signed", "true");
        let report = Bc6hKtx2Codec.encode_to(&img, &signed, &mut Vec::new()).unwrap();
        assert!(!report.notes[0].contains("below"), "{report:?}");
        let fine = HdrImage::zeroed(4, 4, Channels::Rgb);
        assert!(Bc6hDdsCodec.encode_to(&fine, &EncodeSettings::default(), &mut Vec::new()).unwrap().notes.is_empty());
    }

    #[test]
    fn streamed_files_are_the_texture_writers_files() {
        // Taller than a band, with a partial band and block row at the bottom, RGBA input.
        let (w, h) = (37u32, 2 * BAND_ROWS + 9);
        let samples = (0..w * h * 4).map(|i| ((i * 7919) % 1000) as f32 * 0.013 - 0.5).collect();
        let image = HdrImage::new(w, h, Channels::Rgba, samples, ColorInfo::default()).unwrap();
        let rgb = image.with_channels(Channels::Rgb);
        for (signed, mips) in [(false, false), (true, true)] {
            let settings = EncodeSettings::default()
                .with_effort(0)
                .with_option("signed", signed.to_string())
                .with_option("mips", mips.to_string());
            let options = EncodeOptions { signed, effort: 0, pool: settings.pool.clone() };
            let texture = encode_texture(w, h, rgb.samples(), &options, mips).unwrap();
            assert_eq!(Bc6hDdsCodec.encode(&image, &settings).unwrap(), crate::write_dds(&texture).unwrap());
            assert_eq!(
                Bc6hKtx2Codec.encode(&image, &settings).unwrap(),
                crate::write_ktx2(&texture, ColorPrimaries::Bt709).unwrap()
            );
        }
    }

    #[test]
    fn probe_reads_the_header_as_decode_would() {
        let mut img = HdrImage::zeroed(9, 5, Channels::Rgba);
        // KTX2 records BT.2020 in its DFD and the probe reads it there; DDS records nothing.
        img.color.primaries = ColorPrimaries::Bt2020;
        let mips = EncodeSettings::default().with_option("mips", "true");
        let signed = EncodeSettings::default().with_option("signed", "true");
        let codecs: [&dyn ImageCodec; 2] = [&Bc6hDdsCodec, &Bc6hKtx2Codec];
        for codec in codecs {
            for (s, want) in [(&mips, "BC6H UF16, 4 mip levels"), (&signed, "BC6H SF16, 1 mip level")] {
                let file = codec.encode(&img, s).unwrap();
                let info = codec.probe(&file, &Limits::default()).unwrap();
                let back = codec.decode(&file, &Limits::default()).unwrap();
                let got = (info.width, info.height, info.channels, &info.color);
                assert_eq!(got, (9, 5, back.channels(), &back.color));
                let want_primaries =
                    if codec.name() == "bc6h" { ColorPrimaries::Unspecified } else { ColorPrimaries::Bt2020 };
                assert_eq!(info.color.primaries, want_primaries);
                assert_eq!((info.format.as_str(), info.frames), (want, 1));
                let tiny = Limits::default().with_max_alloc_bytes(64);
                assert!(codec.decode(&file, &tiny).is_err() && codec.probe(&file, &tiny).is_ok());
            }
        }
    }

    #[test]
    fn unknown_options_are_rejected() {
        let img = HdrImage::zeroed(4, 4, Channels::Rgb);
        let s = EncodeSettings::default().with_option("quality", "3");
        assert!(matches!(Bc6hDdsCodec.encode(&img, &s), Err(Error::Invalid { .. })));
        let s = EncodeSettings::default().with_option("signed", "maybe");
        assert!(Bc6hKtx2Codec.encode(&img, &s).is_err());
    }

    #[test]
    fn ktx2_keeps_the_primaries_it_can_name() {
        let limits = hdrcodec_core::Limits::default();
        let mut img = HdrImage::new(4, 4, Channels::Rgb, vec![0.5; 48], ColorInfo::default()).unwrap();
        for p in KTX2_PRIMARIES {
            img.color.primaries = p;
            let mut out = Vec::new();
            let report = Bc6hKtx2Codec.encode_to(&img, &EncodeSettings::default(), &mut out).unwrap();
            assert!(report.notes.is_empty(), "{}: {:?}", p.name(), report.notes);
            let back = Bc6hKtx2Codec.decode(&out, &limits).unwrap();
            assert_eq!(back.color.primaries, p);
            assert_eq!(
                back.samples(),
                Bc6hDdsCodec
                    .decode(&Bc6hDdsCodec.encode(&img, &EncodeSettings::default()).unwrap(), &limits)
                    .unwrap()
                    .samples()
            );
        }
        // DCI-P3 has no colorPrimaries value: stored as it is, read back unspecified, noted.
        img.color.primaries = ColorPrimaries::DciP3;
        let mut out = Vec::new();
        let report = Bc6hKtx2Codec.encode_to(&img, &EncodeSettings::default(), &mut out).unwrap();
        assert!(report.notes.len() == 1 && report.notes[0].contains("DCI-P3"), "{:?}", report.notes);
        let back = Bc6hKtx2Codec.decode(&out, &limits).unwrap();
        assert_eq!(back.color.primaries, ColorPrimaries::Unspecified);
        assert!(back.samples().iter().all(|&v| (v - 0.5).abs() < 0.01));
        // DDS records nothing.
        let dds = Bc6hDdsCodec.encode(&img, &EncodeSettings::default()).unwrap();
        assert_eq!(Bc6hDdsCodec.decode(&dds, &limits).unwrap().color.primaries, ColorPrimaries::Unspecified);
    }
}
