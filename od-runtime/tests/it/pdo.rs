//! PDOs: reception, transmission types, SYNC, RTR, event timer, inhibit time, remapping.

use crate::common;
use common::*;
use od_runtime::od::{AbortCode, Area, EntryInfo, ObjectDictionary};
use od_runtime::{Device, Event, Micros, NoStorage, NodeId, WriteSource};

fn operational() -> Harness {
    let mut h = Harness::new();
    assert_eq!(h.start(), ["181 40 02 00"]);
    h.events();
    h
}

#[test]
fn rpdo_event_driven_applies_at_once() {
    let mut h = operational();
    // RPDO1: controlword (shutdown) + modes of operation 1. With CiA 402 the drive goes to
    // "ready to switch on" and displays the mode, which TPDO1 (event-driven) sends; without it
    // both are plain objects and nothing changes that TPDO1 maps.
    if cfg!(feature = "cia402") {
        assert_eq!(h.send("201 06 00 01"), ["181 31 02 01"]);
        assert_eq!(h.od().get(0x6061, 0), 1);
    } else {
        assert_eq!(h.send("201 06 00 01"), Vec::<String>::new());
        assert_eq!(h.od().get(0x6061, 0), 0);
    }
    assert_eq!(h.od().get(0x6040, 0), 6);
    let ev = h.events();
    assert!(ev.contains(&Event::Written { index: 0x6040, sub: 0, source: WriteSource::Rpdo(0) }));
    assert!(ev.contains(&Event::Written { index: 0x6060, sub: 0, source: WriteSource::Rpdo(0) }));
    // Longer than mapped: the mapped part is used.
    h.send("301 00 00 10 27 00 00 55 55");
    assert_eq!(h.od().get(0x607A, 0), 10_000);
    // RPDO3 is not valid (COB-ID bit 31).
    h.send("401 01 00 00 00");
    assert_eq!(h.od().get(0x60FF, 0), 0);
}

#[test]
fn rpdo_too_short_sends_emcy() {
    let mut h = operational();
    assert_eq!(h.send("301 06 00 01"), ["081 10 82 11 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x607A, 0), 0);
    assert_eq!(h.od().get(0x1001, 0), 0x11);
}

#[test]
fn rpdo_veto_skips_the_entry() {
    let mut h = operational();
    h.dev.app_mut().veto.push((0x6060, 0, od_runtime::od::AbortCode::INVALID_VALUE));
    h.send("201 06 00 03");
    assert_eq!(h.od().get(0x6040, 0), 6);
    assert_eq!(h.od().get(0x6060, 0), 0);
}

#[test]
fn synchronous_rpdo_waits_for_sync() {
    let mut h = operational();
    h.sdo_write_ok(0x1401, 2, &[1]);
    h.send("301 00 00 E8 03 00 00");
    assert_eq!(h.od().get(0x607A, 0), 0);
    h.send("080");
    assert_eq!(h.od().get(0x607A, 0), 1000);
}

#[test]
fn tpdo_on_every_sync() {
    let mut h = operational();
    h.dev.od_mut().set(0x6064, 0, 0x1234_5678);
    assert_eq!(h.send("080"), ["281 40 02 78 56 34 12"]);
    assert_eq!(h.send("080"), ["281 40 02 78 56 34 12"]);
    // Every 3rd SYNC.
    h.sdo_write_ok(0x1801, 2, &[3]);
    assert!(h.send("080").is_empty());
    assert!(h.send("080").is_empty());
    assert_eq!(h.send("080"), ["281 40 02 78 56 34 12"]);
    assert!(h.send("080").is_empty());
}

#[test]
fn sync_start_value() {
    let mut h = operational();
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0x80]);
    h.sdo_write_ok(0x1801, 2, &[2]);
    h.sdo_write_ok(0x1801, 6, &[3]);
    h.sdo_write_ok(0x1019, 0, &[5]);
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0]);
    assert!(h.send("080 01").is_empty());
    assert!(h.send("080 02").is_empty());
    // The SYNC with counter 3 is the first counted one; type 2 sends on the second.
    assert!(h.send("080 03").is_empty());
    assert_eq!(h.send("080 04"), ["281 40 02 00 00 00 00"]);
    assert!(h.send("080 05").is_empty());
    assert_eq!(h.send("080 01"), ["281 40 02 00 00 00 00"]);
}

