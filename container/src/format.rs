//! The byte layout of the `.hdrc` chunks (see README.md, the format's specification): the
//! signature, chunk types, and the payloads of HEAD, DATA, COLR, HDRM, INDX and META.
//! All integers are big-endian, all floats IEEE 754 big-endian.

use hdrcodec_core::bytes::{ByteOrder, ByteReader, ByteWriter};
use hdrcodec_core::{
    Channels, Chromaticities, ColorInfo, ColorPrimaries, ContentLightLevel, Error, Hdr10Metadata, Limits,
    MasteringDisplay, Result,
};

/// The eight bytes every `.hdrc` file starts with.
///
/// `8B` (high bit set: catches 7-bit transports and tells the file from text), `HDRC`, then
/// `CR LF` (catches CR LF → LF conversion) and a lone `LF` (catches LF → CR LF conversion).
pub const SIGNATURE: [u8; 8] = [0x8B, b'H', b'D', b'R', b'C', 0x0D, 0x0A, 0x0A];

/// The format version this crate writes and reads (the first byte of HEAD).
pub const VERSION: u8 = 1;

/// Largest chunk payload, as in PNG: lengths fit a signed 32-bit integer.
pub(crate) const MAX_CHUNK_LEN: u32 = 0x7FFF_FFFF;

/// Length field, type and CRC around every payload.
pub(crate) const CHUNK_OVERHEAD: usize = 12;

pub(crate) const HEAD: [u8; 4] = *b"HEAD";
pub(crate) const DATA: [u8; 4] = *b"DATA";
pub(crate) const END: [u8; 4] = *b"END ";
pub(crate) const COLR: [u8; 4] = *b"COLR";
pub(crate) const HDRM: [u8; 4] = *b"HDRM";
pub(crate) const INDX: [u8; 4] = *b"INDX";
pub(crate) const META: [u8; 4] = *b"META";

pub(crate) const HEAD_LEN: usize = 26;
pub(crate) const DATA_HEADER_LEN: usize = 20;
pub(crate) const INDEX_ENTRY_LEN: usize = 20;

/// Checks the eight signature bytes at the start of `data`, naming the damage if it looks
/// like a text-mode transfer.
pub(crate) fn check_signature(data: &[u8]) -> Result<()> {
    if data.len() < SIGNATURE.len() {
        if SIGNATURE.starts_with(data) {
            return Err(Error::truncated("the .hdrc signature"));
        }
    } else if data[..8] == SIGNATURE {
        return Ok(());
    }
    let d = &data[..data.len().min(8)];
    Err(Error::invalid(if d.len() == 8 && d[1..5] == SIGNATURE[1..5] && d[0] == SIGNATURE[0] & 0x7F {
        "the .hdrc signature has lost its high bit (sent through a 7-bit channel)"
    } else if d.len() >= 5 && d[1..5] == SIGNATURE[1..5] {
        "the .hdrc signature is damaged (line endings converted by a text-mode transfer?)"
    } else {
        "not an .hdrc file (wrong signature)"
    }))
}

/// What a reader checks of a parsed HEAD before using it: the dimensions against `limits`
/// (the frame's bytes are charged by whoever allocates it: a decode into a caller's buffer
/// allocates none), and that the `room` bytes after HEAD can hold a DATA chunk of at least 32
/// bytes per tile, which also bounds every tile count.
pub(crate) fn check_head(h: &Head, limits: &Limits, room: u64) -> Result<()> {
    limits.check_dimensions(u64::from(h.width), u64::from(h.height))?;
    check_room(h, room)
}

/// That the `room` bytes after HEAD can hold a DATA chunk of at least 32 bytes per tile.
pub(crate) fn check_room(h: &Head, room: u64) -> Result<()> {
    if h.total_tiles() > room / (CHUNK_OVERHEAD + DATA_HEADER_LEN) as u64 {
        return Err(Error::invalid(format!(
            "{} frames x {} tiles need more DATA chunks than the {room} bytes that follow can hold (truncated file?)",
            h.frames,
            h.tiles_per_frame(),
        )));
    }
    Ok(())
}

