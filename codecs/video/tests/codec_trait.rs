//! AV1 through core's `VideoCodec` trait ([`Av1Codec`]): what a tool that knows only the trait
//! gets. Small frames at rav1e speed 10, so that CI stays fast.

use hdrcodec_core::{
    ColorPrimaries, DecodeOptions, EncodeSettings, Error, Hdr10Metadata, HdrImage, ImageInfo, Limits, MasteringDisplay,
    StreamReport, VideoCodec,
};
use hdrcodec_video::codec::Av1Codec;
use hdrcodec_video::decode::{decode_ivf, Av1DecodeOptions};
use hdrcodec_video::encode::{encode_sequence_mp4, Av1Options};
use hdrcodec_video::hdr10::{content_light_level, Transfer};
use hdrcodec_video::sequences::moving_light_frame;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A file of this test process under the system's temporary directory.
fn temp_file(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("hdrcodec-video-codec-trait-{}-{name}", std::process::id()))
}

fn frames(n: u32, peak: f32) -> Vec<HdrImage> {
    (0..n).map(|t| moving_light_frame(64, 48, peak, 6.0, t, n)).collect()
}

/// Encodes `frames` through the trait with `settings` (into a file, as a tool would); returns
/// the stream.
fn encode(frames: &[HdrImage], info: &ImageInfo, settings: &EncodeSettings) -> Vec<u8> {
    encode_reporting(frames, info, settings).0
}

/// [`encode`], with the encoder's report.
fn encode_reporting(frames: &[HdrImage], info: &ImageInfo, settings: &EncodeSettings) -> (Vec<u8>, StreamReport) {
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    let path = temp_file(&format!("{}.ivf", COUNT.fetch_add(1, Ordering::Relaxed)));
    let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    let mut enc = Av1Codec.begin_encode(info, settings, Box::new(file)).unwrap();
    for f in frames {
        enc.push_frame(f).unwrap();
    }
    let report = enc.finish_report().unwrap();
    assert_eq!(report.frames, frames.len() as u64);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(report.bytes, Some(bytes.len() as u64));
    (bytes, report)
}

fn fast() -> EncodeSettings {
    EncodeSettings::default().with_option("speed", "10").with_option("quantizer", "30")
}

#[test]
fn encode_and_decode_through_the_trait() {
    let frames = frames(3, 4000.0);
    let cll = content_light_level(&frames, Transfer::Pq);
    let md = MasteringDisplay::p3_d65_1000();
    let mut info = ImageInfo::of(&frames[0]).with_frames(3);
    info.color.hdr10 = Some(Hdr10Metadata { mastering_display: Some(md), content_light_level: Some(cll) });
    let ivf = encode(&frames, &info, &fast());
    assert_eq!(&ivf[..4], b"DKIF");
    assert_eq!(u32::from_le_bytes(ivf[24..28].try_into().unwrap()), 3, "the IVF header's frame count");

    let mut dec = Av1Codec.begin_decode(ivf.clone().into(), &DecodeOptions::new(Limits::default())).unwrap();
    let got = dec.info().clone();
    assert_eq!((got.width, got.height, got.frames), (64, 48, 3));
    assert_eq!(got.color.primaries, ColorPrimaries::Bt2020);
    assert_eq!(got.color.nits_per_unit, 100.0);
    let hdr10 = got.color.hdr10.unwrap();
    assert_eq!(hdr10.content_light_level, Some(cll));
    assert_eq!(hdr10.mastering_display.unwrap().to_av1(), md.to_av1());
    assert!(got.format.contains("10-bit 4:2:0 BT.2020 PQ"), "{}", got.format);
    // The same frames as the typed decoder's, then the end.
    let typed = decode_ivf(&ivf, &Av1DecodeOptions::default()).unwrap();
    for want in &typed {
        let frame = dec.next_frame().unwrap().unwrap();
        assert_eq!(frame.samples(), want.samples());
        assert_eq!(frame.color, got.color);
    }
    assert!(dec.next_frame().unwrap().is_none());

    // nits_per_unit rescales the samples; unknown and bad options are errors.
    let options = DecodeOptions::new(Limits::default()).with_option("nits_per_unit", "200");
    let mut dec = Av1Codec.begin_decode(ivf.clone().into(), &options).unwrap();
    let half = dec.next_frame().unwrap().unwrap();
    assert!(half.samples().iter().zip(typed[0].samples()).all(|(a, b)| (2.0 * a - b).abs() <= 1e-4 * b.abs()));
    let bad = DecodeOptions::new(Limits::default()).with_option("nits_per_unit", "-1");
    assert!(Av1Codec.begin_decode(ivf.clone().into(), &bad).is_err());
    let unknown = fast().with_option("bogus", "1");
    let err = Av1Codec.begin_encode(&info, &unknown, Box::new(std::io::sink())).err().unwrap().to_string();
    assert!(err.contains("'bogus'") && err.contains("transfer"), "{err}");
    let err = Av1Codec.begin_encode(&info, &fast().with_option("transfer", "log"), Box::new(std::io::sink()));
    assert!(err.err().unwrap().to_string().contains("pq, hlg or mantiuk"));
}

