//! The application side of a simulated device: the [`DriveApp`] trait, the [`Ctx`] it acts
//! through, and [`DefaultApp`], the behaviour every device gets when nothing more specific is
//! plugged in.

use od_runtime::cia402::{self, State};
use od_runtime::emcy;
use od_runtime::od::{AbortCode, MappedHandle, ObjectDictionary};
use od_runtime::{Event, Micros, NmtCommand, NmtState, NodeId, WriteSource};

use super::Retain;

/// A write on its way to the dictionary, as [`DriveApp::on_write`] sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteRequest<'a> {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value, little-endian, exactly as received; for an SDO download its length and the
    /// entry's limits have been checked (the dictionary's checks come first, so a value of
    /// the wrong size is a length error whatever the application would say of it); an RPDO
    /// entry has its entry's size by construction.
    pub data: &'a [u8],
    /// An SDO download, an RPDO, or a local write.
    pub source: WriteSource,
}

impl WriteRequest<'_> {
    /// The value as an unsigned integer (up to 8 bytes, little-endian, zero-extended).
    pub fn as_u64(&self) -> u64 {
        let mut b = [0u8; 8];
        let n = self.data.len().min(8);
        b[..n].copy_from_slice(&self.data[..n]);
        u64::from_le_bytes(b)
    }
}

/// The behaviour of a simulated device: vendor-specific rules, the motion model, whatever a
/// real drive does beyond the CiA 301/402 services od-runtime implements.
///
/// A [`Node`](super::Node) calls the application in three ways:
///
/// | hook | when | with |
/// |---|---|---|
/// | [`on_write`](DriveApp::on_write) | before a write from the bus (SDO, RPDO) reaches the dictionary, synchronously | the dictionary, read-only; return an abort code to refuse the write |
/// | [`on_event`](DriveApp::on_event) | after the frame or poll that caused the event, in order | a [`Ctx`]: the dictionary and the device's services |
/// | [`tick`](DriveApp::tick) | every [`tick_period`](DriveApp::tick_period) µs (1 ms by default) | a [`Ctx`] |
///
/// Every method has a default, so an application implements only what it needs. The standard
/// reactions of [`DefaultApp`] (completing a quick stop or a fault reaction, reporting a lost
/// heartbeat by EMCY) are kept by holding a `DefaultApp` and passing it the events the
/// application does not handle itself:
///
/// ```
/// use drive::node::{Ctx, DefaultApp, DriveApp, WriteRequest};
/// use od_runtime::od::{AbortCode, MappedHandle, ObjectDictionary};
/// use od_runtime::Event;
///
/// /// A drive whose actual position follows the target position, one step per millisecond.
/// #[derive(Default)]
/// struct Follower {
///     base: DefaultApp,
/// }
///
/// impl<OD: ObjectDictionary> DriveApp<OD> for Follower {
///     fn on_write(&mut self, _od: &OD, w: &WriteRequest<'_>) -> Result<(), AbortCode> {
///         // Modes other than profile position (1) are refused.
///         if w.index == 0x6060 && w.data != [1] {
///             return Err(AbortCode::INVALID_VALUE);
///         }
///         Ok(())
///     }
///
///     fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
///         // Keep the standard reactions (quick stop and fault reaction complete at once,
///         // heartbeat and guarding loss reported by EMCY).
///         self.base.on_event(ctx, event);
///     }
///
///     fn tick(&mut self, ctx: &mut Ctx<'_, OD>) {
///         let target = ctx.read_i64(0x607A, 0).unwrap_or(0);
///         let actual = ctx.read_i64(0x6064, 0).unwrap_or(0);
///         let next = actual + (target - actual).signum();
///         let _ = ctx.od_mut().write(0x6064, 0, &(next as i32).to_le_bytes());
///     }
/// }
/// ```
///
/// Events are delivered after od-runtime has acted on them: a `Written` event comes after the
/// value is in the dictionary, a `Cia402` transition after the statusword changed, a `Sync`
/// after the TPDOs were sampled. Device services the application calls from `on_event` or
/// `tick` (say [`Ctx::set_fault`]) produce further events, which are delivered right after.
///
/// Applications live on the device's thread: `drive-sim` needs them to be `Send`.
pub trait DriveApp<OD> {
    /// Called before a write from a master (SDO download or RPDO) reaches the dictionary.
    /// Returning an error refuses it: the SDO transfer aborts with that code, an RPDO entry
    /// is skipped. Access rights have been checked, and for an SDO download the length and the
    /// entry's limits too. Writes the application makes itself through [`Ctx::write`] are not
    /// shown here.
    fn on_write(&mut self, od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        let _ = (od, write);
        Ok(())
    }

