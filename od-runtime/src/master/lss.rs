//! The LSS master (CiA 305): one request at a time to the devices on the bus, each a step
//! with a timeout, and fastscan as a run of such steps.
//!
//! [`LssMaster`] is sans-IO like the other machines: [`LssMaster::start`] a [`Request`],
//! then [`LssMaster::poll`] for the frames to send (and the timeouts),
//! [`LssMaster::on_frame`] for every frame received, [`LssMaster::deadline`] for when to poll
//! next. Each request ends in one [`Done`]: its [`Answer`] or an [`LssError`] that names the
//! step (and the identity, where the step has one).
//!
//! Requests that may be answered by several devices (identify) wait for the whole step
//! timeout and count the answers. Switch state selective counts its answers after the first
//! for the settle time, or as long again as the first answer took if that is longer (two
//! devices of one identity answer the same frames at once): two answers to one identity are
//! [`ErrorKind::Duplicate`]; no answer is a timeout. A fastscan counts the answers to its first step and to its last
//! confirmation for the settle time after the first ([`LssMaster::set_settle`]: devices
//! answer one request at the same time); with several devices every answered step does.
//! Every other step ends at its answer.
//!
//! ```
//! use od_runtime::lss::Identity;
//! use od_runtime::master::lss::{Answer, LssMaster, Request};
//! use od_runtime::Frame;
//!
//! let mut lss = LssMaster::new();
//! let mut sent = Vec::new();
//! lss.start(Request::ConfigureNodeId(5), 0).unwrap();
//! lss.poll(0, &mut |f| sent.push(f.to_string()));
//! assert_eq!(sent, ["7E5 11 05 00 00 00 00 00 00"]);
//! let answer = Frame::new(0x7E4, &[0x11, 0, 0, 0, 0, 0, 0, 0]).unwrap();
//! let done = lss.on_frame(&answer, 300).unwrap();
//! assert_eq!(done.result, Ok(Answer::Done));
//!
//! // Nobody answers: a timeout naming the step.
//! lss.start(Request::Store, 1_000).unwrap();
//! lss.poll(1_000, &mut |_| {});
//! let done = lss.poll(1_000 + lss.timeout(), &mut |_| {}).unwrap();
//! assert_eq!(done.result.unwrap_err().to_string(), "LSS store configuration: no answer within 20 ms");
//! ```

use crate::frame::{Frame, Micros};
use crate::lss::{FASTSCAN_CONFIRM, Identity, MASTER_COB, Mode, SLAVE_COB, UNCONFIGURED, bit_rate_kbit, cs};

/// The default step timeout, 20 ms: an answer over `drive-sim hub` (TCP, simulated drives in
/// another process) takes 0.2 to 2 ms; 20 ms leaves room for a loaded machine and a slow
/// device, and a full fastscan of a device (about 64 unanswered steps at most) stays near 1 s.
pub const DEFAULT_TIMEOUT: Micros = 20_000;

/// The default settle time of a fastscan step answered by several devices, 2 ms (see
/// [`LssMaster::set_settle`]).
pub const DEFAULT_SETTLE: Micros = 2_000;

/// What the master asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Switch state global (no answer).
    SwitchGlobal(Mode),
    /// Switch state selective: the device of this identity goes to configuration.
    SwitchSelective(Identity),
    /// Configure node-ID (1..=127, or [`UNCONFIGURED`]).
    ConfigureNodeId(u8),
    /// Configure bit timing: an index of the CiA 305 table ([`crate::lss::BIT_RATES`]).
    ConfigureBitTiming(u8),
    /// Activate bit timing with a switch delay in ms (no answer).
    ActivateBitTiming(u16),
    /// Store configuration.
    Store,
    /// Inquire one part of the identity (0 = vendor .. 3 = serial).
    InquireIdentity(u8),
    /// Inquire node-ID.
    InquireNodeId,
    /// Identify remote slave: every device whose vendor and product match and whose revision
    /// and serial number are within the ranges answers; the answers are counted.
    IdentifyRemote {
        /// Vendor-ID.
        vendor: u32,
        /// Product code.
        product: u32,
        /// Revision number, lowest and highest.
        revision: (u32, u32),
        /// Serial number, lowest and highest.
        serial: (u32, u32),
    },
    /// Identify non-configured remote slave: the answers are counted.
    IdentifyNonConfigured,
    /// Fastscan: finds one device without a node-ID and leaves it in configuration. The parts
    /// given are confirmed instead of scanned bit by bit.
    Fastscan([Option<u32>; 4]),
}

