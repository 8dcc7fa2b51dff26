//! The generated client (`Builder::client`) of the three devices, as snapshots: the
//! `pub mod remote` each device module ends with (the rest of the module is the device side,
//! snapshotted and checked in elsewhere).

use od_codegen::Builder;

use crate::common::workspace_root;

/// The `remote` module of `file`'s generated code (with its sidecar), from its doc comment to
/// its closing brace.
fn client_of(module: &str, file: &str) -> String {
    let out = Builder::new()
        .cargo_metadata(false)
        .strict()
        .client(true)
        .device(module, workspace_root().join("devices").join(file))
        .generate()
        .unwrap_or_else(|e| panic!("{file}: {e}"));
    let text = &out[0].text;
    let start = text.find("    /// The ").and_then(|_| text.find("\n    pub mod remote {")).expect("a remote module");
    // Back to the start of its doc comment.
    let doc_start = text[..start].rfind("\n    /// The ").expect("the module's doc") + 1;
    let end = text.rfind("\n}").expect("the device module's end");
    text[doc_start..end].to_owned()
}

#[test]
fn client_snapshots_of_the_three_devices() {
    for (m, file) in [("drvi", "camozzi-drvi.eds"), ("drcs", "camozzi-drcs.eds"), ("akd", "kollmorgen-akd.eds")] {
        let text = client_of(m, file);
        // Every entry method names its object and sub-index in its doc comment.
        assert!(text.contains("/// `0x6041` Statusword: UNSIGNED16, `ro`."), "{m}");
        insta::assert_snapshot!(format!("client_{m}"), text);
    }
}

#[test]
fn the_client_is_only_there_when_asked_for() {
    let out = Builder::new()
        .cargo_metadata(false)
        .device("drvi", workspace_root().join("devices/camozzi-drvi.eds"))
        .generate()
        .unwrap();
    assert!(!out[0].text.contains("pub mod remote"));
    assert!(!out[0].text.contains("od_master"));
}
