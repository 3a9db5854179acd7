//! AV1 HDR10 through FFmpeg's SVT-AV1 wrapper (`ffmpeg -c:v libsvtav1`, Debian `ffmpeg`): the
//! peer of our video rows ([`crate::video_bench`]). FFmpeg's rav1e wrapper rejects HDR keys and
//! libaom writes none; SVT-AV1 writes the colour description, the mastering display and the
//! content light level (`../shared/REFERENCES.md`, row "AV1 + HDR10").
//!
//! Both encoders see the same Y'CbCr: our encoder's own conversion
//! ([`hdrcodec_video::hdr10::frame_to_yuv`]: BT.2020 non-constant luminance, PQ, 10-bit
//! limited range, 4:2:0 co-sited with the top-left luma sample) written as raw
//! `yuv420p10le` for FFmpeg, which is told the same (`-color_primaries bt2020 -color_trc
//! smpte2084 -colorspace bt2020nc -color_range tv`, SVT's `chroma-sample-position=topleft`).
//! FFmpeg decoding a stream (`-c:v libdav1d`) back to raw `yuv420p10le` is the peer decode.

use hdrcodec::core::{ContentLightLevel, Error, HdrImage, MasteringDisplay, Result};
use hdrcodec_video::hdr10::{frame_to_yuv, Range, Subsampling, Transfer, YuvFrame};
use std::ffi::OsString;
use std::path::Path;

/// FFmpeg's program.
pub const PROGRAM: &str = "ffmpeg";
/// Where it comes from, for "not installed" messages.
pub const PACKAGE: &str = "Debian ffmpeg";
/// FFmpeg's name of the SVT-AV1 encoder.
pub const ENCODER: &str = "libsvtav1";
/// FFmpeg's name of the dav1d decoder.
pub const DECODER: &str = "libdav1d";
/// SVT-AV1's preset (0 slowest .. 13 fastest) in the rows.
pub const PRESET: u8 = 8;

/// "ffmpeg 5.1.9-0+deb12u1" from `ffmpeg -version`'s first line.
pub fn ffmpeg_version() -> String {
    let text = super::version_text(PROGRAM, "-version").unwrap_or_default();
    let version =
        text.lines().find_map(|l| l.trim().strip_prefix("ffmpeg version ")).and_then(|v| v.split_whitespace().next());
    version.map_or_else(|| format!("{PROGRAM} (version unknown)"), |v| format!("{PROGRAM} {v}"))
}

/// Whether the FFmpeg on PATH lists the SVT-AV1 encoder and the dav1d decoder (`None`: it has
/// both; otherwise which it lacks).
pub fn missing_codecs() -> Option<String> {
    let encoders = super::version_text(PROGRAM, "-encoders").unwrap_or_default();
    let decoders = super::version_text(PROGRAM, "-decoders").unwrap_or_default();
    let has = |text: &str, name: &str| text.split_whitespace().any(|w| w == name);
    let missing: Vec<&str> =
        [(&encoders, ENCODER), (&decoders, DECODER)].into_iter().filter(|(t, n)| !has(t, n)).map(|(_, n)| n).collect();
    (!missing.is_empty()).then(|| missing.join(" and "))
}

/// SVT-AV1's library version from what an encode printed on stderr ("SVT [version]: SVT-AV1
/// Encoder Lib v1.4.1"): "v1.4.1".
pub fn svt_version(stderr: &str) -> Option<String> {
    let at = stderr.find("SVT-AV1 Encoder Lib ")? + "SVT-AV1 Encoder Lib ".len();
    stderr[at..].split_whitespace().next().map(|v| v.split("Svt[").next().unwrap_or(v).to_string())
}

/// SVT-AV1's `mastering-display` value: `G(x,y)B(x,y)R(x,y)WP(x,y)L(max,min)` (chromaticities
/// and cd/m²; green first, as SVT-AV1 and x265 spell it).
pub fn mastering_display_param(md: &MasteringDisplay) -> String {
    let xy = |p: [f64; 2]| format!("({},{})", p[0], p[1]);
    let [r, g, b] = md.primaries;
    format!("G{}B{}R{}WP{}L({},{})", xy(g), xy(b), xy(r), xy(md.white), md.max_luminance, md.min_luminance)
}

/// FFmpeg's arguments: raw 10-bit 4:2:0 `input` (`width` × `height` at `fps`) to the IVF
/// `output` with SVT-AV1 at `crf` (0-63) and [`PRESET`], on one thread (`lp=1`, `-threads 1`),
/// HDR10 signalled: BT.2020, PQ, limited range, top-left chroma, `md`, `cll`.
pub fn encode_args(
    input: &Path,
    output: &Path,
    (width, height, fps): (u32, u32, u32),
    crf: u8,
    md: &MasteringDisplay,
    cll: ContentLightLevel,
) -> Vec<OsString> {
    let params = format!(
        "lp=1:chroma-sample-position=topleft:mastering-display={}:content-light={},{}",
        mastering_display_param(md),
        cll.max_cll,
        cll.max_fall
    );
    let (size, fps, crf, preset) = (format!("{width}x{height}"), fps.to_string(), crf.to_string(), PRESET.to_string());
    let head = ["-hide_banner", "-nostdin", "-y", "-f", "rawvideo", "-pix_fmt", "yuv420p10le", "-s"];
    let mut args: Vec<OsString> = head.into_iter().map(OsString::from).collect();
    args.extend(super::args(&[
        &size, &"-r", &fps, &"-i", &input, &"-c:v", &ENCODER, &"-preset", &preset, &"-crf", &crf,
    ]));
    args.extend(super::args(&[&"-svtav1-params", &params, &"-threads", &"1"]));
    let colour =
        ["-color_primaries", "bt2020", "-color_trc", "smpte2084", "-colorspace", "bt2020nc", "-color_range", "tv"];
    args.extend(colour.into_iter().map(OsString::from));
    args.extend(super::args(&[&"-f", &"ivf", &output]));
    args
}

