//! The common CiA 402 drive layer (drive::drives::cia402) on the in-memory bus, through real
//! frames: state machine and power stage, modes, stops, errors from the sidecar tables,
//! heartbeat loss, traces.

use std::sync::{Arc, Mutex};

use crate::support::{Master, abort};
use drive::drives::cia402::{BusScale, Plain, Vendor, read_int, scale_i64, write_int};
use drive::drives::{Cia402App, DeviceApps, ErrorTable, Reaction, error_table, sidecar};
use drive::motion::{Environment, Ratio};
use drive::node::{DeviceKind, Node, NodeConfig, NodeStorage, Sim};
use drive::trace::Trace;
use generated::drvi::Dictionary;
use od_runtime::NodeId;
use od_runtime::cia402::State;

const ID: u8 = 5;

type PlainNode = Node<Dictionary, Cia402App<Dictionary, Plain>>;

/// A plain CiA 402 drive (every Vendor default) on the DRVI dictionary.
fn plain() -> Master {
    let mut sim = Sim::new();
    let app = Cia402App::<Dictionary, _>::new(Plain, error_table(DeviceKind::Drvi));
    let node = Node::new(Dictionary::new(ID), app, NodeStorage::memory(), NodeId::new(ID).unwrap());
    sim.add(Box::new(node));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m
}

fn app(m: &Master) -> &Cia402App<Dictionary, Plain> {
    m.sim().downcast::<PlainNode>(0).unwrap().app().unwrap()
}

fn profile(m: &mut Master, v: u32, a: u32) {
    m.write_u32(ID, 0x6081, 0, v).unwrap();
    m.write_u32(ID, 0x6083, 0, a).unwrap();
    m.write_u32(ID, 0x6084, 0, a).unwrap();
}

#[test]
fn every_sidecar_parses_and_has_an_error_table() {
    for kind in DeviceKind::ALL {
        let s = sidecar(kind).unwrap_or_else(|| panic!("{kind} sidecar"));
        let t = error_table(kind);
        assert_eq!(t.entries().len(), s.errors.len(), "{kind}: every error kept");
        assert!(!t.entries().is_empty());
    }
}

#[test]
fn error_lookup_by_code_and_manufacturer() {
    let t = error_table(DeviceKind::Drvi);
    let over_current = t.find(0x2310, Some(0)).unwrap();
    let i2t = t.find(0x2310, Some(11)).unwrap();
    assert_eq!(over_current.text, "Over current error");
    assert_eq!(i2t.text, "I2T fault");
    assert_eq!(i2t.info(), [11, 0, 0, 0, 0]);
    assert_eq!(i2t.register_bits(), 0x03);
    assert_eq!(t.find(0x4210, Some(1)).unwrap().reaction, Reaction::QuickStop);
    // Without a manufacturer value: the first with that code.
    assert_eq!(t.find(0x2310, None).unwrap().text, "Over current error");
    // Unknown codes are hard errors with od-runtime's register bits.
    let unknown = t.resolve(0x5678, None);
    assert_eq!(unknown.reaction, Reaction::PowerOff);
    assert_eq!(unknown.register_bits(), od_runtime::emcy::register_bits(0x5678) | 1);
    let akd = error_table(DeviceKind::Akd);
    assert_eq!(akd.find_vendor("f523").unwrap().code, 0x3110);
    assert!(ErrorTable::default().find(0x2310, None).is_none());
}

#[test]
fn scaling_rounds_half_away_and_saturates() {
    assert_eq!(scale_i64(10, Ratio::new(1, 3)), 3);
    assert_eq!(scale_i64(-5, Ratio::new(1, 2)), -3);
    assert_eq!(scale_i64(5, Ratio::new(1, 2)), 3);
    assert_eq!(scale_i64(i64::MAX, Ratio::new(2, 1)), i64::MAX);
    assert_eq!(scale_i64(7, Ratio::new(0, 1)), 7, "a zero term counts as 1/1");
    let s = BusScale { position: Ratio::new(254, 100), ..BusScale::ONE };
    assert_eq!(s.position_in(1000), 2540);
    assert_eq!(s.position_out(2540), 1000);
}

#[test]
fn od_helpers_saturate_to_the_entry_type() {
    let mut od = Dictionary::new(1);
    assert!(write_int(&mut od, 0x6041, 0, 0x1_2345)); // U16: saturates
    assert_eq!(read_int(&od, 0x6041, 0), Some(0xFFFF));
    assert!(write_int(&mut od, 0x6064, 0, -5));
    assert_eq!(read_int(&od, 0x6064, 0), Some(-5));
    assert!(!write_int(&mut od, 0x6FFF, 0, 1));
    assert_eq!(read_int(&od, 0x1008, 0), None, "a string is not an integer");
}

