//! Profile position: trapezoids, triangles, set-point handling, halt, quick stop, limits.

use crate::motion_common;

use drive::motion::{
    Axis, AxisConfig, CommandError, Mode, PlantConfig, QuickStopOption, RelativeBase, SetPoint, SoftwareLimits,
    StopRamp,
};
use motion_common::*;

/// Checks a move sampled every `dt_us`: velocity never above `vmax`, velocity changes no faster
/// than the larger of `acc`/`dec` (one raw unit of rounding), position changes no more than
/// `vmax · dt`, and the position never passes `target` (demand and actual).
fn check_move(statuses: &[drive::motion::Status], start: i32, target: i32, vmax: f64, acc: f64, dt_us: u32) {
    let dt = f64::from(dt_us) * 1e-6;
    let dir = (target - start).signum();
    let mut prev_v = 0i64;
    let mut prev_p = start;
    for s in statuses {
        let v = i64::from(s.velocity_actual);
        assert!((v as f64).abs() <= vmax + 0.5, "speed {v} above {vmax} at {}", s.time_us);
        assert!(((v - prev_v) as f64).abs() <= acc * dt + 1.0, "Δv {} at {}", v - prev_v, s.time_us);
        assert!(f64::from((s.position_actual - prev_p).abs()) <= vmax * dt + 1.0, "Δp at {}", s.time_us);
        for p in [s.position_actual, s.position_demand] {
            assert!((p - target) * dir <= 0, "overshoot {p} past {target} at {}", s.time_us);
        }
        prev_v = v;
        prev_p = s.position_actual;
    }
    let last = statuses.last().unwrap();
    assert_eq!(last.position_actual, target);
    assert_eq!(last.position_demand, target);
    assert_eq!(last.velocity_actual, 0);
    assert!(last.target_reached);
}

#[test]
fn trapezoid_reaches_target_exactly_within_limits() {
    for &(target, dt_us) in &[(1_000_000, 1000), (-777_777, 1000), (123_457, 250), (5_000_001, 4000), (999_999, 3333)] {
        let mut axis = enabled(plain(100_000, 250_000, 125_000), Mode::ProfilePosition);
        go_to(&mut axis, target);
        let statuses = run_until(&mut axis, dt_us, 120_000_000, |s| s.target_reached);
        check_move(&statuses, 0, target, 100_000.0, 250_000.0, dt_us);
        // The cruise runs at exactly the profile velocity for long moves.
        let peak = statuses.iter().map(|s| s.velocity_actual.abs()).max().unwrap();
        assert_eq!(peak, 100_000, "target {target}");
        // Duration = d/v + v/(2a) + v/(2d) (rounded up to a step).
        let d = f64::from(target.abs());
        let expected = d / 1e5 + 1e5 / 5e5 + 1e5 / 2.5e5;
        let took = statuses.last().unwrap().time_us as f64 * 1e-6;
        assert!(
            took >= expected - 1e-9 && took < expected + f64::from(dt_us) * 1e-6 + 1e-9,
            "took {took}, expected {expected}"
        );
    }
}

#[test]
fn drvi_figure_4_2_positioning_profile() {
    // 720° at 60 rpm, 60 rpm/s: 1 s acceleration (180°), 1 s at 60 rpm (360°), 1 s deceleration.
    let cfg = AxisConfig {
        units: drvi_motor_units(),
        profile_velocity: 6000,
        profile_acceleration: 60,
        profile_deceleration: 60,
        ..AxisConfig::default()
    };
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    go_to(&mut axis, 72_000);
    let statuses = run(&mut axis, 1000, 3100);
    let at = |ms: usize| statuses[ms - 1];
    assert_eq!(at(1000).position_actual, 18_000);
    assert_eq!(at(1000).velocity_actual, 6000);
    assert_eq!(at(2000).position_actual, 54_000);
    assert_eq!(at(3000).position_actual, 72_000);
    assert!(at(3000).target_reached);
    assert!(!at(2999).target_reached);
    assert_eq!(at(500).velocity_actual, 3000);
}

