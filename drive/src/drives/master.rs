//! A small CANopen master for in-process simulations: NMT, expedited and segmented SDO, PDOs
//! and CiA 402 helpers, all as frames on a [`Sim`]'s in-memory bus in virtual time.
//!
//! It is what `drive-sim demo` and the drive tests talk to devices with: every request is a
//! real frame handled by the node runner and od-runtime, every answer a frame back.
//!
//! ```
//! use drive::drives::{DeviceApps, master::Master};
//! use drive::node::{DeviceKind, NodeConfig, Sim};
//!
//! let mut sim = Sim::new();
//! sim.add(DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..Default::default() }, &DeviceApps::new()).unwrap());
//! let mut m = Master::new(sim);
//! m.advance(1000);
//! m.nmt_start(2);
//! assert_eq!(m.read_u32(2, 0x1000, 0).unwrap(), 0xFF7A_0192);
//! m.switch_on(2).unwrap(); // shutdown, switch on, enable operation
//! assert_eq!(m.read_u16(2, 0x6041, 0).unwrap() & 0x6F, 0x27);
//! ```

use std::collections::VecDeque;
use std::fmt;

use od_runtime::Micros;
use od_runtime::cia402::State;

use crate::node::Sim;
use od_bus::{CanFrame, Endpoint, LocalEndpoint};

/// Why an SDO transfer failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoError {
    /// The server aborted with this code.
    Abort(u32),
    /// No answer within the timeout.
    Timeout,
    /// An answer that does not fit the protocol.
    Protocol,
}

impl fmt::Display for SdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SdoError::Abort(code) => write!(f, "SDO abort {code:#010X}"),
            SdoError::Timeout => f.write_str("SDO timeout"),
            SdoError::Protocol => f.write_str("SDO protocol error"),
        }
    }
}

impl std::error::Error for SdoError {}

/// A frame the master saw, with the virtual time it arrived.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seen {
    /// Virtual time, µs.
    pub at: Micros,
    /// The frame.
    pub frame: CanFrame,
}

/// The in-process master. It owns the [`Sim`] and moves its time.
pub struct Master {
    sim: Sim,
    ep: LocalEndpoint,
    /// Frames received and not yet taken by an SDO transfer or [`Master::take_seen`].
    seen: VecDeque<Seen>,
    /// Frames sent and received.
    sent: u64,
    received: u64,
    /// Virtual time an SDO answer may take.
    pub sdo_timeout: Micros,
    /// Step of virtual time while waiting for answers.
    pub step: Micros,
    keep: usize,
}

impl Master {
    /// A master on `sim`'s bus.
    pub fn new(sim: Sim) -> Self {
        let ep = sim.endpoint();
        Self { sim, ep, seen: VecDeque::new(), sent: 0, received: 0, sdo_timeout: 1_000_000, step: 100, keep: 100_000 }
    }

    /// The simulation.
    pub fn sim(&self) -> &Sim {
        &self.sim
    }

    /// The simulation, mutably.
    pub fn sim_mut(&mut self) -> &mut Sim {
        &mut self.sim
    }

    /// Virtual time, µs.
    pub fn now(&self) -> Micros {
        self.sim.now()
    }

    /// Frames sent by the master so far.
    pub fn frames_sent(&self) -> u64 {
        self.sent
    }

    /// Frames received by the master so far.
    pub fn frames_received(&self) -> u64 {
        self.received
    }

    fn collect(&mut self) {
        while let Ok(Some(frame)) = self.ep.try_recv() {
            self.received += 1;
            if self.seen.len() >= self.keep {
                self.seen.pop_front();
            }
            self.seen.push_back(Seen { at: self.sim.now(), frame });
        }
    }

    /// Sends a frame (delivered at the current instant).
    pub fn send(&mut self, frame: CanFrame) {
        if self.ep.send(frame).is_ok() {
            self.sent += 1;
        }
        self.sim.advance(0);
        self.collect();
    }

    /// Moves virtual time forward by `dt` µs in steps of at most 1 ms, collecting frames.
    pub fn advance(&mut self, dt: Micros) {
        let end = self.sim.now().saturating_add(dt);
        loop {
            let now = self.sim.now();
            if now >= end {
                break;
            }
            self.sim.advance((end - now).min(1000));
            self.collect();
        }
        self.sim.advance(0);
        self.collect();
    }

    /// Moves time in steps of `step` µs until `pred` holds (true) or `timeout` µs passed
    /// (false).
    pub fn wait_until(&mut self, timeout: Micros, step: Micros, mut pred: impl FnMut(&mut Master) -> bool) -> bool {
        let end = self.sim.now().saturating_add(timeout);
        loop {
            if pred(self) {
                return true;
            }
            if self.sim.now() >= end {
                return false;
            }
            self.advance(step.max(1));
        }
    }

    /// The frames received and not yet taken, oldest first (SDO answers are taken by the
    /// transfers).
    pub fn seen(&self) -> impl Iterator<Item = &Seen> {
        self.seen.iter()
    }

