//! The Camozzi DRVI device file (`devices/camozzi-drvi.eds`) checked against the DRVI CANopen
//! manual V1.7 (`/work/shared/manuals/camozzi-drvi-canopen-manual.txt`). Every expected value
//! names the manual section or table it was taken from.

use std::sync::OnceLock;

use eds::{Access, DataType, Entry, Model, ObjectType, PdoMappingEntry, Value};

const EDS_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/camozzi-drvi.eds");

fn model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| {
        let parsed = eds::read_file(EDS_PATH, &eds::Options::lenient()).expect("read camozzi-drvi.eds");
        parsed.model
    })
}

fn entry(index: u16, sub: u8) -> &'static Entry {
    model().entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing"))
}

/// The default as an integer (`$NODEID` resolved for node 0, i.e. the value the manual prints).
fn default_int(index: u16, sub: u8) -> i128 {
    let e = entry(index, sub);
    let v = e.default.as_ref().unwrap_or_else(|| panic!("0x{index:04X} sub {sub} has no default"));
    v.resolve(0).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} default is not an integer: {v:?}"))
}

fn default_text(index: u16, sub: u8) -> String {
    match entry(index, sub).default.as_ref() {
        Some(Value::Text(s)) => s.clone(),
        other => panic!("0x{index:04X} sub {sub}: expected a text default, got {other:?}"),
    }
}

fn limits(index: u16, sub: u8) -> (i128, i128) {
    let e = entry(index, sub);
    let lo = e.low_limit().and_then(Value::as_int).expect("LowLimit");
    let hi = e.high_limit().and_then(Value::as_int).expect("HighLimit");
    (lo, hi)
}

fn assert_type(index: u16, sub: u8, data_type: DataType, access: Access, pdo: bool) {
    let e = entry(index, sub);
    assert_eq!(e.data_type, data_type, "0x{index:04X} sub {sub} data type");
    assert_eq!(e.access, access, "0x{index:04X} sub {sub} access");
    assert_eq!(e.pdo_mapping, pdo, "0x{index:04X} sub {sub} PDO mapping");
}

// ---------------------------------------------------------------------------------------------
// Loading
// ---------------------------------------------------------------------------------------------

#[test]
fn loads_without_errors_in_strict_mode() {
    let parsed = eds::read_file(EDS_PATH, &eds::Options::strict()).expect("read camozzi-drvi.eds");
    let errors: Vec<String> =
        parsed.errors().map(|d| format!("{}: {} {:?} {:?}", d.code.0, d.message, d.at, d.context)).collect();
    assert!(errors.is_empty(), "strict mode errors:\n{}", errors.join("\n"));
}

#[test]
fn loads_without_warnings_in_lenient_mode() {
    let parsed = eds::read_file(EDS_PATH, &eds::Options::lenient()).expect("read camozzi-drvi.eds");
    let warnings: Vec<String> = parsed
        .diagnostics
        .iter()
        .filter(|d| d.severity >= eds::Severity::Warning)
        .map(|d| format!("{}: {} {:?} {:?}", d.code.0, d.message, d.at, d.context))
        .collect();
    assert!(warnings.is_empty(), "warnings:\n{}", warnings.join("\n"));
}

#[test]
fn object_and_sub_object_counts() {
    let m = model();
    assert_eq!(m.objects.len(), 93);
    let entries = m.entries().count();
    // 50 VAR objects (one entry each) + 43 ARRAY/RECORD objects with 258 sub-objects in all.
    let vars = m.objects.values().filter(|o| o.object_type == ObjectType::Var).count();
    assert_eq!(vars, 50);
    assert_eq!(entries, 50 + 258);
}

// ---------------------------------------------------------------------------------------------
// Every object of every manual table is present
// ---------------------------------------------------------------------------------------------

/// Table 6.3 (CiA 301 objects).
const TABLE_6_3: &[u16] = &[
    0x1000, 0x1001, 0x1002, 0x1003, 0x1005, 0x1006, 0x1007, 0x1008, 0x1009, 0x100A, 0x100C, 0x100D, 0x1010, 0x1014,
    0x1015, 0x1017, 0x1018, 0x1400, 0x1401, 0x1402, 0x1403, 0x1404, 0x1405, 0x1406, 0x1407, 0x1600, 0x1601, 0x1602,
    0x1603, 0x1604, 0x1605, 0x1606, 0x1607, 0x1800, 0x1801, 0x1802, 0x1803, 0x1804, 0x1805, 0x1806, 0x1807, 0x1A00,
    0x1A01, 0x1A02, 0x1A03, 0x1A04, 0x1A05, 0x1A06, 0x1A07, 0x1F80,
];

/// Table 6.14 (CiA 402 objects).
const TABLE_6_14: &[u16] = &[
    0x603F, 0x6040, 0x6041, 0x6060, 0x6061, 0x6062, 0x6064, 0x6065, 0x6066, 0x606B, 0x606C, 0x606F, 0x6070, 0x6071,
    0x6074, 0x6077, 0x607A, 0x607C, 0x607D, 0x607E, 0x607F, 0x6081, 0x6083, 0x6084, 0x6087, 0x6091, 0x6098, 0x6099,
    0x609A, 0x60FF,
];

