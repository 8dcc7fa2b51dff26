//! The lossless syntax tree of an INI-style CiA 306 file.
//!
//! Every byte of the input belongs to exactly one [`Line`]; concatenating the lines' `raw`
//! spans gives the input back (see [`Document::write_lossless`]). Nothing is normalised here:
//! key spelling, order, duplicates, comments and line endings are all kept. Meaning is given
//! later, when the document is lowered into the typed [`crate::model::Model`].

use crate::source::{SourceFile, Span};

/// How a line ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineEnding {
    /// `\n`
    Lf,
    /// `\r\n`
    CrLf,
    /// A lone `\r` (old Mac files).
    Cr,
    /// The last line of a file without a final line break.
    None,
}

/// What a line says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LineKind {
    /// Only white space.
    Blank,
    /// A `;` comment line (`text` is the span after the `;`).
    Comment {
        /// The comment text after `;`.
        text: Span,
    },
    /// `[name]` (`name` excludes the brackets and surrounding spaces).
    Section {
        /// The section name as written.
        name: Span,
        /// Trailing text after `]` (usually an inline comment); empty span if none.
        trailing: Span,
    },
    /// `key=value` (`key` and `value` trimmed of surrounding white space; an inline `;`
    /// comment is not split off, because CiA 306 values such as ParameterName may contain `;`).
    Entry {
        /// The key as written.
        key: Span,
        /// The value as written (may be empty).
        value: Span,
    },
    /// A line that is none of the above (reported as a diagnostic, kept for round trips).
    Garbage,
}

/// One physical line of the input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Line {
    /// The whole line including its line ending.
    pub raw: Span,
    /// The line without its line ending.
    pub content: Span,
    /// Its line ending.
    pub ending: LineEnding,
    /// Its meaning.
    pub kind: LineKind,
}

/// A lexed file: its source and its lines.
///
/// The lines are lexed on first use ([`Document::lines`]): reading a file into the typed model
/// runs the same lexer ([`crate::lex::Lexer`]) line by line and keeps no line, so a document that
/// is only written back ([`Document::write_lossless`]) or used for diagnostics never pays for
/// the list.
#[derive(Clone, Debug)]
pub struct Document {
    /// The decoded source text.
    pub source: SourceFile,
    lines: std::sync::OnceLock<Vec<Line>>,
}

/// A section with the indices of its lines in [`Document::lines`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SectionRef {
    /// Index of the `[name]` line.
    pub header: usize,
    /// Name span.
    pub name: Span,
    /// Indices of the entry lines that belong to the section, in order.
    pub entries: Vec<usize>,
}

impl Document {
    /// A document over `source`, lexed when its lines are first asked for.
    pub fn new(source: SourceFile) -> Self {
        Document { source, lines: std::sync::OnceLock::new() }
    }

    /// A document whose lines are already known (what [`crate::lex::lex`] found in `source`).
    pub(crate) fn with_lines(source: SourceFile, lines: Vec<Line>) -> Self {
        Document { source, lines: std::sync::OnceLock::from(lines) }
    }

    /// Every line, in order (lexed on the first call).
    pub fn lines(&self) -> &[Line] {
        self.lines.get_or_init(|| crate::lex::lex_lines(&self.source.text))
    }

    /// Sections in file order, each with the entry lines that follow it. Entries before the
    /// first section are not part of any section (see [`Document::orphan_entries`]).
    pub fn sections(&self) -> Vec<SectionRef> {
        let mut out: Vec<SectionRef> = Vec::new();
        for (i, line) in self.lines().iter().enumerate() {
            match &line.kind {
                LineKind::Section { name, .. } => out.push(SectionRef { header: i, name: *name, entries: Vec::new() }),
                LineKind::Entry { .. } => {
                    if let Some(s) = out.last_mut() {
                        s.entries.push(i);
                    }
                }
                _ => {}
            }
        }
        out
    }

    /// Entry lines that come before any section header.
    pub fn orphan_entries(&self) -> Vec<usize> {
        let lines = self.lines();
        let first = lines.iter().position(|l| matches!(l.kind, LineKind::Section { .. })).unwrap_or(lines.len());
        (0..first).filter(|&i| matches!(lines[i].kind, LineKind::Entry { .. })).collect()
    }

    /// The key and value text of an entry line (`None` for other lines).
    pub fn entry(&self, line: usize) -> Option<(&str, &str)> {
        match self.lines().get(line)?.kind {
            LineKind::Entry { key, value } => Some((self.source.slice(key), self.source.slice(value))),
            _ => None,
        }
    }

    /// Writes the document back: byte-identical to the input it was read from (including a UTF-8
    /// byte-order mark; a Windows-1252 or UTF-16 input is re-encoded as it was, which gives the input
    /// back unless it had invalid UTF-16). The lines tile the
    /// text exactly (every byte is in one line's `raw` span), so this is the text itself.
    pub fn write_lossless(&self) -> Vec<u8> {
        let text = &self.source.text;
        let mut out = Vec::with_capacity(text.len() + 3);
        if self.source.bom {
            out.extend_from_slice(b"\xEF\xBB\xBF");
        }
        match self.source.encoding {
            crate::source::Encoding::Utf8 => out.extend_from_slice(text.as_bytes()),
            crate::source::Encoding::Windows1252 => out.extend(crate::encoding::encode_windows_1252(text)),
            crate::source::Encoding::Utf16Le => {
                out.extend_from_slice(&[0xFF, 0xFE]);
                out.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
            }
            crate::source::Encoding::Utf16Be => {
                out.extend_from_slice(&[0xFE, 0xFF]);
                out.extend(text.encode_utf16().flat_map(u16::to_be_bytes));
            }
        }
        out
    }
}
