//! Parsing and formatting of CiA 306 values (numbers, `$NODEID` expressions, strings, bytes).
//!
//! CiA 306 leaves several questions open and real files answer them differently. The rules this
//! crate applies, in order, are:
//!
//! # Integers (BOOLEAN, INTEGERn, UNSIGNEDn, and the constant part of `$NODEID` expressions)
//!
//! * White space around the value is ignored. An optional sign (`-` or `+`) may come first.
//! * `0x`/`0X` followed by hex digits is hexadecimal.
//! * `0` followed by more digits is **octal**, as CiA 306 says. When all digits are 0..7 the value
//!   is read as octal ([`Radix::Oct`]). If the octal and the decimal reading of the same digits
//!   differ (`010` is 8 in octal, 10 in decimal) the value is *ambiguous*: many tools write
//!   leading zeros meaning decimal, and python-canopen refuses such values outright. The reader
//!   keeps the octal value (the standard's reading) and reports [`Quirk::AmbiguousOctal`] so the
//!   user can write `0x8` or `10` instead. When both readings agree (`00`, `001`,
//!   `0000000000`) the value is unambiguous and [`Quirk::LeadingZeros`] is reported only as a note.
//! * `0` followed by digits that include `8` or `9` (`09`, `0080`) is not octal at all; the
//!   digits are read as decimal and [`Quirk::DecimalWithLeadingZero`] is reported.
//! * Anything else made of digits is decimal.
//! * A C literal suffix (`U`, `L`, `UL`, `LL`, `ULL` in any case), as code generators leave
//!   behind, is removed ([`Quirk::CSuffix`], a deviation).
//! * For a *signed* type, an unsigned hexadecimal value that does not fit the positive range but
//!   fits the type's width is a two's complement bit pattern: `0xFFFF` as INTEGER16 is `-1`
//!   ([`Quirk::HexBitPattern`], a note). `-0x10` (a signed hex literal) is `-16`.
//! * BOOLEAN also accepts `TRUE`/`FALSE` in any case ([`Quirk::BooleanWord`], a deviation).
//!
//! # `$NODEID` expressions
//!
//! `$NODEID`, `$NODEID+c`, `c+$NODEID`, `$NODEID-c`, any case and any spacing, are kept symbolic
//! as [`Value::NodeIdPlus`]. `c` follows the integer rules above. Any other shape
//! (`2*$NODEID`, `$NODEID+$NODEID`) is an error.
//!
//! # REAL32 and REAL64
//!
//! A decimal or floating-point literal (`1`, `-2.5`, `1e-3`, `.5`, `inf` and `nan` are accepted by
//! Rust's float syntax) is the value. A `0x` hexadecimal literal is the IEEE 754 **bit pattern**
//! of the type (`0x3F800000` as REAL32 is `1.0`; [`Quirk::RealBitPattern`], a note), because a
//! hexadecimal real value has no other sensible meaning. A C `f` suffix (`0.5f`) is removed
//! ([`Quirk::CSuffix`]).
//!
//! # Strings and bytes
//!
//! VISIBLE_STRING and UNICODE_STRING values are taken verbatim (after trimming, which the lexer
//! already did). OCTET_STRING values are hex digits, optionally separated by spaces and
//! optionally prefixed by `0x`. DOMAIN values are hex digits too; a DOMAIN value that is not hex
//! (some tools write a file name or a decimal `0`) is kept as [`Value::Text`] with
//! [`Quirk::DomainNotHex`].
//!
//! # TIME_OF_DAY and TIME_DIFFERENCE
//!
//! Either one integer (the 48-bit value as sent on the bus: milliseconds in bits 0..28, days in
//! bits 32..48) or two integers `days ms` separated by white space, as lely-core writes them
//! ([`Quirk::TimePair`], a note). Both become the 48-bit integer.
//!
//! # Empty values
//!
//! An empty value of a string type is the empty string (`Text("")`, `Bytes([])`), an empty DOMAIN
//! has no value, and an empty value of a numeric type is *no value* with
//! [`Quirk::EmptyNumeric`] reported by [`parse_value`] callers (see [`ParsedValue::value`]).

use std::fmt::Write as _;

use crate::model::{DataType, Radix, Value};

