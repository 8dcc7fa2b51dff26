//! A network that keeps running: [`Supervisor`] boots a [`Network`] as [`boot`](crate::boot::boot)
//! does, then keeps error control over it for as long as it runs, as CiA 302-2's NMT master
//! does:
//!
//! - every node that produces heartbeats is watched with a consumer time from the description
//!   (`heartbeat_timeout_ms`, by default twice its 1017h plus 50 ms), or by node guarding
//!   (`guard_time_ms`, `life_time_factor`);
//! - a boot-up at run time: the bus ends the SDO transfers in flight to the node at once
//!   ([`Error::Rebooted`](crate::Error::Rebooted)), and the node's boot process (identity,
//!   configuration, PDOs, start rule) runs again for it alone; the other nodes are not touched;
//! - a node lost: its `on_lost` (report, reset that node, or for a mandatory node stop or reset
//!   all nodes) after `reset_delay_ms`, unless it is heard again first (recovered);
//! - a boot that fails (another device answers, a write is refused, no heartbeat): reported
//!   with CiA 302-2's letter; the node is not started; for a mandatory node the network's
//!   `on_mandatory_failure`, at most `boot_attempts` times in a row;
//! - the link going down and up (socketcand): reported, and each node's configuration read
//!   back when it is up again; a node that lost it is configured again;
//! - the CAN controller's state ([`Bus::controller`]: SocketCAN's error frames, an slcan
//!   adapter's bus-off): error warning, error-passive, bus-off, restarted, error-active again
//!   reported; after a restart each node's configuration is read back as after the link.
//!
//! What to do is decided by [`policy::decide`], a function of the policy and what happened,
//! without I/O or clock; this module carries the decisions out. Everything is reported as a
//! [`SupervisorEvent`] ([`Supervisor::events`]).
//!
//! ```no_run
//! # async fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! use od_master::supervisor::Supervisor;
//! let bus = od_master::Bus::open("socketcand://127.0.0.1:29536/can0", Default::default()).await?;
//! let network = od_master::Network::from_description("networks/example.toml".as_ref())?;
//! let supervisor = Supervisor::new(bus, network);
//! let mut events = supervisor.events();
//! tokio::spawn(async move {
//!     while let Ok(event) = events.recv().await {
//!         println!("{event}");
//!     }
//! });
//! // Runs until the future given completes: Ctrl-C, a command, a timer.
//! let summary = supervisor.run(tokio::time::sleep(std::time::Duration::from_secs(3600))).await;
//! println!("{} reboots, {} reconfigured", summary.reboots, summary.reconfigured);
//! # Ok(()) }
//! ```

pub mod policy;

use std::collections::BTreeMap;
use std::future::Future;
use std::time::Duration;

use od_bus::tokio::LinkState;
use od_runtime::master::nmt::Target;
use od_runtime::master::{NodeEvent, Watch};
use od_runtime::{NmtCommand, NmtState, NodeId};
use tokio::sync::broadcast;
use tokio::task::{AbortHandle, JoinSet};
use tokio::time::Instant;

use crate::boot::{self, BootNode, Network, NodeReport, Stage};
use crate::bus::Bus;
use crate::event::Event;
use policy::{Action, Input};

/// The state of the bus itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusState {
    /// The controller is error-active again (SocketCAN).
    ErrorActive,
    /// An error counter passed the warning level (96).
    ErrorWarning,
    /// The controller is error-passive (an error counter passed 127).
    ErrorPassive,
    /// The controller went bus-off: it sends and receives nothing until restarted.
    BusOff,
    /// The controller was restarted after bus-off.
    Restarted,
    /// The link to the bus failed (socketcand): frames are lost until it is back.
    LinkDown {
        /// Why.
        reason: String,
    },
    /// The link is back.
    LinkUp,
    /// The bus is closed for good.
    Closed,
}

impl BusState {
    /// The state a SocketCAN error frame reports (its CAN id with or without the error flag,
    /// and its data), if it reports one: bus-off, restarted, or the controller's passive,
    /// warning or active state. Other errors (a lost arbitration, a protocol error) are not a
    /// change of state: `None`. (The bus decodes them: [`od_bus::ControllerState::from_error_frame`].)
    pub fn from_error_frame(id: u32, data: &[u8]) -> Option<BusState> {
        od_bus::ControllerState::from_error_frame(id, data).map(BusState::from)
    }
}

impl From<od_bus::ControllerState> for BusState {
    fn from(state: od_bus::ControllerState) -> Self {
        match state {
            od_bus::ControllerState::ErrorActive => BusState::ErrorActive,
            od_bus::ControllerState::ErrorWarning => BusState::ErrorWarning,
            od_bus::ControllerState::ErrorPassive => BusState::ErrorPassive,
            od_bus::ControllerState::BusOff => BusState::BusOff,
            od_bus::ControllerState::Restarted => BusState::Restarted,
        }
    }
}

