//! Lowering and validation: [`crate::ast::Document`] → [`crate::model::Model`] + diagnostics.
//!
//! Lowering runs in four passes, each in its own module:
//!
//! 1. `sections`: group the lines into sections (merging duplicates), classify each section
//!    name (`[FileInfo]`, `[1018]`, `[1018sub2]`, `[1016Name]`, ...) and report syntax-level
//!    problems (garbage lines, `#` comments, spelling of section names).
//! 2. `info`: `[FileInfo]`, `[DeviceInfo]`, `[DummyUsage]`, `[Comments]`,
//!    `[DeviceComissioning]` and the three object lists.
//! 3. `objects`: every object section with its sub-objects, typed values and limits,
//!    `CompactSubObj` expansion with `[xxxxName]`/`[xxxxValue]`, `[xxxxObjectLinks]`.
//! 4. `validate`: whole-model checks (object lists against sections, mandatory objects,
//!    PDO communication and mapping objects, PDO counts).
//!
//! Every problem becomes a [`Diagnostic`] with a code from [`crate::codes`]; its severity comes
//! from the code and the [`crate::Strictness`]. Nothing here panics, and nothing a file says is
//! dropped silently: keys and sections this crate does not interpret are kept in the model's
//! `extra` fields and reported as notes.

mod info;
mod objects;
pub mod pdo;
mod pool;
mod sections;
mod validate;

pub use pdo::expand_compact_pdo;
#[doc(hidden)]
pub use sections::name_comparisons;

use crate::ast::Document;
use crate::decimal::decimal_u8;
use crate::diag::{Code, Diagnostic, Severity};
use crate::model::{FileKind, Model};
use crate::source::{SourceFile, Span};
use crate::{Options, Strictness};

/// Lowers a lexed document into the typed model and validates it. The model is always built as
/// far as the file allows; the diagnostics say what was wrong, in file order (problems that
/// concern the whole file come last).
pub fn lower(doc: &Document, options: &Options) -> (Model, Vec<Diagnostic>) {
    let (model, diagnostics, _) = lower_reusing(doc, options, &mut Scratch::default());
    (model, diagnostics)
}

/// [`lower`], with the count of the diagnostics not kept ([`Options::keep_from`]).
pub fn lower_counting(doc: &Document, options: &Options) -> (Model, Vec<Diagnostic>, crate::NotKept) {
    lower_reusing(doc, options, &mut Scratch::default())
}

/// The buffers a [`crate::Reader`] keeps from one file to the next: pass 1's and pass 3's.
#[derive(Default)]
pub(crate) struct Scratch {
    /// Pass 1's buffers, the line index and the diagnostics vector.
    pub pass1: sections::Scratch,
    /// Pass 3's buffers and the models' lists of objects ([`crate::Reader::recycle`]).
    pub pool: pool::Pool,
}

/// [`lower`] with the buffers an earlier file left in `scratch` (and leaving this file's there).
pub(crate) fn lower_reusing(
    doc: &Document,
    options: &Options,
    scratch: &mut Scratch,
) -> (Model, Vec<Diagnostic>, crate::NotKept) {
    let Scratch { pass1, pool } = scratch;
    let mut cx = Ctx::reusing(&doc.source, options.strictness, std::mem::take(&mut pass1.diags), pass1.room_for);
    cx.least_kept = options.least_kept();
    cx.pool = std::mem::take(pool);
    cx.pool.room = pass1.room_for;
    let mut collected = sections::collect(doc, &mut cx, pass1);
    let secs = collected.sections();
    let mut model = Model::default();
    info::lower_info(&secs, &mut model, &mut cx);
    let is_dcf = model.commissioning.is_some()
        || doc.source.name.rsplit('.').next().is_some_and(|ext| ext.eq_ignore_ascii_case("dcf"));
    model.kind = if is_dcf { FileKind::Dcf } else { FileKind::Eds };
    let listed = std::mem::take(&mut cx.pool.listed);
    let lists = info::lower_object_lists(&secs, &mut cx, listed);
    objects::lower_objects(&secs, &lists, &mut model, &mut cx);
    validate::validate(&secs, &lists, &model, &mut cx);
    cx.pool.listed = lists.into_set();
    let list = sections::reuse(secs.list);
    pass1.keep(collected, list);
    cx.report_left_out();
    *pool = cx.pool;
    let not_kept = cx.not_kept;
    let mut diags = cx.diags;
    // File order: by position, whole-file diagnostics last. The sort is stable, so diagnostics
    // at the same place keep the order in which they were found.
    // Most come in order already; otherwise sort positions, not the large diagnostics (this
    // sort is stable too).
    let place = |d: &Diagnostic| d.span.map(|s| s.start).unwrap_or(u32::MAX);
    if !diags.is_sorted_by_key(place) {
        diags.sort_by_cached_key(place);
    }
    // Lines and columns are found once lowering is done: by then the line index is built (pass
    // 1 builds it while it reads the lines), and none is looked up for a diagnostic that is
    // never rendered.
    // In file order: each line is looked for from the previous one's.
    let mut cursor = 0;
    for d in &mut diags {
        d.at = d.span.map(|s| doc.source.line_col_from(s.start, &mut cursor));
    }
    (model, diags, not_kept)
}

