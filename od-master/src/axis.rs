//! A CiA 402 drive over SDO (and an RPDO for cyclic synchronous position).
//!
//! Every state change completes when the statusword (6041h) confirms it, never when the
//! controlword was sent; every error says which drive, its state and statusword, and which
//! object ([`AxisError`]).
//!
//! | operation | objects | method |
//! |---|---|---|
//! | to Operation enabled, fault reset on the way | 6040h, 6041h, 603Fh | [`Axis::enable`] |
//! | mode of operation, confirmed | 6060h, 6061h | [`Axis::set_mode`] |
//! | homing: method, speeds, acceleration, offset; attained or error | 6098h, 6099h, 609Ah, 607Ch | [`Axis::home`] |
//! | profile position: set-point handshake (bit 4 / bit 12), change set immediately, relative; target reached | 607Ah, 6081h, 6083h, 6084h | [`Axis::set_point`], [`Axis::move_to`] |
//! | profile velocity | 60FFh, 6083h, 6084h | [`Axis::run_velocity`] |
//! | cyclic synchronous position: a set-point every SYNC | 1400h+, 1600h+, 607Ah | [`Axis::cyclic_position`], [`Csp::send`] |
//!
//! # What cannot succeed fails at once
//!
//! * Modes: a mode of operation is checked against 6502h (supported drive modes, read once)
//!   before anything is written, by [`Axis::home`], [`Axis::set_point`],
//!   [`Axis::run_velocity`] and [`Axis::cyclic_position`]; by [`Axis::set_mode`] too once
//!   6502h is known, else when the drive refuses the mode. A vendor's 6502h may leave out a
//!   mode its drive runs (the AKD's 65h lacks profile torque and cyclic synchronous position):
//!   the device's sidecar says so (`[[mode]] not_in_6502h = true`) and
//!   [`Axis::with_sidecar`] takes it. A drive without 6502h is checked against its sidecar's
//!   `[[mode]]` list, else not at all.
//! * Limits: statusword bit 11 (internal limit active) is a level, not an edge: a drive that
//!   stopped on its limit keeps it set. Before a move (and whenever bit 11 is set during its
//!   wait) the axis finds out which limit it is: the limit switches of 60FDh (bit 0 negative,
//!   bit 1 positive) where the drive has 60FDh, the software position limits 607Dh the position
//!   is at (or the target is beyond, when bit 11 came up with the move: the drive limited it),
//!   and the limit bits of the drive's own register where its
//!   sidecar names them (`[[warning]] limit = "positive"`: the DRVI's 2006h bits 6 and 7). A
//!   move further into that limit is refused before anything is written
//!   ([`Impossible::IntoLimit`]), or its wait ends at once
//!   ([`StopReason::AtLimit`]); a move away from it is taken and its
//!   wait goes on while bit 11 stands. A bit 11 that comes up during a wait with no limit to be
//!   found (a torque or velocity limit) ends it as before; one standing at the start does not.
//! * Warnings: a warning (statusword bit 7) standing when a move starts does not refuse it and
//!   does not end its wait: it was there before the move and the drive took the move (a
//!   temperature warning, the warning of the limit switch a move leaves). Only a warning that
//!   comes up during the wait ends it, with the drive's register read into the message. A
//!   drive that refuses a command while its warning stands (the DRVI's "command refused"
//!   latched from an earlier refusal) does not acknowledge the set-point: that wait ends after
//!   [`AxisConfig::state_timeout`] (1 s), with the register in the message.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use od_runtime::cia402::State;
use od_runtime::master::{PdoField, PdoMapping, PdoValue};
use od_runtime::od::DataType;
use od_runtime::pdo::{Direction, MapEntry};
use tokio::sync::{broadcast, watch};
use tokio::time::Instant;

use crate::bus::CyclicPdo;
use crate::error::{AxisError, AxisErrorKind, Error, Impossible, Interruption, StopReason};
use crate::event::Event;
use crate::node::{Node, SdoValue};
use crate::register::StatusRegister;
use crate::remote::{Quantity, Scaling, UnitError, dim};
use od_bus::tokio::LinkState;
use od_runtime::master::NodeEvent;
use tokio::sync::mpsc;

const CONTROLWORD: u16 = 0x6040;
const STATUSWORD: u16 = 0x6041;
const MODE: u16 = 0x6060;
const MODE_DISPLAY: u16 = 0x6061;
const POSITION_ACTUAL: u16 = 0x6064;
const TARGET_POSITION: u16 = 0x607A;

/// Statusword bits.
const SW_WARNING: u16 = 1 << 7;
const SW_TARGET_REACHED: u16 = 1 << 10;
const SW_INTERNAL_LIMIT: u16 = 1 << 11;
const SW_BIT12: u16 = 1 << 12;
const SW_BIT13: u16 = 1 << 13;

/// Modes of operation (6060h).
pub mod mode {
    /// Profile position.
    pub const PROFILE_POSITION: i8 = 1;
    /// Profile velocity.
    pub const PROFILE_VELOCITY: i8 = 3;
    /// Homing.
    pub const HOMING: i8 = 6;
    /// Cyclic synchronous position.
    pub const CYCLIC_SYNC_POSITION: i8 = 8;
}

/// How an [`Axis`] waits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisConfig {
    /// How long each state change may take to show in the statusword (default 1 s).
    pub state_timeout: Duration,
    /// How often the statusword is read while waiting (default 10 ms).
    pub poll: Duration,
}

impl Default for AxisConfig {
    fn default() -> Self {
        Self { state_timeout: Duration::from_secs(1), poll: Duration::from_millis(10) }
    }
}

/// A homing run: the method (6098h) and, where given, the speeds, acceleration and offset
/// written before it (unset ones keep the drive's values).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Homing {
    /// The homing method (6098h).
    pub method: i8,
    /// Speed during search for switch (6099h sub 1).
    pub speed_switch: Option<u32>,
    /// Speed during search for zero (6099h sub 2).
    pub speed_zero: Option<u32>,
    /// Homing acceleration (609Ah).
    pub acceleration: Option<u32>,
    /// Home offset (607Ch).
    pub offset: Option<i32>,
    /// How long the homing may take (default 60 s).
    pub timeout: Duration,
}

impl Homing {
    /// Homing with `method` and the drive's own speeds.
    pub fn method(method: i8) -> Self {
        Self {
            method,
            speed_switch: None,
            speed_zero: None,
            acceleration: None,
            offset: None,
            timeout: Duration::from_secs(60),
        }
    }
}

/// A homing method (6098h) alone: `axis.home(HomingMethod(18))` homes with the drive's own
/// speeds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomingMethod(pub i8);

impl From<HomingMethod> for Homing {
    fn from(m: HomingMethod) -> Self {
        Homing::method(m.0)
    }
}

impl From<&Homing> for Homing {
    fn from(h: &Homing) -> Self {
        *h
    }
}

/// A profile-position move's parameters; unset ones keep the drive's values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Move {
    /// Profile velocity (6081h).
    pub velocity: Option<u32>,
    /// Profile acceleration (6083h).
    pub acceleration: Option<u32>,
    /// Profile deceleration (6084h).
    pub deceleration: Option<u32>,
    /// Controlword bit 6: the target is relative.
    pub relative: bool,
    /// Controlword bit 5, change set immediately: the new set-point replaces the running one.
    pub immediate: bool,
    /// How long the drive may take to acknowledge the set-point, and [`Axis::move_to`] to reach
    /// the target (default 30 s).
    pub timeout: Duration,
}

