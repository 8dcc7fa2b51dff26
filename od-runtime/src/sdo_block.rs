//! The SDO block transfer switch (cargo feature `sdo-block`), in a module of its own: the SDO
//! server (`sdo`) and the device that runs it (`device`) both read it, and neither imports
//! from the other to get it.

/// Whether SDO block transfers are built in (cargo feature `sdo-block`).
pub(crate) const SDO_BLOCK: bool = cfg!(feature = "sdo-block");
