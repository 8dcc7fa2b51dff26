//! The CiA 402 axis on each simulated drive: enable, homing, profile position and velocity,
//! cyclic synchronous position, recovery from a fault, errors that name the drive.

use std::path::Path;
use std::time::Duration;

use drive::node::DeviceKind;
use od_bus::tokio::Bus as Link;
use od_master::{Axis, AxisErrorKind, Bus, Config, Error, Homing, Move, NodeId, State, StatusRegister, StopReason};

use crate::harness::{net, net_with, pass};

/// Each drive's homing method that homes where it stands, a target and a speed in its
/// default units, and the configuration its manual's examples start with.
async fn prepare(kind: DeviceKind, axis: &Axis) -> (i8, i32, u32) {
    match kind {
        // 0.01° units: 360° at 60 rpm.
        DeviceKind::Drvi => (37, 36_000, 6_000),
        // The DRCS's stroke is 0..=1000 from the home point.
        DeviceKind::Drcs => (37, 500, 50),
        // 10 000 counts a turn (the AKD manual's examples): half a turn at 1 turn/s, short of
        // the preset machine's limit switch.
        DeviceKind::Akd => {
            axis.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
            (35, 5_000, 10_000)
        }
    }
}

/// Each drive homes and moves; the position the move reports is 6064h, at the target.
#[tokio::test(start_paused = true)]
async fn each_drive_homes_and_moves_to_its_target() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    for (kind, id) in [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)] {
        let axis = Axis::new(n.bus.node(id).unwrap());
        let (method, target, velocity) = prepare(kind, &axis).await;
        let home = axis.home(&Homing::method(method)).await.unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_eq!(home, 0, "{kind:?}");
        assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
        let m = Move {
            velocity: Some(velocity),
            acceleration: Some(velocity),
            deceleration: Some(velocity),
            ..Move::default()
        };
        let at = axis.move_to(target, &m).await.unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        assert_eq!(at, target, "{kind:?}");
        assert_eq!(axis.node().read::<i32>(0x6064, 0).await.unwrap(), at, "{kind:?}");
        // Relative, back by half.
        let back = axis.move_to(-target / 2, &Move { relative: true, ..m }).await.unwrap();
        assert_eq!(back, target - target / 2, "{kind:?}");
    }
}

/// Change set immediately: a second set-point replaces the running one on the AKD, which
/// then stops at the second target.
#[tokio::test(start_paused = true)]
async fn change_set_immediately_replaces_the_running_set_point() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(n.bus.node(4).unwrap());
    let (method, _, v) = prepare(DeviceKind::Akd, &axis).await;
    axis.home(&Homing::method(method)).await.unwrap();
    let m = Move { velocity: Some(v), acceleration: Some(v), deceleration: Some(v), ..Move::default() };
    axis.set_point(100_000, &m).await.unwrap();
    pass(Duration::from_millis(500)).await;
    let at = axis.move_to(5_000, &Move { immediate: true, ..m }).await.unwrap();
    assert_eq!(at, 5_000);
}

/// Profile velocity: the drive runs at the speed asked for (60FFh in position units per
/// second here; the AKD's 606Ch has a scale of its own).
#[tokio::test(start_paused = true)]
async fn profile_velocity_reaches_its_speed() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(n.bus.node(4).unwrap());
    prepare(DeviceKind::Akd, &axis).await;
    axis.run_velocity(5_000, Some(50_000), Some(50_000)).await.unwrap();
    pass(Duration::from_millis(500)).await;
    let v1 = axis.velocity().await.unwrap();
    let p1 = axis.position().await.unwrap();
    pass(Duration::from_secs(1)).await;
    let p2 = axis.position().await.unwrap();
    assert_eq!(axis.velocity().await.unwrap(), v1, "at a steady speed");
    // 5 000 counts/s; the second read comes a few SDO round trips after the second.
    assert!((0..=15).contains(&(p2 - p1 - 5_000)), "moved {} in 1 s", p2 - p1);
}

