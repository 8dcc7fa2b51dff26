//! SDO transfers against the simulated drives: values, concurrency, aborts.

use std::time::Duration;

use drive::node::{DeviceKind, Sim};
use od_master::{Error, Mode, SdoOptions};
use od_runtime::master::SdoError;
use od_runtime::od::Access;
use tokio::time::Instant;

use crate::harness::{net, node, pass};

/// Every readable object of each device reads the same through od-master (normal and block
/// transfers) as the device itself answers it (`Node::upload`: its application's answer or
/// its dictionary's value) on a twin simulation kept at the same virtual time: the value, or
/// the same abort code.
#[tokio::test(start_paused = true)]
async fn every_readable_object_reads_as_the_device_answers_it() {
    for kind in DeviceKind::ALL {
        let n = net(&[(kind, 2)]);
        pass(Duration::from_millis(1)).await;
        let mut twin = Sim::new();
        twin.add(node(kind, 2));
        twin.advance(1000);
        let drive = n.bus.node(2).unwrap().with_retries(0);
        let block = drive.clone().with_options(SdoOptions { mode: Mode::Block, retries: 0, ..SdoOptions::default() });
        let mut compared = 0;
        for e in kind.entries().iter().filter(|e| e.access != Access::Wo) {
            // Counters of time (the DRCS's 2100h..) read the same at the same virtual time.
            let now = n.sim.lock().unwrap().now();
            twin.advance(now.saturating_sub(twin.now()));
            let want = twin.node_mut(0).upload(e.index, e.sub);
            for (how, got) in
                [("normal", drive.read_bytes(e.index, e.sub).await), ("block", block.read_bytes(e.index, e.sub).await)]
            {
                match (&want, got) {
                    (Ok(w), Ok(g)) => assert_eq!(w, &g, "{kind:?} {:04X}h sub {} ({how})", e.index, e.sub),
                    (Err(w), Err(Error::Sdo { error, attempts: 1, .. })) => {
                        assert_eq!(error.error, SdoError::Server(*w), "{kind:?} {:04X}h sub {} ({how})", e.index, e.sub)
                    }
                    (w, g) => {
                        panic!("{kind:?} {:04X}h sub {} ({how}): the device {w:?}, od-master {g:?}", e.index, e.sub)
                    }
                }
            }
            compared += 1;
        }
        assert!(compared > 50, "{kind:?}: {compared} objects");
    }
}

/// Transfers to three nodes overlap: twenty reads of each node's device name take about as
/// long at once as the twenty of one node alone.
#[tokio::test(start_paused = true)]
async fn transfers_to_three_nodes_run_at_once() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(1)).await;
    let reads = |id: u8| {
        let node = n.bus.node(id).unwrap();
        async move {
            let mut names = Vec::new();
            for _ in 0..20 {
                names.push(node.read_string(0x1008, 0).await.unwrap());
            }
            names
        }
    };
    let t0 = Instant::now();
    let alone = reads(4).await;
    let one = t0.elapsed();
    let t0 = Instant::now();
    let (a, b, c) = tokio::join!(reads(2), reads(3), reads(4));
    let three = t0.elapsed();
    assert_eq!(c, alone);
    for names in [&a, &b, &c] {
        assert!(names.iter().all(|s| s == &names[0] && !s.is_empty()));
    }
    assert!(three < one * 3 / 2, "three nodes at once took {three:?}, one node {one:?}");
}

/// Calls to one node from many tasks queue on its SDO channel; each gets its own object's
/// value, the one a call made alone gets.
#[tokio::test(start_paused = true)]
async fn calls_to_one_node_queue_and_each_gets_its_own_answer() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(1)).await;
    let drive = n.bus.node(2).unwrap();
    let objects =
        [(0x1000, 0), (0x1008, 0), (0x1018, 1), (0x1018, 2), (0x6041, 0), (0x6060, 0), (0x1017, 0), (0x1009, 0)];
    let mut alone = Vec::new();
    for (i, s) in objects {
        alone.push(drive.read_bytes(i, s).await.unwrap());
    }
    let tasks: Vec<_> = (0..40)
        .map(|k| {
            let drive = drive.clone();
            let (i, s) = objects[k % objects.len()];
            tokio::spawn(async move { (k, drive.read_bytes(i, s).await.unwrap()) })
        })
        .collect();
    for t in tasks {
        let (k, value) = t.await.unwrap();
        assert_eq!(value, alone[k % objects.len()], "call {k}");
    }
}

/// Written values read back, expedited, segmented and block; typed reads check the length.
#[tokio::test(start_paused = true)]
async fn writes_read_back_and_typed_reads_check_the_length() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(1)).await;
    let drive = n.bus.node(2).unwrap();
    for (k, v) in [1u32, 77, 6000, 123_456].into_iter().enumerate() {
        let mode = [Mode::Normal, Mode::Segmented, Mode::Block, Mode::Normal][k];
        let d = drive.clone().with_options(SdoOptions { mode, ..SdoOptions::default() });
        d.write_idempotent(0x6083, 0, v).await.unwrap();
        assert_eq!(d.read::<u32>(0x6083, 0).await.unwrap(), v, "{mode:?}");
    }
    match drive.read::<u32>(0x6041, 0).await {
        Err(Error::Length { node: 2, index: 0x6041, sub: 0, expected: 4, got: 2 }) => {}
        other => panic!("{other:?}"),
    }
}

/// A server's abort ends the call at once with the node, the object and the CiA 301 name;
/// it is not retried.
#[tokio::test(start_paused = true)]
async fn a_server_abort_is_named_and_not_retried() {
    let n = net(&[(DeviceKind::Drcs, 3)]);
    pass(Duration::from_millis(1)).await;
    let drive = n.bus.node(3).unwrap();
    let t0 = Instant::now();
    let e = drive.read_bytes(0x2FFF, 7).await.unwrap_err();
    assert!(t0.elapsed() < Duration::from_millis(5));
    let Error::Sdo { error, attempts, .. } = &e else { panic!("{e:?}") };
    assert_eq!((error.node, error.index, error.sub, *attempts), (3, 0x2FFF, 7, 1));
    assert_eq!(
        e.to_string(),
        "node 3, upload of 2FFFh sub 7: aborted by the server: 0x06020000 (object does not exist in the object dictionary)"
    );
    let e = drive.write(0x1000, 0, 5u32).await.unwrap_err();
    assert!(
        e.to_string().contains(
            "download to 1000h sub 0: aborted by the server: 0x06010002 (attempt to write a read only object)"
        ),
        "{e}"
    );
}
