//! The Camozzi DRVI (drive::drives::drvi) on the in-memory bus through real frames: every mode,
//! every homing method, units (2014h, 2001h), software limits, warnings (2006h), errors of
//! Table 6.34 with their manufacturer byte, fault reset both ways, persistence.

use std::sync::{Arc, Mutex};

use crate::support::{Master, abort};
use drive::drives::drvi::{self, Drvi, warning};
use drive::drives::{Cia402App, SharedTrace, Vendor};
use drive::motion::{Cam, Environment, Machine, Ratio as Ratio1};
use drive::node::{MemoryRetain, Node, NodeStorage, ParameterSet, Sim};
use drive::storage::FileStorage;
use drive::trace::Trace;
use generated::drvi::Dictionary;
use generated::drvi::units::{Dimension, Quantity, Ratio, Unit, Units};
use od_runtime::NodeId;
use od_runtime::cia402::State;
use od_runtime::od::ObjectDictionary;

const ID: u8 = 3;
const EMCY: u32 = 0x80 + ID as u32;

type DrviNode = Node<Dictionary, Cia402App<Dictionary, Drvi>>;

fn master_with(storage: NodeStorage, trace: Option<SharedTrace>) -> Master {
    let mut sim = Sim::new();
    let mut app = drvi::actuator_app();
    if let Some(t) = trace {
        app = app.with_trace(t);
    }
    sim.add(Box::new(Node::new(Dictionary::new(ID), app, storage, NodeId::new(ID).unwrap())));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m.take_seen();
    m
}

fn master() -> Master {
    master_with(NodeStorage::memory(), None)
}

fn app(m: &Master) -> &Cia402App<Dictionary, Drvi> {
    m.sim().downcast::<DrviNode>(0).unwrap().app().unwrap()
}

fn app_mut(m: &mut Master) -> &mut Cia402App<Dictionary, Drvi> {
    m.sim_mut().downcast_mut::<DrviNode>(0).unwrap().app_mut().unwrap()
}

fn set_environment(m: &mut Master, env: Environment) {
    *app_mut(m).drive_mut().axis_mut().environment_mut() = env;
}

fn state(m: &mut Master) -> State {
    m.state(ID).unwrap().unwrap()
}

fn sw(m: &mut Master) -> u16 {
    m.statusword(ID).unwrap()
}

fn pos(m: &mut Master) -> i64 {
    m.read_i64(ID, 0x6064, 0).unwrap()
}

fn vel(m: &mut Master) -> i64 {
    m.read_i64(ID, 0x606C, 0).unwrap()
}

fn warnings(m: &mut Master) -> u16 {
    m.read_u16(ID, 0x2006, 0).unwrap()
}

fn profile(m: &mut Master, v: u32, a: u32) {
    m.write_u32(ID, 0x6081, 0, v).unwrap();
    m.write_u32(ID, 0x6083, 0, a).unwrap();
    m.write_u32(ID, 0x6084, 0, a).unwrap();
}

fn homing_params(m: &mut Master, method: i8, offset: i32) {
    m.write(ID, 0x6098, 0, &[method as u8]).unwrap();
    m.write_u32(ID, 0x6099, 1, 3000).unwrap(); // 30 rpm
    m.write_u32(ID, 0x6099, 2, 500).unwrap(); // 5 rpm
    m.write_u32(ID, 0x609A, 0, 200).unwrap(); // 200 rpm/s
    m.write_i32(ID, 0x607C, 0, offset).unwrap();
}

/// Runs a homing to completion (sw bits 12 and 10), returns the statusword.
fn home(m: &mut Master, method: i8, offset: i32) -> u16 {
    homing_params(m, method, offset);
    m.set_mode(ID, 6).unwrap();
    if state(m) != State::OperationEnabled {
        m.switch_on(ID).unwrap();
    }
    m.controlword(ID, 0x0F).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    let sw = m.wait_statusword(ID, 0x3400, 0x1400, 60_000_000, 20_000).unwrap_or_else(|| {
        let s = m.statusword(ID).unwrap();
        panic!("homing {method} did not complete: statusword {s:#06X}")
    });
    m.controlword(ID, 0x0F).unwrap();
    sw
}

/// An absolute or relative profile-position move to its end.
fn move_to(m: &mut Master, target: i32, relative: bool) {
    m.set_mode(ID, 1).unwrap();
    m.write_i32(ID, 0x607A, 0, target).unwrap();
    let rel = if relative { 0x40 } else { 0 };
    m.controlword(ID, 0x0F | rel).unwrap();
    m.controlword(ID, 0x1F | rel).unwrap();
    assert_ne!(sw(m) & (1 << 12), 0, "set-point acknowledged");
    m.controlword(ID, 0x0F | rel).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 30_000_000, 10_000).expect("target reached");
}

fn emcys(m: &mut Master) -> Vec<[u8; 8]> {
    m.take_id(EMCY).iter().map(|s| s.frame.raw_data()).collect()
}

// ---------------------------------------------------------------------------------------------
// Modes.

#[test]
fn positioning_needs_homing_first() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 1).unwrap();
    profile(&mut m, 6000, 60);
    m.write_i32(ID, 0x607A, 0, 36_000).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(sw(&mut m) & (1 << 12), 0, "refused: no acknowledge");
    assert_eq!(pos(&mut m), 0);
    assert_ne!(warnings(&mut m) & warning::HOMING_MISSING, 0);
    assert_ne!(sw(&mut m) & (1 << 7), 0, "statusword warning bit");
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 0);
    // Homing 37 clears "homing missing" by itself (auto reset) and sets 2004h.
    home(&mut m, 37, 0);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
    assert_eq!(warnings(&mut m) & warning::HOMING_MISSING, 0);
    assert_eq!(sw(&mut m) & (1 << 7), 0);
}

#[test]
fn absolute_and_relative_moves_follow_figure_4_2() {
    let mut m = master();
    home(&mut m, 37, 0);
    profile(&mut m, 6000, 60); // 60 rpm, 60 rpm/s
    let t0 = m.now();
    move_to(&mut m, 72_000, false); // 720°
    let took = (m.now() - t0) as f64 * 1e-6;
    assert!((3.0..3.1).contains(&took), "1 s up, 1 s at 60 rpm, 1 s down: {took}");
    assert_eq!(pos(&mut m), 72_000);
    // 4.1.2.1: relative to the actual position.
    move_to(&mut m, -36_000, true);
    assert_eq!(pos(&mut m), 36_000);
    // 4.1.2.2: absolute to where it is: no motion.
    move_to(&mut m, 36_000, false);
    assert_eq!(pos(&mut m), 36_000);
}

#[test]
fn a_new_target_during_a_move_is_refused_and_the_warning_resets_itself() {
    let mut m = master();
    home(&mut m, 37, 0);
    profile(&mut m, 6000, 60);
    m.set_mode(ID, 1).unwrap();
    m.write_i32(ID, 0x607A, 0, 72_000).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(500_000);
    m.write_i32(ID, 0x607A, 0, 0).unwrap();
    m.controlword(ID, 0x3F).unwrap(); // even with "change immediately"
    assert_eq!(sw(&mut m) & (1 << 12), 0);
    assert_ne!(warnings(&mut m) & warning::COMMAND_REFUSED, 0);
    m.controlword(ID, 0x0F).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 10_000_000, 10_000).unwrap();
    assert_eq!(pos(&mut m), 72_000, "the first target stood");
    // The next accepted command clears "command refused".
    m.controlword(ID, 0x1F).unwrap();
    assert_eq!(warnings(&mut m) & warning::COMMAND_REFUSED, 0);
    m.controlword(ID, 0x0F).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 10_000_000, 10_000).unwrap();
    assert_eq!(pos(&mut m), 0);
}

#[test]
fn profile_velocity_with_halt_and_the_speed_bit() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 60);
    m.write_u16(ID, 0x606F, 0, 10).unwrap(); // 0.1 rpm
    m.write_u16(ID, 0x6070, 0, 20).unwrap(); // 20 ms
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    m.controlword(ID, 0x1F).unwrap(); // 6.5: bit 4 starts (60FFh applies anyway)
    m.advance(1_100_000);
    assert_eq!(vel(&mut m), 6000);
    let s = sw(&mut m);
    assert_ne!(s & (1 << 10), 0, "velocity reached");
    assert_eq!(s & (1 << 12), 0, "moving");
    m.controlword(ID, 0x11F).unwrap(); // halt
    m.advance(300_000);
    assert_eq!(sw(&mut m) & (1 << 10), 0, "decelerating");
    m.advance(900_000);
    assert_eq!(vel(&mut m), 0);
    let s = sw(&mut m);
    assert_ne!(s & (1 << 10), 0, "halted: stopped");
    assert_ne!(s & (1 << 12), 0, "speed bit: standing");
    m.controlword(ID, 0x1F).unwrap();
    m.advance(1_100_000);
    assert_eq!(vel(&mut m), 6000, "resumes");
}

