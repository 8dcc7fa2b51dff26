//! Axis parameters: what the object dictionary configures, in raw device units.

use super::homing::HomingConfig;
use super::plant::PlantConfig;
use super::units::Units;

/// Modes of operation (6060h / 6061h).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// 0: no mode; the axis holds its position.
    #[default]
    NoMode,
    /// 1: profile position.
    ProfilePosition,
    /// 3: profile velocity.
    ProfileVelocity,
    /// 4: profile torque.
    ProfileTorque,
    /// 6: homing.
    Homing,
    /// 7: interpolated position.
    InterpolatedPosition,
    /// -1 on the Camozzi DRVI: jog (controlword bits 5 and 6 move at 60FFh).
    Jog,
}

impl Mode {
    /// The 6060h value. Jog is -1, the DRVI's manufacturer-specific code.
    pub fn code(self) -> i8 {
        match self {
            Mode::NoMode => 0,
            Mode::ProfilePosition => 1,
            Mode::ProfileVelocity => 3,
            Mode::ProfileTorque => 4,
            Mode::Homing => 6,
            Mode::InterpolatedPosition => 7,
            Mode::Jog => -1,
        }
    }

    /// The mode for a 6060h value; `None` for values the model does not implement. Whether a
    /// device supports a mode is the device's business (its 6502h), not the model's.
    pub fn from_code(code: i8) -> Option<Mode> {
        Some(match code {
            0 => Mode::NoMode,
            1 => Mode::ProfilePosition,
            3 => Mode::ProfileVelocity,
            4 => Mode::ProfileTorque,
            6 => Mode::Homing,
            7 => Mode::InterpolatedPosition,
            -1 => Mode::Jog,
            _ => return None,
        })
    }
}

/// How the axis stops (the ramps of the CiA 402 option codes 605Ah to 605Eh).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StopRamp {
    /// Switch the torque off and let the axis coast to standstill ("disable drive function").
    Coast,
    /// Decelerate with the profile deceleration 6084h ("slow down ramp").
    #[default]
    ProfileDeceleration,
    /// Decelerate with the quick stop deceleration 6085h.
    QuickStopDeceleration,
    /// Decelerate as hard as the torque limit allows ("current limit"; also used for "voltage
    /// limit", which a model without electrical dynamics cannot tell apart).
    TorqueLimit,
}

impl StopRamp {
    /// The ramp of a halt (605Dh), shutdown (605Bh), disable operation (605Ch) or fault reaction
    /// (605Eh) option code: 0 coast, 1 slow down ramp, 2 quick stop ramp, 3 current limit,
    /// 4 voltage limit. `None` for other (manufacturer or reserved) codes.
    pub fn from_option_code(code: i16) -> Option<StopRamp> {
        Some(match code {
            0 => StopRamp::Coast,
            1 => StopRamp::ProfileDeceleration,
            2 => StopRamp::QuickStopDeceleration,
            3 | 4 => StopRamp::TorqueLimit,
            _ => return None,
        })
    }
}

/// A decoded quick stop option code (605Ah).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QuickStopOption {
    /// How the axis stops.
    pub ramp: StopRamp,
    /// After the stop the state machine stays in "quick stop active" (codes 5 to 8) instead of
    /// going to "switch on disabled" (codes 0 to 4).
    pub stay_in_quick_stop: bool,
}

impl QuickStopOption {
    /// Decodes 605Ah: 0 disable drive function; 1/5 slow down ramp; 2/6 quick stop ramp;
    /// 3/7 current limit; 4/8 voltage limit; 5 to 8 stay in quick stop active. `None` for other
    /// codes.
    pub fn from_code(code: i16) -> Option<QuickStopOption> {
        let (ramp_code, stay) = match code {
            0..=4 => (code, false),
            5..=8 => (code - 4, true),
            _ => return None,
        };
        Some(QuickStopOption { ramp: StopRamp::from_option_code(ramp_code)?, stay_in_quick_stop: stay })
    }
}

/// What a relative target (controlword bit 6) is relative to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RelativeBase {
    /// The previous target position (CiA 402).
    #[default]
    PreviousTarget,
    /// The actual position (DRVI 4.1.2.1).
    ActualPosition,
}

/// Software position limits 607Dh, in the drive's position frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SoftwareLimits {
    /// Apply the limits. The caller decides when (DRVI: 2010h = 1 and homed; AKD: limits not
    /// both zero).
    pub enabled: bool,
    /// Minimum position (607Dh sub 1).
    pub min: i32,
    /// Maximum position (607Dh sub 2).
    pub max: i32,
}

impl SoftwareLimits {
    /// Clamps `x` into the limits; the flag says whether it had to.
    pub(crate) fn clamp(&self, x: f64) -> (f64, bool) {
        if !self.enabled {
            return (x, false);
        }
        let (lo, hi) = if self.min <= self.max { (self.min, self.max) } else { (self.max, self.min) };
        let c = x.clamp(lo as f64, hi as f64);
        (c, c != x)
    }
}

/// Interpolated position mode parameters (AKD 60C2h, 60C4h).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InterpolationConfig {
    /// The interpolation period (60C2h: sub 1 × 10^sub 2 s) in µs, normally the SYNC period.
    pub period_us: u32,
    /// Set-points the input buffer holds (60C4h sub 1).
    pub buffer_capacity: usize,
}

