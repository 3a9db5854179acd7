//! L_p u'v' frames as an image payload ([`LpuvImageCodec`], name `lpuv`, id `LPUV`): how a
//! `.hdrc` file (the family's container) carries frames in the Mantiuk 2004 colour space and
//! declares it, as the AV1 stream does in its T.35 message.
//!
//! Bytes (all big-endian): the L_p u'v' description, the same bytes as the AV1 T.35 payload
//! ([`LpuvStreamInfo::to_t35_payload`]: `hdrcodec-lpuv`, version, curve, luma bits, primaries,
//! u'v' scale, L_min, L_max, and in version 2 the plane mapping); width and height (u32); the luma
//! codes (u16 each, row-major), then the u' codes and the v' codes (one byte each). The codes are
//! stored as they are, so the description is version 1 ([`LpuvPlaneMapping::codes`]). Decoding
//! reads the description back, so a file names its own curve, range and primaries: frames come
//! back as linear light in the primaries it names, 1.0 = `nits_per_unit` cd/m² (decode option,
//! default 100; the codes are absolute luminance, so the scale is recorded).
//!
//! ```
//! use hdrcodec_core::{Channels, ColorInfo, EncodeSettings, HdrImage, ImageCodec, Limits};
//! use hdrcodec_video::lpuv_image::LpuvImageCodec;
//!
//! let frame = HdrImage::new(4, 2, Channels::Rgb, vec![2.5; 4 * 2 * 3], ColorInfo::default())?;
//! let bytes = LpuvImageCodec.encode(&frame, &EncodeSettings::default())?;
//! assert!(bytes.starts_with(b"hdrcodec-lpuv"));
//! let back = LpuvImageCodec.decode(&bytes, &Limits::default())?;
//! assert!((back.samples()[1] / 2.5 - 1.0).abs() < 0.01);
//! # Ok::<(), hdrcodec_core::Error>(())
//! ```

use crate::lpuv_av1::{LpuvPlaneMapping, LpuvStreamInfo, T35_COUNTRY_CODE, T35_MAGIC};
use crate::luv::{decode_image, encode_image, LpuvPlanes};
use hdrcodec_core::{
    Channels, ColorInfo, ColorSignalling, DecodeOptions, EncodeReport, EncodeSettings, Error, HdrImage, ImageCodec,
    ImageInfo, Limits, Result,
};
use std::io::Write;

/// L_p u'v' codes with their description, as an [`ImageCodec`] (see the module).
#[derive(Clone, Copy, Debug, Default)]
pub struct LpuvImageCodec;

/// The description, the size and where the planes start.
fn read_header(data: &[u8]) -> Result<(LpuvStreamInfo, u32, u32, usize)> {
    let info = LpuvStreamInfo::from_t35(T35_COUNTRY_CODE, data)?
        .ok_or_else(|| Error::invalid("not L_p u'v' codes (no hdrcodec-lpuv description)"))?;
    let at = info.to_t35_payload().len();
    let size = data.get(at..at + 8).ok_or_else(|| Error::truncated("the L_p u'v' frame size"))?;
    let w = u32::from_be_bytes([size[0], size[1], size[2], size[3]]);
    let h = u32::from_be_bytes([size[4], size[5], size[6], size[7]]);
    Ok((info, w, h, at + 8))
}

fn color_of(info: &LpuvStreamInfo, options: &DecodeOptions) -> Result<ColorInfo> {
    let nits_per_unit = match options.parse_option::<f32>("nits_per_unit")? {
        Some(n) if n.is_finite() && n > 0.0 => n,
        Some(n) => return Err(Error::invalid(format!("nits_per_unit={n}: expected a positive number"))),
        None => 100.0,
    };
    Ok(ColorInfo { primaries: info.primaries()?, nits_per_unit, hdr10: None })
}

