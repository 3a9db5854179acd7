//! Colour: primaries and white points, and (computed from them, never typed in) the
//! RGB↔XYZ matrices; chromatic adaptation and the colour spaces the metrics use.

use crate::transfer::PqTransfer;
use crate::HdrImage;

/// CIE 1931 xy chromaticities of the three primaries and the white point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chromaticities {
    /// Red primary (x, y).
    pub red: [f64; 2],
    /// Green primary (x, y).
    pub green: [f64; 2],
    /// Blue primary (x, y).
    pub blue: [f64; 2],
    /// White point (x, y).
    pub white: [f64; 2],
}

/// CIE standard illuminant D65 (ITU-R BT.709 / BT.2020 white).
pub const D65: [f64; 2] = [0.3127, 0.3290];
/// The DCI projector white of SMPTE RP 431-2.
pub const DCI_WHITE: [f64; 2] = [0.314, 0.351];
/// The ACES white point (SMPTE ST 2065-1), close to D60.
pub const ACES_WHITE: [f64; 2] = [0.32168, 0.33767];
/// The equal-energy illuminant E, white of the CIE XYZ "primaries".
pub const ILLUMINANT_E: [f64; 2] = [1.0 / 3.0, 1.0 / 3.0];

/// The RGB colour spaces the family names; anything else is [`ColorPrimaries::Custom`].
///
/// [`ColorPrimaries::Unspecified`] is what a decoder returns for a format that records no
/// primaries (PFM, DDS): the samples are whatever the writer had. Tools that must interpret them
/// (metrics, a conversion) treat them as BT.709 ([`ColorPrimaries::or_bt709`]) and say so.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ColorPrimaries {
    /// ITU-R BT.709 / sRGB, D65.
    Bt709,
    /// ITU-R BT.2020 / BT.2100, D65.
    Bt2020,
    /// Display P3: DCI-P3 primaries with D65.
    DisplayP3,
    /// DCI-P3 (SMPTE RP 431-2) with the DCI white.
    DciP3,
    /// ACES AP0 (SMPTE ST 2065-1).
    AcesAp0,
    /// ACES AP1 (ACEScg, ACEScc).
    AcesAp1,
    /// Adobe RGB (1998), D65.
    AdobeRgb,
    /// The samples are CIE XYZ (X, Y, Z in R, G, B).
    Xyz,
    /// Any other chromaticities.
    Custom(Chromaticities),
    /// The file does not say: the samples are kept as they were written.
    Unspecified,
}

impl ColorPrimaries {
    /// The primaries of `ColourPrimaries` code `code` of ITU-T H.273 (Table 2), the code points
    /// video streams, ISOBMFF `colr` boxes and JPEG XR's PTM_COLOR_INFO use: 1 BT.709,
    /// 2 unspecified, 9 BT.2020, 10 CIE XYZ (SMPTE ST 428-1), 11 DCI-P3 (SMPTE RP 431-2),
    /// 12 Display P3 (SMPTE EG 432-1). `None` for codes naming other primaries (the older TV
    /// systems, EBU 3213) and reserved codes.
    pub fn from_h273(code: u8) -> Option<Self> {
        Some(match code {
            1 => ColorPrimaries::Bt709,
            2 => ColorPrimaries::Unspecified,
            9 => ColorPrimaries::Bt2020,
            10 => ColorPrimaries::Xyz,
            11 => ColorPrimaries::DciP3,
            12 => ColorPrimaries::DisplayP3,
            _ => return None,
        })
    }

    /// The ITU-T H.273 code of these primaries, for those [`from_h273`](Self::from_h273)
    /// knows.
    pub fn h273(&self) -> Option<u8> {
        (1..=12).find(|&c| Self::from_h273(c).as_ref() == Some(self))
    }

