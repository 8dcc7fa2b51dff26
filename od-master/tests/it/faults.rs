//! Faults: a node that goes silent mid-transfer, wrong toggle bits, aborts, lost frames and
//! random frames. A hand-written SDO server (node 9, object 2000h sub 0) misbehaves on cue.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive::node::DeviceKind;
use od_bus::tokio::Bus as Link;
use od_bus::{CanFrame, MemoryBus};
use od_master::{AbortCode, Bus, Config, Error, SdoOptions};
use od_runtime::master::SdoError;
use tokio::time::Instant;

use crate::harness::{net, pass};

const VALUE: &[u8] = b"twenty bytes of data";

/// What the server does wrong.
#[derive(Clone, Default)]
struct Faults {
    /// What becomes of each answer, in turn (then they are delivered): see [`Fate`].
    script: Vec<Fate>,
    /// Answers nothing from this answer on (counted from 0 over the server's life).
    silent_from: Option<usize>,
    /// Sends its segment with the wrong toggle bit at this answer.
    wrong_toggle_at: Option<usize>,
    /// Aborts with 08000000h at this answer.
    abort_at: Option<usize>,
    /// Drops every n-th answer.
    drop_every: Option<usize>,
}

/// What becomes of one answer of the server.
#[derive(Clone, Copy, Debug)]
enum Fate {
    Deliver,
    Drop,
    /// Sent twice (a transmitter that missed the acknowledgement repeats the frame).
    Twice,
    /// Sent this many milliseconds late (after the client's timeout, when it is long).
    Late(u8),
}

/// What the server saw.
#[derive(Default)]
struct Log {
    requests: Vec<[u8; 8]>,
    written: Vec<Vec<u8>>,
}

/// Starts the server on `bus`; returns its log.
fn server(bus: &MemoryBus, faults: Faults) -> Arc<Mutex<Log>> {
    let log = Arc::new(Mutex::new(Log::default()));
    let (tx, mut rx) = Link::attach(bus).split();
    let shared = Arc::clone(&log);
    tokio::spawn(async move {
        let mut answers = 0usize;
        let mut pos = 0usize;
        let mut toggle = 0u8;
        let mut incoming = Vec::new();
        while let Ok(f) = rx.recv().await {
            if f.id() != 0x609 || f.dlc() != 8 {
                continue;
            }
            let d: [u8; 8] = f.data().try_into().unwrap();
            shared.lock().unwrap().requests.push(d);
            let mut a = [0u8; 8];
            match d[0] {
                0x40 => {
                    pos = 0;
                    toggle = 0;
                    a = [0x41, 0x00, 0x20, 0x00, VALUE.len() as u8, 0, 0, 0];
                }
                c if c & 0xEF == 0x60 => {
                    let n = (VALUE.len() - pos).min(7);
                    let last = pos + n == VALUE.len();
                    let mut t = toggle;
                    if faults.wrong_toggle_at == Some(answers) {
                        t ^= 0x10;
                    }
                    a[0] = t | (((7 - n) as u8) << 1) | u8::from(last);
                    a[1..1 + n].copy_from_slice(&VALUE[pos..pos + n]);
                    pos += n;
                    toggle ^= 0x10;
                }
                0x21 => {
                    incoming.clear();
                    toggle = 0;
                    a = [0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0];
                }
                c if c & 0xE0 == 0x00 => {
                    let n = 7 - usize::from((c >> 1) & 7);
                    incoming.extend_from_slice(&d[1..1 + n]);
                    a[0] = 0x20 | (c & 0x10);
                    if c & 1 != 0 {
                        shared.lock().unwrap().written.push(std::mem::take(&mut incoming));
                    }
                }
                c if c & 0xE3 == 0x23 => {
                    let n = 4 - usize::from((c >> 2) & 3);
                    shared.lock().unwrap().written.push(d[4..4 + n].to_vec());
                    a = [0x60, d[1], d[2], d[3], 0, 0, 0, 0];
                }
                0x80 => continue,
                _ => a = [0x80, d[1], d[2], d[3], 0x01, 0x00, 0x04, 0x05],
            }
            let k = answers;
            answers += 1;
            if faults.silent_from.is_some_and(|s| k >= s) || faults.drop_every.is_some_and(|e| k % e == e - 1) {
                continue;
            }
            if faults.abort_at == Some(k) {
                a = [0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x00, 0x08];
            }
            let answer = CanFrame::standard(0x589, &a).unwrap();
            match faults.script.get(k).copied().unwrap_or(Fate::Deliver) {
                Fate::Deliver => {
                    let _ = tx.send(answer).await;
                }
                Fate::Drop => {}
                Fate::Twice => {
                    let _ = tx.send(answer).await;
                    let _ = tx.send(answer).await;
                }
                Fate::Late(ms) => {
                    let tx = tx.clone();
                    tokio::spawn(async move {
                        tokio::time::sleep(Duration::from_millis(u64::from(ms))).await;
                        let _ = tx.send(answer).await;
                    });
                }
            }
        }
    });
    log
}

