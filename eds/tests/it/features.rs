//! One fixture per feature (`fixtures/features/`): the typed model is snapshot as YAML, and the
//! values that matter are asserted directly.

use std::path::Path;

use eds::model::{Access, Category, DataType, FileKind, ObjectType, Radix, Value};
use eds::{Options, codes};

fn read(name: &str, options: &Options) -> eds::Parsed {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/features").join(name);
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    eds::parse(name, &bytes, options)
}

fn has(p: &eds::Parsed, code: eds::Code) -> bool {
    p.diagnostics.iter().any(|d| d.code == code)
}

fn default(p: &eds::Parsed, index: u16, sub: u8) -> Option<Value> {
    p.model.entry(index, sub).and_then(|e| e.default.clone())
}

#[test]
fn node_id_stays_symbolic() {
    let p = read("nodeid.eds", &Options::lenient());
    for (sub, offset) in [(1, 0x180), (2, 0x180), (3, 0x200), (4, 0), (5, 512)] {
        let v = default(&p, 0x1400, sub).expect("default");
        assert!(v.is_node_relative(), "sub {sub}: {v:?}");
        assert_eq!(v.resolve(0x22), Some(offset + 0x22), "sub {sub}");
        assert_eq!(v.as_int(), None);
    }
    assert_eq!(default(&p, 0x1400, 5), Some(Value::NodeIdPlus { offset: 512, radix: Radix::Dec }));
    let e = p.model.entry(0x1400, 5).expect("entry");
    assert_eq!(e.low_limit().cloned(), Some(Value::NodeIdPlus { offset: 0x200, radix: Radix::Hex }));
    assert!(!p.has_errors());
    insta::assert_yaml_snapshot!("model_nodeid", p.model);
}

#[test]
fn compact_sub_objects_and_dcf() {
    let p = read("compact.dcf", &Options::lenient());
    assert_eq!(p.model.kind, FileKind::Dcf);
    let c = p.model.commissioning.as_ref().expect("commissioning");
    assert_eq!(c.node_id, Some(5));
    assert_eq!(c.baudrate, Some(500));
    assert_eq!(c.network_name.as_deref(), Some("line A"));
    assert_eq!(c.canopen_manager, Some(false));
    assert_eq!(p.model.node_id(), Some(5));
    assert_eq!(p.model.file_info.extra, vec![("LastEDS".to_owned(), "device.eds".to_owned())]);
    let o = p.model.object(0x1016).expect("1016");
    assert_eq!(o.compact_sub_obj, Some(3));
    assert_eq!(o.subs.len(), 4);
    assert_eq!(o.sub(0).map(|e| (e.data_type, e.access)), Some((DataType::Unsigned8, Access::Ro)));
    assert_eq!(default(&p, 0x1016, 0).and_then(|v| v.as_int()), Some(3));
    assert_eq!(o.sub(1).map(|e| e.name.as_str()), Some("Heartbeat of the master"));
    assert_eq!(o.sub(2).map(|e| e.name.as_str()), Some("Consumer heartbeat time2"));
    assert_eq!(o.sub(3).map(|e| e.name.as_str()), Some("Heartbeat of axis 2"));
    assert_eq!(o.sub(1).and_then(|e| e.parameter_value().cloned()), Some(Value::hex(0x007F03E8)));
    assert_eq!(o.sub(3).and_then(|e| e.parameter_value().cloned()), None);
    assert!(o.subs.values().skip(1).all(|e| e.data_type == DataType::Unsigned32 && e.access == Access::Rw));
    let hb = p.model.entry(0x1017, 0).expect("1017");
    assert_eq!(hb.parameter_value().and_then(Value::as_int), Some(100));
    assert_eq!(hb.denotation(), Some("heartbeat_ms"));
    // The English spelling of the section is reported, NodeId's case is noted.
    assert!(has(&p, codes::E0103));
    assert!(has(&p, codes::E0104));
    // [1016Name] says NrOfEntries=2 and has two entries; [1016Value] too: no E0214.
    assert!(!has(&p, codes::E0214));
    assert!(!has(&p, codes::E0315), "ParameterValue belongs in a DCF");
    insta::assert_yaml_snapshot!("model_compact_dcf", p.model);
}

