//! SDO round trips through od-master to a simulated DRVI running in real time: over the
//! socketcand hub on TCP (loopback) and on the in-memory bus. What one read costs end to end:
//! the caller's task, the bus task, the transport, the node's runner and od-runtime's server.

use std::hint::black_box;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use criterion::{Criterion, criterion_group, criterion_main};
use drive::drives::DeviceApps;
use drive::node::{DeviceKind, MonotonicClock, NodeConfig, run};
use od_bus::{Endpoint, Hub, HubConfig, MemoryBus};
use od_master::{Bus, Config};

fn drvi() -> Box<dyn drive::node::AnyNode> {
    DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..Default::default() }, &DeviceApps::new()).unwrap()
}

/// Runs the DRVI on `ep` until `stop`.
fn spawn_node(mut ep: impl Endpoint + 'static, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut node = drvi();
        let _ = run(&mut *node, &mut ep, &MonotonicClock::new(), &stop);
    })
}

fn reads(c: &mut Criterion, name: &str, bus: &Bus, rt: &tokio::runtime::Runtime) {
    let drive = bus.node(2).unwrap();
    let mut group = c.benchmark_group(name);
    group.bench_function("expedited read 1000h", |b| {
        b.iter(|| rt.block_on(async { black_box(drive.read::<u32>(0x1000, 0).await.unwrap()) }))
    });
    group.bench_function("segmented read 1008h", |b| {
        b.iter(|| rt.block_on(async { black_box(drive.read_bytes(0x1008, 0).await.unwrap()) }))
    });
    group.bench_function("expedited write 6083h", |b| {
        b.iter(|| rt.block_on(async { drive.write(0x6083, 0, black_box(1000u32)).await.unwrap() }))
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(1).enable_all().build().unwrap();
    let stop = Arc::new(AtomicBool::new(false));

    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).unwrap();
    let node = spawn_node(hub.attach("can0").unwrap(), Arc::clone(&stop));
    let bus = rt.block_on(Bus::open(&format!("socketcand://{}/can0", hub.local_addr()), Config::default())).unwrap();
    reads(c, "hub", &bus, &rt);
    drop(bus);
    stop.store(true, Ordering::SeqCst);
    hub.stop();
    node.join().unwrap();

    stop.store(false, Ordering::SeqCst);
    let mem = MemoryBus::new();
    let node = spawn_node(mem.endpoint(), Arc::clone(&stop));
    let bus = rt.block_on(async { Bus::start(od_bus::tokio::Bus::attach(&mem), Config::default()) });
    reads(c, "memory", &bus, &rt);
    drop(bus);
    stop.store(true, Ordering::SeqCst);
    node.join().unwrap();
}

criterion_group!(sdo, benches);
criterion_main!(sdo);
