//! The mechanics: a rigid axis with inertia and friction, sensors along its travel, hard end
//! stops, an encoder index and a holding brake.
//!
//! Everything here lives in the *mechanical frame*: the encoder count at power-on is 0 and
//! positive is the motor's positive direction. Homing and polarity define the drive's own frame
//! on top of it (see [`crate::motion::Axis`]).

use super::units::{POSITION_LIMIT, TORQUE_LIMIT, VELOCITY_LIMIT, clamp_finite};

/// A home switch (proximity, reference cam): active while the position is within `low..=high`.
///
/// A switch that is active on a whole side (the "positive home switch" of CiA 402 methods 3 and 4)
/// is a cam with `high = i64::MAX`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cam {
    /// Lowest active position.
    pub low: i64,
    /// Highest active position.
    pub high: i64,
}

impl Cam {
    fn active(&self, m: f64) -> bool {
        m >= self.low as f64 && m <= self.high as f64
    }
}

/// What is mounted along the axis, in mechanical position units.
///
/// The default has nothing: no switches, no end stops, no index pulse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Environment {
    /// The home switch (DRVI "PROXY HOMING", DRCS "Proxy home", AKD reference switch).
    pub home_switch: Option<Cam>,
    /// The negative limit switch, active at and below this position.
    pub negative_limit: Option<i64>,
    /// The positive limit switch, active at and above this position.
    pub positive_limit: Option<i64>,
    /// A hard end stop: the axis cannot go below this position.
    pub negative_end_stop: Option<i64>,
    /// A hard end stop: the axis cannot go above this position.
    pub positive_end_stop: Option<i64>,
    /// Distance between two encoder index pulses (increments per revolution); 0 = no index.
    pub index_period: u64,
    /// Position of one index pulse; the others are at `index_phase + k * index_period`.
    pub index_phase: i64,
}

/// The sensors an axis can be asked about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Sensor {
    Home,
    NegativeLimit,
    PositiveLimit,
}

impl Environment {
    /// Whether `sensor` is active at mechanical position `m`.
    pub(crate) fn active(&self, sensor: Sensor, m: f64) -> bool {
        match sensor {
            Sensor::Home => self.home_switch.is_some_and(|c| c.active(m)),
            Sensor::NegativeLimit => self.negative_limit.is_some_and(|l| m <= l as f64),
            Sensor::PositiveLimit => self.positive_limit.is_some_and(|l| m >= l as f64),
        }
    }

    /// The positions where `sensor` changes state, as `(position, becomes_active_when_moving_up)`.
    fn boundaries(&self, sensor: Sensor) -> [Option<f64>; 2] {
        match sensor {
            Sensor::Home => match self.home_switch {
                Some(c) => [Some(c.low as f64), Some(c.high as f64)],
                None => [None, None],
            },
            Sensor::NegativeLimit => [self.negative_limit.map(|l| l as f64), None],
            Sensor::PositiveLimit => [self.positive_limit.map(|l| l as f64), None],
        }
    }

    /// The state changes of `sensor` while moving from `from` to `to`, in the order they happen:
    /// `(exact position of the switching point, new state)`. At most two (crossing a whole cam).
    pub(crate) fn edges(&self, sensor: Sensor, from: f64, to: f64) -> ([(f64, bool); 2], usize) {
        let mut out = [(0.0, false); 2];
        let mut n = 0;
        if from == to {
            return (out, 0);
        }
        let up = to > from;
        let mut points = self.boundaries(sensor);
        if !up {
            points.swap(0, 1);
        }
        let (lo, hi) = if up { (from, to) } else { (to, from) };
        let mut state = self.active(sensor, from);
        for b in points.into_iter().flatten() {
            if b < lo || b > hi {
                continue;
            }
            // The state just past the boundary, never beyond the end of the travel.
            let step = (b.abs() * 1e-12).max(1e-9);
            let probe = if up { (b + step).min(to) } else { (b - step).max(to) };
            let now = self.active(sensor, probe);
            if now != state && n < 2 {
                out[n] = (b, now);
                n += 1;
                state = now;
            }
        }
        (out, n)
    }

