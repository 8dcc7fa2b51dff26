//! Models built in code for the writer tests and the python-canopen interop test: one per
//! feature of the file format, so a failure names the feature.
#![allow(dead_code)]

use std::collections::BTreeMap;

use eds::model::*;

/// An entry with the given basics and nothing else.
pub fn entry(sub: u8, name: &str, data_type: DataType, access: Access, default: Option<Value>) -> Entry {
    Entry {
        sub: SubIndex(sub),
        name: name.into(),
        data_type,
        access,
        pdo_mapping: false,
        default,
        extras: None,
        at: SourceRef::default(),
    }
}

/// A VAR object holding `e` (its name becomes the object's name).
pub fn var(index: u16, category: Category, e: Entry) -> Object {
    let mut subs = SubMap::new();
    let name = e.name.clone();
    subs.insert(SubIndex(0), Entry { sub: SubIndex(0), ..e });
    Object {
        index: Index(index),
        name,
        object_type: ObjectType::Var,
        category,
        subs,
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: SourceRef::default(),
    }
}

/// An ARRAY or RECORD object with these entries.
pub fn multi(index: u16, name: &str, object_type: ObjectType, category: Category, entries: Vec<Entry>) -> Object {
    Object {
        index: Index(index),
        name: name.into(),
        object_type,
        category,
        subs: entries.into_iter().map(|e| (e.sub, e)).collect(),
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: SourceRef::default(),
    }
}

fn u8_count(n: u8) -> Entry {
    entry(0, "Highest sub-index supported", DataType::Unsigned8, Access::Ro, Some(Value::int(n as i128)))
}

/// Header sections filled in.
pub fn header() -> Model {
    let file_info = FileInfo {
        file_name: Some("fixture.eds".into()),
        file_version: Some(1),
        file_revision: Some(2),
        eds_version: Some("4.0".into()),
        description: Some("Writer fixture".into()),
        creation_time: Some("10:00AM".into()),
        creation_date: Some("01-02-2025".into()),
        created_by: Some("edsback".into()),
        modification_time: Some("11:00AM".into()),
        modification_date: Some("01-03-2025".into()),
        modified_by: Some("edsback".into()),
        extra: vec![("LastEDS".into(), "fixture.eds".into())],
    };
    let mut baud_rates = BTreeMap::new();
    for (rate, on) in
        [(10, false), (20, false), (50, false), (125, true), (250, true), (500, true), (800, false), (1000, true)]
    {
        baud_rates.insert(rate, on);
    }
    let device_info = DeviceInfo {
        vendor_name: Some("Example Vendor".into()),
        vendor_number: Some(0x0000_0151),
        product_name: Some("Example Drive".into()),
        product_number: Some(0x0001_0002),
        revision_number: Some(0x0003_0004),
        order_code: Some("EX-1".into()),
        baud_rates,
        simple_boot_up_master: Some(false),
        simple_boot_up_slave: Some(true),
        granularity: Some(8),
        dynamic_channels_supported: Some(0),
        group_messaging: Some(false),
        nr_of_rx_pdo: Some(1),
        nr_of_tx_pdo: Some(0),
        lss_supported: Some(false),
        compact_pdo: None,
        extra: Vec::new(),
    };
    Model {
        file_info,
        device_info,
        dummy_usage: (1..=7).map(|i| (i, i == 5 || i == 6 || i == 7)).collect(),
        comments: vec!["Written by the eds writer tests.".into(), "Second line: a = b".into()],
        ..Model::default()
    }
}

/// The communication objects every device has.
pub fn mandatory(m: &mut Model) {
    let mut o = var(
        0x1000,
        Category::Mandatory,
        entry(0, "Device type", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x0002_0192))),
    );
    o.subs.get_mut(&SubIndex(0)).unwrap().extras_mut().extra = vec![("Description".into(), "CiA 402 drive".into())];
    m.objects.insert(o.index, o);
    let mut e = entry(0, "Error register", DataType::Unsigned8, Access::Ro, Some(Value::int(0)));
    e.pdo_mapping = true;
    let o = var(0x1001, Category::Mandatory, e);
    m.objects.insert(o.index, o);
    let o = multi(
        0x1018,
        "Identity object",
        ObjectType::Record,
        Category::Mandatory,
        vec![
            u8_count(4),
            entry(1, "Vendor-ID", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x151))),
            entry(2, "Product code", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x10002))),
            entry(3, "Revision number", DataType::Unsigned32, Access::Ro, Some(Value::hex(0x30004))),
            entry(4, "Serial number", DataType::Unsigned32, Access::Ro, Some(Value::int(0))),
        ],
    );
    m.objects.insert(o.index, o);
}

