//! Configured values: a DCF's `ParameterValue`s as a [`ParameterSet`], and [`NodeStorage`],
//! which lays them over the stored parameters at every reset.
//!
//! CiA 306 calls a DCF the description of one configured device: the EDS plus, per entry, the
//! `ParameterValue` the device is to run with. A simulated device started with `--dcf` treats
//! those values as its defaults: at every reset (node or communication, so also at start) the
//! runtime sets each entry of the area to its EDS default, then [`NodeStorage`] applies the
//! DCF's values, then the values a master stored with 1010h. Restoring defaults with 1011h
//! therefore returns to the DCF's values, not the EDS's, as on a device commissioned with a
//! configuration tool.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use od_runtime::Storage;
use od_runtime::od::{AbortCode, Area, DataType, EntryInfo};

use crate::storage::Record;

/// The `ParameterValue`s of a DCF, checked against and encoded for one dictionary.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ParameterSet {
    records: Vec<Record>,
    node_id: Option<u8>,
    name: String,
}

/// A DCF that cannot be applied to a device, with every problem found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DcfError {
    /// One line per problem: `file:line:col: message`.
    pub problems: Vec<String>,
}

impl fmt::Display for DcfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, p) in self.problems.iter().enumerate() {
            if i > 0 {
                f.write_str("\n")?;
            }
            f.write_str(p)?;
        }
        Ok(())
    }
}

impl std::error::Error for DcfError {}

impl ParameterSet {
    /// An empty set (no DCF).
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads a DCF and encodes its `ParameterValue`s for the dictionary described by
    /// `entries`, resolving `$NODEID` with `node_id` (or, when `None`, with the DCF's own
    /// `[DeviceComissioning] NodeID`). Fails, naming every problem with its place in the file,
    /// when the file has errors, names an entry the dictionary lacks, or gives a value the
    /// entry cannot hold.
    pub fn from_dcf(path: &Path, entries: &'static [EntryInfo], node_id: Option<u8>) -> Result<Self, DcfError> {
        let parsed = eds::read_file(path, &eds::Options::lenient())
            .map_err(|e| DcfError { problems: vec![format!("{}: {e}", path.display())] })?;
        if parsed.has_errors() {
            let errors: Vec<eds::Diagnostic> = parsed.errors().cloned().collect();
            let text = eds::diag::render_all(&errors, &parsed.document.source);
            return Err(DcfError { problems: text.lines().map(str::to_owned).collect() });
        }
        Self::from_model(&path.display().to_string(), &parsed.model, entries, node_id)
    }

    /// Like [`ParameterSet::from_dcf`], from a model already read; `name` is used in messages.
    pub fn from_model(
        name: &str,
        model: &eds::Model,
        entries: &'static [EntryInfo],
        node_id: Option<u8>,
    ) -> Result<Self, DcfError> {
        let dcf_node = model.node_id();
        let node = node_id.or(dcf_node);
        let mut problems = Vec::new();
        let mut records = Vec::new();
        for (obj, entry) in model.entries() {
            let Some(value) = entry.parameter_value() else { continue };
            let (index, sub) = (obj.index.0, entry.sub.0);
            let at = format!("{name}:{}:{}: 0x{index:04X}sub{sub:X} ParameterValue", entry.at.line, entry.at.col);
            let Some(info) = lookup(entries, index, sub) else {
                problems.push(format!("{at}: the device has no entry 0x{index:04X}sub{sub:X} ({:?})", entry.name));
                continue;
            };
            match encode(value, info, node) {
                Ok(data) => match info.check_value(&data) {
                    Ok(()) => records.push(Record { index, sub, data }),
                    Err(code) => problems.push(format!("{at}: {} (abort code {:#010X})", describe(code), code.0)),
                },
                Err(message) => problems.push(format!("{at}: {message}")),
            }
        }
        if !problems.is_empty() {
            return Err(DcfError { problems });
        }
        Ok(Self { records, node_id: dcf_node, name: name.to_owned() })
    }

    /// The encoded values, in dictionary order.
    pub fn records(&self) -> &[Record] {
        &self.records
    }

    /// The node id the DCF was configured for, if it names one.
    pub fn node_id(&self) -> Option<u8> {
        self.node_id
    }

    /// The file the values came from.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Sets the value of one entry (replacing the DCF's, if it has one): e.g. `drive-sim
    /// --serial`'s 1018h sub 4, applied at every reset as the DCF's values are.
    pub fn set(&mut self, index: u16, sub: u8, data: Vec<u8>) {
        self.records.retain(|r| (r.index, r.sub) != (index, sub));
        self.records.push(Record { index, sub, data });
    }

    /// Calls `apply` for every value of `area`.
    pub fn apply(&self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        for r in self.records.iter().filter(|r| area.contains(r.index)) {
            apply(r.index, r.sub, &r.data);
        }
    }
}

