//! The text path against the token path: [`od_codegen::expand_text`] (what the `Builder` and
//! `odgen gen` write: the large parts of a module written straight as text, laid out as
//! prettyplease lays them out) must give, byte for byte, the file that prettyplease makes of
//! [`od_codegen::expand`]'s tokens (what the proc macros emit, rendered with
//! [`od_codegen::render`]), for:
//!
//! - every file of the EDS corpus (`$EDS_CORPUS_DIR`; skipped with a message when unset) and
//!   every fixture of this crate;
//! - the bundled devices with their sidecars, as `cargo xtask gen` generates them (the
//!   description embedded, the names behind a feature);
//! - the random models of `compile_all.rs`, names never and always, and with the client;
//! - models whose names sweep every length a name can have, with every storage type, defaults
//!   (`$NODEID`, strings) and limits, so each layout decision of the text writers (a line that
//!   fits the margin, one that does not, one near it) is met on both sides.

use crate::common;

use common::{description_files, workspace_root};

use std::path::{Path, PathBuf};

use eds::model::{Access, DataType as D, Model, ObjectType, Radix, Value};
use od_codegen::{Names, Options};

/// Both paths' files for `model`; panics with the first line where they differ.
fn same_file(what: &str, model: &Model, options: &Options) {
    let tokens = od_codegen::render(&od_codegen::expand(model, options).tokens, &options.source_name)
        .unwrap_or_else(|e| panic!("{what}: the tokens do not parse: {e}"));
    let text = od_codegen::expand_text(model, options)
        .render(&options.source_name)
        .unwrap_or_else(|e| panic!("{what}: the rest does not parse: {e}"));
    if tokens == text {
        return;
    }
    let (t, x): (Vec<&str>, Vec<&str>) = (tokens.lines().collect(), text.lines().collect());
    let at = t.iter().zip(&x).position(|(a, b)| a != b).unwrap_or(t.len().min(x.len()));
    let from = at.saturating_sub(6);
    panic!(
        "{what}: the text path differs from the token path at line {}\n--- tokens (prettyplease)\n{}\n--- text\n{}",
        at + 1,
        t.get(from..(at + 6).min(t.len())).unwrap_or_default().join("\n"),
        x.get(from..(at + 6).min(x.len())).unwrap_or_default().join("\n"),
    );
}

#[test]
fn corpus_and_fixtures() {
    let mut files = description_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures"));
    match std::env::var_os("EDS_CORPUS_DIR") {
        Some(dir) => {
            let dir = PathBuf::from(dir);
            files.extend(description_files(&if dir.is_absolute() { dir } else { workspace_root().join(dir) }));
        }
        None => println!("SKIPPED the corpus part: EDS_CORPUS_DIR is not set (only the fixtures are compared)"),
    }
    for f in &files {
        let parsed = eds::read_file(f, &eds::Options::lenient()).unwrap();
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        same_file(&name, &parsed.model, &Options::new("device", name.clone()));
    }
    println!("{} files: the text path is the token path's rendering", files.len());
}

#[test]
fn bundled_devices_with_sidecars() {
    let dir = workspace_root().join("devices");
    for f in description_files(&dir) {
        let parsed = eds::read_file(&f, &eds::Options::lenient()).unwrap();
        let name = format!("devices/{}", f.file_name().unwrap().to_string_lossy());
        let mut options = Options::new("device", name.clone());
        options.strict = true;
        options.eds_text = Some(String::from_utf8_lossy(&std::fs::read(&f).unwrap()).into_owned());
        options.names = Names::Feature("names".to_owned());
        let sidecar = f.with_extension("toml");
        if sidecar.is_file() {
            options.sidecar = Some(od_codegen::sidecar::Sidecar::read(&sidecar).unwrap());
        }
        same_file(&name, &parsed.model, &options);
    }
}

#[test]
fn random_models() {
    for seed in 0..40 {
        let model = common::random::model(seed);
        let mut options = Options::new(format!("random_{seed:02}"), format!("random_{seed:02}.eds"));
        options.names = if seed % 2 == 0 { Names::Always } else { Names::Never };
        same_file(&format!("seed {seed}"), &model, &options);
        // As compile_all.rs generates them: the default names, with the client.
        let mut options = Options::new(format!("random_{seed:02}"), format!("random_{seed:02}.eds"));
        options.client = true;
        same_file(&format!("seed {seed} with the client"), &model, &options);
    }
}

