//! AV1 in MP4 (ISO base media file format) with the HDR boxes, and a reader for the video
//! track of any MP4 (AV1 or HEVC).
//!
//! No crate on crates.io writes an `av01` sample entry with `mdcv` and `clli` (the crate
//! README has the survey), so the few boxes a single-track file needs are written here, from
//! ISO/IEC 14496-12 (the box syntax), the AV1 ISOBMFF binding (`av01`, `av1C`: samples are
//! temporal units without their temporal delimiter) and ISO/IEC 23001-8 / H.273 (`colr` of
//! type `nclx`). The mastering display (`mdcv`) and content light level (`clli`) boxes follow
//! the HEVC SEI layout: primaries green, blue, red in units of 0.00002, luminance in units of
//! 0.0001 cd/m².
//!
//! The writer takes what the boxes say from the stream itself (its first sequence header, its
//! HDR_CLL and HDR_MDCV metadata OBUs), so the boxes and the bitstream cannot disagree. Layout:
//! `ftyp`, `mdat` (all samples, one chunk), `moov` last: the samples stream out as they come
//! and only the size of `mdat` is patched at the end.
//!
//! The reader walks boxes held in memory, bounds-checks every size against the data, and
//! finds samples through `stsz`/`stsc`/`stco` without allocating per sample, so its memory
//! does not depend on what the file declares.

use crate::obu::{obu_type, Metadata, ObuReader, SequenceHeader};
use hdrcodec_core::bytes::ByteReader;
use hdrcodec_core::{Av1MdcvUnits, ContentLightLevel, Error, Limits, MasteringDisplay, Result, St2086Units};
use std::io::{Seek, SeekFrom, Write};

/// A box: 32-bit size (header included), four-character type, body.
fn plain_box(kind: &[u8; 4], body: &[u8]) -> Result<Vec<u8>> {
    let size = u32::try_from(body.len() + 8).map_err(|_| {
        Error::unsupported(format!("an MP4 '{}' box of more than 4 GiB", String::from_utf8_lossy(kind)))
    })?;
    let mut out = Vec::with_capacity(body.len() + 8);
    out.extend_from_slice(&size.to_be_bytes());
    out.extend_from_slice(kind);
    out.extend_from_slice(body);
    Ok(out)
}

/// A full box: a box whose body starts with version (8 bits) and flags (24 bits).
fn full_box(kind: &[u8; 4], version: u8, flags: u32, body: &[u8]) -> Result<Vec<u8>> {
    let mut b = Vec::with_capacity(body.len() + 4);
    b.extend_from_slice(&((u32::from(version) << 24) | (flags & 0x00ff_ffff)).to_be_bytes());
    b.extend_from_slice(body);
    plain_box(kind, &b)
}

/// A box holding other boxes.
fn container_box(kind: &[u8; 4], children: &[Vec<u8>]) -> Result<Vec<u8>> {
    plain_box(kind, &children.concat())
}

/// The unity transformation matrix of `mvhd` and `tkhd` (16.16 and 2.30 fixed point).
const UNITY_MATRIX: [u32; 9] = [0x0001_0000, 0, 0, 0, 0x0001_0000, 0, 0, 0, 0x4000_0000];

/// The `mdcv` box body (24 bytes): SEI order and units.
pub fn mdcv_body(units: &St2086Units) -> [u8; 24] {
    let mut b = [0u8; 24];
    for (i, xy) in units.sei_order().iter().chain(std::iter::once(&units.white)).enumerate() {
        b[4 * i..4 * i + 2].copy_from_slice(&xy[0].to_be_bytes());
        b[4 * i + 2..4 * i + 4].copy_from_slice(&xy[1].to_be_bytes());
    }
    b[16..20].copy_from_slice(&units.max_luminance.to_be_bytes());
    b[20..24].copy_from_slice(&units.min_luminance.to_be_bytes());
    b
}

/// Parses an `mdcv` box body (or an HEVC mastering display SEI payload: the same 24 bytes).
pub fn parse_mdcv(body: &[u8]) -> Result<St2086Units> {
    let b: &[u8; 24] =
        body.get(..24).and_then(|b| b.try_into().ok()).ok_or_else(|| Error::truncated("a mastering display record"))?;
    let u16_at = |i: usize| u16::from_be_bytes([b[i], b[i + 1]]);
    let u32_at = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let xy = |i: usize| [u16_at(4 * i), u16_at(4 * i + 2)];
    // Stored green, blue, red.
    Ok(St2086Units {
        primaries: [xy(2), xy(0), xy(1)],
        white: xy(3),
        max_luminance: u32_at(16),
        min_luminance: u32_at(20),
    })
}

/// What the AV1 stream says about itself, gathered from the temporal units as they pass
/// (shared with the Matroska writer).
#[derive(Clone, Debug, Default)]
pub(crate) struct StreamFacts {
    /// The first sequence header OBU, whole (header, size field, payload).
    pub(crate) sequence_header_obu: Option<Vec<u8>>,
    pub(crate) sequence_header: Option<SequenceHeader>,
    pub(crate) content_light: Option<ContentLightLevel>,
    pub(crate) mastering_display: Option<Av1MdcvUnits>,
}

