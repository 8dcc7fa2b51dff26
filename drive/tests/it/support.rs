//! How the drive tests talk to simulated devices: `od-master`, the project's master, on the
//! simulation's in-memory bus in virtual time ([`VirtualBus`]).
//!
//! [`Master`] keeps the short calls the tests are written with (`m.read_u32(2, 0x1000, 0)`,
//! `m.switch_on(2)`) and holds no protocol of its own: every SDO, NMT, PDO, SYNC and heartbeat
//! frame is made and parsed by od-master (over `od_runtime::master`); the CiA 402 state and
//! statusword come from [`od_master::Axis`]. What is here is test pacing (how much virtual
//! time passes between two steps) and the conversion of read bytes to the integer a test
//! compares. Raw frames a test writes itself ([`Master::send`]) go on the bus as they are.

use std::net::SocketAddr;
use std::time::Duration;

use drive::node::{Seen, Sim, VirtualBus};
use od_bus::CanFrame;
use od_master::{
    AbortCode, Axis, AxisConfig, AxisError, AxisErrorKind, Error, NmtCommand, PdoField, PdoMapping, PdoValue,
};
use od_runtime::Micros;
use od_runtime::cia402::State;
use od_runtime::master::SdoError;
use od_runtime::od::DataType;
use od_runtime::pdo::{Direction, MapEntry};

/// The SDO options of the tests: one attempt (a test checks the device, not the master's
/// retries), a timeout of 1 s, values up to od-master's default of 4 KiB.
fn sdo_options() -> od_master::SdoOptions {
    od_master::SdoOptions { timeout: Duration::from_secs(1), retries: 0, ..Default::default() }
}

/// The server's abort code of a failed SDO transfer, `None` for any other failure: for
/// `assert_eq!(m.write(..).map_err(abort), Err(Some(0x0609_0030))`.
pub fn abort(e: Error) -> Option<u32> {
    match e {
        Error::Sdo { error, .. } => match error.error {
            SdoError::Server(AbortCode(code)) => Some(code),
            SdoError::Client(_) => None,
        },
        _ => None,
    }
}

/// od-master's blocking facade on a `drive-sim` hub at `addr` (`HOST:PORT`), channel
/// `channel`: SDO answers awaited up to `timeout`, never retried (a lost answer fails the test
/// instead of being hidden).
pub fn hub_master(addr: impl std::fmt::Display, channel: &str, timeout: Duration) -> od_master::blocking::Bus {
    let sdo = od_master::SdoOptions { timeout, retries: 0, ..Default::default() };
    let config = od_master::Config { sdo, ..Default::default() };
    od_master::blocking::Bus::open(&format!("socketcand://{addr}/{channel}"), config).expect("od-master on the hub")
}

/// [`hub_master`] on channel can0, and its handle on node `id`.
pub fn on_hub(addr: SocketAddr, id: u8, timeout: Duration) -> (od_master::blocking::Bus, od_master::blocking::Node) {
    let bus = hub_master(addr, "can0", timeout);
    let node = bus.node(id).expect("a node id");
    (bus, node)
}

/// A simulation and od-master on its bus, with the tests' short calls.
pub struct Master {
    vb: VirtualBus,
}

impl Master {
    /// od-master on `sim`'s bus.
    pub fn new(sim: Sim) -> Self {
        let config = od_master::Config { sdo: sdo_options(), ..Default::default() };
        Self { vb: VirtualBus::new(sim, config).expect("a tokio runtime") }
    }

    /// The simulation.
    pub fn sim(&self) -> &Sim {
        self.vb.sim()
    }

    /// The simulation, mutably.
    pub fn sim_mut(&mut self) -> &mut Sim {
        self.vb.sim_mut()
    }

    /// Virtual time, µs.
    pub fn now(&self) -> Micros {
        self.vb.now()
    }

    /// Lets `dt` µs pass.
    pub fn advance(&mut self, dt: Micros) {
        self.vb.advance(dt);
    }

    /// Moves time in steps of `step` µs until `pred` holds (true) or `timeout` µs passed.
    pub fn wait_until(&mut self, timeout: Micros, step: Micros, mut pred: impl FnMut(&mut Master) -> bool) -> bool {
        let end = self.now().saturating_add(timeout);
        loop {
            if pred(self) {
                return true;
            }
            if self.now() >= end {
                return false;
            }
            self.advance(step.max(1));
        }
    }

    /// The frames received and not yet taken (SDO answers are taken by the transfers).
    pub fn seen(&self) -> impl Iterator<Item = &Seen> {
        self.vb.seen()
    }

    /// Takes the frames received so far.
    pub fn take_seen(&mut self) -> Vec<Seen> {
        self.vb.take_seen()
    }

    /// Takes the frames with COB-ID `id` received so far.
    pub fn take_id(&mut self, id: u32) -> Vec<Seen> {
        self.vb.take_id(id)
    }

    fn node(&self, id: u8) -> od_master::Node {
        self.vb.bus().node(id).expect("a node id in 1..=127")
    }

