//! The common CiA 402 drive: [`Cia402App`] runs a [`drive::motion::Axis`](crate::motion::Axis)
//! behind any generated dictionary, and [`Vendor`] is where a device adds what its manual says.
//!
//! # How a tick and an event flow
//!
//! * **Events** ([`DriveApp::on_event`]), in the order od-runtime raised them:
//!   * every event first lets the drive *follow the state machine* (power stage on entering
//!     Operation enabled, quick stop ramp entering Quick stop active, fault reaction entering
//!     Fault reaction active, off in the other states, fault reset leaving Fault);
//!   * `Written 6040h` applies the controlword's operation-mode bits (4, 5, 6, 8, 9) as
//!     [`Command`]s; `Written 6060h` changes the axis' mode; `Written 607Ah/60FFh/6071h`
//!     the targets; a write of a configuration object (2000h..5FFFh, the profile parameters)
//!     is read into the axis at once (with [`Vendor::configure`]) and the actual values are
//!     written again, so a unit change shows in the next read;
//!   * heartbeat or guarding loss raises the device's fieldbus-disconnection error, once per
//!     loss; it stays latched (Fault) when the link comes back, until a fault reset;
//!   * a SYNC in interpolated position mode queues 60C1h sub 1 and starts the next segment;
//!   * then [`Vendor::on_event`] sees the event (it may also consume it before the drive does,
//!     see [`Vendor::pre_event`]);
//!   * last, the statusword bits the drive owns are computed again, so what a command changed
//!     (set-point acknowledge, target reached of a new target velocity) is visible at once.
//! * **Ticks** (every 1 ms): follow the state, reconfigure if stale, [`Vendor::before_step`],
//!   [`Axis::step`](crate::motion::Axis::step) by the elapsed time, report a finished quick stop
//!   or fault reaction to od-runtime (its ramp has ended: the axis stands, or it is blocked and
//!   its demand is at rest), write the actual values ([`Vendor::actual_values`] for the
//!   device's own), [`Vendor::after_step`],
//!   statusword bits 7, 8, 10..15 ([`Vendor::statusword`]), and a trace sample.
//!
//! # Units
//!
//! The axis runs in the device's *internal* units: whatever the vendor's [`Vendor::configure`]
//! sets up in [`AxisConfig::units`](crate::motion::AxisConfig) (for the DRVI, its default
//! Table 6.2 units). [`BusScale`] converts bus values to internal ones; a device whose bus unit
//! can change (DRVI feed converter 2001h, AKD factor group) returns it from
//! [`Vendor::scale`], and every object the common layer reads or writes goes through it.

use std::marker::PhantomData;
use std::sync::Arc;

use od_runtime::cia402::State;
use od_runtime::od::{AbortCode, MappedHandle, ObjectDictionary, decode_int};
use od_runtime::{Event, Micros, ResetKind, WriteSource};

use super::{ErrorSpec, ErrorTable, Reaction, SharedTrace};
use crate::motion::{
    Axis, AxisConfig, CommandError, Direction, HomingKind, HomingMethod, HomingSignal, JogCommand, Mode,
    QuickStopOption, Ratio, SetPoint, SoftwareLimits, Status, StopRamp,
};
use crate::node::{Ctx, DefaultApp, DriveApp, LossRecord, WriteRequest};
use crate::trace::Sample;

/// Statusword bits the drive (not the state machine) owns: 7 warning, 8 manufacturer, 10 target
/// reached, 11 internal limit active, 12 and 13 mode-specific, 14 and 15 manufacturer.
pub const STATUSWORD_APP_BITS: u16 = 0xFD80;

/// Controlword bit 4: new set-point / homing operation start / enable interpolation.
pub const CW_NEW_SET_POINT: u16 = 1 << 4;
/// Controlword bit 5: change set immediately.
pub const CW_CHANGE_IMMEDIATELY: u16 = 1 << 5;
/// Controlword bit 6: absolute (0) / relative (1).
pub const CW_RELATIVE: u16 = 1 << 6;
/// Controlword bit 8: halt.
pub const CW_HALT: u16 = 1 << 8;
/// Controlword bit 9: change on set-point.
pub const CW_CHANGE_ON_SET_POINT: u16 = 1 << 9;

// ---------------------------------------------------------------------------------------------
// Dictionary access by index, for any dictionary.

/// Reads an integer entry of any dictionary (up to 8 bytes), sign-extended for signed types.
/// `None` when the entry is missing or not an integer.
pub fn read_int<OD: ObjectDictionary + ?Sized>(od: &OD, index: u16, sub: u8) -> Option<i64> {
    let info = od.info(index, sub).ok()?;
    if !info.data_type.is_integer() || info.byte_len() > 8 {
        return None;
    }
    let mut b = [0u8; 8];
    let n = od.read(index, sub, &mut b).ok()?;
    i64::try_from(decode_int(&b[..n], info.data_type.is_signed())).ok()
}

/// Writes an integer entry of any dictionary without side effects (no events, no PDO rules),
/// saturating `value` to the entry's type. Returns false when the entry is missing, not an
/// integer, or refused the value (its limits).
pub fn write_int<OD: ObjectDictionary + ?Sized>(od: &mut OD, index: u16, sub: u8, value: i64) -> bool {
    let Ok(info) = od.info(index, sub) else { return false };
    let len = info.byte_len();
    if !info.data_type.is_integer() || len == 0 || len > 8 {
        return false;
    }
    let bits = (len * 8) as u32;
    let v = if info.data_type.is_signed() {
        let (lo, hi) =
            if bits == 64 { (i64::MIN, i64::MAX) } else { (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1) };
        value.clamp(lo, hi)
    } else {
        let hi = if bits == 64 { i64::MAX } else { (1i64 << bits) - 1 };
        value.clamp(0, hi)
    };
    od.write(index, sub, &v.to_le_bytes()[..len]).is_ok()
}

// ---------------------------------------------------------------------------------------------
// Units.

/// `value × num / den`, rounded half away from zero, saturated to `i64`. A ratio with a zero
/// or negative term counts as 1/1 (as [`Ratio::factor`] does).
pub fn scale_i64(value: i64, r: Ratio) -> i64 {
    if r.num <= 0 || r.den <= 0 || r.num == r.den {
        return value;
    }
    let n = i128::from(value) * i128::from(r.num);
    let d = i128::from(r.den);
    let q = n / d;
    let rem = n % d;
    let q = if 2 * rem.abs() >= d { q + n.signum() } else { q };
    i64::try_from(q).unwrap_or(if q < 0 { i64::MIN } else { i64::MAX })
}

fn recip(r: Ratio) -> Ratio {
    Ratio::new(r.den, r.num)
}

fn sat_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

fn sat_u32(v: i64) -> u32 {
    v.clamp(0, i64::from(u32::MAX)) as u32
}

