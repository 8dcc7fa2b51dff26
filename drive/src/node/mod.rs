//! Running a device: an od-runtime `Device` over a generated dictionary, an application
//! ([`DriveApp`]) and a clock, on any [`Endpoint`](od_bus::Endpoint).
//!
//! ```text
//!            frames ─────► Node::handle ──► od-runtime Device ──► events ──► DriveApp::on_event
//!   Endpoint                                  ▲  (SDO, NMT, PDO,           (through a Ctx:
//!            frames ◄───── Node::poll ◄───────┘   SYNC, EMCY, 402)          faults, EMCY, writes)
//!                            │
//!                            └─► every tick_period: DriveApp::tick (motion model)
//! ```
//!
//! * [`Node`] is the device with its application. It never reads a clock: [`Node::handle`] and
//!   [`Node::poll`] take the time, so tests run it on a virtual clock, frame for frame.
//! * [`AnyNode`] is `Node` without its type parameters, for code that runs any device
//!   (`drive-sim`, [`Sim`]).
//! * [`run`] drives a node on an endpoint in real time with a [`Clock`] ([`MonotonicClock`]),
//!   until a stop flag is set or the bus closes.
//! * [`Sim`] runs nodes on a [`MemoryBus`](od_bus::MemoryBus) in virtual time:
//!   deterministic multi-device tests.
//! * [`DeviceKind`] builds a node for one of the project's devices (DRVI, DRCS, AKD) from a
//!   [`NodeConfig`]; [`Apps`] chooses the application each kind runs.
//! * [`ParameterSet`] and [`NodeStorage`] apply a DCF's values at every reset.
//! * [`Retain`] ([`MemoryRetain`], [`FileRetain`]) keeps what an application retains by itself
//!   across power cycles, outside the dictionary ([`Ctx::retain`], [`Ctx::retained`]: the
//!   DRVI's position at power-off).
//!
//! # Adding a device behaviour
//!
//! A vendor behaviour or a motion model is a [`DriveApp`] over the device's generated
//! dictionary; nothing in this module changes:
//!
//! 1. `impl DriveApp<generated::drvi::Dictionary> for DrviBehaviour`: refuse writes in
//!    [`DriveApp::on_write`] (synchronous, before the dictionary changes), react to events in
//!    [`DriveApp::on_event`] (a write done, an NMT change, a CiA 402 transition, SYNC), run
//!    the motion model in [`DriveApp::tick`] (1 kHz by default), acting through [`Ctx`]:
//!    typed dictionary access, [`Ctx::set_fault`], [`Ctx::quick_stop_done`],
//!    [`Ctx::set_statusword_flags`], [`Ctx::signal_error`], ...
//! 2. Keep a [`DefaultApp`] inside and pass it the events not handled, for the standard
//!    reactions (error control losses by EMCY; instant quick stop and fault reaction for
//!    those the behaviour does not model).
//! 3. Return it from an [`Apps`] implementation and give that to [`DeviceKind::build`];
//!    `drive-sim` builds its devices with `DefaultApps` in one place (`run_devices`).
//! 4. Test it frame for frame with [`Sim`] (virtual time) and the tests of
//!    `drive/tests/it/node_sim.rs` as a model.
//!
//! # Example: a DRVI on the in-memory bus
//!
//! ```
//! use drive::node::{DefaultApp, Node, NodeStorage};
//! use od_bus::CanFrame;
//! use od_runtime::NodeId;
//!
//! let id = NodeId::new(2).unwrap();
//! let mut node = Node::new(generated::drvi::Dictionary::new(2), DefaultApp::new(), NodeStorage::memory(), id);
//! let mut sent = Vec::new();
//! node.poll(0, &mut |f| sent.push(f.to_string()));
//! assert_eq!(sent, ["702#00"]); // boot-up
//!
//! // SDO upload of 1000h (device type).
//! node.handle(&"602#4000100000000000".parse::<CanFrame>().unwrap(), 100);
//! sent.clear();
//! node.poll(100, &mut |f| sent.push(f.to_string()));
//! assert_eq!(sent, ["582#4300100092017AFF"]);
//! ```

