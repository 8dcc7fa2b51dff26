//! Every diagnostic code, with its lenient severity, whether it is a CiA 306 deviation, and a
//! one-line explanation.
//!
//! Codes are grouped by area: `E00xx` text and syntax, `E01xx` section and key names, `E02xx`
//! object definitions, `E03xx` values, `E04xx` object lists, `E05xx` file and device
//! information, `E06xx` PDOs, `E07xx` COB-IDs. A code never changes meaning once published.
//!
//! The severity a user sees depends on the [`Strictness`]: in lenient mode it is the code's
//! [`CodeInfo::lenient`] severity; in strict mode every code that is a CiA 306 deviation
//! ([`CodeInfo::deviation`]) becomes an error, and the others keep their lenient severity.

use serde::{Deserialize, Serialize};

use crate::Strictness;

/// How bad it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Information (e.g. an unknown key that was kept).
    Note,
    /// Something is off, but the file can be used.
    Warning,
    /// The file (or this part of it) cannot be used as written.
    Error,
}

/// A stable diagnostic code, such as `E0201`. The list of codes is below.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Code(pub &'static str);

impl std::fmt::Display for Severity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Severity::Note => "note",
            Severity::Warning => "warning",
            Severity::Error => "error",
        })
    }
}

impl std::fmt::Display for Code {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }
}

/// What a code means and how severe it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CodeInfo {
    /// The code.
    pub code: Code,
    /// Severity in lenient mode.
    pub lenient: Severity,
    /// Whether the problem is a deviation from CiA 306 (an error in strict mode).
    pub deviation: bool,
    /// One line saying what the code is about.
    pub summary: &'static str,
}

