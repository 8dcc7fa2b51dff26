//! The supervisor (`od_master::supervisor`) against the simulated drives of
//! networks/example.toml on the in-memory bus, in virtual time, with faults injected in the
//! drives (`drive::node::Faulty`): power cycles, silenced heartbeats, a wrong device.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive::node::{DeviceKind, Fault, FaultHandle, Faulty, Sim};
use od_bus::Endpoint;
use od_master::supervisor::policy::Action;
use od_master::supervisor::{Summary, Supervisor, SupervisorEvent};
use od_master::{Bus, Config, Error, Network, NmtState};
use tokio::sync::{broadcast, oneshot};
use tokio::task::JoinHandle;

use crate::harness::{STEP, node, pass};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

const EXAMPLE: [(DeviceKind, u8); 3] = [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)];

/// The example network with `extra` TOML appended (supervision tables).
fn example_with(extra: &str) -> Network {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap() + extra;
    Network::from_description_text("networks/example.toml", &repo().join("networks"), &text)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Simulated nodes, each behind a fault injector, with a master on their bus.
struct Rig {
    bus: Bus,
    sim: Arc<Mutex<Sim>>,
    faults: Vec<FaultHandle>,
}

fn rig(nodes: &[(DeviceKind, u8)]) -> Rig {
    let mut sim = Sim::new();
    let mut faults = Vec::new();
    for &(kind, id) in nodes {
        let (faulty, handle) = Faulty::new(node(kind, id));
        sim.add(Box::new(faulty));
        faults.push(handle);
    }
    let (bus, sim) = drive::node::spawn_with_master(sim, Config::default(), STEP);
    Rig { bus, sim, faults }
}

impl Rig {
    fn nmt_state(&self, position: usize) -> NmtState {
        self.sim.lock().unwrap().node(position).nmt_state()
    }
}

/// A supervisor running on its own task, stopped by `stop`.
struct Running {
    events: broadcast::Receiver<SupervisorEvent>,
    stop: oneshot::Sender<()>,
    task: JoinHandle<Summary>,
}

fn supervise(bus: &Bus, network: Network) -> Running {
    let supervisor = Supervisor::new(bus.clone(), network);
    let events = supervisor.events();
    let (stop, stopped) = oneshot::channel::<()>();
    let task = tokio::spawn(supervisor.run(async move {
        let _ = stopped.await;
    }));
    Running { events, stop, task }
}

impl Running {
    /// The next event `want` accepts, within `within` of virtual time; the others seen on the
    /// way are returned too.
    async fn expect(
        &mut self,
        within: Duration,
        want: impl Fn(&SupervisorEvent) -> bool,
    ) -> (SupervisorEvent, Vec<SupervisorEvent>) {
        let mut seen = Vec::new();
        let deadline = tokio::time::Instant::now() + within;
        loop {
            match tokio::time::timeout_at(deadline, self.events.recv()).await {
                Ok(Ok(e)) if want(&e) => return (e, seen),
                Ok(Ok(e)) => seen.push(e),
                Ok(Err(e)) => panic!("events: {e}; seen {seen:#?}"),
                Err(_) => panic!("no such event within {within:?}; seen {seen:#?}"),
            }
        }
    }

    /// Every event of the next `d` of virtual time.
    async fn during(&mut self, d: Duration) -> Vec<SupervisorEvent> {
        pass(d).await;
        let mut seen = Vec::new();
        while let Ok(e) = self.events.try_recv() {
            seen.push(e);
        }
        seen
    }

    async fn stop(self) -> Summary {
        let _ = self.stop.send(());
        self.task.await.unwrap()
    }
}

fn booted(n: u8) -> impl Fn(&SupervisorEvent) -> bool {
    move |e| matches!(e, SupervisorEvent::Booted { node, .. } if *node == n)
}

async fn boot_all(r: &mut Running) {
    for n in [2, 3, 4] {
        r.expect(Duration::from_secs(2), booted(n)).await;
    }
}

#[tokio::test(start_paused = true)]
async fn a_power_cycled_drive_is_configured_again_and_the_others_miss_no_sync() {
    let rig = rig(&EXAMPLE);
    pass(Duration::from_millis(10)).await;
    let network = example_with("");
    let mut r = supervise(&rig.bus, network.clone());
    boot_all(&mut r).await;
    for n in &network.nodes {
        od_master::supervisor::verify(&rig.bus, n).await.unwrap_or_else(|e| panic!("{}: {e}", n.name));
    }
    rig.bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    pass(Duration::from_millis(20)).await;
    let mut frames = rig.bus.frames();
    let syncs_before = *rig.bus.syncs().borrow();

    rig.faults[1].inject(Fault::PowerCycle { off: 5_000 });
    let (rebooted, _) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Rebooted { .. })).await;
    assert_eq!(rebooted, SupervisorEvent::Rebooted { node: 3, name: "y_axis".into() });
    let (done, between) = r.expect(Duration::from_secs(2), |e| matches!(e, SupervisorEvent::Reconfigured { .. })).await;
    assert!(between.is_empty(), "{between:#?}");
    let SupervisorEvent::Reconfigured { node: 3, writes, elapsed, started, .. } = done else { panic!("{done:?}") };
    assert!(started.is_some_and(|s| s <= elapsed), "{started:?} {elapsed:?}");
    assert_eq!(writes, network.nodes[1].plan.writes.len());
    assert!(elapsed < Duration::from_millis(400), "{elapsed:?}");
    assert_eq!(rig.nmt_state(1), NmtState::Operational);
    // Mappings, heartbeat time and parameters read back as at the first boot.
    for n in &network.nodes {
        od_master::supervisor::verify(&rig.bus, n).await.unwrap_or_else(|e| panic!("{}: {e}", n.name));
    }
    pass(Duration::from_millis(20)).await;
    let syncs = *rig.bus.syncs().borrow() - syncs_before;
    // x_axis and z_axis send TPDO 2 after every SYNC (transmission type 1): none missed.
    let (mut x, mut z) = (0u64, 0u64);
    while let Ok(f) = frames.try_recv() {
        match f.id() {
            0x282 => x += 1,
            0x284 => z += 1,
            _ => {}
        }
    }
    assert!(syncs > 100, "{syncs} SYNCs");
    for (name, seen) in [("x_axis", x), ("z_axis", z)] {
        assert!(seen + 1 >= syncs && seen <= syncs, "{name}: {seen} TPDOs for {syncs} SYNCs");
    }
    let others = r.during(Duration::from_millis(10)).await;
    assert!(others.is_empty(), "{others:#?}");
    let summary = r.stop().await;
    assert_eq!((summary.reboots, summary.reconfigured, summary.boot_failures), (1, 1, 0));
}