impl Default for Move {
    fn default() -> Self {
        Self {
            velocity: None,
            acceleration: None,
            deceleration: None,
            relative: false,
            immediate: false,
            timeout: Duration::from_secs(30),
        }
    }
}

/// A CiA 402 drive on a [`Node`].
#[derive(Debug)]
pub struct Axis {
    node: Node,
    config: AxisConfig,
    /// The last statusword read and when, for error messages.
    last: Mutex<Option<(u16, Instant)>>,
    /// The drive's own warning or status register, read into errors.
    register: Option<Arc<StatusRegister>>,
    /// What the device's sidecar says of its modes beside 6502h.
    modes: SidecarModes,
    /// 6502h as read once (`Some(None)`: the drive has none), for the mode checks.
    supported: Mutex<Option<Option<u32>>>,
    /// The last set-point's direction and target, for the limit checks of the wait for it.
    heading: Mutex<Option<Planned>>,
    /// The statusword before the last set-point, for the wait for its target: bits that came
    /// up with the set-point (the AKD clipping it to a software limit) came up during the move.
    before_set_point: Mutex<Option<u16>>,
}

/// What a device's sidecar says of its modes ([`Axis::with_sidecar`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct SidecarModes {
    /// 6502h bits of the modes the drive runs though its 6502h leaves them out.
    added: u32,
    /// The `[[mode]]` list, for a drive without 6502h (`None`: no sidecar, or an empty list).
    listed: Option<Vec<i8>>,
}

/// A move as commanded, for the limit checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Planned {
    /// To an absolute target.
    Position(i32),
    /// Relative, by a distance of this sign.
    Relative(i32),
    /// A target velocity.
    Velocity(i32),
}

/// Where a move goes: the sign of its direction and, for a position, its target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Heading {
    sign: i64,
    target: Option<i64>,
    /// The position it starts from, where read.
    from: Option<i64>,
    /// A velocity rather than a position.
    velocity: bool,
}

impl Heading {
    fn describe(&self) -> String {
        match (self.target, self.from) {
            (Some(t), Some(f)) => format!("a move to {t} from {f}"),
            (Some(t), None) => format!("a move to {t}"),
            (None, _) if self.velocity => {
                format!("a {} velocity", if self.sign > 0 { "positive" } else { "negative" })
            }
            _ => format!("a relative move in the {} direction", if self.sign > 0 { "positive" } else { "negative" }),
        }
    }
}

impl Axis {
    /// The drive on `node`, with the default [`AxisConfig`].
    pub fn new(node: Node) -> Self {
        Self::with_config(node, AxisConfig::default())
    }

    /// The drive on `node` with `config`.
    pub fn with_config(node: Node, config: AxisConfig) -> Self {
        Self {
            node,
            config,
            last: Mutex::new(None),
            register: None,
            modes: SidecarModes::default(),
            supported: Mutex::new(None),
            heading: Mutex::new(None),
            before_set_point: Mutex::new(None),
        }
    }

    /// This drive with its vendor's warning or status register (from its sidecar:
    /// [`StatusRegister::from_sidecar`]): an operation that fails reads it, and its error says
    /// which of its bits are set, in the sidecar's words.
    pub fn with_register(mut self, register: StatusRegister) -> Self {
        self.register = Some(Arc::new(register));
        self
    }

    /// This drive with what its device's sidecar says: its warning or status register
    /// ([`with_register`](Self::with_register)), whose `limit` bits tell which position limit
    /// the drive is at; the modes it runs though its 6502h leaves them out (`[[mode]]
    /// not_in_6502h = true`: the AKD's cyclic synchronous position), taken as supported; and,
    /// for a drive without 6502h (the DRVI), its `[[mode]]` list as the modes it supports.
    pub fn with_sidecar(mut self, sidecar: &od_sidecar::Sidecar) -> Self {
        if let Some(register) = StatusRegister::from_sidecar(sidecar) {
            self.register = Some(Arc::new(register));
        }
        let added = sidecar
            .modes
            .iter()
            .filter(|m| m.not_in_6502h)
            .filter_map(|m| crate::error::supported_mode_bit(m.code))
            .fold(0, |a, b| a | b);
        let listed = (!sidecar.modes.is_empty()).then(|| sidecar.modes.iter().map(|m| m.code).collect());
        self.modes = SidecarModes { added, listed };
        self
    }

    /// The node.
    pub fn node(&self) -> &Node {
        &self.node
    }

    /// This drive in the units of `units` (its generated `units::Units`, read from it with the
    /// generated client's `units()`): positions given and returned as quantities.
    pub fn with_units(self, units: impl Scaling + 'static) -> UnitAxis {
        UnitAxis { axis: self, units: Arc::new(units) }
    }

