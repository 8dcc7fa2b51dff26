//! Pass 1: lines → sections with classified names, and syntax-level diagnostics.
//!
//! Every entry of the file is copied once, into one `Vec` in which the entries of each section
//! are contiguous (entries of a repeated section are moved next to those of its first
//! occurrence), so that a [`Section`] is a borrowed slice and nothing later allocates per entry.

use super::{Crumbs, Ctx, FastMap};
use crate::ast::{Document, LineEnding, LineKind};
use crate::codes;
use crate::model::Category;
use crate::source::{Encoding, LineCol, Span};

/// One `key=value` entry: its key and value, slices of the source text ([`Kv::key`],
/// [`Kv::value`]), in 20 bytes: where the key starts, its length, how far after it the value
/// starts and the value's length (a text's positions are `u32`, as its [`Span`]s are). Their
/// spans follow from where they lie in the text ([`Kv::key_span`]), and the occurrence of a
/// repeated section an entry came from from where the section's headers lie
/// ([`report_duplicate`]). The entries of a file, which pass 1 writes and every later pass
/// reads, are the largest buffer lowering writes, about twice the size of the file with 32
/// bytes an entry (two `&str`), all of it fresh memory (a page fault every 4 KiB) for the
/// first (largest) file a process reads, and again on each thread that reads files.
#[derive(Clone, Copy)]
#[repr(C, packed(4))]
pub(crate) struct Kv<'a> {
    /// The first byte of the key.
    key_at: *const u8,
    key_len: u32,
    /// The value starts this many bytes after the key.
    value_off: u32,
    value_len: u32,
    text: std::marker::PhantomData<&'a str>,
}

const _: () = assert!(std::mem::size_of::<Kv<'_>>() == 20);

impl<'a> Kv<'a> {
    /// An entry whose key and value are `key` and `value` of `text` (spans of the same text;
    /// a span that does not fit it gives an empty slice of it; a value before its key, which
    /// no line has, an empty one after the key).
    pub fn new(text: &'a str, key: Span, value: Span) -> Self {
        let slice = |s: Span| {
            let (start, end) = (s.start as usize, s.end as usize);
            text.get(start..end).or_else(|| text.get(start..start)).unwrap_or(&text[text.len()..])
        };
        let key = slice(key);
        let mut value = slice(value);
        if (value.as_ptr() as usize) < key.as_ptr() as usize {
            value = &key[key.len()..];
        }
        Kv::of(key, value)
    }

    /// The entry of `key` and `value`, slices of one text, the value not before the key (as
    /// on every line, where the key comes before the `=` and the value after it). A key or a
    /// value that does not fit the entry's `u32`s (in a text of 4 GiB or more, which
    /// `eds::read_file` refuses but `eds::parse` is given) makes an entry of an empty key and
    /// value at the key's start: wrong, as the positions of such a text are anyway (spans are
    /// `u32`), but never a slice of anything but the text.
    #[inline(always)]
    pub fn of(key: &'a str, value: &'a str) -> Self {
        let value_off = (value.as_ptr() as usize).wrapping_sub(key.as_ptr() as usize);
        if (key.len() | value_off | value.len()) > u32::MAX as usize {
            return Kv::empty_at(key);
        }
        Kv {
            key_at: key.as_ptr(),
            key_len: key.len() as u32,
            value_off: value_off as u32,
            value_len: value.len() as u32,
            text: std::marker::PhantomData,
        }
    }

    /// [`Kv::of`] of what does not fit an entry: an empty key and value at the key's start.
    #[cold]
    #[inline(never)]
    fn empty_at(key: &'a str) -> Self {
        Kv { key_at: key.as_ptr(), key_len: 0, value_off: 0, value_len: 0, text: std::marker::PhantomData }
    }

    /// The key.
    #[inline(always)]
    pub fn key(&self) -> &'a str {
        let (at, len) = (self.key_at, self.key_len as usize);
        // SAFETY: `at` and `len` are the address and length of a `&'a str` ([`Kv::of`]).
        unsafe { std::str::from_utf8_unchecked(std::slice::from_raw_parts(at, len)) }
    }

    /// The value.
    #[inline(always)]
    pub fn value(&self) -> &'a str {
        let (at, off, len) = (self.key_at, self.value_off as usize, self.value_len as usize);
        // SAFETY: the value is a `&'a str` that starts `off` bytes after the key's first byte,
        // in the same text, and is `len` bytes long ([`Kv::of`]): `at + off` is its address.
        unsafe { std::str::from_utf8_unchecked(std::slice::from_raw_parts(at.add(off), len)) }
    }

    /// The span of the key in `text`, the text it is a slice of.
    #[inline]
    pub fn key_span(&self, text: &str) -> Span {
        span_in(text, self.key())
    }

    /// The span of the value in `text`, the text it is a slice of.
    #[inline]
    pub fn value_span(&self, text: &str) -> Span {
        span_in(text, self.value())
    }
}

impl std::fmt::Debug for Kv<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Kv").field("key", &self.key()).field("value", &self.value()).finish()
    }
}

/// The span of `part`, a slice of `text`, in `text` (the distance of their addresses is its
/// start).
#[inline]
fn span_in(text: &str, part: &str) -> Span {
    let start = (part.as_ptr() as usize).wrapping_sub(text.as_ptr() as usize) as u32;
    Span::new(start, start.wrapping_add(part.len() as u32))
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

impl Kind {
    /// The kind as one number (its index, variant and sub-index packed together, in this
    /// order), by which the sections are found: one word to compare, where the derived `Hash`
    /// and `Eq` of the enum took its fields one by one. The index comes first so that the
    /// sections of a file that lists its objects in ascending order come in ascending order of
    /// key (an object, its sub-objects, then its name, value and link sections).
    #[inline]
    pub fn key(self) -> u32 {
        let (tag, index, sub): (u32, u16, u8) = match self {
            Kind::FileInfo => (0, 0, 0),
            Kind::DeviceInfo => (1, 0, 0),
            Kind::DummyUsage => (2, 0, 0),
            Kind::Comments => (3, 0, 0),
            Kind::List(c) => (4, c as u16, 0),
            Kind::Commissioning => (5, 0, 0),
            Kind::Object(i) => (6, i, 0),
            Kind::Sub(i, s) => (7, i, s),
            Kind::Names(i) => (8, i, 0),
            Kind::Values(i) => (9, i, 0),
            Kind::Links(i) => (10, i, 0),
            Kind::Unknown => (11, 0, 0),
        };
        (index as u32) << 16 | tag << 8 | sub as u32
    }

    /// The slot of a section kind that a file has at most one of (the information sections
    /// and the object lists) in [`KindIndex`]'s table.
    #[inline]
    fn fixed_slot(self) -> Option<usize> {
        Some(match self {
            Kind::FileInfo => 0,
            Kind::DeviceInfo => 1,
            Kind::DummyUsage => 2,
            Kind::Comments => 3,
            Kind::List(Category::Mandatory) => 4,
            Kind::List(Category::Optional) => 5,
            Kind::List(Category::Manufacturer) => 6,
            Kind::Commissioning => 7,
            _ => return None,
        })
    }
}

/// The sections of a file by kind ([`Kind::Unknown`] excepted): the information sections and
/// object lists in a table of their own, the object sections (objects, sub-objects, name,
/// value and link sections) by [`Kind::key`] in a vector that stays sorted while the file
/// gives them in ascending order, as nearly every file does (then a section is entered at the
/// end, or found again, without hashing), and in a hash map from the first that comes out of
/// order on.
#[derive(Default)]
pub(crate) struct KindIndex {
    fixed: [Option<u32>; 8],
    sorted: Vec<(u32, u32)>,
    /// The number of sections the file is expected to have at most (the hash map's room).
    expected: usize,
    hashed: FastMap<u32, u32>,
    /// Whether the object sections are in `hashed` (else in `sorted`).
    is_hashed: bool,
}

impl KindIndex {
    /// Empties the index (keeping its memory) for a file of about `n` sections (the room the
    /// hash map is given when the sections come out of order), with room in
    /// the sorted vector for `room` (an emptied vector too small is replaced, not grown: growing
    /// would copy its old block onto fresh pages).
    fn reset(&mut self, n: usize, room: usize) {
        self.fixed = [None; 8];
        self.sorted = with_room(std::mem::take(&mut self.sorted), n.max(room));
        self.expected = n;
        self.hashed.clear();
        self.is_hashed = false;
    }

    /// The number of the section of `kind`; if there is none yet, `next` becomes its number
    /// (and `None` is returned).
    #[inline(always)]
    fn enter(&mut self, kind: Kind, next: usize) -> Option<usize> {
        let next = next as u32;
        if let Some(slot) = kind.fixed_slot() {
            return match self.fixed[slot] {
                Some(i) => Some(i as usize),
                None => {
                    self.fixed[slot] = Some(next);
                    None
                }
            };
        }
        let key = kind.key();
        if !self.is_hashed {
            match self.sorted.last() {
                Some(&(last, _)) if last >= key => match self.sorted.binary_search_by_key(&key, |&(k, _)| k) {
                    Ok(at) => return Some(self.sorted[at].1 as usize),
                    Err(_) => {
                        // Out of order: hashed from now on (a sorted insertion would move the
                        // later sections each time).
                        self.hashed.reserve(self.expected.max(self.sorted.len()));
                        self.hashed.extend(self.sorted.drain(..));
                        self.is_hashed = true;
                    }
                },
                _ => {
                    self.sorted.push((key, next));
                    return None;
                }
            }
        }
        match self.hashed.entry(key) {
            std::collections::hash_map::Entry::Occupied(e) => Some(*e.get() as usize),
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(next);
                None
            }
        }
    }

    /// The number of the section of `kind`.
    fn get(&self, kind: Kind) -> Option<usize> {
        if let Some(slot) = kind.fixed_slot() {
            return self.fixed[slot].map(|i| i as usize);
        }
        let key = kind.key();
        let i = if self.is_hashed {
            *self.hashed.get(&key)?
        } else {
            self.sorted[self.sorted.binary_search_by_key(&key, |&(k, _)| k).ok()?].1
        };
        Some(i as usize)
    }
}

