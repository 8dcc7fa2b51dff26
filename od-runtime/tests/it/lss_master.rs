//! The LSS master's machine (CiA 305): its frames, exactly, and its steps against devices.

use crate::common;
use common::*;
use od_runtime::lss::{Identity, Mode};
use od_runtime::master::lss::{Answer, DEFAULT_TIMEOUT, Done, ErrorKind, LssMaster, Request, Step};
use od_runtime::{Device, Frame, NodeId};

/// Runs `req` to its end, answering each frame sent with `answer` (frames, as text, to
/// receive 300 µs later); returns the frames sent and the result.
fn run(req: Request, mut answer: impl FnMut(&str) -> Vec<String>) -> (Vec<String>, Done) {
    let mut m = LssMaster::new();
    let mut now = 0;
    let mut sent = Vec::new();
    m.start(req, now).unwrap();
    for _ in 0..1000 {
        let mut out = Vec::new();
        if let Some(d) = m.poll(now, &mut |f| out.push(f.to_string())) {
            sent.extend(out);
            return (sent, d);
        }
        let mut replies = Vec::new();
        for f in &out {
            replies.extend(answer(f));
        }
        sent.extend(out);
        now += 300;
        for r in replies {
            if let Some(d) = m.on_frame(&frame(&r), now) {
                return (sent, d);
            }
        }
        now = now.max(m.deadline().unwrap());
    }
    panic!("no end");
}

#[test]
fn frames_of_every_request() {
    let id = Identity { vendor: 0x1234_5678, product: 2, revision: 3, serial: 0xA1B2_C3D4 };
    let cases: [(Request, &[&str], &str); 9] = [
        (Request::SwitchGlobal(Mode::Configuration), &["7E5 04 01 00 00 00 00 00 00"], ""),
        (Request::SwitchGlobal(Mode::Waiting), &["7E5 04 00 00 00 00 00 00 00"], ""),
        (
            Request::SwitchSelective(id),
            &[
                "7E5 40 78 56 34 12 00 00 00",
                "7E5 41 02 00 00 00 00 00 00",
                "7E5 42 03 00 00 00 00 00 00",
                "7E5 43 D4 C3 B2 A1 00 00 00",
            ],
            "7E4 44 00 00 00 00 00 00 00",
        ),
        (Request::ConfigureNodeId(0x7F), &["7E5 11 7F 00 00 00 00 00 00"], "7E4 11 00 00 00 00 00 00 00"),
        (Request::ConfigureBitTiming(4), &["7E5 13 00 04 00 00 00 00 00"], "7E4 13 00 00 00 00 00 00 00"),
        (Request::ActivateBitTiming(0x1234), &["7E5 15 34 12 00 00 00 00 00"], ""),
        (Request::Store, &["7E5 17 00 00 00 00 00 00 00"], "7E4 17 00 00 00 00 00 00 00"),
        (Request::InquireNodeId, &["7E5 5E 00 00 00 00 00 00 00"], "7E4 5E 09 00 00 00 00 00 00"),
        (Request::IdentifyNonConfigured, &["7E5 4C 00 00 00 00 00 00 00"], "7E4 50 00 00 00 00 00 00 00"),
    ];
    for (req, frames, reply) in cases {
        // The answer comes to the last frame of the request.
        let last = frames[frames.len() - 1];
        let (sent, done) = run(req, |f| if f == last && !reply.is_empty() { vec![reply.to_owned()] } else { vec![] });
        assert_eq!(sent, frames, "{req:?}");
        let want = match req {
            Request::InquireNodeId => Answer::NodeId(9),
            Request::IdentifyNonConfigured => Answer::Answers(1),
            _ => Answer::Done,
        };
        assert_eq!(done.result, Ok(want), "{req:?}");
    }
    for p in 0..4u8 {
        let (sent, done) = run(Request::InquireIdentity(p), |f| {
            let c = &f[4..6];
            vec![format!("7E4 {c} 78 56 34 12 00 00 00")]
        });
        assert_eq!(sent, [format!("7E5 {:02X} 00 00 00 00 00 00 00", 0x5A + p)]);
        assert_eq!(done.result, Ok(Answer::Value(0x1234_5678)));
    }
    let (sent, _) =
        run(Request::IdentifyRemote { vendor: 1, product: 2, revision: (3, 4), serial: (5, 0xFFFF_FFFF) }, |_| vec![]);
    assert_eq!(
        sent,
        [
            "7E5 46 01 00 00 00 00 00 00",
            "7E5 47 02 00 00 00 00 00 00",
            "7E5 48 03 00 00 00 00 00 00",
            "7E5 49 04 00 00 00 00 00 00",
            "7E5 4A 05 00 00 00 00 00 00",
            "7E5 4B FF FF FF FF 00 00 00"
        ]
    );
}

