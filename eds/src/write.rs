//! Canonical EDS and DCF writers: [`crate::model::Model`] → text.
//!
//! There is one canonical form, so that `odgen fmt` has a fixed point and two tools that write
//! the same model write the same bytes:
//!
//! - Sections in this order: `[FileInfo]`, `[DeviceInfo]`, `[DeviceComissioning]` (DCF only),
//!   `[DummyUsage]` and `[Comments]` (when the model has any), then `[MandatoryObjects]`,
//!   `[OptionalObjects]` and `[ManufacturerObjects]`, each list followed by its objects in index
//!   order, and last the sections this crate does not interpret, in the order they were read.
//! - An object is written as `[1018]`, then its sub-objects as `[1018sub0]`, `[1018sub1]`, … (index
//!   as four upper-case hex digits, sub-index as upper-case hex without padding), then
//!   `[1018ObjectLinks]`. An ARRAY that was read in compact form (`CompactSubObj=N`) is written
//!   compactly again, with its names in `[xxxxName]` and its differing values in `[xxxxValue]`,
//!   as long as its expanded entries still fit that form; otherwise it is written expanded.
//! - Keys of an entry in this order: `ParameterName`, `ObjectType`, `DataType`, `AccessType`,
//!   `DefaultValue`, `ParameterValue`, `LowLimit`, `HighLimit`, `PDOMapping`, `ObjFlags`,
//!   `Denotation`, `UploadFile`, `DownloadFile`, then the keys this crate does not interpret, as
//!   they were read.
//! - Numbers keep the radix they were read in ([`Radix`]); hexadecimal digits are upper case
//!   after a lower-case `0x` and integers of a fixed-size type are padded to the type's width
//!   (`0x00000180`). `$NODEID` expressions are written `$NODEID+0x180` (and `$NODEID+0x0`, never a
//!   bare `$NODEID`, which python-canopen cannot read). REAL values use the
//!   shortest decimal text that reads back as the same `f64`. OCTET_STRING and DOMAIN values are
//!   upper-case hex digits without separators.
//! - Type codes are `0x0007`, object codes `0x7`, booleans `0`/`1`, line ends `\n`, one blank line
//!   between sections, no comments (the model has none to give).
//!
//! Reading a written file gives the model back (`read(write(m)) == m`) for every model whose
//! strings can be written at all: an INI line cannot hold a line break, and a value cannot
//! start or end with white space (readers trim it). [`unrepresentable`] lists what in a model
//! cannot survive the trip.

use std::fmt::Write as _;

use crate::model::{
    Access, Category, Commissioning, DataType, DeviceInfo, Entry, FileInfo, FileKind, Index, Model, Object, ObjectType,
    Radix, SourceRef, SubIndex, Value,
};

/// Writes the model as an EDS: everything in it except `[DeviceComissioning]`.
///
/// `ParameterValue` and `Denotation` keys are written where the model has them: some vendor
/// EDS files carry them, and dropping them would change what the file means.
pub fn write_eds(model: &Model) -> String {
    Writer::new(model, false).finish()
}

/// Writes the model as a DCF: the EDS plus `[DeviceComissioning]` (when the model has it).
pub fn write_dcf(model: &Model) -> String {
    Writer::new(model, true).finish()
}

/// Writes the model as the kind of file it says it is ([`Model::kind`]).
pub fn write(model: &Model) -> String {
    match model.kind {
        FileKind::Eds => write_eds(model),
        FileKind::Dcf => write_dcf(model),
    }
}

/// Formats one value the canonical way for an entry of type `data_type` (see the module docs).
///
/// The type only sets the zero padding of hexadecimal integers: `0x0180` for UNSIGNED16.
pub fn format_value(value: &Value, data_type: DataType) -> String {
    let mut s = String::new();
    push_value(&mut s, value, data_type);
    s
}

fn hex_width(data_type: DataType) -> usize {
    match data_type.bits() {
        Some(bits) if data_type.is_signed() || data_type.is_unsigned() => bits.div_ceil(8) as usize * 2,
        _ => 0,
    }
}

fn push_int(out: &mut String, value: i128, radix: Radix, width: usize) {
    let sign = if value < 0 { "-" } else { "" };
    let magnitude = value.unsigned_abs();
    let _ = match radix {
        Radix::Dec => write!(out, "{sign}{magnitude}"),
        // Negative numbers are written with a sign, never as a two's complement bit pattern:
        // python-canopen reads `DefaultValue=0xFFF0` of an INTEGER16 as 65520.
        Radix::Hex if value < 0 => write!(out, "-0x{magnitude:X}"),
        Radix::Hex => write!(out, "0x{magnitude:0width$X}"),
        // CiA 306 octal: a leading 0. Zero itself is written `00` so it still reads as octal.
        Radix::Oct => write!(out, "{sign}0{magnitude:o}"),
    };
}