#[test]
fn every_frame_is_charged_to_the_limits_before_it_is_decoded() {
    let frames = frames(2, 1000.0);
    let ivf = encode(&frames, &ImageInfo::of(&frames[0]).with_frames(2), &fast());
    let frame_bytes = 64 * 48 * 3 * 4;
    // Room for the stream's index but not for a frame: begin succeeds, the first frame fails.
    let limits = Limits::default().with_max_alloc_bytes(frame_bytes - 1);
    let mut dec = Av1Codec.begin_decode(ivf.clone().into(), &DecodeOptions::new(limits.clone())).unwrap();
    assert!(matches!(dec.next_frame(), Err(Error::LimitExceeded { .. })));
    // A budget the caller has mostly spent: the charge counts what is in use.
    let limits = Limits::default().with_max_alloc_bytes(frame_bytes + 1000);
    let mut dec = Av1Codec.begin_decode(ivf.into(), &DecodeOptions::new(limits.clone())).unwrap();
    let held = dec.next_frame().unwrap().unwrap();
    let _mine = limits.charge(frame_bytes, "a frame the caller keeps").unwrap();
    assert!(matches!(dec.next_frame(), Err(Error::LimitExceeded { .. })));
    drop(held);
}

#[test]
fn mantiuk_and_mp4_through_the_trait() {
    let mut frames = frames(2, 2000.0);
    for f in &mut frames {
        f.color.primaries = ColorPrimaries::DisplayP3;
    }
    let info = ImageInfo::of(&frames[0]).with_frames(2);
    let ivf = encode(&frames, &info, &fast().with_option("transfer", "mantiuk"));
    let mut dec = Av1Codec.begin_decode(ivf.into(), &DecodeOptions::new(Limits::default())).unwrap();
    assert_eq!(dec.info().color.primaries, ColorPrimaries::DisplayP3);
    assert!(dec.info().format.contains("L_p u'v'"), "{}", dec.info().format);
    assert_eq!(dec.next_frame().unwrap().unwrap().color.primaries, ColorPrimaries::DisplayP3);

    // MP4 (written by the typed API) reads through the trait as the IVF does.
    let frames = self::frames(2, 1000.0);
    let options = Av1Options { speed: 10, quantizer: 30, ..Av1Options::default() };
    let (_, mp4) = encode_sequence_mp4(&frames, &options, std::io::Cursor::new(Vec::new())).unwrap();
    let mp4 = mp4.into_inner();
    let typed = decode_ivf(&mp4, &Av1DecodeOptions::default()).unwrap();
    let mut dec = Av1Codec.begin_decode(mp4.into(), &DecodeOptions::new(Limits::default())).unwrap();
    assert_eq!(dec.info().frames, 2);
    for want in &typed {
        assert_eq!(dec.next_frame().unwrap().unwrap().samples(), want.samples());
    }
    assert!(dec.next_frame().unwrap().is_none());
}

