//! The master's speed over a real bus (a benchmark program, not a test; `scripts/bench-master.sh`
//! runs it against `drive-sim hub` beside python-canopen). One JSON object on stdout per run.
//!
//! ```text
//! bench reads --bus socketcand://127.0.0.1:29536/can0 --nodes 1,2,3 --seconds 10
//! bench raw   --bus socketcand://127.0.0.1:29536/can0 --nodes 1 --seconds 10
//! bench csp   --bus socketcand://127.0.0.1:29536/can0 --nodes 1,2,3 --seconds 60 --period-us 1000
//! ```
//!
//! `reads`: expedited SDO reads of 1000h, back to back, one task per node (od-master runs the
//! nodes' transfers at once, one at a time per node); reads per second in total and per node.
//!
//! `csp`: each node homed where it stands (method 35 or 37, as its manual names "home here"),
//! then cyclic synchronous position over RPDO 4 (COB-ID 500h + node) with a SYNC every
//! `--period-us`, a set-point per SYNC per node for `--seconds`. A second connection to the hub
//! logs every SYNC and set-point with the hub's time stamp (when the hub relayed it): a SYNC
//! period without a set-point of a node is a missed one, one with more a doubled one, one with
//! the same value as the period before a repeated one (the values step every period); missed
//! ones are also counted
//! apart where neither that period nor the one before was over 1.5 periods long (`missed_on_time`:
//! not explained by the master's process being stalled); the SYNC jitter is |interval - period|
//! between consecutive SYNCs, p50/p99/max, and `late_syncs` those over half a period.
//!
//! It is an example of the crate (so `cargo build --all-targets` builds it in CI) rather than a
//! criterion bench: the figures come from a bus outside the process, the same one python-canopen
//! is measured on, and the CSP run is one long real-time run, not repeated samples.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use od_bus::socketcand::{Decoder, Message};
use od_master::{Axis, Bus, Config, Homing};

fn usage() -> ! {
    eprintln!(
        "usage: bench reads|csp --bus socketcand://HOST:PORT/CHANNEL --nodes 1,2,3 [--seconds S] [--period-us P]"
    );
    std::process::exit(2)
}

struct Args {
    what: String,
    bus: String,
    nodes: Vec<u8>,
    seconds: f64,
    period_us: u64,
}

fn args() -> Args {
    let mut it = std::env::args().skip(1);
    let what = it.next().unwrap_or_else(|| usage());
    let mut a = Args { what, bus: String::new(), nodes: vec![1], seconds: 10.0, period_us: 1000 };
    while let Some(flag) = it.next() {
        let value = it.next().unwrap_or_else(|| usage());
        match flag.as_str() {
            "--bus" => a.bus = value,
            "--nodes" => a.nodes = value.split(',').map(|n| n.parse().unwrap_or_else(|_| usage())).collect(),
            "--seconds" => a.seconds = value.parse().unwrap_or_else(|_| usage()),
            "--period-us" => a.period_us = value.parse().unwrap_or_else(|_| usage()),
            _ => usage(),
        }
    }
    if a.bus.is_empty() || a.nodes.is_empty() {
        usage()
    }
    a
}

fn main() {
    let a = args();
    let rt = match std::env::var("BENCH_RUNTIME").as_deref() {
        Ok("current") => tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap(),
        _ => tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap(),
    };
    let result = match a.what.as_str() {
        "raw" => raw(&a),
        "reads" => rt.block_on(reads(&a)),
        "csp" => rt.block_on(csp(&a)),
        _ => usage(),
    };
    match result {
        Ok(json) => println!("{json}"),
        Err(e) => {
            eprintln!("bench: {e}");
            std::process::exit(1)
        }
    }
}

