//! DCFs for a whole network, from one TOML description.
//!
//! A network file names each node's device description, node id and bit rate, the parameters to
//! configure and the PDO mappings, by the same names the generated Rust uses. [`build`] checks
//! everything (node ids, bit rates, names, and every mapping with the PDO rules the device runtime
//! applies, `od_runtime::pdo::check_entry` through `crate::pdo::MappingChecker`) and gives
//! one DCF per node, written by `eds::write::write_dcf` after `eds::write::configure`; or, if
//! anything is wrong, every problem as a [`Diagnostic`] located in the TOML file (with the
//! device description's object as a second location).
//!
//! # The format
//!
//! ```toml
//! [network]
//! name = "line"          # optional: NetworkName in each DCF
//! baud_rate = 1000       # kbit/s; every device must support it
//!
//! [nodes.x_axis]         # the node's name: NodeName, and the DCF is x_axis.dcf
//! device = "../devices/camozzi-drvi.eds"   # relative to this file
//! node_id = 2
//! # baud_rate = 1000     # optional; must equal [network] baud_rate (one bus, one bit rate)
//! tpdo1 = ["statusword", "position_actual_value"]
//! rpdo1 = ["controlword", "target_position"]
//!
//! [nodes.x_axis.tpdo2]   # the long form, with communication settings
//! map = ["modes_of_operation_display", "velocity_actual_value"]
//! transmission_type = 255  # 0-240 SYNC, 252-253 RTR (TPDO), 254-255 event-driven
//! event_timer = 10         # ms (sub-index 5)
//! inhibit_time = 50        # units of 100 µs (sub-index 3; TPDOs only)
//!
//! [nodes.x_axis.parameters]
//! producer_heartbeat_time = 100            # by name
//! "0x6060sub0" = 1                         # by index (hex) and sub-index (hex)
//! identity_object_vendor_id = "0x151"      # strings are read like EDS values ($NODEID+0x180, text)
//! ```
//!
//! Names are the `snake_case` identifiers of `ParameterName` (see [`names`]); a mapping list
//! may also hold indices (`"0x6041"`, `"0x6041sub0"`). Each mapped object is mapped with its data
//! type's length. A PDO key sets sub-index 0 and the entries of the mapping object, and makes
//! the PDO valid (bit 31 of its COB-ID cleared); an empty list (`tpdo3 = []`) disables it. PDOs
//! the file does not mention keep the device's defaults.
//!
//! # What the DCFs contain
//!
//! Each DCF is the device's EDS with `[DeviceComissioning]` (`NodeID`, `NodeName`, `Baudrate`,
//! `NetworkName`), `FileName` set to the DCF's name, and a `ParameterValue` on every configured
//! entry. Every entry whose value depends on the node id gets that value resolved as its
//! `ParameterValue` (`0x00000182` for node 2), while its `DefaultValue` keeps `$NODEID+0x180`.
//! Nothing is written when anything is wrong.

/// The writes of a concise DCF: `eds::concise`, beside the reader, so that a master boots
/// from DCFs without the generator.
pub use eds::concise;
pub mod desc;
pub mod diag;
pub mod names;
mod node;

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Component, Path, PathBuf};

use eds::model::{Index, Model, SubIndex, Value};
use eds::source::SourceFile;

use diag::codes;
pub use diag::{Diagnostic, Severity, Snippet, render, render_all};
use node::{Configured, Device, NodeCtx};

/// The DCF of one node.
#[derive(Clone, Debug)]
pub struct NodeDcf {
    /// The node's name (its table key).
    pub name: String,
    /// Its node id.
    pub node_id: u8,
    /// The device description it was configured from, as shown in diagnostics.
    pub device: String,
    /// `{name}.dcf`.
    pub file_name: String,
    /// The configured model.
    pub model: Model,
    /// The DCF text (`eds::write::write_dcf` of `model`).
    pub text: String,
    /// How the master supervises it after boot (`[nodes.NAME.supervision]`).
    pub supervision: desc::NodeSupervision,
    /// `lss`: the master gives it its node-ID over LSS before booting (found by the DCF's
    /// identity and `LSS_SerialNumber`).
    pub lss: bool,
    /// `lss_store`: that node-ID stored in the device.
    pub lss_store: bool,
}