    fn last_statusword(&self) -> Option<(u16, Instant)> {
        *self.last.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// An error about `index`/`sub` with the last statusword seen and its age.
    fn error(&self, index: u16, sub: u8, kind: AxisErrorKind) -> Error {
        let last = self.last_statusword();
        let statusword = last.map(|(sw, _)| sw);
        Error::Axis(Box::new(AxisError {
            node: self.node.id(),
            state: statusword.and_then(State::from_statusword),
            statusword,
            seen: last.map(|(_, at)| at.elapsed()),
            index,
            sub,
            kind,
            register: None,
        }))
    }

    /// `error` with the drive's register read into it (where the axis has one and it reads).
    async fn explained(&self, index: u16, sub: u8, kind: AxisErrorKind) -> Error {
        let mut e = self.error(index, sub, kind);
        if let (Some(reg), Error::Axis(a)) = (&self.register, &mut e)
            && let Ok(bytes) = self.node.read_bytes(reg.index, reg.sub).await
            && (1..=4).contains(&bytes.len())
        {
            let mut b = [0u8; 4];
            b[..bytes.len()].copy_from_slice(&bytes);
            a.register = Some(reg.reading(u32::from_le_bytes(b)));
        }
        e
    }

    async fn read<T: SdoValue>(&self, index: u16, sub: u8) -> Result<T, Error> {
        self.node.read(index, sub).await.map_err(|e| self.error(index, sub, AxisErrorKind::Sdo(Box::new(e))))
    }

    /// A parameter or a target: writing it twice is writing it once, so it is retried.
    async fn set<T: SdoValue>(&self, index: u16, sub: u8, value: T) -> Result<(), Error> {
        self.node
            .write_idempotent(index, sub, value)
            .await
            .map_err(|e| self.error(index, sub, AxisErrorKind::Sdo(Box::new(e))))
    }

    /// Writes the controlword (never retried: the drive acts on edges of its bits).
    pub async fn controlword(&self, cw: u16) -> Result<(), Error> {
        self.node
            .write(CONTROLWORD, 0, cw)
            .await
            .map_err(|e| self.error(CONTROLWORD, 0, AxisErrorKind::Sdo(Box::new(e))))
    }

    /// Reads the statusword.
    pub async fn statusword(&self) -> Result<u16, Error> {
        let sw: u16 = self.read(STATUSWORD, 0).await?;
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some((sw, Instant::now()));
        Ok(sw)
    }

    /// The CiA 402 state the statusword shows (`None` for a combination CiA 402 does not
    /// define).
    pub async fn state(&self) -> Result<Option<State>, Error> {
        Ok(State::from_statusword(self.statusword().await?))
    }

    /// The position actual value (6064h).
    pub async fn position(&self) -> Result<i32, Error> {
        self.read(POSITION_ACTUAL, 0).await
    }

    /// The error code (603Fh), 0 when it cannot be read.
    async fn error_code(&self) -> u16 {
        self.node.read::<u16>(0x603F, 0).await.unwrap_or(0)
    }

    /// Reads the statusword every poll period until `done` holds for it; fails when the drive
    /// faults (unless `done` accepts a fault) or `timeout` passes.
    async fn wait(&self, what: &str, timeout: Duration, done: impl Fn(u16) -> bool) -> Result<u16, Error> {
        self.wait_guarded(what, timeout, Guard::State, None, done).await
    }

    /// [`wait`](Self::wait), also stopping as soon as `guard` says the wait cannot end well;
    /// `before` is the statusword before the command waited on (else the wait's first).
    async fn wait_guarded(
        &self,
        what: &str,
        timeout: Duration,
        guard: Guard,
        before: Option<u16>,
        done: impl Fn(u16) -> bool,
    ) -> Result<u16, Error> {
        let end = Instant::now() + timeout;
        let mut watch = guard.watch(self, before);
        let mut interrupts = self.interrupts();
        loop {
            let sw = self.statusword().await?;
            // What happened to the node while the statusword was read comes first: a read that
            // a reboot cut short starts again and answers the rebooted drive's statusword.
            self.interrupted(&mut interrupts)?;
            if done(sw) {
                return Ok(sw);
            }
            if matches!(State::from_statusword(sw), Some(State::Fault | State::FaultReactionActive)) {
                let error_code = self.error_code().await;
                return Err(self.explained(STATUSWORD, 0, AxisErrorKind::Fault { error_code }).await);
            }
            let stop = match watch.check(sw) {
                Verdict::Go => None,
                Verdict::Stop(why) => Some(why),
                Verdict::Limited { rose, warning_rose } => self.limit_verdict(rose, warning_rose).await?,
            };
            if let Some(mut why) = stop {
                if matches!(why, StopReason::Emergency { .. }) {
                    // The EMCY can come before the statusword shows why: the error shows it,
                    // and a limit the move heads for is named rather than the EMCY's code (the
                    // EMCY says the drive limited the move now: its target counts).
                    if let Ok(sw) = self.statusword().await
                        && sw & SW_INTERNAL_LIMIT != 0
                        && watch.guard == Guard::Motion
                        && let Some(limit @ StopReason::AtLimit(_)) = self.limit_verdict(true, false).await?
                    {
                        why = limit;
                    }
                }
                let kind = AxisErrorKind::Stopped { what: what.to_owned(), why };
                return Err(self.explained(STATUSWORD, 0, kind).await);
            }
            if Instant::now() >= end {
                let timeout_ms = u64::try_from(timeout.as_millis()).unwrap_or(u64::MAX);
                let kind = AxisErrorKind::Timeout { what: what.to_owned(), timeout_ms };
                return Err(self.explained(STATUSWORD, 0, kind).await);
            }
            self.pause(&mut interrupts).await?;
        }
    }

    /// Statusword bit 11 is set during a move's wait (it came up, or stood at the start):
    /// the wait stops when the limit is the one the move heads for; a limit behind it (the
    /// move leaves a limit switch) lets it go on. A bit 11 that came up with no limit to be
    /// found (a torque or velocity limit) stops it as before; one that stood, does not.
    async fn limit_verdict(&self, rose: bool, warning_rose: bool) -> Result<Option<StopReason>, Error> {
        let planned = *self.heading.lock().unwrap_or_else(|e| e.into_inner());
        let heading = match planned {
            Some(p) => Some(self.heading(p).await?),
            None => None,
        };
        // The target beyond a software limit counts when bit 11 came up during the move (the
        // drive limited it); a bit 11 that stood before is the drive's (the DRVI's stands while
        // its limit check is on, against limits it offsets by the home offset).
        let target = if rose { heading.and_then(|h| h.target) } else { None };
        let limits = self.active_limits(target).await?;
        let ahead = heading.filter(|h| h.sign != 0).and_then(|h| limits.iter().find(|l| l.side == side_of(h.sign)));
        Ok(match ahead {
            Some(limit) => Some(StopReason::AtLimit(limit.clone())),
            None if limits.is_empty() && rose => Some(StopReason::InternalLimit),
            None if limits.is_empty() && warning_rose => Some(StopReason::Warning),
            None => None,
        })
    }

    async fn wait_state(&self, want: State) -> Result<(), Error> {
        let what = format!("{want:?}");
        self.wait(&what, self.config.state_timeout, |sw| State::from_statusword(sw) == Some(want)).await.map(drop)
    }

    /// Takes the drive to Operation enabled from whatever state it is in: a fault reset (a
    /// rising edge of bit 7) out of Fault, then shutdown, switch on and enable operation, each
    /// step confirmed by the statusword.
    pub async fn enable(&self) -> Result<(), Error> {
        // At most: fault reaction → fault → reset → ready → switched on → enabled, and a
        // quick stop on the way.
        for _ in 0..8 {
            let sw = self.statusword().await?;
            let Some(state) = State::from_statusword(sw) else {
                tokio::time::sleep(self.config.poll).await;
                continue;
            };
            match state {
                State::OperationEnabled => return Ok(()),
                State::FaultReactionActive => {
                    let what = "the end of the fault reaction";
                    self.wait(what, self.config.state_timeout, |sw| {
                        State::from_statusword(sw) != Some(State::FaultReactionActive)
                    })
                    .await?;
                }
                State::Fault => {
                    self.controlword(0x0000).await?;
                    self.controlword(0x0080).await?;
                    let end = Instant::now() + self.config.state_timeout;
                    loop {
                        let sw = self.statusword().await?;
                        if State::from_statusword(sw) != Some(State::Fault) {
                            break;
                        }
                        if Instant::now() >= end {
                            let error_code = self.error_code().await;
                            return Err(self.error(CONTROLWORD, 0, AxisErrorKind::Fault { error_code }));
                        }
                        tokio::time::sleep(self.config.poll).await;
                    }
                    self.controlword(0x0000).await?;
                }
                State::NotReadyToSwitchOn => self.wait_state(State::SwitchOnDisabled).await?,
                State::SwitchOnDisabled => {
                    self.controlword(0x0006).await?;
                    self.wait_state(State::ReadyToSwitchOn).await?;
                }
                State::ReadyToSwitchOn => {
                    self.controlword(0x0007).await?;
                    self.wait_state(State::SwitchedOn).await?;
                }
                State::SwitchedOn => {
                    self.controlword(0x000F).await?;
                    self.wait_state(State::OperationEnabled).await?;
                }
                State::QuickStopActive => {
                    // Disable voltage (transition 12) and start over from Switch on disabled.
                    self.controlword(0x0000).await?;
                    self.wait_state(State::SwitchOnDisabled).await?;
                }
            }
        }
        self.wait_state(State::OperationEnabled).await
    }

    /// Shutdown: to Ready to switch on (power stage off), confirmed.
    pub async fn disable(&self) -> Result<(), Error> {
        self.controlword(0x0006).await?;
        self.wait_state(State::ReadyToSwitchOn).await
    }

    /// Writes the mode of operation (6060h) and waits until 6061h shows it.
    ///
    /// A mode the drive does not support (6502h, with what its sidecar adds:
    /// [`with_sidecar`](Self::with_sidecar)) fails naming 6502h ([`Impossible::Mode`]): before
    /// anything is written once the axis knows 6502h (the operations that select a mode for
    /// themselves read it first), else as soon as the drive refuses the write or 6061h does
    /// not follow (a plain mode change costs no extra transfer).
    pub async fn set_mode(&self, mode: i8) -> Result<(), Error> {
        if self.supported.lock().unwrap_or_else(|e| e.into_inner()).is_some() {
            self.check_mode(mode).await?;
        }
        let shown: i8 = self.read(MODE_DISPLAY, 0).await?;
        if shown == mode {
            return Ok(());
        }
        if let Err(e) = self.set(MODE, 0, mode).await {
            self.check_mode(mode).await?;
            return Err(e);
        }
        let end = Instant::now() + self.config.state_timeout;
        loop {
            let shown: i8 = self.read(MODE_DISPLAY, 0).await?;
            if shown == mode {
                return Ok(());
            }
            if Instant::now() >= end {
                self.check_mode(mode).await?;
                return Err(self.error(MODE_DISPLAY, 0, AxisErrorKind::Mode { wanted: mode, shown }));
            }
            tokio::time::sleep(self.config.poll).await;
        }
    }

    /// Homes the drive: writes the method and the parameters given, enters homing mode, enables
    /// the drive, starts the homing (bit 4) and waits for "homing attained" (bits 12 and 10),
    /// failing on a homing error (bit 13), a fault, or the timeout. Returns the position
    /// actual value (6064h) at the end.
    pub async fn home(&self, homing: impl Into<Homing>) -> Result<i32, Error> {
        let homing = &homing.into();
        if homing.method == 0 {
            return Err(self.error(0x6098, 0, AxisErrorKind::Impossible(Impossible::NoHomingMethod)));
        }
        self.check_mode(mode::HOMING).await?;
        self.set(0x6098, 0, homing.method).await?;
        if let Some(v) = homing.speed_switch {
            self.set(0x6099, 1, v).await?;
        }
        if let Some(v) = homing.speed_zero {
            self.set(0x6099, 2, v).await?;
        }
        if let Some(v) = homing.acceleration {
            self.set(0x609A, 0, v).await?;
        }
        if let Some(v) = homing.offset {
            self.set(0x607C, 0, v).await?;
        }
        self.set_mode(mode::HOMING).await?;
        self.enable().await?;
        self.controlword(0x000F).await?;
        self.controlword(0x001F).await?;
        let result = self
            .wait_guarded("homing attained", homing.timeout, Guard::Homing, None, |sw| {
                sw & SW_BIT13 != 0 || sw & (SW_BIT12 | SW_TARGET_REACHED) == SW_BIT12 | SW_TARGET_REACHED
            })
            .await;
        let sw = match result {
            Ok(sw) => sw,
            Err(e) => {
                // Stop the homing (a falling bit 4) before reporting.
                let _ = self.node.write(CONTROLWORD, 0, 0x000Fu16).await;
                return Err(e);
            }
        };
        self.controlword(0x000F).await?;
        if sw & SW_BIT13 != 0 {
            return Err(self.error(0x6098, 0, AxisErrorKind::Bit13("homing error")));
        }
        self.position().await
    }

    /// Profile position: writes the target and the move's parameters, enters profile position
    /// mode, enables the drive, and hands the set-point over: bit 4 up, wait for the
    /// acknowledgement (bit 12), bit 4 down. Does not wait for the target.
    pub async fn set_point(&self, target: i32, m: &Move) -> Result<(), Error> {
        self.check_mode(mode::PROFILE_POSITION).await?;
        self.check_velocity(m).await?;
        self.check_limits(if m.relative { Planned::Relative(target) } else { Planned::Position(target) }).await?;
        self.set_mode(mode::PROFILE_POSITION).await?;
        if let Some(v) = m.velocity {
            self.set(0x6081, 0, v).await?;
        }
        if let Some(v) = m.acceleration {
            self.set(0x6083, 0, v).await?;
        }
        if let Some(v) = m.deceleration {
            self.set(0x6084, 0, v).await?;
        }
        self.enable().await?;
        let bits = 0x000F | if m.immediate { 1 << 5 } else { 0 } | if m.relative { 1 << 6 } else { 0 };
        // A new set-point needs bit 4 low and the previous acknowledgement gone.
        self.controlword(bits).await?;
        let before = self
            .wait("bit 12 clear before a new set-point", self.config.state_timeout, |sw| sw & SW_BIT12 == 0)
            .await?;
        *self.before_set_point.lock().unwrap_or_else(|e| e.into_inner()) = Some(before);
        self.set(TARGET_POSITION, 0, target).await?;
        self.controlword(bits | 0x10).await?;
        let acknowledged = self.wait_guarded(
            "set-point acknowledge",
            m.timeout.min(self.config.state_timeout),
            Guard::Motion,
            Some(before),
            |sw| sw & SW_BIT12 != 0,
        );
        if let Err(e) = acknowledged.await {
            let _ = self.node.write(CONTROLWORD, 0, bits).await;
            return Err(match e {
                Error::Axis(a) if matches!(a.kind, AxisErrorKind::Timeout { .. }) => {
                    let timeout_ms = u64::try_from(m.timeout.min(self.config.state_timeout).as_millis()).unwrap_or(0);
                    let mut e = self.error(TARGET_POSITION, 0, AxisErrorKind::SetPoint { timeout_ms });
                    if let Error::Axis(b) = &mut e {
                        b.register = a.register;
                    }
                    e
                }
                e => e,
            });
        }
        self.controlword(bits).await
    }

    /// Waits for "target reached" (bit 10), failing on a following error (bit 13), a fault or
    /// the timeout.
    pub async fn wait_target_reached(&self, timeout: Duration) -> Result<(), Error> {
        let before = self.before_set_point.lock().unwrap_or_else(|e| e.into_inner()).take();
        let sw = self
            .wait_guarded("target reached", timeout, Guard::Motion, before, |sw| {
                sw & (SW_TARGET_REACHED | SW_BIT13) != 0
            })
            .await?;
        if sw & SW_TARGET_REACHED == 0 {
            return Err(self.error(TARGET_POSITION, 0, AxisErrorKind::Bit13("following error")));
        }
        Ok(())
    }

    /// A profile-position move to its end: [`set_point`](Self::set_point), then
    /// [`wait_target_reached`](Self::wait_target_reached). Returns the position actual value.
    pub async fn move_to(&self, target: i32, m: &Move) -> Result<i32, Error> {
        self.set_point(target, m).await?;
        self.wait_target_reached(m.timeout).await?;
        self.position().await
    }

    /// Profile velocity: enters the mode, writes the target velocity (60FFh) and the ramps
    /// given, and enables the drive; it runs until told otherwise.
    pub async fn run_velocity(
        &self,
        velocity: i32,
        acceleration: Option<u32>,
        deceleration: Option<u32>,
    ) -> Result<(), Error> {
        self.check_mode(mode::PROFILE_VELOCITY).await?;
        self.check_limits(Planned::Velocity(velocity)).await?;
        self.set_mode(mode::PROFILE_VELOCITY).await?;
        if let Some(v) = acceleration {
            self.set(0x6083, 0, v).await?;
        }
        if let Some(v) = deceleration {
            self.set(0x6084, 0, v).await?;
        }
        self.set(0x60FF, 0, velocity).await?;
        self.enable().await?;
        self.controlword(0x000F).await
    }

    /// The velocity actual value (606Ch).
    pub async fn velocity(&self) -> Result<i32, Error> {
        self.read(0x606C, 0).await
    }

    /// Cyclic synchronous position: maps the target position (607Ah) into RPDO `rpdo`
    /// (1..=512; communication 1400h + rpdo − 1, mapping 1600h + rpdo − 1) on COB-ID `cob_id`,
    /// synchronous (every SYNC), starts the node (NMT), enters the mode and enables the drive.
    /// The bus must send SYNC ([`Bus::start_sync`](crate::Bus::start_sync)); the bus sends the
    /// RPDO right before each SYNC ([`Bus::cyclic_pdo`](crate::Bus::cyclic_pdo)), with the
    /// latest set-point [`Csp::send`] gave (at first the position the drive is at), until the
    /// [`Csp`] is dropped.
    ///
    /// A drive whose supported drive modes (6502h) lack cyclic synchronous position fails at
    /// once, before anything is written; the AKD, whose 6502h leaves out the mode it runs,
    /// passes with its sidecar ([`with_sidecar`](Self::with_sidecar)).
    pub async fn cyclic_position(&self, rpdo: u16, cob_id: u16) -> Result<Csp, Error> {
        self.check_mode(mode::CYCLIC_SYNC_POSITION).await?;
        let k = rpdo.clamp(1, 512) - 1;
        // 607Ah, 32 bits, synchronous (transmission type 1).
        let wrap = |index, sub, e| self.error(index, sub, AxisErrorKind::Sdo(Box::new(e)));
        crate::remote::remap(&self.node, 0x1400 + k, u32::from(cob_id & 0x7FF), &[0x607A_0020], Some(1), wrap).await?;
        let field =
            PdoField { entry: MapEntry { index: TARGET_POSITION, sub: 0, bits: 32 }, data_type: DataType::Integer32 };
        let mapping =
            PdoMapping::from_fields(Direction::Receive, &[field]).map_err(|error| Error::Pdo { cob_id, error })?;
        // The set-point to start from: where the drive is.
        let here = self.position().await?;
        self.set(TARGET_POSITION, 0, here).await?;
        self.node.start().await?;
        self.set_mode(mode::CYCLIC_SYNC_POSITION).await?;
        self.enable().await?;
        let events = self.interrupts();
        let pdo = self.node.bus().cyclic_pdo(cob_id, mapping, &[PdoValue::Signed(i64::from(here))]).await?;
        Ok(Csp { pdo: Some(pdo), syncs: self.node.bus().syncs(), node: self.node.id(), events, stopped: None })
    }
}

/// What makes an operation impossible, checked before it starts.
impl Axis {
    /// Fails at once when the drive's supported drive modes (6502h, read once), with the
    /// modes its sidecar adds, lack `mode`. A drive without 6502h (or one that refuses to read
    /// it) is checked against its sidecar's `[[mode]]` list where the axis has one, else not
    /// checked; so are modes 6502h has no bit for (manufacturer-specific ones).
    async fn check_mode(&self, mode: i8) -> Result<(), Error> {
        let cached = *self.supported.lock().unwrap_or_else(|e| e.into_inner());
        let supported = match cached {
            Some(s) => s,
            None => {
                let s = match self.node.read::<u32>(0x6502, 0).await {
                    Ok(v) => Some(v),
                    Err(Error::Sdo { error, .. }) if matches!(error.error, od_runtime::master::SdoError::Server(_)) => {
                        None
                    }
                    Err(e) => return Err(self.error(0x6502, 0, AxisErrorKind::Sdo(Box::new(e)))),
                };
                *self.supported.lock().unwrap_or_else(|e| e.into_inner()) = Some(s);
                s
            }
        };
        match supported {
            Some(supported) => {
                let Some(bit) = crate::error::supported_mode_bit(mode) else { return Ok(()) };
                if (supported | self.modes.added) & bit == 0 {
                    let added = self.modes.added;
                    let kind = AxisErrorKind::Impossible(Impossible::Mode { mode, supported, added });
                    return Err(self.error(0x6502, 0, kind));
                }
            }
            None => {
                if let Some(listed) = &self.modes.listed
                    && !listed.contains(&mode)
                {
                    let kind = AxisErrorKind::Impossible(Impossible::ModeNotListed { mode, listed: listed.clone() });
                    return Err(self.error(MODE, 0, kind));
                }
            }
        }
        Ok(())
    }

