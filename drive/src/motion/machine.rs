//! The machine around a drive's motor: free rotation, or a linear travel with a home switch,
//! limit switches and hard end stops, and the load's inertia. What `drive-sim run --machine`
//! reads (a TOML file or a preset's name) and what each drive turns into its
//! [`Environment`] and plant.
//!
//! Positions are in the drive's *machine unit*, the position unit its 6064h shows at power-on
//! with the default parameters (AKD: motor turns; DRVI: 0.01° of the motor; DRCS: mm or °), so a
//! file reads as the drive's documentation does. Each drive says how many of its internal
//! counts a machine unit is, and how many machine units a motor turn is (the default distance
//! between two encoder index pulses).
//!
//! ```
//! use drive::motion::{Machine, Travel};
//!
//! let m = Machine::parse("axis.toml", r#"
//!     name = "a short axis"
//!     travel = "linear"
//!     load_inertia = 2.0
//!     home_switch = [0.25, 0.5]
//!     negative_limit = -1.0
//!     positive_limit = 2.0
//!     negative_end_stop = -2.0
//!     positive_end_stop = 3.0
//! "#).unwrap();
//! assert_eq!(m.travel, Travel::Linear);
//! // 1000 counts per machine unit, one unit per motor turn.
//! let env = m.environment(1000.0, 1.0);
//! assert_eq!((env.negative_end_stop, env.positive_end_stop), (Some(-2000), Some(3000)));
//! assert_eq!(env.index_period, 1000);
//! // Free rotation has no end stops: a file that gives one is an error.
//! let e = Machine::parse("free.toml", "travel = \"rotary\"\npositive_end_stop = 3.0").unwrap_err();
//! assert!(e.to_string().contains("rotary"), "{e}");
//! ```

use std::path::Path;

use serde::Deserialize;

use super::plant::{Cam, Environment};

/// How the load moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Travel {
    /// The motor (and its load) turns freely: no limit switches, no end stops.
    Rotary,
    /// A travel with ends: limit switches and hard end stops where the file puts them.
    Linear,
}

/// A machine description (see the module documentation).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// A name for messages and `drive-sim run --help`.
    #[serde(default)]
    pub name: String,
    /// Free rotation or a linear travel.
    pub travel: Travel,
    /// The load's inertia reflected to the motor shaft, as a multiple of the motor's own
    /// (0: a bare motor). The drives' built-in mechanics are a motor with a load of its own
    /// inertia, 1, the default.
    #[serde(default = "one")]
    pub load_inertia: f64,
    /// Linear: the usable stroke from the home point (the DRCS shows it in 607Dh sub 2).
    #[serde(default)]
    pub stroke: Option<f64>,
    /// The home switch (reference cam, proximity), active from the first to the second
    /// position.
    #[serde(default)]
    pub home_switch: Option<[f64; 2]>,
    /// Linear: the negative limit switch, active at and below this position.
    #[serde(default)]
    pub negative_limit: Option<f64>,
    /// Linear: the positive limit switch, active at and above this position.
    #[serde(default)]
    pub positive_limit: Option<f64>,
    /// Linear: the hard end stop below.
    #[serde(default)]
    pub negative_end_stop: Option<f64>,
    /// Linear: the hard end stop above.
    #[serde(default)]
    pub positive_end_stop: Option<f64>,
    /// Distance between two encoder index pulses (default: one motor turn; 0: no index).
    #[serde(default)]
    pub index_period: Option<f64>,
    /// Position of one index pulse.
    #[serde(default)]
    pub index_phase: f64,
}

fn one() -> f64 {
    1.0
}

/// A machine description that cannot be used.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct MachineError {
    /// The file (or preset) it came from.
    pub file: String,
    /// What is wrong, with the line and column where TOML gives them.
    pub message: String,
}

/// The largest position a machine file may give, in machine units.
pub const POSITION_LIMIT: f64 = 1e9;

