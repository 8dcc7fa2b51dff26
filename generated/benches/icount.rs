//! Instructions per operation of generated code, counted by valgrind: a measure that does not
//! depend on how loaded the machine is (criterion's times in `benches/runtime.rs` do).
//!
//! `cargo bench -p generated --bench icount` runs every operation under
//! `valgrind --tool=cachegrind` twice, with two iteration counts, and prints the difference of
//! the instruction counts divided by the difference of the iterations: the cost of one
//! operation, without start-up. The `baseline` row is the loop alone (choosing the next key);
//! the other rows include it. With an operation name and a count as arguments
//! (`icount lookup 1000`) the binary just runs that loop, which is what valgrind is given.
//!
//! Instructions are not nanoseconds (a division or a cache miss costs more than an add), so the
//! report gives both: read the counts together with `cargo bench -p generated --bench runtime`.

#[path = "../../od-runtime/benches/support/icount.rs"]
mod icount;

use std::hint::black_box;

use generated::akd;
use generated::drvi;
use od_runtime::od::ObjectDictionary;

/// Keys visited in a scrambled order, 1024 of them so the next one is `i & 1023`.
fn keys() -> Vec<(u16, u8)> {
    let all: Vec<(u16, u8)> = akd::ENTRIES.iter().map(|e| (e.index, e.sub)).collect();
    (0..1024).map(|i| all[(i * 7919) % all.len()]).collect()
}

fn units() -> drvi::units::Units {
    let mut od = drvi::Dictionary::new(32);
    od.set_feed_converter_numerator(100).unwrap_or_default();
    od.set_feed_converter_denominator(254).unwrap_or_default();
    drvi::units::Units::from_dictionary(&od).expect("DRVI units")
}

const OPS: &[(&str, &str)] = &[
    ("baseline", "the loop alone: the next key and black_box"),
    ("lookup", "AKD Dictionary::position(index, sub)"),
    ("info", "AKD ObjectDictionary::info(index, sub)"),
    ("read", "AKD ObjectDictionary::read(index, sub) into a buffer"),
    ("pdo", "AKD Tpdo3 (u16 + i32) pack + unpack"),
    ("to_physical", "DRVI position raw -> physical (exact)"),
    ("to_raw", "DRVI position 360.1 deg -> raw (rounded)"),
    ("to_raw_int", "DRVI position 360 deg -> raw (rounded)"),
    ("from_dictionary", "DRVI Units::from_dictionary (all dimensions prepared)"),
    ("device_rpdo", "DRVI device: RPDO1 (controlword) received and applied"),
    ("device_sync", "DRVI device: SYNC turned into 4 TPDOs (5 mapped entries)"),
];

type DrviDevice = od_runtime::Device<drvi::Dictionary, (), od_runtime::NoStorage>;

/// The DRVI device of `benches/runtime.rs`' `device` group: booted, remote, operational.
fn drvi_device() -> DrviDevice {
    use od_runtime::{Device, NmtCommand, NoStorage, NodeId};
    let node = NodeId::new(2).unwrap_or_else(|| unreachable!());
    let mut dev = Device::new(drvi::Dictionary::new(2), (), NoStorage, node);
    dev.poll(0, |_| {});
    dev.set_remote(true);
    dev.nmt_command(NmtCommand::Start, 0);
    dev.poll(0, |_| {});
    dev
}

/// Maps TPDOs 1..4 of the DRVI device as `benches/runtime.rs` does: synchronous, statusword /
/// position / velocity / statusword + position.
fn map_four_tpdos(dev: &mut DrviDevice) -> Result<(), String> {
    let maps: [&[u32]; 4] = [&[0x6041_0010], &[0x6064_0020], &[0x606C_0020], &[0x6041_0010, 0x6064_0020]];
    for (n, map) in maps.iter().enumerate() {
        let n = n as u16;
        let cob = 0x182 + 0x100 * u32::from(n);
        let w = |dev: &mut DrviDevice, index: u16, sub: u8, data: &[u8]| {
            dev.write(index, sub, data).map_err(|e| format!("{index:04X}sub{sub}: {e:?}"))
        };
        w(dev, 0x1800 + n, 1, &(cob | 0x8000_0000).to_le_bytes())?;
        w(dev, 0x1800 + n, 2, &[1])?;
        w(dev, 0x1A00 + n, 0, &[0])?;
        for (k, m) in map.iter().enumerate() {
            w(dev, 0x1A00 + n, k as u8 + 1, &m.to_le_bytes())?;
        }
        w(dev, 0x1A00 + n, 0, &[map.len() as u8])?;
        w(dev, 0x1800 + n, 1, &cob.to_le_bytes())?;
    }
    Ok(())
}