/// Cyclic synchronous position on the AKD: an RPDO mapped at run time carries one set-point
/// per 1 ms SYNC, and the drive follows the ramp to its end.
#[tokio::test(start_paused = true)]
async fn cyclic_synchronous_position_follows_a_set_point_per_sync() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    // The sidecar: the AKD runs cyclic synchronous position though its 6502h leaves it out.
    let axis = Axis::new(n.bus.node(4).unwrap()).with_sidecar(&crate::harness::sidecar("kollmorgen-akd"));
    prepare(DeviceKind::Akd, &axis).await;
    axis.home(&Homing::method(35)).await.unwrap();
    n.bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut csp = axis.cyclic_position(4, 0x504).await.unwrap();
    let start = axis.position().await.unwrap();
    let mut last = 0;
    for k in 1..=1000 {
        let n = csp.send(start + 5 * k).await.unwrap();
        assert!(n > last, "one set-point per SYNC");
        last = n;
    }
    pass(Duration::from_millis(20)).await;
    assert_eq!(axis.position().await.unwrap(), start + 5_000);
    assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
}

/// The master's heartbeat stops when its program does (here: every handle dropped); the AKD,
/// consuming it, reacts with EMCY 8130h. A new master takes it back to Operation enabled,
/// through a fault reset if it went to Fault.
#[tokio::test(start_paused = true)]
async fn a_lost_master_heartbeat_stops_the_drive_and_enable_recovers_it() {
    let config =
        Config { heartbeat: Some((NodeId::new(127).unwrap(), Duration::from_millis(20))), ..Config::default() };
    let n = net_with(&[(DeviceKind::Akd, 4)], config);
    pass(Duration::from_millis(5)).await;
    {
        let axis = Axis::new(n.bus.node(4).unwrap());
        axis.node().write_idempotent(0x1016, 1, (127u32 << 16) | 100).await.unwrap();
        axis.node().start().await.unwrap();
        axis.enable().await.unwrap();
        pass(Duration::from_millis(100)).await;
        assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled), "heartbeats arrive");
    }
    let sim = n.sim;
    drop(n.bus);
    pass(Duration::from_millis(500)).await;
    let bus = Bus::start(Link::attach(sim.lock().unwrap().bus()), Config::default());
    let axis = Axis::new(bus.node(4).unwrap());
    let stopped = axis.state().await.unwrap();
    assert!(matches!(stopped, Some(State::Fault | State::SwitchOnDisabled | State::QuickStopActive)), "{stopped:?}");
    // The error history's newest entry: life guard or heartbeat error.
    assert_eq!(axis.node().read::<u32>(0x1003, 1).await.unwrap() & 0xFFFF, 0x8130);
    axis.enable().await.unwrap();
    assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
}

/// Errors name the drive, the last statusword seen (its age, its state, its bits in words) and
/// the object: a set-point the DRVI refuses (no homing yet) raises its warning bit, and the
/// wait for the acknowledgement stops there, with 2006h read into the message.
#[tokio::test(start_paused = true)]
async fn an_axis_error_names_the_drive_its_state_and_the_object() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let sidecar = Path::new(env!("CARGO_MANIFEST_DIR")).join("../devices/camozzi-drvi.toml");
    let register = StatusRegister::from_sidecar(&od_sidecar::Sidecar::read(&sidecar).unwrap()).unwrap();
    let axis = Axis::new(n.bus.node(2).unwrap()).with_register(register);
    let m = Move { velocity: Some(6_000), timeout: Duration::from_millis(200), ..Move::default() };
    let e = axis.set_point(1_000, &m).await.unwrap_err();
    let Error::Axis(a) = &e else { panic!("{e:?}") };
    assert_eq!((a.node, a.state, a.index, a.sub), (2, Some(State::OperationEnabled), 0x6041, 0));
    assert!(matches!(&a.kind, AxisErrorKind::Stopped { why: StopReason::Warning, .. }), "{e}");
    let text = e.to_string();
    assert!(text.starts_with("drive 2 (last statusword seen "), "{text}");
    assert!(text.contains(" ms ago: Operation enabled; warning, remote"), "{text}");
    assert!(
        text.ends_with(
            "6041h sub 0: stopped waiting for set-point acknowledge: statusword bit 7 (warning) went up; the \
             drive's register 2006h = 0100h: Homing missing"
        ),
        "{text}"
    );
    // A node that does not answer: the SDO error, inside the axis error, names the object.
    let ghost = Axis::new(n.bus.node(9).unwrap().with_timeout(Duration::from_millis(50)).with_retries(0));
    let e = ghost.enable().await.unwrap_err();
    assert!(e.to_string().contains("drive 9 (no statusword read yet), 6041h sub 0: node 9, upload of 6041h sub 0: aborted by the client: 0x05040000 (SDO protocol timed out); nothing has been received from node 9"), "{e}");
}

