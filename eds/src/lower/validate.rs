//! Pass 4: checks across the whole model.

use super::info::{Lists, category_slot, list_name};
use super::sections::{Kind, Sections};
use super::{Crumbs, Ctx, object_context, otype, sub_context};
use crate::codes;
use crate::model::{DataType, Entry, Index, Model, Object, ObjectType, PdoMappingEntry, Role, Value};
use crate::source::Span;

pub(crate) fn validate(secs: &Sections<'_>, lists: &Lists, model: &Model, cx: &mut Ctx<'_>) {
    object_lists(secs, lists, model, cx);
    mandatory(model, cx);
    pdos(secs, model, cx);
    // (Sub-index 0 of each object is checked by lowering: `sub_index_zero`.)
    cob_ids(secs, model, cx);
}

fn object_lists(secs: &Sections<'_>, lists: &Lists, model: &Model, cx: &mut Ctx<'_>) {
    if lists.present.iter().all(|p| !p) {
        let d = cx.emit(
            codes::E0407,
            None,
            "the file has none of [MandatoryObjects], [OptionalObjects], [ManufacturerObjects]",
        );
        d.hint =
            Some("list every object in the list it belongs to; this reader loaded the object sections it found".into());
        return;
    }
    // The objects no list names; and how many are named, so that the listed objects are
    // searched for those without a section only when some listed index has no object.
    let mut listed_objects = 0;
    for obj in model.objects.values() {
        if lists.contains(obj.index.0) {
            listed_objects += 1;
            continue;
        }
        let cat = obj.category;
        let d = cx.emit(
            codes::E0402,
            Some(obj.at.span),
            super::cat(["object 0x", &super::hex4(obj.index.0), " is not named in any object list"]),
        );
        d.hint = Some(
            if lists.present[category_slot(cat)] {
                super::cat(["add it to [", list_name(cat), "] and raise SupportedObjects"])
            } else {
                super::cat(["add a [", list_name(cat), "] section that lists it"])
            }
            .into(),
        );
        d.context = vec![object_context(obj.index.0, &obj.name)];
    }
    // The listed objects that have no section (few), in file order.
    if listed_objects < lists.listed.len() {
        let mut missing: Vec<(u16, crate::model::Category, Span)> = (lists.listed.iter().copied())
            .filter(|&(index, _, _)| {
                !model.objects.contains_key(&Index(index)) && secs.get(Kind::Object(index)).is_none()
            })
            .collect();
        missing.sort_by_key(|&(_, _, span)| span.start);
        for (index, cat, span) in missing {
            let hex = super::hex4(index);
            let d = cx.emit(
                codes::E0401,
                Some(span),
                super::cat(["[", list_name(cat), "] lists 0x", &hex, ", but there is no section [", &hex, "]"]),
            );
            d.hint = Some(super::cat(["add the section [", &hex, "] or remove the list entry"]).into());
        }
    }
}

fn mandatory(model: &Model, cx: &mut Ctx<'_>) {
    // (role, expected object types, data type of the value: of sub 0 for a VAR, sub 1 for 1018h)
    let checks: [(u16, &[ObjectType], u8, DataType); 3] = [
        (0x1000, &[ObjectType::Var], 0, DataType::Unsigned32),
        (0x1001, &[ObjectType::Var], 0, DataType::Unsigned8),
        (0x1018, &[ObjectType::Record], 1, DataType::Unsigned32),
    ];
    for (index, types, sub, dt) in checks {
        let what = match Index(index).role() {
            Role::DeviceType => "device type",
            Role::ErrorRegister => "error register",
            _ => "identity object",
        };
        let Some(obj) = model.object(index) else {
            let d = cx.emit(codes::E0501, None, format!("mandatory object 0x{index:04X} ({what}) is missing"));
            d.hint = Some("CiA 301 requires 0x1000, 0x1001 and 0x1018 in every device".into());
            continue;
        };
        // (Made only for a diagnostic: most files have all three objects as CiA 301 says.)
        let ctx = || vec![object_context(index, &obj.name)];
        if !types.contains(&obj.object_type) {
            let d = cx.emit(
                codes::E0507,
                Some(obj.at.span),
                format!(
                    "0x{index:04X} ({what}) is a {} but CiA 301 makes it a {}",
                    otype(obj.object_type),
                    otype(types[0])
                ),
            );
            d.context = ctx();
            continue;
        }
        if let Some(e) = obj.sub(sub)
            && e.data_type != dt
        {
            let mut c = ctx();
            if sub != 0 {
                c.push(sub_context(sub, &e.name));
            }
            let d = cx.emit(
                codes::E0507,
                Some(e.at.span),
                format!("{what} entry is {} but CiA 301 makes it {}", e.data_type.name(), dt.name()),
            );
            d.hint = Some(format!("write DataType=0x{:04X}", dt.code()).into());
            d.context = c;
        }
    }
}

