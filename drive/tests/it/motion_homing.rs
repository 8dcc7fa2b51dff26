//! Homing: every method finds the right edge or index pulse and applies the offset.
//!
//! The axis (mechanical positions): negative end stop -60 000, negative limit switch active at
//! and below -50 000, positive limit switch at and above 50 000, positive end stop 60 000,
//! index pulses at 1000 + k · 4000. The home switch is a cam placed per test. The axis starts
//! at 0.

use crate::motion_common;

use drive::motion::{
    Axis, AxisConfig, Cam, Environment, HomeOffsetMode, HomingConfig, HomingError, HomingMethod, HomingState, Mode,
    PlantConfig,
};
use motion_common::run_until;

const POSITIVE_CAM: Cam = Cam { low: 10_000, high: 12_000 };
const NEGATIVE_CAM: Cam = Cam { low: -12_000, high: -10_000 };

fn environment(cam: Option<Cam>) -> Environment {
    Environment {
        home_switch: cam,
        negative_limit: Some(-50_000),
        positive_limit: Some(50_000),
        negative_end_stop: Some(-60_000),
        positive_end_stop: Some(60_000),
        index_period: 4000,
        index_phase: 1000,
    }
}

fn homing_config(method: HomingMethod) -> AxisConfig {
    AxisConfig {
        homing: HomingConfig {
            method,
            search_speed: 20_000,
            zero_speed: 2_000,
            acceleration: 200_000,
            deceleration: 200_000,
            ..HomingConfig::default()
        },
        ..AxisConfig::default()
    }
}

/// Homes and returns the axis and every status along the way.
fn home(cfg: AxisConfig, env: Environment, start: i32) -> (Axis, Vec<drive::motion::Status>) {
    let mut axis = Axis::with_environment(cfg, env);
    axis.set_actual_position(start, false);
    axis.set_power(true);
    axis.set_mode(Mode::Homing);
    axis.start_homing().expect("homing starts");
    let statuses = run_until(&mut axis, 1000, 60_000_000, |s| {
        matches!(s.homing, HomingState::Completed | HomingState::Error(_)) && s.standing
    });
    (axis, statuses)
}

/// The mechanical position the axis stands at: the environment knows it through the sensors,
/// so find it by moving a limit switch onto the axis.
fn mechanical_position(axis: &Axis) -> i64 {
    // Binary search on the positive limit switch position: active when m >= limit.
    let (mut lo, mut hi) = (-100_000i64, 100_000i64);
    while lo < hi {
        let mid = lo + (hi - lo + 1) / 2;
        let mut probe = axis.clone();
        probe.environment_mut().positive_limit = Some(mid);
        if probe.status().inputs.positive_limit { lo = mid } else { hi = mid - 1 }
    }
    lo
}

/// Homes with a home offset of 250 and checks that the axis completed homing standing on the
/// mechanical position `home_at`, which now reads 250.
fn assert_home(method: HomingMethod, cam: Option<Cam>, home_at: i64) -> Vec<drive::motion::Status> {
    let mut cfg = homing_config(method);
    cfg.homing.offset = 250;
    let (axis, statuses) = home(cfg, environment(cam), 0);
    let last = statuses.last().unwrap();
    assert_eq!(last.homing, HomingState::Completed, "method {}: {last:?}", method.code);
    assert!(last.homed && last.target_reached && last.standing);
    assert_eq!(last.position_actual, 250, "method {}", method.code);
    assert_eq!(mechanical_position(&axis), home_at, "method {}", method.code);
    statuses
}

fn camozzi(code: i8) -> HomingMethod {
    HomingMethod::camozzi(code).unwrap()
}

fn cia(code: i8) -> HomingMethod {
    HomingMethod::cia402(code).unwrap()
}

#[test]
fn camozzi_proximity_methods() {
    // 17/18: leave the proximity in the opposite direction; home where it turns off.
    let s = assert_home(camozzi(17), Some(NEGATIVE_CAM), -10_000);
    // The search ran at the fast speed, the exit at the slow one.
    assert_eq!(s.iter().map(|s| s.velocity_actual).min(), Some(-20_000));
    assert_home(camozzi(18), Some(POSITIVE_CAM), 10_000);
    // 1/2: then on to the next index pulse.
    assert_home(camozzi(1), Some(NEGATIVE_CAM), -7_000);
    assert_home(camozzi(2), Some(POSITIVE_CAM), 9_000);
    // 37: here.
    let s = assert_home(camozzi(37), None, 0);
    assert!(s.iter().all(|s| s.velocity_actual == 0));
}

