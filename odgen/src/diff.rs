//! What changed between two device descriptions.
//!
//! [`diff`] compares two [`Model`]s by meaning, not by spelling: `0x10` and `16` are the same
//! default, key order and comments do not exist in a model, and `$NODEID+0x180` stays symbolic.
//! It reports
//!
//! * objects added and removed (one row per object, not one per entry),
//! * entries added to or removed from an object that is in both,
//! * changed object fields (`ParameterName`, `ObjectType`, and the object list it is in) and
//!   changed entry fields (`ParameterName`, `DataType`, `AccessType`, `DefaultValue`,
//!   `ParameterValue`, `LowLimit`, `HighLimit`, `PDOMapping`),
//! * changed `[DeviceInfo]` fields that shape the generated code and the bus (vendor, product and
//!   revision numbers, bit rates, PDO counts, granularity).
//!
//! [`render_table`] prints an aligned table for people, [`render_json`] the same as JSON.
//!
//! ```
//! let old = eds::parse("old.eds", b"[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\n", &eds::Options::lenient()).model;
//! let mut new = old.clone();
//! new.objects.get_mut(&eds::Index(0x1000)).unwrap().subs.get_mut(&eds::SubIndex(0)).unwrap().access = eds::Access::Const;
//! let d = odgen::diff::diff(&old, &new);
//! assert_eq!(d.changes.len(), 1);
//! assert!(odgen::diff::render_table(&d).contains("AccessType"));
//! ```

use std::fmt::Write as _;

use eds::model::{Category, DataType, Entry, Model, Object, ObjectType, Value};
use eds::write::format_value;
use serde::Serialize;

/// What happened to a row's subject.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Only in the new description.
    Added,
    /// Only in the old description.
    Removed,
    /// In both, with a field that differs.
    Changed,
}

impl Kind {
    fn as_str(self) -> &'static str {
        match self {
            Kind::Added => "added",
            Kind::Removed => "removed",
            Kind::Changed => "changed",
        }
    }
}

/// One difference.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Change {
    /// The object's index (`None` for `[DeviceInfo]` fields).
    pub index: Option<u16>,
    /// The entry's sub-index (`None` for a whole object or a `[DeviceInfo]` field).
    pub sub: Option<u8>,
    /// The object's name, and the entry's after a ` / ` (the new name if it changed).
    pub name: String,
    /// Added, removed or changed.
    pub kind: Kind,
    /// The field that changed, by its EDS key (`AccessType`, `DefaultValue`, ...); `None` for
    /// added and removed objects and entries.
    pub field: Option<String>,
    /// The old value as an EDS file writes it (a summary for a removed object or entry).
    pub old: Option<String>,
    /// The new value (a summary for an added object or entry).
    pub new: Option<String>,
}

impl Change {
    /// `0x6041`, `0x1A00sub1`, or `[DeviceInfo]`.
    pub fn location(&self) -> String {
        match (self.index, self.sub) {
            (Some(i), Some(s)) => format!("0x{i:04X}sub{s:X}"),
            (Some(i), None) => format!("0x{i:04X}"),
            _ => "[DeviceInfo]".to_owned(),
        }
    }
}

/// Every difference between two descriptions, in (index, sub-index) order, `[DeviceInfo]` first.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Diff {
    /// The differences.
    pub changes: Vec<Change>,
}

/// Counts of a [`Diff`], for its summary line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Summary {
    /// Objects only in the new description.
    pub objects_added: usize,
    /// Objects only in the old description.
    pub objects_removed: usize,
    /// Entries added to objects that are in both.
    pub entries_added: usize,
    /// Entries removed from objects that are in both.
    pub entries_removed: usize,
    /// Changed fields (of objects, entries and `[DeviceInfo]`).
    pub fields_changed: usize,
}

impl Diff {
    /// Whether the descriptions mean the same.
    pub fn is_empty(&self) -> bool {
        self.changes.is_empty()
    }

