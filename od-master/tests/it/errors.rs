//! What errors say: the Display and Debug text of every kind (snapshots), the checks that make
//! an axis operation fail at once, the waits that stop as soon as the drive says they cannot
//! end well, the vendor register read into the message, a node never heard from.

use std::time::Duration;

use drive::node::DeviceKind;
use od_master::remote::{Unit, UnitError};
use od_master::{
    AbortCode, Axis, AxisError, AxisErrorKind, Error, HomingMethod, Impossible, Limit, LimitSource, Move,
    RegisterReading, SdoContext, State, StatusRegister, StopReason, TransferError,
};
use od_runtime::master::{Direction, PdoError, SdoError};
use od_sidecar::LimitSide;

use crate::harness::{net, pass, sidecar};

fn transfer(direction: Direction, index: u16, sub: u8, error: SdoError) -> TransferError {
    TransferError { node: 4, direction, index, sub, error }
}

fn axis(kind: AxisErrorKind, register: Option<RegisterReading>) -> Error {
    Error::Axis(Box::new(AxisError {
        node: 4,
        state: State::from_statusword(0x0AB7),
        statusword: Some(0x0AB7),
        seen: Some(Duration::from_millis(12)),
        index: 0x6041,
        sub: 0,
        kind,
        register,
    }))
}

/// Every kind of error, as Display and as Debug (what `main() -> Result<(), Error>` prints).
#[test]
fn every_error_displays_and_debugs_its_facts() {
    let timeout = SdoError::Client(AbortCode::TIMEOUT);
    let errors = vec![
        Error::Sdo {
            error: transfer(Direction::Upload, 0x6401, 1, SdoError::Server(AbortCode(0x0602_0000))),
            attempts: 1,
            context: None,
        },
        Error::Sdo { error: transfer(Direction::Download, 0x6083, 0, timeout), attempts: 3, context: None },
        Error::Sdo {
            error: transfer(Direction::Upload, 0x1000, 0, timeout),
            attempts: 1,
            context: Some(SdoContext::LinkDown {
                reason: "cannot connect to 127.0.0.1:29536: connection refused".into(),
                down_for: Duration::from_millis(10_250),
            }),
        },
        Error::Sdo {
            error: transfer(Direction::Upload, 0x1000, 0, timeout),
            attempts: 3,
            context: Some(SdoContext::NeverHeard),
        },
        Error::Length { node: 4, index: 0x6064, sub: 0, expected: 4, got: 2 },
        Error::TooLong { node: 4, index: 0x1F50, sub: 1, len: 5_000_000_000 },
        Error::Closed,
        Error::Transport(od_bus::TransportError::Down { reason: "the server closed the connection".into() }),
        Error::Pdo { cob_id: 0x204, error: PdoError::OutOfRange { field: 1 } },
        Error::SyncCounter(1),
        Error::NodeId(128),
        Error::Refused { node: 4, index: 0x6081, sub: 0, code: AbortCode::VALUE_TOO_HIGH },
        Error::Unit {
            node: 4,
            index: 0x607A,
            sub: 0,
            error: UnitError::WrongUnit { expected: Unit::Degree, got: Unit::Millimeter },
        },
        axis(AxisErrorKind::Sdo(Box::new(Error::Closed)), None),
        axis(AxisErrorKind::Timeout { what: "target reached".into(), timeout_ms: 30_000 }, None),
        axis(AxisErrorKind::Fault { error_code: 0x8612 }, None),
        axis(AxisErrorKind::Bit13("homing error"), None),
        axis(AxisErrorKind::Mode { wanted: 6, shown: 1 }, None),
        axis(
            AxisErrorKind::SetPoint { timeout_ms: 1000 },
            Some(RegisterReading { index: 0x2006, sub: 0, value: 0x0800, bits: vec!["Command refused".into()] }),
        ),
        axis(AxisErrorKind::Impossible(Impossible::NoHomingMethod), None),
        axis(AxisErrorKind::Impossible(Impossible::NoProfileVelocity), None),
        axis(AxisErrorKind::Impossible(Impossible::Mode { mode: 8, supported: 0x65, added: 0 }), None),
        axis(AxisErrorKind::Impossible(Impossible::Mode { mode: 9, supported: 0x65, added: 0x88 }), None),
        axis(AxisErrorKind::Impossible(Impossible::ModeNotListed { mode: 8, listed: vec![0, 1, 3, 4, 6, -1] }), None),
        axis(
            AxisErrorKind::Impossible(Impossible::IntoLimit {
                limit: Limit { side: LimitSide::Positive, by: LimitSource::Switch { inputs: 0x0000_0002 } },
                what: "a move to 120000 from 20950".into(),
            }),
            None,
        ),
        axis(
            AxisErrorKind::Impossible(Impossible::IntoLimit {
                limit: Limit { side: LimitSide::Negative, by: LimitSource::Software { value: -5000 } },
                what: "a negative velocity".into(),
            }),
            None,
        ),
        axis(
            AxisErrorKind::Stopped {
                what: "target reached".into(),
                why: StopReason::AtLimit(Limit {
                    side: LimitSide::Positive,
                    by: LimitSource::Register {
                        index: 0x2006,
                        sub: 0,
                        bit: 6,
                        text: "Positive position limit reached".into(),
                    },
                }),
            },
            None,
        ),
        axis(AxisErrorKind::Stopped { what: "target reached".into(), why: StopReason::InternalLimit }, None),
        axis(
            AxisErrorKind::Stopped { what: "set-point acknowledge".into(), why: StopReason::Warning },
            Some(RegisterReading {
                index: 0x1002,
                sub: 0,
                value: 0x8000_4100,
                bits: vec!["Warning active".into(), "Set-points not accepted".into()],
            }),
        ),
        axis(
            AxisErrorKind::Stopped {
                what: "homing attained".into(),
                why: StopReason::LeftOperationEnabled(Some(State::SwitchOnDisabled)),
            },
            None,
        ),
        axis(
            AxisErrorKind::Stopped {
                what: "target reached".into(),
                why: StopReason::Emergency { code: 0x8612, text: Some("Hardware limit switch".into()) },
            },
            None,
        ),
        Error::Axis(Box::new(AxisError {
            node: 9,
            state: None,
            statusword: None,
            seen: None,
            index: 0x6041,
            sub: 0,
            kind: AxisErrorKind::Timeout { what: "Operation enabled".into(), timeout_ms: 1000 },
            register: None,
        })),
    ];
    let mut text = String::new();
    for e in &errors {
        let (display, debug) = (e.to_string(), format!("{e:?}"));
        assert!(debug.ends_with(&display), "Debug says what Display says: {debug}");
        text.push_str(&format!("{display}\n{debug}\n\n"));
    }
    insta::assert_snapshot!(text);
}

