//! L_p u'v' (Mantiuk et al. 2004) in AV1 planes, and the ITU-T T.35 message that says so.
//!
//! The planes hold the codes of [`crate::luv`]: the ψ luma code (0..2047 at 11 bits, 0..1023 at
//! 10) and u'v' codes round(410·u'), round(410·v') (0..255), either in a 12-bit stream (AV1
//! profile 2, Professional) or in a 10-bit one (4:2:0: profile 0, Main, which hardware decoders
//! have; [`LpuvStreamInfo::main10`]). How the codes sit in the planes is the
//! [`LpuvPlaneMapping`]: each plane's codes are stretched linearly, P = round(c·P_max/c_max),
//! and the decoder takes c = round(P·c_max/P_max), which gives every code back exactly; version 1
//! streams (before November 2026) hold the codes as they are in 12-bit planes and still decode.
//! They are not a CICP colour space, so the sequence header carries no colour description; the
//! stream is identified by a T.35 metadata OBU on every frame instead (see [`LpuvStreamInfo`]).
//! For 4:2:0 the u'v' codes of each 2x2 block are averaged (chromaticity codes, not light:
//! the codes are what the decoder rebuilds colour from) and the decoder replicates them back.

use crate::curves::LumaCurve;
use crate::hdr10::{Subsampling, YuvFrame};
use crate::luv::{decode_image, encode_image, LpuvPlanes, UV_SCALE};
use crate::mantiuk::{Psi04, PsiIntegration, PsiOptions};
use crate::obu::StreamSummary;
use hdrcodec_core::{ColorInfo, ColorPrimaries, Error, HdrImage, Result};

/// Bit depth of the 12-bit (Professional profile) AV1 planes that carry L_p u'v', and of every
/// stream described by a version 1 or 2 message.
pub const LPUV_BIT_DEPTH: u32 = 12;
/// Bit depth of the 10-bit (Main profile at 4:2:0) AV1 planes that carry L_p u'v' (version 3
/// of the message).
pub const LPUV_MAIN_BIT_DEPTH: u32 = 10;

/// `itu_t_t35_country_code` of our message: 0xFF, "the country code is in the next byte".
pub const T35_COUNTRY_CODE: u8 = 0xFF;
/// `itu_t_t35_country_code_extension_byte`: 0xFF, which names no country. We have no T.35
/// terminal provider code, so we claim no country's provider space (0xB5 would sit among the
/// US providers' codes); the ASCII magic is what identifies the message.
pub const T35_COUNTRY_CODE_EXTENSION: u8 = 0xFF;
/// The first bytes of the payload (after the country code and its extension).
pub const T35_MAGIC: &[u8; 13] = b"hdrcodec-lpuv";
/// Payload format version written for 10-bit planes (the newest); version 2 is written for
/// mapped 12-bit planes and version 1 (no mapping: codes as they are in 12-bit planes) for
/// [`LpuvPlaneMapping::codes`], so that 12-bit streams stay readable by older decoders.
pub const T35_VERSION: u8 = 3;
/// Payload length of version 1: magic, version, curve, bits, primaries, u'v' scale (u16),
/// L_min, L_max (f64).
pub const T35_PAYLOAD_LEN_V1: usize = 13 + 4 + 2 + 8 + 8;
/// Payload length of version 2: version 1's fields and the plane mapping (two u16).
pub const T35_PAYLOAD_LEN_V2: usize = T35_PAYLOAD_LEN_V1 + 4;
/// Payload length of version 3: version 2's fields and the planes' bit depth (one byte).
pub const T35_PAYLOAD_LEN: usize = T35_PAYLOAD_LEN_V2 + 1;
/// The largest sample of the 12-bit planes.
const PLANE_MAX: u32 = (1 << LPUV_BIT_DEPTH) - 1;
/// The largest u'v' code (8 bits).
const UV_CODE_MAX: u32 = 255;