/// MP4, Matroska and WebM through the trait: `begin_encode` (the file built in memory, then
/// copied to the plain writer) and `begin_encode_seekable` (straight to a borrowed writer that
/// seeks) write the same bytes as the typed API; `finish_report` keeps the clipped samples and
/// the content light written; the MP4 decodes through the trait as the typed decoder reads it.
#[test]
fn mp4_and_matroska_through_the_trait_with_the_report() {
    use hdrcodec_video::encode::Av1Encoder;
    let frames = frames(2, 50_000.0); // above PQ's peak: clipped, and counted
    let cll = content_light_level(&frames, Transfer::Pq);
    let mut info = ImageInfo::of(&frames[0]).with_frames(2);
    info.color.hdr10 = Some(Hdr10Metadata { mastering_display: None, content_light_level: Some(cll) });
    let options = Av1Codec::av1_options(&info, &fast()).unwrap();
    let (w, h) = (info.width, info.height);
    for container in ["ivf", "mp4", "mkv", "webm"] {
        let settings = fast().with_option("container", container);
        let (bytes, report) = encode_reporting(&frames, &info, &settings);
        assert_eq!(report.content_light, Some(cll), "{container}");
        assert!(report.clipped.above_peak > 0, "{container}: {:?}", report.clipped);
        // Straight to a borrowed writer that seeks.
        let mut cursor = std::io::Cursor::new(Vec::new());
        let mut enc = Av1Codec.begin_encode_seekable(&info, &settings, Box::new(&mut cursor)).unwrap();
        for f in &frames {
            enc.push_frame(f).unwrap();
        }
        assert_eq!(enc.finish_report().unwrap(), report, "{container}");
        assert_eq!(cursor.get_ref(), &bytes, "{container}: seekable and in-memory writes differ");
        // The typed API's bytes.
        let out = std::io::Cursor::new(Vec::new());
        let typed = match container {
            "ivf" => Av1Encoder::begin(w, h, 2, &options, Vec::new()).and_then(|mut e| {
                frames.iter().try_for_each(|f| e.push_frame(f))?;
                e.finish().map(|(_, v)| v)
            }),
            "mp4" => Av1Encoder::begin_mp4(w, h, &options, out).and_then(|mut e| {
                frames.iter().try_for_each(|f| e.push_frame(f))?;
                e.finish().map(|(_, c)| c.into_inner())
            }),
            _ => Av1Encoder::begin_mkv(w, h, &options, out, container == "webm").and_then(|mut e| {
                frames.iter().try_for_each(|f| e.push_frame(f))?;
                e.finish().map(|(_, c)| c.into_inner())
            }),
        };
        assert_eq!(typed.unwrap(), bytes, "{container}: trait and typed API differ");
        match container {
            "mp4" => {
                assert_eq!(&bytes[4..8], b"ftyp");
                let want = decode_ivf(&bytes, &Av1DecodeOptions::default()).unwrap();
                let mut dec = Av1Codec.begin_decode(bytes.into(), &DecodeOptions::new(Limits::default())).unwrap();
                for want in &want {
                    assert_eq!(dec.next_frame().unwrap().unwrap().samples(), want.samples());
                }
            }
            "mkv" | "webm" => {
                assert_eq!(&bytes[..4], &[0x1a, 0x45, 0xdf, 0xa3]); // EBML
                let doc_type: &[u8] = if container == "webm" { b"webm" } else { b"matroska" };
                assert!(bytes.windows(doc_type.len()).any(|w| w == doc_type));
                matroska_reads_back(&bytes, &frames, cll);
            }
            _ => assert_eq!(&bytes[..4], b"DKIF"),
        }
    }
    let bad = fast().with_option("container", "avi");
    let err = Av1Codec.begin_encode(&info, &bad, Box::new(std::io::sink())).err().unwrap().to_string();
    assert!(err.contains("ivf, mp4, mkv or webm"), "{err}");
}

