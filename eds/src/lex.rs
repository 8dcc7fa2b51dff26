//! The lexer: decoded text → lossless [`crate::ast::Document`].
//!
//! The lexer works one physical line at a time. A line ends at `\r\n`, `\n` or a lone `\r`;
//! the last line may have no ending at all. Each line's content (without its ending) is
//! classified by its first non-blank byte:
//!
//! ```text
//! line     = blank | comment | section | entry | garbage
//! blank    = ws*                       ; also a line of Unicode white space only
//! comment  = ws* (";" | "#") any*      ; "#" is not CiA 306; lowering reports it
//! section  = ws* "[" name "]" trailing ; name has no "[" or "]"; it is trimmed; trailing is
//!                                      ; everything after "]"
//! entry    = key "=" value             ; at the first "="; key (non-empty) and value are trimmed
//! garbage  = anything else             ; kept for round trips, reported by lowering
//! ws       = " " | "\t" | "\x0B" | "\x0C"
//! ```
//!
//! "Trimmed" means Unicode white space is removed from both ends, as [`str::trim`] does.
//!
//! Positions are byte [`Span`]s into the decoded text; [`crate::source::SourceFile::line_col`]
//! turns them into lines and columns for diagnostics. The lexer never fails and never drops a
//! byte: the `raw` spans of the lines tile the text exactly, so
//! [`crate::ast::Document::write_lossless`] gives the input back.
//!
//! # Speed
//!
//! The lexer is the first thing every byte of a file goes through, so it works on bytes, not
//! `char`s: every character that decides the shape of a line (`[`, `]`, `=`, `;`, `#`, line ends,
//! ASCII blanks) is ASCII, and UTF-8 never uses ASCII bytes inside a multi-byte character.
//! Searches for line ends and for `=` look at eight bytes at a time. Trimming looks at the
//! bytes at either end and only falls back to [`str::trim`] when it meets a non-ASCII byte there
//! (which may be Unicode white space). It allocates the `Vec` of lines and nothing else.

use crate::ast::{Document, Line, LineEnding, LineKind};
use crate::source::{SourceFile, Span};

/// Lexes a decoded source file. Never fails: unrecognised lines become [`LineKind::Garbage`].
pub fn lex(source: SourceFile) -> Document {
    let mut starts = Vec::with_capacity(source.text.len() / 12 + 2);
    let lines = lex_into(&source.text, &mut starts);
    // The lexer found every `\n`: give the source its line index instead of letting it search.
    source.set_line_starts(starts);
    Document { source, lines }
}

/// Lexes text into lines (the work behind [`lex`]).
pub fn lex_lines(text: &str) -> Vec<Line> {
    lex_into(text, &mut Vec::with_capacity(text.len() / 12 + 2))
}

/// Lexes `text`, and puts the offset of every line start that follows a `\n` (with 0 first)
/// into `line_starts`.
fn lex_into(text: &str, line_starts: &mut Vec<u32>) -> Vec<Line> {
    let b = text.as_bytes();
    let n = b.len();
    // Typical EDS lines are 12-25 bytes long; a few more or less costs little either way.
    let mut lines = Vec::with_capacity(n / 10 + 16);
    line_starts.push(0);
    let mut start = 0usize;
    while start < n {
        // Each line is scanned once: up to its first non-blank byte, which decides what to look
        // for next; an entry line up to its `=` and then to its end.
        let mut first = start;
        while first < n && is_blank(b[first]) {
            first += 1;
        }
        let (content_end, kind) = match b.get(first) {
            None | Some(b'\n' | b'\r') => (first, LineKind::Blank),
            Some(b';' | b'#') => {
                let end = find_eol(b, first + 1).unwrap_or(n);
                (end, LineKind::Comment { text: Span::new(first as u32 + 1, end as u32) })
            }
            Some(b'[') => {
                let end = find_eol(b, first + 1).unwrap_or(n);
                (end, section(text, first + 1, end))
            }
            Some(_) => match find_eq_or_eol(b, first) {
                Some(eq) if b[eq] == b'=' => {
                    let end = find_eol(b, eq + 1).unwrap_or(n);
                    // The blanks before `first` would be trimmed anyway.
                    let key = trim_span(text, first, eq);
                    let kind = if key.is_empty() {
                        LineKind::Garbage
                    } else {
                        LineKind::Entry { key, value: trim_span(text, eq + 1, end) }
                    };
                    (end, kind)
                }
                eol => {
                    let end = eol.unwrap_or(n);
                    // Only Unicode white space (e.g. a no-break space) is a blank line too.
                    let kind = if text[first..end].trim().is_empty() { LineKind::Blank } else { LineKind::Garbage };
                    (end, kind)
                }
            },
        };
        let (ending, next) = match b.get(content_end) {
            None => (LineEnding::None, n),
            Some(b'\n') => (LineEnding::Lf, content_end + 1),
            Some(_) if b.get(content_end + 1) == Some(&b'\n') => (LineEnding::CrLf, content_end + 2),
            Some(_) => (LineEnding::Cr, content_end + 1),
        };
        if matches!(ending, LineEnding::Lf | LineEnding::CrLf) {
            line_starts.push(next as u32);
        }
        lines.push(Line {
            raw: Span::new(start as u32, next as u32),
            content: Span::new(start as u32, content_end as u32),
            ending,
            kind,
        });
        start = next;
    }
    lines
}

