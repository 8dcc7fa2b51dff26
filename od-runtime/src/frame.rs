//! CAN frames and the virtual clock.

/// Time in microseconds since an arbitrary origin, passed in by the caller.
///
/// The runtime never reads a clock: every call that depends on time takes `now`, so tests are
/// deterministic and an embedded target can feed a hardware timer. The value should not go
/// backwards; if it does, pending timeouts simply fire later (nothing panics).
pub type Micros = u64;

/// A classic CAN frame with an 11-bit identifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Frame {
    id: u16,
    rtr: bool,
    len: u8,
    data: [u8; 8],
}

impl Frame {
    /// An empty data frame with identifier 0 (a placeholder in fixed-size queues).
    #[cfg(feature = "embedded-can")]
    pub(crate) const EMPTY: Self = Self { id: 0, rtr: false, len: 0, data: [0; 8] };

    /// A data frame. `None` if `id` does not fit in 11 bits or `data` is longer than 8 bytes.
    pub fn new(id: u16, data: &[u8]) -> Option<Self> {
        if id > 0x7FF || data.len() > 8 {
            return None;
        }
        let mut d = [0u8; 8];
        d[..data.len()].copy_from_slice(data);
        Some(Self { id, rtr: false, len: data.len() as u8, data: d })
    }

    /// A remote (RTR) frame requesting `len` bytes. `None` if `id` does not fit in 11 bits or
    /// `len > 8`.
    pub fn remote(id: u16, len: u8) -> Option<Self> {
        if id > 0x7FF || len > 8 {
            return None;
        }
        Some(Self { id, rtr: true, len, data: [0; 8] })
    }

    /// A frame from raw parts as a driver delivers them: `id` is masked to 11 bits, `len` is
    /// clamped to 8 and the bytes past `len` are zeroed, so any input gives a valid frame.
    pub fn from_parts(id: u16, rtr: bool, len: u8, data: [u8; 8]) -> Self {
        let len = len.min(8);
        let mut d = [0u8; 8];
        if !rtr {
            d[..len as usize].copy_from_slice(&data[..len as usize]);
        }
        Self { id: id & 0x7FF, rtr, len, data: d }
    }

    /// An 8-byte data frame (the runtime's own responses). `id` is masked to 11 bits.
    #[inline]
    pub(crate) const fn full(id: u16, data: [u8; 8]) -> Self {
        Self { id: id & 0x7FF, rtr: false, len: 8, data }
    }

    /// A data frame of `len <= 8` bytes taken from `data` (runtime internal).
    #[inline]
    pub(crate) fn short(id: u16, data: [u8; 8], len: usize) -> Self {
        let len = len.min(8);
        // Zero past `len` with a mask rather than a copy of variable length.
        let keep = if len >= 8 { u64::MAX } else { (1u64 << (8 * len)) - 1 };
        let d = (u64::from_le_bytes(data) & keep).to_le_bytes();
        Self { id: id & 0x7FF, rtr: false, len: len as u8, data: d }
    }

    /// A PDO of `len` bytes (at most 8 by construction; clamped all the same) whose `data` is
    /// already zero past `len`, as the runtime packs a mapping, and an `id` already cut
    /// to 11 bits when the PDO was loaded (runtime internal: no mask on the hot path).
    #[inline(always)]
    pub(crate) fn packed(id: u16, data: [u8; 8], len: u8) -> Self {
        Self { id, rtr: false, len: if len > 8 { 8 } else { len }, data }
    }

    /// The 11-bit identifier (COB-ID).
    #[inline]
    pub const fn id(&self) -> u16 {
        self.id
    }

    /// Whether this is a remote transmission request.
    #[inline]
    pub const fn is_rtr(&self) -> bool {
        self.rtr
    }

    /// The data length code (0..=8).
    #[inline]
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// Whether the frame carries no data bytes.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The data bytes (empty for a remote frame).
    #[inline]
    pub fn data(&self) -> &[u8] {
        if self.rtr { &[] } else { &self.data[..self.len as usize] }
    }

    /// All eight data bytes, zero past `len`.
    #[inline]
    pub const fn raw(&self) -> &[u8; 8] {
        &self.data
    }
}

impl core::fmt::Display for Frame {
    /// `581 60 40 60 00 00 00 00 00`, or `701 R1` for a remote frame: the notation of the
    /// device manuals and of the tests.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{:03X}", self.id)?;
        if self.rtr {
            return write!(f, " R{}", self.len);
        }
        for b in self.data() {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}

/// A CANopen node id, 1..=127.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(u8);

impl NodeId {
    /// `None` unless `id` is in 1..=127.
    pub const fn new(id: u8) -> Option<Self> {
        if id >= 1 && id <= 127 { Some(Self(id)) } else { None }
    }

    /// The raw id.
    pub const fn get(self) -> u8 {
        self.0
    }
}