fn push_value(out: &mut String, value: &Value, data_type: DataType) {
    match value {
        Value::Int { value, radix } => push_int(out, *value, *radix, hex_width(data_type)),
        Value::NodeIdPlus { offset, radix } => {
            // Always with the constant, even when it is 0: python-canopen (2.4.1) cannot read a
            // bare `$NODEID` (it strips the symbol and fails on the empty rest), while every
            // reader understands `$NODEID+0x0`, which reads back as the same value.
            out.push_str("$NODEID");
            out.push(if *offset < 0 { '-' } else { '+' });
            push_int(out, offset.abs(), *radix, 0);
        }
        // Reals (shortest text per type), strings and bytes are written as the reader's
        // formatter writes them.
        Value::Real(_) | Value::Text(_) | Value::Bytes(_) => {
            out.push_str(&crate::value::format_value(value, data_type))
        }
    }
}

/// Something in a model that no INI file can hold, so that reading the written file back would
/// give a different model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unrepresentable {
    /// Where: `object 0x1018 "Identity", sub 2`, `[FileInfo] Description`, ...
    pub context: String,
    /// What is wrong with it.
    pub message: String,
}

impl std::fmt::Display for Unrepresentable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.context, self.message)
    }
}

/// The keys of an object or sub-object section the writer writes from the model's typed fields.
const TYPED_OBJECT_KEYS: [&str; 15] = [
    "ParameterName",
    "ObjectType",
    "DataType",
    "AccessType",
    "DefaultValue",
    "PDOMapping",
    "SubNumber",
    "CompactSubObj",
    "LowLimit",
    "HighLimit",
    "ObjFlags",
    "ParameterValue",
    "Denotation",
    "UploadFile",
    "DownloadFile",
];

/// An unknown key kept with the name of a key the writer writes from the model (the reader keeps
/// a value it cannot read that way): written, it would be the key's second line.
fn written_key(out: &mut Vec<Unrepresentable>, ctx: &dyn Fn() -> String, key: &str, value: &str) {
    if TYPED_OBJECT_KEYS.iter().any(|k| k.eq_ignore_ascii_case(key)) {
        out.push(Unrepresentable {
            context: ctx(),
            message: format!(
                "`{key}={}` could not be read and is kept as text; written beside the `{key}` odgen writes, it would be a repeated key",
                crate::diag::shorten(value).escape_debug()
            ),
        });
    }
}

/// Lists what in `model` would not survive being written and read back: text with a line
/// break, text with white space at either end (readers trim values), keys that are empty or
/// contain `=` or start with `[` or `;`, section names with `]`, a `compact_sub_obj` on an
/// object whose entries are not the compact shape (see [`compact_info`]), and unreadable values
/// of typed keys kept as text (they would be written as a second line of the key).
pub fn unrepresentable(model: &Model) -> Vec<Unrepresentable> {
    let mut out = Vec::new();
    let mut compact_problems = Vec::new();
    let mut text = |context: &dyn Fn() -> String, what: &str, s: &str| {
        if s.contains(['\n', '\r']) {
            out.push(Unrepresentable { context: context(), message: format!("{what} contains a line break") });
        } else if s.trim() != s {
            out.push(Unrepresentable {
                context: context(),
                message: format!("{what} starts or ends with white space, which readers trim"),
            });
        }
    };
    let fi = &model.file_info;
    for (k, v) in string_fields_file_info(fi).into_iter().chain(
        string_fields_device_info(&model.device_info)
            .into_iter()
            .chain(model.commissioning.iter().flat_map(string_fields_commissioning)),
    ) {
        text(&|| format!("`{k}`"), "the value", v);
    }
    for (i, line) in model.comments.iter().enumerate() {
        text(&|| format!("[Comments] Line{}", i + 1), "the comment", line);
    }
    for obj in model.objects.values() {
        let ctx = || format!("object {} \"{}\"", obj.index, obj.name);
        if obj.compact_sub_obj.is_some() && compact_form(obj).is_none() {
            compact_problems.push(Unrepresentable {
                context: ctx(),
                message: "CompactSubObj is set but the sub-objects differ from what it expands to; \
                          the object is written expanded and reads back without CompactSubObj"
                    .to_owned(),
            });
        }
        text(&ctx, "the name", &obj.name);
        for (k, v) in &obj.extra {
            text(&ctx, &format!("the value of `{k}`"), v);
            written_key(&mut compact_problems, &ctx, k, v);
        }
        for e in obj.subs.values() {
            let ctx = || format!("object {} \"{}\", sub {} \"{}\"", obj.index, obj.name, e.sub, e.name);
            text(&ctx, "the name", &e.name);
            for (what, v) in [
                ("DefaultValue", e.default.as_ref()),
                ("ParameterValue", e.parameter_value()),
                ("LowLimit", e.low_limit()),
                ("HighLimit", e.high_limit()),
            ] {
                if let Some(Value::Text(t)) = v {
                    text(&ctx, what, t);
                }
            }
            for (what, v) in
                [("Denotation", e.denotation()), ("UploadFile", e.upload_file()), ("DownloadFile", e.download_file())]
            {
                if let Some(t) = v {
                    text(&ctx, what, t);
                }
            }
            for (k, v) in e.extra() {
                text(&ctx, &format!("the value of `{k}`"), v);
                written_key(&mut compact_problems, &ctx, k, v);
            }
        }
    }
    for sec in &model.extra_sections {
        for (k, v) in &sec.entries {
            text(&|| format!("[{}]", sec.name), &format!("the value of `{k}`"), v);
        }
    }
    out.append(&mut compact_problems);
    // Keys and section names.
    let mut keys: Vec<(String, &str)> = Vec::new();
    keys.extend(model.file_info.extra.iter().map(|(k, _)| ("[FileInfo]".to_owned(), k.as_str())));
    keys.extend(model.device_info.extra.iter().map(|(k, _)| ("[DeviceInfo]".to_owned(), k.as_str())));
    if let Some(c) = &model.commissioning {
        keys.extend(c.extra.iter().map(|(k, _)| ("[DeviceComissioning]".to_owned(), k.as_str())));
    }
    for obj in model.objects.values() {
        keys.extend(obj.extra.iter().map(|(k, _)| (format!("object {}", obj.index), k.as_str())));
        for e in obj.subs.values() {
            keys.extend(e.extra().iter().map(|(k, _)| (format!("object {} sub {}", obj.index, e.sub), k.as_str())));
        }
    }
    for sec in &model.extra_sections {
        if sec.name.contains([']', '\n', '\r']) || sec.name.trim() != sec.name || sec.name.is_empty() {
            out.push(Unrepresentable {
                context: format!("section {:?}", sec.name),
                message: "a section name must be non-empty, without `]`, line breaks or white space at its ends"
                    .to_owned(),
            });
        }
        keys.extend(sec.entries.iter().map(|(k, _)| (format!("[{}]", sec.name), k.as_str())));
    }
    for (ctx, k) in keys {
        if k.is_empty() || k.contains(['=', '\n', '\r']) || k.starts_with(['[', ';']) || k.trim() != k {
            out.push(Unrepresentable {
                context: ctx,
                message: format!("the key {k:?} cannot be written (empty, `=`, line break, leading `[`/`;` or white space at its ends)"),
            });
        }
    }
    out
}

