//! One node: its parameters and PDOs turned into configured values, each remembering where in
//! the network file it came from.

use std::ops::Range;

use crate::pdo::MappingChecker;
use eds::model::{DataType, Entry, Model, Value};
use od_runtime::pdo::Direction;

use super::desc::{Located, NodeDesc, PdoDesc, Reader, Scalar, pdo_name};
use super::diag::{Diagnostic, Snippet, codes};
use super::names::{NameIndex, Named};

/// A device description as read for the network.
pub(crate) struct Device {
    /// The path shown in diagnostics.
    pub display: String,
    /// What was read.
    pub parsed: eds::Parsed,
    /// Its entry names.
    pub names: NameIndex,
}

impl Device {
    /// The quoted section of an object or entry.
    pub fn snippet(&self, at: eds::model::SourceRef) -> Option<Snippet> {
        Snippet::eds(&self.parsed.document.source, &self.display, at)
    }

    /// The quoted line of a `[DeviceInfo]` key (`NrOfTXPDO`, `BaudRate_500`), if the file has it.
    pub fn device_info_key(&self, key: &str) -> Option<Snippet> {
        let doc = &self.parsed.document;
        let section =
            doc.sections().into_iter().find(|s| doc.source.slice(s.name).trim().eq_ignore_ascii_case("DeviceInfo"))?;
        let line = section
            .entries
            .iter()
            .copied()
            .find(|&l| doc.entry(l).is_some_and(|(k, _)| k.eq_ignore_ascii_case(key)))?;
        let start = doc.lines()[line].content.start as usize;
        let end = doc.lines()[line].content.end as usize;
        let mut s = Snippet::at(&doc.source, &self.display, start..end);
        s.width = 0;
        Some(s)
    }

    fn model(&self) -> &Model {
        &self.parsed.model
    }
}

/// One value to configure, with its origin in the network file.
#[derive(Clone, Debug)]
pub(crate) struct Configured {
    pub index: u16,
    pub sub: u8,
    pub value: Value,
    pub span: Range<usize>,
    /// What set it: `parameter \`x\``, `TPDO 1 mapping`, ...
    pub what: String,
}

/// Node-level context for diagnostics.
pub(crate) struct NodeCtx<'a> {
    pub reader: &'a Reader<'a>,
    pub device: &'a Device,
    pub node: &'a NodeDesc,
    pub node_id: u8,
    pub context: String,
}