    /// The chromaticities that define this space, from its standard.
    pub fn chromaticities(&self) -> Chromaticities {
        let c =
            |r: [f64; 2], g: [f64; 2], b: [f64; 2], w: [f64; 2]| Chromaticities { red: r, green: g, blue: b, white: w };
        match *self {
            // ITU-R BT.709-6, Table "1.3 Chromaticity coordinates".
            ColorPrimaries::Bt709 => c([0.640, 0.330], [0.300, 0.600], [0.150, 0.060], D65),
            // ITU-R BT.2020-2, Table 3.
            ColorPrimaries::Bt2020 => c([0.708, 0.292], [0.170, 0.797], [0.131, 0.046], D65),
            // SMPTE EG 432-1 (P3-D65) and SMPTE RP 431-2 (DCI-P3).
            ColorPrimaries::DisplayP3 => c([0.680, 0.320], [0.265, 0.690], [0.150, 0.060], D65),
            ColorPrimaries::DciP3 => c([0.680, 0.320], [0.265, 0.690], [0.150, 0.060], DCI_WHITE),
            // SMPTE ST 2065-1 (AP0) and the ACEScg specification S-2014-004 (AP1).
            ColorPrimaries::AcesAp0 => c([0.7347, 0.2653], [0.0, 1.0], [0.0001, -0.0770], ACES_WHITE),
            ColorPrimaries::AcesAp1 => c([0.713, 0.293], [0.165, 0.830], [0.128, 0.044], ACES_WHITE),
            // Adobe RGB (1998) Color Image Encoding, section 4.3.
            ColorPrimaries::AdobeRgb => c([0.640, 0.330], [0.210, 0.710], [0.150, 0.060], D65),
            ColorPrimaries::Xyz => c([1.0, 0.0], [0.0, 1.0], [0.0, 0.0], ILLUMINANT_E),
            ColorPrimaries::Custom(ch) => ch,
            // Only where something must be assumed: see `or_bt709`.
            ColorPrimaries::Unspecified => ColorPrimaries::Bt709.chromaticities(),
        }
    }

    /// False for [`ColorPrimaries::Unspecified`].
    pub fn is_specified(&self) -> bool {
        !matches!(self, ColorPrimaries::Unspecified)
    }

    /// These primaries, or BT.709 where they are unspecified: what a tool assumes when it must
    /// interpret samples whose file recorded no primaries (and then says that it assumed).
    pub fn or_bt709(self) -> Self {
        match self {
            ColorPrimaries::Unspecified => ColorPrimaries::Bt709,
            p => p,
        }
    }

    /// The named space called `name` (as given on a command line: `bt709`, `srgb`, `bt2020`,
    /// `rec2020`, `p3`, `display-p3`, `dci-p3`, `aces`, `ap0`, `acescg`, `ap1`, `adobe-rgb`, `xyz`;
    /// case, `-`, `_`, `.` and spaces are ignored).
    pub fn from_name(name: &str) -> Option<Self> {
        let key: String = name.chars().filter(|c| c.is_ascii_alphanumeric()).collect::<String>().to_ascii_lowercase();
        Some(match key.as_str() {
            "bt709" | "rec709" | "srgb" | "709" => ColorPrimaries::Bt709,
            "bt2020" | "rec2020" | "bt2100" | "2020" => ColorPrimaries::Bt2020,
            "p3" | "displayp3" | "p3d65" => ColorPrimaries::DisplayP3,
            "dcip3" | "p3dci" => ColorPrimaries::DciP3,
            "aces" | "ap0" | "acesap0" | "aces20651" => ColorPrimaries::AcesAp0,
            "acescg" | "ap1" | "acesap1" => ColorPrimaries::AcesAp1,
            "adobergb" | "adobergb1998" => ColorPrimaries::AdobeRgb,
            "xyz" | "ciexyz" => ColorPrimaries::Xyz,
            _ => return None,
        })
    }

    /// Every named space, in a fixed order (file formats may store an index into it).
    pub const NAMED: [ColorPrimaries; 8] = [
        ColorPrimaries::Bt709,
        ColorPrimaries::Bt2020,
        ColorPrimaries::DisplayP3,
        ColorPrimaries::DciP3,
        ColorPrimaries::AcesAp0,
        ColorPrimaries::AcesAp1,
        ColorPrimaries::AdobeRgb,
        ColorPrimaries::Xyz,
    ];

    /// The named space with exactly these chromaticities, else `Custom`.
    pub fn from_chromaticities(ch: Chromaticities) -> Self {
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 5e-4 && (a[1] - b[1]).abs() < 5e-4;
        for p in Self::NAMED {
            let n = p.chromaticities();
            if close(n.red, ch.red) && close(n.green, ch.green) && close(n.blue, ch.blue) && close(n.white, ch.white) {
                return p;
            }
        }
        ColorPrimaries::Custom(ch)
    }