impl std::fmt::Display for BusState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BusState::ErrorActive => f.write_str("bus error-active again"),
            BusState::ErrorWarning => f.write_str("bus error warning (an error counter passed 96)"),
            BusState::ErrorPassive => f.write_str("bus error-passive (an error counter passed 127)"),
            BusState::BusOff => f.write_str("bus-off: the controller is off the bus"),
            BusState::Restarted => f.write_str("bus restarted after bus-off"),
            BusState::LinkDown { reason } => write!(f, "link down: {reason}"),
            BusState::LinkUp => f.write_str("link up"),
            BusState::Closed => f.write_str("bus closed"),
        }
    }
}

/// What the supervisor reports. Every node event names the node by id and name.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SupervisorEvent {
    /// The node was configured (and started, if the master starts it) at the first boot.
    Booted {
        /// Node id.
        node: u8,
        /// Its name in the network.
        name: String,
        /// SDO writes made.
        writes: usize,
    },
    /// A keep-alive node found operational at the start: left as it is.
    KeptAlive {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
    },
    /// A boot-up message at run time: the node restarted with its defaults.
    Rebooted {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
    },
    /// A rebooted (or reset) node was configured again and is running.
    Reconfigured {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// SDO writes made.
        writes: usize,
        /// From its boot-up message to its heartbeat saying Operational (or to its last write
        /// when it is not started by the master or produces no heartbeat).
        elapsed: Duration,
        /// From its boot-up message to the NMT start that made it Operational (configured and
        /// started; `elapsed` adds the wait for its next heartbeat), if it was started.
        started: Option<Duration>,
    },
    /// The node's boot process failed; the node was not started.
    BootFailed {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// The step that failed.
        step: Stage,
        /// The object it failed at, if any.
        object: Option<(u16, u8)>,
        /// CiA 302-2's letter for it ([`BootError::reason_letter`](crate::boot::BootError::reason_letter)).
        reason: Option<char>,
        /// The whole error, in words.
        message: String,
    },
    /// Its heartbeat (or guarding) was lost.
    Lost {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
    },
    /// Heard again after a loss, before any reset.
    Recovered {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// The state its heartbeat says.
        state: NmtState,
    },
    /// The policy acted because of this node.
    Acted {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// What was done.
        action: Action,
    },
    /// A mandatory node cannot be booted and the policy has nothing more to try: the network
    /// cannot run as described.
    MandatoryFailed {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
    },
    /// Its configuration was read back after the master was off the bus (link down and up, bus-off
    /// and restarted) and is as configured.
    Verified {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// Objects read back.
        objects: usize,
    },
    /// The node's device was given its node-ID over LSS (the description's `lss = true`)
    /// before its boot.
    LssAssigned {
        /// Node id.
        node: u8,
        /// Its name.
        name: String,
        /// The device's serial number.
        serial: u32,
    },
    /// A device without a node-ID that the description does not name was found by the LSS
    /// step's fastscan: left as it is.
    LssUnknown {
        /// Its identity.
        identity: crate::lss::Identity,
    },
    /// The bus's own state changed.
    Bus(BusState),
}

impl std::fmt::Display for SupervisorEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SupervisorEvent::Booted { node, name, writes } => {
                write!(f, "{name} (node {node}): booted, {writes} writes")
            }
            SupervisorEvent::KeptAlive { node, name } => {
                write!(f, "{name} (node {node}): operational already, kept alive (not configured again)")
            }
            SupervisorEvent::Rebooted { node, name } => write!(f, "{name} (node {node}): rebooted (boot-up message)"),
            SupervisorEvent::Reconfigured { node, name, writes, elapsed, started } => {
                write!(f, "{name} (node {node}): reconfigured, {writes} writes")?;
                if let Some(s) = started {
                    write!(f, ", started {:.1} ms after its boot-up", s.as_secs_f64() * 1e3)?;
                }
                write!(f, ", running (heartbeat) after {:.1} ms", elapsed.as_secs_f64() * 1e3)
            }
            SupervisorEvent::BootFailed { node, name, step, reason, message, .. } => {
                write!(f, "{name} (node {node}): boot failed {step}")?;
                if let Some(r) = reason {
                    write!(f, " (CiA 302-2 error {r})")?;
                }
                write!(f, ": {message}")
            }
            SupervisorEvent::Lost { node, name } => write!(f, "{name} (node {node}): heartbeat lost"),
            SupervisorEvent::Recovered { node, name, state } => {
                write!(f, "{name} (node {node}): recovered, {state:?}")
            }
            SupervisorEvent::Acted { node, name, action } => match action {
                Action::ResetNode => write!(f, "{name} (node {node}): NMT reset node sent to it"),
                Action::StopAll => write!(f, "{name} (node {node}): NMT stop sent to all nodes"),
                Action::ResetAll => write!(f, "{name} (node {node}): NMT reset node sent to all nodes"),
                Action::GiveUp => write!(f, "{name} (node {node}): boot failed too often, nothing more is tried"),
                Action::Configure => write!(f, "{name} (node {node}): configuring"),
                Action::ResetAfter(ms) => write!(f, "{name} (node {node}): reset in {ms} ms unless it comes back"),
            },
            SupervisorEvent::MandatoryFailed { node, name } => {
                write!(f, "{name} (node {node}): mandatory node cannot be booted; the network cannot run")
            }
            SupervisorEvent::Verified { node, name, objects } => {
                write!(f, "{name} (node {node}): configuration read back ({objects} objects), unchanged")
            }
            SupervisorEvent::LssAssigned { node, name, serial } => {
                write!(f, "{name} (node {node}): node-ID given over LSS to the device of serial number {serial}")
            }
            SupervisorEvent::LssUnknown { identity } => {
                write!(f, "LSS: a device without a node-ID the description does not name ({identity}): left as it is")
            }
            SupervisorEvent::Bus(state) => write!(f, "{state}"),
        }
    }
}

