//! The SDO client (CiA 301 §7.2.4): expedited, segmented and block transfers, as a state
//! machine for one SDO channel of one server.
//!
//! One [`SdoClient`] runs one transfer at a time, as CiA 301 allows on an SDO channel; a
//! master runs transfers to several nodes at once with one client per node. The client owns
//! no I/O and no clock:
//!
//! - [`SdoClient::upload`] / [`SdoClient::download`] start a transfer with a buffer the caller
//!   hands over (any `B: AsRef<[u8]> + AsMut<[u8]>`: a `Vec<u8>` on a host, an array or a
//!   `&mut [u8]` on a microcontroller) and get it back in the [`Done`] that ends the transfer;
//! - [`SdoClient::on_frame`] takes every frame received (it keeps those on its COB-ID);
//! - [`SdoClient::poll`] hands out the frames to send and fires the timeout;
//!   [`SdoClient::deadline`] says when it next needs to be called.
//!
//! A transfer ends exactly once, with a [`Done`] from `on_frame`, `poll` or
//! [`SdoClient::abort`]. Every way it can fail ends it with a [`SdoError`]: the server's abort
//! ([`SdoError::Server`]), or this client's, which sends the abort frame first
//! ([`SdoError::Client`]: timeout, wrong toggle bit, wrong sequence number, CRC mismatch, a
//! size indication the data does not match, a value larger than the buffer, an unexpected
//! command). A transfer that completes has every byte the server sent and nothing else: the
//! checks above run before [`Done::result`] is `Ok`.
//!
//! The client never retries. Retrying is the caller's decision (a read can be repeated, a
//! write only when the object is idempotent), and a retry is a new transfer from the start.
//!
//! A server that does not do block transfers (CiA 301 lets a server leave them out) is met
//! with a fallback, on by default ([`SdoClient::set_block_fallback`]): a block transfer whose
//! initiate request the server refuses with abort 0504 0001h (command specifier not valid or
//! unknown) for the transfer's object starts again as a normal transfer, and a normal initiate
//! upload response that indicates the size, to a block upload request (what python-canopen's
//! `LocalNode` sends, whatever the protocol switch threshold), continues as that normal upload. Nothing of the
//! object moved before either answer, so the value read or written is the same; with the
//! fallback off, both end the transfer as CiA 301 says (the abort; a client abort with
//! 0504 0001h).
//!
//! Frames on the client's receive COB-ID that are not 8 bytes long, remote frames, and
//! initiate responses naming another object than the transfer's (a late answer to an earlier,
//! timed-out transfer) are ignored. Any other frame that is not the answer expected at that
//! point aborts the transfer.

use super::super::crc::crc16_ccitt;
use super::super::frame::{Frame, Micros, NodeId};
use super::super::od::AbortCode;

/// Default time the client waits for each answer of the server: 1 s (drives that write to
/// flash while answering need hundreds of milliseconds; 20 ms is known to fail on real drives).
pub const DEFAULT_TIMEOUT: Micros = 1_000_000;

/// Largest block size of a block transfer (segments per block), and the client's default.
pub const MAX_BLOCK_SIZE: u8 = 127;

/// Block transfers acknowledged with no progress this many times in a row are aborted with
/// [`AbortCode::GENERAL_ERROR`]: a bus that always loses the same segment would otherwise
/// keep a transfer alive for ever, each block answered within the timeout.
pub const MAX_STALLED_BLOCKS: u8 = 8;

/// How a transfer moves its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Mode {
    /// Expedited when the value fits in 4 bytes, segmented otherwise (the server decides for
    /// an upload).
    #[default]
    Normal,
    /// Always segmented, even for a download of up to 4 bytes.
    Segmented,
    /// Block transfer, with CRC when the server supports it.
    Block,
}

/// The direction of a transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Server to client (a read).
    Upload,
    /// Client to server (a write).
    Download,
}

