//! Diagnostics: one type for every problem found in a file, rendered like rustc or as JSON.
//!
//! Each diagnostic has a stable [`Code`], a severity for lenient mode, and a flag saying whether
//! it is a CiA 306 deviation (strict mode turns deviations into errors).

use serde::{Deserialize, Serialize};

use crate::source::{LineCol, Span};

/// How bad it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Information (e.g. an unknown key that was kept).
    Note,
    /// Something is off, but the file can be used.
    Warning,
    /// The file (or this part of it) cannot be used as written.
    Error,
}

/// A stable diagnostic code, such as `E0201`. The list of codes is in [`crate::codes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Code(pub &'static str);

/// One problem in one file.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnostic {
    /// Severity after applying the strictness level.
    pub severity: Severity,
    /// Stable code.
    pub code: Code,
    /// What is wrong, in one sentence.
    pub message: String,
    /// File name as given by the user.
    pub file: String,
    /// Where (`None` for whole-file problems such as a missing section).
    pub span: Option<Span>,
    /// Line and column of `span.start`.
    pub at: Option<LineCol>,
    /// Where in the dictionary, innermost last: `object 0x1018 "Identity Object"`, `sub 2
    /// "Product Code"`.
    pub context: Vec<String>,
    /// How to fix it, where known.
    pub hint: Option<String>,
}

impl Diagnostic {
    /// A diagnostic for `code` with its severity at `strictness` (see [`crate::codes`]).
    pub fn new(code: Code, strictness: crate::Strictness, file: &str, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: crate::codes::severity(code, strictness),
            code,
            message: message.into(),
            file: file.to_owned(),
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

impl std::fmt::Display for Severity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Severity::Note => "note",
            Severity::Warning => "warning",
            Severity::Error => "error",
        })
    }
}

impl std::fmt::Display for Code {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
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
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(out, "{}[{}]: {}", d.severity, d.code, d.message);
    let at = d.span.map(|s| (s, d.at.unwrap_or_else(|| source.line_col(s.start))));
    let gutter = at.map(|(_, lc)| lc.line.to_string().len()).unwrap_or(1);
    let pad = " ".repeat(gutter);
    match at {
        Some((span, lc)) => {
            let _ = writeln!(out, "{pad}--> {}:{}:{}", d.file, lc.line, lc.col);
            let line = source.line_text(lc.line);
            let shown: String = line.chars().map(|c| if c == '\t' { ' ' } else { c }).collect();
            let _ = writeln!(out, "{pad} |");
            let _ = writeln!(out, "{} | {}", lc.line, shown.trim_end());
            // Underline the part of the span that lies on this line (at least one caret).
            let line_chars = line.chars().count() as u32;
            let start_col = lc.col.saturating_sub(1).min(line_chars);
            let span_text = source.slice(span);
            let span_chars = span_text.split(['\n', '\r']).next().unwrap_or("").chars().count() as u32;
            let width = span_chars.min(line_chars.saturating_sub(start_col)).max(1);
            let _ = writeln!(out, "{pad} | {}{}", " ".repeat(start_col as usize), "^".repeat(width as usize));
        }
        None => {
            let _ = writeln!(out, "{pad}--> {}", d.file);
        }
    }
    if !d.context.is_empty() {
        let _ = writeln!(out, "{pad} = note: in {}", d.context.join(", "));
    }
    if let Some(h) = &d.hint {
        let _ = writeln!(out, "{pad} = help: {h}");
    }
    out
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
