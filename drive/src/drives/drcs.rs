//! The Camozzi DRCS stepper drive, as its CANopen manual describes it, on top of the common
//! CiA 402 layer ([`super::cia402`]).
//!
//! | manual | behaviour | here |
//! |---|---|---|
//! | 3.4.4, 3.4.26 | modes 1 (profile position), 3 (profile velocity), 6 (homing); 0 = no mode | [`Vendor::supports_mode`] |
//! | chapter 4, 3.6.1 | units: mm, mm/s, mm/s² with an actuator configured by QSet, °, °/s, °/s² for "only motor"; 2001h: value = default value × numerator / denominator for positions, velocities and accelerations, on SDO and PDOs alike (the dictionary holds bus values, so PDOs carry what SDO reads) | [`Vendor::scale`]; the axis runs in µm (or m°) |
//! | chapter 4, 3.4.14 | software limits 607Dh: 0 and the actuator's full scale, relative to the homing position, not set for "only motor"; a target outside is an error (7320h) and the motor does not move | [`Mechanics`], [`Vendor::before_command`] |
//! | chapter 5 | profile position: bit 4 starts, bit 6 relative; statusword bit 12 high while the positioning runs until the command ends, bit 10 target reached; the target cannot change during a movement (refused) | [`Vendor::before_command`], [`Vendor::statusword`] |
//! | chapter 6, 3.4.8..3.4.11 | profile velocity: moves while halt is 0 and 60FFh ≠ 0; bit 10 target reached within 606Dh for 606Eh (halt: stopped), bit 12 zero speed below 606Fh for 6070h | common layer |
//! | chapter 7, 3.4.13 | homing 17 (proximity, negative), 18 (positive), 37 (current position) with 6099h, 6083h/6084h as homing ramps, 607Ch: move by the offset and make that position zero; statusword bits 13/12/10 as in chapter 7's table; error 8613h when the proximity is not found (end of the stroke, timeout) | [`Vendor::configure`], [`Vendor::after_step`] |
//! | chapter 7, 3.2.4 | homing is required after start-up before any movement: a movement command without it is error FF13h "operation without reset" | [`Vendor::before_command`] |
//! | 3.6.2, 3.6.3, 3.6.4 | inputs 2002h (In 1-8, Enable, Strobe, Proxy home, Proxy ext), outputs 2003h (Alarm, Busy, Out, Pos ok, Homing ok, Ready), homing status 2004h | [`Vendor::after_step`], [`Conditions`] |
//! | 3.6.5 | brake 2005h (1 = engaged): engaged while the motor is torqueless, released with torque; writable only torqueless (0 releases it to move the axis by hand until the next power-stage change) | [`Drcs`] |
//! | 3.6.6..3.6.9 | counters 2100h torqueless, 2101h torque on and stopped, 2102h torque on and moving (s), 2103h total stroke (motor revolutions, both directions) | [`Counters`] |
//! | 3.2.4 | errors 2310h, 3120h, 4210h, 6320h, 7305h (power stage off), 8613h (quick stop), 7320h, FF13h, 5530h (reported only: EMCY, 1003h, 1001h, statusword bit 7 until the next accepted command) | the sidecar's table through [`super::Drive::raise`]; causes from [`Conditions`] and the axis |
//! | 3.2.11, 3.2.12 | life guarding (100Ch × 100Dh) lost: an error, then the communication is reset | the sidecar lists 8130h (quick stop, a decision there); [`Vendor::after_step`] resets the communication once in Fault |
//! | 3.2.13 | 1010h stores the objects of the manual's list only | the sidecar's `[store]` list through [`super::store`] |
//! | 3.2.25 | 1F80h: only bits 2 and 3 may be set (others abort); bit 3 with bit 2 clear starts the node by itself | [`Vendor::on_write`], [`Vendor::before_step`] |
//! | 3.4.15 | polarity 607Eh bit 7 reverses the direction, also of the homing searches | [`Vendor::polarity_reverses_homing`] |
//!
//! Decisions where the manual is silent or unclear:
//! * the DRCS has no heartbeat consumer (no 1016h in table 3.1): the loss of the master it can
//!   detect is life guarding. The loss is the "fieldbus disconnection" error 8130h (CiA 301
//!   life guard error, not in the 3.2.4 list: the sidecar adds it with a decision), a soft
//!   error: the axis stops on the quick stop ramp (6084h, the DRCS has no 6085h), the drive
//!   goes to Fault, and then (3.2.12: the guarding messages must arrive "to avoid an error and
//!   reset the communication") the communication is reset: boot-up message, pre-operational.
//! * a relative target is relative to the actual position (the DRCS refuses new targets
//!   during a movement, so this differs from CiA 402's "previous target" only after a halt;
//!   the Camozzi DRVI documents the actual position).
//! * homing errors of every kind (proximity not found before an end stop, timeout, zero
//!   speeds) are 8613h, the only homing error of the list. The timeout is the time to travel
//!   twice the [`Mechanics::homing_stroke`] plus the home offset at the fast speed, plus 5 s.
//! * reset node restarts the drive's position counter at 0 and loses the homing (a stepper
//!   without an absolute encoder); the counters 2100h..2103h keep counting ("since it left the
//!   factory") for as long as the simulation runs.
//! * step loss (7305h, with the optional external encoder, 608Fh) is a following error above
//!   two full steps (1/100 motor revolution), checked outside homing.
//! * statusword bit 7 (warning) is set while a reported-only error (7320h, FF13h, 5530h) is
//!   outstanding; the next accepted command (or a fault reset) sends the error reset EMCY.
//! * the 1003h list's electrical causes are simulated through [`Conditions`]: supply below
//!   18 V (3120h), drive temperature above 85 °C (4210h), an overcurrent flag (2310h), a motor
//!   configuration flag (6320h), a flash flag checked after each reset node (5530h).

