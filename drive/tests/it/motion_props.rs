//! No sequence of commands, parameters and step sizes makes the model panic, lose determinism,
//! or produce values it does not report as saturated.

use drive::motion::{
    Axis, AxisConfig, Cam, Environment, HomingMethod, JogCommand, Mode, PlantConfig, QuickStopOption, Ratio, SetPoint,
    SoftwareLimits, Status, StopRamp, Units,
};
use proptest::prelude::*;

#[derive(Debug, Clone)]
enum Op {
    Step(u32),
    Steps(u16, u32),
    Power(bool),
    Mode(i8),
    SetPoint(i32, bool, bool, bool),
    Release,
    Velocity(i32),
    Torque(i32),
    Jog(u16),
    Halt(bool),
    QuickStop(i16),
    ReleaseQuickStop,
    StartHoming(i8, bool),
    AbortHoming,
    Interpolation(bool),
    Push(i32),
    Sync,
    Brake(bool),
    SetActual(i32, bool),
    Profile(u32, u32, u32, u32),
    Limits(bool, i32, i32),
    TorqueParams(u32, u32),
    Polarity(bool),
}

fn op() -> impl Strategy<Value = Op> {
    let big = prop_oneof![any::<u32>(), 0u32..100_000];
    prop_oneof![
        6 => (1u32..20_000).prop_map(Op::Step),
        2 => (1u16..200, prop_oneof![Just(1000u32), 1u32..5000]).prop_map(|(n, dt)| Op::Steps(n, dt)),
        1 => any::<u32>().prop_map(Op::Step),
        1 => any::<bool>().prop_map(Op::Power),
        2 => prop_oneof![Just(-1i8), Just(0), Just(1), Just(3), Just(4), Just(6), Just(7), any::<i8>()].prop_map(Op::Mode),
        2 => (any::<i32>(), any::<bool>(), any::<bool>(), any::<bool>()).prop_map(|(t, a, b, c)| Op::SetPoint(t, a, b, c)),
        1 => Just(Op::Release),
        2 => prop_oneof![any::<i32>(), -100_000i32..100_000].prop_map(Op::Velocity),
        1 => any::<i32>().prop_map(Op::Torque),
        1 => any::<u16>().prop_map(Op::Jog),
        1 => any::<bool>().prop_map(Op::Halt),
        1 => (-2i16..10).prop_map(Op::QuickStop),
        1 => Just(Op::ReleaseQuickStop),
        1 => (any::<i8>(), any::<bool>()).prop_map(|(c, v)| Op::StartHoming(c, v)),
        1 => Just(Op::AbortHoming),
        1 => any::<bool>().prop_map(Op::Interpolation),
        1 => any::<i32>().prop_map(Op::Push),
        1 => Just(Op::Sync),
        1 => any::<bool>().prop_map(Op::Brake),
        1 => (any::<i32>(), any::<bool>()).prop_map(|(p, h)| Op::SetActual(p, h)),
        1 => (big.clone(), big.clone(), big.clone(), big.clone()).prop_map(|(a, b, c, d)| Op::Profile(a, b, c, d)),
        1 => (any::<bool>(), any::<i32>(), any::<i32>()).prop_map(|(e, a, b)| Op::Limits(e, a, b)),
        1 => (big.clone(), big).prop_map(|(a, b)| Op::TorqueParams(a, b)),
        1 => any::<bool>().prop_map(Op::Polarity),
    ]
}

fn config() -> impl Strategy<Value = (AxisConfig, Environment)> {
    (
        (any::<i64>(), any::<i64>(), 1i64..1000, 1i64..1000),
        (0.0f64..1.0, 0.0f64..1.0, 0.0f64..100.0, prop_oneof![Just(f64::NAN), Just(-1.0), 0.0f64..10.0]),
        (any::<u32>(), 0u32..100_000, 0u32..100_000, 0u32..1_000_000),
        (prop::option::of((-100_000i64..100_000, 0i64..50_000)), prop::option::of(-200_000i64..0)),
        (0u64..10_000, any::<i64>(), 0u32..50_000, 0u64..5_000_000),
    )
        .prop_map(|((vn, an, vd, ad), (j, b, c, bw), (mt, ts, hs, ha), (cam, stop), (ip, phase, fe, timeout))| {
            let mut cfg = AxisConfig {
                units: Units { velocity: Ratio::new(vn, vd), acceleration: Ratio::new(an, ad) },
                max_torque: mt,
                torque_slope: ts,
                following_error_window: fe,
                following_error_timeout_ms: 5,
                plant: PlantConfig { inertia: j, viscous: b, coulomb: c, bandwidth: bw, max_speed: 0.0 },
                ..AxisConfig::default()
            };
            cfg.homing.search_speed = hs;
            cfg.homing.zero_speed = hs / 4;
            cfg.homing.acceleration = ha;
            cfg.homing.deceleration = ha;
            cfg.homing.timeout_us = timeout;
            cfg.homing.torque_limit = mt / 2;
            let env = Environment {
                home_switch: cam.map(|(low, len)| Cam { low, high: low + len }),
                negative_limit: stop.map(|s| s + 1000),
                positive_limit: stop.map(|s| -s - 1000),
                negative_end_stop: stop,
                positive_end_stop: stop.map(|s| -s),
                index_period: ip,
                index_phase: phase,
            };
            (cfg, env)
        })
}