/// Something worth telling the user about a value that was nevertheless read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Quirk {
    /// `010`: octal by CiA 306, but the decimal reading differs (`octal`, `decimal`).
    AmbiguousOctal {
        /// The value as octal (what was used).
        octal: i128,
        /// The value as decimal (what the author may have meant).
        decimal: i128,
    },
    /// `001`: leading zeros where octal and decimal agree.
    LeadingZeros,
    /// `09`: a leading zero, but the digits are not octal; read as decimal.
    DecimalWithLeadingZero,
    /// `0xFFFF` for a signed type, read as two's complement.
    HexBitPattern,
    /// `0x3F800000` for a REAL, read as an IEEE 754 bit pattern.
    RealBitPattern,
    /// `TRUE`/`FALSE` for a BOOLEAN.
    BooleanWord,
    /// A DOMAIN value that is not hex digits, kept as text.
    DomainNotHex,
    /// An empty value for a numeric type.
    EmptyNumeric,
    /// White space inside a number or between a sign and digits (`- 5`, `0x 10`).
    SpacedNumber,
    /// A TIME_OF_DAY or TIME_DIFFERENCE written as `days ms`.
    TimePair,
    /// A C literal suffix (`10U`, `0x1234LL`, `0.5f`), removed to read the number.
    CSuffix,
}

/// Why a value could not be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// Not a number.
    #[error("`{0}` is not a number")]
    NotANumber(String),
    /// A number too large for any supported type.
    #[error("`{0}` is too large")]
    TooLarge(String),
    /// A `$NODEID` expression of an unsupported shape.
    #[error("`{0}` is not a `$NODEID` expression this reader understands (use `$NODEID+c` or `c+$NODEID`)")]
    BadNodeIdExpr(String),
    /// `$NODEID` in a value of a type that cannot hold it.
    #[error("`$NODEID` cannot be used in a {0} value")]
    NodeIdNotAllowed(&'static str),
    /// Not a hex byte string.
    #[error("`{0}` is not a string of hex byte pairs")]
    NotHexBytes(String),
    /// Not a real number.
    #[error("`{0}` is not a real number")]
    NotAReal(String),
    /// A hex bit pattern wider than the REAL type.
    #[error("bit pattern `{0}` is wider than {1}")]
    RealPatternTooWide(String, &'static str),
}

/// A value read from text, with the remarks about how it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct ParsedValue {
    /// The value (`None` for an empty numeric or DOMAIN value).
    pub value: Option<Value>,
    /// Remarks, in the order found.
    pub quirks: Vec<Quirk>,
}

/// An integer read from text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParsedInt {
    /// The value, sign applied (before any two's complement reinterpretation).
    pub value: i128,
    /// How it was written.
    pub radix: Radix,
    /// Whether an explicit `-` was written.
    pub negative: bool,
}

/// Reads `text` as a value of type `ty`. Never panics.
///
/// ```
/// use canopen_eds::model::{DataType, Radix, Value};
/// let v = canopen_eds::value::parse_value(" $NodeID + 0x200 ", DataType::Unsigned32).unwrap();
/// assert_eq!(v.value, Some(Value::NodeIdPlus { offset: 0x200, radix: Radix::Hex }));
/// let v = canopen_eds::value::parse_value("0xFFFF", DataType::Integer16).unwrap();
/// assert_eq!(v.value.unwrap().as_int(), Some(-1));
/// ```
pub fn parse_value(text: &str, ty: DataType) -> Result<ParsedValue, ValueError> {
    let mut quirks = Vec::new();
    let value = parse_value_into(text, ty, &mut quirks)?;
    Ok(ParsedValue { value, quirks })
}

/// [`parse_value`], its quirks appended to `quirks` (a buffer the caller reuses: most values
/// have none, but a file may have hundreds that do, each a vector of its own otherwise).
pub(crate) fn parse_value_into(text: &str, ty: DataType, quirks: &mut Vec<Quirk>) -> Result<Option<Value>, ValueError> {
    let t = crate::lex::trim(text);
    let value = match ty {
        DataType::VisibleString | DataType::UnicodeString => Some(Value::Text(t.to_owned())),
        DataType::OctetString => Some(Value::Bytes(parse_hex_bytes(t)?)),
        DataType::Domain => {
            if t.is_empty() {
                None
            } else {
                match parse_hex_bytes(t) {
                    Ok(b) => Some(Value::Bytes(b)),
                    Err(_) => {
                        quirks.push(Quirk::DomainNotHex);
                        Some(Value::Text(t.to_owned()))
                    }
                }
            }
        }
        DataType::TimeOfDay | DataType::TimeDifference if t.split_ascii_whitespace().count() == 2 => {
            // `days ms`, as lely writes it: days since 1984-01-01 (or a difference in days) and
            // milliseconds after midnight. Stored as the 48-bit wire value `ms | days << 32`.
            let mut parts = t.split_ascii_whitespace();
            let days = parse_int(parts.next().unwrap_or(""), quirks)?;
            let ms = parse_int(parts.next().unwrap_or(""), quirks)?;
            if !(0..=0xFFFF).contains(&days.value) || !(0..(1 << 28)).contains(&ms.value) {
                return Err(ValueError::TooLarge(t.to_owned()));
            }
            quirks.push(Quirk::TimePair);
            Some(Value::Int { value: ms.value | days.value << 32, radix: Radix::Dec })
        }
        DataType::Real32 | DataType::Real64 => {
            if t.is_empty() {
                quirks.push(Quirk::EmptyNumeric);
                None
            } else if contains_node_id(t) {
                return Err(ValueError::NodeIdNotAllowed(ty.name()));
            } else {
                Some(Value::Real(parse_real(t, ty == DataType::Real32, quirks)?))
            }
        }
        _ => {
            if let Some((v, radix)) = parse_plain_uint(t) {
                // The common case (`0x1A`, `100`), read without the general rules.
                Some(Value::Int { value: twos_complement(v as i128, radix, false, ty, quirks), radix })
            } else if t.is_empty() {
                quirks.push(Quirk::EmptyNumeric);
                None
            } else if contains_node_id(t) {
                let (offset, radix) = parse_node_id_expr(t, quirks)?;
                Some(Value::NodeIdPlus { offset, radix })
            } else if ty == DataType::Boolean && t.eq_ignore_ascii_case("true") {
                quirks.push(Quirk::BooleanWord);
                Some(Value::Int { value: 1, radix: Radix::Dec })
            } else if ty == DataType::Boolean && t.eq_ignore_ascii_case("false") {
                quirks.push(Quirk::BooleanWord);
                Some(Value::Int { value: 0, radix: Radix::Dec })
            } else {
                let p = parse_int(t, quirks)?;
                Some(Value::Int { value: twos_complement(p.value, p.radix, p.negative, ty, quirks), radix: p.radix })
            }
        }
    };
    Ok(value)
}