macro_rules! codes {
    ($($(#[doc = $doc:literal])* $name:ident = $sev:ident, $dev:literal, $summary:literal;)*) => {
        $(
            $(#[doc = $doc])*
            pub const $name: Code = Code(stringify!($name));
        )*
        /// Every code, in numeric order.
        pub const ALL: &[CodeInfo] = &[
            $(CodeInfo { code: $name, lenient: Severity::$sev, deviation: $dev, summary: $summary },)*
        ];
    };
}

codes! {
    // ---- E00xx: text and syntax ----
    /// The file is not UTF-8; it was decoded as Windows-1252.
    E0001 = Warning, true, "file is not valid UTF-8 (decoded as Windows-1252)";
    /// A line that is neither a section header, a `key=value` entry, a comment nor blank.
    E0002 = Warning, true, "line is not a section, an entry, a comment or blank";
    /// An entry before the first section header.
    E0003 = Warning, true, "entry outside of any section";
    /// A `#` comment (CiA 306 comments start with `;`).
    E0004 = Warning, true, "comment starts with `#` instead of `;`";
    /// Text after the `]` of a section header that is not a `;` comment.
    E0005 = Warning, true, "unexpected text after a section header";
    /// A section that appears more than once (entries are merged, later keys win).
    E0006 = Warning, true, "duplicate section";
    /// A key that appears more than once in a section (the later value wins).
    E0007 = Warning, true, "duplicate key";
    /// A value that carries an inline comment (`rw ; note`), which was removed to read it.
    E0008 = Warning, true, "value carries an inline comment";
    /// A non-ASCII character (CiA 306 files are ASCII).
    E0009 = Note, false, "non-ASCII text";
    /// The file is UTF-16 (with a byte-order mark); it was decoded as such.
    E0010 = Warning, true, "file is UTF-16";
    /// UTF-16 text with code units that are not valid UTF-16 (decoded as U+FFFD).
    E0011 = Error, true, "invalid UTF-16";

    // ---- E01xx: section and key names ----
    /// A section this crate does not interpret; it is kept in `Model::extra_sections`.
    E0101 = Note, false, "unknown section (kept)";
    /// A key this crate does not interpret; it is kept in the `extra` list of its owner.
    E0102 = Note, false, "unknown key (kept)";
    /// A known section or key spelled differently from CiA 306 (other than letter case).
    E0103 = Warning, true, "misspelled section or key name";
    /// A known section or key written in a different letter case than CiA 306 uses.
    E0104 = Note, false, "section or key name in non-standard letter case";
    /// An object section name whose hexadecimal part is not well formed.
    E0105 = Warning, true, "malformed object section name";

    // ---- E02xx: object definitions ----
    /// `ParameterName` is missing.
    E0201 = Error, true, "missing ParameterName";
    /// `ObjectType` is missing; VAR is assumed.
    E0202 = Note, false, "missing ObjectType (VAR assumed)";
    /// `ObjectType` is not one of 0x0, 0x2, 0x5..0x9.
    E0203 = Error, true, "invalid ObjectType";
    /// `DataType` is missing on an entry that needs one.
    E0204 = Error, true, "missing DataType";
    /// `DataType` is not a number.
    E0205 = Error, true, "invalid DataType";
    /// `AccessType` is missing.
    E0206 = Error, true, "missing AccessType";
    /// `AccessType` is not one of ro, wo, rw, rwr, rww, const.
    E0207 = Warning, true, "invalid AccessType";
    /// `PDOMapping` is not 0 or 1.
    E0208 = Warning, true, "invalid PDOMapping";
    /// `SubNumber` does not match the sub-objects present.
    E0209 = Warning, true, "SubNumber does not match the sub-objects";
    /// Sub-index 0 of an ARRAY or RECORD is not UNSIGNED8.
    E0210 = Warning, true, "sub-index 0 is not UNSIGNED8";
    /// A sub-object section whose object is missing or has no sub-objects.
    E0211 = Warning, true, "sub-object without a matching object";
    /// An ARRAY or RECORD without sub-index 0.
    E0212 = Warning, true, "ARRAY or RECORD without sub-index 0";
    /// `CompactSubObj` misuse (invalid number, on a non-ARRAY, or with explicit sub-objects).
    E0213 = Warning, true, "invalid CompactSubObj";
    /// A `[xxxxName]`/`[xxxxValue]` section problem (wrong count, sub-index out of range, no
    /// compact object).
    E0214 = Warning, true, "invalid [xxxxName]/[xxxxValue]/[xxxxObjectLinks] section";
    /// A DataType that names neither a basic type nor a type defined in the file.
    E0215 = Note, false, "data type is not a basic CiA 301 type";
    /// `ObjFlags` is not a number.
    E0216 = Warning, true, "invalid ObjFlags";
    /// A key that does not belong to this kind of section (e.g. DataType on a RECORD).
    E0217 = Note, false, "key has no meaning in this section";
    /// A sub-object whose ObjectType is not VAR.
    E0218 = Warning, true, "sub-object ObjectType is not VAR";
    /// The type of an entry does not fit the object (e.g. an ARRAY whose elements differ).
    E0219 = Warning, true, "ARRAY elements of different data types";
    /// Sub-objects for an object whose type has none (VAR, DOMAIN).
    E0220 = Warning, true, "sub-objects for an object without sub-objects";
    /// Sub-index 0 of an ARRAY or RECORD is not the highest sub-index present (for an ARRAY,
    /// nor the number of elements); a writable sub-index 0 (a count of entries in use) is above
    /// it. PDO mapping objects are left to E0608.
    E0221 = Warning, true, "sub-index 0 does not match the sub-objects";
    /// More implicit CompactSubObj elements than a file of its size may declare
    /// ([`crate::lower::implicit_budget`]): a resource limit, so an error in either mode. The
    /// arrays past the bound keep only sub-index 0 in the model.
    E0222 = Error, false, "too many implicit CompactSubObj elements for the file's size";

    // ---- E03xx: values ----
    /// A value that cannot be read as the entry's data type.
    E0301 = Warning, true, "value cannot be read";
    /// A value outside the range of the entry's data type.
    E0302 = Warning, true, "value out of range for its data type";
    /// A number with a leading zero whose octal (CiA 306) and decimal readings differ.
    E0303 = Warning, false, "ambiguous leading-zero number (octal by CiA 306)";
    /// A number with a leading zero that contains 8 or 9: read as decimal.
    E0304 = Warning, true, "leading-zero number with digits 8 or 9 (read as decimal)";
    /// A number with leading zeros that reads the same in octal and decimal.
    E0305 = Note, false, "leading zeros in a number";
    /// The default (or parameter) value lies outside LowLimit..HighLimit.
    E0306 = Warning, true, "value outside LowLimit..HighLimit";
    /// LowLimit is greater than HighLimit.
    E0307 = Warning, true, "LowLimit greater than HighLimit";
    /// An empty value for a numeric data type.
    E0308 = Note, true, "empty numeric value";
    /// A hexadecimal value of a signed type read as a two's complement bit pattern.
    E0309 = Note, false, "hex value of a signed type read as two's complement";
    /// A hexadecimal value of a REAL type read as an IEEE 754 bit pattern.
    E0310 = Note, false, "hex value of a REAL type read as its bit pattern";
    /// `TRUE`/`FALSE` for a BOOLEAN (CiA 306 writes 0 or 1).
    E0311 = Warning, true, "BOOLEAN written as a word";
    /// A DOMAIN value that is not hex bytes, kept as text.
    E0312 = Note, false, "DOMAIN value is not hex bytes (kept as text)";
    /// Limits on a data type without a numeric range.
    E0313 = Warning, true, "limits on a non-numeric data type";
    /// White space inside a number.
    E0314 = Warning, true, "white space inside a number";
    /// A ParameterValue in a file that is not a DCF.
    E0315 = Note, false, "ParameterValue in an EDS";
    /// A TIME_OF_DAY or TIME_DIFFERENCE value written as `days ms` (lely-core's form).
    E0316 = Note, false, "time value written as `days ms`";
    /// A number with a C literal suffix (`0x1234LL`, `0.5f`), removed to read it.
    E0317 = Warning, true, "number with a C literal suffix";

    // ---- E04xx: object lists ----
    /// An object named in an object list has no section.
    E0401 = Warning, true, "listed object has no section";
    /// An object section that no object list names.
    E0402 = Warning, true, "object section not in any object list";
    /// `SupportedObjects` does not match the entries of the list.
    E0403 = Warning, true, "SupportedObjects does not match the list";
    /// A malformed object-list entry (key not 1..N, value not an index).
    E0404 = Warning, true, "malformed object list entry";
    /// An object named more than once in the object lists.
    E0405 = Warning, true, "object listed more than once";
    /// An object in the wrong list (1000h/1001h/1018h are mandatory; 2000h..5FFFh manufacturer).
    E0406 = Warning, true, "object in the wrong object list";
    /// An object list section is missing.
    E0407 = Warning, true, "object list section missing";

    // ---- E05xx: file and device information ----
    /// A mandatory object (1000h, 1001h, 1018h) is missing.
    E0501 = Warning, true, "mandatory object missing";
    /// `[FileInfo]` or `[DeviceInfo]` is missing.
    E0502 = Warning, true, "information section missing";
    /// A \[FileInfo\]/\[DeviceInfo\]/\[DeviceComissioning\]/\[DummyUsage\] value cannot be read.
    E0503 = Warning, true, "invalid information value";
    /// NrOfRXPDO/NrOfTXPDO does not match the PDO objects present.
    E0504 = Warning, true, "PDO count does not match the objects";
    /// A required \[DeviceInfo\] or \[FileInfo\] key is missing.
    E0505 = Note, true, "required information key missing";
    /// A node id outside 1..=127.
    E0506 = Warning, true, "node id out of range";
    /// A mandatory object has the wrong object type or data type.
    E0507 = Warning, true, "mandatory object has the wrong type";

    // ---- E06xx: PDOs ----
    /// A PDO mapping entry names an object or sub-object that does not exist.
    E0601 = Warning, true, "mapped object does not exist";
    /// A PDO mapping entry names an entry with PDOMapping=0.
    E0602 = Warning, true, "mapped entry is not PDO-mappable";
    /// The length in a PDO mapping entry does not match the mapped data type.
    E0603 = Warning, true, "mapping length does not match the data type";
    /// A dummy mapping entry for a type that \[DummyUsage\] does not enable.
    E0604 = Warning, true, "dummy mapping not enabled in [DummyUsage]";
    /// A PDO mapping longer than 64 bits.
    E0605 = Warning, true, "PDO mapping longer than 64 bits";
    /// An RPDO maps an entry that is not writable.
    E0606 = Warning, true, "RPDO maps an entry that cannot be written";
    /// A TPDO maps an entry that is not readable.
    E0607 = Warning, true, "TPDO maps an entry that cannot be read";
    /// The number of mapped entries (sub-index 0) exceeds the entries present or 64.
    E0608 = Warning, true, "mapping count exceeds the mapping entries";
    /// A PDO mapping object without its communication object, or the other way round.
    E0609 = Warning, true, "PDO communication and mapping objects do not pair";
    /// AccessType rwr/rww on an entry that is not PDO-mappable, or PDOMapping on a type that
    /// cannot be mapped.
    E0610 = Note, true, "AccessType and PDOMapping disagree";
    /// A PDO mapping value that is not a number (e.g. `$NODEID` in a mapping).
    E0611 = Warning, true, "PDO mapping value cannot be read";
    /// `CompactPDO` in \[DeviceInfo\]: PDO objects are implied rather than written out (see
    /// [`crate::lower::expand_compact_pdo`]).
    E0612 = Note, false, "PDO objects implied by CompactPDO";
    /// A PDO mapping entry whose length is not a multiple of \[DeviceInfo\] `Granularity`.
    E0613 = Warning, true, "mapping length is not a multiple of Granularity";
    /// `Granularity=0` (the mapping cannot be changed) with writable PDO mapping parameters.
    E0614 = Warning, true, "writable PDO mapping with Granularity=0";

    // ---- E07xx: COB-IDs ----
    /// A PDO, SYNC or EMCY COB-ID in use whose 11-bit CAN-ID CiA 301 restricts (0x000,
    /// 0x001..0x07F, 0x101..0x180, 0x581..0x5FF, 0x601..0x67F, 0x6E0..0x6FF, 0x701..0x7FF),
    /// for some node id when it depends on it.
    E0701 = Warning, true, "COB-ID uses a restricted CAN-ID";
    /// A COB-ID in use with bit 29 clear (11-bit CAN-ID) but CAN-ID bits above bit 10 set.
    E0702 = Warning, true, "11-bit COB-ID with bits above bit 10";
    /// Two of the device's PDOs (or a PDO and its SYNC or EMCY) in use on the same CAN-ID.
    E0703 = Warning, true, "duplicate COB-ID";
}

/// The information about `code` (`None` for a code not in [`ALL`]).
pub fn info(code: Code) -> Option<&'static CodeInfo> {
    // ALL is sorted by code and every code has five bytes (a unit test checks both), so the
    // codes compare like the numbers their five bytes spell: no string comparison per step.
    let key = key(code)?;
    ALL.binary_search_by_key(&key, |c| key_of_listed(c.code)).ok().map(|i| &ALL[i])
}

/// The five bytes of a code as a big-endian number (`None` if it does not have five bytes).
#[inline]
fn key(code: Code) -> Option<u64> {
    match code.0.as_bytes() {
        &[a, b, c, d, e] => Some(u64::from_be_bytes([0, 0, 0, a, b, c, d, e])),
        _ => None,
    }
}

/// [`key`] of a code in [`ALL`] (which has five bytes).
#[inline]
fn key_of_listed(code: Code) -> u64 {
    key(code).unwrap_or(0)
}

/// The severity of `code` at a strictness level.
pub fn severity(code: Code, strictness: Strictness) -> Severity {
    match info(code) {
        Some(i) if strictness == Strictness::Strict && i.deviation => Severity::Error,
        Some(i) => i.lenient,
        None => Severity::Error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_sorted_and_unique() {
        for w in ALL.windows(2) {
            assert!(w[0].code.0 < w[1].code.0, "{:?} before {:?}", w[0].code, w[1].code);
        }
        for c in ALL {
            assert_eq!(c.code.0.len(), 5);
            assert!(c.code.0.starts_with('E'));
            assert_eq!(info(c.code), Some(c));
        }
        assert_eq!(info(Code("E9999")), None);
        assert_eq!(info(Code("")), None);
    }

    #[test]
    fn strict_promotes_deviations_only() {
        assert_eq!(severity(E0004, Strictness::Lenient), Severity::Warning);
        assert_eq!(severity(E0004, Strictness::Strict), Severity::Error);
        assert_eq!(severity(E0101, Strictness::Strict), Severity::Note);
        assert_eq!(severity(E0303, Strictness::Strict), Severity::Warning);
    }
}
