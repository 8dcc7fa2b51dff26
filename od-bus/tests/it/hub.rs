//! The socketcand hub over real TCP connections on 127.0.0.1: relaying between clients as
//! python-can writes and reads the protocol, in-process endpoints, hostile clients, slow
//! clients, and shutdown.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use od_bus::{CanFrame, Endpoint, Hub, HubConfig, HubEvent, SocketcandClient, TransportError};

const WAIT: Duration = Duration::from_secs(15);

/// A client speaking the protocol as text, the way python-can does.
struct TextClient {
    stream: TcpStream,
    pending: Vec<u8>,
}

impl TextClient {
    fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(WAIT)).unwrap();
        Self { stream, pending: Vec::new() }
    }

    /// Connects, expects `< hi >`, opens `channel` and enters raw mode.
    fn raw(addr: SocketAddr, channel: &str) -> Self {
        let mut client = Self::connect(addr);
        assert_eq!(client.next(), "< hi >");
        client.say(&format!("< open {channel} >"));
        assert_eq!(client.next(), "< ok >");
        client.say("< rawmode >");
        assert_eq!(client.next(), "< ok >");
        client
    }

    fn say(&mut self, text: &str) {
        self.stream.write_all(text.as_bytes()).unwrap();
    }

    /// The next complete `< ... >` message (panics after WAIT).
    fn next(&mut self) -> String {
        let deadline = Instant::now() + WAIT;
        loop {
            if let Some(end) = self.pending.iter().position(|&b| b == b'>') {
                let message: Vec<u8> = self.pending.drain(..=end).collect();
                let text = String::from_utf8(message).unwrap();
                return text.trim_start().to_owned();
            }
            assert!(Instant::now() < deadline, "no message within {WAIT:?}");
            let mut buf = [0u8; 4096];
            let n = self.stream.read(&mut buf).expect("read");
            assert!(n > 0, "hub closed the connection; had {:?}", String::from_utf8_lossy(&self.pending));
            self.pending.extend_from_slice(&buf[..n]);
        }
    }

    /// Sends `< echo >` and returns every message received before the echo came back. The hub
    /// handles one client's messages in order, so this proves nothing else is on its way.
    fn drain_until_echo(&mut self) -> Vec<String> {
        self.say("< echo >");
        let mut before = Vec::new();
        loop {
            let message = self.next();
            if message == "< echo >" {
                return before;
            }
            before.push(message);
        }
    }

    /// Waits for the hub to close the connection; true if it did within WAIT.
    fn closed_by_hub(&mut self) -> bool {
        let deadline = Instant::now() + WAIT;
        let mut buf = [0u8; 4096];
        while Instant::now() < deadline {
            match self.stream.read(&mut buf) {
                Ok(0) => return true,
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return true,
                Err(_) => return false,
            }
        }
        false
    }
}

/// Splits `< frame ID TIME DATA >` the way python-can does (split on single spaces, at most 3
/// parts), checking the timestamp is `seconds.microseconds` with six digits.
fn frame_fields(message: &str) -> (String, String) {
    let inner =
        message.strip_prefix("< frame ").and_then(|m| m.strip_suffix(" >")).unwrap_or_else(|| panic!("{message}"));
    let parts: Vec<&str> = inner.splitn(3, ' ').collect();
    assert_eq!(parts.len(), 3, "python-can needs three fields in {message:?}");
    let (secs, micros) = parts[1].split_once('.').unwrap();
    assert!(secs.parse::<u64>().unwrap() > 1_600_000_000, "wall-clock seconds in {message}");
    assert_eq!(micros.len(), 6);
    (parts[0].to_owned(), parts[2].to_owned())
}

fn quiet_hub() -> Hub {
    Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).unwrap()
}

fn recording_hub(config: HubConfig) -> (Hub, Arc<Mutex<Vec<HubEvent>>>) {
    let events = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&events);
    let config = config.with_observer(Arc::new(move |event: &HubEvent| sink.lock().unwrap().push(event.clone())));
    (Hub::bind("127.0.0.1:0", config).unwrap(), events)
}

