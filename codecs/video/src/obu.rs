//! AV1 open bitstream units (OBUs): a walker over a temporal unit, and parsers for the parts
//! that HDR10 signalling lives in, so that a stream can be checked without decoding it — the
//! sequence header's `color_config` and the metadata OBUs (content light level, mastering
//! display, ITU-T T.35).
//!
//! Written from the syntax tables of the AV1 Bitstream & Decoding Process Specification
//! (version 1.0.0 with errata): §4.10 descriptors (`f(n)`, `leb128()`, `uvlc()`), §5.3 OBU
//! header and trailing bits, §5.5 sequence header OBU, §5.8 metadata OBU; semantics in §6.4
//! and §6.7. Every read is bounds-checked: bad input gives an [`Error`], never a panic, and
//! nothing is allocated in proportion to what the input declares.

use hdrcodec_core::{Av1MdcvUnits, ContentLightLevel, Error, Hdr10Metadata, MasteringDisplay, Result};

/// `obu_type` values (AV1 §6.2.2, Table "OBU types").
pub mod obu_type {
    /// OBU_SEQUENCE_HEADER.
    pub const SEQUENCE_HEADER: u8 = 1;
    /// OBU_TEMPORAL_DELIMITER.
    pub const TEMPORAL_DELIMITER: u8 = 2;
    /// OBU_FRAME_HEADER.
    pub const FRAME_HEADER: u8 = 3;
    /// OBU_TILE_GROUP.
    pub const TILE_GROUP: u8 = 4;
    /// OBU_METADATA.
    pub const METADATA: u8 = 5;
    /// OBU_FRAME.
    pub const FRAME: u8 = 6;
    /// OBU_REDUNDANT_FRAME_HEADER.
    pub const REDUNDANT_FRAME_HEADER: u8 = 7;
    /// OBU_TILE_LIST.
    pub const TILE_LIST: u8 = 8;
    /// OBU_PADDING.
    pub const PADDING: u8 = 15;
}

/// `metadata_type` values (AV1 §6.7.1).
pub mod metadata_type {
    /// METADATA_TYPE_HDR_CLL.
    pub const HDR_CLL: u64 = 1;
    /// METADATA_TYPE_HDR_MDCV.
    pub const HDR_MDCV: u64 = 2;
    /// METADATA_TYPE_SCALABILITY.
    pub const SCALABILITY: u64 = 3;
    /// METADATA_TYPE_ITUT_T35.
    pub const ITUT_T35: u64 = 4;
    /// METADATA_TYPE_TIMECODE.
    pub const TIMECODE: u64 = 5;
}

/// `leb128()` (§4.10.5): little-endian base-128, at most 8 bytes, value below 2^32 (the spec
/// requires it of conforming streams). Returns the value and the bytes it took.
pub fn read_leb128(data: &[u8]) -> Result<(u64, usize)> {
    let mut value = 0u64;
    for i in 0..8 {
        let byte = *data.get(i).ok_or_else(|| Error::truncated("a leb128 number"))?;
        value |= u64::from(byte & 0x7f) << (7 * i);
        if byte & 0x80 == 0 {
            if value > u64::from(u32::MAX) {
                return Err(Error::invalid(format!("leb128 value {value} exceeds 2^32 - 1")));
            }
            return Ok((value, i + 1));
        }
    }
    Err(Error::invalid("a leb128 number longer than 8 bytes"))
}

/// Appends `value` as `leb128()` in the fewest bytes.
pub fn write_leb128(out: &mut Vec<u8>, mut value: u64) {
    loop {
        let byte = (value & 0x7f) as u8;
        value >>= 7;
        if value == 0 {
            out.push(byte);
            return;
        }
        out.push(byte | 0x80);
    }
}

/// An MSB-first bit reader over one OBU payload, for the `f(n)` descriptor (§4.10.2).
struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    what: &'static str,
}

impl<'a> Bits<'a> {
    fn new(data: &'a [u8], what: &'static str) -> Self {
        Bits { data, pos: 0, what }
    }

    /// `f(n)` for n ≤ 32.
    fn f(&mut self, n: u32) -> Result<u32> {
        let mut v = 0u32;
        for _ in 0..n {
            let byte = *self.data.get(self.pos / 8).ok_or_else(|| Error::truncated(self.what))?;
            let bit = (byte >> (7 - self.pos % 8)) & 1;
            v = (v << 1) | u32::from(bit);
            self.pos += 1;
        }
        Ok(v)
    }

