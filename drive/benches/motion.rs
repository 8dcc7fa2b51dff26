//! Simulated seconds per wall-clock second of one axis stepped at 1 ms.
//!
//! Each iteration simulates one second (1000 steps of 1 ms); criterion reports the throughput
//! in elements (steps) per second, so *simulated seconds per wall second = elements/s ÷ 1000*.
//!
//! * `profile_position`: back-and-forth trapezoidal moves (the exact-tracking path).
//! * `profile_velocity`: velocity reversals with a status read and a trace sample every step.
//! * `torque_physics`: torque mode with inertia and friction (the integrated-physics path).
//! * `homing`: repeated CiA 402 method 8 homings on a simulated axis with switches and index.
//!
//! Run with `cargo bench -p drive --bench motion`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use drive::motion::{Axis, AxisConfig, Cam, Environment, HomingMethod, HomingState, Mode, PlantConfig, SetPoint};
use drive::trace::Trace;

const STEPS: u64 = 1000;

fn config() -> AxisConfig {
    AxisConfig {
        profile_velocity: 100_000,
        profile_acceleration: 1_000_000,
        profile_deceleration: 1_000_000,
        torque_slope: 10_000,
        max_torque: 5000,
        plant: PlantConfig { inertia: 0.001, viscous: 0.001, coulomb: 20.0, ..PlantConfig::default() },
        ..AxisConfig::default()
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("motion");
    group.throughput(Throughput::Elements(STEPS));

    let mut axis = Axis::new(config());
    axis.set_power(true);
    axis.set_mode(Mode::ProfilePosition);
    let mut flip = 1;
    group.bench_function("profile_position", |b| {
        b.iter(|| {
            for k in 0..STEPS {
                if k % 250 == 0 {
                    flip = -flip;
                    let _ = axis.new_set_point(SetPoint { target: flip * 10_000, ..SetPoint::default() });
                    axis.release_set_point();
                }
                axis.step(1000);
            }
            black_box(axis.status())
        })
    });

    let mut axis = Axis::new(config());
    axis.set_power(true);
    axis.set_mode(Mode::ProfileVelocity);
    let mut trace = Trace::with_interval(0);
    group.bench_function("profile_velocity", |b| {
        b.iter(|| {
            for k in 0..STEPS {
                if k % 500 == 0 {
                    flip = -flip;
                    let _ = axis.set_target_velocity(flip * 50_000);
                }
                axis.step(1000);
                trace.record(&axis.status(), 0x0237);
            }
            if trace.samples().len() > 1_000_000 {
                trace = Trace::with_interval(0);
            }
            black_box(trace.samples().len())
        })
    });

    let mut axis = Axis::new(config());
    axis.set_power(true);
    axis.set_mode(Mode::ProfileTorque);
    group.bench_function("torque_physics", |b| {
        b.iter(|| {
            for k in 0..STEPS {
                if k % 500 == 0 {
                    flip = -flip;
                    axis.set_target_torque(flip * 300);
                }
                axis.step(1000);
            }
            black_box(axis.status())
        })
    });

    let mut cfg = config();
    cfg.homing.method = HomingMethod::cia402(8).expect("method 8");
    cfg.homing.search_speed = 100_000;
    cfg.homing.zero_speed = 10_000;
    cfg.homing.acceleration = 1_000_000;
    cfg.homing.deceleration = 1_000_000;
    let env = Environment {
        home_switch: Some(Cam { low: 20_000, high: 30_000 }),
        negative_limit: Some(-100_000),
        positive_limit: Some(100_000),
        index_period: 4096,
        ..Environment::default()
    };
    let mut axis = Axis::with_environment(cfg, env);
    axis.set_power(true);
    axis.set_mode(Mode::Homing);
    group.bench_function("homing", |b| {
        b.iter(|| {
            for _ in 0..STEPS {
                if matches!(axis.status().homing, HomingState::Completed | HomingState::Idle) {
                    axis.set_actual_position(0, false);
                    let _ = axis.start_homing();
                }
                axis.step(1000);
            }
            black_box(axis.status())
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
