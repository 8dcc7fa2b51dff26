//! Without the `cia402` feature the device runs no CiA 402 state machine: 6040h, 6041h, 6060h
//! and 6061h are plain objects, whatever is written and however (SDO or RPDO).

use crate::common;
use common::*;
use od_runtime::Event;

#[test]
fn controlword_and_modes_are_plain_objects() {
    let mut h = Harness::new();
    assert_eq!(h.dev.cia402_state(), None);
    assert_eq!(h.start(), ["181 40 02 00"], "6041h's default, untouched");
    // Shutdown, switch on, enable operation: stored, and nothing else happens.
    for cw in [0x06u16, 0x07, 0x0F] {
        h.sdo_write_ok(0x6040, 0, &cw.to_le_bytes());
        assert_eq!(h.od().get(0x6040, 0), i128::from(cw));
        assert_eq!(h.od().get(0x6041, 0), 0x0240);
    }
    // Modes of operation is not mirrored into the display.
    h.sdo_write_ok(0x6060, 0, &[1]);
    assert_eq!(h.od().get(0x6061, 0), 0);
    // Over an RPDO (controlword + modes of operation): written, no TPDO follows.
    assert!(h.send("201 80 00 03").is_empty());
    assert_eq!((h.od().get(0x6040, 0), h.od().get(0x6060, 0)), (0x80, 3));
    assert!(!h.events().iter().any(|e| matches!(e, Event::Cia402(_))));
    // Local control does not refuse the controlword either.
    h.dev.set_remote(false);
    h.sdo_write_ok(0x6040, 0, &[0x06, 0x00]);
    assert_eq!(h.dev.cia402_state(), None);
}
