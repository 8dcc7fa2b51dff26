//! The Camozzi DRCS (drive::drives::drcs) on the in-memory bus, through real frames: the
//! chapter 8 programming examples frame by frame, the modes of chapters 5 to 7, units and the
//! feed converter 2001h (chapter 4, 3.6.1), the vendor objects of 3.6, the errors of 3.2.4,
//! life guarding, and 1010h/1011h (3.2.13).
//!
//! The node id is the manual's: 3 (SDO 603h/583h, EMCY 83h).

use std::sync::{Arc, Mutex};

use crate::support::{Master, abort};
use drive::drives::drcs::{self, Drcs, Mechanics, code, input, output};
use drive::drives::{Cia402App, DeviceApps};
use drive::node::{DeviceKind, Node, NodeConfig, NodeStorage, Sim};
use drive::trace::Trace;
use generated::drcs::Dictionary;
use generated::drcs::units::{Dimension, Quantity, Ratio, Unit, Units};
use od_bus::CanFrame;
use od_runtime::NodeId;
use od_runtime::cia402::State;
use od_runtime::od::ObjectDictionary;

const ID: u8 = 3;
const SDO_RX: u32 = 0x600 + ID as u32;
const SDO_TX: u32 = 0x580 + ID as u32;
const EMCY: u32 = 0x80 + ID as u32;

type DrcsNode = Node<Dictionary, Cia402App<Dictionary, Drcs>, NodeStorage>;

/// A DRCS at node 3 on the in-memory bus, started (NMT operational), with `mechanics`.
fn drcs_with(mechanics: Mechanics) -> Master {
    let mut sim = Sim::new();
    let node = Node::new(
        Dictionary::new(ID),
        drcs::app_with(mechanics),
        drive::drives::store::stored_objects_only(DeviceKind::Drcs, NodeStorage::memory()),
        NodeId::new(ID).unwrap(),
    );
    sim.add(Box::new(node));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m.advance(1000);
    m
}

/// The default DRCS (the actuator of [`Mechanics::actuator`]).
fn drcs() -> Master {
    drcs_with(Mechanics::actuator())
}

fn node(m: &Master) -> &DrcsNode {
    m.sim().downcast::<DrcsNode>(0).unwrap()
}

fn node_mut(m: &mut Master) -> &mut DrcsNode {
    m.sim_mut().downcast_mut::<DrcsNode>(0).unwrap()
}

fn app(m: &Master) -> &Cia402App<Dictionary, Drcs> {
    node(m).app().unwrap()
}

fn vendor_mut(m: &mut Master) -> &mut Drcs {
    node_mut(m).app_mut().unwrap().vendor_mut()
}

/// Records a trace of bus values every tick.
fn trace(m: &mut Master) -> Arc<Mutex<Trace>> {
    let t = Arc::new(Mutex::new(Trace::new()));
    node_mut(m).app_mut().unwrap().drive_mut().set_trace(Some(Arc::clone(&t)));
    t
}

/// The manual's frame text ("2B 40 60 00 06 00 00 00") as bytes.
fn bytes(text: &str) -> [u8; 8] {
    let v: Vec<u8> = text.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect();
    v.try_into().unwrap()
}

/// Sends one SDO request frame of node 3 and returns the response frame's data.
fn exchange(m: &mut Master, request: [u8; 8]) -> [u8; 8] {
    m.take_id(SDO_TX);
    m.send(CanFrame::standard(SDO_RX, &request).unwrap());
    let mut answer = None;
    assert!(
        m.wait_until(100_000, 100, |m| {
            answer = m.take_id(SDO_TX).first().map(|s| s.frame.raw_data());
            answer.is_some()
        }),
        "no response to {request:02X?}"
    );
    answer.unwrap()
}

/// The response CiA 301 defines for an expedited download: 60h, index, sub-index, zeros.
fn download_response(request: [u8; 8]) -> [u8; 8] {
    [0x60, request[1], request[2], request[3], 0, 0, 0, 0]
}

/// Sends a chapter 8 frame and compares the response byte for byte.
fn replay(m: &mut Master, frame: &str) {
    let request = bytes(frame);
    assert_eq!(exchange(m, request), download_response(request), "response to {frame}");
}

fn sw(m: &mut Master) -> u16 {
    m.statusword(ID).unwrap()
}

fn position(m: &mut Master) -> i64 {
    m.read_i64(ID, 0x6064, 0).unwrap()
}

fn velocity(m: &mut Master) -> i64 {
    m.read_i64(ID, 0x606C, 0).unwrap()
}

/// Waits (virtual time) until the statusword has `bits` set, polling every 10 ms.
fn wait_bits(m: &mut Master, bits: u16, timeout_us: u64) -> u16 {
    m.wait_statusword(ID, bits, bits, timeout_us, 10_000)
        .unwrap_or_else(|| panic!("statusword bits {bits:#06X} not set within {timeout_us} µs"))
}

/// EMCY frames received so far (taken).
fn emcys(m: &mut Master) -> Vec<[u8; 8]> {
    m.take_id(EMCY).into_iter().map(|s| s.frame.raw_data()).collect()
}

/// Enables, homes with method 37 (no motion) and selects profile position with 50 mm/s and
/// 100 mm/s².
fn enabled_and_homed(m: &mut Master) {
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 37).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    wait_bits(m, 0x1400, 100_000);
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 1).unwrap();
    m.write_u32(ID, 0x6081, 0, 50).unwrap();
    m.write_u32(ID, 0x6083, 0, 100).unwrap();
    m.write_u32(ID, 0x6084, 0, 100).unwrap();
    m.advance(2000);
}

/// Like [`enabled_and_homed`], with a homing 17 on the actuator's proximity, so that the
/// software limits 0..1000 mm match the actuator's stroke.
fn enabled_and_homed_17(m: &mut Master) {
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 17).unwrap();
    m.write_u32(ID, 0x6083, 0, 200).unwrap();
    m.write_u32(ID, 0x6084, 0, 200).unwrap();
    m.write_u32(ID, 0x6099, 1, 100).unwrap();
    m.write_u32(ID, 0x6099, 2, 20).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    wait_bits(m, 0x1400, 30_000_000);
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 1).unwrap();
    m.write_u32(ID, 0x6081, 0, 50).unwrap();
    m.write_u32(ID, 0x6083, 0, 100).unwrap();
    m.write_u32(ID, 0x6084, 0, 100).unwrap();
    m.advance(2000);
}

/// A profile position move: target, bit 4 (with `relative`), release, wait for target reached.
fn move_to(m: &mut Master, target: i32, relative: bool) {
    m.write_i32(ID, 0x607A, 0, target).unwrap();
    let start = if relative { 0x5F } else { 0x1F };
    m.controlword(ID, start).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(20_000);
    wait_bits(m, 0x0400, 60_000_000);
}

// ---------------------------------------------------------------------------------------------
// Chapter 8.