/// A chunk type for messages: printable ASCII as is, anything else as `\xNN`.
pub(crate) fn type_name(t: [u8; 4]) -> String {
    t.iter().map(|&b| if (0x20..0x7F).contains(&b) { (b as char).to_string() } else { format!("\\x{b:02X}") }).collect()
}

/// The contents of the HEAD chunk: what the file holds.
///
/// Every frame is cut into a grid of `tile_width` × `tile_height` tiles (the last column and row
/// may be narrower); an untiled file has one tile the size of the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Head {
    /// Id of the codec that encoded every DATA payload ([`ImageCodec::id`](hdrcodec_core::ImageCodec::id)).
    pub codec: [u8; 4],
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Channels of the image.
    pub channels: Channels,
    /// Number of frames (1 for a still image).
    pub frames: u32,
    /// Tile width, 1..=width.
    pub tile_width: u32,
    /// Tile height, 1..=height.
    pub tile_height: u32,
}

impl Head {
    /// One untiled frame.
    pub fn new(codec: [u8; 4], width: u32, height: u32, channels: Channels) -> Self {
        Head { codec, width, height, channels, frames: 1, tile_width: width, tile_height: height }
    }

    /// The same with tiles of at most `tile_width` × `tile_height` (clamped to the image).
    pub fn with_tiles(mut self, tile_width: u32, tile_height: u32) -> Self {
        self.tile_width = tile_width.min(self.width);
        self.tile_height = tile_height.min(self.height);
        self
    }

    /// The same with `frames` frames.
    pub fn with_frames(mut self, frames: u32) -> Self {
        self.frames = frames;
        self
    }

    /// Number of tile columns.
    pub fn tile_columns(&self) -> u32 {
        self.width.div_ceil(self.tile_width.max(1))
    }

    /// Number of tile rows.
    pub fn tile_rows(&self) -> u32 {
        self.height.div_ceil(self.tile_height.max(1))
    }

    /// Tiles in one frame.
    pub fn tiles_per_frame(&self) -> u64 {
        u64::from(self.tile_columns()) * u64::from(self.tile_rows())
    }

    /// The DATA header of the tile at (`column`, `row`) of `frame`.
    pub fn tile(&self, frame: u32, column: u32, row: u32) -> DataHeader {
        let x = column * self.tile_width;
        let y = row * self.tile_height;
        DataHeader {
            frame,
            x,
            y,
            width: self.tile_width.min(self.width - x),
            height: self.tile_height.min(self.height - y),
        }
    }

    /// Every tile of `frame`, row by row.
    pub fn frame_tiles(&self, frame: u32) -> impl Iterator<Item = DataHeader> + '_ {
        (0..self.tile_rows()).flat_map(move |r| (0..self.tile_columns()).map(move |c| self.tile(frame, c, r)))
    }

    /// Structural checks shared by the writer and the reader.
    pub(crate) fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::invalid(format!("image dimensions {}x{} are empty", self.width, self.height)));
        }
        if self.frames == 0 {
            return Err(Error::invalid("the frame count is 0"));
        }
        if self.tile_width == 0
            || self.tile_height == 0
            || self.tile_width > self.width
            || self.tile_height > self.height
        {
            return Err(Error::invalid(format!(
                "tile size {}x{} does not fit the {}x{} image",
                self.tile_width, self.tile_height, self.width, self.height
            )));
        }
        // Bounds every tile key and count computed from this head (frame × tiles per frame).
        if u64::from(self.frames).checked_mul(self.tiles_per_frame()).is_none() {
            return Err(Error::invalid(format!(
                "{} frames of {} tiles are too many",
                self.frames,
                self.tiles_per_frame()
            )));
        }
        Ok(())
    }

    /// Tiles in all frames (fits in `u64` for every head that passed `check`).
    pub(crate) fn total_tiles(&self) -> u64 {
        u64::from(self.frames).saturating_mul(self.tiles_per_frame())
    }

    pub(crate) fn to_bytes(self) -> Vec<u8> {
        let mut w = payload_writer();
        w.u8(VERSION);
        w.u8(self.channels.count() as u8);
        w.bytes(&self.codec);
        for v in [self.width, self.height, self.frames, self.tile_width, self.tile_height] {
            w.u32(v);
        }
        debug_assert_eq!(w.len(), HEAD_LEN);
        w.into_vec()
    }

    pub(crate) fn parse(p: &[u8]) -> Result<Head> {
        let head = read_payload(p, "the HEAD fields", |r| {
            let version = r.u8("the format version")?;
            if version != VERSION {
                return Err(Error::unsupported(format!(
                    "format version {version} (this reader knows version {VERSION})"
                )));
            }
            let channels = r.u8("the channel count")?;
            let channels = Channels::from_count(usize::from(channels))
                .ok_or_else(|| Error::invalid(format!("{channels} channels (expected 3 or 4)")))?;
            Ok(Head {
                codec: r.array("the codec id")?,
                width: r.u32("the width")?,
                height: r.u32("the height")?,
                channels,
                frames: r.u32("the frame count")?,
                tile_width: r.u32("the tile width")?,
                tile_height: r.u32("the tile height")?,
            })
        })?;
        head.check()?;
        Ok(head)
    }
}

