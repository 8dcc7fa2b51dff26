//! [`VirtualBus`]: a simulation and the project's master on its bus, in virtual time.

use std::collections::VecDeque;
use std::future::{Future, poll_fn};
use std::pin::pin;
use std::sync::{Arc, Mutex, Weak};
use std::task::Poll;
use std::time::Duration;

use od_bus::{CanFrame, Endpoint, LocalEndpoint};
use od_runtime::Micros;
use tokio::runtime::Runtime;
use tokio::sync::broadcast::{self, error::TryRecvError};
use tokio::time::Instant;

use super::Sim;

/// How far virtual time moves at a time while a call waits for something later than now.
pub const STEP: Micros = 100;

/// Longest step of [`VirtualBus::advance`]: frames it collects are stamped with the end of
/// their step.
pub const ADVANCE_STEP: Micros = 1000;

/// Frames kept for [`VirtualBus::seen`] before the oldest are dropped.
const KEEP: usize = 100_000;

/// A frame the master received, with the virtual time it was collected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Seen {
    /// Virtual time, µs.
    pub at: Micros,
    /// The frame.
    pub frame: CanFrame,
}

/// A [`Sim`] and an [`od_master::Bus`] on its in-memory bus, moved together in virtual time:
/// how `drive-sim demo`, the drive tests and the benchmarks talk to simulated devices.
///
/// The master is the project's one master, `od-master`: every SDO, NMT, PDO, SYNC and
/// heartbeat frame is made and parsed there (its protocol core is `od_runtime::master`). This
/// type only runs it: a current-thread tokio runtime with a paused clock, on which the
/// master's bus task runs while [`run`](Self::run) waits for one of its calls (or while
/// [`advance`](Self::advance) hands it frames), tokio's clock brought to the simulation's
/// before each. The program keeps `&mut` access to the [`Sim`] between calls, to look at or
/// change a device.
///
/// Within one instant the devices answer at once: a request sent at `t` is handled, and its
/// answer received, at `t` (a round trip takes no virtual time, as on the simulation's own
/// endpoints); time moves on in steps of [`STEP`] only while a call waits for something
/// later (a timeout, a device that answers late).
///
/// ```
/// use drive::drives::DeviceApps;
/// use drive::node::{DeviceKind, NodeConfig, Sim, VirtualBus};
///
/// let mut sim = Sim::new();
/// sim.add(DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..Default::default() }, &DeviceApps::new()).unwrap());
/// let mut vb = VirtualBus::new(sim, od_master::Config::default()).unwrap();
/// vb.advance(1000); // boot-up
/// assert_eq!(vb.take_id(0x702).len(), 1);
/// let node = vb.bus().node(2).unwrap();
/// assert_eq!(vb.run(node.read::<u32>(0x1000, 0)).unwrap(), 0xFF7A_0192);
/// vb.run(node.start()).unwrap(); // NMT start
/// vb.advance(1000);
/// assert_eq!(vb.sim().node(0).nmt_state(), od_runtime::NmtState::Operational);
/// ```
pub struct VirtualBus {
    rt: Runtime,
    sim: Sim,
    bus: od_master::Bus,
    frames: broadcast::Receiver<CanFrame>,
    /// A listener on the bus that only tells whether frames went by: [`advance`](Self::advance)
    /// runs the master only for the steps in which it has something to receive.
    probe: LocalEndpoint,
    seen: VecDeque<Seen>,
    received: u64,
    missed: u64,
    /// Frames that went by on the bus (the master's and the devices').
    went_by: u64,
    /// Tokio's instant that is the simulation's time 0.
    origin: Instant,
}

impl std::fmt::Debug for VirtualBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VirtualBus").field("now", &self.sim.now()).field("seen", &self.seen.len()).finish()
    }
}

impl VirtualBus {
    /// The master (with `config`) on `sim`'s bus, its clock at the simulation's time. Fails
    /// only if the runtime cannot be made.
    pub fn new(sim: Sim, config: od_master::Config) -> std::io::Result<Self> {
        let rt = tokio::runtime::Builder::new_current_thread().enable_time().start_paused(true).build()?;
        let (bus, frames, origin) = rt.block_on(async {
            let bus = od_master::Bus::start(od_bus::tokio::Bus::attach(sim.bus()), config);
            let frames = bus.frames();
            let origin = Instant::now() - Duration::from_micros(sim.now());
            (bus, frames, origin)
        });
        let probe = sim.endpoint();
        Ok(Self { rt, sim, bus, frames, probe, seen: VecDeque::new(), received: 0, missed: 0, went_by: 0, origin })
    }

    /// The master: [`od_master::Bus::node`] for SDO and NMT, PDOs, SYNC, events. Its calls
    /// are futures to give to [`run`](Self::run).
    pub fn bus(&self) -> &od_master::Bus {
        &self.bus
    }

