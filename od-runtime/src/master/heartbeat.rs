//! Error control on the master side (CiA 301 §7.2.8.3.2): the heartbeat consumer and the node
//! guarding master in one table of watched nodes, and the master's own heartbeat producer.
//!
//! [`NodeMonitor`] watches up to `N` nodes, each either by heartbeat (the node sends its state
//! every producer time; the master waits up to a consumer time) or by node guarding (the
//! master sends a remote request every guard time; the node answers with its state and a
//! toggle bit; it is lost after guard time × life time factor without a valid answer). It
//! reports [`NodeEvent`]s, keeping apart a node that was never heard from (an optional boot
//! timeout, [`NodeEvent::NeverSeen`]) and one that was heard and went silent
//! ([`NodeEvent::Lost`], then [`NodeEvent::Recovered`]).
//!
//! Monitoring of a node starts with its first heartbeat. A boot-up message (state 00h) reports
//! [`NodeEvent::BootUp`] and pauses the timeout until the next heartbeat, since a node that
//! just reset produces heartbeats only once it is configured again.

use crate::frame::{Frame, Micros, NodeId};
use crate::nmt::NmtState;

/// What the monitor noticed about a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NodeEvent {
    /// A boot-up message: the node (re)started and is now pre-operational.
    BootUp {
        /// The node.
        node: u8,
    },
    /// The first heartbeat (or guarding answer) of a node not heard from before.
    FirstSeen {
        /// The node.
        node: u8,
        /// The state it reported.
        state: NmtState,
    },
    /// The node reported another NMT state than before.
    StateChanged {
        /// The node.
        node: u8,
        /// The state it reported before.
        from: NmtState,
        /// The state it reports now.
        to: NmtState,
    },
    /// A node that was heard from missed its heartbeat (consumer time) or its guarding answers
    /// (node life time).
    Lost {
        /// The node.
        node: u8,
    },
    /// A lost node is heard from again.
    Recovered {
        /// The node.
        node: u8,
        /// The state it reports.
        state: NmtState,
    },
    /// The boot timeout passed and the node was never heard from.
    NeverSeen {
        /// The node.
        node: u8,
    },
    /// A node guarding answer did not alternate its toggle bit (an answer was lost, or the node
    /// reset without a boot-up message reaching the master). The monitor takes the received
    /// toggle bit as the new reference.
    GuardToggle {
        /// The node.
        node: u8,
    },
}

/// How a node is watched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Watch {
    /// Heartbeat consumer: lost when no heartbeat arrives within `timeout` of the last one
    /// (the consumer heartbeat time; 0 only reports, never times out).
    Heartbeat {
        /// The consumer heartbeat time.
        timeout: Micros,
    },
    /// Node guarding: a remote request every `guard_time`; lost after
    /// `guard_time × life_time_factor` without a valid answer.
    Guarding {
        /// The guard time (the node's 100Ch); 0 sends no requests.
        guard_time: Micros,
        /// The life time factor (the node's 100Dh).
        life_time_factor: u8,
    },
}

/// The table of watched nodes is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Full;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Slot {
    node: u8,
    watch: Watch,
    /// The last state reported (`None` before the first message).
    state: Option<NmtState>,
    /// Heard from since it was watched.
    seen: bool,
    lost: bool,
    /// When the node is lost unless it is heard from (`None`: not timing).
    lost_at: Option<Micros>,
    /// When [`NodeEvent::NeverSeen`] fires unless it is heard from.
    boot_at: Option<Micros>,
    /// Node guarding: when the next request goes out, and the toggle bit expected.
    guard_at: Micros,
    toggle: bool,
}

/// Watches up to `N` nodes by heartbeat or node guarding. Allocation-free; every call visits
/// at most `N` slots.
#[derive(Clone, Debug)]
pub struct NodeMonitor<const N: usize> {
    slots: [Option<Slot>; N],
}

