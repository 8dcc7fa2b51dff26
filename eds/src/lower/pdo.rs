//! `CompactPDO`: PDO objects a device has without the file spelling them out.
//!
//! CiA 306 lets `[DeviceInfo]` say `CompactPDO=<bits>` instead of listing every PDO
//! communication and mapping object. This reader keeps the model as written (the key is in
//! [`crate::model::DeviceInfo::compact_pdo`]) and offers [`expand_compact_pdo`] to turn it into
//! explicit objects. The reading it implements, bit by bit (set = the sub-index exists):
//!
//! | bit | communication sub-index | type | default |
//! |-----|-------------------------|------|---------|
//! | 0 | 1 COB-ID | UNSIGNED32 rw | the predefined connection set for PDOs 1-4 (`$NODEID+0x200`, `+0x300`, ... for RPDOs, `$NODEID+0x180`, ... for TPDOs); `0x80000000` (invalid) for the others |
//! | 1 | 2 transmission type | UNSIGNED8 rw | `0xFF` (event-driven, device profile) |
//! | 2 | 3 inhibit time | UNSIGNED16 rw | 0 |
//! | 3 | 4 reserved (TPDO only) | UNSIGNED8 rw | 0 |
//! | 4 | 5 event timer | UNSIGNED16 rw | 0 |
//! | 5 | 6 SYNC start value (TPDO only) | UNSIGNED8 rw | 0 |
//!
//! Sub-index 0 (UNSIGNED8 ro) holds the highest sub-index present. For each PDO whose mapping
//! object is missing, a RECORD with sub-index 0 (count, default 0) and eight UNSIGNED32
//! mapping entries (default 0) is created, writable when `Granularity` is not 0 (0 means the
//! mapping cannot be changed). As many PDOs are created as `NrOfRXPDO`/`NrOfTXPDO` ask for,
//! at the lowest free numbers; existing communication objects gain the sub-indices the bits
//! name when they lack them.

use crate::model::{
    Access, Category, DataType, Entry, Index, Model, Object, ObjectType, Radix, Role, SourceRef, SubIndex, SubMap,
    Value,
};

fn entry(sub: u8, name: &str, data_type: DataType, access: Access, default: Value) -> Entry {
    Entry { default: Some(default), ..Entry::new(sub, name, data_type, access) }
}

fn record(index: u16, name: impl Into<crate::model::Name>) -> Object {
    Object {
        index: Index(index),
        name: name.into(),
        object_type: ObjectType::Record,
        category: Category::Optional,
        subs: SubMap::new(),
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: SourceRef::default(),
    }
}

/// The communication sub-objects the CompactPDO bits name, for PDO `n` (0-based).
fn comm_subs(bits: u8, rx: bool, n: u16) -> Vec<Entry> {
    let mut out = Vec::new();
    if bits & 0x01 != 0 {
        let cob = if n < 4 {
            let base = if rx { 0x200 } else { 0x180 } + 0x100 * n as i128;
            Value::NodeIdPlus { offset: base, radix: Radix::Hex }
        } else {
            Value::hex(0x8000_0000)
        };
        let name = if rx { "COB-ID used by RPDO" } else { "COB-ID used by TPDO" };
        out.push(entry(1, name, DataType::Unsigned32, Access::Rw, cob));
    }
    if bits & 0x02 != 0 {
        out.push(entry(2, "Transmission type", DataType::Unsigned8, Access::Rw, Value::hex(0xFF)));
    }
    if bits & 0x04 != 0 {
        out.push(entry(3, "Inhibit time", DataType::Unsigned16, Access::Rw, Value::int(0)));
    }
    if !rx && bits & 0x08 != 0 {
        out.push(entry(4, "Reserved", DataType::Unsigned8, Access::Rw, Value::int(0)));
    }
    if bits & 0x10 != 0 {
        out.push(entry(5, "Event timer", DataType::Unsigned16, Access::Rw, Value::int(0)));
    }
    if !rx && bits & 0x20 != 0 {
        out.push(entry(6, "SYNC start value", DataType::Unsigned8, Access::Rw, Value::int(0)));
    }
    out
}

fn set_highest_sub(obj: &mut Object) {
    let highest = obj.subs.keys().map(|s| s.0).max().unwrap_or(0);
    let e = obj.subs.get_or_insert_with(SubIndex(0), || {
        entry(0, "Highest sub-index supported", DataType::Unsigned8, Access::Ro, Value::int(0))
    });
    if e.default.as_ref().and_then(Value::as_int).is_none_or(|v| v < highest as i128) {
        e.default = Some(Value::int(highest as i128));
    }
}

