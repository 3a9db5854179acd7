//! Just enough HEVC (ITU-T H.265) to say what an HDR10 HEVC stream in MP4 declares, without
//! decoding it: the sequence parameter set up to the VUI's colour description (§7.3.2.2,
//! §E.2.1), and the SEI messages that carry HDR10 static metadata — mastering display colour
//! volume (payload type 137, §D.2.28) and content light level (144, §D.2.35).
//!
//! Written from the syntax tables of H.265 (v4, 12/2016). Every read is bounds-checked; bad
//! input gives an [`Error`], never a panic. The only allocation is the RBSP copy of one NAL
//! unit (emulation prevention removed), no larger than the NAL unit itself.

use crate::mp4::{parse_mdcv, until_error};
use hdrcodec_core::{ContentLightLevel, Error, Result, St2086Units};

/// `nal_unit_type` of a sequence parameter set.
pub const NAL_SPS: u8 = 33;
/// `nal_unit_type` of a prefix SEI message.
pub const NAL_PREFIX_SEI: u8 = 39;
/// `nal_unit_type` of a suffix SEI message.
pub const NAL_SUFFIX_SEI: u8 = 40;
/// SEI `payloadType` of the mastering display colour volume.
pub const SEI_MASTERING_DISPLAY: u32 = 137;
/// SEI `payloadType` of the content light level information.
pub const SEI_CONTENT_LIGHT_LEVEL: u32 = 144;

/// The `nal_unit_type` of a NAL unit (its first byte's bits 1..6), if it has a header.
pub fn nal_type(nal: &[u8]) -> Option<u8> {
    nal.first().map(|b| (b >> 1) & 0x3f)
}

/// The RBSP of a NAL unit: its payload after the 2-byte header, with every
/// `emulation_prevention_three_byte` (the 3 of 00 00 03) removed (§7.4.2).
pub fn rbsp(nal: &[u8]) -> Result<Vec<u8>> {
    let payload = nal.get(2..).ok_or_else(|| Error::truncated("an HEVC NAL unit header"))?;
    let mut out = Vec::with_capacity(payload.len());
    let mut zeros = 0;
    for &b in payload {
        if zeros >= 2 && b == 3 {
            zeros = 0;
            continue;
        }
        zeros = if b == 0 { zeros + 1 } else { 0 };
        out.push(b);
    }
    Ok(out)
}

/// MSB-first bits with the Exp-Golomb descriptors `ue(v)` and `se(v)` (§9.2).
struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Bits<'a> {
    fn u(&mut self, n: u32) -> Result<u32> {
        let mut v = 0u32;
        for _ in 0..n {
            let byte =
                *self.data.get(self.pos / 8).ok_or_else(|| Error::truncated("an HEVC sequence parameter set"))?;
            v = (v << 1) | u32::from((byte >> (7 - self.pos % 8)) & 1);
            self.pos += 1;
        }
        Ok(v)
    }

    fn flag(&mut self) -> Result<bool> {
        Ok(self.u(1)? == 1)
    }

    fn skip(&mut self, n: u32) -> Result<()> {
        let end = self.pos + n as usize;
        if end > self.data.len() * 8 {
            return Err(Error::truncated("an HEVC sequence parameter set"));
        }
        self.pos = end;
        Ok(())
    }

    fn ue(&mut self) -> Result<u32> {
        let mut zeros = 0;
        while !self.flag()? {
            zeros += 1;
            if zeros > 31 {
                return Err(Error::invalid("an HEVC Exp-Golomb code longer than 32 bits"));
            }
        }
        Ok(((1u64 << zeros) - 1 + u64::from(self.u(zeros)?)).min(u64::from(u32::MAX)) as u32)
    }

    fn se(&mut self) -> Result<i64> {
        let k = i64::from(self.ue()?);
        Ok(if k % 2 == 1 { (k + 1) / 2 } else { -k / 2 })
    }
}

