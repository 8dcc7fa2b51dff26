//! A blocking facade for simple scripts: the same master, its calls waited for on a runtime of
//! its own.
//!
//! [`Bus::open`] starts a tokio runtime with one worker thread, on which the bus task runs
//! between calls too (heartbeats, SYNC, events keep going while the script does something
//! else); every method blocks the calling thread until the async call it wraps is done. Do
//! not use it from inside a tokio runtime (block_on would panic there): async code uses
//! [`crate::Bus`].
//!
//! ```no_run
//! let bus = od_master::blocking::Bus::open("socketcand://localhost:29536/can0", Default::default())?;
//! let drive = bus.node(2)?;
//! println!("{}", drive.read_string(0x1008, 0)?);
//! drive.write_idempotent(0x6083, 0, 1000u32)?;
//! # Ok::<(), od_master::Error>(())
//! ```

use std::sync::Arc;
use std::time::Duration;

use od_bus::CanFrame;
use od_runtime::master::nmt::Target;
use od_runtime::{NmtCommand, cia402::State};
use tokio::runtime::Runtime;
use tokio::sync::broadcast;

use crate::axis::{Homing, Move};
use crate::error::Error;
use crate::event::Event;
use crate::node::{SdoOptions, SdoValue};

/// The blocking handle on a bus ([`crate::Bus`] underneath).
#[derive(Clone, Debug)]
pub struct Bus {
    rt: Arc<Runtime>,
    inner: crate::Bus,
}

/// The blocking handle on a node ([`crate::Node`] underneath).
#[derive(Clone, Debug)]
pub struct Node {
    rt: Arc<Runtime>,
    inner: crate::Node,
}

/// The blocking handle on a CiA 402 drive ([`crate::Axis`] underneath).
#[derive(Debug)]
pub struct Axis {
    rt: Arc<Runtime>,
    inner: crate::Axis,
}

fn runtime() -> Result<Runtime, Error> {
    tokio::runtime::Builder::new_multi_thread().worker_threads(1).thread_name("od-master").enable_all().build().map_err(
        |e| Error::Transport(od_bus::TransportError::Unavailable(format!("cannot start a tokio runtime: {e}"))),
    )
}

impl Bus {
    /// Opens the bus at `addr` (see [`crate::Bus::open`]) on a runtime of its own.
    pub fn open(addr: &str, config: crate::Config) -> Result<Self, Error> {
        let rt = Arc::new(runtime()?);
        let inner = rt.block_on(crate::Bus::open(addr, config))?;
        Ok(Self { rt, inner })
    }

    /// The async handle, for code that has both.
    pub fn as_async(&self) -> &crate::Bus {
        &self.inner
    }

    /// A handle on node `id`.
    pub fn node(&self, id: u8) -> Result<Node, Error> {
        Ok(Node { rt: Arc::clone(&self.rt), inner: self.inner.node(id)? })
    }

    /// The bus's events from now on (`blocking_recv`, `try_recv` on the receiver).
    pub fn events(&self) -> broadcast::Receiver<Event> {
        self.inner.events()
    }

    /// Puts a frame on the bus.
    pub fn send(&self, frame: CanFrame) -> Result<(), Error> {
        self.rt.block_on(self.inner.send(frame))
    }

    /// An NMT command to one node or all.
    pub fn nmt(&self, command: NmtCommand, target: Target) -> Result<(), Error> {
        self.rt.block_on(self.inner.nmt(command, target))
    }

    /// Starts SYNC (see [`crate::Bus::start_sync`]).
    pub fn start_sync(&self, period: Duration, counter: u8) -> Result<(), Error> {
        self.rt.block_on(self.inner.start_sync(period, counter))
    }

    /// Stops SYNC.
    pub fn stop_sync(&self) -> Result<(), Error> {
        self.rt.block_on(self.inner.stop_sync())
    }
}

impl Node {
    /// The node id.
    pub fn id(&self) -> u8 {
        self.inner.id()
    }

    /// This node with other SDO options.
    pub fn with_options(self, options: SdoOptions) -> Self {
        Self { rt: self.rt, inner: self.inner.with_options(options) }
    }

    /// See [`crate::Node::read_bytes`].
    pub fn read_bytes(&self, index: u16, sub: u8) -> Result<Vec<u8>, Error> {
        self.rt.block_on(self.inner.read_bytes(index, sub))
    }

    /// See [`crate::Node::write_bytes`].
    pub fn write_bytes(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), Error> {
        self.rt.block_on(self.inner.write_bytes(index, sub, data))
    }

    /// See [`crate::Node::read`].
    pub fn read<T: SdoValue>(&self, index: u16, sub: u8) -> Result<T, Error> {
        self.rt.block_on(self.inner.read(index, sub))
    }

    /// See [`crate::Node::read_string`].
    pub fn read_string(&self, index: u16, sub: u8) -> Result<String, Error> {
        self.rt.block_on(self.inner.read_string(index, sub))
    }

    /// See [`crate::Node::write`] (never retried).
    pub fn write<T: SdoValue>(&self, index: u16, sub: u8, value: T) -> Result<(), Error> {
        self.rt.block_on(self.inner.write(index, sub, value))
    }

    /// See [`crate::Node::write_idempotent`] (retried like a read).
    pub fn write_idempotent<T: SdoValue>(&self, index: u16, sub: u8, value: T) -> Result<(), Error> {
        self.rt.block_on(self.inner.write_idempotent(index, sub, value))
    }

    /// An NMT command to this node.
    pub fn nmt(&self, command: NmtCommand) -> Result<(), Error> {
        self.rt.block_on(self.inner.nmt(command))
    }

    /// This node's CiA 402 drive.
    pub fn axis(&self) -> Axis {
        Axis { rt: Arc::clone(&self.rt), inner: crate::Axis::new(self.inner.clone()) }
    }
}

impl Axis {
    /// See [`crate::Axis::state`].
    pub fn state(&self) -> Result<Option<State>, Error> {
        self.rt.block_on(self.inner.state())
    }

    /// See [`crate::Axis::enable`].
    pub fn enable(&self) -> Result<(), Error> {
        self.rt.block_on(self.inner.enable())
    }

    /// See [`crate::Axis::disable`].
    pub fn disable(&self) -> Result<(), Error> {
        self.rt.block_on(self.inner.disable())
    }

    /// See [`crate::Axis::home`].
    pub fn home(&self, homing: &Homing) -> Result<i32, Error> {
        self.rt.block_on(self.inner.home(homing))
    }

    /// See [`crate::Axis::move_to`].
    pub fn move_to(&self, target: i32, m: &Move) -> Result<i32, Error> {
        self.rt.block_on(self.inner.move_to(target, m))
    }

    /// See [`crate::Axis::position`].
    pub fn position(&self) -> Result<i32, Error> {
        self.rt.block_on(self.inner.position())
    }
}