#[test]
fn profile_torque_follows_the_slope_of_figure_4_4() {
    let mut m = master();
    set_environment(&mut m, Environment::default()); // no end stops in the way
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 4).unwrap();
    m.write_u32(ID, 0x6087, 0, 1000).unwrap(); // 1000 mA/s
    m.write(ID, 0x6071, 0, &1000i16.to_le_bytes()).unwrap();
    m.advance(500_000);
    let t = m.read_i64(ID, 0x6074, 0).unwrap();
    assert!((480..=520).contains(&t), "{t}");
    m.advance(600_000);
    assert_eq!(m.read_i64(ID, 0x6074, 0).unwrap(), 1000);
    assert!(vel(&mut m) > 0, "the motor turns");
    assert_ne!(sw(&mut m) & (1 << 10), 0, "target torque reached");
    m.write(ID, 0x6071, 0, &0i16.to_le_bytes()).unwrap();
    m.advance(1_100_000);
    assert_eq!(m.read_i64(ID, 0x6074, 0).unwrap(), 0);
}

#[test]
fn torque_limit_2015h_caps_every_mode_and_sets_bit_14() {
    let mut m = master();
    home(&mut m, 37, 0);
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 10_000); // a hard acceleration: 10000 rpm/s needs about 1.7 A
    m.write(ID, 0x6071, 0, &300i16.to_le_bytes()).unwrap(); // limit 300 mA
    m.write_u8(ID, 0x2015, 0, 1).unwrap();
    m.write_i32(ID, 0x60FF, 0, 100_000).unwrap(); // 1000 rpm
    m.advance(50_000);
    let current = m.read_i64(ID, 0x6077, 0).unwrap();
    assert!(current.abs() <= 300, "{current}");
    assert_ne!(sw(&mut m) & (1 << 14), 0, "torque limit active");
    m.write_u8(ID, 0x2015, 0, 0).unwrap();
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.advance(2_000_000);
    assert_eq!(sw(&mut m) & (1 << 14), 0);
}

#[test]
fn jog_with_controlword_bits_5_and_6() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, -1).unwrap();
    assert_eq!(m.read_i64(ID, 0x6061, 0).unwrap(), -1);
    profile(&mut m, 0, 600);
    m.write_i32(ID, 0x60FF, 0, -3000).unwrap(); // the sign does not matter
    m.controlword(ID, 0x4F).unwrap(); // bit 6: clockwise
    m.advance(200_000);
    assert_eq!(vel(&mut m), 3000);
    assert_eq!(sw(&mut m) & 0x3000, 0x1000, "jog clockwise");
    m.controlword(ID, 0x6F).unwrap(); // both: invalid, the previous state persists
    m.advance(50_000);
    assert_eq!(vel(&mut m), 3000);
    m.controlword(ID, 0x2F).unwrap(); // bit 5: counter-clockwise
    m.advance(300_000);
    assert_eq!(vel(&mut m), -3000);
    assert_eq!(sw(&mut m) & 0x3000, 0x2000);
    m.controlword(ID, 0x0F).unwrap();
    m.advance(300_000);
    assert_eq!(vel(&mut m), 0);
    assert_eq!(sw(&mut m) & 0x3000, 0, "jog off");
}

#[test]
fn unsupported_modes_and_methods_are_refused() {
    let mut m = master();
    for mode in [2u8, 5, 7, 8, 0xFE] {
        assert_eq!(m.write(ID, 0x6060, 0, &[mode]).map_err(abort), Err(Some(0x0609_0030)), "mode {mode}");
    }
    for method in [3u8, 19, 33, 35, 0xFB] {
        assert_eq!(m.write(ID, 0x6098, 0, &[method]).map_err(abort), Err(Some(0x0609_0030)), "method {method}");
    }
}

// ---------------------------------------------------------------------------------------------
// Homing: every method of Table 6.29.

/// Homes with `method` and offset 777 in `env`, returning the mechanical home point (the
/// position the trace shows right before the frame switched to the offset).
fn home_point(method: i8, env: Environment) -> i64 {
    home_point_with_polarity(method, env, 0)
}

/// [`home_point`] with 607Eh = `polarity`.
fn home_point_with_polarity(method: i8, env: Environment, polarity: u8) -> i64 {
    let trace: SharedTrace = Arc::new(Mutex::new(Trace::new()));
    let mut m = master_with(NodeStorage::memory(), Some(Arc::clone(&trace)));
    set_environment(&mut m, env);
    m.write_u8(ID, 0x607E, 0, polarity).unwrap();
    let s = home(&mut m, method, 777);
    assert_eq!(s & 0x3400, 0x1400, "bits 12 and 10: completed");
    assert_eq!(pos(&mut m), 777, "6.3.4.14: the actual position becomes the offset");
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
    let t = trace.lock().unwrap();
    let samples = t.samples();
    let i = samples.iter().rposition(|s| s.position_actual != 777).expect("motion before the switch");
    i64::from(samples[i].position_actual)
}

fn env(cam: (i64, i64)) -> Environment {
    Environment { home_switch: Some(Cam { low: cam.0, high: cam.1 }), ..drvi::default_environment() }
}

#[test]
fn homing_17_18_on_the_proximity() {
    assert_eq!(home_point(18, env((20_000, 25_000))), 20_000, "leaves it negative: its low edge");
    assert_eq!(home_point(17, env((-25_000, -20_000))), -20_000, "leaves it positive: its high edge");
    // Already on the proximity at the start: only the out phase.
    assert_eq!(home_point(18, env((-1_000, 5_000))), -1_000);
}

/// 6.3.4.16: the polarity "has an impact to ALL the mode of operation (homings, ...)": with
/// 607Eh = 80h every direction is the drive's reversed one, so method 17 (negative search)
/// finds the proximity on the motor's positive side and leaves it going the motor's negative
/// way: the cam's low mechanical edge, read in the reversed frame.
#[test]
fn reversed_polarity_reverses_the_homing_searches() {
    assert_eq!(home_point_with_polarity(17, env((20_000, 25_000)), 0x80), -20_000);
    assert_eq!(home_point_with_polarity(18, env((-25_000, -20_000)), 0x80), 20_000);
    let ends = drvi::default_environment(); // end stops at −50000 and 150000 (motor frame)
    assert_eq!(home_point_with_polarity(-3, ends, 0x80), -150_000, "the motor's positive end stop");
    assert_eq!(home_point_with_polarity(-4, ends, 0x80), 50_000);
}

/// 6.7: the homing runs at 6099h sub 1 (search) and sub 2 (leaving the proximity), with the
/// ramps of 609Ah: method 18 at 30 rpm, 5 rpm, 200 rpm/s.
#[test]
fn homing_runs_at_the_6099h_speeds_with_the_609ah_ramps() {
    let trace: SharedTrace = Arc::new(Mutex::new(Trace::new()));
    let mut m = master_with(NodeStorage::memory(), Some(Arc::clone(&trace)));
    set_environment(&mut m, env((20_000, 25_000)));
    home(&mut m, 18, 0); // homing_params: 6099h = 3000, 500 (0.01 rpm), 609Ah = 200 rpm/s
    let t = trace.lock().unwrap();
    let v: Vec<(u64, i32)> = t.samples().iter().map(|s| (s.time_us, s.velocity_demand)).collect();
    assert_eq!(v.iter().map(|s| s.1).max(), Some(3000), "search at 30 rpm");
    assert_eq!(v.iter().map(|s| s.1).min(), Some(-500), "leaving the proximity at 5 rpm");
    // The acceleration: 200 rpm/s = 20 000 bus units per s², 1000 in the first 50 ms.
    let start = v.iter().find(|s| s.1 > 0).unwrap().0;
    let at = |t_us: u64| v.iter().find(|s| s.0 >= t_us).unwrap().1;
    assert!((900..=1100).contains(&at(start + 50_000)), "{}", at(start + 50_000));
    assert!((1900..=2100).contains(&at(start + 100_000)), "{}", at(start + 100_000));
}

#[test]
fn homing_1_2_on_the_index_after_the_proximity() {
    // Index pulses at 1000 + k·36000.
    assert_eq!(home_point(2, env((20_000, 25_000))), 1_000);
    assert_eq!(home_point(1, env((-25_000, -20_000))), 1_000);
    assert_eq!(home_point(1, env((-45_000, -40_000))), -35_000, "the first index beyond the edge");
}

#[test]
fn torque_homings_push_against_the_end_stops() {
    let ends = drvi::default_environment(); // end stops at −50000 and 150000
    assert_eq!(home_point(-3, ends), -50_000);
    assert_eq!(home_point(-4, ends), 150_000);
    assert_eq!(home_point(-1, ends), -35_000, "then the index going positive");
    assert_eq!(home_point(-2, ends), 145_000, "then the index going negative");
}

#[test]
fn homing_37_needs_no_speeds() {
    let mut m = master(); // 6098h = 37 and 6099h = 0 by default
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(5_000);
    assert_eq!(sw(&mut m) & 0x3400, 0x1400);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
}

#[test]
fn homing_37_takes_the_current_position() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 600);
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    m.advance(500_000);
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.advance(500_000);
    let before = pos(&mut m);
    assert!(before > 0);
    home(&mut m, 37, -500);
    assert_eq!(pos(&mut m), -500);
}

