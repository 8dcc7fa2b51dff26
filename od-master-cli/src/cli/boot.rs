//! `od-master boot`: a network description or DCFs booted (see `od_master::boot`), one line
//! (or JSON object) per node; `--plan` prints what would be written, without a bus.

use std::io::Write as _;
use std::path::PathBuf;

use od_master::boot::{self, BootError, BootOptions, Network, NodeReport};
use serde_json::json;

use super::value::hex;

/// The network of `files`: one `.toml` description, or DCFs. The error is the whole message
/// (every problem of the description).
pub fn load(files: &[PathBuf]) -> Result<Network, String> {
    Network::load(files).map_err(|e| e.to_string())
}

/// The plan of every node: what `boot` checks and writes, in order.
pub fn print_plan(network: &Network, json: bool) {
    // Written with errors ignored: a closed pipe (`| head`) ends the output, not the program.
    let mut out = std::io::stdout().lock();
    for node in &network.nodes {
        let p = &node.plan;
        if json {
            let writes: Vec<_> = p
                .writes
                .iter()
                .map(|w| json!({ "index": w.index, "sub": w.sub, "data": w.data, "role": boot::role_name(w.role) }))
                .collect();
            let identity: Vec<_> = p
                .identity
                .checks()
                .iter()
                .filter(|c| c.3 != 0)
                .map(|&(index, sub, what, value)| json!({ "index": index, "subindex": sub, "name": what, "value": value }))
                .collect();
            let _ = writeln!(
                out,
                "{}",
                json!({ "node": node.node_id, "name": node.name, "device": node.device, "identity": identity, "writes": writes })
            );
        } else {
            let _ = writeln!(out, "{} (node {}, {}): {} writes", node.name, node.node_id, node.device, p.writes.len());
            for (index, sub, what, value) in p.identity.checks() {
                if value != 0 {
                    let _ = writeln!(out, "  check {index:04X}h:{sub} {what} = 0x{value:08X}");
                }
            }
            for w in &p.writes {
                let _ = writeln!(
                    out,
                    "  write {:04X}h:{} = {} ({})",
                    w.index,
                    w.sub,
                    hex(&w.data),
                    boot::role_name(w.role)
                );
            }
        }
    }
}

/// Boots the network and prints one line per node; true when every node booted.
pub async fn run(bus: &od_master::Bus, network: &Network, options: &BootOptions, json: bool) -> bool {
    let outcome = boot::boot_network(bus, network, options).await;
    let reports = outcome.nodes;
    let mut out = std::io::stdout().lock();
    // The LSS step first (nodes marked `lss = true`): who got a node-ID, unknown devices found.
    if let Some(lss) = &outcome.lss {
        for (id, node, had) in &lss.assigned {
            let name = network.nodes.iter().find(|n| n.node_id == *node).map_or("", |n| n.name.as_str());
            if json {
                let _ = writeln!(
                    out,
                    "{}",
                    json!({ "lss": "assigned", "node": node, "name": name, "serial": id.serial, "had": had })
                );
            } else {
                let had = had.map_or("none".to_owned(), |h| h.to_string());
                let _ = writeln!(out, "{name} (node {node}): node-ID given over LSS (serial {}, had {had})", id.serial);
            }
        }
        if let Some(e) = &lss.scan_error {
            if json {
                let _ = writeln!(out, "{}", json!({ "lss": "scan_failed", "error": e.to_string() }));
            } else {
                eprintln!("od-master: LSS: the search for devices the description does not name failed: {e}");
            }
        }
        for id in &lss.unknown {
            if json {
                let _ = writeln!(
                    out,
                    "{}",
                    json!({ "lss": "unknown", "vendor": id.vendor, "product": id.product, "revision": id.revision, "serial": id.serial })
                );
            } else {
                let _ = writeln!(
                    out,
                    "LSS: unknown device without a node-ID ({id}): not in the description, left as it is"
                );
            }
        }
    }
    for r in &reports {
        let device = network.nodes.iter().find(|n| n.node_id == r.node_id).map(|n| n.device.as_str()).unwrap_or("");
        if json {
            let _ = writeln!(out, "{}", report_json(r, device));
            continue;
        }
        match &r.result {
            Ok(()) => {
                let started = if r.started { "started" } else { "not started" };
                let _ = writeln!(out, "{} (node {}): {} writes, {started}", r.name, r.node_id, r.written);
            }
            // A failure on standard error, one line naming the node and the object.
            Err(e) => eprintln!("od-master: {e}"),
        }
    }
    reports.iter().all(|r| r.result.is_ok())
}

fn report_json(r: &NodeReport, device: &str) -> serde_json::Value {
    let (index, sub) = match r.result.as_ref().err().and_then(BootError::object) {
        Some((i, s)) => (Some(i), Some(s)),
        None => (None, None),
    };
    let stage = match &r.result {
        Err(BootError::Identity { .. }) => Some(boot::Stage::Identity.to_string()),
        Err(BootError::Bus { stage, .. }) => Some(stage.to_string()),
        Err(BootError::NoHeartbeat { .. }) => Some(boot::Stage::Nmt.to_string()),
        Err(BootError::Lss { .. } | BootError::NoBootUp { .. }) => Some(boot::Stage::Lss.to_string()),
        Ok(()) => None,
    };
    json!({
        "node": r.node_id,
        "name": r.name,
        "device": device,
        "ok": r.result.is_ok(),
        "written": r.written,
        "planned": r.planned,
        "started": r.started,
        "error": r.result.as_ref().err().map(|e| e.to_string()),
        "stage": stage,
        "index": index,
        "subindex": sub,
    })
}