impl ImageCodec for LpuvImageCodec {
    fn name(&self) -> &'static str {
        "lpuv"
    }
    fn id(&self) -> [u8; 4] {
        *b"LPUV"
    }
    /// None: L_p u'v' codes have no file of their own; they are a `.hdrc` payload.
    fn extensions(&self) -> &'static [&'static str] {
        &[]
    }
    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(T35_MAGIC)
    }
    /// L_p u'v' holds colour absolutely (CIE u'v'): any primaries are converted in, and decoded
    /// to the BT.709, BT.2020 or P3-D65 that the description names (others to BT.2020).
    fn color_signalling(&self) -> ColorSignalling {
        ColorSignalling::Any
    }
    /// The codes are absolute luminance.
    fn records_nits_per_unit(&self) -> bool {
        true
    }
    fn decode_option_keys(&self) -> &'static [&'static str] {
        &["nits_per_unit"]
    }
    fn probe(&self, data: &[u8], limits: &Limits) -> Result<ImageInfo> {
        let (info, w, h, _) = read_header(data)?;
        limits.check_dimensions(u64::from(w), u64::from(h))?;
        let format = format!("L_p u'v' {:?} {}-bit", info.curve, info.bits);
        Ok(ImageInfo::new(w, h, Channels::Rgb, color_of(&info, &DecodeOptions::default())?).with_format(format))
    }
    fn decode_with(&self, data: &[u8], options: &DecodeOptions) -> Result<HdrImage> {
        let (info, w, h, at) = read_header(data)?;
        let limits = &options.limits;
        limits.check_dimensions(u64::from(w), u64::from(h))?;
        let n = u64::from(w) * u64::from(h);
        if (data.len() - at) as u64 != 4 * n {
            return Err(Error::invalid(format!(
                "L_p u'v' planes of {} bytes for {w}x{h} pixels (4 bytes each)",
                data.len() - at
            )));
        }
        let _charge = limits.charge(n * 12 + n * 4, "the L_p u'v' frame and its planes")?;
        let n = n as usize;
        let body = &data[at..];
        let top = (1u32 << info.bits) - 1;
        let mut luma = Vec::with_capacity(n);
        for c in body[..2 * n].chunks_exact(2) {
            let code = u16::from_be_bytes([c[0], c[1]]);
            if u32::from(code) > top {
                return Err(Error::invalid(format!("an L_p u'v' luma code {code} above the curve's top {top}")));
            }
            luma.push(code);
        }
        let planes = LpuvPlanes {
            width: w,
            height: h,
            bits: info.bits.into(),
            luma,
            u: body[2 * n..3 * n].to_vec(),
            v: body[3 * n..].to_vec(),
        };
        decode_image(&info.psi()?, &planes, color_of(&info, options)?)
    }
    fn encode_to(&self, image: &HdrImage, settings: &EncodeSettings, out: &mut dyn Write) -> Result<EncodeReport> {
        settings.check_options(self.name(), &[])?;
        let mut info = LpuvStreamInfo::for_primaries(image.color.primaries);
        info.mapping = LpuvPlaneMapping::codes(info.bits);
        let planes = encode_image(&info.psi()?, image)?;
        let mut bytes = info.to_t35_payload();
        bytes.extend_from_slice(&planes.width.to_be_bytes());
        bytes.extend_from_slice(&planes.height.to_be_bytes());
        bytes.extend(planes.luma.iter().flat_map(|c| c.to_be_bytes()));
        bytes.extend_from_slice(&planes.u);
        bytes.extend_from_slice(&planes.v);
        out.write_all(&bytes).map_err(Error::Io)?;
        Ok(EncodeReport::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip_and_damage_is_an_error() {
        let samples: Vec<f32> = (0..6 * 3 * 3).map(|i| 0.01 + (i as f32 * 0.37).sin().abs() * 40.0).collect();
        let color =
            ColorInfo { primaries: hdrcodec_core::ColorPrimaries::DisplayP3, nits_per_unit: 203.0, hdr10: None };
        let frame = HdrImage::new(6, 3, Channels::Rgb, samples, color).unwrap();
        let bytes = LpuvImageCodec.encode(&frame, &EncodeSettings::default()).unwrap();
        assert_eq!(bytes.len(), 35 + 8 + 18 * 4);
        assert_eq!(bytes[13], 1, "codes as they are: a version 1 description");
        let options = DecodeOptions::new(Limits::default()).with_option("nits_per_unit", "203");
        let back = LpuvImageCodec.decode_with(&bytes, &options).unwrap();
        assert_eq!(back.color.primaries, hdrcodec_core::ColorPrimaries::DisplayP3);
        // Decoding again encodes to the same codes.
        assert_eq!(LpuvImageCodec.encode(&back, &EncodeSettings::default()).unwrap(), bytes);
        assert_eq!(LpuvImageCodec.probe(&bytes, &Limits::default()).unwrap().width, 6);
        for len in 0..bytes.len() {
            assert!(LpuvImageCodec.decode(&bytes[..len], &Limits::default()).is_err(), "cut at {len}");
        }
        let mut high = bytes.clone();
        high[43] = 0xff; // luma code 0xff.. above 2047
        assert!(LpuvImageCodec.decode(&high, &Limits::default()).is_err());
        let small = Limits::default().with_max_alloc_bytes(100);
        assert!(matches!(LpuvImageCodec.decode(&bytes, &small), Err(Error::LimitExceeded { .. })));
    }
}
