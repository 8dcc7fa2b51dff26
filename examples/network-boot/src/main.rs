//! Boots a network with `od-master`: each node's identity checked, its configuration and PDO
//! mappings written, and the nodes started (CiA 302-2), then the drives' TPDOs counted.
//!
//! ```sh
//! cargo run -p network-boot                       # networks/example.toml on three simulated drives
//! cargo run -p network-boot -- --bus socketcand://127.0.0.1:29536/can0 networks/example.toml
//! ```
//!
//! Without `--bus`, the three drives of the example (a DRVI at node 2, a DRCS at 3, an AKD at 4)
//! run in this process on the in-memory bus `mem://network-boot`, in real time. Exit code 0 when
//! every node booted, 1 when one did not (each failure names its node and object), 2 for bad
//! usage.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use drive::drives::DeviceApps;
use drive::node::{DeviceKind, MonotonicClock, NodeConfig};
use od_master::boot::{self, BootOptions, Network};
use od_master::{Bus, Config};

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
    if boot_and_watch(&bus, &network).await { ExitCode::SUCCESS } else { ExitCode::from(1) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The example as CI runs it: the example network on the three simulated drives, every node
    /// booted and sending its TPDO 1.
    #[tokio::test]
    async fn the_example_network_boots_on_the_simulated_drives() {
        let _drives = Drives::start("network-boot-test");
        let bus = Bus::open("mem://network-boot-test", Config::default()).await.unwrap();
        let network = Network::load(&[example_network()]).unwrap();
        let mut frames = bus.frames();
        assert!(boot_and_watch(&bus, &network).await);
        let mut seen = std::collections::BTreeSet::new();
        while let Ok(f) = frames.try_recv() {
            seen.insert(f.id());
        }
        for id in [0x182, 0x183, 0x184] {
            assert!(seen.contains(&id), "TPDO 1 of node {} ({id:03X}h) after boot", id - 0x180);
        }
    }
}
