//! How a master supervises a network after boot: the settings of a network description's
//! `[network.supervision]` and `[nodes.NAME.supervision]` tables, as CiA 302-2's 1F80h (NMT
//! start-up) and 1F81h (NMT slave assignment) say them.
//!
//! They are written once, here, for both of their users: `od_codegen::network` reads them from
//! a network description (by hand, for its located diagnostics, with the keys and ranges below),
//! and `od_master::supervisor` acts on them (and reads them from a master DCF's 1F80h/1F81h).
//! This crate holds them because both depend on it and it needs nothing but serde: the
//! supervisor does not link the code generator.
//!
//! The serde derives read and write the same keys as the description, so a tool of your own can
//! keep them in a TOML file of its own:
//!
//! ```
//! use od_sidecar::supervision::{FailureAction, NodeSupervision};
//!
//! let s = NodeSupervision::from_toml("mandatory = true\non_lost = \"stop_all\"\n").unwrap();
//! assert!(s.mandatory && s.start);
//! assert_eq!(s.on_lost, FailureAction::StopAll);
//! assert!(NodeSupervision::from_toml("on_lost = \"stop_all\"\n").unwrap_err().contains("mandatory"));
//! ```

use std::ops::RangeInclusive;

use serde::{Deserialize, Serialize};

/// What the master does about a node whose heartbeat (or guarding) is lost, or, network-wide
/// (`[network.supervision] on_mandatory_failure`), about a mandatory node that cannot be booted.
/// Written `"report"`, `"reset_node"`, `"stop_all"`, `"reset_all"` in the file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureAction {
    /// Report it; nothing is sent (the default).
    #[default]
    Report,
    /// NMT reset node to that node alone: it boots again and is configured again.
    ResetNode,
    /// NMT stop to all nodes (CiA 302-2's 1F80h bit 6). Mandatory nodes only.
    StopAll,
    /// NMT reset node to all nodes (CiA 302-2's 1F80h bit 4). Mandatory nodes only.
    ResetAll,
}

impl FailureAction {
    /// Every action with its name in the file.
    pub const ALL: [(FailureAction, &'static str); 4] = [
        (FailureAction::Report, "report"),
        (FailureAction::ResetNode, "reset_node"),
        (FailureAction::StopAll, "stop_all"),
        (FailureAction::ResetAll, "reset_all"),
    ];

    /// Its name in the file.
    pub fn name(self) -> &'static str {
        Self::ALL.iter().find(|(a, _)| *a == self).map_or("report", |(_, n)| n)
    }

    /// Whether it acts on every node, not only the failed one.
    pub fn is_network_wide(self) -> bool {
        matches!(self, FailureAction::StopAll | FailureAction::ResetAll)
    }
}

/// How the master supervises one node after boot (`[nodes.NAME.supervision]`), as CiA 302-2's
/// 1F81h (NMT slave assignment) says it. Every key is optional; the defaults are [`Default`]'s.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NodeSupervision {
    /// `mandatory` (default false; 1F81h bit 3): the network cannot run without it; its
    /// failures may act on all nodes.
    pub mandatory: bool,
    /// `keep_alive` (default false; 1F81h bit 4): a node found operational when the master
    /// starts is left as it is, not configured again.
    pub keep_alive: bool,
    /// `configure` (default true; 1F81h bit 2): the master checks its identity and writes its
    /// configuration at boot and after each boot-up at run time.
    pub configure: bool,
    /// `start` (default true; 1F80h bit 3 clear): the master starts it (NMT start) once
    /// configured; false leaves it pre-operational for the application.
    pub start: bool,
    /// `on_lost` (default `"report"`): what a lost heartbeat (or guarding) leads to.
    pub on_lost: FailureAction,
    /// `heartbeat_timeout_ms` (default: twice its 1017h producer time, plus 50 ms): the
    /// master's heartbeat consumer time for it; 0 does not watch it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heartbeat_timeout_ms: Option<u32>,
    /// `guard_time_ms` (default 0: heartbeat instead): node guarding every this many ms.
    pub guard_time_ms: u16,
    /// `life_time_factor` (default 3): guarding requests without answer before it is lost.
    pub life_time_factor: u8,
    /// `reset_delay_ms` (default 500): how long a lost node has to come back before
    /// `on_lost` acts; back within it, it is reported recovered and nothing is sent.
    pub reset_delay_ms: u32,
}

impl Default for NodeSupervision {
    fn default() -> Self {
        Self {
            mandatory: false,
            keep_alive: false,
            configure: true,
            start: true,
            on_lost: FailureAction::Report,
            heartbeat_timeout_ms: None,
            guard_time_ms: 0,
            life_time_factor: 3,
            reset_delay_ms: 500,
        }
    }
}

