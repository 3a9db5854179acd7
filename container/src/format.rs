//! The byte layout of the `.hdrc` chunks (see README.md, the format's specification): the
//! signature, chunk types, and the payloads of HEAD, DATA, COLR, HDRM, INDX and META.
//! All integers are big-endian, all floats IEEE 754 big-endian.

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

/// [`Limits::check_image`] without its overflow: `Limits::none()` lets 2³²−1 × 2³²−1 through
/// the dimension check, and the byte count of such an image does not fit in a `u64`.
pub(crate) fn check_image(limits: &Limits, width: u32, height: u32, channels: Channels) -> Result<()> {
    limits.check_dimensions(u64::from(width), u64::from(height))?;
    let bytes = (u64::from(width) * u64::from(height)).saturating_mul(channels.count() as u64 * 4);
    limits.check_alloc(bytes, "the decoded image")
}

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

    pub(crate) fn to_bytes(self) -> [u8; HEAD_LEN] {
        let mut b = [0u8; HEAD_LEN];
        b[0] = VERSION;
        b[1] = self.channels.count() as u8;
        b[2..6].copy_from_slice(&self.codec);
        b[6..10].copy_from_slice(&self.width.to_be_bytes());
        b[10..14].copy_from_slice(&self.height.to_be_bytes());
        b[14..18].copy_from_slice(&self.frames.to_be_bytes());
        b[18..22].copy_from_slice(&self.tile_width.to_be_bytes());
        b[22..26].copy_from_slice(&self.tile_height.to_be_bytes());
        b
    }

    pub(crate) fn parse(p: &[u8]) -> Result<Head> {
        if p.first().is_some_and(|&v| v != VERSION) {
            return Err(Error::unsupported(format!("format version {} (this reader knows version {VERSION})", p[0])));
        }
        let mut c = Cursor::exact(p, HEAD_LEN, "HEAD")?;
        let _version = c.u8();
        let channels = c.u8();
        let channels = Channels::from_count(usize::from(channels))
            .ok_or_else(|| Error::invalid(format!("{channels} channels (expected 3 or 4)")))?;
        let head = Head {
            codec: c.array(),
            width: c.u32(),
            height: c.u32(),
            channels,
            frames: c.u32(),
            tile_width: c.u32(),
            tile_height: c.u32(),
        };
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
    pub(crate) fn to_bytes(self) -> [u8; DATA_HEADER_LEN] {
        let mut b = [0u8; DATA_HEADER_LEN];
        for (i, v) in [self.frame, self.x, self.y, self.width, self.height].into_iter().enumerate() {
            b[4 * i..4 * i + 4].copy_from_slice(&v.to_be_bytes());
        }
        b
    }

    /// Splits a DATA payload into its header and the codec payload.
    pub(crate) fn parse(p: &[u8]) -> Result<(DataHeader, &[u8])> {
        if p.len() < DATA_HEADER_LEN {
            return Err(Error::invalid(format!(
                "payload of {} bytes, shorter than the {DATA_HEADER_LEN}-byte tile header",
                p.len()
            )));
        }
        let (h, rest) = p.split_at(DATA_HEADER_LEN);
        let mut c = Cursor::new(h);
        Ok((DataHeader { frame: c.u32(), x: c.u32(), y: c.u32(), width: c.u32(), height: c.u32() }, rest))
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
    let mut b = Vec::with_capacity(4 + entries.len() * INDEX_ENTRY_LEN);
    b.extend_from_slice(&(entries.len() as u32).to_be_bytes());
    for e in entries {
        b.extend_from_slice(&e.offset.to_be_bytes());
        b.extend_from_slice(&e.frame.to_be_bytes());
        b.extend_from_slice(&e.x.to_be_bytes());
        b.extend_from_slice(&e.y.to_be_bytes());
    }
    b
}

pub(crate) fn parse_index(p: &[u8]) -> Result<Vec<IndexEntry>> {
    let mut c = Cursor::new(p);
    let n = c.need(4).map(|_| c.u32())?;
    if (p.len() - 4) as u64 != u64::from(n) * INDEX_ENTRY_LEN as u64 {
        return Err(Error::invalid(format!(
            "{n} entries need {} bytes, the payload has {}",
            4 + u64::from(n) * 20,
            p.len()
        )));
    }
    Ok((0..n).map(|_| IndexEntry { offset: c.u64(), frame: c.u32(), x: c.u32(), y: c.u32() }).collect())
}

// The COLR chunk stores 1 + the index into this list; the order is part of the format.
const NAMED_PRIMARIES: [ColorPrimaries; 8] = ColorPrimaries::NAMED;
/// The COLR primaries id of [`ColorPrimaries::Unspecified`].
const UNSPECIFIED_ID: u8 = 255;

fn put_f64s(b: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        b.extend_from_slice(&x.to_be_bytes());
    }
}