#[test]
fn every_object_type() {
    let p = read("object_types.eds", &Options::strict());
    let t = |i: u16| p.model.object(i).map(|o| o.object_type);
    assert_eq!(t(0x0007), Some(ObjectType::DefType));
    assert_eq!(t(0x0020), Some(ObjectType::DefStruct));
    assert_eq!(t(0x1F50), Some(ObjectType::Domain));
    assert_eq!(t(0x2000), Some(ObjectType::Null));
    assert_eq!(t(0x2001), Some(ObjectType::Var));
    assert_eq!(t(0x2002), Some(ObjectType::Array));
    assert_eq!(t(0x2003), Some(ObjectType::Record));
    assert!(p.model.object(0x2000).is_some_and(|o| o.subs.is_empty()));
    let domain = p.model.entry(0x1F50, 0).expect("domain entry");
    assert_eq!((domain.data_type, domain.access), (DataType::Domain, Access::Rw), "DOMAIN defaults");
    assert_eq!(domain.upload_file(), Some("program.bin"));
    assert_eq!(default(&p, 0x2004, 0), Some(Value::Bytes(vec![0xDE, 0xAD, 0xBE, 0xEF])));
    assert_eq!(
        p.model.object(0x2001).map(|o| o.object_links.clone()),
        Some(vec![eds::Index(0x2002), eds::Index(0x2003)])
    );
    assert_eq!(p.model.object(0x2003).and_then(|o| o.obj_flags), Some(1));
    assert_eq!(p.model.entry(0x2003, 2).and_then(|e| e.obj_flags()), Some(2));
    assert_eq!(default(&p, 0x2002, 1), Some(Value::Real(1.5)));
    assert_eq!(p.model.object(0x2001).map(|o| o.category), Some(Category::Manufacturer));
    let errors: Vec<_> = p.errors().map(|d| d.code).collect();
    // Strict mode still has things to say (no [DeviceInfo], no mandatory objects), but nothing
    // about the object types themselves.
    assert!(errors.iter().all(|c| [codes::E0501, codes::E0502].contains(c)), "{errors:?}");
    insta::assert_yaml_snapshot!("model_object_types", p.model);
}

#[test]
fn every_data_type() {
    let p = read("data_types.eds", &Options::lenient());
    let int = |sub| default(&p, 0x2000, sub).and_then(|v| v.as_int());
    let real = |sub| match default(&p, 0x2000, sub) {
        Some(Value::Real(f)) => f,
        v => panic!("sub {sub}: {v:?}"),
    };
    let o = p.model.object(0x2000).expect("2000");
    let types: Vec<DataType> = o.subs.values().skip(1).map(|e| e.data_type).collect();
    for t in DataType::BASIC {
        assert!(types.contains(&t), "{t:?} not covered");
    }
    assert_eq!(int(1), Some(1));
    assert_eq!(int(2), Some(-128));
    assert_eq!(int(3), Some(-16));
    assert_eq!(p.model.entry(0x2000, 3).and_then(|e| e.low_limit()).and_then(Value::as_int), Some(-32768));
    assert_eq!(int(4), Some(-1));
    assert_eq!(int(6), Some(0xFFFF));
    assert_eq!(int(7), Some(u32::MAX as i128));
    assert_eq!(real(8), -125.0);
    assert_eq!(default(&p, 0x2000, 9), Some(Value::Text("Hello; world = 1".into())));
    assert_eq!(default(&p, 0x2000, 0xA), Some(Value::Bytes(vec![1, 2, 0xAB])));
    assert_eq!(default(&p, 0x2000, 0xB), Some(Value::Text("Grüße".into())));
    assert_eq!(int(0xC), Some(43_200_000 | 365 << 32));
    assert_eq!(default(&p, 0x2000, 0xF), None);
    assert_eq!(int(0x10), Some(-(1 << 23)));
    assert_eq!(real(0x11), 1.5);
    assert_eq!(int(0x12), Some(-(1 << 39)));
    assert_eq!(int(0x14), Some(-(1 << 55)));
    assert_eq!(int(0x15), Some(i64::MIN as i128));
    assert_eq!(int(0x1B), Some(u64::MAX as i128));
    assert_eq!(real(0x1C) as f32, std::f32::consts::PI);
    assert_eq!(real(0x1D), 3.0);
    assert!(!p.has_errors(), "{:#?}", p.diagnostics);
    assert!(!p.diagnostics.iter().any(|d| d.code == codes::E0302), "no value is out of range");
    insta::assert_yaml_snapshot!("model_data_types", p.model);
}

