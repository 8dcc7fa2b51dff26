//! `od-master run`: a network booted, then kept running by `od_master::supervisor` until
//! Ctrl-C, one line (or JSON object) per event.

use std::io::Write as _;
use std::sync::Arc;

use od_master::supervisor::{BusState, Supervisor, SupervisorEvent};
use od_master::{Bus, Network};
use serde_json::json;
use tokio::sync::{Notify, broadcast};

/// Supervises `network` on `bus` until Ctrl-C or until a mandatory node cannot be booted
/// (after its policy ran): the error names those nodes.
pub async fn run(bus: Bus, network: Network, json: bool) -> Result<(), String> {
    let supervisor = Supervisor::new(bus, network);
    let mut events = supervisor.events();
    let failed = Arc::new(Notify::new());
    let failed_seen = Arc::clone(&failed);
    let printer = tokio::spawn(async move {
        loop {
            match events.recv().await {
                Ok(event) => {
                    print(&event, json);
                    if matches!(event, SupervisorEvent::MandatoryFailed { .. }) {
                        failed_seen.notify_one();
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    eprintln!("od-master: {n} events not shown (output too slow)")
                }
                Err(broadcast::error::RecvError::Closed) => return,
            }
        }
    });
    let shutdown = async move {
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            () = failed.notified() => {}
        }
    };
    let summary = supervisor.run(shutdown).await;
    // The supervisor is gone: the printer shows what is left and ends.
    let _ = printer.await;
    if summary.mandatory_failed.is_empty() {
        Ok(())
    } else {
        Err(format!("mandatory node(s) cannot be booted: {}", summary.mandatory_failed.join(", ")))
    }
}

fn print(event: &SupervisorEvent, json: bool) {
    // Written with errors ignored: a closed pipe ends the output, not the supervision.
    let mut out = std::io::stdout().lock();
    let _ = if json { writeln!(out, "{}", to_json(event)) } else { writeln!(out, "{event}") };
}

/// One event as a JSON object: `event` names it, node events carry `node` and `name`.
pub fn to_json(event: &SupervisorEvent) -> serde_json::Value {
    match event {
        SupervisorEvent::Booted { node, name, writes } => {
            json!({ "event": "booted", "node": node, "name": name, "writes": writes })
        }
        SupervisorEvent::KeptAlive { node, name } => json!({ "event": "kept_alive", "node": node, "name": name }),
        SupervisorEvent::Rebooted { node, name } => json!({ "event": "rebooted", "node": node, "name": name }),
        SupervisorEvent::Reconfigured { node, name, writes, elapsed, started } => json!({
            "event": "reconfigured", "node": node, "name": name, "writes": writes,
            "elapsed_ms": elapsed.as_secs_f64() * 1e3,
            "started_ms": started.map(|s| s.as_secs_f64() * 1e3),
        }),
        SupervisorEvent::BootFailed { node, name, step, object, reason, message } => json!({
            "event": "boot_failed", "node": node, "name": name, "step": step.to_string(),
            "index": object.map(|o| o.0), "subindex": object.map(|o| o.1),
            "reason": reason.map(|r| r.to_string()), "message": message,
        }),
        SupervisorEvent::Lost { node, name } => json!({ "event": "lost", "node": node, "name": name }),
        SupervisorEvent::Recovered { node, name, state } => {
            json!({ "event": "recovered", "node": node, "name": name, "state": format!("{state:?}") })
        }
        SupervisorEvent::Acted { node, name, action } => {
            json!({ "event": "acted", "node": node, "name": name, "action": action.name() })
        }
        SupervisorEvent::MandatoryFailed { node, name } => {
            json!({ "event": "mandatory_failed", "node": node, "name": name })
        }
        SupervisorEvent::Verified { node, name, objects } => {
            json!({ "event": "verified", "node": node, "name": name, "objects": objects })
        }
        SupervisorEvent::Bus(state) => {
            let (name, reason) = match state {
                BusState::ErrorActive => ("error_active", None),
                BusState::ErrorWarning => ("error_warning", None),
                BusState::ErrorPassive => ("error_passive", None),
                BusState::BusOff => ("bus_off", None),
                BusState::Restarted => ("restarted", None),
                BusState::LinkDown { reason } => ("link_down", Some(reason.clone())),
                BusState::LinkUp => ("link_up", None),
                BusState::Closed => ("closed", None),
            };
            json!({ "event": "bus", "state": name, "reason": reason })
        }
        SupervisorEvent::LssAssigned { node, name, serial } => {
            json!({ "event": "lss_assigned", "node": node, "name": name, "serial": serial })
        }
        SupervisorEvent::LssUnknown { identity } => json!({
            "event": "lss_unknown", "vendor": identity.vendor, "product": identity.product,
            "revision": identity.revision, "serial": identity.serial
        }),
        other => json!({ "event": "other", "text": other.to_string() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bus's own states as `--json` prints them (SocketCAN's controller states and
    /// socketcand's link), each with its name, the link down with its reason.
    #[test]
    fn bus_states_as_json_lines() {
        let table = [
            (BusState::ErrorWarning, json!({ "event": "bus", "state": "error_warning", "reason": null })),
            (BusState::ErrorPassive, json!({ "event": "bus", "state": "error_passive", "reason": null })),
            (BusState::BusOff, json!({ "event": "bus", "state": "bus_off", "reason": null })),
            (BusState::Restarted, json!({ "event": "bus", "state": "restarted", "reason": null })),
            (BusState::ErrorActive, json!({ "event": "bus", "state": "error_active", "reason": null })),
            (
                BusState::LinkDown { reason: "connection reset".into() },
                json!({ "event": "bus", "state": "link_down", "reason": "connection reset" }),
            ),
            (BusState::LinkUp, json!({ "event": "bus", "state": "link_up", "reason": null })),
        ];
        for (state, want) in table {
            assert_eq!(to_json(&SupervisorEvent::Bus(state.clone())), want, "{state:?}");
        }
        // And in words: what the controller did.
        assert_eq!(SupervisorEvent::Bus(BusState::BusOff).to_string(), "bus-off: the controller is off the bus");
    }
}
