//! PDOs on the master side: a mapping configured at run time, checked by the same rules the
//! device applies ([`crate::pdo::check_mapping`]), that packs values into an RPDO's data and
//! unpacks a TPDO's.
//!
//! Values are [`PdoValue`]s typed by each mapped object's data type: unsigned and BOOLEAN
//! fields take [`PdoValue::Unsigned`], signed ones [`PdoValue::Signed`] (sign-extended from
//! their bit length when decoded), REAL32/REAL64 their float, strings and DOMAIN
//! [`PdoValue::Bytes`]. Dummy entries (index 0001h..0007h) are sent as zeros and decoded like
//! any field of their type.

use crate::od::{AbortCode, Access, DataType};
use crate::pdo::{Direction, MapEntry, Mappable, check_mapping, get_bits, put_bits};

/// One mapped field: where it comes from and its data type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PdoField {
    /// Index, sub-index and length in bits.
    pub entry: MapEntry,
    /// The data type of the mapped object.
    pub data_type: DataType,
}

/// A field's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PdoValue {
    /// BOOLEAN, UNSIGNEDn, TIME_OF_DAY and TIME_DIFFERENCE (raw 48 bits).
    Unsigned(u64),
    /// INTEGERn.
    Signed(i64),
    /// REAL32.
    Real32(f32),
    /// REAL64.
    Real64(f64),
    /// VISIBLE_STRING, OCTET_STRING, UNICODE_STRING, DOMAIN: `len` bytes of `data` (zero
    /// padded to the field's length when encoded).
    Bytes {
        /// The bytes (those past `len` are zero).
        data: [u8; 8],
        /// How many bytes are used.
        len: u8,
    },
}

/// Why a mapping or a value was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PdoError {
    /// The mapping breaks a CiA 301 rule; the abort code the device would answer with.
    Mapping(AbortCode),
    /// More entries than the mapping's capacity `N`.
    TooManyEntries,
    /// A number of values different from the number of fields.
    ValueCount,
    /// Field `field` was given a value of the wrong kind for its data type.
    WrongKind {
        /// The field's position in the mapping.
        field: usize,
    },
    /// Field `field`'s value does not fit in its bit length.
    OutOfRange {
        /// The field's position in the mapping.
        field: usize,
    },
    /// The PDO's data is shorter than the mapping.
    TooShort {
        /// Bytes received.
        len: usize,
        /// Bytes the mapping needs.
        needed: usize,
    },
}

impl core::fmt::Display for PdoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PdoError::Mapping(c) => write!(f, "mapping refused: {c}"),
            PdoError::TooManyEntries => write!(f, "more mapping entries than the mapping can hold"),
            PdoError::ValueCount => write!(f, "the number of values differs from the number of mapped fields"),
            PdoError::WrongKind { field } => write!(f, "field {field}: value of the wrong kind for its data type"),
            PdoError::OutOfRange { field } => write!(f, "field {field}: value does not fit in its bit length"),
            PdoError::TooShort { len, needed } => write!(f, "PDO of {len} bytes, its mapping needs {needed}"),
        }
    }
}

/// A PDO mapping of up to `N` fields (at most 64 bits in all).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoMapping<const N: usize = 8> {
    fields: [PdoField; N],
    len: usize,
    bits: u32,
}

const EMPTY: PdoField = PdoField { entry: MapEntry { index: 0, sub: 0, bits: 0 }, data_type: DataType::Unsigned8 };

impl<const N: usize> PdoMapping<N> {
    /// The mapping values `0xIIIISSLL` (the mapping object's sub-indices 1..=n) for a PDO of
    /// direction `dir`, checked against the mapped objects' descriptions from `lookup` (from
    /// the node's EDS, say) by the device's own rules.
    pub fn new(
        dir: Direction,
        values: &[u32],
        mut lookup: impl FnMut(u16, u8) -> Result<Mappable, AbortCode>,
    ) -> Result<Self, PdoError> {
        if values.len() > N {
            return Err(PdoError::TooManyEntries);
        }
        let bits = check_mapping(dir, values, &mut lookup).map_err(PdoError::Mapping)?;
        let mut fields = [EMPTY; N];
        for (f, &v) in fields.iter_mut().zip(values) {
            let entry = MapEntry::decode(v);
            let data_type = match DataType::from_index(entry.index) {
                Some(t) if entry.is_dummy() => t,
                _ => lookup(entry.index, entry.sub).map_err(PdoError::Mapping)?.data_type,
            };
            *f = PdoField { entry, data_type };
        }
        Ok(Self { fields, len: values.len(), bits })
    }

    /// A mapping from fields given with their types, checked by the same rules as if each
    /// object were mappable in both directions with exactly the field's length (a string or
    /// DOMAIN field's length is its capacity).
    pub fn from_fields(dir: Direction, fields: &[PdoField]) -> Result<Self, PdoError> {
        if fields.len() > N {
            return Err(PdoError::TooManyEntries);
        }
        let mut values = [0u32; N];
        for (v, f) in values.iter_mut().zip(fields) {
            *v = f.entry.encode();
        }
        let lookup = |index: u16, sub: u8| {
            let f = fields.iter().find(|f| f.entry.index == index && f.entry.sub == sub).ok_or(AbortCode::NO_OBJECT)?;
            let bits = if f.data_type.is_variable_length() { u32::from(f.entry.bits) } else { f.data_type.bits() };
            Ok(Mappable { data_type: f.data_type, access: Access::Rw, pdo_mappable: true, bits })
        };
        let mapping = Self::new(dir, &values[..fields.len()], lookup)?;
        // A dummy entry's type is its index; a field that says otherwise is a mistake.
        match mapping.fields().iter().zip(fields).position(|(m, f)| m.data_type != f.data_type) {
            Some(_) => Err(PdoError::Mapping(AbortCode::PARAMETER_INCOMPATIBLE)),
            None => Ok(mapping),
        }
    }