/// How L_p u'v' codes are placed in the planes: the planes' bit depth (10 or 12) and the plane
/// sample of the top code of each plane, luma and u'v' (versions 2 and 3 of the payload).
///
/// rav1e's quantizer steps are steps of plane samples; codes that use a sixteenth of the range
/// (u'v', 0..255) or half of it (11-bit ψ, 0..2047) are quantized 16 and 2 times more coarsely
/// than codes that span it. A code c of a plane whose top code is c_max and whose top sample
/// is P_max sits at P = round(c·P_max/c_max) (half up) and is read back as
/// c = round(P·c_max/P_max), clamped to c_max: exact for every code since P_max ≥ c_max.
/// The mapping changes only where codes sit, not the codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LpuvPlaneMapping {
    /// Bits per plane sample: 12 (Professional profile) or 10 (Main profile at 4:2:0).
    pub plane_bits: u8,
    /// The Y sample of the top luma code (2^bits − 1 ..= 2^`plane_bits` − 1).
    pub luma_top: u16,
    /// The U and V sample of u'v' code 255 (255 ..= 2^`plane_bits` − 1).
    pub uv_top: u16,
}

impl Default for LpuvPlaneMapping {
    /// Luma stretched onto the whole 12-bit range, u'v' codes ×4 (P_max 1020); chosen by the
    /// measurements in the crate README ("L_p u'v' (Mantiuk 2004) in AV1").
    fn default() -> Self {
        LpuvPlaneMapping {
            plane_bits: LPUV_BIT_DEPTH as u8,
            luma_top: PLANE_MAX as u16,
            uv_top: 4 * UV_CODE_MAX as u16,
        }
    }
}

impl LpuvPlaneMapping {
    /// The codes as they are (version 1 streams): top samples 2^`luma_bits` − 1 and 255.
    pub fn codes(luma_bits: u8) -> Self {
        LpuvPlaneMapping {
            plane_bits: LPUV_BIT_DEPTH as u8,
            luma_top: ((1u32 << luma_bits.min(12)) - 1) as u16,
            uv_top: UV_CODE_MAX as u16,
        }
    }

    /// 10-bit planes (AV1 Main profile at 4:2:0) for 10-bit luma codes, both planes' codes as
    /// they are: luma over the whole range (top 1023), u'v' over a quarter of it (top 255).
    /// That is the 12-bit default's luma:chroma ratio (rav1e's quantizer steps scale with the
    /// bit depth, so only the share of the range matters); u'v' over the whole 10-bit range
    /// (top 1020) measured 0.4–2.6 dB PU21-PSNR worse at equal bytes (crate README).
    pub fn main10() -> Self {
        LpuvPlaneMapping { plane_bits: LPUV_MAIN_BIT_DEPTH as u8, luma_top: 1023, uv_top: UV_CODE_MAX as u16 }
    }

    /// The largest sample of the planes.
    pub fn plane_max(&self) -> u32 {
        (1u32 << self.plane_bits.min(16)) - 1
    }

    /// Whether this is [`codes`](Self::codes) for `luma_bits` (written as a version 1 payload).
    pub fn is_codes(&self, luma_bits: u8) -> bool {
        *self == LpuvPlaneMapping::codes(luma_bits)
    }

    /// The plane sample of `code` (0..=`code_max`) when the top code sits at `top`.
    pub fn to_plane(code: u16, code_max: u32, top: u16) -> u16 {
        let top = u32::from(top);
        ((2 * u32::from(code).min(code_max) * top + code_max) / (2 * code_max.max(1))).min(PLANE_MAX) as u16
    }

    /// The code of plane sample `sample` (any 12-bit value: a lossy encoder may move it), when
    /// the top code `code_max` sits at `top`; clamped to `code_max`.
    pub fn to_code(sample: u16, code_max: u32, top: u16) -> u16 {
        let top = u32::from(top).max(1);
        ((2 * u32::from(sample) * code_max + top) / (2 * top)).min(code_max) as u16
    }
}

