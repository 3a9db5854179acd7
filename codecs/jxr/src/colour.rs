//! The colour of a file's samples, from what its container says.
//!
//! JPEG XR's codestream carries no colour; the container may (T.832 Annex A):
//! - PTM_COLOR_INFO (A.7.4): ITU-T H.273 code points for the colour primaries, the transfer
//!   characteristics, the matrix coefficients and the full-range flag. Read here: the
//!   primaries (BT.709, BT.2020, P3, DCI-P3, XYZ) and, for the integer formats, the transfer
//!   (sRGB, linear, PQ). jxrlib ignores the tag.
//! - Without it, the WIC convention (JXR-NOTES §7): the half, float, fixed-point and RGBE
//!   formats are linear scRGB (BT.709 primaries, 1.0 = 80 cd/m²); the integer formats
//!   sRGB-encoded, linearised with 80 cd/m² as sRGB's reference white.
//! - ICC_PROFILE and XMP_METADATA are kept as metadata, not interpreted.
//!
//! What a file says that is not applied (a transfer other than sRGB, linear and PQ, primaries
//! without a named space here, limited range) keeps the samples as decoded and is said in the
//! image's metadata (`jxr.colour_note`); nothing is guessed.

use crate::container::{Container, OutputBitDepth, OutputColorFormat, PixelFormat};
use crate::output::{SampleTransfer, NITS_PER_UNIT};
use hdrcodec_core::{ColorInfo, ColorPrimaries};

/// The colour of a file's samples and how to linearise them.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FileColour {
    /// What the decoded image carries.
    pub color: ColorInfo,
    /// How the integer formats' samples become linear light.
    pub transfer: SampleTransfer,
    /// What the container said about colour, for the image's metadata.
    pub metadata: Vec<(String, String)>,
}

/// True for the formats whose colour samples are integer codes of some transfer function.
fn integer_coded(format: &PixelFormat) -> bool {
    use OutputBitDepth::*;
    matches!(format.bit_depth, Bd1White1 | Bd1Black1 | Bd8 | Bd16 | Bd5 | Bd10 | Bd565)
        && format.color != OutputColorFormat::Rgbe
}

/// The H.273 transfer characteristics codes in words, for notes.
fn transfer_name(code: u8) -> String {
    let name = match code {
        1 | 6 | 14 | 15 => "BT.709/BT.601/BT.2020 camera curve",
        4 | 5 => "power law",
        8 => "linear",
        13 => "sRGB",
        16 => "PQ (SMPTE ST 2084)",
        18 => "HLG (ARIB STD-B67)",
        2 => "unspecified",
        _ => "other",
    };
    format!("{code} ({name})")
}