#[test]
fn number_rules() {
    let p = read("numbers.eds", &Options::lenient());
    let v = |sub| default(&p, 0x2000, sub);
    assert_eq!(v(1), Some(Value::Int { value: 8, radix: Radix::Oct }));
    assert_eq!(v(2), Some(Value::Int { value: 1, radix: Radix::Oct }));
    assert_eq!(v(3), Some(Value::Int { value: 0, radix: Radix::Oct }));
    assert_eq!(v(4), Some(Value::Int { value: 9, radix: Radix::Dec }));
    assert_eq!(v(5), None);
    assert_eq!(v(6), Some(Value::int(0)));
    assert_eq!(v(7), Some(Value::int(0)));
    let codes_at = |sub: u8| -> Vec<eds::Code> {
        let at = p.model.entry(0x2000, sub).expect("entry").at.span.start;
        let next = p.model.entry(0x2000, sub + 1).map(|e| e.at.span.start).unwrap_or(u32::MAX);
        p.diagnostics
            .iter()
            .filter(|d| d.span.is_some_and(|s| s.start > at && s.start < next))
            .map(|d| d.code)
            .collect()
    };
    assert_eq!(codes_at(1), vec![codes::E0303]);
    assert_eq!(codes_at(2), vec![codes::E0305]);
    assert_eq!(codes_at(3), vec![codes::E0305]);
    assert_eq!(codes_at(4), vec![codes::E0304]);
    assert_eq!(codes_at(5), vec![codes::E0308]);
    assert_eq!(codes_at(6), vec![codes::E0311]);
    assert_eq!(codes_at(7), vec![]);
}

#[test]
fn lenient_loads_what_vendors_write() {
    let p = read("lenient.eds", &Options::lenient());
    // Everything but the entry without DataType is there.
    assert!(p.model.object(0x100A).is_some(), "[100a] is read as 0x100A");
    assert_eq!(p.model.entry(0x1001, 0).map(|e| (e.name.as_str(), e.access)), Some(("Error register", Access::Ro)));
    assert_eq!(p.model.entry(0x1000, 0).map(|e| e.access), Some(Access::Ro));
    assert_eq!(p.model.entry(0x1018, 0).map(|e| e.access), Some(Access::Const));
    assert!(p.model.entry(0x1018, 1).is_none(), "no DataType: skipped");
    assert_eq!(p.model.file_info.file_name.as_deref(), Some("lenient.eds"));
    assert_eq!(p.model.device_info.baud_rates.get(&100), Some(&true));
    assert_eq!(p.model.device_info.extra, vec![("NG_Slave".to_owned(), "0".to_owned())]);
    // The one error is located at the section that lacks DataType.
    let errors: Vec<_> = p.errors().collect();
    assert_eq!(errors.len(), 1, "{errors:#?}");
    assert_eq!(errors[0].code, codes::E0204);
    assert_eq!(p.document.source.slice(errors[0].span.expect("span")), "1018sub1");
    assert!(has(&p, codes::E0207), "AccessType=R");
    assert!(has(&p, codes::E0103), "[Mandatory Objects]");
    assert!(p.diagnostics.iter().any(|d| d.code == codes::E0104 && d.message.contains("Baudrate_100")));
    let text = eds::diag::render_all(&p.diagnostics, &p.document.source);
    insta::assert_snapshot!("diag_lenient_eds", text);
    insta::assert_yaml_snapshot!("model_lenient", p.model);
}

