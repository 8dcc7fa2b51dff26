//! The socketcand protocol: ASCII messages in angle brackets over TCP.
//!
//! socketcand (linux-can) exposes CAN buses over TCP; python-can's `socketcand` interface is
//! its best-known client and the one this project is tested against. A session in raw mode:
//!
//! ```text
//! server: < hi >
//! client: < open can0 >                  server: < ok >
//! client: < rawmode >                    server: < ok >
//! client: < send 601 8 40 41 60 0 0 0 0 0 >
//! server: < frame 581 1700000000.123456 4B41600004000000 >
//! ```
//!
//! Details this module settles (each checked against python-can 4.6.1 and socketcand's docs):
//!
//! * `send`: identifier in hex, then the length in decimal, then one hex token (1 or 2 digits)
//!   per byte. An identifier of 1 to 3 digits is standard, 4 to 8 digits extended. Emitted with
//!   3 or 8 digits and two-digit bytes.
//! * `frame`: identifier, `seconds.microseconds`, then the data as one contiguous hex string.
//!   Emitted identifiers have exactly 3 digits (standard) or 8 (extended), because python-can
//!   calls any length other than 3 extended. With no data the message ends in two spaces,
//!   `< frame 080 1700000000.000001  >`: python-can splits the inside on spaces and needs the
//!   empty third field. Parsing also accepts data split into byte tokens (older socketcand).
//! * Remote frames: `< sendrtr ID LEN >` from a client and `< rtr ID TIMESTAMP LEN >` to it.
//!   python-can cannot produce them and logs and skips the latter.
//! * `< error TEXT >` reports a problem with the client's last message. python-can reads any
//!   `error` message as an error frame and fails on text it cannot parse, so the hub sends one
//!   only to a client that sent something malformed.
//! * python-can reads each handshake reply with a single `recv` and compares the whole text,
//!   so the hub writes every reply on its own and pauses briefly after `< ok >` before writing
//!   frames (see `HubConfig::reply_pause`).
//! * BCM-mode commands (`add`, `filter`, `subscribe`, ...), CAN FD, ISO-TP and control mode are
//!   recognised and answered as unsupported.

use std::fmt::{self, Write as _};
use std::str::FromStr;

use crate::frame::{CanFrame, FrameError, hex_byte, hex_digit};
pub use crate::timestamp::Timestamp;

/// Longest message accepted, from `<` to `>` inclusive. The longest valid message, a `frame`
/// with an extended id, a 20-digit second count and eight bytes, is about 70 bytes; an `open`
/// with the longest channel name is 77.
pub const MAX_MESSAGE_LEN: usize = 256;

/// Longest channel name a client may open (socketcand itself allows 16, an interface name).
pub const MAX_CHANNEL_LEN: usize = 64;

/// The receive buffer a socketcand connection asks the OS for, in bytes: about 0.6 s of a
/// 1 Mbit/s bus at full load (some 9,000 frames/s, 45 bytes a frame as text).
///
/// Left to itself, Linux grows a TCP receive buffer up to `net.ipv4.tcp_rmem`'s maximum (32 MB
/// on common setups): a program that stops reading for a while would then get minutes of old
/// frames when it resumes, with nothing lost and nothing said. With a bound, a reader that
/// falls behind makes the server's queue for it overflow instead, and the hub counts the frames
/// it drops and says so (the client prints "frames lost"); what the program reads stays
/// recent. A remote server over a slow link still has room: 256 KiB is far more than a
/// round trip's worth of a CAN bus.
pub const RECEIVE_BUFFER: usize = 256 * 1024;

/// Sets [`RECEIVE_BUFFER`] on a connected socket.
pub(crate) fn bound_receive_buffer<S>(stream: &S) -> Result<(), crate::TransportError>
where
    for<'s> socket2::SockRef<'s>: From<&'s S>,
{
    socket2::SockRef::from(stream)
        .set_recv_buffer_size(RECEIVE_BUFFER)
        .map_err(|e| crate::TransportError::io("cannot set the socket's receive buffer", e))
}