#[test]
fn state_machine_walk_switches_the_power_stage() {
    let mut m = plain();
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    m.switch_on(ID).unwrap();
    assert!(app(&m).drive().axis().status().power);
    // Disable operation (5): power off.
    m.controlword(ID, 0x07).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchedOn));
    assert!(!app(&m).drive().axis().status().power);
    m.controlword(ID, 0x0F).unwrap();
    m.advance(2000);
    assert!(app(&m).drive().axis().status().power);
    // Shutdown (8) and disable voltage (9).
    m.controlword(ID, 0x06).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::ReadyToSwitchOn));
    assert!(!app(&m).drive().axis().status().power);
    m.controlword(ID, 0x0F).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    m.controlword(ID, 0x00).unwrap();
    m.advance(2000);
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert!(!app(&m).drive().axis().status().power);
}

#[test]
fn unsupported_modes_and_homing_methods_are_refused() {
    let mut m = plain();
    assert_eq!(m.write(ID, 0x6060, 0, &[2]).map_err(abort), Err(Some(0x0609_0030)));
    assert_eq!(m.write(ID, 0x6060, 0, &[0xFF]).map_err(abort), Err(Some(0x0609_0030)), "-1 is not CiA 402");
    m.set_mode(ID, 1).unwrap();
    assert_eq!(m.write(ID, 0x6098, 0, &[36]).map_err(abort), Err(Some(0x0609_0030)));
    m.write(ID, 0x6098, 0, &[35]).unwrap();
}

#[test]
fn profile_position_absolute_and_relative_with_handshake() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 1).unwrap();
    profile(&mut m, 1000, 2000);
    m.write_i32(ID, 0x607A, 0, 1500).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    let sw = m.statusword(ID).unwrap();
    assert_ne!(sw & (1 << 12), 0, "set-point acknowledge");
    assert_eq!(sw & (1 << 10), 0, "moving");
    m.controlword(ID, 0x0F).unwrap();
    let sw = m.wait_statusword(ID, 1 << 10, 1 << 10, 5_000_000, 10_000).expect("target reached");
    assert_eq!(sw & (1 << 12), 0, "acknowledge dropped with bit 4");
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 1500);
    assert_eq!(m.read_i64(ID, 0x6062, 0).unwrap(), 1500);
    // 0.5 s up, 1 s cruise, 0.5 s down: about 2 s.
    let t = app(&m).drive().status().time_us;
    assert!((1_990_000..2_200_000).contains(&t), "{t}");
    // Relative: +500 from the previous target.
    m.write_i32(ID, 0x607A, 0, 500).unwrap();
    m.controlword(ID, 0x5F).unwrap();
    m.controlword(ID, 0x4F).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 5_000_000, 10_000).unwrap();
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 2000);
}

#[test]
fn set_point_edges_while_disabled_are_ignored() {
    let mut m = plain();
    m.set_mode(ID, 1).unwrap();
    profile(&mut m, 1000, 2000);
    m.write_i32(ID, 0x607A, 0, 800).unwrap();
    m.controlword(ID, 0x06).unwrap();
    m.controlword(ID, 0x17).unwrap(); // switched on, bit 4 rises while not enabled
    m.controlword(ID, 0x1F).unwrap(); // enabled with bit 4 still high: no edge
    m.advance(100_000);
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 0);
    m.controlword(ID, 0x0F).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.wait_statusword(ID, 1 << 10, 1 << 10, 5_000_000, 10_000).unwrap();
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 800);
}

#[test]
fn profile_velocity_with_halt_and_speed_bit() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 500).unwrap();
    m.advance(600_000);
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 500);
    assert_eq!(m.statusword(ID).unwrap() & (1 << 12), 0, "moving: speed bit 0");
    m.controlword(ID, 0x010F).unwrap(); // halt
    m.advance(600_000);
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 0);
    let sw = m.statusword(ID).unwrap();
    assert_ne!(sw & (1 << 10), 0, "halted and standing: target reached");
    assert_ne!(sw & (1 << 12), 0, "speed bit: standing");
    m.controlword(ID, 0x000F).unwrap();
    m.advance(600_000);
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 500, "resumes after halt");
}

#[test]
fn profile_torque_ramps_with_the_slope() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 4).unwrap();
    m.write_u32(ID, 0x6087, 0, 1000).unwrap(); // 1000 mA/s
    m.write(ID, 0x6071, 0, &500i16.to_le_bytes()).unwrap();
    m.advance(250_000);
    let t = m.read_i64(ID, 0x6077, 0).unwrap();
    assert!((230..=270).contains(&t), "ramping: {t}");
    m.advance(500_000);
    assert_eq!(m.read_i64(ID, 0x6077, 0).unwrap(), 500);
    assert_ne!(m.statusword(ID).unwrap() & (1 << 10), 0, "target torque reached");
}

