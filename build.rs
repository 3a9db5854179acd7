// The `intel_tex_2` peer (a dev-dependency used by the BC6H tests and benches) links Intel's
// ISPC kernels, which need the C++ runtime on Linux.
fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-link-lib=stdc++");
    }
}