#[test]
fn torque_homing_uses_6071h_and_the_2013h_threshold() {
    let trace: SharedTrace = Arc::new(Mutex::new(Trace::new()));
    let mut m = master_with(NodeStorage::memory(), Some(Arc::clone(&trace)));
    m.write(ID, 0x6071, 0, &800i16.to_le_bytes()).unwrap(); // limit 800 mA
    m.write_u16(ID, 0x2013, 0, 12).unwrap(); // 12 % of 5 A = 600 mA
    home(&mut m, -4, 0);
    let peak = trace.lock().unwrap().samples().iter().map(|s| s.torque_actual.abs()).max().unwrap();
    assert!((600..=800).contains(&peak), "pushed to the threshold, within the limit: {peak}");
}

#[test]
fn a_proximity_overrun_is_the_soft_homing_error_8613h() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    homing_params(&mut m, 18, 0);
    m.write_u32(ID, 0x6099, 1, 30_000).unwrap(); // 300 rpm
    m.write_u32(ID, 0x609A, 0, 100).unwrap(); // 100 rpm/s: stops far beyond the proximity
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    assert!(m.wait_until(20_000_000, 10_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    let e = emcys(&mut m);
    assert_eq!(e[0], [0x13, 0x86, 0x01, 13, 0, 0, 0, 0], "8613h, manufacturer byte 13");
    // Found when the axis has stopped beyond the proximity: the quick stop has nothing to do.
    assert_eq!(state(&mut m), State::Fault);
    assert_ne!(sw(&mut m) & (1 << 13), 0, "homing error bit");
    assert_eq!(vel(&mut m), 0);
    assert_eq!(m.read_u32(ID, 0x1003, 1).unwrap(), 0x000D_8613, "1003h: code + manufacturer info");
}

// ---------------------------------------------------------------------------------------------
// Units.

#[test]
fn actuator_type_2014h_switches_the_unit_system() {
    let mut m = master();
    free_machine(&mut m);
    home(&mut m, 37, 0);
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 100);
    // Only motor: 6000 = 60 rpm = 360 °/s = 36000 position units/s.
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    m.advance(1_000_000);
    let p0 = pos(&mut m);
    m.advance(1_000_000);
    assert_eq!(pos(&mut m) - p0, 36_000);
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.advance(1_000_000);
    // Custom actuator with the default screw pitch 6092h = 100/1 (1 mm per turn, 6.3.4.23):
    // 1000 = 10 mm/s = 1000 position units (0.01 mm) per second, ten motor turns a second.
    m.write_u8(ID, 0x2014, 0, 7).unwrap();
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    m.advance(1_000_000);
    let (p0, c0) = (pos(&mut m), counts(&m));
    m.advance(1_000_000);
    assert_eq!(pos(&mut m) - p0, 1_000);
    assert_eq!(counts(&m) - c0, 10 * 36_000, "ten motor turns");
    let units = generated::drvi::units::Units::from_dictionary(&{
        let mut od = Dictionary::new(ID);
        od.set_actuator_type(7).unwrap();
        od
    })
    .unwrap();
    assert_eq!(units.unit(generated::drvi::units::Dimension::Position), Some(generated::drvi::units::Unit::Millimeter));
}

/// The generated units module fed with the drive's own 2014h, 2001h, 6091h and 6092h, as a
/// master would build it.
fn units(m: &mut Master) -> Units {
    let mut od = Dictionary::new(ID);
    od.set_actuator_type(m.read_u8(ID, 0x2014, 0).unwrap()).unwrap();
    for (index, sub) in [(0x2001, 1), (0x2001, 2), (0x6091, 1), (0x6091, 2), (0x6092, 1), (0x6092, 2)] {
        let v = m.read_u32(ID, index, sub).unwrap();
        od.write(index, sub, &v.to_le_bytes()).unwrap();
    }
    Units::from_dictionary(&od).unwrap()
}

/// A free motor (no end stops): the unit tests turn it many times.
fn free_machine(m: &mut Master) {
    set_environment(m, Machine::free().environment(drvi::COUNTS_PER_MACHINE_UNIT, drvi::MACHINE_UNITS_PER_TURN));
}

/// The motor's position in the drive's counts (0.01° of the motor, 36 000 a turn).
fn counts(m: &Master) -> i64 {
    i64::from(app(m).drive().axis().status().position_actual)
}

fn raw(m: &mut Master, d: Dimension, q: Quantity) -> i64 {
    units(m).to_raw(d, q).unwrap()
}

fn physical(m: &mut Master, d: Dimension, index: u16) -> Quantity {
    let value = m.read_i64(ID, index, 0).unwrap();
    units(m).to_physical(d, value).unwrap()
}

fn quantity(n: i128, d: i128, unit: Unit) -> Quantity {
    Quantity::new(Ratio::new(n, d).unwrap(), unit)
}

/// Issue #7 point 8 on the DRVI: absolute and relative moves given in physical units, converted
/// by `generated::drvi::units` from the unit system the drive reports (2014h) and its feed
/// converter (2001h), in degrees (only motor), millimetres (actuator) and inches (2001h).
#[test]
fn moves_in_degrees_millimetres_and_inches_through_the_generated_units() {
    use Dimension::{Acceleration, Position, Velocity};
    let mut m = master();
    free_machine(&mut m);
    home(&mut m, 37, 0);
    assert_eq!(units(&mut m).unit(Position), Some(Unit::Degree));
    let v = raw(&mut m, Velocity, Quantity::int(60, Unit::Rpm));
    let a = raw(&mut m, Acceleration, Quantity::int(600, Unit::RpmPerSecond));
    profile(&mut m, v as u32, a as u32);
    let target = raw(&mut m, Position, Quantity::int(450, Unit::Degree));
    let t0 = m.now();
    move_to(&mut m, target as i32, false);
    let took = (m.now() - t0) as f64 * 1e-6;
    assert!((1.35..1.45).contains(&took), "450 deg at 360 deg/s with 0.1 s ramps: {took} s");
    assert_eq!(physical(&mut m, Position, 0x6064), Quantity::int(450, Unit::Degree));
    let back = raw(&mut m, Position, quantity(-361, 4, Unit::Degree));
    move_to(&mut m, back as i32, true);
    assert_eq!(physical(&mut m, Position, 0x6064), quantity(1439, 4, Unit::Degree), "359.75 deg");

    // A custom actuator (2014h = 7) with a 5 mm screw (6092h = 500/1): 0.01 mm; then inches
    // through 2001h = 100/254.
    m.write_u8(ID, 0x2014, 0, 7).unwrap();
    m.write_u32(ID, 0x6092, 1, 500).unwrap();
    assert_eq!(units(&mut m).unit(Position), Some(Unit::Millimeter));
    let v = raw(&mut m, Velocity, Quantity::int(100, Unit::MillimeterPerSecond));
    let a = raw(&mut m, Acceleration, Quantity::int(1000, Unit::MillimeterPerSecond2));
    profile(&mut m, v as u32, a as u32);
    let target = raw(&mut m, Position, quantity(127, 10, Unit::Millimeter));
    move_to(&mut m, target as i32, false);
    assert_eq!(pos(&mut m), 1270);
    assert_eq!(physical(&mut m, Position, 0x6064), quantity(127, 10, Unit::Millimeter));
    m.write_u32(ID, 0x2001, 1, 100).unwrap();
    m.write_u32(ID, 0x2001, 2, 254).unwrap();
    assert_eq!(pos(&mut m), 500, "12.7 mm = 0.5 in in thousandths");
    assert_eq!(physical(&mut m, Position, 0x6064), quantity(127, 10, Unit::Millimeter));
    let v = raw(&mut m, Velocity, quantity(254, 10, Unit::MillimeterPerSecond));
    let a = raw(&mut m, Acceleration, Quantity::int(254, Unit::MillimeterPerSecond2));
    assert_eq!((v, a), (1000, 100), "1 in/s in 0.001 in/s, 10 in/s^2 in 0.1 in/s^2 (Table 6.2 × 100/254)");
    profile(&mut m, v as u32, a as u32);
    let back = raw(&mut m, Position, quantity(-254, 100, Unit::Millimeter));
    move_to(&mut m, back as i32, true);
    assert_eq!(pos(&mut m), 400);
    assert_eq!(physical(&mut m, Position, 0x6064), quantity(1016, 100, Unit::Millimeter));
    // Velocities too: profile velocity at 1 in/s reads 25.4 mm/s back.
    m.set_mode(ID, 3).unwrap();
    m.write_i32(ID, 0x60FF, 0, v as i32).unwrap();
    m.advance(500_000);
    assert_eq!(physical(&mut m, Velocity, 0x606C), quantity(254, 10, Unit::MillimeterPerSecond));
}

