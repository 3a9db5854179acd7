//! hdrcodec: the facade of the hdrcodec family of HDR image codecs.
//!
//! It re-exports every codec crate and offers a [`Registry`] that picks a codec by name, by
//! file extension or by sniffing the first bytes of a file, so that tools (the `hdrcodec` CLI,
//! benches, fuzzers) can read and write any format of the family alike.
//!
//! ```no_run
//! use hdrcodec::core::{EncodeSettings, Limits};
//! let reg = hdrcodec::registry();
//! let (_codec, image) = reg.read(std::path::Path::new("in.exr"), &Limits::default())?;
//! let codec = reg.for_output(std::path::Path::new("out.pfm"))?;
//! // PFM records no primaries: the samples are kept as they are, and a note says so.
//! let (pfm, _notes) = hdrcodec::encode_for(codec.as_ref(), &image, &EncodeSettings::default())?;
//! hdrcodec::write_atomic(std::path::Path::new("out.pfm"), &pfm)?;
//! # Ok::<(), hdrcodec::core::Error>(())
//! ```

#![forbid(unsafe_code)]

#[cfg(feature = "image")]
pub mod image_hooks;
#[cfg(feature = "image")]
pub use image_hooks::register_image_decoding_hooks;

pub use hdrcodec_bc6h as bc6h;
pub use hdrcodec_container as container;
pub use hdrcodec_core as core;
pub use hdrcodec_exr as exr;
pub use hdrcodec_jpeghdr as jpeghdr;
pub use hdrcodec_jxr as jxr;
pub use hdrcodec_logluv as logluv;
pub use hdrcodec_pfm as pfm;
pub use hdrcodec_rgbe as rgbe;
#[cfg(feature = "video")]
pub use hdrcodec_video as video;

use crate::core::{
    ColorPrimaries, ColorSignalling, DecodeOptions, EncodeSettings, Error, HdrImage, ImageCodec, ImageInfo, Limits,
    Result, WriteSeek,
};
use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

/// Every codec of the family that has a file format of its own. **Registering a codec is one
/// line here.** The `.hdrc` container is built on top of these by [`Registry::default`].
fn standard_codecs() -> Vec<Arc<dyn ImageCodec>> {
    vec![
        Arc::new(exr::ExrCodec),
        Arc::new(pfm::PfmCodec),
        Arc::new(rgbe::RgbeCodec::new()),
        // The first LogLuv entry is the one `.tif` resolves to when writing; every one of them
        // reads any LogLuv TIFF.
        Arc::new(logluv::LogLuvTiffCodec::new(logluv::Encoding::LogLuv32)),
        Arc::new(logluv::LogLuvTiffCodec::new(logluv::Encoding::LogLuv24)),
        Arc::new(logluv::LogLuvTiffCodec::new(logluv::Encoding::LogL16)),
        Arc::new(bc6h::Bc6hDdsCodec),
        Arc::new(bc6h::Bc6hKtx2Codec),
        Arc::new(jxr::JxrCodec),
        Arc::new(jpeghdr::GainMapJpegCodec),
        // Writes Ward & Simmons' JPEG-HDR when named; reading .jpg stays with the line above.
        Arc::new(jpeghdr::JpegHdrCodec),
    ]
}

/// A set of codecs, looked up by name, file extension or sniffed bytes.
#[derive(Clone)]
pub struct Registry {
    codecs: Vec<Arc<dyn ImageCodec>>,
}

/// What a `.hdrc` file may carry: every standard codec and, with the `video` feature, L_p u'v'
/// codes with their description ([`video::lpuv_image::LpuvImageCodec`], `payload=lpuv`), which
/// has no file of its own and so is not among the registry's codecs.
fn payload_codecs() -> Vec<Arc<dyn ImageCodec>> {
    #[allow(unused_mut)]
    let mut codecs = standard_codecs();
    #[cfg(feature = "video")]
    codecs.push(Arc::new(video::lpuv_image::LpuvImageCodec));
    codecs
}

impl Default for Registry {
    /// Every codec of the family, plus the `.hdrc` container that can carry any of them.
    fn default() -> Self {
        let mut codecs = standard_codecs();
        // The container adds its own raw payload codecs (raw-f32, raw-f16).
        codecs.push(Arc::new(container::HdrcCodec::new(payload_codecs())));
        Registry { codecs }
    }
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.codecs.iter().map(|c| c.name())).finish()
    }
}

/// The default [`Registry`]: every codec of the family.
pub fn registry() -> Registry {
    Registry::default()
}