/// The header of a DATA chunk: which frame and which rectangle its payload covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DataHeader {
    /// Frame number, 0-based.
    pub frame: u32,
    /// Left edge of the tile.
    pub x: u32,
    /// Top edge of the tile.
    pub y: u32,
    /// Tile width.
    pub width: u32,
    /// Tile height.
    pub height: u32,
}

impl DataHeader {
    pub(crate) fn to_bytes(self) -> Vec<u8> {
        let mut w = payload_writer();
        for v in [self.frame, self.x, self.y, self.width, self.height] {
            w.u32(v);
        }
        debug_assert_eq!(w.len(), DATA_HEADER_LEN);
        w.into_vec()
    }

    /// Splits a DATA payload into its header and the codec payload.
    pub(crate) fn parse(p: &[u8]) -> Result<(DataHeader, &[u8])> {
        read_payload(p, "the tile", |r| {
            let what = "the tile header";
            let header = DataHeader {
                frame: r.u32(what)?,
                x: r.u32(what)?,
                y: r.u32(what)?,
                width: r.u32(what)?,
                height: r.u32(what)?,
            };
            Ok((header, r.rest()))
        })
    }

    /// The tile's position in the file's grid, as `frame * tiles_per_frame + row * columns + column`;
    /// fails unless the rectangle is exactly one tile of the grid of `head`.
    pub(crate) fn grid_key(&self, head: &Head) -> Result<u64> {
        if self.frame >= head.frames {
            return Err(Error::invalid(format!("frame {} of a file of {} frames", self.frame, head.frames)));
        }
        let inside = self.width > 0
            && self.height > 0
            && u64::from(self.x) + u64::from(self.width) <= u64::from(head.width)
            && u64::from(self.y) + u64::from(self.height) <= u64::from(head.height);
        let (c, r) = (self.x / head.tile_width, self.y / head.tile_height);
        if !inside || head.tile(self.frame, c, r) != *self {
            return Err(Error::invalid(format!(
                "rectangle {}x{} at ({}, {}) is not a tile of the {}x{} image's {}x{} grid",
                self.width, self.height, self.x, self.y, head.width, head.height, head.tile_width, head.tile_height
            )));
        }
        Ok(u64::from(self.frame) * head.tiles_per_frame()
            + u64::from(r) * u64::from(head.tile_columns())
            + u64::from(c))
    }
}

/// One INDX entry: where a DATA chunk starts and which tile it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexEntry {
    /// Offset of the DATA chunk (its length field) from the start of the file.
    pub offset: u64,
    /// Frame of the tile.
    pub frame: u32,
    /// Left edge of the tile.
    pub x: u32,
    /// Top edge of the tile.
    pub y: u32,
}

