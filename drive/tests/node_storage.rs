//! Parameters saved with 1010h in a state directory: they survive a new process, a torn or
//! corrupt file is ignored with a warning, and 1011h deletes them.

use std::path::{Path, PathBuf};

use drive::node::{DefaultApp, DefaultApps, DeviceKind, Node, NodeConfig};
use drive::storage::FileStorage;
use od_bus::CanFrame;
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
    // One file for every area, no temporary left behind.
    let names: Vec<String> =
        std::fs::read_dir(&dir.0).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["drvi-node2.params"]);

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
fn a_corrupt_file_is_ignored_with_a_warning_and_every_area_starts_from_defaults() {
    let dir = TempDir::new("corrupt");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    let file = first.storage_mut().set_path();
    drop(first);
    let mut bytes = std::fs::read(&file).unwrap();
    let last = bytes.len() - 10;
    bytes[last] ^= 0x40; // inside the last record
    std::fs::write(&file, &bytes).unwrap();

    // The areas were saved together and are dropped together: no mix of saved and default.
    let mut second = drvi(&dir.0);
    assert_eq!(value(&second, 0x6083), 0);
    assert_eq!(value(&second, 0x1017), 0);
    let warnings = second.storage_mut().warnings();
    assert!(!warnings.is_empty());
    assert!(warnings.iter().all(|w| w.contains("checksum mismatch") && w.contains("defaults used")), "{warnings:?}");
}

#[test]
fn a_torn_file_is_ignored_with_a_warning() {
    let dir = TempDir::new("torn");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    let file = first.storage_mut().set_path();
    drop(first);
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();

    let mut second = drvi(&dir.0);
    assert_eq!(value(&second, 0x1017), 0);
    assert_eq!(value(&second, 0x6083), 0);
    let warnings = second.storage_mut().warnings();
    assert!(!warnings.is_empty() && warnings.iter().all(|w| w.contains("drvi-node2.params")), "{warnings:?}");
}

#[test]
fn restoring_defaults_deletes_the_images() {
    let dir = TempDir::new("restore");
    let mut first = drvi(&dir.0);
    configure_and_save(&mut first);
    // The devices have 1011h sub 1 only: every area. Nothing changes until the next reset.
    assert_eq!(sdo(&mut first, "602#231110016C6F6164"), "582#6011100100000000");
    for area in [Area::Communication, Area::Application, Area::Manufacturer] {
        assert_eq!(first.storage_mut().read_image(area), Ok(None), "{area:?}");
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
    // Node 2's file copied to node 3's name: refused (another device's parameters).
    std::fs::copy(dir.0.join("drvi-node2.params"), dir.0.join("drvi-node3.params")).unwrap();
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
    assert!(dir.0.join("akd-node7.params").is_file());
}

/// A DRVI like [`drvi`] whose storage calls `hook` at every step of a save.
fn drvi_with_hook(dir: &Path, hook: drive::storage::IoHook) -> Drvi {
    let storage =
        FileStorage::open(dir, "drvi-node2").unwrap().with_warning_sink(std::sync::Arc::new(|_| {})).with_io_hook(hook);
    let mut node = Node::new(generated::drvi::Dictionary::new(2), DefaultApp::new(), storage, NodeId::new(2).unwrap());
    node.poll(0, &mut |_| {});
    node
}

/// Writes 6083h (application area) = 1000 + g and 1017h (communication area) = 100 + g.
fn configure(node: &mut Drvi, g: u32) {
    let acc = (1000 + g).to_le_bytes();
    let request = format!("602#23836000{:02X}{:02X}{:02X}{:02X}", acc[0], acc[1], acc[2], acc[3]);
    assert_eq!(sdo(node, &request), "582#6083600000000000");
    let hb = (100 + g) as u16;
    let request = format!("602#2B171000{:02X}{:02X}0000", hb & 0xFF, hb >> 8);
    assert_eq!(sdo(node, &request), "582#6017100000000000");
}

/// The save generation the stored areas come from; panics on a mix of two saves.
fn generation(dir: &Path) -> u32 {
    let node = drvi(dir);
    let (acc, hb) = (value(&node, 0x6083), value(&node, 0x1017));
    assert_eq!(acc.checked_sub(1000), hb.checked_sub(100), "areas from different saves: 6083h={acc} 1017h={hb}");
    hb - 100
}

const STEPS: [drive::storage::IoStep; 5] = [
    drive::storage::IoStep::TempHalfWritten,
    drive::storage::IoStep::TempWritten,
    drive::storage::IoStep::TempSynced,
    drive::storage::IoStep::Renamed,
    drive::storage::IoStep::DirSynced,
];

#[test]
fn a_save_all_killed_at_any_step_leaves_every_area_from_one_save() {
    use std::sync::atomic::{AtomicBool, Ordering};
    for (n, &kill_at) in STEPS.iter().enumerate() {
        let dir = TempDir::new(&format!("kill-{n}"));
        let mut node = drvi(&dir.0);
        configure(&mut node, 1);
        assert_eq!(sdo(&mut node, "602#2310100173617665"), "582#6010100100000000");
        drop(node);
        assert_eq!(generation(&dir.0), 1);

        // The second save is killed at `kill_at`: a panic in the hook stops it there, with
        // nothing cleaned up, as SIGKILL would.
        let armed = std::sync::Arc::new(AtomicBool::new(false));
        let trigger = std::sync::Arc::clone(&armed);
        let hook: drive::storage::IoHook = std::sync::Arc::new(move |step| {
            if step == kill_at && trigger.load(Ordering::SeqCst) {
                std::panic::panic_any("killed");
            }
            Ok(())
        });
        let mut node = drvi_with_hook(&dir.0, hook);
        configure(&mut node, 2);
        armed.store(true, Ordering::SeqCst);
        let killed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            node.handle(&"602#2310100173617665".parse::<CanFrame>().unwrap(), 10);
        }));
        assert!(killed.is_err(), "the save reached {kill_at:?}");
        std::mem::forget(node); // a killed process runs no destructors

        // Before the rename the old save stands, from it on the new one: never a mix.
        let expected = if n >= 3 { 2 } else { 1 };
        assert_eq!(generation(&dir.0), expected, "killed at {kill_at:?}");
    }
}

