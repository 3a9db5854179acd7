//! Colour: primaries and white points, and (computed from them, never typed in) the
//! RGB↔XYZ matrices; chromatic adaptation and the colour spaces the metrics use.

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
#[derive(Clone, Copy, Debug, PartialEq)]
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
}

impl ColorPrimaries {
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
        }
    }

    /// The named space with exactly these chromaticities, else `Custom`.
    pub fn from_chromaticities(ch: Chromaticities) -> Self {
        const NAMED: [ColorPrimaries; 8] = [
            ColorPrimaries::Bt709,
            ColorPrimaries::Bt2020,
            ColorPrimaries::DisplayP3,
            ColorPrimaries::DciP3,
            ColorPrimaries::AcesAp0,
            ColorPrimaries::AcesAp1,
            ColorPrimaries::AdobeRgb,
            ColorPrimaries::Xyz,
        ];
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 5e-4 && (a[1] - b[1]).abs() < 5e-4;
        for p in NAMED {
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
        }
    }
}
