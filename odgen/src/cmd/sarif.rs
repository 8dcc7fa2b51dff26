//! `odgen check --format sarif`: diagnostics as SARIF 2.1.0 (OASIS Static Analysis Results
//! Interchange Format), the format code-scanning services read to annotate files in pull
//! requests.
//!
//! One run; the tool's rules are every diagnostic code (`ruleIndex` is the code's place in
//! [`eds::codes::ALL`] followed by `od_codegen::diag::ALL`); one result per diagnostic, located by file, line and column (columns
//! count characters: `columnKind` is `unicodeCodePoints`); files that could not be read are
//! tool execution notifications of the run's invocation. Written directly, as it goes.

use std::fmt::Write as _;

use eds::diag::push_json_str;
use eds::{Diagnostic, Severity};

use super::Stream;

fn level(s: Severity) -> &'static str {
    match s {
        Severity::Error => "error",
        Severity::Warning => "warning",
        Severity::Note => "note",
    }
}

/// A file path as a URI reference: relative paths stay relative (to the directory `odgen` ran
/// in), absolute ones become `file://` URIs; bytes outside the unreserved set and `/` are
/// percent-encoded.
pub fn path_uri(path: &str) -> String {
    let mut out = String::with_capacity(path.len() + 8);
    if path.starts_with('/') {
        out.push_str("file://");
    }
    for b in path.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~' | b'/') {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// Writes the log's start: the tool and its rules, and opens the results. Then come the results
/// ([`push_result`], separated by commas) and [`finish`].
pub fn start(out: &mut Stream) {
    out.with(|buf| {
        buf.push_str(
            "{\"$schema\":\"https://json.schemastore.org/sarif-2.1.0.json\",\"version\":\"2.1.0\",\"runs\":[{",
        );
        let _ = write!(
            buf,
            "\"tool\":{{\"driver\":{{\"name\":\"odgen\",\"version\":\"{}\",\"rules\":[",
            env!("CARGO_PKG_VERSION")
        );
        for (i, info) in rules().enumerate() {
            if i > 0 {
                buf.push(',');
            }
            let _ = write!(buf, "\n{{\"id\":\"{}\",\"shortDescription\":{{\"text\":", info.code);
            push_json_str(buf, info.summary);
            let _ = write!(
                buf,
                "}},\"defaultConfiguration\":{{\"level\":\"{}\"}},\"properties\":{{\"deviation\":{}}}}}",
                level(info.lenient),
                info.deviation
            );
        }
        buf.push_str("]}},\"columnKind\":\"unicodeCodePoints\",\"results\":[");
    });
}

/// The rules: the reader's codes ([`eds::codes::ALL`]), then the generator's
/// ([`od_codegen::diag::ALL`]), which `odgen check` reports too.
pub fn rules() -> impl Iterator<Item = &'static eds::codes::CodeInfo> {
    eds::codes::ALL.iter().chain(od_codegen::diag::ALL)
}

/// Appends one result (a JSON object).
pub fn push_result(buf: &mut String, d: &Diagnostic, source: &eds::source::SourceFile) {
    let index = rules().position(|c| c.code == d.code);
    buf.push('{');
    let _ = write!(buf, "\"ruleId\":\"{}\",", d.code);
    if let Some(i) = index {
        let _ = write!(buf, "\"ruleIndex\":{i},");
    }
    let _ = write!(buf, "\"level\":\"{}\",\"message\":{{\"text\":", level(d.severity));
    let mut text = d.message.clone();
    if !d.context.is_empty() {
        text.push_str("\nin ");
        text.push_str(&d.context.join(", "));
    }
    if let Some(h) = &d.hint {
        text.push_str("\nhelp: ");
        text.push_str(h);
    }
    push_json_str(buf, &text);
    buf.push_str("},\"locations\":[{\"physicalLocation\":{\"artifactLocation\":{\"uri\":");
    push_json_str(buf, &path_uri(&d.file));
    buf.push('}');
    if let (Some(span), Some(at)) = (d.span, d.at) {
        let end = source.line_col(span.end);
        let _ = write!(
            buf,
            ",\"region\":{{\"startLine\":{},\"startColumn\":{},\"endLine\":{},\"endColumn\":{}}}",
            at.line,
            at.col,
            end.line.max(at.line),
            if end.line > at.line { end.col } else { end.col.max(at.col) }
        );
    }
    buf.push_str("}}]}");
}

/// Closes the results and writes the invocation, with a notification for each file that could
/// not be read (`(path, reason)`).
pub fn finish(out: &mut Stream, unreadable: &[(String, String)]) {
    out.with(|buf| {
        let _ = write!(buf, "\n],\"invocations\":[{{\"executionSuccessful\":{}", unreadable.is_empty());
        buf.push_str(",\"toolExecutionNotifications\":[");
        for (i, (file, reason)) in unreadable.iter().enumerate() {
            if i > 0 {
                buf.push(',');
            }
            buf.push_str("\n{\"level\":\"error\",\"message\":{\"text\":");
            push_json_str(buf, &format!("cannot read {file}: {reason}"));
            buf.push_str("},\"locations\":[{\"physicalLocation\":{\"artifactLocation\":{\"uri\":");
            push_json_str(buf, &path_uri(file));
            buf.push_str("}}}]}");
        }
        buf.push_str("]}]}]}\n");
    });
}
