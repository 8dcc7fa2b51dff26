//! A network configured at boot, as CiA 302-2 asks of a configuration manager: each node's
//! identity checked, its configuration written, its PDOs mapped, and the nodes started.
//!
//! The network comes from a description (`networks/*.toml`, the format `odgen dcf --network`
//! reads; see `od_codegen::network`, with the feature `network-description`) or from one DCF per node ([`Network::load`]). For each
//! node, [`boot`]:
//!
//! 1. reads 1000h (device type) and 1018h sub 1, 2 and 3 (vendor id, product code, revision
//!    number) and compares each with the value the file expects: the device description's
//!    `[DeviceInfo]` `VendorNumber`, `ProductNumber`, `RevisionNumber` (or 1018h's default)
//!    and 1000h's default. As CiA 302-2 does with its expected-identity objects 1F84h–1F87h, the
//!    whole value is compared, and a value of 0 in the file is not checked. The serial number
//!    (1018h sub 4) is not compared: a device description cannot know it. A wrong device is an
//!    [`BootError::Identity`] naming the node, the object and both values;
//! 2. sends NMT enter pre-operational, and writes the values that differ from the device
//!    description's defaults, the PDOs in CiA 301's order (disable, communication parameters,
//!    mapping, enable): [`eds::concise`] says which and in what order;
//! 3. once every node has been tried, starts the nodes: one NMT start to all nodes when every
//!    node was configured, as CiA 302-2's "start all nodes" does, or else an NMT start to each
//!    node that was configured, so that a node that failed stays pre-operational;
//! 4. waits for each started node that produces heartbeats (1017h, as configured) to send one
//!    saying Operational, within three of its periods (at least 100 ms): CiA 302-2's "start
//!    error control". A node that does not is a [`BootError::NoHeartbeat`].
//!
//! Nodes are booted at the same time (each node's transfers one after another on its own SDO
//! channel). A node that fails does not stop the others: [`boot`] returns one [`NodeReport`]
//! per node, saying what failed and at which object.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use od_bus::CanFrame;
use tokio::sync::broadcast;
use tokio::time::Instant;

use crate::supervisor::policy::{NetworkSupervision, NodeSupervision};
use eds::concise::{self, Plan, Role};
use od_runtime::master::nmt::Target;
use od_runtime::{NmtCommand, NodeId};

use crate::bus::Bus;
use crate::error::Error;

/// One node to boot.
#[derive(Clone, Debug)]
pub struct BootNode {
    /// Its name (the network file's table key, a DCF's `NodeName`, or the DCF's file name).
    pub name: String,
    /// Its node id.
    pub node_id: u8,
    /// The device description or DCF it was configured from, as shown in messages.
    pub device: String,
    /// What to check and write.
    pub plan: Plan,
    /// Its serial number, when the description gives one (`serial`, the DCF's
    /// `LSS_SerialNumber`): the device LSS gives this node-ID to ([`crate::lss`]).
    pub serial: Option<u32>,
    /// Whether [`boot`] gives it its node-ID over LSS first (the description's `lss = true`;
    /// needs `serial`): see [`crate::lss::Lss::commission`].
    pub lss: bool,
    /// Whether that node-ID is stored in the device (`lss_store`, default true).
    pub lss_store: bool,
    /// How the supervisor watches it after boot ([`crate::supervisor`]); [`boot`] does not
    /// look at it.
    pub supervision: NodeSupervision,
}

/// The nodes of a network, each with its plan.
#[derive(Clone, Debug, Default)]
pub struct Network {
    /// In the order of the file (or of the DCFs given).
    pub nodes: Vec<BootNode>,
    /// How the supervisor treats the network after boot (`[network.supervision]`, or a master
    /// DCF's 1F80h: [`Network::apply_master_dcf`]).
    pub supervision: NetworkSupervision,
}

/// Why a network description or a DCF cannot be booted. Its text lists every problem.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// A file cannot be read.
    #[error("cannot read {path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        error: std::io::Error,
    },
    /// The description or a DCF has errors (rendered as `odgen` renders them).
    #[error("{0}")]
    Invalid(String),
}