    /// How many of each kind.
    pub fn summary(&self) -> Summary {
        let mut s = Summary::default();
        for c in &self.changes {
            match (c.kind, c.sub) {
                (Kind::Changed, _) => s.fields_changed += 1,
                (Kind::Added, None) => s.objects_added += 1,
                (Kind::Removed, None) => s.objects_removed += 1,
                (Kind::Added, Some(_)) => s.entries_added += 1,
                (Kind::Removed, Some(_)) => s.entries_removed += 1,
            }
        }
        s
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let parts: Vec<String> = [
            (self.objects_added, "object", "added"),
            (self.objects_removed, "object", "removed"),
            (self.entries_added, "entry", "added"),
            (self.entries_removed, "entry", "removed"),
            (self.fields_changed, "field", "changed"),
        ]
        .into_iter()
        .filter(|(n, _, _)| *n > 0)
        .map(|(n, what, how)| {
            let what = match (n, what) {
                (1, w) => w.to_owned(),
                (_, "entry") => "entries".to_owned(),
                (_, w) => format!("{w}s"),
            };
            format!("{n} {what} {how}")
        })
        .collect();
        if parts.is_empty() { f.write_str("no differences") } else { f.write_str(&parts.join(", ")) }
    }
}

/// A value by meaning (radix ignored), for comparing.
fn same_value(a: Option<&Value>, b: Option<&Value>) -> bool {
    match (a, b) {
        (Some(Value::Int { value: x, .. }), Some(Value::Int { value: y, .. })) => x == y,
        (Some(Value::NodeIdPlus { offset: x, .. }), Some(Value::NodeIdPlus { offset: y, .. })) => x == y,
        (Some(Value::Real(x)), Some(Value::Real(y))) => x.to_bits() == y.to_bits() || x == y,
        _ => a == b,
    }
}

fn type_text(t: DataType) -> String {
    match t {
        DataType::Other(code) => format!("0x{code:04X}"),
        t => t.name().to_owned(),
    }
}

fn object_type_text(t: ObjectType) -> &'static str {
    match t {
        ObjectType::Null => "NULL",
        ObjectType::Domain => "DOMAIN",
        ObjectType::DefType => "DEFTYPE",
        ObjectType::DefStruct => "DEFSTRUCT",
        ObjectType::Var => "VAR",
        ObjectType::Array => "ARRAY",
        ObjectType::Record => "RECORD",
    }
}

fn category_text(c: Category) -> &'static str {
    match c {
        Category::Mandatory => "MandatoryObjects",
        Category::Optional => "OptionalObjects",
        Category::Manufacturer => "ManufacturerObjects",
    }
}

fn value_text(v: Option<&Value>, t: DataType) -> Option<String> {
    v.map(|v| format_value(v, t))
}

fn entry_summary(e: &Entry) -> String {
    let mut s = format!("{} {}", type_text(e.data_type), e.access.as_str());
    if let Some(d) = value_text(e.default.as_ref(), e.data_type) {
        let _ = write!(s, " = {d}");
    }
    if e.pdo_mapping {
        s.push_str(", mappable");
    }
    s
}

fn object_summary(o: &Object) -> String {
    match o.var() {
        Some(e) => entry_summary(e),
        None => {
            let n = o.subs.len();
            format!("{} with {n} entr{}", object_type_text(o.object_type), if n == 1 { "y" } else { "ies" })
        }
    }
}

fn entry_name(o: &Object, e: &Entry) -> String {
    if o.object_type.has_subs() { format!("{} / {}", o.name, e.name) } else { o.name.as_str().to_owned() }
}

/// Compares two descriptions.
pub fn diff(old: &Model, new: &Model) -> Diff {
    let mut changes = Vec::new();
    device_info(old, new, &mut changes);
    let mut indices: Vec<_> = old.objects.keys().chain(new.objects.keys()).copied().collect();
    indices.sort();
    indices.dedup();
    for index in indices {
        let i = index.0;
        match (old.objects.get(&index), new.objects.get(&index)) {
            (Some(o), None) => changes.push(Change {
                index: Some(i),
                sub: None,
                name: o.name.as_str().to_owned(),
                kind: Kind::Removed,
                field: None,
                old: Some(object_summary(o)),
                new: None,
            }),
            (None, Some(n)) => changes.push(Change {
                index: Some(i),
                sub: None,
                name: n.name.as_str().to_owned(),
                kind: Kind::Added,
                field: None,
                old: None,
                new: Some(object_summary(n)),
            }),
            (Some(o), Some(n)) => object(o, n, &mut changes),
            (None, None) => {}
        }
    }
    Diff { changes }
}