/// The span of the text that gave an entry its value (ParameterValue before DefaultValue),
/// falling back to the entry's section.
fn value_span(secs: &Sections<'_>, obj: &Object, e: &Entry) -> Span {
    let find = |kind: Kind, keys: &[&str]| {
        let sec = secs.get(kind)?;
        keys.iter().find_map(|k| {
            sec.entries.iter().rev().find(|kv| kv.key().eq_ignore_ascii_case(k)).map(|kv| kv.value_span(secs.text))
        })
    };
    let explicit =
        if e.parameter_value().is_some() { &["ParameterValue", "DefaultValue"][..] } else { &["DefaultValue"][..] };
    if !obj.object_type.has_subs() {
        return find(Kind::Object(obj.index.0), explicit).unwrap_or(e.at.span);
    }
    find(Kind::Sub(obj.index.0, e.sub.0), explicit)
        .or_else(|| find(Kind::Values(obj.index.0), &[super::decimal_u8(e.sub.0)]))
        .or_else(|| if obj.compact_sub_obj.is_some() { find(Kind::Object(obj.index.0), explicit) } else { None })
        .unwrap_or(e.at.span)
}

/// The value an entry has on the device: ParameterValue if configured, else DefaultValue.
fn effective(e: &Entry) -> Option<&Value> {
    e.parameter_value().or(e.default.as_ref())
}

fn pdos(secs: &Sections<'_>, model: &Model, cx: &mut Ctx<'_>) {
    let mut rx_comm = 0u32;
    let mut tx_comm = 0u32;
    // The PDO objects (communication and mapping) are 0x1400..=0x1BFF: only those are looked at,
    // and which of them the file has is a bit each (on the stack), for `pair`'s look-ups.
    let mut present = PdoSet::default();
    for (index, _) in model.objects.range(PDO_OBJECTS) {
        present.insert(index.0);
    }
    for (_, obj) in model.objects.range(PDO_OBJECTS) {
        let (is_rpdo, n) = match obj.index.role() {
            Role::RpdoCommunication(_) => {
                rx_comm += 1;
                pair(&present, obj, obj.index.0 + 0x200, "mapping", cx);
                continue;
            }
            Role::TpdoCommunication(_) => {
                tx_comm += 1;
                pair(&present, obj, obj.index.0 + 0x200, "mapping", cx);
                continue;
            }
            Role::RpdoMapping(n) => (true, n),
            Role::TpdoMapping(n) => (false, n),
            _ => continue,
        };
        pair(&present, obj, obj.index.0 - 0x200, "communication", cx);
        mapping(secs, model, obj, is_rpdo, n, cx);
    }
    let di = &model.device_info;
    if di.granularity == Some(0) {
        fixed_mapping(secs, model, cx);
    }
    let compact = di.compact_pdo.unwrap_or(0) != 0;
    for (declared, present, key, what) in [
        (di.nr_of_rx_pdo, rx_comm, "NrOfRXPDO", "RPDO communication objects (0x1400..)"),
        (di.nr_of_tx_pdo, tx_comm, "NrOfTXPDO", "TPDO communication objects (0x1800..)"),
    ] {
        let Some(declared) = declared else { continue };
        // With CompactPDO, PDOs may be implied instead of written out.
        if declared as u32 != present && !(compact && present < declared as u32) {
            let span = secs
                .get(Kind::DeviceInfo)
                .and_then(|s| s.entries.iter().rev().find(|kv| kv.key().eq_ignore_ascii_case(key)))
                .map(|kv| kv.value_span(&cx.src.text));
            let d = cx.emit(codes::E0504, span, format!("{key}={declared} but the file has {present} {what}"));
            d.hint = Some(format!("set {key}={present}").into());
        }
    }
}

/// Which indices of [`PDO_OBJECTS`] a file has: a bit each (256 bytes).
#[derive(Default)]
struct PdoSet([u64; 32]);

impl PdoSet {
    /// Adds `index` (one of [`PDO_OBJECTS`]; others are not kept).
    fn insert(&mut self, index: u16) {
        let Some(bit) = index.checked_sub(0x1400).filter(|&b| b < 0x800) else { return };
        self.0[bit as usize / 64] |= 1 << (bit % 64);
    }

    /// Whether `index` was added.
    fn contains(&self, index: u16) -> bool {
        index.checked_sub(0x1400).filter(|&b| b < 0x800).is_some_and(|b| self.0[b as usize / 64] >> (b % 64) & 1 != 0)
    }
}

/// Reports a PDO communication object without its mapping object or the other way round
/// (`other`, which `present` says whether the file has).
fn pair(present: &PdoSet, obj: &Object, other: u16, other_kind: &str, cx: &mut Ctx<'_>) {
    if !present.contains(other) {
        let d = cx.emit(
            codes::E0609,
            Some(obj.at.span),
            format!("0x{:04X} has no matching PDO {other_kind} object 0x{other:04X}", obj.index.0),
        );
        d.hint = Some(format!("add object 0x{other:04X} or remove 0x{:04X}", obj.index.0).into());
        d.context = vec![object_context(obj.index.0, &obj.name)];
    }
}

