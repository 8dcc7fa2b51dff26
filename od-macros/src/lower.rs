//! The front end's second half: the spanned syntax tree → [`eds::Model`], the same typed model
//! an EDS file lowers to.
//!
//! Everything a declaration can get wrong on its own is checked here and reported on the
//! offending tokens: unknown data types and access keywords, indices and sub-indices out of
//! range, duplicates, values that do not fit their type or their limits, PDO mappings that name
//! entries nobody declared. Checks that concern the dictionary as a whole (mandatory objects,
//! PDO lengths and directions, strict CiA 306 conformance) are the EDS reader's and the code
//! generator's, run on this model by [`crate::validate`].
//!
//! Besides the model, lowering records where each part of it was declared ([`Spans`]), so that
//! diagnostics about the model can point back at the macro input, and which objects could not be
//! lowered because of an error ([`Lowered::poisoned`]), so that follow-up problems about them
//! are not reported.

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet};

use eds::model::{
    Access, Category, DataType, Entry, Index, Model, Object, ObjectType, PdoMappingEntry, Radix, Role, SourceRef,
    SubIndex, Value,
};
use proc_macro2::Ident;

use crate::ast::{BrokenKind, Dsl, Item, Name, Num, ObjKind, ObjectDecl, PdoDecl, Prop, Spec, Val};
use crate::ctxt::{Ctxt, Loc};

/// The module name when the input has no `mod name;`.
pub(crate) const DEFAULT_MODULE: &str = "od";

/// The CiA 301 bit rates, in kbit/s.
const BAUD_RATES: [u16; 8] = [10, 20, 50, 125, 250, 500, 800, 1000];

/// A part of an entry's declaration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Field {
    /// The whole declaration.
    Decl,
    Name,
    Type,
    Access,
    Pdo,
    Default,
    Low,
    High,
}

/// Where each part of the model was declared in the macro input.
#[derive(Default)]
pub(crate) struct Spans {
    /// Object declarations (their head: keyword to name).
    pub objects: HashMap<u16, Loc>,
    /// Entry parts by `(index, sub-index, part)`.
    pub entries: HashMap<(u16, u8, Field), Loc>,
    /// The `device` keyword.
    pub device: Option<Loc>,
    /// `[FileInfo]`/`[DeviceInfo]` keys (lower case; `baudrate` for every `BaudRate_N`) → the
    /// property that set them.
    pub info_keys: HashMap<String, Loc>,
}

impl Spans {
    /// The most precise place known for a part of an entry (falling back to the entry, then
    /// to the object).
    pub fn entry(&self, index: u16, sub: Option<u8>, field: Field) -> Option<Loc> {
        let precise = sub.and_then(|sub| {
            self.entries.get(&(index, sub, field)).or_else(|| self.entries.get(&(index, sub, Field::Decl)))
        });
        if let Some(l) = precise {
            return Some(*l);
        }
        self.objects.get(&index).copied()
    }
}

/// The result of lowering.
pub(crate) struct Lowered {
    /// The model (without the objects that had errors).
    pub model: Model,
    /// The generated module's name.
    pub module: String,
    /// `strict;`, if given.
    pub strict: Option<Loc>,
    /// Where things were declared.
    pub spans: Spans,
    /// Indices of objects that were declared but not lowered because of an error.
    pub poisoned: BTreeSet<u16>,
    /// Whether the device block had an error.
    pub device_poisoned: bool,
    /// PDO mapping entries `(mapping index, sub-index)` → the index they map.
    pub map_targets: HashMap<(u16, u8), u16>,
    /// The whole macro input.
    pub input: Loc,
    /// Whether parsing or lowering reported any error.
    pub had_errors: bool,
}

/// Lowers a parsed input. Errors go to `cx`; the model holds everything that lowered cleanly.
pub(crate) fn lower(dsl: &Dsl, cx: &mut Ctxt, errors_before_parse: usize) -> Lowered {
    let mut l = Lowerer {
        cx,
        out: Lowered {
            model: Model::default(),
            module: DEFAULT_MODULE.to_owned(),
            strict: None,
            spans: Spans::default(),
            poisoned: BTreeSet::new(),
            device_poisoned: false,
            map_targets: HashMap::new(),
            input: dsl.loc,
            had_errors: false,
        },
        declared: HashMap::new(),
    };
    let mut module_seen = false;
    let mut device: Option<(Loc, &[Prop])> = None;
    for item in &dsl.items {
        match item {
            Item::Module { name } => {
                if module_seen {
                    l.cx.error(Loc::of(name.span()), "the module name is already given");
                }
                module_seen = true;
                l.out.module = name.to_string();
            }
            Item::Strict(loc) => {
                if l.out.strict.is_some() {
                    l.cx.error(*loc, "`strict;` is already given");
                }
                l.out.strict = Some(*loc);
            }
            Item::Device { kw, props } => {
                if device.is_some() {
                    l.cx.error(*kw, "the device is already described; give one `device { … }` block");
                } else {
                    device = Some((*kw, props));
                }
            }
            Item::Broken { kind, number } => match (kind, number.and_then(|n| u16::try_from(n).ok())) {
                (BrokenKind::Object, Some(index)) => {
                    l.out.poisoned.insert(index);
                }
                (BrokenKind::Pdo(rx), Some(n)) if (1..=512).contains(&n) => {
                    let comm = if *rx { 0x1400 } else { 0x1800 } + n - 1;
                    l.out.poisoned.extend([comm, comm + 0x200]);
                }
                (BrokenKind::Device, _) => l.out.device_poisoned = true,
                _ => {}
            },
            Item::Object(_) | Item::Pdo(_) => {}
        }
    }
    l.device(device);
    for item in &dsl.items {
        if let Item::Object(d) = item {
            l.object(d);
        }
    }
    for item in &dsl.items {
        if let Item::Pdo(p) = item {
            l.pdo(p);
        }
    }
    let model = &mut l.out.model;
    let count = |m: &Model, f: fn(Role) -> bool| m.objects.keys().filter(|i| f(i.role())).count() as u16;
    model.device_info.nr_of_rx_pdo = Some(count(model, |r| matches!(r, Role::RpdoCommunication(_))));
    model.device_info.nr_of_tx_pdo = Some(count(model, |r| matches!(r, Role::TpdoCommunication(_))));
    l.out.had_errors = l.cx.count() > errors_before_parse;
    l.out
}

