//! The Camozzi DRVI integrated drive, as its CANopen manual (V1.7) describes it, on top of the
//! common CiA 402 layer ([`super::cia402`]).
//!
//! | manual | behaviour | here |
//! |---|---|---|
//! | Table 6.17 | modes 1, 3, 4, 6, -1 (jog) | [`Vendor::supports_mode`] |
//! | Table 6.2, 6.3.6.10 | units: 2014h = 0 "only motor" 0.01°, 0.01 rpm, rpm/s; otherwise 0.01 mm, 0.01 mm/s, mm/s²; mA, mA/s | [`Vendor::scale`] turns them into the axis' counts; switching 2014h switches them |
//! | 6.3.6.1 | feed converter 2001h: new unit = default × num / den for positions, speeds, accelerations, on SDO and PDOs alike; 0 refused | [`Vendor::scale`] |
//! | 6.3.4.22, 6.3.4.23, 7.5.1 | an actuator (2014h ≠ 0) turns the motor through the screw pitch 6092h (feed / shaft revolutions, × 100: 100/1 = 1 mm per turn) and the gear 6091h (motor / shaft revolutions; the default 0/0 is 1:1): positions, velocities, accelerations, targets, actual values, limits; a change shows in the actual values at once; 0 in 6092h refused | [`actuator_scale`] |
//! | 4.1.2, 6.4 | profile position: bit 4 starts, bit 6 relative to the *actual* position; the target cannot change during a movement (refused, warning "command refused"); homing is mandatory first (refused, warning "homing missing") | [`Vendor::before_command`] |
//! | 4.1.1, 6.5 | profile velocity: bit 12 speed = standing (606Fh/6070h), bit 10 with halt | common layer |
//! | 4.1.3, 6.6, 5.0.2 | profile torque with 6087h; 2015h = 1 limits \|current\| to \|6071h\| in every mode; statusword bit 14 = torque limit active | [`Vendor::configure`], [`Vendor::statusword`] |
//! | 4.1.5, 6.7, Table 6.29 | homing 1, 2, 17, 18, 37, -1..-4 with 6099h, 609Ah, 607Ch (actual position := offset), torque homings limited by 6071h with the 2013h threshold (% of the I²T current); 2004h; homing error = error 8613h/13 (soft) | [`crate::motion::HomingMethod::camozzi`], [`Vendor::after_step`] |
//! | 4.1.4, 6.8 | jog: cw bits 6/5 = cw / ccw, speed \|60FFh\|; sw bits 13/12 | common layer |
//! | 5.0.1, 6.3.4.15 | software limits 607Dh − 607Ch, in force with 2010h = 1 after homing in the actuator configuration: out-of-range targets and speeds above 607Fh refused ("command refused"); the actual position outside = error 6120h (soft), warning bits 6/7; after its reset the check is suspended until the first movement completes; the EXT PROXY input acts the same way | [`Drvi`] |
//! | 6.9, Table 6.34 | errors with the manufacturer byte in EMCY byte 3; soft errors quick-stop, hard ones switch the power stage off | the sidecar's table through [`super::Drive::raise`]; causes from [`Conditions`] (supplies, temperatures, I²T, STO, encoder, short circuit, memory, control, CAN error passive); 8210h/8220h (PDO length) are od-runtime's EMCY only |
//! | 6.9, Table 6.36 | 2006h warnings, latched; "homing missing" and "command refused" reset by themselves; statusword bit 7 while any is set | [`Drvi`] |
//! | 6.9.3 | fault reset by cw bit 7 or 0 written to 1003h sub 0 | [`Vendor::on_event`] |
//! | 6.3.6.2, 6.3.6.3 | inputs 2002h (IN1, IN2, EXT PROXY, PROXY), output 2003h | [`Vendor::after_step`] |
//! | 6.3.6.7 | PID selection 2011h: the position loop's bandwidth | [`Vendor::configure`] |
//! | 6.3.6.8 | profile check 2012h: warnings "target position / speed not reached" after the timeout | [`Vendor::after_step`] |
//! | 6.3.4.16 | polarity 607Eh bit 7 reverses every mode, homing searches included | [`Vendor::polarity_reverses_homing`] |
//! | 5.0.3 | the position survives a reset node, and a power cycle (a restart of the process), when homed and stopped | [`SavedPosition`] kept as the node's retained data ([`Ctx::retain`]: the state directory's `drvi-node<id>.retained`), restored in [`Vendor::init`] |
//!
//! Decisions where the manual is silent or unclear:
//! * the axis counts 0.01° of the motor in every configuration, and a machine's positions are
//!   in that unit (the 6064h unit at power-on, 2014h = 0): an actuator shows them through
//!   6092h and 6091h ([`actuator_scale`]), so a change of the screw pitch moves nothing, it
//!   changes what 6064h reads. The gear ratio applies to the actuator configuration only
//!   (7.5.1 names it with the screw pitch); only motor counts motor degrees. With more than
//!   360 mm of travel a motor turn (7.5.1 allows 2000), a count is more than 0.01 mm: targets
//!   go to the nearest count, and 6064h moves in steps of more than one.
//! * the machine: the DRVI starts as a bare motor turning freely ([`app`], the `free` machine
//!   of [`super::machine`]), as its default 2014h = 0 ("only motor", 6.3.6.10) says; a
//!   Camozzi actuator with the PROXY INPUT proximity and end stops is the `drvi-actuator`
//!   preset ([`actuator_app`]).
//! * a lost guarding master is the fieldbus disconnection error, then a communication reset
//!   (6.3.2.12) that keeps 1001h and 1003h; an RPDO longer than its mapping is EMCY 8220h
//!   (table 6.34) and is processed.
//! * profile velocity applies 60FFh when it is written (CiA 402); the manual's "bit 4 starts the
//!   movement" is also honoured: a rising bit 4 re-applies 60FFh.
//! * statusword bit 11 "ila = internal limits active (software limits enabled)" is set while
//!   the software limit check is in force, as the manual's wording says.
//! * the thermal model: motor and drive temperatures rise with the current squared (+40 °C
//!   and +30 °C at the I²T current of [`I2T_CURRENT_MA`], time constants 60 s and 30 s);
//!   the I²T fault trips after the current stayed above [`I2T_CURRENT_MA`] for an energy of
//!   2 s at twice that current.

