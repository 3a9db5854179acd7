//! libultrahdr 1.4 in-process, through tests/peers/libultrahdr_shim.c (the library of the
//! reference venv's imagecodecs wheel; tests/build.rs links it and sets `cfg(libultrahdr)` when
//! it finds it): what benches/ultrahdr_decode.rs and ultrahdr_encode.rs call.
use std::os::raw::{c_char, c_int};

extern "C" {
    #[allow(clippy::too_many_arguments)]
    fn uhdr_shim_decode(
        data: *const u8,
        len: usize,
        out: *mut u16,
        out_len: usize,
        width: *mut u32,
        height: *mut u32,
        err: *mut c_char,
        err_len: usize,
    ) -> c_int;
    #[allow(clippy::too_many_arguments)]
    fn uhdr_shim_encode(
        rgba: *const u16,
        width: u32,
        height: u32,
        gamut: c_int,
        quality: c_int,
        scale: c_int,
        out: *mut u8,
        out_cap: usize,
        out_size: *mut usize,
        err: *mut c_char,
        err_len: usize,
    ) -> c_int;
}

/// The shim's return code and NUL-terminated message as an error.
fn error(rc: c_int, err: &[u8]) -> String {
    let end = err.iter().position(|&b| b == 0).unwrap_or(err.len());
    format!("libultrahdr error {rc}: {}", String::from_utf8_lossy(&err[..end]))
}

/// Decodes `data` to linear half-float RGBA: the size, and the samples (as bits) when
/// `out` is given (it must hold width·height·4 halves).
pub fn decode(data: &[u8], out: Option<&mut [u16]>) -> Result<(u32, u32), String> {
    let (mut w, mut h) = (0u32, 0u32);
    let mut err = [0u8; 256];
    let (ptr, len) = match out {
        Some(o) => (o.as_mut_ptr(), o.len()),
        None => (std::ptr::null_mut(), 0),
    };
    // SAFETY: `data` is valid for reads of `data.len()` bytes, `ptr` is null or valid for
    // writes of `len` halves, `err` for 256 bytes, `w` and `h` are live locals; the shim
    // checks that the image fits in `len` before writing, NUL-terminates `err`, and keeps
    // no pointer after it returns.
    let rc = unsafe {
        uhdr_shim_decode(data.as_ptr(), data.len(), ptr, len, &mut w, &mut h, err.as_mut_ptr().cast(), err.len())
    };
    if rc == 0 {
        Ok((w, h))
    } else {
        Err(error(rc, &err))
    }
}

/// What libultrahdr's encoder is asked for.
#[derive(Clone, Copy, Debug)]
pub struct EncodeSettings {
    /// libultrahdr's colour gamut code (0 BT.709, 1 Display P3).
    pub gamut: u8,
    /// JPEG quality of the base image and of the map.
    pub quality: u8,
    /// The map is this many times smaller than the image per axis (libultrahdr's default 1).
    pub scale: u8,
}

/// Encodes `width`×`height` linear half-float RGBA (`rgba`, as bits, SDR white = 1.0) as an
/// Ultra HDR JPEG into `out` (grown as needed; the file is `out[..len]`): its length.
pub fn encode(
    rgba: &[u16],
    (width, height): (u32, u32),
    s: EncodeSettings,
    out: &mut Vec<u8>,
) -> Result<usize, String> {
    if rgba.len() != width as usize * height as usize * 4 {
        return Err(format!("{} halves are no {width}x{height} RGBA image", rgba.len()));
    }
    loop {
        let mut size = 0usize;
        let mut err = [0u8; 256];
        // SAFETY: `rgba` holds width·height·4 halves (checked above) and is only read; `out`
        // is valid for writes of `out.len()` bytes, `err` for 256, `size` is a live local; the
        // shim writes the file only if it fits in `out.len()`, NUL-terminates `err`, and keeps
        // no pointer after it returns.
        let rc = unsafe {
            uhdr_shim_encode(
                rgba.as_ptr(),
                width,
                height,
                c_int::from(s.gamut),
                c_int::from(s.quality),
                c_int::from(s.scale),
                out.as_mut_ptr(),
                out.len(),
                &mut size,
                err.as_mut_ptr().cast(),
                err.len(),
            )
        };
        match rc {
            0 => return Ok(size),
            -1 if size > out.len() => out.resize(size, 0),
            _ => return Err(error(rc, &err)),
        }
    }
}
