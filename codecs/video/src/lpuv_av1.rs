//! L_p u'v' (Mantiuk et al. 2004) in AV1 planes, and the ITU-T T.35 message that says so.
//!
//! The planes hold the codes of [`crate::luv`] unscaled, in a 12-bit stream (AV1 profile 2):
//! Y = the ψ luma code (0..2047 at 11 bits), U = round(410·u'), V = round(410·v') (0..255).
//! They are not a CICP colour space, so the sequence header carries no colour description; the
//! stream is identified by a T.35 metadata OBU on every frame instead (see [`LpuvStreamInfo`]).
//! For 4:2:0 the u'v' codes of each 2x2 block are averaged (chromaticity codes, not light:
//! the codes are what the decoder rebuilds colour from) and the decoder replicates them back.

use crate::curves::LumaCurve;
use crate::hdr10::{Subsampling, YuvFrame};
use crate::luv::{decode_image, encode_image, LpuvPlanes, UV_SCALE};
use crate::mantiuk::{Psi04, PsiIntegration, PsiOptions};
use hdrcodec_core::{ColorInfo, ColorPrimaries, Error, HdrImage, Result};

/// Bit depth of the AV1 planes that carry L_p u'v'.
pub const LPUV_BIT_DEPTH: u32 = 12;

/// `itu_t_t35_country_code` of our message: 0xFF, "the country code is in the next byte".
pub const T35_COUNTRY_CODE: u8 = 0xFF;
/// `itu_t_t35_country_code_extension_byte`: 0xFF, which names no country. We have no T.35
/// terminal provider code, so we claim no country's provider space (0xB5 would sit among the
/// US providers' codes); the ASCII magic is what identifies the message.
pub const T35_COUNTRY_CODE_EXTENSION: u8 = 0xFF;
/// The first bytes of the payload (after the country code and its extension).
pub const T35_MAGIC: &[u8; 13] = b"hdrcodec-lpuv";
/// Payload format version.
pub const T35_VERSION: u8 = 1;
/// Payload length: magic, version, curve, bits, primaries, u'v' scale (u16), L_min, L_max (f64).
pub const T35_PAYLOAD_LEN: usize = 13 + 4 + 2 + 8 + 8;

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
/// Payload bytes (after country code 0xFF and extension 0xFF), big-endian, 35 bytes:
/// `"hdrcodec-lpuv"` (13 ASCII bytes), version (1), curve id (1 = ψ 2004 continuous,
/// 2 = ψ by LumaHDRv's recurrence), luma bits (11), H.273 colour primaries of the decoded RGB
/// (1 BT.709, 9 BT.2020, 12 P3-D65), u'v' scale as u16 (410), L_min and L_max in cd/m² as f64.
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
        }
    }
}

impl LpuvStreamInfo {
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

    /// The T.35 payload (after the country code and extension byte).
    pub fn to_t35_payload(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(T35_PAYLOAD_LEN);
        out.extend_from_slice(T35_MAGIC);
        out.extend_from_slice(&[T35_VERSION, self.curve.id(), self.bits, self.primaries_h273]);
        out.extend_from_slice(&(UV_SCALE as u16).to_be_bytes());
        out.extend_from_slice(&self.min_nits.to_be_bytes());
        out.extend_from_slice(&self.max_nits.to_be_bytes());
        out
    }

    /// Parses a T.35 message. `Ok(None)`: not ours (another country code or magic). Errors:
    /// ours but truncated, of another version, or with values we cannot decode.
    pub fn from_t35(country_code: u8, payload: &[u8]) -> Result<Option<Self>> {
        if country_code != T35_COUNTRY_CODE || !payload.starts_with(T35_MAGIC) {
            return Ok(None);
        }
        let b = payload.get(..T35_PAYLOAD_LEN).ok_or_else(|| Error::truncated("the hdrcodec-lpuv T.35 message"))?;
        if b[13] != T35_VERSION {
            return Err(Error::unsupported(format!("hdrcodec-lpuv T.35 message version {}", b[13])));
        }
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
        };
        let scale = u16::from_be_bytes([b[17], b[18]]);
        if f64::from(scale) != UV_SCALE {
            return Err(Error::unsupported(format!("L_p u'v' stream with u'v' scale {scale}")));
        }
        if u32::from(info.bits) > LPUV_BIT_DEPTH || info.bits < 8 {
            return Err(Error::unsupported(format!("L_p u'v' luma of {} bits in 12-bit planes", info.bits)));
        }
        if !(info.min_nits > 0.0 && info.max_nits > info.min_nits && info.max_nits.is_finite()) {
            return Err(Error::invalid(format!("L_p u'v' range {} … {} cd/m²", info.min_nits, info.max_nits)));
        }
        info.primaries()?;
        Ok(Some(info))
    }
}

