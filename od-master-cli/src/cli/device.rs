//! A device description given with `--eds`: the EDS/DCF, the names its generated code gives its
//! entries, its default PDO mappings, and the sidecar TOML next to it (same stem), if any.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::Path;
use std::rc::Rc;

use eds::{Model, Value};
use od_sidecar::Sidecar;

use super::object::Names;

/// One field of a PDO: the entry it maps and its bit length.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    /// Mapped index.
    pub index: u16,
    /// Mapped sub-index.
    pub sub: u8,
    /// Bits.
    pub bits: u8,
}

/// A PDO of the device, from its communication and mapping parameters' defaults.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pdo {
    /// `TPDO3`, `RPDO1`, ...
    pub name: String,
    /// The COB-ID on this node.
    pub cob_id: u32,
    /// Its fields in order.
    pub fields: Vec<Field>,
}

/// A loaded device description.
pub struct Device {
    /// The model.
    pub model: Model,
    /// Entry names.
    pub names: Names,
    /// The sidecar next to the EDS.
    pub sidecar: Option<Sidecar>,
    /// [`pdos`](Self::pdos) by node, worked out once.
    pdos: RefCell<BTreeMap<u8, Rc<[Pdo]>>>,
    /// Values a network's configuration writes ([`configure`](Self::configure)), over the
    /// file's.
    configured: BTreeMap<(u16, u8), i128>,
}

impl Device {
    /// Reads `path` (and `stem.toml` beside it, when there is one). Errors are one line.
    pub fn load(path: &Path) -> Result<Self, String> {
        let file = path.display().to_string();
        let parsed = eds::read_file(path, &eds::Options::lenient()).map_err(|e| format!("cannot read {file}: {e}"))?;
        if let Some(e) = parsed.errors().next() {
            let at = e.at.as_ref().map(|a| format!(":{}:{}", a.line, a.col)).unwrap_or_default();
            return Err(format!("{file}{at}: {}", e.message));
        }
        let model = parsed.model;
        let names = Names::new(&file, &model);
        let toml = path.with_extension("toml");
        let sidecar = if toml.is_file() {
            Some(Sidecar::read(&toml).map_err(|e| format!("{}: {e}", toml.display()))?)
        } else {
            None
        };
        Ok(Self { model, names, sidecar, pdos: RefCell::default(), configured: BTreeMap::new() })
    }

    /// Takes the writes a network's boot makes (its plan, in order; the last write of an entry
    /// wins): the PDOs are then those the network configures, not the file's defaults.
    pub fn configure<'a>(&mut self, writes: impl IntoIterator<Item = (u16, u8, &'a [u8])>) {
        for (index, sub, data) in writes {
            let mut le = [0u8; 16];
            let n = data.len().min(16);
            le[..n].copy_from_slice(&data[..n]);
            self.configured.insert((index, sub), i128::from_le_bytes(le));
        }
        self.pdos.borrow_mut().clear();
    }

    fn value(&self, index: u16, sub: u8, node: u8) -> Option<i128> {
        if let Some(&v) = self.configured.get(&(index, sub)) {
            return Some(v);
        }
        let e = self.model.entry(index, sub)?;
        e.parameter_value().or(e.default.as_ref()).and_then(|v: &Value| v.resolve(node))
    }

    /// The PDOs the device has by default on node `node` (valid COB-IDs only).
    pub fn pdos(&self, node: u8) -> Rc<[Pdo]> {
        Rc::clone(self.pdos.borrow_mut().entry(node).or_insert_with(|| self.find_pdos(node).into()))
    }

    fn find_pdos(&self, node: u8) -> Vec<Pdo> {
        let mut out = Vec::new();
        for (comm, map, kind) in [(0x1400u16, 0x1600u16, "RPDO"), (0x1800, 0x1A00, "TPDO")] {
            for n in 0..512u16 {
                let Some(cob) = self.value(comm + n, 1, node) else { continue };
                let cob = cob as u32;
                if cob & 0x8000_0000 != 0 {
                    continue;
                }
                let count = self.value(map + n, 0, node).unwrap_or(0).clamp(0, 64) as u8;
                let fields = (1..=count)
                    .filter_map(|s| self.value(map + n, s, node))
                    .map(|v| {
                        let v = v as u32;
                        Field { index: (v >> 16) as u16, sub: (v >> 8) as u8, bits: v as u8 }
                    })
                    .collect();
                out.push(Pdo { name: format!("{kind}{}", n + 1), cob_id: cob & 0x1FFF_FFFF, fields });
            }
        }
        out
    }

    /// The sidecar's text of an EMCY: the entry whose manufacturer bytes match, else the one for
    /// the code without any.
    pub fn emcy_text(&self, code: u16, manufacturer: &[u8]) -> Option<&str> {
        let sidecar = self.sidecar.as_ref()?;
        let mut bytes = [0u8; 8];
        let n = manufacturer.len().min(8);
        bytes[..n].copy_from_slice(&manufacturer[..n]);
        let vendor = u64::from_le_bytes(bytes);
        let of_code = || sidecar.errors.iter().filter(|e| e.code.0 == i64::from(code));
        let matching = of_code().find(|e| {
            e.manufacturer.is_some_and(|m| {
                let m = m.0 as u64;
                let width = (64 - m.leading_zeros()).div_ceil(8).max(1);
                let mask = if width >= 8 { u64::MAX } else { (1u64 << (8 * width)) - 1 };
                vendor & mask == m
            })
        });
        matching.or_else(|| of_code().find(|e| e.manufacturer.is_none())).map(|e| e.text.as_str())
    }
}
