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
use od_master::boot::{self, BootOptions, Network};
use od_master::remote::{Quantity, Unit, dim};
use od_master::{Axis, Bus, Config, Error, Event, Homing, HomingMethod, Move, SdoContext};

use crate::client::{akd, drcs, drvi};
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

/// `q` is exactly `num / den` in `unit`.
fn is(q: &Quantity<dim::Position>, num: i128, den: i128, unit: Unit) -> bool {
    q.unit() == unit && q.value().num() * den == num * q.value().den()
}

/// networks/example.toml booted over the hub, then each drive driven through its generated
/// client in the units its sidecar and the network leave it in: homed, moved in user units, and
/// its position in deg, mm or user units checked against the raw 6064h and the scaling objects
/// read separately. All three at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_the_hub_the_example_network_boots_and_each_drive_moves_through_its_client() {
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    let bus = Bus::open(&format!("socketcand://{}/can0", rig.addr()), Config::default()).await.unwrap();
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../networks/example.toml");
    let network = Network::from_description(&file).unwrap();
    for r in boot::boot(&bus, &network, &BootOptions::default()).await {
        assert!(r.result.is_ok() && r.started && r.written == r.planned, "{}: {:?}", r.name, r.result);
    }
    let node = |id| bus.node(id).unwrap();

    // DRVI, 2014h = 0 (only motor): 0.01 deg per unit, times 2001h denominator / numerator.
    let x = async {
        let drive = drvi::remote::Remote::new(node(2));
        assert_eq!(drive.actuator_type().read().await.unwrap(), 0);
        let units = drive.units().await.unwrap();
        assert_eq!(units.system(), drvi::units::System::OnlyMotor);
        drive.profile_velocity().write_in(&units, Quantity::rpm(120)).await.unwrap();
        let axis = Axis::new(drive.node().clone()).with_units(units);
        let home = axis.home(HomingMethod(37)).await.unwrap_or_else(|e| panic!("{e}"));
        assert!(is(&home, 0, 1, Unit::Degree), "{}", home.to_f64());
        let ramps = Move { acceleration: Some(24_000), deceleration: Some(24_000), ..Move::default() };
        let at = axis.move_to_with(Quantity::deg(45), &ramps).await.unwrap_or_else(|e| panic!("{e}"));
        let raw = i128::from(drive.node().read::<i32>(0x6064, 0).await.unwrap());
        let num = i128::from(drive.node().read::<u32>(0x2001, 1).await.unwrap());
        let den = i128::from(drive.node().read::<u32>(0x2001, 2).await.unwrap());
        assert!(is(&at, raw * den, 100 * num, Unit::Degree), "{} deg, 6064h = {raw}", at.to_f64());
        assert!(is(&axis.position().await.unwrap(), 45, 1, Unit::Degree));
        raw
    };
    // DRCS, actuator: mm, times 2001h denominator / numerator.
    let y = async {
        let drive = drcs::remote::Remote::new(node(3));
        let units = drive.units().await.unwrap();
        assert_eq!(units.system(), drcs::units::System::Actuator);
        drive.profile_velocity_in_pp_mode().write_in(&units, Quantity::mm_per_s(200)).await.unwrap();
        let axis = Axis::new(drive.node().clone()).with_units(units);
        axis.home(HomingMethod(37)).await.unwrap_or_else(|e| panic!("{e}"));
        let ramps = Move { acceleration: Some(2_000), deceleration: Some(2_000), ..Move::default() };
        let at = axis.move_to_with(Quantity::mm(15), &ramps).await.unwrap_or_else(|e| panic!("{e}"));
        let raw = i128::from(drive.node().read::<i32>(0x6064, 0).await.unwrap());
        let num = i128::from(drive.node().read::<u32>(0x2001, 1).await.unwrap());
        let den = i128::from(drive.node().read::<u32>(0x2001, 2).await.unwrap());
        assert!(is(&at, raw * den, num, Unit::Millimeter), "{} mm, 6064h = {raw}", at.to_f64());
        raw
    };
    // AKD: user units, 6092h feed per shaft revolutions of the motor.
    let z = async {
        let drive = akd::remote::Remote::new(node(4));
        let units = drive.units().await.unwrap();
        drive.profile_velocity().write_in(&units, Quantity::user_per_s(20)).await.unwrap();
        let axis = Axis::new(drive.node().clone()).with_units(units);
        axis.home(HomingMethod(35)).await.unwrap_or_else(|e| panic!("{e}"));
        let ramps = Move { acceleration: Some(200), deceleration: Some(200), ..Move::default() };
        let at = axis.move_to_with(Quantity::user(1), &ramps).await.unwrap_or_else(|e| panic!("{e}"));
        let raw = drive.node().read::<i32>(0x6064, 0).await.unwrap();
        let feed = i128::from(drive.node().read::<u32>(0x6092, 1).await.unwrap());
        let shaft = i128::from(drive.node().read::<u32>(0x6092, 2).await.unwrap());
        assert!(is(&at, raw.into(), 1, Unit::UserUnit), "{} user units, 6064h = {raw}", at.to_f64());
        let turns = units.to_internal(akd::units::Dimension::Position, raw.into()).unwrap();
        assert_eq!(turns.num() * feed, i128::from(raw) * shaft * turns.den(), "motor turns of 6064h = {raw}");
        i128::from(raw)
    };
    assert_eq!(tokio::join!(x, y, z), (4_500, 15, 1));
    drop(bus);
    rig.shutdown();
}