#[test]
fn triangular_profile_for_short_moves() {
    // d = 10 000, a = d = 100 000 units/s²: vp = sqrt(a·d) = 31 623 < vmax 100 000, 2·vp/a s.
    let mut axis = enabled(plain(100_000, 100_000, 100_000), Mode::ProfilePosition);
    go_to(&mut axis, 10_000);
    let statuses = run_until(&mut axis, 100, 10_000_000, |s| s.target_reached);
    check_move(&statuses, 0, 10_000, 100_000.0, 100_000.0, 100);
    let peak = statuses.iter().map(|s| s.velocity_actual).max().unwrap();
    assert!((31_500..=31_623).contains(&peak), "peak {peak}");
    let took = statuses.last().unwrap().time_us;
    assert!((632_400..=632_500).contains(&took), "took {took}");
    // Asymmetric: a = 4 d. vp² = 2·a·d·dist/(a + d).
    let mut axis = enabled(plain(100_000, 400_000, 100_000), Mode::ProfilePosition);
    go_to(&mut axis, 10_000);
    let statuses = run_until(&mut axis, 100, 10_000_000, |s| s.target_reached);
    check_move(&statuses, 0, 10_000, 100_000.0, 400_000.0, 100);
    let peak = statuses.iter().map(|s| s.velocity_actual).max().unwrap();
    let vp = (2.0f64 * 4e5 * 1e5 * 1e4 / 5e5).sqrt();
    assert!((f64::from(peak) - vp).abs() <= 40.0, "peak {peak} vs {vp}");
}

#[test]
fn relative_targets() {
    let mut axis = enabled(plain(10_000, 100_000, 100_000), Mode::ProfilePosition);
    go_to(&mut axis, 1000);
    run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    axis.new_set_point(SetPoint { target: 500, relative: true, ..SetPoint::default() }).unwrap();
    axis.release_set_point();
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 1500);
    // Relative to the previous target even while moving (CiA 402) ...
    go_to(&mut axis, 5000);
    run(&mut axis, 1000, 10);
    axis.new_set_point(SetPoint { target: 100, relative: true, change_immediately: true, ..SetPoint::default() })
        .unwrap();
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 5100);
    // ... or to the actual position (DRVI 4.1.2.1).
    axis.config_mut().relative_base = RelativeBase::ActualPosition;
    axis.new_set_point(SetPoint { target: -100, relative: true, ..SetPoint::default() }).unwrap();
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 5000);
}

#[test]
fn change_immediately_replans_from_the_current_motion() {
    let mut axis = enabled(plain(10_000, 20_000, 20_000), Mode::ProfilePosition);
    go_to(&mut axis, 100_000);
    let before = run(&mut axis, 1000, 1000);
    let v = before.last().unwrap().velocity_actual;
    assert_eq!(v, 10_000);
    // Reverse to -1000: decelerate (0.5 s, 2500 units), come back.
    axis.new_set_point(SetPoint { target: -1000, change_immediately: true, ..SetPoint::default() }).unwrap();
    let after = run_until(&mut axis, 1000, 10_000_000, |s| s.target_reached);
    let max_p = after.iter().map(|s| s.position_actual).max().unwrap();
    let p0 = before.last().unwrap().position_actual;
    assert_eq!(max_p, p0 + 2500);
    assert_eq!(after.last().unwrap().position_actual, -1000);
    // Velocity is continuous through the change.
    assert!((after[0].velocity_actual - v).abs() <= 20);
}

#[test]
fn buffered_set_point_waits_and_acknowledge_handshake() {
    let mut axis = enabled(plain(10_000, 100_000, 100_000), Mode::ProfilePosition);
    assert!(!axis.status().set_point_acknowledge);
    axis.new_set_point(SetPoint { target: 5000, ..SetPoint::default() }).unwrap();
    assert!(axis.status().set_point_acknowledge);
    axis.release_set_point();
    assert!(!axis.status().set_point_acknowledge);
    run(&mut axis, 1000, 100);
    // A second set-point while moving is buffered: ack stays high while it waits.
    axis.new_set_point(SetPoint { target: 8000, ..SetPoint::default() }).unwrap();
    axis.release_set_point();
    assert!(axis.status().set_point_acknowledge);
    // A third is refused: the buffer holds one.
    assert_eq!(axis.new_set_point(SetPoint { target: 1, ..SetPoint::default() }), Err(CommandError::Busy));
    let s = run_until(&mut axis, 1000, 10_000_000, |s| !s.set_point_acknowledge);
    // The first move stopped on 5000 before the buffered one started.
    let at_first = s.last().unwrap();
    assert_eq!(at_first.position_actual, 5000);
    assert!(!at_first.target_reached);
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 8000);
}