/// A hash map for the small keys lowering looks things up by (indices, section kinds). The
/// standard hasher resists collision attacks, which costs more than the rest of a lookup; these
/// keys come from one file and the maps are dropped with it, so a multiplicative hash is enough.
pub(crate) type FastMap<K, V> = std::collections::HashMap<K, V, std::hash::BuildHasherDefault<FastHasher>>;

/// The hasher of [`FastMap`]: each word is mixed in with a rotate, an xor and a multiplication.
#[derive(Clone, Copy, Default)]
pub(crate) struct FastHasher(u64);

impl FastHasher {
    #[inline]
    fn add(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x517C_C1B7_2722_0A95);
    }
}

impl std::hash::Hasher for FastHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.add(b as u64);
        }
    }

    #[inline]
    fn write_u8(&mut self, n: u8) {
        self.add(n as u64);
    }

    #[inline]
    fn write_u16(&mut self, n: u16) {
        self.add(n as u64);
    }

    #[inline]
    fn write_u32(&mut self, n: u32) {
        self.add(n as u64);
    }

    #[inline]
    fn write_u64(&mut self, n: u64) {
        self.add(n);
    }

    #[inline]
    fn write_usize(&mut self, n: usize) {
        self.add(n as u64);
    }
}

/// Lowering state shared by the passes: the source and the diagnostics found so far.
pub(crate) struct Ctx<'a> {
    pub src: &'a SourceFile,
    pub strictness: Strictness,
    pub diags: Vec<Diagnostic>,
    /// The severities of recently emitted codes, by the address of the code's text: a file
    /// emits a few codes many times, and the table of all codes, searched between megabytes of
    /// text, is seldom in the cache.
    severities: [(u64, Severity); 16],
    /// The file name every diagnostic shares, made on the first one (most files have none).
    file: Option<std::sync::Arc<str>>,
    /// Once [`MAX_PER_CODE`] diagnostics are kept: how many of each code were found, and how
    /// many of those were not kept.
    counts: Vec<(Code, u32, u32)>,
    /// What [`Ctx::emit`] hands out for a diagnostic that is not kept.
    scratch: Diagnostic,
    /// Where each section header of the file starts, in file order, when a section is
    /// repeated (else empty): entries of a section with no header between them come from the
    /// same occurrence of it ([`sections::report_duplicate`]).
    pub header_starts: Vec<u32>,
    /// How many more implicit CompactSubObj elements the model may hold ([`implicit_budget`]).
    pub implicit_left: usize,
    /// Whether the file has gone over [`implicit_budget`] (E0222 is reported once).
    pub implicit_exceeded: bool,
    /// The least severe diagnostics kept ([`Options::keep_from`]).
    pub least_kept: crate::diag::Severity,
    /// The diagnostics less severe than that, counted.
    pub not_kept: crate::NotKept,
    /// A buffer for the quirks of one value at a time (taken and put back around each use).
    pub quirks: Vec<crate::value::Quirk>,
    /// The buffers of earlier files' models, for this file's ([`pool::Pool`]).
    pub pool: pool::Pool,
}