/// A section, with the entries of all its occurrences (duplicates are merged).
#[derive(Debug)]
pub(crate) struct Section<'a> {
    pub name: &'a str,
    pub name_span: Span,
    /// Where the name starts (what [`crate::source::SourceFile::line_col`] says, found while
    /// reading the lines in order instead of by a search).
    pub at: LineCol,
    pub kind: Kind,
    pub entries: &'a [Kv<'a>],
}

/// All sections in file order (of first occurrence), with a lookup by kind.
pub(crate) struct Sections<'a> {
    pub list: Vec<Section<'a>>,
    /// The source text the sections' names and entries are slices of.
    pub text: &'a str,
    by_kind: &'a KindIndex,
}

impl<'a> Sections<'a> {
    /// The section of a kind (not for [`Kind::Unknown`]).
    pub fn get(&self, kind: Kind) -> Option<&Section<'a>> {
        self.by_kind.get(kind).map(|i| &self.list[i])
    }
}

/// A section as [`collect`] finds it: its entries are a range of [`Collected::entries`].
pub(crate) struct Head<'a> {
    name: &'a str,
    name_span: Span,
    at: LineCol,
    kind: Kind,
    entries: std::ops::Range<usize>,
}

/// What pass 1 found: the entries of all sections (each section's contiguous) and the sections.
/// [`Collected::sections`] gives the view the other passes use.
pub(crate) struct Collected<'a> {
    text: &'a str,
    entries: Vec<Kv<'a>>,
    heads: Vec<Head<'a>>,
    /// The sections by kind.
    by_kind: KindIndex,
}

/// The buffers pass 1 fills, kept from one file to the next by a [`crate::Reader`]: a process
/// reading many files then reuses their memory rather than touching fresh pages for each file
/// (each a page fault, a good part of a short run's cost), and the vectors, already as large as
/// an earlier file needed, seldom grow.
#[derive(Default)]
pub(crate) struct Scratch {
    entries: Vec<Kv<'static>>,
    heads: Vec<Head<'static>>,
    by_kind: KindIndex,
    /// The line index, which goes to the file's [`crate::source::SourceFile`]; given back
    /// with the file ([`crate::Reader::recycle`]).
    pub line_starts: Vec<u32>,
    /// The diagnostics of a file given back, emptied: the next file's are put there.
    pub diags: Vec<crate::Diagnostic>,
    /// The buffers are made with room for a file of at least this many bytes: a buffer that
    /// grows is replaced, and its replacement's pages are fresh again, while room that is never
    /// written costs no memory (only address space).
    pub room_for: usize,
}

impl Scratch {
    /// Keeps the buffers of `collected` (emptied) for the next file, and the allocation of
    /// its list of sections (made from its heads' by [`Collected::sections`]) for the heads.
    pub fn keep(&mut self, collected: Collected<'_>, sections: Vec<Head<'static>>) {
        let Collected { entries, heads, by_kind, .. } = collected;
        self.entries = reuse(entries);
        self.heads = if sections.capacity() >= heads.capacity() { sections } else { reuse(heads) };
        self.by_kind = by_kind;
    }
}

/// An empty vector on the allocation of `v`, for elements of another type of the same size and
/// alignment (the same type with another lifetime: how a buffer of items borrowed from one
/// file's text is kept for the next file). The standard library collects a vector's iterator
/// into its own allocation when the layouts agree (`reuse_keeps_the_allocation` holds that
/// true); were it ever not to, this would only allocate anew.
pub(crate) fn reuse<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().filter_map(|_| None).collect()
}

/// `v` emptied, with room for at least `n` elements: a buffer too small is replaced, not grown
/// (growing an empty vector would copy its whole old allocation: bytes that mean nothing, on
/// fresh pages).
pub(crate) fn with_room<T>(mut v: Vec<T>, n: usize) -> Vec<T> {
    v.clear();
    if v.capacity() < n {
        v = Vec::with_capacity(n);
    }
    v
}