/// Chapter 8, complete: every frame of the listing, sent as printed to node 3, each response
/// compared byte for byte with the SDO download response; between the groups the test waits
/// as a master would (homing done, target reached) and checks what the frames did.
#[test]
fn chapter_8_programming_examples_frame_by_frame() {
    let mut m = drcs();
    // Enable the motor to execute the commands.
    replay(&mut m, "2B 40 60 00 06 00 00 00"); // "ready to switch on"
    m.advance(1000);
    assert_eq!(m.state(ID).unwrap(), Some(State::ReadyToSwitchOn));
    replay(&mut m, "2B 40 60 00 07 00 00 00"); // "Switched on"
    m.advance(1000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchedOn));
    replay(&mut m, "2B 40 60 00 0F 00 00 00"); // "Operation enabled"
    m.advance(1000);
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 0, "brake released with torque");
    // Switch to the Homing mode profile.
    replay(&mut m, "2F 60 60 00 06 00 00 00"); // "set homing mode"
    replay(&mut m, "2F 98 60 00 11 00 00 00"); // "set homing method to 17"
    m.advance(1000);
    assert_eq!(m.read_i64(ID, 0x6061, 0).unwrap(), 6);
    assert_eq!(m.read_i64(ID, 0x6098, 0).unwrap(), 17);
    // Setting the homing profile.
    replay(&mut m, "23 83 60 00 64 00 00 00"); // "set acceleration to 100mm/s²"
    replay(&mut m, "23 84 60 00 64 00 00 00"); // "set deceleration to 100mm/s²"
    replay(&mut m, "23 99 60 01 32 00 00 00"); // "set fast velocity home to 50mm/s"
    replay(&mut m, "23 99 60 02 32 00 00 00"); // "set slow velocity home to 50mm/s"
    assert_eq!(m.read_u32(ID, 0x6099, 1).unwrap(), 50);
    assert_eq!(m.read_u32(ID, 0x6099, 2).unwrap(), 50);
    // Start homing procedure.
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 0, "not homed at start-up");
    replay(&mut m, "2B 40 60 00 1F 00 00 00"); // "set start homing"
    replay(&mut m, "2B 40 60 00 0F 00 00 00"); // "reset start command"
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x3400, 0, "homing in progress: bits 13, 12, 10 = 000");
    assert!(velocity(&mut m) < 0, "method 17 searches in the negative direction");
    let s = wait_bits(&mut m, 0x1400, 30_000_000);
    assert_eq!(s & 0x3400, 0x1400, "homing completed successfully: 011");
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
    assert_eq!(position(&mut m), 0);
    // Switch to position profile.
    replay(&mut m, "2F 60 60 00 01 00 00 00"); // "set profile position mode"
    // Setting the motion profile.
    replay(&mut m, "23 81 60 00 32 00 00 00"); // "set velocity to 50mm/s"
    replay(&mut m, "23 83 60 00 64 00 00 00"); // "set acceleration to 100mm/s²"
    replay(&mut m, "23 84 60 00 64 00 00 00"); // "set deceleration to 100mm/s²"
    // Command for movement to an absolute position.
    replay(&mut m, "23 7A 60 00 2C 01 00 00"); // "set target to 300mm"
    let t0 = m.now();
    replay(&mut m, "2B 40 60 00 1F 00 00 00"); // "set start command"
    assert_ne!(sw(&mut m) & 0x1000, 0, "bit 12: the drive took the set-point");
    replay(&mut m, "2B 40 60 00 0F 00 00 00"); // "clear command"
    m.advance(1_000_000);
    assert_ne!(sw(&mut m) & 0x1000, 0, "bit 12 stays high while the positioning runs");
    assert_eq!(sw(&mut m) & 0x0400, 0);
    wait_bits(&mut m, 0x0400, 20_000_000);
    // 0.5 s up to 50 mm/s, 5.5 s at 50 mm/s, 0.5 s down: 6.5 s.
    let took = m.now() - t0;
    assert!((6_500_000..6_600_000).contains(&took), "300 mm took {took} µs");
    assert_eq!(position(&mut m), 300);
    assert_eq!(sw(&mut m) & 0x1000, 0, "bit 12 low: ready for a new command");
    // Command for movement to a relative position.
    replay(&mut m, "23 7A 60 00 2C 01 00 00"); // "set target to 300mm"
    replay(&mut m, "2B 40 60 00 5F 00 00 00"); // "set start command" (relative)
    replay(&mut m, "2B 40 60 00 0F 00 00 00"); // "clear command"
    m.advance(1_000_000);
    assert!(position(&mut m) > 300);
    wait_bits(&mut m, 0x0400, 20_000_000);
    assert_eq!(position(&mut m), 600);
    // Switch to the velocity profile.
    replay(&mut m, "2B 40 60 00 0F 01 00 00"); // "set motion halted"
    replay(&mut m, "2F 60 60 00 03 00 00 00"); // "set profile velocity"
    // Setting the motion profile.
    replay(&mut m, "23 FF 60 00 32 00 00 00"); // "set target velocity to 50mm/s"
    replay(&mut m, "23 83 60 00 64 00 00 00"); // "set acceleration to 100mm/s²"
    replay(&mut m, "23 84 60 00 64 00 00 00"); // "set deceleration to 100mm/s²"
    m.advance(200_000);
    assert_eq!(velocity(&mut m), 0, "halted: no motion");
    assert_ne!(sw(&mut m) & 0x1400, 0, "halted and stopped: bit 10; zero speed: bit 12");
    // Speed movement start / stop command.
    replay(&mut m, "2B 40 60 00 0F 00 00 00"); // "set motion start"
    m.advance(700_000);
    assert_eq!(velocity(&mut m), 50);
    assert_eq!(sw(&mut m) & 0x1000, 0, "moving: bit 12 = 0");
    replay(&mut m, "23 FF 60 00 64 00 00 00"); // "change target velocity to 100mm/s"
    m.advance(700_000);
    assert_eq!(velocity(&mut m), 100);
    replay(&mut m, "2B 40 60 00 0F 01 00 00"); // "set motion halted"
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x0400, 0, "halt: bit 10 = 0 while decelerating");
    m.advance(1_200_000);
    assert_eq!(velocity(&mut m), 0);
    assert_ne!(sw(&mut m) & 0x0400, 0, "halt: bit 10 = 1 once stopped");
    replay(&mut m, "23 FF 60 00 00 00 00 00"); // "change target velocity to 0mm/s"
    assert_eq!(m.read_i64(ID, 0x60FF, 0).unwrap(), 0);
    // No error on the way.
    assert!(emcys(&mut m).is_empty());
    assert_eq!(m.read_u64(ID, 0x1001, 0).unwrap(), 0);
}

// ---------------------------------------------------------------------------------------------
// State machine, modes, homing (chapters 5 to 7).

#[test]
fn state_machine_to_operation_enabled_and_back() {
    let mut m = drcs();
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    m.switch_on(ID).unwrap();
    assert_eq!(sw(&mut m) & 0x6F, 0x27);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & output::READY, output::READY);
    // Disable voltage: torqueless, the brake engages.
    m.controlword(ID, 0x00).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & output::READY, 0);
    // Modes and homing methods the manual does not list are refused.
    assert_eq!(m.write_u8(ID, 0x6060, 0, 4).map_err(abort), Err(Some(0x0609_0030)));
    assert_eq!(m.write_u8(ID, 0x6060, 0, 7).map_err(abort), Err(Some(0x0609_0030)));
    for method in [1u8, 2, 35, 0xFF] {
        assert_eq!(m.write_u8(ID, 0x6098, 0, method).map_err(abort), Err(Some(0x0609_0030)), "method {method}");
    }
    for method in [17u8, 18, 37] {
        m.write_u8(ID, 0x6098, 0, method).unwrap();
    }
    // The statusword goes out on TPDO1 (1A00h: 6041h, transmission type 255) as it changes.
    m.take_id(0x180 + u32::from(ID));
    m.switch_on(ID).unwrap();
    let tpdo: Vec<u16> = m
        .take_id(0x180 + u32::from(ID))
        .iter()
        .map(|s| u16::from_le_bytes([s.frame.raw_data()[0], s.frame.raw_data()[1]]))
        .collect();
    assert!(tpdo.iter().any(|s| s & 0x6F == 0x27), "TPDO1 shows Operation enabled: {tpdo:04X?}");
}

