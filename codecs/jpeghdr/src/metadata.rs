//! Gain-map metadata in one model, ISO 21496-1's (clause 5): the Adobe/Ultra HDR XMP fields
//! and Apple's headroom are translated into it, and the ISO binary record (APP2
//! `urn:iso:std:iso:ts:21496:-1`) is read and written from it.
//!
//! Everything is as the standard counts it: headrooms, gain minimum and maximum in log2 stops;
//! gamma and offsets linear. "Base" is the image every viewer shows (the primary JPEG);
//! "alternate" the rendition the gain map leads to.

use hdrcodec_core::{Error, Result};

/// The APP2 payload signature of an ISO 21496-1 record.
pub const ISO_SIGNATURE: &[u8] = b"urn:iso:std:iso:ts:21496:-1\0";

/// Gain-map metadata (ISO 21496-1 clause 5.2), per channel where the standard allows it.
#[derive(Clone, Debug, PartialEq)]
pub struct GainMapMetadata {
    /// Headroom of the base image, log2 (0 for an SDR base).
    pub base_headroom: f64,
    /// Headroom of the alternate (HDR for an SDR base) rendition, log2.
    pub alternate_headroom: f64,
    /// Gain of a map code of 0, log2, per channel (R, G, B).
    pub gain_min: [f64; 3],
    /// Gain of a map code of 255, log2, per channel.
    pub gain_max: [f64; 3],
    /// The map's gamma, per channel: a code `c` means `(c / 255)^(1 / gamma)` of the range.
    pub gamma: [f64; 3],
    /// Offset added to the base's linear value before the gain, per channel.
    pub base_offset: [f64; 3],
    /// Offset subtracted from the result, per channel.
    pub alternate_offset: [f64; 3],
    /// True when the three channels' values may differ (the record's `is_multichannel`).
    pub multichannel: bool,
    /// True when the gain applies in the base image's colour space (false: in the gain map's
    /// own, as its ICC profile says).
    pub use_base_colour_space: bool,
}

impl GainMapMetadata {
    /// The weight of the gain for a display of `headroom` (log2 of HDR white over SDR white):
    /// 0 gives the base rendition, 1 the alternate; negative when the base is the HDR one
    /// (ISO 21496-1 5.3.3: the gain is divided out as the display's headroom falls).
    pub fn weight(&self, headroom: f64) -> f64 {
        let span = self.alternate_headroom - self.base_headroom;
        if span == 0.0 {
            // No headroom between the two renditions: nothing to adapt (as libavif).
            return 0.0;
        }
        let w = ((headroom - self.base_headroom) / span).clamp(0.0, 1.0);
        if span < 0.0 {
            -w
        } else {
            w
        }
    }

    /// The weight that gives the most HDR rendition the file describes: 1 with an SDR base
    /// (full gain), 0 with an HDR base (the base itself).
    pub fn full_hdr_weight(&self) -> f64 {
        if self.alternate_headroom >= self.base_headroom {
            1.0
        } else {
            0.0
        }
    }

    /// The headrooms and ranges in words, for `hdrcodec info`: (headroom, gain) lines.
    pub fn describe(&self) -> (String, String) {
        let stops = |s: f64| format!("{s:.3} stops (x{:.2})", s.exp2());
        let headroom = match (self.base_headroom, self.alternate_headroom) {
            (0.0, alt) => format!("HDR rendition {} above an SDR base", stops(alt)),
            (base, alt) => format!("base {}, alternate rendition {}", stops(base), stops(alt)),
        };
        // One value when the channels agree, else R/G/B.
        let per_channel = |v: &[f64; 3]| {
            if v.iter().all(|&x| x == v[0]) {
                format!("{:.4}", v[0])
            } else {
                v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join("/")
            }
        };
        let gain = format!(
            "log2 gain {} to {}, gamma {}, offsets {} (base) {} (alternate)",
            per_channel(&self.gain_min),
            per_channel(&self.gain_max),
            per_channel(&self.gamma),
            per_channel(&self.base_offset),
            per_channel(&self.alternate_offset)
        );
        (headroom, gain)
    }