    fn axis(&self, id: u8) -> Axis {
        Axis::with_config(
            self.node(id),
            AxisConfig { state_timeout: Duration::from_secs(1), poll: Duration::from_millis(1) },
        )
    }

    /// Runs an SDO transfer with `node`; its answers are not left in [`seen`](Self::seen).
    fn sdo<T>(&mut self, node: u8, call: impl AsyncFnOnce(od_master::Node) -> Result<T, Error>) -> Result<T, Error> {
        let since = self.vb.seen_len();
        let handle = self.node(node);
        let out = self.vb.run(call(handle));
        self.vb.forget_since(since, 0x580 + u32::from(node));
        out
    }

    /// Runs `call` with od-master's handle of `node` (what a test of od-master's own
    /// procedures, such as `remote::map_pdo`, calls them with).
    pub fn with_node<T>(
        &mut self,
        node: u8,
        call: impl AsyncFnOnce(od_master::Node) -> Result<T, Error>,
    ) -> Result<T, Error> {
        self.sdo(node, call)
    }

    /// Puts a frame on the bus as it is (a test's own raw frame).
    pub fn send(&mut self, frame: CanFrame) {
        let bus = self.vb.bus().clone();
        self.vb.run(bus.send(frame)).expect("a frame on the memory bus");
    }

    /// NMT command `cs` (1 start, 2 stop, 80h pre-operational, 81h reset node, 82h reset
    /// communication) to `node` (0 = all).
    pub fn nmt(&mut self, cs: u8, node: u8) {
        let command = match cs {
            0x01 => NmtCommand::Start,
            0x02 => NmtCommand::Stop,
            0x80 => NmtCommand::EnterPreOperational,
            0x81 => NmtCommand::ResetNode,
            0x82 => NmtCommand::ResetCommunication,
            _ => panic!("no NMT command {cs:#04X}"),
        };
        let target = match node {
            0 => od_master::Target::All,
            id => od_master::Target::Node(od_master::NodeId::new(id).expect("a node id")),
        };
        let bus = self.vb.bus().clone();
        self.vb.run(bus.nmt(command, target)).expect("NMT on the memory bus");
    }

    /// NMT start.
    pub fn nmt_start(&mut self, node: u8) {
        self.nmt(0x01, node);
    }

    /// One SYNC.
    pub fn sync(&mut self) {
        let bus = self.vb.bus().clone();
        self.vb.run(bus.send_sync()).expect("SYNC on the memory bus");
    }

    /// A PDO on `id` carrying `data` (one OCTET_STRING field of its length, packed by
    /// od-master).
    pub fn pdo(&mut self, id: u32, data: &[u8]) {
        let bits = u8::try_from(data.len() * 8).expect("at most 8 bytes");
        let field = PdoField { entry: MapEntry { index: 0, sub: 0, bits }, data_type: DataType::OctetString };
        let mapping = PdoMapping::from_fields(Direction::Receive, &[field]).expect("a one-field mapping");
        let mut bytes = [0u8; 8];
        bytes[..data.len()].copy_from_slice(data);
        let value = PdoValue::Bytes { data: bytes, len: data.len() as u8 };
        let bus = self.vb.bus().clone();
        let cob_id = u16::try_from(id).expect("an 11-bit COB-ID");
        self.vb.run(async move { bus.send_pdo(cob_id, &mapping, &[value]).await }).expect("a PDO on the memory bus");
    }

    /// The master's heartbeat (operational) as node `id`.
    pub fn heartbeat(&mut self, id: u8) {
        let bus = self.vb.bus().clone();
        self.vb.run(bus.send_heartbeat(id, od_master::NmtState::Operational)).expect("a heartbeat on the memory bus");
    }