fn field(
    changes: &mut Vec<Change>,
    index: Option<u16>,
    sub: Option<u8>,
    name: &str,
    key: &str,
    old: Option<String>,
    new: Option<String>,
) {
    changes.push(Change {
        index,
        sub,
        name: name.to_owned(),
        kind: Kind::Changed,
        field: Some(key.to_owned()),
        old,
        new,
    });
}

fn object(o: &Object, n: &Object, changes: &mut Vec<Change>) {
    let i = Some(o.index.0);
    let var = !o.object_type.has_subs() && !n.object_type.has_subs();
    if o.name != n.name {
        field(
            changes,
            i,
            None,
            &n.name,
            "ParameterName",
            Some(o.name.as_str().to_owned()),
            Some(n.name.as_str().to_owned()),
        );
    }
    if o.object_type != n.object_type {
        let t = |x: &Object| Some(object_type_text(x.object_type).to_owned());
        field(changes, i, None, &n.name, "ObjectType", t(o), t(n));
    }
    if o.category != n.category {
        let c = |x: &Object| Some(category_text(x.category).to_owned());
        field(changes, i, None, &n.name, "object list", c(o), c(n));
    }
    let mut subs: Vec<_> = o.subs.keys().chain(n.subs.keys()).copied().collect();
    subs.sort();
    subs.dedup();
    for sub in subs {
        let s = sub.0;
        // A VAR's single entry is the object: report its fields at the index alone.
        let at = if var && s == 0 { None } else { Some(s) };
        match (o.subs.get(&sub), n.subs.get(&sub)) {
            (Some(e), None) => changes.push(Change {
                index: i,
                sub: Some(s),
                name: entry_name(o, e),
                kind: Kind::Removed,
                field: None,
                old: Some(entry_summary(e)),
                new: None,
            }),
            (None, Some(e)) => changes.push(Change {
                index: i,
                sub: Some(s),
                name: entry_name(n, e),
                kind: Kind::Added,
                field: None,
                old: None,
                new: Some(entry_summary(e)),
            }),
            (Some(a), Some(b)) => {
                let name = entry_name(n, b);
                if a.name != b.name && at.is_some() {
                    field(
                        changes,
                        i,
                        at,
                        &name,
                        "ParameterName",
                        Some(a.name.as_str().to_owned()),
                        Some(b.name.as_str().to_owned()),
                    );
                }
                if a.data_type != b.data_type {
                    field(
                        changes,
                        i,
                        at,
                        &name,
                        "DataType",
                        Some(type_text(a.data_type)),
                        Some(type_text(b.data_type)),
                    );
                }
                if a.access != b.access {
                    let t = |e: &Entry| Some(e.access.as_str().to_owned());
                    field(changes, i, at, &name, "AccessType", t(a), t(b));
                }
                for (key, x, y) in [
                    ("DefaultValue", a.default.as_ref(), b.default.as_ref()),
                    ("ParameterValue", a.parameter_value(), b.parameter_value()),
                    ("LowLimit", a.low_limit(), b.low_limit()),
                    ("HighLimit", a.high_limit(), b.high_limit()),
                ] {
                    if !same_value(x, y) || (x.is_some() != y.is_some()) {
                        field(changes, i, at, &name, key, value_text(x, a.data_type), value_text(y, b.data_type));
                    }
                }
                if a.pdo_mapping != b.pdo_mapping {
                    let t = |e: &Entry| Some(u8::from(e.pdo_mapping).to_string());
                    field(changes, i, at, &name, "PDOMapping", t(a), t(b));
                }
            }
            (None, None) => {}
        }
    }
}