impl Default for InterpolationConfig {
    fn default() -> Self {
        InterpolationConfig { period_us: 1_000, buffer_capacity: 10 }
    }
}

/// Everything that shapes the motion, in raw device units unless a field says otherwise.
///
/// Change fields at any time through [`crate::motion::Axis::config_mut`]; profile parameters take
/// effect with the next command (a new set-point, a new target velocity), as on a real drive.
/// A zero velocity, acceleration or deceleration makes a command that needs it fail with
/// [`crate::motion::CommandError::InvalidProfile`] instead of moving.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisConfig {
    /// How raw velocity and acceleration relate to position units.
    pub units: Units,
    /// Profile velocity 6081h.
    pub profile_velocity: u32,
    /// Profile acceleration 6083h.
    pub profile_acceleration: u32,
    /// Profile deceleration 6084h.
    pub profile_deceleration: u32,
    /// Max profile velocity 607Fh: caps 6081h, 60FFh and the homing speeds.
    pub max_profile_velocity: u32,
    /// Quick stop deceleration 6085h (0: the profile deceleration is used).
    pub quick_stop_deceleration: u32,
    /// Torque slope 6087h, raw torque units per second (0: steps without a ramp).
    pub torque_slope: u32,
    /// Torque limit (6072h, or the DRVI's 6071h with 2015h = 1), raw torque units.
    pub max_torque: u32,
    /// Position window 6067h (`u32::MAX`: target reached as soon as the demand is).
    pub position_window: u32,
    /// Position window time 6068h, ms.
    pub position_window_time_ms: u16,
    /// Velocity window 606Dh, raw velocity units.
    pub velocity_window: u32,
    /// Velocity window time 606Eh, ms.
    pub velocity_window_time_ms: u16,
    /// Velocity threshold 606Fh (below it the axis counts as standing), raw velocity units.
    pub velocity_threshold: u32,
    /// Velocity threshold time 6070h, ms.
    pub velocity_threshold_time_ms: u16,
    /// Following error window 6065h (0 or `u32::MAX`: no following error check).
    pub following_error_window: u32,
    /// Following error time out 6066h, ms.
    pub following_error_timeout_ms: u16,
    /// Software position limits 607Dh.
    pub software_limits: SoftwareLimits,
    /// Base of relative targets.
    pub relative_base: RelativeBase,
    /// Polarity 607Eh bit 7: the drive's positive direction is the motor's negative one.
    pub reverse_polarity: bool,
    /// How a halt (controlword bit 8) stops the axis (605Dh).
    pub halt_ramp: StopRamp,
    /// Homing parameters.
    pub homing: HomingConfig,
    /// Interpolated position parameters.
    pub interpolation: InterpolationConfig,
    /// Mechanics.
    pub plant: PlantConfig,
}

impl Default for AxisConfig {
    /// Zero profile parameters (as the DRVI ships), no limits, no windows.
    fn default() -> Self {
        AxisConfig {
            units: Units::default(),
            profile_velocity: 0,
            profile_acceleration: 0,
            profile_deceleration: 0,
            max_profile_velocity: u32::MAX,
            quick_stop_deceleration: 0,
            torque_slope: 0,
            max_torque: u32::MAX,
            position_window: u32::MAX,
            position_window_time_ms: 0,
            velocity_window: 0,
            velocity_window_time_ms: 0,
            velocity_threshold: 0,
            velocity_threshold_time_ms: 0,
            following_error_window: u32::MAX,
            following_error_timeout_ms: 0,
            software_limits: SoftwareLimits::default(),
            relative_base: RelativeBase::default(),
            reverse_polarity: false,
            halt_ramp: StopRamp::ProfileDeceleration,
            homing: HomingConfig::default(),
            interpolation: InterpolationConfig::default(),
            plant: PlantConfig::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_stop_codes() {
        assert_eq!(
            QuickStopOption::from_code(2),
            Some(QuickStopOption { ramp: StopRamp::QuickStopDeceleration, stay_in_quick_stop: false })
        );
        assert_eq!(
            QuickStopOption::from_code(6),
            Some(QuickStopOption { ramp: StopRamp::QuickStopDeceleration, stay_in_quick_stop: true })
        );
        assert_eq!(QuickStopOption::from_code(0).unwrap().ramp, StopRamp::Coast);
        assert_eq!(QuickStopOption::from_code(8).unwrap().ramp, StopRamp::TorqueLimit);
        assert_eq!(QuickStopOption::from_code(9), None);
        assert_eq!(QuickStopOption::from_code(-1), None);
    }

    #[test]
    fn mode_codes_round_trip() {
        for code in [-1, 0, 1, 3, 4, 6, 7] {
            assert_eq!(Mode::from_code(code).unwrap().code(), code);
        }
        assert_eq!(Mode::from_code(8), None);
    }

    #[test]
    fn software_limits_clamp() {
        let l = SoftwareLimits { enabled: true, min: -10, max: 10 };
        assert_eq!(l.clamp(20.0), (10.0, true));
        assert_eq!(l.clamp(0.0), (0.0, false));
        let swapped = SoftwareLimits { enabled: true, min: 10, max: -10 };
        assert_eq!(swapped.clamp(-20.0), (-10.0, true));
        assert_eq!(SoftwareLimits::default().clamp(1e9), (1e9, false));
    }
}