pub(crate) fn index_bytes(entries: &[IndexEntry]) -> Vec<u8> {
    let mut w = ByteWriter::from_vec(Vec::with_capacity(4 + entries.len() * INDEX_ENTRY_LEN), ByteOrder::Big);
    w.u32(entries.len() as u32);
    for e in entries {
        w.u64(e.offset);
        for v in [e.frame, e.x, e.y] {
            w.u32(v);
        }
    }
    w.into_vec()
}

pub(crate) fn parse_index(p: &[u8]) -> Result<Vec<IndexEntry>> {
    read_payload(p, "the last entry", |r| {
        let n = r.u32("the entry count")?;
        // Every entry must be there before any is stored.
        r.check_remaining(
            u64::from(n),
            INDEX_ENTRY_LEN as u64,
            format_args!("{n} entries of {INDEX_ENTRY_LEN} bytes"),
        )?;
        (0..n)
            .map(|i| {
                let what = format_args!("entry {i}");
                Ok(IndexEntry { offset: r.u64(what)?, frame: r.u32(what)?, x: r.u32(what)?, y: r.u32(what)? })
            })
            .collect()
    })
}

// The COLR chunk stores 1 + the index into this list; the order is part of the format.
const NAMED_PRIMARIES: [ColorPrimaries; 8] = ColorPrimaries::NAMED;
/// The COLR primaries id of [`ColorPrimaries::Unspecified`].
const UNSPECIFIED_ID: u8 = 255;

fn put_f64s(w: &mut ByteWriter, v: &[f64]) {
    for &x in v {
        w.f64(x);
    }
}

/// `N` big-endian f64, each finite.
fn finite_f64s<const N: usize>(r: &mut ByteReader<'_>, what: &str) -> Result<[f64; N]> {
    let mut v = [0f64; N];
    for x in &mut v {
        *x = r.f64(what)?;
        if !x.is_finite() {
            return Err(Error::invalid(format!("non-finite value {x} in {what}")));
        }
    }
    Ok(v)
}

fn chroma_values(c: &Chromaticities) -> [f64; 8] {
    [c.red[0], c.red[1], c.green[0], c.green[1], c.blue[0], c.blue[1], c.white[0], c.white[1]]
}

/// COLR: primaries id (0 = custom, followed by eight f64 chromaticities; 255 = unspecified),
/// then `nits_per_unit` (f32).
pub(crate) fn color_bytes(color: &ColorInfo) -> Vec<u8> {
    let mut w = ByteWriter::from_vec(Vec::with_capacity(69), ByteOrder::Big);
    match color.primaries {
        ColorPrimaries::Custom(ch) => {
            w.u8(0);
            put_f64s(&mut w, &chroma_values(&ch));
        }
        ColorPrimaries::Unspecified => w.u8(UNSPECIFIED_ID),
        named => match NAMED_PRIMARIES.iter().position(|p| *p == named) {
            Some(i) => w.u8(i as u8 + 1),
            // A space without a number of its own: its chromaticities.
            None => {
                w.u8(0);
                put_f64s(&mut w, &chroma_values(&named.chromaticities()));
            }
        },
    }
    w.f32(color.nits_per_unit);
    w.into_vec()
}

pub(crate) fn parse_color(p: &[u8]) -> Result<ColorInfo> {
    read_payload(p, "nits_per_unit", |r| {
        let id = r.u8("the primaries id")?;
        let primaries = match id {
            0 => {
                let v = finite_f64s::<8>(r, "the custom chromaticities")?;
                ColorPrimaries::Custom(Chromaticities {
                    red: [v[0], v[1]],
                    green: [v[2], v[3]],
                    blue: [v[4], v[5]],
                    white: [v[6], v[7]],
                })
            }
            1..=8 => NAMED_PRIMARIES[usize::from(id - 1)],
            UNSPECIFIED_ID => ColorPrimaries::Unspecified,
            _ => return Err(Error::invalid(format!("unknown primaries id {id}"))),
        };
        let nits = r.f32("nits_per_unit")?;
        if !(nits.is_finite() && nits > 0.0) {
            return Err(Error::invalid(format!("nits_per_unit {nits} is not a positive number")));
        }
        Ok(ColorInfo { primaries, nits_per_unit: nits, hdr10: None })
    })
}