/// Implicit CompactSubObj elements a file of `len` bytes may declare: 65,536 (256 full arrays;
/// the real files we know declare at most about 2,100) and one per 64 bytes beyond that.
///
/// Each element is a model entry of about 100 bytes, and a tool holding the model and its
/// output needs up to about 320 bytes per element (`odgen fmt`), while `CompactSubObj=255`
/// declares 255 of them in 18 bytes: without a bound, 0.75 MB of such arrays is a model of
/// 1.9 million entries and 230 to 600 MB. With it, the elements cost at most about 21 MB plus
/// 5 bytes per input byte, within the tools' "10 x the input + 64 MB" budget. A file that asks
/// for more gets E0222 (an error), and the arrays past the bound keep only sub-index 0.
pub fn implicit_budget(len: usize) -> usize {
    65_536 + len / 64
}

/// At most this many diagnostics of one code are kept for a file; the rest are counted, and
/// one diagnostic per code says how many were left out. A file of a million bad lines would
/// otherwise hold a million diagnostics (about 300 bytes each, a hundred times the line).
pub const MAX_PER_CODE: u32 = 10_000;

/// At most this many diagnostics are kept for a file in all.
pub const MAX_KEPT: usize = 100_000;

impl<'a> Ctx<'a> {
    /// A context for lowering `src` at `strictness`.
    #[cfg(test)]
    pub fn new(src: &'a SourceFile, strictness: Strictness) -> Self {
        Self::reusing(src, strictness, Vec::new(), 0)
    }

    /// [`Ctx::new`], its diagnostics put in `diags` (emptied), with room for those of a file of
    /// `room_for` bytes if `src` is smaller.
    pub fn reusing(src: &'a SourceFile, strictness: Strictness, diags: Vec<Diagnostic>, room_for: usize) -> Self {
        Ctx {
            src,
            strictness,
            // The real files we test with have a diagnostic per 435 bytes on average: room for
            // one per 256 bytes means few files grow the vector (each growth copies every
            // diagnostic so far, onto fresh memory). Room never written costs no memory, and a
            // reader gives room for the size it expects (files read one after another, largest
            // or not, then share one vector that does not grow).
            diags: sections::with_room(diags, src.text.len().max(room_for) / 256 + 32),
            severities: [(0, Severity::Note); 16],
            file: None,
            counts: Vec::new(),
            scratch: Diagnostic::new(crate::codes::E0002, strictness, "", ""),
            header_starts: Vec::new(),
            implicit_left: implicit_budget(src.text.len()),
            implicit_exceeded: false,
            least_kept: crate::diag::Severity::Note,
            not_kept: crate::NotKept::default(),
            quirks: Vec::new(),
            pool: pool::Pool::default(),
        }
    }

    /// The severity of `code` at this context's strictness ([`crate::codes::severity`]).
    #[inline]
    fn severity(&mut self, code: Code) -> Severity {
        // The address and length of a code's text identify the text, and so the code.
        let key = code.0.as_ptr() as usize as u64 ^ (code.0.len() as u64) << 59;
        let slot = &mut self.severities[(key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 60) as usize];
        if slot.0 != key {
            *slot = (key, crate::codes::severity(code, self.strictness));
        }
        slot.1
    }

    /// Records a diagnostic at `span` (or for the whole file) and returns it for adding context
    /// and a hint.
    pub fn emit(&mut self, code: Code, span: Option<Span>, message: impl Into<String>) -> &mut Diagnostic {
        let severity = self.severity(code);
        if severity < self.least_kept {
            self.count_not_kept(severity);
            return self.scratch();
        }
        // Counting starts when a file has as many diagnostics as one code may keep.
        if self.diags.len() >= MAX_PER_CODE as usize && !self.keep(code) {
            return self.scratch();
        }
        self.diags.push(Diagnostic {
            severity,
            code,
            message: crate::diag::shorten_message(message.into()),
            file: self.file.get_or_insert_with(|| self.src.name.as_str().into()).clone(),
            span,
            // Filled in by `lower` when all are found.
            at: None,
            context: Vec::new(),
            hint: None,
        });
        let last = self.diags.len() - 1;
        &mut self.diags[last]
    }
}

impl Ctx<'_> {
    /// `f` with the context and its buffer of quirks (emptied), taken out of the context while
    /// `f` runs (so that `f` may report them) and put back after: one buffer for every value.
    pub fn with_quirks<R>(&mut self, f: impl FnOnce(&mut Self, &mut Vec<crate::value::Quirk>) -> R) -> R {
        let mut quirks = std::mem::take(&mut self.quirks);
        quirks.clear();
        let r = f(self, &mut quirks);
        self.quirks = quirks;
        r
    }
}

