//! Source text, byte spans and line/column lookup.

use serde::{Deserialize, Serialize};

/// A half-open byte range `start..end` into a [`SourceFile`]'s decoded text.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Span {
    /// First byte.
    pub start: u32,
    /// One past the last byte.
    pub end: u32,
}

impl Span {
    /// A span from `start` to `end`.
    pub const fn new(start: u32, end: u32) -> Self {
        Span { start, end }
    }

    /// Length in bytes.
    pub const fn len(&self) -> u32 {
        self.end - self.start
    }

    /// Whether the span covers no byte.
    pub const fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// Which text encoding the file was decoded from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Encoding {
    /// Valid UTF-8 (with or without a byte-order mark).
    Utf8,
    /// Not UTF-8: decoded as Windows-1252 (reported as a warning).
    Windows1252,
    /// UTF-16, little-endian, with its byte-order mark (`FF FE`; reported as a warning).
    Utf16Le,
    /// UTF-16, big-endian, with its byte-order mark (`FE FF`; reported as a warning).
    Utf16Be,
}

/// A 1-based line and column (column counted in characters).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct LineCol {
    /// 1-based line number.
    pub line: u32,
    /// 1-based column, in characters.
    pub col: u32,
}

/// The offset of every line start: 0 and each offset after a line end (`\n`, `\r\n` or a lone
/// `\r`, as the lexer splits lines). Looks at eight bytes at a time, because every byte of every
/// file passes through here.
fn line_starts(b: &[u8]) -> Vec<u32> {
    const LO7: u64 = 0x7F7F_7F7F_7F7F_7F7F;
    const NL: u64 = 0x0101_0101_0101_0101 * b'\n' as u64;
    const CR: u64 = 0x0101_0101_0101_0101 * b'\r' as u64;
    // The high bit of each byte of `w` that equals the byte repeated in `pattern` (exact: no
    // carries between bytes).
    let matches = |w: u64, pattern: u64| {
        let x = w ^ pattern;
        !(((x & LO7) + LO7) | x | LO7)
    };
    // Typical EDS lines are 15-25 bytes long.
    let mut out = Vec::with_capacity(b.len() / 16 + 2);
    out.push(0u32);
    let mut chunks = b.chunks_exact(8);
    let mut base = 0usize;
    for c in &mut chunks {
        let mut w = [0u8; 8];
        w.copy_from_slice(c);
        let w = u64::from_le_bytes(w);
        let mut z = matches(w, NL) | matches(w, CR);
        while z != 0 {
            let i = base + (z.trailing_zeros() / 8) as usize;
            // A `\r` followed by `\n` ends its line at the `\n`.
            if !(b[i] == b'\r' && b.get(i + 1) == Some(&b'\n')) {
                out.push((i + 1) as u32);
            }
            z &= z - 1;
        }
        base += 8;
    }
    for (i, &c) in chunks.remainder().iter().enumerate() {
        let i = base + i;
        if c == b'\n' || (c == b'\r' && b.get(i + 1) != Some(&b'\n')) {
            out.push((i + 1) as u32);
        }
    }
    out
}

/// A decoded source file with a line index.
#[derive(Clone, Debug)]
pub struct SourceFile {
    /// The name used in diagnostics (usually the path as given by the user).
    pub name: String,
    /// The decoded text. Byte-identical to the input when `encoding` is UTF-8.
    pub text: String,
    /// The encoding the bytes were decoded from.
    pub encoding: Encoding,
    /// Whether the input started with a UTF-8 byte-order mark (kept for lossless writing; the
    /// mark itself is not part of `text`). UTF-16 text always has its mark, which `encoding`
    /// implies.
    pub bom: bool,
    /// For UTF-16: the number of code units that were not valid UTF-16 (unpaired surrogates, an
    /// odd last byte), each decoded as U+FFFD. Reported as an error: the text is not what the
    /// file says.
    pub invalid_units: usize,
    /// Offsets of the line starts; found by the lexer, which looks at every byte anyway, or
    /// computed on first use.
    line_starts: std::sync::OnceLock<Vec<u32>>,
    /// Whether `text` was found to be all ASCII when it was decoded ([`SourceFile::decode_owned`]
    /// looks at every byte for that anyway), so that lowering need not look again for the
    /// first non-ASCII byte (E0009; deriving it again cost 0.35 M instructions on the corpus);
    /// `false` only means "not known". Like `line_starts`, it describes the text as decoded.
    ascii: bool,
}

