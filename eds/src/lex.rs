//! The lexer: decoded text → lossless lines ([`Line`]), from which the syntax tree
//! (`crate::ast`) is built.
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
//! byte: the `raw` spans of the lines tile the text exactly, so that they give the input
//! back.
//!
//! # Speed
//!
//! The grammar is written as nom parsers over bytes, not `char`s: every character that decides
//! the shape of a line (`[`, `]`, `=`, `;`, `#`, line ends, ASCII blanks) is ASCII, and UTF-8
//! never uses ASCII bytes inside a multi-byte character, so byte positions are always char
//! boundaries where the grammar cuts. The line's first byte picks the rule, so each byte is
//! looked at once. The parsers that run over the bulk of the text (`take_till` up to `=` or a
//! line end) compare sixteen bytes at a time (SSE2 on x86_64, one of the crate's four kinds of
//! `unsafe` use; eight-byte words elsewhere), and the line end is one match on two bytes. The commonest line,
//! `Key=Value` with nothing to trim, has a shorter path of its own
//! ([`Lexer::next_plain_entry`], tested to agree with the general one): on x86_64 it compares
//! the sixteen bytes from the line's start once with `=`, the line ends and the printable range,
//! and a line that ends within them (seven in ten) is decided on those masks alone: where key and
//! value end, whether a byte at either end of them needs trimming, which line end it has; a
//! longer line's further blocks are compared with the line ends only (lines within sixteen
//! bytes of the end of the text take the byte-wise scan). It cuts the key and the value out of
//! the text without checking for char boundaries again (the second: the cuts are at ASCII
//! bytes the scan found; the third is pass 1's entry, `lower::sections::Kv`, which keeps its
//! key and value as an address and `u32` lengths and gives them back with `from_raw_parts`; the
//! fourth is `source::SourceFile::decode_owned`, which takes a file all of whose bytes are ASCII as
//! its text without validating it as UTF-8 again).
//! Trimming looks at the bytes at either end and only falls back to [`str::trim`] when it meets
//! a non-ASCII byte there (which may be Unicode white space). [`Lexer`] allocates nothing; [`lex_lines`]
//! allocates the `Vec` of lines.

use nom::bytes::complete::take_while;
use nom::{IResult, Parser};

use crate::source::Span;

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

/// Lexes text into lines (all the lines [`Lexer`] yields).
pub fn lex_lines(text: &str) -> Vec<Line> {
    let mut lines = Vec::with_capacity(text.len() / 10 + 16);
    lines.extend(Lexer::new(text));
    lines
}

/// The lexer, as an iterator over the lines of a text, in order. [`lex_lines`] collects them; the
/// reader ([`crate::parse`]) takes them one at a time and keeps none.
#[derive(Clone, Debug)]
pub struct Lexer<'a> {
    text: &'a str,
    /// What is left to lex (a suffix of `text`).
    rest: &'a str,
}

impl<'a> Lexer<'a> {
    /// A lexer at the start of `text`.
    pub fn new(text: &'a str) -> Self {
        Lexer { text, rest: text }
    }
}

impl Iterator for Lexer<'_> {
    type Item = Line;

    #[inline]
    fn next(&mut self) -> Option<Line> {
        let base = self.text.as_bytes();
        let input = self.rest.as_bytes();
        if input.is_empty() {
            return None;
        }
        let start = offset(base, input);
        let (after, kind) = line_content(self.text, base, input);
        let content_end = offset(base, after);
        // `line_ending` cannot fail: its last branch accepts the end of the input, and `after`
        // is either empty or starts with a line end.
        let (rest, ending) = line_ending(after).unwrap_or((&after[after.len()..], LineEnding::None));
        let next = offset(base, rest);
        // (`next` follows a line end or is the end of the text: a char boundary.)
        self.rest = self.text.get(next..).unwrap_or("");
        Some(Line {
            raw: Span::new(start as u32, next as u32),
            content: Span::new(start as u32, content_end as u32),
            ending,
            kind,
        })
    }
}

/// A line [`Lexer::next_plain_entry`] read: an entry whose key and value need no trimming.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlainEntry<'a> {
    /// The key.
    pub key: &'a str,
    /// The value (empty when nothing follows `=`).
    pub value: &'a str,
    /// Where the key (and the line) starts in the text.
    pub start: u32,
    /// Where the next line starts.
    pub end: u32,
    /// Whether the line ended with `\n` or `\r\n` (otherwise it was the last line, with no
    /// ending).
    pub newline: bool,
}

impl PlainEntry<'_> {
    /// The span of the key.
    pub fn key_span(&self) -> Span {
        Span::new(self.start, self.start + self.key.len() as u32)
    }

    /// The span of the value (after the key and its `=`).
    pub fn value_span(&self) -> Span {
        let start = self.start + self.key.len() as u32 + 1;
        Span::new(start, start + self.value.len() as u32)
    }
}

/// A line [`Lexer::next_plain_section`] read: a section header `[Name]` with nothing to trim
/// and nothing after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlainSection<'a> {
    /// The name, between the brackets.
    pub name: &'a str,
    /// Where the line (its `[`) starts in the text.
    pub start: u32,
    /// Where the next line starts.
    pub end: u32,
    /// Whether the line ended with `\n` or `\r\n` (otherwise it was the last line, with no
    /// ending).
    pub newline: bool,
}

