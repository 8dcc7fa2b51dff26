//! Instructions per operation of the device core's hot paths, counted by valgrind: a measure
//! that does not depend on how loaded the machine is (the times of `benches/services.rs` do).
//!
//! `cargo bench -p od-runtime --bench icount` runs every operation under
//! `valgrind --tool=cachegrind` twice, with two iteration counts, and prints the difference of
//! the instruction counts divided by the difference of the iterations: the cost of one
//! operation, without start-up. The operations are those of `benches/services.rs`, on the same
//! hand-built test dictionary. With an operation name and a count as arguments
//! (`icount sync 1000`) the binary just runs that loop, which is what valgrind is given (and
//! what `valgrind --tool=callgrind` can be given to see where the instructions go).

#[path = "support/icount.rs"]
mod icount;

#[path = "../tests/it/common/mod.rs"]
mod common;

use common::*;
use od_runtime::{Device, Frame, NmtCommand, NodeId};
use std::hint::black_box;

type BenchDevice = Device<TestOd, (), MemStorage>;

fn device() -> BenchDevice {
    let mut dev = Device::new(TestOd::new(), (), MemStorage::default(), NodeId::new(1).unwrap());
    dev.poll(0, |_| {});
    dev
}

const OPS: &[(&str, &str)] = &[
    ("sdo_upload", "SDO expedited upload of 6041h, request to response"),
    ("sdo_download", "SDO expedited download of 607Ah, request to response"),
    ("rpdo", "RPDO2 (controlword + target position) received and applied"),
    ("sync", "SYNC turned into 4 TPDOs (statusword, mode, position, velocity, error register)"),
    ("poll_idle", "poll with nothing to do (operational, synchronous TPDOs only)"),
];

fn run(op: &str, n: usize) -> Result<(), String> {
    let mut dev = device();
    let mut sink = 0u64;
    match op {
        "sdo_upload" | "sdo_download" => {
            let req = if op == "sdo_upload" {
                frame("601 40 41 60 00 00 00 00 00")
            } else {
                frame("601 23 7A 60 00 E8 03 00 00")
            };
            for _ in 0..n {
                dev.on_frame(black_box(&req), 0);
                dev.poll(0, |f| sink += u64::from(f.data()[0]));
            }
        }
        "rpdo" => {
            dev.nmt_command(NmtCommand::Start, 0);
            dev.poll(0, |_| {});
            let rx = frame("301 0F 00 40 42 0F 00");
            for _ in 0..n {
                dev.on_frame(black_box(&rx), 0);
            }
            sink = dev.od().get(0x607A, 0) as u64;
        }
        "sync" => {
            for p in 0..4u16 {
                let cob = 0x181 + 0x100 * u32::from(p);
                dev.write(0x1800 + p, 1, &(cob | 0x8000_0000).to_le_bytes()).map_err(|e| format!("{e:?}"))?;
                dev.write(0x1800 + p, 2, &[1]).map_err(|e| format!("{e:?}"))?;
                dev.write(0x1800 + p, 1, &cob.to_le_bytes()).map_err(|e| format!("{e:?}"))?;
            }
            dev.nmt_command(NmtCommand::Start, 0);
            dev.od_mut().set(0x6064, 0, 123_456);
            dev.od_mut().set(0x606C, 0, -789);
            let sync = Frame::new(0x080, &[]).ok_or("SYNC frame")?;
            for _ in 0..n {
                dev.on_frame(black_box(&sync), 0);
                dev.poll(0, |f| sink += f.len() as u64);
            }
            // 4 frames of 3, 6, 6 and 1 bytes per SYNC.
            if sink != 16 * n as u64 {
                return Err(format!("unexpected frames: {sink} bytes for {n} SYNCs"));
            }
        }
        "poll_idle" => {
            dev.write(0x1800, 2, &[1]).map_err(|e| format!("{e:?}"))?;
            dev.nmt_command(NmtCommand::Start, 0);
            dev.poll(0, |_| {});
            for _ in 0..n {
                dev.poll(black_box(0), |f| sink += f.len() as u64);
            }
        }
        other => return Err(format!("unknown operation `{other}`")),
    }
    black_box(sink);
    Ok(())
}

fn main() {
    icount::main(OPS, (1_000, 11_000), run);
}
