//! The typed object-dictionary model that every other part of the project consumes.
//!
//! A [`Model`] is what an EDS or DCF *means*, independent of how it was spelled. It is plain
//! serde data in one canonical form (sorted maps), so it can be dumped, compared and
//! snapshot-tested. The code generator sees only this type.
//!
//! Uniform cells: every readable/writable cell of the dictionary is an [`Entry`] at an
//! `(index, sub-index)`. A VAR (or DOMAIN/DEFTYPE) object holds exactly one entry at sub-index 0;
//! ARRAY, RECORD and DEFSTRUCT objects hold one entry per sub-object.
//!
//! Source locations ([`SourceRef`]) are carried for diagnostics but do not take part in
//! equality: a model read from a file equals the same model built in code.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

pub use crate::name::Name;
use crate::source::Span;

/// An object index (0x0000..=0xFFFF).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Index(pub u16);

/// A sub-index (0x00..=0xFF).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct SubIndex(pub u8);

impl fmt::Display for Index {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:04X}", self.0)
    }
}

impl fmt::Display for SubIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// Where something was written in its source file. Ignored by `==` (see the module docs).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
pub struct SourceRef {
    /// 1-based line of the section header or key.
    pub line: u32,
    /// 1-based column.
    pub col: u32,
    /// Byte span in the decoded text.
    pub span: Span,
}

impl PartialEq for SourceRef {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// CiA 301 object codes (`ObjectType=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ObjectType {
    /// 0x0: no data fields.
    Null,
    /// 0x2: large variable amount of data.
    Domain,
    /// 0x5: a type definition (BOOLEAN, UNSIGNED8, ...).
    DefType,
    /// 0x6: a record type definition.
    DefStruct,
    /// 0x7: a single value.
    Var,
    /// 0x8: several values of one type, sub-index 0 holds the count.
    Array,
    /// 0x9: several values of possibly different types.
    Record,
}

impl ObjectType {
    /// The CiA 306 code.
    pub const fn code(self) -> u8 {
        match self {
            ObjectType::Null => 0x0,
            ObjectType::Domain => 0x2,
            ObjectType::DefType => 0x5,
            ObjectType::DefStruct => 0x6,
            ObjectType::Var => 0x7,
            ObjectType::Array => 0x8,
            ObjectType::Record => 0x9,
        }
    }

    /// The object type for a CiA 306 code.
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x0 => ObjectType::Null,
            0x2 => ObjectType::Domain,
            0x5 => ObjectType::DefType,
            0x6 => ObjectType::DefStruct,
            0x7 => ObjectType::Var,
            0x8 => ObjectType::Array,
            0x9 => ObjectType::Record,
            _ => return None,
        })
    }

    /// Whether objects of this type have sub-objects (and sub-index 0 is the count).
    pub const fn has_subs(self) -> bool {
        matches!(self, ObjectType::Array | ObjectType::Record | ObjectType::DefStruct)
    }
}

/// CiA 301 data types (the index of their DEFTYPE object, `DataType=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum DataType {
    /// 0x0001
    Boolean,
    /// 0x0002
    Integer8,
    /// 0x0003
    Integer16,
    /// 0x0004
    Integer32,
    /// 0x0005
    Unsigned8,
    /// 0x0006
    Unsigned16,
    /// 0x0007
    Unsigned32,
    /// 0x0008
    Real32,
    /// 0x0009
    VisibleString,
    /// 0x000A
    OctetString,
    /// 0x000B
    UnicodeString,
    /// 0x000C
    TimeOfDay,
    /// 0x000D
    TimeDifference,
    /// 0x000F
    Domain,
    /// 0x0010
    Integer24,
    /// 0x0011
    Real64,
    /// 0x0012
    Integer40,
    /// 0x0013
    Integer48,
    /// 0x0014
    Integer56,
    /// 0x0015
    Integer64,
    /// 0x0016
    Unsigned24,
    /// 0x0018
    Unsigned40,
    /// 0x0019
    Unsigned48,
    /// 0x001A
    Unsigned56,
    /// 0x001B
    Unsigned64,
    /// Any other type index: complex types (0x0020.. PDO_COMMUNICATION_PARAMETER, ...) and
    /// manufacturer or profile-defined types.
    Other(u16),
}

impl DataType {
    /// Every basic (non-`Other`) type, in code order.
    pub const BASIC: [DataType; 25] = [
        DataType::Boolean,
        DataType::Integer8,
        DataType::Integer16,
        DataType::Integer32,
        DataType::Unsigned8,
        DataType::Unsigned16,
        DataType::Unsigned32,
        DataType::Real32,
        DataType::VisibleString,
        DataType::OctetString,
        DataType::UnicodeString,
        DataType::TimeOfDay,
        DataType::TimeDifference,
        DataType::Domain,
        DataType::Integer24,
        DataType::Real64,
        DataType::Integer40,
        DataType::Integer48,
        DataType::Integer56,
        DataType::Integer64,
        DataType::Unsigned24,
        DataType::Unsigned40,
        DataType::Unsigned48,
        DataType::Unsigned56,
        DataType::Unsigned64,
    ];

    /// The CiA 301 type index.
    pub const fn code(self) -> u16 {
        match self {
            DataType::Boolean => 0x01,
            DataType::Integer8 => 0x02,
            DataType::Integer16 => 0x03,
            DataType::Integer32 => 0x04,
            DataType::Unsigned8 => 0x05,
            DataType::Unsigned16 => 0x06,
            DataType::Unsigned32 => 0x07,
            DataType::Real32 => 0x08,
            DataType::VisibleString => 0x09,
            DataType::OctetString => 0x0A,
            DataType::UnicodeString => 0x0B,
            DataType::TimeOfDay => 0x0C,
            DataType::TimeDifference => 0x0D,
            DataType::Domain => 0x0F,
            DataType::Integer24 => 0x10,
            DataType::Real64 => 0x11,
            DataType::Integer40 => 0x12,
            DataType::Integer48 => 0x13,
            DataType::Integer56 => 0x14,
            DataType::Integer64 => 0x15,
            DataType::Unsigned24 => 0x16,
            DataType::Unsigned40 => 0x18,
            DataType::Unsigned48 => 0x19,
            DataType::Unsigned56 => 0x1A,
            DataType::Unsigned64 => 0x1B,
            DataType::Other(c) => c,
        }
    }

    /// The data type for a type index.
    pub fn from_code(code: u16) -> Self {
        // A table by code (built at compile time from `BASIC`): a file names a type for almost
        // every entry, and a search through `BASIC` cost a jump per candidate.
        const BY_CODE: [Option<DataType>; 0x1C] = {
            let mut table = [None; 0x1C];
            let mut i = 0;
            while i < DataType::BASIC.len() {
                let t = DataType::BASIC[i];
                table[t.code() as usize] = Some(t);
                i += 1;
            }
            table
        };
        match BY_CODE.get(code as usize) {
            Some(&Some(t)) => t,
            _ => DataType::Other(code),
        }
    }

