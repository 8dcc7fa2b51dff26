//! The writes that boot a node (`od_codegen::network::concise`): the example network's set,
//! pinned after comparing it with Lely's `dcfgen` (`scripts/dcfgen-compare.py`), and the rules
//! every plan keeps: applied to a device at its defaults it leaves every configured value in
//! place, and every PDO is disabled while its mapping changes (CiA 301).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use od_codegen::network::concise::{Plan, Role, plan};
use od_codegen::network::{self, NodeDcf};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn example() -> &'static [NodeDcf] {
    static DCFS: std::sync::OnceLock<Vec<NodeDcf>> = std::sync::OnceLock::new();
    DCFS.get_or_init(build_example)
}

fn build_example() -> Vec<NodeDcf> {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let o = network::build("networks/example.toml", &repo().join("networks"), &text);
    assert!(!o.has_errors(), "{}", network::render_all(&o.diagnostics));
    o.dcfs
}

fn render(name: &str, node_id: u8, plan: &Plan) -> String {
    let mut s = format!("{name} (node {node_id}): identity {:08X?}\n", plan.identity.checks().map(|c| c.3));
    for w in &plan.writes {
        let hex: Vec<String> = w.data.iter().map(|b| format!("{b:02X}")).collect();
        writeln!(s, "  {:04X}h sub {:<3} = {:<12} {:?}", w.index, w.sub, hex.join(" "), w.role).unwrap();
    }
    s
}

#[test]
fn example_network_writes() {
    let mut out = String::new();
    for dcf in example() {
        let p = plan(&dcf.model, dcf.node_id).unwrap();
        out.push_str(&render(&dcf.name, dcf.node_id, &p));
    }
    insta::assert_snapshot!(out);
}

/// A device at its defaults that refuses what CiA 301 refuses while a PDO runs: a mapping
/// entry written while the PDO is valid or its count is not 0, a count while the PDO is valid,
/// and a new CAN-ID in a valid COB-ID.
struct Device {
    values: BTreeMap<(u16, u8), Vec<u8>>,
}

impl Device {
    fn at_defaults(model: &eds::Model, node_id: u8) -> Self {
        let mut values = BTreeMap::new();
        for obj in model.objects.values() {
            for e in obj.subs.values() {
                if let Some(b) =
                    e.default.as_ref().and_then(|v| od_codegen::network::concise::encode(v, e.data_type, node_id).ok())
                {
                    values.insert((obj.index.0, e.sub.0), b);
                }
            }
        }
        Self { values }
    }

    fn u32(&self, index: u16, sub: u8) -> u32 {
        let b = self.values.get(&(index, sub)).cloned().unwrap_or_default();
        let mut le = [0u8; 4];
        le[..b.len().min(4)].copy_from_slice(&b[..b.len().min(4)]);
        u32::from_le_bytes(le)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), String> {
        let pdo_comm = |i: u16| (0x1400..=0x15FF).contains(&i) || (0x1800..=0x19FF).contains(&i);
        let pdo_map = |i: u16| (0x1600..=0x17FF).contains(&i) || (0x1A00..=0x1BFF).contains(&i);
        if pdo_map(index) {
            let valid = self.u32(index - 0x200, 1) & 0x8000_0000 == 0;
            if valid {
                return Err(format!("{index:04X}h sub {sub} written while the PDO is valid"));
            }
            if sub > 0 && self.u32(index, 0) != 0 {
                return Err(format!("{index:04X}h sub {sub} written while the mapping count is not 0"));
            }
        }
        if pdo_comm(index) && sub == 1 {
            let old = self.u32(index, 1);
            let new = u32::from_le_bytes(data.try_into().unwrap());
            if old & 0x8000_0000 == 0 && new & 0x8000_0000 == 0 && old != new {
                return Err(format!("{index:04X}h: CAN-ID changed while the PDO is valid"));
            }
        }
        self.values.insert((index, sub), data.to_vec());
        Ok(())
    }
}

/// `model` with the configured values of the entries `keep` says no to taken away.
fn some_configured(model: &eds::Model, keep: &[bool]) -> eds::Model {
    let mut m = model.clone();
    let mut i = 0;
    for obj in m.objects.values_mut() {
        for e in obj.subs.values_mut() {
            if e.parameter_value().is_some() && e.access.writable() {
                if !keep[i % keep.len()] {
                    e.set_parameter_value(None);
                }
                i += 1;
            }
        }
    }
    m
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 64, ..Default::default() })]

    /// Any subset of the example's configuration: applied to a device at its defaults, the
    /// plan passes CiA 301's PDO rules (also when applied again, as a second boot does) and
    /// leaves every configured value in place, and it writes no parameter that is already the
    /// default.
    #[test]
    fn a_plan_configures_a_device_at_its_defaults(keep in proptest::collection::vec(proptest::bool::ANY, 1..64)) {
        for dcf in example() {
            let model = some_configured(&dcf.model, &keep);
            let p = plan(&model, dcf.node_id).unwrap();
            let mut device = Device::at_defaults(&model, dcf.node_id);
            for w in &p.writes {
                if w.role == Role::Parameter {
                    proptest::prop_assert_ne!(device.values.get(&(w.index, w.sub)), Some(&w.data));
                }
                device.write(w.index, w.sub, &w.data).map_err(proptest::test_runner::TestCaseError::fail)?;
            }
            // A second boot (the node keeps the first one's configuration) passes the same
            // rules: every PDO it touches is disabled first, whatever its default.
            for w in &p.writes {
                device.write(w.index, w.sub, &w.data).map_err(|e| proptest::test_runner::TestCaseError::fail(format!("second boot: {e}")))?;
            }
            for obj in model.objects.values() {
                for e in obj.subs.values() {
                    if let (Some(pv), true) = (e.parameter_value(), e.access.writable()) {
                        let want = od_codegen::network::concise::encode(pv, e.data_type, dcf.node_id).unwrap();
                        proptest::prop_assert_eq!(
                            device.values.get(&(obj.index.0, e.sub.0)), Some(&want),
                            "{}: {:04X}h sub {}", dcf.name, obj.index.0, e.sub.0
                        );
                    }
                }
            }
        }
    }
}
