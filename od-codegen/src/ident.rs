//! The one identifier policy of the generator.
//!
//! Every Rust name in generated code comes from a CANopen `ParameterName` through this module
//! (the planner, `plan.rs`, combines an object's and a sub-entry's words):
//!
//! * Words are split at anything that is not an ASCII letter or digit, and at case changes
//!   (`TPDOMapping` → `tpdo`, `mapping`; `homeOffset` → `home`, `offset`), never between a
//!   letter and a digit (`RxPDO1` → `rx`, `pdo1`). A run of capitals with a plural `s` is one
//!   word (`COB-IDs` → `cob`, `ids`). Letters outside ASCII are spelt in ASCII (`ü` → `ue`,
//!   `é` → `e`, `°` → `deg`); other characters separate words and are dropped.
//! * A leading ordinal moves to the end as a number (`1st receive PDO parameter` →
//!   `receive_pdo_parameter_1`).
//! * `snake_case` for fields and methods, `SCREAMING_SNAKE_CASE` for constants, `CamelCase` for
//!   types.
//! * A name that would start with a digit gets an `x`/`X` prefix (`24V supply` → `x24v_supply`).
//! * A name that is a Rust keyword gets a trailing underscore (`type` → `type_`).
//! * An empty name (no letters or digits at all) falls back to the index: `x2001`, `sub3`.
//! * A name longer than [`MAX_LEN`] is shortened by [`shorten`], never cut inside a word.
//! * Collisions the planner's rules do not resolve are settled by [`Names`]: the later
//!   claimant gets a suffix made of its index (and sub-index), and a warning says so.

use std::collections::BTreeSet;

/// The ASCII spelling of a letter outside ASCII (German umlauts and ß spelt out, accents
/// dropped, a few symbols as words); `None`: not a letter we spell (a separator).
fn transliterate(c: char) -> Option<&'static str> {
    Some(match c {
        'ä' => "ae",
        'ö' => "oe",
        'ü' => "ue",
        'Ä' => "Ae",
        'Ö' => "Oe",
        'Ü' => "Ue",
        'ß' => "ss",
        'µ' | 'μ' => "u",
        '°' => "deg",
        '²' => "2",
        '³' => "3",
        'à' | 'á' | 'â' | 'ã' | 'å' => "a",
        'À' | 'Á' | 'Â' | 'Ã' | 'Å' => "A",
        'ç' => "c",
        'Ç' => "C",
        'è' | 'é' | 'ê' | 'ë' => "e",
        'È' | 'É' | 'Ê' | 'Ë' => "E",
        'ì' | 'í' | 'î' | 'ï' => "i",
        'Ì' | 'Í' | 'Î' | 'Ï' => "I",
        'ñ' => "n",
        'Ñ' => "N",
        'ò' | 'ó' | 'ô' | 'õ' | 'ø' => "o",
        'Ò' | 'Ó' | 'Ô' | 'Õ' | 'Ø' => "O",
        'ù' | 'ú' | 'û' => "u",
        'Ù' | 'Ú' | 'Û' => "U",
        'ý' | 'ÿ' => "y",
        'Ý' => "Y",
        _ => return None,
    })
}

/// Whether `w` is an ordinal written with digits (`1st`, `2nd`, `3rd`, `4th`, `21st`); gives
/// its number.
fn ordinal(w: &str) -> Option<&str> {
    let digits = w.trim_end_matches(|c: char| c.is_ascii_alphabetic());
    let suffix = &w[digits.len()..];
    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) && matches!(suffix, "st" | "nd" | "rd" | "th"))
        .then_some(digits)
}

