//! Sets `solid_avx512` when the compiler accepts the AVX-512 target features (stable since Rust
//! 1.89): `describe` then has an AVX-512 copy. Older compilers (down to the crate's rust-version)
//! build the crate without it.

use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(solid_avx512)");
    println!("cargo::rerun-if-changed=build.rs");
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let minor = Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .and_then(|out| String::from_utf8(out.stdout).ok())
        .and_then(|v| {
            // "rustc 1.89.0 (29483883e 2025-08-04)"
            let mut parts = v.split_whitespace().nth(1)?.split('.');
            let major: u32 = parts.next()?.parse().ok()?;
            let minor: u32 = parts.next()?.parse().ok()?;
            (major == 1).then_some(minor)
        });
    if minor.is_some_and(|m| m >= 89) {
        println!("cargo::rustc-cfg=solid_avx512");
    }
}
