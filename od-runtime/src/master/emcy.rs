//! The EMCY consumer (CiA 301 §7.2.7): decodes emergency messages into code, error register
//! and the five manufacturer-specific bytes.

use crate::frame::Frame;

/// One emergency message.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Emergency {
    /// The node that sent it.
    pub node: u8,
    /// The emergency error code (0000h: error reset or no error).
    pub code: u16,
    /// The node's error register (1001h) at the time.
    pub register: u8,
    /// The manufacturer-specific error field.
    pub vendor: [u8; 5],
}

impl Emergency {
    /// Decodes a frame on the default EMCY COB-IDs (080h + node id, 081h..=0FFh). `None` for
    /// any other frame, a remote frame, or a frame that is not 8 bytes long.
    pub fn from_frame(frame: &Frame) -> Option<Self> {
        let id = frame.id();
        if !(0x081..=0x0FF).contains(&id) {
            return None;
        }
        Self::decode((id - 0x080) as u8, frame)
    }

    /// Decodes the emergency message `frame` of `node`, whatever its COB-ID (a node's 1014h
    /// may move it). `None` for a remote frame or one that is not 8 bytes long.
    pub fn decode(node: u8, frame: &Frame) -> Option<Self> {
        if frame.is_rtr() || frame.len() != 8 {
            return None;
        }
        let d = frame.raw();
        Some(Self {
            node,
            code: u16::from_le_bytes([d[0], d[1]]),
            register: d[2],
            vendor: [d[3], d[4], d[5], d[6], d[7]],
        })
    }

    /// Whether this message says the node's errors are gone (code 0000h, "error reset or no
    /// error").
    pub const fn is_reset(&self) -> bool {
        self.code == 0
    }

    /// The CiA 301 meaning of the code: the code itself when the standard names it, its
    /// class otherwise.
    pub const fn description(&self) -> &'static str {
        describe(self.code)
    }
}

/// The CiA 301 meaning of an emergency error code: the code itself when the standard names it
/// (8130h "life guard error or heartbeat error"), its class otherwise (23xxh "current, device
/// output side").
pub const fn describe(code: u16) -> &'static str {
    match code {
        0x0000 => "error reset or no error",
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard error or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8150 => "CAN-ID collision",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8230 => "DAM MPDO not processed, destination object not available",
        0x8240 => "unexpected SYNC data length",
        0x8250 => "RPDO timeout",
        _ => match code >> 8 {
            0x10 => "generic error",
            0x20 => "current",
            0x21 => "current, device input side",
            0x22 => "current inside the device",
            0x23 => "current, device output side",
            0x30 => "voltage",
            0x31 => "mains voltage",
            0x32 => "voltage inside the device",
            0x33 => "output voltage",
            0x40 => "temperature",
            0x41 => "ambient temperature",
            0x42 => "device temperature",
            0x50 => "device hardware",
            0x60 => "device software",
            0x61 => "internal software",
            0x62 => "user software",
            0x63 => "data set",
            0x70 => "additional modules",
            0x80 => "monitoring",
            0x81 => "communication",
            0x82 => "protocol error",
            0x90 => "external error",
            0xF0 => "additional functions",
            0xFF => "device specific",
            _ => match code >> 12 {
                0x2 => "current",
                0x3 => "voltage",
                0x4 => "temperature",
                0x8 => "monitoring",
                _ => "unknown error code",
            },
        },
    }
}

impl core::fmt::Display for Emergency {
    /// `node 3: EMCY 8130h (life guard error or heartbeat error), error register 11h, vendor
    /// 00 00 00 00 00`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "node {}: EMCY {:04X}h ({}), error register {:02X}h, vendor",
            self.node,
            self.code,
            self.description(),
            self.register
        )?;
        for b in self.vendor {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}