#[test]
fn controlword_by_rpdo1() {
    let mut m = drcs();
    let rpdo = 0x200 + u32::from(ID);
    for cw in [0x06u16, 0x07, 0x0F] {
        m.pdo(rpdo, &cw.to_le_bytes());
        m.advance(2000);
    }
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
}

#[test]
fn homing_17_moves_by_the_home_offset_and_sets_zero_there() {
    let mut m = drcs();
    let t = trace(&mut m);
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u32(ID, 0x6083, 0, 100).unwrap();
    m.write_u32(ID, 0x6084, 0, 100).unwrap();
    m.write_u32(ID, 0x6099, 1, 50).unwrap();
    m.write_u32(ID, 0x6099, 2, 10).unwrap();
    m.write_i32(ID, 0x607C, 0, 20).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & output::BUSY, output::BUSY);
    let s = wait_bits(&mut m, 0x1400, 30_000_000);
    assert_eq!(s & 0x2000, 0);
    assert_eq!(position(&mut m), 0);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
    let out = m.read_u32(ID, 0x2003, 0).unwrap();
    assert_eq!(out & (output::HOMING_OK | output::BUSY), output::HOMING_OK);
    // In the start-up frame (0 = where the carriage stood) the proximity ends at -100 mm: the
    // search went below it, the slow phase latched its edge, and the axis stopped 20 mm
    // beyond it before that point became zero.
    let samples = t.lock().unwrap().samples().to_vec();
    let min = samples.iter().map(|s| s.position_actual).min().unwrap();
    assert!((-120..=-105).contains(&min), "the search stopped on the proximity: {min}");
    let done = samples.iter().position(|s| s.statusword & 0x1400 == 0x1400).unwrap();
    assert_eq!(samples[done - 1].position_actual, -80, "moved by the offset before zeroing");
    // On the proximity's edge, 2002h shows Proxy home.
    m.write_i32(ID, 0x607C, 0, 0).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    wait_bits(&mut m, 0x1400, 30_000_000);
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap() & input::PROXY_HOME, input::PROXY_HOME);
}

#[test]
fn homing_18_with_reversed_polarity_and_its_error_without() {
    // The proximity lies in the motor's negative direction: method 18 searches the positive
    // direction, which is the motor's negative one with 607Eh = 80h.
    let mut m = drcs();
    let t = trace(&mut m);
    m.write_u8(ID, 0x607E, 0, 0x80).unwrap();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 18).unwrap();
    m.write_u32(ID, 0x6083, 0, 200).unwrap();
    m.write_u32(ID, 0x6084, 0, 200).unwrap();
    m.write_u32(ID, 0x6099, 1, 80).unwrap();
    m.write_u32(ID, 0x6099, 2, 10).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(200_000);
    assert!(velocity(&mut m) > 0, "18 searches in the positive direction");
    wait_bits(&mut m, 0x1400, 30_000_000);
    assert_eq!(position(&mut m), 0);
    let max = t.lock().unwrap().samples().iter().map(|s| s.position_actual).max().unwrap();
    assert!(max > 100, "found the proximity 100 mm away: {max}");
    assert!(emcys(&mut m).is_empty());

    // Without the polarity the positive search finds no proximity before the end stop:
    // "homing terminated with error" (101), error 8613h (a soft error: quick stop, Fault).
    let mut m = drcs();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 18).unwrap();
    m.write_u32(ID, 0x6083, 0, 1000).unwrap();
    m.write_u32(ID, 0x6084, 0, 1000).unwrap();
    m.write_u32(ID, 0x6099, 1, 200).unwrap();
    m.write_u32(ID, 0x6099, 2, 10).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(8_000_000);
    let s = sw(&mut m);
    assert_eq!(s & 0x3400, 0x2400, "homing error, standing: 101");
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert_eq!(emcys(&mut m), vec![[0x13, 0x86, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(m.read_u32(ID, 0x1003, 1).unwrap() & 0xFFFF, 0x8613);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 0);
}

#[test]
fn homing_37_takes_the_current_position_without_moving() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    move_to(&mut m, 300, false);
    let stroke = m.read_u32(ID, 0x2103, 0).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 37).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x3400, 0x1400);
    assert_eq!(position(&mut m), 0);
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), stroke, "nothing moved");
    // The software limits refer to the new zero.
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 1).unwrap();
    move_to(&mut m, 500, false);
    assert_eq!(position(&mut m), 500);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), (800.0f64 / 70.0) as u32, "800 mm of 70 mm revolutions");
}

/// 3.2.4 7305h: with the external encoder, a motor that loses steps (here: blocked by the
/// actuator's end stop, which the software limits no longer guard after a homing 37 away from
/// the proximity) is a hard error: the power stage goes off at once and the brake holds.
#[test]
fn step_loss_is_a_hard_error() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    move_to(&mut m, 300, false);
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 1).unwrap();
    m.write_i32(ID, 0x607A, 0, 700).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(13_000_000);
    assert_eq!(emcys(&mut m), vec![[0x05, 0x73, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert_eq!(position(&mut m), 610, "blocked by the end stop 910 mm from the start position");
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1, "brake engaged");
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & output::ALARM, output::ALARM);
    assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0x7305);
    // Without the external encoder nothing notices.
    let mut m = drcs();
    vendor_mut(&mut m).conditions.external_encoder = false;
    enabled_and_homed(&mut m);
    move_to(&mut m, 300, false);
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 1).unwrap();
    m.write_i32(ID, 0x607A, 0, 700).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(13_000_000);
    assert!(emcys(&mut m).is_empty());
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    assert_eq!(position(&mut m), 610);
}

#[test]
fn homing_speeds_of_zero_are_a_homing_error() {
    let mut m = drcs();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(10_000);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert_eq!(emcys(&mut m), vec![[0x13, 0x86, 0x01, 0, 0, 0, 0, 0]]);
}

#[test]
fn profile_position_bit_12_and_no_target_change_during_a_move() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    m.write_i32(ID, 0x607A, 0, 200).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    assert_ne!(sw(&mut m) & 0x1000, 0);
    m.controlword(ID, 0x0F).unwrap();
    m.advance(1_000_000);
    assert_ne!(sw(&mut m) & 0x1000, 0, "high until the end of the command");
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & (output::BUSY | output::POS_OK), output::BUSY);
    // A new target during the movement is refused: the move goes on to 200.
    m.write_i32(ID, 0x607A, 0, 50).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    wait_bits(&mut m, 0x0400, 20_000_000);
    assert_eq!(position(&mut m), 200);
    assert_eq!(sw(&mut m) & 0x1000, 0);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap() & (output::BUSY | output::POS_OK), output::POS_OK);
    assert!(emcys(&mut m).is_empty(), "no error code for a refused target");
    // 3.4.2: halt interrupts the movement, and it resumes when the halt is reset.
    m.write_i32(ID, 0x607A, 0, 600).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(2_000_000);
    m.controlword(ID, 0x10F).unwrap();
    m.advance(1_000_000);
    assert_eq!(sw(&mut m) & 0x1400, 0x0400, "halted and stopped: ready for a new command");
    let stopped = position(&mut m);
    assert!((250..350).contains(&stopped), "{stopped}");
    m.controlword(ID, 0x0F).unwrap();
    m.advance(500_000);
    assert!(position(&mut m) > stopped, "resumed");
    wait_bits(&mut m, 0x0400, 20_000_000);
    assert_eq!(position(&mut m), 600);
    // While halted a new target is accepted (the movement was interrupted); relative targets
    // count from where the axis stands.
    m.write_i32(ID, 0x607A, 0, 100).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(1_000_000);
    m.controlword(ID, 0x10F).unwrap();
    m.advance(1_000_000);
    let stopped = position(&mut m);
    assert!((500..580).contains(&stopped), "{stopped}");
    m.write_i32(ID, 0x607A, 0, 10).unwrap();
    m.controlword(ID, 0x15F).unwrap();
    m.controlword(ID, 0x14F).unwrap();
    m.advance(500_000);
    assert_eq!(position(&mut m), stopped, "still halted");
    m.controlword(ID, 0x4F).unwrap();
    wait_bits(&mut m, 0x0400, 20_000_000);
    assert_eq!(position(&mut m), stopped + 10);
}

