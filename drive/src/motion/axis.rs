//! The simulated axis: commands in, `step`, status out.

use super::config::{AxisConfig, Mode, RelativeBase, StopRamp};
use super::homing::{Cmd, HomeOffsetMode, HomingError, HomingKind, HomingState, Observation, Sequence};
use super::interp::Interpolator;
use super::plant::{Drive, Environment, Plant, Sensor};
use super::profile::Plan;
use super::units::{POSITION_LIMIT, TORQUE_LIMIT, VELOCITY_LIMIT, clamp_finite, to_i32};

/// A profile position set-point: the target and the controlword bits that came with bit 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SetPoint {
    /// Target position 607Ah.
    pub target: i32,
    /// Controlword bit 6: the target is relative (to [`crate::motion::AxisConfig::relative_base`]).
    pub relative: bool,
    /// Controlword bit 5: abort the current move and go to this target now. Without it the
    /// set-point waits in a one-entry buffer until the current move has reached its target.
    pub change_immediately: bool,
    /// Controlword bit 9 (change on set-point): when this set-point is buffered, the current
    /// move does not stop on its target but passes through it towards this one.
    pub change_on_set_point: bool,
}

/// Jog command from controlword bits 5 and 6 (DRVI Table 6.30).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum JogCommand {
    /// Bits 6/5 = 0/0: stop.
    #[default]
    Stop,
    /// Bit 6 = 1: clockwise, the positive direction.
    Positive,
    /// Bit 5 = 1: counter-clockwise, the negative direction.
    Negative,
    /// Both bits: invalid, the previous command persists.
    Invalid,
}

impl JogCommand {
    /// Decodes controlword bits 5 and 6.
    pub fn from_controlword(controlword: u16) -> JogCommand {
        match (controlword & 0x40 != 0, controlword & 0x20 != 0) {
            (false, false) => JogCommand::Stop,
            (true, false) => JogCommand::Positive,
            (false, true) => JogCommand::Negative,
            (true, true) => JogCommand::Invalid,
        }
    }
}

/// Jog state for statusword bits 12 and 13 (DRVI Table 6.31).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum JogState {
    /// Not jogging (bits 13/12 = 0/0).
    #[default]
    Off,
    /// Jogging clockwise (0/1).
    Positive,
    /// Jogging counter-clockwise (1/0).
    Negative,
}

/// Why a command was not accepted. The axis state is unchanged by a refused command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// The command belongs to another mode of operation.
    #[error("the command does not apply to the active mode of operation")]
    WrongMode,
    /// The power stage is off (the drive is not in "operation enabled").
    #[error("the power stage is off")]
    PowerOff,
    /// A quick stop is active.
    #[error("a quick stop is active")]
    Stopping,
    /// The halt bit is set.
    #[error("the axis is halted")]
    Halted,
    /// A set-point is already waiting in the buffer (set-point acknowledge still high).
    #[error("the set-point buffer is full")]
    Busy,
    /// A velocity, acceleration or deceleration the command needs is zero.
    #[error("a profile velocity, acceleration or deceleration the command needs is zero")]
    InvalidProfile,
    /// The interpolation buffer is full.
    #[error("the interpolation buffer is full")]
    BufferFull,
}

/// The sensor inputs as the drive sees them (DRVI 2002h, DRCS 2002h, AKD 60FDh).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inputs {
    /// Home switch.
    pub home_switch: bool,
    /// Negative limit switch.
    pub negative_limit: bool,
    /// Positive limit switch.
    pub positive_limit: bool,
    /// An index pulse passed during the last step.
    pub index_pulse: bool,
    /// The axis is pressed against a hard end stop.
    pub end_stop: bool,
}

/// Everything the caller needs to fill the statusword and the actual-value objects.
///
/// Positions, velocities and torques are in raw device units, rounded and saturated to `i32`
/// (see [`Status::saturated`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Status {
    /// Simulated time, µs.
    pub time_us: u64,
    /// The active mode (6061h).
    pub mode: Mode,
    /// The power stage is on.
    pub power: bool,
    /// The brake is engaged.
    pub brake: bool,
    /// Position demand value 6062h.
    pub position_demand: i32,
    /// Position actual value 6064h.
    pub position_actual: i32,
    /// Velocity demand value 606Bh.
    pub velocity_demand: i32,
    /// Velocity actual value 606Ch.
    pub velocity_actual: i32,
    /// Torque demand 6074h.
    pub torque_demand: i32,
    /// Torque actual value 6077h.
    pub torque_actual: i32,
    /// Following error actual value 60F4h (demand - actual).
    pub following_error: i32,
    /// The following error exceeded 6065h for longer than 6066h (statusword bit 13 in position
    /// modes).
    pub following_error_exceeded: bool,
    /// Statusword bit 10 for the active mode (in homing mode the same as
    /// [`HomingState::statusword_bits`]).
    pub target_reached: bool,
    /// Statusword bit 12 in profile position mode.
    pub set_point_acknowledge: bool,
    /// Statusword bit 11: a software limit clipped the current target or stopped the axis.
    pub internal_limit_active: bool,
    /// The torque was limited during the last step (DRVI statusword bit 14).
    pub torque_limit_active: bool,
    /// The actual speed stayed below 606Fh for 6070h (statusword bit 12 "speed" in profile
    /// velocity mode: 1 = standing).
    pub zero_speed: bool,
    /// The demand stands still and so does the axis.
    pub standing: bool,
    /// A quick stop is active and the axis has stopped.
    pub quick_stop_complete: bool,
    /// Homing progress.
    pub homing: HomingState,
    /// A homing completed since power-up (DRVI/DRCS 2004h).
    pub homed: bool,
    /// Jog state (DRVI statusword bits 12 and 13 in jog mode).
    pub jog: JogState,
    /// Interpolated position mode is enabled (statusword bit 12 in mode 7).
    pub interpolation_active: bool,
    /// Set-points waiting in the interpolation buffer.
    pub interpolation_buffered: usize,
    /// The last SYNC found the interpolation buffer empty.
    pub interpolation_underflow: bool,
    /// Sensor inputs.
    pub inputs: Inputs,
    /// Some value was out of range and saturated since the last
    /// [`Axis::clear_saturated`]; the model stays finite and keeps running.
    pub saturated: bool,
}

