//! Boots a network with `od-master`: each node's identity checked, its configuration and PDO
//! mappings written, and the nodes started (CiA 302-2), then the drives' TPDOs counted. Then
//! each axis is homed and moved through the client generated from its EDS, in the user units
//! its scaling objects give (the DRVI in degrees, the DRCS in mm, the AKD in its user units),
//! and the position it reports in those units is checked against the raw 6064h and the scaling
//! objects read separately.
//!
//! ```sh
//! cargo run -p network-boot                       # networks/example.toml on three simulated drives
//! cargo run -p network-boot -- --bus socketcand://127.0.0.1:29536/can0 networks/example.toml
//! ```
//!
//! Without `--bus`, the three drives of the example (a DRVI at node 2, a DRCS at 3, an AKD at 4)
//! run in this process on the in-memory bus `mem://network-boot`, in real time. Exit code 0 when
//! every node booted and every axis moved and read back right, 1 when not (each failure names
//! its node and object), 2 for bad usage.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use drive::drives::DeviceApps;
use drive::node::{DeviceKind, MonotonicClock, NodeConfig};
use od_master::boot::{self, BootOptions, Network};
use od_master::remote::{Quantity, Unit};
use od_master::{Axis, Bus, Config, Error, HomingMethod, Move};

// The clients of the three drives, generated from their EDS and sidecars.
od_macros::include_eds!("../../devices/camozzi-drvi.eds", mod drvi, client);
od_macros::include_eds!("../../devices/camozzi-drcs.eds", mod drcs, client);
od_macros::include_eds!("../../devices/kollmorgen-akd.eds", mod akd, client);