#[test]
fn camozzi_torque_methods_push_against_the_end_stop() {
    for (code, home_at) in [(-3, -60_000), (-4, 60_000), (-1, -59_000), (-2, 57_000)] {
        let mut cfg = homing_config(camozzi(code));
        cfg.plant = PlantConfig { inertia: 0.001, ..PlantConfig::default() };
        cfg.max_torque = 5000;
        cfg.homing.torque_limit = 800;
        cfg.homing.torque_threshold = 700;
        cfg.homing.offset = 250;
        let (axis, statuses) = home(cfg, environment(None), 0);
        let last = statuses.last().unwrap();
        assert_eq!(last.homing, HomingState::Completed, "method {code}");
        assert_eq!(last.position_actual, 250);
        assert_eq!(mechanical_position(&axis), home_at, "method {code}");
        // Against the stop the current rose to the homing limit, never beyond.
        let dir = if matches!(code, -1 | -3) { -1 } else { 1 };
        let peak = statuses.iter().map(|s| s.torque_actual * dir).max().unwrap();
        assert_eq!(peak, 800, "method {code}");
        assert!(statuses.iter().any(|s| s.torque_limit_active && s.inputs.end_stop));
        assert_eq!(last.torque_actual, 0, "no torque once homed");
    }
}

#[test]
fn cia402_limit_switch_methods() {
    assert_home(cia(1), None, -47_000);
    assert_home(cia(2), None, 49_000);
    assert_home(cia(17), None, -50_000);
    assert_home(cia(18), None, 50_000);
}

#[test]
fn cia402_home_switch_methods_used_by_the_akd() {
    // 8: left edge approached from the left, then the index to its right.
    assert_home(cia(8), Some(POSITIVE_CAM), 13_000);
    // 24: the same edge, no index.
    assert_home(cia(24), Some(POSITIVE_CAM), 10_000);
    // 12 and 28 search negative; with the cam on the positive side they reverse at the negative
    // limit switch, then home on the cam's right edge approached from the right.
    assert_home(cia(12), Some(POSITIVE_CAM), 9_000);
    assert_home(cia(28), Some(POSITIVE_CAM), 12_000);
    // With the cam on the negative side no reversal is needed.
    assert_home(cia(28), Some(NEGATIVE_CAM), -10_000);
    assert_home(cia(12), Some(NEGATIVE_CAM), -11_000);
}

#[test]
fn cia402_other_home_switch_methods() {
    let positive_side = Some(Cam { low: 10_000, high: i64::MAX });
    let negative_side = Some(Cam { low: i64::MIN, high: -10_000 });
    assert_home(cia(3), positive_side, 9_000);
    assert_home(cia(4), positive_side, 13_000);
    assert_home(cia(5), negative_side, -7_000);
    assert_home(cia(6), negative_side, -11_000);
    assert_home(cia(7), Some(POSITIVE_CAM), 9_000);
    assert_home(cia(9), Some(POSITIVE_CAM), 9_000);
    assert_home(cia(10), Some(POSITIVE_CAM), 13_000);
    assert_home(cia(11), Some(NEGATIVE_CAM), -7_000);
    assert_home(cia(13), Some(NEGATIVE_CAM), -11_000);
    assert_home(cia(14), Some(NEGATIVE_CAM), -15_000);
    assert_home(cia(26), Some(POSITIVE_CAM), 12_000);
}

#[test]
fn cia402_index_and_current_position_methods() {
    assert_home(cia(33), None, -3_000);
    assert_home(cia(34), None, 1_000);
    assert_home(cia(35), None, 0);
    assert_home(cia(37), None, 0);
}

#[test]
fn starting_on_the_proximity_begins_with_the_slow_phase() {
    let mut cfg = homing_config(camozzi(18));
    cfg.homing.offset = 0;
    let mut axis = Axis::with_environment(cfg, environment(Some(POSITIVE_CAM)));
    // Move onto the cam first (11 000) in profile position mode.
    axis.config_mut().profile_velocity = 50_000;
    axis.config_mut().profile_acceleration = 500_000;
    axis.config_mut().profile_deceleration = 500_000;
    axis.set_power(true);
    axis.set_mode(Mode::ProfilePosition);
    motion_common::go_to(&mut axis, 11_000);
    run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert!(axis.status().inputs.home_switch);
    axis.set_mode(Mode::Homing);
    axis.start_homing().unwrap();
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.homing == HomingState::Completed);
    assert!(s.iter().all(|s| s.velocity_actual.abs() <= 2_000), "never faster than the slow speed");
    assert_eq!(mechanical_position(&axis), 10_000);
    assert_eq!(axis.status().position_actual, 0);
}

#[test]
fn offset_modes() {
    let run_with = |mode: HomeOffsetMode| {
        let mut cfg = homing_config(camozzi(18));
        cfg.homing.offset = 3_000;
        cfg.homing.offset_mode = mode;
        let (axis, s) = home(cfg, environment(Some(POSITIVE_CAM)), 0);
        assert_eq!(s.last().unwrap().homing, HomingState::Completed);
        (s.last().unwrap().position_actual, mechanical_position(&axis))
    };
    assert_eq!(run_with(HomeOffsetMode::AssignOffset), (3_000, 10_000));
    assert_eq!(run_with(HomeOffsetMode::AssignNegatedOffset), (-3_000, 10_000));
    // DRCS: move by the offset from the home point, make that zero.
    assert_eq!(run_with(HomeOffsetMode::MoveByOffset), (0, 13_000));
}