/// The lower-case extension of `path` without the dot, if it has one.
fn extension_of(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

impl Registry {
    /// A registry of exactly these codecs (earlier ones win ties on extension and sniffing).
    pub fn new(codecs: Vec<Arc<dyn ImageCodec>>) -> Self {
        Registry { codecs }
    }

    /// Adds a codec after the existing ones.
    pub fn register(&mut self, codec: Arc<dyn ImageCodec>) {
        self.codecs.push(codec);
    }

    /// All codecs, in registration order.
    pub fn codecs(&self) -> &[Arc<dyn ImageCodec>] {
        &self.codecs
    }

    /// The names of all codecs.
    pub fn names(&self) -> Vec<&'static str> {
        self.codecs.iter().map(|c| c.name()).collect()
    }

    /// Every extension some codec handles, sorted, without duplicates.
    pub fn extensions(&self) -> Vec<&'static str> {
        let mut v: Vec<&'static str> = self.codecs.iter().flat_map(|c| c.extensions().iter().copied()).collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The codec called `name` (case-insensitive).
    pub fn by_name(&self, name: &str) -> Result<Arc<dyn ImageCodec>> {
        self.codecs
            .iter()
            .find(|c| c.name().eq_ignore_ascii_case(name))
            .cloned()
            .ok_or_else(|| Error::unsupported(format!("unknown codec '{name}' (known: {})", self.names().join(", "))))
    }

    /// The codecs that handle extension `ext` (without the dot, any case), in order.
    pub fn by_extension(&self, ext: &str) -> Vec<Arc<dyn ImageCodec>> {
        let ext = ext.trim_start_matches('.');
        self.codecs.iter().filter(|c| c.extensions().iter().any(|e| e.eq_ignore_ascii_case(ext))).cloned().collect()
    }

    /// The first codec whose magic-number test accepts `head`.
    pub fn sniff(&self, head: &[u8]) -> Option<Arc<dyn ImageCodec>> {
        self.codecs.iter().find(|c| c.sniff(head)).cloned()
    }

    fn unknown_extension(&self, path: &Path) -> Error {
        let known = self.extensions().join(", ");
        match extension_of(path) {
            Some(ext) => Error::unsupported(format!("unknown file extension '.{ext}' (known: {known})")),
            None => Error::unsupported(format!("'{}' has no file extension (known: {known})", path.display())),
        }
    }

    /// The codec that writes `path`, chosen by its extension.
    pub fn for_output(&self, path: &Path) -> Result<Arc<dyn ImageCodec>> {
        extension_of(path)
            .and_then(|ext| self.by_extension(&ext).into_iter().next())
            .ok_or_else(|| self.unknown_extension(path))
    }

    /// The codec that reads `data`, which came from `path`: by extension first (when several
    /// codecs share it, the one whose magic number matches), then by sniffing the bytes. A file
    /// whose extension names one format but whose bytes are clearly another's (a mislabelled
    /// file) is read as what its bytes say.
    pub fn for_input(&self, path: &Path, data: &[u8]) -> Result<Arc<dyn ImageCodec>> {
        let head = &data[..data.len().min(64)];
        let by_ext = extension_of(path).map(|e| self.by_extension(&e)).unwrap_or_default();
        if let Some(c) = by_ext.iter().find(|c| c.sniff(head)) {
            return Ok(c.clone());
        }
        if let Some(c) = self.sniff(head) {
            return Ok(c);
        }
        by_ext.into_iter().next().ok_or_else(|| self.unknown_extension(path))
    }

    /// Size, channels, colour and stored format of `data` (the contents of `path`) from its
    /// header, by the codec [`Registry::for_input`] picks ([`ImageCodec::probe`]): no pixel is
    /// decoded and nothing of the image's size is allocated (for `info` and batch planning).
    pub fn probe(&self, path: &Path, data: &[u8], limits: &Limits) -> Result<(Arc<dyn ImageCodec>, ImageInfo)> {
        let codec = self.for_input(path, data)?;
        let info = codec.probe(data, limits)?;
        Ok((codec, info))
    }

    /// [`Registry::probe`] of the file at `path`, read from the file
    /// ([`ImageCodec::probe_from`]): the codecs that can read only their header (OpenEXR, JPEG
    /// XR, `.hdrc`, Radiance, PFM, LogLuv TIFF) never read the file whole. Also returns the
    /// file, back at its start, for a decoder that reads it
    /// ([`ImageCodec::decode_rows_from`]).
    pub fn probe_file(&self, path: &Path, limits: &Limits) -> Result<(Arc<dyn ImageCodec>, ImageInfo, std::fs::File)> {
        use std::io::Seek;
        let (codec, mut file) = self.open(path)?;
        let info = codec.probe_from(&mut file, limits)?;
        file.rewind().map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display()))))?;
        Ok((codec, info, file))
    }

    /// Decodes `data` (the contents of `path`) with the codec [`Registry::for_input`] picks.
    pub fn decode(&self, path: &Path, data: &[u8], limits: &Limits) -> Result<(Arc<dyn ImageCodec>, HdrImage)> {
        self.decode_with(path, data, &DecodeOptions::new(limits.clone()))
    }

    /// [`Registry::decode`] with the caller's limits and threads.
    pub fn decode_with(
        &self,
        path: &Path,
        data: &[u8],
        options: &DecodeOptions,
    ) -> Result<(Arc<dyn ImageCodec>, HdrImage)> {
        let codec = self.for_input(path, data)?;
        let image = codec.decode_with(data, options)?;
        Ok((codec, image))
    }

    /// Reads and decodes the file at `path`.
    pub fn read(&self, path: &Path, limits: &Limits) -> Result<(Arc<dyn ImageCodec>, HdrImage)> {
        self.read_with(path, &DecodeOptions::new(limits.clone()))
    }

    /// [`Registry::read`] with the caller's limits and threads: the codec is chosen from the
    /// file's first bytes as [`Registry::for_input`] chooses it, then decodes from the open file
    /// ([`ImageCodec::decode_from`]), so that a codec that reads its file piece by piece
    /// (OpenEXR) never holds it whole.
    pub fn read_with(&self, path: &Path, options: &DecodeOptions) -> Result<(Arc<dyn ImageCodec>, HdrImage)> {
        let (codec, mut file) = self.open(path)?;
        let image = codec.decode_from(&mut file, options)?;
        Ok((codec, image))
    }

    /// Opens the file at `path` for a decoder that reads it from the file
    /// ([`ImageCodec::decode_rows_from`]): the codec chosen from its first bytes as
    /// [`Registry::for_input`] chooses it, and the file, at its start.
    pub fn open(&self, path: &Path) -> Result<(Arc<dyn ImageCodec>, std::fs::File)> {
        use std::io::{Read, Seek};
        let named = |e: std::io::Error| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display())));
        let mut file = std::fs::File::open(path).map_err(named)?;
        let mut head = Vec::with_capacity(64);
        (&mut file).take(64).read_to_end(&mut head).map_err(named)?;
        file.rewind().map_err(named)?;
        Ok((self.for_input(path, &head)?, file))
    }
}

/// The codecs of frame sequences ([`VideoCodec`](crate::core::VideoCodec)): the `.hdrc`
/// container carrying any codec of [`registry`], and with the `video` feature AV1
/// ([`video::codec::Av1Codec`]: IVF and MP4). **Registering a stream codec is one line here.**
/// Pick one by name or by [`extensions`](crate::core::VideoCodec::extensions).
pub fn video_codecs() -> Vec<Arc<dyn crate::core::VideoCodec>> {
    #[allow(unused_mut)]
    let mut codecs: Vec<Arc<dyn crate::core::VideoCodec>> =
        vec![Arc::new(container::HdrcVideoCodec::new(payload_codecs()))];
    #[cfg(feature = "video")]
    codecs.push(Arc::new(video::codec::Av1Codec));
    codecs
}

/// Reads a whole file, with an error that names it.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", path.display()))))
}

/// The option every codec accepts through the facade: `primaries=NAME` converts the image to
/// the named primaries before encoding (see [`prepare_colour`]).
pub const PRIMARIES_OPTION: &str = "primaries";

/// An image made ready for one codec's colour signalling by [`prepare_colour`].
#[derive(Debug)]
pub struct PreparedImage<'a> {
    /// The samples to encode: the input itself, or a converted copy.
    pub image: Cow<'a, HdrImage>,
    /// The settings to encode with, without the facade's own `primaries` option.
    pub settings: EncodeSettings,
    /// What was done or kept, one sentence each, for the user.
    pub notes: Vec<String>,
}