/// `Granularity=0` says the PDO mappings cannot be changed (CiA 306): then no mapping
/// parameter may be writable. Reported once, at the Granularity key, naming the first writable
/// one.
fn fixed_mapping(secs: &Sections<'_>, model: &Model, cx: &mut Ctx<'_>) {
    let writable: Vec<(&Object, &Entry)> = model
        .objects
        .range(PDO_OBJECTS)
        .map(|(_, o)| o)
        .filter(|o| is_pdo_mapping(o.index.0))
        .filter_map(|o| Some((o, o.subs.values().find(|e| e.access.writable())?)))
        .collect();
    let Some(&(obj, e)) = writable.first() else { return };
    let span = secs
        .get(Kind::DeviceInfo)
        .and_then(|s| s.entries.iter().rev().find(|kv| kv.key().eq_ignore_ascii_case("Granularity")))
        .map(|kv| kv.value_span(&cx.src.text));
    let more = match writable.len() {
        1 => String::new(),
        n => format!(" (and {} more mapping object{})", n - 1, if n == 2 { "" } else { "s" }),
    };
    let d = cx.emit(
        codes::E0614,
        span,
        format!(
            "Granularity=0 says the PDO mappings cannot be changed, but 0x{:04X} sub {} \"{}\" is {}{more}",
            obj.index.0,
            e.sub.0,
            e.name,
            e.access.as_str()
        ),
    );
    d.hint = Some(
        "make the mapping parameters ro (or const), or set Granularity to the mapping unit in bits (usually 8)".into(),
    );
}

/// The indices of the PDO communication and mapping objects (RPDO communication 0x1400.. to
/// TPDO mapping ..0x1BFF).
const PDO_OBJECTS: std::ops::RangeInclusive<Index> = Index(0x1400)..=Index(0x1BFF);

/// The indices of the objects with a COB-ID [`cob_ids`] checks: 0x1005 (SYNC), 0x1014 (EMCY)
/// and the PDO communication objects, with the PDO mapping objects between them.
const COB_ID_OBJECTS: std::ops::RangeInclusive<Index> = Index(0x1005)..=Index(0x19FF);

/// `v` in decimal, as `format!("{v}")` writes it: numbers from 0 to 255 (sub-indices and
/// counts of them, most numbers a diagnostic here shows) as a slice of a table.
fn decimal(v: impl Into<i128>) -> std::borrow::Cow<'static, str> {
    let v = v.into();
    match u8::try_from(v) {
        Ok(b) => super::decimal_u8(b).into(),
        Err(_) => v.to_string().into(),
    }
}

/// Whether `index` is a PDO mapping object's (`Role::RpdoMapping` or `Role::TpdoMapping`),
/// decided on the number without [`Index::role`]'s cases.
#[inline]
fn is_pdo_mapping(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF)
}

/// `RPDO 1`, `TPDO 3` (PDO numbers count from 1).
fn pdo_name(is_rpdo: bool, n: u16) -> String {
    super::cat([if is_rpdo { "RPDO " } else { "TPDO " }, &decimal(n + 1)])
}

