//! What the bus reports: node state and error control, emergencies, the link.

use std::collections::HashMap;

use od_bus::tokio::LinkState;
use od_runtime::master::{Emergency, NodeEvent, PdoError};
use od_sidecar::Sidecar;

/// Something that happened on the bus, as [`Bus::events`](crate::Bus::events) reports it.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// Boot-up, first heartbeat, NMT state change, heartbeat (or guarding) lost and recovered,
    /// never heard from within its boot timeout.
    Node(NodeEvent),
    /// An emergency message, with the device's own text for its code when the node's sidecar
    /// has one ([`Bus::set_emcy_texts`](crate::Bus::set_emcy_texts)).
    Emergency {
        /// Node, code, error register and the five manufacturer bytes.
        emcy: Emergency,
        /// The device's text for the code, if known.
        text: Option<String>,
    },
    /// The link went down, came back, or closed for good.
    Link(LinkState),
    /// A TPDO that does not fit the mapping it was subscribed with (shorter than the mapping).
    PdoError {
        /// The PDO's COB-ID.
        cob_id: u16,
        /// What was wrong.
        error: PdoError,
    },
}

/// The texts of a device's emergency codes, by code and manufacturer bytes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EmcyTexts {
    by_code: HashMap<u16, Vec<(Option<u64>, String)>>,
}

impl EmcyTexts {
    /// No texts.
    pub fn new() -> Self {
        Self::default()
    }

    /// The error table of a device's sidecar (`[[error]]`: code, manufacturer bytes, text).
    pub fn from_sidecar(sidecar: &Sidecar) -> Self {
        let mut texts = Self::new();
        for e in &sidecar.errors {
            let Ok(code) = u16::try_from(e.code.0) else { continue };
            let manufacturer = e.manufacturer.and_then(|m| u64::try_from(m.0).ok());
            texts.insert(code, manufacturer, e.text.clone());
        }
        texts
    }

    /// Adds the text of `code`; with `manufacturer`, only for an EMCY whose manufacturer bytes
    /// (little-endian, from byte 3) hold that value.
    pub fn insert(&mut self, code: u16, manufacturer: Option<u64>, text: String) {
        self.by_code.entry(code).or_default().push((manufacturer, text));
    }

    /// The text for an emergency: the entry whose manufacturer value matches its bytes, else
    /// the entry for the code without one, else `None` (several entries for the code and none
    /// matching: no guess).
    pub fn text(&self, emcy: &Emergency) -> Option<&str> {
        let entries = self.by_code.get(&emcy.code)?;
        let mut bytes = [0u8; 8];
        bytes[..5].copy_from_slice(&emcy.vendor);
        let vendor = u64::from_le_bytes(bytes);
        let matching = entries.iter().find(|(m, _)| m.is_some_and(|m| vendor & mask(m) == m));
        let general = entries.iter().find(|(m, _)| m.is_none());
        let only = if entries.len() == 1 { entries.first() } else { None };
        matching.or(general).or(only).map(|(_, t)| t.as_str())
    }
}

/// The bytes a manufacturer value occupies: 00FFh for one byte, FFFFh for two, ...
fn mask(value: u64) -> u64 {
    let bytes = (64 - value.leading_zeros()).div_ceil(8).max(1);
    if bytes >= 8 { u64::MAX } else { (1u64 << (8 * bytes)) - 1 }
}