use od_runtime::Event;
use od_runtime::od::{AbortCode, ObjectDictionary};

use super::cia402::{BusScale, Cia402App, Command, Vendor, read_int, write_int};
use super::{Drive, error_table};
use crate::motion::{
    Axis, AxisConfig, Cam, CommandError, Environment, HomingMethod, HomingState, Machine, Mode, PlantConfig, Ratio,
    RelativeBase, SoftwareLimits, Status, Units,
};
use crate::node::{Ctx, DeviceKind, WriteRequest};

/// The current of the motor's I²T rating, mA: 2013h is a percentage of it.
pub const I2T_CURRENT_MA: u32 = 5_000;
/// The drive's peak current, mA (the 6071h range).
pub const PEAK_CURRENT_MA: u32 = 15_000;

/// 2006h bits (Table 6.36).
pub mod warning {
    /// VDC under-voltage lockout (< 20 V).
    pub const VDC_UVLO: u16 = 1 << 0;
    /// VDC over-voltage lockout (> 60 V).
    pub const VDC_OVLO: u16 = 1 << 1;
    /// VL under-voltage lockout (< 21 V).
    pub const VL_UVLO: u16 = 1 << 2;
    /// VL over-voltage lockout (> 27 V).
    pub const VL_OVLO: u16 = 1 << 3;
    /// Motor temperature limit (> 75 °C).
    pub const MOTOR_TEMPERATURE: u16 = 1 << 4;
    /// Drive temperature limit (> 75 °C).
    pub const DRIVE_TEMPERATURE: u16 = 1 << 5;
    /// Positive position limit reached.
    pub const POSITIVE_LIMIT: u16 = 1 << 6;
    /// Negative position limit reached.
    pub const NEGATIVE_LIMIT: u16 = 1 << 7;
    /// Homing missing (resets by itself once homed).
    pub const HOMING_MISSING: u16 = 1 << 8;
    /// Target speed not reached.
    pub const SPEED_NOT_REACHED: u16 = 1 << 9;
    /// Target position not reached.
    pub const POSITION_NOT_REACHED: u16 = 1 << 10;
    /// Command refused (resets by itself when a command is accepted).
    pub const COMMAND_REFUSED: u16 = 1 << 11;
    /// The bits that reset by themselves (6.9).
    pub const AUTO_RESET: u16 = HOMING_MISSING | COMMAND_REFUSED;
}

/// What the drive measures around it: supplies, temperatures, safety input, encoder. Tests and
/// demos change these to provoke the errors and warnings of Tables 6.34 and 6.36.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    /// Power supply VBUS/VDC, mV (nominal 48 V).
    pub vbus_mv: u32,
    /// Logic supply VL/VLOG, mV (nominal 24 V).
    pub vlog_mv: u32,
    /// VEXT present.
    pub vext: bool,
    /// The STO hardware enable is present.
    pub hw_enable: bool,
    /// The encoder works.
    pub encoder_ok: bool,
    /// A short circuit in the motor phases or the power stage (over current, 2310h/0).
    pub short_circuit: bool,
    /// The parameter memory is damaged (5530h).
    pub memory_fault: bool,
    /// The control firmware failed (6100h).
    pub control_fault: bool,
    /// The CAN controller is error passive (8120h).
    pub can_error_passive: bool,
    /// Ambient temperature, °C.
    pub ambient_c: f64,
    /// Digital input IN1 (2002h bit 0).
    pub in1: bool,
    /// Digital input IN2 (2002h bit 1).
    pub in2: bool,
}

impl Default for Conditions {
    fn default() -> Self {
        Self {
            vbus_mv: 48_000,
            vlog_mv: 24_000,
            vext: true,
            hw_enable: true,
            encoder_ok: true,
            short_circuit: false,
            memory_fault: false,
            control_fault: false,
            can_error_passive: false,
            ambient_c: 25.0,
            in1: false,
            in2: false,
        }
    }
}

/// A condition-driven error: raised when it appears, again after a reset if it persists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cause {
    VbusOver,
    VlogOver,
    VbusUnder,
    VlogUnder,
    MotorHot,
    DriveHot,
    I2t,
    Vext,
    Sto,
    Encoder,
    OverCurrent,
    Memory,
    Control,
    CanPassive,
}

