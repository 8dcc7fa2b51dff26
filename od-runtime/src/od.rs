//! The contract between a generated object dictionary and the runtime.
//!
//! Generated code (from `od-codegen`) implements [`ObjectDictionary`] for its storage struct and
//! provides a static, sorted table of [`EntryInfo`]. The runtime's services (SDO server, PDOs,
//! NMT resets, store/restore) reach the dictionary only through this trait, so any dictionary,
//! generated or hand-written, plugs in.
//!
//! Implementations share two helpers so every dictionary applies the same rules:
//! [`EntryInfo::check_value`] (length and limit checks with the CiA 301 abort codes, to call
//! from [`ObjectDictionary::write`]) and [`DefaultValue::encode`] (a default as bus bytes with
//! `$NODEID` resolved, for [`ObjectDictionary::restore_defaults`]). The PDO mapping rules live in
//! [`crate::pdo`] as pure functions for the same reason.

/// A CiA 301 SDO abort code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

impl AbortCode {
    /// Toggle bit not alternated.
    pub const TOGGLE_BIT: Self = Self(0x0503_0000);
    /// SDO protocol timed out.
    pub const TIMEOUT: Self = Self(0x0504_0000);
    /// Client/server command specifier not valid or unknown.
    pub const INVALID_COMMAND: Self = Self(0x0504_0001);
    /// Invalid block size (block mode only).
    pub const INVALID_BLOCK_SIZE: Self = Self(0x0504_0002);
    /// Invalid sequence number (block mode only).
    pub const INVALID_SEQUENCE: Self = Self(0x0504_0003);
    /// CRC error (block mode only).
    pub const CRC_ERROR: Self = Self(0x0504_0004);
    /// Out of memory.
    pub const OUT_OF_MEMORY: Self = Self(0x0504_0005);
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: Self = Self(0x0601_0000);
    /// Attempt to read a write only object.
    pub const WRITE_ONLY: Self = Self(0x0601_0001);
    /// Attempt to write a read only object.
    pub const READ_ONLY: Self = Self(0x0601_0002);
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: Self = Self(0x0602_0000);
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: Self = Self(0x0604_0041);
    /// The number and length of the objects to be mapped would exceed PDO length.
    pub const PDO_LENGTH_EXCEEDED: Self = Self(0x0604_0042);
    /// General parameter incompatibility reason.
    pub const PARAMETER_INCOMPATIBLE: Self = Self(0x0604_0043);
    /// General internal incompatibility in the device.
    pub const INTERNAL_INCOMPATIBLE: Self = Self(0x0604_0047);
    /// Access failed due to a hardware error.
    pub const HARDWARE_ERROR: Self = Self(0x0606_0000);
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: Self = Self(0x0607_0010);
    /// Data type does not match, length of service parameter too high.
    pub const LENGTH_TOO_HIGH: Self = Self(0x0607_0012);
    /// Data type does not match, length of service parameter too low.
    pub const LENGTH_TOO_LOW: Self = Self(0x0607_0013);
    /// Sub-index does not exist.
    pub const NO_SUB_INDEX: Self = Self(0x0609_0011);
    /// Invalid value for parameter (download only).
    pub const INVALID_VALUE: Self = Self(0x0609_0030);
    /// Value of parameter written too high (download only).
    pub const VALUE_TOO_HIGH: Self = Self(0x0609_0031);
    /// Value of parameter written too low (download only).
    pub const VALUE_TOO_LOW: Self = Self(0x0609_0032);
    /// Maximum value is less than minimum value.
    pub const MAX_LESS_THAN_MIN: Self = Self(0x0609_0036);
    /// General error.
    pub const GENERAL_ERROR: Self = Self(0x0800_0000);
    /// Data cannot be transferred or stored to the application.
    pub const CANNOT_STORE: Self = Self(0x0800_0020);
    /// ... because of local control.
    pub const LOCAL_CONTROL: Self = Self(0x0800_0021);
    /// ... because of the present device state.
    pub const DEVICE_STATE: Self = Self(0x0800_0022);
    /// No data available.
    pub const NO_DATA: Self = Self(0x0800_0024);
    /// Resource not available: SDO connection.
    pub const NO_SDO_CONNECTION: Self = Self(0x060A_0023);
    /// Object dictionary dynamic generation fails or no object dictionary is present.
    pub const NO_DICTIONARY: Self = Self(0x0800_0023);