impl PlainSection<'_> {
    /// The span of the name.
    pub fn name_span(&self) -> Span {
        Span::new(self.start + 1, self.start + 1 + self.name.len() as u32)
    }
}

impl<'a> Lexer<'a> {
    /// Reads the next line if it is the commonest kind: `Key=Value` with no blank around the key
    /// or the value, ended by `\n`, `\r\n` or the end of the text (the key starts with a digit
    /// or a byte from `A` to `~` other than `[`, none of which starts another kind of line; and
    /// no byte that starts or ends the key or the value is white space or non-ASCII).
    /// Any other line is left for [`Iterator::next`]; the lexer does not move. A line read here is
    /// what `next` would have made of it (`LineKind::Entry` with the same spans), with less work:
    /// no line kind to dispatch on and no trimming to decide.
    #[inline(always)]
    pub fn next_plain_entry(&mut self) -> Option<PlainEntry<'a>> {
        // Keys start with a letter (`A` and up, where no byte but `[` starts another kind of
        // line) or, in the object lists, a digit: one look-up in a table of those bytes.
        let &first = self.rest.as_bytes().first()?;
        if !PLAIN_FIRST[first as usize] {
            return None;
        }
        // Every path gives the line's shape (`PlainLine`), and the entry is cut in one place.
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        let line = match self.plain_line_in_blocks() {
            Some(line) => line?,
            None => self.plain_line_bytes()?,
        };
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
        let line = self.plain_line_bytes()?;
        Some(self.cut_plain_entry(line))
    }

    /// Reads the next line if it is the commonest section header: `[Name]` at the start of the
    /// line, ended right after the `]` by `\n`, `\r\n` or the end of the text, with a name
    /// that needs no trimming (its first and last bytes are printable ASCII other than the
    /// space). Any other line is left for [`Iterator::next`]; the lexer does not move. A line
    /// read here is what `next` would have made of it (`LineKind::Section` with the same name
    /// and nothing trailing), with less work.
    #[inline]
    pub fn next_plain_section(&mut self) -> Option<PlainSection<'a>> {
        let input = self.rest.as_bytes();
        if input.first() != Some(&b'[') {
            return None;
        }
        let name_len = prefix_without(&input[1..], [b']', b'[', b'\n', b'\r']);
        let close = 1 + name_len;
        if input.get(close) != Some(&b']') || name_len == 0 {
            return None;
        }
        if !is_graphic(input[1]) || !is_graphic(input[name_len]) {
            return None;
        }
        let (ending, newline) = match &input[close + 1..] {
            [b'\n', ..] => (1, true),
            [b'\r', b'\n', ..] => (2, true),
            [] => (0, false),
            _ => return None,
        };
        // (Cut at `[`, `]` and after the line end, all ASCII: char boundaries.)
        let name = self.rest.get(1..close)?;
        let after = self.rest.get(close + 1 + ending..)?;
        let start = offset(self.text.as_bytes(), input) as u32;
        self.rest = after;
        Some(PlainSection { name, start, end: offset(self.text.as_bytes(), after.as_bytes()) as u32, newline })
    }

    /// Reads the next line if it is empty, ended by `\n` or `\r\n` (what [`Iterator::next`]
    /// makes a [`LineKind::Blank`] line with no content), and returns where the line after it
    /// starts. Any other line is left; the lexer does not move.
    #[inline(always)]
    pub fn next_empty_line(&mut self) -> Option<u32> {
        let ending = match self.rest.as_bytes() {
            [b'\n', ..] => 1,
            [b'\r', b'\n', ..] => 2,
            _ => return None,
        };
        self.rest = self.rest.get(ending..)?;
        Some(offset(self.text.as_bytes(), self.rest.as_bytes()) as u32)
    }

    /// [`Lexer::next_plain_entry`]'s look at a line that starts at least sixteen bytes before
    /// the end of the text (`None` otherwise, or when a block of the line would reach past the
    /// end: then [`Lexer::plain_line_bytes`] reads it). The line is read in sixteen-byte blocks
    /// from its start. The first is compared once with `=`, the two line-end bytes and the
    /// printable range ([`BlockMasks`]): a line that ends in it (seven in ten) is decided on
    /// its masks without looking at a byte again (where its key and value end, whether the
    /// bytes at either end of them need trimming, which line end it has). For a longer line
    /// the next blocks are only compared with the line ends, and [`Lexer::plain_line_at`]
    /// looks at the bytes at the ends of its key and value.
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[inline(always)]
    fn plain_line_in_blocks(&self) -> Option<Option<PlainLine>> {
        let input = self.rest.as_bytes();
        let m = BlockMasks::of(input.first_chunk::<16>()?);
        let stop = m.eq | m.ends();
        if stop == 0 {
            // A key of sixteen bytes or more.
            return self.plain_line_long_key();
        }
        // The key ends at the first `=` or line end (the line is an entry only if it is `=`),
        // the value at the first line end after it.
        let i = stop.trailing_zeros();
        if m.eq & (1 << i) == 0 {
            return Some(None);
        }
        let ends_after = m.ends() & (!1u32 << i);
        if ends_after == 0 {
            // The value runs into the next block (three lines in ten).
            return self.plain_line_from(16, i as usize);
        }
        let e = ends_after.trailing_zeros();
        // The key's last byte and the value's first and last are printable and not the space;
        // when the value is empty, the bits looked at are the `=` and the line end, neither of
        // them `blank`. (The key is not empty: `PLAIN_FIRST` has no `=`; `i < e < 16`.)
        let ends_of_parts = (1u32 << i) >> 1 | 1 << (i + 1) | 1 << (e - 1);
        if m.blank & ends_of_parts != 0 {
            return Some(None);
        }
        let ending = if m.lf >> e & 1 != 0 {
            1
        } else if e < 15 {
            // A `\r`, followed by `\n` or (a lone `\r`) not.
            if m.lf >> (e + 1) & 1 == 0 {
                return Some(None);
            }
            2
        } else if input.get(16) == Some(&b'\n') {
            2
        } else {
            return Some(None);
        };
        Some(Some(PlainLine { key_len: i as usize, line_len: e as usize, ending }))
    }

    /// The end of [`Lexer::plain_line_in_blocks`] for a line whose key ends at `key_len`,
    /// and whose first `at` bytes (a multiple of sixteen) hold no line end: looks for the line
    /// end in the blocks from `at` on.
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[inline(always)]
    fn plain_line_from(&self, mut at: usize, key_len: usize) -> Option<Option<PlainLine>> {
        let input = self.rest.as_bytes();
        loop {
            let ends = BlockMasks::line_ends(input.get(at..at + 16)?.try_into().ok()?);
            if ends != 0 {
                return Some(self.plain_line_at(key_len, at + ends.trailing_zeros() as usize));
            }
            at += 16;
        }
    }

    /// [`Lexer::plain_line_in_blocks`] for a line whose first sixteen bytes hold no `=` and no
    /// line end (a long key, or no entry at all; rare).
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    #[inline(never)]
    fn plain_line_long_key(&self) -> Option<Option<PlainLine>> {
        let input = self.rest.as_bytes();
        let mut at = 16;
        loop {
            let m = BlockMasks::of(input.get(at..at + 16)?.try_into().ok()?);
            let stop = m.eq | m.ends();
            if stop != 0 {
                let i = stop.trailing_zeros();
                if m.eq & (1 << i) == 0 {
                    return Some(None);
                }
                let ends_after = m.ends() & (!1u32 << i);
                if ends_after != 0 {
                    return Some(self.plain_line_at(at + i as usize, at + ends_after.trailing_zeros() as usize));
                }
                return self.plain_line_from(at + 16, at + i as usize);
            }
            at += 16;
        }
    }

    /// The shape of the line at the start of what is left if it is a plain entry, given that
    /// its key is `key_len` bytes long (if an `=` follows) and its content ends at `line_len`,
    /// at a line-end byte or the end of the text. Every scan but the blocks' ends here.
    #[inline(always)]
    fn plain_line_at(&self, key_len: usize, line_len: usize) -> Option<PlainLine> {
        let input = self.rest.as_bytes();
        if input.get(key_len) != Some(&b'=') || !is_graphic(*input.get(key_len.checked_sub(1)?)?) {
            return None;
        }
        let value_part = input.get(key_len + 1..line_len)?;
        if let (Some(&a), Some(&b)) = (value_part.first(), value_part.last())
            && !(is_graphic(a) && is_graphic(b))
        {
            return None;
        }
        let ending = match input.get(line_len..)? {
            [b'\n', ..] => 1,
            [b'\r', b'\n', ..] => 2,
            [] => 0,
            // A lone `\r`: the general path keeps count of columns after it.
            _ => return None,
        };
        Some(PlainLine { key_len, line_len, ending })
    }

    /// Moves past the plain entry at the start of what is left, of the shape `line`, and gives
    /// it back.
    #[inline(always)]
    fn cut_plain_entry(&mut self, line: PlainLine) -> PlainEntry<'a> {
        let PlainLine { key_len, line_len, ending } = line;
        let input = self.rest.as_bytes();
        // (`PlainLine` promises `key_len < line_len <= line_len + ending <= input.len()`.)
        let (key, value, after) = (&input[..key_len], &input[key_len + 1..line_len], &input[line_len + ending..]);
        // SAFETY: `input` is the bytes of the `str` `self.rest`, and each slice is cut where an
        // ASCII byte starts (the `=` at `key_len`, the byte after it, the line end at
        // `line_len`, the byte after the line end: what a `PlainLine` promises) or at an end of
        // `input`: every cut is a char boundary, so each slice is UTF-8. (`str` slicing checked
        // the boundaries again, byte by byte, on the commonest line of every file.)
        let (key, value, after) = unsafe {
            (
                std::str::from_utf8_unchecked(key),
                std::str::from_utf8_unchecked(value),
                std::str::from_utf8_unchecked(after),
            )
        };
        let start = offset(self.text.as_bytes(), input) as u32;
        self.rest = after;
        let end = offset(self.text.as_bytes(), after.as_bytes()) as u32;
        PlainEntry { key, value, start, end, newline: ending != 0 }
    }

    /// [`Lexer::next_plain_entry`]'s look at any line, the last one included (scanning for the
    /// key's end, then for the value's).
    #[inline(always)]
    fn plain_line_bytes(&self) -> Option<PlainLine> {
        let input = self.rest.as_bytes();
        let key_len = prefix_without(input, [b'=', b'\n', b'\r']);
        if input.get(key_len) != Some(&b'=') {
            return None;
        }
        let line_len = key_len + 1 + prefix_without(&input[key_len + 1..], [b'\n', b'\r']);
        self.plain_line_at(key_len, line_len)
    }
}

