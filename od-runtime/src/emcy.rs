//! Emergency (EMCY) helpers: the error register bits of an error code and the frame queue.

/// Error register (1001h) bit: generic error; set whenever any error is active.
pub const REG_GENERIC: u8 = 0x01;
/// Error register bit: current.
pub const REG_CURRENT: u8 = 0x02;
/// Error register bit: voltage.
pub const REG_VOLTAGE: u8 = 0x04;
/// Error register bit: temperature.
pub const REG_TEMPERATURE: u8 = 0x08;
/// Error register bit: communication error (overrun, error state, PDO length, life guarding).
pub const REG_COMMUNICATION: u8 = 0x10;
/// Error register bit: device profile specific.
pub const REG_PROFILE: u8 = 0x20;
/// Error register bit: manufacturer specific.
pub const REG_MANUFACTURER: u8 = 0x80;

/// The error register bits CiA 301 associates with an emergency error code's class
/// (2xxxh current, 3xxxh voltage, 4xxxh temperature, 81xxh/82xxh communication, FFxxh
/// manufacturer), always including [`REG_GENERIC`] unless the code is 0000h (error reset).
pub const fn register_bits(code: u16) -> u8 {
    if code == 0 {
        return 0;
    }
    REG_GENERIC
        | match code >> 12 {
            0x2 => REG_CURRENT,
            0x3 => REG_VOLTAGE,
            0x4 => REG_TEMPERATURE,
            // CiA 301: 81xx communication, 82xx protocol errors; 83xx..8Fxx are the device
            // profile's monitoring codes (CiA 402: 8400h velocity, 8500h position, 8600h
            // positioning, 8700h sync controller), not communication errors.
            0x8 if (code >> 8) & 0xF <= 2 => REG_COMMUNICATION,
            0x8 => REG_PROFILE,
            0xF if code >> 8 == 0xFF => REG_MANUFACTURER,
            _ => 0,
        }
}

/// EMCY error code: RPDO not processed because its length was too short (8210h).
pub const PDO_LENGTH_ERROR: u16 = 0x8210;

/// EMCY error code: RPDO longer than its mapping (8220h), sent when the application asks
/// ([`crate::App::rpdo_length_exceeded`]).
pub const PDO_LENGTH_EXCEEDED: u16 = 0x8220;

const QUEUE: usize = 8;

/// A bounded FIFO of EMCY payloads waiting for the inhibit time or a state that allows them.
/// When full, the oldest message is dropped.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Queue {
    items: [[u8; 8]; QUEUE],
    head: usize,
    len: usize,
}

impl Queue {
    pub(crate) const fn new() -> Self {
        Self { items: [[0; 8]; QUEUE], head: 0, len: 0 }
    }

    pub(crate) fn push(&mut self, d: [u8; 8]) {
        if self.len == QUEUE {
            self.head = (self.head + 1) % QUEUE;
            self.len -= 1;
        }
        self.items[(self.head + self.len) % QUEUE] = d;
        self.len += 1;
    }

    pub(crate) fn pop(&mut self) -> Option<[u8; 8]> {
        if self.len == 0 {
            return None;
        }
        let d = self.items[self.head];
        self.head = (self.head + 1) % QUEUE;
        self.len -= 1;
        Some(d)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes() {
        assert_eq!(register_bits(0x2310), 0x03);
        assert_eq!(register_bits(0x3210), 0x05);
        assert_eq!(register_bits(0x4210), 0x09);
        assert_eq!(register_bits(0x8130), 0x11);
        assert_eq!(register_bits(0x8210), 0x11);
        assert_eq!(register_bits(0x8611), 0x21, "following error: device profile");
        assert_eq!(register_bits(0x8580), 0x21);
        assert_eq!(register_bits(0xFF01), 0x81);
        assert_eq!(register_bits(0x5000), 0x01);
        assert_eq!(register_bits(0), 0);
    }

    #[test]
    fn queue_drops_oldest() {
        let mut q = Queue::new();
        for i in 0..10u8 {
            q.push([i; 8]);
        }
        assert_eq!(q.pop(), Some([2; 8]));
        let mut n = 1;
        while q.pop().is_some() {
            n += 1;
        }
        assert_eq!(n, 8);
        assert!(q.is_empty());
    }
}