    /// SDO download.
    pub fn write(&mut self, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<(), Error> {
        self.sdo(node, async |n| n.write_bytes(index, sub, data).await)
    }

    /// SDO upload.
    pub fn read(&mut self, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, Error> {
        self.sdo(node, async |n| n.read_bytes(index, sub).await)
    }

    /// Reads a value of 1 to `N` bytes, little-endian, as its unsigned bits.
    fn read_le<const N: usize>(&mut self, node: u8, index: u16, sub: u8) -> Result<([u8; 8], usize), Error> {
        let d = self.read(node, index, sub)?;
        if d.is_empty() || d.len() > N {
            return Err(Error::Length { node, index, sub, expected: N, got: d.len() });
        }
        let mut b = [0u8; 8];
        b[..d.len()].copy_from_slice(&d);
        Ok((b, d.len()))
    }

    /// Reads an unsigned value of up to 8 bytes.
    pub fn read_u64(&mut self, node: u8, index: u16, sub: u8) -> Result<u64, Error> {
        Ok(u64::from_le_bytes(self.read_le::<8>(node, index, sub)?.0))
    }

    /// Reads a value of up to 8 bytes and sign-extends it from its length.
    pub fn read_i64(&mut self, node: u8, index: u16, sub: u8) -> Result<i64, Error> {
        let (b, len) = self.read_le::<8>(node, index, sub)?;
        let shift = 64 - 8 * len as u32;
        Ok((i64::from_le_bytes(b) << shift) >> shift)
    }

    /// Reads a value of one byte.
    pub fn read_u8(&mut self, node: u8, index: u16, sub: u8) -> Result<u8, Error> {
        Ok(self.read_le::<1>(node, index, sub)?.0[0])
    }

    /// Reads a value of up to 2 bytes.
    pub fn read_u16(&mut self, node: u8, index: u16, sub: u8) -> Result<u16, Error> {
        let (b, _) = self.read_le::<2>(node, index, sub)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    /// Reads a value of up to 4 bytes.
    pub fn read_u32(&mut self, node: u8, index: u16, sub: u8) -> Result<u32, Error> {
        let (b, _) = self.read_le::<4>(node, index, sub)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Writes an 8-bit value.
    pub fn write_u8(&mut self, node: u8, index: u16, sub: u8, v: u8) -> Result<(), Error> {
        self.sdo(node, async |n| n.write(index, sub, v).await)
    }

    /// Writes a 16-bit value.
    pub fn write_u16(&mut self, node: u8, index: u16, sub: u8, v: u16) -> Result<(), Error> {
        self.sdo(node, async |n| n.write(index, sub, v).await)
    }

    /// Writes a 32-bit value.
    pub fn write_u32(&mut self, node: u8, index: u16, sub: u8, v: u32) -> Result<(), Error> {
        self.sdo(node, async |n| n.write(index, sub, v).await)
    }

    /// Writes a signed 32-bit value.
    pub fn write_i32(&mut self, node: u8, index: u16, sub: u8, v: i32) -> Result<(), Error> {
        self.sdo(node, async |n| n.write(index, sub, v).await)
    }

    /// The statusword (6041h), read by the axis.
    pub fn statusword(&mut self, node: u8) -> Result<u16, Error> {
        let axis = self.axis(node);
        let since = self.vb.seen_len();
        let out = self.vb.run(axis.statusword());
        self.vb.forget_since(since, 0x580 + u32::from(node));
        out
    }

    /// The CiA 402 state from the statusword.
    pub fn state(&mut self, node: u8) -> Result<Option<State>, Error> {
        Ok(State::from_statusword(self.statusword(node)?))
    }

    /// Writes the controlword (never retried).
    pub fn controlword(&mut self, node: u8, cw: u16) -> Result<(), Error> {
        let axis = self.axis(node);
        let since = self.vb.seen_len();
        let out = self.vb.run(axis.controlword(cw));
        self.vb.forget_since(since, 0x580 + u32::from(node));
        out
    }

    /// Shutdown (6), switch on (7), enable operation (15), 2 ms apart: to Operation enabled
    /// from Switch on disabled, each state checked on the way (a drive in Fault fails: the
    /// tests that want a fault reset write it).
    pub fn switch_on(&mut self, node: u8) -> Result<(), Error> {
        for (cw, want) in [(0x06, State::ReadyToSwitchOn), (0x07, State::SwitchedOn), (0x0F, State::OperationEnabled)] {
            self.controlword(node, cw)?;
            self.advance(2000);
            let sw = self.statusword(node)?;
            let state = State::from_statusword(sw);
            if state != Some(want) {
                let kind = AxisErrorKind::Timeout { what: format!("{want:?}"), timeout_ms: 2 };
                let error = AxisError {
                    node,
                    state,
                    statusword: Some(sw),
                    seen: None,
                    index: 0x6041,
                    sub: 0,
                    kind,
                    register: None,
                };
                return Err(Error::Axis(Box::new(error)));
            }
        }
        Ok(())
    }

    /// Writes 6060h and, 1 ms later, checks that 6061h shows it.
    pub fn set_mode(&mut self, node: u8, mode: i8) -> Result<(), Error> {
        self.sdo(node, async |n| n.write(0x6060, 0, mode).await)?;
        self.advance(1000);
        let shown = self.read_i64(node, 0x6061, 0)?;
        if shown == i64::from(mode) {
            return Ok(());
        }
        let kind = AxisErrorKind::Mode { wanted: mode, shown: shown as i8 };
        let error =
            AxisError { node, state: None, statusword: None, seen: None, index: 0x6061, sub: 0, kind, register: None };
        Err(Error::Axis(Box::new(error)))
    }

    /// Polls the statusword every `poll` µs until `statusword & mask == value`; the statusword,
    /// or `None` on timeout (or a failed read).
    pub fn wait_statusword(&mut self, node: u8, mask: u16, value: u16, timeout: Micros, poll: Micros) -> Option<u16> {
        let end = self.now().saturating_add(timeout);
        loop {
            let sw = self.statusword(node).ok()?;
            if sw & mask == value {
                return Some(sw);
            }
            if self.now() >= end {
                return None;
            }
            self.advance(poll.max(1));
        }
    }
}
