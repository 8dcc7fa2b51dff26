//! What a configuration manager writes to bring one node from its defaults to its DCF: the
//! entries of a concise DCF (CiA 302-3), in the order CiA 301 needs them, and the identity
//! (1000h, 1018h) the node is checked against first (CiA 302-2).
//!
//! [`plan`] compares each entry's configured value (`ParameterValue`, `$NODEID` resolved) with
//! its default (`DefaultValue`, resolved the same way) and writes only those that differ, as a
//! concise DCF does. Entries the SDO client cannot write (`ro`, `const`) are left out: their
//! `ParameterValue` describes the device, it does not configure it. PDOs are written as whole
//! units, so that the device never runs a half-written PDO:
//!
//! 1. the COB-ID (sub 1) with bit 31 set: the PDO is disabled (even when its default is disabled:
//!    a node configured by an earlier boot runs it, and refuses a new mapping while it does);
//! 2. the communication parameters that differ (transmission type, inhibit time, event timer,
//!    SYNC start value), by sub-index;
//! 3. if any mapping entry differs: the number of entries (mapping sub 0) set to 0, every entry
//!    of the new mapping from 1 on (and any entry past them that is configured), and the number
//!    of entries;
//! 4. the COB-ID without bit 31 (left out when the PDO is to stay disabled).
//!
//! A PDO none of whose values differ is not touched. The order of the whole: the communication
//! profile's own entries (1000h–13FFh, 1C00h–1FFFh) first, then RPDOs, then TPDOs, then
//! everything from 2000h on, each by index and sub-index. Lely's `dcfgen` makes the same writes
//! in the same order for the example network but for one kind: it leaves out the disabling
//! write of a PDO whose default COB-ID is disabled already. Elsewhere it also rewrites every
//! mapping it is given when that equals the default, and writes every `sdo` entry given when
//! that equals the default (`scripts/dcfgen-compare.py` lists the differences).

use crate::model::{DataType, Entry, Model, Value};

/// What one write of the plan is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// A parameter outside the PDO objects.
    Parameter,
    /// A PDO's COB-ID with bit 31 set, before its other entries are written.
    PdoDisable,
    /// A PDO communication parameter (transmission type, inhibit time, event timer, ...).
    PdoParameter,
    /// A mapping's number of entries set to 0, before its entries are written.
    MappingClear,
    /// One mapping entry.
    MappingEntry,
    /// A mapping's number of entries, after its entries.
    MappingCount,
    /// A PDO's COB-ID without bit 31: the PDO is valid again.
    PdoEnable,
}

/// One SDO download of the plan.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Write {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value, little-endian, as many bytes as its data type has.
    pub data: Vec<u8>,
    /// What the write is for.
    pub role: Role,
}

/// The identity a node is checked against (CiA 302-2 compares each one that is not 0, the
/// rule of its expected-identity objects 1F84h–1F87h).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Identity {
    /// 1000h, device type.
    pub device_type: u32,
    /// 1018h sub 1.
    pub vendor_id: u32,
    /// 1018h sub 2.
    pub product_code: u32,
    /// 1018h sub 3.
    pub revision: u32,
}

impl Identity {
    /// The objects compared, with their names, and the values expected (0: not compared).
    pub fn checks(&self) -> [(u16, u8, &'static str, u32); 4] {
        [
            (0x1000, 0, "device type", self.device_type),
            (0x1018, 1, "vendor id", self.vendor_id),
            (0x1018, 2, "product code", self.product_code),
            (0x1018, 3, "revision number", self.revision),
        ]
    }
}

/// What to do to one node: check its identity, then write.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Plan {
    /// The identity expected.
    pub identity: Identity,
    /// The writes, in order.
    pub writes: Vec<Write>,
    /// The producer heartbeat time (1017h, ms) the node runs once configured: its configured
    /// value, or its default; 0 when it has none.
    pub heartbeat_ms: u16,
}

/// A value of the DCF that cannot be written as its entry's type says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanError {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for PlanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:04X}h sub {}: {}", self.index, self.sub, self.message)
    }
}