impl FromStr for Timestamp {
    type Err = ParseError;

    /// `SECONDS.FRACTION`, the fraction 1 to 9 digits (truncated to microseconds), or whole
    /// seconds alone.
    fn from_str(text: &str) -> Result<Self, ParseError> {
        let bad = || ParseError::Timestamp(snippet(text));
        let (whole, fraction) = text.split_once('.').unwrap_or((text, ""));
        if whole.is_empty() || !whole.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        if fraction.len() > 9 || !fraction.bytes().all(|b| b.is_ascii_digit()) || text.ends_with('.') {
            return Err(bad());
        }
        let secs = whole.parse::<u64>().map_err(|_| bad())?;
        let mut micros = 0u32;
        for i in 0..6 {
            let digit = fraction.as_bytes().get(i).map_or(0, |b| u32::from(b - b'0'));
            micros = micros * 10 + digit;
        }
        // Six digits at most: below a million.
        Self::new(secs, micros).ok_or_else(bad)
    }
}

/// One protocol message, in either direction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// `< hi >`: the server's greeting.
    Hi,
    /// `< ok >`: the server accepted `open` or a mode change.
    Ok,
    /// `< echo >`: a liveness probe; the server answers with the same message.
    Echo,
    /// `< open CHANNEL >`: select the bus to talk to.
    Open(String),
    /// `< rawmode >`: receive every frame on the bus.
    RawMode,
    /// `< bcmmode >`: back to broadcast-manager mode (this hub then stops forwarding frames).
    BcmMode,
    /// `< send ID LEN BYTES... >` (data frame) or `< sendrtr ID LEN >` (remote frame): a client
    /// puts a frame on the bus.
    Send(CanFrame),
    /// `< frame ID TIME DATA >` or `< rtr ID TIME LEN >`: the server reports a frame seen on
    /// the bus.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// When the server received it.
        timestamp: Timestamp,
    },
    /// `< error TEXT >`: the server rejects the client's last message.
    Error(String),
    /// `< dropreport >` (this hub's extension, not socketcand's): the client asks to be told
    /// when the hub drops frames for it because it reads more slowly than the bus runs. No
    /// reply; from then on the hub sends [`Message::Dropped`] at most once per report interval.
    DropReport,
    /// `< dropped TOTAL >` (this hub's extension): the hub dropped frames for this client, TOTAL
    /// so far. Sent only to clients that asked with `< dropreport >`: python-can reads any
    /// unknown message as an error.
    Dropped(u64),
}

