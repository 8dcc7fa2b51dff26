//! The SDO server (CiA 301 §7.2.4): expedited, segmented and block transfers.
//!
//! The server is a state machine over 8-byte request payloads. It reaches the dictionary only
//! through [`ObjectAccess`], which the device implements with access-right checks, the
//! communication objects' side effects and the application's veto. Responses are queued and
//! handed out by [`SdoServer::poll`]; a block upload's segments are produced there too, at
//! most one block (127 frames) per call.

use crate::crc::crc16_ccitt;
use crate::frame::Micros;
use crate::od::{AbortCode, Access, EntryInfo};
use crate::sdo_block::SDO_BLOCK;

/// Default SDO timeout: a transfer idle for this long is aborted with 0x0504_0000.
pub const DEFAULT_TIMEOUT: Micros = 1_000_000;

/// Largest block size (segments per block) of a block transfer.
const MAX_BLKSIZE: u8 = 127;

/// What the SDO server needs of an entry: whether a client may read and write it and how
/// long its value is, in one word (so that a lookup's answer, `Result<SdoEntry, AbortCode>`,
/// travels in two registers): the length in bytes in bits 0..24 (longer values count as
/// 16 MiB − 1, past any SDO buffer), whether it varies in bit 24, readable and writable in
/// bits 25 and 26.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoEntry(u32);

impl SdoEntry {
    /// An entry of `access` whose value is `len` bytes long (`variable`: at most `len`).
    pub const fn new(access: Access, variable: bool, len: usize) -> Self {
        let len = if len > 0xFF_FFFF { 0xFF_FFFF } else { len as u32 };
        SdoEntry(len | (variable as u32) << 24 | (access.readable() as u32) << 25 | (access.writable() as u32) << 26)
    }

    /// Whether a client may read the entry ([`Access::readable`]).
    pub const fn readable(self) -> bool {
        self.0 & 1 << 25 != 0
    }

    /// Whether a client may write the entry ([`Access::writable`]).
    pub const fn writable(self) -> bool {
        self.0 & 1 << 26 != 0
    }

    /// Whether the value's length varies (strings, DOMAIN): [`byte_len`](Self::byte_len) is then its
    /// capacity.
    pub const fn variable(self) -> bool {
        self.0 & 1 << 24 != 0
    }

    /// The value's length in bytes ([`EntryInfo::byte_len`]).
    pub const fn byte_len(self) -> usize {
        (self.0 & 0xFF_FFFF) as usize
    }
}

impl From<&EntryInfo> for SdoEntry {
    fn from(e: &EntryInfo) -> Self {
        SdoEntry::new(e.access, e.data_type.is_variable_length(), e.byte_len())
    }
}

/// How the SDO server reaches the dictionary.
pub trait ObjectAccess {
    /// Access and length of an entry (`NO_OBJECT` / `NO_SUB_INDEX` when absent).
    fn info(&self, index: u16, sub: u8) -> Result<SdoEntry, AbortCode>;
    /// Reads the value into `buf`, returning its length.
    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode>;
    /// Writes a value from the bus (the application may veto it).
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum UpPhase {
    /// Initiated; waiting for the client's "start upload".
    WaitStart,
    /// A block is to be sent by the next poll.
    Sending,
    /// A block was sent (`sent` segments, the last one carrying `c` if `last`); waiting for
    /// the client's acknowledgement.
    WaitAck { sent: u8, last: bool },
    /// The end message was sent; waiting for the client's end response.
    WaitEnd,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    /// Segmented download: `pos` bytes received so far.
    Download {
        index: u16,
        sub: u8,
        toggle: bool,
        size: Option<usize>,
        pos: usize,
    },
    /// Segmented upload of `len` bytes held in the buffer, `pos` sent so far.
    Upload {
        index: u16,
        sub: u8,
        toggle: bool,
        len: usize,
        pos: usize,
    },
    /// Block download. `seq` is the last in-order sequence number of the current block, `lost`
    /// is set once a segment went missing, `last` once the segment with `c` was accepted.
    BlockDownload {
        index: u16,
        sub: u8,
        crc: bool,
        size: Option<usize>,
        pos: usize,
        blksize: u8,
        seq: u8,
        lost: bool,
        last: bool,
    },
    /// Block upload of `len` bytes; `acked` bytes confirmed by the client.
    BlockUpload {
        index: u16,
        sub: u8,
        crc: bool,
        len: usize,
        acked: usize,
        blksize: u8,
        phase: UpPhase,
    },
}

/// An SDO server with a transfer buffer of `N` bytes (the largest value it can move).
pub struct SdoServer<const N: usize> {
    state: State,
    buf: [u8; N],
    out: Option<[u8; 8]>,
    last: Micros,
    timeout: Micros,
}

impl<const N: usize> Default for SdoServer<N> {
    fn default() -> Self {
        Self::new()
    }
}

fn mux(d: &[u8; 8]) -> (u16, u8) {
    (u16::from_le_bytes([d[1], d[2]]), d[3])
}

fn frame(cmd: u8, index: u16, sub: u8, tail: [u8; 4]) -> [u8; 8] {
    let i = index.to_le_bytes();
    [cmd, i[0], i[1], sub, tail[0], tail[1], tail[2], tail[3]]
}

/// The 8-byte payload of an abort transfer message.
pub fn abort_frame(index: u16, sub: u8, code: AbortCode) -> [u8; 8] {
    frame(0x80, index, sub, code.0.to_le_bytes())
}

impl<const N: usize> SdoServer<N> {
    /// An idle server with the default timeout.
    pub const fn new() -> Self {
        Self { state: State::Idle, buf: [0; N], out: None, last: 0, timeout: DEFAULT_TIMEOUT }
    }

