//! What each fuzz target does with its input, one function per target, shared by the targets
//! (`fuzz_targets/<target>.rs`, which include this file) and by the workspace test
//! `tests/fuzz_regressions.rs`, which replays every input under `fuzz/regressions/<target>/`
//! through the same function. Each function returns normally or panics (an assertion on the
//! decoders' contract); results of the decoders themselves may be `Ok` or `Err`.
//!
//! Beyond "no panic, no allocation past `Limits::fuzzing()`", every target checks that the
//! codec's header-only `probe` agrees with its decoder: where decoding succeeds, probing must
//! succeed too and give the same size, channels and colour; and that its `probe_from` (the
//! header read from a file) gives what `probe` gives: the same answer or an error of the same kind.

use hdrcodec_bc6h::ktx2::read_ktx2_primaries;
use hdrcodec_bc6h::modes::{pack_block, unpack_block};
use hdrcodec_bc6h::{decode_block, decode_surface, read_dds, read_ktx2, write_dds, write_ktx2};
use hdrcodec_bc6h::{Bc6hDdsCodec, Bc6hKtx2Codec};
use hdrcodec_container::{decode_frames, HdrcCodec, RawF16Codec, RawF32Codec, Reader, SeekReader};
use hdrcodec_core::{EncodeSettings, HdrImage, ImageCodec, ImageInfo, Limits, Result};
use hdrcodec_exr::{ExrCodec, ExrCompression};
use hdrcodec_jpeghdr::{GainMapJpegCodec, Rendering};
use hdrcodec_jxr::JxrCodec;
use hdrcodec_logluv::{raster_to_image, read_tiff, DecodeOptions, Encoding, LogLuvTiffCodec};
use hdrcodec_pfm::PfmCodec;
use hdrcodec_rgbe::{decode, encode, MantissaDecode, RgbeDecodeOptions, RgbeEncodeOptions, Rounding};

/// What a target does with one input.
pub type Target = fn(&[u8]);

/// Every target, by the name cargo-fuzz knows it by (`fuzz/Cargo.toml`).
pub const TARGETS: [(&str, Target); 13] = [
    ("bc6h_block", bc6h_block),
    ("bc6h_files", bc6h_files),
    ("container", container),
    ("exr", exr),
    ("gainmap_jpeg", gainmap_jpeg),
    ("ivf_obu", ivf_obu),
    ("jpeg_metadata", jpeg_metadata),
    ("jxr", jxr),
    ("logluv", logluv),
    ("mp4", mp4),
    ("pfm", pfm),
    ("rgbe", rgbe),
    ("y4m", y4m),
];

/// Where `decoded` succeeded, `probed` must have too, with the same header facts.
fn probe_agrees(codec: &str, probed: Result<ImageInfo>, decoded: &Result<HdrImage>) {
    if let Ok(img) = decoded {
        let info = probed.unwrap_or_else(|e| panic!("{codec}: decode succeeds but probe fails: {e}"));
        assert_eq!(
            (info.width, info.height, info.channels, &info.color),
            (img.width(), img.height(), img.channels(), &img.color),
            "{codec}: probe and decode disagree"
        );
    }
}

/// Runs `codec`'s probe and decode on `data`; checks that they agree; returns the decode.
fn probe_and_decode(codec: &dyn ImageCodec, data: &[u8], limits: &Limits) -> Result<HdrImage> {
    let probed = codec.probe(data, limits);
    let decoded = codec.decode(data, limits);
    from_a_file_agrees(codec, data, limits, &probed, decoded.is_err());
    probe_agrees(codec.name(), probed, &decoded);
    decoded
}

/// `codec.probe_from` on `data` as a file says what `probed` (its `probe`) says: the same
/// answer, or an error of the same kind. `.hdrc` reads its structure from a file as its stream
/// decoder does (tile headers, index, META), so it may refuse what `probe` takes where decoding
/// (`decode_fails`) fails too, and of a damaged file it reports the first problem that walk
/// meets, which may be of another kind than `probe`'s.
fn from_a_file_agrees(
    codec: &dyn ImageCodec,
    data: &[u8],
    limits: &Limits,
    probed: &Result<ImageInfo>,
    decode_fails: bool,
) {
    let from = codec.probe_from(&mut std::io::Cursor::new(data), limits);
    match (probed, &from) {
        // Compared as printed: a NaN chromaticity (which OpenEXR headers can hold) is not equal
        // to itself.
        (Ok(p), Ok(f)) => {
            assert_eq!(format!("{p:?}"), format!("{f:?}"), "{}: probe_from and probe disagree", codec.name())
        }
        (Err(_), Err(_)) if codec.name() == "hdrc" => {}
        (Err(p), Err(f)) => assert_eq!(
            std::mem::discriminant(p),
            std::mem::discriminant(f),
            "{}: probe said {p}, probe_from {f}",
            codec.name()
        ),
        (Ok(_), Err(_)) if codec.name() == "hdrc" && decode_fails => {}
        (p, f) => panic!("{}: probe said {p:?}, probe_from {f:?}", codec.name()),
    }
}