/// Table 6.19 (manufacturer objects), rebuilt from 6.3.6.
const TABLE_6_19: &[u16] = &[0x2001, 0x2002, 0x2003, 0x2004, 0x2006, 0x2010, 0x2011, 0x2012, 0x2013, 0x2014, 0x2015];

/// Objects described only in the text: 1011h (6.3.2.14), 6092h (6.3.4.23).
const TEXT_ONLY: &[u16] = &[0x1011, 0x6092];

/// Table 6.22 (profile position objects).
const TABLE_6_22: &[u16] = &[0x6060, 0x607A, 0x6081, 0x6083, 0x6084];
/// Table 6.23 (profile velocity objects).
const TABLE_6_23: &[u16] = &[0x60FF, 0x6083, 0x6084, 0x606F, 0x6070];
/// Table 6.28 (homing objects; 609901h / 609902h are sub-indices).
const TABLE_6_28: &[(u16, u8)] =
    &[(0x6060, 0), (0x6099, 1), (0x6099, 2), (0x6098, 0), (0x609A, 0), (0x607C, 0), (0x6071, 0), (0x2013, 0)];
/// Table 6.32 (jog mode objects).
const TABLE_6_32: &[u16] = &[0x6060, 0x60FF, 0x6083, 0x6084];
/// Table 6.35 (error dictionary objects).
const TABLE_6_35: &[u16] = &[0x603F, 0x1003];
/// Table 6.41 (node guarding objects) and 6.10.2.2 (heartbeat).
const TABLE_6_41: &[u16] = &[0x100C, 0x100D, 0x1017];

#[test]
fn every_manual_table_object_is_present() {
    let m = model();
    let mut missing = Vec::new();
    for (table, list) in [
        ("6.3", TABLE_6_3),
        ("6.14", TABLE_6_14),
        ("6.19", TABLE_6_19),
        ("text", TEXT_ONLY),
        ("6.22", TABLE_6_22),
        ("6.23", TABLE_6_23),
        ("6.32", TABLE_6_32),
        ("6.35", TABLE_6_35),
        ("6.41", TABLE_6_41),
    ] {
        for &index in list {
            if m.object(index).is_none() {
                missing.push(format!("table {table}: 0x{index:04X}"));
            }
        }
    }
    for &(index, sub) in TABLE_6_28 {
        if m.entry(index, sub).is_none() {
            missing.push(format!("table 6.28: 0x{index:04X} sub {sub}"));
        }
    }
    assert!(missing.is_empty(), "missing: {missing:?}");
    assert_eq!(TABLE_6_3.len() + TABLE_6_14.len() + TABLE_6_19.len() + TEXT_ONLY.len(), 93);
    // Nothing beyond what the manual lists.
    let listed: std::collections::BTreeSet<u16> =
        TABLE_6_3.iter().chain(TABLE_6_14).chain(TABLE_6_19).chain(TEXT_ONLY).copied().collect();
    let extra: Vec<_> = m.objects.keys().filter(|i| !listed.contains(&i.0)).collect();
    assert!(extra.is_empty(), "objects not in the manual: {extra:?}");
}

#[test]
fn sub_object_layout_of_complex_objects() {
    // (index, object type, highest sub-index) from tables 6.3, 6.14 and sections 6.3.2 / 6.3.4 / 6.3.6.
    let expected: &[(u16, ObjectType, u8)] = &[
        (0x1003, ObjectType::Array, 8),  // T6.3: standard error fields 1..8
        (0x1010, ObjectType::Array, 1),  // T6.3: save all parameters
        (0x1011, ObjectType::Array, 1),  // 6.3.2.14
        (0x1018, ObjectType::Record, 4), // T6.3 / T6.8
        (0x607D, ObjectType::Array, 2),  // T6.14: min / max software position limit
        (0x6091, ObjectType::Array, 2),  // T6.14: MotorRevs / ShaftRevs
        (0x6092, ObjectType::Array, 2),  // 6.3.4.23: Feed / shaft revolutions
        (0x6099, ObjectType::Array, 2),  // T6.14: fast / slow homing speed
        (0x2001, ObjectType::Record, 2), // 6.3.6.1: Numerator / Denominator
        (0x2011, ObjectType::Record, 5), // 6.3.6.7: PID selection + four gains
        (0x2012, ObjectType::Record, 2), // 6.3.6.8: profile check, timeout
    ];
    for &(index, object_type, highest) in expected {
        let o = model().object(index).unwrap();
        assert_eq!(o.object_type, object_type, "0x{index:04X}");
        assert_eq!(o.subs.len(), highest as usize + 1, "0x{index:04X} sub count");
        assert_eq!(o.sub(0).unwrap().data_type, DataType::Unsigned8, "0x{index:04X} sub 0");
        if index != 0x1003 {
            assert_eq!(default_int(index, 0), highest as i128, "0x{index:04X} sub 0 default");
        }
    }
    for n in 0..8u16 {
        // T6.3: RPDO communication sub 0..2, TPDO communication sub 0..5, mappings sub 0..8.
        assert_eq!(model().object(0x1400 + n).unwrap().subs.len(), 3);
        assert_eq!(default_int(0x1400 + n, 0), 2);
        assert_eq!(model().object(0x1800 + n).unwrap().subs.len(), 6);
        assert_eq!(default_int(0x1800 + n, 0), 5);
        assert_eq!(model().object(0x1600 + n).unwrap().subs.len(), 9);
        assert_eq!(model().object(0x1A00 + n).unwrap().subs.len(), 9);
    }
}