fn string_fields_file_info(fi: &FileInfo) -> Vec<(&'static str, &str)> {
    let mut v = Vec::new();
    for (k, s) in [
        ("FileName", &fi.file_name),
        ("EDSVersion", &fi.eds_version),
        ("Description", &fi.description),
        ("CreationTime", &fi.creation_time),
        ("CreationDate", &fi.creation_date),
        ("CreatedBy", &fi.created_by),
        ("ModificationTime", &fi.modification_time),
        ("ModificationDate", &fi.modification_date),
        ("ModifiedBy", &fi.modified_by),
    ] {
        if let Some(s) = s {
            v.push((k, s.as_str()));
        }
    }
    v
}

fn string_fields_device_info(di: &DeviceInfo) -> Vec<(&'static str, &str)> {
    [("VendorName", &di.vendor_name), ("ProductName", &di.product_name), ("OrderCode", &di.order_code)]
        .into_iter()
        .filter_map(|(k, s)| Some((k, s.as_deref()?)))
        .collect()
}

fn string_fields_commissioning(c: &Commissioning) -> Vec<(&'static str, &str)> {
    [("NodeName", &c.node_name), ("NetworkName", &c.network_name)]
        .into_iter()
        .filter_map(|(k, s)| Some((k, s.as_deref()?)))
        .collect()
}

/// The section writer: accumulates text, one section at a time.
struct Writer<'m> {
    model: &'m Model,
    dcf: bool,
    out: String,
}

impl<'m> Writer<'m> {
    fn new(model: &'m Model, dcf: bool) -> Self {
        // Roughly 150 bytes per entry is what real files average.
        let entries: usize = model.objects.values().map(|o| o.subs.len() + 1).sum();
        Writer { model, dcf, out: String::with_capacity(1024 + entries * 160) }
    }

    fn section(&mut self, name: std::fmt::Arguments<'_>) {
        if !self.out.is_empty() {
            self.out.push('\n');
        }
        let _ = writeln!(self.out, "[{name}]");
    }

    fn key(&mut self, key: &str, value: std::fmt::Arguments<'_>) {
        let _ = writeln!(self.out, "{key}={value}");
    }

    fn opt_str(&mut self, key: &str, value: Option<&str>) {
        if let Some(v) = value {
            self.key(key, format_args!("{v}"));
        }
    }

    fn opt_dec<T: std::fmt::Display>(&mut self, key: &str, value: Option<T>) {
        if let Some(v) = value {
            self.key(key, format_args!("{v}"));
        }
    }