/// The `.hdrc` container: the validating `Reader` and the whole decode path (`decode_frames`
/// with the raw payload codecs, `HdrcCodec::decode` and `probe`), the decode from a stream
/// (`HdrcCodec::decode_from`, which must agree with it) and the index-driven `SeekReader`. Fuzzing builds (`--cfg fuzzing`) skip the CRC check so that mutations reach
/// the chunk parsers behind it.
pub fn container(data: &[u8]) {
    fn raw(id: [u8; 4]) -> Option<&'static dyn ImageCodec> {
        match &id {
            b"RF32" => Some(&RawF32Codec),
            b"RF16" => Some(&RawF16Codec),
            _ => None,
        }
    }
    let limits = Limits::fuzzing();
    if let Ok(r) = Reader::new(data, &limits) {
        let h = *r.head();
        let _ = (r.color(), r.hdr10(), r.metadata(), r.color_info());
        // Every tile the grid promises is there, and random access finds exactly it.
        for d in r.data_chunks() {
            let (c, row) = (d.header.x / h.tile_width, d.header.y / h.tile_height);
            assert_eq!(r.tile(d.header.frame, c, row).map(|t| t.offset), Some(d.offset));
        }
        assert_eq!(r.data_chunks().len() as u64, u64::from(h.frames) * h.tiles_per_frame());
        // The probe reads the same HEAD and colour from a file the reader accepts.
        let p = hdrcodec_container::probe(data, &limits).expect("a file the reader accepts probes");
        assert_eq!((p.head, &p.color), (h, &r.color_info()));
        if let Ok(frames) = decode_frames(data, &limits.clone().into(), &raw) {
            assert_eq!(frames.len() as u64, u64::from(h.frames));
            for f in &frames {
                assert_eq!((f.width(), f.height(), f.channels()), (h.width, h.height, h.channels));
            }
        }
    }
    let from_memory = probe_and_decode(&HdrcCodec::default(), data, &limits);
    // Decoded from a stream (each DATA chunk read as it is decoded): the image decoded from
    // memory, or an error; where only one of them fails, it is for holding a few chunks more
    // or fewer within the budget.
    let options = limits.clone().into();
    let from_stream = HdrcCodec::default().decode_from(&mut std::io::Cursor::new(data), &options);
    match (&from_memory, &from_stream) {
        (Ok(a), Ok(b)) => {
            let bits = |i: &HdrImage| i.samples().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!((bits(a), &a.color, &a.metadata), (bits(b), &b.color, &b.metadata));
        }
        (Ok(_), Err(e)) | (Err(e), Ok(_)) => {
            assert!(matches!(e, hdrcodec_core::Error::LimitExceeded { .. }), "only one path failed: {e}")
        }
        (Err(_), Err(_)) => {}
    }
    if let Ok(mut s) = SeekReader::new(std::io::Cursor::new(data), &limits) {
        let h = *s.head();
        // Bounded: `new` checked that the file can hold a DATA chunk per tile.
        for f in 0..h.frames {
            for row in 0..h.tile_rows() {
                for c in 0..h.tile_columns() {
                    if let Ok((t, _)) = s.read_tile(f, c, row) {
                        assert_eq!(t, h.tile(f, c, row));
                    }
                }
            }
        }
    }
}

/// OpenEXR: `Ok` or `Err`, never a panic (a panic inside the `exr` crate is caught by the codec
/// and returned as `Error::Invalid`), never an allocation past the limits. A successful decode
/// is re-encoded with a compression picked by the last input byte and decoded again.
pub fn exr(data: &[u8]) {
    let limits = Limits::fuzzing();
    if let Ok(img) = probe_and_decode(&ExrCodec, data, &limits) {
        if img.pixel_count() <= 1 << 14 {
            let flags = data.last().copied().unwrap_or(0) as usize;
            let c = ExrCompression::ALL[flags % ExrCompression::ALL.len()];
            let pixel = if flags & 0x80 == 0 { "half" } else { "float" };
            let settings = EncodeSettings::default().with_option("compression", c.name()).with_option("pixel", pixel);
            let bytes = ExrCodec.encode(&img, &settings).expect("a decoded image always encodes");
            let back = ExrCodec.decode(&bytes, &limits).expect("our own output always decodes");
            assert_eq!((back.width(), back.height(), back.channels()), (img.width(), img.height(), img.channels()));
        }
    }
}