#[test]
fn errors_name_the_step() {
    let (_, d) = run(Request::ConfigureNodeId(5), |_| vec!["7E4 11 01 00 00 00 00 00 00".into()]);
    assert_eq!(d.result.unwrap_err().to_string(), "LSS configure node-ID 5: refused: node-ID out of range");
    let (_, d) = run(Request::ConfigureBitTiming(3), |_| vec!["7E4 13 01 00 00 00 00 00 00".into()]);
    assert_eq!(
        d.result.unwrap_err().to_string(),
        "LSS configure bit timing 250 kbit/s (index 3): refused: bit rate not supported by the device"
    );
    let (_, d) = run(Request::Store, |_| vec!["7E4 17 02 00 00 00 00 00 00".into()]);
    assert_eq!(d.result.unwrap_err().to_string(), "LSS store configuration: refused: storage media access error");
    let (sent, d) = run(Request::ConfigureBitTiming(5), |_| vec![]);
    assert!(sent.is_empty(), "an index outside the table is refused before sending");
    assert_eq!(
        d.result.unwrap_err().to_string(),
        "LSS configure bit timing index 5: not a bit rate of the CiA 305 table (1000, 800, 500, 250, 125, 50, 20, 10 kbit/s)"
    );
    let (sent, d) = run(Request::ConfigureNodeId(0), |_| vec![]);
    assert!(sent.is_empty());
    assert_eq!(d.result.unwrap_err().kind, ErrorKind::Invalid);
    let (_, d) = run(Request::InquireIdentity(3), |_| vec![]);
    assert_eq!(d.result.unwrap_err().to_string(), "LSS inquire serial number: no answer within 20 ms");
    let id = Identity { vendor: 1, product: 2, revision: 3, serial: 4 };
    let (_, d) = run(Request::SwitchSelective(id), |f| {
        if f.starts_with("7E5 43") { vec!["7E4 44 00 00 00 00 00 00 00".into(); 2] } else { vec![] }
    });
    let e = d.result.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Duplicate(2));
    assert_eq!(
        e.to_string(),
        "LSS switch state selective (vendor 00000001h, product 00000002h, revision 00000003h, serial 00000004h): 2 devices answered: two devices have this identity"
    );
    // Answers on other COB-IDs, of other specifiers, or shorter are not taken.
    let (_, d) = run(Request::InquireNodeId, |_| {
        vec!["7E3 5E 01 00 00 00 00 00 00".into(), "7E4 5D 01 00 00 00 00 00 00".into(), "7E4 5E 01".into()]
    });
    assert_eq!(d.result.unwrap_err().kind, ErrorKind::Timeout(DEFAULT_TIMEOUT));
    let mut m = LssMaster::new();
    m.start(Request::Store, 0).unwrap();
    assert!(m.start(Request::Store, 0).is_err(), "one request at a time");
}

/// Devices on one in-memory bus with the master, in virtual time.
struct Net {
    devs: Vec<TestDevice>,
    now: u64,
    frames: usize,
}

