//! The network file, read from TOML into located values (every value keeps its byte span).
//!
//! The file is walked by hand over `toml::de::DeTable` rather than deserialised with serde, so
//! that every unknown key, wrong type and missing key becomes a located diagnostic with a
//! "did you mean" for misspelt keys, and all of them are reported in one run.

use std::ops::Range;

use toml::Spanned;
use toml::de::{DeTable, DeValue};

use super::diag::{Diagnostic, Snippet, codes};
use super::names::suggest;
use od_runtime::pdo::Direction;

/// A value with the byte range it was written at.
#[derive(Clone, Debug, PartialEq)]
pub struct Located<T> {
    /// The value.
    pub value: T,
    /// Byte range in the network file.
    pub span: Range<usize>,
}

/// A TOML scalar given as a configured value.
#[derive(Clone, Debug, PartialEq)]
pub enum Scalar {
    /// An integer; `hex` when written `0x...`.
    Int {
        /// The value.
        value: i128,
        /// Written in hexadecimal.
        hex: bool,
    },
    /// A float.
    Float(f64),
    /// `true` / `false`.
    Bool(bool),
    /// A string: read by the entry's data type like an EDS value (`"$NODEID+0x180"`, text, hex
    /// bytes).
    Str(String),
}

/// `[network]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NetworkDesc {
    /// `name`: written as `NetworkName` in each DCF.
    pub name: Option<Located<String>>,
    /// `baud_rate` in kbit/s.
    pub baud_rate: Option<Located<i128>>,
    /// `[network.supervision]`.
    pub supervision: NetworkSupervision,
}

// The supervision settings are written once, in `od_sidecar::supervision`, for this reader and
// for od-master's supervisor (which does not link the generator); read here by hand like the
// rest of the file, with the keys and ranges given there.
pub use od_sidecar::supervision::{FailureAction, NetworkSupervision, NodeSupervision};

/// One `[nodes.NAME]` table.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeDesc {
    /// The table key: the node's name (`NodeName`, and the DCF's file name).
    pub name: Located<String>,
    /// `device`: the EDS, relative to the network file.
    pub device: Option<Located<String>>,
    /// `node_id`.
    pub node_id: Option<Located<i128>>,
    /// `baud_rate` (must agree with the network's).
    pub baud_rate: Option<Located<i128>>,
    /// `serial`: the device's serial number (1018h sub 4), which LSS finds it by (the DCF's
    /// `LSS_SerialNumber`).
    pub serial: Option<Located<i128>>,
    /// `lss` (default false): the master gives the device of `serial` (and the EDS's identity)
    /// this node-ID over LSS (CiA 305) before it boots the network.
    pub lss: bool,
    /// `lss_store` (default true): the node-ID given over LSS is stored in the device (it keeps
    /// it across a power cycle); false: given again at every boot.
    pub lss_store: bool,
    /// `[nodes.NAME.parameters]`, in file order.
    pub parameters: Vec<(Located<String>, Located<Scalar>)>,
    /// `tpdoN` / `rpdoN`, in file order.
    pub pdos: Vec<PdoDesc>,
    /// `[nodes.NAME.supervision]`.
    pub supervision: NodeSupervision,
}

/// One `tpdoN` / `rpdoN` key.
#[derive(Clone, Debug, PartialEq)]
pub struct PdoDesc {
    /// Receive or transmit.
    pub dir: Direction,
    /// `N` (1-based, as in the key).
    pub number: u32,
    /// The key's span.
    pub key_span: Range<usize>,
    /// The mapped objects (names or indices), in order.
    pub map: Vec<Located<String>>,
    /// The span of the mapping list.
    pub map_span: Range<usize>,
    /// `transmission_type`.
    pub transmission_type: Option<Located<i128>>,
    /// `event_timer` in ms.
    pub event_timer: Option<Located<i128>>,
    /// `inhibit_time` in units of 100 µs (TPDO only).
    pub inhibit_time: Option<Located<i128>>,
}

