//! The canonical text the writer produces, feature by feature, and `configure`.

use crate::write_common;

use eds::model::*;
use eds::write::{configure, format_value, unrepresentable, write_dcf, write_eds};
use write_common::{entry, full_dcf, full_eds, multi, var};

fn small() -> Model {
    let mut m = Model::default();
    m.file_info.file_name = Some("small.eds".into());
    m.device_info.vendor_number = Some(0x151);
    m.device_info.baud_rates.insert(500, true);
    m.objects.insert(
        Index(0x1000),
        var(
            0x1000,
            Category::Mandatory,
            entry(0, "Device type", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x20192))),
        ),
    );
    m.objects.insert(
        Index(0x1018),
        multi(
            0x1018,
            "Identity",
            ObjectType::Record,
            Category::Mandatory,
            vec![
                entry(0, "Count", DataType::Unsigned8, Access::Ro, Some(Value::int(1))),
                entry(1, "Vendor-ID", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x151))),
            ],
        ),
    );
    let mut e = entry(0, "Target", DataType::Integer32, Access::Rww, Some(Value::int(-5)));
    e.pdo_mapping = true;
    e.extras_mut().low_limit = Some(Value::hex(-0x10));
    e.extras_mut().high_limit = Some(Value::Int { value: 8, radix: Radix::Oct });
    e.extras_mut().extra = vec![("Unit".into(), "mm".into())];
    m.objects.insert(Index(0x607A), var(0x607A, Category::Optional, e));
    m
}

