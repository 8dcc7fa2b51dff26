//! When a device lets a master change a PDO's mapping and CAN-ID ([`Remapping`]): below both
//! `od` (a dictionary declares its rule) and `pdo` (the rule applied), public as
//! `od_runtime::pdo::Remapping`.

/// When a device lets a master change a PDO's mapping and CAN-ID: part of the device's
/// description ([`ObjectDictionary::PDO_REMAPPING`](crate::od::ObjectDictionary::PDO_REMAPPING),
/// from the `[pdo] remapping` key of a generated dictionary's sidecar), not a fixed rule.
///
/// Under both rules a mapping entry (sub-index 1..) may be written only while sub-index 0 is 0
/// (else abort 0601 0000h), and writing sub-index 0 = n checks the n entries as a whole
/// ([`check_mapping`](crate::pdo::check_mapping): 0604 0041h, 0604 0042h, 0604 0043h for a mapping that does not fit).
/// So CiA 301's order (COB-ID bit 31 set, sub 0 = 0, the entries, sub 0 = n, bit 31 cleared)
/// works on every device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Remapping {
    /// CiA 301 (§7.5.2.35, §7.5.2.36): a PDO's mapping (sub-index 0 and the entries) and the
    /// CAN-ID bits of its COB-ID may be written only while the PDO is invalid (COB-ID bit 31
    /// set); otherwise abort 0601 0000h (mapping) or 0609 0030h (CAN-ID).
    #[default]
    Cia301,
    /// The PDO may stay valid while it is reconfigured: writing sub-index 0 = 0 deactivates it
    /// (a PDO without entries is neither sent nor received), the entries may then be written,
    /// and sub-index 0 = n activates it again with the new mapping; a new CAN-ID may be written
    /// into a valid COB-ID. The Kollmorgen AKD's (CANopen manual 6.3.1.2: sub-index 0 "0: PDO
    /// not activated, 1-8: PDO activated"; the listings 7.2.1.5, 7.2.1.6, 7.2.1.8 and 7.2.2.1
    /// remap valid PDOs, and 7.2.2.1 sets a valid RPDO's CAN-ID, with success answers).
    WhileValid,
}

impl Remapping {
    /// Whether a PDO must be invalid (COB-ID bit 31 set) before its mapping or CAN-ID change.
    pub const fn needs_invalid_pdo(self) -> bool {
        matches!(self, Self::Cia301)
    }
}