#[test]
fn feed_converter_2001h_rescales_sdo_and_pdo_values() {
    let mut m = master();
    home(&mut m, 37, 0);
    profile(&mut m, 6000, 600);
    move_to(&mut m, 25_400, false);
    // Inches (6.3.6.1): numerator 100, denominator 254: the bus unit is now 0.0254 of the old.
    m.write_u32(ID, 0x2001, 1, 100).unwrap();
    m.write_u32(ID, 0x2001, 2, 254).unwrap();
    m.advance(2000);
    assert_eq!(pos(&mut m), 10_000);
    // TPDO with 6064h: the same value.
    m.write_u32(ID, 0x1801, 1, 0x8000_0283).unwrap();
    m.write_u8(ID, 0x1A01, 0, 0).unwrap();
    m.write_u32(ID, 0x1A01, 1, 0x6064_0020).unwrap();
    m.write_u8(ID, 0x1A01, 0, 1).unwrap();
    m.take_seen();
    m.write_u32(ID, 0x1801, 1, 0x283).unwrap();
    m.advance(20_000);
    let tpdo = m.take_id(0x283);
    assert_eq!(tpdo.last().unwrap().frame.data(), 10_000i32.to_le_bytes());
    // Targets in the new unit: 5000 = half the way back.
    move_to(&mut m, 5_000, false);
    assert_eq!(pos(&mut m), 5_000);
    // A target by RPDO (RPDO2 = 607Ah) is in the new unit too: 7500 thousandths of an inch.
    m.write_u32(ID, 0x1401, 1, 0x8000_0303).unwrap();
    m.write_u8(ID, 0x1601, 0, 0).unwrap();
    m.write_u32(ID, 0x1601, 1, 0x607A_0020).unwrap();
    m.write_u8(ID, 0x1601, 0, 1).unwrap();
    m.write_u32(ID, 0x1401, 1, 0x303).unwrap();
    m.pdo(0x303, &7_500i32.to_le_bytes());
    m.advance(2000);
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 30_000_000, 10_000).expect("target reached");
    assert_eq!(pos(&mut m), 7_500);
    assert_eq!(app(&m).drive().axis().status().position_actual, 19_050, "7500 x 254 / 100 default units");
    move_to(&mut m, 5_000, false);
    m.write_u32(ID, 0x2001, 1, 1).unwrap();
    m.write_u32(ID, 0x2001, 2, 1).unwrap();
    m.advance(2000);
    assert_eq!(pos(&mut m), 12_700);
}

/// A unit change shows in what the master reads next, before the next control tick: 2001h
/// rescales 6064h and 6062h at once, 2014h switches 606Ch from 0.01 rpm to 0.01 mm/s at once.
#[test]
fn unit_changes_show_in_the_actual_values_at_once() {
    let mut m = master();
    home(&mut m, 37, 0);
    profile(&mut m, 6000, 600);
    move_to(&mut m, 25_400, false);
    let ticks = app(&m).drive().ticks();
    m.write_u32(ID, 0x2001, 2, 254).unwrap(); // numerator 1: 254 old units per new one
    assert_eq!(pos(&mut m), 100);
    assert_eq!(m.read_i64(ID, 0x6062, 0).unwrap(), 100);
    assert_eq!(app(&m).drive().ticks(), ticks, "no tick in between");
    m.write_u32(ID, 0x2001, 2, 1).unwrap();
    // 60 rpm only motor, one turn a second; as an actuator with the default 1 mm screw
    // (6092h = 100/1) that is 1 mm/s = 100 (0.01 mm/s).
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 100);
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    m.advance(1_000_000);
    assert_eq!(vel(&mut m), 6000);
    let ticks = app(&m).drive().ticks();
    let at = pos(&mut m);
    m.write_u8(ID, 0x2014, 0, 7).unwrap();
    assert_eq!(vel(&mut m), 100, "the speed of a moment ago in the new unit");
    // 6064h: the same motor angle, 25 400 + a turn and a bit (0.01°), in 0.01 mm of a 1 mm screw.
    let mm = |deg: i64, pitch: i64| (deg * pitch + 18_000 * deg.signum()) / 36_000;
    assert_eq!(pos(&mut m), mm(at, 100));
    // 6092h and 6091h too: a 5 mm screw, then a 2:1 gear in front of it.
    m.write_u32(ID, 0x6092, 1, 500).unwrap();
    assert_eq!(vel(&mut m), 500);
    assert_eq!(pos(&mut m), mm(at, 500));
    m.write_u32(ID, 0x6091, 1, 2).unwrap();
    m.write_u32(ID, 0x6091, 2, 1).unwrap();
    assert_eq!(vel(&mut m), 250);
    assert_eq!(pos(&mut m), mm(at, 250));
    assert_eq!(app(&m).drive().ticks(), ticks, "no tick in between");
}

/// An actuator (2014h = 7) with the screw pitch 6092h = `feed`/1 and the gear 6091h, on a
/// free motor homed at 0.
fn actuator(feed: u32, gear: (u32, u32)) -> Master {
    let mut m = master();
    free_machine(&mut m);
    home(&mut m, 37, 0);
    m.write_u8(ID, 0x2014, 0, 7).unwrap();
    m.write_u32(ID, 0x6092, 1, feed).unwrap();
    m.write_u32(ID, 0x6091, 1, gear.0).unwrap();
    m.write_u32(ID, 0x6091, 2, gear.1).unwrap();
    m
}

/// Issue #28, as a master following 6.3.4.23 sees it: one motor turn in the only-motor
/// configuration (6064h = 36000, 0.01°), then the custom actuator: 6064h is the screw's travel
/// for one turn, 1.00 mm at 6092h = 100/1, 5.00 mm at 500/1, half that behind a 2:1 gear
/// (6091h = 2/1); the default 0/0 gear is 1:1. The generated units agree on every value.
#[test]
fn one_motor_turn_is_the_screw_pitch_through_the_gear() {
    use Dimension::Position;
    for (feed, gear, travel) in
        [(100, (0, 0), 100), (100, (1, 1), 100), (500, (0, 0), 500), (100, (2, 1), 50), (500, (2, 1), 250)]
    {
        let mut m = master();
        free_machine(&mut m);
        home(&mut m, 37, 0);
        profile(&mut m, 6000, 600);
        move_to(&mut m, 36_000, false);
        assert_eq!(counts(&m), 36_000, "one motor turn");
        m.write_u8(ID, 0x2014, 0, 7).unwrap();
        m.write_u32(ID, 0x6092, 1, feed).unwrap();
        m.write_u32(ID, 0x6091, 1, gear.0).unwrap();
        m.write_u32(ID, 0x6091, 2, gear.1).unwrap();
        let why = format!("6092h = {feed}/1, 6091h = {}/{}", gear.0, gear.1);
        assert_eq!(pos(&mut m), travel, "{why}");
        assert_eq!(m.read_i64(ID, 0x6062, 0).unwrap(), travel, "{why}: the demand too");
        let u = units(&mut m);
        assert_eq!(physical(&mut m, Position, 0x6064), quantity(travel.into(), 100, Unit::Millimeter), "{why}");
        assert_eq!(u.to_internal(Position, travel).unwrap(), Ratio::int(1), "{why}: one motor revolution");
        let one_turn = u.internal_to_physical(Position, Ratio::int(1)).unwrap();
        assert_eq!(one_turn, quantity(travel.into(), 100, Unit::Millimeter), "{why}");
        assert_eq!(u.internal_to_raw(Position, Ratio::int(1)).unwrap(), travel, "{why}");
    }
}

/// A move to 10.00 mm turns the motor 10 times at 6092h = 100/1 (20 times behind a 2:1 gear,
/// twice at 500/1); the target, the profile and the actual values all in 0.01 mm, the
/// velocity read back in 0.01 mm/s, and the generated units give the same motor revolutions.
#[test]
fn a_move_to_10_mm_turns_the_motor_as_the_screw_and_the_gear_say() {
    use Dimension::{Acceleration, Position, Velocity};
    for (feed, gear, turns) in [(100, (1, 1), 10), (100, (2, 1), 20), (500, (1, 1), 2), (500, (3, 2), 3)] {
        let mut m = actuator(feed, gear);
        let why = format!("6092h = {feed}/1, 6091h = {}/{}", gear.0, gear.1);
        let v = raw(&mut m, Velocity, Quantity::int(5, Unit::MillimeterPerSecond));
        let a = raw(&mut m, Acceleration, Quantity::int(50, Unit::MillimeterPerSecond2));
        assert_eq!((v, a), (500, 50));
        profile(&mut m, v as u32, a as u32);
        let target = raw(&mut m, Position, Quantity::int(10, Unit::Millimeter));
        assert_eq!(target, 1000);
        move_to(&mut m, target as i32, false);
        assert_eq!(counts(&m), turns * 36_000, "{why}: {turns} motor turns");
        assert_eq!(pos(&mut m), 1000, "{why}");
        let u = units(&mut m);
        assert_eq!(u.to_internal(Position, 1000).unwrap(), Ratio::int(turns), "{why}");
        // Back at the profile velocity: 5 mm/s, read as 500 (0.01 mm/s) while it runs.
        m.write_i32(ID, 0x607A, 0, 0).unwrap();
        m.controlword(ID, 0x1F).unwrap();
        m.advance(400_000);
        assert_eq!(vel(&mut m), -500, "{why}");
        let rev_s = u.to_internal(Velocity, -500).unwrap();
        assert_eq!(rev_s, Ratio::new(-5 * i128::from(turns), 10).unwrap(), "{why}: motor rev/s");
        m.controlword(ID, 0x0F).unwrap();
        m.wait_statusword(ID, 1 << 10, 1 << 10, 30_000_000, 10_000).expect("target reached");
        assert_eq!((counts(&m), pos(&mut m)), (0, 0), "{why}");
    }
}

