//! Camozzi DRCS stepper drive: the EDS (`devices/camozzi-drcs.eds`) checked against the
//! manual (`camozzi-drcs-canopen-manual.txt`, its EDS is named "drcs_rev102.eds" there).
//!
//! Every expected value below is quoted from the manual; the comment names the section or
//! table. Where the EDS deliberately differs from the printed table (a reconciliation decision
//! recorded in the EDS `[Comments]`), the comment says so.

use devices::sidecar::{Dimension, ObjRef, Reaction, ScalingKind, Sidecar, Unit};
use eds::{Access, Category, DataType, Index, Model, ObjectType, Options, PdoMappingEntry, Value};

const EDS_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/camozzi-drcs.eds");

fn load_with(options: &Options) -> eds::Parsed {
    eds::read_file(EDS_PATH, options).expect("devices/camozzi-drcs.eds is readable")
}

fn model() -> Model {
    let parsed = load_with(&Options::lenient());
    let errors: Vec<_> = parsed.errors().collect();
    assert!(errors.is_empty(), "errors in camozzi-drcs.eds: {errors:#?}");
    parsed.model
}

/// The integer default of `(index, sub)`, with `$NODEID` resolved for node 0.
fn default_int(m: &Model, index: u16, sub: u8) -> i128 {
    let e = m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing"));
    e.default
        .as_ref()
        .and_then(|v| v.resolve(0))
        .unwrap_or_else(|| panic!("0x{index:04X} sub {sub} has no integer default: {:?}", e.default))
}

fn default_text(m: &Model, index: u16, sub: u8) -> String {
    match &m.entry(index, sub).expect("entry").default {
        Some(Value::Text(s)) => s.clone(),
        other => panic!("0x{index:04X} sub {sub}: expected text default, got {other:?}"),
    }
}

fn dtype(m: &Model, index: u16, sub: u8) -> DataType {
    m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing")).data_type
}

fn access(m: &Model, index: u16, sub: u8) -> Access {
    m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing")).access
}

fn mappable(m: &Model, index: u16, sub: u8) -> bool {
    m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing")).pdo_mapping
}

/// Table 3.1 "CIA301 profile objects": every index it lists.
const TABLE_3_1: &[u16] = &[
    0x1000, 0x1001, 0x1002, 0x1003, 0x1005, 0x1006, 0x1007, 0x1008, 0x1009, 0x100A, 0x100C, 0x100D, 0x1010, 0x1011,
    0x1012, 0x1014, 0x1015, 0x1017, 0x1018, 0x1019, 0x1020, 0x1200, 0x1400, 0x1401, 0x1402, 0x1403, 0x1404, 0x1405,
    0x1406, 0x1407, 0x1600, 0x1601, 0x1602, 0x1603, 0x1604, 0x1605, 0x1606, 0x1607, 0x1800, 0x1801, 0x1802, 0x1803,
    0x1804, 0x1805, 0x1806, 0x1807, 0x1A00, 0x1A01, 0x1A02, 0x1A03, 0x1A04, 0x1A05, 0x1A06, 0x1A07, 0x1F80,
];

/// Table 3.3 "CIA 402 profile objects": every index it lists; the second "6402h" row (Motor
/// manufacturer) is 6404h as CiA 402 defines (decision recorded in the EDS).
const TABLE_3_3: &[u16] = &[
    0x603F, 0x6040, 0x6041, 0x6060, 0x6061, 0x6062, 0x6064, 0x606B, 0x606C, 0x606D, 0x606E, 0x606F, 0x6070, 0x607A,
    0x607C, 0x607D, 0x607E, 0x6081, 0x6083, 0x6084, 0x608F, 0x6091, 0x6092, 0x6098, 0x6099, 0x60FF, 0x6402, 0x6404,
    0x6502, 0x67FF,
];

/// Table 3.5 "Manufacturer custom objects".
const TABLE_3_5: &[u16] = &[0x2001, 0x2002, 0x2003, 0x2004, 0x2005];

/// Objects described only in the text: 3.6.6 to 3.6.9 (counters).
const TEXT_ONLY: &[u16] = &[0x2100, 0x2101, 0x2102, 0x2103];

#[test]
fn every_table_object_is_present() {
    let m = model();
    for &i in TABLE_3_1.iter().chain(TABLE_3_3).chain(TABLE_3_5).chain(TEXT_ONLY) {
        assert!(m.object(i).is_some(), "object 0x{i:04X} from the manual is missing");
    }
    let listed = TABLE_3_1.len() + TABLE_3_3.len() + TABLE_3_5.len() + TEXT_ONLY.len();
    assert_eq!(listed, 94);
    // Nothing beyond the manual.
    assert_eq!(m.objects.len(), listed, "the EDS holds objects the manual does not list");
}

