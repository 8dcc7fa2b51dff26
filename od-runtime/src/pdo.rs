//! PDO mapping rules and bit packing.
//!
//! The rules here are pure functions so that the code generator can apply exactly the checks the
//! runtime applies when a master remaps a PDO over SDO (CiA 301 §7.4.x): an entry
//! `0xIIIISSLL` (index, sub-index, length in bits) is accepted when the object exists, is
//! mappable in the PDO's direction, and its length matches; a whole mapping is accepted when
//! it carries at most 64 bits.
//!
//! When a PDO may be reconfigured is a device's choice ([`Remapping`], a dictionary's
//! [`ObjectDictionary::PDO_REMAPPING`](crate::od::ObjectDictionary::PDO_REMAPPING)): CiA 301's
//! rule by default, or a vendor's that lets the PDO stay valid.

use crate::od::{AbortCode, Access, DataType, EntryInfo};

/// Most entries a mapping object can hold (sub-indices 1..=64).
pub const MAX_MAPPED: usize = 64;

pub use crate::remapping::Remapping;

/// The direction of a PDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Receive PDO: the master writes the mapped objects.
    Receive,
    /// Transmit PDO: the device sends the mapped objects.
    Transmit,
}

/// What the mapping rules need to know about a mapped object.
///
/// Built from an [`EntryInfo`] with `From`, or by the code generator from its model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mappable {
    /// Data type of the object.
    pub data_type: DataType,
    /// Access type of the object.
    pub access: Access,
    /// `PDOMapping=1` in the description.
    pub pdo_mappable: bool,
    /// Size in bits (capacity for variable-length types).
    pub bits: u32,
}

impl From<&EntryInfo> for Mappable {
    fn from(e: &EntryInfo) -> Self {
        Self { data_type: e.data_type, access: e.access, pdo_mappable: e.pdo_mappable(), bits: e.bits() }
    }
}

/// One decoded mapping entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct MapEntry {
    /// Object index (0x0001..=0x0007 for a dummy entry).
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Length in bits (1..=64).
    pub bits: u8,
}

impl MapEntry {
    /// Splits a mapping value `0xIIIISSLL`.
    pub const fn decode(value: u32) -> Self {
        Self { index: (value >> 16) as u16, sub: (value >> 8) as u8, bits: value as u8 }
    }

    /// The mapping value `0xIIIISSLL`.
    pub const fn encode(self) -> u32 {
        (self.index as u32) << 16 | (self.sub as u32) << 8 | self.bits as u32
    }

    /// Whether this is a dummy entry (a data type index 0x0001..=0x0007) that only skips bits.
    pub const fn is_dummy(self) -> bool {
        self.index >= 1 && self.index <= 7
    }

    /// Number of whole bytes the value of this entry occupies in the dictionary.
    pub const fn byte_len(self) -> usize {
        (self.bits as usize).div_ceil(8)
    }
}

/// Size in bits of a dummy mapping entry's data type (index 0x0001..=0x0007), if it is one.
pub const fn dummy_bits(index: u16) -> Option<u32> {
    match index {
        0x0001 => Some(1),
        0x0002 | 0x0005 => Some(8),
        0x0003 | 0x0006 => Some(16),
        0x0004 | 0x0007 => Some(32),
        _ => None,
    }
}