use generated::drcs::Dictionary;
use generated::drcs::units::System;
use od_runtime::cia402::State;
use od_runtime::od::{AbortCode, ObjectDictionary};
use od_runtime::{Event, Micros, NmtCommand};

use super::cia402::{BusScale, Cia402App, Command, Vendor, read_int, write_int};
use super::{Drive, Reaction, error_table};
use crate::motion::{
    AxisConfig, Cam, Environment, HomeOffsetMode, HomingMethod, HomingState, Machine, Mode, PlantConfig, Ratio,
    RelativeBase, SoftwareLimits, Status, Travel, Units,
};
use crate::node::{Ctx, DeviceKind, WriteRequest};

/// Internal units per default bus unit: the axis runs in µm (actuator) or m° (only motor).
pub const INTERNAL_PER_UNIT: i64 = 1000;
/// Microsteps per motor revolution (chapter 4).
pub const MICROSTEPS_PER_REV: u32 = 3200;
/// Full steps per motor revolution (a 1.8° stepper).
pub const FULL_STEPS_PER_REV: u32 = 200;
/// The phase current limit of the DRCS-A05 (mA): the torque unit of the simulated mechanics.
pub const CURRENT_LIMIT_MA: u32 = 5000;

/// The error codes of 3.2.4 (and the fieldbus disconnection this simulation adds).
pub mod code {
    /// Overcurrent error.
    pub const OVERCURRENT: u16 = 0x2310;
    /// Power voltage absent/too low error.
    pub const UNDERVOLTAGE: u16 = 0x3120;
    /// Temperature too high error.
    pub const TEMPERATURE: u16 = 0x4210;
    /// Position, step loss (if external encoder present) error.
    pub const STEP_LOSS: u16 = 0x7305;
    /// Homing procedure timeout error.
    pub const HOMING: u16 = 0x8613;
    /// Motor configuration error.
    pub const MOTOR_CONFIGURATION: u16 = 0x6320;
    /// Positioning out of software limits error.
    pub const SOFTWARE_LIMIT: u16 = 0x7320;
    /// Operation without reset (a movement before homing).
    pub const NOT_HOMED: u16 = 0xFF13;
    /// Flash data lost.
    pub const FLASH: u16 = 0x5530;
    /// Fieldbus disconnection: life guarding lost (CiA 301 8130h; not in the 3.2.4 list).
    pub const FIELDBUS: u16 = 0x8130;
}

/// 2002h bits (3.6.2).
pub mod input {
    /// In 1 (bit 0) .. In 8 (bit 7).
    pub const IN_MASK: u32 = 0xFF;
    /// Hardware enable (ENB, pin 4).
    pub const ENABLE: u32 = 1 << 8;
    /// Strobe.
    pub const STROBE: u32 = 1 << 9;
    /// Zero proximity (the home switch).
    pub const PROXY_HOME: u32 = 1 << 10;
    /// External proximity.
    pub const PROXY_EXT: u32 = 1 << 11;
}