#[test]
fn a_save_all_failing_at_any_step_aborts_and_keeps_the_previous_save() {
    for (n, &fail_at) in STEPS.iter().enumerate().take(4) {
        let dir = TempDir::new(&format!("fail-{n}"));
        let mut node = drvi(&dir.0);
        configure(&mut node, 1);
        assert_eq!(sdo(&mut node, "602#2310100173617665"), "582#6010100100000000");
        drop(node);
        let hook: drive::storage::IoHook =
            std::sync::Arc::new(
                move |step| if step == fail_at { Err(std::io::Error::other("disk full")) } else { Ok(()) },
            );
        let mut node = drvi_with_hook(&dir.0, hook);
        configure(&mut node, 2);
        assert_eq!(sdo(&mut node, "602#2310100173617665"), "582#8010100120000008", "failing at {fail_at:?}");
        drop(node);
        // A failure after the rename (the directory sync) cannot undo it; before it, nothing
        // changed.
        assert_eq!(generation(&dir.0), if n >= 3 { 2 } else { 1 }, "failing at {fail_at:?}");
        let leftovers: Vec<_> = std::fs::read_dir(&dir.0)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "tmp"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}

/// Saves `records` as the image of `area` alone, as od-runtime does for 1010h sub 2, 3 or 4
/// (no bundled device has those sub-indices).
fn save_one_area(storage: &mut FileStorage, area: Area, records: &[drive::storage::Record]) {
    use od_runtime::Storage;
    storage.begin_transaction().unwrap();
    storage.begin_save(area).unwrap();
    for r in records {
        storage.save_entry(r.index, r.sub, &r.data).unwrap();
    }
    storage.end_save(area).unwrap();
    storage.end_transaction(true).unwrap();
}

#[test]
fn a_save_of_one_area_replaces_that_area_only() {
    use drive::storage::Record;
    let dir = TempDir::new("one-area");
    let mut node = drvi(&dir.0);
    configure(&mut node, 1);
    assert_eq!(sdo(&mut node, "602#2310100173617665"), "582#6010100100000000");
    drop(node);
    let mut storage = FileStorage::open(&dir.0, "drvi-node2").unwrap();
    let app = [Record { index: 0x6083, sub: 0, data: 1002u32.to_le_bytes().to_vec() }];
    save_one_area(&mut storage, Area::Application, &app);
    assert_eq!(storage.read_image(Area::Application), Ok(Some(app.to_vec())));
    let node = drvi(&dir.0);
    assert_eq!((value(&node, 0x6083), value(&node, 0x1017)), (1002, 101));
}

#[test]
fn per_area_files_of_earlier_releases_are_read_and_replaced_by_the_first_save() {
    use drive::storage::{Record, encode_image};
    let dir = TempDir::new("legacy");
    std::fs::create_dir_all(&dir.0).unwrap();
    let comm = [Record { index: 0x1017, sub: 0, data: vec![0x65, 0x00] }];
    let app = [Record { index: 0x6083, sub: 0, data: 1001u32.to_le_bytes().to_vec() }];
    std::fs::write(dir.0.join("drvi-node2.comm.params"), encode_image(Area::Communication, "drvi-node2", &comm))
        .unwrap();
    std::fs::write(dir.0.join("drvi-node2.app.params"), encode_image(Area::Application, "drvi-node2", &app)).unwrap();
    assert_eq!(generation(&dir.0), 1);

    // Saving the application area keeps the communication area of the old files.
    let mut storage = FileStorage::open(&dir.0, "drvi-node2").unwrap();
    let app = [Record { index: 0x6083, sub: 0, data: 1002u32.to_le_bytes().to_vec() }];
    save_one_area(&mut storage, Area::Application, &app);
    let names: Vec<String> =
        std::fs::read_dir(&dir.0).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["drvi-node2.params"]);
    let node = drvi(&dir.0);
    assert_eq!((value(&node, 0x6083), value(&node, 0x1017)), (1002, 101));
}