impl Cause {
    const ALL: [Cause; 14] = [
        Cause::VbusOver,
        Cause::VlogOver,
        Cause::VbusUnder,
        Cause::VlogUnder,
        Cause::MotorHot,
        Cause::DriveHot,
        Cause::I2t,
        Cause::Vext,
        Cause::Sto,
        Cause::Encoder,
        Cause::OverCurrent,
        Cause::Memory,
        Cause::Control,
        Cause::CanPassive,
    ];

    /// Table 6.34: code and manufacturer parameter.
    fn error(self) -> (u16, u64) {
        match self {
            Cause::VbusOver => (0x3110, 0),
            Cause::VlogOver => (0x3110, 1),
            Cause::VbusUnder => (0x3120, 0),
            Cause::VlogUnder => (0x3120, 1),
            Cause::MotorHot => (0x4210, 0),
            Cause::DriveHot => (0x4210, 1),
            Cause::I2t => (0x2310, 11),
            Cause::Vext => (0x5120, 0),
            Cause::Sto => (0x5540, 0),
            Cause::Encoder => (0x7305, 0),
            Cause::OverCurrent => (0x2310, 0),
            Cause::Memory => (0x5530, 0),
            Cause::Control => (0x6100, 0),
            Cause::CanPassive => (0x8120, 0),
        }
    }

    fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

/// The software limit check of 5.0.1.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum LimitCheck {
    /// In force when its conditions hold.
    #[default]
    Normal,
    /// Suspended after the reset of a limit error, until a movement completes.
    Suspended {
        /// The axis has moved since.
        moved: bool,
    },
}

/// The DRVI's behaviour on top of the common CiA 402 drive.
#[derive(Clone, Debug)]
pub struct Drvi {
    /// Supplies, temperatures and inputs the drive sees.
    pub conditions: Conditions,
    /// The machine's inertia on the built-in one ([`Machine::inertia_factor`]).
    inertia_factor: f64,
    /// Motor winding temperature, °C.
    pub motor_c: f64,
    /// Drive (power stage) temperature, °C.
    pub drive_c: f64,
    /// I²T accumulator: (A² − I²T current²)·s above the rating.
    i2t: f64,
    warnings: u16,
    /// Causes currently raised (bit per [`Cause`]).
    raised: u16,
    limit: LimitCheck,
    /// The limit check is in force (2010h = 1, homed, actuator, not suspended).
    limits_active: bool,
    limit_error: bool,
    last_cw: u16,
    last_now: Option<u64>,
    last_dt_us: u64,
    homing_failed: bool,
    position_timer_us: u64,
    speed_timer_us: u64,
    pid_bandwidth: f64,
    /// 5.0.3: the position record last retained, and whether this run has looked for one.
    saved: Option<SavedPosition>,
    restore_done: bool,
}

/// 5.0.3: what the DRVI keeps at power-off: whether it was homed and standing, its actual
/// position, and where the motor stood (so the machine is found where it was).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SavedPosition {
    /// Homed and standing: the position may be restored.
    pub valid: bool,
    /// The actual position in the drive's counts (0.01° of the motor).
    pub position: i32,
    /// The motor's own position (the mechanical frame of the simulated machine).
    pub motor: i64,
}

impl SavedPosition {
    const VERSION: u8 = 1;

    /// The retained bytes: version, valid, position (i32 LE), motor (i64 LE).
    pub fn encode(&self) -> [u8; 14] {
        let mut b = [0u8; 14];
        b[0] = Self::VERSION;
        b[1] = u8::from(self.valid);
        b[2..6].copy_from_slice(&self.position.to_le_bytes());
        b[6..14].copy_from_slice(&self.motor.to_le_bytes());
        b
    }

    /// A record from retained bytes; `None` for anything else.
    pub fn decode(b: &[u8]) -> Option<Self> {
        if b.len() != 14 || b[0] != Self::VERSION || b[1] > 1 {
            return None;
        }
        Some(Self {
            valid: b[1] == 1,
            position: i32::from_le_bytes(b[2..6].try_into().ok()?),
            motor: i64::from_le_bytes(b[6..14].try_into().ok()?),
        })
    }
}

/// The motor's own (mechanical) position. The axis reports positions in the drive's frame
/// (`±motor + offset`, the sign from 607Eh); read under both polarities, the two readings
/// differ by twice the motor position.
fn motor_position(axis: &mut Axis) -> i64 {
    let reversed = axis.config().reverse_polarity;
    let a = i64::from(axis.status().position_actual);
    axis.config_mut().reverse_polarity = !reversed;
    let b = i64::from(axis.status().position_actual);
    axis.config_mut().reverse_polarity = reversed;
    if reversed { (b - a) / 2 } else { (a - b) / 2 }
}

/// `env` moved by `by` along the motor's axis.
fn shifted(env: Environment, by: i64) -> Environment {
    let at = |x: Option<i64>| x.map(|x| x.saturating_add(by));
    let period = i64::try_from(env.index_period).unwrap_or(0);
    Environment {
        home_switch: env.home_switch.map(|c| Cam { low: c.low.saturating_add(by), high: c.high.saturating_add(by) }),
        negative_limit: at(env.negative_limit),
        positive_limit: at(env.positive_limit),
        negative_end_stop: at(env.negative_end_stop),
        positive_end_stop: at(env.positive_end_stop),
        index_period: env.index_period,
        index_phase: if period > 0 { (env.index_phase.saturating_add(by)).rem_euclid(period) } else { env.index_phase },
    }
}