fn mapping(secs: &Sections<'_>, model: &Model, obj: &Object, is_rpdo: bool, n: u16, cx: &mut Ctx<'_>) {
    // Messages and contexts are only formatted for the diagnostics that are emitted.
    let pdo = || pdo_name(is_rpdo, n);
    let ctx = Crumbs::object(obj.index.0, &obj.name);
    let Some(count_entry) = obj.sub(0) else { return };
    let Some(count) = effective(count_entry).and_then(Value::as_int) else { return };
    let present = obj.subs.keys().filter(|s| s.0 != 0).count();
    if !(0..=64).contains(&count) {
        let d = cx.emit(
            codes::E0608,
            Some(value_span(secs, obj, count_entry)),
            format!("{} maps {count} entries; a PDO holds at most 64", pdo()),
        );
        d.context = ctx.to_vec();
        return;
    }
    let granularity = model.device_info.granularity;
    let mut total_bits: u32 = 0;
    let mut missing = Vec::new();
    for s in 1..=count as u8 {
        let Some(e) = obj.sub(s) else {
            missing.push(s);
            continue;
        };
        let c = ctx.sub(s, &e.name);
        let span = || value_span(secs, obj, e);
        let raw = match effective(e) {
            None => continue,
            Some(Value::Int { value, .. }) if (0..=u32::MAX as i128).contains(value) => *value as u32,
            Some(v) => {
                let d = cx.emit(
                    codes::E0611,
                    Some(span()),
                    format!(
                        "mapping entry `{}` is not a 32-bit `0xIIIISSLL` value",
                        crate::value::format_value(v, e.data_type)
                    ),
                );
                d.context = c.to_vec();
                continue;
            }
        };
        if raw == 0 {
            continue;
        }
        let m = PdoMappingEntry::from_u32(raw);
        total_bits += m.bits as u32;
        let target_text = || super::cat(["0x", &super::hex4(m.index.0), " sub ", super::decimal_u8(m.sub.0)]);
        if let Some(g) = granularity.filter(|&g| g != 0)
            && !m.bits.is_multiple_of(g)
        {
            let d = cx.emit(
                codes::E0613,
                Some(span()),
                format!(
                    "{} maps {} with {} bits, which is not a multiple of Granularity={g}",
                    pdo(),
                    target_text(),
                    m.bits
                ),
            );
            d.hint = Some(
                format!(
                    "this device maps in units of {g} bits ([DeviceInfo] Granularity); map whole units or change Granularity"
                )
                .into(),
            );
            d.context = c.to_vec();
        }
        if m.is_dummy() {
            let ty = DataType::from_code(m.index.0);
            if model.dummy_usage.get(&m.index.0) != Some(&true) {
                let d = cx.emit(
                    codes::E0604,
                    Some(span()),
                    format!(
                        "{} maps a dummy {} (0x{raw:08X}), but [DummyUsage] does not enable Dummy{:04X}",
                        pdo(),
                        ty.name(),
                        m.index.0
                    ),
                );
                d.hint = Some(format!("add `Dummy{:04X}=1` to [DummyUsage]", m.index.0).into());
                d.context = c.to_vec();
            }
            if let Some(bits) = ty.bits()
                && bits != m.bits as u32
            {
                let d = cx.emit(
                    codes::E0603,
                    Some(span()),
                    format!("dummy {} is {bits} bits long, but the mapping says {}", ty.name(), m.bits),
                );
                d.hint = Some(format!("write 0x{:08X}", (raw & !0xFF) | bits).into());
                d.context = c.to_vec();
            }
            continue;
        }
        let Some(target) = model.entry(m.index.0, m.sub.0) else {
            let what = if model.object(m.index.0).is_some() {
                format!("object 0x{:04X} has no usable sub-index {}", m.index.0, m.sub.0)
            } else {
                "the file does not define it".to_owned()
            };
            let d = cx.emit(
                codes::E0601,
                Some(span()),
                format!("{} maps {} (0x{raw:08X}), but {what}", pdo(), target_text()),
            );
            d.context = c.to_vec();
            continue;
        };
        let target_text = || match model.object(m.index.0) {
            Some(o) if o.object_type.has_subs() => {
                super::cat([&target_text(), " \"", &target.name, "\" of \"", &o.name, "\""])
            }
            _ => super::cat(["0x", &super::hex4(m.index.0), " \"", &target.name, "\""]),
        };
        if !target.pdo_mapping {
            let d = cx.emit(
                codes::E0602,
                Some(span()),
                super::cat([&pdo(), " maps ", &target_text(), ", which has PDOMapping=0"]),
            );
            d.hint = Some("set PDOMapping=1 on the mapped entry, or remove the mapping".into());
            d.context = c.to_vec();
        }
        if let Some(bits) = target.data_type.bits()
            && bits != m.bits as u32
        {
            let d = cx.emit(
                codes::E0603,
                Some(span()),
                format!(
                    "{} maps {} with {} bits, but it is {} ({bits} bits)",
                    pdo(),
                    target_text(),
                    m.bits,
                    target.data_type.name()
                ),
            );
            d.hint = Some(format!("write 0x{:08X}", (raw & !0xFF) | bits).into());
            d.context = c.to_vec();
        }
        if is_rpdo && !target.access.rpdo_ok() {
            let d = cx.emit(
                codes::E0606,
                Some(span()),
                format!("{} writes {}, whose AccessType is {}", pdo(), target_text(), target.access.as_str()),
            );
            d.hint = Some("an RPDO entry must be writable (wo, rw or rww)".into());
            d.context = c.to_vec();
        }
        if !is_rpdo && !target.access.tpdo_ok() {
            let d = cx.emit(
                codes::E0607,
                Some(span()),
                format!("{} reads {}, whose AccessType is {}", pdo(), target_text(), target.access.as_str()),
            );
            d.hint = Some("a TPDO entry must be readable (ro, rw, rwr or const)".into());
            d.context = c.to_vec();
        }
    }
    if !missing.is_empty() {
        let d = cx.emit(
            codes::E0608,
            Some(value_span(secs, obj, count_entry)),
            format!(
                "{} maps {count} entries, but sub-index {} is missing",
                pdo(),
                missing.iter().map(u8::to_string).collect::<Vec<_>>().join(", ")
            ),
        );
        d.hint = Some(format!("lower the count to {present} or add the mapping entries").into());
        d.context = ctx.to_vec();
    }
    if total_bits > 64 {
        let d = cx.emit(
            codes::E0605,
            Some(value_span(secs, obj, count_entry)),
            format!("{} maps {total_bits} bits; a CAN PDO carries at most 64", pdo()),
        );
        d.hint = Some("split the mapping over two PDOs".into());
        d.context = ctx.to_vec();
    }
}