/// Makes `image` ready for `codec`, converting its colour at most once and only into what the
/// format can say ([`ImageCodec::color_signalling`]):
/// - `primaries=NAME` among the settings' options converts explicitly to NAME (an error if the
///   format records primaries but not these; for a format that records none, the converted
///   samples are stored without a label). The option is removed before the codec sees it.
/// - Otherwise a format that records any primaries gets the image as it is; one that records a
///   fixed set gets it as it is when its primaries are in the set, else converted to BT.2020
///   (or the set's first named entry) with a note; one that records none keeps the samples as they are
///   (no gamut conversion, no clipping) and a note says that they will read back unspecified.
///
/// Samples whose primaries are unspecified (from a PFM or DDS file) are never converted:
/// `primaries=NAME` *labels* them as NAME (the user knows what the samples are), and without it
/// a format that records primaries but cannot say "unknown" stores its default (BT.709 for
/// OpenEXR and Radiance) and its encoder's report says so.
pub fn prepare_colour<'a>(
    codec: &dyn ImageCodec,
    image: &'a HdrImage,
    settings: &EncodeSettings,
) -> Result<PreparedImage<'a>> {
    let ColourPlan { target, settings, notes } = plan_colour(codec, &image.color.primaries, settings)?;
    let image = match target {
        Some(ColourTarget::Label(to)) => {
            let mut labelled = image.clone();
            labelled.color.primaries = to;
            Cow::Owned(labelled)
        }
        Some(ColourTarget::Convert(to)) => Cow::Owned(crate::core::color::convert_primaries(image, to)),
        // A format that cannot say "unspecified" notes what it recorded instead (EncodeReport).
        None => Cow::Borrowed(image),
    };
    Ok(PreparedImage { image, settings, notes })
}

/// What [`prepare_colour`] does to samples in some primaries, decided before any sample is seen
/// (so that a conversion band by band, [`convert_file`], decides as a whole image would).
#[derive(Clone, Debug)]
struct ColourPlan {
    target: Option<ColourTarget>,
    /// The settings without the facade's `primaries` option.
    settings: EncodeSettings,
    notes: Vec<String>,
}

/// A change of the image's primaries.
#[derive(Clone, Copy, Debug, PartialEq)]
enum ColourTarget {
    /// Unspecified samples labelled with these primaries, unchanged.
    Label(ColorPrimaries),
    /// The samples converted to these primaries.
    Convert(ColorPrimaries),
}

impl ColourTarget {
    /// The primaries the encoded image carries.
    fn primaries(self) -> ColorPrimaries {
        match self {
            ColourTarget::Label(p) | ColourTarget::Convert(p) => p,
        }
    }
}

/// [`prepare_colour`]'s decision for samples in `from`.
fn plan_colour(codec: &dyn ImageCodec, from: &ColorPrimaries, settings: &EncodeSettings) -> Result<ColourPlan> {
    let from = *from;
    let requested = match settings.option(PRIMARIES_OPTION) {
        None => None,
        Some(name) => Some(ColorPrimaries::from_name(name).ok_or_else(|| {
            Error::invalid(format!(
                "option primaries={name}: unknown primaries (known: bt709, bt2020, p3, dci-p3, aces, acescg, adobe-rgb, xyz)"
            ))
        })?),
    };
    let settings = settings.clone().without_option(PRIMARIES_OPTION);
    let signalling = codec.color_signalling();
    let mut notes = Vec::new();
    let target = match (requested, signalling) {
        (Some(p), ColorSignalling::None) => {
            notes.push(format!(
                "{} records no primaries: the samples were converted to {} and are stored without a label",
                codec.name(),
                p.name()
            ));
            Some(p)
        }
        (Some(p), s) if !s.can_record(&p) => {
            return Err(Error::unsupported(format!(
                "{} cannot record {} primaries{}",
                codec.name(),
                p.name(),
                recordable(&s)
            )))
        }
        (Some(p), _) => Some(p),
        (None, ColorSignalling::Only(set)) if !set.contains(&from) && from.is_specified() => {
            let named = set.iter().copied().find(ColorPrimaries::is_specified);
            match if set.contains(&ColorPrimaries::Bt2020) { Some(ColorPrimaries::Bt2020) } else { named } {
                Some(to) => {
                    notes.push(format!(
                        "{} cannot record {} primaries{}: the samples were converted to {}",
                        codec.name(),
                        from.name(),
                        recordable(&signalling),
                        to.name()
                    ));
                    Some(to)
                }
                // A set that names no primaries only says "unspecified": as a format without any.
                None => {
                    notes.push(no_primaries_note(codec, &from));
                    None
                }
            }
        }
        (None, ColorSignalling::None) if from.is_specified() => {
            notes.push(no_primaries_note(codec, &from));
            None
        }
        (None, _) => None,
    };
    let target = match target {
        Some(to) if !from.is_specified() => {
            notes.push(format!("the input records no primaries: its samples are labelled {} as asked", to.name()));
            Some(ColourTarget::Label(to))
        }
        Some(to) if to != from => Some(ColourTarget::Convert(to)),
        _ => None,
    };
    Ok(ColourPlan { target, settings, notes })
}

/// The note for samples in `from` stored by a format that records no primaries.
fn no_primaries_note(codec: &dyn ImageCodec, from: &ColorPrimaries) -> String {
    format!(
        "{} records no primaries: the {} samples are stored as they are and read back as unspecified \
         (--opt primaries=NAME converts them)",
        codec.name(),
        from.name()
    )
}

/// ", which can record X, Y and Z" for an error message.
fn recordable(s: &ColorSignalling) -> String {
    match s {
        ColorSignalling::Only(set) => {
            let names: Vec<_> = set.iter().filter(|p| p.is_specified()).map(|p| p.name()).collect();
            format!(" (it records {})", names.join(", "))
        }
        _ => String::new(),
    }
}

/// Encodes `image` for `codec`: [`prepare_colour`], then the codec. Returns the bytes and the
/// notes of both (colour decisions, values the format clipped).
pub fn encode_for(
    codec: &dyn ImageCodec,
    image: &HdrImage,
    settings: &EncodeSettings,
) -> Result<(Vec<u8>, Vec<String>)> {
    let prepared = prepare_colour(codec, image, settings)?;
    let mut bytes = Vec::new();
    let report = codec.encode_to(&prepared.image, &prepared.settings, &mut bytes)?;
    let mut notes = prepared.notes;
    notes.extend(report.notes);
    Ok((bytes, notes))
}

/// Writes `bytes` to `path` so that `path` either gets the whole content or is left untouched
/// (see [`write_atomic_with`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| Ok(w.write_all(bytes)?))
}