/// Where a plain entry's parts end, as the lexer's look at its line found them: the key is
/// `key_len` bytes long and an `=` follows it; the content ends at `line_len`, where a line
/// end of `ending` bytes (`\n` or `\r\n`; none at the end of the text) starts. Made only where
/// those bytes were checked to be there: `Lexer::cut_plain_entry` relies on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PlainLine {
    key_len: usize,
    line_len: usize,
    ending: usize,
}

/// The bytes a line read by [`Lexer::next_plain_entry`] may start with: `0` to `9` and `A` to
/// `~` except `[` (printable, and starting no comment, section header or blank line).
static PLAIN_FIRST: [bool; 256] = {
    let mut table = [false; 256];
    let mut b = 0;
    while b < 256 {
        table[b] = matches!(b as u8, b'0'..=b'9' | b'A'..=b'~') && b as u8 != b'[';
        b += 1;
    }
    table
};

/// A printable ASCII byte other than the space: no trimming removes it.
#[inline(always)]
fn is_graphic(b: u8) -> bool {
    (0x21..=0x7E).contains(&b)
}

/// Which bytes of a sixteen-byte block (bit n: byte n) are `=`, `\n`, `\r`, and neither
/// printable ASCII other than the space ([`is_graphic`]) nor a line end (`blank`: white space,
/// control bytes, non-ASCII).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BlockMasks {
    eq: u32,
    lf: u32,
    cr: u32,
    blank: u32,
}

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
impl BlockMasks {
    /// The masks of `block` (SSE2: one load, a compare for each of `=`, `\n`, `\r`, a range
    /// check, four masks).
    #[inline(always)]
    fn of(block: &[u8; 16]) -> Self {
        use std::arch::x86_64::*;
        // SAFETY: the intrinsics need SSE2, which every x86_64 processor has and the cfg
        // above checks is enabled; the load reads the sixteen bytes of `block`, which it
        // borrows (an unaligned load, as `_mm_loadu_si128` allows).
        unsafe {
            let v = _mm_loadu_si128(block.as_ptr().cast());
            let mask = |m: __m128i| _mm_movemask_epi8(m) as u32;
            let lf = _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\n' as i8));
            let cr = _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\r' as i8));
            // Signed compares: 0x21..=0x7F are above 0x20, bytes from 0x80 up are negative.
            let graphic =
                _mm_andnot_si128(_mm_cmpeq_epi8(v, _mm_set1_epi8(0x7F)), _mm_cmpgt_epi8(v, _mm_set1_epi8(0x20)));
            BlockMasks {
                eq: mask(_mm_cmpeq_epi8(v, _mm_set1_epi8(b'=' as i8))),
                lf: mask(lf),
                cr: mask(cr),
                blank: mask(_mm_or_si128(_mm_or_si128(graphic, lf), cr)) ^ 0xFFFF,
            }
        }
    }