#[test]
fn homing_status_sequence() {
    let (_, s) = home(homing_config(camozzi(18)), environment(Some(POSITIVE_CAM)), 0);
    let states: Vec<HomingState> = s.iter().map(|s| s.homing).fold(Vec::new(), |mut v, h| {
        if v.last() != Some(&h) {
            v.push(h);
        }
        v
    });
    assert_eq!(states, [HomingState::InProgress, HomingState::Attained, HomingState::Completed]);
    // Statusword bits (10, 12, 13) over the run: in progress 000, attained 010, done 110.
    assert_eq!(s[0].homing.statusword_bits(s[0].standing), (false, false, false));
    let last = s.last().unwrap();
    assert_eq!(last.homing.statusword_bits(last.standing), (true, true, false));
    assert!(last.target_reached);
}

#[test]
fn proximity_overshoot_is_an_error_for_camozzi_methods() {
    let narrow = Some(Cam { low: 10_000, high: 10_050 });
    let mut cfg = homing_config(camozzi(18));
    cfg.homing.deceleration = 20_000; // 20 000²/(2·20 000) = 10 000 units to stop
    let (_, s) = home(cfg.clone(), environment(narrow), 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Error(HomingError::SwitchOvershoot));
    let last = s.last().unwrap();
    assert_eq!(last.homing.statusword_bits(last.standing), (true, false, true));
    // CiA 402 methods recover. 25 approaches the right edge from the right: stopping beyond
    // the cam already put the axis there.
    cfg.homing.method = cia(25);
    let (axis, s) = home(cfg.clone(), environment(narrow), 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Completed);
    assert_eq!(mechanical_position(&axis), 10_050);
    // 24 approaches the left edge from the left: it backs off through the cam first.
    cfg.homing.method = cia(24);
    let (axis, s) = home(cfg, environment(narrow), 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Completed);
    assert_eq!(mechanical_position(&axis), 10_000);
    assert!(s.iter().any(|s| s.velocity_actual == -20_000), "backed off at the fast speed");
}

#[test]
fn homing_errors() {
    // No proximity: the search reaches the limit switch.
    let (_, s) = home(homing_config(camozzi(18)), environment(None), 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Error(HomingError::NotFound));
    // No limit switch either: the end stop blocks the search.
    let mut env = environment(None);
    env.positive_limit = None;
    let (_, s) = home(homing_config(camozzi(18)), env, 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Error(HomingError::Blocked));
    // Nothing at all: the timeout.
    let mut cfg = homing_config(camozzi(18));
    cfg.homing.timeout_us = 2_000_000;
    let (_, s) = home(cfg, Environment::default(), 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Error(HomingError::Timeout));
    assert!(s.last().unwrap().time_us >= 2_000_000);
    // No index pulse on the encoder.
    let mut env = environment(Some(POSITIVE_CAM));
    env.index_period = 0;
    let (_, s) = home(homing_config(camozzi(2)), env, 0);
    assert_eq!(s.last().unwrap().homing, HomingState::Error(HomingError::NoIndexPulse));
    // Zero speeds are refused up front.
    let mut cfg = homing_config(camozzi(18));
    cfg.homing.zero_speed = 0;
    let mut axis = Axis::with_environment(cfg, environment(Some(POSITIVE_CAM)));
    axis.set_power(true);
    axis.set_mode(Mode::Homing);
    assert!(axis.start_homing().is_err());
    assert_eq!(axis.status().homing, HomingState::Error(HomingError::InvalidParameters));
}

#[test]
fn halt_interrupts_homing() {
    let mut axis = Axis::with_environment(homing_config(cia(18)), environment(None));
    axis.set_power(true);
    axis.set_mode(Mode::Homing);
    axis.start_homing().unwrap();
    run_until(&mut axis, 1000, 1_000_000, |s| s.velocity_actual == 20_000);
    axis.set_halt(true);
    let s = run_until(&mut axis, 1000, 1_000_000, |s| s.standing);
    let last = s.last().unwrap();
    assert_eq!(last.homing, HomingState::Interrupted);
    assert_eq!(last.homing.statusword_bits(last.standing), (true, false, false));
    assert!(!last.homed);
    // Not while halted; started again after the halt, it completes.
    assert_eq!(axis.start_homing(), Err(drive::motion::CommandError::Halted));
    axis.set_halt(false);
    axis.start_homing().unwrap();
    run_until(&mut axis, 1000, 10_000_000, |s| s.homing == HomingState::Completed);
    assert_eq!(mechanical_position(&axis), 50_000);
}
