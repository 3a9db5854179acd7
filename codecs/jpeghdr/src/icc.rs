//! Just enough of ICC profiles (ICC.1:2022) to name the primaries of a JPEG's RGB: the
//! profile is reassembled from its APP2 chunks and its colorant tags are matched against the
//! primaries the family knows. A profile that matches none is reported, not guessed.

use hdrcodec_core::color::{bradford, mat_apply};
use hdrcodec_core::ColorPrimaries;

/// The APP2 payload signature of an ICC profile chunk.
pub const SIGNATURE: &[u8] = b"ICC_PROFILE\0";

/// Reassembles an ICC profile from its chunks (each payload: sequence number from 1, chunk
/// count, data; ICC.1 B.4). `None` if a chunk is missing or numbered inconsistently.
pub fn assemble<'a>(chunks: impl Iterator<Item = &'a [u8]>) -> Option<Vec<u8>> {
    let mut parts: Vec<(u8, u8, &[u8])> = chunks.filter(|c| c.len() >= 2).map(|c| (c[0], c[1], &c[2..])).collect();
    if parts.is_empty() {
        return None;
    }
    parts.sort_by_key(|p| p.0);
    let count = parts[0].1;
    let consistent = parts.len() == usize::from(count)
        && parts.iter().enumerate().all(|(i, p)| usize::from(p.0) == i + 1 && p.1 == count);
    consistent.then(|| parts.iter().flat_map(|p| p.2.iter().copied()).collect())
}

/// The colorants (rXYZ, gXYZ, bXYZ: PCS XYZ, D50-adapted) of an RGB display profile.
fn colorants(profile: &[u8]) -> Option<[[f64; 3]; 3]> {
    let u32_at = |o: usize| profile.get(o..o + 4).map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
    if profile.get(16..20) != Some(b"RGB ") {
        return None;
    }
    let count = u32_at(128)? as usize;
    let mut out = [[0.0; 3]; 3];
    let mut found = 0;
    for i in 0..count.min(1000) {
        let e = 132 + 12 * i;
        let (sig, offset, size) = (profile.get(e..e + 4)?, u32_at(e + 4)? as usize, u32_at(e + 8)? as usize);
        let k = match sig {
            b"rXYZ" => 0,
            b"gXYZ" => 1,
            b"bXYZ" => 2,
            _ => continue,
        };
        let data = profile.get(offset..offset.checked_add(size)?)?;
        if data.len() < 20 || &data[..4] != b"XYZ " {
            return None;
        }
        for (c, v) in out[k].iter_mut().enumerate() {
            let b = &data[8 + 4 * c..12 + 4 * c];
            *v = f64::from(i32::from_be_bytes([b[0], b[1], b[2], b[3]])) / 65536.0;
        }
        found |= 1 << k;
    }
    (found == 7).then_some(out)
}

/// The primaries an ICC profile's colorants describe, if they are (within the precision of
/// the profile's s15Fixed16 numbers and the writers' adaptation) one set the family knows.
pub fn primaries(profile: &[u8]) -> Option<ColorPrimaries> {
    let colorants = colorants(profile)?;
    let d65_to_d50 = bradford([0.3127, 0.3290], [0.3457, 0.3585]);
    [ColorPrimaries::Bt709, ColorPrimaries::DisplayP3, ColorPrimaries::Bt2020, ColorPrimaries::AdobeRgb]
        .into_iter()
        .find(|p| {
            let m = p.chromaticities().rgb_to_xyz();
            (0..3).all(|k| {
                let xyz = mat_apply(&d65_to_d50, [m[0][k], m[1][k], m[2][k]]);
                (0..3).all(|c| (xyz[c] - colorants[k][c]).abs() < 0.003)
            })
        })
}

/// The tone curve a profile of [`rgb_profile_with`] gives its three channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Curve {
    /// The sRGB transfer curve (IEC 61966-2-1), of 8-bit pictures.
    Srgb,
    /// The identity: samples proportional to light, as HDR images hold them.
    Linear,
}

/// A display profile (ICC.1:2022, version 4.3) for RGB in `primaries` with a D65 white and the
/// sRGB transfer curve: what a base image in Display P3 carries so that viewers and our
/// [`primaries`] know its colours. `None` for primaries without chromaticities.
pub fn rgb_profile(primaries: &ColorPrimaries, description: &str) -> Option<Vec<u8>> {
    rgb_profile_with(primaries, description, Curve::Srgb)
}