/// PFM: a successful decode is re-encoded and must decode to the same samples (bitwise: PFM
/// stores `f32` exactly).
pub fn pfm(data: &[u8]) {
    let limits = Limits::fuzzing();
    if let Ok(img) = probe_and_decode(&PfmCodec, data, &limits) {
        let bytes = PfmCodec.encode(&img, &EncodeSettings::default()).expect("a decoded image always encodes");
        let back = PfmCodec.decode(&bytes, &limits).expect("our own output always decodes");
        let same = img.samples().iter().zip(back.samples()).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same && img.samples().len() == back.samples().len(), "PFM round trip changed samples");
    }
}

/// Gain-map JPEG: the file's structure and metadata (MPF, XMP, ISO 21496-1, ICC), `probe`
/// against the full HDR decode, and a decode for a display of headroom 2.
pub fn gainmap_jpeg(data: &[u8]) {
    // zune-jpeg 0.4 panics on some malformed streams; the codec catches those calls and
    // returns an error, which is its contract. libfuzzer-sys's panic hook aborts on every
    // panic, caught or not, so under the fuzzer this target keeps the default hook: a panic
    // that leaves the codec still reaches libfuzzer-sys's own catch and aborts.
    #[cfg(fuzzing)]
    {
        static HOOK: std::sync::Once = std::sync::Once::new();
        HOOK.call_once(|| {
            let _ = std::panic::take_hook();
        });
    }
    let limits = Limits::fuzzing();
    let _ = probe_and_decode(&GainMapJpegCodec, data, &limits);
    let _ = hdrcodec_jpeghdr::decode(data, &limits, Rendering { headroom: Some(2.0) });
}

/// IVF and AV1 OBU parsing (hdrcodec-video without its encoder and decoder): the IVF reader
/// under `Limits::fuzzing()`, the OBU walker, sequence header and metadata OBU parsers on each
/// frame, and the same parsers on the raw input as one temporal unit; the Matroska/WebM reader
/// (EBML header, first video track with its Colour element, every block of the track within
/// the input and the limits). What parses as a mastering display or a leb128 number must write
/// back to the same value.
pub fn ivf_obu(data: &[u8]) {
    use hdrcodec_video::ivf::IvfReader;
    use hdrcodec_video::mkv::MkvTrack;
    use hdrcodec_video::obu::{
        mdcv_body, read_leb128, write_leb128, Metadata, ObuReader, SequenceHeader, StreamSummary,
    };
    let limits = Limits::fuzzing();
    if let Ok(mut reader) = IvfReader::new(data, &limits) {
        let mut summary = StreamSummary::default();
        while let Ok(Some(frame)) = reader.next_frame() {
            assert!(frame.data.len() as u64 <= limits.max_alloc_bytes);
            if summary.add_temporal_unit(frame.data).is_err() {
                break;
            }
        }
        let _ = summary.hdr10();
    }
    if let Ok(track) = MkvTrack::first_video(data, &limits) {
        let mut blocks = track.blocks();
        let mut summary = StreamSummary::default();
        while let Ok(Some(frame)) = blocks.next_frame() {
            assert!(frame.len() as u64 <= limits.max_alloc_bytes);
            if summary.add_temporal_unit(frame).is_err() {
                break;
            }
        }
    }
    for obu in ObuReader::new(data).flatten() {
        let _ = SequenceHeader::parse(obu.payload);
        match Metadata::parse(obu.payload) {
            Ok(Metadata::MasteringDisplay(units)) => {
                let mut again = vec![hdrcodec_video::obu::metadata_type::HDR_MDCV as u8];
                again.extend_from_slice(&mdcv_body(&units));
                assert_eq!(Metadata::parse(&again).ok(), Some(Metadata::MasteringDisplay(units)), "MDCV write-back");
            }
            Ok(Metadata::ItuT35 { country_code, payload, .. }) => lpuv_t35(country_code, payload),
            _ => {}
        }
    }
    // The L_p u'v' T.35 parser on the raw bytes too: country code first, then the payload.
    if let Some((&country_code, payload)) = data.split_first() {
        lpuv_t35(country_code, payload);
    }
    let _ = StreamSummary::default().add_temporal_unit(data);
    if let Ok((value, len)) = read_leb128(data) {
        let mut out = Vec::new();
        write_leb128(&mut out, value);
        assert!(out.len() <= len && read_leb128(&out).ok() == Some((value, out.len())), "leb128 write-back");
    }
}