fn wait_until(what: &str, mut condition: impl FnMut() -> bool) {
    let deadline = Instant::now() + WAIT;
    while !condition() {
        assert!(Instant::now() < deadline, "timed out waiting until {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn two_text_clients_relay_standard_and_extended_frames_both_ways() {
    let hub = quiet_hub();
    let mut master = TextClient::raw(hub.local_addr(), "can0");
    let mut device = TextClient::raw(hub.local_addr(), "can0");

    // Exactly what python-can writes for an SDO download request.
    master.say("< send 601 8 2b 40 60 0 6 0 0 0 >");
    let got = device.next();
    assert_eq!(frame_fields(&got), ("601".into(), "2B40600006000000".into()), "{got}");

    device.say("< send 581 8 60 40 60 0 0 0 0 0 >");
    assert_eq!(frame_fields(&master.next()), ("581".into(), "6040600000000000".into()));

    master.say("< send 1ABCDEF0 3 1 2 ff >");
    assert_eq!(frame_fields(&device.next()), ("1ABCDEF0".into(), "0102FF".into()));
    device.say("< send 00000123 0  >");
    assert_eq!(frame_fields(&master.next()), ("00000123".into(), String::new()), "extended keeps 8 digits");

    // SYNC: no data, the message ends in two spaces so python-can sees an empty third field.
    master.say("< send 080 0  >");
    let sync = device.next();
    assert!(sync.ends_with("  >"), "{sync:?}");
    assert_eq!(frame_fields(&sync), ("080".into(), String::new()));

    // Nothing echoes back to the senders.
    assert_eq!(master.drain_until_echo(), Vec::<String>::new());
    assert_eq!(device.drain_until_echo(), Vec::<String>::new());
}

#[test]
fn rust_clients_relay_through_the_hub_and_channels_are_separate_buses() {
    let hub = quiet_hub();
    let mut a = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut b = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut c = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut other = SocketcandClient::connect(hub.local_addr(), "can1").unwrap();
    assert_eq!(hub.channels(), ["can0", "can1"]);

    let frames = [
        CanFrame::standard(0x000, &[0x82, 0x00]).unwrap(),
        CanFrame::extended(0x1FFF_FFFF, &[0xAA; 8]).unwrap(),
        CanFrame::remote(0x705, false, 1).unwrap(),
        CanFrame::remote(0x0012_3456, true, 0).unwrap(),
    ];
    for frame in frames {
        a.send(frame).unwrap();
    }
    for receiver in [&mut b, &mut c] {
        for frame in frames {
            assert_eq!(receiver.recv_timeout(WAIT).unwrap(), Some(frame));
        }
    }
    b.send(frames[0]).unwrap();
    assert_eq!(a.recv_timeout(WAIT).unwrap(), Some(frames[0]));
    assert_eq!(c.recv_timeout(WAIT).unwrap(), Some(frames[0]));

    a.echo(WAIT).unwrap();
    b.echo(WAIT).unwrap();
    other.echo(WAIT).unwrap();
    assert_eq!(a.try_recv().unwrap(), None, "the sender does not hear itself");
    assert_eq!(b.try_recv().unwrap(), None);
    assert_eq!(other.try_recv().unwrap(), None, "can1 hears nothing from can0");
    assert_eq!(a.remote_errors() + b.remote_errors() + c.remote_errors(), 0);
}

#[test]
fn in_process_endpoints_and_tcp_clients_share_a_channel() {
    let hub = quiet_hub();
    let mut device = hub.attach("can0").unwrap();
    let mut second_device = hub.attach("can0").unwrap();
    let mut master = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut text = TextClient::raw(hub.local_addr(), "can0");

    let request = CanFrame::standard(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap();
    master.send(request).unwrap();
    assert_eq!(device.recv_timeout(WAIT).unwrap(), Some(request));
    assert_eq!(second_device.recv_timeout(WAIT).unwrap(), Some(request));
    assert_eq!(frame_fields(&text.next()).0, "605");

    let response = CanFrame::standard(0x585, &[0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0, 0]).unwrap();
    device.send(response).unwrap();
    assert_eq!(master.recv_timeout(WAIT).unwrap(), Some(response));
    assert_eq!(second_device.recv_timeout(WAIT).unwrap(), Some(response));
    assert_eq!(frame_fields(&text.next()), ("585".into(), "4B41600037020000".into()));
    assert_eq!(device.try_recv().unwrap(), None);

    // Node guarding: a remote frame from the master reaches the device as a remote frame.
    master.send(CanFrame::remote(0x705, false, 1).unwrap()).unwrap();
    let rtr = device.recv_timeout(WAIT).unwrap().unwrap();
    assert!(rtr.is_remote() && rtr.dlc() == 1 && rtr.id() == 0x705);
    let rtr_text = text.next();
    let fields: Vec<&str> = rtr_text.split(' ').collect();
    assert_eq!((fields[1], fields[2], fields[4], fields[5]), ("rtr", "705", "1", ">"), "{rtr_text}");
}

#[test]
fn malformed_input_gets_error_replies_and_the_hub_keeps_serving() {
    let (hub, events) = recording_hub(HubConfig::default());
    let mut peer = TextClient::raw(hub.local_addr(), "can0");
    let mut hostile = TextClient::connect(hub.local_addr());
    assert_eq!(hostile.next(), "< hi >");

    // Before `open` nothing but open and echo is allowed.
    hostile.say("< send 601 0 >");
    assert_eq!(hostile.next(), "< error open a channel first >");
    hostile.say("< rawmode >");
    assert_eq!(hostile.next(), "< error open a channel first >");
    hostile.say("< open can0 >");
    assert_eq!(hostile.next(), "< ok >");
    hostile.say("< open can1 >");
    assert_eq!(hostile.next(), "< error a channel is already open >");

    let cases = [
        ("< launch missiles >", "< error unknown command 'launch' >"),
        ("< add 1 0 123 0 >", "< error command 'add' is not supported (raw mode only) >"),
        ("< send 601 9 0 0 0 0 0 0 0 0 0 >", "< error bad length '9', expected 0 to 8 >"),
        ("< send 601 2 1 >", "< error length says 2 bytes but 1 follow >"),
        ("< send 8000 0 0 >", "< error length says 0 bytes but 1 follow >"),
        ("< send 800 0 >", "< error standard CAN id 0x800 is above 0x7FF >"),
        ("< send zz 0 >", "< error bad CAN id 'zz', expected 1 to 8 hex digits >"),
        ("< send 601 1 1ff >", "< error bad data byte '1ff', expected 1 or 2 hex digits >"),
        ("<>", "< error empty message >"),
        ("< frame 123 1.0 00 >", "< error 'frame' is a server message >"),
        ("< hi >", "< error 'hi' is a server message >"),
        ("< send 601\u{e9} 0 >", "< error message is not ASCII text >"),
        ("< send 601 0 < echo >", "< error message without closing bracket skipped >"),
    ];
    for (input, reply) in cases {
        hostile.say(input);
        assert_eq!(hostile.next(), reply, "for {input:?}");
    }
    // The unterminated case above was followed by an echo, answered after the error.
    assert_eq!(hostile.next(), "< echo >");

    // An endless message is cut off at the limit, then the stream resynchronises.
    hostile.say(&format!("< {}", "x".repeat(100_000)));
    assert_eq!(hostile.next(), "< error message longer than 256 bytes skipped >");
    hostile.say(" >< rawmode >");
    assert_eq!(hostile.next(), "< ok >");

    // Stray bytes between messages are ignored (and logged), binary junk too.
    hostile.say("hello\x00\x01\u{ff}");
    let junk: Vec<u8> =
        (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).filter(|&b| b != b'<').collect();
    hostile.stream.write_all(&junk).unwrap();
    hostile.say("< send 1 1 a >");
    assert_eq!(frame_fields(&peer.next()), ("001".into(), "0A".into()), "a 1-digit id is standard");
    assert_eq!(hostile.drain_until_echo(), Vec::<String>::new());

    // Everyone else was served throughout.
    peer.say("< send 181 2 1 2 >");
    assert_eq!(frame_fields(&hostile.next()), ("181".into(), "0102".into()));
    assert_eq!(hub.client_count(), 2);

    let events = events.lock().unwrap();
    let errors = events.iter().filter(|e| matches!(e, HubEvent::ProtocolError { .. })).count();
    assert_eq!(errors, HubConfig::LOGGED_ERRORS_PER_CLIENT as usize, "errors are logged up to the limit");
    assert_eq!(events.iter().filter(|e| matches!(e, HubEvent::ErrorsSuppressed { .. })).count(), 1);
}

#[test]
fn random_bytes_from_many_clients_do_not_bring_the_hub_down() {
    let hub = quiet_hub();
    let mut witness_a = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut witness_b = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    for round in 0..8 {
        let mut stream = TcpStream::connect(hub.local_addr()).unwrap();
        let mut bytes = Vec::new();
        for _ in 0..20_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            // Mostly protocol-looking characters, so that parsing gets exercised deeply.
            let alphabet = b"<> sendframeopenrawmode0123456789abcdefABCDEF.\n\x00\xff";
            bytes.push(if round % 2 == 0 { alphabet[(seed % alphabet.len() as u64) as usize] } else { seed as u8 });
        }
        if round == 3 {
            bytes.splice(0..0, b"< open can0 >< rawmode >".iter().copied());
        }
        // The hub may close on us or answer; either way it must go on serving the witnesses.
        let _ = stream.write_all(&bytes);
        drop(stream);
        let frame = CanFrame::standard(0x700 + round, &[round as u8]).unwrap();
        witness_a.send(frame).unwrap();
        // Frames sent by a fuzzing client in raw mode may reach the witness first.
        let deadline = Instant::now() + WAIT;
        loop {
            let got = witness_b.recv_timeout(WAIT).unwrap().expect("witness still served");
            if got == frame {
                break;
            }
            assert!(Instant::now() < deadline);
        }
    }
    witness_a.echo(WAIT).unwrap();
}

#[test]
fn a_client_that_stops_reading_loses_frames_counted_not_its_connection() {
    let config = HubConfig {
        client_queue: 64,
        write_timeout: Duration::from_secs(30),
        drop_report_interval: Duration::ZERO,
        ..HubConfig::default()
    };
    let (hub, events) = recording_hub(config);
    // The stuck client asks for drop reports (SocketcandClient does) and reads nothing for now.
    let mut stuck = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut sender = hub.attach("can0").unwrap();
    let mut listener = hub.attach("can0").unwrap();
    let healthy_seen = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let healthy = {
        let mut client = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
        let seen = Arc::clone(&healthy_seen);
        std::thread::spawn(move || {
            while let Some(frame) = client.recv_timeout(WAIT).unwrap() {
                if frame.id() == 0x7FF {
                    return true;
                }
                seen.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            }
            false
        })
    };

    // Stream to everyone, in bursts the healthy clients keep up with, until the stuck client's
    // socket buffers and then its queue are full and frames are dropped for it. Sending must
    // never block.
    let frame = CanFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    let dropped_logged =
        || events.lock().unwrap().iter().any(|e| matches!(e, HubEvent::FramesDropped { total, .. } if *total > 0));
    let mut slowest = Duration::ZERO;
    let mut sent = 0u64;
    let start = Instant::now();
    while !dropped_logged() {
        assert!(start.elapsed() < Duration::from_secs(120), "nothing dropped for the stuck client ({sent} sent)");
        for _ in 0..32 {
            let t = Instant::now();
            sender.send(frame).unwrap();
            slowest = slowest.max(t.elapsed());
            sent += 1;
        }
        while listener.try_recv().unwrap().is_some() {}
        let deadline = Instant::now() + WAIT;
        while healthy_seen.load(std::sync::atomic::Ordering::SeqCst) < sent {
            assert!(Instant::now() < deadline, "the healthy client fell behind");
            std::thread::yield_now();
        }
    }
    // A blocked send would last until the 30 s write timeout; allow for a loaded machine.
    assert!(slowest < Duration::from_secs(2), "a send blocked for {slowest:?}");
    assert!(sent > 64, "only the socket buffers' worth of frames can be queued before the limit bites");
    assert_eq!(listener.dropped(), 0);
    assert_eq!(hub.client_count(), 2, "nobody was disconnected");

    // The stuck client reads again: it gets what was queued, learns how much was dropped, and
    // then the bus as usual.
    // Markers are sent until one arrives; while the backlog drains, some may be dropped too
    // (and counted like any other frame).
    let marker = CanFrame::standard(0x7FF, &[]).unwrap();
    let (mut received, mut markers_sent) = (0u64, 0u64);
    let deadline = Instant::now() + Duration::from_secs(60);
    'catch_up: loop {
        sender.send(marker).unwrap();
        markers_sent += 1;
        assert!(Instant::now() < deadline, "the stuck client never caught up");
        let first = stuck.recv_timeout(Duration::from_millis(20)).unwrap();
        let mut next = first;
        while let Some(f) = next {
            if f == frame {
                received += 1;
            } else if f == marker {
                received += 1;
                break 'catch_up;
            }
            next = stuck.try_recv().unwrap();
        }
    }
    // Whatever follows the first marker (the markers sent after it) is still on its way.
    let deadline = Instant::now() + WAIT;
    while received + stuck.lost() < sent + markers_sent && Instant::now() < deadline {
        if let Some(f) = stuck.recv_timeout(Duration::from_millis(20)).unwrap()
            && (f == frame || f == marker)
        {
            received += 1;
        }
    }
    assert!(stuck.lost() > 0);
    assert_eq!(
        received + stuck.lost(),
        sent + markers_sent,
        "every frame (and marker) was either delivered or counted as dropped"
    );
    let ends: Vec<String> = events
        .lock()
        .unwrap()
        .iter()
        .filter(|e| matches!(e, HubEvent::Overflow { .. }))
        .map(|e| e.to_string())
        .collect();
    assert!(ends.is_empty(), "{ends:?}");
    assert!(healthy.join().unwrap(), "the healthy client stayed connected to the end");
}

/// Frames reach a TCP client whole and in order across the two ways the hub writes them: at once
/// from the relaying thread while the client's socket takes them, and through its writer thread
/// once the socket is full (with the rest of a frame the socket took only part of going first).
/// The client reads nothing until far more than its socket buffers hold has been sent.
#[test]
fn frames_stay_whole_and_in_order_when_the_socket_fills_while_writing_directly() {
    const FRAMES: u32 = 300_000; // about 12 MB of text: more than loopback socket buffers take
    let config = HubConfig { client_queue: FRAMES as usize, ..HubConfig::default() };
    let (hub, events) = recording_hub(config);
    let mut reader = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut sender = hub.attach("can0").unwrap();
    for n in 0..FRAMES {
        let id = 0x100 + n % 0x600; // lengths and identifiers vary, so do the texts
        let bytes = n.to_le_bytes();
        sender.send(CanFrame::standard(id, &bytes[..1 + (n % 4) as usize]).unwrap()).unwrap();
    }
    for n in 0..FRAMES {
        let frame = reader.recv_timeout(WAIT).unwrap().unwrap_or_else(|| panic!("frame {n} never came"));
        let bytes = n.to_le_bytes();
        assert_eq!(frame, CanFrame::standard(0x100 + n % 0x600, &bytes[..1 + (n % 4) as usize]).unwrap(), "frame {n}");
    }
    assert_eq!(reader.remote_errors(), 0, "{:?}", reader.last_remote_error());
    assert_eq!(reader.lost(), 0);
    assert!(!events.lock().unwrap().iter().any(|e| matches!(e, HubEvent::FramesDropped { .. })));
}

#[test]
fn connections_beyond_the_limit_are_refused_when_every_client_sends() {
    let config = HubConfig { max_clients: 2, ..HubConfig::default() };
    let (hub, events) = recording_hub(config);
    let mut a = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut b = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    for client in [&mut a, &mut b] {
        client.send(CanFrame::standard(0x701, &[0x05]).unwrap()).unwrap();
        client.echo(WAIT).unwrap(); // the hub has handled the frame
    }
    let mut third = TextClient::connect(hub.local_addr());
    assert_eq!(third.next(), "< error too many clients, 2 clients already connected, all of them sending >");
    assert!(third.closed_by_hub());
    let err = SocketcandClient::connect(hub.local_addr(), "can0").unwrap_err();
    assert!(err.to_string().contains("too many clients"), "{err}");
    assert!(events.lock().unwrap().iter().any(|e| matches!(e, HubEvent::Rejected { .. })));
    assert!(!events.lock().unwrap().iter().any(|e| matches!(e, HubEvent::Evicted { .. })));
}

#[test]
fn a_full_hub_closes_the_longest_idle_silent_client_to_let_a_master_in() {
    let config = HubConfig { max_clients: 4, ..HubConfig::default() };
    let (hub, events) = recording_hub(config);
    // One client that sends (kept), then silent ones: two in raw mode, one mid-handshake.
    let mut sender = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    sender.send(CanFrame::standard(0x705, &[0x05]).unwrap()).unwrap();
    sender.echo(WAIT).unwrap();
    let mut oldest = TextClient::raw(hub.local_addr(), "can0");
    std::thread::sleep(Duration::from_millis(20));
    let mut younger = TextClient::raw(hub.local_addr(), "can0");
    std::thread::sleep(Duration::from_millis(20));
    let mut handshaking = TextClient::connect(hub.local_addr());
    assert_eq!(handshaking.next(), "< hi >");
    wait_until("four clients", || hub.client_count() == 4);

    // The master gets in; the silent client idle longest makes room.
    let mut device = hub.attach("can0").unwrap();
    let mut master = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    assert!(oldest.closed_by_hub(), "the longest-idle silent client was closed");
    master.send(CanFrame::standard(0x000, &[0x01, 0x00]).unwrap()).unwrap();
    assert_eq!(device.recv_timeout(WAIT).unwrap().map(|f| f.id()), Some(0x000));
    assert_eq!(hub.client_count(), 4);
    let evicted: Vec<HubEvent> =
        events.lock().unwrap().iter().filter(|e| matches!(e, HubEvent::Evicted { .. })).cloned().collect();
    assert_eq!(evicted.len(), 1, "{evicted:?}");

    // Next in line: the younger raw client (the master sent a frame, the handshaking one
    // spoke later), never the client that sends.
    let _second = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    assert!(younger.closed_by_hub());
    sender.send(CanFrame::standard(0x705, &[0x05]).unwrap()).unwrap();
    sender.echo(WAIT).unwrap();
    drop(handshaking);
}

#[test]
fn the_default_limits_let_a_master_in_past_many_idle_clients_quickly() {
    let defaults = HubConfig::default();
    assert!(defaults.max_clients >= 1000, "connections are cheap: {}", defaults.max_clients);
    assert!(defaults.open_timeout <= Duration::from_secs(10), "{:?}", defaults.open_timeout);
    let hub = quiet_hub();
    let idle: Vec<TextClient> = (0..100).map(|_| TextClient::raw(hub.local_addr(), "can0")).collect();
    let mut master = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    master.echo(WAIT).unwrap();
    assert_eq!(hub.client_count(), 101);
    drop(idle);
}

#[test]
fn a_flooding_client_is_slowed_down_and_others_still_join() {
    let rate = 2_000;
    let config = HubConfig { max_rate: rate, ..HubConfig::default() };
    let hub = Hub::bind("127.0.0.1:0", config.quiet()).unwrap();
    let mut listener = hub.attach("can0").unwrap();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flooder = {
        let mut client = TextClient::raw(hub.local_addr(), "can0");
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let burst = "< send 181 8 1 2 3 4 5 6 7 8 >".repeat(256);
            while !stop.load(std::sync::atomic::Ordering::SeqCst) {
                if client.stream.write_all(burst.as_bytes()).is_err() {
                    break;
                }
            }
        })
    };
    let start = Instant::now();
    let mut received = 0u64;
    while start.elapsed() < Duration::from_secs(1) {
        if listener.recv_timeout(Duration::from_millis(10)).unwrap().is_some() {
            received += 1;
        }
    }
    // Clients join and talk during the flood.
    for _ in 0..5 {
        let mut late = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
        late.send(CanFrame::standard(0x080, &[]).unwrap()).unwrap();
        late.echo(WAIT).unwrap();
    }
    while listener.try_recv().unwrap().is_some() {
        received += 1;
    }
    let elapsed = start.elapsed().as_secs_f64();
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    // The bucket holds a tenth of a second, and a read of up to 16 KiB (about 550 such
    // messages) passes before the reader pauses: a load-proof upper bound.
    let bound = (f64::from(rate) * elapsed) as u64 + u64::from(rate) / 10 + 600;
    assert!(received <= bound, "{received} frames in {elapsed:.2} s at a limit of {rate}/s");
    assert!(received > 0);
    drop(hub);
    let _ = flooder.join();
}