    fn opt_hex32(&mut self, key: &str, value: Option<u32>) {
        if let Some(v) = value {
            self.key(key, format_args!("0x{v:08X}"));
        }
    }

    fn opt_bool(&mut self, key: &str, value: Option<bool>) {
        if let Some(v) = value {
            self.key(key, format_args!("{}", v as u8));
        }
    }

    fn extra(&mut self, extra: &[(String, String)]) {
        for (k, v) in extra {
            self.key(k, format_args!("{v}"));
        }
    }

    fn value(&mut self, key: &str, value: Option<&Value>, data_type: DataType) {
        if let Some(v) = value {
            self.out.push_str(key);
            self.out.push('=');
            push_value(&mut self.out, v, data_type);
            self.out.push('\n');
        }
    }

    fn finish(mut self) -> String {
        let m = self.model;
        self.file_info(&m.file_info);
        self.device_info(&m.device_info);
        if self.dcf
            && let Some(c) = &m.commissioning
        {
            self.commissioning(c);
        }
        if !m.dummy_usage.is_empty() {
            self.section(format_args!("DummyUsage"));
            for (&n, &on) in &m.dummy_usage {
                self.key(&format!("Dummy{n:04X}"), format_args!("{}", on as u8));
            }
        }
        if !m.comments.is_empty() {
            self.section(format_args!("Comments"));
            self.key("Lines", format_args!("{}", m.comments.len()));
            for (i, line) in m.comments.iter().enumerate() {
                self.key(&format!("Line{}", i + 1), format_args!("{line}"));
            }
        }
        for (category, list) in [
            (Category::Mandatory, "MandatoryObjects"),
            (Category::Optional, "OptionalObjects"),
            (Category::Manufacturer, "ManufacturerObjects"),
        ] {
            let objects: Vec<&Object> = m.objects.values().filter(|o| o.category == category).collect();
            self.section(format_args!("{list}"));
            self.key("SupportedObjects", format_args!("{}", objects.len()));
            for (i, o) in objects.iter().enumerate() {
                self.key(&(i + 1).to_string(), format_args!("0x{:04X}", o.index.0));
            }
            for o in objects {
                self.object(o);
            }
        }
        for sec in &m.extra_sections {
            self.section(format_args!("{}", sec.name));
            self.extra(&sec.entries);
        }
        self.out
    }

    fn file_info(&mut self, fi: &FileInfo) {
        self.section(format_args!("FileInfo"));
        self.opt_str("FileName", fi.file_name.as_deref());
        self.opt_dec("FileVersion", fi.file_version);
        self.opt_dec("FileRevision", fi.file_revision);
        self.opt_str("EDSVersion", fi.eds_version.as_deref());
        self.opt_str("Description", fi.description.as_deref());
        self.opt_str("CreationTime", fi.creation_time.as_deref());
        self.opt_str("CreationDate", fi.creation_date.as_deref());
        self.opt_str("CreatedBy", fi.created_by.as_deref());
        self.opt_str("ModificationTime", fi.modification_time.as_deref());
        self.opt_str("ModificationDate", fi.modification_date.as_deref());
        self.opt_str("ModifiedBy", fi.modified_by.as_deref());
        self.extra(&fi.extra);
    }

    fn device_info(&mut self, di: &DeviceInfo) {
        self.section(format_args!("DeviceInfo"));
        self.opt_str("VendorName", di.vendor_name.as_deref());
        self.opt_hex32("VendorNumber", di.vendor_number);
        self.opt_str("ProductName", di.product_name.as_deref());
        self.opt_hex32("ProductNumber", di.product_number);
        self.opt_hex32("RevisionNumber", di.revision_number);
        self.opt_str("OrderCode", di.order_code.as_deref());
        for (&rate, &on) in &di.baud_rates {
            self.key(&format!("BaudRate_{rate}"), format_args!("{}", on as u8));
        }
        self.opt_bool("SimpleBootUpMaster", di.simple_boot_up_master);
        self.opt_bool("SimpleBootUpSlave", di.simple_boot_up_slave);
        self.opt_dec("Granularity", di.granularity);
        self.opt_dec("DynamicChannelsSupported", di.dynamic_channels_supported);
        self.opt_bool("GroupMessaging", di.group_messaging);
        self.opt_dec("NrOfRXPDO", di.nr_of_rx_pdo);
        self.opt_dec("NrOfTXPDO", di.nr_of_tx_pdo);
        self.opt_bool("LSS_Supported", di.lss_supported);
        self.opt_dec("CompactPDO", di.compact_pdo);
        self.extra(&di.extra);
    }

