//! Frames per second through the transports.
//!
//! * `hub/tcp_to_tcp`: two socketcand TCP clients on one hub channel, one sending, the other
//!   receiving, with at most `WINDOW` frames in flight (a master streaming PDOs to a device).
//! * `hub/local_to_tcp`: an in-process endpoint (a simulated device) sending to a TCP client
//!   (the master), the path every device response takes in `drive-sim`.
//! * `memory_bus/relay`: one endpoint to another on the in-memory bus.
//! * `slcan/encode`, `slcan/decode`: one SDO frame to its slcan line and back (the ASCII an
//!   slcan adapter costs the host per frame).
//!
//! Criterion reports the throughput in elements (frames) per second. Run with
//! `cargo bench -p od-bus --bench hub`.

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use od_bus::{CanFrame, Endpoint, Hub, HubConfig, MemoryBus, SocketcandClient};

/// Frames sent ahead of those received; well under the hub's per-client queue (4096).
const WINDOW: u64 = 256;

fn pdo(n: u64) -> CanFrame {
    CanFrame::standard(0x201, &n.to_le_bytes()).expect("valid frame")
}

/// Streams `count` frames from `tx` to `rx`, keeping at most WINDOW in flight.
fn stream(tx: &mut dyn Endpoint, rx: &mut dyn Endpoint, count: u64) -> Duration {
    let start = Instant::now();
    let (mut sent, mut received) = (0, 0);
    while received < count {
        while sent < count && sent - received < WINDOW {
            tx.send(pdo(sent)).expect("send");
            sent += 1;
        }
        let frame = rx.recv_timeout(Duration::from_secs(10)).expect("receive").expect("a frame was lost");
        assert_eq!(frame.data(), &received.to_le_bytes(), "frames out of order");
        received += 1;
    }
    start.elapsed()
}

fn hub(c: &mut Criterion) {
    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind");
    let mut group = c.benchmark_group("hub");
    group.throughput(Throughput::Elements(1));
    group.sample_size(20).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(4));

    let mut sender = SocketcandClient::connect(hub.local_addr(), "bench").expect("connect sender");
    let mut receiver = SocketcandClient::connect(hub.local_addr(), "bench").expect("connect receiver");
    group.bench_function("tcp_to_tcp", |b| b.iter_custom(|n| stream(&mut sender, &mut receiver, n)));
    drop((sender, receiver));

    let mut device = hub.attach("bench2").expect("attach");
    let mut master = SocketcandClient::connect(hub.local_addr(), "bench2").expect("connect master");
    group.bench_function("local_to_tcp", |b| b.iter_custom(|n| stream(&mut device, &mut master, n)));
    group.finish();
}

fn memory_bus(c: &mut Criterion) {
    let bus = MemoryBus::new();
    let mut a = bus.endpoint();
    let mut b = bus.endpoint();
    let mut group = c.benchmark_group("memory_bus");
    group.throughput(Throughput::Elements(1));
    group.bench_function("relay", |bench| {
        bench.iter(|| {
            a.send(black_box(pdo(7))).expect("send");
            b.try_recv().expect("recv").expect("frame")
        })
    });
    group.finish();
}

/// slcan's ASCII, what the serial adapters cost the host per frame beside the port's write:
/// one 8-byte SDO frame encoded, and its line decoded (the goal: well under 5 µs).
fn slcan_codec(c: &mut Criterion) {
    let frame = CanFrame::standard(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
    let mut group = c.benchmark_group("slcan");
    group.throughput(Throughput::Elements(1));
    let mut line = Vec::with_capacity(32);
    group.bench_function("encode", |b| {
        b.iter(|| {
            line.clear();
            od_bus::slcan::encode(black_box(&frame), &mut line);
            line.len()
        })
    });
    let mut encoded = Vec::new();
    od_bus::slcan::encode(&frame, &mut encoded);
    let mut decoder = od_bus::slcan::Decoder::new();
    group.bench_function("decode", |b| {
        b.iter(|| {
            let mut got = None;
            decoder.feed(black_box(&encoded), |reply| got = Some(reply));
            got
        })
    });
    group.finish();
}

criterion_group!(benches, hub, memory_bus, slcan_codec);
criterion_main!(benches);