impl SourceFile {
    /// Decodes `bytes` (UTF-16 when it starts with a UTF-16 byte-order mark, otherwise UTF-8,
    /// falling back to Windows-1252) and indexes its lines.
    pub fn decode(name: impl Into<String>, bytes: &[u8]) -> Self {
        let utf16 = match bytes {
            [0xFF, 0xFE, rest @ ..] => Some((Encoding::Utf16Le, rest, u16::from_le_bytes as fn([u8; 2]) -> u16)),
            [0xFE, 0xFF, rest @ ..] => Some((Encoding::Utf16Be, rest, u16::from_be_bytes as fn([u8; 2]) -> u16)),
            _ => None,
        };
        if let Some((encoding, body, unit)) = utf16 {
            let units = body.chunks_exact(2).map(|c| unit([c[0], c[1]]));
            let mut invalid = body.len() % 2;
            let mut text = String::with_capacity(body.len() / 2);
            for c in char::decode_utf16(units) {
                text.push(c.unwrap_or_else(|_| {
                    invalid += 1;
                    char::REPLACEMENT_CHARACTER
                }));
            }
            if body.len() % 2 == 1 {
                text.push(char::REPLACEMENT_CHARACTER);
            }
            let mut src = Self::from_parts(name.into(), text, encoding, false);
            src.invalid_units = invalid;
            return src;
        }
        let (bom, body) = match bytes.strip_prefix(b"\xEF\xBB\xBF") {
            Some(rest) => (true, rest),
            None => (false, bytes),
        };
        let (text, encoding) = match std::str::from_utf8(body) {
            Ok(s) => (s.to_owned(), Encoding::Utf8),
            Err(_) => (crate::encoding::decode_windows_1252(body), Encoding::Windows1252),
        };
        Self::from_parts(name.into(), text, encoding, bom)
    }