impl Network {
    /// The LSS plan of the network ([`crate::lss::Lss::assign`]): for each node whose
    /// description gives a serial number, the identity to select (the device description's
    /// vendor-ID, product code and revision number, and that serial number) and its node-ID, in
    /// the order of the description. (Here rather than in `lss`, which `boot` uses: no import
    /// circle.)
    pub fn lss_plan(&self) -> Vec<(crate::lss::Identity, u8)> {
        self.nodes
            .iter()
            .filter_map(|n| {
                let id = &n.plan.identity;
                let serial = n.serial?;
                Some((
                    crate::lss::Identity {
                        vendor: id.vendor_id,
                        product: id.product_code,
                        revision: id.revision,
                        serial,
                    },
                    n.node_id,
                ))
            })
            .collect()
    }

    /// A network from files: one network description (`.toml`), or DCFs.
    pub fn load(paths: &[PathBuf]) -> Result<Self, LoadError> {
        match paths {
            [one] if one.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")) => Self::from_description(one),
            [] => Err(LoadError::Invalid("no network description or DCF given".to_owned())),
            dcfs => {
                if let Some(toml) = dcfs.iter().find(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")))
                {
                    return Err(LoadError::Invalid(format!(
                        "{}: a network description is given alone, not with other files",
                        toml.display()
                    )));
                }
                let mut net = Network::default();
                let mut problems = Vec::new();
                for path in dcfs {
                    match Self::dcf(path) {
                        Ok(node) => net.nodes.push(node),
                        Err(LoadError::Invalid(p)) => problems.push(p),
                        Err(e) => return Err(e),
                    }
                }
                let mut ids = std::collections::BTreeMap::new();
                for n in &net.nodes {
                    if let Some(first) = ids.insert(n.node_id, &n.name) {
                        problems.push(format!("{} and {} both have node id {}", first, n.name, n.node_id));
                    }
                }
                if problems.is_empty() { Ok(net) } else { Err(LoadError::Invalid(problems.join("\n"))) }
            }
        }
    }

    /// A network from a description file (device paths relative to it).
    ///
    /// Needs the feature `network-description` (it reads the description with the code
    /// generator's `od_codegen::network`, which names objects as generated code does); without
    /// it, the error says so.
    pub fn from_description(path: &Path) -> Result<Self, LoadError> {
        let text =
            std::fs::read_to_string(path).map_err(|error| LoadError::Io { path: path.display().to_string(), error })?;
        let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        Self::from_description_text(&path.display().to_string(), dir, &text)
    }

    /// A network from a description's text: `display` names it in messages, device paths are
    /// relative to `dir`.
    #[cfg(feature = "network-description")]
    pub fn from_description_text(display: &str, dir: &Path, text: &str) -> Result<Self, LoadError> {
        let outcome = od_codegen::network::build(display, dir, text);
        if outcome.has_errors() {
            return Err(LoadError::Invalid(od_codegen::network::render_all(&outcome.diagnostics)));
        }
        let mut net = Network { supervision: outcome.supervision, ..Network::default() };
        let mut problems = Vec::new();
        for dcf in outcome.dcfs {
            match concise::plan(&dcf.model, dcf.node_id) {
                Ok(plan) => {
                    let serial = dcf.model.commissioning.as_ref().and_then(|c| c.lss_serial_number);
                    net.nodes.push(BootNode {
                        name: dcf.name,
                        node_id: dcf.node_id,
                        device: dcf.device,
                        plan,
                        serial,
                        supervision: dcf.supervision,
                        lss: dcf.lss,
                        lss_store: dcf.lss_store,
                    })
                }
                Err(e) => problems.extend(e.iter().map(|p| format!("node `{}` ({}): {p}", dcf.name, dcf.device))),
            }
        }
        if problems.is_empty() { Ok(net) } else { Err(LoadError::Invalid(problems.join("\n"))) }
    }

    /// A network from a description's text: `display` names it in messages, device paths are
    /// relative to `dir`. This build has no feature `network-description`: always an error
    /// that says so (DCFs load without it, through [`Network::load`]).
    #[cfg(not(feature = "network-description"))]
    pub fn from_description_text(display: &str, dir: &Path, text: &str) -> Result<Self, LoadError> {
        let _ = (dir, text);
        Err(LoadError::Invalid(format!(
            "{display}: reading a network description needs od-master's feature `network-description` \
             (od-master = {{ version = \"...\", features = [\"network-description\"] }}); DCFs load without it"
        )))
    }

    /// One node from its DCF: the node id from `[DeviceComissioning]` `NodeID`.
    fn dcf(path: &Path) -> Result<BootNode, LoadError> {
        let shown = path.display().to_string();
        let parsed = eds::read_file(path, &eds::Options::lenient())
            .map_err(|error| LoadError::Io { path: shown.clone(), error })?;
        if parsed.has_errors() {
            let first = parsed.errors().next().map(|d| d.message.clone()).unwrap_or_default();
            return Err(LoadError::Invalid(format!(
                "{shown}: the DCF has {} error(s) (`odgen check {shown}` lists them); first: {first}",
                parsed.errors().count()
            )));
        }
        let model = parsed.model;
        let commissioning = model.commissioning.as_ref();
        let Some(node_id) = commissioning.and_then(|c| c.node_id).filter(|id| (1..=127).contains(id)) else {
            return Err(LoadError::Invalid(format!(
                "{shown}: no node id: a DCF names its node in [DeviceComissioning] NodeID (1..=127)"
            )));
        };
        let name = commissioning
            .and_then(|c| c.node_name.clone())
            .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .unwrap_or_else(|| format!("node {node_id}"));
        let plan = concise::plan(&model, node_id).map_err(|e| {
            LoadError::Invalid(e.iter().map(|p| format!("{shown}: {p}")).collect::<Vec<_>>().join("\n"))
        })?;
        let serial = commissioning.and_then(|c| c.lss_serial_number);
        Ok(BootNode {
            name,
            node_id,
            device: shown,
            plan,
            serial,
            lss: false,
            lss_store: true,
            supervision: NodeSupervision::default(),
        })
    }

    /// Takes the supervision settings of a master's DCF: 1F80h (NMT start-up) for the network,
    /// 1F81h sub N (NMT slave assignment) for node N, where the DCF gives a value
    /// (`ParameterValue`, else `DefaultValue`). Nodes the DCF does not list keep theirs.
    pub fn apply_master_dcf(&mut self, path: &Path) -> Result<(), LoadError> {
        let shown = path.display().to_string();
        let parsed = eds::read_file(path, &eds::Options::lenient())
            .map_err(|error| LoadError::Io { path: shown.clone(), error })?;
        if parsed.has_errors() {
            return Err(LoadError::Invalid(format!(
                "{shown}: the master's DCF has {} error(s) (`odgen check {shown}` lists them)",
                parsed.errors().count()
            )));
        }
        self.apply_master_model(&parsed.model);
        Ok(())
    }

    /// [`Network::apply_master_dcf`] on a model already read.
    pub fn apply_master_model(&mut self, model: &eds::Model) {
        let value = |index: u16, sub: u8| -> Option<u32> {
            let entry = model.objects.get(&eds::Index(index))?.subs.get(&eds::SubIndex(sub))?;
            let v = entry.parameter_value().or(entry.default.as_ref())?;
            u32::try_from(v.resolve(0)?).ok()
        };
        if let Some(v) = value(0x1F80, 0) {
            let attempts = self.supervision.boot_attempts;
            self.supervision = NetworkSupervision { boot_attempts: attempts, ..NetworkSupervision::from_1f80(v) };
            // 1F80h bit 3: the application starts the nodes, not the master.
            if v & (1 << 3) != 0 {
                self.nodes.iter_mut().for_each(|n| n.supervision.start = false);
            }
        }
        let stop_or_reset = self.supervision.on_mandatory_failure;
        for node in &mut self.nodes {
            if let Some(v) = value(0x1F81, node.node_id) {
                let start = node.supervision.start;
                node.supervision = NodeSupervision { start: start && v & 1 != 0, ..NodeSupervision::from_1f81(v) };
                if node.supervision.mandatory && stop_or_reset.is_network_wide() {
                    node.supervision.on_lost = stop_or_reset;
                }
            }
        }
    }
}

/// What [`boot`] does beyond configuring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BootOptions {
    /// Start the nodes (NMT start) once configured (default true).
    pub start: bool,
    /// Boot the nodes at the same time (default true), or one after another.
    pub concurrent: bool,
    /// The LSS step timeout for the nodes marked `lss = true` (default
    /// [`crate::lss::DEFAULT_TIMEOUT`], 20 ms; raise it on a loaded host or a slow gateway).
    pub lss_step_timeout: Duration,
}

