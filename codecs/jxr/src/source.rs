//! Where a codestream's bytes come from: held in memory, or read from a file through a window
//! per packet, so that decoding from a file never holds the file whole.
//!
//! A packet's bits are read by a [`BitReader`] over a slice, as in memory; between
//! macroblocks, [`Packet::reserve`] makes sure that the window holds at least what one
//! macroblock can consume ([`mb_bound`]) past the reader's position, sliding the window
//! (the unread tail moved to its front, the rest read from the file) when it does not. The
//! window always runs on to the codestream's end as the in-memory slice does (a packet that
//! runs into the next one reads the next one's bytes, as jxrlib does), so a reader sees the
//! same bits either way, and a reader that goes past a window that does not reach the end is
//! an error, never zeros.

use crate::bits::{BitReader, ReaderState};
use crate::header::Codestream;
use crate::mb::MB_COEFFS;
use hdrcodec_core::{Allocation, Error, Limits, ReadSeek, Result};
use std::sync::Mutex;

/// Reads bytes at an offset of a file; shared by the packets' windows, which the tiles of a
/// tile row refill from the pool's threads.
pub(crate) trait ReadAt: Sync {
    /// Fills `out` with the bytes at `offset`; a file that ends first is [`Error::Truncated`].
    fn read_at(&self, offset: u64, out: &mut [u8]) -> Result<()>;
    /// The limits windows are charged to.
    fn limits(&self) -> &Limits;
    /// How windows are sized and moved.
    fn tuning(&self) -> Tuning;
}

/// How windows are sized and moved: the defaults, or (tests) windows as small as the bound
/// allows, moved before every macroblock, or a bound that is too small.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Tuning {
    /// The smallest window, bytes (reads from the file are about this large).
    pub min_window: usize,
    /// Slide the window before every macroblock, not only when it runs low.
    pub slide_always: bool,
    /// Bytes one macroblock is assumed to consume at most, instead of [`mb_bound`] (tests of
    /// the error when a reader overruns its window).
    pub bound: Option<usize>,
}

impl Default for Tuning {
    fn default() -> Self {
        Tuning { min_window: 64 << 10, slide_always: false, bound: None }
    }
}

/// A file read from several threads in turn (a lock around the caller's reader).
pub(crate) struct SharedFile<'f> {
    input: Mutex<&'f mut dyn ReadSeek>,
    limits: Limits,
    tuning: Tuning,
}

impl<'f> SharedFile<'f> {
    /// `input`, whose offsets count from its start; windows charged to `limits`.
    pub fn new(input: &'f mut dyn ReadSeek, limits: &Limits, tuning: Tuning) -> Self {
        SharedFile { input: Mutex::new(input), limits: limits.clone(), tuning }
    }
}

impl ReadAt for SharedFile<'_> {
    fn read_at(&self, offset: u64, out: &mut [u8]) -> Result<()> {
        let mut input = self.input.lock().map_err(|_| Error::invalid("JPEG XR: a thread reading the file failed"))?;
        hdrcodec_core::read_exact_at(&mut **input, offset, out, "the JPEG XR file")
    }
    fn limits(&self) -> &Limits {
        &self.limits
    }
    fn tuning(&self) -> Tuning {
        self.tuning
    }
}

/// The bytes of one codestream: held in memory, or `len` bytes of a file from `start`.
#[derive(Clone, Copy)]
pub(crate) enum Source<'a> {
    /// The codestream's bytes.
    Memory(&'a [u8]),
    /// The codestream in a file.
    File {
        /// The file.
        file: &'a dyn ReadAt,
        /// The codestream's first byte in the file.
        start: u64,
        /// The codestream's length.
        len: u64,
    },
}

impl<'a> From<&'a [u8]> for Source<'a> {
    fn from(data: &'a [u8]) -> Self {
        Source::Memory(data)
    }
}

impl<'a> Source<'a> {
    /// The codestream's length, bytes.
    pub fn len(&self) -> u64 {
        match self {
            Source::Memory(d) => d.len() as u64,
            Source::File { len, .. } => *len,
        }
    }

