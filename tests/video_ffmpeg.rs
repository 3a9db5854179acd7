//! hdrcodec-video's AV1 streams judged by FFmpeg and dav1d (VIDEO-NOTES §4):
//! - `ffprobe` reports the stream's colour signalling as written: smpte2084 (or arib-std-b67),
//!   bt2020, bt2020nc, tv range, chroma location topleft;
//! - `ffprobe` frame side data shows exactly our mastering display (AV1 units over 65536, 256
//!   and 16384) and content light level;
//! - `ffmpeg -f md5` (libdav1d), `dav1d --muxer md5` and `md5sum` of the planes our decoder
//!   returns agree: three decoders (the CLI, FFmpeg's wrapper, ours through the dav1d crate) and
//!   one hash;
//! - a stream SVT-AV1 wrote (through FFmpeg) reads, in our parser, as the HDR10 values it was
//!   given, and decodes in ours to FFmpeg's samples.
mod common;

use common::{require, run_ok, temp_dir, tool};
use hdrcodec_core::{Channels, ColorInfo, ColorPrimaries, HdrImage, MasteringDisplay};
use hdrcodec_video::decode::{Av1DecodeOptions, Av1Decoder};
use hdrcodec_video::encode::{encode_sequence, encode_sequence_mp4, Av1Options};
use hdrcodec_video::hdr10::{content_light_level, Subsampling, Transfer};
use hdrcodec_video::lpuv_av1::LpuvStreamInfo;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Four 96x64 BT.2020 frames: a ramp from 1 to 1000 cd/m² with a colour wash, and a 3000 cd/m²
/// square moving right.
fn frames() -> Vec<HdrImage> {
    frames_of(96, 64)
}

/// [`frames`] at any size.
fn frames_of(w: u32, h: u32) -> Vec<HdrImage> {
    (0..4)
        .map(|t| {
            let mut s = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let l = 10f32.powf(-2.0 + 3.0 * (x + y) as f32 / (w + h) as f32);
                    let hue = x as f32 / w as f32;
                    let bright = (10 + 8 * t..22 + 8 * t).contains(&x) && (20..32).contains(&y);
                    s.extend(if bright { [30.0, 27.0, 20.0] } else { [l * (0.5 + hue), l * 0.8, l * (1.2 - hue)] });
                }
            }
            let color = ColorInfo { primaries: ColorPrimaries::Bt2020, nits_per_unit: 100.0, hdr10: None };
            HdrImage::new(w, h, Channels::Rgb, s, color).unwrap()
        })
        .collect()
}

fn write_stream(dir: &Path, name: &str, options: &Av1Options) -> std::path::PathBuf {
    write_frames(dir, name, &frames(), options)
}

fn write_frames(dir: &Path, name: &str, frames: &[HdrImage], options: &Av1Options) -> std::path::PathBuf {
    let (_, ivf) = encode_sequence(frames, options, Vec::new()).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, ivf).unwrap();
    path
}

fn ffprobe_json(args: &[&str], file: &Path) -> Value {
    let out = run_ok(Command::new("ffprobe").args(["-v", "error", "-of", "json"]).args(args).arg(file));
    serde_json::from_slice(&out.stdout).expect("ffprobe prints JSON")
}

fn fast() -> Av1Options {
    Av1Options { speed: 10, quantizer: 60, ..Av1Options::default() }
}