/// What a run of the supervisor saw, when it ends.
#[derive(Debug, Default)]
pub struct Summary {
    /// The first boot's report of each node booted then.
    pub boot: Vec<NodeReport>,
    /// Boot-ups at run time.
    pub reboots: u64,
    /// Nodes configured again after a boot-up.
    pub reconfigured: u64,
    /// Boots that failed (first boot included).
    pub boot_failures: u64,
    /// Heartbeat losses.
    pub lost: u64,
    /// Mandatory nodes that could not be booted ([`SupervisorEvent::MandatoryFailed`]).
    pub mandatory_failed: Vec<String>,
}

/// Keeps a network running: see the [module](self).
#[derive(Debug)]
pub struct Supervisor {
    bus: Bus,
    network: Network,
    events: broadcast::Sender<SupervisorEvent>,
    lss_step_timeout: Duration,
}

/// What the loop knows about one node.
#[derive(Default)]
struct NodeRun {
    /// Its boot process, while one runs (a boot-up aborts it and starts another).
    booting: Option<AbortHandle>,
    /// Generation of the boot process running: a report of an older one is stale.
    generation: u64,
    /// When its last boot-up was seen.
    boot_up_at: Option<Instant>,
    /// Boots failed in a row.
    failures: u32,
    /// When `on_lost` acts unless it comes back.
    reset_at: Option<Instant>,
    /// Reported failed for good.
    given_up: bool,
    /// After a reset the master sent: when to boot it anyway if no boot-up was heard (a
    /// boot-up lost, or a heartbeat that cannot get through), and how many such boots failed.
    boot_check_at: Option<Instant>,
    checks_failed: u32,
    /// Marked `lss = true` and lost: the bus is searched for a device of its type without a
    /// node-ID (its own after a power cycle that forgot it, or a replacement) at
    /// `lss_probe_at`, until it is heard again.
    lss_lost: bool,
    lss_probe_at: Option<Instant>,
}

/// How often a lost node marked `lss = true` is looked for as a device without a node-ID.
pub const LSS_PROBE: Duration = Duration::from_millis(500);

/// What one LSS search for a lost node found.
enum Probe {
    /// No device of its type without a node-ID.
    Nothing,
    /// This one, now given the node's node-ID (its boot-up follows).
    Assigned(crate::lss::Identity),
    /// Several: which one replaces the node cannot be told; none is touched.
    Ambiguous(Vec<crate::lss::Identity>),
}

/// The LSS search for a lost node `n` marked `lss = true`: a fastscan narrowed by its device
/// description's vendor, product and revision (the serial number scanned: a replacement has
/// another one); exactly one device found gets `n`'s node-ID (stored as `lss_store` says).
async fn lss_probe(bus: Bus, n: BootNode, step_timeout: Duration) -> Result<Probe, crate::Error> {
    use crate::lss::{ErrorKind, Lss, Step};
    let id = &n.plan.identity;
    let mut session = Lss::new(&bus);
    session.set_timeout(step_timeout);
    let found = match session.scan([Some(id.vendor_id), Some(id.product_code), Some(id.revision), None]).await {
        Ok(found) => found,
        // Devices without a node-ID, none of this type.
        Err(crate::Error::Lss { error, .. })
            if matches!(error.step, Step::FastscanConfirm { known: true, .. })
                && matches!(error.kind, ErrorKind::Timeout(_)) =>
        {
            Vec::new()
        }
        Err(e) => return Err(e),
    };
    match found[..] {
        [] => Ok(Probe::Nothing),
        [one] => {
            session.set_node_id(one, n.node_id, n.lss_store).await?;
            Ok(Probe::Assigned(one))
        }
        _ => Ok(Probe::Ambiguous(found)),
    }
}