#[test]
fn object_lists_and_categories() {
    let m = model();
    for idx in [0x1000, 0x1001, 0x1018] {
        assert_eq!(m.object(idx).unwrap().category, Category::Mandatory);
    }
    for &idx in TABLE_3_5.iter().chain(TEXT_ONLY) {
        assert_eq!(m.object(idx).unwrap().category, Category::Manufacturer);
    }
    for &idx in TABLE_3_1.iter().chain(TABLE_3_3) {
        if ![0x1000, 0x1001, 0x1018].contains(&idx) {
            assert_eq!(m.object(idx).unwrap().category, Category::Optional, "0x{idx:04X}");
        }
    }
}

#[test]
fn sub_objects_of_every_table_row_are_present() {
    let m = model();
    // (index, highest sub-index) for every multi-entry object of tables 3.1, 3.3 and 3.5.
    let records: &[(u16, u8)] = &[
        (0x1003, 8), // 3.1: eight standard error fields
        (0x1010, 1),
        (0x1011, 1),
        (0x1018, 4),
        (0x1020, 2), // 3.1 sub0 = 2 (sub 2 added per CiA 301)
        (0x1200, 2),
        (0x607D, 2),
        (0x608F, 2),
        (0x6091, 2),
        (0x6092, 2),
        (0x6099, 2),
        (0x2001, 2),
    ];
    for &(idx, top) in records {
        let o = m.object(idx).unwrap();
        assert!(o.object_type.has_subs(), "0x{idx:04X}");
        for s in 0..=top {
            assert!(o.sub(s).is_some(), "0x{idx:04X} sub {s}");
        }
        assert_eq!(o.subs.len(), top as usize + 1, "0x{idx:04X}");
        assert_eq!(o.sub(0).unwrap().data_type, DataType::Unsigned8, "0x{idx:04X} sub 0");
    }
    for n in 0..8u16 {
        // 3.1: RPDO communication subs 0..2, TPDO communication subs 0..5, mappings 0..8.
        assert_eq!(m.object(0x1400 + n).unwrap().subs.len(), 3);
        assert_eq!(m.object(0x1800 + n).unwrap().subs.len(), 6);
        assert_eq!(m.object(0x1600 + n).unwrap().subs.len(), 9);
        assert_eq!(m.object(0x1A00 + n).unwrap().subs.len(), 9);
        assert_eq!(default_int(&m, 0x1400 + n, 0), 2);
        assert_eq!(default_int(&m, 0x1800 + n, 0), 5);
    }
}

