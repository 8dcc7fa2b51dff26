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

fn example() -> Vec<NodeDcf> {
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