#[test]
fn profile_velocity_windows_thresholds_and_halt() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    m.write_u16(ID, 0x606D, 0, 1).unwrap(); // velocity window 1 mm/s
    m.write_u16(ID, 0x606E, 0, 100).unwrap(); // for 100 ms
    m.write_u16(ID, 0x606F, 0, 2).unwrap(); // zero speed below 2 mm/s
    m.write_u16(ID, 0x6070, 0, 50).unwrap(); // for 50 ms
    m.set_mode(ID, 3).unwrap();
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x1000, 0x1000, "standing: zero speed");
    m.write_i32(ID, 0x60FF, 0, 40).unwrap();
    m.advance(200_000);
    assert_eq!(sw(&mut m) & 0x1400, 0, "accelerating: neither target reached nor zero speed");
    // 40 mm/s at 100 mm/s² is reached after 0.4 s; bit 10 100 ms later.
    m.advance(250_000);
    assert_eq!(velocity(&mut m), 40);
    assert_eq!(sw(&mut m) & 0x0400, 0, "within the window for less than 606Eh");
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x0400, 0x0400);
    // Halt: decelerating (bit 10 = 0), then stopped (bit 10 = 1) and zero speed after 6070h.
    m.controlword(ID, 0x10F).unwrap();
    m.advance(100_000);
    assert_eq!(sw(&mut m) & 0x1400, 0);
    m.advance(400_000);
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(sw(&mut m) & 0x1400, 0x1400);
    // Released, it moves again; negative velocities too.
    m.controlword(ID, 0x0F).unwrap();
    m.write_i32(ID, 0x60FF, 0, -20).unwrap();
    m.advance(1_000_000);
    assert_eq!(velocity(&mut m), -20);
    // The software limit stops a velocity movement (bit 11) at 0 mm.
    m.advance(20_000_000);
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(position(&mut m), 0);
    assert_ne!(sw(&mut m) & 0x0800, 0, "internal limit active");
}

// ---------------------------------------------------------------------------------------------
// Units and the feed converter (chapter 4, 3.6.1).

/// The generated units module for the device's current 2001h, 6091h and 6092h (read over SDO
/// into a local copy of the dictionary; 6091h and 6092h are read-only on the bus).
fn units(m: &mut Master) -> Units {
    let mut od = Dictionary::new(ID);
    for (index, sub) in [(0x2001, 1), (0x2001, 2), (0x6091, 1), (0x6091, 2), (0x6092, 1), (0x6092, 2)] {
        let v = m.read_u32(ID, index, sub).unwrap();
        od.write(index, sub, &v.to_le_bytes()).unwrap();
    }
    Units::from_dictionary(&od).unwrap()
}

fn mm(value: i64) -> Quantity {
    Quantity::int(value, Unit::Millimeter)
}

/// A move to `target` (absolute or relative, in mm) through the generated units module.
fn move_mm(m: &mut Master, target: Quantity, relative: bool) {
    let raw = units(m).to_raw(Dimension::Position, target).unwrap();
    move_to(m, i32::try_from(raw).unwrap(), relative);
}

fn position_mm(m: &mut Master) -> Quantity {
    let raw = position(m);
    units(m).to_physical(Dimension::Position, raw).unwrap()
}

#[test]
fn absolute_and_relative_moves_in_mm_through_the_generated_units() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    assert_eq!(units(&mut m).unit(Dimension::Position), Some(Unit::Millimeter));
    move_mm(&mut m, mm(250), false);
    assert_eq!(position_mm(&mut m), mm(250));
    move_mm(&mut m, mm(-40), true);
    assert_eq!(position_mm(&mut m), mm(210));
    // Micrometres: 2001h = 1000/1 (value = mm × 1000).
    m.write_u32(ID, 0x2001, 1, 1000).unwrap();
    m.write_u32(ID, 0x2001, 2, 1).unwrap();
    assert_eq!(position(&mut m), 210_000);
    assert_eq!(position_mm(&mut m), mm(210));
    // 6081h/6083h/6084h are now µm/s and µm/s²: the profile keeps its speed only when the
    // master rewrites them in the new unit.
    m.write_u32(ID, 0x6081, 0, 50_000).unwrap();
    m.write_u32(ID, 0x6083, 0, 100_000).unwrap();
    m.write_u32(ID, 0x6084, 0, 100_000).unwrap();
    let quarter = Quantity::new(Ratio::new(1, 4).unwrap(), Unit::Millimeter);
    move_mm(&mut m, quarter, true);
    assert_eq!(position(&mut m), 210_250);
    assert_eq!(position_mm(&mut m), Quantity::new(Ratio::new(841, 4).unwrap(), Unit::Millimeter));
    // Inches as the formula gives them: 10/254 (value = mm × 10 / 254).
    m.write_u32(ID, 0x2001, 1, 10).unwrap();
    m.write_u32(ID, 0x2001, 2, 254).unwrap();
    assert_eq!(position(&mut m), 8, "210.25 mm = 8.28 in");
    m.write_u32(ID, 0x6081, 0, 2).unwrap(); // 2 in/s = 50.8 mm/s
    m.write_u32(ID, 0x6083, 0, 4).unwrap();
    m.write_u32(ID, 0x6084, 0, 4).unwrap();
    move_mm(&mut m, mm(254), false); // 10 in
    assert_eq!(position(&mut m), 10);
    assert_eq!(position_mm(&mut m), mm(254));
    assert_eq!(app(&m).drive().axis().status().position_actual, 254_000, "exactly 254 mm");
    // Velocities follow the unit: 2 in/s cruise.
    m.write_i32(ID, 0x607A, 0, 0).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(1_000_000);
    assert_eq!(velocity(&mut m), -2);
    assert_eq!(app(&m).drive().axis().status().velocity_actual, -50_800);
}

