//! Property tests: hostile frame sequences never panic and never leave the SDO server stuck.

use crate::common;
use common::*;
use od_runtime::{Frame, Micros};
use proptest::prelude::*;

/// COB-IDs the device listens to, plus anything.
fn id() -> impl Strategy<Value = u16> {
    prop_oneof![
        3 => prop::sample::select(vec![0x000u16, 0x080, 0x181, 0x201, 0x281, 0x301, 0x401, 0x501, 0x601, 0x701, 0x702]),
        1 => 0u16..0x800,
    ]
}

/// SDO-looking payloads: a command byte, an index the dictionary has, anything after.
fn sdo_payload() -> impl Strategy<Value = [u8; 8]> {
    let index = prop::sample::select(vec![
        0x1000u16, 0x1003, 0x1005, 0x1006, 0x1008, 0x1010, 0x1011, 0x1017, 0x1019, 0x1400, 0x1600, 0x1800, 0x1A00,
        0x1A01, 0x2001, 0x2003, 0x6040, 0x6060, 0x9999,
    ]);
    (any::<u8>(), index, 0u8..10, any::<[u8; 4]>()).prop_map(|(cmd, i, sub, tail)| {
        let b = i.to_le_bytes();
        [cmd, b[0], b[1], sub, tail[0], tail[1], tail[2], tail[3]]
    })
}

#[derive(Debug, Clone)]
enum Step {
    Frame(u16, bool, u8, [u8; 8]),
    Sdo([u8; 8]),
    Wait(Micros),
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        4 => (id(), prop::bool::weighted(0.1), 0u8..=8, any::<[u8; 8]>()).prop_map(|(i, r, l, d)| Step::Frame(i, r, l, d)),
        4 => sdo_payload().prop_map(Step::Sdo),
        1 => prop_oneof![0u64..2_000, 0u64..2_000_000].prop_map(Step::Wait),
    ]
}

fn run(h: &mut Harness, steps: &[Step]) {
    for s in steps {
        match s {
            Step::Frame(id, rtr, len, data) => {
                h.dev.on_frame(&Frame::from_parts(*id, *rtr, *len, *data), h.now);
            }
            Step::Sdo(d) => h.dev.on_frame(&Frame::new(0x601, d).unwrap(), h.now),
            Step::Wait(us) => h.now += us,
        }
        let out = h.poll();
        assert!(out.len() <= 160, "one poll sent {} frames", out.len());
    }
}

/// Sends an upload request of 1000h and returns the SDO answers.
fn upload_device_type(h: &mut Harness) -> Vec<String> {
    h.send("601 40 00 10 00 00 00 00 00").into_iter().filter(|f| f.starts_with("581 ")).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn hostile_frames_never_panic_and_sdo_recovers(steps in prop::collection::vec(step(), 0..120)) {
        let mut h = Harness::new();
        run(&mut h, &steps);
        // Whatever happened, a master that puts the node in pre-operational gets answers:
        // at once, or after the SDO timeout cleared a transfer the garbage started.
        h.send("000 80 00");
        let mut answer = upload_device_type(&mut h);
        if answer.is_empty() || answer[0] != "581 43 00 10 00 92 01 02 00" {
            h.advance(2_000_000);
            answer = upload_device_type(&mut h);
        }
        prop_assert_eq!(answer, vec!["581 43 00 10 00 92 01 02 00".to_string()]);
    }

    #[test]
    fn sdo_garbage_in_every_transfer_state(prefix in prop::sample::select(vec![
        "601 40 08 10 00 00 00 00 00",
        "601 21 01 20 00 0C 00 00 00",
        "601 C6 03 20 00 00 01 00 00",
        "601 A4 03 20 00 05 00 00 00",
        "601 A4 08 10 00 02 00 00 00",
    ]), garbage in prop::collection::vec(any::<[u8; 8]>(), 0..40)) {
        let mut h = Harness::new();
        h.send(prefix);
        h.send("601 A3 00 00 00 00 00 00 00");
        for g in &garbage {
            h.dev.on_frame(&Frame::new(0x601, g).unwrap(), h.now);
            h.poll();
        }
        h.send("000 80 00");
        let mut answer = upload_device_type(&mut h);
        if answer.is_empty() || answer[0] != "581 43 00 10 00 92 01 02 00" {
            h.advance(2_000_000);
            answer = upload_device_type(&mut h);
        }
        prop_assert_eq!(answer, vec!["581 43 00 10 00 92 01 02 00".to_string()]);
    }

    #[test]
    fn transfers_round_trip(
        data in prop::collection::vec(any::<u8>(), 0..1024),
        blk in 1u8..=127,
        crc in any::<bool>(),
        lose in prop::option::of(1u8..=127),
        segmented in any::<bool>(),
    ) {
        let mut h = Harness::new();
        // Without `sdo-block` the device has segmented transfers only.
        let block = cfg!(feature = "sdo-block");
        if segmented || !block {
            // The last segment's answer carries that segment's toggle bit.
            let segments = data.len().div_ceil(7).max(1);
            let last = if segments % 2 == 0 { "581 30 00 00 00 00 00 00 00" } else { "581 20 00 00 00 00 00 00 00" };
            prop_assert_eq!(segmented_download(&mut h, 0x2003, &data), last);
            prop_assert_eq!(upload(&mut h, 0x2003, 0), data.clone());
        } else {
            prop_assert_eq!(block_download(&mut h, 0x2003, &data, crc, lose), "581 A1 00 00 00 00 00 00 00");
        }
        prop_assert_eq!(h.od().bytes(0x2003, 0), data.clone());
        if block {
            prop_assert_eq!(block_upload(&mut h, 0x2003, 0, blk, crc), data);
        }
    }

    #[test]
    fn frame_from_parts_is_total(id in any::<u16>(), rtr in any::<bool>(), len in any::<u8>(), data in any::<[u8; 8]>()) {
        let f = Frame::from_parts(id, rtr, len, data);
        prop_assert!(f.id() <= 0x7FF);
        prop_assert!(f.len() <= 8);
        prop_assert!(f.data().len() <= 8);
    }
}