    /// The CiA 301 meaning of the code (table "SDO abort codes"), `None` for a code the
    /// standard does not define (a vendor's own, or noise).
    pub const fn name(self) -> Option<&'static str> {
        Some(match self.0 {
            0x0503_0000 => "toggle bit not alternated",
            0x0504_0000 => "SDO protocol timed out",
            0x0504_0001 => "client/server command specifier not valid or unknown",
            0x0504_0002 => "invalid block size",
            0x0504_0003 => "invalid sequence number",
            0x0504_0004 => "CRC error",
            0x0504_0005 => "out of memory",
            0x0601_0000 => "unsupported access to an object",
            0x0601_0001 => "attempt to read a write only object",
            0x0601_0002 => "attempt to write a read only object",
            0x0602_0000 => "object does not exist in the object dictionary",
            0x0604_0041 => "object cannot be mapped to the PDO",
            0x0604_0042 => "the number and length of the objects to be mapped would exceed the PDO length",
            0x0604_0043 => "general parameter incompatibility",
            0x0604_0047 => "general internal incompatibility in the device",
            0x0606_0000 => "access failed due to a hardware error",
            0x0607_0010 => "data type does not match, length of service parameter does not match",
            0x0607_0012 => "data type does not match, length of service parameter too high",
            0x0607_0013 => "data type does not match, length of service parameter too low",
            0x0609_0011 => "sub-index does not exist",
            0x0609_0030 => "invalid value for parameter",
            0x0609_0031 => "value of parameter written too high",
            0x0609_0032 => "value of parameter written too low",
            0x0609_0036 => "maximum value is less than minimum value",
            0x060A_0023 => "resource not available: SDO connection",
            0x0800_0000 => "general error",
            0x0800_0020 => "data cannot be transferred or stored to the application",
            0x0800_0021 => "data cannot be transferred or stored to the application because of local control",
            0x0800_0022 => {
                "data cannot be transferred or stored to the application because of the present device state"
            }
            0x0800_0023 => "object dictionary dynamic generation fails or no object dictionary is present",
            0x0800_0024 => "no data available",
            _ => return None,
        })
    }
}

impl core::fmt::Display for AbortCode {
    /// `0x06020000 (object does not exist in the object dictionary)`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{:#010X} ({})", self.0, self.name().unwrap_or("unknown abort code"))
    }
}

/// CiA 301 data types, by their type index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
#[allow(missing_docs)]
pub enum DataType {
    Boolean = 0x01,
    Integer8 = 0x02,
    Integer16 = 0x03,
    Integer32 = 0x04,
    Unsigned8 = 0x05,
    Unsigned16 = 0x06,
    Unsigned32 = 0x07,
    Real32 = 0x08,
    VisibleString = 0x09,
    OctetString = 0x0A,
    UnicodeString = 0x0B,
    TimeOfDay = 0x0C,
    TimeDifference = 0x0D,
    Domain = 0x0F,
    Integer24 = 0x10,
    Real64 = 0x11,
    Integer40 = 0x12,
    Integer48 = 0x13,
    Integer56 = 0x14,
    Integer64 = 0x15,
    Unsigned24 = 0x16,
    Unsigned40 = 0x18,
    Unsigned48 = 0x19,
    Unsigned56 = 0x1A,
    Unsigned64 = 0x1B,
}

impl DataType {
    /// The data type with this type index (the index of its DEFTYPE object, 0x0001..=0x001B),
    /// `None` for an index that is not one of the types above.
    pub const fn from_index(index: u16) -> Option<Self> {
        use DataType as D;
        Some(match index {
            0x01 => D::Boolean,
            0x02 => D::Integer8,
            0x03 => D::Integer16,
            0x04 => D::Integer32,
            0x05 => D::Unsigned8,
            0x06 => D::Unsigned16,
            0x07 => D::Unsigned32,
            0x08 => D::Real32,
            0x09 => D::VisibleString,
            0x0A => D::OctetString,
            0x0B => D::UnicodeString,
            0x0C => D::TimeOfDay,
            0x0D => D::TimeDifference,
            0x0F => D::Domain,
            0x10 => D::Integer24,
            0x11 => D::Real64,
            0x12 => D::Integer40,
            0x13 => D::Integer48,
            0x14 => D::Integer56,
            0x15 => D::Integer64,
            0x16 => D::Unsigned24,
            0x18 => D::Unsigned40,
            0x19 => D::Unsigned48,
            0x1A => D::Unsigned56,
            0x1B => D::Unsigned64,
            _ => return None,
        })
    }

    /// Whether values of this type have a variable length (strings, DOMAIN).
    pub const fn is_variable_length(self) -> bool {
        // One bit per type index (all below 32): VISIBLE_STRING, OCTET_STRING, UNICODE_STRING
        // and DOMAIN. A mask where a `matches!` became a 28-byte table in a firmware.
        const VARIABLE: u32 = 1 << DataType::VisibleString as u32
            | 1 << DataType::OctetString as u32
            | 1 << DataType::UnicodeString as u32
            | 1 << DataType::Domain as u32;
        VARIABLE >> self as u32 & 1 != 0
    }