/// Lets `write` stream the content of `path` so that `path` either gets the whole content or is
/// left untouched: the data goes (buffered) to a temporary file in the same directory, is flushed
/// to disk (fsync) and renamed over `path` only when `write` succeeds; on any error the temporary
/// file is removed. Nothing of the content is held in memory beyond the write buffer. `write`
/// may seek (formats whose index precedes the data fill it in last); the writer is `Send`, so a
/// stream encoder ([`core::VideoEncoder`]) may own a borrow of it.
pub fn write_atomic_with<T>(path: &Path, write: impl FnOnce(&mut (dyn WriteSeek + Send)) -> Result<T>) -> Result<T> {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| Error::invalid(format!("'{}' is not a file name", path.display())))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = dir.join(atomic_temp_name(name, std::process::id()));
    let io =
        |e: std::io::Error, what: &Path| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", what.display())));
    let result = (|| {
        let f = temps_in_flight::create(&tmp).map_err(|e| io(e, path))?;
        let mut buffered = std::io::BufWriter::with_capacity(1 << 20, f);
        let value = write(&mut buffered).map_err(|e| match e {
            Error::Io(e) => io(e, path),
            e => e,
        })?;
        let f = buffered.into_inner().map_err(|e| io(e.into_error(), path))?;
        f.sync_all().map_err(|e| io(e, path))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(|e| io(e, path))?;
        Ok(value)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    temps_in_flight::forget(&tmp);
    result
}

/// Removes the temporary files that [`write_atomic_with`] is writing at this moment, in every
/// thread, and makes every later call fail (before creating anything) with
/// [`std::io::ErrorKind::Interrupted`]: what a signal handler calls just before the process
/// ends, so that an interrupted run leaves no temporary file. Returns how many were removed.
///
/// No file can slip through: a temporary file is created and recorded under one lock, and
/// this function takes the same lock. A writer that renames its file into place just before
/// leaves a whole output, which is fine; one still writing loses its file and fails.
pub fn remove_temp_files_in_flight() -> usize {
    temps_in_flight::remove_all()
}

/// The temporary files of [`write_atomic_with`] in flight, for [`remove_temp_files_in_flight`].
mod temps_in_flight {
    use std::path::{Path, PathBuf};
    use std::sync::{Mutex, MutexGuard};

    struct InFlight {
        paths: Vec<PathBuf>,
        /// Set by [`remove_all`]: the process is stopping, nothing new may be created.
        stopping: bool,
    }

    static IN_FLIGHT: Mutex<InFlight> = Mutex::new(InFlight { paths: Vec::new(), stopping: false });

    /// The list even if a thread panicked while holding it: it holds paths only, always valid.
    fn lock() -> MutexGuard<'static, InFlight> {
        IN_FLIGHT.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Creates `tmp` (which must not exist) and records it, both under the lock.
    pub(super) fn create(tmp: &Path) -> std::io::Result<std::fs::File> {
        let mut in_flight = lock();
        if in_flight.stopping {
            return Err(std::io::Error::new(std::io::ErrorKind::Interrupted, "the process is stopping"));
        }
        let file = std::fs::OpenOptions::new().write(true).create_new(true).open(tmp)?;
        in_flight.paths.push(tmp.to_path_buf());
        Ok(file)
    }

    /// `tmp` was renamed into place or removed.
    pub(super) fn forget(tmp: &Path) {
        let mut in_flight = lock();
        if let Some(i) = in_flight.paths.iter().position(|p| p == tmp) {
            in_flight.paths.swap_remove(i);
        }
    }

    pub(super) fn remove_all() -> usize {
        let mut in_flight = lock();
        in_flight.stopping = true;
        let paths = std::mem::take(&mut in_flight.paths);
        paths.iter().filter(|p| std::fs::remove_file(p).is_ok()).count()
    }
}

/// The name of the temporary file [`write_atomic_with`] writes for the file called `name`, in
/// the same directory, from process `pid`: hidden, and ending in `.tmp` so that no tool takes it
/// for an image of the format.
pub fn atomic_temp_name(name: &str, pid: u32) -> String {
    format!(".{name}.{pid}.tmp")
}

/// True when `candidate` is the name of a temporary file that [`write_atomic_with`] (in any
/// process) writes for the file called `name`: what a killed writer leaves behind, for a batch
/// tool to remove on its next run.
pub fn is_atomic_temp_name_of(name: &str, candidate: &str) -> bool {
    candidate
        .strip_prefix('.')
        .and_then(|rest| rest.strip_prefix(name))
        .and_then(|rest| rest.strip_prefix('.'))
        .and_then(|rest| rest.strip_suffix(".tmp"))
        .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}

/// Encodes `image` for `codec` straight into the file at `path` ([`prepare_colour`], then the
/// codec streaming into [`write_atomic_with`]): the encoded bytes are never held whole beside the
/// image. Returns the notes of the colour preparation and of the codec.
pub fn encode_file(
    codec: &dyn ImageCodec,
    image: &HdrImage,
    settings: &EncodeSettings,
    path: &Path,
) -> Result<Vec<String>> {
    let prepared = prepare_colour(codec, image, settings)?;
    let report = write_atomic_with(path, |w| codec.encode_to_seekable(&prepared.image, &prepared.settings, w))?;
    let mut notes = prepared.notes;
    notes.extend(report.notes);
    Ok(notes)
}

/// Decodes `input` with `decoder` and encodes it with `encoder` into the file at `path`
/// ([`write_atomic_with`]), row band by row band when the encoder can take rows
/// ([`ImageCodec::row_encoder`]): then neither the decoded image nor the encoded file is held
/// whole, only the bands in flight (and, from an [`Input::File`], not the input file either for
/// a decoder that reads it piece by piece). The colour is prepared as [`prepare_colour`] would prepare
/// the whole image (the decision is taken from the header; conversions are applied per band),
/// and the bytes written are those [`encode_file`] writes for the decoded image. Rows that a
/// decoder delivers out of order wait (charged to the limits) until the rows above them came.
/// Otherwise the image is decoded whole, then encoded. Returns the notes of the colour
/// preparation and of the encoder.
pub fn convert_file(
    decoder: &dyn ImageCodec,
    input: Input<'_>,
    options: &DecodeOptions,
    encoder: &dyn ImageCodec,
    settings: &EncodeSettings,
    path: &Path,
) -> Result<Vec<String>> {
    write_atomic_with(path, |out| {
        let mut sink = ConvertSink { encoder, settings, limits: &options.limits, out, state: ConvertState::Waiting };
        match input {
            Input::Bytes(data) => decoder.decode_rows(data, options, &mut sink)?,
            Input::File(file) => decoder.decode_rows_from(file, options, &mut sink)?,
        }
        sink.finish()
    })
}

/// What [`convert_file`] decodes: a file's bytes in memory, or the file itself (any source
/// that reads and seeks, from its position; [`Registry::open`] opens one), which the decoder
/// reads as it decodes ([`ImageCodec::decode_rows_from`]), so that a codec that reads its file
/// piece by piece (OpenEXR, PFM, LogLuv TIFF, `.hdrc`, ...) never holds it whole. Same bytes,
/// notes and errors either way.
pub enum Input<'a> {
    /// The file's bytes.
    Bytes(&'a [u8]),
    /// The file.
    File(&'a mut dyn crate::core::ReadSeek),
}

/// The [`RowSink`](crate::core::sink::RowSink) of [`convert_file`].
struct ConvertSink<'a, 'w> {
    encoder: &'a dyn ImageCodec,
    settings: &'a EncodeSettings,
    limits: &'a Limits,
    out: &'w mut dyn WriteSeek,
    state: ConvertState,
}

enum ConvertState {
    /// Before the decoder's header.
    Waiting,
    /// Rows go to the encoder as they come.
    Streaming(Box<RowStream>),
    /// The encoder needs the whole image: it is decoded in place, then encoded.
    Whole(Box<crate::core::sink::ImageSink>),
}

/// The state of a conversion band by band.
struct RowStream {
    encoder: Box<dyn crate::core::RowEncoder>,
    /// The primaries conversion applied to each band, if any.
    matrix: Option<[[f32; 3]; 3]>,
    channels: usize,
    row_len: usize,
    height: u32,
    /// The next row the encoder takes.
    next: u32,
    /// Rows that came early, by first row, each charged to the limits while held.
    early: std::collections::BTreeMap<u32, (Vec<f32>, crate::core::Allocation)>,
    /// The converted band (when a matrix applies).
    band: Vec<f32>,
    notes: Vec<String>,
}

impl RowStream {
    /// Converts and encodes rows that follow the last ones encoded.
    fn encode(&mut self, samples: &[f32], out: &mut dyn WriteSeek) -> Result<()> {
        match &self.matrix {
            Some(m) => {
                self.band.clear();
                self.band.extend_from_slice(samples);
                for px in self.band.chunks_exact_mut(self.channels) {
                    let v = crate::core::color::mat_apply_f32s(m, [px[0], px[1], px[2]]);
                    px[..3].copy_from_slice(&v);
                }
                self.encoder.write_rows(&self.band, out)?;
            }
            None => self.encoder.write_rows(samples, out)?,
        }
        self.next += (samples.len() / self.row_len) as u32;
        Ok(())
    }
}

impl crate::core::sink::RowSink for ConvertSink<'_, '_> {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        let plan = plan_colour(self.encoder, &info.color.primaries, self.settings)?;
        let mut encoded = info.clone();
        if let Some(target) = plan.target {
            encoded.color.primaries = target.primaries();
        }
        self.state = match self.encoder.row_encoder(&encoded, &plan.settings)? {
            Some(encoder) => {
                let matrix = match plan.target {
                    Some(ColourTarget::Convert(to)) => Some(crate::core::color::mat_to_f32(
                        &crate::core::color::rgb_to_rgb(&info.color.primaries, &to),
                    )),
                    _ => None,
                };
                let channels = info.channels.count();
                ConvertState::Streaming(Box::new(RowStream {
                    encoder,
                    matrix,
                    channels,
                    row_len: info.width as usize * channels,
                    height: info.height,
                    next: 0,
                    early: Default::default(),
                    band: Vec::new(),
                    notes: plan.notes,
                }))
            }
            None => {
                let mut whole = Box::new(crate::core::sink::ImageSink::new(self.limits));
                whole.start(info)?;
                ConvertState::Whole(whole)
            }
        };
        Ok(())
    }

    fn rows_mut(&mut self, y: u32, rows: u32) -> Option<&mut [f32]> {
        match &mut self.state {
            ConvertState::Whole(whole) => whole.rows_mut(y, rows),
            _ => None,
        }
    }

    fn put_rows(&mut self, y: u32, samples: &[f32]) -> Result<()> {
        let stream = match &mut self.state {
            ConvertState::Whole(whole) => return whole.put_rows(y, samples),
            ConvertState::Waiting => {
                return Err(Error::invalid("a decoder delivered rows before its header (a bug in the decoder)"))
            }
            ConvertState::Streaming(stream) => stream,
        };
        let rows = samples.len() / stream.row_len.max(1);
        if !samples.len().is_multiple_of(stream.row_len.max(1)) || u64::from(y) + rows as u64 > u64::from(stream.height)
        {
            return Err(Error::invalid(format!(
                "a decoder delivered {} samples at row {y}, not whole rows inside the image (a bug in the decoder)",
                samples.len()
            )));
        }
        if y != stream.next {
            if y < stream.next || stream.early.contains_key(&y) {
                return Err(Error::invalid(format!("a decoder delivered row {y} twice (a bug in the decoder)")));
            }
            let charge = self.limits.charge(samples.len() as u64 * 4, "rows decoded ahead of the rows above them")?;
            stream.early.insert(y, (samples.to_vec(), charge));
            return Ok(());
        }
        stream.encode(samples, self.out)?;
        while let Some((rows, _charge)) = stream.early.remove(&stream.next) {
            stream.encode(&rows, self.out)?;
        }
        Ok(())
    }
}

impl ConvertSink<'_, '_> {
    /// Completes the file once the decoder is done; returns the notes.
    fn finish(self) -> Result<Vec<String>> {
        match self.state {
            ConvertState::Waiting => Err(Error::invalid("the decoder delivered no image (a bug in the decoder)")),
            ConvertState::Streaming(stream) => {
                let RowStream { encoder, height, next, mut notes, .. } = *stream;
                if next != height {
                    return Err(Error::invalid(format!(
                        "the decoder delivered {next} of the image's {height} rows in order (a bug in the decoder)"
                    )));
                }
                notes.extend(encoder.finish(self.out)?.notes);
                Ok(notes)
            }
            ConvertState::Whole(whole) => {
                let image = whole.finish()?;
                let prepared = prepare_colour(self.encoder, &image, self.settings)?;
                let report = self.encoder.encode_to_seekable(&prepared.image, &prepared.settings, self.out)?;
                let mut notes = prepared.notes;
                notes.extend(report.notes);
                Ok(notes)
            }
        }
    }
}

/// The absolute luminance of every pixel of `image`, in cd/m² (alpha is ignored).
pub fn luminance(image: &HdrImage) -> Vec<f64> {
    luminance_iter(image).collect()
}

/// [`luminance`] one pixel at a time, without a buffer.
pub fn luminance_iter(image: &HdrImage) -> impl Iterator<Item = f64> + '_ {
    let [wr, wg, wb] = crate::core::color::luminance_weights(&image.color.primaries);
    let k = f64::from(image.color.nits_per_unit);
    image.rgb().map(move |[r, g, b]| k * (wr * f64::from(r) + wg * f64::from(g) + wb * f64::from(b)))
}