    /// The mapped fields in order.
    pub fn fields(&self) -> &[PdoField] {
        &self.fields[..self.len]
    }

    /// The mapping values to write to the mapping object's sub-indices 1..=n.
    pub fn values(&self) -> impl Iterator<Item = u32> + '_ {
        self.fields().iter().map(|f| f.entry.encode())
    }

    /// Length of the mapping in bits.
    pub const fn bits(&self) -> u32 {
        self.bits
    }

    /// Length of the PDO in bytes.
    pub const fn byte_len(&self) -> usize {
        self.bits.div_ceil(8) as usize
    }

    /// Packs one value per field into the PDO's data; returns it and its length in bytes.
    pub fn encode(&self, values: &[PdoValue]) -> Result<([u8; 8], usize), PdoError> {
        if values.len() != self.len {
            return Err(PdoError::ValueCount);
        }
        let mut data = [0u8; 8];
        let mut offset = 0u32;
        for (i, (f, v)) in self.fields().iter().zip(values).enumerate() {
            let bits = u32::from(f.entry.bits);
            if !f.entry.is_dummy() {
                let raw = raw_bits(f, *v).map_err(|e| e.at(i))?;
                put_bits(&mut data, offset, bits, &raw);
            }
            offset += bits;
        }
        Ok((data, self.byte_len()))
    }

    /// The value of field `i` in a received PDO's `data` (which may be longer than the
    /// mapping, never shorter).
    pub fn get(&self, data: &[u8], i: usize) -> Result<PdoValue, PdoError> {
        let needed = self.byte_len();
        if data.len() < needed {
            return Err(PdoError::TooShort { len: data.len(), needed });
        }
        let f = self.fields().get(i).ok_or(PdoError::ValueCount)?;
        let offset: u32 = self.fields()[..i].iter().map(|f| u32::from(f.entry.bits)).sum();
        let mut src = [0u8; 8];
        let n = data.len().min(8);
        src[..n].copy_from_slice(&data[..n]);
        let mut raw = [0u8; 8];
        let bytes = get_bits(&src, offset, u32::from(f.entry.bits), &mut raw);
        Ok(value_of(f, raw, bytes))
    }

    /// Unpacks every field of a received PDO's `data` into `out` (at least one slot per
    /// field); returns the number of fields.
    pub fn decode(&self, data: &[u8], out: &mut [PdoValue]) -> Result<usize, PdoError> {
        if out.len() < self.len {
            return Err(PdoError::ValueCount);
        }
        for (i, slot) in out.iter_mut().take(self.len).enumerate() {
            *slot = self.get(data, i)?;
        }
        Ok(self.len)
    }
}

impl PdoError {
    fn at(self, field: usize) -> Self {
        match self {
            PdoError::WrongKind { .. } => PdoError::WrongKind { field },
            PdoError::OutOfRange { .. } => PdoError::OutOfRange { field },
            e => e,
        }
    }
}

/// The low `bits` bits of a value, little-endian, after checking that it fits.
fn raw_bits(f: &PdoField, v: PdoValue) -> Result<[u8; 8], PdoError> {
    let bits = u32::from(f.entry.bits);
    let t = f.data_type;
    let wrong = PdoError::WrongKind { field: 0 };
    let range = PdoError::OutOfRange { field: 0 };
    match v {
        PdoValue::Unsigned(u) if !t.is_signed() && t.is_integer() => {
            if bits < 64 && u >> bits != 0 {
                return Err(range);
            }
            Ok(u.to_le_bytes())
        }
        PdoValue::Unsigned(u) if matches!(t, DataType::TimeOfDay | DataType::TimeDifference) => {
            if bits < 64 && u >> bits != 0 {
                return Err(range);
            }
            Ok(u.to_le_bytes())
        }
        PdoValue::Signed(s) if t.is_signed() => {
            if bits < 64 {
                let min = -(1i64 << (bits - 1));
                let max = (1i64 << (bits - 1)) - 1;
                if s < min || s > max {
                    return Err(range);
                }
            }
            Ok(s.to_le_bytes())
        }
        PdoValue::Real32(x) if t == DataType::Real32 => {
            let mut b = [0u8; 8];
            b[..4].copy_from_slice(&x.to_le_bytes());
            Ok(b)
        }
        PdoValue::Real64(x) if t == DataType::Real64 => Ok(x.to_le_bytes()),
        PdoValue::Bytes { data, len } if t.is_variable_length() => {
            if u32::from(len) * 8 > bits || len > 8 {
                return Err(range);
            }
            let mut b = [0u8; 8];
            b[..usize::from(len)].copy_from_slice(&data[..usize::from(len)]);
            Ok(b)
        }
        _ => Err(wrong),
    }
}

fn value_of(f: &PdoField, raw: [u8; 8], bytes: usize) -> PdoValue {
    let bits = u32::from(f.entry.bits);
    let u = u64::from_le_bytes(raw);
    let t = f.data_type;
    match t {
        DataType::Real32 => PdoValue::Real32(f32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]])),
        DataType::Real64 => PdoValue::Real64(f64::from_le_bytes(raw)),
        _ if t.is_variable_length() => PdoValue::Bytes { data: raw, len: bytes as u8 },
        _ if t.is_signed() => {
            let shift = 64 - bits.clamp(1, 64);
            PdoValue::Signed(((u << shift) as i64) >> shift)
        }
        _ => PdoValue::Unsigned(u),
    }
}