impl StreamFacts {
    /// Notes what `data` (one temporal unit) says and returns it without its temporal delimiter
    /// and padding, as both containers store a temporal unit.
    pub(crate) fn observe(&mut self, data: &[u8]) -> Result<Vec<u8>> {
        let mut sample = Vec::with_capacity(data.len());
        for obu in ObuReader::new(data) {
            let obu = obu?;
            match obu.obu_type {
                obu_type::TEMPORAL_DELIMITER | obu_type::PADDING => continue,
                obu_type::SEQUENCE_HEADER if self.sequence_header.is_none() => {
                    self.sequence_header = Some(SequenceHeader::parse(obu.payload)?);
                    self.sequence_header_obu = Some(obu.raw.to_vec());
                }
                obu_type::METADATA => match Metadata::parse(obu.payload)? {
                    Metadata::ContentLight(c) => self.content_light = Some(c),
                    Metadata::MasteringDisplay(m) => self.mastering_display = Some(m),
                    _ => {}
                },
                _ => {}
            }
            sample.extend_from_slice(obu.raw);
        }
        if self.sequence_header.is_none() {
            return Err(Error::invalid("an AV1 stream whose first temporal unit has no sequence header"));
        }
        Ok(sample)
    }
}

/// The AV1 codec configuration record (`av1C` in MP4, Matroska's `CodecPrivate`): four bytes
/// from the sequence header, then the sequence header OBU as the configuration OBUs.
pub(crate) fn av1_config_record(seq: &SequenceHeader, seq_obu: &[u8]) -> Vec<u8> {
    let c = &seq.color;
    let mut av1c = vec![
        0x81, // marker, version 1
        (seq.profile << 5) | (seq.level_idx & 0x1f),
        (seq.tier << 7)
            | (u8::from(c.bit_depth > 8) << 6)
            | (u8::from(c.bit_depth == 12) << 5)
            | (u8::from(c.mono_chrome) << 4)
            | (u8::from(c.subsampling_x) << 3)
            | (u8::from(c.subsampling_y) << 2)
            | (c.chroma_sample_position & 3),
        0, // no initial_presentation_delay
    ];
    av1c.extend_from_slice(seq_obu);
    av1c
}

/// Writes one AV1 track to an MP4 file: samples as they come, the index (`moov`) at the end.
pub struct Mp4Writer<W: Write + Seek> {
    out: W,
    /// Ticks per second of the track (the frame rate: one tick per frame).
    timescale: u32,
    /// Where the `mdat` box starts in `out`.
    mdat_start: u64,
    /// Bytes of sample data written.
    mdat_payload: u64,
    sample_sizes: Vec<u32>,
    /// 1-based numbers of the sync (key) samples.
    sync_samples: Vec<u32>,
    facts: StreamFacts,
}

/// Bytes of `ftyp` plus the `mdat` header this writer puts before the first sample.
const MDAT_HEADER_LEN: u64 = 16;

impl<W: Write + Seek> Mp4Writer<W> {
    /// Writes `ftyp` and the start of `mdat`; the track runs at `fps` frames per second.
    pub fn new(mut out: W, fps: u32) -> Result<Self> {
        let mut ftyp = Vec::new();
        ftyp.extend_from_slice(b"isom"); // major brand
        ftyp.extend_from_slice(&0x200u32.to_be_bytes()); // minor version
        for brand in [b"isom", b"iso6", b"av01", b"mp41"] {
            ftyp.extend_from_slice(brand);
        }
        let ftyp = plain_box(b"ftyp", &ftyp)?;
        let io = Error::Io;
        let mdat_start = out.stream_position().map_err(io)? + ftyp.len() as u64;
        out.write_all(&ftyp).map_err(io)?;
        // size 1: the 64-bit size follows, patched in `finish`.
        let mut mdat = [0u8; MDAT_HEADER_LEN as usize];
        mdat[0..4].copy_from_slice(&1u32.to_be_bytes());
        mdat[4..8].copy_from_slice(b"mdat");
        out.write_all(&mdat).map_err(io)?;
        Ok(Mp4Writer {
            out,
            timescale: fps.max(1),
            mdat_start,
            mdat_payload: 0,
            sample_sizes: Vec::new(),
            sync_samples: Vec::new(),
            facts: StreamFacts::default(),
        })
    }

    /// Writes one temporal unit as a sample, without its temporal delimiter (the AV1 ISOBMFF
    /// binding leaves delimiting to the container). `keyframe` marks a sync sample: one that
    /// starts with a sequence header and a key frame.
    pub fn write_temporal_unit(&mut self, data: &[u8], keyframe: bool) -> Result<()> {
        let sample = self.facts.observe(data)?;
        let size = u32::try_from(sample.len())
            .map_err(|_| Error::unsupported(format!("an MP4 sample of {} bytes", sample.len())))?;
        let number = u32::try_from(self.sample_sizes.len() + 1)
            .map_err(|_| Error::unsupported("more than 2^32 - 1 samples in one MP4 track"))?;
        self.out.write_all(&sample).map_err(Error::Io)?;
        self.mdat_payload += sample.len() as u64;
        self.sample_sizes.push(size);
        if keyframe {
            self.sync_samples.push(number);
        }
        Ok(())
    }

    /// Samples written so far.
    pub fn samples_written(&self) -> u64 {
        self.sample_sizes.len() as u64
    }

    /// Completes `mdat`, writes `moov` and returns the output and the file's length in bytes.
    pub fn finish(mut self) -> Result<(W, u64)> {
        let seq = self.facts.sequence_header.ok_or_else(|| Error::invalid("an MP4 track without samples"))?;
        let seq_obu = self.facts.sequence_header_obu.clone().unwrap_or_default();
        let moov = self.moov(&seq, &seq_obu)?;
        let io = Error::Io;
        let mdat_size = MDAT_HEADER_LEN + self.mdat_payload;
        self.out.write_all(&moov).map_err(io)?;
        let end = self.out.stream_position().map_err(io)?;
        self.out.seek(SeekFrom::Start(self.mdat_start + 8)).map_err(io)?;
        self.out.write_all(&mdat_size.to_be_bytes()).map_err(io)?;
        self.out.seek(SeekFrom::Start(end)).map_err(io)?;
        self.out.flush().map_err(io)?;
        Ok((self.out, end))
    }