    /// The line ends, `\n` or `\r`.
    #[inline(always)]
    fn ends(self) -> u32 {
        self.lf | self.cr
    }

    /// The line ends of `block` alone (SSE2: one load, two compares, one mask).
    #[inline(always)]
    fn line_ends(block: &[u8; 16]) -> u32 {
        use std::arch::x86_64::*;
        // SAFETY: as in `BlockMasks::of`.
        unsafe {
            let v = _mm_loadu_si128(block.as_ptr().cast());
            let ends = _mm_or_si128(
                _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\n' as i8)),
                _mm_cmpeq_epi8(v, _mm_set1_epi8(b'\r' as i8)),
            );
            _mm_movemask_epi8(ends) as u32
        }
    }
}

type In<'a> = &'a [u8];
type Res<'a, O> = IResult<In<'a>, O>;

/// Byte offset of `part` (a sub-slice of `base`) in `base`.
#[inline(always)]
fn offset(base: In<'_>, part: In<'_>) -> usize {
    part.as_ptr() as usize - base.as_ptr() as usize
}

const LO: u64 = 0x0101_0101_0101_0101;
const HI: u64 = 0x8080_8080_8080_8080;

/// The high bit of the first byte of `w` (in memory order) that equals `t` is set, and no bit
/// of an earlier byte (later bytes may be flagged wrongly; they do not matter).
#[inline(always)]
const fn eq_mask(w: u64, t: u8) -> u64 {
    let x = w ^ (LO * t as u64);
    x.wrapping_sub(LO) & !x & HI
}

