//! Any HAL's CAN driver as the device's bus (cargo feature `embedded-can`).
//!
//! [`Frame`] implements the [`embedded_can::Frame`] trait, and [`from_can`] / [`to_can`]
//! convert between it and a driver's own frame type. [`CanLink`] is the receive/transmit loop
//! over an [`embedded_can::nb::Can`] driver: call [`CanLink::service`] from the main loop (or a
//! CAN interrupt and a timer tick) with the time, and it feeds every received frame to the
//! device, polls it, and transmits what it produced, queueing frames while the driver's
//! mailboxes are full.
//!
//! CANopen uses 11-bit identifiers: frames with an extended (29-bit) identifier are not for
//! the device and are skipped, never truncated into a wrong 11-bit one.

use embedded_can::{ErrorKind, Id, StandardId};

use crate::frame::{Frame, Micros};
use crate::od::ObjectDictionary;
use crate::{App, Device, Storage};

impl embedded_can::Frame for Frame {
    /// A data frame; `None` for an extended identifier or more than 8 bytes.
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        match id.into() {
            Id::Standard(id) => Frame::new(id.as_raw(), data),
            Id::Extended(_) => None,
        }
    }

    /// A remote frame; `None` for an extended identifier or a length above 8.
    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        match (id.into(), u8::try_from(dlc)) {
            (Id::Standard(id), Ok(dlc)) => Frame::remote(id.as_raw(), dlc),
            _ => None,
        }
    }

    fn is_extended(&self) -> bool {
        false
    }

    fn is_remote_frame(&self) -> bool {
        self.is_rtr()
    }

    fn id(&self) -> Id {
        // Every constructor keeps the identifier within 11 bits.
        Id::Standard(StandardId::new(Frame::id(self)).unwrap_or(StandardId::ZERO))
    }

    fn dlc(&self) -> usize {
        self.len()
    }

    fn data(&self) -> &[u8] {
        Frame::data(self)
    }
}

/// A driver's frame as the device's: `None` for an extended identifier (not CANopen's).
/// A data length above 8 (CAN FD) is cut to 8 bytes.
pub fn from_can<F: embedded_can::Frame>(f: &F) -> Option<Frame> {
    let Id::Standard(id) = f.id() else {
        return None;
    };
    if f.is_remote_frame() {
        return Some(Frame::from_parts(id.as_raw(), true, f.dlc().min(8) as u8, [0; 8]));
    }
    let mut data = [0u8; 8];
    let src = f.data();
    let n = src.len().min(8);
    data[..n].copy_from_slice(&src[..n]);
    Some(Frame::from_parts(id.as_raw(), false, n as u8, data))
}

/// The device's frame as a driver's: `None` if the driver's type refuses it.
pub fn to_can<F: embedded_can::Frame>(f: &Frame) -> Option<F> {
    let id = StandardId::new(f.id())?;
    if f.is_rtr() { F::new_remote(id, f.len()) } else { F::new(id, f.data()) }
}

/// Most frames one [`CanLink::service`] call takes from the driver, so that a flooded bus
/// cannot keep the loop from polling the device and transmitting.
pub const MAX_RECEIVE_PER_SERVICE: usize = 32;

/// The receive/transmit loop between a [`Device`] and an [`embedded_can::nb::Can`] driver,
/// with a transmit queue of `Q` frames for when the driver's mailboxes are full.
///
/// Frames leave in the order the device produced them (SDO segments and PDOs keep their
/// order). A frame that finds the queue full is dropped and counted ([`CanLink::dropped`]),
/// as a CAN controller counts a transmit overrun; nothing blocks.
#[derive(Clone, Debug)]
pub struct CanLink<const Q: usize = 16> {
    queue: [Frame; Q],
    head: usize,
    len: usize,
    dropped: u32,
    errors: u32,
    last_error: Option<ErrorKind>,
}

impl<const Q: usize> Default for CanLink<Q> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const Q: usize> CanLink<Q> {
    /// An empty link.
    pub const fn new() -> Self {
        Self { queue: [Frame::EMPTY; Q], head: 0, len: 0, dropped: 0, errors: 0, last_error: None }
    }

