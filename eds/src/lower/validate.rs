//! Pass 4: checks across the whole model.

use super::info::{Lists, category_slot, list_name};
use super::sections::{Kind, Sections};
use super::{Ctx, object_context, otype, sub_context};
use crate::codes;
use crate::model::{DataType, Entry, Index, Model, Object, ObjectType, PdoMappingEntry, Role, Value};
use crate::source::Span;

pub(crate) fn validate(secs: &Sections<'_>, lists: &Lists, model: &Model, cx: &mut Ctx<'_>) {
    object_lists(secs, lists, model, cx);
    mandatory(model, cx);
    pdos(secs, model, cx);
}

fn object_lists(secs: &Sections<'_>, lists: &Lists, model: &Model, cx: &mut Ctx<'_>) {
    if lists.present.iter().all(|p| !p) {
        let d = cx.emit(
            codes::E0407,
            None,
            "the file has none of [MandatoryObjects], [OptionalObjects], [ManufacturerObjects]",
        );
        d.hint = Some(
            "list every object in the list it belongs to; this reader loaded the object sections it found".to_owned(),
        );
        return;
    }
    let mut listed: Vec<(&u16, &(crate::model::Category, Span))> = lists.listed.iter().collect();
    listed.sort_by_key(|(_, (_, span))| span.start);
    for (&index, &(cat, span)) in listed {
        if !model.objects.contains_key(&Index(index)) && secs.get(Kind::Object(index)).is_none() {
            let d = cx.emit(
                codes::E0401,
                Some(span),
                format!("[{}] lists 0x{index:04X}, but there is no section [{index:04X}]", list_name(cat)),
            );
            d.hint = Some(format!("add the section [{index:04X}] or remove the list entry"));
        }
    }
    for obj in model.objects.values() {
        if !lists.listed.contains_key(&obj.index.0) {
            let cat = obj.category;
            let d = cx.emit(
                codes::E0402,
                Some(obj.at.span),
                format!("object 0x{:04X} is not named in any object list", obj.index.0),
            );
            d.hint = Some(if lists.present[category_slot(cat)] {
                format!("add it to [{}] and raise SupportedObjects", list_name(cat))
            } else {
                format!("add a [{}] section that lists it", list_name(cat))
            });
            d.context = vec![object_context(obj.index.0, &obj.name)];
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
            d.hint = Some("CiA 301 requires 0x1000, 0x1001 and 0x1018 in every device".to_owned());
            continue;
        };
        let ctx = vec![object_context(index, &obj.name)];
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
            d.context = ctx.clone();
            continue;
        }
        if let Some(e) = obj.sub(sub)
            && e.data_type != dt
        {
            let mut c = ctx.clone();
            if sub != 0 {
                c.push(sub_context(sub, &e.name));
            }
            let d = cx.emit(
                codes::E0507,
                Some(e.at.span),
                format!("{what} entry is {} but CiA 301 makes it {}", e.data_type.name(), dt.name()),
            );
            d.hint = Some(format!("write DataType=0x{:04X}", dt.code()));
            d.context = c;
        }
    }
}

/// The span of the text that gave an entry its value (ParameterValue before DefaultValue),
/// falling back to the entry's section.
fn value_span(secs: &Sections<'_>, obj: &Object, e: &Entry) -> Span {
    let find = |kind: Kind, keys: &[&str]| {
        let sec = secs.get(kind)?;
        keys.iter()
            .find_map(|k| sec.entries.iter().rev().find(|kv| kv.key.eq_ignore_ascii_case(k)).map(|kv| kv.value_span))
    };
    let key = e.sub.0.to_string();
    let explicit =
        if e.parameter_value.is_some() { &["ParameterValue", "DefaultValue"][..] } else { &["DefaultValue"][..] };
    find(Kind::Sub(obj.index.0, e.sub.0), explicit)
        .or_else(|| find(Kind::Values(obj.index.0), &[key.as_str()]))
        .or_else(|| if obj.compact_sub_obj.is_some() { find(Kind::Object(obj.index.0), explicit) } else { None })
        .unwrap_or(e.at.span)
}