/// Why a message could not be read. The `Display` text is what the hub puts in its
/// `< error ... >` reply, so it never contains `<` or `>` and quotes at most a short, cleaned
/// excerpt of the input.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ParseError {
    /// Bytes outside any `< ... >`.
    #[error("{0} bytes outside any message ignored")]
    Junk(usize),
    /// A message longer than [`MAX_MESSAGE_LEN`]; everything up to its `>` is skipped.
    #[error("message longer than {MAX_MESSAGE_LEN} bytes skipped")]
    TooLong,
    /// A `<` inside a message: the message before it had no closing `>`.
    #[error("message without closing bracket skipped")]
    Unterminated,
    /// Not delimited by `<` and `>`.
    #[error("a message must be enclosed in angle brackets")]
    NotDelimited,
    /// Non-ASCII bytes inside a message.
    #[error("message is not ASCII text")]
    NotAscii,
    /// Nothing between the brackets.
    #[error("empty message")]
    Empty,
    /// A command this protocol does not have.
    #[error("unknown command '{0}'")]
    Unknown(String),
    /// A socketcand command this implementation does not provide.
    #[error("command '{0}' is not supported (raw mode only)")]
    Unsupported(&'static str),
    /// Wrong number of arguments.
    #[error("wrong arguments for '{command}', expected: {usage}")]
    Arguments {
        /// The command.
        command: &'static str,
        /// Its syntax.
        usage: &'static str,
    },
    /// An identifier that is not 1 to 8 hex digits.
    #[error("bad CAN id '{0}', expected 1 to 8 hex digits")]
    Id(String),
    /// A length that is not 0 to 8.
    #[error("bad length '{0}', expected 0 to 8")]
    Length(String),
    /// The number of data bytes differs from the length given.
    #[error("length says {declared} bytes but {found} follow")]
    LengthMismatch {
        /// The length field.
        declared: usize,
        /// Bytes present.
        found: usize,
    },
    /// A data byte that is not 1 or 2 hex digits.
    #[error("bad data byte '{0}', expected 1 or 2 hex digits")]
    Byte(String),
    /// Frame data that is not an even number of hex digits, at most 16.
    #[error("bad frame data '{0}', expected up to 16 hex digits")]
    Data(String),
    /// A timestamp that is not `seconds.fraction`.
    #[error("bad timestamp '{0}'")]
    Timestamp(String),
    /// A channel name that is empty, too long or has characters other than printable ASCII.
    #[error("bad channel name '{0}', expected 1 to {MAX_CHANNEL_LEN} printable characters")]
    Channel(String),
    /// Fields that do not make a valid frame (an id out of range for its format).
    #[error("{0}")]
    Frame(#[from] FrameError),
}

/// A short excerpt of client text that is safe to echo inside an `< error ... >` reply.
fn snippet(text: &str) -> String {
    const LIMIT: usize = 24;
    let mut out: String = text.chars().take(LIMIT).map(|c| if is_safe(c) { c } else { '?' }).collect();
    if text.chars().count() > LIMIT {
        out.push_str("...");
    }
    out
}

fn is_safe(c: char) -> bool {
    c.is_ascii_graphic() && c != '<' && c != '>'
}

const UNSUPPORTED: &[&str] = &[
    "add",
    "update",
    "delete",
    "filter",
    "muxfilter",
    "subscribe",
    "unsubscribe",
    "controlmode",
    "statistics",
    "isotpmode",
    "isotpconf",
    "sendpdu",
    "fdsend",
    "fdframe",
    "stat",
    "pdu",
];

impl Message {
    /// Parses one complete message, brackets included (`< send 601 0 >`).
    pub fn parse(text: &str) -> Result<Self, ParseError> {
        let inner = text.strip_prefix('<').and_then(|t| t.strip_suffix('>')).ok_or(ParseError::NotDelimited)?;
        let mut words = inner.split_ascii_whitespace();
        let command = words.next().ok_or(ParseError::Empty)?;
        let args: Vec<&str> = words.collect();
        let no_args = |message: Message, name: &'static str| {
            if args.is_empty() { Ok(message) } else { Err(ParseError::Arguments { command: name, usage: name }) }
        };
        match command {
            "hi" => no_args(Message::Hi, "hi"),
            "ok" => no_args(Message::Ok, "ok"),
            "echo" => no_args(Message::Echo, "echo"),
            "rawmode" => no_args(Message::RawMode, "rawmode"),
            "bcmmode" => no_args(Message::BcmMode, "bcmmode"),
            "open" => match args.as_slice() {
                [name] => parse_channel(name).map(|name| Message::Open(name.to_owned())),
                _ => Err(ParseError::Arguments { command: "open", usage: "open CHANNEL" }),
            },
            "send" => parse_send(&args),
            "sendrtr" => match args.as_slice() {
                [id, len] => {
                    let (id, extended) = parse_id(id)?;
                    Ok(Message::Send(CanFrame::remote(id, extended, parse_len(len)?)?))
                }
                _ => Err(ParseError::Arguments { command: "sendrtr", usage: "sendrtr ID LEN" }),
            },
            "frame" => match args.as_slice() {
                [id, time, data @ ..] => {
                    let (id, extended) = parse_id(id)?;
                    let timestamp = time.parse()?;
                    let frame = parse_contiguous(id, extended, data)?;
                    Ok(Message::Frame { frame, timestamp })
                }
                _ => Err(ParseError::Arguments { command: "frame", usage: "frame ID SECONDS.MICROS DATA" }),
            },
            "rtr" => match args.as_slice() {
                [id, time, len] => {
                    let (id, extended) = parse_id(id)?;
                    let timestamp = time.parse()?;
                    Ok(Message::Frame { frame: CanFrame::remote(id, extended, parse_len(len)?)?, timestamp })
                }
                _ => Err(ParseError::Arguments { command: "rtr", usage: "rtr ID SECONDS.MICROS LEN" }),
            },
            "error" => Ok(Message::Error(args.join(" "))),
            "dropreport" => no_args(Message::DropReport, "dropreport"),
            "dropped" => match args.as_slice() {
                [total] if total.len() <= 20 && total.bytes().all(|b| b.is_ascii_digit()) => total
                    .parse()
                    .map(Message::Dropped)
                    .map_err(|_| ParseError::Arguments { command: "dropped", usage: "dropped TOTAL" }),
                _ => Err(ParseError::Arguments { command: "dropped", usage: "dropped TOTAL" }),
            },
            other => match UNSUPPORTED.iter().find(|&&name| name == other) {
                Some(name) => Err(ParseError::Unsupported(name)),
                None => Err(ParseError::Unknown(snippet(other))),
            },
        }
    }

    /// Appends the message's wire form to `out` (no allocation beyond growing `out`).
    pub fn write_to(&self, out: &mut String) {
        // Writing into a String cannot fail.
        let _ = write!(out, "{self}");
    }
}