#[test]
fn quick_stop_ramps_then_switches_off() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    m.advance(1_100_000);
    m.controlword(ID, 0x0B).unwrap(); // quick stop
    assert_eq!(m.state(ID).unwrap(), Some(State::QuickStopActive));
    assert!(app(&m).drive().axis().status().power, "power stays on while ramping");
    m.advance(500_000);
    assert_eq!(m.state(ID).unwrap(), Some(State::QuickStopActive));
    assert!(m.wait_until(1_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::SwitchOnDisabled)));
    assert!(!app(&m).drive().axis().status().power);
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 0);
}

#[test]
fn soft_and_hard_errors_from_the_table() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    m.advance(1_100_000);
    m.take_seen();
    // Soft: over temperature drive (4210h / 1): quick stop ramp, then Fault.
    let now = m.now();
    let node = m.sim_mut().downcast_mut::<PlainNode>(0).unwrap();
    node.with_app(now, |app, ctx| {
        app.drive_mut().raise(ctx, 0x4210, Some(1));
    });
    m.advance(0);
    let emcy = m.take_id(0x80 + u32::from(ID));
    assert_eq!(emcy.len(), 1);
    assert_eq!(emcy[0].frame.data(), [0x10, 0x42, 0x09, 1, 0, 0, 0, 0]);
    assert_eq!(m.state(ID).unwrap(), Some(State::FaultReactionActive));
    assert_eq!(m.read_u16(ID, 0x603F, 0).unwrap(), 0x4210);
    m.advance(300_000);
    assert!(m.read_i64(ID, 0x606C, 0).unwrap() > 0, "still ramping down");
    assert!(m.wait_until(2_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 0);
    // Fault reset (cw bit 7), enable again.
    m.controlword(ID, 0x80).unwrap();
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
    assert_eq!(m.read_u16(ID, 0x603F, 0).unwrap(), 0);
    assert!(app(&m).drive().fault().is_none());
    m.controlword(ID, 0x00).unwrap();
    m.switch_on(ID).unwrap();
    m.advance(1_100_000);
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 1000);
    // Hard: over current (2310h / 0): power off at once, the axis coasts.
    let now = m.now();
    let node = m.sim_mut().downcast_mut::<PlainNode>(0).unwrap();
    node.with_app(now, |app, ctx| {
        app.drive_mut().raise(ctx, 0x2310, Some(0));
    });
    m.advance(0);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert!(!app(&m).drive().axis().status().power);
    let emcy = m.take_id(0x80 + u32::from(ID));
    assert_eq!(emcy.last().unwrap().frame.data(), [0x10, 0x23, 0x03, 0, 0, 0, 0, 0]);
}

#[test]
fn heartbeat_loss_is_the_fieldbus_disconnection_error() {
    let mut m = plain();
    // Consume the master's (node 127) heartbeat, 100 ms.
    m.write_u32(ID, 0x1016, 1, (127 << 16) | 100).ok();
    let has_consumer = m.read_u32(ID, 0x1016, 1).is_ok();
    if !has_consumer {
        // The DRVI has no 1016h: guard instead (100 ms × 3).
        m.write_u16(ID, 0x100C, 0, 100).unwrap();
        m.write_u8(ID, 0x100D, 0, 3).unwrap();
    }
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    for _ in 0..12 {
        if has_consumer {
            m.heartbeat(127);
        } else {
            m.send(od_bus::CanFrame::remote(0x700 + u32::from(ID), false, 1).unwrap());
        }
        m.advance(90_000);
    }
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    m.take_seen();
    // Silence: the life time runs out.
    assert!(m.wait_until(1_000_000, 5_000, |m| m.seen().any(|s| s.frame.id() == 0x80 + u32::from(ID))));
    let emcy = m.take_id(0x80 + u32::from(ID));
    assert_eq!(&emcy[0].frame.data()[..3], [0x30, 0x81, 0x11]);
    assert_eq!(m.state(ID).unwrap(), Some(State::FaultReactionActive), "soft error: quick stop first");
    assert!(m.wait_until(3_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    assert_eq!(m.read_i64(ID, 0x606C, 0).unwrap(), 0);
}

/// A vendor that refuses every set-point and records the refusals.
#[derive(Default)]
struct Refuser {
    refused: Arc<Mutex<u32>>,
}

impl Vendor<Dictionary> for Refuser {
    fn before_command(
        &mut self,
        _: &mut drive::drives::Drive,
        _: &mut drive::node::Ctx<'_, Dictionary>,
        cmd: &mut drive::drives::Command,
    ) -> bool {
        if matches!(cmd, drive::drives::Command::SetPoint(_)) {
            *self.refused.lock().unwrap() += 1;
            return false;
        }
        true
    }

    fn statusword(&self, _: &drive::drives::Drive, _: &Dictionary, _: &drive::motion::Status, bits: &mut u16) {
        *bits |= 1 << 15;
    }
}

#[test]
fn vendor_hooks_refuse_commands_and_add_statusword_bits() {
    let refused = Arc::new(Mutex::new(0));
    let mut sim = Sim::new();
    let app = Cia402App::<Dictionary, _>::new(Refuser { refused: Arc::clone(&refused) }, error_table(DeviceKind::Drvi));
    sim.add(Box::new(Node::new(Dictionary::new(ID), app, NodeStorage::memory(), NodeId::new(ID).unwrap())));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 1).unwrap();
    profile(&mut m, 1000, 1000);
    m.write_i32(ID, 0x607A, 0, 1000).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(100_000);
    assert_eq!(*refused.lock().unwrap(), 1);
    let sw = m.statusword(ID).unwrap();
    assert_eq!(sw & (1 << 12), 0, "no acknowledge for a refused set-point");
    assert_ne!(sw & (1 << 15), 0, "vendor bit");
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 0);
}

