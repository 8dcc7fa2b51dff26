//! Over an slcan adapter: the master on `slcan://PTY`, the pseudo-terminal of drive's
//! simulated adapter (`drive-sim slcan`), whose CAN side is an in-memory bus with the drives
//! running on it in real time; the wire is emulated at the bit rate the master sets (S8,
//! 1 Mbit/s). The hub tests' work through it: scan, read and write, 10 KB in one segmented
//! download and one segmented upload (to a program-download target beside the drives: see
//! [`ProgramTarget`]), NMT with heartbeats, a home and move checked against 6064h.

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
        Self::start_with(nodes, Vec::new(), firmware)
    }

    /// The drives and `extra` nodes on one bus.
    fn start_with(nodes: &[(DeviceKind, u8)], extra: Vec<Box<dyn AnyNode>>, firmware: Firmware) -> Self {
        let bus = MemoryBus::new();
        let mut endpoint = bus.endpoint();
        let stop = Arc::new(AtomicBool::new(false));
        let mut nodes: Vec<_> = nodes.iter().map(|&(kind, id)| node(kind, id)).chain(extra).collect();
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

/// Scan, read, write (expedited and segmented), NMT with the heartbeat watched, through a
/// stock CANable (no acknowledgements).
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

/// A program-download target: CiA 302-3's program data, 1F50h sub 1, a DOMAIN of up to 16 KiB,
/// on od-runtime's device and SDO server (the drives' own, with a 16 KiB transfer buffer where
/// theirs have 1 KiB). None of the simulated drives has an object that large: their manuals
/// give none (the DRVI takes its firmware over USB, 7.8.2; the AKD's CANopen manual names no
/// program download), and a 10 KB transfer is what a program or a parameter file sent to a
/// bootloader is. It shares the bus with the drives, as such a node would.
struct ProgramTarget {
    dev: od_runtime::Device<ProgramData, (), od_runtime::NoStorage, PROGRAM_CAP>,
    last_poll: Option<od_runtime::Micros>,
}

/// 1F50h sub 1's capacity, and the SDO server's buffer.
const PROGRAM_CAP: usize = 16 * 1024;

/// The target's dictionary: 1000h, 1F50h sub 0 and sub 1 (the program data).
struct ProgramData {
    program: Vec<u8>,
}

static PROGRAM_EXTRAS: od_runtime::od::EntryExtras =
    od_runtime::od::EntryExtras { bits: (PROGRAM_CAP * 8) as u32, ..od_runtime::od::EntryExtras::NONE };

static PROGRAM_ENTRIES: [od_runtime::od::EntryInfo; 3] = {
    use od_runtime::od::{Access, DataType, EntryInfo};
    [
        EntryInfo::new(0x1000, 0, DataType::Unsigned32, Access::Ro, false),
        EntryInfo::new(0x1F50, 0, DataType::Unsigned8, Access::Ro, false),
        EntryInfo::new(0x1F50, 1, DataType::Domain, Access::Rw, false).with_extras(&PROGRAM_EXTRAS),
    ]
};

impl od_runtime::od::ObjectDictionary for ProgramData {
    fn entries(&self) -> &'static [od_runtime::od::EntryInfo] {
        &PROGRAM_ENTRIES
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, od_runtime::od::AbortCode> {
        let value: &[u8] = match (index, sub) {
            (0x1000, 0) => &[0, 0, 0, 0],
            (0x1F50, 0) => &[1],
            (0x1F50, 1) => &self.program,
            _ => return Err(self.info(index, sub).err().unwrap_or(od_runtime::od::AbortCode::NO_OBJECT)),
        };
        let out = buf.get_mut(..value.len()).ok_or(od_runtime::od::AbortCode::OUT_OF_MEMORY)?;
        out.copy_from_slice(value);
        Ok(value.len())
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), od_runtime::od::AbortCode> {
        match (index, sub) {
            (0x1F50, 1) if data.len() <= PROGRAM_CAP => {
                self.program = data.to_vec();
                Ok(())
            }
            (0x1F50, 1) => Err(od_runtime::od::AbortCode::LENGTH_TOO_HIGH),
            _ => Err(self.info(index, sub).err().unwrap_or(od_runtime::od::AbortCode::READ_ONLY)),
        }
    }

    fn restore_defaults(&mut self, _area: od_runtime::od::Area, _node_id: u8) {}
}

impl ProgramTarget {
    fn boxed(id: u8) -> Box<dyn AnyNode> {
        let id = od_runtime::NodeId::new(id).expect("a node id");
        let dev = od_runtime::Device::with_capacity(ProgramData { program: Vec::new() }, (), od_runtime::NoStorage, id);
        Box::new(Self { dev, last_poll: None })
    }
}

impl AnyNode for ProgramTarget {
    fn handle(&mut self, frame: &od_bus::CanFrame, now: od_runtime::Micros) {
        if let Ok(f) = od_runtime::Frame::try_from(*frame) {
            self.dev.on_frame(&f, now);
        }
    }
    fn poll(&mut self, now: od_runtime::Micros, emit: &mut dyn FnMut(od_bus::CanFrame)) {
        self.last_poll = Some(now);
        self.dev.poll(now, |f| emit(f.into()));
    }
    fn next_deadline(&self) -> od_runtime::Micros {
        self.last_poll.map_or(0, |t| t + 1_000)
    }
    fn node_id(&self) -> od_runtime::NodeId {
        self.dev.node_id()
    }
    fn nmt_state(&self) -> NmtState {
        self.dev.nmt_state()
    }
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, od_runtime::od::AbortCode> {
        let mut buf = vec![0; PROGRAM_CAP];
        let n = od_runtime::od::ObjectDictionary::read(self.dev.od(), index, sub, &mut buf)?;
        buf.truncate(n);
        Ok(buf)
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// 10 KB written to a program-download target's 1F50h sub 1 in one segmented download
/// (expedited and block off) and read back in one segmented upload, through a stock CANable at
/// 1 Mbit/s, the AKD on the same bus; the bytes read are the bytes written.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ten_kilobytes_go_both_ways_in_one_segmented_transfer_each() {
    let rig = Rig::start_with(&[(DeviceKind::Akd, 4)], vec![ProgramTarget::boxed(10)], Firmware::Canable);
    let bus = Bus::open(&rig.addr(1_000_000), Config::default()).await.unwrap();
    // (An upload longer than SdoOptions::max_len's default is refused by the client.)
    let segmented = SdoOptions {
        mode: Mode::Segmented,
        timeout: Duration::from_secs(2),
        max_len: PROGRAM_CAP,
        ..SdoOptions::default()
    };
    let target = bus.node(10).unwrap().with_options(segmented);
    // Bytes that show a lost, repeated or reordered segment (no period of 7).
    let mut x = 0x1234_5678u32;
    let data: Vec<u8> = (0..10 * 1024)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect();
    let t = std::time::Instant::now();
    target.write_bytes(0x1F50, 1, &data).await.unwrap_or_else(|e| panic!("{e}"));
    let down = t.elapsed();
    let t = std::time::Instant::now();
    let back = target.read_bytes(0x1F50, 1).await.unwrap_or_else(|e| panic!("{e}"));
    let up = t.elapsed();
    assert_eq!(back.len(), data.len());
    assert!(back == data, "the bytes read back differ from those written");
    // The drive beside it answers as before.
    assert_eq!(bus.node(4).unwrap().read::<u32>(0x1000, 0).await.unwrap() & 0xFFFF, 402);
    eprintln!("10 KB over slcan at 1 Mbit/s: download {down:?}, upload {up:?} (1,463 segments each way)");
}