/// What [`build`] made: the DCFs (none if anything is wrong) and every diagnostic.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    /// One DCF per node, in the order of the file; empty when there are errors.
    pub dcfs: Vec<NodeDcf>,
    /// Every problem found, in the order found (file order within each stage).
    pub diagnostics: Vec<Diagnostic>,
    /// How the master supervises the network after boot (`[network.supervision]`).
    pub supervision: desc::NetworkSupervision,
}

impl Outcome {
    /// Whether any diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }
}

/// Reads the network file at `path` and builds its DCFs. Device paths are relative to the
/// file's directory. Fails only when the file itself cannot be read.
pub fn build_file(path: &Path) -> std::io::Result<Outcome> {
    let text = std::fs::read_to_string(path)?;
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    Ok(build(&path.display().to_string(), dir, &text))
}

/// Builds the DCFs of a network description.
///
/// `display` is the file name shown in diagnostics; device paths are opened relative to `dir`
/// and shown relative to `display`'s directory.
pub fn build(display: &str, dir: &Path, text: &str) -> Outcome {
    let source = SourceFile::from_str(display, text);
    let mut reader = desc::Reader { source: &source, file: display, diagnostics: Vec::new() };
    let root = match toml::de::DeTable::parse(text) {
        Ok(t) => t,
        Err(e) => {
            let span = e.span().unwrap_or(0..0);
            let message = e.message().trim().to_owned();
            let d =
                Diagnostic::error(codes::TOML_SYNTAX, format!("not valid TOML: {message}")).at(reader.snippet(span));
            return Outcome { dcfs: Vec::new(), diagnostics: vec![d], supervision: Default::default() };
        }
    };
    let description = reader.document(root.get_ref());
    let mut diags = std::mem::take(&mut reader.diagnostics);
    let network = &description.network;

    // Bit rate: one per bus.
    if let Some(b) = &network.baud_rate {
        check_standard_baud(&reader, b, &mut diags);
    }
    let mut bus_baud: Option<(i128, Range<usize>)> = network.baud_rate.as_ref().map(|b| (b.value, b.span.clone()));

    let display_dir = Path::new(display).parent().map(Path::to_path_buf).unwrap_or_default();
    let mut devices: BTreeMap<PathBuf, Option<Device>> = BTreeMap::new();
    let mut ids: BTreeMap<u8, (String, Range<usize>)> = BTreeMap::new();
    let mut dcfs = Vec::new();
    for node in &description.nodes {
        let name = &node.name.value;
        let node_errors_before = diags.len();

        // Node id.
        let node_id = node.node_id.as_ref().and_then(|id| {
            if (1..=127).contains(&id.value) {
                let v = id.value as u8;
                if let Some((first, first_span)) = ids.get(&v) {
                    diags.push(
                        Diagnostic::error(
                            codes::NODE_ID_COLLISION,
                            format!("node id {v} is taken by node `{first}`; each node on a bus needs its own id"),
                        )
                        .at(reader.snippet(id.span.clone()))
                        .context(format!("node `{name}`"))
                        .note(format!("node `{first}` has node id {v} here"), Some(reader.snippet(first_span.clone())))
                        .help(free_ids_help(&ids)),
                    );
                    None
                } else {
                    ids.insert(v, (name.clone(), id.span.clone()));
                    Some(v)
                }
            } else {
                diags.push(
                    Diagnostic::error(codes::BAD_NODE_ID, format!("node id {} is outside 1..=127", id.value))
                        .at(reader.snippet(id.span.clone()))
                        .context(format!("node `{name}`"))
                        .help("CANopen node ids are 1 to 127 (0 addresses all nodes in NMT commands)"),
                );
                None
            }
        });

        // Serial number (LSS).
        let serial = node.serial.as_ref().and_then(|s| match u32::try_from(s.value) {
            Ok(v) => Some(v),
            Err(_) => {
                diags.push(
                    Diagnostic::error(codes::BAD_VALUE, format!("serial number {} is outside 0..=4294967295", s.value))
                        .at(reader.snippet(s.span.clone()))
                        .context(format!("node `{name}`"))
                        .help("the serial number is the device's 1018h sub 4, an UNSIGNED32"),
                );
                None
            }
        });

        // Bit rate.
        let baud: Option<(i128, Range<usize>)> = match (&node.baud_rate, &bus_baud) {
            (Some(b), Some((bus, bus_span))) => {
                if b.value != *bus {
                    diags.push(
                        Diagnostic::error(
                            codes::BAUD_RATE_MISMATCH,
                            format!("node `{name}` is set to {} kbit/s, but the bus runs at {bus} kbit/s", b.value),
                        )
                        .at(reader.snippet(b.span.clone()))
                        .note("the bus bit rate is set here", Some(reader.snippet(bus_span.clone())))
                        .help("all nodes on one bus use one bit rate"),
                    );
                    None
                } else {
                    Some((b.value, b.span.clone()))
                }
            }
            (Some(b), None) => {
                check_standard_baud(&reader, b, &mut diags);
                bus_baud = Some((b.value, b.span.clone()));
                Some((b.value, b.span.clone()))
            }
            (None, Some(bus)) => Some(bus.clone()),
            (None, None) => {
                diags.push(
                    Diagnostic::error(codes::BAUD_RATE_MISMATCH, format!("no bit rate for node `{name}`"))
                        .at(reader.snippet(node.name.span.clone()))
                        .help("set the bus bit rate: `[network]` `baud_rate = 500` (kbit/s)"),
                );
                None
            }
        };

        // Device description.
        let Some(device_path) = &node.device else { continue };
        let path = dir.join(&device_path.value);
        let shown = normalize(&display_dir.join(&device_path.value)).display().to_string();
        let device = devices
            .entry(path.clone())
            .or_insert_with(|| load_device(&path, &shown, &reader, &device_path.span, &mut diags));
        let Some(device) = device.as_ref() else {
            if !diags[node_errors_before..]
                .iter()
                .any(|d| d.code == codes::DEVICE_UNREADABLE || d.code == codes::DEVICE_ERRORS)
            {
                // Loaded (and reported) for an earlier node.
                diags.push(
                    Diagnostic::error(
                        codes::DEVICE_ERRORS,
                        format!("the device description of node `{name}` cannot be used (see above)"),
                    )
                    .at(reader.snippet(device_path.span.clone())),
                );
            }
            continue;
        };
        let context = format!("node `{name}` ({})", device.display);

        // The device must support the bit rate.
        let baud = baud.filter(|(b, _)| u16::try_from(*b).is_ok_and(|b| eds::write::STANDARD_BAUD_RATES.contains(&b)));
        if let Some((b, span)) = &baud {
            let rates = &device.parsed.model.device_info.baud_rates;
            if !rates.is_empty() && rates.get(&(*b as u16)) != Some(&true) {
                let supported: Vec<String> = rates.iter().filter(|(_, on)| **on).map(|(r, _)| r.to_string()).collect();
                let key = format!("BaudRate_{b}");
                diags.push(
                    Diagnostic::error(
                        codes::UNSUPPORTED_BAUD_RATE,
                        format!("the device of node `{name}` does not support {b} kbit/s"),
                    )
                    .at(reader.snippet(span.clone()))
                    .context(context.clone())
                    .note(format!("{key} is not 1 in the device description"), device.device_info_key(&key))
                    .help(if supported.is_empty() {
                        "the device declares no bit rate".to_owned()
                    } else {
                        format!("it supports {} kbit/s", supported.join(", "))
                    }),
                );
            }
        }
        // With a bad or taken node id, the values are still checked (with a stand-in id for
        // `$NODEID`), so that one run reports every problem; no DCF is written then.
        let node_id_ok = node_id.is_some();
        let node_id = node_id.unwrap_or(1);

        // Values.
        let ctx = NodeCtx { reader: &reader, device, node, node_id, context: context.clone() };
        let mut values: Vec<Configured> = Vec::new();
        ctx.parameters(&mut values, &mut diags);
        let checker = crate::pdo::MappingChecker::new(
            &device.parsed.model,
            &crate::Options::new("network", device.display.clone()),
        );
        for pdo in &node.pdos {
            ctx.pdo(pdo, &checker, &mut values, &mut diags);
        }

        // One value per entry.
        let mut first: BTreeMap<(u16, u8), usize> = BTreeMap::new();
        let mut unique: Vec<Configured> = Vec::new();
        for v in values {
            if let Some(&i) = first.get(&(v.index, v.sub)) {
                let earlier: &Configured = &unique[i];
                diags.push(
                    Diagnostic::error(
                        codes::CONFIGURED_TWICE,
                        format!(
                            "0x{:04X} sub {} is configured twice: by {} and by {}",
                            v.index, v.sub, earlier.what, v.what
                        ),
                    )
                    .at(reader.snippet(v.span.clone()))
                    .context(context.clone())
                    .note(format!("{} sets it here", earlier.what), Some(reader.snippet(earlier.span.clone())))
                    .help("give each entry one value"),
                );
                continue;
            }
            first.insert((v.index, v.sub), unique.len());
            unique.push(v);
        }
        let clean = diags.len() == node_errors_before && node_id_ok;

        let pairs: Vec<(u16, u8, Value)> = unique.iter().map(|v| (v.index, v.sub, v.value.clone())).collect();
        let baud_kbit = baud.as_ref().map(|(b, _)| *b as u16);
        let configured =
            eds::write::configure(&device.parsed.model, node_id, if clean { baud_kbit } else { None }, &pairs);
        let mut model = match configured {
            Ok(_) if !clean => continue,
            Ok(m) => m,
            Err(e) => {
                // Problems without a target are about the node id and bit rate, which are
                // reported above with their locations.
                for p in e.problems.into_iter().filter(|p| p.target.is_some()) {
                    let origin =
                        p.target.and_then(|(Index(i), SubIndex(s))| unique.iter().find(|v| v.index == i && v.sub == s));
                    let span = origin.map(|o| o.span.clone()).unwrap_or(node.name.span.clone());
                    let mut d = Diagnostic::error(codes::BAD_VALUE, p.message.clone())
                        .at(reader.snippet(span))
                        .context(context.clone());
                    if let Some(o) = origin {
                        d = d.context(o.what.clone());
                    }
                    if let (Some(at), Some((Index(i), SubIndex(s)))) = (p.at, p.target) {
                        let label = node::entry_label(&device.parsed.model, i, s);
                        d = d.note(format!("{label} is defined here"), device.snippet(at));
                    }
                    if let Some(h) = p.hint {
                        d = d.help(h);
                    }
                    diags.push(d);
                }
                continue;
            }
        };
        resolve_node_id_values(&mut model, node_id);
        let file_name = format!("{name}.dcf");
        model.file_info.file_name = Some(file_name.clone());
        if let Some(c) = model.commissioning.as_mut() {
            c.node_name = Some(name.clone());
            c.network_name = network.name.as_ref().map(|n| n.value.clone());
            c.lss_serial_number = serial.or(c.lss_serial_number);
        }
        let text = eds::write::write_dcf(&model);
        dcfs.push(NodeDcf {
            name: name.clone(),
            node_id,
            device: device.display.clone(),
            file_name,
            model,
            text,
            supervision: node.supervision,
            lss: node.lss,
            lss_store: node.lss_store,
        });
    }
    // File order: each diagnostic at its place in the network file (stable, so that those at
    // one place keep the order they were found in).
    diags.sort_by_key(|d| match &d.at {
        Some(s) if s.file == display => (s.line, s.col),
        _ => (u32::MAX, 0),
    });
    let failed = diags.iter().any(|d| d.severity == Severity::Error);
    let supervision = description.network.supervision;
    Outcome { dcfs: if failed { Vec::new() } else { dcfs }, diagnostics: diags, supervision }
}

