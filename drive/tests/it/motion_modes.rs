//! Profile velocity, profile torque, jog, interpolated position, mode changes.

use crate::motion_common;

use drive::motion::{
    Axis, AxisConfig, CommandError, InterpolationConfig, JogCommand, JogState, Mode, PlantConfig, SoftwareLimits,
    StopRamp,
};
use motion_common::*;

fn drvi_velocity() -> AxisConfig {
    AxisConfig {
        units: drvi_motor_units(),
        profile_acceleration: 60,
        profile_deceleration: 60,
        velocity_window: 10,
        velocity_window_time_ms: 5,
        velocity_threshold: 5,
        velocity_threshold_time_ms: 10,
        ..AxisConfig::default()
    }
}

#[test]
fn drvi_figure_4_1_speed_profile() {
    // 60 rpm/s up to 60 rpm given at t = 0, back to 0 given at t = 2 s.
    let mut axis = enabled(drvi_velocity(), Mode::ProfileVelocity);
    let idle = run(&mut axis, 1000, 10);
    assert!(!idle[8].zero_speed && idle[9].zero_speed, "standing for 10 ms");
    axis.set_target_velocity(6000).unwrap();
    let first = run(&mut axis, 1000, 2000);
    axis.set_target_velocity(0).unwrap();
    let second = run(&mut axis, 1000, 1500);
    let all: Vec<_> = first.iter().chain(&second).collect();
    let at = |ms: usize| all[ms - 1];
    assert_eq!(at(500).velocity_actual, 3000);
    assert_eq!(at(1000).velocity_actual, 6000);
    assert_eq!(at(2000).velocity_actual, 6000);
    assert_eq!(at(2500).velocity_actual, 3000);
    assert_eq!(at(3000).velocity_actual, 0);
    // 18 000 + 36 000 + 18 000 (0.01°): 720°.
    assert_eq!(at(3500).position_actual - idle[9].position_actual, 72_000);
    // Target reached: within 10 raw units of the target for 5 ms.
    let reached = first.iter().position(|s| s.target_reached).unwrap() + 1;
    // 5994 at 999 ms is the first speed within 10 of 6000; 5 ms later (counting that one).
    assert_eq!(reached, 999 + 5 - 1, "first ms with target reached");
    // Zero speed (bit 12): below 5 raw units for 10 ms.
    assert!(!first[100].zero_speed);
    // The speed drops by 6 raw units per ms: 6 at 2999 ms, 0 (within 5) from 3000 ms; bit 12
    // after 10 ms of that.
    let still = second.iter().position(|s| s.zero_speed).unwrap() + 2001;
    assert_eq!(still, 3000 + 10 - 1);
}

#[test]
fn profile_velocity_halt_and_reversal() {
    let mut axis = enabled(drvi_velocity(), Mode::ProfileVelocity);
    axis.set_target_velocity(6000).unwrap();
    run(&mut axis, 1000, 1500);
    axis.set_halt(true);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.standing);
    assert_eq!(s.len(), 1000);
    assert!(s.last().unwrap().target_reached, "halted: target reached = standing");
    assert!(!s[500].target_reached);
    axis.set_halt(false);
    // Through zero to the other side: 2 s from +60 to -60 rpm.
    axis.set_target_velocity(-6000).unwrap();
    let s = run(&mut axis, 1000, 1000);
    assert_eq!(s.last().unwrap().velocity_actual, -6000);
    axis.set_target_velocity(6000).unwrap();
    let s = run(&mut axis, 1000, 2000);
    assert_eq!(s[999].velocity_actual, 0);
    assert_eq!(s[1999].velocity_actual, 6000);
}

#[test]
fn profile_velocity_respects_max_profile_velocity_and_refuses_zero_ramps() {
    let mut cfg = drvi_velocity();
    cfg.max_profile_velocity = 3000;
    let mut axis = enabled(cfg, Mode::ProfileVelocity);
    axis.set_target_velocity(-6000).unwrap();
    let s = run(&mut axis, 1000, 2000);
    assert_eq!(s.last().unwrap().velocity_actual, -3000);
    axis.config_mut().profile_deceleration = 0;
    assert_eq!(axis.set_target_velocity(0), Err(CommandError::InvalidProfile));
    assert_eq!(run(&mut axis, 1000, 10).last().unwrap().velocity_actual, -3000);
}

#[test]
fn profile_velocity_stops_on_software_limits() {
    let mut cfg = drvi_velocity();
    cfg.software_limits = SoftwareLimits { enabled: true, min: -50_000, max: 50_000 };
    let mut axis = enabled(cfg, Mode::ProfileVelocity);
    axis.set_target_velocity(6000).unwrap();
    let s = run_until(&mut axis, 1000, 10_000_000, |s| s.standing && s.internal_limit_active);
    assert_eq!(s.last().unwrap().position_actual, 50_000);
    assert!(s.iter().all(|s| s.position_actual <= 50_000));
    // Away from the limit is fine.
    axis.set_target_velocity(-6000).unwrap();
    let s = run(&mut axis, 1000, 500);
    assert!(s.last().unwrap().position_actual < 50_000);
    assert!(!s.last().unwrap().internal_limit_active);
}