/// Where the demand comes from in a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    /// No torque: the axis coasts.
    Off,
    /// Torque mode.
    Torque,
    /// The trajectory plan.
    Plan,
    /// The interpolator.
    Interp,
}

/// One simulated axis: a drive's power stage, trajectory generator and the mechanics it moves.
///
/// Everything is deterministic: time only advances in [`Axis::step`], by the amount given.
/// Commands take effect at once (the next step follows them); [`Axis::status`] reports the state
/// after the last step and the last command.
///
/// ```
/// use drive::motion::{Axis, AxisConfig, Mode, SetPoint};
///
/// let mut axis = Axis::new(AxisConfig {
///     profile_velocity: 1000,
///     profile_acceleration: 2000,
///     profile_deceleration: 2000,
///     ..AxisConfig::default()
/// });
/// axis.set_power(true);
/// axis.set_mode(Mode::ProfilePosition);
/// axis.new_set_point(SetPoint { target: 1500, ..SetPoint::default() }).unwrap();
/// axis.release_set_point();
/// while !axis.status().target_reached {
///     axis.step(1000); // 1 ms
/// }
/// // 0.5 s up to 1000/s, 1 s cruise, 0.5 s down.
/// assert_eq!(axis.status().position_actual, 1500);
/// assert_eq!(axis.status().time_us, 2_000_000);
/// ```
#[derive(Debug, Clone)]
pub struct Axis {
    cfg: AxisConfig,
    env: Environment,
    plant: Plant,
    /// Drive frame: x = sign · m + shift.
    shift: f64,
    time_us: u64,
    last_dt_us: u64,
    mode: Mode,
    power: bool,
    halt: bool,
    stop: Option<StopRamp>,
    source: Source,
    plan: Plan,
    plan_start_us: u64,
    /// Demand position and velocity (drive frame) after the last step.
    demand_p: f64,
    demand_v: f64,
    /// Torque mode: the ramped torque demand (drive frame).
    torque_cmd: f64,
    target_torque: i32,
    target_velocity: i32,
    jog: JogCommand,
    /// Profile position: the current target, whether a move to it is under way, the buffer.
    target: f64,
    pp_moving: bool,
    buffered: Option<(f64, bool)>,
    ack: bool,
    /// Velocity modes: stopping at a software limit.
    limit_stop: bool,
    internal_limit: bool,
    homing: HomingState,
    homed: bool,
    sequence: Option<Sequence>,
    homing_started_us: u64,
    ip: Interpolator,
    index_pulse: bool,
    position_window_us: u64,
    velocity_window_us: u64,
    zero_speed_us: u64,
    following_error_us: u64,
    saturated: bool,
}

fn ms_to_us(ms: u16) -> u64 {
    u64::from(ms) * 1000
}

impl Axis {
    /// An axis at position 0, power off, mode 0, with nothing mounted along it.
    pub fn new(cfg: AxisConfig) -> Axis {
        Axis::with_environment(cfg, Environment::default())
    }

    /// An axis at position 0 with switches, end stops and an index as `env` says.
    pub fn with_environment(cfg: AxisConfig, env: Environment) -> Axis {
        Axis {
            cfg,
            env,
            plant: Plant::new(),
            shift: 0.0,
            time_us: 0,
            last_dt_us: 0,
            mode: Mode::NoMode,
            power: false,
            halt: false,
            stop: None,
            source: Source::Off,
            plan: Plan::hold(0.0),
            plan_start_us: 0,
            demand_p: 0.0,
            demand_v: 0.0,
            torque_cmd: 0.0,
            target_torque: 0,
            target_velocity: 0,
            jog: JogCommand::Stop,
            target: 0.0,
            pp_moving: false,
            buffered: None,
            ack: false,
            limit_stop: false,
            internal_limit: false,
            homing: HomingState::Idle,
            homed: false,
            sequence: None,
            homing_started_us: 0,
            ip: Interpolator::new(),
            index_pulse: false,
            position_window_us: 0,
            velocity_window_us: 0,
            zero_speed_us: 0,
            following_error_us: 0,
            saturated: false,
        }
    }

    /// The parameters.
    pub fn config(&self) -> &AxisConfig {
        &self.cfg
    }

    /// The parameters, to change them (they apply from the next command).
    pub fn config_mut(&mut self) -> &mut AxisConfig {
        &mut self.cfg
    }

    /// What is mounted along the axis.
    pub fn environment(&self) -> &Environment {
        &self.env
    }

    /// What is mounted along the axis, to move switches or stops.
    pub fn environment_mut(&mut self) -> &mut Environment {
        &mut self.env
    }

    // ---------------------------------------------------------------------------------------
    // Frames and units.

    fn sign(&self) -> f64 {
        if self.cfg.reverse_polarity { -1.0 } else { 1.0 }
    }

    fn to_drive(&self, m: f64) -> f64 {
        self.sign() * m + self.shift
    }

    fn to_mech(&self, x: f64) -> f64 {
        self.sign() * (x - self.shift)
    }