    /// Takes the frames received so far.
    pub fn take_seen(&mut self) -> Vec<Seen> {
        self.seen.drain(..).collect()
    }

    /// Takes the frames with COB-ID `id` received so far.
    pub fn take_id(&mut self, id: u32) -> Vec<Seen> {
        let (hit, rest): (Vec<Seen>, Vec<Seen>) = self.seen.drain(..).partition(|s| s.frame.id() == id);
        self.seen = rest.into();
        hit
    }

    /// NMT command `cs` (1 start, 2 stop, 0x80 pre-operational, 0x81 reset node, 0x82 reset
    /// communication) to `node` (0 = all).
    pub fn nmt(&mut self, cs: u8, node: u8) {
        if let Ok(f) = CanFrame::standard(0, &[cs, node]) {
            self.send(f);
        }
    }

    /// NMT start.
    pub fn nmt_start(&mut self, node: u8) {
        self.nmt(1, node);
    }

    /// A SYNC message.
    pub fn sync(&mut self) {
        if let Ok(f) = CanFrame::standard(0x80, &[]) {
            self.send(f);
        }
    }

    /// A PDO (or any frame) with `id` and `data`.
    pub fn pdo(&mut self, id: u32, data: &[u8]) {
        if let Ok(f) = CanFrame::standard(id, data) {
            self.send(f);
        }
    }

    /// The master's heartbeat (state 5, operational) as node `id`.
    pub fn heartbeat(&mut self, id: u8) {
        self.pdo(0x700 + u32::from(id), &[5]);
    }

    fn request(&mut self, node: u8, data: [u8; 8]) -> Result<[u8; 8], SdoError> {
        let tx = 0x580 + u32::from(node);
        let f = CanFrame::standard(0x600 + u32::from(node), &data).map_err(|_| SdoError::Protocol)?;
        self.send(f);
        let end = self.sim.now().saturating_add(self.sdo_timeout);
        loop {
            if let Some(i) = self.seen.iter().position(|s| s.frame.id() == tx) {
                let s = self.seen.remove(i).ok_or(SdoError::Protocol)?;
                let d = s.frame.raw_data();
                if d[0] == 0x80 {
                    return Err(SdoError::Abort(u32::from_le_bytes([d[4], d[5], d[6], d[7]])));
                }
                return Ok(d);
            }
            if self.sim.now() >= end {
                return Err(SdoError::Timeout);
            }
            self.advance(self.step);
        }
    }

    /// SDO download (expedited up to 4 bytes, segmented beyond).
    pub fn write(&mut self, node: u8, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        let [lo, hi] = index.to_le_bytes();
        if data.len() <= 4 && !data.is_empty() {
            let mut req = [0x23 | (((4 - data.len()) as u8) << 2), lo, hi, sub, 0, 0, 0, 0];
            req[4..4 + data.len()].copy_from_slice(data);
            let r = self.request(node, req)?;
            return if r[0] == 0x60 { Ok(()) } else { Err(SdoError::Protocol) };
        }
        let size = u32::try_from(data.len()).map_err(|_| SdoError::Protocol)?.to_le_bytes();
        let r = self.request(node, [0x21, lo, hi, sub, size[0], size[1], size[2], size[3]])?;
        if r[0] != 0x60 {
            return Err(SdoError::Protocol);
        }
        let mut toggle = 0u8;
        let chunks: Vec<&[u8]> = data.chunks(7).collect();
        for (i, chunk) in chunks.iter().enumerate() {
            let last = i + 1 == chunks.len();
            let mut req = [0u8; 8];
            req[0] = toggle | (((7 - chunk.len()) as u8) << 1) | u8::from(last);
            req[1..1 + chunk.len()].copy_from_slice(chunk);
            let r = self.request(node, req)?;
            if r[0] != (0x20 | toggle) {
                return Err(SdoError::Protocol);
            }
            toggle ^= 0x10;
        }
        Ok(())
    }

    /// SDO upload (expedited or segmented).
    pub fn read(&mut self, node: u8, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
        let [lo, hi] = index.to_le_bytes();
        let r = self.request(node, [0x40, lo, hi, sub, 0, 0, 0, 0])?;
        if r[0] & 0xE0 != 0x40 {
            return Err(SdoError::Protocol);
        }
        if r[0] & 0x02 != 0 {
            let n = if r[0] & 0x01 != 0 { 4 - usize::from((r[0] >> 2) & 3) } else { 4 };
            return Ok(r[4..4 + n].to_vec());
        }
        let mut out = Vec::new();
        let mut toggle = 0u8;
        for _ in 0..100_000 {
            let r = self.request(node, [0x60 | toggle, 0, 0, 0, 0, 0, 0, 0])?;
            if r[0] & 0xF0 != toggle {
                return Err(SdoError::Protocol);
            }
            let n = 7 - usize::from((r[0] >> 1) & 7);
            out.extend_from_slice(&r[1..1 + n]);
            if r[0] & 1 != 0 {
                return Ok(out);
            }
            toggle ^= 0x10;
        }
        Err(SdoError::Protocol)
    }