#[test]
fn ffprobe_reads_our_hdr10_signalling_and_metadata() {
    let Some(_) = require(tool("ffprobe"), "ffprobe (Debian ffmpeg)") else { return };
    let dir = temp_dir("video_ffmpeg_probe");
    let md = MasteringDisplay::p3_d65_1000();
    let path = write_stream(&dir, "pq.ivf", &Av1Options { mastering_display: md, ..fast() });

    let stream = ffprobe_json(
        &[
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=codec_name,profile,pix_fmt,color_range,color_space,color_transfer,color_primaries,chroma_location",
        ],
        &path,
    );
    let s = &stream["streams"][0];
    assert_eq!(s["codec_name"], "av1");
    assert_eq!(s["pix_fmt"], "yuv420p10le");
    assert_eq!(s["color_transfer"], "smpte2084");
    assert_eq!(s["color_primaries"], "bt2020");
    assert_eq!(s["color_space"], "bt2020nc");
    assert_eq!(s["color_range"], "tv");
    assert_eq!(s["chroma_location"], "topleft");

    let frames_json = ffprobe_json(
        &[
            "-select_streams",
            "v:0",
            "-show_frames",
            "-show_entries",
            "frame=color_transfer,color_primaries,color_space:frame_side_data_list",
        ],
        &path,
    );
    let decoded = frames_json["frames"].as_array().expect("frames");
    assert_eq!(decoded.len(), 4, "FFmpeg (libdav1d) decodes every frame");
    let units = md.to_av1();
    let cll = content_light_level(&frames(), Transfer::Pq);
    for f in decoded {
        assert_eq!(f["color_transfer"], "smpte2084");
        let side = f["side_data_list"].as_array().expect("HDR10 side data on every frame");
        let mdcv = side.iter().find(|d| d["side_data_type"] == "Mastering display metadata").expect("MDCV");
        let chroma = |key: &str, v: u16| assert_eq!(mdcv[key], format!("{v}/65536"), "{key}");
        for (i, colour) in ["red", "green", "blue"].iter().enumerate() {
            chroma(&format!("{colour}_x"), units.primaries[i][0]);
            chroma(&format!("{colour}_y"), units.primaries[i][1]);
        }
        chroma("white_point_x", units.white[0]);
        chroma("white_point_y", units.white[1]);
        assert_eq!(mdcv["max_luminance"], format!("{}/256", units.luminance_max));
        assert_eq!(mdcv["min_luminance"], format!("{}/16384", units.luminance_min));
        let light = side.iter().find(|d| d["side_data_type"] == "Content light level metadata").expect("CLL");
        assert_eq!(light["max_content"], u64::from(cll.max_cll));
        assert_eq!(light["max_average"], u64::from(cll.max_fall));
    }

    let hlg = write_stream(&dir, "hlg.ivf", &Av1Options { transfer: Transfer::HLG_1000, ..fast() });
    let s = ffprobe_json(&["-select_streams", "v:0", "-show_entries", "stream=color_transfer,color_primaries"], &hlg);
    assert_eq!(s["streams"][0]["color_transfer"], "arib-std-b67");
    assert_eq!(s["streams"][0]["color_primaries"], "bt2020");
}

/// The first 32 hexadecimal characters in `text` that form one word.
fn md5_in(text: &str) -> String {
    text.split(|c: char| !c.is_ascii_hexdigit())
        .find(|w| w.len() == 32)
        .unwrap_or_else(|| panic!("no MD5 in {text:?}"))
        .to_ascii_lowercase()
}

#[test]
fn ffmpeg_dav1d_and_our_decoder_agree_bit_for_bit() {
    let Some(_) = require(tool("ffmpeg"), "ffmpeg (Debian ffmpeg)") else { return };
    let Some(_) = require(tool("dav1d"), "the dav1d CLI (Debian dav1d)") else { return };
    let Some(_) = require(tool("md5sum"), "md5sum (coreutils)") else { return };
    let dir = temp_dir("video_ffmpeg_md5");
    // Odd sizes give chroma planes of (w + 1) / 2 x (h + 1) / 2.
    for (name, (w, h), options) in [
        ("pq.ivf", (96, 64), fast()),
        ("hlg_lowlatency.ivf", (96, 64), Av1Options { transfer: Transfer::HLG_1000, low_latency: true, ..fast() }),
        ("pq_odd_97x63.ivf", (97, 63), fast()),
    ] {
        let path = write_frames(&dir, name, &frames_of(w, h), &options);
        let ffmpeg = ffmpeg_md5(&path);
        let dav1d = run_ok(Command::new("dav1d").args(["-q", "-i"]).arg(&path).args(["--muxer", "md5", "-o", "-"]));
        let dav1d = md5_in(&String::from_utf8_lossy(&dav1d.stdout));
        let (raw, count) = our_planes(&path);
        assert_eq!(count, 4);
        let ours = md5sum(&dir.join(format!("{name}.yuv")), &raw);
        assert_eq!(ffmpeg, dav1d, "{name}: FFmpeg and the dav1d CLI");
        assert_eq!(ours, ffmpeg, "{name}: our decode and FFmpeg's");
    }
}

/// FFmpeg's (libdav1d's) decode of `path` as 10-bit 4:2:0 planes, hashed by `-f md5`.
fn ffmpeg_md5(path: &Path) -> String {
    ffmpeg_md5_as(path, "yuv420p10le")
}