    /// The `av01` sample entry: visual sample entry fields, `av1C`, `colr`, `mdcv`, `clli`.
    fn sample_entry(&self, seq: &SequenceHeader, seq_obu: &[u8]) -> Result<Vec<u8>> {
        let (w, h) = match (u16::try_from(seq.max_frame_width), u16::try_from(seq.max_frame_height)) {
            (Ok(w), Ok(h)) => (w, h),
            _ => return Err(Error::unsupported("frames larger than 65535 pixels in an MP4 sample entry")),
        };
        let mut e = Vec::new();
        e.extend_from_slice(&[0; 6]); // reserved
        e.extend_from_slice(&1u16.to_be_bytes()); // data_reference_index
        e.extend_from_slice(&[0; 16]); // pre_defined, reserved, pre_defined[3]
        e.extend_from_slice(&w.to_be_bytes());
        e.extend_from_slice(&h.to_be_bytes());
        e.extend_from_slice(&0x0048_0000u32.to_be_bytes()); // 72 dpi
        e.extend_from_slice(&0x0048_0000u32.to_be_bytes());
        e.extend_from_slice(&0u32.to_be_bytes()); // reserved
        e.extend_from_slice(&1u16.to_be_bytes()); // frame_count
        let mut name = [0u8; 32];
        let text = b"AOM Coding";
        name[0] = text.len() as u8;
        name[1..=text.len()].copy_from_slice(text);
        e.extend_from_slice(&name);
        e.extend_from_slice(&0x0018u16.to_be_bytes()); // depth
        e.extend_from_slice(&(-1i16).to_be_bytes()); // pre_defined

        let c = &seq.color;
        let av1c = av1_config_record(seq, seq_obu);
        e.extend(plain_box(b"av1C", &av1c)?);
        if let Some(d) = c.color_description {
            let mut colr = b"nclx".to_vec();
            for v in [d.color_primaries, d.transfer_characteristics, d.matrix_coefficients] {
                colr.extend_from_slice(&u16::from(v).to_be_bytes());
            }
            colr.push(u8::from(c.full_range) << 7);
            e.extend(plain_box(b"colr", &colr)?);
        }
        if let Some(units) = &self.facts.mastering_display {
            let st2086 = MasteringDisplay::from_av1(units).to_st2086();
            e.extend(plain_box(b"mdcv", &mdcv_body(&st2086))?);
        }
        if let Some(cll) = &self.facts.content_light {
            let mut clli = cll.max_cll.to_be_bytes().to_vec();
            clli.extend_from_slice(&cll.max_fall.to_be_bytes());
            e.extend(plain_box(b"clli", &clli)?);
        }
        plain_box(b"av01", &e)
    }

    fn moov(&self, seq: &SequenceHeader, seq_obu: &[u8]) -> Result<Vec<u8>> {
        let n = self.sample_sizes.len() as u32;
        let duration = n; // one tick per frame
        let be32 = |v: u32| v.to_be_bytes();
        let matrix: Vec<u8> = UNITY_MATRIX.iter().flat_map(|v| v.to_be_bytes()).collect();

        let mut mvhd = Vec::new();
        mvhd.extend_from_slice(&[0; 8]); // creation, modification time
        mvhd.extend_from_slice(&be32(self.timescale));
        mvhd.extend_from_slice(&be32(duration));
        mvhd.extend_from_slice(&be32(0x0001_0000)); // rate 1.0
        mvhd.extend_from_slice(&0x0100u16.to_be_bytes()); // volume 1.0
        mvhd.extend_from_slice(&[0; 10]); // reserved
        mvhd.extend_from_slice(&matrix);
        mvhd.extend_from_slice(&[0; 24]); // pre_defined
        mvhd.extend_from_slice(&be32(2)); // next_track_ID
        let mvhd = full_box(b"mvhd", 0, 0, &mvhd)?;

        let mut tkhd = Vec::new();
        tkhd.extend_from_slice(&[0; 8]);
        tkhd.extend_from_slice(&be32(1)); // track_ID
        tkhd.extend_from_slice(&[0; 4]);
        tkhd.extend_from_slice(&be32(duration)); // in the movie timescale, which is the same
        tkhd.extend_from_slice(&[0; 8]);
        tkhd.extend_from_slice(&[0; 8]); // layer, alternate_group, volume 0 (video), reserved
        tkhd.extend_from_slice(&matrix);
        tkhd.extend_from_slice(&be32(seq.max_frame_width << 16));
        tkhd.extend_from_slice(&be32(seq.max_frame_height << 16));
        // flags: track_enabled | track_in_movie
        let tkhd = full_box(b"tkhd", 0, 3, &tkhd)?;

        let mut mdhd = Vec::new();
        mdhd.extend_from_slice(&[0; 8]);
        mdhd.extend_from_slice(&be32(self.timescale));
        mdhd.extend_from_slice(&be32(duration));
        mdhd.extend_from_slice(&0x55c4u16.to_be_bytes()); // language "und", 5 bits a letter
        mdhd.extend_from_slice(&[0; 2]);
        let mdhd = full_box(b"mdhd", 0, 0, &mdhd)?;

        let mut hdlr = vec![0; 4]; // pre_defined
        hdlr.extend_from_slice(b"vide");
        hdlr.extend_from_slice(&[0; 12]);
        hdlr.extend_from_slice(b"hdrcodec AV1\0");
        let hdlr = full_box(b"hdlr", 0, 0, &hdlr)?;

        let vmhd = full_box(b"vmhd", 0, 1, &[0; 8])?;
        let url = full_box(b"url ", 0, 1, &[])?; // flag 1: media in this file
        let mut dref = be32(1).to_vec();
        dref.extend(url);
        let dinf = container_box(b"dinf", &[full_box(b"dref", 0, 0, &dref)?])?;

        let mut stsd = be32(1).to_vec();
        stsd.extend(self.sample_entry(seq, seq_obu)?);
        let stsd = full_box(b"stsd", 0, 0, &stsd)?;
        let mut stts = Vec::new();
        if n > 0 {
            stts.extend_from_slice(&be32(1));
            stts.extend_from_slice(&be32(n));
            stts.extend_from_slice(&be32(1));
        } else {
            stts.extend_from_slice(&be32(0));
        }
        let stts = full_box(b"stts", 0, 0, &stts)?;
        let mut stss = be32(self.sync_samples.len() as u32).to_vec();
        stss.extend(self.sync_samples.iter().flat_map(|s| s.to_be_bytes()));
        let stss = full_box(b"stss", 0, 0, &stss)?;
        // One chunk holding every sample.
        let mut stsc = be32(1).to_vec();
        for v in [1, n, 1] {
            stsc.extend_from_slice(&be32(v));
        }
        let stsc = full_box(b"stsc", 0, 0, &stsc)?;
        let mut stsz = be32(0).to_vec(); // sample_size 0: a table follows
        stsz.extend_from_slice(&be32(n));
        stsz.extend(self.sample_sizes.iter().flat_map(|s| s.to_be_bytes()));
        let stsz = full_box(b"stsz", 0, 0, &stsz)?;
        let chunk_offset = self.mdat_start + MDAT_HEADER_LEN;
        let stco = match u32::try_from(chunk_offset) {
            Ok(offset) => full_box(b"stco", 0, 0, &[be32(1), be32(offset)].concat())?,
            Err(_) => full_box(b"co64", 0, 0, &[be32(1).to_vec(), chunk_offset.to_be_bytes().to_vec()].concat())?,
        };
        let stbl = container_box(b"stbl", &[stsd, stts, stss, stsc, stsz, stco])?;
        let minf = container_box(b"minf", &[vmhd, dinf, stbl])?;
        let mdia = container_box(b"mdia", &[mdhd, hdlr, minf])?;
        let trak = container_box(b"trak", &[tkhd, mdia])?;
        container_box(b"moov", &[mvhd, trak])
    }
}

