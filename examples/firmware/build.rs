//! The firmware binary's memory layout: `memory.x` for cortex-m-rt's `link.x`, on a
//! microcontroller target only, and an empty `device.x` (the library also builds and is tested on the host).

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo::rerun-if-changed=memory.x");
    println!("cargo::rerun-if-changed=build.rs");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::write(out.join("memory.x"), include_bytes!("memory.x")).expect("OUT_DIR is writable");
    // cortex-m-rt's `device` feature includes `device.x`, where a device crate would name its
    // interrupt handlers; this firmware's interrupts all go to `DefaultHandler` (`__INTERRUPTS`
    // in the binary), so there is nothing to name.
    fs::write(out.join("device.x"), "/* every interrupt: DefaultHandler */\n").expect("OUT_DIR is writable");
    println!("cargo::rustc-link-search={}", out.display());
    println!("cargo::rustc-link-arg-bins=-Tlink.x");
}
