//! Events (boot-up, heartbeat lost and recovered, never seen, NMT state, EMCY with the
//! sidecar's text), SYNC, and PDOs mapped at run time, on the simulated drives.

use std::time::Duration;

use drive::drives::sidecar;
use drive::node::DeviceKind;
use od_bus::tokio::Bus as Link;
use od_master::{EmcyTexts, Event, NmtState, NodeEvent, PdoField, PdoMapping, PdoValue, Watch};
use od_runtime::od::DataType;
use od_runtime::pdo::{Direction, MapEntry};
use tokio::sync::broadcast;
use tokio::time::Instant;

use crate::harness::{net, pass};

/// Every event received so far.
fn drain(events: &mut broadcast::Receiver<Event>) -> Vec<Event> {
    let mut out = Vec::new();
    while let Ok(e) = events.try_recv() {
        out.push(e);
    }
    out
}

/// Waits (virtual time, at most `limit`) for the first event `pick` accepts.
async fn wait_for<T>(
    events: &mut broadcast::Receiver<Event>,
    limit: Duration,
    mut pick: impl FnMut(&Event) -> Option<T>,
) -> Option<T> {
    let end = Instant::now() + limit;
    loop {
        let e = tokio::time::timeout_at(end, events.recv()).await.ok()?.ok()?;
        if let Some(t) = pick(&e) {
            return Some(t);
        }
    }
}

#[tokio::test(start_paused = true)]
async fn boot_up_heartbeat_state_changes_loss_and_recovery_are_reported() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    let mut events = n.bus.events();
    pass(Duration::from_millis(5)).await;
    let boot: Vec<_> = drain(&mut events).into_iter().collect();
    for id in [2, 3, 4] {
        assert!(boot.contains(&Event::Node(NodeEvent::BootUp { node: id })), "{boot:?}");
    }
    // Heartbeats of node 2 every 100 ms, watched with a 250 ms consumer time.
    let drive = n.bus.node(2).unwrap();
    drive.write_idempotent(0x1017, 0, 100u16).await.unwrap();
    n.bus.watch(2, Watch::Heartbeat { timeout: 250_000 }, None).await.unwrap();
    let first = wait_for(&mut events, Duration::from_millis(150), |e| match e {
        Event::Node(NodeEvent::FirstSeen { node: 2, state }) => Some(*state),
        _ => None,
    });
    assert_eq!(first.await, Some(NmtState::PreOperational));
    drive.start().await.unwrap();
    let changed = wait_for(&mut events, Duration::from_millis(150), |e| match e {
        Event::Node(NodeEvent::StateChanged { node: 2, from, to }) => Some((*from, *to)),
        _ => None,
    });
    assert_eq!(changed.await, Some((NmtState::PreOperational, NmtState::Operational)));
    // The heartbeat stops: lost within the consumer time of the last one.
    drive.write_idempotent(0x1017, 0, 0u16).await.unwrap();
    let t0 = Instant::now();
    let lost = wait_for(&mut events, Duration::from_millis(400), |e| {
        (*e == Event::Node(NodeEvent::Lost { node: 2 })).then_some(())
    });
    assert_eq!(lost.await, Some(()));
    assert!(t0.elapsed() <= Duration::from_millis(251), "{:?}", t0.elapsed());
    drive.write_idempotent(0x1017, 0, 100u16).await.unwrap();
    let back = wait_for(&mut events, Duration::from_millis(150), |e| match e {
        Event::Node(NodeEvent::Recovered { node: 2, state }) => Some(*state),
        _ => None,
    });
    assert_eq!(back.await, Some(NmtState::Operational));
}

#[tokio::test(start_paused = true)]
async fn a_node_never_heard_from_is_reported_at_its_boot_timeout_not_as_lost() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    let mut events = n.bus.events();
    n.bus.watch(9, Watch::Heartbeat { timeout: 100_000 }, Some(Duration::from_millis(500))).await.unwrap();
    let t0 = Instant::now();
    let e = wait_for(&mut events, Duration::from_secs(2), |e| match e {
        Event::Node(NodeEvent::NeverSeen { node }) | Event::Node(NodeEvent::Lost { node }) if *node == 9 => {
            Some(e.clone())
        }
        _ => None,
    });
    assert_eq!(e.await, Some(Event::Node(NodeEvent::NeverSeen { node: 9 })));
    assert_eq!(t0.elapsed(), Duration::from_millis(500));
    pass(Duration::from_secs(1)).await;
    assert!(!drain(&mut events).iter().any(|e| matches!(e, Event::Node(NodeEvent::Lost { node: 9 }))));
}