/// Checks one mapping entry value for a PDO of direction `dir`.
///
/// `lookup` gives the mapped object's properties (or the `NO_OBJECT` / `NO_SUB_INDEX` abort);
/// it is not called for dummy entries. Rules, in order:
/// - dummy entries (index 0x0001..=0x0007) are accepted in receive PDOs only, with the data
///   type's exact length (`NOT_MAPPABLE` in a transmit PDO, `PARAMETER_INCOMPATIBLE` for a wrong
///   length);
/// - the object must exist (the lookup's abort code);
/// - it must have `PDOMapping=1` and an access type allowing the direction
///   ([`Access::rpdo_ok`], [`Access::tpdo_ok`]), else `NOT_MAPPABLE` (0x0604_0041);
/// - a length over 64 bits is `PDO_LENGTH_EXCEEDED` (0x0604_0042);
/// - the length must equal the type's size (fixed-size types) or be a whole number of bytes
///   within the capacity (strings, DOMAIN), else `PARAMETER_INCOMPATIBLE` (0x0604_0043).
#[cfg_attr(target_os = "none", inline(never))]
pub fn check_entry(
    dir: Direction,
    value: u32,
    lookup: impl FnOnce(u16, u8) -> Result<Mappable, AbortCode>,
) -> Result<MapEntry, AbortCode> {
    let e = MapEntry::decode(value);
    if let Some(bits) = dummy_bits(e.index) {
        if dir == Direction::Transmit {
            return Err(AbortCode::NOT_MAPPABLE);
        }
        if u32::from(e.bits) != bits {
            return Err(AbortCode::PARAMETER_INCOMPATIBLE);
        }
        return Ok(e);
    }
    let m = lookup(e.index, e.sub)?;
    let direction_ok = match dir {
        Direction::Receive => m.access.rpdo_ok(),
        Direction::Transmit => m.access.tpdo_ok(),
    };
    if !m.pdo_mappable || !direction_ok {
        return Err(AbortCode::NOT_MAPPABLE);
    }
    if e.bits > 64 {
        return Err(AbortCode::PDO_LENGTH_EXCEEDED);
    }
    let fits = if m.data_type.is_variable_length() {
        e.bits.is_multiple_of(8) && u32::from(e.bits) <= m.bits
    } else {
        u32::from(e.bits) == m.bits
    };
    if e.bits == 0 || !fits {
        return Err(AbortCode::PARAMETER_INCOMPATIBLE);
    }
    Ok(e)
}

/// Checks a whole mapping (the values of sub-indices `1..=n`) and returns its length in bits.
///
/// Each entry is checked with [`check_entry`]; more than 64 entries or more than 64 bits in
/// total is `PDO_LENGTH_EXCEEDED` (0x0604_0042).
pub fn check_mapping(
    dir: Direction,
    values: &[u32],
    mut lookup: impl FnMut(u16, u8) -> Result<Mappable, AbortCode>,
) -> Result<u32, AbortCode> {
    if values.len() > MAX_MAPPED {
        return Err(AbortCode::PDO_LENGTH_EXCEEDED);
    }
    let mut total = 0u32;
    for &v in values {
        let e = check_entry(dir, v, &mut lookup)?;
        total += u32::from(e.bits);
        if total > 64 {
            return Err(AbortCode::PDO_LENGTH_EXCEEDED);
        }
    }
    Ok(total)
}

/// Copies the low `bits` bits of `src` (little-endian) into `dst` starting at bit `offset`
/// (bit 0 = least significant bit of byte 0). Bits beyond `dst` are dropped.
pub fn put_bits(dst: &mut [u8; 8], offset: u32, bits: u32, src: &[u8]) {
    if offset.is_multiple_of(8) && bits.is_multiple_of(8) {
        let start = ((offset / 8) as usize).min(8);
        let n = ((bits / 8) as usize).min(src.len()).min(8 - start);
        dst[start..start + n].copy_from_slice(&src[..n]);
        return;
    }
    for i in 0..bits.min(64) {
        let to = offset + i;
        if to >= 64 {
            break;
        }
        let bit = src.get((i / 8) as usize).is_some_and(|b| b >> (i % 8) & 1 != 0);
        let byte = &mut dst[(to / 8) as usize];
        if bit {
            *byte |= 1 << (to % 8);
        } else {
            *byte &= !(1 << (to % 8));
        }
    }
}