/// Why a transfer failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SdoError {
    /// The server sent an abort with this code.
    Server(AbortCode),
    /// This client aborted the transfer (and sent the abort frame) with this code:
    /// [`AbortCode::TIMEOUT`], [`AbortCode::TOGGLE_BIT`], [`AbortCode::CRC_ERROR`], ... or the
    /// code given to [`SdoClient::abort`].
    Client(AbortCode),
}

impl SdoError {
    /// The abort code, whoever sent it.
    pub const fn code(self) -> AbortCode {
        match self {
            SdoError::Server(c) | SdoError::Client(c) => c,
        }
    }

    /// Whether the server did not answer in time.
    pub const fn is_timeout(self) -> bool {
        matches!(self, SdoError::Client(AbortCode::TIMEOUT))
    }
}

impl core::fmt::Display for SdoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SdoError::Server(c) => write!(f, "aborted by the server: {c}"),
            SdoError::Client(c) => write!(f, "aborted by the client: {c}"),
        }
    }
}

/// A failed transfer with what it was about, for messages: `node 5, upload of 1008h sub 0:
/// aborted by the client: 0x05040000 (SDO protocol timed out)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TransferError {
    /// The server's node id.
    pub node: u8,
    /// Upload or download.
    pub direction: Direction,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// What went wrong.
    pub error: SdoError,
}

impl core::fmt::Display for TransferError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let dir = match self.direction {
            Direction::Upload => "upload of",
            Direction::Download => "download to",
        };
        write!(f, "node {}, {dir} {:04X}h sub {}: {}", self.node, self.index, self.sub, self.error)
    }
}

/// The end of a transfer: the caller's buffer back, and the outcome.
#[derive(Debug)]
pub struct Done<B> {
    /// The server's node id.
    pub node: u8,
    /// Upload or download.
    pub direction: Direction,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The buffer given to [`SdoClient::upload`] or [`SdoClient::download`].
    pub buf: B,
    /// The number of bytes moved (an upload's value is `buf.as_ref()[..n]`), or why not.
    pub result: Result<usize, SdoError>,
}

impl<B> Done<B> {
    /// The failure with its node and object, if the transfer failed.
    pub fn error(&self) -> Option<TransferError> {
        let error = *self.result.as_ref().err()?;
        Some(TransferError { node: self.node, direction: self.direction, index: self.index, sub: self.sub, error })
    }
}

/// Why a transfer could not start; the buffer comes back in [`Rejected::buf`].
#[derive(Debug)]
pub struct Rejected<B> {
    /// The buffer that was given.
    pub buf: B,
    /// The reason.
    pub reason: Reject,
}

/// The reason a transfer could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reject {
    /// A transfer is already running on this channel.
    Busy,
    /// The data is longer than an SDO size indication can say (4 GiB).
    TooLong,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    /// Waiting for the initiate download response (0x60).
    DownInit {
        expedited: bool,
    },
    /// A segment ending at `end` was sent with toggle `toggle`; waiting for its response.
    DownSeg {
        toggle: bool,
        end: usize,
    },
    /// Waiting for the block download initiate response.
    BlockDownInit,
    /// The block starting at byte `start` is to be sent by the next poll, `blksize` segments.
    BlockDownSend {
        start: usize,
        blksize: u8,
    },
    /// `sent` segments from `start` were sent; waiting for the acknowledgement.
    BlockDownAck {
        start: usize,
        sent: u8,
    },
    /// The end request was sent; waiting for the end response.
    BlockDownEnd,
    /// Waiting for the initiate upload response.
    UpInit,
    /// A segment was requested with toggle `toggle`; `pos` bytes received so far.
    UpSeg {
        toggle: bool,
        pos: usize,
    },
    /// Waiting for the block upload initiate response.
    BlockUpInit,
    /// Receiving a block: `pos` bytes (7 per segment) in order so far, `seq` the last
    /// in-order sequence number of the current block.
    BlockUpData {
        pos: usize,
        seq: u8,
    },
    /// The last segment arrived at `pos` bytes; waiting for the end request.
    BlockUpEnd {
        pos: usize,
    },
}

