//! The one identifier policy of the generator.
//!
//! Every Rust name in generated code comes from a CANopen `ParameterName` through this module:
//!
//! * Words are split at anything that is not an ASCII letter or digit, and at case changes
//!   (`TPDOMapping` → `tpdo`, `mapping`; `homeOffset` → `home`, `offset`). Other characters
//!   (including non-ASCII letters) separate words and are dropped.
//! * `snake_case` for fields and methods, `SCREAMING_SNAKE_CASE` for constants, `CamelCase` for
//!   types.
//! * A name that would start with a digit gets an `x`/`X` prefix (`24V supply` → `x24v_supply`).
//! * A name that is a Rust keyword gets a trailing underscore (`type` → `type_`).
//! * An empty name (no letters or digits at all) falls back to the index: `x2001`, `sub3`.
//! * Collisions are resolved by [`Names`]: the second claimant of a name gets a suffix made of its
//!   index (and sub-index), and a warning says so.

use std::collections::BTreeSet;

/// Splits a parameter name into lower-case ASCII words.
pub fn words(name: &str) -> Vec<String> {
    let chars: Vec<char> = name.chars().collect();
    let mut out = Vec::new();
    let mut cur = String::new();
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_ascii_alphanumeric() {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            continue;
        }
        if !cur.is_empty() && c.is_ascii_uppercase() {
            let prev = chars[i - 1];
            let next_lower = chars.get(i + 1).is_some_and(|n| n.is_ascii_lowercase());
            if prev.is_ascii_lowercase() || (prev.is_ascii_uppercase() && next_lower) {
                out.push(std::mem::take(&mut cur));
            }
        }
        cur.push(c.to_ascii_lowercase());
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
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
        assert_eq!(snake("Übergröße").as_deref(), Some("bergr_e"));
        assert_eq!(snake(" -- "), None);
        assert_eq!(screaming("Controlword").as_deref(), Some("CONTROLWORD"));
        assert_eq!(screaming("Type").as_deref(), Some("TYPE"));
        assert_eq!(screaming("1st value").as_deref(), Some("X1ST_VALUE"));
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
