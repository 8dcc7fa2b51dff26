//! Diagnostics: one type for every problem found in a file, rendered like rustc or as JSON.
//!
//! Each diagnostic has a stable [`Code`], a severity for lenient mode, and a flag saying whether
//! it is a CiA 306 deviation (strict mode turns deviations into errors).

use std::borrow::Cow;
use std::sync::Arc;

use serde::Serialize;

pub use crate::codes::{Code, Severity};
use crate::source::{LineCol, Span};

/// One problem in one file.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnostic {
    /// Severity after applying the strictness level.
    pub severity: Severity,
    /// Stable code.
    pub code: Code,
    /// What is wrong, in one sentence.
    pub message: String,
    /// File name as given by the user, shared by all the diagnostics of one file (a reader
    /// finding thousands of problems stores the name once).
    #[serde(serialize_with = "serialize_str")]
    pub file: Arc<str>,
    /// Where (`None` for whole-file problems such as a missing section).
    pub span: Option<Span>,
    /// Line and column of `span.start`.
    pub at: Option<LineCol>,
    /// Where in the dictionary, innermost last: `object 0x1018 "Identity Object"`, `sub 2
    /// "Product Code"`.
    pub context: Vec<String>,
    /// How to fix it, where known: most hints are fixed text, which a `Cow::Borrowed` holds
    /// without copying; `Some(text.into())` sets one from a `&'static str` or a `String`.
    pub hint: Option<Cow<'static, str>>,
}

/// Serialises a shared string as a plain string (serde's `Arc` support needs its `rc` feature).
fn serialize_str<S: serde::Serializer>(s: &Arc<str>, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(s)
}

impl Diagnostic {
    /// A diagnostic for `code` with its severity at `strictness` (see [`crate::codes`]).
    pub fn new(code: Code, strictness: crate::Strictness, file: &str, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: crate::codes::severity(code, strictness),
            code,
            message: message.into(),
            file: file.into(),
            span: None,
            at: None,
            context: Vec::new(),
            hint: None,
        }
    }

    /// Whether the code is a CiA 306 deviation (an error in strict mode).
    pub fn is_deviation(&self) -> bool {
        crate::codes::info(self.code).is_some_and(|i| i.deviation)
    }
}

/// Renders one diagnostic the way rustc does:
///
/// ```text
/// error[E0301]: DefaultValue `0x1G` cannot be read as UNSIGNED32: `0x1G` is not a number
///   --> device.eds:12:14
///    |
/// 12 | DefaultValue=0x1G
///    |              ^^^^
///    = note: in object 0x1018 "Identity Object", sub 2 "Product Code"
///    = help: write a decimal number or a 0x-prefixed hexadecimal number
/// ```
///
/// `source` supplies the quoted line; a diagnostic without a span shows only its file name.
pub fn render(d: &Diagnostic, source: &crate::source::SourceFile) -> String {
    let mut out = String::new();
    render_to(&mut out, d, source);
    out
}