impl Default for Drvi {
    fn default() -> Self {
        Self {
            conditions: Conditions::default(),
            inertia_factor: 1.0,
            motor_c: 25.0,
            drive_c: 25.0,
            i2t: 0.0,
            warnings: 0,
            raised: 0,
            limit: LimitCheck::Normal,
            limits_active: false,
            limit_error: false,
            last_cw: 0,
            last_now: None,
            last_dt_us: 0,
            homing_failed: false,
            position_timer_us: 0,
            speed_timer_us: 0,
            pid_bandwidth: 300.0,
            saved: None,
            restore_done: false,
        }
    }
}

/// Internal position counts per machine unit: the axis counts 0.01° of the motor in every
/// configuration, and a machine's positions are in the unit 6064h shows at power-on with the
/// default parameters (2014h = 0, only motor: 0.01°).
pub const COUNTS_PER_MACHINE_UNIT: f64 = 1.0;

/// Machine units per motor turn (36 000 × 0.01°): the default index period.
pub const MACHINE_UNITS_PER_TURN: f64 = 36_000.0;

/// Internal counts per motor turn: 0.01° (Table 6.2, only motor).
pub const COUNTS_PER_TURN: i64 = 36_000;

/// 2014h = 0: only motor (6.3.6.10); any other value is an actuator (Table 6.2 (**)).
fn only_motor<OD: ObjectDictionary + ?Sized>(od: &OD) -> bool {
    read_int(od, 0x2014, 0).unwrap_or(0) == 0
}

/// A term of 2001h, 6091h or 6092h as the drive uses it: a 0 (6091h's printed default 0/0; a
/// 0 in 2001h or 6092h, which the drive refuses over the bus, can only come from a parameter
/// file) counts as 1.
fn term<OD: ObjectDictionary + ?Sized>(od: &OD, index: u16, sub: u8) -> u64 {
    read_int(od, index, sub).filter(|v| *v > 0).map_or(1, |v| v.unsigned_abs())
}

fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// `num / den` (both ≥ 1) as the motion model's ratio: in lowest terms, exact when both terms
/// then fit an `i64`. Otherwise (only for 6091h/6092h/2001h terms far beyond any screw: the
/// product of three 32-bit terms) the last convergent of its continued fraction whose terms
/// fit, a relative error below 2^-63; a ratio beyond the `i64` range is `i64::MAX` (or its
/// inverse), which saturates every value as the exact one would.
pub fn fit(num: u128, den: u128) -> Ratio {
    let (num, den) = (num.max(1), den.max(1));
    let g = gcd(num, den);
    let (num, den) = (num / g, den / g);
    let max = i64::MAX as u128;
    if num <= max && den <= max {
        return Ratio::new(num as i64, den as i64);
    }
    // Convergents p/q of num/den: p₋₁/q₋₁ = 1/0, p₋₂/q₋₂ = 0/1.
    let (mut p0, mut q0, mut p1, mut q1) = (0u128, 1u128, 1u128, 0u128);
    let (mut n, mut d) = (num, den);
    while d != 0 {
        let a = n / d;
        let next =
            a.checked_mul(p1).and_then(|x| x.checked_add(p0)).zip(a.checked_mul(q1).and_then(|x| x.checked_add(q0)));
        match next {
            Some((p2, q2)) if p2 <= max && q2 <= max => {
                (p0, q0, p1, q1) = (p1, q1, p2, q2);
                (n, d) = (d, n - a * d);
            }
            _ => break,
        }
    }
    match (p1, q1) {
        (_, 0) => Ratio::new(i64::MAX, 1),
        (0, _) => Ratio::new(1, i64::MAX),
        (p, q) => Ratio::new(p as i64, q as i64),
    }
}

/// The actuator configuration (2014h ≠ 0): counts (0.01° of the motor) per bus unit.
///
/// 6092h gives the screw pitch as feed / shaft revolutions in 0.01 mm (6.3.4.23: pitch 1 mm is
/// feed 100 over 1 revolution), 6091h the motor revolutions per shaft revolution (6.3.4.22),
/// 2001h the bus unit (6.3.6.1: bus value = default value × numerator / denominator). So a
/// bus position `p` is `p × den₂₀₀₁/num₂₀₀₁` hundredths of a mm, `× shaft/feed` shaft turns,
/// `× motor/shaft` motor turns, `× 36 000` counts:
///
/// * position (0.01 mm) and velocity (0.01 mm/s): `36 000 × den₂₀₀₁ × motor₆₀₉₁ × shaft₆₀₉₂ /
///   (num₂₀₀₁ × shaft₆₀₉₁ × feed₆₀₉₂)` counts (per second);
/// * acceleration (mm/s², Table 6.2): 100 times that, counts per second².
///
/// Exact (rounded half away from zero per value, as every bus conversion) whenever the reduced
/// ratio fits 64 bits ([`fit`]). The generated `drvi::units` says the same
/// (`Units::internal_factor` = motor revolutions per bus unit); tests hold the two together.
pub fn actuator_scale<OD: ObjectDictionary + ?Sized>(od: &OD) -> BusScale {
    let num = u128::from(term(od, 0x2001, 2))
        * COUNTS_PER_TURN as u128
        * u128::from(term(od, 0x6091, 1))
        * u128::from(term(od, 0x6092, 2));
    let den = u128::from(term(od, 0x2001, 1)) * u128::from(term(od, 0x6091, 2)) * u128::from(term(od, 0x6092, 1));
    let r = fit(num, den);
    BusScale { position: r, velocity: r, acceleration: fit(num * 100, den), ..BusScale::ONE }
}