/// 2003h bits (3.6.3).
pub mod output {
    /// Alarm: the drive is in Fault (or its fault reaction).
    pub const ALARM: u32 = 1 << 0;
    /// Busy: the axis is moving or homing.
    pub const BUSY: u32 = 1 << 1;
    /// The output QSet programs.
    pub const OUT: u32 = 1 << 2;
    /// Position reached (profile position, target reached).
    pub const POS_OK: u32 = 1 << 3;
    /// Homing done.
    pub const HOMING_OK: u32 = 1 << 4;
    /// Ready: Operation enabled.
    pub const READY: u32 = 1 << 5;
}

/// What QSet configured: the unit system, the actuator's ratios and stroke, and the mechanics
/// along the axis. Positions are internal units (µm, or m° for "only motor") in the mechanical
/// frame: 0 is where the carriage stands when the drive starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// Actuator (mm) or only motor (°).
    pub system: System,
    /// The actuator's full scale (607Dh sub 2, internal units; sub 1 is 0); `None` for "only
    /// motor" (no software limits).
    pub full_scale: Option<i64>,
    /// 6091h: motor revolutions, shaft revolutions.
    pub gear_ratio: (u32, u32),
    /// 6092h: feed (mm), shaft revolutions.
    pub feed_constant: (u32, u32),
    /// Sensors and end stops.
    pub environment: Environment,
    /// The longest travel a homing search may need (internal units): sets its timeout.
    pub homing_stroke: i64,
    /// The machine's inertia on the built-in one ([`Machine::inertia_factor`]).
    pub inertia_factor: f64,
}

impl Mechanics {
    /// A belt axis of 1000 mm stroke, 70 mm per pulley revolution, direct drive: its zero
    /// proximity is active from 100 mm below the start position down to the negative end
    /// (40 mm long, so a search at 50 mm/s with 100 mm/s² stops on it), end stops 50 mm below
    /// the proximity's edge and 10 mm beyond the full scale, an encoder index every motor
    /// revolution.
    pub fn actuator() -> Self {
        Self {
            system: System::Actuator,
            full_scale: Some(1_000_000),
            gear_ratio: (1, 1),
            feed_constant: (70, 1),
            environment: Environment {
                home_switch: Some(Cam { low: -140_000, high: -100_000 }),
                negative_limit: None,
                positive_limit: None,
                negative_end_stop: Some(-150_000),
                positive_end_stop: Some(910_000),
                index_period: 70_000,
                index_phase: 0,
            },
            homing_stroke: 1_060_000,
            inertia_factor: 1.0,
        }
    }

    /// A motor without an actuator ("only motor" in QSet): degrees, no software limits, no end
    /// stops, a proximity cam from −140° to −100° should a homing 17/18 be used.
    pub fn only_motor() -> Self {
        Self {
            system: System::OnlyMotor,
            full_scale: None,
            gear_ratio: (1, 1),
            feed_constant: (1, 1),
            environment: Environment {
                home_switch: Some(Cam { low: -140_000, high: -100_000 }),
                negative_limit: None,
                positive_limit: None,
                negative_end_stop: None,
                positive_end_stop: None,
                index_period: 360_000,
                index_phase: 0,
            },
            homing_stroke: 3_600_000,
            inertia_factor: 1.0,
        }
    }

    /// What QSet configures for `machine` (positions in mm, or ° for a rotary one): a linear
    /// machine is an actuator of the belt's ratios (70 mm per turn, direct drive) with its
    /// stroke as the full scale; a rotary one is "only motor".
    pub fn from_machine(machine: &Machine) -> Self {
        let unit = INTERNAL_PER_UNIT as f64;
        let inertia_factor = machine.inertia_factor();
        match machine.travel {
            Travel::Rotary => {
                Self { environment: machine.environment(unit, 360.0), inertia_factor, ..Self::only_motor() }
            }
            Travel::Linear => {
                let belt = Self::actuator();
                let environment = machine.environment(unit, belt.mm_per_motor_turn());
                let full_scale = machine.stroke.map(|s| (s * unit).round() as i64);
                // A search may have to cross the whole travel: between the end stops, else the
                // stroke, else the belt's.
                let travel = match (environment.negative_end_stop, environment.positive_end_stop) {
                    (Some(lo), Some(hi)) => hi.saturating_sub(lo),
                    _ => full_scale.map_or(belt.homing_stroke, |f| f.saturating_add(60_000)),
                };
                Self { full_scale, environment, homing_stroke: travel, inertia_factor, ..belt }
            }
        }
    }