impl std::error::Error for PlanError {}

/// The identity a configured model expects: the `[DeviceInfo]` numbers, or where one is
/// missing the default of its 1018h entry; 1000h's default.
pub fn identity(model: &Model, node_id: u8) -> Identity {
    let default = |index: u16, sub: u8| -> u32 {
        entry(model, index, sub)
            .and_then(|e| e.default.as_ref())
            .and_then(|v| v.resolve(node_id))
            .and_then(|v| u32::try_from(v).ok())
            .unwrap_or(0)
    };
    let info = &model.device_info;
    Identity {
        device_type: default(0x1000, 0),
        vendor_id: info.vendor_number.unwrap_or_else(|| default(0x1018, 1)),
        product_code: info.product_number.unwrap_or_else(|| default(0x1018, 2)),
        revision: info.revision_number.unwrap_or_else(|| default(0x1018, 3)),
    }
}

fn entry(model: &Model, index: u16, sub: u8) -> Option<&Entry> {
    model.objects.get(&crate::model::Index(index))?.subs.get(&crate::model::SubIndex(sub))
}

/// The bytes of `value` as `data_type` carries it on the bus.
pub fn encode(value: &Value, data_type: DataType, node_id: u8) -> Result<Vec<u8>, String> {
    if let Some(bits) = data_type.bits() {
        match data_type {
            DataType::Real32 => {
                let v = real(value)?;
                return Ok((v as f32).to_le_bytes().to_vec());
            }
            DataType::Real64 => return Ok(real(value)?.to_le_bytes().to_vec()),
            _ => {}
        }
        let Some(v) = value.resolve(node_id) else {
            return Err(format!("{value:?} is not a number, but the entry is {}", data_type.name()));
        };
        let bytes = bits.div_ceil(8) as usize;
        let (lo, hi) = if data_type.is_signed() {
            (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
        } else {
            (0, (1i128 << bits) - 1)
        };
        if v < lo || v > hi {
            return Err(format!("{v} does not fit {}", data_type.name()));
        }
        return Ok(v.to_le_bytes()[..bytes].to_vec());
    }
    match (value, data_type) {
        (Value::Text(t), DataType::UnicodeString) => Ok(t.encode_utf16().flat_map(u16::to_le_bytes).collect()),
        (Value::Text(t), _) => Ok(t.as_bytes().to_vec()),
        (Value::Bytes(b), _) => Ok(b.clone()),
        (v, dt) => Err(format!("{v:?} cannot be written as {}", dt.name())),
    }
}

fn real(value: &Value) -> Result<f64, String> {
    match value {
        Value::Real(r) => Ok(*r),
        Value::Int { value, .. } => Ok(*value as f64),
        v => Err(format!("{v:?} is not a number")),
    }
}

/// One entry's configured and default bytes (the configured value is the default when the
/// DCF gives none).
struct Cell<'a> {
    entry: &'a Entry,
    index: u16,
    target: Option<Vec<u8>>,
    default: Option<Vec<u8>>,
}

impl Cell<'_> {
    /// Configured, writable and not the default.
    fn differs(&self) -> bool {
        self.entry.access.writable()
            && self.entry.parameter_value().is_some()
            && self.target.is_some()
            && self.target != self.default
    }

    fn write(&self, role: Role) -> Write {
        Write { index: self.index, sub: self.entry.sub.0, data: self.target.clone().unwrap_or_default(), role }
    }

    fn u32(bytes: &Option<Vec<u8>>) -> Option<u32> {
        let b = bytes.as_ref()?;
        let mut le = [0u8; 4];
        le[..b.len().min(4)].copy_from_slice(&b[..b.len().min(4)]);
        Some(u32::from_le_bytes(le))
    }
}