/// Our Matroska file read back: the trait's decode equals the typed decode of the same encode
/// in IVF, the stream's content light is ours; with the Segment and Cluster sizes made unknown
/// (as a live writer leaves them) the same frames come back; every truncation and bit flip is
/// an error or fewer frames, never a panic.
fn matroska_reads_back(mkv: &[u8], frames: &[HdrImage], cll: hdrcodec_core::ContentLightLevel) {
    use hdrcodec_video::decode::probe_stream;
    let options = Av1Options { speed: 10, quantizer: 30, content_light: Some(cll), ..Av1Options::default() };
    let (_, ivf) = hdrcodec_video::encode::encode_sequence(frames, &options, Vec::new()).unwrap();
    let want = decode_ivf(&ivf, &Av1DecodeOptions::default()).unwrap();
    let decode_all = |data: &[u8]| -> Vec<HdrImage> {
        let mut dec = Av1Codec.begin_decode(data.to_vec().into(), &DecodeOptions::new(Limits::default())).unwrap();
        assert_eq!(dec.info().frames, frames.len() as u32);
        assert_eq!(dec.info().color.hdr10.unwrap().content_light_level, Some(cll));
        std::iter::from_fn(|| dec.next_frame().unwrap()).collect()
    };
    let got = decode_all(mkv);
    assert_eq!(got.len(), want.len());
    for (a, b) in got.iter().zip(&want) {
        assert_eq!(a.samples(), b.samples());
    }
    // Unknown sizes: our sizes are 8-byte EBML numbers, 0x01 then seven bytes; all ones is unknown.
    let mut live = mkv.to_vec();
    for id in [&[0x18, 0x53, 0x80, 0x67][..], &[0x1f, 0x43, 0xb6, 0x75]] {
        let mut at = 0;
        while let Some(p) = live[at..].windows(4).position(|w| w == id) {
            let size = at + p + 4;
            live[size..size + 8].copy_from_slice(&[0x01, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff]);
            at = size + 8;
        }
    }
    assert_ne!(live, mkv);
    assert_eq!(
        decode_all(&live).iter().map(|f| f.samples().to_vec()).collect::<Vec<_>>(),
        want.iter().map(|f| f.samples().to_vec()).collect::<Vec<_>>()
    );
    // Damage: never a panic; a cut file gives an error or fewer frames.
    let limits = Limits::default();
    for len in 0..mkv.len() {
        if let Ok(s) = probe_stream(&mkv[..len], &limits) {
            assert!(s.temporal_units <= frames.len() as u64);
        }
    }
    for at in 0..mkv.len() {
        let mut bad = mkv.to_vec();
        bad[at] ^= 0x5a;
        let _ = probe_stream(&bad, &limits);
    }
    // A block larger than the limits allow is refused before it is used.
    let small = Limits::default().with_max_alloc_bytes(16);
    assert!(matches!(probe_stream(mkv, &small), Err(Error::LimitExceeded { .. })));
}

/// The generated moving light (a 6-pixel disc at exactly its peak, 64x48, 3 frames): the
/// stream's MaxCLL is the peak the PQ signal holds (the light's own up to 10 000 cd/m², else
/// 10 000 with the clipped samples counted), and the decoded frames reach it within PQ's
/// precision at the top of the curve.
#[test]
fn the_moving_light_s_max_cll_is_its_peak() {
    use hdrcodec_core::PqTransfer;
    use hdrcodec_video::decode::probe_ivf;
    use hdrcodec_video::encode::encode_sequence;
    for peak in [10_000.0f32, 50_000.0] {
        let frames = frames(3, peak);
        let options = Av1Options { speed: 10, quantizer: 10, ..Av1Options::default() };
        let (summary, ivf) = encode_sequence(&frames, &options, Vec::new()).unwrap();
        let cll = probe_ivf(&ivf, &Limits::default()).unwrap().1.content_light.unwrap();
        assert_eq!(cll.max_cll, 10_000, "peak {peak}");
        // Every component of the disc above 10 000 cd/m² was clipped, and counted.
        assert_eq!(summary.clipped.above_peak > 0, peak > 10_000.0, "{:?}", summary.clipped);
        let decoded = decode_ivf(&ivf, &Av1DecodeOptions::default()).unwrap();
        let measured = decoded.iter().map(hdrcodec_core::hdr10::max_cll_nits).fold(0.0, f64::max);
        // Two 10-bit limited-range codes below PQ's top (code 940) is 10 000 → 9 784 cd/m².
        let two_codes_down = PqTransfer::decode(1.0 - 2.0 / 876.0);
        eprintln!("moving light at {peak} cd/m²: decoded MaxCLL {measured:.0}, two codes down {two_codes_down:.0}");
        assert!(measured <= 10_000.5 && measured >= two_codes_down, "decoded MaxCLL {measured}");
    }
}