    /// Size in bits of a fixed-size value (1 for BOOLEAN); 0 for the variable-length types.
    pub const fn bits(self) -> u32 {
        use DataType as D;
        match self {
            D::Boolean => 1,
            D::Integer8 | D::Unsigned8 => 8,
            D::Integer16 | D::Unsigned16 => 16,
            D::Integer24 | D::Unsigned24 => 24,
            D::Integer32 | D::Unsigned32 | D::Real32 => 32,
            D::Integer40 | D::Unsigned40 => 40,
            D::Integer48 | D::Unsigned48 | D::TimeOfDay | D::TimeDifference => 48,
            D::Integer56 | D::Unsigned56 => 56,
            D::Integer64 | D::Unsigned64 | D::Real64 => 64,
            D::VisibleString | D::OctetString | D::UnicodeString | D::Domain => 0,
        }
    }
}

/// Access type of an entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only.
    Ro,
    /// Write only.
    Wo,
    /// Read/write.
    Rw,
    /// Read/write, TPDO-mappable.
    Rwr,
    /// Read/write, RPDO-mappable.
    Rww,
    /// Constant.
    Const,
}

impl Access {
    /// Whether an SDO client may read the entry.
    pub const fn readable(self) -> bool {
        !matches!(self, Access::Wo)
    }

    /// Whether an SDO client may write the entry.
    pub const fn writable(self) -> bool {
        matches!(self, Access::Wo | Access::Rw | Access::Rwr | Access::Rww)
    }

    /// Whether the entry may be mapped into an RPDO.
    pub const fn rpdo_ok(self) -> bool {
        matches!(self, Access::Wo | Access::Rw | Access::Rww)
    }

    /// Whether the entry may be mapped into a TPDO.
    pub const fn tpdo_ok(self) -> bool {
        matches!(self, Access::Ro | Access::Rw | Access::Rwr | Access::Const)
    }
}

/// The default value of an entry, as the device description gives it.
///
/// Integers are kept in 64 bits: every CiA 301 integer type fits, and an UNSIGNED64 above
/// `i64::MAX` is kept as the same 64 bits (a default is encoded by truncation to the type's
/// size, so the bytes are the same). REAL32 defaults stay `f32`, so a single-precision FPU
/// never needs double-precision arithmetic to restore them.
///
/// The 64-bit values are [`Bits64`] (two 32-bit words): a default then needs 4-byte alignment
/// only, and an [`EntryExtras`] row is 20 bytes on a 32-bit target instead of 24.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DefaultValue {
    /// No default given (zero / empty).
    None,
    /// An integer (BOOLEAN as 0/1).
    Int(Bits64),
    /// `$NODEID + offset`, resolved at start-up and on communication reset.
    NodeIdPlus(Bits64),
    /// A REAL32 value.
    Real32(f32),
    /// A REAL64 value, as its bits ([`Bits64::real`]).
    Real64(Bits64),
    /// Bytes of a string, OCTET_STRING or DOMAIN.
    Bytes(&'static [u8]),
}

/// 64 bits as two 32-bit words, low first: an `i64` or an `f64`'s bits kept at 4-byte
/// alignment ([`DefaultValue`]'s 64-bit values).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Bits64([u32; 2]);

impl Bits64 {
    /// The bits of `v`.
    pub const fn int(v: i64) -> Self {
        Bits64([v as u32, (v >> 32) as u32])
    }

    /// The bits of `v` (`f64::to_bits`).
    pub const fn real(v: f64) -> Self {
        Self::int(v.to_bits() as i64)
    }

    /// The value as an `i64` (an `f64`'s bits for [`real`](Self::real)).
    pub const fn get(self) -> i64 {
        (self.0[0] as u64 | (self.0[1] as u64) << 32) as i64
    }
}

/// What only some entries have: a capacity (strings, DOMAIN), limits, a default other than
/// zero. Kept apart from [`EntryInfo`] so that the entries without them pay one pointer, and
/// shared by every entry with the same values (generated tables hold each distinct one once).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EntryExtras {
    /// The capacity in bits of a variable-length value (0 for fixed-size types, whose size
    /// follows from the data type).
    pub bits: u32,
    /// Default value.
    pub default: DefaultValue,
    /// The limits, for the few entries that have any.
    pub limits: Option<&'static Limits>,
}

impl EntryExtras {
    /// No capacity, no limits, no default.
    pub const NONE: Self = Self { bits: 0, default: DefaultValue::None, limits: None };
}

/// The values an integer entry accepts from the bus (`LowLimit`, `HighLimit`), in 64 bits
/// like [`DefaultValue::Int`]: a limit of an UNSIGNED64 above `i64::MAX` is kept as its 64
/// bits, and [`EntryInfo::low`]/[`EntryInfo::high`] read it back as the unsigned number. An
/// entry limited on one side only has its type's range on the other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Lowest value accepted.
    pub low: i64,
    /// Highest value accepted.
    pub high: i64,
}