#[test]
fn traces_record_bus_values_every_tick() {
    let apps = DeviceApps::with_trace(0);
    let mut sim = Sim::new();
    sim.add(DeviceKind::Drvi.build(&NodeConfig { node_id: Some(ID), ..Default::default() }, &apps).unwrap());
    let mut m = Master::new(sim);
    m.advance(1000);
    m.advance(50_000);
    let traces = apps.traces();
    assert_eq!(traces.len(), 1);
    assert_eq!(traces[0].0, DeviceKind::Drvi);
    let t: Trace = traces[0].1.lock().unwrap().clone();
    assert!((45..=52).contains(&t.samples().len()), "{}", t.samples().len());
    assert!(t.samples().windows(2).all(|w| w[1].time_us - w[0].time_us == 1000));
}

#[test]
fn mechanics_are_reachable_for_tests() {
    let mut m = plain();
    let node = m.sim_mut().downcast_mut::<PlainNode>(0).unwrap();
    let app = node.app_mut().unwrap();
    *app.drive_mut().axis_mut().environment_mut() = Environment { negative_end_stop: Some(-100), ..Default::default() };
    assert_eq!(app.drive().axis().environment().negative_end_stop, Some(-100));
}

type AkdPlain = Node<generated::akd::Dictionary, Cia402App<generated::akd::Dictionary, Plain>>;

/// A plain CiA 402 drive on the AKD dictionary (which has 1016h and 60C0h..60C4h).
fn plain_akd() -> Master {
    let mut sim = Sim::new();
    let app = Cia402App::<generated::akd::Dictionary, _>::new(Plain, error_table(DeviceKind::Akd));
    let node = Node::new(generated::akd::Dictionary::new(ID), app, NodeStorage::memory(), NodeId::new(ID).unwrap());
    sim.add(Box::new(node));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m
}

#[test]
fn interpolated_position_consumes_60c1h_at_each_sync() {
    let mut m = plain_akd();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 7).unwrap();
    // 60C2h: 1 × 10^-3 s, the SYNC period.
    m.controlword(ID, 0x1F).unwrap(); // enable interpolation
    assert_ne!(m.statusword(ID).unwrap() & (1 << 12), 0, "ip mode active");
    for k in 1..=100 {
        m.write_i32(ID, 0x60C1, 1, 10 * k).unwrap();
        m.sync();
        m.advance(1000);
    }
    m.advance(5000);
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 1000);
    // Disabled: further set-points are not followed.
    m.controlword(ID, 0x0F).unwrap();
    m.write_i32(ID, 0x60C1, 1, 5000).unwrap();
    m.sync();
    m.advance(10_000);
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 1000);
    let _ = app_akd(&m);
}

fn app_akd(m: &Master) -> &Cia402App<generated::akd::Dictionary, Plain> {
    m.sim().downcast::<AkdPlain>(0).unwrap().app().unwrap()
}