#[tokio::test(start_paused = true)]
async fn an_sdo_transfer_to_a_node_that_reboots_ends_at_once() {
    let rig = rig(&[]);
    let mut device = rig.sim.lock().unwrap().endpoint();
    // The node is on the bus (a heartbeat): a boot-up from it now is a reboot.
    device.send("705#7F".parse().unwrap()).unwrap();
    pass(Duration::from_millis(1)).await;
    // A plain write, and a read with no retries left: each ends at once, saying why.
    let node = rig.bus.node(5).unwrap().with_retries(0);
    for (request, index, sub) in [("605#2B17100064000000", 0x1017, 0), ("605#4018100100000000", 0x1018, 1)] {
        let n = node.clone();
        let transfer = tokio::spawn(async move {
            if index == 0x1017 {
                n.write::<u16>(0x1017, 0, 100).await
            } else {
                n.read::<u32>(0x1018, 1).await.map(drop)
            }
        });
        pass(Duration::from_millis(5)).await;
        assert_eq!(device.try_recv().unwrap().unwrap().to_string(), request);
        let started = tokio::time::Instant::now();
        device.send("705#00".parse().unwrap()).unwrap();
        let result = transfer.await.unwrap();
        assert!(started.elapsed() < Duration::from_millis(5), "{:?}", started.elapsed());
        match result {
            Err(e @ Error::Rebooted { node: 5, .. }) => assert_eq!(
                e.to_string(),
                format!("node 5, {index:04X}h sub {sub}: the node rebooted (boot-up message) during the transfer")
            ),
            other => panic!("{other:?}"),
        }
        while let Ok(Some(_)) = device.try_recv() {}
    }
    // A read with retries left starts again at once on the rebooted node, and its answer ends it.
    let node = rig.bus.node(5).unwrap();
    let read = tokio::spawn(async move { node.read::<u32>(0x1018, 1).await });
    pass(Duration::from_millis(5)).await;
    assert_eq!(device.try_recv().unwrap().unwrap().to_string(), "605#4018100100000000");
    device.send("705#00".parse().unwrap()).unwrap();
    pass(Duration::from_millis(1)).await;
    // The abort of the forgotten transfer (which the rebooted server ignores), then the request.
    assert_eq!(device.try_recv().unwrap().unwrap().to_string(), "605#8018100100000008");
    assert_eq!(device.try_recv().unwrap().unwrap().to_string(), "605#4018100100000000");
    device.send("585#4318100197000000".parse().unwrap()).unwrap();
    assert_eq!(read.await.unwrap().unwrap(), 0x97);
}

