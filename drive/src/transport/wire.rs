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

use super::CanFrame;
use super::bus::MemberId;
use super::queue::lock;
use super::socketcand::Timestamp;

/// Frames one member may have waiting for the wire.
pub(crate) const TX_QUEUE: usize = 16;

/// How far a busy wire may run behind real time and catch up. Sleeps overshoot, by
/// milliseconds on a loaded machine; while frames wait, the bus time an overshoot lost is made
/// up by sending the next frames back to back, so the wire keeps its rate on average. An idle
/// wire earns no such credit: the frame that ends the idleness starts at once.
const CATCH_UP: Duration = Duration::from_millis(50);

/// Frames delivered this much before their last bit would have passed are fine: the wire
/// sleeps only for longer gaps, which saves a system call per frame at high bit rates.
const EARLY: Duration = Duration::from_micros(100);

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
}

/// The wire of one channel (see the [module docs](self)).
pub(crate) struct Wire {
    bitrate: u32,
    state: Mutex<State>,
    /// Signalled when a frame is queued or the wire closes.
    ready: Condvar,
    /// Signalled when a frame left a queue.
    space: Condvar,
}

impl Wire {
    pub(crate) fn new(bitrate: u32) -> Self {
        Self {
            bitrate: bitrate.max(1),
            state: Mutex::new(State { queues: Vec::new(), closed: false }),
            ready: Condvar::new(),
            space: Condvar::new(),
        }
    }

    /// Queues `frame` from `from`. A full queue waits up to `block` for room (none: drop at
    /// once). Returns false when the frame was dropped (queue full, or the wire closed).
    pub(crate) fn submit(&self, from: MemberId, frame: CanFrame, block: Option<Duration>) -> bool {
        let deadline = block.and_then(|b| Instant::now().checked_add(b));
        let mut state = lock(&self.state);
        loop {
            if state.closed {
                return false;
            }
            let at = match state.queues.iter().position(|(id, _)| *id == from) {
                Some(at) => at,
                None => {
                    state.queues.push((from, VecDeque::with_capacity(TX_QUEUE)));
                    state.queues.len() - 1
                }
            };
            let queue = &mut state.queues[at].1;
            if queue.len() < TX_QUEUE {
                queue.push_back(frame);
                drop(state);
                self.ready.notify_one();
                return true;
            }
            let Some(deadline) = deadline else { return false };
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            state = self.space.wait_timeout(state, left).unwrap_or_else(PoisonError::into_inner).0;
        }
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

    /// The next frame to win arbitration, waiting for one, and whether the wire had to wait
    /// (was idle); `None` once closed.
    fn next(&self) -> Option<(MemberId, CanFrame, bool)> {
        let mut state = lock(&self.state);
        let mut waited = false;
        loop {
            if state.closed {
                return None;
            }
            let winner = state
                .queues
                .iter()
                .enumerate()
                .filter_map(|(at, (_, queue))| queue.front().map(|f| (arbitration_key(f), at)))
                .min();
            if let Some((_, at)) = winner {
                let (from, queue) = &mut state.queues[at];
                let from = *from;
                let frame = queue.pop_front()?;
                if queue.is_empty() {
                    state.queues.swap_remove(at);
                }
                drop(state);
                self.space.notify_all();
                return Some((from, frame, waited));
            }
            waited = true;
            state = self.ready.wait(state).unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// The wire's thread: carries frames until the wire closes or `deliver` returns false (the
    /// channel is gone).
    pub(crate) fn carry(&self, mut deliver: impl FnMut(MemberId, CanFrame, Timestamp) -> bool) {
        let mut free_at = Instant::now();
        while let Some((from, frame, idle)) = self.next() {
            let bits = u64::from(frame_bits(&frame));
            let length = Duration::from_nanos(bits * 1_000_000_000 / u64::from(self.bitrate));
            let now = Instant::now();
            let start = if idle { free_at.max(now) } else { free_at.max(now.checked_sub(CATCH_UP).unwrap_or(now)) };
            free_at = start + length;
            if free_at > now + EARLY {
                std::thread::sleep(free_at - now);
            }
            if !deliver(from, frame, Timestamp::now()) {
                return;
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
        let wire = Wire::new(1_000_000);
        for i in 0..TX_QUEUE as u32 {
            assert!(wire.submit(1, std(0x700 - i, &[]), None));
        }
        assert!(!wire.submit(1, std(0x100, &[]), None), "queue full: dropped");
        assert!(!wire.submit(1, std(0x100, &[]), Some(Duration::from_millis(1))), "still full after waiting");
        assert!(wire.submit(2, std(0x7FF, &[]), None));
        assert!(wire.submit(3, std(0x001, &[]), None));
        // Member 3's frame has the lowest id; member 1's queue goes in its own order.
        assert_eq!(wire.next().map(|(from, f, _)| (from, f.id())), Some((3, 0x001)));
        assert_eq!(wire.next().map(|(from, f, _)| (from, f.id())), Some((1, 0x700)));
        wire.forget(1);
        assert_eq!(wire.next().map(|(from, f, _)| (from, f.id())), Some((2, 0x7FF)));
        wire.close();
        assert!(wire.next().is_none());
        assert!(!wire.submit(2, std(1, &[]), None));
    }
}