#[test]
fn a_lost_heartbeat_is_raised_once_and_stays_latched() {
    let mut m = plain_akd();
    m.write_u32(ID, 0x1016, 1, (1 << 16) | 100).unwrap(); // node 1, 100 ms
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    for _ in 0..10 {
        m.heartbeat(1);
        m.advance(50_000);
    }
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    m.take_seen();
    m.advance(1_000_000);
    let emcy = m.take_id(0x80 + u32::from(ID));
    assert_eq!(emcy.len(), 1, "one EMCY per loss: {emcy:?}");
    assert_eq!(&emcy[0].frame.data()[..2], [0x30, 0x81]);
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    assert!(!app_akd(&m).drive().axis().status().power);
    // The master is back: still latched until the fault reset.
    for _ in 0..3 {
        m.heartbeat(1);
        m.advance(50_000);
    }
    assert_eq!(m.state(ID).unwrap(), Some(State::Fault));
    m.controlword(ID, 0x80).unwrap();
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchOnDisabled));
}

#[test]
fn cia402_homing_on_a_limit_switch_sets_bits_12_and_10() {
    let mut m = plain_akd();
    {
        let node = m.sim_mut().downcast_mut::<AkdPlain>(0).unwrap();
        let env = node.app_mut().unwrap().drive_mut().axis_mut().environment_mut();
        *env = Environment { negative_limit: Some(-3000), ..Default::default() };
    }
    m.switch_on(ID).unwrap();
    m.write(ID, 0x6098, 0, &[17]).unwrap(); // negative limit switch, no index
    m.write_u32(ID, 0x6099, 1, 2000).unwrap();
    m.write_u32(ID, 0x6099, 2, 200).unwrap();
    m.write_u32(ID, 0x609A, 0, 20_000).unwrap();
    m.write_i32(ID, 0x607C, 0, 0).unwrap();
    m.set_mode(ID, 6).unwrap();
    assert_eq!(m.statusword(ID).unwrap() & 0x3400, 0x0400, "not started: bit 10 only");
    m.controlword(ID, 0x1F).unwrap();
    assert_eq!(m.statusword(ID).unwrap() & 0x3400, 0, "in progress");
    let sw = m.wait_statusword(ID, 0x3400, 0x1400, 10_000_000, 10_000).expect("homing completed");
    assert_eq!(sw & (1 << 13), 0);
    assert_eq!(m.read_i64(ID, 0x6064, 0).unwrap(), 0);
}

// ---------------------------------------------------------------------------------------------
// Polarity and homing (607Eh).

fn app_mut(m: &mut Master) -> &mut Cia402App<Dictionary, Plain> {
    m.sim_mut().downcast_mut::<PlainNode>(0).unwrap().app_mut().unwrap()
}

/// Starts homing `method` with 607Eh = `polarity` and returns the sign of 606Ch during the
/// search and the statusword at its end.
fn search_direction(m: &mut Master, method: u8, polarity: u8) -> (i64, u16) {
    m.write_u8(ID, 0x607E, 0, polarity).unwrap();
    m.write(ID, 0x6098, 0, &[method]).unwrap();
    m.write_u32(ID, 0x6099, 1, 2000).unwrap();
    m.write_u32(ID, 0x6099, 2, 500).unwrap();
    m.write_u32(ID, 0x609A, 0, 20_000).unwrap();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 6).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    m.advance(300_000);
    let v = m.read_i64(ID, 0x606C, 0).unwrap();
    let sw = m.wait_statusword(ID, 0x3400, 0x1400, 20_000_000, 10_000).unwrap_or_else(|| m.statusword(ID).unwrap());
    (v.signum(), sw)
}

/// CiA 402 (607Eh): "the polarity flag shall have no influence on the homing mode". Method 17
/// (negative limit switch) searches the motor's negative side either way; with 607Eh = 80h
/// that direction reads as a positive velocity on the bus.
#[test]
fn polarity_leaves_a_cia402_homing_alone() {
    for (polarity, bus_sign) in [(0x00, -1), (0x80, 1)] {
        let mut m = plain();
        let env = Environment { negative_limit: Some(-3000), ..Environment::default() };
        *app_mut(&mut m).drive_mut().axis_mut().environment_mut() = env;
        let (sign, sw) = search_direction(&mut m, 17, polarity);
        assert_eq!(sign, bus_sign, "607Eh = {polarity:#04X}: 606Ch during the search");
        assert_eq!(sw & 0x3400, 0x1400, "607Eh = {polarity:#04X}: homed on the negative limit switch");
        assert_eq!(app(&m).drive().axis().status().position_actual, 0, "the home point reads as the offset");
    }
}