/// x_axis mandatory with `policy` as the network's answer to its failure; a DRCS at node 2.
async fn wrong_device(policy: &str) -> (Rig, Running, SupervisorEvent) {
    let rig = rig(&[(DeviceKind::Drcs, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(10)).await;
    let network = example_with(&format!(
        "\n[network.supervision]\non_mandatory_failure = \"{policy}\"\nboot_attempts = 3\n\
         [nodes.x_axis.supervision]\nmandatory = true\n"
    ));
    let mut r = supervise(&rig.bus, network);
    let (failed, _) = r.expect(Duration::from_secs(2), |e| matches!(e, SupervisorEvent::BootFailed { .. })).await;
    (rig, r, failed)
}

fn check_identity_failure(failed: &SupervisorEvent) {
    let SupervisorEvent::BootFailed { node: 2, name, object, reason, message, .. } = failed else {
        panic!("{failed:?}")
    };
    assert_eq!(name, "x_axis");
    // The device types differ (FF7Ch in the DRCS's upper half, FF7Ah in the DRVI's).
    assert_eq!((*object, *reason), (Some((0x1000, 0)), Some('C')), "{message}");
    assert_eq!(
        message,
        "node 2 (x_axis): wrong device: 1000h:0 device type is 0xFF7C0192, devices/camozzi-drvi.eds expects 0xFF7A0192"
    );
}

#[tokio::test(start_paused = true)]
async fn a_wrong_mandatory_device_is_reported_and_left_pre_operational() {
    let (rig, mut r, failed) = wrong_device("report").await;
    check_identity_failure(&failed);
    let (end, _) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::MandatoryFailed { .. })).await;
    assert_eq!(end, SupervisorEvent::MandatoryFailed { node: 2, name: "x_axis".into() });
    let later = r.during(Duration::from_millis(500)).await;
    assert!(!later.iter().any(|e| matches!(e, SupervisorEvent::Acted { .. })), "{later:#?}");
    assert_eq!(rig.nmt_state(0), NmtState::PreOperational);
    assert_eq!(rig.nmt_state(1), NmtState::Operational);
    assert_eq!(rig.nmt_state(2), NmtState::Operational);
    assert_eq!(r.stop().await.mandatory_failed, ["x_axis"]);
}

#[tokio::test(start_paused = true)]
async fn a_wrong_mandatory_device_is_reset_a_bounded_number_of_times() {
    let (rig, mut r, failed) = wrong_device("reset_node").await;
    check_identity_failure(&failed);
    let (_, seen) = r.expect(Duration::from_secs(5), |e| matches!(e, SupervisorEvent::MandatoryFailed { .. })).await;
    let acted: Vec<Action> = seen
        .iter()
        .filter_map(|e| if let SupervisorEvent::Acted { action, .. } = e { Some(*action) } else { None })
        .collect();
    assert_eq!(acted, [Action::ResetNode, Action::ResetNode, Action::GiveUp], "{seen:#?}");
    let reboots = seen.iter().filter(|e| matches!(e, SupervisorEvent::Rebooted { node: 2, .. })).count();
    assert_eq!(reboots, 2);
    // Nothing more: no loop.
    let later = r.during(Duration::from_secs(2)).await;
    assert!(later.is_empty(), "{later:#?}");
    assert_eq!(rig.nmt_state(0), NmtState::PreOperational);
    assert_eq!(rig.nmt_state(1), NmtState::Operational);
    r.stop().await;
}

#[tokio::test(start_paused = true)]
async fn a_wrong_mandatory_device_stops_all_nodes() {
    let (rig, mut r, failed) = wrong_device("stop_all").await;
    check_identity_failure(&failed);
    let (_, seen) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::MandatoryFailed { .. })).await;
    assert!(
        seen.iter().any(|e| matches!(e, SupervisorEvent::Acted { node: 2, action: Action::StopAll, .. })),
        "{seen:#?}"
    );
    pass(Duration::from_millis(10)).await;
    for i in 0..3 {
        assert_eq!(rig.nmt_state(i), NmtState::Stopped, "node at {i}");
    }
    r.stop().await;
}

#[tokio::test(start_paused = true)]
async fn a_wrong_mandatory_device_resets_all_nodes_a_bounded_number_of_times() {
    let (rig, mut r, failed) = wrong_device("reset_all").await;
    check_identity_failure(&failed);
    let (_, seen) = r.expect(Duration::from_secs(5), |e| matches!(e, SupervisorEvent::MandatoryFailed { .. })).await;
    let mut seen = seen;
    seen.extend(r.during(Duration::from_secs(2)).await);
    let resets = seen.iter().filter(|e| matches!(e, SupervisorEvent::Acted { action: Action::ResetAll, .. })).count();
    assert_eq!(resets, 2, "{seen:#?}");
    // Every reset rebooted the others too (a boot cut short by the next reset is started
    // over), and they were configured again after the last.
    for n in [3, 4] {
        let reboots = seen.iter().filter(|e| matches!(e, SupervisorEvent::Rebooted { node, .. } if *node == n)).count();
        assert_eq!(reboots, 2, "node {n}: {seen:#?}");
        let last = seen.iter().rposition(|e| matches!(e, SupervisorEvent::Rebooted { node, .. } if *node == n));
        let configured =
            seen.iter().rposition(|e| matches!(e, SupervisorEvent::Reconfigured { node, .. } if *node == n));
        assert!(configured > last, "node {n}: {seen:#?}");
    }
    assert_eq!(rig.nmt_state(1), NmtState::Operational);
    let later = r.during(Duration::from_secs(2)).await;
    assert!(later.is_empty(), "{later:#?}");
    assert_eq!(rig.nmt_state(0), NmtState::PreOperational);
    assert_eq!(rig.nmt_state(2), NmtState::Operational);
    r.stop().await;
}