/// Sub-index 0 of an ARRAY or RECORD says how far the object goes: the highest sub-index it
/// supports (CiA 301), which for an ARRAY is also the number of its elements. A writable
/// sub-index 0 counts the entries in use (0x1003 "number of errors") and may be lower. PDO
/// mapping objects are checked with their mapping (E0608).
///
/// The highest sub-index is the highest in the model or `highest_section`, the highest with a
/// sub-object section (sections count even when their entry could not be read; that is
/// reported on its own).
///
/// Lowering calls this as it finishes each object, while the object and its sections are still
/// in the cache: a pass of its own over the whole model and the section list, which has run
/// long by then, took 3 % of the reading time for this one comparison per object.
pub(crate) fn sub_index_zero(secs: &Sections<'_>, obj: &Object, highest_section: Option<u8>, cx: &mut Ctx<'_>) {
    if !matches!(obj.object_type, ObjectType::Array | ObjectType::Record) || is_pdo_mapping(obj.index.0) {
        return;
    }
    let Some(e0) = obj.sub(0) else { return };
    let Some(value) = effective(e0).and_then(Value::as_int) else { return };
    let in_model = obj.subs.keys().next_back().map(|s| s.0);
    let highest = in_model.max(highest_section).unwrap_or(0) as i128;
    let count = obj.subs.len() as i128 - 1;
    let is_array = obj.object_type == ObjectType::Array;
    let ok = if e0.access.writable() {
        (0..=highest).contains(&value)
    } else {
        value == highest || (is_array && value == count)
    };
    if ok {
        return;
    }
    let show_count = is_array && count != highest;
    let (value, highest, count) = (decimal(value), decimal(highest), decimal(count));
    let (elements, count, tail) = if show_count { (" and it has ", &*count, " elements") } else { ("", "", "") };
    let d = cx.emit(
        codes::E0221,
        Some(value_span(secs, obj, e0)),
        super::cat([
            "sub-index 0 of ",
            otype(obj.object_type),
            " 0x",
            &super::hex4(obj.index.0),
            " is ",
            &value,
            ", but the highest sub-index present is ",
            &highest,
            elements,
            count,
            tail,
        ]),
    );
    d.hint = Some(
        if e0.access.writable() {
            super::cat(["sub-index 0 counts the entries in use: at most ", &highest])
        } else {
            super::cat(["set sub-index 0 to ", &highest, ", the highest sub-index the object supports"])
        }
        .into(),
    );
    d.context = Crumbs::object(obj.index.0, &obj.name).sub(0, &e0.name).to_vec();
}

/// CAN-IDs CiA 301 keeps from configurable communication objects (SYNC, TIME, EMCY, PDO, SDO):
/// NMT, the default SDO and NMT error control channels, and reserved ranges.
const RESTRICTED_CAN_IDS: [(u32, u32); 8] = [
    (0x000, 0x000),
    (0x001, 0x07F),
    (0x101, 0x180),
    (0x581, 0x5FF),
    (0x601, 0x67F),
    (0x6E0, 0x6FF),
    (0x701, 0x77F),
    (0x780, 0x7FF),
];

/// A COB-ID entry: a PDO's communication sub-index 1, 0x1005 (SYNC) or 0x1014 (EMCY).
struct CobId<'m> {
    obj: &'m Object,
    entry: &'m Entry,
    /// `TPDO 1`, `SYNC`, `EMCY` (written only into a diagnostic).
    what: CobOwner,
    value: &'m Value,
    /// Bit 31 says "not valid" (PDO, EMCY); SYNC has no such bit.
    has_valid_bit: bool,
}

/// Whose COB-ID a [`CobId`] is; shown as `TPDO 1`, `SYNC`, `EMCY`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CobOwner {
    /// A PDO: whether it is an RPDO, and its number counted from 0.
    Pdo(bool, u16),
    Sync,
    Emcy,
}

impl std::fmt::Display for CobOwner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            CobOwner::Pdo(is_rpdo, n) => f.write_str(&pdo_name(is_rpdo, n)),
            CobOwner::Sync => f.write_str("SYNC"),
            CobOwner::Emcy => f.write_str("EMCY"),
        }
    }
}

impl CobId<'_> {
    /// The 32-bit value for node id `node` (`None` when out of range).
    fn resolve(&self, node: u8) -> Option<u32> {
        u32::try_from(self.value.resolve(node)?).ok()
    }

    /// Whether the object is in use (see [`in_use`]).
    fn in_use(&self, raw: u32) -> bool {
        in_use(raw, self.has_valid_bit)
    }

    /// Whether [`can_id_check`] finds nothing for any of `nodes` (see [`quiet_for_all`]).
    fn quiet_for_all(&self, nodes: std::ops::RangeInclusive<u8>) -> bool {
        quiet_for_all(self.value, self.has_valid_bit, nodes)
    }
}

