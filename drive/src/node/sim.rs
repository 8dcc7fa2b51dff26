//! Deterministic simulations: nodes on an in-memory bus, driven by a virtual clock.

use od_runtime::Micros;

use super::AnyNode;
use od_bus::{Endpoint, LocalEndpoint, MemoryBus};

/// Nodes on a [`MemoryBus`], run in virtual time: the same inputs give the same frames, in the
/// same order, at the same virtual times, however fast the machine is.
///
/// A test attaches its own endpoints (the master) with [`Sim::endpoint`], sends frames on them,
/// and moves time with [`Sim::advance`]; every node handles what reached it and runs its
/// timers at its deadlines in between.
///
/// ```
/// use drive::node::{DefaultApps, DeviceKind, NodeConfig, Sim};
/// use od_bus::{CanFrame, Endpoint};
///
/// let mut sim = Sim::new();
/// let mut master = sim.endpoint();
/// sim.add(DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..Default::default() }, &DefaultApps).unwrap());
/// sim.advance(0);
/// assert_eq!(master.try_recv().unwrap().unwrap().to_string(), "702#00"); // boot-up
/// master.send("000#0102".parse::<CanFrame>().unwrap()).unwrap(); // NMT start node 2
/// sim.advance(1000);
/// assert_eq!(sim.node(0).nmt_state(), od_runtime::NmtState::Operational);
/// ```
pub struct Sim {
    bus: MemoryBus,
    nodes: Vec<(Box<dyn AnyNode>, LocalEndpoint)>,
    now: Micros,
}

/// Rounds of frame exchange within one instant before time moves on anyway (two nodes that
/// answer each other forever cannot hang a test).
const MAX_ROUNDS: usize = 1000;

impl Default for Sim {
    fn default() -> Self {
        Self::new()
    }
}

impl Sim {
    /// An empty simulation at time 0.
    pub fn new() -> Self {
        Self { bus: MemoryBus::new(), nodes: Vec::new(), now: 0 }
    }

    /// The bus, for endpoints of the test's own.
    pub fn bus(&self) -> &MemoryBus {
        &self.bus
    }

    /// A new endpoint on the bus (a master, a listener).
    pub fn endpoint(&self) -> LocalEndpoint {
        self.bus.endpoint()
    }

    /// Adds a node; it starts (boot-up) at the next [`Sim::advance`]. Returns its position.
    pub fn add(&mut self, node: Box<dyn AnyNode>) -> usize {
        self.nodes.push((node, self.bus.endpoint()));
        self.nodes.len() - 1
    }

    /// The virtual time in microseconds.
    pub fn now(&self) -> Micros {
        self.now
    }

    /// Node `i` (in the order added). Panics if there is no such node: a test bug.
    pub fn node(&self, i: usize) -> &dyn AnyNode {
        &*self.nodes[i].0
    }

    /// Node `i`, mutably.
    pub fn node_mut(&mut self, i: usize) -> &mut dyn AnyNode {
        &mut *self.nodes[i].0
    }

    /// Node `i` as its concrete type `T` (a `Node<Dictionary, App>`), if it is one.
    pub fn downcast<T: 'static>(&self, i: usize) -> Option<&T> {
        self.nodes.get(i)?.0.as_any().downcast_ref()
    }

    /// Node `i` as its concrete type, mutably.
    pub fn downcast_mut<T: 'static>(&mut self, i: usize) -> Option<&mut T> {
        self.nodes.get_mut(i)?.0.as_any_mut().downcast_mut()
    }

    /// Moves time forward by `dt` µs: at the current time and at every node deadline up to
    /// the end, each node handles the frames that reached it (polling after each) and polls
    /// when its deadline has come; frames sent in an instant are delivered in the same instant.
    pub fn advance(&mut self, dt: Micros) {
        let target = self.now.saturating_add(dt);
        self.step();
        loop {
            let next = self.nodes.iter().map(|(n, _)| n.next_deadline()).min().unwrap_or(target).min(target);
            if next <= self.now {
                break;
            }
            self.now = next;
            self.step();
        }
        self.now = target;
    }

    /// Everything due at the current time.
    fn step(&mut self) {
        let now = self.now;
        let mut out = Vec::new();
        for _ in 0..MAX_ROUNDS {
            let mut received = false;
            for (node, ep) in &mut self.nodes {
                while let Ok(Some(frame)) = ep.try_recv() {
                    received = true;
                    node.handle(&frame, now);
                    node.poll(now, &mut |f| out.push(f));
                    for f in out.drain(..) {
                        let _ = ep.send(f);
                    }
                }
                if node.next_deadline() <= now {
                    node.poll(now, &mut |f| out.push(f));
                    for f in out.drain(..) {
                        let _ = ep.send(f);
                    }
                }
            }
            if !received {
                break;
            }
        }
    }
}
