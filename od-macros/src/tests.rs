//! In-process tests of both macros: the expansion functions run on `proc_macro2` tokens, so
//! models, generated code and error positions can be inspected directly.

use std::path::{Path, PathBuf};

use eds::model::{Access, DataType, Model, Value};
use proc_macro2::TokenStream;
use quote::quote;

use crate::expand::{self, Expansion};

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn fixture(name: &str) -> PathBuf {
    manifest_dir().join("tests/fixtures").join(name)
}

/// The demo device, declared inline. `tests/fixtures/demo.eds` is the same device written by
/// hand as an EDS.
fn demo_input() -> TokenStream {
    quote! {
        mod demo;
        strict;

        device {
            vendor_name = "Example Automation",
            vendor_id = 0xABC,
            product_name = "Demo I/O",
            product_code = 0x42,
            revision = 0x0001_0000,
            order_code = "DEMO-IO-1",
            baud_rates = [125, 250, 500, 1000],
            description = "Inline demo device",
        }

        var 0x1000 "Device type": u32, ro, default = 0x0000_0191;
        var 0x1001 "Error register": u8, ro, pdo, default = 0;
        var 0x1017 "Producer heartbeat time": UNSIGNED16, rw, default = 1000;
        record 0x1018 "Identity object" {
            1 "Vendor-ID": u32, ro, default = 0x0000_0ABC;
            2 "Product code": u32, ro, default = 0x0000_0042;
            3 "Revision number": u32, ro, default = 0x0001_0000;
            4 "Serial number": u32, ro, default = 0;
        }
        record 0x1200 "SDO server parameter" {
            1 "COB-ID client to server": u32, ro, default = NODEID + 0x600;
            2 "COB-ID server to client": u32, ro, default = 0x580 + $NODEID;
        }

        var 0x2000 "Setpoint": i16, rww, pdo, default = 0, min = -1000, max = 1000;
        var 0x2001 "Gain": REAL32, rw, default = 1.5;
        var 0x2002 "Label": VISIBLE_STRING, rw, default = "demo";

        array 0x6000 "Read inputs": u8, ro, pdo, len = 2, element = "Input", default = 0;
        array 0x6200 "Write outputs": u8, rww, pdo {
            1 "Output 1";
            2 "Output 2", default = 0xFF;
        }
        array 0x6401 "Analogue inputs": i16, ro, pdo, default = 0 {
            1 "Channel 1";
            2 "Channel 2", default = -5;
        }

        rpdo 1: map = [0x6200:1, 0x6200:2, 0x2000];
        tpdo 1: transmission = 1, event_timer = 100, map = [0x6000:1, 0x6000:2, 0x1001];
    }
}