pub(crate) fn parse_channel(name: &str) -> Result<&str, ParseError> {
    if name.is_empty() || name.len() > MAX_CHANNEL_LEN || !name.chars().all(is_safe) {
        return Err(ParseError::Channel(snippet(name)));
    }
    Ok(name)
}

/// 1 to 3 hex digits: standard; 4 to 8: extended.
fn parse_id(text: &str) -> Result<(u32, bool), ParseError> {
    if text.is_empty() || text.len() > 8 || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ParseError::Id(snippet(text)));
    }
    let id = u32::from_str_radix(text, 16).map_err(|_| ParseError::Id(snippet(text)))?;
    Ok((id, text.len() > 3))
}

fn parse_len(text: &str) -> Result<u8, ParseError> {
    match text.as_bytes() {
        [digit @ b'0'..=b'8'] => Ok(digit - b'0'),
        _ => Err(ParseError::Length(snippet(text))),
    }
}

fn parse_send(args: &[&str]) -> Result<Message, ParseError> {
    let [id, len, bytes @ ..] = args else {
        return Err(ParseError::Arguments { command: "send", usage: "send ID LEN BYTE..." });
    };
    let (id, extended) = parse_id(id)?;
    let len = usize::from(parse_len(len)?);
    if bytes.len() != len {
        return Err(ParseError::LengthMismatch { declared: len, found: bytes.len() });
    }
    let mut data = [0u8; 8];
    for (slot, token) in data.iter_mut().zip(bytes) {
        *slot = match token.as_bytes() {
            [low] => hex_digit(*low),
            [high, low] => hex_byte(*high, *low),
            _ => None,
        }
        .ok_or_else(|| ParseError::Byte(snippet(token)))?;
    }
    let frame = if extended { CanFrame::extended(id, &data[..len]) } else { CanFrame::standard(id, &data[..len]) };
    Ok(Message::Send(frame?))
}

/// Frame data as one hex string, or as several tokens of whole bytes.
fn parse_contiguous(id: u32, extended: bool, tokens: &[&str]) -> Result<CanFrame, ParseError> {
    let mut data = [0u8; 8];
    let mut len = 0;
    for token in tokens {
        let digits = token.as_bytes();
        if !digits.len().is_multiple_of(2) || len + digits.len() / 2 > 8 {
            return Err(ParseError::Data(snippet(&tokens.join(" "))));
        }
        for pair in digits.chunks(2) {
            data[len] = hex_byte(pair[0], pair[1]).ok_or_else(|| ParseError::Data(snippet(token)))?;
            len += 1;
        }
    }
    let frame = if extended { CanFrame::extended(id, &data[..len]) } else { CanFrame::standard(id, &data[..len]) };
    Ok(frame?)
}

