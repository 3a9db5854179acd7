//! HDR10 static metadata: SMPTE ST 2086 mastering display colour volume and the CTA-861.3
//! content light level (MaxCLL, MaxFALL).

/// SMPTE ST 2086 mastering display colour volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasteringDisplay {
    /// Display primaries (x, y) in the order red, green, blue.
    pub primaries: [[f64; 2]; 3],
    /// Display white point (x, y).
    pub white: [f64; 2],
    /// Maximum display luminance, cd/m².
    pub max_luminance: f64,
    /// Minimum display luminance, cd/m².
    pub min_luminance: f64,
}

/// CTA-861.3 content light level, in whole cd/m² as the standard carries them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ContentLightLevel {
    /// MaxCLL: the largest max(R,G,B) of any pixel of any frame, in nits.
    pub max_cll: u16,
    /// MaxFALL: the largest frame average of max(R,G,B), in nits.
    pub max_fall: u16,
}

/// HDR10 static metadata as carried by video and image containers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Hdr10Metadata {
    /// Mastering display colour volume, if known.
    pub mastering_display: Option<MasteringDisplay>,
    /// Content light level, if known.
    pub content_light_level: Option<ContentLightLevel>,
}
