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

/// The number a PDO or SDO parameter object carries by its role (1-based), for naming objects
/// that share one name.
fn role_number(obj: &Object) -> Option<u32> {
    use eds::model::Role;
    match obj.index.role() {
        Role::SdoServer(n) | Role::SdoClient(n) => Some(n as u32 + 1),
        Role::RpdoCommunication(n) | Role::RpdoMapping(n) | Role::TpdoCommunication(n) | Role::TpdoMapping(n) => {
            Some(n as u32 + 1)
        }
        _ => None,
    }
}

fn holds_values(obj: &Object) -> bool {
    !matches!(obj.object_type, ObjectType::DefType | ObjectType::DefStruct | ObjectType::Null)
}

/// The words of every value-holding object's name. Objects that share one name (sixteen
/// "RPDO communication parameter"s, a vendor's repeated "Trace config") all take a number at
/// the end: their PDO/SDO number when each has a distinct one, else their place among the
/// objects of that name, by index. A name depends only on its own object and the objects it
/// really collides with.
fn object_words(model: &Model) -> std::collections::BTreeMap<u16, Vec<String>> {
    use std::collections::BTreeMap;
    let mut words: BTreeMap<u16, Vec<String>> = BTreeMap::new();
    let mut groups: BTreeMap<Vec<String>, Vec<&Object>> = BTreeMap::new();
    for obj in model.objects.values().filter(|o| holds_values(o)) {
        let mut w = ident::words(&obj.name);
        if w.is_empty() {
            w = vec!["object".to_owned(), format!("{:04x}", obj.index.0)];
        }
        groups.entry(w.clone()).or_default().push(obj);
        words.insert(obj.index.0, w);
    }
    for members in groups.values().filter(|m| m.len() > 1) {
        let numbers: Vec<Option<u32>> = members.iter().map(|o| role_number(o)).collect();
        let distinct = numbers.iter().all(Option::is_some)
            && numbers.iter().collect::<std::collections::BTreeSet<_>>().len() == numbers.len();
        for (pos, obj) in members.iter().enumerate() {
            let n = if distinct { numbers[pos].unwrap_or(0) } else { pos as u32 + 1 };
            if let Some(w) = words.get_mut(&obj.index.0) {
                w.push(n.to_string());
            }
        }
    }
    words
}

/// The sub-entry's own words: its name without the words it repeats from its object: the
/// object's whole name in front (`Error history` / `Error history 3` → `3`; `Remote TPDO
/// mapping parameter` / `Remote TPDO mapping parameter2` → `2`), or the object's last words
/// (`Receive file` / `File name` → `name`; `Variable Int32` / `int32` → nothing).
fn strip_object_words(sub: &[String], obj: &[String]) -> Vec<String> {
    if obj.is_empty() || sub.is_empty() {
        return sub.to_vec();
    }
    // The whole object name, its last word glued to a number.
    if sub.len() >= obj.len() && sub[..obj.len() - 1] == obj[..obj.len() - 1] {
        let (o, w) = (&obj[obj.len() - 1], &sub[obj.len() - 1]);
        if let Some(d) = w.strip_prefix(o.as_str())
            && !d.is_empty()
            && d.bytes().all(|b| b.is_ascii_digit())
        {
            let mut rest = vec![d.to_owned()];
            rest.extend_from_slice(&sub[obj.len()..]);
            return rest;
        }
    }
    // The longest run of the object's last words that the sub-entry's name starts with.
    let k = (1..=obj.len().min(sub.len())).rev().find(|&k| obj[obj.len() - k..] == sub[..k]).unwrap_or(0);
    sub[k..].to_vec()
}