/// [`render`], appended to `out` (a caller rendering many diagnostics reuses one buffer).
pub fn render_to(out: &mut String, d: &Diagnostic, source: &crate::source::SourceFile) {
    // Written piece by piece into `out`, without a `format!` or temporary string per line: a
    // folder's check renders thousands of these, and the allocations and formatting machinery
    // were most of the cost of rendering one. Each line's lead (the gutter's spaces and what
    // follows them) is one slice of a padded constant, and a number is one slice of digits:
    // every push costs a capacity check and a copy, whatever its length.
    // (Each push of a text of a length known here is a few moves, not a call to `memcpy`:
    // hence a push in each arm, and codes, all five bytes long, pushed as five bytes.)
    match d.severity {
        Severity::Note => out.push_str("note["),
        Severity::Warning => out.push_str("warning["),
        Severity::Error => out.push_str("error["),
    }
    match d.code.0.get(..5) {
        Some(code) if d.code.0.len() == 5 => out.push_str(code),
        _ => out.push_str(d.code.0),
    }
    out.push_str("]: ");
    out.push_str(&d.message);
    out.push('\n');
    let at = d.span.map(|s| (s, d.at.unwrap_or_else(|| source.line_col(s.start))));
    let gutter = at.map(|(_, lc)| lc.line.checked_ilog10().unwrap_or(0) as usize + 1).unwrap_or(1);
    match at {
        Some((span, lc)) => {
            push_lead(out, gutter, ARROW);
            out.push_str(&d.file);
            out.push(':');
            push_u32(out, lc.line);
            out.push(':');
            push_u32(out, lc.col);
            out.push('\n');
            let line = source.line_text(lc.line);
            let ascii = line.is_ascii();
            let line_chars = if ascii { line.len() as u32 } else { line.chars().count() as u32 };
            let start_col = lc.col.saturating_sub(1).min(line_chars);
            let span_text = source.slice(span);
            // (The span's first line: up to its first line end.)
            let first = &span_text[..crate::lex::prefix_without(span_text.as_bytes(), [b'\n', b'\r'])];
            let span_chars = if first.is_ascii() { first.len() as u32 } else { first.chars().count() as u32 };
            let width = span_chars.min(line_chars.saturating_sub(start_col)).max(1);
            // A long line is cut to a window around the span's start, marked with `…`.
            let (from, to) = quote_window(line_chars, start_col);
            push_lead(out, gutter, BAR);
            push_u32(out, lc.line);
            out.push_str(" | ");
            if from > 0 {
                out.push('…');
            }
            // (A tab is quoted as one space, so that the carets line up; an uncut line is
            // quoted without its trailing white space, which tabs are too.)
            let untab = |c: char| if c == '\t' { ' ' } else { c };
            match line.get(from as usize..to as usize) {
                // An ASCII line (most are): its characters are its bytes, pushed as a slice.
                Some(part) if ascii => {
                    let part = if to < line_chars { part } else { part.trim_end() };
                    if crate::lex::prefix_without(part.as_bytes(), [b'\t']) < part.len() {
                        out.extend(part.chars().map(untab));
                    } else {
                        out.push_str(part);
                    }
                }
                _ => {
                    let quoted_at = out.len();
                    out.extend(line.chars().skip(from as usize).take((to - from) as usize).map(untab));
                    if to >= line_chars {
                        let kept = out[quoted_at..].trim_end().len();
                        out.truncate(quoted_at + kept);
                    }
                }
            }
            if to < line_chars {
                out.push_str("…\n");
            } else {
                out.push('\n');
            }
            // Underline the part of the span that lies on this line and in the window (at
            // least one caret).
            let lead = start_col - from + u32::from(from > 0);
            let width = width.min(to.saturating_sub(start_col)).max(1);
            push_lead(out, gutter, BAR_OPEN);
            push_n(out, SPACES, lead as usize);
            push_n(out, CARETS, width as usize);
            out.push('\n');
        }
        None => {
            push_lead(out, gutter, ARROW);
            out.push_str(&d.file);
            out.push('\n');
        }
    }
    if !d.context.is_empty() {
        push_lead(out, gutter, NOTE_IN);
        for (i, c) in d.context.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            out.push_str(c);
        }
        out.push('\n');
    }
    if let Some(h) = &d.hint {
        push_lead(out, gutter, HELP);
        out.push_str(h);
        out.push('\n');
    }
}

/// Runs of spaces and carets, pushed as slices of these rather than a character at a time.
const SPACES: &str = "                                ";
const CARETS: &str = "^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^^";

/// The leads of a rendered diagnostic's lines after the gutter, each after [`LEAD_ROOM`] spaces
/// (see [`push_lead`]).
const LEAD_ROOM: usize = 16;
const ARROW: &str = "                --> ";
const BAR: &str = "                 |\n";
const BAR_OPEN: &str = "                 | ";
const NOTE_IN: &str = "                 = note: in ";
const HELP: &str = "                 = help: ";

/// `gutter` spaces and then `lead` (one of the padded leads, [`ARROW`] and the others).
/// Inlined, with a case for each gutter of up to five digits, so that each push is of a length
/// known where it is made (a few moves, not a call to `memcpy`).
#[inline(always)]
fn push_lead(out: &mut String, gutter: usize, lead: &str) {
    let at = |g: usize| lead.get(LEAD_ROOM - g..);
    let part = match gutter {
        1 => at(1),
        2 => at(2),
        3 => at(3),
        4 => at(4),
        5 => at(5),
        _ => None,
    };
    match part {
        Some(part) => out.push_str(part),
        None => push_lead_any(out, gutter, lead),
    }
}