fn write_id(f: &mut fmt::Formatter<'_>, frame: &CanFrame) -> fmt::Result {
    if frame.is_extended() { write!(f, "{:08X}", frame.id()) } else { write!(f, "{:03X}", frame.id()) }
}

/// The canonical wire form, e.g. `< send 601 2 40 41 >`.
impl fmt::Display for Message {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Message::Hi => f.write_str("< hi >"),
            Message::Ok => f.write_str("< ok >"),
            Message::Echo => f.write_str("< echo >"),
            Message::RawMode => f.write_str("< rawmode >"),
            Message::BcmMode => f.write_str("< bcmmode >"),
            Message::DropReport => f.write_str("< dropreport >"),
            Message::Dropped(total) => write!(f, "< dropped {total} >"),
            Message::Open(channel) => {
                let clean: String = channel.chars().map(|c| if is_safe(c) { c } else { '_' }).collect();
                write!(f, "< open {clean} >")
            }
            Message::Send(frame) if frame.is_remote() => {
                f.write_str("< sendrtr ")?;
                write_id(f, frame)?;
                write!(f, " {} >", frame.dlc())
            }
            Message::Send(frame) => {
                f.write_str("< send ")?;
                write_id(f, frame)?;
                write!(f, " {}", frame.dlc())?;
                for byte in frame.data() {
                    write!(f, " {byte:02X}")?;
                }
                f.write_str(" >")
            }
            Message::Frame { frame, timestamp } if frame.is_remote() => {
                f.write_str("< rtr ")?;
                write_id(f, frame)?;
                write!(f, " {timestamp} {} >", frame.dlc())
            }
            Message::Frame { frame, timestamp } => {
                f.write_str("< frame ")?;
                write_id(f, frame)?;
                write!(f, " {timestamp} ")?;
                for byte in frame.data() {
                    write!(f, "{byte:02X}")?;
                }
                f.write_str(" >")
            }
            Message::Error(text) => {
                f.write_str("< error")?;
                for word in text.split_whitespace() {
                    f.write_char(' ')?;
                    for c in word.chars() {
                        f.write_char(if is_safe(c) { c } else { '?' })?;
                    }
                }
                f.write_str(" >")
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Between messages.
    Idle,
    /// After a `<`.
    Inside,
    /// Inside a message that grew past the limit, until its `>`.
    Skipping,
}

/// Splits a TCP byte stream into messages.
///
/// Feed it whatever `read` returned; it calls back once per complete message or problem and
/// keeps a partial message for the next call. Memory is bounded by [`MAX_MESSAGE_LEN`] whatever
/// the input, and no input makes it panic.
///
/// ```
/// use od_bus::socketcand::{Decoder, Message};
/// let mut decoder = Decoder::new();
/// let mut seen = Vec::new();
/// decoder.feed(b"< hi >< ok", |m| seen.push(m));
/// decoder.feed(b" >", |m| seen.push(m));
/// assert_eq!(seen, [Ok(Message::Hi), Ok(Message::Ok)]);
/// ```
#[derive(Debug)]
pub struct Decoder {
    buf: Vec<u8>,
    state: State,
    junk: usize,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder between messages.
    pub fn new() -> Self {
        Self { buf: Vec::with_capacity(MAX_MESSAGE_LEN), state: State::Idle, junk: 0 }
    }