/// One box of a file held in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mp4Box<'a> {
    /// The four-character type.
    pub kind: [u8; 4],
    /// The body, after the size and type (and 64-bit size) fields.
    pub body: &'a [u8],
}

/// Walks the boxes in `data`, one level deep.
#[derive(Clone, Debug)]
pub struct BoxReader<'a> {
    data: &'a [u8],
}

impl<'a> BoxReader<'a> {
    /// A walker over the boxes that `data` holds back to back.
    pub fn new(data: &'a [u8]) -> Self {
        BoxReader { data }
    }

    /// The next box, `None` at the end; a size that does not fit the data is an error.
    pub fn next_box(&mut self) -> Result<Option<Mp4Box<'a>>> {
        if self.data.is_empty() {
            return Ok(None);
        }
        let mut r = ByteReader::be(self.data);
        let size = u64::from(r.u32("an MP4 box header")?);
        let kind: [u8; 4] = r.array("an MP4 box header")?;
        let size = match size {
            0 => self.data.len() as u64, // to the end of the data
            1 => r.u64("an MP4 box's 64-bit size")?,
            s => s,
        };
        let header = r.position();
        if size < header {
            return Err(Error::invalid(format!(
                "MP4 box '{}' declares {size} bytes, less than its header",
                String::from_utf8_lossy(&kind)
            )));
        }
        if size > self.data.len() as u64 {
            return Err(Error::truncated(format!(
                "MP4 box '{}' declaring {size} bytes ({} left)",
                String::from_utf8_lossy(&kind),
                self.data.len()
            )));
        }
        let body = &self.data[header as usize..size as usize];
        self.data = &self.data[size as usize..];
        Ok(Some(Mp4Box { kind, body }))
    }

    /// Every box in turn, up to the end or to the first error.
    pub fn boxes(mut self) -> impl Iterator<Item = Result<Mp4Box<'a>>> {
        until_error(move || self.next_box())
    }

    /// The first box of type `kind` at this level, if any.
    pub fn find(data: &'a [u8], kind: &[u8; 4]) -> Result<Option<&'a [u8]>> {
        for b in BoxReader::new(data).boxes() {
            let b = b?;
            if &b.kind == kind {
                return Ok(Some(b.body));
            }
        }
        Ok(None)
    }
}

/// The items `read` returns up to the end or to its first error, which is the last item.
pub(crate) fn until_error<T>(mut read: impl FnMut() -> Result<Option<T>>) -> impl Iterator<Item = Result<T>> {
    let mut failed = false;
    std::iter::from_fn(move || {
        if failed {
            return None;
        }
        let next = read().transpose();
        failed = matches!(next, Some(Err(_)));
        next
    })
}

/// The body of a full box after its version and flags, and the version.
fn full_box_body<'a>(body: &'a [u8], what: &str) -> Result<(u8, &'a [u8])> {
    if body.len() < 4 {
        return Err(Error::truncated(format!("the MP4 '{what}' box")));
    }
    Ok((body[0], &body[4..]))
}

/// A `colr` box of type `nclx`: H.273 code points and the range.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Nclx {
    /// ColourPrimaries (9 = BT.2020).
    pub primaries: u16,
    /// TransferCharacteristics (16 = PQ, 18 = HLG).
    pub transfer: u16,
    /// MatrixCoefficients (9 = BT.2020 non-constant luminance).
    pub matrix: u16,
    /// `full_range_flag`.
    pub full_range: bool,
}