    fn flag(&mut self) -> Result<bool> {
        Ok(self.f(1)? == 1)
    }

    /// `uvlc()` (§4.10.3); only skipped here, so the value saturates as the spec's does.
    fn uvlc(&mut self) -> Result<u32> {
        let mut leading_zeros = 0u32;
        while !self.flag()? {
            leading_zeros += 1;
            if leading_zeros >= 32 {
                return Ok(u32::MAX);
            }
        }
        let value = self.f(leading_zeros)?;
        Ok(value.saturating_add((1u32 << leading_zeros) - 1))
    }
}

/// One OBU: its header fields and payload (§5.3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Obu<'a> {
    /// `obu_type` (see [`obu_type`]).
    pub obu_type: u8,
    /// `temporal_id` and `spatial_id` when the OBU has an extension header.
    pub extension: Option<(u8, u8)>,
    /// The payload (`obu_size` bytes).
    pub payload: &'a [u8],
    /// The whole OBU as it stands in the data: header, size field and payload.
    pub raw: &'a [u8],
}

/// Walks the OBUs of a temporal unit (or any run of OBUs, e.g. an IVF frame's payload).
#[derive(Clone, Debug)]
pub struct ObuReader<'a> {
    data: &'a [u8],
    failed: bool,
}

impl<'a> ObuReader<'a> {
    /// A walker over `data`.
    pub fn new(data: &'a [u8]) -> Self {
        ObuReader { data, failed: false }
    }

    /// The next OBU, `None` at the end. An OBU without `obu_has_size_field` takes the rest of
    /// the data (the low-overhead format requires the field, §5.2, but Annex B does not).
    pub fn next_obu(&mut self) -> Result<Option<Obu<'a>>> {
        if self.data.is_empty() {
            return Ok(None);
        }
        let header = self.data[0];
        if header & 0x80 != 0 {
            return Err(Error::invalid("OBU header with obu_forbidden_bit set"));
        }
        let obu_type = (header >> 3) & 0x0f;
        let has_extension = header & 0x04 != 0;
        let has_size = header & 0x02 != 0;
        let mut pos = 1;
        let extension = if has_extension {
            let ext = *self.data.get(1).ok_or_else(|| Error::truncated("an OBU extension header"))?;
            pos = 2;
            Some((ext >> 5, (ext >> 3) & 0x03))
        } else {
            None
        };
        let size = if has_size {
            let (size, len) = read_leb128(&self.data[pos..])?;
            pos += len;
            size
        } else {
            (self.data.len() - pos) as u64
        };
        let rest = &self.data[pos..];
        if size > rest.len() as u64 {
            return Err(Error::truncated(format!("an OBU of type {obu_type} declaring {size} bytes")));
        }
        let raw = &self.data[..pos + size as usize];
        let (payload, after) = rest.split_at(size as usize);
        self.data = after;
        Ok(Some(Obu { obu_type, extension, payload, raw }))
    }
}

impl<'a> Iterator for ObuReader<'a> {
    type Item = Result<Obu<'a>>;
    /// Stops after the first error.
    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let next = self.next_obu().transpose();
        self.failed = matches!(next, Some(Err(_)));
        next
    }
}

/// `color_primaries`, `transfer_characteristics`, `matrix_coefficients` (ITU-T H.273 codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColorDescription {
    /// H.273 ColourPrimaries: 9 = BT.2020.
    pub color_primaries: u8,
    /// H.273 TransferCharacteristics: 16 = PQ, 18 = HLG.
    pub transfer_characteristics: u8,
    /// H.273 MatrixCoefficients: 9 = BT.2020 non-constant luminance.
    pub matrix_coefficients: u8,
}

impl ColorDescription {
    /// HDR10: BT.2020 primaries, PQ, BT.2020 NCL (9/16/9).
    pub const HDR10_PQ: Self =
        ColorDescription { color_primaries: 9, transfer_characteristics: 16, matrix_coefficients: 9 };
    /// BT.2100 HLG: 9/18/9.
    pub const HLG: Self = ColorDescription { color_primaries: 9, transfer_characteristics: 18, matrix_coefficients: 9 };
}