#[test]
fn an_emulated_wire_carries_no_more_than_its_bitrate_and_arbitrates_by_identifier() {
    // 1000 bit/s: an 8-byte frame occupies the wire for over 100 ms, so the frames queued
    // while it is on the wire compete, and the lowest identifier goes next.
    let config = HubConfig { bitrate: Some(1_000), ..HubConfig::default() };
    let hub = Hub::bind("127.0.0.1:0", config.quiet()).unwrap();
    let mut listener = hub.attach("can0").unwrap();
    let mut senders: Vec<_> = (0..4).map(|_| hub.attach("can0").unwrap()).collect();
    let start = Instant::now();
    senders[0].send(CanFrame::standard(0x700, &[0xFF; 8]).unwrap()).unwrap();
    std::thread::sleep(Duration::from_millis(5));
    for (sender, id) in senders[1..].iter_mut().zip([0x300, 0x100, 0x200]) {
        sender.send(CanFrame::standard(id, &[0; 2]).unwrap()).unwrap();
    }
    let mut order = Vec::new();
    let mut bits = 0;
    while order.len() < 4 {
        let frame = listener.recv_timeout(Duration::from_secs(10)).unwrap().expect("frames arrive");
        bits += od_bus::wire::frame_bits(&frame);
        order.push(frame.id());
    }
    assert_eq!(order, [0x700, 0x100, 0x200, 0x300]);
    // Never faster than the wire (load can only make it slower).
    let least = Duration::from_secs_f64(f64::from(bits) / 1_000.0) - Duration::from_millis(3);
    assert!(start.elapsed() >= least, "{:?} for {bits} bits", start.elapsed());
}