#[test]
fn compact_pdo_expands_into_objects() {
    let p = read("compact_pdo.eds", &Options::lenient());
    assert!(has(&p, codes::E0612));
    assert!(!has(&p, codes::E0504), "implied PDOs are not missing PDOs");
    let mut model = p.model.clone();
    let made = eds::lower::expand_compact_pdo(&mut model);
    let want: Vec<eds::Index> = [0x1400, 0x1401, 0x1600, 0x1601, 0x1800, 0x1A00].map(eds::Index).to_vec();
    assert_eq!(made, want);
    // 0x13: COB-ID, transmission type, event timer.
    let subs: Vec<u8> = model.object(0x1800).expect("1800").subs.keys().map(|s| s.0).collect();
    assert_eq!(subs, vec![0, 1, 2, 5]);
    assert_eq!(model.entry(0x1401, 1).and_then(|e| e.default.as_ref()).and_then(|v| v.resolve(3)), Some(0x303));
    // Expanding twice changes nothing.
    assert!(eds::lower::expand_compact_pdo(&mut model).is_empty());
}

#[test]
fn unknown_sections_and_keys_are_kept() {
    let p = read("lenient.eds", &Options::lenient());
    assert!(p.model.device_info.extra.iter().any(|(k, _)| k == "NG_Slave"));
    let src = "[FileInfo]\nFileName=x\n[Tools]\nEditor=vi\nEditor=emacs\n[1000]\nParameterName=Device type\nDataType=7\nAccessType=ro\nVendorKey=42\n";
    let p = eds::parse("x.eds", src.as_bytes(), &Options::lenient());
    assert_eq!(p.model.extra_sections.len(), 1);
    assert_eq!(p.model.extra_sections[0].name, "Tools");
    // A repeated key is reported (E0007) and, as in every section, its later value is used.
    assert_eq!(p.model.extra_sections[0].entries, vec![("Editor".to_owned(), "emacs".to_owned())]);
    assert!(has(&p, codes::E0007));
    assert_eq!(
        p.model.entry(0x1000, 0).map(|e| e.extra().to_vec()),
        Some(vec![("VendorKey".to_owned(), "42".to_owned())])
    );
    assert!(has(&p, codes::E0101));
    assert!(has(&p, codes::E0102));
}

#[test]
fn duplicate_sections_merge_and_later_keys_win() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/diag/E0006.eds");
    let p = eds::parse("E0006.eds", &std::fs::read(path).expect("read"), &Options::lenient());
    let e = p.model.entry(0x2000, 0).expect("2000");
    assert_eq!(e.high_limit().and_then(Value::as_int), Some(2000), "the repeated section's HighLimit wins");
    assert_eq!(e.name, "Target speed", "keys of the first occurrence are kept");
    assert!(!has(&p, codes::E0007), "keys repeated by a repeated section are reported once, as E0006");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/diag/E0007.eds");
    let p = eds::parse("E0007.eds", &std::fs::read(path).expect("read"), &Options::lenient());
    assert_eq!(default(&p, 0x2000, 0).and_then(|v| v.as_int()), Some(200), "the later DefaultValue wins");
}

#[test]
fn entries_carry_their_source_location() {
    let p = read("object_types.eds", &Options::lenient());
    let e = p.model.entry(0x2003, 2).expect("2003sub2");
    assert_eq!(p.document.source.slice(e.at.span), "2003sub2");
    assert_eq!(p.document.source.line_text(e.at.line), "[2003sub2]");
    assert_eq!(e.at.col, 2);
}