/// The floor of the path: the same reads by a plain blocking socketcand client (od-bus's
/// `SocketcandClient`), one request on the socket and a blocking wait for its answer, no
/// master. What od-master adds is the difference.
fn raw(a: &Args) -> Result<String, od_master::Error> {
    use od_bus::{CanFrame, Endpoint, SocketcandClient};
    let rest = a.bus.strip_prefix("socketcand://").unwrap_or_else(|| usage());
    let (addr, channel) = rest.split_once('/').unwrap_or((rest, "can0"));
    let mut c = SocketcandClient::connect(addr, channel).map_err(od_master::Error::from)?;
    let id = a.nodes[0];
    let request = CanFrame::standard(0x600 + u32::from(id), &[0x40, 0x00, 0x10, 0, 0, 0, 0, 0]).expect("a frame");
    let answer = 0x580 + u32::from(id);
    let start = Instant::now();
    let mut n = 0u64;
    while start.elapsed().as_secs_f64() < a.seconds {
        c.send(request).map_err(od_master::Error::from)?;
        loop {
            match c.recv_timeout(Duration::from_secs(1)).map_err(od_master::Error::from)? {
                Some(f) if f.id() == answer => break,
                Some(_) => {}
                None => return Err(od_master::Error::Closed),
            }
        }
        n += 1;
    }
    let secs = start.elapsed().as_secs_f64();
    Ok(format!(
        "{{\"bench\":\"raw reads\",\"nodes\":1,\"seconds\":{secs:.3},\"reads\":{n},\"reads_per_s\":{:.0}}}",
        n as f64 / secs
    ))
}

async fn reads(a: &Args) -> Result<String, od_master::Error> {
    let bus = Bus::open(&a.bus, Config::default()).await?;
    // A first read of each node opens its channel and checks the node answers.
    for &id in &a.nodes {
        bus.node(id)?.read::<u32>(0x1000, 0).await?;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let mut tasks = Vec::new();
    let start = Instant::now();
    for &id in &a.nodes {
        let node = bus.node(id)?;
        let stop = Arc::clone(&stop);
        tasks.push(tokio::spawn(async move {
            let mut n = 0u64;
            while !stop.load(Ordering::Relaxed) {
                node.read::<u32>(0x1000, 0).await?;
                n += 1;
            }
            Ok::<u64, od_master::Error>(n)
        }));
    }
    tokio::time::sleep(Duration::from_secs_f64(a.seconds)).await;
    stop.store(true, Ordering::Relaxed);
    let mut per_node = Vec::new();
    for t in tasks {
        per_node.push(t.await.expect("a read task panicked")?);
    }
    let secs = start.elapsed().as_secs_f64();
    let total: u64 = per_node.iter().sum();
    let rates: Vec<String> = per_node.iter().map(|n| format!("{:.0}", *n as f64 / secs)).collect();
    Ok(format!(
        "{{\"bench\":\"reads\",\"nodes\":{},\"seconds\":{secs:.3},\"reads\":{total},\"reads_per_s\":{:.0},\"per_node\":[{}]}}",
        a.nodes.len(),
        total as f64 / secs,
        rates.join(",")
    ))
}

/// A frame the hub relayed, as the log connection saw it: identifier, the hub's time stamp in
/// microseconds, and a set-point's value (its first four bytes).
type Logged = (u32, u64, i32);

/// Connects to the hub as a plain socketcand client and logs SYNC (080h) and the RPDOs in
/// `ids` with their time stamps until `stop`.
fn log_frames(
    addr: &str,
    channel: &str,
    ids: Vec<u32>,
    stop: Arc<AtomicBool>,
    ready: Arc<AtomicU64>,
) -> Result<Vec<Logged>, String> {
    let mut s = TcpStream::connect(addr).map_err(|e| format!("log connection to {addr}: {e}"))?;
    s.set_nodelay(true).ok();
    s.set_read_timeout(Some(Duration::from_millis(100))).ok();
    let mut dec = Decoder::new();
    let mut log = Vec::new();
    let mut handshake = 0;
    let mut buf = vec![0u8; 1 << 16];
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(log);
        }
        let n = match s.read(&mut buf) {
            Ok(0) => return Err("the hub closed the log connection".into()),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => continue,
            Err(e) => return Err(format!("log connection: {e}")),
        };
        let mut replies = Vec::new();
        dec.feed(&buf[..n], |m| match m {
            Ok(Message::Frame { frame, timestamp }) if frame.id() == 0x080 || ids.contains(&frame.id()) => {
                let mut v = [0u8; 4];
                let d = frame.data();
                v[..d.len().min(4)].copy_from_slice(&d[..d.len().min(4)]);
                let at = timestamp.secs() * 1_000_000 + u64::from(timestamp.micros());
                log.push((frame.id(), at, i32::from_le_bytes(v)));
            }
            Ok(Message::Hi | Message::Ok) => replies.push(()),
            _ => {}
        });
        for () in replies {
            handshake += 1;
            let mut text = String::new();
            match handshake {
                1 => Message::Open(channel.to_owned()).write_to(&mut text),
                2 => Message::RawMode.write_to(&mut text),
                _ => ready.store(1, Ordering::SeqCst),
            }
            s.write_all(text.as_bytes()).map_err(|e| format!("log connection handshake: {e}"))?;
        }
    }
}