/// The machine's positions are the motor's (0.01°, the power-on unit): an actuator shows them
/// through the screw. The `drvi-actuator` preset's proximity (PROXY INPUT, 2002h bit 3) lies
/// at 200°..250° of the motor: 20.00..25.00 mm on a 36 mm screw (6092h = 3600/1), half that
/// behind a 2:1 gear.
#[test]
fn the_machine_shows_through_the_screw_and_the_gear() {
    for (gear, low, high) in [((1, 1), 2_000, 2_500), ((2, 1), 1_000, 1_250)] {
        let mut m = master();
        home(&mut m, 37, 0);
        m.write_u8(ID, 0x2014, 0, 7).unwrap();
        m.write_u32(ID, 0x6092, 1, 3_600).unwrap();
        m.write_u32(ID, 0x6091, 1, gear.0).unwrap();
        m.write_u32(ID, 0x6091, 2, gear.1).unwrap();
        profile(&mut m, 1_000, 100);
        let proxy = |m: &mut Master| m.read_u32(ID, 0x2002, 0).unwrap() & 0b1000 != 0;
        for (target, on) in [(low - 10, false), (low + 10, true), (high - 10, true), (high + 10, false)] {
            move_to(&mut m, target, false);
            assert_eq!(proxy(&mut m), on, "6091h = {}/{}: at {target}", gear.0, gear.1);
        }
    }
}

/// 2001h and 6092h divide: a 0 in either sub is refused (0609 0030h), the value kept. 6091h
/// may be 0 (its printed default 0/0 is 1:1). The generated units report a 0 held in 6092h
/// (a dictionary written without the drive) as `ZeroFactor`, never a division by zero.
#[test]
fn zero_terms_of_the_screw_and_the_feed_converter_are_refused() {
    let mut m = actuator(100, (0, 0));
    for (index, sub) in [(0x6092, 1), (0x6092, 2), (0x2001, 1), (0x2001, 2)] {
        let before = m.read_u32(ID, index, sub).unwrap();
        assert_eq!(m.write_u32(ID, index, sub, 0).map_err(abort), Err(Some(0x0609_0030)), "{index:04X}h sub {sub}");
        assert_eq!(m.read_u32(ID, index, sub).unwrap(), before);
    }
    m.write_u32(ID, 0x6091, 1, 0).unwrap();
    m.write_u32(ID, 0x6091, 2, 3).unwrap();
    assert_eq!(units(&mut m).to_internal(Dimension::Position, 100).unwrap(), Ratio::new(1, 3).unwrap());
    let mut od = Dictionary::new(ID);
    od.write(0x2014, 0, &[7]).unwrap();
    od.write(0x6092, 2, &0u32.to_le_bytes()).unwrap();
    assert_eq!(Units::from_dictionary(&od), Err(generated::drvi::units::UnitError::ZeroFactor { index: 0x6092 }));
    // The drive itself never divides by it: a held 0 counts as 1 (a 0.01 mm pitch per turn).
    let s = <Drvi as Vendor<Dictionary>>::scale(&Drvi::default(), &od);
    assert_eq!(s.position, Ratio1::new(360, 1));
}

/// The generated units and the drive agree over random factor values (every 32-bit term of
/// 2001h, 6091h, 6092h, 2014h): the drive's counts (0.01° of the motor) of a bus value are the
/// generated motor revolutions × 36 000 (degrees × 100 for only motor), rounded half away from
/// zero, and the bus value of a count the generated `internal_to_raw`; exactly while the
/// reduced ratio fits 64 bits (it always does for screws up to 2000 mm), otherwise within one
/// count (the drive's approximation is within 2^-63).
mod agreement {
    use super::*;
    use drive::drives::BusScale;
    use proptest::prelude::*;

    fn od(actuator: u8, fc: (u32, u32), gear: (u32, u32), feed: (u32, u32)) -> Dictionary {
        let mut od = Dictionary::new(ID);
        od.write(0x2014, 0, &[actuator]).unwrap();
        for ((index, sub), v) in [
            ((0x2001, 1), fc.0),
            ((0x2001, 2), fc.1),
            ((0x6091, 1), gear.0),
            ((0x6091, 2), gear.1),
            ((0x6092, 1), feed.0),
            ((0x6092, 2), feed.1),
        ] {
            od.write(index, sub, &v.to_le_bytes()).unwrap();
        }
        od
    }

    /// `x` rounded half away from zero, if it fits an `i64`.
    fn round(x: Ratio) -> Option<i64> {
        i64::try_from(x.round()).ok()
    }

    fn close(drive: i64, units: i64, exact: bool) -> bool {
        if exact { drive == units } else { drive.abs_diff(units) <= 1 }
    }

    /// The drive's ratio is exactly `want`.
    fn exact(r: drive::motion::Ratio, want: Ratio) -> bool {
        Ratio::new(r.num.into(), r.den.into()) == Some(want)
    }