    /// Where the drive's position limits are, when statusword bit 11 (internal limit active)
    /// says it is limited: the limit switches of 60FDh (bit 0 negative, bit 1 positive) where
    /// the drive has 60FDh; the software position limits 607Dh (both 0: none) that the
    /// position is at or `target` (where given) is beyond; the limit bits of the drive's own register
    /// ([`with_sidecar`](Self::with_sidecar)). Objects the drive lacks are skipped.
    async fn active_limits(&self, target: Option<i64>) -> Result<Vec<crate::error::Limit>, Error> {
        use crate::error::{Limit, LimitSource};
        use od_sidecar::LimitSide::{Negative, Positive};
        let mut found = Vec::new();
        if let Some(inputs) = self.optional::<u32>(0x60FD, 0).await? {
            for (bit, side) in [(1u32, Positive), (0, Negative)] {
                if inputs & (1 << bit) != 0 {
                    found.push(Limit { side, by: LimitSource::Switch { inputs } });
                }
            }
        }
        if let (Some(min), Some(max)) = (self.optional::<i32>(0x607D, 1).await?, self.optional::<i32>(0x607D, 2).await?)
            && (min, max) != (0, 0)
        {
            let here = i64::from(self.position().await?);
            let (lo, hi) = (i64::from(min.min(max)), i64::from(min.max(max)));
            if here >= hi || target.is_some_and(|t| t > hi) {
                found.push(Limit { side: Positive, by: LimitSource::Software { value: min.max(max) } });
            }
            if here <= lo || target.is_some_and(|t| t < lo) {
                found.push(Limit { side: Negative, by: LimitSource::Software { value: min.min(max) } });
            }
        }
        if let Some(reg) = &self.register
            && !reg.limits.is_empty()
            && let Ok(bytes) = self.node.read_bytes(reg.index, reg.sub).await
            && (1..=4).contains(&bytes.len())
        {
            let mut b = [0u8; 4];
            b[..bytes.len()].copy_from_slice(&bytes);
            let value = u32::from_le_bytes(b);
            for &(bit, side) in &reg.limits {
                if value & (1 << bit) != 0 {
                    let text = reg.text(bit).unwrap_or_default().to_owned();
                    found.push(Limit { side, by: LimitSource::Register { index: reg.index, sub: reg.sub, bit, text } });
                }
            }
        }
        Ok(found)
    }

