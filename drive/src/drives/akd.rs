//! The Kollmorgen AKD servo drive, as its CANopen manual (Italian, revision F, March 2012)
//! describes it, on top of the common CiA 402 layer ([`super::cia402`]).
//!
//! | manual | behaviour | here |
//! |---|---|---|
//! | 6.4.2.3, 4.1.1 | modes 1, 3, 4, 6, 7 and 8 (cyclic synchronous position, listed but not described) | [`Vendor::supports_mode`]; mode 8 follows 607Ah at every SYNC |
//! | 6.5, 4.4 | unit systems: FBUS.PARAM05 (36E9h) bit 4 = 0 scales positions, velocities and accelerations by UNIT.PIN/UNIT.POUT (6092h) per motor turn; bit 4 = 1 by the factor group 608Fh × 6091h / 6092h and 204Ch for velocities | [`FactorGroup`] through the generated `units` module; every bus value the common layer handles goes through it, PDOs included |
//! | 6.8.2.1, 6.9.2.2 | 6063h and 60C1h in increments, 608Fh of them per motor turn | [`Vendor::after_step`], the SYNC handler |
//! | 7.1.1 | bus scaling column: 606Ch is 1000:1 (the bus carries 1000 × VL.FB) | [`Vendor::after_step`] |
//! | 6.4.1 | "Switched on": the output stage is on and holds the axis; transition 5 stops with the ramp and holds; a fault reaction on a blocked axis ends with its ramp (common layer) | [`Vendor::disable_reaction`] |
//! | 6.4.2.2, 7.2 | statusword: bit 10 only in Operation enabled; 0 in interpolated position mode and before a homing; homing ends with 0x0637 then 0x1637 (7.2.1.8); bit 7 while a warning is active | [`Vendor::statusword`] |
//! | 6.10 | homing methods 1, 2, 8, 12, 17, 18, 24, 28, 33, 34, 35; a falling bit 4 aborts; 6099h defaults 60 rpm and 1/8 of it; HOME.P sets the home position | [`Vendor::homing_method`], [`Vendor::configure`]; errors F157/F158/F161 |
//! | 6.11 | profile position; 607Dh software limits checked against new targets, in force after save and restart | [`Vendor::init`], [`Vendor::before_command`]; warnings n107/n108, faults F107/F108 |
//! | 6.9 | interpolated position: 60C0h 0 linear (60C1h sub 1 taken at each SYNC), -2 PVT (sub 1 position, sub 2 time, sub 3 velocity); 60C2h period; 60C4h buffer; FBUS.PARAM04 SYNC supervision F125 | [`Vendor::pre_event`], [`Vendor::before_step`] |
//! | 6.7 | profile torque in per mille of rated torque (6071h, 6077h); 2071h/2077h in mA | common layer; [`Vendor::on_event`] for 2071h |
//! | 6.2.3.8, 6.2.3.9, 6.2.2.11 | 60FDh inputs (bits 0..2 limit and home switches, 16..22 DIN1..7, 24..30 changed, reset by 20B8h); 60FEh outputs (bit 0 brake, 16/17 DOUT1/2) under the mask of sub 2 | [`Vendor::after_step`], [`Akd::outputs`] |
//! | 6.2.1.3 | manufacturer status register 1002h | [`manufacturer_status`] |
//! | 6.1, 5.4.4 | EMCY codes from the sidecar table; faults stop with the quick stop ramp (F702, F602 switch the power stage off); warnings set statusword bit 7 and are reset by an EMCY 0000h when their cause is gone | the sidecar table through [`super::Drive::raise`] |
//! | 5.4.7, 5.4.8 | heartbeat or guarding loss: F129 (8130h), braked to standstill | [`Vendor::pre_event`] (the EMCY names the lost node) |
//! | 6.2.1.12, 5.4.1 | 1010h saves the parameters (the sidecar's `[store]` list: process values and commands are not saved); reset node reloads them | the sidecar's `[store]` list through [`super::store`] |
//! | 6.2.2.3, 7.2.1.9 | ASCII channel 2026h: WorkBench commands written 4 characters at a time, the answer read 4 characters per (expedited) upload of sub 2 | [`Vendor::on_event`], [`Vendor::on_upload`] |
//! | 6.6.2.1 | 606Ch: user units over SDO, rpm in a PDO (both 1000:1) | [`Vendor::actual_values`], [`Vendor::on_tpdo`] |
//! | 6.3.1.2, 6.3, 7.2.1.5 to 7.2.2.1 | PDO remapping while the PDO stays valid: mapping sub 0 = 0 deactivates it, the entries are written, sub 0 = n checks and activates it; a valid PDO's CAN-ID may change (7.2.2.1); CiA 301's order (COB-ID bit 31 first: 6.3, 7.2.2.2) works too | the sidecar's `[pdo] remapping = "while-valid"`, carried by the generated dictionary (`ObjectDictionary::PDO_REMAPPING`) to od-runtime |
//!
//! Decisions where the manual is silent (recorded here and tested in `drive/tests/drives_akd.rs`):
//! * the axis counts 2^20 increments per motor turn internally ([`COUNTS_PER_TURN`]), whatever
//!   608Fh says; 608Fh only changes what 6063h and 60C1h count.
//! * motor data the EDS leaves at 0 take the values of [`motor`] (6000 rpm, ramps of
//!   10 000 rpm/s, peak torque 3000 ‰, 3 A rated current); 6083h/6084h = 0 use DRV.ACC/DRV.DEC
//!   (3501h/3522h), and those the default ramp; the quick stop ramp is CS.DEC (3440h sub 1).
//! * a velocity factor 204Ch with a negative term reverses the signed velocities (60FFh,
//!   606Bh, 606Ch: 6.5.2.1 "modifies the resolution and the direction"), not the speeds
//!   (6081h, 6099h, 607Fh); 0 is refused (6.5.2.1 "0 must not be used"), as are zero terms of
//!   608Fh and 6092h.
//! * 6099h and 6081h above the motor's top speed are refused with 0609 0031h (7.2.1.8 gets
//!   that answer for 72 000 units/s in the default units).
//! * software limits: a profile position or interpolation target beyond them is clipped and
//!   raises warning n107/n108 (8582h/8583h) until a target within them is given; reaching a
//!   limit in profile velocity or torque mode is fault F107/F108 (8580h/8581h).
//! * the heat sink faults at 85 °C (F235, 4310h, the 7.2.1.10 example) and warns above 75 °C
//!   (n235, 4391h); a missing hardware enable (STO) is fault F602 while the power stage is on,
//!   warning n602 otherwise.
//! * each SDO upload of 2026h sub 2 takes the next 4 characters of the answer (7.2.1.9); the
//!   entry itself holds its first 32 characters; an answer is cut at 125 characters.
//! * 606Ch carries user units × 1000 over SDO and rpm × 1000 in a PDO (6.6.2.1 "PDO in rpm",
//!   the 1000:1 bus factor of the object kept).
//! * the machine: limit switches, end stops and a reference switch by default (the homings of
//!   7.2.1.7 and 7.2.1.8 need them; [`default_environment`]), a free motor with `--machine
//!   free`. A limit switch reached while moving towards it stops the trajectory (warning
//!   8612h, bit 11): table 6.1 has no code for it. A command away from the switch releases
//!   the stop even while the axis still brakes towards it: the new trajectory brakes and
//!   reverses without being stopped again, until the switch goes off or a command heads for
//!   it again.
//! * numbers written over the ASCII channel are read with checked arithmetic and must fit the
//!   parameter's type and limits after the bus factor ("Error: value out of range").

use std::collections::VecDeque;
use std::sync::OnceLock;

use generated::akd::Dictionary;
use generated::akd::units::{self, Dimension, System, Units as AkdUnits};
use od_runtime::cia402::State;
use od_runtime::od::{AbortCode, MappedHandle, ObjectDictionary};
use od_runtime::{Event, Micros};

use super::cia402::{BusScale, Cia402App, Command, DisableReaction, Vendor, read_int, scale_i64, write_int};
use super::{Drive, ErrorSpec, error_table, sidecar};
use crate::motion::{
    AxisConfig, Environment, HomeOffsetMode, HomingError, HomingKind, HomingMethod, HomingSignal, HomingState, Machine,
    Mode, PlantConfig, Ratio, SoftwareLimits, Status, StopRamp, Units,
};
use crate::node::{Ctx, DeviceKind, WriteRequest};