fn apply(axis: &mut Axis, op: &Op) {
    match *op {
        Op::Step(dt) => axis.step(dt),
        Op::Steps(n, dt) => {
            for _ in 0..n {
                axis.step(dt);
            }
        }
        Op::Power(on) => axis.set_power(on),
        Op::Mode(code) => {
            if let Some(mode) = Mode::from_code(code) {
                axis.set_mode(mode);
            }
        }
        Op::SetPoint(target, relative, change_immediately, change_on_set_point) => {
            let _ = axis.new_set_point(SetPoint { target, relative, change_immediately, change_on_set_point });
        }
        Op::Release => axis.release_set_point(),
        Op::Velocity(v) => {
            let _ = axis.set_target_velocity(v);
        }
        Op::Torque(t) => axis.set_target_torque(t),
        Op::Jog(cw) => axis.set_jog(JogCommand::from_controlword(cw)),
        Op::Halt(h) => axis.set_halt(h),
        Op::QuickStop(code) => {
            let ramp = QuickStopOption::from_code(code).map_or(StopRamp::QuickStopDeceleration, |o| o.ramp);
            axis.quick_stop(ramp);
        }
        Op::ReleaseQuickStop => axis.release_quick_stop(),
        Op::StartHoming(code, camozzi) => {
            let method = if camozzi { HomingMethod::camozzi(code) } else { HomingMethod::cia402(code) };
            if let Some(method) = method {
                axis.config_mut().homing.method = method;
            }
            let _ = axis.start_homing();
        }
        Op::AbortHoming => axis.abort_homing(),
        Op::Interpolation(on) => axis.set_interpolation_enabled(on),
        Op::Push(p) => {
            let _ = axis.push_interpolation_point(p);
        }
        Op::Sync => axis.sync(),
        Op::Brake(on) => axis.set_brake(on),
        Op::SetActual(p, homed) => axis.set_actual_position(p, homed),
        Op::Profile(v, a, d, q) => {
            let c = axis.config_mut();
            c.profile_velocity = v;
            c.profile_acceleration = a;
            c.profile_deceleration = d;
            c.quick_stop_deceleration = q;
        }
        Op::Limits(enabled, min, max) => axis.config_mut().software_limits = SoftwareLimits { enabled, min, max },
        Op::TorqueParams(slope, limit) => {
            let c = axis.config_mut();
            c.torque_slope = slope;
            c.max_torque = limit;
        }
        Op::Polarity(r) => axis.config_mut().reverse_polarity = r,
    }
}

/// An output at the edge of `i32` must come with the saturation flag.
fn check(status: &Status) -> Result<(), TestCaseError> {
    let values = [
        status.position_demand,
        status.position_actual,
        status.velocity_demand,
        status.velocity_actual,
        status.torque_demand,
        status.torque_actual,
        status.following_error,
    ];
    if values.iter().any(|&v| v == i32::MIN || v == i32::MAX) {
        prop_assert!(status.saturated, "unreported saturation: {status:?}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn commands_never_panic_and_stay_deterministic(
        (cfg, env) in config(),
        ops in prop::collection::vec(op(), 1..60),
    ) {
        let mut a = Axis::with_environment(cfg.clone(), env);
        let mut b = Axis::with_environment(cfg, env);
        // Most of the interesting behaviour needs the power stage on.
        for op in std::iter::once(&Op::Power(true)).chain(&ops) {
            apply(&mut a, op);
            apply(&mut b, op);
            let (sa, sb) = (a.status(), b.status());
            check(&sa)?;
            prop_assert_eq!(sa, sb);
        }
    }

    /// With parameters in a sensible range, nothing saturates: the model stays well inside its
    /// numeric range whatever is commanded.
    #[test]
    fn sane_parameters_never_saturate(
        ops in prop::collection::vec(op().prop_filter("sane", |op| !matches!(
            op,
            Op::Profile(..) | Op::TorqueParams(..) | Op::SetActual(..) | Op::SetPoint(..) | Op::Velocity(_)
                | Op::Push(_) | Op::Step(_) | Op::Torque(_)
        )), 1..40),
        targets in prop::collection::vec(-1_000_000i32..1_000_000, 1..5),
    ) {
        let mut cfg = AxisConfig {
            profile_velocity: 10_000,
            profile_acceleration: 100_000,
            profile_deceleration: 100_000,
            quick_stop_deceleration: 200_000,
            torque_slope: 1000,
            max_torque: 3000,
            plant: PlantConfig { inertia: 0.01, viscous: 0.01, coulomb: 10.0, ..PlantConfig::default() },
            ..AxisConfig::default()
        };
        cfg.homing.search_speed = 5000;
        cfg.homing.zero_speed = 500;
        cfg.homing.acceleration = 50_000;
        cfg.homing.deceleration = 50_000;
        cfg.homing.timeout_us = 3_000_000;
        let env = Environment {
            home_switch: Some(Cam { low: 1000, high: 2000 }),
            negative_limit: Some(-40_000),
            positive_limit: Some(40_000),
            negative_end_stop: Some(-50_000),
            positive_end_stop: Some(50_000),
            index_period: 4096,
            index_phase: 0,
        };
        let mut axis = Axis::with_environment(cfg, env);
        for (k, op) in ops.iter().enumerate() {
            apply(&mut axis, op);
            let target = targets[k % targets.len()];
            apply(&mut axis, &Op::SetPoint(target, false, k % 2 == 0, false));
            apply(&mut axis, &Op::Velocity(target / 100));
            apply(&mut axis, &Op::Torque(target / 1000));
            apply(&mut axis, &Op::Push(target / 10));
            apply(&mut axis, &Op::Steps(20, 1000));
            let s = axis.status();
            prop_assert!(!s.saturated, "{:?} after {:?}", s, op);
            prop_assert!(s.position_actual.abs() <= 1_000_000 + 60_000, "{:?}", s);
            prop_assert!(s.torque_actual.abs() <= 3000, "{:?}", s);
        }
    }
}