    /// A short human-readable name ("BT.709", "BT.2020", ..., "custom").
    pub fn name(&self) -> &'static str {
        match self {
            ColorPrimaries::Bt709 => "BT.709",
            ColorPrimaries::Bt2020 => "BT.2020",
            ColorPrimaries::DisplayP3 => "Display P3",
            ColorPrimaries::DciP3 => "DCI-P3",
            ColorPrimaries::AcesAp0 => "ACES AP0",
            ColorPrimaries::AcesAp1 => "ACES AP1",
            ColorPrimaries::AdobeRgb => "Adobe RGB",
            ColorPrimaries::Xyz => "CIE XYZ",
            ColorPrimaries::Custom(_) => "custom",
            ColorPrimaries::Unspecified => "unspecified",
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 3x3 matrices
// ---------------------------------------------------------------------------------------------

/// A row-major 3x3 matrix: `out[i] = sum_j m[i][j] * in[j]`.
pub type Mat3 = [[f64; 3]; 3];

/// The identity matrix.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The matrix product `a · b` (apply `b` first, then `a`).
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    r
}

/// The inverse of `m`, or `None` if it is singular (or nearly so, or not finite).
pub fn mat_inverse(m: &Mat3) -> Option<Mat3> {
    // Cofactor expansion; the adjugate's transpose over the determinant.
    let c = |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let cof = [
        [c(1, 2, 1, 2), -c(1, 2, 0, 2), c(1, 2, 0, 1)],
        [-c(0, 2, 1, 2), c(0, 2, 0, 2), -c(0, 2, 0, 1)],
        [c(0, 1, 1, 2), -c(0, 1, 0, 2), c(0, 1, 0, 1)],
    ];
    let det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    if !det.is_finite() || det.abs() <= 1e-12 * scale * scale * scale {
        return None;
    }
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = cof[j][i] / det;
        }
    }
    Some(r)
}