/// Increments per motor turn the axis counts internally (2^PRBASE with PRBASE 20, 6.8.2.1).
pub const COUNTS_PER_TURN: i64 = 1 << 20;

/// The simulated motor's data, used where the EDS default of the WorkBench parameter is 0.
pub mod motor {
    /// Top speed (MOTOR.VMAX), rpm.
    pub const VMAX_RPM: i64 = 6000;
    /// Ramps (DRV.ACC, DRV.DEC, HOME.ACC, CS.DEC when 0), rpm/s.
    pub const RAMP_RPM_PER_S: i64 = 10_000;
    /// Homing search speed when 6099h sub 1 is 0 (6.10.2.3: "equivalent of 60 rpm"), rpm.
    pub const HOMING_RPM: i64 = 60;
    /// Peak torque (6072h when 0), per mille of rated torque.
    pub const PEAK_TORQUE_PERMILLE: u32 = 3000;
    /// Rated (continuous) current (MOTOR.ICONT when 0), mA: 1000 ‰ of torque.
    pub const RATED_CURRENT_MA: i64 = 3000;
    /// Heat sink temperature of fault F235, °C.
    pub const HEAT_SINK_FAULT_C: f64 = 85.0;
    /// Heat sink temperature of warning n235, °C.
    pub const HEAT_SINK_WARNING_C: f64 = 75.0;
}

/// Statusword-independent view of the drive: the bits of 1002h (6.2.1.3) the simulation sets.
pub mod manufacturer_status {
    /// A motion (positioning, homing) is active.
    pub const MOTION_ACTIVE: u32 = 1 << 0;
    /// The reference position was found (homed).
    pub const HOMED: u32 = 1 << 1;
    /// The reference (home) switch is high.
    pub const HOME_SWITCH: u32 = 1 << 2;
    /// In position.
    pub const IN_POSITION: u32 = 1 << 3;
    /// A warning is active.
    pub const WARNING: u32 = 1 << 8;
    /// Target velocity reached (pp or pv).
    pub const VELOCITY_REACHED: u32 = 1 << 9;
    /// Homing error.
    pub const HOMING_ERROR: u32 = 1 << 11;
    /// Safe torque off selected.
    pub const SAFE_TORQUE_OFF: u32 = 1 << 13;
    /// The power stage is enabled.
    pub const POWER_STAGE: u32 = 1 << 14;
    /// Fault state.
    pub const FAULT: u32 = 1 << 15;
    /// A homing movement is active.
    pub const HOMING_ACTIVE: u32 = 1 << 16;
    /// Emergency stop (quick stop) active.
    pub const QUICK_STOP: u32 = 1 << 19;
    /// The homing movement has finished.
    pub const HOMING_DONE: u32 = 1 << 23;
    /// Digital input 1 (bit 26 input 2, 27 input 3, 28 input 4).
    pub const DIN1: u32 = 1 << 25;
    /// The hardware enable input is set.
    pub const HARDWARE_ENABLE: u32 = 1 << 29;
}

/// How the simulated machine is wired to the digital inputs (60FDh bits 16..22).
pub mod din {
    /// DIN1: reference (home) switch.
    pub const HOME_SWITCH: u8 = 1;
    /// DIN2: positive limit switch.
    pub const POSITIVE_LIMIT: u8 = 2;
    /// DIN3: negative limit switch.
    pub const NEGATIVE_LIMIT: u8 = 3;
}

/// The error codes the AKD raises by itself (6.1).
pub mod code {
    /// F129: life guard or heartbeat error.
    pub const F129_HEARTBEAT: u16 = 0x8130;
    /// F235: excess temperature, drive (heat sink).
    pub const F235_HEAT_SINK: u16 = 0x4310;
    /// n235: power temperature sensor 1 high.
    pub const N235_HEAT_SINK: u16 = 0x4391;
    /// F107: software limit switch, positive.
    pub const F107_POSITIVE_LIMIT: u16 = 0x8580;
    /// F108: software limit switch, negative.
    pub const F108_NEGATIVE_LIMIT: u16 = 0x8581;
    /// n107: positive software position limit exceeded.
    pub const N107_POSITIVE_LIMIT: u16 = 0x8582;
    /// n108: negative software position limit exceeded.
    pub const N108_NEGATIVE_LIMIT: u16 = 0x8583;
    /// n704: PVT buffer overflow.
    pub const N704_PVT_OVERFLOW: u16 = 0x8584;
    /// n705: PVT buffer underflow.
    pub const N705_PVT_UNDERFLOW: u16 = 0x8585;
    /// Hardware limit switch reached (CiA 402 8612h "reference limit"; table 6.1 has no code
    /// for it: see the sidecar's decision on 60FDh).
    pub const LIMIT_SWITCH: u16 = 0x8612;
    /// F439: following error.
    pub const F439_FOLLOWING_ERROR: u16 = 0x8611;
    /// F157: homing index pulse not found.
    pub const F157_INDEX_NOT_FOUND: u16 = 0x86A0;
    /// F158: homing reference switch not found.
    pub const F158_SWITCH_NOT_FOUND: u16 = 0x86A1;
    /// F161: homing procedure failed.
    pub const F161_HOMING_FAILED: u16 = 0x86A4;
    /// F125: fieldbus synchronization lost.
    pub const F125_SYNC_LOST: u16 = 0x8780;
    /// F602: safe torque off.
    pub const F602_SAFE_TORQUE_OFF: u16 = 0xFF0B;
    /// n602: safe torque off (warning).
    pub const N602_SAFE_TORQUE_OFF: u16 = 0xFF16;
}

// ---------------------------------------------------------------------------------------------
// Units.

/// The AKD's factor group (6.5) as conversions to the axis' increments: which unit system
/// 36E9h bit 4 selects, and the internal counts per bus unit of each dimension.
///
/// Built from the generated `units` module of the dictionary
/// ([`generated::akd::units::Units`]), which knows the sidecar's formulas:
/// `increments = user × 608Fh × 6091h / 6092h` (ds402 factors; velocities also × 204Ch) or
/// `motor turns = user / 6092h` (WorkBench units). The axis counts [`COUNTS_PER_TURN`] per
/// motor turn, so both become counts per user unit here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FactorGroup {
    /// The unit system in force.
    pub system: System,
    /// Counts per bus unit: positions, velocities (per second), accelerations (per second²).
    pub scale: BusScale,
    /// 608Fh: encoder increments per motor turn (6063h and 60C1h count these), as `(num, den)`.
    pub increments_per_turn: Ratio,
}

impl FactorGroup {
    /// The factor group of the dictionary's current values; a factor that cannot be used (a
    /// zero term written before the drive could refuse it, an overflow) falls back to the
    /// defaults for its dimension.
    pub fn read(od: &Dictionary) -> FactorGroup {
        let turn = Ratio::new(COUNTS_PER_TURN, 1);
        let enc = AkdUnits::encoder_resolution(od)
            .ok()
            .and_then(to_motion_ratio)
            .filter(|r| r.num > 0 && r.den > 0)
            .unwrap_or(turn);
        let system = System::active(od);
        let Ok(u) = AkdUnits::from_dictionary(od) else {
            return FactorGroup {
                system,
                scale: BusScale { position: turn, velocity: turn, acceleration: turn, ..BusScale::ONE },
                increments_per_turn: enc,
            };
        };
        // Counts per user unit from the module's internal factor (increments or motor turns),
        // as a magnitude; a negative factor (204Ch) is a direction, carried apart.
        let counts = |d: Dimension| -> Ratio {
            let Some(g) = u.internal_factor(d) else { return turn };
            let to_counts = match u.system() {
                System::Ds402Factors => {
                    units::Ratio::new(i128::from(COUNTS_PER_TURN) * i128::from(enc.den), i128::from(enc.num))
                }
                System::WorkbenchUnits => units::Ratio::new(i128::from(COUNTS_PER_TURN), 1),
            };
            to_counts
                .and_then(|c| g.checked_mul(c))
                .and_then(|r| units::Ratio::new(r.num().abs(), r.den()))
                .and_then(to_motion_ratio)
                .filter(|r| r.num > 0)
                .unwrap_or(turn)
        };
        // 6.5.2.1: 204Ch "modifies the resolution and the direction" of the velocity values.
        let reverse_velocity = u.internal_factor(Dimension::Velocity).is_some_and(|g| g.num() < 0);
        FactorGroup {
            system: u.system(),
            scale: BusScale {
                position: counts(Dimension::Position),
                velocity: counts(Dimension::Velocity),
                reverse_velocity,
                acceleration: counts(Dimension::Acceleration),
                torque: Ratio::ONE,
            },
            increments_per_turn: enc,
        }
    }