impl<const N: usize> Default for NodeMonitor<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> NodeMonitor<N> {
    /// No node watched.
    pub const fn new() -> Self {
        Self { slots: [None; N] }
    }

    fn slot(&mut self, node: u8) -> Option<&mut Slot> {
        self.slots.iter_mut().flatten().find(|s| s.node == node)
    }

    /// Starts (or restarts) watching `node`. With `boot_timeout`, [`NodeEvent::NeverSeen`]
    /// fires if the node is not heard from within it. Node guarding sends its first request
    /// at the next poll. Replaces an earlier watch of the same node, forgetting what it knew.
    pub fn watch(&mut self, node: NodeId, watch: Watch, boot_timeout: Option<Micros>, now: Micros) -> Result<(), Full> {
        let slot = Slot {
            node: node.get(),
            watch,
            state: None,
            seen: false,
            lost: false,
            lost_at: match watch {
                Watch::Guarding { guard_time, life_time_factor } if guard_time > 0 && life_time_factor > 0 => {
                    Some(now.saturating_add(guard_time.saturating_mul(Micros::from(life_time_factor))))
                }
                _ => None,
            },
            boot_at: boot_timeout.map(|t| now.saturating_add(t)),
            guard_at: now,
            toggle: false,
        };
        if let Some(s) = self.slot(node.get()) {
            *s = slot;
            return Ok(());
        }
        let free = self.slots.iter_mut().find(|s| s.is_none()).ok_or(Full)?;
        *free = Some(slot);
        Ok(())
    }

    /// Stops watching `node`.
    pub fn unwatch(&mut self, node: NodeId) {
        for s in &mut self.slots {
            if s.is_some_and(|s| s.node == node.get()) {
                *s = None;
            }
        }
    }

    /// The last NMT state `node` reported, if it is watched and was heard from.
    pub fn state(&self, node: NodeId) -> Option<NmtState> {
        self.slots.iter().flatten().find(|s| s.node == node.get())?.state
    }

    /// Whether `node` is watched, was heard from and is not lost.
    pub fn is_alive(&self, node: NodeId) -> bool {
        self.slots.iter().flatten().any(|s| s.node == node.get() && s.seen && !s.lost)
    }

    /// Takes a received frame: heartbeats, boot-up messages and guarding answers of watched
    /// nodes (COB-ID 700h + node id, one data byte); everything else is ignored.
    pub fn on_frame(&mut self, frame: &Frame, now: Micros) -> Option<NodeEvent> {
        let id = frame.id();
        if !(0x701..=0x77F).contains(&id) || frame.is_rtr() || frame.len() != 1 {
            return None;
        }
        let node = (id - 0x700) as u8;
        let b = frame.data()[0];
        let slot = self.slot(node)?;
        let guarding = matches!(slot.watch, Watch::Guarding { .. });
        let state = NmtState::from_code(b)?;
        if b & 0x80 != 0 && !guarding {
            // Bit 7 is reserved in a heartbeat.
            return None;
        }
        let first = !slot.seen;
        slot.seen = true;
        slot.boot_at = None;
        if state == NmtState::Initialising {
            slot.state = Some(state);
            slot.lost = false;
            slot.toggle = false;
            slot.lost_at = match slot.watch {
                // A guarded node is still asked and must answer within its life time.
                Watch::Guarding { guard_time, life_time_factor } if guard_time > 0 && life_time_factor > 0 => {
                    Some(now.saturating_add(guard_time.saturating_mul(Micros::from(life_time_factor))))
                }
                _ => None,
            };
            return Some(NodeEvent::BootUp { node });
        }
        let mut toggle_error = false;
        match slot.watch {
            Watch::Heartbeat { timeout } => {
                slot.lost_at = (timeout > 0).then(|| now.saturating_add(timeout));
            }
            Watch::Guarding { guard_time, life_time_factor } => {
                let t = b & 0x80 != 0;
                toggle_error = t != slot.toggle;
                slot.toggle = !t;
                // An answer with a wrong toggle bit is reported, but the node did answer.
                if guard_time > 0 && life_time_factor > 0 {
                    slot.lost_at = Some(now.saturating_add(guard_time.saturating_mul(Micros::from(life_time_factor))));
                }
            }
        }
        let before = slot.state.replace(state);
        if toggle_error {
            return Some(NodeEvent::GuardToggle { node });
        }
        if slot.lost {
            slot.lost = false;
            return Some(NodeEvent::Recovered { node, state });
        }
        match before {
            _ if first => Some(NodeEvent::FirstSeen { node, state }),
            Some(from) if from != state => Some(NodeEvent::StateChanged { node, from, to: state }),
            _ => None,
        }
    }

