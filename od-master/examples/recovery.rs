//! Recovery time and soak of the supervisor (a benchmark, not a test: it reports).
//!
//! ```text
//! recovery mem [ROUNDS]                          the three drives on the in-memory bus, real time
//! recovery hub ADDR SOCKET [ROUNDS]              over a hub: drives of `drive-sim run --control SOCKET`
//! recovery soak ADDR SOCKET SECONDS [MIN_S MAX_S]  random power cycles every MIN..MAX s (10..30)
//! ```
//!
//! networks/example.toml is supervised with SYNC every 1 ms. Each round power-cycles each
//! drive in turn (off 5 ms) and records the supervisor's time from the boot-up message to the
//! node Operational again (its `Reconfigured` event). The soak counts reboots seen, nodes
//! reconfigured, configurations read back wrong, and TPDO 2 (sent after every SYNC) missing on
//! the drives not being power-cycled.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use od_master::supervisor::{Supervisor, SupervisorEvent, verify};
use od_master::{Bus, Config, Network};
use tokio::sync::broadcast;

fn example() -> Network {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../networks/example.toml");
    Network::from_description(&path).expect("networks/example.toml")
}

/// How a drive is power-cycled.
enum Injector {
    Mem(Vec<(u8, drive::node::FaultHandle)>),
    Socket(PathBuf),
}

impl Injector {
    fn power_cycle(&self, node: u8) {
        match self {
            Injector::Mem(handles) => {
                if let Some((_, h)) = handles.iter().find(|(id, _)| *id == node) {
                    h.inject(drive::node::Fault::PowerCycle { off: 5_000 });
                }
            }
            Injector::Socket(path) => control(path, &format!("{node} power-cycle 5")),
        }
    }
}

fn control(path: &Path, line: &str) {
    let mut s = std::os::unix::net::UnixStream::connect(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    writeln!(s, "{line}").unwrap();
    let mut answer = String::new();
    BufReader::new(s).read_line(&mut answer).unwrap();
    assert_eq!(answer.trim(), "ok", "{line}");
}

/// Boot-up to started (configured, NMT start sent) and to the heartbeat saying Operational.
async fn next_reconfigured(events: &mut broadcast::Receiver<SupervisorEvent>, node: u8) -> (Duration, Duration) {
    loop {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(SupervisorEvent::Reconfigured { node: n, elapsed, started, .. })) if n == node => {
                return (started.unwrap_or(elapsed), elapsed);
            }
            Ok(Ok(SupervisorEvent::BootFailed { message, .. })) => panic!("boot failed: {message}"),
            Ok(Ok(_)) | Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
            other => panic!("no reconfiguration of node {node}: {other:?}"),
        }
    }
}

async fn booted(events: &mut broadcast::Receiver<SupervisorEvent>, n: usize) {
    let mut seen = 0;
    while seen < n {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(SupervisorEvent::Booted { .. })) => seen += 1,
            Ok(Ok(SupervisorEvent::BootFailed { message, .. })) => panic!("boot failed: {message}"),
            Ok(_) => {}
            Err(_) => panic!("the network did not boot"),
        }
    }
}

fn stats(name: &str, mut v: Vec<f64>) {
    v.sort_by(f64::total_cmp);
    let median = v[v.len() / 2];
    println!(
        "{name} over {} cycles: min {:.1} ms, median {:.1} ms, max {:.1} ms",
        v.len(),
        v[0],
        median,
        v[v.len() - 1]
    );
}