    fn actual_p(&self) -> f64 {
        self.to_drive(self.plant.m)
    }

    fn actual_v(&self) -> f64 {
        self.sign() * self.plant.v
    }

    fn vel(&self, raw: u32) -> f64 {
        self.cfg.units.velocity_in(f64::from(raw))
    }

    fn acc(&self, raw: u32) -> f64 {
        self.cfg.units.acceleration_in(f64::from(raw))
    }

    fn vmax(&self) -> f64 {
        self.vel(self.cfg.profile_velocity.min(self.cfg.max_profile_velocity))
    }

    /// Deceleration a torque-limited stop reaches: the torque limit over the inertia.
    fn hard_decel(&self) -> f64 {
        let j = if self.cfg.plant.inertia.is_finite() && self.cfg.plant.inertia > 0.0 {
            self.cfg.plant.inertia
        } else {
            1e-6
        };
        (f64::from(self.cfg.max_torque) / j).clamp(1e-3, 1e18)
    }

    fn stop_decel(&self, ramp: StopRamp) -> f64 {
        let profile = self.acc(self.cfg.profile_deceleration);
        let quick = self.acc(self.cfg.quick_stop_deceleration);
        let pick = |first: f64, second: f64| {
            if first > 0.0 {
                first
            } else if second > 0.0 {
                second
            } else {
                self.hard_decel()
            }
        };
        match ramp {
            StopRamp::ProfileDeceleration | StopRamp::Coast => pick(profile, quick),
            StopRamp::QuickStopDeceleration => pick(quick, profile),
            StopRamp::TorqueLimit => self.hard_decel(),
        }
    }

    fn torque_limit(&self) -> f64 {
        let mut limit = f64::from(self.cfg.max_torque);
        if let Some(seq) = &self.sequence
            && self.homing == HomingState::InProgress
            && matches!(self.cfg.homing.method.kind, HomingKind::EndStop { .. })
            && !seq.attained()
            && self.cfg.homing.torque_limit > 0
        {
            limit = limit.min(f64::from(self.cfg.homing.torque_limit));
        }
        limit
    }

    // ---------------------------------------------------------------------------------------
    // Commands.

    /// Switches the power stage on (operation enabled) or off. Off, the torque is zero and the
    /// axis coasts; a move, a homing or interpolation in progress is dropped. On, the demand
    /// starts from the actual position.
    pub fn set_power(&mut self, on: bool) {
        if on == self.power {
            return;
        }
        self.sync_demand_to_source();
        self.power = on;
        if !on {
            self.stop = None;
            self.pp_moving = false;
            self.buffered = None;
            self.ip.enabled = false;
            self.interrupt_homing();
        } else {
            self.target = self.actual_p();
        }
        self.replan();
    }

    /// Engages or releases the holding brake. Engaged, the axis does not move whatever the
    /// torque.
    pub fn set_brake(&mut self, engaged: bool) {
        self.plant.brake = engaged;
    }

    /// Changes the mode of operation. The new mode starts from the current motion: profile
    /// position and homing stop and wait for a command, profile velocity and jog ramp to their
    /// targets, torque mode ramps from the actual torque.
    pub fn set_mode(&mut self, mode: Mode) {
        if mode == self.mode {
            return;
        }
        self.sync_demand_to_source();
        if self.mode == Mode::Homing {
            self.interrupt_homing();
        }
        if mode == Mode::Homing {
            self.homing = HomingState::Idle;
        }
        self.mode = mode;
        self.pp_moving = false;
        self.buffered = None;
        self.ack = false;
        self.ip.enabled = false;
        self.limit_stop = false;
        self.torque_cmd = self.sign() * self.plant.torque;
        self.replan();
        self.target = self.plan.final_position().unwrap_or(self.demand_p);
    }

    /// Controlword bit 8. Halting stops the axis with [`AxisConfig::halt_ramp`]; releasing it
    /// resumes the mode (a profile position move continues to its target). Homing is
    /// interrupted by a halt and must be started again.
    pub fn set_halt(&mut self, halt: bool) {
        if halt == self.halt {
            return;
        }
        self.sync_demand_to_source();
        self.halt = halt;
        if halt {
            self.interrupt_homing();
        }
        self.limit_stop = false;
        self.replan();
    }

    /// Starts a quick stop (or a fault reaction) with `ramp`; until [`Axis::release_quick_stop`]
    /// the axis stays stopped and refuses motion commands. [`StopRamp::Coast`] removes the
    /// torque.
    pub fn quick_stop(&mut self, ramp: StopRamp) {
        self.sync_demand_to_source();
        self.stop = Some(ramp);
        self.pp_moving = false;
        self.buffered = None;
        self.interrupt_homing();
        self.replan();
    }

    /// Leaves the quick stop (CiA 402 transition 16): the axis holds where it stopped and the
    /// mode resumes (profile velocity and jog ramp to their targets again).
    pub fn release_quick_stop(&mut self) {
        if self.stop.is_none() {
            return;
        }
        self.sync_demand_to_source();
        self.stop = None;
        self.replan();
        self.target = self.plan.final_position().unwrap_or(self.demand_p);
    }

