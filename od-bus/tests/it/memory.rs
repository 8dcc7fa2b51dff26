//! The in-memory bus: CAN broadcast semantics, deterministic without threads, usable with them.

use std::time::{Duration, Instant};

use od_bus::{CanFrame, Endpoint, MemoryBus};
use proptest::prelude::*;

fn frame(id: u32, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

fn drain(endpoint: &mut dyn Endpoint) -> Vec<CanFrame> {
    std::iter::from_fn(|| endpoint.try_recv().unwrap()).collect()
}

#[test]
fn a_frame_reaches_every_other_endpoint_in_send_order() {
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut drive_a = bus.endpoint();
    let mut drive_b = bus.endpoint();
    let nmt = frame(0x000, &[0x01, 0x00]);
    let sync = frame(0x080, &[]);
    master.send(nmt).unwrap();
    master.send(sync).unwrap();
    let boot = frame(0x705, &[0x00]);
    drive_a.send(boot).unwrap();

    assert_eq!(drain(&mut drive_a), [nmt, sync]);
    assert_eq!(drain(&mut drive_b), [nmt, sync, boot]);
    assert_eq!(drain(&mut master), [boot], "the sender never hears its own frames");
}

#[test]
fn an_endpoint_receives_only_what_was_sent_after_it_joined_and_leaves_when_dropped() {
    let bus = MemoryBus::new();
    let mut first = bus.endpoint();
    first.send(frame(0x100, &[1])).unwrap();
    let mut late = bus.endpoint();
    assert_eq!(late.try_recv().unwrap(), None);
    assert_eq!(bus.endpoint_count(), 2);
    drop(late);
    assert_eq!(bus.endpoint_count(), 1);
    // Sending with nobody listening is not an error, as on an idle CAN bus.
    first.send(frame(0x100, &[2])).unwrap();
}

#[test]
fn a_full_queue_drops_new_frames_and_counts_them_without_affecting_the_others() {
    let bus = MemoryBus::with_capacity(2);
    let mut sender = bus.endpoint();
    let mut slow = bus.endpoint();
    let mut fast = bus.endpoint();
    for i in 0..5 {
        sender.send(frame(0x200, &[i])).unwrap();
        assert_eq!(fast.try_recv().unwrap(), Some(frame(0x200, &[i])));
    }
    assert_eq!(slow.pending(), 2);
    assert_eq!(slow.dropped(), 3);
    assert_eq!(drain(&mut slow), [frame(0x200, &[0]), frame(0x200, &[1])], "the oldest frames are kept");
    assert_eq!(fast.dropped(), 0);
}

#[test]
fn recv_timeout_waits_and_gives_up() {
    let bus = MemoryBus::new();
    let mut lonely = bus.endpoint();
    let start = Instant::now();
    assert_eq!(lonely.recv_timeout(Duration::from_millis(30)).unwrap(), None);
    assert!(start.elapsed() >= Duration::from_millis(30));
}

#[test]
fn endpoints_work_across_threads() {
    let bus = MemoryBus::new();
    let mut master = bus.endpoint();
    let mut device = bus.endpoint();
    // A device answering each SDO upload request on 0x605 with a response on 0x585.
    let worker = std::thread::spawn(move || {
        let mut answered = 0;
        while answered < 100 {
            let Some(request) = device.recv_timeout(Duration::from_secs(5)).unwrap() else { break };
            let mut data = request.raw_data();
            data[0] = 0x4B;
            device.send(CanFrame::standard(0x585, &data).unwrap()).unwrap();
            answered += 1;
        }
        answered
    });
    for i in 0..100u8 {
        master.send(frame(0x605, &[0x40, i, 0x60, 0, 0, 0, 0, 0])).unwrap();
        let reply = master.recv_timeout(Duration::from_secs(5)).unwrap().expect("device answers");
        assert_eq!(reply.id(), 0x585);
        assert_eq!(reply.data()[..2], [0x4B, i]);
    }
    assert_eq!(worker.join().unwrap(), 100);
}

proptest! {
    /// Any interleaving of sends: each endpoint receives exactly the frames the others sent,
    /// in the order they were sent.
    #[test]
    fn broadcast_matches_a_model(sends in prop::collection::vec((0usize..4, 0u32..0x800, prop::collection::vec(any::<u8>(), 0..=8)), 0..64)) {
        let bus = MemoryBus::new();
        let mut endpoints: Vec<_> = (0..4).map(|_| bus.endpoint()).collect();
        let mut expected: Vec<Vec<CanFrame>> = vec![Vec::new(); 4];
        for (from, id, data) in &sends {
            let sent = frame(*id, data);
            endpoints[*from].send(sent).unwrap();
            for (to, inbox) in expected.iter_mut().enumerate() {
                if to != *from {
                    inbox.push(sent);
                }
            }
        }
        for (endpoint, want) in endpoints.iter_mut().zip(&expected) {
            prop_assert_eq!(&drain(endpoint), want);
        }
    }
}

/// A device's answers to one turn go out together: `send_all` on an in-process endpoint puts
/// them on the bus in order with no other member's frame between them (as a socket client's one
/// write does), while another member sends as fast as it can from another thread.
#[test]
fn send_all_keeps_a_batch_together_against_a_concurrent_sender() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

    const TURNS: u32 = 2_000;
    let bus = MemoryBus::new();
    let mut device = bus.endpoint();
    let mut other = bus.endpoint();
    let mut reader = bus.endpoint();
    let stop = Arc::new(AtomicBool::new(false));
    let chattered = Arc::new(AtomicU32::new(0));
    let read = Arc::new(AtomicU32::new(0));
    let chatter = {
        let (stop, chattered, read) = (Arc::clone(&stop), Arc::clone(&chattered), Arc::clone(&read));
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                // At most 16 of its frames unread at a time: the reader's queue never overflows,
                // however the threads are scheduled.
                let n = chattered.load(Ordering::Relaxed);
                if n < read.load(Ordering::Relaxed) + 16 {
                    other.send(frame(0x181, &n.to_le_bytes())).unwrap();
                    chattered.store(n + 1, Ordering::Relaxed);
                } else {
                    std::thread::yield_now();
                }
            }
        })
    };
    // The other sender is running before the first batch.
    while chattered.load(Ordering::Relaxed) < 8 {
        std::thread::yield_now();
    }
    let mut received = Vec::new();
    for turn in 0..TURNS {
        let t = turn.to_le_bytes();
        device.send_all(&[frame(0x582, &t), frame(0x583, &t), frame(0x584, &t)]).unwrap();
        // Read as we go.
        let got = drain(&mut reader);
        read.fetch_add(got.iter().filter(|f| f.id() == 0x181).count() as u32, Ordering::Relaxed);
        received.extend(got);
    }
    stop.store(true, Ordering::Relaxed);
    chatter.join().unwrap();
    received.extend(drain(&mut reader));
    assert_eq!(reader.dropped(), 0);
    let ids: Vec<u32> = received.iter().map(|f| f.id()).collect();
    let starts: Vec<usize> = ids.iter().enumerate().filter(|(_, id)| **id == 0x582).map(|(i, _)| i).collect();
    assert_eq!(starts.len(), TURNS as usize, "every batch arrived");
    let split = starts.iter().filter(|&&i| ids.get(i + 1..i + 3) != Some(&[0x583, 0x584][..])).count();
    assert_eq!(split, 0, "batches with another frame inside, of {TURNS}");
    assert!(ids.contains(&0x181), "the other sender's frames came too");
}