    pub(crate) fn check(&self) -> Result<()> {
        let finite = [self.base_headroom, self.alternate_headroom]
            .iter()
            .chain(&self.gain_min)
            .chain(&self.gain_max)
            .chain(&self.gamma)
            .chain(&self.base_offset)
            .chain(&self.alternate_offset)
            .all(|v| v.is_finite());
        if !finite {
            return Err(Error::invalid("gain map metadata: a value is not finite"));
        }
        if self.gamma.iter().any(|&g| g <= 0.0) {
            return Err(Error::invalid("gain map metadata: gamma must be positive"));
        }
        if (0..3).any(|c| self.gain_max[c] < self.gain_min[c]) {
            return Err(Error::invalid("gain map metadata: gain max below gain min"));
        }
        Ok(())
    }

    /// Reads an ISO 21496-1 record (signature removed). `Ok(None)` for the version-only record
    /// a primary image carries (4 bytes: it only says to look in the gain map).
    pub fn from_iso(record: &[u8]) -> Result<Option<Self>> {
        let bad = |what: &str| Error::invalid(format!("ISO 21496-1 gain map metadata: {what}"));
        let mut r = Reader { data: record, pos: 0 };
        let min_version = r.u16().ok_or_else(|| bad("truncated"))?;
        let _writer_version = r.u16().ok_or_else(|| bad("truncated"))?;
        if min_version != 0 {
            return Err(Error::unsupported(format!("ISO 21496-1 gain map metadata of minimum version {min_version}")));
        }
        if r.pos == record.len() {
            return Ok(None);
        }
        let flags = r.u8().ok_or_else(|| bad("truncated"))?;
        let multichannel = flags & 0x80 != 0;
        let use_base_colour_space = flags & 0x40 != 0;
        let common_denominator = flags & 0x08 != 0;
        let backward = flags & 0x04 != 0;
        let channels = if multichannel { 3 } else { 1 };
        let mut m = GainMapMetadata {
            base_headroom: 0.0,
            alternate_headroom: 0.0,
            gain_min: [0.0; 3],
            gain_max: [0.0; 3],
            gamma: [1.0; 3],
            base_offset: [0.0; 3],
            alternate_offset: [0.0; 3],
            multichannel,
            use_base_colour_space,
        };
        let truncated = || bad("truncated");
        if common_denominator {
            let d = r.u32().ok_or_else(truncated)?;
            if d == 0 {
                return Err(bad("a denominator is zero"));
            }
            let d = f64::from(d);
            m.base_headroom = f64::from(r.u32().ok_or_else(truncated)?) / d;
            m.alternate_headroom = f64::from(r.u32().ok_or_else(truncated)?) / d;
            for c in 0..channels {
                m.gain_min[c] = f64::from(r.i32().ok_or_else(truncated)?) / d;
                m.gain_max[c] = f64::from(r.i32().ok_or_else(truncated)?) / d;
                m.gamma[c] = f64::from(r.u32().ok_or_else(truncated)?) / d;
                m.base_offset[c] = f64::from(r.i32().ok_or_else(truncated)?) / d;
                m.alternate_offset[c] = f64::from(r.i32().ok_or_else(truncated)?) / d;
            }
        } else {
            m.base_headroom = r.unsigned_fraction().ok_or_else(truncated)??;
            m.alternate_headroom = r.unsigned_fraction().ok_or_else(truncated)??;
            for c in 0..channels {
                m.gain_min[c] = r.signed_fraction().ok_or_else(truncated)??;
                m.gain_max[c] = r.signed_fraction().ok_or_else(truncated)??;
                m.gamma[c] = r.unsigned_fraction().ok_or_else(truncated)??;
                m.base_offset[c] = r.signed_fraction().ok_or_else(truncated)??;
                m.alternate_offset[c] = r.signed_fraction().ok_or_else(truncated)??;
            }
        }
        if !multichannel {
            for v in [&mut m.gain_min, &mut m.gain_max, &mut m.gamma, &mut m.base_offset, &mut m.alternate_offset] {
                v[1] = v[0];
                v[2] = v[0];
            }
        }
        // The flag says which rendition is the HDR one; the headrooms say it too, and readers
        // (Skia, libavif) go by the headrooms. A record whose two disagree is broken.
        if backward && m.alternate_headroom > m.base_headroom {
            return Err(bad("backward direction with an alternate headroom above the base's"));
        }
        m.check()?;
        Ok(Some(m))
    }