/// How long after an NMT reset the node's boot-up is waited for before it is booted anyway.
const BOOT_CHECK: Duration = Duration::from_secs(1);

/// What a finished task of the loop brings back.
enum Done {
    Boot { node: u8, generation: u64, report: NodeReport },
    Verify { node: u8, result: Result<usize, String> },
    Lss { node: u8, result: Result<Probe, crate::Error> },
}

impl Supervisor {
    /// A supervisor of `network` on `bus`. Nothing happens until [`Supervisor::run`].
    pub fn new(bus: Bus, network: Network) -> Self {
        let (events, _) = broadcast::channel(1024);
        Self { bus, network, events, lss_step_timeout: Duration::from_micros(crate::lss::DEFAULT_TIMEOUT) }
    }

    /// Sets the LSS step timeout of the first boot's LSS step (the nodes marked `lss = true`;
    /// default [`crate::lss::DEFAULT_TIMEOUT`]).
    pub fn set_lss_step_timeout(&mut self, timeout: Duration) {
        self.lss_step_timeout = timeout;
    }

    /// Subscribes to its events from now on (subscribe before [`Supervisor::run`] to see the
    /// first boot's).
    pub fn events(&self) -> broadcast::Receiver<SupervisorEvent> {
        self.events.subscribe()
    }

    /// The bus it runs on.
    pub fn bus(&self) -> &Bus {
        &self.bus
    }

    fn emit(&self, event: SupervisorEvent) {
        let _ = self.events.send(event);
    }

    fn position(&self, node: u8) -> Option<usize> {
        self.network.nodes.iter().position(|n| n.node_id == node)
    }