/// For a signed type, an unsigned hexadecimal value that does not fit the positive range but
/// fits the type's width is a two's complement bit pattern (see the module docs).
fn twos_complement(value: i128, radix: Radix, negative: bool, ty: DataType, quirks: &mut Vec<Quirk>) -> i128 {
    if let (Some(bits), true, Radix::Hex, false) = (ty.bits(), ty.is_signed(), radix, negative) {
        let max = (1i128 << (bits - 1)) - 1;
        if value > max && value < (1i128 << bits) {
            quirks.push(Quirk::HexBitPattern);
            return value - (1i128 << bits);
        }
    }
    value
}

/// Reads the plain forms of an unsigned integer, which need no remark: `0`, decimal digits
/// without a leading zero (at most 19), or `0x`/`0X` and 1 to 16 hex digits. `None` for
/// anything else, which [`parse_int`] reads by the general rules. For the plain forms both give
/// the same value and radix.
#[inline]
pub(crate) fn parse_plain_uint(s: &str) -> Option<(u64, Radix)> {
    match s.as_bytes() {
        [b'0', b'x' | b'X', digits @ ..] if !digits.is_empty() && digits.len() <= 16 => {
            let mut v = 0u64;
            for &b in digits {
                let d = HEX_VALUE[b as usize];
                if d > 0xF {
                    return None;
                }
                v = v << 4 | d as u64;
            }
            Some((v, Radix::Hex))
        }
        [b'0'] => Some((0, Radix::Dec)),
        digits @ [b'1'..=b'9', ..] if digits.len() <= 19 => {
            let mut v = 0u64;
            for &b in digits {
                if !b.is_ascii_digit() {
                    return None;
                }
                v = v * 10 + (b - b'0') as u64;
            }
            Some((v, Radix::Dec))
        }
        _ => None,
    }
}

/// The value of four hex digits (either case), or `None` if a byte is none: what
/// [`parse_plain_uint`] reads after `0x` (an object index, a type code), with no loop and one
/// check of the four look-ups OR'ed together (a byte that is no digit makes them 0xFF).
#[inline]
pub(crate) fn hex4_value(digits: [u8; 4]) -> Option<u16> {
    let [a, b, c, d] = digits.map(|b| HEX_VALUE[b as usize]);
    ((a | b | c | d) <= 0xF).then_some((a as u16) << 12 | (b as u16) << 8 | (c as u16) << 4 | d as u16)
}

/// Each byte's value as a hex digit (either case), `0xFF` for a byte that is none: one look-up
/// per digit of the plain hex numbers that most values and types are, where [`digit`] takes a
/// comparison per range.
const HEX_VALUE: [u8; 256] = {
    let mut table = [0xFF; 256];
    let mut b = 0;
    while b < 256 {
        table[b] = match b as u8 {
            c @ b'0'..=b'9' => c - b'0',
            c @ b'a'..=b'f' => c - b'a' + 10,
            c @ b'A'..=b'F' => c - b'A' + 10,
            _ => 0xFF,
        };
        b += 1;
    }
    table
};

/// Whether `text` mentions `$NODEID` (any case).
pub fn contains_node_id(text: &str) -> bool {
    text.as_bytes().contains(&b'$') && find_ci(text, "$nodeid").is_some()
}

