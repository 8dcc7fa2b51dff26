//! NMT slave: boot-up, state transitions, node addressing, resets, services per state.

use crate::common;
use common::*;
use od_runtime::{Event, NmtState, ResetKind};

#[test]
fn boot_up_then_pre_operational() {
    let mut h = Harness::new();
    assert_eq!(h.dev.nmt_state(), NmtState::PreOperational);
    let ev = h.events();
    assert!(ev.contains(&Event::Reset(ResetKind::Node)));
    assert!(ev.contains(&Event::Nmt { from: NmtState::Initialising, to: NmtState::PreOperational }));
    // No second boot-up.
    assert!(h.advance(1000).is_empty());
}

#[test]
fn start_stop_pre_operational() {
    let mut h = Harness::new();
    h.events();
    // Start: the event-driven TPDO1 goes out once (statusword 0240h, mode display 0).
    assert_eq!(h.start(), ["181 40 02 00"]);
    assert_eq!(h.dev.nmt_state(), NmtState::Operational);
    assert_eq!(h.events(), [Event::Nmt { from: NmtState::PreOperational, to: NmtState::Operational }]);
    assert!(h.send("000 02 01").is_empty());
    assert_eq!(h.dev.nmt_state(), NmtState::Stopped);
    assert!(h.send("000 80 01").is_empty());
    assert_eq!(h.dev.nmt_state(), NmtState::PreOperational);
    // Broadcast (node 0).
    h.send("000 01 00");
    assert_eq!(h.dev.nmt_state(), NmtState::Operational);
    // Another node's command, unknown commands and short frames are ignored.
    h.send("000 02 02");
    h.send("000 03 01");
    h.send("000 02");
    h.send("000");
    assert_eq!(h.dev.nmt_state(), NmtState::Operational);
    // Stopped from pre-operational, operational from stopped.
    h.send("000 80 00");
    h.send("000 02 00");
    assert_eq!(h.dev.nmt_state(), NmtState::Stopped);
    h.send("000 01 01");
    assert_eq!(h.dev.nmt_state(), NmtState::Operational);
}

#[test]
fn heartbeat_state_bytes() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[100, 0]);
    assert_eq!(h.advance(100_000), ["701 7F"]);
    h.start();
    assert_eq!(h.advance(100_000), ["701 05"]);
    h.send("000 02 01");
    assert_eq!(h.advance(100_000), ["701 04"]);
}

#[test]
fn reset_communication_restores_only_communication_objects() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[100, 0]);
    h.sdo_write_ok(0x607A, 0, &[1, 2, 3, 4]);
    h.start();
    h.events();
    assert_eq!(h.send("000 82 01"), ["701 00"]);
    assert_eq!(h.dev.nmt_state(), NmtState::PreOperational);
    assert_eq!(h.od().get(0x1017, 0), 0);
    assert_eq!(h.od().get(0x607A, 0), 0x0403_0201);
    let ev = h.events();
    assert!(ev.contains(&Event::Reset(ResetKind::Communication)));
    assert!(ev.contains(&Event::Nmt { from: NmtState::Operational, to: NmtState::Initialising }));
    // The heartbeat producer is off again.
    assert!(h.advance(500_000).is_empty());
}

#[test]
fn reset_node_restores_every_area() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[100, 0]);
    h.sdo_write_ok(0x607A, 0, &[1, 2, 3, 4]);
    h.sdo_write_ok(0x2001, 0, b"xy");
    assert_eq!(h.send("000 81 00"), ["701 00"]);
    assert_eq!(h.od().get(0x1017, 0), 0);
    assert_eq!(h.od().get(0x607A, 0), 0);
    assert_eq!(h.od().bytes(0x2001, 0), b"axis");
    // Node id resolved in the defaults.
    assert_eq!(h.od().get(0x1014, 0), 0x81);
    assert_eq!(h.od().get(0x1800, 1), 0x181);
}

#[test]
fn reset_aborts_a_transfer_in_progress() {
    let mut h = Harness::new();
    h.exchange("601 40 08 10 00 00 00 00 00", &["581 41 08 10 00 15 00 00 00"]);
    h.send("000 82 01");
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 80 00 00 00 01 00 04 05"]);
}

#[test]
fn services_per_state() {
    let mut h = Harness::new();
    // Pre-operational: SDO and EMCY yes, PDO no.
    h.dev.signal_error(0x5000, 0, [0; 5]);
    assert_eq!(h.poll(), ["081 00 50 01 00 00 00 00 00"]);
    assert!(h.send("201 0F 00 03").is_empty());
    assert_eq!(h.od().get(0x6040, 0), 0);
    assert!(h.send("181 R2").is_empty());
    // Stopped: no SDO, no EMCY (held back), no SYNC processing, no PDO.
    h.start();
    h.send("000 02 01");
    assert!(h.send("601 40 00 10 00 00 00 00 00").is_empty());
    h.dev.signal_error(0x5001, 0, [0; 5]);
    assert!(h.poll().is_empty());
    h.events();
    assert!(h.send("080").is_empty());
    assert!(h.events().is_empty());
    assert!(h.send("201 0F 00 03").is_empty());
    assert_eq!(h.od().get(0x6040, 0), 0);
    // Back to pre-operational: the held EMCY goes out.
    assert_eq!(h.send("000 80 01"), ["081 01 50 01 00 00 00 00 00"]);
}