    /// Boots the network, then supervises it until `shutdown` completes (or the bus closes).
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> Summary {
        let mut summary = Summary::default();
        // Subscribed before anything is sent, so that nothing after is missed.
        let mut bus_events = self.bus.events();
        let mut controller = self.bus.controller();
        let mut controller_open = true;
        let mut runs: BTreeMap<u8, NodeRun> =
            self.network.nodes.iter().map(|n| (n.node_id, NodeRun::default())).collect();
        let mut tasks: JoinSet<Done> = JoinSet::new();

        // The first boot: keep-alive nodes found operational are left as they are.
        let alive = self.operational_keep_alive().await;
        let to_boot: Vec<BootNode> = self
            .network
            .nodes
            .iter()
            .filter(|n| n.supervision.configure && !alive.contains(&n.node_id))
            .cloned()
            .collect();
        for n in self.network.nodes.iter().filter(|n| alive.contains(&n.node_id)) {
            self.emit(SupervisorEvent::KeptAlive { node: n.node_id, name: n.name.clone() });
        }
        // Watched before the boot: a node that goes silent right after it is lost, not
        // forgotten by a watch that starts over.
        for n in &self.network.nodes {
            self.watch(n).await;
        }
        // The nodes marked for LSS get their node-ID first; those that cannot are not booted.
        let all = to_boot.len() == self.network.nodes.len();
        let (lss, reports) =
            boot::boot_with_lss(&self.bus, &to_boot, true, &|n| n.supervision.start, all, self.lss_step_timeout).await;
        for (id, node, _) in lss.iter().flat_map(|c| &c.assigned) {
            if let Some(n) = to_boot.iter().find(|n| n.node_id == *node) {
                self.emit(SupervisorEvent::LssAssigned { node: *node, name: n.name.clone(), serial: id.serial });
            }
        }
        for identity in lss.iter().flat_map(|c| &c.unknown) {
            self.emit(SupervisorEvent::LssUnknown { identity: *identity });
        }
        for r in &reports {
            self.settle_boot(r, &mut runs, &mut summary, None).await;
        }
        summary.boot = reports;

        tokio::pin!(shutdown);
        // One LSS conversation at a time on the bus.
        let mut lss_probing = false;
        loop {
            let next_reset = runs.values().flat_map(|r| [r.reset_at, r.boot_check_at, r.lss_probe_at]).flatten().min();
            tokio::select! {
                () = &mut shutdown => break,
                event = bus_events.recv() => match event {
                    Ok(event) => {
                        if !self.bus_event(event, &mut runs, &mut tasks, &mut summary) {
                            break;
                        }
                    }
                    Err(broadcast::error::RecvError::Lagged(_)) => {}
                    Err(broadcast::error::RecvError::Closed) => break,
                },
                change = controller.recv(), if controller_open => match change {
                    Ok(state) => self.controller_changed(state, &mut tasks),
                    // Changes missed: what the controller went through is unknown, as after
                    // a link that was down.
                    Err(broadcast::error::RecvError::Lagged(_)) => self.verify_all(&mut tasks),
                    // Nothing reports any more (the bus handles keep it open while they live).
                    Err(broadcast::error::RecvError::Closed) => controller_open = false,
                },
                Some(done) = tasks.join_next(), if !tasks.is_empty() => match done {
                    Ok(Done::Boot { node, generation, report }) => {
                        let Some(run) = runs.get_mut(&node) else { continue };
                        if run.generation != generation {
                            continue;
                        }
                        run.booting = None;
                        let since = run.boot_up_at;
                        self.settle_boot(&report, &mut runs, &mut summary, since).await;
                    }
                    Ok(Done::Verify { node, result }) => self.verified(node, result, &mut runs, &mut tasks),
                    Ok(Done::Lss { node, result }) => {
                        lss_probing = false;
                        self.probed(node, result, &mut runs);
                    }
                    // Aborted by a newer boot-up: its successor reports.
                    Err(_) => {}
                },
                () = sleep_until(next_reset) => {
                    let now = Instant::now();
                    let due: Vec<u8> = runs.iter().filter(|(_, r)| r.reset_at.is_some_and(|t| t <= now)).map(|(id, _)| *id).collect();
                    let checks: Vec<u8> = runs.iter().filter(|(_, r)| r.boot_check_at.is_some_and(|t| t <= now)).map(|(id, _)| *id).collect();
                    let probes: Vec<u8> = runs.iter().filter(|(_, r)| r.lss_probe_at.is_some_and(|t| t <= now)).map(|(id, _)| *id).collect();
                    for node in probes {
                        let (Some(i), Some(run)) = (self.position(node), runs.get_mut(&node)) else { continue };
                        if lss_probing {
                            run.lss_probe_at = Some(now + LSS_PROBE);
                            continue;
                        }
                        run.lss_probe_at = None;
                        lss_probing = true;
                        let (bus, n, timeout) = (self.bus.clone(), self.network.nodes[i].clone(), self.lss_step_timeout);
                        tasks.spawn(async move { Done::Lss { node, result: lss_probe(bus, n, timeout).await } });
                    }
                    for node in checks {
                        let Some(i) = self.position(node) else { continue };
                        let n = &self.network.nodes[i];
                        if let Some(run) = runs.get_mut(&node) {
                            run.boot_check_at = None;
                            if run.booting.is_none() && n.supervision.configure {
                                self.spawn_boot(n, run, &mut tasks);
                            }
                        }
                    }
                    for node in due {
                        if let Some(run) = runs.get_mut(&node) {
                            run.reset_at = None;
                        }
                        let Some(i) = self.position(node) else { continue };
                        let n = &self.network.nodes[i];
                        if let Some(action) = policy::decide(&n.supervision, &self.network.supervision, Input::StillLost) {
                            self.act(n, action).await;
                            self.expect_boot(action, node, &mut runs);
                        }
                    }
                }
            }
        }
        tasks.abort_all();
        summary
    }

    /// What an LSS search for the lost node `node` found: a device given its node-ID (its
    /// boot-up follows, and the reboot path configures it), nothing (searched again after
    /// [`LSS_PROBE`] while it stays lost), several candidates or an error (reported; not
    /// searched again until it is lost anew).
    fn probed(&self, node: u8, result: Result<Probe, crate::Error>, runs: &mut BTreeMap<u8, NodeRun>) {
        let (Some(i), Some(run)) = (self.position(node), runs.get_mut(&node)) else { return };
        let n = &self.network.nodes[i];
        match result {
            Ok(Probe::Assigned(identity)) => {
                run.lss_lost = false;
                self.emit(SupervisorEvent::LssAssigned { node, name: n.name.clone(), serial: identity.serial });
            }
            Ok(Probe::Nothing) if run.lss_lost => run.lss_probe_at = Some(Instant::now() + LSS_PROBE),
            Ok(Probe::Nothing) => {}
            Ok(Probe::Ambiguous(found)) => {
                run.lss_lost = false;
                for identity in found {
                    self.emit(SupervisorEvent::LssUnknown { identity });
                }
            }
            Err(e) => {
                run.lss_lost = false;
                self.emit(SupervisorEvent::BootFailed {
                    node,
                    name: n.name.clone(),
                    step: Stage::Lss,
                    object: None,
                    reason: None,
                    message: format!("node {node} ({}): looking for its device over LSS: {e}", n.name),
                });
            }
        }
    }

