//! slcan, the Lawicel ASCII protocol of serial CAN adapters (CANable, USBtin, Lawicel CANUSB,
//! many Arduino and ESP32 bridges): the codec, sans I/O, and a blocking [`Endpoint`] over any
//! byte stream ([`SlcanPort`]).
//!
//! One command or message is one line of ASCII ended by `\r`:
//!
//! | line | meaning |
//! |---|---|
//! | `tIIILDD..` | data frame, 11-bit id `III`, length `L` (0-8), `L` data bytes in hex |
//! | `TIIIIIIIILDD..` | data frame, 29-bit id |
//! | `rIIIL`, `RIIIIIIIIL` | remote frame (standard, extended), length requested `L` |
//! | `S0`..`S8` | bit rate 10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k, 1M |
//! | `O`, `L`, `C` | open the channel (normal, listen-only), close it |
//! | `F` | read the status flags (reply `Fxx`) |
//! | `V`, `N` | version (`Vhhss`), serial number (`Nxxxx`) |
//!
//! An adapter's frames may carry a 4-digit millisecond time stamp after the data (Lawicel's
//! `Z1`); the decoder accepts it. Adapters differ in what they answer: a Lawicel device
//! acknowledges every command with `\r` (`z\r`/`Z\r` for a frame sent) or refuses it with BEL
//! (0x07), and reports status flags; the stock CANable firmware answers nothing at all. So a
//! host never waits for a reply: it writes and goes on ([`Session`]), and it uses the
//! acknowledgements and flags where they come.
//!
//! The decoder never panics and never makes up a frame: a line that is not exactly one of the
//! forms above (garbage, a line longer than [`MAX_LINE`], a BEL in the middle of a line, two
//! lines run together because a `\r` was lost) is one [`LineError`], and decoding goes on
//! from the next line.
//!
//! ```
//! use od_bus::CanFrame;
//! use od_bus::slcan::{Decoder, Reply, encode};
//! let frame = CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0x00]).unwrap();
//! let mut line = Vec::new();
//! encode(&frame, &mut line);
//! assert_eq!(line, b"t601440416000\r");
//! let mut replies = Vec::new();
//! Decoder::new().feed(b"x?\rt601440416000\r", |reply| replies.push(reply));
//! assert!(matches!(replies[0], Reply::Invalid(_)));
//! assert_eq!(replies[1], Reply::Frame { frame, timestamp: None });
//! ```

use std::collections::VecDeque;
use std::fmt;
use std::io;
use std::time::{Duration, Instant};

use crate::endpoint::Endpoint;
use crate::error::TransportError;
use crate::frame::{CanFrame, hex_digit};

/// Longest line the decoders keep (a frame with an extended id, 8 bytes and a time stamp is
/// 30 characters; version strings are longer on some firmware). Past it a line is
/// [`LineError::Overlong`] and dropped up to its `\r`.
pub const MAX_LINE: usize = 64;

/// The bit rates of `S0` to `S8`, in bits per second.
pub const BITRATES: [u32; 9] = [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000];