/// HDRM: flags (bit 0 mastering display, bit 1 content light level), then those present.
pub(crate) fn hdr10_bytes(m: &Hdr10Metadata) -> Vec<u8> {
    let mut w = payload_writer();
    w.u8(u8::from(m.mastering_display.is_some()) | (u8::from(m.content_light_level.is_some()) << 1));
    if let Some(d) = &m.mastering_display {
        let [r, g, bl] = d.primaries;
        put_f64s(
            &mut w,
            &[r[0], r[1], g[0], g[1], bl[0], bl[1], d.white[0], d.white[1], d.max_luminance, d.min_luminance],
        );
    }
    if let Some(l) = &m.content_light_level {
        w.u16(l.max_cll);
        w.u16(l.max_fall);
    }
    w.into_vec()
}

pub(crate) fn parse_hdr10(p: &[u8]) -> Result<Hdr10Metadata> {
    read_payload(p, "the fields its flags announce", |r| {
        let flags = r.u8("the flags")?;
        if flags > 3 {
            return Err(Error::invalid(format!("unknown flags 0x{flags:02X}")));
        }
        let mastering_display = if flags & 1 != 0 {
            let v = finite_f64s::<10>(r, "the mastering display")?;
            Some(MasteringDisplay {
                primaries: [[v[0], v[1]], [v[2], v[3]], [v[4], v[5]]],
                white: [v[6], v[7]],
                max_luminance: v[8],
                min_luminance: v[9],
            })
        } else {
            None
        };
        let content_light_level = if flags & 2 != 0 {
            let what = "the content light level";
            Some(ContentLightLevel { max_cll: r.u16(what)?, max_fall: r.u16(what)? })
        } else {
            None
        };
        Ok(Hdr10Metadata { mastering_display, content_light_level })
    })
}

/// META: pair count, then per pair a u32 length and UTF-8 bytes for the key, the same for the value.
pub(crate) fn meta_bytes(pairs: &[(String, String)]) -> Result<Vec<u8>> {
    let mut w = payload_writer();
    w.u32(u32::try_from(pairs.len()).map_err(|_| Error::invalid("too many metadata pairs"))?);
    for (k, v) in pairs {
        if k.is_empty() {
            return Err(Error::invalid("a metadata key is empty"));
        }
        for s in [k, v] {
            let n = u32::try_from(s.len()).map_err(|_| Error::invalid("a metadata string is longer than 4 GiB"))?;
            w.u32(n);
            w.bytes(s.as_bytes());
        }
    }
    Ok(w.into_vec())
}

pub(crate) fn parse_meta(p: &[u8]) -> Result<Vec<(String, String)>> {
    read_payload(p, "the last pair", |r| {
        let n = r.u32("the pair count")?;
        // No pre-allocation from the declared count: every pair needs at least 8 bytes of the payload.
        let mut pairs = Vec::new();
        for i in 0..n {
            let mut s = [String::new(), String::new()];
            for (j, part) in s.iter_mut().enumerate() {
                let what = if j == 0 { "key" } else { "value" };
                let len = r.u32(format_args!("the length of the {what} of pair {i}"))?;
                let bytes = r.bytes(u64::from(len), format_args!("the {what} of pair {i}"))?;
                *part = std::str::from_utf8(bytes)
                    .map_err(|_| Error::invalid(format!("the {what} of pair {i} is not UTF-8")))?
                    .to_string();
            }
            let [k, v] = s;
            if k.is_empty() {
                return Err(Error::invalid(format!("the key of pair {i} is empty")));
            }
            pairs.push((k, v));
        }
        Ok(pairs)
    })
}

/// A big-endian writer for a chunk payload.
fn payload_writer() -> ByteWriter {
    ByteWriter::new(ByteOrder::Big)
}

