//! Simulated drives on the in-memory bus, moved in step with tokio's (paused) clock.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive::drives::DeviceApps;
use drive::node::{DeviceKind, NodeConfig, Sim};
use od_master::{Bus, Config};

/// How far the simulation moves between two looks at the bus: the latency of a simulated
/// node's answer.
pub const STEP: Duration = Duration::from_micros(200);

/// The simulation and the master on its bus.
pub struct Net {
    pub bus: Bus,
    pub sim: Arc<Mutex<Sim>>,
}

pub fn node(kind: DeviceKind, id: u8) -> Box<dyn drive::node::AnyNode> {
    kind.build(&NodeConfig { node_id: Some(id), ..Default::default() }, &DeviceApps::new()).expect("a simulated node")
}

/// `nodes` on a fresh simulation with a master on its bus; to be called in a runtime with a
/// paused clock (`#[tokio::test(start_paused = true)]`). The nodes boot at the first step.
pub fn net(nodes: &[(DeviceKind, u8)]) -> Net {
    net_with(nodes, Config::default())
}

pub fn net_with(nodes: &[(DeviceKind, u8)], config: Config) -> Net {
    let mut sim = Sim::new();
    for &(kind, id) in nodes {
        sim.add(node(kind, id));
    }
    let (bus, sim) = drive::node::spawn_with_master(sim, config, STEP);
    Net { bus, sim }
}

/// The sidecar of a device of ours (`kollmorgen-akd`, `camozzi-drvi`, ...).
pub fn sidecar(name: &str) -> od_sidecar::Sidecar {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../devices/{name}.toml"));
    od_sidecar::Sidecar::read(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Lets `d` of virtual time pass.
pub async fn pass(d: Duration) {
    tokio::time::sleep(d).await;
}
