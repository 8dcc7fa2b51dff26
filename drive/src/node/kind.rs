//! [`DeviceKind`], in a module of its own: the node's set-up (`devices`, which builds a node of
//! a kind) and the drives' store lists (`drives::store`, one per kind) both name it, and
//! neither imports from the other to get it. Its methods are in `devices`.

/// One of the devices whose dictionaries the `generated` crate holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DeviceKind {
    /// Camozzi DRVI integrated drive (`devices/camozzi-drvi.eds`).
    Drvi,
    /// Camozzi DRCS stepper drive (`devices/camozzi-drcs.eds`).
    Drcs,
    /// Kollmorgen AKD servo drive (`devices/kollmorgen-akd.eds`).
    Akd,
}