/// The whole file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Description {
    /// `[network]`.
    pub network: NetworkDesc,
    /// `[nodes.*]`, in file order.
    pub nodes: Vec<NodeDesc>,
}

/// Reading context: the source for snippets, and the diagnostics found so far.
pub(crate) struct Reader<'a> {
    pub source: &'a eds::source::SourceFile,
    pub file: &'a str,
    pub diagnostics: Vec<Diagnostic>,
}

type Entry<'t, 'i> = (&'t Spanned<std::borrow::Cow<'i, str>>, &'t Spanned<DeValue<'i>>);

fn type_name(v: &DeValue<'_>) -> &'static str {
    match v {
        DeValue::String(_) => "a string",
        DeValue::Integer(_) => "an integer",
        DeValue::Float(_) => "a float",
        DeValue::Boolean(_) => "a boolean",
        DeValue::Datetime(_) => "a date-time",
        DeValue::Array(_) => "an array",
        DeValue::Table(_) => "a table",
    }
}

/// The table's entries in file order.
fn sorted<'t, 'i>(t: &'t DeTable<'i>) -> Vec<Entry<'t, 'i>> {
    let mut v: Vec<Entry<'t, 'i>> = t.iter().collect();
    v.sort_by_key(|(k, _)| k.span().start);
    v
}

impl<'a> Reader<'a> {
    pub(crate) fn snippet(&self, span: Range<usize>) -> Snippet {
        Snippet::at(self.source, self.file, span)
    }

    fn push(&mut self, d: Diagnostic) {
        self.diagnostics.push(d);
    }

    fn unknown_key(&mut self, key: &Spanned<std::borrow::Cow<'_, str>>, known: &[&str], context: &str) {
        let mut d = Diagnostic::error(codes::UNKNOWN_KEY, format!("unknown key `{}` in {context}", key.get_ref()))
            .at(self.snippet(key.span()));
        d = match suggest(key.get_ref(), known.iter().copied()).first() {
            Some(s) => d.help(format!("did you mean `{s}`?")),
            None => d.help(format!("the keys of {context} are {}", quoted_list(known))),
        };
        self.push(d);
    }

    fn wrong_type(&mut self, v: &Spanned<DeValue<'_>>, what: &str, expected: &str) {
        let d =
            Diagnostic::error(codes::WRONG_TYPE, format!("{what} must be {expected}, not {}", type_name(v.get_ref())))
                .at(self.snippet(v.span()));
        self.push(d);
    }

    fn string(&mut self, v: &Spanned<DeValue<'_>>, what: &str) -> Option<Located<String>> {
        match v.get_ref() {
            DeValue::String(s) => Some(Located { value: s.to_string(), span: v.span() }),
            _ => {
                self.wrong_type(v, what, "a string");
                None
            }
        }
    }

    fn integer(&mut self, v: &Spanned<DeValue<'_>>, what: &str) -> Option<Located<i128>> {
        match v.get_ref() {
            DeValue::Integer(i) => match i128::from_str_radix(i.as_str(), i.radix()) {
                Ok(value) => Some(Located { value, span: v.span() }),
                Err(_) => {
                    self.wrong_type(v, what, "an integer that fits 64 bits");
                    None
                }
            },
            _ => {
                self.wrong_type(v, what, "an integer");
                None
            }
        }
    }

    fn table<'t, 'i>(&mut self, v: &'t Spanned<DeValue<'i>>, what: &str) -> Option<&'t DeTable<'i>> {
        match v.get_ref() {
            DeValue::Table(t) => Some(t),
            _ => {
                self.wrong_type(v, what, "a table");
                None
            }
        }
    }

    /// Reads the whole document.
    pub(crate) fn document(&mut self, root: &DeTable<'_>) -> Description {
        let mut desc = Description::default();
        let mut nodes_seen = false;
        for (k, v) in sorted(root) {
            match k.get_ref().as_ref() {
                "network" => {
                    if let Some(t) = self.table(v, "`network`") {
                        desc.network = self.network(t);
                    }
                }
                "nodes" => {
                    nodes_seen = true;
                    if let Some(t) = self.table(v, "`nodes`") {
                        for (name, node) in sorted(t) {
                            if let Some(n) = self.node(name, node) {
                                desc.nodes.push(n);
                            }
                        }
                    }
                }
                _ => self.unknown_key(k, &["network", "nodes"], "the network file"),
            }
        }
        if !nodes_seen {
            self.push(
                Diagnostic::error(codes::NO_NODES, "the network has no nodes")
                    .at(self.snippet(0..0))
                    .help("add a node: `[nodes.x_axis]` with `device = \"...eds\"` and `node_id = 2`"),
            );
        }
        desc
    }

    fn network(&mut self, t: &DeTable<'_>) -> NetworkDesc {
        let mut n = NetworkDesc::default();
        for (k, v) in sorted(t) {
            match k.get_ref().as_ref() {
                "name" => n.name = self.string(v, "`name`"),
                "baud_rate" => n.baud_rate = self.integer(v, "`baud_rate`"),
                "supervision" => {
                    if let Some(t) = self.table(v, "`[network.supervision]`") {
                        n.supervision = self.network_supervision(t);
                    }
                }
                _ => self.unknown_key(k, &["name", "baud_rate", "supervision"], "`[network]`"),
            }
        }
        n
    }

    fn node(&mut self, name: &Spanned<std::borrow::Cow<'_, str>>, v: &Spanned<DeValue<'_>>) -> Option<NodeDesc> {
        let node_name = name.get_ref().to_string();
        let what = format!("node `{node_name}`");
        let t = self.table(v, &what)?;
        if node_name.is_empty() || !node_name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
            self.push(
                Diagnostic::error(codes::BAD_NODE_NAME, format!("node name `{node_name}` cannot be a file name"))
                    .at(self.snippet(name.span()))
                    .help("node names are the DCF file names: use letters, digits, `_` and `-`"),
            );
        }
        let mut node = NodeDesc {
            name: Located { value: node_name.clone(), span: name.span() },
            device: None,
            node_id: None,
            baud_rate: None,
            serial: None,
            lss: false,
            lss_store: true,
            parameters: Vec::new(),
            pdos: Vec::new(),
            supervision: NodeSupervision::default(),
        };
        const KNOWN: &[&str] = &[
            "device",
            "node_id",
            "baud_rate",
            "serial",
            "lss",
            "lss_store",
            "parameters",
            "supervision",
            "tpdoN",
            "rpdoN",
        ];
        let mut present = (false, false);
        let (mut lss_span, mut lss_store_span) = (None, None);
        for (k, v) in sorted(t) {
            let key = k.get_ref().as_ref();
            match key {
                "device" => {
                    present.0 = true;
                    node.device = self.string(v, "`device`");
                }
                "node_id" => {
                    present.1 = true;
                    node.node_id = self.integer(v, "`node_id`");
                }
                "baud_rate" => node.baud_rate = self.integer(v, "`baud_rate`"),
                "serial" => node.serial = self.integer(v, "`serial`"),
                "lss" => {
                    node.lss = self.boolean(v, "`lss`").unwrap_or(false);
                    lss_span = Some(v.span());
                }
                "lss_store" => {
                    node.lss_store = self.boolean(v, "`lss_store`").unwrap_or(true);
                    lss_store_span = Some(v.span());
                }
                "supervision" => {
                    if let Some(t) = self.table(v, "`supervision`") {
                        node.supervision = self.node_supervision(t, &node_name);
                    }
                }
                "parameters" => {
                    if let Some(p) = self.table(v, "`parameters`") {
                        for (pk, pv) in sorted(p) {
                            if let Some(s) = self.scalar(pv, pk.get_ref()) {
                                node.parameters.push((Located { value: pk.get_ref().to_string(), span: pk.span() }, s));
                            }
                        }
                    }
                }
                _ => match pdo_key(key) {
                    Some((dir, number)) => {
                        if let Some(p) = self.pdo(dir, number, k.span(), v) {
                            node.pdos.push(p);
                        }
                    }
                    None => self.unknown_key(k, KNOWN, &format!("node `{node_name}`")),
                },
            }
        }
        if !present.0 {
            self.push(
                Diagnostic::error(codes::MISSING_KEY, format!("node `{node_name}` has no `device`"))
                    .at(self.snippet(name.span()))
                    .help("name its device description: `device = \"../devices/x.eds\"` (relative to this file)"),
            );
        }
        if !present.1 {
            self.push(
                Diagnostic::error(codes::MISSING_KEY, format!("node `{node_name}` has no `node_id`"))
                    .at(self.snippet(name.span()))
                    .help("give it a node id from 1 to 127: `node_id = 2`"),
            );
        }
        if let Some(span) = lss_span
            && node.lss
            && node.serial.is_none()
        {
            self.push(
                Diagnostic::error(
                    codes::MISSING_KEY,
                    format!("node `{node_name}`: `lss = true` needs the device's serial number"),
                )
                .at(self.snippet(span))
                .help("LSS finds the device by its identity: add `serial = N` (its 1018h sub 4)"),
            );
        }
        if let Some(span) = lss_store_span
            && !node.lss
        {
            self.push(
                Diagnostic::error(codes::BAD_VALUE, format!("node `{node_name}`: `lss_store` without `lss = true`"))
                    .at(self.snippet(span))
                    .help("add `lss = true` (the node-ID given over LSS at boot), or remove `lss_store`"),
            );
        }
        Some(node)
    }

    fn boolean(&mut self, v: &Spanned<DeValue<'_>>, what: &str) -> Option<bool> {
        match v.get_ref() {
            DeValue::Boolean(b) => Some(*b),
            _ => {
                self.wrong_type(v, what, "true or false");
                None
            }
        }
    }

    /// An integer within `range`, or a diagnostic saying so.
    fn bounded(&mut self, v: &Spanned<DeValue<'_>>, what: &str, range: std::ops::RangeInclusive<i128>) -> Option<i128> {
        let n = self.integer(v, what)?;
        if range.contains(&n.value) {
            return Some(n.value);
        }
        self.push(
            Diagnostic::error(
                codes::BAD_VALUE,
                format!("{what} is {}, outside {}..={}", n.value, range.start(), range.end()),
            )
            .at(self.snippet(n.span))
            .help(format!("give {what} a value from {} to {}", range.start(), range.end())),
        );
        None
    }

    fn failure_action(&mut self, v: &Spanned<DeValue<'_>>, what: &str) -> Option<FailureAction> {
        let s = self.string(v, what)?;
        if let Some((a, _)) = FailureAction::ALL.iter().find(|(_, n)| *n == s.value) {
            return Some(*a);
        }
        let names: Vec<&str> = FailureAction::ALL.iter().map(|(_, n)| *n).collect();
        let mut d = Diagnostic::error(codes::BAD_VALUE, format!("{what} is `{}`, not an action", s.value))
            .at(self.snippet(s.span));
        d = match suggest(&s.value, names.iter().copied()).first() {
            Some(near) => d.help(format!("did you mean `{near}`? (the actions are {})", quoted_list(&names))),
            None => d.help(format!("the actions are {}", quoted_list(&names))),
        };
        self.push(d);
        None
    }

    /// `[network.supervision]`.
    fn network_supervision(&mut self, t: &DeTable<'_>) -> NetworkSupervision {
        let mut n = NetworkSupervision::default();
        const KNOWN: &[&str] = &NetworkSupervision::KEYS;
        for (k, v) in sorted(t) {
            match k.get_ref().as_ref() {
                "on_mandatory_failure" => {
                    if let Some(a) = self.failure_action(v, "`on_mandatory_failure`") {
                        n.on_mandatory_failure = a;
                    }
                }
                "boot_attempts" => {
                    if let Some(a) = self.bounded(v, "`boot_attempts`", wide(NetworkSupervision::BOOT_ATTEMPTS)) {
                        n.boot_attempts = a as u32;
                    }
                }
                _ => self.unknown_key(k, KNOWN, "`[network.supervision]`"),
            }
        }
        n
    }

    /// `[nodes.NAME.supervision]`.
    fn node_supervision(&mut self, t: &DeTable<'_>, node_name: &str) -> NodeSupervision {
        let mut n = NodeSupervision::default();
        const KNOWN: &[&str] = &NodeSupervision::KEYS;
        let mut on_lost_span = None;
        for (k, v) in sorted(t) {
            match k.get_ref().as_ref() {
                "mandatory" => n.mandatory = self.boolean(v, "`mandatory`").unwrap_or(n.mandatory),
                "keep_alive" => n.keep_alive = self.boolean(v, "`keep_alive`").unwrap_or(n.keep_alive),
                "configure" => n.configure = self.boolean(v, "`configure`").unwrap_or(n.configure),
                "start" => n.start = self.boolean(v, "`start`").unwrap_or(n.start),
                "on_lost" => {
                    if let Some(a) = self.failure_action(v, "`on_lost`") {
                        n.on_lost = a;
                        on_lost_span = Some(v.span());
                    }
                }
                "heartbeat_timeout_ms" => {
                    n.heartbeat_timeout_ms = self
                        .bounded(v, "`heartbeat_timeout_ms`", wide(NodeSupervision::HEARTBEAT_TIMEOUT_MS))
                        .map(|x| x as u32)
                        .or(n.heartbeat_timeout_ms)
                }
                "guard_time_ms" => {
                    n.guard_time_ms = self
                        .bounded(v, "`guard_time_ms`", wide(NodeSupervision::GUARD_TIME_MS))
                        .map_or(n.guard_time_ms, |x| x as u16)
                }
                "life_time_factor" => {
                    n.life_time_factor = self
                        .bounded(v, "`life_time_factor`", wide(NodeSupervision::LIFE_TIME_FACTOR))
                        .map_or(n.life_time_factor, |x| x as u8)
                }
                "reset_delay_ms" => {
                    n.reset_delay_ms = self
                        .bounded(v, "`reset_delay_ms`", wide(NodeSupervision::RESET_DELAY_MS))
                        .map_or(n.reset_delay_ms, |x| x as u32)
                }
                _ => self.unknown_key(k, KNOWN, &format!("the supervision of node `{node_name}`")),
            }
        }
        if let Some(span) = on_lost_span
            && n.on_lost.is_network_wide()
            && !n.mandatory
        {
            self.push(
                Diagnostic::error(
                    codes::BAD_VALUE,
                    format!(
                        "node `{node_name}`: `on_lost = \"{}\"` acts on every node, which only a mandatory node may",
                        n.on_lost.name()
                    ),
                )
                .at(self.snippet(span))
                .help("add `mandatory = true`, or use `\"reset_node\"` or `\"report\"`"),
            );
        }
        n
    }

    fn scalar(&mut self, v: &Spanned<DeValue<'_>>, key: &str) -> Option<Located<Scalar>> {
        let value = match v.get_ref() {
            DeValue::Integer(i) => match i128::from_str_radix(i.as_str(), i.radix()) {
                Ok(value) => Scalar::Int { value, hex: i.radix() == 16 },
                Err(_) => {
                    self.wrong_type(v, &format!("`{key}`"), "an integer that fits 64 bits");
                    return None;
                }
            },
            DeValue::Float(f) => match f.as_str().parse::<f64>() {
                Ok(x) => Scalar::Float(x),
                Err(_) => {
                    self.wrong_type(v, &format!("`{key}`"), "a finite number");
                    return None;
                }
            },
            DeValue::Boolean(b) => Scalar::Bool(*b),
            DeValue::String(s) => Scalar::Str(s.to_string()),
            _ => {
                self.wrong_type(v, &format!("`{key}`"), "an integer, a float, a boolean or a string");
                return None;
            }
        };
        Some(Located { value, span: v.span() })
    }

    fn map_list(&mut self, v: &Spanned<DeValue<'_>>, what: &str) -> Option<Vec<Located<String>>> {
        let DeValue::Array(items) = v.get_ref() else {
            self.wrong_type(v, what, "an array of object names");
            return None;
        };
        let mut out = Vec::new();
        for item in items {
            if let Some(s) = self.string(item, &format!("an entry of {what}")) {
                out.push(s);
            }
        }
        Some(out)
    }

    fn pdo(
        &mut self,
        dir: Direction,
        number: u32,
        key_span: Range<usize>,
        v: &Spanned<DeValue<'_>>,
    ) -> Option<PdoDesc> {
        let name = pdo_name(dir, number);
        let mut pdo = PdoDesc {
            dir,
            number,
            key_span: key_span.clone(),
            map: Vec::new(),
            map_span: v.span(),
            transmission_type: None,
            event_timer: None,
            inhibit_time: None,
        };
        match v.get_ref() {
            DeValue::Array(_) => pdo.map = self.map_list(v, &format!("`{name}`"))?,
            DeValue::Table(t) => {
                let mut have_map = false;
                for (k, v) in sorted(t) {
                    match k.get_ref().as_ref() {
                        "map" => {
                            have_map = true;
                            pdo.map_span = v.span();
                            pdo.map = self.map_list(v, "`map`")?;
                        }
                        "transmission_type" => pdo.transmission_type = self.integer(v, "`transmission_type`"),
                        "event_timer" => pdo.event_timer = self.integer(v, "`event_timer`"),
                        "inhibit_time" => pdo.inhibit_time = self.integer(v, "`inhibit_time`"),
                        _ => self.unknown_key(
                            k,
                            &["map", "transmission_type", "event_timer", "inhibit_time"],
                            &format!("`{name}`"),
                        ),
                    }
                }
                if !have_map {
                    self.push(
                        Diagnostic::error(codes::MISSING_KEY, format!("`{name}` has no `map`"))
                            .at(self.snippet(key_span))
                            .help("list the mapped objects: `map = [\"statusword\"]` (an empty list disables the PDO)"),
                    );
                    return None;
                }
            }
            _ => {
                self.wrong_type(v, &format!("`{name}`"), "an array of object names or a table with `map`");
                return None;
            }
        }
        Some(pdo)
    }
}

