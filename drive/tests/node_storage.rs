//! Parameters saved with 1010h in a state directory: they survive a new process, a torn or
//! corrupt file is ignored with a warning, and 1011h deletes them.

use std::path::{Path, PathBuf};

use drive::node::{DefaultApp, DefaultApps, DeviceKind, Node, NodeConfig};
use drive::storage::FileStorage;
use drive::transport::CanFrame;
use od_runtime::NodeId;
use od_runtime::od::{Area, ObjectDictionary};

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let path = std::env::temp_dir().join(format!("drive-node-storage-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        Self(path)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

type Drvi = Node<generated::drvi::Dictionary, DefaultApp, FileStorage>;

/// A DRVI (node 2) whose 1010h saves go to `dir`, started at time 0.
fn drvi(dir: &Path) -> Drvi {
    let storage = FileStorage::open(dir, "drvi-node2").unwrap().with_warning_sink(std::sync::Arc::new(|_| {}));
    let mut node = Node::new(generated::drvi::Dictionary::new(2), DefaultApp::new(), storage, NodeId::new(2).unwrap());
    let mut sent = Vec::new();
    node.poll(0, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent, ["702#00"]);
    node
}

/// One request, one response.
fn sdo(node: &mut Drvi, request: &str) -> String {
    node.handle(&request.parse::<CanFrame>().unwrap(), 10);
    let mut sent = Vec::new();
    node.poll(10, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent.len(), 1, "{sent:?}");
    sent.remove(0)
}

fn value(node: &Drvi, index: u16) -> u32 {
    let mut b = [0u8; 8];
    let n = node.od().read(index, 0, &mut b).unwrap();
    let mut v = [0u8; 4];
    v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
    u32::from_le_bytes(v)
}

/// Writes 6083h = 1234 and 1017h = 100, saves everything.
fn configure_and_save(node: &mut Drvi) {
    assert_eq!(sdo(node, "602#23836000D2040000"), "582#6083600000000000");
    assert_eq!(sdo(node, "602#2B17100064000000"), "582#6017100000000000");
    assert_eq!(sdo(node, "602#2310100173617665"), "582#6010100100000000");
}

#[test]
fn saved_parameters_survive_a_new_process() {
    let dir = TempDir::new("survive");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    drop(first);
    // Files per area, no temporary left behind.
    let mut names: Vec<String> =
        std::fs::read_dir(&dir.0).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["drvi-node2.app.params", "drvi-node2.comm.params", "drvi-node2.mfr.params"]);

    let mut second = drvi(&dir.0);
    assert_eq!(value(&second, 0x6083), 1234);
    assert_eq!(value(&second, 0x1017), 100);
    // The restored heartbeat runs.
    let mut sent = Vec::new();
    second.poll(100_000, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent, ["702#7F"]);
    assert!(second.storage_mut().warnings().is_empty());
}

#[test]
fn a_corrupt_area_is_ignored_with_a_warning_and_the_others_load() {
    let dir = TempDir::new("corrupt");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    let app_file = first.storage_mut().path(Area::Application);
    drop(first);
    let mut bytes = std::fs::read(&app_file).unwrap();
    let last = bytes.len() - 6;
    bytes[last] ^= 0x40; // inside the last record
    std::fs::write(&app_file, &bytes).unwrap();

    let mut second = drvi(&dir.0);
    assert_eq!(value(&second, 0x6083), 0, "the application area falls back to its defaults");
    assert_eq!(value(&second, 0x1017), 100, "the communication area still loads");
    let warnings = second.storage_mut().warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("checksum mismatch") && warnings[0].contains("defaults used"), "{warnings:?}");
}

#[test]
fn a_torn_file_is_ignored_with_a_warning() {
    let dir = TempDir::new("torn");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    let comm_file = first.storage_mut().path(Area::Communication);
    drop(first);
    let bytes = std::fs::read(&comm_file).unwrap();
    std::fs::write(&comm_file, &bytes[..bytes.len() / 2]).unwrap();

    let mut second = drvi(&dir.0);
    assert_eq!(value(&second, 0x1017), 0);
    assert_eq!(value(&second, 0x6083), 1234);
    let warnings = second.storage_mut().warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("drvi-node2.comm.params"), "{warnings:?}");
}

#[test]
fn restoring_defaults_deletes_the_images() {
    let dir = TempDir::new("restore");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    // The devices have 1011h sub 1 only: every area. Nothing changes until the next reset.
    assert_eq!(sdo(&mut first, "602#231110016C6F6164"), "582#6011100100000000");
    for area in [Area::Communication, Area::Application, Area::Manufacturer] {
        assert!(!first.storage_mut().path(area).exists(), "{area:?}");
    }
    assert_eq!(value(&first, 0x6083), 1234);
    drop(first);
    let second = drvi(&dir.0);
    assert_eq!(value(&second, 0x6083), 0);
    assert_eq!(value(&second, 0x1017), 0);
}

#[test]
fn a_failing_save_aborts_with_0800_0020_and_warns() {
    let dir = TempDir::new("fail");
    let mut node = drvi(&dir.0);
    // The directory disappears and a file takes its name: the save cannot write.
    std::fs::remove_dir_all(&dir.0).unwrap();
    std::fs::write(&dir.0, b"not a directory").unwrap();
    assert_eq!(sdo(&mut node, "602#2310100173617665"), "582#8010100120000008");
    let warnings = node.storage_mut().warnings();
    assert!(warnings.iter().any(|w| w.contains("cannot save")), "{warnings:?}");
    std::fs::remove_file(&dir.0).unwrap();
}

#[test]
fn leftover_temporary_files_are_removed_and_foreign_images_refused() {
    let dir = TempDir::new("leftover");
    std::fs::create_dir_all(&dir.0).unwrap();
    let tmp = dir.0.join("drvi-node2.app.params.tmp");
    std::fs::write(&tmp, b"half a save").unwrap();
    let mut first = drvi(&dir.0);
    assert!(!tmp.exists());
    configure_and_save(&mut first);
    drop(first);
    // Node 2's image copied to node 3's name: refused (another device's parameters).
    std::fs::copy(dir.0.join("drvi-node2.app.params"), dir.0.join("drvi-node3.app.params")).unwrap();
    let mut storage = FileStorage::open(&dir.0, "drvi-node3").unwrap().with_warning_sink(std::sync::Arc::new(|_| {}));
    let err = storage.read_image(Area::Application).unwrap_err();
    assert!(err.contains("'drvi-node2'"), "{err}");
    let mut seen = 0;
    od_runtime::Storage::load(&mut storage, Area::Application, &mut |_, _, _| seen += 1);
    assert_eq!(seen, 0);
}

#[test]
fn drive_sim_nodes_name_their_files_by_kind_and_node_id() {
    let dir = TempDir::new("kinds");
    let config = NodeConfig { node_id: Some(7), state_dir: Some(dir.0.clone()), ..NodeConfig::default() };
    let mut node = DeviceKind::Akd.build(&config, &DefaultApps).unwrap();
    let mut sent: Vec<String> = Vec::new();
    node.poll(0, &mut |f| sent.push(f.to_string()));
    node.handle(&"607#2310100173617665".parse().unwrap(), 1);
    sent.clear();
    node.poll(1, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent, ["587#6010100100000000"]);
    for area in ["comm", "app", "mfr"] {
        assert!(dir.0.join(format!("akd-node7.{area}.params")).is_file(), "{area}");
    }
}
