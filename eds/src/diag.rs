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