    /// Profile position: a new set-point (the rising edge of controlword bit 4).
    ///
    /// Accepted, it raises set-point acknowledge until [`Axis::release_set_point`] (and while
    /// the buffer holds a set-point). A target outside the software limits is clipped to them
    /// and raises internal limit active.
    pub fn new_set_point(&mut self, sp: SetPoint) -> Result<(), CommandError> {
        if self.mode != Mode::ProfilePosition {
            return Err(CommandError::WrongMode);
        }
        if !self.power {
            return Err(CommandError::PowerOff);
        }
        if self.stop.is_some() {
            return Err(CommandError::Stopping);
        }
        let (vmax, acc, dec) =
            (self.vmax(), self.acc(self.cfg.profile_acceleration), self.acc(self.cfg.profile_deceleration));
        if !(vmax > 0.0 && acc > 0.0 && dec > 0.0) {
            return Err(CommandError::InvalidProfile);
        }
        if self.pp_moving && !sp.change_immediately && self.buffered.is_some() {
            return Err(CommandError::Busy);
        }
        let base = match self.cfg.relative_base {
            RelativeBase::PreviousTarget => self.target,
            RelativeBase::ActualPosition => self.actual_p(),
        };
        let raw = if sp.relative { base + f64::from(sp.target) } else { f64::from(sp.target) };
        let raw = clamp_finite(raw, POSITION_LIMIT, &mut self.saturated);
        let (target, clipped) = self.cfg.software_limits.clamp(raw);
        self.internal_limit = clipped;
        self.ack = true;
        self.position_window_us = 0;
        if !self.pp_moving || sp.change_immediately {
            self.target = target;
            self.buffered = None;
            self.pp_moving = true;
            self.sync_demand_to_source();
            self.replan();
        } else {
            self.buffered = Some((target, sp.change_on_set_point));
            if sp.change_on_set_point {
                self.replan();
            }
        }
        Ok(())
    }

    /// Profile position: controlword bit 4 went back to 0. Set-point acknowledge drops unless
    /// a set-point still waits in the buffer.
    pub fn release_set_point(&mut self) {
        self.ack = false;
    }

    /// Target velocity 60FFh (profile velocity mode; the jog speed in jog mode). Applied at once
    /// in profile velocity mode, clipped to 607Fh.
    pub fn set_target_velocity(&mut self, velocity: i32) -> Result<(), CommandError> {
        let old = self.target_velocity;
        self.target_velocity = velocity;
        if matches!(self.mode, Mode::ProfileVelocity | Mode::Jog) && self.power && self.stop.is_none() && !self.halt {
            if self.velocity_plan().is_none() {
                self.target_velocity = old;
                return Err(CommandError::InvalidProfile);
            }
            self.sync_demand_to_source();
            self.limit_stop = false;
            self.internal_limit = false;
            self.replan();
        }
        Ok(())
    }

    /// Jog (DRVI mode -1): the command from controlword bits 5 and 6. The speed is |60FFh|.
    pub fn set_jog(&mut self, jog: JogCommand) {
        if jog == JogCommand::Invalid || jog == self.jog {
            return;
        }
        self.jog = jog;
        if self.mode == Mode::Jog && self.power && self.stop.is_none() && !self.halt {
            self.sync_demand_to_source();
            self.limit_stop = false;
            self.replan();
        }
    }

    /// Target torque 6071h (profile torque mode), ramped with 6087h and limited to the torque
    /// limit.
    pub fn set_target_torque(&mut self, torque: i32) {
        self.target_torque = torque;
    }

    /// Homing: start (the rising edge of controlword bit 4 in homing mode).
    pub fn start_homing(&mut self) -> Result<(), CommandError> {
        if self.mode != Mode::Homing {
            return Err(CommandError::WrongMode);
        }
        if !self.power {
            return Err(CommandError::PowerOff);
        }
        if self.stop.is_some() {
            return Err(CommandError::Stopping);
        }
        if self.halt {
            return Err(CommandError::Halted);
        }
        let h = self.cfg.homing;
        let cap = |raw: u32| raw.min(self.cfg.max_profile_velocity);
        let (fast, slow) = (self.vel(cap(h.search_speed)), self.vel(cap(h.zero_speed)));
        let (acc, dec) = (self.acc(h.acceleration), self.acc(h.deceleration));
        let moves = h.method.kind != HomingKind::CurrentPosition;
        if moves && !(fast > 0.0 && slow > 0.0 && acc > 0.0 && dec > 0.0) {
            self.homing = HomingState::Error(HomingError::InvalidParameters);
            return Err(CommandError::InvalidProfile);
        }
        self.sync_demand_to_source();
        let threshold = match (h.torque_threshold, h.torque_limit) {
            (0, 0) => f64::from(self.cfg.max_torque),
            (0, limit) => f64::from(limit.min(self.cfg.max_torque)),
            (t, _) => f64::from(t),
        };
        self.homed = false;
        self.homing = HomingState::InProgress;
        self.homing_started_us = self.time_us;
        let stall = u64::from(h.stall_time_us.max(1));
        let (seq, cmd) = Sequence::start(h.method, &self.env, self.plant.m, fast, slow, threshold, stall);
        self.sequence = Some(seq);
        self.apply_homing(cmd);
        Ok(())
    }

    /// Homing: abort (controlword bit 4 back to 0 on the AKD). The axis stops.
    pub fn abort_homing(&mut self) {
        if self.interrupt_homing() {
            self.replan();
        }
    }

    /// Interpolated position: enable or disable interpolation (controlword bit 4 in mode 7).
    pub fn set_interpolation_enabled(&mut self, enabled: bool) {
        if enabled == self.ip.enabled {
            return;
        }
        self.sync_demand_to_source();
        self.ip.enabled = enabled;
        self.replan();
    }

    /// Interpolated position: queue a set-point (60C1h sub 1); it is used at a later SYNC.
    pub fn push_interpolation_point(&mut self, position: i32) -> Result<(), CommandError> {
        if self.ip.push(position, self.cfg.interpolation.buffer_capacity) {
            Ok(())
        } else {
            Err(CommandError::BufferFull)
        }
    }

