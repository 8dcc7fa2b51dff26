//! The LSS slave (CiA 305), frame by frame against the command specifiers. The test
//! dictionary's identity: vendor 0ABCh, product 0402h, revision 0001_0000h, serial 12345
//! (3039h).

use crate::common;
use common::*;
use od_runtime::lss::{self, Identity, LssConfig, Mode};
use od_runtime::{Device, Event, NmtState, NoStorage, NodeId};

const ID: Identity = Identity { vendor: 0xABC, product: 0x402, revision: 0x1_0000, serial: 12345 };

/// A device with LSS on: `node` `None` starts without a node-ID.
fn lss_harness(node: Option<u8>, storage: MemStorage) -> Harness {
    let mut dev = Device::new(TestOd::new(), Recorder::default(), storage, NodeId::new(NODE).unwrap());
    dev.enable_lss(node.and_then(NodeId::new));
    Harness { dev, now: 0, extra: Vec::new() }
}

fn switch_selective(h: &mut Harness, id: &Identity) -> Vec<String> {
    let mut out = Vec::new();
    for (cs, v) in [(0x40u8, id.vendor), (0x41, id.product), (0x42, id.revision), (0x43, id.serial)] {
        let b = v.to_le_bytes();
        out.extend(h.send(&format!("7E5 {cs:02X} {} 00 00 00", hex(&b))));
    }
    out
}

#[test]
fn an_unconfigured_device_sends_nothing_and_ignores_nmt_and_sdo() {
    let mut h = lss_harness(None, MemStorage::default());
    assert_eq!(h.poll(), Vec::<String>::new(), "no boot-up without a node-ID");
    assert_eq!(h.dev.active_node_id(), None);
    assert_eq!(h.dev.nmt_state(), NmtState::Initialising);
    assert!(h.send("000 01 00").is_empty());
    assert_eq!(h.dev.nmt_state(), NmtState::Initialising);
    assert!(h.send("6FF 40 18 10 01 00 00 00 00").is_empty());
    assert!(h.send("601 40 18 10 01 00 00 00 00").is_empty());
    assert!(h.advance(10_000_000).is_empty());
}

#[test]
fn configure_node_id_then_waiting_boots_with_it() {
    let mut h = lss_harness(None, MemStorage::default());
    assert!(h.poll().is_empty());
    // Configure in waiting: ignored.
    assert!(h.send("7E5 11 05 00 00 00 00 00 00").is_empty());
    assert!(h.send("7E5 04 01 00 00 00 00 00 00").is_empty());
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Configuration);
    h.exchange("7E5 11 05 00 00 00 00 00 00", &["7E4 11 00 00 00 00 00 00 00"]);
    // Still without a node-ID until the switch back to waiting.
    h.exchange("7E5 5E 00 00 00 00 00 00 00", &["7E4 5E FF 00 00 00 00 00 00"]);
    h.exchange("7E5 04 00 00 00 00 00 00 00", &["705 00"]);
    assert_eq!(h.dev.active_node_id(), NodeId::new(5));
    assert_eq!(h.dev.node_id().get(), 5);
    assert_eq!(h.dev.nmt_state(), NmtState::PreOperational);
    // The SDO server and NMT run on the new node-ID.
    h.exchange("605 40 18 10 04 00 00 00 00", &["585 43 18 10 04 39 30 00 00"]);
    h.send("000 01 05");
    assert_eq!(h.dev.nmt_state(), NmtState::Operational);
}

#[test]
fn configure_node_id_out_of_range_is_refused() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    assert_eq!(h.poll(), ["703 00"]);
    h.send("7E5 04 01 00 00 00 00 00 00");
    for bad in ["00", "80", "FE"] {
        h.exchange(&format!("7E5 11 {bad} 00 00 00 00 00 00"), &["7E4 11 01 00 00 00 00 00 00"]);
    }
    assert_eq!(h.dev.lss().unwrap().pending_node_id(), 3);
}