#[test]
fn acyclic_synchronous_sends_on_sync_after_a_change() {
    let mut h = operational();
    h.sdo_write_ok(0x1801, 2, &[0]);
    assert_eq!(h.send("080"), ["281 40 02 00 00 00 00"]);
    assert!(h.send("080").is_empty());
    h.dev.od_mut().set(0x6064, 0, 5);
    assert!(h.poll().is_empty());
    assert_eq!(h.send("080"), ["281 40 02 05 00 00 00"]);
    assert!(h.send("080").is_empty());
    h.dev.request_tpdo(1);
    assert_eq!(h.send("080"), ["281 40 02 05 00 00 00"]);
}

#[test]
fn rtr_transmission_types() {
    let mut h = operational();
    // 253: sampled when the request arrives.
    h.sdo_write_ok(0x1801, 2, &[253]);
    h.dev.od_mut().set(0x6064, 0, 7);
    assert!(h.send("080").is_empty());
    assert_eq!(h.send("281 R6"), ["281 40 02 07 00 00 00"]);
    // 252: sampled at SYNC, sent on request.
    h.sdo_write_ok(0x1801, 2, &[252]);
    assert!(h.send("080").is_empty());
    h.dev.od_mut().set(0x6064, 0, 8);
    assert_eq!(h.send("281 R6"), ["281 40 02 07 00 00 00"]);
    h.send("080");
    assert_eq!(h.send("281 R6"), ["281 40 02 08 00 00 00"]);
    // RTR not allowed (bit 30).
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0x40]);
    assert!(h.send("281 R6").is_empty());
    // No PDO service outside operational.
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0]);
    h.send("000 80 01");
    assert!(h.send("281 R6").is_empty());
}

#[test]
fn event_timer_and_change_of_state() {
    let mut h = operational();
    h.sdo_write_ok(0x1800, 5, &[100, 0]);
    assert!(h.advance(99_000).is_empty());
    assert_eq!(h.advance(1_000), ["181 40 02 00"]);
    assert!(h.advance(50_000).is_empty());
    // A change goes out at once and restarts the timer.
    h.dev.od_mut().set(0x6061, 0, 3);
    assert_eq!(h.poll(), ["181 40 02 03"]);
    assert!(h.advance(99_000).is_empty());
    assert_eq!(h.advance(1_000), ["181 40 02 03"]);
}

#[test]
fn inhibit_time_delays_changes() {
    let mut h = operational();
    // 10 ms inhibit time (100 × 100 µs) may only be set while the PDO is not valid.
    h.exchange("601 2B 00 18 03 64 00 00 00", &["581 80 00 18 03 30 00 09 06"]);
    h.sdo_write_ok(0x1800, 1, &[0x81, 0x01, 0, 0x80]);
    h.sdo_write_ok(0x1800, 3, &[100, 0]);
    h.sdo_write_ok(0x1800, 1, &[0x81, 0x01, 0, 0]);
    // Valid again: the event-driven PDO is sent once.
    assert_eq!(h.extra, ["181 40 02 00"]);
    h.dev.od_mut().set(0x6061, 0, 1);
    assert!(h.advance(5_000).is_empty());
    h.dev.od_mut().set(0x6061, 0, 2);
    assert!(h.advance(4_999).is_empty());
    assert_eq!(h.advance(1), ["181 40 02 02"]);
}

#[test]
fn inhibited_synchronous_tpdo_goes_out_at_a_later_poll() {
    // TPDO2 (281h) is synchronous (type 1); a 10 ms inhibit time holds the second SYNC's
    // sample until polls without any SYNC or frame find the inhibit time over.
    let mut h = operational();
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0x80]);
    h.sdo_write_ok(0x1801, 3, &[100, 0]);
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0]);
    h.dev.od_mut().set(0x6064, 0, 1);
    assert_eq!(h.send("080"), ["281 40 02 01 00 00 00"]);
    h.dev.od_mut().set(0x6064, 0, 2);
    assert!(h.advance(1_000).is_empty());
    assert!(h.send("080").is_empty(), "the sample waits for the inhibit time");
    h.dev.od_mut().set(0x6064, 0, 3);
    assert!(h.advance(8_000).is_empty());
    // The sample taken at the SYNC, not the value at transmission.
    assert_eq!(h.advance(1_000), ["281 40 02 02 00 00 00"]);
    assert!(h.advance(20_000).is_empty(), "sent once");
    // An RTR answers at once (no inhibit check) and a pending SYNC sample still follows.
    h.sdo_write_ok(0x1801, 2, &[1]);
    assert_eq!(h.send("080"), ["281 40 02 03 00 00 00"]);
    h.dev.od_mut().set(0x6064, 0, 4);
    assert!(h.advance(1_000).is_empty());
    assert!(h.send("080").is_empty());
    assert_eq!(h.send("281 R6"), ["281 40 02 04 00 00 00"]);
    assert!(h.advance(5_000).is_empty());
    assert_eq!(h.advance(5_000), ["281 40 02 04 00 00 00"]);
    assert!(h.advance(20_000).is_empty());
}