    /// The CiA 301 name (`UNSIGNED32`, ...).
    pub fn name(self) -> &'static str {
        match self {
            DataType::Boolean => "BOOLEAN",
            DataType::Integer8 => "INTEGER8",
            DataType::Integer16 => "INTEGER16",
            DataType::Integer32 => "INTEGER32",
            DataType::Unsigned8 => "UNSIGNED8",
            DataType::Unsigned16 => "UNSIGNED16",
            DataType::Unsigned32 => "UNSIGNED32",
            DataType::Real32 => "REAL32",
            DataType::VisibleString => "VISIBLE_STRING",
            DataType::OctetString => "OCTET_STRING",
            DataType::UnicodeString => "UNICODE_STRING",
            DataType::TimeOfDay => "TIME_OF_DAY",
            DataType::TimeDifference => "TIME_DIFFERENCE",
            DataType::Domain => "DOMAIN",
            DataType::Integer24 => "INTEGER24",
            DataType::Real64 => "REAL64",
            DataType::Integer40 => "INTEGER40",
            DataType::Integer48 => "INTEGER48",
            DataType::Integer56 => "INTEGER56",
            DataType::Integer64 => "INTEGER64",
            DataType::Unsigned24 => "UNSIGNED24",
            DataType::Unsigned40 => "UNSIGNED40",
            DataType::Unsigned48 => "UNSIGNED48",
            DataType::Unsigned56 => "UNSIGNED56",
            DataType::Unsigned64 => "UNSIGNED64",
            DataType::Other(_) => "OTHER",
        }
    }

    /// Size in bits of a fixed-size type (`None` for strings, DOMAIN and `Other`).
    pub const fn bits(self) -> Option<u32> {
        Some(match self {
            DataType::Boolean => 1,
            DataType::Integer8 | DataType::Unsigned8 => 8,
            DataType::Integer16 | DataType::Unsigned16 => 16,
            DataType::Integer24 | DataType::Unsigned24 => 24,
            DataType::Integer32 | DataType::Unsigned32 | DataType::Real32 => 32,
            DataType::Integer40 | DataType::Unsigned40 => 40,
            DataType::Integer48 | DataType::Unsigned48 | DataType::TimeOfDay | DataType::TimeDifference => 48,
            DataType::Integer56 | DataType::Unsigned56 => 56,
            DataType::Integer64 | DataType::Unsigned64 | DataType::Real64 => 64,
            _ => return None,
        })
    }

    /// Whether this is a signed integer type.
    pub const fn is_signed(self) -> bool {
        matches!(
            self,
            DataType::Integer8
                | DataType::Integer16
                | DataType::Integer24
                | DataType::Integer32
                | DataType::Integer40
                | DataType::Integer48
                | DataType::Integer56
                | DataType::Integer64
        )
    }

    /// Whether this is an unsigned integer type (BOOLEAN excluded).
    pub const fn is_unsigned(self) -> bool {
        matches!(
            self,
            DataType::Unsigned8
                | DataType::Unsigned16
                | DataType::Unsigned24
                | DataType::Unsigned32
                | DataType::Unsigned40
                | DataType::Unsigned48
                | DataType::Unsigned56
                | DataType::Unsigned64
        )
    }

    /// Whether this is REAL32 or REAL64.
    pub const fn is_real(self) -> bool {
        matches!(self, DataType::Real32 | DataType::Real64)
    }

    /// The inclusive value range of an integer type (BOOLEAN is 0..=1).
    pub fn int_range(self) -> Option<(i128, i128)> {
        let bits = self.bits()? as i128;
        if self == DataType::Boolean {
            Some((0, 1))
        } else if self.is_signed() {
            Some((-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1))
        } else if self.is_unsigned() {
            Some((0, (1i128 << bits) - 1))
        } else {
            None
        }
    }
}

/// Access type (`AccessType=`, any case in files).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Access {
    /// Read only (value may change, e.g. statusword).
    Ro,
    /// Write only.
    Wo,
    /// Read and write.
    Rw,
    /// Read and write, mappable into a TPDO (read on process input).
    Rwr,
    /// Read and write, mappable into an RPDO (write on process output).
    Rww,
    /// Read only, value never changes.
    Const,
}

impl Access {
    /// The canonical (lower-case) spelling.
    pub const fn as_str(self) -> &'static str {
        match self {
            Access::Ro => "ro",
            Access::Wo => "wo",
            Access::Rw => "rw",
            Access::Rwr => "rwr",
            Access::Rww => "rww",
            Access::Const => "const",
        }
    }

    /// Parses a spelling, any case, surrounding white space ignored. Every entry of a file has
    /// an AccessType, so this allocates nothing and tells the six spellings apart by their
    /// letters rather than comparing them one after another.
    pub fn parse(s: &str) -> Option<Self> {
        // The spellings of CiA 306 itself, which nearly every file uses, compared as they are.
        match s.as_bytes() {
            b"ro" => return Some(Access::Ro),
            b"rw" => return Some(Access::Rw),
            b"wo" => return Some(Access::Wo),
            b"const" => return Some(Access::Const),
            _ => {}
        }
        let lower = |b: &u8| b.to_ascii_lowercase();
        match crate::lex::trim(s).as_bytes() {
            [a, b] => match (lower(a), lower(b)) {
                (b'r', b'o') => Some(Access::Ro),
                (b'w', b'o') => Some(Access::Wo),
                (b'r', b'w') => Some(Access::Rw),
                _ => None,
            },
            [a, b, c] => match (lower(a), lower(b), lower(c)) {
                (b'r', b'w', b'r') => Some(Access::Rwr),
                (b'r', b'w', b'w') => Some(Access::Rww),
                _ => None,
            },
            t @ [_, _, _, _, _] if t.eq_ignore_ascii_case(b"const") => Some(Access::Const),
            _ => None,
        }
    }

    /// Whether an SDO client may read the entry.
    pub const fn readable(self) -> bool {
        !matches!(self, Access::Wo)
    }

    /// Whether an SDO client may write the entry.
    pub const fn writable(self) -> bool {
        matches!(self, Access::Wo | Access::Rw | Access::Rwr | Access::Rww)
    }

    /// Whether the entry may be mapped into an RPDO (the master writes it).
    pub const fn rpdo_ok(self) -> bool {
        matches!(self, Access::Wo | Access::Rw | Access::Rww)
    }

    /// Whether the entry may be mapped into a TPDO (the device sends it).
    pub const fn tpdo_ok(self) -> bool {
        matches!(self, Access::Ro | Access::Rw | Access::Rwr | Access::Const)
    }
}

/// The radix a number was written in, kept so that a rewritten file reads the same.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Radix {
    /// Decimal.
    #[default]
    Dec,
    /// `0x` hexadecimal.
    Hex,
    /// CiA 306 octal (a leading `0`).
    Oct,
}

/// A typed value (DefaultValue, ParameterValue, LowLimit, HighLimit).
///
/// `$NODEID` stays symbolic ([`Value::NodeIdPlus`]) until [`Value::resolve`] is given a node id.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Value {
    /// An integer (all integer types, BOOLEAN as 0/1).
    Int {
        /// The value.
        value: i128,
        /// How it was written.
        radix: Radix,
    },
    /// `$NODEID + offset` (written in either order, any case, with or without spaces).
    NodeIdPlus {
        /// The constant part (may be 0 or negative).
        offset: i128,
        /// How the constant part was written.
        radix: Radix,
    },
    /// A REAL32/REAL64 value.
    Real(f64),
    /// A VISIBLE_STRING or UNICODE_STRING value.
    Text(String),
    /// An OCTET_STRING or DOMAIN value (written as hex digits; serialised as one string of
    /// upper-case hex digits, two per byte, not as a list of numbers: a 50 MB value made a
    /// gigabyte of JSON that way).
    Bytes(#[serde(with = "hex_bytes")] Vec<u8>),
}

/// Serde form of [`Value::Bytes`]: a string of hex digits (a list of numbers is read too).
mod hex_bytes {
    use serde::de::{self, Deserializer, SeqAccess, Visitor};
    use serde::ser::Serializer;

    pub fn serialize<S: Serializer>(bytes: &[u8], serializer: S) -> Result<S::Ok, S::Error> {
        const HEX: &[u8; 16] = b"0123456789ABCDEF";
        let mut text = String::with_capacity(bytes.len() * 2);
        for &b in bytes {
            text.push(HEX[(b >> 4) as usize] as char);
            text.push(HEX[(b & 15) as usize] as char);
        }
        serializer.serialize_str(&text)
    }

