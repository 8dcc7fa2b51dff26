//! Faults on demand: a device that can be power-cycled, have its heartbeat silenced while it
//! keeps running (a pulled cable, seen from the master), or be put in Fault, while it runs.
//!
//! [`Faulty`] wraps any node; its [`FaultHandle`] (cheap to clone, usable from any thread)
//! queues [`Fault`]s that the node takes at its next poll. Everything else passes through, so
//! `Sim::downcast` and friends still see the device inside.

use std::any::Any;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use od_bus::CanFrame;
use od_runtime::od::AbortCode;
use od_runtime::{Micros, NmtCommand, NmtState, NodeId};

use super::AnyNode;

/// A fault to inject.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// Power off for `off` µs (it neither sends nor receives), then on: it boots again with
    /// its stored parameters (1010h), as after a brown-out.
    PowerCycle {
        /// How long it stays off.
        off: Micros,
    },
    /// No heartbeat (700h + id) leaves it for `duration` µs; everything else runs on.
    Silence {
        /// How long.
        duration: Micros,
    },
    /// The drive goes to Fault with this error code (603Fh, EMCY). With `sticky`, the cause
    /// stays: after each fault reset it faults again at once.
    Fault {
        /// The error code.
        code: u16,
        /// The cause stays until [`Fault::Clear`].
        sticky: bool,
    },
    /// The cause of a sticky fault is gone (a fault reset then clears the fault).
    Clear,
}

impl std::str::FromStr for Fault {
    type Err = String;

    /// `power-cycle [OFF_MS]`, `silence MS`, `fault [CODE] [sticky]`, `clear` (the node id
    /// given apart).
    fn from_str(s: &str) -> Result<Self, String> {
        let words: Vec<&str> = s.split_whitespace().collect();
        let ms = |w: &str| -> Result<Micros, String> {
            w.parse::<u64>()
                .map(|m| m.saturating_mul(1000))
                .map_err(|_| format!("`{w}` is not a number of milliseconds"))
        };
        let code = |w: &str| -> Result<u16, String> {
            let t = w.trim_start_matches("0x").trim_end_matches('h');
            u16::from_str_radix(t, 16).map_err(|_| format!("`{w}` is not a 16-bit error code in hexadecimal (5530h)"))
        };
        match words.as_slice() {
            ["power-cycle"] => Ok(Fault::PowerCycle { off: 10_000 }),
            ["power-cycle", off] => Ok(Fault::PowerCycle { off: ms(off)? }),
            ["silence", d] => Ok(Fault::Silence { duration: ms(d)? }),
            ["fault"] => Ok(Fault::Fault { code: 0x5530, sticky: false }),
            ["fault", c] => Ok(Fault::Fault { code: code(c)?, sticky: false }),
            ["fault", c, "sticky"] => Ok(Fault::Fault { code: code(c)?, sticky: true }),
            ["clear"] => Ok(Fault::Clear),
            _ => {
                Err(format!("`{s}`: expected `power-cycle [OFF_MS]`, `silence MS`, `fault [CODE] [sticky]` or `clear`"))
            }
        }
    }
}

/// Queues faults for one [`Faulty`] node, from any thread.
#[derive(Clone, Debug, Default)]
pub struct FaultHandle {
    queue: Arc<Mutex<VecDeque<Fault>>>,
}

impl FaultHandle {
    /// The node takes `fault` at its next poll.
    pub fn inject(&self, fault: Fault) {
        self.queue.lock().unwrap_or_else(|e| e.into_inner()).push_back(fault);
    }

    fn take(&self) -> Option<Fault> {
        self.queue.lock().unwrap_or_else(|e| e.into_inner()).pop_front()
    }

    fn pending(&self) -> bool {
        !self.queue.lock().unwrap_or_else(|e| e.into_inner()).is_empty()
    }
}

/// A node whose faults can be injected while it runs (see the [module](self)).
pub struct Faulty {
    inner: Box<dyn AnyNode>,
    handle: FaultHandle,
    off_until: Option<Micros>,
    silent_until: Option<Micros>,
    sticky: Option<u16>,
}

impl Faulty {
    /// Wraps `inner`; faults come through the handle.
    pub fn new(inner: Box<dyn AnyNode>) -> (Self, FaultHandle) {
        let handle = FaultHandle::default();
        (Self { inner, handle: handle.clone(), off_until: None, silent_until: None, sticky: None }, handle)
    }