    fn commissioning(&mut self, c: &Commissioning) {
        self.section(format_args!("DeviceComissioning"));
        self.opt_dec("NodeID", c.node_id);
        self.opt_str("NodeName", c.node_name.as_deref());
        self.opt_dec("Baudrate", c.baudrate);
        self.opt_dec("NetNumber", c.net_number);
        self.opt_str("NetworkName", c.network_name.as_deref());
        self.opt_bool("CANopenManager", c.canopen_manager);
        self.opt_hex32("LSS_SerialNumber", c.lss_serial_number);
        self.extra(&c.extra);
    }

    fn object(&mut self, o: &Object) {
        let idx = o.index.0;
        self.section(format_args!("{idx:04X}"));
        self.key("ParameterName", format_args!("{}", o.name));
        self.key("ObjectType", format_args!("0x{:X}", o.object_type.code()));
        if !o.object_type.has_subs() {
            // VAR, DOMAIN, DEFTYPE, NULL: the object section is its sub-0 entry.
            if let Some(e) = o.subs.get(&SubIndex(0)) {
                self.entry_keys(e);
            }
            self.opt_obj_flags(o.obj_flags);
            self.extra(&o.extra);
            // A well-formed model has nothing else; anything that is there is written, not lost.
            for e in o.subs.values().filter(|e| e.sub.0 != 0) {
                self.sub_section(idx, e);
            }
        } else if let Some(compact) = compact_form(o) {
            self.compact(o, &compact);
        } else {
            self.key("SubNumber", format_args!("0x{:X}", o.subs.len()));
            self.opt_obj_flags(o.obj_flags);
            self.extra(&o.extra);
            for e in o.subs.values() {
                self.sub_section(idx, e);
            }
        }
        if !o.object_links.is_empty() {
            self.section(format_args!("{idx:04X}ObjectLinks"));
            self.key("ObjectLinks", format_args!("{}", o.object_links.len()));
            for (i, Index(link)) in o.object_links.iter().enumerate() {
                self.key(&(i + 1).to_string(), format_args!("0x{link:04X}"));
            }
        }
    }

    fn opt_obj_flags(&mut self, flags: Option<u32>) {
        if let Some(f) = flags {
            self.key("ObjFlags", format_args!("0x{f:X}"));
        }
    }

    fn sub_section(&mut self, idx: u16, e: &Entry) {
        self.section(format_args!("{idx:04X}sub{:X}", e.sub.0));
        self.key("ParameterName", format_args!("{}", e.name));
        self.key("ObjectType", format_args!("0x{:X}", ObjectType::Var.code()));
        self.entry_keys(e);
    }

    /// Every key of an entry after `ParameterName` and `ObjectType`.
    fn entry_keys(&mut self, e: &Entry) {
        self.entry_type_keys(e.data_type, e.access);
        self.value("DefaultValue", e.default.as_ref(), e.data_type);
        self.value("ParameterValue", e.parameter_value(), e.data_type);
        self.value("LowLimit", e.low_limit(), e.data_type);
        self.value("HighLimit", e.high_limit(), e.data_type);
        self.key("PDOMapping", format_args!("{}", e.pdo_mapping as u8));
        self.opt_obj_flags(e.obj_flags());
        self.opt_str("Denotation", e.denotation());
        self.opt_str("UploadFile", e.upload_file());
        self.opt_str("DownloadFile", e.download_file());
        self.extra(e.extra());
    }

    fn entry_type_keys(&mut self, data_type: DataType, access: Access) {
        self.key("DataType", format_args!("0x{:04X}", data_type.code()));
        self.key("AccessType", format_args!("{}", access.as_str()));
    }

    fn compact(&mut self, o: &Object, c: &Compact<'_>) {
        let idx = o.index.0;
        let proto = c.proto;
        self.entry_type_keys(proto.data_type, proto.access);
        self.value("DefaultValue", c.default.as_ref(), proto.data_type);
        self.value("LowLimit", proto.low_limit(), proto.data_type);
        self.value("HighLimit", proto.high_limit(), proto.data_type);
        self.key("PDOMapping", format_args!("{}", proto.pdo_mapping as u8));
        self.key("CompactSubObj", format_args!("{}", c.n));
        self.opt_obj_flags(o.obj_flags);
        self.opt_str("Denotation", proto.denotation());
        self.opt_str("UploadFile", proto.upload_file());
        self.opt_str("DownloadFile", proto.download_file());
        self.extra(&o.extra);
        // python-canopen creates the sub-objects of a compact ARRAY from `[xxxxName]` only, so
        // an ARRAY gets the section even when every name is the implied one; on a RECORD
        // (which CiA 306 does not allow compact, but files do it) the section makes
        // python-canopen fail, so it is written only when a name differs.
        let implied = |(s, name): &(u8, &str)| *name == format!("{}{s}", o.name);
        if !c.names.is_empty() && (o.object_type == ObjectType::Array || !c.names.iter().all(implied)) {
            self.section(format_args!("{idx:04X}Name"));
            self.key("NrOfEntries", format_args!("{}", c.names.len()));
            for (sub, name) in &c.names {
                self.key(&sub.to_string(), format_args!("{name}"));
            }
        }
        if !c.values.is_empty() {
            self.section(format_args!("{idx:04X}Value"));
            self.key("NrOfEntries", format_args!("{}", c.values.len()));
            for (sub, value) in &c.values {
                self.key(&sub.to_string(), format_args!("{}", format_value(value, proto.data_type)));
            }
        }
    }
}