mod app;
mod devices;
mod faults;
mod kind;
mod params;
mod retain;
mod run;
mod sim;
mod virtual_bus;

use std::any::Any;
use std::collections::VecDeque;

use od_runtime::od::{AbortCode, ObjectDictionary};
use od_runtime::{Device, Event, Frame, Micros, NmtState, NodeId, Storage, WriteSource};

use od_bus::CanFrame;

pub use app::{Ctx, DefaultApp, DriveApp, EMCY_HEARTBEAT_OR_GUARDING, EMCY_RPDO_TIMEOUT, LossRecord, WriteRequest};
pub use devices::{Apps, DefaultApps, DeviceKind, NodeConfig, NodeSetupError};
pub use faults::{Fault, FaultHandle, Faulty};
pub use params::{DcfError, NodeStorage, ParameterSet};
pub use retain::{FileRetain, MemoryRetain, Retain};
pub use run::{
    Backoff, BusEvent, Clock, MonotonicClock, RunStats, run, run_group, run_group_reconnecting, run_reconnecting,
};
pub use sim::Sim;
pub use virtual_bus::{ADVANCE_STEP, STEP, Seen, VirtualBus, spawn_with_master};

/// Events held between the device call that raised them and their delivery to the
/// application. A single frame raises at most a few dozen (an RPDO of 64 one-bit entries);
/// past this, events are dropped and counted ([`Node::dropped_events`]).
const EVENT_QUEUE: usize = 4096;

/// Poll interval of the device's own timers (heartbeat, event timers, SDO timeout, inhibit
/// times): od-runtime wants a poll at least every millisecond.
pub const POLL_INTERVAL: Micros = 1000;

/// The od-runtime side of the application: vetoes go to the application synchronously,
/// events are queued for delivery with a [`Ctx`].
struct Hooks<A> {
    /// `None` while the application runs (its own device calls are then not vetoed by itself).
    app: Option<A>,
    events: VecDeque<Event>,
    dropped: u64,
}

impl<OD: ObjectDictionary, A: DriveApp<OD>> od_runtime::App<OD> for Hooks<A> {
    fn on_write(&mut self, od: &OD, index: u16, sub: u8, data: &[u8], source: WriteSource) -> Result<(), AbortCode> {
        match (&mut self.app, source) {
            (Some(app), WriteSource::Sdo | WriteSource::Rpdo(_)) => {
                // The dictionary's own checks (length first, then its limits) come before the
                // application's: a value of the wrong size is a length error whatever it is.
                // An RPDO entry has its entry's size by construction (the mapping was checked
                // when loaded), so the PDO path keeps its handle-only speed.
                if matches!(source, WriteSource::Sdo)
                    && let Ok(info) = od.info(index, sub)
                {
                    info.check_value(data)?;
                }
                app.on_write(od, &WriteRequest { index, sub, data, source })
            }
            _ => Ok(()),
        }
    }

