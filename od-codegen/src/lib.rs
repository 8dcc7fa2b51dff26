#![doc = include_str!("../README.md")]
//! # Three ways in
//!
//! * **build.rs**, in the style of `prost-build`:
//!
//!   ```no_run
//!   // build.rs: fn main() { … }
//!   od_codegen::Builder::new()
//!       .device("drvi", "../devices/camozzi-drvi.eds")
//!       .compile()
//!       .unwrap_or_else(|e| panic!("{e}"));
//!   ```
//!
//!   and in the crate, `include!(concat!(env!("OUT_DIR"), "/drvi.rs"));` brings in
//!   `pub mod drvi` (the file defines the module itself, so it can sit at the crate root). See [`Builder`] for what the build
//!   script reads, writes and tells Cargo.
//! * **`cargo xtask gen`** regenerates the checked-in crate `generated/` (one feature per device)
//!   through the same [`Builder`] with [`Builder::out_dir`]; `cargo xtask gen --check` fails when
//!   it is stale.
//! * **The library**: [`generate`] (pure: model in, tokens out) and [`render`] (tokens to text),
//!   or [`expand_text`] and [`GeneratedText::render`] (model to text, the `Builder`'s path).
//!
//! # What the generated module looks like
//!
//! For a device whose EDS has a VAR `[6040]` "Controlword" (UNSIGNED16, rww, PDO-mappable) and
//! an RPDO 1 mapping `0x60400010`, the module contains, among others:
//!
//! ```text
//! pub mod drvi {
//!     pub const EDS: &str = r#"[FileInfo] ..."#;
//!     pub mod index { pub const CONTROLWORD: u16 = 0x6040; /* ... */ }
//!     pub static ENTRIES: [::od_runtime::od::EntryInfo; N] = [/* sorted by (index, sub) */];
//!     pub struct Dictionary { /* one typed field per entry */ }
//!     impl Dictionary {
//!         pub const fn new(node_id: u8) -> Self;                  // defaults, $NODEID resolved
//!         pub const fn controlword(&self) -> u16;
//!         pub fn set_controlword(&mut self, v: u16) -> Result<(), AbortCode>;  // limits checked
//!         pub fn bus_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
//!         pub fn check_rpdo_mapping(mapping: &[u32]) -> Result<u32, AbortCode>;
//!     }
//!     impl ::od_runtime::od::ObjectDictionary for Dictionary { /* table-driven */ }
//!     pub mod pdo {
//!         pub struct Rpdo1 { pub controlword: u16 }
//!         impl Rpdo1 { pub fn pack(&self) -> [u8; 2]; pub fn unpack(data: &[u8]) -> Result<Self, LengthError>; }
//!     }
//!     pub mod units { /* with a sidecar: Units::from_dictionary, typed quantities */ }
//! }
//! ```
//!
//! The OD, PDO and unit code uses only `core` and `::od_runtime` (by absolute paths), so it
//! compiles in `#![no_std]` crates and never allocates. The code is data-driven: the per-entry
//! parts are tables, field declarations, inline accessors and two `match`es handing out field
//! references; everything else is generic code in od-runtime's hidden, versioned support module
//! `::od_runtime::__private_v3` ([`RUNTIME_PRIVATE`]). Code generated against another version
//! of that module does not compile, with an error naming the module it expected: regenerate it.
//!
//! # Storage types
//!
//! | CiA 301 type | Rust type |
//! |---|---|
//! | BOOLEAN | `bool` |
//! | UNSIGNED8/16/32/64, INTEGER8/16/32/64 | `u8`..`u64`, `i8`..`i64` |
//! | UNSIGNED24, INTEGER24 | `u32`, `i32`; setters check the 24-bit range |
//! | UNSIGNED40/48/56, INTEGER40/48/56, TIME_OF_DAY, TIME_DIFFERENCE | `u64`, `i64`; range checked |
//! | REAL32, REAL64 | `f32`, `f64` |
//! | VISIBLE_STRING, UNICODE_STRING (UTF-16LE), OCTET_STRING, DOMAIN | a fixed-capacity buffer |
//!
//! A buffer's capacity is the length of its default, but at least [`Options::min_capacity`]
//! bytes (default [`DEFAULT_MIN_CAPACITY`]). Entries of other (complex) types are left out with
//! a warning.
//!
//! # Names
//!
//! Names come from `ParameterName` through one policy (see the `ident` module docs): a VAR's
//! accessor is its name in `snake_case` (`Controlword` → `controlword`), a sub-entry's is the
//! object's name and the sub-entry's own words joined, without the words it repeats from its
//! object (`Identity object` / `Vendor-ID` → `identity_object_vendor_id`; `Error history` /
//! `Error history 1` → `error_history_1`). Objects sharing one name take their PDO/SDO number
//! or their place among them (`rpdo_mapping_parameter_2_mapped_object_1`), elements sharing one
//! name their sub-index. A clash the rules do not resolve gets the index suffix and one warning
//! per object.
//!
//! # Lenient and strict
//!
//! What a description gets wrong for the generator (a default PDO mapping that breaks a mapping
//! rule, a limit outside the entry's type, …) is a *deviation*: left out or repaired, reported
//! as a warning, or as an error with [`Options::strict`]. See [`diag`].
//!
//! # Values
//!
//! A dictionary starts from each entry's DCF `ParameterValue` if present, else its EDS
//! `DefaultValue` (`$NODEID` resolved by `Dictionary::new(node_id)`), and
//! `restore_defaults` returns to the same values: for a DCF, the configured values are the
//! device's power-on values.
#![deny(missing_docs)]