/// What a sequence parameter set declares about the pictures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HevcSps {
    /// `general_profile_idc` (2 = Main 10).
    pub profile_idc: u8,
    /// `general_level_idc` (30 × the level).
    pub level_idc: u8,
    /// `chroma_format_idc`: 0 mono, 1 4:2:0, 2 4:2:2, 3 4:4:4.
    pub chroma_format_idc: u32,
    /// `pic_width_in_luma_samples` (before the conformance window).
    pub coded_width: u32,
    /// `pic_height_in_luma_samples`.
    pub coded_height: u32,
    /// Luma bit depth.
    pub bit_depth: u32,
    /// `video_full_range_flag` (false when the VUI does not say).
    pub full_range: bool,
    /// (colour_primaries, transfer_characteristics, matrix_coeffs), when the VUI has them.
    pub colour_description: Option<[u8; 3]>,
}

/// `profile_tier_level(1, max_sub_layers_minus1)` (§7.3.3): skipped, keeping profile and level.
fn profile_tier_level(b: &mut Bits, max_sub_layers_minus1: u32) -> Result<(u8, u8)> {
    b.skip(3)?; // general_profile_space, general_tier_flag
    let profile = b.u(5)? as u8;
    b.skip(32 + 4 + 43 + 1)?; // compatibility flags, source flags, constraint flags
    let level = b.u(8)? as u8;
    let mut present = [(false, false); 8];
    for p in present.iter_mut().take(max_sub_layers_minus1 as usize) {
        *p = (b.flag()?, b.flag()?);
    }
    if max_sub_layers_minus1 > 0 {
        b.skip(2 * (8 - max_sub_layers_minus1))?; // reserved_zero_2bits
    }
    for &(profile_present, level_present) in present.iter().take(max_sub_layers_minus1 as usize) {
        if profile_present {
            b.skip(88)?;
        }
        if level_present {
            b.skip(8)?;
        }
    }
    Ok((profile, level))
}

/// `scaling_list_data()` (§7.3.4), skipped.
fn skip_scaling_list_data(b: &mut Bits) -> Result<()> {
    for size_id in 0..4u32 {
        let step = if size_id == 3 { 3 } else { 1 };
        for _ in (0..6).step_by(step) {
            if !b.flag()? {
                b.ue()?; // scaling_list_pred_matrix_id_delta
            } else {
                let coefficients = 64.min(1 << (4 + (size_id << 1)));
                if size_id > 1 {
                    b.se()?; // scaling_list_dc_coef_minus8
                }
                for _ in 0..coefficients {
                    b.se()?; // scaling_list_delta_coef
                }
            }
        }
    }
    Ok(())
}

/// The largest `num_short_term_ref_pic_sets` (§7.4.3.2.1) and delta POCs per set.
const MAX_ST_RPS: u32 = 64;
const MAX_DELTA_POCS: u32 = 32;

/// `st_ref_pic_set(idx)` of an SPS (§7.3.7), skipped; returns NumDeltaPocs[idx].
fn skip_st_ref_pic_set(b: &mut Bits, idx: usize, num_delta_pocs: &[u32]) -> Result<u32> {
    let inter_rps_prediction = idx != 0 && b.flag()?;
    if inter_rps_prediction {
        // In an SPS delta_idx_minus1 is absent (inferred 0): the reference is the previous set.
        b.skip(1)?; // delta_rps_sign
        b.ue()?; // abs_delta_rps_minus1
        let mut count = 0;
        for _ in 0..=num_delta_pocs[idx - 1] {
            let used_by_curr_pic = b.flag()?;
            let use_delta = used_by_curr_pic || b.flag()?;
            count += u32::from(use_delta);
        }
        Ok(count)
    } else {
        let negative = b.ue()?;
        let positive = b.ue()?;
        if negative > MAX_DELTA_POCS || positive > MAX_DELTA_POCS {
            return Err(Error::invalid("an HEVC reference picture set with more than 32 pictures"));
        }
        for _ in 0..negative + positive {
            b.ue()?; // delta_poc_sX_minus1
            b.skip(1)?; // used_by_curr_pic_sX_flag
        }
        Ok(negative + positive)
    }
}

