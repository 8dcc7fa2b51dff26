//! The client side of the socketcand protocol: an [`Endpoint`] on a channel of a hub (ours or
//! a real socketcand) reached over TCP.

use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use crate::endpoint::Endpoint;
use crate::error::TransportError;
use crate::frame::CanFrame;
use crate::socketcand::{Decoder, Message, parse_channel};

/// The client's side of a socketcand session without the I/O: what to say in the handshake, and
/// what the server's messages mean. The blocking [`SocketcandClient`] and the async client
/// (`tokio` feature) both drive one, each over its own socket.
#[derive(Debug)]
pub(crate) struct ClientSession {
    decoder: Decoder,
    /// Messages other than frames, for the handshake (or an echo) to check.
    replies: VecDeque<Message>,
    remote_errors: u64,
    last_remote_error: Option<String>,
    /// Frames the server reported dropping for us (`< dropped N >`, our hub's extension).
    server_dropped: u64,
}

/// Replies kept for a caller that is not waiting for them (after the handshake).
const MAX_REPLIES: usize = 16;

impl ClientSession {
    pub(crate) fn new() -> Self {
        Self {
            decoder: Decoder::new(),
            replies: VecDeque::new(),
            remote_errors: 0,
            last_remote_error: None,
            server_dropped: 0,
        }
    }

    /// The handshake, step by step: what to send (nothing first: the server speaks first with
    /// `< hi >`) and the reply that must come back. Checks the channel name first.
    pub(crate) fn handshake(channel: &str) -> Result<[(Option<Message>, Message); 3], TransportError> {
        parse_channel(channel).map_err(|e| TransportError::Protocol(e.to_string()))?;
        Ok([
            (None, Message::Hi),
            (Some(Message::Open(channel.to_owned())), Message::Ok),
            (Some(Message::RawMode), Message::Ok),
        ])
    }

    /// Sent once the handshake is done, with no reply: our hub then reports the frames it drops
    /// for this client (`< dropped N >`); a real socketcand answers `< error ... >`, which is
    /// only counted.
    pub(crate) const AFTER_HANDSHAKE: Message = Message::DropReport;

    /// Decodes what the socket gave: frames go to `on_frame`, drop reports and malformed
    /// messages are counted, other messages kept as replies.
    pub(crate) fn feed(&mut self, bytes: &[u8], mut on_frame: impl FnMut(CanFrame)) {
        let (replies, errors, dropped) = (&mut self.replies, &mut self.remote_errors, &mut self.server_dropped);
        self.decoder.feed(bytes, |message| match message {
            Ok(Message::Frame { frame, .. }) => on_frame(frame),
            Ok(Message::Dropped(total)) => *dropped = (*dropped).max(total),
            Ok(other) => replies.push_back(other),
            // A server sending garbage: nothing to answer, the frames around it still count.
            Err(_) => *errors += 1,
        });
        if replies.len() > MAX_REPLIES {
            replies.drain(..replies.len() - MAX_REPLIES);
        }
    }

    /// The next reply, checked against `wanted`: `None` while none has come.
    pub(crate) fn take_reply(&mut self, wanted: &Message) -> Option<Result<(), TransportError>> {
        Some(match self.replies.pop_front()? {
            reply if reply == *wanted => Ok(()),
            Message::Error(text) => Err(TransportError::Protocol(format!("server refused: {text}"))),
            other => Err(TransportError::Protocol(format!("expected {wanted}, got {other}"))),
        })
    }

    /// Drops the replies nobody waits for, counting the `< error >` ones (outside a handshake
    /// they report a problem with something we sent).
    pub(crate) fn settle_replies(&mut self) {
        while let Some(reply) = self.replies.pop_front() {
            if let Message::Error(text) = reply {
                self.remote_errors += 1;
                self.last_remote_error = Some(text);
            }
        }
    }

    pub(crate) fn remote_errors(&self) -> u64 {
        self.remote_errors
    }

    pub(crate) fn last_remote_error(&self) -> Option<&str> {
        self.last_remote_error.as_deref()
    }

    pub(crate) fn server_dropped(&self) -> u64 {
        self.server_dropped
    }
}