struct Lowerer<'c> {
    cx: &'c mut Ctxt,
    out: Lowered,
    /// Every index declared so far (by an object or a PDO), with the name it was declared as.
    declared: HashMap<u16, String>,
}

/// The object list CiA 306 puts an index in.
fn category(index: u16) -> Category {
    match index {
        0x1000 | 0x1001 | 0x1018 => Category::Mandatory,
        0x2000..=0x5FFF => Category::Manufacturer,
        _ => Category::Optional,
    }
}

fn radix(hex: bool) -> Radix {
    if hex { Radix::Hex } else { Radix::Dec }
}

/// An entry with the given basics and nothing else.
fn plain_entry(sub: u8, name: &str, data_type: DataType, access: Access, default: Option<Value>) -> Entry {
    Entry {
        sub: SubIndex(sub),
        name: name.into(),
        data_type,
        access,
        pdo_mapping: false,
        default,
        extras: None,
        at: SourceRef::default(),
    }
}

fn plain_object(index: u16, name: &str, object_type: ObjectType, subs: BTreeMap<SubIndex, Entry>) -> Object {
    Object {
        index: Index(index),
        name: name.into(),
        object_type,
        category: category(index),
        subs: subs.into(),
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: SourceRef::default(),
    }
}

/// The name of the count entry (sub-index 0) of generated ARRAY and RECORD objects.
const SUB0_NAME: &str = "Highest sub-index supported";

const DATA_TYPES: &str = "a CiA 301 type name (UNSIGNED16, INTEGER32, REAL32, VISIBLE_STRING, TIME_OF_DAY, …) \
     or a Rust primitive (bool, u8..u64, i8..i64, f32, f64)";

/// The properties an entry can have.
#[derive(Default)]
struct EntryProps<'p> {
    pdo: Option<Loc>,
    default: Option<&'p Val>,
    min: Option<&'p Val>,
    max: Option<&'p Val>,
}

/// Where an entry's parts were declared.
struct EntryLocs {
    decl: Loc,
    name: Loc,
    ty: Loc,
    access: Loc,
}