/// The `Sn` code of a bit rate, `None` for a rate slcan has no code for.
pub fn bitrate_code(bits_per_second: u32) -> Option<u8> {
    BITRATES.iter().position(|&b| b == bits_per_second).map(|i| i as u8)
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Appends the line for `frame` (`t`, `T`, `r` or `R`, with its `\r`) to `out`.
pub fn encode(frame: &CanFrame, out: &mut Vec<u8>) {
    let mut line = [0u8; 27];
    let n = encode_into(frame, &mut line);
    out.extend_from_slice(&line[..n]);
}

/// Writes the line for `frame` into `line`; returns its length (at most 27, `\r` included).
pub fn encode_into(frame: &CanFrame, line: &mut [u8; 27]) -> usize {
    let (kind, digits) = match (frame.is_extended(), frame.is_remote()) {
        (false, false) => (b't', 3),
        (true, false) => (b'T', 8),
        (false, true) => (b'r', 3),
        (true, true) => (b'R', 8),
    };
    line[0] = kind;
    let id = frame.id();
    for i in 0..digits {
        line[1 + i] = HEX[((id >> (4 * (digits - 1 - i))) & 0xF) as usize];
    }
    let mut n = 1 + digits;
    line[n] = b'0' + frame.dlc();
    n += 1;
    for &byte in frame.data() {
        line[n] = HEX[usize::from(byte >> 4)];
        line[n + 1] = HEX[usize::from(byte & 0xF)];
        n += 2;
    }
    line[n] = b'\r';
    n + 1
}

/// Why a line is not one the protocol has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    /// Longer than [`MAX_LINE`]: dropped up to its `\r`.
    #[error("a line longer than {MAX_LINE} characters (dropped up to its \\r)")]
    Overlong,
    /// A BEL (0x07) came in the middle of a line: the part before it is dropped.
    #[error("a BEL in the middle of a line (the part before it was dropped)")]
    Interrupted,
    /// A line that starts with no command or message the protocol has.
    #[error("not an slcan line (unknown first character)")]
    Unknown,
    /// A frame, status or command line whose rest does not fit its first character.
    #[error("malformed slcan line: {0}")]
    Malformed(&'static str),
}

/// What an adapter sends a host, one line at a time.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// A frame received from the bus, with the adapter's millisecond time stamp if it sends one.
    Frame {
        /// The frame.
        frame: CanFrame,
        /// `Z1`'s time stamp, milliseconds modulo 60000.
        timestamp: Option<u16>,
    },
    /// `\r` alone: the command before was done (Lawicel).
    Ok,
    /// BEL: the command before was refused (Lawicel: channel not open, bus-off, bad command).
    Error,
    /// `z` or `Z`: a frame was queued for transmission (Lawicel).
    Sent,
    /// `Fxx`: the status flags ([`status`] names the bits).
    Status(u8),
    /// `Vhhss` (or `v...`): the version string, without its first character.
    Version(String),
    /// `Nxxxx`: the serial number, without the `N`.
    Serial(String),
    /// A line that is none of the above; decoding goes on with the next one.
    Invalid(LineError),
}

/// The status flags of a Lawicel `F` reply.
pub mod status {
    /// The adapter's receive queue was full: frames were lost.
    pub const RX_FULL: u8 = 0x01;
    /// The adapter's transmit queue was full.
    pub const TX_FULL: u8 = 0x02;
    /// Error warning (an error counter reached 96).
    pub const ERROR_WARNING: u8 = 0x04;
    /// Data overrun: frames were lost.
    pub const OVERRUN: u8 = 0x08;
    /// Error passive (an error counter reached 128).
    pub const ERROR_PASSIVE: u8 = 0x20;
    /// Arbitration lost.
    pub const ARBITRATION_LOST: u8 = 0x40;
    /// Bus error: the controller went bus-off; a Lawicel adapter recovers only by `C` then `O`.
    pub const BUS_ERROR: u8 = 0x80;
}

/// Cuts a byte stream into lines: `\r` (or `\n`, or `\r\n`) ends a line, BEL stands alone,
/// nothing grows past [`MAX_LINE`].
#[derive(Debug, Clone)]
struct Lines {
    buf: [u8; MAX_LINE],
    len: usize,
    overlong: bool,
    /// The last byte was `\r`: a `\n` right after it belongs to it.
    after_cr: bool,
}

enum Piece<'a> {
    Line(&'a [u8]),
    Bel,
    Invalid(LineError),
}

impl Lines {
    const fn new() -> Self {
        Self { buf: [0; MAX_LINE], len: 0, overlong: false, after_cr: false }
    }

    fn feed(&mut self, bytes: &[u8], mut piece: impl FnMut(Piece<'_>)) {
        for &byte in bytes {
            match byte {
                b'\r' | b'\n' => {
                    let swallowed = byte == b'\n' && (self.after_cr || (self.len == 0 && !self.overlong));
                    self.after_cr = byte == b'\r';
                    if swallowed {
                        continue;
                    }
                    if self.overlong {
                        piece(Piece::Invalid(LineError::Overlong));
                    } else {
                        piece(Piece::Line(&self.buf[..self.len]));
                    }
                    self.len = 0;
                    self.overlong = false;
                }
                0x07 => {
                    self.after_cr = false;
                    if self.len > 0 || self.overlong {
                        piece(Piece::Invalid(LineError::Interrupted));
                    }
                    self.len = 0;
                    self.overlong = false;
                    piece(Piece::Bel);
                }
                _ => {
                    self.after_cr = false;
                    if self.overlong {
                    } else if self.len == MAX_LINE {
                        self.overlong = true;
                    } else {
                        self.buf[self.len] = byte;
                        self.len += 1;
                    }
                }
            }
        }
    }

    /// Forgets a partial line (after a reconnection: the bytes before belong to another port).
    fn clear(&mut self) {
        *self = Self::new();
    }
}

/// The host's decoder: bytes from an adapter in, [`Reply`]s out.
#[derive(Debug, Clone)]
pub struct Decoder {
    lines: Lines,
}

impl Default for Decoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder {
    /// A decoder at the start of a line.
    pub const fn new() -> Self {
        Self { lines: Lines::new() }
    }

