//! Lowering and validation: [`crate::ast::Document`] → [`crate::model::Model`] + diagnostics.

use crate::ast::{Document, LineKind};
use crate::diag::Diagnostic;
use crate::model::Model;
use crate::source::Encoding;
use crate::{Options, codes};

/// Lowers a lexed document into the typed model and validates it.
pub fn lower(doc: &Document, options: &Options) -> (Model, Vec<Diagnostic>) {
    let mut diags = Vec::new();
    let file = &doc.source.name;
    if doc.source.encoding == Encoding::Windows1252 {
        diags.push(Diagnostic::new(
            codes::E0001,
            options.strictness,
            file,
            "file is not valid UTF-8; decoded as Windows-1252",
        ));
    }
    for line in &doc.lines {
        if line.kind == LineKind::Garbage {
            let mut d =
                Diagnostic::new(codes::E0002, options.strictness, file, "line is not a section, an entry or a comment");
            d.span = Some(line.content);
            d.at = Some(doc.source.line_col(line.content.start));
            diags.push(d);
        }
    }
    (Model::default(), diags)
}