/// Frames waiting for [`SdoClient::poll`]: at most an abort of the transfer that ended and the
/// first request of the next one, or the end response of a block upload and the next request.
#[derive(Clone, Copy, Debug)]
struct Queue {
    items: [[u8; 8]; 3],
    len: u8,
}

impl Queue {
    const fn new() -> Self {
        Self { items: [[0; 8]; 3], len: 0 }
    }

    fn push(&mut self, d: [u8; 8]) {
        // Three slots are enough for any sequence of calls between two polls (an ended
        // transfer's last frame, the next transfer's initiate, and its abort); if a caller
        // piles up more, the oldest frame is dropped rather than anything panicking.
        if usize::from(self.len) == self.items.len() {
            self.items.copy_within(1.., 0);
            self.len -= 1;
        }
        self.items[usize::from(self.len)] = d;
        self.len += 1;
    }
}

/// The client side of one SDO channel to one server. `B` is the caller's buffer type.
///
/// See the [module documentation](self) for the protocol it runs and the
/// [`master`](crate::master) module for an example.
#[derive(Debug)]
pub struct SdoClient<B> {
    node: u8,
    tx: u16,
    rx: u16,
    timeout: Micros,
    blksize: u8,
    pst: u8,
    /// Block transfers fall back to normal ones with a server that has none.
    fallback: bool,
    state: State,
    direction: Direction,
    index: u16,
    sub: u8,
    /// An upload's size indication, when the server gave one.
    size: Option<usize>,
    /// The server handles CRCs in this block transfer.
    crc: bool,
    buf: Option<B>,
    deadline: Micros,
    out: Queue,
    /// Frames of the running transfer in `out`, not sent yet, and whether any was sent.
    unsent: u8,
    on_bus: bool,
    /// Blocks in a row acknowledged with no segment taken.
    stalls: u8,
    /// The last block upload segment taken, to recognise it if CAN delivers it twice.
    last_seg: [u8; 8],
}

fn mux_of(d: &[u8; 8]) -> (u16, u8) {
    (u16::from_le_bytes([d[1], d[2]]), d[3])
}

fn request(cmd: u8, index: u16, sub: u8, tail: [u8; 4]) -> [u8; 8] {
    let i = index.to_le_bytes();
    [cmd, i[0], i[1], sub, tail[0], tail[1], tail[2], tail[3]]
}

impl<B: AsRef<[u8]> + AsMut<[u8]>> SdoClient<B> {
    /// A client of the default SDO channel of `node` (requests on 600h + id, responses on
    /// 580h + id), with the default timeout and block size.
    pub const fn new(node: NodeId) -> Self {
        let id = node.get() as u16;
        Self::with_cob_ids(node, 0x600 + id, 0x580 + id)
    }

    /// A client of another SDO channel: requests sent on `tx`, responses received on `rx`
    /// (the server's 1200h..127Fh sub 1 and sub 2; identifiers are cut to 11 bits).
    pub const fn with_cob_ids(node: NodeId, tx: u16, rx: u16) -> Self {
        Self {
            node: node.get(),
            tx: tx & 0x7FF,
            rx: rx & 0x7FF,
            timeout: DEFAULT_TIMEOUT,
            blksize: MAX_BLOCK_SIZE,
            pst: 0,
            fallback: true,
            state: State::Idle,
            direction: Direction::Upload,
            index: 0,
            sub: 0,
            size: None,
            crc: false,
            buf: None,
            deadline: 0,
            out: Queue::new(),
            unsent: 0,
            on_bus: false,
            stalls: 0,
            last_seg: [0; 8],
        }
    }

    /// The server's node id.
    pub const fn node(&self) -> u8 {
        self.node
    }

    /// The COB-IDs: requests sent, responses received.
    pub const fn cob_ids(&self) -> (u16, u16) {
        (self.tx, self.rx)
    }

    /// Sets how long the client waits for each answer of the server (0 waits forever). It
    /// applies from the next frame sent or received on, so a caller with per-call timeouts
    /// sets it before starting each transfer.
    pub fn set_timeout(&mut self, timeout: Micros) {
        self.timeout = timeout;
    }