    /// Decodes `bytes`, calling `reply` for each complete line (a partial line waits for more).
    pub fn feed(&mut self, bytes: &[u8], mut reply: impl FnMut(Reply)) {
        self.lines.feed(bytes, |piece| {
            reply(match piece {
                Piece::Line(line) => parse_reply(line),
                Piece::Bel => Reply::Error,
                Piece::Invalid(error) => Reply::Invalid(error),
            })
        });
    }

    /// Forgets a partial line.
    pub fn clear(&mut self) {
        self.lines.clear();
    }
}

fn parse_reply(line: &[u8]) -> Reply {
    let Some(&first) = line.first() else { return Reply::Ok };
    let rest = &line[1..];
    match first {
        b't' | b'T' | b'r' | b'R' => match parse_frame(line, true) {
            Ok((frame, timestamp)) => Reply::Frame { frame, timestamp },
            Err(error) => Reply::Invalid(error),
        },
        b'z' | b'Z' if rest.is_empty() => Reply::Sent,
        b'F' => match rest {
            [high, low] => match (hex_digit(*high), hex_digit(*low)) {
                (Some(h), Some(l)) => Reply::Status(h << 4 | l),
                _ => Reply::Invalid(LineError::Malformed("status flags must be two hex digits")),
            },
            _ => Reply::Invalid(LineError::Malformed("status flags must be two hex digits")),
        },
        b'V' | b'v' | b'N' if rest.iter().all(|b| b.is_ascii_graphic() || *b == b' ') => {
            let text = String::from_utf8_lossy(rest).into_owned();
            if first == b'N' { Reply::Serial(text) } else { Reply::Version(text) }
        }
        _ => Reply::Invalid(LineError::Unknown),
    }
}

/// Parses a frame line (`t`, `T`, `r`, `R`); an adapter's line may end in a time stamp.
fn parse_frame(line: &[u8], timestamp_allowed: bool) -> Result<(CanFrame, Option<u16>), LineError> {
    let (extended, remote) = match line.first() {
        Some(b't') => (false, false),
        Some(b'T') => (true, false),
        Some(b'r') => (false, true),
        Some(b'R') => (true, true),
        _ => return Err(LineError::Unknown),
    };
    let digits = if extended { 8 } else { 3 };
    if line.len() < 2 + digits {
        return Err(LineError::Malformed("a frame line too short for its id and length"));
    }
    let id = hex_value(&line[1..1 + digits]).ok_or(LineError::Malformed("the id must be hex digits"))?;
    let dlc = match line[1 + digits] {
        digit @ b'0'..=b'8' => digit - b'0',
        _ => return Err(LineError::Malformed("the length must be a digit from 0 to 8")),
    };
    let rest = &line[2 + digits..];
    let data_digits = if remote { 0 } else { 2 * usize::from(dlc) };
    let timestamp = match rest.len().checked_sub(data_digits) {
        Some(0) => None,
        Some(4) if timestamp_allowed => Some(
            u16::try_from(hex_value(&rest[data_digits..]).ok_or(LineError::Malformed("the time stamp must be hex"))?)
                .map_err(|_| LineError::Malformed("the time stamp must be 4 hex digits"))?,
        ),
        _ => return Err(LineError::Malformed("the data does not match the length")),
    };
    let mut data = [0u8; 8];
    for (slot, pair) in data.iter_mut().zip(rest[..data_digits].chunks(2)) {
        *slot = (hex_value(pair).ok_or(LineError::Malformed("data must be hex digits"))?) as u8;
    }
    let frame = CanFrame::from_parts(id, extended, remote, dlc, data)
        .map_err(|_| LineError::Malformed("a standard id above 7FF"))?;
    Ok((frame, timestamp))
}

/// The value of up to 8 hex digits.
fn hex_value(digits: &[u8]) -> Option<u32> {
    digits.iter().try_fold(0u32, |value, &digit| Some(value << 4 | u32::from(hex_digit(digit)?)))
}

/// What a host sends an adapter, as an adapter reads it (the simulated adapter's side).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `t`, `T`, `r`, `R`: put this frame on the bus.
    Transmit(CanFrame),
    /// `O`: open the channel.
    Open,
    /// `L`: open the channel listening only (no acknowledgement, no transmission).
    ListenOnly,
    /// `C`: close the channel.
    Close,
    /// `Sn`: bit rate `BITRATES[n]`.
    Bitrate(u8),
    /// `sxxyy`: SJA1000 bit timing registers BTR0 and BTR1.
    BitTiming(u16),
    /// `V`: the version.
    Version,
    /// `N`: the serial number.
    SerialNumber,
    /// `F`: the status flags.
    Status,
    /// `Zn`: time stamps on (`Z1`) or off (`Z0`).
    Timestamps(bool),
    /// `M0`/`M1` (CANable's mode): silent (listen-only) when `true`.
    Silent(bool),
    /// `Mxxxxxxxx`, `mxxxxxxxx` (Lawicel): acceptance code or mask; the flag is `true` for the mask.
    Acceptance(bool, u32),
    /// `A0`/`A1` (CANable): automatic retransmission off or on.
    AutoRetransmit(bool),
    /// An empty line (a host clearing the adapter's input, `\r\r\r`).
    Empty,
}