    struct Hex;

    impl<'de> Visitor<'de> for Hex {
        type Value = Vec<u8>;

        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("a string of hex digits, two per byte")
        }

        fn visit_str<E: de::Error>(self, v: &str) -> Result<Vec<u8>, E> {
            if !v.len().is_multiple_of(2) {
                return Err(E::custom("an odd number of hex digits"));
            }
            v.as_bytes()
                .chunks_exact(2)
                .map(|p| {
                    std::str::from_utf8(p)
                        .ok()
                        .and_then(|p| u8::from_str_radix(p, 16).ok())
                        .ok_or_else(|| E::custom("not a hex digit"))
                })
                .collect()
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<u8>, A::Error> {
            let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 16));
            while let Some(b) = seq.next_element::<u8>()? {
                out.push(b);
            }
            Ok(out)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<u8>, D::Error> {
        deserializer.deserialize_any(Hex)
    }
}

impl Value {
    /// A decimal integer.
    pub const fn int(value: i128) -> Self {
        Value::Int { value, radix: Radix::Dec }
    }

    /// A hexadecimal integer.
    pub const fn hex(value: i128) -> Self {
        Value::Int { value, radix: Radix::Hex }
    }

    /// Whether the value depends on the node id.
    pub const fn is_node_relative(&self) -> bool {
        matches!(self, Value::NodeIdPlus { .. })
    }

    /// The integer this value stands for on node `node_id` (`None` for non-integers).
    pub fn resolve(&self, node_id: u8) -> Option<i128> {
        match *self {
            Value::Int { value, .. } => Some(value),
            Value::NodeIdPlus { offset, .. } => Some(offset + node_id as i128),
            _ => None,
        }
    }

    /// The integer, if the value is a plain integer (no `$NODEID`).
    pub fn as_int(&self) -> Option<i128> {
        match *self {
            Value::Int { value, .. } => Some(value),
            _ => None,
        }
    }
}

/// Which object list names an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Category {
    /// `[MandatoryObjects]`
    Mandatory,
    /// `[OptionalObjects]`
    Optional,
    /// `[ManufacturerObjects]`
    Manufacturer,
}

/// One cell of the dictionary: an `(index, sub-index)` with a type and a value.
///
/// The keys most entries have are fields; the ones few entries have (ParameterValue, limits,
/// ObjFlags, Denotation, UploadFile, DownloadFile, unknown keys) are in one boxed
/// [`EntryExtras`], read through the methods of the same names, so that an entry without them
/// (most of the tens of thousands a large file has) is 96 bytes rather than 288. It is
/// serialised flat, with every key, as if all were fields.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(from = "EntryRepr", into = "EntryRepr")]
pub struct Entry {
    /// Sub-index (0 for a VAR object).
    pub sub: SubIndex,
    /// `ParameterName`.
    pub name: Name,
    /// `DataType`.
    pub data_type: DataType,
    /// `AccessType`.
    pub access: Access,
    /// `PDOMapping`.
    pub pdo_mapping: bool,
    /// `DefaultValue` (the EDS default).
    pub default: Option<Value>,
    /// The rarely set keys (`None`: none of them is set). Read them with
    /// [`Entry::parameter_value`] and its siblings, set them through [`Entry::extras_mut`].
    pub extras: Option<Box<EntryExtras>>,
    /// Where the section was written.
    pub at: SourceRef,
}

/// The keys of an [`Entry`] that few entries have.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EntryExtras {
    /// `ParameterValue` (a DCF's configured value).
    pub parameter_value: Option<Value>,
    /// `LowLimit`.
    pub low_limit: Option<Value>,
    /// `HighLimit`.
    pub high_limit: Option<Value>,
    /// `ObjFlags` (bit 0: refuse write on download, bit 1: refuse read on scan).
    pub obj_flags: Option<u32>,
    /// `Denotation` (DCF; the project also uses it for vendor ASCII parameter names).
    pub denotation: Option<String>,
    /// `UploadFile` (DOMAIN).
    pub upload_file: Option<String>,
    /// `DownloadFile` (DOMAIN).
    pub download_file: Option<String>,
    /// Keys this crate does not interpret, as written, in file order.
    pub extra: Vec<(String, String)>,
}

/// No extras at all, boxed or not.
static NO_EXTRAS: EntryExtras = EntryExtras {
    parameter_value: None,
    low_limit: None,
    high_limit: None,
    obj_flags: None,
    denotation: None,
    upload_file: None,
    download_file: None,
    extra: Vec::new(),
};

impl EntryExtras {
    /// Whether no key is set (the same as having no extras).
    pub fn is_empty(&self) -> bool {
        *self == NO_EXTRAS
    }
}

impl Entry {
    /// An entry with these fields, no default value, no extras and no source position.
    pub fn new(sub: u8, name: impl Into<Name>, data_type: DataType, access: Access) -> Self {
        Entry {
            sub: SubIndex(sub),
            name: name.into(),
            data_type,
            access,
            pdo_mapping: false,
            default: None,
            extras: None,
            at: SourceRef::default(),
        }
    }

    /// The rarely set keys, all `None` and empty when the entry has none.
    #[inline]
    pub fn extras(&self) -> &EntryExtras {
        self.extras.as_deref().unwrap_or(&NO_EXTRAS)
    }

    /// The rarely set keys, to change them (made on first use).
    pub fn extras_mut(&mut self) -> &mut EntryExtras {
        self.extras.get_or_insert_with(Default::default)
    }

    /// `ParameterValue` (a DCF's configured value).
    #[inline]
    pub fn parameter_value(&self) -> Option<&Value> {
        self.extras().parameter_value.as_ref()
    }

    /// `LowLimit`.
    #[inline]
    pub fn low_limit(&self) -> Option<&Value> {
        self.extras().low_limit.as_ref()
    }

    /// `HighLimit`.
    #[inline]
    pub fn high_limit(&self) -> Option<&Value> {
        self.extras().high_limit.as_ref()
    }

    /// `ObjFlags`.
    #[inline]
    pub fn obj_flags(&self) -> Option<u32> {
        self.extras().obj_flags
    }

    /// `Denotation`.
    #[inline]
    pub fn denotation(&self) -> Option<&str> {
        self.extras().denotation.as_deref()
    }

    /// `UploadFile`.
    #[inline]
    pub fn upload_file(&self) -> Option<&str> {
        self.extras().upload_file.as_deref()
    }

    /// `DownloadFile`.
    #[inline]
    pub fn download_file(&self) -> Option<&str> {
        self.extras().download_file.as_deref()
    }

    /// Keys this crate does not interpret, as written, in file order.
    #[inline]
    pub fn extra(&self) -> &[(String, String)] {
        &self.extras().extra
    }

    /// Sets `ParameterValue` (`None` removes it).
    pub fn set_parameter_value(&mut self, value: Option<Value>) {
        if value.is_some() || self.extras.is_some() {
            self.extras_mut().parameter_value = value;
        }
    }
}

/// Equal when every key is equal; no extras and empty extras are the same.
impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.sub == other.sub
            && self.name == other.name
            && self.data_type == other.data_type
            && self.access == other.access
            && self.pdo_mapping == other.pdo_mapping
            && self.default == other.default
            && self.at == other.at
            && self.extras() == other.extras()
    }
}