    /// A reader of the packet at `offset` of the codestream (checked by the header parser to
    /// lie inside it), whose macroblocks each consume at most `bound` bytes: in memory, the
    /// bytes from `offset` to the codestream's end; from a file, a window of them, one of
    /// `open` read side by side (the packets of a tile row), which share the least window
    /// size ([`Tuning::min_window`]).
    pub fn packet(&self, offset: u64, bound: usize, open: usize) -> Result<Packet<'a>> {
        let past = || Error::invalid("JPEG XR: an index table entry points past the end of the codestream");
        match *self {
            Source::Memory(data) => {
                let bytes = data.get(usize::try_from(offset).map_err(|_| past())?..).ok_or_else(past)?;
                Ok(Packet {
                    bytes: Bytes::Memory(bytes),
                    state: ReaderState::default(),
                    #[cfg(test)]
                    last: 0.into(),
                })
            }
            Source::File { file, start, len } => {
                if offset > len {
                    return Err(past());
                }
                let tuning = file.tuning();
                let bound = tuning.bound.unwrap_or(bound);
                // The window: twice the bound, at least the packet's share of the tuning's
                // minimum, at most the rest of the codestream.
                let rest = len - offset;
                let least = tuning.min_window / open.max(1);
                let cap = (2 * bound + MARGIN).max(least).min(usize::try_from(rest).unwrap_or(usize::MAX));
                let charge = file.limits().charge(cap as u64, "a JPEG XR packet window")?;
                let mut buf = vec![0; cap];
                file.read_at(start + offset, &mut buf)?;
                let window = Window {
                    file,
                    buf,
                    cap,
                    at: start + offset,
                    end: start + len,
                    bound,
                    slide_always: tuning.slide_always,
                    _charge: charge,
                };
                Ok(Packet {
                    bytes: Bytes::Window(Box::new(window)),
                    state: ReaderState::default(),
                    #[cfg(test)]
                    last: 0.into(),
                })
            }
        }
    }
}

/// Bytes past a macroblock's bound that a window also holds: the bit reader loads 8 bytes at
/// a time, FLEXBITS groups load 8 bytes at their own bit position.
const MARGIN: usize = 16;

/// One packet being read.
pub(crate) struct Packet<'a> {
    bytes: Bytes<'a>,
    state: ReaderState,
    /// Tests: the reader's position at the last macroblock (see [`tests::MAX_MB_BITS`]).
    #[cfg(test)]
    last: std::cell::Cell<u64>,
}

enum Bytes<'a> {
    /// From the packet's start to the codestream's end.
    Memory(&'a [u8]),
    /// A window of the same bytes in a file.
    Window(Box<Window<'a>>),
}

/// Bytes `at .. at + buf.len()` of a file, in which a packet is read.
struct Window<'a> {
    file: &'a dyn ReadAt,
    buf: Vec<u8>,
    /// Bytes the window holds when full.
    cap: usize,
    /// Where `buf` starts in the file.
    at: u64,
    /// Where the codestream ends in the file.
    end: u64,
    /// Bytes a macroblock consumes at most.
    bound: usize,
    slide_always: bool,
    _charge: Allocation,
}

impl Window<'_> {
    /// True when the window holds the codestream's last byte.
    fn at_end(&self) -> bool {
        self.at + self.buf.len() as u64 >= self.end
    }
}

/// Bits a reader in state `s` has consumed, from the start of its data.
fn bit_pos(s: ReaderState, data: &[u8]) -> u64 {
    BitReader::resume(data, s).bit_pos()
}

impl<'a> Packet<'a> {
    /// Runs `f` on a reader at the packet's position, then keeps the reader's position.
    #[inline(always)]
    pub fn run<T>(&mut self, f: impl FnOnce(&mut BitReader) -> T) -> T {
        let data: &[u8] = match &self.bytes {
            Bytes::Memory(d) => d,
            Bytes::Window(w) => &w.buf,
        };
        let mut r = BitReader::resume(data, self.state);
        let out = f(&mut r);
        self.state = r.state();
        out
    }