/// Issue #28 on the DRCS: 6092h (mm per pulley revolution) and 6091h (motor per pulley
/// revolutions), which QSet sets (3.4.20, 3.4.21), relate the actuator's millimetres to motor
/// turns in the drive (2103h counts motor revolutions, 3.6.9) and in the generated units alike,
/// whatever unit 2001h makes of the millimetres.
#[test]
fn motor_turns_follow_the_feed_constant_and_the_gear_ratio() {
    use Dimension::Position;
    for (gear, turns) in [((1, 1), 2), ((2, 1), 4), ((3, 2), 3)] {
        let mut m = drcs_with(Mechanics { gear_ratio: gear, ..Mechanics::actuator() });
        assert_eq!((m.read_u32(ID, 0x6091, 1).unwrap(), m.read_u32(ID, 0x6091, 2).unwrap()), gear);
        assert_eq!((m.read_u32(ID, 0x6092, 1).unwrap(), m.read_u32(ID, 0x6092, 2).unwrap()), (70, 1));
        enabled_and_homed(&mut m);
        move_mm(&mut m, mm(140), false); // two pulley turns of 70 mm
        let why = format!("6091h = {}/{}", gear.0, gear.1);
        assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), turns as u32, "{why}: motor revolutions");
        let u = units(&mut m);
        assert_eq!(u.to_internal(Position, position(&mut m)).unwrap(), Ratio::int(turns), "{why}");
        let one_turn =
            Quantity::new(Ratio::new(70 * i128::from(gear.1), i128::from(gear.0)).unwrap(), Unit::Millimeter);
        assert_eq!(u.internal_to_physical(Position, Ratio::int(1)).unwrap(), one_turn, "{why}");
        // Micrometres (2001h = 1000/1): the same motor turns for the same travel.
        m.write_u32(ID, 0x2001, 1, 1000).unwrap();
        let u = units(&mut m);
        assert_eq!(position(&mut m), 140_000);
        assert_eq!(u.to_internal(Position, 140_000).unwrap(), Ratio::int(turns), "{why}");
        assert_eq!(u.internal_to_raw(Position, Ratio::int(turns)).unwrap(), 140_000, "{why}");
    }
}

#[test]
fn feed_converter_examples_of_chapter_4() {
    // The inch example as printed, 100/254, gives ten times the inch value (decision in the
    // sidecar): 254 mm reads 100.
    let mut m = drcs();
    enabled_and_homed(&mut m);
    move_to(&mut m, 254, false);
    m.write_u32(ID, 0x2001, 1, 100).unwrap();
    m.write_u32(ID, 0x2001, 2, 254).unwrap();
    assert_eq!(position(&mut m), 100);
    assert_eq!(m.read_i64(ID, 0x607D, 2).unwrap(), 394, "1000 mm full scale × 100/254");
    // 0 is not a ratio.
    assert_eq!(m.write_u32(ID, 0x2001, 1, 0).map_err(abort), Err(Some(0x0609_0030)));
    assert_eq!(m.write_u32(ID, 0x2001, 2, 0).map_err(abort), Err(Some(0x0609_0030)));

    // Only motor: degrees; 888/100 gives microsteps, and "to perform a complete motor
    // revolution, set a position of 3200 µstep" (3200 / 8.88 = 360.36°).
    let mut m = drcs_with(Mechanics::only_motor());
    assert_eq!((m.read_i64(ID, 0x607D, 1).unwrap(), m.read_i64(ID, 0x607D, 2).unwrap()), (0, 0), "no limits");
    enabled_and_homed(&mut m);
    move_to(&mut m, 360, false);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), 1, "one motor revolution");
    m.write_u32(ID, 0x2001, 1, 888).unwrap();
    m.write_u32(ID, 0x2001, 2, 100).unwrap();
    assert_eq!(position(&mut m), 3197, "360° = 3196.8 µstep");
    m.write_u32(ID, 0x6081, 0, 3200).unwrap();
    m.write_u32(ID, 0x6083, 0, 6400).unwrap();
    m.write_u32(ID, 0x6084, 0, 6400).unwrap();
    move_to(&mut m, 3197 + 3200, false);
    assert_eq!(position(&mut m), 6397);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), 2);
    // No software limits: negative positions are fine.
    move_to(&mut m, -3200, false);
    assert_eq!(position(&mut m), -3200);
}

/// 3.6.1: the feed converter applies to PDOs as to SDO: RPDO2 carries 607Ah, TPDO2 6064h.
#[test]
fn feed_converter_applies_to_pdos() {
    let mut m = drcs();
    enabled_and_homed(&mut m);
    let (rpdo2, tpdo2) = (0x300 + u32::from(ID), 0x280 + u32::from(ID));
    // RPDO2: controlword + target position; TPDO2: statusword + actual position on SYNC.
    m.write_u32(ID, 0x1401, 1, 0x8000_0000 | rpdo2).unwrap();
    m.write_u8(ID, 0x1601, 0, 0).unwrap();
    m.write_u32(ID, 0x1601, 1, 0x6040_0010).unwrap();
    m.write_u32(ID, 0x1601, 2, 0x607A_0020).unwrap();
    m.write_u8(ID, 0x1601, 0, 2).unwrap();
    m.write_u32(ID, 0x1401, 1, rpdo2).unwrap();
    m.write_u32(ID, 0x1801, 1, 0x8000_0000 | tpdo2).unwrap();
    m.write_u8(ID, 0x1801, 2, 1).unwrap();
    m.write_u8(ID, 0x1A01, 0, 0).unwrap();
    m.write_u32(ID, 0x1A01, 1, 0x6041_0010).unwrap();
    m.write_u32(ID, 0x1A01, 2, 0x6064_0020).unwrap();
    m.write_u8(ID, 0x1A01, 0, 2).unwrap();
    m.write_u32(ID, 0x1801, 1, tpdo2).unwrap();
    let actual = |m: &mut Master| {
        m.take_id(tpdo2);
        m.sync();
        m.advance(1000);
        let f = m.take_id(tpdo2).pop().expect("TPDO2 on SYNC").frame.raw_data();
        i32::from_le_bytes([f[2], f[3], f[4], f[5]])
    };
    let start = |m: &mut Master, target: i32| {
        let t = target.to_le_bytes();
        m.pdo(rpdo2, &[0x1F, 0, t[0], t[1], t[2], t[3]]);
        m.pdo(rpdo2, &[0x0F, 0, t[0], t[1], t[2], t[3]]);
        m.advance(20_000);
        wait_bits(m, 0x0400, 20_000_000);
    };
    start(&mut m, 100);
    assert_eq!(actual(&mut m), 100);
    m.write_u32(ID, 0x2001, 1, 10).unwrap();
    m.write_u32(ID, 0x2001, 2, 1).unwrap(); // 0.1 mm
    assert_eq!(actual(&mut m), 1000);
    start(&mut m, 1234);
    assert_eq!(actual(&mut m), 1234);
    assert_eq!(app(&m).drive().axis().status().position_actual, 123_400);
}

// ---------------------------------------------------------------------------------------------
// Errors (3.2.4), guarding (3.2.11/12), fault reset.

