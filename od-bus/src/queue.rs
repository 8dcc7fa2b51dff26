//! A bounded, closable FIFO shared between threads: the receive queue of every in-process
//! endpoint and the send queue of every TCP client of the hub.
//!
//! Pushing never blocks: a full queue refuses the item and the caller decides what overflow means
//! (an in-process endpoint drops the frame and counts it, the hub disconnects a TCP client). This
//! is what keeps one slow reader from stalling the others.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// Locks a mutex, ignoring poisoning: the data behind our mutexes (queues, member lists) stays
/// consistent even if a thread panicked while holding the lock, and the hub must keep serving.
pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Why [`BoundedQueue::push`] refused an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PushError {
    /// The queue holds `capacity` items already.
    Full,
    /// The queue was closed; nobody will take items out any more.
    Closed,
}

/// The queue was closed and is empty.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Closed;

struct State<T> {
    items: VecDeque<T>,
    closed: bool,
    /// Consumers blocked in `wait`: a push wakes someone only when there is someone to wake,
    /// which saves a futex system call per frame on the common path.
    waiters: usize,
    /// The consumer of [`BoundedQueue::drain_blocking`] took items and has not come back for
    /// more: it is still handing them on, so nothing may overtake them
    /// ([`BoundedQueue::push_or_hand`]).
    working: bool,
    /// [`BoundedQueue::hold`]: the consumer of `drain_blocking` takes nothing until
    /// [`BoundedQueue::release`], and nothing is handed past the queue.
    held: bool,
}

/// Bounded multi-producer FIFO with blocking, timed receive.
pub(crate) struct BoundedQueue<T> {
    state: Mutex<State<T>>,
    ready: Condvar,
    capacity: usize,
}