#[test]
fn jog_follows_controlword_bits_5_and_6() {
    let mut cfg = drvi_velocity();
    cfg.profile_acceleration = 600;
    cfg.profile_deceleration = 600;
    let mut axis = enabled(cfg, Mode::Jog);
    axis.set_target_velocity(-3000).unwrap(); // the sign of 60FFh does not matter
    assert_eq!(JogCommand::from_controlword(0x004F), JogCommand::Positive);
    assert_eq!(JogCommand::from_controlword(0x002F), JogCommand::Negative);
    assert_eq!(JogCommand::from_controlword(0x006F), JogCommand::Invalid);
    assert_eq!(JogCommand::from_controlword(0x000F), JogCommand::Stop);
    axis.set_jog(JogCommand::from_controlword(0x004F));
    let s = run(&mut axis, 1000, 500);
    assert_eq!(s.last().unwrap().velocity_actual, 3000);
    assert_eq!(s.last().unwrap().jog, JogState::Positive);
    axis.set_jog(JogCommand::Invalid);
    assert_eq!(run(&mut axis, 1000, 50).last().unwrap().velocity_actual, 3000);
    axis.set_jog(JogCommand::Negative);
    let s = run(&mut axis, 1000, 1000);
    assert_eq!(s.last().unwrap().velocity_actual, -3000);
    assert_eq!(s.last().unwrap().jog, JogState::Negative);
    axis.set_jog(JogCommand::Stop);
    let s = run(&mut axis, 1000, 500);
    assert_eq!(s.last().unwrap().velocity_actual, 0);
    assert_eq!(s.last().unwrap().jog, JogState::Off);
}

fn torque_axis() -> AxisConfig {
    AxisConfig {
        torque_slope: 1000, // mA/s
        profile_deceleration: 100_000,
        // 1 mA accelerates 10 units/s², 0.01 mA per unit/s of viscous friction.
        plant: PlantConfig { inertia: 0.1, viscous: 0.01, ..PlantConfig::default() },
        ..AxisConfig::default()
    }
}

#[test]
fn drvi_figure_4_4_torque_profile() {
    let mut axis = enabled(torque_axis(), Mode::ProfileTorque);
    axis.set_target_torque(1000);
    let first = run(&mut axis, 1000, 2000);
    axis.set_target_torque(0);
    let second = run(&mut axis, 1000, 1500);
    let all: Vec<_> = first.iter().chain(&second).collect();
    let at = |ms: usize| all[ms - 1];
    for (ms, ma) in [(1, 1), (500, 500), (1000, 1000), (2000, 1000), (2500, 500), (3000, 0), (3500, 0)] {
        assert_eq!(at(ms).torque_demand, ma, "demand at {ms} ms");
        assert_eq!(at(ms).torque_actual, ma, "actual at {ms} ms");
    }
    assert!(!at(999).target_reached);
    assert!(at(1000).target_reached);
    // The torque accelerates the axis against viscous friction.
    assert!(at(2000).velocity_actual > at(1000).velocity_actual);
    assert!(at(3500).velocity_actual < at(3000).velocity_actual);
}

#[test]
fn torque_limit_and_speed_limit() {
    let mut cfg = torque_axis();
    cfg.max_torque = 800;
    cfg.torque_slope = 0;
    cfg.plant.max_speed = 2000.0;
    cfg.plant.viscous = 0.0;
    cfg.profile_deceleration = 4000; // 400 mA of the 800 available
    let mut axis = enabled(cfg, Mode::ProfileTorque);
    axis.set_target_torque(-1500);
    let s = run(&mut axis, 1000, 1000);
    assert_eq!(s[0].torque_demand, -800, "the target is limited");
    assert!(s[0].target_reached);
    assert!(s.iter().all(|s| s.torque_actual >= -800));
    // Speed stays at the motor's top speed (one step of overshoot at most: 8 units/s).
    assert!(s.iter().all(|s| s.velocity_actual >= -2008), "{:?}", s.iter().map(|s| s.velocity_actual).min());
    assert!(s.last().unwrap().velocity_actual <= -2000);
    assert_eq!(s.last().unwrap().torque_actual, 0, "no torque needed to hold speed without friction");
    // Halt: stop on the halt ramp (profile deceleration, 0.5 s from 2000), then stand.
    axis.set_halt(true);
    let s = run_until(&mut axis, 1000, 1_000_000, |s| s.standing);
    assert!((500..=502).contains(&s.len()), "{}", s.len());
    assert!(s.iter().all(|s| !s.torque_limit_active));
    assert!(s.last().unwrap().target_reached, "halted and standing");
    assert_eq!(s.last().unwrap().torque_actual, 400, "the last braking step");
    axis.step(1000);
    assert_eq!(axis.status().torque_actual, 0);
    // Released, the torque ramps again from the actual torque (0), not from where it was.
    axis.config_mut().torque_slope = 1000;
    axis.set_halt(false);
    let s = run(&mut axis, 1000, 100);
    assert_eq!(s[0].torque_actual, -1);
    assert_eq!(s[99].torque_actual, -100);
    assert!(!s.last().unwrap().target_reached, "still ramping to -800");
}