/// The luma curve of an L_p u'v' stream (the payload's curve id).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LpuvCurve {
    /// id 1: ψ of 2004, the continuous ODE ([`PsiIntegration::Continuous`]).
    Psi04Continuous,
    /// id 2: ψ by LumaHDRv's recurrence ([`PsiIntegration::LumaHdrvRecurrence`]).
    Psi04Recurrence,
}

impl LpuvCurve {
    /// The id written in the payload.
    pub fn id(self) -> u8 {
        match self {
            LpuvCurve::Psi04Continuous => 1,
            LpuvCurve::Psi04Recurrence => 2,
        }
    }

    fn from_id(id: u8) -> Result<Self> {
        match id {
            1 => Ok(LpuvCurve::Psi04Continuous),
            2 => Ok(LpuvCurve::Psi04Recurrence),
            other => Err(Error::unsupported(format!("L_p u'v' stream with luma curve id {other}"))),
        }
    }
}

/// What an L_p u'v' stream's T.35 message says: how to turn its codes back into light.
///
/// Payload bytes (after country code 0xFF and extension 0xFF), big-endian, 40 bytes:
/// `"hdrcodec-lpuv"` (13 ASCII bytes), version (2), curve id (1 = ψ 2004 continuous,
/// 2 = ψ by LumaHDRv's recurrence), luma bits (11), H.273 colour primaries of the decoded RGB
/// (1 BT.709, 9 BT.2020, 12 P3-D65), u'v' scale as u16 (410), L_min and L_max in cd/m² as f64,
/// the plane mapping ([`LpuvPlaneMapping`]): the Y sample of the top luma code and the U/V
/// sample of u'v' code 255, two u16; the planes' bit depth (10 or 12), one byte. Version 2 is
/// the same without the bit depth (39 bytes, 12-bit planes), version 1 also without the mapping
/// (35 bytes, codes as they are in 12-bit planes); both are still read, and written for 12-bit
/// planes (version 1 for [`LpuvPlaneMapping::codes`]), so that 12-bit streams stay readable by
/// decoders older than version 3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LpuvStreamInfo {
    /// The luma curve.
    pub curve: LpuvCurve,
    /// Bits of the luma codes.
    pub bits: u8,
    /// H.273 primaries the decoder returns RGB in (the source frames' own, where listed).
    pub primaries_h273: u8,
    /// Luminance of luma code 0, cd/m².
    pub min_nits: f64,
    /// Luminance of the top luma code, cd/m².
    pub max_nits: f64,
    /// Where the codes sit in the planes.
    pub mapping: LpuvPlaneMapping,
}

impl Default for LpuvStreamInfo {
    /// The paper's curve: ψ at 11 bits over 10⁻⁴ … 10⁸ cd/m², decoded to BT.709.
    fn default() -> Self {
        let psi = PsiOptions::default();
        LpuvStreamInfo {
            curve: LpuvCurve::Psi04Continuous,
            bits: psi.bits as u8,
            primaries_h273: 1,
            min_nits: psi.min_nits,
            max_nits: psi.max_nits,
            mapping: LpuvPlaneMapping::default(),
        }
    }
}

impl LpuvStreamInfo {
    /// The description from the first of a stream's T.35 messages that is ours (others, such
    /// as HDR10+ or captions, may come before it); `None` when none is.
    pub fn from_summary(summary: &StreamSummary) -> Result<Option<Self>> {
        for (country_code, payload) in &summary.t35_messages {
            if let Some(info) = LpuvStreamInfo::from_t35(*country_code, payload)? {
                return Ok(Some(info));
            }
        }
        Ok(None)
    }

    /// The default curve, decoding to `primaries` when H.273 names them (BT.709, BT.2020,
    /// P3-D65), else to BT.2020 (L_p u'v' itself holds every visible colour).
    pub fn for_primaries(primaries: ColorPrimaries) -> Self {
        let primaries_h273 = match primaries.or_bt709() {
            ColorPrimaries::Bt709 => 1,
            ColorPrimaries::DisplayP3 => 12,
            _ => 9,
        };
        LpuvStreamInfo { primaries_h273, ..LpuvStreamInfo::default() }
    }