/// FFmpeg's (libdav1d's) decode of `path` as planes of `pix_fmt`, hashed by `-f md5`.
fn ffmpeg_md5_as(path: &Path, pix_fmt: &str) -> String {
    let out = run_ok(
        Command::new("ffmpeg").args(["-v", "error", "-i"]).arg(path).args(["-f", "md5", "-pix_fmt", pix_fmt, "-"]),
    );
    md5_in(&String::from_utf8_lossy(&out.stdout))
}

/// L_p u'v' in 12-bit AV1 (profile 2, no colour description): FFmpeg decodes the planes to the
/// same samples as our decoder, at 4:4:4 and 4:2:0.
#[test]
fn ffmpeg_decodes_our_12_bit_lpuv_planes_as_we_do() {
    let Some(_) = require(tool("ffmpeg"), "ffmpeg (Debian ffmpeg)") else { return };
    let Some(_) = require(tool("md5sum"), "md5sum (coreutils)") else { return };
    let dir = temp_dir("video_ffmpeg_lpuv");
    for (name, subsampling, pix_fmt) in
        [("lpuv444.ivf", Subsampling::Yuv444, "yuv444p12le"), ("lpuv420.ivf", Subsampling::Yuv420, "yuv420p12le")]
    {
        let options = Av1Options {
            lpuv: Some(LpuvStreamInfo::for_primaries(ColorPrimaries::Bt2020)),
            low_latency: true,
            subsampling,
            quantizer: 10,
            ..fast()
        };
        let path = write_stream(&dir, name, &options);
        let (raw, count) = our_planes(&path);
        assert_eq!(count, 4);
        let ours = md5sum(&dir.join(format!("{name}.yuv")), &raw);
        assert_eq!(ours, ffmpeg_md5_as(&path, pix_fmt), "{name}: our decode and FFmpeg's");
    }
}

/// `md5sum` of `bytes`, written to `path` first.
fn md5sum(path: &Path, bytes: &[u8]) -> String {
    std::fs::write(path, bytes).unwrap();
    md5_in(&String::from_utf8_lossy(&run_ok(Command::new("md5sum").arg(path)).stdout))
}

/// The planes our decoder returns for the IVF file at `path`, as one little-endian byte string.
fn our_planes(path: &Path) -> (Vec<u8>, usize) {
    let data = std::fs::read(path).unwrap();
    let mut decoder = Av1Decoder::new(&data, &Av1DecodeOptions::default()).unwrap();
    let (mut raw, mut count) = (Vec::new(), 0);
    while let Some(planes) = decoder.next_planes().unwrap() {
        for plane in [&planes.y, &planes.cb, &planes.cr] {
            raw.extend(plane.iter().flat_map(|v| v.to_le_bytes()));
        }
        count += 1;
    }
    (raw, count)
}

#[test]
fn we_read_an_svt_av1_hdr10_stream_as_ffmpeg_does() {
    let Some(_) = require(tool("ffmpeg"), "ffmpeg (Debian ffmpeg)") else { return };
    let Some(_) = require(tool("md5sum"), "md5sum (coreutils)") else { return };
    let dir = temp_dir("video_ffmpeg_svt");
    let path = dir.join("svt.ivf");
    // SVT-AV1 1.4 through FFmpeg, with the P3-D65 1000 / 0.0001 cd/m² display of VIDEO-NOTES §3.2.
    run_ok(Command::new("ffmpeg").args(["-v", "error", "-y", "-f", "lavfi", "-i", "testsrc2=s=128x72:d=0.2:r=25"]).args([
        "-pix_fmt",
        "yuv420p10le",
        "-c:v",
        "libsvtav1",
        "-preset",
        "12",
        "-svtav1-params",
        "mastering-display=G(0.265,0.690)B(0.150,0.060)R(0.680,0.320)WP(0.3127,0.3290)L(1000,0.0001):content-light=1000,400",
        "-color_primaries",
        "bt2020",
        "-color_trc",
        "smpte2084",
        "-colorspace",
        "bt2020nc",
    ])
    .arg(&path));
    let data = std::fs::read(&path).unwrap();
    let (_, s) = hdrcodec_video::decode::probe_ivf(&data, &Default::default()).unwrap();
    let seq = s.sequence_header.unwrap();
    assert_eq!(seq.color.color_description, Some(hdrcodec_video::obu::ColorDescription::HDR10_PQ));
    assert_eq!((seq.color.bit_depth, seq.max_frame_width, seq.max_frame_height), (10, 128, 72));
    // Exactly the bytes of the notes' worked example: 44564, 20972, ... 256000, 2.
    assert_eq!(s.mastering_display, Some(MasteringDisplay::p3_d65_1000().to_av1()));
    let cll = s.content_light.unwrap();
    assert_eq!((cll.max_cll, cll.max_fall), (1000, 400));
    // And we decode SVT-AV1's stream to the same samples as FFmpeg.
    let (raw, count) = our_planes(&path);
    assert_eq!(count, 5);
    assert_eq!(md5sum(&dir.join("ours.yuv"), &raw), ffmpeg_md5(&path));
}