#[test]
fn a_tcp_client_sending_more_than_the_wire_carries_waits_for_it() {
    let bitrate = 125_000;
    let config = HubConfig { bitrate: Some(bitrate), max_rate: 0, ..HubConfig::default() };
    let hub = Hub::bind("127.0.0.1:0", config.quiet()).unwrap();
    let mut listener = hub.attach("can0").unwrap();
    let mut client = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let frame = CanFrame::standard(0x181, &[0x55; 8]).unwrap();
    let count = 300u32;
    let start = Instant::now();
    let writer = std::thread::spawn(move || {
        for _ in 0..count {
            client.send(frame).unwrap();
        }
        client
    });
    let mut received = 0;
    while received < count {
        listener.recv_timeout(Duration::from_secs(30)).unwrap().expect("every frame arrives");
        received += 1;
    }
    let _client = writer.join().unwrap();
    assert_eq!(listener.dropped(), 0, "a TCP sender waits; nothing is lost");
    let least = f64::from(count * od_bus::wire::frame_bits(&frame)) / f64::from(bitrate) - 0.005;
    assert!(start.elapsed().as_secs_f64() >= least, "{:?}, at least {least:.3} s", start.elapsed());
}

#[test]
fn mode_switches_follow_socketcand() {
    let hub = quiet_hub();
    let mut sender = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut client = TextClient::connect(hub.local_addr());
    assert_eq!(client.next(), "< hi >");
    client.say("< echo >");
    assert_eq!(client.next(), "< echo >");
    client.say("< open can0 >");
    assert_eq!(client.next(), "< ok >");
    // In BCM mode (after open) a client may send but receives no raw frames.
    client.say("< send 123 1 55 >");
    assert_eq!(sender.recv_timeout(WAIT).unwrap(), Some(CanFrame::standard(0x123, &[0x55]).unwrap()));
    sender.send(CanFrame::standard(0x1, &[]).unwrap()).unwrap();
    sender.echo(WAIT).unwrap();
    assert_eq!(client.drain_until_echo(), Vec::<String>::new());
    client.say("< rawmode >");
    assert_eq!(client.next(), "< ok >");
    sender.send(CanFrame::standard(0x2, &[]).unwrap()).unwrap();
    assert_eq!(frame_fields(&client.next()).0, "002");
    client.say("< bcmmode >");
    assert_eq!(client.next(), "< ok >");
    sender.send(CanFrame::standard(0x3, &[]).unwrap()).unwrap();
    sender.echo(WAIT).unwrap();
    assert_eq!(client.drain_until_echo(), Vec::<String>::new());
}