    /// Called for every [`Event`] of the device, in order. The default does nothing; hold a
    /// [`DefaultApp`] and pass it the events you do not handle to keep the standard reactions
    /// (without them a quick stop or a fault reaction never completes).
    fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        let _ = (ctx, event);
    }

    /// Periodic work (the motion model, timers of vendor behaviour), every
    /// [`tick_period`](DriveApp::tick_period). `ctx.now()` is the time of this tick; a node
    /// that fell behind (a blocked thread) skips ticks rather than running them in a burst, so
    /// compute time steps from `ctx.now()`.
    fn tick(&mut self, ctx: &mut Ctx<'_, OD>) {
        let _ = ctx;
    }

    /// Microseconds between two [`tick`](DriveApp::tick)s; 0 disables ticking. Read once,
    /// when the node is built. Default: 1000 (1 kHz, the control cycle of the drives
    /// simulated here).
    fn tick_period(&self) -> Micros {
        1000
    }

    /// An SDO upload is about to read `index`/`sub`: `Some` answers it with what is put in
    /// `buf` instead of the dictionary's value (od-runtime's [`od_runtime::App::on_upload`]).
    /// Default: `None`.
    fn on_upload(&mut self, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<Result<usize, AbortCode>> {
        let _ = (od, index, sub, buf);
        None
    }

    /// A TPDO's data, packed from the dictionary by `map`, before it is sent: change the bits
    /// of a value whose PDO form differs from its SDO form. Default: nothing.
    fn on_tpdo(&mut self, od: &OD, map: &[MappedHandle], data: &mut [u8; 8]) {
        let _ = (od, map, data);
    }

    /// RPDO `pdo` (0-based) arrived longer than its mapping (it is processed anyway): `true`
    /// sends EMCY 8220h. Default: `false`.
    fn rpdo_length_exceeded(&mut self, pdo: u16) -> bool {
        let _ = pdo;
        false
    }
}

impl<OD, A: DriveApp<OD> + ?Sized> DriveApp<OD> for Box<A> {
    fn on_write(&mut self, od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        (**self).on_write(od, write)
    }

    fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        (**self).on_event(ctx, event)
    }

    fn tick(&mut self, ctx: &mut Ctx<'_, OD>) {
        (**self).tick(ctx)
    }

    fn tick_period(&self) -> Micros {
        (**self).tick_period()
    }

    fn on_upload(&mut self, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<Result<usize, AbortCode>> {
        (**self).on_upload(od, index, sub, buf)
    }

    fn on_tpdo(&mut self, od: &OD, map: &[MappedHandle], data: &mut [u8; 8]) {
        (**self).on_tpdo(od, map, data)
    }

    fn rpdo_length_exceeded(&mut self, pdo: u16) -> bool {
        (**self).rpdo_length_exceeded(pdo)
    }
}

/// What [`Ctx`] needs from a device: implemented by od-runtime's `Device` for any storage,
/// buffer size and PDO count, so applications do not carry those type parameters.
pub(crate) trait DeviceOps<OD> {
    fn od(&self) -> &OD;
    fn od_mut(&mut self) -> &mut OD;
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
    fn node_id(&self) -> NodeId;
    fn nmt_state(&self) -> NmtState;
    fn nmt_command(&mut self, cmd: NmtCommand, now: Micros);
    fn cia402_state(&self) -> Option<State>;
    fn set_fault(&mut self, code: u16);
    fn set_fault_with(&mut self, code: u16, register: u8, info: [u8; 5]);
    fn fault_reset(&mut self);
    fn fault_reaction_done(&mut self);
    fn quick_stop_done(&mut self);
    fn set_remote(&mut self, remote: bool);
    fn set_statusword_flags(&mut self, mask: u16, value: u16) -> bool;
    fn signal_error(&mut self, code: u16, register: u8, info: [u8; 5]);
    fn reset_error(&mut self, register: u8);
    fn error_register(&self) -> u8;
    fn request_tpdo(&mut self, n: usize);
    fn reload(&mut self);
}

