//! What a channel delivers frames to: its members, each named by a [`MemberId`] and reached
//! through a [`Sink`]. Below both the channel (`bus`) and the emulated wire (`wire`), which
//! both speak of members and neither of which needs the other for it.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::frame::CanFrame;
use crate::timestamp::Timestamp;

/// Identifies one member of a channel (an endpoint or a TCP client), unique in the process.
pub(crate) type MemberId = u64;

pub(crate) fn next_member_id() -> MemberId {
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// What happened to a frame handed to a [`Sink`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delivery {
    /// Queued for the member.
    Accepted,
    /// The member's queue was full; the frame was dropped and the member stays.
    Dropped,
    /// The member is gone (closed, or disconnected for overflowing); remove it.
    Gone,
}

/// The receiving side of a channel member.
pub(crate) trait Sink: Send + Sync {
    /// Hands over a frame without blocking.
    fn deliver(&self, frame: CanFrame, at: Timestamp) -> Delivery;
    /// Closes the member for good (the hub is shutting down).
    fn close(&self);
    /// Hands over the frames of `batch` not sent by `me`, in order (an emulated wire delivers
    /// what is due in one go). The default hands them over one by one.
    fn deliver_batch(&self, batch: &[(MemberId, CanFrame)], me: MemberId, at: Timestamp) -> Delivery {
        let mut result = Delivery::Accepted;
        for (from, frame) in batch {
            if *from != me {
                match self.deliver(*frame, at) {
                    Delivery::Gone => return Delivery::Gone,
                    Delivery::Dropped => result = Delivery::Dropped,
                    Delivery::Accepted => {}
                }
            }
        }
        result
    }
}