/// `m · v` for an f64 triple.
#[inline]
pub fn mat_apply(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// `m · v` for an f32 triple (the matrix is rounded to f32 first; use [`mat_to_f32`] once
/// and [`mat_apply_f32s`] in hot loops).
#[inline]
pub fn mat_apply_f32(m: &Mat3, v: [f32; 3]) -> [f32; 3] {
    mat_apply_f32s(&mat_to_f32(m), v)
}

/// The matrix rounded to f32, for per-pixel loops.
pub fn mat_to_f32(m: &Mat3) -> [[f32; 3]; 3] {
    m.map(|row| row.map(|v| v as f32))
}

/// `m · v` with an f32 matrix.
#[inline]
pub fn mat_apply_f32s(m: &[[f32; 3]; 3], v: [f32; 3]) -> [f32; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

fn diag(d: [f64; 3]) -> Mat3 {
    [[d[0], 0.0, 0.0], [0.0, d[1], 0.0], [0.0, 0.0, d[2]]]
}

// ---------------------------------------------------------------------------------------------
// RGB <-> XYZ from chromaticities
// ---------------------------------------------------------------------------------------------

impl Chromaticities {
    /// The RGB→XYZ matrix, with the white (R=G=B=1) mapped to Y = 1, or `None` if the
    /// chromaticities are degenerate (collinear primaries, white with y ≤ 0, not finite).
    ///
    /// Computed as in SMPTE RP 177: the primaries' xyz columns scaled so that they sum to the
    /// white point's XYZ. The columns are taken as (x, y, 1-x-y) rather than divided by y, so
    /// primaries with y = 0 (the XYZ "primaries") work too.
    pub fn try_rgb_to_xyz(&self) -> Option<Mat3> {
        let col = |p: [f64; 2]| [p[0], p[1], 1.0 - p[0] - p[1]];
        let (r, g, b) = (col(self.red), col(self.green), col(self.blue));
        let p = [[r[0], g[0], b[0]], [r[1], g[1], b[1]], [r[2], g[2], b[2]]];
        let [wx, wy] = self.white;
        if wy.is_nan() || wy <= 0.0 || !wx.is_finite() || !wy.is_finite() {
            return None;
        }
        let w = xyy_to_xyz([wx, wy, 1.0]);
        let s = mat_apply(&mat_inverse(&p)?, w);
        Some(mat_mul(&p, &diag(s)))
    }

    /// The RGB→XYZ matrix (white → Y = 1). Degenerate chromaticities (see
    /// [`try_rgb_to_xyz`](Self::try_rgb_to_xyz)) give the identity, so that a malformed custom
    /// colour space can never produce NaN pixels; validate untrusted chromaticities first.
    pub fn rgb_to_xyz(&self) -> Mat3 {
        self.try_rgb_to_xyz().unwrap_or(IDENTITY)
    }

    /// The XYZ→RGB matrix, the inverse of [`rgb_to_xyz`](Self::rgb_to_xyz).
    pub fn xyz_to_rgb(&self) -> Mat3 {
        mat_inverse(&self.rgb_to_xyz()).unwrap_or(IDENTITY)
    }

    /// Whether the chromaticities define a usable RGB space.
    pub fn is_valid(&self) -> bool {
        self.try_rgb_to_xyz().is_some()
    }
}

impl ColorPrimaries {
    /// The RGB→XYZ matrix of this space (white → Y = 1).
    pub fn rgb_to_xyz(&self) -> Mat3 {
        match self {
            ColorPrimaries::Xyz => IDENTITY,
            p => p.chromaticities().rgb_to_xyz(),
        }
    }

    /// The XYZ→RGB matrix of this space.
    pub fn xyz_to_rgb(&self) -> Mat3 {
        match self {
            ColorPrimaries::Xyz => IDENTITY,
            p => p.chromaticities().xyz_to_rgb(),
        }
    }
}

/// The luminance weights of an RGB space: the Y row of its RGB→XYZ matrix
/// (0.2126, 0.7152, 0.0722 for BT.709).
pub fn luminance_weights(p: &ColorPrimaries) -> [f64; 3] {
    p.rgb_to_xyz()[1]
}

// ---------------------------------------------------------------------------------------------
// Chromatic adaptation and RGB -> RGB
// ---------------------------------------------------------------------------------------------

/// The Bradford cone-response matrix (Lam 1985, as used by ICC v4 and CIECAM97s). These nine
/// numbers define the transform; they are not derived from anything else.
const BRADFORD: Mat3 = [[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]];

/// The Bradford chromatic adaptation from `src_white` to `dst_white` (xy chromaticities),
/// an XYZ→XYZ matrix: `M⁻¹ · diag(ρσβ_dst / ρσβ_src) · M`.
pub fn bradford(src_white: [f64; 2], dst_white: [f64; 2]) -> Mat3 {
    let src = mat_apply(&BRADFORD, xyy_to_xyz([src_white[0], src_white[1], 1.0]));
    let dst = mat_apply(&BRADFORD, xyy_to_xyz([dst_white[0], dst_white[1], 1.0]));
    let inv = mat_inverse(&BRADFORD).expect("the Bradford matrix is invertible");
    let scale = [dst[0] / src[0], dst[1] / src[1], dst[2] / src[2]];
    if scale.iter().any(|s| !s.is_finite()) {
        return IDENTITY;
    }
    mat_mul(&inv, &mat_mul(&diag(scale), &BRADFORD))
}

/// The linear RGB→RGB matrix from `from` to `to`, through XYZ, with a Bradford adaptation when
/// the white points differ. CIE XYZ ([`ColorPrimaries::Xyz`]) has no adapted white: conversions
/// to or from it are plain colorimetric (no adaptation), as Radiance XYZE and TIFF LogLuv expect.
///
/// Unspecified primaries are taken as BT.709 here (a caller that converts such samples has
/// decided to assume it and says so).
pub fn rgb_to_rgb(from: &ColorPrimaries, to: &ColorPrimaries) -> Mat3 {
    let (from, to) = (&from.or_bt709(), &to.or_bt709());
    if from == to {
        return IDENTITY;
    }
    let (wf, wt) = (from.chromaticities().white, to.chromaticities().white);
    let adapt = if *from != ColorPrimaries::Xyz
        && *to != ColorPrimaries::Xyz
        && ((wf[0] - wt[0]).abs() > 1e-9 || (wf[1] - wt[1]).abs() > 1e-9)
    {
        bradford(wf, wt)
    } else {
        IDENTITY
    };
    mat_mul(&to.xyz_to_rgb(), &mat_mul(&adapt, &from.rgb_to_xyz()))
}

/// The image with its pixels expressed in the primaries `to` (alpha and metadata untouched,
/// `color.primaries` set to `to`). Out-of-gamut colours come out negative; nothing is clipped.
pub fn convert_primaries(image: &HdrImage, to: ColorPrimaries) -> HdrImage {
    let mut out = image.clone();
    if image.color.primaries != to {
        let m = mat_to_f32(&rgb_to_rgb(&image.color.primaries, &to));
        let n = image.channels().count();
        for px in out.samples_mut().chunks_exact_mut(n) {
            let [r, g, b] = mat_apply_f32s(&m, [px[0], px[1], px[2]]);
            px[0] = r;
            px[1] = g;
            px[2] = b;
        }
    }
    out.color.primaries = to;
    out
}

// ---------------------------------------------------------------------------------------------
// xyY, u'v', L u'v'
// ---------------------------------------------------------------------------------------------

/// CIE xyY → XYZ. A chromaticity with y ≤ 0 gives black.
pub fn xyy_to_xyz(xyy: [f64; 3]) -> [f64; 3] {
    let [x, y, big_y] = xyy;
    if y.is_nan() || y <= 0.0 {
        return [0.0; 3];
    }
    [x * big_y / y, big_y, (1.0 - x - y) * big_y / y]
}

/// CIE XYZ → xyY. Black (X+Y+Z = 0) gets the D65 chromaticity, so that it stays neutral.
pub fn xyz_to_xyy(xyz: [f64; 3]) -> [f64; 3] {
    let sum = xyz[0] + xyz[1] + xyz[2];
    if sum == 0.0 || !sum.is_finite() {
        return [D65[0], D65[1], 0.0];
    }
    [xyz[0] / sum, xyz[1] / sum, xyz[1]]
}

/// CIE 1976 UCS chromaticity (u', v') of XYZ: u' = 4X / (X + 15Y + 3Z), v' = 9Y / (X + 15Y + 3Z).
/// Black gets the D65 chromaticity.
pub fn xyz_to_uv_prime(xyz: [f64; 3]) -> [f64; 2] {
    let d = xyz[0] + 15.0 * xyz[1] + 3.0 * xyz[2];
    if d == 0.0 || !d.is_finite() {
        return xy_to_uv_prime(D65);
    }
    [4.0 * xyz[0] / d, 9.0 * xyz[1] / d]
}

/// xy → u'v': u' = 4x / (−2x + 12y + 3), v' = 9y / (−2x + 12y + 3).
pub fn xy_to_uv_prime(xy: [f64; 2]) -> [f64; 2] {
    let d = -2.0 * xy[0] + 12.0 * xy[1] + 3.0;
    [4.0 * xy[0] / d, 9.0 * xy[1] / d]
}

/// u'v' → xy: x = 9u' / (6u' − 16v' + 12), y = 4v' / (6u' − 16v' + 12).
pub fn uv_prime_to_xy(uv: [f64; 2]) -> [f64; 2] {
    let d = 6.0 * uv[0] - 16.0 * uv[1] + 12.0;
    [9.0 * uv[0] / d, 4.0 * uv[1] / d]
}

/// XYZ → (L, u', v') with L = Y, the representation LogLuv encodes.
pub fn xyz_to_luv_prime(xyz: [f64; 3]) -> [f64; 3] {
    let [u, v] = xyz_to_uv_prime(xyz);
    [xyz[1], u, v]
}

/// (L, u', v') → XYZ: X = L·9u' / 4v', Z = L·(12 − 3u' − 20v') / 4v'. v' ≤ 0 gives black.
pub fn luv_prime_to_xyz(luv: [f64; 3]) -> [f64; 3] {
    let [l, u, v] = luv;
    if v.is_nan() || v <= 0.0 {
        return [0.0; 3];
    }
    [l * 9.0 * u / (4.0 * v), l, l * (12.0 - 3.0 * u - 20.0 * v) / (4.0 * v)]
}

// ---------------------------------------------------------------------------------------------
// ICtCp (ITU-R BT.2100, PQ)
// ---------------------------------------------------------------------------------------------

/// BT.2100 Table 7 (ICtCp): linear BT.2020 RGB → LMS, in 1/4096 as the Recommendation gives it.
pub(crate) const RGB2020_TO_LMS: Mat3 = [
    [1688.0 / 4096.0, 2146.0 / 4096.0, 262.0 / 4096.0],
    [683.0 / 4096.0, 2951.0 / 4096.0, 462.0 / 4096.0],
    [99.0 / 4096.0, 309.0 / 4096.0, 3688.0 / 4096.0],
];
/// BT.2100 Table 7: PQ-encoded L'M'S' → ICtCp.
pub(crate) const LMS_P_TO_ICTCP: Mat3 = [
    [0.5, 0.5, 0.0],
    [6610.0 / 4096.0, -13613.0 / 4096.0, 7003.0 / 4096.0],
    [17933.0 / 4096.0, -17390.0 / 4096.0, -543.0 / 4096.0],
];

/// ICtCp (BT.2100, PQ variant) of linear BT.2020 RGB given in cd/m².
/// Negative LMS (far out of gamut) is clamped to 0 before the PQ curve.
pub fn rgb2020_to_ictcp(rgb_nits: [f64; 3]) -> [f64; 3] {
    let lms = mat_apply(&RGB2020_TO_LMS, rgb_nits);
    let lms_p = lms.map(PqTransfer::encode);
    mat_apply(&LMS_P_TO_ICTCP, lms_p)
}

/// Linear BT.2020 RGB in cd/m² of an ICtCp (PQ) triple; the inverse of [`rgb2020_to_ictcp`].
pub fn ictcp_to_rgb2020(ictcp: [f64; 3]) -> [f64; 3] {
    let lms_p = mat_apply(&mat_inverse(&LMS_P_TO_ICTCP).expect("invertible"), ictcp);
    let lms = lms_p.map(PqTransfer::decode);
    mat_apply(&mat_inverse(&RGB2020_TO_LMS).expect("invertible"), lms)
}

/// ΔE ITP of ITU-R BT.2124 between two ICtCp triples:
/// 720 · √(ΔI² + (0.5·ΔCt)² + ΔCp²). One unit is about one just-noticeable difference.
pub fn delta_e_itp_ictcp(a: [f64; 3], b: [f64; 3]) -> f64 {
    let di = a[0] - b[0];
    let dt = 0.5 * (a[1] - b[1]);
    let dp = a[2] - b[2];
    720.0 * (di * di + dt * dt + dp * dp).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Y'CbCr
// ---------------------------------------------------------------------------------------------

/// The luma coefficients Kr and Kb of a non-constant-luminance Y'CbCr (Kg = 1 − Kr − Kb).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YcbcrCoefficients {
    /// Red weight of luma.
    pub kr: f64,
    /// Blue weight of luma.
    pub kb: f64,
}

impl YcbcrCoefficients {
    /// ITU-R BT.709-6 item 3.2: Kr = 0.2126, Kb = 0.0722.
    pub const BT709: Self = YcbcrCoefficients { kr: 0.2126, kb: 0.0722 };
    /// ITU-R BT.2020-2 Table 4: Kr = 0.2627, Kb = 0.0593.
    pub const BT2020: Self = YcbcrCoefficients { kr: 0.2627, kb: 0.0593 };
}

/// Non-linear R'G'B' → Y'CbCr (analogue form: Y' in 0 … 1, Cb and Cr in −0.5 … 0.5):
/// Y' = Kr·R' + Kg·G' + Kb·B', Cb = (B' − Y') / (2(1 − Kb)), Cr = (R' − Y') / (2(1 − Kr)).
pub fn rgb_to_ycbcr(rgb: [f64; 3], k: YcbcrCoefficients) -> [f64; 3] {
    let kg = 1.0 - k.kr - k.kb;
    let y = k.kr * rgb[0] + kg * rgb[1] + k.kb * rgb[2];
    [y, (rgb[2] - y) / (2.0 * (1.0 - k.kb)), (rgb[0] - y) / (2.0 * (1.0 - k.kr))]
}

/// Y'CbCr → non-linear R'G'B', the inverse of [`rgb_to_ycbcr`].
pub fn ycbcr_to_rgb(ycc: [f64; 3], k: YcbcrCoefficients) -> [f64; 3] {
    let kg = 1.0 - k.kr - k.kb;
    let [y, cb, cr] = ycc;
    let r = y + 2.0 * (1.0 - k.kr) * cr;
    let b = y + 2.0 * (1.0 - k.kb) * cb;
    let g = (y - k.kr * r - k.kb * b) / kg;
    [r, g, b]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channels, ColorInfo};

    fn assert_mat(m: &Mat3, want: &Mat3, tol: f64, what: &str) {
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[i][j] - want[i][j]).abs() <= tol, "{what}[{i}][{j}] = {} want {}", m[i][j], want[i][j]);
            }
        }
    }

    #[test]
    fn h273_codes_name_the_standard_primaries() {
        // H.273 Table 2: code 9 is BT.2020's red at (0.708, 0.292), code 12 EG 432-1's D65 P3.
        assert_eq!(ColorPrimaries::from_h273(9).unwrap().chromaticities().red, [0.708, 0.292]);
        assert_eq!(ColorPrimaries::from_h273(12), Some(ColorPrimaries::DisplayP3));
        assert_eq!(ColorPrimaries::from_h273(2), Some(ColorPrimaries::Unspecified));
        for code in [0, 3, 4, 5, 6, 7, 8, 13, 22, 255] {
            assert_eq!(ColorPrimaries::from_h273(code), None, "{code}");
        }
        for p in [ColorPrimaries::Bt709, ColorPrimaries::Bt2020, ColorPrimaries::DciP3, ColorPrimaries::Xyz] {
            assert_eq!(ColorPrimaries::from_h273(p.h273().unwrap()), Some(p));
        }
        assert_eq!(ColorPrimaries::AcesAp0.h273(), None);
    }

    #[test]
    fn bt709_matrix_matches_iec_61966_2_1() {
        // IEC 61966-2-1 (sRGB) section 5.2, the four-decimal RGB→XYZ matrix.
        let want = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
        assert_mat(&ColorPrimaries::Bt709.rgb_to_xyz(), &want, 6e-5, "709");
        // The luminance weights of the PU21 reference code (get_luminance in pu21_metric.m) are
        // this row computed with a slightly different D65 (they differ in the fifth decimal).
        let w = luminance_weights(&ColorPrimaries::Bt709);
        assert_mat(&[w, w, w], &[[0.212656, 0.715158, 0.072186]; 3], 2e-5, "709 Y");
    }

    #[test]
    fn bt2020_matrices_match_bt2087() {
        // ITU-R BT.2020-2 Table 4: luma weights Kr = 0.2627, Kb = 0.0593 (Kg = 0.6780).
        let w = luminance_weights(&ColorPrimaries::Bt2020);
        assert_mat(&[w, w, w], &[[0.2627, 0.6780, 0.0593]; 3], 6e-5, "2020 Y");
        // ITU-R BT.2087-0 Annex 1: XYZ → BT.2020 RGB and the linear BT.709 → BT.2020 matrix.
        let xyz_to_2020 = [[1.7167, -0.3557, -0.2534], [-0.6667, 1.6165, 0.0158], [0.0176, -0.0428, 0.9421]];
        assert_mat(&ColorPrimaries::Bt2020.xyz_to_rgb(), &xyz_to_2020, 6e-5, "XYZ→2020");
        let m709_2020 = [[0.6274, 0.3293, 0.0433], [0.0691, 0.9195, 0.0114], [0.0164, 0.0880, 0.8956]];
        assert_mat(&rgb_to_rgb(&ColorPrimaries::Bt709, &ColorPrimaries::Bt2020), &m709_2020, 6e-5, "709→2020");
        // White maps to white in every named space (rows of rgb_to_rgb sum to 1).
        let m = rgb_to_rgb(&ColorPrimaries::AcesAp0, &ColorPrimaries::DisplayP3);
        assert_mat(&[mat_apply(&m, [1.0; 3]); 3], &[[1.0; 3]; 3], 1e-12, "white");
    }

    #[test]
    fn bradford_d65_to_d50_matches_css_color_4() {
        // W3C CSS Color Module Level 4, sample code D65_to_D50 (Bradford, D65 = (0.3127, 0.3290),
        // D50 = (0.3457, 0.3585)).
        let want = [
            [1.0479298208405488, 0.022946793341019088, -0.05019222954313557],
            [0.029627815688159344, 0.990434484573249, -0.01707382502938514],
            [-0.009243058152591178, 0.015055144896577895, 0.7518742899580008],
        ];
        assert_mat(&bradford(D65, [0.3457, 0.3585]), &want, 1e-6, "Bradford");
        assert_mat(&bradford(D65, D65), &IDENTITY, 1e-12, "Bradford identity");
    }

    #[test]
    fn xyz_space_and_degenerate_primaries() {
        assert_mat(&ColorPrimaries::Xyz.rgb_to_xyz(), &IDENTITY, 0.0, "XYZ");
        // The generic derivation agrees for the XYZ "primaries" (y = 0 for red and blue).
        assert_mat(&ColorPrimaries::Xyz.chromaticities().rgb_to_xyz(), &IDENTITY, 1e-12, "XYZ generic");
        let bad = Chromaticities { red: [0.3, 0.3], green: [0.4, 0.4], blue: [0.5, 0.5], white: D65 };
        assert!(!bad.is_valid());
        assert_eq!(bad.rgb_to_xyz(), IDENTITY);
        let m = ColorPrimaries::DciP3.rgb_to_xyz();
        assert_mat(&mat_mul(&m, &ColorPrimaries::DciP3.xyz_to_rgb()), &IDENTITY, 1e-12, "inverse");
    }

    #[test]
    fn chromaticity_coordinates() {
        // CIE 15:2004 Table T.3: D65 u' = 0.1978, v' = 0.4683.
        let uv = xy_to_uv_prime(D65);
        assert!((uv[0] - 0.1978).abs() < 5e-5 && (uv[1] - 0.4683).abs() < 5e-5, "{uv:?}");
        let xyz = xyy_to_xyz([D65[0], D65[1], 1.0]);
        let uv2 = xyz_to_uv_prime(xyz);
        assert!((uv2[0] - uv[0]).abs() < 1e-12 && (uv2[1] - uv[1]).abs() < 1e-12);
        let xy = uv_prime_to_xy(uv);
        assert!((xy[0] - D65[0]).abs() < 1e-12 && (xy[1] - D65[1]).abs() < 1e-12);
        let back = xyz_to_xyy(xyz);
        assert!((back[0] - D65[0]).abs() < 1e-12 && (back[2] - 1.0).abs() < 1e-12);
        let luv = xyz_to_luv_prime([0.3, 0.2, 0.7]);
        let x = luv_prime_to_xyz(luv);
        assert_mat(&[x; 3], &[[0.3, 0.2, 0.7]; 3], 1e-12, "Lu'v'");
        assert_eq!(xyz_to_xyy([0.0; 3]), [D65[0], D65[1], 0.0]);
    }

    #[test]
    fn ictcp_matches_reference_outputs() {
        // colour-science RGB_to_ICtCp docs example (Dolby 2016 / BT.2100 PQ, L_p = 10 000,
        // RGB in cd/m²): [0.45620519, 0.03081071, 0.04091952] → [0.0735136, 0.0047525, 0.0935159].
        let ictcp = rgb2020_to_ictcp([0.456_205_19, 0.030_810_71, 0.040_919_52]);
        assert_mat(&[ictcp; 3], &[[0.073_513_6, 0.004_752_5, 0.093_515_9]; 3], 1e-7, "ICtCp");
        let rgb = ictcp_to_rgb2020(ictcp);
        assert_mat(&[rgb; 3], &[[0.456_205_19, 0.030_810_71, 0.040_919_52]; 3], 1e-9, "inverse");
        // BT.2100: neutral colours have Ct = Cp = 0, and I is the PQ of the luminance.
        let grey = rgb2020_to_ictcp([100.0; 3]);
        assert!(grey[1].abs() < 1e-12 && grey[2].abs() < 1e-12);
        assert!((grey[0] - PqTransfer::encode(100.0)).abs() < 1e-12);
    }

    #[test]
    fn delta_e_itp_matches_reference_output() {
        // colour-science delta_E_ITP docs example (ITU-R BT.2124): 1.42657228...
        let a = [0.488_546_807_2, -0.047_393_506_75, 0.074_754_013_02];
        let b = [0.489_920_323_1, -0.045_675_082_03, 0.073_613_417_75];
        assert!((delta_e_itp_ictcp(a, b) - 1.426_572_28).abs() < 1e-8);
        assert_eq!(delta_e_itp_ictcp(a, a), 0.0);
    }

    #[test]
    fn ycbcr_matches_the_recommendations() {
        // BT.709-6 item 3.3: Cb = (B′ − Y′)/1.8556, Cr = (R′ − Y′)/1.5748;
        // BT.2020-2 Table 4: Cb = (B′ − Y′)/1.8814, Cr = (R′ − Y′)/1.4746.
        for (k, db, dr) in [(YcbcrCoefficients::BT709, 1.8556, 1.5748), (YcbcrCoefficients::BT2020, 1.8814, 1.4746)] {
            let rgb = [0.8, 0.3, 0.55];
            let [y, cb, cr] = rgb_to_ycbcr(rgb, k);
            assert!((cb - (rgb[2] - y) / db).abs() < 1e-12);
            assert!((cr - (rgb[0] - y) / dr).abs() < 1e-12);
            // Saturated primaries reach the ±0.5 limits.
            assert!((rgb_to_ycbcr([1.0, 0.0, 0.0], k)[2] - 0.5).abs() < 1e-12);
            assert!((rgb_to_ycbcr([0.0, 0.0, 1.0], k)[1] - 0.5).abs() < 1e-12);
            let back = ycbcr_to_rgb([y, cb, cr], k);
            assert_mat(&[back; 3], &[rgb; 3], 1e-12, "Y'CbCr");
        }
    }

    #[test]
    fn convert_primaries_keeps_alpha_and_round_trips() {
        let samples = vec![1.0, 0.5, 0.25, 0.7, 0.0, 2.0, 8.0, 0.3];
        let img = HdrImage::new(2, 1, Channels::Rgba, samples.clone(), ColorInfo::default()).unwrap();
        let wide = convert_primaries(&img, ColorPrimaries::Bt2020);
        assert_eq!(wide.color.primaries, ColorPrimaries::Bt2020);
        assert_eq!(wide.samples()[3], 0.7);
        assert_eq!(wide.samples()[7], 0.3);
        let m = rgb_to_rgb(&ColorPrimaries::Bt709, &ColorPrimaries::Bt2020);
        let want = mat_apply(&m, [1.0, 0.5, 0.25]);
        assert!((wide.samples()[0] as f64 - want[0]).abs() < 1e-6);
        let back = convert_primaries(&wide, ColorPrimaries::Bt709);
        for (a, b) in back.samples().iter().zip(&samples) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
    }
}
