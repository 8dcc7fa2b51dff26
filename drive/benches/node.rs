//! What a simulated device costs.
//!
//! * `cpu share` (printed, not criterion): one DRVI with 4 synchronous TPDOs run by
//!   `drive::node::run` on its own thread, a master thread sending SYNC at 1 kHz on the
//!   in-memory bus and checking that 4 TPDOs answer each SYNC. The device thread's CPU time
//!   (`CLOCK_THREAD_CPUTIME_ID`) over the wall time of a fixed number of SYNCs is its CPU
//!   share; the process's CPU time (master included) is printed too. Measured twice: with the
//!   default application, and with an application ticking at 1 kHz (the control cycle a
//!   motion model runs at).
//! * `node/sync_4_tpdos`: the same SYNC handled in virtual time (handle + poll), per SYNC.
//! * `node/sdo_upload`: an expedited SDO upload handled in virtual time.
//! * `node/sdo_via_hub`: an SDO upload round trip from a socketcand TCP client through the hub
//!   to a device in the same process and back (what python-canopen sees).
//!
//! Run with `cargo bench -p drive --bench node`. Under `cargo test` (no `--bench` argument)
//! everything runs briefly, as a smoke test.

use std::hint::black_box;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use criterion::{Criterion, Throughput};
use drive::node::{Ctx, DefaultApp, DriveApp, MonotonicClock, Node, NodeStorage, run};
use generated::drvi::Dictionary;
use od_bus::{CanFrame, Endpoint, Hub, HubConfig, MemoryBus, SocketcandClient};
use od_runtime::{Event, Micros, NodeId};

const NODE: u8 = 2;

/// A 1 kHz tick that moves the actual position, as a motion model would.
#[derive(Default)]
struct Ticking {
    base: DefaultApp,
    position: i32,
}

impl DriveApp<Dictionary> for Ticking {
    fn on_event(&mut self, ctx: &mut Ctx<'_, Dictionary>, event: Event) {
        self.base.on_event(ctx, event);
    }

    fn tick(&mut self, ctx: &mut Ctx<'_, Dictionary>) {
        self.position = self.position.wrapping_add(7);
        let _ = ctx.od_mut().set_position_actual_value(self.position);
        let _ = ctx.od_mut().set_velocity_actual_value(7000);
    }

    fn tick_period(&self) -> Micros {
        1000
    }
}

/// A DRVI whose TPDOs 1..=4 are synchronous (type 1) with 2 to 8 bytes each.
fn configured<A: DriveApp<Dictionary>>(app: A) -> Node<Dictionary, A> {
    let mut node = Node::new(Dictionary::new(NODE), app, NodeStorage::memory(), NodeId::new(NODE).unwrap());
    node.poll(0, &mut |_| {});
    let maps: [&[u32]; 4] =
        [&[0x6041_0010, 0x6064_0020], &[0x606C_0020], &[0x6041_0010, 0x6061_0008], &[0x6064_0020, 0x606C_0020]];
    node.with_app(0, |_, ctx| {
        for (n, map) in maps.iter().enumerate() {
            let (comm, mapping) = (0x1800 + n as u16, 0x1A00 + n as u16);
            let cob = 0x180 + 0x100 * n as u32 + u32::from(NODE);
            ctx.write(comm, 1, &(cob | 0x8000_0000).to_le_bytes()).unwrap();
            ctx.write(mapping, 0, &[0]).unwrap();
            for (k, entry) in map.iter().enumerate() {
                ctx.write(mapping, k as u8 + 1, &entry.to_le_bytes()).unwrap();
            }
            ctx.write(mapping, 0, &[map.len() as u8]).unwrap();
            ctx.write(comm, 2, &[1]).unwrap();
            ctx.write(comm, 5, &[0, 0]).unwrap();
            ctx.write(comm, 1, &cob.to_le_bytes()).unwrap();
        }
        ctx.nmt_command(od_runtime::NmtCommand::Start);
    });
    node.poll(0, &mut |_| {});
    node
}

fn sync_frame() -> CanFrame {
    CanFrame::standard(0x080, &[]).unwrap()
}

fn thread_cpu() -> Duration {
    cpu_clock(libc::CLOCK_THREAD_CPUTIME_ID)
}

fn process_cpu() -> Duration {
    cpu_clock(libc::CLOCK_PROCESS_CPUTIME_ID)
}

fn cpu_clock(clock: libc::clockid_t) -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid out pointer for the duration of the call.
    let rc = unsafe { libc::clock_gettime(clock, &raw mut ts) };
    assert_eq!(rc, 0, "clock_gettime");
    Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// The device side of a CPU share measurement.
enum Responder<A> {
    /// A node run by `drive::node::run`.
    Node(Box<Node<Dictionary, A>>),
    /// No device: a loop of the same shape (wait for a frame or the next millisecond, answer
    /// a SYNC with 4 frames), measuring what the thread and the bus cost by themselves.
    BusOnly,
}

