//! Run-time behaviour of a generated dictionary, on the fixture that exercises every code path
//! (24- and 40-bit integers, BOOLEAN, REAL32 with limits, strings, bit-granular PDOs, a dummy
//! entry, `$NODEID` defaults, name collisions).

use generated::fixture_mini::{Dictionary, ENTRIES, index, pdo};
use od_runtime::od::{AbortCode, Area, ObjectDictionary};
use proptest::prelude::*;

fn read(od: &Dictionary, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
    let mut buf = [0u8; 64];
    let n = od.read(index, sub, &mut buf)?;
    Ok(buf[..n].to_vec())
}

#[test]
fn defaults_and_node_id() {
    let od = Dictionary::new(5);
    assert_eq!(od.device_type(), 0x0002_0192);
    assert_eq!(od.rpdo_communication_parameter_1_cob_id(), 0x205);
    assert_eq!(od.position_window(), 0x15);
    assert_eq!(od.signed_24(), -5);
    assert!(od.flag());
    assert_eq!(od.gain(), 1.5);
    assert_eq!(od.blob(), &[1, 2]);
    assert_eq!(od.counter(), 0x1_2345_6789);
    assert_eq!(od.manufacturer_device_name(), b"Mini drive");
    assert_eq!(index::CONTROLWORD, 0x6040);
    assert_eq!(Dictionary::new(5), Dictionary::new(5));
}

#[test]
fn table_is_sorted_and_lookups_distinguish_missing_objects_from_missing_subs() {
    assert!(ENTRIES.windows(2).all(|w| (w[0].index, w[0].sub) < (w[1].index, w[1].sub)));
    let od = Dictionary::new(1);
    assert_eq!(od.name(0x6040, 0), Some("Controlword"));
    assert_eq!(od.name(0x1018, 4), Some("Identity object: Serial number"));
    assert_eq!(od.name(0x1018, 9), None);
    assert_eq!(od.info(0x1018, 5), Err(AbortCode::NO_SUB_INDEX));
    assert_eq!(od.info(0x1019, 0), Err(AbortCode::NO_OBJECT));
    assert_eq!(od.info(0x0000, 0), Err(AbortCode::NO_OBJECT));
    assert_eq!(od.info(0xFFFF, 0xFF), Err(AbortCode::NO_OBJECT));
    for (i, e) in ENTRIES.iter().enumerate() {
        assert_eq!(Dictionary::position(e.index, e.sub), Ok(i));
    }
}