// ---------------------------------------------------------------------------------------------
// Values straight from the manual
// ---------------------------------------------------------------------------------------------

#[test]
fn identity_and_device_info() {
    let m = model();
    // T6.3: 1000h Device Type default 0xFF7A0192 (profile 402 in the low word).
    assert_eq!(default_int(0x1000, 0), 0xFF7A_0192);
    assert_eq!(default_int(0x1000, 0) & 0xFFFF, 402);
    // T6.3 / T6.8: 1018h sub0 = 4, Vendor Id 0x97, Product code 0x5A, Revision 1, Serial 0.
    assert_eq!(default_int(0x1018, 0), 4);
    assert_eq!(default_int(0x1018, 1), 0x97);
    assert_eq!(default_int(0x1018, 2), 0x5A);
    assert_eq!(default_int(0x1018, 3), 1);
    assert_eq!(default_int(0x1018, 4), 0);
    assert_type(0x1018, 1, DataType::Unsigned32, Access::Ro, false);
    // [DeviceInfo] mirrors 1018h.
    assert_eq!(m.device_info.vendor_number, Some(0x97));
    assert_eq!(m.device_info.product_number, Some(0x5A));
    assert_eq!(m.device_info.revision_number, Some(1));
    assert_eq!(m.device_info.nr_of_rx_pdo, Some(8)); // 6.3.2.19: 1400h-1407h
    assert_eq!(m.device_info.nr_of_tx_pdo, Some(8)); // 6.3.2.21: 1800h-1807h
    assert_eq!(m.device_info.simple_boot_up_slave, Some(true));
    // Table 7.4: default baud rate 1 Mbit/s (the only rate the manual names).
    assert_eq!(m.device_info.baud_rates.get(&1000), Some(&true));
    // T6.3: 1008h "DRVI", 1009h "1", 100Ah "0", all STR CONST.
    assert_eq!(default_text(0x1008, 0), "DRVI");
    assert_eq!(default_text(0x1009, 0), "1");
    assert_eq!(default_text(0x100A, 0), "0");
    assert_type(0x1008, 0, DataType::VisibleString, Access::Const, false);
}