/// Luminance statistics of an image in cd/m², computed in one pass without side buffers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LuminanceStats {
    /// Smallest finite luminance (+∞ when there is none).
    pub min: f64,
    /// Largest finite luminance (−∞ when there is none).
    pub max: f64,
    /// Mean of the finite luminances (0 when there is none).
    pub mean: f64,
    /// Samples (alpha included) that are NaN or infinite.
    pub non_finite_samples: usize,
}

impl LuminanceStats {
    /// The statistics of `image`.
    pub fn of(image: &HdrImage) -> Self {
        ImageStats::of(image).luminance
    }
}

/// What `hdrcodec info` measures on the pixels: luminance statistics and the CTA-861.3 light
/// levels of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageStats {
    /// Luminance in cd/m² (in the image's primaries, BT.709 when it records none).
    pub luminance: LuminanceStats,
    /// MaxCLL of the frame, cd/m² ([`crate::core::hdr10::max_cll_nits`]).
    pub max_cll_nits: f64,
    /// MaxFALL of the frame, cd/m² ([`crate::core::hdr10::frame_average_light_level`]).
    pub frame_average_nits: f64,
}

impl ImageStats {
    /// The statistics of a decoded image.
    pub fn of(image: &HdrImage) -> Self {
        let mut info = ImageInfo::new(image.width(), image.height(), image.channels(), image.color.clone());
        info.metadata = image.metadata.clone();
        let mut sink = StatsSink::new();
        use crate::core::sink::RowSink;
        // Infallible: the rows are whole and inside the image the sink was started with.
        let measured = sink.start(&info).and_then(|()| sink.put_rows(0, image.samples()));
        debug_assert!(measured.is_ok());
        sink.stats()
    }
}

