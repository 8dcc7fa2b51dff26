//! CiA 402 state machine: every transition, driven by controlword writes over SDO and RPDO.

use crate::common;
use common::*;
use od_runtime::Event;
use od_runtime::cia402::{State, StateMachine};

fn sw(h: &Harness) -> u16 {
    h.od().get(0x6041, 0) as u16
}

fn cw(h: &mut Harness, v: u16) {
    h.sdo_write_ok(0x6040, 0, &v.to_le_bytes());
}

fn transitions(h: &mut Harness) -> Vec<u8> {
    h.events()
        .into_iter()
        .filter_map(|e| match e {
            Event::Cia402(t) => Some(t.number),
            _ => None,
        })
        .collect()
}

/// Brings the drive into `target` from Switch on disabled.
fn reach(h: &mut Harness, target: State) {
    match target {
        State::SwitchOnDisabled => {}
        State::ReadyToSwitchOn => cw(h, 0x06),
        State::SwitchedOn => {
            cw(h, 0x06);
            cw(h, 0x07)
        }
        State::OperationEnabled => {
            cw(h, 0x06);
            cw(h, 0x07);
            cw(h, 0x0F)
        }
        State::QuickStopActive => {
            reach(h, State::OperationEnabled);
            cw(h, 0x02)
        }
        State::Fault => {
            h.dev.set_fault(0x2310);
            h.dev.fault_reaction_done();
        }
        _ => unreachable!(),
    }
    assert_eq!(h.dev.cia402_state(), Some(target));
    h.events();
}

#[test]
fn boot_enters_switch_on_disabled() {
    let mut h = Harness::new();
    assert_eq!(h.dev.cia402_state(), Some(State::SwitchOnDisabled));
    assert_eq!(transitions(&mut h), [1]);
    assert_eq!(sw(&h), 0x0240);
}

#[test]
fn transition_table() {
    // (start state, controlword, end state, transitions, statusword)
    let table: &[(State, u16, State, &[u8], u16)] = &[
        (State::SwitchOnDisabled, 0x06, State::ReadyToSwitchOn, &[2], 0x0231),
        (State::SwitchOnDisabled, 0x0E, State::ReadyToSwitchOn, &[2], 0x0231),
        (State::SwitchOnDisabled, 0x07, State::SwitchOnDisabled, &[], 0x0240),
        (State::SwitchOnDisabled, 0x0F, State::SwitchOnDisabled, &[], 0x0240),
        (State::ReadyToSwitchOn, 0x07, State::SwitchedOn, &[3], 0x0233),
        (State::ReadyToSwitchOn, 0x0F, State::OperationEnabled, &[3, 4], 0x0237),
        (State::ReadyToSwitchOn, 0x00, State::SwitchOnDisabled, &[7], 0x0240),
        (State::ReadyToSwitchOn, 0x02, State::SwitchOnDisabled, &[7], 0x0240),
        (State::SwitchedOn, 0x0F, State::OperationEnabled, &[4], 0x0237),
        (State::SwitchedOn, 0x06, State::ReadyToSwitchOn, &[6], 0x0231),
        (State::SwitchedOn, 0x00, State::SwitchOnDisabled, &[10], 0x0240),
        (State::SwitchedOn, 0x02, State::SwitchOnDisabled, &[10], 0x0240),
        (State::OperationEnabled, 0x07, State::SwitchedOn, &[5], 0x0233),
        (State::OperationEnabled, 0x06, State::ReadyToSwitchOn, &[8], 0x0231),
        (State::OperationEnabled, 0x00, State::SwitchOnDisabled, &[9], 0x0240),
        (State::OperationEnabled, 0x02, State::QuickStopActive, &[11], 0x0217),
        (State::OperationEnabled, 0x0F, State::OperationEnabled, &[], 0x0237),
        (State::QuickStopActive, 0x00, State::SwitchOnDisabled, &[12], 0x0240),
        (State::QuickStopActive, 0x0F, State::QuickStopActive, &[], 0x0217),
        (State::Fault, 0x80, State::SwitchOnDisabled, &[15], 0x0240),
        (State::Fault, 0x0F, State::Fault, &[], 0x0208),
    ];
    for &(from, word, to, ts, status) in table {
        let mut h = Harness::new();
        reach(&mut h, from);
        cw(&mut h, word);
        assert_eq!(h.dev.cia402_state(), Some(to), "{from:?} + {word:#06x}");
        assert_eq!(transitions(&mut h), ts, "{from:?} + {word:#06x}");
        assert_eq!(sw(&h), status, "{from:?} + {word:#06x}");
        assert_eq!(State::from_statusword(status), Some(to));
    }
}