    /// [`SourceFile::decode`] of bytes the caller gives away: UTF-8 without a byte-order mark,
    /// the commonest case, becomes the text without a copy.
    pub fn decode_owned(name: impl Into<String>, bytes: Vec<u8>) -> Self {
        if bytes.starts_with(b"\xEF\xBB\xBF") || bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
            return Self::decode(name, &bytes);
        }
        // Nearly every file is ASCII, which is valid UTF-8: one fast look at its bytes decides
        // that, instead of the UTF-8 validation and, for E0009, a second look for a non-ASCII byte.
        if first_non_ascii(&bytes).is_none() {
            // SAFETY: every byte is below 0x80, and a sequence of ASCII bytes is valid UTF-8.
            let text = unsafe { String::from_utf8_unchecked(bytes) };
            let mut src = Self::from_parts(name.into(), text, Encoding::Utf8, false);
            src.ascii = true;
            return src;
        }
        match String::from_utf8(bytes) {
            Ok(text) => Self::from_parts(name.into(), text, Encoding::Utf8, false),
            Err(e) => Self::decode(name, e.as_bytes()),
        }
    }

    /// Where the text's first non-ASCII byte is, if it has one.
    pub(crate) fn first_non_ascii(&self) -> Option<usize> {
        if self.ascii { None } else { first_non_ascii(self.text.as_bytes()) }
    }

    /// Wraps already decoded text.
    pub fn from_str(name: impl Into<String>, text: impl Into<String>) -> Self {
        Self::from_parts(name.into(), text.into(), Encoding::Utf8, false)
    }

    fn from_parts(name: String, text: String, encoding: Encoding, bom: bool) -> Self {
        SourceFile {
            name,
            text,
            encoding,
            bom,
            invalid_units: 0,
            line_starts: std::sync::OnceLock::new(),
            ascii: false,
        }
    }

    /// The offset of every line start (0 and each offset after a line end).
    fn starts(&self) -> &[u32] {
        self.line_starts.get_or_init(|| line_starts(self.text.as_bytes()))
    }

    /// Records the line starts a caller found while reading the text (the lexer does), so that
    /// they need not be searched for again. They must be what [`line_starts`] finds (checked in
    /// debug builds); if the index was already built, it is kept.
    pub(crate) fn set_line_starts(&self, starts: Vec<u32>) {
        debug_assert_eq!(starts, line_starts(self.text.as_bytes()), "line starts of {}", self.name);
        let _ = self.line_starts.set(starts);
    }

    /// The text and the line index (if it was built), for their memory to be reused.
    pub(crate) fn into_buffers(self) -> (String, Option<Vec<u32>>) {
        (self.text, self.line_starts.into_inner())
    }

    /// The text a span covers (empty if the span is out of range).
    pub fn slice(&self, span: Span) -> &str {
        self.text.get(span.start as usize..span.end as usize).unwrap_or("")
    }

    /// Line and column of a byte offset.
    pub fn line_col(&self, offset: u32) -> LineCol {
        let starts = self.starts();
        let line_idx = match starts.binary_search(&offset) {
            Ok(i) => i,
            Err(i) => i - 1,
        };
        self.col_in_line(line_idx, offset)
    }

    /// [`SourceFile::line_col`] for offsets taken in ascending order: `cursor` is the index of
    /// the line of the previous offset (start with 0), and the line is looked for from there:
    /// up to 64 lines ahead one after another, then by a binary search of the lines that follow.
    /// (The index is cold by the time diagnostics get their places: reading it in order lets
    /// the processor fetch ahead, where each step of a binary search waits for its load.) An
    /// offset before the cursor's line is searched for from the start.
    pub(crate) fn line_col_from(&self, offset: u32, cursor: &mut usize) -> LineCol {
        let starts = self.starts();
        let mut i = if starts.get(*cursor).is_some_and(|&s| s <= offset) { *cursor } else { 0 };
        let near = (i + 64).min(starts.len());
        while i + 1 < near && starts[i + 1] <= offset {
            i += 1;
        }
        if i + 1 == near && near < starts.len() && starts[near] <= offset {
            i = near + starts[near..].partition_point(|&s| s <= offset) - 1;
        }
        *cursor = i;
        self.col_in_line(i, offset)
    }

    /// Line and column of `offset`, which lies in line `line_idx` (0-based).
    fn col_in_line(&self, line_idx: usize, offset: u32) -> LineCol {
        let starts = self.starts();
        let start = starts[line_idx] as usize;
        let end = (offset as usize).min(self.text.len());
        // Columns count characters; most lines are ASCII, where that is the length in bytes
        // (`chars().count()` looked at each byte of short strings one at a time).
        let col = self
            .text
            .get(start..end)
            .map(|s| if s.is_ascii() { s.len() } else { s.chars().count() })
            .unwrap_or(end - start);
        LineCol { line: line_idx as u32 + 1, col: col as u32 + 1 }
    }

    /// The text of 1-based line `line`, without its line ending.
    pub fn line_text(&self, line: u32) -> &str {
        let i = line.saturating_sub(1) as usize;
        let starts = self.starts();
        let Some(&start) = starts.get(i) else { return "" };
        let end = starts.get(i + 1).map(|&e| e as usize).unwrap_or(self.text.len());
        self.text[start as usize..end].trim_end_matches(['\n', '\r'])
    }

    /// Number of lines.
    pub fn line_count(&self) -> usize {
        self.starts().len()
    }
}