/// The value an entry has on the device: ParameterValue if configured, else DefaultValue.
fn effective(e: &Entry) -> Option<&Value> {
    e.parameter_value.as_ref().or(e.default.as_ref())
}

fn pdos(secs: &Sections<'_>, model: &Model, cx: &mut Ctx<'_>) {
    let mut rx_comm = 0u32;
    let mut tx_comm = 0u32;
    for obj in model.objects.values() {
        let (is_rpdo, n) = match obj.index.role() {
            Role::RpdoCommunication(_) => {
                rx_comm += 1;
                pair(model, obj, obj.index.0 + 0x200, "mapping", cx);
                continue;
            }
            Role::TpdoCommunication(_) => {
                tx_comm += 1;
                pair(model, obj, obj.index.0 + 0x200, "mapping", cx);
                continue;
            }
            Role::RpdoMapping(n) => (true, n),
            Role::TpdoMapping(n) => (false, n),
            _ => continue,
        };
        pair(model, obj, obj.index.0 - 0x200, "communication", cx);
        mapping(secs, model, obj, is_rpdo, n, cx);
    }
    let di = &model.device_info;
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
                .and_then(|s| s.entries.iter().rev().find(|kv| kv.key.eq_ignore_ascii_case(key)))
                .map(|kv| kv.value_span);
            let d = cx.emit(codes::E0504, span, format!("{key}={declared} but the file has {present} {what}"));
            d.hint = Some(format!("set {key}={present}"));
        }
    }
}

fn pair(model: &Model, obj: &Object, other: u16, other_kind: &str, cx: &mut Ctx<'_>) {
    if !model.objects.contains_key(&Index(other)) {
        let d = cx.emit(
            codes::E0609,
            Some(obj.at.span),
            format!("0x{:04X} has no matching PDO {other_kind} object 0x{other:04X}", obj.index.0),
        );
        d.hint = Some(format!("add object 0x{other:04X} or remove 0x{:04X}", obj.index.0));
        d.context = vec![object_context(obj.index.0, &obj.name)];
    }
}