/// [`rgb_profile`] with the tone curve `curve`.
pub fn rgb_profile_with(primaries: &ColorPrimaries, description: &str, curve: Curve) -> Option<Vec<u8>> {
    let to_xyz = primaries.chromaticities().try_rgb_to_xyz()?;
    let d65_to_d50 = bradford([0.3127, 0.3290], [0.3457, 0.3585]);
    let s15 = |v: f64| ((v * 65536.0).round() as i32).to_be_bytes();
    let xyz = |v: [f64; 3]| [b"XYZ \0\0\0\0".to_vec(), v.iter().flat_map(|&x| s15(x)).collect()].concat();
    let mluc = |text: &str| {
        let utf16: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
        let mut t = b"mluc\0\0\0\0".to_vec();
        t.extend(1u32.to_be_bytes());
        t.extend(12u32.to_be_bytes());
        t.extend(b"enUS");
        t.extend((utf16.len() as u32).to_be_bytes());
        t.extend(28u32.to_be_bytes());
        t.extend(utf16);
        t
    };
    let mut para = b"para\0\0\0\0".to_vec();
    match curve {
        // sRGB's curve as parametric function 3: Y = (aX + b)^g for X ≥ d, else cX.
        Curve::Srgb => {
            para.extend(3u16.to_be_bytes());
            para.extend(0u16.to_be_bytes());
            for v in [2.4, 1.0 / 1.055, 0.055 / 1.055, 1.0 / 12.92, 0.04045] {
                para.extend(s15(v));
            }
        }
        // Parametric function 0, Y = X^g, with g = 1.
        Curve::Linear => {
            para.extend(0u16.to_be_bytes());
            para.extend(0u16.to_be_bytes());
            para.extend(s15(1.0));
        }
    }
    let chad = [b"sf32\0\0\0\0".to_vec(), d65_to_d50.iter().flatten().flat_map(|&x| s15(x)).collect()].concat();
    let colorant = |k: usize| xyz(mat_apply(&d65_to_d50, [to_xyz[0][k], to_xyz[1][k], to_xyz[2][k]]));
    let d50 = [0.9642, 1.0, 0.8249];
    let tags: Vec<(&[u8; 4], Vec<u8>)> = vec![
        (b"desc", mluc(description)),
        (b"cprt", mluc("No copyright, use freely")),
        (b"wtpt", xyz(d50)),
        (b"chad", chad),
        (b"rXYZ", colorant(0)),
        (b"gXYZ", colorant(1)),
        (b"bXYZ", colorant(2)),
        (b"rTRC", para.clone()),
        (b"gTRC", para.clone()),
        (b"bTRC", para),
    ];
    let mut data = Vec::new();
    let mut table = (tags.len() as u32).to_be_bytes().to_vec();
    let data_start = 128 + 4 + 12 * tags.len();
    for (sig, body) in &tags {
        table.extend(*sig);
        table.extend(((data_start + data.len()) as u32).to_be_bytes());
        table.extend((body.len() as u32).to_be_bytes());
        data.extend(body);
        data.resize(data.len().next_multiple_of(4), 0);
    }
    let size = (data_start + data.len()) as u32;
    let mut header = Vec::with_capacity(128);
    header.extend(size.to_be_bytes());
    header.extend([0u8; 4]); // preferred CMM
    header.extend(0x0430_0000u32.to_be_bytes());
    header.extend(b"mntrRGB XYZ ");
    for v in [2026u16, 1, 1, 0, 0, 0] {
        header.extend(v.to_be_bytes());
    }
    header.extend(b"acsp");
    header.resize(64, 0); // platform, flags, device manufacturer, model, attributes
    header.extend(0u32.to_be_bytes()); // perceptual intent
    header.extend(d50.iter().flat_map(|&x| s15(x)));
    header.resize(128, 0); // creator, profile ID (not computed), reserved
    Some([header, table, data].concat())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal RGB profile holding only the three colorant tags.
    fn profile(colorants: [[f64; 3]; 3]) -> Vec<u8> {
        let mut p = vec![0u8; 132 + 3 * 12];
        p[16..20].copy_from_slice(b"RGB ");
        p[128..132].copy_from_slice(&3u32.to_be_bytes());
        for (k, sig) in [b"rXYZ", b"gXYZ", b"bXYZ"].into_iter().enumerate() {
            let offset = p.len() as u32;
            let e = 132 + 12 * k;
            p[e..e + 4].copy_from_slice(sig);
            p[e + 4..e + 8].copy_from_slice(&offset.to_be_bytes());
            p[e + 8..e + 12].copy_from_slice(&20u32.to_be_bytes());
            p.extend(b"XYZ \0\0\0\0");
            for v in colorants[k] {
                p.extend(((v * 65536.0).round() as i32).to_be_bytes());
            }
        }
        p
    }

    #[test]
    fn srgb_and_display_p3_colorants_are_recognised() {
        // The colorants of the ICC's sRGB and of Apple's Display P3 profiles (D50, as stored).
        let srgb = [[0.4361, 0.2225, 0.0139], [0.3851, 0.7169, 0.0971], [0.1431, 0.0606, 0.7141]];
        let p3 = [[0.5151, 0.2412, -0.0011], [0.2920, 0.6922, 0.0419], [0.1571, 0.0666, 0.7841]];
        assert_eq!(primaries(&profile(srgb)), Some(ColorPrimaries::Bt709));
        assert_eq!(primaries(&profile(p3)), Some(ColorPrimaries::DisplayP3));
        assert_eq!(primaries(&profile([[0.5, 0.3, 0.0], [0.3, 0.6, 0.1], [0.1, 0.1, 0.8]])), None);
        let p = profile(srgb);
        for n in 0..p.len() {
            assert_eq!(primaries(&p[..n]), None);
        }
    }

    #[test]
    fn written_profiles_name_their_primaries() {
        for p in [ColorPrimaries::Bt709, ColorPrimaries::DisplayP3, ColorPrimaries::Bt2020] {
            let profile = rgb_profile(&p, "test").unwrap();
            assert_eq!(u32::from_be_bytes(profile[..4].try_into().unwrap()) as usize, profile.len());
            assert_eq!(primaries(&profile), Some(p));
        }
    }

    #[test]
    fn chunks_reassemble_in_order() {
        let (a, b) = ([2u8, 2, 7, 8], [1u8, 2, 5, 6]);
        assert_eq!(assemble([&a[..], &b[..]].into_iter()), Some(vec![5, 6, 7, 8]));
        assert_eq!(assemble([&a[..]].into_iter()), None);
    }
}