/// A homing the DRCS cannot run (its homing speeds are 0 out of the box) is a homing error
/// (bit 13) and a fault, 8613h; the error says so, and `enable` waits for the fault reaction,
/// resets the fault and brings the drive back.
#[tokio::test(start_paused = true)]
async fn a_homing_that_faults_is_reported_and_enable_resets_the_fault() {
    let n = net(&[(DeviceKind::Drcs, 3)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(n.bus.node(3).unwrap());
    let e = axis.home(&Homing::method(17)).await.unwrap_err();
    let Error::Axis(a) = &e else { panic!("{e:?}") };
    assert!(matches!(a.kind, AxisErrorKind::Bit13("homing error")), "{e}");
    assert_eq!((a.node, a.state, a.index), (3, Some(State::FaultReactionActive), 0x6098));
    assert_eq!(
        e.to_string(),
        "drive 3 (last statusword seen 261Fh 1 ms ago: Fault reaction active; remote, target reached, bit 13 \
         (following error / homing error)), 6098h sub 0: statusword bit 13 set: homing error"
    );
    assert_eq!(axis.node().read::<u16>(0x603F, 0).await.unwrap(), 0x8613);
    axis.enable().await.unwrap();
    assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
    assert_eq!(axis.home(&Homing::method(37)).await.unwrap(), 0);
}

/// A cyclic PDO goes out right before every SYNC, in the bus's frame order, with the latest
/// values given, and stops when its handle is dropped.
#[tokio::test(start_paused = true)]
async fn a_cyclic_pdo_precedes_every_sync_with_the_latest_values() {
    use od_master::{PdoField, PdoMapping, PdoValue};
    use od_runtime::od::DataType;
    use od_runtime::pdo::{Direction, MapEntry};
    let n = net(&[]);
    let mut seen = Link::attach(n.sim.lock().unwrap().bus());
    let field = PdoField { entry: MapEntry { index: 0x607A, sub: 0, bits: 32 }, data_type: DataType::Integer32 };
    let mapping = PdoMapping::from_fields(Direction::Receive, &[field]).unwrap();
    let pdo = n.bus.cyclic_pdo(0x204, mapping, &[PdoValue::Signed(-2)]).await.unwrap();
    n.bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut frames = Vec::new();
    let mut record = async |frames: &mut Vec<(u32, Vec<u8>)>, d: Duration| {
        let end = tokio::time::Instant::now() + d;
        while let Ok(Ok(f)) = tokio::time::timeout_at(end, seen.recv()).await {
            frames.push((f.id(), f.data().to_vec()));
        }
    };
    record(&mut frames, Duration::from_micros(2_500)).await;
    pdo.set(&[PdoValue::Signed(7)]).await.unwrap();
    record(&mut frames, Duration::from_millis(3)).await;
    drop(pdo);
    record(&mut frames, Duration::from_millis(3)).await;
    n.bus.stop_sync().await.unwrap();
    let shown: Vec<String> = frames.iter().map(|(id, d)| format!("{id:03X} {d:02X?}")).collect();
    let syncs: Vec<usize> = frames.iter().enumerate().filter(|(_, f)| f.0 == 0x080).map(|(i, _)| i).collect();
    assert!(syncs.len() >= 8, "{shown:#?}");
    let mut values = Vec::new();
    for (k, &i) in syncs.iter().enumerate() {
        let from = if k == 0 { 0 } else { syncs[k - 1] + 1 };
        let between = &frames[from..i];
        match between {
            [] => values.push(None),
            [(0x204, d)] => values.push(Some(i32::from_le_bytes(d[..4].try_into().unwrap()))),
            other => panic!("one PDO at most before a SYNC: {other:?} in {shown:#?}"),
        }
    }
    // -2 until the set, 7 after it, nothing once dropped: in that order, each at least twice.
    let mut runs: Vec<(Option<i32>, usize)> = Vec::new();
    for v in values {
        match runs.last_mut() {
            Some((last, count)) if *last == v => *count += 1,
            _ => runs.push((v, 1)),
        }
    }
    assert_eq!(runs.iter().map(|r| r.0).collect::<Vec<_>>(), [Some(-2), Some(7), None], "{shown:#?}");
    assert!(runs.iter().all(|r| r.1 >= 2), "{runs:?}");
}