impl HevcSps {
    /// Parses a sequence parameter set NAL unit (header included) up to the VUI's colour fields.
    pub fn parse(nal: &[u8]) -> Result<Self> {
        if nal_type(nal) != Some(NAL_SPS) {
            return Err(Error::invalid("not an HEVC sequence parameter set"));
        }
        let data = rbsp(nal)?;
        let b = &mut Bits { data: &data, pos: 0 };
        b.skip(4)?; // sps_video_parameter_set_id
        let max_sub_layers_minus1 = b.u(3)?;
        if max_sub_layers_minus1 > 6 {
            return Err(Error::invalid("an HEVC SPS with more than 7 sub-layers"));
        }
        b.skip(1)?; // sps_temporal_id_nesting_flag
        let (profile_idc, level_idc) = profile_tier_level(b, max_sub_layers_minus1)?;
        b.ue()?; // sps_seq_parameter_set_id
        let chroma_format_idc = b.ue()?;
        if chroma_format_idc == 3 {
            b.skip(1)?; // separate_colour_plane_flag
        }
        let coded_width = b.ue()?;
        let coded_height = b.ue()?;
        if b.flag()? {
            for _ in 0..4 {
                b.ue()?; // conf_win_*_offset
            }
        }
        let bit_depth = b.ue()?.saturating_add(8);
        b.ue()?; // bit_depth_chroma_minus8
        let log2_max_poc_lsb = b.ue()?.saturating_add(4);
        let ordering_for_all = b.flag()?;
        let first = if ordering_for_all { 0 } else { max_sub_layers_minus1 };
        for _ in first..=max_sub_layers_minus1 {
            for _ in 0..3 {
                b.ue()?; // max_dec_pic_buffering, max_num_reorder_pics, max_latency_increase
            }
        }
        for _ in 0..6 {
            b.ue()?; // coding and transform block sizes, transform hierarchy depths
        }
        if b.flag()? && b.flag()? {
            skip_scaling_list_data(b)?;
        }
        b.skip(2)?; // amp_enabled_flag, sample_adaptive_offset_enabled_flag
        if b.flag()? {
            b.skip(8)?; // pcm sample bit depths
            b.ue()?;
            b.ue()?;
            b.skip(1)?;
        }
        let num_st_rps = b.ue()?;
        if num_st_rps > MAX_ST_RPS {
            return Err(Error::invalid(format!("an HEVC SPS with {num_st_rps} short-term reference picture sets")));
        }
        let mut num_delta_pocs = [0u32; MAX_ST_RPS as usize];
        for idx in 0..num_st_rps as usize {
            num_delta_pocs[idx] = skip_st_ref_pic_set(b, idx, &num_delta_pocs)?;
        }
        if b.flag()? {
            let long_term = b.ue()?;
            if long_term > 32 {
                return Err(Error::invalid("an HEVC SPS with more than 32 long-term reference pictures"));
            }
            for _ in 0..long_term {
                b.skip(log2_max_poc_lsb.min(16) + 1)?; // lt_ref_pic_poc_lsb_sps, used_by_curr_pic_lt_sps_flag
            }
        }
        b.skip(2)?; // sps_temporal_mvp_enabled_flag, strong_intra_smoothing_enabled_flag
        let mut sps = HevcSps {
            profile_idc,
            level_idc,
            chroma_format_idc,
            coded_width,
            coded_height,
            bit_depth,
            full_range: false,
            colour_description: None,
        };
        if !b.flag()? {
            return Ok(sps); // no VUI
        }
        if b.flag()? && b.u(8)? == 255 {
            b.skip(32)?; // sar_width, sar_height
        }
        if b.flag()? {
            b.skip(1)?; // overscan_appropriate_flag
        }
        if b.flag()? {
            b.skip(3)?; // video_format
            sps.full_range = b.flag()?;
            if b.flag()? {
                sps.colour_description = Some([b.u(8)? as u8, b.u(8)? as u8, b.u(8)? as u8]);
            }
        }
        Ok(sps)
    }
}

