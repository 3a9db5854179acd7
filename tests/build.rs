//! Native peers of the tests and benches.
//!
//! - The `intel_tex_2` peer (a dev-dependency of the BC6H tests and benches) links Intel's ISPC
//!   kernels, which need the C++ runtime on Linux.
//! - jxrlib, the JPEG XR peer of benches/jxr_decode.rs and benches/jxr_encode.rs, is called
//!   in-process through a small C shim (peers/jxrlib_shim.c) over Debian `libjxr-dev` (headers
//!   and `pkg-config libjxr`; scripts/setup-reference-tools.sh installs it). Without it the shim is not built and the
//!   benches say jxrlib is missing (a failure under `CI=true`): `cfg(jxrlib)` tells it.
//! - libultrahdr 1.4, the Ultra HDR peer of benches/ultrahdr_decode.rs and ultrahdr_encode.rs
//!   (through benches/libultrahdr.rs), is the shared library
//!   bundled in the reference venv's imagecodecs wheel (`$HDRCODEC_VENV`, else `.venv`;
//!   scripts/setup-reference-tools.sh makes it), without a header: peers/libultrahdr_shim.c
//!   declares the few functions it calls. Found, it is linked (with an rpath to its directory)
//!   into the benches only, and `cfg(libultrahdr)` is set.
//! - OpenEXR 3.1, the reference peer of benches/exr.rs, is called in-process through a small C++
//!   shim (peers/openexr_shim.cpp) over Debian `libopenexr-dev` (`pkg-config OpenEXR`;
//!   scripts/setup-reference-tools.sh installs it). Without it the shim is not built and the
//!   bench says OpenEXR is missing: `cfg(openexr)` tells it.
//!
//! `rustc-link-lib` would reach only this package's (empty) library, which the test and bench
//! binaries never link, so they get the link flags themselves.
use std::path::PathBuf;
use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(jxrlib)");
    println!("cargo::rustc-check-cfg=cfg(libultrahdr)");
    println!("cargo::rustc-check-cfg=cfg(openexr)");
    println!("cargo::rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo::rustc-link-arg-tests=-lstdc++");
        println!("cargo::rustc-link-arg-benches=-lstdc++");
    }
    jxrlib_shim();
    libultrahdr_shim();
    openexr_shim();
}

/// `pkg-config <args> <package>`, split at white space; `None` if pkg-config or the package is
/// not there.
fn pkg_config(package: &str, args: &str) -> Option<Vec<String>> {
    let out = Command::new("pkg-config").args([args, package]).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).split_whitespace().map(str::to_string).collect())
}

fn openexr_shim() {
    println!("cargo::rerun-if-changed=peers/openexr_shim.cpp");
    let (Some(cflags), Some(libs)) = (pkg_config("OpenEXR", "--cflags"), pkg_config("OpenEXR", "--libs")) else {
        println!(
            "cargo::warning=OpenEXR (Debian libopenexr-dev) not found: benches/exr.rs runs without its in-process peer"
        );
        return;
    };
    let mut build = cc::Build::new();
    build.cpp(true).std("c++14").file("peers/openexr_shim.cpp").cargo_metadata(false);
    for flag in &cflags {
        match flag.strip_prefix("-I") {
            Some(dir) => build.include(dir),
            None => build.flag(flag),
        };
    }
    build.compile("openexr_shim");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo::rustc-link-arg-benches=-L{}", out.display());
    // The shim first, then the libraries it calls.
    println!("cargo::rustc-link-arg-benches=-lopenexr_shim");
    for lib in &libs {
        println!("cargo::rustc-link-arg-benches={lib}");
    }
    println!("cargo::rustc-cfg=openexr");
}