    /// Internal counts → 6063h increments.
    pub fn counts_to_increments(&self, counts: i64) -> i64 {
        let e = self.increments_per_turn;
        scale_i64(counts, Ratio::new(e.num, e.den.saturating_mul(COUNTS_PER_TURN)))
    }

    /// 6063h / 60C1h increments → internal counts.
    pub fn increments_to_counts(&self, increments: i64) -> i64 {
        let e = self.increments_per_turn;
        scale_i64(increments, Ratio::new(e.den.saturating_mul(COUNTS_PER_TURN), e.num))
    }
}

/// A generated (i128) ratio as the motion model's i64 ratio, reduced; `None` if it does not fit.
fn to_motion_ratio(r: units::Ratio) -> Option<Ratio> {
    let r = r.reduced();
    Some(Ratio::new(i64::try_from(r.num()).ok()?, i64::try_from(r.den()).ok()?))
}

/// MOTOR.VMAX (35A3h, rpm), or the simulated motor's.
fn top_speed_rpm(od: &Dictionary) -> i64 {
    read_int(od, 0x35A3, 0).filter(|v| *v > 0).unwrap_or(motor::VMAX_RPM)
}

/// MOTOR.ICONT (358Eh, 1000:1 so the bus carries mA), or the simulated motor's.
fn rated_current_ma(od: &Dictionary) -> i64 {
    read_int(od, 0x358E, 0).filter(|v| *v > 0).unwrap_or(motor::RATED_CURRENT_MA)
}

/// Counts per second of `rpm`.
const fn rpm_counts(rpm: i64) -> i64 {
    rpm * COUNTS_PER_TURN / 60
}

fn sat_u32(v: i64) -> u32 {
    v.clamp(0, i64::from(u32::MAX)) as u32
}

fn sat_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

// ---------------------------------------------------------------------------------------------
// The mechanics.

/// The machine an AKD app starts with (the `akd-linear` preset), in counts (2^20 per motor
/// turn): a reference switch from 0.25 to 0.5 turn, limit switches at -1 and +2 turns, hard
/// end stops one turn beyond them (-2 and +3 turns), the encoder index every turn at 0.1 turn.
pub fn default_environment() -> Environment {
    super::machine::default_machine(DeviceKind::Akd).environment(COUNTS_PER_TURN as f64, 1.0)
}

/// The motor and load in counts and per mille of rated torque: 1000 ‰ accelerates the axis at
/// 500 turns/s², 100 ‰ of viscous friction at top speed, 20 ‰ of dry friction.
pub fn plant() -> PlantConfig {
    let turn = COUNTS_PER_TURN as f64;
    PlantConfig {
        inertia: 1000.0 / (500.0 * turn),
        viscous: 100.0 / (100.0 * turn),
        coulomb: 20.0,
        bandwidth: 300.0,
        max_speed: rpm_counts(motor::VMAX_RPM) as f64,
    }
}

/// An AKD application on `machine` (positions in motor turns).
pub fn app_with(machine: &Machine) -> Cia402App<Dictionary, Akd> {
    let akd = Akd { inertia_factor: machine.inertia_factor(), ..Akd::default() };
    let mut app = Cia402App::new(akd, error_table(DeviceKind::Akd));
    *app.drive_mut().axis_mut().environment_mut() = machine.environment(COUNTS_PER_TURN as f64, 1.0);
    app
}

/// An AKD application with the default mechanics ([`default_environment`]).
pub fn app() -> Cia402App<Dictionary, Akd> {
    app_with(&super::machine::default_machine(DeviceKind::Akd))
}

// ---------------------------------------------------------------------------------------------
// The device.

/// What the drive measures around it; tests and demos change these to provoke the errors of
/// chapter 6.1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    /// Heat sink temperature, °C (F235 above [`motor::HEAT_SINK_FAULT_C`]).
    pub heat_sink_c: f64,
    /// The hardware enable input (safe torque off when absent).
    pub hardware_enable: bool,
    /// Levels of DIN4..DIN7 (bit 0 = DIN4); DIN1..3 are the machine's switches ([`din`]).
    pub free_inputs: u8,
}

impl Default for Conditions {
    fn default() -> Self {
        Self { heat_sink_c: 40.0, hardware_enable: true, free_inputs: 0 }
    }
}

/// A PVT segment (60C0h = -2): the end point and how long the way there takes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PvtPoint {
    /// End position, counts.
    p: f64,
    /// End velocity, counts/s.
    v: f64,
    /// Duration, s.
    t: f64,
}

/// The segment being run: cubic Hermite from `(p0, v0)` to the point.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PvtRun {
    p0: f64,
    v0: f64,
    to: PvtPoint,
    elapsed: f64,
}

impl PvtRun {
    fn position(&self, t: f64) -> f64 {
        let d = self.to.t.max(1e-6);
        let s = (t / d).clamp(0.0, 1.0);
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        h00 * self.p0 + h10 * d * self.v0 + h01 * self.to.p + h11 * d * self.to.v
    }
}

/// The AKD's behaviour on top of the common CiA 402 drive.
#[derive(Clone, Debug)]
pub struct Akd {
    /// What the drive measures.
    pub conditions: Conditions,
    /// The machine's inertia on the built-in one ([`Machine::inertia_factor`]).
    inertia_factor: f64,
    /// The software limits in force (607Dh at the last reset node, bus units).
    limits: Option<(i64, i64)>,
    /// Active warnings (codes), oldest first.
    warnings: Vec<u16>,
    /// Warning n107/n108 of a clipped target.
    clip_warning: Option<u16>,
    /// A software-limit fault was raised and the axis has not left the limit since.
    limit_fault: bool,
    /// The trajectory was stopped on a hardware limit switch: +1 positive, -1 negative.
    switch_stop: Option<i8>,
    /// A command away from the limit switch on this side (+1, -1) released its stop: the
    /// trajectory may still run towards the switch while it brakes to reverse, which does not
    /// stop it again; cleared when that switch goes off or a command heads for it again.
    leaving: Option<i8>,
    following_fault: bool,
    homing_failed: bool,
    /// Ticks since the homing completed (the AKD shows bit 10 one tick before bit 12).
    homing_done_ticks: u32,
    /// Condition faults raised (F235, F602), until their cause is gone and no fault holds them.
    heat_fault: bool,
    sto_fault: bool,
    /// DIN1..7 levels at the last tick and their change latches (60FDh bits 24..30).
    din_last: u8,
    din_changed: u8,
    /// 60FEh as applied: DOUT1/DOUT2 bits 16/17 and the brake bit 0.
    outputs: u32,
    /// SYNC supervision (FBUS.PARAM04).
    last_sync: Option<Micros>,
    sync_period: Option<Micros>,
    sync_lost: bool,
    /// PVT segments waiting and running.
    pvt_queue: VecDeque<PvtPoint>,
    pvt_run: Option<PvtRun>,
    pvt_underflow: bool,
    /// ASCII channel input not yet terminated by CR/LF.
    ascii_input: Vec<u8>,
    /// The answer not yet read from 2026h sub 2, handed out four characters per upload.
    ascii_output: VecDeque<u8>,
    last_now: Option<Micros>,
}

impl Default for Akd {
    fn default() -> Self {
        Self {
            conditions: Conditions::default(),
            inertia_factor: 1.0,
            limits: None,
            warnings: Vec::new(),
            clip_warning: None,
            limit_fault: false,
            switch_stop: None,
            leaving: None,
            following_fault: false,
            homing_failed: false,
            homing_done_ticks: 0,
            heat_fault: false,
            sto_fault: false,
            din_last: 0,
            din_changed: 0,
            outputs: 0,
            last_sync: None,
            sync_period: None,
            sync_lost: false,
            pvt_queue: VecDeque::new(),
            pvt_run: None,
            pvt_underflow: false,
            ascii_input: Vec::new(),
            ascii_output: VecDeque::new(),
            last_now: None,
        }
    }
}

/// The homing methods of the sidecar (6.10.2.2).
fn supported_homing(code: i8) -> bool {
    sidecar(DeviceKind::Akd).is_some_and(|s| s.homing_methods.iter().any(|h| h.code == code))
}

