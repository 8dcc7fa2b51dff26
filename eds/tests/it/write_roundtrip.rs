//! Property: every representable model, written and read back, is the same model.
//!
//! "Representable" (see `eds::write::unrepresentable`): no line breaks in text, no white space
//! at either end of a value, values that are valid for their type, and no REAL NaN (NaN is not
//! equal to itself, so no model holding it equals anything). The strategies below build only
//! such models; everything else about them is random: header fields, baud rates, dummy usage,
//! comments, commissioning, objects of every kind with every basic type, values in every radix
//! and `$NODEID` form, limits, flags, unknown keys and sections.

use crate::write_common;

use eds::model::*;
use proptest::collection::{btree_map, btree_set, vec};
use proptest::option;
use proptest::prelude::*;

/// Printable text without white space at the ends (ASCII, with some non-ASCII letters).
fn text() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => "[!-~]([ -~]{0,14}[!-~])?",
        1 => "[a-zé✓ü]{1,6}( [a-zé✓ü]{1,6}){0,2}",
        1 => Just(String::new()),
    ]
}

/// Non-empty text (names of things readers require).
fn name() -> impl Strategy<Value = String> {
    "[A-Za-z0-9_.()-]([ -~]{0,20}[A-Za-z0-9_.()-])?"
}

fn extra_keys(max: usize) -> impl Strategy<Value = Vec<(String, String)>> {
    btree_map("X[a-z]{1,6}", text(), 0..=max).prop_map(|m| m.into_iter().collect())
}

fn radix() -> impl Strategy<Value = Radix> {
    prop_oneof![Just(Radix::Dec), Just(Radix::Hex), Just(Radix::Oct)]
}

fn data_type() -> impl Strategy<Value = DataType> {
    prop_oneof![
        8 => proptest::sample::select(DataType::BASIC.to_vec()),
        1 => (0x20u16..0x30).prop_map(DataType::Other),
    ]
}

/// A value that is valid for `ty`.
fn value(ty: DataType) -> BoxedStrategy<Value> {
    match ty {
        DataType::VisibleString | DataType::UnicodeString => text().prop_map(Value::Text).boxed(),
        DataType::OctetString => vec(any::<u8>(), 0..6).prop_map(Value::Bytes).boxed(),
        DataType::Domain => vec(any::<u8>(), 1..6).prop_map(Value::Bytes).boxed(),
        DataType::Real32 => prop_oneof![
            any::<f32>().prop_filter("NaN is not equal to itself", |f| !f.is_nan()).prop_map(|f| Value::Real(f as f64)),
            (-1000i32..1000).prop_map(|i| Value::Real(i as f64 / 8.0)),
        ]
        .boxed(),
        DataType::Real64 => any::<f64>().prop_filter("NaN", |f| !f.is_nan()).prop_map(Value::Real).boxed(),
        _ => {
            let (lo, hi) = ty.int_range().unwrap_or((0, (1i128 << 48) - 1));
            let relative = ty.is_unsigned() || matches!(ty, DataType::Other(_));
            let int = (lo..=hi, radix()).prop_map(|(value, radix)| Value::Int { value, radix });
            if relative {
                prop_oneof![
                    3 => int,
                    1 => (-0x80i128..0x800, radix()).prop_map(|(offset, radix)| Value::NodeIdPlus { offset, radix }),
                ]
                .boxed()
            } else {
                int.boxed()
            }
        }
    }
}

fn access() -> impl Strategy<Value = Access> {
    proptest::sample::select(vec![Access::Ro, Access::Wo, Access::Rw, Access::Rwr, Access::Rww, Access::Const])
}

fn entry(sub: u8, with_parameter_value: bool) -> impl Strategy<Value = Entry> {
    (data_type(), name(), access(), any::<bool>()).prop_flat_map(move |(ty, name, access, pdo)| {
        let pv = if with_parameter_value { option::of(value(ty)).boxed() } else { Just(None).boxed() };
        (
            option::of(value(ty)),
            pv,
            option::of(value(ty)),
            option::of(value(ty)),
            option::of(0u32..4),
            option::of(name_text()),
            option::of(name_text()),
            option::of(name_text()),
            extra_keys(2),
        )
            .prop_map(move |(default, parameter_value, low, high, obj_flags, denotation, up, down, extra)| {
                let is_domain = ty == DataType::Domain;
                Entry {
                    sub: SubIndex(sub),
                    name: name.clone().into(),
                    data_type: ty,
                    access,
                    pdo_mapping: pdo,
                    default,
                    extras: Some(Box::new(EntryExtras {
                        parameter_value,
                        low_limit: low,
                        high_limit: high,
                        obj_flags,
                        denotation,
                        upload_file: if is_domain { up } else { None },
                        download_file: if is_domain { down } else { None },
                        extra,
                    })),
                    at: SourceRef::default(),
                }
            })
    })
}

fn name_text() -> impl Strategy<Value = String> {
    name()
}