#[test]
fn cia301_values_from_table_3_1() {
    let m = model();
    // 3.1 1000h Device Type U32 RO 0xFF7C0192
    assert_eq!(default_int(&m, 0x1000, 0), 0xFF7C0192);
    assert_eq!(dtype(&m, 0x1000, 0), DataType::Unsigned32);
    assert_eq!(access(&m, 0x1000, 0), Access::Ro);
    // 3.1 1001h Error register U8 RO, PDO mapping Yes
    assert_eq!(dtype(&m, 0x1001, 0), DataType::Unsigned8);
    assert!(mappable(&m, 0x1001, 0));
    // 3.1 1002h Manufacturer status register U32 RO, PDO mapping Yes
    assert_eq!(dtype(&m, 0x1002, 0), DataType::Unsigned32);
    assert!(mappable(&m, 0x1002, 0));
    // 3.1 1003h eight "Standard error field" U32 RO
    for s in 1..=8 {
        assert_eq!(dtype(&m, 0x1003, s), DataType::Unsigned32);
        assert_eq!(access(&m, 0x1003, s), Access::Ro);
    }
    // 3.2.4: writing zero into sub 0 clears the history (table says RO: decision -> rw)
    assert_eq!(access(&m, 0x1003, 0), Access::Rw);
    // 3.1 1005h COB_ID sync 0x00000080 RW
    assert_eq!(default_int(&m, 0x1005, 0), 0x80);
    assert_eq!(access(&m, 0x1005, 0), Access::Rw);
    // 3.1 1006h / 1007h default 0
    assert_eq!(default_int(&m, 0x1006, 0), 0);
    assert_eq!(default_int(&m, 0x1007, 0), 0);
    // 3.1 1008h "DRCS", 1009h "1", 100Ah "1.18", all CONST strings
    assert_eq!(default_text(&m, 0x1008, 0), "DRCS");
    assert_eq!(default_text(&m, 0x1009, 0), "1");
    assert_eq!(default_text(&m, 0x100A, 0), "1.18");
    for idx in [0x1008, 0x1009, 0x100A] {
        assert_eq!(dtype(&m, idx, 0), DataType::VisibleString);
        assert_eq!(access(&m, idx, 0), Access::Const);
    }
    // 3.1 100Ch Guard time U16 RW 0 ms; 100Dh Life time factor 0 (U8 per CiA 301, decision)
    assert_eq!(dtype(&m, 0x100C, 0), DataType::Unsigned16);
    assert_eq!(default_int(&m, 0x100C, 0), 0);
    assert_eq!(dtype(&m, 0x100D, 0), DataType::Unsigned8);
    // 3.1 1010h sub 1 "Save all parameters" U32 RW
    assert_eq!(dtype(&m, 0x1010, 1), DataType::Unsigned32);
    assert_eq!(access(&m, 0x1010, 1), Access::Rw);
    // 3.1 1012h COB-ID time stamp 0x80000100
    assert_eq!(default_int(&m, 0x1012, 0), 0x8000_0100);
    // 3.1 1014h COB_ID emcy 0x00000080 (node 0) -> $NODEID+0x80, RO
    let emcy = m.entry(0x1014, 0).unwrap();
    assert!(emcy.default.as_ref().unwrap().is_node_relative());
    assert_eq!(emcy.default.as_ref().unwrap().resolve(3), Some(0x83));
    assert_eq!(emcy.access, Access::Ro);
    // 3.1 1015h Inhibit time emergency U16 0; 1017h Producer heartbeat time U16 0 ms
    assert_eq!(dtype(&m, 0x1015, 0), DataType::Unsigned16);
    assert_eq!(dtype(&m, 0x1017, 0), DataType::Unsigned16);
    assert_eq!(default_int(&m, 0x1017, 0), 0);
    // 3.1 / 3.2.18 1018h: 4 entries, vendor 0x151, product 0x5A, revision 1, serial 0
    assert_eq!(default_int(&m, 0x1018, 0), 4);
    assert_eq!(default_int(&m, 0x1018, 1), 0x151);
    assert_eq!(dtype(&m, 0x1018, 1), DataType::Unsigned32); // table says U8: CiA 301 decision
    assert_eq!(default_int(&m, 0x1018, 2), 0x5A);
    assert_eq!(default_int(&m, 0x1018, 3), 1);
    assert_eq!(default_int(&m, 0x1018, 4), 0);
    // 3.1 1019h Synchronous counter overflow value U8 RW 0; 3.2.19 range up to 240
    assert_eq!(dtype(&m, 0x1019, 0), DataType::Unsigned8);
    assert_eq!(default_int(&m, 0x1019, 0), 0);
    assert_eq!(m.entry(0x1019, 0).unwrap().high_limit().and_then(Value::as_int), Some(240));
    // 3.1 1020h Highest sub-index supported 2
    assert_eq!(default_int(&m, 0x1020, 0), 2);
    // 3.1 1200h SDO COB-IDs 0x600 / 0x580 relative to the node id
    assert_eq!(m.entry(0x1200, 1).unwrap().default.as_ref().unwrap().resolve(3), Some(0x603));
    assert_eq!(m.entry(0x1200, 2).unwrap().default.as_ref().unwrap().resolve(3), Some(0x583));
    // 3.1 1F80h NMT startup 0x00000004
    assert_eq!(default_int(&m, 0x1F80, 0), 4);
}

#[test]
fn pdo_defaults_from_table_3_1() {
    let m = model();
    let rpdo: [i128; 8] =
        [0x200, 0x8000_0300, 0x8000_0400, 0x8000_0500, 0x8000_0000, 0x8000_0000, 0x8000_0000, 0x8000_0000];
    let tpdo: [i128; 8] =
        [0x180, 0x8000_0280, 0x8000_0380, 0x8000_0480, 0x8000_0000, 0x8000_0000, 0x8000_0000, 0x8000_0000];
    for n in 0..8u16 {
        // 3.1: COB-IDs printed for node 0
        assert_eq!(default_int(&m, 0x1400 + n, 1), rpdo[n as usize], "RPDO{}", n + 1);
        assert_eq!(default_int(&m, 0x1800 + n, 1), tpdo[n as usize], "TPDO{}", n + 1);
        // the first four are relative to the node id
        let rel = m.entry(0x1400 + n, 1).unwrap().default.as_ref().unwrap().is_node_relative();
        assert_eq!(rel, n < 4);
        // 3.1: transmission type 0xFF
        assert_eq!(default_int(&m, 0x1400 + n, 2), 0xFF);
        assert_eq!(default_int(&m, 0x1800 + n, 2), 0xFF);
        // 3.1: TPDO inhibit time 0, compatibility entry 0, event timer 0
        assert_eq!(default_int(&m, 0x1800 + n, 3), 0);
        assert_eq!(dtype(&m, 0x1800 + n, 3), DataType::Unsigned16);
        assert_eq!(default_int(&m, 0x1800 + n, 4), 0);
        assert_eq!(default_int(&m, 0x1800 + n, 5), 0);
        assert_eq!(dtype(&m, 0x1800 + n, 5), DataType::Unsigned16);
    }
    // RPDO1 for node 3 is 0x203 (chapter 8 drive at address 3)
    assert_eq!(m.entry(0x1400, 1).unwrap().default.as_ref().unwrap().resolve(3), Some(0x203));
    // 3.1 1600h: 1 mapped object, entry 1 = 0x60400010 (controlword)
    assert_eq!(default_int(&m, 0x1600, 0), 1);
    assert_eq!(default_int(&m, 0x1600, 1), 0x6040_0010);
    // 3.1 1A00h: 1 mapped object, entry 1 = 0x60410010 (statusword)
    assert_eq!(default_int(&m, 0x1A00, 0), 1);
    assert_eq!(default_int(&m, 0x1A00, 1), 0x6041_0010);
    for n in 1..8u16 {
        assert_eq!(default_int(&m, 0x1600 + n, 0), 0);
        assert_eq!(default_int(&m, 0x1A00 + n, 0), 0);
    }
}

