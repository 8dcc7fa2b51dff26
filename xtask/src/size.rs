//! `cargo xtask size [--elf FILE]`: builds the example firmware (`examples/firmware`) for a
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
//!   code in the image is dead weight that something pulled in);
//! * any firmware may need more than [`STACK`] bytes of stack: a static upper bound from the
//!   machine code ([`stack`]), the deepest call path from the reset handler (each function's
//!   prologue: pushes, `sub sp`, `vpush`; calls followed through `bl` and tail branches) plus
//!   the worst exception handler and the 104 bytes the core stacks for an exception with FPU
//!   state. A call through a register (`blx rN`) is followed when the register was last loaded
//!   with a literal of the function's own pool (a direct call made through a register to save
//!   code); other calls through registers cannot be followed; their count is printed (0 today).
//!
//! The ELF is read with the `object` crate, so no binutils for the target are needed.
//! `--elf FILE` prints the same figures for any Cortex-M ELF, without building or a budget.
//! The table ends with the C reference, CANopenNode ([`CANOPENNODE`]), labelled with its
//! source. `--services` builds the DRCS firmware without each of the services a firmware
//! author chooses ([`SERVICES`], od-runtime's features) and prints what each costs in flash.

use std::path::{Path, PathBuf};
use std::process::Command;

use object::{Object, ObjectSection, ObjectSymbol};

/// The firmware's target.
pub const TARGET: &str = "thumbv7em-none-eabihf";
/// Flash budget of the DRCS firmware, bytes (issue #39: below CANopenNode's 19,508 B built the
/// same way by `scripts/canopennode-size.sh`).
pub const DRCS_FLASH: u64 = 19_000;
/// RAM budget of the DRCS firmware (static data; the stack comes on top), bytes.
pub const DRCS_RAM: u64 = 4 * 1024;
/// Flash budget per dictionary entry of the AKD beyond the DRCS's, bytes (an 8-byte row and its
/// share of the extras and the code: 11.2 B at issue #39, 15.7 B before).
pub const FLASH_PER_ENTRY: u64 = 12;
/// Stack budget of every firmware (the static worst case, exceptions included), bytes.
pub const STACK: u64 = 1024;

/// The devices the firmware is built for: cargo feature, module in `generated/src`.
const DEVICES: &[&str] = &["drcs", "drvi", "akd"];

/// The services a firmware author chooses (od-runtime's features, passed on by the firmware's):
/// every firmware is built with all of them; `--services` builds the DRCS without each.
pub const SERVICES: &[&str] = &["sdo-block", "cia402", "store"];
/// Services a firmware is built without (`--services` measures what each adds to the DRCS
/// firmware built with all of [`SERVICES`]).
pub const OPTIONAL: &[&str] = &["lss"];

/// The C reference (issue #29): CANopenNode v4, commit 9b8beed, built for the same Cortex-M4F
/// by `scripts/canopennode-size.sh` (arm-none-eabi-gcc -Os, LTO, --gc-sections, newlib-nano,
/// `CO_USE_GLOBALS`, its blank driver and DS301 example dictionary).
pub struct Reference {
    /// Where the figures come from.
    pub source: &'static str,
    /// Entries of its dictionary.
    pub entries: u64,
    /// `.text`, `.rodata`, `.data`, bytes.
    pub text: u64,
    /// `.rodata`.
    pub rodata: u64,
    /// `.data` (in flash and in RAM).
    pub data: u64,
    /// Static RAM (`.data` + `.bss`), bytes.
    pub ram: u64,
}

/// CANopenNode's figures from a fresh run of `scripts/canopennode-size.sh` (2026-12-06,
/// arm-none-eabi-gcc 12.2, newlib-nano 3.3: flash 19,508 B, RAM 5,864 B).
pub const CANOPENNODE: Reference = Reference {
    source: "CANopenNode v4 9b8beed, DS301 example (scripts/canopennode-size.sh, 2026-12-06)",
    entries: 193,
    text: 16_508,
    rodata: 1_928,
    data: 1_072,
    ram: 5_864,
};

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
    /// Static upper bound of the stack, bytes (0 when not estimated).
    pub stack: u64,
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
    Ok(Image { sizes, fmt_symbols, stack: 0 })
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
    build_with(root, device, SERVICES)
}

