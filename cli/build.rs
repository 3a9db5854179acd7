//! With the `ispc` feature, Intel ISPC's BC6H kernels (intel_tex_2, C++ objects) need the C++
//! runtime at link time (`../shared/REFERENCES.md`, row "BC6H DDS": link `stdc++`).
fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_ISPC").is_some() {
        println!("cargo::rustc-link-lib=stdc++");
    }
}