#[test]
fn remapping_procedure_with_bit_granular_entries() {
    let mut h = operational();
    // Changing a valid PDO's mapping is refused.
    assert_eq!(h.sdo_write_abort(0x1A00, 0, &[0]), 0x0601_0000);
    // 1. invalidate, 2. sub0 = 0, 3. entries, 4. sub0 = n, 5. valid again.
    h.sdo_write_ok(0x1800, 1, &[0x81, 0x01, 0, 0x80]);
    // Entries cannot change while sub0 != 0.
    assert_eq!(h.sdo_write_abort(0x1A00, 1, &[0x01, 0x01, 0x04, 0x20]), 0x0601_0000);
    h.sdo_write_ok(0x1A00, 0, &[0]);
    h.sdo_write_ok(0x1A00, 1, &[0x01, 0x01, 0x04, 0x20]); // 2004h sub1, BOOLEAN, 1 bit
    h.sdo_write_ok(0x1A00, 2, &[0x01, 0x03, 0x04, 0x20]); // 2004h sub3, 1 bit
    h.sdo_write_ok(0x1A00, 3, &[0x08, 0x00, 0x05, 0x20]); // 2005h, INTEGER8 at bit 2
    h.sdo_write_ok(0x1A00, 4, &[0x10, 0x00, 0x41, 0x60]); // statusword at bit 10
    h.sdo_write_ok(0x1A00, 0, &[4]);
    h.dev.od_mut().set(0x2004, 1, 1);
    h.dev.od_mut().set(0x2004, 3, 0);
    h.dev.od_mut().set(0x2005, 0, -1);
    h.sdo_write_ok(0x1800, 1, &[0x81, 0x01, 0, 0]);
    // bits: 1, 0, FFh << 2, 0240h << 10 → 0x0009_03FD: 26 bits → 4 bytes.
    assert_eq!(h.extra, ["181 FD 03 09 00"]);
    h.dev.od_mut().set(0x2004, 3, 1);
    assert_eq!(h.poll(), ["181 FF 03 09 00"]);

    // RPDO with booleans and a dummy entry.
    h.sdo_write_ok(0x1402, 1, &[0x01, 0x04, 0, 0x80]);
    h.sdo_write_ok(0x1602, 0, &[0]);
    h.sdo_write_ok(0x1602, 1, &[0x01, 0x02, 0x04, 0x20]);
    // A dummy BOOLEAN with 3 bits does not match its type.
    assert_eq!(h.sdo_write_abort(0x1602, 2, &[0x03, 0x00, 0x01, 0x00]), 0x0604_0043);
    h.sdo_write_ok(0x1602, 2, &[0x08, 0x00, 0x05, 0x00]); // dummy UNSIGNED8
    h.sdo_write_ok(0x1602, 3, &[0x01, 0x04, 0x04, 0x20]);
    h.sdo_write_ok(0x1602, 0, &[3]);
    h.sdo_write_ok(0x1402, 1, &[0x01, 0x04, 0, 0]);
    // bit 0 → 2004h sub2, bits 1..8 skipped, bit 9 → 2004h sub4.
    h.send("401 03 02");
    assert_eq!(h.od().get(0x2004, 2), 1);
    assert_eq!(h.od().get(0x2004, 4), 1);
}