/// An entry's flags byte keeps what it is given: the size of every data type (BOOLEAN's one
/// bit, 0 for the variable-length types) and `PDOMapping`, independently of each other.
#[test]
fn entry_flags_keep_the_size_and_the_mapping_flag() {
    use od_runtime::od::{Access, DataType as D, EntryFlags, EntryInfo};
    let all = [
        D::Boolean,
        D::Integer8,
        D::Integer16,
        D::Integer24,
        D::Integer32,
        D::Integer40,
        D::Integer48,
        D::Integer56,
        D::Integer64,
        D::Unsigned8,
        D::Unsigned16,
        D::Unsigned24,
        D::Unsigned32,
        D::Unsigned40,
        D::Unsigned48,
        D::Unsigned56,
        D::Unsigned64,
        D::Real32,
        D::Real64,
        D::TimeOfDay,
        D::TimeDifference,
        D::VisibleString,
        D::OctetString,
        D::UnicodeString,
        D::Domain,
    ];
    for dt in all {
        for pdo in [false, true] {
            let e = EntryInfo::new(0x2000, 1, dt, Access::Rw, pdo);
            assert_eq!((e.bits(), e.pdo_mappable()), (dt.bits(), pdo), "{dt:?}");
        }
    }
    for bits in 0..=64u8 {
        for pdo in [false, true] {
            let f = EntryFlags::new(bits, pdo);
            assert_eq!((f.bits(), f.pdo_mappable()), (u32::from(bits), pdo));
        }
    }
    assert_eq!(EntryFlags::new(200, true).bits(), 0, "a size past 64 bits is none");
}

/// The limit rule as stated on `EntryInfo::low`/`high`: the value and the limits as 128-bit
/// numbers (unsigned types read their bits unsigned), BOOLEAN 0 or 1.
fn limit_rule(e: &od_runtime::od::EntryInfo, data: &[u8]) -> Result<(), od_runtime::od::AbortCode> {
    use od_runtime::od::{AbortCode, DataType};
    let v = od_runtime::od::decode_int(data, e.data_type.is_signed());
    if e.data_type == DataType::Boolean && v > 1 {
        return Err(AbortCode::INVALID_VALUE);
    }
    if e.high().is_some_and(|h| v > h) {
        return Err(AbortCode::VALUE_TOO_HIGH);
    }
    if e.low().is_some_and(|l| v < l) {
        return Err(AbortCode::VALUE_TOO_LOW);
    }
    Ok(())
}

proptest! {
    /// `check_value` compares in 64 bits; it must say what the 128-bit rule says, for every
    /// integer type, any limits and any value of the type's length.
    #[test]
    fn limit_checks_agree_with_the_128_bit_rule(
        t in 0usize..17,
        low in any::<i64>(),
        high in any::<i64>(),
        small in any::<bool>(),
        bytes in any::<[u8; 8]>(),
    ) {
        use od_runtime::od::{Access, DataType as D, DefaultValue, EntryExtras, EntryInfo, Limits};
        let types = [
            D::Boolean, D::Unsigned8, D::Unsigned16, D::Unsigned24, D::Unsigned32, D::Unsigned40,
            D::Unsigned48, D::Unsigned56, D::Unsigned64, D::Integer8, D::Integer16, D::Integer24,
            D::Integer32, D::Integer40, D::Integer48, D::Integer56, D::Integer64,
        ];
        let dt = types[t];
        // Limits near zero as often as anywhere, so that both outcomes occur.
        let (low, high) = if small { (low % 300, high % 300) } else { (low, high) };
        let limits: &'static Limits = Box::leak(Box::new(Limits { low, high }));
        let extras: &'static EntryExtras =
            Box::leak(Box::new(EntryExtras { bits: 0, default: DefaultValue::None, limits: Some(limits) }));
        for e in [EntryInfo::new(0x2000, 0, dt, Access::Rw, false), EntryInfo::new(0x2000, 0, dt, Access::Rw, false).with_extras(extras)] {
            let data = &bytes[..e.byte_len()];
            prop_assert_eq!(e.check_value(data), limit_rule(&e, data), "{:?} {:?}", dt, data);
        }
    }
}
