//! Values as their type says: printed (numbers in decimal, COB-IDs in hex, strings as text,
//! DOMAIN and OCTET_STRING as hex) and parsed for `write` (by the entry's type from the EDS, or
//! by a `type:` prefix without one), range-checked.

use eds::DataType;

/// A value as read from a device, ready to print.
#[derive(Clone, Debug, PartialEq)]
pub enum Shown {
    /// An integer (BOOLEAN as 0/1).
    Int(i128),
    /// An integer to print in hex (COB-IDs, bit fields without a type).
    Hex(u64, usize),
    /// A REAL32/REAL64.
    Real(f64),
    /// A VISIBLE_STRING/UNICODE_STRING.
    Text(String),
    /// Bytes (DOMAIN, OCTET_STRING, or anything of unknown type).
    Bytes(Vec<u8>),
}

impl Shown {
    /// The text form.
    pub fn text(&self) -> String {
        match self {
            Shown::Int(v) => v.to_string(),
            Shown::Hex(v, bytes) => format!("0x{v:0width$X}", width = bytes * 2),
            Shown::Real(v) => v.to_string(),
            Shown::Text(s) => s.clone(),
            Shown::Bytes(b) => hex(b),
        }
    }

    /// The JSON form: numbers as numbers (hex and bytes as strings).
    pub fn json(&self) -> serde_json::Value {
        match self {
            Shown::Int(v) => match i64::try_from(*v) {
                Ok(v) => v.into(),
                Err(_) => match u64::try_from(*v) {
                    Ok(v) => v.into(),
                    Err(_) => v.to_string().into(),
                },
            },
            Shown::Real(v) => serde_json::Number::from_f64(*v).map_or(serde_json::Value::Null, Into::into),
            other => other.text().into(),
        }
    }
}

/// Lower-case hex digits, two per byte.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether `index`/`sub` holds a COB-ID (printed in hex): the communication parameters' sub 1
/// of SDO/PDO, and SYNC/EMCY/TIME COB-IDs.
pub fn is_cob_id(index: u16, sub: u8) -> bool {
    matches!(index, 0x1005 | 0x1012 | 0x1014)
        || (matches!(index, 0x1200..=0x12FF | 0x1400..=0x15FF | 0x1800..=0x19FF) && sub == 1)
        || (matches!(index, 0x1280..=0x12FF) && sub == 2)
}

/// Bytes of a type's value on the bus (`None`: any length).
pub fn width(dt: DataType) -> Option<usize> {
    use DataType::*;
    Some(match dt {
        Boolean | Integer8 | Unsigned8 => 1,
        Integer16 | Unsigned16 => 2,
        Integer24 | Unsigned24 => 3,
        Integer32 | Unsigned32 | Real32 => 4,
        Integer40 | Unsigned40 => 5,
        Integer48 | Unsigned48 | TimeOfDay | TimeDifference => 6,
        Integer56 | Unsigned56 => 7,
        Integer64 | Unsigned64 | Real64 => 8,
        _ => return None,
    })
}

fn signed(dt: DataType) -> bool {
    use DataType::*;
    matches!(dt, Integer8 | Integer16 | Integer24 | Integer32 | Integer40 | Integer48 | Integer56 | Integer64)
}

fn is_int(dt: DataType) -> bool {
    use DataType::*;
    signed(dt)
        || matches!(
            dt,
            Boolean
                | Unsigned8
                | Unsigned16
                | Unsigned24
                | Unsigned32
                | Unsigned40
                | Unsigned48
                | Unsigned56
                | Unsigned64
        )
}

fn le_int(bytes: &[u8], signed: bool) -> i128 {
    let mut v: u128 = 0;
    for (i, b) in bytes.iter().enumerate() {
        v |= u128::from(*b) << (8 * i);
    }
    let bits = 8 * bytes.len() as u32;
    if signed && bits > 0 && bits < 128 && v >> (bits - 1) & 1 == 1 {
        (v | (u128::MAX << bits)) as i128
    } else {
        v as i128
    }
}