    /// Consumes `bytes`, calling `emit` for each complete message (or error) in order.
    /// Whitespace between messages is ignored; other stray bytes are reported once per run as
    /// [`ParseError::Junk`].
    pub fn feed(&mut self, bytes: &[u8], mut emit: impl FnMut(Result<Message, ParseError>)) {
        for &byte in bytes {
            match (self.state, byte) {
                (_, b'<') => {
                    if self.state == State::Inside {
                        emit(Err(ParseError::Unterminated));
                    }
                    self.flush_junk(&mut emit);
                    self.buf.clear();
                    self.buf.push(byte);
                    self.state = State::Inside;
                }
                (State::Idle, byte) => {
                    if !byte.is_ascii_whitespace() {
                        self.junk += 1;
                    }
                }
                (State::Inside, b'>') => {
                    self.buf.push(byte);
                    self.state = State::Idle;
                    emit(match std::str::from_utf8(&self.buf) {
                        Ok(text) if text.is_ascii() => Message::parse(text),
                        _ => Err(ParseError::NotAscii),
                    });
                }
                (State::Inside, byte) => {
                    self.buf.push(byte);
                    if self.buf.len() >= MAX_MESSAGE_LEN {
                        self.buf.clear();
                        self.state = State::Skipping;
                        emit(Err(ParseError::TooLong));
                    }
                }
                (State::Skipping, b'>') => self.state = State::Idle,
                (State::Skipping, _) => {}
            }
        }
        self.flush_junk(&mut emit);
    }

    fn flush_junk(&mut self, emit: &mut impl FnMut(Result<Message, ParseError>)) {
        if self.junk > 0 {
            emit(Err(ParseError::Junk(self.junk)));
            self.junk = 0;
        }
    }