fn ip_axis() -> Axis {
    let cfg = AxisConfig {
        interpolation: InterpolationConfig { period_us: 1000, buffer_capacity: 10 },
        software_limits: SoftwareLimits { enabled: true, min: -100_000, max: 1000 },
        ..AxisConfig::default()
    };
    let mut axis = enabled(cfg, Mode::InterpolatedPosition);
    axis.set_interpolation_enabled(true);
    axis
}

#[test]
fn interpolated_position_is_linear_between_syncs() {
    let mut axis = ip_axis();
    assert!(axis.status().interpolation_active);
    // AKD 7.2.2.1: a set-point of 500 increments, taken at the next SYNC.
    axis.push_interpolation_point(500).unwrap();
    axis.push_interpolation_point(700).unwrap();
    assert_eq!(axis.status().interpolation_buffered, 2);
    axis.step(250);
    assert_eq!(axis.status().position_actual, 0, "nothing moves before the SYNC");
    axis.sync();
    let s = run(&mut axis, 250, 4);
    assert_eq!(s.iter().map(|s| s.position_demand).collect::<Vec<_>>(), [125, 250, 375, 500]);
    assert_eq!(s.iter().map(|s| s.position_actual).collect::<Vec<_>>(), [125, 250, 375, 500]);
    assert_eq!(s[0].velocity_demand, 500_000);
    axis.sync();
    let s = run(&mut axis, 500, 2);
    assert_eq!(s.iter().map(|s| s.position_actual).collect::<Vec<_>>(), [600, 700]);
    assert!(s[1].target_reached);
    // An empty buffer at SYNC: hold and report the underflow.
    axis.sync();
    let s = run(&mut axis, 500, 2);
    assert_eq!(s[1].position_actual, 700);
    assert!(s[1].interpolation_underflow);
    // Software limits clip set-points.
    axis.push_interpolation_point(5000).unwrap();
    axis.sync();
    let s = run(&mut axis, 1000, 1);
    assert_eq!(s[0].position_actual, 1000);
    assert!(s[0].internal_limit_active);
}

#[test]
fn interpolation_buffer_full_and_disable() {
    let mut axis = ip_axis();
    for k in 0..10 {
        axis.push_interpolation_point(-k * 100).unwrap();
    }
    assert_eq!(axis.push_interpolation_point(1), Err(CommandError::BufferFull));
    for _ in 0..5 {
        axis.sync();
        run(&mut axis, 1000, 1);
    }
    assert_eq!(axis.status().position_actual, -400);
    assert_eq!(axis.status().interpolation_buffered, 5);
    axis.clear_interpolation_buffer();
    assert_eq!(axis.status().interpolation_buffered, 0);
    axis.set_interpolation_enabled(false);
    assert!(!axis.status().interpolation_active);
    axis.sync(); // ignored
    run(&mut axis, 1000, 5);
    assert_eq!(axis.status().position_actual, -400);
}

#[test]
fn mode_change_while_moving_stops_and_holds() {
    let mut cfg = drvi_velocity();
    cfg.profile_velocity = 6000;
    let mut axis = enabled(cfg, Mode::ProfileVelocity);
    axis.set_target_velocity(6000).unwrap();
    run(&mut axis, 1000, 1000);
    let p0 = axis.status().position_actual;
    axis.set_mode(Mode::ProfilePosition);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual - p0, 18_000);
    assert_eq!(s.last().unwrap().velocity_actual, 0);
    assert_eq!(s.last().unwrap().mode, Mode::ProfilePosition);
    // Back to profile velocity: it ramps to 60FFh again.
    axis.set_mode(Mode::ProfileVelocity);
    let s = run(&mut axis, 1000, 1000);
    assert_eq!(s.last().unwrap().velocity_actual, 6000);
    // A fault reaction that coasts takes the torque away at once.
    axis.quick_stop(StopRamp::Coast);
    axis.step(1000);
    assert_eq!(axis.status().torque_actual, 0);
}

#[test]
fn reverse_polarity_mirrors_the_motion() {
    let mut cfg = plain(10_000, 100_000, 100_000);
    cfg.reverse_polarity = true;
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    axis.environment_mut().positive_limit = Some(-3000);
    go_to(&mut axis, 5000);
    let s = run_until(&mut axis, 1000, 5_000_000, |s| s.target_reached);
    assert_eq!(s.last().unwrap().position_actual, 5000);
    // Mechanically the motor turned negative: its positive limit switch (at -3000 on the
    // motor's own scale) is not hit, and setting the position re-references without motion.
    assert!(!s.last().unwrap().inputs.positive_limit);
    axis.set_actual_position(0, false);
    assert_eq!(axis.status().position_actual, 0);
    assert_eq!(axis.status().position_demand, 0);
}