#[test]
fn communication_objects() {
    // T6.3: 1001h Error Register U8 RO, PDO mapping Yes.
    assert_type(0x1001, 0, DataType::Unsigned8, Access::Ro, true);
    // T6.3: 1002h Manufacturer status register U32 RO, PDO mapping Yes.
    assert_type(0x1002, 0, DataType::Unsigned32, Access::Ro, true);
    // T6.3: 1003h standard error fields U32 RO; 6.3.2.4: writing 0 to sub 0 clears the history.
    assert_type(0x1003, 1, DataType::Unsigned32, Access::Ro, false);
    assert!(entry(0x1003, 0).access.writable());
    // T6.3: 1005h COB-ID SYNC 0x00000080 (absolute).
    let sync = entry(0x1005, 0).default.as_ref().unwrap();
    assert!(!sync.is_node_relative());
    assert_eq!(sync.as_int(), Some(0x80));
    // T6.3: 1006h, 1007h U32 RW 0; 100Ch U16 RW 0; 1015h, 1017h U16 RW 0.
    assert_eq!(default_int(0x1006, 0), 0);
    assert_eq!(default_int(0x1007, 0), 0);
    assert_type(0x100C, 0, DataType::Unsigned16, Access::Rw, false);
    assert_eq!(default_int(0x100C, 0), 0);
    assert_type(0x1015, 0, DataType::Unsigned16, Access::Rw, false);
    assert_type(0x1017, 0, DataType::Unsigned16, Access::Rw, false);
    assert_eq!(default_int(0x1017, 0), 0);
    // T6.3: 1010h sub1 Save all Parameters U32 RW 0.
    assert_type(0x1010, 1, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(default_int(0x1010, 1), 0);
    // 6.3.2.14: 1011h sub1 restores (signature written there).
    assert_type(0x1011, 1, DataType::Unsigned32, Access::Rw, false);
    // T6.3: 1014h COB-ID EMCY 0x00000080 at node 0 = $NODEID+0x80, RO.
    let emcy = entry(0x1014, 0).default.as_ref().unwrap();
    assert!(emcy.is_node_relative());
    assert_eq!(emcy.resolve(32), Some(0x80 + 32)); // Table 7.4: default node id 32
    assert_eq!(entry(0x1014, 0).access, Access::Ro);
    // T6.3: 1F80h NMT Startup U32 RW 0x00000004.
    assert_type(0x1F80, 0, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(default_int(0x1F80, 0), 0x0000_0004);
}

#[test]
fn pdo_communication_parameters() {
    // T6.3: RPDO COB-IDs at node 0; RPDO1 valid, 2..5 invalid (bit 31), 6..8 0x80000000.
    let rpdo = [0x0000_0200, 0x8000_0300, 0x8000_0400, 0x8000_0500, 0x8000_0680];
    for (n, &cob) in rpdo.iter().enumerate() {
        let v = entry(0x1400 + n as u16, 1).default.as_ref().unwrap();
        assert!(v.is_node_relative(), "RPDO{} COB-ID is node relative", n + 1);
        assert_eq!(v.resolve(0), Some(cob));
    }
    for n in 5..8u16 {
        assert_eq!(entry(0x1400 + n, 1).default.as_ref().unwrap().as_int(), Some(0x8000_0000));
        assert_eq!(entry(0x1800 + n - 1, 1).default.as_ref().unwrap().as_int(), Some(0x8000_0000));
    }
    // T6.3: TPDO COB-IDs at node 0.
    let tpdo = [0x0000_0180, 0x8000_0280, 0x8000_0380, 0x8000_0480];
    for (n, &cob) in tpdo.iter().enumerate() {
        let v = entry(0x1800 + n as u16, 1).default.as_ref().unwrap();
        assert!(v.is_node_relative());
        assert_eq!(v.resolve(0), Some(cob));
    }
    // RPDO1 at the default node id 32 (Table 7.4) is 0x220, TPDO1 0x1A0.
    assert_eq!(entry(0x1400, 1).default.as_ref().unwrap().resolve(32), Some(0x220));
    assert_eq!(entry(0x1800, 1).default.as_ref().unwrap().resolve(32), Some(0x1A0));
    for n in 0..8u16 {
        // T6.3: transmission type 0xFF everywhere.
        assert_eq!(default_int(0x1400 + n, 2), 0xFF);
        assert_eq!(default_int(0x1800 + n, 2), 0xFF);
        // T6.3: TPDO inhibit time 0, compatibility entry 0.
        assert_eq!(default_int(0x1800 + n, 3), 0);
        assert_type(0x1800 + n, 3, DataType::Unsigned16, Access::Rw, false);
        assert_eq!(default_int(0x1800 + n, 4), 0);
        // T6.3: event timer 0x0064 on TPDO1, 0 on the others.
        assert_eq!(default_int(0x1800 + n, 5), if n == 0 { 100 } else { 0 });
        assert_type(0x1800 + n, 5, DataType::Unsigned16, Access::Rw, false);
    }
}

#[test]
fn default_pdo_mappings() {
    // T6.3: 1600h sub0 = 1, sub1 = 0x60400010 (controlword); 1A00h sub0 = 1, sub1 = 0x60410010.
    assert_eq!(default_int(0x1600, 0), 1);
    assert_eq!(default_int(0x1600, 1), 0x6040_0010);
    assert_eq!(default_int(0x1A00, 0), 1);
    assert_eq!(default_int(0x1A00, 1), 0x6041_0010);
    for n in 0..8u16 {
        for (mapping, rpdo) in [(0x1600 + n, true), (0x1A00 + n, false)] {
            let count = default_int(mapping, 0) as u8;
            let mut bits = 0u32;
            for sub in 1..=8u8 {
                let raw = default_int(mapping, sub) as u32;
                if sub > count {
                    assert_eq!(raw, 0, "0x{mapping:04X} sub {sub}");
                    continue;
                }
                let pm = PdoMappingEntry::from_u32(raw);
                let target = entry(pm.index.0, pm.sub.0);
                assert!(target.pdo_mapping, "0x{mapping:04X} maps a non-mappable object");
                assert_eq!(target.data_type.bits(), Some(pm.bits as u32), "0x{mapping:04X} sub {sub} length");
                if rpdo {
                    assert!(target.access.rpdo_ok());
                } else {
                    assert!(target.access.tpdo_ok());
                }
                bits += pm.bits as u32;
            }
            assert!(bits <= 64);
        }
    }
}

#[test]
fn cia402_objects() {
    // T6.14: 603Fh Error Code U16 RO TPDO.
    assert_type(0x603F, 0, DataType::Unsigned16, Access::Ro, true);
    // T6.14: 6040h Controlword U16 RW RPDO 0; 6041h Statusword U16 RO TPDO 0.
    assert_type(0x6040, 0, DataType::Unsigned16, Access::Rw, true);
    assert_eq!(default_int(0x6040, 0), 0);
    assert_type(0x6041, 0, DataType::Unsigned16, Access::Ro, true);
    // T6.14: 6060h S8 RW RPDO 0; 6061h S8 RO TPDO 0.
    assert_type(0x6060, 0, DataType::Integer8, Access::Rw, true);
    assert_type(0x6061, 0, DataType::Integer8, Access::Ro, true);
    // T6.14: 6062h S32 RO no PDO; 6064h S32 RO TPDO.
    assert_type(0x6062, 0, DataType::Integer32, Access::Ro, false);
    assert_type(0x6064, 0, DataType::Integer32, Access::Ro, true);
    // T6.14: 6065h U32 RO, 6066h U16 RO.
    assert_type(0x6065, 0, DataType::Unsigned32, Access::Ro, false);
    assert_type(0x6066, 0, DataType::Unsigned16, Access::Ro, false);
    // T6.14: 606Bh S32 RO, 606Ch S32 RO TPDO, 606Fh/6070h U16 RW.
    assert_type(0x606B, 0, DataType::Integer32, Access::Ro, false);
    assert_type(0x606C, 0, DataType::Integer32, Access::Ro, true);
    assert_type(0x606F, 0, DataType::Unsigned16, Access::Rw, false);
    assert_type(0x6070, 0, DataType::Unsigned16, Access::Rw, false);
    // T6.14: 6071h S16 RW RPDO; range -15000..15000 mA from UVIX 7.6.1.8.
    assert_type(0x6071, 0, DataType::Integer16, Access::Rw, true);
    assert_eq!(limits(0x6071, 0), (-15000, 15000));
    // T6.14: 6074h, 6077h S16 RO.
    assert_type(0x6074, 0, DataType::Integer16, Access::Ro, false);
    assert_type(0x6077, 0, DataType::Integer16, Access::Ro, false);
    // T6.14: 607Ah, 607Ch S32 RW RPDO.
    assert_type(0x607A, 0, DataType::Integer32, Access::Rw, true);
    assert_type(0x607C, 0, DataType::Integer32, Access::Rw, true);
    // T6.14: 607Dh sub1/sub2 S32 RW 0.
    assert_type(0x607D, 1, DataType::Integer32, Access::Rw, false);
    assert_type(0x607D, 2, DataType::Integer32, Access::Rw, false);
    assert_eq!(default_int(0x607D, 1), 0);
    // T6.14 / T6.18: 607Eh Polarity U8 RW RPDO 0 (0x80 = reverse).
    assert_type(0x607E, 0, DataType::Unsigned8, Access::Rw, true);
    assert_eq!(default_int(0x607E, 0), 0);
    // T6.14: 607Fh Max profile velocity U32 RW 65535.
    assert_type(0x607F, 0, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(default_int(0x607F, 0), 65535);
    // T6.14: 6081h, 6083h, 6084h U32 RW RPDO 0; 6087h U32 RW 0.
    for index in [0x6081, 0x6083, 0x6084] {
        assert_type(index, 0, DataType::Unsigned32, Access::Rw, true);
        assert_eq!(default_int(index, 0), 0);
    }
    assert_type(0x6087, 0, DataType::Unsigned32, Access::Rw, false);
    // T6.14: 6091h MotorRevs / ShaftRevs U32 RW 0.
    assert_type(0x6091, 1, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(default_int(0x6091, 1), 0);
    assert_eq!(default_int(0x6091, 2), 0);
    // 6.3.4.23: 6092h Feed = 100 x screw pitch (pitch 1 -> 100), shaft revolutions 1.
    assert_eq!(default_int(0x6092, 1), 100);
    assert_eq!(default_int(0x6092, 2), 1);
    // T6.14: 6098h Homing Method S8 RW RPDO default 37.
    assert_type(0x6098, 0, DataType::Integer8, Access::Rw, true);
    assert_eq!(default_int(0x6098, 0), 37);
    // T6.14: 6099h sub1/sub2 U32 RW RPDO 0.
    assert_type(0x6099, 1, DataType::Unsigned32, Access::Rw, true);
    assert_type(0x6099, 2, DataType::Unsigned32, Access::Rw, true);
    // T6.14: 609Ah U32 RW 0; range 0..65535 from UVIX 7.6.1.4.
    assert_type(0x609A, 0, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(limits(0x609A, 0), (0, 65535));
    // T6.14: 60FFh Target Velocity S32 RW RPDO 0.
    assert_type(0x60FF, 0, DataType::Integer32, Access::Rw, true);
    assert_eq!(default_int(0x60FF, 0), 0);
}

#[test]
fn manufacturer_objects() {
    // 6.3.6.1 / T6.19: 2001h Numerator and Denominator U32 RW, default 1 (unit unchanged).
    assert_eq!(entry(0x2001, 1).name, "Numerator");
    assert_eq!(entry(0x2001, 2).name, "Denominator");
    assert_type(0x2001, 1, DataType::Unsigned32, Access::Rw, false);
    assert_eq!(default_int(0x2001, 1), 1);
    assert_eq!(default_int(0x2001, 2), 1);
    // 6.3.6.2 / T6.20: 2002h Input status U32 read-only, TPDO.
    assert_type(0x2002, 0, DataType::Unsigned32, Access::Ro, true);
    // 6.12 / T6.44: 2003h Output status U32, written to set the output.
    assert_type(0x2003, 0, DataType::Unsigned32, Access::Rw, true);
    // 6.3.6.4: 2004h Homing ok U8 RO, 0 = not performed.
    assert_type(0x2004, 0, DataType::Unsigned8, Access::Ro, true);
    assert_eq!(default_int(0x2004, 0), 0);
    // 6.3.6.5 / T6.36: 2006h Warnings read-only, 16 bits (bits 12..15 reserved).
    assert_type(0x2006, 0, DataType::Unsigned16, Access::Ro, false);
    // 6.3.6.6: 2010h Limits enable 0/1, default 0.
    assert_type(0x2010, 0, DataType::Unsigned8, Access::Rw, false);
    assert_eq!(limits(0x2010, 0), (0, 1));
    // 6.3.6.7: 2011h five PID sub-entries; PID selection 0..4.
    assert_eq!(default_int(0x2011, 0), 5);
    assert_eq!(entry(0x2011, 1).name, "PID selection");
    assert_eq!(limits(0x2011, 1), (0, 4));
    // T6.19 (realigned) defaults, consistent with 7.6.3 (KP position 0.1 x 10, KP speed 1000 x 10).
    assert_eq!(entry(0x2011, 2).name, "Kp position");
    assert_eq!(default_int(0x2011, 2), 1);
    assert_eq!(entry(0x2011, 3).name, "Kp speed");
    assert_eq!(default_int(0x2011, 3), 10000);
    assert_eq!(entry(0x2011, 4).name, "Ki position");
    assert_eq!(entry(0x2011, 5).name, "Ki speed");
    // 6.3.6.8: 2012h profile check (enable) and profile check timeout in ms.
    assert_eq!(entry(0x2012, 1).name, "Profile check");
    assert_type(0x2012, 2, DataType::Unsigned16, Access::Rw, false);
    assert_eq!(default_int(0x2012, 2), 50);
    // 6.3.6.9 / 7.6.1.4: 2013h homing torque limit in % of I2T, 0..100.
    assert_eq!(limits(0x2013, 0), (0, 100));
    // 6.3.6.10: 2014h actuator type, 0 = only motor (the default configuration).
    assert_type(0x2014, 0, DataType::Unsigned8, Access::Rw, false);
    assert_eq!(default_int(0x2014, 0), 0);
    // 6.3.6.11: 2015h torque limit enable 0/1.
    assert_eq!(limits(0x2015, 0), (0, 1));
}

#[test]
fn every_reconciliation_decision_is_in_the_comments() {
    let comments = &model().comments;
    assert!(comments.len() >= 30, "{} comment lines", comments.len());
    for needle in ["T6.19", "2011h sub order", "1011h", "6092h", "1404h", "6098h", "2003h", "100Dh"] {
        assert!(comments.iter().any(|c| c.contains(needle)), "no [Comments] line about {needle}");
    }
}

// ---------------------------------------------------------------------------------------------
// The sidecar
// ---------------------------------------------------------------------------------------------

mod sidecar {
    use devices::sidecar::{Dimension, Num, ObjRef, Ratio, Reaction, ScalingKind, Sidecar, Unit};

    use super::{entry, model};

    fn sidecar() -> Sidecar {
        Sidecar::read(&devices::sidecar_path("camozzi-drvi")).unwrap_or_else(|e| panic!("{e}"))
    }

    fn r(s: &str) -> ObjRef {
        s.parse().unwrap()
    }

    #[test]
    fn parses_and_names_its_eds() {
        let s = sidecar();
        assert_eq!(s.device.name, "camozzi-drvi");
        assert_eq!(s.device.eds, "camozzi-drvi.eds");
    }

    #[test]
    fn every_reference_exists_in_the_eds() {
        let s = sidecar();
        let mut missing = Vec::new();
        for (obj, what) in s.references() {
            let found = match obj.sub {
                None => model().object(obj.index).is_some(),
                Some(sub) => model().entry(obj.index, sub).is_some(),
            };
            if !found {
                missing.push(format!("{obj} ({what})"));
            }
        }
        assert!(missing.is_empty(), "{missing:?}");
    }

    #[test]
    fn unit_table_6_2() {
        let s = sidecar();
        // 6.3.6.10: 2014h = 0 only motor; Table 6.2 (*): degrees x 100, RPM x 100, RPM/s, mA.
        let motor = s.active_unit_system(|o| (o == r("0x2014")).then_some(0)).unwrap();
        assert_eq!(motor.name, "only-motor");
        let hundredth = Ratio { num: 1, den: 100 };
        assert_eq!(
            (motor.units[&Dimension::Position].unit, motor.units[&Dimension::Position].scale),
            (Unit::Degree, hundredth)
        );
        assert_eq!(
            (motor.units[&Dimension::Velocity].unit, motor.units[&Dimension::Velocity].scale),
            (Unit::Rpm, hundredth)
        );
        assert_eq!(motor.units[&Dimension::Acceleration].unit, Unit::RpmPerSecond);
        assert_eq!(motor.units[&Dimension::Acceleration].scale, Ratio::ONE);
        assert_eq!(motor.units[&Dimension::Torque].unit, Unit::MilliAmpere);
        assert_eq!(motor.units[&Dimension::TorqueSlope].unit, Unit::MilliAmperePerSecond);
        // 6.1: a position target of 36000 in only-motor is one turn (360 degrees).
        let pos = &motor.units[&Dimension::Position];
        assert_eq!(36000 * pos.scale.num / pos.scale.den, 360);
        // Table 6.2 (**): 2014h = 7 custom actuator: mm x 100, mm/s x 100, mm/s^2.
        let act = s.active_unit_system(|o| (o == r("0x2014")).then_some(7)).unwrap();
        assert_eq!(act.name, "actuator");
        assert_eq!(
            (act.units[&Dimension::Position].unit, act.units[&Dimension::Position].scale),
            (Unit::Millimeter, hundredth)
        );
        assert_eq!(
            (act.units[&Dimension::Velocity].unit, act.units[&Dimension::Velocity].scale),
            (Unit::MillimeterPerSecond, hundredth)
        );
        assert_eq!(act.units[&Dimension::Acceleration].unit, Unit::MillimeterPerSecond2);
        assert_eq!(act.units[&Dimension::Torque].unit, Unit::MilliAmpere);
        // The default value of 2014h selects only-motor.
        assert_eq!(super::default_int(0x2014, 0), 0);
    }

    #[test]
    fn communication_time_units() {
        let s = sidecar();
        let unit = |o: &str| s.object_units[&r(o)].unit;
        // 6.3.2.11 guard time ms, 6.3.2.16 EMCY inhibit 100 us, 6.3.2.17 heartbeat ms.
        assert_eq!(unit("0x100C"), Unit::Millisecond);
        assert_eq!(unit("0x1015"), Unit::HundredMicroseconds);
        assert_eq!(unit("0x1017"), Unit::Millisecond);
        // 6.3.2.21: TPDO inhibit time in 100 us, event timer in ms.
        for n in 0..8u16 {
            assert_eq!(unit(&format!("0x{:04X}sub3", 0x1800 + n)), Unit::HundredMicroseconds);
            assert_eq!(unit(&format!("0x{:04X}sub5", 0x1800 + n)), Unit::Millisecond);
        }
        // CiA 301 (decision): 1006h in microseconds.
        assert_eq!(unit("0x1006"), Unit::Microsecond);
    }

    #[test]
    fn dimensions_of_motion_objects() {
        let s = sidecar();
        for index in [0x6062, 0x6064, 0x607A, 0x607C] {
            assert_eq!(s.dimension_of(index, 0), Some(Dimension::Position), "0x{index:04X}");
        }
        assert_eq!(s.dimension_of(0x607D, 1), Some(Dimension::Position));
        assert_eq!(s.dimension_of(0x607D, 2), Some(Dimension::Position));
        for index in [0x606B, 0x606C, 0x606F, 0x607F, 0x6081, 0x60FF] {
            assert_eq!(s.dimension_of(index, 0), Some(Dimension::Velocity), "0x{index:04X}");
        }
        assert_eq!(s.dimension_of(0x6099, 1), Some(Dimension::Velocity));
        assert_eq!(s.dimension_of(0x6099, 2), Some(Dimension::Velocity));
        for index in [0x6083, 0x6084, 0x609A] {
            assert_eq!(s.dimension_of(index, 0), Some(Dimension::Acceleration), "0x{index:04X}");
        }
        for index in [0x6071, 0x6074, 0x6077] {
            assert_eq!(s.dimension_of(index, 0), Some(Dimension::Torque), "0x{index:04X}");
        }
        assert_eq!(s.dimension_of(0x6087, 0), Some(Dimension::TorqueSlope));
        // Every dimensioned entry is a number.
        for obj in s.dimensions.keys() {
            assert!(entry(obj.index, obj.sub_or_zero()).data_type.bits().is_some(), "{obj}");
        }
    }

    #[test]
    fn scaling_objects() {
        let s = sidecar();
        // 6.3.6.1: 2001h sub1 Numerator, sub2 Denominator.
        let fc = s.scaling_object(ScalingKind::FeedConverter).unwrap();
        assert_eq!(fc.object, r("0x2001"));
        assert_eq!(entry(0x2001, fc.subs["numerator"]).name, "Numerator");
        assert_eq!(entry(0x2001, fc.subs["denominator"]).name, "Denominator");
        // Inch example (6.3.6.1): 1 in = 2540 hundredths of mm -> 2540 * 100 / 254 = 1000.
        assert_eq!(2540 * 100 / 254, 1000);
        // 6.3.4.23: feed = 100 x pitch / shaft revolutions; the defaults give a 1 mm pitch.
        let feed = s.scaling_object(ScalingKind::FeedConstant).unwrap();
        assert_eq!(feed.object, r("0x6092"));
        let f = super::default_int(0x6092, feed.subs["feed"]);
        let revs = super::default_int(0x6092, feed.subs["shaft_revolutions"]);
        assert_eq!(f / (100 * revs), 1);
        // The feed counts hundredths of a millimetre (Table 6.2's position unit).
        let fu = feed.feed_unit.expect("6092h counts 0.01 mm");
        assert_eq!((fu.unit, fu.scale), (Unit::Millimeter, Ratio { num: 1, den: 100 }));
        let gear = s.scaling_object(ScalingKind::GearRatio).unwrap();
        assert_eq!(gear.object, r("0x6091"));
        assert_eq!((gear.subs["motor_revolutions"], gear.subs["shaft_revolutions"]), (1, 2));
        assert_eq!(s.scaling_object(ScalingKind::ActuatorType).unwrap().object, r("0x2014"));
        // Issue #28: the actuator's units turn the motor through 6092h and 6091h (6.3.4.22,
        // 6.3.4.23); only motor counts motor degrees through 2001h alone.
        for system in &s.unit_systems {
            for d in [Dimension::Position, Dimension::Velocity, Dimension::Acceleration] {
                let want: &[ScalingKind] = if system.name == "actuator" {
                    &[ScalingKind::FeedConverter, ScalingKind::FeedConstant, ScalingKind::GearRatio]
                } else {
                    &[ScalingKind::FeedConverter]
                };
                assert_eq!(system.units[&d].scaled_by, want, "{} {d:?}", system.name);
            }
        }
    }

    #[test]
    fn modes_and_homing_methods() {
        let s = sidecar();
        // Table 6.17: -1 jog, 0 none, 1 profile position, 3 profile velocity, 4 profile torque, 6 homing.
        let mut modes: Vec<i8> = s.modes.iter().map(|m| m.code).collect();
        modes.sort();
        assert_eq!(modes, [-1, 0, 1, 3, 4, 6]);
        // Table 6.29: 1, 2, 17, 18, 37, -1..-4.
        let mut methods: Vec<i8> = s.homing_methods.iter().map(|h| h.code).collect();
        methods.sort();
        assert_eq!(methods, [-4, -3, -2, -1, 1, 2, 17, 18, 37]);
        // Table 6.29: 1 = proximity negative direction + zero encoder, 18 = proximity positive.
        let m1 = s.homing_methods.iter().find(|h| h.code == 1).unwrap();
        assert!(m1.description.contains("negative direction + zero encoder"));
        let m18 = s.homing_methods.iter().find(|h| h.code == 18).unwrap();
        assert!(m18.description.starts_with("Proximity homing, positive direction"));
        // T6.14: the 6098h default 37 is a supported method.
        assert!(methods.contains(&(super::default_int(0x6098, 0) as i8)));
    }

    #[test]
    fn error_table_6_34() {
        let s = sidecar();
        // Table 6.34: Errcode value and manufacturer parameter.
        let table: &[(i64, i64, &str)] = &[
            (0x0000, 0, "Drive is not in error state"),
            (0x2310, 0, "Over current error"),
            (0x2310, 11, "I2T fault"),
            (0x3110, 0, "Over voltage error VBUS (> 80V)"),
            (0x3110, 1, "Over voltage error VLOG (> 29V)"),
            (0x3120, 0, "Under voltage error VBUS (< 10V)"),
            (0x3120, 1, "Under voltage error VLOG (< 16V)"),
            (0x4210, 0, "Over temperature motor error (> 100°C)"),
            (0x4210, 1, "Over temperature drive error (> 100°C)"),
            (0x5120, 0, "VEXT missing"),
            (0x5530, 0, "Non volatile memory fault"),
            (0x5540, 0, "Error HW Enable is not present (STO)"),
            (0x6100, 0, "Control fault"),
            (0x6120, 0, "Software Limits exceed"),
            (0x7305, 0, "Encoder fault"),
            (0x8120, 0, "CAN in error passive"),
            (0x8210, 0, "PDO data length too short"),
            (0x8220, 0, "PDO data length exceeded"),
            (0x8613, 13, "Homing execution error"),
        ];
        for &(code, manufacturer, text) in table {
            let e = s
                .errors
                .iter()
                .find(|e| e.code == Num(code) && e.manufacturer == Some(Num(manufacturer)))
                .unwrap_or_else(|| panic!("error 0x{code:04X}/{manufacturer} missing"));
            assert_eq!(e.text, text);
        }
        // 6.9: soft errors quick-stop, the others switch the power stage off.
        let reaction = |code: i64, m: i64| {
            s.errors.iter().find(|e| e.code == Num(code) && e.manufacturer == Some(Num(m))).unwrap().reaction
        };
        assert_eq!(reaction(0x4210, 0), Reaction::QuickStop);
        assert_eq!(reaction(0x4210, 1), Reaction::QuickStop);
        assert_eq!(reaction(0x8613, 13), Reaction::QuickStop);
        assert_eq!(reaction(0x2310, 0), Reaction::PowerOff);
        assert_eq!(reaction(0x5540, 0), Reaction::PowerOff);
        // Every error sets the generic bit of 1001h (except "no error").
        for e in s.errors.iter().filter(|e| e.code != Num(0)) {
            assert_eq!(e.register.unwrap().0 & 1, 1, "0x{:04X}", e.code.0);
        }
    }

    #[test]
    fn warning_bits_table_6_36() {
        let s = sidecar();
        let texts = [
            "VDC UVLO (< 20V)",
            "VDC OVLO (> 60V)",
            "VL UVLO (< 21V)",
            "VL OVLO (> 27V)",
            "Temperature motor limit (> 75°C)",
            "Temperature drive limit (> 75°C)",
            "Positive position limit reached",
            "Negative position limit reached",
            "Homing missing",
            "Target speed not reached",
            "Target position not reached",
            "Command refused",
        ];
        assert_eq!(s.warnings.len(), texts.len());
        for (bit, text) in texts.iter().enumerate() {
            let w = s.warnings.iter().find(|w| w.bit as usize == bit).unwrap();
            assert_eq!(w.object, r("0x2006"));
            assert_eq!(w.text, *text);
            // 6.9: only "homing missing" (bit 8) and "command refused" (bit 11) reset by themselves.
            assert_eq!(w.auto_reset, bit == 8 || bit == 11, "bit {bit}");
        }
        // Table 6.36: bits 12..15 reserved, all fit the U16 of 2006h.
        assert!(s.warnings.iter().all(|w| w.bit < 12));
    }

    #[test]
    fn store_list() {
        let s = sidecar();
        // 6.3.2.13: 1010h saves configuration; command values are not stored.
        for stored in ["0x2001", "0x2011", "0x2014", "0x6098", "0x6099", "0x1400", "0x1A00"] {
            assert!(s.store.objects.contains(&r(stored)), "{stored}");
        }
        for not_stored in ["0x6040", "0x607A", "0x60FF", "0x1010", "0x1011"] {
            assert!(!s.store.objects.contains(&r(not_stored)), "{not_stored}");
        }
        // Stored objects must be writable.
        for obj in &s.store.objects {
            let o = model().object(obj.index).unwrap();
            assert!(o.subs.values().any(|e| e.access.writable()), "{obj}");
        }
        assert!(s.store.note.as_deref().unwrap().contains("0x65766173"));
    }

    #[test]
    fn decisions_are_recorded() {
        let s = sidecar();
        assert!(s.decisions.len() >= 40, "{} decisions", s.decisions.len());
        for object in ["0x2011", "0x2003", "0x6098", "0x6092", "0x1011", "0x100D"] {
            assert!(s.decisions.iter().any(|d| d.object == Some(r(object))), "no decision about {object}");
        }
    }
}