/// What the COB-ID check finds in one node's 32-bit COB-ID.
#[derive(Debug, PartialEq, Eq)]
enum CanIdCheck {
    /// Nothing: not in use (bit 31 set where it means "not valid"), a 29-bit CAN-ID, or a free
    /// 11-bit one.
    Fine,
    /// An 11-bit CAN-ID (bit 29 clear) with bits set above bit 10.
    TooWide,
    /// An 11-bit CAN-ID that CiA 301 restricts.
    Restricted(u32),
}

/// Whether a COB-ID is in use: bit 31 clear where it means "not valid" (`has_valid_bit`).
fn in_use(raw: u32, has_valid_bit: bool) -> bool {
    !has_valid_bit || raw & 0x8000_0000 == 0
}

/// Whether the CAN-ID checks apply to a COB-ID: in use, with an 11-bit CAN-ID (bit 29 clear).
fn checked_11_bit(raw: u32, has_valid_bit: bool) -> bool {
    in_use(raw, has_valid_bit) && raw & 0x2000_0000 == 0
}

fn can_id_check(raw: u32, has_valid_bit: bool) -> CanIdCheck {
    if !checked_11_bit(raw, has_valid_bit) {
        return CanIdCheck::Fine;
    }
    let id = raw & 0x1FFF_FFFF;
    if id > 0x7FF {
        CanIdCheck::TooWide
    } else if RESTRICTED_CAN_IDS.iter().any(|&(lo, hi)| (lo..=hi).contains(&id)) {
        CanIdCheck::Restricted(id)
    } else {
        CanIdCheck::Fine
    }
}

/// Whether [`can_id_check`] is `Fine` for the value on every node of `nodes`, decided from the
/// first and the last node's value without trying each (a `$NODEID+...` COB-ID in an EDS is
/// judged for all 127 node ids): when both agree in every bit above the CAN-ID's 11 bits, all
/// nodes between agree too (the value grows by one per node), and their CAN-IDs are one run.
/// `false` means "look at each node".
fn quiet_for_all(value: &Value, has_valid_bit: bool, nodes: std::ops::RangeInclusive<u8>) -> bool {
    let raw = |n: u8| value.resolve(n).and_then(|v| u32::try_from(v).ok());
    let (Some(lo), Some(hi)) = (raw(*nodes.start()), raw(*nodes.end())) else {
        return false;
    };
    if lo >> 11 != hi >> 11 {
        return false;
    }
    if !checked_11_bit(lo, has_valid_bit) {
        // Not in use, or a 29-bit CAN-ID, on every node (bits 29 and 31 are the same for all).
        return true;
    }
    let (first, last) = (lo & 0x1FFF_FFFF, hi & 0x1FFF_FFFF);
    last <= 0x7FF && RESTRICTED_CAN_IDS.iter().all(|&(r_lo, r_hi)| last < r_lo || first > r_hi)
}

/// The node ids a value is judged for: the configured one in a DCF, else all of 1..=127 when
/// the value depends on the node id, else just one (any).
fn node_ids(model: &Model, v: &Value) -> std::ops::RangeInclusive<u8> {
    match model.node_id() {
        Some(n) => n..=n,
        None if v.is_node_relative() => 1..=127,
        None => 1..=1,
    }
}

/// `0x181` or, for a value that depends on the node id, `$NODEID+0x180`.
fn show_cob(v: &Value) -> String {
    crate::value::format_value(v, DataType::Unsigned32)
}