impl Command {
    /// Parses one line (without its `\r`).
    pub fn parse(line: &[u8]) -> Result<Self, LineError> {
        let Some(&first) = line.first() else { return Ok(Command::Empty) };
        let rest = &line[1..];
        let flag = |rest: &[u8]| match rest {
            [b'0'] => Ok(false),
            [b'1'] => Ok(true),
            _ => Err(LineError::Malformed("expected 0 or 1")),
        };
        match first {
            b't' | b'T' | b'r' | b'R' => parse_frame(line, false).map(|(frame, _)| Command::Transmit(frame)),
            b'O' | b'L' | b'C' | b'V' | b'v' | b'N' | b'F' if !rest.is_empty() => {
                Err(LineError::Malformed("this command takes no argument"))
            }
            b'O' => Ok(Command::Open),
            b'L' => Ok(Command::ListenOnly),
            b'C' => Ok(Command::Close),
            b'V' | b'v' => Ok(Command::Version),
            b'N' => Ok(Command::SerialNumber),
            b'F' => Ok(Command::Status),
            b'S' => match rest {
                [digit @ b'0'..=b'8'] => Ok(Command::Bitrate(digit - b'0')),
                _ => Err(LineError::Malformed("the bit rate code must be S0 to S8")),
            },
            b's' if rest.len() == 4 => hex_value(rest)
                .map(|v| Command::BitTiming(v as u16))
                .ok_or(LineError::Malformed("s takes four hex digits")),
            b'Z' => flag(rest).map(Command::Timestamps),
            b'A' | b'a' => flag(rest).map(Command::AutoRetransmit),
            b'M' | b'm' if rest.len() == 1 => flag(rest).map(Command::Silent),
            b'M' | b'm' if rest.len() == 8 => hex_value(rest)
                .map(|v| Command::Acceptance(first == b'm', v))
                .ok_or(LineError::Malformed("an acceptance code or mask is eight hex digits")),
            _ => Err(LineError::Unknown),
        }
    }
}

/// The adapter's decoder: bytes from a host in, [`Command`]s (or why a line is none) out.
#[derive(Debug, Clone)]
pub struct CommandDecoder {
    lines: Lines,
}

impl Default for CommandDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl CommandDecoder {
    /// A decoder at the start of a line.
    pub const fn new() -> Self {
        Self { lines: Lines::new() }
    }

    /// Decodes `bytes`, calling `command` for each complete line.
    pub fn feed(&mut self, bytes: &[u8], mut command: impl FnMut(Result<Command, LineError>)) {
        self.lines.feed(bytes, |piece| match piece {
            Piece::Line(line) => command(Command::parse(line)),
            Piece::Bel => command(Err(LineError::Unknown)),
            Piece::Invalid(error) => command(Err(error)),
        });
    }
}

/// How a host sets an adapter up: the bus's bit rate and whether to stay silent on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Setup {
    /// Bits per second, one of [`BITRATES`].
    pub bitrate: u32,
    /// Listen only: no acknowledgements, no transmissions (CANable's `M1`, Lawicel's `L`).
    pub listen_only: bool,
}