#[test]
fn stopping_the_hub_closes_clients_and_endpoints() {
    let hub = quiet_hub();
    let addr = hub.local_addr();
    let mut client = SocketcandClient::connect(addr, "can0").unwrap();
    let mut device = hub.attach("can0").unwrap();
    let mut idle = TextClient::connect(addr);
    assert_eq!(idle.next(), "< hi >");
    let start = Instant::now();
    hub.stop();
    assert!(start.elapsed() < Duration::from_secs(3), "stop took {:?}", start.elapsed());
    assert!(matches!(client.recv_timeout(WAIT), Err(TransportError::Closed)));
    assert!(matches!(device.recv_timeout(WAIT), Err(TransportError::Closed)));
    assert!(matches!(device.send(CanFrame::standard(1, &[]).unwrap()), Err(TransportError::Closed)));
    assert!(idle.closed_by_hub());
    assert!(matches!(hub.attach("can0"), Err(TransportError::Closed)));
    assert!(TcpStream::connect_timeout(&addr, Duration::from_secs(1)).is_err(), "listener closed");
    hub.stop(); // idempotent
}

#[test]
fn client_handshake_failures_are_reported() {
    // A server that is not socketcand.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        stream.write_all(b"HTTP/1.1 400 Bad Request\r\n\r\n").unwrap();
        let (mut stream2, _) = listener.accept().unwrap();
        stream2.write_all(b"< hi >").unwrap();
        let mut buf = [0u8; 64];
        let _ = stream2.read(&mut buf);
        stream2.write_all(b"< error no such bus >").unwrap();
        std::thread::sleep(Duration::from_millis(200));
    });
    let err = SocketcandClient::connect_timeout(addr, "can0", Duration::from_millis(500)).unwrap_err();
    assert!(matches!(err, TransportError::Protocol(_)), "{err}");
    let err = SocketcandClient::connect_timeout(addr, "can0", Duration::from_secs(2)).unwrap_err();
    assert_eq!(err.to_string(), "protocol error: server refused: no such bus");
    server.join().unwrap();
    let err = SocketcandClient::connect("127.0.0.1:1", "can0").unwrap_err();
    assert!(err.to_string().contains("cannot connect"), "{err}");
    let err = SocketcandClient::connect("127.0.0.1:1", "bad name").unwrap_err();
    assert!(err.to_string().contains("bad channel name"), "{err}");
}