/// Internal units per bus unit, per dimension: `internal = bus × ratio`. The identity unless
/// the device's bus unit is configurable (DRVI 2001h, AKD 6091h/6092h/204Ch).
///
/// Ratios are magnitudes (a motion [`Ratio`] has no sign). A bus unit that counts against the
/// motor's direction (AKD 204Ch with one negative term: "changes the resolution *and the
/// direction*", 6.5.2.1) sets [`BusScale::reverse_velocity`]: signed velocities are negated on
/// their way in and out, speeds (unsigned magnitudes: profile velocity, limits, windows,
/// homing speeds) are not.
///
/// ```
/// use drive::drives::BusScale;
/// use drive::motion::Ratio;
///
/// let s = BusScale { velocity: Ratio::new(6, 1), reverse_velocity: true, ..BusScale::ONE };
/// assert_eq!(s.velocity_in(10), -60); // 60FFh = 10 turns the motor backwards
/// assert_eq!(s.velocity_out(-60), 10); // and 606Ch reads it as forwards
/// assert_eq!(s.speed_in(10), 60); // 6081h = 10 is a speed of 60, whatever the direction
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusScale {
    /// Positions (6062h, 6064h, 607Ah, 607Ch, 607Dh, 6065h, 6067h, 60F4h, 60C1h).
    pub position: Ratio,
    /// Velocities (606Bh, 606Ch, 606Dh, 606Fh, 607Fh, 6081h, 6099h, 60FFh).
    pub velocity: Ratio,
    /// Signed velocities (60FFh, 606Bh, 606Ch) count against the motor's direction.
    pub reverse_velocity: bool,
    /// Accelerations (6083h, 6084h, 6085h, 609Ah).
    pub acceleration: Ratio,
    /// Torques (6071h, 6072h, 6074h, 6077h, 6087h per second).
    pub torque: Ratio,
}

impl Default for BusScale {
    fn default() -> Self {
        Self::ONE
    }
}

impl BusScale {
    /// Bus units are the internal units.
    pub const ONE: BusScale = BusScale {
        position: Ratio::ONE,
        velocity: Ratio::ONE,
        reverse_velocity: false,
        acceleration: Ratio::ONE,
        torque: Ratio::ONE,
    };

    fn velocity_sign(&self, v: i64) -> i64 {
        if self.reverse_velocity { v.saturating_neg() } else { v }
    }

    /// Bus position → internal.
    pub fn position_in(&self, bus: i64) -> i64 {
        scale_i64(bus, self.position)
    }
    /// Internal position → bus.
    pub fn position_out(&self, internal: i64) -> i64 {
        scale_i64(internal, recip(self.position))
    }
    /// Bus velocity (signed: 60FFh) → internal, direction included.
    pub fn velocity_in(&self, bus: i64) -> i64 {
        self.velocity_sign(scale_i64(bus, self.velocity))
    }
    /// Internal velocity → bus velocity (signed: 606Bh, 606Ch), direction included.
    pub fn velocity_out(&self, internal: i64) -> i64 {
        self.velocity_sign(scale_i64(internal, recip(self.velocity)))
    }
    /// Bus speed (a magnitude: 6081h, 607Fh, 6099h, 606Dh, 606Fh) → internal.
    pub fn speed_in(&self, bus: i64) -> i64 {
        scale_i64(bus, self.velocity)
    }
    /// Bus acceleration → internal.
    pub fn acceleration_in(&self, bus: i64) -> i64 {
        scale_i64(bus, self.acceleration)
    }
    /// Bus torque → internal.
    pub fn torque_in(&self, bus: i64) -> i64 {
        scale_i64(bus, self.torque)
    }
    /// Internal torque → bus.
    pub fn torque_out(&self, internal: i64) -> i64 {
        scale_i64(internal, recip(self.torque))
    }
}

// ---------------------------------------------------------------------------------------------
// The vendor extension point.

/// A motion command the controlword (or a target write) is about to give the axis. Vendors see
/// it in [`Vendor::before_command`] (to refuse it, or change it) and its outcome in
/// [`Vendor::after_command`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Profile position: a new set-point (cw bit 4 rising), target in internal units.
    SetPoint(SetPoint),
    /// Homing: start (cw bit 4 rising in mode 6).
    StartHoming,
    /// Homing: cw bit 4 fell during homing (only with [`Vendor::homing_abort_on_release`]).
    AbortHoming,
    /// Target velocity (60FFh written, or a mode change to profile velocity / jog), internal
    /// units.
    TargetVelocity(i32),
    /// Target torque (6071h written), internal units.
    TargetTorque(i32),
    /// Jog (cw bits 5/6 changed in mode -1).
    Jog(JogCommand),
    /// Interpolated position: cw bit 4 enables or disables interpolation.
    Interpolation(bool),
}