/// [`push_lead`] for any gutter.
#[inline(never)]
fn push_lead_any(out: &mut String, gutter: usize, lead: &str) {
    match lead.get(LEAD_ROOM.saturating_sub(gutter)..) {
        Some(part) if gutter <= LEAD_ROOM => out.push_str(part),
        _ => {
            push_n(out, SPACES, gutter);
            out.push_str(&lead[LEAD_ROOM..]);
        }
    }
}

/// `n` times the character `run` (one of [`SPACES`], [`CARETS`]) is made of.
fn push_n(out: &mut String, run: &str, n: usize) {
    let mut left = n;
    while left > 0 {
        let k = left.min(run.len());
        out.push_str(&run[..k]);
        left -= k;
    }
}

/// Appends the decimal digits of `n`, from the highest power of ten down: each digit is known
/// to be below ten where it is pushed, so it is stored as one byte with no check of its width
/// (digits written into a buffer and pushed from it were a `from_utf8` check and a copy each).
fn push_u32(out: &mut String, n: u32) {
    let mut p = 1u32;
    while p <= n / 10 {
        p *= 10;
    }
    loop {
        out.push(char::from(b'0' + (n / p % 10) as u8));
        if p == 1 {
            break;
        }
        p /= 10;
    }
}

/// The longest text from the file a diagnostic's message or context quotes, in characters.
pub const MAX_QUOTED_TEXT: usize = 80;

/// `text` when it is at most [`MAX_QUOTED_TEXT`] characters long, otherwise its first
/// [`MAX_QUOTED_TEXT`] characters and `…`: what a message or breadcrumb quotes of a file's text
/// (a value or name may be megabytes long; its diagnostics stay a few lines).
pub fn shorten(text: &str) -> Cow<'_, str> {
    if text.len() <= MAX_QUOTED_TEXT {
        return Cow::Borrowed(text);
    }
    match text.char_indices().nth(MAX_QUOTED_TEXT) {
        None => Cow::Borrowed(text),
        Some((cut, _)) => Cow::Owned(format!("{}…", &text[..cut])),
    }
}

/// A message with every backtick-quoted part longer than [`MAX_QUOTED_TEXT`] characters cut
/// with `…` (see [`shorten`]); short messages are returned as they are.
pub fn shorten_message(message: String) -> String {
    if message.len() <= 2 * MAX_QUOTED_TEXT {
        return message;
    }
    let mut out = String::with_capacity(4 * MAX_QUOTED_TEXT);
    for (i, part) in message.split('`').enumerate() {
        if i > 0 {
            out.push('`');
        }
        // Odd parts are inside backticks; an unquoted part longer than a page is cut too.
        if i % 2 == 1 || part.len() > 8 * MAX_QUOTED_TEXT { out.push_str(&shorten(part)) } else { out.push_str(part) }
    }
    out
}

/// The longest part of a source line a rendered diagnostic quotes, in characters.
pub const MAX_QUOTED: u32 = 200;

/// Which characters `from..to` of a line of `len` characters are quoted for a span starting at
/// character `col`: the whole line when it is at most [`MAX_QUOTED`] long, otherwise
/// [`MAX_QUOTED`] characters from the line start, or from a little before `col` when `col` lies
/// further in.
fn quote_window(len: u32, col: u32) -> (u32, u32) {
    if len <= MAX_QUOTED {
        return (0, len);
    }
    let from = if col < MAX_QUOTED - 40 { 0 } else { (col - 40).min(len - MAX_QUOTED) };
    (from, from + MAX_QUOTED)
}

/// Renders every diagnostic (in the order given, one blank line between them) followed by a
/// summary line such as `2 errors, 1 warning, 3 notes`.
pub fn render_all(diagnostics: &[Diagnostic], source: &crate::source::SourceFile) -> String {
    let mut out = String::new();
    for d in diagnostics {
        out.push_str(&render(d, source));
        out.push('\n');
    }
    out.push_str(&summary(diagnostics));
    out.push('\n');
    out
}

/// `2 errors, 1 warning, 3 notes` (`no problems` when empty).
pub fn summary(diagnostics: &[Diagnostic]) -> String {
    let count = |s: Severity| diagnostics.iter().filter(|d| d.severity == s).count();
    let part = |n: usize, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
    let (e, w, n) = (count(Severity::Error), count(Severity::Warning), count(Severity::Note));
    if e + w + n == 0 {
        return "no problems".to_owned();
    }
    let mut parts = Vec::new();
    if e > 0 {
        parts.push(part(e, "error"));
    }
    if w > 0 {
        parts.push(part(w, "warning"));
    }
    if n > 0 {
        parts.push(part(n, "note"));
    }
    parts.join(", ")
}