impl<OD, A, S, const BUF: usize, const PDOS: usize> DeviceOps<OD> for od_runtime::Device<OD, A, S, BUF, PDOS>
where
    OD: ObjectDictionary,
    A: od_runtime::App<OD>,
    S: od_runtime::Storage,
{
    fn od(&self) -> &OD {
        od_runtime::Device::od(self)
    }
    fn od_mut(&mut self) -> &mut OD {
        od_runtime::Device::od_mut(self)
    }
    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        od_runtime::Device::write(self, index, sub, data)
    }
    fn node_id(&self) -> NodeId {
        od_runtime::Device::node_id(self)
    }
    fn nmt_state(&self) -> NmtState {
        od_runtime::Device::nmt_state(self)
    }
    fn nmt_command(&mut self, cmd: NmtCommand, now: Micros) {
        od_runtime::Device::nmt_command(self, cmd, now)
    }
    fn cia402_state(&self) -> Option<State> {
        od_runtime::Device::cia402_state(self)
    }
    fn set_fault(&mut self, code: u16) {
        od_runtime::Device::set_fault(self, code)
    }
    fn set_fault_with(&mut self, code: u16, register: u8, info: [u8; 5]) {
        od_runtime::Device::set_fault_with(self, code, register, info)
    }
    fn fault_reset(&mut self) {
        od_runtime::Device::fault_reset(self)
    }
    fn fault_reaction_done(&mut self) {
        od_runtime::Device::fault_reaction_done(self)
    }
    fn quick_stop_done(&mut self) {
        od_runtime::Device::quick_stop_done(self)
    }
    fn set_remote(&mut self, remote: bool) {
        od_runtime::Device::set_remote(self, remote)
    }
    fn set_statusword_flags(&mut self, mask: u16, value: u16) -> bool {
        od_runtime::Device::set_statusword_flags(self, mask, value)
    }
    fn signal_error(&mut self, code: u16, register: u8, info: [u8; 5]) {
        od_runtime::Device::signal_error(self, code, register, info)
    }
    fn reset_error(&mut self, register: u8) {
        od_runtime::Device::reset_error(self, register)
    }
    fn error_register(&self) -> u8 {
        od_runtime::Device::error_register(self)
    }
    fn request_tpdo(&mut self, n: usize) {
        od_runtime::Device::request_tpdo(self, n)
    }
    fn reload(&mut self) {
        od_runtime::Device::reload(self)
    }
}

/// What an application acts through in [`DriveApp::on_event`] and [`DriveApp::tick`]: the
/// dictionary, the time, and the device's services (faults, EMCY, NMT, CiA 402 reactions).
pub struct Ctx<'a, OD> {
    dev: &'a mut dyn DeviceOps<OD>,
    now: Micros,
    retain: Option<&'a mut dyn Retain>,
}

impl<'a, OD> Ctx<'a, OD> {
    pub(crate) fn new(dev: &'a mut dyn DeviceOps<OD>, now: Micros) -> Self {
        Self { dev, now, retain: None }
    }

    pub(crate) fn with_retain(mut self, retain: &'a mut dyn Retain) -> Self {
        self.retain = Some(retain);
        self
    }

    /// The data the application retained last ([`Ctx::retain`]), in this run or a previous
    /// one (with a state directory), if any.
    pub fn retained(&mut self) -> Option<Vec<u8>> {
        self.retain.as_mut().and_then(|r| r.load())
    }

    /// Keeps `data` across power cycles, outside the dictionary (what a drive saves by itself,
    /// like the DRVI's position at power-off, 5.0.3): atomically, in the node's
    /// [`Retain`] backend. An error (a full disk) is returned, not raised on the bus.
    pub fn retain(&mut self, data: &[u8]) -> std::io::Result<()> {
        match self.retain.as_mut() {
            Some(r) => r.store(data),
            None => Err(std::io::Error::other("this context has no retained data")),
        }
    }

    /// The time of the call that led here (µs on the node's clock).
    pub fn now(&self) -> Micros {
        self.now
    }

    /// The node id.
    pub fn node_id(&self) -> NodeId {
        self.dev.node_id()
    }

    /// The dictionary. Generated dictionaries have typed getters (`od.statusword()`).
    pub fn od(&self) -> &OD {
        self.dev.od()
    }

    /// The dictionary, for the application's own values (actual position, velocity, input
    /// states, statusword bits 8..15). Writes here have no side effects: no events, no PDO
    /// rules, no CiA 402 transitions. Changing a communication parameter (1000h..1FFFh) this
    /// way needs [`Ctx::reload`]; prefer [`Ctx::write`] for those.
    pub fn od_mut(&mut self) -> &mut OD {
        self.dev.od_mut()
    }