/// PDO and node-id-relative objects.
pub fn pdos(m: &mut Model) {
    let nid = |offset, radix| Some(Value::NodeIdPlus { offset, radix });
    let o = multi(
        0x1400,
        "RPDO1 communication parameter",
        ObjectType::Record,
        Category::Optional,
        vec![
            u8_count(2),
            entry(1, "COB-ID used by RPDO", DataType::Unsigned32, Access::Rw, nid(0x200, Radix::Hex)),
            entry(2, "Transmission type", DataType::Unsigned8, Access::Rw, Some(Value::hex(0xFF))),
        ],
    );
    m.objects.insert(o.index, o);
    let mut map1 = entry(1, "Mapped object 1", DataType::Unsigned32, Access::Rw, Some(Value::hex(0x6040_0010)));
    map1.extras_mut().low_limit = Some(Value::int(0));
    let o = multi(
        0x1600,
        "RPDO1 mapping parameter",
        ObjectType::Array,
        Category::Optional,
        vec![entry(0, "Number of mapped objects", DataType::Unsigned8, Access::Rw, Some(Value::int(1))), map1],
    );
    m.objects.insert(o.index, o);
    let o = var(
        0x1014,
        Category::Optional,
        entry(0, "COB-ID EMCY", DataType::Unsigned32, Access::Rw, nid(0x80, Radix::Hex)),
    );
    m.objects.insert(o.index, o);
    let o = var(
        0x1015,
        Category::Optional,
        entry(0, "Node-relative decimal", DataType::Unsigned16, Access::Rw, nid(7, Radix::Dec)),
    );
    m.objects.insert(o.index, o);
    let o =
        var(0x1016, Category::Optional, entry(0, "Bare node id", DataType::Unsigned8, Access::Rw, nid(0, Radix::Hex)));
    m.objects.insert(o.index, o);
}

/// A RECORD with one entry of every basic type, with limits in several radices.
pub fn all_types(m: &mut Model) {
    let mut entries = vec![u8_count(0)];
    let mut sub = 1u8;
    for ty in DataType::BASIC {
        let default = match ty {
            DataType::Boolean => Some(Value::int(1)),
            DataType::Real32 => Some(Value::Real(1.5)),
            DataType::Real64 => Some(Value::Real(-0.1)),
            DataType::VisibleString => Some(Value::Text("hello world".into())),
            DataType::UnicodeString => Some(Value::Text("grüße ✓".into())),
            DataType::OctetString => Some(Value::Bytes(vec![0x01, 0xAB, 0x00])),
            DataType::Domain => Some(Value::Bytes(vec![0xDE, 0xAD])),
            DataType::TimeOfDay | DataType::TimeDifference => Some(Value::int(0)),
            t if t.is_signed() => Some(Value::int(t.int_range().unwrap().0)),
            t => Some(Value::hex(t.int_range().unwrap().1)),
        };
        let mut e = entry(sub, &format!("{} value", ty.name()), ty, Access::Rw, default);
        if ty.is_signed() {
            let (lo, hi) = ty.int_range().unwrap();
            e.extras_mut().low_limit = Some(Value::int(lo));
            e.extras_mut().high_limit = Some(Value::hex(hi));
        }
        if ty == DataType::Unsigned16 {
            e.extras_mut().low_limit = Some(Value::Int { value: 0, radix: Radix::Oct });
            e.extras_mut().high_limit = Some(Value::int(1000));
            e.default = Some(Value::Int { value: 8, radix: Radix::Oct });
        }
        if ty == DataType::Real64 {
            e.extras_mut().low_limit = Some(Value::Real(-10.0));
            e.extras_mut().high_limit = Some(Value::Real(10.25));
        }
        e.pdo_mapping = ty.bits().is_some();
        entries.push(e);
        sub += 1;
    }
    entries[0].default = Some(Value::int(sub as i128 - 1));
    let o = multi(0x2000, "All types", ObjectType::Record, Category::Manufacturer, entries);
    m.objects.insert(o.index, o);
}