/// The video track of an MP4 file: its sample entry's facts and where its samples are.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mp4Track<'a> {
    /// The sample entry's type: `av01`, `hvc1`, `hev1`, `avc1`, …
    pub codec: [u8; 4],
    /// Width from the sample entry.
    pub width: u16,
    /// Height from the sample entry.
    pub height: u16,
    /// Ticks per second of the media (`mdhd`).
    pub timescale: u32,
    /// Duration in `timescale` ticks (`mdhd`).
    pub duration: u64,
    /// The codec configuration record's body (`av1C`, `hvcC` or `avcC`), if present.
    pub config: Option<&'a [u8]>,
    /// The `colr` box of type `nclx`, if present.
    pub nclx: Option<Nclx>,
    /// The `mdcv` box, if present.
    pub mastering_display: Option<St2086Units>,
    /// The `clli` box, if present.
    pub content_light: Option<ContentLightLevel>,
    /// Samples in the track (`stsz`).
    pub sample_count: u32,
    stsz: &'a [u8],
    stsc: &'a [u8],
    chunk_offsets: &'a [u8],
    chunk_offsets_are_64_bit: bool,
    file: &'a [u8],
    max_sample_bytes: u64,
}

impl<'a> Mp4Track<'a> {
    /// Finds the first video track (`hdlr` type `vide`) of an MP4 file held in memory.
    pub fn first_video(file: &'a [u8], limits: &Limits) -> Result<Self> {
        let moov = BoxReader::find(file, b"moov")?.ok_or_else(|| Error::invalid("an MP4 file without 'moov'"))?;
        for b in BoxReader::new(moov).boxes() {
            let b = b?;
            if &b.kind != b"trak" {
                continue;
            }
            let mdia =
                BoxReader::find(b.body, b"mdia")?.ok_or_else(|| Error::invalid("an MP4 track without 'mdia'"))?;
            let hdlr = BoxReader::find(mdia, b"hdlr")?.ok_or_else(|| Error::invalid("an MP4 track without 'hdlr'"))?;
            let (_, hdlr) = full_box_body(hdlr, "hdlr")?;
            if hdlr.get(4..8) != Some(b"vide") {
                continue;
            }
            return Self::parse(file, mdia, limits);
        }
        Err(Error::invalid("an MP4 file without a video track"))
    }

    fn parse(file: &'a [u8], mdia: &'a [u8], limits: &Limits) -> Result<Self> {
        let need =
            |b: Option<&'a [u8]>, what: &str| b.ok_or_else(|| Error::invalid(format!("an MP4 track without '{what}'")));
        let (version, mdhd) = full_box_body(need(BoxReader::find(mdia, b"mdhd")?, "mdhd")?, "mdhd")?;
        let mut r = ByteReader::be(mdhd);
        let (timescale, duration) = if version == 1 {
            r.skip(16, "the MP4 'mdhd' box")?;
            (r.u32("the MP4 'mdhd' box")?, r.u64("the MP4 'mdhd' box")?)
        } else {
            r.skip(8, "the MP4 'mdhd' box")?;
            (r.u32("the MP4 'mdhd' box")?, u64::from(r.u32("the MP4 'mdhd' box")?))
        };
        let minf = need(BoxReader::find(mdia, b"minf")?, "minf")?;
        let stbl = need(BoxReader::find(minf, b"stbl")?, "stbl")?;
        let (_, stsd) = full_box_body(need(BoxReader::find(stbl, b"stsd")?, "stsd")?, "stsd")?;
        let mut r = ByteReader::be(stsd);
        if r.u32("the MP4 'stsd' box")? == 0 {
            return Err(Error::invalid("an MP4 track without a sample entry"));
        }
        let entry = BoxReader::new(r.rest()).next_box()?.ok_or_else(|| Error::truncated("the MP4 sample entry"))?;
        // VisualSampleEntry: 6 reserved, data_reference_index, 16 bytes, width, height, then
        // 50 bytes up to the child boxes.
        let mut v = ByteReader::be(entry.body);
        v.skip(24, "the MP4 visual sample entry")?;
        let width = v.u16("the MP4 visual sample entry")?;
        let height = v.u16("the MP4 visual sample entry")?;
        v.skip(50, "the MP4 visual sample entry")?;
        let (mut config, mut nclx, mut mastering_display, mut content_light) = (None, None, None, None);
        for child in BoxReader::new(v.rest()).boxes() {
            let child = child?;
            match &child.kind {
                b"av1C" | b"hvcC" | b"avcC" => config = Some(child.body),
                b"colr" if child.body.get(..4) == Some(b"nclx") => {
                    let mut c = ByteReader::be(&child.body[4..]);
                    nclx = Some(Nclx {
                        primaries: c.u16("the MP4 'colr' box")?,
                        transfer: c.u16("the MP4 'colr' box")?,
                        matrix: c.u16("the MP4 'colr' box")?,
                        full_range: c.u8("the MP4 'colr' box")? & 0x80 != 0,
                    })
                }
                b"mdcv" => mastering_display = Some(parse_mdcv(child.body)?),
                b"clli" => {
                    let mut c = ByteReader::be(child.body);
                    content_light = Some(ContentLightLevel {
                        max_cll: c.u16("the MP4 'clli' box")?,
                        max_fall: c.u16("the MP4 'clli' box")?,
                    });
                }
                _ => {}
            }
        }
        if width != 0 && height != 0 {
            limits.check_dimensions(width.into(), height.into())?;
        }
        let (_, stsz) = full_box_body(need(BoxReader::find(stbl, b"stsz")?, "stsz")?, "stsz")?;
        let mut r = ByteReader::be(stsz);
        let uniform = r.u32("the MP4 'stsz' box")?;
        let sample_count = r.u32("the MP4 'stsz' box")?;
        if uniform == 0 {
            r.check_remaining(sample_count.into(), 4, "the MP4 sample size table")?;
        }
        let (_, stsc) = full_box_body(need(BoxReader::find(stbl, b"stsc")?, "stsc")?, "stsc")?;
        let (chunk_offsets, chunk_offsets_are_64_bit) = match BoxReader::find(stbl, b"stco")? {
            Some(b) => (full_box_body(b, "stco")?.1, false),
            None => (full_box_body(need(BoxReader::find(stbl, b"co64")?, "stco")?, "co64")?.1, true),
        };
        Ok(Mp4Track {
            codec: entry.kind,
            width,
            height,
            timescale,
            duration,
            config,
            nclx,
            mastering_display,
            content_light,
            sample_count,
            stsz,
            stsc,
            chunk_offsets,
            chunk_offsets_are_64_bit,
            file,
            max_sample_bytes: limits.max_alloc_bytes,
        })
    }

