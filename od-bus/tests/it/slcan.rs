//! slcan: the codec's properties (every frame kind round-trips; garbage, overlong lines, BEL
//! and a lost `\r` are errors that resynchronise, never a panic or a made-up frame), and the
//! async bus over a pseudo-terminal whose master side plays the adapter: the setup written,
//! frames both ways, Lawicel's status flags and bus-off recovery, the adapter unplugged and
//! plugged in again.

use od_bus::CanFrame;
use od_bus::slcan::{Command, Decoder, Reply, encode};
use proptest::prelude::*;

fn any_frame() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (0u32..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, data)| CanFrame::standard(id, &data).unwrap()),
        (0u32..=0x1FFF_FFFF, proptest::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, data)| CanFrame::extended(id, &data).unwrap()),
        (0u32..=0x7FF, 0u8..=8).prop_map(|(id, dlc)| CanFrame::remote(id, false, dlc).unwrap()),
        (0u32..=0x1FFF_FFFF, 0u8..=8).prop_map(|(id, dlc)| CanFrame::remote(id, true, dlc).unwrap()),
    ]
}

fn decode(bytes: &[u8], chunk: usize) -> Vec<Reply> {
    let mut decoder = Decoder::new();
    let mut out = Vec::new();
    for piece in bytes.chunks(chunk.max(1)) {
        decoder.feed(piece, |reply| out.push(reply));
    }
    out
}

fn frames_of(replies: &[Reply]) -> Vec<CanFrame> {
    replies.iter().filter_map(|r| if let Reply::Frame { frame, .. } = r { Some(*frame) } else { None }).collect()
}

/// How a stream of lines is damaged.
#[derive(Debug, Clone)]
enum Damage {
    /// The `\r` of line `n` is lost: it runs into the next.
    LoseCr(usize),
    /// A BEL comes in the middle of line `n`.
    Bel(usize, usize),
    /// Bytes without a line end come before line `n`.
    Garbage(usize, Vec<u8>),
    /// A run longer than any line comes before line `n`.
    Overlong(usize, usize),
}

fn any_damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        any::<usize>().prop_map(Damage::LoseCr),
        (any::<usize>(), any::<usize>()).prop_map(|(n, at)| Damage::Bel(n, at)),
        (
            any::<usize>(),
            proptest::collection::vec(
                any::<u8>().prop_filter("no line end", |b| !matches!(b, b'\r' | b'\n' | 7)),
                1..40
            )
        )
            .prop_map(|(n, g)| Damage::Garbage(n, g)),
        (any::<usize>(), 65usize..300).prop_map(|(n, len)| Damage::Overlong(n, len)),
    ]
}

proptest! {
    #[test]
    fn every_frame_kind_encodes_and_decodes_to_itself(frame in any_frame(), chunk in 1usize..30) {
        let mut line = Vec::new();
        encode(&frame, &mut line);
        prop_assert_eq!(decode(&line, chunk), vec![Reply::Frame { frame, timestamp: None }]);
        prop_assert_eq!(Command::parse(&line[..line.len() - 1]), Ok(Command::Transmit(frame)));
        // An adapter's time stamp (Z1) after the data.
        line.pop();
        line.extend_from_slice(b"1F3A\r");
        prop_assert_eq!(decode(&line, chunk), vec![Reply::Frame { frame, timestamp: Some(0x1F3A) }]);
    }

    /// Damaged streams: never a panic, every frame decoded is one that was sent and in its
    /// order, each damage costs at most the two lines around it, and decoding goes on.
    #[test]
    fn damage_is_an_error_that_resynchronises_never_a_wrong_frame(
        frames in proptest::collection::vec(any_frame(), 1..20),
        damages in proptest::collection::vec(any_damage(), 0..4),
        chunk in 1usize..64,
    ) {
        let mut lines: Vec<Vec<u8>> = frames.iter().map(|f| { let mut l = Vec::new(); encode(f, &mut l); l }).collect();
        let count = lines.len();
        for damage in &damages {
            match damage {
                Damage::LoseCr(n) => { lines[n % count].pop(); }
                Damage::Bel(n, at) => { let line = &mut lines[n % count]; let at = 1 + at % (line.len() - 1); line.insert(at, 7); }
                Damage::Garbage(n, bytes) => { let line = &mut lines[n % count]; line.splice(0..0, bytes.iter().copied()); }
                Damage::Overlong(n, len) => { let line = &mut lines[n % count]; line.splice(0..0, std::iter::repeat_n(b'7', *len)); }
            }
        }
        let stream: Vec<u8> = lines.concat();
        let got = frames_of(&decode(&stream, chunk));
        // A subsequence of what was sent, in order.
        let mut sent = frames.iter();
        for frame in &got {
            prop_assert!(sent.any(|f| f == frame), "{frame} was never sent, or came out of order: {got:?}");
        }
        prop_assert!(got.len() + 2 * damages.len() >= frames.len(), "{} of {} frames with {} damages", got.len(), frames.len(), damages.len());
        // A clean line after the damage decodes.
        let mut tail = stream.clone();
        tail.extend_from_slice(b"\rt1231AA\r");
        let replies = decode(&tail, chunk);
        prop_assert_eq!(frames_of(&replies).last().copied(), Some(CanFrame::standard(0x123, &[0xAA]).unwrap()));
    }

    #[test]
    fn any_bytes_decode_without_panicking_the_same_in_any_chunks(bytes in proptest::collection::vec(any::<u8>(), 0..400), chunk in 1usize..50) {
        prop_assert_eq!(decode(&bytes, chunk), decode(&bytes, bytes.len().max(1)));
        let mut decoder = od_bus::slcan::CommandDecoder::new();
        decoder.feed(&bytes, |_| {});
    }
}