    /// Reads an unsigned value of up to 8 bytes.
    pub fn read_u64(&mut self, node: u8, index: u16, sub: u8) -> Result<u64, SdoError> {
        let d = self.read(node, index, sub)?;
        let mut b = [0u8; 8];
        let n = d.len().min(8);
        b[..n].copy_from_slice(&d[..n]);
        Ok(u64::from_le_bytes(b))
    }

    /// Reads a value and sign-extends it from its length.
    pub fn read_i64(&mut self, node: u8, index: u16, sub: u8) -> Result<i64, SdoError> {
        let d = self.read(node, index, sub)?;
        if d.is_empty() || d.len() > 8 {
            return Err(SdoError::Protocol);
        }
        let mut b = if d[d.len() - 1] & 0x80 != 0 { [0xFF; 8] } else { [0; 8] };
        b[..d.len()].copy_from_slice(&d);
        Ok(i64::from_le_bytes(b))
    }

    /// Reads an 8-bit value.
    pub fn read_u8(&mut self, node: u8, index: u16, sub: u8) -> Result<u8, SdoError> {
        Ok(self.read_u64(node, index, sub)? as u8)
    }

    /// Reads a 16-bit value.
    pub fn read_u16(&mut self, node: u8, index: u16, sub: u8) -> Result<u16, SdoError> {
        Ok(self.read_u64(node, index, sub)? as u16)
    }

    /// Reads a 32-bit value.
    pub fn read_u32(&mut self, node: u8, index: u16, sub: u8) -> Result<u32, SdoError> {
        Ok(self.read_u64(node, index, sub)? as u32)
    }

    /// Writes an 8-bit value.
    pub fn write_u8(&mut self, node: u8, index: u16, sub: u8, v: u8) -> Result<(), SdoError> {
        self.write(node, index, sub, &[v])
    }

    /// Writes a 16-bit value.
    pub fn write_u16(&mut self, node: u8, index: u16, sub: u8, v: u16) -> Result<(), SdoError> {
        self.write(node, index, sub, &v.to_le_bytes())
    }

    /// Writes a 32-bit value.
    pub fn write_u32(&mut self, node: u8, index: u16, sub: u8, v: u32) -> Result<(), SdoError> {
        self.write(node, index, sub, &v.to_le_bytes())
    }

    /// Writes a signed 32-bit value.
    pub fn write_i32(&mut self, node: u8, index: u16, sub: u8, v: i32) -> Result<(), SdoError> {
        self.write(node, index, sub, &v.to_le_bytes())
    }

    /// The statusword (6041h).
    pub fn statusword(&mut self, node: u8) -> Result<u16, SdoError> {
        self.read_u16(node, 0x6041, 0)
    }

    /// The CiA 402 state from the statusword.
    pub fn state(&mut self, node: u8) -> Result<Option<State>, SdoError> {
        Ok(State::from_statusword(self.statusword(node)?))
    }

    /// Writes the controlword.
    pub fn controlword(&mut self, node: u8, cw: u16) -> Result<(), SdoError> {
        self.write_u16(node, 0x6040, 0, cw)
    }

    /// Shutdown (6), switch on (7), enable operation (15): to Operation enabled from Switch on
    /// disabled, checking each state on the way.
    pub fn switch_on(&mut self, node: u8) -> Result<(), SdoError> {
        for (cw, want) in [(0x06, State::ReadyToSwitchOn), (0x07, State::SwitchedOn), (0x0F, State::OperationEnabled)] {
            self.controlword(node, cw)?;
            self.advance(2000);
            if self.state(node)? != Some(want) {
                return Err(SdoError::Protocol);
            }
        }
        Ok(())
    }

    /// Sets 6060h and waits until 6061h shows it.
    pub fn set_mode(&mut self, node: u8, mode: i8) -> Result<(), SdoError> {
        self.write(node, 0x6060, 0, &[mode as u8])?;
        self.advance(1000);
        let shown = self.read_i64(node, 0x6061, 0)?;
        if shown == i64::from(mode) { Ok(()) } else { Err(SdoError::Protocol) }
    }

    /// Waits (virtual time, polling the statusword over SDO every `poll` µs) until
    /// `statusword & mask == value`; returns the statusword, or `None` on timeout.
    pub fn wait_statusword(&mut self, node: u8, mask: u16, value: u16, timeout: Micros, poll: Micros) -> Option<u16> {
        let end = self.sim.now().saturating_add(timeout);
        loop {
            let sw = self.statusword(node).ok()?;
            if sw & mask == value {
                return Some(sw);
            }
            if self.sim.now() >= end {
                return None;
            }
            self.advance(poll.max(1));
        }
    }
}
