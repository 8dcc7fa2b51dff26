//! A minimal driver for the bxCAN controller of STM32F1/F4 parts (CAN1), implementing
//! [`embedded_can::nb::Can`]: what a HAL's driver gives a firmware, written out here so the
//! example needs no HAL. Register layout from the STM32F4 reference manual (RM0090, bxCAN).
//!
//! It configures one filter that accepts every frame into FIFO 0 and uses the three transmit
//! mailboxes. Clocks and pins are the board's business and set up before [`BxCan::new`].

use embedded_can::ErrorKind;
use od_runtime::Frame;

/// Base address of CAN1 on the STM32F4.
pub const CAN1: usize = 0x4000_6400;

/// The bit timing register for 500 kbit/s from a 42 MHz APB1 clock: prescaler 6, 14 time
/// quanta (BS1 = 11, BS2 = 2), sample point at 86 %, SJW 1.
pub const BTR_500K_42MHZ: u32 = (1 << 20) | (10 << 16) | 5;

const MCR: usize = 0x000;
const MSR: usize = 0x004;
const TSR: usize = 0x008;
const RF0R: usize = 0x00C;
const BTR: usize = 0x01C;
const TX0: usize = 0x180;
const RX0: usize = 0x1B0;
const FMR: usize = 0x200;
const FS1R: usize = 0x20C;
const FFA1R: usize = 0x214;
const FA1R: usize = 0x21C;
const F0R1: usize = 0x240;
const F0R2: usize = 0x244;

const MCR_INRQ: u32 = 1 << 0;
const MCR_SLEEP: u32 = 1 << 1;
const MSR_INAK: u32 = 1 << 0;
const TSR_TME0: u32 = 1 << 26;
const RF0R_FMP: u32 = 0b11;
const RF0R_FOVR: u32 = 1 << 4;
const RF0R_RFOM: u32 = 1 << 5;
const TIR_TXRQ: u32 = 1 << 0;
const IR_RTR: u32 = 1 << 1;
const IR_IDE: u32 = 1 << 2;

/// Register polls before a mode change counts as failed (the controller's acknowledgement
/// takes 11 recessive bits; this is far more at any bus speed).
const MODE_POLLS: u32 = 1_000_000;

/// A driver error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BxError(pub ErrorKind);

impl embedded_can::Error for BxError {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

/// The bxCAN controller at one base address.
#[derive(Debug)]
pub struct BxCan {
    base: usize,
}

impl BxCan {
    /// Initialises the controller at `base` with bit timing `btr`, accepting every frame,
    /// and joins the bus. `Err` if the controller does not acknowledge a mode change.
    ///
    /// # Safety
    ///
    /// `base` is the register block of a bxCAN controller whose clock and pins are enabled,
    /// and nothing else uses it while the driver lives.
    pub unsafe fn new(base: usize, btr: u32) -> Result<Self, BxError> {
        let can = Self { base };
        can.modify(MCR, |r| (r & !MCR_SLEEP) | MCR_INRQ);
        can.wait(MSR_INAK, true)?;
        can.write(BTR, btr);
        // Filter bank 0: 32-bit identifier/mask, mask 0 (accept all), FIFO 0, active.
        can.modify(FMR, |r| r | 1);
        can.modify(FA1R, |r| r & !1);
        can.modify(FS1R, |r| r | 1);
        can.modify(FFA1R, |r| r & !1);
        can.write(F0R1, 0);
        can.write(F0R2, 0);
        can.modify(FA1R, |r| r | 1);
        can.modify(FMR, |r| r & !1);
        can.modify(MCR, |r| r & !MCR_INRQ);
        can.wait(MSR_INAK, false)?;
        Ok(can)
    }

    fn reg(&self, off: usize) -> *mut u32 {
        (self.base + off) as *mut u32
    }

    fn read(&self, off: usize) -> u32 {
        // SAFETY: a register of the block `new`'s caller gave us alone.
        unsafe { self.reg(off).read_volatile() }
    }

    fn write(&self, off: usize, v: u32) {
        // SAFETY: as in `read`.
        unsafe { self.reg(off).write_volatile(v) }
    }

    fn modify(&self, off: usize, f: impl FnOnce(u32) -> u32) {
        self.write(off, f(self.read(off)));
    }

    fn wait(&self, bit: u32, set: bool) -> Result<(), BxError> {
        for _ in 0..MODE_POLLS {
            if (self.read(MSR) & bit != 0) == set {
                return Ok(());
            }
        }
        Err(BxError(ErrorKind::Other))
    }
}

impl embedded_can::nb::Can for BxCan {
    type Frame = Frame;
    type Error = BxError;

    fn transmit(&mut self, frame: &Frame) -> nb::Result<Option<Frame>, BxError> {
        let tsr = self.read(TSR);
        let Some(mb) = (0..3).find(|k| tsr & (TSR_TME0 << k) != 0) else {
            return Err(nb::Error::WouldBlock);
        };
        let at = TX0 + 0x10 * mb;
        let raw = frame.raw();
        self.write(at + 4, frame.len() as u32);
        self.write(at + 8, u32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]));
        self.write(at + 12, u32::from_le_bytes([raw[4], raw[5], raw[6], raw[7]]));
        let rtr = if frame.is_rtr() { IR_RTR } else { 0 };
        self.write(at, (u32::from(frame.id()) << 21) | rtr | TIR_TXRQ);
        Ok(None)
    }

    fn receive(&mut self) -> nb::Result<Frame, BxError> {
        let rf = self.read(RF0R);
        if rf & RF0R_FOVR != 0 {
            // Clear the overrun flag (write 1) and report it once; the FIFO still holds frames.
            self.write(RF0R, RF0R_FOVR);
            return Err(nb::Error::Other(BxError(ErrorKind::Overrun)));
        }
        if rf & RF0R_FMP == 0 {
            return Err(nb::Error::WouldBlock);
        }
        let (ir, dtr, lo, hi) = (self.read(RX0), self.read(RX0 + 4), self.read(RX0 + 8), self.read(RX0 + 12));
        self.write(RF0R, RF0R_RFOM);
        if ir & IR_IDE != 0 {
            // An extended identifier: not CANopen. Released above; report an empty turn.
            return Err(nb::Error::WouldBlock);
        }
        let mut data = [0u8; 8];
        data[..4].copy_from_slice(&lo.to_le_bytes());
        data[4..].copy_from_slice(&hi.to_le_bytes());
        Ok(Frame::from_parts((ir >> 21) as u16, ir & IR_RTR != 0, (dtr & 0xF) as u8, data))
    }
}