    /// The simulation.
    pub fn sim(&self) -> &Sim {
        &self.sim
    }

    /// The simulation, mutably (to change a device between calls). Time moved here with
    /// [`Sim::advance`] is caught up by the master's clock at the next call.
    pub fn sim_mut(&mut self) -> &mut Sim {
        &mut self.sim
    }

    /// Virtual time, µs.
    pub fn now(&self) -> Micros {
        self.sim.now()
    }

    /// Frames the master received so far.
    pub fn frames_received(&self) -> u64 {
        self.received
    }

    /// Frames that went by on the bus so far: the master's and the devices'.
    pub fn frames_on_bus(&self) -> u64 {
        self.went_by
    }

    /// Frames received by the master that were not collected here because more than the
    /// broadcast's capacity arrived in one instant (0 in every run so far; a test can check).
    pub fn frames_missed(&self) -> u64 {
        self.missed
    }

    /// Runs `fut` (a call of the master) to its end, the simulation moving with the master's
    /// clock: at once within an instant, in steps of [`STEP`] while `fut` waits for later.
    pub fn run<F: Future>(&mut self, fut: F) -> F::Output {
        let Self { rt, sim, frames, probe, seen, received, missed, went_by, origin, .. } = self;
        let mut t = Tap { sim, frames, probe, seen, received, missed, went_by, last_went_by: 1, origin: *origin };
        rt.block_on(async {
            t.catch_up().await;
            let mut fut = pin!(fut);
            let mut quiet = 0;
            loop {
                if let Poll::Ready(out) = poll_fn(|cx| Poll::Ready(fut.as_mut().poll(cx))).await {
                    // The master has taken in every frame the devices sent at this instant
                    // once a round moves nothing on the bus (the last one may have, if the
                    // call ended with a frame the master sent).
                    if t.last_went_by > 0 {
                        while t.round().await {}
                    }
                    return out;
                }
                if t.round().await {
                    quiet = 0;
                    continue;
                }
                quiet += 1;
                if quiet < 2 {
                    continue;
                }
                // Nothing moves at this instant: on to the next step, or to the instant the
                // call is done (a timeout of the master's).
                quiet = 0;
                tokio::select! {
                    biased;
                    out = fut.as_mut() => {
                        t.follow();
                        t.settle().await;
                        return out;
                    }
                    () = tokio::time::sleep(Duration::from_micros(STEP)) => t.follow(),
                }
            }
        })
    }

    /// Lets `dt` µs of virtual time pass in steps of at most [`ADVANCE_STEP`]; after each step
    /// in which frames went by, the master's clock catches up and it receives them (frames
    /// collected for [`seen`](Self::seen) are stamped with the end of their step). Steps in
    /// which nothing went by cost the simulation's time only.
    pub fn advance(&mut self, dt: Micros) {
        let end = self.sim.now().saturating_add(dt);
        loop {
            let now = self.sim.now();
            if now >= end {
                break;
            }
            self.sim.advance((end - now).min(ADVANCE_STEP));
            self.receive();
        }
        self.sim.advance(0);
        self.receive();
    }

    /// Lets the master receive what went by since it last ran, if anything did.
    fn receive(&mut self) {
        let n = drain(&mut self.probe);
        if n == 0 {
            return;
        }
        self.went_by += n as u64;
        let Self { rt, sim, frames, probe, seen, received, missed, went_by, origin, .. } = self;
        let mut t = Tap { sim, frames, probe, seen, received, missed, went_by, last_went_by: 1, origin: *origin };
        rt.block_on(async {
            t.catch_up().await;
            t.settle().await;
        });
    }

    /// Moves time in steps of `step` µs until `pred` holds (true) or `timeout` µs passed
    /// (false).
    pub fn wait_until(&mut self, timeout: Micros, step: Micros, mut pred: impl FnMut(&mut Self) -> bool) -> bool {
        let end = self.now().saturating_add(timeout);
        loop {
            if pred(self) {
                return true;
            }
            if self.now() >= end {
                return false;
            }
            self.advance(step.max(1));
        }
    }

    /// The frames received and not yet taken, oldest first.
    pub fn seen(&self) -> impl Iterator<Item = &Seen> {
        self.seen.iter()
    }

    /// Takes the frames received so far.
    pub fn take_seen(&mut self) -> Vec<Seen> {
        self.seen.drain(..).collect()
    }

    /// Takes the frames with COB-ID `id` received so far.
    pub fn take_id(&mut self, id: u32) -> Vec<Seen> {
        let (hit, rest): (Vec<Seen>, Vec<Seen>) = self.seen.drain(..).partition(|s| s.frame.id() == id);
        self.seen = rest.into();
        hit
    }