/// The position of the first byte of `b` that is not ASCII (0x80 or above), if any.
///
/// Blocks of 256 bytes are ORed together first (which the compiler does sixteen bytes at a time
/// without a branch), and only a block with such a byte is searched byte by byte.
pub(crate) fn first_non_ascii(b: &[u8]) -> Option<usize> {
    const BLOCK: usize = 256;
    let mut blocks = b.chunks_exact(BLOCK);
    let mut at = 0;
    for block in &mut blocks {
        if block.iter().fold(0u8, |acc, &c| acc | c) >= 0x80 {
            return block.iter().position(|&c| c >= 0x80).map(|i| at + i);
        }
        at += BLOCK;
    }
    let rest = blocks.remainder();
    if rest.is_ascii() { None } else { rest.iter().position(|&c| c >= 0x80).map(|i| at + i) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_non_ascii_is_what_a_byte_scan_finds() {
        for len in [0usize, 1, 15, 16, 63, 64, 65, 127, 128, 200, 255, 256, 257, 511, 512, 700] {
            for at in (0..len).step_by(7).chain([len.saturating_sub(1)]) {
                for high in [0x80u8, 0xC3, 0xFF] {
                    let mut b = vec![b'a'; len];
                    assert_eq!(first_non_ascii(&b), None);
                    if len > 0 {
                        b[at] = high;
                        if at + 1 < len {
                            b[len - 1] = 0xFF;
                        }
                        assert_eq!(first_non_ascii(&b), b.iter().position(|&c| c >= 0x80), "{len} {at}");
                    }
                }
            }
        }
    }

    #[test]
    fn decode_owned_gives_the_text_and_encoding_decode_gives() {
        let cases: [&[u8]; 8] = [
            b"",
            b"[1000]\nA=1\n",
            "[1000]\nName=Gr\u{fc}\u{df}e\n".as_bytes(),
            b"\xEF\xBB\xBF[1000]\n",
            b"Name=Gr\xFC\xDFe\n",
            b"\xFF\xFEa\0=\0",
            b"\xFE\xFF\0a\0=",
            b"abc\x80",
        ];
        for bytes in cases {
            let long: Vec<u8> = b"x".repeat(300).into_iter().chain(bytes.iter().copied()).collect();
            for b in [bytes.to_vec(), long] {
                let (a, o) = (SourceFile::decode("a", &b), SourceFile::decode_owned("a", b.clone()));
                assert_eq!(
                    (&a.text, a.encoding, a.bom, a.invalid_units),
                    (&o.text, o.encoding, o.bom, o.invalid_units)
                );
                let expect = if a.encoding == Encoding::Utf8 { first_non_ascii(a.text.as_bytes()) } else { None };
                if a.encoding == Encoding::Utf8 {
                    assert_eq!(o.first_non_ascii(), expect);
                    assert_eq!(a.first_non_ascii(), expect);
                }
            }
        }
    }

    #[test]
    fn line_starts_match_a_byte_loop() {
        let text: Vec<u8> = b"a\nbb\n\n\x0B\n\x0B\x0Bccc\r\n\n\n\r\r\n\n\n\n\n\nxyz\x8A\x0A\r\xFF\n\r".repeat(3);
        for end in 0..text.len() {
            let b = &text[..end];
            let ends = |i: usize| b[i] == b'\n' || (b[i] == b'\r' && b.get(i + 1) != Some(&b'\n'));
            let naive: Vec<u32> =
                std::iter::once(0).chain((0..b.len()).filter(|&i| ends(i)).map(|i| i as u32 + 1)).collect();
            assert_eq!(line_starts(b), naive);
        }
    }

    #[test]
    fn line_col_from_a_cursor_agrees_with_line_col() {
        let text: String = (0..300).map(|i| "x".repeat(i % 7) + if i % 5 == 0 { "\r\n" } else { "\n" }).collect();
        let src = SourceFile::from_str("a", text.as_str());
        let len = text.len() as u32;
        for step in [1u32, 3, 17, 200, 1000] {
            let mut cursor = 0;
            let mut offset = 0;
            while offset <= len {
                assert_eq!(src.line_col_from(offset, &mut cursor), src.line_col(offset), "{offset}");
                offset += step;
            }
        }
        // Offsets out of order still get their line.
        let mut cursor = 0;
        for offset in [500, 10, 900, 0, len] {
            assert_eq!(src.line_col_from(offset, &mut cursor), src.line_col(offset));
        }
    }

    #[test]
    fn line_and_column() {
        let src = SourceFile::from_str("a", "ab\ncä d\n\nx");
        assert_eq!(src.line_count(), 4);
        assert_eq!(src.line_col(0), LineCol { line: 1, col: 1 });
        assert_eq!(src.line_col(3), LineCol { line: 2, col: 1 });
        // Columns count characters: `ä` is two bytes.
        assert_eq!(src.line_col(7), LineCol { line: 2, col: 4 });
        assert_eq!(src.line_text(2), "cä d");
        assert_eq!(src.line_col(10), LineCol { line: 4, col: 1 });
    }
}