/// The mechanics of the `drvi-actuator` preset, in 0.01° of the motor: a
/// home proximity (PROXY INPUT) from 20 000 to 25 000, hard end stops at −50 000 and 150 000,
/// an encoder index every 36 000 (one turn) at 1 000, no EXT PROXY. The DRVI starts with a
/// free motor ([`super::machine`]); tests that need the proximity or the end stops take this.
pub fn default_environment() -> Environment {
    actuator_machine().environment(COUNTS_PER_MACHINE_UNIT, MACHINE_UNITS_PER_TURN)
}

fn actuator_machine() -> Machine {
    super::machine::preset(DeviceKind::Drvi, "drvi-actuator").unwrap_or_else(Machine::free)
}

/// The mechanics' constants (torque in mA, positions in 0.01 units): 1 A accelerates the
/// load at 6000 rpm/s; viscous friction balances 1 A at 3000 rpm; 20 mA dry friction; top
/// speed 3000 rpm.
pub fn plant(bandwidth: f64) -> PlantConfig {
    PlantConfig { inertia: 1000.0 / 3.6e6, viscous: 1000.0 / 1.8e6, coulomb: 20.0, bandwidth, max_speed: 1.8e6 }
}

/// A DRVI application on `machine` (positions in 0.01° of the motor).
pub fn app_with(machine: &Machine) -> Cia402App<generated::drvi::Dictionary, Drvi> {
    let drvi = Drvi { inertia_factor: machine.inertia_factor(), ..Drvi::default() };
    let mut app = Cia402App::new(drvi, error_table(DeviceKind::Drvi));
    *app.drive_mut().axis_mut().environment_mut() =
        machine.environment(COUNTS_PER_MACHINE_UNIT, MACHINE_UNITS_PER_TURN);
    app
}

/// A DRVI application on the `drvi-actuator` preset (proximity and end stops): what the
/// tests of homings and limits use.
pub fn actuator_app() -> Cia402App<generated::drvi::Dictionary, Drvi> {
    app_with(&actuator_machine())
}

/// A DRVI application on its default machine: a bare motor turning freely, as its default
/// "only motor" configuration (2014h = 0) says.
pub fn app() -> Cia402App<generated::drvi::Dictionary, Drvi> {
    app_with(&super::machine::default_machine(DeviceKind::Drvi))
}

impl Drvi {
    /// The latched and automatic warning bits (2006h).
    pub fn warnings(&self) -> u16 {
        self.warnings
    }

    /// Whether the software limit check is in force.
    pub fn limits_active(&self) -> bool {
        self.limits_active
    }

    /// Sets warning bits (latched until a reset unless auto-reset).
    pub fn warn(&mut self, bits: u16) {
        self.warnings |= bits;
    }

    /// A reset command (cw bit 7 edge, 0 written to 1003h sub 0): the latched warnings clear;
    /// conditions still present raise again at the next tick.
    fn reset_warnings(&mut self) {
        self.warnings &= warning::HOMING_MISSING;
        self.raised = 0;
        self.homing_failed = false;
        self.position_timer_us = 0;
        self.speed_timer_us = 0;
    }

    fn limits_configured<OD: ObjectDictionary>(od: &OD) -> bool {
        read_int(od, 0x2010, 0).unwrap_or(0) == 1 && read_int(od, 0x2014, 0).unwrap_or(0) != 0
    }

    /// The corrected limits (607Dh − 607Ch), internal units, ordered.
    fn limits<OD: ObjectDictionary>(od: &OD, scale: &BusScale) -> (i64, i64) {
        let offset = read_int(od, 0x607C, 0).unwrap_or(0);
        let lo = read_int(od, 0x607D, 1).unwrap_or(0).saturating_sub(offset);
        let hi = read_int(od, 0x607D, 2).unwrap_or(0).saturating_sub(offset);
        let (lo, hi) = (scale.position_in(lo), scale.position_in(hi));
        (lo.min(hi), lo.max(hi))
    }

    fn thermal(&mut self, current_ma: f64, dt: f64) {
        let i = current_ma / f64::from(I2T_CURRENT_MA);
        let ambient = self.conditions.ambient_c;
        let step = |t: &mut f64, rise: f64, tau: f64| {
            let target = ambient + rise * i * i;
            *t += (target - *t) * (dt / tau).min(1.0);
        };
        step(&mut self.motor_c, 40.0, 60.0);
        step(&mut self.drive_c, 30.0, 30.0);
        let rated = f64::from(I2T_CURRENT_MA) / 1000.0;
        let amps = current_ma / 1000.0;
        self.i2t = (self.i2t + (amps * amps - rated * rated) * dt).max(0.0);
    }

