//! Puts the repository's `memory.x` (the reference target's memory map) on the linker's
//! search path, where cortex-m-rt's `link.x` includes it.

use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default());
    let memory =
        PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default()).join("../memory.x");
    if let Err(e) = std::fs::copy(&memory, out.join("memory.x")) {
        println!("cargo:warning=cannot copy {}: {e}", memory.display());
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=build.rs");
}
