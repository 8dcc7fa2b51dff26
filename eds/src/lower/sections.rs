//! Pass 1: lines → sections with classified names, and syntax-level diagnostics.

use std::collections::HashMap;

use super::{Crumbs, Ctx};
use crate::ast::{Document, LineKind};
use crate::codes;
use crate::model::Category;
use crate::source::{Encoding, Span};

/// One `key=value` entry.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kv<'a> {
    pub key: &'a str,
    pub value: &'a str,
    pub key_span: Span,
    pub value_span: Span,
    /// Which occurrence of a duplicated section the entry came from (0 = the first).
    pub occurrence: u16,
}

/// What a section name means.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Kind {
    FileInfo,
    DeviceInfo,
    DummyUsage,
    Comments,
    List(Category),
    Commissioning,
    Object(u16),
    Sub(u16, u8),
    Names(u16),
    Values(u16),
    Links(u16),
    Unknown,
}

/// A section, with the entries of all its occurrences (duplicates are merged).
#[derive(Debug)]
pub(crate) struct Section<'a> {
    pub name: &'a str,
    pub name_span: Span,
    pub kind: Kind,
    pub entries: Vec<Kv<'a>>,
}

/// All sections in file order (of first occurrence), with a lookup by kind.
pub(crate) struct Sections<'a> {
    pub list: Vec<Section<'a>>,
    by_kind: HashMap<Kind, usize>,
}

impl<'a> Sections<'a> {
    /// The section of a kind (not for [`Kind::Unknown`]).
    pub fn get(&self, kind: Kind) -> Option<&Section<'a>> {
        self.by_kind.get(&kind).map(|&i| &self.list[i])
    }
}

/// The fixed (non-object) sections and their CiA 306 spelling.
const FIXED: &[(&str, Kind)] = &[
    ("FileInfo", Kind::FileInfo),
    ("DeviceInfo", Kind::DeviceInfo),
    ("DummyUsage", Kind::DummyUsage),
    ("Comments", Kind::Comments),
    ("MandatoryObjects", Kind::List(Category::Mandatory)),
    ("OptionalObjects", Kind::List(Category::Optional)),
    ("ManufacturerObjects", Kind::List(Category::Manufacturer)),
    ("DeviceComissioning", Kind::Commissioning),
];

/// How a section or key name relates to its CiA 306 spelling.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Spelling {
    Exact,
    /// Same letters, different case; holds the CiA 306 spelling.
    Case(String),
    /// Different spelling (spaces, underscores, a known misspelling); holds the CiA 306 spelling.
    Misspelled(String),
    /// Looks like an object section but is malformed; holds the reason.
    Malformed(String),
}

/// Whether `a` and `b` are equal ignoring ASCII case and the characters ` `, `_` and `-`.
pub(crate) fn loose_eq(a: &str, b: &str) -> bool {
    let significant = |c: &u8| !matches!(c, b' ' | b'_' | b'-' | b'\t');
    let mut x = a.bytes().filter(significant);
    let mut y = b.bytes().filter(significant);
    loop {
        match (x.next(), y.next()) {
            (None, None) => return true,
            (Some(p), Some(q)) if p.eq_ignore_ascii_case(&q) => {}
            _ => return false,
        }
    }
}

fn hex4(s: &str) -> Option<u16> {
    if s.len() == 4 && s.bytes().all(|b| b.is_ascii_hexdigit()) { u16::from_str_radix(s, 16).ok() } else { None }
}

/// Classifies a section name.
pub(crate) fn classify(name: &str) -> (Kind, Spelling) {
    if let Some(index) = name.get(..4).and_then(hex4) {
        return classify_object(name, index);
    }
    for &(canon, kind) in FIXED {
        if name == canon {
            return (kind, Spelling::Exact);
        }
        if name.eq_ignore_ascii_case(canon) {
            return (kind, Spelling::Case(canon.to_owned()));
        }
    }
    // The spec's own typo is the standard; the correct English spelling is a common mistake.
    if loose_eq(name, "DeviceCommissioning") {
        return (Kind::Commissioning, Spelling::Misspelled("DeviceComissioning".to_owned()));
    }
    for &(canon, kind) in FIXED {
        if loose_eq(name, canon) {
            return (kind, Spelling::Misspelled(canon.to_owned()));
        }
    }
    (Kind::Unknown, Spelling::Exact)
}