impl Ctx<'_> {
    /// What [`Ctx::emit`] hands out for a diagnostic that is not kept, emptied.
    fn scratch(&mut self) -> &mut Diagnostic {
        self.scratch.message.clear();
        self.scratch.context.clear();
        self.scratch.hint = None;
        &mut self.scratch
    }

    fn count_not_kept(&mut self, severity: crate::diag::Severity) {
        match severity {
            crate::diag::Severity::Note => self.not_kept.notes += 1,
            crate::diag::Severity::Warning => self.not_kept.warnings += 1,
            // (Errors are always kept: no severity is above them.)
            crate::diag::Severity::Error => {}
        }
    }

    /// Whether diagnostics of `code` are kept at all ([`Options::keep_from`]); when they are
    /// not, one is counted, as [`Ctx::emit`] would count it. For the reports made most often,
    /// so that what they would say is not put together only to be dropped:
    /// `if cx.skips(code) { .. } else { cx.emit(code, ..) .. }`.
    #[inline]
    pub fn skips(&mut self, code: Code) -> bool {
        let severity = self.severity(code);
        if severity < self.least_kept {
            self.count_not_kept(severity);
            true
        } else {
            false
        }
    }
}

impl Ctx<'_> {
    /// Counts a diagnostic of `code` and says whether it is kept.
    #[cold]
    fn keep(&mut self, code: Code) -> bool {
        if self.counts.is_empty() {
            for d in &self.diags {
                match self.counts.iter_mut().find(|c| c.0 == d.code) {
                    Some(c) => c.1 += 1,
                    None => self.counts.push((d.code, 1, 0)),
                }
            }
        }
        let total = self.diags.len();
        let i = match self.counts.iter().position(|c| c.0 == code) {
            Some(i) => i,
            None => {
                self.counts.push((code, 0, 0));
                self.counts.len() - 1
            }
        };
        let c = &mut self.counts[i];
        c.1 += 1;
        let keep = c.1 <= MAX_PER_CODE && total < MAX_KEPT;
        if !keep {
            c.2 += 1;
        }
        keep
    }

    /// One diagnostic for each code some of whose diagnostics were not kept.
    fn report_left_out(&mut self) {
        let left_out: Vec<(Code, u32)> = self.counts.iter().filter(|c| c.2 > 0).map(|c| (c.0, c.2)).collect();
        for (code, n) in left_out {
            let severity = self.severity(code);
            let mut d = Diagnostic::new(
                code,
                self.strictness,
                &self.src.name,
                format!(
                    "{n} more {code} diagnostic{} in this file are not listed (at most {MAX_PER_CODE} of a code, \
                     {MAX_KEPT} in all, are kept)",
                    if n == 1 { "" } else { "s" }
                ),
            );
            d.severity = severity;
            d.hint = Some("fix the ones listed and check again".into());
            self.diags.push(d);
        }
    }
}

/// Where in the dictionary a diagnostic is, kept as borrowed parts and only formatted into
/// [`Diagnostic::context`] when a diagnostic is emitted (most entries produce none).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Crumbs<'a> {
    object: Option<(u16, CrumbName<'a>)>,
    sub: Option<(u8, CrumbName<'a>)>,
}

/// The name a breadcrumb shows: a text, or the `ParameterName` of a section's entries, looked
/// for only when a diagnostic needs it (most sections have none to report).
#[derive(Clone, Copy, Debug)]
enum CrumbName<'a> {
    Text(&'a str),
    /// The value of the last `ParameterName` key of `entries` (any case), else `or`.
    Parameter {
        entries: &'a [sections::Kv<'a>],
        or: &'a str,
    },
}

impl<'a> CrumbName<'a> {
    fn get(self) -> &'a str {
        match self {
            CrumbName::Text(s) => s,
            CrumbName::Parameter { entries, or } => sections::parameter_name(entries).unwrap_or(or),
        }
    }
}

impl<'a> Crumbs<'a> {
    /// In object `index` named `name`.
    pub fn object(index: u16, name: &'a str) -> Self {
        Crumbs { object: Some((index, CrumbName::Text(name))), sub: None }
    }