/// The master and a listener on a fresh memory bus with the server.
fn setup(faults: Faults) -> (Bus, Arc<Mutex<Log>>, Link) {
    let mem = MemoryBus::new();
    let log = server(&mem, faults);
    let listener = Link::attach(&mem);
    (Bus::start(Link::attach(&mem), Config::default()), log, listener)
}

fn opts(timeout_ms: u64, retries: u8) -> SdoOptions {
    SdoOptions { timeout: Duration::from_millis(timeout_ms), retries, ..SdoOptions::default() }
}

/// Frames with COB-ID `id` the listener has.
fn drain(listener: &mut Link, id: u32) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(Ok(f)) = tokio_test_poll(listener) {
        if f.id() == id {
            out.push(f.to_string());
        }
    }
    out
}

fn tokio_test_poll(listener: &mut Link) -> Option<Result<CanFrame, od_bus::TransportError>> {
    use std::future::Future;
    use std::task::{Context, Poll, Waker};
    let mut fut = std::pin::pin!(listener.recv());
    match fut.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
        Poll::Ready(r) => Some(r),
        Poll::Pending => None,
    }
}

#[tokio::test(start_paused = true)]
async fn a_node_that_goes_silent_mid_transfer_times_out_naming_node_and_object() {
    let (bus, log, mut listener) = setup(Faults { silent_from: Some(1), ..Faults::default() });
    let node = bus.node(9).unwrap().with_options(opts(100, 0));
    let t0 = Instant::now();
    let e = node.read_bytes(0x2000, 0).await.unwrap_err();
    let took = t0.elapsed();
    assert!(took >= Duration::from_millis(100) && took < Duration::from_millis(102), "{took:?}");
    assert_eq!(
        e.to_string(),
        "node 9, upload of 2000h sub 0: aborted by the client: 0x05040000 (SDO protocol timed out)"
    );
    // The client told the server: the abort frame went out.
    assert_eq!(drain(&mut listener, 0x609).last().unwrap(), "609#8000200000000405");
    // With retries, each attempt starts over from the initiate request; the node stays silent.
    let node = node.with_options(opts(100, 2));
    let t0 = Instant::now();
    let e = node.read_bytes(0x2000, 0).await.unwrap_err();
    assert!(t0.elapsed() < Duration::from_millis(303), "{:?}", t0.elapsed());
    assert!(
        matches!(e, Error::Sdo { attempts: 3, error, .. } if error.error == SdoError::Client(AbortCode::TIMEOUT)),
        "{e:?}"
    );
    assert!(e.to_string().ends_with("(after 3 attempts)"), "{e}");
    let initiates = log.lock().unwrap().requests.iter().filter(|r| r[0] == 0x40).count();
    assert_eq!(initiates, 4);
}

#[tokio::test(start_paused = true)]
async fn a_wrong_toggle_bit_aborts_the_transfer_and_a_retry_reads_the_right_value() {
    let (bus, _log, mut listener) = setup(Faults { wrong_toggle_at: Some(2), ..Faults::default() });
    let node = bus.node(9).unwrap().with_options(opts(100, 0));
    let e = node.read_bytes(0x2000, 0).await.unwrap_err();
    assert!(matches!(&e, Error::Sdo { error, .. } if error.error == SdoError::Client(AbortCode::TOGGLE_BIT)), "{e:?}");
    assert!(e.to_string().contains("toggle bit not alternated"));
    assert_eq!(drain(&mut listener, 0x609).last().unwrap(), "609#8000200000000305");
    // The same fault again, now with a retry: a new transfer from the start, the right value.
    let (bus, log, _) = setup(Faults { wrong_toggle_at: Some(2), ..Faults::default() });
    let node = bus.node(9).unwrap().with_options(opts(100, 1));
    assert_eq!(node.read_bytes(0x2000, 0).await.unwrap(), VALUE);
    let initiates = log.lock().unwrap().requests.iter().filter(|r| r[0] == 0x40).count();
    assert_eq!(initiates, 2);
}

#[tokio::test(start_paused = true)]
async fn a_server_abort_mid_transfer_ends_it_with_the_servers_code() {
    let (bus, log, _) = setup(Faults { abort_at: Some(1), ..Faults::default() });
    let node = bus.node(9).unwrap().with_options(opts(100, 3));
    let e = node.read_bytes(0x2000, 0).await.unwrap_err();
    assert_eq!(e.to_string(), "node 9, upload of 2000h sub 0: aborted by the server: 0x08000000 (general error)");
    assert_eq!(log.lock().unwrap().requests.len(), 2, "not retried");
}