#[test]
fn quick_stop_option_codes() {
    // 1..=4: the drive leaves Quick stop active when the application's ramp is done.
    let mut h = Harness::new();
    reach(&mut h, State::QuickStopActive);
    h.dev.quick_stop_done();
    assert_eq!(transitions(&mut h), [12]);
    assert_eq!(h.dev.cia402_state(), Some(State::SwitchOnDisabled));
    // 5..=8: it stays, and enable operation goes back (16).
    let mut h = Harness::new();
    h.sdo_write_ok(0x605A, 0, &[6, 0]);
    reach(&mut h, State::QuickStopActive);
    h.dev.quick_stop_done();
    assert!(transitions(&mut h).is_empty());
    cw(&mut h, 0x0F);
    assert_eq!(transitions(&mut h), [16]);
    assert_eq!(h.dev.cia402_state(), Some(State::OperationEnabled));
    // 0: disable drive function at once (11 then 12).
    let mut h = Harness::new();
    h.sdo_write_ok(0x605A, 0, &[0, 0]);
    reach(&mut h, State::OperationEnabled);
    cw(&mut h, 0x02);
    assert_eq!(transitions(&mut h), [11, 12]);
}

#[test]
fn fault_reaction_and_reset_edge() {
    let mut h = Harness::new();
    reach(&mut h, State::OperationEnabled);
    h.dev.set_fault(0x2310);
    assert_eq!(h.dev.cia402_state(), Some(State::FaultReactionActive));
    assert_eq!(sw(&h), 0x021F);
    assert_eq!(h.od().get(0x603F, 0), 0x2310);
    assert_eq!(h.poll(), ["081 10 23 03 00 00 00 00 00"]);
    // A second fault during the reaction changes nothing.
    h.dev.set_fault(0x2311);
    assert_eq!(h.dev.cia402_state(), Some(State::FaultReactionActive));
    assert_eq!(h.poll(), ["081 11 23 03 00 00 00 00 00"]);
    h.dev.fault_reaction_done();
    assert_eq!(transitions(&mut h), [13, 14]);
    assert_eq!(sw(&h), 0x0208);
    // Bit 7 held high is no new reset; the 0 → 1 edge is.
    cw(&mut h, 0x00);
    cw(&mut h, 0x80);
    assert_eq!(transitions(&mut h), [15]);
    assert_eq!(h.od().get(0x603F, 0), 0);
    // The fault reset sends the "error reset" EMCY.
    assert_eq!(h.extra, ["081 00 00 00 00 00 00 00 00"]);
    // Only the fault's register bits are cleared.
    h.extra.clear();
    h.dev.signal_error(0x8130, od_runtime::emcy::REG_COMMUNICATION, [0; 5]);
    h.dev.set_fault(0x2310);
    h.dev.fault_reaction_done();
    cw(&mut h, 0x00);
    cw(&mut h, 0x80);
    assert_eq!(h.dev.error_register(), 0x11);
    assert_eq!(h.extra.last().unwrap(), "081 00 00 11 00 00 00 00 00");
    h.dev.set_fault(0x2310);
    h.dev.fault_reaction_done();
    h.events();
    cw(&mut h, 0x80);
    assert!(transitions(&mut h).is_empty());
    cw(&mut h, 0x00);
    cw(&mut h, 0x80);
    assert_eq!(transitions(&mut h), [15]);
}

#[test]
fn faults_from_every_state() {
    for from in [State::SwitchOnDisabled, State::ReadyToSwitchOn, State::SwitchedOn, State::QuickStopActive] {
        let mut h = Harness::new();
        reach(&mut h, from);
        h.dev.set_fault(0x5000);
        assert_eq!(transitions(&mut h), [13], "{from:?}");
    }
}

#[test]
fn statusword_keeps_application_bits_and_remote() {
    let mut h = Harness::new();
    h.dev.od_mut().set(0x6041, 0, 0x0640); // target reached (bit 10)
    cw(&mut h, 0x06);
    assert_eq!(sw(&h), 0x0631);
    h.dev.set_remote(false);
    assert_eq!(sw(&h), 0x0431);
    assert_eq!(h.sdo_write_abort(0x6040, 0, &[0x07, 0]), 0x0800_0021);
}

#[test]
fn controlword_over_rpdo() {
    let mut h = Harness::new();
    h.start();
    h.events();
    h.send("201 06 00 01");
    h.send("201 0F 00 01");
    assert_eq!(transitions(&mut h), [2, 3, 4]);
    assert_eq!(h.dev.cia402_state(), Some(State::OperationEnabled));
    assert_eq!(h.od().get(0x6061, 0), 1);
}

#[test]
fn pure_state_machine() {
    let mut sm = StateMachine::new();
    assert_eq!(sm.state(), State::NotReadyToSwitchOn);
    // Commands are ignored before initialisation.
    assert!(sm.controlword(0x06, 2).is_empty());
    assert_eq!(sm.initialised().iter().map(|t| t.number).collect::<Vec<_>>(), [1]);
    assert!(sm.initialised().is_empty());
    assert_eq!(State::from_statusword(0x0000), Some(State::NotReadyToSwitchOn));
    assert_eq!(State::from_statusword(0x0001), None);
}

#[test]
fn application_statusword_flags() {
    let mut h = Harness::new();
    cw(&mut h, 0x06);
    assert!(h.dev.set_statusword_flags(0x0400 | 0x0001, 0x0400));
    // Target reached set, the state bit 0 untouched.
    assert_eq!(sw(&h), 0x0631);
    assert!(h.dev.set_statusword_flags(0x0400, 0));
    assert_eq!(sw(&h), 0x0231);
}
