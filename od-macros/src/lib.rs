#![doc = include_str!("../README.md")]
//! # `object_dictionary!`: a dictionary declared inline
//!
//! ```
//! od_macros::object_dictionary! {
//!     mod demo;        // the generated module (default: `od`)
//!     strict;          // validate like `odgen check --strict` (optional)
//!
//!     device {
//!         vendor_name = "Example Automation",
//!         vendor_id = 0x0000_0ABC,
//!         product_name = "Demo I/O",
//!         product_code = 0x42,
//!         revision = 0x0001_0000,
//!         baud_rates = [125, 250, 500, 1000],
//!     }
//!
//!     var 0x1000 "Device type": u32, ro, default = 0x0000_0191;
//!     var 0x1001 "Error register": u8, ro, pdo, default = 0;
//!     record 0x1018 "Identity object" {
//!         1 "Vendor-ID": u32, ro, default = 0x0000_0ABC;
//!         2 "Product code": u32, ro, default = 0x42;
//!     }
//!     record 0x1200 "SDO server parameter" {
//!         1 "COB-ID client to server": u32, ro, default = NODEID + 0x600;
//!         2 "COB-ID server to client": u32, ro, default = NODEID + 0x580;
//!     }
//!     array 0x6000 "Read inputs": u8, ro, pdo, len = 2, element = "Input", default = 0;
//!     var 0x6200 "Write outputs": u8, rww, pdo, default = 0;
//!     var 0x2000 "Setpoint": i16, rww, pdo, default = 0, min = -1000, max = 1000;
//!
//!     rpdo 1: map = [0x6200, 0x2000];
//!     tpdo 1: event_timer = 100, map = [0x6000:1, 0x6000:2, 0x1001];
//! }
//!
//! let mut od = demo::Dictionary::new(5);
//! assert_eq!(od.sdo_server_parameter_cob_id_client_to_server(), 0x605);
//! od.set_setpoint(-20).unwrap();
//! assert!(od.set_setpoint(2000).is_err()); // outside min..=max
//! assert!(demo::EDS.contains("[6000sub2]"));
//! ```
//!
//! ## The language
//!
//! Items end with `;` (or with their `{ … }` body), in any order:
//!
//! | item | meaning |
//! |---|---|
//! | `mod name;` | name of the generated module (default `od`) |
//! | `strict;` | every CiA 306 deviation is an error (as `odgen check --strict`) |
//! | `device { key = value, … }` | `vendor_name`, `vendor_id`, `product_name`, `product_code`, `revision`, `order_code`, `baud_rates = [kbit/s, …]`, `granularity` (default 8), `description`, `created_by`, `file_version` (default 1), `file_revision` (default 0), `simple_boot_up_master` (default `false`), `simple_boot_up_slave` (default `true`), `lss_supported` |
//! | `var INDEX "Name": TYPE, ACCESS, props;` | a VAR |
//! | `array INDEX "Name": TYPE, ACCESS, props, len = N;` | an ARRAY of N elements named `"Element 1"`… (`element = "Input"` names them `"Input 1"`…) |
//! | `array INDEX "Name": TYPE, ACCESS, props { SUB "Name", props; … }` | an ARRAY with named elements (sub-indices 1..=254) |
//! | `record INDEX "Name" { SUB "Name": TYPE, ACCESS, props; … }` | a RECORD |
//! | `rpdo N: props;` / `tpdo N: props;` | PDO N's communication (0x1400/0x1800 + N − 1) and mapping (0x1600/0x1A00 + N − 1) objects |
//!
//! * `TYPE` is a CiA 301 name (`UNSIGNED16`, `VISIBLE_STRING`, `TIME_OF_DAY`, …) or a Rust
//!   primitive (`bool`, `u8`…`u64`, `i8`…`i64`, `f32`, `f64`).
//! * `ACCESS` is `ro`, `wo`, `rw`, `rwr`, `rww` or `const`.
//! * Entry props: `pdo` (PDO-mappable), `default = V`, `min = V`, `max = V`. Array elements take
//!   type, access, `pdo` and (unless they give their own) values from the array.
//! * Values: integers (`0x` hex stays hex in the EDS), `-5`, `1.5`, `"text"`, `b"\x01\x02"`,
//!   `true`/`false`, and `NODEID + 0x180` (also `$NODEID + …`, `0x180 + NODEID`), kept symbolic
//!   and resolved by `Dictionary::new(node_id)`.
//! * Sub-index 0 of an ARRAY or RECORD (the highest sub-index, `u8`, `ro`) is generated unless
//!   the body declares it with its own type and access, as 0x1003 needs:
//!   `array 0x1003 "Pre-defined error field": u32, ro { 0 "Number of errors": u8, rw, default = 0; 1 "Standard error field 1"; }`.
//! * PDO props: `cob_id` (default: the predefined connection set, `NODEID + 0x200`… for RPDOs
//!   1–4 and `NODEID + 0x180`… for TPDOs 1–4, else `0x80000000`), `transmission` (default
//!   `0xFF`), `inhibit` (TPDOs), `event_timer`, `capacity` (mapping entries, default 8) and
//!   `map = [0x6040, 0x6000:1, …]`, whose lengths come from the mapped entries' types.
//!
//! ## What is checked, and where errors go
//!
//! Every mistake in one compile, each on the tokens that caused it:
//!
//! * the macro's own checks: syntax, unknown types, access keywords and properties, indices
//!   and sub-indices out of range, duplicates, values that do not fit their type or limits,
//!   PDO mappings that name undeclared or variable-length entries;
//! * the EDS reader's validation: the dictionary is written as its EDS and read back by
//!   [`canopen_eds::parse`](https://docs.rs/canopen-eds), lenient or strict; every error it
//!   reports about that text is mapped back to the declaration of the object, entry and key it
//!   concerns (so a missing mandatory object under `strict;` fails the build, and the
//!   dictionary compiles exactly when its EDS passes `odgen check`);
//! * the generator's checks (default PDO mappings longer than 64 bits, entries mapped against
//!   their access direction or without `pdo`), where its warnings count as errors too.
//!
//! The generated module's `EDS` constant is that canonical EDS text.
//!
//! # `include_eds!`: a dictionary from a file
//!
//! ```text
//! od_macros::include_eds!("devices/camozzi-drvi.eds");                // pub mod camozzi_drvi
//! od_macros::include_eds!("devices/camozzi-drvi.eds", mod drvi, strict);
//! od_macros::include_eds!("devices/camozzi-drvi.eds", mod drvi, client); // + drvi::remote::Remote
//! od_macros::include_eds!("vendor/akd.eds", mod akd, allow(G0104, E0502)); // those codes not reported
//! ```
//!
//! The path is relative to the crate's `Cargo.toml` (`CARGO_MANIFEST_DIR`). A sidecar beside
//! the file (`camozzi-drvi.toml`) is read as `od_codegen::Builder` reads it, so the module is
//! the same one a build script would write. Both files are tracked (through `include_bytes!`),
//! so editing them rebuilds the crate. The reader's errors (lenient unless `strict`) and the
//! generator's errors are reported on the path literal, as `file:line:col: message` with the
//! offending line quoted. Warnings (what `odgen check` and a build script with
//! `od_codegen::Builder` report for the file: the same codes and text) are compiler warnings
//! on the path literal, one short line each (a proc macro has no warnings of its own on stable
//! Rust: each is the use of a deprecated constant whose note is the diagnostic);
//! `allow(CODE, …)` silences codes, `allow(warnings)` all of them.
#![deny(missing_docs)]

mod ast;
mod ctxt;
mod expand;
mod lower;
mod validate;

#[cfg(test)]
mod tests;

use proc_macro::TokenStream;

/// Declares an object dictionary inline and expands to its generated module. See the
/// [crate documentation](crate) for the language.
#[proc_macro]
pub fn object_dictionary(input: TokenStream) -> TokenStream {
    expand::object_dictionary(input.into()).into()
}

/// Reads an EDS or DCF at compile time (path relative to `CARGO_MANIFEST_DIR`) and expands to
/// its generated module. See the [crate documentation](crate).
#[proc_macro]
pub fn include_eds(input: TokenStream) -> TokenStream {
    let dir = std::env::var_os("CARGO_MANIFEST_DIR").map(std::path::PathBuf::from);
    expand::include_eds(input.into(), dir.as_deref()).into()
}