    /// Interpolated position: drop every queued set-point (60C4h sub 6).
    pub fn clear_interpolation_buffer(&mut self) {
        self.ip.clear();
    }

    /// A SYNC: in interpolated position mode with interpolation enabled, the next set-point
    /// becomes the end of a linear segment one interpolation period long.
    pub fn sync(&mut self) {
        if self.source != Source::Interp {
            return;
        }
        let limits = self.cfg.software_limits;
        let clipped = self.ip.sync(self.demand_p, self.cfg.interpolation.period_us, |x| limits.clamp(x));
        self.internal_limit = clipped;
    }

    /// Sets the actual position to `position` without moving (re-referencing, or restoring a
    /// saved position at power-up as the DRVI does, 5.0.3), and marks the axis homed or not.
    pub fn set_actual_position(&mut self, position: i32, homed: bool) {
        self.sync_demand_to_source();
        let delta = f64::from(position) - self.actual_p();
        self.shift += delta;
        self.demand_p += delta;
        self.target += delta;
        if let Some(b) = &mut self.buffered {
            b.0 += delta;
        }
        self.homed = homed;
        self.interrupt_homing();
        self.replan();
    }

    /// Clears [`Status::saturated`].
    pub fn clear_saturated(&mut self) {
        self.saturated = false;
    }

    // ---------------------------------------------------------------------------------------
    // Planning.

    fn compute_source(&self) -> Source {
        if !self.power || self.stop == Some(StopRamp::Coast) {
            return Source::Off;
        }
        if self.stop.is_some() || self.halt {
            return Source::Plan;
        }
        match self.mode {
            Mode::ProfileTorque => Source::Torque,
            Mode::InterpolatedPosition if self.ip.enabled => Source::Interp,
            _ => Source::Plan,
        }
    }

    /// Makes the demand continuous with what the axis does now: after coasting or torque mode
    /// the demand is the actual state.
    fn sync_demand_to_source(&mut self) {
        if matches!(self.source, Source::Off | Source::Torque) {
            self.demand_p = self.actual_p();
            self.demand_v = self.actual_v();
            self.plant.tracking = true;
        }
    }

    fn set_plan(&mut self, plan: Plan) {
        self.plan = plan;
        self.plan_start_us = self.time_us;
    }

    fn stop_plan(&self, ramp: StopRamp) -> Plan {
        let dec = self.stop_decel(ramp);
        Plan::velocity(self.demand_p, self.demand_v, 0.0, dec, dec).unwrap_or_else(|| Plan::hold(self.demand_p))
    }

    /// The plan for the current state of commands, from the current demand. Returns false when
    /// the mode's command could not be planned (zero profile parameters); the axis then stops.
    fn replan(&mut self) -> bool {
        let mut ok = true;
        let previous = self.source;
        self.source = self.compute_source();
        match self.source {
            Source::Off => {
                let p = self.demand_p;
                self.set_plan(Plan::hold(p));
            }
            Source::Torque => {
                if previous != Source::Torque {
                    // The torque ramp starts from the torque the motor produces now.
                    self.torque_cmd = self.sign() * self.plant.torque;
                }
            }
            Source::Interp => {
                let p = self.demand_p;
                self.ip.hold(p);
                self.demand_v = 0.0;
            }
            Source::Plan => {
                let plan = if let Some(ramp) = self.stop {
                    self.stop_plan(ramp)
                } else if self.halt {
                    self.stop_plan(self.cfg.halt_ramp)
                } else {
                    match self.mode {
                        Mode::ProfilePosition if self.pp_moving => match self.pp_plan() {
                            Some(plan) => plan,
                            None => {
                                ok = false;
                                self.pp_moving = false;
                                self.stop_plan(StopRamp::ProfileDeceleration)
                            }
                        },
                        Mode::ProfileVelocity | Mode::Jog => match self.velocity_plan() {
                            Some(plan) => plan,
                            None => {
                                ok = false;
                                self.stop_plan(StopRamp::ProfileDeceleration)
                            }
                        },
                        Mode::Homing if self.sequence.is_some() => return true,
                        Mode::Homing => {
                            let dec = self.acc(self.cfg.homing.deceleration);
                            if dec > 0.0 {
                                Plan::velocity(self.demand_p, self.demand_v, 0.0, dec, dec)
                                    .unwrap_or_else(|| self.stop_plan(StopRamp::ProfileDeceleration))
                            } else {
                                self.stop_plan(StopRamp::ProfileDeceleration)
                            }
                        }
                        _ => self.stop_plan(StopRamp::ProfileDeceleration),
                    }
                };
                self.set_plan(plan);
            }
        }
        ok
    }

    /// The ramp to the profile velocity / jog target from the current demand.
    fn velocity_plan(&mut self) -> Option<Plan> {
        let vt = self.velocity_target();
        let (acc, dec) = (self.acc(self.cfg.profile_acceleration), self.acc(self.cfg.profile_deceleration));
        let (p, v) = if matches!(self.source, Source::Off | Source::Torque) {
            (self.actual_p(), self.actual_v())
        } else {
            (self.demand_p, self.demand_v)
        };
        Plan::velocity(p, v, vt, acc, dec)
    }

    /// The profile velocity / jog target in position units/s, clipped to 607Fh.
    fn velocity_target(&mut self) -> f64 {
        let raw = match self.mode {
            Mode::Jog => match self.jog {
                JogCommand::Positive => i64::from(self.target_velocity).abs(),
                JogCommand::Negative => -i64::from(self.target_velocity).abs(),
                _ => 0,
            },
            _ => i64::from(self.target_velocity),
        };
        let cap = i64::from(self.cfg.max_profile_velocity);
        let clipped = raw.clamp(-cap, cap);
        let v = self.cfg.units.velocity_in(clipped as f64);
        clamp_finite(v, VELOCITY_LIMIT, &mut self.saturated)
    }

