//! A drive's own warning or status register, named by its sidecar: read into an axis's error
//! when an operation fails, so that the message says what the drive says (the DRVI's 2006h
//! "Command refused", the AKD's 1002h "Set-points not accepted").

use od_sidecar::{LimitSide, Sidecar};

use crate::error::RegisterReading;

/// A vendor register and the texts of its bits ([`Axis::with_register`](crate::Axis::with_register)).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusRegister {
    /// Its index.
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// The texts of the bits, by bit number (0..=31).
    pub bits: Vec<(u8, String)>,
    /// The bits that say the drive is at a position limit (`[[warning]] limit = ...`).
    pub limits: Vec<(u8, LimitSide)>,
}

impl StatusRegister {
    /// The register the sidecar's `[[warning]]` bits are in (the first object they name, with
    /// the bits of that object), `None` when it names none.
    pub fn from_sidecar(sidecar: &Sidecar) -> Option<Self> {
        let first = sidecar.warnings.first()?.object;
        let bits = sidecar
            .warnings
            .iter()
            .filter(|w| w.object == first && w.bit < 32)
            .map(|w| (w.bit, w.text.clone()))
            .collect();
        let limits = sidecar
            .warnings
            .iter()
            .filter(|w| w.object == first && w.bit < 32)
            .filter_map(|w| w.limit.map(|side| (w.bit, side)))
            .collect();
        Some(Self { index: first.index, sub: first.sub.unwrap_or(0), bits, limits })
    }

    /// The text of `bit`, where the sidecar names it.
    pub fn text(&self, bit: u8) -> Option<&str> {
        self.bits.iter().find(|(b, _)| *b == bit).map(|(_, t)| t.as_str())
    }

    /// The reading of `value`: the texts of its bits that are set, lowest first.
    pub fn reading(&self, value: u32) -> RegisterReading {
        let mut set: Vec<&(u8, String)> = self.bits.iter().filter(|(b, _)| value & (1 << b) != 0).collect();
        set.sort_by_key(|(b, _)| *b);
        let bits = set.into_iter().map(|(_, t)| t.clone()).collect();
        RegisterReading { index: self.index, sub: self.sub, value, bits }
    }
}
