//! From the model to a flat, checked plan of what to generate: one [`PEntry`] per stored
//! `(index, sub-index)`, with its Rust type, name, default and limits resolved. The emitters only
//! read the plan, so every decision (and every diagnostic) about an entry is made here, once.

use eds::diag::Severity;
use eds::model::{DataType, Entry, Model, Object, ObjectType, Radix, Value};

use crate::Options;
use crate::diag::{self, Sink};
use crate::ident::{self, Names};

/// How a value is stored in the generated struct.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ty {
    Bool,
    U8,
    U16,
    U32,
    U64,
    I8,
    I16,
    I32,
    I64,
    F32,
    F64,
    /// A fixed-capacity byte buffer (strings, OCTET_STRING, DOMAIN).
    Bytes(usize),
}

impl Ty {
    /// The storage type for a CiA data type (`None`: not storable).
    pub(crate) fn of(dt: DataType, capacity: usize) -> Option<Ty> {
        use DataType as D;
        Some(match dt {
            D::Boolean => Ty::Bool,
            D::Unsigned8 => Ty::U8,
            D::Unsigned16 => Ty::U16,
            D::Unsigned24 | D::Unsigned32 => Ty::U32,
            D::Unsigned40 | D::Unsigned48 | D::Unsigned56 | D::Unsigned64 | D::TimeOfDay | D::TimeDifference => Ty::U64,
            D::Integer8 => Ty::I8,
            D::Integer16 => Ty::I16,
            D::Integer24 | D::Integer32 => Ty::I32,
            D::Integer40 | D::Integer48 | D::Integer56 | D::Integer64 => Ty::I64,
            D::Real32 => Ty::F32,
            D::Real64 => Ty::F64,
            D::VisibleString | D::OctetString | D::UnicodeString | D::Domain => Ty::Bytes(capacity),
            D::Other(_) => return None,
        })
    }

    /// Bits of the storage type (0 for byte buffers).
    pub(crate) fn storage_bits(self) -> u32 {
        match self {
            Ty::Bool => 1,
            Ty::U8 | Ty::I8 => 8,
            Ty::U16 | Ty::I16 => 16,
            Ty::U32 | Ty::I32 | Ty::F32 => 32,
            Ty::U64 | Ty::I64 | Ty::F64 => 64,
            Ty::Bytes(_) => 0,
        }
    }

    pub(crate) fn is_int(self) -> bool {
        matches!(self, Ty::U8 | Ty::U16 | Ty::U32 | Ty::U64 | Ty::I8 | Ty::I16 | Ty::I32 | Ty::I64)
    }

    pub(crate) fn is_real(self) -> bool {
        matches!(self, Ty::F32 | Ty::F64)
    }
}

/// The value range of a CiA type, with TIME_OF_DAY/TIME_DIFFERENCE as 48-bit unsigned.
pub(crate) fn type_range(dt: DataType) -> Option<(i128, i128)> {
    match dt {
        DataType::TimeOfDay | DataType::TimeDifference => Some((0, (1i128 << 48) - 1)),
        _ => dt.int_range(),
    }
}

/// A default value, resolved to the entry's type.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Def {
    None,
    /// An integer, and whether the file wrote it in hex.
    Int(i128, bool),
    /// `$NODEID + offset`, and whether the file wrote the offset in hex.
    NodeId(i128, bool),
    Real(f64),
    Bytes(Vec<u8>),
}

/// One stored entry.
#[derive(Debug)]
pub(crate) struct PEntry<'m> {
    pub obj: &'m Object,
    pub entry: &'m Entry,
    pub index: u16,
    pub sub: u8,
    pub dt: DataType,
    pub ty: Ty,
    /// `EntryInfo::bits`.
    pub bits: u32,
    /// Field, getter and (with `set_`) setter name.
    pub field: String,
    pub default: Def,
    /// Bus limits (`EntryInfo::low/high`).
    pub low: Option<i128>,
    pub high: Option<i128>,
    /// Limits the typed setter checks: the bus limits, narrowed to the CiA type's range when the
    /// storage type is wider (24/40/48/56-bit types).
    pub set_low: Option<i128>,
    pub set_high: Option<i128>,
    /// REAL limits.
    pub real_low: Option<f64>,
    pub real_high: Option<f64>,
    pub description: Option<String>,
}

