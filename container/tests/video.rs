//! `HdrcVideoCodec`: frame streams written frame by frame and read one frame at a time, checked
//! against the whole-sequence `encode_frames` / `decode_frames`.

use hdrcodec_container::{decode_frames, encode_frames, HdrcVideoCodec, Head, RawF16Codec, RawF32Codec, Writer};
use hdrcodec_core::{
    Channels, ColorInfo, ColorPrimaries, ContentLightLevel, DecodeOptions, EncodeSettings, Error, Hdr10Metadata,
    HdrImage, ImageCodec, ImageInfo, Limits, ThreadPool, VideoCodec,
};
use std::io::Write;
use std::sync::{Arc, Mutex};

fn raw(id: [u8; 4]) -> Option<&'static dyn ImageCodec> {
    match &id {
        b"RF32" => Some(&RawF32Codec),
        b"RF16" => Some(&RawF16Codec),
        _ => None,
    }
}

/// A deterministic pattern over many decades, different for every frame.
fn frame(w: u32, h: u32, ch: Channels, seed: u32, color: &ColorInfo) -> HdrImage {
    let n = (w * h) as usize * ch.count();
    let samples = (0..n as u32)
        .map(|i| {
            let r = (i ^ seed.wrapping_mul(0x9E37_79B9)).wrapping_mul(2_654_435_761) >> 8;
            (r % 10_000) as f32 * 10f32.powi((r % 9) as i32 - 4) / 7.0
        })
        .collect();
    HdrImage::new(w, h, ch, samples, color.clone()).unwrap()
}

fn stream_color() -> ColorInfo {
    ColorInfo {
        primaries: ColorPrimaries::Bt2020,
        nits_per_unit: 203.0,
        hdr10: Some(Hdr10Metadata {
            mastering_display: None,
            content_light_level: Some(ContentLightLevel { max_cll: 1000, max_fall: 300 }),
        }),
    }
}

/// An output the test can read back after the encoder (which owns its `Box<dyn Write>`) is done.
#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Shared {
    fn bytes(&self) -> Vec<u8> {
        self.0.lock().unwrap().clone()
    }
}

/// An output that fails once `room` bytes have been written (a full disk, a closed pipe).
struct Full {
    room: usize,
}