/// AV1 in MP4 (our own ISO-BMFF writer): ffprobe reads the stream's colour signalling from the
/// `colr` box and the sequence header, the mastering display and content light level from the
/// `mdcv` and `clli` boxes (SEI units: over 50000 and 10000) and from the metadata OBUs on
/// every decoded frame (AV1 units), all exactly ours; FFmpeg decodes every frame to the same
/// samples as from the IVF of the same encode, and as our decoder reading the MP4.
#[test]
fn ffprobe_reads_our_mp4_hdr_boxes_and_ffmpeg_decodes_it_as_the_ivf() {
    let Some(_) = require(tool("ffprobe"), "ffprobe (Debian ffmpeg)") else { return };
    let Some(_) = require(tool("md5sum"), "md5sum (coreutils)") else { return };
    let dir = temp_dir("video_ffmpeg_mp4");
    let md = MasteringDisplay::p3_d65_1000();
    let options = Av1Options { mastering_display: md, ..fast() };
    let (_, mp4) = encode_sequence_mp4(&frames(), &options, std::io::Cursor::new(Vec::new())).unwrap();
    let path = dir.join("pq.mp4");
    std::fs::write(&path, mp4.into_inner()).unwrap();
    let ivf = write_stream(&dir, "pq.ivf", &options);

    let probe = ffprobe_json(&["-select_streams", "v:0", "-show_streams"], &path);
    let s = &probe["streams"][0];
    assert_eq!(s["codec_name"], "av1");
    assert_eq!(s["codec_tag_string"], "av01");
    assert_eq!((s["width"].as_u64(), s["height"].as_u64()), (Some(96), Some(64)));
    assert_eq!(s["nb_frames"], "4");
    assert_eq!(s["color_transfer"], "smpte2084");
    assert_eq!(s["color_primaries"], "bt2020");
    assert_eq!(s["color_space"], "bt2020nc");
    assert_eq!(s["color_range"], "tv");
    // The boxes carry the SEI units: the stream's AV1 values through core's conversion.
    let st2086 = MasteringDisplay::from_av1(&md.to_av1()).to_st2086();
    let cll = content_light_level(&frames(), Transfer::Pq);
    let side = s["side_data_list"].as_array().expect("stream side data from mdcv and clli");
    let mdcv = side.iter().find(|d| d["side_data_type"] == "Mastering display metadata").expect("mdcv");
    for (i, colour) in ["red", "green", "blue"].iter().enumerate() {
        assert_eq!(mdcv[format!("{colour}_x")], format!("{}/50000", st2086.primaries[i][0]), "{colour}_x");
        assert_eq!(mdcv[format!("{colour}_y")], format!("{}/50000", st2086.primaries[i][1]), "{colour}_y");
    }
    assert_eq!(mdcv["white_point_x"], format!("{}/50000", st2086.white[0]));
    assert_eq!(mdcv["white_point_y"], format!("{}/50000", st2086.white[1]));
    assert_eq!(mdcv["max_luminance"], format!("{}/10000", st2086.max_luminance));
    assert_eq!(mdcv["min_luminance"], format!("{}/10000", st2086.min_luminance));
    let light = side.iter().find(|d| d["side_data_type"] == "Content light level metadata").expect("clli");
    assert_eq!(light["max_content"], u64::from(cll.max_cll));
    assert_eq!(light["max_average"], u64::from(cll.max_fall));

    let frames_json = ffprobe_json(
        &["-select_streams", "v:0", "-show_frames", "-show_entries", "frame=color_transfer:frame_side_data_list"],
        &path,
    );
    let decoded = frames_json["frames"].as_array().expect("frames");
    assert_eq!(decoded.len(), 4, "FFmpeg (libdav1d) decodes every frame of the MP4");
    let units = md.to_av1();
    for f in decoded {
        let side = f["side_data_list"].as_array().expect("HDR10 side data on every frame");
        let mdcv = side.iter().find(|d| d["side_data_type"] == "Mastering display metadata").expect("MDCV");
        assert_eq!(mdcv["red_x"], format!("{}/65536", units.primaries[0][0]));
        assert_eq!(mdcv["max_luminance"], format!("{}/256", units.luminance_max));
    }

    let from_mp4 = ffmpeg_md5(&path);
    assert_eq!(from_mp4, ffmpeg_md5(&ivf), "FFmpeg decodes the MP4 and the IVF of one encode alike");
    let (raw, count) = our_planes(&path);
    assert_eq!(count, 4);
    assert_eq!(md5sum(&dir.join("ours_mp4.yuv"), &raw), from_mp4, "our decode of the MP4 and FFmpeg's");
}

