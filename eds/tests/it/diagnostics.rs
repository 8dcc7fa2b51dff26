//! One fixture per diagnostic code (`fixtures/diag/EXXXX.eds`, each the conformant
//! `fixtures/base.eds` with one mistake): the code is reported, with the severity the code table
//! promises in each mode, and the rendered output is snapshot.

use std::path::{Path, PathBuf};

use eds::{Options, Severity, codes};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// Reads a fixture under a short, machine-independent name.
fn read(path: &Path, options: &Options) -> eds::Parsed {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("fixture.eds");
    eds::parse(name, &bytes, options)
}

#[test]
fn base_fixture_is_clean_even_in_strict_mode() {
    let parsed = read(&fixtures().join("base.eds"), &Options::strict());
    let text = eds::diag::render_all(&parsed.diagnostics, &parsed.document.source);
    assert!(parsed.diagnostics.is_empty(), "{text}");
    assert_eq!(parsed.model.objects.len(), 9);
}

#[test]
fn every_code_has_a_fixture_that_triggers_it() {
    let mut missing = Vec::new();
    for info in codes::ALL {
        let path = fixtures().join("diag").join(format!("{}.eds", info.code));
        if !path.exists() {
            missing.push(info.code.0);
            continue;
        }
        let lenient = read(&path, &Options::lenient());
        let strict = read(&path, &Options::strict());
        let hit = |p: &eds::Parsed| p.diagnostics.iter().find(|d| d.code == info.code).cloned();
        let l = hit(&lenient).unwrap_or_else(|| panic!("{} not reported: {:#?}", info.code, lenient.diagnostics));
        let s = hit(&strict).unwrap_or_else(|| panic!("{} not reported in strict mode", info.code));
        assert_eq!(l.severity, info.lenient, "{} lenient severity", info.code);
        let want = if info.deviation { Severity::Error } else { info.lenient };
        assert_eq!(s.severity, want, "{} strict severity", info.code);
        assert!(l.span.is_none() || l.at.is_some(), "{}: a span comes with a line and column", info.code);
        // Strict mode reports the same problems, only more severely.
        assert_eq!(lenient.diagnostics.len(), strict.diagnostics.len(), "{}", info.code);
        // The model is built either way.
        assert_eq!(lenient.model, strict.model, "{}", info.code);
    }
    assert!(missing.is_empty(), "codes without a fixture: {missing:?}");
}

#[test]
fn no_fixture_without_a_code() {
    for entry in std::fs::read_dir(fixtures().join("diag")).expect("fixtures/diag") {
        let path = entry.expect("dir entry").path();
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_owned();
        assert!(codes::ALL.iter().any(|c| c.code.0 == stem), "{} names no code", path.display());
    }
}

#[test]
fn rendered_diagnostics() {
    for info in codes::ALL {
        let path = fixtures().join("diag").join(format!("{}.eds", info.code));
        let parsed = read(&path, &Options::lenient());
        let text = eds::diag::render_all(&parsed.diagnostics, &parsed.document.source);
        insta::assert_snapshot!(format!("diag_{}", info.code), text);
    }
}

#[test]
fn diagnostics_come_in_file_order() {
    for info in codes::ALL {
        let parsed = read(&fixtures().join("diag").join(format!("{}.eds", info.code)), &Options::lenient());
        let starts: Vec<u32> = parsed.diagnostics.iter().map(|d| d.span.map(|s| s.start).unwrap_or(u32::MAX)).collect();
        let mut sorted = starts.clone();
        sorted.sort();
        assert_eq!(starts, sorted, "{}", info.code);
    }
}

#[test]
fn json_output() {
    let parsed = read(&fixtures().join("diag/E0303.eds"), &Options::strict());
    let json = eds::diag::to_json(&parsed.diagnostics);
    let v: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    let d = &v[0];
    assert_eq!(d["code"], "E0303");
    assert_eq!(d["severity"], "warning");
    assert_eq!(d["deviation"], false);
    assert_eq!(d["file"], "E0303.eds");
    assert!(d["at"]["line"].as_u64().is_some_and(|l| l > 1));
    insta::assert_snapshot!("json_E0303", json);
}