/// What a device adds to the common CiA 402 drive. Every method has a default that is plain
/// CiA 402; a device overrides what its manual does differently.
///
/// Hooks get the common [`Drive`] (axis, scale, raise an error, state) and, where they may act
/// on the device, the [`Ctx`]. Their order in a tick: [`Vendor::before_step`], the axis step,
/// [`Vendor::after_step`], [`Vendor::statusword`].
///
/// ```
/// use drive::drives::{Cia402App, Vendor, error_table};
/// use drive::node::DeviceKind;
/// use generated::drvi::Dictionary;
///
/// /// A DRVI that knows only profile position.
/// struct PositionOnly;
/// impl Vendor<Dictionary> for PositionOnly {
///     fn supports_mode(&self, code: i8) -> bool {
///         code == 1
///     }
/// }
/// let app = Cia402App::<Dictionary, _>::new(PositionOnly, error_table(DeviceKind::Drvi));
/// # let _ = app;
/// ```
#[allow(unused_variables)]
pub trait Vendor<OD>: Send + 'static {
    /// Whether 6060h may take `code` (writes of others are refused with 0609 0030h). Default:
    /// the CiA 402 modes the axis implements (1, 3, 4, 6, 7) and 0.
    fn supports_mode(&self, code: i8) -> bool {
        matches!(code, 0 | 1 | 3 | 4 | 6 | 7)
    }

    /// The homing method a 6098h value selects; `None` refuses the value. Default:
    /// [`HomingMethod::cia402`].
    fn homing_method(&self, code: i8) -> Option<HomingMethod> {
        HomingMethod::cia402(code)
    }

    /// Whether controlword bit 4 falling aborts a homing in progress (AKD) instead of letting
    /// it finish (CiA 402 leaves it to the device; the Camozzi drives let it finish).
    fn homing_abort_on_release(&self) -> bool {
        false
    }

    /// Whether reversed polarity (607Eh bit 7) also reverses the homing methods' directions.
    ///
    /// CiA 402 (607Eh): "the polarity flag shall have no influence on the homing mode": a
    /// method searches the same physical switch in the same physical direction whatever the
    /// polarity, and only the positions it reports are mirrored (default: false). The Camozzi
    /// manuals say the opposite (DRVI 6.3.4.16: the polarity "has an impact to ALL the mode of
    /// operation (homings, positioning, speed, torque)"; DRCS 3.4.15 reverses "the movement
    /// direction"): with `true`, a method runs [`mirrored`], so method 17 ("negative
    /// direction") searches towards the drive's negative positions, the motor's positive side.
    fn polarity_reverses_homing(&self) -> bool {
        false
    }

    /// The error raised when the master's heartbeat or node guarding is lost ("fieldbus
    /// disconnection"): code and manufacturer value, looked up in the error table. Default
    /// 8130h (CiA 301 life guard / heartbeat error).
    fn fieldbus_error(&self) -> (u16, Option<u64>) {
        (0x8130, None)
    }

    /// Whether a lost master (heartbeat or guarding, [`Vendor::fieldbus_error`]) also resets
    /// the communication once the drive is in Fault (DRVI 6.3.2.12, DRCS 3.2.12: "error and
    /// reset the communication"). The error register 1001h and the history 1003h survive the
    /// reset, so the master finds the cause of the Fault. Default: false.
    fn reset_communication_on_link_loss(&self) -> bool {
        false
    }

    /// How the drive stops and what its power stage does on entering a state without
    /// operation (`to`: Switched on, Ready to switch on, Switch on disabled, from `from`).
    /// Default: CiA 402 ([`DisableReaction::cia402`]): 605Ch for disable operation (transition
    /// 5), 605Bh for shutdown (8), the axis coasting otherwise and the power stage off once the
    /// axis stands. A drive whose output stage stays on and holds the axis in Switched on (AKD
    /// 6.4.1.1) returns [`DisableReaction::hold`].
    fn disable_reaction(&self, od: &OD, from: State, to: State) -> DisableReaction
    where
        OD: ObjectDictionary,
    {
        DisableReaction::cia402(od, from, to)
    }

    /// The ramp of a `quick_stop` error's fault reaction. Default: the quick stop deceleration
    /// (6085h, or the profile deceleration without one).
    fn fault_ramp(&self, od: &OD, error: &ErrorSpec) -> StopRamp {
        StopRamp::QuickStopDeceleration
    }

    /// Internal units per bus unit, from the dictionary's current values. Called at every
    /// reconfiguration (after a write at 2000h or above, and after a reset).
    fn scale(&self, od: &OD) -> BusScale {
        BusScale::ONE
    }

    /// Adjusts the axis configuration after the common objects were read into it (internal
    /// units): unit relations ([`AxisConfig::units`]), torque limits, when software limits
    /// apply, homing offset mode and torque threshold, vendor objects.
    fn configure(&mut self, od: &OD, scale: &BusScale, cfg: &mut AxisConfig) {}

    /// After every reset node (defaults and stored values loaded), before any tick: set up the
    /// mechanics ([`Axis::environment_mut`]), restore vendor state.
    fn init(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {}

    /// A write from the bus is about to reach the dictionary (after the common checks): return
    /// an abort code to refuse it.
    fn on_write(&mut self, drive: &Drive, od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        Ok(())
    }

    /// Sees every event before the common drive does; returning true consumes it (the drive
    /// and [`DefaultApp`] then ignore it).
    fn pre_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, event: &Event) -> bool {
        false
    }

    /// Sees every event after the common drive handled it.
    fn on_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, event: &Event) {}

    /// A command is about to go to the axis; return false to refuse it (it is then not given).
    /// `cmd` may be changed (a clipped target).
    fn before_command(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, cmd: &mut Command) -> bool {
        true
    }

    /// The axis' answer to a command that went to it.
    fn after_command(
        &mut self,
        drive: &mut Drive,
        ctx: &mut Ctx<'_, OD>,
        cmd: &Command,
        result: Result<(), CommandError>,
    ) {
    }

    /// Every tick, before the axis steps.
    fn before_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {}

    /// Writes the device's own actual values (in the bus units of [`Drive::scale`]) after the
    /// common ones (6062h, 6064h, 606Bh, 606Ch, 6074h, 6077h, 60F4h): every tick, and at once
    /// after a configuration write that may have changed the units. Values that depend on the
    /// units belong here rather than in [`Vendor::after_step`].
    fn actual_values(&mut self, drive: &Drive, od: &mut OD, status: &Status) {}

    /// Every tick, after the axis stepped and the actual values were written.
    fn after_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {}

    /// Adjusts the statusword bits the drive owns ([`STATUSWORD_APP_BITS`]): `bits` holds the
    /// common ones (10, 11, 12, 13 per mode) on entry.
    fn statusword(&self, drive: &Drive, od: &OD, status: &Status, bits: &mut u16) {}

    /// An SDO upload of `index`/`sub`: `Some` answers it with `buf` instead of the dictionary
    /// (a value a read consumes). Default: `None`.
    fn on_upload(&mut self, drive: &Drive, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<usize> {
        None
    }

    /// A TPDO's data as packed by `map`: change a value whose PDO form differs from its SDO
    /// form. Default: nothing.
    fn on_tpdo(&mut self, drive: &Drive, od: &OD, map: &[MappedHandle], data: &mut [u8; 8]) {}

    /// The drive left Fault (transition 15, by controlword bit 7 or [`Ctx::fault_reset`]);
    /// [`Drive::fault`] still holds the fault being reset.
    fn on_fault_reset(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {}
}

/// `method` seen through a reversed polarity: every direction reversed and the limit switches
/// swapped (the drive's negative limit is the motor's positive one), so it does in the
/// drive's frame what `method` does in the motor's. Edges and index pulses stay as they are,
/// seen in the (reversed) approach direction.
///
/// ```
/// use drive::drives::cia402::mirrored;
/// use drive::motion::HomingMethod;
///
/// // Camozzi 17 (proximity, negative search) mirrored is 18 (positive search).
/// let m17 = HomingMethod::camozzi(17).unwrap();
/// assert_eq!(mirrored(m17).kind, HomingMethod::camozzi(18).unwrap().kind);
/// assert_eq!(mirrored(m17).code, 17, "the 6098h value stays");
/// // CiA 402 method 1 (negative limit switch) mirrored is method 2 (positive limit switch).
/// assert_eq!(mirrored(HomingMethod::cia402(1).unwrap()).kind, HomingMethod::cia402(2).unwrap().kind);
/// ```
pub fn mirrored(method: HomingMethod) -> HomingMethod {
    let flip = |d: Direction| match d {
        Direction::Negative => Direction::Positive,
        Direction::Positive => Direction::Negative,
    };
    let kind = match method.kind {
        HomingKind::CurrentPosition => HomingKind::CurrentPosition,
        HomingKind::Switch { signal, search, approach, edge, index, reverse_at_limit, overshoot_is_error } => {
            HomingKind::Switch {
                signal: match signal {
                    HomingSignal::NegativeLimit => HomingSignal::PositiveLimit,
                    HomingSignal::PositiveLimit => HomingSignal::NegativeLimit,
                    HomingSignal::HomeSwitch => HomingSignal::HomeSwitch,
                },
                search: flip(search),
                approach: flip(approach),
                edge,
                index,
                reverse_at_limit,
                overshoot_is_error,
            }
        }
        HomingKind::EndStop { search, index } => HomingKind::EndStop { search: flip(search), index },
        HomingKind::Index { dir } => HomingKind::Index { dir: flip(dir) },
    };
    HomingMethod { code: method.code, kind }
}

/// What the drive does on entering a state without operation ([`Vendor::disable_reaction`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DisableReaction {
    /// The ramp down; [`StopRamp::Coast`] switches the power stage off at once.
    pub ramp: StopRamp,
    /// The power stage stays on (and is switched on, coming from a state without it) and
    /// holds the axis where the ramp ends; with `Coast` the ramp is the profile deceleration.
    pub hold: bool,
}