/// A connection to a socketcand server in raw mode on one channel.
///
/// [`connect`](SocketcandClient::connect) performs the handshake (`< hi >`, `< open CHANNEL >`,
/// `< rawmode >`, each answered `< ok >`); afterwards [`Endpoint::send`] writes `< send ... >`
/// messages and [`Endpoint::recv_timeout`] returns the frames the server reports. `< error >`
/// messages from the server are counted, not returned (see
/// [`remote_errors`](SocketcandClient::remote_errors)); remote frames work with our hub, which
/// speaks socketcand's `sendrtr`/`rtr` messages. After the handshake it asks the server for
/// `< dropped N >` reports (our hub's extension), so [`Endpoint::lost`] counts the frames the
/// hub dropped because this client read too slowly.
pub struct SocketcandClient {
    stream: TcpStream,
    peer: SocketAddr,
    channel: String,
    session: ClientSession,
    frames: VecDeque<CanFrame>,
    buf: Vec<u8>,
    out: String,
    /// Frames dropped here because more than [`MAX_BUFFERED_FRAMES`] were waiting.
    buffer_dropped: u64,
}

/// Frames decoded but not yet received are kept up to this many; past it the oldest are dropped,
/// as by an overrun CAN controller. (Only a caller that waits for echo replies for a long time
/// while the bus is busy gets near it.)
const MAX_BUFFERED_FRAMES: usize = 65_536;

impl SocketcandClient {
    /// Time allowed for connecting and for each handshake reply.
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

    /// Connects to `addr`, opens `channel` and enters raw mode, allowing
    /// [`DEFAULT_TIMEOUT`](SocketcandClient::DEFAULT_TIMEOUT) for each step.
    pub fn connect(addr: impl ToSocketAddrs, channel: &str) -> Result<Self, TransportError> {
        Self::connect_timeout(addr, channel, Self::DEFAULT_TIMEOUT)
    }

    /// Like [`connect`](SocketcandClient::connect) with a chosen timeout per step.
    pub fn connect_timeout(addr: impl ToSocketAddrs, channel: &str, timeout: Duration) -> Result<Self, TransportError> {
        let handshake = ClientSession::handshake(channel)?;
        let addrs = addr.to_socket_addrs().map_err(|e| TransportError::io("cannot resolve the server address", e))?;
        let mut last_error = None;
        let mut connected = None;
        for candidate in addrs {
            match TcpStream::connect_timeout(&candidate, timeout) {
                Ok(stream) => {
                    connected = Some((stream, candidate));
                    break;
                }
                Err(error) => last_error = Some(TransportError::io(format!("cannot connect to {candidate}"), error)),
            }
        }
        let (stream, peer) = connected.ok_or_else(|| {
            last_error.unwrap_or_else(|| TransportError::Protocol("the address resolved to nothing".into()))
        })?;
        stream.set_nodelay(true).map_err(|e| TransportError::io("cannot configure the socket", e))?;
        crate::socketcand::bound_receive_buffer(&stream)?;
        let mut client = Self {
            stream,
            peer,
            channel: channel.to_owned(),
            session: ClientSession::new(),
            frames: VecDeque::new(),
            buf: vec![0; 16 * 1024],
            out: String::with_capacity(64),
            buffer_dropped: 0,
        };
        for (say, reply) in handshake {
            if let Some(message) = say {
                client.write(&message)?;
            }
            client.expect(reply, timeout)?;
        }
        client.write(&ClientSession::AFTER_HANDSHAKE)?;
        Ok(client)
    }

    /// The server's address.
    pub fn peer_addr(&self) -> SocketAddr {
        self.peer
    }

    /// The channel opened.
    pub fn channel(&self) -> &str {
        &self.channel
    }

    /// `< error >` messages received since the handshake.
    pub fn remote_errors(&self) -> u64 {
        self.session.remote_errors()
    }

    /// Text of the last `< error >` message received.
    pub fn last_remote_error(&self) -> Option<&str> {
        self.session.last_remote_error()
    }