impl<'d> Collected<'d> {
    /// The sections, borrowing their entries. The list is made on the heads' own allocation (a
    /// head and a section have one layout: the range of entries becomes the slice), so it
    /// touches no fresh memory; [`Scratch::keep`] takes it back.
    pub fn sections(&mut self) -> Sections<'_> {
        let heads = std::mem::take(&mut self.heads);
        let this: &Self = self;
        let list = heads
            .into_iter()
            .map(|h| Section {
                name: h.name,
                name_span: h.name_span,
                at: h.at,
                kind: h.kind,
                entries: &this.entries[h.entries],
            })
            .collect();
        Sections { list, text: this.text, by_kind: &this.by_kind }
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

/// Whether a byte counts when [`loose_eq`] compares names.
const fn significant(c: u8) -> bool {
    !matches!(c, b' ' | b'_' | b'-' | b'\t')
}

/// The number of bytes of `s` that [`loose_eq`] compares.
const fn significant_len(s: &[u8]) -> usize {
    let (mut n, mut i) = (0, 0);
    while i < s.len() {
        if significant(s[i]) {
            n += 1;
        }
        i += 1;
    }
    n
}

/// Whether `a` and `b` are equal ignoring ASCII case and the characters ` `, `_` and `-`.
pub(crate) fn loose_eq(a: &str, b: &str) -> bool {
    let significant = |c: &u8| significant(*c);
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

fn hex4(s: &[u8]) -> Option<u16> {
    let mut v = 0u16;
    for &b in s.get(..4)? {
        v = v << 4 | (b as char).to_digit(16)? as u16;
    }
    Some(v)
}

/// Classifies a section name (what [`collect`] does, with [`exact_object`] first).
#[cfg(test)]
pub(crate) fn classify(name: &str) -> (Kind, Spelling) {
    match exact_object(name.as_bytes()) {
        Some(kind) => (kind, Spelling::Exact),
        None => classify_general(name),
    }
}

/// The kind of the commonest section names, object and sub-object sections spelled as CiA 306
/// spells them: `IIII` or `IIIIsubS` with four upper-case hex digits and one or two for the
/// sub-index (what [`classify_general`] finds for them, without its general rules). `None` for
/// any other name.
#[inline(always)]
fn exact_object(name: &[u8]) -> Option<Kind> {
    let digit = |b: u8| match b {
        b'0'..=b'9' => Some((b - b'0') as u16),
        b'A'..=b'F' => Some((b - b'A' + 10) as u16),
        _ => None,
    };
    let (index, rest) = match name {
        [a, b, c, d, rest @ ..] => (digit(*a)? << 12 | digit(*b)? << 8 | digit(*c)? << 4 | digit(*d)?, rest),
        _ => return None,
    };
    match rest {
        [] => Some(Kind::Object(index)),
        [b's', b'u', b'b', s] => Some(Kind::Sub(index, digit(*s)? as u8)),
        [b's', b'u', b'b', s, t] => Some(Kind::Sub(index, (digit(*s)? << 4 | digit(*t)?) as u8)),
        _ => None,
    }
}

/// [`classify`] by the general rules.
fn classify_general(name: &str) -> (Kind, Spelling) {
    if let Some(index) = hex4(name.as_bytes()) {
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

/// Classifies a section name that starts with four hex digits (`index`). The CiA 306 spelling
/// is only built when the name differs from it.
fn classify_object(name: &str, index: u16) -> (Kind, Spelling) {
    // Hex digits (all ASCII) are canonical in upper case.
    let upper = |s: &str| !s.bytes().any(|b| b.is_ascii_lowercase());
    let rest = &name[4..];
    let index_exact = upper(&name[..4]);
    let spelled = |kind: Kind, exact: bool, canon: &dyn Fn() -> String| {
        if exact { (kind, Spelling::Exact) } else { (kind, Spelling::Case(canon())) }
    };
    if rest.is_empty() {
        return spelled(Kind::Object(index), index_exact, &|| super::hex4(index));
    }
    if rest.len() >= 3 && rest.is_char_boundary(3) && rest[..3].eq_ignore_ascii_case("sub") {
        let digits = &rest[3..];
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
            return (Kind::Unknown, Spelling::Malformed(format!("`{digits}` is not a hexadecimal sub-index")));
        }
        let trimmed = &digits[digits.bytes().take_while(|&b| b == b'0').count()..];
        if trimmed.len() > 2 {
            return (Kind::Unknown, Spelling::Malformed(format!("sub-index 0x{digits} is larger than 0xFF")));
        }
        let sub = trimmed.bytes().fold(0u8, |v, b| v << 4 | (b as char).to_digit(16).unwrap_or(0) as u8);
        let exact = index_exact && &rest[..3] == "sub" && upper(digits);
        // (`digits` are ASCII hex digits.)
        let canon = || {
            let mut s = super::hex4(index);
            s.push_str("sub");
            s.extend(digits.bytes().map(|b| char::from(b.to_ascii_uppercase())));
            s
        };
        return spelled(Kind::Sub(index, sub), exact, &canon);
    }
    for (suffix, kind) in
        [("Name", Kind::Names(index)), ("Value", Kind::Values(index)), ("ObjectLinks", Kind::Links(index))]
    {
        if rest.eq_ignore_ascii_case(suffix) {
            return spelled(kind, index_exact && rest == suffix, &|| super::hex4(index) + suffix);
        }
    }
    (Kind::Unknown, Spelling::Exact)
}

/// The name of a section of unknown kind in ASCII lower case, as a map key. Debug builds count
/// the comparisons of two keys ([`name_comparisons`]), so that a test can hold the grouping of
/// sections to a bounded number per section, whatever the file.
#[derive(Eq)]
struct NameKey(String);

impl std::hash::Hash for NameKey {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        self.0.hash(state);
    }
}

impl PartialEq for NameKey {
    fn eq(&self, other: &Self) -> bool {
        #[cfg(debug_assertions)]
        NAME_COMPARISONS.with(|c| c.set(c.get() + 1));
        self.0 == other.0
    }
}

#[cfg(debug_assertions)]
thread_local! {
    static NAME_COMPARISONS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// How many times this thread compared two names of unknown sections while grouping sections
/// (debug builds; 0 in release builds, which do not count).
#[doc(hidden)]
pub fn name_comparisons() -> u64 {
    #[cfg(debug_assertions)]
    return NAME_COMPARISONS.with(|c| c.get());
    #[cfg(not(debug_assertions))]
    0
}

/// Groups the document's lines into sections and reports line-level problems.
pub(crate) fn collect<'a>(doc: &'a Document, cx: &mut Ctx<'_>, scratch: &mut Scratch) -> Collected<'a> {
    let src = &doc.source;
    if matches!(src.encoding, Encoding::Utf16Le | Encoding::Utf16Be) {
        let order = if src.encoding == Encoding::Utf16Le { "little" } else { "big" };
        cx.emit(
            codes::E0010,
            None,
            format!("file is UTF-16 ({order}-endian, with a byte-order mark); it was decoded as such"),
        )
        .hint = Some("save the file as UTF-8 (or plain ASCII, as CiA 306 asks); `odgen fmt` writes it so".into());
        if src.invalid_units > 0 {
            cx.emit(
                codes::E0011,
                None,
                format!("{} code unit(s) are not valid UTF-16; each was read as U+FFFD", src.invalid_units),
            )
            .hint = Some("the file is damaged or not UTF-16: check how it was saved".into());
        }
    } else if src.encoding == Encoding::Windows1252 {
        cx.emit(codes::E0001, None, "file is not valid UTF-8; it was decoded as Windows-1252").hint =
            Some("save the file as UTF-8 (or plain ASCII, as CiA 306 asks)".into());
    } else if let Some(pos) = src.first_non_ascii() {
        let ch_len = src.text[pos..].chars().next().map(char::len_utf8).unwrap_or(1);
        cx.emit(codes::E0009, Some(Span::new(pos as u32, (pos + ch_len) as u32)), "the file contains non-ASCII text")
            .hint = Some("CiA 306 files are ASCII; tools that expect it may misread this text".into());
    }
    // Sized so that nothing grows while the lines are read: the corpus has a line every 15
    // bytes, an entry line every 20 and a section every 120 on average, and its densest files a
    // line every 12.4 bytes and a section every 68; these bounds hold for every file of it (one
    // that exceeds them grows once or twice). Not much more: these lists are twice the text's
    // size, and an allocator that packs blocks densely fills memory with room never written.
    let text = &src.text;
    let sections = text.len() / 64 + 8;
    let room = text.len().max(scratch.room_for);
    let mut heads: Vec<Head<'a>> = with_room(reuse(std::mem::take(&mut scratch.heads)), room / 64 + 8);
    let mut by_kind = std::mem::take(&mut scratch.by_kind);
    // (The hash map of sections, for files whose sections are not in order, a third of the
    // corpus, is sized for about as many sections as a file has on average, not at most: its
    // buckets are written all over, so that each page of a map sized for 2.5 times the
    // sections is touched all the same, and a map too small only grows once; the rounding of
    // its size to a power of two leaves room for the denser files.)
    by_kind.reset(text.len() / 128 + 8, room / 64 + 8);
    // Sections of unknown kind, by name in ASCII lower case (names are matched ignoring ASCII
    // case). Real files have few; a file of many must not cost a scan of all the others each,
    // and the names are the file's choice: the standard (keyed) hasher, not `FastMap`'s.
    let mut unknown: std::collections::HashMap<NameKey, usize> = std::collections::HashMap::new();
    let mut entries: Vec<Kv<'a>> = with_room(reuse(std::mem::take(&mut scratch.entries)), room / 12 + 8);
    // Each section header starts a run of entries: (section, first entry, where the header's
    // name starts). A run ends where the next begins. Until a section is repeated, each run is
    // a section of its own, in order, and is kept in the section's head (the first entry in
    // the start of its range; the header in its name's span): the list of runs is only made
    // (from the heads) when a section comes again, which few files have.
    let mut runs: Vec<(u32, u32, u32)> = Vec::new();
    let mut repeated = false;
    // Whether the following entries belong to a section.
    let mut current = false;
    // The start of every line (lines end at `\n`, `\r\n` or a lone `\r`, for positions as for
    // the lexer), handed to the source for its diagnostics; its length is the number of the
    // current line.
    let mut line_starts: Vec<u32> = with_room(std::mem::take(&mut scratch.line_starts), room / 10 + 2);
    line_starts.push(0);
    // Enters the section named `name` (a span; `name_str` its text), whose name starts in
    // column `col` (evaluated only for a section not seen before): shared by the section fast
    // path and the general one.
    macro_rules! enter_section {
        ($name:expr, $name_str:expr, $col:expr) => {{
            let (name, name_str): (Span, &'a str) = ($name, $name_str);
            // Object and sub-object names spelled as CiA 306 spells them need neither the
            // general rules nor a spelling to report.
            let kind = match exact_object(name_str.as_bytes()) {
                Some(kind) => kind,
                None => {
                    let (kind, spelling) = classify_general(name_str);
                    report_spelling(cx, name, name_str, &spelling);
                    kind
                }
            };
            // A new section of a known kind is entered under the number it is about to get
            // (one hash and one probe, where a look-up and an insertion took two).
            let existing = match kind {
                Kind::Unknown => match unknown.entry(NameKey(name_str.to_ascii_lowercase())) {
                    std::collections::hash_map::Entry::Occupied(e) => Some(*e.get()),
                    std::collections::hash_map::Entry::Vacant(e) => {
                        e.insert(heads.len());
                        None
                    }
                },
                k => by_kind.enter(k, heads.len()),
            };
            let first = entries.len();
            match existing {
                Some(i) => {
                    if !repeated {
                        repeated = true;
                        runs = runs_of_heads(&heads, sections);
                    }
                    section_again(cx, name, name_str, heads[i].at.line);
                    runs.push((i as u32, first as u32, name.start));
                }
                None => {
                    let i = heads.len();
                    let at = LineCol { line: line_starts.len() as u32, col: $col };
                    heads.push(Head { name: name_str, name_span: name, at, kind, entries: first..first });
                    if repeated {
                        runs.push((i as u32, first as u32, name.start));
                    }
                }
            }
            current = true;
        }};
    }
    // The lines are taken from the lexer one at a time; none is kept. Most lines are plain
    // entries inside a section: the lexer reads those on a shorter path of their own.
    let mut lexer = crate::lex::Lexer::new(text);
    loop {
        if current && let Some(e) = lexer.next_plain_entry() {
            entries.push(Kv::of(e.key, e.value));
            if e.newline {
                line_starts.push(e.end);
            }
            continue;
        }
        // Empty lines (one between sections, as most files write them) need no more than
        // their end.
        if let Some(end) = lexer.next_empty_line() {
            line_starts.push(end);
            continue;
        }
        // Section headers `[Name]` with nothing to trim or after them, most of the others.
        if let Some(sec) = lexer.next_plain_section() {
            // (The name starts in column 2, after the `[` that starts the line.)
            enter_section!(sec.name_span(), sec.name, 2);
            if sec.newline {
                line_starts.push(sec.end);
            }
            continue;
        }
        let Some(line) = lexer.next() else { break };
        // Entries in a section are most lines: tested first, on their own, before a jump on
        // the kind of the others.
        if let LineKind::Entry { key, value } = line.kind
            && current
        {
            entries.push(Kv::new(&src.text, key, value));
        } else {
            match line.kind {
                // (An entry here has no section.)
                LineKind::Entry { key, .. } => entry_outside(cx, line.content, src.slice(key)),
                LineKind::Section { name, trailing } => {
                    let name_str = src.slice(name);
                    if !trailing.is_empty() {
                        text_after_header(cx, trailing, src.slice(trailing), name_str);
                    }
                    let col = || char_count(src.slice(Span::new(line.raw.start, name.start))) + 1;
                    enter_section!(name, name_str, col());
                }
                LineKind::Comment { text } => {
                    if text.start > 0 && src.text.as_bytes().get(text.start as usize - 1) == Some(&b'#') {
                        hash_comment(cx, Span::new(text.start - 1, text.start));
                    }
                }
                LineKind::Garbage => garbage_line(cx, line.content, src.slice(line.content)),
                LineKind::Blank => {}
            }
        }
        match line.ending {
            LineEnding::Lf | LineEnding::CrLf | LineEnding::Cr => line_starts.push(line.raw.end),
            LineEnding::None => {}
        }
    }
    src.set_line_starts(line_starts);
    let run_end = |r: usize| runs.get(r + 1).map_or(entries.len(), |&(_, start, _)| start as usize);
    if !repeated {
        // Every section has exactly one run, in order, which ends where the next begins.
        let mut end = entries.len();
        for h in heads.iter_mut().rev() {
            h.entries.end = end;
            end = h.entries.start;
        }
    } else {
        // Move the entries of each section's runs together, sections in order of first
        // occurrence, runs (and entries) in file order.
        let mut runs_of: Vec<Vec<usize>> = vec![Vec::new(); heads.len()];
        for (r, &(i, _, _)) in runs.iter().enumerate() {
            runs_of[i as usize].push(r);
        }
        let mut grouped = Vec::with_capacity(entries.len());
        for (i, rs) in runs_of.iter().enumerate() {
            let start = grouped.len();
            for &r in rs {
                grouped.extend_from_slice(&entries[runs[r].1 as usize..run_end(r)]);
            }
            heads[i].entries = start..grouped.len();
        }
        entries = grouped;
        cx.header_starts = runs.iter().map(|&(_, _, at)| at).collect();
    }
    Collected { text, entries, heads, by_kind }
}

/// The runs of entries of `heads`, each section one run, in order (what `collect` lists until
/// a section is repeated), with room for `room` runs.
#[cold]
fn runs_of_heads(heads: &[Head<'_>], room: usize) -> Vec<(u32, u32, u32)> {
    let mut runs = Vec::with_capacity(room.max(heads.len() + 1));
    runs.extend(heads.iter().enumerate().map(|(i, h)| (i as u32, h.entries.start as u32, h.name_span.start)));
    runs
}

// The reports of pass 1 that few lines need, kept out of its loop over the lines (whose
// common paths then keep more of their values in registers).

/// E0003: an entry before any section header.
#[cold]
#[inline(never)]
fn entry_outside(cx: &mut Ctx<'_>, line: Span, key: &str) {
    let d = cx.emit(codes::E0003, Some(line), format!("entry `{key}` comes before any section header and is ignored"));
    d.hint = Some("move it into the section it belongs to".into());
}

/// E0005: text after a section header (`trailing`, its text `text`), unless a comment.
#[cold]
#[inline(never)]
fn text_after_header(cx: &mut Ctx<'_>, trailing: Span, text: &str, name: &str) {
    let trailing_str = text.trim();
    if !trailing_str.is_empty() && !trailing_str.starts_with(';') {
        let d = cx.emit(
            codes::E0005,
            Some(trailing),
            format!("unexpected text `{trailing_str}` after section header [{name}]"),
        );
        d.hint = Some("put comments on their own line, starting with `;`".into());
    }
}

/// E0004: a comment that starts with `#` (at `hash`).
#[cold]
#[inline(never)]
fn hash_comment(cx: &mut Ctx<'_>, hash: Span) {
    cx.emit(codes::E0004, Some(hash), "comment starts with `#`").hint = Some("CiA 306 comments start with `;`".into());
}

/// E0002: a line that is nothing CiA 306 knows (`content`, its text `text`).
#[cold]
#[inline(never)]
fn garbage_line(cx: &mut Ctx<'_>, content: Span, text: &str) {
    let shown: String = text.trim().chars().take(60).collect();
    let hint = if text.trim_start().starts_with('[') {
        "close the section name with `]`"
    } else {
        "entries are written `Key=Value`; comments start with `;`"
    };
    let d = cx.emit(
        codes::E0002,
        Some(content),
        format!("`{shown}` is not a section header, a `key=value` entry or a comment (line ignored)"),
    );
    d.hint = Some(hint.into());
}

/// E0006: a section that appeared before, at line `first`.
#[cold]
#[inline(never)]
fn section_again(cx: &mut Ctx<'_>, name: Span, name_str: &str, first: u32) {
    let d = cx.emit(codes::E0006, Some(name), format!("section [{name_str}] appears again (first at line {first})"));
    d.hint = Some("merge the two sections; where both set a key, this reader uses the later value".into());
}

/// The number of characters in `s`.
fn char_count(s: &str) -> u32 {
    (if s.is_ascii() { s.len() } else { s.chars().count() }) as u32
}

fn report_spelling(cx: &mut Ctx<'_>, span: Span, name: &str, spelling: &Spelling) {
    match spelling {
        Spelling::Exact => {}
        Spelling::Case(canon) => {
            // (Case differences are common: the messages are put together without the formatter,
            // and not at all when notes are not kept.)
            if cx.skips(codes::E0104) {
                return;
            }
            cx.emit(
                codes::E0104,
                Some(span),
                super::cat(["section [", name, "] is written [", canon, "] in CiA 306"]),
            )
            .hint = Some(super::cat(["write [", canon, "]"]).into());
        }
        Spelling::Misspelled(canon) => {
            let d = cx.emit(codes::E0103, Some(span), format!("section [{name}] is spelled [{canon}] in CiA 306"));
            d.hint = Some(if canon == "DeviceComissioning" {
                "CiA 306 spells it [DeviceComissioning] (one `m`); this reader accepts both".into()
            } else {
                format!("write [{canon}]").into()
            });
        }
        Spelling::Malformed(why) => {
            let d =
                cx.emit(codes::E0105, Some(span), format!("section [{name}] looks like an object section, but {why}"));
            d.hint = Some("object sections are [IIII], [IIIIsubS], [IIIIName], [IIIIValue] or [IIIIObjectLinks] with hexadecimal IIII and S".into());
        }
    }
}

/// The known keys of a kind of section, with a lookup that ignores ASCII case.
///
/// A key is found by its length first (a bit mask per length), then by comparing it with the
/// keys of that length as two 64-bit words (its first and last eight bytes, which cover keys of
/// up to 16 bytes), lower-cased eight bytes at a time. Longer keys are compared byte by byte.
pub(crate) struct KeySet<const N: usize> {
    /// The CiA 306 spellings.
    pub names: [&'static str; N],
    /// For each length, a bit per key of that length.
    by_len: [u32; 32],
    /// For each number of significant bytes ([`loose_eq`]), a bit per key with that many: a key
    /// that matches none exactly is compared loosely only with the keys it could equal.
    by_significant: [u32; 32],
    /// The fewest significant bytes of any key: a key shorter than that (counting every byte)
    /// equals none loosely, and is not looked at byte by byte.
    min_significant: usize,
    /// For each first letter (ASCII case folded, [`first_slot`]), a bit per key starting with it:
    /// with the length, this leaves one candidate for almost every key.
    by_first: [u32; 32],
    /// Each key's two words as spelled.
    words: [(u64, u64); N],
    /// Each key's two words in lower case.
    lower: [(u64, u64); N],
}

const LO: u64 = 0x0101_0101_0101_0101;

/// The slot of [`KeySet::by_first`] for a key's first byte: its low five bits once ASCII
/// letters are folded to lower case (other bytes share slots with letters, which only makes
/// the filter let more candidates through).
#[inline]
const fn first_slot(b: u8) -> usize {
    ((b | 0x20) & 31) as usize
}

/// Lower-cases the ASCII letters among the eight bytes of `w` (and nothing else).
#[inline]
const fn ascii_lower(w: u64) -> u64 {
    let low7 = w & (LO * 0x7F);
    // The high bit of each byte is set where the byte is >= 'A', resp. > 'Z' (no carries: a
    // byte of `low7` is at most 0x7F and the addends at most 0x3F).
    let ge_a = low7 + LO * (0x80 - b'A' as u64);
    let gt_z = low7 + LO * (0x80 - b'Z' as u64 - 1);
    let upper = ge_a & !gt_z & !w & (LO * 0x80);
    w | (upper >> 2)
}

/// The first and the last eight bytes of `b` (for `b.len() >= 8`; they overlap when it is
/// shorter than 16), or `b` padded with zeros and 0 (when shorter than 8).
#[inline]
const fn words(b: &[u8]) -> (u64, u64) {
    let n = b.len();
    let mut first = [0u8; 8];
    let mut last = [0u8; 8];
    let mut i = 0;
    while i < 8 && i < n {
        first[i] = b[i];
        if n >= 8 {
            last[i] = b[n - 8 + i];
        }
        i += 1;
    }
    (u64::from_le_bytes(first), u64::from_le_bytes(last))
}

/// [`words`] for keys read from a file (eight-byte loads where the key is long enough).
#[inline(always)]
fn key_words(b: &[u8]) -> (u64, u64) {
    let n = b.len();
    if n >= 8 {
        let mut first = [0u8; 8];
        let mut last = [0u8; 8];
        first.copy_from_slice(&b[..8]);
        last.copy_from_slice(&b[n - 8..]);
        (u64::from_le_bytes(first), u64::from_le_bytes(last))
    } else {
        (b.iter().rev().fold(0u64, |w, &c| w << 8 | c as u64), 0)
    }
}

impl<const N: usize> KeySet<N> {
    /// A key set (checked at compile time: at most 32 keys, each shorter than 32 bytes).
    pub const fn new(names: [&'static str; N]) -> Self {
        assert!(N <= 32, "at most 32 keys");
        let mut by_len = [0u32; 32];
        let mut by_first = [0u32; 32];
        let mut by_significant = [0u32; 32];
        let mut min_significant = usize::MAX;
        let mut words_of = [(0u64, 0u64); N];
        let mut lower = [(0u64, 0u64); N];
        let mut i = 0;
        while i < N {
            let len = names[i].len();
            assert!(len < 32, "keys are shorter than 32 bytes");
            by_len[len] |= 1 << i;
            assert!(len > 0, "keys are not empty");
            by_first[first_slot(names[i].as_bytes()[0])] |= 1 << i;
            by_significant[significant_len(names[i].as_bytes())] |= 1 << i;
            if significant_len(names[i].as_bytes()) < min_significant {
                min_significant = significant_len(names[i].as_bytes());
            }
            let w = words(names[i].as_bytes());
            words_of[i] = w;
            lower[i] = (ascii_lower(w.0), ascii_lower(w.1));
            // No two keys are equal ignoring case (so a key spelled exactly like one of them
            // matches that one only, and `find` may try the exact spellings first). Checked on
            // the two words, which for keys longer than 16 bytes is stricter than needed.
            let mut j = 0;
            while j < i {
                assert!(
                    names[j].len() != len || lower[j].0 != lower[i].0 || lower[j].1 != lower[i].1,
                    "keys differ ignoring case"
                );
                j += 1;
            }
            i += 1;
        }
        KeySet { names, by_len, by_significant, min_significant, by_first, words: words_of, lower }
    }

    /// The number of the key that `key` equals by [`loose_eq`] (case, spaces, `_` and `-`
    /// ignored), for keys [`KeySet::find`] did not find.
    pub fn find_loose(&self, key: &str) -> Option<usize> {
        // (Object lists hold hundreds of keys `1`, `2`, ... and no known key is that short.)
        if key.len() < self.min_significant {
            return None;
        }
        let mut candidates = *self.by_significant.get(significant_len(key.as_bytes()))?;
        while candidates != 0 {
            let i = candidates.trailing_zeros() as usize;
            if loose_eq(self.names[i], key) {
                return Some(i);
            }
            candidates &= candidates - 1;
        }
        None
    }

    /// Whether `key` is spelled exactly as key number `i` (false when there is no such key, or
    /// it is longer than 16 bytes: compared by its two words, as [`KeySet::find`] does).
    #[inline(always)]
    pub fn is_exactly(&self, i: usize, key: &str) -> bool {
        i < N && key.len() == self.names[i].len() && key.len() <= 16 && key_words(key.as_bytes()) == self.words[i]
    }

    /// The number of the key that equals `key` ignoring ASCII case, and whether `key` is
    /// spelled exactly like it.
    #[inline]
    pub fn find(&self, key: &str) -> Option<(usize, bool)> {
        let first = *key.as_bytes().first()?;
        let mut candidates = *self.by_len.get(key.len())? & self.by_first[first_slot(first)];
        if candidates == 0 {
            return None;
        }
        if key.len() > 16 {
            while candidates != 0 {
                let i = candidates.trailing_zeros() as usize;
                if self.names[i].eq_ignore_ascii_case(key) {
                    return Some((i, self.names[i] == key));
                }
                candidates &= candidates - 1;
            }
            return None;
        }
        let w = key_words(key.as_bytes());
        // Most files spell keys as CiA 306 does: try that before lower-casing.
        let mut exact = candidates;
        while exact != 0 {
            let i = exact.trailing_zeros() as usize;
            if self.words[i] == w {
                return Some((i, true));
            }
            exact &= exact - 1;
        }
        let l = (ascii_lower(w.0), ascii_lower(w.1));
        while candidates != 0 {
            let i = candidates.trailing_zeros() as usize;
            if self.lower[i] == l {
                return Some((i, self.words[i] == w));
            }
            candidates &= candidates - 1;
        }
        None
    }
}

/// The known keys of a section, matched against its entries.
pub(crate) struct Keys<'a, const N: usize> {
    /// For each known key, the entry that sets it (the last one if repeated).
    pub found: [Option<&'a Kv<'a>>; N],
    /// Entries whose key is not known, in file order of each key's first entry, with the value
    /// of its last.
    pub unknown: Vec<&'a Kv<'a>>,
}

impl<'a, const N: usize> Keys<'a, N> {
    /// No keys.
    #[inline]
    pub fn new() -> Self {
        Keys { found: [None; N], unknown: Vec::new() }
    }

    /// Forgets every key (the vector keeps its room).
    #[inline]
    pub fn clear(&mut self) {
        self.found = [None; N];
        self.unknown.clear();
    }

    /// The entry for known key number `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Option<&'a Kv<'a>> {
        self.found.get(i).copied().flatten()
    }
}

/// The value of a section's (last) `ParameterName` key, any case: the name its diagnostics
/// carry ([`Crumbs::object_named_by`]), looked for when a diagnostic is made (which may be
/// before the section's keys are matched). The key is compared as spelled first, which is how
/// nearly every file spells it; lower-casing it byte by byte cost 1 M instructions per corpus
/// pass.
pub(crate) fn parameter_name<'a>(entries: &[Kv<'a>]) -> Option<&'a str> {
    const KEY: &str = "ParameterName";
    let is_name = |k: &str| k.len() == KEY.len() && (k == KEY || k.eq_ignore_ascii_case(KEY));
    entries.iter().rev().find(|kv| is_name(kv.key())).map(|kv| kv.value())
}

/// Matches a section's entries against `known` key names (case-insensitively), reporting case
/// and spelling differences, repeated keys and (when `report_unknown`) unknown keys.
pub(crate) fn match_keys<'a, const N: usize>(
    cx: &mut Ctx<'_>,
    sec: &Section<'a>,
    known: &KeySet<N>,
    context: Crumbs<'_>,
    report_unknown: bool,
) -> Keys<'a, N> {
    let mut keys = Keys::new();
    fill_keys(cx, sec, known, context, report_unknown, &mut keys);
    keys
}