/// The sub-entry's own words: its name without every word its object's name already says, in
/// any position, singular and plural alike (`Software position limit` / `Max software position
/// limit` → `max`; `Programmable limit switch widths` / `Limit switch 3 width` → `3`; `Wake and
/// shake parameters` / `Wake and shake maximum current` → `maximum current`). A word glued to a
/// number (`parameter2`) counts as the word and the number. A linking word (`and`, `of`) goes
/// only beside a word that went, and never stays at either end; a number goes only where the
/// object says it beside the same word (`Touch probe 1 config` / `Touch probe 1 config mode`),
/// else it stays in its place. Words in `keep` stay (they tell siblings apart).
fn drop_object_words(sub: &[String], obj: &[String], keep: &std::collections::BTreeSet<String>) -> Vec<String> {
    let said: std::collections::BTreeSet<String> = obj.iter().map(|w| ident::singular(w)).collect();
    let mut split = Vec::with_capacity(sub.len());
    for w in sub {
        let glued = obj.iter().filter(|o| !o.bytes().all(|b| b.is_ascii_digit())).find_map(|o| {
            w.strip_prefix(o.as_str()).filter(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
        });
        match glued {
            Some(d) => {
                split.push(w[..w.len() - d.len()].to_owned());
                split.push(d.to_owned());
            }
            None => split.push(w.clone()),
        }
    }
    let linking = |w: &str| ident::LINKING.contains(&w);
    let number = |w: &str| w.bytes().all(|b| b.is_ascii_digit());
    let objs: Vec<String> = obj.iter().map(|w| ident::singular(w)).collect();
    let subs: Vec<String> = split.iter().map(|w| ident::singular(w)).collect();
    // The number at `i` beside the same word as one the object says.
    let same_place = |i: usize| {
        objs.iter().enumerate().any(|(j, o)| {
            *o == subs[i]
                && ((i > 0 && j > 0 && subs[i - 1] == objs[j - 1])
                    || (i + 1 < subs.len() && j + 1 < objs.len() && subs[i + 1] == objs[j + 1]))
        })
    };
    let mut gone: Vec<bool> = (0..split.len())
        .map(|i| {
            let w = &split[i];
            !linking(w) && !keep.contains(&subs[i]) && said.contains(&subs[i]) && (!number(w) || same_place(i))
        })
        .collect();
    for i in 0..split.len() {
        if linking(&split[i])
            && said.contains(&split[i])
            && ((i > 0 && gone[i - 1]) || gone.get(i + 1).copied().unwrap_or(false))
        {
            gone[i] = true;
        }
    }
    // A word a kept linking word ties to a kept word stays: `client to server`, `number of
    // errors` keep their sense.
    for i in 1..split.len().saturating_sub(1) {
        if linking(&split[i]) && !gone[i] {
            let (l, r) = (i - 1, i + 1);
            if gone[l] && !gone[r] && !linking(&split[r]) {
                gone[l] = false;
            } else if gone[r] && !gone[l] && !linking(&split[l]) {
                gone[r] = false;
            }
        }
    }
    // Linking words left at an end beside a dropped word go too (`COB-ID used by RPDO` →
    // `cob id`); one that starts or ends the name itself stays (`Std in`, `Analog input used`).
    let mut first = 0;
    while first < split.len()
        && (gone[first] || (linking(&split[first]) && first > 0 && first + 1 < split.len() && gone[first - 1]))
    {
        gone[first] = true;
        first += 1;
    }
    let mut last = split.len();
    while last > first && (gone[last - 1] || (linking(&split[last - 1]) && last < split.len() && gone[last])) {
        gone[last - 1] = true;
        last -= 1;
    }
    let mut rest: Vec<String> = split.into_iter().zip(gone).filter(|(_, g)| !g).map(|(w, _)| w).collect();
    // Words a dropped one stood between (`PERSIST_APP_AUTO auto-store` → `auto auto`) are one.
    rest.dedup_by(|a, b| a == b && !number(a));
    rest
}

/// The words of each sub-entry's name within its object, as `(name, fuller name)`: the
/// object's words, then the sub-entry's own.
///
/// The own words are the sub-entry's name without the words its object already says
/// ([`drop_object_words`]). Siblings whose own words are alike keep the object's words that
/// tell them apart. When the own words are empty, an entry whose name carries a number or is
/// shared by a sibling takes its sub-index (`consumer_heartbeat_time_1`), another its name
/// without just the object's leading words ([`strip_object_words`]: `Feed constant` / `Feed`
/// → `feed`) if that is unique; own
/// words still shared with a sibling take the fuller name if unique, else the sub-index as a
/// plain number. The fuller name is
/// the one without just the object's leading words, tried before the index suffix when the
/// name is taken by another object's accessor.
fn sub_words(obj: &Object, obj_words: &[String]) -> std::collections::BTreeMap<u8, (Vec<String>, Vec<String>)> {
    use std::collections::{BTreeMap, BTreeSet};
    let plain = ident::words(&obj.name);
    let names: BTreeMap<u8, Vec<String>> = obj.subs.values().map(|e| (e.sub.0, ident::words(&e.name))).collect();
    let fuller: BTreeMap<u8, Vec<String>> = names.iter().map(|(s, w)| (*s, strip_object_words(w, &plain))).collect();
    let none = BTreeSet::new();
    let mut own: BTreeMap<u8, Vec<String>> =
        names.iter().map(|(s, w)| (*s, drop_object_words(w, &plain, &none))).collect();
    // Siblings whose own words are empty or alike keep the object's words that tell them apart
    // (`Vl velocity min max amount` / `Vl velocity min amount`, `… max amount` → `min`, `max`).
    // (Counted once per map: an array has up to 255 entries, and comparing each with each
    // was most of planning a large DCF in a debug build script.)
    fn counts(words: impl IntoIterator<Item = Vec<String>>) -> BTreeMap<Vec<String>, usize> {
        let mut c = BTreeMap::new();
        for w in words {
            *c.entry(w).or_insert(0) += 1;
        }
        c
    }
    let count = counts(own.values().cloned());
    let groups: BTreeSet<Vec<String>> = own.values().filter(|w| w.is_empty() || count[*w] > 1).cloned().collect();
    for g in groups {
        let members: Vec<u8> = own.iter().filter(|(_, w)| **w == g).map(|(s, _)| *s).collect();
        let sets: Vec<BTreeSet<String>> =
            members.iter().map(|s| names[s].iter().map(|w| ident::singular(w)).collect()).collect();
        let apart: BTreeSet<String> =
            sets.iter().flatten().filter(|w| !sets.iter().all(|set| set.contains(*w))).cloned().collect();
        if apart.is_empty() {
            continue;
        }
        let redone: Vec<Vec<String>> = members.iter().map(|s| drop_object_words(&names[s], &plain, &apart)).collect();
        let count = counts(redone.iter().cloned());
        if redone.iter().all(|w| !w.is_empty() && count[w] == 1) {
            for (s, w) in members.iter().zip(redone) {
                own.insert(*s, w);
            }
        }
    }
    let (own_count, fuller_count) = (counts(own.values().cloned()), counts(fuller.values().cloned()));
    let unique = |count: &BTreeMap<Vec<String>, usize>, w: &Vec<String>| count.get(w) == Some(&1);
    let mut chosen: BTreeMap<u8, Vec<String>> = BTreeMap::new();
    for (sub, w) in &own {
        let f = &fuller[sub];
        let number = vec![sub.to_string()];
        // Another entry's own words are `f`.
        let others_own = own_count.get(f).copied().unwrap_or(0) - usize::from(w == f);
        let pick = if !w.is_empty() && unique(&own_count, w) {
            w.clone()
        } else if w.is_empty()
            && (names[sub].iter().any(|x| x.bytes().any(|b| b.is_ascii_digit())) || !unique(&fuller_count, f))
            && !own_count.contains_key(&number)
        {
            number
        } else if !f.is_empty() && unique(&fuller_count, f) && others_own == 0 {
            f.clone()
        } else {
            let mut n = w.clone();
            n.push(sub.to_string());
            n
        };
        chosen.insert(*sub, pick);
    }
    // A fuller name that equals a sibling's own: both take their number.
    let dup: BTreeSet<Vec<String>> =
        counts(chosen.values().cloned()).into_iter().filter(|(_, n)| *n > 1).map(|(w, _)| w).collect();
    chosen
        .into_iter()
        .map(|(sub, mut w)| {
            if dup.contains(&w) {
                w.push(sub.to_string());
            }
            let mut name = obj_words.to_vec();
            name.extend(w);
            let mut full = obj_words.to_vec();
            full.extend(fuller[&sub].iter().cloned());
            if full == name || fuller[&sub].is_empty() {
                full = name.clone();
            }
            (sub, (name, full))
        })
        .collect()
}

/// `snake_case` of words, at most [`ident::MAX_LEN`] characters.
fn snake_name(words: Vec<String>, reserve: usize) -> String {
    let w = ident::shorten(words, ident::MAX_LEN - 1 - reserve);
    ident::snake(&w.join(" ")).unwrap_or_else(|| "entry".to_owned())
}

/// The name each value-holding object's entries start with (`snake_case`, its group number
/// included), by index.
pub(crate) fn object_names(model: &Model) -> Vec<(u16, String)> {
    object_words(model).into_iter().map(|(i, w)| (i, snake_name(w, 0))).collect()
}

pub(crate) fn build<'m>(model: &'m Model, options: &Options, sink: &mut Sink) -> Plan<'m> {
    let mut entries = Vec::new();
    let mut objects = Vec::new();
    let mut methods = Names::with_reserved(RESERVED_METHODS);
    for r in RESERVED_METHODS {
        methods.insert(format!("set_{r}"));
    }
    let mut consts = Names::default();
    let words = object_words(model);

    for obj in model.objects.values() {
        if !holds_values(obj) {
            sink.at_object(
                Severity::Note,
                diag::NO_VALUE_OBJECT,
                obj,
                format!("{:?} objects hold no value; not part of the generated dictionary", obj.object_type),
            );
            continue;
        }
        let obj_words = words.get(&obj.index.0).cloned().unwrap_or_default();
        let subs = if obj.object_type.has_subs() { sub_words(obj, &obj_words) } else { Default::default() };
        let mut kept_any = false;
        let mut renamed = Vec::new();
        for e in obj.subs.values() {
            let (w, fuller) = subs.get(&e.sub.0).cloned().unwrap_or_else(|| (obj_words.clone(), obj_words.clone()));
            let Some((p, rename)) = plan_entry(obj, e, w, fuller, options, sink, &mut methods) else { continue };
            renamed.extend(rename);
            entries.push(p);
            kept_any = true;
        }
        // One warning per object, however many of its names were taken.
        if let Some((first, first_field)) = renamed.first() {
            let more = match renamed.len() {
                1 => String::new(),
                n => format!(" (and {} more of its entries)", n - 1),
            };
            sink.at_object(
                Severity::Warning,
                diag::NAME_COLLISION,
                obj,
                format!(
                    "the name `{first}` is already taken (by another object's accessor or setter, or by a \
                     method of `Dictionary`); this entry's accessors are `{first_field}` / \
                     `set_{first_field}`{more}"
                ),
            );
        }
        if kept_any {
            let base = snake_name(obj_words.clone(), 0).trim_end_matches('_').to_ascii_uppercase();
            let base = ident::screaming(&base).unwrap_or(base);
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

/// Plans one entry named by `words` (or `fuller` when that is taken); also gives `(wanted,
/// given)` when the wanted name was taken.
fn plan_entry<'m>(
    obj: &'m Object,
    e: &'m Entry,
    words: Vec<String>,
    fuller: Vec<String>,
    options: &Options,
    sink: &mut Sink,
    methods: &mut Names,
) -> Option<(PEntry<'m>, Option<(String, String)>)> {
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

    // Name: the planned words; when taken, the fuller words; the index (and sub-index) as a
    // last resort.
    let base = snake_name(words.clone(), 0);
    let fuller = snake_name(fuller, 0);
    let fallback = if obj.object_type.has_subs() {
        let mut w = ident::shorten(words.clone(), ident::MAX_LEN - 1 - 9);
        w.push(format!("{:04x}", obj.index.0));
        w.push(e.sub.0.to_string());
        w.join("_")
    } else {
        let mut w = ident::shorten(words.clone(), ident::MAX_LEN - 1 - 5);
        w.push(format!("{:04x}", obj.index.0));
        w.join("_")
    };
    let fallback = ident::snake(&fallback).unwrap_or(fallback);
    let free = |m: &Names, c: &str| m.is_free(c) && m.is_free(&format!("set_{c}"));
    // A sub-entry whose name is taken first takes its sub-index (`…_used_1`): the fuller name
    // would say its object's words again.
    let numbered = if obj.object_type.has_subs() && !base.ends_with(&format!("_{}", e.sub.0)) {
        let mut w = words.clone();
        w.push(e.sub.0.to_string());
        snake_name(w, 0)
    } else {
        base.clone()
    };
    let field = match [&base, &numbered, &fuller, &fallback].into_iter().find(|c| free(methods, c)) {
        Some(c) => c.clone(),
        None => (2u32..).map(|n| format!("{fallback}_{n}")).find(|c| free(methods, c)).unwrap_or(fallback.clone()),
    };
    let rename = (field != base).then(|| (base.clone(), field.clone()));
    methods.insert(field.clone());
    methods.insert(format!("set_{field}"));

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
    // A limit outside the type is clipped to it (the setter compares in the storage type, so an
    // unclipped one would not compile); a limit at the type's edge says nothing and is dropped,
    // so the table stays minimal.
    let range = type_range(dt);
    if let Some((lo, hi)) = range {
        for (which, limit) in [("LowLimit", &mut low), ("HighLimit", &mut high)] {
            let Some(l) = *limit else { continue };
            if !(lo..=hi).contains(&l) {
                let clipped = l.clamp(lo, hi);
                sink.at_entry(
                    sink.deviation(),
                    diag::LIMIT_CLIPPED,
                    obj,
                    e,
                    format!("{which} {l} lies outside the {} range {lo}..={hi}; clipped to {clipped}", dt.name()),
                );
                *limit = Some(clipped);
            }
        }
        if low.is_some_and(|l| l <= lo) {
            low = None;
        }
        if high.is_some_and(|h| h >= hi) {
            high = None;
        }
    }
    // A NaN limit says nothing (and `v < NaN` is a lint error); a REAL32 limit beyond `f32` is
    // clipped to it.
    if ty.is_real() {
        let max = if dt == DataType::Real32 { f32::MAX as f64 } else { f64::MAX };
        for (which, limit) in [("LowLimit", &mut real_low), ("HighLimit", &mut real_high)] {
            let Some(l) = *limit else { continue };
            if l.is_nan() {
                sink.at_entry(Severity::Warning, diag::LIMIT_IGNORED, obj, e, format!("{which} is NaN; ignored"));
                *limit = None;
            } else if l.is_finite() && !(-max..=max).contains(&l) {
                let clipped = l.clamp(-max, max);
                sink.at_entry(
                    sink.deviation(),
                    diag::LIMIT_CLIPPED,
                    obj,
                    e,
                    format!("{which} {l} lies outside the {} range; clipped to {clipped}", dt.name()),
                );
                *limit = Some(clipped);
            }
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

    Some((
        PEntry {
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
        },
        rename,
    ))
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
    let sev = sink.deviation();
    let mut bad = |msg: String| {
        sink.at_entry(sev, diag::BAD_DEFAULT, obj, e, msg);
        sink.hint("the generated entry starts at zero (empty)");
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
        DataType::Real32 | DataType::Real64 => {
            let f = match v {
                Value::Real(f) => *f,
                Value::Int { value, .. } => *value as f64,
                _ => return bad(format!("the default of a {} entry must be a number", dt.name())),
            };
            if dt == DataType::Real32 && f.is_finite() && (f as f32).is_infinite() {
                bad(format!("default {f} is outside the REAL32 range"))
            } else {
                (Def::Real(f), 0)
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn w(s: &str) -> Vec<String> {
        ident::words(s)
    }

    fn own(obj: &str, sub: &str) -> String {
        drop_object_words(&w(sub), &w(obj), &Default::default()).join("_")
    }

    #[test]
    fn sub_entries_drop_the_words_their_object_says() {
        assert_eq!(own("Software position limit", "Max software position limit"), "max");
        assert_eq!(own("Restore default parameters", "Restore all default parameters"), "all");
        assert_eq!(own("Touch probe source", "Touch probe 1 source"), "1");
        assert_eq!(own("Programmable limit switch widths", "Limit switch 3 width"), "3");
        assert_eq!(own("Wake and shake parameters", "Wake and shake maximum current"), "maximum_current");
        assert_eq!(own("Remote TPDO mapping parameter", "Remote TPDO mapping parameter2"), "2");
        // Numbers the object says in the same place go; others stay.
        assert_eq!(own("Touch probe 1 config", "Touch probe 1 config mode"), "mode");
        assert_eq!(own("Analog input 8 bit", "Analog input 3"), "3");
        // Linking words: dropped with the words they tied, kept where they tie kept words.
        assert_eq!(own("RPDO communication parameter", "COB-ID used by RPDO"), "cob_id");
        assert_eq!(own("Server SDO parameter", "COB-ID client to server"), "cob_id_client_to_server");
        assert_eq!(own("Pre-defined error field", "Number of errors"), "number_of_errors");
        assert_eq!(own("OS prompt", "Std in"), "std_in");
        assert_eq!(own("Analog input feedback", "Analog input used"), "used");
        assert_eq!(own("Error history", "Error history"), "");
    }

    fn model(text: &str) -> Model {
        let parsed = eds::parse("t.eds", text.as_bytes(), &eds::Options::lenient());
        assert!(!parsed.has_errors(), "{:#?}", parsed.diagnostics);
        parsed.model
    }

    fn record(name: &str, object_type: u8, subs: &[&str]) -> String {
        let mut t = format!(
            "[FileInfo]\nFileName=t.eds\n[DeviceInfo]\nVendorName=x\n[MandatoryObjects]\nSupportedObjects=1\n1=0x1000\n\
             [1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\n\
             [ManufacturerObjects]\nSupportedObjects=1\n1=0x2000\n[2000]\nParameterName={name}\nObjectType=0x{object_type:X}\nSubNumber={}\n\
             [2000sub0]\nParameterName=Number of entries\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue={}\n",
            subs.len() + 1,
            subs.len()
        );
        for (i, s) in subs.iter().enumerate() {
            t.push_str(&format!(
                "[2000sub{}]\nParameterName={s}\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\n",
                i + 1
            ));
        }
        t
    }

    fn names(text: &str) -> Vec<String> {
        let m = model(text);
        crate::accessor_names(&m).into_iter().filter(|(i, s, _)| *i == 0x2000 && *s > 0).map(|(_, _, n)| n).collect()
    }

    #[test]
    fn siblings_stay_apart_and_empty_names_fall_back() {
        // Siblings left alike keep the object's words that tell them apart.
        assert_eq!(
            names(&record("Vl velocity min max amount", 0x9, &["Vl velocity min amount", "Vl velocity max amount"])),
            ["vl_velocity_min_max_amount_min", "vl_velocity_min_max_amount_max"]
        );
        // Elements named alike take their sub-index.
        assert_eq!(
            names(&record("Consumer heartbeat time", 0x8, &["Consumer heartbeat time", "Consumer heartbeat time"])),
            ["consumer_heartbeat_time_1", "consumer_heartbeat_time_2"]
        );
        // A member left with nothing keeps its fuller name when that is unique.
        assert_eq!(
            names(&record("Feed constant", 0x8, &["Feed", "Shaft revolutions"])),
            ["feed_constant_feed", "feed_constant_shaft_revolutions"]
        );
        // Own words shared by siblings that nothing else tells apart: the sub-index.
        assert_eq!(names(&record("Motor", 0x9, &["Reserved", "Reserved"])), ["motor_reserved_1", "motor_reserved_2"]);
    }
}