/// The DRCS refuses to move before homing with EMCY FF13h; the event carries code, register,
/// manufacturer bytes and the text of the DRCS's sidecar.
#[tokio::test(start_paused = true)]
async fn an_emcy_carries_its_code_register_bytes_and_the_sidecars_text() {
    let n = net(&[(DeviceKind::Drcs, 3)]);
    let mut events = n.bus.events();
    n.bus.set_emcy_texts(3, EmcyTexts::from_sidecar(sidecar(DeviceKind::Drcs).unwrap())).await.unwrap();
    pass(Duration::from_millis(5)).await;
    let axis = od_master::Axis::new(n.bus.node(3).unwrap());
    axis.enable().await.unwrap();
    axis.set_mode(1).await.unwrap();
    let drive = axis.node();
    drive.write(0x6081, 0, 50u32).await.unwrap();
    drive.write(0x607A, 0, 100i32).await.unwrap();
    drive.write(0x6040, 0, 0x1Fu16).await.unwrap();
    drive.write(0x6040, 0, 0x0Fu16).await.unwrap();
    let emcy = wait_for(&mut events, Duration::from_millis(500), |e| match e {
        Event::Emergency { emcy, text } => Some((*emcy, text.clone())),
        _ => None,
    });
    let (emcy, text) = emcy.await.expect("an EMCY");
    assert_eq!((emcy.node, emcy.code, emcy.register, emcy.vendor), (3, 0xFF13, 0x01, [0; 5]));
    assert_eq!(text.as_deref(), Some("Operation without reset"));
}

/// SYNC every 10 ms: ten frames in 100 ms on 080h, counted by `syncs`; with a counter they
/// carry 1, 2, ..., overflow, 1, ...
#[tokio::test(start_paused = true)]
async fn sync_goes_out_every_period_with_its_counter() {
    let n = net(&[]);
    let mut listener = Link::attach(n.sim.lock().unwrap().bus());
    let syncs = n.bus.syncs();
    n.bus.start_sync(Duration::from_millis(10), 3).await.unwrap();
    pass(Duration::from_millis(95)).await;
    n.bus.stop_sync().await.unwrap();
    pass(Duration::from_millis(50)).await;
    let mut got = Vec::new();
    while let Ok(Ok(f)) = tokio::time::timeout(Duration::ZERO, listener.recv()).await {
        got.push(f.to_string());
    }
    assert_eq!(
        got,
        ["080#01", "080#02", "080#03", "080#01", "080#02", "080#03", "080#01", "080#02", "080#03", "080#01"]
    );
    assert_eq!(*syncs.borrow(), 10);
    assert!(
        matches!(n.bus.start_sync(Duration::from_millis(10), 1).await, Err(od_master::Error::SyncCounter(1))),
        "1019h = 1 is reserved"
    );
}

/// A TPDO mapped at run time (statusword and position actual value, on every SYNC) arrives
/// decoded; its values are what SDO reads of the same objects give.
#[tokio::test(start_paused = true)]
async fn a_tpdo_mapped_at_run_time_is_received_decoded() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(2)).await;
    let drive = n.bus.node(2).unwrap();
    drive.write(0x1800, 1, 0x8000_0182u32).await.unwrap();
    drive.write(0x1A00, 0, 0u8).await.unwrap();
    drive.write(0x1A00, 1, 0x6041_0010u32).await.unwrap();
    drive.write(0x1A00, 2, 0x6064_0020u32).await.unwrap();
    drive.write(0x1A00, 0, 2u8).await.unwrap();
    drive.write(0x1800, 2, 1u8).await.unwrap();
    drive.write(0x1800, 1, 0x182u32).await.unwrap();
    let fields = [
        PdoField { entry: MapEntry { index: 0x6041, sub: 0, bits: 16 }, data_type: DataType::Unsigned16 },
        PdoField { entry: MapEntry { index: 0x6064, sub: 0, bits: 32 }, data_type: DataType::Integer32 },
    ];
    let mapping = PdoMapping::from_fields(Direction::Transmit, &fields).unwrap();
    let mut tpdos = n.bus.tpdo(0x182, mapping, 16).await.unwrap();
    drive.start().await.unwrap();
    n.bus.start_sync(Duration::from_millis(10), 0).await.unwrap();
    let mut received = 0;
    for _ in 0..5 {
        let t = tokio::time::timeout(Duration::from_millis(20), tpdos.recv()).await.unwrap().unwrap();
        assert_eq!(t.cob_id, 0x182);
        let sw = drive.read::<u16>(0x6041, 0).await.unwrap();
        let pos = drive.read::<i32>(0x6064, 0).await.unwrap();
        assert_eq!(t.values, [PdoValue::Unsigned(u64::from(sw)), PdoValue::Signed(i64::from(pos))]);
        received += 1;
    }
    assert_eq!(received, 5);
}
