//! The classic CAN frame every transport carries.

use std::fmt;
use std::str::FromStr;

/// Why a [`CanFrame`] could not be built. Every constructor checks its input, so a frame that
/// exists is always one a CAN controller could put on the wire.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A standard (11-bit) identifier above 0x7FF.
    #[error("standard CAN id {0:#x} is above 0x7FF")]
    StandardIdOutOfRange(u32),
    /// An extended (29-bit) identifier above 0x1FFFFFFF.
    #[error("extended CAN id {0:#x} is above 0x1FFFFFFF")]
    ExtendedIdOutOfRange(u32),
    /// More than eight data bytes, or a data length code above 8.
    #[error("a classic CAN frame carries at most 8 bytes, got {0}")]
    TooLong(usize),
    /// Text that is not a frame in `cansend` notation (`601#2B406000`, `701#R`, `12345678#00`).
    #[error("not a frame in cansend notation ({0}); expected e.g. 601#2B40600006000000 or 701#R")]
    Notation(&'static str),
    /// A frame with an extended identifier where only standard ones exist (CANopen's frames,
    /// `od_runtime::Frame`).
    #[error("extended CAN id {0:#x} where only standard (11-bit) ids are used")]
    Extended(u32),
}

/// One classic CAN 2.0 frame: an 11-bit (standard) or 29-bit (extended) identifier, the remote
/// transmission request flag, a data length code of 0 to 8 and up to eight data bytes.
///
/// The fields are private so that a frame always holds a valid combination: the identifier fits
/// its format, `dlc <= 8`, and the bytes past `dlc` (all eight for a remote frame) are zero, so
/// `==` compares what would be on the wire. The layout mirrors Linux's `struct can_frame` and
/// od-runtime's frame type, so converting between them is a field copy through
/// [`CanFrame::from_parts`] and the accessors.
///
/// ```
/// use od_bus::CanFrame;
/// let sdo = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]).unwrap();
/// assert_eq!(sdo.id(), 0x601);
/// assert_eq!(sdo.data(), &[0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]);
/// assert_eq!(sdo.to_string(), "601#4041600000000000");
/// assert_eq!("601#4041600000000000".parse::<CanFrame>().unwrap(), sdo);
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: u32,
    extended: bool,
    rtr: bool,
    dlc: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// Highest standard (11-bit) identifier.
    pub const MAX_STANDARD_ID: u32 = 0x7FF;
    /// Highest extended (29-bit) identifier.
    pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;

    /// A data frame with a standard 11-bit identifier.
    pub fn standard(id: u32, data: &[u8]) -> Result<Self, FrameError> {
        Self::data_frame(id, false, data)
    }

    /// A data frame with an extended 29-bit identifier.
    pub fn extended(id: u32, data: &[u8]) -> Result<Self, FrameError> {
        Self::data_frame(id, true, data)
    }

    /// A remote (RTR) frame: no data, but a data length code naming the length requested.
    pub fn remote(id: u32, extended: bool, dlc: u8) -> Result<Self, FrameError> {
        Self::from_parts(id, extended, true, dlc, [0; 8])
    }

    /// Builds a frame from its raw fields, as a driver or another frame type holds them.
    /// Bytes past `dlc` are cleared (all of them for a remote frame).
    pub fn from_parts(id: u32, extended: bool, rtr: bool, dlc: u8, mut data: [u8; 8]) -> Result<Self, FrameError> {
        check_id(id, extended)?;
        if dlc > 8 {
            return Err(FrameError::TooLong(usize::from(dlc)));
        }
        let keep = if rtr { 0 } else { usize::from(dlc) };
        data[keep..].fill(0);
        Ok(Self { id, extended, rtr, dlc, data })
    }

    fn data_frame(id: u32, extended: bool, bytes: &[u8]) -> Result<Self, FrameError> {
        check_id(id, extended)?;
        if bytes.len() > 8 {
            return Err(FrameError::TooLong(bytes.len()));
        }
        let mut data = [0; 8];
        data[..bytes.len()].copy_from_slice(bytes);
        // bytes.len() <= 8 was checked above, so the cast is exact.
        Ok(Self { id, extended, rtr: false, dlc: bytes.len() as u8, data })
    }

    /// The identifier, without format flags (at most 0x7FF or 0x1FFFFFFF).
    pub fn id(&self) -> u32 {
        self.id
    }

    /// Whether the identifier is a 29-bit extended one.
    pub fn is_extended(&self) -> bool {
        self.extended
    }

    /// Whether this is a remote transmission request.
    pub fn is_remote(&self) -> bool {
        self.rtr
    }

    /// The data length code, 0 to 8. For a remote frame it is the length requested.
    pub fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The payload: `dlc` bytes for a data frame, nothing for a remote frame.
    pub fn data(&self) -> &[u8] {
        if self.rtr { &[] } else { &self.data[..usize::from(self.dlc)] }
    }

    /// All eight data bytes, zero past the payload (the shape of `struct can_frame`).
    pub fn raw_data(&self) -> [u8; 8] {
        self.data
    }
}

