//! What goes wrong on a bus, and in an address: below everything that reports it.

use crate::frame::FrameError;

/// The accepted forms, as error messages name them.
pub(crate) const FORMS: &str =
    "socketcand://HOST:PORT/CHANNEL, socketcan://IFACE, slcan://PORT?bitrate=500000 or mem://NAME";

/// What can go wrong on a bus.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The bus is gone for good: the hub stopped, or the server closed the connection.
    #[error("the bus was closed")]
    Closed,
    /// The underlying socket failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The server broke the protocol or refused a request (socketcand handshake).
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A frame received from the OS or a peer that is not a valid CAN frame.
    #[error("invalid frame: {0}")]
    Frame(#[from] FrameError),
    /// The requested transport is not compiled in or not available on this platform.
    #[error("{0}")]
    Unavailable(String),
    /// The address string is not one of the accepted forms.
    #[error(transparent)]
    Address(#[from] BusAddrError),
    /// The connection is down and being restored (the async socketcand client, which
    /// reconnects): this frame was not sent; sending again once the link is back works.
    #[error("the bus connection is down ({reason}); reconnecting")]
    Down {
        /// Why the link went down.
        reason: String,
    },
}

impl TransportError {
    pub(crate) fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Self::Io { context: context.into(), source }
    }
}

/// Text that is not a [`BusAddr`](crate::BusAddr); the message names the accepted forms.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("bad bus address '{text}': {reason} (expected {FORMS})")]
pub struct BusAddrError {
    text: String,
    reason: &'static str,
}

impl BusAddrError {
    pub(crate) fn new(text: &str, reason: &'static str) -> Self {
        // The text is echoed in the message: printable and short.
        Self { text: text.chars().take(80).map(|c| if c.is_control() { '?' } else { c }).collect(), reason }
    }

    /// What was wrong with the text.
    pub fn reason(&self) -> &'static str {
        self.reason
    }
}