impl Default for BootOptions {
    fn default() -> Self {
        Self { start: true, concurrent: true, lss_step_timeout: Duration::from_micros(crate::lss::DEFAULT_TIMEOUT) }
    }
}

/// The step of the boot a failure happened in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Reading 1000h and 1018h.
    Identity,
    /// Writing the configuration and the PDOs.
    Configure,
    /// The NMT commands (pre-operational before configuring, start after).
    Nmt,
    /// Giving the node its node-ID over LSS, before the rest (`lss = true`).
    Lss,
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Stage::Identity => "checking the identity",
            Stage::Configure => "writing the configuration",
            Stage::Nmt => "NMT",
            Stage::Lss => "LSS",
        })
    }
}

/// Why one node did not boot.
#[derive(Debug, thiserror::Error)]
pub enum BootError {
    /// The node is another device than the file says.
    #[error(
        "node {node} ({name}): wrong device: {index:04X}h:{sub} {what} is 0x{found:08X}, {device} expects 0x{expected:08X}"
    )]
    Identity {
        /// The node id.
        node: u8,
        /// The node's name.
        name: String,
        /// The file.
        device: String,
        /// 1000h or 1018h.
        index: u16,
        /// The sub-index.
        sub: u8,
        /// "vendor id", "product code", ...
        what: &'static str,
        /// The value the file expects.
        expected: u32,
        /// The value the node gave.
        found: u32,
    },
    /// The node was started and produces heartbeats (1017h), but none said Operational in
    /// time: CiA 302-2's "start error control" (its error K).
    #[error(
        "node {node} ({name}): no heartbeat saying Operational within {waited_ms} ms of the NMT start (1017h = {heartbeat_ms} ms)"
    )]
    NoHeartbeat {
        /// The node id.
        node: u8,
        /// The node's name.
        name: String,
        /// Its producer heartbeat time.
        heartbeat_ms: u16,
        /// How long boot waited.
        waited_ms: u64,
    },
    /// The node is marked for LSS (`lss = true`) and its device could not be given its
    /// node-ID: the error names the LSS step and the identity (a timeout of switch state
    /// selective: no device of that identity answers).
    #[error("node {node} ({name}): giving the device of serial number {serial} its node-ID over LSS failed: {error}")]
    Lss {
        /// The node id.
        node: u8,
        /// The node's name.
        name: String,
        /// The serial number the description gives.
        serial: u32,
        /// The LSS step's error (shared by every marked node when the scan itself failed).
        error: std::sync::Arc<Error>,
    },
    /// The node's device was given its node-ID over LSS but sent no boot-up with it.
    #[error(
        "node {node} ({name}): the device of serial number {serial} was given node-ID {node} over LSS \
         but sent no boot-up within {waited_ms} ms"
    )]
    NoBootUp {
        /// The node id.
        node: u8,
        /// The node's name.
        name: String,
        /// The serial number.
        serial: u32,
        /// How long boot waited.
        waited_ms: u64,
    },
    /// An SDO transfer or NMT command failed (the error names the node and the object).
    #[error("{name}, {stage}: {error}")]
    Bus {
        /// The node's name.
        name: String,
        /// Where in the boot.
        stage: Stage,
        /// The transfer's error.
        error: Error,
    },
}