    /// The plan to the profile position target (blending into a buffered set-point).
    fn pp_plan(&self) -> Option<Plan> {
        let vmax = self.vmax();
        let (acc, dec) = (self.acc(self.cfg.profile_acceleration), self.acc(self.cfg.profile_deceleration));
        let mut vf = 0.0;
        if let Some((next, true)) = self.buffered {
            let here = self.target - self.demand_p;
            let beyond = next - self.target;
            if here != 0.0 && beyond != 0.0 && here.signum() == beyond.signum() {
                vf = vmax;
            }
        }
        Plan::position(self.demand_p, self.demand_v, self.target, vmax, acc, dec, vf)
    }

    /// Ends a homing in progress early (halt, mode change, power off, quick stop, abort).
    ///
    /// Searching, the homing is interrupted. Once the home point is known the drive has
    /// reported "homing attained" (statusword bit 12), and a master may act on it at once
    /// (switch the mode, as python-canopen's `homing()` does): the reference is then committed
    /// as the completed homing would set it, and the homing counts as completed.
    fn interrupt_homing(&mut self) -> bool {
        let Some(seq) = self.sequence.take() else { return false };
        match (self.homing, seq.home) {
            (HomingState::Attained, Some(home)) => {
                self.commit_home(home);
                self.homing = HomingState::Completed;
                true
            }
            (HomingState::InProgress | HomingState::Attained, _) => {
                self.homing = HomingState::Interrupted;
                true
            }
            _ => false,
        }
    }

    /// Sets the drive frame as a homing onto mechanical home point `home` sets it (the
    /// offset move of [`HomeOffsetMode::MoveByOffset`] counted as done), keeping the demand,
    /// the target and the buffer where they are mechanically; marks the axis homed.
    fn commit_home(&mut self, home: f64) {
        let h = self.cfg.homing;
        let (s, offset) = (self.sign(), f64::from(h.offset));
        let shift = match h.offset_mode {
            HomeOffsetMode::AssignOffset => offset - s * home,
            HomeOffsetMode::AssignNegatedOffset => -offset - s * home,
            // The move by the offset ends at home + s × offset, and that point becomes zero.
            HomeOffsetMode::MoveByOffset => -s * (home + s * offset),
        };
        let delta = shift - self.shift;
        self.shift = shift;
        self.demand_p += delta;
        self.target += delta;
        if let Some(b) = &mut self.buffered {
            b.0 += delta;
        }
        self.homed = true;
    }

    fn apply_homing(&mut self, cmd: Cmd) {
        let h = self.cfg.homing;
        let (acc, dec) = (self.acc(h.acceleration), self.acc(h.deceleration));
        let s = self.sign();
        match cmd {
            Cmd::None => {}
            Cmd::Velocity(vm) => {
                let plan = Plan::velocity(self.demand_p, self.demand_v, s * vm, acc, dec);
                if let Some(plan) = plan {
                    self.set_plan(plan);
                }
            }
            Cmd::Stop => {
                let plan = Plan::velocity(self.demand_p, self.demand_v, 0.0, acc, dec);
                self.set_plan(plan.unwrap_or_else(|| self.stop_plan(StopRamp::QuickStopDeceleration)));
            }
            Cmd::MoveTo { m, speed, resync } => {
                if resync {
                    self.demand_p = self.actual_p();
                    self.demand_v = self.actual_v();
                }
                let x = self.to_drive(m);
                match Plan::position(self.demand_p, self.demand_v, x, speed, acc, dec, 0.0) {
                    Some(plan) => self.set_plan(plan),
                    None => self.fail_homing(HomingError::InvalidParameters),
                }
            }
            Cmd::OffsetMove => {
                if h.offset_mode == HomeOffsetMode::MoveByOffset && h.offset != 0 {
                    let x = self.demand_p + f64::from(h.offset);
                    let speed = self.vel(h.search_speed.min(self.cfg.max_profile_velocity));
                    match Plan::position(self.demand_p, self.demand_v, x, speed, acc, dec, 0.0) {
                        Some(plan) => self.set_plan(plan),
                        None => self.fail_homing(HomingError::InvalidParameters),
                    }
                }
            }
            Cmd::Complete { home, at } => {
                let offset = f64::from(h.offset);
                self.shift = match h.offset_mode {
                    HomeOffsetMode::AssignOffset => offset - s * home,
                    HomeOffsetMode::AssignNegatedOffset => -offset - s * home,
                    HomeOffsetMode::MoveByOffset => -s * at,
                };
                self.demand_p = self.actual_p();
                self.demand_v = 0.0;
                self.target = self.demand_p;
                self.set_plan(Plan::hold(self.demand_p));
                self.sequence = None;
                self.homing = HomingState::Completed;
                self.homed = true;
            }
            Cmd::Fail(e) => self.fail_homing(e),
        }
    }

    fn fail_homing(&mut self, e: HomingError) {
        self.sequence = None;
        self.homing = HomingState::Error(e);
        // Stop from where the axis really is: the demand may have run ahead of a blocked axis.
        self.demand_p = self.actual_p();
        self.demand_v = self.actual_v();
        let dec = self.acc(self.cfg.homing.deceleration);
        let plan = if dec > 0.0 { Plan::velocity(self.demand_p, self.demand_v, 0.0, dec, dec) } else { None };
        let plan = plan.unwrap_or_else(|| self.stop_plan(StopRamp::QuickStopDeceleration));
        self.set_plan(plan);
    }