/// Builds the firmware of `device` with the services `services`.
fn build_with(root: &Path, device: &str, services: &[&str]) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let status = Command::new(cargo)
        .current_dir(root)
        .args(["build", "--locked", "-p", "firmware", "--bin", "firmware", "--profile", "firmware"])
        .args(["--target", TARGET, "--no-default-features", "--features"])
        .arg(format!("rt,{device}{}", services.iter().map(|s| format!(",{s}")).collect::<String>()))
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
    match args {
        [] => {}
        [flag, path] if flag == "--elf" => return report_elf(Path::new(path)),
        [flag] if flag == "--services" => return services(&crate::workspace_root()),
        _ => return Err("usage: cargo xtask size [--elf FILE | --services]".to_owned()),
    }
    let root = crate::workspace_root();
    let mut rows = Vec::new();
    for &dev in DEVICES {
        let elf = build(&root, dev)?;
        let bytes = std::fs::read(&elf).map_err(|e| format!("{}: {e}", elf.display()))?;
        let mut image = read_elf(&bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
        let (stack, path, indirect) = stack::estimate(&bytes).map_err(|e| format!("{}: {e}", elf.display()))?;
        image.stack = stack;
        println!("{dev}: worst-case stack {stack} B ({indirect} indirect calls not followed); deepest path:");
        for p in &path {
            println!("    {p}");
        }
        let module = root.join("generated/src").join(format!("{dev}.rs"));
        let text = std::fs::read_to_string(&module).map_err(|e| format!("{}: {e}", module.display()))?;
        let entries = entry_count(&text).ok_or_else(|| format!("{}: no ENTRIES table", module.display()))?;
        rows.push((dev, entries, image));
    }
    println!(
        "{:<6} {:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>8} {:>7} {:>6}",
        "device", "entries", "vectors", ".text", ".rodata", ".data", ".bss", "flash", "RAM", "stack"
    );
    for (dev, entries, img) in &rows {
        let s = img.sizes;
        println!(
            "{dev:<6} {entries:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>8} {:>7} {:>6}",
            s.vectors,
            s.text,
            s.rodata,
            s.data,
            s.bss,
            s.flash(),
            s.ram(),
            img.stack
        );
    }
    let r = &CANOPENNODE;
    println!(
        "{:<6} {:>7} {:>7} {:>8} {:>8} {:>6} {:>6} {:>8} {:>7}   reference: {}",
        "C ref",
        r.entries,
        "-",
        r.text,
        r.rodata,
        r.data,
        "-",
        r.text + r.rodata + r.data,
        r.ram,
        r.source
    );
    check(&rows)
}

/// `--services`: what each of [`SERVICES`] costs the DRCS firmware in flash (built without it).
fn services(root: &Path) -> Result<(), String> {
    let flash = |services: &[&str]| -> Result<u64, String> {
        let elf = build_with(root, "drcs", services)?;
        let bytes = std::fs::read(&elf).map_err(|e| format!("{}: {e}", elf.display()))?;
        Ok(read_elf(&bytes)?.sizes.flash())
    };
    let all = flash(SERVICES)?;
    let none = flash(&[])?;
    let mut rows = Vec::new();
    for s in SERVICES {
        let without: Vec<&str> = SERVICES.iter().copied().filter(|x| x != s).collect();
        rows.push((*s, all.saturating_sub(flash(&without)?)));
    }
    println!("DRCS firmware: {all} B of flash with {}, {none} B with none of them", SERVICES.join(", "));
    for (s, cost) in rows {
        println!("  {s:<10} {cost:>6} B");
    }
    for s in OPTIONAL {
        let with: Vec<&str> = SERVICES.iter().copied().chain([*s]).collect();
        let cost = flash(&with)?.saturating_sub(all);
        println!("  {s:<10} {cost:>6} B (off by default: added to the above)");
    }
    Ok(())
}

