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
//!   A single lower-case letter before a capital is a prefix (`mA` → `ma`, `kHz` → `khz`). Case
//!   alone cannot split every word right (`CANopen` reads like `SDOServer`, `EtherCAT` like
//!   `RxPDO`), so a short list of the field's mixed-case words ([`FIELD_WORDS`]) is matched
//!   first: `CANopen baudrate` → `canopen_baudrate`.
//! * Leading numbers, in any form (`1.`, `1)`, `1-`, `1st`, `1rst`, `5V`, `8-Bit`), move behind
//!   the other words, an ordinal as its number (`1. Receive PDO parameter` →
//!   `receive_pdo_parameter_1`, `5V DC supply` → `dc_supply_5v`); a name that is only a number
//!   spells it (`2nd` → `second`). No name starts with a digit, so none needs a prefix.
//! * `snake_case` for fields and methods, `SCREAMING_SNAKE_CASE` for constants, `CamelCase` for
//!   types.
//! * A name that is a Rust keyword gets a trailing underscore (`type` → `type_`).
//! * An empty name (no letters or digits at all) falls back to the index: `object_2001`, `sub3`.
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

/// Mixed-case words of the field that are one word, as they are written. Case alone cannot
/// tell `CANopen` (`CAN` + `open`) from `SDOServer` (`SDO` + `Server`), nor `EtherCAT` from
/// `RxPDO` (`Rx` + `PDO`): the splitting rule follows the common camel-case reading, and these
/// few names of buses, encoders and standards, which read the other way, are matched before it
/// (`CANopenNode` → `canopen`, `node`; `CiA402` → `cia402`). Only a spelling listed here, with
/// no lower-case letter right after it, is matched.
pub const FIELD_WORDS: &[&str] = &["CANopen", "EtherCAT", "PLCopen", "CiA", "BiSS", "EnDat", "DeviceNet", "EtherNet"];

/// Letters after the digits of an ordinal: English `1st`, `2nd`, `3rd`, `4th` (and `3th`,
/// `1rst` as vendors write them), French `1er`, `1re`, `2e`, `2eme` (`2ème`).
const ORDINAL_ENDINGS: &[&str] = &["st", "nd", "rd", "th", "rst", "er", "re", "ere", "e", "eme", "ieme"];

/// The digits of `w` when it is an ordinal written with digits (`1st`, `21st`, `1rst`, `2eme`).
fn ordinal(w: &str) -> Option<&str> {
    let digits = w.trim_end_matches(|c: char| c.is_ascii_alphabetic());
    let suffix = &w[digits.len()..];
    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) && ORDINAL_ENDINGS.contains(&suffix))
        .then_some(digits)
}

fn starts_with_digit(w: &str) -> bool {
    w.starts_with(|c: char| c.is_ascii_digit())
}

/// The longest word a hyphen binds to a leading number as its measure (`8-Bit`, `2-axis`,
/// `3-phase`); a longer one (`1-Receive`) starts the name's own words.
const MEASURE_LEN: usize = 5;