/// The example's drives, running on their own threads until dropped.
struct Drives {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Drives {
    /// The three drives of networks/example.toml on the in-memory bus named `bus`.
    fn start(bus: &str) -> Self {
        let memory = od_bus::MemoryBus::named(bus);
        let stop = Arc::new(AtomicBool::new(false));
        let threads = [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]
            .into_iter()
            .map(|(kind, id)| {
                let config = NodeConfig { node_id: Some(id), ..Default::default() };
                let mut node = kind.build(&config, &DeviceApps::new()).expect("a simulated drive");
                let mut endpoint = memory.endpoint();
                let stop = Arc::clone(&stop);
                std::thread::spawn(move || {
                    let _ = drive::node::run(&mut *node, &mut endpoint, &MonotonicClock::new(), &stop);
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Drives {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Boots `network` on `bus`, prints a line per node and the TPDOs each started node sends in
/// 200 ms; true when every node booted.
async fn boot_and_watch(bus: &Bus, network: &Network) -> bool {
    let mut frames = bus.frames();
    let reports = boot::boot(bus, network, &BootOptions::default()).await;
    for r in &reports {
        match &r.result {
            Ok(()) => println!("{} (node {}): {} writes, started", r.name, r.node_id, r.written),
            Err(e) => eprintln!("network-boot: {e}"),
        }
    }
    // What the started nodes send: TPDO 1 (180h + id) on event, at least every 20 ms.
    while frames.try_recv().is_ok() {}
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut tpdo1 = std::collections::BTreeMap::<u8, usize>::new();
    while let Ok(f) = frames.try_recv() {
        if (0x181..=0x1FF).contains(&f.id()) {
            *tpdo1.entry((f.id() - 0x180) as u8).or_default() += 1;
        }
    }
    for r in reports.iter().filter(|r| r.started) {
        println!("{}: {} TPDO 1 frames in 200 ms", r.name, tpdo1.get(&r.node_id).copied().unwrap_or(0));
    }
    reports.iter().all(|r| r.result.is_ok())
}

/// Where an axis ended, as its units say and as the raw 6064h and the scaling objects say.
struct Moved {
    /// The position read through the axis, in the drive's units.
    at: Quantity<od_master::remote::dim::Position>,
    /// 6064h, raw.
    raw: i32,
    /// The scaling objects read separately, as the line shows them (`2001h = 1/1`).
    scaling: String,
    /// Whether `at` is `raw` scaled by those objects' factor, exactly.
    scaled: bool,
    /// The target.
    target: Quantity<od_master::remote::dim::Position>,
}

/// `q` is exactly `num / den`.
fn is(q: &Quantity<od_master::remote::dim::Position>, num: i128, den: i128) -> bool {
    q.value().num() * den == num * q.value().den()
}

fn symbol(unit: Unit) -> &'static str {
    match unit {
        Unit::Degree => "deg",
        Unit::Millimeter => "mm",
        Unit::UserUnit => "user units",
        _ => "?",
    }
}

// Each axis moves back to 0 (its home) at the end, so that the example can run again on the
// same drives (the AKD's and the DRCS's machines have limit switches and end stops).

/// The DRVI of the example in its only-motor units (2014h = 0, its default): homed where it
/// is, 90 degrees at 120 rpm written in units, the ramps raw (rpm/s). 0.01 degree per 6064h
/// unit, times 2001h's denominator over its numerator.
async fn move_drvi(bus: &Bus, id: u8) -> Result<Moved, Error> {
    let drive = drvi::remote::Remote::new(bus.node(id)?);
    let units = drive.units().await?;
    drive.profile_velocity().write_in(&units, Quantity::rpm(120)).await?;
    let axis = Axis::new(drive.node().clone()).with_units(units);
    axis.home(HomingMethod(37)).await?;
    let target = Quantity::deg(90);
    let ramps = Move { acceleration: Some(24_000), deceleration: Some(24_000), ..Move::default() };
    axis.move_to_with(target, &ramps).await?;
    let at = axis.position().await?;
    let raw = drive.node().read::<i32>(0x6064, 0).await?;
    let (num, den) = (drive.node().read::<u32>(0x2001, 1).await?, drive.node().read::<u32>(0x2001, 2).await?);
    let scaled = at.unit() == Unit::Degree && is(&at, i128::from(raw) * i128::from(den), 100 * i128::from(num));
    axis.move_to_with(Quantity::deg(0), &ramps).await?;
    Ok(Moved { at, raw, scaling: format!("2001h = {num}/{den}, 0.01 deg"), scaled, target })
}

/// The DRCS of the example in mm (its actuator units): homed where it is, 20 mm at 200 mm/s.
/// 1 mm per 6064h unit, times 2001h's denominator over its numerator.
async fn move_drcs(bus: &Bus, id: u8) -> Result<Moved, Error> {
    let drive = drcs::remote::Remote::new(bus.node(id)?);
    let units = drive.units().await?;
    drive.profile_velocity_in_pp_mode().write_in(&units, Quantity::mm_per_s(200)).await?;
    let axis = Axis::new(drive.node().clone()).with_units(units);
    axis.home(HomingMethod(37)).await?;
    let target = Quantity::mm(20);
    let ramps = Move { acceleration: Some(2_000), deceleration: Some(2_000), ..Move::default() };
    axis.move_to_with(target, &ramps).await?;
    let at = axis.position().await?;
    let raw = drive.node().read::<i32>(0x6064, 0).await?;
    let (num, den) = (drive.node().read::<u32>(0x2001, 1).await?, drive.node().read::<u32>(0x2001, 2).await?);
    let scaled = at.unit() == Unit::Millimeter && is(&at, i128::from(raw) * i128::from(den), i128::from(num));
    axis.move_to_with(Quantity::mm(0), &ramps).await?;
    Ok(Moved { at, raw, scaling: format!("2001h = {num}/{den}, mm"), scaled, target })
}

/// The AKD of the example in its user units (6092h feed per shaft revolutions of the motor;
/// 1/1 by default: a user unit is a turn): homed where it is (method 35), 1 user unit at 20
/// per second (its limit switch is 2 turns away). 6064h is in user units; the motor turns the
/// generated units give for it are 6064h times 6092h's shaft revolutions over its feed.
async fn move_akd(bus: &Bus, id: u8) -> Result<Moved, Error> {
    let drive = akd::remote::Remote::new(bus.node(id)?);
    let units = drive.units().await?;
    let turns = |raw: i32| units.to_internal(akd::units::Dimension::Position, i64::from(raw));
    drive.profile_velocity().write_in(&units, Quantity::user_per_s(20)).await?;
    let axis = Axis::new(drive.node().clone()).with_units(units);
    axis.home(HomingMethod(35)).await?;
    let target = Quantity::user(1);
    let ramps = Move { acceleration: Some(200), deceleration: Some(200), ..Move::default() };
    axis.move_to_with(target, &ramps).await?;
    let at = axis.position().await?;
    let raw = drive.node().read::<i32>(0x6064, 0).await?;
    let (feed, shaft) = (drive.node().read::<u32>(0x6092, 1).await?, drive.node().read::<u32>(0x6092, 2).await?);
    let (raw_turns, feed_turns) = (i128::from(raw) * i128::from(shaft), i128::from(feed));
    let scaled = at.unit() == Unit::UserUnit
        && is(&at, raw.into(), 1)
        && turns(raw).is_ok_and(|t| t.num() * feed_turns == raw_turns * t.den());
    let revolutions = f64::from(raw) * f64::from(shaft) / f64::from(feed);
    let scaling = format!("6092h = {feed}/{shaft}, {revolutions} motor turns");
    axis.move_to_with(Quantity::user(0), &ramps).await?;
    Ok(Moved { at, raw, scaling, scaled, target })
}

/// Moves the example's three axes at once: the DRVI on `ids[0]`, the DRCS on `ids[1]`, the AKD
/// on `ids[2]`.
async fn move_axes(bus: &Bus, ids: [u8; 3]) -> [Result<Moved, Error>; 3] {
    let (x, y, z) = tokio::join!(move_drvi(bus, ids[0]), move_drcs(bus, ids[1]), move_akd(bus, ids[2]));
    [x, y, z]
}

/// Prints a line per axis; true when each reached its target and its position in units is its
/// raw 6064h scaled by its scaling objects.
fn report(names: [&str; 3], ids: [u8; 3], moved: &[Result<Moved, Error>; 3]) -> bool {
    let mut ok = true;
    for ((name, id), moved) in names.into_iter().zip(ids).zip(moved) {
        match moved {
            Ok(m) => {
                let unit = symbol(m.at.unit());
                let line = format!(
                    "{name} (node {id}): at {} {unit}; 6064h = {}, {}; back at 0",
                    m.at.to_f64(),
                    m.raw,
                    m.scaling
                );
                let reached =
                    m.at.unit() == m.target.unit() && is(&m.at, m.target.value().num(), m.target.value().den());
                if m.scaled && reached {
                    println!("{line}");
                } else {
                    ok = false;
                    let why = if m.scaled { "not at the target" } else { "not what the scaling objects give" };
                    eprintln!("network-boot: {line}: {why}");
                }
            }
            Err(e) => {
                ok = false;
                eprintln!("network-boot: {name}: {e}");
            }
        }
    }
    ok
}

/// Boots the example network, then moves its three axes; true when all went right.
async fn boot_and_move(bus: &Bus, network: &Network) -> bool {
    let booted = boot_and_watch(bus, network).await;
    let node = |name: &str| network.nodes.iter().find(|n| n.name == name).map(|n| n.node_id);
    let (Some(x), Some(y), Some(z)) = (node("x_axis"), node("y_axis"), node("z_axis")) else {
        eprintln!("network-boot: the network has no x_axis, y_axis and z_axis to move");
        return false;
    };
    booted && report(["x_axis", "y_axis", "z_axis"], [x, y, z], &move_axes(bus, [x, y, z]).await)
}

fn example_network() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../networks/example.toml")
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut addr = None;
    let mut file = None;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bus" => addr = args.next(),
            _ if file.is_none() && !a.starts_with('-') => file = Some(PathBuf::from(a)),
            _ => {
                eprintln!("usage: network-boot [--bus ADDR] [NETWORK.toml | DCF...]");
                return ExitCode::from(2);
            }
        }
    }
    let network = match Network::load(&[file.unwrap_or_else(example_network)]) {
        Ok(n) => n,
        Err(e) => {
            eprintln!("network-boot: {e}");
            return ExitCode::from(2);
        }
    };
    // The simulated drives when no bus is given; they stop when `_drives` is dropped.
    let _drives = addr.is_none().then(|| Drives::start("network-boot"));
    let addr = addr.unwrap_or_else(|| "mem://network-boot".to_owned());
    let bus = match Bus::open(&addr, Config::default()).await {
        Ok(b) => b,
        Err(e) => {
            eprintln!("network-boot: cannot open the bus {addr}: {e}");
            return ExitCode::from(2);
        }
    };
    if boot_and_move(&bus, &network).await { ExitCode::SUCCESS } else { ExitCode::from(1) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use drive::node::Sim;
    use std::sync::Mutex;

    /// The example as CI runs it (`cargo run -p network-boot`): the example network on the three
    /// simulated drives in real time, every node booted and sending its TPDO 1, every axis moved.
    #[tokio::test]
    async fn the_example_network_boots_on_the_simulated_drives_and_its_axes_move() {
        let _drives = Drives::start("network-boot-test");
        let bus = Bus::open("mem://network-boot-test", Config::default()).await.unwrap();
        let network = Network::load(&[example_network()]).unwrap();
        let mut frames = bus.frames();
        assert!(boot_and_move(&bus, &network).await);
        let mut seen = std::collections::BTreeSet::new();
        while let Ok(f) = frames.try_recv() {
            seen.insert(f.id());
        }
        for id in [0x182, 0x183, 0x184] {
            assert!(seen.contains(&id), "TPDO 1 of node {} ({id:03X}h) after boot", id - 0x180);
        }
    }

    /// The three drives in one simulation moved in step with tokio's paused clock, and a master
    /// on its bus.
    fn simulated() -> (Bus, Arc<Mutex<Sim>>) {
        let mut sim = Sim::new();
        for (kind, id) in [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)] {
            let config = NodeConfig { node_id: Some(id), ..Default::default() };
            sim.add(kind.build(&config, &DeviceApps::new()).expect("a simulated drive"));
        }
        drive::node::spawn_with_master(sim, Config::default(), Duration::from_micros(200))
    }

    fn raw(moved: &[Result<Moved, Error>; 3]) -> Vec<i32> {
        moved.iter().map(|m| m.as_ref().map(|m| m.raw).unwrap()).collect()
    }

    const NAMES: [&str; 3] = ["x_axis", "y_axis", "z_axis"];

    /// In virtual time: the boot and the moves, then the moves again with scaling objects other
    /// than 1/1 (2001h on the DRVI and the DRCS, 6092h on the AKD), so that the check of each
    /// position against its raw 6064h and scaling objects has a factor to get wrong.
    #[tokio::test(start_paused = true)]
    async fn the_axes_move_in_their_units_whatever_the_scaling_objects() {
        let (bus, _sim) = simulated();
        let network = Network::load(&[example_network()]).unwrap();
        assert!(boot_and_move(&bus, &network).await);
        let (x, y, z) = (bus.node(2).unwrap(), bus.node(3).unwrap(), bus.node(4).unwrap());
        for node in [&x, &y, &z] {
            assert_eq!(node.read::<i32>(0x6064, 0).await.unwrap(), 0, "node {} back home", node.id());
        }
        let moved = move_axes(&bus, [2, 3, 4]).await;
        assert!(report(NAMES, [2, 3, 4], &moved));
        // 90 deg at 0.01 deg, 20 mm, 1 user unit.
        assert_eq!(raw(&moved), [9_000, 20, 1]);

        x.write_idempotent(0x2001, 1, 3u32).await.unwrap();
        x.write_idempotent(0x2001, 2, 2u32).await.unwrap();
        y.write_idempotent(0x2001, 1, 2u32).await.unwrap();
        y.write_idempotent(0x2001, 2, 5u32).await.unwrap();
        z.write_idempotent(0x6092, 1, 4u32).await.unwrap();
        let moved = move_axes(&bus, [2, 3, 4]).await;
        assert!(report(NAMES, [2, 3, 4], &moved));
        // 90 deg = 9000 x 3/2 on the DRVI; 20 mm = 20 x 2/5 on the DRCS; the AKD's 6064h is in
        // user units whatever 6092h says (a user unit is a quarter turn now).
        assert_eq!(raw(&moved), [13_500, 8, 1]);
        let turns = moved[2].as_ref().unwrap().scaling.clone();
        assert_eq!(turns, "6092h = 4/1, 0.25 motor turns");
    }

    /// An axis that cannot be moved (no drive at its node) fails the example, named, while the
    /// others still move; so does a position that is not the target.
    #[tokio::test(start_paused = true)]
    async fn a_wrong_position_or_an_axis_that_does_not_answer_fails_the_example() {
        let (bus, _sim) = simulated();
        let mut moved = move_axes(&bus, [2, 3, 5]).await;
        assert!(matches!(&moved[2], Err(e) if e.to_string().contains("node 5")), "{:?}", moved[2].as_ref().err());
        assert!(!report(NAMES, [2, 3, 5], &moved));
        moved[2] = move_akd(&bus, 4).await;
        assert!(report(NAMES, [2, 3, 4], &moved));
        if let Ok(m) = &mut moved[1] {
            m.target = Quantity::mm(21);
        }
        assert!(!report(NAMES, [2, 3, 4], &moved));
    }
}