impl Setup {
    /// The commands that open the channel, for any adapter and without waiting for replies:
    /// `\r\r\r` ends whatever partial command the adapter holds, `C` closes the channel if
    /// open, `Sn` sets the bit rate, then the mode and `O`. Listen-only is said both ways,
    /// `M1` (CANable) and `L` (Lawicel); each firmware refuses or ignores the other's command,
    /// and a Lawicel device opened by `L` refuses the `O` after it. Normal mode sends `M0`, so
    /// a CANable left silent by an earlier session transmits again.
    pub fn open_commands(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(b"\r\r\r");
        self.reopen_commands(out);
    }

    /// `C`, `Sn`, the mode and `O`: what brings a Lawicel adapter back from bus-off.
    pub fn reopen_commands(&self, out: &mut Vec<u8>) {
        // A Setup's bit rate was checked where it was made; 500 kbit/s is never taken.
        let code = bitrate_code(self.bitrate).unwrap_or(6);
        out.extend_from_slice(b"C\rS");
        out.push(b'0' + code);
        out.extend_from_slice(if self.listen_only { b"\rM1\rL\rO\r" } else { b"\rM0\rO\r" });
    }
}

/// What a [`Session`] reports besides frames.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Event {
    /// The adapter answered a command: it is one that acknowledges (Lawicel); from now on its
    /// status flags are polled.
    Acknowledging,
    /// The status flags said bus-off; the session wrote `C` and `O` to recover.
    BusOff {
        /// The flags of the `F` reply.
        flags: u8,
    },
    /// The status flags said frames were lost in the adapter.
    Overrun {
        /// The flags of the `F` reply.
        flags: u8,
    },
    /// A line that was not one of the protocol's, skipped.
    Invalid(LineError),
}

/// A host's side of one slcan link, sans I/O: decodes what the adapter sends, tells frames
/// from replies, learns whether the adapter acknowledges, polls its status flags when it does
/// (every [`Session::STATUS_INTERVAL`]), and recovers from bus-off by `C` then `O`. It never
/// waits for a reply: firmware that answers nothing works the same.
#[derive(Debug, Clone)]
pub struct Session {
    setup: Setup,
    decoder: Decoder,
    acknowledging: bool,
    next_status: Option<Instant>,
    overruns: u64,
    invalid: u64,
}

impl Session {
    /// How often the status flags of an acknowledging adapter are read.
    pub const STATUS_INTERVAL: Duration = Duration::from_millis(500);

    /// A session for an adapter set up as `setup`; write [`Setup::open_commands`] first.
    pub fn new(setup: Setup) -> Self {
        Self { setup, decoder: Decoder::new(), acknowledging: false, next_status: None, overruns: 0, invalid: 0 }
    }

    /// The setup.
    pub fn setup(&self) -> &Setup {
        &self.setup
    }

    /// Whether the adapter has answered a command (Lawicel) rather than stayed silent (CANable).
    pub fn acknowledging(&self) -> bool {
        self.acknowledging
    }

    /// Overruns the adapter reported (each lost at least one frame).
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Lines that were not the protocol's.
    pub fn invalid_lines(&self) -> u64 {
        self.invalid
    }