    fn check_conditions<OD: ObjectDictionary>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        let c = self.conditions;
        let rated = f64::from(I2T_CURRENT_MA) / 1000.0;
        let present = |cause: Cause| match cause {
            Cause::VbusOver => c.vbus_mv > 80_000,
            Cause::VlogOver => c.vlog_mv > 29_000,
            Cause::VbusUnder => c.vbus_mv < 10_000,
            Cause::VlogUnder => c.vlog_mv < 16_000,
            Cause::MotorHot => self.motor_c > 100.0,
            Cause::DriveHot => self.drive_c > 100.0,
            Cause::I2t => self.i2t > 2.0 * (4.0 * rated * rated - rated * rated),
            Cause::Vext => !c.vext,
            Cause::Sto => !c.hw_enable,
            Cause::Encoder => !c.encoder_ok,
            Cause::OverCurrent => c.short_circuit,
            Cause::Memory => c.memory_fault,
            Cause::Control => c.control_fault,
            Cause::CanPassive => c.can_error_passive,
        };
        for cause in Cause::ALL {
            if present(cause) {
                if self.raised & cause.bit() == 0 {
                    self.raised |= cause.bit();
                    let (code, m) = cause.error();
                    drive.raise(ctx, code, Some(m));
                }
            } else if drive.fault().is_none() {
                // Gone, and no fault latches it: a new occurrence raises again.
                self.raised &= !cause.bit();
            }
        }
        let mut w = 0;
        w |= if c.vbus_mv < 20_000 { warning::VDC_UVLO } else { 0 };
        w |= if c.vbus_mv > 60_000 { warning::VDC_OVLO } else { 0 };
        w |= if c.vlog_mv < 21_000 { warning::VL_UVLO } else { 0 };
        w |= if c.vlog_mv > 27_000 { warning::VL_OVLO } else { 0 };
        w |= if self.motor_c > 75.0 { warning::MOTOR_TEMPERATURE } else { 0 };
        w |= if self.drive_c > 75.0 { warning::DRIVE_TEMPERATURE } else { 0 };
        self.warnings |= w;
    }

    fn check_limits<OD: ObjectDictionary>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        let configured = Self::limits_configured(ctx.od());
        if let LimitCheck::Suspended { moved } = &mut self.limit {
            *moved |= status.velocity_actual != 0;
            let done = match drive.mode() {
                Mode::ProfilePosition => status.target_reached,
                _ => status.standing,
            };
            if *moved && done && status.power {
                self.limit = LimitCheck::Normal;
            }
        }
        let normal = self.limit == LimitCheck::Normal;
        self.limits_active = configured && status.homed && normal;
        // The EXT PROXY input is a hardware limit under the same enable (5.0.1).
        let ext = configured && normal;
        let (mut over, mut under) = (false, false);
        if self.limits_active {
            let (lo, hi) = Self::limits(ctx.od(), &drive.scale());
            let x = i64::from(status.position_actual);
            (over, under) = (x > hi, x < lo);
        }
        over |= ext && status.inputs.positive_limit;
        under |= ext && status.inputs.negative_limit;
        if over {
            self.warnings |= warning::POSITIVE_LIMIT;
        }
        if under {
            self.warnings |= warning::NEGATIVE_LIMIT;
        }
        if over || under {
            if !self.limit_error && drive.fault().is_none() {
                drive.raise(ctx, 0x6120, Some(0));
            }
            self.limit_error = true;
        } else {
            self.limit_error = false;
        }
    }

    fn profile_check<OD: ObjectDictionary>(&mut self, drive: &Drive, od: &OD, status: &Status, dt_us: u64) {
        let enabled = read_int(od, 0x2012, 1).unwrap_or(0) == 1;
        let timeout = read_int(od, 0x2012, 2).unwrap_or(50).max(0) as u64 * 1000;
        if !enabled || !status.power {
            self.position_timer_us = 0;
            self.speed_timer_us = 0;
            return;
        }
        let bump = |t: &mut u64, on: bool| *t = if on { t.saturating_add(dt_us) } else { 0 };
        // Position: the demand is at rest and the axis is not on it (blocked, torque-limited).
        let position_off = drive.mode() == Mode::ProfilePosition
            && status.velocity_demand == 0
            && (i64::from(status.position_demand) - i64::from(status.position_actual)).abs() > 10;
        bump(&mut self.position_timer_us, position_off);
        if self.position_timer_us > timeout {
            self.warnings |= warning::POSITION_NOT_REACHED;
        }
        // Speed: the demand has reached the target and the axis does not follow.
        let target = i64::from(status.velocity_demand);
        let speed_off = matches!(drive.mode(), Mode::ProfileVelocity | Mode::Jog)
            && target != 0
            && (target - i64::from(status.velocity_actual)).abs() > (target.abs() / 100).max(1);
        bump(&mut self.speed_timer_us, speed_off);
        if self.speed_timer_us > timeout {
            self.warnings |= warning::SPEED_NOT_REACHED;
        }
    }

    /// 5.0.3: keeps the position record current, so that whenever the power goes (the process
    /// ends, even killed) the last one says whether the axis was homed and standing, and
    /// where. Written when that changes: at the end and at the start of each movement.
    fn retain_position<OD: ObjectDictionary>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        if !self.restore_done {
            // Ticks can run before the start-up reset: the record is not ours to replace yet.
            return;
        }
        let valid = status.homed && status.standing;
        let position = if valid { status.position_actual } else { 0 };
        if self.saved.is_some_and(|s| s.valid == valid && s.position == position) {
            return;
        }
        let motor = if valid { motor_position(drive.axis_mut()) } else { 0 };
        let record = SavedPosition { valid, position, motor };
        // The drive "tries to save" (5.0.3): a failure leaves the previous record, retried
        // at the next change.
        let _ = ctx.retain(&record.encode());
        self.saved = Some(record);
    }

    fn refuse(&mut self) -> bool {
        self.warnings |= warning::COMMAND_REFUSED;
        false
    }
}