/// A vendor register from a sidecar: the DRVI's 2006h, each bit with the manual's text.
#[test]
fn the_drvi_sidecar_names_its_warning_register() {
    let reg = drvi_register();
    assert_eq!((reg.index, reg.sub, reg.bits.len()), (0x2006, 0, 12));
    assert_eq!(reg.reading(0x0900).to_string(), "2006h = 0900h: Homing missing, Command refused");
    let akd = od_sidecar::Sidecar::read(&devices_dir().join("kollmorgen-akd.toml")).unwrap();
    let reg = StatusRegister::from_sidecar(&akd).expect("the AKD names 1002h");
    assert_eq!(reg.index, 0x1002);
    assert_eq!(reg.reading(0x8000_0800).to_string(), "1002h = 80000800h: Homing error, Set-points not accepted");
}

fn devices_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../devices")
}

fn drvi_register() -> StatusRegister {
    let sidecar = od_sidecar::Sidecar::read(&devices_dir().join("camozzi-drvi.toml")).unwrap();
    StatusRegister::from_sidecar(&sidecar).expect("the DRVI names 2006h")
}

fn impossible(e: &Error) -> &Impossible {
    match e {
        Error::Axis(a) => match &a.kind {
            AxisErrorKind::Impossible(i) => i,
            _ => panic!("{e}"),
        },
        _ => panic!("{e}"),
    }
}