/// A [`RowSink`](crate::core::sink::RowSink) that keeps nothing of the image: it measures
/// [`ImageStats`] as the rows go by, so that `info` decodes a file of any size in the memory of
/// a band of rows ([`ImageCodec::decode_rows`]).
#[derive(Clone, Debug, Default)]
pub struct StatsSink {
    info: Option<ImageInfo>,
    weights: [f64; 3],
    nits: f64,
    min: f64,
    max: f64,
    sum: f64,
    finite: u64,
    non_finite_samples: usize,
    max_light: f64,
    light_sum: f64,
    pixels: u64,
}

impl StatsSink {
    /// A sink that has seen nothing yet.
    pub fn new() -> Self {
        StatsSink { min: f64::INFINITY, max: f64::NEG_INFINITY, ..Default::default() }
    }

    /// What the decoder announced (size, channels, colour, metadata), once started.
    pub fn info(&self) -> Option<&ImageInfo> {
        self.info.as_ref()
    }

    /// The statistics of the rows seen so far.
    pub fn stats(&self) -> ImageStats {
        let per_pixel = |sum: f64| if self.pixels == 0 { 0.0 } else { sum / self.pixels as f64 * self.nits };
        ImageStats {
            luminance: LuminanceStats {
                min: self.min,
                max: self.max,
                mean: self.sum / self.finite.max(1) as f64,
                non_finite_samples: self.non_finite_samples,
            },
            max_cll_nits: self.max_light * self.nits,
            frame_average_nits: per_pixel(self.light_sum),
        }
    }
}

impl crate::core::sink::RowSink for StatsSink {
    fn start(&mut self, info: &ImageInfo) -> Result<()> {
        self.weights = crate::core::color::luminance_weights(&info.color.primaries);
        self.nits = f64::from(info.color.nits_per_unit);
        self.info = Some(info.clone());
        Ok(())
    }