/// One object, for the index constants.
#[derive(Debug)]
pub(crate) struct PObject<'m> {
    pub obj: &'m Object,
    pub konst: String,
}

/// The whole plan.
#[derive(Debug)]
pub(crate) struct Plan<'m> {
    pub entries: Vec<PEntry<'m>>,
    pub objects: Vec<PObject<'m>>,
}

/// Names the generated `Dictionary` type already uses; entries never take them (nor `set_` +
/// them).
pub(crate) const RESERVED_METHODS: &[&str] = &[
    "new",
    "zeroed",
    "position",
    "info",
    "entries",
    "read",
    "write",
    "restore_defaults",
    "bus_read",
    "bus_write",
    "slot",
    "slot_mut",
    "check_rpdo_mapping",
    "check_tpdo_mapping",
    "clone",
    "fmt",
    "eq",
    "ne",
];

/// The description of an entry (`Description=` key, kept by the reader among the extra keys).
fn description(extra: &[(String, String)]) -> Option<String> {
    extra
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case("Description"))
        .map(|(_, v)| v.trim().to_owned())
        .filter(|s| !s.is_empty())
}

/// The value an entry starts with: a DCF's `ParameterValue`, else the EDS `DefaultValue`.
pub(crate) fn effective_value(e: &Entry) -> Option<&Value> {
    e.parameter_value().or(e.default.as_ref())
}

pub(crate) fn build<'m>(model: &'m Model, options: &Options, sink: &mut Sink) -> Plan<'m> {
    let mut entries = Vec::new();
    let mut objects = Vec::new();
    let mut methods = Names::with_reserved(RESERVED_METHODS);
    for r in RESERVED_METHODS {
        methods.insert(format!("set_{r}"));
    }
    let mut consts = Names::default();

    for obj in model.objects.values() {
        if matches!(obj.object_type, ObjectType::DefType | ObjectType::DefStruct | ObjectType::Null) {
            sink.at_object(
                Severity::Note,
                diag::NO_VALUE_OBJECT,
                obj,
                format!("{:?} objects hold no value; not part of the generated dictionary", obj.object_type),
            );
            continue;
        }
        let obj_base = ident::snake(&obj.name).unwrap_or_else(|| format!("x{:04x}", obj.index.0));
        let mut kept_any = false;
        for e in obj.subs.values() {
            let Some(p) = plan_entry(obj, e, &obj_base, options, sink, &mut methods) else { continue };
            entries.push(p);
            kept_any = true;
        }
        if kept_any {
            let base = ident::screaming(&obj.name).unwrap_or_else(|| format!("X{:04X}", obj.index.0));
            let (konst, renamed) = consts.claim(&base, &[format!("{base}_{:04X}", obj.index.0)]);
            if renamed {
                sink.at_object(
                    Severity::Warning,
                    diag::NAME_COLLISION,
                    obj,
                    format!("the index constant `{base}` is already taken; this object's is `{konst}`"),
                );
            }
            objects.push(PObject { obj, konst });
        }
    }
    Plan { entries, objects }
}

