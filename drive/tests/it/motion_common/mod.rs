//! Helpers shared by the motion tests.
#![allow(dead_code)]

use drive::motion::{Axis, AxisConfig, Mode, Ratio, SetPoint, Status, Units};

/// The DRVI in its "only motor" configuration: 0.01°, 0.01 rpm (= 6 units/s), rpm/s (= 600
/// units/s²).
pub fn drvi_motor_units() -> Units {
    Units { velocity: Ratio::new(6, 1), acceleration: Ratio::new(600, 1) }
}

/// Velocity and acceleration in position units (per second, per second squared).
pub fn plain(vmax: u32, acc: u32, dec: u32) -> AxisConfig {
    AxisConfig { profile_velocity: vmax, profile_acceleration: acc, profile_deceleration: dec, ..AxisConfig::default() }
}

/// An axis powered on in `mode`.
pub fn enabled(cfg: AxisConfig, mode: Mode) -> Axis {
    let mut axis = Axis::new(cfg);
    axis.set_power(true);
    axis.set_mode(mode);
    axis
}

/// Sends an absolute set-point and releases bit 4 (the usual handshake).
pub fn go_to(axis: &mut Axis, target: i32) {
    axis.new_set_point(SetPoint { target, ..SetPoint::default() }).expect("set-point accepted");
    axis.release_set_point();
}

/// Steps `dt_us` until `done` holds or `limit_us` of simulated time passed; returns every status.
pub fn run_until(axis: &mut Axis, dt_us: u32, limit_us: u64, mut done: impl FnMut(&Status) -> bool) -> Vec<Status> {
    let start = axis.status().time_us;
    let mut out = Vec::new();
    loop {
        axis.step(dt_us);
        let s = axis.status();
        out.push(s);
        if done(&s) {
            return out;
        }
        assert!(s.time_us - start < limit_us, "not done after {limit_us} µs: {s:?}");
    }
}

/// Steps `n` times.
pub fn run(axis: &mut Axis, dt_us: u32, n: usize) -> Vec<Status> {
    (0..n)
        .map(|_| {
            axis.step(dt_us);
            axis.status()
        })
        .collect()
}