/// The corpus HDR10 HEVC clip in MP4 (no `colr`, `mdcv` or `clli` box: HDR is signalled only
/// in the HEVC VUI and SEI): our probe reads what FFmpeg reads — codec, size, frames, the VUI
/// colour description and range, the mastering display (as stored) and content light level
/// SEI — and reports the mastering display as malformed (VIDEO-NOTES §4: primaries written
/// R, G, B where the SEI wants G, B, R; nits where it counts 0.0001 cd/m²).
#[test]
fn we_read_the_corpus_hevc_mp4_as_ffprobe_does_and_flag_its_mastering_display() {
    let Some(_) = require(tool("ffprobe"), "ffprobe (Debian ffmpeg)") else { return };
    let Some(corpus) = require(common::corpus_dir(), "the shared corpus") else { return };
    let path = corpus.join("video/hdr10-video-with-sdr-container.mp4");
    let data = std::fs::read(&path).unwrap();
    let info = hdrcodec_video::mp4::probe_mp4(&data, &Default::default()).unwrap();

    let probe = ffprobe_json(&["-select_streams", "v:0", "-show_streams"], &path);
    let s = &probe["streams"][0];
    assert_eq!(s["codec_tag_string"], String::from_utf8_lossy(&info.codec).as_ref());
    assert_eq!((s["width"].as_u64(), s["height"].as_u64()), (Some(info.width.into()), Some(info.height.into())));
    assert_eq!(s["nb_frames"], info.frames.to_string());
    assert_eq!(info.bit_depth, Some(10));
    let (cicp, source) = info.colour.expect("the VUI's colour description");
    assert_eq!(source, "HEVC VUI");
    assert_eq!((s["color_primaries"].as_str(), cicp[0]), (Some("bt2020"), 9));
    assert_eq!((s["color_transfer"].as_str(), cicp[1]), (Some("smpte2084"), 16));
    assert_eq!((s["color_space"].as_str(), cicp[2]), (Some("bt2020nc"), 9));
    assert_eq!((s["color_range"].as_str(), info.full_range), (Some("tv"), Some(false)));

    let frames = ffprobe_json(
        &["-select_streams", "v:0", "-read_intervals", "%+#1", "-show_frames", "-show_entries", "frame_side_data_list"],
        &path,
    );
    let side = frames["frames"][0]["side_data_list"].as_array().expect("side data");
    let mdcv = side.iter().find(|d| d["side_data_type"] == "Mastering display metadata").expect("MDCV SEI");
    let (md, source) = info.mastering_display.expect("the mastering display SEI");
    assert_eq!(source, "HEVC SEI");
    let units = md.to_st2086();
    for (i, colour) in ["red", "green", "blue"].iter().enumerate() {
        assert_eq!(mdcv[format!("{colour}_x")], format!("{}/50000", units.primaries[i][0]), "{colour}_x");
        assert_eq!(mdcv[format!("{colour}_y")], format!("{}/50000", units.primaries[i][1]), "{colour}_y");
    }
    assert_eq!(mdcv["max_luminance"], format!("{}/10000", units.max_luminance));
    assert_eq!(mdcv["min_luminance"], format!("{}/10000", units.min_luminance));
    let light = side.iter().find(|d| d["side_data_type"] == "Content light level metadata").expect("CLL SEI");
    let (cll, _) = info.content_light.expect("the content light level SEI");
    assert_eq!((light["max_content"].as_u64(), light["max_average"].as_u64()), (Some(1000), Some(200)));
    assert_eq!((cll.max_cll, cll.max_fall), (1000, 200));
    // Both faults of the notes, and nothing else.
    assert_eq!(info.problems.len(), 2, "{:?}", info.problems);
    assert!(info.problems[0].contains("primaries out of order"), "{:?}", info.problems);
    assert!(info.problems[1].contains("0.1 cd/m²"), "{:?}", info.problems);
}