    /// A read of an object the drive may lack: `None` when it aborts the read.
    async fn optional<T: SdoValue>(&self, index: u16, sub: u8) -> Result<Option<T>, Error> {
        match self.node.read::<T>(index, sub).await {
            Ok(v) => Ok(Some(v)),
            Err(Error::Sdo { error, .. }) if matches!(error.error, od_runtime::master::SdoError::Server(_)) => Ok(None),
            Err(e) => Err(self.error(index, sub, AxisErrorKind::Sdo(Box::new(e)))),
        }
    }

    /// Where `planned` goes from here.
    async fn heading(&self, planned: Planned) -> Result<Heading, Error> {
        Ok(match planned {
            Planned::Velocity(v) => Heading { sign: i64::from(v).signum(), target: None, from: None, velocity: true },
            Planned::Relative(d) => Heading { sign: i64::from(d).signum(), target: None, from: None, velocity: false },
            Planned::Position(t) => {
                let here = i64::from(self.position().await?);
                let t = i64::from(t);
                Heading { sign: (t - here).signum(), target: Some(t), from: Some(here), velocity: false }
            }
        })
    }

    /// Fails at once when the drive is limited (statusword bit 11) by the limit `planned`
    /// goes into; a move away from it passes. Remembers `planned` for the waits that follow.
    async fn check_limits(&self, planned: Planned) -> Result<(), Error> {
        *self.heading.lock().unwrap_or_else(|e| e.into_inner()) = Some(planned);
        // A statusword read within the last poll period (by the operation before) is as good
        // as a new one; a bit 11 that comes up later is seen by the move's wait.
        let sw = match self.last_statusword() {
            Some((sw, at)) if at.elapsed() < self.config.poll => sw,
            _ => self.statusword().await?,
        };
        if sw & SW_INTERNAL_LIMIT == 0 {
            return Ok(());
        }
        let heading = self.heading(planned).await?;
        if heading.sign == 0 {
            return Ok(());
        }
        if let Some(limit) = self.active_limits(None).await?.into_iter().find(|l| l.side == side_of(heading.sign)) {
            let what = heading.describe();
            let (index, sub) = limit_object(&limit);
            return Err(self
                .explained(index, sub, AxisErrorKind::Impossible(Impossible::IntoLimit { limit, what }))
                .await);
        }
        Ok(())
    }