/// [`match_keys`] into `keys`, which must be empty ([`Keys::new`], [`Keys::clear`]): for the
/// sections of objects and sub-objects, the commonest, a `Keys` returned was copied out of the
/// frame that filled it (about twenty instructions a section, and a `memcpy` call once the
/// compiler no longer kept it apart), and a `Keys` reused from one sub-object to the next
/// keeps its vector of unknown keys.
pub(crate) fn fill_keys<'a, const N: usize>(
    cx: &mut Ctx<'_>,
    sec: &Section<'a>,
    known: &KeySet<N>,
    context: Crumbs<'_>,
    report_unknown: bool,
    keys: &mut Keys<'a, N>,
) {
    let Keys { found, unknown } = keys;
    // The last unknown entry of each key, once there are enough of them (object lists have
    // hundreds) that searching the earlier ones for a repeat would cost more than hashing.
    let mut last_unknown: Option<FastMap<Caseless<'a>, usize>> = None;
    // Whether the unknown keys so far are `1`, `2`, `3`, ... in order, as object lists and
    // numbered sections write them: then the next number, written plainly, repeats none of
    // them and is kept without a search.
    let mut numbered = true;
    let names = &known.names;
    // The key expected next: the one after the last found, in the key set's order, which is
    // the order CiA 306 and nearly every file write them in (ParameterName, ObjectType,
    // DataType, AccessType, DefaultValue, PDOMapping): compared first, as spelled.
    let mut next = 0;
    for (at, kv) in sec.entries.iter().enumerate() {
        let found_key = if known.is_exactly(next, kv.key()) { Some((next, true)) } else { known.find(kv.key()) };
        let mut hit = found_key.map(|(i, _)| i);
        if let Some((i, exact)) = found_key {
            next = i + 1;
            if !exact && !cx.skips(codes::E0104) {
                let d = cx.emit(
                    codes::E0104,
                    Some(kv.key_span(&cx.src.text)),
                    super::cat(["key `", kv.key(), "` is written `", names[i], "` in CiA 306"]),
                );
                d.hint = Some(super::cat(["write `", names[i], "`"]).into());
                d.context = context.to_vec();
            }
        } else {
            hit = known.find_loose(kv.key());
            if let Some(i) = hit {
                let d = cx.emit(
                    codes::E0103,
                    Some(kv.key_span(&cx.src.text)),
                    format!("key `{}` is spelled `{}` in CiA 306", kv.key(), names[i]),
                );
                d.hint = Some(format!("write `{}`", names[i]).into());
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
            None if numbered && is_number(kv.key(), unknown.len() + 1) => {
                debug_assert!(!unknown.iter().any(|u| u.key().eq_ignore_ascii_case(kv.key())), "{}", kv.key());
                if unknown.capacity() == 0 {
                    // Room for every entry left, so that the vector is not grown step by step.
                    unknown.reserve_exact(sec.entries.len() - at);
                }
                unknown.push(kv);
                if report_unknown {
                    report_unknown_key(cx, kv, sec, context);
                }
            }
            None => {
                numbered = false;
                if last_unknown.is_none() && unknown.len() >= 8 {
                    // Sized for every entry of the section, so that neither grows again.
                    unknown.reserve(sec.entries.len());
                    let mut map = FastMap::with_capacity_and_hasher(sec.entries.len(), Default::default());
                    map.extend(unknown.iter().enumerate().map(|(i, u)| (Caseless(u.key()), i)));
                    last_unknown = Some(map);
                }
                let prev = match &mut last_unknown {
                    Some(map) => match map.entry(Caseless(kv.key())) {
                        std::collections::hash_map::Entry::Occupied(e) => Some(*e.get()),
                        std::collections::hash_map::Entry::Vacant(e) => {
                            e.insert(unknown.len());
                            None
                        }
                    },
                    None => unknown.iter().position(|u| same_key(u.key(), kv.key())),
                };
                // A repeated key keeps its first place with the later value, as a known key
                // does: the model (and a file written from it) has each key once.
                match prev {
                    Some(i) => {
                        report_duplicate(cx, unknown[i], kv, context);
                        unknown[i] = kv;
                    }
                    None => {
                        if unknown.capacity() == 0 {
                            unknown.reserve_exact(sec.entries.len() - at);
                        }
                        unknown.push(kv)
                    }
                }
                if report_unknown {
                    report_unknown_key(cx, kv, sec, context);
                }
            }
        }
    }
}

/// Whether two keys are equal ignoring ASCII case, compared from their ends: the unknown keys
/// of a section that share a length (`Dummy0001`, `Dummy0002`, ...; `BaudRate_125`,
/// `BaudRate_250`) mostly differ in their last bytes.
#[inline]
fn same_key(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().rev().zip(b.bytes().rev()).all(|(x, y)| x.eq_ignore_ascii_case(&y))
}

/// Reports a key that is not one of its section's (E0102).
fn report_unknown_key(cx: &mut Ctx<'_>, kv: &Kv<'_>, sec: &Section<'_>, context: Crumbs<'_>) {
    let d = cx.emit(
        codes::E0102,
        Some(kv.key_span(&cx.src.text)),
        format!("key `{}` is not a CiA 306 key of [{}]; it is kept as written", kv.key(), sec.name),
    );
    d.context = context.to_vec();
}

/// Whether `key` is `n` in decimal as written plainly (no sign, no leading zero).
#[inline]
fn is_number(key: &str, n: usize) -> bool {
    let b = key.as_bytes();
    if b.is_empty() || b.len() > 19 || b[0] == b'0' {
        return false;
    }
    let mut v = 0u64;
    for &c in b {
        if !c.is_ascii_digit() {
            return false;
        }
        v = v * 10 + (c - b'0') as u64;
    }
    v == n as u64
}

/// A key compared and hashed ignoring ASCII case.
#[derive(Clone, Copy)]
struct Caseless<'a>(&'a str);