#[test]
fn rustc_like_layout() {
    let parsed = read(&fixtures().join("diag/E0301.eds"), &Options::strict());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0301).expect("E0301");
    let text = eds::diag::render(d, &parsed.document.source);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("error[E0301]: DefaultValue `fast` cannot be read as UNSIGNED16"), "{text}");
    assert!(lines[1].trim_start().starts_with("--> E0301.eds:"), "{text}");
    let src_line = lines.iter().position(|l| l.ends_with("| DefaultValue=fast")).expect("source line");
    let caret = lines[src_line + 1];
    let col = caret.find('^').expect("caret");
    assert_eq!(&lines[src_line][col..col + 4], "fast");
    assert_eq!(caret.matches('^').count(), 4);
    assert!(text.contains("= note: in object 0x2000 \"Target speed\""), "{text}");
    assert!(text.contains("= help: "), "{text}");
}

#[test]
fn breadcrumbs_name_object_and_sub() {
    let parsed = read(&fixtures().join("diag/E0210.eds"), &Options::lenient());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0210).expect("E0210");
    assert_eq!(d.context, vec!["object 0x1018 \"Identity Object\"", "sub 0 \"Highest sub-index supported\""]);
}

#[test]
fn hints_for_known_misspellings() {
    let hint = |code: &str, c| {
        let parsed = read(&fixtures().join(format!("diag/{code}.eds")), &Options::lenient());
        parsed.diagnostics.iter().find(|d| d.code == c).and_then(|d| d.hint.clone()).unwrap_or_default()
    };
    assert_eq!(hint("E0104", codes::E0104), "write `BaudRate_500`");
    assert!(hint("E0303", codes::E0303).contains("`10`"));
    assert!(hint("E0303", codes::E0303).contains("`0x8`"));
    let parsed = read(&fixtures().join("features/compact.dcf"), &Options::lenient());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0103).expect("E0103");
    assert!(d.hint.as_deref().unwrap_or_default().contains("[DeviceComissioning]"));
}

/// `base.eds` with edits: each `(section, old, new)` replaces the first `old` after the
/// `[section]` header; `(section, "", text)` appends `text` after the header line; a section
/// of `""` appends `new` at the end of the file.
fn base_with(edits: &[(&str, &str, &str)]) -> String {
    let mut s = std::fs::read_to_string(fixtures().join("base.eds")).expect("base.eds");
    for &(section, old, new) in edits {
        if section.is_empty() {
            s.push_str(new);
            continue;
        }
        let header = format!("[{section}]\n");
        let at = s.find(&header).unwrap_or_else(|| panic!("no [{section}]")) + header.len();
        if old.is_empty() {
            s.insert_str(at, new);
        } else {
            let i = at + s[at..].find(old).unwrap_or_else(|| panic!("no `{old}` in [{section}]"));
            s.replace_range(i..i + old.len(), new);
        }
    }
    s
}

/// The codes `text` gets, with the messages of the codes in `of`.
fn codes_of(text: &str, of: &[eds::Code]) -> Vec<(eds::Code, String)> {
    let p = eds::parse("t.eds", text.as_bytes(), &Options::lenient());
    p.diagnostics.iter().filter(|d| of.contains(&d.code)).map(|d| (d.code, d.message.clone())).collect()
}

/// An RPDO 2 whose communication object has `cob` as COB-ID (appended to `base.eds`, with
/// NrOfRXPDO raised and the objects listed).
fn second_rpdo(cob: &str) -> Vec<(&'static str, &'static str, String)> {
    vec![
        ("DeviceInfo", "NrOfRXPDO=1", "NrOfRXPDO=2".to_owned()),
        ("OptionalObjects", "SupportedObjects=4", "SupportedObjects=6\n5=0x1401\n6=0x1601".to_owned()),
        (
            "",
            "",
            format!(
                "\n[1401]\nParameterName=RPDO 2 communication\nObjectType=0x9\nSubNumber=2\n\n[1401sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\nPDOMapping=0\n\n[1401sub1]\nParameterName=COB-ID used by RPDO\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue={cob}\nPDOMapping=0\n\n[1601]\nParameterName=RPDO 2 mapping\nObjectType=0x9\nSubNumber=1\n\n[1601sub0]\nParameterName=Number of mapped objects\nObjectType=0x7\nDataType=0x0005\nAccessType=rw\nDefaultValue=0\nPDOMapping=0\n"
            ),
        ),
    ]
}

fn edits(e: &[(&'static str, &'static str, String)]) -> String {
    base_with(&e.iter().map(|(a, b, c)| (*a, *b, c.as_str())).collect::<Vec<_>>())
}