impl Akd {
    /// The active warnings (EMCY codes), oldest first.
    pub fn warnings(&self) -> &[u16] {
        &self.warnings
    }

    /// The software limits in force (bus units), `None` when off.
    pub fn limits_in_force(&self) -> Option<(i64, i64)> {
        self.limits
    }

    /// 60FEh as applied (sub 1 under the mask of sub 2): bit 0 brake, bits 16/17 DOUT1/DOUT2.
    pub fn outputs(&self) -> u32 {
        self.outputs
    }

    /// The digital inputs DIN1..DIN7 (bit 0 = DIN1) at the last tick.
    pub fn inputs(&self) -> u8 {
        self.din_last
    }

    /// PVT segments waiting.
    pub fn pvt_queued(&self) -> usize {
        self.pvt_queue.len()
    }

    fn warn<OD>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, code: u16) {
        if !self.warnings.contains(&code) {
            self.warnings.push(code);
            drive.raise(ctx, code, None);
        }
    }

    fn unwarn<OD>(&mut self, drive: &Drive, ctx: &mut Ctx<'_, OD>, code: u16) {
        if let Some(i) = self.warnings.iter().position(|w| *w == code) {
            self.warnings.remove(i);
            // 5.4.4.1 transitions 2 and 4: EMCY 0000h with the remaining error register.
            let bits = drive.errors().resolve(code, None).register_bits();
            let keep = self
                .warnings
                .iter()
                .map(|w| drive.errors().resolve(*w, None).register_bits())
                .chain(drive.fault().map(|f| f.error.register_bits()))
                .fold(0u8, |a, b| a | b);
            // The generic bit goes when no other bit remains (od-runtime's reset_error).
            ctx.reset_error(bits & !keep);
        }
    }

    fn set_warning<OD>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, code: u16, on: bool) {
        if on {
            self.warn(drive, ctx, code);
        } else {
            self.unwarn(drive, ctx, code);
        }
    }

    /// The software limits from 607Dh (both 0: off), ordered.
    fn limits_of(od: &Dictionary) -> Option<(i64, i64)> {
        let (a, b) = (read_int(od, 0x607D, 1).unwrap_or(0), read_int(od, 0x607D, 2).unwrap_or(0));
        ((a, b) != (0, 0)).then_some((a.min(b), a.max(b)))
    }

    /// The DIN1..DIN7 levels.
    fn din(&self, status: &Status) -> u8 {
        let i = status.inputs;
        u8::from(i.home_switch)
            | u8::from(i.positive_limit) << 1
            | u8::from(i.negative_limit) << 2
            | (self.conditions.free_inputs & 0x0F) << 3
    }

    fn apply_outputs(&mut self, drive: &mut Drive, od: &Dictionary) {
        let value = read_int(od, 0x60FE, 1).unwrap_or(0) as u32;
        let mask = read_int(od, 0x60FE, 2).unwrap_or(0) as u32;
        self.outputs = value & mask & 0x0003_0001;
        drive.axis_mut().set_brake(self.outputs & 1 != 0);
    }

    /// The statusword bits of mode 8 (cyclic synchronous position).
    fn csp(drive: &Drive) -> bool {
        drive.mode_code() == 8
    }

    fn check_conditions(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let c = self.conditions;
        let hot = c.heat_sink_c > motor::HEAT_SINK_FAULT_C;
        if hot && !self.heat_fault {
            self.heat_fault = true;
            drive.raise(ctx, code::F235_HEAT_SINK, None);
        } else if !hot && drive.fault().is_none() {
            self.heat_fault = false;
        }
        self.set_warning(drive, ctx, code::N235_HEAT_SINK, c.heat_sink_c > motor::HEAT_SINK_WARNING_C && !hot);
        let powered = drive.axis().status().power;
        let sto = !c.hardware_enable;
        if sto && powered && !self.sto_fault {
            self.sto_fault = true;
            drive.raise(ctx, code::F602_SAFE_TORQUE_OFF, None);
        } else if !sto && drive.fault().is_none() {
            self.sto_fault = false;
        }
        self.set_warning(drive, ctx, code::N602_SAFE_TORQUE_OFF, sto && !self.sto_fault);
        if sto && powered {
            drive.axis_mut().set_power(false);
        }
    }

    /// Which limit switch the axis' motion heads into (+1 positive, -1 negative), in the
    /// mechanical frame the switches live in.
    fn switch_ahead(drive: &Drive, status: &Status) -> Option<i8> {
        let reversed = drive.axis().config().reverse_polarity;
        let v = i64::from(status.velocity_demand) * if reversed { -1 } else { 1 };
        let t = i64::from(status.torque_demand) * if reversed { -1 } else { 1 };
        let push = if v != 0 { v } else { t };
        let i = status.inputs;
        if i.positive_limit && push > 0 {
            Some(1)
        } else if i.negative_limit && push < 0 {
            Some(-1)
        } else {
            None
        }
    }

    /// A limit switch reached while moving towards it: the trajectory stops on the quick stop
    /// ramp and holds (no demand winds up behind the switch), warning 8612h. The stop ends
    /// with a command away from the switch or a mode change ([`Vendor::before_command`]).
    fn check_switches(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, status: &Status) {
        let moving = drive.state() == State::OperationEnabled && drive.mode() != Mode::Homing && status.power;
        let i = status.inputs;
        if (self.leaving == Some(1) && !i.positive_limit) || (self.leaving == Some(-1) && !i.negative_limit) {
            self.leaving = None;
        }
        if self.switch_stop.is_none()
            && moving
            && let Some(side) = Self::switch_ahead(drive, status)
            && self.leaving != Some(side)
        {
            self.switch_stop = Some(side);
            drive.axis_mut().quick_stop(StopRamp::QuickStopDeceleration);
            self.warn(drive, ctx, code::LIMIT_SWITCH);
        }
        if self.warnings.contains(&code::LIMIT_SWITCH) && !i.positive_limit && !i.negative_limit {
            self.unwarn(drive, ctx, code::LIMIT_SWITCH);
        }
        if !moving {
            // Another stop (a disable, quick stop or fault reaction of the state machine, or
            // the homing) has taken over the axis: it is not released here.
            self.switch_stop = None;
            self.leaving = None;
        }
    }

    fn release_switch_stop(&mut self, drive: &mut Drive) {
        if self.switch_stop.take().is_some() {
            drive.axis_mut().release_quick_stop();
        }
    }

    /// F107/F108: the limit reached in a mode without a position target.
    fn check_limits(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, status: &Status) {
        let Some((lo, hi)) = self.limits else {
            self.limit_fault = false;
            return;
        };
        let s = drive.scale();
        let (lo, hi) = (s.position_in(lo), s.position_in(hi));
        let x = i64::from(status.position_actual);
        let v = i64::from(status.velocity_demand);
        let free_mode = matches!(drive.mode(), Mode::ProfileVelocity | Mode::ProfileTorque);
        let outward = if free_mode && status.power {
            if (x >= hi || status.internal_limit_active) && v > 0 {
                Some(code::F107_POSITIVE_LIMIT)
            } else if (x <= lo || status.internal_limit_active) && v < 0 {
                Some(code::F108_NEGATIVE_LIMIT)
            } else {
                None
            }
        } else {
            None
        };
        match outward {
            Some(c) if !self.limit_fault && drive.fault().is_none() => {
                self.limit_fault = true;
                drive.raise(ctx, c, None);
            }
            Some(_) => {}
            None if x > lo && x < hi => self.limit_fault = false,
            None => {}
        }
    }

    fn homing_error(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, status: &Status) {
        match status.homing {
            HomingState::Error(e) if !self.homing_failed => {
                self.homing_failed = true;
                let method = drive.axis().config().homing.method;
                let code = match (e, method.kind) {
                    (HomingError::NoIndexPulse, _) => code::F157_INDEX_NOT_FOUND,
                    (HomingError::NotFound, HomingKind::Switch { signal: HomingSignal::HomeSwitch, .. }) => {
                        code::F158_SWITCH_NOT_FOUND
                    }
                    _ => code::F161_HOMING_FAILED,
                };
                drive.raise(ctx, code, None);
            }
            HomingState::Error(_) => {}
            _ => self.homing_failed = false,
        }
        if status.homing == HomingState::Completed && drive.mode() == Mode::Homing {
            self.homing_done_ticks = self.homing_done_ticks.saturating_add(1);
        } else {
            self.homing_done_ticks = 0;
        }
    }

    fn manufacturer_status(&self, drive: &Drive, status: &Status) -> u32 {
        use manufacturer_status as m;
        let bit = |on: bool, b: u32| if on { b } else { 0 };
        let homing_active = status.homing == HomingState::InProgress || status.homing == HomingState::Attained;
        let state = drive.state();
        let din = u32::from(self.din_last & 0x0F);
        bit(!status.standing, m::MOTION_ACTIVE)
            | bit(status.homed, m::HOMED)
            | bit(status.inputs.home_switch, m::HOME_SWITCH)
            | bit(drive.mode() == Mode::ProfilePosition && status.target_reached && status.power, m::IN_POSITION)
            | bit(!self.warnings.is_empty(), m::WARNING)
            | bit(drive.mode() == Mode::ProfileVelocity && status.target_reached && status.power, m::VELOCITY_REACHED)
            | bit(matches!(status.homing, HomingState::Error(_)), m::HOMING_ERROR)
            | bit(!self.conditions.hardware_enable, m::SAFE_TORQUE_OFF)
            | bit(status.power, m::POWER_STAGE)
            | bit(matches!(state, State::Fault | State::FaultReactionActive), m::FAULT)
            | bit(homing_active, m::HOMING_ACTIVE)
            | bit(state == State::QuickStopActive, m::QUICK_STOP)
            | bit(status.homing == HomingState::Completed, m::HOMING_DONE)
            | (din * m::DIN1)
            | bit(self.conditions.hardware_enable, m::HARDWARE_ENABLE)
    }

    /// A SYNC in interpolated position mode: the next set-point (linear) or PVT segment.
    fn interpolation_sync(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let fg = FactorGroup::read(ctx.od());
        let active = drive.axis().status().interpolation_active;
        let sub_mode = read_int(ctx.od(), 0x60C0, 0).unwrap_or(0);
        if sub_mode == -2 {
            let p = read_int(ctx.od(), 0x60C1, 1).unwrap_or(0);
            let t_ms = read_int(ctx.od(), 0x60C1, 2).unwrap_or(0);
            let v = read_int(ctx.od(), 0x60C1, 3).unwrap_or(0);
            if active && t_ms > 0 {
                let capacity = read_int(ctx.od(), 0x60C4, 1).unwrap_or(10).clamp(1, 1024) as usize;
                let point = PvtPoint {
                    p: fg.increments_to_counts(p) as f64,
                    v: fg.increments_to_counts(v) as f64,
                    t: t_ms as f64 * 1e-3,
                };
                if self.pvt_queue.len() + 1 >= capacity {
                    self.warn(drive, ctx, code::N704_PVT_OVERFLOW);
                } else {
                    self.pvt_queue.push_back(point);
                }
            }
            return;
        }
        if active {
            let counts = sat_i32(fg.increments_to_counts(read_int(ctx.od(), 0x60C1, 1).unwrap_or(0)));
            let _ = drive.axis_mut().push_interpolation_point(counts);
        }
        drive.axis_mut().sync();
        self.clip_check_after_interpolation(drive, ctx);
    }

    /// Mode 8: 607Ah is the set-point of the next SYNC period.
    fn csp_sync(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        if drive.axis().status().interpolation_active {
            let target = read_int(ctx.od(), 0x607A, 0).unwrap_or(0);
            let counts = sat_i32(drive.scale().position_in(target));
            let _ = drive.axis_mut().push_interpolation_point(counts);
        }
        drive.axis_mut().sync();
        self.clip_check_after_interpolation(drive, ctx);
    }

    fn clip_check_after_interpolation(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let st = drive.axis().status();
        let want = if st.internal_limit_active {
            let (lo, hi) = self.limits.unwrap_or((0, 0));
            let mid = drive.scale().position_in((lo + hi) / 2);
            Some(if i64::from(st.position_demand) >= mid {
                code::N107_POSITIVE_LIMIT
            } else {
                code::N108_NEGATIVE_LIMIT
            })
        } else {
            None
        };
        self.set_clip_warning(drive, ctx, want);
    }

    fn set_clip_warning<OD>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, want: Option<u16>) {
        if self.clip_warning == want {
            return;
        }
        if let Some(old) = self.clip_warning.take() {
            self.unwarn(drive, ctx, old);
        }
        if let Some(new) = want {
            self.warn(drive, ctx, new);
        }
        self.clip_warning = want;
    }

    /// Runs the PVT segments: one interpolation point per tick on the cubic.
    fn pvt_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, dt: f64) {
        let st = drive.axis().status();
        if drive.mode() != Mode::InterpolatedPosition || !st.interpolation_active {
            self.pvt_run = None;
            self.pvt_queue.clear();
            return;
        }
        if self.pvt_run.is_none() {
            let Some(to) = self.pvt_queue.pop_front() else { return };
            self.pvt_run = Some(PvtRun { p0: f64::from(st.position_demand), v0: 0.0, to, elapsed: 0.0 });
        }
        let Some(run) = &mut self.pvt_run else { return };
        run.elapsed += dt;
        let p = run.position(run.elapsed);
        let done = run.elapsed >= run.to.t - 1e-9;
        let end = run.to;
        let _ = drive.axis_mut().push_interpolation_point(sat_i32(p.round() as i64));
        drive.axis_mut().sync();
        if done {
            self.pvt_run = self.pvt_queue.pop_front().map(|to| PvtRun { p0: end.p, v0: end.v, to, elapsed: 0.0 });
            let underflow = self.pvt_run.is_none() && end.v != 0.0;
            if underflow && !self.pvt_underflow {
                self.warn(drive, ctx, code::N705_PVT_UNDERFLOW);
            }
            self.pvt_underflow = underflow;
        }
    }

    // ---- ASCII channel (6.2.2.3) ----------------------------------------------------------

    fn ascii_write(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let piece = ctx.od().ascii_channel_command().to_vec();
        for b in piece {
            if b == b'\r' || b == b'\n' {
                if !self.ascii_input.is_empty() {
                    let line = String::from_utf8_lossy(&std::mem::take(&mut self.ascii_input)).into_owned();
                    let answer = self.ascii_execute(drive, ctx, line.trim());
                    let mut text = format!(">{answer}").into_bytes();
                    text.truncate(ASCII_ANSWER_MAX);
                    text.extend_from_slice(b"\n\r\n");
                    // 7.2.1.9: each upload of sub 2 takes the next four characters; the
                    // dictionary holds the beginning of the answer (its capacity) for reads
                    // that do not go through an SDO upload.
                    let capacity = text.len().min(32);
                    let _ = ctx.od_mut().set_ascii_channel_response(&text[..capacity]);
                    self.ascii_output = text.into();
                }
            } else if self.ascii_input.len() < 256 {
                self.ascii_input.push(b);
            }
        }
    }

    fn ascii_execute(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, line: &str) -> String {
        let mut words = line.split_whitespace();
        let Some(name) = words.next() else { return String::new() };
        let name = name.to_ascii_uppercase();
        let value = words.next();
        match name.as_str() {
            "DRV.FAULTS" => match drive.fault() {
                None => "No faults active".into(),
                Some(f) => {
                    let number =
                        f.error.vendor_code.as_deref().map_or(String::new(), |v| v.trim_start_matches('F').to_owned());
                    format!("{number}: {}", f.error.text)
                }
            },
            "DRV.WARNINGS" if self.warnings.is_empty() => "No warnings active".into(),
            "DRV.WARNINGS" => self
                .warnings
                .iter()
                .map(|w| drive.errors().resolve(*w, None).vendor_code.unwrap_or_else(|| format!("{w:04X}")))
                .collect::<Vec<_>>()
                .join(" "),
            // 6.4.1.2: under controlword control no other channel may command the drive.
            "DRV.EN" | "DRV.DIS" | "DRV.STOP" | "MT.MOVE" => "Error: the fieldbus controls the drive".into(),
            "DRV.NVSAVE" => match ctx.write(0x1010, 1, &od_runtime::storage::SAVE_SIGNATURE.to_le_bytes()) {
                Ok(()) => String::new(),
                Err(e) => format!("Error: {:08X}", e.0),
            },
            _ => match parameter(&name) {
                None => "Error: unknown command".into(),
                Some(p) => match value {
                    None => read_parameter(ctx.od(), p),
                    Some(text) => write_parameter(ctx, p, text),
                },
            },
        }
    }
}