fn bus_only(device: &mut dyn Endpoint, stop: &AtomicBool) {
    let start = Instant::now();
    let mut next = Duration::from_millis(1);
    let pdo = CanFrame::standard(0x180 + u32::from(NODE), &[0; 8]).unwrap();
    while !stop.load(Ordering::Relaxed) {
        let wait = next.saturating_sub(start.elapsed()).min(Duration::from_millis(20));
        match device.recv_timeout(wait).expect("recv") {
            Some(f) if f.id() == 0x080 => (0..4).for_each(|_| device.send(pdo).expect("send")),
            Some(_) => {}
            None => next = start.elapsed() + Duration::from_millis(1),
        }
    }
}

/// Runs `responder` for `syncs` SYNCs at 1 kHz; returns (device thread CPU, process CPU, wall).
fn cpu_share<A: DriveApp<Dictionary> + Send + 'static>(
    responder: Responder<A>,
    syncs: u32,
) -> (Duration, Duration, Duration) {
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut device = bus.endpoint();
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let start = thread_cpu();
            match responder {
                Responder::Node(mut node) => {
                    run(&mut *node, &mut device, &MonotonicClock::new(), &stop).expect("run");
                }
                Responder::BusOnly => bus_only(&mut device, &stop),
            }
            thread_cpu() - start
        })
    };
    std::thread::sleep(Duration::from_millis(20));
    while master.try_recv().unwrap().is_some() {}
    let (wall_start, cpu_start) = (Instant::now(), process_cpu());
    for k in 0..syncs {
        let due = wall_start + Duration::from_millis(u64::from(k));
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        master.send(sync_frame()).unwrap();
        for _ in 0..4 {
            let f = master.recv_timeout(Duration::from_secs(1)).unwrap().expect("a TPDO for every SYNC");
            assert_eq!(f.id() & 0x7F, u32::from(NODE));
        }
    }
    let (wall, process) = (wall_start.elapsed(), process_cpu() - cpu_start);
    stop.store(true, Ordering::SeqCst);
    let device_cpu = thread.join().unwrap();
    (device_cpu, process, wall)
}

fn report_cpu_share(full: bool) {
    let syncs = if full { 10_000 } else { 200 };
    for (name, measured) in [
        ("default app", cpu_share(Responder::Node(Box::new(configured(DefaultApp::new()))), syncs)),
        ("app ticking at 1 kHz", cpu_share(Responder::Node(Box::new(configured(Ticking::default()))), syncs)),
        ("no device (thread + bus only)", cpu_share::<DefaultApp>(Responder::BusOnly, syncs)),
    ] {
        let (device, process, wall) = measured;
        let pct = |d: Duration| 100.0 * d.as_secs_f64() / wall.as_secs_f64();
        println!(
            "cpu share, 1 kHz SYNC, 4 TPDOs, {name}: device thread {:.2} % of one core ({:.1} us per SYNC), \
             process {:.2} % ({syncs} SYNCs in {:.2} s)",
            pct(device),
            device.as_secs_f64() * 1e6 / f64::from(syncs),
            pct(process),
            wall.as_secs_f64()
        );
    }
}

fn virtual_time(c: &mut Criterion) {
    let mut group = c.benchmark_group("node");
    group.throughput(Throughput::Elements(1));
    let mut node = configured(DefaultApp::new());
    let mut now: Micros = 1_000;
    let sync = sync_frame();
    group.bench_function("sync_4_tpdos", |b| {
        b.iter(|| {
            now += 1_000;
            node.handle(black_box(&sync), now);
            let mut n = 0;
            node.poll(now, &mut |f| {
                black_box(f);
                n += 1;
            });
            assert_eq!(n, 4);
        })
    });
    let request = CanFrame::standard(0x602, &[0x40, 0x64, 0x60, 0x00, 0, 0, 0, 0]).unwrap();
    group.bench_function("sdo_upload", |b| {
        b.iter(|| {
            now += 10;
            node.handle(black_box(&request), now);
            let mut reply = None;
            node.poll(now, &mut |f| reply = Some(f));
            black_box(reply.expect("a response"))
        })
    });
    group.finish();
}

fn via_hub(c: &mut Criterion) {
    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind");
    let mut device = hub.attach("can0").expect("attach");
    let stop = Arc::new(AtomicBool::new(false));
    let thread = {
        let stop = Arc::clone(&stop);
        let mut node = configured(DefaultApp::new());
        std::thread::spawn(move || run(&mut node, &mut device, &MonotonicClock::new(), &stop))
    };
    let mut master = SocketcandClient::connect(hub.local_addr(), "can0").expect("connect");
    let request = CanFrame::standard(0x602, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
    let mut group = c.benchmark_group("node");
    group.throughput(Throughput::Elements(1));
    group.bench_function("sdo_via_hub", |b| {
        b.iter(|| {
            master.send(request).unwrap();
            loop {
                let f = master.recv_timeout(Duration::from_secs(5)).unwrap().expect("SDO response");
                if f.id() == 0x582 {
                    break black_box(f);
                }
            }
        })
    });
    group.finish();
    stop.store(true, Ordering::SeqCst);
    let _ = thread.join();
    hub.stop();
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let mut c = Criterion::default().configure_from_args();
    virtual_time(&mut c);
    via_hub(&mut c);
    c.final_summary();
    report_cpu_share(full);
}