fn lookup(entries: &'static [EntryInfo], index: u16, sub: u8) -> Option<&'static EntryInfo> {
    entries.binary_search_by(|e| (e.index, e.sub).cmp(&(index, sub))).ok().map(|i| &entries[i])
}

fn describe(code: AbortCode) -> &'static str {
    match code {
        AbortCode::LENGTH_TOO_HIGH => "the value is too long for the entry",
        AbortCode::LENGTH_TOO_LOW => "the value is too short for the entry",
        AbortCode::VALUE_TOO_HIGH => "the value is above the entry's HighLimit",
        AbortCode::VALUE_TOO_LOW => "the value is below the entry's LowLimit",
        AbortCode::INVALID_VALUE => "the value is not valid for the entry",
        _ => "the entry refuses the value",
    }
}

/// Encodes a typed value as the entry's little-endian bytes.
fn encode(value: &eds::Value, info: &EntryInfo, node: Option<u8>) -> Result<Vec<u8>, String> {
    let len = info.byte_len();
    match (value, info.data_type) {
        (eds::Value::NodeIdPlus { .. }, _) if node.is_none() => {
            Err("uses $NODEID, but no node id is known (give --node-id or a NodeID in [DeviceComissioning])".into())
        }
        (eds::Value::Int { .. } | eds::Value::NodeIdPlus { .. }, t) if t.is_integer() => {
            let v = value.resolve(node.unwrap_or(0)).unwrap_or(0);
            let bytes = v.to_le_bytes();
            let data = bytes[..len.min(16)].to_vec();
            if od_runtime::od::decode_int(&data, t.is_signed()) != v {
                return Err(format!("{v} does not fit in {} bits", info.bits()));
            }
            Ok(data)
        }
        (eds::Value::Int { value, .. }, DataType::Real32) => Ok((*value as f32).to_le_bytes().to_vec()),
        (eds::Value::Int { value, .. }, DataType::Real64) => Ok((*value as f64).to_le_bytes().to_vec()),
        (eds::Value::Real(f), DataType::Real32) => Ok((*f as f32).to_le_bytes().to_vec()),
        (eds::Value::Real(f), DataType::Real64) => Ok(f.to_le_bytes().to_vec()),
        (eds::Value::Text(s), DataType::UnicodeString) => Ok(s.encode_utf16().flat_map(u16::to_le_bytes).collect()),
        (eds::Value::Text(s), DataType::VisibleString | DataType::OctetString | DataType::Domain) => {
            Ok(s.as_bytes().to_vec())
        }
        (eds::Value::Bytes(b), t) if t.is_variable_length() => Ok(b.clone()),
        (v, t) => Err(format!("a {} cannot hold {v:?}", type_name(t))),
    }
}

fn type_name(t: DataType) -> String {
    format!("{t:?}").to_uppercase()
}

/// The storage a [`Node`](super::Node) runs with: a [`ParameterSet`] (from `--dcf`, possibly
/// empty) laid under a backend that keeps what 1010h saves ([`crate::storage::FileStorage`],
/// [`crate::storage::MemoryStorage`], or od-runtime's `NoStorage`).
///
/// Loading an area applies the set's values first and the backend's stored values after them,
/// so stored values win. Saving and erasing go to the backend only.
pub struct NodeStorage {
    params: Arc<ParameterSet>,
    backend: Box<dyn Storage + Send>,
}

impl fmt::Debug for NodeStorage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("NodeStorage").field("params", &self.params.records.len()).finish_non_exhaustive()
    }
}

impl NodeStorage {
    /// `params` over `backend`.
    pub fn new(params: Arc<ParameterSet>, backend: Box<dyn Storage + Send>) -> Self {
        Self { params, backend }
    }

    /// In-memory storage without configured values.
    pub fn memory() -> Self {
        Self::new(Arc::new(ParameterSet::new()), Box::new(crate::storage::MemoryStorage::new()))
    }

    /// The configured values.
    pub fn params(&self) -> &ParameterSet {
        &self.params
    }
}

impl Storage for NodeStorage {
    fn begin_save(&mut self, area: Area) -> Result<(), AbortCode> {
        self.backend.begin_save(area)
    }

    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.backend.save_entry(index, sub, data)
    }

    fn end_save(&mut self, area: Area) -> Result<(), AbortCode> {
        self.backend.end_save(area)
    }

    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        self.params.apply(area, apply);
        self.backend.load(area, apply);
    }

    fn erase(&mut self, area: Area) -> Result<(), AbortCode> {
        self.backend.erase(area)
    }

    fn begin_transaction(&mut self) -> Result<(), AbortCode> {
        self.backend.begin_transaction()
    }

    fn end_transaction(&mut self, commit: bool) -> Result<(), AbortCode> {
        self.backend.end_transaction(commit)
    }

    fn save_lss(&mut self, config: od_runtime::lss::LssConfig) -> Result<(), AbortCode> {
        self.backend.save_lss(config)
    }

    fn load_lss(&mut self) -> Option<od_runtime::lss::LssConfig> {
        self.backend.load_lss()
    }
}