impl NodeSupervision {
    /// The keys of `[nodes.NAME.supervision]`, in the order the documentation lists them.
    pub const KEYS: [&'static str; 9] = [
        "mandatory",
        "keep_alive",
        "configure",
        "start",
        "on_lost",
        "heartbeat_timeout_ms",
        "guard_time_ms",
        "life_time_factor",
        "reset_delay_ms",
    ];
    /// The values `heartbeat_timeout_ms` may take.
    pub const HEARTBEAT_TIMEOUT_MS: RangeInclusive<u32> = 0..=65_535;
    /// The values `guard_time_ms` may take.
    pub const GUARD_TIME_MS: RangeInclusive<u16> = 0..=u16::MAX;
    /// The values `life_time_factor` may take.
    pub const LIFE_TIME_FACTOR: RangeInclusive<u8> = 1..=u8::MAX;
    /// The values `reset_delay_ms` may take (up to 10 minutes).
    pub const RESET_DELAY_MS: RangeInclusive<u32> = 0..=600_000;

    /// From CiA 302-2's 1F81h value for the node (NMT slave assignment): bit 0 listed (not
    /// listed: not configured nor started), bit 2 configure, bit 3 mandatory, bit 4 keep-alive,
    /// bits 8-15 retry factor (life time factor), bits 16-31 guard time in ms. The keys not in
    /// 1F81h keep their defaults.
    pub fn from_1f81(value: u32) -> Self {
        let listed = value & 1 != 0;
        let guard = (value >> 16) as u16;
        let retry = ((value >> 8) & 0xFF) as u8;
        Self {
            mandatory: listed && value & (1 << 3) != 0,
            keep_alive: value & (1 << 4) != 0,
            configure: listed && value & (1 << 2) != 0,
            start: listed,
            guard_time_ms: guard,
            life_time_factor: if retry == 0 { 3 } else { retry },
            ..Self::default()
        }
    }

    /// The rules the types cannot say: each value in its range, and a network-wide `on_lost`
    /// only on a mandatory node. The first broken one, in words with the fix.
    pub fn check(&self) -> Result<(), String> {
        let heartbeat = self.heartbeat_timeout_ms.unwrap_or(0);
        outside("heartbeat_timeout_ms", heartbeat, Self::HEARTBEAT_TIMEOUT_MS)?;
        outside("life_time_factor", self.life_time_factor, Self::LIFE_TIME_FACTOR)?;
        outside("reset_delay_ms", self.reset_delay_ms, Self::RESET_DELAY_MS)?;
        if self.on_lost.is_network_wide() && !self.mandatory {
            return Err(format!(
                "`on_lost = \"{}\"` acts on every node, which only a mandatory node may: add `mandatory = true`, \
                 or use `\"reset_node\"` or `\"report\"`",
                self.on_lost.name()
            ));
        }
        Ok(())
    }

    /// Reads the body of a `[nodes.NAME.supervision]` table and checks it ([`check`](Self::check)).
    pub fn from_toml(text: &str) -> Result<Self, String> {
        let s: Self = toml::from_str(text).map_err(|e| e.message().to_owned())?;
        s.check()?;
        Ok(s)
    }
}

/// How the master supervises the network as a whole (`[network.supervision]`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NetworkSupervision {
    /// `on_mandatory_failure` (default `"report"`): what a mandatory node that cannot be booted
    /// (wrong identity, configuration refused, no heartbeat) does to the network.
    pub on_mandatory_failure: FailureAction,
    /// `boot_attempts` (default 3): how many times in a row a node's boot may fail before
    /// `on_mandatory_failure` or `on_lost` stops acting on it (no endless reset loop).
    pub boot_attempts: u32,
}

impl Default for NetworkSupervision {
    fn default() -> Self {
        Self { on_mandatory_failure: FailureAction::Report, boot_attempts: 3 }
    }
}