mod builder;
mod client;
pub mod diag;
mod emit;
mod entry;
pub mod ident;
mod lit;
mod lookup;
pub mod network;
pub mod pdo;
mod plan;
pub mod standard;
mod support;
mod text;
pub mod units;

use eds::model::Model;
use proc_macro2::TokenStream;
use quote::{format_ident, quote};

pub use builder::{Builder, Error, Output, write_if_changed};
pub use support::RUNTIME_PRIVATE;

/// The EDS/DCF reader (`eds::parse`, the model, diagnostics), re-exported so a build script
/// that calls [`expand`] itself needs `od-codegen` as its only build-dependency.
pub use eds;
/// Diagnostics as both the reader and the generator report them.
pub use eds::diag::{Diagnostic, Severity};
/// The sidecar schema ([`sidecar::Sidecar`]: units, scaling, modes, error tables), an input of
/// the generator ([`Options::sidecar`]).
pub use od_sidecar as sidecar;

/// The smallest capacity, in bytes, of a generated string or byte buffer.
pub const DEFAULT_MIN_CAPACITY: usize = 32;

/// What to generate.
#[derive(Clone, Debug)]
pub struct Options {
    /// Name of the generated module (`drvi` → `pub mod drvi`); must be a Rust identifier.
    pub module: String,
    /// The file the model came from, as shown in the header and in diagnostics.
    pub source_name: String,
    /// The device description's text, emitted as `pub const EDS: &str` (line ends normalised
    /// to `\n`); no `EDS` constant if `None`.
    pub eds_text: Option<String>,
    /// The device sidecar, for unit conversions. Without one, a description with CiA 402
    /// objects gets the units derived from them ([`standard::starting_sidecar`]); with one,
    /// CiA 402's positions, velocities and accelerations it does not name are added
    /// ([`standard::effective_sidecar`]).
    pub sidecar: Option<crate::sidecar::Sidecar>,
    /// Smallest capacity of a string or byte buffer, in bytes.
    pub min_capacity: usize,
    /// Strict mode: every deviation ([`diag::DEVIATIONS`]) is an error instead of a warning.
    pub strict: bool,
    /// Whether to generate the entries' names (`NAMES`, `ObjectDictionary::name`).
    pub names: Names,
    /// Whether to generate the master's view of the device too: `pub mod remote` with a
    /// `Remote` on `od_master::Node` (the generated code then needs `od-master`, `od-runtime`
    /// and `std`). See `od_master::remote`.
    pub client: bool,
}

/// Whether generated code holds the entries' names (about 40 bytes of flash per entry).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum Names {
    /// Always (the default).
    #[default]
    Always,
    /// Never: `ObjectDictionary::name` answers `None`.
    Never,
    /// When the crate the code is compiled in has this cargo feature enabled (the
    /// `generated` crate: `names`, a default feature).
    Feature(String),
}

impl Options {
    /// Options for module `module` generated from `source_name`.
    pub fn new(module: impl Into<String>, source_name: impl Into<String>) -> Self {
        Options {
            module: module.into(),
            source_name: source_name.into(),
            eds_text: None,
            sidecar: None,
            min_capacity: DEFAULT_MIN_CAPACITY,
            strict: false,
            names: Names::Always,
            client: false,
        }
    }
}

/// Generated tokens and everything found while generating them.
#[derive(Clone, Debug)]
pub struct Generated {
    /// `pub mod <module> { … }`.
    pub tokens: TokenStream,
    /// Diagnostics located in the device description, in generation order.
    pub diagnostics: Vec<Diagnostic>,
}

impl Generated {
    /// Whether any diagnostic is an error (the [`Builder`] then fails).
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }
}