const RESET_Y_WHEN_LOST: &str = "\n[nodes.y_axis.supervision]\non_lost = \"reset_node\"\nreset_delay_ms = 500\n";

#[tokio::test(start_paused = true)]
async fn a_silenced_heartbeat_is_lost_then_the_node_reset_and_configured_again() {
    let rig = rig(&EXAMPLE);
    pass(Duration::from_millis(10)).await;
    let mut r = supervise(&rig.bus, example_with(RESET_Y_WHEN_LOST));
    boot_all(&mut r).await;
    rig.faults[1].inject(Fault::Silence { duration: 2_000_000 });
    let (lost, _) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Lost { .. })).await;
    assert_eq!(lost, SupervisorEvent::Lost { node: 3, name: "y_axis".into() });
    let (acted, _) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Acted { .. })).await;
    assert!(matches!(acted, SupervisorEvent::Acted { node: 3, action: Action::ResetNode, .. }), "{acted:?}");
    // Its boot-up is silenced too: it is booted anyway a second after the reset, again until
    // its heartbeat gets through.
    let (done, _) =
        r.expect(Duration::from_secs(4), |e| matches!(e, SupervisorEvent::Reconfigured { node: 3, .. })).await;
    assert!(matches!(done, SupervisorEvent::Reconfigured { writes: 28, .. }), "{done:?}");
    assert_eq!(rig.nmt_state(1), NmtState::Operational);
    // Then quiet (its heartbeat, back, may still be reported as recovered: the same frame
    // confirms the boot and ends the loss).
    let later = r.during(Duration::from_secs(1)).await;
    assert!(later.iter().all(|e| matches!(e, SupervisorEvent::Recovered { node: 3, .. })), "{later:#?}");
    r.stop().await;
}

#[tokio::test(start_paused = true)]
async fn a_heartbeat_back_before_the_reset_is_recovered() {
    let rig = rig(&EXAMPLE);
    pass(Duration::from_millis(10)).await;
    let mut r = supervise(&rig.bus, example_with(RESET_Y_WHEN_LOST));
    boot_all(&mut r).await;
    rig.faults[1].inject(Fault::Silence { duration: 400_000 });
    r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Lost { node: 3, .. })).await;
    let (back, _) = r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Recovered { .. })).await;
    assert_eq!(back, SupervisorEvent::Recovered { node: 3, name: "y_axis".into(), state: NmtState::Operational });
    let later = r.during(Duration::from_secs(1)).await;
    assert!(later.is_empty(), "{later:#?}");
    let summary = r.stop().await;
    assert_eq!((summary.lost, summary.reboots), (1, 0));
}

#[test]
fn supervision_keys_are_read_and_checked() {
    let n = example_with(
        "\n[network.supervision]\non_mandatory_failure = \"stop_all\"\n[nodes.z_axis.supervision]\n\
         mandatory = true\nkeep_alive = true\nstart = false\non_lost = \"reset_all\"\nheartbeat_timeout_ms = 300\n",
    );
    assert_eq!(n.supervision.on_mandatory_failure, od_master::supervisor::policy::FailureAction::StopAll);
    let z = &n.nodes[2].supervision;
    assert!(z.mandatory && z.keep_alive && !z.start && z.configure);
    assert_eq!(z.heartbeat_timeout_ms, Some(300));
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap()
        + "\n[nodes.y_axis.supervision]\non_lost = \"reset_everything\"\nmandatry = true\n\
           [nodes.x_axis.supervision]\non_lost = \"stop_all\"\n";
    let e = Network::from_description_text("networks/example.toml", &repo().join("networks"), &text).unwrap_err();
    let e = e.to_string();
    assert!(e.contains("`on_lost` is `reset_everything`, not an action"), "{e}");
    assert!(e.contains("did you mean `mandatory`?"), "{e}");
    assert!(e.contains("acts on every node, which only a mandatory node may"), "{e}");
}