/// [`Entry`] as it is serialised: every key a field, in the order of the CiA 306 keywords.
#[derive(Clone, Serialize, Deserialize)]
struct EntryRepr {
    sub: SubIndex,
    name: Name,
    data_type: DataType,
    access: Access,
    pdo_mapping: bool,
    default: Option<Value>,
    parameter_value: Option<Value>,
    low_limit: Option<Value>,
    high_limit: Option<Value>,
    obj_flags: Option<u32>,
    denotation: Option<String>,
    upload_file: Option<String>,
    download_file: Option<String>,
    extra: Vec<(String, String)>,
    at: SourceRef,
}

impl From<EntryRepr> for Entry {
    fn from(r: EntryRepr) -> Self {
        let extras = EntryExtras {
            parameter_value: r.parameter_value,
            low_limit: r.low_limit,
            high_limit: r.high_limit,
            obj_flags: r.obj_flags,
            denotation: r.denotation,
            upload_file: r.upload_file,
            download_file: r.download_file,
            extra: r.extra,
        };
        Entry {
            sub: r.sub,
            name: r.name,
            data_type: r.data_type,
            access: r.access,
            pdo_mapping: r.pdo_mapping,
            default: r.default,
            extras: (!extras.is_empty()).then(|| Box::new(extras)),
            at: r.at,
        }
    }
}

impl From<Entry> for EntryRepr {
    fn from(e: Entry) -> Self {
        let x = e.extras.map(|b| *b).unwrap_or_default();
        EntryRepr {
            sub: e.sub,
            name: e.name,
            data_type: e.data_type,
            access: e.access,
            pdo_mapping: e.pdo_mapping,
            default: e.default,
            parameter_value: x.parameter_value,
            low_limit: x.low_limit,
            high_limit: x.high_limit,
            obj_flags: x.obj_flags,
            denotation: x.denotation,
            upload_file: x.upload_file,
            download_file: x.download_file,
            extra: x.extra,
            at: e.at,
        }
    }
}

/// A map kept as a vector sorted by key, with the methods of a `BTreeMap` (`get`, `insert`,
/// `values`, `keys`, `iter`, `range`, `len`, ...), iterated in key order, and serialised and
/// printed exactly like one. The model keeps its objects ([`ObjectMap`]) and the entries of each
/// object ([`SubMap`]) in one.
///
/// Files list their objects, and objects their entries, in ascending order almost always: then
/// every insertion is a push at the end, a lookup is a binary search through one contiguous
/// block, and dropping the map frees one allocation, where a B-tree searched from its root for
/// each insertion, spread its values over nodes of eleven, and walked them to free them.
/// Inserting out of order moves the later values up, as `Vec::insert` does.
///
/// ```
/// use canopen_eds::model::*;
/// let entry = |sub: u8| Entry { sub: SubIndex(sub), name: format!("Entry {sub}").into(),
///     data_type: DataType::Unsigned8, access: Access::Ro, pdo_mapping: false, default: None,
///     extras: None, at: SourceRef::default() };
/// let mut subs = SubMap::new();
/// subs.insert(SubIndex(2), entry(2));
/// subs.insert(SubIndex(0), entry(0));
/// assert_eq!(subs.keys().map(|s| s.0).collect::<Vec<_>>(), [0, 2]);
/// assert_eq!(subs[&SubIndex(2)].name, "Entry 2");
/// assert!(!subs.contains_key(&SubIndex(1)));
/// ```
#[derive(Clone, PartialEq)]
pub struct VecMap<K, V> {
    /// Sorted by key, no key twice. Each value holds its key ([`Keyed`]), so it is stored
    /// once: a `(SubIndex, Entry)` pair took 112 bytes (the entry's alignment padded the key to
    /// 16), an entry alone 96.
    entries: Vec<V>,
    key: std::marker::PhantomData<fn() -> K>,
}

/// A value that holds its own key (an [`Entry`] its sub-index, an [`Object`] its index), so
/// that a [`VecMap`] stores the key once. A map sets the key of each value it is given to the
/// key it is given with; changing a value's key in place (through `get_mut` or `values_mut`)
/// leaves the map out of order.
pub trait Keyed<K> {
    /// The key.
    fn key(&self) -> &K;
    /// Sets the key.
    fn set_key(&mut self, key: K);
}

impl Keyed<SubIndex> for Entry {
    #[inline]
    fn key(&self) -> &SubIndex {
        &self.sub
    }
    #[inline]
    fn set_key(&mut self, key: SubIndex) {
        self.sub = key;
    }
}

impl Keyed<Index> for Object {
    #[inline]
    fn key(&self) -> &Index {
        &self.index
    }
    #[inline]
    fn set_key(&mut self, key: Index) {
        self.index = key;
    }
}

/// The entries of an object by sub-index (see [`VecMap`]).
pub type SubMap = VecMap<SubIndex, Entry>;

/// The objects of a model by index (see [`VecMap`]).
pub type ObjectMap = VecMap<Index, Object>;

/// The iterator of [`SubMap::iter`].
pub type SubIter<'a> = MapIter<'a, SubIndex, Entry>;

impl<K, V> Default for VecMap<K, V> {
    fn default() -> Self {
        VecMap { entries: Vec::new(), key: std::marker::PhantomData }
    }
}

/// `value` with its key set to `key`.
#[inline]
fn keyed<K, V: Keyed<K>>(key: K, mut value: V) -> V {
    value.set_key(key);
    value
}

impl<K: Ord + Copy, V: Keyed<K>> VecMap<K, V> {
    /// An empty map (allocates nothing).
    pub const fn new() -> Self {
        VecMap { entries: Vec::new(), key: std::marker::PhantomData }
    }

    /// An empty map with room for `n` entries.
    pub fn with_capacity(n: usize) -> Self {
        VecMap { entries: Vec::with_capacity(n), key: std::marker::PhantomData }
    }

    /// A map of `values`, which may come in any order, each holding its key; of values with
    /// the same key the last one is kept, as collecting into a `BTreeMap` does. Values that
    /// come sorted (as lowering makes them, most of the time) are taken as they are, without
    /// moving them.
    pub(crate) fn from_values(mut values: Vec<V>) -> Self {
        if values.is_sorted_by(|a, b| a.key() < b.key()) {
            return VecMap { entries: values, key: std::marker::PhantomData };
        }
        // Stable: equal keys keep their order, so that the last of them can be kept. Repeats
        // are dropped in place (no second vector): of a run of equal keys, each later value
        // takes the place of the one kept so far.
        values.sort_by_key(|v| *v.key());
        values.dedup_by(|later, kept| {
            let same = later.key() == kept.key();
            if same {
                std::mem::swap(later, kept);
            }
            same
        });
        VecMap { entries: values, key: std::marker::PhantomData }
    }

    /// The values in key order, as the vector that holds them.
    pub(crate) fn into_values(self) -> Vec<V> {
        self.entries
    }

    /// A map of `values`, which may come in any order, each holding its own key, no key twice
    /// (as lowering makes the objects of a file: one per object section). Values not in order
    /// are sorted in place, without the buffer the stable sort of [`VecMap::from_values`]
    /// asks for (a block the size of half the values, of a size that changes with each file).
    pub(crate) fn from_unique_values(mut values: Vec<V>) -> Self {
        if !values.is_sorted_by(|a, b| a.key() < b.key()) {
            values.sort_unstable_by_key(|v| *v.key());
            debug_assert!(values.is_sorted_by(|a, b| a.key() < b.key()), "a key twice");
        }
        VecMap { entries: values, key: std::marker::PhantomData }
    }

    /// The number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Where `key` is, or where it would go.
    #[inline]
    fn find(&self, key: K) -> Result<usize, usize> {
        self.entries.binary_search_by_key(&key, |v| *v.key())
    }

    /// The value at `key`.
    #[inline]
    pub fn get(&self, key: &K) -> Option<&V> {
        self.find(*key).ok().map(|i| &self.entries[i])
    }