#[test]
fn bus_reads_and_writes_are_little_endian_with_exact_lengths() {
    let mut od = Dictionary::new(1);
    assert_eq!(read(&od, 0x1000, 0).unwrap(), vec![0x92, 0x01, 0x02, 0x00]);
    assert_eq!(read(&od, 0x2001, 0).unwrap(), vec![0xFB, 0xFF, 0xFF]); // INTEGER24 -5
    assert_eq!(read(&od, 0x2005, 0).unwrap(), vec![0x89, 0x67, 0x45, 0x23, 0x01]); // UNSIGNED40
    assert_eq!(read(&od, 0x2002, 0).unwrap(), vec![1]);
    od.write(0x6040, 0, &[0x0F, 0x00]).unwrap();
    assert_eq!(od.controlword(), 0x000F);
    assert_eq!(od.write(0x6040, 0, &[0x0F]), Err(AbortCode::LENGTH_TOO_LOW));
    assert_eq!(od.write(0x6040, 0, &[0, 0, 0]), Err(AbortCode::LENGTH_TOO_HIGH));
    od.write(0x2001, 0, &[0x18, 0xFC, 0xFF]).unwrap(); // -1000, the low limit
    assert_eq!(od.signed_24(), -1000);
    assert_eq!(od.write(0x2001, 0, &[0x17, 0xFC, 0xFF]), Err(AbortCode::VALUE_TOO_LOW));
    assert_eq!(od.write(0x2001, 0, &[0xE9, 0x03, 0x00]), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(od.write(0x2002, 0, &[2]), Err(AbortCode::INVALID_VALUE));
    assert_eq!(od.write(0x2003, 0, &10.5f32.to_le_bytes()), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(od.write(0x2003, 0, &(-0.5f32).to_le_bytes()), Err(AbortCode::VALUE_TOO_LOW));
    od.write(0x2003, 0, &2.25f32.to_le_bytes()).unwrap();
    assert_eq!(od.gain(), 2.25);
    od.write(0x1008, 0, b"renamed").unwrap();
    assert_eq!(read(&od, 0x1008, 0).unwrap(), b"renamed");
    assert_eq!(od.write(0x1008, 0, &[b'x'; 33]), Err(AbortCode::LENGTH_TOO_HIGH));
    let mut small = [0u8; 2];
    assert_eq!(od.read(0x1000, 0, &mut small), Err(AbortCode::OUT_OF_MEMORY));
}

#[test]
fn bus_side_enforces_access_application_side_does_not() {
    let mut od = Dictionary::new(1);
    assert_eq!(od.bus_write(0x6041, 0, &[1, 0]), Err(AbortCode::READ_ONLY));
    assert_eq!(od.bus_write(0x1008, 0, b"x"), Err(AbortCode::READ_ONLY));
    od.set_statusword(0x0237).unwrap();
    let mut buf = [0u8; 2];
    assert_eq!(od.bus_read(0x6041, 0, &mut buf), Ok(2));
    assert_eq!(buf, [0x37, 0x02]);
    od.bus_write(0x6040, 0, &[6, 0]).unwrap();
    assert_eq!(od.controlword(), 6);
}

#[test]
fn typed_setters_enforce_limits_and_type_ranges() {
    let mut od = Dictionary::new(1);
    assert_eq!(od.set_modes_of_operation(-4), Err(AbortCode::VALUE_TOO_LOW));
    assert_eq!(od.set_modes_of_operation(11), Err(AbortCode::VALUE_TOO_HIGH));
    od.set_modes_of_operation(-3).unwrap();
    assert_eq!(od.set_signed_24(1001), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(od.set_counter(1 << 40), Err(AbortCode::VALUE_TOO_HIGH)); // UNSIGNED40 in a u64
    od.set_counter((1 << 40) - 1).unwrap();
    assert_eq!(od.set_gains_2_2(501), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(od.set_gain(f32::INFINITY), Err(AbortCode::VALUE_TOO_HIGH));
    assert_eq!(od.set_blob(&[0; 33]), Err(AbortCode::LENGTH_TOO_HIGH));
    od.set_blob(&[9; 32]).unwrap();
    assert_eq!(od.blob(), &[9; 32]);
}

#[test]
fn restore_defaults_by_area() {
    let mut od = Dictionary::new(7);
    od.set_rpdo_communication_parameter_1_cob_id(0x8000_0000).unwrap();
    od.set_controlword(0xFF).unwrap();
    od.set_signed_24(100).unwrap();
    od.set_manufacturer_device_name(b"other").unwrap();
    od.restore_defaults(Area::Application, 9);
    assert_eq!(od.controlword(), 0);
    assert_eq!(od.signed_24(), 100, "manufacturer area untouched");
    assert_eq!(od.rpdo_communication_parameter_1_cob_id(), 0x8000_0000);
    od.restore_defaults(Area::All, 9);
    assert_eq!(od.rpdo_communication_parameter_1_cob_id(), 0x209);
    assert_eq!(od.signed_24(), -5);
    assert_eq!(od.manufacturer_device_name(), b"Mini drive");
    assert_eq!(od, Dictionary::new(9));
}

#[test]
fn pdo_layouts_are_bit_exact() {
    assert_eq!(pdo::Rpdo1::LEN, 4); // 16 + dummy 8 + 8
    assert_eq!(pdo::Rpdo1::MAPPING, [0x6040_0010, 0x0005_0008, 0x6060_0008]);
    let r = pdo::Rpdo1 { controlword: 0x1234, modes_of_operation: -1 };
    assert_eq!(r.pack(), [0x34, 0x12, 0x00, 0xFF]);
    assert_eq!(pdo::Rpdo1::unpack(&[0x34, 0x12, 0xAA, 0xFF, 0x99]), Ok(r)); // dummy and extra byte ignored
    assert_eq!(pdo::Rpdo1::unpack(&[1, 2, 3]), Err(pdo::LengthError { expected: 4, actual: 3 }));

    // 16 + 8 + 24 + 1 bits: the boolean sits at bit 48.
    let t = pdo::Tpdo1 { statusword: 0x0637, modes_of_operation_display: 3, signed_24: -2, flag: true };
    assert_eq!(t.pack(), [0x37, 0x06, 0x03, 0xFE, 0xFF, 0xFF, 0x01]);
    assert_eq!(pdo::Tpdo1::unpack(&t.pack()), Ok(t));

    let mut od = Dictionary::new(1);
    od.set_position_actual_value(-123_456).unwrap();
    let t2 = pdo::TxMappingTable1A01::from_dictionary(&od);
    assert_eq!(pdo::TxMappingTable1A01::LEN, 8);
    assert_eq!(t2.pack()[..4], (-123_456i32).to_le_bytes());
    let mut od2 = Dictionary::new(1);
    pdo::Rpdo1 { controlword: 0x0F, modes_of_operation: 99 }.to_dictionary(&mut od2).unwrap_err();
    pdo::Rpdo1 { controlword: 0x0F, modes_of_operation: 1 }.to_dictionary(&mut od2).unwrap();
    assert_eq!(od2.controlword(), 0x0F);
}

#[test]
fn run_time_mapping_checks() {
    assert_eq!(Dictionary::check_rpdo_mapping(&pdo::Rpdo1::MAPPING), Ok(32));
    assert_eq!(Dictionary::check_tpdo_mapping(&pdo::Tpdo1::MAPPING), Ok(49));
    assert_eq!(Dictionary::check_tpdo_mapping(&[0x6040_0010]), Err(AbortCode::NOT_MAPPABLE));
    assert_eq!(Dictionary::check_rpdo_mapping(&[0x6041_0010]), Err(AbortCode::NOT_MAPPABLE));
    assert_eq!(Dictionary::check_rpdo_mapping(&[0x6040_0008]), Err(AbortCode::PARAMETER_INCOMPATIBLE));
    assert_eq!(
        Dictionary::check_tpdo_mapping(&[0x6064_0020, 0x6064_0020, 0x6041_0010]),
        Err(AbortCode::PDO_LENGTH_EXCEEDED)
    );
}

proptest! {
    #[test]
    fn tpdo1_round_trips(status: u16, mode: i8, s24 in -(1i32 << 23)..(1i32 << 23), flag: bool) {
        let t = pdo::Tpdo1 { statusword: status, modes_of_operation_display: mode, signed_24: s24, flag };
        prop_assert_eq!(pdo::Tpdo1::unpack(&t.pack()), Ok(t));
    }

    #[test]
    fn tpdo2_round_trips(p: i32, v: i32) {
        let t = pdo::TxMappingTable1A01 { position_actual_value: p, velocity_actual_value: v };
        let bytes = t.pack();
        prop_assert_eq!(&bytes[..4], &p.to_le_bytes());
        prop_assert_eq!(pdo::TxMappingTable1A01::unpack(&bytes), Ok(t));
    }

    #[test]
    fn hostile_bus_input_never_panics(index: u16, sub: u8, data in proptest::collection::vec(any::<u8>(), 0..80)) {
        let mut od = Dictionary::new(1);
        let _ = od.write(index, sub, &data);
        let _ = od.bus_write(index, sub, &data);
        let mut buf = [0u8; 80];
        let _ = od.read(index, sub, &mut buf);
        let _ = pdo::Tpdo1::unpack(&data);
        let _ = Dictionary::check_rpdo_mapping(&data.iter().map(|b| u32::from(*b) * 0x0101_0101).collect::<Vec<_>>());
    }

    #[test]
    fn every_entry_reads_back_what_was_written(pos in 0..ENTRIES.len()) {
        let e = &ENTRIES[pos];
        let mut od = Dictionary::new(1);
        let mut buf = [0u8; 64];
        let n = od.read(e.index, e.sub, &mut buf).unwrap();
        // Writing back the current value always succeeds and changes nothing.
        od.write(e.index, e.sub, &buf[..n]).unwrap();
        prop_assert_eq!(&od, &Dictionary::new(1));
    }
}