    /// The timeout in force.
    pub const fn timeout(&self) -> Micros {
        self.timeout
    }

    /// Sets the number of segments per block the client asks for in block uploads (clamped
    /// to 1..=127; default 127).
    pub fn set_block_size(&mut self, blksize: u8) {
        self.blksize = blksize.clamp(1, MAX_BLOCK_SIZE);
    }

    /// Sets the protocol switch threshold of block uploads: a server may answer a block upload
    /// of at most this many bytes with a normal (expedited or segmented) upload. 0 (the
    /// default) forbids the switch.
    pub fn set_protocol_switch_threshold(&mut self, bytes: u8) {
        self.pst = bytes;
    }

    /// Sets whether a block transfer falls back to a normal one with a server that does not do
    /// block transfers (default on; see the [module documentation](self)): the block initiate
    /// request refused with 0504 0001h starts the transfer again as a normal one, and a
    /// normal initiate upload response indicating the size, to a block upload, continues as a
    /// normal upload. Off,
    /// the refusal ends the transfer with [`SdoError::Server`] and a normal answer above the
    /// protocol switch threshold with [`SdoError::Client`] 0504 0001h.
    pub fn set_block_fallback(&mut self, on: bool) {
        self.fallback = on;
    }

    /// Whether block transfers fall back to normal ones ([`set_block_fallback`](Self::set_block_fallback)).
    pub const fn block_fallback(&self) -> bool {
        self.fallback
    }

    /// Whether no transfer is running (a new one may start).
    pub fn is_idle(&self) -> bool {
        self.state == State::Idle
    }

    /// The time at which [`poll`](Self::poll) next has something to do: `Some(0)` when frames
    /// are waiting to be sent, the timeout of the running transfer, `None` when idle.
    pub fn deadline(&self) -> Option<Micros> {
        if self.out.len > 0 || matches!(self.state, State::BlockDownSend { .. }) {
            return Some(0);
        }
        match self.state {
            State::Idle => None,
            _ if self.timeout == 0 => None,
            _ => Some(self.deadline),
        }
    }

    fn start(&mut self, direction: Direction, index: u16, sub: u8, buf: B, now: Micros) -> Result<(), Rejected<B>> {
        if self.state != State::Idle {
            return Err(Rejected { buf, reason: Reject::Busy });
        }
        if u32::try_from(buf.as_ref().len()).is_err() {
            return Err(Rejected { buf, reason: Reject::TooLong });
        }
        self.direction = direction;
        self.index = index;
        self.sub = sub;
        self.size = None;
        self.crc = false;
        self.buf = Some(buf);
        self.last_seg = [0; 8];
        self.unsent = 0;
        self.on_bus = false;
        self.stalls = 0;
        self.deadline = now.saturating_add(self.timeout);
        Ok(())
    }

    /// Starts reading `index`/`sub` into `buf`; the value must fit in `buf` (its whole
    /// length is the capacity). Rejected when a transfer is running.
    pub fn upload(&mut self, index: u16, sub: u8, buf: B, mode: Mode, now: Micros) -> Result<(), Rejected<B>> {
        self.start(Direction::Upload, index, sub, buf, now)?;
        if mode == Mode::Block {
            // cc = 1: the client checks a CRC whenever the server sends one.
            self.push(request(0xA4, index, sub, [self.blksize, self.pst, 0, 0]));
            self.state = State::BlockUpInit;
        } else {
            self.push(request(0x40, index, sub, [0; 4]));
            self.state = State::UpInit;
        }
        Ok(())
    }

    /// Starts writing all of `data` to `index`/`sub`. Rejected when a transfer is running or
    /// the data is longer than 4 GiB.
    pub fn download(&mut self, index: u16, sub: u8, data: B, mode: Mode, now: Micros) -> Result<(), Rejected<B>> {
        self.start(Direction::Download, index, sub, data, now)?;
        self.initiate_download(mode);
        Ok(())
    }

