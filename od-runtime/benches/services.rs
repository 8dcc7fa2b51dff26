//! Hot paths of the device core, measured on the hand-built test dictionary with an
//! application that does nothing (`()`): an expedited SDO request handled to its response, an
//! RPDO received and applied, and a SYNC turned into four TPDOs.

#[path = "../tests/common/mod.rs"]
mod common;

use common::*;
use criterion::{Criterion, criterion_group, criterion_main};
use od_runtime::{Device, Frame, NmtCommand, NodeId};
use std::hint::black_box;

type BenchDevice = Device<TestOd, (), MemStorage>;

fn device() -> BenchDevice {
    let mut dev = Device::new(TestOd::new(), (), MemStorage::default(), NodeId::new(1).unwrap());
    dev.poll(0, |_| {});
    dev
}

fn sdo(c: &mut Criterion) {
    let mut dev = device();
    let upload = frame("601 40 41 60 00 00 00 00 00");
    let download = frame("601 23 7A 60 00 E8 03 00 00");
    let mut g = c.benchmark_group("sdo");
    g.bench_function("expedited_upload", |b| {
        b.iter(|| {
            let mut resp = None;
            dev.on_frame(black_box(&upload), 0);
            dev.poll(0, |f| resp = Some(f));
            black_box(resp)
        })
    });
    g.bench_function("expedited_download", |b| {
        b.iter(|| {
            let mut resp = None;
            dev.on_frame(black_box(&download), 0);
            dev.poll(0, |f| resp = Some(f));
            black_box(resp)
        })
    });
    g.finish();
}

fn rpdo(c: &mut Criterion) {
    let mut dev = device();
    dev.nmt_command(NmtCommand::Start, 0);
    dev.poll(0, |_| {});
    // RPDO2: controlword + target position, event-driven (applied on reception).
    let rx = frame("301 0F 00 40 42 0F 00");
    c.bench_function("rpdo_receive_and_apply", |b| {
        b.iter(|| {
            dev.on_frame(black_box(&rx), 0);
        })
    });
    assert_eq!(dev.od().get(0x607A, 0), 1_000_000);
}

fn sync_tpdos(c: &mut Criterion) {
    let mut dev = device();
    for n in 0..4u16 {
        let cob = 0x181 + 0x100 * u32::from(n);
        dev.write(0x1800 + n, 1, &(cob | 0x8000_0000).to_le_bytes()).unwrap();
        dev.write(0x1800 + n, 2, &[1]).unwrap();
        dev.write(0x1800 + n, 1, &cob.to_le_bytes()).unwrap();
    }
    dev.nmt_command(NmtCommand::Start, 0);
    dev.od_mut().set(0x6064, 0, 123_456);
    dev.od_mut().set(0x606C, 0, -789);
    let sync = Frame::new(0x080, &[]).unwrap();
    let mut n = 0;
    dev.on_frame(&sync, 0);
    dev.poll(0, |_| n += 1);
    assert_eq!(n, 4, "four TPDOs per SYNC");
    c.bench_function("sync_to_4_tpdos", |b| {
        b.iter(|| {
            let mut sent = 0u32;
            dev.on_frame(black_box(&sync), 0);
            dev.poll(0, |f| sent += f.len() as u32);
            black_box(sent)
        })
    });
}

criterion_group!(benches, sdo, rpdo, sync_tpdos);
criterion_main!(benches);