    fn put_rows(&mut self, _y: u32, samples: &[f32]) -> Result<()> {
        let n = self.info.as_ref().map_or(3, |i| i.channels.count());
        let [wr, wg, wb] = self.weights;
        for px in samples.chunks_exact(n) {
            let rgb = [px[0], px[1], px[2]];
            let y = self.nits * (wr * f64::from(rgb[0]) + wg * f64::from(rgb[1]) + wb * f64::from(rgb[2]));
            if y.is_finite() {
                self.min = self.min.min(y);
                self.max = self.max.max(y);
                self.sum += y;
                self.finite += 1;
            }
            self.non_finite_samples += px.iter().filter(|v| !v.is_finite()).count();
            let light = crate::core::hdr10::max_component(rgb);
            self.max_light = self.max_light.max(light);
            self.light_sum += light;
            self.pixels += 1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn video_codecs_are_the_container_and_with_the_feature_av1() {
        let codecs = super::video_codecs();
        let names: Vec<&str> = codecs.iter().map(|c| c.name()).collect();
        let expected: &[&str] = if cfg!(feature = "video") { &["hdrc", "av1"] } else { &["hdrc"] };
        assert_eq!(names, expected);
        assert!(codecs.iter().all(|c| !c.extensions().is_empty()));
    }

    use super::*;
    use crate::core::EncodeSettings;
    use std::io::Write;

    #[test]
    fn probe_file_reads_the_header_from_the_file_and_leaves_it_at_its_start() {
        let reg = registry();
        let (w, h) = (64u32, 48u32);
        let samples = (0..w * h * 3).map(|i| (i % 13) as f32 / 4.0).collect();
        let image = HdrImage::new(w, h, crate::core::Channels::Rgb, samples, Default::default()).unwrap();
        let dir = std::env::temp_dir().join(format!("hdrcodec-probe-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for ext in ["exr", "pfm", "hdr", "tif", "jxr", "hdrc"] {
            let path = dir.join(format!("small.{ext}"));
            let codec = reg.for_output(&path).unwrap();
            let (bytes, _) = encode_for(codec.as_ref(), &image, &EncodeSettings::default()).unwrap();
            std::fs::write(&path, &bytes).unwrap();
            let (_, expected) = reg.probe(&path, &bytes, &Limits::default()).unwrap();
            // Within fewer bytes than the file: only the header is read.
            let tight = Limits::default().with_max_alloc_bytes(bytes.len() as u64 / 2);
            let (found, info, mut file) = reg.probe_file(&path, &tight).unwrap_or_else(|e| panic!("{ext}: {e}"));
            assert_eq!((found.name(), &info), (codec.name(), &expected), "{ext}");
            let decoded = found.decode_from(&mut file, &DecodeOptions::new(Limits::default())).unwrap();
            assert_eq!(decoded.samples(), codec.decode(&bytes, &Limits::default()).unwrap().samples(), "{ext}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A codec for registry tests: magic "FAKE", extensions fake / fk.
    struct Fake(&'static str, &'static [&'static str], &'static [u8]);
    impl ImageCodec for Fake {
        fn name(&self) -> &'static str {
            self.0
        }
        fn id(&self) -> [u8; 4] {
            *b"fake"
        }
        fn extensions(&self) -> &'static [&'static str] {
            self.1
        }
        fn sniff(&self, head: &[u8]) -> bool {
            head.starts_with(self.2)
        }
        fn color_signalling(&self) -> crate::core::ColorSignalling {
            crate::core::ColorSignalling::Any
        }
        fn decode_with(&self, _: &[u8], _: &crate::core::DecodeOptions) -> Result<HdrImage> {
            Err(Error::unsupported(self.0))
        }
        fn encode_to(
            &self,
            _: &HdrImage,
            _: &EncodeSettings,
            out: &mut dyn Write,
        ) -> Result<crate::core::EncodeReport> {
            out.write_all(self.2)?;
            Ok(crate::core::EncodeReport::new())
        }
    }

    fn reg() -> Registry {
        Registry::new(vec![
            Arc::new(Fake("one", &["aa", "shared"], b"ONE")),
            Arc::new(Fake("two", &["bb", "shared"], b"TWO")),
        ])
    }

    #[test]
    fn picks_by_name_and_extension_case_insensitively() {
        let r = reg();
        assert_eq!(r.by_name("TWO").unwrap().name(), "two");
        let e = r.by_name("three").err().unwrap().to_string();
        assert!(e.contains("unknown codec 'three'") && e.contains("one, two"), "{e}");
        assert_eq!(r.for_output(Path::new("x/y.AA")).unwrap().name(), "one");
        assert_eq!(r.for_output(Path::new("y.bb")).unwrap().name(), "two");
        let e = r.for_output(Path::new("y.xyz")).err().unwrap().to_string();
        assert!(e.contains("unknown file extension '.xyz' (known: aa, bb, shared)"), "{e}");
        assert!(r.for_output(Path::new("noext")).err().unwrap().to_string().contains("no file extension"));
    }

    #[test]
    fn input_uses_extension_then_bytes() {
        let r = reg();
        // Shared extension: the magic number decides.
        assert_eq!(r.for_input(Path::new("a.shared"), b"TWO...").unwrap().name(), "two");
        // Known extension, unrecognisable bytes: the extension's codec (which reports the damage).
        assert_eq!(r.for_input(Path::new("a.bb"), b"junk").unwrap().name(), "two");
        // Mislabelled file: the bytes win.
        assert_eq!(r.for_input(Path::new("a.aa"), b"TWO").unwrap().name(), "two");
        // Unknown extension: sniffing, else a clear error.
        assert_eq!(r.for_input(Path::new("a.xyz"), b"ONE").unwrap().name(), "one");
        let e = r.for_input(Path::new("a.xyz"), b"junk").err().unwrap().to_string();
        assert!(e.contains("unknown file extension '.xyz'"), "{e}");
    }

    #[test]
    fn default_registry_has_every_format_and_the_container() {
        let r = registry();
        for name in ["exr", "pfm", "hdrc"] {
            assert!(r.by_name(name).is_ok(), "{name} missing from {r:?}");
        }
        for ext in ["exr", "pfm", "hdrc"] {
            assert!(!r.by_extension(ext).is_empty(), "no codec for .{ext}");
        }
    }

    #[test]
    fn atomic_write_leaves_nothing_on_error() {
        let dir = std::env::temp_dir().join(format!("hdrcodec-atomic-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("out.bin");
        write_atomic(&p, b"hello").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"hello");
        // Renaming onto a directory fails: the temporary file must not survive.
        let sub = dir.join("sub.bin");
        std::fs::create_dir(&sub).unwrap();
        std::fs::write(sub.join("keep"), b"x").unwrap();
        assert!(write_atomic(&sub, b"data").is_err());
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 2, "{names:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn atomic_temp_names_are_recognised_exactly() {
        let tmp = atomic_temp_name("a.jxr", 4242);
        assert_eq!(tmp, ".a.jxr.4242.tmp");
        assert!(is_atomic_temp_name_of("a.jxr", &tmp));
        for other in [".a.jxr.tmp", ".a.jxr.42x.tmp", "a.jxr.42.tmp", ".b.a.jxr.42.tmp", ".a.jxr.42.tmp.x", "a.jxr"] {
            assert!(!is_atomic_temp_name_of("a.jxr", other), "{other}");
        }
        // Another file's temporary file is not this one's.
        assert!(!is_atomic_temp_name_of("a.jx", &tmp));
    }

    #[test]
    fn luminance_is_absolute() {
        // ITU-R BT.709-6 item 3.2: Y = 0.2126 R + 0.7152 G + 0.0722 B; 1.0 = nits_per_unit.
        let mut img =
            HdrImage::new(2, 1, crate::core::Channels::Rgb, vec![1.0, 0.0, 0.0, 2.0, 2.0, 2.0], Default::default())
                .unwrap();
        img.color.nits_per_unit = 80.0;
        let l = luminance(&img);
        assert!((l[0] - 80.0 * 0.2126).abs() < 0.01 && (l[1] - 160.0).abs() < 1e-3, "{l:?}");
    }

    /// A codec that only declares a colour signalling (for `prepare_colour`).
    struct Signals(ColorSignalling);
    impl ImageCodec for Signals {
        fn name(&self) -> &'static str {
            "signals"
        }
        fn id(&self) -> [u8; 4] {
            *b"SIGN"
        }
        fn extensions(&self) -> &'static [&'static str] {
            &[]
        }
        fn sniff(&self, _: &[u8]) -> bool {
            false
        }
        fn color_signalling(&self) -> ColorSignalling {
            self.0
        }
        fn decode_with(&self, _: &[u8], _: &DecodeOptions) -> Result<HdrImage> {
            Err(Error::unsupported("signals"))
        }
        fn encode_to(&self, _: &HdrImage, _: &EncodeSettings, _: &mut dyn Write) -> Result<crate::core::EncodeReport> {
            Ok(crate::core::EncodeReport::new())
        }
    }

    const ONLY: ColorSignalling = ColorSignalling::Only(&[ColorPrimaries::Bt709, ColorPrimaries::Bt2020]);

    fn image(primaries: ColorPrimaries) -> HdrImage {
        let samples = vec![1.0, 0.5, 0.25, 0.02, 3.0, 0.0];
        let color = crate::core::ColorInfo { primaries, ..Default::default() };
        HdrImage::new(2, 1, crate::core::Channels::Rgb, samples, color).unwrap()
    }

    /// `prepare_colour` with `primaries=NAME` when `name` is given, plus an option the codec keeps.
    fn prepare<'a>(s: ColorSignalling, img: &'a HdrImage, name: Option<&str>) -> Result<PreparedImage<'a>> {
        let mut settings = EncodeSettings::default().with_option("keep", "1");
        if let Some(n) = name {
            settings = settings.with_option(PRIMARIES_OPTION, n);
        }
        prepare_colour(&Signals(s), img, &settings)
    }

    fn kept(p: &PreparedImage<'_>, img: &HdrImage) {
        assert!(matches!(p.image, Cow::Borrowed(_)), "not converted");
        assert_eq!(*p.image, *img);
        assert_eq!(p.settings.options, [("keep".to_string(), "1".to_string())], "only primaries= is taken");
    }

    #[test]
    fn prepare_colour_keeps_what_the_format_records() {
        // Any: every primaries as they are, unspecified too (the codec's report speaks for it).
        for primaries in [ColorPrimaries::Bt2020, ColorPrimaries::DciP3, ColorPrimaries::Unspecified] {
            let img = image(primaries);
            let p = prepare(ColorSignalling::Any, &img, None).unwrap();
            kept(&p, &img);
            assert!(p.notes.is_empty(), "{:?}", p.notes);
        }
        // Only, with the image's primaries in the set.
        let img = image(ColorPrimaries::Bt2020);
        let p = prepare(ONLY, &img, None).unwrap();
        kept(&p, &img);
        assert!(p.notes.is_empty());
        // None: the samples as they are, and a note that they read back unspecified.
        let p = prepare(ColorSignalling::None, &img, None).unwrap();
        kept(&p, &img);
        assert_eq!(
            p.notes,
            ["signals records no primaries: the BT.2020 samples are stored as they are and read back as \
              unspecified (--opt primaries=NAME converts them)"]
        );
        // Unspecified samples into a format without primaries: nothing to say.
        let img = image(ColorPrimaries::Unspecified);
        let p = prepare(ColorSignalling::None, &img, None).unwrap();
        kept(&p, &img);
        assert!(p.notes.is_empty());
    }

    #[test]
    fn prepare_colour_converts_what_a_fixed_set_cannot_say() {
        // Only, without the image's primaries: converted to BT.2020 (in the set), with a note.
        let img = image(ColorPrimaries::DciP3);
        let p = prepare(ONLY, &img, None).unwrap();
        assert_eq!(*p.image, crate::core::color::convert_primaries(&img, ColorPrimaries::Bt2020));
        assert_eq!(
            p.notes,
            ["signals cannot record DCI-P3 primaries (it records BT.709, BT.2020): the samples were converted to BT.2020"]
        );
        // A set without BT.2020: its first named entry (an "unspecified" entry is not a target).
        let adobe = ColorSignalling::Only(&[ColorPrimaries::Unspecified, ColorPrimaries::AdobeRgb]);
        let p = prepare(adobe, &img, None).unwrap();
        assert_eq!(p.image.color.primaries, ColorPrimaries::AdobeRgb);
        assert_eq!(*p.image, crate::core::color::convert_primaries(&img, ColorPrimaries::AdobeRgb));
        // A set that only says "unspecified" keeps the samples, as a format without primaries.
        let p = prepare(ColorSignalling::Only(&[ColorPrimaries::Unspecified]), &img, None).unwrap();
        kept(&p, &img);
        assert!(p.notes[0].contains("records no primaries: the DCI-P3 samples are stored as they are"));
        // Unspecified samples are never converted: a set that can say "unspecified" keeps them
        // (KTX2); one that cannot keeps them too, and the codec's report says what it wrote.
        let img = image(ColorPrimaries::Unspecified);
        kept(&prepare(adobe, &img, None).unwrap(), &img);
        let p = prepare(ONLY, &img, None).unwrap();
        kept(&p, &img);
        assert!(p.notes.is_empty());
    }

    #[test]
    fn prepare_colour_with_primaries_named() {
        // Explicit: converted, into a format that records any primaries or has them in its set.
        let img = image(ColorPrimaries::Bt709);
        for s in [ColorSignalling::Any, ONLY] {
            let p = prepare(s, &img, Some("BT.2020")).unwrap();
            assert_eq!(*p.image, crate::core::color::convert_primaries(&img, ColorPrimaries::Bt2020));
            assert!(p.notes.is_empty(), "{:?}", p.notes);
            assert_eq!(p.settings.options, [("keep".to_string(), "1".to_string())]);
        }
        // The primaries it already has: nothing to convert.
        kept(&prepare(ColorSignalling::Any, &img, Some("srgb")).unwrap(), &img);
        // Into a format without primaries: converted, stored unlabelled, said.
        let p = prepare(ColorSignalling::None, &img, Some("p3")).unwrap();
        assert_eq!(*p.image, crate::core::color::convert_primaries(&img, ColorPrimaries::DisplayP3));
        assert_eq!(
            p.notes,
            ["signals records no primaries: the samples were converted to Display P3 and are stored without a label"]
        );
        // Unspecified input: labelled, not converted (the user says what the samples are).
        let img = image(ColorPrimaries::Unspecified);
        let p = prepare(ColorSignalling::Any, &img, Some("bt2020")).unwrap();
        assert_eq!(p.image.samples(), img.samples());
        assert_eq!(p.image.color.primaries, ColorPrimaries::Bt2020);
        assert_eq!(p.notes, ["the input records no primaries: its samples are labelled BT.2020 as asked"]);
        // An unknown name is an error naming the known ones.
        let e = prepare(ColorSignalling::Any, &img, Some("bt999")).unwrap_err();
        assert!(matches!(e, Error::Invalid { .. }), "{e}");
        assert!(e.to_string().contains("primaries=bt999: unknown primaries (known: bt709, bt2020"), "{e}");
        // A fixed set that cannot record the named primaries: an error, nothing converted.
        let e = prepare(ONLY, &image(ColorPrimaries::Bt709), Some("dci-p3")).unwrap_err();
        assert!(matches!(e, Error::Unsupported { .. }), "{e}");
        assert!(e.to_string().contains("signals cannot record DCI-P3 primaries (it records BT.709, BT.2020)"), "{e}");
    }
}