/// `chroma_sample_position` (§6.4.2).
pub mod chroma_sample_position {
    /// CSP_UNKNOWN.
    pub const UNKNOWN: u8 = 0;
    /// CSP_VERTICAL: horizontally co-sited with luma column 0, vertically between rows (ffprobe `left`).
    pub const VERTICAL: u8 = 1;
    /// CSP_COLOCATED: co-sited with the top-left luma sample (ffprobe `topleft`).
    pub const COLOCATED: u8 = 2;
}

/// The sequence header's `color_config()` (§5.5.2), with the values the spec infers for
/// fields that are absent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColorConfig {
    /// BitDepth: 8, 10 or 12.
    pub bit_depth: u8,
    /// `mono_chrome`.
    pub mono_chrome: bool,
    /// The colour description, when `color_description_present_flag` is set.
    pub color_description: Option<ColorDescription>,
    /// `color_range`: true = full range, false = studio ("limited") range.
    pub full_range: bool,
    /// `subsampling_x`.
    pub subsampling_x: bool,
    /// `subsampling_y`.
    pub subsampling_y: bool,
    /// `chroma_sample_position` (see [`chroma_sample_position`]); 0 unless 4:2:0.
    pub chroma_sample_position: u8,
    /// `separate_uv_delta_q`.
    pub separate_uv_delta_q: bool,
}

/// The fields of a sequence header OBU (§5.5.1) that describe the stream as a whole.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SequenceHeader {
    /// `seq_profile`: 0 Main, 1 High, 2 Professional.
    pub profile: u8,
    /// `still_picture`.
    pub still_picture: bool,
    /// `seq_level_idx[0]`, the level of the first operating point (31: no level constraint).
    pub level_idx: u8,
    /// `seq_tier[0]`.
    pub tier: u8,
    /// `max_frame_width_minus_1 + 1`.
    pub max_frame_width: u32,
    /// `max_frame_height_minus_1 + 1`.
    pub max_frame_height: u32,
    /// `color_config()`.
    pub color: ColorConfig,
    /// `film_grain_params_present`.
    pub film_grain_params_present: bool,
}

impl SequenceHeader {
    /// Parses a sequence header OBU's payload.
    pub fn parse(payload: &[u8]) -> Result<Self> {
        let mut b = Bits::new(payload, "the AV1 sequence header");
        let profile = b.f(3)? as u8;
        if profile > 2 {
            return Err(Error::unsupported(format!("AV1 seq_profile {profile} (reserved)")));
        }
        let still_picture = b.flag()?;
        let reduced_still_picture_header = b.flag()?;
        let (level_idx, tier);
        if reduced_still_picture_header {
            level_idx = b.f(5)? as u8;
            tier = 0;
        } else {
            let timing_info_present = b.flag()?;
            let mut decoder_model_info_present = false;
            let mut buffer_delay_length = 0;
            if timing_info_present {
                // timing_info() (§5.5.3)
                b.f(32)?; // num_units_in_display_tick
                b.f(32)?; // time_scale
                if b.flag()? {
                    b.uvlc()?; // num_ticks_per_picture_minus_1
                }
                decoder_model_info_present = b.flag()?;
                if decoder_model_info_present {
                    // decoder_model_info() (§5.5.4)
                    buffer_delay_length = b.f(5)? + 1;
                    b.f(32)?; // num_units_in_decoding_tick
                    b.f(5)?; // buffer_removal_time_length_minus_1
                    b.f(5)?; // frame_presentation_time_length_minus_1
                }
            }
            let initial_display_delay_present = b.flag()?;
            let operating_points = b.f(5)? + 1;
            let (mut first_level, mut first_tier) = (0u8, 0u8);
            for i in 0..operating_points {
                b.f(12)?; // operating_point_idc[i]
                let level = b.f(5)? as u8;
                let t = if level > 7 { b.f(1)? as u8 } else { 0 };
                if i == 0 {
                    (first_level, first_tier) = (level, t);
                }
                if decoder_model_info_present && b.flag()? {
                    // operating_parameters_info(i) (§5.5.5)
                    b.f(buffer_delay_length)?; // decoder_buffer_delay
                    b.f(buffer_delay_length)?; // encoder_buffer_delay
                    b.f(1)?; // low_delay_mode_flag
                }
                if initial_display_delay_present && b.flag()? {
                    b.f(4)?; // initial_display_delay_minus_1
                }
            }
            level_idx = first_level;
            tier = first_tier;
        }
        let width_bits = b.f(4)? + 1;
        let height_bits = b.f(4)? + 1;
        let max_frame_width = b.f(width_bits)? + 1;
        let max_frame_height = b.f(height_bits)? + 1;
        let frame_id_numbers_present = !reduced_still_picture_header && b.flag()?;
        if frame_id_numbers_present {
            b.f(4)?; // delta_frame_id_length_minus_2
            b.f(3)?; // additional_frame_id_length_minus_1
        }
        b.f(3)?; // use_128x128_superblock, enable_filter_intra, enable_intra_edge_filter
        if !reduced_still_picture_header {
            b.f(4)?; // enable_interintra_compound, masked_compound, warped_motion, dual_filter
            let enable_order_hint = b.flag()?;
            if enable_order_hint {
                b.f(2)?; // enable_jnt_comp, enable_ref_frame_mvs
            }
            // seq_choose_screen_content_tools, else seq_force_screen_content_tools; a chosen
            // value is SELECT_SCREEN_CONTENT_TOOLS (2), which is > 0.
            let force_screen_content_tools = if b.flag()? { 2 } else { b.f(1)? };
            if force_screen_content_tools > 0 && !b.flag()? {
                b.f(1)?; // seq_force_integer_mv
            }
            if enable_order_hint {
                b.f(3)?; // order_hint_bits_minus_1
            }
        }
        b.f(3)?; // enable_superres, enable_cdef, enable_restoration
        let color = parse_color_config(&mut b, profile)?;
        let film_grain_params_present = b.flag()?;
        Ok(SequenceHeader {
            profile,
            still_picture,
            level_idx,
            tier,
            max_frame_width,
            max_frame_height,
            color,
            film_grain_params_present,
        })
    }
}