#[test]
fn a_client_that_never_opens_a_channel_is_disconnected() {
    let config = HubConfig { open_timeout: Duration::from_millis(200), ..HubConfig::default() };
    let (hub, events) = recording_hub(config);
    let mut idle = TextClient::connect(hub.local_addr());
    assert_eq!(idle.next(), "< hi >");
    idle.say("< echo >"); // talking is not enough
    assert_eq!(idle.next(), "< echo >");
    // A client that opened in time may stay silent for longer than that.
    let mut listener = TextClient::raw(hub.local_addr(), "can0");
    // Closed within WAIT (5 s), far sooner than the default 30 s: the setting is honoured.
    assert!(idle.closed_by_hub());
    std::thread::sleep(Duration::from_millis(300));
    let mut device = hub.attach("can0").unwrap();
    device.send(CanFrame::standard(0x1, &[]).unwrap()).unwrap();
    assert_eq!(frame_fields(&listener.next()).0, "001");
    assert_eq!(hub.client_count(), 1);
    let events = events.lock().unwrap();
    assert!(
        events.iter().any(
            |e| matches!(e, HubEvent::Disconnected { reason, .. } if reason.starts_with("no channel opened within"))
        ),
        "{events:?}"
    );
}

#[test]
fn handshake_replies_arrive_alone_while_the_bus_is_busy() {
    // python-can reads each handshake reply with a single recv(256) and compares the whole text
    // with "< ok >": a frame in the same read fails its connect. Simulated drives send
    // heartbeats and PDOs all the time, so a master must be able to join a busy bus.
    let hub = quiet_hub();
    let mut device = hub.attach("can0").unwrap();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let chatter = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let heartbeat = CanFrame::standard(0x705, &[0x05]).unwrap();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                device.send(heartbeat).unwrap();
                std::thread::sleep(Duration::from_micros(50));
            }
        })
    };
    for attempt in 0..20 {
        let mut stream = TcpStream::connect(hub.local_addr()).unwrap();
        stream.set_read_timeout(Some(WAIT)).unwrap();
        let recv = |stream: &mut TcpStream| {
            let mut buf = [0u8; 256];
            let n = stream.read(&mut buf).unwrap();
            String::from_utf8_lossy(&buf[..n]).into_owned()
        };
        assert_eq!(recv(&mut stream), "< hi >");
        stream.write_all(b"< open can0 >").unwrap();
        assert_eq!(recv(&mut stream), "< ok >");
        stream.write_all(b"< rawmode >").unwrap();
        assert_eq!(recv(&mut stream), "< ok >", "attempt {attempt}");
        assert!(recv(&mut stream).starts_with("< frame 705 "), "frames follow");
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    chatter.join().unwrap();
}