/// What a request got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// Done (switched, configured, stored, activated).
    Done,
    /// An inquired identity part.
    Value(u32),
    /// An inquired node-ID ([`UNCONFIGURED`] for none).
    NodeId(u8),
    /// How many devices answered an identify request.
    Answers(u8),
    /// Fastscan: the device found (now in configuration), `None` when no device without a
    /// node-ID answered.
    Found(Option<Identity>),
}

/// The step a request was at when it failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Switch state selective to this identity.
    SwitchSelective(Identity),
    /// Configure node-ID.
    ConfigureNodeId(u8),
    /// Configure bit timing (table index).
    ConfigureBitTiming(u8),
    /// Configure bit timing, asked as a bit rate in kbit/s (one the table may not have).
    BitRate(u32),
    /// Store configuration.
    Store,
    /// Inquire identity part (0..=3).
    InquireIdentity(u8),
    /// Inquire node-ID.
    InquireNodeId,
    /// Fastscan: the confirmation of a part at this value, with the parts found before it.
    FastscanConfirm {
        /// The part (0 = vendor .. 3 = serial).
        part: u8,
        /// The value sent.
        value: u32,
        /// The identity as far as it was found.
        so_far: Identity,
        /// Whether the value was given (narrowing), not scanned.
        known: bool,
    },
}

/// Why a request failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// No answer within the step timeout (µs).
    Timeout(Micros),
    /// The device answered with an error code (and the specific error byte).
    Refused {
        /// Error code (1: not supported / out of range, 2: storage, FFh: specific).
        code: u8,
        /// The implementation-specific error, when `code` is FFh.
        specific: u8,
    },
    /// Several devices answered a request meant for one identity.
    Duplicate(u8),
    /// Refused before sending: a node-ID outside 1..=127 and FFh, or a bit timing index the
    /// CiA 305 table does not define.
    Invalid,
}

/// A failed LSS request: the step and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssError {
    /// The step.
    pub step: Step,
    /// Why.
    pub kind: ErrorKind,
}

const PARTS: [&str; 4] = ["vendor-ID", "product code", "revision number", "serial number"];

/// The name of an identity part (0 = vendor .. 3 = serial).
pub fn part_name(part: u8) -> &'static str {
    PARTS[usize::from(part.min(3))]
}

impl core::fmt::Display for Step {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Step::SwitchSelective(id) => write!(f, "switch state selective ({id})"),
            Step::ConfigureNodeId(n) => write!(f, "configure node-ID {n}"),
            Step::ConfigureBitTiming(i) => match bit_rate_kbit(*i) {
                Some(k) => write!(f, "configure bit timing {k} kbit/s (index {i})"),
                None => write!(f, "configure bit timing index {i}"),
            },
            Step::BitRate(k) => write!(f, "configure bit timing {k} kbit/s"),
            Step::Store => f.write_str("store configuration"),
            Step::InquireIdentity(p) => write!(f, "inquire {}", part_name(*p)),
            Step::InquireNodeId => f.write_str("inquire node-ID"),
            Step::FastscanConfirm { part, value, so_far, known } => {
                let given = if *known { " given" } else { "" };
                write!(f, "fastscan, confirmation of the{given} {} {value:08X}h", part_name(*part))?;
                if *part > 0 {
                    write!(f, " (found so far: ")?;
                    for p in 0..*part {
                        if p > 0 {
                            f.write_str(", ")?;
                        }
                        write!(f, "{} {:08X}h", part_name(p), so_far.part(p))?;
                    }
                    f.write_str(")")?;
                }
                Ok(())
            }
        }
    }
}