    /// The primaries of the decoded frames.
    pub fn primaries(&self) -> Result<ColorPrimaries> {
        match self.primaries_h273 {
            1 => Ok(ColorPrimaries::Bt709),
            9 => Ok(ColorPrimaries::Bt2020),
            12 => Ok(ColorPrimaries::DisplayP3),
            other => Err(Error::unsupported(format!("L_p u'v' stream with H.273 primaries {other}"))),
        }
    }

    /// The default curve at 10 bits (ψ over 10⁻⁴ … 10⁸ cd/m², steps of 0.30 tvi: under the
    /// threshold, see the crate README's bits table) in 10-bit planes
    /// ([`LpuvPlaneMapping::main10`]): with 4:2:0 an AV1 Main-profile stream.
    pub fn main10(primaries: ColorPrimaries) -> Self {
        LpuvStreamInfo {
            bits: LPUV_MAIN_BIT_DEPTH as u8,
            mapping: LpuvPlaneMapping::main10(),
            ..LpuvStreamInfo::for_primaries(primaries)
        }
    }

    /// The luma curve as a table.
    pub fn psi(&self) -> Result<Psi04> {
        let integration = match self.curve {
            LpuvCurve::Psi04Continuous => PsiIntegration::Continuous,
            LpuvCurve::Psi04Recurrence => PsiIntegration::LumaHdrvRecurrence,
        };
        Psi04::new(&PsiOptions {
            bits: self.bits.into(),
            min_nits: self.min_nits,
            max_nits: self.max_nits,
            integration,
        })
    }

    /// The T.35 payload (after the country code and extension byte): version 3 (40 bytes) for
    /// planes other than 12-bit, else version 1 (35 bytes) for [`LpuvPlaneMapping::codes`] and
    /// version 2 (39 bytes) for other mappings.
    pub fn to_t35_payload(&self) -> Vec<u8> {
        let version = if u32::from(self.mapping.plane_bits) != LPUV_BIT_DEPTH {
            T35_VERSION
        } else if self.mapping.is_codes(self.bits) {
            1
        } else {
            2
        };
        let mut out = Vec::with_capacity(T35_PAYLOAD_LEN);
        out.extend_from_slice(T35_MAGIC);
        out.extend_from_slice(&[version, self.curve.id(), self.bits, self.primaries_h273]);
        out.extend_from_slice(&(UV_SCALE as u16).to_be_bytes());
        out.extend_from_slice(&self.min_nits.to_be_bytes());
        out.extend_from_slice(&self.max_nits.to_be_bytes());
        if version >= 2 {
            out.extend_from_slice(&self.mapping.luma_top.to_be_bytes());
            out.extend_from_slice(&self.mapping.uv_top.to_be_bytes());
        }
        if version >= 3 {
            out.push(self.mapping.plane_bits);
        }
        out
    }

