//! What 1010h ("store parameters") saves: the objects of the device's sidecar `[store]` list,
//! nothing else.
//!
//! od-runtime hands every writable entry of an area to the storage when a master writes
//! `save` to 1010h. A real drive keeps only its parameters: commands (6040h, 607Ah, 60FFh),
//! process values and the store/restore objects themselves are not kept, and which objects
//! count as parameters is what each manual says (DRVI 6.3.2.13, DRCS 3.2.13, AKD 6.2.1.12),
//! transcribed into the sidecar's `[store]` list. [`StoreFilter`] applies that list between
//! od-runtime and the node's storage; [`stored_objects_only`] wraps a node's storage with the
//! list of a bundled device, as [`DeviceKind::build`] does for every device.
//!
//! Loading is not filtered: a stored image only ever holds listed objects, and the values of a
//! DCF (`--dcf`) are applied whatever the list says.

use std::sync::Arc;

use devices::sidecar::ObjRef;
use od_runtime::Storage;
use od_runtime::od::{AbortCode, Area};

use super::sidecar;
use crate::node::{DeviceKind, NodeStorage, ParameterSet};

/// A storage that saves only the objects of a store list; loading and erasing pass through.
///
/// ```
/// use devices::sidecar::ObjRef;
/// use drive::drives::store::StoreFilter;
/// use drive::node::NodeStorage;
///
/// let filter = StoreFilter::new(
///     NodeStorage::memory(),
///     vec![ObjRef { index: 0x6081, sub: None }, ObjRef { index: 0x6099, sub: Some(1) }],
/// );
/// assert!(filter.stores(0x6081, 0));
/// assert!(filter.stores(0x6099, 1));
/// assert!(!filter.stores(0x6099, 2));
/// assert!(!filter.stores(0x6040, 0)); // a command
/// ```
pub struct StoreFilter {
    inner: NodeStorage,
    objects: Vec<ObjRef>,
}

impl StoreFilter {
    /// `inner`, saving only `objects` (a reference without sub-index covers every sub).
    pub fn new(inner: NodeStorage, objects: Vec<ObjRef>) -> Self {
        Self { inner, objects }
    }

    /// Whether `index`/`sub` is saved.
    pub fn stores(&self, index: u16, sub: u8) -> bool {
        self.objects.iter().any(|r| r.index == index && r.sub.is_none_or(|s| s == sub))
    }

    /// The store list.
    pub fn objects(&self) -> &[ObjRef] {
        &self.objects
    }
}

impl Storage for StoreFilter {
    fn begin_save(&mut self, area: Area) -> Result<(), AbortCode> {
        self.inner.begin_save(area)
    }

    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        if self.stores(index, sub) { self.inner.save_entry(index, sub, data) } else { Ok(()) }
    }

    fn end_save(&mut self, area: Area) -> Result<(), AbortCode> {
        self.inner.end_save(area)
    }

    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        self.inner.load(area, apply);
    }

    fn erase(&mut self, area: Area) -> Result<(), AbortCode> {
        self.inner.erase(area)
    }

    fn begin_transaction(&mut self) -> Result<(), AbortCode> {
        self.inner.begin_transaction()
    }

    fn end_transaction(&mut self, commit: bool) -> Result<(), AbortCode> {
        self.inner.end_transaction(commit)
    }

    fn save_lss(&mut self, config: od_runtime::lss::LssConfig) -> Result<(), AbortCode> {
        self.inner.save_lss(config)
    }

    fn load_lss(&mut self) -> Option<od_runtime::lss::LssConfig> {
        self.inner.load_lss()
    }
}

/// The `[store]` list of a bundled device (empty if its sidecar does not parse, which the
/// `drives_common` tests rule out).
pub fn store_list(kind: DeviceKind) -> Vec<ObjRef> {
    sidecar(kind).map(|s| s.store.objects.clone()).unwrap_or_default()
}

/// `storage` saving only the objects of `kind`'s store list: what [`DeviceKind::build`] runs
/// every node with.
pub fn stored_objects_only(kind: DeviceKind, storage: NodeStorage) -> NodeStorage {
    NodeStorage::new(Arc::new(ParameterSet::new()), Box::new(StoreFilter::new(storage, store_list(kind))))
}