#[test]
fn canonical_text_of_a_small_model() {
    let expected = "\
[FileInfo]
FileName=small.eds

[DeviceInfo]
VendorNumber=0x00000151
BaudRate_500=1

[MandatoryObjects]
SupportedObjects=2
1=0x1000
2=0x1018

[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00020192
PDOMapping=0

[1018]
ParameterName=Identity
ObjectType=0x9
SubNumber=0x2

[1018sub0]
ParameterName=Count
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=1
PDOMapping=0

[1018sub1]
ParameterName=Vendor-ID
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000151
PDOMapping=0

[OptionalObjects]
SupportedObjects=1
1=0x607A

[607A]
ParameterName=Target
ObjectType=0x7
DataType=0x0004
AccessType=rww
DefaultValue=-5
LowLimit=-0x10
HighLimit=010
PDOMapping=1
Unit=mm

[ManufacturerObjects]
SupportedObjects=0
";
    assert_eq!(write_eds(&small()), expected);
}

fn position(text: &str, needle: &str) -> usize {
    text.find(needle).unwrap_or_else(|| panic!("{needle} missing from:\n{text}"))
}

#[test]
fn sections_come_in_canonical_order() {
    let text = write_dcf(&full_dcf());
    let order = [
        "[FileInfo]",
        "[DeviceInfo]",
        "[DeviceComissioning]",
        "[DummyUsage]",
        "[Comments]",
        "[MandatoryObjects]",
        "[1000]",
        "[1001]",
        "[1018]",
        "[1018sub4]",
        "[OptionalObjects]",
        "[1014]",
        "[1400sub2]",
        "[1600sub1]",
        "[6040]",
        "[ManufacturerObjects]",
        "[2000]",
        "[2001]",
        "[2001ObjectLinks]",
        "[2002]",
        "[2003sub1A]",
        "[Tools]",
    ];
    let positions: Vec<usize> =
        order.iter().map(|s| position(&text, &format!("\n{s}\n").replace("\n[FileInfo]", "[FileInfo]"))).collect();
    for (w, pair) in positions.windows(2).enumerate() {
        assert!(pair[0] < pair[1], "{} should come before {}", order[w], order[w + 1]);
    }
    // Sub-indices are hex: sub 0x1A of 0x2003, not "sub26".
    assert!(!text.contains("[2003sub26]"));
}

#[test]
fn entry_keys_come_in_canonical_order() {
    let text = write_dcf(&full_dcf());
    let section = &text[position(&text, "[2001]\n")..];
    let section = &section[..section.find("\n\n").unwrap()];
    let keys: Vec<&str> = section.lines().skip(1).map(|l| l.split('=').next().unwrap()).collect();
    assert_eq!(
        keys,
        [
            "ParameterName",
            "ObjectType",
            "DataType",
            "AccessType",
            "DefaultValue",
            "ParameterValue",
            "PDOMapping",
            "ObjFlags",
            "Denotation",
            "Unit",
            "Factor"
        ]
    );
    let domain = &text[position(&text, "[2002]\n")..];
    let domain = &domain[..domain.find("\n\n").unwrap()];
    assert!(domain.contains("ObjectType=0x2\n"), "{domain}");
    assert!(domain.ends_with("PDOMapping=0\nUploadFile=fw_up.bin\nDownloadFile=fw_down.bin"), "{domain}");
}

#[test]
fn eds_has_no_commissioning_and_dcf_has_it() {
    let dcf = full_dcf();
    let eds_text = write_eds(&dcf);
    let dcf_text = write_dcf(&dcf);
    assert!(!eds_text.contains("[DeviceComissioning]"));
    let c = &dcf_text[position(&dcf_text, "[DeviceComissioning]")..];
    let c = &c[..c.find("\n\n").unwrap()];
    assert_eq!(
        c,
        "[DeviceComissioning]\nNodeID=5\nNodeName=axis_x\nBaudrate=500\nNetNumber=1\nNetworkName=machine\nCANopenManager=0\nLSS_SerialNumber=0x00001234"
    );
    // The EDS default stays next to the configured value.
    let rpdo = &dcf_text[position(&dcf_text, "[1400sub1]")..];
    assert!(rpdo.contains("DefaultValue=$NODEID+0x200\nParameterValue=$NODEID+0x200\n"));
    // write() follows the model's kind.
    assert_eq!(eds::write::write(&dcf), dcf_text);
    assert_eq!(eds::write::write(&full_eds()), write_eds(&full_eds()));
}

#[test]
fn values_are_written_in_their_radix() {
    let cases: Vec<(Value, DataType, &str)> = vec![
        (Value::int(42), DataType::Unsigned8, "42"),
        (Value::hex(0x2A), DataType::Unsigned8, "0x2A"),
        (Value::hex(0x180), DataType::Unsigned32, "0x00000180"),
        (Value::hex(0x180), DataType::Other(0x40), "0x180"),
        (Value::hex(-1), DataType::Integer16, "-0x1"),
        (Value::int(-32768), DataType::Integer16, "-32768"),
        (Value::Int { value: 8, radix: Radix::Oct }, DataType::Unsigned8, "010"),
        (Value::Int { value: 0, radix: Radix::Oct }, DataType::Unsigned8, "00"),
        (Value::Int { value: -8, radix: Radix::Oct }, DataType::Integer8, "-010"),
        (Value::NodeIdPlus { offset: 0x180, radix: Radix::Hex }, DataType::Unsigned32, "$NODEID+0x180"),
        (Value::NodeIdPlus { offset: -2, radix: Radix::Dec }, DataType::Unsigned32, "$NODEID-2"),
        (Value::NodeIdPlus { offset: 0, radix: Radix::Hex }, DataType::Unsigned8, "$NODEID+0x0"),
        (Value::NodeIdPlus { offset: 0, radix: Radix::Dec }, DataType::Unsigned8, "$NODEID+0"),
        (Value::Real(0.1f32 as f64), DataType::Real32, "0.1"),
        (Value::Real(0.1), DataType::Real64, "0.1"),
        (Value::Real(-2.0), DataType::Real64, "-2"),
        (Value::Real(f64::INFINITY), DataType::Real64, "inf"),
        (Value::Text("a = b ; c".into()), DataType::VisibleString, "a = b ; c"),
        (Value::Bytes(vec![0, 0xAB, 0x1]), DataType::OctetString, "00AB01"),
    ];
    for (v, ty, want) in cases {
        assert_eq!(format_value(&v, ty), want, "{v:?} as {ty:?}");
        // And the reader's value rules read it back as the same value.
        let back = eds::value::parse_value(want, ty).unwrap().value.unwrap();
        assert_eq!(back, v, "{want} as {ty:?}");
    }
}

#[test]
fn unrepresentable_models_are_named() {
    assert!(unrepresentable(&full_dcf()).is_empty());
    let mut m = small();
    m.comments.push("two\nlines".into());
    m.objects
        .get_mut(&Index(0x607A))
        .unwrap()
        .subs
        .get_mut(&SubIndex(0))
        .unwrap()
        .extras_mut()
        .extra
        .push(("Bad=Key".into(), "v".into()));
    m.file_info.description = Some(" padded".into());
    let problems = unrepresentable(&m);
    let text: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
    assert_eq!(problems.len(), 3, "{text:#?}");
    assert!(text.iter().any(|t| t.contains("Line1") && t.contains("line break")), "{text:#?}");
    assert!(text.iter().any(|t| t.contains("Bad=Key")), "{text:#?}");
    assert!(text.iter().any(|t| t.contains("Description") && t.contains("white space")), "{text:#?}");
}

// ---- configure ----

#[test]
fn configure_records_values_and_keeps_defaults() {
    let eds = full_eds();
    let dcf = configure(
        &eds,
        0x7F,
        Some(1000),
        &[(0x1400, 1, Value::NodeIdPlus { offset: 0x300, radix: Radix::Hex }), (0x2000, 8, Value::int(3))],
    )
    .unwrap();
    assert_eq!(dcf.kind, FileKind::Dcf);
    let c = dcf.commissioning.as_ref().unwrap();
    assert_eq!((c.node_id, c.baudrate), (Some(0x7F), Some(1000)));
    let cob = dcf.entry(0x1400, 1).unwrap();
    assert_eq!(cob.default, Some(Value::NodeIdPlus { offset: 0x200, radix: Radix::Hex }));
    assert_eq!(cob.parameter_value().cloned(), Some(Value::NodeIdPlus { offset: 0x300, radix: Radix::Hex }));
    // An integer given for a REAL32 is recorded as a REAL.
    assert_eq!(dcf.entry(0x2000, 8).unwrap().data_type, DataType::Real32);
    assert_eq!(dcf.entry(0x2000, 8).unwrap().parameter_value().cloned(), Some(Value::Real(3.0)));
    // Nothing else changed.
    let mut back = dcf.clone();
    back.kind = FileKind::Eds;
    back.commissioning = None;
    for (i, s) in [(0x1400, 1), (0x2000, 8)] {
        back.objects.get_mut(&Index(i)).unwrap().subs.get_mut(&SubIndex(s)).unwrap().set_parameter_value(None);
    }
    assert_eq!(back, eds);
    // Without a bit rate, an existing one is kept.
    let again = configure(&dcf, 3, None, &[]).unwrap();
    assert_eq!(again.commissioning.unwrap().baudrate, Some(1000));
}

fn problems(model: &Model, node: u8, baud: Option<u16>, values: &[(u16, u8, Value)]) -> Vec<String> {
    configure(model, node, baud, values).unwrap_err().problems.iter().map(|p| p.to_string()).collect()
}

#[test]
fn configure_reports_every_problem_with_its_place() {
    let mut eds = full_eds();
    // Give one entry a source location, as a model read from a file has.
    eds.objects.get_mut(&Index(0x2001)).unwrap().subs.get_mut(&SubIndex(0)).unwrap().at =
        SourceRef { line: 812, col: 1, span: Default::default() };
    let mut limited = eds.objects[&Index(0x1600)].subs[&SubIndex(1)].clone();
    limited.extras_mut().high_limit = Some(Value::NodeIdPlus { offset: 0x10, radix: Radix::Hex });
    eds.objects.get_mut(&Index(0x1600)).unwrap().subs.insert(SubIndex(1), limited);
    let p = problems(
        &eds,
        0,
        Some(800),
        &[
            (0x5555, 0, Value::int(1)),
            (0x1018, 9, Value::int(1)),
            (0x1000, 0, Value::int(1)),
            (0x2001, 0, Value::int(40000)),
            (0x2001, 0, Value::int(1)),
            (0x2000, 9, Value::int(7)),
            (0x1600, 1, Value::int(0x20)),
        ],
    );
    let expect = [
        "node id 0 is outside 1..=127",
        "the device does not support 800 kbit/s",
        "the device has no object 0x5555",
        "object 0x1018 has no sub-index 9 (hint: its sub-indices are 0, 1, 2, 3, 4)",
        "in object 0x1000 \"Device type\": in sub 0 \"Device type\": the entry is `ro`",
        "812:1: in object 0x2001 \"Flags and denotation\": in sub 0 \"Flags and denotation\": 40000 is outside the INTEGER16 range -32768..=32767",
        "this entry is configured twice",
        "`7` is not text, not a VISIBLE_STRING value",
        "is above the entry's HighLimit 16",
    ];
    assert_eq!(p.len(), expect.len(), "{p:#?}");
    for (got, want) in p.iter().zip(expect) {
        assert!(got.contains(want), "expected {want:?} in {got:?}");
    }
}

#[test]
fn configure_checks_types_and_limits() {
    let eds = full_eds();
    // Unsigned8 (sub 5 of 0x2000): 255 fits, 256 does not, -1 does not.
    assert!(configure(&eds, 1, None, &[(0x2000, 5, Value::int(255))]).is_ok());
    assert!(
        problems(&eds, 1, None, &[(0x2000, 5, Value::int(256))])[0].contains("outside the UNSIGNED8 range 0..=255")
    );
    assert!(problems(&eds, 1, None, &[(0x2000, 5, Value::int(-1))])[0].contains("outside"));
    // $NODEID is resolved for the range check only: 0xF0 + 0x20 > 0xFF.
    let nid = Value::NodeIdPlus { offset: 0xF0, radix: Radix::Hex };
    assert!(configure(&eds, 0x0F, None, &[(0x2000, 5, nid.clone())]).is_ok());
    assert!(problems(&eds, 0x20, None, &[(0x2000, 5, nid)])[0].contains("with node id 32"));
    // Reals: text is not a number; REAL32 overflow.
    assert!(problems(&eds, 1, None, &[(0x2000, 8, Value::Text("x".into()))])[0].contains("not a REAL32 value"));
    assert!(problems(&eds, 1, None, &[(0x2000, 8, Value::Real(1e300))])[0].contains("does not fit a REAL32"));
    // REAL64 limits are -10..=10.25.
    assert!(configure(&eds, 1, None, &[(0x2000, 16, Value::Real(10.25))]).is_ok());
    assert!(
        problems(&eds, 1, None, &[(0x2000, 16, Value::Real(10.5))])[0].contains("above the entry's HighLimit 10.25")
    );
    assert!(problems(&eds, 1, None, &[(0x2000, 16, Value::int(-11))])[0].contains("below the entry's LowLimit -10"));
    // Bytes for OCTET_STRING, text for VISIBLE_STRING (printable ASCII only).
    assert!(configure(&eds, 1, None, &[(0x2000, 10, Value::Bytes(vec![1, 2]))]).is_ok());
    assert!(problems(&eds, 1, None, &[(0x2000, 10, Value::int(1))])[0].contains("not a string of hex bytes"));
    assert!(problems(&eds, 1, None, &[(0x2000, 9, Value::Text("grüß".into()))])[0].contains("printable ASCII"));
    assert!(configure(&eds, 1, None, &[(0x2000, 11, Value::Text("grüß".into()))]).is_ok());
    assert!(problems(&eds, 1, None, &[(0x2000, 9, Value::Text("a\nb".into()))])[0].contains("line break"));
    // Bit rates: not a CANopen rate.
    assert!(problems(&eds, 1, Some(300), &[])[0].contains("300 kbit/s is not a CANopen bit rate"));
    assert!(configure(&eds, 1, Some(125), &[]).is_ok());
}

#[test]
fn compact_arrays_stay_compact() {
    let text = write_dcf(&full_dcf());
    let start = position(&text, "[2100]\n");
    let section: String = text[start..].split("\n\n").take(3).collect::<Vec<_>>().join("\n\n");
    assert_eq!(
        section,
        "[2100]\nParameterName=Gains\nObjectType=0x8\nDataType=0x0006\nAccessType=rw\nDefaultValue=0x0010\n\
         HighLimit=1000\nPDOMapping=1\nCompactSubObj=3\n\n\
         [2100Name]\nNrOfEntries=3\n1=Gains1\n2=Gain Y\n3=Gains3\n\n\
         [2100Value]\nNrOfEntries=1\n3=999"
    );
    assert!(!text.contains("[2100sub"));
    let info = eds::write::compact_info(&full_dcf().objects[&Index(0x2100)]).unwrap();
    assert_eq!((info.n, info.data_type, info.default), (3, DataType::Unsigned16, Some(Value::hex(0x10))));

    // Change one sub-object so it no longer fits the compact form: written expanded, and the
    // model is reported as not representable (CompactSubObj would be lost).
    let mut m = full_eds();
    let o = m.objects.get_mut(&Index(0x2100)).unwrap();
    o.subs.get_mut(&SubIndex(2)).unwrap().access = Access::Ro;
    assert!(eds::write::compact_info(o).is_none());
    let text = write_eds(&m);
    assert!(text.contains("[2100sub2]\n") && !text.contains("CompactSubObj"), "{text}");
    assert_eq!(unrepresentable(&m).len(), 1);
}
