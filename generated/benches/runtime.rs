//! Run-time costs of generated code: entry lookup, PDO pack + unpack, a unit conversion.
//!
//! `cargo bench -p generated --bench runtime`. Targets (issue #4): lookup <= 10 ns, pack + unpack
//! <= 20 ns, conversion <= 10 ns. Times include the loop choosing the next key (its own row,
//! "loop overhead"); `--bench icount` counts instructions, which a loaded machine does not skew.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use od_runtime::od::ObjectDictionary;

/// 1024 keys of the AKD dictionary in a scrambled order (so the next one is `i & 1023`, without
/// a division in the measured loop).
fn akd_keys() -> Vec<(u16, u8)> {
    let all: Vec<(u16, u8)> = generated::akd::ENTRIES.iter().map(|e| (e.index, e.sub)).collect();
    (0..1024).map(|i| all[(i * 7919) % all.len()]).collect()
}

fn lookup(c: &mut Criterion) {
    use generated::akd::{Dictionary, ENTRIES};
    let keys = akd_keys();
    let od = Dictionary::new(1);
    let mut i = 0usize;
    c.bench_function("lookup: loop overhead (next key only)", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let (index, sub) = keys[i & 1023];
            (black_box(index), black_box(sub))
        })
    });
    c.bench_function(&format!("lookup: AKD position(index, sub), {} entries", ENTRIES.len()), |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let (index, sub) = keys[i & 1023];
            Dictionary::position(black_box(index), black_box(sub))
        })
    });
    c.bench_function("lookup: AKD info(index, sub) through the trait", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let (index, sub) = keys[i & 1023];
            od.info(black_box(index), black_box(sub)).map(|e| e.bits())
        })
    });
    let absent: Vec<(u16, u8)> = keys.iter().map(|&(index, sub)| (index ^ 0x0800, sub.wrapping_add(100))).collect();
    c.bench_function("lookup: AKD position of absent keys", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let (index, sub) = absent[i & 1023];
            Dictionary::position(black_box(index), black_box(sub))
        })
    });
    let mut buf = [0u8; 64];
    c.bench_function("read: AKD read(index, sub) as bytes", |b| {
        b.iter(|| {
            i = i.wrapping_add(1);
            let (index, sub) = keys[i & 1023];
            od.read(black_box(index), black_box(sub), &mut buf)
        })
    });
}

fn pdo(c: &mut Criterion) {
    use generated::akd::pdo::Tpdo3;
    let mut t = Tpdo3 { statusword: 0x0637, position_actual_value: -123_456 };
    c.bench_function("pdo: AKD TPDO3 (u16 + i32) pack + unpack", |b| {
        b.iter(|| {
            t.position_actual_value = t.position_actual_value.wrapping_add(1);
            let bytes = black_box(&t).pack();
            Tpdo3::unpack(black_box(&bytes))
        })
    });
    use generated::fixture_mini::pdo::Tpdo1;
    let t = Tpdo1 { statusword: 0x0637, modes_of_operation_display: 3, signed_24: -2, flag: true };
    c.bench_function("pdo: bit-granular TPDO (16 + 8 + 24 + 1 bits) pack + unpack", |b| {
        b.iter(|| Tpdo1::unpack(&black_box(&t).pack()))
    });
}

fn units(c: &mut Criterion) {
    use generated::drvi::Dictionary;
    use generated::drvi::units::{Dimension, Quantity, Ratio, Unit, Units};
    let mut od = Dictionary::new(32);
    od.set_feed_converter_numerator(100).unwrap();
    od.set_feed_converter_denominator(254).unwrap();
    let u = Units::from_dictionary(&od).unwrap();
    let mut raw = 0i64;
    c.bench_function("units: DRVI raw -> physical (exact)", |b| {
        b.iter(|| {
            raw += 1;
            u.to_physical(Dimension::Position, black_box(raw))
        })
    });
    let q = Quantity::new(Ratio::new(3601, 10).unwrap(), Unit::Degree);
    c.bench_function("units: DRVI physical -> raw (rounded)", |b| {
        b.iter(|| u.to_raw(Dimension::Position, black_box(q)))
    });
    let q = Quantity::int(360, Unit::Degree);
    c.bench_function("units: DRVI physical -> raw, integer quantity", |b| {
        b.iter(|| u.to_raw(Dimension::Position, black_box(q)))
    });
    let q = Quantity::new(Ratio::new(3601, 7).unwrap(), Unit::Degree);
    c.bench_function("units: DRVI physical -> raw, denominator 7 (hardware division)", |b| {
        b.iter(|| u.to_raw(Dimension::Position, black_box(q)))
    });
    c.bench_function("units: Units::from_dictionary", |b| b.iter(|| Units::from_dictionary(black_box(&od))));
}

/// The device core (od-runtime) over a generated dictionary, as a drive runs it: the DRVI's
/// RPDO1 (controlword, which also steps the CiA 402 state machine) received and applied, and a
/// SYNC turned into four synchronous TPDOs of statusword / position / velocity.
fn device(c: &mut Criterion) {
    use generated::drvi::Dictionary;
    use od_runtime::{Device, Frame, NmtCommand, NoStorage, NodeId};

    fn start() -> Device<Dictionary, (), NoStorage> {
        let mut dev = Device::new(Dictionary::new(2), (), NoStorage, NodeId::new(2).unwrap());
        dev.poll(0, |_| {});
        dev.set_remote(true);
        dev.nmt_command(NmtCommand::Start, 0);
        dev.poll(0, |_| {});
        dev
    }

    let mut dev = start();
    let rx = Frame::new(0x202, &[0x06, 0x00]).unwrap(); // RPDO1: controlword "shutdown"
    dev.on_frame(&rx, 0);
    c.bench_function("device: DRVI RPDO1 received and applied (controlword)", |b| {
        b.iter(|| dev.on_frame(black_box(&rx), 0))
    });

    let mut dev = start();
    let maps: [&[u32]; 4] = [&[0x6041_0010], &[0x6064_0020], &[0x606C_0020], &[0x6041_0010, 0x6064_0020]];
    for (n, map) in maps.iter().enumerate() {
        let n = n as u16;
        let cob = 0x182 + 0x100 * u32::from(n);
        dev.write(0x1800 + n, 1, &(cob | 0x8000_0000).to_le_bytes()).unwrap();
        dev.write(0x1800 + n, 2, &[1]).unwrap();
        dev.write(0x1A00 + n, 0, &[0]).unwrap();
        for (k, m) in map.iter().enumerate() {
            dev.write(0x1A00 + n, k as u8 + 1, &m.to_le_bytes()).unwrap();
        }
        dev.write(0x1A00 + n, 0, &[map.len() as u8]).unwrap();
        dev.write(0x1800 + n, 1, &cob.to_le_bytes()).unwrap();
    }
    let sync = Frame::new(0x080, &[]).unwrap();
    let mut count = 0;
    dev.on_frame(&sync, 0);
    dev.poll(0, |_| count += 1);
    assert_eq!(count, 4, "four TPDOs per SYNC");
    c.bench_function("device: DRVI SYNC turned into 4 TPDOs", |b| {
        b.iter(|| {
            let mut sent = 0u32;
            dev.on_frame(black_box(&sync), 0);
            dev.poll(0, |f| sent += u32::from(f.data()[0]));
            black_box(sent)
        })
    });
}

criterion_group!(benches, lookup, pdo, units, device);
criterion_main!(benches);