impl BootError {
    /// CiA 302-2's letter for why a node's boot failed ("boot slave" error status), where one fits:
    /// `B` no answer reading 1000h, `C` 1000h differs, `D` 1018h:1 (vendor) differs, `M` 1018h:2
    /// (product) differs, `N` 1018h:3 (revision) differs, `J` configuration download failed, `K`
    /// no heartbeat in the start error control.
    pub fn reason_letter(&self) -> Option<char> {
        match self {
            BootError::Identity { index: 0x1000, .. } => Some('C'),
            BootError::Identity { index: 0x1018, sub: 1, .. } => Some('D'),
            BootError::Identity { index: 0x1018, sub: 2, .. } => Some('M'),
            BootError::Identity { index: 0x1018, sub: 3, .. } => Some('N'),
            BootError::Identity { .. } => None,
            BootError::NoHeartbeat { .. } => Some('K'),
            BootError::Bus { stage: Stage::Identity, .. } => Some('B'),
            BootError::Bus { stage: Stage::Configure, .. } => Some('J'),
            BootError::Bus { stage: Stage::Nmt | Stage::Lss, .. } => None,
            BootError::Lss { .. } | BootError::NoBootUp { .. } => None,
        }
    }

    /// The object the failure is about, if any.
    pub fn object(&self) -> Option<(u16, u8)> {
        match self {
            BootError::Identity { index, sub, .. } => Some((*index, *sub)),
            BootError::NoHeartbeat { .. } => Some((0x1017, 0)),
            BootError::Lss { .. } | BootError::NoBootUp { .. } => None,
            BootError::Bus { error: Error::Sdo { error, .. }, .. } => Some((error.index, error.sub)),
            BootError::Bus { error: Error::Length { index, sub, .. }, .. } => Some((*index, *sub)),
            BootError::Bus { .. } => None,
        }
    }
}