#[test]
fn a_configured_device_takes_its_new_node_id_at_reset_communication() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    assert_eq!(h.poll(), ["703 00"]);
    h.send("7E5 04 01 00 00 00 00 00 00");
    h.exchange("7E5 11 07 00 00 00 00 00 00", &["7E4 11 00 00 00 00 00 00 00"]);
    assert!(h.send("7E5 04 00 00 00 00 00 00 00").is_empty(), "a device with a node-ID keeps it until a reset");
    h.exchange("7E5 04 01 00 00 00 00 00 00", &[]);
    h.exchange("7E5 5E 00 00 00 00 00 00 00", &["7E4 5E 03 00 00 00 00 00 00"]);
    h.send("7E5 04 00 00 00 00 00 00 00");
    assert_eq!(h.send("000 82 03"), ["707 00"]);
    assert_eq!(h.dev.active_node_id(), NodeId::new(7));
}

#[test]
fn switch_selective_answers_only_the_full_identity_in_order() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    h.poll();
    assert_eq!(switch_selective(&mut h, &ID), ["7E4 44 00 00 00 00 00 00 00"]);
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Configuration);
    h.send("7E5 04 00 00 00 00 00 00 00");
    // One part off: no answer, still waiting.
    for wrong in [
        Identity { serial: 12346, ..ID },
        Identity { vendor: 1, ..ID },
        Identity { product: 1, ..ID },
        Identity { revision: 1, ..ID },
    ] {
        assert!(switch_selective(&mut h, &wrong).is_empty(), "{wrong}");
        assert_eq!(h.dev.lss().unwrap().mode(), Mode::Waiting);
    }
    // Out of order (serial before revision): no answer.
    h.send("7E5 40 BC 0A 00 00 00 00 00");
    h.send("7E5 41 02 04 00 00 00 00 00");
    assert!(h.send("7E5 43 39 30 00 00 00 00 00").is_empty());
    assert!(h.send("7E5 42 00 00 01 00 00 00 00").is_empty());
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Waiting);
}

#[test]
fn inquire_identity_and_node_id() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    h.poll();
    // Waiting: inquiries are not served.
    assert!(h.send("7E5 5A 00 00 00 00 00 00 00").is_empty());
    h.send("7E5 04 01 00 00 00 00 00 00");
    h.exchange("7E5 5A 00 00 00 00 00 00 00", &["7E4 5A BC 0A 00 00 00 00 00"]);
    h.exchange("7E5 5B 00 00 00 00 00 00 00", &["7E4 5B 02 04 00 00 00 00 00"]);
    h.exchange("7E5 5C 00 00 00 00 00 00 00", &["7E4 5C 00 00 01 00 00 00 00"]);
    h.exchange("7E5 5D 00 00 00 00 00 00 00", &["7E4 5D 39 30 00 00 00 00 00"]);
    h.exchange("7E5 5E 00 00 00 00 00 00 00", &["7E4 5E 03 00 00 00 00 00 00"]);
    // Frames of another length and unknown specifiers are ignored.
    assert!(h.send("7E5 5A").is_empty());
    assert!(h.send("7E5 99 00 00 00 00 00 00 00").is_empty());
}

#[test]
fn bit_timing_from_the_cia305_table_then_activate() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    h.poll();
    h.send("7E5 04 01 00 00 00 00 00 00");
    // Index 5 is reserved, 9 (automatic) not offered, 10 beyond the table, selector 1 unknown.
    for bad in ["00 05", "00 09", "00 0A", "01 00"] {
        h.exchange(&format!("7E5 13 {bad} 00 00 00 00 00"), &["7E4 13 01 00 00 00 00 00 00"]);
    }
    h.events();
    h.exchange("7E5 15 64 00 00 00 00 00 00", &[]);
    assert!(!h.events().iter().any(|e| matches!(e, Event::LssBitTiming { .. })), "nothing configured");
    h.exchange("7E5 13 00 03 00 00 00 00 00", &["7E4 13 00 00 00 00 00 00 00"]);
    h.exchange("7E5 15 64 00 00 00 00 00 00", &[]);
    assert!(h.events().contains(&Event::LssBitTiming { index: 3, delay_ms: 100 }));
    assert_eq!(h.dev.lss().unwrap().bit_rate(), Some(3));
    assert_eq!(lss::bit_rate_kbit(3), Some(250));
}