fn find_ci(hay: &str, needle: &str) -> Option<usize> {
    let h = hay.as_bytes();
    let n = needle.as_bytes();
    if n.len() > h.len() {
        return None;
    }
    (0..=h.len() - n.len()).find(|&i| h[i..i + n.len()].eq_ignore_ascii_case(n))
}

/// Reads a `$NODEID` expression: `$NODEID`, `$NODEID+c`, `$NODEID-c`, `c+$NODEID`.
pub fn parse_node_id_expr(text: &str, quirks: &mut Vec<Quirk>) -> Result<(i128, Radix), ValueError> {
    let bad = || ValueError::BadNodeIdExpr(text.to_owned());
    let t = text.trim();
    let at = find_ci(t, "$nodeid").ok_or_else(bad)?;
    let before = t[..at].trim();
    let after = t[at + "$nodeid".len()..].trim();
    if contains_node_id(after) || contains_node_id(before) {
        return Err(bad());
    }
    match (before.is_empty(), after.is_empty()) {
        (true, true) => Ok((0, Radix::Hex)),
        (true, false) => {
            let (neg, num) = if let Some(r) = after.strip_prefix('+') {
                (false, r)
            } else if let Some(r) = after.strip_prefix('-') {
                (true, r)
            } else {
                return Err(bad());
            };
            let num = num.trim();
            if num.starts_with(['+', '-']) {
                return Err(bad());
            }
            let p = parse_int(num, quirks).map_err(|_| bad())?;
            Ok((if neg { -p.value } else { p.value }, p.radix))
        }
        (false, true) => {
            let num = before.strip_suffix('+').ok_or_else(bad)?.trim();
            let p = parse_int(num, quirks).map_err(|_| bad())?;
            Ok((p.value, p.radix))
        }
        (false, false) => Err(bad()),
    }
}

/// Reads an integer by the rules in the module docs. `quirks` receives the octal and
/// leading-zero remarks.
pub fn parse_int(text: &str, quirks: &mut Vec<Quirk>) -> Result<ParsedInt, ValueError> {
    let nan = || ValueError::NotANumber(text.to_owned());
    let t = crate::lex::trim(text);
    let (negative, rest) = match t.as_bytes().first() {
        Some(b'-') => (true, &t[1..]),
        Some(b'+') => (false, &t[1..]),
        _ => (false, t),
    };
    let mut body = crate::lex::trim_start(rest);
    if body.len() != rest.len() {
        quirks.push(Quirk::SpacedNumber);
    }
    let b = body.as_bytes();
    let mut unsuffixed = b.len();
    while unsuffixed > 0 && matches!(b[unsuffixed - 1], b'u' | b'U' | b'l' | b'L') {
        unsuffixed -= 1;
    }
    if unsuffixed != b.len() && unsuffixed + 3 >= b.len() && unsuffixed != 0 {
        quirks.push(Quirk::CSuffix);
        // The suffix letters are ASCII, so this is a char boundary.
        body = &body[..unsuffixed];
    }
    let (radix, digits) = if let Some(h) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        (Radix::Hex, h)
    } else if body.len() > 1 && body.starts_with('0') {
        (Radix::Oct, &body[1..])
    } else {
        (Radix::Dec, body)
    };
    if digits.is_empty() {
        return Err(nan());
    }
    let too_large = || ValueError::TooLarge(text.to_owned());
    let (value, radix) = match radix {
        Radix::Oct => {
            if !digits.bytes().all(|b| b.is_ascii_digit()) {
                return Err(nan());
            }
            if digits.bytes().all(|b| (b'0'..=b'7').contains(&b)) {
                let oct = accumulate(digits, 8).ok_or_else(too_large)?;
                let dec = accumulate(digits, 10).ok_or_else(too_large)?;
                if oct != dec {
                    let sign = if negative { -1 } else { 1 };
                    quirks.push(Quirk::AmbiguousOctal { octal: sign * oct, decimal: sign * dec });
                } else {
                    quirks.push(Quirk::LeadingZeros);
                }
                (oct, Radix::Oct)
            } else {
                quirks.push(Quirk::DecimalWithLeadingZero);
                (accumulate(digits, 10).ok_or_else(too_large)?, Radix::Dec)
            }
        }
        _ => {
            let radix_n = if radix == Radix::Hex { 16 } else { 10 };
            // Up to 16 hex or 19 decimal digits fit a u64: read and check them in one go.
            let short = if radix_n == 16 { 16 } else { 19 };
            if digits.len() <= short {
                let mut v = 0u64;
                for &b in digits.as_bytes() {
                    let d = digit(b).filter(|&d| d < radix_n).ok_or_else(nan)?;
                    v = v * radix_n as u64 + d as u64;
                }
                (v as i128, radix)
            } else {
                let ok = match radix_n {
                    16 => digits.bytes().all(|b| b.is_ascii_hexdigit()),
                    _ => digits.bytes().all(|b| b.is_ascii_digit()),
                };
                if !ok {
                    return Err(nan());
                }
                (accumulate(digits, radix_n).ok_or_else(too_large)?, radix)
            }
        }
    };
    Ok(ParsedInt { value: if negative { -value } else { value }, radix, negative })
}