    /// Writes an object as the device itself would: with the runtime's checks and side effects
    /// (PDO rules, CiA 402 state machine on 6040h, store/restore on 1010h/1011h) and a
    /// `Written` event with [`WriteSource::Local`], but without access-right checks and without
    /// the application's own [`DriveApp::on_write`].
    pub fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.dev.write(index, sub, data)
    }

    /// Reads an integer entry (up to 8 bytes), sign-extended when its type is signed. `None`
    /// for entries that do not exist or are not integers.
    pub fn read_i64(&self, index: u16, sub: u8) -> Option<i64>
    where
        OD: ObjectDictionary,
    {
        let info = self.od().info(index, sub).ok()?;
        if !info.data_type.is_integer() || info.byte_len() > 8 {
            return None;
        }
        let mut b = [0u8; 8];
        let n = self.od().read(index, sub, &mut b).ok()?;
        i64::try_from(od_runtime::od::decode_int(&b[..n], info.data_type.is_signed())).ok()
    }

    /// The NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.dev.nmt_state()
    }

    /// Runs an NMT command locally (a device that starts by itself sends itself `Start`).
    pub fn nmt_command(&mut self, cmd: NmtCommand) {
        let now = self.now;
        self.dev.nmt_command(cmd, now)
    }

    /// The CiA 402 state, if the dictionary has 6040h and 6041h.
    pub fn cia402_state(&self) -> Option<State> {
        self.dev.cia402_state()
    }

    /// Reports a drive fault: 603Fh = `error_code`, an EMCY, and CiA 402 transition 13 (Fault
    /// reaction active). Finish the fault reaction with [`Ctx::fault_reaction_done`].
    pub fn set_fault(&mut self, error_code: u16) {
        self.dev.set_fault(error_code)
    }

    /// Like [`Ctx::set_fault`], with the EMCY's error register bits and manufacturer-specific
    /// bytes (`info[0]` is EMCY byte 3) as a vendor's error table gives them.
    pub fn set_fault_with(&mut self, error_code: u16, register: u8, info: [u8; 5]) {
        self.dev.set_fault_with(error_code, register, info)
    }

    /// A fault reset from something other than controlword bit 7 (the DRVI's 0 written to
    /// 1003h sub 0): transition 15 from Fault, with 603Fh, 1001h and the error reset EMCY as
    /// for the controlword's. Nothing in other states.
    pub fn fault_reset(&mut self) {
        self.dev.fault_reset()
    }

    /// The fault reaction is complete: transition 14 to Fault.
    pub fn fault_reaction_done(&mut self) {
        self.dev.fault_reaction_done()
    }

    /// The quick stop ramp is complete: transition 12 when 605Ah is 0..=4.
    pub fn quick_stop_done(&mut self) {
        self.dev.quick_stop_done()
    }

    /// Sets statusword bit 9 (remote); while clear, controlword writes from the bus abort with
    /// 0x0800_0021.
    pub fn set_remote(&mut self, remote: bool) {
        self.dev.set_remote(remote)
    }

    /// Sets the application's statusword bits (`mask` selects them; bits 0..=6 and 9 belong to
    /// the state machine and are left alone): target reached (10), internal limit active (11),
    /// the mode-specific bits 12 and 13, warning (7), manufacturer bits 8, 14, 15. Returns
    /// false when the dictionary has no statusword.
    pub fn set_statusword_flags(&mut self, mask: u16, value: u16) -> bool {
        self.dev.set_statusword_flags(mask, value)
    }

    /// Signals an error: 1001h bits, 1003h history and an EMCY `code, 1001h, info`.
    pub fn signal_error(&mut self, code: u16, register: u8, info: [u8; 5]) {
        self.dev.signal_error(code, register, info)
    }

    /// Clears 1001h bits and sends the "error reset" EMCY (code 0000h).
    pub fn reset_error(&mut self, register: u8) {
        self.dev.reset_error(register)
    }

    /// The error register (1001h).
    pub fn error_register(&self) -> u8 {
        self.dev.error_register()
    }

    /// Asks for a transmission of TPDO `n` (0 = the one of 1800h); see od-runtime's
    /// `Device::request_tpdo`.
    pub fn request_tpdo(&mut self, n: usize) {
        self.dev.request_tpdo(n)
    }

    /// Re-reads every communication parameter after [`Ctx::od_mut`] changed one.
    pub fn reload(&mut self) {
        self.dev.reload()
    }
}

/// EMCY error code of a heartbeat or life guarding loss (CiA 301: "life guard error or
/// heartbeat error").
pub const EMCY_HEARTBEAT_OR_GUARDING: u16 = 0x8130;