    /// The samples in decoding order, borrowed from the file.
    pub fn samples(&self) -> Mp4Samples<'a> {
        Mp4Samples { track: self.clone(), index: 0, chunk: 0, left_in_chunk: 0, next_offset: 0, stsc_entry: 0 }
    }

    fn sample_size(&self, index: u32) -> Result<u64> {
        let mut r = ByteReader::be(self.stsz);
        let uniform = r.u32("the MP4 'stsz' box")?;
        if uniform != 0 {
            return Ok(uniform.into());
        }
        Ok(r.at(8 + 4 * u64::from(index)).u32("the MP4 sample size table")?.into())
    }

    fn chunk_offset(&self, chunk: u32) -> Result<u64> {
        let r = ByteReader::be(self.chunk_offsets);
        let count = r.at(0).u32("the MP4 chunk offset table")?;
        if chunk >= count {
            return Err(Error::invalid(format!(
                "MP4 sample table refers to chunk {} of {count}",
                u64::from(chunk) + 1
            )));
        }
        if self.chunk_offsets_are_64_bit {
            r.at(4 + 8 * u64::from(chunk)).u64("the MP4 chunk offset table")
        } else {
            Ok(r.at(4 + 4 * u64::from(chunk)).u32("the MP4 chunk offset table")?.into())
        }
    }

    /// `stsc` entry `i`: (first_chunk, samples_per_chunk), first_chunk 1-based.
    fn stsc_entry(&self, i: u32) -> Result<Option<(u32, u32)>> {
        let r = ByteReader::be(self.stsc);
        if i >= r.at(0).u32("the MP4 'stsc' box")? {
            return Ok(None);
        }
        let mut e = r.at(4 + 12 * u64::from(i));
        Ok(Some((e.u32("the MP4 'stsc' box")?, e.u32("the MP4 'stsc' box")?)))
    }
}

/// The samples of an [`Mp4Track`], in order.
#[derive(Clone, Debug)]
pub struct Mp4Samples<'a> {
    track: Mp4Track<'a>,
    index: u32,
    /// The current chunk, 0-based.
    chunk: u32,
    left_in_chunk: u32,
    next_offset: u64,
    /// The `stsc` entry that covers `chunk`.
    stsc_entry: u32,
}

impl<'a> Mp4Samples<'a> {
    /// Every remaining sample in turn, up to the end or to the first error.
    pub fn results(mut self) -> impl Iterator<Item = Result<&'a [u8]>> {
        until_error(move || self.next_sample())
    }

    /// The next sample, `None` after the last.
    pub fn next_sample(&mut self) -> Result<Option<&'a [u8]>> {
        let t = &self.track;
        if self.index >= t.sample_count {
            return Ok(None);
        }
        // Move to the next chunk that holds samples (an entry may give 0 per chunk).
        let mut guard = 0u32;
        while self.left_in_chunk == 0 {
            if self.index > 0 || guard > 0 {
                self.chunk =
                    self.chunk.checked_add(1).ok_or_else(|| Error::invalid("an MP4 sample table past 2^32 chunks"))?;
            }
            guard += 1;
            // The entry in force: the last whose first_chunk is at most this chunk.
            while let Some((first, _)) = t.stsc_entry(self.stsc_entry + 1)? {
                if u64::from(first) <= u64::from(self.chunk) + 1 {
                    self.stsc_entry += 1;
                } else {
                    break;
                }
            }
            let (first, per_chunk) =
                t.stsc_entry(self.stsc_entry)?.ok_or_else(|| Error::invalid("an MP4 track with an empty 'stsc'"))?;
            if first == 0 || u64::from(first) > u64::from(self.chunk) + 1 {
                return Err(Error::invalid("an MP4 'stsc' box whose entries are out of order"));
            }
            self.left_in_chunk = per_chunk;
            self.next_offset = t.chunk_offset(self.chunk)?;
        }
        let size = t.sample_size(self.index)?;
        if size > t.max_sample_bytes {
            return Err(Error::limit(format!(
                "MP4 sample {} declares {size} bytes, more than the limit of {}",
                self.index, t.max_sample_bytes
            )));
        }
        let data =
            ByteReader::be(t.file).bytes_at(self.next_offset, size, format_args!("MP4 sample {}", self.index))?;
        self.next_offset += size;
        self.left_in_chunk -= 1;
        self.index += 1;
        Ok(Some(data))
    }
}