#[test]
fn default_pdo_mappings_are_consistent() {
    let m = model();
    for (map, rx) in (0..8u16).map(|n| (0x1600 + n, true)).chain((0..8u16).map(|n| (0x1A00 + n, false))) {
        let count = default_int(&m, map, 0) as u8;
        let mut bits = 0u32;
        for s in 1..=count {
            let e = PdoMappingEntry::from_u32(default_int(&m, map, s) as u32);
            let target = m.entry(e.index.0, e.sub.0).expect("mapped object exists");
            assert!(target.pdo_mapping, "0x{map:04X} maps a non-mappable object");
            assert_eq!(Some(e.bits as u32), target.data_type.bits());
            assert!(if rx { target.access.rpdo_ok() } else { target.access.tpdo_ok() });
            bits += e.bits as u32;
        }
        assert!(bits <= 64);
    }
}

#[test]
fn cia402_values_from_table_3_3() {
    let m = model();
    // 3.3: types, access and PDO mapping of the process objects
    let rows: &[(u16, DataType, bool)] = &[
        (0x603F, DataType::Unsigned16, true),
        (0x6040, DataType::Unsigned16, true),
        (0x6041, DataType::Unsigned16, true),
        (0x6060, DataType::Integer8, true),
        (0x6061, DataType::Integer8, true),
        (0x6062, DataType::Integer32, false),
        (0x6064, DataType::Integer32, true),
        (0x606B, DataType::Integer32, false),
        (0x606C, DataType::Integer32, true),
        (0x606D, DataType::Unsigned16, false),
        (0x606E, DataType::Unsigned16, false),
        (0x606F, DataType::Unsigned16, false),
        (0x6070, DataType::Unsigned16, false),
        (0x607A, DataType::Integer32, true),
        (0x607C, DataType::Integer32, true),
        (0x607E, DataType::Unsigned8, true),
        (0x6081, DataType::Unsigned32, true),
        (0x6083, DataType::Unsigned32, true),
        (0x6084, DataType::Unsigned32, true),
        (0x60FF, DataType::Integer32, true),
        (0x6402, DataType::Unsigned16, false),
        (0x6502, DataType::Unsigned32, false),
        (0x67FF, DataType::Unsigned32, false),
    ];
    for &(idx, t, pdo) in rows {
        assert_eq!(dtype(&m, idx, 0), t, "0x{idx:04X}");
        assert_eq!(mappable(&m, idx, 0), pdo, "0x{idx:04X}");
    }
    for idx in [0x603F, 0x6041, 0x6061, 0x6062, 0x6064, 0x606B, 0x606C, 0x6402, 0x6404, 0x6502, 0x67FF] {
        assert_eq!(access(&m, idx, 0), Access::Ro, "0x{idx:04X}");
    }
    for idx in [0x6060, 0x606D, 0x606E, 0x606F, 0x6070, 0x607A, 0x607C, 0x607E, 0x6081, 0x6083, 0x6084, 0x6098, 0x60FF]
    {
        assert_eq!(access(&m, idx, 0), Access::Rw, "0x{idx:04X}");
    }
    // 3.3: 6040h is WO in the table; CiA 402 rw (decision) - it must at least be writable
    assert!(access(&m, 0x6040, 0).writable());
    // 3.3: 6060h / 6061h default 0
    assert_eq!(default_int(&m, 0x6060, 0), 0);
    assert_eq!(default_int(&m, 0x6061, 0), 0);
    // 3.3: 607Dh software limits S32, set by QSet (read-only)
    assert_eq!(dtype(&m, 0x607D, 1), DataType::Integer32);
    assert_eq!(dtype(&m, 0x607D, 2), DataType::Integer32);
    assert_eq!(access(&m, 0x607D, 1), Access::Ro);
    assert_eq!(access(&m, 0x607D, 0), Access::Const);
    // 3.3 / 3.4.19 608Fh: Encoder increments 1000, Motor revolutions 1
    assert_eq!(default_int(&m, 0x608F, 0), 2);
    assert_eq!(default_int(&m, 0x608F, 1), 1000);
    assert_eq!(default_int(&m, 0x608F, 2), 1);
    // 3.3 6091h / 6092h: two U32 RO parameters each
    for idx in [0x6091, 0x6092] {
        assert_eq!(default_int(&m, idx, 0), 2);
        for s in 1..=2 {
            assert_eq!(dtype(&m, idx, s), DataType::Unsigned32);
            assert_eq!(access(&m, idx, s), Access::Ro);
        }
    }
    // 3.3 6098h Homing method default 17 (INTEGER8 per CiA 402, decision)
    assert_eq!(default_int(&m, 0x6098, 0), 17);
    assert!(mappable(&m, 0x6098, 0));
    // 3.3 6099h: fast and slow homing speed, U32 RW, mappable, default 0
    for s in 1..=2 {
        assert_eq!(dtype(&m, 0x6099, s), DataType::Unsigned32);
        assert_eq!(access(&m, 0x6099, s), Access::Rw);
        assert!(mappable(&m, 0x6099, s));
        assert_eq!(default_int(&m, 0x6099, s), 0);
    }
    // 3.3 / 3.4.25 6402h Motor type 0x09 (microstep stepper)
    assert_eq!(default_int(&m, 0x6402, 0), 9);
    // 3.3 second "6402h" row: Motor manufacturer "Camozzi" -> 6404h
    assert_eq!(default_text(&m, 0x6404, 0), "Camozzi");
    assert_eq!(dtype(&m, 0x6404, 0), DataType::VisibleString);
    // 3.3 / 3.4.26 6502h 0x25: profile position (bit 0), profile velocity (bit 2), homing (bit 5)
    assert_eq!(default_int(&m, 0x6502, 0), 0x25);
    assert_eq!(default_int(&m, 0x6502, 0), (1 << 0) | (1 << 2) | (1 << 5));
    // 3.3 67FFh Single device type 0x00440192
    assert_eq!(default_int(&m, 0x67FF, 0), 0x0044_0192);
    // 3.2.1 / 1000h and 67FFh: profile 402 in the low word
    assert_eq!(default_int(&m, 0x1000, 0) & 0xFFFF, 402);
    assert_eq!(default_int(&m, 0x67FF, 0) & 0xFFFF, 402);
    // 3.4.15 607Eh Polarity default 0 (forwards)
    assert_eq!(default_int(&m, 0x607E, 0), 0);
}