/// The value of an ASCII hex digit.
#[inline]
fn digit(b: u8) -> Option<u32> {
    match b {
        b'0'..=b'9' => Some((b - b'0') as u32),
        b'a'..=b'f' => Some((b - b'a') as u32 + 10),
        b'A'..=b'F' => Some((b - b'A') as u32 + 10),
        _ => None,
    }
}

/// Accumulates validated digits; `None` on overflow past 2^100 (far beyond any CiA type).
fn accumulate(digits: &str, radix: u32) -> Option<i128> {
    let mut v: i128 = 0;
    for c in digits.chars() {
        let d = c.to_digit(radix)? as i128;
        v = v.checked_mul(radix as i128)?.checked_add(d)?;
        if v > (1i128 << 100) {
            return None;
        }
    }
    Some(v)
}

fn parse_real(t: &str, is32: bool, quirks: &mut Vec<Quirk>) -> Result<f64, ValueError> {
    let hex = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X"));
    if let Some(h) = hex {
        if h.is_empty() || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(ValueError::NotAReal(t.to_owned()));
        }
        let h = h.trim_start_matches('0');
        if is32 {
            if h.len() > 8 {
                return Err(ValueError::RealPatternTooWide(t.to_owned(), "REAL32"));
            }
            let bits = u32::from_str_radix(if h.is_empty() { "0" } else { h }, 16)
                .map_err(|_| ValueError::NotAReal(t.to_owned()))?;
            quirks.push(Quirk::RealBitPattern);
            return Ok(f32::from_bits(bits) as f64);
        }
        if h.len() > 16 {
            return Err(ValueError::RealPatternTooWide(t.to_owned(), "REAL64"));
        }
        let bits = u64::from_str_radix(if h.is_empty() { "0" } else { h }, 16)
            .map_err(|_| ValueError::NotAReal(t.to_owned()))?;
        quirks.push(Quirk::RealBitPattern);
        return Ok(f64::from_bits(bits));
    }
    // Rust's float syntax also accepts "inf", "infinity" and "nan"; keep them, they are valid
    // IEEE values a device may well use as a default.
    let mut t = t;
    if let Some(head) = t.strip_suffix(['f', 'F'])
        && head.ends_with(|c: char| c.is_ascii_digit() || c == '.')
    {
        quirks.push(Quirk::CSuffix);
        t = head;
    }
    if is32 {
        t.parse::<f32>().map(|f| f as f64).map_err(|_| ValueError::NotAReal(t.to_owned()))
    } else {
        t.parse::<f64>().map_err(|_| ValueError::NotAReal(t.to_owned()))
    }
}

/// Reads hex byte pairs (`0A1B`, `0A 1B`, `0x0A1B`).
pub fn parse_hex_bytes(t: &str) -> Result<Vec<u8>, ValueError> {
    let err = || ValueError::NotHexBytes(t.to_owned());
    let body = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")).unwrap_or(t);
    let mut out = Vec::with_capacity(body.len() / 2);
    let mut hi: Option<u8> = None;
    for b in body.bytes() {
        if b == b' ' || b == b'\t' {
            if hi.is_some() {
                return Err(err());
            }
            continue;
        }
        let d = (b as char).to_digit(16).ok_or_else(err)? as u8;
        match hi.take() {
            None => hi = Some(d),
            Some(h) => out.push(h << 4 | d),
        }
    }
    if hi.is_some() {
        return Err(err());
    }
    Ok(out)
}

/// Whether an integer value fits `ty` (strings and `Other` types always fit). `$NODEID`
/// expressions are checked for node ids 1 and 127.
pub fn check_range(value: &Value, ty: DataType) -> Result<(), String> {
    let Some((lo, hi)) = ty.int_range() else { return Ok(()) };
    let check = |v: i128, what: &str| {
        if v < lo || v > hi { Err(format!("{what}{v} is outside the {} range {lo}..={hi}", ty.name())) } else { Ok(()) }
    };
    match value {
        Value::Int { value, .. } => check(*value, ""),
        Value::NodeIdPlus { offset, .. } => {
            check(offset + 1, "with node id 1 the value ")?;
            check(offset + 127, "with node id 127 the value ")
        }
        Value::Real(_) => Err(format!("a real number is not a {} value", ty.name())),
        Value::Text(_) => Err(format!("text is not a {} value", ty.name())),
        Value::Bytes(_) => Err(format!("bytes are not a {} value", ty.name())),
    }
}