/// A name's leading numbers, in any form (`1.`, `1)`, `1-`, `1st`, `1rst`, `2eme`, `5V`,
/// `8-Bit`, `1 2`), move behind its other words, where a person puts an index or a measure:
/// `1. Receive PDO parameter` → `receive pdo parameter 1`, `5V DC supply` → `dc supply 5v`,
/// `8-Bit analog Input 1` → `analog input 1 8 bit`. An ordinal keeps only its number. A name
/// that is nothing but numbers spells its first one out (`2nd` → `second`, `5V` → `five v`,
/// `1234` → `number 1234`). So no word list starts with a digit.
///
/// `hyphen[i]`: a single `-` joined word `i` to the one before.
fn move_leading_numbers(words: Vec<String>, hyphen: &[bool]) -> Vec<String> {
    if !words.first().is_some_and(|w| starts_with_digit(w)) {
        return words;
    }
    let mut lead = Vec::new();
    let mut i = 0;
    while i < words.len() && starts_with_digit(&words[i]) {
        lead.push(ordinal(&words[i]).unwrap_or(&words[i]).to_owned());
        i += 1;
        if i < words.len()
            && hyphen.get(i).copied().unwrap_or(false)
            && words[i].len() <= MEASURE_LEN
            && words[i].bytes().all(|b| b.is_ascii_alphabetic())
        {
            lead.push(words[i].clone());
            i += 1;
        }
    }
    let mut out = words[i..].to_vec();
    if out.is_empty() {
        let first = &words[0];
        let digits = first.trim_end_matches(|c: char| c.is_ascii_alphabetic());
        let spelt = if ordinal(first).is_some() { spell_ordinal(digits) } else { spell_cardinal(digits) };
        match spelt {
            Some(spelt) => {
                out.extend(spelt);
                let unit = if ordinal(first).is_some() { "" } else { &first[digits.len()..] };
                if !unit.is_empty() {
                    out.push(unit.to_owned());
                }
            }
            None => {
                out.push("number".to_owned());
                out.push(lead[0].clone());
            }
        }
        out.extend(lead.into_iter().skip(1));
    } else {
        out.extend(lead);
    }
    out
}

const ONES: [&str; 20] = [
    "zero",
    "one",
    "two",
    "three",
    "four",
    "five",
    "six",
    "seven",
    "eight",
    "nine",
    "ten",
    "eleven",
    "twelve",
    "thirteen",
    "fourteen",
    "fifteen",
    "sixteen",
    "seventeen",
    "eighteen",
    "nineteen",
];
const ONES_TH: [&str; 20] = [
    "zeroth",
    "first",
    "second",
    "third",
    "fourth",
    "fifth",
    "sixth",
    "seventh",
    "eighth",
    "ninth",
    "tenth",
    "eleventh",
    "twelfth",
    "thirteenth",
    "fourteenth",
    "fifteenth",
    "sixteenth",
    "seventeenth",
    "eighteenth",
    "nineteenth",
];
const TENS: [&str; 10] = ["", "", "twenty", "thirty", "forty", "fifty", "sixty", "seventy", "eighty", "ninety"];
const TENS_TH: [&str; 10] =
    ["", "", "twentieth", "thirtieth", "fortieth", "fiftieth", "sixtieth", "seventieth", "eightieth", "ninetieth"];

/// The number below 100 written in `digits` (no leading zero but `0` itself).
fn small_number(digits: &str) -> Option<usize> {
    if digits.is_empty() || digits.len() > 2 || (digits.len() == 2 && digits.starts_with('0')) {
        return None;
    }
    digits.parse().ok()
}

/// `21` → `twenty one`; `None` from 100 on.
fn spell_cardinal(digits: &str) -> Option<Vec<String>> {
    let n = small_number(digits)?;
    Some(match n {
        0..20 => vec![ONES[n].to_owned()],
        _ if n % 10 == 0 => vec![TENS[n / 10].to_owned()],
        _ => vec![TENS[n / 10].to_owned(), ONES[n % 10].to_owned()],
    })
}

/// `21` → `twenty first`; `None` from 100 on.
fn spell_ordinal(digits: &str) -> Option<Vec<String>> {
    let n = small_number(digits)?;
    Some(match n {
        0..20 => vec![ONES_TH[n].to_owned()],
        _ if n % 10 == 0 => vec![TENS_TH[n / 10].to_owned()],
        _ => vec![TENS[n / 10].to_owned(), ONES_TH[n % 10].to_owned()],
    })
}

/// The field word ([`FIELD_WORDS`]) written at `chars[i..]`, if one is, with nothing but a
/// non-lower-case character after it.
fn field_word_at(chars: &[char], i: usize) -> Option<&'static str> {
    FIELD_WORDS.iter().copied().find(|w| {
        let n = w.chars().count();
        chars.len() >= i + n
            && w.chars().zip(&chars[i..i + n]).all(|(a, b)| a == *b)
            && !chars.get(i + n).is_some_and(|c| c.is_ascii_lowercase())
    })
}