    /// Sends the node guarding requests that are due (`7xx R1`) and reports timeouts
    /// ([`NodeEvent::Lost`], [`NodeEvent::NeverSeen`]).
    pub fn poll(&mut self, now: Micros, mut emit: impl FnMut(Frame), mut event: impl FnMut(NodeEvent)) {
        for s in self.slots.iter_mut().flatten() {
            if let Watch::Guarding { guard_time, .. } = s.watch
                && guard_time > 0
                && now >= s.guard_at
            {
                if let Some(f) = Frame::remote(0x700 + u16::from(s.node), 1) {
                    emit(f);
                }
                s.guard_at = now.saturating_add(guard_time);
            }
            if s.boot_at.is_some_and(|t| now >= t) {
                s.boot_at = None;
                event(NodeEvent::NeverSeen { node: s.node });
            }
            if s.lost_at.is_some_and(|t| now >= t) {
                s.lost_at = None;
                if s.seen {
                    s.lost = true;
                    event(NodeEvent::Lost { node: s.node });
                } else if matches!(s.watch, Watch::Guarding { .. }) && s.boot_at.is_none() {
                    // Guarded but never answered, with no boot timeout of its own: the life
                    // time stands in for it.
                    event(NodeEvent::NeverSeen { node: s.node });
                }
            }
        }
    }

    /// The earliest time [`poll`](Self::poll) has something to do, `None` if nothing is timed.
    pub fn deadline(&self) -> Option<Micros> {
        self.slots
            .iter()
            .flatten()
            .flat_map(|s| {
                let guard = match s.watch {
                    Watch::Guarding { guard_time, .. } if guard_time > 0 => Some(s.guard_at),
                    _ => None,
                };
                [guard, s.boot_at, s.lost_at]
            })
            .flatten()
            .min()
    }
}

/// The master's own heartbeat (1017h on the master), so that nodes consuming it stop their
/// drives when the master program dies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeartbeatProducer {
    id: u16,
    period: Micros,
    state: NmtState,
    next: Micros,
}

impl HeartbeatProducer {
    /// A producer for node id `node` every `period` (0 sends nothing), reporting
    /// operational; the first heartbeat goes out at the first poll.
    pub const fn new(node: NodeId, period: Micros) -> Self {
        Self { id: 0x700 + node.get() as u16, period, state: NmtState::Operational, next: 0 }
    }

    /// Sets the state the heartbeats report.
    pub fn set_state(&mut self, state: NmtState) {
        self.state = state;
    }

    /// Sends the heartbeat when it is due. A late poll sends one frame, not the ones missed.
    pub fn poll(&mut self, now: Micros, mut emit: impl FnMut(Frame)) {
        if self.period == 0 || now < self.next {
            return;
        }
        emit(Frame::short(self.id, [self.state.code(), 0, 0, 0, 0, 0, 0, 0], 1));
        self.next = now.saturating_add(self.period);
    }

    /// When the next heartbeat is due (`None` if disabled).
    pub const fn deadline(&self) -> Option<Micros> {
        if self.period == 0 { None } else { Some(self.next) }
    }
}