#[test]
fn software_limit_violation_is_error_7320h_and_the_motor_does_not_move() {
    let mut m = drcs();
    enabled_and_homed_17(&mut m);
    assert_eq!(m.read_i64(ID, 0x607D, 1).unwrap(), 0);
    assert_eq!(m.read_i64(ID, 0x607D, 2).unwrap(), 1000);
    assert_eq!(m.write_i32(ID, 0x607D, 2, 2000).map_err(abort), Err(Some(0x0601_0002)), "set by QSet");
    move_to(&mut m, 900, false);
    emcys(&mut m);
    // Absolute beyond the full scale.
    m.write_i32(ID, 0x607A, 0, 1001).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(500_000);
    assert_eq!(emcys(&mut m), vec![[0x20, 0x73, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(position(&mut m), 900, "the motor does not move");
    assert_eq!(velocity(&mut m), 0);
    let s = sw(&mut m);
    assert_eq!(s & 0x6F, 0x27, "still Operation enabled");
    assert_eq!(s & 0x0080, 0x0080, "warning bit 7");
    assert_eq!(m.read_u64(ID, 0x1001, 0).unwrap(), 0x01);
    assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0x7320);
    assert_eq!(m.read_u32(ID, 0x1003, 0).unwrap(), 1);
    assert_eq!(m.read_u32(ID, 0x1003, 1).unwrap() & 0xFFFF, 0x7320);
    // Relative beyond (900 + 150), and below 0 (the homing position).
    for (target, cw) in [(150, 0x5F), (-1, 0x1F)] {
        m.write_i32(ID, 0x607A, 0, target).unwrap();
        m.controlword(ID, cw).unwrap();
        m.controlword(ID, 0x0F).unwrap();
        m.advance(100_000);
        assert_eq!(emcys(&mut m), vec![[0x20, 0x73, 0x01, 0, 0, 0, 0, 0]], "target {target}");
        assert_eq!(position(&mut m), 900);
    }
    // A target inside is accepted: the error reset EMCY, bit 7 and 1001h clear.
    move_to(&mut m, 1000, false);
    assert_eq!(position(&mut m), 1000);
    assert_eq!(emcys(&mut m), vec![[0; 8]]);
    assert_eq!(sw(&mut m) & 0x0080, 0);
    assert_eq!(m.read_u64(ID, 0x1001, 0).unwrap(), 0);
    assert_eq!(m.read_u32(ID, 0x1003, 0).unwrap(), 3, "the history keeps the three");
}

#[test]
fn movement_without_homing_is_error_ff13h() {
    let mut m = drcs();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 1).unwrap();
    m.write_u32(ID, 0x6081, 0, 50).unwrap();
    m.write_u32(ID, 0x6083, 0, 100).unwrap();
    m.write_u32(ID, 0x6084, 0, 100).unwrap();
    m.write_i32(ID, 0x607A, 0, 100).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(500_000);
    assert_eq!(emcys(&mut m), vec![[0x13, 0xFF, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(position(&mut m), 0);
    assert_eq!(sw(&mut m) & 0x0080, 0x0080);
    // Profile velocity too: the target is kept but nothing moves.
    m.set_mode(ID, 3).unwrap();
    m.write_i32(ID, 0x60FF, 0, 30).unwrap();
    m.advance(500_000);
    assert_eq!(emcys(&mut m), vec![[0x13, 0xFF, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(velocity(&mut m), 0);
    // Nor after a reconfiguration (which re-reads 60FFh).
    m.write_u32(ID, 0x6083, 0, 200).unwrap();
    m.advance(500_000);
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(position(&mut m), 0);
    // Homing (37), then the held target velocity applies in profile velocity.
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 37).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(emcys(&mut m), vec![[0; 8]], "homing is accepted: error reset");
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 3).unwrap();
    m.advance(500_000);
    assert_eq!(velocity(&mut m), 30);
    assert!(emcys(&mut m).is_empty());
}

#[test]
fn supply_temperature_current_and_motor_errors_switch_the_power_off() {
    type Provoke = fn(&mut drcs::Conditions);
    let cases: [(Provoke, u16, u8); 4] = [
        (|c| c.overcurrent = true, code::OVERCURRENT, 0x03),
        (|c| c.supply_mv = 12_000, code::UNDERVOLTAGE, 0x05),
        (|c| c.temperature_c = 90.0, code::TEMPERATURE, 0x09),
        (|c| c.motor_configured = false, code::MOTOR_CONFIGURATION, 0x01),
    ];
    for (provoke, code, register) in cases {
        let mut m = drcs();
        enabled_and_homed(&mut m);
        m.set_mode(ID, 3).unwrap();
        m.write_i32(ID, 0x60FF, 0, 50).unwrap();
        m.advance(1_000_000);
        assert_eq!(velocity(&mut m), 50);
        emcys(&mut m);
        provoke(&mut vendor_mut(&mut m).conditions);
        m.advance(2000);
        let [lo, hi] = code.to_le_bytes();
        assert_eq!(emcys(&mut m), vec![[lo, hi, register, 0, 0, 0, 0, 0]], "{code:04X}");
        // Hard error: the power stage is off at once and the brake holds the axis.
        assert_eq!(m.state(ID).unwrap(), Some(State::Fault), "{code:04X}");
        assert_eq!(velocity(&mut m), 0);
        assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1);
        assert_eq!(m.read_u64(ID, 0x1001, 0).unwrap(), u64::from(register));
        // A fault reset while the cause persists: the error comes back.
        m.controlword(ID, 0x80).unwrap();
        m.advance(5000);
        assert_eq!(m.state(ID).unwrap(), Some(State::Fault), "{code:04X} persists");
        let again = emcys(&mut m);
        assert_eq!(again.first(), Some(&[0; 8]), "error reset EMCY");
        assert_eq!(again.get(1), Some(&[lo, hi, register, 0, 0, 0, 0, 0]), "raised again");
        // Cause gone: the reset sticks.
        vendor_mut(&mut m).conditions = drcs::Conditions::default();
        m.controlword(ID, 0x00).unwrap();
        m.controlword(ID, 0x80).unwrap();
        m.advance(5000);
        assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled), "{code:04X}");
        assert_eq!(m.read_u64(ID, 0x1001, 0).unwrap(), 0);
        assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0);
    }
}

#[test]
fn flash_data_lost_is_reported_after_reset_node() {
    let mut m = drcs();
    vendor_mut(&mut m).conditions.flash_ok = false;
    emcys(&mut m);
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(emcys(&mut m), vec![[0x30, 0x55, 0x01, 0, 0, 0, 0, 0]]);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled), "reported only");
    assert_eq!(sw(&mut m) & 0x80, 0x80);
}

/// The DRCS has no heartbeat consumer (1016h); losing the master's life guarding (100Ch ×
/// 100Dh) is the fieldbus disconnection: quick stop with 6084h, Fault, then the communication
/// resets (boot-up, pre-operational).
#[test]
fn life_guarding_loss_quick_stops_then_resets_the_communication() {
    let mut m = drcs();
    assert_eq!(m.read(ID, 0x1016, 1).map_err(abort), Err(Some(0x0602_0000)), "no heartbeat consumer");
    enabled_and_homed(&mut m);
    m.set_mode(ID, 3).unwrap();
    m.write_i32(ID, 0x60FF, 0, 100).unwrap();
    m.advance(1_500_000);
    assert_eq!(velocity(&mut m), 100);
    m.write_u16(ID, 0x100C, 0, 100).unwrap();
    m.write_u8(ID, 0x100D, 0, 3).unwrap();
    let guard = 0x700 + u32::from(ID);
    m.take_id(guard);
    for _ in 0..10 {
        m.send(CanFrame::remote(guard, false, 1).unwrap());
        m.advance(100_000);
    }
    let replies = m.take_id(guard);
    assert!(replies.len() >= 10 && replies.iter().all(|s| s.frame.raw_data()[0] & 0x7F == 5), "operational");
    emcys(&mut m);
    // The master goes away: after 300 ms the error, a quick stop ramp of 1 s (100 mm/s at
    // 100 mm/s²), then Fault and the communication reset.
    m.advance(350_000);
    assert_eq!(emcys(&mut m), vec![[0x30, 0x81, 0x11, 0, 0, 0, 0, 0]]);
    assert_eq!(m.state(ID).unwrap(), Some(State::FaultReactionActive));
    let v = velocity(&mut m);
    assert!((50..100).contains(&v), "ramping down: {v}");
    m.advance(1_200_000);
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    let boot: Vec<_> = m.take_id(guard).iter().map(|s| s.frame.raw_data()[0]).collect();
    assert_eq!(boot, vec![0], "boot-up message after the communication reset");
    // Pre-operational, SDO works; the communication reset restored 1000h..1FFFh (guarding
    // off) except the error register and the history, which still name the cause of the
    // Fault (issue 17); 603Fh keeps the error until a fault reset.
    assert_eq!(m.read_u16(ID, 0x100C, 0).unwrap(), 0);
    assert_eq!(m.read_u32(ID, 0x1003, 0).unwrap(), 1);
    assert_eq!(m.read_u32(ID, 0x1003, 1).unwrap() & 0xFFFF, 0x8130);
    assert_eq!(m.read_u8(ID, 0x1001, 0).unwrap(), 0x11);
    assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0x8130);
    m.controlword(ID, 0x80).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0);
    assert_eq!(emcys(&mut m), vec![[0; 8]]);
}