/// How a compact ARRAY is written.
struct Compact<'o> {
    n: u8,
    /// The entry whose type, access, default, limits, mapping and flags every sub-object
    /// 1..=n shares (sub 0 itself when n is 0).
    proto: &'o Entry,
    /// The object's `DefaultValue`.
    default: Option<Value>,
    /// `[xxxxName]` lines: every sub-object's name (python-canopen only creates the sub-objects
    /// it finds names for, so all of them are written even where the name is the implied one).
    names: Vec<(u8, &'o str)>,
    /// `[xxxxValue]` lines: the configured values (`ParameterValue`) of the sub-objects.
    values: Vec<(u8, &'o Value)>,
}

/// The name the reader gives sub-index 0 of a compact ARRAY.
const COMPACT_SUB0_NAME: &str = "NrOfObjects";

/// Whether `o` can be written in compact form so that reading it back gives `o` again.
///
/// The reader expands `CompactSubObj=N` into sub-index 0 (`NrOfObjects`, UNSIGNED8, `ro`,
/// default N) and sub-indices 1..=N that all take the object section's keys, with names from
/// `[xxxxName]` and configured values from `[xxxxValue]`. An object qualifies when its entries
/// are exactly that shape.
fn compact_form(o: &Object) -> Option<Compact<'_>> {
    let n = o.compact_sub_obj?;
    if !o.object_type.has_subs() || o.subs.len() != n as usize + 1 {
        return None;
    }
    let sub0 = o.subs.get(&SubIndex(0))?;
    let sub0_ok = sub0.name == COMPACT_SUB0_NAME
        && sub0.data_type == DataType::Unsigned8
        && sub0.access == Access::Ro
        && !sub0.pdo_mapping
        && sub0.default == Some(Value::int(n as i128))
        && sub0.extras().is_empty();
    if !sub0_ok {
        return None;
    }
    let proto = o.subs.get(&SubIndex(1)).unwrap_or(sub0);
    let mut names = Vec::with_capacity(n as usize);
    let mut values = Vec::new();
    for s in 1..=n {
        let e = o.subs.get(&SubIndex(s))?;
        let shared = e.data_type == proto.data_type
            && e.access == proto.access
            && e.pdo_mapping == proto.pdo_mapping
            && e.default == proto.default
            && e.low_limit() == proto.low_limit()
            && e.high_limit() == proto.high_limit()
            && e.obj_flags() == o.obj_flags
            && e.denotation() == proto.denotation()
            && e.upload_file() == proto.upload_file()
            && e.download_file() == proto.download_file()
            && e.extra().is_empty();
        if !shared {
            return None;
        }
        names.push((s, e.name.as_str()));
        if let Some(v) = e.parameter_value() {
            values.push((s, v));
        }
    }
    Some(Compact { n, proto, default: proto.default.clone(), names, values })
}

/// What a compact ARRAY looks like to a reader that does not expand `[xxxxValue]`
/// (python-canopen): its shared type and `DefaultValue`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompactInfo {
    /// `CompactSubObj=N`.
    pub n: u8,
    /// The shared data type of sub-indices 1..=N.
    pub data_type: DataType,
    /// The shared `DefaultValue` written in the object section.
    pub default: Option<Value>,
}

/// Whether the writers write `o` in compact form (`CompactSubObj=N`), and with what shared
/// type and default; `None` when it is written with one section per sub-object.
pub fn compact_info(o: &Object) -> Option<CompactInfo> {
    compact_form(o).map(|c| CompactInfo { n: c.n, data_type: c.proto.data_type, default: c.default })
}

/// Standard CiA 301 bit rates in kbit/s.
pub const STANDARD_BAUD_RATES: [u16; 8] = [10, 20, 50, 125, 250, 500, 800, 1000];

/// One thing wrong with a configuration requested from [`configure`].
#[derive(Clone, Debug, PartialEq)]
pub struct ConfigProblem {
    /// The entry the problem is about (`None` for the node id and bit rate).
    pub target: Option<(Index, SubIndex)>,
    /// Where the entry is in the device description, when the model was read from a file.
    pub at: Option<SourceRef>,
    /// Breadcrumbs, outermost first: `object 0x6060 "Modes of operation"`, `sub 0 "..."`.
    pub context: Vec<String>,
    /// What is wrong, in one sentence.
    pub message: String,
    /// How to fix it, where known.
    pub hint: Option<String>,
}