    /// Millimetres of the actuator per motor turn: 6092h feed / shaft revolutions over 6091h
    /// motor / shaft revolutions (3.4.20, 3.4.21; a zero term counts as 1).
    pub fn mm_per_motor_turn(&self) -> f64 {
        let r = |(a, b): (u32, u32)| f64::from(a.max(1)) / f64::from(b.max(1));
        r(self.feed_constant) / r(self.gear_ratio)
    }

    /// Internal units per motor revolution, from 6091h and 6092h as the dictionary holds them
    /// (the actuator: feed / gear ratio in mm), or 360° (only motor).
    pub fn internal_per_revolution<OD: ObjectDictionary>(&self, od: &OD) -> f64 {
        match self.system {
            System::OnlyMotor => 360.0 * INTERNAL_PER_UNIT as f64,
            System::Actuator => {
                let get = |i: u16, s: u8| read_int(od, i, s).filter(|v| *v > 0).unwrap_or(1) as f64;
                let mm_per_shaft_rev = get(0x6092, 1) / get(0x6092, 2);
                let motor_per_shaft_rev = get(0x6091, 1) / get(0x6091, 2);
                mm_per_shaft_rev / motor_per_shaft_rev * INTERNAL_PER_UNIT as f64
            }
        }
    }

    /// The mechanics' constants (torque in mA, internal position units): 1 A accelerates the
    /// load at 10 m/s² (3600 °/s² for the bare motor), viscous friction takes 1 A at 1 m/s
    /// (3600 °/s), 50 mA dry friction.
    pub fn plant(&self) -> PlantConfig {
        let (acc, speed) = match self.system {
            System::Actuator => (1.0e7, 1.0e6),
            System::OnlyMotor => (3.6e6, 3.6e6),
        };
        PlantConfig {
            inertia: 1000.0 / acc * self.inertia_factor,
            viscous: 1000.0 / speed,
            coulomb: 50.0,
            bandwidth: 300.0,
            max_speed: 2.0 * speed,
        }
    }
}

/// What the drive measures around it; tests change these to provoke the errors of 3.2.4 and
/// to set the inputs of 2002h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    /// Power supply, mV (below 18 V: 3120h).
    pub supply_mv: u32,
    /// Drive temperature, °C (above 85 °C: 4210h).
    pub temperature_c: f64,
    /// An overcurrent is detected (2310h).
    pub overcurrent: bool,
    /// The motor configuration is valid (otherwise 6320h).
    pub motor_configured: bool,
    /// The stored data survived (otherwise 5530h after each reset node).
    pub flash_ok: bool,
    /// The optional external encoder is fitted (step-loss detection, 7305h).
    pub external_encoder: bool,
    /// The hardware enable input ENB (2002h bit 8).
    pub enable: bool,
    /// In 1..In 8 (2002h bits 0..7).
    pub inputs: u8,
    /// The strobe input (2002h bit 9).
    pub strobe: bool,
    /// The external proximity (2002h bit 11; a limit switch of the mechanics also sets it).
    pub proxy_ext: bool,
    /// The output QSet programs (2003h bit 2).
    pub out: bool,
}

impl Default for Conditions {
    fn default() -> Self {
        Self {
            supply_mv: 48_000,
            temperature_c: 35.0,
            overcurrent: false,
            motor_configured: true,
            flash_ok: true,
            external_encoder: true,
            enable: true,
            inputs: 0,
            strobe: false,
            proxy_ext: false,
            out: false,
        }
    }
}

/// A condition-driven error: raised when it appears, again after a fault reset if it persists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cause {
    Overcurrent,
    Undervoltage,
    Temperature,
    MotorConfiguration,
    StepLoss,
}

impl Cause {
    const ALL: [Cause; 5] =
        [Cause::Overcurrent, Cause::Undervoltage, Cause::Temperature, Cause::MotorConfiguration, Cause::StepLoss];

    fn code(self) -> u16 {
        match self {
            Cause::Overcurrent => code::OVERCURRENT,
            Cause::Undervoltage => code::UNDERVOLTAGE,
            Cause::Temperature => code::TEMPERATURE,
            Cause::MotorConfiguration => code::MOTOR_CONFIGURATION,
            Cause::StepLoss => code::STEP_LOSS,
        }
    }

    fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

/// The counters of 3.6.6..3.6.9, with sub-second resolution.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Counters {
    /// Torqueless (power stage off), µs.
    pub torqueless_us: u64,
    /// Torque on and stopped, µs.
    pub stopped_us: u64,
    /// Torque on and moving, µs.
    pub moving_us: u64,
    /// Distance travelled in either direction, internal units.
    pub stroke: f64,
}

/// The DRCS behaviour on top of the common CiA 402 drive.
#[derive(Clone, Debug)]
pub struct Drcs {
    /// Supplies, temperature, inputs.
    pub conditions: Conditions,
    mechanics: Mechanics,
    counters: Counters,
    last_now: Option<Micros>,
    /// Causes currently raised (bit per [`Cause`]).
    raised: u8,
    /// 1001h bits of reported-only errors not yet cleared.
    reported: u8,
    homing_failed: bool,
    was_homed: bool,
    /// 2005h = 0 written while torqueless: the brake stays released until the power stage
    /// changes.
    manual_release: bool,
    last_power: bool,
    last_cw: u16,
    start_pending: bool,
    flash_check_pending: bool,
}

impl Drcs {
    /// A DRCS with mechanics `mechanics` (what QSet configured).
    pub fn new(mechanics: Mechanics) -> Self {
        Self {
            conditions: Conditions::default(),
            mechanics,
            counters: Counters::default(),
            last_now: None,
            raised: 0,
            reported: 0,
            homing_failed: false,
            was_homed: false,
            manual_release: false,
            last_power: false,
            last_cw: 0,
            start_pending: false,
            flash_check_pending: true,
        }
    }

    /// The configured mechanics.
    pub fn mechanics(&self) -> &Mechanics {
        &self.mechanics
    }

    /// The counters (2100h..2103h hold them in whole seconds and revolutions).
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Whether a reported-only error (7320h, FF13h, 5530h) is outstanding (statusword bit 7).
    pub fn warning(&self) -> bool {
        self.reported != 0
    }