    /// Queues the initiate request of a download of the whole buffer.
    fn initiate_download(&mut self, mode: Mode) {
        let (index, sub) = (self.index, self.sub);
        let len = self.len();
        let size = (len as u32).to_le_bytes();
        match mode {
            Mode::Normal if (1..=4).contains(&len) => {
                let mut tail = [0u8; 4];
                tail[..len].copy_from_slice(self.data());
                self.push(request(0x23 | (((4 - len) as u8) << 2), index, sub, tail));
                self.state = State::DownInit { expedited: true };
            }
            Mode::Normal | Mode::Segmented => {
                self.push(request(0x21, index, sub, size));
                self.state = State::DownInit { expedited: false };
            }
            Mode::Block => {
                self.push(request(0xC6, index, sub, size));
                self.state = State::BlockDownInit;
            }
        }
    }

    /// Ends the running transfer with `code`: the abort frame goes out with the next poll and
    /// the transfer ends with [`SdoError::Client`]. `None` when no transfer is running.
    pub fn abort(&mut self, code: AbortCode) -> Option<Done<B>> {
        if self.state == State::Idle {
            return None;
        }
        Some(self.fail(code))
    }

    /// Queues a frame of the running transfer.
    fn push(&mut self, d: [u8; 8]) {
        self.out.push(d);
        self.unsent = self.unsent.saturating_add(1).min(self.out.len);
    }

    fn data(&self) -> &[u8] {
        self.buf.as_ref().map_or(&[], |b| b.as_ref())
    }

    fn len(&self) -> usize {
        self.data().len()
    }

    fn finish(&mut self, result: Result<usize, SdoError>) -> Done<B> {
        self.state = State::Idle;
        // Frames queued from here on (an end response, an abort) belong to no transfer.
        self.unsent = 0;
        let buf = self.buf.take().expect("a running transfer holds its buffer");
        Done { node: self.node, direction: self.direction, index: self.index, sub: self.sub, buf, result }
    }

    fn fail(&mut self, code: AbortCode) -> Done<B> {
        // The transfer's frames not sent yet are withdrawn: a segment queued before the answer
        // that made the client give up would otherwise still go out, and could complete on the
        // server a download this client reports as failed.
        self.out.len -= self.unsent;
        if self.on_bus {
            self.push(request(0x80, self.index, self.sub, code.0.to_le_bytes()));
        }
        // Else nothing of this transfer reached the bus: no abort either.
        self.finish(Err(SdoError::Client(code)))
    }

