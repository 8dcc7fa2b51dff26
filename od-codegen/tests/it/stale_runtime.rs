//! The versioning invariant: generated code names od-runtime's support module by its versioned
//! absolute path (`::od_runtime::__private_v3::…`), so code and runtime from different interface
//! versions do not compile together, and the error names the module the code expected.
//!
//! Two compile-fail cases (`tests/stale/*.rs` with their `.stderr`), both made from the code
//! this generator writes for a one-entry device, compiled by the workspace's compile tests
//! (`ui-tests/tests/ui.rs`, the workspace's one trybuild project):
//!
//! * `older_generator.rs`: code written against an earlier interface (`__private_v2`), compiled
//!   with today's runtime: "cannot find `__private_v2` in `od_runtime`".
//! * `newer_runtime.rs`: today's code, compiled with a runtime whose interface moved on to
//!   `__private_v4` (simulated: the file names itself `od_runtime`, re-exports the real runtime's
//!   public modules and offers only `__private_v4`): "cannot find `__private_v3` in
//!   `od_runtime`".
//!
//! The fixtures are checked in so trybuild can compare the compiler's output; a test keeps
//! them equal to what the generator writes today (`ODGEN_BLESS=1` rewrites them).

use crate::common;

use std::path::PathBuf;

use common::{model, var};
use eds::model::{Access, DataType, Value};
use od_codegen::{Options, RUNTIME_PRIVATE, generate, render};

/// The generated module of a one-entry device.
fn tiny() -> String {
    let m = model(vec![var(0x2000, "Speed", DataType::Unsigned8, Access::Rw, Some(Value::int(7)), false)]);
    let tokens = generate(&m, &Options::new("tiny", "tiny.eds"));
    render(&tokens, "tiny.eds").expect("generated code renders")
}

fn older_generator() -> String {
    format!(
        "//! Code generated against the support module of an earlier interface version.\n\n{}\nfn main() {{}}\n",
        tiny().replace(RUNTIME_PRIVATE, "__private_v2")
    )
}

fn newer_runtime() -> String {
    format!(
        "//! Today's generated code with a runtime whose support module moved on to `__private_v4`.\n\
         \n\
         extern crate od_runtime as real_runtime;\n\
         extern crate self as od_runtime;\n\
         \n\
         pub use real_runtime::{{od, pdo}};\n\
         \n\
         /// The next interface version (the same items, renamed module).\n\
         pub mod __private_v4 {{\n    pub use real_runtime::{RUNTIME_PRIVATE}::*;\n}}\n\
         \n{}\nfn main() {{}}\n",
        tiny()
    )
}

fn fixtures() -> [(PathBuf, String); 2] {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/stale");
    [(dir.join("older_generator.rs"), older_generator()), (dir.join("newer_runtime.rs"), newer_runtime())]
}

#[test]
fn fixtures_are_what_the_generator_writes() {
    let bless = std::env::var_os("ODGEN_BLESS").is_some();
    for (path, text) in fixtures() {
        let current = std::fs::read_to_string(&path).unwrap_or_default();
        if bless {
            if current != text {
                std::fs::write(&path, &text).unwrap();
            }
        } else {
            assert!(current == text, "{} is stale: rerun with ODGEN_BLESS=1", path.display());
        }
    }
}

#[test]
fn fixtures_differ_from_todays_code_only_in_the_version() {
    let [(_, older), (_, newer)] = fixtures();
    assert!(older.contains("::od_runtime::__private_v2::") && !older.contains(RUNTIME_PRIVATE));
    assert!(newer.contains(&format!("::od_runtime::{RUNTIME_PRIVATE}::")));
}