    /// Raises a reported-only error: EMCY, 1003h, 1001h, 603Fh; statusword bit 7 until cleared.
    fn report<OD: ObjectDictionary>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, code: u16) {
        let spec = drive.raise(ctx, code, None);
        if matches!(spec.reaction, Reaction::None | Reaction::Warning) {
            self.reported |= spec.register_bits();
            write_int(ctx.od_mut(), 0x603F, 0, i64::from(code));
        }
    }

    /// Clears the reported-only errors with the error reset EMCY (not while a fault holds).
    fn clear_reported<OD: ObjectDictionary>(&mut self, drive: &Drive, ctx: &mut Ctx<'_, OD>) {
        if self.reported != 0 && drive.fault().is_none() {
            ctx.reset_error(self.reported);
            write_int(ctx.od_mut(), 0x603F, 0, 0);
            self.reported = 0;
        }
    }

    /// The brake follows the power stage (engaged torqueless unless released by hand).
    fn sync_brake(&mut self, drive: &mut Drive) {
        let status = drive.axis().status();
        if status.power != self.last_power {
            self.last_power = status.power;
            self.manual_release = false;
        }
        let engaged = !status.power && !self.manual_release;
        if status.brake != engaged {
            drive.axis_mut().set_brake(engaged);
        }
    }

    /// Software limits in internal units (0 and the full scale), when set.
    fn limits(&self) -> Option<(i64, i64)> {
        self.mechanics.full_scale.map(|fs| (fs.min(0), fs.max(0)))
    }

    fn check_conditions<OD: ObjectDictionary>(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        let c = self.conditions;
        let homing = matches!(status.homing, HomingState::InProgress | HomingState::Attained);
        let step_limit = self.mechanics.internal_per_revolution(ctx.od()) / f64::from(FULL_STEPS_PER_REV) * 2.0;
        let present = |cause: Cause| match cause {
            Cause::Overcurrent => c.overcurrent,
            Cause::Undervoltage => c.supply_mv < 18_000,
            Cause::Temperature => c.temperature_c > 85.0,
            Cause::MotorConfiguration => !c.motor_configured,
            Cause::StepLoss => {
                c.external_encoder && status.power && !homing && f64::from(status.following_error).abs() > step_limit
            }
        };
        for cause in Cause::ALL {
            if present(cause) {
                if self.raised & cause.bit() == 0 {
                    self.raised |= cause.bit();
                    drive.raise(ctx, cause.code(), None);
                }
            } else if drive.fault().is_none() {
                self.raised &= !cause.bit();
            }
        }
    }

    /// 607Dh in the bus unit of `scale`.
    fn write_limits<OD: ObjectDictionary>(&self, od: &mut OD, scale: &BusScale) {
        let (lo, hi) = self.limits().unwrap_or((0, 0));
        write_int(od, 0x607D, 1, scale.position_out(lo));
        write_int(od, 0x607D, 2, scale.position_out(hi));
    }

    fn count(&mut self, status: &Status, dt_us: u64) {
        let c = &mut self.counters;
        if !status.power {
            c.torqueless_us = c.torqueless_us.saturating_add(dt_us);
        } else if status.standing {
            c.stopped_us = c.stopped_us.saturating_add(dt_us);
        } else {
            c.moving_us = c.moving_us.saturating_add(dt_us);
        }
        c.stroke += f64::from(status.velocity_actual).abs() * dt_us as f64 * 1e-6;
    }

    fn write_objects<OD: ObjectDictionary>(&self, drive: &Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        // The unit 2001h sets now (the drive's own scale follows at its next reconfiguration).
        let scale = Vendor::<OD>::scale(self, ctx.od());
        let state = drive.state();
        let c = self.conditions;
        let inputs = u32::from(c.inputs)
            | if c.enable { input::ENABLE } else { 0 }
            | if c.strobe { input::STROBE } else { 0 }
            | if status.inputs.home_switch { input::PROXY_HOME } else { 0 }
            | if c.proxy_ext || status.inputs.negative_limit || status.inputs.positive_limit {
                input::PROXY_EXT
            } else {
                0
            };
        let homing = matches!(status.homing, HomingState::InProgress | HomingState::Attained);
        let outputs = if matches!(state, State::Fault | State::FaultReactionActive) { output::ALARM } else { 0 }
            | if status.power && (!status.standing || homing) { output::BUSY } else { 0 }
            | if c.out { output::OUT } else { 0 }
            | if drive.mode() == Mode::ProfilePosition && status.power && status.target_reached {
                output::POS_OK
            } else {
                0
            }
            | if status.homed { output::HOMING_OK } else { 0 }
            | if state == State::OperationEnabled { output::READY } else { 0 };
        let per_rev = self.mechanics.internal_per_revolution(ctx.od());
        let revolutions = if per_rev > 0.0 { (self.counters.stroke / per_rev).floor() as i64 } else { 0 };
        let secs = |us: u64| (us / 1_000_000) as i64;
        let m = self.mechanics;
        let od = ctx.od_mut();
        write_int(od, 0x2002, 0, i64::from(inputs));
        write_int(od, 0x2003, 0, i64::from(outputs));
        write_int(od, 0x2004, 0, i64::from(status.homed));
        write_int(od, 0x2005, 0, i64::from(status.brake));
        write_int(od, 0x2100, 0, secs(self.counters.torqueless_us));
        write_int(od, 0x2101, 0, secs(self.counters.stopped_us));
        write_int(od, 0x2102, 0, secs(self.counters.moving_us));
        write_int(od, 0x2103, 0, revolutions);
        self.write_limits(od, &scale);
        write_int(od, 0x6091, 1, i64::from(m.gear_ratio.0));
        write_int(od, 0x6091, 2, i64::from(m.gear_ratio.1));
        write_int(od, 0x6092, 1, i64::from(m.feed_constant.0));
        write_int(od, 0x6092, 2, i64::from(m.feed_constant.1));
    }
}

impl<OD: ObjectDictionary> Vendor<OD> for Drcs {
    /// 3.4.4: 1, 3, 6; 0 = no mode requested.
    fn supports_mode(&self, code: i8) -> bool {
        matches!(code, 0 | 1 | 3 | 6)
    }

    /// Chapter 7: 17, 18 and 37 (CiA 402 directions; 3.4.22 has 17 and 18 swapped).
    fn homing_method(&self, code: i8) -> Option<HomingMethod> {
        matches!(code, 17 | 18 | 37).then(|| HomingMethod::camozzi(code)).flatten()
    }

    /// 3.4.15: the polarity reverses the movement direction, the homing searches included.
    fn polarity_reverses_homing(&self) -> bool {
        true
    }