#[test]
fn an_attached_endpoint_that_does_not_read_loses_frames_counted_and_logged_sparsely() {
    let config = HubConfig { endpoint_queue: 4, ..HubConfig::default() };
    let (hub, events) = recording_hub(config);
    let mut lazy = hub.attach("can0").unwrap();
    let mut busy = hub.attach("can0").unwrap();
    let mut master = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    for i in 0..20u8 {
        master.send(CanFrame::standard(0x200, &[i]).unwrap()).unwrap();
        assert_eq!(busy.recv_timeout(WAIT).unwrap().unwrap().data(), &[i]);
    }
    assert_eq!(lazy.pending(), 4);
    assert_eq!(lazy.dropped(), 16);
    let first: Vec<u8> = (0..4).map(|_| lazy.try_recv().unwrap().unwrap().data()[0]).collect();
    assert_eq!(first, [0, 1, 2, 3]);
    let logged: Vec<u64> = events
        .lock()
        .unwrap()
        .iter()
        .filter_map(|e| match e {
            HubEvent::EndpointOverflow { channel, dropped } if channel == "can0" => Some(*dropped),
            _ => None,
        })
        .collect();
    assert_eq!(logged, [1, 2, 4, 8, 16]);
    assert_eq!(hub.client_count(), 1, "the TCP client is unaffected");
}