/// Formats a value for an EDS/DCF file so that [`parse_value`] reads back the same value.
///
/// Integers keep their radix (octal as `0…`, hex as `0x…`); a negative hexadecimal value of a
/// signed type is written as its two's complement bit pattern (`-1` as INTEGER16 is `0xFFFF`);
/// `$NODEID` expressions are written `$NODEID+0x180`; reals in the shortest decimal form that
/// reads back exactly; bytes as upper-case hex pairs without separators.
///
/// ```
/// use canopen_eds::model::{DataType, Value, Radix};
/// assert_eq!(canopen_eds::value::format_value(&Value::hex(0x180), DataType::Unsigned32), "0x180");
/// assert_eq!(canopen_eds::value::format_value(&Value::NodeIdPlus { offset: 0x200, radix: Radix::Hex }, DataType::Unsigned32), "$NODEID+0x200");
/// assert_eq!(canopen_eds::value::format_value(&Value::hex(-1), DataType::Integer16), "0xFFFF");
/// ```
pub fn format_value(value: &Value, ty: DataType) -> String {
    match value {
        Value::Int { value, radix } => format_int(*value, *radix, ty),
        Value::NodeIdPlus { offset, radix } => {
            if *offset == 0 {
                "$NODEID".to_owned()
            } else if *offset < 0 {
                format!("$NODEID-{}", format_int(-offset, *radix, DataType::Other(0)))
            } else {
                format!("$NODEID+{}", format_int(*offset, *radix, DataType::Other(0)))
            }
        }
        Value::Real(f) => {
            if ty == DataType::Real32 {
                format_real(*f as f32 as f64, true)
            } else {
                format_real(*f, false)
            }
        }
        Value::Text(s) => s.clone(),
        Value::Bytes(b) => {
            let mut s = String::with_capacity(b.len() * 2);
            for byte in b {
                let _ = write!(s, "{byte:02X}");
            }
            s
        }
    }
}

fn format_real(f: f64, is32: bool) -> String {
    if f.is_nan() {
        return "nan".to_owned();
    }
    if f.is_infinite() {
        return if f > 0.0 { "inf".to_owned() } else { "-inf".to_owned() };
    }
    if is32 { format!("{}", f as f32) } else { format!("{f}") }
}