fn percentile(sorted: &[u64], p: f64) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

async fn csp(a: &Args) -> Result<String, od_master::Error> {
    let rest = a.bus.strip_prefix("socketcand://").unwrap_or_else(|| usage());
    let (addr, channel) = rest.split_once('/').unwrap_or((rest, "can0"));
    let bus = Bus::open(&a.bus, Config::default()).await?;
    let mut streams = Vec::new();
    for &id in &a.nodes {
        let mut axis = Axis::new(bus.node(id)?);
        // "Home here": 35 in CiA 402 since 2012 (the AKD), 37 before it (the Camozzi drives).
        let ty = axis.node().read::<u32>(0x1018, 1).await?;
        let method = if ty == 0x0000_006A { 35 } else { 37 };
        if ty == 0x0000_006A {
            // Its sidecar: the AKD runs cyclic synchronous position though its 6502h leaves it
            // out, and the axis checks modes against 6502h.
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/kollmorgen-akd.toml");
            if let Ok(sidecar) = od_sidecar::Sidecar::read(std::path::Path::new(path)) {
                axis = axis.with_sidecar(&sidecar);
            }
        }
        // From any state, through a fault reset: an AKD left in cyclic synchronous position by
        // an earlier run faulted (F125) when its SYNC stopped, and faults again without SYNC
        // unless it leaves that mode first.
        axis.node().start().await?;
        axis.set_mode(1).await?;
        axis.enable().await?;
        axis.home(&Homing::method(method)).await?;
        streams.push((id, axis));
    }
    let ids: Vec<u32> = a.nodes.iter().map(|&id| 0x500 + u32::from(id)).collect();
    let stop = Arc::new(AtomicBool::new(false));
    let ready = Arc::new(AtomicU64::new(0));
    let logger = {
        let (addr, channel, ids, stop, ready) =
            (addr.to_owned(), channel.to_owned(), ids.clone(), Arc::clone(&stop), Arc::clone(&ready));
        std::thread::spawn(move || log_frames(&addr, &channel, ids, stop, ready))
    };
    while ready.load(Ordering::SeqCst) == 0 && !logger.is_finished() {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    if logger.is_finished() {
        let why = match logger.join() {
            Ok(Err(e)) => e,
            _ => "the log connection ended".to_owned(),
        };
        return Err(od_master::Error::Transport(od_bus::TransportError::Protocol(why)));
    }
    let period = Duration::from_micros(a.period_us);
    bus.start_sync(period, 0).await?;
    let mut csps = Vec::new();
    for (id, axis) in &streams {
        csps.push((*id, axis.cyclic_position(4, 0x500 + u16::from(*id)).await?));
    }
    // Every stream is set up: the measured run starts at the next SYNC.
    let run = Duration::from_secs_f64(a.seconds);
    let mut tasks = Vec::new();
    for (id, mut csp) in csps {
        let axis = Axis::new(bus.node(id)?);
        tasks.push(tokio::spawn(async move {
            let here = axis.position().await?;
            let mut sent = 0u64;
            let began = Instant::now();
            while began.elapsed() < run {
                // A triangle of 20 units each way, a step of one unit every set-point (so each
                // differs from the one before, and a repeated one shows).
                let k = (sent % 40) as i32;
                csp.send(here + if k < 20 { k } else { 40 - k }).await?;
                sent += 1;
            }
            Ok::<u64, od_master::Error>(sent)
        }));
    }
    let mut sent = Vec::new();
    for t in tasks {
        sent.push(t.await.expect("a CSP task panicked")?);
    }
    bus.stop_sync().await?;
    tokio::time::sleep(Duration::from_millis(200)).await;
    stop.store(true, Ordering::SeqCst);
    let log = match logger.join() {
        Ok(Ok(log)) => log,
        Ok(Err(e)) => return Err(od_master::Error::Transport(od_bus::TransportError::Protocol(e))),
        Err(_) => return Err(od_master::Error::Closed),
    };
    drop(streams);

    // Each SYNC period (from one SYNC to the next) should hold one set-point of each node.
    let syncs: Vec<usize> = log.iter().enumerate().filter(|(_, f)| f.0 == 0x080).map(|(i, _)| i).collect();
    let mut missed = vec![0u64; ids.len()];
    let mut doubled = vec![0u64; ids.len()];
    let mut periods = 0u64;
    // The first periods (before every stream sends) and the last (after they stop) are left out:
    // from the first period holding every node's set-point to the last one.
    let mut windows = Vec::new();
    // Each period's length, to tell a set-point missed by a stalled machine (the master's
    // process not run for over half a period: a SYNC late) from one missed otherwise.
    let lengths: Vec<u64> = syncs.windows(2).map(|w| log[w[1]].1 - log[w[0]].1).collect();
    let stalled = |k: usize| lengths[k] > a.period_us * 3 / 2 || (k > 0 && lengths[k - 1] > a.period_us * 3 / 2);
    let mut missed_on_time = vec![0u64; ids.len()];
    // Per period and node: the set-points and the last value.
    let mut values: Vec<Vec<Option<i32>>> = Vec::new();
    for w in syncs.windows(2) {
        let mut count = vec![0u64; ids.len()];
        let mut value = vec![None; ids.len()];
        for f in &log[w[0] + 1..w[1]] {
            if let Some(k) = ids.iter().position(|&id| id == f.0) {
                count[k] += 1;
                value[k] = Some(f.2);
            }
        }
        windows.push(count);
        values.push(value);
    }
    // A set-point equal to the one of the period before: the task computing them was late and
    // the bus repeated the last one (a missed update, though the drive had a set-point).
    let mut repeated = vec![0u64; ids.len()];
    let first = windows.iter().position(|c| c.iter().all(|&n| n >= 1)).unwrap_or(windows.len());
    let last = windows.iter().rposition(|c| c.iter().all(|&n| n >= 1)).unwrap_or(0);
    if first <= last {
        for (i, c) in windows.iter().enumerate().take(last + 1).skip(first) {
            periods += 1;
            for (k, &n) in c.iter().enumerate() {
                if i > first && n > 0 && values[i][k] == values[i - 1][k] {
                    repeated[k] += 1;
                }
                if n == 0 {
                    missed[k] += 1;
                    if !stalled(i) {
                        missed_on_time[k] += 1;
                    }
                }
                if n > 1 {
                    doubled[k] += n - 1;
                }
            }
        }
    }
    let times: Vec<u64> =
        syncs[first.min(syncs.len())..(last + 2).min(syncs.len())].iter().map(|&i| log[i].1).collect();
    let mut jitter: Vec<u64> = times.windows(2).map(|w| (w[1] - w[0]).abs_diff(a.period_us)).collect();
    let late = jitter.iter().filter(|&&j| j > a.period_us / 2).count();
    jitter.sort_unstable();
    let list = |v: &[u64]| v.iter().map(u64::to_string).collect::<Vec<_>>().join(",");
    Ok(format!(
        "{{\"bench\":\"csp\",\"nodes\":{},\"period_us\":{},\"seconds\":{:.3},\"syncs\":{},\"periods\":{periods},\
         \"setpoints_sent\":[{}],\"missed\":[{}],\"missed_on_time\":[{}],\"repeated\":[{}],\"doubled\":[{}],\"late_syncs\":{late},\"jitter_us\":{{\"p50\":{},\"p99\":{},\"max\":{}}}}}",
        a.nodes.len(),
        a.period_us,
        times.last().zip(times.first()).map_or(0.0, |(l, f)| (l - f) as f64 / 1e6),
        times.len(),
        list(&sent),
        list(&missed),
        list(&missed_on_time),
        list(&repeated),
        list(&doubled),
        percentile(&jitter, 0.5),
        percentile(&jitter, 0.99),
        jitter.last().copied().unwrap_or(0),
    ))
}