impl Lowerer<'_> {
    // ---- device ------------------------------------------------------------------------------

    fn device(&mut self, device: Option<(Loc, &[Prop])>) {
        let module = self.out.module.clone();
        let fi = &mut self.out.model.file_info;
        fi.file_name = Some(format!("{module}.eds"));
        fi.file_version = Some(1);
        fi.file_revision = Some(0);
        fi.eds_version = Some("4.0".to_owned());
        let di = &mut self.out.model.device_info;
        di.granularity = Some(8);
        di.simple_boot_up_master = Some(false);
        di.simple_boot_up_slave = Some(true);
        let Some((kw, props)) = device else { return };
        self.out.spans.device = Some(kw);
        let before = self.cx.count();
        let mut seen = HashSet::new();
        for p in props {
            let key = p.key.to_string();
            if !seen.insert(key.clone()) {
                self.cx.error(Loc::of(p.key.span()), format!("`{key}` is already given"));
                continue;
            }
            let Some(v) = self.needs_value(p) else { continue };
            let (eds_key, ok) = match key.as_str() {
                "vendor_name" => ("vendorname", self.set_text(v, |m| &mut m.device_info.vendor_name)),
                "product_name" => ("productname", self.set_text(v, |m| &mut m.device_info.product_name)),
                "order_code" => ("ordercode", self.set_text(v, |m| &mut m.device_info.order_code)),
                "description" => ("description", self.set_text(v, |m| &mut m.file_info.description)),
                "created_by" => ("createdby", self.set_text(v, |m| &mut m.file_info.created_by)),
                "vendor_id" => (
                    "vendornumber",
                    self.set_uint(v, u32::MAX as u64, |m, x| m.device_info.vendor_number = Some(x as u32)),
                ),
                "product_code" => (
                    "productnumber",
                    self.set_uint(v, u32::MAX as u64, |m, x| m.device_info.product_number = Some(x as u32)),
                ),
                "revision" => (
                    "revisionnumber",
                    self.set_uint(v, u32::MAX as u64, |m, x| m.device_info.revision_number = Some(x as u32)),
                ),
                "granularity" => {
                    ("granularity", self.set_uint(v, 64, |m, x| m.device_info.granularity = Some(x as u8)))
                }
                "file_version" => {
                    ("fileversion", self.set_uint(v, 0xFF, |m, x| m.file_info.file_version = Some(x as u32)))
                }
                "file_revision" => {
                    ("filerevision", self.set_uint(v, 0xFF, |m, x| m.file_info.file_revision = Some(x as u32)))
                }
                "simple_boot_up_master" => {
                    ("simplebootupmaster", self.set_bool(v, |m, b| m.device_info.simple_boot_up_master = Some(b)))
                }
                "simple_boot_up_slave" => {
                    ("simplebootupslave", self.set_bool(v, |m, b| m.device_info.simple_boot_up_slave = Some(b)))
                }
                "lss_supported" => ("lss_supported", self.set_bool(v, |m, b| m.device_info.lss_supported = Some(b))),
                "baud_rates" => ("baudrate", self.baud_rates(v)),
                _ => {
                    self.cx.error(
                        Loc::of(p.key.span()),
                        format!(
                            "unknown device property `{key}`; expected one of vendor_name, vendor_id, product_name, \
                             product_code, revision, order_code, baud_rates, granularity, description, created_by, \
                             file_version, file_revision, simple_boot_up_master, simple_boot_up_slave, lss_supported"
                        ),
                    );
                    continue;
                }
            };
            if ok {
                self.out.spans.info_keys.insert(eds_key.to_owned(), p.loc);
            }
        }
        if self.cx.count() > before {
            self.out.device_poisoned = true;
        }
    }

    fn needs_value<'p>(&mut self, p: &'p Prop) -> Option<&'p Val> {
        if p.value.is_none() {
            self.cx.error(p.loc, format!("`{}` needs a value: `{} = …`", p.key, p.key));
        }
        p.value.as_ref()
    }

    fn set_text(&mut self, v: &Val, slot: fn(&mut Model) -> &mut Option<String>) -> bool {
        let Val::Text { value, loc } = v else {
            self.cx.error(v.loc(), format!("expected a string, found {}", v.describe()));
            return false;
        };
        if !self.check_text(value, *loc, "this text", false) {
            return false;
        }
        *slot(&mut self.out.model) = Some(value.clone());
        true
    }

    fn set_uint(&mut self, v: &Val, max: u64, set: fn(&mut Model, u64)) -> bool {
        match v {
            Val::Int { value, .. } if (0..=max as i128).contains(value) => {
                set(&mut self.out.model, *value as u64);
                true
            }
            Val::Int { value, loc, .. } => {
                self.cx.error(*loc, format!("{value} is out of range 0..={max}"));
                false
            }
            other => {
                self.cx.error(other.loc(), format!("expected an integer, found {}", other.describe()));
                false
            }
        }
    }

    fn set_bool(&mut self, v: &Val, set: fn(&mut Model, bool)) -> bool {
        match v {
            Val::Bool { value, .. } => {
                set(&mut self.out.model, *value);
                true
            }
            other => {
                self.cx.error(other.loc(), format!("expected `true` or `false`, found {}", other.describe()));
                false
            }
        }
    }

    fn baud_rates(&mut self, v: &Val) -> bool {
        let Val::List { items, .. } = v else {
            self.cx.error(v.loc(), "expected a list of bit rates in kbit/s, as in `[125, 250, 500, 1000]`");
            return false;
        };
        let before = self.cx.count();
        let mut rates = BTreeMap::new();
        for r in BAUD_RATES {
            rates.insert(r, false);
        }
        for item in items {
            match item {
                Val::Int { value, .. } if BAUD_RATES.iter().any(|&r| r as i128 == *value) => {
                    rates.insert(*value as u16, true);
                }
                other => self.cx.error(
                    other.loc(),
                    "expected a CiA 301 bit rate in kbit/s: 10, 20, 50, 125, 250, 500, 800 or 1000",
                ),
            }
        }
        if self.cx.count() > before {
            return false;
        }
        self.out.model.device_info.baud_rates = rates;
        true
    }

    /// Text that an EDS line can hold: no line break, no white space at either end (readers trim
    /// values), and for names not empty.
    fn check_text(&mut self, s: &str, loc: Loc, what: &str, is_name: bool) -> bool {
        let problem = if is_name && s.trim().is_empty() {
            Some("is empty")
        } else if s.contains(['\n', '\r']) {
            Some("contains a line break, which an EDS line cannot hold")
        } else if s.trim() != s {
            Some("starts or ends with white space, which EDS readers remove")
        } else {
            None
        };
        if let Some(p) = problem {
            self.cx.error(loc, format!("{what} {p}"));
            return false;
        }
        true
    }

    // ---- objects -----------------------------------------------------------------------------

    fn index(&mut self, n: Num) -> Option<u16> {
        match u16::try_from(n.value) {
            Ok(i) if i >= 0x1000 => Some(i),
            Ok(i) => {
                self.cx.error(
                    n.loc,
                    format!("index 0x{i:04X} is a data type definition (0x0001..=0x0FFF); objects start at 0x1000"),
                );
                None
            }
            Err(_) => {
                self.cx
                    .error(n.loc, format!("index 0x{:X} is out of range: object indices are 0x1000..=0xFFFF", n.value));
                None
            }
        }
    }

    /// Claims `index` for `name`; reports a duplicate at `loc`.
    fn claim(&mut self, index: u16, name: &str, loc: Loc, what: impl FnOnce() -> String) -> bool {
        if let Some(first) = self.declared.get(&index) {
            self.cx.error(loc, format!("{}: object 0x{index:04X} is already declared (\"{first}\")", what()));
            return false;
        }
        self.declared.insert(index, name.to_owned());
        true
    }

    fn object(&mut self, d: &ObjectDecl) {
        let before = self.cx.count();
        let Some(index) = self.index(d.index) else { return };
        // A duplicate is still checked (every mistake in one compile), but kept out of the
        // model and of the spans, which stay the first declaration's.
        let duplicate = !self.claim(index, &d.name.value, d.index.loc, || format!("duplicate index 0x{index:04X}"));
        let saved = duplicate.then(|| std::mem::take(&mut self.out.spans));
        let head = Loc { start: d.loc.start, end: d.name.loc.end };
        self.out.spans.objects.insert(index, head);
        self.check_text(&d.name.value, d.name.loc, "the name", true);
        let obj = match d.kind {
            ObjKind::Var => self.var(index, d),
            ObjKind::Array => self.array(index, d, head),
            ObjKind::Record => self.record(index, d, head),
        };
        if let Some(spans) = saved {
            self.out.spans = spans;
            return;
        }
        match obj {
            Some(o) if self.cx.count() == before => {
                self.out.model.objects.insert(Index(index), o);
            }
            _ => {
                self.out.poisoned.insert(index);
            }
        }
    }

    fn data_type(&mut self, ty: &Ident) -> Option<DataType> {
        let s = ty.to_string();
        let rust = match s.as_str() {
            "bool" => Some(DataType::Boolean),
            "u8" => Some(DataType::Unsigned8),
            "u16" => Some(DataType::Unsigned16),
            "u32" => Some(DataType::Unsigned32),
            "u64" => Some(DataType::Unsigned64),
            "i8" => Some(DataType::Integer8),
            "i16" => Some(DataType::Integer16),
            "i32" => Some(DataType::Integer32),
            "i64" => Some(DataType::Integer64),
            "f32" => Some(DataType::Real32),
            "f64" => Some(DataType::Real64),
            _ => None,
        };
        let found = rust.or_else(|| DataType::BASIC.iter().copied().find(|t| t.name().eq_ignore_ascii_case(&s)));
        if found.is_none() {
            self.cx.error(Loc::of(ty.span()), format!("unknown data type `{s}`; expected {DATA_TYPES}"));
        }
        found
    }

    fn access(&mut self, access: &Ident) -> Option<Access> {
        let s = access.to_string();
        let found = Access::parse(&s);
        if found.is_none() {
            self.cx.error(
                Loc::of(access.span()),
                format!("unknown access type `{s}`; expected `ro`, `wo`, `rw`, `rwr`, `rww` or `const`"),
            );
        }
        found
    }

    /// Sorts an entry's properties; `extra` names the other keys allowed here (returned as is).
    fn entry_props<'p>(&mut self, props: &'p [Prop], extra: &[&str], flags: bool) -> (EntryProps<'p>, Vec<&'p Prop>) {
        let mut ep = EntryProps::default();
        let mut rest = Vec::new();
        let mut seen = HashSet::new();
        for p in props {
            let key = p.key.to_string();
            if !seen.insert(key.clone()) {
                self.cx.error(Loc::of(p.key.span()), format!("`{key}` is already given"));
                continue;
            }
            match key.as_str() {
                "pdo" if flags => match &p.value {
                    None => ep.pdo = Some(p.loc),
                    Some(_) => {
                        self.cx.error(p.loc, "`pdo` is a flag: write `pdo` alone to make the entry PDO-mappable")
                    }
                },
                "default" | "min" | "max" => {
                    let Some(v) = self.needs_value(p) else { continue };
                    match key.as_str() {
                        "default" => ep.default = Some(v),
                        "min" => ep.min = Some(v),
                        _ => ep.max = Some(v),
                    }
                }
                k if extra.contains(&k) => rest.push(p),
                _ => {
                    let mut known: Vec<&str> = if flags { vec!["pdo"] } else { Vec::new() };
                    known.extend(["default", "min", "max"]);
                    known.extend(extra);
                    let list = known.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ");
                    let hint = if key == "pdo" { " (an element takes `pdo` from its array)" } else { "" };
                    self.cx.error(Loc::of(p.key.span()), format!("unknown property `{key}`{hint}; expected {list}"));
                }
            }
        }
        (ep, rest)
    }

    /// Builds an entry and records where its parts were declared.
    #[allow(clippy::too_many_arguments)]
    fn make_entry(
        &mut self,
        index: u16,
        sub: u8,
        name: &str,
        dt: DataType,
        access: Access,
        ep: &EntryProps<'_>,
        locs: &EntryLocs,
    ) -> Entry {
        let default = ep.default.and_then(|v| self.value(dt, v, "default"));
        let low = ep.min.and_then(|v| self.limit(dt, v, "min"));
        let high = ep.max.and_then(|v| self.limit(dt, v, "max"));
        self.check_limits(dt, default.as_ref(), low.as_ref(), high.as_ref(), ep);
        let spans = &mut self.out.spans.entries;
        spans.insert((index, sub, Field::Decl), locs.decl);
        spans.insert((index, sub, Field::Name), locs.name);
        spans.insert((index, sub, Field::Type), locs.ty);
        spans.insert((index, sub, Field::Access), locs.access);
        if let Some(l) = ep.pdo {
            spans.insert((index, sub, Field::Pdo), l);
        }
        for (field, v) in [(Field::Default, ep.default), (Field::Low, ep.min), (Field::High, ep.max)] {
            if let Some(v) = v {
                spans.insert((index, sub, field), v.loc());
            }
        }
        let mut e = plain_entry(sub, name, dt, access, default);
        e.pdo_mapping = ep.pdo.is_some();
        if low.is_some() || high.is_some() {
            let x = e.extras_mut();
            x.low_limit = low;
            x.high_limit = high;
        }
        e
    }

    /// Gives a written value the entry's data type; reports what does not fit.
    fn value(&mut self, dt: DataType, v: &Val, what: &str) -> Option<Value> {
        let ty = dt.name();
        let loc = v.loc();
        let wrong = |cx: &mut Ctxt, expected: &str| {
            cx.error(loc, format!("`{what}` of a {ty} entry must be {expected}, found {}", v.describe()));
            None
        };
        let is_int = dt.is_signed() || dt.is_unsigned() || matches!(dt, DataType::TimeOfDay | DataType::TimeDifference);
        let value = match (dt, v) {
            (DataType::Boolean, Val::Bool { value, .. }) => Value::int(*value as i128),
            (DataType::Boolean, Val::Int { value, hex, .. }) => Value::Int { value: *value, radix: radix(*hex) },
            (DataType::Boolean, _) => return wrong(self.cx, "`true`, `false`, 0 or 1"),
            (_, Val::Int { value, hex, .. }) if is_int => Value::Int { value: *value, radix: radix(*hex) },
            (_, Val::NodeId { offset, hex, .. }) if is_int => Value::NodeIdPlus { offset: *offset, radix: radix(*hex) },
            _ if is_int => return wrong(self.cx, "an integer or `NODEID + n`"),
            (DataType::Real32 | DataType::Real64, Val::Int { value, .. }) => Value::Real(*value as f64),
            (DataType::Real32 | DataType::Real64, Val::Real { value, .. }) => Value::Real(*value),
            (DataType::Real32 | DataType::Real64, _) => return wrong(self.cx, "a number"),
            (DataType::VisibleString, Val::Text { value, .. }) => {
                if !value.chars().all(|c| (' '..='~').contains(&c)) {
                    self.cx.error(loc, format!("`{what}`: a VISIBLE_STRING holds printable ASCII characters only"));
                    return None;
                }
                Value::Text(value.clone())
            }
            (DataType::UnicodeString, Val::Text { value, .. }) => Value::Text(value.clone()),
            (DataType::VisibleString | DataType::UnicodeString, _) => return wrong(self.cx, "a string"),
            (DataType::OctetString | DataType::Domain, Val::Bytes { value, .. }) => Value::Bytes(value.clone()),
            (DataType::OctetString | DataType::Domain, _) => {
                return wrong(self.cx, "a byte string such as `b\"\\x01\\x02\"`");
            }
            _ => return wrong(self.cx, "a value of a basic type"),
        };
        if let Value::Text(t) = &value
            && !self.check_text(t, loc, &format!("`{what}`"), false)
        {
            return None;
        }
        let range = match dt {
            DataType::TimeOfDay | DataType::TimeDifference => Some((0, (1i128 << 48) - 1)),
            _ => dt.int_range(),
        };
        if let Some((lo, hi)) = range {
            let (a, b) = match &value {
                Value::Int { value, .. } => (*value, *value),
                Value::NodeIdPlus { offset, .. } => (offset.saturating_add(1), offset.saturating_add(127)),
                _ => (lo, hi),
            };
            if a < lo || b > hi {
                let shown = match &value {
                    Value::NodeIdPlus { .. } => format!("with node ids 1..=127 the value runs {a}..={b}, which"),
                    _ => format!("{a}"),
                };
                self.cx.error(loc, format!("`{what}` is out of range: {shown} does not fit {ty} ({lo}..={hi})"));
                return None;
            }
        }
        if let (DataType::Real32, Value::Real(r)) = (dt, &value)
            && r.abs() > f32::MAX as f64
        {
            self.cx.error(loc, format!("`{what}` is out of range: {r} does not fit REAL32"));
            return None;
        }
        Some(value)
    }

    fn limit(&mut self, dt: DataType, v: &Val, what: &str) -> Option<Value> {
        let numeric = dt.int_range().is_some() || dt.is_real();
        if !numeric {
            self.cx.error(v.loc(), format!("`{what}` applies to numeric entries; {} has no range", dt.name()));
            return None;
        }
        if let Val::NodeId { loc, .. } = v {
            self.cx.error(
                *loc,
                format!("`{what}` cannot depend on the node id; the generated setters check constant limits"),
            );
            return None;
        }
        self.value(dt, v, what)
    }

    fn check_limits(
        &mut self,
        dt: DataType,
        d: Option<&Value>,
        lo: Option<&Value>,
        hi: Option<&Value>,
        ep: &EntryProps<'_>,
    ) {
        let num = |v: Option<&Value>| match v {
            Some(Value::Int { value, .. }) => Some(*value as f64),
            Some(Value::Real(r)) => Some(*r),
            _ => None,
        };
        let show = |x: f64| if dt.is_real() { format!("{x}") } else { format!("{}", x as i128) };
        if let (Some(l), Some(h), Some(at)) = (num(lo), num(hi), ep.max)
            && l > h
        {
            self.cx.error(at.loc(), format!("`max` ({}) is less than `min` ({})", show(h), show(l)));
            return;
        }
        let Some((x, at)) = num(d).zip(ep.default) else { return };
        if let Some(l) = num(lo)
            && x < l
        {
            self.cx.error(at.loc(), format!("`default` ({}) is below `min` ({})", show(x), show(l)));
        }
        if let Some(h) = num(hi)
            && x > h
        {
            self.cx.error(at.loc(), format!("`default` ({}) is above `max` ({})", show(x), show(h)));
        }
    }

    fn spec_types(&mut self, spec: &Spec) -> (Option<DataType>, Option<Access>) {
        (self.data_type(&spec.ty), self.access(&spec.access))
    }

    fn locs(&self, decl: Loc, name: &Name, spec: &Spec) -> EntryLocs {
        EntryLocs { decl, name: name.loc, ty: Loc::of(spec.ty.span()), access: Loc::of(spec.access.span()) }
    }

    fn var(&mut self, index: u16, d: &ObjectDecl) -> Option<Object> {
        let spec = d.spec.as_ref()?;
        let (dt, acc) = self.spec_types(spec);
        let (ep, _) = self.entry_props(&d.props, &[], true);
        let (dt, acc) = (dt?, acc?);
        let locs = self.locs(Loc { start: d.loc.start, end: d.name.loc.end }, &d.name, spec);
        let e = self.make_entry(index, 0, &d.name.value, dt, acc, &ep, &locs);
        Some(plain_object(index, &d.name.value, ObjectType::Var, BTreeMap::from([(SubIndex(0), e)])))
    }

    /// A sub-index, 0..=254 (255 is reserved).
    fn sub_index(&mut self, n: Num) -> Option<u8> {
        match u8::try_from(n.value) {
            Ok(s) if s < 0xFF => Some(s),
            _ => {
                self.cx.error(
                    n.loc,
                    format!("sub-index {} is out of range: sub-indices are 0..=254 (255 is reserved)", n.value),
                );
                None
            }
        }
    }

    fn record(&mut self, index: u16, d: &ObjectDecl, head: Loc) -> Option<Object> {
        let body = d.body.as_deref().unwrap_or_default();
        let mut subs = BTreeMap::new();
        let mut ok = true;
        for s in body {
            let Some(sub) = self.sub_index(s.sub) else {
                ok = false;
                continue;
            };
            if let Some(first) = subs.get(&SubIndex(sub)).map(|e: &Entry| e.name.clone()) {
                self.cx.error(s.sub.loc, format!("sub-index {sub} of 0x{index:04X} is already declared (\"{first}\")"));
                ok = false;
                continue;
            }
            self.check_text(&s.name.value, s.name.loc, "the name", true);
            let Some(spec) = &s.spec else { continue };
            let (dt, acc) = self.spec_types(spec);
            let (ep, _) = self.entry_props(&s.props, &[], true);
            let (Some(dt), Some(acc)) = (dt, acc) else {
                ok = false;
                continue;
            };
            let locs = self.locs(s.loc, &s.name, spec);
            subs.insert(SubIndex(sub), self.make_entry(index, sub, &s.name.value, dt, acc, &ep, &locs));
        }
        if body.is_empty() {
            self.cx.error(head, "a record needs at least one sub-object");
            return None;
        }
        if !ok {
            return None;
        }
        self.count_entry(index, head, &mut subs);
        Some(plain_object(index, &d.name.value, ObjectType::Record, subs))
    }

    /// Adds sub-index 0 (the highest sub-index, read-only) unless it was declared.
    fn count_entry(&mut self, index: u16, head: Loc, subs: &mut BTreeMap<SubIndex, Entry>) {
        let highest = subs.keys().map(|s| s.0).max().unwrap_or(0);
        if let std::collections::btree_map::Entry::Vacant(slot) = subs.entry(SubIndex(0)) {
            slot.insert(plain_entry(0, SUB0_NAME, DataType::Unsigned8, Access::Ro, Some(Value::int(highest as i128))));
            self.out.spans.entries.insert((index, 0, Field::Decl), head);
        }
    }

    fn array(&mut self, index: u16, d: &ObjectDecl, head: Loc) -> Option<Object> {
        let spec = d.spec.as_ref()?;
        let (dt, acc) = self.spec_types(spec);
        let (shared, extra) = self.entry_props(&d.props, &["len", "element"], true);
        let mut len: Option<(u8, &Prop)> = None;
        let mut element = "Element".to_owned();
        for p in extra {
            let Some(v) = self.needs_value(p) else { continue };
            match (p.key.to_string().as_str(), v) {
                ("len", Val::Int { value, .. }) if (1..=254).contains(value) => len = Some((*value as u8, p)),
                ("len", v) => self.cx.error(v.loc(), "`len` is the number of elements, 1..=254"),
                (_, Val::Text { value, loc }) => {
                    if self.check_text(value, *loc, "the element name", true) {
                        element = value.clone();
                    }
                }
                (_, v) => self.cx.error(v.loc(), format!("`element` is the elements' name, found {}", v.describe())),
            }
        }
        let (dt, acc) = (dt?, acc?);
        let mut subs = BTreeMap::new();
        match (&d.body, len) {
            (Some(_), Some((_, p))) => {
                self.cx.error(p.loc, "give either `len = N` or the elements in `{ … }`, not both");
                return None;
            }
            (None, None) => {
                self.cx.error(head, "an array needs `len = N` or its elements in `{ … }`");
                return None;
            }
            (None, Some((n, _))) => {
                for k in 1..=n {
                    let locs = EntryLocs {
                        decl: head,
                        name: head,
                        ty: Loc::of(spec.ty.span()),
                        access: Loc::of(spec.access.span()),
                    };
                    let e = self.make_entry(index, k, &format!("{element} {k}"), dt, acc, &shared, &locs);
                    subs.insert(SubIndex(k), e);
                }
            }
            (Some(body), None) => {
                let mut ok = true;
                for s in body {
                    let Some(sub) = self.sub_index(s.sub) else {
                        ok = false;
                        continue;
                    };
                    if let Some(first) = subs.get(&SubIndex(sub)).map(|e: &Entry| e.name.clone()) {
                        self.cx.error(
                            s.sub.loc,
                            format!("sub-index {sub} of 0x{index:04X} is already declared (\"{first}\")"),
                        );
                        ok = false;
                        continue;
                    }
                    match (&s.spec, sub) {
                        (Some(spec), 0) => {
                            // The count entry, declared with its own type and access.
                            let (cdt, cacc) = self.spec_types(spec);
                            let (ep, _) = self.entry_props(&s.props, &[], true);
                            self.check_text(&s.name.value, s.name.loc, "the name", true);
                            if let (Some(cdt), Some(cacc)) = (cdt, cacc) {
                                let locs = self.locs(s.loc, &s.name, spec);
                                subs.insert(
                                    SubIndex(0),
                                    self.make_entry(index, 0, &s.name.value, cdt, cacc, &ep, &locs),
                                );
                            } else {
                                ok = false;
                            }
                            continue;
                        }
                        (Some(spec), _) => {
                            self.cx.error(
                                Loc::of(spec.ty.span()),
                                "an array element takes its type and access from the array; write `N \"name\", default = …` \
                                 (only sub-index 0, the count, is declared with its own)",
                            );
                            ok = false;
                            continue;
                        }
                        (None, 0) => {
                            self.cx.error(
                                s.sub.loc,
                                "sub-index 0 of an array is its element count: leave it out (it is generated) or declare \
                                 it with its type and access, as in `0 \"Number of errors\": u8, rw, default = 0;`",
                            );
                            ok = false;
                            continue;
                        }
                        (None, _) => {}
                    }
                    self.check_text(&s.name.value, s.name.loc, "the name", true);
                    let (own, _) = self.entry_props(&s.props, &[], false);
                    let ep = EntryProps {
                        pdo: shared.pdo,
                        default: own.default.or(shared.default),
                        min: own.min.or(shared.min),
                        max: own.max.or(shared.max),
                    };
                    let locs = EntryLocs {
                        decl: s.loc,
                        name: s.name.loc,
                        ty: Loc::of(spec.ty.span()),
                        access: Loc::of(spec.access.span()),
                    };
                    subs.insert(SubIndex(sub), self.make_entry(index, sub, &s.name.value, dt, acc, &ep, &locs));
                }
                if body.is_empty() {
                    self.cx.error(head, "an array needs at least one element");
                    return None;
                }
                if !ok {
                    return None;
                }
            }
        }
        self.count_entry(index, head, &mut subs);
        Some(plain_object(index, &d.name.value, ObjectType::Array, subs))
    }

    // ---- PDOs --------------------------------------------------------------------------------

    fn pdo(&mut self, p: &PdoDecl) {
        let kind = if p.rx { "RPDO" } else { "TPDO" };
        let head = Loc { start: p.loc.start, end: p.number.loc.end };
        let n = match u16::try_from(p.number.value) {
            Ok(n) if (1..=512).contains(&n) => n,
            _ => {
                self.cx.error(
                    p.number.loc,
                    format!("{kind} {} is out of range: PDOs are numbered 1..=512", p.number.value),
                );
                return;
            }
        };
        let comm = if p.rx { 0x1400 } else { 0x1800 } + n - 1;
        let map = comm + 0x200;
        let comm_name = format!("{kind} communication parameter {n}");
        let map_name = format!("{kind} mapping parameter {n}");
        let uses = || format!("{kind} {n} uses objects 0x{comm:04X} and 0x{map:04X}");
        if !self.claim(comm, &comm_name, p.number.loc, uses) || !self.claim(map, &map_name, p.number.loc, uses) {
            return;
        }
        let mut seen = HashSet::new();
        let default_cob = if n <= 4 {
            Value::NodeIdPlus { offset: if p.rx { 0x200 } else { 0x180 } + 0x100 * (n as i128 - 1), radix: Radix::Hex }
        } else {
            Value::hex(0x8000_0000)
        };
        let mut cob = (default_cob, None);
        let mut transmission = (Value::hex(0xFF), None);
        let mut inhibit = (Value::int(0), None);
        let mut event_timer = (Value::int(0), None);
        let mut capacity: (u8, Option<Loc>) = (8, None);
        let mut mapped: Vec<(PdoMappingEntry, Loc)> = Vec::new();
        let mut map_loc = None;
        for prop in &p.props {
            let key = prop.key.to_string();
            if !seen.insert(key.clone()) {
                self.cx.error(Loc::of(prop.key.span()), format!("`{key}` is already given"));
                continue;
            }
            let Some(v) = self.needs_value(prop) else { continue };
            let slot = match key.as_str() {
                "cob_id" => Some((&mut cob, DataType::Unsigned32)),
                "transmission" => Some((&mut transmission, DataType::Unsigned8)),
                "inhibit" if !p.rx => Some((&mut inhibit, DataType::Unsigned16)),
                "event_timer" => Some((&mut event_timer, DataType::Unsigned16)),
                _ => None,
            };
            if let Some((slot, dt)) = slot {
                if let Some(value) = self.value(dt, v, &key) {
                    *slot = (value, Some(v.loc()));
                }
                continue;
            }
            match key.as_str() {
                "capacity" => match v {
                    Val::Int { value, loc, .. } if (1..=64).contains(value) => capacity = (*value as u8, Some(*loc)),
                    other => self.cx.error(other.loc(), "`capacity` is the number of mapping entries, 1..=64"),
                },
                "map" => {
                    map_loc = Some(prop.loc);
                    let Val::List { items, .. } = v else {
                        self.cx.error(v.loc(), "`map` is a list of entries, as in `map = [0x6040, 0x6000:1]`");
                        continue;
                    };
                    for item in items {
                        match self.mapped(kind, n, item) {
                            Mapped::Entry(m) => mapped.push((m, item.loc())),
                            // About a broken object: reported there already.
                            Mapped::Skipped => {}
                        }
                    }
                }
                _ => {
                    let inhibit = if p.rx { "" } else { "inhibit, " };
                    let hint = if key == "inhibit" { " (an RPDO has no inhibit time)" } else { "" };
                    self.cx.error(
                        Loc::of(prop.key.span()),
                        format!(
                            "unknown PDO property `{key}`{hint}; expected cob_id, transmission, {inhibit}event_timer, map or capacity"
                        ),
                    );
                }
            }
        }
        if mapped.len() > capacity.0 as usize {
            let at = map_loc.unwrap_or(head);
            self.cx.error(
                at,
                format!("{kind} {n} maps {} entries but has room for {}; raise `capacity`", mapped.len(), capacity.0),
            );
        }
        // A PDO with mistakes is still built from what is valid (defaults for bad properties,
        // only the entries that resolved), so that the checks of the whole dictionary still see
        // it and report the problems of its valid parts; nothing it lacks can cause a false
        // report.
        mapped.truncate(capacity.0 as usize);

        // Communication parameter.
        let spans = &mut self.out.spans;
        spans.objects.insert(comm, head);
        let mut subs = BTreeMap::new();
        let cob_name = if p.rx { "COB-ID used by RPDO" } else { "COB-ID used by TPDO" };
        let mut comm_entries = vec![
            (1u8, cob_name, DataType::Unsigned32, cob),
            (2, "Transmission type", DataType::Unsigned8, transmission),
        ];
        if !p.rx {
            comm_entries.push((3, "Inhibit time", DataType::Unsigned16, inhibit));
        }
        comm_entries.push((5, "Event timer", DataType::Unsigned16, event_timer));
        for (sub, name, dt, (value, loc)) in comm_entries {
            subs.insert(SubIndex(sub), plain_entry(sub, name, dt, Access::Rw, Some(value)));
            spans.entries.insert((comm, sub, Field::Decl), head);
            if let Some(l) = loc {
                spans.entries.insert((comm, sub, Field::Default), l);
            }
        }
        subs.insert(SubIndex(0), plain_entry(0, SUB0_NAME, DataType::Unsigned8, Access::Ro, Some(Value::int(5))));
        self.out.model.objects.insert(Index(comm), plain_object(comm, &comm_name, ObjectType::Record, subs));

        // Mapping parameter.
        let map_at = map_loc.unwrap_or(head);
        spans.objects.insert(map, map_at);
        spans.entries.insert((map, 0, Field::Decl), map_at);
        let mut subs = BTreeMap::new();
        let count = Value::int(mapped.len() as i128);
        subs.insert(
            SubIndex(0),
            plain_entry(0, "Number of mapped objects", DataType::Unsigned8, Access::Rw, Some(count)),
        );
        for k in 1..=capacity.0 {
            let (value, loc) = match mapped.get(k as usize - 1) {
                Some((m, loc)) => {
                    self.out.map_targets.insert((map, k), m.index.0);
                    (Value::hex(m.to_u32() as i128), *loc)
                }
                None => (Value::hex(0), capacity.1.unwrap_or(map_at)),
            };
            spans.entries.insert((map, k, Field::Decl), loc);
            let name = format!("Mapped object {k}");
            subs.insert(SubIndex(k), plain_entry(k, &name, DataType::Unsigned32, Access::Rw, Some(value)));
        }
        self.out.model.objects.insert(Index(map), plain_object(map, &map_name, ObjectType::Record, subs));
    }

    /// Resolves one `map` element to a mapping entry.
    fn mapped(&mut self, kind: &str, n: u16, item: &Val) -> Mapped {
        let (index, sub, loc) = match item {
            Val::Int { value, loc, .. } => (*value, 0i128, *loc),
            Val::Ref { index, sub, loc } => (index.value as i128, sub.value as i128, *loc),
            other => {
                self.cx.error(
                    other.loc(),
                    format!("expected an entry such as `0x6040` or `0x6000:1`, found {}", other.describe()),
                );
                return Mapped::Skipped;
            }
        };
        let (Ok(index), Ok(sub)) = (u16::try_from(index), u8::try_from(sub)) else {
            self.cx.error(loc, "an entry is `index` (0..=0xFFFF) or `index:sub` (sub 0..=255)");
            return Mapped::Skipped;
        };
        if self.out.poisoned.contains(&index) {
            return Mapped::Skipped;
        }
        let Some(obj) = self.out.model.objects.get(&Index(index)) else {
            self.cx.error(
                loc,
                format!("{kind} {n} maps 0x{index:04X} sub {sub}, but no object 0x{index:04X} is declared"),
            );
            return Mapped::Skipped;
        };
        let Some(e) = obj.sub(sub) else {
            self.cx.error(
                loc,
                format!("{kind} {n} maps 0x{index:04X} sub {sub}, but \"{}\" has no sub-index {sub}", obj.name),
            );
            return Mapped::Skipped;
        };
        let Some(bits) = e.data_type.bits() else {
            self.cx.error(
                loc,
                format!(
                    "{kind} {n} maps 0x{index:04X} sub {sub} \"{}\", a {}; only fixed-size entries fit in a PDO",
                    e.name,
                    e.data_type.name()
                ),
            );
            return Mapped::Skipped;
        };
        Mapped::Entry(PdoMappingEntry { index: Index(index), sub: SubIndex(sub), bits: bits as u8 })
    }
}

enum Mapped {
    /// The entry to map.
    Entry(PdoMappingEntry),
    /// Left out: it had an error, or it names an object that had one.
    Skipped,
}