#[test]
fn mapping_abort_codes() {
    let mut h = operational();
    h.sdo_write_ok(0x1801, 1, &[0x81, 0x02, 0, 0x80]);
    h.sdo_write_ok(0x1A01, 0, &[0]);
    // Not mappable: no PDOMapping, or wrong direction.
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x10, 0x00, 0x07, 0x20]), 0x0604_0041);
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x20, 0x00, 0x06, 0x20]), 0x0604_0041);
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x08, 0x00, 0x05, 0x00]), 0x0604_0041);
    // Length differs from the object's.
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x08, 0x00, 0x41, 0x60]), 0x0604_0043);
    // Missing object / sub-index.
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x08, 0x00, 0x00, 0x30]), 0x0602_0000);
    assert_eq!(h.sdo_write_abort(0x1A01, 1, &[0x08, 0x09, 0x04, 0x20]), 0x0609_0011);
    // More than 64 bits.
    h.sdo_write_ok(0x1A01, 1, &[0x20, 0x00, 0x64, 0x60]);
    h.sdo_write_ok(0x1A01, 2, &[0x20, 0x00, 0x6C, 0x60]);
    h.sdo_write_ok(0x1A01, 3, &[0x10, 0x00, 0x41, 0x60]);
    assert_eq!(h.sdo_write_abort(0x1A01, 0, &[3]), 0x0604_0042);
    assert_eq!(h.sdo_write_abort(0x1A01, 0, &[9]), 0x0609_0031);
    h.sdo_write_ok(0x1A01, 0, &[2]);
    // An RPDO cannot map a read-only object.
    h.sdo_write_ok(0x1400, 1, &[0x01, 0x02, 0, 0x80]);
    h.sdo_write_ok(0x1600, 0, &[0]);
    assert_eq!(h.sdo_write_abort(0x1600, 1, &[0x10, 0x00, 0x41, 0x60]), 0x0604_0041);
    // COB-ID: changing the id of a valid PDO, 29-bit ids, restricted ids.
    assert_eq!(h.sdo_write_abort(0x1800, 1, &[0x82, 0x01, 0, 0]), 0x0609_0030);
    assert_eq!(h.sdo_write_abort(0x1801, 1, &[0x81, 0x02, 0, 0x20]), 0x0609_0030);
    assert_eq!(h.sdo_write_abort(0x1801, 1, &[0x81, 0x05, 0, 0]), 0x0609_0030);
    // Transmission types.
    assert_eq!(h.sdo_write_abort(0x1800, 2, &[241]), 0x0609_0030);
    assert_eq!(h.sdo_write_abort(0x1400, 2, &[252]), 0x0609_0030);
    h.sdo_write_ok(0x1800, 2, &[252]);
}

#[test]
fn pdo_count_follows_the_dictionary() {
    let mut h = operational();
    // TPDO4 (1803h, error register) becomes valid and sends on change.
    h.sdo_write_ok(0x1803, 1, &[0x81, 0x04, 0, 0]);
    assert_eq!(h.extra, ["481 00"]);
    h.dev.signal_error(0x3210, od_runtime::emcy::REG_VOLTAGE, [0; 5]);
    assert_eq!(h.poll(), ["081 10 32 05 00 00 00 00 00", "481 05"]);
}

#[test]
fn rpdo_deadline_monitoring() {
    let mut h = operational();
    h.sdo_write_ok(0x1400, 5, &[50, 0]); // 50 ms
    h.events();
    // Not monitored before the first reception.
    h.advance(200_000);
    assert!(h.events().is_empty());
    h.send("201 06 00 01");
    h.events();
    h.advance(49_999);
    assert!(h.events().is_empty());
    h.advance(1);
    assert_eq!(h.events(), [Event::RpdoTimeout { pdo: 0 }]);
    h.advance(100_000);
    assert!(h.events().is_empty());
    h.send("201 06 00 01");
    h.events();
    h.advance(50_000);
    assert_eq!(h.events(), [Event::RpdoTimeout { pdo: 0 }]);
}

#[test]
fn a_mapping_longer_than_the_device_keeps_is_refused() {
    use od_runtime::{Device, NodeId};
    // Room for 3 mapped entries per PDO (MAP = 3), as a generated `Device` type sizes it.
    let mut dev: Device<TestOd, Recorder, MemStorage, 1024, 8, 3> =
        Device::with_capacity(TestOd::new(), Recorder::default(), MemStorage::default(), NodeId::new(NODE).unwrap());
    let mut sdo = |index: u16, sub: u8, data: &[u8]| {
        let mut b = vec![0x23 | ((4 - data.len() as u8) << 2), index as u8, (index >> 8) as u8, sub];
        b.extend_from_slice(data);
        b.resize(8, 0);
        dev.on_frame(&frame(&format!("601 {}", hex(&b))), 0);
        let mut out = Vec::new();
        dev.poll(0, |f| out.push(f.to_string()));
        out.into_iter().find(|f| f.starts_with("581 ")).unwrap()
    };
    sdo(0x1800, 1, &[0x81, 0x01, 0, 0x80]);
    sdo(0x1A00, 0, &[0]);
    for k in 1..=4u8 {
        assert!(sdo(0x1A00, k, &[0x01, k, 0x04, 0x20]).starts_with("581 60"), "entry {k}");
    }
    assert_eq!(abort_code(&sdo(0x1A00, 0, &[4])), Some(0x0609_0031), "4 entries > MAP");
    assert!(sdo(0x1A00, 0, &[3]).starts_with("581 60"));
    assert!(sdo(0x1800, 1, &[0x81, 0x01, 0, 0]).starts_with("581 60"), "valid again with 3 entries");
}