/// `color_config()` (§5.5.2).
fn parse_color_config(b: &mut Bits, profile: u8) -> Result<ColorConfig> {
    let high_bitdepth = b.flag()?;
    let bit_depth = if profile == 2 && high_bitdepth {
        if b.flag()? {
            12
        } else {
            10
        }
    } else if high_bitdepth {
        10
    } else {
        8
    };
    let mono_chrome = profile != 1 && b.flag()?;
    let color_description = if b.flag()? {
        Some(ColorDescription {
            color_primaries: b.f(8)? as u8,
            transfer_characteristics: b.f(8)? as u8,
            matrix_coefficients: b.f(8)? as u8,
        })
    } else {
        None
    };
    let mut c = ColorConfig {
        bit_depth,
        mono_chrome,
        color_description,
        full_range: false,
        subsampling_x: true,
        subsampling_y: true,
        chroma_sample_position: chroma_sample_position::UNKNOWN,
        separate_uv_delta_q: false,
    };
    if mono_chrome {
        c.full_range = b.flag()?;
        return Ok(c);
    }
    // BT.709 primaries, sRGB transfer and the identity matrix: the spec fixes full range 4:4:4.
    let srgb = matches!(
        color_description,
        Some(ColorDescription { color_primaries: 1, transfer_characteristics: 13, matrix_coefficients: 0 })
    );
    if srgb {
        c.full_range = true;
        (c.subsampling_x, c.subsampling_y) = (false, false);
    } else {
        c.full_range = b.flag()?;
        (c.subsampling_x, c.subsampling_y) = match profile {
            0 => (true, true),
            1 => (false, false),
            _ if bit_depth == 12 => {
                let x = b.flag()?;
                (x, x && b.flag()?)
            }
            _ => (true, false),
        };
        if c.subsampling_x && c.subsampling_y {
            c.chroma_sample_position = b.f(2)? as u8;
        }
    }
    c.separate_uv_delta_q = b.flag()?;
    Ok(c)
}

