//! Non-volatile storage of parameters (1010h store, 1011h restore defaults).
//!
//! The runtime decides *what* is stored (every writable entry of an area except DOMAINs and
//! the store/restore objects themselves, as `(index, sub, bytes)` records) and *when* (on a
//! "save" written to 1010h; stored values are loaded at every reset node / reset
//! communication). A [`Storage`] implementation only persists records: a file on a host, a
//! flash sector on a microcontroller.

use crate::od::{AbortCode, Area};

/// The "save" signature written to 1010h sub-indices (ASCII `save`, little-endian).
pub const SAVE_SIGNATURE: u32 = 0x6576_6173;
/// The "load" signature written to 1011h sub-indices (ASCII `load`, little-endian).
pub const LOAD_SIGNATURE: u32 = 0x6461_6F6C;

/// Persists parameter records per area.
///
/// The runtime calls it with [`Area::Communication`], [`Area::Application`] or
/// [`Area::Manufacturer`], never [`Area::All`]. A failing call makes the SDO transfer that
/// caused it abort with the returned code (use `CANNOT_STORE`, 0x0800_0020, when in doubt).
pub trait Storage {
    /// Starts a new image of `area`; the old one stays valid until [`Storage::end_save`].
    fn begin_save(&mut self, area: Area) -> Result<(), AbortCode>;
    /// Adds one record to the image being saved.
    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
    /// Commits the image of `area`.
    fn end_save(&mut self, area: Area) -> Result<(), AbortCode>;
    /// Calls `apply` for every record of the stored image of `area`, if there is one.
    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8]));
    /// Deletes the stored image of `area` (1011h: defaults apply from the next reset).
    fn erase(&mut self, area: Area) -> Result<(), AbortCode>;
    /// Starts a group of saves and erases that must take effect together: the runtime calls
    /// it before the areas of one 1010h or 1011h write (all three for sub 1), then
    /// [`Storage::end_transaction`]. A backend that can, keeps the images of the group aside
    /// and commits them as one step, so a power cut leaves every area from the same save.
    /// The default does nothing: each `end_save`/`erase` then takes effect on its own.
    fn begin_transaction(&mut self) -> Result<(), AbortCode> {
        Ok(())
    }
    /// Ends the group begun by [`Storage::begin_transaction`]: `commit` true makes it take
    /// effect (all of it or, on error, none of it); false drops it (a step failed).
    fn end_transaction(&mut self, commit: bool) -> Result<(), AbortCode> {
        let _ = commit;
        Ok(())
    }

    /// Stores the LSS configuration (CiA 305 "store configuration"): the node-ID
    /// ([`crate::lss::UNCONFIGURED`] for none) and the bit timing table index, if one is known.
    /// Default: not supported (the master is told error code 1).
    fn save_lss(&mut self, config: crate::lss::LssConfig) -> Result<(), AbortCode> {
        let _ = config;
        Err(AbortCode::CANNOT_STORE)
    }

    /// The LSS configuration stored by [`Storage::save_lss`], read once at start-up: it takes
    /// the place of the node-ID the device was made with. Default: none.
    fn load_lss(&mut self) -> Option<crate::lss::LssConfig> {
        None
    }
}

/// No persistent storage: saving aborts with `CANNOT_STORE`, nothing is ever loaded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoStorage;

impl Storage for NoStorage {
    fn begin_save(&mut self, _: Area) -> Result<(), AbortCode> {
        Err(AbortCode::CANNOT_STORE)
    }
    fn save_entry(&mut self, _: u16, _: u8, _: &[u8]) -> Result<(), AbortCode> {
        Err(AbortCode::CANNOT_STORE)
    }
    fn end_save(&mut self, _: Area) -> Result<(), AbortCode> {
        Err(AbortCode::CANNOT_STORE)
    }
    fn load(&mut self, _: Area, _: &mut dyn FnMut(u16, u8, &[u8])) {}
    fn erase(&mut self, _: Area) -> Result<(), AbortCode> {
        Ok(())
    }
}

/// The areas a 1010h/1011h sub-index covers (CiA 301: 1 all, 2 communication, 3 application,
/// 4 and above manufacturer-specific).
pub(crate) fn areas_of(sub: u8) -> &'static [Area] {
    match sub {
        0 => &[],
        1 => &[Area::Communication, Area::Application, Area::Manufacturer],
        2 => &[Area::Communication],
        3 => &[Area::Application],
        _ => &[Area::Manufacturer],
    }
}