/// The byte of an [`EntryInfo`] that holds the size in bits of a fixed-size value (1 for
/// BOOLEAN, 0 for the variable-length types, whose capacity is in the extras; bits 0..7) and
/// `PDOMapping` (bit 7). Kept in the row, the size costs no look at the data type or the extras.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EntryFlags(u8);

impl EntryFlags {
    /// The flags of an entry whose fixed-size values have `bits` bits (at most 64; 0 for a
    /// variable-length type, as [`DataType::bits`] says) and that may or may not be mapped.
    pub const fn new(bits: u8, pdo_mappable: bool) -> Self {
        let bits = if bits > 64 { 0 } else { bits };
        Self(bits | (pdo_mappable as u8) << 7)
    }

    /// The size in bits of a fixed-size value; 0 for a variable-length type.
    #[inline]
    pub const fn bits(self) -> u32 {
        (self.0 & 0x7F) as u32
    }

    /// `PDOMapping=1`.
    #[inline]
    pub const fn pdo_mappable(self) -> bool {
        self.0 & 0x80 != 0
    }
}

/// Static metadata of one `(index, sub-index)` entry: 12 bytes on a 32-bit target.
///
/// The rarely present data (capacity, limits, default) is behind [`EntryInfo::extras`] and
/// read through [`bits`](Self::bits), [`low`](Self::low), [`high`](Self::high) and
/// [`default`](Self::default); names are the dictionary's
/// ([`ObjectDictionary::name`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EntryInfo {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Data type.
    pub data_type: DataType,
    /// Access type.
    pub access: Access,
    /// The size of a fixed-size value and `PDOMapping` (read them through
    /// [`bits`](Self::bits) and [`pdo_mappable`](Self::pdo_mappable)).
    pub flags: EntryFlags,
    /// Where the dictionary stores the value, in a numbering of its own (generated
    /// dictionaries: the byte offset of the value in their storage struct). Hand-written
    /// dictionaries may leave it 0.
    pub slot: u16,
    /// Capacity, limits and default, if the entry has any.
    pub extras: Option<&'static EntryExtras>,
}

impl EntryInfo {
    /// An entry without capacity, limits or default, at slot 0.
    pub const fn new(index: u16, sub: u8, data_type: DataType, access: Access, pdo_mappable: bool) -> Self {
        let flags = EntryFlags::new(data_type.bits() as u8, pdo_mappable);
        Self { index, sub, data_type, access, flags, slot: 0, extras: None }
    }

    /// `PDOMapping=1`: the entry may be mapped into a PDO.
    #[inline]
    pub const fn pdo_mappable(&self) -> bool {
        self.flags.pdo_mappable()
    }

    /// This entry with `extras`.
    pub const fn with_extras(mut self, extras: &'static EntryExtras) -> Self {
        self.extras = Some(extras);
        self
    }

    /// This entry at `slot`.
    pub const fn with_slot(mut self, slot: u16) -> Self {
        self.slot = slot;
        self
    }

    /// Size in bits for fixed-size types (1 for BOOLEAN); the capacity in bits for
    /// variable-length types.
    #[cfg_attr(target_os = "none", inline(never))]
    #[cfg_attr(not(target_os = "none"), inline)]
    pub const fn bits(&self) -> u32 {
        // The row's own byte for a fixed-size value (most entries): no read of the extras and
        // no work on the data type.
        match (self.flags.bits(), self.extras) {
            (0, Some(x)) => x.bits,
            (b, _) => b,
        }
    }

    /// Lowest value accepted from the bus, if limited.
    #[inline]
    pub const fn low(&self) -> Option<i128> {
        match self.extras {
            Some(EntryExtras { limits: Some(Limits { low, .. }), .. }) => Some(self.limit(*low)),
            _ => None,
        }
    }

    /// Highest value accepted from the bus, if limited.
    #[inline]
    pub const fn high(&self) -> Option<i128> {
        match self.extras {
            Some(EntryExtras { limits: Some(Limits { high, .. }), .. }) => Some(self.limit(*high)),
            _ => None,
        }
    }

    /// A limit as the number it stands for: unsigned types read its 64 bits as unsigned.
    const fn limit(&self, v: i64) -> i128 {
        if self.data_type.is_signed() { v as i128 } else { v as u64 as i128 }
    }

    /// Default value.
    #[inline]
    pub const fn default(&self) -> DefaultValue {
        match self.extras {
            Some(x) => x.default,
            None => DefaultValue::None,
        }
    }

    /// Whether the entry has integer limits.
    #[inline]
    const fn limited(&self) -> bool {
        matches!(self.extras, Some(EntryExtras { limits: Some(_), .. }))
    }
}

/// Which part of the dictionary a reset or store/restore covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Area {
    /// 0x1000..=0x1FFF.
    Communication,
    /// 0x6000..=0x9FFF (standardised device profile).
    Application,
    /// 0x2000..=0x5FFF.
    Manufacturer,
    /// Every entry.
    All,
}