/// The hub goes away mid-session and comes back on the same port: a transfer meanwhile that
/// may wait only briefly fails saying the link is down (not a bare SDO timeout); one issued
/// during the outage with the default wait (`SdoOptions::link_wait`, 10 s) goes out once the
/// link is back and succeeds with the right value; the link reports down and up.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_hub_restarted_a_read_waits_for_the_link_and_succeeds() {
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2)]);
    let addr = rig.addr();
    let bus = Bus::open(&format!("socketcand://{addr}/can0"), Config::default()).await.unwrap();
    let mut events = bus.events();
    let drive = bus.node(2).unwrap().with_timeout(Duration::from_millis(200)).with_retries(0);
    let device_type = drive.read::<u32>(0x1000, 0).await.unwrap();
    rig.shutdown();
    let e = drive.clone().with_link_wait(Duration::from_millis(300)).read::<u32>(0x1000, 0).await.unwrap_err();
    assert!(matches!(&e, Error::Sdo { context: Some(SdoContext::LinkDown { .. }), .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.starts_with("node 2, upload of 1000h sub 0: the link to the bus is down ("), "{text}");
    assert!(text.contains("it did not come back within SdoOptions::link_wait"), "{text}");

    // Issued while the hub is gone; the hub comes back 0.5 s later.
    let issued = std::time::Instant::now();
    let pending = tokio::spawn({
        let drive = drive.clone();
        async move { drive.read::<u32>(0x1000, 0).await }
    });
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(!pending.is_finished(), "the read waits for the link");
    let rig = Rig::start(&addr.to_string(), &[(DeviceKind::Drvi, 2)]);
    let value = tokio::time::timeout(Duration::from_secs(10), pending).await.expect("within the link wait");
    assert_eq!(value.unwrap().unwrap_or_else(|e| panic!("{e}")), device_type);
    eprintln!("a read issued during a 0.5 s hub outage succeeded {:?} after it was issued", issued.elapsed());
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

/// Over the hub, the waits of #36 that could not succeed end at once and say why: the AKD's
/// homing with its default method 0 (6098h) fails before anything moves; its move into the
/// positive limit switch (+2 turns) ends as statusword bit 11 goes up (0AB7h), not after 30 s;
/// the DRVI's profile-position move with its default profile velocity 0 (6081h) fails before
/// the set-point, where it used to be "not acknowledged" after a second.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_the_hub_waits_that_cannot_succeed_end_at_once_saying_why() {
    use od_master::{AxisErrorKind, Impossible, StopReason};
    use std::time::Instant;
    let rig = Rig::start("127.0.0.1:0", &[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    let bus = Bus::open(&format!("socketcand://{}/can0", rig.addr()), Config::default()).await.unwrap();
    let kind = |e: &Error| match e {
        Error::Axis(a) => format!("{:?}", a.kind),
        e => panic!("{e}"),
    };
    let akd = Axis::new(bus.node(4).unwrap());
    let method = akd.node().read::<i8>(0x6098, 0).await.unwrap();
    let t = Instant::now();
    let e = akd.home(HomingMethod(method)).await.unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    assert_eq!(kind(&e), format!("{:?}", AxisErrorKind::Impossible(Impossible::NoHomingMethod)), "{e}");
    assert!(e.to_string().contains("homing method 0 (6098h)"), "{e}");

    let sidecar = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../devices/kollmorgen-akd.toml");
    let sidecar = od_sidecar::Sidecar::read(&sidecar).unwrap();
    bus.set_emcy_texts(4, od_master::EmcyTexts::from_sidecar(&sidecar)).await.unwrap();
    let akd = akd.with_register(od_master::StatusRegister::from_sidecar(&sidecar).unwrap());
    akd.node().write_idempotent(0x6092, 1, 10_000u32).await.unwrap();
    akd.home(HomingMethod(35)).await.unwrap_or_else(|e| panic!("{e}"));
    let m =
        Move { velocity: Some(40_000), acceleration: Some(400_000), deceleration: Some(400_000), ..Move::default() };
    let t = Instant::now();
    let e = akd.move_to(100_000, &m).await.unwrap_err();
    // 2 turns at 4 turns/s: 0.6 s to the switch, then at once.
    assert!(t.elapsed() < Duration::from_millis(1_600), "{:?}: {e}", t.elapsed());
    let Error::Axis(a) = &e else { panic!("{e}") };
    // Whichever says it first: the statusword's bit 11 or the EMCY 8612h (limit switch).
    let why = match &a.kind {
        AxisErrorKind::Stopped {
            why: why @ (StopReason::AtLimit(_) | StopReason::InternalLimit | StopReason::Emergency { .. }),
            ..
        } => why,
        _ => panic!("{e}"),
    };
    if let StopReason::Emergency { code, text } = why {
        assert_eq!(*code, 0x8612, "{e}");
        assert!(text.is_some(), "the sidecar's text: {e}");
    }
    assert!(e.to_string().contains("internal limit active"), "{e}");
    eprintln!("AKD into its limit switch: {e}");
    // On the switch: further in is refused at once, naming it; out is taken and succeeds.
    let t = Instant::now();
    let e = akd.move_to(120_000, &m).await.unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    assert!(matches!(&e, Error::Axis(a) if matches!(a.kind, AxisErrorKind::Impossible(Impossible::IntoLimit { .. }))));
    assert!(e.to_string().contains("limited by its positive limit switch (digital inputs 60FDh = "), "{e}");
    eprintln!("AKD further into its limit switch ({:?}): {e}", t.elapsed());
    let t = Instant::now();
    assert_eq!(akd.move_to(0, &m).await.unwrap_or_else(|e| panic!("{e}")), 0);
    eprintln!("AKD out of its limit switch to 0: {:?}", t.elapsed());

    let drvi = Axis::new(bus.node(2).unwrap());
    drvi.home(HomingMethod(37)).await.unwrap_or_else(|e| panic!("{e}"));
    let t = Instant::now();
    let e = drvi.move_to(3_600, &Move::default()).await.unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    assert_eq!(kind(&e), format!("{:?}", AxisErrorKind::Impossible(Impossible::NoProfileVelocity)), "{e}");
    assert!(e.to_string().contains("profile velocity 6081h is 0"), "{e}");
    drop(bus);
    rig.shutdown();
}