fn device_info(old: &Model, new: &Model, changes: &mut Vec<Change>) {
    let (a, b) = (&old.device_info, &new.device_info);
    let hex = |v: Option<u32>| v.map(|v| format!("0x{v:08X}"));
    let num = |v: Option<u16>| v.map(|v| v.to_string());
    let rates = |m: &std::collections::BTreeMap<u16, bool>| {
        let on: Vec<String> = m.iter().filter(|(_, on)| **on).map(|(r, _)| r.to_string()).collect();
        Some(if on.is_empty() { "none".to_owned() } else { on.join(", ") })
    };
    let rows: [(&str, Option<String>, Option<String>); 9] = [
        ("VendorName", a.vendor_name.clone(), b.vendor_name.clone()),
        ("VendorNumber", hex(a.vendor_number), hex(b.vendor_number)),
        ("ProductName", a.product_name.clone(), b.product_name.clone()),
        ("ProductNumber", hex(a.product_number), hex(b.product_number)),
        ("RevisionNumber", hex(a.revision_number), hex(b.revision_number)),
        ("BaudRate (kbit/s)", rates(&a.baud_rates), rates(&b.baud_rates)),
        ("NrOfRXPDO", num(a.nr_of_rx_pdo), num(b.nr_of_rx_pdo)),
        ("NrOfTXPDO", num(a.nr_of_tx_pdo), num(b.nr_of_tx_pdo)),
        ("Granularity", a.granularity.map(|g| g.to_string()), b.granularity.map(|g| g.to_string())),
    ];
    for (key, x, y) in rows {
        if x != y {
            field(changes, None, None, "", key, x, y);
        }
    }
}

/// Longest cell text in the table; longer values are cut with `…` (the JSON has them whole).
pub const MAX_CELL: usize = 48;

fn cell(s: &str) -> String {
    if s.chars().count() > MAX_CELL {
        let mut t: String = s.chars().take(MAX_CELL - 1).collect();
        t.push('…');
        t
    } else {
        s.to_owned()
    }
}

/// The differences as an aligned table followed by a summary line; `no differences` alone when
/// the descriptions mean the same.
///
/// ```text
/// WHERE         NAME                                CHANGE   FIELD         OLD                                NEW
/// 0x1008        Manufacturer device name            removed                VISIBLE_STRING const = Test drive
/// 0x1018sub3    Identity object / Revision number   added                                                     UNSIGNED32 ro = 0x00000002
/// 0x6060        Modes of operation                  changed  AccessType    rw                                 ro
/// 1 object removed, 1 entry added, 1 field changed
/// ```
pub fn render_table(d: &Diff) -> String {
    let mut out = String::new();
    if d.is_empty() {
        out.push_str("no differences\n");
        return out;
    }
    let header = ["WHERE", "NAME", "CHANGE", "FIELD", "OLD", "NEW"];
    let rows: Vec<[String; 6]> = d
        .changes
        .iter()
        .map(|c| {
            [
                c.location(),
                cell(&c.name),
                c.kind.as_str().to_owned(),
                c.field.clone().unwrap_or_default(),
                cell(c.old.as_deref().unwrap_or(if c.kind == Kind::Changed { "-" } else { "" })),
                cell(c.new.as_deref().unwrap_or(if c.kind == Kind::Changed { "-" } else { "" })),
            ]
        })
        .collect();
    let mut widths = header.map(|h| h.chars().count());
    for r in &rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let mut line = |cells: &[&str]| {
        let mut l = String::new();
        for (i, (c, w)) in cells.iter().zip(widths).enumerate() {
            if i > 0 {
                l.push_str("  ");
            }
            l.push_str(c);
            if i + 1 < cells.len() {
                l.push_str(&" ".repeat(w - c.chars().count()));
            }
        }
        out.push_str(l.trim_end());
        out.push('\n');
    };
    line(&header);
    for r in &rows {
        line(&r.each_ref().map(String::as_str));
    }
    let _ = writeln!(out, "{}", d.summary());
    out
}

/// The differences as JSON: `{"identical", "summary", "changes": [{"where", "index", "sub",
/// "name", "change", "field", "old", "new"}]}` (index and sub as numbers, `null` where not
/// applicable).
pub fn render_json(d: &Diff) -> String {
    let changes: Vec<serde_json::Value> = d
        .changes
        .iter()
        .map(|c| {
            serde_json::json!({
                "where": c.location(),
                "index": c.index,
                "sub": c.sub,
                "name": c.name,
                "change": c.kind,
                "field": c.field,
                "old": c.old,
                "new": c.new,
            })
        })
        .collect();
    let doc = serde_json::json!({
        "identical": d.is_empty(),
        "summary": d.summary(),
        "changes": changes,
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_else(|_| "{}".to_owned());
    s.push('\n');
    s
}