/// Reads the big-endian fields of a chunk payload with `read`, which must use up the payload
/// (`last` names what it ends with, for the message when bytes follow). A chunk's length is
/// CRC-checked, so a payload that ends inside a field is an invalid chunk, not a truncated file.
fn read_payload<'a, T>(p: &'a [u8], last: &str, read: impl FnOnce(&mut ByteReader<'a>) -> Result<T>) -> Result<T> {
    let mut r = ByteReader::be(p);
    let value = read(&mut r).map_err(|e| match e {
        Error::Truncated { what } => Error::invalid(format!("the payload ends inside {what}")),
        e => e,
    })?;
    match r.remaining() {
        0 => Ok(value),
        n => Err(Error::invalid(format!("{n} bytes after {last}, at the end of the {}-byte payload", p.len()))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn invalid(r: Result<impl std::fmt::Debug>, says: &str) {
        match r {
            Err(e @ Error::Invalid { .. }) => assert!(e.to_string().contains(says), "{e}"),
            other => panic!("expected an invalid payload saying '{says}', got {other:?}"),
        }
    }

    #[test]
    fn a_payload_shorter_or_longer_than_its_fields_is_invalid_and_named() {
        let head = Head::new(*b"RF32", 5, 3, Channels::Rgb).with_tiles(2, 2).with_frames(4);
        let b = head.to_bytes();
        assert_eq!(Head::parse(&b).unwrap(), head);
        for cut in 0..b.len() {
            assert!(matches!(Head::parse(&b[..cut]), Err(Error::Invalid { .. })), "cut at {cut}");
        }
        invalid(Head::parse(&b[..20]), "the payload ends inside the tile width (bytes 18..22 of a 20-byte input)");
        invalid(Head::parse(&[&b[..], &[0]].concat()), "1 bytes after the HEAD fields");
        let mut v2 = b.clone();
        v2[0] = 2;
        assert!(matches!(Head::parse(&v2), Err(Error::Unsupported { .. })));

        let tile = head.tile(3, 1, 1);
        let data = [&tile.to_bytes()[..], b"payload"].concat();
        assert_eq!(DataHeader::parse(&data).unwrap(), (tile, &b"payload"[..]));
        invalid(DataHeader::parse(&data[..19]), "the payload ends inside the tile header");

        let entries = [IndexEntry { offset: 1 << 40, frame: 1, x: 2, y: 3 }; 2];
        let b = index_bytes(&entries);
        assert_eq!(parse_index(&b).unwrap(), entries);
        invalid(parse_index(&b[..2]), "the entry count");
        invalid(parse_index(&b[..b.len() - 1]), "2 entries of 20 bytes");
        invalid(parse_index(&[&b[..], &[0]].concat()), "1 bytes after the last entry");

        let pairs = [("software".to_string(), "test".to_string()), ("k".to_string(), String::new())];
        let b = meta_bytes(&pairs).unwrap();
        assert_eq!(parse_meta(&b).unwrap(), pairs);
        invalid(parse_meta(&b[..b.len() - 3]), "the length of the value of pair 1");
        invalid(parse_meta(&b[..10]), "the key of pair 0");
        invalid(parse_meta(&[&b[..], &[0]].concat()), "1 bytes after the last pair");

        let color = ColorInfo {
            primaries: ColorPrimaries::Custom(ColorPrimaries::Bt709.chromaticities()),
            ..ColorInfo::default()
        };
        let b = color_bytes(&color);
        assert_eq!((b.len(), parse_color(&b).unwrap()), (69, color));
        invalid(parse_color(&[]), "the primaries id");
        invalid(parse_color(&b[..68]), "nits_per_unit");
        invalid(parse_color(&[1, 0, 0, 0]), "nits_per_unit");
        invalid(parse_color(&[1, 0x42, 0xC8, 0, 0, 9]), "1 bytes after nits_per_unit");

        let m = Hdr10Metadata {
            mastering_display: None,
            content_light_level: Some(ContentLightLevel { max_cll: 4000, max_fall: 300 }),
        };
        let b = hdr10_bytes(&m);
        assert_eq!(parse_hdr10(&b).unwrap(), m);
        invalid(parse_hdr10(&b[..4]), "the content light level");
        invalid(parse_hdr10(&[3, 0]), "the mastering display");
        invalid(parse_hdr10(&[&b[..], &[0]].concat()), "1 bytes after the fields its flags announce");
    }
}
