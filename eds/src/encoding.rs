//! Windows-1252, the fallback for EDS files that are not UTF-8.
//!
//! Bytes 0x00-0x7F and 0xA0-0xFF map to the same code points; 0x80-0x9F map through the table
//! below. The five bytes Windows-1252 leaves undefined (0x81, 0x8D, 0x8F, 0x90, 0x9D) map to the
//! C1 control with the same number, as the WHATWG encoding standard does, so decoding never
//! fails and encoding the decoded text gives the original bytes back.

const HIGH: [char; 32] = [
    '\u{20AC}', '\u{0081}', '\u{201A}', '\u{0192}', '\u{201E}', '\u{2026}', '\u{2020}', '\u{2021}', //
    '\u{02C6}', '\u{2030}', '\u{0160}', '\u{2039}', '\u{0152}', '\u{008D}', '\u{017D}', '\u{008F}', //
    '\u{0090}', '\u{2018}', '\u{2019}', '\u{201C}', '\u{201D}', '\u{2022}', '\u{2013}', '\u{2014}', //
    '\u{02DC}', '\u{2122}', '\u{0161}', '\u{203A}', '\u{0153}', '\u{009D}', '\u{017E}', '\u{0178}', //
];

/// Decodes Windows-1252 bytes. Never fails.
pub fn decode_windows_1252(bytes: &[u8]) -> String {
    bytes
        .iter()
        .map(|&b| match b {
            0x80..=0x9F => HIGH[(b - 0x80) as usize],
            _ => b as char,
        })
        .collect()
}

/// Encodes text to Windows-1252. Characters that have no Windows-1252 byte become `?`
/// (this cannot happen for text produced by [`decode_windows_1252`]).
pub fn encode_windows_1252(text: &str) -> Vec<u8> {
    text.chars()
        .map(|c| match c as u32 {
            0x00..=0x7F | 0xA0..=0xFF => c as u8,
            _ => HIGH.iter().position(|&h| h == c).map(|i| 0x80 + i as u8).unwrap_or(b'?'),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_byte_round_trips() {
        let all: Vec<u8> = (0..=255u8).collect();
        let text = decode_windows_1252(&all);
        assert_eq!(encode_windows_1252(&text), all);
        assert_eq!(decode_windows_1252(&[0x94]), "\u{201D}");
        assert_eq!(decode_windows_1252(&[0xF6]), "ö");
    }
}