fn mapping(secs: &Sections<'_>, model: &Model, obj: &Object, is_rpdo: bool, n: u16, cx: &mut Ctx<'_>) {
    let pdo = format!("{} {}", if is_rpdo { "RPDO" } else { "TPDO" }, n + 1);
    let ctx = vec![object_context(obj.index.0, &obj.name)];
    let Some(count_entry) = obj.sub(0) else { return };
    let Some(count) = effective(count_entry).and_then(Value::as_int) else { return };
    let present = obj.subs.keys().filter(|s| s.0 != 0).count();
    if !(0..=64).contains(&count) {
        let d = cx.emit(
            codes::E0608,
            Some(value_span(secs, obj, count_entry)),
            format!("{pdo} maps {count} entries; a PDO holds at most 64"),
        );
        d.context = ctx.clone();
        return;
    }
    let mut total_bits: u32 = 0;
    let mut missing = Vec::new();
    for s in 1..=count as u8 {
        let Some(e) = obj.sub(s) else {
            missing.push(s);
            continue;
        };
        let mut c = ctx.clone();
        c.push(sub_context(s, &e.name));
        let span = value_span(secs, obj, e);
        let raw = match effective(e) {
            None => continue,
            Some(Value::Int { value, .. }) if (0..=u32::MAX as i128).contains(value) => *value as u32,
            Some(v) => {
                let d = cx.emit(
                    codes::E0611,
                    Some(span),
                    format!(
                        "mapping entry `{}` is not a 32-bit `0xIIIISSLL` value",
                        crate::value::format_value(v, e.data_type)
                    ),
                );
                d.context = c;
                continue;
            }
        };
        if raw == 0 {
            continue;
        }
        let m = PdoMappingEntry::from_u32(raw);
        total_bits += m.bits as u32;
        let target_text = format!("0x{:04X} sub {}", m.index.0, m.sub.0);
        if m.is_dummy() {
            let ty = DataType::from_code(m.index.0);
            if model.dummy_usage.get(&m.index.0) != Some(&true) {
                let d = cx.emit(
                    codes::E0604,
                    Some(span),
                    format!(
                        "{pdo} maps a dummy {} (0x{raw:08X}), but [DummyUsage] does not enable Dummy{:04X}",
                        ty.name(),
                        m.index.0
                    ),
                );
                d.hint = Some(format!("add `Dummy{:04X}=1` to [DummyUsage]", m.index.0));
                d.context = c.clone();
            }
            if let Some(bits) = ty.bits()
                && bits != m.bits as u32
            {
                let d = cx.emit(
                    codes::E0603,
                    Some(span),
                    format!("dummy {} is {bits} bits long, but the mapping says {}", ty.name(), m.bits),
                );
                d.hint = Some(format!("write 0x{:08X}", (raw & !0xFF) | bits));
                d.context = c;
            }
            continue;
        }
        let Some(target) = model.entry(m.index.0, m.sub.0) else {
            let what = if model.object(m.index.0).is_some() {
                format!("object 0x{:04X} has no usable sub-index {}", m.index.0, m.sub.0)
            } else {
                "the file does not define it".to_owned()
            };
            let d = cx.emit(codes::E0601, Some(span), format!("{pdo} maps {target_text} (0x{raw:08X}), but {what}"));
            d.context = c;
            continue;
        };
        let target_text = match model.object(m.index.0) {
            Some(o) if o.object_type.has_subs() => format!("{target_text} \"{}\" of \"{}\"", target.name, o.name),
            _ => format!("0x{:04X} \"{}\"", m.index.0, target.name),
        };
        if !target.pdo_mapping {
            let d = cx.emit(codes::E0602, Some(span), format!("{pdo} maps {target_text}, which has PDOMapping=0"));
            d.hint = Some("set PDOMapping=1 on the mapped entry, or remove the mapping".to_owned());
            d.context = c.clone();
        }
        if let Some(bits) = target.data_type.bits()
            && bits != m.bits as u32
        {
            let d = cx.emit(
                codes::E0603,
                Some(span),
                format!(
                    "{pdo} maps {target_text} with {} bits, but it is {} ({bits} bits)",
                    m.bits,
                    target.data_type.name()
                ),
            );
            d.hint = Some(format!("write 0x{:08X}", (raw & !0xFF) | bits));
            d.context = c.clone();
        }
        if is_rpdo && !target.access.rpdo_ok() {
            let d = cx.emit(
                codes::E0606,
                Some(span),
                format!("{pdo} writes {target_text}, whose AccessType is {}", target.access.as_str()),
            );
            d.hint = Some("an RPDO entry must be writable (wo, rw or rww)".to_owned());
            d.context = c.clone();
        }
        if !is_rpdo && !target.access.tpdo_ok() {
            let d = cx.emit(
                codes::E0607,
                Some(span),
                format!("{pdo} reads {target_text}, whose AccessType is {}", target.access.as_str()),
            );
            d.hint = Some("a TPDO entry must be readable (ro, rw, rwr or const)".to_owned());
            d.context = c;
        }
    }
    if !missing.is_empty() {
        let d = cx.emit(
            codes::E0608,
            Some(value_span(secs, obj, count_entry)),
            format!(
                "{pdo} maps {count} entries, but sub-index {} is missing",
                missing.iter().map(u8::to_string).collect::<Vec<_>>().join(", ")
            ),
        );
        d.hint = Some(format!("lower the count to {present} or add the mapping entries"));
        d.context = ctx.clone();
    }
    if total_bits > 64 {
        let d = cx.emit(
            codes::E0605,
            Some(value_span(secs, obj, count_entry)),
            format!("{pdo} maps {total_bits} bits; a CAN PDO carries at most 64"),
        );
        d.hint = Some("split the mapping over two PDOs".to_owned());
        d.context = ctx;
    }
}
