//! Names a person would write, measured over the corpus (`$EDS_CORPUS_DIR`; skipped with a
//! message when unset) and this crate's fixtures: the test prints the figures and holds them to
//! the limits.
//!
//! * at most 1% of accessor names carry the `_IIII` / `_IIII_S` index suffix (the last resort
//!   of collision handling);
//! * no accessor name is longer than 64 characters;
//! * at most one name-collision warning (G0001) per object;
//! * no name starts with a number or an `x` before one (`x1st_…`, `x1_…`, `x5v_…`), none splits
//!   a mixed-case field word of its entry's names (`ca_nopen`), none splits a plural acronym
//!   (`cob_i_ds`), none repeats a word right after itself (`error_history_error_history`);
//! * no sub-entry's accessor says a run of two or more of its object's words twice
//!   (`software_position_limit_max_software_position_limit`, `touch_probe_source_touch_probe_1_source`),
//!   over the corpus and the three bundled devices.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn files() -> Vec<PathBuf> {
    let mut dirs = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")];
    match std::env::var_os("EDS_CORPUS_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
            dirs.push(if d.is_absolute() { d } else { root.join(d) });
        }
        None => println!("SKIPPED the corpus part: EDS_CORPUS_DIR is not set (only the fixtures are measured)"),
    }
    let mut v = Vec::new();
    for dir in dirs {
        let mut here: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .flatten()
            .map(|e| e.path())
            .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
            .collect();
        here.sort();
        v.extend(here);
    }
    v
}

/// `(name, index, sub)` of every getter, read from the generated text: the doc line
/// ``/// Reads `0x1018` sub 1 …`` precedes each.
fn getters(text: &str) -> Vec<(String, u16, Option<u8>)> {
    let mut out = Vec::new();
    let mut at: Option<(u16, Option<u8>)> = None;
    for line in text.lines().map(str::trim) {
        if let Some(rest) = line.strip_prefix("/// Reads `0x") {
            let index = u16::from_str_radix(&rest[..4], 16).ok();
            let sub = rest[5..].strip_prefix(" sub ").and_then(|r| r.split(' ').next()).and_then(|s| s.parse().ok());
            at = index.map(|i| (i, sub));
        } else if let Some(rest) = line.strip_prefix("pub const fn ").or_else(|| line.strip_prefix("pub fn ")) {
            // A long signature is wrapped: `pub const fn name(` with `&self,` on the next line.
            let name = rest.split_once("(&self)").map(|(n, _)| n).or_else(|| rest.strip_suffix('('));
            if let (Some((i, s)), Some(name)) = (at.take(), name) {
                out.push((name.to_owned(), i, s));
            }
        }
    }
    out
}

/// Whether `name` starts with a number or a number in disguise (`x1_…`, `x1st_…`, `x5v_…`).
fn starts_with_number(name: &str) -> bool {
    let b = name.as_bytes();
    b.first().is_some_and(u8::is_ascii_digit) || (b.first() == Some(&b'x') && b.get(1).is_some_and(u8::is_ascii_digit))
}

fn has_index_suffix(name: &str, index: u16, sub: Option<u8>) -> bool {
    let i = format!("_{index:04x}");
    name.ends_with(&i) || sub.is_some_and(|s| name.ends_with(&format!("{i}_{s}"))) || name.contains(&format!("{i}_"))
}