/// A device whose manual says the polarity reverses the homing too (the Camozzi drives) runs
/// the mirrored method: with 607Eh = 80h method 17 searches the drive's negative direction
/// (606Ch < 0), the motor's positive side, where a plain CiA 402 drive finds nothing.
#[test]
fn a_vendor_can_make_the_polarity_reverse_the_homing() {
    struct Camozzi;
    impl Vendor<Dictionary> for Camozzi {
        fn homing_method(&self, code: i8) -> Option<drive::motion::HomingMethod> {
            drive::motion::HomingMethod::cia402(code)
        }
        fn polarity_reverses_homing(&self) -> bool {
            true
        }
    }
    type CamozziNode = Node<Dictionary, Cia402App<Dictionary, Camozzi>>;
    let mut sim = Sim::new();
    let mut app = Cia402App::<Dictionary, _>::new(Camozzi, error_table(DeviceKind::Drvi));
    // Only a positive limit switch: the mirrored method 17 looks for it (the drive's negative
    // limit is the motor's positive one).
    *app.drive_mut().axis_mut().environment_mut() =
        Environment { positive_limit: Some(3000), ..Environment::default() };
    sim.add(Box::new(Node::new(Dictionary::new(ID), app, NodeStorage::memory(), NodeId::new(ID).unwrap())));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    let (sign, sw) = search_direction(&mut m, 17, 0x80);
    assert_eq!(sign, -1, "the drive's negative direction");
    assert_eq!(sw & 0x3400, 0x1400, "homed");
    let node = m.sim().downcast::<CamozziNode>(0).unwrap();
    let st = node.app().unwrap().drive().axis().status();
    assert!(st.homed);
    assert_eq!(st.position_actual, 0, "the home point reads as the home offset");
}

// ---------------------------------------------------------------------------------------------
// 1010h: the sidecar's store list, for every device.

#[test]
fn every_store_list_object_is_a_writable_entry_of_its_dictionary() {
    for kind in DeviceKind::ALL {
        let list = drive::drives::store::store_list(kind);
        assert!(list.len() > 20, "{kind}: a store list");
        for r in &list {
            let writable = kind
                .entries()
                .iter()
                .filter(|e| e.index == r.index && r.sub.is_none_or(|s| s == e.sub))
                .any(|e| e.access.writable());
            assert!(writable, "{kind}: {r} is not a writable entry");
        }
        for command in [0x6040u16, 0x607A, 0x1010, 0x1011] {
            assert!(!list.iter().any(|r| r.index == command), "{kind}: {command:04X} is not a parameter");
        }
        // The DRCS manual lists the target velocity among its stored objects (3.2.13).
        assert_eq!(list.iter().any(|r| r.index == 0x60FF), kind == DeviceKind::Drcs, "{kind}: 60FFh");
    }
}