    /// Handles one event of the bus; false when the bus has closed.
    fn bus_event(
        &self,
        event: Event,
        runs: &mut BTreeMap<u8, NodeRun>,
        tasks: &mut JoinSet<Done>,
        summary: &mut Summary,
    ) -> bool {
        match event {
            Event::Node(NodeEvent::BootUp { node }) => {
                let Some(i) = self.position(node) else { return true };
                let n = &self.network.nodes[i];
                summary.reboots += 1;
                self.emit(SupervisorEvent::Rebooted { node, name: n.name.clone() });
                let Some(run) = runs.get_mut(&node) else { return true };
                run.boot_up_at = Some(Instant::now());
                run.reset_at = None;
                run.boot_check_at = None;
                run.lss_lost = false;
                run.lss_probe_at = None;
                if let Some(old) = run.booting.take() {
                    old.abort();
                }
                if policy::decide(&n.supervision, &self.network.supervision, Input::BootUp) == Some(Action::Configure) {
                    self.spawn_boot(n, run, tasks);
                }
            }
            Event::Node(NodeEvent::Lost { node }) => {
                let Some(i) = self.position(node) else { return true };
                let n = &self.network.nodes[i];
                summary.lost += 1;
                self.emit(SupervisorEvent::Lost { node, name: n.name.clone() });
                if n.lss
                    && n.serial.is_some()
                    && let Some(run) = runs.get_mut(&node)
                {
                    run.lss_lost = true;
                    run.lss_probe_at = Some(Instant::now() + LSS_PROBE);
                }
                if let (Some(Action::ResetAfter(ms)), Some(run)) =
                    (policy::decide(&n.supervision, &self.network.supervision, Input::Lost), runs.get_mut(&node))
                {
                    run.reset_at = Some(Instant::now() + Duration::from_millis(u64::from(ms)));
                }
            }
            Event::Node(NodeEvent::Recovered { node, state }) => {
                let Some(i) = self.position(node) else { return true };
                if let Some(run) = runs.get_mut(&node) {
                    run.reset_at = None;
                    run.lss_lost = false;
                    run.lss_probe_at = None;
                }
                self.emit(SupervisorEvent::Recovered { node, name: self.network.nodes[i].name.clone(), state });
            }
            Event::Link(LinkState::Down { reason, .. }) => {
                self.emit(SupervisorEvent::Bus(BusState::LinkDown { reason }))
            }
            Event::Link(LinkState::Up { .. }) => {
                self.emit(SupervisorEvent::Bus(BusState::LinkUp));
                // What happened while the link was down is unknown.
                self.verify_all(tasks);
            }
            Event::Link(LinkState::Closed) => {
                self.emit(SupervisorEvent::Bus(BusState::Closed));
                return false;
            }
            _ => {}
        }
        true
    }

    /// Each node's configuration is read back, and a node that lost it is configured again:
    /// what happened on the bus while the master was not on it is unknown.
    fn verify_all(&self, tasks: &mut JoinSet<Done>) {
        for n in self.network.nodes.iter().filter(|n| n.supervision.configure) {
            let (bus, n) = (self.bus.clone(), n.clone());
            tasks.spawn(async move { Done::Verify { node: n.node_id, result: verify(&bus, &n).await } });
        }
    }

    /// The CAN controller's state changed: reported; once it is back on the bus after bus-off,
    /// every node is read back (boot-ups and state changes sent meanwhile were not heard).
    fn controller_changed(&self, state: od_bus::ControllerState, tasks: &mut JoinSet<Done>) {
        self.emit(SupervisorEvent::Bus(BusState::from(state)));
        if state == od_bus::ControllerState::Restarted {
            self.verify_all(tasks);
        }
    }

    /// After `action` (a reset sent because of `node`), the nodes reset are booted
    /// [`BOOT_CHECK`] later even if their boot-up is not heard.
    fn expect_boot(&self, action: Action, node: u8, runs: &mut BTreeMap<u8, NodeRun>) {
        let at = Instant::now() + BOOT_CHECK;
        for (id, run) in runs.iter_mut() {
            let reset = match action {
                Action::ResetNode => *id == node,
                Action::ResetAll => true,
                _ => false,
            };
            if reset {
                run.boot_check_at = Some(at);
                run.checks_failed = 0;
                run.boot_up_at = Some(Instant::now());
            }
        }
    }

    fn spawn_boot(&self, n: &BootNode, run: &mut NodeRun, tasks: &mut JoinSet<Done>) {
        run.generation += 1;
        let generation = run.generation;
        let (bus, node) = (self.bus.clone(), n.clone());
        let handle = tasks.spawn(async move {
            let one = std::slice::from_ref(&node);
            let mut reports = boot::boot_nodes(&bus, one, false, &|n| n.supervision.start, false).await;
            let report = reports.pop().unwrap_or_else(|| NodeReport {
                name: node.name.clone(),
                node_id: node.node_id,
                written: 0,
                planned: node.plan.writes.len(),
                started: false,
                started_at: None,
                result: Err(boot::BootError::Bus {
                    name: node.name.clone(),
                    stage: Stage::Configure,
                    error: crate::Error::Closed,
                }),
            });
            Done::Boot { node: node.node_id, generation, report }
        });
        run.booting = Some(handle);
    }