const LO: u64 = 0x0101_0101_0101_0101;
const HI: u64 = 0x8080_8080_8080_8080;
const NL: u64 = LO * b'\n' as u64;
const CR: u64 = LO * b'\r' as u64;
const EQ: u64 = LO * b'=' as u64;

/// Flags (with its high bit) each byte of `w` that equals the byte repeated in `pattern`. The
/// lowest flag is always a real match: a false flag can only come from a borrow out of a real
/// match below it. Callers use the lowest flag only.
#[inline(always)]
fn eq_bytes(w: u64, pattern: u64) -> u64 {
    let x = w ^ pattern;
    x.wrapping_sub(LO) & !x & HI
}

#[inline(always)]
fn word(b: &[u8], i: usize) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(w)
}

/// Offset of the first `\n` or `\r` in `b` at or after `from`, eight bytes at a time (SWAR).
#[inline]
fn find_eol(b: &[u8], from: usize) -> Option<usize> {
    let mut i = from;
    while i + 8 <= b.len() {
        let w = word(b, i);
        let z = eq_bytes(w, NL) | eq_bytes(w, CR);
        if z != 0 {
            return Some(i + (z.trailing_zeros() / 8) as usize);
        }
        i += 8;
    }
    b.get(i..)?.iter().position(|&c| c == b'\n' || c == b'\r').map(|p| i + p)
}

/// Offset of the first `=`, `\n` or `\r` in `b` at or after `from`, eight bytes at a time.
#[inline]
fn find_eq_or_eol(b: &[u8], from: usize) -> Option<usize> {
    let mut i = from;
    while i + 8 <= b.len() {
        let w = word(b, i);
        let z = eq_bytes(w, EQ) | eq_bytes(w, NL) | eq_bytes(w, CR);
        if z != 0 {
            return Some(i + (z.trailing_zeros() / 8) as usize);
        }
        i += 8;
    }
    b.get(i..)?.iter().position(|&c| c == b'=' || c == b'\n' || c == b'\r').map(|p| i + p)
}

/// The blanks that may come before a comment or section header.
#[inline]
fn is_blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | 0x0B | 0x0C)
}

/// `s.trim()`, deciding quickly when neither end can be white space: every white space
/// character is either ASCII at or below `' '` or not ASCII at all.
#[inline]
pub(crate) fn trim(s: &str) -> &str {
    match (s.as_bytes().first(), s.as_bytes().last()) {
        (Some(0x21..=0x7E), Some(0x21..=0x7E)) => s,
        _ => s.trim(),
    }
}

/// `s.trim_start()`, deciding quickly as [`trim`] does.
#[inline]
pub(crate) fn trim_start(s: &str) -> &str {
    match s.as_bytes().first() {
        Some(0x21..=0x7E) => s,
        _ => s.trim_start(),
    }
}