    /// Fails at once when the move's profile velocity, or else the drive's 6081h, is 0.
    async fn check_velocity(&self, m: &Move) -> Result<(), Error> {
        let velocity = match m.velocity {
            Some(v) => v,
            None => self.read::<u32>(0x6081, 0).await?,
        };
        if velocity == 0 {
            return Err(self.error(0x6081, 0, AxisErrorKind::Impossible(Impossible::NoProfileVelocity)));
        }
        Ok(())
    }
}

/// The limit a move of direction `sign` (non-zero) goes into.
fn side_of(sign: i64) -> od_sidecar::LimitSide {
    if sign > 0 { od_sidecar::LimitSide::Positive } else { od_sidecar::LimitSide::Negative }
}

/// The object that says which limit it is, for the error.
fn limit_object(limit: &crate::error::Limit) -> (u16, u8) {
    use crate::error::LimitSource;
    match &limit.by {
        LimitSource::Switch { .. } => (0x60FD, 0),
        LimitSource::Software { .. } => (0x607D, if limit.side == od_sidecar::LimitSide::Positive { 2 } else { 1 }),
        LimitSource::Register { index, sub, .. } => (*index, *sub),
    }
}

/// What, beside a fault, ends a wait before its timeout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Guard {
    /// A state change: only a fault.
    State,
    /// A homing: the drive left Operation enabled. Not statusword bits 7 and 11 nor EMCYs:
    /// homing methods on limit switches run into them on purpose.
    Homing,
    /// A set-point or a move: the drive left Operation enabled, statusword bit 11 (internal
    /// limit) or bit 7 (warning) went up, or the drive sent an EMCY other than 0000h.
    Motion,
}

impl Guard {
    fn watch(self, axis: &Axis, before: Option<u16>) -> GuardWatch {
        let emcy = (self == Guard::Motion).then(|| axis.node.bus().events());
        GuardWatch { guard: self, node: axis.node.id(), prev: before, emcy, limit_examined: false }
    }
}

/// What [`GuardWatch::check`] makes of a statusword.
enum Verdict {
    /// Nothing stops the wait.
    Go,
    /// This stops it.
    Stop(StopReason),
    /// Statusword bit 11 is set and has not been looked into since it came up (or since the
    /// wait started): which limit it is decides ([`Axis::limit_verdict`]).
    Limited {
        /// It came up during the wait.
        rose: bool,
        /// Bit 7 (warning) came up with it.
        warning_rose: bool,
    },
}

/// A [`Guard`] over one wait: the statusword it started with, and the bus's events.
struct GuardWatch {
    guard: Guard,
    node: u8,
    /// The statusword before this one (at first the one before the command, if given).
    prev: Option<u16>,
    emcy: Option<broadcast::Receiver<Event>>,
    /// Bit 11 is set and was looked into; cleared when it drops.
    limit_examined: bool,
}

impl GuardWatch {
    /// Why the wait should stop, given the statusword just read. Bit 7 (warning) counts when
    /// it goes up during the wait: a warning standing at its start is the drive's standing
    /// condition (a temperature warning, the limit switch a move is leaving), not a reason to
    /// stop a move the drive took. Bit 11 (internal limit) is looked into whenever it is set
    /// and was not looked into since it came up ([`Verdict::Limited`]).
    fn check(&mut self, sw: u16) -> Verdict {
        let prev = self.prev.replace(sw).unwrap_or(sw);
        if self.guard == Guard::State {
            return Verdict::Go;
        }
        let state = State::from_statusword(sw);
        if state != Some(State::OperationEnabled) {
            return Verdict::Stop(StopReason::LeftOperationEnabled(state));
        }
        if self.guard == Guard::Homing {
            return Verdict::Go;
        }
        if let Some(events) = &mut self.emcy {
            loop {
                match events.try_recv() {
                    Ok(Event::Emergency { emcy, text }) if emcy.node == self.node && emcy.code != 0 => {
                        return Verdict::Stop(StopReason::Emergency { code: emcy.code, text });
                    }
                    Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) => {}
                    Err(_) => break,
                }
            }
        }
        let rose = |bit: u16| sw & bit != 0 && prev & bit == 0;
        if sw & SW_INTERNAL_LIMIT == 0 {
            self.limit_examined = false;
        } else if !self.limit_examined {
            self.limit_examined = true;
            return Verdict::Limited { rose: rose(SW_INTERNAL_LIMIT), warning_rose: rose(SW_WARNING) };
        }
        if rose(SW_WARNING) {
            return Verdict::Stop(StopReason::Warning);
        }
        Verdict::Go
    }
}

/// A CiA 402 drive whose positions are quantities ([`Axis::with_units`]):
/// `axis.move_to(Quantity::deg(720))`. A position of the wrong dimension does not compile; one
/// in a unit the drive is not set up for (mm to a drive in degrees) is an
/// [`Error::Unit`] before anything is sent.
#[derive(Debug)]
pub struct UnitAxis {
    axis: Axis,
    units: Arc<dyn Scaling>,
}

impl UnitAxis {
    /// The axis in raw units.
    pub fn axis(&self) -> &Axis {
        &self.axis
    }

    /// The conversions.
    pub fn units(&self) -> &dyn Scaling {
        &*self.units
    }

    fn raw(&self, q: Quantity<dim::Position>) -> Result<i32, Error> {
        let unit = |error| Error::Unit { node: self.axis.node.id(), index: TARGET_POSITION, sub: 0, error };
        let raw = self.units.to_raw(od_sidecar::Dimension::Position, q.value(), q.unit()).map_err(unit)?;
        i32::try_from(raw).map_err(|_| unit(UnitError::OutOfRange))
    }

    fn physical(&self, raw: i32) -> Result<Quantity<dim::Position>, Error> {
        let (value, unit) = self
            .units
            .to_physical(od_sidecar::Dimension::Position, i64::from(raw))
            .map_err(|error| Error::Unit { node: self.axis.node.id(), index: POSITION_ACTUAL, sub: 0, error })?;
        Ok(Quantity::from_ratio(value, unit))
    }

    /// To Operation enabled ([`Axis::enable`]).
    pub async fn enable(&self) -> Result<(), Error> {
        self.axis.enable().await
    }

    /// Homes the drive ([`Axis::home`]); the position at the end.
    pub async fn home(&self, homing: impl Into<Homing>) -> Result<Quantity<dim::Position>, Error> {
        let raw = self.axis.home(homing).await?;
        self.physical(raw)
    }

    /// The position actual value (6064h).
    pub async fn position(&self) -> Result<Quantity<dim::Position>, Error> {
        let raw = self.axis.position().await?;
        self.physical(raw)
    }

    /// A profile-position move to `target` with the drive's own speeds, to its end; the
    /// position actual value at the end.
    pub async fn move_to(&self, target: Quantity<dim::Position>) -> Result<Quantity<dim::Position>, Error> {
        self.move_to_with(target, &Move::default()).await
    }