/// `send_all` puts several frames on the bus with one write, in order; what one read brought in
/// is counted by `buffered` and handed out by `try_recv` without another read.
#[test]
fn a_client_sends_several_frames_in_one_write_and_counts_what_it_holds() {
    let hub = quiet_hub();
    let mut a = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let mut b = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let frames: Vec<CanFrame> =
        (0..50u8).map(|n| CanFrame::standard(0x580 + u32::from(n % 3), &[n]).unwrap()).collect();
    a.send_all(&frames).unwrap();
    a.send_all(&[]).unwrap();
    let mut got = Vec::new();
    while got.len() < frames.len() {
        got.push(b.recv_timeout(WAIT).unwrap().expect("every frame arrives"));
        for _ in 0..b.buffered() {
            got.push(b.try_recv().unwrap().expect("a frame it said it held"));
        }
    }
    assert_eq!(got, frames);
    assert_eq!(b.buffered(), 0);
}

/// A hub that serves named channels refuses another (a misspelt `can1`): the client's open
/// fails saying which channels the hub serves, instead of joining an empty bus.
#[test]
fn a_hub_serving_named_channels_refuses_another() {
    let config = HubConfig { channels: vec!["can0".into()], ..HubConfig::default() };
    let (hub, _events) = recording_hub(config);
    let err = SocketcandClient::connect(hub.local_addr(), "can1").unwrap_err();
    assert_eq!(
        err.to_string(),
        "protocol error: server refused: channel can1 is not served here; this hub serves can0"
    );
    SocketcandClient::connect(hub.local_addr(), "can0").expect("the channel served");
}

/// A hub serving any channel reports one opened beside busy others, which nothing else is on:
/// the likely typo, in its log.
#[test]
fn a_lone_channel_beside_busy_ones_is_reported() {
    let (hub, events) = recording_hub(HubConfig::default());
    let _device = hub.attach("can0").unwrap();
    let _master = SocketcandClient::connect(hub.local_addr(), "can1").unwrap();
    let _second = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
    let lone: Vec<String> = events
        .lock()
        .unwrap()
        .iter()
        .filter(|e| matches!(e, HubEvent::LoneChannel { .. }))
        .map(|e| e.to_string())
        .collect();
    assert_eq!(lone.len(), 1, "{lone:?}");
    assert!(
        lone[0].ends_with(
            "opened channel can1, which nothing else is on (channels in use: can0): a misspelt channel name?"
        ),
        "{lone:?}"
    );
}

#[test]
fn a_frame_sent_as_soon_as_a_client_is_in_raw_mode_reaches_it() {
    // A client that has its `< ok >` to `< rawmode >` is on the bus: python-can returns from its
    // constructor then, and a test (or a master) sends at once. The hub used to queue the reply
    // before the client joined the channel, so a frame relayed in between was lost to it when
    // its reader thread was preempted there (seen in CI as a burst's first frames missing).
    // No pause after the reply (it only delays the frames), so attempts are quick.
    let hub =
        Hub::bind("127.0.0.1:0", HubConfig { reply_pause: Duration::ZERO, ..HubConfig::default().quiet() }).unwrap();
    let mut device = hub.attach("can0").unwrap();
    for attempt in 0..2000u32 {
        let mut client = TextClient::raw(hub.local_addr(), "can0");
        let frame = CanFrame::standard(0x181, &attempt.to_le_bytes()).unwrap();
        device.send(frame).unwrap();
        let message = client.next();
        assert!(message.starts_with("< frame 181 "), "attempt {attempt}: {message}");
    }
}
