//! The machines around the drives (issue 17): every preset of every device, the defaults,
//! machine files, on the in-memory bus and the virtual clock.

use crate::support::Master;
use drive::drives::akd::{self, COUNTS_PER_TURN};
use drive::drives::drcs::{self, Mechanics};
use drive::drives::machine::{self, presets};
use drive::drives::{DeviceApps, drvi};
use drive::motion::{Cam, Environment, Machine, Travel};
use drive::node::{DeviceKind, Node, NodeConfig, NodeStorage, Sim};
use od_runtime::NodeId;
use od_runtime::cia402::State;

const ID: u8 = 5;

/// A drive of `kind` on `machine` (`None`: its default), started, enabled, in mode `mode`.
fn drive_on(kind: DeviceKind, machine: Option<Machine>) -> Master {
    let apps = DeviceApps::new();
    apps.set_machine(machine);
    let mut sim = Sim::new();
    sim.add(kind.build(&NodeConfig { node_id: Some(ID), ..Default::default() }, &apps).unwrap());
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(ID);
    m.advance(1000);
    m.take_seen();
    m.switch_on(ID).unwrap();
    m
}

/// Profile velocity at `velocity` (bus units) for `seconds`; the position reached.
fn run_velocity(m: &mut Master, velocity: i32, acceleration: u32, seconds: u64) -> i64 {
    m.write_u32(ID, 0x6083, 0, acceleration).unwrap();
    m.write_u32(ID, 0x6084, 0, acceleration).unwrap();
    m.set_mode(ID, 3).unwrap();
    m.write_i32(ID, 0x60FF, 0, velocity).unwrap();
    for _ in 0..seconds * 10 {
        m.advance(100_000);
    }
    m.read_i64(ID, 0x6064, 0).unwrap()
}

fn emcy_codes(m: &mut Master) -> Vec<u16> {
    m.take_id(0x80 + u32::from(ID)).iter().map(|s| u16::from_le_bytes([s.frame.data()[0], s.frame.data()[1]])).collect()
}

#[test]
fn every_device_has_its_presets_and_the_default_first() {
    let names = |kind| presets(kind).iter().map(|p| p.name).collect::<Vec<_>>();
    assert_eq!(names(DeviceKind::Drvi), ["free", "drvi-actuator"]);
    assert_eq!(names(DeviceKind::Drcs), ["drcs-belt", "free"]);
    assert_eq!(names(DeviceKind::Akd), ["akd-linear", "free"]);
    for kind in DeviceKind::ALL {
        for p in presets(kind) {
            assert_eq!(p.machine.check(), Ok(()), "{kind} {}", p.name);
            // A preset written as a file reads back as itself.
            assert_eq!(Machine::parse("preset.toml", &p.machine.to_toml()).unwrap(), p.machine);
            assert_eq!(machine::resolve(kind, p.name).unwrap(), p.machine);
        }
    }
    let help = machine::help();
    for line in ["drvi free (default)", "drcs drcs-belt (default)", "akd akd-linear (default)"] {
        assert!(help.contains(line), "{line}: {help}");
    }
}

/// The presets keep the layouts the tests were written for.
#[test]
fn the_presets_are_the_former_fixed_layouts() {
    let turn = COUNTS_PER_TURN;
    assert_eq!(
        akd::default_environment(),
        Environment {
            home_switch: Some(Cam { low: turn / 4, high: turn / 2 }),
            negative_limit: Some(-turn),
            positive_limit: Some(2 * turn),
            negative_end_stop: Some(-2 * turn),
            positive_end_stop: Some(3 * turn),
            index_period: turn as u64,
            index_phase: (turn as f64 * 0.1).round() as i64,
        }
    );
    assert_eq!(
        drvi::default_environment(),
        Environment {
            home_switch: Some(Cam { low: 20_000, high: 25_000 }),
            negative_limit: None,
            positive_limit: None,
            negative_end_stop: Some(-50_000),
            positive_end_stop: Some(150_000),
            index_period: 36_000,
            index_phase: 1_000,
        }
    );
    let belt = machine::preset(DeviceKind::Drcs, "drcs-belt").unwrap();
    assert_eq!(Mechanics::from_machine(&belt), Mechanics::actuator());
    let free = Mechanics::from_machine(&machine::preset(DeviceKind::Drcs, "free").unwrap());
    assert_eq!(free.system, Mechanics::only_motor().system);
    assert_eq!(free.environment, Environment { index_period: 360_000, ..Environment::default() });
}

/// Finding 7: the DRVI starts as the bare motor its default 2014h = 0 ("only motor") says,
/// and the manual's speed mode (4.1.1) turns it for as long as the master wants: ten turns at
/// 60 rpm without an end stop or an I²T fault.
#[test]
fn drvi_default_is_a_free_motor() {
    let mut m = drive_on(DeviceKind::Drvi, None);
    assert_eq!(m.read_u8(ID, 0x2014, 0).unwrap(), 0, "only motor");
    let p = run_velocity(&mut m, 6000, 600, 11); // 60 rpm (0.01 rpm), 600 rpm/s
    assert!(p > 10 * 36_000, "{p}");
    assert_eq!(m.state(ID).unwrap(), Some(State::OperationEnabled));
    assert!(emcy_codes(&mut m).is_empty());
}

#[test]
fn drvi_actuator_preset_ends_on_its_end_stop() {
    let mut m = drive_on(DeviceKind::Drvi, machine::preset(DeviceKind::Drvi, "drvi-actuator"));
    let p = run_velocity(&mut m, 6000, 600, 6);
    assert!((149_000..=150_000).contains(&p), "blocked at 1500.00: {p}");
}

