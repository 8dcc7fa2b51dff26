//! The nom lexer: decoded text → lossless [`crate::ast::Document`].
//!
//! The lexer works one physical line at a time. A line ends at `\r\n`, `\n` or a lone `\r`;
//! the last line may have no ending at all. Finding line ends is most of the work, so it scans
//! eight bytes at a time. Each line's content (without its ending) is then classified by its
//! first non-blank byte and a small nom grammar:
//!
//! ```text
//! line     = blank | comment | section | entry | garbage
//! blank    = ws*
//! comment  = ws* (";" | "#") any*          ; "#" is not CiA 306; lowering reports it
//! section  = ws* "[" name "]" trailing     ; name is trimmed, trailing is everything after "]"
//! entry    = key "=" value                 ; key (non-empty) and value are trimmed
//! garbage  = anything else                 ; kept for round trips, reported by lowering
//! ```
//!
//! Positions are byte [`Span`]s into the decoded text; [`crate::source::SourceFile::line_col`]
//! turns them into lines and columns for diagnostics. The lexer never fails and never drops a
//! byte: the `raw` spans of the lines tile the text exactly, so
//! [`crate::ast::Document::write_lossless`] gives the input back. It allocates the `Vec` of
//! lines and nothing else.

use nom::{
    IResult, Parser,
    bytes::complete::{take_till, take_while},
    character::complete::{char, one_of},
    combinator::rest,
    sequence::{delimited, preceded},
};

use crate::ast::{Document, Line, LineEnding, LineKind};
use crate::source::{SourceFile, Span};

/// Lexes a decoded source file. Never fails: unrecognised lines become [`LineKind::Garbage`].
pub fn lex(source: SourceFile) -> Document {
    let lines = lex_lines(&source.text);
    Document { source, lines }
}

/// Lexes text into lines (the work behind [`lex`]).
pub fn lex_lines(text: &str) -> Vec<Line> {
    let bytes = text.as_bytes();
    // Typical EDS lines are 15-25 bytes long.
    let mut lines = Vec::with_capacity(bytes.len() / 20 + 1);
    let mut start = 0usize;
    while start < bytes.len() {
        let (content_end, ending, next) = match find_eol(&bytes[start..]) {
            Some(off) => {
                let i = start + off;
                if bytes[i] == b'\n' {
                    (i, LineEnding::Lf, i + 1)
                } else if bytes.get(i + 1) == Some(&b'\n') {
                    (i, LineEnding::CrLf, i + 2)
                } else {
                    (i, LineEnding::Cr, i + 1)
                }
            }
            None => (bytes.len(), LineEnding::None, bytes.len()),
        };
        // Line ends are ASCII, so these offsets are char boundaries.
        let content = &text[start..content_end];
        let kind = classify(content, start as u32);
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

/// Offset of the first `\n` or `\r` in `b`. Scans eight bytes at a time (SWAR), because this
/// search is most of the lexer's work.
#[inline]
fn find_eol(b: &[u8]) -> Option<usize> {
    const LO: u64 = 0x0101_0101_0101_0101;
    const HI: u64 = 0x8080_8080_8080_8080;
    const NL: u64 = LO * b'\n' as u64;
    const CR: u64 = LO * b'\r' as u64;
    let mut i = 0;
    while i + 8 <= b.len() {
        let mut w = [0u8; 8];
        w.copy_from_slice(&b[i..i + 8]);
        let w = u64::from_le_bytes(w);
        let x = w ^ NL;
        let y = w ^ CR;
        // A byte of x or y is zero where w had '\n' or '\r'.
        let zx = x.wrapping_sub(LO) & !x & HI;
        let zy = y.wrapping_sub(LO) & !y & HI;
        let z = zx | zy;
        if z != 0 {
            return Some(i + (z.trailing_zeros() / 8) as usize);
        }
        i += 8;
    }
    b[i..].iter().position(|&c| c == b'\n' || c == b'\r').map(|p| i + p)
}

fn is_ws(c: char) -> bool {
    c == ' ' || c == '\t' || c == '\u{0B}' || c == '\u{0C}'
}

/// Classifies the content of one line. `base` is the content's offset in the file.
fn classify(content: &str, base: u32) -> LineKind {
    let span_of = |s: &str| {
        let off = s.as_ptr() as usize - content.as_ptr() as usize;
        Span::new(base + off as u32, base + (off + s.len()) as u32)
    };
    // Dispatch on the first non-blank byte, then let the matching nom parser do the work.
    match content.bytes().find(|&b| !matches!(b, b' ' | b'\t' | 0x0B | 0x0C)) {
        None => return LineKind::Blank,
        Some(b';' | b'#') => {
            if let Ok((_, text)) = comment(content) {
                return LineKind::Comment { text: span_of(text) };
            }
        }
        Some(b'[') => {
            if let Ok((trailing, name)) = section(content) {
                return LineKind::Section { name: span_of(name.trim()), trailing: span_of(trailing) };
            }
        }
        Some(_) => {
            if let Ok((value, key)) = entry(content) {
                let key = key.trim();
                if !key.is_empty() {
                    return LineKind::Entry { key: span_of(key), value: span_of(value.trim()) };
                }
            } else if content.trim().is_empty() {
                // Only Unicode white space (e.g. a no-break space).
                return LineKind::Blank;
            }
        }
    }
    LineKind::Garbage
}

fn comment(i: &str) -> IResult<&str, &str> {
    preceded((take_while(is_ws), one_of(";#")), rest).parse(i)
}

fn section(i: &str) -> IResult<&str, &str> {
    preceded(take_while(is_ws), delimited(char('['), take_till(|c| c == ']' || c == '['), char(']'))).parse(i)
}

fn entry(i: &str) -> IResult<&str, &str> {
    let (i, key) = take_till(|c| c == '=')(i)?;
    let (i, _) = char('=')(i)?;
    Ok((i, key))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(text: &str) -> Vec<(LineKind, LineEnding)> {
        lex_lines(text).into_iter().map(|l| (l.kind, l.ending)).collect()
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
    }

    #[test]
    fn eol_search_matches_naive() {
        let text = "0123456789abcdef\r0123\n".repeat(3);
        let b = text.as_bytes();
        for s in 0..b.len() {
            let naive = b[s..].iter().position(|&c| c == b'\n' || c == b'\r');
            assert_eq!(find_eol(&b[s..]), naive);
        }
        // Bytes just above and below the line-end characters must not match.
        assert_eq!(find_eol(&[0x0B, 0x0C, 0x0E, 0x09, 0x8A, 0x8D, 0xFF, 0x00, b'\r']), Some(8));
    }

    #[test]
    fn empty_input() {
        assert!(kinds("").is_empty());
        assert_eq!(kinds("\n"), vec![(LineKind::Blank, LineEnding::Lf)]);
    }
}