/// Fault reset is controlword bit 7 (0 → 1); 0 written to 1003h sub 0 only clears the history
/// on the DRCS (3.2.4).
#[test]
fn fault_reset_by_controlword_and_history_clear() {
    let mut m = drcs();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap(); // zero homing speeds: 8613h
    m.advance(10_000);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert_eq!(m.read_u32(ID, 0x1003, 0).unwrap(), 1);
    m.write_u8(ID, 0x1003, 0, 0).unwrap();
    m.advance(2000);
    assert_eq!(m.read_u32(ID, 0x1003, 0).unwrap(), 0);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault), "the history clear is no fault reset");
    emcys(&mut m);
    m.controlword(ID, 0x0F).unwrap();
    m.controlword(ID, 0x8F).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert_eq!(emcys(&mut m), vec![[0; 8]]);
    assert_eq!(m.read_u64(ID, 0x603F, 0).unwrap(), 0);
    m.switch_on(ID).unwrap();
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
}

// ---------------------------------------------------------------------------------------------
// Vendor objects (3.6).

#[test]
fn brake_follows_the_power_stage_and_is_released_by_hand_only_torqueless() {
    let mut m = drcs();
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1, "engaged at start-up (torqueless)");
    assert!(app(&m).drive().axis().status().brake);
    m.switch_on(ID).unwrap();
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 0);
    assert!(!app(&m).drive().axis().status().brake);
    assert_eq!(m.write_u8(ID, 0x2005, 0, 1).map_err(abort), Err(Some(0x0800_0022)), "not with torque");
    m.controlword(ID, 0x06).unwrap();
    m.advance(2000);
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1);
    // Released by hand while torqueless; 2 is no brake state.
    assert_eq!(m.write_u8(ID, 0x2005, 0, 2).map_err(abort), Err(Some(0x0609_0030)));
    m.write_u8(ID, 0x2005, 0, 0).unwrap();
    m.advance(2000);
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 0);
    assert!(!app(&m).drive().axis().status().brake);
    m.write_u8(ID, 0x2005, 0, 1).unwrap();
    m.advance(2000);
    assert!(app(&m).drive().axis().status().brake);
    m.write_u8(ID, 0x2005, 0, 0).unwrap();
    // The power stage on and off again: the drive takes the brake back.
    m.controlword(ID, 0x07).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(2000);
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 0);
    m.controlword(ID, 0x06).unwrap();
    m.advance(2000);
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1);
    assert!(app(&m).drive().axis().status().brake);
}

#[test]
fn counters_advance_with_the_virtual_clock_and_the_axis() {
    let mut m = drcs();
    let c0 = vendor_mut(&mut m).counters();
    m.advance(3_000_000);
    assert_eq!(m.read_u32(ID, 0x2100, 0).unwrap(), 3, "torqueless since start-up");
    enabled_and_homed(&mut m);
    let before = vendor_mut(&mut m).counters();
    m.advance(2_000_000);
    let after = vendor_mut(&mut m).counters();
    assert_eq!(after.stopped_us - before.stopped_us, 2_000_000);
    assert_eq!(after.torqueless_us, before.torqueless_us);
    // 720 mm out and back at 50 mm/s: 2 × 14.9 s moving, 20 motor revolutions of 70 mm.
    move_to(&mut m, 720, false);
    move_to(&mut m, 0, false);
    let c = vendor_mut(&mut m).counters();
    let moving = c.moving_us - after.moving_us;
    assert!((29_800_000..29_900_000).contains(&moving), "{moving}");
    assert!((c.stroke - 1_440_000.0).abs() < 50.0, "stroke {} µm", c.stroke);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), 20);
    assert_eq!(u64::from(m.read_u32(ID, 0x2102, 0).unwrap()), c.moving_us / 1_000_000);
    assert_eq!(u64::from(m.read_u32(ID, 0x2101, 0).unwrap()), c.stopped_us / 1_000_000);
    assert_eq!(u64::from(m.read_u32(ID, 0x2100, 0).unwrap()), c.torqueless_us / 1_000_000);
    let counted = c.torqueless_us + c.stopped_us + c.moving_us - c0.torqueless_us;
    assert!(m.now() - counted <= 2_000, "every tick is counted once: {counted} of {}", m.now());
    // Read-only, and they survive a reset node ("since it left the factory").
    assert_eq!(m.write_u32(ID, 0x2103, 0, 0).map_err(abort), Err(Some(0x0601_0002)));
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(m.read_u32(ID, 0x2103, 0).unwrap(), 20);
}

#[test]
fn inputs_and_outputs() {
    let mut m = drcs();
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap(), input::ENABLE);
    {
        let c = &mut vendor_mut(&mut m).conditions;
        c.inputs = 0b1000_0101;
        c.strobe = true;
        c.proxy_ext = true;
        c.enable = false;
        c.out = true;
    }
    m.advance(2000);
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap(), 0b1000_0101 | input::STROBE | input::PROXY_EXT);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), output::OUT);
    assert_eq!(m.write_u32(ID, 0x2003, 0, 0).map_err(abort), Err(Some(0x0601_0002)), "read-only");
    vendor_mut(&mut m).conditions = drcs::Conditions::default();
    enabled_and_homed(&mut m);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), output::READY | output::HOMING_OK | output::POS_OK);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
    // The homing is lost with a reset node.
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 0);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), 0);
}

// ---------------------------------------------------------------------------------------------
// Store and restore (3.2.13), NMT start-up (3.2.25).