impl Area {
    /// Whether `index` belongs to this area.
    pub const fn contains(self, index: u16) -> bool {
        match self {
            Area::Communication => index >= 0x1000 && index <= 0x1FFF,
            Area::Application => index >= 0x6000 && index <= 0x9FFF,
            Area::Manufacturer => index >= 0x2000 && index <= 0x5FFF,
            Area::All => true,
        }
    }
}

/// A resolved reference to one entry, for repeated access without looking the entry up again.
///
/// The runtime resolves every entry a PDO maps once, when the mapping is loaded, with
/// [`ObjectDictionary::handle`], and from then on reaches the value with
/// [`ObjectDictionary::read_handle`] and [`ObjectDictionary::write_handle`]: on every SYNC, for
/// every received PDO. What the number means is the dictionary's business. The default methods
/// use the key `index << 8 | sub` ([`Handle::from_key`]), so they work for any dictionary;
/// generated dictionaries use the entry's position in their table, which makes an access one
/// `match` on a number, without a lookup.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Handle(u32);

impl Handle {
    /// A handle with a number of the dictionary's choosing.
    pub const fn new(raw: u32) -> Self {
        Self(raw)
    }

    /// The number given to [`Handle::new`].
    pub const fn get(self) -> u32 {
        self.0
    }

    /// The handle the default methods of [`ObjectDictionary`] use: the key `index << 8 | sub`.
    pub const fn from_key(index: u16, sub: u8) -> Self {
        Self((index as u32) << 8 | sub as u32)
    }

    /// `(index, sub)` of a handle made by [`Handle::from_key`].
    pub const fn key(self) -> (u16, u8) {
        ((self.0 >> 8) as u16, self.0 as u8)
    }
}

/// One entry of a loaded PDO mapping: the mapped object, its length in the PDO and its
/// [`Handle`]. The runtime keeps a slice of these per PDO and hands it to
/// [`ObjectDictionary::read_mapped`] on every transmission.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MappedHandle {
    /// Object index (0x0001..=0x0007 for a dummy entry of an RPDO).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in the PDO in bits (1..=64 in a loaded mapping).
    pub bits: u8,
    /// The entry, resolved when the mapping was loaded (meaningless for a dummy entry).
    pub handle: Handle,
}

impl MappedHandle {
    /// An unused entry.
    pub const EMPTY: Self = Self { index: 0, sub: 0, bits: 0, handle: Handle::new(0) };

    /// Whether this is a dummy entry (index 0x0001..=0x0007), which only skips bits.
    pub const fn is_dummy(&self) -> bool {
        self.index >= 1 && self.index <= 7
    }
}

/// The low `bits` bits of `v`, in two shifts; the shift count is taken modulo 64, so no value
/// makes it overflow (`bits` is 1..=64 in a loaded mapping).
#[inline(always)]
pub(crate) fn low_bits(v: u64, bits: u32) -> u64 {
    let s = 64u32.wrapping_sub(bits) & 63;
    (v << s) >> s
}

/// Packs a mapping into one 64-bit word: each entry's value, as `read` gives it, cut to its
/// low `bits` bits and placed from bit 0 up in mapping order. A loaded mapping has at most 64
/// bits, so every entry fits and the word is zero past the mapping's length; the shift count
/// is taken modulo 64 all the same, so no slice makes it panic. The shared body of
/// [`ObjectDictionary::read_mapped`] and of the generated dictionaries' override.
#[inline(always)]
pub(crate) fn pack_mapped(map: &[MappedHandle], mut read: impl FnMut(Handle) -> [u8; 8]) -> u64 {
    let mut word = 0u64;
    let mut offset = 0u32;
    for e in map {
        let bits = u32::from(e.bits);
        word |= low_bits(u64::from_le_bytes(read(e.handle)), bits) << (offset & 63);
        offset = offset.wrapping_add(bits);
    }
    word
}

/// The services of CiA 301 whose objects a dictionary may lack, and which a
/// [`Device`](crate::Device) serves only when it has them: [`ObjectDictionary::SERVICES`].
///
/// A generated dictionary sets it from its EDS. It is a constant, so the code of a service
/// the dictionary has no objects for is not linked into a firmware (the SDO server, NMT, EMCY,
/// PDOs and the heartbeat producer are always there; the PDOs are sized by the generated
/// `PDOS` and `MAPPED_PER_PDO`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Services {
    /// SYNC consumer and producer (1005h; 1006h and 1019h configure them). Also on without
    /// 1005h when the dictionary has PDOs: any PDO can be synchronous (transmission types
    /// 0–240), and SYNC then arrives on the predefined COB-ID 80h.
    pub sync: bool,
    /// Node guarding and life guarding (100Ch and 100Dh).
    pub node_guarding: bool,
    /// Heartbeat consumer (1016h).
    pub heartbeat_consumer: bool,
    /// EMCY error history (1003h).
    pub emcy_history: bool,
}