/// The L_p u'v' T.35 message parser: what it accepts, written back, parses to the same.
fn lpuv_t35(country_code: u8, payload: &[u8]) {
    use hdrcodec_video::lpuv_av1::LpuvStreamInfo;
    if let Ok(Some(info)) = LpuvStreamInfo::from_t35(country_code, payload) {
        let again = LpuvStreamInfo::from_t35(country_code, &info.to_t35_payload());
        assert_eq!(again.ok().flatten(), Some(info), "L_p u'v' T.35 write-back");
    }
}

/// MP4 (ISO base media file) reading: the box walker, the video track's sample table (every
/// sample within the input and the limits), the whole probe (AV1 OBUs or HEVC parameter sets
/// and SEI), and the HEVC parsers on the raw input; what `mdcv` parsing accepts writes back
/// to the same bytes.
pub fn mp4(data: &[u8]) {
    use hdrcodec_video::hevc::{hvcc_nal_units, sample_nal_units, HevcHdrSei, HevcSps};
    use hdrcodec_video::mp4::{mdcv_body, parse_mdcv, probe_mp4, BoxReader, Mp4Track};
    let limits = Limits::fuzzing();
    if let Ok(track) = Mp4Track::first_video(data, &limits) {
        for sample in track.samples().results() {
            match sample {
                Ok(s) => assert!(s.len() as u64 <= limits.max_alloc_bytes),
                Err(_) => break,
            }
        }
    }
    let _ = probe_mp4(data, &limits);
    let _ = BoxReader::new(data).boxes().count();
    let _ = HevcSps::parse(data);
    let mut sei = HevcHdrSei::default();
    let _ = sei.add_nal(data);
    for nal in sample_nal_units(data, 4).take(64) {
        match nal {
            Ok(nal) => {
                let _ = sei.add_nal(nal);
            }
            Err(_) => break,
        }
    }
    let _ = hvcc_nal_units(data);
    if let Ok(units) = parse_mdcv(data) {
        assert_eq!(mdcv_body(&units)[..], data[..24], "mdcv write-back");
    }
}

/// HDR JPEG's metadata parsers alone, each given the whole input (faster than the whole
/// decoder, which reaches them only through valid JPEG structure): the ISO 21496-1 record (and
/// what it writes back parses again), hdrgm / GContainer / Apple XMP, MPF, ICC primaries, the
/// JPEG-HDR header text, EXIF orientation and Apple's maker note, and the marker walker.
pub fn jpeg_metadata(data: &[u8]) {
    use hdrcodec_jpeghdr::{exif, icc, markers, metadata::GainMapMetadata, mpf, ratio::RatioHeader, xmp::Xmp};
    if let Ok(Some(m)) = GainMapMetadata::from_iso(data) {
        let again = GainMapMetadata::from_iso(&m.to_iso());
        assert!(matches!(again, Ok(Some(_))), "a record we write back must parse: {again:?}");
        let _ = (m.describe(), m.weight(1.5), m.full_hdr_weight());
    }
    if let Ok(x) = Xmp::new(data) {
        let _ = (x.hdrgm_version(), x.hdrgm_metadata(), x.container_items(), x.is_apple_gain_map(), x.apple_headroom());
    }
    let _ = mpf::parse(data, 0, 0);
    let _ = mpf::parse(data, usize::MAX / 2, usize::MAX / 4);
    let _ = icc::primaries(data);
    let _ = icc::assemble(data.chunks(97));
    let _ = RatioHeader::parse(&String::from_utf8_lossy(data));
    let _ = (exif::orientation(data), exif::apple_headroom_stops_in(data));
    if let Ok(image) = markers::parse_image(data, 0) {
        let _ = hdrcodec_jpeghdr::ratio::ratio_image(&image);
    }
    let _ = markers::next_image_start(data, data.len() / 2);
}