impl<OD: ObjectDictionary> Vendor<OD> for Drvi {
    /// Table 6.17: 1, 3, 4, 6 and -1 (jog); 0 = no mode.
    fn supports_mode(&self, code: i8) -> bool {
        matches!(code, 0 | 1 | 3 | 4 | 6 | -1)
    }

    /// 6.3.2.12: the guarding messages must arrive "to avoid an error and reset the
    /// communication": the fieldbus disconnection error, then a communication reset.
    fn reset_communication_on_link_loss(&self) -> bool {
        true
    }

    /// Table 6.29.
    fn homing_method(&self, code: i8) -> Option<HomingMethod> {
        HomingMethod::camozzi(code)
    }

    /// 6.3.4.16: the polarity "has an impact to ALL the mode of operation (homings,
    /// positioning, speed, torque)".
    fn polarity_reverses_homing(&self) -> bool {
        true
    }

    /// The axis counts 0.01° of the motor ([`COUNTS_PER_TURN`] a turn) in every configuration.
    /// Only motor: 2001h alone (new unit = default unit × numerator / denominator). An
    /// actuator: 2001h, then 6092h and 6091h ([`actuator_scale`]).
    fn scale(&self, od: &OD) -> BusScale {
        if only_motor(od) {
            // 0.01°, 0.01 rpm (= 0.06 °/s = 6 counts/s), rpm/s (= 6 °/s² = 600 counts/s²).
            let (num, den) = (u128::from(term(od, 0x2001, 2)), u128::from(term(od, 0x2001, 1)));
            BusScale {
                position: fit(num, den),
                velocity: fit(num * 6, den),
                acceleration: fit(num * 600, den),
                ..BusScale::ONE
            }
        } else {
            actuator_scale(od)
        }
    }

    /// 2001h and 6092h divide ([`actuator_scale`]); the manual gives no meaning to a 0 in
    /// either (6.3.6.1, 6.3.4.23), so the drive refuses it. 6091h may hold 0: its printed
    /// default 0/0 is 1:1.
    fn on_write(&mut self, _drive: &Drive, _od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        match (write.index, write.sub) {
            (0x2001 | 0x6092, 1 | 2) if write.as_u64() == 0 => Err(AbortCode::INVALID_VALUE),
            _ => Ok(()),
        }
    }

    fn configure(&mut self, od: &OD, _scale: &BusScale, cfg: &mut AxisConfig) {
        // The bus scale gives counts, counts/s and counts/s² in both configurations: a bus
        // value is rounded once, after the whole factor (2001h included).
        cfg.units = Units { velocity: Ratio::ONE, acceleration: Ratio::ONE };
        cfg.relative_base = RelativeBase::ActualPosition;
        // The DRVI checks its limits itself (refusing targets rather than clipping them).
        cfg.software_limits = SoftwareLimits::default();
        let target_torque = read_int(od, 0x6071, 0).unwrap_or(0).unsigned_abs().min(u64::from(PEAK_CURRENT_MA)) as u32;
        cfg.max_torque = if read_int(od, 0x2015, 0) == Some(1) { target_torque } else { PEAK_CURRENT_MA };
        // Torque homings: 6071h limits the current, 2013h (% of the I²T current) is the
        // threshold at the end stop.
        cfg.homing.torque_limit = target_torque;
        let pct = read_int(od, 0x2013, 0).unwrap_or(10).clamp(0, 100) as u32;
        let threshold = I2T_CURRENT_MA * pct / 100;
        cfg.homing.torque_threshold = if target_torque > 0 { threshold.min(target_torque) } else { threshold };
        cfg.homing.torque_threshold = cfg.homing.torque_threshold.max(1);
        // 2011h: PID presets as loop bandwidths; custom scales with Kp position (sub 2, ×10).
        self.pid_bandwidth = match read_int(od, 0x2011, 1).unwrap_or(1) {
            0 | 2 => 300.0,
            1 => 150.0,
            3 => 600.0,
            _ => (read_int(od, 0x2011, 2).unwrap_or(1) as f64 * 30.0).clamp(10.0, 2000.0),
        };
        cfg.plant = plant(self.pid_bandwidth);
        cfg.plant.inertia *= self.inertia_factor;
    }

    fn init(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        // 5.0.3: a homed axis that stood still keeps its position through a power cycle.
        let status = drive.axis().status();
        if status.homed && !status.standing {
            let p = status.position_actual;
            drive.axis_mut().set_actual_position(p, false);
        }
        if !self.restore_done {
            // Power-on: the position saved at power-off, if the axis was homed and standing.
            // The motor has not moved since (nothing moves a switched-off simulation), so the
            // encoder check of 5.0.3 always passes: the machine is where it was, relative to
            // the motor, and the actual position is the saved one.
            self.restore_done = true;
            if let Some(saved) = ctx.retained().and_then(|b| SavedPosition::decode(&b)).filter(|s| s.valid) {
                let axis = drive.axis_mut();
                let here = motor_position(axis);
                *axis.environment_mut() = shifted(*axis.environment(), here - saved.motor);
                axis.set_actual_position(saved.position, true);
                self.saved = Some(saved);
            }
        }
        self.reset_warnings();
        self.limit = LimitCheck::Normal;
        self.last_cw = 0;
    }