/// The length of the longest prefix of `b` without any byte of `set`: what
/// `take_till(|c| set.contains(&c))` finds. On x86_64 sixteen bytes are compared at a time with
/// SSE2 (one compare per byte of `set`, one mask); the last bytes, and all of them elsewhere,
/// eight at a time in a `u64`.
#[inline(always)]
pub(crate) fn prefix_without<const N: usize>(b: In<'_>, set: [u8; N]) -> usize {
    let mut i = 0;
    // Most keys and values are shorter than sixteen bytes: one block finds their end, where
    // eight-byte words took two or three rounds (corpus pass: 61.2 -> 58.7 M instructions).
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    let b = {
        use std::arch::x86_64::*;
        let mut blocks = b.chunks_exact(16);
        for block in &mut blocks {
            let mut lo = [0u8; 8];
            let mut hi = [0u8; 8];
            lo.copy_from_slice(&block[..8]);
            hi.copy_from_slice(&block[8..]);
            // SAFETY: the intrinsics need SSE2, which every x86_64 processor has and the cfg
            // above checks is enabled; they read no memory (the block is loaded as two `u64`s).
            let bits = unsafe {
                let v = _mm_set_epi64x(i64::from_le_bytes(hi), i64::from_le_bytes(lo));
                let mut m = _mm_setzero_si128();
                for t in set {
                    m = _mm_or_si128(m, _mm_cmpeq_epi8(v, _mm_set1_epi8(t as i8)));
                }
                _mm_movemask_epi8(m) as u32
            };
            if bits != 0 {
                return i + bits.trailing_zeros() as usize;
            }
            i += 16;
        }
        blocks.remainder()
    };
    let mut words = b.chunks_exact(8);
    for chunk in &mut words {
        let mut w = [0u8; 8];
        w.copy_from_slice(chunk);
        let w = u64::from_le_bytes(w);
        let mut m = 0;
        for t in set {
            m |= eq_mask(w, t);
        }
        if m != 0 {
            return i + (m.trailing_zeros() / 8) as usize;
        }
        i += 8;
    }
    i + words.remainder().iter().position(|c| set.contains(c)).unwrap_or(words.remainder().len())
}