/// Classifies a section name that starts with four hex digits (`index`).
fn classify_object(name: &str, index: u16) -> (Kind, Spelling) {
    let rest = &name[4..];
    let canon_index = format!("{index:04X}");
    let spelled = |kind: Kind, canon: String| {
        if canon == name { (kind, Spelling::Exact) } else { (kind, Spelling::Case(canon)) }
    };
    if rest.is_empty() {
        return spelled(Kind::Object(index), canon_index);
    }
    if rest.len() >= 3 && rest.is_char_boundary(3) && rest[..3].eq_ignore_ascii_case("sub") {
        let digits = &rest[3..];
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
            return (Kind::Unknown, Spelling::Malformed(format!("`{digits}` is not a hexadecimal sub-index")));
        }
        let trimmed = digits.trim_start_matches('0');
        if trimmed.len() > 2 {
            return (Kind::Unknown, Spelling::Malformed(format!("sub-index 0x{digits} is larger than 0xFF")));
        }
        let sub = u8::from_str_radix(if trimmed.is_empty() { "0" } else { trimmed }, 16).unwrap_or(0);
        return spelled(Kind::Sub(index, sub), format!("{canon_index}sub{}", digits.to_ascii_uppercase()));
    }
    for (suffix, kind) in
        [("Name", Kind::Names(index)), ("Value", Kind::Values(index)), ("ObjectLinks", Kind::Links(index))]
    {
        if rest.eq_ignore_ascii_case(suffix) {
            return spelled(kind, format!("{canon_index}{suffix}"));
        }
    }
    (Kind::Unknown, Spelling::Exact)
}

/// Groups the document's lines into sections and reports line-level problems.
pub(crate) fn collect<'a>(doc: &'a Document, cx: &mut Ctx<'_>) -> Sections<'a> {
    let src = &doc.source;
    if src.encoding == Encoding::Windows1252 {
        cx.emit(codes::E0001, None, "file is not valid UTF-8; it was decoded as Windows-1252").hint =
            Some("save the file as UTF-8 (or plain ASCII, as CiA 306 asks)".to_owned());
    } else if let Some(pos) = src.text.bytes().position(|b| b >= 0x80) {
        let ch_len = src.text[pos..].chars().next().map(char::len_utf8).unwrap_or(1);
        cx.emit(codes::E0009, Some(Span::new(pos as u32, (pos + ch_len) as u32)), "the file contains non-ASCII text")
            .hint = Some("CiA 306 files are ASCII; tools that expect it may misread this text".to_owned());
    }
    let mut list: Vec<Section<'a>> = Vec::new();
    let mut by_kind: HashMap<Kind, usize> = HashMap::new();
    let mut unknown_by_name: HashMap<String, usize> = HashMap::new();
    let mut occurrences: Vec<u16> = Vec::new();
    // Index into `list` of the section the following entries belong to, and its occurrence.
    let mut current: Option<(usize, u16)> = None;
    for line in &doc.lines {
        match line.kind {
            LineKind::Section { name, trailing } => {
                let name_str = src.slice(name);
                let trailing_str = src.slice(trailing).trim();
                if !trailing_str.is_empty() && !trailing_str.starts_with(';') {
                    let d = cx.emit(
                        codes::E0005,
                        Some(trailing),
                        format!("unexpected text `{trailing_str}` after section header [{name_str}]"),
                    );
                    d.hint = Some("put comments on their own line, starting with `;`".to_owned());
                }
                let (kind, spelling) = classify(name_str);
                report_spelling(cx, name, name_str, &spelling);
                let existing = match kind {
                    Kind::Unknown => unknown_by_name.get(&name_str.to_ascii_lowercase()).copied(),
                    k => by_kind.get(&k).copied(),
                };
                match existing {
                    Some(i) => {
                        occurrences[i] += 1;
                        let first = src.line_col(list[i].name_span.start);
                        let d = cx.emit(
                            codes::E0006,
                            Some(name),
                            format!("section [{name_str}] appears again (first at line {})", first.line),
                        );
                        d.hint = Some(
                            "merge the two sections; where both set a key, this reader uses the later value".to_owned(),
                        );
                        current = Some((i, occurrences[i]));
                    }
                    None => {
                        let i = list.len();
                        list.push(Section { name: name_str, name_span: name, kind, entries: Vec::with_capacity(8) });
                        occurrences.push(0);
                        match kind {
                            Kind::Unknown => {
                                unknown_by_name.insert(name_str.to_ascii_lowercase(), i);
                            }
                            k => {
                                by_kind.insert(k, i);
                            }
                        }
                        current = Some((i, 0));
                    }
                }
            }
            LineKind::Entry { key, value } => {
                let kv = Kv {
                    key: src.slice(key),
                    value: src.slice(value),
                    key_span: key,
                    value_span: value,
                    occurrence: 0,
                };
                match current {
                    Some((i, occ)) => list[i].entries.push(Kv { occurrence: occ, ..kv }),
                    None => {
                        let d = cx.emit(
                            codes::E0003,
                            Some(line.content),
                            format!("entry `{}` comes before any section header and is ignored", kv.key),
                        );
                        d.hint = Some("move it into the section it belongs to".to_owned());
                    }
                }
            }
            LineKind::Comment { text } => {
                if text.start > 0 && src.text.as_bytes().get(text.start as usize - 1) == Some(&b'#') {
                    let hash = Span::new(text.start - 1, text.start);
                    cx.emit(codes::E0004, Some(hash), "comment starts with `#`").hint =
                        Some("CiA 306 comments start with `;`".to_owned());
                }
            }
            LineKind::Garbage => {
                let content = src.slice(line.content);
                let shown: String = content.trim().chars().take(60).collect();
                let hint = if content.trim_start().starts_with('[') {
                    "close the section name with `]`"
                } else {
                    "entries are written `Key=Value`; comments start with `;`"
                };
                let d = cx.emit(
                    codes::E0002,
                    Some(line.content),
                    format!("`{shown}` is not a section header, a `key=value` entry or a comment (line ignored)"),
                );
                d.hint = Some(hint.to_owned());
            }
            LineKind::Blank => {}
        }
    }
    Sections { list, by_kind }
}