fn expand_ok(input: TokenStream) -> Expansion {
    match expand::dictionary(input) {
        Ok(e) => e,
        Err(errors) => {
            panic!("unexpected errors:\n{}", errors.into_iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n"))
        }
    }
}

fn model_of(input: TokenStream) -> Model {
    expand_ok(input).lowered.model
}

/// Every error of an input given as text, one message a line, in the order reported. Where each
/// one sits is the compiler's to show: the inputs of the error tests below are compile-fail
/// cases ([`ui_case`]), whose `.stderr` files hold every error with its line, column and the
/// tokens it underlines (here, outside a compiler, spans carry no positions).
fn errors_of(src: &str) -> String {
    let input: TokenStream = src.parse().expect("test input tokenizes");
    let errors = match expand::dictionary(input) {
        Ok(_) => panic!("expected errors for:\n{src}"),
        Err(e) => e,
    };
    errors.into_iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n")
}

/// What the `object_dictionary! { … }` of the compile-fail case `NAME` holds
/// (`ui-tests/tests/ui/fail/NAME.rs`): one input for both kinds of test.
fn ui_case(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../ui-tests/tests/ui/fail").join(format!("{name}.rs"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let open = "od_macros::object_dictionary! {";
    let start = text.find(open).unwrap_or_else(|| panic!("{}: no `{open}`", path.display())) + open.len();
    let end = text.rfind("\n}\n").unwrap_or_else(|| panic!("{}: no closing `}}` line", path.display()));
    text[start..end].to_owned()
}

// ---- the same dictionary both ways -------------------------------------------------------------

#[test]
fn inline_dictionary_equals_the_hand_written_eds() {
    let inline = expand_ok(demo_input());
    let bytes = std::fs::read(fixture("demo.eds")).unwrap();
    let parsed = eds::parse("demo.eds", &bytes, &eds::Options::strict());
    assert!(!parsed.has_errors(), "{:#?}", parsed.diagnostics);
    let from_file = parsed.model;

    // One model...
    for (index, obj) in &from_file.objects {
        assert_eq!(inline.lowered.model.objects.get(index), Some(obj), "object 0x{:04X}", index.0);
    }
    assert_eq!(inline.lowered.model, from_file);

    // ... so one expansion: the macro's tokens are what the generator makes of the EDS file.
    let mut options = od_codegen::Options::new("demo", "demo.eds");
    options.eds_text = Some(eds::write::write_eds(&from_file));
    let from_eds = od_codegen::generate(&from_file, &options);
    assert_eq!(inline.tokens.to_string(), from_eds.to_string());
}

#[test]
fn eds_constant_reads_back_as_the_same_model_and_passes_strict_check() {
    let e = expand_ok(demo_input());
    let text = &e.checked.eds_text;
    assert_eq!(text, &eds::write::write_eds(&e.lowered.model));
    // It is the text the generated `EDS` constant holds.
    let lit = proc_macro2::Literal::string(text).to_string();
    let tokens = e.tokens.to_string();
    assert!(tokens.contains("pub const EDS") && (tokens.contains(&lit) || tokens.contains("[FileInfo]")));

    let parsed = eds::parse("demo.eds", text.as_bytes(), &eds::Options::strict());
    let errors: Vec<_> = parsed.errors().collect();
    assert!(errors.is_empty(), "odgen check --strict would fail: {errors:#?}");
    assert_eq!(parsed.model, e.lowered.model);
    insta::assert_snapshot!("demo_eds", text);
}

#[test]
fn expansion_snapshot() {
    let e = expand_ok(quote! {
        mod tiny;
        var 0x1017 "Producer heartbeat time": u16, rw, default = 500, max = 60000;
        record 0x1800 "TPDO communication parameter 1" {
            1 "COB-ID used by TPDO": u32, rw, default = NODEID + 0x180;
        }
    });
    // The generic support code lives in od-runtime (`::od_runtime::__private_v3`), so the
    // expansion is exactly what this dictionary made.
    let file: syn::File = syn::parse2(e.tokens).expect("generated code parses");
    assert!(!quote! { #file }.to_string().contains("__rt"), "no per-dictionary support module");
    let text = od_codegen::render(&quote! { #file }, "tiny.eds").expect("generated code parses");
    insta::assert_snapshot!("tiny_expansion", text);
}

// ---- the language ------------------------------------------------------------------------------

#[test]
fn values_types_and_node_id_forms() {
    let m = model_of(quote! {
        record 0x2100 "Forms" {
            1 "a": u32, rw, default = NODEID + 0x180;
            2 "b": u32, rw, default = $NODEID + 0x180;
            3 "c": u32, rw, default = 0x180 + NODEID;
            4 "d": u32, rw, default = 0x180 + $nodeid;
            5 "e": u32, rw, default = NODEID - 1;
            6 "f": u32, rw, default = NODEID;
        }
        var 0x2101 "Flag": bool, rw, default = true;
        var 0x2102 "Big": UNSIGNED64, rw, default = 0xFFFF_FFFF_FFFF_FFFF;
        var 0x2103 "Ratio": f64, rw, default = -2;
        var 0x2104 "Blob": OCTET_STRING, rw, default = b"\x01\xAB";
        var 0x2105 "Wide": UNICODE_STRING, rw, default = "Grüße";
        var 0x2106 "Time": TIME_OF_DAY, ro;
        var 0x2107 "Counter": UNSIGNED24, rw;
        array 0x1003 "Pre-defined error field": u32, ro {
            0 "Number of errors": u8, rw, default = 0, max = 2;
            1 "Standard error field 1";
            2 "Standard error field 2";
        }
    });
    let hex180 = Value::NodeIdPlus { offset: 0x180, radix: eds::model::Radix::Hex };
    for sub in 1..=4 {
        assert_eq!(m.entry(0x2100, sub).unwrap().default, Some(hex180.clone()), "sub {sub}");
    }
    assert_eq!(
        m.entry(0x2100, 5).unwrap().default,
        Some(Value::NodeIdPlus { offset: -1, radix: eds::model::Radix::Dec })
    );
    assert_eq!(m.entry(0x2100, 6).unwrap().default.as_ref().and_then(|v| v.resolve(7)), Some(7));
    assert_eq!(m.entry(0x2100, 0).unwrap().default, Some(Value::int(6)));
    assert_eq!(m.entry(0x2100, 0).unwrap().access, Access::Ro);
    assert_eq!(m.entry(0x2101, 0).unwrap().default, Some(Value::int(1)));
    assert_eq!(m.entry(0x2102, 0).unwrap().default, Some(Value::hex(u64::MAX as i128)));
    assert_eq!(m.entry(0x2103, 0).unwrap().default, Some(Value::Real(-2.0)));
    assert_eq!(m.entry(0x2104, 0).unwrap().default, Some(Value::Bytes(vec![1, 0xAB])));
    assert_eq!(m.entry(0x2105, 0).unwrap().default, Some(Value::Text("Grüße".into())));
    assert_eq!(m.entry(0x2106, 0).unwrap().data_type, DataType::TimeOfDay);
    assert_eq!(m.entry(0x2107, 0).unwrap().data_type, DataType::Unsigned24);
    assert_eq!(m.object(0x2100).unwrap().category, eds::model::Category::Manufacturer);
    let count = m.entry(0x1003, 0).unwrap();
    assert_eq!(
        (count.name.as_str(), count.access, count.default.clone()),
        ("Number of errors", Access::Rw, Some(Value::int(0)))
    );
    assert_eq!(m.entry(0x1003, 2).unwrap().data_type, DataType::Unsigned32);
}

#[test]
fn pdo_objects_follow_cia_301() {
    let m = model_of(quote! {
        var 0x6040 "Controlword": u16, rww, pdo;
        var 0x6041 "Statusword": u16, ro, pdo;
        var 0x6064 "Position actual value": i32, ro, pdo;
        rpdo 1: map = [0x6040];
        rpdo 5: cob_id = 0x300, map = [0x6040];
        tpdo 2: inhibit = 10, event_timer = 50, capacity = 2, map = [0x6041, 0x6064];
    });
    // Predefined connection set for PDOs 1..4, invalid COB-ID beyond unless given.
    let cob = |i: u16| m.entry(i, 1).unwrap().default.as_ref().unwrap().resolve(3).unwrap();
    assert_eq!(cob(0x1400), 0x203);
    assert_eq!(cob(0x1404), 0x300);
    assert_eq!(cob(0x1801), 0x283);
    assert!(m.entry(0x1400, 3).is_none(), "an RPDO has no inhibit time");
    assert_eq!(m.entry(0x1801, 3).unwrap().default, Some(Value::int(10)));
    assert_eq!(m.entry(0x1801, 5).unwrap().default, Some(Value::int(50)));
    let tpdo_map = m.object(0x1A01).unwrap();
    assert_eq!(tpdo_map.subs.len(), 3, "count + capacity 2");
    assert_eq!(tpdo_map.sub(0).unwrap().default, Some(Value::int(2)));
    assert_eq!(tpdo_map.sub(1).unwrap().default, Some(Value::hex(0x6041_0010)));
    assert_eq!(tpdo_map.sub(2).unwrap().default, Some(Value::hex(0x6064_0020)));
    assert_eq!(m.object(0x1600).unwrap().subs.len(), 9, "count + 8 entries by default");
    assert_eq!(m.device_info.nr_of_rx_pdo, Some(2));
    assert_eq!(m.device_info.nr_of_tx_pdo, Some(1));
}

#[test]
fn defaults_of_an_empty_dictionary() {
    let e = expand_ok(quote! {});
    assert_eq!(e.lowered.module, "od");
    let m = &e.lowered.model;
    assert_eq!(m.file_info.file_name.as_deref(), Some("od.eds"));
    assert_eq!(m.file_info.eds_version.as_deref(), Some("4.0"));
    assert_eq!(m.device_info.granularity, Some(8));
    assert!(m.objects.is_empty());
    assert!(e.tokens.to_string().contains("pub mod od"));
}

// ---- errors --------------------------------------------------------------------------------------

#[test]
fn every_declaration_error_in_one_pass_on_its_token() {
    // Each on its token: `ui-tests/tests/ui/fail/every_declaration.stderr`.
    let errors = errors_of(&ui_case("every_declaration"));
    insta::assert_snapshot!("declaration_errors", errors);
}

#[test]
fn pdo_errors() {
    let errors = errors_of(&ui_case("every_pdo"));
    insta::assert_snapshot!("pdo_errors", errors);
}

#[test]
fn strict_reports_what_lenient_lets_pass() {
    let body = r#"
device { vendor_name = "V", product_name = "P", baud_rates = [250] }
var 0x2000 "A": u32, rw;
"#;
    // Lenient: a fragment without the mandatory objects is fine.
    let input: TokenStream = body.parse().unwrap();
    assert!(expand::dictionary(input).is_ok());
    let errors = errors_of(&format!("strict;{body}"));
    insta::assert_snapshot!("strict_errors", errors);
}

#[test]
fn follow_up_errors_are_not_reported() {
    // 0x2000 has an unknown type: the PDO mapping it is not also reported, and neither is the
    // (strict) mandatory-object check that a broken dictionary cannot pass anyway.
    let errors = errors_of(&ui_case("follow_up"));
    insta::assert_snapshot!("follow_up_errors", errors);
}

#[test]
fn syntax_errors_recover_at_the_next_item() {
    let errors = errors_of(&ui_case("syntax"));
    insta::assert_snapshot!("syntax_errors", errors);
}

// ---- include_eds! --------------------------------------------------------------------------------

#[test]
fn include_eds_tracks_the_file_and_names_the_module_after_it() {
    let included = expand::include(quote! { "tests/fixtures/demo.eds" }, Some(&manifest_dir())).unwrap();
    assert_eq!(included.tracked, vec![fixture("demo.eds").to_str().unwrap().to_owned()]);
    let text = od_codegen::render(&included.module, "x").unwrap();
    assert!(text.contains("pub mod demo {"), "module named after the file stem");

    let all = expand::include_eds(quote! { "tests/fixtures/demo.eds", mod renamed, strict }, Some(&manifest_dir()));
    let all = all.to_string();
    assert!(all.contains("pub mod renamed"));
    let path_lit = proc_macro2::Literal::string(fixture("demo.eds").to_str().unwrap()).to_string();
    assert!(
        all.contains(&format!("const _ : & [u8] = include_bytes ! ({path_lit})")),
        "{}",
        &all[all.len().saturating_sub(300)..]
    );
}

#[test]
fn include_eds_is_what_the_build_script_builder_writes() {
    // The DRVI has a sidecar beside it: both paths must read it the same way.
    let root = manifest_dir().parent().unwrap().to_path_buf();
    let included = expand::include(quote! { "devices/camozzi-drvi.eds", mod drvi }, Some(&root)).unwrap();
    assert_eq!(included.tracked.len(), 2, "the EDS and its sidecar are tracked");
    assert!(included.tracked[1].ends_with("camozzi-drvi.toml"));
    let outputs = od_codegen::Builder::new()
        .root(&root)
        .cargo_metadata(false)
        .embed_eds(true)
        .device("drvi", "devices/camozzi-drvi.eds")
        .generate()
        .unwrap();
    let rendered = od_codegen::render(&included.module, "devices/camozzi-drvi.eds").unwrap();
    assert!(rendered == outputs[0].text, "include_eds! and Builder differ");
}

fn include_errors(input: TokenStream, dir: Option<&Path>) -> String {
    match expand::include(input, dir) {
        Ok(_) => panic!("expected errors"),
        Err(e) => e.into_iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n---\n"),
    }
}

#[test]
fn include_eds_reports_file_diagnostics_with_their_location() {
    let errors = include_errors(quote! { "tests/fixtures/broken.eds" }, Some(&manifest_dir()));
    insta::assert_snapshot!("include_errors", errors);

    // Strict: the deviations a lenient read lets pass are errors too.
    let lenient = include_errors(quote! { "tests/fixtures/broken.eds" }, Some(&manifest_dir()));
    let strict = include_errors(quote! { "tests/fixtures/broken.eds", strict }, Some(&manifest_dir()));
    assert!(strict.matches("\n---\n").count() > lenient.matches("\n---\n").count());
    assert!(strict.contains("tests/fixtures/broken.eds: mandatory object 0x1001 (error register) is missing [E0501]"));
}

#[test]
fn include_eds_io_and_argument_errors() {
    let missing = include_errors(quote! { "tests/fixtures/nope.eds" }, Some(&manifest_dir()));
    assert!(missing.starts_with("cannot read `") && missing.contains("nope.eds"), "{missing}");
    let no_dir = include_errors(quote! { "x.eds" }, None);
    assert!(no_dir.contains("CARGO_MANIFEST_DIR"), "{no_dir}");
    let bad = include_errors(quote! { "x.eds", colour }, Some(&manifest_dir()));
    assert_eq!(bad, "expected `mod name`, `strict`, `client` or `allow(CODE, …)`");
    let not_lit = include_errors(quote! { devices }, Some(&manifest_dir()));
    assert_eq!(not_lit, "expected string literal");
}

#[test]
fn include_eds_reports_the_warnings_a_build_reports_and_allow_silences_them() {
    // The generator's fixture with deviations: the same short lines as the Builder prints.
    let root = manifest_dir().parent().unwrap().to_path_buf();
    let path = "od-codegen/tests/fixtures/vendor-quirks.eds";
    let included = expand::include(quote! { #path, mod quirks }, Some(&root)).unwrap();
    let built = od_codegen::Builder::new()
        .root(&root)
        .cargo_metadata(false)
        .device("quirks", path)
        .generate_all()
        .remove(0)
        .unwrap();
    assert!(!included.warning_lines.is_empty());
    assert_eq!(included.warning_lines, built.short_lines(eds::diag::Severity::Warning));
    let tokens = included.warnings.to_string();
    assert!(tokens.contains("deprecated") && tokens.contains("warning[G0108]"), "{tokens}");

    // One code allowed: its lines go; all allowed: none is left.
    let allowed = expand::include(quote! { #path, mod quirks, allow(G0108) }, Some(&root)).unwrap();
    assert!(!allowed.warning_lines.iter().any(|l| l.contains("[G0108]")));
    assert!(allowed.warning_lines.len() < included.warning_lines.len());
    let none = expand::include(quote! { #path, allow(warnings) }, Some(&root)).unwrap();
    assert!(none.warning_lines.is_empty() && none.warnings.is_empty());

    // A misspelt code is an error on it.
    let e = include_errors(quote! { #path, allow(G01) }, Some(&root));
    assert!(e.contains("expected a diagnostic code"), "{e}");
}