    /// In memory, a reader at the packet's position over the bytes themselves (not borrowing
    /// the packet), for a loop over macroblocks that keeps it in a local and hands its state
    /// back with [`set_state`](Self::set_state); `None` for a window.
    #[inline(always)]
    pub fn memory_reader(&self) -> Option<BitReader<'a>> {
        match self.bytes {
            Bytes::Memory(d) => Some(BitReader::resume(d, self.state)),
            Bytes::Window(_) => None,
        }
    }

    /// A reader at the packet's position in its window (for a packet in memory, as
    /// [`memory_reader`](Self::memory_reader)); its state goes back with
    /// [`set_state`](Self::set_state).
    #[inline(always)]
    pub fn window_reader(&self) -> BitReader<'_> {
        match &self.bytes {
            Bytes::Memory(d) => BitReader::resume(d, self.state),
            Bytes::Window(w) => BitReader::resume(&w.buf, self.state),
        }
    }

    /// Where a reader from [`memory_reader`](Self::memory_reader) stopped.
    #[inline(always)]
    pub fn set_state(&mut self, state: ReaderState) {
        self.state = state;
    }

    /// Tests: counts what the macroblock before consumed of a packet in memory (the reader
    /// now at bit `bit`).
    #[cfg(test)]
    pub fn note(&self, bit: u64) {
        tests::note(&self.last, bit);
    }

    /// Before a macroblock: makes sure that the window holds at least what a macroblock can
    /// consume past the reader's position (in memory, all of it is there). A reader already
    /// past a window that does not reach the codestream's end is an error.
    #[inline(always)]
    pub fn reserve(&mut self) -> Result<()> {
        match &mut self.bytes {
            Bytes::Memory(_d) => {
                #[cfg(test)]
                tests::note(&self.last, bit_pos(self.state, _d));
                Ok(())
            }
            Bytes::Window(w) => {
                if w.at_end() {
                    return Ok(());
                }
                let bit = bit_pos(self.state, &w.buf);
                let held = w.buf.len() as u64 * 8;
                if bit > held {
                    return Err(overrun());
                }
                if w.slide_always || held - bit < (w.bound + MARGIN) as u64 * 8 {
                    self.state = slide(w, bit)?;
                }
                Ok(())
            }
        }
    }

    /// [`Error::Truncated`] naming `what` if the reader went past the codestream's end; an
    /// error too if it went past a window that does not reach it.
    pub fn check(&self, what: &str) -> Result<()> {
        match &self.bytes {
            Bytes::Memory(d) => {
                #[cfg(test)]
                tests::note(&self.last, bit_pos(self.state, d));
                BitReader::resume(d, self.state).check(what)
            }
            Bytes::Window(w) => {
                let r = BitReader::resume(&w.buf, self.state);
                if r.overrun() && !w.at_end() {
                    return Err(overrun());
                }
                r.check(what)
            }
        }
    }
}

fn overrun() -> Error {
    Error::invalid("JPEG XR: a macroblock read past its window of the file (a bug in the decoder's bound)")
}

/// Moves window `w` so that it starts at the byte of bit `bit` and holds as much as it can,
/// and gives the state of a reader at that bit.
#[cold]
#[inline(never)]
fn slide(w: &mut Window, bit: u64) -> Result<ReaderState> {
    let byte = (bit / 8) as usize;
    w.buf.drain(..byte);
    w.at += byte as u64;
    let held = w.buf.len();
    let want = (w.cap as u64).min(w.end - w.at) as usize;
    if want > held {
        w.buf.resize(want, 0);
        w.file.read_at(w.at + held as u64, &mut w.buf[held..])?;
    }
    let mut r = BitReader::new(&w.buf);
    r.seek(bit % 8);
    Ok(r.state())
}

/// Bits one channel of a macroblock consumes at most, counted from the syntax of T.832
/// clause 8.7 (what `macroblock` reads):
/// - each of its 256 coefficients (DC, 15 LP, 240 HP) at most 80 bits: a run-level symbol
///   (FIRST_INDEX / INDEX / the last positions' codes, Tables 59-61, at most 8 bits; the sign,
///   1; a run, RUN_INDEX and its raw bits, at most 8; ABSLEVEL_INDEX, Table 62, at most 8 with
///   its raw bits, or the escape: 4 + 2 + 3 bits of width and at most 29 raw bits, 38), 63
///   bits; and its refinement (REFINE_LP, FLEXBITS or the DC's model bits: at most 15, the
///   model's limit, and a sign bit), 16. The DC's flag and level fit in the same 80 bits;
/// - its share of MB_CBP (NUM_CBP, REFINE_CBP, four NUM_BLKCBP with their VALUE_012 codes,
///   raw bits and the chroma patterns: under 128 bits for the three channels of a YUV
///   macroblock, under 48 per channel otherwise), 128.
const CHANNEL_BITS: usize = 256 * 80 + 128;

/// Bits of a macroblock that are not one channel's: DC_YUV's flags (at most 5), CBPLP (at
/// most 16, one bit per channel), two quantizer indices (at most 1 + 4 each).
const MB_BITS: usize = 5 + 16 + 2 * 5;