/// The colour of the samples of the file whose container is `container`.
pub(crate) fn file_colour(container: &Container) -> FileColour {
    let format = container.pixel_format;
    let integer = integer_coded(format);
    let mut colour = FileColour {
        color: ColorInfo { primaries: ColorPrimaries::Bt709, nits_per_unit: NITS_PER_UNIT, hdr10: None },
        transfer: if integer { SampleTransfer::Srgb } else { SampleTransfer::Linear },
        metadata: Vec::new(),
    };
    let mut notes = Vec::new();
    if let Some([primaries, transfer, matrix, full_range]) = container.ptm_color_info {
        colour.metadata.push((
            "jxr.ptm_color_info".into(),
            format!("primaries {primaries}, transfer {transfer}, matrix {matrix}, full range {full_range}"),
        ));
        colour.color.primaries = match ColorPrimaries::from_h273(primaries) {
            Some(p) => p,
            None => {
                notes.push(format!(
                    "colour primaries {primaries} (H.273) name no space known here: the samples are kept and read as unspecified"
                ));
                ColorPrimaries::Unspecified
            }
        };
        if integer {
            colour.transfer = match transfer {
                13 | 2 => SampleTransfer::Srgb,
                8 => SampleTransfer::Linear,
                16 => SampleTransfer::Pq,
                other => {
                    notes.push(format!(
                        "transfer {} is not applied: the samples are its signal values, 0 to 1",
                        transfer_name(other)
                    ));
                    SampleTransfer::Linear
                }
            };
            if full_range == 0 {
                notes.push("the samples are marked limited range; they are read as full range".into());
            }
        } else if !matches!(transfer, 2 | 8) {
            notes.push(format!(
                "transfer {} is ignored: {} samples are linear by definition",
                transfer_name(transfer),
                format.name
            ));
        }
    }
    if let Some(icc) = container.icc_profile {
        colour.metadata.push(("jxr.icc_profile".into(), format!("{} bytes, not applied", icc.len())));
    }
    if let Some(xmp) = container.xmp {
        colour.metadata.push(("xmp".into(), String::from_utf8_lossy(xmp).trim_end_matches('\0').to_string()));
    }
    if !notes.is_empty() {
        colour.metadata.push(("jxr.colour_note".into(), notes.join("; ")));
    }
    colour
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::container::PIXEL_FORMATS;

    fn container(format: &str, ptm: Option<[u8; 4]>) -> Container<'static> {
        let pixel_format = PIXEL_FORMATS.iter().find(|f| f.name == format).unwrap();
        Container {
            version: 1,
            pixel_format_guid: pixel_format.guid,
            pixel_format,
            image: &[],
            alpha: None,
            orientation: None,
            width: None,
            height: None,
            resolution: None,
            icc_profile: None,
            xmp: None,
            ptm_color_info: ptm,
            exif_ifd: None,
        }
    }

    fn note(c: &FileColour) -> Option<&str> {
        c.metadata.iter().find(|(k, _)| k == "jxr.colour_note").map(|(_, v)| v.as_str())
    }

    #[test]
    fn without_colour_info_the_wic_convention_holds() {
        let half = file_colour(&container("64bppRGBAHalf", None));
        assert_eq!((half.color.primaries, half.color.nits_per_unit), (ColorPrimaries::Bt709, 80.0));
        assert_eq!((half.transfer, half.metadata.len()), (SampleTransfer::Linear, 0));
        assert_eq!(file_colour(&container("48bppRGB", None)).transfer, SampleTransfer::Srgb);
        assert_eq!(file_colour(&container("32bppRGB101010", None)).transfer, SampleTransfer::Srgb);
        // RGBE is linear, though its bit depth is BD8.
        assert_eq!(file_colour(&container("32bppRGBE", None)).transfer, SampleTransfer::Linear);
    }

    #[test]
    fn ptm_color_info_gives_primaries_and_the_integer_transfer() {
        // BT.2020 primaries, PQ, BT.2020 matrix, full range: an HDR10-style 10-bit file.
        let pq = file_colour(&container("32bppRGB101010", Some([9, 16, 9, 1])));
        assert_eq!((pq.color.primaries, pq.transfer), (ColorPrimaries::Bt2020, SampleTransfer::Pq));
        assert_eq!(note(&pq), None);
        assert_eq!(pq.metadata[0].1, "primaries 9, transfer 16, matrix 9, full range 1");
        let linear = file_colour(&container("48bppRGB", Some([12, 8, 0, 1])));
        assert_eq!((linear.color.primaries, linear.transfer), (ColorPrimaries::DisplayP3, SampleTransfer::Linear));
        // Half samples are linear whatever the transfer says; a contradiction is noted.
        let half = file_colour(&container("64bppRGBHalf", Some([1, 13, 0, 1])));
        assert_eq!(half.transfer, SampleTransfer::Linear);
        assert!(note(&half).unwrap().contains("13 (sRGB) is ignored"), "{half:?}");
    }

    #[test]
    fn what_is_not_applied_is_said() {
        let hlg = file_colour(&container("48bppRGB", Some([9, 18, 9, 0])));
        assert_eq!(hlg.transfer, SampleTransfer::Linear);
        let n = note(&hlg).unwrap();
        assert!(n.contains("18 (HLG (ARIB STD-B67)) is not applied") && n.contains("limited range"), "{n}");
        let other = file_colour(&container("24bppRGB", Some([5, 13, 1, 1])));
        assert_eq!(other.color.primaries, ColorPrimaries::Unspecified);
        assert!(note(&other).unwrap().contains("primaries 5"));
    }

    #[test]
    fn pq_decodes_to_80_nit_units() {
        // ST 2084: signal 0.5081 is about 100 cd/m², 1.0 is 10 000 cd/m².
        assert!((SampleTransfer::Pq.decode(1.0) - 125.0).abs() < 1e-9);
        assert!((SampleTransfer::Pq.decode(0.508_078) * 80.0 - 100.0).abs() < 0.01);
    }
}