/// FFmpeg's arguments: the AV1 `input` decoded by libdav1d on one thread to raw
/// `yuv420p10le` in `output`.
pub fn decode_args(input: &Path, output: &Path) -> Vec<OsString> {
    let head = ["-hide_banner", "-nostdin", "-y", "-threads", "1", "-c:v", DECODER, "-i"];
    let mut args: Vec<OsString> = head.into_iter().map(OsString::from).collect();
    args.extend(super::args(&[&input, &"-f", &"rawvideo", &"-pix_fmt", &"yuv420p10le", &output]));
    args
}

/// The frames as our encoder codes them (PQ, limited range, 4:2:0), as raw `yuv420p10le`
/// (each frame's Y', Cb, Cr planes, 16-bit little-endian codes), and the samples the PQ policy
/// clipped.
pub fn raw_yuv(frames: &[HdrImage]) -> (Vec<u8>, u64) {
    let mut out = Vec::new();
    let mut clipped = 0;
    for frame in frames {
        let (yuv, report) = frame_to_yuv(frame, Transfer::Pq, Range::Limited, Subsampling::Yuv420);
        clipped += report.nan + report.negative + report.above_peak;
        push_planes(&yuv, &mut out);
    }
    (out, clipped)
}

/// Appends `yuv`'s planes as 16-bit little-endian codes.
pub fn push_planes(yuv: &YuvFrame, out: &mut Vec<u8>) {
    for plane in [&yuv.y, &yuv.cb, &yuv.cr] {
        out.extend(plane.iter().flat_map(|c| c.to_le_bytes()));
    }
}

/// Checks that raw `yuv420p10le` of `frames` frames of `width` × `height` has exactly that
/// many bytes.
pub fn check_raw_size(data: &[u8], width: usize, height: usize, frames: usize) -> Result<()> {
    let (cw, ch) = YuvFrame::chroma_size(width, height, Subsampling::Yuv420);
    let expected = frames * 2 * (width * height + 2 * cw * ch);
    if data.len() != expected {
        return Err(Error::invalid(format!(
            "ffmpeg decoded {} bytes of yuv420p10le, not the {expected} of {frames} {width}x{height} frames",
            data.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::{Channels, ColorInfo, ColorPrimaries};

    #[test]
    fn the_command_line_signals_hdr10() {
        let md = MasteringDisplay::bt2020(1000.0, 0.0001);
        let cll = ContentLightLevel { max_cll: 4000, max_fall: 120 };
        let args = encode_args(Path::new("in.yuv"), Path::new("out.ivf"), (128, 72, 25), 35, &md, cll);
        let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(
            args.join(" "),
            "-hide_banner -nostdin -y -f rawvideo -pix_fmt yuv420p10le -s 128x72 -r 25 -i in.yuv -c:v libsvtav1 \
             -preset 8 -crf 35 -svtav1-params lp=1:chroma-sample-position=topleft:mastering-display=\
             G(0.17,0.797)B(0.131,0.046)R(0.708,0.292)WP(0.3127,0.329)L(1000,0.0001):content-light=4000,120 \
             -threads 1 -color_primaries bt2020 -color_trc smpte2084 -colorspace bt2020nc -color_range tv -f ivf out.ivf"
        );
    }

    #[test]
    fn the_svt_version_is_read_from_its_banner() {
        let banner = "Svt[info]: SVT [version]:\tSVT-AV1 Encoder Lib v1.4.1Svt[info]: ---\nSvt[info]: SVT [build]";
        assert_eq!(svt_version(banner).as_deref(), Some("v1.4.1"));
        assert_eq!(svt_version("Svt[info]: SVT [version]:\tSVT-AV1 Encoder Lib v2.0.0\n").as_deref(), Some("v2.0.0"));
        assert_eq!(svt_version("no banner"), None);
    }

    #[test]
    fn raw_yuv_has_the_planes_ffmpeg_expects() {
        let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None };
        // 4x2: 8 luma and 2 + 2 chroma codes per frame; one sample of 200 units (20000 cd/m²)
        // is above PQ's peak.
        let mut samples = vec![1.0f32; 24];
        samples[0] = 200.0;
        let frame = HdrImage::new(4, 2, Channels::Rgb, samples, color).unwrap();
        let (raw, clipped) = raw_yuv(&[frame.clone(), frame]);
        assert_eq!(clipped, 2);
        check_raw_size(&raw, 4, 2, 2).unwrap();
        assert!(check_raw_size(&raw[2..], 4, 2, 2).is_err());
        // 100 cd/m² grey: PQ 0.508 → limited-range 10-bit luma round((219·0.508 + 16)·4) = 509;
        // the grey right half's chroma 512 (the left half's holds the bright red sample).
        let (y1, cb) = (u16::from_le_bytes([raw[2], raw[3]]), u16::from_le_bytes([raw[18], raw[19]]));
        assert!((508..=510).contains(&y1), "{y1}");
        assert_eq!(cb, 512);
    }
}
