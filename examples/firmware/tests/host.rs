//! The firmware's application logic on the host: [`Firmware`] on the in-memory bus of the
//! `od-bus` crate, through an `embedded_can::nb::Can` adapter, driven by a master made of
//! plain frames (NMT, SDO, SYNC), exactly as the binary runs it on CAN1.

use firmware::Firmware;
use od_bus::{CanFrame, Endpoint, LocalEndpoint, MemoryBus};
use od_runtime::{Frame, NodeId};

const NODE: u8 = 5;

/// The in-memory bus as a CAN driver with one transmit mailbox that is always free.
struct BusCan(LocalEndpoint);

#[derive(Debug)]
struct BusError;

impl embedded_can::Error for BusError {
    fn kind(&self) -> embedded_can::ErrorKind {
        embedded_can::ErrorKind::Other
    }
}

impl embedded_can::nb::Can for BusCan {
    type Frame = Frame;
    type Error = BusError;

    fn transmit(&mut self, f: &Frame) -> nb::Result<Option<Frame>, BusError> {
        let frame = if f.is_rtr() {
            CanFrame::remote(f.id().into(), false, f.len() as u8)
        } else {
            CanFrame::standard(f.id().into(), f.data())
        };
        self.0.send(frame.map_err(|_| BusError)?).map_err(|_| BusError)?;
        Ok(None)
    }

    fn receive(&mut self) -> nb::Result<Frame, BusError> {
        match self.0.try_recv().map_err(|_| BusError)? {
            Some(f) => Ok(Frame::from_parts(f.id() as u16, f.is_remote(), f.dlc(), f.raw_data())),
            None => Err(nb::Error::WouldBlock),
        }
    }
}

struct Bench {
    fw: &'static mut Firmware,
    can: BusCan,
    master: LocalEndpoint,
    now: u64,
}

impl Bench {
    /// The firmware as the binary builds it: in place, from a zeroed dictionary.
    fn new() -> Self {
        let place = Box::leak(Box::new(std::mem::MaybeUninit::uninit()));
        Self::with(Firmware::init(place, NodeId::new(NODE).unwrap()))
    }

    /// The firmware built by the `const fn` (the dictionary starts from its defaults).
    fn from_const() -> Self {
        Self::with(Box::leak(Box::new(Firmware::new(NodeId::new(NODE).unwrap()))))
    }

    fn with(fw: &'static mut Firmware) -> Self {
        let bus = MemoryBus::new();
        let can = BusCan(bus.endpoint());
        let master = bus.endpoint();
        Self { fw, can, master, now: 0 }
    }

    /// Runs the firmware for `ms` milliseconds in 100 µs turns; returns what it sent.
    fn run(&mut self, ms: u64) -> Vec<String> {
        for _ in 0..ms * 10 {
            self.fw.step(&mut self.can, self.now);
            self.now += 100;
        }
        let mut out = Vec::new();
        while let Some(f) = self.master.try_recv().unwrap() {
            out.push(Frame::from_parts(f.id() as u16, f.is_remote(), f.dlc(), f.raw_data()).to_string());
        }
        out
    }

    fn send(&mut self, id: u16, data: &[u8]) -> Vec<String> {
        self.master.send(CanFrame::standard(id.into(), data).unwrap()).unwrap();
        self.run(1)
    }

    fn sdo_write(&mut self, index: u16, sub: u8, value: &[u8]) {
        let mut d = vec![0x23 | ((4 - value.len() as u8) << 2), index as u8, (index >> 8) as u8, sub];
        d.extend_from_slice(value);
        d.resize(8, 0);
        let out = self.send(0x600 + u16::from(NODE), &d);
        let want = format!("585 60 {:02X} {:02X} {sub:02X} 00 00 00 00", index & 0xFF, index >> 8);
        assert!(out.contains(&want), "write {index:04X}: {out:?}");
    }

    fn sdo_read(&mut self, index: u16, sub: u8) -> u32 {
        let out = self.send(0x600 + u16::from(NODE), &[0x40, index as u8, (index >> 8) as u8, sub, 0, 0, 0, 0]);
        let resp = out.iter().find(|f| f.starts_with("585 ")).unwrap_or_else(|| panic!("no answer: {out:?}"));
        let b: Vec<u8> = resp.split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
        assert_eq!(b[0] & 0xE3, 0x43, "expedited upload of {index:04X}: {resp}");
        u32::from_le_bytes([b[4], b[5], b[6], b[7]])
    }
}

#[test]
fn boots_enables_and_moves_to_the_target() {
    boot_enable_move(Bench::new());
    boot_enable_move(Bench::from_const());
}

fn boot_enable_move(mut b: Bench) {
    assert_eq!(b.run(1), ["705 00"], "boot-up");
    b.send(0x000, &[0x01, NODE]);
    assert_eq!(b.fw.device().nmt_state(), od_runtime::NmtState::Operational);
    b.sdo_write(0x6060, 0, &[1]);
    b.sdo_write(0x607A, 0, &1234i32.to_le_bytes());
    // Not enabled: the axis stands still.
    b.run(5);
    assert_eq!(b.sdo_read(0x6064, 0), 0);
    for cw in [0x06u16, 0x07, 0x0F] {
        b.sdo_write(0x6040, 0, &cw.to_le_bytes());
    }
    assert!(b.fw.device().app().enabled(), "state {:?}", b.fw.device().cia402_state());
    // 100 increments per millisecond: 1234 takes 13 ms.
    b.run(5);
    let halfway = b.sdo_read(0x6064, 0) as i32;
    assert!((400..1234).contains(&halfway), "{halfway}");
    assert_eq!(b.sdo_read(0x6041, 0) & (1 << 10), 0, "target not reached yet");
    b.run(20);
    assert_eq!(b.sdo_read(0x6064, 0) as i32, 1234);
    assert_ne!(b.sdo_read(0x6041, 0) & (1 << 10), 0, "target reached");
    // Disable: a new target is not followed.
    b.sdo_write(0x6040, 0, &0x06u16.to_le_bytes());
    b.sdo_write(0x607A, 0, &(-50i32).to_le_bytes());
    b.run(5);
    assert_eq!(b.sdo_read(0x6064, 0) as i32, 1234);
    assert_eq!((b.fw.link().dropped(), b.fw.link().errors()), (0, 0));
}

#[test]
fn sync_answers_with_the_synchronous_tpdo() {
    let mut b = Bench::new();
    b.run(1);
    // The defaults are in place after the boot (the dictionary started zeroed).
    assert_eq!(b.sdo_read(0x1800, 1), 0x180 + u32::from(NODE));
    // TPDO1 (statusword, by the DRCS's default mapping) made synchronous, every SYNC.
    b.sdo_write(0x1800, 2, &[1]);
    let sw = b.sdo_read(0x6041, 0) as u16;
    b.send(0x000, &[0x01, NODE]);
    let out = b.send(0x080, &[]);
    assert_eq!(out, [format!("185 {:02X} {:02X}", sw & 0xFF, sw >> 8)]);
}
