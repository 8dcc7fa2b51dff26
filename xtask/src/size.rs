//! `cargo xtask size [--no-build]`: builds the example firmware (`examples/firmware`) for a
//! Cortex-M4F once per device, reads each ELF and checks the size budget.
//!
//! For each device it prints the bytes of `.vector_table`, `.text`, `.rodata`, `.data` and
//! `.bss`, flash (vector table + code + read-only data + the load image of `.data`) and RAM
//! (`.data` + `.bss` + `.uninit`; the stack comes on top), and fails when
//!
//! * the DRCS firmware takes more than [`DRCS_FLASH`] bytes of flash or [`DRCS_RAM`] of RAM;
//! * the AKD firmware takes more than [`FLASH_PER_ENTRY`] bytes of flash per dictionary entry
//!   it has beyond the DRCS's;
//! * any firmware links code of `core::fmt` (with panic-halt nothing formats, so formatting
//!   code in the image is dead weight that something pulled in).
//!
//! The ELF is read with the `object` crate, so no binutils for the target are needed.

use std::path::{Path, PathBuf};
use std::process::Command;

use object::{Object, ObjectSection, ObjectSymbol};

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// Flash budget of the DRCS firmware, bytes.
pub const DRCS_FLASH: u64 = 32 * 1024;
/// RAM budget of the DRCS firmware (static data; the stack comes on top), bytes.
pub const DRCS_RAM: u64 = 4 * 1024;
/// Flash budget per dictionary entry of the AKD beyond the DRCS's, bytes.
pub const FLASH_PER_ENTRY: u64 = 16;

/// The devices the firmware is built for: cargo feature, module in `generated/src`.
const DEVICES: &[&str] = &["drcs", "drvi", "akd"];

/// Sizes of one firmware image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sizes {
    /// `.vector_table`.
    pub vectors: u64,
    /// `.text`.
    pub text: u64,
    /// `.rodata`.
    pub rodata: u64,
    /// `.data` (in flash and in RAM).
    pub data: u64,
    /// `.bss` and `.uninit`.
    pub bss: u64,
}

impl Sizes {
    /// Bytes of flash.
    pub fn flash(&self) -> u64 {
        self.vectors + self.text + self.rodata + self.data
    }

    /// Bytes of static RAM.
    pub fn ram(&self) -> u64 {
        self.data + self.bss
    }
}

/// What one ELF holds: its sizes and the `core::fmt` functions linked in.
#[derive(Debug, Default)]
pub struct Image {
    /// Section sizes.
    pub sizes: Sizes,
    /// Names (mangled) of linked `core::fmt` symbols.
    pub fmt_symbols: Vec<String>,
}

/// Reads an ELF image.
pub fn read_elf(bytes: &[u8]) -> Result<Image, String> {
    let file = object::File::parse(bytes).map_err(|e| format!("not an object file: {e}"))?;
    let mut sizes = Sizes::default();
    for s in file.sections() {
        let name = s.name().map_err(|e| format!("section name: {e}"))?;
        let slot = match name {
            ".vector_table" => &mut sizes.vectors,
            ".text" => &mut sizes.text,
            ".rodata" => &mut sizes.rodata,
            ".data" => &mut sizes.data,
            ".bss" | ".uninit" => &mut sizes.bss,
            _ => continue,
        };
        *slot += s.size();
    }
    // `4core3fmt` is in the legacy (`_ZN4core3fmt…`) and the v0 (`…4core3fmt…`) mangling of
    // every item of core::fmt.
    let fmt_symbols = file
        .symbols()
        .filter(|s| s.size() > 0)
        .filter_map(|s| s.name().ok().map(str::to_owned))
        .filter(|n| n.contains("4core3fmt"))
        .collect();
    Ok(Image { sizes, fmt_symbols })
}

/// Entries of a generated dictionary: the length of its `ENTRIES` table.
pub fn entry_count(generated_module: &str) -> Option<u64> {
    let at = generated_module.find("pub static ENTRIES: [")?;
    let rest = &generated_module[at..];
    let semi = rest.find(';')?;
    let end = rest[semi..].find(']')? + semi;
    rest[semi + 1..end].trim().parse().ok()
}

fn build(root: &Path, device: &str) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let status = Command::new(cargo)
        .current_dir(root)
        .args(["build", "--locked", "-p", "firmware", "--bin", "firmware", "--profile", "firmware"])
        .args(["--target", TARGET, "--no-default-features", "--features"])
        .arg(format!("rt,{device}"))
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!(
            "the {device} firmware did not build (is the target installed? `rustup target add {TARGET}`)"
        ));
    }
    let target = std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("target"));
    let target = if target.is_absolute() { target } else { root.join(target) };
    Ok(target.join(TARGET).join("firmware").join("firmware"))
}