    /// Takes bytes read from the adapter: frames to `frame`, other news to `event`, and the
    /// commands the session wants written (bus-off recovery) appended to `out`.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        now: Instant,
        out: &mut Vec<u8>,
        mut frame: impl FnMut(CanFrame),
        mut event: impl FnMut(Event),
    ) {
        let Self { setup, decoder, acknowledging, next_status, overruns, invalid } = self;
        decoder.feed(bytes, |reply| match reply {
            Reply::Frame { frame: f, .. } => frame(f),
            Reply::Invalid(error) => {
                *invalid += 1;
                event(Event::Invalid(error));
            }
            Reply::Version(_) | Reply::Serial(_) => {}
            reply => {
                if !*acknowledging {
                    *acknowledging = true;
                    *next_status = Some(now + Self::STATUS_INTERVAL);
                    event(Event::Acknowledging);
                }
                match reply {
                    Reply::Status(flags) if flags & status::BUS_ERROR != 0 => {
                        setup.reopen_commands(out);
                        event(Event::BusOff { flags });
                    }
                    Reply::Status(flags) if flags & (status::OVERRUN | status::RX_FULL) != 0 => {
                        *overruns += 1;
                        event(Event::Overrun { flags });
                    }
                    // A refused command (a frame sent to a closed or bus-off channel): ask
                    // for the flags at once rather than at the next interval.
                    Reply::Error => *next_status = Some(now),
                    _ => {}
                }
            }
        });
    }

    /// When [`poll`](Session::poll) has something to write next (`None`: never, the adapter
    /// does not acknowledge).
    pub fn deadline(&self) -> Option<Instant> {
        self.next_status
    }

    /// Appends `F\r` to `out` when the status flags are due.
    pub fn poll(&mut self, now: Instant, out: &mut Vec<u8>) {
        if self.next_status.is_some_and(|due| now >= due) {
            out.extend_from_slice(b"F\r");
            self.next_status = Some(now + Self::STATUS_INTERVAL);
        }
    }

    /// After the port was opened again: the adapter may be another one, and any partial line
    /// is gone. Write [`Setup::open_commands`] again.
    pub fn restart(&mut self) {
        self.decoder.clear();
        self.acknowledging = false;
        self.next_status = None;
    }
}

/// A byte stream an slcan adapter is reached through: a serial port, or a pseudo-terminal in
/// tests. Reads wait at most the timeout set, then fail with `TimedOut` or `WouldBlock`.
pub trait SerialLink: io::Read + io::Write + Send {
    /// How long a read waits for the first byte.
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
}

impl SerialLink for Box<dyn serialport::SerialPort> {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.set_timeout(timeout).map_err(io::Error::from)
    }
}

#[cfg(unix)]
impl SerialLink for serialport::TTYPort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self, timeout).map_err(io::Error::from)
    }
}

/// Opens the serial port `port` at `serial_baud` (USB adapters ignore the speed), naming it
/// and the likely cause in the error.
pub fn open_serial(port: &str, serial_baud: u32) -> Result<Box<dyn serialport::SerialPort>, TransportError> {
    serialport::new(port, serial_baud).timeout(Duration::from_millis(50)).open().map_err(|e| {
        let hint = match e.kind() {
            serialport::ErrorKind::NoDevice => "is the adapter plugged in, and is the name right?",
            serialport::ErrorKind::Io(io::ErrorKind::PermissionDenied) => {
                "no permission: on Linux join the group that owns it (dialout, uucp)"
            }
            serialport::ErrorKind::Io(io::ErrorKind::NotFound) => "no such port: is the adapter plugged in?",
            _ => "is the adapter plugged in, and not open in another program?",
        };
        TransportError::io(format!("cannot open serial port {port} ({hint})"), io::Error::from(e))
    })
}

/// A blocking [`Endpoint`] on an slcan adapter, over any [`SerialLink`]: [`SlcanPort::open`]
/// for a serial port by name, [`SlcanPort::new`] for a stream already open (a pseudo-terminal
/// in tests). It writes the setup at once and never waits for a reply; a failed port is an
/// error of `send` or `recv_timeout` (the async bus, `od_bus::tokio::Bus`, opens it again).
pub struct SlcanPort<P> {
    port: P,
    name: String,
    session: Session,
    frames: VecDeque<CanFrame>,
    out: Vec<u8>,
    buf: Box<[u8; 1024]>,
    timeout: Option<Duration>,
}

impl SlcanPort<Box<dyn serialport::SerialPort>> {
    /// Opens the serial port `port` (`/dev/ttyACM0`, `COM4`, `/dev/cu.usbmodem1101`) at
    /// `serial_baud` and sets the adapter up.
    pub fn open(port: &str, serial_baud: u32, setup: Setup) -> Result<Self, TransportError> {
        Self::new(open_serial(port, serial_baud)?, port, setup)
    }
}

impl<P: SerialLink> SlcanPort<P> {
    /// Sets up the adapter on `port` (named `name` in errors): writes [`Setup::open_commands`].
    pub fn new(mut port: P, name: &str, setup: Setup) -> Result<Self, TransportError> {
        if bitrate_code(setup.bitrate).is_none() {
            return Err(TransportError::Unavailable(bitrate_error(setup.bitrate)));
        }
        let mut out = Vec::with_capacity(64);
        setup.open_commands(&mut out);
        port.write_all(&out).and_then(|()| port.flush()).map_err(|e| write_error(name, e))?;
        out.clear();
        Ok(Self {
            port,
            name: name.to_owned(),
            session: Session::new(setup),
            frames: VecDeque::new(),
            out,
            buf: Box::new([0; 1024]),
            timeout: None,
        })
    }