#[test]
fn akd_free_preset_turns_without_switches() {
    let mut m = drive_on(DeviceKind::Akd, machine::preset(DeviceKind::Akd, "free"));
    let p = run_velocity(&mut m, 5, 100, 3); // 5 turns/s
    assert!(p >= 12, "{p} turns");
    assert_eq!(m.read_u32(ID, 0x60FD, 0).unwrap() & 0x7, 0, "no switch");
    assert!(emcy_codes(&mut m).is_empty());
}

#[test]
fn akd_linear_preset_stops_on_its_limit_switch() {
    let mut m = drive_on(DeviceKind::Akd, None);
    let p = run_velocity(&mut m, 5, 100, 3);
    assert_eq!(p, 2, "stopped on the switch at 2 turns");
    assert_eq!(m.read_u32(ID, 0x60FD, 0).unwrap() & 0x7, 0b010, "positive limit switch");
    assert_eq!(emcy_codes(&mut m), [akd::code::LIMIT_SWITCH]);
}

/// The DRCS homes (it moves nothing before), then runs; `fast` in bus units per second.
fn drcs_homed_run(m: &mut Master, fast: i32, seconds: u64) -> i64 {
    m.set_mode(ID, 6).unwrap();
    m.write_u8(ID, 0x6098, 0, 37).unwrap();
    m.controlword(ID, 0x1F).unwrap();
    assert!(m.wait_statusword(ID, 0x1400, 0x1400, 100_000, 1000).is_some());
    m.controlword(ID, 0x0F).unwrap();
    run_velocity(m, fast, 100, seconds)
}

#[test]
fn drcs_belt_preset_is_its_eds_qset_configuration() {
    let mut m = drive_on(DeviceKind::Drcs, None);
    assert_eq!(m.read_i64(ID, 0x607D, 2).unwrap(), 1000);
    assert_eq!(m.read_u32(ID, 0x6092, 1).unwrap(), 70);
    // Past the full scale the hard end stop at 910 mm holds the carriage.
    let p = drcs_homed_run(&mut m, 100, 12);
    assert!((905..=910).contains(&p), "{p} mm");
}

#[test]
fn drcs_free_preset_is_only_motor() {
    let mut m = drive_on(DeviceKind::Drcs, machine::preset(DeviceKind::Drcs, "free"));
    assert_eq!((m.read_i64(ID, 0x607D, 1).unwrap(), m.read_i64(ID, 0x607D, 2).unwrap()), (0, 0), "no limits");
    let p = drcs_homed_run(&mut m, 360, 6); // 360 °/s
    assert!(p > 1500, "{p}°");
    assert_ne!(m.state(ID).unwrap(), Some(State::Fault));
}

/// A machine file for each device: its switches and end stops, in the device's unit.
#[test]
fn a_machine_file_works_for_every_device() {
    // AKD: an end stop at 1.5 turns, a heavy load.
    let akd_file =
        Machine::parse("akd.toml", "travel = \"linear\"\nload_inertia = 9.0\npositive_end_stop = 1.5").unwrap();
    let mut m = drive_on(DeviceKind::Akd, Some(akd_file));
    run_velocity(&mut m, 1, 100, 3);
    let increments = m.read_i64(ID, 0x6063, 0).unwrap();
    let end = 3 * COUNTS_PER_TURN / 2;
    assert!((end - COUNTS_PER_TURN / 100..=end).contains(&increments), "blocked at 1.5 turns: {increments}");
    // The load: (1 + 9) / 2 times the built-in inertia (a motor with a load of its own).
    type AkdNode = Node<generated::akd::Dictionary, drive::drives::Cia402App<generated::akd::Dictionary, akd::Akd>>;
    let mut sim = Sim::new();
    let app = akd::app_with(&Machine { load_inertia: 9.0, ..Machine::free() });
    sim.add(Box::new(Node::new(
        generated::akd::Dictionary::new(ID),
        app,
        NodeStorage::memory(),
        NodeId::new(ID).unwrap(),
    )));
    sim.advance(5000);
    let inertia = sim.downcast::<AkdNode>(0).unwrap().app().unwrap().drive().axis().config().plant.inertia;
    assert!((inertia / akd::plant().inertia - 5.0).abs() < 1e-9, "{inertia}");
    // DRVI: end stop at 90° (0.01° units).
    let drvi_file = Machine::parse("drvi.toml", "travel = \"linear\"\npositive_end_stop = 9000.0").unwrap();
    let mut m = drive_on(DeviceKind::Drvi, Some(drvi_file));
    let p = run_velocity(&mut m, 6000, 600, 2);
    assert!((8_900..=9_000).contains(&p), "{p}");
    // DRCS: a 300 mm stroke between end stops at -10 and 310 mm.
    let drcs_file = Machine::parse(
        "drcs.toml",
        "travel = \"linear\"\nstroke = 300.0\nnegative_end_stop = -10.0\npositive_end_stop = 310.0",
    )
    .unwrap();
    assert_eq!(drcs_file.travel, Travel::Linear);
    let mut m = drive_on(DeviceKind::Drcs, Some(drcs_file));
    assert_eq!(m.read_i64(ID, 0x607D, 2).unwrap(), 300, "the stroke is the full scale");
    // Profile velocity ends at the full scale (the software limit), before the end stop.
    let p = drcs_homed_run(&mut m, 100, 5);
    assert!((295..=300).contains(&p), "{p} mm");
    let _ = drcs::app();
}