    /// The value at `key`, to change it.
    #[inline]
    pub fn get_mut(&mut self, key: &K) -> Option<&mut V> {
        self.find(*key).ok().map(|i| &mut self.entries[i])
    }

    /// The key and value at `key`.
    pub fn get_key_value(&self, key: &K) -> Option<(&K, &V)> {
        self.find(*key).ok().map(|i| (self.entries[i].key(), &self.entries[i]))
    }

    /// Whether there is a value at `key`.
    #[inline]
    pub fn contains_key(&self, key: &K) -> bool {
        self.find(*key).is_ok()
    }

    /// Puts `value` at `key` (setting its key to `key`) and returns the value that was there.
    /// Adding in key order costs no search.
    #[inline]
    pub fn insert(&mut self, key: K, value: V) -> Option<V> {
        if self.entries.last().is_none_or(|last| *last.key() < key) {
            self.entries.push(keyed(key, value));
            return None;
        }
        match self.find(key) {
            Ok(i) => Some(std::mem::replace(&mut self.entries[i], keyed(key, value))),
            Err(i) => {
                self.entries.insert(i, keyed(key, value));
                None
            }
        }
    }

    /// The value at `key`, after putting `make()` there if there was none (what
    /// `map.entry(key).or_insert_with(make)` does for a `BTreeMap`).
    pub fn get_or_insert_with(&mut self, key: K, make: impl FnOnce() -> V) -> &mut V {
        let i = match self.find(key) {
            Ok(i) => i,
            Err(i) => {
                self.entries.insert(i, keyed(key, make()));
                i
            }
        };
        &mut self.entries[i]
    }

    /// Takes out the value at `key`.
    pub fn remove(&mut self, key: &K) -> Option<V> {
        self.find(*key).ok().map(|i| self.entries.remove(i))
    }

    /// Keeps the entries for which `keep` says so.
    pub fn retain(&mut self, mut keep: impl FnMut(&K, &mut V) -> bool) {
        self.entries.retain_mut(|v| {
            let k = *v.key();
            keep(&k, v)
        });
    }

    /// Removes every entry.
    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// The entry with the lowest key.
    pub fn first_key_value(&self) -> Option<(&K, &V)> {
        self.entries.first().map(|v| (v.key(), v))
    }

    /// The entry with the highest key.
    pub fn last_key_value(&self) -> Option<(&K, &V)> {
        self.entries.last().map(|v| (v.key(), v))
    }

    /// The entries in key order.
    pub fn iter(&self) -> MapIter<'_, K, V> {
        MapIter(self.entries.iter(), std::marker::PhantomData)
    }

    /// The entries in key order, to change them (each key a copy: the value holds it).
    pub fn iter_mut(&mut self) -> impl DoubleEndedIterator<Item = (K, &mut V)> + ExactSizeIterator {
        self.entries.iter_mut().map(|v| (*v.key(), v))
    }

    /// The keys in order.
    pub fn keys(&self) -> impl DoubleEndedIterator<Item = &K> + ExactSizeIterator + Clone {
        self.entries.iter().map(|v| v.key())
    }

    /// The values in key order.
    pub fn values(&self) -> impl DoubleEndedIterator<Item = &V> + ExactSizeIterator + Clone {
        self.entries.iter()
    }

    /// The values in key order, to change them.
    pub fn values_mut(&mut self) -> impl DoubleEndedIterator<Item = &mut V> + ExactSizeIterator {
        self.entries.iter_mut()
    }

    /// The entries whose key lies in `range`, in order.
    pub fn range(&self, range: impl std::ops::RangeBounds<K>) -> MapIter<'_, K, V> {
        use std::ops::Bound;
        let from = match range.start_bound() {
            Bound::Included(k) => self.entries.partition_point(|v| v.key() < k),
            Bound::Excluded(k) => self.entries.partition_point(|v| v.key() <= k),
            Bound::Unbounded => 0,
        };
        let to = match range.end_bound() {
            Bound::Included(k) => self.entries.partition_point(|v| v.key() <= k),
            Bound::Excluded(k) => self.entries.partition_point(|v| v.key() < k),
            Bound::Unbounded => self.entries.len(),
        };
        MapIter(self.entries[from..to.max(from)].iter(), std::marker::PhantomData)
    }
}

impl VecMap<SubIndex, Entry> {
    /// Puts `make(k)` at every sub-index `k` of `keys`, in order (lowering builds the elements of
    /// a `CompactSubObj` array this way). When all of `keys` lie above the map's last key, the
    /// entries are made straight into the map's storage; otherwise each is inserted.
    pub(crate) fn extend_with(&mut self, keys: std::ops::RangeInclusive<u8>, mut make: impl FnMut(u8) -> Entry) {
        if self.entries.last().is_none_or(|last| last.sub.0 < *keys.start()) {
            self.entries.extend(keys.map(|k| keyed(SubIndex(k), make(k))));
        } else {
            for k in keys {
                self.insert(SubIndex(k), make(k));
            }
        }
    }
}

/// The iterator of [`VecMap::iter`]: `(&K, &V)` in key order.
#[derive(Debug)]
pub struct MapIter<'a, K, V>(std::slice::Iter<'a, V>, std::marker::PhantomData<fn() -> K>);

impl<K, V> Clone for MapIter<'_, K, V> {
    fn clone(&self) -> Self {
        MapIter(self.0.clone(), std::marker::PhantomData)
    }
}

impl<'a, K: 'a, V: Keyed<K>> Iterator for MapIter<'a, K, V> {
    type Item = (&'a K, &'a V);

    #[inline]
    fn next(&mut self) -> Option<Self::Item> {
        self.0.next().map(|v| (v.key(), v))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.0.size_hint()
    }
}

impl<'a, K: 'a, V: Keyed<K>> DoubleEndedIterator for MapIter<'a, K, V> {
    fn next_back(&mut self) -> Option<Self::Item> {
        self.0.next_back().map(|v| (v.key(), v))
    }
}

impl<'a, K: 'a, V: Keyed<K>> ExactSizeIterator for MapIter<'a, K, V> {}

impl<'a, K: 'a, V: Keyed<K>> std::iter::FusedIterator for MapIter<'a, K, V> {}

impl<K: Ord + Copy + fmt::Debug, V: Keyed<K>> std::ops::Index<&K> for VecMap<K, V> {
    type Output = V;

    /// The value at `key`. Panics if there is none, as indexing a `BTreeMap` does; use
    /// [`VecMap::get`] for keys that may be missing.
    fn index(&self, key: &K) -> &V {
        match self.get(key) {
            Some(v) => v,
            None => panic!("no entry at {key:?}"),
        }
    }
}

impl<K: Ord + Copy, V: Keyed<K>> FromIterator<(K, V)> for VecMap<K, V> {
    /// Collects entries in any order; of entries with the same key the last one is kept, as
    /// collecting into a `BTreeMap` does.
    fn from_iter<I: IntoIterator<Item = (K, V)>>(iter: I) -> Self {
        VecMap::from_values(iter.into_iter().map(|(k, v)| keyed(k, v)).collect())
    }
}

impl<K: Ord + Copy, V: Keyed<K>> Extend<(K, V)> for VecMap<K, V> {
    fn extend<I: IntoIterator<Item = (K, V)>>(&mut self, iter: I) {
        let iter = iter.into_iter();
        self.entries.reserve(iter.size_hint().0);
        for (k, v) in iter {
            self.insert(k, v);
        }
    }
}

impl<K: Ord + Copy, V: Keyed<K>, const N: usize> From<[(K, V); N]> for VecMap<K, V> {
    fn from(entries: [(K, V); N]) -> Self {
        entries.into_iter().collect()
    }
}