impl core::fmt::Display for LssError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "LSS {}: ", self.step)?;
        match self.kind {
            ErrorKind::Timeout(t) => {
                write!(f, "no answer within {} ms", t / 1000)?;
                match self.step {
                    Step::FastscanConfirm { known: true, part, .. } => {
                        write!(f, " (no device without a node-ID has this {}: check the EDS given)", part_name(part))?
                    }
                    Step::FastscanConfirm { .. } => f.write_str(" (the device stopped answering during the scan)")?,
                    _ => {}
                }
                Ok(())
            }
            ErrorKind::Refused { code, specific } => match (self.step, code) {
                (Step::ConfigureNodeId(_), 1) => f.write_str("refused: node-ID out of range"),
                (Step::ConfigureBitTiming(_), 1) => f.write_str("refused: bit rate not supported by the device"),
                (Step::Store, 1) => f.write_str("refused: the device cannot store its configuration"),
                (Step::Store, 2) => f.write_str("refused: storage media access error"),
                (_, 0xFF) => write!(f, "refused: implementation-specific error {specific}"),
                _ => write!(f, "refused with error code {code}"),
            },
            ErrorKind::Duplicate(n) => write!(f, "{n} devices answered: two devices have this identity"),
            ErrorKind::Invalid => match self.step {
                Step::ConfigureNodeId(_) => f.write_str("not a node-ID (1..=127, or 255 for none)"),
                Step::ConfigureBitTiming(_) | Step::BitRate(_) => {
                    f.write_str("not a bit rate of the CiA 305 table (1000, 800, 500, 250, 125, 50, 20, 10 kbit/s)")
                }
                _ => f.write_str("invalid request"),
            },
        }
    }
}

/// The end of a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Done {
    /// The request.
    pub request: Request,
    /// Its answer or why it failed.
    pub result: Result<Answer, LssError>,
}

/// [`LssMaster::start`] while a request runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Busy;

impl core::fmt::Display for Busy {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("an LSS request is already running")
    }
}

/// Fastscan progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scan {
    /// The first step (bit checked 80h): is there any device without a node-ID?
    Reset,
    /// Scanning `bit` of `part`.
    Bit { part: u8, bit: u8 },
    /// Confirming `part` with its bit 0 as it stands; `second` when bit 0 was set after the
    /// first confirmation got no answer.
    Confirm { part: u8, second: bool },
}

#[derive(Clone, Copy, Debug)]
struct Running {
    request: Request,
    /// The frames of the current step not yet sent (a selective switch sends four).
    out: [[u8; 8]; 4],
    out_len: u8,
    /// When the current step times out (set when its frames are sent).
    deadline: Option<Micros>,
    /// When the current step's frames were sent.
    sent_at: Micros,
    /// The answer specifier the step waits for.
    expect: u8,
    /// Whether the step waits out its timeout counting answers.
    count: bool,
    answers: u8,
    /// The first answer's data.
    first: [u8; 8],
    scan: Scan,
    id: [u32; 4],
    /// Fastscan with several devices answering: each answered step waits `settle` after its
    /// first answer, so that the others' answers to it are not taken for the next step's.
    settle_on: bool,
    settling: bool,
}

/// The LSS master's machine (see the [module](self)).
#[derive(Clone, Debug)]
pub struct LssMaster {
    timeout: Micros,
    settle: Micros,
    running: Option<Running>,
    frames: u32,
}

impl Default for LssMaster {
    fn default() -> Self {
        Self::new()
    }
}

fn frame(cs: u8, rest: &[u8]) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[0] = cs;
    for (o, b) in d[1..].iter_mut().zip(rest) {
        *o = *b;
    }
    d
}

fn fastscan_frame(id: u32, bit: u8, sub: u8, next: u8) -> [u8; 8] {
    let v = id.to_le_bytes();
    [cs::FASTSCAN, v[0], v[1], v[2], v[3], bit, sub, next]
}

impl LssMaster {
    /// A master with the [`DEFAULT_TIMEOUT`].
    pub const fn new() -> Self {
        Self { timeout: DEFAULT_TIMEOUT, settle: DEFAULT_SETTLE, running: None, frames: 0 }
    }

    /// Sets the settle time (µs): with several devices in a fastscan, how long an answered
    /// step waits after its first answer for the others' (on a real bus their identical
    /// answers are one frame; on a hub or a bridge they are several). At most the timeout.
    pub fn set_settle(&mut self, settle: Micros) {
        self.settle = settle;
    }