impl Net {
    fn new(serials: &[(u32, Option<u8>)]) -> Self {
        let devs = serials
            .iter()
            .map(|&(serial, node)| {
                let mut d =
                    Device::new(TestOd::new(), Recorder::default(), MemStorage::default(), NodeId::new(1).unwrap());
                d.enable_lss(node.and_then(NodeId::new));
                d.poll(0, |_| {});
                // After the first reset, which restores the defaults.
                d.od_mut().set(0x1018, 4, i128::from(serial));
                d
            })
            .collect();
        Self { devs, now: 0, frames: 0 }
    }

    fn run(&mut self, m: &mut LssMaster, req: Request) -> Done {
        m.start(req, self.now).unwrap();
        loop {
            let mut out = Vec::new();
            if let Some(d) = m.poll(self.now, &mut |f| out.push(f)) {
                self.deliver(&out);
                return d;
            }
            self.frames += out.len();
            let answers = self.deliver(&out);
            self.now += 200;
            for a in answers {
                if let Some(d) = m.on_frame(&a, self.now) {
                    return d;
                }
            }
            if let Some(dl) = m.deadline() {
                self.now = self.now.max(dl);
            }
        }
    }

    fn deliver(&mut self, out: &[Frame]) -> Vec<Frame> {
        let mut answers = Vec::new();
        for f in out {
            for d in &mut self.devs {
                d.on_frame(f, self.now);
                d.poll(self.now, |a| answers.push(a));
            }
        }
        answers
    }
}

#[test]
fn fastscan_finds_three_devices_one_after_the_other() {
    let serials = [1001, 1002, 77];
    let mut net = Net::new(&serials.map(|s| (s, None)));
    let mut m = LssMaster::new();
    let mut found = Vec::new();
    loop {
        match net.run(&mut m, Request::Fastscan([None; 4])).result.unwrap() {
            Answer::Found(Some(id)) => found.push(id.serial),
            Answer::Found(None) => break,
            other => panic!("{other:?}"),
        }
        assert!(found.len() <= 3);
    }
    found.sort();
    assert_eq!(found, [77, 1001, 1002]);
    // Narrowed by vendor, product and revision: the serial number's 31 bits and a
    // confirmation or two per device.
    let mut net = Net::new(&serials.map(|s| (s, None)));
    let start = net.frames;
    let known = [Some(0xABC), Some(0x402), Some(0x1_0000), None];
    let mut n = 0;
    while let Answer::Found(Some(id)) = net.run(&mut m, Request::Fastscan(known)).result.unwrap() {
        assert!(serials.contains(&id.serial));
        // Give it a node-ID: it leaves the scan.
        net.run(&mut m, Request::ConfigureNodeId(2 + n));
        net.run(&mut m, Request::SwitchGlobal(Mode::Waiting));
        n += 1;
    }
    assert_eq!(n, 3);
    let per_device = (net.frames - start) / 3;
    assert!(per_device < 40, "{per_device} frames a device");
    let mut ids: Vec<u8> = net.devs.iter().map(|d| d.active_node_id().unwrap().get()).collect();
    ids.sort();
    assert_eq!(ids, [2, 3, 4]);
}

#[test]
fn fastscan_errors_duplicate_vanished_and_wrong_narrowing() {
    let mut m = LssMaster::new();
    let mut net = Net::new(&[(5, None), (5, None)]);
    let e = net.run(&mut m, Request::Fastscan([None; 4])).result.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Duplicate(2));
    assert!(e.to_string().contains("serial number 00000005h"), "{e}");
    // A narrowing that matches no device.
    let mut net = Net::new(&[(5, None)]);
    let e = net.run(&mut m, Request::Fastscan([Some(0xDEAD), None, None, None])).result.unwrap_err();
    assert!(matches!(e.step, Step::FastscanConfirm { part: 0, known: true, .. }));
    assert_eq!(
        e.to_string(),
        "LSS fastscan, confirmation of the given vendor-ID 0000DEADh: no answer within 20 ms (no device without a node-ID has this vendor-ID: check the EDS given)"
    );
    // No device without a node-ID: found none after one step.
    let mut net = Net::new(&[(5, Some(3))]);
    let before = net.frames;
    assert_eq!(net.run(&mut m, Request::Fastscan([None; 4])).result, Ok(Answer::Found(None)));
    assert_eq!(net.frames - before, 1);
}

