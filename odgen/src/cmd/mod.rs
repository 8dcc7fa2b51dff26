//! One module per subcommand.

pub mod bench_read;
pub mod check;
pub mod dcf;
pub mod dump;
pub mod fmt;

use std::path::Path;

/// Exit code for "ran, found errors" (diagnostics with errors, files not canonical).
pub const EXIT_FAILURE: u8 = 1;
/// Exit code for "could not do what was asked" (unreadable file, bad arguments).
pub const EXIT_TROUBLE: u8 = 2;

/// Reads a file, or prints why not (`error: cannot read X: ...`) and gives `None`.
pub fn read_or_report(path: &Path, options: &eds::Options) -> Option<eds::Parsed> {
    match eds::read_file(path, options) {
        Ok(p) => Some(p),
        Err(e) => {
            eprintln!("error: cannot read {}: {e}", path.display());
            None
        }
    }
}