/// The nom parsers that take the bytes up to the first byte of a set (possibly none; they never
/// fail): nom's `take_till`, with a block-at-a-time scan, because every byte of a file passes
/// through them.
macro_rules! till {
    ($(#[$doc:meta])* $name:ident, $set:expr) => {
        $(#[$doc])*
        #[inline(always)]
        fn $name(input: In<'_>) -> Res<'_, In<'_>> {
            let n = prefix_without(input, $set);
            Ok((&input[n..], &input[..n]))
        }
    };
}

till!(
    /// The rest of a line: everything up to its line end.
    rest_of_line,
    [b'\n', b'\r']
);
till!(
    /// A key: everything up to the first `=` (or the line end, when the line is no entry).
    till_equals,
    [b'=', b'\n', b'\r']
);
till!(
    /// A section name: everything up to the first bracket (or the line end).
    till_bracket,
    [b']', b'[', b'\n', b'\r']
);

/// The nom parser that takes the single byte `b` (nom's `char`, for bytes: it compares one
/// byte and splits the input, with nothing that is not inlined).
#[inline(always)]
fn byte(b: u8) -> impl Fn(In<'_>) -> Res<'_, u8> {
    move |input| match input.split_first() {
        Some((&c, rest)) if c == b => Ok((rest, c)),
        _ => Err(nom::Err::Error(nom::error::Error::new(input, nom::error::ErrorKind::Char))),
    }
}

/// `\r\n`, `\n`, a lone `\r`, or the end of the file (a nom parser; it fails on anything else).
/// Once per line, so written as one match on the next two bytes rather than as
/// `alt((tag("\r\n"), tag("\n"), tag("\r"), eof))`, which compares byte slices four times.
#[inline(always)]
fn line_ending(input: In<'_>) -> Res<'_, LineEnding> {
    match input {
        [b'\r', b'\n', rest @ ..] => Ok((rest, LineEnding::CrLf)),
        [b'\n', rest @ ..] => Ok((rest, LineEnding::Lf)),
        [b'\r', rest @ ..] => Ok((rest, LineEnding::Cr)),
        [] => Ok((input, LineEnding::None)),
        _ => Err(nom::Err::Error(nom::error::Error::new(input, nom::error::ErrorKind::CrLf))),
    }
}

/// The content of the line that starts `input` (which is not empty): what it says, and the
/// input after it (at the line end). The first byte usually decides.
#[inline(always)]
fn line_content<'a>(text: &str, base: In<'a>, input: In<'a>) -> (In<'a>, LineKind) {
    // Most lines are entries whose key starts with a letter: one comparison sends them on (no
    // byte from `A` up, other than `[`, starts anything else), before a jump on the rest.
    if input[0] >= b'A' && input[0] != b'[' {
        return entry_or_other(text, base, input);
    }
    match input[0] {
        b'\n' | b'\r' => (input, LineKind::Blank),
        b';' | b'#' => comment(base, &input[1..]),
        b'[' => section_or_garbage(text, base, input),
        b' ' | b'\t' | 0x0B | 0x0C => {
            // Blanks before the first byte that decides the line's shape.
            let body =
                take_while::<_, _, nom::error::Error<In<'_>>>(is_blank).parse(input).map_or(input, |(body, _)| body);
            match body.first() {
                None | Some(b'\n' | b'\r') => (body, LineKind::Blank),
                Some(b';' | b'#') => comment(base, &body[1..]),
                Some(b'[') => section_or_garbage(text, base, body),
                Some(_) => entry_or_other(text, base, input),
            }
        }
        _ => entry_or_other(text, base, input),
    }
}

/// The comment text after `;` or `#`, to the line end.
#[inline(always)]
fn comment<'a>(base: In<'a>, text_part: In<'a>) -> (In<'a>, LineKind) {
    let (after, text) = rest_of_line(text_part).unwrap_or((text_part, text_part));
    (after, LineKind::Comment { text: span(base, text) })
}

/// The span of `part` (a sub-slice of `base`).
#[inline(always)]
fn span(base: In<'_>, part: In<'_>) -> Span {
    let start = offset(base, part);
    Span::new(start as u32, (start + part.len()) as u32)
}

/// `"[" name "]" trailing`, trailing up to the line end: a section header if a `]` closes the
/// name before any other `[`.
#[inline(always)]
fn section(input: In<'_>) -> Res<'_, (In<'_>, In<'_>)> {
    let (input, _) = byte(b'[')(input)?;
    let (input, name) = till_bracket(input)?;
    let (input, _) = byte(b']')(input)?;
    let (input, trailing) = rest_of_line(input)?;
    Ok((input, (name, trailing)))
}

/// A section header, or a garbage line that starts like one.
fn section_or_garbage<'a>(text: &str, base: In<'a>, body: In<'a>) -> (In<'a>, LineKind) {
    match section(body) {
        Ok((after, (name, trailing))) => {
            let kind = LineKind::Section { name: trim_part(text, base, name), trailing: span(base, trailing) };
            (after, kind)
        }
        Err(_) => (rest_of_line(body).map_or(body, |(after, _)| after), LineKind::Garbage),
    }
}

/// `key "=" value` at the first `=`, the value up to the line end.
#[inline(always)]
fn entry(input: In<'_>) -> Res<'_, (In<'_>, In<'_>)> {
    let (input, key) = till_equals(input)?;
    let (input, _) = byte(b'=')(input)?;
    let (input, value) = rest_of_line(input)?;
    Ok((input, (key, value)))
}

/// An entry (with a non-empty key); a line without `=` is blank if it holds only Unicode white
/// space (e.g. a no-break space), garbage otherwise.
#[inline(always)]
fn entry_or_other<'a>(text: &str, base: In<'a>, content: In<'a>) -> (In<'a>, LineKind) {
    match entry(content) {
        Ok((after, (key, value))) => {
            let key = trim_part(text, base, key);
            if key.is_empty() {
                (after, LineKind::Garbage)
            } else {
                (after, LineKind::Entry { key, value: trim_part(text, base, value) })
            }
        }
        Err(_) => {
            let (after, line) = rest_of_line(content).unwrap_or((content, content));
            let line = span(base, line);
            let blank = text[line.start as usize..line.end as usize].trim().is_empty();
            (after, if blank { LineKind::Blank } else { LineKind::Garbage })
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

/// The span of `part` (a sub-slice of `base`, the bytes of `text`, cut at char boundaries)
/// trimmed as [`str::trim`] trims it.
#[inline(always)]
fn trim_part(text: &str, base: In<'_>, part: In<'_>) -> Span {
    // Most keys and values have nothing to trim (decided on the part's own first and last
    // byte, with no index into the text to check).
    if let (Some(0x21..=0x7E), Some(0x21..=0x7E)) = (part.first(), part.last()) {
        return span(base, part);
    }
    let whole = span(base, part);
    let s = &text[whole.start as usize..whole.end as usize];
    let t = s.trim();
    // `trim` gives the empty string at the start for white space only.
    let off = whole.start as usize + (t.as_ptr() as usize - s.as_ptr() as usize);
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

    /// The block and word scans find what a byte loop finds, for every byte of the set at every
    /// offset of inputs up to 40 bytes long (two sixteen-byte blocks, then a word and single
    /// bytes), with bytes that differ from a target in one bit around it.
    #[test]
    fn prefix_scan_matches_a_byte_loop() {
        let naive = |b: &[u8], set: &[u8]| b.iter().position(|c| set.contains(c)).unwrap_or(b.len());
        for len in 0..40 {
            for pos in 0..=len {
                for &t in b"=\n\r][" {
                    let mut b: Vec<u8> = (0..len).map(|i| [b'a', t ^ 1, t ^ 0x80, 0, 0xFF][i % 5]).collect();
                    if pos < len {
                        b[pos] = t;
                    }
                    assert_eq!(prefix_without(&b, [b'=', b'\n', b'\r']), naive(&b, b"=\n\r"), "{b:?}");
                    assert_eq!(prefix_without(&b, [b']', b'[', b'\n', b'\r']), naive(&b, b"][\n\r"), "{b:?}");
                }
            }
        }
    }

    /// Walks `text` line by line as the reader does, trying the fast path `fast` first: every
    /// line it reads is what the general path makes of it (`agree` checks the two), both lexers
    /// then stand at the next line, and a line it leaves is left where it was. Returns how many
    /// lines the fast path read.
    fn check_fast_path<'t, T>(
        text: &'t str,
        fast: impl Fn(&mut Lexer<'t>) -> Option<T>,
        agree: impl Fn(&Line, &T),
    ) -> usize {
        let mut lexer = Lexer::new(text);
        let mut read = 0;
        loop {
            let mut general = lexer.clone();
            let Some(line) = general.next() else {
                assert!(fast(&mut lexer).is_none(), "{text:?}");
                break;
            };
            match fast(&mut lexer) {
                Some(t) => {
                    read += 1;
                    agree(&line, &t);
                    assert_eq!(lexer.rest.len(), general.rest.len(), "{text:?}");
                }
                // The fast path did not move; the general path reads the line.
                None => assert_eq!(lexer.next(), Some(line)),
            }
        }
        read
    }

    /// [`check_fast_path`] for the entry fast path.
    fn check_plain_entries(text: &str) -> usize {
        check_fast_path(text, Lexer::next_plain_entry, |line, e| {
            assert_eq!(line.kind, LineKind::Entry { key: e.key_span(), value: e.value_span() }, "{text:?}");
            let slice = |sp: Span| &text[sp.start as usize..sp.end as usize];
            assert_eq!((e.key, e.value), (slice(e.key_span()), slice(e.value_span())));
            assert_eq!(line.raw.end, e.end);
            assert_eq!(matches!(line.ending, LineEnding::Lf | LineEnding::CrLf), e.newline);
            assert!(e.newline || line.ending == LineEnding::None);
        })
    }

    /// [`check_fast_path`] for the section fast path.
    fn check_plain_sections(text: &str) -> usize {
        check_fast_path(text, Lexer::next_plain_section, |line, sec| {
            let trailing = Span::new(line.content.end, line.content.end);
            assert_eq!(line.kind, LineKind::Section { name: sec.name_span(), trailing }, "{text:?}");
            assert_eq!(sec.name, &text[sec.name_span().start as usize..sec.name_span().end as usize]);
            assert_eq!((line.raw.start, line.raw.end), (sec.start, sec.end));
            assert_eq!(matches!(line.ending, LineEnding::Lf | LineEnding::CrLf), sec.newline);
            assert!(sec.newline || line.ending == LineEnding::None);
        })
    }

    #[test]
    fn plain_sections_are_read_as_the_general_path_reads_them() {
        let text = "[FileInfo]\n[1018]\r\n[1018sub0]\r[a b]\n[ a]\n[a ]\n[]\n[x]y\n[x][y]\n [z]\n[\u{e4}]\n[a\u{e4}b]\n\
                    [a[b]\n[x]\r\r\n[last]";
        assert_eq!(check_plain_sections(text), 5);
        for text in ["[", "[]", "[a", "[a]", "[a]\r", "[a]\r\n", "[a] ", "[\u{3000}a]"] {
            check_plain_sections(text);
        }
    }

    #[test]
    fn empty_lines_are_read_as_the_general_path_reads_them() {
        for text in ["\n", "\r\n", "\r", "\r\r\n", " \n", "\nK=v", "\r\n\n[a]", "", "x\n"] {
            let mut fast = Lexer::new(text);
            let mut general = fast.clone();
            let line = general.next();
            match fast.next_empty_line() {
                Some(end) => {
                    let line = line.expect("a line");
                    assert_eq!(line.kind, LineKind::Blank, "{text:?}");
                    assert!(line.content.is_empty() && matches!(line.ending, LineEnding::Lf | LineEnding::CrLf));
                    assert_eq!(line.raw.end, end);
                    assert_eq!(fast.rest, general.rest);
                }
                None => {
                    assert!(line.is_none_or(|l| !l.content.is_empty() || l.ending == LineEnding::Cr), "{text:?}");
                    assert_eq!(fast.rest, text, "the lexer did not move");
                }
            }
        }
    }

    #[test]
    fn plain_entries_are_read_as_the_general_path_reads_them() {
        let text = "Key=Value\r\nKey = V\nK=\n[sec]\nKey=V\rX=1\nK\u{E9}=v\n Key=v\n=v\n~=x\nA=b c\nA= b\nA=b \nLast=1";
        // Plain: `Key=Value`, `K=`, `X=1` (after the lone `\r`), `~=x`, `A=b c`, `Last=1`.
        assert_eq!(check_plain_entries(text), 6);
        let mut lexer = Lexer::new("Key=V\rX=1");
        assert_eq!(lexer.next_plain_entry(), None, "a lone `\\r` is left to the general path");
        let mut lexer = Lexer::new("Last=1");
        assert_eq!(
            lexer.next_plain_entry(),
            Some(PlainEntry { key: "Last", value: "1", start: 0, end: 6, newline: false })
        );
        assert_eq!(lexer.next(), None);
        for n in 0..40 {
            // Keys and values across the sixteen-byte blocks of the scan.
            let key = "K".repeat(n + 1);
            let value = "v".repeat(n);
            assert_eq!(check_plain_entries(&format!("{key}={value}\r\n{key}={value}\n{key}={value}")), 3);
        }
        // Numbered keys (object lists) are plain too; lines that start with any other byte
        // below `A` are left to the general path.
        let text = "1=0x1000\n12=0x1001\r\n0=x\n9 =x\n$=x\n!=x\n;c=x\n#c=x\n[=x\n\t1=x\n";
        assert_eq!(check_plain_entries(text), 3);
        for b in 0..=255u8 {
            let line = [b, b'=', b'v'];
            let expect = b.is_ascii_digit() || (b'A'..=b'~').contains(&b) && b != b'[';
            if let Ok(text) = std::str::from_utf8(&line) {
                assert_eq!(check_plain_entries(text), expect as usize, "{text:?}");
            }
        }
    }

    /// Lines whose key and value end at every position around the ends of the first and second
    /// sixteen-byte blocks, with each kind of byte in turn at the end of the key, the start of
    /// the value and its end (bytes that need trimming and bytes that do not), and each line
    /// end, far from the end of the text (read in blocks) and at it (byte by byte): the fast
    /// path reads each as the general path does, and reads all those that need no trimming.
    #[test]
    fn plain_entries_across_block_ends() {
        let bytes = ['v', ' ', '\t', '\x0B', '\x7F', '~', '!', '\u{e9}', '\u{a0}', '=', '[', '#'];
        for key_len in [1, 2, 13, 14, 15, 16, 17, 18, 30, 31, 32] {
            for value_len in [0, 1, 2, 3, 13, 14, 15, 16, 17, 29, 30, 31, 32, 33] {
                for (which, &b) in (0..3).flat_map(|w| bytes.iter().map(move |b| (w, b))) {
                    let (mut key_end, mut first, mut last) = ('K', 'v', 'w');
                    *[&mut key_end, &mut first, &mut last][which] = b;
                    let mut key: String = "K".repeat(key_len - 1);
                    key.push(key_end);
                    let mut value = String::new();
                    if value_len > 0 {
                        value.push(first);
                    }
                    if value_len > 1 {
                        value.push_str(&"w".repeat(value_len - 2));
                        value.push(last);
                    }
                    let plain = [key_end, first, last].iter().all(|&c| c.is_ascii_graphic())
                        && !value.contains('=')
                        && (value_len > 0 || which != 1)
                        && (value_len > 1 || which != 2)
                        && PLAIN_FIRST[key.as_bytes()[0] as usize];
                    for ending in ["\n", "\r\n", "\r", "\r\r\n", ""] {
                        let line = format!("{key}={value}{ending}");
                        let read = check_plain_entries(&format!("{line}Pad=1\nPad=2\nPad=3\nPad=4\nPad=5\n"));
                        if plain && (ending == "\n" || ending == "\r\n") && !key.contains('=') {
                            assert_eq!(read, 6, "{line:?}");
                        }
                        check_plain_entries(&line);
                        check_plain_entries(&format!("A=1\n{line}"));
                    }
                }
            }
        }
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
        fn plain_entries_agree_with_the_general_path(text in "([ \t\x0B\x0C\u{A0}\u{85}\u{3000}]|\\PC|\r|\n|\\[|\\]|=|;|#|[a-zA-Z]){0,200}") {
            check_plain_entries(&text);
            check_plain_sections(&text);
        }

        /// The same, with every line at least sixteen bytes before the end of the text, where
        /// the fast path reads whole blocks (and lines that run into the padding).
        #[test]
        fn plain_entries_agree_with_the_general_path_in_blocks(
            text in "([ \t\x0B\x0C\u{A0}\u{85}\u{3000}]|\\PC|\r|\n|\\[|\\]|=|;|#|[a-zA-Z]){0,200}",
            pad in "(=|\r|\n|[a-z ]){16,40}",
        ) {
            check_plain_entries(&format!("{text}{pad}"));
            check_plain_entries(&format!("{text}\n{pad}"));
        }

        #[test]
        fn agrees_with_the_reference_on_eds_like_lines(
            lines in proptest::collection::vec("[ \t\u{A0}]{0,2}(\\[[0-9A-Fa-fsub ]{0,10}\\]|[A-Za-z]{1,14}[ \t]?=[ \t]?[0-9a-zA-Z$+ ;#]{0,12}|;.{0,5}|#.{0,3})[ \t\u{A0}]{0,2}", 0..40),
            ending in "\r\n|\n|\r",
        ) {
            check_against_reference(&lines.join(&ending));
            check_plain_entries(&lines.join(&ending));
            check_plain_entries(&format!("{}{ending}{}", lines.join(&ending), "Pad=1\n".repeat(4)));
            check_plain_sections(&lines.join(&ending));
        }
    }
}
