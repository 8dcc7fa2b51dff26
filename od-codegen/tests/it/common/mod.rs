//! Models built in code, for tests that must not depend on the EDS reader.
#![allow(dead_code)]

use eds::model::*;

/// An entry with the given properties and no limits.
pub fn entry(sub: u8, name: &str, dt: DataType, access: Access, default: Option<Value>, pdo: bool) -> Entry {
    Entry {
        sub: SubIndex(sub),
        name: name.into(),
        data_type: dt,
        access,
        pdo_mapping: pdo,
        default,
        extras: None,
        at: SourceRef::default(),
    }
}

/// A VAR object.
pub fn var(index: u16, name: &str, dt: DataType, access: Access, default: Option<Value>, pdo: bool) -> Object {
    object(index, name, ObjectType::Var, vec![entry(0, name, dt, access, default, pdo)])
}

/// An object of any type holding `entries`.
pub fn object(index: u16, name: &str, ot: ObjectType, entries: Vec<Entry>) -> Object {
    Object {
        index: Index(index),
        name: name.into(),
        object_type: ot,
        category: if index < 0x2000 { Category::Optional } else { Category::Manufacturer },
        subs: entries.into_iter().map(|e| (e.sub, e)).collect(),
        compact_sub_obj: None,
        object_links: Vec::new(),
        obj_flags: None,
        extra: Vec::new(),
        at: SourceRef::default(),
    }
}

/// A PDO mapping record at `index` with `entries` (`0xIIIISSLL`).
pub fn mapping(index: u16, entries: &[u32]) -> Object {
    let mut subs = vec![entry(
        0,
        "Number of mapped objects",
        DataType::Unsigned8,
        Access::Rw,
        Some(Value::int(entries.len() as i128)),
        false,
    )];
    for (i, e) in entries.iter().enumerate() {
        subs.push(entry(
            i as u8 + 1,
            &format!("Mapped object {}", i + 1),
            DataType::Unsigned32,
            Access::Rw,
            Some(Value::hex(*e as i128)),
            false,
        ));
    }
    object(index, "Mapping", ObjectType::Record, subs)
}

/// A model holding `objects`, byte granularity, no dummies.
pub fn model(objects: Vec<Object>) -> Model {
    let mut m = Model::default();
    m.device_info.product_name = Some("Test device".into());
    m.device_info.vendor_name = Some("Tests".into());
    m.device_info.granularity = Some(8);
    m.objects = objects.into_iter().map(|o| (o.index, o)).collect();
    m
}

/// Models built at random from the parts real files get wrong (a fixed seed per model).
pub mod random;

/// The workspace's root directory.
pub fn workspace_root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("od-codegen/ has a parent").to_path_buf()
}

/// The `.eds` and `.dcf` files in `dir` (any case), sorted; panics if `dir` cannot be read.
pub fn description_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
        })
        .collect();
    v.sort();
    v
}