impl<K: Ord + Copy, V: Keyed<K>> From<BTreeMap<K, V>> for VecMap<K, V> {
    fn from(map: BTreeMap<K, V>) -> Self {
        VecMap { entries: map.into_iter().map(|(k, v)| keyed(k, v)).collect(), key: std::marker::PhantomData }
    }
}

impl<K: Ord + Copy, V: Keyed<K>> From<VecMap<K, V>> for BTreeMap<K, V> {
    fn from(map: VecMap<K, V>) -> Self {
        map.into_iter().collect()
    }
}

impl<K: Copy, V: Keyed<K>> IntoIterator for VecMap<K, V> {
    type Item = (K, V);
    type IntoIter = std::iter::Map<std::vec::IntoIter<V>, fn(V) -> (K, V)>;

    fn into_iter(self) -> Self::IntoIter {
        self.entries.into_iter().map(|v| (*v.key(), v))
    }
}

impl<'a, K: 'a, V: Keyed<K>> IntoIterator for &'a VecMap<K, V> {
    type Item = (&'a K, &'a V);
    type IntoIter = MapIter<'a, K, V>;

    fn into_iter(self) -> MapIter<'a, K, V> {
        MapIter(self.entries.iter(), std::marker::PhantomData)
    }
}

impl<K: fmt::Debug, V: fmt::Debug + Keyed<K>> fmt::Debug for VecMap<K, V> {
    /// As a `BTreeMap` prints: `{SubIndex(0): Entry { .. }, ..}`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_map().entries(self.entries.iter().map(|v| (v.key(), v))).finish()
    }
}

impl<K: Serialize, V: Serialize + Keyed<K>> Serialize for VecMap<K, V> {
    /// As a map from key to value, in order, as a `BTreeMap` is serialised.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.entries.iter().map(|v| (v.key(), v)))
    }
}

impl<'de, K: Deserialize<'de> + Ord + Copy, V: Deserialize<'de> + Keyed<K>> Deserialize<'de> for VecMap<K, V> {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        BTreeMap::<K, V>::deserialize(deserializer).map(VecMap::from)
    }
}

/// An object: an index with one (VAR) or several (ARRAY, RECORD) entries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// The index.
    pub index: Index,
    /// `ParameterName` of the object.
    pub name: Name,
    /// `ObjectType`.
    pub object_type: ObjectType,
    /// The object list that names it.
    pub category: Category,
    /// The entries by sub-index: one at sub 0 for VAR/DOMAIN/DEFTYPE objects.
    pub subs: SubMap,
    /// `CompactSubObj=N` when the file used the compact form (the entries are expanded in
    /// `subs` all the same; this only says how to write the object back).
    pub compact_sub_obj: Option<u8>,
    /// `[xxxxObjectLinks]`.
    pub object_links: Vec<Index>,
    /// `ObjFlags` on an ARRAY/RECORD object section.
    pub obj_flags: Option<u32>,
    /// Keys of the object section this crate does not interpret, as written, in file order.
    pub extra: Vec<(String, String)>,
    /// Where the section was written.
    pub at: SourceRef,
}

impl Object {
    /// The entry at `sub`.
    pub fn sub(&self, sub: u8) -> Option<&Entry> {
        self.subs.get(&SubIndex(sub))
    }

    /// The single entry of a VAR object (sub 0).
    pub fn var(&self) -> Option<&Entry> {
        if self.object_type.has_subs() { None } else { self.sub(0) }
    }
}

/// `[FileInfo]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FileInfo {
    /// `FileName`
    pub file_name: Option<String>,
    /// `FileVersion`
    pub file_version: Option<u32>,
    /// `FileRevision`
    pub file_revision: Option<u32>,
    /// `EDSVersion` (as written, e.g. "4.0")
    pub eds_version: Option<String>,
    /// `Description`
    pub description: Option<String>,
    /// `CreationTime`
    pub creation_time: Option<String>,
    /// `CreationDate`
    pub creation_date: Option<String>,
    /// `CreatedBy`
    pub created_by: Option<String>,
    /// `ModificationTime`
    pub modification_time: Option<String>,
    /// `ModificationDate`
    pub modification_date: Option<String>,
    /// `ModifiedBy`
    pub modified_by: Option<String>,
    /// Other keys, as written.
    pub extra: Vec<(String, String)>,
}

/// `[DeviceInfo]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DeviceInfo {
    /// `VendorName`
    pub vendor_name: Option<String>,
    /// `VendorNumber`
    pub vendor_number: Option<u32>,
    /// `ProductName`
    pub product_name: Option<String>,
    /// `ProductNumber`
    pub product_number: Option<u32>,
    /// `RevisionNumber`
    pub revision_number: Option<u32>,
    /// `OrderCode`
    pub order_code: Option<String>,
    /// `BaudRate_10` .. `BaudRate_1000`: kbit/s -> supported, for the keys present.
    pub baud_rates: BTreeMap<u16, bool>,
    /// `SimpleBootUpMaster`
    pub simple_boot_up_master: Option<bool>,
    /// `SimpleBootUpSlave`
    pub simple_boot_up_slave: Option<bool>,
    /// `Granularity` (0..=64: the mapping granularity in bits; 0 = no mapping)
    pub granularity: Option<u8>,
    /// `DynamicChannelsSupported`
    pub dynamic_channels_supported: Option<u8>,
    /// `GroupMessaging`
    pub group_messaging: Option<bool>,
    /// `NrOfRXPDO`
    pub nr_of_rx_pdo: Option<u16>,
    /// `NrOfTXPDO`
    pub nr_of_tx_pdo: Option<u16>,
    /// `LSS_Supported`
    pub lss_supported: Option<bool>,
    /// `CompactPDO` (bit field, CiA 306 4.6.2)
    pub compact_pdo: Option<u8>,
    /// Other keys, as written.
    pub extra: Vec<(String, String)>,
}

/// `[DeviceComissioning]` (DCF only; the spec's own spelling).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Commissioning {
    /// `NodeID` (also accepted: `NodeId`, any case)
    pub node_id: Option<u8>,
    /// `NodeName`
    pub node_name: Option<String>,
    /// `Baudrate` in kbit/s
    pub baudrate: Option<u16>,
    /// `NetNumber`
    pub net_number: Option<u32>,
    /// `NetworkName`
    pub network_name: Option<String>,
    /// `CANopenManager`
    pub canopen_manager: Option<bool>,
    /// `LSS_SerialNumber`
    pub lss_serial_number: Option<u32>,
    /// Other keys, as written.
    pub extra: Vec<(String, String)>,
}

/// A section this crate does not interpret, kept with its entries in file order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExtraSection {
    /// Section name as written.
    pub name: String,
    /// Its entries.
    pub entries: Vec<(String, String)>,
}

/// Whether a file is a device description or a device configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum FileKind {
    /// Electronic data sheet.
    #[default]
    Eds,
    /// Device configuration file (has `[DeviceComissioning]`).
    Dcf,
}

/// A whole device description.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// EDS or DCF.
    pub kind: FileKind,
    /// `[FileInfo]`.
    pub file_info: FileInfo,
    /// `[DeviceInfo]`.
    pub device_info: DeviceInfo,
    /// `[DummyUsage]`: `Dummy0001`..`Dummy0007` -> supported.
    pub dummy_usage: BTreeMap<u16, bool>,
    /// `[Comments]` lines.
    pub comments: Vec<String>,
    /// `[DeviceComissioning]` (DCF).
    pub commissioning: Option<Commissioning>,
    /// Every object, sorted by index.
    pub objects: ObjectMap,
    /// Sections this crate does not interpret, in file order.
    pub extra_sections: Vec<ExtraSection>,
}