    /// In object `index` named by the `ParameterName` among `entries` (else `or`).
    pub fn object_named_by(index: u16, entries: &'a [sections::Kv<'a>], or: &'a str) -> Self {
        Crumbs { object: Some((index, CrumbName::Parameter { entries, or })), sub: None }
    }

    /// The same object, sub-index `sub` named `name`.
    pub fn sub(self, sub: u8, name: &'a str) -> Self {
        Crumbs { sub: Some((sub, CrumbName::Text(name))), ..self }
    }

    /// The same object, sub-index `sub` named by the `ParameterName` among `entries` (else
    /// nothing).
    pub fn sub_named_by(self, sub: u8, entries: &'a [sections::Kv<'a>]) -> Self {
        Crumbs { sub: Some((sub, CrumbName::Parameter { entries, or: "" })), ..self }
    }

    /// The breadcrumbs as [`Diagnostic::context`] wants them.
    pub fn to_vec(self) -> Vec<String> {
        let mut v = Vec::with_capacity(2);
        if let Some((i, n)) = self.object {
            v.push(object_context(i, n.get()));
        }
        if let Some((s, n)) = self.sub {
            v.push(sub_context(s, n.get()));
        }
        v
    }
}

/// The CiA 306 name of an object type (`VAR`, `RECORD`, ...).
pub(crate) fn otype(t: crate::model::ObjectType) -> &'static str {
    use crate::model::ObjectType as T;
    match t {
        T::Null => "NULL",
        T::Domain => "DOMAIN",
        T::DefType => "DEFTYPE",
        T::DefStruct => "DEFSTRUCT",
        T::Var => "VAR",
        T::Array => "ARRAY",
        T::Record => "RECORD",
    }
}

/// `object 0x1018 "Identity Object"`
pub(crate) fn object_context(index: u16, name: &str) -> String {
    let name = &*crate::diag::shorten(name);
    let mut s = String::with_capacity(name.len() + 16);
    s.push_str("object 0x");
    push_hex4(&mut s, index);
    s.push_str(" \"");
    s.push_str(name);
    s.push('"');
    s
}

/// `sub 2 "Product Code"`
pub(crate) fn sub_context(sub: u8, name: &str) -> String {
    let name = &*crate::diag::shorten(name);
    let mut s = String::with_capacity(name.len() + 10);
    s.push_str("sub ");
    s.push_str(decimal_u8(sub));
    s.push_str(" \"");
    s.push_str(name);
    s.push('"');
    s
}

/// The pieces joined into one string of exactly their length: what `format!` gives for text
/// pieces, for the diagnostics found most often (the formatter costs several times more).
pub(crate) fn cat<const N: usize>(pieces: [&str; N]) -> String {
    let mut s = String::with_capacity(pieces.iter().map(|p| p.len()).sum());
    for p in pieces {
        s.push_str(p);
    }
    s
}

/// `v` as four upper-case hex digits (`format!("{v:04X}")`).
pub(crate) fn hex4(v: u16) -> String {
    let mut s = String::with_capacity(4);
    push_hex4(&mut s, v);
    s
}

/// Appends `v` as four upper-case hex digits (`format!("{v:04X}")` without the formatter).
pub(crate) fn push_hex4(s: &mut String, v: u16) {
    for shift in [12, 8, 4, 0] {
        s.push(char::from(b"0123456789ABCDEF"[(v >> shift) as usize & 0xF]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_formatting_matches_format() {
        for v in [0u16, 1, 0xA, 0x1018, 0xFFFF, 0x0100] {
            let mut s = String::new();
            push_hex4(&mut s, v);
            assert_eq!(s, format!("{v:04X}"));
        }
        assert_eq!(object_context(0x1018, "Identity"), "object 0x1018 \"Identity\"");
        assert_eq!(sub_context(12, "Ä"), "sub 12 \"Ä\"");
        assert_eq!(cat(["a", "", "bc", "Ä"]), "abcÄ");
        for v in 0..=255u8 {
            assert_eq!(decimal_u8(v), v.to_string());
        }
        assert_eq!(cat([]), "");
        assert_eq!(hex4(0x1a0), "01A0");
    }
}