/// Splits a parameter name into lower-case ASCII words.
///
/// Besides splitting at non-alphanumerics and case changes: letters outside ASCII are spelt in
/// ASCII (`Übergröße` → `uebergroesse`), an apostrophe inside a word is dropped (`won't` →
/// `wont`), a run of capitals with a plural `s` is one word (`COB-IDs` → `cob`, `ids`), and a
/// leading ordinal moves to the end as a number (`1st receive PDO parameter` → `receive`,
/// `pdo`, `parameter`, `1`), so no name needs an `x` prefix for it.
pub fn words(name: &str) -> Vec<String> {
    let mut chars: Vec<char> = Vec::with_capacity(name.len());
    for c in name.chars() {
        match transliterate(c) {
            Some(t) => chars.extend(t.chars()),
            None => chars.push(c),
        }
    }
    let mut out = Vec::new();
    let mut cur = String::new();
    for (i, &c) in chars.iter().enumerate() {
        if (c == '\'' || c == '’') && !cur.is_empty() && chars.get(i + 1).is_some_and(|n| n.is_ascii_alphabetic()) {
            continue;
        }
        if !c.is_ascii_alphanumeric() {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            continue;
        }
        if !cur.is_empty() && c.is_ascii_uppercase() {
            let prev = chars[i - 1];
            let next = chars.get(i + 1).copied();
            let next_lower = next.is_some_and(|n| n.is_ascii_lowercase());
            // `IDs`, `PDOs`: the lower-case `s` ends the word, it does not start one.
            let plural_s = next == Some('s') && !chars.get(i + 2).is_some_and(|n| n.is_ascii_lowercase());
            if prev.is_ascii_lowercase() || (prev.is_ascii_uppercase() && next_lower && !plural_s) {
                out.push(std::mem::take(&mut cur));
            }
        }
        cur.push(c.to_ascii_lowercase());
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    if out.len() > 1
        && let Some(n) = ordinal(&out[0])
    {
        let n = n.to_owned();
        out.remove(0);
        out.push(n);
    }
    out
}

/// Whole-word abbreviations used only to bring a name under [`MAX_LEN`].
const ABBREVIATIONS: &[(&str, &str)] = &[
    ("parameter", "param"),
    ("parameters", "params"),
    ("communication", "comm"),
    ("configuration", "config"),
    ("maximum", "max"),
    ("minimum", "min"),
    ("number", "num"),
    ("application", "app"),
    ("information", "info"),
    ("transmission", "tx"),
    ("transmit", "tx"),
    ("receive", "rx"),
    ("manufacturer", "mfr"),
    ("specific", "spec"),
    ("position", "pos"),
    ("velocity", "vel"),
    ("acceleration", "accel"),
    ("deceleration", "decel"),
    ("temperature", "temp"),
    ("interrupt", "irq"),
    ("supported", "supp"),
    ("digital", "dig"),
    ("analogue", "analog"),
];

/// Words that only link others; dropped (from inside a name, never its ends) to shorten it.
pub(crate) const LINKING: &[&str] =
    &["of", "the", "for", "by", "used", "to", "and", "in", "a", "an", "on", "with", "from", "at"];

/// The longest name the generator gives (getters; setters add `set_`).
pub const MAX_LEN: usize = 64;

/// A word compared singular and plural alike: `widths` → `width`, `entries` → `entry`,
/// `switches` → `switch`, `ids` → `id`.
pub fn singular(w: &str) -> String {
    if let Some(stem) = w.strip_suffix("ies").filter(|s| s.len() >= 2) {
        return format!("{stem}y");
    }
    for end in ["sses", "ches", "shes", "xes"] {
        if w.ends_with(end) {
            return w[..w.len() - 2].to_owned();
        }
    }
    match w.strip_suffix('s') {
        Some(stem) if w.len() >= 3 && !stem.ends_with('s') => stem.to_owned(),
        _ => w.to_owned(),
    }
}

fn joined_len(w: &[String]) -> usize {
    w.iter().map(String::len).sum::<usize>() + w.len().saturating_sub(1)
}

/// Shortens a name given as words to at most `max` characters (joined by `_`), in steps that
/// keep it readable, each only while the name is still too long: repeated words (not
/// numbers) after their first use are dropped, linking words inside the name are dropped, long
/// words take their usual abbreviation, long words take their usual abbreviation (the table's order), and finally words are dropped from the middle (the
/// first two and the last three stay). Never cuts a word.
pub fn shorten(mut w: Vec<String>, max: usize) -> Vec<String> {
    if joined_len(&w) <= max {
        return w;
    }
    let mut seen = BTreeSet::new();
    w.retain(|x| x.bytes().all(|b| b.is_ascii_digit()) || seen.insert(x.clone()));
    if joined_len(&w) <= max {
        return w;
    }
    let n = w.len();
    let mut i = 0;
    w.retain(|x| {
        i += 1;
        !(i > 1 && i < n && LINKING.contains(&x.as_str()))
    });
    for (long, short) in ABBREVIATIONS {
        if joined_len(&w) <= max {
            return w;
        }
        for x in w.iter_mut().filter(|x| x == long) {
            *x = (*short).to_owned();
        }
    }
    while joined_len(&w) > max && w.len() > 5 {
        w.remove(2);
    }
    while joined_len(&w) > max && w.len() > 1 {
        w.remove(w.len() / 2);
    }
    w
}

const KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern", "false", "fn",
    "for", "gen", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return", "self",
    "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where", "while", "abstract", "become",
    "box", "do", "final", "macro", "override", "priv", "try", "typeof", "unsized", "virtual", "yield",
];