impl Model {
    /// The object at `index`.
    pub fn object(&self, index: u16) -> Option<&Object> {
        self.objects.get(&Index(index))
    }

    /// The entry at `(index, sub)`.
    pub fn entry(&self, index: u16, sub: u8) -> Option<&Entry> {
        self.object(index)?.sub(sub)
    }

    /// Every entry, in (index, sub-index) order.
    pub fn entries(&self) -> impl Iterator<Item = (&Object, &Entry)> {
        self.objects.values().flat_map(|o| o.subs.values().map(move |e| (o, e)))
    }

    /// The node id a DCF was configured for.
    pub fn node_id(&self) -> Option<u8> {
        self.commissioning.as_ref()?.node_id
    }
}

/// What CiA 301 (and CiA 402) make of an index: the meaning the code generator and the
/// validator use, instead of range checks scattered through their code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Role {
    /// 0x0001..=0x0007: basic data types (usable as dummy mapping entries).
    DataTypeDefinition(DataType),
    /// 0x0008..=0x0FFF: other type definitions.
    OtherTypeDefinition,
    /// 0x1000
    DeviceType,
    /// 0x1001
    ErrorRegister,
    /// 0x1003
    PreDefinedErrorField,
    /// 0x1005
    SyncCobId,
    /// 0x1006
    CommunicationCyclePeriod,
    /// 0x100C
    GuardTime,
    /// 0x100D
    LifeTimeFactor,
    /// 0x1010
    StoreParameters,
    /// 0x1011
    RestoreDefaultParameters,
    /// 0x1014
    EmcyCobId,
    /// 0x1015
    InhibitTimeEmcy,
    /// 0x1016
    ConsumerHeartbeatTime,
    /// 0x1017
    ProducerHeartbeatTime,
    /// 0x1018
    Identity,
    /// 0x1019
    SyncCounterOverflow,
    /// 0x1200..=0x127F: server SDO parameter n (0-based).
    SdoServer(u8),
    /// 0x1280..=0x12FF: client SDO parameter n (0-based).
    SdoClient(u8),
    /// 0x1400..=0x15FF: RPDO n communication parameter (0-based).
    RpdoCommunication(u16),
    /// 0x1600..=0x17FF: RPDO n mapping parameter (0-based).
    RpdoMapping(u16),
    /// 0x1800..=0x19FF: TPDO n communication parameter (0-based).
    TpdoCommunication(u16),
    /// 0x1A00..=0x1BFF: TPDO n mapping parameter (0-based).
    TpdoMapping(u16),
    /// Any other index in 0x1000..=0x1FFF.
    OtherCommunication,
    /// 0x2000..=0x5FFF.
    ManufacturerSpecific,
    /// 0x6000..=0x9FFF.
    StandardizedProfile,
    /// Anything else (0x0000, 0xA000..).
    Reserved,
}

impl Index {
    /// What this index is for.
    // (The arms of the communication area overlap on purpose: the named indices and ranges
    // come first, and the rest of 0x1000..=0x1FFF falls to `OtherCommunication`.)
    #[allow(clippy::match_overlapping_arm)]
    #[inline]
    pub fn role(self) -> Role {
        let i = self.0;
        // Most objects of most files are manufacturer-specific or profile objects: decided by
        // one comparison before the communication area's many cases.
        if i >= 0x2000 {
            return match i {
                0x2000..=0x5FFF => Role::ManufacturerSpecific,
                0x6000..=0x9FFF => Role::StandardizedProfile,
                _ => Role::Reserved,
            };
        }
        match i {
            0x0001..=0x0007 => Role::DataTypeDefinition(DataType::from_code(i)),
            0x0008..=0x0FFF => Role::OtherTypeDefinition,
            0x1000 => Role::DeviceType,
            0x1001 => Role::ErrorRegister,
            0x1003 => Role::PreDefinedErrorField,
            0x1005 => Role::SyncCobId,
            0x1006 => Role::CommunicationCyclePeriod,
            0x100C => Role::GuardTime,
            0x100D => Role::LifeTimeFactor,
            0x1010 => Role::StoreParameters,
            0x1011 => Role::RestoreDefaultParameters,
            0x1014 => Role::EmcyCobId,
            0x1015 => Role::InhibitTimeEmcy,
            0x1016 => Role::ConsumerHeartbeatTime,
            0x1017 => Role::ProducerHeartbeatTime,
            0x1018 => Role::Identity,
            0x1019 => Role::SyncCounterOverflow,
            0x1200..=0x127F => Role::SdoServer((i - 0x1200) as u8),
            0x1280..=0x12FF => Role::SdoClient((i - 0x1280) as u8),
            0x1400..=0x15FF => Role::RpdoCommunication(i - 0x1400),
            0x1600..=0x17FF => Role::RpdoMapping(i - 0x1600),
            0x1800..=0x19FF => Role::TpdoCommunication(i - 0x1800),
            0x1A00..=0x1BFF => Role::TpdoMapping(i - 0x1A00),
            0x1000..=0x1FFF => Role::OtherCommunication,
            // (0x0000; every index from 0x2000 up was decided above.)
            _ => Role::Reserved,
        }
    }
}

/// One entry of a PDO mapping object: `0xIIIISSLL`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PdoMappingEntry {
    /// Mapped index (0x0001..=0x0007 are dummy entries).
    pub index: Index,
    /// Mapped sub-index.
    pub sub: SubIndex,
    /// Length in bits.
    pub bits: u8,
}

impl PdoMappingEntry {
    /// Decodes `0xIIIISSLL`.
    pub const fn from_u32(raw: u32) -> Self {
        PdoMappingEntry { index: Index((raw >> 16) as u16), sub: SubIndex((raw >> 8) as u8), bits: raw as u8 }
    }

    /// Encodes `0xIIIISSLL`.
    pub const fn to_u32(self) -> u32 {
        ((self.index.0 as u32) << 16) | ((self.sub.0 as u32) << 8) | self.bits as u32
    }

    /// Whether this is a dummy entry (a data type index).
    pub const fn is_dummy(self) -> bool {
        self.index.0 >= 0x0001 && self.index.0 <= 0x0007
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value that holds its key, for testing [`VecMap`] apart from the model's types
    /// (serialised as its number alone, as a `BTreeMap<u16, u32>`'s values are).
    #[derive(Clone, Copy, Debug, PartialEq)]
    struct Held(u16, u32);

    impl Keyed<u16> for Held {
        fn key(&self) -> &u16 {
            &self.0
        }
        fn set_key(&mut self, key: u16) {
            self.0 = key;
        }
    }

    impl Serialize for Held {
        fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
            self.1.serialize(serializer)
        }
    }