/// Keys and sections the model only carries along: ObjFlags, Denotation, DOMAIN files, object
/// links, unknown keys and sections, a DOMAIN object, a negative value, a sub-index above 9.
pub fn odds_and_ends(m: &mut Model) {
    let mut e = entry(0, "Flags and denotation", DataType::Integer16, Access::Rww, Some(Value::int(-300)));
    e.extras_mut().obj_flags = Some(3);
    e.pdo_mapping = true;
    e.extras_mut().denotation = Some("my_flags".into());
    e.extras_mut().extra = vec![("Unit".into(), "mm".into()), ("Factor".into(), "0.01".into())];
    let mut o = var(0x2001, Category::Manufacturer, e);
    o.object_links = vec![Index(0x2000), Index(0x2002)];
    m.objects.insert(o.index, o);

    let mut e = entry(0, "Firmware", DataType::Domain, Access::Wo, None);
    e.extras_mut().upload_file = Some("fw_up.bin".into());
    e.extras_mut().download_file = Some("fw_down.bin".into());
    let mut o = var(0x2002, Category::Manufacturer, e);
    o.object_type = ObjectType::Domain;
    m.objects.insert(o.index, o);

    let mut entries = vec![entry(0, "Number of entries", DataType::Unsigned8, Access::Ro, Some(Value::int(0x1A)))];
    for sub in [1u8, 0x0A, 0x1A] {
        let mut e =
            entry(sub, &format!("Element {sub}"), DataType::Integer32, Access::Rwr, Some(Value::hex(sub as i128)));
        e.pdo_mapping = true;
        entries.push(e);
    }
    let mut o = multi(0x2003, "Sparse array", ObjectType::Array, Category::Manufacturer, entries);
    o.obj_flags = Some(1);
    o.extra = vec![("StorageLocation".into(), "RAM".into())];
    m.objects.insert(o.index, o);

    let o = var(0x6040, Category::Optional, {
        let mut e = entry(0, "Controlword", DataType::Unsigned16, Access::Rww, Some(Value::hex(0)));
        e.pdo_mapping = true;
        e
    });
    m.objects.insert(o.index, o);
    m.objects.insert(Index(0x2100), compact_gains());
    m.extra_sections.push(ExtraSection {
        name: "Tools".into(),
        entries: vec![("Items".into(), "1".into()), ("Item1".into(), "odgen".into())],
    });
}

/// A compact ARRAY (`CompactSubObj=3`) as the reader expands it: sub 0 `NrOfObjects`, subs
/// 1..=3 sharing the object section's keys, sub 2 renamed.
pub fn compact_gains() -> Object {
    let mut sub0 = entry(0, "NrOfObjects", DataType::Unsigned8, Access::Ro, Some(Value::int(3)));
    sub0.pdo_mapping = false;
    let mut entries = vec![sub0];
    for s in 1..=3u8 {
        let name = if s == 2 { "Gain Y".to_owned() } else { format!("Gains{s}") };
        let mut e = entry(s, &name, DataType::Unsigned16, Access::Rw, Some(Value::hex(0x10)));
        e.extras_mut().high_limit = Some(Value::int(1000));
        e.pdo_mapping = true;
        entries.push(e);
    }
    let mut o = multi(0x2100, "Gains", ObjectType::Array, Category::Manufacturer, entries);
    o.compact_sub_obj = Some(3);
    o
}

/// A full EDS model with every feature above.
pub fn full_eds() -> Model {
    let mut m = header();
    mandatory(&mut m);
    pdos(&mut m);
    all_types(&mut m);
    odds_and_ends(&mut m);
    m
}

/// [`full_eds`] configured for node 5 at 500 kbit/s with a few ParameterValues.
pub fn full_dcf() -> Model {
    let mut m = eds::write::configure(
        &full_eds(),
        5,
        Some(500),
        &[
            (0x1400, 1, Value::NodeIdPlus { offset: 0x200, radix: Radix::Hex }),
            (0x1400, 2, Value::int(1)),
            (0x2000, 9, Value::Text("configured".into())),
            (0x2000, 8, Value::Real(2.25)),
            (0x2001, 0, Value::int(-5)),
            (0x6040, 0, Value::hex(0x0F)),
            (0x2100, 3, Value::int(999)),
        ],
    )
    .expect("fixture configuration is valid");
    let c = m.commissioning.as_mut().unwrap();
    c.node_name = Some("axis_x".into());
    c.net_number = Some(1);
    c.network_name = Some("machine".into());
    c.canopen_manager = Some(false);
    c.lss_serial_number = Some(0x1234);
    m.objects.get_mut(&Index(0x2000)).unwrap().subs.get_mut(&SubIndex(1)).unwrap().extras_mut().denotation =
        Some("enable".into());
    m
}