fn format_int(v: i128, radix: Radix, ty: DataType) -> String {
    match radix {
        Radix::Dec => v.to_string(),
        Radix::Hex => {
            if v < 0 {
                match ty.bits() {
                    Some(bits) if ty.is_signed() && v >= -(1i128 << (bits - 1)) => {
                        format!("0x{:X}", v + (1i128 << bits))
                    }
                    _ => format!("-0x{:X}", -v),
                }
            } else {
                format!("0x{v:X}")
            }
        }
        Radix::Oct => {
            if v < 0 {
                format!("-0{:o}", -v)
            } else {
                format!("0{v:o}")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn int(t: &str, ty: DataType) -> (Option<i128>, Vec<Quirk>) {
        let p = parse_value(t, ty).unwrap();
        (p.value.and_then(|v| v.as_int()), p.quirks)
    }

    #[test]
    fn decimal_hex_octal() {
        assert_eq!(int("42", DataType::Unsigned8), (Some(42), vec![]));
        assert_eq!(int("0x2A", DataType::Unsigned8), (Some(42), vec![]));
        assert_eq!(int("0X2a", DataType::Unsigned8), (Some(42), vec![]));
        assert_eq!(int("0", DataType::Unsigned8), (Some(0), vec![]));
        assert_eq!(int("010", DataType::Unsigned8), (Some(8), vec![Quirk::AmbiguousOctal { octal: 8, decimal: 10 }]));
        assert_eq!(int("001", DataType::Unsigned8), (Some(1), vec![Quirk::LeadingZeros]));
        assert_eq!(int("0000000000", DataType::Unsigned32), (Some(0), vec![Quirk::LeadingZeros]));
        assert_eq!(int("09", DataType::Unsigned8), (Some(9), vec![Quirk::DecimalWithLeadingZero]));
        assert!(parse_value("0x", DataType::Unsigned8).is_err());
        assert!(parse_value("12a", DataType::Unsigned8).is_err());
        assert!(parse_value("1.5", DataType::Unsigned8).is_err());
    }

    #[test]
    fn c_suffixes() {
        assert_eq!(int("0x1234LL", DataType::Unsigned64), (Some(0x1234), vec![Quirk::CSuffix]));
        assert_eq!(int("10U", DataType::Unsigned8), (Some(10), vec![Quirk::CSuffix]));
        assert!(parse_value("L", DataType::Unsigned8).is_err());
        assert!(parse_value("10ULLL", DataType::Unsigned8).is_err());
        let r = parse_value("0.5f", DataType::Real32).unwrap();
        assert_eq!((r.value, r.quirks), (Some(Value::Real(0.5)), vec![Quirk::CSuffix]));
        assert!(parse_value("f", DataType::Real32).is_err());
    }

    #[test]
    fn signed() {
        assert_eq!(int("-5", DataType::Integer8), (Some(-5), vec![]));
        assert_eq!(int("-0x10", DataType::Integer16), (Some(-16), vec![]));
        assert_eq!(int("0xFFFF", DataType::Integer16), (Some(-1), vec![Quirk::HexBitPattern]));
        assert_eq!(int("0x7FFF", DataType::Integer16), (Some(0x7FFF), vec![]));
        assert_eq!(int("0x10000", DataType::Integer16), (Some(0x10000), vec![]));
        assert_eq!(format_value(&Value::hex(-1), DataType::Integer16), "0xFFFF");
        assert_eq!(format_value(&Value::hex(-16), DataType::Integer32), "0xFFFFFFF0");
    }

    #[test]
    fn node_id_shapes() {
        for (t, off) in [
            ("$NODEID+0x180", 0x180),
            ("0x180+$NODEID", 0x180),
            ("$NodeID + 0x200", 0x200),
            ("$nodeid", 0),
            ("$NODEID-1", -1),
            ("  512 + $NODEID ", 512),
        ] {
            let v = parse_value(t, DataType::Unsigned32).unwrap().value.unwrap();
            assert_eq!(v.resolve(5), Some(off + 5), "{t}");
        }
        for bad in ["2*$NODEID", "$NODEID+$NODEID", "$NODEID 5", "0x180-$NODEID", "$NODEID+"] {
            assert!(parse_value(bad, DataType::Unsigned32).is_err(), "{bad}");
        }
        assert!(parse_value("$NODEID", DataType::Real32).is_err());
    }

    #[test]
    fn reals() {
        let r = |t: &str, ty| match parse_value(t, ty).unwrap().value {
            Some(Value::Real(f)) => f,
            v => panic!("{v:?}"),
        };
        assert_eq!(r("1.5", DataType::Real32), 1.5);
        assert_eq!(r("-2", DataType::Real64), -2.0);
        assert_eq!(r("0x3F800000", DataType::Real32), 1.0);
        assert_eq!(r("0x3FF0000000000000", DataType::Real64), 1.0);
        assert!(parse_value("0x123456789", DataType::Real32).is_err());
        assert_eq!(format_value(&Value::Real(0.1f32 as f64), DataType::Real32), "0.1");
    }

    #[test]
    fn bytes_and_strings() {
        assert_eq!(parse_value("0A 1b", DataType::OctetString).unwrap().value, Some(Value::Bytes(vec![0x0A, 0x1B])));
        assert!(parse_value("0A1", DataType::OctetString).is_err());
        let d = parse_value("file.bin", DataType::Domain).unwrap();
        assert_eq!(d.quirks, vec![Quirk::DomainNotHex]);
        assert_eq!(parse_value("", DataType::Domain).unwrap().value, None);
        assert_eq!(parse_value("", DataType::VisibleString).unwrap().value, Some(Value::Text(String::new())));
        assert_eq!(parse_value("", DataType::Unsigned8).unwrap().quirks, vec![Quirk::EmptyNumeric]);
        assert_eq!(format_value(&Value::Bytes(vec![1, 0xAB]), DataType::OctetString), "01AB");
    }

    #[test]
    fn times() {
        assert_eq!(int("365 43200000", DataType::TimeOfDay), (Some(43200000 | 365 << 32), vec![Quirk::TimePair]));
        assert_eq!(int("12", DataType::TimeDifference), (Some(12), vec![]));
        assert!(parse_value("1 2 3", DataType::TimeOfDay).is_err());
        assert!(parse_value("70000 1", DataType::TimeOfDay).is_err());
    }

    /// The table of hex digits gives each byte the value [`digit`] gives it.
    #[test]
    fn hex_table_is_digit() {
        for b in 0..=u8::MAX {
            assert_eq!(digit(b), Some(HEX_VALUE[b as usize] as u32).filter(|&d| d <= 0xF), "{b:#04X}");
        }
    }

    /// [`parse_plain_uint`] as it read hex digits before their table: [`digit`] per byte.
    fn plain_uint_by_digit(s: &str) -> Option<(u64, Radix)> {
        match s.as_bytes() {
            [b'0', b'x' | b'X', digits @ ..] if !digits.is_empty() && digits.len() <= 16 => {
                let mut v = 0u64;
                for &b in digits {
                    v = v << 4 | digit(b)? as u64;
                }
                Some((v, Radix::Hex))
            }
            _ => parse_plain_uint(s),
        }
    }

    /// Every ASCII byte (and a multi-byte character) at every place of every length of hex
    /// digits reads as it did with [`digit`].
    #[test]
    fn plain_hex_reads_as_by_digit() {
        let others: Vec<String> = (0u8..0x80).map(|b| (b as char).to_string()).chain(["é".into()]).collect();
        for prefix in ["0x", "0X"] {
            for len in 1..=17 {
                for at in 0..len {
                    for other in &others {
                        for fill in ["9", "f", "A"] {
                            let t = format!("{prefix}{}{other}{}", fill.repeat(at), fill.repeat(len - at - 1));
                            assert_eq!(parse_plain_uint(&t), plain_uint_by_digit(&t), "{t:?}");
                        }
                    }
                }
            }
        }
    }

    /// Four hex digits read as `parse_plain_uint` reads them after `0x`, for every byte at
    /// every place.
    #[test]
    fn hex4_is_plain_hex() {
        for at in 0..4 {
            for b in 0..=u8::MAX {
                for fill in [b'0', b'9', b'a', b'F'] {
                    let mut digits = [fill; 4];
                    digits[at] = b;
                    let mut text = b"0x".to_vec();
                    text.extend(digits);
                    let plain = std::str::from_utf8(&text).ok().and_then(parse_plain_uint).map(|(v, _)| v as u16);
                    assert_eq!(hex4_value(digits), plain, "{text:?}");
                }
            }
        }
        for v in 0..=u16::MAX {
            assert_eq!(hex4_value(format!("{v:04X}").into_bytes().try_into().unwrap()), Some(v));
            assert_eq!(hex4_value(format!("{v:04x}").into_bytes().try_into().unwrap()), Some(v));
        }
    }

    proptest::proptest! {
        /// Plain numbers read as with [`digit`], and as the numbers they were written from.
        #[test]
        fn plain_hex_agrees(t in "(0[xX])?[0-9a-fA-FgG:@`/ ]{0,20}", n in proptest::num::u64::ANY) {
            proptest::prop_assert_eq!(parse_plain_uint(&t), plain_uint_by_digit(&t));
            for t in [format!("0x{n:X}"), format!("0x{n:x}"), format!("0X{n:016X}")] {
                proptest::prop_assert_eq!(parse_plain_uint(&t), Some((n, Radix::Hex)));
            }
        }
    }

    #[test]
    fn plain_numbers_read_as_parse_int_reads_them() {
        for t in [
            "0",
            "7",
            "0x0",
            "0X1a",
            "0x0007",
            "0xFFFFFFFFFFFFFFFF",
            "18446744073709551615",
            "9999999999999999999",
            "10000000000000000000",
            "0x10000000000000000",
            "00",
            "01",
            "08",
            "0x",
            "x1",
            "1a",
            "-1",
            "+1",
            " 1",
            "1 ",
            "1U",
            "0x1L",
            "",
            "0xg",
            "١",
        ] {
            let mut q = Vec::new();
            let full = parse_int(t, &mut q).ok().filter(|_| q.is_empty()).map(|p| (p.value, p.radix));
            // Not plain: left to the general rules (which may still read it).
            if let Some((v, r)) = parse_plain_uint(t) {
                assert_eq!(full, Some((v as i128, r)), "{t:?}");
            }
        }
        for plain in ["0", "7", "0x0", "0X1a", "0x0007", "0xFFFFFFFFFFFFFFFF", "9999999999999999999"] {
            assert!(parse_plain_uint(plain).is_some(), "{plain}");
        }
        assert_eq!(parse_value("0xFFFF", DataType::Integer16).unwrap().value.and_then(|v| v.as_int()), Some(-1));
        assert_eq!(parse_value("0xFFFF", DataType::Integer16).unwrap().quirks, vec![Quirk::HexBitPattern]);
    }

    #[test]
    fn booleans() {
        assert_eq!(int("TRUE", DataType::Boolean), (Some(1), vec![Quirk::BooleanWord]));
        assert_eq!(int("false", DataType::Boolean), (Some(0), vec![Quirk::BooleanWord]));
        assert!(parse_value("true", DataType::Unsigned8).is_err());
    }

    #[test]
    fn format_round_trips() {
        for (v, ty) in [
            (Value::Int { value: 8, radix: Radix::Oct }, DataType::Unsigned8),
            (Value::Int { value: 0, radix: Radix::Oct }, DataType::Unsigned8),
            (Value::NodeIdPlus { offset: -3, radix: Radix::Dec }, DataType::Unsigned32),
            (Value::hex(i64::MIN as i128), DataType::Integer64),
            (Value::int(u64::MAX as i128), DataType::Unsigned64),
            (Value::Real(1e-7), DataType::Real64),
        ] {
            let s = format_value(&v, ty);
            let back = parse_value(&s, ty).unwrap().value.unwrap();
            assert_eq!(back, v, "{s}");
        }
    }
}
