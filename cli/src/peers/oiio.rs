//! OpenEXR through OpenImageIO's `oiiotool` (Debian `openimageio-tools`, which links the
//! OpenEXR C++ library): the peer of our `exr:` rows. oiiotool re-writes the input (an
//! uncompressed float EXR of ours) with a compression and pixel type; our decoder reads that
//! file; oiiotool decoding it again to uncompressed float is the peer decode
//! (`../shared/REFERENCES.md`, row "OpenEXR").

use std::ffi::OsString;
use std::path::Path;

/// OpenImageIO's command-line tool.
pub const PROGRAM: &str = "oiiotool";
/// Where it comes from, for "not installed" messages.
pub const PACKAGE: &str = "Debian openimageio-tools";

/// "oiiotool 2.4.7.1 (OpenEXR 3.1.5)": OIIO's version from `oiiotool --version`, OpenEXR's from
/// the "Dependent libraries" line of `oiiotool --help`.
pub fn version() -> String {
    let oiio = super::version_text(PROGRAM, "--version").and_then(|t| t.split_whitespace().next().map(str::to_string));
    let exr = super::version_text(PROGRAM, "--help").and_then(|t| {
        let line = t.lines().find(|l| l.starts_with("Dependent libraries:"))?;
        let at = line.find("OpenEXR ")?;
        line[at..].split(',').next().map(|s| s.trim().to_string())
    });
    match (oiio, exr) {
        (Some(v), Some(e)) => format!("{PROGRAM} {v} ({e})"),
        (Some(v), None) => format!("{PROGRAM} {v}"),
        _ => format!("{PROGRAM} (version unknown)"),
    }
}

/// oiiotool's arguments: `input` re-written to `output` with `compression` (OpenEXR's name:
/// `piz`, `zip`, `dwaa`, ...) and `pixel` samples (`half` or `float`), without the software
/// attributes OIIO would add.
pub fn encode_args(input: &Path, output: &Path, compression: &str, pixel: &str) -> Vec<OsString> {
    super::args(&[&"--nosoftwareattrib", &input, &"--compression", &compression, &"-d", &pixel, &"-o", &output])
}

/// oiiotool's arguments for the peer decode: `input` to an uncompressed float EXR `output`.
pub fn decode_args(input: &Path, output: &Path) -> Vec<OsString> {
    encode_args(input, output, "none", "float")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_lines() {
        let args = encode_args(Path::new("a.exr"), Path::new("b.exr"), "piz", "half");
        let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(args.join(" "), "--nosoftwareattrib a.exr --compression piz -d half -o b.exr");
        let args = decode_args(Path::new("b.exr"), Path::new("c.exr"));
        let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(args.join(" "), "--nosoftwareattrib b.exr --compression none -d float -o c.exr");
    }
}