/// A parsed metadata OBU (§5.8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metadata<'a> {
    /// `metadata_hdr_cll()` (§5.8.3): MaxCLL and MaxFALL in cd/m².
    ContentLight(ContentLightLevel),
    /// `metadata_hdr_mdcv()` (§5.8.4) in the AV1 fixed-point units.
    MasteringDisplay(Av1MdcvUnits),
    /// `metadata_itut_t35()` (§5.8.2).
    ItuT35 {
        /// `itu_t_t35_country_code`.
        country_code: u8,
        /// `itu_t_t35_country_code_extension_byte`, present when the country code is 0xFF.
        country_code_extension: Option<u8>,
        /// The payload bytes, with the OBU's trailing bits removed.
        payload: &'a [u8],
    },
    /// Any other metadata type (scalability, timecode, reserved), not parsed.
    Other {
        /// `metadata_type`.
        metadata_type: u64,
    },
}

/// Removes `trailing_bits()` (§5.3.4) from the end of an OBU payload whose length the syntax
/// does not fix: trailing zero bytes, then the byte holding the `trailing_one_bit` (0x80).
/// dav1d finds the end of a T.35 payload the same way, so a payload ending in zero bytes
/// survives only with the trailing-bits byte after it.
fn strip_trailing_bits(data: &[u8]) -> Result<&[u8]> {
    let end = data.iter().rposition(|&b| b != 0).ok_or_else(|| Error::invalid("an OBU without its trailing bits"))?;
    if data[end] != 0x80 {
        return Err(Error::invalid(format!("an OBU whose trailing bits end in 0x{:02x} instead of 0x80", data[end])));
    }
    Ok(&data[..end])
}

impl<'a> Metadata<'a> {
    /// Parses a metadata OBU's payload.
    pub fn parse(payload: &'a [u8]) -> Result<Self> {
        let (kind, len) = read_leb128(payload)?;
        let body = &payload[len..];
        let be16 = |i: usize| -> Result<u16> {
            let b = body.get(i..i + 2).ok_or_else(|| Error::truncated("an HDR metadata OBU"))?;
            Ok(u16::from_be_bytes([b[0], b[1]]))
        };
        let be32 = |i: usize| -> Result<u32> {
            let b = body.get(i..i + 4).ok_or_else(|| Error::truncated("an HDR metadata OBU"))?;
            Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
        };
        Ok(match kind {
            metadata_type::HDR_CLL => {
                Metadata::ContentLight(ContentLightLevel { max_cll: be16(0)?, max_fall: be16(2)? })
            }
            metadata_type::HDR_MDCV => {
                let xy = |i: usize| -> Result<[u16; 2]> { Ok([be16(4 * i)?, be16(4 * i + 2)?]) };
                Metadata::MasteringDisplay(Av1MdcvUnits {
                    primaries: [xy(0)?, xy(1)?, xy(2)?],
                    white: xy(3)?,
                    luminance_max: be32(16)?,
                    luminance_min: be32(20)?,
                })
            }
            metadata_type::ITUT_T35 => {
                let body = strip_trailing_bits(body)?;
                let (&country_code, rest) = body.split_first().ok_or_else(|| Error::truncated("an ITU-T T.35 OBU"))?;
                let (country_code_extension, payload) = if country_code == 0xff {
                    let (&ext, rest) =
                        rest.split_first().ok_or_else(|| Error::truncated("an ITU-T T.35 country code extension"))?;
                    (Some(ext), rest)
                } else {
                    (None, rest)
                };
                Metadata::ItuT35 { country_code, country_code_extension, payload }
            }
            other => Metadata::Other { metadata_type: other },
        })
    }
}

/// Appends a complete metadata OBU (header with size field, `metadata_type`, `body`, trailing
/// bits): for tests, fuzz seeds and tools that add metadata to a stream.
pub fn write_metadata_obu(out: &mut Vec<u8>, kind: u64, body: &[u8]) {
    let mut payload = Vec::with_capacity(body.len() + 3);
    write_leb128(&mut payload, kind);
    payload.extend_from_slice(body);
    payload.push(0x80);
    out.push(obu_type::METADATA << 3 | 0x02);
    write_leb128(out, payload.len() as u64);
    out.extend_from_slice(&payload);
}