/// Bytes one macroblock of the codestream `cs` consumes at most from any one of its packets,
/// its channels and its interleaved alpha channel together ([`CHANNEL_BITS`]); the tile
/// headers before a tile's first macroblock (quantizer sets: at most 33 of 2 + 8 bits a
/// channel, per plane) take less than a channel's share.
pub(crate) fn mb_bound(cs: &Codestream) -> usize {
    let channels = cs.primary.channels + cs.alpha.as_ref().map_or(0, |a| a.channels);
    (channels * CHANNEL_BITS + MB_BITS).div_ceil(8) + 8
}

// The coefficients the bound counts are a macroblock channel's.
const _: () = assert!(MB_COEFFS == 256);

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::vlc;
    use crate::JxrCodec;
    use hdrcodec_core::sink::ImageSink;
    use hdrcodec_core::{Channels, DecodeOptions, HdrImage, ImageCodec, ThreadPool};

    fn longest(codes: &[&str]) -> usize {
        codes.iter().map(|c| c.len()).max().unwrap_or(0)
    }

    /// The code lengths [`CHANNEL_BITS`] counts are the tables' (T.832 Tables 59-62 and the
    /// CBP tables).
    #[test]
    fn the_bound_counts_the_longest_codes() {
        let index = vlc::FIRST_INDEX_CODES
            .iter()
            .map(|t| longest(t))
            .chain(vlc::INDEX_CODES.iter().map(|t| longest(t)))
            .chain([longest(&vlc::INDEX2_CODES)])
            .max()
            .unwrap();
        assert!(index <= 8, "{index}");
        // RUN_INDEX and at most 3 raw bits (runs up to 14).
        assert!(longest(&vlc::RUN_INDEX_CODES) + 3 <= 8);
        let abs = vlc::ABS_LEVEL_CODES.iter().map(|t| longest(t)).max().unwrap();
        // A symbol: its index, sign, run and level, whose raw bits are at most 2 for the first
        // six ABSLEVEL_INDEX symbols and 4 + 2 + 3 + 29 after the escape.
        assert!(index + 1 + 8 + abs + 38 <= 63, "{index} {abs}");
        // MB_CBP of a YUV macroblock: NUM_CBP, REFINE_CBP, then per block NUM_BLKCBP, two
        // VALUE_012, two raw bits and, 4:4:4, two NUM_CH_BLK with their REFINE_CBP.
        let num_cbp = vlc::NUM_CBP_CODES.iter().map(|t| longest(t)).max().unwrap();
        let blk = vlc::NUM_BLKCBP_YUV_CODES.iter().map(|t| longest(t)).max().unwrap().max(num_cbp);
        let refine = longest(&vlc::REFINE_CBP2_CODES).max(2);
        let value = longest(&vlc::VALUE_012_CODES);
        let chroma = 2 * (longest(&vlc::NUM_CH_BLK_CODES) + refine);
        let yuv = num_cbp + refine + 4 * (blk + 2 * value + 2 + chroma);
        assert!(yuv <= 3 * 128, "{yuv}");
        let per_channel = num_cbp + refine + 4 * (num_cbp + 2 * value + 2);
        assert!(per_channel <= 128, "{per_channel}");
        assert!(longest(&vlc::DC_YUV_CODES) <= 5 && longest(&vlc::CBPLP_444_CODES) <= 16);
    }

    thread_local! {
        /// The most bits a macroblock (with whatever preceded it in its packet: the start code
        /// and the tile headers for the first) consumed from a packet held in memory, on
        /// this thread, since it was last reset.
        pub(super) static MAX_MB_BITS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
    }

    /// Counts what was consumed since the last macroblock (`last`), now at bit `bit`.
    pub(super) fn note(last: &std::cell::Cell<u64>, bit: u64) {
        let used = bit.saturating_sub(last.get());
        MAX_MB_BITS.with(|m| m.set(m.get().max(used)));
        last.set(bit);
    }

    fn testdata(name: &str) -> Vec<u8> {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("testdata").join(name);
        std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    fn options(threads: usize) -> DecodeOptions {
        DecodeOptions::new(Limits::default()).with_pool(ThreadPool::new(threads).unwrap())
    }

    /// The file decoded from memory, and the most bytes one of its macroblocks consumed from
    /// one packet (plus one for a start inside a byte).
    fn from_memory(file: &[u8], options: &DecodeOptions) -> (Result<HdrImage>, usize) {
        MAX_MB_BITS.with(|m| m.set(0));
        let image = JxrCodec.decode_with(file, options);
        (image, (MAX_MB_BITS.with(|m| m.get()) as usize).div_ceil(8) + 1)
    }

    fn from_stream(file: &[u8], options: &DecodeOptions, tuning: Tuning) -> Result<HdrImage> {
        let mut sink = ImageSink::new(&options.limits);
        crate::render::decode_rows_from_tuned(&mut std::io::Cursor::new(file), options, &mut sink, tuning)?;
        sink.finish()
    }

    fn same(a: &HdrImage, b: &HdrImage) -> bool {
        (a.width(), a.height(), a.channels()) == (b.width(), b.height(), b.channels())
            && a.samples().iter().zip(b.samples()).all(|(x, y)| x.to_bits() == y.to_bits())
    }

    /// Windows as small as the sound bound allows, moved before every macroblock or only when
    /// they run low.
    const SMALL: [Tuning; 2] = [
        Tuning { min_window: 0, slide_always: true, bound: None },
        Tuning { min_window: 0, slide_always: false, bound: None },
    ];

    /// Every test file decodes from a stream to the samples it decodes to from memory, on one
    /// thread and on two (tiles refilling their windows from the pool's threads): with the
    /// default windows, and with windows as small as each file allows (its own largest
    /// macroblock as the bound, at the limit), moved before every macroblock.
    #[test]
    fn test_files_decode_from_a_stream_as_from_memory() {
        let mut names: Vec<String> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/testdata"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.ends_with(".jxr"))
            .collect();
        names.sort();
        assert!(names.len() >= 20, "{names:?}");
        for name in &names {
            let file = testdata(name);
            let (want, used) = from_memory(&file, &options(1));
            let want = match want {
                Ok(image) => image,
                // 32bppCMYK has no linear RGB: the same error from a stream.
                Err(e @ Error::Unsupported { .. }) => {
                    let got = from_stream(&file, &options(1), Tuning::default()).unwrap_err();
                    assert_eq!(got.to_string(), e.to_string(), "{name}");
                    continue;
                }
                Err(e) => panic!("{name}: {e}"),
            };
            let at_limit = Tuning { min_window: 0, slide_always: true, bound: Some(used) };
            let runs_low = Tuning { slide_always: false, ..at_limit };
            for threads in [1, 2] {
                for tuning in [Tuning::default(), at_limit, runs_low] {
                    let got = from_stream(&file, &options(threads), tuning)
                        .unwrap_or_else(|e| panic!("{name}, {threads} threads, {tuning:?}: {e}"));
                    assert!(same(&got, &want), "{name}, {threads} threads, {tuning:?}");
                }
            }
        }
    }

    /// Images our encoder writes in both bitstream orders, with tiles of uneven sizes, alpha,
    /// band truncation and trimmed flexbits: large enough for windows of the sound bound to
    /// slide many times.
    fn generated() -> Vec<(String, Vec<u8>)> {
        use crate::encoder::{encode, BitstreamOrder, EncodeOptions};
        use crate::header::Bands;
        use crate::input::SampleFormat;
        let mut next = crate::testing::rng(7);
        let (w, h) = (200u32, 88u32);
        let mut out = Vec::new();
        for (i, channels) in [Channels::Rgb, Channels::Rgba].into_iter().enumerate() {
            // Smooth gradients with noise: HP and flexbits all busy.
            let samples: Vec<f32> = (0..(w * h) as usize * channels.count())
                .map(|k| ((k % 97) as f32 * 0.05 + (next() % 1000) as f32 / 300.0) * if k % 7 == 0 { 9.0 } else { 1.0 })
                .collect();
            let image = HdrImage::new(w, h, channels, samples, hdrcodec_core::ColorInfo::default()).unwrap();
            for (quality, order, tile_mbs, bands, trim) in [
                (100, BitstreamOrder::Spatial, 0, Bands::All, 0),
                (100, BitstreamOrder::Frequency, 0, Bands::All, 0),
                (100, BitstreamOrder::Frequency, 5, Bands::All, 0),
                (90, BitstreamOrder::Spatial, 4, Bands::All, 2),
                (95, BitstreamOrder::Frequency, 3, Bands::NoFlexbits, 0),
                (95, BitstreamOrder::Frequency, 0, Bands::NoHighpass, 0),
            ] {
                let format = if i == 0 { SampleFormat::Float } else { SampleFormat::Half };
                let options = EncodeOptions {
                    quality,
                    format,
                    order,
                    tile_mbs,
                    bands,
                    trim_flexbits: trim,
                    ..EncodeOptions::default()
                };
                let (file, _) = encode(&image, &options, &ThreadPool::single()).unwrap();
                let name = format!("{channels:?} q{quality} {order:?} tiles {tile_mbs} {bands:?} trim {trim}");
                out.push((name, file));
            }
        }
        out
    }

    /// Larger files, windows of the sound bound ([`mb_bound`]) with no minimum: the same
    /// samples as from memory, on one and two threads, and no macroblock consumed more than
    /// the bound.
    #[test]
    fn generated_files_slide_their_windows_and_decode_alike() {
        let mut sliding = 0;
        for (name, file) in generated() {
            let (want, used) = from_memory(&file, &options(1));
            let want = want.unwrap_or_else(|e| panic!("{name}: {e}"));
            let container = crate::container::parse_container(&file).unwrap();
            let bound = mb_bound(&crate::header::parse(container.image).unwrap());
            assert!(used <= bound, "{name}: {used} > {bound}");
            sliding += usize::from(file.len() > 4 * bound);
            for threads in [1, 2] {
                for tuning in SMALL {
                    let got = from_stream(&file, &options(threads), tuning)
                        .unwrap_or_else(|e| panic!("{name}, {threads} threads, {tuning:?}: {e}"));
                    assert!(same(&got, &want), "{name}, {threads} threads, {tuning:?}");
                }
            }
        }
        // Most files are several windows long.
        assert!(sliding >= 8, "{sliding}");
    }

    /// A bound smaller than what macroblocks consume: a reader that reaches the end of its
    /// window while the codestream goes on is an error, never zeros.
    #[test]
    fn a_reader_past_its_window_is_an_error() {
        let mut errors = 0;
        for (name, file) in generated().into_iter().take(2) {
            let (want, _) = from_memory(&file, &options(1));
            let tuning = Tuning { min_window: 0, slide_always: false, bound: Some(8) };
            match from_stream(&file, &options(1), tuning) {
                Ok(got) => assert!(same(&got, &want.unwrap()), "{name}"),
                Err(e) => {
                    assert!(e.to_string().contains("past its window"), "{name}: {e}");
                    errors += 1;
                }
            }
        }
        assert!(errors > 0);
    }

    /// Every cut of a file and bit flips in it: from a stream (windows of the sound bound, no
    /// minimum, so that they slide) the same samples or an error as from memory, never a
    /// panic.
    #[test]
    fn damaged_files_decode_from_a_stream_as_from_memory() {
        let limits = Limits::default().with_max_alloc_bytes(64 << 20);
        let options = DecodeOptions::new(limits);
        let small = ["tiny_tiles.jxr", "tiny_alpha_sp.jxr", "t835_hard_2x2.jxr"].map(|n| (n.to_string(), testdata(n)));
        let large = generated().into_iter().step_by(3);
        for (name, file) in small.into_iter().chain(large) {
            let mut next = crate::testing::rng(file.len() as u64);
            let step = (file.len() / 300).max(1);
            let mut bad = file.clone();
            let cuts = (0..file.len()).step_by(step).map(|n| file[..n].to_vec());
            let flips = (0..200).map(|_| {
                bad.copy_from_slice(&file);
                let at = (next() % file.len() as u64) as usize;
                bad[at] ^= 1 << (next() % 8);
                bad.clone()
            });
            for damaged in cuts.chain(flips.collect::<Vec<_>>()) {
                let want = JxrCodec.decode_with(&damaged, &options);
                let got = from_stream(&damaged, &options, SMALL[1]);
                match (&want, &got) {
                    (Ok(a), Ok(b)) => assert!(same(a, b), "{name}, {} bytes", damaged.len()),
                    (Err(a), Err(b)) => assert_eq!(
                        std::mem::discriminant(a),
                        std::mem::discriminant(b),
                        "{name}, {} bytes: {a} / {b}",
                        damaged.len()
                    ),
                    _ => panic!("{name}, {} bytes: {:?} / {:?}", damaged.len(), want.err(), got.err()),
                }
            }
        }
    }
}