    /// The first index pulse strictly beyond `from` in direction `dir` (±1), if the axis has one.
    pub(crate) fn next_index(&self, from: f64, dir: f64) -> Option<f64> {
        if self.index_period == 0 {
            return None;
        }
        let n = self.index_period as f64;
        let phase = self.index_phase as f64;
        let k = (from - phase) / n;
        let k = if dir > 0.0 {
            let c = k.ceil();
            if phase + c * n <= from { c + 1.0 } else { c }
        } else {
            let f = k.floor();
            if phase + f * n >= from { f - 1.0 } else { f }
        };
        let p = phase + k * n;
        p.is_finite().then_some(p)
    }

    /// Whether an index pulse lies in the half-open interval travelled from `from` to `to`.
    pub(crate) fn index_crossed(&self, from: f64, to: f64) -> bool {
        if from == to {
            return false;
        }
        let dir = if to > from { 1.0 } else { -1.0 };
        self.next_index(from, dir).is_some_and(|p| (p - to) * dir <= 0.0)
    }
}

/// Mechanical constants and the recovery loop of the servo.
///
/// The torque unit is the device's raw torque unit (mA, per mille, ...). The defaults describe an
/// almost ideal drive: a tiny inertia, no friction and a torque limit so high it never acts, so
/// the axis follows the demand exactly. Configure realistic values to see following errors,
/// torque saturation and coasting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantConfig {
    /// Torque needed per position unit/s² of acceleration (inertia).
    pub inertia: f64,
    /// Viscous friction: torque per position unit/s.
    pub viscous: f64,
    /// Coulomb (dry) friction torque; also the torque needed to break away from standstill.
    pub coulomb: f64,
    /// Bandwidth of the position loop that recovers from disturbances, rad/s (limited to half
    /// the step rate for stability).
    pub bandwidth: f64,
    /// The motor's top speed in position units/s (torque mode cannot exceed it); 0 = no limit.
    pub max_speed: f64,
}

impl Default for PlantConfig {
    fn default() -> Self {
        PlantConfig { inertia: 1e-6, viscous: 0.0, coulomb: 0.0, bandwidth: 300.0, max_speed: 0.0 }
    }
}

impl PlantConfig {
    fn inertia(&self) -> f64 {
        if self.inertia.is_finite() && self.inertia > 0.0 { self.inertia.min(1e9) } else { 1e-6 }
    }

    fn non_negative(x: f64) -> f64 {
        if x.is_finite() && x > 0.0 { x.min(1e12) } else { 0.0 }
    }

    /// Friction torque at velocity `v` (position units/s); at standstill the dry part acts
    /// against `dir`, the direction the axis is pushed.
    pub(crate) fn drag(&self, v: f64, dir: f64) -> f64 {
        let towards = if v != 0.0 { v } else { dir };
        Self::non_negative(self.viscous) * v + Self::non_negative(self.coulomb) * sign(towards)
    }

    fn coulomb(&self) -> f64 {
        Self::non_negative(self.coulomb)
    }

    fn viscous(&self) -> f64 {
        Self::non_negative(self.viscous)
    }

    pub(crate) fn max_speed(&self) -> f64 {
        Self::non_negative(self.max_speed)
    }
}

/// How the torque is decided in a physics step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Drive {
    /// Power stage off: no torque, the axis coasts.
    Off,
    /// Follow a position/velocity demand (mechanical frame): `p0, v0` at the start of the
    /// step, `p, v` at its end, `a` the feed-forward acceleration between them.
    Track { p0: f64, v0: f64, p: f64, v: f64, a: f64 },
    /// Apply this torque (torque mode).
    Torque(f64),
}

/// The mechanical state.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Plant {
    /// Position (mechanical frame, position units).
    pub(crate) m: f64,
    /// Velocity (position units/s).
    pub(crate) v: f64,
    /// Torque the motor produces (raw torque units).
    pub(crate) torque: f64,
    /// Torque the controller asked for before the limit.
    pub(crate) torque_demand: f64,
    /// True while the axis follows the demand exactly (no loop error to recover).
    pub(crate) tracking: bool,
    /// The brake holds the axis.
    pub(crate) brake: bool,
    /// The axis is pressed against an end stop.
    pub(crate) at_end_stop: bool,
    /// The torque was limited during the last step.
    pub(crate) torque_limited: bool,
}

impl Plant {
    pub(crate) fn new() -> Self {
        Plant {
            m: 0.0,
            v: 0.0,
            torque: 0.0,
            torque_demand: 0.0,
            tracking: true,
            brake: false,
            at_end_stop: false,
            torque_limited: false,
        }
    }