/// How one node's boot went.
#[derive(Debug)]
pub struct NodeReport {
    /// The node's name.
    pub name: String,
    /// Its node id.
    pub node_id: u8,
    /// Writes made (all of the plan's when it succeeded).
    pub written: usize,
    /// Writes the plan has.
    pub planned: usize,
    /// Whether an NMT start was sent to it (or to all nodes).
    pub started: bool,
    /// When the NMT start went out (before its heartbeat confirmed it), if it did.
    pub started_at: Option<Instant>,
    /// Configured, or why not.
    pub result: Result<(), BootError>,
}

/// Boots `network` on `bus`: see the [module](self) for the steps. One report per node, in the
/// network's order; an error of one node never stops another. [`boot_network`] says what the
/// LSS step found too.
pub async fn boot(bus: &Bus, network: &Network, options: &BootOptions) -> Vec<NodeReport> {
    boot_network(bus, network, options).await.nodes
}

/// How long [`boot`] waits for the boot-up of a device LSS gave a node-ID to (it sends it as
/// soon as it is back in waiting; the bound is for a slow bridge or a loaded host).
pub const LSS_BOOT_UP: Duration = Duration::from_millis(1000);

/// What [`boot_network`] did.
#[derive(Debug, Default)]
pub struct BootOutcome {
    /// The LSS step, when a node is marked `lss = true`: the devices given a node-ID, those
    /// already at theirs, and the devices without a node-ID the description does not name
    /// (found, not touched). Its `failed` list is empty: those nodes' reports say why.
    pub lss: Option<crate::lss::Commissioning>,
    /// One report per node, in the network's order.
    pub nodes: Vec<NodeReport>,
}

/// [`boot`], with what the LSS step did. The nodes the description marks for LSS (`lss =
/// true`, with `serial`) first get their node-ID ([`crate::lss::Lss::commission`], at
/// [`BootOptions::lss_step_timeout`]), and boot waits for the boot-up of each
/// one given a new node-ID ([`LSS_BOOT_UP`] at most); a node whose device cannot be given its
/// node-ID fails ([`BootError::Lss`], [`BootError::NoBootUp`]) and is not booted; the others
/// boot as usual. Nodes not marked are not touched by the LSS step.
pub async fn boot_network(bus: &Bus, network: &Network, options: &BootOptions) -> BootOutcome {
    let (lss, nodes) =
        boot_with_lss(bus, &network.nodes, options.concurrent, &|_| options.start, true, options.lss_step_timeout)
            .await;
    BootOutcome { lss, nodes }
}

