//! `odgen fmt`: rewrite files in the canonical form of `eds::write`.
//!
//! A file is only rewritten when it has no errors and when reading the rewritten text gives the
//! same model back; otherwise it is left alone and the reason printed. Comment lines (`;`) are
//! not part of the model and are dropped: the tool says how many.

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

fn format_one(path: &Path, check: bool) -> Outcome {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: cannot read {}: {e}", path.display());
            return Outcome::Failed;
        }
    };
    let name = path.display().to_string();
    let parsed = eds::parse(&name, &bytes, &eds::Options::lenient());
    if parsed.has_errors() {
        for d in parsed.errors() {
            eprintln!("{}", eds::diag::render(d, &parsed.document.source));
        }
        eprintln!("error: not formatting {name}: fix its errors first");
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
    if text.as_bytes() == bytes.as_slice() {
        return Outcome::Canonical;
    }
    if check {
        let first = first_difference(&bytes, text.as_bytes());
        super::outln!("{name}: not in canonical form (first difference at line {first})");
        return Outcome::NotCanonical;
    }
    let comments =
        parsed.document.lines().iter().filter(|l| matches!(l.kind, eds::ast::LineKind::Comment { .. })).count();
    if let Err(e) = write_atomically(path, text.as_bytes()) {
        eprintln!("error: cannot write {name}: {e}");
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

/// Writes `path` via a temporary file in the same directory and a rename, so an interrupted
/// run never leaves a half-written description.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{file_name}.odgen-{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}