/// `tpdo3` → (Transmit, 3).
fn pdo_key(key: &str) -> Option<(Direction, u32)> {
    let (dir, rest) = if let Some(r) = key.strip_prefix("tpdo") {
        (Direction::Transmit, r)
    } else {
        (Direction::Receive, key.strip_prefix("rpdo")?)
    };
    if rest.is_empty() || !rest.bytes().all(|b| b.is_ascii_digit()) || rest.starts_with('0') || rest.len() > 3 {
        return None;
    }
    Some((dir, rest.parse().ok()?))
}

/// `TPDO 3`.
pub fn pdo_name(dir: Direction, number: u32) -> String {
    match dir {
        Direction::Transmit => format!("TPDO {number}"),
        Direction::Receive => format!("RPDO {number}"),
    }
}

fn quoted_list(items: &[&str]) -> String {
    items.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", ")
}

/// A range of the supervision settings as the reader's integers.
fn wide<T: Copy + Into<i128>>(r: std::ops::RangeInclusive<T>) -> std::ops::RangeInclusive<i128> {
    (*r.start()).into()..=(*r.end()).into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pdo_keys() {
        assert_eq!(pdo_key("tpdo1"), Some((Direction::Transmit, 1)));
        assert_eq!(pdo_key("rpdo12"), Some((Direction::Receive, 12)));
        assert_eq!(pdo_key("tpdo0"), None);
        assert_eq!(pdo_key("tpdo"), None);
        assert_eq!(pdo_key("tpdo01"), None);
        assert_eq!(pdo_key("xpdo1"), None);
    }
}