/// What makes a homing or a move impossible is found before anything moves: homing method 0
/// (the AKD's default 6098h), profile velocity 0 (the DRVI's default 6081h); a mode 6502h
/// lists passes (the DRCS's profile velocity).
#[tokio::test(start_paused = true)]
async fn impossible_operations_fail_at_once_saying_why() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let start = tokio::time::Instant::now();
    let akd = Axis::new(n.bus.node(4).unwrap());
    let method = akd.node().read::<i8>(0x6098, 0).await.unwrap();
    assert_eq!(method, 0, "the AKD's default homing method");
    let e = akd.home(HomingMethod(method)).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::NoHomingMethod);
    assert!(e.to_string().contains("homing method 0 (6098h) is no homing method"), "{e}");

    let drvi = Axis::new(n.bus.node(2).unwrap());
    drvi.home(HomingMethod(37)).await.unwrap();
    assert_eq!(drvi.node().read::<u32>(0x6081, 0).await.unwrap(), 0, "the DRVI's default profile velocity");
    let e = drvi.move_to(1_000, &Move::default()).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::NoProfileVelocity);
    assert!(e.to_string().contains("profile velocity 6081h is 0"), "{e}");
    let e = drvi.move_to(1_000, &Move { velocity: Some(0), ..Move::default() }).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::NoProfileVelocity);

    // The DRCS's 6502h = 25h: profile position, profile velocity, homing.
    let drcs = Axis::new(n.bus.node(3).unwrap());
    assert_eq!(drcs.node().read::<u32>(0x6502, 0).await.unwrap(), 0x25);
    drcs.run_velocity(10, None, None).await.unwrap();
    let akd_modes = akd.node().read::<u32>(0x6502, 0).await.unwrap();
    assert_eq!(akd_modes & (1 << 7), 0, "the AKD's 6502h lists no cyclic synchronous position");
    // Nothing waited for its timeout: a few SDO round trips each.
    assert!(start.elapsed() < Duration::from_secs(2), "{:?}", start.elapsed());
}

/// A mode missing from 6502h is refused before anything is written: a drive (node 5, a
/// hand-written SDO server) whose supported drive modes are profile position alone, asked to
/// home; the only transfer is the read of 6502h.
#[tokio::test(start_paused = true)]
async fn a_mode_the_drive_does_not_list_is_refused_before_anything_is_written() {
    let n = net(&[]);
    let (tx, mut rx) = od_bus::tokio::Bus::attach(n.sim.lock().unwrap().bus()).split();
    let requests = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let seen = std::sync::Arc::clone(&requests);
    tokio::spawn(async move {
        while let Ok(f) = rx.recv().await {
            if f.id() != 0x605 || f.dlc() != 8 {
                continue;
            }
            let d = f.data();
            seen.lock().unwrap().push(d.to_vec());
            let answer = if d[..4] == [0x40, 0x02, 0x65, 0x00] {
                [0x43, 0x02, 0x65, 0x00, 0x01, 0, 0, 0]
            } else {
                [0x80, d[1], d[2], d[3], 0x00, 0x00, 0x02, 0x06]
            };
            let _ = tx.send(od_bus::CanFrame::standard(0x585, &answer).unwrap()).await;
        }
    });
    let drive = Axis::new(n.bus.node(5).unwrap());
    let e = drive.home(HomingMethod(37)).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::Mode { mode: 6, supported: 1, added: 0 });
    assert!(
        e.to_string().ends_with(
            "6502h sub 0: the drive does not support mode 6 (homing): its supported drive modes 6502h = 00000001h \
             (profile position)"
        ),
        "{e}"
    );
    assert_eq!(requests.lock().unwrap().len(), 1, "only 6502h was read");
}

/// A set-point the DRVI refuses during a movement (6.4: the target cannot change while it
/// moves): statusword bit 7 goes up and the wait stops at once, with 2006h "Command refused"
/// in the message, not after its timeout as "not acknowledged".
#[tokio::test(start_paused = true)]
async fn a_refused_set_point_stops_the_wait_with_the_vendor_register() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let drvi = Axis::new(n.bus.node(2).unwrap()).with_register(drvi_register());
    drvi.home(HomingMethod(37)).await.unwrap();
    let m = Move { velocity: Some(6_000), acceleration: Some(6_000), deceleration: Some(6_000), ..Move::default() };
    drvi.set_point(36_000, &m).await.unwrap();
    pass(Duration::from_millis(200)).await;
    let start = tokio::time::Instant::now();
    let e = drvi.set_point(0, &m).await.unwrap_err();
    assert!(start.elapsed() < Duration::from_millis(200), "{:?}: {e}", start.elapsed());
    let Error::Axis(a) = &e else { panic!("{e}") };
    assert!(matches!(a.kind, AxisErrorKind::Stopped { why: StopReason::Warning, .. }), "{e}");
    let reg = a.register.as_ref().expect("2006h read");
    assert_eq!((reg.index, reg.value & 0x0800), (0x2006, 0x0800), "{e}");
    assert!(e.to_string().contains("statusword bit 7 (warning) went up"), "{e}");
    assert!(e.to_string().contains("Command refused"), "{e}");
}