#[test]
fn sub_index_zero_against_the_sub_objects() {
    let c = |e: &[(&str, &str, &str)]| codes_of(&base_with(e), &[codes::E0221]);
    // Too low and too high, for a read-only sub-index 0.
    assert_eq!(c(&[("1018sub0", "DefaultValue=2", "DefaultValue=1")]).len(), 1);
    assert_eq!(c(&[("1018sub0", "DefaultValue=2", "DefaultValue=3")]).len(), 1);
    // A writable sub-index 0 counts entries in use: lower is fine, higher is not.
    let rw = ("1018sub0", "AccessType=ro", "AccessType=rw");
    assert!(c(&[rw, ("1018sub0", "DefaultValue=2", "DefaultValue=0")]).is_empty());
    assert_eq!(c(&[rw, ("1018sub0", "DefaultValue=2", "DefaultValue=3")]).len(), 1);
    // PDO mapping objects count mapped entries (E0608's business, not E0221's).
    assert!(c(&[("1600sub0", "DefaultValue=2", "DefaultValue=1")]).is_empty());
    // A sub-object whose entry could not be read still counts as present (no second error).
    assert!(c(&[("1018sub2", "DataType=0x0007\n", "")]).is_empty());
    // An ARRAY may give the number of its elements where sub-indices are left out.
    let sparse = "\n[2002]\nParameterName=Gains\nObjectType=0x8\nSubNumber=3\n\n[2002sub0]\nParameterName=Number of gains\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=N\nPDOMapping=0\n\n[2002sub1]\nParameterName=P\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=1\nPDOMapping=0\n\n[2002sub4]\nParameterName=D\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=1\nPDOMapping=0\n";
    let listed = ("ManufacturerObjects", "SupportedObjects=2\n", "SupportedObjects=3\n3=0x2002\n");
    for (n, ok) in [("4", true), ("2", true), ("3", false)] {
        let text = base_with(&[listed, ("", "", &sparse.replace("=N", &format!("={n}")))]);
        let found = codes_of(&text, &[codes::E0221]);
        assert_eq!(found.is_empty(), ok, "sub 0 = {n}: {found:?}");
        if !ok {
            assert_eq!(
                found[0].1,
                "sub-index 0 of ARRAY 0x2002 is 3, but the highest sub-index present is 4 and it has 2 elements"
            );
        }
    }
    // CompactSubObj arrays are consistent by construction.
    let compact = "\n[2002]\nParameterName=Table\nObjectType=0x8\nCompactSubObj=5\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\nPDOMapping=0\n";
    assert!(codes_of(&base_with(&[listed, ("", "", compact)]), &[codes::E0221]).is_empty());
}

#[test]
fn granularity_of_mapping_entries() {
    let c = |g: &str| codes_of(&base_with(&[("DeviceInfo", "Granularity=8", g)]), &[codes::E0613, codes::E0614]);
    assert!(c("Granularity=8").is_empty());
    assert!(c("Granularity=1").is_empty());
    // RPDO 1 maps 16 and 8 bits, TPDO 1 maps 32 and 8 bits.
    assert_eq!(c("Granularity=16").len(), 2);
    assert_eq!(c("Granularity=32").len(), 3);
    // Without Granularity nothing is judged (its absence is E0505).
    assert!(c("").is_empty());
    // Granularity 0: the mapping cannot be changed, so writable mapping parameters are one
    // problem, reported once.
    let zero = c("Granularity=0");
    assert_eq!(zero.len(), 1, "{zero:?}");
    assert_eq!(zero[0].0, codes::E0614);
    let mut text = base_with(&[("DeviceInfo", "Granularity=8", "Granularity=0")]);
    for s in ["1600sub0", "1600sub1", "1600sub2", "1A00sub0", "1A00sub1", "1A00sub2"] {
        let at = text.find(&format!("[{s}]")).expect("section");
        let i = at + text[at..].find("AccessType=rw").expect("rw");
        text.replace_range(i..i + "AccessType=rw".len(), "AccessType=ro");
    }
    assert!(codes_of(&text, &[codes::E0613, codes::E0614]).is_empty());
}