async fn rounds(bus: Bus, injector: Injector, rounds: usize) {
    let network = example();
    let supervisor = Supervisor::new(bus.clone(), network.clone());
    let mut events = supervisor.events();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(supervisor.run(async move {
        let _ = stopped.await;
    }));
    booted(&mut events, network.nodes.len()).await;
    bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut times: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for _ in 0..rounds {
        for n in &network.nodes {
            injector.power_cycle(n.node_id);
            let (started, confirmed) = next_reconfigured(&mut events, n.node_id).await;
            let name = format!("{} (node {})", n.name, n.node_id);
            times
                .entry(format!("{name}: boot-up -> configured and started"))
                .or_default()
                .push(started.as_secs_f64() * 1e3);
            times
                .entry(format!("{name}: boot-up -> heartbeat says Operational"))
                .or_default()
                .push(confirmed.as_secs_f64() * 1e3);
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    for (name, v) in times {
        stats(&name, v);
    }
    let _ = stop.send(());
    let _ = task.await;
}

/// A small xorshift: the soak's random intervals and drives, no dependency for it.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

/// Every SYNC, TPDO 2 and boot-up in the hub's order, from a connection of its own: for each
/// drive, the SYNCs it has not answered with its TPDO 2.
///
/// A boot-up forgives the SYNCs the drive could not answer because it was off: those since its
/// last TPDO 2, and also those in flight at that TPDO 2 — SYNCs that reached the hub after the
/// SYNC it answered but before its answer (frames of the drives and of the master interleave
/// in the hub as on a CAN bus; a drive that goes off right after leaves such a SYNC
/// unanswered). What was in flight is what the count held above its least value right after
/// one of its last [`SETTLE`] TPDO 2. Nothing counts for the drive from its boot-up to its
/// first TPDO 2 after (it is being configured), and no TPDO 2 brings its count below where the
/// boot-up left it (such a TPDO 2 answers a SYNC of that time, not counted). A SYNC left
/// unanswered at any other time stays counted.
#[derive(Default)]
struct Unanswered {
    /// SYNCs not answered yet.
    owed: i64,
    /// `owed` right after each of its last [`SETTLE`] TPDO 2.
    after: std::collections::VecDeque<i64>,
    /// Where its last boot-up left `owed`.
    floor: i64,
    /// Between its boot-up and its first TPDO 2.
    rebooting: bool,
    /// The hub's frames up to its last TPDO 2, when a SYNC was in flight at it.
    overtaken: Option<Vec<(Duration, od_bus::CanFrame)>>,
}

/// TPDO 2 (one a SYNC: 1 ms each) over which the least count is the settled one.
const SETTLE: usize = 50;
/// Frames kept to show where a SYNC in flight was forgiven, or a TPDO 2 not counted.
const CONTEXT: usize = 24;
/// Such cases shown at most.
const SHOWN: usize = 3;

/// What [`count_in_hub_order`] found.
#[derive(Debug, Default)]
struct HubCount {
    /// SYNCs not answered, per drive.
    unanswered: BTreeMap<u8, i64>,
    /// Frames the hub dropped for the counting connection.
    lost: u64,
    /// SYNCs in flight at a drive's last TPDO 2 before its power cycle, forgiven.
    in_flight: i64,
    /// TPDO 2 right after a drive's boot-up answering a SYNC of its configuration time.
    early: i64,
}

fn show(frames: impl Iterator<Item = (Duration, od_bus::CanFrame)>) {
    for (at, f) in frames {
        println!("  {:>12.3} ms  {:03X}  {:02X?}", at.as_secs_f64() * 1e3, f.id(), f.data());
    }
}

async fn count_in_hub_order(addr: String, nodes: Vec<u8>) -> HubCount {
    let mut link = od_bus::tokio::Bus::open(&addr).await.expect("a listening connection to the hub");
    let mut per_node: BTreeMap<u8, Unanswered> = nodes.iter().map(|n| (*n, Unanswered::default())).collect();
    let start = Instant::now();
    let mut recent: std::collections::VecDeque<(Duration, od_bus::CanFrame)> = Default::default();
    let mut count = HubCount::default();
    let mut shown = 0;
    loop {
        let Ok(frame) = link.recv().await else { break };
        if recent.len() == CONTEXT {
            recent.pop_front();
        }
        recent.push_back((start.elapsed(), frame));
        let node =
            |base: u32| u8::try_from(frame.id().wrapping_sub(base)).ok().and_then(|n| nodes.contains(&n).then_some(n));
        match frame.id() {
            0x080 => per_node.values_mut().filter(|u| !u.rebooting).for_each(|u| u.owed += 1),
            0x7FF => break,
            id if id & !0x7F == 0x280 => {
                if let Some((n, u)) = node(0x280).and_then(|n| per_node.get_mut(&n).map(|u| (n, u))) {
                    if std::mem::take(&mut u.rebooting) {
                        u.owed = u.floor;
                    } else if u.owed - 1 < u.floor {
                        count.early += 1;
                        if shown < SHOWN {
                            shown += 1;
                            println!(
                                "node {n}'s TPDO 2 answers a SYNC that came before its first TPDO 2 after its \
                                 boot-up (not counted); the hub's frames up to it:"
                            );
                            show(recent.iter().copied());
                        }
                    } else {
                        u.owed -= 1;
                    }
                    if u.after.len() == SETTLE {
                        u.after.pop_front();
                    }
                    u.after.push_back(u.owed);
                    let least = u.after.iter().copied().min().unwrap_or(u.owed);
                    u.overtaken = (u.owed > least).then(|| recent.iter().copied().collect());
                }
            }
            id if id & !0x7F == 0x700 && frame.data() == [0] => {
                if let Some((n, u)) = node(0x700).and_then(|n| per_node.get_mut(&n).map(|u| (n, u))) {
                    let at_last = u.after.back().copied().unwrap_or(u.owed);
                    let settled = u.after.iter().copied().min().unwrap_or(u.owed);
                    count.in_flight += at_last - settled;
                    if let Some(frames) = u.overtaken.take()
                        && shown < SHOWN
                    {
                        shown += 1;
                        println!(
                            "node {n}'s last TPDO 2 before its power cycle came after {} SYNC(s) it never answered \
                             (it went off), forgiven; the hub's frames up to that TPDO 2:",
                            at_last - settled
                        );
                        show(frames.into_iter());
                    }
                    u.owed = settled;
                    u.floor = settled;
                    u.rebooting = true;
                    u.after.clear();
                }
            }
            _ => {}
        }
    }
    count.unanswered = per_node.into_iter().map(|(n, u)| (n, u.owed)).collect();
    count.lost = link.lost();
    count
}

async fn soak(bus: Bus, addr: &str, injector: Injector, seconds: u64, min_s: f64, max_s: f64) {
    let network = example();
    let supervisor = Supervisor::new(bus.clone(), network.clone());
    let mut events = supervisor.events();
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let task = tokio::spawn(supervisor.run(async move {
        let _ = stopped.await;
    }));
    booted(&mut events, network.nodes.len()).await;
    let counter = tokio::spawn(count_in_hub_order(addr.to_owned(), network.nodes.iter().map(|n| n.node_id).collect()));
    tokio::time::sleep(Duration::from_millis(100)).await;
    bus.start_sync(Duration::from_millis(1), 0).await.unwrap();
    let mut frames = bus.frames();
    let syncs = bus.syncs();
    let mut rng = Rng(Instant::now().elapsed().as_nanos() as u64 | 0x9E37_79B9_7F4A_7C15);
    let end = Instant::now() + Duration::from_secs(seconds);
    let (mut cycles, mut reconfigured, mut wrong, mut missed, mut lagged) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut times = Vec::new();
    // SYNCs minus TPDO 2 in one window, for one drive: the least and the most seen (the count
    // above forgives 2 a window, one at each edge; this shows what the edges really took).
    let (mut least, mut most) = (i64::MAX, i64::MIN);
    while Instant::now() < end {
        let wait = min_s + (max_s - min_s) * (rng.next() % 1000) as f64 / 1000.0;
        tokio::time::sleep(Duration::from_secs_f64(wait)).await;
        let victim = &network.nodes[(rng.next() % network.nodes.len() as u64) as usize];
        // TPDO 2 of the others, counted from the power cycle to 100 ms after the reconfiguration.
        // Everything older is dropped (a lagged reader resumes with what is left: drained too).
        while let Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) = frames.try_recv() {}
        let sync_before = *syncs.borrow();
        injector.power_cycle(victim.node_id);
        cycles += 1;
        let (_, t) = next_reconfigured(&mut events, victim.node_id).await;
        reconfigured += 1;
        times.push(t.as_secs_f64() * 1e3);
        tokio::time::sleep(Duration::from_millis(100)).await;
        let sync_count = *syncs.borrow() - sync_before;
        let mut tpdo2: BTreeMap<u32, u64> = BTreeMap::new();
        loop {
            match frames.try_recv() {
                Ok(f) => *tpdo2.entry(f.id()).or_default() += 1,
                Err(broadcast::error::TryRecvError::Lagged(n)) => lagged += n,
                Err(_) => break,
            }
        }
        for other in network.nodes.iter().filter(|n| n.node_id != victim.node_id) {
            let got = tpdo2.get(&(0x280 + u32::from(other.node_id))).copied().unwrap_or(0);
            // One at each edge of the window may fall outside it.
            missed += sync_count.saturating_sub(got + 2);
            let short = sync_count as i64 - got as i64;
            (least, most) = (least.min(short), most.max(short));
        }
        if let Err(e) = verify(&bus, victim).await {
            eprintln!("wrong configuration of {}: {e}", victim.name);
            wrong += 1;
        }
    }
    println!(
        "soak {seconds} s: {cycles} power cycles, {cycles} reboots seen, {reconfigured} reconfigured, \
         {wrong} wrong configurations, {missed} TPDO 2 missed on the other drives while one rebooted ({lagged} frames not seen in those windows: reader lagged)"
    );
    // The last SYNC's answers in, then the listener told to end (an id nobody else uses).
    bus.stop_sync().await.ok();
    tokio::time::sleep(Duration::from_millis(200)).await;
    bus.send(od_bus::CanFrame::standard(0x7FF, &[]).unwrap()).await.ok();
    match tokio::time::timeout(Duration::from_secs(5), counter).await {
        Ok(Ok(HubCount { unanswered, lost, in_flight, early })) => println!(
            "in the hub's order, whole soak: SYNCs not answered by TPDO 2, per drive, outside its own power cycles: \
             {unanswered:?} (frames the hub dropped for this listener: {lost}; forgiven: {in_flight} SYNC(s) in flight \
             at a drive's last TPDO 2 before its power cycle; {early} TPDO 2 after a boot-up answering a SYNC of the \
             configuration time)"
        ),
        other => println!("the hub-order count did not end: {other:?}"),
    }
    if least <= most {
        println!("SYNCs minus TPDO 2 of one drive not rebooted, per window: from {least} to {most}");
    }
    if !times.is_empty() {
        stats("all drives: boot-up -> heartbeat says Operational", times);
    }
    let _ = stop.send(());
    let _ = task.await;
}

#[tokio::main]
async fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, default: f64| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    match args.first().map(String::as_str) {
        Some("mem") => {
            use drive::node::{DeviceKind, Faulty, NodeConfig, Sim};
            let mut sim = Sim::new();
            let mut handles = Vec::new();
            for (kind, id) in [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)] {
                let node = kind
                    .build(&NodeConfig { node_id: Some(id), ..Default::default() }, &drive::drives::DeviceApps::new())
                    .unwrap();
                let (faulty, handle) = Faulty::new(node);
                sim.add(Box::new(faulty));
                handles.push((id, handle));
            }
            let (bus, _sim) = drive::node::spawn_with_master(sim, Config::default(), Duration::from_micros(100));
            tokio::time::sleep(Duration::from_millis(20)).await;
            rounds(bus, Injector::Mem(handles), num(1, 10.0) as usize).await;
        }
        Some("hub") if args.len() >= 3 => {
            let bus = Bus::open(&args[1], Config::default()).await.expect("the bus");
            rounds(bus, Injector::Socket(PathBuf::from(&args[2])), num(3, 10.0) as usize).await;
        }
        Some("soak") if args.len() >= 4 => {
            let bus = Bus::open(&args[1], Config::default()).await.expect("the bus");
            let injector = Injector::Socket(PathBuf::from(&args[2]));
            let addr = args[1].clone();
            soak(bus, &addr, injector, num(3, 600.0) as u64, num(4, 10.0), num(5, 30.0)).await;
        }
        _ => {
            eprintln!(
                "usage: recovery mem [ROUNDS] | hub ADDR SOCKET [ROUNDS] | soak ADDR SOCKET SECONDS [MIN_S MAX_S]"
            );
            std::process::exit(2);
        }
    }
}