#[test]
fn manufacturer_values_from_table_3_5_and_text() {
    let m = model();
    // 3.5 2001h Feed converter: Numerator, Denominator U32 RW, not mappable
    assert_eq!(m.object(0x2001).unwrap().name, "Feed converter");
    assert_eq!(m.entry(0x2001, 1).unwrap().name, "Numerator");
    assert_eq!(m.entry(0x2001, 2).unwrap().name, "Denominator");
    for s in 1..=2 {
        assert_eq!(dtype(&m, 0x2001, s), DataType::Unsigned32);
        assert_eq!(access(&m, 0x2001, s), Access::Rw);
        assert!(!mappable(&m, 0x2001, s));
    }
    // 3.5 2002h Input status U32 RO Yes; 2003h Output status U32 RO Yes
    for idx in [0x2002, 0x2003] {
        assert_eq!(dtype(&m, idx, 0), DataType::Unsigned32);
        assert_eq!(access(&m, idx, 0), Access::Ro);
        assert!(mappable(&m, idx, 0));
    }
    // 3.5 2004h Homing status U8 RO Yes
    assert_eq!(dtype(&m, 0x2004, 0), DataType::Unsigned8);
    assert_eq!(access(&m, 0x2004, 0), Access::Ro);
    // 3.5 2005h Brake U8 RW Yes (R)
    assert_eq!(dtype(&m, 0x2005, 0), DataType::Unsigned8);
    assert_eq!(access(&m, 0x2005, 0), Access::Rw);
    assert!(mappable(&m, 0x2005, 0));
    // 3.6.6 - 3.6.9: read-only counters
    for idx in TEXT_ONLY {
        assert_eq!(access(&m, *idx, 0), Access::Ro);
        assert_eq!(m.object(*idx).unwrap().object_type, ObjectType::Var);
    }
    assert_eq!(m.object(0x2103).unwrap().name, "Total stroke");
}

#[test]
fn device_info_from_chapter_2() {
    let m = model();
    let d = &m.device_info;
    // chapter 2: 10, 20, 50, 125, 250, 500, 800 kbit/s and 1 Mbit/s
    for rate in [10u16, 20, 50, 125, 250, 500, 800, 1000] {
        assert_eq!(d.baud_rates.get(&rate), Some(&true), "{rate} kbit/s");
    }
    // 3.1: eight RPDOs and eight TPDOs
    assert_eq!(d.nr_of_rx_pdo, Some(8));
    assert_eq!(d.nr_of_tx_pdo, Some(8));
    assert_eq!(d.simple_boot_up_slave, Some(true));
    assert_eq!(d.vendor_number, Some(0x151));
    assert_eq!(d.product_number, Some(0x5A));
    assert_eq!(d.revision_number, Some(1));
    assert_eq!(d.lss_supported, Some(false));
    assert_eq!(d.granularity, Some(8));
    // chapter 3: the manual calls the file drcs_rev102.eds
    assert!(m.file_info.description.as_deref().unwrap_or("").contains("drcs_rev102.eds"));
    assert!(!m.comments.is_empty());
}

