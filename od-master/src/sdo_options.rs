//! How a node's SDO transfers run ([`SdoOptions`]): the bus keeps a default for the nodes it
//! hands out and each [`Node`](crate::Node) its own, so the definition sits below both `bus`
//! and `node`. Public as `od_master::SdoOptions` and `od_master::node::SdoOptions`.

use std::time::Duration;

use od_runtime::master::Mode;

/// How a node's SDO transfers run: per node ([`Node::with_options`](crate::Node::with_options)) and per call (a node
/// handle is cheap: clone one with other options for a single call).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoOptions {
    /// How long the client waits for each answer of the server (default 1 s: drives that
    /// write to flash while answering need hundreds of milliseconds).
    pub timeout: Duration,
    /// How many times a failed read, or a write to an object said to be idempotent, is
    /// started again after a lost or garbled answer (timeout, toggle bit, CRC, sequence).
    /// Default 2. A server's abort for the object itself is never retried, nor a plain write.
    pub retries: u8,
    /// Expedited/segmented (default), always segmented, or block transfer.
    pub mode: Mode,
    /// A block transfer to a server that does not do them runs as a normal one (default on):
    /// the block request refused with 0504 0001h is sent again as a normal one, and a normal
    /// upload answer to a block upload (python-canopen's `LocalNode`) is followed. Off, both
    /// fail with the 0504 0001h abort (see `od_runtime::master::SdoClient::set_block_fallback`).
    pub block_fallback: bool,
    /// The largest value a read accepts (default 4 KiB); a longer one aborts the transfer
    /// with "out of memory".
    pub max_len: usize,
    /// How long a transfer waits for the bus's link to come back (a socketcand server
    /// restarted; the bus reconnects by itself) before it fails saying the link is down
    /// (default 10 s; 0: fail at once). A read or an idempotent write caught by the outage
    /// starts again once the link is up; one asked for while the link is down starts then.
    /// A plain write that was under way is not repeated: it fails saying the link is down.
    pub link_wait: Duration,
}

impl Default for SdoOptions {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(1),
            retries: 2,
            mode: Mode::Normal,
            block_fallback: true,
            max_len: 4096,
            link_wait: Duration::from_secs(10),
        }
    }
}