/// How a value read from `index`/`sub` shows, by its type when known.
pub fn show(bytes: &[u8], dt: Option<DataType>, index: u16, sub: u8) -> Shown {
    match dt {
        Some(dt) if is_int(dt) && width(dt) == Some(bytes.len()) => {
            if is_cob_id(index, sub) {
                Shown::Hex(le_int(bytes, false) as u64, bytes.len())
            } else {
                Shown::Int(le_int(bytes, signed(dt)))
            }
        }
        Some(DataType::Real32) if bytes.len() == 4 => {
            Shown::Real(f64::from(f32::from_le_bytes(bytes.try_into().unwrap_or_default())))
        }
        Some(DataType::Real64) if bytes.len() == 8 => {
            Shown::Real(f64::from_le_bytes(bytes.try_into().unwrap_or_default()))
        }
        Some(DataType::VisibleString) => Shown::Text(String::from_utf8_lossy(bytes).trim_end_matches('\0').to_owned()),
        Some(DataType::UnicodeString) => {
            let units: Vec<u16> = bytes.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect();
            Shown::Text(String::from_utf16_lossy(&units).trim_end_matches('\0').to_owned())
        }
        Some(_) => Shown::Bytes(bytes.to_vec()),
        // No EDS: the well-known strings of CiA 301 as text, COB-IDs in hex, short values as
        // unsigned numbers, the rest as bytes.
        None if matches!(index, 0x1008..=0x100A) => {
            Shown::Text(String::from_utf8_lossy(bytes).trim_end_matches('\0').to_owned())
        }
        None if is_cob_id(index, sub) && bytes.len() == 4 => Shown::Hex(le_int(bytes, false) as u64, 4),
        None if matches!(bytes.len(), 1 | 2 | 4 | 8) => Shown::Int(le_int(bytes, false)),
        None => Shown::Bytes(bytes.to_vec()),
    }
}

/// Why a value could not be written.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ValueError {
    /// Not a value of the type.
    #[error("`{text}` is not a {ty} value")]
    Syntax {
        /// The text given.
        text: String,
        /// The type.
        ty: String,
    },
    /// Outside the type's range.
    #[error("{text} is outside the range of {ty} ({low}..={high})")]
    Range {
        /// The text given.
        text: String,
        /// The type.
        ty: String,
        /// Lowest value.
        low: i128,
        /// Highest value.
        high: i128,
    },
    /// No type known.
    #[error(
        "the type of `{0}` is unknown: give --eds, or a typed value (u8: u16: u32: u64: i8: i16: i32: i64: f32: f64: str: hex:, e.g. u16:1234)"
    )]
    Untyped(String),
    /// A type the command line cannot write.
    #[error("values of type {0} cannot be written from the command line")]
    Unsupported(String),
}

/// The range of an integer type.
pub fn range(dt: DataType) -> Option<(i128, i128)> {
    let bits = 8 * width(dt)? as u32;
    if dt == DataType::Boolean {
        Some((0, 1))
    } else if signed(dt) {
        Some((-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1))
    } else if is_int(dt) {
        Some((0, (1i128 << bits) - 1))
    } else {
        None
    }
}

fn parse_int(text: &str) -> Option<i128> {
    let t = text.trim().replace('_', "");
    let (neg, t) = match t.strip_prefix('-') {
        Some(r) => (true, r.to_owned()),
        None => (false, t),
    };
    let v = if let Some(h) = t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        i128::from_str_radix(h, 16).ok()?
    } else if let Some(b) = t.strip_prefix("0b") {
        i128::from_str_radix(b, 2).ok()?
    } else {
        t.parse::<i128>().ok()?
    };
    Some(if neg { -v } else { v })
}

/// Parses hex digits (spaces allowed between bytes).
pub fn parse_hex(text: &str) -> Option<Vec<u8>> {
    let digits: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    let digits = digits.strip_prefix("0x").unwrap_or(&digits);
    if !digits.len().is_multiple_of(2) || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
        return None;
    }
    (0..digits.len()).step_by(2).map(|i| u8::from_str_radix(&digits[i..i + 2], 16).ok()).collect()
}

/// `text` as the bytes of a value of type `dt`, range-checked.
pub fn encode(text: &str, dt: DataType) -> Result<Vec<u8>, ValueError> {
    let ty = format!("{dt:?}").to_ascii_uppercase();
    let syntax = || ValueError::Syntax { text: text.to_owned(), ty: ty.clone() };
    if let Some((low, high)) = range(dt) {
        let v = match (dt, text.trim()) {
            (DataType::Boolean, "true") => 1,
            (DataType::Boolean, "false") => 0,
            _ => parse_int(text).ok_or_else(syntax)?,
        };
        if v < low || v > high {
            return Err(ValueError::Range { text: text.to_owned(), ty, low, high });
        }
        let n = width(dt).unwrap_or(0);
        return Ok(v.to_le_bytes()[..n].to_vec());
    }
    match dt {
        DataType::Real32 => {
            let v: f32 = text.trim().parse().map_err(|_| syntax())?;
            Ok(v.to_le_bytes().to_vec())
        }
        DataType::Real64 => {
            let v: f64 = text.trim().parse().map_err(|_| syntax())?;
            Ok(v.to_le_bytes().to_vec())
        }
        DataType::VisibleString => Ok(text.as_bytes().to_vec()),
        DataType::UnicodeString => Ok(text.encode_utf16().flat_map(u16::to_le_bytes).collect()),
        DataType::OctetString | DataType::Domain => parse_hex(text).ok_or_else(syntax),
        other => Err(ValueError::Unsupported(format!("{other:?}"))),
    }
}