impl Services {
    /// Every service (the default of a hand-written dictionary: what it serves is then decided
    /// by the objects it has, at run time).
    pub const ALL: Self = Self { sync: true, node_guarding: true, heartbeat_consumer: true, emcy_history: true };

    /// The services whose objects are among `entries` (sorted or not).
    pub const fn of(entries: &[EntryInfo]) -> Self {
        let (mut sync, mut guard_time, mut life_factor, mut consumer, mut history) =
            (false, false, false, false, false);
        let mut i = 0;
        while i < entries.len() {
            match entries[i].index {
                0x1005 | 0x1400..=0x15FF | 0x1800..=0x19FF => sync = true,
                0x100C => guard_time = true,
                0x100D => life_factor = true,
                0x1016 => consumer = true,
                0x1003 => history = true,
                _ => {}
            }
            i += 1;
        }
        Self { sync, node_guarding: guard_time && life_factor, heartbeat_consumer: consumer, emcy_history: history }
    }
}

/// An object dictionary the runtime can serve.
///
/// Values travel as little-endian bytes, as on the bus. Implementations check lengths and
/// limits; the caller (SDO server, PDO engine) checks access rights using [`EntryInfo`].
/// No method may panic, whatever the arguments.
///
/// Five methods are required. Three more, the *handle* methods ([`handle`](Self::handle),
/// [`read_handle`](Self::read_handle), [`write_handle`](Self::write_handle)), are a fast path
/// for the PDOs: their defaults go through [`info`](Self::info), [`read`](Self::read) and
/// [`write`](Self::write), so a hand-written dictionary works without them. A dictionary that
/// can reach an entry faster by a number of its own (a position, an offset) overrides all three
/// together, consistently.
pub trait ObjectDictionary {
    /// The optional services the dictionary has objects for (see [`Services`]); a generated
    /// dictionary's are its EDS's. Default: [`Services::ALL`].
    const SERVICES: Services = Services::ALL;

    /// When a master may change a PDO's mapping and CAN-ID ([`crate::pdo::Remapping`]): a
    /// generated dictionary's comes from its sidecar (`[pdo] remapping`). Default: CiA 301's.
    /// A constant, so a firmware links only the rule it keeps.
    const PDO_REMAPPING: crate::remapping::Remapping = crate::remapping::Remapping::Cia301;

    /// Whether the device answers LSS (CiA 305; the EDS's `LSS_Supported=1`), with
    /// od-runtime's `lss` feature. Default: no.
    const LSS: bool = false;

    /// Every entry's metadata, sorted by `(index, sub)`.
    fn entries(&self) -> &'static [EntryInfo];

