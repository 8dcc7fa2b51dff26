//! Diagnostics for network descriptions: located in the TOML file, with the device description
//! (EDS) as a second location where the problem is about one of its objects.
//!
//! A [`Diagnostic`] carries its quoted lines with it ([`Snippet`]), so it can be rendered,
//! compared or serialised without the files it came from.

use std::fmt::Write as _;
use std::ops::Range;

use eds::source::SourceFile;
use serde::Serialize;

pub use eds::diag::Severity;

/// A stable diagnostic code for network descriptions (`N0401`, ...). The codes are listed in the
/// [`codes`] module.
pub type Code = &'static str;

/// The codes of network diagnostics, grouped by hundreds.
pub mod codes {
    use super::Code;

    /// The network file is not valid TOML.
    pub const TOML_SYNTAX: Code = "N0001";
    /// A key the format does not know (the help names the closest known key).
    pub const UNKNOWN_KEY: Code = "N0002";
    /// A required key is missing.
    pub const MISSING_KEY: Code = "N0003";
    /// A value has the wrong TOML type (a string where a number belongs, ...).
    pub const WRONG_TYPE: Code = "N0004";
    /// A node name that cannot be a file name.
    pub const BAD_NODE_NAME: Code = "N0005";
    /// The network has no nodes.
    pub const NO_NODES: Code = "N0006";
    /// A device description cannot be read.
    pub const DEVICE_UNREADABLE: Code = "N0101";
    /// A device description has errors.
    pub const DEVICE_ERRORS: Code = "N0102";
    /// A node id outside 1..=127.
    pub const BAD_NODE_ID: Code = "N0201";
    /// Two nodes with one node id.
    pub const NODE_ID_COLLISION: Code = "N0202";
    /// A bit rate CANopen does not define.
    pub const BAD_BAUD_RATE: Code = "N0301";
    /// A bit rate the device does not support.
    pub const UNSUPPORTED_BAUD_RATE: Code = "N0302";
    /// Nodes on one bus with different bit rates, or none given.
    pub const BAUD_RATE_MISMATCH: Code = "N0303";
    /// A name or index that is not in the device's dictionary.
    pub const UNKNOWN_OBJECT: Code = "N0401";
    /// A name of an ARRAY or RECORD where one of its entries is meant.
    pub const NOT_AN_ENTRY: Code = "N0402";
    /// A PDO the device does not have.
    pub const NO_SUCH_PDO: Code = "N0501";
    /// A PDO whose mapping cannot hold what is asked (fixed mapping, too few mapping entries).
    pub const MAPPING_CAPACITY: Code = "N0502";
    /// An object with `PDOMapping=0`.
    pub const NOT_MAPPABLE: Code = "N0503";
    /// An object whose access type does not allow the PDO's direction.
    pub const MAPPING_ACCESS: Code = "N0504";
    /// A mapping longer than 64 bits.
    pub const PDO_TOO_LONG: Code = "N0505";
    /// A mapped object whose length cannot be mapped (strings, DOMAIN, mismatched lengths).
    pub const MAPPING_LENGTH: Code = "N0506";
    /// A PDO setting the device's communication object has no entry for, or that does not
    /// apply to the PDO's direction.
    pub const PDO_SETTING: Code = "N0507";
    /// A configured value the entry cannot take (type, range, limits, access).
    pub const BAD_VALUE: Code = "N0601";
    /// One entry configured twice.
    pub const CONFIGURED_TWICE: Code = "N0602";
}

/// A quoted source line with the part a diagnostic is about underlined.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Snippet {
    /// File name as shown to the user.
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column (characters).
    pub col: u32,
    /// The whole line, tabs shown as spaces, trailing white space removed.
    pub text: String,
    /// How many characters to underline (0: none, the line is only quoted).
    pub width: u32,
}

impl Snippet {
    /// The snippet for byte range `span` of `source`, shown as `file`.
    pub fn at(source: &SourceFile, file: &str, span: Range<usize>) -> Self {
        let lc = source.line_col(span.start as u32);
        let line = source.line_text(lc.line);
        let text: String = line.chars().map(|c| if c == '\t' { ' ' } else { c }).collect();
        let text = text.trim_end().to_owned();
        let covered = source.text.get(span.clone()).unwrap_or("");
        let first_line = covered.split(['\n', '\r']).next().unwrap_or("");
        let line_chars = text.chars().count() as u32;
        let start = lc.col.saturating_sub(1).min(line_chars);
        let width = (first_line.chars().count() as u32).min(line_chars.saturating_sub(start)).max(1);
        Snippet { file: file.to_owned(), line: lc.line, col: lc.col, text, width }
    }

    /// The line of a device description where an object or entry section starts (quoted, not
    /// underlined: the whole section is meant).
    pub fn eds(source: &SourceFile, file: &str, at: eds::model::SourceRef) -> Option<Self> {
        if at.line == 0 {
            return None;
        }
        let text = source.line_text(at.line).trim_end().to_owned();
        Some(Snippet { file: file.to_owned(), line: at.line, col: at.col.max(1), text, width: 0 })
    }
}

