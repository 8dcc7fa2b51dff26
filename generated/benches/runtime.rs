//! Run-time costs of generated code: entry lookup, PDO pack + unpack, a unit conversion.
//!
//! `cargo bench -p generated`. Targets (issue #4): lookup <= 10 ns, pack + unpack <= 20 ns,
//! conversion <= 10 ns.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use od_runtime::od::ObjectDictionary;

fn lookup(c: &mut Criterion) {
    use generated::akd::{Dictionary, ENTRIES};
    let keys: Vec<(u16, u8)> = ENTRIES.iter().map(|e| (e.index, e.sub)).collect();
    let od = Dictionary::new(1);
    let mut i = 0usize;
    c.bench_function(&format!("lookup: AKD position(index, sub), {} entries", keys.len()), |b| {
        b.iter(|| {
            i = (i + 7919) % keys.len();
            let (index, sub) = keys[i];
            Dictionary::position(black_box(index), black_box(sub))
        })
    });
    c.bench_function("lookup: AKD info(index, sub) through the trait", |b| {
        b.iter(|| {
            i = (i + 7919) % keys.len();
            let (index, sub) = keys[i];
            od.info(black_box(index), black_box(sub)).map(|e| e.bits)
        })
    });
    let mut buf = [0u8; 64];
    c.bench_function("read: AKD read(index, sub) as bytes", |b| {
        b.iter(|| {
            i = (i + 7919) % keys.len();
            let (index, sub) = keys[i];
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
    c.bench_function("units: Units::from_dictionary", |b| b.iter(|| Units::from_dictionary(black_box(&od))));
}

criterion_group!(benches, lookup, pdo, units);
criterion_main!(benches);