/// Extracts `bits` bits starting at bit `offset` of `src` into `dst` (little-endian, zero
/// filled). Returns the number of bytes the value occupies.
pub fn get_bits(src: &[u8; 8], offset: u32, bits: u32, dst: &mut [u8; 8]) -> usize {
    let n = (bits.min(64) as usize).div_ceil(8);
    *dst = [0; 8];
    if offset.is_multiple_of(8) && bits.is_multiple_of(8) {
        let start = ((offset / 8) as usize).min(8);
        let m = n.min(8 - start);
        dst[..m].copy_from_slice(&src[start..start + m]);
        return n;
    }
    for i in 0..bits.min(64) {
        let from = offset + i;
        if from >= 64 {
            break;
        }
        if src[(from / 8) as usize] >> (from % 8) & 1 != 0 {
            dst[(i / 8) as usize] |= 1 << (i % 8);
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(data_type: DataType, access: Access, bits: u32) -> Result<Mappable, AbortCode> {
        Ok(Mappable { data_type, access, pdo_mappable: true, bits })
    }

    #[test]
    fn entry_rules() {
        let u16rw = |_, _| obj(DataType::Unsigned16, Access::Rw, 16);
        assert_eq!(check_entry(Direction::Receive, 0x6040_0010, u16rw), Ok(MapEntry::decode(0x6040_0010)));
        assert_eq!(check_entry(Direction::Receive, 0x6040_0008, u16rw), Err(AbortCode::PARAMETER_INCOMPATIBLE));
        assert_eq!(check_entry(Direction::Receive, 0x6040_0000, u16rw), Err(AbortCode::PARAMETER_INCOMPATIBLE));
        let ro = |_, _| obj(DataType::Unsigned16, Access::Ro, 16);
        assert_eq!(check_entry(Direction::Receive, 0x6041_0010, ro), Err(AbortCode::NOT_MAPPABLE));
        assert!(check_entry(Direction::Transmit, 0x6041_0010, ro).is_ok());
        let not =
            |_, _| Ok(Mappable { data_type: DataType::Unsigned8, access: Access::Rw, pdo_mappable: false, bits: 8 });
        assert_eq!(check_entry(Direction::Transmit, 0x2000_0008, not), Err(AbortCode::NOT_MAPPABLE));
        let missing = |_, _| Err(AbortCode::NO_OBJECT);
        assert_eq!(check_entry(Direction::Transmit, 0x2000_0008, missing), Err(AbortCode::NO_OBJECT));
        assert!(check_entry(Direction::Receive, 0x0005_0008, missing).is_ok());
        assert_eq!(check_entry(Direction::Receive, 0x0005_0010, missing), Err(AbortCode::PARAMETER_INCOMPATIBLE));
        assert_eq!(check_entry(Direction::Transmit, 0x0005_0008, missing), Err(AbortCode::NOT_MAPPABLE));
        let s = |_, _| obj(DataType::VisibleString, Access::Ro, 128);
        assert!(check_entry(Direction::Transmit, 0x2000_0040, s).is_ok());
        assert_eq!(check_entry(Direction::Transmit, 0x2000_0048, s), Err(AbortCode::PDO_LENGTH_EXCEEDED));
        assert_eq!(check_entry(Direction::Transmit, 0x2000_0004, s), Err(AbortCode::PARAMETER_INCOMPATIBLE));
    }

    #[test]
    fn mapping_length() {
        let u32rw = |_, _| obj(DataType::Unsigned32, Access::Rw, 32);
        assert_eq!(check_mapping(Direction::Receive, &[0x6000_0020, 0x6001_0020], u32rw), Ok(64));
        assert_eq!(
            check_mapping(Direction::Receive, &[0x6000_0020, 0x6001_0020, 0x6002_0020], u32rw),
            Err(AbortCode::PDO_LENGTH_EXCEEDED)
        );
        let b = |_, _| obj(DataType::Boolean, Access::Rw, 1);
        assert_eq!(check_mapping(Direction::Receive, &[0x6000_0001; 64], b), Ok(64));
        assert_eq!(check_mapping(Direction::Receive, &[0x6000_0001; 65], b), Err(AbortCode::PDO_LENGTH_EXCEEDED));
    }

    #[test]
    fn bits_round_trip() {
        let mut d = [0u8; 8];
        put_bits(&mut d, 0, 1, &[1]);
        put_bits(&mut d, 1, 16, &[0x34, 0x12]);
        put_bits(&mut d, 17, 3, &[0b101]);
        assert_eq!(d[0], 0x69);
        let mut out = [0u8; 8];
        assert_eq!(get_bits(&d, 1, 16, &mut out), 2);
        assert_eq!(&out[..2], &[0x34, 0x12]);
        assert_eq!(get_bits(&d, 17, 3, &mut out), 1);
        assert_eq!(out[0], 0b101);
        put_bits(&mut d, 60, 16, &[0xFF, 0xFF]);
        assert_eq!(d[7], 0xF0);
        assert_eq!(get_bits(&d, 60, 16, &mut out), 2);
        assert_eq!(&out[..2], &[0x0F, 0]);
    }
}