/// EMCY error code of an RPDO that did not arrive within its event timer (CiA 301: "RPDO
/// timeout").
pub const EMCY_RPDO_TIMEOUT: u16 = 0x8250;

/// The behaviour of a device without application-specific logic: the CiA 402 state machine of
/// od-runtime with instant reactions, and error control losses reported by EMCY.
///
/// * Quick stop active: the quick stop is complete at once (transition 12 for 605Ah 0..=4;
///   the drive stays in Quick stop active for 5..=8, as CiA 402 says).
/// * Fault reaction active: the fault reaction is complete at once (transition 14 to Fault).
/// * A monitored heartbeat (1016h) stops: EMCY 8130h with the node id in the first
///   manufacturer byte, communication bit in 1001h. When it comes back (and no other
///   monitored node is still missing, and guarding is not lost): the error reset EMCY.
/// * Life guarding lost (100Ch × 100Dh without a guarding request): EMCY 8130h with byte 0
///   = 0; cleared the same way when guarding resumes.
/// * An RPDO with deadline monitoring (1400h.. sub 5) stays away: EMCY 8250h with the PDO
///   number (1 = 1400h) in the first manufacturer byte.
/// * Reset node: the loss records are forgotten (1001h was reset by the runtime). Reset
///   communication: outstanding loss reports are withdrawn with an error reset EMCY, as
///   monitoring starts afresh.
///
/// Device behaviours keep these reactions by holding a `DefaultApp` and passing it the events
/// they do not handle themselves (see [`DriveApp`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DefaultApp {
    lost: LossRecord,
}

/// Which error-control losses are being reported.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LossRecord {
    /// Bit n: the heartbeat of node n is missing (reported).
    pub heartbeats: u128,
    /// Life guarding is lost (reported).
    pub guarding: bool,
}

impl DefaultApp {
    /// A default application.
    pub fn new() -> Self {
        Self::default()
    }

    /// The losses currently reported.
    pub fn losses(&self) -> LossRecord {
        self.lost
    }

    /// The standard reaction to `event` (see the type's docs).
    pub fn on_event<OD>(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        let lost = &mut self.lost;
        match event {
            Event::Cia402(cia402::Transition { to: State::QuickStopActive, .. }) => ctx.quick_stop_done(),
            Event::Cia402(cia402::Transition { to: State::FaultReactionActive, .. }) => ctx.fault_reaction_done(),
            Event::HeartbeatTimeout { node } => {
                let bit = 1u128 << (node & 0x7F);
                if lost.heartbeats & bit == 0 {
                    lost.heartbeats |= bit;
                    ctx.signal_error(EMCY_HEARTBEAT_OR_GUARDING, emcy::REG_COMMUNICATION, [node, 0, 0, 0, 0]);
                }
            }
            Event::HeartbeatStarted { node, .. } => {
                let bit = 1u128 << (node & 0x7F);
                if lost.heartbeats & bit != 0 {
                    lost.heartbeats &= !bit;
                    if lost.heartbeats == 0 && !lost.guarding {
                        ctx.reset_error(emcy::REG_COMMUNICATION);
                    }
                }
            }
            Event::LifeGuardingLost if !lost.guarding => {
                lost.guarding = true;
                ctx.signal_error(EMCY_HEARTBEAT_OR_GUARDING, emcy::REG_COMMUNICATION, [0; 5]);
            }
            Event::LifeGuardingResumed if lost.guarding => {
                lost.guarding = false;
                if lost.heartbeats == 0 {
                    ctx.reset_error(emcy::REG_COMMUNICATION);
                }
            }
            Event::RpdoTimeout { pdo } => {
                let number = u8::try_from(pdo.saturating_add(1)).unwrap_or(u8::MAX);
                ctx.signal_error(EMCY_RPDO_TIMEOUT, emcy::REG_COMMUNICATION, [number, 0, 0, 0, 0]);
            }
            Event::Reset(od_runtime::ResetKind::Node) => *lost = LossRecord::default(),
            // Consumers and guarding restart from scratch; the runtime cleared nothing in 1001h,
            // so an outstanding loss report is withdrawn.
            Event::Reset(od_runtime::ResetKind::Communication) if *lost != LossRecord::default() => {
                *lost = LossRecord::default();
                ctx.reset_error(emcy::REG_COMMUNICATION);
            }
            _ => {}
        }
    }
}

impl<OD> DriveApp<OD> for DefaultApp {
    fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        DefaultApp::on_event(self, ctx, event)
    }

    /// The default application has no periodic work.
    fn tick_period(&self) -> Micros {
        0
    }
}