    /// The full ISO 21496-1 record (signature not included), in the form every reader takes:
    /// separate fractions, backward-direction and common-denominator flags clear. Fractions
    /// have denominator 2^20 (|x| < 2048 stops or linear units, far beyond real metadata), or a
    /// larger power of two for a small value that would keep fewer than 10 bits (a positive
    /// gamma must not round to 0).
    pub fn to_iso(&self) -> Vec<u8> {
        let channels = if self.multichannel { 3 } else { 1 };
        let mut out = Vec::with_capacity(21 + 40 * channels);
        out.extend(0u16.to_be_bytes());
        out.extend(0u16.to_be_bytes());
        out.push(if self.multichannel { 0x80 } else { 0 } | if self.use_base_colour_space { 0x40 } else { 0 });
        let unsigned = |out: &mut Vec<u8>, v: f64| {
            let (num, den) = to_fraction(v.max(0.0), f64::from(u32::MAX));
            out.extend((num as u32).to_be_bytes());
            out.extend(den.to_be_bytes());
        };
        let signed = |out: &mut Vec<u8>, v: f64| {
            let (num, den) = to_fraction(v, f64::from(i32::MAX));
            out.extend((num as i32).to_be_bytes());
            out.extend(den.to_be_bytes());
        };
        unsigned(&mut out, self.base_headroom);
        unsigned(&mut out, self.alternate_headroom);
        for c in 0..channels {
            signed(&mut out, self.gain_min[c]);
            signed(&mut out, self.gain_max[c]);
            unsigned(&mut out, self.gamma[c]);
            signed(&mut out, self.base_offset[c]);
            signed(&mut out, self.alternate_offset[c]);
        }
        out
    }

    /// The version-only record a primary image carries (signature not included).
    pub fn iso_version_record() -> [u8; 4] {
        [0, 0, 0, 0]
    }
}

/// `v` as numerator / denominator for the ISO record: denominator 2^20, raised (by powers of
/// two, up to 2^31) while the numerator would keep fewer than 10 bits of a non-zero `v`; the
/// numerator rounded, at least 1 in magnitude for a non-zero `v`, and within ±`max`.
fn to_fraction(v: f64, max: f64) -> (f64, u32) {
    let mut den: u32 = 1 << 20;
    while v != 0.0 && (v * f64::from(den)).abs() < 1024.0 && den < 1 << 31 {
        den <<= 1;
    }
    let mut num = (v * f64::from(den)).round();
    if num == 0.0 && v != 0.0 {
        num = v.signum();
    }
    (num.clamp(-max - 1.0, max), den)
}

/// Big-endian reads from a record.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let b = self.data.get(self.pos..self.pos + N)?.try_into().ok()?;
        self.pos += N;
        Some(b)
    }
    fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_be_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_be_bytes)
    }
    fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_be_bytes)
    }
    /// A u32 / u32 fraction; `Some(Err)` for a zero denominator.
    fn unsigned_fraction(&mut self) -> Option<Result<f64>> {
        let (n, d) = (self.u32()?, self.u32()?);
        Some(fraction(f64::from(n), d))
    }
    /// An s32 / u32 fraction.
    fn signed_fraction(&mut self) -> Option<Result<f64>> {
        let (n, d) = (self.i32()?, self.u32()?);
        Some(fraction(f64::from(n), d))
    }
}