#[cfg(all(unix, feature = "tokio"))]
mod pty {
    use std::io::{Read, Write};
    use std::path::Path;
    use std::time::{Duration, Instant};

    use od_bus::CanFrame;
    use od_bus::tokio::{Bus, LinkState, Options, Reconnect};
    use serialport::{SerialPort, TTYPort};

    /// The adapter's side of a fresh pseudo-terminal, and the path a host opens.
    fn adapter() -> (TTYPort, String) {
        let (mut master, slave) = TTYPort::pair().unwrap();
        let path = slave.name().unwrap();
        drop(slave);
        master.set_timeout(Duration::from_millis(20)).unwrap();
        (master, path)
    }

    /// Reads from the adapter's side until `want` has come (or fails after 5 s).
    fn expect(master: &mut TTYPort, want: &[u8]) {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut got = Vec::new();
        let mut buf = [0u8; 256];
        while !got.windows(want.len()).any(|w| w == want) {
            assert!(
                Instant::now() < deadline,
                "waited for {:?}, got {:?}",
                String::from_utf8_lossy(want),
                String::from_utf8_lossy(&got)
            );
            match master.read(&mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("{e}"),
            }
        }
    }

    /// One plain read of what the host left on the terminal.
    fn read_left(master: TTYPort, buf: &mut [u8]) -> usize {
        use std::os::fd::{FromRawFd, IntoRawFd};
        // SAFETY: the descriptor comes from `into_raw_fd`, so the File is its only owner.
        let mut file = unsafe { std::fs::File::from_raw_fd(master.into_raw_fd()) };
        file.read(buf).unwrap_or(0)
    }

    async fn link_becomes(bus: &Bus, want: impl Fn(&LinkState) -> bool) -> LinkState {
        let mut link = bus.link();
        let state = tokio::time::timeout(Duration::from_secs(10), link.wait_for(|s| want(s))).await;
        state.expect("link state in time").expect("link watch").clone()
    }