    /// Sets the timeout after which an idle transfer is aborted (0 disables it).
    pub fn set_timeout(&mut self, timeout: Micros) {
        self.timeout = timeout;
    }

    /// Drops any transfer in progress and any queued response, without sending anything.
    pub fn reset(&mut self) {
        self.state = State::Idle;
        self.out = None;
    }

    /// Whether a transfer is in progress.
    pub fn busy(&self) -> bool {
        self.state != State::Idle
    }

    fn abort(&mut self, index: u16, sub: u8, code: AbortCode) {
        self.out = Some(abort_frame(index, sub, code));
        self.state = State::Idle;
    }

    /// Queues a response. Out of line on a microcontroller: a dozen callers.
    #[cfg_attr(target_os = "none", inline(never))]
    fn respond(&mut self, d: [u8; 8]) {
        self.out = Some(d);
    }

    /// Handles one request payload (the data of a frame on the server's receive COB-ID).
    pub fn request(&mut self, d: &[u8; 8], now: Micros, acc: &mut impl ObjectAccess) {
        self.last = now;
        if SDO_BLOCK && let State::BlockDownload { .. } = self.state {
            if let Err((index, sub, code)) = self.block_download_frame(d, acc) {
                self.abort(index, sub, code);
            }
            return;
        }
        let cmd = d[0];
        let result = match cmd >> 5 {
            0 => self.download_segment(d, acc),
            1 => self.initiate_download(d, acc),
            2 => self.initiate_upload(d, acc),
            3 => self.upload_segment(d),
            4 => {
                // Abort from the client: drop the transfer silently.
                self.state = State::Idle;
                Ok(())
            }
            // Block transfers, when built in (cargo feature `sdo-block`); without, their
            // command specifiers are not valid ones.
            5 if SDO_BLOCK => self.block_upload(d, acc),
            6 if SDO_BLOCK => self.initiate_block_download(d, acc),
            _ => {
                let (i, s) = mux(d);
                Err((i, s, AbortCode::INVALID_COMMAND))
            }
        };
        if let Err((index, sub, code)) = result {
            self.abort(index, sub, code);
        }
    }

    fn current_mux(&self) -> (u16, u8) {
        match self.state {
            State::Idle => (0, 0),
            State::Download { index, sub, .. }
            | State::Upload { index, sub, .. }
            | State::BlockDownload { index, sub, .. }
            | State::BlockUpload { index, sub, .. } => (index, sub),
        }
    }