fn check_id(id: u32, extended: bool) -> Result<(), FrameError> {
    match extended {
        false if id > CanFrame::MAX_STANDARD_ID => Err(FrameError::StandardIdOutOfRange(id)),
        true if id > CanFrame::MAX_EXTENDED_ID => Err(FrameError::ExtendedIdOutOfRange(id)),
        _ => Ok(()),
    }
}

/// `cansend` notation: `601#2B40600006000000`, `12345678#00` (eight digits mean extended),
/// `701#R` (remote, dlc 0), `701#R1` (remote, dlc 1).
impl fmt::Display for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.extended {
            write!(f, "{:08X}#", self.id)?;
        } else {
            write!(f, "{:03X}#", self.id)?;
        }
        if self.rtr {
            f.write_str("R")?;
            if self.dlc > 0 {
                write!(f, "{}", self.dlc)?;
            }
        } else {
            for byte in self.data() {
                write!(f, "{byte:02X}")?;
            }
        }
        Ok(())
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "CanFrame({self})")
    }
}

/// Parses `cansend` notation (see the `Display` impl). An identifier of 1 to 3 hex digits is
/// standard, 4 to 8 digits extended; data is an even number of hex digits, optionally with `.`
/// between bytes as `cansend` allows.
impl FromStr for CanFrame {
    type Err = FrameError;

    fn from_str(text: &str) -> Result<Self, FrameError> {
        let (id_text, rest) = text.split_once('#').ok_or(FrameError::Notation("no '#' between id and data"))?;
        if id_text.is_empty() || id_text.len() > 8 || !id_text.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(FrameError::Notation("the id must be 1 to 8 hex digits"));
        }
        let id = u32::from_str_radix(id_text, 16).map_err(|_| FrameError::Notation("bad id"))?;
        let extended = id_text.len() > 3;
        if let Some(dlc_text) = rest.strip_prefix(['R', 'r']) {
            let dlc = match dlc_text {
                "" => 0,
                digit if digit.len() == 1 => {
                    digit.parse::<u8>().map_err(|_| FrameError::Notation("the remote length must be 0 to 8"))?
                }
                _ => return Err(FrameError::Notation("the remote length must be one digit")),
            };
            return Self::remote(id, extended, dlc);
        }
        let hex: Vec<u8> = rest.bytes().filter(|&b| b != b'.').collect();
        if !hex.len().is_multiple_of(2) {
            return Err(FrameError::Notation("odd number of data hex digits"));
        }
        if hex.len() > 16 {
            return Err(FrameError::TooLong(hex.len() / 2));
        }
        let mut data = [0u8; 8];
        for (slot, pair) in data.iter_mut().zip(hex.chunks(2)) {
            *slot = hex_byte(pair[0], pair[1]).ok_or(FrameError::Notation("data must be hex digits"))?;
        }
        Self::data_frame(id, extended, &data[..hex.len() / 2])
    }
}

/// A frame of the device and master protocol core: always a valid standard frame.
#[cfg(feature = "od-runtime")]
impl From<od_runtime::frame::Frame> for CanFrame {
    fn from(frame: od_runtime::frame::Frame) -> Self {
        let data = *frame.raw();
        // An od-runtime frame has an 11-bit id and at most 8 bytes: every field fits.
        Self { id: u32::from(frame.id()), extended: false, rtr: frame.is_rtr(), dlc: frame.len() as u8, data }
    }
}

/// The protocol core's frame; extended identifiers have none ([`FrameError::Extended`]).
#[cfg(feature = "od-runtime")]
impl TryFrom<CanFrame> for od_runtime::frame::Frame {
    type Error = FrameError;

