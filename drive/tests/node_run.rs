//! The real-time loop (`drive::node::run`): prompt responses, timers on the monotonic clock,
//! and both ways to end (the stop flag, a bus that closes).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use drive::node::{DefaultApps, DeviceKind, MonotonicClock, NodeConfig, run};
use drive::transport::{CanFrame, Endpoint, Hub, HubConfig, LocalEndpoint, MemoryBus, TransportError};

const WAIT: Duration = Duration::from_secs(5);

fn next_with_id(ep: &mut LocalEndpoint, id: u32) -> (Instant, CanFrame) {
    let deadline = Instant::now() + WAIT;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match ep.recv_timeout(left).unwrap() {
            Some(f) if f.id() == id => return (Instant::now(), f),
            Some(_) => continue,
            None => panic!("no frame with id {id:#x}"),
        }
    }
}

#[test]
fn the_loop_answers_at_once_keeps_time_and_stops_on_the_flag() {
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut device = bus.endpoint();
    let mut node =
        DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..NodeConfig::default() }, &DefaultApps).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || run(&mut *node, &mut device, &MonotonicClock::new(), &stop))
    };
    assert_eq!(next_with_id(&mut master, 0x702).1.data(), [0x00]);

    // An SDO request is answered as it arrives (a few microseconds here; the bound leaves room
    // for a loaded machine).
    let mut latencies = Vec::new();
    for _ in 0..20 {
        let sent = Instant::now();
        master.send(CanFrame::standard(0x602, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
        let (at, reply) = next_with_id(&mut master, 0x582);
        assert_eq!(reply.data(), [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x7A, 0xFF]);
        latencies.push(at - sent);
    }
    latencies.sort();
    assert!(latencies[10] < Duration::from_millis(2), "median SDO latency {:?}", latencies[10]);

    // Heartbeat of 20 ms on the monotonic clock.
    master.send(CanFrame::standard(0x602, &[0x2B, 0x17, 0x10, 0x00, 20, 0, 0, 0]).unwrap()).unwrap();
    next_with_id(&mut master, 0x582);
    let stamps: Vec<Instant> = (0..11).map(|_| next_with_id(&mut master, 0x702).0).collect();
    let mut gaps: Vec<Duration> = stamps.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort();
    let median = gaps[gaps.len() / 2];
    assert!(median > Duration::from_millis(17) && median < Duration::from_millis(23), "{gaps:?}");

    stop.store(true, Ordering::SeqCst);
    let stats = thread.join().unwrap().unwrap();
    assert!(stats.received >= 21, "{stats:?}");
    assert!(stats.sent >= 32, "{stats:?}");
    assert!(stats.polls >= stats.received, "{stats:?}");
}

#[test]
fn the_loop_ends_with_closed_when_the_hub_stops() {
    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).unwrap();
    let mut device = hub.attach("can0").unwrap();
    let mut node =
        DeviceKind::Akd.build(&NodeConfig { node_id: Some(4), ..NodeConfig::default() }, &DefaultApps).unwrap();
    let stop = AtomicBool::new(false);
    std::thread::scope(|s| {
        let handle = s.spawn(|| run(&mut *node, &mut device, &MonotonicClock::new(), &stop));
        std::thread::sleep(Duration::from_millis(50));
        let stopped = Instant::now();
        hub.stop();
        let result = handle.join().unwrap();
        assert!(matches!(result, Err(TransportError::Closed)), "{result:?}");
        assert!(stopped.elapsed() < Duration::from_secs(1));
    });
}
