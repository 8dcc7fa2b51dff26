//! Hot paths of the device core, measured on the hand-built test dictionary with an
//! application that does nothing (`()`): an expedited SDO request handled to its response, an
//! RPDO received and applied, and a SYNC turned into four TPDOs. The test dictionary implements
//! the handle methods of `ObjectDictionary` (the PDO fast path); the `plain/…` rows run the same
//! PDO work on a dictionary that leaves them to the trait's defaults (a lookup per access).
//!
//! Every benchmark runs twice: `wall/…` with criterion's wall clock, and `cpu/…` with the
//! thread's CPU time (Linux `CLOCK_THREAD_CPUTIME_ID`), which stays meaningful on a machine
//! shared with other builds, where wall-clock figures include time spent preempted.

#[path = "../tests/it/common/mod.rs"]
mod common;

use common::*;
use criterion::measurement::{Measurement, ValueFormatter};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use od_runtime::od::ObjectDictionary;
use od_runtime::{Device, Frame, NmtCommand, NodeId};
use std::hint::black_box;

type BenchDevice<OD = TestOd> = Device<OD, (), MemStorage>;

fn device() -> BenchDevice {
    device_with(TestOd::new())
}

fn device_with<OD: ObjectDictionary>(od: OD) -> BenchDevice<OD> {
    let mut dev = Device::new(od, (), MemStorage::default(), NodeId::new(1).unwrap());
    dev.poll(0, |_| {});
    dev
}

fn sdo<M: Measurement + 'static>(c: &mut Criterion<M>, clock: &str) {
    let mut dev = device();
    let upload = frame("601 40 41 60 00 00 00 00 00");
    let download = frame("601 23 7A 60 00 E8 03 00 00");
    c.bench_function(&format!("{clock}/sdo_expedited_upload"), |b| {
        b.iter(|| {
            let mut resp = None;
            dev.on_frame(black_box(&upload), 0);
            dev.poll(0, |f| resp = Some(f));
            black_box(resp)
        })
    });
    c.bench_function(&format!("{clock}/sdo_expedited_download"), |b| {
        b.iter(|| {
            let mut resp = None;
            dev.on_frame(black_box(&download), 0);
            dev.poll(0, |f| resp = Some(f));
            black_box(resp)
        })
    });
}

fn rpdo<M: Measurement + 'static, OD: ObjectDictionary>(c: &mut Criterion<M>, clock: &str, od: OD) {
    let mut dev = device_with(od);
    dev.nmt_command(NmtCommand::Start, 0);
    dev.poll(0, |_| {});
    // RPDO2: controlword + target position, event-driven (applied on reception).
    let rx = frame("301 0F 00 40 42 0F 00");
    // Checked once before the measurement (which a filter may skip): the frame is applied.
    dev.on_frame(&rx, 0);
    let mut b = [0u8; 4];
    assert_eq!(dev.od().read(0x607A, 0, &mut b), Ok(4));
    assert_eq!(i32::from_le_bytes(b), 1_000_000);
    c.bench_function(&format!("{clock}/rpdo_receive_and_apply"), |b| {
        b.iter(|| {
            dev.on_frame(black_box(&rx), 0);
        })
    });
}

fn sync_tpdos<M: Measurement + 'static, OD: ObjectDictionary>(c: &mut Criterion<M>, clock: &str, od: OD) {
    let mut dev = device_with(od);
    for n in 0..4u16 {
        let cob = 0x181 + 0x100 * u32::from(n);
        dev.write(0x1800 + n, 1, &(cob | 0x8000_0000).to_le_bytes()).unwrap();
        dev.write(0x1800 + n, 2, &[1]).unwrap();
        dev.write(0x1800 + n, 1, &cob.to_le_bytes()).unwrap();
    }
    dev.nmt_command(NmtCommand::Start, 0);
    dev.od_mut().write(0x6064, 0, &123_456i32.to_le_bytes()).unwrap();
    dev.od_mut().write(0x606C, 0, &(-789i32).to_le_bytes()).unwrap();
    let sync = Frame::new(0x080, &[]).unwrap();
    let mut n = 0;
    dev.on_frame(&sync, 0);
    dev.poll(0, |_| n += 1);
    assert_eq!(n, 4, "four TPDOs per SYNC");
    c.bench_function(&format!("{clock}/sync_to_4_tpdos"), |b| {
        b.iter(|| {
            let mut sent = 0u32;
            dev.on_frame(black_box(&sync), 0);
            dev.poll(0, |f| sent += f.len() as u32);
            black_box(sent)
        })
    });
}

fn wall(c: &mut Criterion) {
    sdo(c, "wall");
    rpdo(c, "wall", TestOd::new());
    sync_tpdos(c, "wall", TestOd::new());
    rpdo(c, "wall/plain", PlainOd::default());
    sync_tpdos(c, "wall/plain", PlainOd::default());
}

fn cpu(c: &mut Criterion<CpuTime>) {
    sdo(c, "cpu");
    rpdo(c, "cpu", TestOd::new());
    sync_tpdos(c, "cpu", TestOd::new());
    rpdo(c, "cpu/plain", PlainOd::default());
    sync_tpdos(c, "cpu/plain", PlainOd::default());
}

/// Thread CPU time in nanoseconds.
pub struct CpuTime;

#[cfg(target_os = "linux")]
fn thread_cpu_ns() -> u64 {
    #[repr(C)]
    struct Timespec {
        tv_sec: i64,
        tv_nsec: i64,
    }
    unsafe extern "C" {
        fn clock_gettime(clock: i32, ts: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut ts = Timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; clock_gettime only writes into it.
    unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_ns() -> u64 {
    use std::sync::OnceLock;
    static START: OnceLock<std::time::Instant> = OnceLock::new();
    START.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
}

struct Nanos;

impl ValueFormatter for Nanos {
    fn scale_values(&self, _typical: f64, _values: &mut [f64]) -> &'static str {
        "ns"
    }
    fn scale_throughputs(&self, _typical: f64, _t: &Throughput, values: &mut [f64]) -> &'static str {
        for v in values {
            *v = 1e9 / *v;
        }
        "/s"
    }
    fn scale_for_machines(&self, _values: &mut [f64]) -> &'static str {
        "ns"
    }
}

impl Measurement for CpuTime {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        thread_cpu_ns()
    }
    fn end(&self, start: u64) -> u64 {
        thread_cpu_ns().saturating_sub(start)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        &Nanos
    }
}

criterion_group!(wall_clock, wall);
criterion_group! {
    name = cpu_time;
    config = Criterion::default().with_measurement(CpuTime);
    targets = cpu
}
criterion_main!(wall_clock, cpu_time);