/// Appends `text` to `out` as a JSON string (quoted and escaped).
pub fn push_json_str(out: &mut String, text: &str) {
    out.push('"');
    let bytes = text.as_bytes();
    let mut from = 0;
    for (i, &b) in bytes.iter().enumerate() {
        let esc: &str = match b {
            b'"' => "\\\"",
            b'\\' => "\\\\",
            b'\n' => "\\n",
            b'\r' => "\\r",
            b'\t' => "\\t",
            0..=0x1F => "",
            _ => continue,
        };
        out.push_str(&text[from..i]);
        if esc.is_empty() {
            use std::fmt::Write as _;
            let _ = write!(out, "\\u{b:04x}");
        } else {
            out.push_str(esc);
        }
        from = i + 1;
    }
    out.push_str(&text[from..]);
    out.push('"');
}

/// Appends one diagnostic as a JSON object, written directly (no value tree): the fields of
/// [`Diagnostic`] in order, then `deviation`, exactly what [`to_json`] gives for each element.
pub fn push_json(out: &mut String, d: &Diagnostic) {
    use std::fmt::Write as _;
    let _ = write!(out, "{{\"severity\":\"{}\",\"code\":\"{}\",\"message\":", d.severity, d.code);
    push_json_str(out, &d.message);
    out.push_str(",\"file\":");
    push_json_str(out, &d.file);
    match d.span {
        Some(s) => _ = write!(out, ",\"span\":{{\"start\":{},\"end\":{}}}", s.start, s.end),
        None => out.push_str(",\"span\":null"),
    }
    match d.at {
        Some(a) => _ = write!(out, ",\"at\":{{\"line\":{},\"col\":{}}}", a.line, a.col),
        None => out.push_str(",\"at\":null"),
    }
    out.push_str(",\"context\":[");
    for (i, c) in d.context.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        push_json_str(out, c);
    }
    out.push_str("],\"hint\":");
    match &d.hint {
        Some(h) => push_json_str(out, h),
        None => out.push_str("null"),
    }
    let _ = write!(out, ",\"deviation\":{}}}", d.is_deviation());
}

