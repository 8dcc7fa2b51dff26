//! `Document::write_lossless` gives back the input byte for byte, whatever the input (but
//! invalid UTF-16, reported as error E0011); and no input makes the reader panic.

use std::path::Path;

use eds::Options;
use eds::ast::{LineEnding, LineKind};
use proptest::prelude::*;

fn round_trip(bytes: &[u8]) {
    for options in [Options::lenient(), Options::strict()] {
        let p = eds::parse("input.eds", bytes, &options);
        // Invalid UTF-16 cannot be given back (its units were read as U+FFFD): it is an error.
        if p.document.source.invalid_units > 0 {
            assert!(p.diagnostics.iter().any(|d| d.code == eds::codes::E0011));
            continue;
        }
        assert_eq!(p.document.write_lossless(), bytes, "lossless for {:?}", String::from_utf8_lossy(bytes));
        // The lines tile the text: every byte is in exactly one line, in order.
        let text = &p.document.source.text;
        let joined: String = p.document.lines().iter().map(|l| p.document.source.slice(l.raw)).collect();
        assert_eq!(&joined, text, "the lines of {:?} do not tile it", String::from_utf8_lossy(bytes));
        // Rendering every diagnostic must not panic either.
        let _ = eds::diag::render_all(&p.diagnostics, &p.document.source);
        let _ = eds::diag::to_json(&p.diagnostics);
    }
}

#[test]
fn every_fixture_round_trips() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let mut n = 0;
    for dir in [root.clone(), root.join("diag"), root.join("features")] {
        for entry in std::fs::read_dir(&dir).expect("fixture dir") {
            let path = entry.expect("entry").path();
            if path.is_file() {
                round_trip(&std::fs::read(&path).expect("read"));
                n += 1;
            }
        }
    }
    assert!(n > 80, "{n} fixtures");
}

#[test]
fn line_endings_bom_and_encodings() {
    for input in [
        &b"[1000]\r\nParameterName=x\r\n"[..],
        b"[1000]\rParameterName=x\r",
        b"[1000]\nParameterName=x",
        b"\xEF\xBB\xBF[1000]\nParameterName=x\n",
        b"[1000]\nParameterName=f\xf6r\n",
        b"\xEF\xBB\xBF[1000]\nParameterName=\x94\x81\n",
        b"\r\n\r\r\n\n",
        b"",
        b"=\n[\n]\n;\n#\n",
    ] {
        round_trip(input);
    }
    let p = eds::parse("x.eds", b"[A]\r\nk=v\rj=w\nlast", &Options::lenient());
    let endings: Vec<_> = p.document.lines().iter().map(|l| l.ending).collect();
    assert_eq!(endings, [LineEnding::CrLf, LineEnding::Cr, LineEnding::Lf, LineEnding::None]);
    assert_eq!(p.document.lines()[3].kind, LineKind::Garbage);
}

#[test]
fn keys_keep_spelling_comments_and_order() {
    let src = "; head\n[deviceinfo]\n  vendorNAME = ACME  \n; between\nproductname=Thing\n";
    let p = eds::parse("x.eds", src.as_bytes(), &Options::lenient());
    let entries: Vec<_> = (0..p.document.lines().len()).filter_map(|i| p.document.entry(i)).collect();
    assert_eq!(entries, vec![("vendorNAME", "ACME"), ("productname", "Thing")]);
    let comments = p.document.lines().iter().filter(|l| matches!(l.kind, LineKind::Comment { .. })).count();
    assert_eq!(comments, 2);
    assert_eq!(p.model.device_info.vendor_name.as_deref(), Some("ACME"));
    assert_eq!(p.document.write_lossless(), src.as_bytes());
}

/// Lines that look like EDS, to drive the reader past the lexer into lowering and validation.
fn eds_line() -> impl Strategy<Value = String> {
    let section = prop_oneof![
        Just("FileInfo".to_owned()),
        Just("DeviceInfo".to_owned()),
        Just("DummyUsage".to_owned()),
        Just("Comments".to_owned()),
        Just("MandatoryObjects".to_owned()),
        Just("OptionalObjects".to_owned()),
        Just("DeviceComissioning".to_owned()),
        (0x1000u16..0x1003).prop_map(|i| format!("{i:04X}")),
        (0x1600u16..0x1602).prop_map(|i| format!("{i:04X}")),
        (0x1A00u16..0x1A01).prop_map(|i| format!("{i:04X}")),
        ((0x1000u16..0x1003), 0u8..4).prop_map(|(i, s)| format!("{i:04X}sub{s}")),
        ((0x1600u16..0x1602), 0u8..4).prop_map(|(i, s)| format!("{i:04X}sub{s}")),
        (0x1000u16..0x1003).prop_map(|i| format!("{i:04X}Name")),
        (0x1000u16..0x1003).prop_map(|i| format!("{i:04X}Value")),
        "[a-zA-Z0-9 ]{0,8}",
    ];
    let key = prop_oneof![
        Just("ParameterName"),
        Just("ObjectType"),
        Just("DataType"),
        Just("AccessType"),
        Just("DefaultValue"),
        Just("ParameterValue"),
        Just("LowLimit"),
        Just("HighLimit"),
        Just("PDOMapping"),
        Just("SubNumber"),
        Just("CompactSubObj"),
        Just("ObjFlags"),
        Just("NrOfEntries"),
        Just("SupportedObjects"),
        Just("NrOfRXPDO"),
        Just("CompactPDO"),
        Just("Granularity"),
        Just("NodeID"),
        Just("Lines"),
        Just("Dummy0005"),
        Just("1"),
        Just("2"),
    ];
    let value = prop_oneof![
        Just("0x7".to_owned()),
        Just("0x9".to_owned()),
        Just("0x8".to_owned()),
        Just("0x0005".to_owned()),
        Just("0x0007".to_owned()),
        Just("rw".to_owned()),
        Just("$NODEID+0x180".to_owned()),
        Just("0x10000010".to_owned()),
        Just("0x00050008".to_owned()),
        Just("255".to_owned()),
        Just("010".to_owned()),
        Just("".to_owned()),
        "-?[0-9]{1,22}",
        "0x[0-9A-F]{1,20}",
        "[ -~]{0,12}",
    ];
    prop_oneof![
        section.prop_map(|s| format!("[{s}]")),
        (key, value).prop_map(|(k, v)| format!("{k}={v}")),
        "[ -~]{0,20}",
        Just(String::new()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic_and_round_trip(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        round_trip(&bytes);
    }

    #[test]
    fn arbitrary_text_never_panics_and_round_trips(text in "(\\PC|\r|\n|\\[|\\]|=|;){0,300}") {
        round_trip(text.as_bytes());
    }

    #[test]
    fn eds_like_files_never_panic(lines in proptest::collection::vec(eds_line(), 0..80), crlf in any::<bool>()) {
        let text = lines.join(if crlf { "\r\n" } else { "\n" });
        round_trip(text.as_bytes());
        let mut model = eds::parse("x.eds", text.as_bytes(), &Options::lenient()).model;
        let _ = eds::lower::expand_compact_pdo(&mut model);
    }
}