/// Splits a parameter name into lower-case ASCII words.
///
/// Besides splitting at non-alphanumerics and case changes: letters outside ASCII are spelt in
/// ASCII (`Übergröße` → `uebergroesse`), an apostrophe inside a word is dropped (`won't` →
/// `wont`), a run of capitals with a plural `s` is one word (`COB-IDs` → `cob`, `ids`), a
/// single lower-case letter before a capital is its prefix, not a word (`mA` → `ma`, `kHz` →
/// `khz`), the field's mixed-case words stay whole ([`FIELD_WORDS`]: `CANopen` → `canopen`),
/// and leading numbers move behind the other words (`move_leading_numbers`: `1st receive PDO
/// parameter` → `receive`, `pdo`, `parameter`, `1`), so no word list starts with a digit.
pub fn words(name: &str) -> Vec<String> {
    let mut chars: Vec<char> = Vec::with_capacity(name.len());
    for c in name.chars() {
        match transliterate(c) {
            Some(t) => chars.extend(t.chars()),
            None => chars.push(c),
        }
    }
    let mut out = Vec::new();
    // Whether a single `-` joined each word of `out` to the one before.
    let mut hyphen = Vec::new();
    let mut sep = String::new();
    let mut cur = String::new();
    let mut push = |cur: &mut String, sep: &mut String, out: &mut Vec<String>| {
        if !cur.is_empty() {
            hyphen.push(sep == "-");
            out.push(std::mem::take(cur));
            sep.clear();
        }
    };
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if (c == '\'' || c == '’') && !cur.is_empty() && chars.get(i + 1).is_some_and(|n| n.is_ascii_alphabetic()) {
            i += 1;
            continue;
        }
        if !c.is_ascii_alphanumeric() {
            push(&mut cur, &mut sep, &mut out);
            sep.push(c);
            i += 1;
            continue;
        }
        if c.is_ascii_uppercase()
            && (cur.is_empty() || chars[i - 1].is_ascii_lowercase())
            && let Some(w) = field_word_at(&chars, i)
        {
            push(&mut cur, &mut sep, &mut out);
            cur.push_str(&w.to_ascii_lowercase());
            i += w.chars().count();
            continue;
        }
        if !cur.is_empty() && c.is_ascii_uppercase() {
            let prev = chars[i - 1];
            let next = chars.get(i + 1).copied();
            let next_lower = next.is_some_and(|n| n.is_ascii_lowercase());
            // `IDs`, `PDOs`: the lower-case `s` ends the word, it does not start one.
            let plural_s = next == Some('s') && !chars.get(i + 2).is_some_and(|n| n.is_ascii_lowercase());
            // `mA`, `kHz`: a lone lower-case letter is a prefix of what follows.
            let prefix = cur.len() == 1 && prev.is_ascii_lowercase();
            if (prev.is_ascii_lowercase() && !prefix) || (prev.is_ascii_uppercase() && next_lower && !plural_s) {
                push(&mut cur, &mut sep, &mut out);
            }
        }
        cur.push(c.to_ascii_lowercase());
        i += 1;
    }
    push(&mut cur, &mut sep, &mut out);
    move_leading_numbers(out, &hyphen)
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

/// Escapes a keyword. ([`words`] never starts with a digit, so neither does a name.)
fn finish(mut s: String) -> String {
    if KEYWORDS.contains(&s.as_str()) || s == "Self" || s == "_" {
        s.push('_');
    }
    s
}

/// `snake_case`, or `None` when the name has no letters or digits.
pub fn snake(name: &str) -> Option<String> {
    let w = words(name);
    if w.is_empty() { None } else { Some(finish(w.join("_"))) }
}