impl std::fmt::Display for ConfigProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(at) = self.at.filter(|a| a.line > 0) {
            write!(f, "{}:{}: ", at.line, at.col)?;
        }
        for c in &self.context {
            write!(f, "in {c}: ")?;
        }
        f.write_str(&self.message)?;
        if let Some(h) = &self.hint {
            write!(f, " (hint: {h})")?;
        }
        Ok(())
    }
}

/// Why [`configure`] refused: every problem found, not just the first.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{} configuration problem{}: {}", .problems.len(), if .problems.len() == 1 { "" } else { "s" },
    .problems.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; "))]
pub struct ConfigureError {
    /// Each problem, in the order the values were given (node id and bit rate first).
    pub problems: Vec<ConfigProblem>,
}

/// Configures a device description for one node: the result is a DCF model with
/// `[DeviceComissioning]` `NodeID` (and `Baudrate`, when given) set and a `ParameterValue` on
/// each entry in `values`.
///
/// Nothing is resolved: `DefaultValue`s stay as the EDS wrote them (`$NODEID+0x180` stays
/// symbolic) and a `$NODEID` expression given as a value is recorded as such. Each value is
/// checked against its entry: the entry exists and is writable, the value has the entry's type
/// (an integer is accepted for a REAL and recorded as a REAL), fits the type's range and the
/// entry's `LowLimit`/`HighLimit` (with `$NODEID` taken as `node_id`). Every problem is
/// reported, each with the entry's location in the description.
///
/// ```
/// use canopen_eds::model::*;
/// use canopen_eds::write::configure;
/// # let mut model = Model::default();
/// # let mut subs = SubMap::new();
/// # subs.insert(SubIndex(0), Entry { sub: SubIndex(0), name: "Modes of operation".into(),
/// #     data_type: DataType::Integer8, access: Access::Rw, pdo_mapping: true, default: Some(Value::int(0)),
/// #     extras: None, at: SourceRef::default() });
/// # model.objects.insert(Index(0x6060), Object { index: Index(0x6060), name: "Modes of operation".into(),
/// #     object_type: ObjectType::Var, category: Category::Optional, subs, compact_sub_obj: None,
/// #     object_links: vec![], obj_flags: None, extra: vec![], at: SourceRef::default() });
/// let dcf = configure(&model, 5, Some(500), &[(0x6060, 0, Value::int(1))]).unwrap();
/// assert_eq!(dcf.node_id(), Some(5));
/// assert_eq!(dcf.entry(0x6060, 0).unwrap().parameter_value(), Some(&Value::int(1)));
/// assert!(configure(&model, 5, None, &[(0x6060, 0, Value::int(300))]).is_err());
/// ```
pub fn configure(
    model: &Model,
    node_id: u8,
    baud_kbit: Option<u16>,
    values: &[(u16, u8, Value)],
) -> Result<Model, ConfigureError> {
    let mut problems = Vec::new();
    let general = |message: String, hint: Option<String>| ConfigProblem {
        target: None,
        at: None,
        context: Vec::new(),
        message,
        hint,
    };
    if !(1..=127).contains(&node_id) {
        problems.push(general(
            format!("node id {node_id} is outside 1..=127"),
            Some("CANopen node ids are 1 to 127".to_owned()),
        ));
    }
    if let Some(baud) = baud_kbit {
        if !STANDARD_BAUD_RATES.contains(&baud) {
            problems.push(general(
                format!("{baud} kbit/s is not a CANopen bit rate"),
                Some(format!("use one of {STANDARD_BAUD_RATES:?}")),
            ));
        } else if !model.device_info.baud_rates.is_empty() && model.device_info.baud_rates.get(&baud) != Some(&true) {
            let supported: Vec<u16> =
                model.device_info.baud_rates.iter().filter(|(_, on)| **on).map(|(r, _)| *r).collect();
            problems.push(general(
                format!("the device does not support {baud} kbit/s (`BaudRate_{baud}` is not 1 in [DeviceInfo])"),
                Some(format!("supported: {supported:?} kbit/s")),
            ));
        }
    }

    let mut out = model.clone();
    let mut seen = std::collections::BTreeSet::new();
    for (index, sub, value) in values {
        let (index, sub) = (*index, *sub);
        let target = Some((Index(index), SubIndex(sub)));
        let Some(obj) = model.object(index) else {
            problems.push(ConfigProblem {
                target,
                at: None,
                context: Vec::new(),
                message: format!("the device has no object 0x{index:04X}"),
                hint: None,
            });
            continue;
        };
        let obj_ctx = format!("object {} \"{}\"", obj.index, obj.name);
        let Some(entry) = obj.sub(sub) else {
            let subs: Vec<String> = obj.subs.keys().map(|s| s.0.to_string()).collect();
            problems.push(ConfigProblem {
                target,
                at: Some(obj.at),
                context: vec![obj_ctx],
                message: format!("object 0x{index:04X} has no sub-index {sub}"),
                hint: Some(format!("its sub-indices are {}", subs.join(", "))),
            });
            continue;
        };
        let mut problem = |message: String, hint: Option<String>| {
            problems.push(ConfigProblem {
                target,
                at: Some(entry.at),
                context: vec![obj_ctx.clone(), format!("sub {} \"{}\"", entry.sub, entry.name)],
                message,
                hint,
            })
        };
        if !seen.insert((index, sub)) {
            problem("this entry is configured twice".to_owned(), Some("give each entry one value".to_owned()));
            continue;
        }
        if !entry.access.writable() {
            problem(
                format!("the entry is `{}`, so a master cannot write a configured value to it", entry.access.as_str()),
                None,
            );
            continue;
        }
        match check_config_value(entry, value, node_id) {
            Ok(v) => {
                if let Some(e) = out.objects.get_mut(&Index(index)).and_then(|o| o.subs.get_mut(&SubIndex(sub))) {
                    e.set_parameter_value(Some(v));
                }
            }
            Err((message, hint)) => problem(message, hint),
        }
    }
    if !problems.is_empty() {
        return Err(ConfigureError { problems });
    }
    out.kind = FileKind::Dcf;
    let c = out.commissioning.get_or_insert_with(Commissioning::default);
    c.node_id = Some(node_id);
    if baud_kbit.is_some() {
        c.baudrate = baud_kbit;
    }
    Ok(out)
}