    fn check(s: BusScale, u: &Units, only_motor: bool, bus: i32, count: i32) -> Result<(), TestCaseError> {
        use Dimension::{Acceleration, Position, Velocity};
        let bus = i64::from(bus);
        // Counts (per second, per second²) per bus unit.
        let per = |d: Dimension| -> Ratio {
            if only_motor {
                // Degrees per raw unit × 100 = counts of 0.01°; rpm (rpm/s) per raw unit × 600
                // (1 rpm = 6 °/s = 600 counts/s).
                let k = if d == Position { 100 } else { 600 };
                u.factor(d).unwrap().checked_mul(Ratio::int(k)).unwrap()
            } else {
                u.internal_factor(d).unwrap().checked_mul(Ratio::int(36_000)).unwrap()
            }
        };
        for (d, r) in [(Position, s.position), (Velocity, s.velocity), (Acceleration, s.acceleration)] {
            let want = per(d);
            let is_exact = exact(r, want);
            let got_in = match d {
                Position => s.position_in(bus),
                Velocity => s.velocity_in(bus),
                _ => s.acceleration_in(bus),
            };
            if let Some(w) = want.checked_mul_int(bus).and_then(round).filter(|w| w.unsigned_abs() < 1 << 62) {
                prop_assert!(close(got_in, w, is_exact), "{d:?} in: drive {got_in}, units {w}");
            }
            if d == Position && !only_motor {
                let back = s.position_out(i64::from(count));
                let w = u.internal_to_raw(Position, Ratio::new(i128::from(count), 36_000).unwrap());
                if let Ok(w) = w {
                    prop_assert!(close(back, w, is_exact), "position out: drive {back}, units {w}");
                }
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn over_random_factors(
            actuator in prop_oneof![Just(0u8), Just(7u8), any::<u8>()],
            fc in (1..=u32::MAX, 1..=u32::MAX),
            gear in (0..=u32::MAX, 0..=u32::MAX),
            feed in (1..=u32::MAX, 1..=u32::MAX),
            bus in any::<i32>(),
            count in any::<i32>(),
        ) {
            let od = od(actuator, fc, gear, feed);
            let s = <Drvi as Vendor<Dictionary>>::scale(&Drvi::default(), &od);
            let u = Units::from_dictionary(&od).unwrap();
            check(s, &u, actuator == 0, bus, count)?;
        }

        /// Screws a DRVI can have (UVIX 7.5.1: 0..2000 mm a turn) and real gears: exact.
        #[test]
        fn over_real_screws(
            fc in (1..=1000u32, 1..=1000u32),
            gear in (0..=100u32, 0..=100u32),
            feed in (1..=200_000u32, 1..=10u32),
            bus in any::<i32>(),
            count in any::<i32>(),
        ) {
            let od = od(7, fc, gear, feed);
            let s = <Drvi as Vendor<Dictionary>>::scale(&Drvi::default(), &od);
            let u = Units::from_dictionary(&od).unwrap();
            let g = u.internal_factor(Dimension::Position).unwrap().checked_mul(Ratio::int(36_000)).unwrap();
            prop_assert!(exact(s.position, g), "{:?} vs {g}", s.position);
            check(s, &u, false, bus, count)?;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Software limits (5.0.1).

/// An actuator of 100 mm per motor turn (6092h = 10000/1: a belt): one bus unit (0.01 mm) is
/// 3.6 counts, and the preset's end stops lie at −138.89 mm and 416.67 mm.
fn belt(m: &mut Master) {
    m.write_u8(ID, 0x2014, 0, 7).unwrap();
    m.write_u32(ID, 0x6092, 1, 10_000).unwrap();
}

fn limited(m: &mut Master) {
    belt(m);
    m.write_i32(ID, 0x607C, 0, 1_000).unwrap();
    m.write_i32(ID, 0x607D, 1, -9_000).unwrap();
    m.write_i32(ID, 0x607D, 2, 21_000).unwrap(); // corrected: −10000 .. 20000
    m.write_u8(ID, 0x2010, 0, 1).unwrap();
}

#[test]
fn software_limits_refuse_targets_outside_607d_minus_the_offset() {
    let mut m = master();
    limited(&mut m);
    assert_eq!(sw(&mut m) & (1 << 11), 0, "not in force before homing");
    home(&mut m, 37, 1_000);
    m.advance(2000);
    assert_ne!(sw(&mut m) & (1 << 11), 0, "in force: bit 11");
    profile(&mut m, 5_000, 500);
    move_to(&mut m, 20_000, false);
    assert_eq!(pos(&mut m), 20_000, "the corrected maximum is allowed");
    m.write_i32(ID, 0x607A, 0, 20_001).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(pos(&mut m), 20_000);
    assert_ne!(warnings(&mut m) & warning::COMMAND_REFUSED, 0);
    m.controlword(ID, 0x0F).unwrap();
    // A relative target counts from the actual position.
    m.write_i32(ID, 0x607A, 0, -30_001).unwrap();
    m.controlword(ID, 0x5F).unwrap();
    m.advance(100_000);
    assert_eq!(pos(&mut m), 20_000);
    m.controlword(ID, 0x4F).unwrap();
    // Speeds above 607Fh are refused too.
    m.write_u32(ID, 0x607F, 0, 4_000).unwrap();
    m.write_i32(ID, 0x607A, 0, 0).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(pos(&mut m), 20_000, "6081h 5000 > 607Fh 4000: refused");
    assert_eq!(sw(&mut m) & (1 << 12), 0);
    m.controlword(ID, 0x0F).unwrap();
    m.write_u32(ID, 0x6081, 0, 4_000).unwrap();
    move_to(&mut m, 0, false);
    assert_eq!(pos(&mut m), 0);
}

#[test]
fn leaving_the_limits_raises_6120h_and_the_check_waits_after_its_reset() {
    let mut m = master();
    limited(&mut m);
    home(&mut m, 37, 1_000);
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1_000);
    m.write_i32(ID, 0x60FF, 0, 10_000).unwrap();
    assert!(m.wait_until(5_000_000, 5_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    let e = emcys(&mut m);
    assert_eq!(e[0], [0x20, 0x61, 0x01, 0, 0, 0, 0, 0], "EMCY 6120h");
    assert_ne!(warnings(&mut m) & warning::POSITIVE_LIMIT, 0);
    assert!(m.wait_until(5_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    assert!(pos(&mut m) > 20_000, "stopped with the quick stop ramp beyond the limit");
    // 5.0.1: reset with 1003h sub 0 = 0, then 0, 6, 7, 15.
    m.write_u8(ID, 0x1003, 0, 0).unwrap();
    assert_eq!(state(&mut m), State::SwitchOnDisabled);
    assert_eq!(e.len(), 1);
    assert_eq!(emcys(&mut m).last().unwrap()[..2], [0, 0], "error reset EMCY");
    assert_eq!(warnings(&mut m) & warning::POSITIVE_LIMIT, 0, "warnings reset too");
    m.controlword(ID, 0).unwrap();
    m.switch_on(ID).unwrap();
    assert_eq!(sw(&mut m) & (1 << 11), 0, "check suspended");
    // Back into range with a move (the check is suspended: no new error).
    m.write_i32(ID, 0x60FF, 0, -10_000).unwrap();
    m.advance(800_000);
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.advance(1_000_000);
    assert!(pos(&mut m) < 20_000);
    assert_eq!(state(&mut m), State::OperationEnabled);
    assert_ne!(sw(&mut m) & (1 << 11), 0, "in force again after the first completed movement");
    assert!(emcys(&mut m).is_empty());
}

/// Table 6.36 bit 7 "negative position limit reached": the lower limit, corrected by the home
/// offset (607Dh sub 1 − 607Ch), raises 6120h like the upper one, sets bit 7 (not bit 6), and
/// both resets clear it.
#[test]
fn leaving_the_lower_limit_sets_warning_bit_7_and_6120h() {
    let mut m = master();
    limited(&mut m);
    home(&mut m, 37, 1_000);
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1_000);
    m.write_i32(ID, 0x60FF, 0, -10_000).unwrap();
    assert!(m.wait_until(5_000_000, 5_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    let e = emcys(&mut m);
    assert_eq!(e[0], [0x20, 0x61, 0x01, 0, 0, 0, 0, 0], "EMCY 6120h");
    assert_eq!(warnings(&mut m) & (warning::NEGATIVE_LIMIT | warning::POSITIVE_LIMIT), warning::NEGATIVE_LIMIT);
    assert!(m.wait_until(5_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    assert!(pos(&mut m) < -10_000, "beyond −9000 − 1000");
    assert!(pos(&mut m) > -11_500, "stopped on the ramp (10 000 at 1000/s²: 50 units)");
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.controlword(ID, 0x00).unwrap();
    m.controlword(ID, 0x80).unwrap();
    assert_eq!(state(&mut m), State::SwitchOnDisabled);
    assert_eq!(warnings(&mut m) & warning::NEGATIVE_LIMIT, 0);
}

/// 6.3.6.2/6.3.6.3/6.12: 2002h shows IN1, IN2 (bits 0, 1) and is read-only; 2003h bit 0 sets
/// the GPIO output (6.12 writes it, although 6.3.6.3 calls it read-only: the sidecar's
/// decision), over SDO and over an RPDO; 2004h and 2006h are read-only.
#[test]
fn inputs_2002h_and_the_output_2003h() {
    let mut m = master();
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap() & 0b11, 0);
    conditions(&mut m, |c| c.in1 = true);
    m.advance(2000);
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap() & 0b11, 0b01);
    conditions(&mut m, |c| {
        c.in1 = false;
        c.in2 = true;
    });
    m.advance(2000);
    assert_eq!(m.read_u32(ID, 0x2002, 0).unwrap() & 0b11, 0b10);
    for index in [0x2002, 0x2004, 0x2006] {
        assert_eq!(m.write_u32(ID, index, 0, 1).map_err(abort), Err(Some(0x0601_0002)), "{index:04X}h");
    }
    m.write_u32(ID, 0x2003, 0, 1).unwrap();
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), 1, "OUT high");
    m.write_u32(ID, 0x2003, 0, 0).unwrap();
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), 0, "OUT low");
    // RPDO2 carrying 2003h.
    m.write_u32(ID, 0x1401, 1, 0x8000_0300 + u32::from(ID)).unwrap();
    m.write_u8(ID, 0x1601, 0, 0).unwrap();
    m.write_u32(ID, 0x1601, 1, 0x2003_0020).unwrap();
    m.write_u8(ID, 0x1601, 0, 1).unwrap();
    m.write_u32(ID, 0x1401, 1, 0x300 + u32::from(ID)).unwrap();
    m.send(od_bus::CanFrame::standard(0x300 + u32::from(ID), &1u32.to_le_bytes()).unwrap());
    m.advance(2000);
    assert_eq!(m.read_u32(ID, 0x2003, 0).unwrap(), 1, "OUT high by RPDO");
}

#[test]
fn the_ext_proxy_input_is_a_hardware_limit_under_2010h() {
    let mut m = master();
    // EXT PROXY at 30 000 counts (83.33 mm on the belt).
    set_environment(&mut m, Environment { positive_limit: Some(30_000), ..drvi::default_environment() });
    belt(&mut m); // 10000 = 100 mm/s, a turn a second
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1_000);
    m.write_i32(ID, 0x60FF, 0, 10_000).unwrap();
    m.advance(2_000_000);
    assert!(counts(&m) > 60_000, "2010h = 0: the input is only reported");
    assert_ne!(m.read_u32(ID, 0x2002, 0).unwrap() & 0b100, 0, "2002h bit 2 EXT PROXY");
    assert_eq!(state(&mut m), State::OperationEnabled);
    m.write_i32(ID, 0x60FF, 0, -10_000).unwrap();
    m.advance(2_500_000);
    m.write_i32(ID, 0x60FF, 0, 0).unwrap();
    m.write_u8(ID, 0x2010, 0, 1).unwrap();
    m.advance(1_000_000);
    m.take_seen();
    m.write_i32(ID, 0x60FF, 0, 10_000).unwrap();
    assert!(m.wait_until(10_000_000, 5_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    assert_eq!(emcys(&mut m)[0][..3], [0x20, 0x61, 0x01]);
}

// ---------------------------------------------------------------------------------------------
// Errors, warnings, resets.

fn conditions(m: &mut Master, f: impl FnOnce(&mut drvi::Conditions)) {
    f(&mut app_mut(m).vendor_mut().conditions);
}

#[test]
fn warnings_latch_until_a_reset_and_set_statusword_bit_7() {
    let mut m = master();
    conditions(&mut m, |c| {
        c.vbus_mv = 62_000;
        c.vlog_mv = 20_500;
    });
    m.advance(2000);
    assert_eq!(warnings(&mut m), warning::VDC_OVLO | warning::VL_UVLO);
    assert_ne!(sw(&mut m) & (1 << 7), 0);
    conditions(&mut m, |c| *c = drvi::Conditions::default());
    m.advance(10_000);
    assert_eq!(warnings(&mut m), warning::VDC_OVLO | warning::VL_UVLO, "latched");
    m.controlword(ID, 0x80).unwrap(); // reset (also outside Fault)
    m.controlword(ID, 0x00).unwrap();
    m.advance(2000);
    assert_eq!(warnings(&mut m), 0);
    assert_eq!(sw(&mut m) & (1 << 7), 0);
    // The other reset: 0 written to 1003h sub 0.
    conditions(&mut m, |c| {
        c.vbus_mv = 19_000;
        c.vlog_mv = 28_000;
        c.ambient_c = 90.0;
    });
    m.advance(120_000_000);
    let w = warnings(&mut m);
    let all = warning::VDC_UVLO | warning::VL_OVLO | warning::MOTOR_TEMPERATURE | warning::DRIVE_TEMPERATURE;
    assert_eq!(w, all, "{w:#06X}");
    assert_eq!(state(&mut m), State::SwitchOnDisabled, "warnings do not change the state");
    conditions(&mut m, |c| *c = drvi::Conditions::default());
    m.write_u8(ID, 0x1003, 0, 0).unwrap();
    m.advance(2000);
    assert_eq!(warnings(&mut m) & (warning::VDC_UVLO | warning::VL_OVLO), 0);
}

#[test]
fn hard_errors_switch_off_at_once_with_their_manufacturer_byte() {
    for (what, set, emcy) in [
        (
            "VLOG over 29 V",
            Box::new(|c: &mut drvi::Conditions| c.vlog_mv = 30_000) as Box<dyn Fn(&mut drvi::Conditions)>,
            [0x10, 0x31, 0x05, 1],
        ),
        ("VBUS under 10 V", Box::new(|c: &mut drvi::Conditions| c.vbus_mv = 9_000), [0x20, 0x31, 0x05, 0]),
        ("VLOG under 16 V", Box::new(|c: &mut drvi::Conditions| c.vlog_mv = 15_000), [0x20, 0x31, 0x05, 1]),
        ("VBUS over 80 V", Box::new(|c: &mut drvi::Conditions| c.vbus_mv = 81_000), [0x10, 0x31, 0x05, 0]),
        ("STO", Box::new(|c: &mut drvi::Conditions| c.hw_enable = false), [0x40, 0x55, 0x01, 0]),
        ("VEXT", Box::new(|c: &mut drvi::Conditions| c.vext = false), [0x20, 0x51, 0x05, 0]),
        ("encoder", Box::new(|c: &mut drvi::Conditions| c.encoder_ok = false), [0x05, 0x73, 0x01, 0]),
    ] {
        let mut m = master();
        m.switch_on(ID).unwrap();
        m.set_mode(ID, 3).unwrap();
        profile(&mut m, 0, 600);
        m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
        m.advance(1_000_000);
        m.take_seen();
        conditions(&mut m, |c| set(c));
        m.advance(2000);
        let e = emcys(&mut m);
        assert_eq!(e[0][..4], emcy, "{what}");
        assert_eq!(state(&mut m), State::Fault, "{what}: hard error, no ramp");
        assert!(!app(&m).drive().axis().status().power, "{what}");
        assert!(vel(&mut m) > 0, "{what}: the axis coasts");
    }
}

#[test]
fn every_error_of_table_6_34_has_a_cause_with_its_reaction_and_manufacturer_byte() {
    type Set = fn(&mut drvi::Conditions);
    let causes: [(u16, u8, Set); 12] = [
        (0x2310, 0, |c| c.short_circuit = true),
        (0x3110, 0, |c| c.vbus_mv = 81_000),
        (0x3110, 1, |c| c.vlog_mv = 30_000),
        (0x3120, 0, |c| c.vbus_mv = 9_000),
        (0x3120, 1, |c| c.vlog_mv = 15_000),
        (0x5120, 0, |c| c.vext = false),
        (0x5530, 0, |c| c.memory_fault = true),
        (0x5540, 0, |c| c.hw_enable = false),
        (0x6100, 0, |c| c.control_fault = true),
        (0x7305, 0, |c| c.encoder_ok = false),
        (0x8120, 0, |c| c.can_error_passive = true),
        (0x4210, 0, |_| {}), // the motor temperature, set below
    ];
    let table = drive::drives::error_table(drive::node::DeviceKind::Drvi);
    for (code, manufacturer, set) in causes {
        let spec = table.find(code, Some(u64::from(manufacturer))).unwrap();
        let mut m = master();
        m.switch_on(ID).unwrap();
        m.set_mode(ID, 3).unwrap();
        profile(&mut m, 0, 600);
        m.write_i32(ID, 0x60FF, 0, 600).unwrap();
        m.advance(200_000);
        m.take_seen();
        conditions(&mut m, set);
        if code == 0x4210 {
            app_mut(&mut m).vendor_mut().motor_c = 101.0;
            conditions(&mut m, |c| c.ambient_c = 101.0);
        }
        m.advance(2000);
        let e = emcys(&mut m);
        let [lo, hi] = code.to_le_bytes();
        assert_eq!(e[0][..4], [lo, hi, spec.register_bits(), manufacturer], "{code:04X}h/{manufacturer}");
        assert_eq!(m.read_u16(ID, 0x603F, 0).unwrap(), code);
        assert_eq!(m.read_u32(ID, 0x1003, 1).unwrap(), u32::from(code) | u32::from(manufacturer) << 16);
        let expected = match spec.reaction {
            drive::drives::Reaction::PowerOff => State::Fault,
            _ => State::FaultReactionActive,
        };
        assert_eq!(state(&mut m), expected, "{code:04X}h/{manufacturer}: {:?}", spec.reaction);
    }
}

#[test]
fn an_over_temperature_is_a_soft_error_and_a_persisting_cause_comes_back_after_reset() {
    let mut m = master();
    set_environment(&mut m, Environment::default()); // no end stops in the way
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 600);
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    m.advance(1_000_000);
    m.take_seen();
    conditions(&mut m, |c| c.ambient_c = 140.0);
    assert!(m.wait_until(120_000_000, 100_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    let e = emcys(&mut m);
    assert_eq!(e[0][..4], [0x10, 0x42, 0x09, 1], "the drive heats faster: 4210h / 1");
    assert_eq!(state(&mut m), State::FaultReactionActive, "soft: quick stop first");
    assert!(m.wait_until(2_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    // Still hot: the fault comes back after the reset.
    m.controlword(ID, 0x80).unwrap();
    m.advance(5000);
    assert_eq!(state(&mut m), State::Fault);
    conditions(&mut m, |c| c.ambient_c = 25.0);
    app_mut(&mut m).vendor_mut().motor_c = 25.0;
    app_mut(&mut m).vendor_mut().drive_c = 25.0;
    m.controlword(ID, 0x00).unwrap();
    m.controlword(ID, 0x80).unwrap();
    m.advance(5000);
    assert_eq!(state(&mut m), State::SwitchOnDisabled);
    assert_eq!(m.read_u16(ID, 0x603F, 0).unwrap(), 0);
}

#[test]
fn i2t_trips_after_an_overload() {
    let mut m = master(); // pushing against the end stop at 150000
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 4).unwrap();
    m.write(ID, 0x6071, 0, &10_000i16.to_le_bytes()).unwrap(); // twice the I²T current
    m.write_u32(ID, 0x6087, 0, 1_000_000).unwrap();
    assert!(m.wait_until(10_000_000, 10_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    let t = m.now();
    assert_eq!(emcys(&mut m)[0][..4], [0x10, 0x23, 0x03, 11], "2310h / 11: I²T fault");
    assert!((1_500_000..4_000_000).contains(&t), "about 2 s at twice the rating: {t}");
    assert_eq!(state(&mut m), State::Fault);
}

#[test]
fn fault_reset_by_1003h_sub_0() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    conditions(&mut m, |c| c.hw_enable = false);
    m.advance(2000);
    assert_eq!(state(&mut m), State::Fault);
    conditions(&mut m, |c| c.hw_enable = true);
    assert_eq!(m.read_u64(ID, 0x1003, 0).unwrap(), 1);
    m.write_u8(ID, 0x1003, 0, 0).unwrap();
    assert_eq!(state(&mut m), State::SwitchOnDisabled);
    assert_eq!(m.read_u64(ID, 0x1003, 0).unwrap(), 0, "history cleared");
    assert_eq!(m.read_u8_or(ID, 0x1001), 0);
    m.switch_on(ID).unwrap();
}

trait ReadU8 {
    fn read_u8_or(&mut self, node: u8, index: u16) -> u8;
}

impl ReadU8 for Master {
    fn read_u8_or(&mut self, node: u8, index: u16) -> u8 {
        self.read_u64(node, index, 0).unwrap() as u8
    }
}

#[test]
fn a_lost_guarding_master_is_the_fieldbus_disconnection_soft_error() {
    let mut m = master();
    m.write_u16(ID, 0x100C, 0, 100).unwrap();
    m.write_u8(ID, 0x100D, 0, 3).unwrap();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 600);
    m.write_i32(ID, 0x60FF, 0, 6000).unwrap();
    for _ in 0..12 {
        m.send(od_bus::CanFrame::remote(0x700 + u32::from(ID), false, 1).unwrap());
        m.advance(90_000);
    }
    m.take_seen();
    assert!(m.wait_until(1_000_000, 5_000, |m| m.seen().any(|s| s.frame.id() == EMCY)));
    assert_eq!(emcys(&mut m)[0], [0x30, 0x81, 0x11, 0, 0, 0, 0, 0]);
    assert_eq!(state(&mut m), State::FaultReactionActive);
    assert!(m.wait_until(2_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    // Guarding again does not clear the latched error; a reset does.
    m.send(od_bus::CanFrame::remote(0x700 + u32::from(ID), false, 1).unwrap());
    m.advance(50_000);
    assert_eq!(state(&mut m), State::Fault);
    m.controlword(ID, 0x80).unwrap();
    assert_eq!(state(&mut m), State::SwitchOnDisabled);
}

#[test]
fn profile_check_2012h_warns_when_the_target_is_not_reached() {
    let mut m = master();
    set_environment(&mut m, Environment { positive_end_stop: Some(10_000), ..drvi::default_environment() });
    home(&mut m, 37, 0);
    profile(&mut m, 3000, 600);
    m.set_mode(ID, 1).unwrap();
    m.write_i32(ID, 0x607A, 0, 20_000).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.advance(3_000_000);
    assert_eq!(pos(&mut m), 10_000, "blocked by the end stop");
    assert_ne!(warnings(&mut m) & warning::POSITION_NOT_REACHED, 0);
    // Disabled: no warning.
    m.controlword(ID, 0x8F).unwrap();
    m.controlword(ID, 0x0F).unwrap();
    m.write_u8(ID, 0x2012, 1, 0).unwrap();
    m.advance(1_000_000);
    assert_eq!(warnings(&mut m) & warning::POSITION_NOT_REACHED, 0);
}

#[test]
fn speed_check_warns_when_the_torque_limit_holds_the_speed_back() {
    let mut m = master();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 60_000);
    m.write(ID, 0x6071, 0, &100i16.to_le_bytes()).unwrap();
    m.write_u8(ID, 0x2015, 0, 1).unwrap();
    m.write_i32(ID, 0x60FF, 0, 300_000).unwrap(); // 3000 rpm: needs more than 100 mA
    m.advance(1_000_000);
    assert_ne!(warnings(&mut m) & warning::SPEED_NOT_REACHED, 0);
}

#[test]
fn pid_selection_2011h_sets_the_loop_bandwidth() {
    let mut m = master();
    let bw = |m: &Master| app(m).drive().axis().config().plant.bandwidth;
    m.advance(2000);
    assert_eq!(bw(&m), 150.0, "default: PID low");
    m.write_u16(ID, 0x2011, 1, 3).unwrap();
    m.advance(2000);
    assert_eq!(bw(&m), 600.0);
    m.write_u16(ID, 0x2011, 1, 4).unwrap();
    m.write_u16(ID, 0x2011, 2, 20).unwrap();
    m.advance(2000);
    assert_eq!(bw(&m), 600.0, "custom: 30 × Kp position (×10)");
}

// ---------------------------------------------------------------------------------------------
// Persistence.

#[test]
fn saved_parameters_survive_a_restart() {
    let dir = std::env::temp_dir().join(format!("drvi-save-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let storage =
        || NodeStorage::new(Arc::new(ParameterSet::new()), Box::new(FileStorage::open(&dir, "drvi-node3").unwrap()));
    {
        let mut m = master_with(storage(), None);
        homing_params(&mut m, -2, 4_321);
        m.write_u8(ID, 0x2014, 0, 7).unwrap();
        m.write_u32(ID, 0x2001, 1, 100).unwrap();
        m.write_u32(ID, 0x2001, 2, 254).unwrap();
        m.write_u32(ID, 0x6091, 1, 2).unwrap();
        m.write_u32(ID, 0x6091, 2, 1).unwrap();
        m.write_u32(ID, 0x6092, 1, 500).unwrap();
        m.write_u16(ID, 0x2013, 0, 40).unwrap();
        m.write(ID, 0x1010, 1, b"save").unwrap();
    }
    let mut m = master_with(storage(), None);
    assert_eq!(m.read_i64(ID, 0x6098, 0).unwrap(), -2);
    assert_eq!(m.read_i64(ID, 0x607C, 0).unwrap(), 4_321);
    assert_eq!(m.read_u64(ID, 0x2014, 0).unwrap(), 7);
    assert_eq!(m.read_u64(ID, 0x2001, 2).unwrap(), 254);
    assert_eq!(m.read_u64(ID, 0x2013, 0).unwrap(), 40);
    assert_eq!(m.read_u64(ID, 0x6091, 1).unwrap(), 2);
    assert_eq!(m.read_u64(ID, 0x6092, 1).unwrap(), 500);
    // The restored configuration is in force: the actuator unit system, the feed converter, the
    // gear and the screw: 0.001 in = 2.54 (0.01 mm) × 2 turns / 5 mm × 36 000 = 365.76 counts.
    let units = app(&m).drive().axis().config().units;
    assert_eq!((units.velocity, units.acceleration), (Ratio1::ONE, Ratio1::ONE));
    assert_eq!(app(&m).drive().scale().position, Ratio1::new(9_144, 25));
    // 1011h "load" + reset node: defaults again.
    m.write(ID, 0x1011, 1, b"load").unwrap();
    m.nmt(0x81, ID);
    m.advance(2000);
    assert_eq!(m.read_i64(ID, 0x6098, 0).unwrap(), 37);
    assert_eq!(m.read_u64(ID, 0x2014, 0).unwrap(), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A DRVI whose retained data (5.0.3) lives in `retain`: "switching it off" is dropping the
/// master, "on" is a new one with the same `retain`.
fn master_retaining(retain: &MemoryRetain) -> Master {
    let mut sim = Sim::new();
    let node = Node::new(Dictionary::new(ID), drvi::actuator_app(), NodeStorage::memory(), NodeId::new(ID).unwrap())
        .with_retain(Box::new(retain.clone()));
    sim.add(Box::new(node));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m
}

/// 5.0.3: homed and stopped at power-off, the DRVI has its position back at power-on: no
/// homing needed, and the machine is where it was (the proximity, 20 000..25 000 in the frame
/// of the first homing, is still there).
#[test]
fn a_homed_standing_axis_keeps_its_position_through_a_power_cycle() {
    let retain = MemoryRetain::new();
    let proximity = |m: &mut Master| m.read_u64(ID, 0x2002, 0).unwrap() & 0x08 != 0;
    {
        let mut m = master_retaining(&retain);
        home(&mut m, 37, 0);
        profile(&mut m, 6000, 600);
        move_to(&mut m, 22_000, false);
        assert!(proximity(&mut m));
        move_to(&mut m, -12_345, false);
        m.advance(10_000);
        assert_eq!(pos(&mut m), -12_345);
    } // power off
    let mut m = master_retaining(&retain);
    assert_eq!(pos(&mut m), -12_345, "the saved position");
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1, "homed");
    m.switch_on(ID).unwrap();
    profile(&mut m, 6000, 600);
    move_to(&mut m, 19_000, false);
    assert_eq!(warnings(&mut m) & warning::HOMING_MISSING, 0, "no homing needed");
    assert_eq!(pos(&mut m), 19_000);
    assert!(!proximity(&mut m));
    move_to(&mut m, 22_000, false);
    assert!(proximity(&mut m), "the proximity where it was");
}

/// Power cut while moving: nothing to restore, the homing is needed again.
#[test]
fn an_axis_switched_off_while_moving_must_be_homed_again() {
    let retain = MemoryRetain::new();
    {
        let mut m = master_retaining(&retain);
        home(&mut m, 37, 0);
        profile(&mut m, 6000, 600);
        m.set_mode(ID, 1).unwrap();
        m.write_i32(ID, 0x607A, 0, 30_000).unwrap();
        m.controlword(ID, 0x1F).unwrap();
        m.advance(300_000);
        assert_ne!(vel(&mut m), 0, "moving");
    }
    let mut m = master_retaining(&retain);
    assert_eq!(pos(&mut m), 0);
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 0, "not homed");
}

#[test]
fn a_homed_axis_keeps_its_position_through_a_reset_node() {
    let mut m = master();
    home(&mut m, 37, 0);
    profile(&mut m, 6000, 600);
    move_to(&mut m, 12_345, false);
    m.nmt(0x81, ID);
    m.advance(5000);
    assert_eq!(pos(&mut m), 12_345, "5.0.3");
    assert_eq!(m.read_u64(ID, 0x2004, 0).unwrap(), 1);
}
