//! Diagnostics the generator reports, with their stable codes.
//!
//! They are [`eds::Diagnostic`]s, located at the entry of the device description they are about,
//! so they render exactly like the reader's own diagnostics.
//!
//! # Deviations: lenient and strict
//!
//! Real vendor files break rules the generator relies on (a default PDO mapping of an object
//! that does not exist, a limit outside the entry's type, …). Such a *deviation* never stops
//! generation: what it concerns is left out or repaired, everything else is generated, and the
//! tokens compile. In lenient mode (the default) a deviation is a **warning**; in strict mode
//! ([`crate::Options::strict`], `Builder::strict()`, `odgen gen --strict`) it is an **error**,
//! for authors who own their file. The table's "deviation" rows are those; the others have one
//! severity in both modes.
//!
//! | code  | severity | meaning |
//! |-------|----------|---------|
//! | G0001 | warning  | two entries derive the same Rust name; the later one gets a suffix |
//! | G0002 | warning  | an entry has a data type the generator cannot store; it is left out |
//! | G0003 | deviation | a default value does not fit the entry's type; the entry starts at zero |
//! | G0004 | warning  | a limit the runtime cannot enforce (`$NODEID` limit) is ignored |
//! | G0005 | note     | an object of a kind that holds no value (DEFTYPE, DEFSTRUCT, NULL) is left out |
//! | G0006 | error    | the module name is not a Rust identifier |
//! | G0007 | error    | more than 65535 objects: the lookup table cannot number them |
//! | G0008 | deviation | a limit lies outside the entry's type; it is clipped to the type |
//! | G0101 | deviation | a default PDO mapping carries more than 64 bits |
//! | G0102 | deviation | a mapped entry does not have `PDOMapping=1` |
//! | G0103 | deviation | a mapped entry's access type does not allow this PDO direction |
//! | G0104 | deviation | a mapped object does not exist (or a dummy type the device does not support) |
//! | G0105 | deviation | a mapping length does not match the mapped entry |
//! | G0106 | deviation | a mapping object is malformed (count or entry missing, not a number) |
//! | G0107 | warning  | a mapping has a variable-length entry; no typed layout is generated |
//! | G0108 | deviation | a counted mapping entry is `0x00000000` (a placeholder: nothing mapped) |
//! | G0109 | note     | a mapping object has no communication object: a mapping table, not a PDO; no client method |
//! | G0201 | error    | the sidecar's unit description is inconsistent with the device description |
//! | G0202 | error    | the sidecar cannot be read (TOML or schema error, with its own location) |
//!
//! A default PDO mapping with a deviation gets no typed layout (`pdo::Rpdo1`, …); its mapping
//! parameters stay in the dictionary as data, served over SDO and remappable by a master.

use eds::diag::{Code, Diagnostic, Severity};
use eds::model::{Entry, Object, SourceRef};
use eds::source::LineCol;

/// Name collision.
pub const NAME_COLLISION: Code = Code("G0001");
/// Unsupported data type.
pub const UNSUPPORTED_TYPE: Code = Code("G0002");
/// Default out of range.
pub const BAD_DEFAULT: Code = Code("G0003");
/// Limit ignored.
pub const LIMIT_IGNORED: Code = Code("G0004");
/// Object without value left out.
pub const NO_VALUE_OBJECT: Code = Code("G0005");
/// Module name not an identifier.
pub const BAD_MODULE_NAME: Code = Code("G0006");
/// Too many objects for the lookup table.
pub const TOO_MANY_OBJECTS: Code = Code("G0007");
/// Limit outside the entry's type, clipped.
pub const LIMIT_CLIPPED: Code = Code("G0008");
/// PDO longer than 64 bits.
pub const PDO_TOO_LONG: Code = Code("G0101");
/// Mapped entry lacks `PDOMapping=1`.
pub const PDO_NOT_MAPPABLE: Code = Code("G0102");
/// Mapped entry has the wrong access direction.
pub const PDO_ACCESS: Code = Code("G0103");
/// Mapped object missing.
pub const PDO_NO_OBJECT: Code = Code("G0104");
/// Mapping length mismatch.
pub const PDO_LENGTH: Code = Code("G0105");
/// Malformed mapping object.
pub const PDO_MALFORMED: Code = Code("G0106");
/// Variable-length entry in a mapping.
pub const PDO_VARIABLE: Code = Code("G0107");
/// Placeholder mapping entry `0x00000000` inside the counted range.
pub const PDO_PLACEHOLDER: Code = Code("G0108");
/// Mapping object without its communication object (a mapping table, not a PDO).
pub const PDO_NO_COMM: Code = Code("G0109");
/// Unit description inconsistent.
pub const UNITS: Code = Code("G0201");
/// Sidecar unreadable.
pub const SIDECAR: Code = Code("G0202");

/// Builds diagnostics for one source file.
#[derive(Debug)]
pub(crate) struct Sink {
    file: std::sync::Arc<str>,
    strict: bool,
    pub(crate) out: Vec<Diagnostic>,
}

impl Sink {
    pub(crate) fn new(file: &str, strict: bool) -> Self {
        Sink { file: file.into(), strict, out: Vec::new() }
    }

    /// The severity of a deviation: a warning when lenient, an error when strict.
    pub(crate) fn deviation(&self) -> Severity {
        if self.strict { Severity::Error } else { Severity::Warning }
    }

    /// Reports at an entry (context: object, then sub-object).
    pub(crate) fn at_entry(&mut self, severity: Severity, code: Code, obj: &Object, entry: &Entry, message: String) {
        let mut context = vec![object_context(obj)];
        if obj.object_type.has_subs() {
            context.push(format!("sub {} \"{}\"", entry.sub.0, entry.name));
        }
        self.push(severity, code, entry.at, context, message);
    }