/// A value written without an EDS: `u16:1234`, `i32:-5`, `f32:1.5`, `str:abc`, `hex:0102`
/// (`bool:`, `u8:` .. `u64:`, `i8:` .. `i64:`, `f64:` too).
pub fn encode_typed(text: &str) -> Result<Vec<u8>, ValueError> {
    let Some((ty, value)) = text.split_once(':') else { return Err(ValueError::Untyped(text.to_owned())) };
    let dt = match ty {
        "bool" => DataType::Boolean,
        "u8" => DataType::Unsigned8,
        "u16" => DataType::Unsigned16,
        "u24" => DataType::Unsigned24,
        "u32" => DataType::Unsigned32,
        "u64" => DataType::Unsigned64,
        "i8" => DataType::Integer8,
        "i16" => DataType::Integer16,
        "i24" => DataType::Integer24,
        "i32" => DataType::Integer32,
        "i64" => DataType::Integer64,
        "f32" => DataType::Real32,
        "f64" => DataType::Real64,
        "str" => DataType::VisibleString,
        "hex" => DataType::Domain,
        _ => return Err(ValueError::Untyped(text.to_owned())),
    };
    encode(value, dt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use DataType::*;

    const INTS: [DataType; 17] = [
        Boolean, Integer8, Integer16, Integer24, Integer32, Integer40, Integer48, Integer56, Integer64, Unsigned8,
        Unsigned16, Unsigned24, Unsigned32, Unsigned40, Unsigned48, Unsigned56, Unsigned64,
    ];

    #[test]
    fn every_integer_type_round_trips_its_bounds_and_refuses_one_beyond() {
        for dt in INTS {
            let (low, high) = range(dt).unwrap();
            for v in [low, high, low + (high - low) / 3] {
                let bytes = encode(&v.to_string(), dt).unwrap();
                assert_eq!(bytes.len(), width(dt).unwrap());
                assert_eq!(show(&bytes, Some(dt), 0x2000, 0), Shown::Int(v), "{dt:?} {v}");
            }
            for v in [low - 1, high + 1] {
                assert!(matches!(encode(&v.to_string(), dt), Err(ValueError::Range { .. })), "{dt:?} {v}");
            }
        }
    }

    #[test]
    fn strings_domains_and_reals() {
        assert_eq!(encode("abc", VisibleString).unwrap(), b"abc");
        assert_eq!(show(b"abc\0", Some(VisibleString), 0x1008, 0), Shown::Text("abc".into()));
        assert_eq!(encode("01 02ff", Domain).unwrap(), [1, 2, 0xff]);
        assert_eq!(show(&[1, 2, 0xff], Some(Domain), 0x2000, 0).text(), "0102ff");
        assert!(encode("012", Domain).is_err());
        assert_eq!(show(&encode("1.5", Real32).unwrap(), Some(Real32), 0x2000, 0), Shown::Real(1.5));
        assert_eq!(show(&[0x81, 1, 0, 0], Some(Unsigned32), 0x1800, 1).text(), "0x00000181");
        assert_eq!(encode("0x10", Unsigned8).unwrap(), [0x10]);
    }

    #[test]
    fn typed_values_without_an_eds() {
        assert_eq!(encode_typed("u16:1234").unwrap(), 1234u16.to_le_bytes());
        assert_eq!(encode_typed("i32:-5").unwrap(), (-5i32).to_le_bytes());
        assert_eq!(encode_typed("str:abc").unwrap(), b"abc");
        assert_eq!(encode_typed("hex:0102").unwrap(), [1, 2]);
        assert!(matches!(encode_typed("1234"), Err(ValueError::Untyped(_))));
        assert!(matches!(encode_typed("u8:256"), Err(ValueError::Range { .. })));
        assert!(matches!(encode_typed("q8:1"), Err(ValueError::Untyped(_))));
    }
}