#[test]
fn cob_ids_restricted_frame_bits_and_duplicates() {
    let tpdo = |cob: &str| {
        codes_of(
            &base_with(&[("1800sub1", "DefaultValue=0x180+$NODEID", &format!("DefaultValue={cob}"))]),
            &[codes::E0701, codes::E0702, codes::E0703],
        )
    };
    assert!(tpdo("$NODEID+0x280").is_empty());
    assert!(tpdo("0x281").is_empty());
    let fixed = tpdo("0x5A0");
    assert_eq!(fixed, vec![(codes::E0701, "TPDO 1 COB-ID 0x5A0 is CAN-ID 0x5A0, which CiA 301 reserves".to_owned())]);
    // Relative to the node id: only the node ids that land in a restricted range.
    assert_eq!(
        tpdo("$NODEID+0x540"),
        vec![(
            codes::E0701,
            "TPDO 1 COB-ID $NODEID+0x540 is CAN-ID 0x581..=0x5BF for node ids 65..=127, which CiA 301 reserves"
                .to_owned()
        )]
    );
    // A PDO that is not valid (bit 31) and a 29-bit CAN-ID (bit 29) are not judged by the
    // 11-bit rules; the RTR bit (30) is not part of the CAN-ID.
    assert!(tpdo("0x800005A0").is_empty());
    assert!(tpdo("0x200005A0").is_empty());
    assert!(tpdo("0x20012345").is_empty());
    assert_eq!(tpdo("0x400005A0").len(), 1);
    assert_eq!(tpdo("0x12345")[0].0, codes::E0702);
    assert_eq!(tpdo("$NODEID+0x7FF")[0].0, codes::E0702);
    // The same CAN-ID as the RPDO: equal offsets from the node id, equal fixed values; with
    // the RTR bit or an invalid PDO it is the same ID resp. no conflict.
    assert_eq!(tpdo("$NODEID+0x200")[0].0, codes::E0703);
    assert_eq!(tpdo("0x40000000+$NODEID+0x200").len(), 0, "not a NODEID expression this reader accepts");
    assert_eq!(tpdo("$NODEID+0x40000200")[0].0, codes::E0703);
    assert!(tpdo("$NODEID+0x80000200").is_empty());
    let two = |a: &str, b: &str| {
        let mut e = second_rpdo(b);
        e.push(("1400sub1", "DefaultValue=$NODEID+0x200", format!("DefaultValue={a}")));
        codes_of(&edits(&e), &[codes::E0703])
    };
    assert_eq!(two("0x301", "0x301").len(), 1);
    assert!(two("0x301", "0x302").is_empty());
    // A fixed and a relative value meet only for one node id: not judged in an EDS.
    assert!(two("0x301", "$NODEID+0x300").is_empty());
    // SYNC and EMCY are the device's CAN-IDs too.
    let sync = "\n[1005]\nParameterName=COB-ID SYNC\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x80\nPDOMapping=0\n\n[1014]\nParameterName=COB-ID EMCY\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x80\nPDOMapping=0\n";
    let list = ("OptionalObjects", "SupportedObjects=4", "SupportedObjects=6\n5=0x1005\n6=0x1014");
    let with_sync = |tpdo: &str| {
        codes_of(
            &base_with(&[list, ("1800sub1", "DefaultValue=0x180+$NODEID", tpdo), ("", "", sync)]),
            &[codes::E0701, codes::E0702, codes::E0703],
        )
    };
    assert!(with_sync("DefaultValue=0x180+$NODEID").is_empty());
    assert_eq!(
        with_sync("DefaultValue=0x80"),
        vec![(codes::E0703, "TPDO 1 COB-ID 0x80 is the same CAN-ID as SYNC (0x1005 sub 0: 0x80)".to_owned())]
    );
    assert_eq!(with_sync("DefaultValue=$NODEID+0x80")[0].0, codes::E0703);
}

#[test]
fn cob_ids_of_a_dcf_are_judged_for_its_node_id() {
    let dcf = |node: &str, tpdo: &str| {
        let mut e = second_rpdo("0x305");
        e.push(("1800sub1", "DefaultValue=0x180+$NODEID", format!("DefaultValue={tpdo}")));
        e.push(("", "", format!("\n[DeviceComissioning]\nNodeID={node}\nBaudrate=500\n")));
        let text = edits(&e);
        let p = eds::parse("t.dcf", text.as_bytes(), &Options::lenient());
        p.diagnostics.iter().filter(|d| d.code.0.starts_with("E07")).map(|d| d.message.clone()).collect::<Vec<_>>()
    };
    // Node 5: RPDO 2 (0x305) meets TPDO 1 at $NODEID+0x300 only on this node.
    assert_eq!(dcf("5", "$NODEID+0x300").len(), 1);
    assert!(dcf("6", "$NODEID+0x300").is_empty());
    // $NODEID+0x540 is restricted for node 100 only when the DCF says node 100.
    assert_eq!(
        dcf("100", "$NODEID+0x540"),
        vec!["TPDO 1 COB-ID $NODEID+0x540 is CAN-ID 0x5A4, which CiA 301 reserves"]
    );
    assert!(dcf("10", "$NODEID+0x540").is_empty());
}