/// [`TestOd`] with the rule of a device that remaps a PDO while it stays valid (the Kollmorgen
/// AKD's): what a hand-written dictionary declares, as a generated one does from its sidecar.
#[derive(Clone, Default)]
struct WhileValidOd(TestOd);

impl ObjectDictionary for WhileValidOd {
    const PDO_REMAPPING: od_runtime::pdo::Remapping = od_runtime::pdo::Remapping::WhileValid;

    fn entries(&self) -> &'static [EntryInfo] {
        self.0.entries()
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.0.read(index, sub, buf)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.0.write(index, sub, data)
    }

    fn restore_defaults(&mut self, area: Area, node_id: u8) {
        self.0.restore_defaults(area, node_id)
    }
}

#[test]
fn a_dictionary_with_the_while_valid_rule_remaps_a_valid_pdo() {
    assert_eq!(<TestOd as ObjectDictionary>::PDO_REMAPPING, od_runtime::pdo::Remapping::Cia301, "the default");
    let mut dev = Device::new(WhileValidOd(TestOd::new()), (), NoStorage, NodeId::new(NODE).unwrap());
    let mut now = 0;
    let exchange = |dev: &mut Device<WhileValidOd, ()>, now: &mut Micros, req: &str| {
        *now += 1000;
        dev.on_frame(&frame(req), *now);
        let mut out = Vec::new();
        dev.poll(*now, |f| out.push(f.to_string()));
        out.retain(|f| !f.starts_with("701"));
        out
    };
    exchange(&mut dev, &mut now, "000 01 01");
    // TPDO1 (181h, valid, event-driven) remapped without touching its COB-ID: sub 0 = 0 takes
    // it off the bus, an entry is refused while sub 0 is not 0, sub 0 = n checks the mapping.
    assert_eq!(exchange(&mut dev, &mut now, "601 23 00 1A 01 20 00 64 60"), ["581 80 00 1A 01 00 00 01 06"]);
    assert_eq!(exchange(&mut dev, &mut now, "601 2F 00 1A 00 00 00 00 00"), ["581 60 00 1A 00 00 00 00 00"]);
    assert_eq!(exchange(&mut dev, &mut now, "601 23 00 1A 01 20 00 64 60"), ["581 60 00 1A 01 00 00 00 00"]);
    assert_eq!(exchange(&mut dev, &mut now, "601 23 00 1A 02 20 00 64 60"), ["581 60 00 1A 02 00 00 00 00"]);
    assert_eq!(exchange(&mut dev, &mut now, "601 23 00 1A 03 10 00 41 60"), ["581 60 00 1A 03 00 00 00 00"]);
    // 80 bits: refused when sub 0 is written (0604 0042h); two entries fit.
    assert_eq!(exchange(&mut dev, &mut now, "601 2F 00 1A 00 03 00 00 00"), ["581 80 00 1A 00 42 00 04 06"]);
    // Active again, the event-driven TPDO1 sends its new mapping (6064h twice).
    assert_eq!(
        exchange(&mut dev, &mut now, "601 2F 00 1A 00 02 00 00 00"),
        ["581 60 00 1A 00 00 00 00 00", "181 00 00 00 00 00 00 00 00"]
    );
    // The valid TPDO1 takes a new CAN-ID at once (and sends on it); a restricted one is still
    // refused.
    assert_eq!(
        exchange(&mut dev, &mut now, "601 23 00 18 01 81 02 00 00"),
        ["581 60 00 18 01 00 00 00 00", "281 00 00 00 00 00 00 00 00"]
    );
    assert_eq!(exchange(&mut dev, &mut now, "601 23 00 18 01 01 07 00 00"), ["581 80 00 18 01 30 00 09 06"]);
    // Event-driven: the new mapping goes out on 281h when 6064h changes.
    dev.od_mut().0.set(0x6064, 0, 0x0102_0304);
    now += 1000;
    let mut out = Vec::new();
    dev.poll(now, |f| out.push(f.to_string()));
    assert_eq!(out, ["281 04 03 02 01 04 03 02 01"]);
}