impl Write for Full {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        if b.len() > self.room {
            return Err(std::io::Error::new(std::io::ErrorKind::StorageFull, "disk full"));
        }
        self.room -= b.len();
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn info_of(frames: &[HdrImage]) -> ImageInfo {
    let f = &frames[0];
    ImageInfo::new(f.width(), f.height(), f.channels(), f.color.clone()).with_frames(frames.len() as u32)
}

/// Streams `frames` through the video encoder; returns the file.
fn stream(codec: &HdrcVideoCodec, frames: &[HdrImage], settings: &EncodeSettings) -> Vec<u8> {
    let out = Shared::default();
    let mut enc = codec.begin_encode(&info_of(frames), settings, Box::new(out.clone())).unwrap();
    let mut tiles_out = 0;
    for f in frames {
        enc.push_frame(f).unwrap();
        // Written as it comes: each frame's tiles are in the output before the next frame.
        let now = out.bytes().windows(4).filter(|w| w == b"DATA").count();
        assert!(now > tiles_out, "push_frame wrote no tile");
        tiles_out = now;
    }
    assert_eq!(enc.finish().unwrap(), frames.len() as u64);
    out.bytes()
}

#[test]
fn streamed_frames_equal_encode_frames_and_decode_one_at_a_time() {
    let codec = HdrcVideoCodec::default();
    let color = stream_color();
    for (ch, tile, payload) in [(Channels::Rgba, Some(32), "raw-f32"), (Channels::Rgb, None, "raw-f16")] {
        let mut frames: Vec<HdrImage> = (0..5).map(|i| frame(70, 33, ch, i, &color)).collect();
        frames[0].set_metadata("software", "video test");
        let mut settings =
            EncodeSettings::default().with_option("payload", payload).with_pool(ThreadPool::new(2).unwrap());
        if let Some(t) = tile {
            settings = settings.with_option("tile", t.to_string());
        }
        let file = stream(&codec, &frames, &settings);
        // The same bytes as the whole-sequence encoder with the same payload and tiles.
        let payload_codec: &dyn ImageCodec = if payload == "raw-f32" { &RawF32Codec } else { &RawF16Codec };
        let whole = encode_frames(&frames, payload_codec, &EncodeSettings::default(), tile).unwrap();
        assert_eq!(file, whole, "{ch:?} {payload}");
        // One frame at a time equals decode_frames.
        let expect = decode_frames(&whole, &DecodeOptions::new(Limits::default()), &raw).unwrap();
        let mut dec = codec.begin_decode(Arc::from(file), &DecodeOptions::new(Limits::default())).unwrap();
        let info = dec.info().clone();
        assert_eq!((info.width, info.height, info.channels, info.frames), (70, 33, ch, 5));
        assert_eq!(info.color, color);
        let tiles = if tile.is_some() { "6 tiles of 32x32" } else { "untiled" };
        assert_eq!(info.format, format!("{payload} payload, {tiles}"));
        let mut got = Vec::new();
        while let Some(f) = dec.next_frame().unwrap() {
            got.push(f);
        }
        assert_eq!(got, expect);
        assert!(dec.next_frame().unwrap().is_none());
        if payload == "raw-f32" {
            // Lossless; META (the first frame's metadata) is every decoded frame's.
            for (g, f) in got.iter().zip(&frames) {
                assert!(g.samples() == f.samples() && g.color == f.color, "raw-f32 is lossless");
                assert_eq!(g.metadata, frames[0].metadata);
            }
        }
    }
}

#[test]
fn the_decoder_holds_one_frame_not_the_sequence() {
    let color = ColorInfo::default();
    let frames: Vec<HdrImage> = (0..8).map(|i| frame(64, 64, Channels::Rgb, i, &color)).collect();
    let file = stream(&HdrcVideoCodec::default(), &frames, &EncodeSettings::default());
    // Room for one decoded frame (48 KiB of samples) and its tile, not for eight.
    let limits = Limits::default().with_max_alloc_bytes(64 * 64 * 3 * 4 * 2);
    assert!(decode_frames(&file, &DecodeOptions::new(limits.clone()), &raw).is_err());
    let mut dec = HdrcVideoCodec::default().begin_decode(Arc::from(file), &DecodeOptions::new(limits)).unwrap();
    for f in &frames {
        assert_eq!(&dec.next_frame().unwrap().unwrap(), f);
    }
}

#[test]
fn frames_that_do_not_fit_the_stream_are_refused() {
    let codec = HdrcVideoCodec::default();
    let color = stream_color();
    let frames: Vec<HdrImage> = (0..3).map(|i| frame(16, 8, Channels::Rgb, i, &color)).collect();
    let out = Shared::default();
    let mut enc = codec.begin_encode(&info_of(&frames), &EncodeSettings::default(), Box::new(out.clone())).unwrap();
    enc.push_frame(&frames[0]).unwrap();
    let refused = [
        frame(17, 8, Channels::Rgb, 9, &color),
        frame(16, 8, Channels::Rgba, 9, &color),
        frame(16, 8, Channels::Rgb, 9, &ColorInfo::default()),
    ];
    for bad in &refused {
        let e = enc.push_frame(bad).unwrap_err();
        assert!(matches!(e, Error::Invalid { .. }), "{e}");
        assert!(e.to_string().contains("frame 1"), "{e}");
    }
    // A refused frame writes nothing: the stream goes on and is valid.
    enc.push_frame(&frames[1]).unwrap();
    enc.push_frame(&frames[2]).unwrap();
    let e = enc.push_frame(&frames[0]).unwrap_err().to_string();
    assert!(e.contains("begun for 3 frames"), "{e}");
    enc.finish().unwrap();
    let back = decode_frames(&out.bytes(), &DecodeOptions::new(Limits::default()), &raw).unwrap();
    assert_eq!(back, frames);

    // Fewer frames than HEAD promised: `finish` fails.
    let mut enc =
        codec.begin_encode(&info_of(&frames), &EncodeSettings::default(), Box::new(Shared::default())).unwrap();
    enc.push_frame(&frames[0]).unwrap();
    let e = enc.finish().unwrap_err().to_string();
    assert!(e.contains("1 of the 3 frames"), "{e}");
    // An unknown frame count cannot be written into HEAD.
    let unknown = info_of(&frames).with_frames(0);
    let e = codec.begin_encode(&unknown, &EncodeSettings::default(), Box::new(Shared::default())).err().unwrap();
    assert!(e.to_string().contains("frame count up front"), "{e}");
    // Options are checked as HdrcCodec checks them.
    let bad = EncodeSettings::default().with_option("payload", "nope");
    assert!(codec.begin_encode(&info_of(&frames), &bad, Box::new(Shared::default())).is_err());
}

#[test]
fn a_failing_output_is_an_error_and_stops_the_stream() {
    let color = ColorInfo::default();
    let frames: Vec<HdrImage> = (0..3).map(|i| frame(16, 8, Channels::Rgb, i, &color)).collect();
    let full = stream(&HdrcVideoCodec::default(), &frames, &EncodeSettings::default()).len();
    let mut failed_pushes = 0;
    for room in [0, 10, 60, full / 2, full - 1] {
        let codec = HdrcVideoCodec::default();
        let enc = codec.begin_encode(&info_of(&frames), &EncodeSettings::default(), Box::new(Full { room }));
        let Ok(mut enc) = enc else { continue };
        let pushed: Vec<bool> = frames.iter().map(|f| enc.push_frame(f).is_ok()).collect();
        let finished = enc.finish();
        assert!(finished.is_err(), "room {room}: {pushed:?}");
        // Once a push fails, no later push succeeds.
        if let Some(first_bad) = pushed.iter().position(|ok| !ok) {
            assert!(pushed[first_bad..].iter().all(|ok| !ok), "room {room}: {pushed:?}");
            failed_pushes += 1;
        }
    }
    assert!(failed_pushes > 0, "no case failed in push_frame");
}

#[test]
fn truncated_or_damaged_streams_are_errors_never_panics() {
    let color = stream_color();
    let frames: Vec<HdrImage> = (0..3).map(|i| frame(20, 10, Channels::Rgba, i, &color)).collect();
    let codec = HdrcVideoCodec::default();
    let file = stream(&codec, &frames, &EncodeSettings::default().with_option("tile", "8"));
    let options = DecodeOptions::new(Limits::default());
    for n in 0..file.len() {
        assert!(codec.begin_decode(Arc::from(&file[..n]), &options).is_err(), "truncated to {n}");
    }
    for at in (0..file.len()).step_by(7) {
        let mut bad = file.clone();
        bad[at] ^= 0x20;
        // A damaged byte fails the CRC (or a check before it) at the start; nothing is decoded.
        assert!(codec.begin_decode(Arc::from(bad), &options).is_err(), "byte {at}");
    }
    // A payload codec the decoder does not have.
    let head = Head::new(*b"QQQQ", 2, 1, Channels::Rgb);
    let mut w = Writer::new(Vec::new(), &head).unwrap();
    w.write_data(&head.tile(0, 0, 0), b"not ours").unwrap();
    let e = codec.begin_decode(Arc::from(w.finish().unwrap()), &options).err().unwrap();
    assert!(matches!(e, Error::Unsupported { .. }), "{e}");
}