/// A move into the AKD's positive limit switch (+2 turns): statusword bit 11 goes up and the
/// wait for the target ends at once, naming it.
#[tokio::test(start_paused = true)]
async fn a_move_into_a_limit_switch_stops_the_wait_at_once() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let akd = Axis::new(n.bus.node(4).unwrap());
    akd.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    akd.home(HomingMethod(35)).await.unwrap();
    let m =
        Move { velocity: Some(40_000), acceleration: Some(400_000), deceleration: Some(400_000), ..Move::default() };
    let start = tokio::time::Instant::now();
    let e = akd.move_to(100_000, &m).await.unwrap_err();
    // 2 turns at 4 turns/s: half a second, then at once.
    assert!(start.elapsed() < Duration::from_millis(1_500), "{:?}", start.elapsed());
    let Error::Axis(a) = &e else { panic!("{e}") };
    assert!(matches!(&a.kind, AxisErrorKind::Stopped { why: StopReason::AtLimit(_), .. }), "{e}");
    assert!(e.to_string().contains("internal limit active"), "{e}");
}

/// A node that never answered and was never heard: the error suggests it is not on the bus.
#[tokio::test(start_paused = true)]
async fn a_read_from_a_node_never_heard_from_says_it_may_not_be_on_the_bus() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let ghost = n.bus.node(9).unwrap().with_timeout(Duration::from_millis(50));
    let e = ghost.read::<u32>(0x1000, 0).await.unwrap_err();
    assert!(matches!(&e, Error::Sdo { context: Some(SdoContext::NeverHeard), attempts: 3, .. }), "{e:?}");
    assert_eq!(
        e.to_string(),
        "node 9, upload of 1000h sub 0: aborted by the client: 0x05040000 (SDO protocol timed out) (after 3 attempts); \
         nothing has been received from node 9 since the bus was opened: is it on this bus (its node id, bit rate, \
         power and wiring)?"
    );
}

/// A generated `Units` says what it is in one line: its system and what one raw unit is in each
/// dimension (its Debug was the prepared divisors, 2 000 characters).
#[tokio::test(start_paused = true)]
async fn generated_units_display_their_system_and_factors() {
    use crate::client::{akd, drvi};
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let units = drvi::remote::Remote::new(n.bus.node(2).unwrap()).units().await.unwrap();
    assert_eq!(
        units.to_string(),
        "only-motor: 1 raw = 1/100 deg (Position), 1/100 rpm (Velocity), 1 rpm/s (Acceleration), 1 mA (Torque), \
         1 mA/s (TorqueSlope), 1 ms (Time)"
    );
    assert_eq!(format!("{units:?}"), format!("Units({units})"));
    let units = akd::remote::Remote::new(n.bus.node(4).unwrap()).units().await.unwrap();
    assert!(format!("{units:?}").len() < 200, "{units:?}");
}