fn chroma_values(c: &Chromaticities) -> [f64; 8] {
    [c.red[0], c.red[1], c.green[0], c.green[1], c.blue[0], c.blue[1], c.white[0], c.white[1]]
}

/// COLR: primaries id (0 = custom, followed by eight f64 chromaticities; 255 = unspecified),
/// then `nits_per_unit` (f32).
pub(crate) fn color_bytes(color: &ColorInfo) -> Vec<u8> {
    let mut b = Vec::with_capacity(69);
    match color.primaries {
        ColorPrimaries::Custom(ch) => {
            b.push(0);
            put_f64s(&mut b, &chroma_values(&ch));
        }
        ColorPrimaries::Unspecified => b.push(UNSPECIFIED_ID),
        named => match NAMED_PRIMARIES.iter().position(|p| *p == named) {
            Some(i) => b.push(i as u8 + 1),
            // A space without a number of its own: its chromaticities.
            None => {
                b.push(0);
                put_f64s(&mut b, &chroma_values(&named.chromaticities()));
            }
        },
    }
    b.extend_from_slice(&color.nits_per_unit.to_be_bytes());
    b
}

pub(crate) fn parse_color(p: &[u8]) -> Result<ColorInfo> {
    let id = *p.first().ok_or_else(|| Error::invalid("empty payload"))?;
    let primaries = match id {
        0 => {
            let mut c = Cursor::exact(p, 69, "COLR with custom primaries")?;
            c.u8();
            let v = c.finite_f64s::<8>()?;
            ColorPrimaries::Custom(Chromaticities {
                red: [v[0], v[1]],
                green: [v[2], v[3]],
                blue: [v[4], v[5]],
                white: [v[6], v[7]],
            })
        }
        1..=8 => {
            Cursor::exact(p, 5, "COLR with named primaries")?;
            NAMED_PRIMARIES[usize::from(id - 1)]
        }
        UNSPECIFIED_ID => {
            Cursor::exact(p, 5, "COLR with unspecified primaries")?;
            ColorPrimaries::Unspecified
        }
        _ => return Err(Error::invalid(format!("unknown primaries id {id}"))),
    };
    let nits = f32::from_be_bytes([p[p.len() - 4], p[p.len() - 3], p[p.len() - 2], p[p.len() - 1]]);
    if !(nits.is_finite() && nits > 0.0) {
        return Err(Error::invalid(format!("nits_per_unit {nits} is not a positive number")));
    }
    Ok(ColorInfo { primaries, nits_per_unit: nits, hdr10: None })
}

/// HDRM: flags (bit 0 mastering display, bit 1 content light level), then those present.
pub(crate) fn hdr10_bytes(m: &Hdr10Metadata) -> Vec<u8> {
    let mut b = vec![u8::from(m.mastering_display.is_some()) | (u8::from(m.content_light_level.is_some()) << 1)];
    if let Some(d) = &m.mastering_display {
        let [r, g, bl] = d.primaries;
        put_f64s(
            &mut b,
            &[r[0], r[1], g[0], g[1], bl[0], bl[1], d.white[0], d.white[1], d.max_luminance, d.min_luminance],
        );
    }
    if let Some(l) = &m.content_light_level {
        b.extend_from_slice(&l.max_cll.to_be_bytes());
        b.extend_from_slice(&l.max_fall.to_be_bytes());
    }
    b
}

