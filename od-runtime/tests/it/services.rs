//! SYNC, EMCY, heartbeat producer/consumer and node guarding.

use crate::common;
use common::*;
use od_runtime::Event;
use od_runtime::emcy::{REG_CURRENT, REG_VOLTAGE};

#[test]
fn sync_consumer_reports_counter() {
    let mut h = Harness::new();
    h.events();
    h.send("080");
    h.send("080 07");
    assert_eq!(h.events(), [Event::Sync { counter: None }, Event::Sync { counter: Some(7) }]);
    // Another COB-ID for SYNC.
    h.sdo_write_ok(0x1005, 0, &[0x85, 0, 0, 0]);
    h.events();
    h.send("080");
    assert!(h.events().is_empty());
    h.send("085");
    assert_eq!(h.events(), [Event::Sync { counter: None }]);
}

#[test]
fn sync_producer_with_counter_overflow() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1019, 0, &[3]);
    h.sdo_write_ok(0x1006, 0, &[0x10, 0x27, 0, 0]); // 10 ms
    h.sdo_write_ok(0x1005, 0, &[0x80, 0, 0, 0x40]); // producer
    assert_eq!(h.advance(10_000), ["080 01"]);
    assert!(h.advance(9_999).is_empty());
    assert_eq!(h.advance(1), ["080 02"]);
    h.start();
    // The device's own SYNC drives its synchronous TPDO2.
    assert_eq!(h.advance(10_000), ["080 03", "281 40 02 00 00 00 00"]);
    assert_eq!(h.advance(10_000), ["080 01", "281 40 02 00 00 00 00"]);
    // Without overflow value: no counter byte.
    h.sdo_write_ok(0x1006, 0, &[0, 0, 0, 0]);
    h.sdo_write_ok(0x1019, 0, &[0]);
    h.sdo_write_ok(0x1006, 0, &[0x10, 0x27, 0, 0]);
    assert_eq!(h.advance(10_000), ["080", "281 40 02 00 00 00 00"]);
    // Invalid overflow values.
    h.sdo_write_ok(0x1006, 0, &[0, 0, 0, 0]);
    assert_eq!(h.sdo_write_abort(0x1019, 0, &[1]), 0x0609_0030);
    assert_eq!(h.sdo_write_abort(0x1019, 0, &[241]), 0x0609_0030);
}

#[test]
fn emcy_error_register_and_history() {
    let mut h = Harness::new();
    h.dev.signal_error(0x2310, REG_CURRENT, [1, 2, 3, 4, 5]);
    assert_eq!(h.poll(), ["081 10 23 03 01 02 03 04 05"]);
    assert_eq!(h.od().get(0x1001, 0), 0x03);
    assert_eq!(h.od().get(0x1003, 0), 1);
    assert_eq!(h.od().get(0x1003, 1), 0x0201_2310);
    h.dev.signal_error(0x3210, REG_VOLTAGE, [0; 5]);
    assert_eq!(h.poll(), ["081 10 32 07 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x1003, 0), 2);
    assert_eq!(h.od().get(0x1003, 1), 0x3210);
    assert_eq!(h.od().get(0x1003, 2), 0x0201_2310);
    // Read over SDO: newest first.
    h.exchange("601 40 03 10 00 00 00 00 00", &["581 4F 03 10 00 02 00 00 00"]);
    h.exchange("601 40 03 10 01 00 00 00 00", &["581 43 03 10 01 10 32 00 00"]);
    // Only 0 may be written to sub0; it clears the history.
    assert_eq!(h.sdo_write_abort(0x1003, 0, &[1]), 0x0609_0030);
    assert_eq!(h.sdo_write_abort(0x1003, 1, &[0, 0, 0, 0]), 0x0601_0002);
    h.sdo_write_ok(0x1003, 0, &[0]);
    assert_eq!(h.od().get(0x1003, 0), 0);
    assert_eq!(h.od().get(0x1003, 1), 0);
    // Error reset.
    h.dev.reset_error(REG_CURRENT);
    assert_eq!(h.poll(), ["081 00 00 05 00 00 00 00 00"]);
    h.dev.reset_error(REG_VOLTAGE);
    assert_eq!(h.poll(), ["081 00 00 00 00 00 00 00 00"]);
    assert_eq!(h.dev.error_register(), 0);
}

#[test]
fn emcy_history_is_bounded() {
    let mut h = Harness::new();
    for i in 0..12u16 {
        h.dev.signal_error(0x5000 + i, 0, [0; 5]);
    }
    assert_eq!(h.od().get(0x1003, 0), 8);
    assert_eq!(h.od().get(0x1003, 1), 0x500B);
    assert_eq!(h.od().get(0x1003, 8), 0x5004);
    // The transmit queue keeps the 8 newest.
    let out = h.poll();
    assert_eq!(out.len(), 8);
    assert_eq!(out[0], "081 04 50 01 00 00 00 00 00");
}

#[test]
fn emcy_inhibit_time_and_cob_id() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1015, 0, &[100, 0]); // 10 ms
    h.dev.signal_error(0x5000, 0, [0; 5]);
    h.dev.signal_error(0x5001, 0, [0; 5]);
    assert_eq!(h.poll(), ["081 00 50 01 00 00 00 00 00"]);
    assert!(h.advance(9_999).is_empty());
    assert_eq!(h.advance(1), ["081 01 50 01 00 00 00 00 00"]);
    // Another COB-ID, then not valid.
    h.sdo_write_ok(0x1014, 0, &[0x90, 0, 0, 0]);
    h.dev.signal_error(0x5002, 0, [0; 5]);
    assert_eq!(h.advance(10_000), ["090 02 50 01 00 00 00 00 00"]);
    h.sdo_write_ok(0x1014, 0, &[0x90, 0, 0, 0x80]);
    h.dev.signal_error(0x5003, 0, [0; 5]);
    assert!(h.advance(10_000).is_empty());
}