    // ---------------------------------------------------------------------------------------
    // Simulation.

    /// Advances the simulation by `dt_us` microseconds (0 does nothing).
    pub fn step(&mut self, dt_us: u32) {
        if dt_us == 0 {
            return;
        }
        let dt_us = u64::from(dt_us);
        let dt = dt_us as f64 * 1e-6;
        self.time_us = self.time_us.saturating_add(dt_us);
        self.last_dt_us = dt_us;
        let s = self.sign();
        let from = self.plant.m;
        let mut sat = false;
        let drive = match self.source {
            Source::Off => Drive::Off,
            Source::Torque => {
                let limit = f64::from(self.cfg.max_torque);
                let target = f64::from(self.target_torque).clamp(-limit, limit);
                let slope = f64::from(self.cfg.torque_slope);
                let step = slope * dt;
                self.torque_cmd = if slope > 0.0 && (target - self.torque_cmd).abs() > step {
                    self.torque_cmd + (target - self.torque_cmd).signum() * step
                } else {
                    target
                };
                self.torque_cmd = clamp_finite(self.torque_cmd, TORQUE_LIMIT, &mut sat);
                Drive::Torque(s * self.torque_cmd)
            }
            Source::Plan | Source::Interp => {
                let (p, v) = if self.source == Source::Plan {
                    let t = (self.time_us - self.plan_start_us) as f64 * 1e-6;
                    self.plan.eval(t)
                } else {
                    self.ip.advance(dt_us)
                };
                let p = clamp_finite(p, POSITION_LIMIT, &mut sat);
                let v = clamp_finite(v, VELOCITY_LIMIT, &mut sat);
                let a = clamp_finite((v - self.demand_v) / dt, 1e300, &mut sat);
                let (p0, v0) = (self.to_mech(self.demand_p), s * self.demand_v);
                self.demand_p = p;
                self.demand_v = v;
                Drive::Track { p0, v0, p: self.to_mech(p), v: s * v, a: s * a }
            }
        };
        let limit = self.torque_limit();
        self.plant.step(&self.cfg.plant, &self.env, drive, limit, dt, &mut sat);
        if matches!(self.source, Source::Off | Source::Torque) {
            self.demand_p = self.actual_p();
            self.demand_v = self.actual_v();
            self.plan = Plan::hold(self.demand_p);
            self.plan_start_us = self.time_us;
        }
        self.index_pulse = self.env.index_crossed(from, self.plant.m);
        self.after_step(from, dt_us);
        self.update_timers(dt_us);
        self.saturated |= sat;
    }

    fn plan_t(&self) -> f64 {
        (self.time_us - self.plan_start_us) as f64 * 1e-6
    }

    fn standing(&self) -> bool {
        match self.source {
            Source::Plan => self.plan.settled(self.plan_t()) && self.plant.tracking && self.plant.v == 0.0,
            Source::Interp => self.ip.segment_end().1 && self.plant.tracking && self.plant.v == 0.0,
            Source::Off | Source::Torque => self.plant.v == 0.0,
        }
    }

    fn after_step(&mut self, from: f64, dt_us: u64) {
        // Profile position: the move is over; start the buffered one.
        if self.source == Source::Plan
            && self.mode == Mode::ProfilePosition
            && self.pp_moving
            && self.stop.is_none()
            && !self.halt
            && self.plan_t() >= self.plan.duration()
        {
            if let Some((next, _)) = self.buffered.take() {
                self.target = next;
                self.position_window_us = 0;
                if !self.replan() {
                    self.pp_moving = false;
                }
            } else if self.plan.end_velocity() == 0.0 {
                self.pp_moving = false;
            }
        }
        // Velocity modes: stop on a software limit.
        if self.source == Source::Plan
            && matches!(self.mode, Mode::ProfileVelocity | Mode::Jog)
            && self.stop.is_none()
            && !self.halt
            && !self.limit_stop
            && self.cfg.software_limits.enabled
            && self.demand_v != 0.0
        {
            let l = self.cfg.software_limits;
            let (lo, hi) = if l.min <= l.max { (l.min, l.max) } else { (l.max, l.min) };
            let v = self.demand_v;
            let limit = if v > 0.0 { f64::from(hi) } else { f64::from(lo) };
            let dec = self.acc(self.cfg.profile_deceleration).max(1e-9);
            let dist = (limit - self.demand_p) * v.signum();
            let lookahead = v.abs() * dt_us as f64 * 1e-6;
            if dist <= v * v / (2.0 * dec) + lookahead {
                let acc = self.acc(self.cfg.profile_acceleration).max(1e-9);
                if let Some(plan) = Plan::position(self.demand_p, v, limit, v.abs(), acc, dec, 0.0) {
                    self.set_plan(plan);
                }
                self.limit_stop = true;
                self.internal_limit = true;
            }
        }
        // Homing.
        if let Some(mut seq) = self.sequence.take() {
            let timeout = self.cfg.homing.timeout_us;
            let cmd = if timeout > 0 && self.time_us.saturating_sub(self.homing_started_us) > timeout {
                Cmd::Fail(HomingError::Timeout)
            } else {
                let obs = Observation {
                    env: &self.env,
                    from,
                    to: self.plant.m,
                    v: self.plant.v,
                    torque: self.plant.torque,
                    stopped: self.source == Source::Plan
                        && self.plan.settled(self.plan_t())
                        && self.plant.tracking
                        && self.plant.v == 0.0,
                    at_end_stop: self.plant.at_end_stop,
                    dt_us,
                };
                seq.update(&obs)
            };
            if seq.attained() && self.homing == HomingState::InProgress {
                self.homing = HomingState::Attained;
            }
            self.sequence = Some(seq);
            self.apply_homing(cmd);
        }
    }