    /// Advances the mechanics by `dt` seconds.
    ///
    /// `limit` is the torque limit (magnitude). With `Drive::Track` the axis follows the demand
    /// exactly when the torque needed stays within the limit and nothing blocks it; otherwise a
    /// position loop with the feed-forward acceleration drives a physical integration until the
    /// error is gone.
    pub(crate) fn step(
        &mut self,
        cfg: &PlantConfig,
        env: &Environment,
        drive: Drive,
        limit: f64,
        dt: f64,
        sat: &mut bool,
    ) {
        let j = cfg.inertia();
        let limit = if limit.is_finite() { limit.clamp(0.0, TORQUE_LIMIT) } else { TORQUE_LIMIT };
        self.torque_limited = false;
        match drive {
            Drive::Track { p, v, a, .. } if self.tracking && !self.brake => {
                // Torque for the average acceleration over the step, plus friction at the end speed.
                let acc = (v - self.v) / dt;
                let need = j * acc + cfg.drag(v, a);
                let blocked = env.negative_end_stop.is_some_and(|s| p < s as f64)
                    || env.positive_end_stop.is_some_and(|s| p > s as f64);
                if need.abs() <= limit && !blocked {
                    self.m = clamp_finite(p, POSITION_LIMIT, sat);
                    self.v = clamp_finite(v, VELOCITY_LIMIT, sat);
                    self.torque = clamp_finite(need, TORQUE_LIMIT, sat);
                    self.torque_demand = self.torque;
                    self.at_end_stop = false;
                    return;
                }
                self.tracking = false;
                self.physics(cfg, env, drive, limit, j, dt, sat);
            }
            _ => self.physics(cfg, env, drive, limit, j, dt, sat),
        }
        if let Drive::Track { p, v, .. } = drive
            && !self.brake
            && (p - self.m).abs() < 1e-6
            && (v - self.v).abs() < 1e-6
        {
            // The loop has caught up: follow exactly again.
            self.m = p;
            self.v = v;
            self.tracking = true;
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn physics(
        &mut self,
        cfg: &PlantConfig,
        env: &Environment,
        drive: Drive,
        limit: f64,
        j: f64,
        dt: f64,
        sat: &mut bool,
    ) {
        let omega = cfg.bandwidth.clamp(1.0, 1e6).min(0.5 / dt);
        let demand = match drive {
            Drive::Off => 0.0,
            Drive::Torque(t) => t,
            Drive::Track { p0, v0, a, .. } => {
                // The loop acts on the error at the start of the step; the feed-forward carries
                // the demand through it. The position error asks for a correcting speed that
                // is linear near zero and follows the braking curve of half the available
                // acceleration further out, so a saturated loop closes the gap without
                // overshooting instead of winding up.
                let e = p0 - self.m;
                let a_avail = (0.5 * limit / j).max(1e-9);
                let v_corr = sign(e) * (omega * e.abs()).min((2.0 * a_avail * e.abs()).sqrt());
                let a_cmd = a + 2.0 * omega * (v0 + v_corr - self.v);
                j * a_cmd + cfg.drag(self.v, a_cmd)
            }
        };
        let demand = clamp_finite(demand, TORQUE_LIMIT, sat);
        let mut torque = demand.clamp(-limit, limit);
        if torque != demand {
            self.torque_limited = true;
        }
        // Torque mode respects the motor's top speed: no torque beyond what holds it there.
        let vmax = cfg.max_speed();
        if matches!(drive, Drive::Torque(_)) && vmax > 0.0 && self.v.abs() >= vmax && torque * self.v > 0.0 {
            let hold = cfg.drag(self.v, self.v);
            if torque.abs() > hold.abs() {
                torque = hold;
            }
        }
        self.torque_demand = demand;
        self.torque = torque;
        if self.brake {
            self.v = 0.0;
            self.at_end_stop = false;
            return;
        }
        // Integrate, viscous friction implicitly (stable for any step); dry friction cannot
        // reverse the motion on its own.
        let v0 = self.v;
        let dry = cfg.coulomb();
        let drive_net = if v0 == 0.0 {
            if torque.abs() <= dry { 0.0 } else { torque - dry * sign(torque) }
        } else {
            torque - dry * sign(v0)
        };
        let mut v1 = (v0 + drive_net / j * dt) / (1.0 + cfg.viscous() / j * dt);
        if v0 != 0.0 && sign(v1) != sign(v0) && (sign(torque) != sign(v1) || torque.abs() <= dry) {
            v1 = 0.0;
        }
        let v1 = clamp_finite(v1, VELOCITY_LIMIT, sat);
        let mut m1 = clamp_finite(self.m + 0.5 * (v0 + v1) * dt, POSITION_LIMIT, sat);
        let mut v1 = v1;
        self.at_end_stop = false;
        if let Some(s) = env.negative_end_stop.map(|s| s as f64)
            && m1 <= s
            && (m1 < s || v1 <= 0.0)
        {
            m1 = s;
            v1 = v1.max(0.0);
            self.at_end_stop = torque < 0.0 || v0 < 0.0;
        }
        if let Some(s) = env.positive_end_stop.map(|s| s as f64)
            && m1 >= s
            && (m1 > s || v1 >= 0.0)
        {
            m1 = s;
            v1 = v1.min(0.0);
            self.at_end_stop = torque > 0.0 || v0 > 0.0;
        }
        self.m = m1;
        self.v = v1;
    }
}

fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cam_edges_in_travel_order() {
        let env = Environment { home_switch: Some(Cam { low: 100, high: 200 }), ..Default::default() };
        let (e, n) = env.edges(Sensor::Home, 0.0, 300.0);
        assert_eq!(&e[..n], &[(100.0, true), (200.0, false)]);
        let (e, n) = env.edges(Sensor::Home, 300.0, 150.0);
        assert_eq!(&e[..n], &[(200.0, true)]);
        let (e, n) = env.edges(Sensor::Home, 150.0, 160.0);
        assert_eq!(n, 0, "{:?}", &e[..n]);
    }

    #[test]
    fn limit_edges() {
        let env = Environment { negative_limit: Some(-50), positive_limit: Some(50), ..Default::default() };
        let (e, n) = env.edges(Sensor::NegativeLimit, 0.0, -60.0);
        assert_eq!(&e[..n], &[(-50.0, true)]);
        let (e, n) = env.edges(Sensor::NegativeLimit, -60.0, -40.0);
        assert_eq!(&e[..n], &[(-50.0, false)]);
        let (e, n) = env.edges(Sensor::PositiveLimit, 0.0, 50.0);
        assert_eq!(&e[..n], &[(50.0, true)]);
    }

    #[test]
    fn index_positions() {
        let env = Environment { index_period: 1000, index_phase: 250, ..Default::default() };
        assert_eq!(env.next_index(0.0, 1.0), Some(250.0));
        assert_eq!(env.next_index(250.0, 1.0), Some(1250.0));
        assert_eq!(env.next_index(250.0, -1.0), Some(-750.0));
        assert_eq!(env.next_index(-100.0, -1.0), Some(-750.0));
        assert!(env.index_crossed(200.0, 250.0));
        assert!(!env.index_crossed(250.0, 300.0));
        assert_eq!(Environment::default().next_index(0.0, 1.0), None);
    }

    #[test]
    fn end_stop_blocks_and_torque_saturates() {
        let env = Environment { positive_end_stop: Some(10), ..Default::default() };
        let cfg = PlantConfig { inertia: 1.0, ..Default::default() };
        let mut plant = Plant::new();
        let mut sat = false;
        for i in 1..=2000 {
            let t = i as f64 * 1e-3;
            let drive = Drive::Track { p0: 100.0 * (t - 1e-3), v0: 100.0, p: 100.0 * t, v: 100.0, a: 0.0 };
            plant.step(&cfg, &env, drive, 500.0, 1e-3, &mut sat);
        }
        assert_eq!(plant.m, 10.0);
        assert_eq!(plant.v, 0.0);
        assert_eq!(plant.torque, 500.0);
        assert!(plant.at_end_stop && plant.torque_limited && !sat);
    }

    #[test]
    fn coasting_stops_by_friction() {
        let env = Environment::default();
        let cfg = PlantConfig { inertia: 1.0, coulomb: 10.0, ..Default::default() };
        let mut plant = Plant { v: 100.0, tracking: false, ..Plant::new() };
        let mut sat = false;
        for _ in 0..20_000 {
            plant.step(&cfg, &env, Drive::Off, 1000.0, 1e-3, &mut sat);
        }
        assert_eq!(plant.v, 0.0);
        // v²/(2 a) = 100² / 20 = 500.
        assert!((plant.m - 500.0).abs() < 0.2, "{}", plant.m);
    }
}