/// FFmpeg's Y4M muxer against our Y4M reader: `testsrc` written by FFmpeg as Y4M (8-bit
/// `420jpeg`, `420p10`, `444p12`, with its `XCOLORRANGE=LIMITED`) and as raw planes; our reader
/// returns exactly the raw planes, frame by frame, with the header's size and depth.
#[test]
fn we_read_ffmpeg_s_y4m_as_its_raw_planes() {
    use hdrcodec_core::Limits;
    use hdrcodec_video::y4m::Y4mReader;
    let Some(_) = require(tool("ffmpeg"), "ffmpeg (Debian ffmpeg)") else { return };
    let dir = temp_dir("video_ffmpeg_y4m");
    for (pix_fmt, bits, chroma) in [("yuv420p", 8, 4), ("yuv420p10le", 10, 4), ("yuv444p12le", 12, 1)] {
        let (y4m, raw) = (dir.join(format!("{pix_fmt}.y4m")), dir.join(format!("{pix_fmt}.raw")));
        for (out, format) in [(&y4m, "yuv4mpegpipe"), (&raw, "rawvideo")] {
            run_ok(
                Command::new("ffmpeg")
                    .args(["-v", "error", "-y", "-f", "lavfi", "-i", "testsrc=size=18x10:rate=5", "-frames:v", "3"])
                    .args(["-pix_fmt", pix_fmt, "-strict", "-1", "-f", format])
                    .arg(out),
            );
        }
        let data = std::fs::read(&y4m).unwrap();
        let mut reader = Y4mReader::new(&data[..], &Limits::default()).unwrap();
        let h = *reader.header();
        assert_eq!((h.width, h.height, h.bit_depth, h.full_range), (18, 10, bits, false), "{pix_fmt}");
        let mut ours = Vec::new();
        while let Some(yuv) = reader.next_frame().unwrap() {
            assert_eq!(yuv.cb.len(), 18 * 10 / chroma, "{pix_fmt}");
            for plane in [&yuv.y, &yuv.cb, &yuv.cr] {
                if bits == 8 {
                    ours.extend(plane.iter().map(|&v| v as u8));
                } else {
                    ours.extend(plane.iter().flat_map(|v| v.to_le_bytes()));
                }
            }
        }
        assert_eq!(reader.frames_read(), 3, "{pix_fmt}");
        assert!(ours == std::fs::read(&raw).unwrap(), "{pix_fmt}: our planes differ from FFmpeg's raw output");
    }
}

/// The SDR rendition (`Av1Options::sdr`, `hdrcodec video encode --sdr`): ffprobe reports 8-bit
/// 4:2:0 BT.709 primaries and matrix, the sRGB transfer, limited range; FFmpeg (libdav1d)
/// decodes the planes to the samples ours gives.
#[test]
fn ffprobe_reads_our_sdr_rendition_as_bt709_and_ffmpeg_decodes_it_as_we_do() {
    use hdrcodec_video::sdr::SdrRendition;
    let Some(_) = require(tool("ffprobe"), "ffprobe (Debian ffmpeg)") else { return };
    let Some(_) = require(tool("md5sum"), "md5sum (coreutils)") else { return };
    let dir = temp_dir("video_ffmpeg_sdr");
    let options = Av1Options { sdr: Some(SdrRendition::new(200.0).unwrap()), ..fast() };
    let path = write_stream(&dir, "sdr.ivf", &options);
    let keys = ["codec_name", "pix_fmt", "color_primaries", "color_space", "color_transfer", "color_range"];
    let stream =
        ffprobe_json(&["-select_streams", "v:0", "-show_entries", &format!("stream={}", keys.join(","))], &path);
    let s = &stream["streams"][0];
    assert_eq!(fields(s, &keys), ["av1", "yuv420p", "bt709", "bt709", "iec61966-2-1", "tv"], "{s}");
    let (raw, count) = our_planes(&path);
    assert_eq!(count, 4);
    // Our planes are 8-bit samples held in u16: the low bytes are FFmpeg's yuv420p.
    let bytes: Vec<u8> = raw.chunks_exact(2).map(|b| b[0]).collect();
    assert!(raw.chunks_exact(2).all(|b| b[1] == 0));
    let ours = md5sum(&dir.join("sdr.yuv"), &bytes);
    assert_eq!(ours, ffmpeg_md5_as(&path, "yuv420p"), "our decode and FFmpeg's");
}

