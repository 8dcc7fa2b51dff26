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
//! The grammar is written with nom combinators over bytes, not `char`s: every character that
//! decides the shape of a line (`[`, `]`, `=`, `;`, `#`, line ends, ASCII blanks) is ASCII, and
//! UTF-8 never uses ASCII bytes inside a multi-byte character, so byte positions are always
//! char boundaries where the grammar cuts. Trimming looks at the bytes at either end and only
//! falls back to [`str::trim`] when it meets a non-ASCII byte there (which may be Unicode white
//! space). It allocates the `Vec` of lines and nothing else.

use nom::branch::alt;
use nom::bytes::complete::{tag, take_till, take_while};
use nom::character::complete::one_of;
use nom::combinator::{eof, value};
use nom::{IResult, Parser};

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
    let base = text.as_bytes();
    // Typical EDS lines are 12-25 bytes long; a few more or less costs little either way.
    let mut lines = Vec::with_capacity(base.len() / 10 + 16);
    line_starts.push(0);
    let mut input = base;
    while !input.is_empty() {
        let start = offset(base, input);
        // `physical_line` cannot fail on non-empty input: every part of it accepts nothing.
        let Ok((rest, (content, ending))) = physical_line(input) else { break };
        let content_start = offset(base, content);
        let content_end = content_start + content.len();
        let next = offset(base, rest);
        if matches!(ending, LineEnding::Lf | LineEnding::CrLf) {
            line_starts.push(next as u32);
        }
        lines.push(Line {
            raw: Span::new(start as u32, next as u32),
            content: Span::new(content_start as u32, content_end as u32),
            ending,
            kind: classify(text, content_start, content_end),
        });
        input = rest;
    }
    lines
}

type In<'a> = &'a [u8];

/// Byte offset of `part` (a sub-slice of `base`) in `base`.
#[inline(always)]
fn offset(base: In<'_>, part: In<'_>) -> usize {
    part.as_ptr() as usize - base.as_ptr() as usize
}

fn is_eol(c: u8) -> bool {
    c == b'\n' || c == b'\r'
}

/// One physical line: its content (up to, not including, the line end) and how it ends.
fn physical_line(input: In<'_>) -> IResult<In<'_>, (In<'_>, LineEnding)> {
    (take_till(is_eol), line_ending).parse(input)
}

/// `\r\n`, `\n`, a lone `\r`, or the end of the file.
fn line_ending(input: In<'_>) -> IResult<In<'_>, LineEnding> {
    alt((
        value(LineEnding::CrLf, tag(&b"\r\n"[..])),
        value(LineEnding::Lf, tag(&b"\n"[..])),
        value(LineEnding::Cr, tag(&b"\r"[..])),
        value(LineEnding::None, eof),
    ))
    .parse(input)
}

/// The grammar of one line's content (`text[start..end]`, without its line end).
fn classify(text: &str, start: usize, end: usize) -> LineKind {
    let base = text.as_bytes();
    let content = &base[start..end];
    // Blanks before the first byte that decides the line's shape.
    let Ok((body, _)) = take_while::<_, _, nom::error::Error<In<'_>>>(is_blank).parse(content) else {
        return LineKind::Garbage;
    };
    if body.is_empty() {
        return LineKind::Blank;
    }
    if let Ok((text_part, _)) = one_of::<_, _, nom::error::Error<In<'_>>>(";#").parse(body) {
        let at = offset(base, text_part) as u32;
        return LineKind::Comment { text: Span::new(at, end as u32) };
    }
    if body[0] == b'[' {
        return section(text, base, body, end);
    }
    entry_or_other(text, base, content, end)
}

/// `"[" name "]" trailing`: a section if a `]` closes the name before any other `[`.
fn section(text: &str, base: In<'_>, body: In<'_>, end: usize) -> LineKind {
    let parsed: IResult<In<'_>, (In<'_>, In<'_>, In<'_>)> =
        (tag(&b"["[..]), take_till(|c| c == b']' || c == b'['), tag(&b"]"[..])).parse(body);
    match parsed {
        Ok((trailing, (_, name, _))) => {
            let name_start = offset(base, name);
            LineKind::Section {
                name: trim_span(text, name_start, name_start + name.len()),
                trailing: Span::new(offset(base, trailing) as u32, end as u32),
            }
        }
        Err(_) => LineKind::Garbage,
    }
}

/// `key "=" value` at the first `=`; a line without one is blank if it holds only Unicode
/// white space (e.g. a no-break space), garbage otherwise.
fn entry_or_other(text: &str, base: In<'_>, content: In<'_>, end: usize) -> LineKind {
    let parsed: IResult<In<'_>, (In<'_>, In<'_>)> = (take_till(|c| c == b'='), tag(&b"="[..])).parse(content);
    match parsed {
        Ok((value, (key, _))) => {
            let key_start = offset(base, key);
            let key = trim_span(text, key_start, key_start + key.len());
            if key.is_empty() {
                LineKind::Garbage
            } else {
                LineKind::Entry { key, value: trim_span(text, offset(base, value), end) }
            }
        }
        Err(_) => {
            let start = offset(base, content);
            if text[start..end].trim().is_empty() { LineKind::Blank } else { LineKind::Garbage }
        }
    }
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
