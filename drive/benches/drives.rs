//! How fast the simulated drives run in virtual time: simulated seconds per wall second.
//!
//! * `drives/drvi_1`: one DRVI (common CiA 402 layer + DRVI behaviour + motion model, ticking at
//!   1 ms) turning at 60 rpm in profile velocity, its TPDO1 (statusword) and a TPDO2 with
//!   position and velocity every 10 ms going to a master endpoint on the in-memory bus. One
//!   iteration simulates 1 s; criterion's throughput is in simulated milliseconds per second.
//! * `drives/drvi_32`: 32 such DRVIs on one in-memory bus (node ids 1..=32), 100 ms per
//!   iteration; throughput in simulated bus milliseconds per second.
//!
//! The ratio "simulated seconds per wall second" is printed at the end (`realtime factor`).
//! Run with `cargo bench -p drive --bench drives`; under `cargo test` (no `--bench` argument)
//! everything runs briefly, as a smoke test.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput};
use drive::drives::DeviceApps;
use drive::drives::master::Master;
use drive::node::{DeviceKind, NodeConfig, Sim};

/// `n` DRVIs enabled and turning at 60 rpm, TPDO2 = 6064h + 606Ch every 10 ms.
fn drives(n: u8) -> Master {
    let mut sim = Sim::new();
    let apps = DeviceApps::new();
    for id in 1..=n {
        let config = NodeConfig { node_id: Some(id), ..NodeConfig::default() };
        sim.add(DeviceKind::Drvi.build(&config, &apps).expect("a DRVI"));
    }
    let mut m = Master::new(sim);
    m.advance(1000);
    for id in 1..=n {
        let cob = 0x280 + u32::from(id);
        m.write_u32(id, 0x1801, 1, cob | 0x8000_0000).unwrap();
        m.write_u8(id, 0x1A01, 0, 0).unwrap();
        m.write_u32(id, 0x1A01, 1, 0x6064_0020).unwrap();
        m.write_u32(id, 0x1A01, 2, 0x606C_0020).unwrap();
        m.write_u8(id, 0x1A01, 0, 2).unwrap();
        m.write_u16(id, 0x1801, 3, 100).unwrap(); // inhibit 10 ms
        m.write_u16(id, 0x1801, 5, 10).unwrap(); // event timer 10 ms
        m.write_u32(id, 0x1801, 1, cob).unwrap();
        m.switch_on(id).unwrap();
        m.set_mode(id, 3).unwrap();
        m.write_u32(id, 0x6083, 0, 600).unwrap();
        m.write_u32(id, 0x6084, 0, 600).unwrap();
        m.write_i32(id, 0x60FF, 0, 6000).unwrap();
    }
    m.nmt_start(0);
    m.advance(200_000);
    m.take_seen();
    m
}

/// Simulated seconds per wall second over `simulated_us` of virtual time.
fn factor(m: &mut Master, simulated_us: u64) -> f64 {
    let t = Instant::now();
    m.advance(simulated_us);
    m.take_seen();
    simulated_us as f64 * 1e-6 / t.elapsed().as_secs_f64()
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let mut c = Criterion::default().configure_from_args();
    let mut group = c.benchmark_group("drives");
    group.sample_size(10);

    let mut one = drives(1);
    let step = if full { 1_000_000 } else { 20_000 };
    group.throughput(Throughput::Elements(step / 1000));
    group.bench_function("drvi_1", |b| {
        b.iter(|| {
            one.advance(black_box(step));
            one.take_seen();
        })
    });

    let mut many = drives(32);
    let step = if full { 100_000 } else { 5_000 };
    group.throughput(Throughput::Elements(step / 1000));
    group.bench_function("drvi_32", |b| {
        b.iter(|| {
            many.advance(black_box(step));
            many.take_seen();
        })
    });
    group.finish();
    c.final_summary();

    let span = if full { 10_000_000 } else { 100_000 };
    let f1 = factor(&mut one, span);
    let f32 = factor(&mut many, span / 10);
    println!("realtime factor: 1 DRVI at 1 ms: {f1:.1} simulated s per wall s");
    println!(
        "realtime factor: 32 DRVIs on one in-memory bus: {f32:.2} simulated s per wall s ({:.1} drive-s per wall s)",
        f32 * 32.0
    );
}