    /// Length and size checks shared by segmented and block downloads.
    fn check_size(info: SdoEntry, size: usize) -> Result<(), AbortCode> {
        let cap = info.byte_len();
        if info.variable() {
            if size > cap {
                return Err(AbortCode::LENGTH_TOO_HIGH);
            }
        } else if size > cap {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        } else if size < cap {
            return Err(AbortCode::LENGTH_TOO_LOW);
        }
        if size > N {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        Ok(())
    }

    fn writable(acc: &impl ObjectAccess, index: u16, sub: u8) -> Result<SdoEntry, AbortCode> {
        let info = acc.info(index, sub)?;
        if !info.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        Ok(info)
    }

    fn initiate_download(&mut self, d: &[u8; 8], acc: &mut impl ObjectAccess) -> Result<(), (u16, u8, AbortCode)> {
        let (index, sub) = mux(d);
        let cmd = d[0];
        let info = Self::writable(acc, index, sub).map_err(|c| (index, sub, c))?;
        let sized = cmd & 0x01 != 0;
        if cmd & 0x02 != 0 {
            let n = if sized {
                4 - usize::from((cmd >> 2) & 0x03)
            } else if info.variable() {
                4
            } else {
                info.byte_len().clamp(1, 4)
            };
            acc.write(index, sub, &d[4..4 + n]).map_err(|c| (index, sub, c))?;
            self.state = State::Idle;
        } else {
            let size = if sized {
                let s = u32::from_le_bytes([d[4], d[5], d[6], d[7]]) as usize;
                Self::check_size(info, s).map_err(|c| (index, sub, c))?;
                Some(s)
            } else {
                None
            };
            self.state = State::Download { index, sub, toggle: false, size, pos: 0 };
        }
        self.respond(frame(0x60, index, sub, [0; 4]));
        Ok(())
    }

    fn download_segment(&mut self, d: &[u8; 8], acc: &mut impl ObjectAccess) -> Result<(), (u16, u8, AbortCode)> {
        let State::Download { index, sub, toggle, size, pos } = self.state else {
            let (i, s) = self.current_mux();
            return Err((i, s, AbortCode::INVALID_COMMAND));
        };
        let cmd = d[0];
        let t = cmd & 0x10 != 0;
        if t != toggle {
            return Err((index, sub, AbortCode::TOGGLE_BIT));
        }
        let n = 7 - usize::from((cmd >> 1) & 0x07);
        let end = pos + n;
        if size.is_some_and(|s| end > s) {
            return Err((index, sub, AbortCode::LENGTH_MISMATCH));
        }
        if end > N {
            return Err((index, sub, AbortCode::OUT_OF_MEMORY));
        }
        self.buf[pos..end].copy_from_slice(&d[1..1 + n]);
        let reply = [0x20 | (cmd & 0x10), 0, 0, 0, 0, 0, 0, 0];
        if cmd & 0x01 != 0 {
            if size.is_some_and(|s| s != end) {
                return Err((index, sub, AbortCode::LENGTH_MISMATCH));
            }
            acc.write(index, sub, &self.buf[..end]).map_err(|c| (index, sub, c))?;
            self.state = State::Idle;
        } else {
            self.state = State::Download { index, sub, toggle: !toggle, size, pos: end };
        }
        self.respond(reply);
        Ok(())
    }

    /// Reads an entry for upload into the buffer, checking read access.
    fn load(&mut self, acc: &mut impl ObjectAccess, index: u16, sub: u8) -> Result<usize, (u16, u8, AbortCode)> {
        let info = acc.info(index, sub).map_err(|c| (index, sub, c))?;
        if !info.readable() {
            return Err((index, sub, AbortCode::WRITE_ONLY));
        }
        let len = acc.read(index, sub, &mut self.buf).map_err(|c| (index, sub, c))?;
        if len > N {
            return Err((index, sub, AbortCode::OUT_OF_MEMORY));
        }
        Ok(len)
    }

    /// Answers an initiate upload for `len` bytes in the buffer: expedited up to 4 bytes,
    /// segmented otherwise.
    fn start_upload(&mut self, index: u16, sub: u8, len: usize) {
        if (1..=4).contains(&len) {
            let mut tail = [0u8; 4];
            tail[..len].copy_from_slice(&self.buf[..len]);
            self.respond(frame(0x43 | (((4 - len) as u8) << 2), index, sub, tail));
            self.state = State::Idle;
        } else {
            self.respond(frame(0x41, index, sub, (len as u32).to_le_bytes()));
            self.state = State::Upload { index, sub, toggle: false, len, pos: 0 };
        }
    }

    fn initiate_upload(&mut self, d: &[u8; 8], acc: &mut impl ObjectAccess) -> Result<(), (u16, u8, AbortCode)> {
        let (index, sub) = mux(d);
        let len = self.load(acc, index, sub)?;
        self.start_upload(index, sub, len);
        Ok(())
    }

    fn upload_segment(&mut self, d: &[u8; 8]) -> Result<(), (u16, u8, AbortCode)> {
        let State::Upload { index, sub, toggle, len, pos } = self.state else {
            let (i, s) = self.current_mux();
            return Err((i, s, AbortCode::INVALID_COMMAND));
        };
        let t = d[0] & 0x10 != 0;
        if t != toggle {
            return Err((index, sub, AbortCode::TOGGLE_BIT));
        }
        let n = (len - pos).min(7);
        let end = pos + n;
        let last = end == len;
        let mut reply = [0u8; 8];
        reply[0] = (d[0] & 0x10) | (((7 - n) as u8) << 1) | u8::from(last);
        reply[1..1 + n].copy_from_slice(&self.buf[pos..end]);
        self.respond(reply);
        self.state = if last { State::Idle } else { State::Upload { index, sub, toggle: !toggle, len, pos: end } };
        Ok(())
    }

    fn blksize_for(pos: usize) -> u8 {
        let room = N.saturating_sub(pos).div_ceil(7);
        room.clamp(1, usize::from(MAX_BLKSIZE)) as u8
    }

    fn initiate_block_download(
        &mut self,
        d: &[u8; 8],
        acc: &mut impl ObjectAccess,
    ) -> Result<(), (u16, u8, AbortCode)> {
        let (index, sub) = mux(d);
        let cmd = d[0];
        if cmd & 0x01 != 0 {
            // An end request outside a block download.
            let (i, s) = self.current_mux();
            return Err((i, s, AbortCode::INVALID_COMMAND));
        }
        let info = Self::writable(acc, index, sub).map_err(|c| (index, sub, c))?;
        let size = if cmd & 0x02 != 0 {
            let s = u32::from_le_bytes([d[4], d[5], d[6], d[7]]) as usize;
            Self::check_size(info, s).map_err(|c| (index, sub, c))?;
            Some(s)
        } else {
            None
        };
        let blksize = Self::blksize_for(0);
        self.state = State::BlockDownload {
            index,
            sub,
            crc: cmd & 0x04 != 0,
            size,
            pos: 0,
            blksize,
            seq: 0,
            lost: false,
            last: false,
        };
        self.respond(frame(0xA4, index, sub, [blksize, 0, 0, 0]));
        Ok(())
    }

    /// A frame received during a block download: a segment, the end request once the last
    /// segment was acknowledged, or an abort.
    fn block_download_frame(&mut self, d: &[u8; 8], acc: &mut impl ObjectAccess) -> Result<(), (u16, u8, AbortCode)> {
        let State::BlockDownload { index, sub, crc, size, pos, blksize, seq, lost, last } = self.state else {
            return Ok(());
        };
        let cmd = d[0];
        if cmd == 0x80 {
            self.state = State::Idle;
            return Ok(());
        }
        if last {
            // Only the end request (or an abort) may follow the last segment.
            if cmd & 0xE3 != 0xC1 {
                return Err((index, sub, AbortCode::INVALID_COMMAND));
            }
            let unused = usize::from((cmd >> 2) & 0x07);
            let len = pos.saturating_sub(unused);
            if len > N {
                return Err((index, sub, AbortCode::OUT_OF_MEMORY));
            }
            if size.is_some_and(|s| s != len) {
                return Err((index, sub, AbortCode::LENGTH_MISMATCH));
            }
            if crc && crc16_ccitt(0, &self.buf[..len]) != u16::from_le_bytes([d[1], d[2]]) {
                return Err((index, sub, AbortCode::CRC_ERROR));
            }
            acc.write(index, sub, &self.buf[..len]).map_err(|c| (index, sub, c))?;
            self.state = State::Idle;
            self.respond([0xA1, 0, 0, 0, 0, 0, 0, 0]);
            return Ok(());
        }
        let s = cmd & 0x7F;
        let c = cmd & 0x80 != 0;
        if s == 0 || s > blksize {
            return Err((index, sub, AbortCode::INVALID_SEQUENCE));
        }
        let (mut pos, mut seq, mut lost, mut last) = (pos, seq, lost, last);
        if !lost && s == seq + 1 {
            if pos >= N {
                return Err((index, sub, AbortCode::OUT_OF_MEMORY));
            }
            if size.is_some_and(|sz| pos > 0 && pos >= sz) {
                return Err((index, sub, AbortCode::LENGTH_MISMATCH));
            }
            // The last segment may carry up to 6 padding bytes past the buffer's end; they are
            // dropped here and the end request says how many there were.
            let n = 7.min(N - pos);
            self.buf[pos..pos + n].copy_from_slice(&d[1..1 + n]);
            pos += 7;
            seq = s;
            last = c;
        } else if s != seq {
            lost = true;
        }
        let mut next = blksize;
        if c || s == blksize {
            next = Self::blksize_for(pos);
            self.respond([0xA2, seq, next, 0, 0, 0, 0, 0]);
            seq = 0;
            lost = false;
        }
        self.state = State::BlockDownload { index, sub, crc, size, pos, blksize: next, seq, lost, last };
        Ok(())
    }

    fn block_upload(&mut self, d: &[u8; 8], acc: &mut impl ObjectAccess) -> Result<(), (u16, u8, AbortCode)> {
        let cmd = d[0];
        match cmd & 0x03 {
            0 => {
                let (index, sub) = mux(d);
                let blksize = d[4];
                if blksize == 0 || blksize > MAX_BLKSIZE {
                    return Err((index, sub, AbortCode::INVALID_BLOCK_SIZE));
                }
                let len = self.load(acc, index, sub)?;
                let pst = usize::from(d[5]);
                if pst != 0 && len <= pst {
                    // Protocol switch: the client accepts a normal upload for small values.
                    self.start_upload(index, sub, len);
                    return Ok(());
                }
                self.state = State::BlockUpload {
                    index,
                    sub,
                    crc: cmd & 0x04 != 0,
                    len,
                    acked: 0,
                    blksize,
                    phase: UpPhase::WaitStart,
                };
                self.respond(frame(0xC6, index, sub, (len as u32).to_le_bytes()));
                Ok(())
            }
            3 => match self.state {
                State::BlockUpload { phase: UpPhase::WaitStart, index, sub, crc, len, acked, blksize } => {
                    self.state = State::BlockUpload { index, sub, crc, len, acked, blksize, phase: UpPhase::Sending };
                    Ok(())
                }
                _ => {
                    let (i, s) = self.current_mux();
                    Err((i, s, AbortCode::INVALID_COMMAND))
                }
            },
            2 => match self.state {
                State::BlockUpload { phase: UpPhase::WaitAck { sent, last }, index, sub, crc, len, acked, .. } => {
                    let ackseq = d[1];
                    if ackseq > sent {
                        return Err((index, sub, AbortCode::INVALID_SEQUENCE));
                    }
                    let acked = (acked + 7 * usize::from(ackseq)).min(len);
                    if last && ackseq == sent {
                        let unused = if len == 0 { 7 } else { (7 - len % 7) % 7 } as u8;
                        // The CRC is always sent: this server announces CRC support in its initiate response,
                        // and clients (python-canopen among them) check it whenever the server announced it,
                        // whether or not they asked for it themselves.
                        let crc_value = crc16_ccitt(0, &self.buf[..len]);
                        let c = crc_value.to_le_bytes();
                        self.respond([0xC1 | (unused << 2), c[0], c[1], 0, 0, 0, 0, 0]);
                        self.state =
                            State::BlockUpload { index, sub, crc, len, acked, blksize: 0, phase: UpPhase::WaitEnd };
                        return Ok(());
                    }
                    let blksize = d[2];
                    if blksize == 0 || blksize > MAX_BLKSIZE {
                        return Err((index, sub, AbortCode::INVALID_BLOCK_SIZE));
                    }
                    self.state = State::BlockUpload { index, sub, crc, len, acked, blksize, phase: UpPhase::Sending };
                    Ok(())
                }
                _ => {
                    let (i, s) = self.current_mux();
                    Err((i, s, AbortCode::INVALID_COMMAND))
                }
            },
            _ => match self.state {
                State::BlockUpload { phase: UpPhase::WaitEnd, .. } => {
                    self.state = State::Idle;
                    Ok(())
                }
                _ => {
                    let (i, s) = self.current_mux();
                    Err((i, s, AbortCode::INVALID_COMMAND))
                }
            },
        }
    }

    /// Emits the queued response, a block upload's next block, or a timeout abort.
    #[inline]
    pub fn poll(&mut self, now: Micros, emit: &mut impl FnMut([u8; 8])) {
        // The usual poll: no response queued, no transfer under way.
        if self.out.is_none() && matches!(self.state, State::Idle) {
            return;
        }
        self.poll_busy(now, emit);
    }

    fn poll_busy(&mut self, now: Micros, emit: &mut impl FnMut([u8; 8])) {
        if let Some(d) = self.out.take() {
            emit(d);
        }
        if SDO_BLOCK
            && let State::BlockUpload { index, sub, crc, len, acked, blksize, phase: UpPhase::Sending } = self.state
        {
            let mut pos = acked;
            let mut sent = 0u8;
            let mut last = false;
            while sent < blksize && !last {
                let n = (len - pos).min(7);
                sent += 1;
                last = pos + n >= len;
                let mut seg = [0u8; 8];
                seg[0] = sent | if last { 0x80 } else { 0 };
                seg[1..1 + n].copy_from_slice(&self.buf[pos..pos + n]);
                emit(seg);
                pos += n;
            }
            self.state =
                State::BlockUpload { index, sub, crc, len, acked, blksize, phase: UpPhase::WaitAck { sent, last } };
            self.last = now;
            return;
        }
        if self.state != State::Idle && self.timeout != 0 && now.saturating_sub(self.last) >= self.timeout {
            let (index, sub) = self.current_mux();
            self.state = State::Idle;
            emit(abort_frame(index, sub, AbortCode::TIMEOUT));
        }
    }
}