/// Generates the module for one device. Pure: no IO, deterministic. Diagnostics are dropped;
/// use [`expand`] to get them.
pub fn generate(model: &Model, options: &Options) -> TokenStream {
    expand(model, options).tokens
}

/// Generates the module for one device and reports what it found.
///
/// Entries or PDO layouts with deviations or errors are left out or repaired (so the tokens
/// always compile, for every model); the diagnostics say what and why. Whether a deviation is a
/// warning or an error is [`Options::strict`]'s choice.
pub fn expand(model: &Model, options: &Options) -> Generated {
    let mut parts = text::Parts::tokens();
    let (tokens, diagnostics) = expand_with(model, options, &mut parts);
    Generated { tokens, diagnostics }
}

/// A generated module on its way to text: what [`expand_text`] gives and the [`Builder`] (and
/// so `odgen gen`) writes with [`GeneratedText::render`].
///
/// The large, repetitive parts of the module (the index constants, the entry and name tables,
/// the `Dictionary` struct, its constructors and accessors) are already text, laid out as
/// prettyplease lays them out; only the rest goes through syn and prettyplease. The file is the
/// same as [`render`] makes of [`expand`]'s tokens (a test holds the two paths to each other).
#[derive(Clone, Debug)]
pub struct GeneratedText {
    /// The module with a placeholder item for each part already written as text.
    skeleton: TokenStream,
    /// The placeholders' name prefix.
    prefix: String,
    parts: Vec<String>,
    /// Diagnostics located in the device description, in generation order.
    pub diagnostics: Vec<Diagnostic>,
}

impl GeneratedText {
    /// Whether any diagnostic is an error (the [`Builder`] then fails).
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }

    /// The formatted Rust file with the `@generated` [`header`] naming `source_name`.
    ///
    /// Returns an error (never panics) if the tokens are not a valid file, which would be a bug
    /// in the generator.
    pub fn render(&self, source_name: &str) -> Result<String, syn::Error> {
        let rest = render(&self.skeleton, source_name)?;
        Ok(text::splice(&rest, &self.prefix, &self.parts))
    }
}

/// Generates the module for one device as text (the [`Builder`]'s path, much faster than
/// [`render`] of [`expand`] in a debug build script), and reports what it found.
pub fn expand_text(model: &Model, options: &Options) -> GeneratedText {
    let mut parts = text::Parts::text(options.eds_text.as_deref());
    let (skeleton, diagnostics) = expand_with(model, options, &mut parts);
    let (prefix, parts) = parts.into_texts();
    GeneratedText { skeleton, prefix, parts, diagnostics }
}

fn expand_with(model: &Model, options: &Options, parts: &mut text::Parts) -> (TokenStream, Vec<Diagnostic>) {
    let options = &with_standard_units(model, options);
    let mut sink = diag::Sink::new(&options.source_name, options.strict);
    let module = match syn::parse_str::<syn::Ident>(&options.module) {
        Ok(_) => format_ident!("{}", options.module),
        Err(_) => {
            sink.general(
                Severity::Error,
                diag::BAD_MODULE_NAME,
                format!("module name `{}` is not a Rust identifier; using `device`", options.module),
            );
            format_ident!("device")
        }
    };
    let plan = plan::build(model, options, &mut sink);
    let eds_const = match options.eds_text.as_deref() {
        Some(text) => {
            let text = lit::text_block(&text.replace("\r\n", "\n"));
            quote! {
                /// The device description this module was generated from.
                pub const EDS: &str = #text;
            }
        }
        None => TokenStream::new(),
    };
    let index = emit::index_consts(&plan, parts);
    let tables = emit::tables(&plan, &options.names, &mut sink, parts);
    let dictionary = emit::dictionary(model, &plan, &options.names, options.sidecar.as_ref(), parts);
    let device = emit::device_type(model, &plan);
    let aliases = standard::dictionary_aliases(&plan);
    let pdo = pdo::module(model, &plan, &mut sink);
    let units = match &options.sidecar {
        Some(sc) => units::module(model, &plan, sc, &mut sink),
        None => TokenStream::new(),
    };
    let product = model.device_info.product_name.as_deref().unwrap_or(&options.source_name);
    let client = if options.client {
        client::module(model, &plan, options.sidecar.as_ref(), !units.is_empty(), product)
    } else {
        TokenStream::new()
    };
    let mod_doc = lit::doc(&[
        format!("Object dictionary, PDO layouts and units of the {}.", lit::doc_escape(product)),
        String::new(),
        format!("Generated by od-codegen from `{}`.", lit::doc_escape(&options.source_name)),
    ]);
    let tokens = quote! {
        #mod_doc
        #[allow(dead_code, clippy::approx_constant, clippy::excessive_precision, clippy::unreadable_literal)]
        pub mod #module {
            #eds_const

            #index
            #tables
            #dictionary
            #aliases
            #device
            #pdo
            #units
            #client
        }
    };
    let mut diagnostics = sink.out;
    diagnostics.sort_by_key(|d| d.at.map(|a| (a.line, a.col)));
    (tokens, diagnostics)
}