fn report_spelling(cx: &mut Ctx<'_>, span: Span, name: &str, spelling: &Spelling) {
    match spelling {
        Spelling::Exact => {}
        Spelling::Case(canon) => {
            cx.emit(codes::E0104, Some(span), format!("section [{name}] is written [{canon}] in CiA 306")).hint =
                Some(format!("write [{canon}]"));
        }
        Spelling::Misspelled(canon) => {
            let d = cx.emit(codes::E0103, Some(span), format!("section [{name}] is spelled [{canon}] in CiA 306"));
            d.hint = Some(if canon == "DeviceComissioning" {
                "CiA 306 spells it [DeviceComissioning] (one `m`); this reader accepts both".to_owned()
            } else {
                format!("write [{canon}]")
            });
        }
        Spelling::Malformed(why) => {
            let d =
                cx.emit(codes::E0105, Some(span), format!("section [{name}] looks like an object section, but {why}"));
            d.hint = Some("object sections are [IIII], [IIIIsubS], [IIIIName], [IIIIValue] or [IIIIObjectLinks] with hexadecimal IIII and S".to_owned());
        }
    }
}

/// The known keys of a section, matched against its entries.
pub(crate) struct Keys<'s, 'a> {
    /// For each known key, the entry that sets it (the last one if repeated).
    pub found: Vec<Option<&'s Kv<'a>>>,
    /// Entries whose key is not known, in file order.
    pub unknown: Vec<&'s Kv<'a>>,
}

impl<'s, 'a> Keys<'s, 'a> {
    /// The entry for known key number `i`.
    pub fn get(&self, i: usize) -> Option<&'s Kv<'a>> {
        self.found.get(i).copied().flatten()
    }
}