fn object(index: u16, dcf: bool) -> impl Strategy<Value = Object> {
    let category = match index {
        0x1000 | 0x1001 | 0x1018 => Just(Category::Mandatory).boxed(),
        0x2000..=0x5FFF => Just(Category::Manufacturer).boxed(),
        _ => Just(Category::Optional).boxed(),
    };
    let kind = prop_oneof![4 => Just(ObjectType::Var), 1 => Just(ObjectType::Domain), 2 => Just(ObjectType::Array), 2 => Just(ObjectType::Record)];
    (kind, category, name(), vec(0x1000u16..0x6FFF, 0..3), option::of(0u32..4), extra_keys(2)).prop_flat_map(
        move |(object_type, category, name, links, obj_flags, extra)| {
            let subs: BoxedStrategy<SubMap> = if object_type.has_subs() {
                btree_set(1u8..=0x30, 0..5)
                    .prop_flat_map(move |set| {
                        let mut subs: Vec<BoxedStrategy<Entry>> = vec![entry(0, dcf).boxed()];
                        subs.extend(set.into_iter().map(|s| entry(s, dcf).boxed()));
                        subs
                    })
                    .prop_map(|entries| entries.into_iter().map(|e| (e.sub, e)).collect())
                    .boxed()
            } else {
                let name = name.clone();
                entry(0, dcf)
                    .prop_map(move |mut e| {
                        e.name = name.clone().into();
                        if object_type == ObjectType::Domain {
                            e.data_type = DataType::Domain;
                            e.default = None;
                            e.set_parameter_value(None);
                            e.extras_mut().low_limit = None;
                            e.extras_mut().high_limit = None;
                        }
                        SubMap::from([(SubIndex(0), e)])
                    })
                    .boxed()
            };
            let (name, links, extra) = (name.clone(), links.clone(), extra.clone());
            subs.prop_map(move |subs| Object {
                index: Index(index),
                name: name.clone().into(),
                object_type,
                category,
                subs,
                compact_sub_obj: None,
                object_links: links.iter().map(|&i| Index(i)).collect(),
                // A VAR's section is its entry: flags and unknown keys belong to the entry.
                obj_flags: if object_type.has_subs() { obj_flags } else { None },
                extra: if object_type.has_subs() { extra.clone() } else { Vec::new() },
                at: SourceRef::default(),
            })
        },
    )
}

/// A compact ARRAY (`CompactSubObj=N`) in exactly the shape the reader expands it to.
fn compact_object(index: u16, dcf: bool) -> impl Strategy<Value = Object> {
    (entry(1, false), name(), 0u8..6, option::of(0u32..4), extra_keys(2), vec(option::of(name()), 6)).prop_flat_map(
        move |(proto, obj_name, n, obj_flags, extra, names)| {
            let ty = proto.data_type;
            let pvs = if dcf { vec(option::of(value(ty)), 6).boxed() } else { Just(vec![None; 6]).boxed() };
            pvs.prop_map(move |pvs| {
                let mut subs = SubMap::new();
                let mut sub0 =
                    write_common::entry(0, "NrOfObjects", DataType::Unsigned8, Access::Ro, Some(Value::int(n as i128)));
                sub0.pdo_mapping = false;
                subs.insert(SubIndex(0), sub0);
                for s in 1..=n {
                    let mut e = proto.clone();
                    e.sub = SubIndex(s);
                    e.name = names[s as usize - 1].clone().unwrap_or_else(|| format!("{obj_name}{s}")).into();
                    e.set_parameter_value(pvs[s as usize - 1].clone());
                    let x = e.extras_mut();
                    x.obj_flags = obj_flags;
                    x.extra.clear();
                    subs.insert(SubIndex(s), e);
                }
                Object {
                    index: Index(index),
                    name: obj_name.clone().into(),
                    object_type: ObjectType::Array,
                    category: Category::Manufacturer,
                    subs,
                    compact_sub_obj: Some(n),
                    object_links: Vec::new(),
                    obj_flags,
                    extra: extra.clone(),
                    at: SourceRef::default(),
                }
            })
        },
    )
}

fn file_info() -> impl Strategy<Value = FileInfo> {
    (
        (option::of(name()), option::of(any::<u8>().prop_map(u32::from)), option::of(any::<u8>().prop_map(u32::from))),
        (option::of(Just("4.0".to_owned())), option::of(name()), option::of(name()), option::of(name())),
        (option::of(name()), option::of(name()), option::of(name()), option::of(name())),
        extra_keys(2),
    )
        .prop_map(
            |(
                (file_name, file_version, file_revision),
                (eds_version, description, ct, cd),
                (cb, mt, md, mb),
                extra,
            )| {
                FileInfo {
                    file_name,
                    file_version,
                    file_revision,
                    eds_version,
                    description,
                    creation_time: ct,
                    creation_date: cd,
                    created_by: cb,
                    modification_time: mt,
                    modification_date: md,
                    modified_by: mb,
                    extra,
                }
            },
        )
}

