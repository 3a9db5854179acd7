// The `intel_tex_2` peer (a dev-dependency of the BC6H tests and benches) links Intel's ISPC
// kernels, which need the C++ runtime on Linux. `rustc-link-lib` would reach only this package's
// (empty) library, which the test binaries never link, so the tests and benches get the flag
// themselves.
fn main() {
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-link-arg-tests=-lstdc++");
        println!("cargo:rustc-link-arg-benches=-lstdc++");
    }
}