/// JPEG XR: the codec (probe and decode through the container, entropy decoding, the
/// transform and output formatting), jxrlib's raw samples for any pixel format, 1/4 and 1/16
/// resolution and a region, and the coefficients of the primary and planar alpha
/// codestreams, on one and two threads.
pub fn jxr(data: &[u8]) {
    let limits = Limits::fuzzing();
    let _ = probe_and_decode(&JxrCodec, data, &limits);
    let options = hdrcodec_core::DecodeOptions::new(limits.clone());
    // From a stream, each packet through the smallest window the bound allows: the same
    // samples as from memory, or (holding less) an error only where memory ran out too.
    let mut small = options.clone();
    small.options.push(("window".to_string(), "0".to_string()));
    let from_stream = JxrCodec.decode_from(&mut std::io::Cursor::new(data), &small);
    match (JxrCodec.decode_with(data, &options), from_stream) {
        (Ok(a), Ok(b)) => assert!(
            a.samples().iter().zip(b.samples()).all(|(x, y)| x.to_bits() == y.to_bits())
                && (a.width(), a.height(), a.channels()) == (b.width(), b.height(), b.channels()),
            "JPEG XR decoded from a stream differs from the decode from memory"
        ),
        (Err(_), Err(_))
        | (Err(hdrcodec_core::Error::LimitExceeded { .. }), Ok(_))
        | (Ok(_), Err(hdrcodec_core::Error::LimitExceeded { .. })) => {}
        (a, b) => panic!("JPEG XR from memory: {:?}, from a stream: {:?}", a.err(), b.err()),
    }
    let _ = hdrcodec_jxr::decode_raw(data, &options);
    if let Ok(c) = hdrcodec_jxr::container::parse_container(data) {
        let _ = hdrcodec_jxr::decode_coefficients(c.image, &options);
        if let Some(alpha) = c.alpha {
            let _ = hdrcodec_jxr::decode_coefficients(alpha, &options);
        }
        // Reduced resolutions, and a rectangle of the middle third (in stored orientation).
        use hdrcodec_jxr::{JxrDecodeRequest, Rect, Resolution};
        for resolution in [Resolution::Quarter, Resolution::Sixteenth] {
            let _ = hdrcodec_jxr::decode_raw_with(data, &options, &JxrDecodeRequest { region: None, resolution });
        }
        if let Ok(cs) = hdrcodec_jxr::header::parse(c.image) {
            let (w, h) = (cs.image.width, cs.image.height);
            let region = Some(Rect { x: w / 3, y: h / 3, width: (w / 3).max(1), height: (h / 3).max(1) });
            let _ = hdrcodec_jxr::decode_raw_with(data, &options, &JxrDecodeRequest { region, ..Default::default() });
        }
        // One pool for every input (starting threads per input would slow the fuzzer down).
        static POOL: std::sync::OnceLock<Option<hdrcodec_core::ThreadPool>> = std::sync::OnceLock::new();
        if let Some(pool) = POOL.get_or_init(|| hdrcodec_core::ThreadPool::new(2).ok()) {
            let _ = hdrcodec_jxr::decode_raw(data, &options.clone().with_pool(pool.clone()));
        }
    }
}

/// Radiance RGBE: both mantissa modes and the raw/exposure paths (picked by the first byte);
/// a successful decode is re-encoded (both roundings, flat or RLE) and decoded again.
pub fn rgbe(data: &[u8]) {
    let limits = Limits::fuzzing();
    let flags = data.first().copied().unwrap_or(0);
    let opts = RgbeDecodeOptions {
        apply_exposure: flags & 1 == 1,
        mantissa: if flags & 2 == 2 { MantissaDecode::Centred } else { MantissaDecode::Truncated },
    };
    let _ = hdrcodec_rgbe::read_header(data);
    let decoded = decode(data, &limits, &opts);
    let probed = hdrcodec_rgbe::probe(data, &limits);
    from_a_file_agrees(&hdrcodec_rgbe::RgbeCodec::default(), data, &limits, &probed, decoded.is_err());
    probe_agrees("rgbe", probed, &decoded);
    if let Ok(img) = decoded {
        if img.pixel_count() <= 1 << 16 {
            let rounding = if flags & 4 == 4 { Rounding::Nearest } else { Rounding::Truncate };
            let bytes = encode(&img, &RgbeEncodeOptions { rounding, rle: flags & 8 == 0, ..Default::default() })
                .expect("a decoded image always encodes");
            let back = decode(&bytes, &limits, &opts).expect("our own output always decodes");
            assert_eq!((back.width(), back.height()), (img.width(), img.height()));
        }
    }
}