fn device_info() -> impl Strategy<Value = DeviceInfo> {
    (
        (option::of(name()), option::of(any::<u32>()), option::of(name()), option::of(any::<u32>())),
        (
            option::of(any::<u32>()),
            option::of(name()),
            btree_map(proptest::sample::select(eds::write::STANDARD_BAUD_RATES.to_vec()), any::<bool>(), 0..8),
        ),
        (option::of(any::<bool>()), option::of(any::<bool>()), option::of(0u8..=64), option::of(0u8..=1)),
        (
            option::of(any::<bool>()),
            option::of(0u16..=512),
            option::of(0u16..=512),
            option::of(any::<bool>()),
            option::of(0u8..=7),
        ),
        extra_keys(2),
    )
        .prop_map(
            |(
                (vn, vnum, pn, pnum),
                (rev, oc, baud_rates),
                (sbm, sbs, gran, dyn_ch),
                (gm, rx, tx, lss, cpdo),
                extra,
            )| {
                DeviceInfo {
                    vendor_name: vn,
                    vendor_number: vnum,
                    product_name: pn,
                    product_number: pnum,
                    revision_number: rev,
                    order_code: oc,
                    baud_rates,
                    simple_boot_up_master: sbm,
                    simple_boot_up_slave: sbs,
                    granularity: gran,
                    dynamic_channels_supported: dyn_ch,
                    group_messaging: gm,
                    nr_of_rx_pdo: rx,
                    nr_of_tx_pdo: tx,
                    lss_supported: lss,
                    compact_pdo: cpdo,
                    extra,
                }
            },
        )
}

fn commissioning() -> impl Strategy<Value = Commissioning> {
    (
        option::of(1u8..=127),
        option::of(name()),
        option::of(proptest::sample::select(eds::write::STANDARD_BAUD_RATES.to_vec())),
        option::of(0u32..1000),
        option::of(name()),
        option::of(any::<bool>()),
        option::of(any::<u32>()),
        extra_keys(2),
    )
        .prop_map(
            |(node_id, node_name, baudrate, net_number, network_name, canopen_manager, lss_serial_number, extra)| {
                Commissioning {
                    node_id,
                    node_name,
                    baudrate,
                    net_number,
                    network_name,
                    canopen_manager,
                    lss_serial_number,
                    extra,
                }
            },
        )
}

fn model() -> impl Strategy<Value = Model> {
    any::<bool>().prop_flat_map(|dcf| {
        let indices = btree_set(
            prop_oneof![
                Just(0x1000u16),
                Just(0x1001),
                Just(0x1018),
                0x1002u16..0x1FFF,
                0x2000u16..0x5FFF,
                0x6000u16..0x9FFF
            ],
            0..8,
        );
        (
            file_info(),
            device_info(),
            btree_map(1u16..=7, any::<bool>(), 0..=7),
            vec(text(), 0..3),
            if dcf { option::of(commissioning()).boxed() } else { Just(None).boxed() },
            indices.prop_flat_map(move |set| {
                set.into_iter()
                    .map(|i| {
                        if (0x2000..0x5FFF).contains(&i) && i % 3 == 0 {
                            compact_object(i, dcf).boxed()
                        } else {
                            object(i, dcf).boxed()
                        }
                    })
                    .collect::<Vec<_>>()
            }),
            btree_map("Extra[A-Z][a-z]{0,5}", extra_keys(3), 0..3),
        )
            .prop_map(move |(file_info, device_info, dummy_usage, comments, commissioning, objects, extra)| {
                Model {
                    kind: if dcf { FileKind::Dcf } else { FileKind::Eds },
                    file_info,
                    device_info,
                    dummy_usage,
                    comments,
                    commissioning,
                    objects: objects.into_iter().map(|o| (o.index, o)).collect(),
                    extra_sections: extra.into_iter().map(|(name, entries)| ExtraSection { name, entries }).collect(),
                }
            })
    })
}

fn file_name(m: &Model) -> &'static str {
    match m.kind {
        FileKind::Eds => "random.eds",
        FileKind::Dcf => "random.dcf",
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn written_models_read_back_identical(m in model()) {
        prop_assert!(eds::write::unrepresentable(&m).is_empty(), "{:?}", eds::write::unrepresentable(&m));
        let text = eds::write::write(&m);
        let back = eds::parse(file_name(&m), text.as_bytes(), &eds::Options::lenient());
        prop_assert_eq!(&back.model, &m, "written text:\n{}", text);
        // Canonical: writing the model read back gives the same bytes.
        prop_assert_eq!(eds::write::write(&back.model), text);
    }
}

#[test]
fn fixtures_read_back_identical() {
    for (name, m) in [("full.eds", write_common::full_eds()), ("full.dcf", write_common::full_dcf())] {
        let text = eds::write::write(&m);
        let back = eds::parse(name, text.as_bytes(), &eds::Options::lenient());
        assert_eq!(back.model, m, "{name}:\n{text}");
    }
}
