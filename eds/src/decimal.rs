//! Numbers written in decimal without the formatter: the names and messages of the reader
//! (lowering) and the names of compact array elements (`name`) share it, so it sits below both.

/// The numbers 0 to 255 in decimal, one after the other: `0123456789101112...255`.
const DECIMALS: &str = {
    const BYTES: [u8; 10 + 90 * 2 + 156 * 3] = {
        let mut out = [0u8; 10 + 90 * 2 + 156 * 3];
        let (mut v, mut at) = (0usize, 0usize);
        while v < 256 {
            if v >= 100 {
                out[at] = b'0' + (v / 100) as u8;
                at += 1;
            }
            if v >= 10 {
                out[at] = b'0' + (v / 10 % 10) as u8;
                at += 1;
            }
            out[at] = b'0' + (v % 10) as u8;
            at += 1;
            v += 1;
        }
        out
    };
    match std::str::from_utf8(&BYTES) {
        Ok(s) => s,
        Err(_) => panic!("ASCII digits"),
    }
};

/// `v` in decimal (`format!("{v}")`), as a slice of a table: no formatting and no arithmetic
/// beyond finding the place. Sub-indices, the numbers lowering writes into names and messages,
/// are bytes.
pub(crate) fn decimal_u8(v: u8) -> &'static str {
    let v = v as usize;
    let (start, len) = if v < 10 {
        (v, 1)
    } else if v < 100 {
        (10 + (v - 10) * 2, 2)
    } else {
        (190 + (v - 100) * 3, 3)
    };
    DECIMALS.get(start..start + len).unwrap_or("")
}