    /// A profile-position move to `target` with `m`'s parameters (raw), to its end.
    pub async fn move_to_with(
        &self,
        target: Quantity<dim::Position>,
        m: &Move,
    ) -> Result<Quantity<dim::Position>, Error> {
        let raw = self.raw(target)?;
        let at = self.axis.move_to(raw, m).await?;
        self.physical(at)
    }

    /// Hands a set-point over without waiting for the target ([`Axis::set_point`]).
    pub async fn set_point(&self, target: Quantity<dim::Position>, m: &Move) -> Result<(), Error> {
        let raw = self.raw(target)?;
        self.axis.set_point(raw, m).await
    }
}

/// A cyclic synchronous position stream ([`Axis::cyclic_position`]).
#[derive(Debug)]
pub struct Csp {
    /// `None` once stopped: the bus no longer sends it.
    pdo: Option<CyclicPdo>,
    syncs: watch::Receiver<u64>,
    node: u8,
    events: broadcast::Receiver<Event>,
    stopped: Option<Interruption>,
}

impl Csp {
    /// Waits for the next SYNC, then makes `position` the next set-point: the bus sends it
    /// right before the SYNC after, and the drive takes it at that SYNC. Returns the number of
    /// SYNCs sent so far.
    ///
    /// A drive that rebooted (it forgot its mapping), was lost, or whose link went down stops
    /// the stream at once: no more set-points are sent, and this and every later call fail
    /// with [`Interruption`].
    pub async fn send(&mut self, position: i32) -> Result<u64, Error> {
        loop {
            self.check()?;
            tokio::select! {
                changed = self.syncs.changed() => {
                    changed.map_err(|_| Error::Closed)?;
                    break;
                }
                event = self.events.recv() => {
                    if let Some(why) = interruption(self.node, event) {
                        self.stop(why);
                    }
                }
            }
        }
        self.check()?;
        let n = *self.syncs.borrow_and_update();
        match &self.pdo {
            Some(pdo) => pdo.set(&[PdoValue::Signed(i64::from(position))]).await?,
            None => return self.check().map(|()| n),
        }
        Ok(n)
    }

    /// Why the stream stopped, if it did.
    pub fn stopped(&self) -> Option<&Interruption> {
        self.stopped.as_ref()
    }

    fn stop(&mut self, why: Interruption) {
        // Dropping the cyclic PDO takes it off the bus from the next SYNC.
        self.pdo = None;
        self.stopped.get_or_insert(why);
    }

    /// Takes the events that came in; an error once stopped.
    fn check(&mut self) -> Result<(), Error> {
        loop {
            match self.events.try_recv() {
                Ok(event) => {
                    if let Some(why) = interruption(self.node, Ok(event)) {
                        self.stop(why);
                    }
                }
                Err(broadcast::error::TryRecvError::Lagged(_)) => {}
                Err(_) => break,
            }
        }
        match &self.stopped {
            None => Ok(()),
            Some(why) => Err(Error::Axis(Box::new(AxisError {
                node: self.node,
                state: None,
                statusword: None,
                seen: None,
                index: TARGET_POSITION,
                sub: 0,
                kind: AxisErrorKind::Interrupted(why.clone()),
                register: None,
            }))),
        }
    }
}

// Supervision (issue #35): operations that end at once when the drive reboots, is lost or its
// link goes down; explicit recovery; an opt-in recovery policy.

/// What a bus event means for an operation on `node`, if it ends it.
fn interruption(node: u8, event: Result<Event, broadcast::error::RecvError>) -> Option<Interruption> {
    match event {
        Ok(Event::Node(NodeEvent::BootUp { node: n })) if n == node => Some(Interruption::Rebooted),
        Ok(Event::Node(NodeEvent::Lost { node: n })) if n == node => Some(Interruption::Lost),
        Ok(Event::Link(LinkState::Down { reason, .. })) => Some(Interruption::LinkDown(reason)),
        Ok(Event::Link(LinkState::Closed)) | Err(broadcast::error::RecvError::Closed) => {
            Some(Interruption::LinkDown("the bus closed".to_owned()))
        }
        _ => None,
    }
}

/// The time a drive needs between the two controlword writes of a fault reset (0 then bit 7):
/// at least one drive cycle (1 ms for the drives here), with a margin.
pub const FAULT_RESET_GAP: Duration = Duration::from_millis(2);

/// What an [`Axis`] may do by itself after trouble ([`Axis::keep`]). Opt-in: the default is
/// [`RecoveryPolicy::Never`], since a drive enabled behind the application's back is a hazard
/// (a safe-torque-off input low at power-up makes every automatic enable fail anyway).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RecoveryPolicy {
    /// Report only; the application calls [`Axis::recover`].
    #[default]
    Never,
    /// After a reboot (once the supervisor has configured it again), re-select the mode and
    /// enable it. Faults are left to the application.
    ReenableAfterReboot,
    /// After a fault, a fault reset and enable, at most `attempts` times, waiting `backoff`
    /// before the first and twice as long before each next one; then it gives up and reports.
    FaultReset {
        /// Attempts in all.
        attempts: u32,
        /// Wait before the first attempt (doubled each time).
        backoff: Duration,
    },
}

/// What went wrong with a drive, for [`recovery_step`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trouble {
    /// It rebooted.
    Rebooted,
    /// It went to Fault.
    Fault,
}

/// What the policy says to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecoveryStep {
    /// Nothing (the application acts).
    Nothing,
    /// Recover after this wait.
    Recover {
        /// Wait first.
        after: Duration,
    },
    /// The attempts are used up: report and stop trying.
    GiveUp,
}

/// The step for `trouble` under `policy` after `tried` attempts already made for it: a pure
/// function, no I/O, no clock.
pub fn recovery_step(policy: RecoveryPolicy, trouble: Trouble, tried: u32) -> RecoveryStep {
    match (policy, trouble) {
        (RecoveryPolicy::ReenableAfterReboot, Trouble::Rebooted) if tried == 0 => {
            RecoveryStep::Recover { after: Duration::ZERO }
        }
        (RecoveryPolicy::ReenableAfterReboot, Trouble::Rebooted) => RecoveryStep::GiveUp,
        (RecoveryPolicy::FaultReset { attempts, backoff }, Trouble::Fault) => {
            if tried >= attempts {
                RecoveryStep::GiveUp
            } else {
                RecoveryStep::Recover { after: backoff.saturating_mul(1u32 << tried.min(16)) }
            }
        }
        _ => RecoveryStep::Nothing,
    }
}

/// What [`Axis::keep`] reports.
#[derive(Debug)]
pub enum AxisReport {
    /// The drive is enabled again after `trouble`, at attempt `attempt` (1-based).
    Recovered {
        /// What happened to it.
        trouble: Trouble,
        /// The attempt that worked.
        attempt: u32,
    },
    /// An attempt failed.
    AttemptFailed {
        /// What happened to it.
        trouble: Trouble,
        /// The attempt (1-based).
        attempt: u32,
        /// Why it failed.
        error: Error,
    },
    /// No more attempts: the drive stays as it is until the application acts.
    GaveUp {
        /// What happened to it.
        trouble: Trouble,
        /// Attempts made.
        attempts: u32,
    },
}

impl Axis {
    /// The bus events from now on, for an operation to end at once on trouble.
    fn interrupts(&self) -> broadcast::Receiver<Event> {
        self.node.bus().events()
    }

