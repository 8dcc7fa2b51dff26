//! `odgen fmt`: rewrite files in the canonical form of `eds::write`.
//!
//! A file is only rewritten when it has no errors, no line the reader ignored (listed instead)
//! and when reading the rewritten text gives the same model back; otherwise it is left alone and
//! the reason printed. Comment lines (`;`) are not part of the model and are dropped: the tool
//! says how many. The file is replaced through [`odgen::safe_write`]: through symbolic links,
//! keeping its mode and owner; devices, FIFOs and read-only files are refused.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// `odgen fmt [--check] FILE...`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Change nothing; exit 1 if any file is not in canonical form.
    #[arg(long)]
    pub check: bool,
    /// EDS or DCF files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
}

enum Outcome {
    Canonical,
    Rewritten,
    NotCanonical,
    Failed,
}

/// Runs the subcommand.
pub fn run(args: Args) -> ExitCode {
    let mut failed = 0;
    let mut not_canonical = 0;
    for path in &args.files {
        match format_one(path, args.check) {
            Outcome::Canonical | Outcome::Rewritten => {}
            Outcome::NotCanonical => not_canonical += 1,
            Outcome::Failed => failed += 1,
        }
    }
    if failed > 0 {
        ExitCode::from(EXIT_TROUBLE)
    } else if not_canonical > 0 {
        ExitCode::from(EXIT_FAILURE)
    } else {
        ExitCode::SUCCESS
    }
}

/// Codes of diagnostics that say the reader ignored a line: formatting would drop the line, so
/// a file with any is refused, with the list.
const IGNORED_LINES: [eds::Code; 2] = [eds::codes::E0002, eds::codes::E0003];

/// At most this many ignored lines are listed when a file is refused for them.
const LISTED: usize = 20;

fn format_one(path: &Path, check: bool) -> Outcome {
    let name = path.display().to_string();
    // (Refuses FIFOs and devices before opening them: `fmt /dev/null` changes nothing.)
    let bytes = match eds::read_bytes(path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: cannot read {name}: {e}");
            return Outcome::Failed;
        }
    };
    let parsed = eds::parse(&name, &bytes, &eds::Options::lenient());
    if parsed.has_errors() {
        for d in parsed.errors() {
            eprintln!("{}", eds::diag::render(d, &parsed.document.source));
        }
        eprintln!("error: not formatting {name}: fix its errors first");
        return Outcome::Failed;
    }
    let ignored: Vec<&eds::Diagnostic> =
        parsed.diagnostics.iter().filter(|d| IGNORED_LINES.contains(&d.code)).collect();
    if !ignored.is_empty() {
        let n = ignored.len();
        eprintln!(
            "error: not formatting {name}: the reader ignored {n} line{} that the canonical form would drop:",
            if n == 1 { "" } else { "s" }
        );
        let source = &parsed.document.source;
        for d in ignored.iter().take(LISTED) {
            let line = d.at.map_or(0, |a| a.line);
            eprintln!("  line {line}: {}", eds::diag::shorten(source.line_text(line).trim()));
        }
        if n > LISTED {
            eprintln!("  … and {} more", n - LISTED);
        }
        eprintln!("  (make each a `;` comment, move it into its section, or remove it; `odgen check` says why)");
        return Outcome::Failed;
    }
    let unrepresentable = eds::write::unrepresentable(&parsed.model);
    if !unrepresentable.is_empty() {
        eprintln!("error: not formatting {name}: the canonical form cannot say what the file says:");
        for u in unrepresentable.iter().take(LISTED) {
            eprintln!("  {u}");
        }
        if unrepresentable.len() > LISTED {
            eprintln!("  … and {} more", unrepresentable.len() - LISTED);
        }
        return Outcome::Failed;
    }
    let text = eds::write::write(&parsed.model);
    // Safety net: never replace a file with text that means something else.
    let back = eds::parse(&name, text.as_bytes(), &eds::Options::lenient());
    if back.model != parsed.model {
        eprintln!(
            "error: not formatting {name}: the canonical text would not read back as the same model (a bug in odgen; please report it)"
        );
        return Outcome::Failed;
    }
    drop(back);
    if text.as_bytes() == bytes.as_slice() {
        return Outcome::Canonical;
    }
    if check {
        let first = first_difference(&bytes, text.as_bytes());
        super::outln!("{name}: not in canonical form (first difference at line {first})");
        return Outcome::NotCanonical;
    }
    // Counted as the lexer yields the lines, none kept (a file of 50M blank lines made a
    // 3 GB list of lines only to count its comments).
    let comments = eds::lex::Lexer::new(&parsed.document.source.text)
        .filter(|l| matches!(l.kind, eds::ast::LineKind::Comment { .. }))
        .count();
    drop(parsed);
    drop(bytes);
    if let Err(e) = odgen::safe_write::write(path, text.as_bytes()) {
        eprintln!("error: cannot write {e}");
        return Outcome::Failed;
    }
    if comments > 0 {
        eprintln!(
            "warning: {name}: {comments} comment line{} dropped (comments are not part of the model)",
            if comments == 1 { "" } else { "s" }
        );
    }
    super::outln!("formatted {name}");
    Outcome::Rewritten
}

/// 1-based line number of the first line that differs.
fn first_difference(a: &[u8], b: &[u8]) -> usize {
    let same = a.iter().zip(b).take_while(|(x, y)| x == y).count();
    a[..same].iter().filter(|&&c| c == b'\n').count() + 1
}