pub(crate) fn parse_hdr10(p: &[u8]) -> Result<Hdr10Metadata> {
    let flags = *p.first().ok_or_else(|| Error::invalid("empty payload"))?;
    if flags > 3 {
        return Err(Error::invalid(format!("unknown flags 0x{flags:02X}")));
    }
    let (md, cll) = (flags & 1 != 0, flags & 2 != 0);
    let mut c = Cursor::exact(p, 1 + if md { 80 } else { 0 } + if cll { 4 } else { 0 }, "HDRM with these flags")?;
    c.u8();
    let mastering_display = if md {
        let v = c.finite_f64s::<10>()?;
        Some(MasteringDisplay {
            primaries: [[v[0], v[1]], [v[2], v[3]], [v[4], v[5]]],
            white: [v[6], v[7]],
            max_luminance: v[8],
            min_luminance: v[9],
        })
    } else {
        None
    };
    let content_light_level = cll.then(|| ContentLightLevel { max_cll: c.u16(), max_fall: c.u16() });
    Ok(Hdr10Metadata { mastering_display, content_light_level })
}

/// META: pair count, then per pair a u32 length and UTF-8 bytes for the key, the same for the value.
pub(crate) fn meta_bytes(pairs: &[(String, String)]) -> Result<Vec<u8>> {
    let mut b = Vec::new();
    b.extend_from_slice(
        &u32::try_from(pairs.len()).map_err(|_| Error::invalid("too many metadata pairs"))?.to_be_bytes(),
    );
    for (k, v) in pairs {
        if k.is_empty() {
            return Err(Error::invalid("a metadata key is empty"));
        }
        for s in [k, v] {
            let n = u32::try_from(s.len()).map_err(|_| Error::invalid("a metadata string is longer than 4 GiB"))?;
            b.extend_from_slice(&n.to_be_bytes());
            b.extend_from_slice(s.as_bytes());
        }
    }
    Ok(b)
}

pub(crate) fn parse_meta(p: &[u8]) -> Result<Vec<(String, String)>> {
    let mut c = Cursor::new(p);
    let n = c.need(4).map(|_| c.u32())?;
    // No pre-allocation from the declared count: every pair needs at least 8 bytes of the payload.
    let mut pairs = Vec::new();
    for i in 0..n {
        let mut s = [String::new(), String::new()];
        for (j, part) in s.iter_mut().enumerate() {
            let what = if j == 0 { "key" } else { "value" };
            let len = c.need(4).map(|_| c.u32())? as usize;
            let bytes =
                c.take(len).map_err(|_| Error::invalid(format!("the {what} of pair {i} overruns the payload")))?;
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
    if c.pos != p.len() {
        return Err(Error::invalid(format!("{} bytes after the last pair", p.len() - c.pos)));
    }
    Ok(pairs)
}

/// Reads big-endian fields from a payload whose length was checked beforehand
/// (the fixed-size readers panic on overrun, so every caller checks with `exact` or `need`).
pub(crate) struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    pub(crate) fn new(b: &'a [u8]) -> Self {
        Cursor { b, pos: 0 }
    }

    fn exact(b: &'a [u8], len: usize, what: &str) -> Result<Self> {
        if b.len() != len {
            return Err(Error::invalid(format!("payload of {} bytes ({what} has {len})", b.len())));
        }
        Ok(Cursor::new(b))
    }

    /// Checks that `n` more bytes remain (the fixed-size readers below then consume them).
    fn need(&self, n: usize) -> Result<()> {
        let left = self.b.len() - self.pos;
        if left < n {
            return Err(Error::invalid(format!("payload ends {} bytes too early", n - left)));
        }
        Ok(())
    }

    /// The next `n` bytes, consumed, or an error if fewer remain.
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        self.need(n)?;
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        a.copy_from_slice(&self.b[self.pos..self.pos + N]);
        self.pos += N;
        a
    }
    fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_be_bytes(self.array())
    }
    pub(crate) fn u32(&mut self) -> u32 {
        u32::from_be_bytes(self.array())
    }
    fn u64(&mut self) -> u64 {
        u64::from_be_bytes(self.array())
    }
    fn finite_f64s<const N: usize>(&mut self) -> Result<[f64; N]> {
        let mut v = [0f64; N];
        for x in &mut v {
            *x = f64::from_be_bytes(self.array());
            if !x.is_finite() {
                return Err(Error::invalid(format!("non-finite value {x}")));
            }
        }
        Ok(v)
    }
}