    fn take_faults(&mut self, now: Micros) {
        while let Some(fault) = self.handle.take() {
            match fault {
                Fault::PowerCycle { off } => self.off_until = Some(now.saturating_add(off)),
                Fault::Silence { duration } => self.silent_until = Some(now.saturating_add(duration)),
                Fault::Fault { code, sticky } => {
                    self.sticky = sticky.then_some(code);
                    self.inner.inject_fault(code, now);
                }
                Fault::Clear => self.sticky = None,
            }
        }
    }

    fn is_off(&self, now: Micros) -> bool {
        self.off_until.is_some_and(|t| now < t)
    }
}

impl AnyNode for Faulty {
    fn handle(&mut self, frame: &CanFrame, now: Micros) {
        if !self.is_off(now) {
            self.inner.handle(frame, now);
        }
    }

    fn poll(&mut self, now: Micros, emit: &mut dyn FnMut(CanFrame)) {
        self.take_faults(now);
        if self.is_off(now) {
            return;
        }
        if self.off_until.take().is_some() {
            // Power is back: it boots with what it stored, nothing of what it was told.
            self.sticky = None;
            self.inner.local_nmt(NmtCommand::ResetNode, now);
        }
        if let Some(code) = self.sticky {
            use od_runtime::cia402::State;
            if !matches!(self.inner.cia402_state(), Some(State::Fault | State::FaultReactionActive) | None) {
                self.inner.inject_fault(code, now);
            }
        }
        if self.silent_until.is_some_and(|t| now >= t) {
            self.silent_until = None;
        }
        let heartbeat = 0x700 + u32::from(self.inner.node_id().get());
        let silent = self.silent_until.is_some();
        self.inner.poll(now, &mut |f| {
            if !(silent && f.id() == heartbeat) {
                emit(f);
            }
        });
    }

    fn next_deadline(&self) -> Micros {
        if self.handle.pending() {
            return 0;
        }
        if let Some(on) = self.off_until {
            // Off: nothing runs until the power is back.
            return on;
        }
        let mut next = self.inner.next_deadline();
        for t in [self.off_until, self.silent_until].into_iter().flatten() {
            next = next.min(t);
        }
        next
    }

    fn node_id(&self) -> NodeId {
        self.inner.node_id()
    }

    fn nmt_state(&self) -> NmtState {
        self.inner.nmt_state()
    }

    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        self.inner.upload(index, sub)
    }

    fn as_any(&self) -> &dyn Any {
        self.inner.as_any()
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self.inner.as_any_mut()
    }

    fn local_nmt(&mut self, command: NmtCommand, now: Micros) {
        self.inner.local_nmt(command, now)
    }

    fn inject_fault(&mut self, error_code: u16, now: Micros) {
        self.inner.inject_fault(error_code, now)
    }

    fn cia402_state(&self) -> Option<od_runtime::cia402::State> {
        self.inner.cia402_state()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_commands() {
        let table: &[(&str, Result<Fault, &str>)] = &[
            ("power-cycle", Ok(Fault::PowerCycle { off: 10_000 })),
            ("power-cycle 5", Ok(Fault::PowerCycle { off: 5_000 })),
            ("silence 2000", Ok(Fault::Silence { duration: 2_000_000 })),
            ("fault", Ok(Fault::Fault { code: 0x5530, sticky: false })),
            ("fault 7500h sticky", Ok(Fault::Fault { code: 0x7500, sticky: true })),
            ("fault 0x2310", Ok(Fault::Fault { code: 0x2310, sticky: false })),
            ("clear", Ok(Fault::Clear)),
            ("silence", Err("`silence`: expected")),
            ("silence soon", Err("`soon` is not a number of milliseconds")),
            ("fault 12345", Err("`12345` is not a 16-bit error code")),
        ];
        for (text, want) in table {
            match (text.parse::<Fault>(), want) {
                (Ok(got), Ok(want)) => assert_eq!(got, *want, "{text}"),
                (Err(got), Err(want)) => assert!(got.starts_with(want), "{text}: {got}"),
                (got, _) => panic!("{text}: {got:?}"),
            }
        }
    }
}