#[test]
fn store_configuration_survives_a_power_cycle() {
    let mut h = lss_harness(None, MemStorage::default());
    h.poll();
    h.send("7E5 04 01 00 00 00 00 00 00");
    h.exchange("7E5 11 09 00 00 00 00 00 00", &["7E4 11 00 00 00 00 00 00 00"]);
    h.exchange("7E5 13 00 02 00 00 00 00 00", &["7E4 13 00 00 00 00 00 00 00"]);
    h.exchange("7E5 17 00 00 00 00 00 00 00", &["7E4 17 00 00 00 00 00 00 00"]);
    let storage = h.dev.storage_mut().clone();
    assert_eq!(storage.lss, Some(LssConfig { node_id: 9, bit_rate: Some(2) }));
    // Power cycle: made without a node-ID, starts with the stored one.
    let mut h = lss_harness(None, storage);
    assert_eq!(h.poll(), ["709 00"]);
    assert_eq!(h.dev.lss().unwrap().bit_rate(), Some(2));
}

#[test]
fn store_errors_say_not_supported_or_storage_failed() {
    let mut dev = Device::new(TestOd::new(), Recorder::default(), NoStorage, NodeId::new(2).unwrap());
    dev.enable_lss(NodeId::new(2));
    let mut out = Vec::new();
    dev.poll(0, |_| {});
    dev.on_frame(&frame("7E5 04 01 00 00 00 00 00 00"), 0);
    dev.on_frame(&frame("7E5 17 00 00 00 00 00 00 00"), 0);
    dev.poll(0, |f| out.push(f.to_string()));
    assert_eq!(out, ["7E4 17 01 00 00 00 00 00 00"]);
    let mut failing = MemStorage::default();
    failing.fail = true;
    let mut h = lss_harness(Some(2), failing);
    h.poll();
    h.send("7E5 04 01 00 00 00 00 00 00");
    h.exchange("7E5 17 00 00 00 00 00 00 00", &["7E4 17 02 00 00 00 00 00 00"]);
}

#[test]
fn unconfigure_store_and_reset_leaves_the_device_without_a_node_id() {
    let mut h = lss_harness(Some(1), MemStorage::default());
    assert_eq!(h.poll(), ["701 00"]);
    h.send("7E5 04 01 00 00 00 00 00 00");
    h.exchange("7E5 11 FF 00 00 00 00 00 00", &["7E4 11 00 00 00 00 00 00 00"]);
    h.exchange("7E5 17 00 00 00 00 00 00 00", &["7E4 17 00 00 00 00 00 00 00"]);
    h.send("7E5 04 00 00 00 00 00 00 00");
    assert!(h.send("000 81 00").is_empty(), "reset node: no boot-up without a node-ID");
    assert_eq!(h.dev.active_node_id(), None);
    let storage = h.dev.storage_mut().clone();
    let mut h = lss_harness(Some(1), storage);
    assert!(h.poll().is_empty(), "power cycle: the stored FFh wins over the node-ID made with");
}

#[test]
fn identify_remote_slave_by_ranges() {
    let mut h = lss_harness(Some(3), MemStorage::default());
    h.poll();
    let ask = |h: &mut Harness, rev: (u32, u32), serial: (u32, u32)| {
        let mut out = Vec::new();
        for (cs, v) in
            [(0x46u8, 0xABC), (0x47, 0x402), (0x48, rev.0), (0x49, rev.1), (0x4A, serial.0), (0x4B, serial.1)]
        {
            let b: [u8; 4] = u32::to_le_bytes(v);
            out.extend(h.send(&format!("7E5 {cs:02X} {} 00 00 00", hex(&b))));
        }
        out
    };
    assert_eq!(ask(&mut h, (0, u32::MAX), (0, u32::MAX)), ["7E4 4F 00 00 00 00 00 00 00"]);
    assert_eq!(ask(&mut h, (0x1_0000, 0x1_0000), (12345, 12345)), ["7E4 4F 00 00 00 00 00 00 00"]);
    assert!(ask(&mut h, (0, 0xFFFF), (0, u32::MAX)).is_empty());
    assert!(ask(&mut h, (0, u32::MAX), (12346, 20000)).is_empty());
    // Identify non-configured: only a device without a node-ID answers.
    assert!(h.send("7E5 4C 00 00 00 00 00 00 00").is_empty());
    let mut u = lss_harness(None, MemStorage::default());
    u.poll();
    u.exchange("7E5 4C 00 00 00 00 00 00 00", &["7E4 50 00 00 00 00 00 00 00"]);
}