/// Chapter 8 frame listings (drive at node 3): each SDO download's command specifier must match
/// the size of the object's data type (0x2F = 1 byte, 0x2B = 2 bytes, 0x23 = 4 bytes), and the
/// objects must be writable. The full request/response exchange is the drive's acceptance test.
#[test]
fn chapter_8_sdo_downloads_fit_the_dictionary() {
    let m = model();
    let frames: &[[u8; 8]] = &[
        [0x2B, 0x40, 0x60, 0x00, 0x06, 0x00, 0x00, 0x00], // ready to switch on
        [0x2B, 0x40, 0x60, 0x00, 0x07, 0x00, 0x00, 0x00], // switched on
        [0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0x00, 0x00], // operation enabled
        [0x2F, 0x60, 0x60, 0x00, 0x06, 0x00, 0x00, 0x00], // set homing mode
        [0x2F, 0x98, 0x60, 0x00, 0x11, 0x00, 0x00, 0x00], // homing method 17
        [0x23, 0x83, 0x60, 0x00, 0x64, 0x00, 0x00, 0x00], // acceleration 100 mm/s^2
        [0x23, 0x84, 0x60, 0x00, 0x64, 0x00, 0x00, 0x00], // deceleration 100 mm/s^2
        [0x23, 0x99, 0x60, 0x01, 0x32, 0x00, 0x00, 0x00], // fast homing speed 50 mm/s
        [0x23, 0x99, 0x60, 0x02, 0x32, 0x00, 0x00, 0x00], // slow homing speed 50 mm/s
        [0x2B, 0x40, 0x60, 0x00, 0x1F, 0x00, 0x00, 0x00], // start homing
        [0x2F, 0x60, 0x60, 0x00, 0x01, 0x00, 0x00, 0x00], // profile position mode
        [0x23, 0x81, 0x60, 0x00, 0x32, 0x00, 0x00, 0x00], // profile velocity 50 mm/s
        [0x23, 0x7A, 0x60, 0x00, 0x2C, 0x01, 0x00, 0x00], // target 300 mm
        [0x2B, 0x40, 0x60, 0x00, 0x5F, 0x00, 0x00, 0x00], // relative start
        [0x2B, 0x40, 0x60, 0x00, 0x0F, 0x01, 0x00, 0x00], // motion halted
        [0x2F, 0x60, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00], // profile velocity mode
        [0x23, 0xFF, 0x60, 0x00, 0x32, 0x00, 0x00, 0x00], // target velocity 50 mm/s
        [0x23, 0xFF, 0x60, 0x00, 0x64, 0x00, 0x00, 0x00], // target velocity 100 mm/s
    ];
    for f in frames {
        let index = u16::from_le_bytes([f[1], f[2]]);
        let e = m.entry(index, f[3]).unwrap_or_else(|| panic!("chapter 8 writes 0x{index:04X} sub {}", f[3]));
        let bytes = 4 - ((f[0] >> 2) & 0x3) as u32;
        assert_eq!(f[0] & 0xE3, 0x23, "expedited download with size indicated");
        assert_eq!(e.data_type.bits(), Some(bytes * 8), "0x{index:04X} sub {}", f[3]);
        assert!(e.access.writable(), "0x{index:04X}");
        let raw = u32::from_le_bytes([f[4], f[5], f[6], f[7]]) as i128;
        let (lo, hi) = e.data_type.int_range().unwrap();
        assert!((lo..=hi).contains(&raw));
    }
    // "set target to 300mm": 0x012C
    assert_eq!(u32::from_le_bytes([0x2C, 0x01, 0x00, 0x00]), 300);
}

#[test]
fn loads_without_errors_in_strict_mode() {
    let parsed = load_with(&Options::strict());
    let errors: Vec<_> = parsed.errors().collect();
    assert!(errors.is_empty(), "strict errors: {errors:#?}");
}

#[test]
fn index_is_ordered_and_names_are_english() {
    let m = model();
    let idx: Vec<Index> = m.objects.keys().copied().collect();
    let mut sorted = idx.clone();
    sorted.sort();
    assert_eq!(idx, sorted);
    for (o, e) in m.entries() {
        assert!(!e.name.is_empty() && e.name.is_ascii(), "0x{:04X} sub {}", o.index.0, e.sub.0);
    }
}

// ---------------------------------------------------------------------------------------------
// The sidecar (devices/camozzi-drcs.toml)
// ---------------------------------------------------------------------------------------------