    /// Metadata of one entry: `Err(NO_OBJECT)` if the index is absent, `Err(NO_SUB_INDEX)` if
    /// only the sub-index is.
    fn info(&self, index: u16, sub: u8) -> Result<&'static EntryInfo, AbortCode> {
        let all = self.entries();
        match all.binary_search_by(|e| (e.index, e.sub).cmp(&(index, sub))) {
            Ok(i) => Ok(&all[i]),
            Err(i) => {
                let exists = all.get(i).is_some_and(|e| e.index == index) || (i > 0 && all[i - 1].index == index);
                Err(if exists { AbortCode::NO_SUB_INDEX } else { AbortCode::NO_OBJECT })
            }
        }
    }

    /// Metadata of one entry, by value: what the device's services read. Errors as
    /// [`info`](Self::info)'s.
    ///
    /// Default: a copy of [`info`](Self::info)'s. Generated dictionaries decode it from their
    /// compact rows (8 bytes an entry), so a firmware links no table of [`EntryInfo`]s.
    fn entry(&self, index: u16, sub: u8) -> Result<EntryInfo, AbortCode> {
        self.info(index, sub).copied()
    }

    /// The number of entries. Default: the length of [`entries`](Self::entries).
    fn entry_count(&self) -> usize {
        self.entries().len()
    }

    /// Metadata of the entry at `pos` in `(index, sub)` order, by value (`None` past the
    /// last). Default: a copy of [`entries`](Self::entries)`[pos]`.
    fn entry_at(&self, pos: usize) -> Option<EntryInfo> {
        self.entries().get(pos).copied()
    }

    /// Copies the current value into `buf` and returns its length in bytes.
    /// `Err(OUT_OF_MEMORY)` if `buf` is too small.
    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode>;

    /// Stores a value given as bytes: checks the length (0x0607_0010/12/13) and the limits
    /// (0x0609_0030/31/32); does not check access rights.
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;

    /// Sets every entry of `area` back to its default, resolving `$NODEID` with `node_id`.
    fn restore_defaults(&mut self, area: Area, node_id: u8);

    /// The entry's name (`ParameterName`; `Object: Sub-object` for a sub-entry), if the
    /// dictionary keeps names (generated ones do unless generated without; a firmware may
    /// leave them out to save flash).
    ///
    /// Default: `None`.
    fn name(&self, index: u16, sub: u8) -> Option<&'static str> {
        let _ = (index, sub);
        None
    }

    /// Resolves `(index, sub)` for [`read_handle`](Self::read_handle) and
    /// [`write_handle`](Self::write_handle); `None` if the entry does not exist. A handle stays
    /// valid as long as the dictionary value does (the entries are a static table).
    ///
    /// Default: [`Handle::from_key`] once [`entry`](Self::entry) found the entry.
    fn handle(&self, index: u16, sub: u8) -> Option<Handle> {
        self.entry(index, sub).ok().map(|_| Handle::from_key(index, sub))
    }

    /// The value behind `h` as little-endian bytes: the whole value for every fixed-size type,
    /// the first 8 bytes of a longer one (a string mapped into a PDO), zero past the value's
    /// length. All zeros for a handle that names no entry (never a panic).
    ///
    /// Default: [`read`](Self::read) with the key; values longer than 256 bytes read as zeros.
    fn read_handle(&self, h: Handle) -> [u8; 8] {
        let (index, sub) = h.key();
        let mut buf = [0u8; 8];
        match self.read(index, sub, &mut buf) {
            Ok(_) => buf,
            Err(AbortCode::OUT_OF_MEMORY) => read_long(self, index, sub),
            Err(_) => [0; 8],
        }
    }

    /// Stores a value given as bytes, with the same checks as [`write`](Self::write) (length,
    /// limits; no access rights). `Err(NO_OBJECT)` for a handle that names no entry.
    ///
    /// Default: [`write`](Self::write) with the key.
    fn write_handle(&mut self, h: Handle, data: &[u8]) -> Result<(), AbortCode> {
        let (index, sub) = h.key();
        self.write(index, sub, data)
    }

    /// The data of a transmit PDO as one little-endian 64-bit word: each entry's value
    /// ([`read_handle`](Self::read_handle)) cut to its low `bits` bits, placed from bit 0 up
    /// in mapping order. The runtime calls it on every SYNC and every asynchronous
    /// transmission, with a mapping whose lengths add up to at most 64 bits.
    ///
    /// Default: `read_handle` for each entry. Generated dictionaries override it with their
    /// reads inlined into the loop (one call per PDO instead of one per entry); an override
    /// must give the same word.
    fn read_mapped(&self, map: &[MappedHandle]) -> u64 {
        pack_mapped(map, |h| self.read_handle(h))
    }
}

/// The first 8 bytes of a value too long for an 8-byte buffer (the default
/// [`ObjectDictionary::read_handle`]); kept out of line so the common case needs no large stack.
#[cold]
#[inline(never)]
fn read_long<D: ObjectDictionary + ?Sized>(od: &D, index: u16, sub: u8) -> [u8; 8] {
    let mut big = [0u8; 256];
    let mut out = [0u8; 8];
    if od.read(index, sub, &mut big).is_ok() {
        out.copy_from_slice(&big[..8]);
    }
    out
}

impl DataType {
    /// Whether values of this type are signed integers (read as two's complement for limits).
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

    /// Whether values of this type are integers (BOOLEAN included) whose limits are compared as
    /// numbers.
    pub const fn is_integer(self) -> bool {
        !matches!(
            self,
            DataType::Real32
                | DataType::Real64
                | DataType::VisibleString
                | DataType::OctetString
                | DataType::UnicodeString
                | DataType::Domain
                | DataType::TimeOfDay
                | DataType::TimeDifference
        )
    }
}

impl EntryInfo {
    /// Size in bytes of a fixed-size value, or the capacity in bytes of a variable-length one.
    pub const fn byte_len(&self) -> usize {
        (self.bits() as usize).div_ceil(8)
    }

    /// Checks a value given as little-endian bytes against this entry: its length (exact for
    /// fixed-size types, at most the capacity for strings and DOMAIN) and its `low`/`high`
    /// limits. This is the check [`ObjectDictionary::write`] implementations are expected to
    /// make; generated dictionaries call it so every dictionary shares one rule set.
    ///
    /// Errors: `LENGTH_TOO_HIGH` (0x0607_0012), `LENGTH_TOO_LOW` (0x0607_0013),
    /// `VALUE_TOO_HIGH` (0x0609_0031), `VALUE_TOO_LOW` (0x0609_0032), and `INVALID_VALUE`
    /// (0x0609_0030) for a BOOLEAN that is neither 0 nor 1.
    #[inline]
    pub fn check_value(&self, data: &[u8]) -> Result<(), AbortCode> {
        // The common case first, inlined (an exact length, no limits, not a BOOLEAN), which
        // every rule of `check_value_slow` accepts: one comparison per field on the PDO path.
        if data.len() == self.byte_len() && !self.limited() && !matches!(self.data_type, DataType::Boolean) {
            return Ok(());
        }
        self.check_value_slow(data)
    }