/// Every `$NODEID` value gets its resolved `ParameterValue` (the DefaultValue keeps the
/// expression).
fn resolve_node_id_values(model: &mut Model, node_id: u8) {
    for obj in model.objects.values_mut() {
        for e in obj.subs.values_mut() {
            let source = match (e.parameter_value(), &e.default) {
                (Some(v @ Value::NodeIdPlus { .. }), _) => Some(v.clone()),
                (None, Some(v @ Value::NodeIdPlus { .. })) => Some(v.clone()),
                _ => None,
            };
            if let Some(v) = source.and_then(|v| v.resolve(node_id)) {
                e.set_parameter_value(Some(Value::hex(v)));
            }
        }
    }
}

fn check_standard_baud(reader: &desc::Reader<'_>, b: &desc::Located<i128>, diags: &mut Vec<Diagnostic>) {
    if !eds::write::STANDARD_BAUD_RATES.iter().any(|&r| i128::from(r) == b.value) {
        diags.push(
            Diagnostic::error(codes::BAD_BAUD_RATE, format!("{} kbit/s is not a CANopen bit rate", b.value))
                .at(reader.snippet(b.span.clone()))
                .help(format!(
                    "use one of {} (kbit/s)",
                    eds::write::STANDARD_BAUD_RATES.iter().map(|r| r.to_string()).collect::<Vec<_>>().join(", ")
                )),
        );
    }
}