impl DisableReaction {
    /// CiA 402: leaving Operation enabled for Switched on (transition 5) ramps as 605Ch says,
    /// for Ready to switch on (8) as 605Bh says (codes 1..=3 of the quick stop options;
    /// absent or 0: coast); any other way in coasts. The power stage goes off.
    pub fn cia402<OD: ObjectDictionary + ?Sized>(od: &OD, from: State, to: State) -> Self {
        let ramp = match (from, to) {
            (State::OperationEnabled, State::SwitchedOn) => read_int(od, 0x605C, 0),
            (State::OperationEnabled, State::ReadyToSwitchOn) => read_int(od, 0x605B, 0),
            _ => None,
        }
        .and_then(|c| StopRamp::from_option_code(c as i16))
        .unwrap_or(StopRamp::Coast);
        Self { ramp, hold: false }
    }

    /// The power stage stays on and holds the axis after ramping down with `ramp`.
    pub fn hold(ramp: StopRamp) -> Self {
        Self { ramp, hold: true }
    }
}

/// The plain CiA 402 device: every [`Vendor`] default.
#[derive(Clone, Copy, Debug, Default)]
pub struct Plain;

impl<OD> Vendor<OD> for Plain {}

// ---------------------------------------------------------------------------------------------
// The common drive state.

/// The error that put the drive in Fault reaction active / Fault.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ActiveFault {
    /// The table entry.
    pub error: ErrorSpec,
    /// When it was raised (µs).
    pub at: Micros,
}

/// How the power stage is being switched off after leaving Operation enabled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stopping {
    /// Nothing pending.
    No,
    /// Ramping down (605Bh/605Ch), then off.
    ThenOff,
}

/// The common drive: the axis and what the CiA 402 layer keeps between events and ticks.
/// Vendors reach it through their hooks.
pub struct Drive {
    axis: Axis,
    errors: Arc<ErrorTable>,
    scale: BusScale,
    state: State,
    mode: Mode,
    mode_code: i8,
    controlword: u16,
    dirty: bool,
    stopping: Stopping,
    quick_stop_reported: bool,
    fault: Option<ActiveFault>,
    last_tick: Option<Micros>,
    status: Status,
    statusword: u16,
    trace: Option<SharedTrace>,
    target_velocity: i32,
    target_torque: i32,
    ticks: u64,
    link_lost: LossRecord,
    /// A lost master asked for a communication reset, done once the drive is in Fault.
    comm_reset_pending: bool,
    /// 1001h and 1003h as they were before that reset, written back after it.
    kept_errors: Option<KeptErrors>,
}

/// The error register and the error history, kept over a communication reset (which restores
/// the communication area, these included, to its power-on values).
#[derive(Clone, Debug, PartialEq, Eq)]
struct KeptErrors {
    register: i64,
    history: Vec<i64>,
}

impl KeptErrors {
    fn read<OD: ObjectDictionary + ?Sized>(od: &OD) -> Self {
        let count = read_int(od, 0x1003, 0).unwrap_or(0).clamp(0, 254) as u8;
        Self {
            register: read_int(od, 0x1001, 0).unwrap_or(0),
            history: (1..=count).map_while(|k| read_int(od, 0x1003, k)).collect(),
        }
    }

    fn write<OD: ObjectDictionary + ?Sized>(&self, od: &mut OD) {
        write_int(od, 0x1001, 0, self.register);
        for (k, v) in self.history.iter().enumerate() {
            write_int(od, 0x1003, (k + 1) as u8, *v);
        }
        write_int(od, 0x1003, 0, self.history.len() as i64);
    }
}

impl Drive {
    fn new(errors: Arc<ErrorTable>) -> Self {
        let axis = Axis::new(AxisConfig::default());
        let status = axis.status();
        Self {
            axis,
            errors,
            scale: BusScale::ONE,
            state: State::NotReadyToSwitchOn,
            mode: Mode::NoMode,
            mode_code: 0,
            controlword: 0,
            dirty: true,
            stopping: Stopping::No,
            quick_stop_reported: false,
            fault: None,
            last_tick: None,
            status,
            statusword: 0,
            trace: None,
            target_velocity: 0,
            target_torque: 0,
            ticks: 0,
            link_lost: LossRecord::default(),
            comm_reset_pending: false,
            kept_errors: None,
        }
    }

    /// The axis.
    pub fn axis(&self) -> &Axis {
        &self.axis
    }

    /// The axis, to command it directly (vendor modes, mechanics, re-referencing).
    pub fn axis_mut(&mut self) -> &mut Axis {
        &mut self.axis
    }

    /// The error table.
    pub fn errors(&self) -> &ErrorTable {
        &self.errors
    }

    /// The bus scale in use.
    pub fn scale(&self) -> BusScale {
        self.scale
    }

    /// The CiA 402 state the drive last followed.
    pub fn state(&self) -> State {
        self.state
    }

    /// The mode of operation the axis runs (from 6061h).
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The 6061h value (also for modes the axis does not implement).
    pub fn mode_code(&self) -> i8 {
        self.mode_code
    }

    /// The controlword as last applied.
    pub fn controlword(&self) -> u16 {
        self.controlword
    }

    /// The axis status after the last tick.
    pub fn status(&self) -> &Status {
        &self.status
    }

    /// The statusword after the last tick.
    pub fn statusword(&self) -> u16 {
        self.statusword
    }