/// Runs the command.
pub fn main(args: &[String]) -> Result<(), String> {
    if let Some(a) = args.first() {
        return Err(format!("unknown argument `{a}` (usage: cargo xtask size)"));
    }
    let root = crate::workspace_root();
    let mut rows = Vec::new();
    for &dev in DEVICES {
        let elf = build(&root, dev)?;
        let bytes = std::fs::read(&elf).map_err(|e| format!("{}: {e}", elf.display()))?;
        let image = read_elf(&bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
        let module = root.join("generated/src").join(format!("{dev}.rs"));
        let text = std::fs::read_to_string(&module).map_err(|e| format!("{}: {e}", module.display()))?;
        let entries = entry_count(&text).ok_or_else(|| format!("{}: no ENTRIES table", module.display()))?;
        rows.push((dev, entries, image));
    }
    println!(
        "{:<6} {:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>8} {:>7}",
        "device", "entries", "vectors", ".text", ".rodata", ".data", ".bss", "flash", "RAM"
    );
    for (dev, entries, img) in &rows {
        let s = img.sizes;
        println!(
            "{dev:<6} {entries:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>8} {:>7}",
            s.vectors,
            s.text,
            s.rodata,
            s.data,
            s.bss,
            s.flash(),
            s.ram()
        );
    }
    check(&rows)
}

/// Checks the budget; every failure is named.
pub fn check(rows: &[(&str, u64, Image)]) -> Result<(), String> {
    let mut errors = Vec::new();
    let find = |name: &str| rows.iter().find(|(d, ..)| *d == name);
    if let Some((_, drcs_entries, drcs)) = find("drcs") {
        let s = drcs.sizes;
        if s.flash() > DRCS_FLASH {
            errors.push(format!("DRCS firmware: {} bytes of flash, budget {DRCS_FLASH}", s.flash()));
        }
        if s.ram() > DRCS_RAM {
            errors.push(format!("DRCS firmware: {} bytes of RAM, budget {DRCS_RAM}", s.ram()));
        }
        if let Some((_, akd_entries, akd)) = find("akd") {
            let extra = akd_entries.saturating_sub(*drcs_entries).max(1);
            let per = akd.sizes.flash().saturating_sub(s.flash()) as f64 / extra as f64;
            println!("AKD over DRCS: {per:.1} bytes of flash per additional entry ({extra} entries)");
            if per > FLASH_PER_ENTRY as f64 {
                errors.push(format!(
                    "AKD firmware: {per:.1} bytes of flash per entry beyond the DRCS's, budget {FLASH_PER_ENTRY}"
                ));
            }
        }
    }
    for (dev, _, img) in rows {
        if !img.fmt_symbols.is_empty() {
            let some: Vec<&str> = img.fmt_symbols.iter().take(5).map(String::as_str).collect();
            errors.push(format!(
                "{dev} firmware links {} core::fmt symbols, e.g. {}",
                img.fmt_symbols.len(),
                some.join(", ")
            ));
        }
    }
    if errors.is_empty() {
        println!("size budget: ok");
        Ok(())
    } else {
        Err(format!("size budget exceeded:\n  {}", errors.join("\n  ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entry_counts_of_the_checked_in_modules() {
        let root = crate::workspace_root();
        for (dev, min) in [("drcs", 300), ("drvi", 300), ("akd", 500)] {
            let text = std::fs::read_to_string(root.join("generated/src").join(format!("{dev}.rs"))).unwrap();
            let n = entry_count(&text).unwrap_or_else(|| panic!("{dev}: no count"));
            assert!(n >= min, "{dev}: {n}");
        }
        assert_eq!(entry_count("pub static ENTRIES: [X; 12] = [];"), Some(12));
        assert_eq!(entry_count("nothing"), None);
    }

    #[test]
    fn over_budget_is_named_and_fmt_symbols_fail() {
        let img = |flash: u64, ram: u64, fmt: &[&str]| Image {
            sizes: Sizes { text: flash, bss: ram, ..Sizes::default() },
            fmt_symbols: fmt.iter().map(|s| s.to_string()).collect(),
        };
        assert!(check(&[("drcs", 300, img(30_000, 4000, &[])), ("akd", 500, img(33_200, 4000, &[]))]).is_ok());
        let e = check(&[
            ("drcs", 300, img(40_000, 5000, &[])),
            ("akd", 500, img(50_000, 4000, &["_ZN4core3fmt5write17h0E"])),
        ])
        .unwrap_err();
        assert!(e.contains("40000 bytes of flash"), "{e}");
        assert!(e.contains("5000 bytes of RAM"), "{e}");
        assert!(e.contains("50.0 bytes of flash per entry"), "{e}");
        assert!(e.contains("akd firmware links 1 core::fmt"), "{e}");
    }

    #[test]
    fn reads_sections_of_an_elf() {
        // The test binary itself is an ELF on the project's machines: it has a .text section.
        let me = std::env::current_exe().unwrap();
        let img = read_elf(&std::fs::read(me).unwrap()).unwrap();
        assert!(img.sizes.text > 0);
        assert!(!img.fmt_symbols.is_empty(), "a std test binary formats");
        assert!(read_elf(b"not an elf").is_err());
    }
}
