//! Over TCP: the master on a socketcand hub (the hub `drive-sim hub` runs), the simulated
//! drives attached to it in real time on threads of their own.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use drive::node::{DeviceKind, MonotonicClock, run};
use od_bus::tokio::LinkState;
use od_bus::{Hub, HubConfig};
use od_master::{Axis, Bus, Config, Event, Homing, Move};

use crate::harness::node;

/// A hub with drives running on it.
struct Rig {
    hub: Hub,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Rig {
    fn start(addr: &str, nodes: &[(DeviceKind, u8)]) -> Self {
        let hub = Hub::bind(addr, HubConfig::default().quiet()).expect("bind the hub");
        let stop = Arc::new(AtomicBool::new(false));
        let threads = nodes
            .iter()
            .map(|&(kind, id)| {
                let mut ep = hub.attach("can0").unwrap();
                let stop = Arc::clone(&stop);
                let mut n = node(kind, id);
                std::thread::spawn(move || {
                    // Ends with the hub (the endpoint closes) or the stop flag.
                    let _ = run(&mut *n, &mut ep, &MonotonicClock::new(), &stop);
                })
            })
            .collect();
        Self { hub, stop, threads }
    }

    fn addr(&self) -> SocketAddr {
        self.hub.local_addr()
    }

    fn shutdown(self) {
        self.stop.store(true, Ordering::SeqCst);
        self.hub.stop();
        for t in self.threads {
            t.join().unwrap();
        }
    }
}

/// Each drive homes and moves over the hub, all three at once; the position each reports is
/// its 6064h, at the target.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_the_hub_each_drive_homes_and_moves() {
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    let bus = Bus::open(&format!("socketcand://{}/can0", rig.addr()), Config::default()).await.unwrap();
    let go = |id: u8, method: i8, target: i32, v: u32| {
        let axis = Axis::new(bus.node(id).unwrap());
        async move {
            if id == 4 {
                axis.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
            }
            let home = axis.home(&Homing::method(method)).await.unwrap_or_else(|e| panic!("{e}"));
            let m = Move { velocity: Some(v), acceleration: Some(v * 4), deceleration: Some(v * 4), ..Move::default() };
            let at = axis.move_to(target, &m).await.unwrap_or_else(|e| panic!("{e}"));
            (home, at, axis.node().read::<i32>(0x6064, 0).await.unwrap())
        }
    };
    // DRVI 36° at 60 rpm, DRCS 100 of its 1000 at 200/s, AKD half a turn at 1 turn/s.
    let (a, b, c) = tokio::join!(go(2, 37, 3_600, 6_000), go(3, 37, 100, 200), go(4, 35, 5_000, 10_000));
    assert_eq!(a, (0, 3_600, 3_600));
    assert_eq!(b, (0, 100, 100));
    assert_eq!(c, (0, 5_000, 5_000));
    drop(bus);
    rig.shutdown();
}

/// The hub goes away mid-session and comes back on the same port: transfers meanwhile fail
/// with a timeout naming the node, the link reports down and up, and the next transfer
/// succeeds with the right value.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hub_restarted_the_bus_reconnects_and_the_next_transfer_succeeds() {
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2)]);
    let addr = rig.addr();
    let bus = Bus::open(&format!("socketcand://{addr}/can0"), Config::default()).await.unwrap();
    let mut events = bus.events();
    let drive = bus.node(2).unwrap().with_timeout(Duration::from_millis(200)).with_retries(0);
    let device_type = drive.read::<u32>(0x1000, 0).await.unwrap();
    rig.shutdown();
    let e = drive.read::<u32>(0x1000, 0).await.unwrap_err();
    assert!(e.to_string().starts_with("node 2, upload of 1000h sub 0: aborted by the client: 0x05040000"), "{e}");
    let rig = Rig::start(&addr.to_string(), &[(DeviceKind::Drvi, 2)]);
    let mut link = bus.link();
    let up = tokio::time::timeout(
        Duration::from_secs(10),
        link.wait_for(|s| matches!(s, LinkState::Up { reconnects: 1.. })),
    );
    up.await.expect("reconnected within 10 s").unwrap();
    let drive = drive.with_timeout(Duration::from_secs(1)).with_retries(2);
    assert_eq!(drive.read::<u32>(0x1000, 0).await.unwrap(), device_type);
    let mut saw = (false, false);
    while let Ok(e) = events.try_recv() {
        match e {
            Event::Link(LinkState::Down { .. }) => saw.0 = true,
            Event::Link(LinkState::Up { .. }) => saw.1 = true,
            _ => {}
        }
    }
    assert_eq!(saw, (true, true), "link events");
    drop(bus);
    rig.shutdown();
}

/// The blocking facade, from a plain thread: the same values as the async master, and a drive
/// enabled and moved.
#[test]
fn the_blocking_facade_reads_writes_and_moves_a_drive() {
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2)]);
    let bus = od_master::blocking::Bus::open(&format!("socketcand://{}/can0", rig.addr()), Config::default()).unwrap();
    let drive = bus.node(2).unwrap();
    assert_eq!(drive.read::<u32>(0x1000, 0).unwrap(), 0xFF7A_0192);
    drive.write_idempotent(0x6083, 0, 600u32).unwrap();
    assert_eq!(drive.read::<u32>(0x6083, 0).unwrap(), 600);
    let axis = drive.axis();
    assert_eq!(axis.home(&Homing::method(37)).unwrap(), 0);
    let m = Move { velocity: Some(6_000), acceleration: Some(24_000), deceleration: Some(24_000), ..Move::default() };
    assert_eq!(axis.move_to(1_800, &m).unwrap(), 1_800);
    drop((axis, drive, bus));
    rig.shutdown();
}
