//! Store (1010h) and restore (1011h) parameters through the storage trait.

use crate::common;
use common::*;
#[cfg(feature = "store")]
use od_runtime::{Device, NoStorage, NodeId};

const SAVE: [u8; 4] = *b"save";
#[cfg(feature = "store")]
const LOAD: [u8; 4] = *b"load";

#[test]
#[cfg(feature = "store")]
fn store_all_then_reset_node_loads_stored_values() {
    let mut h = Harness::new();
    h.exchange("601 40 10 10 01 00 00 00 00", &["581 43 10 10 01 01 00 00 00"]);
    h.sdo_write_ok(0x607A, 0, &[0xE8, 0x03, 0, 0]);
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]);
    h.sdo_write_ok(0x2001, 0, b"ax1");
    h.exchange("601 23 10 10 01 73 61 76 65", &["581 60 10 10 01 00 00 00 00"]);
    assert_eq!(h.dev.storage_mut().saves, 3);
    h.sdo_write_ok(0x607A, 0, &[0, 0, 0, 0]);
    h.sdo_write_ok(0x1017, 0, &[0, 0]);
    h.send("000 81 01");
    assert_eq!(h.od().get(0x607A, 0), 1000);
    assert_eq!(h.od().get(0x1017, 0), 500);
    assert_eq!(h.od().bytes(0x2001, 0), b"ax1");
    // Read-only and DOMAIN entries are not in the image.
    let comm = &h.dev.storage_mut().images[&1];
    assert!(comm.iter().all(|(i, _, _)| *i != 0x1000 && *i != 0x1003 && *i != 0x1010));
    let mfr = &h.dev.storage_mut().images[&3];
    assert!(mfr.iter().all(|(i, _, _)| *i != 0x2003));
    // The stored heartbeat is active after the reset.
    assert_eq!(h.advance(500_000), ["701 7F"]);
}

#[test]
#[cfg(feature = "store")]
fn store_one_area() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x607A, 0, &[5, 0, 0, 0]);
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]);
    h.sdo_write_ok(0x1010, 2, &SAVE);
    h.send("000 81 01");
    assert_eq!(h.od().get(0x1017, 0), 500);
    assert_eq!(h.od().get(0x607A, 0), 0);
    h.sdo_write_ok(0x607A, 0, &[5, 0, 0, 0]);
    h.sdo_write_ok(0x1010, 3, &SAVE);
    h.send("000 81 01");
    assert_eq!(h.od().get(0x607A, 0), 5);
}

#[test]
#[cfg(feature = "store")]
fn restore_defaults_takes_effect_at_the_next_reset() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x607A, 0, &[5, 0, 0, 0]);
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]);
    h.sdo_write_ok(0x1010, 1, &SAVE);
    h.exchange("601 23 11 10 01 6C 6F 61 64", &["581 60 11 10 01 00 00 00 00"]);
    // Nothing changes now.
    assert_eq!(h.od().get(0x607A, 0), 5);
    assert_eq!(h.od().get(0x1017, 0), 500);
    h.send("000 81 01");
    assert_eq!(h.od().get(0x607A, 0), 0);
    assert_eq!(h.od().get(0x1017, 0), 0);
    // Restore of one area keeps the others' stored values.
    h.sdo_write_ok(0x607A, 0, &[5, 0, 0, 0]);
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]);
    h.sdo_write_ok(0x1010, 1, &SAVE);
    h.sdo_write_ok(0x1011, 2, &LOAD);
    h.send("000 81 01");
    assert_eq!(h.od().get(0x607A, 0), 5);
    assert_eq!(h.od().get(0x1017, 0), 0);
}

#[test]
#[cfg(feature = "store")]
fn signatures_and_failures() {
    let mut h = Harness::new();
    assert_eq!(h.sdo_write_abort(0x1010, 1, b"SAVE"), 0x0800_0020);
    assert_eq!(h.sdo_write_abort(0x1011, 1, &SAVE), 0x0800_0020);
    assert_eq!(h.sdo_write_abort(0x1010, 1, &[0x73, 0x61]), 0x0607_0013);
    assert_eq!(h.sdo_write_abort(0x1010, 5, &SAVE), 0x0609_0011);
    h.dev.storage_mut().fail = true;
    assert_eq!(h.sdo_write_abort(0x1010, 1, &SAVE), 0x0606_0000);
    // Without storage, saving is refused.
    let mut dev = Device::new(TestOd::new(), (), NoStorage, NodeId::new(1).unwrap());
    let mut out = Vec::new();
    dev.poll(0, |f| out.push(f.to_string()));
    dev.on_frame(&frame("601 23 10 10 01 73 61 76 65"), 1);
    dev.poll(1, |f| out.push(f.to_string()));
    assert_eq!(out, ["701 00", "581 80 10 10 01 20 00 00 08"]);
}

#[test]
#[cfg(feature = "store")]
fn stored_values_survive_a_new_device() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x6060, 0, &[3]);
    h.sdo_write_ok(0x1010, 1, &SAVE);
    let storage = h.dev.storage_mut().clone();
    let h2 = Harness::with_storage(storage);
    assert_eq!(h2.od().get(0x6060, 0), 3);
}

/// Without the `store` feature nothing is ever saved: "save" is refused with 0800 0020h (as by a
/// device without storage), "load" is accepted and changes nothing, a reset keeps the defaults,
/// and the storage is never touched.
#[test]
#[cfg(not(feature = "store"))]
fn without_the_store_feature_save_is_refused_and_nothing_is_stored() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[0xF4, 0x01]);
    assert_eq!(h.sdo_write_abort(0x1010, 1, &SAVE), 0x0800_0020);
    assert_eq!(h.sdo_write_abort(0x1010, 2, &SAVE), 0x0800_0020);
    h.sdo_write_ok(0x1011, 1, b"load");
    h.send("000 81 01");
    assert_eq!(h.od().get(0x1017, 0), 0, "the default after the reset");
    assert_eq!(h.dev.storage_mut().saves, 0);
    assert!(h.dev.storage_mut().images.is_empty());
}