    /// The session (whether the adapter acknowledges, overruns, invalid lines).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// Reads once, waiting at most `timeout`; false when nothing came.
    fn read_some(&mut self, timeout: Duration) -> Result<bool, TransportError> {
        let timeout = timeout.max(Duration::from_millis(1));
        if self.timeout != Some(timeout) {
            self.port.set_read_timeout(timeout).map_err(|e| read_error(&self.name, e))?;
            self.timeout = Some(timeout);
        }
        let n = match self.port.read(&mut self.buf[..]) {
            Ok(0) => return Err(TransportError::Closed),
            Ok(n) => n,
            Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => 0,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => 0,
            Err(e) => return Err(read_error(&self.name, e)),
        };
        let now = Instant::now();
        let Self { session, frames, out, buf, .. } = self;
        session.feed(&buf[..n], now, out, |frame| frames.push_back(frame), |_| {});
        session.poll(now, out);
        self.flush_out()?;
        Ok(n > 0)
    }

    fn flush_out(&mut self) -> Result<(), TransportError> {
        if !self.out.is_empty() {
            let result = self.port.write_all(&self.out);
            self.out.clear();
            result.map_err(|e| write_error(&self.name, e))?;
        }
        Ok(())
    }
}

fn write_error(name: &str, error: io::Error) -> TransportError {
    TransportError::io(format!("cannot write to {name} (was the adapter unplugged?)"), error)
}

fn read_error(name: &str, error: io::Error) -> TransportError {
    TransportError::io(format!("cannot read from {name} (was the adapter unplugged?)"), error)
}

pub(crate) fn bitrate_error(bitrate: u32) -> String {
    format!("slcan has no code for {bitrate} bit/s; the rates are {BITRATES:?} (S0 to S8)")
}

impl<P: SerialLink> Endpoint for SlcanPort<P> {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        self.send_all(&[frame])
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        for frame in frames {
            encode(frame, &mut self.out);
        }
        self.flush_out()
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        let deadline = Instant::now().checked_add(timeout);
        loop {
            if let Some(frame) = self.frames.pop_front() {
                return Ok(Some(frame));
            }
            let left = deadline.map_or(Duration::from_secs(1), |d| d.saturating_duration_since(Instant::now()));
            if left.is_zero() {
                // One look without waiting (a zero timeout polls).
                self.read_some(Duration::from_millis(1))?;
                return Ok(self.frames.pop_front());
            }
            self.read_some(left)?;
        }
    }

    fn buffered(&self) -> usize {
        self.frames.len()
    }

    fn lost(&self) -> u64 {
        self.session.overruns()
    }
}