#[test]
fn a_device_that_stops_answering_mid_scan_is_a_timeout_naming_the_step() {
    let mut m = LssMaster::new();
    let mut net = Net::new(&[(5, None)]);
    m.start(Request::Fastscan([None; 4]), 0).unwrap();
    let mut steps = 0;
    let done = loop {
        let mut out = Vec::new();
        if let Some(d) = m.poll(net.now, &mut |f| out.push(f)) {
            break d;
        }
        steps += out.len();
        // The device is gone after 40 steps (in the product code).
        let answers = if steps < 40 { net.deliver(&out) } else { vec![] };
        net.now += 200;
        let mut end = None;
        for a in answers {
            end = end.or(m.on_frame(&a, net.now));
        }
        if let Some(d) = end {
            break d;
        }
        net.now = net.now.max(m.deadline().unwrap());
    };
    let e = done.result.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout(DEFAULT_TIMEOUT));
    assert!(matches!(e.step, Step::FastscanConfirm { part: 1, .. }), "{e}");
    assert!(e.to_string().ends_with("(the device stopped answering during the scan)"), "{e}");
    assert!(e.to_string().contains("found so far: vendor-ID 00000ABCh"), "{e}");
    assert!(net.now < 40 * DEFAULT_TIMEOUT, "bounded: {} µs", net.now);
}

/// Switch state selective counts answers after its first one for the settle time, or as long
/// again as the first answer took, not for the whole step timeout.
#[test]
fn switch_selective_ends_soon_after_its_answer_and_still_sees_a_duplicate() {
    let id = Identity { vendor: 1, product: 2, revision: 3, serial: 4 };
    let answer = frame("7E4 44 00 00 00 00 00 00 00");
    // Answered after 300 µs: ends 2 ms (the settle time) later, not after 20 ms.
    let mut m = LssMaster::new();
    m.start(Request::SwitchSelective(id), 0).unwrap();
    assert!(m.poll(0, &mut |_| {}).is_none());
    assert_eq!(m.deadline(), Some(DEFAULT_TIMEOUT));
    assert!(m.on_frame(&answer, 300).is_none());
    assert_eq!(m.deadline(), Some(2_300));
    assert_eq!(m.poll(2_300, &mut |_| {}).map(|d| d.result), Some(Ok(Answer::Done)));
    // A second device right behind the first: a duplicate.
    m.start(Request::SwitchSelective(id), 10_000).unwrap();
    assert!(m.poll(10_000, &mut |_| {}).is_none());
    assert!(m.on_frame(&answer, 10_300).is_none());
    assert!(m.on_frame(&answer, 11_000).is_none());
    let e = m.poll(12_300, &mut |_| {}).unwrap().result.unwrap_err();
    assert_eq!((e.step, e.kind), (Step::SwitchSelective(id), ErrorKind::Duplicate(2)));
    // A slow answer (8 ms): the window is as long again, within the step timeout.
    m.start(Request::SwitchSelective(id), 50_000).unwrap();
    assert!(m.poll(50_000, &mut |_| {}).is_none());
    assert!(m.on_frame(&answer, 58_000).is_none());
    assert_eq!(m.deadline(), Some(66_000));
    // Answered after 15 ms: the step timeout (20 ms) still bounds it.
    assert_eq!(m.poll(66_000, &mut |_| {}).map(|d| d.result), Some(Ok(Answer::Done)));
    m.start(Request::SwitchSelective(id), 100_000).unwrap();
    assert!(m.poll(100_000, &mut |_| {}).is_none());
    assert!(m.on_frame(&answer, 115_000).is_none());
    assert_eq!(m.deadline(), Some(100_000 + DEFAULT_TIMEOUT));
}