/// The SDR rendition through rav1e and dav1d: an 8-bit BT.709 sRGB stream whose decoded frames
/// are the tone-mapped source within the tolerance of 8-bit coding at quantizer 20.
#[test]
fn the_sdr_rendition_decodes_to_the_tone_mapped_frames() {
    use hdrcodec_video::decode::probe_ivf;
    use hdrcodec_video::encode::encode_sequence;
    use hdrcodec_video::sdr::SdrRendition;
    let frames = frames(3, 4000.0);
    let sdr = SdrRendition::new(100.0).unwrap();
    let options = Av1Options { speed: 10, quantizer: 20, sdr: Some(sdr.clone()), ..Av1Options::default() };
    let (_, ivf) = encode_sequence(&frames, &options, Vec::new()).unwrap();
    let seq = probe_ivf(&ivf, &Limits::default()).unwrap().1.sequence_header.unwrap();
    assert_eq!(seq.color.bit_depth, 8);
    let cicp = seq.color.color_description.unwrap();
    assert_eq!((cicp.color_primaries, cicp.transfer_characteristics, cicp.matrix_coefficients), (1, 13, 1));
    let mut dec = Av1Codec.begin_decode(ivf.into(), &DecodeOptions::new(Limits::default())).unwrap();
    assert_eq!(dec.info().color.primaries, ColorPrimaries::Bt709);
    assert!(dec.info().format.contains("8-bit 4:2:0 BT.709 sRGB"), "{}", dec.info().format);
    for source in &frames {
        let want = sdr.display_light(source);
        let got = dec.next_frame().unwrap().unwrap();
        // Compared where the eye compares them, in the sRGB signal: the mean and the worst error.
        let (mut sum, mut worst) = (0.0f64, 0.0f64);
        for (a, b) in want.samples().iter().zip(got.samples()) {
            let d = (hdrcodec_core::SrgbTransfer::encode(f64::from(*a))
                - hdrcodec_core::SrgbTransfer::encode(f64::from(*b)))
            .abs();
            sum += d;
            worst = worst.max(d);
        }
        let mean = sum / want.samples().len() as f64;
        eprintln!(
            "SDR 100 cd/m², q20: mean |Δ sRGB signal| {:.4} ({:.2} of 8-bit codes), worst {worst:.3}",
            mean,
            mean * 219.0
        );
        assert!(mean < 1.0 / 219.0 && worst < 0.08, "mean {mean}, worst {worst}");
    }
    assert!(dec.next_frame().unwrap().is_none());
}

/// The generated pan (a 64x48 window moving corner to corner over a 160x120 scene, here the
/// moving light's first frame, 4 frames): HDR10 through the trait at quantizer 30 decodes to
/// every frame of the pan within a PU21-PSNR bound (measured 62.2, 41.5, 42.5, 51.5 dB: the
/// frames that cross the light's edge cost most; bound 40), and the frames are the window's own
/// (each decoded frame is at least 20 dB closer to its source than to the next frame's; measured
/// 1.5–4.9 dB against the next).
#[test]
fn a_pan_round_trips_through_the_trait() {
    use hdrcodec_core::metrics::pu21_psnr;
    use hdrcodec_video::sequences::pan_frame;
    let scene = moving_light_frame(160, 120, 2000.0, 12.0, 0, 1);
    let frames: Vec<HdrImage> = (0..4).map(|t| pan_frame(&scene, 64, 48, t, 4).unwrap()).collect();
    let ivf = encode(&frames, &ImageInfo::of(&frames[0]).with_frames(4), &fast());
    let mut dec = Av1Codec.begin_decode(ivf.into(), &DecodeOptions::new(Limits::default())).unwrap();
    let decoded: Vec<HdrImage> = std::iter::from_fn(|| dec.next_frame().unwrap()).collect();
    assert_eq!(decoded.len(), 4);
    for (t, (source, back)) in frames.iter().zip(&decoded).enumerate() {
        let own = pu21_psnr(source, back).unwrap();
        let other = pu21_psnr(&frames[(t + 1) % 4], back).unwrap();
        eprintln!("pan frame {t}: PU21-PSNR {own:.1} dB against its source, {other:.1} against the next");
        assert!(own > 40.0 && own > other + 20.0, "frame {t}: {own:.1} / {other:.1} dB");
    }
}

