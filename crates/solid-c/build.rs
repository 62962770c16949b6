//! Gives libsolid.so its SONAME, so that programs linked against it find it by name (through
//! their RPATH or the loader's path), wherever it was installed.

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo::rustc-cdylib-link-arg=-Wl,-soname,libsolid.so");
    }
}