/// Sub-object sections without their object are found wherever their index falls among the
/// objects' (before the first, between two, after the last, several per index), and reported
/// in file order; sub-objects of objects that exist are not.
#[test]
fn sub_objects_without_an_object_are_all_found() {
    let base = std::fs::read_to_string(fixtures().join("base.eds")).expect("base.eds");
    let orphan = |name: &str| format!("\n[{name}]\nParameterName=Orphan\nDataType=0x0005\nAccessType=ro\n");
    let names = ["0FFFsub1", "1017sub0", "1017sub2", "1019sub1", "1800sub9", "1FFFsub0", "3000sub1", "3000sub2"];
    let mut text = base.clone();
    for name in names {
        text.push_str(&orphan(name));
    }
    let parsed = eds::parse("orphans.eds", text.as_bytes(), &Options::lenient());
    let reported: Vec<&str> = parsed
        .diagnostics
        .iter()
        .filter(|d| d.code == codes::E0211)
        .map(|d| &text[d.span.expect("span").start as usize..d.span.expect("span").end as usize])
        .collect();
    // 1800sub9 belongs to object 1800, which exists.
    let want: Vec<&str> = names.iter().copied().filter(|n| *n != "1800sub9").collect();
    assert_eq!(reported, want);
    assert_eq!(parsed.model.entry(0x1800, 9).map(|e| e.name.as_str()), Some("Orphan"));
}

/// A `BaudRate_` key is reported when it is not spelled as CiA 306 writes it (prefix case, a
/// sign or leading zeros), and read as the rate it names either way.
#[test]
fn baud_rate_keys_in_canonical_and_other_spellings() {
    for (key, rate, reported) in [
        ("BaudRate_500", 500u16, false),
        ("BaudRate_0", 0, false),
        ("baudrate_500", 500, true),
        ("BAUDRATE_125", 125, true),
        ("BaudRate_0500", 500, true),
        ("BaudRate_+250", 250, true),
        ("BaudRate_00", 0, true),
    ] {
        let text = format!("[DeviceInfo]\nVendorName=x\n{key}=1\n");
        let parsed = eds::parse("baud.eds", text.as_bytes(), &Options::lenient());
        let spelling: Vec<_> = parsed.diagnostics.iter().filter(|d| d.code == codes::E0104).collect();
        assert_eq!(!spelling.is_empty(), reported, "{key}: {spelling:?}");
        if reported {
            assert_eq!(spelling[0].hint.as_deref(), Some(format!("write `BaudRate_{rate}`").as_str()), "{key}");
        }
        assert_eq!(parsed.model.device_info.baud_rates.get(&rate), Some(&true), "{key}");
    }
}

/// A value that reads once its inline comment is cut off gets E0008 and nothing else about
/// its number: the remarks of the failed first reading (the comment taken for a C literal
/// suffix, say) are not reported. The same rule for every key read this way.
#[test]
fn an_inline_comment_is_reported_once_and_only_as_such() {
    let number_codes = [
        codes::E0008,
        codes::E0301,
        codes::E0302,
        codes::E0303,
        codes::E0304,
        codes::E0305,
        codes::E0309,
        codes::E0314,
        codes::E0317,
    ];
    for (old, new) in [
        ("PDOMapping=0", "PDOMapping=0 # Optional"),
        ("PDOMapping=0", "PDOMapping=0 ; never mapped"),
        ("ObjectType=0x7", "ObjectType=0x7 # VAR"),
        ("DataType=0x0005", "DataType=0x0005 ; UNSIGNED8"),
        ("DefaultValue=2", "DefaultValue=2 # two entries"),
        ("AccessType=ro", "AccessType=ro # read only"),
    ] {
        let found = codes_of(&base_with(&[("1018sub0", old, new)]), &number_codes);
        assert_eq!(found.len(), 1, "{new}: {found:?}");
        assert_eq!(found[0].0, codes::E0008, "{new}: {found:?}");
    }
}