/// Makes the PDO objects that `CompactPDO` implies explicit (see the module docs). Returns the
/// indices of the objects created or completed, in ascending order. Does nothing when
/// `CompactPDO` is absent or 0.
pub fn expand_compact_pdo(model: &mut Model) -> Vec<Index> {
    let bits = model.device_info.compact_pdo.unwrap_or(0);
    if bits == 0 {
        return Vec::new();
    }
    let mapping_access = if model.device_info.granularity == Some(0) { Access::Ro } else { Access::Rw };
    let mut touched = Vec::new();
    for rx in [true, false] {
        let (base, wanted) =
            if rx { (0x1400u16, model.device_info.nr_of_rx_pdo) } else { (0x1800u16, model.device_info.nr_of_tx_pdo) };
        let is_comm = |r: Role| {
            if rx { matches!(r, Role::RpdoCommunication(_)) } else { matches!(r, Role::TpdoCommunication(_)) }
        };
        // Complete the communication objects that exist.
        let existing: Vec<Index> = model.objects.keys().copied().filter(|i| is_comm(i.role())).collect();
        for idx in &existing {
            let n = idx.0 - base;
            let Some(obj) = model.objects.get_mut(idx) else { continue };
            let mut changed = false;
            for e in comm_subs(bits, rx, n) {
                if !obj.subs.contains_key(&e.sub) {
                    obj.subs.insert(e.sub, e);
                    changed = true;
                }
            }
            if changed {
                set_highest_sub(obj);
                touched.push(*idx);
            }
        }
        // Create the PDOs that are missing.
        let mut missing = (wanted.unwrap_or(0) as usize).saturating_sub(existing.len());
        let mut n = 0u16;
        while missing > 0 && n < 0x200 {
            let comm = Index(base + n);
            if model.objects.contains_key(&comm) {
                n += 1;
                continue;
            }
            let kind = if rx { "RPDO" } else { "TPDO" };
            let mut obj = record(comm.0, format!("{kind} communication parameter {}", n + 1));
            for e in comm_subs(bits, rx, n) {
                obj.subs.insert(e.sub, e);
            }
            set_highest_sub(&mut obj);
            model.objects.insert(comm, obj);
            touched.push(comm);
            let map = Index(comm.0 + 0x200);
            if !model.objects.contains_key(&map) {
                let mut m = record(map.0, format!("{kind} mapping parameter {}", n + 1));
                m.subs.insert(
                    SubIndex(0),
                    entry(0, "Number of mapped objects", DataType::Unsigned8, mapping_access, Value::int(0)),
                );
                for s in 1..=8u8 {
                    m.subs.insert(
                        SubIndex(s),
                        entry(s, &format!("Mapped object {s}"), DataType::Unsigned32, mapping_access, Value::hex(0)),
                    );
                }
                model.objects.insert(map, m);
                touched.push(map);
            }
            missing -= 1;
            n += 1;
        }
    }
    touched.sort();
    touched.dedup();
    touched
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn creates_the_pdos_the_counts_ask_for() {
        let mut m = Model::default();
        m.device_info.compact_pdo = Some(0x13);
        m.device_info.nr_of_rx_pdo = Some(2);
        m.device_info.nr_of_tx_pdo = Some(1);
        m.device_info.granularity = Some(8);
        let made = expand_compact_pdo(&mut m);
        assert_eq!(
            made,
            vec![Index(0x1400), Index(0x1401), Index(0x1600), Index(0x1601), Index(0x1800), Index(0x1A00)]
        );
        let cob = m.entry(0x1401, 1).and_then(|e| e.default.clone()).unwrap();
        assert_eq!(cob.resolve(5), Some(0x305));
        assert_eq!(m.entry(0x1800, 1).and_then(|e| e.default.as_ref()).and_then(|v| v.resolve(1)), Some(0x181));
        assert_eq!(m.entry(0x1800, 2).and_then(|e| e.default.as_ref()).and_then(Value::as_int), Some(0xFF));
        assert!(m.entry(0x1800, 3).is_none());
        assert_eq!(m.entry(0x1800, 0).and_then(|e| e.default.as_ref()).and_then(Value::as_int), Some(5));
        assert_eq!(m.entry(0x1A00, 8).map(|e| e.access), Some(Access::Rw));
    }

    #[test]
    fn nothing_without_compact_pdo() {
        let mut m = Model::default();
        m.device_info.nr_of_rx_pdo = Some(4);
        assert!(expand_compact_pdo(&mut m).is_empty());
        assert!(m.objects.is_empty());
    }
}