fn sidecar() -> Sidecar {
    Sidecar::read(&devices::sidecar_path("camozzi-drcs")).unwrap_or_else(|e| panic!("{e}"))
}

/// `value_new = value_default * numerator / denominator` (3.6.1, chapter 4), the formula the
/// sidecar records for 2001h.
fn feed_convert(value_default: f64, numerator: u32, denominator: u32) -> f64 {
    value_default * numerator as f64 / denominator as f64
}

#[test]
fn sidecar_loads_and_refers_only_to_existing_entries() {
    let s = sidecar();
    let m = model();
    assert_eq!(s.device.name, "camozzi-drcs");
    assert_eq!(s.device.eds, "camozzi-drcs.eds");
    for (r, what) in s.references() {
        let o = m.object(r.index).unwrap_or_else(|| panic!("{what} refers to missing {r}"));
        if let Some(sub) = r.sub {
            assert!(o.sub(sub).is_some(), "{what} refers to missing {r}");
        }
    }
}

#[test]
fn sidecar_units_chapter_4() {
    let s = sidecar();
    // chapter 4: position [mm], velocity [mm/s], acceleration [mm/s^2] with an axis / cylinder
    let u = s.active_unit_system(|_| None).expect("default unit system");
    assert_eq!(u.units[&Dimension::Position].unit, Unit::Millimeter);
    assert_eq!(u.units[&Dimension::Velocity].unit, Unit::MillimeterPerSecond);
    assert_eq!(u.units[&Dimension::Acceleration].unit, Unit::MillimeterPerSecond2);
    for d in [Dimension::Position, Dimension::Velocity, Dimension::Acceleration] {
        // not x100 (unlike the DRVI)
        assert_eq!(u.units[&d].scale, devices::sidecar::Ratio::ONE);
        // 2001h sets the bus unit; 6092h (mm per pulley turn, 3.4.21) and 6091h (3.4.20) relate
        // the millimetres to motor turns.
        assert_eq!(
            u.units[&d].scaled_by,
            vec![ScalingKind::FeedConverter, ScalingKind::FeedConstant, ScalingKind::GearRatio]
        );
    }
    // table 3.3: 606Eh / 6070h in ms
    assert_eq!(u.units[&Dimension::Time].unit, Unit::Millisecond);
    // dimensions of the motion objects (table 3.3 units column)
    for idx in [0x6062, 0x6064, 0x607A, 0x607C] {
        assert_eq!(s.dimension_of(idx, 0), Some(Dimension::Position), "0x{idx:04X}");
    }
    assert_eq!(s.dimension_of(0x607D, 1), Some(Dimension::Position));
    assert_eq!(s.dimension_of(0x607D, 2), Some(Dimension::Position));
    for idx in [0x606B, 0x606C, 0x606D, 0x606F, 0x6081, 0x60FF] {
        assert_eq!(s.dimension_of(idx, 0), Some(Dimension::Velocity), "0x{idx:04X}");
    }
    assert_eq!(s.dimension_of(0x6099, 1), Some(Dimension::Velocity));
    assert_eq!(s.dimension_of(0x6099, 2), Some(Dimension::Velocity));
    assert_eq!(s.dimension_of(0x6083, 0), Some(Dimension::Acceleration));
    assert_eq!(s.dimension_of(0x6084, 0), Some(Dimension::Acceleration));
    assert_eq!(s.dimension_of(0x606E, 0), Some(Dimension::Time));
    assert_eq!(s.dimension_of(0x6070, 0), Some(Dimension::Time));
}

#[test]
fn feed_converter_examples_chapter_4() {
    let s = sidecar();
    let fc = s.scaling_object(ScalingKind::FeedConverter).expect("2001h");
    assert_eq!(fc.object, ObjRef { index: 0x2001, sub: None });
    assert_eq!(fc.subs["numerator"], 1);
    assert_eq!(fc.subs["denominator"], 2);
    assert!(fc.formula.contains("numerator / denominator"));
    // chapter 4 microstep example: 888 / 100 -> 360 deg = 3196.8 microsteps (consistent)
    assert!((feed_convert(360.0, 888, 100) - 3196.8).abs() < 1e-9);
    // ... which the manual rounds to "3200 microsteps per revolution" (exact ratio 80/9)
    assert!((feed_convert(360.0, 80, 9) - 3200.0).abs() < 1e-9);
    // chapter 4 inch example as printed: 100 / 254 turns 25.4 mm into 10 "inches": off by ten
    assert!((feed_convert(25.4, 100, 254) - 10.0).abs() < 1e-9);
    // the formula needs 10 / 254 for inches: 25.4 mm -> 1 in, 1 mm -> 0.03937 in
    assert!((feed_convert(25.4, 10, 254) - 1.0).abs() < 1e-9);
    assert!((feed_convert(1.0, 10, 254) - 0.03937).abs() < 1e-5);
    // the discrepancy is recorded
    assert!(s.decisions.iter().any(|d| d.object == Some(fc.object) && d.text.contains("off by ten")));
    // defaults 1/1 leave the units unchanged (decision)
    let m = model();
    assert_eq!(default_int(&m, 0x2001, 1), 1);
    assert_eq!(default_int(&m, 0x2001, 2), 1);
    // 3.4.20 / 3.4.21 ratios
    assert_eq!(s.scaling_object(ScalingKind::GearRatio).unwrap().object.index, 0x6091);
    assert_eq!(s.scaling_object(ScalingKind::FeedConstant).unwrap().object.index, 0x6092);
}

