//! An emulated CAN wire: a channel that carries at most what a real bus of a given bit rate
//! carries, frames arbitrated by identifier (`drive-sim hub --bitrate`, `run --listen
//! --bitrate`).
//!
//! Each member of the channel has a small transmit queue (like a CAN controller's transmit
//! buffers). When the wire is free it takes, among the first frames of every queue, the one
//! that wins arbitration (the lowest identifier, a standard frame before an extended one with
//! the same base identifier, a data frame before a remote one), keeps the bus busy for the
//! frame's exact length in bits (stuff bits counted, interframe space included) and delivers
//! it to the other members when its last bit has passed. A member's own frames keep their
//! order, as in a controller that sends its buffers in order.
//!
//! A TCP client whose queue is full waits (its reader thread stops reading, so TCP slows the
//! client down to what the wire carries); an in-process endpoint loses the frame, counted.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

use crate::frame::CanFrame;
use crate::queue::lock;
use crate::sink::MemberId;
use crate::timestamp::Timestamp;

/// Frames one member may have waiting for the wire.
pub(crate) const TX_QUEUE: usize = 16;

/// How far a busy wire may run behind real time and catch up. Sleeps overshoot, by
/// milliseconds on a loaded machine; while frames wait, the bus time an overshoot lost is made
/// up by sending the next frames back to back, so the wire keeps its rate on average. An idle
/// wire earns no such credit: the frame that ends the idleness starts at once.
const CATCH_UP: Duration = Duration::from_millis(50);

/// Frames delivered this much before their last bit would have passed are fine: a frame that
/// finds the bus free and is this short (any frame at 1 Mbit/s) goes at once, from the
/// sender's thread, and the wire's thread waits only for longer gaps.
const EARLY: Duration = Duration::from_micros(500);

/// Bits a frame takes on the wire: start of frame to the end of the intermission (3 bits),
/// stuff bits included (computed from the actual identifier, data and CRC).
///
/// ```text
/// standard data frame, 8 bytes, no stuff bits: 1 + 11 + 3 + 4 + 64 + 15 + 1 + 2 + 7 + 3 = 111
/// ```
pub fn frame_bits(frame: &CanFrame) -> u32 {
    // The stuffed region: SOF through the CRC sequence, at most 1 + 32 + 6 + 64 + 15 bits.
    let mut bits = [false; 128];
    let mut n = 0;
    let push = |value: u32, width: u32, bits: &mut [bool; 128], n: &mut usize| {
        for i in (0..width).rev() {
            bits[*n] = (value >> i) & 1 == 1;
            *n += 1;
        }
    };
    push(0, 1, &mut bits, &mut n); // start of frame (dominant)
    let remote = u32::from(frame.is_remote());
    if frame.is_extended() {
        push(frame.id() >> 18, 11, &mut bits, &mut n);
        push(1, 1, &mut bits, &mut n); // SRR (recessive)
        push(1, 1, &mut bits, &mut n); // IDE (recessive: extended)
        push(frame.id() & 0x3_FFFF, 18, &mut bits, &mut n);
        push(remote, 1, &mut bits, &mut n); // RTR
        push(0, 2, &mut bits, &mut n); // r1, r0
    } else {
        push(frame.id(), 11, &mut bits, &mut n);
        push(remote, 1, &mut bits, &mut n); // RTR
        push(0, 2, &mut bits, &mut n); // IDE (dominant: standard), r0
    }
    push(u32::from(frame.dlc()), 4, &mut bits, &mut n);
    if !frame.is_remote() {
        for &byte in frame.data() {
            push(u32::from(byte), 8, &mut bits, &mut n);
        }
    }
    let crc = crc15(&bits[..n]);
    push(u32::from(crc), 15, &mut bits, &mut n);
    let stuffed = stuff_bits(&bits[..n]);
    // CRC delimiter, ACK slot and delimiter, end of frame, intermission.
    (n as u32) + stuffed + 1 + 2 + 7 + 3
}