    fn verified(
        &self,
        node: u8,
        result: Result<usize, String>,
        runs: &mut BTreeMap<u8, NodeRun>,
        tasks: &mut JoinSet<Done>,
    ) {
        let Some(i) = self.position(node) else { return };
        let n = &self.network.nodes[i];
        match result {
            Ok(objects) => self.emit(SupervisorEvent::Verified { node, name: n.name.clone(), objects }),
            Err(message) => {
                self.emit(SupervisorEvent::BootFailed {
                    node,
                    name: n.name.clone(),
                    step: Stage::Configure,
                    object: None,
                    reason: None,
                    message: format!("read back after the master was off the bus: {message}; configuring again"),
                });
                if let Some(run) = runs.get_mut(&node)
                    && run.booting.is_none()
                {
                    run.boot_up_at = Some(Instant::now());
                    self.spawn_boot(n, run, tasks);
                }
            }
        }
    }

    /// Reports a node's boot and carries out what the policy says about it.
    async fn settle_boot(
        &self,
        r: &NodeReport,
        runs: &mut BTreeMap<u8, NodeRun>,
        summary: &mut Summary,
        boot_up_at: Option<Instant>,
    ) {
        let Some(i) = self.position(r.node_id) else { return };
        let n = &self.network.nodes[i];
        let Some(run) = runs.get_mut(&r.node_id) else { return };
        match &r.result {
            Ok(()) => {
                run.failures = 0;
                run.given_up = false;
                run.checks_failed = 0;
                match boot_up_at {
                    Some(at) => {
                        summary.reconfigured += 1;
                        self.emit(SupervisorEvent::Reconfigured {
                            node: r.node_id,
                            name: r.name.clone(),
                            writes: r.written,
                            elapsed: at.elapsed(),
                            started: r.started_at.map(|s| s.saturating_duration_since(at)),
                        });
                    }
                    None => {
                        self.emit(SupervisorEvent::Booted { node: r.node_id, name: r.name.clone(), writes: r.written })
                    }
                }
            }
            // A boot cut short by another boot-up is no failure of the node: the boot-up's own
            // boot follows (and reports).
            Err(boot::BootError::Bus { error: crate::Error::Rebooted { .. }, .. }) => {}
            Err(e) => {
                summary.boot_failures += 1;
                run.failures = run.failures.saturating_add(1);
                let step = match e {
                    boot::BootError::Identity { .. } => Stage::Identity,
                    boot::BootError::NoHeartbeat { .. } => Stage::Nmt,
                    boot::BootError::Bus { stage, .. } => *stage,
                    boot::BootError::Lss { .. } | boot::BootError::NoBootUp { .. } => Stage::Lss,
                };
                self.emit(SupervisorEvent::BootFailed {
                    node: r.node_id,
                    name: r.name.clone(),
                    step,
                    object: e.object(),
                    reason: e.reason_letter(),
                    message: e.to_string(),
                });
                // A boot after a reset without a boot-up heard (the node may still be out of
                // reach): tried again a bounded number of times.
                if boot_up_at.is_some()
                    && !n.supervision.mandatory
                    && run.checks_failed < self.network.supervision.boot_attempts
                {
                    run.checks_failed += 1;
                    if run.checks_failed < self.network.supervision.boot_attempts {
                        run.boot_check_at = Some(Instant::now() + BOOT_CHECK);
                    }
                }
                let failures = run.failures;
                let action = policy::decide(&n.supervision, &self.network.supervision, Input::BootFailed { failures });
                let final_failure = match action {
                    Some(Action::GiveUp) => {
                        let first = !run.given_up;
                        run.given_up = true;
                        first
                    }
                    // A policy that does not boot it again: this failure is final.
                    Some(Action::StopAll) | None => true,
                    Some(_) => false,
                };
                if let Some(action) = action {
                    self.act(n, action).await;
                    self.expect_boot(action, n.node_id, runs);
                }
                if final_failure && n.supervision.mandatory {
                    summary.mandatory_failed.push(n.name.clone());
                    self.emit(SupervisorEvent::MandatoryFailed { node: n.node_id, name: n.name.clone() });
                }
            }
        }
    }