    /// Sets the step timeout (µs): how long a step waits for its answer, and how long the
    /// steps that count answers wait for them. At least 1 ms.
    pub fn set_timeout(&mut self, timeout: Micros) {
        self.timeout = timeout.max(1_000);
    }

    /// The step timeout (µs).
    pub const fn timeout(&self) -> Micros {
        self.timeout
    }

    /// Frames sent so far (all requests).
    pub const fn frames_sent(&self) -> u32 {
        self.frames
    }

    /// Whether a request runs.
    pub const fn is_busy(&self) -> bool {
        self.running.is_some()
    }

    /// Starts a request; its frames go out at the next [`LssMaster::poll`].
    pub fn start(&mut self, request: Request, now: Micros) -> Result<(), Busy> {
        if self.running.is_some() {
            return Err(Busy);
        }
        let mut r = Running {
            request,
            out: [[0; 8]; 4],
            out_len: 1,
            deadline: None,
            sent_at: now,
            expect: 0,
            count: false,
            answers: 0,
            first: [0; 8],
            scan: Scan::Reset,
            id: [0; 4],
            settle_on: false,
            settling: false,
        };
        match request {
            Request::SwitchGlobal(m) => {
                r.out[0] = frame(cs::SWITCH_GLOBAL, &[u8::from(m == Mode::Configuration)]);
            }
            Request::SwitchSelective(id) => {
                for (k, v) in id.parts().iter().enumerate() {
                    r.out[k] = frame(cs::SWITCH_VENDOR + k as u8, &v.to_le_bytes());
                }
                r.out_len = 4;
                r.expect = cs::SWITCH_RESPONSE;
                r.count = true;
            }
            Request::ConfigureNodeId(n) => {
                r.out[0] = frame(cs::CONFIGURE_NODE_ID, &[n]);
                r.expect = cs::CONFIGURE_NODE_ID;
            }
            Request::ConfigureBitTiming(i) => {
                r.out[0] = frame(cs::CONFIGURE_BIT_TIMING, &[0, i]);
                r.expect = cs::CONFIGURE_BIT_TIMING;
            }
            Request::ActivateBitTiming(delay) => r.out[0] = frame(cs::ACTIVATE_BIT_TIMING, &delay.to_le_bytes()),
            Request::Store => {
                r.out[0] = frame(cs::STORE, &[]);
                r.expect = cs::STORE;
            }
            Request::InquireIdentity(p) => {
                let c = cs::INQUIRE_VENDOR + p.min(3);
                r.out[0] = frame(c, &[]);
                r.expect = c;
            }
            Request::InquireNodeId => {
                r.out[0] = frame(cs::INQUIRE_NODE_ID, &[]);
                r.expect = cs::INQUIRE_NODE_ID;
            }
            Request::IdentifyRemote { .. } => {
                // Six frames: sent four, then two, as one step (the queue holds four).
                r.out_len = 0;
                r.expect = cs::IDENTIFY_RESPONSE;
                r.count = true;
            }
            Request::IdentifyNonConfigured => {
                r.out[0] = frame(cs::IDENTIFY_NON_CONFIGURED, &[]);
                r.expect = cs::NON_CONFIGURED_RESPONSE;
                r.count = true;
            }
            Request::Fastscan(_) => {
                r.out[0] = fastscan_frame(0, FASTSCAN_CONFIRM, 0, 0);
                r.expect = cs::IDENTIFY_RESPONSE;
            }
        }
        let invalid = match request {
            Request::ConfigureNodeId(n) => !((1..=127).contains(&n) || n == UNCONFIGURED),
            Request::ConfigureBitTiming(i) => bit_rate_kbit(i).is_none(),
            _ => false,
        };
        if invalid {
            // Refused at the next poll, without sending.
            r.out_len = 0;
            r.expect = 0xFF;
            r.deadline = Some(0);
        }
        self.running = Some(r);
        Ok(())
    }

