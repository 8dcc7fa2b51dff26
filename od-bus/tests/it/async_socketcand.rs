//! The async socketcand client against the project's own hub over loopback TCP: frames both
//! ways, interplay with the blocking client and in-process endpoints on one channel, the hub
//! restarting (the link goes down, sends fail, it comes back by itself and sends work again),
//! and closing for good when asked not to reconnect. Real time: the hub runs on threads.

use std::net::SocketAddr;
use std::time::Duration;

use od_bus::tokio::{Bus, LinkState, Options, Reconnect};
use od_bus::{BusAddr, CanFrame, Endpoint, Hub, HubConfig, SocketcandClient, TransportError};

const WAIT: Duration = Duration::from_secs(15);

fn frame(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

fn hub_on(addr: &str) -> Hub {
    // The hub pauses after each `< ok >` for python-can's sake; not needed here.
    Hub::bind(addr, HubConfig { reply_pause: Duration::ZERO, ..HubConfig::default() }.quiet()).unwrap()
}

fn addr(hub: &SocketAddr, channel: &str) -> BusAddr {
    BusAddr::Socketcand { host: hub.ip().to_string(), port: hub.port(), channel: channel.into() }
}

fn fast_reconnect() -> Options {
    Options {
        reconnect: Reconnect::Backoff { first: Duration::from_millis(20), max: Duration::from_millis(200) },
        ..Options::default()
    }
}

async fn recv(bus: &mut Bus) -> CanFrame {
    tokio::time::timeout(WAIT, bus.recv()).await.expect("a frame in time").unwrap()
}

/// Waits (polling, the hub's threads do the work) for a blocking endpoint's next frame.
async fn recv_blocking(endpoint: &mut dyn Endpoint) -> CanFrame {
    let deadline = tokio::time::Instant::now() + WAIT;
    loop {
        if let Some(frame) = endpoint.try_recv().unwrap() {
            return frame;
        }
        assert!(tokio::time::Instant::now() < deadline, "no frame in time");
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
}

async fn wait_for_link(bus: &Bus, wanted: impl Fn(&LinkState) -> bool) -> LinkState {
    let mut link = bus.link();
    let state = tokio::time::timeout(WAIT, link.wait_for(|s| wanted(s))).await.expect("link state in time").unwrap();
    state.clone()
}

#[tokio::test]
async fn frames_go_both_ways_between_the_async_client_and_hub_members() {
    let hub = hub_on("127.0.0.1:0");
    let mut device = hub.attach("can0").unwrap();
    let text = format!("socketcand://{}/can0", hub.local_addr());
    let mut master = Bus::open(&text).await.unwrap();
    let frames = [
        frame(0x000, &[0x01, 0x00]),
        frame(0x080, &[]),
        CanFrame::extended(0x1ABC_DEF0, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        CanFrame::remote(0x705, false, 1).unwrap(),
    ];
    for f in frames {
        master.send(f).await.unwrap();
        assert_eq!(recv_blocking(&mut device).await, f);
        device.send(f).unwrap();
        assert_eq!(recv(&mut master).await, f);
    }
    assert_eq!(master.lost(), 0);
    assert_eq!(*master.link().borrow(), LinkState::Up { reconnects: 0 });
}

#[tokio::test]
async fn the_blocking_and_the_async_client_interoperate_on_one_hub() {
    let hub = hub_on("127.0.0.1:0");
    let (mut tx, mut rx) = {
        let bus = Bus::open_with(&addr(&hub.local_addr(), "line"), &Options::default()).await.unwrap();
        bus.split()
    };
    let mut blocking = SocketcandClient::connect(hub.local_addr(), "line").unwrap();
    let mut other_channel = SocketcandClient::connect(hub.local_addr(), "other").unwrap();
    // Async -> blocking, in order, from a task of its own.
    let sender = tokio::spawn(async move {
        for i in 0..50u32 {
            tx.send(frame(0x180 + i, &i.to_le_bytes())).await.unwrap();
        }
        tx
    });
    for i in 0..50u32 {
        assert_eq!(recv_blocking(&mut blocking).await, frame(0x180 + i, &i.to_le_bytes()));
    }
    tx = sender.await.unwrap();
    // Blocking -> async.
    for i in 0..50u32 {
        blocking.send(CanFrame::extended(0x10_0000 + i, &[i as u8]).unwrap()).unwrap();
    }
    for i in 0..50u32 {
        let got = tokio::time::timeout(WAIT, rx.recv()).await.unwrap().unwrap();
        assert_eq!(got, CanFrame::extended(0x10_0000 + i, &[i as u8]).unwrap());
    }
    assert_eq!(other_channel.try_recv().unwrap(), None, "another channel is another bus");
    drop(tx);
}

#[tokio::test]
async fn after_a_hub_restart_the_client_reconnects_and_sends_again() {
    let hub = hub_on("127.0.0.1:0");
    let at = hub.local_addr();
    let mut master = Bus::open_with(&addr(&at, "can0"), &fast_reconnect()).await.unwrap();
    let mut device = hub.attach("can0").unwrap();
    master.send(frame(0x601, &[0x40, 0x00, 0x10, 0x00])).await.unwrap();
    assert_eq!(recv_blocking(&mut device).await.id(), 0x601);

    // The hub goes away: the link goes down, and sends say so.
    drop(device);
    hub.stop();
    drop(hub);
    let down = wait_for_link(&master, |s| matches!(s, LinkState::Down { .. })).await;
    assert!(matches!(down, LinkState::Down { .. }), "{down:?}");
    let err = master.send(frame(0x080, &[])).await.unwrap_err();
    assert!(matches!(err, TransportError::Down { .. }), "{err:?}");
    assert!(err.to_string().contains("reconnecting"), "{err}");

    // A new hub on the same address: the client finds it by itself.
    let hub = hub_on(&at.to_string());
    let up = wait_for_link(&master, |s| matches!(s, LinkState::Up { .. })).await;
    assert_eq!(up, LinkState::Up { reconnects: 1 });
    let mut device = hub.attach("can0").unwrap();
    master.send(frame(0x602, &[0x40])).await.unwrap();
    assert_eq!(recv_blocking(&mut device).await, frame(0x602, &[0x40]));
    device.send(frame(0x582, &[0x4B])).unwrap();
    assert_eq!(recv(&mut master).await, frame(0x582, &[0x4B]));
}

#[tokio::test]
async fn without_reconnect_a_lost_hub_closes_the_bus() {
    let hub = hub_on("127.0.0.1:0");
    let options = Options { reconnect: Reconnect::Never, ..Options::default() };
    let mut master = Bus::open_with(&addr(&hub.local_addr(), "can0"), &options).await.unwrap();
    let mut device = hub.attach("can0").unwrap();
    device.send(frame(0x701, &[0x05])).unwrap();
    assert_eq!(recv(&mut master).await.id(), 0x701);
    hub.stop();
    let closed = wait_for_link(&master, |s| *s == LinkState::Closed).await;
    assert_eq!(closed, LinkState::Closed);
    assert!(matches!(tokio::time::timeout(WAIT, master.recv()).await.unwrap(), Err(TransportError::Closed)));
    assert!(matches!(master.send(frame(0x080, &[])).await, Err(TransportError::Closed)));
}

#[tokio::test]
async fn connection_failures_are_reported_when_opening() {
    // Nobody listens on a port just freed.
    let at = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let err = Bus::open(&format!("socketcand://{at}/can0")).await.unwrap_err();
    assert!(err.to_string().contains(&at.to_string()), "{err}");
    // A server that is not socketcand: the handshake times out, naming what was missing.
    let silent = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let options = Options { connect_timeout: Duration::from_millis(200), ..Options::default() };
    let err = Bus::open_with(&addr(&silent.local_addr().unwrap(), "can0"), &options).await.unwrap_err();
    assert!(err.to_string().contains("< hi >"), "{err}");
}

#[tokio::test]
async fn dropping_both_halves_ends_the_connection() {
    let hub = hub_on("127.0.0.1:0");
    let bus = Bus::open_with(&addr(&hub.local_addr(), "can0"), &Options::default()).await.unwrap();
    assert_eq!(hub.client_count(), 1);
    let (tx, rx) = bus.split();
    drop(rx);
    // The sender alone still works.
    let mut device = hub.attach("can0").unwrap();
    tx.send(frame(0x080, &[])).await.unwrap();
    assert_eq!(recv_blocking(&mut device).await, frame(0x080, &[]));
    drop(tx);
    let deadline = tokio::time::Instant::now() + WAIT;
    while hub.client_count() > 0 {
        assert!(tokio::time::Instant::now() < deadline, "the hub still has the client");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// `send_all` puts frames on the bus in order (one write on a socketcand link); `try_recv` hands
/// out what has arrived without waiting and `None` when nothing has. The same on a memory bus.
#[tokio::test]
async fn send_all_keeps_order_and_try_recv_takes_only_what_has_arrived() {
    let hub = hub_on("127.0.0.1:0");
    let mut device = hub.attach("can0").unwrap();
    let text = format!("socketcand://{}/can0", hub.local_addr());
    let (tx, mut rx) = Bus::open(&text).await.unwrap().split();
    let frames: Vec<CanFrame> = (0..40u8).map(|n| frame(0x600 + u32::from(n % 4), &[n, 0x10])).collect();
    tx.send_all(&frames).await.unwrap();
    tx.send_all(&[]).await.unwrap();
    for sent in &frames {
        assert_eq!(recv_blocking(&mut device).await, *sent);
    }
    assert_eq!(rx.try_recv().unwrap(), None);
    device.send_all(&frames).unwrap();
    let mut got = Vec::new();
    let deadline = tokio::time::Instant::now() + WAIT;
    while got.len() < frames.len() {
        match rx.try_recv().unwrap() {
            Some(frame) => got.push(frame),
            None => {
                assert!(tokio::time::Instant::now() < deadline, "{} of {} frames", got.len(), frames.len());
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
        }
    }
    assert_eq!(got, frames);
    assert_eq!(rx.try_recv().unwrap(), None);

    let memory = od_bus::MemoryBus::new();
    let mut other = memory.endpoint();
    let (tx, mut rx) = Bus::attach(&memory).split();
    tx.send_all(&frames[..3]).await.unwrap();
    assert_eq!(
        [other.try_recv().unwrap(), other.try_recv().unwrap(), other.try_recv().unwrap()],
        [Some(frames[0]), Some(frames[1]), Some(frames[2])]
    );
    assert_eq!(rx.try_recv().unwrap(), None);
    other.send(frames[3]).unwrap();
    assert_eq!(rx.try_recv().unwrap(), Some(frames[3]));
    assert_eq!(rx.try_recv().unwrap(), None);
}