/// The CAN CRC (polynomial 0x4599) of a bit sequence.
fn crc15(bits: &[bool]) -> u16 {
    let mut crc: u16 = 0;
    for &bit in bits {
        let next = bit ^ ((crc >> 14) & 1 == 1);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= 0x4599;
        }
    }
    crc
}

/// Stuff bits a transmitter inserts into `bits`: one of the opposite level after every five
/// equal bits, the stuff bit itself starting the next run.
fn stuff_bits(bits: &[bool]) -> u32 {
    let Some((&first, rest)) = bits.split_first() else { return 0 };
    let (mut level, mut run, mut stuffed) = (first, 1, 0);
    for &bit in rest {
        if bit == level {
            run += 1;
            if run == 5 {
                stuffed += 1;
                level = !bit;
                run = 1;
            }
        } else {
            level = bit;
            run = 1;
        }
    }
    stuffed
}

/// Orders frames as arbitration does: the smaller key wins. The key is the arbitration field
/// read bit by bit (base identifier, then RTR/SRR, IDE, extension, RTR), dominant = 0.
pub fn arbitration_key(frame: &CanFrame) -> u32 {
    let remote = u32::from(frame.is_remote());
    if frame.is_extended() {
        ((frame.id() >> 18) << 21) | (1 << 20) | (1 << 19) | ((frame.id() & 0x3_FFFF) << 1) | remote
    } else {
        (frame.id() << 21) | (remote << 20)
    }
}

struct State {
    queues: Vec<(MemberId, VecDeque<CanFrame>)>,
    closed: bool,
    /// When the last frame booked on the bus ends.
    free_at: Instant,
    /// The frame on the wire (it won arbitration) and when its last bit passes.
    on_wire: Option<(MemberId, CanFrame, Instant)>,
    /// A thread is handing a frame to the members (outside the lock): frames leave one at a
    /// time, in order.
    delivering: bool,
}

/// Frames handed to the members together, each with its sender.
pub(crate) type Batch = [(MemberId, CanFrame)];

/// What a thread working the wire does next.
enum Step {
    /// Hand these frames (sender, frame), in order, to the members; then clear `delivering`.
    Deliver(Vec<(MemberId, CanFrame)>),
    /// Nothing before this moment.
    WaitUntil(Instant),
    /// Nothing until a frame is queued or a delivery ends.
    Wait,
}

/// The wire of one channel (see the [module docs](self)).
///
/// The sender's thread itself delivers a frame that finds the bus free and ends within
/// [`EARLY`] (every frame at 1 Mbit/s on an idle bus), so a quiet bus adds no thread switch;
/// the wire's thread ([`Wire::carry`]) delivers the rest when their time comes.
pub(crate) struct Wire {
    bitrate: u32,
    state: Mutex<State>,
    /// Signalled when the wire's thread may have work: a frame queued, a delivery ended, the
    /// wire closed.
    ready: Condvar,
    /// Signalled when a frame left a queue.
    space: Condvar,
}

impl Wire {
    pub(crate) fn new(bitrate: u32) -> Self {
        Self {
            bitrate: bitrate.max(1),
            state: Mutex::new(State {
                queues: Vec::new(),
                closed: false,
                free_at: Instant::now(),
                on_wire: None,
                delivering: false,
            }),
            ready: Condvar::new(),
            space: Condvar::new(),
        }
    }

    fn length(&self, frame: &CanFrame) -> Duration {
        Duration::from_nanos(u64::from(frame_bits(frame)) * 1_000_000_000 / u64::from(self.bitrate))
    }