    /// Whether a message has been started but not finished.
    pub fn is_mid_message(&self) -> bool {
        self.state != State::Idle
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn std(id: u32, data: &[u8]) -> CanFrame {
        CanFrame::standard(id, data).unwrap()
    }

    fn ts(secs: u64, micros: u32) -> Timestamp {
        Timestamp::new(secs, micros).unwrap()
    }

    fn decode_all(bytes: &[u8]) -> Vec<Result<Message, ParseError>> {
        let mut out = Vec::new();
        Decoder::new().feed(bytes, |m| out.push(m));
        out
    }

    #[test]
    fn control_messages_print_and_parse() {
        for (message, text) in [
            (Message::Hi, "< hi >"),
            (Message::Ok, "< ok >"),
            (Message::Echo, "< echo >"),
            (Message::RawMode, "< rawmode >"),
            (Message::BcmMode, "< bcmmode >"),
            (Message::Open("can0".into()), "< open can0 >"),
            (Message::Error("unknown command".into()), "< error unknown command >"),
            (Message::DropReport, "< dropreport >"),
            (Message::Dropped(12345), "< dropped 12345 >"),
        ] {
            assert_eq!(message.to_string(), text);
            assert_eq!(Message::parse(text), Ok(message));
        }
    }

    #[test]
    fn send_as_python_can_writes_it() {
        // python-can: id with 3 or 8 upper-case digits, length in hex, bytes in lower-case hex
        // without padding.
        let message = Message::parse("< send 601 8 2b 40 60 0 6 0 0 0 >").unwrap();
        assert_eq!(message, Message::Send(std(0x601, &[0x2B, 0x40, 0x60, 0, 6, 0, 0, 0])));
        let ext = Message::parse("< send 1ABCDEF0 2 ff 1 >").unwrap();
        assert_eq!(ext, Message::Send(CanFrame::extended(0x1ABC_DEF0, &[0xFF, 1]).unwrap()));
        // python-can writes an empty payload as two spaces.
        assert_eq!(Message::parse("< send 080 0  >"), Ok(Message::Send(std(0x80, &[]))));
    }

    #[test]
    fn send_prints_canonically() {
        assert_eq!(Message::Send(std(0x601, &[0x2B, 0x40])).to_string(), "< send 601 2 2B 40 >");
        assert_eq!(Message::Send(std(0x80, &[])).to_string(), "< send 080 0 >");
        let ext = CanFrame::extended(0x12, &[1]).unwrap();
        assert_eq!(Message::Send(ext).to_string(), "< send 00000012 1 01 >");
        let rtr = CanFrame::remote(0x701, false, 1).unwrap();
        assert_eq!(Message::Send(rtr).to_string(), "< sendrtr 701 1 >");
        assert_eq!(Message::parse("< sendrtr 701 1 >"), Ok(Message::Send(rtr)));
    }

    #[test]
    fn frame_as_python_can_reads_it() {
        let frame = Message::Frame {
            frame: std(0x581, &[0x4B, 0x41, 0x60, 0, 6, 0, 0, 0]),
            timestamp: ts(1_700_000_000, 123_456),
        };
        assert_eq!(frame.to_string(), "< frame 581 1700000000.123456 4B41600006000000 >");
        assert_eq!(Message::parse("< frame 581 1700000000.123456 4B41600006000000 >"), Ok(frame));
        // No data: python-can needs the empty third field, hence two spaces.
        let sync = Message::Frame { frame: std(0x80, &[]), timestamp: ts(1, 5) };
        assert_eq!(sync.to_string(), "< frame 080 1.000005  >");
        assert_eq!(Message::parse("< frame 080 1.000005  >"), Ok(sync));
        let ext = Message::Frame { frame: CanFrame::extended(0x7FF, &[1]).unwrap(), timestamp: ts(0, 0) };
        assert_eq!(ext.to_string(), "< frame 000007FF 0.000000 01 >", "extended ids always get 8 digits");
        let rtr = Message::Frame { frame: CanFrame::remote(0x705, false, 1).unwrap(), timestamp: ts(2, 3) };
        assert_eq!(rtr.to_string(), "< rtr 705 2.000003 1 >");
        assert_eq!(Message::parse("< rtr 705 2.000003 1 >"), Ok(rtr));
    }

    #[test]
    fn frame_data_may_be_split_in_bytes() {
        // The socketcand protocol document shows this older form.
        let parsed = Message::parse("< frame 123 23.424242 11 22 33 44 >").unwrap();
        assert_eq!(parsed, Message::Frame { frame: std(0x123, &[0x11, 0x22, 0x33, 0x44]), timestamp: ts(23, 424_242) });
    }

    #[test]
    fn timestamps_parse_leniently_and_print_six_digits() {
        assert_eq!("12.5".parse::<Timestamp>(), Ok(ts(12, 500_000)));
        assert_eq!("12".parse::<Timestamp>(), Ok(ts(12, 0)));
        assert_eq!("1.123456789".parse::<Timestamp>(), Ok(ts(1, 123_456)));
        for bad in ["", ".5", "1.", "1.2.3", "a.1", "1.1234567890", "-1.0", "99999999999999999999999.0"] {
            assert!(bad.parse::<Timestamp>().is_err(), "{bad:?} parsed");
        }
        assert_eq!(ts(3, 7).to_string(), "3.000007");
        assert_eq!(Timestamp::new(0, 1_000_000), None);
    }

    #[test]
    fn malformed_messages_are_rejected_with_a_reason() {
        let cases: &[(&str, ParseError)] = &[
            ("send 601 0", ParseError::NotDelimited),
            ("<  >", ParseError::Empty),
            ("< launch >", ParseError::Unknown("launch".into())),
            ("< add 1 0 123 0 >", ParseError::Unsupported("add")),
            ("< fdsend 123 0 0 >", ParseError::Unsupported("fdsend")),
            ("< hi there >", ParseError::Arguments { command: "hi", usage: "hi" }),
            ("< open >", ParseError::Arguments { command: "open", usage: "open CHANNEL" }),
            ("< open a b >", ParseError::Arguments { command: "open", usage: "open CHANNEL" }),
            ("< send 601 >", ParseError::Arguments { command: "send", usage: "send ID LEN BYTE..." }),
            ("< send xyz 0 >", ParseError::Id("xyz".into())),
            ("< send 123456789 0 >", ParseError::Id("123456789".into())),
            ("< send 601 9 0 0 0 0 0 0 0 0 0 >", ParseError::Length("9".into())),
            ("< send 601 -1 >", ParseError::Length("-1".into())),
            ("< send 601 2 1 >", ParseError::LengthMismatch { declared: 2, found: 1 }),
            ("< send 601 1 1 2 >", ParseError::LengthMismatch { declared: 1, found: 2 }),
            ("< send 601 1 100 >", ParseError::Byte("100".into())),
            ("< send 601 1 g >", ParseError::Byte("g".into())),
            ("< send 800 0 >", ParseError::Frame(FrameError::StandardIdOutOfRange(0x800))),
            ("< send 20000000 0 >", ParseError::Frame(FrameError::ExtendedIdOutOfRange(0x2000_0000))),
            ("< sendrtr 701 >", ParseError::Arguments { command: "sendrtr", usage: "sendrtr ID LEN" }),
            ("< frame 581 1.0 123 >", ParseError::Data("123".into())),
            ("< frame 581 1.0 001122334455667788 >", ParseError::Data("001122334455667788".into())),
            ("< frame 581 x 00 >", ParseError::Timestamp("x".into())),
            ("< frame 581 >", ParseError::Arguments { command: "frame", usage: "frame ID SECONDS.MICROS DATA" }),
        ];
        for (text, expected) in cases {
            assert_eq!(Message::parse(text).as_ref(), Err(expected), "{text}");
        }
    }

    #[test]
    fn channel_names_are_checked() {
        let long = "c".repeat(MAX_CHANNEL_LEN + 1);
        let err = Message::parse(&format!("< open {long} >")).unwrap_err();
        assert!(matches!(err, ParseError::Channel(_)), "{err:?}");
        assert_eq!(Message::parse("< open vcan0 >"), Ok(Message::Open("vcan0".into())));
    }

    #[test]
    fn error_texts_never_break_the_framing() {
        let err = Message::parse("< send 60<1 0 >").unwrap_err();
        let reply = Message::Error(err.to_string()).to_string();
        assert_eq!(reply.matches('<').count(), 1, "{reply}");
        assert_eq!(reply.matches('>').count(), 1, "{reply}");
        let odd = Message::Error("a<b>c\u{7f}é \n x".into()).to_string();
        assert_eq!(odd, "< error a?b?c?? x >");
        assert_eq!(Message::parse(&odd), Ok(Message::Error("a?b?c?? x".into())));
        let long = ParseError::Unknown(snippet(&"x".repeat(100))).to_string();
        assert!(long.len() < 60, "{long}");
    }

    #[test]
    fn decoder_splits_coalesced_and_fragmented_input() {
        let stream = b"< hi >< ok >\n< frame 581 1.000000 00 >   < echo >";
        let whole = decode_all(stream);
        assert_eq!(whole.len(), 4);
        for split in 0..stream.len() {
            let mut decoder = Decoder::new();
            let mut parts = Vec::new();
            decoder.feed(&stream[..split], |m| parts.push(m));
            decoder.feed(&stream[split..], |m| parts.push(m));
            assert_eq!(parts, whole, "split at {split}");
            assert!(!decoder.is_mid_message());
        }
    }

    #[test]
    fn decoder_reports_junk_unterminated_and_overlong_messages_then_resyncs() {
        assert_eq!(decode_all(b"garbage< hi >"), [Err(ParseError::Junk(7)), Ok(Message::Hi)]);
        assert_eq!(decode_all(b"< send 601< hi >"), [Err(ParseError::Unterminated), Ok(Message::Hi)]);
        let mut long = b"< ".to_vec();
        long.extend(std::iter::repeat_n(b'x', 10_000));
        long.extend_from_slice(b" >< ok >");
        assert_eq!(decode_all(&long), [Err(ParseError::TooLong), Ok(Message::Ok)]);
        assert_eq!(decode_all(b"< \xff\xfe >< ok >"), [Err(ParseError::NotAscii), Ok(Message::Ok)]);
        assert_eq!(decode_all(b"> > ok"), [Err(ParseError::Junk(4))]);
    }
}
