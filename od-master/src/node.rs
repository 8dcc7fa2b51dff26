//! One node of the bus: SDO reads and writes (raw and typed) and NMT.

use std::time::Duration;

use od_runtime::master::nmt::Target;
use od_runtime::{NmtCommand, NodeId};

use crate::bus::{Bus, Op};
use crate::error::Error;
pub use crate::sdo_options::SdoOptions;

/// [`Bus::node`] lives beside [`Node`], which it makes: the bus module names no node type.
impl Bus {
    /// A handle on node `id` for SDO transfers and NMT, with the bus's default SDO options.
    pub fn node(&self, id: u8) -> Result<Node, Error> {
        let id = NodeId::new(id).ok_or(Error::NodeId(id))?;
        Ok(Node::new(self.clone(), id, self.sdo_options()))
    }
}

/// A value an SDO transfer carries as its little-endian bytes: the integer types, `f32`
/// (REAL32), `f64` (REAL64) and `bool` (BOOLEAN, one byte).
pub trait SdoValue: Sized {
    /// The number of bytes on the bus.
    const LEN: usize;
    /// The value of exactly [`LEN`](Self::LEN) bytes.
    fn from_le(bytes: &[u8]) -> Option<Self>;
    /// The value's bytes.
    fn to_le(&self) -> Vec<u8>;
}

macro_rules! sdo_value {
    ($($t:ty),*) => {$(
        impl SdoValue for $t {
            const LEN: usize = size_of::<$t>();
            fn from_le(bytes: &[u8]) -> Option<Self> {
                Some(<$t>::from_le_bytes(bytes.try_into().ok()?))
            }
            fn to_le(&self) -> Vec<u8> {
                self.to_le_bytes().to_vec()
            }
        }
    )*};
}

sdo_value!(u8, u16, u32, u64, i8, i16, i32, i64, f32, f64);

impl SdoValue for bool {
    const LEN: usize = 1;
    fn from_le(bytes: &[u8]) -> Option<Self> {
        match bytes {
            [b] => Some(*b != 0),
            _ => None,
        }
    }
    fn to_le(&self) -> Vec<u8> {
        vec![u8::from(*self)]
    }
}

/// A handle on one node: its SDO channel (one transfer at a time; calls from several tasks
/// queue) and NMT commands for it.
#[derive(Clone, Debug)]
pub struct Node {
    bus: Bus,
    id: NodeId,
    options: SdoOptions,
}

impl Node {
    pub(crate) fn new(bus: Bus, id: NodeId, options: SdoOptions) -> Self {
        Self { bus, id, options }
    }

    /// The node id.
    pub fn id(&self) -> u8 {
        self.id.get()
    }

    /// The bus this node is on.
    pub fn bus(&self) -> &Bus {
        &self.bus
    }

    /// The SDO options in force.
    pub fn options(&self) -> SdoOptions {
        self.options
    }

    /// This node with other SDO options.
    pub fn with_options(mut self, options: SdoOptions) -> Self {
        self.options = options;
        self
    }

    /// This node with another SDO timeout.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.options.timeout = timeout;
        self
    }

    /// This node with another number of retries.
    pub fn with_retries(mut self, retries: u8) -> Self {
        self.options.retries = retries;
        self
    }

    /// This node with another wait for a link that is down ([`SdoOptions::link_wait`]).
    pub fn with_link_wait(mut self, link_wait: Duration) -> Self {
        self.options.link_wait = link_wait;
        self
    }

    /// Reads `index`/`sub` (an SDO upload), retried on lost answers.
    pub async fn read_bytes(&self, index: u16, sub: u8) -> Result<Vec<u8>, Error> {
        self.bus.sdo(self.id, index, sub, Op::Upload(self.options.max_len), self.options).await
    }

    /// Writes `data` to `index`/`sub` (an SDO download), never retried: the object may act on
    /// every write it gets (a controlword, a "save" command).
    pub async fn write_bytes(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), Error> {
        let op = Op::Download { data: data.to_vec(), idempotent: false };
        self.bus.sdo(self.id, index, sub, op, self.options).await.map(drop)
    }

    /// Writes `data` to an object that writing twice leaves as writing once (a parameter, a
    /// target value): retried like a read.
    pub async fn write_bytes_idempotent(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), Error> {
        let op = Op::Download { data: data.to_vec(), idempotent: true };
        self.bus.sdo(self.id, index, sub, op, self.options).await.map(drop)
    }

    /// Reads a typed value; a value of another length is an [`Error::Length`].
    pub async fn read<T: SdoValue>(&self, index: u16, sub: u8) -> Result<T, Error> {
        let bytes = self.read_bytes(index, sub).await?;
        T::from_le(&bytes).ok_or(Error::Length { node: self.id(), index, sub, expected: T::LEN, got: bytes.len() })
    }

    /// Reads a VISIBLE_STRING (lossy UTF-8, trailing NULs removed).
    pub async fn read_string(&self, index: u16, sub: u8) -> Result<String, Error> {
        let bytes = self.read_bytes(index, sub).await?;
        Ok(String::from_utf8_lossy(&bytes).trim_end_matches('\0').to_owned())
    }

    /// Writes a typed value, never retried (see [`write_bytes`](Self::write_bytes)).
    pub async fn write<T: SdoValue>(&self, index: u16, sub: u8, value: T) -> Result<(), Error> {
        self.write_bytes(index, sub, &value.to_le()).await
    }

    /// Writes a typed value to an idempotent object, retried like a read.
    pub async fn write_idempotent<T: SdoValue>(&self, index: u16, sub: u8, value: T) -> Result<(), Error> {
        self.write_bytes_idempotent(index, sub, &value.to_le()).await
    }

    /// Sends an NMT command to this node.
    pub async fn nmt(&self, command: NmtCommand) -> Result<(), Error> {
        self.bus.nmt(command, Target::Node(self.id)).await
    }

    /// NMT start: to Operational.
    pub async fn start(&self) -> Result<(), Error> {
        self.nmt(NmtCommand::Start).await
    }

    /// NMT stop: to Stopped.
    pub async fn stop(&self) -> Result<(), Error> {
        self.nmt(NmtCommand::Stop).await
    }

    /// NMT enter pre-operational.
    pub async fn pre_operational(&self) -> Result<(), Error> {
        self.nmt(NmtCommand::EnterPreOperational).await
    }

    /// NMT reset node.
    pub async fn reset(&self) -> Result<(), Error> {
        self.nmt(NmtCommand::ResetNode).await
    }

    /// NMT reset communication.
    pub async fn reset_communication(&self) -> Result<(), Error> {
        self.nmt(NmtCommand::ResetCommunication).await
    }
}