    /// Queues `frame` from `from`. A full queue waits up to `block` for room (none: drop at
    /// once). Returns false when the frame was dropped (queue full, or the wire closed). If
    /// the bus is free the frame (or one that beats it) goes at once, `deliver` handing it to
    /// the members from this thread.
    pub(crate) fn submit(
        &self,
        from: MemberId,
        frame: CanFrame,
        block: Option<Duration>,
        deliver: &dyn Fn(&Batch, Timestamp),
    ) -> bool {
        let deadline = block.and_then(|b| Instant::now().checked_add(b));
        let mut state = lock(&self.state);
        loop {
            if state.closed {
                return false;
            }
            let idle = !state.delivering && state.on_wire.is_none() && state.queues.iter().all(|(_, q)| q.is_empty());
            let at = match state.queues.iter().position(|(id, _)| *id == from) {
                Some(at) => at,
                None => {
                    state.queues.push((from, VecDeque::with_capacity(TX_QUEUE)));
                    state.queues.len() - 1
                }
            };
            if state.queues[at].1.len() < TX_QUEUE {
                state.queues[at].1.push_back(frame);
                let now = Instant::now();
                if idle && state.free_at < now {
                    state.free_at = now; // an idle bus earns no catch-up credit
                }
                break;
            }
            let Some(deadline) = deadline else { return false };
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            state = self.space.wait_timeout(state, left).unwrap_or_else(PoisonError::into_inner).0;
        }
        while let Step::Deliver(batch) = self.step(&mut state, Instant::now()) {
            drop(state);
            deliver(&batch, Timestamp::now());
            state = lock(&self.state);
            state.delivering = false;
        }
        let more = state.on_wire.is_some() || state.queues.iter().any(|(_, q)| !q.is_empty());
        drop(state);
        if more {
            self.ready.notify_one();
        }
        true
    }

    /// Drops the queue of a member that left.
    pub(crate) fn forget(&self, id: MemberId) {
        lock(&self.state).queues.retain(|(member, _)| *member != id);
        self.space.notify_all();
    }

    pub(crate) fn close(&self) {
        lock(&self.state).closed = true;
        self.ready.notify_all();
        self.space.notify_all();
    }

    /// The frame that wins arbitration among the first of every queue, taken out.
    fn pop_winner(state: &mut State) -> Option<(MemberId, CanFrame)> {
        let (_, at) = state
            .queues
            .iter()
            .enumerate()
            .filter_map(|(at, (_, queue))| queue.front().map(|f| (arbitration_key(f), at)))
            .min()?;
        let (from, queue) = &mut state.queues[at];
        let from = *from;
        let frame = queue.pop_front()?;
        if queue.is_empty() {
            state.queues.swap_remove(at);
        }
        Some((from, frame))
    }

    /// Moves the wire on to `now`: the frames whose last bit has (nearly) passed are delivered,
    /// in one batch, and a free bus starts the next frame to win arbitration. Handing frames
    /// to the members costs a wake-up per member, so a wire that delivered one frame at a time
    /// would carry less than its bit rate on a busy machine; a batch costs the same.
    fn step(&self, state: &mut State, now: Instant) -> Step {
        const MAX_BATCH: usize = 64;
        if state.closed || state.delivering {
            return Step::Wait;
        }
        let mut batch = Vec::new();
        let mut popped = false;
        let wait = loop {
            if let Some((_, _, end)) = state.on_wire {
                if end > now + EARLY {
                    break Step::WaitUntil(end - EARLY);
                }
                let (from, frame, _) = state.on_wire.take().expect("checked above");
                batch.push((from, frame));
            }
            if batch.len() >= MAX_BATCH {
                break Step::Wait;
            }
            // The bus is free: arbitration among the waiting frames. A bus that ran late while
            // frames waited makes up at most CATCH_UP of lost time.
            let start = state.free_at.max(now.checked_sub(CATCH_UP).unwrap_or(now));
            if start > now + EARLY {
                break Step::WaitUntil(start - EARLY);
            }
            let Some((from, frame)) = Self::pop_winner(state) else { break Step::Wait };
            popped = true;
            let end = start + self.length(&frame);
            state.free_at = end;
            state.on_wire = Some((from, frame, end));
        };
        if popped {
            self.space.notify_all();
        }
        if batch.is_empty() {
            return wait;
        }
        state.delivering = true;
        Step::Deliver(batch)
    }