fn free_ids_help(ids: &BTreeMap<u8, (String, Range<usize>)>) -> String {
    match (1..=127u8).find(|i| !ids.contains_key(i)) {
        Some(free) => format!("node id {free} is free"),
        None => "all 127 node ids are taken".to_owned(),
    }
}

fn load_device(
    path: &Path,
    shown: &str,
    reader: &desc::Reader<'_>,
    span: &Range<usize>,
    diags: &mut Vec<Diagnostic>,
) -> Option<Device> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) => {
            diags.push(
                Diagnostic::error(codes::DEVICE_UNREADABLE, format!("cannot read the device description {shown}: {e}"))
                    .at(reader.snippet(span.clone()))
                    .help("device paths are relative to the network file"),
            );
            return None;
        }
    };
    let parsed = eds::parse(shown, &bytes, &eds::Options::lenient());
    if parsed.has_errors() {
        let count = parsed.errors().count();
        let mut d = Diagnostic::error(
            codes::DEVICE_ERRORS,
            format!("the device description {shown} has {count} error{}", if count == 1 { "" } else { "s" }),
        )
        .at(reader.snippet(span.clone()))
        .help(format!("`odgen check {shown}` lists them; fix them before configuring the device"));
        if let Some(first) = parsed.errors().next() {
            let at = first.span.map(|s| Snippet::at(&parsed.document.source, shown, s.start as usize..s.end as usize));
            d = d.note(format!("first: {}", first.message), at);
        }
        diags.push(d);
        return None;
    }
    let names = names::NameIndex::new(&parsed.model);
    Some(Device { display: shown.to_owned(), parsed, names })
}

/// `networks/../devices/x.eds` → `devices/x.eds` (lexically; leading `..` kept).
fn normalize(p: &Path) -> PathBuf {
    let mut out: Vec<Component<'_>> = Vec::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out.iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalizes_paths() {
        assert_eq!(normalize(Path::new("networks/../devices/x.eds")), PathBuf::from("devices/x.eds"));
        assert_eq!(normalize(Path::new("../devices/x.eds")), PathBuf::from("../devices/x.eds"));
        assert_eq!(normalize(Path::new("./a/./b.eds")), PathBuf::from("a/b.eds"));
    }
}