    fn on_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, event: &Event) {
        match *event {
            Event::Written { index: 0x6040, sub: 0, .. } => {
                let cw = drive.controlword();
                let last = self.last_cw;
                let rose = |bit: u16| cw & bit != 0 && last & bit == 0;
                if rose(0x80) {
                    self.reset_warnings();
                }
                // 6.5: in profile velocity a rising bit 4 (re)starts the movement at 60FFh.
                if drive.mode() == Mode::ProfileVelocity && rose(0x10) {
                    let v = read_int(ctx.od(), 0x60FF, 0).unwrap_or(0);
                    let v = drive.scale().velocity_in(v).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
                    let _ = drive.axis_mut().set_target_velocity(v);
                }
                self.last_cw = cw;
            }
            // 6.9.3: 0 written to 1003h sub 0 resets errors and warnings.
            Event::Written { index: 0x1003, sub: 0, .. } => {
                self.reset_warnings();
                ctx.fault_reset();
            }
            // 2015h limits the current to |6071h|: a new target torque is a new limit.
            Event::Written { index: 0x6071, .. } => drive.mark_dirty(),
            _ => {}
        }
        // Warnings a command set or a reset cleared are visible at once.
        write_int(ctx.od_mut(), 0x2006, 0, i64::from(self.warnings));
    }

    fn before_command(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, cmd: &mut Command) -> bool {
        let od = ctx.od();
        let scale = drive.scale();
        let status = drive.axis().status();
        match cmd {
            Command::SetPoint(sp) => {
                // 4.1.5: homing first.
                if !status.homed {
                    self.warnings |= warning::HOMING_MISSING;
                    return false;
                }
                // 6.4: the target cannot change during a movement.
                if !status.target_reached && !status.standing {
                    return self.refuse();
                }
                if self.limits_active {
                    let target = if sp.relative {
                        i64::from(status.position_actual) + i64::from(sp.target)
                    } else {
                        i64::from(sp.target)
                    };
                    let (lo, hi) = Self::limits(od, &scale);
                    let vmax = read_int(od, 0x607F, 0).unwrap_or(i64::MAX);
                    let v = read_int(od, 0x6081, 0).unwrap_or(0);
                    if target < lo || target > hi || v > vmax {
                        return self.refuse();
                    }
                }
            }
            Command::TargetVelocity(v) if self.limits_active => {
                let vmax = scale.speed_in(read_int(od, 0x607F, 0).unwrap_or(i64::MAX));
                if i64::from(*v).abs() > vmax {
                    return self.refuse();
                }
            }
            _ => {}
        }
        true
    }

    fn after_command(&mut self, _: &mut Drive, _: &mut Ctx<'_, OD>, cmd: &Command, result: Result<(), CommandError>) {
        match result {
            // "Command refused" resets by itself when a command is accepted.
            Ok(()) => self.warnings &= !warning::COMMAND_REFUSED,
            Err(_) if matches!(cmd, Command::SetPoint(_) | Command::StartHoming | Command::TargetVelocity(_)) => {
                self.warnings |= warning::COMMAND_REFUSED;
            }
            Err(_) => {}
        }
    }

    fn before_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        let now = ctx.now();
        let dt = self.last_now.map_or(0, |t| now.saturating_sub(t));
        self.last_now = Some(now);
        self.last_dt_us = dt;
        let current = f64::from(drive.axis().status().torque_actual.unsigned_abs());
        self.thermal(current, dt as f64 * 1e-6);
        self.check_conditions(drive, ctx);
    }

    fn after_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        // Homing: 2004h, the error 8613h/13 (a soft error), the automatic warning.
        match status.homing {
            HomingState::Error(_) if !self.homing_failed => {
                self.homing_failed = true;
                drive.raise(ctx, 0x8613, Some(13));
            }
            HomingState::InProgress => self.homing_failed = false,
            _ => {}
        }
        if status.homed {
            self.warnings &= !warning::HOMING_MISSING;
        }
        self.retain_position(drive, ctx, status);
        self.check_limits(drive, ctx, status);
        self.profile_check(drive, ctx.od(), status, self.last_dt_us);
        let inputs = u32::from(self.conditions.in1)
            | u32::from(self.conditions.in2) << 1
            | u32::from(status.inputs.negative_limit || status.inputs.positive_limit) << 2
            | u32::from(status.inputs.home_switch) << 3;
        let od = ctx.od_mut();
        write_int(od, 0x2002, 0, i64::from(inputs));
        write_int(od, 0x2004, 0, i64::from(status.homed));
        write_int(od, 0x2006, 0, i64::from(self.warnings));
    }

    fn on_fault_reset(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        // 5.0.1: after a limit error the check waits for the first completed movement, so the
        // axis can be brought back into range.
        if drive.fault().is_some_and(|f| f.error.code == 0x6120) {
            self.limit = LimitCheck::Suspended { moved: false };
            self.limits_active = false;
        }
        self.limit_error = false;
        self.reset_warnings();
        write_int(ctx.od_mut(), 0x2006, 0, i64::from(self.warnings));
    }

    fn statusword(&self, _drive: &Drive, od: &OD, status: &Status, bits: &mut u16) {
        let set = |bits: &mut u16, n: u16, on: bool| {
            if on {
                *bits |= 1 << n;
            } else {
                *bits &= !(1 << n);
            }
        };
        set(bits, 7, self.warnings != 0);
        set(bits, 11, self.limits_active);
        set(bits, 14, status.torque_limit_active && read_int(od, 0x2015, 0) == Some(1));
    }
}