    /// 2001h: bus value = default-unit value × numerator / denominator, for positions,
    /// velocities and accelerations; the axis runs in thousandths of the default unit.
    fn scale(&self, od: &OD) -> BusScale {
        let num = read_int(od, 0x2001, 1).filter(|v| *v > 0).unwrap_or(1);
        let den = read_int(od, 0x2001, 2).filter(|v| *v > 0).unwrap_or(1);
        let r = Ratio::new(INTERNAL_PER_UNIT * den, num);
        BusScale { position: r, velocity: r, acceleration: r, ..BusScale::ONE }
    }

    fn configure(&mut self, _od: &OD, _scale: &BusScale, cfg: &mut AxisConfig) {
        // Internal units throughout: velocities in internal units/s, accelerations per s².
        cfg.units = Units { velocity: Ratio::ONE, acceleration: Ratio::ONE };
        cfg.relative_base = RelativeBase::ActualPosition;
        cfg.max_torque = CURRENT_LIMIT_MA;
        cfg.plant = self.mechanics.plant();
        // 607Dh comes from the mechanics (the dictionary shows them in the current unit).
        cfg.software_limits = match self.limits() {
            Some((lo, hi)) => SoftwareLimits {
                enabled: true,
                min: lo.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                max: hi.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
            },
            None => SoftwareLimits::default(),
        };
        // Chapter 7: the homing ramps are 6083h and 6084h; 3.4.13: move by the offset.
        let h = &mut cfg.homing;
        h.acceleration = cfg.profile_acceleration;
        h.deceleration = cfg.profile_deceleration;
        h.offset_mode = HomeOffsetMode::MoveByOffset;
        h.torque_limit = 0;
        h.torque_threshold = 0;
        h.timeout_us = if h.search_speed > 0 {
            let travel = 2.0 * self.mechanics.homing_stroke as f64 + f64::from(h.offset).abs();
            ((travel / f64::from(h.search_speed) + 5.0) * 1e6).min(u64::MAX as f64 / 2.0) as u64
        } else {
            0
        };
    }

    fn init(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        // A restart: the position counter starts at 0 and the homing is gone.
        drive.axis_mut().set_actual_position(0, false);
        self.raised = 0;
        self.reported = 0;
        self.homing_failed = matches!(drive.axis().status().homing, HomingState::Error(_));
        self.was_homed = false;
        self.last_cw = 0;
        self.manual_release = false;
        self.last_power = drive.axis().status().power;
        self.sync_brake(drive);
        // 3.2.25: bit 3 "start node" with bit 2 clear starts the node by itself.
        let startup = read_int(ctx.od(), 0x1F80, 0).unwrap_or(0);
        self.start_pending = startup & 0x08 != 0 && startup & 0x04 == 0;
        self.flash_check_pending = true;
        let status = drive.axis().status();
        self.write_objects(drive, ctx, &status);
    }

    fn on_write(&mut self, drive: &Drive, _od: &OD, write: &WriteRequest<'_>) -> Result<(), AbortCode> {
        match (write.index, write.sub) {
            (0x2001, 1 | 2) if write.as_u64() == 0 => Err(AbortCode::INVALID_VALUE),
            (0x2005, 0) if drive.axis().status().power => Err(AbortCode::DEVICE_STATE),
            (0x2005, 0) if write.as_u64() > 1 => Err(AbortCode::INVALID_VALUE),
            (0x1F80, 0) if write.as_u64() & !0x0C != 0 => Err(AbortCode::INVALID_VALUE),
            _ => Ok(()),
        }
    }

    fn on_event(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, event: &Event) {
        match *event {
            Event::Written { index: 0x2005, sub: 0, .. } => {
                let engaged = read_int(ctx.od(), 0x2005, 0).unwrap_or(1) != 0;
                if !drive.axis().status().power {
                    self.manual_release = !engaged;
                }
            }
            Event::Written { index: 0x6040, sub: 0, .. } => {
                let cw = drive.controlword();
                if cw & 0x80 != 0 && self.last_cw & 0x80 == 0 {
                    self.clear_reported(drive, ctx);
                }
                self.last_cw = cw;
            }
            _ => {}
        }
        self.sync_brake(drive);
        // What the event changed (brake, outputs) is visible at once, not only after a tick.
        let status = drive.axis().status();
        self.write_objects(drive, ctx, &status);
    }