impl NodeCtx<'_> {
    fn error(&self, code: &'static str, message: impl Into<String>, span: Range<usize>) -> Diagnostic {
        Diagnostic::error(code, message).at(self.reader.snippet(span)).context(self.context.clone())
    }

    fn entry_label(&self, index: u16, sub: u8) -> String {
        entry_label(self.device.model(), index, sub)
    }

    fn entry_note(&self, d: Diagnostic, index: u16, sub: u8, what: &str) -> Diagnostic {
        let Some(e) = self.device.model().entry(index, sub) else { return d };
        d.note(format!("{} {what}", self.entry_label(index, sub)), self.device.snippet(e.at))
    }

    /// Resolves a name or `0xIIII` / `0xIIIIsubSS` to an entry, or explains why not.
    // The error is a whole diagnostic, built once per bad name: its size does not matter.
    #[allow(clippy::result_large_err)]
    fn resolve(&self, name: &Located<String>, role: &str) -> Result<(u16, u8), Diagnostic> {
        let text = name.value.trim();
        let m = self.device.model();
        if let Some(rest) = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
            let lower = rest.to_ascii_lowercase();
            let (i, s) = match lower.split_once("sub") {
                Some((i, s)) => (i, Some(s.strip_prefix("0x").unwrap_or(s))),
                None => (lower.as_str(), None),
            };
            let bad = || {
                self.error(codes::UNKNOWN_OBJECT, format!("`{text}` is not an index"), name.span.clone())
                    .help("write an index as `0x6041` or `0x1A00sub1` (hexadecimal), or use the entry's name")
            };
            let index = u16::from_str_radix(i, 16).map_err(|_| bad())?;
            let sub = match s {
                Some(s) => u8::from_str_radix(s, 16).map_err(|_| bad())?,
                None => 0,
            };
            let Some(obj) = m.object(index) else {
                return Err(self.error(
                    codes::UNKNOWN_OBJECT,
                    format!("the device has no object 0x{index:04X}"),
                    name.span.clone(),
                ));
            };
            if s.is_none() && obj.object_type.has_subs() {
                return Err(self
                    .error(
                        codes::NOT_AN_ENTRY,
                        format!(
                            "0x{index:04X} \"{}\" is {}: {role} needs one of its entries",
                            obj.name,
                            kind_name(obj.object_type)
                        ),
                        name.span.clone(),
                    )
                    .help(format!("name a sub-index: `0x{index:04X}sub1`")));
            }
            if obj.sub(sub).is_none() {
                let subs: Vec<String> = obj.subs.keys().map(|s| format!("{:X}", s.0)).collect();
                return Err(self
                    .error(
                        codes::UNKNOWN_OBJECT,
                        format!("object 0x{index:04X} \"{}\" has no sub-index 0x{sub:X}", obj.name),
                        name.span.clone(),
                    )
                    .help(format!("its sub-indices are {}", subs.join(", "))));
            }
            return Ok((index, sub));
        }
        match self.device.names.get(text) {
            Some(Named::Entry(i, s)) => Ok((i, s)),
            Some(Named::Object(i)) => {
                let obj = m.object(i);
                let kind = obj.map(|o| kind_name(o.object_type)).unwrap_or("an object");
                let entries = self.device.names.entries_of(i);
                let shown: Vec<String> = entries.iter().take(4).map(|e| format!("`{e}`")).collect();
                let more = if entries.len() > 4 { ", ..." } else { "" };
                Err(self
                    .error(
                        codes::NOT_AN_ENTRY,
                        format!("`{text}` is {kind} (0x{i:04X}): {role} needs one of its entries"),
                        name.span.clone(),
                    )
                    .help(format!("name an entry, e.g. {}{more}", shown.join(", "))))
            }
            None => {
                let mut d = self.error(
                    codes::UNKNOWN_OBJECT,
                    format!("the device has no object named `{text}`"),
                    name.span.clone(),
                );
                let snake = crate::ident::snake(text);
                let hint = match snake.as_deref() {
                    Some(s) if s != text && self.device.names.get(s).is_some() => {
                        Some(format!("names are the snake_case identifiers of ParameterName: write `{s}`"))
                    }
                    _ => {
                        let close = self.device.names.suggest(text);
                        match close.as_slice() {
                            [] => None,
                            [one] => Some(match self.device.names.get(one) {
                                Some(Named::Entry(i, s)) => {
                                    format!("did you mean `{one}` ({})?", self.entry_label(i, s))
                                }
                                _ => format!("did you mean `{one}`?"),
                            }),
                            many => Some(format!(
                                "did you mean one of {}?",
                                many.iter().map(|c| format!("`{c}`")).collect::<Vec<_>>().join(", ")
                            )),
                        }
                    }
                };
                d = match hint {
                    Some(h) => d.help(h),
                    None => d.help(format!(
                        "names are the snake_case identifiers of ParameterName (`odgen dump {}` lists them), or write an index as `0x6041sub0`",
                        self.device.display
                    )),
                };
                Err(d)
            }
        }
    }

    /// The configured values of `[nodes.X.parameters]`.
    pub fn parameters(&self, out: &mut Vec<Configured>, diags: &mut Vec<Diagnostic>) {
        for (key, value) in &self.node.parameters {
            let (index, sub) = match self.resolve(key, "a parameter") {
                Ok(t) => t,
                Err(d) => {
                    diags.push(d);
                    continue;
                }
            };
            let Some(entry) = self.device.model().entry(index, sub) else { continue };
            match scalar_value(&value.value, entry) {
                Ok(v) => out.push(Configured {
                    index,
                    sub,
                    value: v,
                    span: value.span.clone(),
                    what: format!("parameter `{}`", key.value),
                }),
                Err(message) => {
                    let d = self.error(codes::BAD_VALUE, message, value.span.clone());
                    diags.push(self.entry_note(d, index, sub, "is defined here"));
                }
            }
        }
    }

    /// The configured values of one PDO.
    pub fn pdo(
        &self,
        pdo: &PdoDesc,
        checker: &MappingChecker<'_>,
        out: &mut Vec<Configured>,
        diags: &mut Vec<Diagnostic>,
    ) {
        let m = self.device.model();
        let di = &m.device_info;
        let (comm_base, map_base, declared, key_name, nr_key) = match pdo.dir {
            Direction::Transmit => (0x1800u32, 0x1A00u32, di.nr_of_tx_pdo, "tpdo", "NrOfTXPDO"),
            Direction::Receive => (0x1400u32, 0x1600u32, di.nr_of_rx_pdo, "rpdo", "NrOfRXPDO"),
        };
        let name = pdo_name(pdo.dir, pdo.number);
        let ctx = format!("{}, {name}", self.context);
        let err = |code, message: String, span: Range<usize>| {
            Diagnostic::error(code, message).at(self.reader.snippet(span)).context(ctx.clone())
        };
        if let Some(n) = declared
            && pdo.number > u32::from(n)
        {
            let mut d = err(
                codes::NO_SUCH_PDO,
                format!("the device has {n} {}s, so there is no `{key_name}{}`", &name[..4], pdo.number),
                pdo.key_span.clone(),
            )
            .note(format!("{nr_key}={n} in the device description"), self.device.device_info_key(nr_key));
            d = d.help(if n == 0 {
                format!("this device has no {}s", &name[..4])
            } else {
                format!("use `{key_name}1` to `{key_name}{n}`")
            });
            diags.push(d);
            return;
        }
        if pdo.number > 512 {
            diags.push(err(
                codes::NO_SUCH_PDO,
                format!("CANopen has at most 512 {}s", &name[..4]),
                pdo.key_span.clone(),
            ));
            return;
        }
        let comm = (comm_base + pdo.number - 1) as u16;
        let map = (map_base + pdo.number - 1) as u16;
        for (index, what) in [(comm, "communication parameter"), (map, "mapping parameter")] {
            if m.object(index).is_none() {
                diags.push(err(
                    codes::NO_SUCH_PDO,
                    format!("the device has no {name} {what} (object 0x{index:04X})"),
                    pdo.key_span.clone(),
                ));
                return;
            }
        }
        let map_obj = m.object(map).expect("checked above");
        let Some(count) = map_obj.sub(0) else {
            diags.push(err(
                codes::MAPPING_CAPACITY,
                format!("the {name} mapping object 0x{map:04X} has no sub-index 0"),
                pdo.key_span.clone(),
            ));
            return;
        };
        if !count.access.writable() {
            let d = err(
                codes::MAPPING_CAPACITY,
                format!("the {name} mapping is fixed on this device: 0x{map:04X} sub 0 is `{}`", count.access.as_str()),
                pdo.map_span.clone(),
            );
            diags.push(self.entry_note(d, map, 0, "is defined here"));
            return;
        }
        let capacity = (1..=64u8).take_while(|s| map_obj.sub(*s).is_some()).count();

        // Resolve and check each mapped object with the run-time rules.
        let mut raws: Vec<u32> = Vec::new();
        let mut ok = true;
        for (i, item) in pdo.map.iter().enumerate() {
            if i == capacity {
                let d = err(
                    codes::MAPPING_CAPACITY,
                    format!(
                        "the {name} mapping object 0x{map:04X} holds {capacity} entries; `{}` would be entry {}",
                        item.value,
                        i + 1
                    ),
                    item.span.clone(),
                );
                diags.push(self.entry_note(d, map, 0, "is defined here"));
                ok = false;
                break;
            }
            let (index, sub) = match self.resolve(item, &format!("a {name} mapping")) {
                Ok(t) => t,
                Err(mut d) => {
                    d.context = vec![ctx.clone()];
                    diags.push(d);
                    ok = false;
                    continue;
                }
            };
            let entry = m.entry(index, sub).expect("resolved entries exist");
            let label = self.entry_label(index, sub);
            let Some(bits) = entry.data_type.bits() else {
                let d = err(
                    codes::MAPPING_LENGTH,
                    format!(
                        "`{}` is a {}: only entries of a fixed size can be mapped by name",
                        item.value,
                        entry.data_type.name()
                    ),
                    item.span.clone(),
                );
                diags.push(self.entry_note(d, index, sub, "is defined here"));
                ok = false;
                continue;
            };
            let raw = (u32::from(index) << 16) | (u32::from(sub) << 8) | bits;
            if let Err(e) = checker.check(pdo.dir, &[raw]) {
                let (code, message, help) = match e.abort_code {
                    0x0604_0041 if !entry.pdo_mapping => (
                        codes::NOT_MAPPABLE,
                        format!("`{}` cannot be mapped into a PDO: {label} has PDOMapping=0", item.value),
                        "only entries with PDOMapping=1 can be mapped; configure this one under `parameters` instead"
                            .to_owned(),
                    ),
                    0x0604_0041 => {
                        let (dir_text, help) = match pdo.dir {
                            Direction::Receive => (
                                "an RPDO carries values the master writes",
                                "map it into a TPDO, or pick an entry with access wo, rw or rww",
                            ),
                            Direction::Transmit => (
                                "a TPDO carries values the device sends",
                                "map it into an RPDO, or pick an entry with access ro, rw, rwr or const",
                            ),
                        };
                        (
                            codes::MAPPING_ACCESS,
                            format!("`{}` is `{}`, but {dir_text}", item.value, entry.access.as_str()),
                            help.to_owned(),
                        )
                    }
                    0x0604_0043 => {
                        (codes::MAPPING_LENGTH, e.message.clone(), "map it with its type's length".to_owned())
                    }
                    _ => (
                        codes::UNKNOWN_OBJECT,
                        format!("`{}` is not part of the generated dictionary, so it cannot be mapped", item.value),
                        "only entries of basic data types can be mapped".to_owned(),
                    ),
                };
                let d = err(code, message, item.span.clone())
                    .note(
                        format!("the run-time check refuses it with SDO abort 0x{:08X}: {}", e.abort_code, e.message),
                        None,
                    )
                    .help(help);
                diags.push(self.entry_note(d, index, sub, "is defined here"));
                ok = false;
                continue;
            }
            raws.push(raw);
        }
        if !ok {
            return;
        }
        if let Err(e) = checker.check(pdo.dir, &raws) {
            // Per-entry checks passed, so this is the total length.
            let mut total = 0u32;
            let mut at = pdo.map.len() - 1;
            for (i, r) in raws.iter().enumerate() {
                total += r & 0xFF;
                if total > 64 && at == pdo.map.len() - 1 {
                    at = i;
                }
            }
            let sizes: Vec<String> =
                pdo.map.iter().zip(&raws).map(|(n, r)| format!("{} {}", n.value, r & 0xFF)).collect();
            diags.push(
                err(
                    codes::PDO_TOO_LONG,
                    format!("{name} would carry {total} bits; a PDO holds at most 64 bits (8 bytes)"),
                    pdo.map[at].span.clone(),
                )
                .note(format!("bits: {} = {total}", sizes.join(" + ")), None)
                .note(
                    format!("the run-time check refuses it with SDO abort 0x{:08X}: {}", e.abort_code, e.message),
                    None,
                )
                .help(format!(
                    "move `{}` and what follows into another {}",
                    pdo.map[at].value,
                    &name[..4]
                )),
            );
            return;
        }

        // The mapping.
        let what = format!("{name} mapping");
        out.push(Configured {
            index: map,
            sub: 0,
            value: Value::int(raws.len() as i128),
            span: pdo.map_span.clone(),
            what: what.clone(),
        });
        for ((i, raw), item) in raws.iter().enumerate().zip(&pdo.map) {
            out.push(Configured {
                index: map,
                sub: i as u8 + 1,
                value: Value::hex(i128::from(*raw)),
                span: item.span.clone(),
                what: what.clone(),
            });
        }

        // The COB-ID: valid when something is mapped, not valid for an empty mapping.
        if let Some(cob) = m.entry(comm, 1) {
            let current = cob.default.as_ref().and_then(|v| v.resolve(self.node_id));
            if let Some(current) = current {
                let wanted = if raws.is_empty() { current | 0x8000_0000 } else { current & !0x8000_0000 };
                if !raws.is_empty() && wanted & 0x1FFF_FFFF == 0 {
                    let d = err(
                        codes::PDO_SETTING,
                        format!("{name} has no default CAN identifier (its COB-ID default is 0x{current:08X})"),
                        pdo.key_span.clone(),
                    )
                    .help(format!("give it one under `parameters`: `\"0x{comm:04X}sub1\" = 0x...`"));
                    diags.push(self.entry_note(d, comm, 1, "is defined here"));
                } else if wanted != current {
                    out.push(Configured {
                        index: comm,
                        sub: 1,
                        value: Value::hex(wanted),
                        span: pdo.key_span.clone(),
                        what: if raws.is_empty() { format!("{name} (disabled)") } else { format!("{name} (enabled)") },
                    });
                }
            }
        }

        // Communication settings.
        let settings = [
            (&pdo.transmission_type, 2u8, "transmission_type"),
            (&pdo.inhibit_time, 3, "inhibit_time"),
            (&pdo.event_timer, 5, "event_timer"),
        ];
        for (setting, sub, key) in settings {
            let Some(v) = setting else { continue };
            if key == "inhibit_time" && pdo.dir == Direction::Receive {
                diags.push(
                    err(codes::PDO_SETTING, "an RPDO has no inhibit time".to_owned(), v.span.clone())
                        .help("inhibit times limit how often a device sends: set them on TPDOs"),
                );
                continue;
            }
            if key == "transmission_type" {
                let t = v.value;
                let problem = match (pdo.dir, t) {
                    (_, 241..=251) => Some(format!(
                        "transmission type {t} is reserved (CiA 301: 0-240 synchronous, 252-253 RTR, 254-255 event-driven)"
                    )),
                    (Direction::Receive, 252 | 253) => {
                        Some(format!("transmission type {t} (RTR) applies to TPDOs only"))
                    }
                    _ => None,
                };
                if let Some(p) = problem {
                    diags.push(err(codes::PDO_SETTING, p, v.span.clone()));
                    continue;
                }
            }
            if m.entry(comm, sub).is_none() {
                let comm_obj = m.object(comm).expect("checked above");
                let d = err(
                    codes::PDO_SETTING,
                    format!("the device's {name} communication object 0x{comm:04X} has no sub-index {sub} for `{key}`"),
                    v.span.clone(),
                )
                .note(format!("0x{comm:04X} \"{}\" is defined here", comm_obj.name), self.device.snippet(comm_obj.at));
                diags.push(d);
                continue;
            }
            out.push(Configured {
                index: comm,
                sub,
                value: Value::int(v.value),
                span: v.span.clone(),
                what: format!("{name} {key}"),
            });
        }
    }
}