/// The longest ASCII answer (before its `\n\r\n`): a long fault text is cut here.
const ASCII_ANSWER_MAX: usize = 125;

/// Characters of the ASCII answer per upload of 2026h sub 2 (7.2.1.9).
const ASCII_CHUNK: usize = 4;

/// A WorkBench parameter reachable by name over the ASCII channel.
#[derive(Clone, Copy, Debug)]
struct Parameter {
    index: u16,
    sub: u8,
    /// Bus value = WorkBench value × factor (7.1.1); 0 for integers.
    factor: u32,
}

/// The parameter with WorkBench name `name` (the EDS Denotation), the first where several
/// entries share it.
fn parameter(name: &str) -> Option<Parameter> {
    static TABLE: OnceLock<Vec<(String, Parameter)>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let parsed = eds::parse("kollmorgen-akd.eds", generated::akd::EDS.as_bytes(), &eds::Options::lenient());
        let scaling = sidecar(DeviceKind::Akd).map(|s| &s.bus_scaling);
        let mut out = Vec::new();
        for (o, e) in parsed.model.entries() {
            let Some(d) = e.denotation() else { continue };
            if d.contains(',') || d.contains(' ') {
                continue;
            }
            let (index, sub) = (o.index.0, e.sub.0);
            let factor = scaling
                .and_then(|m| {
                    m.get(&devices::sidecar::ObjRef { index, sub: Some(sub) })
                        .or_else(|| m.get(&devices::sidecar::ObjRef { index, sub: None }).filter(|_| sub == 0))
                })
                .map_or(0, |b| match b {
                    devices::sidecar::BusScaling::Factor(f) => *f,
                    devices::sidecar::BusScaling::Variable => 0,
                });
            out.push((d.to_ascii_uppercase(), Parameter { index, sub, factor }));
        }
        out
    });
    // A name on several objects (UNIT.PIN on 35CAh and 6092h sub 1, PL.ERR on 35C5h and 60F4h)
    // is one WorkBench parameter: the profile object stands for it.
    let mut hits = table.iter().filter(|(n, _)| n == name).map(|(_, p)| *p);
    let first = hits.next()?;
    Some(hits.chain(std::iter::once(first)).find(|p| p.index >= 0x6000).unwrap_or(first))
}