    /// Parses a T.35 message. `Ok(None)`: not ours (another country code or magic). Errors:
    /// ours but truncated, of another version, or with values we cannot decode.
    pub fn from_t35(country_code: u8, payload: &[u8]) -> Result<Option<Self>> {
        if country_code != T35_COUNTRY_CODE || !payload.starts_with(T35_MAGIC) {
            return Ok(None);
        }
        let truncated = || Error::truncated("the hdrcodec-lpuv T.35 message");
        let version = *payload.get(13).ok_or_else(truncated)?;
        let (len, mapping) = match version {
            1 => (T35_PAYLOAD_LEN_V1, None),
            2 | 3 => {
                let len = if version == 2 { T35_PAYLOAD_LEN_V2 } else { T35_PAYLOAD_LEN };
                let b = payload.get(..len).ok_or_else(truncated)?;
                let mapping = LpuvPlaneMapping {
                    plane_bits: if version == 2 { LPUV_BIT_DEPTH as u8 } else { b[39] },
                    luma_top: u16::from_be_bytes([b[35], b[36]]),
                    uv_top: u16::from_be_bytes([b[37], b[38]]),
                };
                (len, Some(mapping))
            }
            other => return Err(Error::unsupported(format!("hdrcodec-lpuv T.35 message version {other}"))),
        };
        let b = payload.get(..len).ok_or_else(truncated)?;
        let f64_at = |i: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[i..i + 8]);
            f64::from_be_bytes(a)
        };
        let info = LpuvStreamInfo {
            curve: LpuvCurve::from_id(b[14])?,
            bits: b[15],
            primaries_h273: b[16],
            min_nits: f64_at(19),
            max_nits: f64_at(27),
            mapping: mapping.unwrap_or(LpuvPlaneMapping::codes(b[15])),
        };
        let scale = u16::from_be_bytes([b[17], b[18]]);
        if f64::from(scale) != UV_SCALE {
            return Err(Error::unsupported(format!("L_p u'v' stream with u'v' scale {scale}")));
        }
        info.check()?;
        Ok(Some(info))
    }

    /// Checks that a decoder can invert what this describes: plane depth 10 or 12, luma bits
    /// from 8 to the plane depth, a luminance range, top samples from each plane's top code to
    /// the planes' largest sample, primaries H.273 names (what [`from_t35`](Self::from_t35)
    /// checks, and the encoder before its first frame).
    pub fn check(&self) -> Result<()> {
        let info = self;
        let plane_bits = info.mapping.plane_bits;
        if u32::from(plane_bits) != LPUV_BIT_DEPTH && u32::from(plane_bits) != LPUV_MAIN_BIT_DEPTH {
            return Err(Error::unsupported(format!("L_p u'v' in {plane_bits}-bit planes (10 or 12 are read)")));
        }
        if info.bits > plane_bits || info.bits < 8 {
            return Err(Error::unsupported(format!("L_p u'v' luma of {} bits in {plane_bits}-bit planes", info.bits)));
        }
        if !(info.min_nits > 0.0 && info.max_nits > info.min_nits && info.max_nits.is_finite()) {
            return Err(Error::invalid(format!("L_p u'v' range {} … {} cd/m²", info.min_nits, info.max_nits)));
        }
        let luma_max = (1u32 << info.bits) - 1;
        let (luma_top, uv_top) = (u32::from(info.mapping.luma_top), u32::from(info.mapping.uv_top));
        let plane_max = info.mapping.plane_max();
        if !(luma_max..=plane_max).contains(&luma_top) || !(UV_CODE_MAX..=plane_max).contains(&uv_top) {
            return Err(Error::invalid(format!(
                "L_p u'v' planes with top samples {luma_top} (luma, {} bits) and {uv_top} (u'v'): each must be from its top code to {plane_max}",
                info.bits
            )));
        }
        info.primaries()?;
        Ok(())
    }
}

/// A frame (any primaries, `nits_per_unit`) → AV1 planes (10- or 12-bit) of L_p u'v' codes
/// placed by `mapping`.
pub fn frame_to_lpuv_yuv(
    psi: &Psi04,
    frame: &HdrImage,
    subsampling: Subsampling,
    mapping: LpuvPlaneMapping,
) -> Result<YuvFrame> {
    let planes = encode_image(psi, frame)?;
    let (w, h) = (planes.width as usize, planes.height as usize);
    let (cw, ch) = YuvFrame::chroma_size(w, h, subsampling);
    let luma_max = (1u32 << psi.bits()) - 1;
    let uv = |code: u16| LpuvPlaneMapping::to_plane(code, UV_CODE_MAX, mapping.uv_top);
    let chroma = |codes: &[u8]| -> Vec<u16> {
        match subsampling {
            Subsampling::Yuv444 => codes.iter().map(|&c| uv(u16::from(c))).collect(),
            Subsampling::Yuv420 => {
                let mut out = Vec::with_capacity(cw * ch);
                for cy in 0..ch {
                    for cx in 0..cw {
                        let (mut sum, mut n) = (0u32, 0u32);
                        for y in 2 * cy..(2 * cy + 2).min(h) {
                            for x in 2 * cx..(2 * cx + 2).min(w) {
                                sum += u32::from(codes[y * w + x]);
                                n += 1;
                            }
                        }
                        // Rounded mean; n ≥ 1 since every chroma sample covers a luma sample.
                        out.push(uv(((2 * sum + n) / (2 * n)) as u16));
                    }
                }
                out
            }
        }
    };
    Ok(YuvFrame {
        width: w,
        height: h,
        subsampling,
        y: planes.luma.iter().map(|&c| LpuvPlaneMapping::to_plane(c, luma_max, mapping.luma_top)).collect(),
        cb: chroma(&planes.u),
        cr: chroma(&planes.v),
    })
}