    /// Reports at an object.
    pub(crate) fn at_object(&mut self, severity: Severity, code: Code, obj: &Object, message: String) {
        self.push(severity, code, obj.at, vec![object_context(obj)], message);
    }

    /// Reports without a location in the device description.
    pub(crate) fn general(&mut self, severity: Severity, code: Code, message: String) {
        self.out.push(Diagnostic {
            severity,
            code,
            message,
            file: self.file.clone(),
            span: None,
            at: None,
            context: Vec::new(),
            hint: None,
        });
    }

    fn push(&mut self, severity: Severity, code: Code, at: SourceRef, context: Vec<String>, message: String) {
        let located = at.line > 0;
        self.out.push(Diagnostic {
            severity,
            code,
            message,
            file: self.file.clone(),
            span: located.then_some(at.span),
            at: located.then_some(LineCol { line: at.line, col: at.col.max(1) }),
            context,
            hint: None,
        });
    }

    /// Adds a hint to the last diagnostic.
    pub(crate) fn hint(&mut self, hint: impl Into<std::borrow::Cow<'static, str>>) {
        if let Some(d) = self.out.last_mut() {
            d.hint = Some(hint.into());
        }
    }
}

fn object_context(obj: &Object) -> String {
    format!("object 0x{:04X} \"{}\"", obj.index.0, obj.name)
}

/// Renders diagnostics one per line, `file:line:col: severity[code]: message (context)`, for
/// places without the source text at hand.
pub fn render_plain(diags: &[Diagnostic]) -> String {
    let mut s = String::new();
    for d in diags {
        let sev = match d.severity {
            Severity::Note => "note",
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        let loc = match d.at {
            Some(lc) => format!("{}:{}:{}", d.file, lc.line, lc.col),
            None => d.file.to_string(),
        };
        s.push_str(&format!("{loc}: {sev}[{}]: ", d.code.0));
        if !d.context.is_empty() {
            s.push_str(&format!("in {}: ", d.context.join(", ")));
        }
        s.push_str(&d.message);
        if let Some(h) = &d.hint {
            s.push_str(&format!(" (hint: {h})"));
        }
        s.push('\n');
    }
    s
}

/// One diagnostic as one short line: `file:line:col: warning[G0104]: message` (no context,
/// no hint), as a build script prints it.
pub fn short_line(d: &Diagnostic) -> String {
    match d.at {
        Some(lc) => format!("{}:{}:{}: {}[{}]: {}", d.file, lc.line, lc.col, d.severity, d.code.0, d.message),
        None => format!("{}: {}[{}]: {}", d.file, d.severity, d.code.0, d.message),
    }
}

/// Every code the generator reports, with its lenient severity, whether it is a deviation and
/// one line saying what it is about (the table of the module docs), for tools that list rules
/// (`odgen check --format sarif`).
pub const ALL: &[eds::codes::CodeInfo] = {
    use eds::codes::CodeInfo as C;
    const fn c(code: Code, lenient: Severity, deviation: bool, summary: &'static str) -> C {
        C { code, lenient, deviation, summary }
    }
    use Severity::{Error as E, Note as N, Warning as W};
    &[
        c(NAME_COLLISION, W, false, "two entries derive the same Rust name; the later one gets a suffix"),
        c(UNSUPPORTED_TYPE, W, false, "an entry has a data type the generator cannot store; it is left out"),
        c(BAD_DEFAULT, W, true, "a default value does not fit the entry's type; the entry starts at zero"),
        c(LIMIT_IGNORED, W, false, "a limit the runtime cannot enforce ($NODEID limit) is ignored"),
        c(NO_VALUE_OBJECT, N, false, "an object of a kind that holds no value is left out"),
        c(BAD_MODULE_NAME, E, false, "the module name is not a Rust identifier"),
        c(TOO_MANY_OBJECTS, E, false, "more than 65535 objects: the lookup table cannot number them"),
        c(LIMIT_CLIPPED, W, true, "a limit lies outside the entry's type; it is clipped to the type"),
        c(PDO_TOO_LONG, W, true, "a default PDO mapping carries more than 64 bits"),
        c(PDO_NOT_MAPPABLE, W, true, "a mapped entry does not have PDOMapping=1"),
        c(PDO_ACCESS, W, true, "a mapped entry's access type does not allow this PDO direction"),
        c(PDO_NO_OBJECT, W, true, "a mapped object does not exist"),
        c(PDO_LENGTH, W, true, "a mapping length does not match the mapped entry"),
        c(PDO_MALFORMED, W, true, "a mapping object is malformed"),
        c(PDO_VARIABLE, W, false, "a mapping has a variable-length entry; no typed layout is generated"),
        c(PDO_PLACEHOLDER, W, true, "a counted mapping entry is 0x00000000 (a placeholder)"),
        c(PDO_NO_COMM, N, false, "a mapping object has no communication object: a mapping table, not a PDO"),
        c(UNITS, E, false, "the sidecar's unit description is inconsistent with the device description"),
        c(SIDECAR, E, false, "the sidecar cannot be read"),
    ]
};

/// The codes of deviations: warnings in lenient mode, errors in strict mode (see the module
/// docs).
pub const DEVIATIONS: &[Code] = &[
    BAD_DEFAULT,
    LIMIT_CLIPPED,
    PDO_TOO_LONG,
    PDO_NOT_MAPPABLE,
    PDO_ACCESS,
    PDO_NO_OBJECT,
    PDO_LENGTH,
    PDO_MALFORMED,
    PDO_PLACEHOLDER,
];