#[test]
fn corpus_names_are_short_plain_and_rarely_suffixed() {
    let (mut total, mut suffixed, mut longest) = (0usize, 0usize, (0usize, String::new()));
    let mut worst_g0001 = (0usize, String::new());
    let mut g0001_total = 0usize;
    let mut bad = Vec::new();
    for f in files() {
        let bytes = std::fs::read(&f).unwrap();
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let parsed = eds::parse(&name, &bytes, &eds::Options::lenient());
        // The text path (what the `Builder` writes): `text_path.rs` holds it to the token
        // path's rendering for every file here, and it is several times faster in a debug build.
        let g = od_codegen::expand_text(&parsed.model, &od_codegen::Options::new("m", name.clone()));
        let mut per_object: BTreeMap<String, usize> = BTreeMap::new();
        for d in g.diagnostics.iter().filter(|d| d.code.0 == "G0001") {
            *per_object.entry(d.context.first().cloned().unwrap_or_default()).or_default() += 1;
            g0001_total += 1;
        }
        for (obj, n) in per_object {
            if n > worst_g0001.0 {
                worst_g0001 = (n, format!("{name}: {obj}"));
            }
        }
        let text = g.render(&name).unwrap();
        let objects: BTreeMap<u16, String> = od_codegen::object_names(&parsed.model).into_iter().collect();
        for (n, index, sub) in getters(&text) {
            total += 1;
            if has_index_suffix(&n, index, sub) {
                suffixed += 1;
            }
            if n.len() > longest.0 {
                longest = (n.len(), n.clone());
            }
            let words: Vec<&str> = n.split('_').collect();
            // A word the object's name ends with may start a sub-entry's own words (`Vl velocity
            // min max` / `Max pos` → `vl_velocity_min_max_max_pos`); a repeat of the object's
            // name itself is caught by `sub_entries_do_not_repeat_their_objects_words`.
            let last = objects.get(&index).and_then(|o| o.rsplit('_').next()).unwrap_or("");
            let repeated = words.windows(2).any(|w| {
                w[0] == w[1]
                    && !w[0].is_empty()
                    && !w[0].bytes().all(|b| b.is_ascii_digit())
                    && (sub.is_none() || w[0] != last)
            });
            // A mixed-case field word of the entry's or its object's name (`CANopen`) is one word.
            let obj = parsed.model.objects.values().find(|o| o.index.0 == index);
            let source: Vec<&str> = obj
                .map(|o| {
                    let e = sub.and_then(|s| o.subs.values().find(|e| e.sub.0 == s));
                    [Some(o.name.as_str()), e.map(|e| e.name.as_str())].into_iter().flatten().collect()
                })
                .unwrap_or_default();
            let split_field_word = od_codegen::ident::FIELD_WORDS.iter().any(|w| {
                source.iter().any(|t| t.split(|c: char| !c.is_ascii_alphanumeric()).any(|x| x == *w))
                    && !words.contains(&w.to_ascii_lowercase().as_str())
            });
            if starts_with_number(&n) || split_field_word || n.contains("_i_ds") || n.starts_with("i_ds") || repeated {
                bad.push(format!("{name}: {n}"));
            }
        }
    }
    let share = 100.0 * suffixed as f64 / total.max(1) as f64;
    println!("accessor names: {total}");
    println!("with an index suffix: {suffixed} ({share:.2}%)");
    println!("longest: {} characters ({})", longest.0, longest.1);
    println!("G0001 warnings: {g0001_total}; most for one object: {} ({})", worst_g0001.0, worst_g0001.1);
    println!("names breaking the word rules: {}", bad.len());
    assert!(share <= 1.0, "{share:.2}% of names carry an index suffix");
    assert!(longest.0 <= od_codegen::ident::MAX_LEN, "longest name: {}", longest.1);
    assert!(worst_g0001.0 <= 1, "several G0001 for one object: {}", worst_g0001.1);
    assert!(bad.is_empty(), "{bad:#?}");
}

/// Whether the accessor `name` of an entry of the object named `object` says a run of two or
/// more of the object's words twice (any run of two or more contains a pair, so pairs suffice).
fn repeats_object_words(name: &str, object: &str) -> bool {
    let obj: Vec<String> = od_codegen::ident::words(object).iter().map(|w| od_codegen::ident::singular(w)).collect();
    let acc: Vec<String> = name.split('_').filter(|w| !w.is_empty()).map(od_codegen::ident::singular).collect();
    obj.windows(2).any(|pair| acc.windows(2).filter(|w| w == &pair).count() >= 2)
}

/// `(files, accessors, accessors repeating their object's words, examples)` over `files`.
fn repeated_object_words(files: &[PathBuf]) -> (usize, usize, usize, Vec<String>) {
    let (mut total, mut repeated, mut examples) = (0usize, 0usize, Vec::new());
    for f in files {
        let bytes = std::fs::read(f).unwrap();
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let parsed = eds::parse(&name, &bytes, &eds::Options::lenient());
        for (index, sub, acc) in od_codegen::accessor_names(&parsed.model) {
            let Some(obj) = parsed.model.objects.values().find(|o| o.index.0 == index) else { continue };
            if !obj.object_type.has_subs() {
                continue;
            }
            total += 1;
            if repeats_object_words(&acc, &obj.name) {
                repeated += 1;
                if examples.len() < 400 {
                    let sub_name = obj.subs.values().find(|e| e.sub.0 == sub).map(|e| e.name.as_str()).unwrap_or("");
                    examples.push(format!("{name}: {acc}  ({:?} / {sub_name:?})", obj.name));
                }
            }
        }
    }
    (files.len(), total, repeated, examples)
}

#[test]
fn sub_entries_do_not_repeat_their_objects_words() {
    assert!(repeats_object_words("software_position_limit_max_software_position_limit", "Software position limit"));
    assert!(repeats_object_words(
        "programmable_limit_switch_widths_limit_switch_3_width",
        "Programmable limit switch widths"
    ));
    assert!(!repeats_object_words("software_position_limit_max", "Software position limit"));
    assert!(!repeats_object_words("error_history_1", "Error history"));

    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let devices: Vec<PathBuf> = ["camozzi-drvi.eds", "camozzi-drcs.eds", "kollmorgen-akd.eds"]
        .iter()
        .map(|f| root.join("devices").join(f))
        .collect();
    let corpus = files();
    let mut bad = Vec::new();
    for (what, list) in [("bundled devices", &devices), ("fixtures and corpus", &corpus)] {
        let (n, total, repeated, examples) = repeated_object_words(list);
        println!("{what}: {n} files, {total} sub-entry accessors, {repeated} repeat their object's words");
        for e in &examples {
            println!("  {e}");
        }
        bad.extend(examples);
    }
    assert!(bad.is_empty(), "accessors repeating their object's words: {bad:#?}");
}