    /// Takes a received frame. Frames on other COB-IDs are ignored, so a caller may pass every
    /// frame of the bus. Returns the end of the transfer when this frame ends it.
    pub fn on_frame(&mut self, frame: &Frame, now: Micros) -> Option<Done<B>> {
        // Before the request went out, no answer can be this transfer's.
        if frame.id() != self.rx || frame.is_rtr() || frame.len() != 8 || self.state == State::Idle || !self.on_bus {
            return None;
        }
        let d = *frame.raw();
        // In a block upload's data phase 80h is a segment number 0 with the last-segment bit:
        // no valid segment has it, so it is the abort there too.
        if d[0] == 0x80 {
            let code = AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]]));
            let block_init = matches!(self.state, State::BlockUpInit | State::BlockDownInit);
            if block_init && self.fallback && code == AbortCode::INVALID_COMMAND && mux_of(&d) == (self.index, self.sub)
            {
                // The server has no block transfer: the same transfer as a normal one.
                self.deadline = now.saturating_add(self.timeout);
                if self.state == State::BlockUpInit {
                    self.push(request(0x40, self.index, self.sub, [0; 4]));
                    self.state = State::UpInit;
                } else {
                    self.initiate_download(Mode::Normal);
                }
                return None;
            }
            return Some(self.finish(Err(SdoError::Server(code))));
        }
        let initiate =
            matches!(self.state, State::DownInit { .. } | State::BlockDownInit | State::UpInit | State::BlockUpInit);
        if initiate && mux_of(&d) != (self.index, self.sub) {
            // A late answer to an earlier request: not this transfer's.
            return None;
        }
        self.deadline = now.saturating_add(self.timeout);
        match self.step(&d) {
            Ok(done) => done,
            Err(code) => Some(self.fail(code)),
        }
    }

    /// One frame of the server in the current state: `Ok(Some)` when it completes the
    /// transfer, `Err(code)` when the client must abort.
    fn step(&mut self, d: &[u8; 8]) -> Result<Option<Done<B>>, AbortCode> {
        let cmd = d[0];
        match self.state {
            State::Idle => Ok(None),
            State::DownInit { expedited } => {
                if cmd != 0x60 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                if expedited {
                    let n = self.len();
                    return Ok(Some(self.finish(Ok(n))));
                }
                self.send_segment(0, false);
                Ok(None)
            }
            State::DownSeg { toggle, end } => {
                if cmd & 0xEF != 0x20 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                if (cmd & 0x10 != 0) != toggle {
                    return Err(AbortCode::TOGGLE_BIT);
                }
                if end == self.len() {
                    return Ok(Some(self.finish(Ok(end))));
                }
                self.send_segment(end, !toggle);
                Ok(None)
            }
            State::BlockDownInit => {
                if cmd & 0xFB != 0xA0 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                let blksize = d[4];
                if blksize == 0 || blksize > MAX_BLOCK_SIZE {
                    return Err(AbortCode::INVALID_BLOCK_SIZE);
                }
                self.crc = cmd & 0x04 != 0;
                self.state = State::BlockDownSend { start: 0, blksize };
                Ok(None)
            }
            State::BlockDownSend { .. } => Err(AbortCode::INVALID_COMMAND),
            State::BlockDownAck { start, sent } => {
                if cmd != 0xA2 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                let (ackseq, blksize) = (d[1], d[2]);
                if ackseq > sent {
                    return Err(AbortCode::INVALID_SEQUENCE);
                }
                self.stalled(ackseq == 0)?;
                let len = self.len();
                let acked = start + 7 * usize::from(ackseq);
                let segments = len.div_ceil(7).max(1);
                if acked >= 7 * segments {
                    // Every segment arrived: the end request, with the bytes of the last
                    // segment that carried no data and the CRC if the server takes one.
                    let unused = (7 * segments - len) as u8;
                    let crc = if self.crc { crc16_ccitt(0, self.data()) } else { 0 }.to_le_bytes();
                    self.push([0xC1 | (unused << 2), crc[0], crc[1], 0, 0, 0, 0, 0]);
                    self.state = State::BlockDownEnd;
                    return Ok(None);
                }
                if blksize == 0 || blksize > MAX_BLOCK_SIZE {
                    return Err(AbortCode::INVALID_BLOCK_SIZE);
                }
                self.state = State::BlockDownSend { start: acked, blksize };
                Ok(None)
            }
            State::BlockDownEnd => {
                if cmd != 0xA1 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                let n = self.len();
                Ok(Some(self.finish(Ok(n))))
            }
            State::UpInit => self.initiate_upload_response(d),
            State::UpSeg { toggle, pos } => {
                if cmd & 0xE0 != 0 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                if (cmd & 0x10 != 0) != toggle {
                    return Err(AbortCode::TOGGLE_BIT);
                }
                let n = 7 - usize::from((cmd >> 1) & 0x07);
                let end = pos + n;
                if self.size.is_some_and(|s| end > s) {
                    return Err(AbortCode::LENGTH_MISMATCH);
                }
                self.store(pos, &d[1..1 + n])?;
                if cmd & 0x01 != 0 {
                    if self.size.is_some_and(|s| s != end) {
                        return Err(AbortCode::LENGTH_MISMATCH);
                    }
                    return Ok(Some(self.finish(Ok(end))));
                }
                self.push([0x60 | if toggle { 0 } else { 0x10 }, 0, 0, 0, 0, 0, 0, 0]);
                self.state = State::UpSeg { toggle: !toggle, pos: end };
                Ok(None)
            }
            State::BlockUpInit => {
                if cmd >> 5 == 2 && self.pst != 0 {
                    // Protocol switch: the server answered with a normal upload.
                    return self.initiate_upload_response(d);
                }
                if cmd >> 5 == 2 && self.fallback && cmd & 0x01 != 0 {
                    // A server without block upload answered with a normal upload. Only one
                    // that indicates its size (s = 1, as such servers do): it is two bits away
                    // from every block answer (ss = 0), so a block answer with one bit
                    // garbled is not taken for it.
                    return self.initiate_upload_response(d);
                }
                if cmd & 0xF9 != 0xC0 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                self.crc = cmd & 0x04 != 0;
                if cmd & 0x02 != 0 {
                    self.indicated(u32::from_le_bytes([d[4], d[5], d[6], d[7]]))?;
                }
                self.push([0xA3, 0, 0, 0, 0, 0, 0, 0]);
                self.state = State::BlockUpData { pos: 0, seq: 0 };
                Ok(None)
            }
            State::BlockUpData { pos, seq } => {
                let s = cmd & 0x7F;
                let last = cmd & 0x80 != 0;
                if s == 0 || s > self.blksize {
                    return Err(AbortCode::INVALID_SEQUENCE);
                }
                let (mut pos, mut seq) = (pos, seq);
                let in_order = s == seq + 1;
                if !in_order && *d == self.last_seg {
                    // The segment taken last, delivered again (a CAN transmitter repeats a
                    // frame whose acknowledgement it missed): acknowledging it again would
                    // make the server resend a block.
                    return Ok(None);
                }
                if in_order {
                    self.last_seg = *d;
                    // Bytes past the buffer are padding of the last segment or an overflow;
                    // which one the end request tells, so only a certain overflow aborts here.
                    let cap = self.capacity();
                    if pos >= cap.saturating_add(7) || self.size.is_some_and(|sz| pos >= sz.max(1)) {
                        return Err(AbortCode::OUT_OF_MEMORY);
                    }
                    let n = 7.min(cap.saturating_sub(pos));
                    if let Some(b) = self.buf.as_mut() {
                        b.as_mut()[pos..pos + n].copy_from_slice(&d[1..1 + n]);
                    }
                    pos += 7;
                    seq = s;
                }
                if last || s == self.blksize {
                    self.stalled(seq == 0)?;
                    self.push([0xA2, seq, self.blksize, 0, 0, 0, 0, 0]);
                    self.state =
                        if last && in_order { State::BlockUpEnd { pos } } else { State::BlockUpData { pos, seq: 0 } };
                } else {
                    self.state = State::BlockUpData { pos, seq };
                }
                Ok(None)
            }
            State::BlockUpEnd { pos } => {
                if *d == self.last_seg {
                    return Ok(None);
                }
                if cmd & 0xE3 != 0xC1 {
                    return Err(AbortCode::INVALID_COMMAND);
                }
                let unused = usize::from((cmd >> 2) & 0x07);
                let len = pos.saturating_sub(unused);
                if len > self.capacity() {
                    return Err(AbortCode::OUT_OF_MEMORY);
                }
                if self.size.is_some_and(|s| s != len) {
                    return Err(AbortCode::LENGTH_MISMATCH);
                }
                if self.crc && crc16_ccitt(0, &self.data()[..len]) != u16::from_le_bytes([d[1], d[2]]) {
                    return Err(AbortCode::CRC_ERROR);
                }
                self.push([0xA1, 0, 0, 0, 0, 0, 0, 0]);
                Ok(Some(self.finish(Ok(len))))
            }
        }
    }

    /// Counts a block that moved nothing, and aborts after [`MAX_STALLED_BLOCKS`] in a row.
    fn stalled(&mut self, stalled: bool) -> Result<(), AbortCode> {
        self.stalls = if stalled { self.stalls + 1 } else { 0 };
        if self.stalls >= MAX_STALLED_BLOCKS {
            return Err(AbortCode::GENERAL_ERROR);
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.len()
    }

    /// Checks an upload's size indication against the buffer and keeps it.
    fn indicated(&mut self, size: u32) -> Result<(), AbortCode> {
        let size = size as usize;
        if size > self.capacity() {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        self.size = Some(size);
        Ok(())
    }

    /// Copies received bytes to `pos` of the buffer, or aborts when they do not fit.
    fn store(&mut self, pos: usize, bytes: &[u8]) -> Result<(), AbortCode> {
        let end = pos + bytes.len();
        if end > self.capacity() {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        if let Some(b) = self.buf.as_mut() {
            b.as_mut()[pos..end].copy_from_slice(bytes);
        }
        Ok(())
    }

    fn initiate_upload_response(&mut self, d: &[u8; 8]) -> Result<Option<Done<B>>, AbortCode> {
        let cmd = d[0];
        if cmd & 0xF0 != 0x40 {
            return Err(AbortCode::INVALID_COMMAND);
        }
        let sized = cmd & 0x01 != 0;
        if cmd & 0x02 != 0 {
            // Expedited: the value is in the frame (4 bytes when the size is not indicated).
            let n = if sized { 4 - usize::from((cmd >> 2) & 0x03) } else { 4 };
            self.store(0, &d[4..4 + n])?;
            return Ok(Some(self.finish(Ok(n))));
        }
        if sized {
            self.indicated(u32::from_le_bytes([d[4], d[5], d[6], d[7]]))?;
        }
        self.push([0x60, 0, 0, 0, 0, 0, 0, 0]);
        self.state = State::UpSeg { toggle: false, pos: 0 };
        Ok(None)
    }

    /// Queues the download segment starting at `pos`.
    fn send_segment(&mut self, pos: usize, toggle: bool) {
        let len = self.len();
        let n = (len - pos).min(7);
        let end = pos + n;
        let mut seg = [0u8; 8];
        seg[0] = (if toggle { 0x10 } else { 0 }) | (((7 - n) as u8) << 1) | u8::from(end == len);
        seg[1..1 + n].copy_from_slice(&self.data()[pos..end]);
        self.push(seg);
        self.state = State::DownSeg { toggle, end };
    }

    /// Hands the frames to send to `emit` (a block download's whole block at once, up to 127
    /// frames) and fires the timeout. Returns the end of the transfer when it timed out.
    pub fn poll(&mut self, now: Micros, emit: &mut impl FnMut(Frame)) -> Option<Done<B>> {
        let queued = self.out.len;
        for d in &self.out.items[..usize::from(queued)] {
            emit(Frame::full(self.tx, *d));
        }
        self.out.len = 0;
        if self.unsent > 0 {
            self.on_bus = true;
            self.unsent = 0;
        }
        if let State::BlockDownSend { start, blksize } = self.state {
            let data = self.buf.as_ref().map_or(&[][..], |b| b.as_ref());
            let len = data.len();
            let mut pos = start;
            let mut sent = 0u8;
            loop {
                let n = (len - pos).min(7);
                sent += 1;
                let last = pos + n >= len;
                let mut seg = [0u8; 8];
                seg[0] = sent | if last { 0x80 } else { 0 };
                seg[1..1 + n].copy_from_slice(&data[pos..pos + n]);
                emit(Frame::full(self.tx, seg));
                pos += n;
                if last || sent == blksize {
                    break;
                }
            }
            self.state = State::BlockDownAck { start, sent };
            self.deadline = now.saturating_add(self.timeout);
            return None;
        }
        if queued > 0 && self.state != State::Idle {
            self.deadline = now.saturating_add(self.timeout);
            return None;
        }
        if self.state != State::Idle && self.timeout != 0 && now >= self.deadline {
            let done = self.fail(AbortCode::TIMEOUT);
            for d in &self.out.items[..usize::from(self.out.len)] {
                emit(Frame::full(self.tx, *d));
            }
            self.out.len = 0;
            return Some(done);
        }
        None
    }
}