fn read_parameter(od: &Dictionary, p: Parameter) -> String {
    let Some(v) = read_int(od, p.index, p.sub) else { return "Error: not readable".into() };
    match p.factor {
        0 => v.to_string(),
        f => {
            let f = i64::from(f);
            // value / factor with three decimals (the WorkBench display).
            let milli = i128::from(v) * 1000 / i128::from(f);
            let sign = if milli < 0 { "-" } else { "" };
            let m = milli.unsigned_abs();
            format!("{sign}{}.{:03}", m / 1000, m % 1000)
        }
    }
}

fn write_parameter(ctx: &mut Ctx<'_, Dictionary>, p: Parameter, text: &str) -> String {
    let Some(info) = ctx.od().info(p.index, p.sub).ok() else { return "Error: no such parameter".into() };
    if !info.access.writable() {
        return "Error: read only".into();
    }
    let raw = match parse_milli(text) {
        Err(NumberError::NotANumber) => return "Error: not a number".into(),
        Err(NumberError::OutOfRange) => return OUT_OF_RANGE.into(),
        Ok(milli) => match p.factor {
            0 => Some(milli / 1000),
            f => milli.checked_mul(i128::from(f)).map(|v| v / 1000),
        },
    };
    // The value must fit the entry's type and limits: nothing wraps into the dictionary.
    let Some((raw, len)) = raw.and_then(|raw| fits(info, raw).then_some((raw, info.byte_len()))) else {
        return OUT_OF_RANGE.into();
    };
    let Ok(raw) = i64::try_from(raw) else { return OUT_OF_RANGE.into() };
    match ctx.write(p.index, p.sub, &raw.to_le_bytes()[..len.min(8)]) {
        Ok(()) => String::new(),
        Err(e) => format!("Error: {:08X}", e.0),
    }
}

/// The answer to a value the parameter cannot take (beyond its type or its limits).
const OUT_OF_RANGE: &str = "Error: value out of range";

/// Whether `raw` fits integer entry `info`: its type's range (at most 64 bits) and its
/// `low`/`high` limits.
fn fits(info: &od_runtime::od::EntryInfo, raw: i128) -> bool {
    let bits = info.bits();
    if !info.data_type.is_integer() || bits == 0 || bits > 64 {
        return false;
    }
    let (lo, hi) = if info.data_type.is_signed() {
        (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
    } else {
        (0, (1i128 << bits) - 1)
    };
    (lo..=hi).contains(&raw) && info.low().is_none_or(|l| raw >= l) && info.high().is_none_or(|h| raw <= h)
}

/// Why a parameter value was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NumberError {
    /// Not a decimal number.
    NotANumber,
    /// A decimal number too large for any parameter.
    OutOfRange,
}

/// A decimal number × 1000 (`-12.5` → -12500), with checked arithmetic: digits beyond what an
/// `i128` holds are out of range, not wrapped.
fn parse_milli(text: &str) -> Result<i128, NumberError> {
    let (neg, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text),
    };
    let (int, frac) = digits.split_once('.').unwrap_or((digits, ""));
    if int.is_empty() && frac.is_empty() || !int.chars().chain(frac.chars()).all(|c| c.is_ascii_digit()) {
        return Err(NumberError::NotANumber);
    }
    let mut v: i128 = 0;
    for d in int.bytes() {
        v = v.checked_mul(10).and_then(|v| v.checked_add(i128::from(d - b'0'))).ok_or(NumberError::OutOfRange)?;
    }
    v = v.checked_mul(1000).ok_or(NumberError::OutOfRange)?;
    // Thousandths; further decimals are cut off as WorkBench shows three.
    let mut scale = 100;
    for d in frac.bytes().take(3) {
        v += i128::from(d - b'0') * scale;
        scale /= 10;
    }
    Ok(if neg { -v } else { v })
}

// ---------------------------------------------------------------------------------------------
// The hooks.

impl Vendor<Dictionary> for Akd {
    /// 6.4.2.3: 1, 3, 4, 6, 7, 8; 0 = no mode.
    fn supports_mode(&self, code: i8) -> bool {
        matches!(code, 0 | 1 | 3 | 4 | 6 | 7 | 8)
    }

    /// 6.10.2.2: the methods of the sidecar, with their CiA 402 meaning.
    fn homing_method(&self, code: i8) -> Option<HomingMethod> {
        if supported_homing(code) { HomingMethod::cia402(code) } else { None }
    }

    /// 6.10.2.5: bit 4 falling interrupts the homing.
    fn homing_abort_on_release(&self) -> bool {
        true
    }

    /// 6.1, 5.4.7: F129 "life guard error or heartbeat error".
    fn fieldbus_error(&self) -> (u16, Option<u64>) {
        (code::F129_HEARTBEAT, None)
    }

    /// 6.4.1.1: in Switched on the output stage is on and holds the axis (with the hardware
    /// enable present); transition 5 stops with the profile deceleration and holds.
    fn disable_reaction(&self, od: &Dictionary, from: State, to: State) -> DisableReaction {
        if to == State::SwitchedOn && self.conditions.hardware_enable {
            DisableReaction::hold(StopRamp::ProfileDeceleration)
        } else {
            DisableReaction::cia402(od, from, to)
        }
    }

    /// The quick stop ramp (CS.DEC) for every fault.
    fn fault_ramp(&self, _od: &Dictionary, _error: &ErrorSpec) -> StopRamp {
        StopRamp::QuickStopDeceleration
    }

    fn scale(&self, od: &Dictionary) -> BusScale {
        FactorGroup::read(od).scale
    }

