//! The physics and motion layer of the simulated CiA 402 drives.
//!
//! An [`Axis`] is a drive's power stage, trajectory generator and servo loop together with the
//! mechanics they move. It knows nothing of CANopen: the caller (the drive's CiA 402 state
//! machine and object dictionary) turns controlword edges into commands, copies parameters into
//! [`AxisConfig`], calls [`Axis::step`] with the elapsed time, and fills the statusword and the
//! actual-value objects from [`Axis::status`].
//!
//! All values cross the API in the device's raw units (integers as on the bus: 0.01° or counts,
//! 0.01 rpm, rpm/s, mA, ...). [`Units`] says how raw velocities and accelerations relate to
//! position units; conversion to physical units happens elsewhere (the device sidecars).
//!
//! # What is modelled
//!
//! * **Profiles** ([`Mode::ProfilePosition`], [`Mode::ProfileVelocity`], [`Mode::Jog`]):
//!   trapezoidal velocity profiles planned in closed form, so a move ends exactly on its target
//!   whatever the step size; absolute and relative targets; a new set-point either changes the
//!   move immediately or waits in a one-entry buffer (optionally blending through the first
//!   target); halt; triangular profiles for short moves.
//! * **Stops**: halt (605Dh), quick stop (605Ah, decoded by [`QuickStopOption`]) and fault
//!   reactions as [`StopRamp`]s; coasting when the power stage is off; a holding brake.
//! * **Torque** ([`Mode::ProfileTorque`]): the target torque ramped with the torque slope and
//!   limited to the torque limit; the axis accelerates by inertia and friction.
//! * **Homing** ([`Mode::Homing`]): CiA 402 methods and the Camozzi ones (see [`HomingMethod`]),
//!   on a simulated axis with a home switch, limit switches, hard end stops and an encoder index.
//! * **Interpolated position** ([`Mode::InterpolatedPosition`]): a set-point buffer consumed at
//!   each [`Axis::sync`], linear interpolation in between.
//! * **Status**: target reached with the position and velocity windows, set-point acknowledge,
//!   following error, internal limit active (software limits clip targets), torque limit
//!   active, zero speed, homing state, sensor inputs.
//!
//! The servo normally follows the demand exactly. When it cannot (the torque needed exceeds the
//! limit, an end stop or the brake blocks the axis) the mechanics are integrated with inertia
//! and friction and a position loop pulls the axis back onto the demand, which is where
//! following errors and torque saturation come from. Nothing panics and nothing becomes NaN:
//! out-of-range values saturate and set [`Status::saturated`].
//!
//! # Example: the DRVI's Figure 4.2
//!
//! 720° at 60 rpm with 60 rpm/s, "only motor" units (0.01°, 0.01 rpm, rpm/s):
//!
//! ```
//! use drive::motion::{Axis, AxisConfig, Mode, Ratio, SetPoint, Units};
//!
//! let units = Units { velocity: Ratio::new(6, 1), acceleration: Ratio::new(600, 1) };
//! let mut axis = Axis::new(AxisConfig {
//!     units,
//!     profile_velocity: 6000,   // 60 rpm
//!     profile_acceleration: 60, // 60 rpm/s
//!     profile_deceleration: 60,
//!     ..AxisConfig::default()
//! });
//! axis.set_power(true);
//! axis.set_mode(Mode::ProfilePosition);
//! axis.new_set_point(SetPoint { target: 72_000, ..SetPoint::default() }).unwrap();
//! let mut peak = 0;
//! for _ in 0..3000 {
//!     axis.step(1000);
//!     peak = peak.max(axis.status().velocity_actual);
//! }
//! let status = axis.status();
//! assert!(status.target_reached);
//! assert_eq!(status.position_actual, 72_000);
//! assert_eq!(peak, 6000);
//! ```

mod axis;
mod config;
mod homing;
mod interp;
mod machine;
mod plant;
mod profile;
mod units;

pub use axis::{Axis, CommandError, Inputs, JogCommand, JogState, SetPoint, Status};
pub use config::{AxisConfig, InterpolationConfig, Mode, QuickStopOption, RelativeBase, SoftwareLimits, StopRamp};
pub use homing::{
    Direction, Edge, HomeOffsetMode, HomingConfig, HomingError, HomingKind, HomingMethod, HomingSignal, HomingState,
};
pub use machine::{Machine, MachineError, Travel};
pub use plant::{Cam, Environment, PlantConfig};
pub use units::{Ratio, Units};