impl NetworkSupervision {
    /// The keys of `[network.supervision]`.
    pub const KEYS: [&'static str; 2] = ["on_mandatory_failure", "boot_attempts"];
    /// The values `boot_attempts` may take.
    pub const BOOT_ATTEMPTS: RangeInclusive<u32> = 1..=100;

    /// From CiA 302-2's 1F80h value (NMT start-up): bit 6 stop all nodes, else bit 4 reset all
    /// nodes, on an error of a mandatory node; neither: the node alone (reported).
    pub fn from_1f80(value: u32) -> Self {
        let on_mandatory_failure = if value & (1 << 6) != 0 {
            FailureAction::StopAll
        } else if value & (1 << 4) != 0 {
            FailureAction::ResetAll
        } else {
            FailureAction::Report
        };
        Self { on_mandatory_failure, ..Self::default() }
    }

    /// The rules the types cannot say (`boot_attempts` in its range).
    pub fn check(&self) -> Result<(), String> {
        outside("boot_attempts", self.boot_attempts, Self::BOOT_ATTEMPTS)
    }

    /// Reads the body of a `[network.supervision]` table and checks it.
    pub fn from_toml(text: &str) -> Result<Self, String> {
        let s: Self = toml::from_str(text).map_err(|e| e.message().to_owned())?;
        s.check()?;
        Ok(s)
    }
}

fn outside<T: PartialOrd + std::fmt::Display>(key: &str, v: T, range: RangeInclusive<T>) -> Result<(), String> {
    if range.contains(&v) {
        return Ok(());
    }
    Err(format!(
        "`{key}` is {v}, outside {}..={}: give it a value from {} to {}",
        range.start(),
        range.end(),
        range.start(),
        range.end()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serde_reads_the_documented_keys_and_defaults() {
        assert_eq!(NodeSupervision::from_toml("").unwrap(), NodeSupervision::default());
        assert_eq!(NetworkSupervision::from_toml("").unwrap(), NetworkSupervision::default());
        let all = "mandatory = true\nkeep_alive = true\nconfigure = false\nstart = false\non_lost = \"reset_all\"\n\
                   heartbeat_timeout_ms = 300\nguard_time_ms = 100\nlife_time_factor = 4\nreset_delay_ms = 900\n";
        let s = NodeSupervision::from_toml(all).unwrap();
        assert_eq!(
            s,
            NodeSupervision {
                mandatory: true,
                keep_alive: true,
                configure: false,
                start: false,
                on_lost: FailureAction::ResetAll,
                heartbeat_timeout_ms: Some(300),
                guard_time_ms: 100,
                life_time_factor: 4,
                reset_delay_ms: 900,
            }
        );
        // Every key the documentation lists is one serde writes, and back.
        let written = toml::to_string(&s).unwrap();
        for key in NodeSupervision::KEYS {
            assert!(written.contains(&format!("{key} = ")), "{key} in {written}");
        }
        assert_eq!(NodeSupervision::from_toml(&written).unwrap(), s);
        let n = NetworkSupervision::from_toml("on_mandatory_failure = \"stop_all\"\nboot_attempts = 5\n").unwrap();
        let written = toml::to_string(&n).unwrap();
        for key in NetworkSupervision::KEYS {
            assert!(written.contains(&format!("{key} = ")), "{key} in {written}");
        }
        for (a, name) in FailureAction::ALL {
            assert_eq!(
                toml::to_string(&NetworkSupervision { on_mandatory_failure: a, boot_attempts: 3 })
                    .unwrap()
                    .lines()
                    .next(),
                Some(format!("on_mandatory_failure = \"{name}\"").as_str())
            );
        }
    }

    #[test]
    fn bad_tables_are_refused_in_words() {
        assert!(NodeSupervision::from_toml("mandatry = true\n").unwrap_err().contains("unknown field `mandatry`"));
        assert!(NodeSupervision::from_toml("on_lost = \"explode\"\n").unwrap_err().contains("explode"));
        assert!(NodeSupervision::from_toml("life_time_factor = 0\n").unwrap_err().contains("outside 1..=255"));
        assert!(NodeSupervision::from_toml("on_lost = \"reset_all\"\n").unwrap_err().contains("mandatory = true"));
        assert!(NetworkSupervision::from_toml("boot_attempts = 0\n").unwrap_err().contains("outside 1..=100"));
    }

    #[test]
    fn cia_302_2_values() {
        let s = NodeSupervision::from_1f81(0x0064_0A1D);
        assert!(s.mandatory && s.keep_alive && s.configure && s.start);
        assert_eq!((s.guard_time_ms, s.life_time_factor), (100, 10));
        assert!(!NodeSupervision::from_1f81(0x0C).mandatory);
        assert_eq!(NetworkSupervision::from_1f80(0x50).on_mandatory_failure, FailureAction::StopAll);
        assert_eq!(NetworkSupervision::from_1f80(0x10).on_mandatory_failure, FailureAction::ResetAll);
        assert_eq!(NetworkSupervision::from_1f80(0).on_mandatory_failure, FailureAction::Report);
    }
}
