//! The real-time loop (`drive::node::run`): prompt responses, timers on the monotonic clock,
//! and both ways to end (the stop flag, a bus that closes).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use drive::node::{DefaultApps, DeviceKind, MonotonicClock, NodeConfig, run};
use od_bus::{CanFrame, Endpoint, Hub, HubConfig, LocalEndpoint, MemoryBus, TransportError};

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

/// An endpoint whose bus fails for good after `left` more sends.
struct Failing {
    inner: LocalEndpoint,
    left: u32,
}

impl Endpoint for Failing {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        if self.left == 0 {
            return Err(TransportError::Closed);
        }
        self.left -= 1;
        self.inner.send(frame)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        if self.left == 0 {
            return Err(TransportError::Closed);
        }
        self.inner.recv_timeout(timeout)
    }
}

#[test]
fn a_node_whose_bus_fails_keeps_its_state_and_comes_back_when_the_bus_opens_again() {
    use drive::node::{Backoff, BusEvent, run_reconnecting};
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    // The first bus carries the boot-up and two SDO responses, then fails; the first attempt
    // to open it again fails too, the second gives a working endpoint.
    let first: Box<dyn Endpoint> = Box::new(Failing { inner: bus.endpoint(), left: 3 });
    let mut node =
        DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..NodeConfig::default() }, &DefaultApps).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let events = Arc::new(std::sync::Mutex::new(Vec::new()));
    let thread = {
        let (stop, events, bus) = (Arc::clone(&stop), Arc::clone(&events), bus.clone());
        std::thread::spawn(move || {
            let mut attempts = 0;
            let mut open = || -> Result<Box<dyn Endpoint>, TransportError> {
                attempts += 1;
                if attempts == 1 {
                    Err(TransportError::Protocol("not yet".into()))
                } else {
                    Ok(Box::new(bus.endpoint()))
                }
            };
            let backoff = Backoff { first: Duration::from_millis(10), max: Duration::from_millis(40) };
            let mut report = |event: BusEvent<'_>| {
                events.lock().unwrap().push(match event {
                    BusEvent::Lost(_) => "lost".to_owned(),
                    BusEvent::RetryFailed { retry_in, .. } => format!("retry in {retry_in:?}"),
                    BusEvent::Reconnected { attempts } => format!("back after {attempts}"),
                    _ => "other".to_owned(),
                })
            };
            run_reconnecting(&mut *node, first, &mut open, &MonotonicClock::new(), &stop, backoff, &mut report)
        })
    };
    assert_eq!(next_with_id(&mut master, 0x702).1.data(), [0x00]);
    // 6083h = 4321 (not saved: only the running node has it).
    master.send(CanFrame::standard(0x602, &[0x23, 0x83, 0x60, 0x00, 0xE1, 0x10, 0, 0]).unwrap()).unwrap();
    assert_eq!(next_with_id(&mut master, 0x582).1.data()[0], 0x60);
    master.send(CanFrame::standard(0x602, &[0x40, 0x83, 0x60, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
    assert_eq!(next_with_id(&mut master, 0x582).1.data()[4..8], 4321u32.to_le_bytes());
    // The bus fails now; the node is back on a new endpoint with what it had.
    let deadline = Instant::now() + WAIT;
    while !events.lock().unwrap().iter().any(|e| e.starts_with("back")) {
        assert!(Instant::now() < deadline, "{:?}", events.lock().unwrap());
        std::thread::sleep(Duration::from_millis(5));
    }
    master.send(CanFrame::standard(0x602, &[0x40, 0x83, 0x60, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
    assert_eq!(next_with_id(&mut master, 0x582).1.data()[4..8], 4321u32.to_le_bytes());
    stop.store(true, Ordering::SeqCst);
    let stats = thread.join().unwrap();
    assert!(stats.sent >= 4, "{stats:?}");
    assert_eq!(*events.lock().unwrap(), ["lost", "retry in 20ms", "back after 2"]);
}

/// Devices run as a group on one endpoint (`drive-sim run` with several devices): each
/// answers its own requests, requests that come together are all answered, and a frame one
/// device sends reaches the others in the group, which the bus itself never gives back to the
/// endpoint that sent it. Here the AKD (node 2) consumes the DRVI's (node 1) heartbeat, which
/// it can only hear inside the group; when the DRVI falls silent, the AKD reports 8130h.
#[test]
fn a_group_on_one_endpoint_answers_each_node_and_its_devices_hear_each_other() {
    use drive::node::{AnyNode, run_group};
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut device = bus.endpoint();
    let build =
        |kind: DeviceKind, id| kind.build(&NodeConfig { node_id: Some(id), ..NodeConfig::default() }, &DefaultApps);
    let mut nodes = [build(DeviceKind::Drvi, 1).unwrap(), build(DeviceKind::Akd, 2).unwrap()];
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut group: Vec<&mut dyn AnyNode> = nodes.iter_mut().map(|n| &mut **n as &mut dyn AnyNode).collect();
            run_group(&mut group, &mut device, &MonotonicClock::new(), &stop)
        })
    };
    next_with_id(&mut master, 0x701);
    next_with_id(&mut master, 0x702);
    let sdo = |master: &mut LocalEndpoint, node: u32, data: [u8; 8]| {
        master.send(CanFrame::standard(0x600 + node, &data).unwrap()).unwrap();
        next_with_id(master, 0x580 + node).1
    };

    // Two requests at once, two answers, each from its node (1000h: device types differ).
    master.send(CanFrame::standard(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
    master.send(CanFrame::standard(0x602, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
    let mut answers = Vec::new();
    while answers.len() < 2 {
        let frame = master.recv_timeout(WAIT).unwrap().expect("both nodes answer");
        if frame.id() & !0x7F == 0x580 {
            answers.push(frame.id());
        }
    }
    answers.sort();
    assert_eq!(answers, [0x581, 0x582]);

    // The AKD watches node 1's heartbeat (100 ms); the DRVI beats every 20 ms.
    assert_eq!(sdo(&mut master, 2, [0x23, 0x16, 0x10, 0x01, 100, 0, 1, 0]).data()[0], 0x60);
    assert_eq!(sdo(&mut master, 1, [0x2B, 0x17, 0x10, 0x00, 20, 0, 0, 0]).data()[0], 0x60);
    next_with_id(&mut master, 0x701);
    next_with_id(&mut master, 0x701);
    // While the beats come, the AKD reports nothing.
    let quiet_until = Instant::now() + Duration::from_millis(300);
    while let Some(frame) = master.recv_timeout(quiet_until.saturating_duration_since(Instant::now())).unwrap() {
        assert_ne!(frame.id(), 0x082, "EMCY while node 1's heartbeat came: {frame:?}");
    }
    // The DRVI stops beating: the AKD, which heard it only inside the group, notices.
    assert_eq!(sdo(&mut master, 1, [0x2B, 0x17, 0x10, 0x00, 0, 0, 0, 0]).data()[0], 0x60);
    let emcy = next_with_id(&mut master, 0x082).1;
    assert_eq!(emcy.data()[..2], [0x30, 0x81], "{emcy:?}");

    stop.store(true, Ordering::SeqCst);
    let stats = thread.join().unwrap().unwrap();
    assert_eq!(stats.received, 5, "the five requests, nothing else: {stats:?}");
}

/// Two devices of a group that answer each other forever neither lose a frame between them nor
/// hold up the bus: the frames they exchange go on the bus turn after turn, each one reaches
/// the other, and the stop flag still ends the loop.
#[test]
fn devices_that_answer_each_other_forever_lose_nothing_and_do_not_starve_the_bus() {
    use drive::node::{AnyNode, run_group};
    use od_runtime::od::AbortCode;
    use od_runtime::{Micros, NmtState, NodeId};
    use std::sync::atomic::AtomicU64;

    /// Answers each frame of its peer (and the master's kick-off, 000h) with one of its own.
    struct Echo {
        id: u32,
        peer: u32,
        owed: u32,
        heard: Arc<AtomicU64>,
        said: Arc<AtomicU64>,
    }
    impl AnyNode for Echo {
        fn handle(&mut self, frame: &CanFrame, _now: Micros) {
            if frame.id() == 0x100 + self.peer {
                self.heard.fetch_add(1, Ordering::SeqCst);
                self.owed += 1;
            } else if frame.id() == 0 {
                self.owed += 1;
            }
        }
        fn poll(&mut self, _now: Micros, emit: &mut dyn FnMut(CanFrame)) {
            for _ in 0..std::mem::take(&mut self.owed) {
                self.said.fetch_add(1, Ordering::SeqCst);
                emit(CanFrame::standard(0x100 + self.id, &[]).unwrap());
            }
        }
        fn next_deadline(&self) -> Micros {
            Micros::MAX
        }
        fn node_id(&self) -> NodeId {
            NodeId::new(u8::try_from(self.id).unwrap()).unwrap()
        }
        fn nmt_state(&self) -> NmtState {
            NmtState::Operational
        }
        fn upload(&mut self, _index: u16, _sub: u8) -> Result<Vec<u8>, AbortCode> {
            Err(AbortCode::NO_OBJECT)
        }
        fn as_any(&self) -> &dyn std::any::Any {
            self
        }
        fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
            self
        }
    }

    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut device = bus.endpoint();
    let counters: Vec<Arc<AtomicU64>> = (0..4).map(|_| Arc::new(AtomicU64::new(0))).collect();
    let (heard_a, said_a, heard_b, said_b) =
        (Arc::clone(&counters[0]), Arc::clone(&counters[1]), Arc::clone(&counters[2]), Arc::clone(&counters[3]));
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut a = Echo { id: 1, peer: 2, owed: 0, heard: heard_a, said: said_a };
            let mut b = Echo { id: 2, peer: 1, owed: 0, heard: heard_b, said: said_b };
            let mut group: [&mut dyn AnyNode; 2] = [&mut a, &mut b];
            run_group(&mut group, &mut device, &MonotonicClock::new(), &stop)
        })
    };
    // Only node 1 starts: from then on they answer each other.
    master.send(CanFrame::standard(0x000, &[]).unwrap()).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    let before = master.pending();
    // The bus is still served: a second kick-off is heard (each node then owes one more).
    master.send(CanFrame::standard(0x000, &[]).unwrap()).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    stop.store(true, Ordering::SeqCst);
    let stats = thread.join().unwrap().unwrap();
    assert_eq!(stats.received, 2, "{stats:?}");
    let [heard_a, said_a, heard_b, said_b] = [0, 1, 2, 3].map(|i| counters[i].load(Ordering::SeqCst));
    assert!(said_a > 100 && said_b > 100, "{said_a} {said_b}");
    // Every frame one said reached the other, but those said in the very last turn.
    assert!(heard_b <= said_a && said_a - heard_b <= 2, "node 1 said {said_a}, node 2 heard {heard_b}");
    assert!(heard_a <= said_b && said_b - heard_a <= 2, "node 2 said {said_b}, node 1 heard {heard_a}");
    // And all of it went on the bus, turn after turn.
    assert!(before > 0);
    assert_eq!(master.pending() as u64 + master.dropped(), said_a + said_b);
}

/// An endpoint that hands out scripted reads: each read's frames come at once (the first from
/// `recv_timeout`, the others held, as `buffered` says), as a hub's frames do when the device's
/// thread was late; every frame sent is kept. Closed once the script is done.
struct Reads {
    reads: std::collections::VecDeque<Vec<CanFrame>>,
    held: std::collections::VecDeque<CanFrame>,
    sent: Arc<std::sync::Mutex<Vec<CanFrame>>>,
}

impl Endpoint for Reads {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        self.sent.lock().unwrap().push(frame);
        Ok(())
    }

    fn recv_timeout(&mut self, _timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        if let Some(frame) = self.held.pop_front() {
            return Ok(Some(frame));
        }
        let read = self.reads.pop_front().ok_or(TransportError::Closed)?;
        self.held.extend(read);
        Ok(self.held.pop_front())
    }

    fn buffered(&self) -> usize {
        self.held.len()
    }
}

/// Several SYNCs in one read (the device's thread was late, or the master sent them close
/// together): each gets its synchronous TPDO, as on a CAN bus where every SYNC is a frame of its
/// own, in a group and alone; the other frames of the read are still all handled before the
/// answers go out in one write.
#[test]
fn every_sync_of_one_read_gets_its_synchronous_tpdo() {
    use drive::node::{AnyNode, run_group};
    let frame = |id, data: &[u8]| CanFrame::standard(id, data).unwrap();
    let sync = frame(0x080, &[]);
    for grouped in [false, true] {
        let build = |kind: DeviceKind, id| {
            kind.build(&NodeConfig { node_id: Some(id), ..NodeConfig::default() }, &DefaultApps).unwrap()
        };
        let mut nodes = vec![build(DeviceKind::Drvi, 1)];
        if grouped {
            nodes.push(build(DeviceKind::Akd, 2));
        }
        let sent = Arc::new(std::sync::Mutex::new(Vec::new()));
        let mut bus = Reads {
            reads: [
                // TPDO 1 (181h, statusword) sent after every SYNC (1800h sub 2 = 1), started.
                vec![frame(0x601, &[0x2F, 0x00, 0x18, 0x02, 0x01, 0, 0, 0])],
                vec![frame(0x000, &[0x01, 0x01])],
                vec![sync, sync, sync],
                vec![sync, frame(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]), sync],
                vec![frame(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]), sync, sync],
            ]
            .into(),
            held: Default::default(),
            sent: Arc::clone(&sent),
        };
        let stop = AtomicBool::new(false);
        let mut group: Vec<&mut dyn AnyNode> = nodes.iter_mut().map(|n| &mut **n as &mut dyn AnyNode).collect();
        let end = run_group(&mut group, &mut bus, &MonotonicClock::new(), &stop);
        assert!(matches!(end, Err(TransportError::Closed)), "{end:?}");
        let sent = sent.lock().unwrap();
        let ids: Vec<u32> =
            sent.iter().map(|f| f.id()).filter(|id| *id != 0x702 && *id != 0x182 && *id != 0x282).collect();
        assert_eq!(
            ids,
            [0x701, 0x581, 0x181, 0x181, 0x181, 0x181, 0x581, 0x181, 0x581, 0x181, 0x181],
            "grouped {grouped}: {sent:?}"
        );
    }
}