/// `--elf FILE`: the sections and the stack bound of any Cortex-M ELF, without a budget.
fn report_elf(path: &Path) -> Result<(), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let s = read_elf(&bytes).map_err(|e| format!("{}: {e}", path.display()))?.sizes;
    let (stack, path_names, indirect) = stack::estimate(&bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("vectors {} .text {} .rodata {} .data {} .bss {}", s.vectors, s.text, s.rodata, s.data, s.bss);
    println!("flash {} RAM {} stack {stack} ({indirect} indirect calls not followed)", s.flash(), s.ram());
    for p in path_names {
        println!("    {p}");
    }
    Ok(())
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
        if img.stack > STACK {
            errors.push(format!("{dev} firmware: up to {} bytes of stack, budget {STACK}", img.stack));
        }
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
            stack: ram / 4,
        };
        assert!(check(&[("drcs", 300, img(19_000, 4096, &[])), ("akd", 500, img(21_400, 4000, &[]))]).is_ok());
        // One byte over each budget.
        let e = check(&[("drcs", 300, img(19_001, 4097, &[])), ("akd", 500, img(21_402, 4000, &[]))]).unwrap_err();
        assert!(e.contains("19001 bytes of flash, budget 19000"), "{e}");
        assert!(e.contains("4097 bytes of RAM, budget 4096"), "{e}");
        assert!(e.contains("12.0 bytes of flash per entry"), "{e}");
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

/// A static upper bound of the stack a Thumb-2 program uses, from its ELF.
pub mod stack {
    use std::collections::BTreeMap;

    use object::{Object, ObjectSection, ObjectSymbol, SymbolKind};

    /// One function: where it starts, its frame, whom it calls.
    #[derive(Clone, Debug, Default)]
    pub struct Function {
        /// Symbol name.
        pub name: String,
        /// Bytes its prologue takes from the stack (pushes, `sub sp`, `vpush`), all added up.
        pub frame: u64,
        /// Start addresses of the functions it calls (`bl`) or branches to (a tail call).
        pub calls: Vec<u64>,
        /// Calls through a register (`blx rN`): targets unknown.
        pub indirect: usize,
    }

    /// The worst-case stack from `root` through the call graph: `(bytes, path)`; `None` for a
    /// cycle (recursion) or an unknown root.
    pub fn worst(funcs: &BTreeMap<u64, Function>, root: u64) -> Option<(u64, Vec<String>)> {
        fn go(
            funcs: &BTreeMap<u64, Function>,
            at: u64,
            on_path: &mut Vec<u64>,
            memo: &mut BTreeMap<u64, (u64, Vec<String>)>,
        ) -> Option<(u64, Vec<String>)> {
            if let Some(m) = memo.get(&at) {
                return Some(m.clone());
            }
            if on_path.contains(&at) {
                return None;
            }
            let f = funcs.get(&at)?;
            on_path.push(at);
            let mut best = (0, Vec::new());
            for &c in &f.calls {
                if c == at || !funcs.contains_key(&c) {
                    continue;
                }
                let sub = go(funcs, c, on_path, memo)?;
                if sub.0 > best.0 {
                    best = sub;
                }
            }
            on_path.pop();
            let mut path = vec![format!("{} ({} B)", f.name, f.frame)];
            path.extend(best.1);
            let r = (f.frame + best.0, path);
            memo.insert(at, r.clone());
            Some(r)
        }
        go(funcs, root, &mut Vec::new(), &mut BTreeMap::new())
    }

    /// `ThumbExpandImm` for the rotated forms a stack adjustment uses.
    fn expand_imm(imm12: u32) -> u64 {
        let imm8 = imm12 & 0xFF;
        if imm12 >> 10 == 0 {
            return u64::from(match (imm12 >> 8) & 3 {
                0 => imm8,
                1 => imm8 << 16 | imm8,
                2 => imm8 << 24 | imm8 << 8,
                _ => imm8 << 24 | imm8 << 16 | imm8 << 8 | imm8,
            });
        }
        let unrotated = 0x80 | (imm12 & 0x7F);
        u64::from(unrotated.rotate_right(imm12 >> 7))
    }