/// Matroska and WebM from our EBML writer: ffprobe reports the colour elements (smpte2084,
/// bt2020, bt2020nc, tv, topleft) and, as stream side data, exactly our mastering display
/// (floats in the file) and content light level; FFmpeg decodes the same samples as from the IVF
/// of the same frames.
#[test]
fn ffprobe_reads_our_matroska_colour_elements_and_ffmpeg_decodes_it_as_the_ivf() {
    use hdrcodec_video::encode::Av1Encoder;
    let Some(_) = require(tool("ffprobe"), "ffprobe (Debian ffmpeg)") else { return };
    let dir = temp_dir("video_ffmpeg_mkv");
    let md = MasteringDisplay::p3_d65_1000();
    let frames = frames();
    let cll = content_light_level(&frames, Transfer::Pq);
    let options = Av1Options { mastering_display: md, content_light: Some(cll), ..fast() };
    let ivf = write_frames(&dir, "pq.ivf", &frames, &options);
    for (name, webm) in [("pq.mkv", false), ("pq.webm", true)] {
        let mut enc = Av1Encoder::begin_mkv(96, 64, &options, std::io::Cursor::new(Vec::new()), webm).unwrap();
        for f in &frames {
            enc.push_frame(f).unwrap();
        }
        let (_, out) = enc.finish().unwrap();
        let path = dir.join(name);
        std::fs::write(&path, out.into_inner()).unwrap();
        let probe = ffprobe_json(
            &[
                "-select_streams",
                "v:0",
                "-show_entries",
                "format=format_name,duration:stream=codec_name,color_range,color_space,color_transfer,color_primaries,chroma_location,nb_read_frames:stream_side_data_list",
                "-count_frames",
            ],
            &path,
        );
        let s = &probe["streams"][0];
        let keys = ["codec_name", "color_transfer", "color_primaries", "color_space", "color_range", "chroma_location"];
        assert_eq!(fields(s, &keys), ["av1", "smpte2084", "bt2020", "bt2020nc", "tv", "topleft"], "{name}: {probe}");
        assert_eq!(fields(s, &["nb_read_frames"]), ["4"], "{name}");
        assert!(probe["format"]["format_name"].as_str().unwrap().contains("matroska"), "{probe}");
        let side = s["side_data_list"].as_array().expect("stream side data from the colour elements");
        let mdcv = side.iter().find(|d| d["side_data_type"] == "Mastering display metadata").expect("mastering");
        let ratio = |v: &Value| -> f64 {
            let (n, d) = v.as_str().unwrap().split_once('/').unwrap();
            n.parse::<f64>().unwrap() / d.parse::<f64>().unwrap()
        };
        // What we wrote: the stream's HDR_MDCV (AV1 fixed point) as floats.
        let written = MasteringDisplay::from_av1(&md.to_av1());
        for (i, colour) in ["red", "green", "blue"].into_iter().enumerate() {
            assert!((ratio(&mdcv[format!("{colour}_x")]) - written.primaries[i][0]).abs() < 2e-5, "{name} {colour}_x");
            assert!((ratio(&mdcv[format!("{colour}_y")]) - written.primaries[i][1]).abs() < 2e-5, "{name} {colour}_y");
        }
        assert!((ratio(&mdcv["white_point_x"]) - written.white[0]).abs() < 2e-5);
        assert!((ratio(&mdcv["max_luminance"]) - written.max_luminance).abs() < 1e-3, "{mdcv}");
        assert!((ratio(&mdcv["min_luminance"]) - written.min_luminance).abs() < 1e-4, "{mdcv}");
        let light = side.iter().find(|d| d["side_data_type"] == "Content light level metadata").expect("MaxCLL");
        assert_eq!(
            (light["max_content"].as_u64(), light["max_average"].as_u64()),
            (Some(cll.max_cll.into()), Some(cll.max_fall.into()))
        );
        assert_eq!(ffmpeg_md5(&path), ffmpeg_md5(&ivf), "{name}: FFmpeg decodes the same frames as the IVF");
    }
}

