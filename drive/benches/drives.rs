//! How fast the simulated drives run in virtual time: simulated seconds per wall second.
//!
//! * `drives/drvi_1`: one DRVI (common CiA 402 layer + DRVI behaviour + motion model, ticking at
//!   1 ms) turning at 60 rpm in profile velocity, its TPDO1 (statusword) and a TPDO2 with
//!   position and velocity every 10 ms going to od-master on the in-memory bus (a
//!   `VirtualBus`: the master receives after every millisecond in which frames went by). One
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
use drive::node::{DeviceKind, NodeConfig, Sim, VirtualBus};
use od_master::{Axis, Node};

/// `n` DRVIs enabled and turning at 60 rpm, TPDO2 = 6064h + 606Ch every 10 ms, set up by
/// od-master (the master receiving in step with the simulation).
fn drives(n: u8) -> VirtualBus {
    let mut sim = Sim::new();
    let apps = DeviceApps::new();
    for id in 1..=n {
        let config = NodeConfig { node_id: Some(id), ..NodeConfig::default() };
        sim.add(DeviceKind::Drvi.build(&config, &apps).expect("a DRVI"));
    }
    let mut m = VirtualBus::new(sim, od_master::Config::default()).expect("a tokio runtime");
    m.advance(1000);
    for id in 1..=n {
        let node = m.bus().node(id).expect("a node id");
        m.run(setup(node)).expect("a DRVI set up");
    }
    let bus = m.bus().clone();
    m.run(bus.nmt(od_master::NmtCommand::Start, od_master::Target::All)).unwrap();
    m.advance(200_000);
    m.take_seen();
    m
}

async fn setup(node: Node) -> Result<(), od_master::Error> {
    let cob = 0x280 + u32::from(node.id());
    node.write(0x1801, 1, cob | 0x8000_0000).await?;
    node.write(0x1A01, 0, 0u8).await?;
    node.write(0x1A01, 1, 0x6064_0020u32).await?;
    node.write(0x1A01, 2, 0x606C_0020u32).await?;
    node.write(0x1A01, 0, 2u8).await?;
    node.write(0x1801, 3, 100u16).await?; // inhibit 10 ms
    node.write(0x1801, 5, 10u16).await?; // event timer 10 ms
    node.write(0x1801, 1, cob).await?;
    let axis = Axis::new(node.clone());
    axis.enable().await?;
    axis.set_mode(3).await?;
    node.write(0x6083, 0, 600u32).await?;
    node.write(0x6084, 0, 600u32).await?;
    node.write(0x60FF, 0, 6000i32).await
}

/// Simulated seconds per wall second over `simulated_us` of virtual time.
fn factor(m: &mut VirtualBus, simulated_us: u64) -> f64 {
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