/// The body of `metadata_hdr_mdcv()` (§5.8.4) for `units`: 24 bytes, big-endian.
pub fn mdcv_body(units: &Av1MdcvUnits) -> [u8; 24] {
    let mut b = [0u8; 24];
    for (i, xy) in units.primaries.iter().chain(std::iter::once(&units.white)).enumerate() {
        b[4 * i..4 * i + 2].copy_from_slice(&xy[0].to_be_bytes());
        b[4 * i + 2..4 * i + 4].copy_from_slice(&xy[1].to_be_bytes());
    }
    b[16..20].copy_from_slice(&units.luminance_max.to_be_bytes());
    b[20..24].copy_from_slice(&units.luminance_min.to_be_bytes());
    b
}

/// What a walk over a stream's temporal units found: the first sequence header, the HDR10
/// metadata in effect at the end, and the T.35 payloads of each temporal unit.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StreamSummary {
    /// The first sequence header.
    pub sequence_header: Option<SequenceHeader>,
    /// The last HDR_CLL seen.
    pub content_light: Option<ContentLightLevel>,
    /// The last HDR_MDCV seen.
    pub mastering_display: Option<Av1MdcvUnits>,
    /// Temporal units walked.
    pub temporal_units: u64,
    /// Sequence headers whose content differs from the first (a stream that changes format).
    pub changed_sequence_headers: u64,
    /// For each temporal unit, how many T.35 OBUs it held.
    pub t35_per_temporal_unit: Vec<u32>,
    /// The payload (after the country code) of the first T.35 OBU seen.
    pub first_t35: Option<(u8, Vec<u8>)>,
    /// The distinct T.35 messages (country code, payload) in the order first seen, at most
    /// [`MAX_DISTINCT_T35`]: a stream may carry other parties' messages (HDR10+, captions)
    /// before the one a reader looks for, and repeats its own on every frame.
    pub t35_messages: Vec<(u8, Vec<u8>)>,
}

/// How many distinct T.35 messages [`StreamSummary`] keeps; later new ones are counted in
/// `t35_per_temporal_unit` but not kept.
pub const MAX_DISTINCT_T35: usize = 8;

impl StreamSummary {
    /// Adds one temporal unit's OBUs. `t35_per_temporal_unit` grows by one entry per call: the
    /// caller bounds how many it makes (an IVF reader under `Limits` does).
    pub fn add_temporal_unit(&mut self, data: &[u8]) -> Result<()> {
        let mut t35 = 0u32;
        for obu in ObuReader::new(data) {
            let obu = obu?;
            match obu.obu_type {
                obu_type::SEQUENCE_HEADER => {
                    let header = SequenceHeader::parse(obu.payload)?;
                    match &self.sequence_header {
                        None => self.sequence_header = Some(header),
                        Some(first) if *first != header => self.changed_sequence_headers += 1,
                        Some(_) => {}
                    }
                }
                obu_type::METADATA => match Metadata::parse(obu.payload)? {
                    Metadata::ContentLight(c) => self.content_light = Some(c),
                    Metadata::MasteringDisplay(m) => self.mastering_display = Some(m),
                    Metadata::ItuT35 { country_code, payload, .. } => {
                        t35 += 1;
                        if self.first_t35.is_none() {
                            self.first_t35 = Some((country_code, payload.to_vec()));
                        }
                        let seen = self.t35_messages.iter().any(|(c, p)| *c == country_code && p == payload);
                        if !seen && self.t35_messages.len() < MAX_DISTINCT_T35 {
                            self.t35_messages.push((country_code, payload.to_vec()));
                        }
                    }
                    Metadata::Other { .. } => {}
                },
                _ => {}
            }
        }
        self.t35_per_temporal_unit.push(t35);
        self.temporal_units += 1;
        Ok(())
    }