    fn update_timers(&mut self, dt_us: u64) {
        let bump = |timer: &mut u64, on: bool| {
            *timer = if on { timer.saturating_add(dt_us) } else { 0 };
        };
        let c = &self.cfg;
        let actual_v_raw = self.cfg.units.velocity_out(self.actual_v());
        // Position window.
        let in_window =
            c.position_window == u32::MAX || (self.target - self.actual_p()).abs() <= f64::from(c.position_window);
        let mut t = self.position_window_us;
        bump(&mut t, in_window);
        self.position_window_us = t;
        // Velocity window (profile velocity target reached).
        let vt_raw = match self.mode {
            Mode::Jog => match self.jog {
                JogCommand::Positive => f64::from(self.target_velocity).abs(),
                JogCommand::Negative => -f64::from(self.target_velocity).abs(),
                _ => 0.0,
            },
            _ => f64::from(self.target_velocity),
        };
        let cap = f64::from(c.max_profile_velocity);
        let vt_raw = vt_raw.clamp(-cap, cap);
        let mut t = self.velocity_window_us;
        bump(&mut t, (vt_raw - actual_v_raw).abs() <= f64::from(c.velocity_window));
        self.velocity_window_us = t;
        // Zero speed.
        let mut t = self.zero_speed_us;
        bump(&mut t, actual_v_raw.abs() <= f64::from(c.velocity_threshold));
        self.zero_speed_us = t;
        // Following error.
        let window = c.following_error_window;
        let fe = (self.demand_p - self.actual_p()).abs();
        let mut t = self.following_error_us;
        bump(&mut t, window != 0 && window != u32::MAX && self.source != Source::Off && fe > f64::from(window));
        self.following_error_us = t;
    }

    // ---------------------------------------------------------------------------------------
    // Status.

    /// The state after the last step and command.
    pub fn status(&self) -> Status {
        let c = &self.cfg;
        let mut sat = self.saturated;
        let s = self.sign();
        let actual_p = self.actual_p();
        let standing = self.standing();
        let zero_speed = self.zero_speed_us >= ms_to_us(c.velocity_threshold_time_ms);
        let position_ok = self.position_window_us > 0 && self.position_window_us >= ms_to_us(c.position_window_time_ms);
        let velocity_ok = self.velocity_window_us > 0 && self.velocity_window_us >= ms_to_us(c.velocity_window_time_ms);
        let stopped_by_command = self.halt || self.stop.is_some();
        let target_reached = match self.mode {
            _ if stopped_by_command => standing,
            Mode::ProfilePosition => {
                !self.pp_moving && self.buffered.is_none() && self.plan.settled(self.plan_t()) && position_ok
            }
            Mode::ProfileVelocity | Mode::Jog => velocity_ok,
            Mode::ProfileTorque => {
                self.torque_cmd
                    == f64::from(self.target_torque).clamp(-f64::from(c.max_torque), f64::from(c.max_torque))
            }
            Mode::Homing => self.homing.statusword_bits(standing).0,
            Mode::InterpolatedPosition => {
                let (end, over) = self.ip.segment_end();
                self.ip.len() == 0
                    && over
                    && (c.position_window == u32::MAX || (end - actual_p).abs() <= f64::from(c.position_window))
            }
            Mode::NoMode => standing,
        };
        let torque_demand = match self.source {
            Source::Torque => self.torque_cmd,
            _ => s * self.plant.torque_demand,
        };
        let jog = match (self.mode, self.jog) {
            (Mode::Jog, JogCommand::Positive) if self.power && !stopped_by_command => JogState::Positive,
            (Mode::Jog, JogCommand::Negative) if self.power && !stopped_by_command => JogState::Negative,
            _ => JogState::Off,
        };
        let m = self.plant.m;
        Status {
            time_us: self.time_us,
            mode: self.mode,
            power: self.power,
            brake: self.plant.brake,
            position_demand: to_i32(self.demand_p, &mut sat),
            position_actual: to_i32(actual_p, &mut sat),
            velocity_demand: to_i32(c.units.velocity_out(self.demand_v), &mut sat),
            velocity_actual: to_i32(c.units.velocity_out(self.actual_v()), &mut sat),
            torque_demand: to_i32(torque_demand, &mut sat),
            torque_actual: to_i32(s * self.plant.torque, &mut sat),
            following_error: to_i32(self.demand_p - actual_p, &mut sat),
            following_error_exceeded: self.following_error_us > ms_to_us(c.following_error_timeout_ms),
            target_reached,
            set_point_acknowledge: self.mode == Mode::ProfilePosition && (self.ack || self.buffered.is_some()),
            internal_limit_active: self.internal_limit,
            torque_limit_active: self.plant.torque_limited,
            zero_speed,
            standing,
            quick_stop_complete: self.stop.is_some() && standing,
            homing: self.homing,
            homed: self.homed,
            jog,
            interpolation_active: self.source == Source::Interp,
            interpolation_buffered: self.ip.len(),
            interpolation_underflow: self.ip.underflow,
            inputs: Inputs {
                home_switch: self.env.active(Sensor::Home, m),
                negative_limit: self.env.active(Sensor::NegativeLimit, m),
                positive_limit: self.env.active(Sensor::PositiveLimit, m),
                index_pulse: self.index_pulse,
                end_stop: self.plant.at_end_stop,
            },
            saturated: sat,
        }
    }
}