    /// The error that caused the current fault, if any.
    pub fn fault(&self) -> Option<&ActiveFault> {
        self.fault.as_ref()
    }

    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Reads the configuration objects again before the next command or step (vendor objects
    /// changed through [`Ctx::od_mut`] do not raise events).
    pub fn mark_dirty(&mut self) {
        self.dirty = true;
    }

    /// Records a sample into `trace` every tick (`None` stops recording).
    pub fn set_trace(&mut self, trace: Option<SharedTrace>) {
        self.trace = trace;
    }

    /// The trace being recorded.
    pub fn trace(&self) -> Option<&SharedTrace> {
        self.trace.as_ref()
    }

    /// Raises error `code` (with manufacturer value `manufacturer`) as the device's table
    /// says: `quick_stop` and `power_off` errors enter Fault reaction active with an EMCY
    /// carrying the table's register bits and manufacturer bytes; warnings and `none` only send
    /// the EMCY and record it in 1003h. Codes missing from the table are hard errors.
    pub fn raise<OD>(&mut self, ctx: &mut Ctx<'_, OD>, code: u16, manufacturer: Option<u64>) -> ErrorSpec {
        let spec = self.errors.resolve(code, manufacturer);
        self.raise_spec(ctx, &spec);
        spec
    }

    /// Raises a given error (see [`Drive::raise`]).
    pub fn raise_spec<OD>(&mut self, ctx: &mut Ctx<'_, OD>, spec: &ErrorSpec) {
        match spec.reaction {
            Reaction::QuickStop | Reaction::PowerOff => {
                self.fault = Some(ActiveFault { error: spec.clone(), at: ctx.now() });
                ctx.set_fault_with(spec.code, spec.register_bits(), spec.info());
            }
            Reaction::Warning | Reaction::None => ctx.signal_error(spec.code, spec.register_bits(), spec.info()),
        }
    }

    /// Converts the axis' status to the bus values (for the trace and vendors).
    pub fn bus_sample(&self, status: &Status) -> Sample {
        let s = &self.scale;
        Sample {
            time_us: status.time_us,
            mode: self.mode_code,
            statusword: self.statusword,
            position_demand: sat_i32(s.position_out(i64::from(status.position_demand))),
            position_actual: sat_i32(s.position_out(i64::from(status.position_actual))),
            velocity_demand: sat_i32(s.velocity_out(i64::from(status.velocity_demand))),
            velocity_actual: sat_i32(s.velocity_out(i64::from(status.velocity_actual))),
            torque_demand: sat_i32(s.torque_out(i64::from(status.torque_demand))),
            torque_actual: sat_i32(s.torque_out(i64::from(status.torque_actual))),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The app.

/// The common CiA 402 drive application for dictionary `OD` and device behaviour `V`.
///
/// It implements [`DriveApp`], so it plugs into [`Node`](crate::node::Node) and
/// [`Apps`](crate::node::Apps). Events it does not use (RPDO timeouts, NMT) go to a held
/// [`DefaultApp`].
pub struct Cia402App<OD, V> {
    drive: Drive,
    vendor: V,
    default: DefaultApp,
    _od: PhantomData<fn(&OD)>,
}

impl<OD, V> Cia402App<OD, V> {
    /// A drive with device behaviour `vendor` and error table `errors`.
    pub fn new(vendor: V, errors: Arc<ErrorTable>) -> Self {
        Self { drive: Drive::new(errors), vendor, default: DefaultApp::new(), _od: PhantomData }
    }

    /// The common drive state.
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// The common drive state, mutably (tests set up the mechanics through it).
    pub fn drive_mut(&mut self) -> &mut Drive {
        &mut self.drive
    }

    /// The device behaviour.
    pub fn vendor(&self) -> &V {
        &self.vendor
    }

    /// The device behaviour, mutably.
    pub fn vendor_mut(&mut self) -> &mut V {
        &mut self.vendor
    }

    /// Records a trace (see [`Drive::set_trace`]); builder style.
    pub fn with_trace(mut self, trace: SharedTrace) -> Self {
        self.drive.trace = Some(trace);
        self
    }
}

/// Configuration objects the common layer reads (index, sub). Their writes, and any write at
/// 2000h..=5FFFh, make the configuration stale.
fn is_config(index: u16) -> bool {
    matches!(index, 0x2000..=0x5FFF | 0x605A..=0x605E | 0x6065..=0x6070 | 0x6072 | 0x607B..=0x60A4 | 0x60C2 | 0x60C4)
        && !matches!(index, 0x607A)
}

impl<OD: ObjectDictionary, V: Vendor<OD>> Cia402App<OD, V> {
    fn int(od: &OD, index: u16, sub: u8) -> Option<i64> {
        read_int(od, index, sub)
    }

    /// Reads every configuration object into the axis.
    fn reconfigure(&mut self, od: &OD) {
        let d = &mut self.drive;
        d.dirty = false;
        let s = self.vendor.scale(od);
        d.scale = s;
        let mut cfg = d.axis.config().clone();
        let get = |i: u16, sub: u8| Self::int(od, i, sub);
        let vel = |i: u16, sub: u8, default: u32| get(i, sub).map_or(default, |v| sat_u32(s.speed_in(v)));
        let acc = |i: u16, sub: u8, default: u32| get(i, sub).map_or(default, |v| sat_u32(s.acceleration_in(v)));
        let pos = |i: u16, sub: u8, default: u32| get(i, sub).map_or(default, |v| sat_u32(s.position_in(v)));
        let ms = |i: u16, default: u16| get(i, 0).map_or(default, |v| v.clamp(0, i64::from(u16::MAX)) as u16);
        cfg.profile_velocity = vel(0x6081, 0, 0);
        cfg.profile_acceleration = acc(0x6083, 0, 0);
        cfg.profile_deceleration = acc(0x6084, 0, 0);
        cfg.max_profile_velocity = match get(0x607F, 0) {
            Some(v) if v > 0 => sat_u32(s.speed_in(v)),
            _ => u32::MAX,
        };
        cfg.quick_stop_deceleration = acc(0x6085, 0, 0);
        cfg.torque_slope = get(0x6087, 0).map_or(0, |v| sat_u32(s.torque_in(v)));
        cfg.max_torque = match get(0x6072, 0) {
            Some(v) if v > 0 => sat_u32(s.torque_in(v)),
            _ => u32::MAX,
        };
        cfg.position_window = pos(0x6067, 0, u32::MAX);
        cfg.position_window_time_ms = ms(0x6068, 0);
        cfg.velocity_window = vel(0x606D, 0, 0);
        cfg.velocity_window_time_ms = ms(0x606E, 0);
        cfg.velocity_threshold = vel(0x606F, 0, 0);
        cfg.velocity_threshold_time_ms = ms(0x6070, 0);
        cfg.following_error_window = pos(0x6065, 0, u32::MAX);
        cfg.following_error_timeout_ms = ms(0x6066, 0);
        let (min, max) = (get(0x607D, 1), get(0x607D, 2));
        cfg.software_limits = match (min, max) {
            (Some(lo), Some(hi)) => SoftwareLimits {
                enabled: (lo, hi) != (0, 0),
                min: sat_i32(s.position_in(lo)),
                max: sat_i32(s.position_in(hi)),
            },
            _ => SoftwareLimits::default(),
        };
        cfg.reverse_polarity = get(0x607E, 0).is_some_and(|p| p & 0x80 != 0);
        cfg.halt_ramp =
            get(0x605D, 0).and_then(|c| StopRamp::from_option_code(c as i16)).unwrap_or(StopRamp::ProfileDeceleration);
        if let Some(method) =
            get(0x6098, 0).and_then(|c| i8::try_from(c).ok()).and_then(|c| self.vendor.homing_method(c))
        {
            // The axis homes in the motor's own directions whatever 607Eh says (CiA 402); a
            // device whose polarity reverses the homing too searches the mirrored way.
            let mirror = cfg.reverse_polarity && self.vendor.polarity_reverses_homing();
            cfg.homing.method = if mirror { mirrored(method) } else { method };
        }
        cfg.homing.search_speed = vel(0x6099, 1, 0);
        cfg.homing.zero_speed = vel(0x6099, 2, 0);
        cfg.homing.acceleration = acc(0x609A, 0, 0);
        cfg.homing.deceleration = cfg.homing.acceleration;
        cfg.homing.offset = get(0x607C, 0).map_or(0, |v| sat_i32(s.position_in(v)));
        // A homing on the current position (35, 37) moves nowhere, but the axis plans its
        // zero-length move with the homing speeds and never settles when they are 0 (the
        // DRVI's defaults): give it nominal ones.
        if cfg.homing.method.kind == HomingKind::CurrentPosition {
            let h = &mut cfg.homing;
            h.search_speed = h.search_speed.max(1);
            h.zero_speed = h.zero_speed.max(1);
            h.acceleration = h.acceleration.max(1);
            h.deceleration = h.deceleration.max(1);
        }
        if let (Some(v), Some(e)) = (get(0x60C2, 1), get(0x60C2, 2)) {
            // 60C2h: sub 1 × 10^sub 2 seconds.
            let us = (v as f64) * 10f64.powi(e.clamp(-9, 9) as i32 + 6);
            if us.is_finite() && us >= 1.0 {
                cfg.interpolation.period_us = us.min(f64::from(u32::MAX)) as u32;
            }
        }
        if let Some(n) = get(0x60C4, 1).filter(|n| *n > 0) {
            cfg.interpolation.buffer_capacity = n.min(1024) as usize;
        }
        self.vendor.configure(od, &s, &mut cfg);
        *d.axis.config_mut() = cfg;
        // Targets as the dictionary holds them (their bus unit may have changed).
        d.target_velocity = get(0x60FF, 0).map_or(0, |v| sat_i32(s.velocity_in(v)));
        d.target_torque = get(0x6071, 0).map_or(0, |v| sat_i32(s.torque_in(v)));
    }

    fn refresh(&mut self, ctx: &mut Ctx<'_, OD>) {
        if self.drive.dirty {
            self.reconfigure(ctx.od());
            let (v, t) = (self.drive.target_velocity, self.drive.target_torque);
            let _ = self.drive.axis.set_target_velocity(v);
            self.drive.axis.set_target_torque(t);
        }
    }

    /// Gives a command to the axis through the vendor's hooks.
    fn command(&mut self, ctx: &mut Ctx<'_, OD>, mut cmd: Command) {
        if !self.vendor.before_command(&mut self.drive, ctx, &mut cmd) {
            return;
        }
        let axis = &mut self.drive.axis;
        let result = match cmd {
            Command::SetPoint(sp) => axis.new_set_point(sp),
            Command::StartHoming => axis.start_homing(),
            Command::AbortHoming => {
                axis.abort_homing();
                Ok(())
            }
            Command::TargetVelocity(v) => {
                self.drive.target_velocity = v;
                axis.set_target_velocity(v)
            }
            Command::TargetTorque(t) => {
                self.drive.target_torque = t;
                axis.set_target_torque(t);
                Ok(())
            }
            Command::Jog(j) => {
                axis.set_jog(j);
                Ok(())
            }
            Command::Interpolation(on) => {
                axis.set_interpolation_enabled(on);
                Ok(())
            }
        };
        self.vendor.after_command(&mut self.drive, ctx, &cmd, result);
    }

    /// Follows the CiA 402 state od-runtime is in: the power stage and the stop ramps.
    fn follow_state(&mut self, ctx: &mut Ctx<'_, OD>) {
        let Some(now) = ctx.cia402_state() else { return };
        let from = self.drive.state;
        if now == from {
            return;
        }
        self.drive.state = now;
        let d = &mut self.drive;
        match now {
            State::OperationEnabled => {
                // A ramp still running from a disable or quick stop is released: the axis holds
                // where it is and the mode resumes.
                d.stopping = Stopping::No;
                d.axis.release_quick_stop();
                d.axis.set_power(true);
            }
            State::QuickStopActive => {
                d.quick_stop_reported = false;
                let code = Self::int(ctx.od(), 0x605A, 0).unwrap_or(2) as i16;
                let ramp = QuickStopOption::from_code(code).map_or(StopRamp::QuickStopDeceleration, |o| o.ramp);
                if ramp == StopRamp::Coast {
                    d.axis.set_power(false);
                } else {
                    d.axis.quick_stop(ramp);
                }
            }
            State::FaultReactionActive => {
                let ramp = match &d.fault {
                    Some(f) if f.error.reaction == Reaction::QuickStop => self.vendor.fault_ramp(ctx.od(), &f.error),
                    Some(_) => StopRamp::Coast,
                    // A fault od-runtime raised itself: take 605Eh, else a hard stop.
                    None => Self::int(ctx.od(), 0x605E, 0)
                        .and_then(|c| StopRamp::from_option_code(c as i16))
                        .unwrap_or(StopRamp::Coast),
                };
                if ramp == StopRamp::Coast || !d.axis.status().power {
                    d.axis.set_power(false);
                    ctx.fault_reaction_done();
                } else {
                    d.axis.quick_stop(ramp);
                }
            }
            State::Fault => {
                d.stopping = Stopping::No;
                d.axis.set_power(false);
            }
            State::SwitchOnDisabled | State::ReadyToSwitchOn | State::SwitchedOn | State::NotReadyToSwitchOn => {
                let r = self.vendor.disable_reaction(ctx.od(), from, now);
                let powered = d.axis.status().power;
                if r.hold {
                    // The output stage stays on and holds the axis (after ramping down).
                    d.stopping = Stopping::No;
                    if !powered {
                        d.axis.set_power(true);
                    }
                    d.axis.quick_stop(if r.ramp == StopRamp::Coast { StopRamp::ProfileDeceleration } else { r.ramp });
                } else if r.ramp == StopRamp::Coast || !powered {
                    d.stopping = Stopping::No;
                    d.axis.set_power(false);
                } else {
                    d.stopping = Stopping::ThenOff;
                    d.axis.quick_stop(r.ramp);
                }
                if from == State::Fault {
                    // The hook still sees the fault being reset (Drive::fault).
                    self.vendor.on_fault_reset(&mut self.drive, ctx);
                    self.drive.fault = None;
                }
            }
        }
        // What the new state allows may be something the controlword already asks for.
        if now == State::OperationEnabled {
            self.apply_controlword(ctx, true);
        }
    }

    /// Applies the operation-mode bits of the controlword (`fresh`: as if every bit had just
    /// changed, after entering Operation enabled).
    fn apply_controlword(&mut self, ctx: &mut Ctx<'_, OD>, fresh: bool) {
        let cw = Self::int(ctx.od(), 0x6040, 0).unwrap_or(0) as u16;
        // Bit 4 acts on its edges only, also when the drive has just been enabled.
        let prev = self.drive.controlword;
        self.drive.controlword = cw;
        self.refresh(ctx);
        let enabled = self.drive.state == State::OperationEnabled;
        self.drive.axis.set_halt(cw & CW_HALT != 0);
        let rose = cw & CW_NEW_SET_POINT != 0 && prev & CW_NEW_SET_POINT == 0;
        let fell = cw & CW_NEW_SET_POINT == 0 && prev & CW_NEW_SET_POINT != 0;
        match self.drive.mode {
            Mode::ProfilePosition => {
                if rose && enabled {
                    let s = self.drive.scale;
                    let target = Self::int(ctx.od(), 0x607A, 0).unwrap_or(0);
                    let sp = SetPoint {
                        target: sat_i32(s.position_in(target)),
                        relative: cw & CW_RELATIVE != 0,
                        change_immediately: cw & CW_CHANGE_IMMEDIATELY != 0,
                        change_on_set_point: cw & CW_CHANGE_ON_SET_POINT != 0,
                    };
                    self.command(ctx, Command::SetPoint(sp));
                } else if fell {
                    self.drive.axis.release_set_point();
                }
            }
            Mode::Homing => {
                let assigned = Self::int(ctx.od(), 0x6098, 0) != Some(0);
                if rose && enabled && assigned {
                    self.command(ctx, Command::StartHoming);
                } else if fell && self.vendor.homing_abort_on_release() {
                    self.command(ctx, Command::AbortHoming);
                }
            }
            Mode::InterpolatedPosition => {
                if rose || fell || fresh {
                    self.command(ctx, Command::Interpolation(cw & CW_NEW_SET_POINT != 0));
                }
            }
            Mode::Jog => {
                let jog = JogCommand::from_controlword(cw);
                if fresh || jog != JogCommand::from_controlword(prev) {
                    self.command(ctx, Command::Jog(jog));
                }
            }
            Mode::ProfileVelocity | Mode::ProfileTorque | Mode::NoMode => {}
        }
    }

    /// Follows 6061h (od-runtime copies 6060h there when it is written).
    fn apply_mode(&mut self, ctx: &mut Ctx<'_, OD>) {
        let code = Self::int(ctx.od(), 0x6061, 0).or_else(|| Self::int(ctx.od(), 0x6060, 0)).unwrap_or(0);
        let code = i8::try_from(code).unwrap_or(0);
        if code == self.drive.mode_code && Mode::from_code(code) == Some(self.drive.mode) {
            return;
        }
        self.drive.mode_code = code;
        let mode = Mode::from_code(code).filter(|_| self.vendor.supports_mode(code)).unwrap_or(Mode::NoMode);
        self.refresh(ctx);
        self.drive.axis.set_mode(mode);
        self.drive.mode = mode;
        match mode {
            Mode::ProfileVelocity | Mode::Jog => {
                let v = self.drive.target_velocity;
                self.command(ctx, Command::TargetVelocity(v));
            }
            Mode::ProfileTorque => {
                let t = self.drive.target_torque;
                self.command(ctx, Command::TargetTorque(t));
            }
            _ => {}
        }
        if self.drive.state == State::OperationEnabled {
            self.apply_controlword(ctx, true);
        }
    }

    fn handle_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        match event {
            Event::Reset(ResetKind::Node) => {
                let d = &mut self.drive;
                d.dirty = true;
                d.fault = None;
                d.link_lost = LossRecord::default();
                d.comm_reset_pending = false;
                d.kept_errors = None;
                d.stopping = Stopping::No;
                d.controlword = 0;
                d.axis.set_power(false);
                d.state = State::NotReadyToSwitchOn;
                self.refresh(ctx);
                self.vendor.init(&mut self.drive, ctx);
                self.apply_mode(ctx);
            }
            Event::Written { index: 0x6040, sub: 0, .. } => self.apply_controlword(ctx, false),
            Event::Written { index: 0x6060, sub: 0, .. } => self.apply_mode(ctx),
            Event::Written { index: 0x60FF, sub: 0, .. } => {
                let v = Self::int(ctx.od(), 0x60FF, 0).unwrap_or(0);
                let v = sat_i32(self.drive.scale.velocity_in(v));
                self.command(ctx, Command::TargetVelocity(v));
            }
            Event::Written { index: 0x6071, sub: 0, .. } => {
                let t = Self::int(ctx.od(), 0x6071, 0).unwrap_or(0);
                let t = sat_i32(self.drive.scale.torque_in(t));
                self.command(ctx, Command::TargetTorque(t));
            }
            // A configuration write takes effect at once: a unit change (DRVI 2001h, 2014h; AKD
            // factor group) shows in the actual values the master reads next, not a tick later.
            Event::Written { index, .. } if is_config(index) => {
                self.drive.dirty = true;
                self.refresh(ctx);
                let status = self.status_now();
                self.write_actuals(ctx, &status);
            }
            // One error per loss: od-runtime reports a lost link again while it stays lost.
            Event::HeartbeatTimeout { node } => {
                let bit = 1u128 << (node & 0x7F);
                if self.drive.link_lost.heartbeats & bit == 0 {
                    self.drive.link_lost.heartbeats |= bit;
                    self.link_lost(ctx);
                }
            }
            Event::LifeGuardingLost if !self.drive.link_lost.guarding => {
                self.drive.link_lost.guarding = true;
                self.link_lost(ctx);
            }
            // The error stays latched until a fault reset; the link is watched again.
            Event::HeartbeatStarted { node, .. } => self.drive.link_lost.heartbeats &= !(1u128 << (node & 0x7F)),
            Event::LifeGuardingResumed => self.drive.link_lost.guarding = false,
            Event::Reset(ResetKind::Communication) => {
                self.drive.dirty = true;
                self.drive.link_lost = LossRecord::default();
                if let Some(kept) = self.drive.kept_errors.take() {
                    kept.write(ctx.od_mut());
                }
            }
            Event::Sync { .. } if self.drive.mode == Mode::InterpolatedPosition => {
                if let Some(p) = Self::int(ctx.od(), 0x60C1, 1) {
                    let p = sat_i32(self.drive.scale.position_in(p));
                    let _ = self.drive.axis.push_interpolation_point(p);
                }
                self.drive.axis.sync();
            }
            // The drive completes quick stops and fault reactions itself (in tick).
            Event::Cia402(_) => {}
            other => self.default.on_event(ctx, other),
        }
    }

    fn link_lost(&mut self, ctx: &mut Ctx<'_, OD>) {
        let (code, m) = self.vendor.fieldbus_error();
        self.drive.raise(ctx, code, m);
        self.drive.comm_reset_pending |= self.vendor.reset_communication_on_link_loss();
        self.follow_state(ctx);
    }

    fn write_actuals(&mut self, ctx: &mut Ctx<'_, OD>, status: &Status) {
        let s = self.drive.scale;
        let od = ctx.od_mut();
        let p = |v: i32| s.position_out(i64::from(v));
        let v = |x: i32| s.velocity_out(i64::from(x));
        let t = |x: i32| s.torque_out(i64::from(x));
        write_int(od, 0x6062, 0, p(status.position_demand));
        write_int(od, 0x6064, 0, p(status.position_actual));
        write_int(od, 0x6063, 0, i64::from(status.position_actual));
        write_int(od, 0x606B, 0, v(status.velocity_demand));
        write_int(od, 0x606C, 0, v(status.velocity_actual));
        write_int(od, 0x6074, 0, t(status.torque_demand));
        write_int(od, 0x6077, 0, t(status.torque_actual));
        write_int(od, 0x60F4, 0, p(status.following_error));
        self.vendor.actual_values(&self.drive, ctx.od_mut(), status);
    }

    /// The axis' status as of now: [`Axis::status`] with target reached in the velocity modes
    /// checked against the target in force. The axis re-evaluates its velocity window only
    /// when it steps, so right after a new 60FFh (or a jog command) it would still report the
    /// old target as reached until the next tick.
    fn status_now(&self) -> Status {
        let mut status = self.drive.axis.status();
        let cfg = self.drive.axis.config();
        let commanded = self.drive.state == State::OperationEnabled && self.drive.controlword & CW_HALT == 0;
        let target = match self.drive.mode {
            Mode::ProfileVelocity => Some(i64::from(self.drive.target_velocity)),
            Mode::Jog => {
                let v = i64::from(self.drive.target_velocity).abs();
                Some(match status.jog {
                    crate::motion::JogState::Positive => v,
                    crate::motion::JogState::Negative => -v,
                    crate::motion::JogState::Off => 0,
                })
            }
            _ => None,
        };
        if let Some(target) = target.filter(|_| commanded) {
            let cap = i64::from(cfg.max_profile_velocity);
            let off = (target.clamp(-cap, cap) - i64::from(status.velocity_actual)).abs();
            status.target_reached &= off <= i64::from(cfg.velocity_window);
        }
        status
    }

    /// Statusword bits 10..13 as CiA 402 defines them for the mode.
    fn common_bits(&self, status: &Status) -> u16 {
        let bit = |on: bool, n: u16| if on { 1 << n } else { 0 };
        let mut bits = bit(status.target_reached && status.power, 10) | bit(status.internal_limit_active, 11);
        bits |= match self.drive.mode {
            Mode::ProfilePosition => bit(status.set_point_acknowledge, 12) | bit(status.following_error_exceeded, 13),
            Mode::ProfileVelocity => {
                // The axis' zero-speed timer counts from 0, so with 6070h = 0 it reads "standing"
                // even while moving: check the speed against 606Fh here as well.
                let threshold = i64::from(self.drive.axis.config().velocity_threshold);
                bit(status.zero_speed && i64::from(status.velocity_actual).abs() <= threshold, 12)
            }
            Mode::Homing => {
                let (reached, attained, error) = status.homing.statusword_bits(status.standing);
                // Bit 10 in homing follows the homing state, also while the power is off.
                (bits & !(1 << 10)) | bit(reached, 10) | bit(attained, 12) | bit(error, 13)
            }
            Mode::InterpolatedPosition => {
                bit(status.interpolation_active, 12) | bit(status.following_error_exceeded, 13)
            }
            Mode::Jog => {
                use crate::motion::JogState;
                match status.jog {
                    JogState::Positive => 1 << 12,
                    JogState::Negative => 1 << 13,
                    JogState::Off => 0,
                }
            }
            Mode::ProfileTorque | Mode::NoMode => 0,
        };
        bits
    }

    /// Sets the statusword bits the drive owns from `status`.
    fn publish(&mut self, ctx: &mut Ctx<'_, OD>, status: &Status) {
        let mut bits = self.common_bits(status);
        self.vendor.statusword(&self.drive, ctx.od(), status, &mut bits);
        ctx.set_statusword_flags(STATUSWORD_APP_BITS, bits);
        self.drive.statusword = Self::int(ctx.od(), 0x6041, 0).unwrap_or(0) as u16;
        self.drive.status = *status;
    }

    fn run_tick(&mut self, ctx: &mut Ctx<'_, OD>) {
        self.follow_state(ctx);
        self.refresh(ctx);
        self.vendor.before_step(&mut self.drive, ctx);
        let now = ctx.now();
        let dt = self.drive.last_tick.map_or(0, |t| now.saturating_sub(t));
        self.drive.last_tick = Some(now);
        if dt > 0 {
            self.drive.axis.step(u32::try_from(dt).unwrap_or(u32::MAX));
        }
        self.drive.ticks += 1;
        let status = self.drive.axis.status();
        // Stops the state machine waits for.
        match self.drive.state {
            State::QuickStopActive if !self.drive.quick_stop_reported && stop_ended(&status) => {
                self.drive.quick_stop_reported = true;
                ctx.quick_stop_done();
            }
            State::FaultReactionActive if stop_ended(&status) => {
                self.drive.axis.set_power(false);
                ctx.fault_reaction_done();
            }
            _ if self.drive.stopping == Stopping::ThenOff && stop_ended(&status) => {
                self.drive.stopping = Stopping::No;
                self.drive.axis.set_power(false);
            }
            _ => {}
        }
        self.follow_state(ctx);
        let status = self.status_now();
        self.write_actuals(ctx, &status);
        self.vendor.after_step(&mut self.drive, ctx, &status);
        if self.drive.comm_reset_pending && self.drive.state == State::Fault {
            self.drive.comm_reset_pending = false;
            self.drive.kept_errors = Some(KeptErrors::read(ctx.od()));
            ctx.nmt_command(od_runtime::NmtCommand::ResetCommunication);
        }
        self.publish(ctx, &status);
        if let Some(trace) = &self.drive.trace {
            let sample = self.drive.bus_sample(&status);
            if let Ok(mut t) = trace.lock() {
                t.push(Sample { time_us: now, ..sample });
            }
        }
    }
}

impl<OD: ObjectDictionary, V: Vendor<OD>> DriveApp<OD> for Cia402App<OD, V> {
    fn on_write(&mut self, od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        match (write.index, write.sub, write.data) {
            (0x6060, 0, &[code]) if !self.vendor.supports_mode(code as i8) => return Err(AbortCode::INVALID_VALUE),
            // 0 is CiA 402's "no homing method assigned": the default a drive reports (AKD
            // 6.10.2.2) can be written back; a homing started with it starts nothing.
            (0x6098, 0, &[code]) if code != 0 && self.vendor.homing_method(code as i8).is_none() => {
                return Err(AbortCode::INVALID_VALUE);
            }
            _ => {}
        }
        self.vendor.on_write(&self.drive, od, write)
    }

    fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        if self.vendor.pre_event(&mut self.drive, ctx, &event) {
            return;
        }
        if !matches!(event, Event::Reset(ResetKind::Node)) {
            self.follow_state(ctx);
        }
        self.handle_event(ctx, event);
        self.vendor.on_event(&mut self.drive, ctx, &event);
        // What the event changed (a command's set-point acknowledge, a new target's bit 10, a
        // homing started, a state left) is in the statusword at once, not only after the next
        // tick: a master reading 6041h (or a TPDO sampled) right after sees it.
        let status = self.status_now();
        self.publish(ctx, &status);
    }

    fn tick(&mut self, ctx: &mut Ctx<'_, OD>) {
        self.run_tick(ctx);
    }

    fn on_upload(&mut self, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<Result<usize, AbortCode>> {
        self.vendor.on_upload(&self.drive, od, index, sub, buf).map(Ok)
    }

    fn on_tpdo(&mut self, od: &OD, map: &[MappedHandle], data: &mut [u8; 8]) {
        self.vendor.on_tpdo(&self.drive, od, map, data);
    }

    /// EMCY 8220h when the device's error table lists it (DRVI table 6.34).
    fn rpdo_length_exceeded(&mut self, _pdo: u16) -> bool {
        self.drive.errors.find(od_runtime::emcy::PDO_LENGTH_EXCEEDED, None).is_some()
    }
}

/// Whether a stop ramp (quick stop, fault reaction, disable) has ended: the power stage is
/// off, the axis stands on its demand, or the demand has come to rest and the axis does not
/// move although it is not on it (blocked against an end stop, held by a load it cannot move:
/// it never settles on the demand, and the drive must not wait for it forever).
fn stop_ended(status: &Status) -> bool {
    !status.power || status.standing || (status.velocity_demand == 0 && status.velocity_actual == 0)
}

/// Whether a write came from the bus (SDO or RPDO) rather than the device itself.
pub fn from_bus(source: WriteSource) -> bool {
    matches!(source, WriteSource::Sdo | WriteSource::Rpdo(_))
}