/// [`commission`], then [`boot_nodes`] for the nodes it did not fail (one NMT start to all
/// only if none failed); one report per node of `nodes`, in their order.
pub(crate) async fn boot_with_lss(
    bus: &Bus,
    nodes: &[BootNode],
    concurrent: bool,
    start_it: &(dyn Fn(&BootNode) -> bool + Sync),
    all_at_once: bool,
    lss_step_timeout: Duration,
) -> (Option<crate::lss::Commissioning>, Vec<NodeReport>) {
    let (lss, mut failed) = commission(bus, nodes, lss_step_timeout).await;
    let ready: Vec<BootNode> =
        nodes.iter().enumerate().filter(|(i, _)| !failed.contains_key(i)).map(|(_, n)| n.clone()).collect();
    let all_at_once = all_at_once && failed.is_empty();
    let mut booted = boot_nodes(bus, &ready, concurrent, start_it, all_at_once).await.into_iter();
    let reports = nodes
        .iter()
        .enumerate()
        .filter_map(|(i, n)| match failed.remove(&i) {
            Some(error) => Some(NodeReport {
                name: n.name.clone(),
                node_id: n.node_id,
                written: 0,
                planned: n.plan.writes.len(),
                started: false,
                started_at: None,
                result: Err(error),
            }),
            None => booted.next(),
        })
        .collect();
    (lss, reports)
}

/// The LSS step of a boot: the marked nodes' devices given their node-ID, and the boot-ups of
/// those given a new one waited for. The nodes that failed, by their place in `nodes`.
async fn commission(
    bus: &Bus,
    nodes: &[BootNode],
    step_timeout: Duration,
) -> (Option<crate::lss::Commissioning>, BTreeMap<usize, BootError>) {
    use crate::lss::{Identity, Lss, LssNode};
    let mut failed = BTreeMap::new();
    let marked: Vec<(usize, &BootNode, LssNode)> = nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.lss)
        .filter_map(|(i, n)| {
            let id = &n.plan.identity;
            let serial = n.serial?;
            let identity = Identity { vendor: id.vendor_id, product: id.product_code, revision: id.revision, serial };
            Some((i, n, LssNode { identity, node_id: n.node_id, store: n.lss_store }))
        })
        .collect();
    if marked.is_empty() {
        return (None, failed);
    }
    let plan: Vec<LssNode> = marked.iter().map(|m| m.2).collect();
    // Subscribed before the first request: no boot-up is missed.
    let mut frames = bus.frames();
    let mut session = Lss::new(bus);
    session.set_timeout(step_timeout);
    let mut commissioning = match session.commission(&plan).await {
        Ok(c) => c,
        Err(error) => {
            // The scan itself failed: no marked node can be booted; each says why.
            let error = std::sync::Arc::new(error);
            for (i, node, p) in &marked {
                let error = error.clone();
                failed.insert(
                    *i,
                    BootError::Lss { node: node.node_id, name: node.name.clone(), serial: p.identity.serial, error },
                );
            }
            return (None, failed);
        }
    };
    for (p, error) in std::mem::take(&mut commissioning.failed) {
        if let Some((i, node, _)) = marked.iter().find(|m| m.2 == p) {
            let error = std::sync::Arc::new(error);
            failed.insert(
                *i,
                BootError::Lss { node: node.node_id, name: node.name.clone(), serial: p.identity.serial, error },
            );
        }
    }
    // Each device given a node-ID sends its boot-up (at once, or after its reset).
    let mut waiting: BTreeMap<u8, usize> = commissioning
        .assigned
        .iter()
        .filter_map(|a| marked.iter().find(|m| m.2.identity == a.0).map(|m| (a.1, m.0)))
        .collect();
    let started = Instant::now();
    let deadline = started + LSS_BOOT_UP;
    while !waiting.is_empty() {
        match tokio::time::timeout_at(deadline, frames.recv()).await {
            Ok(Ok(f)) => {
                if (0x701..=0x77F).contains(&f.id()) && f.data() == [0] {
                    waiting.remove(&((f.id() - 0x700) as u8));
                }
            }
            Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
            Ok(Err(broadcast::error::RecvError::Closed)) | Err(_) => break,
        }
    }
    for (node_id, i) in waiting {
        let node = &nodes[i];
        failed.insert(
            i,
            BootError::NoBootUp {
                node: node_id,
                name: node.name.clone(),
                serial: node.serial.unwrap_or(0),
                waited_ms: u64::try_from(LSS_BOOT_UP.as_millis()).unwrap_or(u64::MAX),
            },
        );
    }
    (Some(commissioning), failed)
}