/// Runs `f` for `0..n` and keeps the results alive; one monomorphic loop per operation, so the
/// choice of operation is made once, outside the loop.
#[inline(never)]
fn repeat(n: usize, mut f: impl FnMut(usize) -> u64) {
    let mut sink = 0u64;
    for i in 0..n {
        sink = sink.wrapping_add(f(i));
    }
    black_box(sink);
}

fn run(op: &str, n: usize) -> Result<(), String> {
    use drvi::units::{Dimension, Quantity, Ratio, Unit};
    let keys = keys();
    let next = |i: usize| keys[i & 1023];
    let od = akd::Dictionary::new(1);
    let u = units();
    let mut buf = [0u8; 64];
    let decimal = Quantity::new(Ratio::new(3601, 10).unwrap_or(Ratio::ONE), Unit::Degree);
    let integer = Quantity::int(360, Unit::Degree);
    match op {
        "baseline" => repeat(n, |i| {
            let (index, sub) = next(i);
            black_box(index) as u64 + black_box(sub) as u64
        }),
        "lookup" => repeat(n, |i| {
            let (index, sub) = next(i);
            akd::Dictionary::position(black_box(index), black_box(sub)).unwrap_or(0) as u64
        }),
        "info" => repeat(n, |i| {
            let (index, sub) = next(i);
            od.info(black_box(index), black_box(sub)).map(|e| e.bits()).unwrap_or(0) as u64
        }),
        "read" => repeat(n, |i| {
            let (index, sub) = next(i);
            od.read(black_box(index), black_box(sub), &mut buf).unwrap_or(0) as u64
        }),
        "pdo" => repeat(n, |i| {
            let t = akd::pdo::Tpdo3 { statusword: 0x0637, position_actual_value: i as i32 };
            let bytes = black_box(&t).pack();
            akd::pdo::Tpdo3::unpack(black_box(&bytes)).map(|t| t.position_actual_value as u64).unwrap_or(0)
        }),
        "to_physical" => repeat(n, |i| {
            let q = u.to_physical(Dimension::Position, black_box(i as i64));
            q.map(|q| q.value.num() as u64).unwrap_or(0)
        }),
        "to_raw" => repeat(n, |_| u.to_raw(Dimension::Position, black_box(decimal)).unwrap_or(0) as u64),
        "to_raw_int" => repeat(n, |_| u.to_raw(Dimension::Position, black_box(integer)).unwrap_or(0) as u64),
        "from_dictionary" => {
            let mut od = drvi::Dictionary::new(32);
            od.set_feed_converter_numerator(100).unwrap_or_default();
            od.set_feed_converter_denominator(254).unwrap_or_default();
            repeat(n, |_| drvi::units::Units::from_dictionary(black_box(&od)).map(|u| u.system() as u64).unwrap_or(0))
        }
        "device_rpdo" => {
            let mut dev = drvi_device();
            let rx = od_runtime::Frame::new(0x202, &[0x06, 0x00]).ok_or("frame")?;
            repeat(n, |_| {
                dev.on_frame(black_box(&rx), 0);
                0
            })
        }
        "device_sync" => {
            let mut dev = drvi_device();
            map_four_tpdos(&mut dev)?;
            let sync = od_runtime::Frame::new(0x080, &[]).ok_or("frame")?;
            let mut frames = 0u64;
            repeat(n, |_| {
                let mut sent = 0u64;
                dev.on_frame(black_box(&sync), 0);
                dev.poll(0, |f| {
                    sent += u64::from(f.data()[0]);
                    frames += 1;
                });
                sent
            });
            if frames != 4 * n as u64 {
                return Err(format!("{frames} TPDOs for {n} SYNCs"));
            }
        }
        other => return Err(format!("unknown operation `{other}`")),
    }
    Ok(())
}

fn main() {
    icount::main(OPS, (1_000, 21_000), run);
}