    /// A `VecMap` made from entries in any order, with repeated keys, or by inserting them one by
    /// one, is the `BTreeMap` the same entries make; every value it holds has the key it was
    /// given with (whatever key the value held before).
    #[test]
    fn vec_map_agrees_with_btree_map() {
        let orders: [&[(u16, u32)]; 5] = [
            &[],
            &[(1, 10), (2, 20), (3, 30)],
            &[(3, 30), (1, 10), (2, 20)],
            &[(5, 1), (2, 2), (5, 3), (0, 4), (2, 5), (9, 6), (5, 7)],
            &[(4, 0), (3, 0), (2, 0), (1, 0), (0, 0)],
        ];
        // (Each value starts with a key of its own, which the map replaces.)
        let held = |&(k, v): &(u16, u32)| (k, Held(k.wrapping_mul(7).wrapping_add(1), v));
        for pairs in orders {
            let want: BTreeMap<u16, u32> = pairs.iter().copied().collect();
            let want_held: Vec<(u16, Held)> = want.iter().map(|(&k, &v)| (k, Held(k, v))).collect();
            let collected: VecMap<u16, Held> = pairs.iter().map(held).collect();
            let mut inserted = VecMap::new();
            for p in pairs {
                let (k, v) = held(p);
                inserted.insert(k, v);
            }
            let from_btree = VecMap::from(pairs.iter().map(held).collect::<BTreeMap<u16, Held>>());
            for map in [&collected, &inserted, &from_btree] {
                assert_eq!(map.iter().map(|(k, v)| (*k, *v)).collect::<Vec<_>>(), want_held);
                assert_eq!(map.clone().into_iter().collect::<Vec<_>>(), want_held);
                assert_eq!(BTreeMap::from(map.clone()).into_iter().collect::<Vec<_>>(), want_held);
                assert_eq!(map.keys().copied().collect::<Vec<_>>(), want.keys().copied().collect::<Vec<_>>());
                assert_eq!(map.len(), want.len());
                for k in 0..12 {
                    assert_eq!(map.get(&k).map(|h| h.1), want.get(&k).copied(), "{pairs:?} {k}");
                    assert_eq!(map.get(&k).map(|h| h.0), want.get(&k).map(|_| k), "{pairs:?} {k}");
                }
                assert_eq!(
                    map.range(2..=5).map(|(k, _)| *k).collect::<Vec<_>>(),
                    want.range(2..=5).map(|(k, _)| *k).collect::<Vec<_>>()
                );
            }
            assert!(collected == inserted && inserted == from_btree);
            assert_eq!(serde_json::to_string(&collected).unwrap(), serde_json::to_string(&want).unwrap());
            let mut changed = collected.clone();
            for (k, v) in changed.iter_mut() {
                v.1 += k as u32;
            }
            changed.retain(|k, v| k % 2 == 0 && v.0 == *k);
            let want_changed: Vec<(u16, u32)> =
                want.iter().filter(|(k, _)| *k % 2 == 0).map(|(&k, &v)| (k, v + k as u32)).collect();
            assert_eq!(changed.values().map(|h| (h.0, h.1)).collect::<Vec<_>>(), want_changed);
        }
    }

    /// A sub-map's entries have the sub-indices they are stored at, and a model's objects their
    /// indices, however they were put there (the key is kept once, in the value).
    #[test]
    fn the_map_key_is_the_value_key() {
        let mut subs = SubMap::new();
        subs.insert(SubIndex(3), Entry::new(9, "a", DataType::Unsigned8, Access::Ro));
        subs.extend([(SubIndex(1), Entry::new(0, "b", DataType::Unsigned8, Access::Ro))]);
        assert_eq!(subs.iter().map(|(k, e)| (k.0, e.sub.0)).collect::<Vec<_>>(), [(1, 1), (3, 3)]);
        assert_eq!(std::mem::size_of::<Entry>(), 96, "a sub-map stores 96 bytes per entry");
        let json = serde_json::to_string(&subs).unwrap();
        let back: SubMap = serde_json::from_str(&json).unwrap();
        assert!(back == subs);
    }

    /// Every index has the role of its area (CiA 301's object dictionary layout), the areas
    /// meet where they should, and the communication objects with roles of their own have them.
    #[test]
    fn role_of_every_index() {
        for i in 0..=u16::MAX {
            let role = Index(i).role();
            let area_ok = match i {
                0x0000 => role == Role::Reserved,
                0x0001..=0x0007 => role == Role::DataTypeDefinition(DataType::from_code(i)),
                0x0008..=0x0FFF => role == Role::OtherTypeDefinition,
                0x1000..=0x1FFF => !matches!(
                    role,
                    Role::Reserved
                        | Role::ManufacturerSpecific
                        | Role::StandardizedProfile
                        | Role::OtherTypeDefinition
                        | Role::DataTypeDefinition(_)
                ),
                0x2000..=0x5FFF => role == Role::ManufacturerSpecific,
                0x6000..=0x9FFF => role == Role::StandardizedProfile,
                _ => role == Role::Reserved,
            };
            assert!(area_ok, "{i:#06X}: {role:?}");
        }
        let cases = [
            (0x1000, Role::DeviceType),
            (0x1002, Role::OtherCommunication),
            (0x1018, Role::Identity),
            (0x1200, Role::SdoServer(0)),
            (0x12FF, Role::SdoClient(0x7F)),
            (0x1400, Role::RpdoCommunication(0)),
            (0x17FF, Role::RpdoMapping(0x1FF)),
            (0x1A03, Role::TpdoMapping(3)),
            (0x1C00, Role::OtherCommunication),
            (0x1FFF, Role::OtherCommunication),
        ];
        for (i, want) in cases {
            assert_eq!(Index(i).role(), want, "{i:#06X}");
        }
    }

    #[test]
    fn access_spellings() {
        for a in [Access::Ro, Access::Wo, Access::Rw, Access::Rwr, Access::Rww, Access::Const] {
            let s = a.as_str();
            assert_eq!(Access::parse(s), Some(a));
            assert_eq!(Access::parse(&format!(" {} ", s.to_ascii_uppercase())), Some(a));
            assert_eq!(Access::parse(&format!("\u{A0}{s}\t")), Some(a));
        }
        for bad in ["", "r", "rx", "rwx", "ro ro", "cons", "consts", "r\u{F6}", "\u{E4}w"] {
            assert_eq!(Access::parse(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn data_type_codes_round_trip() {
        for t in DataType::BASIC {
            assert_eq!(DataType::from_code(t.code()), t);
        }
        for code in (0..=0x30u16).chain([0xFF, 0x1000, 0xFFFF]) {
            let t = DataType::from_code(code);
            assert_eq!(t.code(), code);
            let basic = DataType::BASIC.iter().any(|b| b.code() == code);
            assert_eq!(t == DataType::Other(code), !basic, "{code:#x}");
        }
    }

    /// Tens of thousands of entries are built, moved and dropped per large file: keep the rarely
    /// set keys out of line.
    #[test]
    fn an_entry_stays_small() {
        assert!(std::mem::size_of::<Entry>() <= 96, "Entry is {} bytes", std::mem::size_of::<Entry>());
    }

    #[test]
    fn no_extras_equal_empty_extras_and_serialise_flat() {
        let plain = Entry::new(1, "x", DataType::Unsigned8, Access::Rw);
        let mut boxed = plain.clone();
        boxed.extras = Some(Box::default());
        assert_eq!(plain, boxed);
        let mut set = plain.clone();
        set.set_parameter_value(Some(Value::int(3)));
        assert_ne!(plain, set);
        assert_eq!(set.parameter_value(), Some(&Value::int(3)));
        set.set_parameter_value(None);
        assert_eq!(plain, set);
        // Setting nothing on an entry without extras makes no box.
        let mut none = plain.clone();
        none.set_parameter_value(None);
        assert!(none.extras.is_none());
        // Serialised with every key, as before the extras were boxed; read back the same.
        let mut full = plain.clone();
        full.extras_mut().denotation = Some("d".into());
        let json = serde_json::to_value(&full).unwrap();
        let keys: Vec<&str> = json.as_object().unwrap().keys().map(String::as_str).collect();
        for k in ["parameter_value", "low_limit", "high_limit", "obj_flags", "denotation", "extra", "at"] {
            assert!(keys.contains(&k), "{k} missing from {keys:?}");
        }
        assert!(!keys.contains(&"extras"));
        let back: Entry = serde_json::from_value(json).unwrap();
        assert_eq!(back, full);
        let back: Entry = serde_json::from_value(serde_json::to_value(&plain).unwrap()).unwrap();
        assert!(back.extras.is_none(), "no box for an entry without extras");
    }
}