#[test]
fn heartbeat_producer() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]); // 500 ms
    assert!(h.advance(499_999).is_empty());
    assert_eq!(h.advance(1), ["701 7F"]);
    assert_eq!(h.advance(500_000), ["701 7F"]);
    h.sdo_write_ok(0x1017, 0, &[0, 0]);
    assert!(h.advance(1_000_000).is_empty());
}

#[test]
fn heartbeat_consumer_timeout_and_recovery() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1016, 1, &[100, 0, 2, 0]); // node 2, 100 ms
    h.events();
    // Not monitored before the first heartbeat.
    assert!(h.advance(500_000).is_empty());
    assert!(h.events().is_empty());
    h.send("702 05");
    assert_eq!(h.events(), [Event::HeartbeatStarted { node: 2, state: 5 }]);
    h.advance(99_999);
    h.send("702 05");
    h.advance(99_999);
    assert!(h.events().is_empty());
    h.advance(1);
    assert_eq!(h.events(), [Event::HeartbeatTimeout { node: 2 }]);
    h.advance(1_000_000);
    assert!(h.events().is_empty());
    h.send("702 7F");
    assert_eq!(h.events(), [Event::HeartbeatStarted { node: 2, state: 0x7F }]);
    // Other nodes are not monitored; works in every NMT state.
    h.send("000 02 01");
    h.send("703 05");
    h.events();
    h.advance(100_000);
    assert_eq!(h.events(), [Event::HeartbeatTimeout { node: 2 }]);
}

#[test]
fn node_guarding_toggle_and_life_guarding() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x100C, 0, &[100, 0]); // 100 ms
    h.sdo_write_ok(0x100D, 0, &[3]);
    h.events();
    assert_eq!(h.send("701 R1"), ["701 7F"]);
    assert_eq!(h.send("701 R1"), ["701 FF"]);
    h.start();
    assert_eq!(h.send("701 R1"), ["701 05"]);
    assert_eq!(h.send("701 R1"), ["701 85"]);
    h.send("000 02 01");
    assert_eq!(h.send("701 R1"), ["701 04"]);
    h.events();
    // Life time = 3 × 100 ms.
    h.advance(299_999);
    assert!(h.events().is_empty());
    h.advance(1);
    assert_eq!(h.events(), [Event::LifeGuardingLost]);
    h.advance(1_000_000);
    assert!(h.events().is_empty());
    assert_eq!(h.send("701 R1"), ["701 84"]);
    assert_eq!(h.events(), [Event::LifeGuardingResumed]);
    // Reset communication restarts the toggle bit.
    assert_eq!(h.send("000 82 01"), ["701 00"]);
    assert_eq!(h.send("701 R1"), ["701 7F"]);
}

#[test]
fn node_guarding_is_off_while_heartbeat_runs() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[100, 0]);
    assert!(h.send("701 R1").is_empty());
}

/// The test dictionary declaring every optional service absent ([`ObjectDictionary::SERVICES`]),
/// though it has their objects: the runtime serves none of them.
struct Without(TestOd);

impl od_runtime::od::ObjectDictionary for Without {
    const SERVICES: od_runtime::od::Services =
        od_runtime::od::Services { sync: false, node_guarding: false, heartbeat_consumer: false, emcy_history: false };
    fn entries(&self) -> &'static [od_runtime::od::EntryInfo] {
        self.0.entries()
    }
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, od_runtime::od::AbortCode> {
        self.0.read(index, sub, buf)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), od_runtime::od::AbortCode> {
        self.0.write(index, sub, data)
    }
    fn restore_defaults(&mut self, area: od_runtime::od::Area, node_id: u8) {
        self.0.restore_defaults(area, node_id)
    }
}

#[derive(Default)]
struct Log(Vec<Event>);

impl<OD> od_runtime::App<OD> for Log {
    fn on_event(&mut self, _: &mut OD, e: Event) {
        self.0.push(e);
    }
}

#[test]
fn services_the_dictionary_declares_absent_are_not_served() {
    use od_runtime::od::ObjectDictionary;
    use od_runtime::{Device, NoStorage, NodeId};
    let mut dev = Device::new(Without(TestOd::new()), Log::default(), NoStorage, NodeId::new(1).unwrap());
    let mut sent = Vec::new();
    dev.poll(0, |f| sent.push(f.to_string()));
    assert_eq!(sent, ["701 00"], "boot-up");
    dev.write(0x100C, 0, &[100, 0]).unwrap();
    dev.write(0x100D, 0, &[3]).unwrap();
    dev.write(0x1016, 1, &[100, 0, 2, 0]).unwrap();
    dev.app_mut().0.clear();
    for f in ["080", "080 07", "701 R1", "702 05"] {
        dev.on_frame(&frame(f), 10);
    }
    sent.clear();
    dev.poll(1_000_000, |f| sent.push(f.to_string()));
    assert!(sent.is_empty(), "no guarding reply: {sent:?}");
    assert!(dev.app().0.is_empty(), "no SYNC, heartbeat or guarding event: {:?}", dev.app().0);
    dev.signal_error(0x1000, 0, [0; 5]);
    let mut b = [0u8; 4];
    assert_eq!(dev.od().read(0x1003, 0, &mut b), Ok(1));
    assert_eq!(b[0], 0, "no error history");
}
