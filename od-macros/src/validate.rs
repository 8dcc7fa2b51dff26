//! Dictionary-wide validation of an inline dictionary, by the same code that validates EDS files.
//!
//! The `eds` crate validates while it lowers text (its checks read sections and keys), and has
//! no entry point that takes a ready-made [`Model`]. Rather than re-implement those checks, or
//! change the reader for this one caller, the macro goes through text:
//!
//! 1. write the lowered model with [`eds::write::write_eds`] (the canonical EDS, which is also
//!    what the generated `EDS` constant holds);
//! 2. read it back with [`eds::parse`], lenient or strict as the input asks;
//! 3. map every diagnostic's position in that text back to the macro input: the text position
//!    gives the section and key (`[1600sub3]`, `DefaultValue`), that gives `(index, sub-index,
//!    part)`, and [`Spans`](crate::lower::Spans) gives the tokens that declared it.
//!
//! So a dictionary declared inline passes exactly when the EDS it stands for passes `odgen check`
//! (with `--strict` for `strict;`). The round trip is also checked: every object must read back
//! equal to the one declared, so the `EDS` constant never misrepresents the dictionary.
//!
//! The generator's diagnostics (for example a default PDO mapping longer than 64 bits) carry
//! the positions of the entries they concern, which are positions in the same text, and are
//! mapped back the same way ([`report_codegen`]).

use std::collections::BTreeSet;

use eds::ast::{Document, LineKind};
use eds::diag::{Diagnostic, Severity};
use eds::model::Model;
use eds::source::{SourceFile, Span};

use crate::ctxt::{Ctxt, Loc};
use crate::lower::{Field, Lowered};

/// What the section and key at a text position stand for.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Place {
    /// A part of an object or of one of its entries.
    Entry { index: u16, sub: Option<u8>, field: Field },
    /// A key (lower case) of `[FileInfo]` or `[DeviceInfo]`; `None` for the section itself.
    Info(Option<String>),
    /// Anywhere else, or the whole file.
    Whole,
}

/// What each line of the written text belongs to.
struct Locator {
    source: SourceFile,
    /// Per line: the section it is in, and its key if it is an entry.
    lines: Vec<(Section, Option<String>)>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Section {
    Object(u16),
    Sub(u16, u8),
    Info,
    Other,
}

fn classify(name: &str) -> Section {
    let hex4 = |s: &str| (s.len() == 4).then(|| u16::from_str_radix(s, 16).ok()).flatten();
    if name.eq_ignore_ascii_case("FileInfo") || name.eq_ignore_ascii_case("DeviceInfo") {
        return Section::Info;
    }
    if let Some(i) = hex4(name) {
        return Section::Object(i);
    }
    if let (Some(i), Some(rest)) = (name.get(..4).and_then(hex4), name.get(4..))
        && let Some(sub) = rest.get(..3).filter(|p| p.eq_ignore_ascii_case("sub")).and_then(|_| rest.get(3..))
        && let Ok(s) = u8::from_str_radix(sub, 16)
    {
        return Section::Sub(i, s);
    }
    Section::Other
}

impl Locator {
    fn new(doc: &Document) -> Self {
        let mut section = Section::Other;
        let mut lines = Vec::with_capacity(doc.lines().len());
        for line in doc.lines() {
            let key = match &line.kind {
                LineKind::Section { name, .. } => {
                    section = classify(doc.source.slice(*name));
                    None
                }
                LineKind::Entry { key, .. } => Some(doc.source.slice(*key).to_ascii_lowercase()),
                _ => None,
            };
            lines.push((section, key));
        }
        Locator { source: doc.source.clone(), lines }
    }