#[test]
fn change_on_set_point_blends_through_the_first_target() {
    let mut axis = enabled(plain(10_000, 100_000, 100_000), Mode::ProfilePosition);
    go_to(&mut axis, 5000);
    run(&mut axis, 1000, 100);
    axis.new_set_point(SetPoint { target: 8000, change_on_set_point: true, ..SetPoint::default() }).unwrap();
    axis.release_set_point();
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.target_reached);
    // Passing 5000 at full speed: the speed never drops between the two targets.
    let through = s.iter().find(|s| s.position_actual >= 5000).unwrap();
    assert_eq!(through.velocity_actual, 10_000);
    assert_eq!(s.last().unwrap().position_actual, 8000);
    // 0.1 s ramp + 0.8 s cruise + 0.05 s down + 0.05 s ... total for 8000 at 10 000/s ≈ 0.9 s.
    assert!(s.last().unwrap().time_us <= 910_000, "{}", s.last().unwrap().time_us);
}

#[test]
fn halt_stops_with_deceleration_and_resumes() {
    let mut axis = enabled(plain(10_000, 100_000, 50_000), Mode::ProfilePosition);
    go_to(&mut axis, 50_000);
    run(&mut axis, 1000, 500);
    let p0 = axis.status().position_actual;
    axis.set_halt(true);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.standing);
    // v²/(2d) = 10 000² / 100 000 = 1000.
    assert_eq!(s.last().unwrap().position_actual - p0, 1000);
    assert!(s.last().unwrap().target_reached, "with halt, target reached means standing");
    run(&mut axis, 1000, 100);
    axis.set_halt(false);
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 50_000);
}

#[test]
fn quick_stop_distance_is_v_squared_over_2d() {
    for &(v, d, qs) in &[(10_000u32, 20_000u32, 5_000u32), (123_456, 1_000_000, 333_333), (7, 100, 3)] {
        let mut cfg = plain(v, d, d);
        cfg.quick_stop_deceleration = qs;
        let mut axis = enabled(cfg, Mode::ProfilePosition);
        go_to(&mut axis, i32::MAX / 2);
        run_until(&mut axis, 1000, 60_000_000, |s| s.velocity_actual == v as i32);
        run(&mut axis, 1000, 10);
        let p0 = axis.status().position_actual;
        let opt = QuickStopOption::from_code(6).unwrap();
        axis.quick_stop(opt.ramp);
        let s = run_until(&mut axis, 1000, 60_000_000, |s| s.quick_stop_complete);
        let expected = f64::from(v) * f64::from(v) / (2.0 * f64::from(qs));
        let got = f64::from(s.last().unwrap().position_actual - p0);
        assert!((got - expected).abs() <= 1.0, "v {v} qs {qs}: {got} vs {expected}");
        // Commands are refused until the quick stop is released.
        assert_eq!(axis.new_set_point(SetPoint::default()), Err(CommandError::Stopping));
        axis.release_quick_stop();
        assert!(axis.status().target_reached);
        go_to(&mut axis, 0);
    }
}

#[test]
fn stop_ramps_follow_option_codes() {
    let distance = |ramp: StopRamp| {
        let mut cfg = plain(10_000, 100_000, 50_000);
        cfg.quick_stop_deceleration = 200_000;
        cfg.plant = PlantConfig { inertia: 0.01, ..PlantConfig::default() };
        cfg.max_torque = 10_000; // 1 000 000 units/s²
        let mut axis = enabled(cfg, Mode::ProfilePosition);
        go_to(&mut axis, 1_000_000);
        run(&mut axis, 1000, 500);
        let p0 = axis.status().position_actual;
        axis.quick_stop(ramp);
        let s = run_until(&mut axis, 100, 5_000_000, |s| s.quick_stop_complete);
        s.last().unwrap().position_actual - p0
    };
    assert_eq!(distance(StopRamp::ProfileDeceleration), 1000);
    assert_eq!(distance(StopRamp::QuickStopDeceleration), 250);
    assert_eq!(distance(StopRamp::TorqueLimit), 50);
    assert_eq!(StopRamp::from_option_code(2), Some(StopRamp::QuickStopDeceleration));
}