/// On the AKD's positive limit switch (+2 turns), where the drive stopped a move (statusword
/// bit 11 and 60FDh bit 1 standing): a move further positive, and a positive velocity, are
/// refused at once naming the switch; a move negative is taken, leaves the switch and reaches
/// its target.
#[tokio::test(start_paused = true)]
async fn on_a_limit_switch_a_move_further_in_is_refused_and_one_out_succeeds() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let akd = Axis::new(n.bus.node(4).unwrap()).with_sidecar(&sidecar("kollmorgen-akd"));
    akd.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    akd.home(HomingMethod(35)).await.unwrap();
    let m =
        Move { velocity: Some(40_000), acceleration: Some(400_000), deceleration: Some(400_000), ..Move::default() };
    let e = akd.move_to(100_000, &m).await.unwrap_err();
    let Error::Axis(a) = &e else { panic!("{e}") };
    assert!(
        matches!(&a.kind, AxisErrorKind::Stopped { why: StopReason::AtLimit(l), .. }
            if l.side == LimitSide::Positive && matches!(l.by, LimitSource::Switch { .. })),
        "{e}"
    );
    assert!(e.to_string().contains("limited by its positive limit switch (digital inputs 60FDh"), "{e}");
    let sw = akd.statusword().await.unwrap();
    assert_ne!(sw & (1 << 11), 0, "standing on the switch: {sw:04X}h");
    assert_eq!(akd.node().read::<u32>(0x60FD, 0).await.unwrap() & 3, 2, "60FDh: the positive switch");
    let here = akd.position().await.unwrap();

    // Further in: refused before anything is written, naming the switch.
    let start = tokio::time::Instant::now();
    let e = akd.move_to(120_000, &m).await.unwrap_err();
    assert!(start.elapsed() < Duration::from_secs(1), "{:?}", start.elapsed());
    assert!(
        matches!(impossible(&e), Impossible::IntoLimit { limit, .. }
            if limit.side == LimitSide::Positive && matches!(limit.by, LimitSource::Switch { inputs } if inputs & 3 == 2)),
        "{e}"
    );
    assert!(
        e.to_string().contains(": bit 1 set) and a move to 120000 from 20")
            && e.to_string().contains("goes further into it; a move the other way is allowed"),
        "{e}"
    );
    let e = akd.move_to(10_000, &Move { relative: true, ..m }).await.unwrap_err();
    assert!(matches!(impossible(&e), Impossible::IntoLimit { .. }), "{e}");
    let e = akd.run_velocity(1_000, None, None).await.unwrap_err();
    assert!(e.to_string().contains("a positive velocity goes further into it"), "{e}");
    assert!(start.elapsed() < Duration::from_secs(1), "{:?}", start.elapsed());
    let now = akd.position().await.unwrap();
    // (The axis settles by a few hundred counts after the quick stop on the switch.)
    assert!((now - here).abs() < 1_000, "not moved towards 120000: {here} then {now}");

    // Out: the standing warning (the switch's, bit 7) and bit 11 do not stop it.
    let start = tokio::time::Instant::now();
    assert_eq!(akd.move_to(0, &m).await.unwrap(), 0);
    assert!(start.elapsed() < Duration::from_secs(2), "{:?}", start.elapsed());
    let sw = akd.statusword().await.unwrap();
    assert_eq!(sw & (1 << 11 | 1 << 7), 0, "off the switch: {sw:04X}h");
}

/// Modes against 6502h (supported drive modes), with what the sidecar says: the DRVI, which
/// has no 6502h, is refused cyclic synchronous position by its sidecar's `[[mode]]` list, at
/// once; the AKD's 6502h (65h) leaves the mode out, so it is refused without the sidecar and
/// runs with it (`not_in_6502h`), as does profile torque.
#[tokio::test(start_paused = true)]
async fn modes_are_checked_against_6502h_and_the_sidecar() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let drvi = Axis::new(n.bus.node(2).unwrap()).with_sidecar(&sidecar("camozzi-drvi"));
    let rpdo1 = drvi.node().read::<u32>(0x1400, 1).await.unwrap();
    let start = tokio::time::Instant::now();
    let e = drvi.cyclic_position(1, 0x202).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::ModeNotListed { mode: 8, listed: vec![0, 1, 3, 4, 6, -1] });
    assert!(
        e.to_string().ends_with(
            "6060h sub 0: the drive does not support mode 8 (cyclic synchronous position): it has no 6502h \
             (supported drive modes) and its sidecar lists the modes 0 (no mode), 1 (profile position), 3 (profile \
             velocity), 4 (profile torque), 6 (homing), -1 (manufacturer-specific)"
        ),
        "{e}"
    );
    let e = drvi.set_mode(8).await.unwrap_err();
    assert!(matches!(impossible(&e), Impossible::ModeNotListed { mode: 8, .. }), "{e}");
    // An axis that has not read 6502h yet writes 6060h; the drive refuses it, and the error
    // names the supported modes, not only the abort.
    let fresh = Axis::new(n.bus.node(2).unwrap()).with_sidecar(&sidecar("camozzi-drvi"));
    let e = fresh.set_mode(8).await.unwrap_err();
    assert!(matches!(impossible(&e), Impossible::ModeNotListed { mode: 8, .. }), "{e}");
    assert!(start.elapsed() < Duration::from_millis(100), "{:?}", start.elapsed());
    assert_eq!(drvi.node().read::<u32>(0x1400, 1).await.unwrap(), rpdo1, "RPDO1 untouched");

    let start = tokio::time::Instant::now();
    let bare = Axis::new(n.bus.node(4).unwrap());
    let e = bare.cyclic_position(4, 0x504).await.unwrap_err();
    assert_eq!(impossible(&e), &Impossible::Mode { mode: 8, supported: 0x65, added: 0 });
    assert!(e.to_string().contains("supported drive modes 6502h = 00000065h"), "{e}");
    assert!(start.elapsed() < Duration::from_millis(200), "{:?}", start.elapsed());

    let akd = Axis::new(n.bus.node(4).unwrap()).with_sidecar(&sidecar("kollmorgen-akd"));
    akd.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    akd.home(HomingMethod(35)).await.unwrap();
    n.bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut csp = akd.cyclic_position(4, 0x504).await.unwrap();
    let here = akd.position().await.unwrap();
    for k in 1..=20 {
        csp.send(here + 10 * k).await.unwrap();
    }
    drop(csp);
    akd.set_mode(4).await.unwrap();
    let e = akd.set_mode(9).await.unwrap_err();
    assert!(
        e.to_string().ends_with(
            "the drive does not support mode 9 (cyclic synchronous velocity): its supported drive modes 6502h = \
             00000065h (profile position, profile velocity, homing, interpolated position), with profile torque, \
             cyclic synchronous position taken from its sidecar (not_in_6502h)"
        ),
        "{e}"
    );
}