impl<T> BoundedQueue<T> {
    /// A queue holding at most `capacity` items (at least one).
    pub(crate) fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            state: Mutex::new(State {
                items: VecDeque::with_capacity(capacity.min(1024)),
                closed: false,
                waiters: 0,
                working: false,
                held: false,
            }),
            ready: Condvar::new(),
            capacity,
        }
    }

    /// Appends an item without blocking.
    pub(crate) fn push(&self, item: T) -> Result<(), PushError> {
        self.push_within(item, self.capacity)
    }

    /// Appends an item without blocking if fewer than `limit` are queued (`limit` may exceed
    /// the capacity: room kept for items that must not be dropped, such as protocol replies).
    pub(crate) fn push_within(&self, item: T, limit: usize) -> Result<(), PushError> {
        let mut state = lock(&self.state);
        if state.closed {
            return Err(PushError::Closed);
        }
        if state.items.len() >= limit {
            return Err(PushError::Full);
        }
        state.items.push_back(item);
        let wake = state.waiters > 0;
        drop(state);
        if wake {
            self.ready.notify_one();
        }
        Ok(())
    }

    /// Hands `item` to `direct` instead of queueing it when nothing is queued and the consumer
    /// holds no items it took earlier, so that nothing is overtaken; otherwise queues it like
    /// [`push`](BoundedQueue::push). `direct` runs under the queue's lock (other producers wait
    /// for it, so it must not block) and returns what it could not take, which is queued, first
    /// in line. For a queue drained with [`drain_blocking`](BoundedQueue::drain_blocking) only,
    /// which tracks whether its consumer is working.
    pub(crate) fn push_or_hand(&self, item: T, direct: impl FnOnce(T) -> Option<T>) -> Result<(), PushError> {
        let mut state = lock(&self.state);
        if state.closed {
            return Err(PushError::Closed);
        }
        let item = if state.items.is_empty() && !state.working && !state.held {
            match direct(item) {
                None => return Ok(()),
                Some(rest) => rest,
            }
        } else if state.items.len() >= self.capacity {
            return Err(PushError::Full);
        } else {
            item
        };
        state.items.push_back(item);
        let wake = state.waiters > 0;
        drop(state);
        if wake {
            self.ready.notify_one();
        }
        Ok(())
    }

    /// Appends every item that fits (one lock, one wake-up for the lot); returns how many did
    /// not fit, or `Err(PushError::Closed)`.
    pub(crate) fn push_all(&self, items: impl Iterator<Item = T>) -> Result<usize, PushError> {
        let mut state = lock(&self.state);
        if state.closed {
            return Err(PushError::Closed);
        }
        let mut refused = 0;
        for item in items {
            if state.items.len() >= self.capacity {
                refused += 1;
            } else {
                state.items.push_back(item);
            }
        }
        let wake = state.waiters > 0 && !state.items.is_empty();
        drop(state);
        if wake {
            self.ready.notify_one();
        }
        Ok(refused)
    }

    /// Takes the oldest item, waiting up to `timeout` for one. Items pushed before [`close`]
    /// are still handed out; `Err(Closed)` comes once the queue is closed and empty.
    ///
    /// [`close`]: BoundedQueue::close
    pub(crate) fn pop_timeout(&self, timeout: Duration) -> Result<Option<T>, Closed> {
        let deadline = Instant::now().checked_add(timeout);
        let mut state = lock(&self.state);
        loop {
            if let Some(item) = state.items.pop_front() {
                return Ok(Some(item));
            }
            if state.closed {
                return Err(Closed);
            }
            let remaining = match deadline {
                Some(deadline) => deadline.saturating_duration_since(Instant::now()),
                None => Duration::MAX,
            };
            if remaining.is_zero() {
                return Ok(None);
            }
            state.waiters += 1;
            state = self.ready.wait_timeout(state, remaining).unwrap_or_else(PoisonError::into_inner).0;
            state.waiters -= 1;
        }
    }

    /// Waits until at least one item is queued, then moves up to `max` items into `out`.
    /// Returns `Err(Closed)` as soon as the queue is closed, dropping what is left: the consumer
    /// (a TCP writer) is going away. The consumer counts as working on what it took until it
    /// calls again (see [`push_or_hand`](BoundedQueue::push_or_hand)).
    pub(crate) fn drain_blocking(&self, out: &mut Vec<T>, max: usize) -> Result<(), Closed> {
        let mut state = lock(&self.state);
        loop {
            if state.closed {
                state.items.clear();
                return Err(Closed);
            }
            if !state.items.is_empty() && !state.held {
                let take = state.items.len().min(max.max(1));
                out.extend(state.items.drain(..take));
                state.working = true;
                return Ok(());
            }
            state.working = false;
            state.waiters += 1;
            state = self.ready.wait(state).unwrap_or_else(PoisonError::into_inner);
            state.waiters -= 1;
        }
    }

    /// Keeps what is queued from here on from the consumer of
    /// [`drain_blocking`](BoundedQueue::drain_blocking) (and from `push_or_hand`'s direct path)
    /// until [`release`](BoundedQueue::release): a reply queued while held goes out only once
    /// what it announces is true.
    pub(crate) fn hold(&self) {
        lock(&self.state).held = true;
    }

    /// Ends a [`hold`](BoundedQueue::hold), waking the consumer if items wait.
    pub(crate) fn release(&self) {
        let mut state = lock(&self.state);
        state.held = false;
        let wake = state.waiters > 0 && !state.items.is_empty();
        drop(state);
        if wake {
            self.ready.notify_one();
        }
    }

    /// Number of queued items.
    pub(crate) fn len(&self) -> usize {
        lock(&self.state).items.len()
    }

    /// Closes the queue: later pushes fail and waiting consumers wake up.
    pub(crate) fn close(&self) {
        lock(&self.state).closed = true;
        self.ready.notify_all();
    }

    /// Whether [`close`](BoundedQueue::close) was called.
    pub(crate) fn is_closed(&self) -> bool {
        lock(&self.state).closed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn refuses_items_past_capacity_and_after_close() {
        let queue = BoundedQueue::new(2);
        assert_eq!(queue.push(1), Ok(()));
        assert_eq!(queue.push(2), Ok(()));
        assert_eq!(queue.push(3), Err(PushError::Full));
        assert_eq!(queue.len(), 2);
        assert_eq!(queue.pop_timeout(Duration::ZERO), Ok(Some(1)));
        queue.close();
        assert!(queue.is_closed());
        assert_eq!(queue.push(4), Err(PushError::Closed));
        assert_eq!(queue.pop_timeout(Duration::ZERO), Ok(Some(2)), "items queued before close are kept");
        assert_eq!(queue.pop_timeout(Duration::ZERO), Err(Closed));
    }

    /// Items are handed over directly only when that overtakes nothing: not while items are
    /// queued, nor while the consumer still holds items it took; what the direct taker leaves
    /// goes first in line.
    /// A thread draining `queue` (up to 10 items), returned once it waits in `drain_blocking`.
    fn blocked_consumer(queue: &Arc<BoundedQueue<i32>>) -> std::thread::JoinHandle<Result<Vec<i32>, Closed>> {
        let consumer = {
            let queue = Arc::clone(queue);
            std::thread::spawn(move || {
                let mut out = Vec::new();
                queue.drain_blocking(&mut out, 10).map(|()| out)
            })
        };
        while lock(&queue.state).waiters == 0 {
            std::thread::yield_now();
        }
        consumer
    }

    #[test]
    fn push_or_hand_never_lets_an_item_overtake_another() {
        let queue = BoundedQueue::new(2);
        let mut direct = Vec::new();
        let mut out = Vec::new();
        // Idle and empty: handed over.
        queue
            .push_or_hand(1, |i| {
                direct.push(i);
                None
            })
            .unwrap();
        // The taker leaves it: queued.
        queue.push_or_hand(2, Some).unwrap();
        // Something queued: queued behind it, the taker not asked.
        queue.push_or_hand(3, |_| unreachable!()).unwrap();
        assert_eq!(queue.push_or_hand(4, |_| unreachable!()), Err(PushError::Full));
        queue.drain_blocking(&mut out, 10).unwrap();
        assert_eq!(out, [2, 3]);
        // The consumer is working on 2 and 3: queued, though the queue is empty.
        queue.push_or_hand(5, |_| unreachable!()).unwrap();
        out.clear();
        queue.drain_blocking(&mut out, 10).unwrap();
        assert_eq!(out, [5]);
        // The consumer comes back for more and finds nothing: idle again.
        let waiting = Arc::new(queue);
        let consumer = blocked_consumer(&waiting);
        waiting
            .push_or_hand(6, |i| {
                direct.push(i);
                None
            })
            .unwrap();
        assert_eq!(direct, [1, 6]);
        waiting.push_or_hand(7, Some).unwrap();
        assert_eq!(consumer.join().unwrap(), Ok(vec![7]));
        waiting.close();
        assert_eq!(waiting.push_or_hand(8, |_| unreachable!()), Err(PushError::Closed));
    }

    #[test]
    fn a_held_queue_gives_nothing_to_its_consumer_and_hands_nothing_past_it() {
        let queue = Arc::new(BoundedQueue::new(8));
        queue.hold();
        // Empty and the consumer idle, but held: queued, not handed over.
        queue.push_or_hand(1, |_| unreachable!()).unwrap();
        queue.push(2).unwrap();
        // The consumer waits although items are queued.
        let consumer = blocked_consumer(&queue);
        queue.push(3).unwrap();
        assert!(!consumer.is_finished());
        queue.release();
        assert_eq!(consumer.join().unwrap(), Ok(vec![1, 2, 3]));
    }

    #[test]
    fn pop_times_out_on_an_empty_queue() {
        let queue = BoundedQueue::<u8>::new(1);
        let start = Instant::now();
        assert_eq!(queue.pop_timeout(Duration::from_millis(20)), Ok(None));
        assert!(start.elapsed() >= Duration::from_millis(20));
    }

    #[test]
    fn a_waiting_consumer_is_woken_by_push_and_close() {
        let queue = Arc::new(BoundedQueue::new(8));
        let consumer = {
            let queue = Arc::clone(&queue);
            std::thread::spawn(move || {
                let mut got = Vec::new();
                while queue.drain_blocking(&mut got, 8).is_ok() {}
                got
            })
        };
        queue.push(7).unwrap();
        while queue.len() > 0 {
            std::thread::yield_now();
        }
        queue.close();
        assert_eq!(consumer.join().unwrap(), vec![7]);
    }
}