/// What the video track of an MP4 file declares, gathered from the boxes and the bitstream
/// (AV1 sequence header and metadata OBUs, or HEVC SPS and SEI) without decoding.
#[derive(Clone, Debug, PartialEq)]
pub struct Mp4VideoInfo {
    /// The sample entry type: `av01`, `hvc1`, `hev1`, …
    pub codec: [u8; 4],
    /// Width in pixels (sample entry).
    pub width: u32,
    /// Height in pixels (sample entry).
    pub height: u32,
    /// Samples (frames) in the track.
    pub frames: u32,
    /// Frames per second from the media duration, when it is known.
    pub frame_rate: Option<f64>,
    /// Luma bit depth, from the bitstream's header.
    pub bit_depth: Option<u32>,
    /// H.273 (primaries, transfer, matrix), and where they were found.
    pub colour: Option<([u8; 3], &'static str)>,
    /// Full range (true) or limited, when declared.
    pub full_range: Option<bool>,
    /// The mastering display as the file states it (cd/m², chromaticities), and where.
    pub mastering_display: Option<(MasteringDisplay, &'static str)>,
    /// MaxCLL / MaxFALL, and where.
    pub content_light: Option<(ContentLightLevel, &'static str)>,
    /// For AV1, what the temporal units say (sequence header, metadata, T.35).
    pub av1: Option<crate::obu::StreamSummary>,
    /// Statements of the file that cannot be right (reported, not corrected).
    pub problems: Vec<String>,
}

/// Reads the first video track of an MP4 file: AV1 (every sample's OBUs are walked) or HEVC
/// (the `hvcC` parameter sets and the first sample's SEI); other codecs give what the boxes say.
pub fn probe_mp4(file: &[u8], limits: &Limits) -> Result<Mp4VideoInfo> {
    let track = Mp4Track::first_video(file, limits)?;
    let mut info = Mp4VideoInfo {
        codec: track.codec,
        width: track.width.into(),
        height: track.height.into(),
        frames: track.sample_count,
        frame_rate: (track.duration > 0 && track.timescale > 0)
            .then(|| f64::from(track.sample_count) * f64::from(track.timescale) / track.duration as f64),
        bit_depth: None,
        colour: track.nclx.map(|c| ([c.primaries, c.transfer, c.matrix].map(|v| v.min(255) as u8), "colr box")),
        full_range: track.nclx.map(|c| c.full_range),
        mastering_display: track.mastering_display.map(|u| (MasteringDisplay::from_st2086(&u), "mdcv box")),
        content_light: track.content_light.map(|c| (c, "clli box")),
        av1: None,
        problems: Vec::new(),
    };
    match &track.codec {
        b"av01" => {
            let mut summary = crate::obu::StreamSummary::default();
            for sample in track.samples().results() {
                summary.add_temporal_unit(sample?)?;
            }
            if summary.sequence_header.is_none() {
                if let Some(obus) = track.config.and_then(|c| c.get(4..)) {
                    let mut config = crate::obu::StreamSummary::default();
                    config.add_temporal_unit(obus)?;
                    summary.sequence_header = config.sequence_header;
                }
            }
            if let Some(seq) = &summary.sequence_header {
                info.bit_depth = Some(seq.color.bit_depth.into());
                if info.colour.is_none() {
                    info.colour = seq.color.color_description.map(|d| {
                        ([d.color_primaries, d.transfer_characteristics, d.matrix_coefficients], "AV1 sequence header")
                    });
                    info.full_range = Some(seq.color.full_range);
                }
            }
            if info.mastering_display.is_none() {
                info.mastering_display =
                    summary.mastering_display.map(|u| (MasteringDisplay::from_av1(&u), "AV1 metadata OBU"));
            }
            if info.content_light.is_none() {
                info.content_light = summary.content_light.map(|c| (c, "AV1 metadata OBU"));
            }
            info.av1 = Some(summary);
        }
        b"hvc1" | b"hev1" => {
            let hvcc = track.config.ok_or_else(|| Error::invalid("an HEVC MP4 track without 'hvcC'"))?;
            let (length_size, nals) = crate::hevc::hvcc_nal_units(hvcc)?;
            let mut sei = crate::hevc::HevcHdrSei::default();
            for nal in &nals {
                if crate::hevc::nal_type(nal) == Some(crate::hevc::NAL_SPS) && info.bit_depth.is_none() {
                    let sps = crate::hevc::HevcSps::parse(nal)?;
                    info.bit_depth = Some(sps.bit_depth);
                    if info.colour.is_none() {
                        info.colour = sps.colour_description.map(|c| (c, "HEVC VUI"));
                        info.full_range = Some(sps.full_range);
                    }
                }
                sei.add_nal(nal)?;
            }
            if let Some(first) = track.samples().next_sample()? {
                for nal in crate::hevc::sample_nal_units(first, length_size) {
                    sei.add_nal(nal?)?;
                }
            }
            if info.mastering_display.is_none() {
                info.mastering_display = sei.mastering_display.map(|u| (MasteringDisplay::from_st2086(&u), "HEVC SEI"));
            }
            if info.content_light.is_none() {
                info.content_light = sei.content_light.map(|c| (c, "HEVC SEI"));
            }
        }
        _ => {}
    }
    if let Some((md, source)) = &info.mastering_display {
        info.problems.extend(mastering_display_problems(md).into_iter().map(|p| format!("{source}: {p}")));
    }
    Ok(info)
}

/// What cannot be right in a mastering display as read (in R, G, B order): primaries that are
/// not where their names put them (red has the largest x, green the largest y, blue the
/// smallest y: true of every real RGB display's gamut), a peak below 50 cd/m² (no HDR
/// mastering display is that dim; typically nits written where the field counts 0.0001 cd/m²),
/// or a black above the peak.
pub fn mastering_display_problems(md: &MasteringDisplay) -> Vec<String> {
    let [r, g, b] = md.primaries;
    let mut problems = Vec::new();
    if !(r[0] > g[0] && r[0] > b[0] && g[1] > r[1] && g[1] > b[1] && b[1] < r[1]) {
        problems.push(format!(
            "primaries out of order: red ({:.4}, {:.4}), green ({:.4}, {:.4}), blue ({:.4}, {:.4}) \
             (red should have the largest x, green the largest y, blue the smallest y: \
             written in another order than the format's)",
            r[0], r[1], g[0], g[1], b[0], b[1]
        ));
    }
    if md.max_luminance < 50.0 {
        problems.push(format!(
            "peak luminance {} cd/m² is implausibly low (a value in cd/m² where the field counts 0.0001 cd/m²?)",
            md.max_luminance
        ));
    }
    if md.min_luminance >= md.max_luminance {
        problems.push(format!("black {} cd/m² is not below the peak {} cd/m²", md.min_luminance, md.max_luminance));
    }
    problems
}

/// True when `data` looks like an ISO base media file (a `ftyp` box first).
pub fn is_mp4(data: &[u8]) -> bool {
    data.get(4..8) == Some(b"ftyp")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::obu::write_metadata_obu;
    use std::io::Cursor;

    /// A temporal unit: delimiter, a (fake, unparsed here) frame OBU.
    fn unit(seq: Option<&[u8]>, frame: &[u8]) -> Vec<u8> {
        let mut tu = vec![0x12, 0x00];
        if let Some(seq) = seq {
            tu.push(0x0a);
            tu.push(seq.len() as u8);
            tu.extend_from_slice(seq);
        }
        tu.push(obu_type::FRAME << 3 | 0x02);
        tu.push(frame.len() as u8);
        tu.extend_from_slice(frame);
        tu
    }

    #[test]
    fn mdcv_is_green_blue_red_in_sei_units() {
        let units = MasteringDisplay::bt2020(1000.0, 0.0001).to_st2086();
        let body = mdcv_body(&units);
        // VIDEO-NOTES §3.2: BT.2020 green (0.170, 0.797) = (8500, 39850) first; white 15635, 16450.
        assert_eq!(&body[..4], &[0x21, 0x34, 0x9b, 0xaa]);
        assert_eq!(&body[12..16], &[0x3d, 0x13, 0x40, 0x42]);
        assert_eq!(&body[16..], &[0, 0x98, 0x96, 0x80, 0, 0, 0, 1]);
        assert_eq!(parse_mdcv(&body).unwrap(), units);
        assert!(parse_mdcv(&body[..23]).is_err());
    }

    #[test]
    fn writes_and_reads_back_a_track() {
        let seq = crate::obu::tests::hdr10_sequence_header();
        let mut first = unit(Some(&seq), &[1, 2, 3]);
        write_metadata_obu(&mut first, crate::obu::metadata_type::HDR_CLL, &[0x03, 0xe8, 0x01, 0x90]);
        let second = unit(None, &[4, 5]);
        let mut w = Mp4Writer::new(Cursor::new(Vec::new()), 25).unwrap();
        w.write_temporal_unit(&first, true).unwrap();
        w.write_temporal_unit(&second, false).unwrap();
        let (out, len) = w.finish().unwrap();
        let file = out.into_inner();
        assert_eq!(len, file.len() as u64);
        assert!(is_mp4(&file));
        let track = Mp4Track::first_video(&file, &Limits::default()).unwrap();
        assert_eq!((&track.codec, track.width, track.height, track.timescale), (b"av01", 96, 64, 25));
        assert_eq!((track.duration, track.sample_count), (2, 2));
        assert_eq!(track.nclx, Some(Nclx { primaries: 9, transfer: 16, matrix: 9, full_range: false }));
        assert_eq!(track.content_light, Some(ContentLightLevel { max_cll: 1000, max_fall: 400 }));
        assert_eq!(track.mastering_display, None);
        let config = track.config.unwrap();
        // marker/version, profile 0 level 8, 10-bit 4:2:0 colocated, then the sequence header OBU.
        assert_eq!(&config[..4], &[0x81, 0x08, 0x4e, 0x00]);
        assert_eq!(&config[4..6], &[0x0a, seq.len() as u8]);
        let samples: Vec<_> = track.samples().results().collect::<Result<_>>().unwrap();
        // The samples are the temporal units without their delimiters.
        assert_eq!(samples, [&first[2..], &second[2..]]);
    }

    #[test]
    fn truncation_and_damage_are_errors_not_panics() {
        let seq = crate::obu::tests::hdr10_sequence_header();
        let mut w = Mp4Writer::new(Cursor::new(Vec::new()), 30).unwrap();
        for i in 0..3u8 {
            w.write_temporal_unit(&unit(Some(&seq), &[i; 7]), true).unwrap();
        }
        let file = w.finish().unwrap().0.into_inner();
        for len in 0..file.len() {
            let cut = &file[..len];
            if let Ok(track) = Mp4Track::first_video(cut, &Limits::default()) {
                // moov is last: a cut file that still parses lost nothing the index points to.
                assert!(track.samples().results().all(|s| s.is_ok()), "cut at {len}");
            }
        }
        for i in 0..file.len() {
            for bit in [0, 3, 7] {
                let mut bad = file.clone();
                bad[i] ^= 1 << bit;
                if let Ok(track) = Mp4Track::first_video(&bad, &Limits::fuzzing()) {
                    let _ = track.samples().results().count();
                }
            }
        }
        assert!(Mp4Writer::new(Cursor::new(Vec::new()), 30).unwrap().finish().is_err());
        let mut w = Mp4Writer::new(Cursor::new(Vec::new()), 30).unwrap();
        assert!(w.write_temporal_unit(&unit(None, &[1]), true).is_err(), "no sequence header first");
        assert!(BoxReader::new(&[0, 0, 0, 4, b'f', b'r', b'e', b'e']).next_box().is_err());
        assert!(BoxReader::new(&[0, 0, 0, 9, b'f', b'r', b'e', b'e']).next_box().is_err());
    }
}