/// A value as a number, for comparisons against limits (`$NODEID` resolved).
fn numeric(value: &Value, node_id: u8) -> Option<f64> {
    match value {
        Value::Real(x) => Some(*x),
        v => v.resolve(node_id).map(|i| i as f64),
    }
}

/// Checks one configured value against its entry; gives back the value to record.
fn check_config_value(entry: &Entry, value: &Value, node_id: u8) -> Result<Value, (String, Option<String>)> {
    let ty = entry.data_type;
    let shown = format_value(value, ty);
    let wrong_kind = |what: &str| {
        Err((format!("`{shown}` is {what}, not a {} value", ty.name()), Some(format!("give a {} value", ty.name()))))
    };
    let value = match (ty, value) {
        (DataType::Other(code), v) => {
            return if v.is_node_relative() {
                Err((format!("`$NODEID` cannot be checked against the complex type 0x{code:04X}"), None))
            } else {
                Ok(v.clone())
            };
        }
        (DataType::VisibleString | DataType::UnicodeString, Value::Text(t)) => {
            if t.contains(['\n', '\r']) || t.trim() != t {
                return Err((
                    "text with a line break or white space at either end cannot be written in a DCF".to_owned(),
                    None,
                ));
            }
            if ty == DataType::VisibleString && !t.chars().all(|c| (' '..='~').contains(&c)) {
                return Err((
                    "a VISIBLE_STRING holds printable ASCII only".to_owned(),
                    Some("use a UNICODE_STRING entry for other characters".to_owned()),
                ));
            }
            value.clone()
        }
        (DataType::OctetString, Value::Bytes(_)) | (DataType::Domain, Value::Bytes(_)) => value.clone(),
        (DataType::VisibleString | DataType::UnicodeString, _) => return wrong_kind("not text"),
        (DataType::OctetString | DataType::Domain, _) => return wrong_kind("not a string of hex bytes"),
        (DataType::Real32 | DataType::Real64, Value::Real(_)) => value.clone(),
        (DataType::Real32 | DataType::Real64, Value::Int { value: i, .. }) => Value::Real(*i as f64),
        (DataType::Real32 | DataType::Real64, _) => return wrong_kind("not a number"),
        (_, Value::Int { .. } | Value::NodeIdPlus { .. }) => {
            let resolved = value.resolve(node_id).unwrap_or_default();
            let (lo, hi) = ty.int_range().unwrap_or((0, (1i128 << ty.bits().unwrap_or(64)) - 1));
            if resolved < lo || resolved > hi {
                let with = if value.is_node_relative() { format!(" (with node id {node_id})") } else { String::new() };
                return Err((format!("{resolved}{with} is outside the {} range {lo}..={hi}", ty.name()), None));
            }
            value.clone()
        }
        (_, _) => return wrong_kind("not an integer"),
    };
    if let Some(x) = numeric(&value, node_id) {
        if ty == DataType::Real32 && x.is_finite() && (x as f32).is_infinite() {
            return Err((format!("{x} does not fit a REAL32"), None));
        }
        let low = entry.low_limit().and_then(|l| numeric(l, node_id));
        let high = entry.high_limit().and_then(|h| numeric(h, node_id));
        if let Some(lo) = low.filter(|lo| x < *lo) {
            return Err((format!("{shown} is below the entry's LowLimit {lo}"), None));
        }
        if let Some(hi) = high.filter(|hi| x > *hi) {
            return Err((format!("{shown} is above the entry's HighLimit {hi}"), None));
        }
    }
    Ok(value)
}