    /// Decodes one function's code (Thumb-2, little-endian) starting at `addr`.
    pub fn decode(name: &str, addr: u64, code: &[u8]) -> Function {
        let mut f = Function { name: name.to_owned(), ..Function::default() };
        let half = |i: usize| code.get(i..i + 2).map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])));
        let mut movw = [None::<u64>; 16];
        // The literal each register was last loaded with (in address order), and a word of the
        // function's code (its literal pool) by address.
        let mut literal = [None::<u64>; 16];
        let word = |at: u64| {
            let off = usize::try_from(at.checked_sub(addr)?).ok()?;
            code.get(off..off + 4).map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
        };
        let mut i = 0;
        while let Some(h1) = half(i) {
            let wide = matches!(h1 >> 11, 0b11101..=0b11111);
            if !wide {
                if h1 & 0xFE00 == 0xB400 {
                    f.frame += 4 * u64::from((h1 & 0xFF).count_ones() + ((h1 >> 8) & 1));
                } else if h1 & 0xFF80 == 0xB080 {
                    f.frame += u64::from(h1 & 0x7F) * 4;
                } else if h1 & 0xF800 == 0x4800 {
                    // LDR Rt, [PC, #imm8 * 4]: a literal, perhaps a function's address.
                    let pc = (addr + i as u64 + 4) & !3;
                    literal[((h1 >> 8) & 7) as usize] = word(pc + u64::from(h1 & 0xFF) * 4);
                } else if h1 & 0xFF87 == 0x4780 {
                    // BLX Rm: followed when Rm was last loaded with a literal of this function
                    // (a call made through a register to save code; opt-level "z" does that).
                    match literal[((h1 >> 3) & 0xF) as usize] {
                        Some(target) => f.calls.push(target & !1),
                        None => f.indirect += 1,
                    }
                }
                i += 2;
                continue;
            }
            let Some(h2) = half(i + 2) else { break };
            let pc = addr + i as u64 + 4;
            if h1 & 0xFF7F == 0xF85F {
                // LDR.W Rt, [PC, #+/-imm12].
                let base = pc & !3;
                let imm = u64::from(h2 & 0xFFF);
                let at = if h1 & 0x80 != 0 { base + imm } else { base.wrapping_sub(imm) };
                literal[(h2 >> 12) as usize] = word(at);
            } else if h1 == 0xE92D {
                f.frame += 4 * u64::from((h2 & 0x5FFF).count_ones());
            } else if h1 == 0xF84D && h2 & 0x0FFF == 0x0D04 {
                f.frame += 4;
            } else if h1 & 0xFFBF == 0xED2D && (h2 >> 9) & 7 == 5 {
                f.frame += u64::from(h2 & 0xFF) * 4;
            } else if (h1 & 0xFBEF == 0xF1AD || h1 & 0xFBFF == 0xF2AD) && h2 & 0x8F00 == 0x0D00 {
                let imm12 = ((h1 >> 10) & 1) << 11 | ((h2 >> 12) & 7) << 8 | (h2 & 0xFF);
                f.frame += if h1 & 0x0200 != 0 { u64::from(imm12) } else { expand_imm(imm12) };
            } else if h1 & 0xFBF0 == 0xF240 {
                let imm16 = (h1 & 0xF) << 12 | ((h1 >> 10) & 1) << 11 | ((h2 >> 12) & 7) << 8 | (h2 & 0xFF);
                movw[((h2 >> 8) & 0xF) as usize] = Some(u64::from(imm16));
            } else if h1 == 0xEBAD && (h2 >> 8) & 0xF == 13 {
                f.frame += movw[(h2 & 0xF) as usize].unwrap_or(0);
            } else if h1 & 0xF800 == 0xF000 && (h2 & 0xD000 == 0xD000 || h2 & 0xD000 == 0x9000) {
                // BL, or B.W (T4) leaving the function: a tail call.
                let s = (h1 >> 10) & 1;
                let (j1, j2) = ((h2 >> 13) & 1, (h2 >> 11) & 1);
                let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
                let imm = s << 24 | i1 << 23 | i2 << 22 | (h1 & 0x3FF) << 12 | (h2 & 0x7FF) << 1;
                let off = ((imm << 7) as i32 >> 7) as i64;
                let target = (pc as i64 + off) as u64;
                let inside = target >= addr && target < addr + code.len() as u64;
                if h2 & 0xD000 == 0xD000 || !inside {
                    f.calls.push(target);
                }
            }
            i += 4;
        }
        f
    }

    /// Every function of an ELF, by start address.
    pub fn functions(bytes: &[u8]) -> Result<BTreeMap<u64, Function>, String> {
        let file = object::File::parse(bytes).map_err(|e| format!("not an object file: {e}"))?;
        let text = file.section_by_name(".text").ok_or("no .text section")?;
        let data = text.data().map_err(|e| format!(".text: {e}"))?;
        let base = text.address();
        let mut funcs = BTreeMap::new();
        for s in file.symbols().filter(|s| s.kind() == SymbolKind::Text && s.size() > 0) {
            let addr = s.address() & !1;
            let Some(start) = addr.checked_sub(base).map(|o| o as usize) else { continue };
            let Some(code) = data.get(start..start + s.size() as usize) else { continue };
            funcs.insert(addr, decode(s.name().unwrap_or("?"), addr, code));
        }
        Ok(funcs)
    }

    /// The worst-case stack from the reset handler, plus what an exception adds: the largest
    /// handler's own worst case and the 104 bytes the core stacks for it (with the FPU's
    /// registers). `(bytes, path from Reset, indirect calls seen)`.
    pub fn estimate(bytes: &[u8]) -> Result<(u64, Vec<String>, usize), String> {
        let funcs = functions(bytes)?;
        let by_name = |n: &str| funcs.iter().find(|(_, f)| f.name == n).map(|(a, _)| *a);
        let reset = by_name("Reset").ok_or("no Reset symbol")?;
        let (main, path) = worst(&funcs, reset).ok_or("recursion on the path from Reset: no static bound")?;
        let mut exception = 0;
        for h in ["SysTick", "HardFault_", "DefaultHandler_"] {
            if let Some(a) = by_name(h) {
                exception = exception.max(worst(&funcs, a).map_or(0, |w| w.0));
            }
        }
        let indirect = funcs.values().map(|f| f.indirect).sum();
        Ok((main + exception + 104, path, indirect))
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn prologues_and_calls_decode() {
            // push {r4-r7, lr}; sub sp, #16; push.w {r8, r9, r11}; vpush {d8}; bl +0x100
            let code: Vec<u8> = [0xB5F0u16, 0xB084, 0xE92D, 0x0B00, 0xED2D, 0x8B02, 0xF000, 0xF87A]
                .iter()
                .flat_map(|h| h.to_le_bytes())
                .collect();
            let f = decode("f", 0x1000, &code);
            assert_eq!(f.frame, 20 + 16 + 12 + 8);
            assert_eq!(f.calls, [0x1000 + 12 + 4 + 0xF4]);
            // ldr r4, [pc, #8]; ldr.w r8, [pc, #12]; blx r4; blx r8; blx r3; the literals.
            let lit: Vec<u8> = [0x4C02u16, 0xF8DF, 0x800C, 0x47A0, 0x47C0, 0x4798]
                .iter()
                .flat_map(|h| h.to_le_bytes())
                .chain(0x0800_2001u32.to_le_bytes())
                .chain(0x0800_3001u32.to_le_bytes())
                .collect();
            let f = decode("lit", 0x2000, &lit);
            // ldr at 0x2000: (0x2004 & !3) + 8 = 0x200C; ldr.w at 0x2002: (0x2006 & !3) + 12 = 0x2010.
            assert_eq!(f.calls, [0x0800_2000, 0x0800_3000]);
            assert_eq!(f.indirect, 1);
            // sub.w sp, sp, #4096 (i:imm3:imm8 = 0b0_100_10000000 → 0x80 ror 9) and subw sp, #1234.
            let big: Vec<u8> = [0xF5AD, 0x5D80, 0xF2AD, 0x4DD2].iter().flat_map(|h: &u16| h.to_le_bytes()).collect();
            assert_eq!(decode("g", 0, &big).frame, 4096 + 1234);
        }

        #[test]
        fn the_worst_path_adds_frames_and_recursion_has_no_bound() {
            let mut funcs = BTreeMap::new();
            let f = |name: &str, frame, calls: &[u64]| Function {
                name: name.into(),
                frame,
                calls: calls.to_vec(),
                indirect: 0,
            };
            funcs.insert(1, f("a", 8, &[2, 3]));
            funcs.insert(2, f("b", 100, &[]));
            funcs.insert(3, f("c", 16, &[4]));
            funcs.insert(4, f("d", 96, &[]));
            assert_eq!(worst(&funcs, 1).unwrap().0, 120);
            funcs.insert(4, f("d", 96, &[3]));
            assert_eq!(worst(&funcs, 1), None);
        }
    }
}