    /// The setup goes out at once (no reply awaited: a stock CANable sends none), then frames
    /// of every kind go both ways.
    #[tokio::test]
    async fn frames_go_both_ways_with_a_silent_adapter() {
        let (mut master, path) = adapter();
        let mut bus = Bus::open(&format!("slcan://{path}?bitrate=1000000")).await.unwrap();
        expect(&mut master, b"\r\r\rC\rS8\rM0\rO\r");
        let frames = [
            CanFrame::standard(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap(),
            CanFrame::extended(0x1ABC_DEF0, &[1, 2, 3]).unwrap(),
            CanFrame::remote(0x705, false, 1).unwrap(),
            CanFrame::remote(0x1234, true, 0).unwrap(),
        ];
        for frame in frames {
            bus.send(frame).await.unwrap();
        }
        expect(&mut master, b"t60184000100000000000\rT1ABCDEF03010203\rr7051\rR000012340\r");
        master.write_all(b"t58180123456789ABCDEF\rgarbage\rT000000110\r\x07r0000\r").unwrap();
        let mut got = Vec::new();
        for _ in 0..3 {
            got.push(tokio::time::timeout(Duration::from_secs(5), bus.recv()).await.unwrap().unwrap());
        }
        assert_eq!(
            got,
            [
                CanFrame::standard(0x581, &[0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF]).unwrap(),
                CanFrame::extended(0x11, &[]).unwrap(),
                CanFrame::remote(0, false, 0).unwrap(),
            ]
        );
        assert_eq!(*bus.link().borrow(), LinkState::Up { reconnects: 0 });
        drop(bus);
        // A bus dropped closes the channel (`C`), then the port: the terminal hangs up. (What
        // is left after the hang-up is read without the port's poll, which fails once the
        // host has hung up even with bytes left to read.)
        let spare = master.try_clone_native().unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut seen = Vec::new();
        let mut buf = [0u8; 64];
        loop {
            assert!(Instant::now() < deadline, "the port is still open after the bus was dropped");
            match master.read(&mut buf) {
                Ok(n) => seen.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => break,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("{e}"),
            }
        }
        let n = read_left(spare, &mut buf);
        seen.extend_from_slice(&buf[..n]);
        assert!(seen.ends_with(b"C\r"), "{:?}", String::from_utf8_lossy(&seen));
    }

    /// A Lawicel adapter acknowledges: its status flags are read, an overrun counts as lost,
    /// and bus-off is recovered by C then O (a short outage on the link).
    #[tokio::test]
    async fn a_lawicel_adapter_is_polled_and_recovered_from_bus_off() {
        let (mut master, path) = adapter();
        let bus = Bus::open(&format!("slcan://{path}?bitrate=125000&listen-only")).await.unwrap();
        let mut controller = bus.controller().subscribe();
        expect(&mut master, b"C\rS4\rM1\rL\rO\r");
        // Its answers: C, S4 done, M1 refused, L done, O refused (already open).
        master.write_all(b"\r\r\x07\r\x07").unwrap();
        expect(&mut master, b"F\r");
        master.write_all(b"F08\r").unwrap();
        expect(&mut master, b"F\r");
        assert_eq!(bus.lost(), 1);
        master.write_all(b"F80\r").unwrap();
        expect(&mut master, b"C\rS4\rM1\rL\rO\r");
        assert_eq!(
            link_becomes(&bus, |s| matches!(s, LinkState::Up { reconnects: 1 })).await,
            LinkState::Up { reconnects: 1 }
        );
        // The controller's listeners hear the bus-off and the restart, in order.
        for want in [od_bus::ControllerState::BusOff, od_bus::ControllerState::Restarted] {
            let got = tokio::time::timeout(Duration::from_secs(5), controller.recv()).await;
            assert_eq!(got.expect("a controller state change within 5 s").unwrap(), want);
        }
    }

    /// The adapter unplugged (the terminal closed) and plugged in again under the same name:
    /// the link goes down, comes back, the setup is written again, and the next frame goes.
    #[tokio::test]
    async fn an_adapter_unplugged_and_plugged_in_again_is_reopened() {
        let dir = std::env::temp_dir().join(format!("od-bus-slcan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let link = dir.join("ttyCAN0");
        let plug = |link: &Path| {
            let (master, path) = adapter();
            let _ = std::fs::remove_file(link);
            std::os::unix::fs::symlink(path, link).unwrap();
            master
        };
        let mut master = plug(&link);
        let options = Options {
            reconnect: Reconnect::Backoff { first: Duration::from_millis(20), max: Duration::from_millis(100) },
            ..Options::default()
        };
        let mut bus = Bus::open_with(&format!("slcan://{}", link.display()).parse().unwrap(), &options).await.unwrap();
        expect(&mut master, b"O\r");
        drop(master);
        std::fs::remove_file(&link).unwrap();
        let down = link_becomes(&bus, |s| matches!(s, LinkState::Down { .. })).await;
        let LinkState::Down { reason, .. } = &down else { unreachable!() };
        assert!(reason.contains("ttyCAN0"), "{reason}");
        let frame = CanFrame::standard(0x000, &[0x81, 0]).unwrap();
        assert!(matches!(bus.send(frame).await, Err(od_bus::TransportError::Down { .. })));
        let mut master = plug(&link);
        link_becomes(&bus, |s| matches!(s, LinkState::Up { reconnects: 1 })).await;
        expect(&mut master, b"\r\r\rC\rS6\rM0\rO\r");
        bus.send(frame).await.unwrap();
        expect(&mut master, b"t00028100\r");
        master.write_all(b"t701100\r").unwrap();
        let got = tokio::time::timeout(Duration::from_secs(5), bus.recv()).await.unwrap().unwrap();
        assert_eq!(got, CanFrame::standard(0x701, &[0]).unwrap());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The blocking endpoint over any byte stream: here the terminal itself.
    #[test]
    fn the_blocking_endpoint_works_over_a_pseudo_terminal() {
        use od_bus::Endpoint;
        use od_bus::slcan::{Setup, SlcanPort};
        let (mut master, slave) = TTYPort::pair().unwrap();
        master.set_timeout(Duration::from_millis(20)).unwrap();
        let mut port = SlcanPort::new(slave, "pty", Setup { bitrate: 250_000, listen_only: false }).unwrap();
        expect(&mut master, b"S5\rM0\rO\r");
        port.send(CanFrame::standard(0x080, &[]).unwrap()).unwrap();
        expect(&mut master, b"t0800\r");
        master.write_all(b"t18110").unwrap();
        assert_eq!(port.recv_timeout(Duration::from_millis(30)).unwrap(), None);
        master.write_all(b"0\r").unwrap();
        assert_eq!(port.recv_timeout(Duration::from_secs(5)).unwrap(), Some(CanFrame::standard(0x181, &[0]).unwrap()));
        drop(master);
        assert!(port.recv_timeout(Duration::from_secs(5)).is_err(), "a closed terminal is an error");
    }
}