/// The AKD's software position limits (607Dh, in force after save and restart, 6.11): a
/// target beyond the positive one is clipped by the drive (statusword bit 11, warning n107), so
/// the wait for it ends at once naming 607Dh sub 2; at the limit, a move further out is refused
/// before anything is written, and a move back in is taken and succeeds.
#[tokio::test(start_paused = true)]
async fn a_target_beyond_a_software_limit_ends_at_once_naming_607dh() {
    let n = net(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let akd = Axis::new(n.bus.node(4).unwrap()).with_sidecar(&sidecar("kollmorgen-akd"));
    let node = akd.node().clone();
    node.write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    node.write_idempotent(0x607D, 1, -5_000i32).await.unwrap();
    node.write_idempotent(0x607D, 2, 5_000i32).await.unwrap();
    node.write(0x1010, 1, u32::from_le_bytes(*b"save")).await.unwrap();
    node.reset().await.unwrap();
    pass(Duration::from_millis(50)).await;
    assert_eq!(node.read::<i32>(0x607D, 2).await.unwrap(), 5_000, "kept over the restart");
    akd.home(HomingMethod(35)).await.unwrap();
    let m =
        Move { velocity: Some(40_000), acceleration: Some(400_000), deceleration: Some(400_000), ..Move::default() };
    let start = tokio::time::Instant::now();
    let e = akd.move_to(9_000, &m).await.unwrap_err();
    assert!(start.elapsed() < Duration::from_millis(200), "{:?}: {e}", start.elapsed());
    let Error::Axis(a) = &e else { panic!("{e}") };
    assert!(
        matches!(&a.kind, AxisErrorKind::Stopped { why: StopReason::AtLimit(l), .. }
            if l.side == LimitSide::Positive && l.by == LimitSource::Software { value: 5_000 }),
        "{e}"
    );
    assert!(e.to_string().contains("positive software position limit (607Dh sub 2 = 5000)"), "{e}");
    // The drive goes on to its limit, where it stands with bit 11.
    pass(Duration::from_millis(500)).await;
    assert_eq!(akd.position().await.unwrap(), 5_000);
    assert_ne!(akd.statusword().await.unwrap() & (1 << 11), 0);
    let e = akd.move_to(6_000, &m).await.unwrap_err();
    assert!(
        matches!(impossible(&e), Impossible::IntoLimit { limit, .. } if limit.by == LimitSource::Software { value: 5_000 }),
        "{e}"
    );
    assert_eq!(akd.move_to(-4_000, &m).await.unwrap(), -4_000);
}