    fn try_from(frame: CanFrame) -> Result<Self, FrameError> {
        if frame.extended {
            return Err(FrameError::Extended(frame.id));
        }
        // A standard id is at most 0x7FF, so the cast is exact.
        Ok(Self::from_parts(frame.id as u16, frame.rtr, frame.dlc, frame.data))
    }
}

/// Value of one ASCII hex digit.
pub(crate) fn hex_digit(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'a'..=b'f' => Some(byte - b'a' + 10),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        _ => None,
    }
}

/// Value of two ASCII hex digits, high nibble first.
pub(crate) fn hex_byte(high: u8, low: u8) -> Option<u8> {
    Some(hex_digit(high)? << 4 | hex_digit(low)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constructors_check_ranges() {
        assert_eq!(CanFrame::standard(0x800, &[]), Err(FrameError::StandardIdOutOfRange(0x800)));
        assert_eq!(CanFrame::extended(0x2000_0000, &[]), Err(FrameError::ExtendedIdOutOfRange(0x2000_0000)));
        assert_eq!(CanFrame::standard(0x7FF, &[0; 9]), Err(FrameError::TooLong(9)));
        assert_eq!(CanFrame::remote(0x701, false, 9), Err(FrameError::TooLong(9)));
        assert!(CanFrame::extended(0x1FFF_FFFF, &[1; 8]).is_ok());
    }

    #[test]
    fn from_parts_clears_bytes_past_the_payload() {
        let frame = CanFrame::from_parts(0x181, false, false, 2, [1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        assert_eq!(frame.data(), &[1, 2]);
        assert_eq!(frame.raw_data(), [1, 2, 0, 0, 0, 0, 0, 0]);
        assert_eq!(frame, CanFrame::standard(0x181, &[1, 2]).unwrap());
        let rtr = CanFrame::from_parts(0x701, false, true, 1, [9; 8]).unwrap();
        assert_eq!(rtr.data(), &[] as &[u8]);
        assert_eq!(rtr.dlc(), 1);
        assert_eq!(rtr.raw_data(), [0; 8]);
    }

    #[test]
    fn cansend_notation_round_trips() {
        for text in ["601#2B40600006000000", "080#", "1ABCDEF0#0102", "701#R", "701#R1", "00000123#R8"] {
            let frame: CanFrame = text.parse().unwrap();
            assert_eq!(frame.to_string(), text);
        }
        let ext: CanFrame = "1234#00".parse().unwrap();
        assert!(ext.is_extended());
        assert_eq!(ext.to_string(), "00001234#00");
        let dotted: CanFrame = "123#01.02.0a".parse().unwrap();
        assert_eq!(dotted.data(), &[1, 2, 10]);
    }

    #[cfg(feature = "od-runtime")]
    #[test]
    fn od_runtime_frames_convert_both_ways() {
        use od_runtime::frame::Frame;
        for id in [0u16, 0x080, 0x601, 0x7FF] {
            for len in 0..=8usize {
                let data: Vec<u8> = (1..=len as u8).collect();
                let theirs = Frame::new(id, &data).unwrap();
                let ours = CanFrame::from(theirs);
                assert_eq!(ours, CanFrame::standard(u32::from(id), &data).unwrap());
                assert_eq!(Frame::try_from(ours), Ok(theirs));
            }
            let rtr = Frame::remote(id, 1).unwrap();
            assert_eq!(CanFrame::from(rtr), CanFrame::remote(u32::from(id), false, 1).unwrap());
            assert_eq!(Frame::try_from(CanFrame::from(rtr)), Ok(rtr));
        }
        let ext = CanFrame::extended(0x601, &[1]).unwrap();
        assert_eq!(Frame::try_from(ext), Err(FrameError::Extended(0x601)));
    }

    #[test]
    fn cansend_notation_rejects_malformed_text() {
        for bad in
            ["", "601", "#00", "123456789#", "60G#00", "601#0", "601#0G", "601#R9", "601#R10", "601#001122334455667788"]
        {
            assert!(bad.parse::<CanFrame>().is_err(), "{bad:?} parsed");
        }
        assert_eq!("800#".parse::<CanFrame>(), Err(FrameError::StandardIdOutOfRange(0x800)));
    }
}