/// A name of `len` letters (one word, so the accessor is the name itself, up to the longest a
/// name may be).
fn long_name(len: usize, letter: char) -> String {
    std::iter::once('v').chain(std::iter::repeat_n(letter, len.saturating_sub(1))).collect()
}

#[test]
fn every_name_length_with_every_type() {
    let types = [
        D::Boolean,
        D::Unsigned8,
        D::Unsigned16,
        D::Unsigned24,
        D::Unsigned32,
        D::Unsigned64,
        D::Integer8,
        D::Integer16,
        D::Integer32,
        D::Integer64,
        D::Real32,
        D::Real64,
        D::VisibleString,
        D::OctetString,
        D::Domain,
    ];
    for (k, dt) in types.iter().enumerate() {
        let string_like = matches!(dt, D::VisibleString | D::OctetString | D::Domain);
        let mut objects = Vec::new();
        for len in 1..=72 {
            let index = 0x2000 + len as u16;
            let name = long_name(len, (b'a' + k as u8) as char);
            let default = match (dt, len % 4) {
                (D::VisibleString, 1) => Some(Value::Text("x".repeat(len))),
                (D::OctetString | D::Domain, 1) => Some(Value::Bytes(vec![0x5A; len])),
                (_, 1) if !string_like => Some(Value::NodeIdPlus { offset: 0x180, radix: Radix::Hex }),
                (D::Real32 | D::Real64, 2) => Some(Value::Real(-1.5)),
                (_, 2) if !string_like => Some(Value::Int { value: 1, radix: Radix::Dec }),
                _ => None,
            };
            let mut o = common::var(index, &name, *dt, Access::Rw, default, len % 3 == 0);
            if len % 5 == 0 && !string_like {
                let e = o.subs.values_mut().next().unwrap();
                e.extras_mut().low_limit = Some(Value::Int { value: 0, radix: Radix::Dec });
                e.extras_mut().high_limit = Some(Value::Int { value: 100, radix: Radix::Dec });
            }
            objects.push(o);
            // A record whose sub-entries are long too (`<object>_<n>` accessors).
            if len % 7 == 0 {
                let subs =
                    (0..3u8).map(|s| common::entry(s, &format!("{name} {s}"), *dt, Access::Ro, None, false)).collect();
                objects.push(common::object(0x3000 + len as u16, &name, ObjectType::Record, subs));
            }
        }
        let model = common::model(objects);
        for names in [Names::Always, Names::Feature("names".to_owned())] {
            let mut options = Options::new("lengths", "lengths.eds");
            options.names = names;
            same_file(&format!("{dt:?} names"), &model, &options);
        }
    }
    // Few entries, and none: tables and constructors that fit one line, or just do not.
    // (The first name's length steps through every column a line can end at.)
    for k in 1..=16u16 {
        for pad in 0..8 {
            let objects = (0..k)
                .map(|i| {
                    let name = if i == 0 { format!("N{}", "x".repeat(pad)) } else { format!("N{i}") };
                    common::var(0x2000 + i, &name, D::Unsigned8, Access::Rw, None, false)
                })
                .collect();
            same_file(&format!("{k} entries, {pad}"), &common::model(objects), &Options::new("few", "few.eds"));
        }
    }
    same_file("no entries", &common::model(Vec::new()), &Options::new("none", "none.eds"));
}

#[test]
fn an_embedded_description_cannot_forge_a_placeholder() {
    let f = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mini.eds");
    let parsed = eds::read_file(&f, &eds::Options::lenient()).unwrap();
    let mut options = Options::new("mini", "mini.eds");
    // Lines that look like the placeholder items standing for the large parts.
    let forged: String =
        (0..8).map(|n| format!("const __ODGEN_PART_{n}: () = ();\n    const __ODGEN_PART_X_{n}: () = ();\n")).collect();
    options.eds_text = Some(format!("{}\n{forged}", String::from_utf8_lossy(&std::fs::read(&f).unwrap())));
    same_file("forged placeholders", &parsed.model, &options);
    let text = od_codegen::expand_text(&parsed.model, &options).render("mini.eds").unwrap();
    assert!(text.contains(&forged), "the embedded description is kept as it was");
}