/// A writer whose bytes the test can still read after the encoder took it.
#[derive(Clone, Default)]
struct SharedWriter(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for SharedWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// `begin_encode` to MP4 or Matroska holds the file in memory: within `max_memory`, else
/// `LimitExceeded` and nothing reaches the writer.
#[test]
fn mp4_and_matroska_built_in_memory_are_bounded_by_max_memory() {
    let frames = frames(4, 4000.0);
    let info = ImageInfo::of(&frames[0]).with_frames(4);
    for container in ["mp4", "mkv"] {
        let full = encode(&frames, &info, &fast().with_option("container", container));
        // Room for the whole file: the same bytes as without the option.
        let roomy =
            fast().with_option("container", container).with_option("max_memory", (full.len() + 4096).to_string());
        assert_eq!(encode(&frames, &info, &roomy), full, "{container}");
        // Room for less than the stream: an error naming the limit, and an untouched writer.
        let tight = fast().with_option("container", container).with_option("max_memory", (full.len() / 2).to_string());
        let out = SharedWriter::default();
        let mut enc = Av1Codec.begin_encode(&info, &tight, Box::new(out.clone())).unwrap();
        let result = frames.iter().try_for_each(|f| enc.push_frame(f)).and_then(|()| enc.finish().map(|_| ()));
        match result {
            Err(Error::LimitExceeded { what }) => assert!(what.contains("in memory"), "{what}"),
            other => panic!("{container}: {other:?}"),
        }
        assert!(out.0.lock().unwrap().is_empty(), "{container}: bytes written before the error");
    }
    let bad = fast().with_option("container", "mp4").with_option("max_memory", "lots");
    assert!(Av1Codec.begin_encode(&info, &bad, Box::new(std::io::sink())).is_err());
}

/// `transfer=mantiuk bits=10` through the trait: a 10-bit Main-profile stream of L_p u'v'.
#[test]
fn mantiuk_in_10_bit_planes_through_the_trait() {
    let frames = frames(2, 2000.0);
    let info = ImageInfo::of(&frames[0]).with_frames(2);
    let settings = fast().with_option("transfer", "mantiuk").with_option("chroma", "420").with_option("bits", "10");
    let ivf = encode(&frames, &info, &settings);
    let (_, summary) = hdrcodec_video::decode::probe_ivf(&ivf, &Limits::default()).unwrap();
    let seq = summary.sequence_header.unwrap();
    assert_eq!((seq.profile, seq.color.bit_depth), (0, 10));
    let mut dec = Av1Codec.begin_decode(ivf.into(), &DecodeOptions::new(Limits::default())).unwrap();
    assert!(dec.info().format.contains("10-bit 4:2:0 L_p u'v'"), "{}", dec.info().format);
    assert!(dec.next_frame().unwrap().is_some());
    // 11 bits is no plane depth; HDR10 (the default transfer) takes no `bits`.
    for bad in [fast().with_option("transfer", "mantiuk").with_option("bits", "11"), fast().with_option("bits", "10")] {
        assert!(Av1Codec.begin_encode(&info, &bad, Box::new(std::io::sink())).is_err(), "{bad:?}");
    }
}