/// Matches a section's entries against `known` key names (case-insensitively), reporting case
/// and spelling differences, repeated keys and (when `report_unknown`) unknown keys.
pub(crate) fn match_keys<'s, 'a>(
    cx: &mut Ctx<'_>,
    sec: &'s Section<'a>,
    known: &[&str],
    context: Crumbs<'_>,
    report_unknown: bool,
) -> Keys<'s, 'a> {
    let mut found: Vec<Option<&'s Kv<'a>>> = vec![None; known.len()];
    let mut unknown: Vec<&'s Kv<'a>> = Vec::new();
    for kv in &sec.entries {
        let mut hit = known.iter().position(|k| k.eq_ignore_ascii_case(kv.key));
        if let Some(i) = hit {
            if known[i] != kv.key {
                let d = cx.emit(
                    codes::E0104,
                    Some(kv.key_span),
                    format!("key `{}` is written `{}` in CiA 306", kv.key, known[i]),
                );
                d.hint = Some(format!("write `{}`", known[i]));
                d.context = context.to_vec();
            }
        } else {
            hit = known.iter().position(|k| loose_eq(k, kv.key));
            if let Some(i) = hit {
                let d = cx.emit(
                    codes::E0103,
                    Some(kv.key_span),
                    format!("key `{}` is spelled `{}` in CiA 306", kv.key, known[i]),
                );
                d.hint = Some(format!("write `{}`", known[i]));
                d.context = context.to_vec();
            }
        }
        match hit {
            Some(i) => {
                if let Some(prev) = found[i] {
                    report_duplicate(cx, prev, kv, context);
                }
                found[i] = Some(kv);
            }
            None => {
                if let Some(prev) = unknown.iter().rev().find(|u| u.key.eq_ignore_ascii_case(kv.key)) {
                    report_duplicate(cx, prev, kv, context);
                }
                unknown.push(kv);
                if report_unknown {
                    let d = cx.emit(
                        codes::E0102,
                        Some(kv.key_span),
                        format!("key `{}` is not a CiA 306 key of [{}]; it is kept as written", kv.key, sec.name),
                    );
                    d.context = context.to_vec();
                }
            }
        }
    }
    Keys { found, unknown }
}

fn report_duplicate(cx: &mut Ctx<'_>, prev: &Kv<'_>, kv: &Kv<'_>, context: Crumbs<'_>) {
    // Repeats that come from a repeated section were already reported with the section.
    if prev.occurrence != kv.occurrence {
        return;
    }
    let first = cx.src.line_col(prev.key_span.start);
    let d = cx.emit(
        codes::E0007,
        Some(kv.key_span),
        format!("key `{}` is set again (first at line {}); the later value `{}` is used", kv.key, first.line, kv.value),
    );
    d.hint = Some("remove one of the two entries".to_owned());
    d.context = context.to_vec();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn section_names() {
        assert_eq!(classify("FileInfo"), (Kind::FileInfo, Spelling::Exact));
        assert_eq!(classify("fileinfo"), (Kind::FileInfo, Spelling::Case("FileInfo".into())));
        assert_eq!(
            classify("DeviceCommissioning"),
            (Kind::Commissioning, Spelling::Misspelled("DeviceComissioning".into()))
        );
        assert_eq!(
            classify("Mandatory Objects"),
            (Kind::List(Category::Mandatory), Spelling::Misspelled("MandatoryObjects".into()))
        );
        assert_eq!(classify("1018"), (Kind::Object(0x1018), Spelling::Exact));
        assert_eq!(classify("100a"), (Kind::Object(0x100A), Spelling::Case("100A".into())));
        assert_eq!(classify("1018sub2"), (Kind::Sub(0x1018, 2), Spelling::Exact));
        assert_eq!(classify("1018Sub02"), (Kind::Sub(0x1018, 2), Spelling::Case("1018sub02".into())));
        assert_eq!(classify("1600subA"), (Kind::Sub(0x1600, 10), Spelling::Exact));
        assert_eq!(classify("1016Name"), (Kind::Names(0x1016), Spelling::Exact));
        assert_eq!(classify("1016value"), (Kind::Values(0x1016), Spelling::Case("1016Value".into())));
        assert_eq!(classify("1F80ObjectLinks"), (Kind::Links(0x1F80), Spelling::Exact));
        assert!(matches!(classify("1018sub100"), (Kind::Unknown, Spelling::Malformed(_))));
        assert!(matches!(classify("1018subx"), (Kind::Unknown, Spelling::Malformed(_))));
        assert!(loose_eq("Device_Info", "deviceinfo"));
        assert!(!loose_eq("DeviceInfo", "DeviceInfos"));
        assert!(!loose_eq("", "x"));
        assert_eq!(classify("M1SubExt6000"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("Tools"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("äöü1"), (Kind::Unknown, Spelling::Exact));
    }
}