/// Boots `nodes` as [`boot`] does, starting those `start_it` says; with `all_at_once`, one NMT
/// start to all nodes when every node was configured and is to be started (else one per node,
/// which leaves the nodes not given here untouched).
pub(crate) async fn boot_nodes(
    bus: &Bus,
    nodes: &[BootNode],
    concurrent: bool,
    start_it: &(dyn Fn(&BootNode) -> bool + Sync),
    all_at_once: bool,
) -> Vec<NodeReport> {
    let mut reports: Vec<NodeReport> = Vec::with_capacity(nodes.len());
    if concurrent {
        let mut tasks = tokio::task::JoinSet::new();
        for (i, node) in nodes.iter().enumerate() {
            let (bus, node) = (bus.clone(), node.clone());
            tasks.spawn(async move { (i, configure(&bus, &node).await) });
        }
        let mut done: Vec<Option<NodeReport>> = nodes.iter().map(|_| None).collect();
        while let Some(joined) = tasks.join_next().await {
            if let Ok((i, report)) = joined {
                done[i] = Some(report);
            }
        }
        for (slot, node) in done.into_iter().zip(nodes) {
            // A task that panicked (a bug) still gives its node a report.
            reports.push(slot.unwrap_or_else(|| NodeReport {
                name: node.name.clone(),
                node_id: node.node_id,
                written: 0,
                planned: node.plan.writes.len(),
                started: false,
                started_at: None,
                result: Err(BootError::Bus { name: node.name.clone(), stage: Stage::Configure, error: Error::Closed }),
            }));
        }
    } else {
        for node in nodes {
            reports.push(configure(bus, node).await);
        }
    }
    let wanted: Vec<bool> = nodes.iter().map(start_it).collect();
    if wanted.iter().any(|w| *w) {
        // Subscribed before the start, so that no heartbeat after it is missed.
        let mut frames = bus.frames();
        start(bus, &mut reports, &wanted, all_at_once).await;
        confirm(&mut frames, nodes, &mut reports).await;
    }
    reports
}

/// CiA 302-2's "start error control": each started node that produces heartbeats (1017h > 0)
/// sends one saying Operational within three of its periods (at least 100 ms), or its report
/// says it did not.
async fn confirm(frames: &mut broadcast::Receiver<CanFrame>, nodes: &[BootNode], reports: &mut [NodeReport]) {
    let now = Instant::now();
    let mut pending: BTreeMap<u8, (usize, u16, Instant)> = BTreeMap::new();
    for (i, (r, node)) in reports.iter().zip(nodes).enumerate() {
        if r.started && r.result.is_ok() && node.plan.heartbeat_ms > 0 {
            let wait = Duration::from_millis(u64::from(node.plan.heartbeat_ms) * 3).max(Duration::from_millis(100));
            pending.insert(r.node_id, (i, node.plan.heartbeat_ms, now + wait));
        }
    }
    while let Some(next) = pending.values().map(|p| p.2).min() {
        match tokio::time::timeout_at(next, frames.recv()).await {
            Ok(Ok(f)) => {
                let operational = f.data().first().is_some_and(|s| s & 0x7F == 0x05);
                if (0x701..=0x77F).contains(&f.id()) && f.data().len() == 1 && operational {
                    pending.remove(&((f.id() - 0x700) as u8));
                }
            }
            Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
            // The bus has closed: nothing more will come.
            Ok(Err(broadcast::error::RecvError::Closed)) => {
                for (i, ..) in std::mem::take(&mut pending).into_values() {
                    let r = &mut reports[i];
                    r.result = Err(BootError::Bus { name: r.name.clone(), stage: Stage::Nmt, error: Error::Closed });
                }
            }
            Err(_) => {
                let late: Vec<u8> = pending.iter().filter(|(_, p)| p.2 <= next).map(|(id, _)| *id).collect();
                for id in late {
                    let Some((i, heartbeat_ms, deadline)) = pending.remove(&id) else { continue };
                    let r = &mut reports[i];
                    r.result = Err(BootError::NoHeartbeat {
                        node: id,
                        name: r.name.clone(),
                        heartbeat_ms,
                        waited_ms: u64::try_from((deadline - now).as_millis()).unwrap_or(u64::MAX),
                    });
                }
            }
        }
    }
}