/// A frame (any primaries, `nits_per_unit`) → 12-bit AV1 planes of L_p u'v' codes.
pub fn frame_to_lpuv_yuv(psi: &Psi04, frame: &HdrImage, subsampling: Subsampling) -> Result<YuvFrame> {
    let planes = encode_image(psi, frame)?;
    let (w, h) = (planes.width as usize, planes.height as usize);
    let (cw, ch) = YuvFrame::chroma_size(w, h, subsampling);
    let chroma = |codes: &[u8]| -> Vec<u16> {
        match subsampling {
            Subsampling::Yuv444 => codes.iter().map(|&c| u16::from(c)).collect(),
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
                        out.push(((2 * sum + n) / (2 * n)) as u16);
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
        y: planes.luma.clone(),
        cb: chroma(&planes.u),
        cr: chroma(&planes.v),
    })
}

/// 12-bit planes of L_p u'v' codes → a frame in `color` (primaries, `nits_per_unit`). Codes
/// beyond the curve's top or 255 (a lossy encoder may overshoot) are clamped to them.
pub fn lpuv_yuv_to_frame(psi: &Psi04, yuv: &YuvFrame, color: ColorInfo) -> Result<HdrImage> {
    let (w, h) = (yuv.width, yuv.height);
    let (cw, ch) = YuvFrame::chroma_size(w, h, yuv.subsampling);
    if yuv.y.len() != w * h || yuv.cb.len() != cw * ch || yuv.cr.len() != cw * ch {
        return Err(Error::invalid("L_p u'v' planes whose sizes do not match the frame"));
    }
    let top = ((1u32 << psi.bits()) - 1) as u16;
    let (sx, sy) = match yuv.subsampling {
        Subsampling::Yuv420 => (1, 1),
        Subsampling::Yuv444 => (0, 0),
    };
    let chroma = |plane: &[u16]| -> Vec<u8> {
        (0..w * h).map(|i| plane[((i / w) >> sy) * cw + ((i % w) >> sx)].min(255) as u8).collect()
    };
    let planes = LpuvPlanes {
        width: w as u32,
        height: h as u32,
        bits: psi.bits(),
        luma: yuv.y.iter().map(|&c| c.min(top)).collect(),
        u: chroma(&yuv.cb),
        v: chroma(&yuv.cr),
    };
    decode_image(psi, &planes, color)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t35_payload_round_trips_byte_by_byte() {
        let info = LpuvStreamInfo::for_primaries(ColorPrimaries::Bt2020);
        let payload = info.to_t35_payload();
        assert_eq!(payload.len(), T35_PAYLOAD_LEN);
        assert_eq!(&payload[..13], b"hdrcodec-lpuv");
        assert_eq!(&payload[13..19], &[1, 1, 11, 9, 0x01, 0x9a]);
        assert_eq!(&payload[19..27], &1e-4f64.to_be_bytes());
        assert_eq!(&payload[27..], &1e8f64.to_be_bytes());
        assert_eq!(LpuvStreamInfo::from_t35(0xff, &payload).unwrap(), Some(info));
        // Not ours: other country code or magic.
        assert_eq!(LpuvStreamInfo::from_t35(0xb5, &payload).unwrap(), None);
        assert_eq!(LpuvStreamInfo::from_t35(0xff, b"something else").unwrap(), None);
        // Ours but broken: truncated, future version, unknown curve, bad range.
        assert!(LpuvStreamInfo::from_t35(0xff, &payload[..30]).is_err());
        for (i, v) in [(13, 2u8), (14, 9), (15, 14), (16, 5)] {
            let mut bad = payload.clone();
            bad[i] = v;
            assert!(LpuvStreamInfo::from_t35(0xff, &bad).is_err(), "byte {i} = {v}");
        }
        let mut bad = payload.clone();
        bad[19..27].copy_from_slice(&2e8f64.to_be_bytes());
        assert!(LpuvStreamInfo::from_t35(0xff, &bad).is_err());
    }

    #[test]
    fn planes_round_trip_without_loss_at_444() {
        let info = LpuvStreamInfo::default();
        let psi = info.psi().unwrap();
        let samples: Vec<f32> = (0..4 * 3 * 3).map(|i| (i as f32 * 0.37).sin().abs() * 50.0).collect();
        let frame = HdrImage::new(4, 3, hdrcodec_core::Channels::Rgb, samples, ColorInfo::default()).unwrap();
        let yuv = frame_to_lpuv_yuv(&psi, &frame, Subsampling::Yuv444).unwrap();
        let back = lpuv_yuv_to_frame(&psi, &yuv, frame.color.clone()).unwrap();
        assert_eq!(frame_to_lpuv_yuv(&psi, &back, Subsampling::Yuv444).unwrap(), yuv);
        let yuv420 = frame_to_lpuv_yuv(&psi, &frame, Subsampling::Yuv420).unwrap();
        assert_eq!((yuv420.cb.len(), &yuv420.y), (4, &yuv.y));
        assert!(lpuv_yuv_to_frame(&psi, &yuv420, frame.color.clone()).is_ok());
    }
}