    /// The HDR10 metadata in core's units (chromaticities and cd/m²), if the stream has any.
    pub fn hdr10(&self) -> Option<Hdr10Metadata> {
        if self.content_light.is_none() && self.mastering_display.is_none() {
            return None;
        }
        Some(Hdr10Metadata {
            mastering_display: self.mastering_display.as_ref().map(MasteringDisplay::from_av1),
            content_light_level: self.content_light,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The MDCV body of an SVT-AV1 stream for a P3-D65 1000 / 0.0001 cd/m² display
    /// (VIDEO-NOTES §3.2, bytes checked with FFmpeg's trace_headers).
    const SVT_P3_MDCV: [u8; 24] = [
        0xae, 0x14, 0x51, 0xec, 0x43, 0xd7, 0xb0, 0xa4, 0x26, 0x66, 0x0f, 0x5c, 0x50, 0x0d, 0x54, 0x39, 0x00, 0x03,
        0xe8, 0x00, 0x00, 0x00, 0x00, 0x02,
    ];

    #[test]
    fn the_svt_av1_mastering_display_is_p3_d65_1000_nits() {
        let mut obu = Vec::new();
        write_metadata_obu(&mut obu, metadata_type::HDR_MDCV, &SVT_P3_MDCV);
        assert_eq!(&obu[..3], &[0x2a, 26, 2]); // header, size, metadata_type
        let o = ObuReader::new(&obu).next_obu().unwrap().unwrap();
        let Metadata::MasteringDisplay(units) = Metadata::parse(o.payload).unwrap() else { panic!("not MDCV") };
        assert_eq!(units.primaries, [[44564, 20972], [17367, 45220], [9830, 3932]]);
        assert_eq!(units.white, [20493, 21561]);
        assert_eq!((units.luminance_max, units.luminance_min), (256_000, 2));
        // Core's conversion (round half up after clamping) gives exactly these units, both ways.
        assert_eq!(MasteringDisplay::p3_d65_1000().to_av1(), units);
        let md = MasteringDisplay::from_av1(&units);
        assert_eq!(md.to_av1(), units);
        assert_eq!(md.max_luminance, 1000.0);
        // 18.14 holds 0.0001 only as 2/16384: within one LSB.
        assert!((md.min_luminance - 0.0001).abs() <= 1.0 / 16384.0);
        assert_eq!(mdcv_body(&units), SVT_P3_MDCV);
    }

    #[test]
    fn cll_and_t35_parse() {
        let mut tu = vec![0x12, 0x00];
        write_metadata_obu(&mut tu, metadata_type::HDR_CLL, &[0x03, 0xe8, 0x01, 0x90]);
        // A payload ending in zero bytes keeps them, because the trailing-bits byte follows.
        write_metadata_obu(&mut tu, metadata_type::ITUT_T35, &[0xb5, 0x00, 0x3c, 0x00, 0x00]);
        write_metadata_obu(&mut tu, metadata_type::ITUT_T35, &[0xff, 0x07, 0x01]);
        let mut s = StreamSummary::default();
        s.add_temporal_unit(&tu).unwrap();
        assert_eq!(s.content_light, Some(ContentLightLevel { max_cll: 1000, max_fall: 400 }));
        assert_eq!(s.t35_per_temporal_unit, [2]);
        assert_eq!(s.first_t35, Some((0xb5, vec![0x00, 0x3c, 0x00, 0x00])));
        // The same temporal unit again: counted, but its messages are not kept twice.
        s.add_temporal_unit(&tu).unwrap();
        assert_eq!(s.t35_per_temporal_unit, [2, 2]);
        // (0xff is followed by its extension byte, which the payload leaves out.)
        assert_eq!(s.t35_messages, [(0xb5, vec![0x00, 0x3c, 0x00, 0x00]), (0xff, vec![0x01])]);
        let obus: Vec<_> = ObuReader::new(&tu).collect::<Result<_>>().unwrap();
        assert_eq!(obus[0].obu_type, obu_type::TEMPORAL_DELIMITER);
        assert_eq!(
            Metadata::parse(obus[3].payload).unwrap(),
            Metadata::ItuT35 { country_code: 0xff, country_code_extension: Some(7), payload: &[1] }
        );
    }

    #[test]
    fn leb128_round_trips_and_rejects_overlong() {
        for v in [0u64, 1, 127, 128, 300, 16_383, 16_384, u32::MAX as u64] {
            let mut b = Vec::new();
            write_leb128(&mut b, v);
            assert_eq!(read_leb128(&b).unwrap(), (v, b.len()));
        }
        assert!(read_leb128(&[0x80; 9]).is_err());
        assert!(read_leb128(&[0xff, 0xff, 0xff, 0xff, 0x7f]).is_err()); // 2^35 - 1
        assert!(read_leb128(&[0x80]).is_err());
    }

    /// A hand-assembled Main-profile sequence header: reduced_still_picture_header = 0, no
    /// timing info, one operating point at level 8 (4.0) tier 0, 96x64, order hints on,
    /// 10-bit, colour description 9/16/9, studio range, chroma_sample_position colocated.
    pub(crate) fn hdr10_sequence_header() -> Vec<u8> {
        let mut bits: Vec<(u32, u32)> = vec![
            (0, 3), // seq_profile
            (0, 1), // still_picture
            (0, 1), // reduced_still_picture_header
            (0, 1), // timing_info_present_flag
            (0, 1), // initial_display_delay_present_flag
            (0, 5), // operating_points_cnt_minus_1
            (0, 12),
            (8, 5), // seq_level_idx[0]
            (0, 1), // seq_tier[0]
            (6, 4),
            (6, 4), // frame_width_bits_minus_1, frame_height_bits_minus_1
            (95, 7),
            (63, 7),
            (0, 1), // frame_id_numbers_present_flag
            (0b011, 3),
            (0b0000, 4),
            (1, 1), // enable_order_hint
            (0b11, 2),
            (1, 1), // seq_choose_screen_content_tools → SELECT
            (1, 1), // seq_choose_integer_mv
            (6, 3), // order_hint_bits_minus_1
            (0b011, 3),
        ];
        bits.extend([(1, 1), (0, 1), (1, 1), (9, 8), (16, 8), (9, 8), (0, 1), (2, 2), (1, 1), (0, 1)]);
        let mut out = Vec::new();
        let (mut acc, mut n) = (0u64, 0u32);
        for (v, w) in bits {
            acc = (acc << w) | v as u64;
            n += w;
            while n >= 8 {
                out.push((acc >> (n - 8)) as u8);
                n -= 8;
            }
        }
        // trailing bits
        acc = (acc << 1) | 1;
        n += 1;
        out.push((acc << (8 - n)) as u8);
        out
    }

    #[test]
    fn sequence_header_colour_config() {
        let h = SequenceHeader::parse(&hdr10_sequence_header()).unwrap();
        assert_eq!((h.profile, h.level_idx, h.tier, h.max_frame_width, h.max_frame_height), (0, 8, 0, 96, 64));
        assert_eq!(
            h.color,
            ColorConfig {
                bit_depth: 10,
                mono_chrome: false,
                color_description: Some(ColorDescription::HDR10_PQ),
                full_range: false,
                subsampling_x: true,
                subsampling_y: true,
                chroma_sample_position: chroma_sample_position::COLOCATED,
                separate_uv_delta_q: true,
            }
        );
    }

    #[test]
    fn truncation_and_garbage_are_errors() {
        let seq = hdr10_sequence_header();
        for len in 0..seq.len() - 1 {
            assert!(SequenceHeader::parse(&seq[..len]).is_err(), "cut at {len}");
        }
        let mut tu = vec![0x12, 0x00, 0x0a, seq.len() as u8];
        tu.extend_from_slice(&seq);
        write_metadata_obu(&mut tu, metadata_type::HDR_MDCV, &SVT_P3_MDCV);
        write_metadata_obu(&mut tu, metadata_type::ITUT_T35, &[0xb5, 1, 2]);
        let mut whole = StreamSummary::default();
        whole.add_temporal_unit(&tu).unwrap();
        assert_eq!(whole.sequence_header.unwrap().color.color_description, Some(ColorDescription::HDR10_PQ));
        assert!(whole.hdr10().unwrap().mastering_display.is_some());
        for len in 1..tu.len() {
            // A cut inside an OBU is an error, a cut between OBUs a shorter unit.
            let _ = StreamSummary::default().add_temporal_unit(&tu[..len]);
        }
        for i in 0..tu.len() {
            for bit in 0..8 {
                let mut bad = tu.clone();
                bad[i] ^= 1 << bit;
                let _ = StreamSummary::default().add_temporal_unit(&bad);
            }
        }
        assert!(ObuReader::new(&[0x80]).next_obu().is_err());
        assert!(ObuReader::new(&[0x0a, 0x05, 0]).next_obu().is_err());
        assert!(Metadata::parse(&[metadata_type::HDR_CLL as u8, 0x03]).is_err());
        assert!(Metadata::parse(&[metadata_type::ITUT_T35 as u8, 0xb5, 0x00]).is_err());
        assert!(Metadata::parse(&[metadata_type::ITUT_T35 as u8, 0x80]).is_err());
    }
}