    fn on_upload(&mut self, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<Result<usize, AbortCode>> {
        self.app.as_mut()?.on_upload(od, index, sub, buf)
    }

    fn on_tpdo(&mut self, od: &OD, map: &[od_runtime::od::MappedHandle], data: &mut [u8; 8]) {
        if let Some(app) = &mut self.app {
            app.on_tpdo(od, map, data);
        }
    }

    fn rpdo_length_exceeded(&mut self, pdo: u16) -> bool {
        self.app.as_mut().is_some_and(|app| app.rpdo_length_exceeded(pdo))
    }

    fn on_event(&mut self, _od: &mut OD, event: Event) {
        if self.events.len() < EVENT_QUEUE {
            self.events.push_back(event);
        } else {
            self.dropped += 1;
        }
    }
}

/// A device: the od-runtime `Device` around dictionary `OD`, the application `A`, and the
/// parameter storage `S` (usually [`NodeStorage`]).
///
/// Feed it the frames from the bus with [`Node::handle`] and call [`Node::poll`] at least
/// every [`POLL_INTERVAL`] (better: at [`Node::next_deadline`]) to run timers and collect the
/// frames to send. Both take the current time in microseconds; the node starts (reset node,
/// boot-up message) at the first call.
pub struct Node<OD, A, S = NodeStorage> {
    dev: Device<OD, Hooks<A>, S>,
    tick_period: Micros,
    next_tick: Option<Micros>,
    last_poll: Option<Micros>,
    /// Something outside the normal flow ([`Node::with_app`]) may have queued frames.
    wake: bool,
    ticks: u64,
    retain: Box<dyn Retain>,
}

impl<OD, A, S> Node<OD, A, S>
where
    OD: ObjectDictionary,
    A: DriveApp<OD>,
    S: Storage,
{
    /// A node with id `node_id`. Nothing happens until the first [`Node::handle`] or
    /// [`Node::poll`].
    pub fn new(od: OD, app: A, storage: S, node_id: NodeId) -> Self {
        let tick_period = app.tick_period();
        let hooks = Hooks { app: Some(app), events: VecDeque::new(), dropped: 0 };
        Self {
            dev: Device::new(od, hooks, storage, node_id),
            tick_period,
            next_tick: None,
            last_poll: None,
            wake: false,
            ticks: 0,
            retain: Box::new(MemoryRetain::new()),
        }
    }

    /// Makes the device answer LSS (CiA 305); `None` starts it without a node-ID (no boot-up,
    /// nothing but LSS until a master gives it one). Before the first [`Node::handle`] or
    /// [`Node::poll`]; a node-ID stored over LSS takes the place of `node_id` at start.
    pub fn enable_lss(&mut self, node_id: Option<NodeId>) {
        self.dev.enable_lss(node_id);
    }

    /// Keeps the application's retained data ([`Ctx::retain`]) in `retain` instead of a
    /// [`MemoryRetain`] of its own: a [`FileRetain`] in the state directory, or a
    /// `MemoryRetain` shared with the node this one replaces. Call before the first
    /// [`Node::handle`] or [`Node::poll`] (the application reads it at the start-up reset).
    pub fn with_retain(mut self, retain: Box<dyn Retain>) -> Self {
        self.retain = retain;
        self
    }

    /// Handles one frame from the bus received at `now`, then delivers the events it raised.
    /// Responses go out at the next [`Node::poll`]. Extended-id frames are not CANopen's and
    /// are ignored.
    pub fn handle(&mut self, frame: &CanFrame, now: Micros) {
        if frame.is_extended() {
            return;
        }
        // A standard id is at most 0x7FF, so the cast is exact.
        let f = Frame::from_parts(frame.id() as u16, frame.is_remote(), frame.dlc(), frame.raw_data());
        self.dev.on_frame(&f, now);
        self.dispatch(now);
    }

    /// Runs the application's tick when it is due, the device's timers, and hands every frame
    /// to send to `emit`.
    pub fn poll(&mut self, now: Micros, emit: &mut dyn FnMut(CanFrame)) {
        let next_tick = *self.next_tick.get_or_insert(now);
        if self.tick_period != 0 && now >= next_tick {
            self.tick(now);
            let next = next_tick.saturating_add(self.tick_period);
            // Behind by more than a period: skip the missed ticks instead of bursting.
            self.next_tick = Some(if next <= now { now.saturating_add(self.tick_period) } else { next });
        }
        // Reactions to events raised by a poll (a heartbeat timeout's EMCY) go out in the same
        // call: poll again while the application had something to react to.
        for _ in 0..3 {
            self.dev.poll(now, |f| {
                if let Some(frame) = to_can(&f) {
                    emit(frame);
                }
            });
            if self.dev.app().events.is_empty() {
                break;
            }
            self.dispatch(now);
        }
        self.last_poll = Some(now);
        self.wake = false;
    }

    /// When the node wants its next [`Node::poll`]: the next application tick or
    /// [`POLL_INTERVAL`] after the last poll, whichever is first (0, meaning at once, before
    /// the first poll and after [`Node::with_app`]).
    pub fn next_deadline(&self) -> Micros {
        let Some(last) = self.last_poll.filter(|_| !self.wake) else { return 0 };
        let timers = last.saturating_add(POLL_INTERVAL);
        match self.next_tick {
            Some(t) if self.tick_period != 0 => t.min(timers),
            _ => timers,
        }
    }

    fn tick(&mut self, now: Micros) {
        let Some(mut app) = self.dev.app_mut().app.take() else { return };
        app.tick(&mut Ctx::new(&mut self.dev, now).with_retain(self.retain.as_mut()));
        self.dev.app_mut().app = Some(app);
        self.ticks += 1;
        self.dispatch(now);
    }

    /// Delivers queued events to the application, including those its reactions raise.
    fn dispatch(&mut self, now: Micros) {
        if self.dev.app().events.is_empty() {
            return;
        }
        let Some(mut app) = self.dev.app_mut().app.take() else { return };
        // Bounded: an application that raises an event for every event it gets cannot hang
        // the node; what is left is delivered at the next call.
        for _ in 0..EVENT_QUEUE {
            let Some(event) = self.dev.app_mut().events.pop_front() else { break };
            app.on_event(&mut Ctx::new(&mut self.dev, now).with_retain(self.retain.as_mut()), event);
        }
        self.dev.app_mut().app = Some(app);
    }

    /// Runs `f` with the application and a [`Ctx`] at time `now`, as if from a tick (a test
    /// injecting a fault, a command-line action); events it raises are delivered afterwards.
    pub fn with_app<R>(&mut self, now: Micros, f: impl FnOnce(&mut A, &mut Ctx<'_, OD>) -> R) -> Option<R> {
        let mut app = self.dev.app_mut().app.take()?;
        let out = f(&mut app, &mut Ctx::new(&mut self.dev, now).with_retain(self.retain.as_mut()));
        self.dev.app_mut().app = Some(app);
        self.dispatch(now);
        self.wake = true;
        Some(out)
    }

    /// The od-runtime device (NMT state, CiA 402 state, error register, the dictionary).
    pub fn device(&self) -> &Device<OD, impl od_runtime::App<OD>, S> {
        &self.dev
    }

    /// The dictionary.
    pub fn od(&self) -> &OD {
        self.dev.od()
    }

    /// The dictionary, mutably (no side effects; see [`Ctx::od_mut`]).
    pub fn od_mut(&mut self) -> &mut OD {
        self.dev.od_mut()
    }

    /// The value an SDO upload of `index`/`sub` carries, without the protocol: the
    /// application's answer ([`DriveApp::on_upload`]) or else the dictionary's value, or the
    /// abort code. For tests that hold a master's reads against the device's own values.
    pub fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        let mut buf = vec![0u8; 1 << 16];
        let mut app = self.dev.app_mut().app.take();
        let answer = app.as_mut().and_then(|a| a.on_upload(self.dev.od(), index, sub, &mut buf));
        self.dev.app_mut().app = app;
        let len = match answer {
            Some(r) => r?,
            None => self.dev.od().read(index, sub, &mut buf)?,
        };
        buf.truncate(len);
        Ok(buf)
    }

    /// The application (`None` only while it runs, which cannot be observed from outside).
    pub fn app(&self) -> Option<&A> {
        self.dev.app().app.as_ref()
    }

    /// The application, mutably.
    pub fn app_mut(&mut self) -> Option<&mut A> {
        self.dev.app_mut().app.as_mut()
    }

    /// The storage.
    pub fn storage_mut(&mut self) -> &mut S {
        self.dev.storage_mut()
    }

    /// Sets the SDO server timeout (default 1 s).
    pub fn set_sdo_timeout(&mut self, timeout: Micros) {
        self.dev.set_sdo_timeout(timeout);
    }

    /// Application ticks run so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Events dropped because the queue was full (0 unless an application floods it).
    pub fn dropped_events(&self) -> u64 {
        self.dev.app().dropped
    }
}

/// od-runtime frames always have an 11-bit id and at most 8 bytes, so this never fails.
fn to_can(f: &Frame) -> Option<CanFrame> {
    CanFrame::from_parts(u32::from(f.id()), false, f.is_rtr(), f.len() as u8, *f.raw()).ok()
}

/// A [`Node`] without its type parameters: what code that runs any device needs.
pub trait AnyNode: Send + 'static {
    /// [`Node::handle`].
    fn handle(&mut self, frame: &CanFrame, now: Micros);
    /// [`Node::poll`].
    fn poll(&mut self, now: Micros, emit: &mut dyn FnMut(CanFrame));
    /// [`Node::next_deadline`].
    fn next_deadline(&self) -> Micros;
    /// The node id.
    fn node_id(&self) -> NodeId;
    /// The node-ID in use: `None` for a device without one (LSS).
    fn active_node_id(&self) -> Option<NodeId> {
        Some(self.node_id())
    }
    /// The NMT state.
    fn nmt_state(&self) -> NmtState;
    /// [`Node::upload`].
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode>;
    /// The concrete node, for tests that look inside (`downcast_ref::<Node<..>>()`).
    fn as_any(&self) -> &dyn Any;
    /// The concrete node, mutably.
    fn as_any_mut(&mut self) -> &mut dyn Any;
    /// Runs an NMT command inside the device, as its own firmware would (a power cycle is
    /// `ResetNode`: it boots again with its stored parameters). Nothing by default.
    fn local_nmt(&mut self, _command: od_runtime::NmtCommand, _now: Micros) {}
    /// Puts the drive in Fault with `error_code` (603Fh, EMCY), as a drive fault would. Nothing
    /// by default.
    fn inject_fault(&mut self, _error_code: u16, _now: Micros) {}
    /// Its CiA 402 state, if it has one.
    fn cia402_state(&self) -> Option<od_runtime::cia402::State> {
        None
    }
}