/// A secondary message, optionally with its own location.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Note {
    /// The message.
    pub message: String,
    /// Where (usually an object of a device description).
    pub at: Option<Snippet>,
}

/// One problem in a network description.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    /// How bad.
    pub severity: Severity,
    /// Stable code (see [`codes`]).
    pub code: Code,
    /// What is wrong, in one sentence.
    pub message: String,
    /// Where in the network file (or the device description, for problems of the device itself).
    pub at: Option<Snippet>,
    /// Breadcrumbs, outermost first: `node \`x_axis\` (devices/camozzi-drvi.eds)`, `TPDO 1`.
    pub context: Vec<String>,
    /// Further locations, e.g. the EDS object a mapping names.
    pub notes: Vec<Note>,
    /// How to fix it, where known.
    pub help: Option<String>,
}

impl Diagnostic {
    /// An error with a message and nothing else.
    pub fn error(code: Code, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Error,
            code,
            message: message.into(),
            at: None,
            context: Vec::new(),
            notes: Vec::new(),
            help: None,
        }
    }

    /// Sets the primary location.
    pub fn at(mut self, at: Snippet) -> Self {
        self.at = Some(at);
        self
    }

    /// Adds a breadcrumb.
    pub fn context(mut self, c: impl Into<String>) -> Self {
        self.context.push(c.into());
        self
    }

    /// Adds a note, located or not.
    pub fn note(mut self, message: impl Into<String>, at: Option<Snippet>) -> Self {
        self.notes.push(Note { message: message.into(), at });
        self
    }

    /// Sets the help text.
    pub fn help(mut self, h: impl Into<String>) -> Self {
        self.help = Some(h.into());
        self
    }
}

fn push_snippet(out: &mut String, s: &Snippet, arrow: &str, pad: &str) {
    let _ = writeln!(out, "{pad}{arrow} {}:{}:{}", s.file, s.line, s.col);
    let _ = writeln!(out, "{pad} |");
    let _ = writeln!(out, "{:>w$} | {}", s.line, s.text, w = pad.len());
    if s.width > 0 {
        let _ = writeln!(out, "{pad} | {}{}", " ".repeat(s.col as usize - 1), "^".repeat(s.width as usize));
    } else {
        let _ = writeln!(out, "{pad} |");
    }
}

/// Renders a diagnostic the way rustc does; notes with a location quote their line after a
/// `:::` arrow:
///
/// ```text
/// error[N0504]: `statusword` is `ro`, but an RPDO carries values the master writes
///     --> networks/line.toml:7:25
///      |
///    7 | rpdo1 = ["controlword", "statusword"]
///      |                         ^^^^^^^^^^^^
///      = note: in node `x_axis` (devices/camozzi-drvi.eds), RPDO 1
///      = note: the run-time check refuses it with SDO abort 0x06040041: maps 0x6041 sub 0 "Statusword" with access `ro` into an RPDO, which needs wo, rw or rww
/// note: 0x6041 "Statusword" is defined here
///     ::: devices/camozzi-drvi.eds:2371:2
///      |
/// 2371 | [6041]
///      |
///      = help: map it into a TPDO, or pick an entry with access wo, rw or rww
/// ```
pub fn render(d: &Diagnostic) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{}[{}]: {}", d.severity, d.code, d.message);
    let width = std::iter::once(d.at.as_ref())
        .chain(d.notes.iter().map(|n| n.at.as_ref()))
        .flatten()
        .map(|s| s.line.to_string().len())
        .max()
        .unwrap_or(1);
    let pad = " ".repeat(width);
    if let Some(at) = &d.at {
        push_snippet(&mut out, at, "-->", &pad);
    }
    if !d.context.is_empty() {
        let _ = writeln!(out, "{pad} = note: in {}", d.context.join(", "));
    }
    for n in &d.notes {
        match &n.at {
            Some(at) => {
                let _ = writeln!(out, "note: {}", n.message);
                push_snippet(&mut out, at, ":::", &pad);
            }
            None => {
                let _ = writeln!(out, "{pad} = note: {}", n.message);
            }
        }
    }
    if let Some(h) = &d.help {
        let _ = writeln!(out, "{pad} = help: {h}");
    }
    out
}

/// Renders every diagnostic, one blank line between them, and a summary line.
pub fn render_all(diagnostics: &[Diagnostic]) -> String {
    let mut out = String::new();
    for d in diagnostics {
        out.push_str(&render(d));
        out.push('\n');
    }
    let errors = diagnostics.iter().filter(|d| d.severity == Severity::Error).count();
    let warnings = diagnostics.iter().filter(|d| d.severity == Severity::Warning).count();
    let plural = |n: usize, w: &str| format!("{n} {w}{}", if n == 1 { "" } else { "s" });
    let _ = writeln!(out, "{}, {}", plural(errors, "error"), plural(warnings, "warning"));
    out
}