    /// The number of frames received and not yet taken.
    pub fn seen_len(&self) -> usize {
        self.seen.len()
    }

    /// Forgets the frames with COB-ID `id` received since [`seen`](Self::seen) held `since`
    /// frames (what a caller does with the answers of an SDO transfer it ran: the transfer
    /// took them).
    pub fn forget_since(&mut self, since: usize, id: u32) {
        let mut i = since.min(self.seen.len());
        while i < self.seen.len() {
            if self.seen[i].frame.id() == id {
                self.seen.remove(i);
            } else {
                i += 1;
            }
        }
    }
}

/// The pieces of a [`VirtualBus`] the runtime's future works on.
struct Tap<'a> {
    sim: &'a mut Sim,
    frames: &'a mut broadcast::Receiver<CanFrame>,
    probe: &'a mut LocalEndpoint,
    seen: &'a mut VecDeque<Seen>,
    received: &'a mut u64,
    missed: &'a mut u64,
    went_by: &'a mut u64,
    /// Frames that went by in the last round (before the first: as if some did).
    last_went_by: usize,
    origin: Instant,
}

impl Tap<'_> {
    /// The simulation's time that tokio's clock shows now.
    fn target(&self) -> Micros {
        u64::try_from(self.origin.elapsed().as_micros()).unwrap_or(u64::MAX)
    }

    /// Brings tokio's clock up to the simulation's (moved by [`Sim::advance`] outside a call).
    async fn catch_up(&mut self) {
        let target = self.target();
        if self.sim.now() > target {
            tokio::time::advance(Duration::from_micros(self.sim.now() - target)).await;
        }
    }

    /// Moves the simulation to tokio's clock.
    fn follow(&mut self) {
        let target = self.target();
        let now = self.sim.now();
        self.sim.advance(target.saturating_sub(now));
        self.collect();
    }

    /// Takes what the master's bus task passed on, stamped with the simulation's time.
    fn collect(&mut self) -> usize {
        let mut n = 0;
        loop {
            match self.frames.try_recv() {
                Ok(frame) => {
                    n += 1;
                    *self.received += 1;
                    if self.seen.len() >= KEEP {
                        self.seen.pop_front();
                    }
                    self.seen.push_back(Seen { at: self.sim.now(), frame });
                }
                Err(TryRecvError::Lagged(k)) => *self.missed += k,
                Err(TryRecvError::Empty | TryRecvError::Closed) => return n,
            }
        }
    }

    /// Lets every task act and every device answer at this instant, until two rounds in a row
    /// move nothing.
    async fn settle(&mut self) {
        let mut quiet = 0;
        while quiet < 2 {
            if self.round().await { quiet = 0 } else { quiet += 1 }
        }
    }

    /// One round at this instant: the other tasks (the master's bus task) run, then the
    /// devices handle what reached them, then what the master passed on is collected. Whether
    /// any frame went by.
    async fn round(&mut self) -> bool {
        tokio::task::yield_now().await;
        self.sim.advance(0);
        let went_by = drain(self.probe);
        self.last_went_by = went_by;
        *self.went_by += went_by as u64;
        let collected = self.collect();
        went_by + collected > 0
    }
}

/// Empties `probe`; the number of frames it held.
fn drain(probe: &mut LocalEndpoint) -> usize {
    let mut n = 0;
    while let Ok(Some(_)) = probe.try_recv() {
        n += 1;
    }
    n
}

/// `sim` with an [`od_master::Bus`] on its in-memory bus, for a program that runs its own tokio
/// runtime: a task spawned on the current runtime moves the simulation to tokio's clock every
/// `step`, until the simulation is dropped. On a paused clock
/// (`#[tokio::test(start_paused = true)]`) the drives and the master move together in virtual
/// time; on a real one, in real time. ([`VirtualBus`] does the same on a runtime of its own, for
/// callers that do not run async code.) Call it within a runtime.
pub fn spawn_with_master(sim: Sim, config: od_master::Config, step: Duration) -> (od_master::Bus, Arc<Mutex<Sim>>) {
    let bus = od_master::Bus::start(od_bus::tokio::Bus::attach(sim.bus()), config);
    let sim = Arc::new(Mutex::new(sim));
    tokio::spawn(follow_tokio_clock(Arc::downgrade(&sim), step));
    (bus, sim)
}

/// Moves the simulation to tokio's time every `step`, until it is dropped.
async fn follow_tokio_clock(sim: Weak<Mutex<Sim>>, step: Duration) {
    let start = Instant::now();
    loop {
        {
            let Some(sim) = sim.upgrade() else { return };
            let mut sim = sim.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            let t = Micros::try_from(start.elapsed().as_micros()).unwrap_or(Micros::MAX);
            let now = sim.now();
            sim.advance(t.saturating_sub(now));
        }
        tokio::time::sleep(step).await;
    }
}