    /// When [`LssMaster::poll`] next has work: a step's timeout.
    pub fn deadline(&self) -> Option<Micros> {
        let r = self.running.as_ref()?;
        if r.out_len > 0 || matches!(r.request, Request::IdentifyRemote { .. }) && r.deadline.is_none() {
            return Some(0);
        }
        r.deadline
    }

    /// Sends the frames due and ends steps whose time is up.
    pub fn poll(&mut self, now: Micros, send: &mut impl FnMut(Frame)) -> Option<Done> {
        let r = self.running.as_mut()?;
        if let Request::IdentifyRemote { vendor, product, revision, serial } = r.request
            && r.deadline.is_none()
        {
            let values = [vendor, product, revision.0, revision.1, serial.0, serial.1];
            for (k, v) in values.iter().enumerate() {
                send(Frame::full(MASTER_COB, frame(cs::IDENTIFY_VENDOR + k as u8, &v.to_le_bytes())));
                self.frames += 1;
            }
            r.deadline = Some(now.saturating_add(self.timeout));
            r.sent_at = now;
            return None;
        }
        if r.out_len > 0 {
            for d in &r.out[..usize::from(r.out_len)] {
                send(Frame::full(MASTER_COB, *d));
                self.frames += 1;
            }
            r.out_len = 0;
            if r.expect == 0 {
                // No answer to wait for.
                let request = r.request;
                self.running = None;
                return Some(Done { request, result: Ok(Answer::Done) });
            }
            r.deadline = Some(now.saturating_add(self.timeout));
            r.sent_at = now;
            return None;
        }
        match r.deadline {
            Some(d) if now >= d => self.step_end(now),
            _ => None,
        }
    }

    /// Takes a received frame; only answers on 7E4h count.
    pub fn on_frame(&mut self, frame: &Frame, now: Micros) -> Option<Done> {
        if frame.id() != SLAVE_COB || frame.is_rtr() || frame.len() != 8 {
            return None;
        }
        let r = self.running.as_mut()?;
        let d = *frame.raw();
        if r.out_len > 0 || r.deadline.is_none() || d[0] != r.expect {
            return None;
        }
        if r.answers == 0 {
            r.first = d;
        }
        r.answers = r.answers.saturating_add(1);
        if r.count {
            if r.answers == 1 && matches!(r.request, Request::SwitchSelective(_)) {
                // A second device of this identity answers the same frames: right behind.
                let window = self.settle.max(now.saturating_sub(r.sent_at));
                r.deadline = r.deadline.map(|d| d.min(now.saturating_add(window)));
            }
            return None;
        }
        // Fastscan: the first step counts the devices without a node-ID, the last
        // confirmation its answers (duplicate identities), and with several devices every
        // answered step lets the others' answers go by: each waits the settle time after its
        // first answer, counting.
        let scan = matches!(r.request, Request::Fastscan(_));
        if scan && (r.settle_on || matches!(r.scan, Scan::Confirm { part: 3, .. } | Scan::Reset)) {
            if !r.settling {
                r.settling = true;
                r.deadline = Some(now.saturating_add(self.settle.min(self.timeout)));
            }
            return None;
        }
        self.step_end(now)
    }