impl Machine {
    /// A machine that turns freely, a bare motor (no load) with an index every turn.
    pub fn free() -> Machine {
        Machine {
            name: "free".into(),
            travel: Travel::Rotary,
            load_inertia: 0.0,
            stroke: None,
            home_switch: None,
            negative_limit: None,
            positive_limit: None,
            negative_end_stop: None,
            positive_end_stop: None,
            index_period: None,
            index_phase: 0.0,
        }
    }

    /// Reads a machine description from TOML text; `file` names it in errors.
    pub fn parse(file: &str, text: &str) -> Result<Machine, MachineError> {
        let error = |message: String| MachineError { file: file.to_owned(), message };
        let machine: Machine = toml::from_str(text).map_err(|e| error(e.to_string().trim_end().to_owned()))?;
        machine.check().map_err(error)?;
        Ok(machine)
    }

    /// Reads a machine description from a file.
    pub fn load(path: &Path) -> Result<Machine, MachineError> {
        let file = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|e| MachineError { file: file.clone(), message: e.to_string() })?;
        Machine::parse(&file, &text)
    }

    /// The rules a description must follow: finite numbers within ±1e9 machine units,
    /// ordered pairs, nothing with ends on a rotary machine.
    pub fn check(&self) -> Result<(), String> {
        let positions = [
            ("negative_limit", self.negative_limit),
            ("positive_limit", self.positive_limit),
            ("negative_end_stop", self.negative_end_stop),
            ("positive_end_stop", self.positive_end_stop),
            ("stroke", self.stroke),
            ("index_period", self.index_period),
            ("index_phase", Some(self.index_phase)),
            ("home_switch", self.home_switch.map(|c| c[0])),
            ("home_switch", self.home_switch.map(|c| c[1])),
        ];
        for (name, v) in positions {
            if let Some(v) = v
                && !(v.is_finite() && v.abs() <= POSITION_LIMIT)
            {
                return Err(format!("{name} = {v}: a finite position within ±{POSITION_LIMIT:e} is needed"));
            }
        }
        if !(self.load_inertia.is_finite() && (0.0..=1e6).contains(&self.load_inertia)) {
            return Err(format!("load_inertia = {}: 0 (a bare motor) up to 1e6 is needed", self.load_inertia));
        }
        if self.travel == Travel::Rotary {
            let ends = [
                ("negative_limit", self.negative_limit.is_some()),
                ("positive_limit", self.positive_limit.is_some()),
                ("negative_end_stop", self.negative_end_stop.is_some()),
                ("positive_end_stop", self.positive_end_stop.is_some()),
                ("stroke", self.stroke.is_some()),
            ];
            if let Some((name, _)) = ends.iter().find(|(_, given)| *given) {
                return Err(format!("a rotary machine turns freely and has no {name}: use travel = \"linear\""));
            }
        }
        let ordered = |a: Option<f64>, b: Option<f64>, what: &str| match (a, b) {
            (Some(a), Some(b)) if a >= b => {
                Err(format!("{what}: the negative one ({a}) must be below the positive one ({b})"))
            }
            _ => Ok(()),
        };
        ordered(self.negative_limit, self.positive_limit, "limit switches")?;
        ordered(self.negative_end_stop, self.positive_end_stop, "end stops")?;
        ordered(self.negative_end_stop, self.negative_limit, "negative end stop and limit switch")?;
        ordered(self.positive_limit, self.positive_end_stop, "positive limit switch and end stop")?;
        if let Some([low, high]) = self.home_switch
            && low > high
        {
            return Err(format!("home_switch = [{low}, {high}]: the first position must not be above the second"));
        }
        if self.stroke.is_some_and(|s| s <= 0.0) {
            return Err("stroke must be above 0".into());
        }
        if self.index_period.is_some_and(|p| p < 0.0) {
            return Err("index_period must not be negative (0: no index)".into());
        }
        Ok(())
    }

    /// The switches, end stops and index in the drive's counts: `counts_per_unit` counts per
    /// machine unit, `units_per_turn` machine units per motor turn (the default index period).
    pub fn environment(&self, counts_per_unit: f64, units_per_turn: f64) -> Environment {
        let at = |x: f64| (x * counts_per_unit).round() as i64;
        let period = self.index_period.unwrap_or(units_per_turn) * counts_per_unit;
        Environment {
            home_switch: self.home_switch.map(|[low, high]| Cam { low: at(low), high: at(high) }),
            negative_limit: self.negative_limit.map(at),
            positive_limit: self.positive_limit.map(at),
            negative_end_stop: self.negative_end_stop.map(at),
            positive_end_stop: self.positive_end_stop.map(at),
            index_period: if period.is_finite() && period >= 1.0 { period.round() as u64 } else { 0 },
            index_phase: at(self.index_phase),
        }
    }

    /// The factor on the drives' built-in inertia (a motor with a load of its own inertia):
    /// `(1 + load_inertia) / 2`.
    pub fn inertia_factor(&self) -> f64 {
        (1.0 + self.load_inertia) / 2.0
    }

    /// The machine as TOML (what `parse` reads back).
    pub fn to_toml(&self) -> String {
        let mut out = String::new();
        if !self.name.is_empty() {
            out.push_str(&format!("name = {:?}\n", self.name));
        }
        let travel = match self.travel {
            Travel::Rotary => "rotary",
            Travel::Linear => "linear",
        };
        out.push_str(&format!("travel = \"{travel}\"\nload_inertia = {:?}\n", self.load_inertia));
        let mut put = |name: &str, v: Option<f64>| {
            if let Some(v) = v {
                out.push_str(&format!("{name} = {v:?}\n"));
            }
        };
        put("stroke", self.stroke);
        put("negative_limit", self.negative_limit);
        put("positive_limit", self.positive_limit);
        put("negative_end_stop", self.negative_end_stop);
        put("positive_end_stop", self.positive_end_stop);
        put("index_period", self.index_period);
        put("index_phase", Some(self.index_phase));
        if let Some([low, high]) = self.home_switch {
            out.push_str(&format!("home_switch = [{low:?}, {high:?}]\n"));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_descriptions_are_errors_with_their_reason() {
        let bad = [
            ("travel = \"linear\"\nnegative_end_stop = 5.0\npositive_end_stop = 1.0", "end stops"),
            ("travel = \"linear\"\nnegative_limit = -1.0\nnegative_end_stop = 0.0", "negative end stop"),
            ("travel = \"rotary\"\nnegative_limit = -1.0", "rotary"),
            ("travel = \"linear\"\nload_inertia = -1.0", "load_inertia"),
            ("travel = \"linear\"\npositive_end_stop = 1e300", "finite position"),
            ("travel = \"linear\"\nhome_switch = [2.0, 1.0]", "home_switch"),
            ("travel = \"sideways\"", "unknown variant"),
            ("travel = \"linear\"\nspeed = 3", "unknown field"),
            ("load_inertia = 1.0", "travel"),
            ("travel = \"linear\"\nstroke = 0.0", "stroke"),
        ];
        for (text, want) in bad {
            let e = Machine::parse("m.toml", text).unwrap_err().to_string();
            assert!(e.starts_with("m.toml: ") && e.contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn a_description_round_trips_through_toml() {
        let mut m = Machine::free();
        assert_eq!(Machine::parse("x", &m.to_toml()).unwrap(), m);
        m.travel = Travel::Linear;
        m.negative_end_stop = Some(-2.5);
        m.positive_end_stop = Some(3.0);
        m.home_switch = Some([0.25, 0.5]);
        m.stroke = Some(2.0);
        m.index_period = Some(0.0);
        assert_eq!(Machine::parse("x", &m.to_toml()).unwrap(), m);
        let env = m.environment(4.0, 1.0);
        assert_eq!(env.negative_end_stop, Some(-10));
        assert_eq!(env.index_period, 0, "0: no index");
    }

    #[test]
    fn free_rotation_has_nothing_to_hit() {
        let env = Machine::free().environment(1000.0, 2.0);
        assert_eq!(env, Environment { index_period: 2000, ..Environment::default() });
        assert_eq!(Machine::free().inertia_factor(), 0.5);
    }
}
