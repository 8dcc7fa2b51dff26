//! Why a unit conversion failed: the error kind `remote` (the generated clients' quantities)
//! and `error` (the crate's [`Error`](crate::Error)) share, in a module below both so that
//! neither imports from the other to name it. Public as `od_master::remote::UnitError`.

use od_sidecar::Unit;

/// Why a unit conversion failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UnitError {
    /// A scaling object holds 0 where it divides.
    #[error("scaling object {index:04X}h is 0")]
    ZeroFactor {
        /// The scaling object.
        index: u16,
    },
    /// An intermediate or final value does not fit.
    #[error("the conversion overflows")]
    Overflow,
    /// The dimension has no unit in the device's configuration.
    #[error("no unit for this dimension in the device's configuration")]
    NoUnit,
    /// The quantity's unit is not the configuration's unit for the dimension.
    #[error("the device's configuration is in {}, not {}", unit_symbol(*.expected), unit_symbol(*.got))]
    WrongUnit {
        /// The configuration's unit.
        expected: Unit,
        /// The quantity's unit.
        got: Unit,
    },
    /// The raw value does not fit the entry's type.
    #[error("the raw value does not fit the entry's type")]
    OutOfRange,
}

fn unit_symbol(u: Unit) -> &'static str {
    u.symbol()
}