    /// Waits one poll period, or less when the drive reboots, is lost or the link goes down.
    /// The events already received: an error when one of them ends the operation.
    fn interrupted(&self, interrupts: &mut broadcast::Receiver<Event>) -> Result<(), Error> {
        loop {
            let event = match interrupts.try_recv() {
                Ok(event) => Ok(event),
                Err(broadcast::error::TryRecvError::Lagged(_)) => continue,
                Err(broadcast::error::TryRecvError::Empty) => return Ok(()),
                Err(broadcast::error::TryRecvError::Closed) => Err(broadcast::error::RecvError::Closed),
            };
            if let Some(why) = interruption(self.node.id(), event) {
                return Err(self.error(STATUSWORD, 0, AxisErrorKind::Interrupted(why)));
            }
        }
    }

    async fn pause(&self, interrupts: &mut broadcast::Receiver<Event>) -> Result<(), Error> {
        let sleep = tokio::time::sleep(self.config.poll);
        tokio::pin!(sleep);
        loop {
            tokio::select! {
                () = &mut sleep => return Ok(()),
                event = interrupts.recv() => {
                    if matches!(event, Err(broadcast::error::RecvError::Lagged(_))) {
                        continue;
                    }
                    if let Some(why) = interruption(self.node.id(), event) {
                        return Err(self.error(STATUSWORD, 0, AxisErrorKind::Interrupted(why)));
                    }
                }
            }
        }
    }

    /// A fault reset as CiA 402 asks: controlword bit 7 low, at least one drive cycle
    /// ([`FAULT_RESET_GAP`]), then high (the rising edge), and the statusword confirming that
    /// the drive left Fault within the state timeout; else the fault with its error code
    /// (603Fh). Nothing when the drive is not in Fault.
    pub async fn fault_reset(&self) -> Result<(), Error> {
        let mut sw = self.statusword().await?;
        if State::from_statusword(sw) == Some(State::FaultReactionActive) {
            sw = self
                .wait("the end of the fault reaction", self.config.state_timeout, |sw| {
                    State::from_statusword(sw) != Some(State::FaultReactionActive)
                })
                .await?;
        }
        if State::from_statusword(sw) != Some(State::Fault) {
            return Ok(());
        }
        self.controlword(0x0000).await?;
        tokio::time::sleep(FAULT_RESET_GAP).await;
        self.controlword(0x0080).await?;
        let end = Instant::now() + self.config.state_timeout;
        loop {
            tokio::time::sleep(FAULT_RESET_GAP).await;
            let sw = self.statusword().await?;
            if State::from_statusword(sw) != Some(State::Fault) {
                return self.controlword(0x0000).await;
            }
            if Instant::now() >= end {
                let error_code = self.error_code().await;
                return Err(self.error(CONTROLWORD, 0, AxisErrorKind::Fault { error_code }));
            }
        }
    }

    /// Brings the drive back after a reboot or a fault, explicitly: [`fault_reset`](Self::fault_reset)
    /// (Self::fault_reset) if it is in Fault, then mode `mode` (6060h, confirmed by 6061h),
    /// then [`enable`](Self::enable).
    pub async fn recover(&self, mode: i8) -> Result<(), Error> {
        self.fault_reset().await?;
        self.set_mode(mode).await?;
        self.enable().await
    }

    /// Applies `policy` by itself from now on, in a task: after a reboot (once the node says
    /// Operational again: the supervisor configured it) or a fault (an EMCY with a non-zero
    /// code), [`recover`](Self::recover) with `mode` as [`recovery_step`] says; every attempt
    /// and its outcome goes to the returned channel. The task ends when the receiver is
    /// dropped or the bus closes. With [`RecoveryPolicy::Never`] it only reports nothing.
    pub fn keep(self: Arc<Self>, policy: RecoveryPolicy, mode: i8) -> mpsc::Receiver<AxisReport> {
        let (tx, rx) = mpsc::channel(16);
        let mut events = self.interrupts();
        tokio::spawn(async move {
            let node = self.node.id();
            let mut tried: std::collections::HashMap<&'static str, u32> = Default::default();
            let mut rebooted = false;
            loop {
                let trouble = match events.recv().await {
                    Ok(Event::Node(NodeEvent::BootUp { node: n })) if n == node => {
                        rebooted = true;
                        tried.insert("reboot", 0);
                        continue;
                    }
                    Ok(Event::Node(NodeEvent::StateChanged {
                        node: n, to: od_runtime::NmtState::Operational, ..
                    })) if n == node && rebooted => {
                        rebooted = false;
                        Trouble::Rebooted
                    }
                    Ok(Event::Emergency { emcy, .. }) if emcy.node == node && emcy.code != 0 => Trouble::Fault,
                    Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => continue,
                    Err(broadcast::error::RecvError::Closed) => return,
                };
                let key = if trouble == Trouble::Rebooted { "reboot" } else { "fault" };
                loop {
                    let n = tried.get(key).copied().unwrap_or(0);
                    let report = match recovery_step(policy, trouble, n) {
                        RecoveryStep::Nothing => break,
                        RecoveryStep::GiveUp => {
                            if n != u32::MAX {
                                let _ = tx.send(AxisReport::GaveUp { trouble, attempts: n }).await;
                            }
                            // Reported once; quiet until a reboot starts afresh.
                            tried.insert(key, u32::MAX);
                            break;
                        }
                        RecoveryStep::Recover { after } => {
                            tokio::time::sleep(after).await;
                            tried.insert(key, n.saturating_add(1));
                            match self.recover(mode).await {
                                Ok(()) => AxisReport::Recovered { trouble, attempt: n + 1 },
                                Err(error) => AxisReport::AttemptFailed { trouble, attempt: n + 1, error },
                            }
                        }
                    };
                    let failed = matches!(report, AxisReport::AttemptFailed { .. });
                    if tx.send(report).await.is_err() {
                        return;
                    }
                    if !failed {
                        break;
                    }
                }
                // The EMCYs of the attempts made are not new faults.
                while events.try_recv().is_ok_and(|e| matches!(e, Event::Emergency { .. })) {}
            }
        });
        rx
    }
}

#[cfg(test)]
mod recovery_tests {
    use super::*;

    #[test]
    fn recovery_steps() {
        let ms = Duration::from_millis;
        let bounded = RecoveryPolicy::FaultReset { attempts: 3, backoff: ms(10) };
        #[rustfmt::skip]
        let table: &[(RecoveryPolicy, Trouble, u32, RecoveryStep)] = &[
            (RecoveryPolicy::Never, Trouble::Rebooted, 0, RecoveryStep::Nothing),
            (RecoveryPolicy::Never, Trouble::Fault, 0, RecoveryStep::Nothing),
            (RecoveryPolicy::ReenableAfterReboot, Trouble::Rebooted, 0, RecoveryStep::Recover { after: ms(0) }),
            (RecoveryPolicy::ReenableAfterReboot, Trouble::Rebooted, 1, RecoveryStep::GiveUp),
            (RecoveryPolicy::ReenableAfterReboot, Trouble::Fault, 0, RecoveryStep::Nothing),
            (bounded, Trouble::Fault, 0, RecoveryStep::Recover { after: ms(10) }),
            (bounded, Trouble::Fault, 1, RecoveryStep::Recover { after: ms(20) }),
            (bounded, Trouble::Fault, 2, RecoveryStep::Recover { after: ms(40) }),
            (bounded, Trouble::Fault, 3, RecoveryStep::GiveUp),
            (bounded, Trouble::Fault, u32::MAX, RecoveryStep::GiveUp),
            (bounded, Trouble::Rebooted, 0, RecoveryStep::Nothing),
        ];
        for &(policy, trouble, tried, want) in table {
            assert_eq!(recovery_step(policy, trouble, tried), want, "{policy:?} {trouble:?} {tried}");
        }
    }
}