    /// Carries out a decision that sends something (or gives up).
    async fn act(&self, n: &BootNode, action: Action) {
        let Some(id) = NodeId::new(n.node_id) else { return };
        let sent = match action {
            Action::ResetNode => self.bus.nmt(NmtCommand::ResetNode, Target::Node(id)).await,
            Action::StopAll => self.bus.nmt(NmtCommand::Stop, Target::All).await,
            Action::ResetAll => self.bus.nmt(NmtCommand::ResetNode, Target::All).await,
            Action::GiveUp => Ok(()),
            // Handled by the loop.
            Action::Configure | Action::ResetAfter(_) => return,
        };
        match sent {
            Ok(()) => self.emit(SupervisorEvent::Acted { node: n.node_id, name: n.name.clone(), action }),
            Err(e) => self.emit(SupervisorEvent::BootFailed {
                node: n.node_id,
                name: n.name.clone(),
                step: Stage::Nmt,
                object: None,
                reason: None,
                message: format!("{} could not be sent: {e}", action.name()),
            }),
        }
    }

    /// Watches each node that produces heartbeats (or is guarded) with its consumer time.
    async fn watch(&self, n: &BootNode) {
        let s = &n.supervision;
        let watch = if s.guard_time_ms > 0 {
            Some(Watch::Guarding {
                guard_time: u64::from(s.guard_time_ms) * 1000,
                life_time_factor: s.life_time_factor,
            })
        } else {
            policy::consumer_time_ms(s, n.plan.heartbeat_ms)
                .map(|ms| Watch::Heartbeat { timeout: u64::from(ms) * 1000 })
        };
        if let Some(watch) = watch {
            let _ = self.bus.watch(n.node_id, watch, None).await;
        }
    }

    /// The keep-alive nodes whose heartbeat says Operational, listened for during at most
    /// twice their heartbeat time plus 50 ms (1 s at most). None asked for: no wait.
    async fn operational_keep_alive(&self) -> Vec<u8> {
        let wanted: Vec<&BootNode> =
            self.network.nodes.iter().filter(|n| n.supervision.keep_alive && n.plan.heartbeat_ms > 0).collect();
        let Some(longest) = wanted.iter().map(|n| n.plan.heartbeat_ms).max() else { return Vec::new() };
        let until = Instant::now() + Duration::from_millis(2 * u64::from(longest) + 50).min(Duration::from_secs(1));
        let mut frames = self.bus.frames();
        let mut found = Vec::new();
        while found.len() < wanted.len() {
            match tokio::time::timeout_at(until, frames.recv()).await {
                Ok(Ok(f)) => {
                    let id = f.id();
                    if (0x701..=0x77F).contains(&id) && f.data() == [0x05] {
                        let node = (id - 0x700) as u8;
                        if wanted.iter().any(|n| n.node_id == node) && !found.contains(&node) {
                            found.push(node);
                        }
                    }
                }
                Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
                Ok(Err(_)) | Err(_) => break,
            }
        }
        found
    }
}

/// Reads back every object `node`'s plan configures and compares it with the value the plan
/// leaves there: the number of objects when all agree, else the first that does not (or the
/// transfer that failed), in words.
pub async fn verify(bus: &Bus, node: &BootNode) -> Result<usize, String> {
    let sdo = bus.node(node.node_id).map_err(|e| e.to_string())?;
    let mut last: BTreeMap<(u16, u8), &[u8]> = BTreeMap::new();
    for w in &node.plan.writes {
        last.insert((w.index, w.sub), &w.data);
    }
    for (&(index, sub), want) in &last {
        let got = sdo.read_bytes(index, sub).await.map_err(|e| e.to_string())?;
        if got != *want {
            return Err(format!(
                "node {}, {index:04X}h sub {sub} is {}, configured {}",
                node.node_id,
                hex(&got),
                hex(want)
            ));
        }
    }
    Ok(last.len())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

async fn sleep_until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn socketcan_error_frames() {
        #[rustfmt::skip]
        let table: &[(u32, &[u8], Option<BusState>)] = &[
            (0x2000_0040, &[0; 8], Some(BusState::BusOff)),
            (0x0000_0040, &[0; 8], Some(BusState::BusOff)),
            (0x2000_0100, &[0; 8], Some(BusState::Restarted)),
            (0x2000_0004, &[0, 0x10, 0, 0, 0, 0, 0, 0], Some(BusState::ErrorPassive)),
            (0x2000_0004, &[0, 0x20, 0, 0, 0, 0, 0, 0], Some(BusState::ErrorPassive)),
            (0x2000_0004, &[0, 0x08, 0, 0, 0, 0, 0, 0], Some(BusState::ErrorWarning)),
            (0x2000_0004, &[0, 0x40, 0, 0, 0, 0, 0, 0], Some(BusState::ErrorActive)),
            (0x2000_0004, &[0, 0x01, 0, 0, 0, 0, 0, 0], None),
            (0x2000_0002, &[0; 8], None),
            (0x2000_0004, &[], None),
        ];
        for (id, data, want) in table {
            assert_eq!(BusState::from_error_frame(*id, data), *want, "{id:08X} {data:?}");
        }
    }
}