/// Planes of L_p u'v' codes placed by `mapping` → a frame in `color` (primaries,
/// `nits_per_unit`). Codes beyond the curve's top or 255 (a lossy encoder may overshoot) are
/// clamped to them.
pub fn lpuv_yuv_to_frame(psi: &Psi04, yuv: &YuvFrame, color: ColorInfo, mapping: LpuvPlaneMapping) -> Result<HdrImage> {
    let (w, h) = (yuv.width, yuv.height);
    let (cw, ch) = YuvFrame::chroma_size(w, h, yuv.subsampling);
    if yuv.y.len() != w * h || yuv.cb.len() != cw * ch || yuv.cr.len() != cw * ch {
        return Err(Error::invalid("L_p u'v' planes whose sizes do not match the frame"));
    }
    let luma_max = (1u32 << psi.bits()) - 1;
    let (sx, sy) = match yuv.subsampling {
        Subsampling::Yuv420 => (1, 1),
        Subsampling::Yuv444 => (0, 0),
    };
    let chroma = |plane: &[u16]| -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                LpuvPlaneMapping::to_code(plane[((i / w) >> sy) * cw + ((i % w) >> sx)], UV_CODE_MAX, mapping.uv_top)
                    as u8
            })
            .collect()
    };
    let planes = LpuvPlanes {
        width: w as u32,
        height: h as u32,
        bits: psi.bits(),
        luma: yuv.y.iter().map(|&p| LpuvPlaneMapping::to_code(p, luma_max, mapping.luma_top)).collect(),
        u: chroma(&yuv.cb),
        v: chroma(&yuv.cr),
    };
    decode_image(psi, &planes, color)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_description_is_found_behind_other_parties_t35_messages() {
        let ours = LpuvStreamInfo::for_primaries(ColorPrimaries::DisplayP3);
        // An HDR10+-style message (United States, another provider) first, then ours.
        let mut summary = StreamSummary::default();
        summary.t35_messages.push((0xb5, vec![0x00, 0x3c, 0x00, 0x01, 0x04, 0x01]));
        assert_eq!(LpuvStreamInfo::from_summary(&summary).unwrap(), None);
        summary.t35_messages.push((T35_COUNTRY_CODE, ours.to_t35_payload()));
        assert_eq!(LpuvStreamInfo::from_summary(&summary).unwrap(), Some(ours));
    }

    #[test]
    fn t35_payload_round_trips_byte_by_byte() {
        let info = LpuvStreamInfo::for_primaries(ColorPrimaries::Bt2020);
        assert_eq!(info.mapping, LpuvPlaneMapping { plane_bits: 12, luma_top: 4095, uv_top: 1020 });
        let payload = info.to_t35_payload();
        assert_eq!(payload.len(), T35_PAYLOAD_LEN_V2);
        assert_eq!(&payload[..13], b"hdrcodec-lpuv");
        assert_eq!(&payload[13..19], &[2, 1, 11, 9, 0x01, 0x9a]);
        assert_eq!(&payload[19..27], &1e-4f64.to_be_bytes());
        assert_eq!(&payload[27..35], &1e8f64.to_be_bytes());
        assert_eq!(&payload[35..], &[0x0f, 0xff, 0x03, 0xfc]);
        assert_eq!(LpuvStreamInfo::from_t35(0xff, &payload).unwrap(), Some(info));
        // Not ours: other country code or magic.
        assert_eq!(LpuvStreamInfo::from_t35(0xb5, &payload).unwrap(), None);
        assert_eq!(LpuvStreamInfo::from_t35(0xff, b"something else").unwrap(), None);
        // Ours but broken: truncated (also inside the mapping), future version, unknown curve,
        // bits, primaries, top samples below the top code or above 4095, bad range.
        for len in [13, 30, 35, 38] {
            assert!(LpuvStreamInfo::from_t35(0xff, &payload[..len]).is_err(), "{len} bytes");
        }
        for (i, v) in [(13, 3u8), (14, 9), (15, 14), (16, 5), (35, 0x10), (35, 0x06), (37, 0x00), (37, 0x10)] {
            let mut bad = payload.clone();
            bad[i] = v;
            assert!(LpuvStreamInfo::from_t35(0xff, &bad).is_err(), "byte {i} = {v}");
        }
        let mut bad = payload.clone();
        bad[19..27].copy_from_slice(&2e8f64.to_be_bytes());
        assert!(LpuvStreamInfo::from_t35(0xff, &bad).is_err());
    }

    #[test]
    fn main_profile_payloads_are_version_3_with_the_plane_depth() {
        let info = LpuvStreamInfo::main10(ColorPrimaries::Bt709);
        assert_eq!((info.bits, info.mapping), (10, LpuvPlaneMapping { plane_bits: 10, luma_top: 1023, uv_top: 255 }));
        let payload = info.to_t35_payload();
        assert_eq!(payload.len(), T35_PAYLOAD_LEN);
        assert_eq!(&payload[13..19], &[3, 1, 10, 1, 0x01, 0x9a]);
        assert_eq!(&payload[35..], &[0x03, 0xff, 0x00, 0xff, 10]);
        assert_eq!(LpuvStreamInfo::from_t35(0xff, &payload).unwrap(), Some(info));
        assert!(LpuvStreamInfo::from_t35(0xff, &payload[..39]).is_err());
        // Plane depth other than 10 or 12; luma bits above it; tops above 1023 in 10-bit planes.
        for (i, v) in [(39, 8u8), (39, 11), (39, 16), (15, 11), (35, 0x04), (37, 0x04), (38, 0xfe)] {
            let mut bad = payload.clone();
            bad[i] = v;
            assert!(LpuvStreamInfo::from_t35(0xff, &bad).is_err(), "byte {i} = {v}");
        }
        // 11-bit codes fit 12-bit planes only.
        let eleven = LpuvStreamInfo { mapping: LpuvPlaneMapping::main10(), ..LpuvStreamInfo::default() };
        assert!(eleven.check().is_err());
        // 12-bit planes described by version 3 read as version 2 does.
        let mut twelve = LpuvStreamInfo::default().to_t35_payload();
        twelve[13] = 3;
        twelve.push(12);
        assert_eq!(LpuvStreamInfo::from_t35(0xff, &twelve).unwrap(), Some(LpuvStreamInfo::default()));
    }

    #[test]
    fn version_1_payloads_still_read_as_codes_in_the_planes() {
        // The bytes a version 1 writer produced (before the mapping existed).
        let mut v1 = b"hdrcodec-lpuv".to_vec();
        v1.extend_from_slice(&[1, 1, 11, 9, 0x01, 0x9a]);
        v1.extend_from_slice(&1e-4f64.to_be_bytes());
        v1.extend_from_slice(&1e8f64.to_be_bytes());
        let info = LpuvStreamInfo::from_t35(0xff, &v1).unwrap().unwrap();
        assert_eq!(info.mapping, LpuvPlaneMapping { plane_bits: 12, luma_top: 2047, uv_top: 255 });
        let codes = LpuvPlaneMapping::codes(11);
        assert_eq!(info, LpuvStreamInfo { mapping: codes, ..LpuvStreamInfo::for_primaries(ColorPrimaries::Bt2020) });
        // And a stream of codes as they are is written as version 1, byte for byte.
        assert_eq!(info.to_t35_payload(), v1);
        assert!(LpuvStreamInfo::from_t35(0xff, &v1[..34]).is_err());
    }

    #[test]
    fn mapped_planes_invert_every_code() {
        for (code_max, top) in
            [(255u32, 255u16), (255, 1020), (255, 4095), (2047, 2047), (2047, 4095), (1023, 3000), (1023, 1023)]
        {
            let (to_plane, to_code) = (LpuvPlaneMapping::to_plane, LpuvPlaneMapping::to_code);
            assert_eq!((to_plane(0, code_max, top), to_plane(code_max as u16, code_max, top)), (0, top));
            let mut last = None;
            for c in 0..=code_max as u16 {
                let p = to_plane(c, code_max, top);
                assert!(last < Some(p), "strictly increasing at {c}");
                last = Some(p);
                assert_eq!(to_code(p, code_max, top), c, "code {c} of {code_max} onto {top}");
                // Plane errors within half a code's width (less the rounding) decode to the code.
                let half = ((u32::from(top) / code_max - 1) / 2) as u16;
                assert_eq!(to_code(p.saturating_sub(half), code_max, top), c);
                assert_eq!(to_code((p + half).min(4095), code_max, top), c);
            }
            assert_eq!(to_code(4095, code_max, top), code_max as u16); // overshoot clamps
        }
        assert_eq!(LpuvPlaneMapping::to_plane(128, 255, 4095), 2056); // 128·4095/255 = 2055.53
        assert_eq!(LpuvPlaneMapping::to_plane(1024, 2047, 4095), 2049); // 1024·4095/2047 = 2048.50
        assert_eq!(LpuvPlaneMapping::to_plane(77, 255, 1020), 308);
    }

    #[test]
    fn planes_round_trip_without_loss_at_444() {
        for info in [
            LpuvStreamInfo { mapping: LpuvPlaneMapping::codes(11), ..LpuvStreamInfo::default() },
            LpuvStreamInfo::default(),
            LpuvStreamInfo::main10(ColorPrimaries::Bt709),
        ] {
            let mapping = info.mapping;
            let psi = info.psi().unwrap();
            let samples: Vec<f32> = (0..4 * 3 * 3).map(|i| (i as f32 * 0.37).sin().abs() * 50.0).collect();
            let frame = HdrImage::new(4, 3, hdrcodec_core::Channels::Rgb, samples, ColorInfo::default()).unwrap();
            let yuv = frame_to_lpuv_yuv(&psi, &frame, Subsampling::Yuv444, mapping).unwrap();
            let back = lpuv_yuv_to_frame(&psi, &yuv, frame.color.clone(), mapping).unwrap();
            assert_eq!(frame_to_lpuv_yuv(&psi, &back, Subsampling::Yuv444, mapping).unwrap(), yuv);
            let yuv420 = frame_to_lpuv_yuv(&psi, &frame, Subsampling::Yuv420, mapping).unwrap();
            assert_eq!((yuv420.cb.len(), &yuv420.y), (4, &yuv.y));
            assert!(lpuv_yuv_to_frame(&psi, &yuv420, frame.color.clone(), mapping).is_ok());
            // Both mappings place the same codes.
            let bits = info.bits;
            let codes = frame_to_lpuv_yuv(&psi, &frame, Subsampling::Yuv444, LpuvPlaneMapping::codes(bits)).unwrap();
            let top = (1u32 << bits) - 1;
            let placed: Vec<u16> =
                codes.y.iter().map(|&c| LpuvPlaneMapping::to_plane(c, top, mapping.luma_top)).collect();
            assert_eq!(yuv.y, placed);
            assert!(yuv.y.iter().chain(&yuv.cb).all(|&p| u32::from(p) <= mapping.plane_max()));
        }
    }
}