/// The generator's diagnostics for `model` with `options`, without generating anything: what
/// [`expand`] and [`expand_text`] report, in the same order (`odgen check` adds them to the
/// reader's, so a build and `odgen check` say the same things about a file).
pub fn diagnose(model: &Model, options: &Options) -> Vec<Diagnostic> {
    let options = &with_standard_units(model, options);
    let mut sink = diag::Sink::new(&options.source_name, options.strict);
    if syn::parse_str::<syn::Ident>(&options.module).is_err() {
        sink.general(
            Severity::Error,
            diag::BAD_MODULE_NAME,
            format!("module name `{}` is not a Rust identifier; using `device`", options.module),
        );
    }
    let plan = plan::build(model, options, &mut sink);
    let keys: Vec<(u16, u8)> = plan.entries.iter().map(|e| (e.index, e.sub)).collect();
    if lookup::tokens(&keys).is_none() {
        // As `emit::tables` says it.
        sink.general(
            Severity::Error,
            diag::TOO_MANY_OBJECTS,
            format!(
                "the device has more than {} objects, or objects in more than {} ranges of 256 \
                 indices; the generated lookup table cannot number them",
                lookup::MAX_OBJECTS,
                lookup::MAX_PAGES
            ),
        );
    }
    pdo::check_layouts(model, &plan, &mut sink);
    if let Some(sc) = &options.sidecar {
        let _ = units::module(model, &plan, sc, &mut sink);
    }
    let mut diagnostics = sink.out;
    diagnostics.sort_by_key(|d| d.at.map(|a| (a.line, a.col)));
    diagnostics
}

/// `options` with the sidecar the generator uses ([`standard::effective_sidecar`]): the given
/// one with CiA 402's dimensions added, or one derived from the file's CiA 402 objects.
fn with_standard_units(model: &Model, options: &Options) -> Options {
    let mut o = options.clone();
    o.sidecar = standard::effective_sidecar(model, options.sidecar.as_ref(), &options.source_name);
    o
}

/// Whether a diagnostic is shown when the codes in `allowed` are allowed: errors always are;
/// a warning or note is not when its code is allowed (as rustc's and clippy's `allow`).
pub fn shown(d: &Diagnostic, allowed: &[String]) -> bool {
    d.severity == Severity::Error || !allowed.iter().any(|a| a.eq_ignore_ascii_case(d.code.0))
}

/// The first line of a generated file: the generator and the description it was generated
/// from (as given: the [`Builder`] names it relative to the crate, never by an absolute path).
pub fn header(source_name: &str) -> String {
    format!("// @generated by od-codegen {} from {source_name}; do not edit.", env!("CARGO_PKG_VERSION"))
}

/// The accessor (getter) name [`generate`] gives each entry of `model`, as `(index, sub,
/// name)` in `(index, sub)` order; the setter is `set_` + the name. Entries left out of the
/// generated code (complex types, DEFTYPE/DEFSTRUCT objects) have none. For tools that name
/// entries the way the generated code does (`odgen`'s network descriptions).
pub fn accessor_names(model: &Model) -> Vec<(u16, u8, String)> {
    let mut sink = diag::Sink::new("", false);
    let options = Options::new("device", "");
    plan::build(model, &options, &mut sink).entries.into_iter().map(|e| (e.index, e.sub, e.field)).collect()
}

/// The name the accessors of each object's entries start with (its `ParameterName` in
/// `snake_case`, with the number objects sharing one name take), by index, for every object
/// that holds values.
pub fn object_names(model: &Model) -> Vec<(u16, String)> {
    plan::object_names(model)
}

/// Renders generated tokens as a formatted Rust file with the `@generated` [`header`] naming
/// `source_name`.
///
/// Returns an error (never panics) if the tokens are not a valid file, which would be a bug in
/// the generator.
pub fn render(tokens: &TokenStream, source_name: &str) -> Result<String, syn::Error> {
    let file: syn::File = syn::parse2(tokens.clone())?;
    let body = prettyplease::unparse(&file);
    Ok(format!("{}\n\n{body}", header(source_name)))
}