impl<OD, A, S> AnyNode for Node<OD, A, S>
where
    OD: ObjectDictionary + Send + 'static,
    A: DriveApp<OD> + Send + 'static,
    S: Storage + Send + 'static,
{
    fn handle(&mut self, frame: &CanFrame, now: Micros) {
        Node::handle(self, frame, now)
    }
    fn poll(&mut self, now: Micros, emit: &mut dyn FnMut(CanFrame)) {
        Node::poll(self, now, emit)
    }
    fn next_deadline(&self) -> Micros {
        Node::next_deadline(self)
    }
    fn node_id(&self) -> NodeId {
        self.dev.node_id()
    }
    fn active_node_id(&self) -> Option<NodeId> {
        self.dev.active_node_id()
    }
    fn nmt_state(&self) -> NmtState {
        self.dev.nmt_state()
    }
    fn upload(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        Node::upload(self, index, sub)
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
    fn local_nmt(&mut self, command: od_runtime::NmtCommand, now: Micros) {
        self.with_app(now, |_, ctx| ctx.nmt_command(command));
    }
    fn inject_fault(&mut self, error_code: u16, now: Micros) {
        self.with_app(now, |_, ctx| ctx.set_fault(error_code));
    }
    fn cia402_state(&self) -> Option<od_runtime::cia402::State> {
        self.dev.cia402_state()
    }
}
