//! The lossless syntax tree of an INI-style CiA 306 file.
//!
//! Every byte of the input belongs to exactly one [`Line`]; concatenating the lines' `raw`
//! spans gives the input back (see [`Document::write_lossless`]). Nothing is normalised here:
//! key spelling, order, duplicates, comments and line endings are all kept. Meaning is given
//! later, when the document is lowered into the typed [`crate::model::Model`].

use crate::lex::Lexer;
pub use crate::lex::{Line, LineEnding, LineKind};
use crate::source::{SourceFile, Span};

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

    /// A document over `source`, lexed at once. Never fails: unrecognised lines become
    /// [`LineKind::Garbage`].
    pub fn lexed(source: SourceFile) -> Self {
        let mut starts = Vec::with_capacity(source.text.len() / 12 + 2);
        starts.push(0);
        // Typical EDS lines are 12-25 bytes long; a few more or less costs little either way.
        let mut lines = Vec::with_capacity(source.text.len() / 10 + 16);
        for line in Lexer::new(&source.text) {
            if line.ending != LineEnding::None {
                starts.push(line.raw.end);
            }
            lines.push(line);
        }
        // The lexer found every line end: give the source its line index instead of letting
        // it search.
        source.set_line_starts(starts);
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