    /// One turn of the loop at time `now`: receives up to [`MAX_RECEIVE_PER_SERVICE`] frames
    /// into the device, polls it, and transmits queued frames until the driver would block.
    /// Driver errors are counted ([`CanLink::errors`]) and end that turn's receiving or
    /// transmitting; the next call tries again.
    pub fn service<C, OD, A, S, const BUF: usize, const PDOS: usize, const MAP: usize>(
        &mut self,
        can: &mut C,
        dev: &mut Device<OD, A, S, BUF, PDOS, MAP>,
        now: Micros,
    ) where
        C: embedded_can::nb::Can,
        OD: ObjectDictionary,
        A: App<OD>,
        S: Storage,
    {
        self.receive(can, |f| dev.on_frame(f, now));
        dev.poll(now, |f| self.push(f));
        self.flush(can);
    }

    /// Takes up to [`MAX_RECEIVE_PER_SERVICE`] frames from the driver and hands the
    /// CANopen ones (11-bit identifiers) to `deliver`.
    pub fn receive<C: embedded_can::nb::Can>(&mut self, can: &mut C, mut deliver: impl FnMut(&Frame)) {
        for _ in 0..MAX_RECEIVE_PER_SERVICE {
            match can.receive() {
                Ok(f) => {
                    if let Some(f) = from_can(&f) {
                        deliver(&f);
                    }
                }
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(e)) => {
                    self.error(embedded_can::Error::kind(&e));
                    break;
                }
            }
        }
    }

    /// Queues a frame for transmission (dropped and counted if the queue is full). Out of
    /// line on a microcontroller: every service that sends calls it.
    #[cfg_attr(target_os = "none", inline(never))]
    pub fn push(&mut self, f: Frame) {
        if self.len == Q {
            self.dropped = self.dropped.saturating_add(1);
            return;
        }
        // head < Q and len < Q here: one subtraction instead of a division.
        let at = self.head + self.len;
        let at = if at >= Q { at - Q } else { at };
        if let Some(slot) = self.queue.get_mut(at) {
            *slot = f;
            self.len += 1;
        }
    }

    /// Transmits queued frames until the queue is empty or the driver would block. A frame the
    /// driver hands back (it made room for ours by taking a lower-priority one out of a
    /// mailbox) goes back into the queue.
    pub fn flush<C: embedded_can::nb::Can>(&mut self, can: &mut C) {
        // Each frame is tried once per call: a driver handing back frames cannot loop it.
        for _ in 0..Q {
            let Some(&front) = self.queue.get(self.head).filter(|_| self.len > 0) else {
                return;
            };
            let Some(out) = to_can::<C::Frame>(&front) else {
                self.pop();
                self.dropped = self.dropped.saturating_add(1);
                continue;
            };
            match can.transmit(&out) {
                Ok(replaced) => {
                    self.pop();
                    if let Some(back) = replaced.as_ref().and_then(from_can) {
                        self.push(back);
                    }
                }
                Err(nb::Error::WouldBlock) => return,
                Err(nb::Error::Other(e)) => {
                    self.error(embedded_can::Error::kind(&e));
                    return;
                }
            }
        }
    }

    fn pop(&mut self) {
        if self.len > 0 {
            self.head = if self.head + 1 >= Q { 0 } else { self.head + 1 };
            self.len -= 1;
        }
    }

    fn error(&mut self, kind: ErrorKind) {
        self.errors = self.errors.saturating_add(1);
        self.last_error = Some(kind);
    }

    /// Frames waiting for a free mailbox.
    pub const fn pending(&self) -> usize {
        self.len
    }

    /// Frames lost: the queue was full, or the driver's frame type refused one.
    pub const fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Driver errors seen (receive or transmit).
    pub const fn errors(&self) -> u32 {
        self.errors
    }

    /// The kind of the last driver error.
    pub const fn last_error(&self) -> Option<ErrorKind> {
        self.last_error
    }
}
