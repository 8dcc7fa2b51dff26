//! Over an slcan adapter: the master on `slcan://PTY`, the pseudo-terminal of drive's
//! simulated adapter (`drive-sim slcan`), whose CAN side is an in-memory bus with the drives
//! running on it in real time; the wire is emulated at the bit rate the master sets (S8,
//! 1 Mbit/s). The hub tests' work through it: scan, read and write, 10 KB in segmented
//! transfers, NMT with heartbeats, a home and move checked against 6064h.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use drive::node::{AnyNode, DeviceKind, MonotonicClock, run_group};
use drive::slcan::{Adapter, AdapterOptions, Firmware, Upstream};
use od_bus::MemoryBus;
use od_master::{Axis, Bus, Config, Event, Homing, Mode, Move, NmtState, NodeEvent, SdoOptions, Watch};

use crate::harness::node;

/// Drives on a memory bus, in real time on a thread, behind a simulated adapter.
struct Rig {
    adapter: Adapter,
    stop: Arc<AtomicBool>,
    devices: Option<std::thread::JoinHandle<()>>,
}

impl Rig {
    fn start(nodes: &[(DeviceKind, u8)], firmware: Firmware) -> Self {
        let bus = MemoryBus::new();
        let mut endpoint = bus.endpoint();
        let stop = Arc::new(AtomicBool::new(false));
        let mut nodes: Vec<_> = nodes.iter().map(|&(kind, id)| node(kind, id)).collect();
        let devices = {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                let mut group: Vec<&mut dyn AnyNode> = nodes.iter_mut().map(|n| &mut **n as &mut dyn AnyNode).collect();
                let _ = run_group(&mut group, &mut endpoint, &MonotonicClock::new(), &stop);
            })
        };
        let options = AdapterOptions { firmware, ..AdapterOptions::default() };
        let adapter = Adapter::start(Upstream::Memory(bus), &options).expect("a simulated adapter");
        Self { adapter, stop, devices: Some(devices) }
    }

    fn addr(&self, bitrate: u32) -> String {
        format!("slcan://{}?bitrate={bitrate}", self.adapter.path().display())
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(devices) = self.devices.take() {
            let _ = devices.join();
        }
    }
}