#[test]
fn power_off_coasts_and_friction_stops_the_axis() {
    let mut cfg = plain(10_000, 100_000, 100_000);
    cfg.plant = PlantConfig { inertia: 0.01, coulomb: 200.0, ..PlantConfig::default() }; // 20 000 units/s²
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    go_to(&mut axis, 1_000_000);
    run(&mut axis, 1000, 500);
    let p0 = axis.status().position_actual;
    axis.set_power(false);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.velocity_actual == 0);
    let last = s.last().unwrap();
    assert_eq!(last.torque_actual, 0);
    assert!(((last.position_actual - p0) - 2500).abs() <= 10, "{}", last.position_actual - p0);
    // Back on: the demand starts where the axis is.
    axis.set_power(true);
    axis.step(1000);
    assert_eq!(axis.status().position_demand, axis.status().position_actual);
    assert_eq!(axis.status().following_error, 0);
}

#[test]
fn brake_holds_the_axis() {
    let mut axis = enabled(plain(10_000, 100_000, 100_000), Mode::ProfilePosition);
    axis.set_brake(true);
    go_to(&mut axis, 10_000);
    let s = run(&mut axis, 1000, 100);
    assert!(s.iter().all(|s| s.position_actual == 0 && s.velocity_actual == 0));
    assert!(s.last().unwrap().following_error > 0);
}

#[test]
fn software_limits_clip_targets() {
    let mut cfg = plain(10_000, 100_000, 100_000);
    cfg.software_limits = SoftwareLimits { enabled: true, min: -2000, max: 3000 };
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    go_to(&mut axis, 10_000);
    assert!(axis.status().internal_limit_active);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 3000);
    go_to(&mut axis, 0);
    assert!(!axis.status().internal_limit_active);
    axis.new_set_point(SetPoint { target: -9000, relative: true, ..SetPoint::default() }).unwrap();
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, -2000);
}

#[test]
fn refused_commands() {
    let mut axis = Axis::new(plain(10_000, 100_000, 100_000));
    axis.set_mode(Mode::ProfilePosition);
    assert_eq!(axis.new_set_point(SetPoint::default()), Err(CommandError::PowerOff));
    axis.set_power(true);
    axis.set_mode(Mode::ProfileVelocity);
    assert_eq!(axis.new_set_point(SetPoint::default()), Err(CommandError::WrongMode));
    axis.set_mode(Mode::ProfilePosition);
    axis.config_mut().profile_acceleration = 0;
    assert_eq!(axis.new_set_point(SetPoint { target: 5, ..SetPoint::default() }), Err(CommandError::InvalidProfile));
    assert!(!axis.status().set_point_acknowledge);
}

#[test]
fn position_window_and_time_delay_target_reached() {
    let mut cfg = plain(10_000, 100_000, 100_000);
    cfg.position_window = 5;
    cfg.position_window_time_ms = 20;
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    go_to(&mut axis, 2000);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    // The move takes 0.3 s; target reached comes 20 ms after the axis is within 5 units.
    let t_in = s.iter().find(|s| (s.position_actual - 2000).abs() <= 5).unwrap().time_us;
    assert_eq!(s.last().unwrap().time_us, t_in + 20_000 - 1000);
}

#[test]
fn torque_saturation_makes_a_following_error() {
    let mut cfg = plain(100_000, 1_000_000, 1_000_000);
    cfg.plant = PlantConfig { inertia: 0.001, ..PlantConfig::default() }; // 1 000 000 needs 1000
    cfg.max_torque = 500;
    cfg.following_error_window = 100;
    cfg.following_error_timeout_ms = 10;
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    go_to(&mut axis, 200_000);
    let s = run(&mut axis, 1000, 100);
    assert!(s.iter().any(|s| s.torque_limit_active));
    assert!(s.iter().all(|s| s.torque_actual.abs() <= 500));
    let worst = s.iter().map(|s| s.following_error.abs()).max().unwrap();
    assert!(worst > 100, "following error {worst}");
    assert!(s.iter().any(|s| s.following_error_exceeded));
    // The loop catches up once the demand is feasible again and ends exactly on target.
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.target_reached && s.standing);
    assert_eq!(s.last().unwrap().position_actual, 200_000);
    assert_eq!(s.last().unwrap().following_error, 0);
}