/// `0x6041 "Statusword"`, or `0x1018 sub 1 "Identity object" / "Vendor-ID"` for an entry of an
/// ARRAY or RECORD.
pub(crate) fn entry_label(m: &Model, index: u16, sub: u8) -> String {
    match (m.object(index), m.entry(index, sub)) {
        (Some(o), Some(e)) if o.object_type.has_subs() => {
            format!("0x{index:04X} sub {sub} \"{}\" / \"{}\"", o.name, e.name)
        }
        (Some(o), _) => format!("0x{index:04X} \"{}\"", o.name),
        _ => format!("0x{index:04X} sub {sub}"),
    }
}

/// A TOML scalar as a value for `entry`.
fn scalar_value(s: &Scalar, entry: &Entry) -> Result<Value, String> {
    let ty = entry.data_type;
    Ok(match s {
        Scalar::Int { value, hex } => {
            Value::Int { value: *value, radix: if *hex { eds::Radix::Hex } else { eds::Radix::Dec } }
        }
        Scalar::Float(x) => Value::Real(*x),
        Scalar::Bool(b) => {
            if ty != DataType::Boolean && !ty.is_unsigned() {
                return Err(format!("a boolean is not a {} value", ty.name()));
            }
            Value::int(i128::from(*b))
        }
        Scalar::Str(text) => match eds::value::parse_value(text, ty) {
            Ok(p) => match p.value {
                Some(v) => v,
                None => return Err(format!("an empty string is not a {} value", ty.name())),
            },
            Err(e) => return Err(format!("`{text}` cannot be read as {}: {e}", ty.name())),
        },
    })
}

/// `an ARRAY`, `a RECORD`: object types as CiA 301 names them.
fn kind_name(t: eds::model::ObjectType) -> &'static str {
    use eds::model::ObjectType as T;
    match t {
        T::Array => "an ARRAY",
        T::Record => "a RECORD",
        T::DefStruct => "a DEFSTRUCT",
        T::DefType => "a DEFTYPE",
        T::Domain => "a DOMAIN",
        T::Var => "a VAR",
        T::Null => "a NULL object",
    }
}