/// The directory and file name of libultrahdr 1.4 in the reference venv's imagecodecs wheel
/// (`imagecodecs.libs/libuhdr-<hash>.so.1.4.<patch>`), if it is there.
fn libultrahdr_library() -> Option<(PathBuf, String)> {
    println!("cargo::rerun-if-env-changed=HDRCODEC_VENV");
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR")?);
    let venv = std::env::var_os("HDRCODEC_VENV").map(PathBuf::from).unwrap_or_else(|| manifest.join("../.venv"));
    for entry in std::fs::read_dir(venv.join("lib")).ok()?.flatten() {
        let libs = entry.path().join("site-packages/imagecodecs.libs");
        let Ok(files) = std::fs::read_dir(&libs) else { continue };
        for file in files.flatten() {
            let name = file.file_name().to_string_lossy().into_owned();
            if name.starts_with("libuhdr-") && name.contains(".so.1.4.") {
                println!("cargo::rerun-if-changed={}", libs.display());
                return Some((libs, name));
            }
        }
    }
    None
}

fn libultrahdr_shim() {
    println!("cargo::rerun-if-changed=peers/libultrahdr_shim.c");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("linux") {
        return;
    }
    let Some((dir, name)) = libultrahdr_library() else {
        println!("cargo::warning=libultrahdr 1.4 (imagecodecs in the reference venv) not found: benches/ultrahdr_decode.rs and ultrahdr_encode.rs run without their peer");
        return;
    };
    cc::Build::new().file("peers/libultrahdr_shim.c").cargo_metadata(false).compile("libultrahdr_shim");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo::rustc-link-arg-benches=-L{}", out.display());
    println!("cargo::rustc-link-arg-benches=-llibultrahdr_shim");
    println!("cargo::rustc-link-arg-benches=-L{}", dir.display());
    println!("cargo::rustc-link-arg-benches=-l:{name}");
    // DT_RPATH, not RUNPATH: the wheel's libuhdr finds its own libjpeg through the same directory.
    println!("cargo::rustc-link-arg-benches=-Wl,--disable-new-dtags,-rpath,{}", dir.display());
    println!("cargo::rustc-cfg=libultrahdr");
}

/// jxrlib's compiler flags from `pkg-config --cflags libjxr` (`-I…/jxrlib -D__ANSI__
/// -DDISABLE_PERF_MEASUREMENT` on Debian), else the same by hand if the header is where
/// Debian puts it; `None` if jxrlib's development files are not installed.
fn jxrlib_cflags() -> Option<Vec<String>> {
    println!("cargo::rerun-if-env-changed=PKG_CONFIG_PATH");
    if let Ok(out) = Command::new("pkg-config").args(["--cflags", "libjxr"]).output() {
        if out.status.success() {
            return Some(String::from_utf8_lossy(&out.stdout).split_whitespace().map(str::to_string).collect());
        }
    }
    let include = "/usr/include/jxrlib";
    println!("cargo::rerun-if-changed={include}/JXRGlue.h");
    std::path::Path::new(include)
        .join("JXRGlue.h")
        .is_file()
        .then(|| vec![format!("-I{include}"), "-D__ANSI__".into(), "-DDISABLE_PERF_MEASUREMENT".into()])
}

fn jxrlib_shim() {
    println!("cargo::rerun-if-changed=peers/jxrlib_shim.c");
    let Some(cflags) = jxrlib_cflags() else {
        println!("cargo::warning=jxrlib (Debian libjxr-dev) not found: benches/jxr_decode.rs and jxr_encode.rs run without their peer");
        return;
    };
    let mut build = cc::Build::new();
    build.file("peers/jxrlib_shim.c").cargo_metadata(false);
    for flag in &cflags {
        if let Some(dir) = flag.strip_prefix("-I") {
            build.include(dir);
        } else if let Some(def) = flag.strip_prefix("-D") {
            let (name, value) = def.split_once('=').map_or((def, None), |(n, v)| (n, Some(v)));
            build.define(name, value);
        } else {
            build.flag(flag);
        }
    }
    build.compile("jxrlib_shim");
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo::rustc-link-arg-benches=-L{}", out.display());
    // The shim first, then the glue library it calls, then the codec library both call.
    for lib in ["-ljxrlib_shim", "-ljxrglue", "-ljpegxr"] {
        println!("cargo::rustc-link-arg-benches={lib}");
    }
    println!("cargo::rustc-cfg=jxrlib");
}