    /// Sends `< echo >` and waits for the server to echo it: a round trip through the server.
    /// Frames arriving meanwhile stay queued for [`recv_timeout`](Endpoint::recv_timeout).
    pub fn echo(&mut self, timeout: Duration) -> Result<(), TransportError> {
        self.write(&Message::Echo)?;
        self.expect(Message::Echo, timeout)
    }

    fn write(&mut self, message: &Message) -> Result<(), TransportError> {
        self.out.clear();
        message.write_to(&mut self.out);
        self.stream.write_all(self.out.as_bytes()).map_err(|e| map_io("cannot write to the server", e))
    }

    /// Waits for a reply other than a frame; it must be `wanted`.
    fn expect(&mut self, wanted: Message, timeout: Duration) -> Result<(), TransportError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(checked) = self.session.take_reply(&wanted) {
                return checked;
            }
            if !self.read_some(deadline)? {
                return Err(TransportError::Protocol(format!("no {wanted} from the server within {timeout:?}")));
            }
        }
    }

    /// Reads what the socket has (waiting until `deadline` at most) and decodes it. Returns
    /// false when the deadline passed without data.
    fn read_some(&mut self, deadline: Instant) -> Result<bool, TransportError> {
        let remaining = deadline.saturating_duration_since(Instant::now());
        let result = if remaining.is_zero() {
            self.stream.set_nonblocking(true).map_err(|e| TransportError::io("cannot poll the socket", e))?;
            let result = self.stream.read(&mut self.buf);
            self.stream.set_nonblocking(false).map_err(|e| TransportError::io("cannot poll the socket", e))?;
            result
        } else {
            self.stream.set_read_timeout(Some(remaining)).map_err(|e| TransportError::io("cannot wait", e))?;
            self.stream.read(&mut self.buf)
        };
        let n = match result {
            Ok(0) => return Err(TransportError::Closed),
            Ok(n) => n,
            Err(error) if matches!(error.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                return Ok(false);
            }
            Err(error) if error.kind() == io::ErrorKind::Interrupted => return Ok(true),
            Err(error) => return Err(map_io("cannot read from the server", error)),
        };
        let (frames, buffer_dropped) = (&mut self.frames, &mut self.buffer_dropped);
        self.session.feed(&self.buf[..n], |frame| {
            if frames.len() >= MAX_BUFFERED_FRAMES {
                frames.pop_front();
                *buffer_dropped += 1;
            }
            frames.push_back(frame);
        });
        Ok(true)
    }
}

/// An I/O error as the bus sees it: the peer gone is [`TransportError::Closed`].
pub(crate) fn map_io(context: &str, error: io::Error) -> TransportError {
    match error.kind() {
        io::ErrorKind::BrokenPipe
        | io::ErrorKind::ConnectionReset
        | io::ErrorKind::ConnectionAborted
        | io::ErrorKind::NotConnected
        | io::ErrorKind::UnexpectedEof => TransportError::Closed,
        _ => TransportError::io(context, error),
    }
}

impl Endpoint for SocketcandClient {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        self.write(&Message::Send(frame))
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        self.out.clear();
        for frame in frames {
            Message::Send(*frame).write_to(&mut self.out);
        }
        self.stream.write_all(self.out.as_bytes()).map_err(|e| map_io("cannot write to the server", e))
    }

    fn buffered(&self) -> usize {
        self.frames.len()
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        let deadline =
            Instant::now().checked_add(timeout).unwrap_or_else(|| Instant::now() + Duration::from_secs(86_400));
        loop {
            if let Some(frame) = self.frames.pop_front() {
                return Ok(Some(frame));
            }
            // Error replies that arrive outside a handshake are counted, not returned.
            self.session.settle_replies();
            if !self.read_some(deadline)? {
                return Ok(None);
            }
        }
    }

    fn lost(&self) -> u64 {
        self.session.server_dropped() + self.buffer_dropped
    }
}

impl fmt::Debug for SocketcandClient {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SocketcandClient")
            .field("peer", &self.peer)
            .field("channel", &self.channel)
            .field("buffered", &self.frames.len())
            .field("remote_errors", &self.session.remote_errors())
            .finish()
    }
}