fn fraction(n: f64, d: u32) -> Result<f64> {
    if d == 0 {
        return Err(Error::invalid("ISO 21496-1 gain map metadata: a denominator is zero"));
    }
    Ok(n / f64::from(d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn describe_names_headrooms_and_per_channel_ranges() {
        let (headroom, gain) = sample(false).describe();
        assert_eq!(headroom, "HDR rendition 2.500 stops (x5.66) above an SDR base");
        assert_eq!(gain, "log2 gain -0.2500 to 2.5000, gamma 1.0000, offsets 0.0156 (base) 0.0156 (alternate)");
        let (_, gain) = sample(true).describe();
        assert!(gain.starts_with("log2 gain -0.2500/-0.5000/-0.2500 to 2.5000/2.0000/2.5000,"), "{gain}");
        let hdr_base = GainMapMetadata { base_headroom: 3.0, alternate_headroom: 0.0, ..sample(false) };
        assert_eq!(hdr_base.describe().0, "base 3.000 stops (x8.00), alternate rendition 0.000 stops (x1.00)");
    }

    fn sample(multichannel: bool) -> GainMapMetadata {
        GainMapMetadata {
            base_headroom: 0.0,
            alternate_headroom: 2.5,
            gain_min: [-0.25, if multichannel { -0.5 } else { -0.25 }, -0.25],
            gain_max: [2.5, if multichannel { 2.0 } else { 2.5 }, 2.5],
            gamma: [1.0; 3],
            base_offset: [1.0 / 64.0; 3],
            alternate_offset: [1.0 / 64.0; 3],
            multichannel,
            use_base_colour_space: true,
        }
    }

    #[test]
    fn iso_record_round_trips() {
        for multichannel in [false, true] {
            let m = sample(multichannel);
            let record = m.to_iso();
            assert_eq!(record.len(), if multichannel { 141 } else { 61 });
            assert_eq!(GainMapMetadata::from_iso(&record).unwrap(), Some(m));
            for n in 5..record.len() {
                assert!(GainMapMetadata::from_iso(&record[..n]).is_err(), "{n}");
            }
        }
        assert_eq!(GainMapMetadata::from_iso(&GainMapMetadata::iso_version_record()).unwrap(), None);
        assert!(GainMapMetadata::from_iso(&[0, 1, 0, 0]).is_err());
        // Small values keep their precision (a positive gamma of 2^-25 is not written as 0:
        // found by the jpeg_metadata fuzz target), large ones their range.
        let tiny = GainMapMetadata { gamma: [2f64.powi(-25); 3], gain_min: [-1e-6; 3], ..sample(false) };
        let back = GainMapMetadata::from_iso(&tiny.to_iso()).unwrap().unwrap();
        assert_eq!(back.gamma, tiny.gamma);
        assert!((back.gain_min[0] + 1e-6).abs() < 1e-9, "{:?}", back.gain_min);
        let huge = GainMapMetadata {
            alternate_headroom: 4000.0,
            gain_min: [-2000.0; 3],
            gain_max: [2000.0; 3],
            ..sample(false)
        };
        let back = GainMapMetadata::from_iso(&huge.to_iso()).unwrap().unwrap();
        assert_eq!((back.alternate_headroom, back.gain_min[0], back.gain_max[0]), (4000.0, -2000.0, 2000.0));
    }

    #[test]
    fn common_denominator_form_reads() {
        // libultrahdr's compact form: denominator 4, base headroom 0, alternate 10/4, one
        // channel: min 0, max 8/4, gamma 4/4, offsets 0.
        let mut r = vec![0, 0, 0, 0, 0x08];
        for v in [4u32, 0, 10, 0, 8, 4, 0, 0] {
            r.extend(v.to_be_bytes());
        }
        let m = GainMapMetadata::from_iso(&r).unwrap().unwrap();
        assert_eq!((m.alternate_headroom, m.gain_max, m.gamma), (2.5, [2.0; 3], [1.0; 3]));
    }

    #[test]
    fn weight_follows_the_display_headroom() {
        let m = sample(false);
        assert_eq!((m.weight(0.0), m.weight(1.25), m.weight(5.0)), (0.0, 0.5, 1.0));
        let hdr_base = GainMapMetadata { base_headroom: 2.5, alternate_headroom: 0.0, ..m };
        assert_eq!((hdr_base.weight(2.5), hdr_base.weight(1.25), hdr_base.weight(0.0)), (-0.0, -0.5, -1.0));
        assert_eq!(hdr_base.full_hdr_weight(), 0.0);
    }
}