    fn configure(&mut self, od: &Dictionary, scale: &BusScale, cfg: &mut AxisConfig) {
        cfg.units = Units::default();
        let ramp = sat_u32(rpm_counts(motor::RAMP_RPM_PER_S));
        let acc = |index: u16, sub: u8| {
            read_int(od, index, sub).filter(|v| *v > 0).map(|v| sat_u32(scale.acceleration_in(v)))
        };
        if cfg.profile_acceleration == 0 {
            cfg.profile_acceleration = acc(0x3501, 0).unwrap_or(ramp);
        }
        if cfg.profile_deceleration == 0 {
            cfg.profile_deceleration = acc(0x3522, 0).unwrap_or(ramp);
        }
        cfg.quick_stop_deceleration = acc(0x3440, 1).unwrap_or(ramp);
        cfg.max_profile_velocity = sat_u32(rpm_counts(top_speed_rpm(od)));
        cfg.max_torque = match read_int(od, 0x6072, 0).filter(|v| *v > 0) {
            Some(t) => sat_u32(t),
            None => motor::PEAK_TORQUE_PERMILLE,
        };
        // MT.TPOSWND (35C6h): the in-position window, user units.
        if let Some(w) = read_int(od, 0x35C6, 0).filter(|v| *v > 0) {
            cfg.position_window = sat_u32(scale.position_in(w));
        }
        cfg.software_limits = match self.limits {
            Some((lo, hi)) => SoftwareLimits {
                enabled: true,
                min: sat_i32(scale.position_in(lo)),
                max: sat_i32(scale.position_in(hi)),
            },
            None => SoftwareLimits::default(),
        };
        let h = &mut cfg.homing;
        if h.search_speed == 0 {
            h.search_speed = sat_u32(rpm_counts(motor::HOMING_RPM));
        }
        if h.zero_speed == 0 {
            h.zero_speed = (h.search_speed / 8).max(1);
        }
        if h.acceleration == 0 {
            h.acceleration = acc(0x3502, 0).unwrap_or(ramp);
            h.deceleration = acc(0x3524, 0).unwrap_or(ramp);
        }
        h.offset_mode = HomeOffsetMode::AssignOffset;
        if read_int(od, 0x60C0, 0) == Some(-2) {
            // PVT: one point per control tick, on the cubic.
            cfg.interpolation.period_us = 1000;
            cfg.interpolation.buffer_capacity = 2;
        }
        cfg.plant = plant();
        cfg.plant.inertia *= self.inertia_factor;
    }

    fn init(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let od = ctx.od_mut();
        let _ = od.set_ascii_channel_command(b"");
        let _ = od.set_ascii_channel_response(b"");
        // 6.11.2.2: limits changed over the bus take effect after save and restart.
        self.limits = Self::limits_of(ctx.od());
        self.warnings.clear();
        self.clip_warning = None;
        self.limit_fault = false;
        self.switch_stop = None;
        self.leaving = None;
        self.following_fault = false;
        self.homing_failed = false;
        self.heat_fault = false;
        self.sto_fault = false;
        self.din_changed = 0;
        self.outputs = 0;
        self.last_sync = None;
        self.sync_period = None;
        self.sync_lost = false;
        self.pvt_queue.clear();
        self.pvt_run = None;
        self.ascii_input.clear();
        self.ascii_output.clear();
        drive.axis_mut().set_brake(false);
        drive.mark_dirty();
    }

    fn on_write(&mut self, _drive: &Drive, od: &Dictionary, w: &WriteRequest<'_>) -> Result<(), AbortCode> {
        let value = w.as_u64();
        match (w.index, w.sub) {
            // 6.5.2.1: "the value 0 must not be used"; 608Fh/6092h divide.
            (0x204C | 0x608F | 0x6092, 1 | 2) if value == 0 => Err(AbortCode::INVALID_VALUE),
            (0x6099, 1 | 2) | (0x6081, 0) => {
                let fg = FactorGroup::read(od);
                let counts = fg.scale.speed_in(i64::try_from(value).unwrap_or(i64::MAX));
                if counts > rpm_counts(top_speed_rpm(od)) { Err(AbortCode::VALUE_TOO_HIGH) } else { Ok(()) }
            }
            _ => Ok(()),
        }
    }