    /// Ends the current step: its answer came, or its time is up.
    fn step_end(&mut self, now: Micros) -> Option<Done> {
        let timeout = self.timeout;
        let r = self.running.as_mut()?;
        let request = r.request;
        let answered = r.answers > 0;
        let fail = |step, kind| Some(Done { request, result: Err(LssError { step, kind }) });
        let d = r.first;
        let done = match request {
            Request::Fastscan(known) => return self.scan_step(known, answered, now),
            _ if r.expect == 0xFF => {
                let step = match request {
                    Request::ConfigureNodeId(n) => Step::ConfigureNodeId(n),
                    Request::ConfigureBitTiming(i) => Step::ConfigureBitTiming(i),
                    _ => Step::Store,
                };
                fail(step, ErrorKind::Invalid)
            }
            Request::SwitchSelective(id) => match r.answers {
                0 => fail(Step::SwitchSelective(id), ErrorKind::Timeout(timeout)),
                1 => Some(Done { request, result: Ok(Answer::Done) }),
                n => fail(Step::SwitchSelective(id), ErrorKind::Duplicate(n)),
            },
            Request::IdentifyRemote { .. } | Request::IdentifyNonConfigured => {
                Some(Done { request, result: Ok(Answer::Answers(r.answers)) })
            }
            _ => {
                let step = match request {
                    Request::ConfigureNodeId(n) => Step::ConfigureNodeId(n),
                    Request::ConfigureBitTiming(i) => Step::ConfigureBitTiming(i),
                    Request::Store => Step::Store,
                    Request::InquireIdentity(p) => Step::InquireIdentity(p),
                    _ => Step::InquireNodeId,
                };
                if !answered {
                    fail(step, ErrorKind::Timeout(timeout))
                } else {
                    match request {
                        Request::InquireIdentity(_) => Some(Done {
                            request,
                            result: Ok(Answer::Value(u32::from_le_bytes([d[1], d[2], d[3], d[4]]))),
                        }),
                        Request::InquireNodeId => Some(Done { request, result: Ok(Answer::NodeId(d[1])) }),
                        _ if d[1] != 0 => fail(step, ErrorKind::Refused { code: d[1], specific: d[2] }),
                        _ => Some(Done { request, result: Ok(Answer::Done) }),
                    }
                }
            }
        };
        self.running = None;
        done
    }

    /// The next fastscan step after one ended (`answered` or not).
    fn scan_step(&mut self, known: [Option<u32>; 4], answered: bool, now: Micros) -> Option<Done> {
        let _ = now;
        let timeout = self.timeout;
        let r = self.running.as_mut()?;
        let request = r.request;
        let answers = r.answers;
        r.answers = 0;
        r.deadline = None;
        r.settling = false;
        let start_part = |r: &mut Running, part: u8| {
            if let Some(v) = known[usize::from(part)] {
                r.id[usize::from(part)] = v;
                r.scan = Scan::Confirm { part, second: true };
            } else {
                r.id[usize::from(part)] = 0;
                r.scan = Scan::Bit { part, bit: 31 };
            }
        };
        match r.scan {
            Scan::Reset => {
                if !answered {
                    self.running = None;
                    return Some(Done { request, result: Ok(Answer::Found(None)) });
                }
                r.settle_on = answers > 1;
                start_part(r, 0);
            }
            Scan::Bit { part, bit } => {
                if !answered {
                    r.id[usize::from(part)] |= 1 << bit;
                }
                r.scan = if bit > 1 { Scan::Bit { part, bit: bit - 1 } } else { Scan::Confirm { part, second: false } };
            }
            Scan::Confirm { part, second } => {
                let p = usize::from(part);
                if !answered {
                    if !second {
                        // Bit 0 is 1.
                        r.id[p] |= 1;
                        r.scan = Scan::Confirm { part, second: true };
                    } else {
                        let so_far = Identity { vendor: r.id[0], product: r.id[1], revision: r.id[2], serial: r.id[3] };
                        let known = known[p].is_some();
                        let step = Step::FastscanConfirm { part, value: r.id[p], so_far, known };
                        self.running = None;
                        return Some(Done {
                            request,
                            result: Err(LssError { step, kind: ErrorKind::Timeout(timeout) }),
                        });
                    }
                } else if part == 3 {
                    let found = Identity { vendor: r.id[0], product: r.id[1], revision: r.id[2], serial: r.id[3] };
                    self.running = None;
                    if answers > 1 {
                        let step = Step::FastscanConfirm { part, value: found.serial, so_far: found, known: false };
                        return Some(Done {
                            request,
                            result: Err(LssError { step, kind: ErrorKind::Duplicate(answers) }),
                        });
                    }
                    return Some(Done { request, result: Ok(Answer::Found(Some(found))) });
                } else {
                    start_part(r, part + 1);
                }
            }
        }
        r.out[0] = match r.scan {
            Scan::Reset => fastscan_frame(0, FASTSCAN_CONFIRM, 0, 0),
            Scan::Bit { part, bit } => fastscan_frame(r.id[usize::from(part)], bit, part, part),
            Scan::Confirm { part, .. } => fastscan_frame(r.id[usize::from(part)], 0, part, (part + 1) & 3),
        };
        r.out_len = 1;
        None
    }
}