// The CiA 402 side: operations that end at once, explicit recovery, the opt-in policy.

use od_master::axis::{AxisReport, RecoveryPolicy, Trouble, mode};
use od_master::{Axis, AxisErrorKind, Homing, Interruption, Move, State};

/// The kind of an axis error, looking through an SDO error that ended because of a reboot.
fn interrupted_by_reboot(e: &Error) -> bool {
    match e {
        Error::Axis(a) => match &a.kind {
            AxisErrorKind::Interrupted(Interruption::Rebooted) => true,
            AxisErrorKind::Sdo(inner) => matches!(**inner, Error::Rebooted { .. }),
            _ => false,
        },
        Error::Rebooted { .. } => true,
        _ => false,
    }
}

#[tokio::test(start_paused = true)]
async fn a_move_on_a_drive_that_reboots_ends_at_once_and_the_drive_stays_still() {
    let rig = rig(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(rig.bus.node(2).unwrap());
    axis.home(&Homing::method(37)).await.unwrap();
    // A long, slow move: 100 turns at 60 rpm.
    let m = Move { velocity: Some(6_000), acceleration: Some(6_000), deceleration: Some(6_000), ..Move::default() };
    let mover = tokio::spawn(async move {
        let result = axis.move_to(3_600_000, &m).await;
        (axis, result)
    });
    pass(Duration::from_millis(300)).await;
    let cut = tokio::time::Instant::now();
    rig.faults[0].inject(Fault::PowerCycle { off: 2_000 });
    let (axis, result) = mover.await.unwrap();
    assert!(cut.elapsed() < Duration::from_millis(50), "ended {:?} after the power cycle", cut.elapsed());
    let e = result.unwrap_err();
    assert!(interrupted_by_reboot(&e), "{e}");
    assert!(e.to_string().starts_with("drive 2 ("), "{e}");
    // It does not move by itself (once a free motor has coasted to a stop: its power stage
    // went off with the power cycle).
    pass(Duration::from_secs(2)).await;
    let here = axis.position().await.unwrap();
    pass(Duration::from_millis(300)).await;
    assert_eq!(axis.position().await.unwrap(), here);
    assert_eq!(axis.state().await.unwrap(), Some(State::SwitchOnDisabled));
    // Until recovered: then, homed again (the reboot lost its reference), it moves again.
    axis.recover(mode::PROFILE_POSITION).await.unwrap();
    assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
    let home = axis.home(&Homing::method(37)).await.unwrap();
    let m = Move { velocity: Some(6_000), acceleration: Some(6_000), deceleration: Some(6_000), ..Move::default() };
    let at = axis.move_to(home + 9_000, &m).await.unwrap();
    assert_eq!(at, home + 9_000);
}

#[tokio::test(start_paused = true)]
async fn recover_resets_a_fault_on_a_rising_edge_and_enables() {
    let rig = rig(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(rig.bus.node(2).unwrap());
    axis.enable().await.unwrap();
    rig.faults[0].inject(Fault::Fault { code: 0x5530, sticky: false });
    pass(Duration::from_millis(50)).await;
    assert_eq!(axis.state().await.unwrap(), Some(State::Fault));
    let mut wire = rig.sim.lock().unwrap().endpoint();
    axis.recover(mode::PROFILE_POSITION).await.unwrap();
    assert_eq!(axis.state().await.unwrap(), Some(State::OperationEnabled));
    // The controlword writes of the reset: bit 7 low, then high.
    let mut controlwords = Vec::new();
    while let Ok(Some(f)) = wire.try_recv() {
        if f.id() == 0x602 && f.data()[..4] == [0x2B, 0x40, 0x60, 0x00] {
            controlwords.push(u16::from_le_bytes([f.data()[4], f.data()[5]]));
        }
    }
    let edge = controlwords.windows(2).position(|w| w == [0x0000, 0x0080]);
    assert!(edge.is_some(), "{controlwords:04X?}");
}

#[tokio::test(start_paused = true)]
async fn a_fault_that_stays_is_reset_a_bounded_number_of_times_then_reported() {
    let rig = rig(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let axis = Arc::new(Axis::new(rig.bus.node(2).unwrap()));
    axis.enable().await.unwrap();
    let policy = RecoveryPolicy::FaultReset { attempts: 3, backoff: Duration::from_millis(10) };
    let mut reports = Arc::clone(&axis).keep(policy, mode::PROFILE_POSITION);
    rig.faults[0].inject(Fault::Fault { code: 0x5530, sticky: true });
    let mut seen = Vec::new();
    loop {
        let report = tokio::time::timeout(Duration::from_secs(20), reports.recv()).await.expect("a report").unwrap();
        let end = matches!(report, AxisReport::GaveUp { .. });
        seen.push(report);
        if end {
            break;
        }
    }
    let failed = seen.iter().filter(|r| matches!(r, AxisReport::AttemptFailed { trouble: Trouble::Fault, .. })).count();
    assert_eq!(failed, 3, "{seen:#?}");
    assert!(matches!(seen.last(), Some(AxisReport::GaveUp { trouble: Trouble::Fault, attempts: 3 })), "{seen:#?}");
    // Never loops: nothing more.
    assert!(tokio::time::timeout(Duration::from_secs(2), reports.recv()).await.is_err());
    assert_eq!(axis.state().await.unwrap(), Some(State::Fault));
    // The cause gone, the application recovers it.
    rig.faults[0].inject(Fault::Clear);
    axis.recover(mode::PROFILE_POSITION).await.unwrap();
}

#[tokio::test(start_paused = true)]
async fn a_csp_stream_to_a_drive_that_rebooted_stops() {
    let rig = rig(&[(DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let axis = Axis::new(rig.bus.node(4).unwrap()).with_sidecar(&crate::harness::sidecar("kollmorgen-akd"));
    axis.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    axis.home(&Homing::method(35)).await.unwrap();
    rig.bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut csp = axis.cyclic_position(4, 0x504).await.unwrap();
    let start = axis.position().await.unwrap();
    for k in 1..=50 {
        csp.send(start + 5 * k).await.unwrap();
    }
    rig.faults[0].inject(Fault::PowerCycle { off: 2_000 });
    let mut ended = None;
    for k in 51..=200 {
        if let Err(e) = csp.send(start + 5 * k).await {
            ended = Some(e);
            break;
        }
    }
    let e = ended.expect("the stream stops");
    assert!(e.to_string().contains("the drive rebooted"), "{e}");
    assert_eq!(csp.stopped(), Some(&Interruption::Rebooted));
    // No set-point goes out any more.
    let mut wire = rig.sim.lock().unwrap().endpoint();
    pass(Duration::from_millis(20)).await;
    while let Ok(Some(f)) = wire.try_recv() {
        assert_ne!(f.id(), 0x504, "a set-point after the stream stopped");
    }
    assert!(csp.send(0).await.is_err());
}

#[tokio::test(start_paused = true)]
async fn re_enable_after_reboot_brings_the_drive_back_once_reconfigured() {
    let rig = rig(&EXAMPLE);
    pass(Duration::from_millis(10)).await;
    let mut r = supervise(&rig.bus, example_with(""));
    boot_all(&mut r).await;
    let x = Arc::new(Axis::new(rig.bus.node(2).unwrap()));
    let y = Axis::new(rig.bus.node(3).unwrap());
    x.enable().await.unwrap();
    y.enable().await.unwrap();
    let mut reports = Arc::clone(&x).keep(RecoveryPolicy::ReenableAfterReboot, mode::PROFILE_POSITION);
    rig.faults[0].inject(Fault::PowerCycle { off: 2_000 });
    rig.faults[1].inject(Fault::PowerCycle { off: 2_000 });
    let report = tokio::time::timeout(Duration::from_secs(2), reports.recv()).await.unwrap().unwrap();
    assert!(matches!(report, AxisReport::Recovered { trouble: Trouble::Rebooted, attempt: 1 }), "{report:?}");
    assert_eq!(x.state().await.unwrap(), Some(State::OperationEnabled));
    // y has no policy: configured again by the supervisor, but left disabled.
    r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Reconfigured { node: 3, .. })).await;
    pass(Duration::from_millis(100)).await;
    assert_eq!(y.state().await.unwrap(), Some(State::SwitchOnDisabled));
    r.stop().await;
}

/// The CAN controller's state changes, as a SocketCAN bus reports them from the kernel's error
/// frames (here played on the memory bus's controller, which has none of its own): each one
/// reported by the supervisor in order; after the restart every node read back, and a node
/// whose configuration changed while the master was off the bus configured again.
#[tokio::test(start_paused = true)]
async fn controller_states_are_reported_and_after_bus_off_every_node_is_read_back() {
    use od_bus::ControllerState;
    use od_master::supervisor::BusState;
    let mut sim = Sim::new();
    for &(kind, id) in &EXAMPLE {
        sim.add(node(kind, id));
    }
    let link = od_bus::tokio::Bus::attach(sim.bus());
    let controller = link.controller();
    let bus = Bus::start(link, Config::default());
    let sim = Arc::new(Mutex::new(sim));
    // The simulation in step with tokio's paused clock.
    let follow = {
        let sim = Arc::clone(&sim);
        tokio::spawn(async move {
            let start = tokio::time::Instant::now();
            loop {
                {
                    let mut sim = sim.lock().unwrap();
                    let t = start.elapsed().as_micros() as u64;
                    let now = sim.now();
                    sim.advance(t.saturating_sub(now));
                }
                tokio::time::sleep(STEP).await;
            }
        })
    };
    pass(Duration::from_millis(10)).await;
    let network = example_with("");
    let mut r = supervise(&bus, network.clone());
    boot_all(&mut r).await;
    pass(Duration::from_millis(50)).await;
    while r.events.try_recv().is_ok() {}

    for (state, want) in [
        (ControllerState::ErrorWarning, BusState::ErrorWarning),
        (ControllerState::ErrorPassive, BusState::ErrorPassive),
        (ControllerState::BusOff, BusState::BusOff),
    ] {
        controller.report(state);
        let (e, before) = r.expect(Duration::from_millis(100), |e| matches!(e, SupervisorEvent::Bus(_))).await;
        assert_eq!(e, SupervisorEvent::Bus(want), "{before:#?}");
        assert!(before.is_empty(), "{before:#?}");
    }
    // While the master is off the bus, y_axis loses its heartbeat time (1017h back to 0).
    let heartbeat = network.nodes[1].plan.writes.iter().find(|w| w.index == 0x1017).expect("y_axis 1017h write");
    bus.node(3).unwrap().write_bytes(0x1017, 0, &[0, 0]).await.unwrap();
    controller.report(ControllerState::Restarted);
    let (e, _) = r.expect(Duration::from_millis(100), |e| matches!(e, SupervisorEvent::Bus(_))).await;
    assert_eq!(e, SupervisorEvent::Bus(BusState::Restarted));
    let mut verified = std::collections::BTreeSet::new();
    let mut reconfigured = std::collections::BTreeSet::new();
    let mut seen = Vec::new();
    while verified.len() + reconfigured.len() < 3 {
        let (e, before) = r
            .expect(Duration::from_secs(2), |e| {
                matches!(e, SupervisorEvent::Reconfigured { .. } | SupervisorEvent::Verified { .. })
            })
            .await;
        seen.extend(before);
        match e {
            SupervisorEvent::Verified { node, objects, .. } => {
                assert_eq!(
                    objects,
                    network
                        .nodes
                        .iter()
                        .find(|n| n.node_id == node)
                        .unwrap()
                        .plan
                        .writes
                        .iter()
                        .map(|w| (w.index, w.sub))
                        .collect::<std::collections::BTreeSet<_>>()
                        .len()
                );
                verified.insert(node);
            }
            SupervisorEvent::Reconfigured { node, .. } => {
                reconfigured.insert(node);
            }
            _ => unreachable!(),
        }
    }
    assert_eq!(verified, [2, 4].into());
    assert_eq!(reconfigured, [3].into());
    // The one read back that differed is named with both values.
    assert!(
        seen.iter().any(|e| matches!(e, SupervisorEvent::BootFailed { node: 3, message, .. }
            if message.contains("1017h") && message.contains("00 00") && message.contains(&hex(&heartbeat.data)))),
        "{seen:#?}"
    );
    for n in &network.nodes {
        od_master::supervisor::verify(&bus, n).await.unwrap_or_else(|e| panic!("{}: {e}", n.name));
    }
    controller.report(ControllerState::ErrorActive);
    let (e, _) = r.expect(Duration::from_millis(100), |e| matches!(e, SupervisorEvent::Bus(_))).await;
    assert_eq!(e, SupervisorEvent::Bus(BusState::ErrorActive));
    // Back to error-active reads nothing back: only the restart does.
    let after = r.during(Duration::from_millis(200)).await;
    assert!(after.is_empty(), "{after:#?}");
    r.stop().await;
    follow.abort();
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

// Over TCP: the hub restarted while the network runs.

/// Drives on a hub at `addr`, in real time, until `stop`.
fn hub_drives(addr: &str) -> (od_bus::Hub, Arc<std::sync::atomic::AtomicBool>, Vec<std::thread::JoinHandle<()>>) {
    let hub = od_bus::Hub::bind(addr, od_bus::HubConfig::default().quiet()).expect("bind the hub");
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let threads = EXAMPLE
        .iter()
        .map(|&(kind, id)| {
            let mut ep = hub.attach("can0").unwrap();
            let stop = Arc::clone(&stop);
            let mut n = node(kind, id);
            std::thread::spawn(move || {
                let _ = drive::node::run(&mut *n, &mut ep, &drive::node::MonotonicClock::new(), &stop);
            })
        })
        .collect();
    (hub, stop, threads)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hub_restarted_link_down_and_up_and_no_node_left_unconfigured() {
    let (hub, stop, threads) = hub_drives("127.0.0.1:0");
    let addr = hub.local_addr();
    let bus = Bus::open(&format!("socketcand://{addr}/can0"), Config::default()).await.unwrap();
    let network = example_with("");
    let mut r = supervise(&bus, network.clone());
    boot_all(&mut r).await;
    // The hub and its drives go away (the drives come back with their defaults).
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    hub.stop();
    threads.into_iter().for_each(|t| t.join().unwrap());
    r.expect(Duration::from_secs(5), |e| {
        matches!(e, SupervisorEvent::Bus(od_master::supervisor::BusState::LinkDown { .. }))
    })
    .await;
    let (hub, stop, threads) = hub_drives(&addr.to_string());
    r.expect(Duration::from_secs(10), |e| matches!(e, SupervisorEvent::Bus(od_master::supervisor::BusState::LinkUp)))
        .await;
    let mut configured = std::collections::BTreeSet::new();
    let mut seen = Vec::new();
    while configured.len() < 3 {
        let (e, before) = r
            .expect(Duration::from_secs(10), |e| {
                matches!(e, SupervisorEvent::Reconfigured { .. } | SupervisorEvent::Verified { .. })
            })
            .await;
        seen.extend(before);
        if let SupervisorEvent::Reconfigured { node, .. } | SupervisorEvent::Verified { node, .. } = e {
            configured.insert(node);
        }
    }
    for n in &network.nodes {
        od_master::supervisor::verify(&bus, n).await.unwrap_or_else(|e| panic!("{}: {e}; {seen:#?}", n.name));
    }
    r.stop().await;
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    hub.stop();
    threads.into_iter().for_each(|t| t.join().unwrap());
}

/// A node marked `lss = true` is lost (its drive removed) and a replacement without a node-ID
/// appears: the supervisor finds it by an LSS fastscan narrowed by the node's EDS identity
/// (its serial number differs from the description's), gives it the node-ID, and configures it
/// after its boot-up like a rebooted node.
#[tokio::test(start_paused = true)]
async fn a_replaced_drive_without_node_id_gets_the_lost_nodes_id_and_is_configured() {
    use drive::drives::DeviceApps;
    use drive::node::NodeConfig;
    let dir = std::env::temp_dir().join(format!("od-master-supervisor-lss-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap().replacen(
        "node_id = 2\n",
        "node_id = 2\nserial = 1001\nlss = true\n",
        1,
    );
    let network = Network::from_description_text("example.toml", &repo().join("networks"), &text).unwrap();
    let build = |kind: DeviceKind, id: u8, serial: u32| {
        let config =
            NodeConfig { node_id: Some(id), serial: Some(serial), state_dir: Some(dir.clone()), ..Default::default() };
        kind.build(&config, &DeviceApps::new()).expect("a simulated drive")
    };
    let mut sim = Sim::new();
    let (x, x_faults) = Faulty::new(build(DeviceKind::Drvi, 2, 1001));
    sim.add(Box::new(x));
    sim.add(node(DeviceKind::Drcs, 3));
    sim.add(node(DeviceKind::Akd, 4));
    let (bus, sim) = drive::node::spawn_with_master(sim, Config::default(), STEP);
    let mut r = supervise(&bus, network);
    for n in 2..=4 {
        r.expect(Duration::from_secs(2), booted(n)).await;
    }
    // The DRVI of x_axis taken out (off for an hour), a new one without a node-ID put in.
    x_faults.inject(Fault::PowerCycle { off: 3_600_000_000 });
    r.expect(Duration::from_secs(1), |e| matches!(e, SupervisorEvent::Lost { node: 2, .. })).await;
    let replacement = sim.lock().unwrap().add(build(DeviceKind::Drvi, 255, 5555));
    let (assigned, _) = r.expect(Duration::from_secs(3), |e| matches!(e, SupervisorEvent::LssAssigned { .. })).await;
    assert_eq!(assigned, SupervisorEvent::LssAssigned { node: 2, name: "x_axis".into(), serial: 5555 });
    let (done, seen) =
        r.expect(Duration::from_secs(2), |e| matches!(e, SupervisorEvent::Reconfigured { node: 2, .. })).await;
    assert!(seen.contains(&SupervisorEvent::Rebooted { node: 2, name: "x_axis".into() }), "{seen:#?}");
    let SupervisorEvent::Reconfigured { writes, .. } = done else { unreachable!() };
    assert_eq!(writes, 29, "the description's configuration, as at the first boot");
    pass(Duration::from_millis(300)).await;
    {
        let sim = sim.lock().unwrap();
        assert_eq!(sim.node(replacement).active_node_id().map(|i| i.get()), Some(2));
        assert_eq!(sim.node(replacement).nmt_state(), NmtState::Operational);
    }
    // Stored: it keeps node 2 across a power cycle.
    assert!(std::fs::read_to_string(dir.join("drvi-sn5555.lss")).unwrap().starts_with("node_id = 2\n"));
    r.stop().await;
    let _ = std::fs::remove_dir_all(&dir);
}
