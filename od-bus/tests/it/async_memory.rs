//! The async memory bus (`od_bus::tokio::Bus` on `mem://`): the same bus as the blocking
//! endpoints, CAN broadcast semantics, halves in different tasks, bounded queues; on tokio's
//! virtual clock.

use std::time::Duration;

use od_bus::tokio::{Bus, LinkState};
use od_bus::{CanFrame, ControllerState, Endpoint, MemoryBus, TransportError};

fn frame(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

#[tokio::test(start_paused = true)]
async fn an_async_master_and_blocking_devices_share_a_named_bus() {
    let devices = MemoryBus::named("async-shared");
    let mut drive_a = devices.endpoint();
    let mut drive_b = devices.endpoint();
    let mut master = Bus::open("mem://async-shared").await.unwrap();
    assert_eq!(devices.endpoint_count(), 3);
    assert_eq!(*master.link().borrow(), LinkState::Up { reconnects: 0 });

    let nmt = frame(0x000, &[0x01, 0x00]);
    master.send(nmt).await.unwrap();
    assert_eq!(drive_a.try_recv().unwrap(), Some(nmt));
    assert_eq!(drive_b.try_recv().unwrap(), Some(nmt));

    let boot_a = frame(0x702, &[0x00]);
    let boot_b = CanFrame::extended(0x1234, &[0x7F]).unwrap();
    drive_a.send(boot_a).unwrap();
    drive_b.send(boot_b).unwrap();
    assert_eq!(master.recv().await.unwrap(), boot_a);
    assert_eq!(master.recv().await.unwrap(), boot_b);
    assert_eq!(drive_b.try_recv().unwrap(), Some(boot_a), "devices hear each other too");
    assert_eq!(drive_a.try_recv().unwrap(), Some(boot_b));
    assert_eq!(drive_a.try_recv().unwrap(), None, "a sender does not hear itself");

    drop(master);
    assert_eq!(devices.endpoint_count(), 2, "the master left the bus");
}

#[tokio::test(start_paused = true)]
async fn recv_waits_for_the_next_frame_and_a_timeout_loses_nothing() {
    let bus = MemoryBus::new();
    let mut device = bus.endpoint();
    let mut master = Bus::attach(&bus);
    // Nothing on the bus: a timed wait ends on the virtual clock, at once in real time.
    let started = tokio::time::Instant::now();
    assert!(tokio::time::timeout(Duration::from_millis(100), master.recv()).await.is_err());
    assert_eq!(started.elapsed(), Duration::from_millis(100));
    // A frame sent while the master waits in another task wakes it.
    let waiter = tokio::spawn(async move {
        let got = master.recv().await.unwrap();
        (got, master)
    });
    tokio::time::sleep(Duration::from_millis(10)).await;
    device.send(frame(0x181, &[1, 2])).unwrap();
    let (got, master) = waiter.await.unwrap();
    assert_eq!(got, frame(0x181, &[1, 2]));
    assert_eq!(master.lost(), 0);
}

#[tokio::test(start_paused = true)]
async fn split_halves_work_from_different_tasks_and_keep_the_order() {
    let bus = MemoryBus::new();
    let mut device = bus.endpoint();
    let (tx, mut rx) = Bus::attach(&bus).split();
    let sender = tokio::spawn(async move {
        for i in 0..100u32 {
            tx.send(frame(0x200 + i, &i.to_le_bytes())).await.unwrap();
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    });
    let receiver = tokio::spawn(async move {
        let mut ids = Vec::new();
        while ids.len() < 100 {
            ids.push(rx.recv().await.unwrap().id());
        }
        ids
    });
    // The device echoes every frame with id + 0x100, in order.
    let mut echoed = 0;
    while echoed < 100 {
        match device.try_recv().unwrap() {
            Some(f) => {
                device.send(frame(f.id() + 0x100, f.data())).unwrap();
                echoed += 1;
            }
            None => tokio::time::sleep(Duration::from_micros(100)).await,
        }
    }
    sender.await.unwrap();
    let ids = receiver.await.unwrap();
    assert_eq!(ids, (0x300..0x364).collect::<Vec<u32>>());
}

#[tokio::test(start_paused = true)]
async fn a_receiver_that_does_not_read_loses_frames_counted_and_the_bus_goes_on() {
    let bus = MemoryBus::with_capacity(8);
    let mut device = bus.endpoint();
    let mut master = Bus::attach(&bus);
    let mut listener = bus.endpoint();
    for i in 0..20u32 {
        device.send(frame(0x100 + i, &[])).unwrap();
    }
    assert_eq!(master.lost(), 12);
    for i in 0..8u32 {
        assert_eq!(master.recv().await.unwrap().id(), 0x100 + i, "the oldest frames are kept");
    }
    assert!(tokio::time::timeout(Duration::from_millis(1), master.recv()).await.is_err());
    assert_eq!(listener.dropped(), 12, "the blocking endpoint with the same queue size lost as many");
    // Sending never waits on the full queues of others.
    master.send(frame(0x080, &[])).await.unwrap();
    assert_eq!(device.try_recv().unwrap(), Some(frame(0x080, &[])));
    while listener.try_recv().unwrap().is_some() {}
}

#[tokio::test(start_paused = true)]
async fn several_async_members_hear_each_other_but_not_themselves() {
    let bus = MemoryBus::new();
    let mut a = Bus::attach(&bus);
    let mut b = Bus::attach(&bus);
    a.send(frame(0x601, &[0x40])).await.unwrap();
    assert_eq!(b.recv().await.unwrap(), frame(0x601, &[0x40]));
    assert!(tokio::time::timeout(Duration::from_millis(5), a.recv()).await.is_err(), "no echo of its own frame");
    let (tx, rx) = b.split();
    drop(tx);
    assert_eq!(bus.endpoint_count(), 2, "one half keeps the member on the bus");
    drop(rx);
    assert_eq!(bus.endpoint_count(), 1);
}

#[tokio::test(start_paused = true)]
async fn a_bad_address_is_refused_naming_the_accepted_forms() {
    let err = Bus::open("mem://a b").await.unwrap_err();
    assert!(matches!(err, TransportError::Address(_)), "{err:?}");
    assert!(err.to_string().contains("socketcand://HOST:PORT/CHANNEL"), "{err}");
}

/// A memory bus has no controller: its state changes are only what a test reports, and every
/// listener (on the bus or on either half) gets each of them, in order.
#[tokio::test]
async fn controller_state_changes_reach_every_listener_in_order() {
    let bus = Bus::attach(&MemoryBus::new());
    let mut on_bus = bus.controller().subscribe();
    let (tx, rx) = bus.split();
    let mut on_tx = tx.controller().subscribe();
    let mut on_rx = rx.controller().subscribe();
    let changes = [
        ControllerState::ErrorWarning,
        ControllerState::ErrorPassive,
        ControllerState::BusOff,
        ControllerState::Restarted,
        ControllerState::ErrorActive,
    ];
    for state in changes {
        rx.controller().report(state);
    }
    for listener in [&mut on_bus, &mut on_tx, &mut on_rx] {
        for want in changes {
            assert_eq!(listener.try_recv(), Ok(want));
        }
        assert!(listener.try_recv().is_err(), "nothing more");
    }
}