    fn pre_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, event: &Event) -> bool {
        match *event {
            // 5.4.8: F129, the EMCY's first manufacturer byte naming the lost node.
            Event::HeartbeatTimeout { node } => {
                let mut spec = drive.errors().resolve(code::F129_HEARTBEAT, None);
                spec.manufacturer = Some(u64::from(node));
                drive.raise_spec(ctx, &spec);
                true
            }
            Event::Sync { .. } => {
                let now = ctx.now();
                if let Some(last) = self.last_sync {
                    self.sync_period = Some(now.saturating_sub(last));
                }
                self.last_sync = Some(now);
                if drive.mode() == Mode::InterpolatedPosition {
                    self.interpolation_sync(drive, ctx);
                    true
                } else if Self::csp(drive) {
                    self.csp_sync(drive, ctx);
                    true
                } else {
                    false
                }
            }
            _ => false,
        }
    }

    /// 7.2.1.9: an upload of 2026h sub 2 hands out the next four characters of the answer
    /// (an expedited transfer), nothing once it is read.
    fn on_upload(&mut self, _drive: &Drive, _od: &Dictionary, index: u16, sub: u8, buf: &mut [u8]) -> Option<usize> {
        if (index, sub) != (0x2026, 2) {
            return None;
        }
        let n = self.ascii_output.len().min(ASCII_CHUNK).min(buf.len());
        for (slot, b) in buf.iter_mut().zip(self.ascii_output.drain(..n)) {
            *slot = b;
        }
        Some(n)
    }

    /// 6.6.2.1: 606Ch in a PDO is the velocity in rpm (at the object's 1000:1 bus factor),
    /// where an SDO read gives user units.
    fn on_tpdo(&mut self, drive: &Drive, _od: &Dictionary, map: &[MappedHandle], data: &mut [u8; 8]) {
        let mut offset = 0u32;
        for e in map {
            let bits = u32::from(e.bits);
            if (e.index, e.sub, bits) == (0x606C, 0, 32) && offset + bits <= 64 {
                let counts = i64::from(drive.status().velocity_actual);
                let rpm_milli = scale_i64(counts, Ratio::new(60_000, COUNTS_PER_TURN));
                let rpm_milli = if drive.scale().reverse_velocity { -rpm_milli } else { rpm_milli };
                let value = u64::from(sat_i32(rpm_milli) as u32);
                let mut word = u64::from_le_bytes(*data);
                word = (word & !(0xFFFF_FFFFu64 << offset)) | (value << offset);
                *data = word.to_le_bytes();
            }
            offset += bits;
        }
    }

    fn on_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, event: &Event) {
        match *event {
            Event::Written { index: 0x20B8, .. } => {
                let reset = read_int(ctx.od(), 0x20B8, 0).unwrap_or(0) as u8;
                self.din_changed &= !(reset & 0x7F);
            }
            Event::Written { index: 0x60FE, .. } => self.apply_outputs(drive, ctx.od()),
            Event::Written { index: 0x2026, sub: 1, .. } => self.ascii_write(drive, ctx),
            // 6.7.2.1: the target current in mA, an alternative to 6071h.
            Event::Written { index: 0x2071, sub: 0, .. } => {
                let ma = read_int(ctx.od(), 0x2071, 0).unwrap_or(0);
                let rated = rated_current_ma(ctx.od());
                let permille = (ma * 1000 / rated).clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16;
                let _ = ctx.write(0x6071, 0, &permille.to_le_bytes());
            }
            Event::Written { index: 0x60C4, sub: 6, .. } => {
                drive.axis_mut().clear_interpolation_buffer();
                self.pvt_queue.clear();
            }
            Event::Written { index: 0x6060, .. } if self.switch_stop.is_some() => {
                self.release_switch_stop(drive);
                if Self::csp(drive) {
                    drive.axis_mut().set_mode(Mode::InterpolatedPosition);
                }
            }
            Event::Written { index: 0x6060, .. } | Event::Reset(od_runtime::ResetKind::Node) if Self::csp(drive) => {
                drive.axis_mut().set_mode(Mode::InterpolatedPosition);
            }
            _ => {}
        }
    }

    fn before_command(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, cmd: &mut Command) -> bool {
        // Stopped on a limit switch: a command away from it releases the stop, one towards it
        // is not taken (the sidecar's decision on 60FDh).
        if let Some(side) = self.switch_stop {
            let reversed = if drive.axis().config().reverse_polarity { -1 } else { 1 };
            let here = i64::from(drive.axis().status().position_actual);
            let heading = match *cmd {
                Command::SetPoint(sp) => {
                    let target = i64::from(sp.target) + if sp.relative { here } else { 0 };
                    Some((target - here).signum())
                }
                Command::TargetVelocity(v) => Some(i64::from(v).signum()),
                Command::TargetTorque(t) => Some(i64::from(t).signum()),
                _ => None,
            };
            match heading.map(|h| h * reversed) {
                Some(h) if h == i64::from(side) => return false,
                Some(_) => {
                    self.release_switch_stop(drive);
                    self.leaving = Some(side);
                }
                None => {}
            }
        } else if let Some(side) = self.leaving {
            // Heading for the switch being left again: it stops the axis again when reached.
            let reversed = if drive.axis().config().reverse_polarity { -1 } else { 1 };
            let here = i64::from(drive.axis().status().position_actual);
            let heading = match *cmd {
                Command::SetPoint(sp) => Some((i64::from(sp.target) - if sp.relative { 0 } else { here }).signum()),
                Command::TargetVelocity(v) => Some(i64::from(v).signum()),
                Command::TargetTorque(t) => Some(i64::from(t).signum()),
                _ => None,
            };
            if heading.map(|h| h * reversed) == Some(i64::from(side)) {
                self.leaving = None;
            }
        }
        if let Command::SetPoint(sp) = cmd
            && let Some((lo, hi)) = self.limits
        {
            let s = drive.scale();
            let base = if sp.relative { i64::from(drive.axis().status().position_demand) } else { 0 };
            let target = base + i64::from(sp.target);
            let want = if target > s.position_in(hi) {
                Some(code::N107_POSITIVE_LIMIT)
            } else if target < s.position_in(lo) {
                Some(code::N108_NEGATIVE_LIMIT)
            } else {
                None
            };
            self.set_clip_warning(drive, ctx, want);
        }
        true
    }

    fn before_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>) {
        let now = ctx.now();
        let dt = self.last_now.map_or(0, |t| now.saturating_sub(t));
        self.last_now = Some(now);
        self.check_conditions(drive, ctx);
        // Mode 8 runs on the interpolator, enabled whenever the power stage is.
        if Self::csp(drive) {
            let st = drive.axis().status();
            if st.power && !st.interpolation_active && drive.state() == State::OperationEnabled {
                drive.axis_mut().set_interpolation_enabled(true);
            }
        }
        if read_int(ctx.od(), 0x60C0, 0) == Some(-2) && dt > 0 {
            self.pvt_step(drive, ctx, dt as f64 * 1e-6);
        }
        // 4.4 FBUS.PARAM04 = 1: three SYNCs missing in a synchronous mode is F125.
        let synchronous = (drive.mode() == Mode::InterpolatedPosition || Self::csp(drive))
            && drive.axis().status().interpolation_active;
        if read_int(ctx.od(), 0x36E8, 0) == Some(1) && synchronous {
            if let (Some(last), Some(period)) = (self.last_sync, self.sync_period.filter(|p| *p > 0)) {
                let lost = now.saturating_sub(last) > period.saturating_mul(3) + period / 2;
                if lost && !self.sync_lost && drive.fault().is_none() {
                    self.sync_lost = true;
                    drive.raise(ctx, code::F125_SYNC_LOST, None);
                }
            }
        } else {
            self.sync_lost = false;
        }
    }

    fn after_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, Dictionary>, status: &Status) {
        self.homing_error(drive, ctx, status);
        if status.following_error_exceeded && !self.following_fault && drive.fault().is_none() {
            self.following_fault = true;
            drive.raise(ctx, code::F439_FOLLOWING_ERROR, None);
        } else if !status.following_error_exceeded {
            self.following_fault = false;
        }
        self.check_limits(drive, ctx, status);
        self.check_switches(drive, ctx, status);
        // Inputs (60FDh): switches, DIN1..7, change latches.
        let din = self.din(status);
        self.din_changed |= din ^ self.din_last;
        self.din_last = din;
        let i = status.inputs;
        let inputs = u32::from(i.negative_limit)
            | u32::from(i.positive_limit) << 1
            | u32::from(i.home_switch) << 2
            | u32::from(din & 0x7F) << 16
            | u32::from(self.din_changed & 0x7F) << 24;
        // 60C4h sub 2: the usable buffer, one less than its size (6.9.2.4: 10, actual 9).
        let size = read_int(ctx.od(), 0x60C4, 1).unwrap_or(10).clamp(1, 1024);
        let free = size - 1 - status.interpolation_buffered as i64 - self.pvt_queue.len() as i64;
        let status_register = self.manufacturer_status(drive, status);
        let od = ctx.od_mut();
        write_int(od, 0x60FD, 0, i64::from(inputs));
        write_int(od, 0x1002, 0, i64::from(status_register));
        write_int(od, 0x60C4, 2, free.max(0));
    }

    /// 6063h in 608Fh increments, 606Ch at 1000:1 (7.1.4), 2077h in mA: every tick and at once
    /// after a factor-group write.
    fn actual_values(&mut self, _drive: &Drive, od: &mut Dictionary, status: &Status) {
        let fg = FactorGroup::read(od);
        let velocity = i64::from(status.velocity_actual);
        let rated = rated_current_ma(od);
        write_int(od, 0x6063, 0, fg.counts_to_increments(i64::from(status.position_actual)));
        write_int(od, 0x606C, 0, fg.scale.velocity_out(velocity.saturating_mul(1000)));
        write_int(od, 0x2077, 0, i64::from(status.torque_actual) * rated / 1000);
    }

    fn statusword(&self, drive: &Drive, _od: &Dictionary, status: &Status, bits: &mut u16) {
        let set = |bits: &mut u16, n: u16, on: bool| {
            if on {
                *bits |= 1 << n;
            } else {
                *bits &= !(1 << n);
            }
        };
        set(bits, 7, !self.warnings.is_empty());
        if self.switch_stop.is_some() {
            // Stopped on a limit switch: the target is not reached, the motion was limited.
            set(bits, 10, false);
            set(bits, 11, true);
        }
        // 7.2.1.2, 7.2.1.8: 0x0233 in Switched on whatever the axis does; the homing result
        // stays visible.
        if drive.state() != State::OperationEnabled && drive.mode() != Mode::Homing {
            set(bits, 10, false);
            set(bits, 12, false);
            set(bits, 13, false);
        }
        match drive.mode() {
            Mode::Homing => match status.homing {
                // 7.2.1.7, 7.2.1.8: 0x0237 before and during the homing, 0x0637 then 0x1637.
                HomingState::Idle | HomingState::InProgress | HomingState::Attained => {
                    set(bits, 10, false);
                    set(bits, 12, false);
                }
                HomingState::Completed => set(bits, 12, self.homing_done_ticks > 1),
                _ => {}
            },
            // 7.2.2.1: 0x0237 and 0x1237 in interpolated position mode; no mode has no target.
            Mode::InterpolatedPosition | Mode::NoMode => set(bits, 10, false),
            _ => {}
        }
        if Self::csp(drive) {
            // CiA 402 csp: bit 12 "drive follows the command value", bit 13 following error.
            set(bits, 10, false);
            set(bits, 12, status.interpolation_active);
            set(bits, 13, status.following_error_exceeded);
        }
    }

    fn on_fault_reset(&mut self, _drive: &mut Drive, _ctx: &mut Ctx<'_, Dictionary>) {
        // Conditions still present raise their fault again at the next tick (6.4.1.2
        // transition 15: "if no error exists in the drive").
        self.heat_fault = false;
        self.sto_fault = false;
        self.following_fault = false;
        self.homing_failed = false;
        self.sync_lost = false;
    }
}

#[cfg(test)]
mod ascii_tests {
    use super::*;

    #[test]
    fn numbers_parse_with_checked_arithmetic() {
        assert_eq!(parse_milli("-12.5"), Ok(-12_500));
        assert_eq!(parse_milli("0.0019"), Ok(1));
        assert_eq!(parse_milli("42"), Ok(42_000));
        assert_eq!(parse_milli("x1"), Err(NumberError::NotANumber));
        assert_eq!(parse_milli("-"), Err(NumberError::NotANumber));
        assert_eq!(parse_milli("1.2.3"), Err(NumberError::NotANumber));
        // i128::MAX / 1000 has 36 digits: 37 are out of range, whatever they are.
        assert_eq!(parse_milli(&"9".repeat(37)), Err(NumberError::OutOfRange));
        assert_eq!(parse_milli(&"1".repeat(80)), Err(NumberError::OutOfRange));
        assert!(parse_milli("170141183460469231731687303715884105").is_ok());
    }
}