fn plan_entry<'m>(
    obj: &'m Object,
    e: &'m Entry,
    obj_base: &str,
    options: &Options,
    sink: &mut Sink,
    methods: &mut Names,
) -> Option<PEntry<'m>> {
    let dt = e.data_type;
    if let DataType::Other(code) = dt {
        sink.at_entry(
            Severity::Warning,
            diag::UNSUPPORTED_TYPE,
            obj,
            e,
            format!(
                "data type 0x{code:04X} is not a basic CiA 301 type; the entry is left out of the generated dictionary"
            ),
        );
        return None;
    }

    // Name.
    let (base, fallback) = if obj.object_type.has_subs() {
        let sub = ident::snake(&e.name).unwrap_or_else(|| format!("sub{}", e.sub.0));
        let base = format!("{obj_base}_{}", sub.trim_end_matches('_'));
        let fb = format!("{base}_{:04x}_{}", obj.index.0, e.sub.0);
        (base, fb)
    } else {
        (obj_base.to_owned(), format!("{}_{:04x}", obj_base.trim_end_matches('_'), obj.index.0))
    };
    let free = |m: &Names, c: &str| m.is_free(c) && m.is_free(&format!("set_{c}"));
    let field = match [&base, &fallback].into_iter().find(|c| free(methods, c)) {
        Some(c) => c.clone(),
        None => (2u32..).map(|n| format!("{fallback}_{n}")).find(|c| free(methods, c)).unwrap_or(fallback.clone()),
    };
    let renamed = field != base;
    methods.insert(field.clone());
    methods.insert(format!("set_{field}"));
    if renamed {
        sink.at_entry(
            Severity::Warning,
            diag::NAME_COLLISION,
            obj,
            e,
            format!("the name `{base}` is already taken by another entry; this entry's accessors are `{field}` / `set_{field}`"),
        );
    }

    // Default.
    let value = effective_value(e);
    let (default, text_len) = resolve_default(obj, e, value, sink);
    let capacity = text_len.max(options.min_capacity);
    let ty = Ty::of(dt, capacity)?;
    let bits = match dt.bits() {
        Some(b) => b,
        None => (capacity as u32).saturating_mul(8),
    };

    // Limits.
    let mut low = None;
    let mut high = None;
    let mut real_low = None;
    let mut real_high = None;
    for (which, v) in [("LowLimit", e.low_limit()), ("HighLimit", e.high_limit())] {
        let Some(v) = v else { continue };
        let is_low = which == "LowLimit";
        if ty.is_real() {
            let f = match v {
                Value::Real(f) => Some(*f),
                Value::Int { value, .. } => Some(*value as f64),
                _ => None,
            };
            match f {
                Some(f) if is_low => real_low = Some(f),
                Some(f) => real_high = Some(f),
                None => sink.at_entry(
                    Severity::Warning,
                    diag::LIMIT_IGNORED,
                    obj,
                    e,
                    format!("{which} is not a number; ignored"),
                ),
            }
        } else if ty.is_int() {
            match v {
                Value::Int { value, .. } => {
                    if is_low {
                        low = Some(*value)
                    } else {
                        high = Some(*value)
                    }
                }
                Value::NodeIdPlus { .. } => sink.at_entry(
                    Severity::Warning,
                    diag::LIMIT_IGNORED,
                    obj,
                    e,
                    format!("{which} depends on $NODEID; the generated dictionary does not enforce it"),
                ),
                _ => sink.at_entry(
                    Severity::Warning,
                    diag::LIMIT_IGNORED,
                    obj,
                    e,
                    format!("{which} is not an integer; ignored"),
                ),
            }
        }
    }
    // Limits wider than the type say nothing: drop them so the table stays minimal.
    let range = type_range(dt);
    if let Some((lo, hi)) = range {
        if low.is_some_and(|l| l <= lo) {
            low = None;
        }
        if high.is_some_and(|h| h >= hi) {
            high = None;
        }
    }
    let (mut set_low, mut set_high) = (low, high);
    if let Some((lo, hi)) = range
        && ty.is_int()
    {
        let (slo, shi) = storage_range(ty);
        if lo > slo && set_low.is_none() {
            set_low = Some(lo);
        }
        if hi < shi && set_high.is_none() {
            set_high = Some(hi);
        }
    }

    Some(PEntry {
        obj,
        entry: e,
        index: obj.index.0,
        sub: e.sub.0,
        dt,
        ty,
        bits,
        field,
        default,
        low,
        high,
        set_low,
        set_high,
        real_low,
        real_high,
        description: description(e.extra())
            .or_else(|| if obj.object_type.has_subs() { None } else { description(&obj.extra) }),
    })
}