    fn place(&self, span: Option<Span>, model: &Model) -> Place {
        let Some(span) = span else { return Place::Whole };
        let line = self.source.line_col(span.start).line as usize;
        let Some((section, key)) = line.checked_sub(1).and_then(|i| self.lines.get(i)) else { return Place::Whole };
        let field = match key.as_deref() {
            Some("parametername") => Field::Name,
            Some("datatype") => Field::Type,
            Some("accesstype") => Field::Access,
            Some("pdomapping") => Field::Pdo,
            Some("defaultvalue") => Field::Default,
            Some("lowlimit") => Field::Low,
            Some("highlimit") => Field::High,
            _ => Field::Decl,
        };
        match *section {
            Section::Object(index) => {
                // A VAR keeps its only entry (sub-index 0) in the object's own section.
                let var = model.object(index).is_some_and(|o| !o.object_type.has_subs());
                Place::Entry { index, sub: var.then_some(0), field }
            }
            Section::Sub(index, sub) => Place::Entry { index, sub: Some(sub), field },
            Section::Info => {
                let key =
                    key.as_ref().map(|k| if k.starts_with("baudrate_") { "baudrate".to_owned() } else { k.clone() });
                Place::Info(key)
            }
            Section::Other => Place::Whole,
        }
    }
}

/// The lowered model after validation.
pub(crate) struct Checked {
    /// The model, with source positions in [`Checked::eds_text`].
    pub model: Model,
    /// The canonical EDS of the model.
    pub eds_text: String,
    /// Its file name (`<module>.eds`).
    pub file_name: String,
    locator: Locator,
    /// Objects the EDS reader reported an error about (the generator's findings about them
    /// are then left out: they are almost always the same problem again).
    reported: BTreeSet<u16>,
}

/// Whether a diagnostic is about something that already had an error in the front end.
fn suppressed(l: &Lowered, place: &Place) -> bool {
    match place {
        Place::Entry { index, sub, .. } => {
            l.poisoned.contains(index)
                || sub.and_then(|s| l.map_targets.get(&(*index, s))).is_some_and(|t| l.poisoned.contains(t))
        }
        Place::Info(_) => l.device_poisoned,
        Place::Whole => l.had_errors,
    }
}

fn resolve(l: &Lowered, place: &Place) -> Loc {
    let whole = l.strict.unwrap_or(l.input);
    match place {
        Place::Entry { index, sub, field } => l.spans.entry(*index, *sub, *field).unwrap_or(whole),
        Place::Info(key) => {
            key.as_ref().and_then(|k| l.spans.info_keys.get(k)).copied().or(l.spans.device).unwrap_or(whole)
        }
        Place::Whole => whole,
    }
}

/// The message of a diagnostic about the written EDS, for a compile error on the macro input.
fn message(d: &Diagnostic) -> String {
    let mut m = format!("{} [{}]", d.message, d.code);
    if !d.context.is_empty() {
        m.push_str(&format!("\n= note: in {}", d.context.join(", ")));
    }
    if let Some(h) = &d.hint {
        m.push_str(&format!("\n= help: {h}"));
    }
    m
}

/// Writes the lowered model as an EDS, reads it back with the EDS reader's validation, and
/// reports every error on the macro input.
pub(crate) fn check(l: &Lowered, cx: &mut Ctxt) -> Checked {
    let file_name = format!("{}.eds", l.module);
    let eds_text = eds::write::write_eds(&l.model);
    let options = if l.strict.is_some() { eds::Options::strict() } else { eds::Options::lenient() };
    let parsed = eds::parse(&file_name, eds_text.as_bytes(), &options);
    let locator = Locator::new(&parsed.document);
    let mut reported = BTreeSet::new();
    for d in parsed.errors() {
        let place = locator.place(d.span, &l.model);
        if suppressed(l, &place) {
            continue;
        }
        if let Place::Entry { index, .. } = place {
            reported.insert(index);
        }
        cx.error(resolve(l, &place), message(d));
    }

    // The round trip: what the EDS says must be what was declared.
    for (index, obj) in &l.model.objects {
        if parsed.model.objects.get(index) != Some(obj) {
            let at = l.spans.objects.get(&index.0).copied().unwrap_or(l.input);
            cx.error(
                at,
                format!(
                    "object 0x{:04X} does not read back the same from the EDS text it is written as; \
                     check its names and texts for characters an EDS line cannot hold",
                    index.0
                ),
            );
        }
    }
    if parsed.model.file_info != l.model.file_info || parsed.model.device_info != l.model.device_info {
        cx.error(
            l.spans.device.unwrap_or(l.input),
            "the device description does not read back the same from the EDS text it is written as",
        );
    }

    // Give the model the positions of its text, for the generator's diagnostics.
    let mut model = l.model.clone();
    for (index, obj) in model.objects.iter_mut() {
        let Some(read) = parsed.model.objects.get(&index) else { continue };
        obj.at = read.at;
        for (sub, e) in obj.subs.iter_mut() {
            if let Some(r) = read.subs.get(&sub) {
                e.at = r.at;
            }
        }
    }
    Checked { model, eds_text, file_name, locator, reported }
}

/// Reports the generator's errors and warnings on the macro input. Warnings count as errors
/// here: in a dictionary written inline they always mean that something declared is renamed
/// or left out of the typed API, which the author can fix at once.
pub(crate) fn report_codegen(l: &Lowered, checked: &Checked, diags: &[Diagnostic], cx: &mut Ctxt) {
    for d in diags.iter().filter(|d| d.severity >= Severity::Warning) {
        let place = checked.locator.place(d.span, &l.model);
        if suppressed(l, &place) {
            continue;
        }
        if let Place::Entry { index, .. } = place
            && checked.reported.contains(&index)
        {
            continue;
        }
        cx.error(resolve(l, &place), message(d));
    }
}