/// Matroska and WebM written by FFmpeg (`ffmpeg -i x.ivf -c copy x.mkv`, also to a pipe) and by us read in our
/// decoder: the same samples as the IVF, the same HDR10 metadata, and the Colour element FFmpeg
/// wrote (9/16/9, limited range) read back from the track.
#[test]
fn we_read_ffmpeg_s_and_our_matroska_as_the_ivf() {
    use hdrcodec_core::Limits;
    use hdrcodec_video::decode::{decode_ivf, probe_stream};
    use hdrcodec_video::encode::Av1Encoder;
    use hdrcodec_video::mkv::MkvTrack;
    let Some(_) = require(tool("ffmpeg"), "ffmpeg (Debian ffmpeg)") else { return };
    let dir = temp_dir("video_ffmpeg_mkv_read");
    let frames = frames();
    let cll = content_light_level(&frames, Transfer::Pq);
    let options = Av1Options { mastering_display: MasteringDisplay::p3_d65_1000(), content_light: Some(cll), ..fast() };
    let ivf = write_frames(&dir, "pq.ivf", &frames, &options);
    let ivf_bytes = std::fs::read(&ivf).unwrap();
    let want = decode_ivf(&ivf_bytes, &Av1DecodeOptions::default()).unwrap();
    let want_hdr10 = probe_stream(&ivf_bytes, &Limits::default()).unwrap().hdr10();
    assert!(want_hdr10.is_some());
    let mut enc = Av1Encoder::begin_mkv(96, 64, &options, std::io::Cursor::new(Vec::new()), false).unwrap();
    for f in &frames {
        enc.push_frame(f).unwrap();
    }
    let ours = enc.finish().unwrap().1.into_inner();
    for name in ["ff.mkv", "ff.webm", "pipe.webm", "ours.mkv"] {
        let path = dir.join(name);
        if name == "ours.mkv" {
            std::fs::write(&path, &ours).unwrap();
        } else if name == "pipe.webm" {
            // Written to a pipe, FFmpeg cannot go back: the Segment's size stays unknown.
            let out = run_ok(
                Command::new("ffmpeg").args(["-v", "error", "-i"]).arg(&ivf).args(["-c", "copy", "-f", "webm", "-"]),
            );
            std::fs::write(&path, out.stdout).unwrap();
        } else {
            run_ok(Command::new("ffmpeg").args(["-v", "error", "-y", "-i"]).arg(&ivf).args(["-c", "copy"]).arg(&path));
        }
        let data = std::fs::read(&path).unwrap();
        let track = MkvTrack::first_video(&data, &Limits::default()).unwrap();
        assert_eq!(track.codec_id, "V_AV1", "{name}");
        assert_eq!(track.doc_type, if name.ends_with("webm") { "webm" } else { "matroska" });
        let c = track.colour.unwrap_or_else(|| panic!("{name}: no Colour element"));
        assert_eq!((c.matrix, c.transfer, c.primaries, c.range), (Some(9), Some(16), Some(9), Some(1)), "{name}");
        if name == "ours.mkv" {
            assert_eq!((c.max_cll, c.max_fall), (Some(cll.max_cll.into()), Some(cll.max_fall.into())));
        }
        assert_eq!(probe_stream(&data, &Limits::default()).unwrap().hdr10(), want_hdr10, "{name}");
        let got = decode_ivf(&data, &Av1DecodeOptions::default()).unwrap();
        assert_eq!(got.len(), want.len(), "{name}");
        for (a, b) in got.iter().zip(&want) {
            assert_eq!(a.samples(), b.samples(), "{name}");
        }
    }
}

/// The string values of `keys` in an ffprobe JSON object ("" where absent).
fn fields(object: &Value, keys: &[&str]) -> Vec<String> {
    keys.iter().map(|k| object[*k].as_str().unwrap_or("").to_string()).collect()
}