    #[inline(never)]
    fn check_value_slow(&self, data: &[u8]) -> Result<(), AbortCode> {
        let len = self.byte_len();
        if self.data_type.is_variable_length() {
            return if data.len() > len { Err(AbortCode::LENGTH_TOO_HIGH) } else { Ok(()) };
        }
        if data.len() > len {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        }
        if data.len() < len {
            return Err(AbortCode::LENGTH_TOO_LOW);
        }
        if !self.data_type.is_integer() || len > 8 {
            return Ok(());
        }
        // A fixed-size integer of `len` (at most 8) bytes, compared in 64 bits: as unsigned
        // numbers for the unsigned types (their limits' 64 bits read unsigned), as signed ones
        // for the signed types. The same order as `low`/`high`'s 128-bit numbers, without
        // 128-bit arithmetic (half of this function's code on a 32-bit microcontroller).
        let mut raw = 0u64;
        for (i, b) in data.iter().take(8).enumerate() {
            raw |= u64::from(*b) << (8 * i);
        }
        if self.data_type == DataType::Boolean && raw > 1 {
            return Err(AbortCode::INVALID_VALUE);
        }
        let Some(&EntryExtras { limits: Some(&Limits { low, high }), .. }) = self.extras else {
            return Ok(());
        };
        let (above, below) = if self.data_type.is_signed() {
            let shift = (64 - 8 * len as u32) & 63;
            let v = ((raw << shift) as i64) >> shift;
            (v > high, v < low)
        } else {
            (raw > high as u64, raw < low as u64)
        };
        if above {
            return Err(AbortCode::VALUE_TOO_HIGH);
        }
        if below {
            return Err(AbortCode::VALUE_TOO_LOW);
        }
        Ok(())
    }
}

/// Reads up to 16 little-endian bytes as an integer, sign-extending when `signed`.
pub fn decode_int(data: &[u8], signed: bool) -> i128 {
    if data.len() <= 8 {
        // The common case in 64-bit arithmetic, without copying through a buffer.
        let mut raw = 0u64;
        for (i, b) in data.iter().enumerate() {
            raw |= u64::from(*b) << (8 * i);
        }
        let width = 8 * data.len() as u32;
        return if signed && width > 0 {
            let shift = 64 - width;
            i128::from(((raw << shift) as i64) >> shift)
        } else {
            i128::from(raw)
        };
    }
    let mut raw = [0u8; 16];
    let n = data.len().min(16);
    raw[..n].copy_from_slice(&data[..n]);
    if signed && n > 0 && n < 16 && data[n - 1] & 0x80 != 0 {
        for b in &mut raw[n..] {
            *b = 0xFF;
        }
    }
    i128::from_le_bytes(raw)
}

impl DefaultValue {
    /// Writes this default for `info` into `buf` as little-endian bytes and returns the length:
    /// the type's size for fixed-size types (integers truncated to it, `$NODEID` resolved with
    /// `node_id`), the byte count for strings and DOMAIN (cut to the capacity and to `buf`).
    /// Returns 0 if `buf` is too small for a fixed-size value.
    pub fn encode(&self, info: &EntryInfo, node_id: u8, buf: &mut [u8]) -> usize {
        let len = info.byte_len();
        if info.data_type.is_variable_length() {
            let bytes: &[u8] = match self {
                DefaultValue::Bytes(b) => b,
                _ => &[],
            };
            let n = bytes.len().min(len).min(buf.len());
            buf[..n].copy_from_slice(&bytes[..n]);
            return n;
        }
        if buf.len() < len {
            return 0;
        }
        let out = &mut buf[..len];
        match *self {
            DefaultValue::None => out.fill(0),
            DefaultValue::Int(v) => copy_int(v.get(), out),
            DefaultValue::NodeIdPlus(v) => copy_int(v.get().wrapping_add(i64::from(node_id)), out),
            // A real default of a real entry is its bits; of any other entry, its bits too
            // (the generator never writes one; this keeps the method total without float
            // conversions).
            DefaultValue::Real32(f) => copy_int(i64::from(f.to_bits()), out),
            DefaultValue::Real64(f) => copy_int(f.get(), out),
            DefaultValue::Bytes(b) => {
                out.fill(0);
                let n = b.len().min(len);
                out[..n].copy_from_slice(&b[..n]);
            }
        }
        len
    }
}

/// The low bytes of `v`, little-endian, sign-extended past 8 bytes.
fn copy_int(v: i64, out: &mut [u8]) {
    let fill = if v < 0 { 0xFF } else { 0 };
    let bytes = v.to_le_bytes();
    for (o, b) in out.iter_mut().zip(bytes.iter().chain(core::iter::repeat(&fill))) {
        *o = *b;
    }
}