    /// The wire's thread: delivers the frames no sender's thread could, when their time comes,
    /// until the wire closes or `deliver` returns false (the channel is gone).
    pub(crate) fn carry(&self, mut deliver: impl FnMut(&[(MemberId, CanFrame)], Timestamp) -> bool) {
        let mut state = lock(&self.state);
        loop {
            if state.closed {
                return;
            }
            match self.step(&mut state, Instant::now()) {
                Step::Deliver(batch) => {
                    drop(state);
                    let alive = deliver(&batch, Timestamp::now());
                    state = lock(&self.state);
                    state.delivering = false;
                    if !alive {
                        return;
                    }
                }
                Step::WaitUntil(at) => {
                    let left = at.saturating_duration_since(Instant::now()).max(Duration::from_micros(1));
                    state = self.ready.wait_timeout(state, left).unwrap_or_else(PoisonError::into_inner).0;
                }
                Step::Wait => {
                    // Waiting frames with nobody delivering are stepped again at once.
                    if !state.delivering && state.queues.iter().any(|(_, q)| !q.is_empty()) {
                        continue;
                    }
                    state = self.ready.wait(state).unwrap_or_else(PoisonError::into_inner);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn std(id: u32, data: &[u8]) -> CanFrame {
        CanFrame::standard(id, data).unwrap()
    }

    #[test]
    fn a_frame_without_stuff_bits_has_the_textbook_length() {
        // 0x555 data 0x55..: alternating levels, so no run of five reaches the stuffing rule
        // before the CRC; the count is the unstuffed length plus whatever the CRC needs.
        let bits = frame_bits(&std(0x555, &[0x55; 8]));
        assert!((111..=111 + 4).contains(&bits), "{bits}");
    }

    #[test]
    fn lengths_lie_between_the_unstuffed_and_the_worst_case_length() {
        // Unstuffed: 47 + 8n standard, 67 + 8n extended; worst case adds one stuff bit per
        // four bits of the stuffed region after the first (34 + 8n or 54 + 8n bits).
        for id in [0u32, 1, 0x7F, 0x555, 0x7FF] {
            for len in 0..=8usize {
                for fill in [0x00u8, 0xFF, 0xAA, 0x0F, 0x3C] {
                    let data = vec![fill; len];
                    let n = 8 * len as u32;
                    let b = frame_bits(&std(id, &data));
                    assert!((47 + n..=47 + n + (34 + n - 1) / 4).contains(&b), "std {id:x} {len} {fill:x}: {b}");
                    let ext = CanFrame::extended(id << 18 | 0x2_AAAA, &data).unwrap();
                    let b = frame_bits(&ext);
                    assert!((67 + n..=67 + n + (54 + n - 1) / 4).contains(&b), "ext {id:x} {len} {fill:x}: {b}");
                }
            }
        }
        // Zeros stuff more than alternating bits.
        assert!(frame_bits(&std(0, &[0; 8])) > frame_bits(&std(0x555, &[0x55; 8])));
    }

    #[test]
    fn stuffing_follows_the_five_equal_bits_rule() {
        assert_eq!(stuff_bits(&[false; 4]), 0);
        assert_eq!(stuff_bits(&[false; 5]), 1);
        // The stuff bit (1) starts a run: 0000 0 [1] 1111 -> a second stuff bit after four 1s.
        assert_eq!(stuff_bits(&[false, false, false, false, false, true, true, true, true]), 2);
        assert_eq!(stuff_bits(&[true, false, true, false, true, false]), 0);
    }

    #[test]
    fn arbitration_orders_by_identifier_standard_before_extended_and_data_before_remote() {
        let key = |f: CanFrame| arbitration_key(&f);
        assert!(key(std(0x080, &[])) < key(std(0x181, &[1])));
        assert!(key(std(0x181, &[])) < key(CanFrame::remote(0x181, false, 0).unwrap()));
        assert!(key(CanFrame::remote(0x181, false, 0).unwrap()) < key(CanFrame::extended(0x181 << 18, &[]).unwrap()));
        assert!(key(CanFrame::extended(0x100 << 18 | 5, &[]).unwrap()) < key(std(0x101, &[])));
        assert!(key(CanFrame::extended(1, &[]).unwrap()) < key(CanFrame::extended(2, &[]).unwrap()));
    }

    #[test]
    fn a_full_transmit_queue_drops_or_waits_and_the_winner_leaves_first() {
        // 1000 bit/s: no frame is short enough to go from the sender's thread.
        let wire = Wire::new(1_000);
        let never = |batch: &[(MemberId, CanFrame)], _: Timestamp| panic!("{batch:?} delivered inline");
        for i in 0..TX_QUEUE as u32 {
            assert!(wire.submit(1, std(0x700 - i, &[]), None, &never));
        }
        // The first frame went on the wire at once: room for one more.
        assert!(wire.submit(1, std(0x6F0, &[]), None, &never));
        assert!(!wire.submit(1, std(0x100, &[]), None, &never), "queue full: dropped");
        assert!(!wire.submit(1, std(0x100, &[]), Some(Duration::from_millis(1)), &never), "still full after waiting");
        assert!(wire.submit(2, std(0x7FF, &[]), None, &never));
        assert!(wire.submit(3, std(0x001, &[]), None, &never));
        let mut state = lock(&wire.state);
        assert_eq!(state.on_wire.as_ref().map(|(from, f, _)| (*from, f.id())), Some((1, 0x700)));
        // Member 3's frame has the lowest id; member 1's queue goes in its own order.
        assert_eq!(Wire::pop_winner(&mut state).map(|(from, f)| (from, f.id())), Some((3, 0x001)));
        assert_eq!(Wire::pop_winner(&mut state).map(|(from, f)| (from, f.id())), Some((1, 0x6FF)));
        drop(state);
        wire.forget(1);
        let mut state = lock(&wire.state);
        assert_eq!(Wire::pop_winner(&mut state).map(|(from, f)| (from, f.id())), Some((2, 0x7FF)));
        assert!(Wire::pop_winner(&mut state).is_none());
        drop(state);
        wire.close();
        assert!(!wire.submit(2, std(1, &[]), None, &never));
    }

    #[test]
    fn a_short_frame_on_a_free_bus_is_delivered_by_the_sender_and_the_next_waits_its_turn() {
        let wire = Wire::new(1_000_000);
        let delivered = std::cell::RefCell::new(Vec::new());
        let record = |batch: &[(MemberId, CanFrame)], _: Timestamp| {
            delivered.borrow_mut().extend(batch.iter().map(|(from, f)| (*from, f.id())))
        };
        assert!(wire.submit(1, std(0x080, &[]), None, &record));
        assert_eq!(*delivered.borrow(), [(1, 0x080)], "an idle 1 Mbit/s bus: at once, from this thread");
        let state = lock(&wire.state);
        assert!(state.on_wire.is_none() && !state.delivering);
    }

    #[test]
    fn a_backlog_that_is_due_leaves_in_one_batch_in_arbitration_order() {
        let wire = Wire::new(1_000_000);
        let now = Instant::now();
        let mut state = lock(&wire.state);
        for (member, ids) in [(1, [0x701, 0x181]), (2, [0x080, 0x702]), (3, [0x581, 0x100])] {
            state.queues.push((member, ids.iter().map(|&id| std(id, &[1, 2])).collect()));
        }
        // The wire ran late while they waited: all six frames' time has passed.
        state.free_at = now - Duration::from_millis(5);
        let Step::Deliver(batch) = wire.step(&mut state, now) else { panic!("nothing due") };
        let order: Vec<(MemberId, u32)> = batch.iter().map(|(from, f)| (*from, f.id())).collect();
        // Per member in order; across members lowest id first among the heads.
        assert_eq!(order, [(2, 0x080), (3, 0x581), (3, 0x100), (1, 0x701), (1, 0x181), (2, 0x702)]);
        assert!(state.delivering && state.on_wire.is_none());
        assert!(matches!(wire.step(&mut state, now), Step::Wait), "one delivery at a time");
    }
}
