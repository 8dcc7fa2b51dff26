//! The machines the simulated drives start with, and the named presets `drive-sim run
//! --machine NAME` knows (a file path gives a [`Machine`] description instead).
//!
//! | device | default | presets | machine unit (the power-on 6064h unit) |
//! |---|---|---|---|
//! | DRVI | `free`: 2014h = 0, "only motor" (manual 4.1.1, 6.3.6.10): a bare motor turning freely | `free`, `drvi-actuator` | 0.01° of the motor (an actuator shows positions through 6092h/6091h) |
//! | DRCS | `drcs-belt`: the belt axis its EDS defaults describe (607Dh, 6092h: 1000 mm stroke, 70 mm per turn) | `drcs-belt`, `free` (QSet "only motor") | mm (° for only motor) |
//! | AKD | `akd-linear`: limit switches at -1 and +2 turns, end stops at -2 and +3, a reference switch at 0.25..0.5 turn (the 7.2.1.7 and 7.2.1.8 homings need them) | `akd-linear`, `free` | motor turns |

use std::path::Path;

use crate::motion::{Machine, MachineError, Travel};
use crate::node::DeviceKind;

/// A named machine of a device.
#[derive(Clone, Debug, PartialEq)]
pub struct Preset {
    /// The name `--machine` takes.
    pub name: &'static str,
    /// One line for `--help`.
    pub description: &'static str,
    /// The machine.
    pub machine: Machine,
}

fn linear(name: &str) -> Machine {
    Machine { name: name.into(), travel: Travel::Linear, load_inertia: 1.0, ..Machine::free() }
}

/// The presets of `kind`, its default first.
pub fn presets(kind: DeviceKind) -> Vec<Preset> {
    let free = |description| Preset { name: "free", description, machine: Machine::free() };
    match kind {
        DeviceKind::Drvi => vec![
            free("a bare motor turning freely, as 2014h = 0 (only motor) says: no proximity, no end stops"),
            Preset {
                name: "drvi-actuator",
                description: "a motor with a proximity (PROXY INPUT) from 200.00 to 250.00 deg, end stops at -500.00 and 1500.00 deg, index every turn at 10.00 deg (an actuator shows them through 6092h/6091h)",
                machine: Machine {
                    home_switch: Some([20_000.0, 25_000.0]),
                    negative_end_stop: Some(-50_000.0),
                    positive_end_stop: Some(150_000.0),
                    index_period: Some(36_000.0),
                    index_phase: 1_000.0,
                    ..linear("drvi-actuator")
                },
            },
        ],
        DeviceKind::Drcs => vec![
            Preset {
                name: "drcs-belt",
                description: "a belt axis of 1000 mm stroke, 70 mm per turn: proximity from -140 to -100 mm, end stops at -150 and 910 mm",
                machine: Machine {
                    stroke: Some(1000.0),
                    home_switch: Some([-140.0, -100.0]),
                    negative_end_stop: Some(-150.0),
                    positive_end_stop: Some(910.0),
                    ..linear("drcs-belt")
                },
            },
            free("QSet \"only motor\": a bare motor turning freely, positions in degrees"),
        ],
        DeviceKind::Akd => vec![
            Preset {
                name: "akd-linear",
                description: "limit switches at -1 and +2 turns, end stops at -2 and +3, reference switch at 0.25..0.5 turn, index at 0.1",
                machine: Machine {
                    home_switch: Some([0.25, 0.5]),
                    negative_limit: Some(-1.0),
                    positive_limit: Some(2.0),
                    negative_end_stop: Some(-2.0),
                    positive_end_stop: Some(3.0),
                    index_phase: 0.1,
                    ..linear("akd-linear")
                },
            },
            free("a bare motor turning freely, index every turn"),
        ],
    }
}

/// The machine `kind` starts with (the first preset).
pub fn default_machine(kind: DeviceKind) -> Machine {
    presets(kind).remove(0).machine
}

/// The preset `name` of `kind`.
pub fn preset(kind: DeviceKind, name: &str) -> Option<Machine> {
    presets(kind).into_iter().find(|p| p.name == name).map(|p| p.machine)
}

/// What `--machine SPEC` means for `kind`: a preset's name, else a file.
pub fn resolve(kind: DeviceKind, spec: &str) -> Result<Machine, MachineError> {
    match preset(kind, spec) {
        Some(m) => Ok(m),
        None if !spec.contains(['/', '.']) && !Path::new(spec).exists() => Err(MachineError {
            file: spec.to_owned(),
            message: format!(
                "neither a file nor a preset of the {kind} (presets: {})",
                presets(kind).iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
            ),
        }),
        None => Machine::load(Path::new(spec)),
    }
}

/// The `drive-sim run --help` text on machines: each device's default and presets.
pub fn help() -> String {
    let mut out = String::from(
        "A machine around the motor of the preceding --device: a preset's name or a TOML file \
         (travel = \"rotary\" | \"linear\", load_inertia, home_switch = [low, high], \
         negative_limit, positive_limit, negative_end_stop, positive_end_stop, stroke, \
         index_period, index_phase; positions in the unit 6064h shows at power-on). \
         Without it each device starts with its default:",
    );
    for kind in DeviceKind::ALL {
        for (i, p) in presets(kind).iter().enumerate() {
            let default = if i == 0 { " (default)" } else { "" };
            out.push_str(&format!("\n  {kind} {}{default}: {}", p.name, p.description));
        }
    }
    out
}