/// One fastscan request: (ID number, bit checked, LSS sub, LSS next).
fn fastscan(h: &mut Harness, id: u32, bit: u8, sub: u8, next: u8) -> bool {
    let b = id.to_le_bytes();
    let out = h.send(&format!("7E5 51 {} {bit:02X} {sub:02X} {next:02X}", hex(&b)));
    match out.as_slice() {
        [] => false,
        [a] if a == "7E4 4F 00 00 00 00 00 00 00" => true,
        other => panic!("fastscan answered {other:?}"),
    }
}

#[test]
fn fastscan_finds_the_identity_bit_by_bit() {
    let mut h = lss_harness(None, MemStorage::default());
    h.poll();
    assert!(fastscan(&mut h, 0, 0x80, 0, 0), "the reset step is answered by every unconfigured device");
    let mut found = [0u32; 4];
    for sub in 0..4u8 {
        let mut id = 0u32;
        for bit in (0..32u8).rev() {
            if !fastscan(&mut h, id, bit, sub, sub) {
                id |= 1 << bit;
            }
        }
        assert!(fastscan(&mut h, id, 0, sub, (sub + 1) & 3), "confirmation of part {sub}");
        found[usize::from(sub)] = id;
    }
    assert_eq!(found, ID.parts());
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Configuration);
    // Found and in configuration: it takes no part in the next scan.
    assert!(!fastscan(&mut h, 0, 0x80, 0, 0));
    h.exchange("7E5 11 04 00 00 00 00 00 00", &["7E4 11 00 00 00 00 00 00 00"]);
    h.exchange("7E5 04 00 00 00 00 00 00 00", &["704 00"]);
    assert!(!fastscan(&mut h, 0, 0x80, 0, 0), "a device with a node-ID takes no part");
}

#[test]
fn fastscan_with_known_parts_and_out_of_step_requests() {
    let mut h = lss_harness(None, MemStorage::default());
    h.poll();
    assert!(fastscan(&mut h, 0, 0x80, 0, 0));
    // A request for a later part before this one is confirmed: ignored.
    assert!(!fastscan(&mut h, 0x402, 0, 1, 2));
    assert!(fastscan(&mut h, 0xABC, 0, 0, 1));
    assert!(!fastscan(&mut h, 0xABD, 0, 1, 2), "a wrong product");
    assert!(fastscan(&mut h, 0x402, 0, 1, 2));
    assert!(fastscan(&mut h, 0x1_0000, 0, 2, 3));
    // LSS next equal to LSS sub: a check of the same part again, not the end.
    assert!(fastscan(&mut h, 12345, 0, 3, 3));
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Waiting);
    assert!(fastscan(&mut h, 12345, 0, 3, 0));
    assert_eq!(h.dev.lss().unwrap().mode(), Mode::Configuration);
    // Bit numbers beyond 31 and parts beyond 3 are ignored.
    let mut h = lss_harness(None, MemStorage::default());
    h.poll();
    assert!(!fastscan(&mut h, 0, 32, 0, 0));
    assert!(!fastscan(&mut h, 0, 0, 4, 0));
    // A device with a node-ID takes no part at all.
    let mut h = lss_harness(Some(3), MemStorage::default());
    h.poll();
    assert!(!fastscan(&mut h, 0, 0x80, 0, 0));
}

#[test]
fn lss_is_off_for_a_dictionary_without_it() {
    let mut h = Harness::new();
    assert!(h.send("7E5 04 01 00 00 00 00 00 00").is_empty());
    assert!(h.send("7E5 5E 00 00 00 00 00 00 00").is_empty());
    assert!(h.dev.lss().is_none());
}