impl<P> fmt::Debug for SlcanPort<P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SlcanPort")
            .field("port", &self.name)
            .field("setup", &self.session.setup)
            .field("acknowledging", &self.session.acknowledging)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn replies(bytes: &[u8]) -> Vec<Reply> {
        let mut out = Vec::new();
        Decoder::new().feed(bytes, |r| out.push(r));
        out
    }

    #[test]
    fn encodes_every_frame_kind() {
        let cases = [
            (CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0]).unwrap(), &b"t601440416000\r"[..]),
            (CanFrame::standard(0x080, &[]).unwrap(), b"t0800\r"),
            (CanFrame::extended(0x1ABC_DEF0, &[0xFF; 8]).unwrap(), b"T1ABCDEF08FFFFFFFFFFFFFFFF\r"),
            (CanFrame::remote(0x705, false, 1).unwrap(), b"r7051\r"),
            (CanFrame::remote(0x10, true, 8).unwrap(), b"R000000108\r"),
        ];
        for (frame, line) in cases {
            let mut out = Vec::new();
            encode(&frame, &mut out);
            assert_eq!(out, line, "{frame}");
            assert_eq!(replies(line), [Reply::Frame { frame, timestamp: None }]);
            assert_eq!(Command::parse(&line[..line.len() - 1]), Ok(Command::Transmit(frame)));
        }
    }

    #[test]
    fn decodes_replies_and_time_stamps() {
        let frame = CanFrame::standard(0x181, &[1, 2]).unwrap();
        assert_eq!(
            replies(b"t18120102EA60\r\r\x07z\rZ\rF80\rV1013\rNA123\r\n"),
            [
                Reply::Frame { frame, timestamp: Some(0xEA60) },
                Reply::Ok,
                Reply::Error,
                Reply::Sent,
                Reply::Sent,
                Reply::Status(0x80),
                Reply::Version("1013".into()),
                Reply::Serial("A123".into()),
            ]
        );
    }

    #[test]
    fn bad_lines_are_errors_and_the_next_line_decodes() {
        let good = CanFrame::standard(0x701, &[5]).unwrap();
        for bad in [
            &b"q\r"[..],
            b"t8000\r",
            b"t1239\r",
            b"t12320\r",
            b"t1231GG\r",
            b"T1234567\r",
            b"F1\r",
            b"t1230t1230\r",
            b"xyz\x07",
        ] {
            let mut input = bad.to_vec();
            input.extend_from_slice(b"t701105\r");
            let got = replies(&input);
            assert!(matches!(got[0], Reply::Invalid(_)), "{bad:?}: {got:?}");
            assert_eq!(got.last(), Some(&Reply::Frame { frame: good, timestamp: None }), "{bad:?}");
        }
        let mut long = vec![b't'; 500];
        long.extend_from_slice(b"\rt701105\r");
        assert_eq!(
            replies(&long),
            [Reply::Invalid(LineError::Overlong), Reply::Frame { frame: good, timestamp: None }]
        );
    }

    #[test]
    fn commands_parse() {
        for (line, command) in [
            (&b"O"[..], Command::Open),
            (b"L", Command::ListenOnly),
            (b"C", Command::Close),
            (b"S8", Command::Bitrate(8)),
            (b"s031C", Command::BitTiming(0x031C)),
            (b"M1", Command::Silent(true)),
            (b"m0", Command::Silent(false)),
            (b"M00000000", Command::Acceptance(false, 0)),
            (b"mFFFFFFFF", Command::Acceptance(true, 0xFFFF_FFFF)),
            (b"Z1", Command::Timestamps(true)),
            (b"A0", Command::AutoRetransmit(false)),
            (b"F", Command::Status),
            (b"V", Command::Version),
            (b"N", Command::SerialNumber),
            (b"", Command::Empty),
        ] {
            assert_eq!(Command::parse(line), Ok(command), "{line:?}");
        }
        for bad in [&b"S9"[..], b"O1", b"M2", b"M123", b"s12", b"X", b"t1234"] {
            assert!(Command::parse(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn the_open_commands_work_for_both_firmwares() {
        let mut out = Vec::new();
        Setup { bitrate: 500_000, listen_only: false }.open_commands(&mut out);
        assert_eq!(out, b"\r\r\rC\rS6\rM0\rO\r");
        out.clear();
        Setup { bitrate: 1_000_000, listen_only: true }.open_commands(&mut out);
        assert_eq!(out, b"\r\r\rC\rS8\rM1\rL\rO\r");
    }

    #[test]
    fn a_session_polls_only_an_adapter_that_answers_and_recovers_from_bus_off() {
        let start = Instant::now();
        let setup = Setup { bitrate: 250_000, listen_only: false };
        let mut session = Session::new(setup);
        let mut out = Vec::new();
        let mut frames = Vec::new();
        let mut events = Vec::new();
        session.feed(b"t1230\r", start, &mut out, |f| frames.push(f), |e| events.push(e));
        session.poll(start + Duration::from_secs(10), &mut out);
        assert!(out.is_empty() && !session.acknowledging() && session.deadline().is_none());
        session.feed(b"\r", start, &mut out, |f| frames.push(f), |e| events.push(e));
        assert_eq!(events, [Event::Acknowledging]);
        session.poll(start + Session::STATUS_INTERVAL, &mut out);
        assert_eq!(out, b"F\r");
        out.clear();
        session.feed(b"F88\r", start, &mut out, |f| frames.push(f), |e| events.push(e));
        assert_eq!(out, b"C\rS5\rM0\rO\r");
        assert_eq!(events[1], Event::BusOff { flags: 0x88 });
        out.clear();
        session.feed(b"F08\r", start, &mut out, |f| frames.push(f), |e| events.push(e));
        assert_eq!(session.overruns(), 1);
        assert!(out.is_empty());
        assert_eq!(frames.len(), 1);
    }
}