/// The diagnostics as a JSON array for tools. Each element has the [`Diagnostic`] fields plus
/// `deviation` (whether strict mode treats the code as an error).
pub fn to_json(diagnostics: &[Diagnostic]) -> String {
    #[derive(Serialize)]
    struct Out<'a> {
        #[serde(flatten)]
        d: &'a Diagnostic,
        deviation: bool,
    }
    let out: Vec<Out<'_>> = diagnostics.iter().map(|d| Out { d, deviation: d.is_deviation() }).collect();
    serde_json::to_string_pretty(&out).unwrap_or_else(|_| "[]".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::SourceFile;

    fn diag(src: &SourceFile, start: u32, end: u32) -> Diagnostic {
        let mut d = Diagnostic::new(crate::codes::E0301, crate::Strictness::Strict, &src.name, "bad value");
        d.span = Some(Span::new(start, end));
        d.at = Some(src.line_col(start));
        d
    }

    #[test]
    fn caret_under_the_span() {
        let src = SourceFile::from_str("a.eds", "[1000]\r\nDefaultValue=0x1G\r\n");
        let text = render(&diag(&src, 21, 25), &src);
        assert_eq!(
            text,
            "error[E0301]: bad value\n --> a.eds:2:14\n  |\n2 | DefaultValue=0x1G\n  |              ^^^^\n"
        );
    }

    #[test]
    fn tabs_non_ascii_and_empty_spans() {
        let src = SourceFile::from_str("a.eds", "\tName=Grüße\nK=\n");
        // `ß` starts at byte 9 (after `\tName=Grü`), column 10 in characters.
        let text = render(&diag(&src, 9, 11), &src);
        assert!(text.contains(" --> a.eds:1:10\n"), "{text}");
        assert!(text.contains("1 |  Name=Grüße\n"), "{text}");
        assert!(text.contains("  |          ^\n"), "{text}");
        // An empty span at the end of a line still gets one caret.
        let text = render(&diag(&src, 16, 16), &src);
        assert!(text.contains("2 | K=\n  |   ^\n"), "{text}");
    }

    #[test]
    fn whole_file_context_and_hint() {
        let src = SourceFile::from_str("a.eds", "");
        let mut d = Diagnostic::new(crate::codes::E0502, crate::Strictness::Lenient, "a.eds", "no [FileInfo]");
        d.context = vec!["object 0x1018 \"Identity\"".into(), "sub 2 \"Product\"".into()];
        d.hint = Some("add it".into());
        assert_eq!(
            render(&d, &src),
            "warning[E0502]: no [FileInfo]\n --> a.eds\n  = note: in object 0x1018 \"Identity\", sub 2 \"Product\"\n  = help: add it\n"
        );
        assert_eq!(summary(&[]), "no problems");
        assert_eq!(summary(&[d.clone(), d]), "2 warnings");
    }

    #[test]
    fn wide_gutters_for_long_files() {
        let text: String = (0..1200).map(|i| format!("K{i}=v\n")).collect();
        let src = SourceFile::from_str("a.eds", text);
        let start = src.text.find("K1100=").unwrap_or(0) as u32;
        let out = render(&diag(&src, start, start + 5), &src);
        assert!(out.contains("    --> a.eds:1101:1\n     |\n1101 | K1100=v\n     | ^^^^^\n"), "{out}");
    }

    /// The quoted line is the line's characters in the window, each tab as one space, and the
    /// carets sit under the span's first column: on ASCII lines (quoted as slices) and others
    /// alike, with tabs anywhere, short lines and lines long enough to be cut.
    #[test]
    fn quoted_lines_and_carets_on_ascii_and_other_lines() {
        let mut next = crate::test_rng(0x9E37_79B9_7F4A_7C15);
        let pieces = ["a", "Key", "=", "\t", " ", "0x1F", "é", "ß", "…", "Value"];
        for _ in 0..300 {
            let len = if next(4) == 0 { 60 + next(400) } else { 1 + next(30) };
            let line: String = (0..len).map(|_| pieces[next(pieces.len() as u64) as usize]).collect();
            let text = format!("[1000]\n{line}\nNext=1\n");
            let src = SourceFile::from_str("a.eds", text.as_str());
            let starts: Vec<usize> = line.char_indices().map(|(i, _)| i).collect();
            for _ in 0..4 {
                let at = starts[next(starts.len() as u64) as usize];
                let start = 7 + at as u32;
                let out = render(&diag(&src, start, start + 1), &src);
                let quoted = out.lines().nth(3).and_then(|l| l.strip_prefix("2 | ")).unwrap_or_else(|| panic!("{out}"));
                let chars = line.chars().count() as u32;
                let col = line[..at].chars().count() as u32;
                let (from, to) = quote_window(chars, col);
                let mut expected: String = line
                    .chars()
                    .skip(from as usize)
                    .take((to - from) as usize)
                    .map(|c| if c == '\t' { ' ' } else { c })
                    .collect();
                if from > 0 {
                    expected.insert(0, '…');
                }
                if to < chars {
                    expected.push('…');
                } else {
                    expected.truncate(expected.trim_end().len());
                }
                assert_eq!(quoted, expected, "{line:?} at {at}");
                let carets = out.lines().nth(4).unwrap_or("");
                let lead = col - from + u32::from(from > 0);
                assert_eq!(carets.find('^'), Some(4 + lead as usize), "{out}");
            }
        }
    }

    /// What [`render`] must give, written as plainly as it can be (a `format!` per line, the
    /// line's characters collected): the reference the optimised renderer is held to.
    fn reference(d: &Diagnostic, source: &SourceFile) -> String {
        let mut out = format!("{}[{}]: {}\n", d.severity, d.code, d.message);
        let at = d.span.map(|s| (s, d.at.unwrap_or_else(|| source.line_col(s.start))));
        let pad = " ".repeat(at.map_or(1, |(_, lc)| lc.line.to_string().len()));
        match at {
            None => out += &format!("{pad}--> {}\n", d.file),
            Some((span, lc)) => {
                out += &format!("{pad}--> {}:{}:{}\n", d.file, lc.line, lc.col);
                let chars: Vec<char> = source.line_text(lc.line).chars().collect();
                let n = chars.len() as u32;
                let start_col = lc.col.saturating_sub(1).min(n);
                let first = source.slice(span).split(['\n', '\r']).next().unwrap_or("");
                let width = (first.chars().count() as u32).min(n - start_col).max(1);
                let (from, to) = quote_window(n, start_col);
                let mut quoted: String =
                    chars[from as usize..to as usize].iter().map(|&c| if c == '\t' { ' ' } else { c }).collect();
                if from > 0 {
                    quoted.insert(0, '…');
                }
                if to < n {
                    quoted.push('…');
                } else {
                    quoted = quoted.trim_end().to_owned();
                }
                out += &format!("{pad} |\n{} | {quoted}\n", lc.line);
                let lead = start_col - from + u32::from(from > 0);
                let width = width.min(to.saturating_sub(start_col)).max(1);
                out += &format!("{pad} | {}{}\n", " ".repeat(lead as usize), "^".repeat(width as usize));
            }
        }
        if !d.context.is_empty() {
            out += &format!("{pad} = note: in {}\n", d.context.join(", "));
        }
        if let Some(h) = &d.hint {
            out += &format!("{pad} = help: {h}\n");
        }
        out
    }

    /// `render_to` gives what the plain reference gives, appended to what the buffer held, for
    /// random files (tabs, non-ASCII and Unicode spaces, trailing white space, `\r\n` and lone
    /// `\r` line ends, lines long enough to be cut, files long enough for wide gutters) and
    /// random diagnostics (spans anywhere, across line ends or past the end, positions given or
    /// computed or out of range, with and without span, context and hint, every severity).
    #[test]
    fn render_to_gives_what_the_plain_reference_gives() {
        let mut next = crate::test_rng(0x2545_F491_4F6C_DD1D);
        let pieces = ["a", "Key", "=", "\t", " ", "0x1F", "é", "ß", "…", "Value", "\u{a0}", "\u{3000}", "漢"];
        let ends = ["\n", "\r\n", "\r"];
        let codes = [crate::codes::E0301, crate::codes::E0502];
        let mut out = String::from("kept: ");
        for _ in 0..300 {
            let lines = match next(5) {
                0 => 1,
                1 => 9 + next(200),
                2 => 1000 + next(12_000),
                _ => 1 + next(12),
            };
            let mut text = String::new();
            for _ in 0..lines {
                let len = match next(6) {
                    0 => 0,
                    1 => 150 + next(400),
                    _ => 1 + next(25),
                };
                text.extend((0..len).map(|_| pieces[next(pieces.len() as u64) as usize]));
                text.push_str(ends[next(3) as usize]);
            }
            if next(3) == 0 {
                text.push_str("Last=line\t ");
            }
            let src = SourceFile::from_str(if next(2) == 0 { "dir/a.eds" } else { "b ü.dcf" }, text.as_str());
            let bounds: Vec<u32> = (0..=text.len()).filter(|&i| text.is_char_boundary(i)).map(|i| i as u32).collect();
            for _ in 0..8 {
                let severity = [Severity::Note, Severity::Warning, Severity::Error][next(3) as usize];
                let mut d = Diagnostic::new(codes[next(2) as usize], crate::Strictness::Lenient, &src.name, "msg `x`");
                d.severity = severity;
                if next(6) > 0 {
                    let start = bounds[next(bounds.len() as u64) as usize];
                    let end = match next(4) {
                        0 => start,
                        1 => start + 1 + next(300) as u32,
                        _ => bounds[next(bounds.len() as u64) as usize].max(start),
                    };
                    d.span = Some(Span::new(start, end));
                    d.at = match next(5) {
                        0 => None,
                        1 => Some(LineCol { line: [0, 99_999, u32::MAX][next(3) as usize], col: next(500) as u32 }),
                        _ => Some(src.line_col(start)),
                    };
                }
                d.context = (0..next(4)).map(|i| format!("object {i} \"n\u{e9}\"")).collect();
                if next(2) == 0 {
                    d.hint = Some(if next(2) == 0 { "fix it".into() } else { format!("use {}", next(100)).into() });
                }
                let before = out.len();
                render_to(&mut out, &d, &src);
                assert_eq!(out[before..], reference(&d, &src), "{d:?} in {text:?}");
            }
            // (The buffer keeps what it held; a long run starts again.)
            out.truncate(6);
        }
        assert_eq!(out, "kept: ");
    }
}