/// `SCREAMING_SNAKE_CASE`, or `None` when the name has no letters or digits.
pub fn screaming(name: &str) -> Option<String> {
    snake(name).map(|s| s.trim_end_matches('_').to_ascii_uppercase()).map(finish)
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
    Some(finish(s))
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
        assert_eq!(snake("24V supply").as_deref(), Some("supply_24v"));
        assert_eq!(snake("Type").as_deref(), Some("type_"));
        assert_eq!(snake("Übergröße").as_deref(), Some("uebergroesse"));
        assert_eq!(snake("COB-IDs").as_deref(), Some("cob_ids"));
        assert_eq!(snake("Number of PDOs").as_deref(), Some("number_of_pdos"));
        assert_eq!(snake("IDs").as_deref(), Some("ids"));
        assert_eq!(snake("IDsize").as_deref(), Some("i_dsize"));
        assert_eq!(snake("CANopen baudrate").as_deref(), Some("canopen_baudrate"));
        assert_eq!(snake("AKD CANopen").as_deref(), Some("akd_canopen"));
        assert_eq!(snake("CANopenNode").as_deref(), Some("canopen_node"));
        assert_eq!(snake("EtherCAT state").as_deref(), Some("ethercat_state"));
        assert_eq!(snake("CiA402 mode").as_deref(), Some("cia402_mode"));
        assert_eq!(snake("BiSS sensor position bits").as_deref(), Some("biss_sensor_position_bits"));
        assert_eq!(snake("Number of IOs").as_deref(), Some("number_of_ios"));
        assert_eq!(snake("SDOServer").as_deref(), Some("sdo_server"));
        assert_eq!(snake("Current mA").as_deref(), Some("current_ma"));
        assert_eq!(snake("Frequency (10 kHz)").as_deref(), Some("frequency_10_khz"));
        assert_eq!(snake("RxPDO1").as_deref(), Some("rx_pdo1"));
        assert_eq!(snake("won't").as_deref(), Some("wont"));
        assert_eq!(snake("1st receive PDO parameter").as_deref(), Some("receive_pdo_parameter_1"));
        assert_eq!(snake("1. Receive PDO parameter").as_deref(), Some("receive_pdo_parameter_1"));
        assert_eq!(snake("1) Receive PDO parameter").as_deref(), Some("receive_pdo_parameter_1"));
        assert_eq!(snake("1- Receive PDO parameter").as_deref(), Some("receive_pdo_parameter_1"));
        assert_eq!(
            snake("1rst receive PDO communication parameter").as_deref(),
            Some("receive_pdo_communication_parameter_1")
        );
        assert_eq!(snake("2eme entree").as_deref(), Some("entree_2"));
        assert_eq!(snake("5V DC supply").as_deref(), Some("dc_supply_5v"));
        assert_eq!(snake("8-Bit analog Input 1").as_deref(), Some("analog_input_1_8_bit"));
        assert_eq!(snake("1-Receive PDO").as_deref(), Some("receive_pdo_1"));
        assert_eq!(snake("1-4 inputs").as_deref(), Some("inputs_1_4"));
        assert_eq!(snake("2nd").as_deref(), Some("second"));
        assert_eq!(snake("21st").as_deref(), Some("twenty_first"));
        assert_eq!(snake("5V").as_deref(), Some("five_v"));
        assert_eq!(snake("40").as_deref(), Some("forty"));
        assert_eq!(snake("1234").as_deref(), Some("number_1234"));
        assert_eq!(snake("16-Bit").as_deref(), Some("sixteen_bit"));
        assert_eq!(snake("Velocity [mm/s]").as_deref(), Some("velocity_mm_s"));
        assert_eq!(snake(" -- "), None);
        assert_eq!(screaming("Controlword").as_deref(), Some("CONTROLWORD"));
        assert_eq!(screaming("Type").as_deref(), Some("TYPE"));
        assert_eq!(screaming("1st value").as_deref(), Some("VALUE_1"));
        assert_eq!(screaming("8-bit input").as_deref(), Some("INPUT_8_BIT"));
        assert_eq!(camel("2nd encoder").as_deref(), Some("Encoder2"));
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