/// A save keeps the listed parameters and nothing else (DRVI 6.3.2.13, DRCS 3.2.13, AKD
/// 6.2.1.12): commands written before the save come back as defaults after a restart.
#[test]
fn a_save_keeps_only_the_store_list() {
    use drive::storage::FileStorage;
    use od_runtime::od::Area;
    for kind in DeviceKind::ALL {
        let dir = std::env::temp_dir().join(format!("drives-common-store-{kind}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let config = NodeConfig { node_id: Some(ID), state_dir: Some(dir.clone()), ..Default::default() };
        let start = || {
            let mut sim = Sim::new();
            sim.add(kind.build(&config, &DeviceApps::new()).unwrap());
            let mut m = Master::new(sim);
            m.advance(1000);
            m
        };
        {
            let mut m = start();
            m.write_u32(ID, 0x6081, 0, 42).unwrap();
            m.write_i32(ID, 0x607A, 0, 4321).unwrap();
            m.write_i32(ID, 0x60FF, 0, 77).unwrap();
            m.controlword(ID, 0x06).unwrap();
            m.write(ID, 0x1010, 1, b"save").unwrap();
        }
        let files = FileStorage::open(&dir, &format!("{kind}-node{ID}")).unwrap();
        let list = drive::drives::store::store_list(kind);
        let mut saved = 0;
        for area in [Area::Communication, Area::Application, Area::Manufacturer] {
            for r in files.read_image(area).unwrap().unwrap_or_default() {
                saved += 1;
                assert!(
                    list.iter().any(|o| o.index == r.index && o.sub.is_none_or(|s| s == r.sub)),
                    "{kind}: {:04X}sub{} saved but not listed",
                    r.index,
                    r.sub
                );
            }
        }
        assert!(saved > 20, "{kind}: {saved} entries saved");
        let mut m = start();
        assert_eq!(m.read_u32(ID, 0x6081, 0).unwrap(), 42, "{kind}: a parameter");
        assert_eq!(m.read_i64(ID, 0x607A, 0).unwrap(), 0, "{kind}: a command");
        let velocity = if kind == DeviceKind::Drcs { 77 } else { 0 };
        assert_eq!(m.read_i64(ID, 0x60FF, 0).unwrap(), velocity, "{kind}: 60FFh (stored by the DRCS only)");
        assert_eq!(m.read_u16(ID, 0x6040, 0).unwrap(), 0, "{kind}: the controlword");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

// ---------------------------------------------------------------------------------------------
// Stops on a blocked axis; holding in Switched on.

/// Profile velocity into a hard end stop: the axis stands against it, away from its demand.
fn blocked_against_an_end_stop() -> Master {
    let mut m = plain();
    *app_mut(&mut m).drive_mut().axis_mut().environment_mut() =
        Environment { positive_end_stop: Some(300), ..Environment::default() };
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 500).unwrap();
    m.advance(2_000_000);
    let st = app(&m).drive().axis().status();
    assert!(st.inputs.end_stop && st.velocity_actual == 0, "blocked: {st:?}");
    m
}

/// The stop ramp of a soft error ends, but the blocked axis never settles on its demand: the
/// fault reaction ends with the ramp (common layer), it does not wait forever.
#[test]
fn a_fault_reaction_on_a_blocked_axis_ends_with_its_ramp() {
    let mut m = blocked_against_an_end_stop();
    let now = m.now();
    m.sim_mut().downcast_mut::<PlainNode>(0).unwrap().with_app(now, |app, ctx| {
        app.drive_mut().raise(ctx, 0x4210, Some(1)); // a quick-stop error
    });
    m.advance(0);
    assert_eq!(m.state(ID).unwrap(), Some(State::FaultReactionActive));
    assert!(m.wait_until(2_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::Fault)));
    assert!(!app(&m).drive().axis().status().power);
}

#[test]
fn a_quick_stop_on_a_blocked_axis_ends_with_its_ramp() {
    let mut m = blocked_against_an_end_stop();
    m.controlword(ID, 0x0B).unwrap();
    assert_eq!(m.state(ID).unwrap(), Some(State::QuickStopActive));
    assert!(m.wait_until(2_000_000, 10_000, |m| m.state(ID).unwrap() == Some(State::SwitchOnDisabled)));
}

/// Vendor::disable_reaction: a drive whose output stage holds the axis in Switched on (the
/// AKD's 6.4.1.1) ramps down on disable operation and keeps the power on; CiA 402 (605Ch = 0
/// here) switches it off at once.
#[test]
fn a_vendor_can_hold_the_axis_in_switched_on() {
    use drive::drives::cia402::DisableReaction;
    use drive::motion::StopRamp;
    struct Holder;
    impl Vendor<Dictionary> for Holder {
        fn disable_reaction(&self, od: &Dictionary, from: State, to: State) -> DisableReaction {
            if to == State::SwitchedOn {
                DisableReaction::hold(StopRamp::ProfileDeceleration)
            } else {
                DisableReaction::cia402(od, from, to)
            }
        }
    }
    type HolderNode = Node<Dictionary, Cia402App<Dictionary, Holder>>;
    let mut sim = Sim::new();
    let app = Cia402App::<Dictionary, _>::new(Holder, error_table(DeviceKind::Drvi));
    sim.add(Box::new(Node::new(Dictionary::new(ID), app, NodeStorage::memory(), NodeId::new(ID).unwrap())));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    let power = |m: &Master| m.sim().downcast::<HolderNode>(0).unwrap().app().unwrap().drive().axis().status();
    // Switch on (transition 3) already powers the stage.
    m.controlword(ID, 0x06).unwrap();
    m.controlword(ID, 0x07).unwrap();
    assert!(power(&m).power, "Switched on: the stage holds the axis");
    m.controlword(ID, 0x0F).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 500).unwrap();
    m.advance(600_000);
    m.controlword(ID, 0x07).unwrap(); // disable operation
    m.advance(200_000);
    let st = power(&m);
    assert!(st.power && st.velocity_actual > 0, "ramping down with the power on: {st:?}");
    m.advance(800_000);
    let st = power(&m);
    assert!(st.power && st.standing, "stopped and held: {st:?}");
    assert_eq!(m.state(ID).unwrap(), Some(State::SwitchedOn));
    // Shutdown (8): CiA 402, off.
    m.controlword(ID, 0x06).unwrap();
    assert!(!power(&m).power);
}

// ---------------------------------------------------------------------------------------------
// What a master reads right after a write.

/// Bit 10 follows a new target velocity at once: reached at 500, not reached right after
/// 60FFh = 1000 (before any tick), reached again once at speed.
#[test]
fn the_statusword_follows_a_new_target_velocity_at_once() {
    let mut m = plain();
    m.switch_on(ID).unwrap();
    m.set_mode(ID, 3).unwrap();
    profile(&mut m, 0, 1000);
    m.write_i32(ID, 0x60FF, 0, 500).unwrap();
    m.advance(700_000);
    assert_ne!(m.statusword(ID).unwrap() & (1 << 10), 0, "at 500");
    let ticks = app(&m).drive().ticks();
    m.write_i32(ID, 0x60FF, 0, 1000).unwrap();
    let sw = m.statusword(ID).unwrap();
    assert_eq!(app(&m).drive().ticks(), ticks, "no tick in between");
    assert_eq!(sw & (1 << 10), 0, "1000 is not reached yet: {sw:#06X}");
    m.advance(700_000);
    assert_ne!(m.statusword(ID).unwrap() & (1 << 10), 0, "at 1000");
}

/// Issue #7 point 1: the plant runs on the virtual clock. The three drives on one in-memory bus,
/// driven through the same frames twice, produce the same frames at the same virtual times and
/// the same traces, tick for tick; and the virtual time is exactly what the master advanced.
#[test]
fn every_drive_is_deterministic_on_the_virtual_clock() {
    type Run = (Vec<(u64, u32, u8, [u8; 8])>, Vec<String>, u64);
    fn run() -> Run {
        let apps = DeviceApps::with_trace(0);
        let mut sim = Sim::new();
        let ids = [(DeviceKind::Drvi, 2u8), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)];
        for (kind, id) in ids {
            sim.add(kind.build(&NodeConfig { node_id: Some(id), ..Default::default() }, &apps).unwrap());
        }
        let mut m = Master::new(sim);
        m.advance(1000);
        m.nmt_start(0);
        // Heartbeats and the statusword TPDOs on event timers keep frames coming.
        for (_, id) in ids {
            m.write_u16(id, 0x1017, 0, 50).unwrap();
        }
        // The DRCS moves only after a homing (3.2.4 FF13h): method 37, in place.
        m.switch_on(3).unwrap();
        m.set_mode(3, 6).unwrap();
        m.write_u8(3, 0x6098, 0, 37).unwrap();
        m.controlword(3, 0x1F).unwrap();
        m.advance(10_000);
        m.controlword(3, 0x0F).unwrap();
        // Profile velocity everywhere: 30 rpm (DRVI), 50 mm/s (DRCS), 5 turns/s (AKD).
        for (id, v, a) in [(2u8, 3000i32, 600u32), (3, 50, 500), (4, 5, 50)] {
            m.switch_on(id).unwrap();
            m.set_mode(id, 3).unwrap();
            m.write_u32(id, 0x6083, 0, a).unwrap();
            m.write_u32(id, 0x6084, 0, a).unwrap();
            m.write_i32(id, 0x60FF, 0, v).unwrap();
        }
        m.advance(300_000);
        for id in [2u8, 3, 4] {
            m.controlword(id, 0x10F).unwrap(); // halt
        }
        m.advance(300_000);
        let frames = m.take_seen().iter().map(|s| (s.at, s.frame.id(), s.frame.dlc(), s.frame.raw_data())).collect();
        let traces = apps.traces().iter().map(|(_, t)| t.lock().unwrap().to_csv()).collect();
        (frames, traces, m.now())
    }
    let (a, b) = (run(), run());
    assert_eq!(a.2, b.2, "the same virtual time");
    assert_eq!(a.0.len(), b.0.len(), "the same number of frames");
    for (i, (x, y)) in a.0.iter().zip(&b.0).enumerate() {
        assert_eq!(x, y, "frame {i}");
    }
    assert_eq!(a.1.len(), 3, "one trace per drive");
    for (i, (x, y)) in a.1.iter().zip(&b.1).enumerate() {
        assert!(x == y, "trace {i} differs");
    }
    // Not trivially equal: every drive moved, and heartbeats went out on the virtual clock.
    for (i, csv) in a.1.iter().enumerate() {
        let t = Trace::from_csv(csv).unwrap();
        assert!(t.samples().iter().any(|s| s.velocity_actual != 0), "drive {i} moved");
        assert_eq!(t.samples().last().unwrap().velocity_actual, 0, "drive {i} halted");
    }
    let beats: Vec<u64> = a.0.iter().filter(|f| f.1 == 0x702).map(|f| f.0).collect();
    assert!(beats.len() >= 10, "{beats:?}");
    assert!(
        beats.windows(2).skip(1).all(|w| w[1] - w[0] == 50_000),
        "50 ms heartbeats on the virtual clock: {beats:?}"
    );
}