fn finish(mut s: String, prefix: char) -> String {
    if s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, prefix);
    }
    if KEYWORDS.contains(&s.as_str()) || s == "Self" || s == "_" {
        s.push('_');
    }
    s
}

/// `snake_case`, or `None` when the name has no letters or digits.
pub fn snake(name: &str) -> Option<String> {
    let w = words(name);
    if w.is_empty() { None } else { Some(finish(w.join("_"), 'x')) }
}

/// `SCREAMING_SNAKE_CASE`, or `None` when the name has no letters or digits.
pub fn screaming(name: &str) -> Option<String> {
    snake(name).map(|s| s.trim_end_matches('_').to_ascii_uppercase()).map(|s| finish(s, 'X'))
}

/// `CamelCase`, or `None` when the name has no letters or digits.
pub fn camel(name: &str) -> Option<String> {
    let w = words(name);
    if w.is_empty() {
        return None;
    }
    let mut s = String::new();
    for word in w {
        let mut cs = word.chars();
        if let Some(f) = cs.next() {
            s.push(f.to_ascii_uppercase());
            s.extend(cs);
        }
    }
    Some(finish(s, 'X'))
}

/// A set of claimed names in one namespace.
#[derive(Debug, Default)]
pub struct Names {
    taken: BTreeSet<String>,
}

impl Names {
    /// A namespace in which `reserved` are already taken.
    pub fn with_reserved(reserved: &[&str]) -> Self {
        Names { taken: reserved.iter().map(|s| s.to_string()).collect() }
    }

    /// Whether `name` is free.
    pub fn is_free(&self, name: &str) -> bool {
        !self.taken.contains(name)
    }

    /// Claims `name`; if taken, tries each of `fallbacks` in turn, then numbered variants of the
    /// last one. Returns the name claimed and whether it differs from `name`.
    pub fn claim(&mut self, name: &str, fallbacks: &[String]) -> (String, bool) {
        self.claim_with(name, fallbacks, |_| true)
    }

    /// Like [`Names::claim`], but a candidate must also satisfy `also_free` (used to claim a
    /// getter and its `set_` setter together).
    pub fn claim_with(&mut self, name: &str, fallbacks: &[String], also_free: impl Fn(&str) -> bool) -> (String, bool) {
        let ok = |s: &str, taken: &BTreeSet<String>| !taken.contains(s) && also_free(s);
        if ok(name, &self.taken) {
            self.taken.insert(name.to_owned());
            return (name.to_owned(), false);
        }
        for f in fallbacks {
            if ok(f, &self.taken) {
                self.taken.insert(f.clone());
                return (f.clone(), true);
            }
        }
        let base = fallbacks.last().map(String::as_str).unwrap_or(name);
        let mut n = 2u32;
        loop {
            let cand = format!("{base}_{n}");
            if ok(&cand, &self.taken) {
                self.taken.insert(cand.clone());
                return (cand, true);
            }
            n += 1;
        }
    }