/// NMT start: to all nodes at once when all were configured (and `all_at_once`), else to each
/// configured one that is `wanted`.
async fn start(bus: &Bus, reports: &mut [NodeReport], wanted: &[bool], all_at_once: bool) {
    if all_at_once
        && !reports.is_empty()
        && wanted.iter().all(|w| *w)
        && reports.iter().all(|r| r.result.is_ok())
        && bus.nmt(NmtCommand::Start, Target::All).await.is_ok()
    {
        let at = Instant::now();
        reports.iter_mut().for_each(|r| {
            r.started = true;
            r.started_at = Some(at);
        });
        return;
    }
    // Some node failed (or the command to all could not be sent): each configured node on its
    // own, each with its own error.
    for (r, _) in reports.iter_mut().zip(wanted).filter(|(r, w)| r.result.is_ok() && **w) {
        let Some(id) = NodeId::new(r.node_id) else { continue };
        match bus.nmt(NmtCommand::Start, Target::Node(id)).await {
            Ok(()) => {
                r.started = true;
                r.started_at = Some(Instant::now());
            }
            Err(error) => r.result = Err(BootError::Bus { name: r.name.clone(), stage: Stage::Nmt, error }),
        }
    }
}

/// Checks one node's identity and writes its configuration.
async fn configure(bus: &Bus, boot: &BootNode) -> NodeReport {
    let mut report = NodeReport {
        name: boot.name.clone(),
        node_id: boot.node_id,
        written: 0,
        planned: boot.plan.writes.len(),
        started: false,
        started_at: None,
        result: Ok(()),
    };
    report.result = run(bus, boot, &mut report.written).await;
    report
}

async fn run(bus: &Bus, boot: &BootNode, written: &mut usize) -> Result<(), BootError> {
    let fail = |stage| move |error| BootError::Bus { name: boot.name.clone(), stage, error };
    let node = bus.node(boot.node_id).map_err(fail(Stage::Identity))?;
    for (index, sub, what, expected) in boot.plan.identity.checks() {
        if expected == 0 {
            continue;
        }
        let found = node.read::<u32>(index, sub).await.map_err(fail(Stage::Identity))?;
        if found != expected {
            return Err(BootError::Identity {
                node: boot.node_id,
                name: boot.name.clone(),
                device: boot.device.clone(),
                index,
                sub,
                what,
                expected,
                found,
            });
        }
    }
    node.pre_operational().await.map_err(fail(Stage::Nmt))?;
    for w in &boot.plan.writes {
        // Every write of a configuration leaves the same state when made twice (a COB-ID, a
        // count, a value): retried like a read after a lost answer.
        node.write_bytes_idempotent(w.index, w.sub, &w.data).await.map_err(fail(Stage::Configure))?;
        *written += 1;
    }
    Ok(())
}

/// The name of a write's role, as `--json` and the docs say it.
pub fn role_name(role: Role) -> &'static str {
    match role {
        Role::Parameter => "parameter",
        Role::PdoDisable => "pdo_disable",
        Role::PdoParameter => "pdo_parameter",
        Role::MappingClear => "mapping_clear",
        Role::MappingEntry => "mapping_entry",
        Role::MappingCount => "mapping_count",
        Role::PdoEnable => "pdo_enable",
    }
}