/// LogLuv TIFF: the bounded TIFF/IFD reader, the SGILOG run-length decoder and the conversion
/// to an image. Whatever decodes must re-encode and read back to the same words.
pub fn logluv(data: &[u8]) {
    let limits = Limits::fuzzing();
    let _ = probe_and_decode(&LogLuvTiffCodec::new(Encoding::LogLuv32), data, &limits);
    if let Ok(raster) = read_tiff(data, &limits) {
        let img = raster_to_image(&raster, &DecodeOptions::default()).expect("a raster always converts");
        assert_eq!(img.pixel_count(), raster.words.len());
        let again = read_tiff(&raster.to_tiff().expect("a raster always writes"), &limits).expect("our file reads");
        assert_eq!(again.words, raster.words);
    }
}

/// BC6H blocks: every 16-byte block (UF16 and SF16) decodes without panicking, never to NaN,
/// to +Inf never and to -Inf only in SF16 (a mode-14 endpoint of -32768 finishes to 0xFC00, as
/// the spec's arithmetic gives), and its fields survive unpack -> pack unchanged.
pub fn bc6h_block(data: &[u8]) {
    for chunk in data.chunks_exact(16) {
        let block: &[u8; 16] = chunk.try_into().expect("16 bytes");
        for signed in [false, true] {
            for texel in decode_block(block, signed) {
                for h in texel {
                    let finite = h & 0x7C00 != 0x7C00;
                    assert!(finite || (signed && h == 0xFC00), "half {h:#06x} from {block:02x?}");
                }
            }
        }
        if let Some(fields) = unpack_block(block) {
            assert_eq!(&pack_block(&fields), block);
        }
    }
    // The surface decoder with a width derived from the data: sizes that disagree are errors.
    if let Some(&w) = data.first() {
        let w = u32::from(w % 16) + 1;
        let blocks = data.len() / 16;
        let bx = w.div_ceil(4) as usize;
        let h = (blocks / bx.max(1)) as u32 * 4;
        let _ = decode_surface(w, h, &data[..data.len() - data.len() % 16], data.len() % 2 == 1);
    }
}

/// BC6H DDS and KTX2 files: a file that parses is written back (KTX2 with the primaries it
/// read) and must read back identically.
pub fn bc6h_files(data: &[u8]) {
    let limits = Limits::fuzzing();
    let _ = probe_and_decode(&Bc6hDdsCodec, data, &limits);
    let _ = probe_and_decode(&Bc6hKtx2Codec, data, &limits);
    if let Ok(tex) = read_dds(data, &limits) {
        let again = read_dds(&write_dds(&tex).expect("a parsed texture writes"), &limits).expect("reads back");
        assert_eq!(again, tex);
    }
    if let Ok(tex) = read_ktx2(data, &limits) {
        let primaries = read_ktx2_primaries(data);
        let written = write_ktx2(&tex, primaries).expect("a parsed texture writes, with the primaries it read");
        let again = read_ktx2(&written, &limits).expect("reads back");
        assert_eq!(again, tex);
        assert_eq!(read_ktx2_primaries(&written), primaries);
    }
}

/// YUV4MPEG2 reading (hdrcodec-video's `y4m`): the header under `Limits::fuzzing()`, then every
/// frame (each within the limits and of the header's size) through the conversion to light,
/// until the end or the first error; and the header parser on the raw input.
pub fn y4m(data: &[u8]) {
    use hdrcodec_video::hdr10::Transfer;
    use hdrcodec_video::y4m::{Y4mHeader, Y4mReader};
    let limits = Limits::fuzzing();
    let _ = Y4mHeader::parse(data, &limits);
    let Ok(mut reader) = Y4mReader::new(data, &limits) else { return };
    let header = *reader.header();
    assert!(header.frame_bytes() <= limits.max_alloc_bytes);
    for transfer in [Transfer::Pq, Transfer::HLG_1000].into_iter().cycle().take(64) {
        match reader.next_frame() {
            Ok(Some(yuv)) => {
                assert_eq!((yuv.width as u32, yuv.height as u32), (header.width, header.height));
                let image = reader.frame_to_image(&yuv, transfer, 100.0).expect("a whole frame converts");
                assert!(image.samples().iter().all(|v| v.is_finite() && *v >= 0.0), "light from Y'CbCr");
            }
            Ok(None) | Err(_) => break,
        }
    }
}