pub(crate) fn storage_range(ty: Ty) -> (i128, i128) {
    match ty {
        Ty::U8 => (0, u8::MAX as i128),
        Ty::U16 => (0, u16::MAX as i128),
        Ty::U32 => (0, u32::MAX as i128),
        Ty::U64 => (0, u64::MAX as i128),
        Ty::I8 => (i8::MIN as i128, i8::MAX as i128),
        Ty::I16 => (i16::MIN as i128, i16::MAX as i128),
        Ty::I32 => (i32::MIN as i128, i32::MAX as i128),
        Ty::I64 => (i64::MIN as i128, i64::MAX as i128),
        Ty::Bool => (0, 1),
        _ => (0, 0),
    }
}

/// Resolves a default to the entry's type; returns it and the byte length of a string default.
fn resolve_default(obj: &Object, e: &Entry, value: Option<&Value>, sink: &mut Sink) -> (Def, usize) {
    let dt = e.data_type;
    let Some(v) = value else { return (Def::None, 0) };
    let mut bad = |msg: String| {
        sink.at_entry(Severity::Error, diag::BAD_DEFAULT, obj, e, msg);
        (Def::None, 0)
    };
    match dt {
        DataType::VisibleString => match v {
            Value::Text(s) => (Def::Bytes(s.as_bytes().to_vec()), s.len()),
            Value::Bytes(b) => (Def::Bytes(b.clone()), b.len()),
            _ => bad(format!("the default of a {} entry must be text", dt.name())),
        },
        DataType::UnicodeString => match v {
            Value::Text(s) => {
                let b: Vec<u8> = s.encode_utf16().flat_map(u16::to_le_bytes).collect();
                let n = b.len();
                (Def::Bytes(b), n)
            }
            Value::Bytes(b) => (Def::Bytes(b.clone()), b.len()),
            _ => bad(format!("the default of a {} entry must be text", dt.name())),
        },
        DataType::OctetString | DataType::Domain => match v {
            Value::Bytes(b) => (Def::Bytes(b.clone()), b.len()),
            // A DOMAIN default that is a file name or a number: the reader already said so.
            Value::Text(_) if dt == DataType::Domain => (Def::None, 0),
            _ => bad(format!("the default of a {} entry must be hex bytes", dt.name())),
        },
        DataType::Real32 | DataType::Real64 => match v {
            Value::Real(f) => (Def::Real(*f), 0),
            Value::Int { value, .. } => (Def::Real(*value as f64), 0),
            _ => bad(format!("the default of a {} entry must be a number", dt.name())),
        },
        _ => {
            let Some((lo, hi)) = type_range(dt) else { return (Def::None, 0) };
            match v {
                Value::Int { value, radix } => {
                    if *value < lo || *value > hi {
                        bad(format!("default {value} is outside the {} range {lo}..={hi}", dt.name()))
                    } else {
                        (Def::Int(*value, *radix == Radix::Hex), 0)
                    }
                }
                Value::NodeIdPlus { offset, radix } => {
                    let (a, b) = (offset + 1, offset + 127);
                    if a < lo || b > hi {
                        bad(format!(
                            "default $NODEID{offset:+} leaves the {} range {lo}..={hi} for some node id in 1..=127",
                            dt.name()
                        ))
                    } else {
                        (Def::NodeId(*offset, *radix == Radix::Hex), 0)
                    }
                }
                _ => bad(format!("the default of a {} entry must be an integer", dt.name())),
            }
        }
    }
}