    fn before_command(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, cmd: &mut Command) -> bool {
        let status = drive.axis().status();
        match *cmd {
            Command::SetPoint(sp) => {
                // Chapter 7: homing first.
                if !status.homed {
                    self.report(drive, ctx, code::NOT_HOMED);
                    return false;
                }
                // Chapter 5: the target cannot change during a movement.
                if !status.target_reached {
                    return false;
                }
                if let Some((lo, hi)) = self.limits() {
                    let target = i64::from(sp.target) + if sp.relative { i64::from(status.position_actual) } else { 0 };
                    if target < lo || target > hi {
                        self.report(drive, ctx, code::SOFTWARE_LIMIT);
                        return false;
                    }
                }
                self.clear_reported(drive, ctx);
            }
            Command::TargetVelocity(v) if v != 0 && !status.homed => {
                let moving = drive.mode() == Mode::ProfileVelocity
                    && drive.state() == State::OperationEnabled
                    && drive.controlword() & 0x100 == 0;
                if moving {
                    self.report(drive, ctx, code::NOT_HOMED);
                }
                return false;
            }
            Command::TargetVelocity(v) if v != 0 => self.clear_reported(drive, ctx),
            Command::StartHoming => self.clear_reported(drive, ctx),
            _ => {}
        }
        true
    }

    fn before_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        if self.start_pending {
            self.start_pending = false;
            ctx.nmt_command(NmtCommand::Start);
        }
        if self.flash_check_pending {
            self.flash_check_pending = false;
            if !self.conditions.flash_ok {
                self.report(drive, ctx, code::FLASH);
            }
        }
        self.sync_brake(drive);
        // Chapter 7: nothing moves before homing, whatever brought a velocity to the axis
        // (a reconfiguration re-applies 60FFh without the command hooks).
        let status = drive.axis().status();
        if !status.homed && drive.mode() == Mode::ProfileVelocity && status.power && !status.standing {
            let _ = drive.axis_mut().set_target_velocity(0);
        }
    }

    fn after_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
        let now = ctx.now();
        let dt = self.last_now.map_or(0, |t| now.saturating_sub(t));
        self.last_now = Some(now);
        self.count(status, dt);
        match status.homing {
            HomingState::Error(_) if !self.homing_failed => {
                self.homing_failed = true;
                drive.raise(ctx, code::HOMING, None);
            }
            HomingState::InProgress => self.homing_failed = false,
            _ => {}
        }
        if status.homed && !self.was_homed {
            // 60FFh was held back before homing: read it again.
            drive.mark_dirty();
        }
        self.was_homed = status.homed;
        self.check_conditions(drive, ctx, status);
        self.write_objects(drive, ctx, status);
    }

    fn statusword(&self, drive: &Drive, _od: &OD, status: &Status, bits: &mut u16) {
        let set = |bits: &mut u16, n: u16, on: bool| {
            if on {
                *bits |= 1 << n;
            } else {
                *bits &= !(1 << n);
            }
        };
        set(bits, 7, self.reported != 0);
        if drive.mode() == Mode::ProfilePosition {
            // Chapter 5: high while the positioning runs, low when a new command is accepted.
            set(bits, 12, status.set_point_acknowledge || (status.power && !status.target_reached));
        }
    }

    /// 3.2.12: a lost guarding master is "an error and reset the communication".
    fn reset_communication_on_link_loss(&self) -> bool {
        true
    }

    fn on_fault_reset(&mut self, _drive: &mut Drive, ctx: &mut Ctx<'_, OD>) {
        // Conditions still present raise again; a failed homing stays failed (and reported)
        // until the next homing starts.
        self.raised = 0;
        if self.reported != 0 {
            ctx.reset_error(self.reported);
            self.reported = 0;
        }
    }
}

/// A DRCS application with mechanics `mechanics`.
pub fn app_with(mechanics: Mechanics) -> Cia402App<Dictionary, Drcs> {
    let mut app = Cia402App::new(Drcs::new(mechanics), error_table(DeviceKind::Drcs));
    *app.drive_mut().axis_mut().environment_mut() = mechanics.environment;
    app
}

/// A DRCS on `machine` (positions in mm, or ° for a rotary one).
pub fn app_on(machine: &Machine) -> Cia402App<Dictionary, Drcs> {
    app_with(Mechanics::from_machine(machine))
}

/// A DRCS on its default machine, the belt axis of [`Mechanics::actuator`]: what `drive-sim`
/// runs.
pub fn app() -> Cia402App<Dictionary, Drcs> {
    app_on(&super::machine::default_machine(DeviceKind::Drcs))
}