/// COB-IDs of PDOs, SYNC and EMCY: 11-bit CAN-IDs that CiA 301 restricts, frame bit against the
/// bits used, and two of the device's own objects on the same CAN-ID.
fn cob_ids(secs: &Sections<'_>, model: &Model, cx: &mut Ctx<'_>) {
    let mut cobs: Vec<CobId<'_>> = Vec::new();
    for (_, obj) in model.objects.range(COB_ID_OBJECTS) {
        let (sub, what, has_valid_bit) = match obj.index.role() {
            Role::RpdoCommunication(n) => (1, CobOwner::Pdo(true, n), true),
            Role::TpdoCommunication(n) => (1, CobOwner::Pdo(false, n), true),
            Role::SyncCobId => (0, CobOwner::Sync, false),
            Role::EmcyCobId => (0, CobOwner::Emcy, true),
            _ => continue,
        };
        let Some(entry) = obj.sub(sub) else { continue };
        let Some(value) = effective(entry).filter(|v| matches!(v, Value::Int { .. } | Value::NodeIdPlus { .. })) else {
            continue;
        };
        cobs.push(CobId { obj, entry, what, value, has_valid_bit });
    }
    for cob in &cobs {
        let ctx = || Crumbs::object(cob.obj.index.0, &cob.obj.name).sub(cob.entry.sub.0, &cob.entry.name).to_vec();
        let span = || value_span(secs, cob.obj, cob.entry);
        // The node ids for which the COB-ID is a used 11-bit CAN-ID with bits above bit 10, or
        // one that CiA 301 restricts.
        let mut too_wide: Option<(u8, u32)> = None;
        let mut restricted: Vec<(u8, u32)> = Vec::new();
        let nodes = node_ids(model, cob.value);
        if cob.quiet_for_all(nodes.clone()) {
            continue;
        }
        for node in nodes {
            let Some(raw) = cob.resolve(node) else { continue };
            match can_id_check(raw, cob.has_valid_bit) {
                CanIdCheck::TooWide => {
                    too_wide.get_or_insert((node, raw));
                }
                CanIdCheck::Restricted(id) => restricted.push((node, id)),
                CanIdCheck::Fine => {}
            }
        }
        if let Some((node, raw)) = too_wide {
            let for_node =
                if cob.value.is_node_relative() { format!(" (0x{raw:08X} for node id {node})") } else { String::new() };
            let d = cx.emit(
                codes::E0702,
                Some(span()),
                format!(
                    "{} COB-ID {}{for_node} has bit 29 clear (an 11-bit CAN-ID) but uses CAN-ID bits above bit 10",
                    cob.what,
                    show_cob(cob.value)
                ),
            );
            d.hint = Some("11-bit CAN-IDs are 0x001..0x7FF; set bit 29 (0x20000000) for a 29-bit CAN-ID".into());
            d.context = ctx();
        } else if let (Some(&(first, id)), Some(&(last, last_id))) = (restricted.first(), restricted.last()) {
            let which = if !cob.value.is_node_relative() || model.node_id().is_some() {
                format!("is CAN-ID 0x{id:03X}")
            } else if first == last {
                format!("is CAN-ID 0x{id:03X} for node id {first}")
            } else if restricted.len() == (last - first) as usize + 1 {
                format!("is CAN-ID 0x{id:03X}..=0x{last_id:03X} for node ids {first}..={last}")
            } else {
                format!("is a restricted CAN-ID for {} node ids (0x{id:03X} for node id {first})", restricted.len())
            };
            let d = cx.emit(
                codes::E0701,
                Some(span()),
                format!("{} COB-ID {} {which}, which CiA 301 reserves", cob.what, show_cob(cob.value)),
            );
            d.hint = Some(
                "CiA 301 restricts 0x000, 0x001..0x07F, 0x101..0x180, 0x581..0x5FF, 0x601..0x67F, 0x6E0..0x6FF and 0x701..0x7FF; use the predefined connection set ($NODEID+0x180 .. $NODEID+0x500 for PDOs 1-4) or another free CAN-ID"
                    .into(),
            );
            d.context = ctx();
        }
    }
    // Two of the device's own objects in use on the same CAN-ID (frame bit and ID compared; the
    // RTR and valid bits are not part of it). Without a node id, values relative to it are
    // compared by their offsets (equal offsets collide on every node), fixed ones by value.
    let key = |cob: &CobId<'_>| -> Option<(bool, u32)> {
        let (relative, raw) = match (model.node_id(), cob.value) {
            (Some(n), _) => (false, cob.resolve(n)?),
            (None, Value::Int { value, .. }) => (false, u32::try_from(*value).ok()?),
            (None, Value::NodeIdPlus { offset, .. }) => (true, u32::try_from(*offset).ok()?),
            _ => return None,
        };
        cob.in_use(raw).then_some((relative, raw & 0x3FFF_FFFF))
    };
    let mut seen: Vec<((bool, u32), usize)> = Vec::with_capacity(cobs.len());
    for (i, cob) in cobs.iter().enumerate() {
        let Some(k) = key(cob) else { continue };
        if let Some(&(_, first)) = seen.iter().find(|(s, _)| *s == k) {
            let other = &cobs[first];
            let d = cx.emit(
                codes::E0703,
                Some(value_span(secs, cob.obj, cob.entry)),
                format!(
                    "{} COB-ID {} is the same CAN-ID as {} (0x{:04X} sub {}: {})",
                    cob.what,
                    show_cob(cob.value),
                    other.what,
                    other.obj.index.0,
                    other.entry.sub.0,
                    show_cob(other.value)
                ),
            );
            d.hint = Some("give each PDO, SYNC and EMCY of the device its own CAN-ID".into());
            d.context = Crumbs::object(cob.obj.index.0, &cob.obj.name).sub(cob.entry.sub.0, &cob.entry.name).to_vec();
        } else {
            seen.push((k, i));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The index ranges the checks look in hold every object of the roles they look for, and
    /// `is_pdo_mapping` is the roles' own test: for every index.
    #[test]
    fn index_ranges_hold_the_roles() {
        for i in 0..=u16::MAX {
            let role = Index(i).role();
            let mapping = matches!(role, Role::RpdoMapping(_) | Role::TpdoMapping(_));
            assert_eq!(is_pdo_mapping(i), mapping, "{i:#06x}");
            let pdo = mapping || matches!(role, Role::RpdoCommunication(_) | Role::TpdoCommunication(_));
            if pdo {
                assert!(PDO_OBJECTS.contains(&Index(i)), "{i:#06x}");
            }
            let cob = matches!(
                role,
                Role::RpdoCommunication(_) | Role::TpdoCommunication(_) | Role::SyncCobId | Role::EmcyCobId
            );
            if cob {
                assert!(COB_ID_OBJECTS.contains(&Index(i)), "{i:#06x}");
            }
        }
    }

    #[test]
    fn decimals_are_written_as_format_writes_them() {
        for v in (-300i128..300).chain([i128::MIN, i128::MAX, 65_535, 1 << 40]) {
            assert_eq!(decimal(v), format!("{v}"));
        }
        for n in 0..=u16::MAX {
            assert_eq!(decimal(n), format!("{n}"));
        }
        for n in [0, 1, 254, 255, 511, u16::MAX - 1] {
            assert_eq!(pdo_name(true, n), format!("RPDO {}", n + 1));
            assert_eq!(pdo_name(false, n), format!("TPDO {}", n + 1));
        }
    }

    #[test]
    fn pdo_sets_hold_the_pdo_indices_added() {
        let mut set = PdoSet::default();
        let added = |i: u16| PDO_OBJECTS.contains(&Index(i)) && i % 3 != 1;
        for i in 0..=u16::MAX {
            if i % 3 != 1 {
                set.insert(i);
            }
        }
        for i in 0..=u16::MAX {
            assert_eq!(set.contains(i), added(i), "{i:#06x}");
        }
    }

    #[test]
    fn cob_owners_are_shown_as_before() {
        assert_eq!(CobOwner::Pdo(true, 0).to_string(), "RPDO 1");
        assert_eq!(CobOwner::Pdo(false, 511).to_string(), "TPDO 512");
        assert_eq!(CobOwner::Sync.to_string(), "SYNC");
        assert_eq!(CobOwner::Emcy.to_string(), "EMCY");
    }

    /// The shortcut says "nothing to report" only where every node's check says so.
    fn agrees(value: Value, has_valid_bit: bool, nodes: std::ops::RangeInclusive<u8>) {
        if quiet_for_all(&value, has_valid_bit, nodes.clone()) {
            for n in nodes {
                let raw = u32::try_from(value.resolve(n).unwrap()).unwrap();
                assert_eq!(can_id_check(raw, has_valid_bit), CanIdCheck::Fine, "{value:?} node {n}");
            }
        }
    }

    #[test]
    fn the_shortcut_is_taken_for_the_predefined_connection_set() {
        let relative = |offset: i128| Value::NodeIdPlus { offset, radix: crate::model::Radix::Hex };
        for offset in [0x180, 0x200, 0x280, 0x300, 0x380, 0x400, 0x480, 0x500, 0x80] {
            // (EMCY's $NODEID+0x80 gives 0x081..0x0FF, between two restricted ranges.)
            assert!(quiet_for_all(&relative(offset), true, 1..=127), "{offset:#x}");
            agrees(relative(offset), true, 1..=127);
        }
        // $NODEID+0x100 reaches 0x101..0x17F (restricted), $NODEID+0x700 the heartbeat range.
        assert!(!quiet_for_all(&relative(0x100), true, 1..=127));
        assert!(!quiet_for_all(&relative(0x700), true, 1..=127));
        // Not valid (bit 31) or 29-bit (bit 29): nothing to check on any node.
        assert!(quiet_for_all(&relative(0x8000_0100), true, 1..=127));
        assert!(quiet_for_all(&relative(0x2000_0100), false, 1..=127));
        // CAN-ID bits above bit 10 in an 11-bit CAN-ID: each node is looked at.
        assert!(!quiet_for_all(&relative(0x980), true, 1..=127));
        // Values whose high bits change within the node range: each node is looked at.
        assert!(!quiet_for_all(&relative(0x7C0), true, 1..=127));
    }

    proptest! {
        #[test]
        fn the_shortcut_agrees_with_each_node(
            base in prop_oneof![0u32..0x900, 0x1FF_FF00u32..0x200_0100, 0x7FFF_FF00u32..0x8000_0900, any::<u32>()],
            relative in any::<bool>(),
            has_valid_bit in any::<bool>(),
            node in 1u8..=127,
        ) {
            let radix = crate::model::Radix::Hex;
            let (value, nodes) = if relative {
                (Value::NodeIdPlus { offset: base as i128, radix }, 1..=127)
            } else {
                (Value::Int { value: base as i128, radix }, node..=node)
            };
            if value.resolve(127).is_some_and(|v| u32::try_from(v).is_ok()) {
                agrees(value, has_valid_bit, nodes);
            }
        }
    }
}