/// HDR10 SEI messages found in NAL units.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HevcHdrSei {
    /// The first mastering display colour volume message, as stored (G, B, R in its units).
    pub mastering_display: Option<St2086Units>,
    /// The first content light level message.
    pub content_light: Option<ContentLightLevel>,
}

impl HevcHdrSei {
    /// Reads the SEI messages of one SEI NAL unit (header included); other NAL types are ignored.
    pub fn add_nal(&mut self, nal: &[u8]) -> Result<()> {
        if !matches!(nal_type(nal), Some(NAL_PREFIX_SEI | NAL_SUFFIX_SEI)) {
            return Ok(());
        }
        let data = rbsp(nal)?;
        let mut rest: &[u8] = &data;
        // sei_message() while more_rbsp_data(): until the trailing bits (0x80, then zeros only).
        // A 0x80 followed by more data is a payloadType of 128.
        while let Some((&first, tail)) = rest.split_first() {
            if first == 0x80 && tail.iter().all(|&b| b == 0) {
                break;
            }
            let mut read_value = || -> Result<u32> {
                let mut v = 0u32;
                loop {
                    let (&b, tail) =
                        rest.split_first().ok_or_else(|| Error::truncated("an HEVC SEI message header"))?;
                    rest = tail;
                    v = v.saturating_add(u32::from(b));
                    if b != 0xff {
                        return Ok(v);
                    }
                }
            };
            let kind = read_value()?;
            let size = read_value()? as usize;
            let payload =
                rest.get(..size).ok_or_else(|| Error::truncated(format!("an HEVC SEI message of type {kind}")))?;
            rest = &rest[size..];
            match kind {
                SEI_MASTERING_DISPLAY if self.mastering_display.is_none() => {
                    self.mastering_display = Some(parse_mdcv(payload)?);
                }
                SEI_CONTENT_LIGHT_LEVEL if self.content_light.is_none() => {
                    let b = payload.get(..4).ok_or_else(|| Error::truncated("an HEVC content light level SEI"))?;
                    self.content_light = Some(ContentLightLevel {
                        max_cll: u16::from_be_bytes([b[0], b[1]]),
                        max_fall: u16::from_be_bytes([b[2], b[3]]),
                    });
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// The NAL units of an `hvcC` record's parameter-set arrays, and its NAL length size.
pub fn hvcc_nal_units(hvcc: &[u8]) -> Result<(usize, Vec<&[u8]>)> {
    let header = hvcc.get(..23).ok_or_else(|| Error::truncated("the MP4 'hvcC' record"))?;
    let length_size = usize::from(header[21] & 3) + 1;
    let arrays = header[22];
    let mut rest = &hvcc[23..];
    let mut nals = Vec::new();
    for _ in 0..arrays {
        let count = rest.get(1..3).ok_or_else(|| Error::truncated("the MP4 'hvcC' record"))?;
        let count = u16::from_be_bytes([count[0], count[1]]);
        rest = &rest[3..];
        for _ in 0..count {
            let len = rest.get(..2).ok_or_else(|| Error::truncated("the MP4 'hvcC' record"))?;
            let len = usize::from(u16::from_be_bytes([len[0], len[1]]));
            let nal = rest.get(2..2 + len).ok_or_else(|| Error::truncated("a NAL unit of the MP4 'hvcC' record"))?;
            nals.push(nal);
            rest = &rest[2 + len..];
        }
    }
    Ok((length_size, nals))
}

/// The NAL units of one length-prefixed MP4 sample, up to the end or to the first error.
pub fn sample_nal_units(sample: &[u8], length_size: usize) -> impl Iterator<Item = Result<&[u8]>> {
    let mut rest = sample;
    until_error(move || {
        if rest.is_empty() {
            return Ok(None);
        }
        let len = rest.get(..length_size).ok_or_else(|| Error::truncated("an HEVC NAL unit length"))?;
        let len = len.iter().fold(0usize, |v, &b| (v << 8) | usize::from(b));
        let nal = rest
            .get(length_size..length_size.saturating_add(len))
            .ok_or_else(|| Error::truncated("an HEVC NAL unit"))?;
        rest = &rest[length_size + len..];
        Ok(Some(nal))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SPS of the corpus clip `hdr10-video-with-sdr-container.mp4` (its `hvcC`), for which
    /// ffprobe reports Main 10, level 150, 1920x1080 (coded 1088), bt2020 / smpte2084 /
    /// bt2020nc, tv range.
    const CORPUS_SPS: &str = "420101022000000300b00000030000030096a003c0801107cad96bb9324ba94848804817685094";

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
    }

    #[test]
    fn the_corpus_sps_says_what_ffprobe_says() {
        let sps = HevcSps::parse(&hex(CORPUS_SPS)).unwrap();
        assert_eq!(
            sps,
            HevcSps {
                profile_idc: 2,
                level_idc: 150,
                chroma_format_idc: 1,
                coded_width: 1920,
                coded_height: 1088,
                bit_depth: 10,
                full_range: false,
                colour_description: Some([9, 16, 9]),
            }
        );
        let nal = hex(CORPUS_SPS);
        // The colour description ends in byte 35; what follows (chroma siting, timing) is not read.
        for len in 0..nal.len() {
            match HevcSps::parse(&nal[..len]) {
                Ok(cut) => assert!(len >= 35 && cut == sps, "cut at {len}"),
                Err(_) => assert!(len < 35, "cut at {len}"),
            }
        }
        for i in 2..nal.len() {
            for bit in 0..8 {
                let mut bad = nal.clone();
                bad[i] ^= 1 << bit;
                let _ = HevcSps::parse(&bad);
            }
        }
    }

    #[test]
    fn sei_messages_with_emulation_prevention() {
        // Prefix SEI: mastering display (137) with BT.2020 G, B, R, 1000 / 0.0001 cd/m², whose
        // last bytes 00 00 00 01 are escaped as 00 00 03 00 01; content light level (144) 1000/400.
        let mut nal = vec![NAL_PREFIX_SEI << 1, 0x01, 137, 24];
        nal.extend_from_slice(&[0x21, 0x34, 0x9b, 0xaa, 0x19, 0x96, 0x08, 0xfc, 0x8a, 0x48, 0x39, 0x08]);
        nal.extend_from_slice(&[0x3d, 0x13, 0x40, 0x42, 0x00, 0x98, 0x96, 0x80, 0x00, 0x00, 0x03, 0x00, 0x01]);
        nal.extend_from_slice(&[144, 4, 0x03, 0xe8, 0x01, 0x90, 0x80]);
        let mut sei = HevcHdrSei::default();
        sei.add_nal(&nal).unwrap();
        let md = sei.mastering_display.unwrap();
        assert_eq!(md.primaries, [[35400, 14600], [8500, 39850], [6550, 2300]]);
        assert_eq!((md.max_luminance, md.min_luminance), (10_000_000, 1));
        assert_eq!(sei.content_light, Some(ContentLightLevel { max_cll: 1000, max_fall: 400 }));
        for len in 0..nal.len() {
            let _ = HevcHdrSei::default().add_nal(&nal[..len]);
        }
        assert!(HevcHdrSei::default().add_nal(&nal[..20]).is_err());
        // Other NAL types are not SEI.
        assert!(HevcHdrSei::default().add_nal(&hex(CORPUS_SPS)).is_ok());
    }

    #[test]
    fn length_prefixed_nal_units() {
        let sample = [0, 0, 0, 2, 0x4e, 0x01, 0, 0, 0, 1, 0x02];
        let nals: Vec<_> = sample_nal_units(&sample, 4).collect::<Result<_>>().unwrap();
        assert_eq!(nals, [&[0x4e, 0x01][..], &[0x02][..]]);
        assert!(sample_nal_units(&sample[..9], 4).any(|n| n.is_err()));
        assert!(hvcc_nal_units(&[1; 22]).is_err());
    }
}