/// With every seventh answer lost, reads and idempotent writes get through on retries and never
/// return a wrong value; a plain write is never sent twice.
#[tokio::test(start_paused = true)]
async fn lost_frames_are_retried_where_allowed_and_never_give_a_wrong_value() {
    let (bus, log, _) = setup(Faults { drop_every: Some(7), ..Faults::default() });
    let node = bus.node(9).unwrap().with_options(opts(50, 5));
    for _ in 0..30 {
        assert_eq!(node.read_bytes(0x2000, 0).await.unwrap(), VALUE);
    }
    for k in 0..30u32 {
        let data = format!("value number {k:04}");
        node.write_bytes_idempotent(0x2000, 0, data.as_bytes()).await.unwrap();
        assert_eq!(log.lock().unwrap().written.last().unwrap(), data.as_bytes());
    }
    // Plain writes: each reaches the server once, whether or not its answer is lost.
    let mut failed = 0;
    for k in 0..30u32 {
        let before = log.lock().unwrap().requests.iter().filter(|r| r[0] & 0xE3 == 0x23).count();
        match node.write(0x2000, 0, k).await {
            Ok(()) => {}
            Err(Error::Sdo { error, attempts: 1, .. }) if error.error == SdoError::Client(AbortCode::TIMEOUT) => {
                failed += 1
            }
            Err(e) => panic!("{e}"),
        }
        let after = log.lock().unwrap().requests.iter().filter(|r| r[0] & 0xE3 == 0x23).count();
        assert_eq!(after - before, 1, "write {k} sent once");
    }
    assert!(failed > 0, "some answers were lost");
}

/// Noise on the bus while transfers run to the drives: random frames on every identifier
/// except the SDO channels of the drives (a frame there is, by CAN's design, the server's
/// answer or a request the drive answers) and NMT (it would reset them), plus short frames on
/// the SDO response identifiers, which the client must ignore. Every read still returns the
/// value read without noise.
#[tokio::test(start_paused = true)]
async fn random_frames_on_the_bus_change_no_value() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(1)).await;
    let objects = [(0x1000, 0), (0x1008, 0), (0x1018, 1), (0x6041, 0), (0x1009, 0)];
    let mut quiet = Vec::new();
    for id in [2, 4] {
        for (i, s) in objects {
            quiet.push(n.bus.node(id).unwrap().read_bytes(i, s).await.unwrap());
        }
    }
    let noise = Link::attach(n.sim.lock().unwrap().bus());
    let mut frames = n.bus.frames();
    let noisy = tokio::spawn(async move {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        loop {
            let r = next();
            let id = (r & 0x7FF) as u32;
            let len = ((r >> 11) % 9) as usize;
            let data = (r >> 16).to_le_bytes();
            let frame = if (0x581..=0x5FF).contains(&id) {
                CanFrame::standard(id, &data[..len.min(7)]).unwrap()
            } else if id == 0 || (0x601..=0x67F).contains(&id) {
                CanFrame::extended(id << 18 | (r >> 40) as u32 & 0x3FFFF, &data[..len]).unwrap()
            } else {
                CanFrame::standard(id, &data[..len]).unwrap()
            };
            if noise.send(frame).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_micros(150)).await;
        }
    });
    for _ in 0..10 {
        let mut k = 0;
        for id in [2, 4] {
            for (i, s) in objects {
                assert_eq!(n.bus.node(id).unwrap().read_bytes(i, s).await.unwrap(), quiet[k], "node {id} {i:04X}h");
                k += 1;
            }
        }
    }
    noisy.abort();
    // The master received the noise (its frame subscription saw it) and carries on.
    let mut seen = 0;
    while !matches!(frames.try_recv(), Err(tokio::sync::broadcast::error::TryRecvError::Empty)) {
        seen += 1;
    }
    assert!(seen > 200, "{seen} frames received");
    assert_eq!(n.bus.node(2).unwrap().read_bytes(0x1000, 0).await.unwrap(), quiet[0]);
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config { cases: 64, ..Default::default() })]

    /// Whatever becomes of the server's answers (lost, repeated, late past the timeout), a read
    /// either returns the server's value or fails with an SDO error naming the node and the
    /// object; a write reaches the server with its data or fails. Nothing panics, nothing hangs.
    #[test]
    fn no_fate_of_the_answers_gives_a_wrong_value(
        fates in proptest::collection::vec(
            proptest::prop_oneof![
                4 => proptest::strategy::Just(Fate::Deliver),
                1 => proptest::strategy::Just(Fate::Drop),
                1 => proptest::strategy::Just(Fate::Twice),
                1 => proptest::strategy::Strategy::prop_map(1u8..120, Fate::Late),
            ],
            0..60,
        ),
        retries in 0u8..4,
    ) {
        let rt = tokio::runtime::Builder::new_current_thread().enable_time().start_paused(true).build().unwrap();
        rt.block_on(async {
            let (bus, log, _) = setup(Faults { script: fates, ..Faults::default() });
            let node = bus.node(9).unwrap().with_options(opts(50, retries));
            for k in 0..8u32 {
                match node.read_bytes(0x2000, 0).await {
                    Ok(v) => assert_eq!(v, VALUE),
                    Err(Error::Sdo { error, .. }) => assert_eq!((error.node, error.index, error.sub), (9, 0x2000, 0)),
                    Err(e) => panic!("{e}"),
                }
                let data = format!("written number {k:03}");
                match node.write_bytes_idempotent(0x2000, 0, data.as_bytes()).await {
                    Ok(()) => assert_eq!(log.lock().unwrap().written.last().unwrap(), data.as_bytes()),
                    Err(Error::Sdo { error, .. }) => assert_eq!((error.node, error.index), (9, 0x2000)),
                    Err(e) => panic!("{e}"),
                }
            }
        });
    }
}