    /// Marks `name` as taken.
    pub fn insert(&mut self, name: String) {
        self.taken.insert(name);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases() {
        assert_eq!(snake("Controlword").as_deref(), Some("controlword"));
        assert_eq!(snake("Modes of operation display").as_deref(), Some("modes_of_operation_display"));
        assert_eq!(snake("TPDOMapping").as_deref(), Some("tpdo_mapping"));
        assert_eq!(snake("homeOffset").as_deref(), Some("home_offset"));
        assert_eq!(snake("Vendor-ID").as_deref(), Some("vendor_id"));
        assert_eq!(snake("24V supply").as_deref(), Some("x24v_supply"));
        assert_eq!(snake("Type").as_deref(), Some("type_"));
        assert_eq!(snake("Übergröße").as_deref(), Some("uebergroesse"));
        assert_eq!(snake("COB-IDs").as_deref(), Some("cob_ids"));
        assert_eq!(snake("Number of PDOs").as_deref(), Some("number_of_pdos"));
        assert_eq!(snake("IDs").as_deref(), Some("ids"));
        assert_eq!(snake("IDsize").as_deref(), Some("i_dsize"));
        assert_eq!(snake("RxPDO1").as_deref(), Some("rx_pdo1"));
        assert_eq!(snake("won't").as_deref(), Some("wont"));
        assert_eq!(snake("1st receive PDO parameter").as_deref(), Some("receive_pdo_parameter_1"));
        assert_eq!(snake("2nd").as_deref(), Some("x2nd"));
        assert_eq!(snake("Velocity [mm/s]").as_deref(), Some("velocity_mm_s"));
        assert_eq!(snake(" -- "), None);
        assert_eq!(screaming("Controlword").as_deref(), Some("CONTROLWORD"));
        assert_eq!(screaming("Type").as_deref(), Some("TYPE"));
        assert_eq!(screaming("1st value").as_deref(), Some("VALUE_1"));
        assert_eq!(screaming("8-bit input").as_deref(), Some("X8_BIT_INPUT"));
        assert_eq!(camel("transmit PDO 1").as_deref(), Some("TransmitPdo1"));
        assert_eq!(camel("self").as_deref(), Some("Self_"));
    }

    #[test]
    fn collisions() {
        let mut n = Names::with_reserved(&["new"]);
        assert_eq!(n.claim("new", &["new_1000".into()]), ("new_1000".into(), true));
        assert_eq!(n.claim("speed", &["speed_2000".into()]), ("speed".into(), false));
        assert_eq!(n.claim("speed", &["speed_2001".into()]), ("speed_2001".into(), true));
        assert_eq!(n.claim("speed", &["speed_2001".into()]), ("speed_2001_2".into(), true));
    }
}

#[cfg(test)]
mod shorten_tests {
    use super::*;

    fn w(s: &str) -> Vec<String> {
        s.split('_').map(str::to_owned).collect()
    }

    #[test]
    fn short_names_are_kept() {
        assert_eq!(shorten(w("controlword"), MAX_LEN), w("controlword"));
    }

    #[test]
    fn long_names_lose_repeats_then_linking_words_then_middle_words() {
        let long = w(
            "input_interrupt_mask_32_input_lines_low_to_high_input_interrupt_mask_low_to_high_for_digital_inputs_1_32",
        );
        let s = shorten(long, MAX_LEN).join("_");
        assert!(s.len() <= MAX_LEN, "{s}");
        assert!(s.starts_with("input_interrupt_mask_32") && s.ends_with("1_32"), "{s}");
        for max in [8, 16, 30] {
            let s = shorten(w("a_very_long_name_of_many_words_that_goes_on_and_on"), max).join("_");
            assert!(s.len() <= max || !s.contains('_'), "{max}: {s}");
        }
    }
}
