//! CRC-16-CCITT as SDO block transfers use it (CiA 301: polynomial x^16 + x^12 + x^5 + 1,
//! initial value 0, no reflection, no final XOR; also known as CRC-16/XMODEM).
//!
//! A host takes a byte a step from a table of 256 entries (512 bytes); a microcontroller
//! (`target_os = "none"`) a nibble a step from a table of 16 (32 bytes), so that a firmware
//! does not carry the large table for a service few transfers use.

/// The CRC of each value of the top `bits` of the register, shifted out.
const fn table<const N: usize>(bits: u32) -> [u16; N] {
    let mut t = [0u16; N];
    let mut i = 0;
    while i < N {
        let mut crc = (i as u16) << (16 - bits);
        let mut b = 0;
        while b < bits {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x1021 } else { crc << 1 };
            b += 1;
        }
        t[i] = crc;
        i += 1;
    }
    t
}

#[cfg_attr(target_os = "none", allow(dead_code))]
static BYTE_TABLE: [u16; 256] = table(8);
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
static NIBBLE_TABLE: [u16; 16] = table(4);

/// A byte a step (the host's CRC).
#[cfg_attr(target_os = "none", allow(dead_code))]
fn by_bytes(mut crc: u16, data: &[u8]) -> u16 {
    for &b in data {
        crc = (crc << 8) ^ BYTE_TABLE[usize::from((crc >> 8) as u8 ^ b)];
    }
    crc
}

/// A nibble a step (a microcontroller's CRC).
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
fn by_nibbles(mut crc: u16, data: &[u8]) -> u16 {
    for &b in data {
        crc = (crc << 4) ^ NIBBLE_TABLE[usize::from(((crc >> 12) as u8 ^ (b >> 4)) & 0xF)];
        crc = (crc << 4) ^ NIBBLE_TABLE[usize::from(((crc >> 12) as u8 ^ b) & 0xF)];
    }
    crc
}

/// Continues a CRC over `data`, starting from `crc` (0 for a new transfer).
pub fn crc16_ccitt(crc: u16, data: &[u8]) -> u16 {
    #[cfg(target_os = "none")]
    return by_nibbles(crc, data);
    #[cfg(not(target_os = "none"))]
    return by_bytes(crc, data);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition: one bit a step.
    fn by_bits(mut crc: u16, data: &[u8]) -> u16 {
        for &b in data {
            crc ^= u16::from(b) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x1021 } else { crc << 1 };
            }
        }
        crc
    }

    #[test]
    fn check_value() {
        // The standard check value of CRC-16/XMODEM.
        assert_eq!(crc16_ccitt(0, b"123456789"), 0x31C3);
        assert_eq!(crc16_ccitt(crc16_ccitt(0, b"1234"), b"56789"), 0x31C3);
        assert_eq!(crc16_ccitt(0, &[]), 0);
    }

    #[test]
    fn both_tables_give_the_definition() {
        // Every byte value from every register value's top byte, and runs of mixed data.
        let mut data = [0u8; 600];
        let mut x = 0x1234_5678u32;
        for d in &mut data {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *d = x as u8;
        }
        for start in [0u16, 0x31C3, 0xFFFF, 0x8000, 0x0001] {
            for b in 0..=255u8 {
                let want = by_bits(start, &[b]);
                assert_eq!(by_bytes(start, &[b]), want, "{start:#x} {b:#x}");
                assert_eq!(by_nibbles(start, &[b]), want, "{start:#x} {b:#x}");
            }
            for len in [0, 1, 7, 127, 600] {
                let want = by_bits(start, &data[..len]);
                assert_eq!(by_bytes(start, &data[..len]), want);
                assert_eq!(by_nibbles(start, &data[..len]), want);
            }
        }
    }
}