impl PartialEq for Caseless<'_> {
    fn eq(&self, other: &Self) -> bool {
        self.0.eq_ignore_ascii_case(other.0)
    }
}

impl Eq for Caseless<'_> {}

impl std::hash::Hash for Caseless<'_> {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        state.write_usize(self.0.len());
        for b in self.0.bytes() {
            state.write_u8(b.to_ascii_lowercase());
        }
    }
}

/// Reports `kv` as a repeat of `prev` (E0007), unless the repeat comes from a repeated section.
pub(crate) fn report_duplicate(cx: &mut Ctx<'_>, prev: &Kv<'_>, kv: &Kv<'_>, context: Crumbs<'_>) {
    // Repeats that come from a repeated section were already reported with the section: the
    // two entries came from one occurrence of it if no section header lies between them.
    let (at, prev_at) = (kv.key_span(&cx.src.text).start, prev.key_span(&cx.src.text).start);
    let headers_before = |at: u32| cx.header_starts.partition_point(|&h| h < at);
    if headers_before(prev_at) != headers_before(at) {
        return;
    }
    let first = cx.src.line_col(prev_at);
    let d = cx.emit(
        codes::E0007,
        Some(kv.key_span(&cx.src.text)),
        format!(
            "key `{}` is set again (first at line {}); the later value `{}` is used",
            kv.key(),
            first.line,
            kv.value()
        ),
    );
    d.hint = Some("remove one of the two entries".into());
    d.context = context.to_vec();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry keeps what fits its `u32`s, and nothing else (an entry of a text of 4 GiB or
    /// more is an empty key and value, not a slice of memory outside the text).
    #[test]
    fn an_entry_keeps_only_what_fits_it() {
        // (A text of 4 GiB is too much for a test; a value before its key, which no line has,
        // gives an offset that wraps past what fits, as one 4 GiB on would.)
        let text = "ab=cd";
        let kv = Kv::of(&text[3..], &text[..2]);
        assert_eq!((kv.key(), kv.value()), ("", ""));
        assert_eq!(kv.key_span(text), Span::new(3, 3));
        let kv = Kv::of(&text[..2], &text[3..]);
        assert_eq!((kv.key(), kv.value()), ("ab", "cd"));
    }

    /// An entry gives back the key and value it was made of, and their spans, whatever their
    /// lengths and places in the text (multi-byte text, empty parts, parts at either end of the
    /// text, spans that do not fit it).
    #[test]
    fn an_entry_gives_back_its_key_and_value() {
        let text = "Ä=ü;\r\nParameterName = Motor ☃ speed\nx=\n=\n".repeat(30);
        let len = text.len() as u32;
        let mut rng = crate::test_rng(0x5EED_0FC0_FFEE);
        let mut boundary = |max: u32| loop {
            let at = rng(max as u64 + 1) as u32;
            if text.is_char_boundary(at as usize) {
                return at;
            }
        };
        for _ in 0..5000 {
            let (a, b, c, d) = (boundary(len), boundary(len), boundary(len), boundary(len));
            let mut at = [a, b, c, d];
            at.sort_unstable();
            let (key, value) = (Span::new(at[0], at[1]), Span::new(at[2], at[3]));
            let kv = Kv::new(&text, key, value);
            assert_eq!(kv.key(), &text[at[0] as usize..at[1] as usize]);
            assert_eq!(kv.value(), &text[at[2] as usize..at[3] as usize]);
            assert_eq!((kv.key_span(&text), kv.value_span(&text)), (key, value));
            assert_eq!(Kv::of(kv.key(), kv.value()).value_span(&text), value);
        }
        // A span past the end is an empty part at its start, or at the end of the text.
        let kv = Kv::new(&text, Span::new(len - 1, len + 5), Span::new(len + 2, len + 9));
        assert_eq!((kv.key(), kv.value()), ("", ""));
        assert_eq!(kv.key_span(&text), Span::new(len - 1, len - 1));
        assert_eq!(kv.value_span(&text), Span::new(len, len));
        assert_eq!(format!("{:?}", Kv::new("K=V", Span::new(0, 1), Span::new(2, 3))), r#"Kv { key: "K", value: "V" }"#);
    }

    /// A buffer of entries borrowed from one text is kept, memory and all, for the next text.
    #[test]
    fn reuse_keeps_the_allocation() {
        let text = String::from("Key=Value");
        let mut entries: Vec<Kv<'_>> = Vec::with_capacity(1000);
        entries.push(Kv::new(&text, Span::new(0, 3), Span::new(4, 9)));
        let (ptr, cap) = (entries.as_ptr() as usize, entries.capacity());
        let kept: Vec<Kv<'static>> = reuse(entries);
        drop(text);
        assert_eq!((kept.as_ptr() as usize, kept.capacity(), kept.len()), (ptr, cap, 0));
        let heads: Vec<Head<'static>> = reuse(Vec::<Head<'_>>::with_capacity(10));
        assert!(heads.capacity() >= 10);
    }

    /// Holds pass 1's entries to the text they came from: for every entry line in a section,
    /// the entry's key and value, and the spans found from where they lie in the text, are
    /// what the lexer's general path gives for that line, whichever path of the lexer read it.
    fn check_entries_against_the_general_path(text: &str) {
        let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", text));
        let src_text: &str = &doc.source.text;
        let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
        let mut collected = collect(&doc, &mut cx, &mut Scratch::default());
        // The general path's entries in sections, by where their key starts.
        let mut general = std::collections::BTreeMap::new();
        let mut in_section = false;
        for line in doc.lines() {
            match line.kind {
                LineKind::Section { .. } => in_section = true,
                LineKind::Entry { key, value } if in_section => {
                    general.insert(key.start, (key, value));
                }
                _ => {}
            }
        }
        let mut seen = std::collections::BTreeSet::new();
        let secs = collected.sections();
        for sec in &secs.list {
            for kv in sec.entries {
                let (key, value) = (kv.key_span(src_text), kv.value_span(src_text));
                assert_eq!(general.get(&key.start), Some(&(key, value)), "{text:?}");
                assert_eq!((kv.key(), kv.value()), (doc.source.slice(key), doc.source.slice(value)), "{text:?}");
                assert!(seen.insert(key.start), "{text:?}");
            }
        }
        assert_eq!(seen.len(), general.len(), "{text:?}");
    }

    #[test]
    fn entries_hold_to_the_text_on_examples() {
        for text in [
            "[S]\nKey=Value\n",
            "[S]\r\n Key = Value \r\n\u{e4}=\u{e4}\rK=\n=v\n[S]\nKey=again",
            "K=outside\n[1000]\nParameterName=x;c\nDefaultValue=\n[1000]\nk\t=\t1\u{A0}",
        ] {
            check_entries_against_the_general_path(text);
        }
    }

    /// The lines of repeated key reports (E0007) of a file of extra sections, by the rule that
    /// numbered each entry with the occurrence of its section: a key set again in the same
    /// occurrence of a section as its first entry is reported, one set again by a repeat of the
    /// section is not.
    fn reference_repeats(lines: &[(usize, usize)]) -> Vec<u32> {
        let mut occurrences: std::collections::HashMap<usize, u32> = Default::default();
        let mut first: std::collections::HashMap<(usize, usize), u32> = Default::default();
        let (mut section, mut out) = (None, Vec::new());
        for (n, &(s, k)) in lines.iter().enumerate() {
            if k == 0 {
                occurrences.entry(s).and_modify(|o| *o += 1).or_insert(0);
                section = Some(s);
            } else if let Some(s) = section {
                let occurrence = occurrences[&s];
                match first.entry((s, k)) {
                    std::collections::hash_map::Entry::Occupied(e) if *e.get() == occurrence => out.push(n as u32 + 1),
                    std::collections::hash_map::Entry::Occupied(_) => {}
                    std::collections::hash_map::Entry::Vacant(e) => {
                        e.insert(occurrence);
                    }
                }
            }
        }
        out.sort();
        out
    }

    /// What [`fill_keys`] finds, by the rules alone: for each known key the index of the entry
    /// that sets it last, and the unknown entries, each key once (at its first entry's place,
    /// with the index of its last).
    fn reference_keys<const N: usize>(known: &KeySet<N>, entries: &[Kv<'_>]) -> (Vec<Option<usize>>, Vec<usize>) {
        let mut found = vec![None; N];
        let mut unknown: Vec<usize> = Vec::new();
        for (j, kv) in entries.iter().enumerate() {
            let key = kv.key();
            let hit = (known.names.iter().position(|n| n.eq_ignore_ascii_case(key)))
                .or_else(|| known.names.iter().position(|n| loose_eq(n, key)));
            match hit {
                Some(i) => found[i] = Some(j),
                None => match unknown.iter().position(|&u| entries[u].key().eq_ignore_ascii_case(key)) {
                    Some(p) => unknown[p] = j,
                    None => unknown.push(j),
                },
            }
        }
        (found, unknown)
    }

    proptest::proptest! {
        /// `fill_keys` (into a `Keys` reused from the section before, as objects' sub-objects
        /// are matched; the key expected next compared first) and `match_keys` find the keys
        /// the rules find, with the same reports,
        /// for keys spelled as CiA 306 does, in other cases, loosely, numbered and unknown
        /// (repeated too; the unknown ones that share a length and differ in their last bytes,
        /// as `Dummy0001` and `BaudRate_125` do).
        #[test]
        fn matched_keys_are_what_the_rules_find(
            sections in proptest::collection::vec(proptest::collection::vec(
                "ParameterName|parametername|Parameter_Name|DynamicChannelsSupported|DynamicCXannelsSupported|DataType|DATATYPE|DataTypf|VendorName|Vendor Name|LSS_Supported|LSSSupported|Dummy000[0-9]|DUMMY000[0-9]|BaudRate_[0-9]{1,4}|[1-9][0-9]?|[a-zA-Z_]{1,3}",
                0..24), 1..4),
        ) {
            // (In an order that the keys drawn often follow, so that the key expected next is
            // often the one found, and often not; one longer than 16 bytes, and a key that has
            // its first and last eight bytes but is not it.)
            const KNOWN: KeySet<6> =
                KeySet::new(["ParameterName", "DynamicChannelsSupported", "DataType", "VendorName", "LSS_Supported", "BaudRate"]);
            let mut text = String::new();
            for (n, keys) in sections.iter().enumerate() {
                text.push_str(&format!("[X{n}]\n"));
                for (j, k) in keys.iter().enumerate() {
                    text.push_str(&format!("{k}=v{j}\n"));
                }
            }
            let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", text.as_str()));
            let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
            let mut collected = collect(&doc, &mut cx, &mut Scratch::default());
            let secs = collected.sections();
            let mut reused = Keys::new();
            for sec in &secs.list {
                let before = cx.diags.len();
                let fresh = match_keys(&mut cx, sec, &KNOWN, Crumbs::default(), true);
                let fresh_diags: Vec<_> = cx.diags[before..].iter().map(|d| (d.code, d.span, d.message.clone())).collect();
                let before = cx.diags.len();
                reused.clear();
                fill_keys(&mut cx, sec, &KNOWN, Crumbs::default(), true, &mut reused);
                let reused_diags: Vec<_> = cx.diags[before..].iter().map(|d| (d.code, d.span, d.message.clone())).collect();
                proptest::prop_assert_eq!(&fresh_diags, &reused_diags);
                let index = |kv: &Kv<'_>| sec.entries.iter().position(|e| std::ptr::eq(e, kv)).unwrap();
                let (found, unknown) = reference_keys(&KNOWN, sec.entries);
                for keys in [&fresh, &reused] {
                    proptest::prop_assert_eq!(keys.found.iter().map(|f| f.map(index)).collect::<Vec<_>>(), found.clone());
                    proptest::prop_assert_eq!(keys.unknown.iter().map(|&kv| index(kv)).collect::<Vec<_>>(), unknown.clone());
                }
            }
        }

        #[test]
        fn entries_hold_to_the_text(
            lines in proptest::collection::vec("[ \t\u{A0}]{0,2}(\\[[0-9A-Fa-fsub ]{0,10}\\]|[A-Za-z\u{e4}]{0,14}[ \t]?=[ \t]?[0-9a-zA-Z$+ ;#=\u{e4}]{0,12}|;.{0,5}|\\PC{0,8})[ \t\u{A0}]{0,2}", 0..40),
            ending in "\r\n|\n|\r",
        ) {
            check_entries_against_the_general_path(&lines.join(&ending));
            check_entries_against_the_general_path(&format!("{}{ending}{}", lines.join(&ending), "Pad=1\n".repeat(4)));
        }

        /// A key set again is reported when its section was not repeated in between, whatever
        /// the order of sections and keys (extra sections `[Xn]`, keys `Kn`; 0 is a header).
        #[test]
        fn repeated_keys_are_reported_by_occurrence(
            lines in proptest::collection::vec((0..3usize, 0..4usize), 0..40),
        ) {
            let text: String =
                lines.iter().map(|&(s, k)| if k == 0 { format!("[X{s}]\n") } else { format!("K{k}=v\n") }).collect();
            let p = crate::parse("x.eds", text.as_bytes(), &crate::Options::lenient());
            let mut repeats: Vec<u32> =
                p.diagnostics.iter().filter(|d| d.code == codes::E0007).filter_map(|d| d.at.map(|a| a.line)).collect();
            repeats.sort();
            let orphans = lines.iter().take_while(|&&(_, k)| k != 0).count();
            proptest::prop_assert_eq!(repeats, reference_repeats(&lines[orphans..]).iter().map(|n| n + orphans as u32).collect::<Vec<_>>(), "{:?}", text);
        }
        /// Each section holds the entries of all its occurrences, in file order, sections in the
        /// order they first come, with where each header was (when a section comes again),
        /// whether or not and wherever sections are repeated (sections `[Xn]`, keys `Kn`;
        /// 0 is a header), in one reader and another reusing its buffers.
        #[test]
        fn sections_hold_the_entries_of_all_their_occurrences(
            files in proptest::collection::vec(proptest::collection::vec((0..4usize, 0..4usize), 0..40), 1..4),
        ) {
            let mut scratch = Scratch::default();
            for lines in &files {
                let text: String = lines
                    .iter()
                    .enumerate()
                    .map(|(n, &(s, k))| if k == 0 { format!("[X{s}]\n") } else { format!("K{k}=v{n}\n") })
                    .collect();
                // The reference: sections by first occurrence, each with its entries in order.
                let mut order: Vec<usize> = Vec::new();
                let mut want: Vec<Vec<String>> = Vec::new();
                let mut headers: Vec<u32> = Vec::new();
                let mut current = None;
                let mut at = 0u32;
                for (n, &(s, k)) in lines.iter().enumerate() {
                    if k == 0 {
                        let i = order.iter().position(|&o| o == s).unwrap_or_else(|| {
                            order.push(s);
                            want.push(Vec::new());
                            order.len() - 1
                        });
                        current = Some(i);
                        headers.push(at + 1);
                    } else if let Some(i) = current {
                        want[i].push(format!("K{k}=v{n}"));
                    }
                    at += if k == 0 { 5 } else { format!("K{k}=v{n}\n").len() as u32 };
                }
                let repeated = headers.len() > order.len();
                let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", &text));
                let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
                let mut collected = collect(&doc, &mut cx, &mut scratch);
                let secs = collected.sections();
                let got: Vec<Vec<String>> = secs
                    .list
                    .iter()
                    .map(|s| s.entries.iter().map(|kv| format!("{}={}", kv.key(), kv.value())).collect())
                    .collect();
                proptest::prop_assert_eq!(&got, &want, "{:?}", text);
                let names: Vec<String> = secs.list.iter().map(|s| s.name.to_string()).collect();
                proptest::prop_assert_eq!(names, order.iter().map(|s| format!("X{s}")).collect::<Vec<_>>());
                let starts = if repeated { headers } else { Vec::new() };
                proptest::prop_assert_eq!(&cx.header_starts, &starts, "{:?}", text);
                let list = reuse(secs.list);
                scratch.keep(collected, list);
            }
        }

        /// Numbered keys (`1`, `2`, ... in order, which skip the search for repeats) are kept and
        /// reported as any unknown keys are: the same keys with a letter in front, which never
        /// look numbered, give the same kept keys, repeats and reports.
        #[test]
        fn numbered_keys_are_kept_as_other_unknown_keys(
            keys in proptest::collection::vec(
                proptest::sample::select(vec!["1", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11", "01", "0", "x", "X"]),
                0..24,
            )
        ) {
            let file = |prefix: &str| {
                let mut t = String::from("[2000]\nParameterName=A\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n");
                for (i, k) in keys.iter().enumerate() {
                    t.push_str(&format!("{prefix}{k}={i}\n"));
                }
                t
            };
            let read = |prefix: &str| {
                let p = crate::parse("t.eds", file(prefix).as_bytes(), &crate::Options::default());
                let extra: Vec<(String, String)> = p.model.objects[&crate::model::Index(0x2000)].subs[&crate::model::SubIndex(0)]
                    .extra()
                    .iter()
                    .map(|(k, v)| (k[prefix.len()..].to_owned(), v.clone()))
                    .collect();
                let reports: Vec<String> =
                    p.diagnostics.iter().map(|d| format!("{:?} {:?}", d.code, d.at.map(|at| at.line))).collect();
                (extra, reports)
            };
            proptest::prop_assert_eq!(read(""), read("k"));
        }
    }

    /// The kind index finds what a hash map finds, for kinds in ascending order, with repeats,
    /// and out of order.
    #[test]
    fn kind_index_agrees_with_a_map() {
        let mut pool = vec![Kind::FileInfo, Kind::DeviceInfo, Kind::Commissioning, Kind::List(Category::Optional)];
        for i in [0u16, 1, 0x1000, 0x1001, 0x1018, 0x1A00, 0xFFFF] {
            pool.extend([Kind::Object(i), Kind::Names(i), Kind::Values(i), Kind::Links(i)]);
            pool.extend([0u8, 1, 0xFF].map(|s| Kind::Sub(i, s)));
        }
        let mut ascending = pool.clone();
        ascending.sort_by_key(|k| k.key());
        let mut orders = vec![ascending.clone(), pool.clone()];
        let mut repeated = ascending.clone();
        repeated.extend(ascending.iter().step_by(3));
        orders.push(repeated);
        let mut late = ascending.clone();
        late.rotate_left(5);
        orders.push(late);
        let mut seed = 7u32;
        for _ in 0..20 {
            let mut o = ascending.clone();
            for i in (1..o.len()).rev() {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                o.swap(i, (seed >> 8) as usize % (i + 1));
            }
            o.extend(o.clone().iter().take(9));
            orders.push(o);
        }
        for order in orders {
            let mut index = KindIndex::default();
            index.reset(4, 4);
            let mut map = std::collections::HashMap::new();
            for (n, &k) in order.iter().enumerate() {
                let want = map.get(&k).copied();
                assert_eq!(index.enter(k, n), want, "{k:?}");
                map.entry(k).or_insert(n);
            }
            for &k in &pool {
                assert_eq!(index.get(k), map.get(&k).copied(), "{k:?}");
            }
            assert_eq!(index.get(Kind::Unknown), None);
            assert_eq!(index.get(Kind::Object(0x2000)), None);
        }
    }

    #[test]
    fn kind_keys_are_distinct() {
        let mut kinds = vec![
            Kind::FileInfo,
            Kind::DeviceInfo,
            Kind::DummyUsage,
            Kind::Comments,
            Kind::Commissioning,
            Kind::Unknown,
            Kind::List(Category::Mandatory),
            Kind::List(Category::Optional),
            Kind::List(Category::Manufacturer),
        ];
        for i in [0u16, 1, 0xFF, 0x100, 0x1018, 0xFFFF] {
            kinds.extend([Kind::Object(i), Kind::Names(i), Kind::Values(i), Kind::Links(i)]);
            kinds.extend([0u8, 1, 0x7F, 0xFF].map(|s| Kind::Sub(i, s)));
        }
        let keys: std::collections::HashSet<u32> = kinds.iter().map(|k| k.key()).collect();
        assert_eq!(keys.len(), kinds.len());
    }

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
        const KEYS: KeySet<4> = KeySet::new(["BaudRate_10", "VendorName", "Granularity", "NrOfRXPDO"]);
        for key in ["baudrate10", "Baud Rate 10", "BAUD-RATE_10", "vendor_name", "Nr_Of_RX_PDO", "granularty", "", "x"]
        {
            let linear = KEYS.names.iter().position(|k| loose_eq(k, key));
            assert_eq!(KEYS.find_loose(key), linear, "{key:?}");
        }
        assert!(loose_eq("Device_Info", "deviceinfo"));
        assert!(!loose_eq("DeviceInfo", "DeviceInfos"));
        assert!(!loose_eq("", "x"));
        assert_eq!(classify("M1SubExt6000"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("Tools"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("äöü1"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("1a2b"), (Kind::Object(0x1A2B), Spelling::Case("1A2B".into())));
        assert_eq!(classify("1A2Bsub0a"), (Kind::Sub(0x1A2B, 10), Spelling::Case("1A2Bsub0A".into())));
        assert_eq!(classify("1A2BSUB0"), (Kind::Sub(0x1A2B, 0), Spelling::Case("1A2Bsub0".into())));
        assert_eq!(classify("1A2Bsub000F"), (Kind::Sub(0x1A2B, 15), Spelling::Exact));
        assert_eq!(classify("1a2bName"), (Kind::Names(0x1A2B), Spelling::Case("1A2BName".into())));
        assert_eq!(classify("1A2BOBJECTLINKS"), (Kind::Links(0x1A2B), Spelling::Case("1A2BObjectLinks".into())));
        assert_eq!(classify("1A2"), (Kind::Unknown, Spelling::Exact));
        assert_eq!(classify("+1A2"), (Kind::Unknown, Spelling::Exact));
    }

    /// The fast path for exactly spelled object names classifies every name as the general
    /// rules do (names built from the digits, letters and suffixes where the rules differ).
    #[test]
    fn exact_object_names_agree_with_the_general_rules() {
        let chars = ["0", "1", "9", "A", "F", "a", "f", "G", "x", " "];
        let suffixes = [
            "",
            "sub",
            "sub0",
            "sub9",
            "subA",
            "subF",
            "suba",
            "subG",
            "sub00",
            "sub1F",
            "sub1f",
            "subFF",
            "sub100",
            "sub001",
            "SUB1",
            "Sub1",
            "sub 1",
            "sub1 ",
            "Name",
            "name",
            "Value",
            "ObjectLinks",
            "x",
            "\u{e4}",
        ];
        let mut fast = 0;
        for a in chars {
            for b in ["0", "A", "f", "x"] {
                for c in ["1", "B", "g"] {
                    for d in chars {
                        for suffix in suffixes {
                            let name = format!("{a}{b}{c}{d}{suffix}");
                            fast += exact_object(name.as_bytes()).is_some() as u32;
                            assert_eq!(classify(&name), classify_general(&name), "{name:?}");
                        }
                    }
                }
            }
        }
        assert!(fast > 100);
        for name in ["", "1", "101", "1018", "1018sub", "1018sub1", "\u{e4}018", "10\u{e4}"] {
            assert_eq!(classify(name), classify_general(name), "{name:?}");
        }
    }

    #[test]
    fn section_positions_are_what_line_col_says() {
        let text = "[FileInfo]\r[DeviceInfo]\r\n  [1000]\nK=v\r\r \u{e4}\u{e4}\r [1001]\n\t[2000]\n[ä]\r\n [3000]";
        let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", text));
        let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
        let mut collected = collect(&doc, &mut cx, &mut Scratch::default());
        let heads = collected.heads.as_ptr() as usize;
        let secs = collected.sections();
        // The list is the heads' allocation, not a new one.
        assert_eq!(secs.list.as_ptr() as usize, heads);
        assert_eq!(secs.list.len(), 7);
        for sec in &secs.list {
            assert_eq!(sec.at, doc.source.line_col(sec.name_span.start), "[{}]", sec.name);
        }
        // And it goes back to being the heads' buffer for the next file.
        let back: Vec<Head<'static>> = reuse(secs.list);
        assert_eq!(back.as_ptr() as usize, heads);
    }

    /// Repeated unknown keys are found the same way with few and with many unknown keys.
    #[test]
    fn repeated_unknown_keys() {
        for n in [3, 20] {
            let mut text = String::from("[OptionalObjects]\n");
            for i in 1..=n {
                text.push_str(&format!("{i}=0x{:04X}\n", 0x1000 + i));
            }
            text.push_str("xY=1\n2=0x2000\nXy=2\n");
            let doc = crate::ast::Document::lexed(crate::source::SourceFile::from_str("x.eds", text));
            let mut cx = Ctx::new(&doc.source, crate::Strictness::Lenient);
            let mut collected = collect(&doc, &mut cx, &mut Scratch::default());
            let secs = collected.sections();
            let keys = match_keys(&mut cx, &secs.list[0], &KeySet::new(["SupportedObjects"]), Crumbs::default(), false);
            // Each key once: `2` and `xY` keep their first place with their later values.
            assert_eq!(keys.unknown.len(), n + 1);
            assert_eq!(keys.unknown[1].value(), "0x2000");
            assert_eq!(keys.unknown[n].value(), "2");
            let repeats: Vec<_> = cx
                .diags
                .iter()
                .map(|d| (d.code, d.span.map(|s| doc.source.line_col(s.start).line), d.message.clone()))
                .collect();
            assert_eq!(
                repeats,
                vec![
                    (
                        codes::E0007,
                        Some(n as u32 + 3),
                        "key `2` is set again (first at line 3); the later value `0x2000` is used".to_owned()
                    ),
                    (
                        codes::E0007,
                        Some(n as u32 + 4),
                        format!("key `Xy` is set again (first at line {}); the later value `2` is used", n + 2)
                    ),
                ],
                "{n}"
            );
        }
    }

    #[test]
    fn key_sets_ignore_case_and_keep_order() {
        const K: KeySet<6> =
            KeySet::new(["DataType", "LowLimit", "ObjFlags", "SubNumber", "Lines", "DynamicChannelsSupported"]);
        assert_eq!(K.find("datatype"), Some((0, false)));
        assert_eq!(K.find("LOWLIMIT"), Some((1, false)));
        assert_eq!(K.find("ObjFlags"), Some((2, true)));
        assert_eq!(K.find("SubNumber"), Some((3, true)));
        assert_eq!(K.find("lines"), Some((4, false)));
        assert_eq!(K.find("Lines"), Some((4, true)));
        assert_eq!(K.find("dynamicchannelssupported"), Some((5, false)));
        assert_eq!(K.find("DynamicChannelsSupported"), Some((5, true)));
        assert_eq!(K.find("DynamicChannelsSupporte_"), None);
        assert_eq!(K.find("SubNumbe"), None);
        assert_eq!(K.find("SubNumb\u{e4}"), None);
        assert_eq!(K.find("SubNumb\u{c4}"), None);
        assert_eq!(K.find(""), None);
        assert_eq!(K.find(&"x".repeat(40)), None);
    }

    /// The word comparison agrees with `eq_ignore_ascii_case` on keys that differ from a known
    /// key in one byte, for every byte value: letters of the other case match, nothing else.
    #[test]
    fn key_lookup_agrees_with_eq_ignore_ascii_case() {
        const K: KeySet<4> = KeySet::new(["ParameterValue", "PDOMapping", "Lines", "A_b-1@[`{"]);
        for (i, name) in K.names.iter().enumerate() {
            for pos in 0..name.len() {
                for byte in 0..=127u8 {
                    let mut key = name.as_bytes().to_vec();
                    key[pos] = byte;
                    let key = String::from_utf8(key).expect("ASCII");
                    let want = name.eq_ignore_ascii_case(&key).then_some((i, *name == key));
                    assert_eq!(K.find(&key), want, "{key:?}");
                }
            }
        }
        for w in [0u64, u64::MAX, 0x4041_5A5B_6061_7A7B, 0xC1DA_C0DB_8041_FF5A] {
            let bytes = w.to_le_bytes().map(|b| b.to_ascii_lowercase());
            assert_eq!(ascii_lower(w), u64::from_le_bytes(bytes), "{w:#x}");
        }
    }
}