/// The identity to check and the writes that take a node at its defaults to the configuration
/// of `model` (a DCF, or the model `network::build` configured), for node `node_id`.
pub fn plan(model: &Model, node_id: u8) -> Result<Plan, Vec<PlanError>> {
    let mut problems = Vec::new();
    let mut cells = Vec::new();
    for obj in model.objects.values() {
        for e in obj.subs.values() {
            let default = e.default.as_ref().and_then(|v| encode(v, e.data_type, node_id).ok());
            let target = match e.parameter_value() {
                // Only a configured value can be wrong: the default is what the device holds.
                Some(pv) => match encode(pv, e.data_type, node_id) {
                    Ok(b) => Some(b),
                    Err(message) => {
                        if e.access.writable() {
                            problems.push(PlanError { index: obj.index.0, sub: e.sub.0, message });
                        }
                        None
                    }
                },
                None => default.clone(),
            };
            cells.push(Cell { entry: e, index: obj.index.0, target, default });
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }

    let is_pdo = |i: u16| (0x1400..=0x1BFF).contains(&i);
    let mut writes = Vec::new();
    for c in cells.iter().filter(|c| c.index < 0x2000 && !is_pdo(c.index) && c.differs()) {
        writes.push(c.write(Role::Parameter));
    }
    let comm_objects: Vec<u16> = cells
        .iter()
        .map(|c| c.index)
        .filter(|&i| (0x1400..=0x15FF).contains(&i) || (0x1800..=0x19FF).contains(&i))
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    for comm in comm_objects.into_iter().filter(|i| seen.insert(*i)) {
        pdo(&cells, comm, &mut writes);
    }
    for c in cells.iter().filter(|c| c.index >= 0x2000 && c.differs()) {
        writes.push(c.write(Role::Parameter));
    }
    let heartbeat_ms = cells
        .iter()
        .find(|c| c.index == 0x1017 && c.entry.sub.0 == 0)
        .and_then(|c| c.target.as_deref())
        .and_then(|b| Some(u16::from_le_bytes(b.try_into().ok()?)))
        .unwrap_or(0);
    Ok(Plan { identity: identity(model, node_id), writes, heartbeat_ms })
}

/// The writes of one PDO (communication object `comm`, mapping `comm + 0x200`).
fn pdo(cells: &[Cell<'_>], comm: u16, writes: &mut Vec<Write>) {
    let of = |index: u16| cells.iter().filter(move |c| c.index == index);
    let cob = of(comm).find(|c| c.entry.sub.0 == 1);
    let params: Vec<&Cell<'_>> = of(comm).filter(|c| c.entry.sub.0 >= 2 && c.differs()).collect();
    let map = comm + 0x200;
    let map_changed = of(map).any(|c| c.differs());
    let cob_changed = cob.is_some_and(|c| c.differs());
    if !cob_changed && params.is_empty() && !map_changed {
        return;
    }
    let cob = cob.filter(|c| c.entry.access.writable());
    let target = cob.and_then(|c| Cell::u32(&c.target));
    // Written even when the default is disabled already: the node may run the PDO from an
    // earlier boot, and refuses a new mapping while it does.
    if let (Some(c), Some(target)) = (cob, target) {
        let disabled = target | 0x8000_0000;
        let mut w = c.write(Role::PdoDisable);
        w.data = disabled.to_le_bytes()[..w.data.len().clamp(1, 4)].to_vec();
        writes.push(w);
    }
    for c in params {
        writes.push(c.write(Role::PdoParameter));
    }
    if let Some(count) = of(map).find(|c| c.entry.sub.0 == 0).filter(|_| map_changed) {
        let n = count.target.as_ref().and_then(|b| b.first().copied()).unwrap_or(0);
        let mut clear = count.write(Role::MappingClear);
        clear.data = vec![0];
        writes.push(clear);
        // The new mapping's entries, and any other entry configured (CiA 301 lets entries past
        // the count be written while the count is 0).
        for c in of(map).filter(|c| (1..=n).contains(&c.entry.sub.0) || (c.entry.sub.0 > n && c.differs())) {
            writes.push(c.write(Role::MappingEntry));
        }
        if n > 0 {
            writes.push(count.write(Role::MappingCount));
        }
    }
    if let (Some(c), Some(target)) = (cob, target)
        && target & 0x8000_0000 == 0
    {
        writes.push(c.write(Role::PdoEnable));
    }
}