async fn next(events: &mut tokio::sync::broadcast::Receiver<Event>, mut pick: impl FnMut(&Event) -> bool) -> Event {
    let wait = async {
        loop {
            if let Ok(e) = events.recv().await
                && pick(&e)
            {
                return e;
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(5), wait).await.expect("the event in time")
}

/// Scan, read, write (expedited and segmented), 10 KB of segmented uploads, NMT with the
/// heartbeat watched, through a stock CANable (no acknowledgements).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_a_canable_the_master_scans_reads_writes_and_commands_nmt() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)], Firmware::Canable);
    let bus = Bus::open(&rig.addr(1_000_000), Config::default()).await.unwrap();
    // Scan: who answers 1000h among nodes 1 to 6.
    let mut found = Vec::new();
    for id in 1..=6u8 {
        let n = bus.node(id).unwrap().with_timeout(Duration::from_millis(100)).with_retries(0);
        if let Ok(device_type) = n.read::<u32>(0x1000, 0).await {
            found.push((id, device_type & 0xFFFF));
        }
    }
    assert_eq!(found, [(2, 402), (4, 402)]);
    let drive = bus.node(2).unwrap();
    for (k, v) in [1u32, 6000, 123_456].into_iter().enumerate() {
        let mode = [Mode::Normal, Mode::Segmented, Mode::Normal][k];
        let d = drive.clone().with_options(SdoOptions { mode, ..SdoOptions::default() });
        d.write_idempotent(0x6083, 0, v).await.unwrap();
        assert_eq!(d.read::<u32>(0x6083, 0).await.unwrap(), v, "{mode:?}");
    }
    // 10 KB through segmented uploads of the AKD's longest string (no object of these drives
    // holds 10 KB at once).
    let segmented = bus.node(4).unwrap().with_options(SdoOptions { mode: Mode::Segmented, ..SdoOptions::default() });
    let mut longest = (0, Vec::new());
    for index in [0x1008, 0x1009, 0x100A] {
        if let Ok(text) = segmented.read_bytes(index, 0).await
            && text.len() > longest.1.len()
        {
            longest = (index, text);
        }
    }
    let (index, name) = longest;
    assert!(!name.is_empty());
    let mut moved = name.len();
    while moved < 10 * 1024 {
        assert_eq!(segmented.read_bytes(index, 0).await.unwrap(), name);
        moved += name.len();
    }
    // NMT: the heartbeat watched, the node started, the state change seen.
    let mut events = bus.events();
    drive.write_idempotent(0x1017, 0, 50u16).await.unwrap();
    bus.watch(2, Watch::Heartbeat { timeout: 500_000 }, None).await.unwrap();
    next(&mut events, |e| matches!(e, Event::Node(NodeEvent::FirstSeen { node: 2, .. }))).await;
    drive.start().await.unwrap();
    let changed = next(&mut events, |e| matches!(e, Event::Node(NodeEvent::StateChanged { node: 2, .. }))).await;
    assert_eq!(
        changed,
        Event::Node(NodeEvent::StateChanged { node: 2, from: NmtState::PreOperational, to: NmtState::Operational })
    );
}

/// A home and a move of the DRVI through a Lawicel adapter (acknowledgements, status flags
/// polled), checked against 6064h; the adapter's replies never reach the master as frames;
/// then a bus-off, recovered by C and O.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_a_lawicel_adapter_a_drive_homes_and_moves() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 2)], Firmware::Lawicel);
    let bus = Bus::open(&rig.addr(500_000), Config::default()).await.unwrap();
    let axis = Axis::new(bus.node(2).unwrap());
    let home = axis.home(&Homing::method(37)).await.unwrap_or_else(|e| panic!("{e}"));
    let m = Move { velocity: Some(6_000), acceleration: Some(24_000), deceleration: Some(24_000), ..Move::default() };
    let at = axis.move_to(3_600, &m).await.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((home, at), (0, 3_600));
    assert_eq!(axis.node().read::<i32>(0x6064, 0).await.unwrap(), 3_600);
    assert!(rig.adapter.is_open());
    // The controller goes bus-off: the status flags say so at the next poll, the bus closes
    // and opens the channel (seen as a short outage), and transfers go on.
    let mut link = bus.link();
    rig.adapter.bus_off();
    tokio::time::timeout(
        Duration::from_secs(5),
        link.wait_for(|s| matches!(s, od_bus::tokio::LinkState::Up { reconnects: 1 })),
    )
    .await
    .expect("recovered from bus-off in time")
    .unwrap();
    assert_eq!(axis.node().read::<i32>(0x6064, 0).await.unwrap(), 3_600);
}

/// The adapter unplugged and plugged in again under the same name: the master's link goes
/// down and comes back, and the next transfer succeeds.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_adapter_unplugged_and_plugged_in_again_carries_the_next_transfer() {
    let bus_side = MemoryBus::new();
    let mut endpoint = bus_side.endpoint();
    let stop = Arc::new(AtomicBool::new(false));
    let devices = {
        let stop = Arc::clone(&stop);
        let mut n = node(DeviceKind::Drvi, 2);
        std::thread::spawn(move || {
            let _ = drive::node::run(&mut *n, &mut endpoint, &MonotonicClock::new(), &stop);
        })
    };
    let dir = std::env::temp_dir().join(format!("od-master-slcan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("ttyACM0");
    let options = AdapterOptions { link: Some(link.clone()), ..AdapterOptions::default() };
    let adapter = Adapter::start(Upstream::Memory(bus_side.clone()), &options).unwrap();
    let bus = Bus::open(&format!("slcan://{}", link.display()), Config::default()).await.unwrap();
    let drive = bus.node(2).unwrap();
    assert_eq!(drive.read::<u32>(0x1000, 0).await.unwrap() & 0xFFFF, 402);
    let mut link_state = bus.link();
    adapter.stop();
    tokio::time::timeout(
        Duration::from_secs(5),
        link_state.wait_for(|s| matches!(s, od_bus::tokio::LinkState::Down { .. })),
    )
    .await
    .expect("link down in time")
    .unwrap();
    let _adapter = Adapter::start(Upstream::Memory(bus_side), &options).unwrap();
    tokio::time::timeout(
        Duration::from_secs(10),
        link_state.wait_for(|s| matches!(s, od_bus::tokio::LinkState::Up { reconnects: 1 })),
    )
    .await
    .expect("link up in time")
    .unwrap();
    assert_eq!(drive.read::<u32>(0x1000, 0).await.unwrap() & 0xFFFF, 402);
    stop.store(true, Ordering::SeqCst);
    devices.join().unwrap();
    let _ = std::fs::remove_dir_all(&dir);
}