/// `text[start..end]` trimmed as [`str::trim`] trims it, as a span (`start` and `end` are char
/// boundaries).
#[inline(always)]
fn trim_span(text: &str, start: usize, end: usize) -> Span {
    let b = text.as_bytes();
    // Most keys and values have nothing to trim.
    if start < end && matches!(b[start], 0x21..=0x7E) && matches!(b[end - 1], 0x21..=0x7E) {
        return Span::new(start as u32, end as u32);
    }
    let s = &text[start..end];
    let t = s.trim();
    // `trim` gives the empty string at the start for white space only.
    let off = start + (t.as_ptr() as usize - s.as_ptr() as usize);
    Span::new(off as u32, (off + t.len()) as u32)
}

/// A `[` line whose name starts at `name_start` and whose content ends at `end`: a section if
/// a `]` closes the name before any other `[`.
fn section(text: &str, name_start: usize, end: usize) -> LineKind {
    let b = text.as_bytes();
    match b[name_start..end].iter().position(|&c| c == b']' || c == b'[').map(|p| name_start + p) {
        Some(c) if b[c] == b']' => {
            LineKind::Section { name: trim_span(text, name_start, c), trailing: Span::new(c as u32 + 1, end as u32) }
        }
        _ => LineKind::Garbage,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn kinds(text: &str) -> Vec<(LineKind, LineEnding)> {
        lex_lines(text).into_iter().map(|l| (l.kind, l.ending)).collect()
    }

    /// The grammar in the module docs, written the obvious way with `str` methods: the lexer
    /// must agree with it on every input.
    fn classify_reference(content: &str, base: u32) -> LineKind {
        let span_of = |s: &str| {
            let off = s.as_ptr() as usize - content.as_ptr() as usize;
            Span::new(base + off as u32, base + (off + s.len()) as u32)
        };
        let body = content.trim_start_matches([' ', '\t', '\u{0B}', '\u{0C}']);
        if body.is_empty() {
            return LineKind::Blank;
        }
        if let Some(text) = body.strip_prefix([';', '#']) {
            return LineKind::Comment { text: span_of(text) };
        }
        if let Some(rest) = body.strip_prefix('[') {
            return match rest.find([']', '[']) {
                Some(i) if rest[i..].starts_with(']') => {
                    LineKind::Section { name: span_of(rest[..i].trim()), trailing: span_of(&rest[i + 1..]) }
                }
                _ => LineKind::Garbage,
            };
        }
        match content.split_once('=') {
            Some((key, value)) if !key.trim().is_empty() => {
                LineKind::Entry { key: span_of(key.trim()), value: span_of(value.trim()) }
            }
            Some(_) => LineKind::Garbage,
            None if content.trim().is_empty() => LineKind::Blank,
            None => LineKind::Garbage,
        }
    }

    fn check_against_reference(text: &str) {
        let lines = lex_lines(text);
        let mut joined = String::new();
        for l in &lines {
            joined.push_str(&text[l.raw.start as usize..l.raw.end as usize]);
            let content = &text[l.content.start as usize..l.content.end as usize];
            assert!(!content.contains(['\n', '\r']), "{content:?}");
            assert_eq!(l.kind, classify_reference(content, l.content.start), "line {content:?}");
        }
        assert_eq!(joined, text);
    }

    #[test]
    fn line_endings() {
        let text = "a=1\r\nb=2\rc=3\nd=4";
        let lines = lex_lines(text);
        let endings: Vec<_> = lines.iter().map(|l| l.ending).collect();
        assert_eq!(endings, [LineEnding::CrLf, LineEnding::Cr, LineEnding::Lf, LineEnding::None]);
        let joined: String = lines.iter().map(|l| &text[l.raw.start as usize..l.raw.end as usize]).collect();
        assert_eq!(joined, text);
    }

    #[test]
    fn line_kinds() {
        let text = " [ 1018sub1 ] ; x\n Key = some value ; not a comment \n; c\n\n  \njunk\n=v\n# hash\n[broken\n";
        let lines = lex_lines(text);
        let s = |sp: Span| &text[sp.start as usize..sp.end as usize];
        match lines[0].kind {
            LineKind::Section { name, trailing } => {
                assert_eq!(s(name), "1018sub1");
                assert_eq!(s(trailing), " ; x");
            }
            ref k => panic!("{k:?}"),
        }
        match lines[1].kind {
            LineKind::Entry { key, value } => {
                assert_eq!(s(key), "Key");
                assert_eq!(s(value), "some value ; not a comment");
            }
            ref k => panic!("{k:?}"),
        }
        assert!(matches!(lines[2].kind, LineKind::Comment { text } if s(text) == " c"));
        assert_eq!(lines[3].kind, LineKind::Blank);
        assert_eq!(lines[4].kind, LineKind::Blank);
        assert_eq!(lines[5].kind, LineKind::Garbage);
        assert_eq!(lines[6].kind, LineKind::Garbage);
        assert!(matches!(lines[7].kind, LineKind::Comment { .. }));
        assert_eq!(lines[8].kind, LineKind::Garbage);
        assert_eq!(lines.len(), 9);
        check_against_reference(text);
    }

    #[test]
    fn unicode_white_space_is_trimmed_like_str_trim() {
        for text in [
            "\u{A0}Key\u{A0}=\u{2003}value\u{3000}",
            "Key\x0B=\x0Bvalue\x0B",
            "[\u{A0}1018\u{85}]",
            "[ \u{A0} ]",
            "[   ]",
            "\u{A0}\u{A0}",
            "K=\u{A0}",
            "K=  ",
            "\u{A0}=v",
            "Kä=ö",
            "Keyé =  é",
        ] {
            check_against_reference(text);
        }
        let lines = lex_lines("K=\u{A0}x\u{A0}\n[ \u{A0} ]");
        assert!(matches!(lines[0].kind, LineKind::Entry { value, .. } if value == Span::new(4, 5)));
        // A name of white space only is the empty string at its start, as `str::trim` gives it.
        assert!(matches!(lines[1].kind, LineKind::Section { name, .. } if name == Span::new(9, 9)));
    }

    #[test]
    fn eol_search_matches_naive() {
        let text = "0123456789abcdef\r0123\n".repeat(3);
        let b = text.as_bytes();
        for s in 0..b.len() {
            let naive = b[s..].iter().position(|&c| c == b'\n' || c == b'\r').map(|p| s + p);
            assert_eq!(find_eol(b, s), naive);
        }
        // Bytes just above and below the line-end characters must not match.
        assert_eq!(find_eol(&[0x0B, 0x0C, 0x0E, 0x09, 0x8A, 0x8D, 0xFF, 0x00, b'\r'], 0), Some(8));
        // A borrow out of a real match does not hide it (0x0A followed by 0x0B).
        assert_eq!(find_eol(&[1, 1, b'\n', 0x0B, 1, 1, 1, 1], 0), Some(2));
    }

    #[test]
    fn eq_search_matches_naive() {
        let text = "Key=Value;a=b;0123456789ABCDEF<>===\r\nx\ny".as_bytes();
        for from in 0..=text.len() {
            let naive = text[from..].iter().position(|&c| matches!(c, b'=' | b'\n' | b'\r')).map(|p| from + p);
            assert_eq!(find_eq_or_eol(text, from), naive, "{from}");
        }
        assert_eq!(find_eq_or_eol(&[b'<', b'>', 0x3C, 0x3E, 0xBD, 0x0B, 0x0E, b'=', 0, 0], 0), Some(7));
        assert_eq!(find_eol(b"abc", 4), None);
    }

    #[test]
    fn empty_input() {
        assert!(kinds("").is_empty());
        assert_eq!(kinds("\n"), vec![(LineKind::Blank, LineEnding::Lf)]);
    }

    proptest! {
        #[test]
        fn agrees_with_the_reference_grammar(text in "([ \t\x0B\x0C\u{A0}\u{85}\u{3000}]|\\PC|\r|\n|\\[|\\]|=|;|#|[a-z]){0,200}") {
            check_against_reference(&text);
        }

        #[test]
        fn agrees_with_the_reference_on_eds_like_lines(
            lines in proptest::collection::vec("[ \t\u{A0}]{0,2}(\\[[0-9A-Fa-fsub ]{0,10}\\]|[A-Za-z]{1,14}[ \t]?=[ \t]?[0-9a-zA-Z$+ ;#]{0,12}|;.{0,5}|#.{0,3})[ \t\u{A0}]{0,2}", 0..40),
            ending in "\r\n|\n|\r",
        ) {
            check_against_reference(&lines.join(&ending));
        }
    }
}
