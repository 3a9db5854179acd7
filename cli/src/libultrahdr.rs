//! libultrahdr 1.4, the Ultra HDR reference library, as the encoder of the bench's
//! `ultrahdr(libultrahdr):qNN` rows: reached through the reference venv's Python and its
//! imagecodecs (`ultrahdr_encode`, which bundles libultrahdr 1.4), an outside program, so the
//! CLI links nothing of it. The venv is `$HDRCODEC_VENV`, else `.venv` in the current
//! directory (scripts/setup-reference-tools.sh makes it); without it the rows say "not
//! installed".

use crate::jxrlib::TempDir;
use hdrcodec::core::half::f16;
use hdrcodec::core::{Channels, ColorPrimaries, Error, HdrImage, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where the encoder comes from, for "not installed" messages.
pub const PACKAGE: &str = "imagecodecs (libultrahdr 1.4) in the reference venv, $HDRCODEC_VENV or ./.venv";

/// SDR white in libultrahdr's linear input, cd/m² (its sample 1.0; BT.2408).
const SDR_WHITE_NITS: f32 = 203.0;

/// Reads raw little-endian half-float RGBA (argv: in, width, height, quality, gamut, out) and
/// writes libultrahdr's Ultra HDR JPEG at that base quality, the library's other settings at
/// its defaults.
const SCRIPT: &str = r#"
import sys, numpy as np, imagecodecs
src, w, h, q, gamut, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
rgba = np.fromfile(src, dtype='<f2').reshape(h, w, 4)
open(out, 'wb').write(imagecodecs.ultrahdr_encode(rgba, level=q, gamut=gamut))
"#;

/// The reference venv's Python, if there is one.
pub fn python() -> Option<PathBuf> {
    let venv = std::env::var_os("HDRCODEC_VENV").map(PathBuf::from).unwrap_or_else(|| PathBuf::from(".venv"));
    let python = venv.join("bin").join("python");
    python.is_file().then_some(python)
}

/// The image as libultrahdr's linear half-float RGBA (SDR white 1.0 = 203 cd/m²; negative and
/// NaN samples 0, above half's range clipped; alpha 1), and the number of samples changed.
pub fn linear_half_rgba(image: &HdrImage) -> (Vec<u8>, usize) {
    let scale = image.color.nits_per_unit / SDR_WHITE_NITS;
    let rgb = image.with_channels(Channels::Rgb);
    let mut clipped = 0;
    let mut out = Vec::with_capacity(rgb.samples().len() / 3 * 8);
    for p in rgb.samples().chunks_exact(3) {
        for &v in p {
            let v = v * scale;
            let kept = if v >= 0.0 { v.min(65504.0) } else { 0.0 };
            clipped += usize::from(kept != v);
            out.extend_from_slice(&f16::from_f32(kept).to_bits().to_le_bytes());
        }
        out.extend_from_slice(&f16::ONE.to_bits().to_le_bytes());
    }
    (out, clipped)
}

/// libultrahdr's gamut code for primaries it takes (BT.709 or Display P3).
pub fn gamut(primaries: ColorPrimaries) -> Result<u8> {
    match primaries {
        ColorPrimaries::Bt709 => Ok(0),
        ColorPrimaries::DisplayP3 => Ok(1),
        p => Err(Error::unsupported(format!("libultrahdr's input in {p:?} primaries"))),
    }
}

/// Encodes `rgba` ([`linear_half_rgba`] of a `width`×`height` image in `gamut`) at base
/// quality `quality` with `python`, in `dir`: the file's bytes.
pub fn encode(
    python: &Path,
    dir: &TempDir,
    rgba: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    gamut: u8,
) -> Result<Vec<u8>> {
    let (input, output) = (dir.path().join("in.f16"), dir.path().join("out.jpg"));
    if !input.is_file() {
        std::fs::write(&input, rgba)?;
    }
    let out = Command::new(python)
        .arg("-c")
        .arg(SCRIPT)
        .arg(&input)
        .args([width.to_string(), height.to_string(), quality.to_string(), gamut.to_string()])
        .arg(&output)
        .output()
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}: {e}", python.display()))))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("").to_string();
        return Err(Error::invalid(format!("libultrahdr (imagecodecs) failed: {last}")));
    }
    Ok(std::fs::read(&output)?)
}