#[test]
fn modes_and_homing_chapters_5_to_7() {
    let s = sidecar();
    // 3.4.4 / chapters 5-7: 1 profile position, 3 velocity profile, 6 homing
    let codes: Vec<i8> = s.modes.iter().map(|m| m.code).collect();
    assert_eq!(codes, vec![1, 3, 6]);
    // 6502h = 0x25 says the same: bit 0 pp, bit 2 pv, bit 5 homing
    let m = model();
    let supported = default_int(&m, 0x6502, 0);
    let bit_of = |code: i8| match code {
        1 => 0,
        3 => 2,
        6 => 5,
        _ => unreachable!(),
    };
    for c in &codes {
        assert_ne!(supported & (1 << bit_of(*c)), 0);
    }
    // chapter 7: methods 17 (negative), 18 (positive), 37 (no proximity)
    let h: Vec<i8> = s.homing_methods.iter().map(|h| h.code).collect();
    assert_eq!(h, vec![17, 18, 37]);
    assert!(s.homing_methods[0].description.contains("negative"));
    assert!(s.homing_methods[1].description.contains("positive"));
    // chapter 7 statusword table in the homing mode note: 011 = completed successfully
    let homing = s.modes.iter().find(|m| m.code == 6).unwrap();
    assert!(homing.note.as_deref().unwrap().contains("011 completed successfully"));
}

#[test]
fn error_list_section_3_2_4() {
    let s = sidecar();
    let expected: &[(i64, &str)] = &[
        (0x2310, "Overcurrent error"),
        (0x3120, "Power voltage absent/too low error"),
        (0x4210, "Temperature too high error"),
        (0x7305, "Position, step loss (if external encoder present) error"),
        (0x8613, "Homing procedure timeout error"),
        (0x6320, "Motor configuration error"),
        (0x7320, "Positioning out of software limits error"),
        (0xFF13, "Operation without reset"),
        (0x5530, "Flash data lost"),
        // Not in the 3.2.4 list: life guarding lost (3.2.12), CiA 301's code (sidecar decision).
        (0x8130, "Fieldbus disconnection: life guarding lost"),
    ];
    assert_eq!(s.errors.len(), expected.len());
    for (e, (code, text)) in s.errors.iter().zip(expected) {
        assert_eq!(e.code.0, *code);
        assert_eq!(e.text, *text);
        // every error sets the generic bit of 1001h (3.2.2: bit 0 mandatory)
        assert_eq!(e.register.unwrap().0 & 1, 1);
    }
    assert_eq!(s.errors[0].reaction, Reaction::PowerOff);
}

#[test]
fn store_list_section_3_2_13() {
    let s = sidecar();
    let stored: Vec<u16> = s.store.objects.iter().map(|r| r.index).collect();
    let mut expected = vec![0x1005, 0x1006, 0x1007, 0x100C, 0x100D, 0x1012, 0x1015, 0x1017, 0x1019, 0x1020];
    for base in [0x1400u16, 0x1600, 0x1800, 0x1A00] {
        expected.extend(base..base + 8);
    }
    expected.extend([
        0x1F80, 0x2001, 0x606D, 0x606E, 0x606F, 0x6070, 0x607C, 0x607E, 0x6081, 0x6083, 0x6084, 0x6098, 0x6099, 0x60FF,
    ]);
    assert_eq!(stored, expected);
    // every stored object is writable somewhere (a stored read-only object would make no sense)
    let m = model();
    for idx in &stored {
        let o = m.object(*idx).unwrap();
        assert!(o.subs.values().any(|e| e.access.writable()), "0x{idx:04X}");
    }
    // 3.2.13: "save" signature, 's' in the LSB
    assert_eq!(u32::from_le_bytes(*b"save"), 0x6576_6173);
}

#[test]
fn every_eds_comment_is_a_sidecar_decision_topic() {
    let s = sidecar();
    let m = model();
    // the EDS [Comments] and the sidecar both carry the decisions
    assert!(m.comments.len() >= 30);
    assert!(s.decisions.len() >= m.comments.len());
    for needle in ["6404h", "INTEGER8", "UNSIGNED8", "697Ah", "6984h", "Yes (R)", "bits 12-31"] {
        assert!(m.comments.iter().any(|c| c.contains(needle)), "EDS comments lack {needle}");
    }
}