#[test]
fn save_stores_the_manual_list_only_and_restore_brings_defaults() {
    let mut m = drcs();
    m.write_u32(ID, 0x6081, 0, 77).unwrap(); // stored
    m.write_u32(ID, 0x2001, 1, 10).unwrap(); // stored
    m.write_i32(ID, 0x60FF, 0, -5).unwrap(); // stored
    m.write_u16(ID, 0x1017, 0, 250).unwrap(); // stored
    m.write_u8(ID, 0x607E, 0, 0x80).unwrap(); // stored
    m.write_u8(ID, 0x6060, 0, 1).unwrap(); // not in the list
    m.write_i32(ID, 0x607A, 0, 55).unwrap(); // not in the list
    m.write_u32(ID, 0x1010, 1, 0x6576_6173).unwrap();
    assert_eq!(m.write_u32(ID, 0x1010, 1, 0x1234).map_err(abort), Err(Some(0x0800_0020)), "wrong signature");
    m.write_u32(ID, 0x6081, 0, 1).unwrap();
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(m.read_u32(ID, 0x6081, 0).unwrap(), 77);
    assert_eq!(m.read_u32(ID, 0x2001, 1).unwrap(), 10);
    assert_eq!(m.read_i64(ID, 0x60FF, 0).unwrap(), -5);
    assert_eq!(m.read_u16(ID, 0x1017, 0).unwrap(), 250);
    assert_eq!(m.read_u64(ID, 0x607E, 0).unwrap(), 0x80);
    assert_eq!(m.read_i64(ID, 0x6060, 0).unwrap(), 0);
    assert_eq!(m.read_i64(ID, 0x607A, 0).unwrap(), 0);
    // 1011h "load": defaults from the next reset.
    m.write_u32(ID, 0x1011, 1, 0x6461_6F6C).unwrap();
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(m.read_u32(ID, 0x6081, 0).unwrap(), 0);
    assert_eq!(m.read_u32(ID, 0x2001, 1).unwrap(), 1);
    assert_eq!(m.read_u16(ID, 0x1017, 0).unwrap(), 0);
}

#[test]
fn saved_parameters_survive_a_restart_with_a_state_directory() {
    let dir = std::env::temp_dir().join(format!("drcs-state-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let config = NodeConfig { node_id: Some(ID), state_dir: Some(dir.clone()), ..Default::default() };
    let start = || {
        let mut sim = Sim::new();
        sim.add(DeviceKind::Drcs.build(&config, &DeviceApps::new()).unwrap());
        let mut m = Master::new(sim);
        m.advance(2000);
        m
    };
    let mut m = start();
    m.write_u32(ID, 0x2001, 1, 25).unwrap();
    m.write_u32(ID, 0x2001, 2, 2).unwrap();
    m.write_u32(ID, 0x6099, 1, 40).unwrap();
    m.write_u8(ID, 0x6098, 0, 18).unwrap();
    m.write_u8(ID, 0x6060, 0, 3).unwrap();
    m.write_u32(ID, 0x1010, 1, 0x6576_6173).unwrap();
    drop(m);
    let mut m = start();
    assert_eq!(m.read_u32(ID, 0x2001, 1).unwrap(), 25);
    assert_eq!(m.read_u32(ID, 0x2001, 2).unwrap(), 2);
    assert_eq!(m.read_u32(ID, 0x6099, 1).unwrap(), 40);
    assert_eq!(m.read_i64(ID, 0x6098, 0).unwrap(), 18);
    assert_eq!(m.read_i64(ID, 0x6060, 0).unwrap(), 0, "6060h is not in the store list");
    // The restored 2001h is in force: 607Dh sub 2 = 1000 mm × 25 / 2.
    assert_eq!(m.read_i64(ID, 0x607D, 2).unwrap(), 12_500);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn nmt_startup_1f80h() {
    let mut m = drcs();
    assert_eq!(m.read_u32(ID, 0x1F80, 0).unwrap(), 4);
    assert_eq!(m.write_u32(ID, 0x1F80, 0, 0x02).map_err(abort), Err(Some(0x0609_0030)), "unmanaged bit");
    // Bit 3 with bit 2 clear: the node starts by itself after a reset.
    m.write_u32(ID, 0x1F80, 0, 0x08).unwrap();
    m.write_u16(ID, 0x1017, 0, 50).unwrap();
    m.write_u32(ID, 0x1010, 1, 0x6576_6173).unwrap();
    m.nmt(0x81, ID);
    m.advance(200_000);
    let hb: Vec<u8> = m.take_id(0x700 + u32::from(ID)).iter().map(|s| s.frame.raw_data()[0]).collect();
    assert_eq!(hb.first(), Some(&0), "boot-up");
    assert_eq!(hb.last(), Some(&5), "operational by itself: {hb:?}");
    // With bit 2 set (the default) it waits for the master.
    m.write_u32(ID, 0x1F80, 0, 0x0C).unwrap();
    m.write_u32(ID, 0x1010, 1, 0x6576_6173).unwrap();
    m.nmt(0x81, ID);
    m.advance(200_000);
    let hb: Vec<u8> = m.take_id(0x700 + u32::from(ID)).iter().map(|s| s.frame.raw_data()[0]).collect();
    assert_eq!(hb.last(), Some(&0x7F), "pre-operational: {hb:?}");
}

#[test]
fn drive_sim_apps_build_the_drcs_with_a_trace() {
    let apps = DeviceApps::with_trace(0);
    let mut sim = Sim::new();
    sim.add(DeviceKind::Drcs.build(&NodeConfig { node_id: Some(ID), ..Default::default() }, &apps).unwrap());
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    enabled_and_homed(&mut m);
    move_to(&mut m, 100, false);
    let traces = apps.traces();
    assert_eq!(traces.len(), 1);
    assert_eq!(traces[0].0, DeviceKind::Drcs);
    let t = traces[0].1.lock().unwrap();
    assert_eq!(t.samples().last().unwrap().position_actual, 100, "bus units (mm)");
    assert!(t.samples().iter().any(|s| s.velocity_actual == 50));
}

#[test]
fn error_table_is_the_manual_list_plus_the_fieldbus_disconnection() {
    // The sidecar lists 8130h itself (with a decision): the app uses the sidecar's table as is.
    let t = drive::drives::error_table(DeviceKind::Drcs);
    let sidecar = drive::drives::sidecar(DeviceKind::Drcs).unwrap();
    assert!(sidecar.decisions.iter().any(|d| d.text.contains("8130h")), "a decision says why");
    let codes: Vec<u16> = t.entries().iter().map(|e| e.code).collect();
    assert_eq!(codes, vec![0x2310, 0x3120, 0x4210, 0x7305, 0x8613, 0x6320, 0x7320, 0xFF13, 0x5530, 0x8130]);
    let fieldbus = t.find(0x8130, None).unwrap();
    assert_eq!(fieldbus.reaction, drive::drives::Reaction::QuickStop);
    assert_eq!(fieldbus.register_bits(), 0x11);
}

/// The DRCS has no 605Ah/6085h: a quick stop from the controlword ramps down on 6084h and
/// ends in Switch on disabled (CiA 402 option 2), torqueless with the brake engaged.
#[test]
fn quick_stop_ramps_on_the_profile_deceleration() {
    let mut m = drcs();
    assert_eq!(m.read(ID, 0x605A, 0).map_err(abort), Err(Some(0x0602_0000)));
    assert_eq!(m.read(ID, 0x6085, 0).map_err(abort), Err(Some(0x0602_0000)));
    enabled_and_homed(&mut m);
    m.set_mode(ID, 3).unwrap();
    m.write_u32(ID, 0x6084, 0, 200).unwrap();
    m.write_i32(ID, 0x60FF, 0, 100).unwrap();
    m.advance(1_500_000);
    assert_eq!(velocity(&mut m), 100);
    m.controlword(ID, 0x0B).unwrap();
    m.advance(250_000);
    assert_eq!(m.state(ID).unwrap(), Some(State::QuickStopActive));
    let v = velocity(&mut m);
    assert!((40..=60).contains(&v), "100 mm/s at 200 mm/s² after 0.25 s: {v}");
    m.advance(300_000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert_eq!(velocity(&mut m), 0);
    assert_eq!(m.read_u64(ID, 0x2005, 0).unwrap(), 1);
    assert!(emcys(&mut m).is_empty());
}
