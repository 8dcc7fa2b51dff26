//! The objects CiA 301 and CiA 402 define, under the standard's names, for code written once
//! for any device's generated client.
//!
//! Every generated client (`od_codegen::Builder::client`, `odgen gen --client`,
//! `include_eds!(…, client)`) implements [`Cia301`] and [`Cia402`], whatever the vendor called
//! the objects in its file (the vendor's names stay, as the client's own methods). A method
//! gives the object's handle, typed by the standard's data type, access and (for motion
//! objects) dimension; an object the file does not have, or has with another type or a
//! narrower access, is an [`Error::Refused`] at once, with the abort code the device would
//! give (0602 0000h "object does not exist", 0607 0010h "data type does not match"), before
//! anything is sent.
//!
//! ```
//! use od_master::profile::Cia402;
//! use od_master::remote::{Quantity, Scaling, dim};
//!
//! /// Works with the AKD's client, the DRVI's, or one generated from any vendor's CiA 402 file.
//! async fn go_to<D: Cia402>(
//!     drive: &D,
//!     units: &dyn Scaling,
//!     to: Quantity<dim::Position>,
//! ) -> Result<u16, od_master::Error> {
//!     drive.target_position()?.write_in(units, to).await?;
//!     drive.statusword()?.read().await
//! }
//! ```
//!
//! The table of objects is od-codegen's `standard::OBJECTS`; the clients implement these
//! traits from it, so a client compiles only when the two agree.

use od_runtime::od::AbortCode;

use crate::error::Error;
use crate::node::Node;
use crate::remote::{Ro, Rw, VisibleString, dim};

/// The error of a standard object the description lacks: what the device would answer.
pub fn missing(node: &Node, index: u16, sub: u8) -> Error {
    Error::Refused { node: node.id(), index, sub, code: AbortCode::NO_OBJECT }
}

/// The error of a standard object the description has with another data type, or an access
/// narrower than the standard's.
pub fn mistyped(node: &Node, index: u16, sub: u8) -> Error {
    Error::Refused { node: node.id(), index, sub, code: AbortCode::LENGTH_MISMATCH }
}

macro_rules! profile {
    (
        $(#[$tm:meta])*
        trait $tr:ident $(: $sup:ident)? { $($head:tt)* }
        $( $(#[$m:meta])* fn $name:ident = $idx:literal, $sub:literal: $acc:ident<$w:ty $(, $d:ident)?>; )*
    ) => {
        $(#[$tm])*
        pub trait $tr $(: $sup)? {
            $($head)*
            $(
                $(#[$m])*
                #[doc = concat!("\n\n`", stringify!($idx), "` sub ", stringify!($sub), ": `", stringify!($acc), "<", stringify!($w), $(", ", stringify!($d),)? ">`.")]
                fn $name(&self) -> Result<$acc<'_, $w $(, dim::$d)?>, Error> {
                    Err(missing(self.node(), $idx, $sub))
                }
            )*
        }
    };
}

profile! {
    /// The CiA 301 objects of any CANopen device (communication profile).
    trait Cia301 {
        /// The node the device is on.
        fn node(&self) -> &Node;
    }
    /// Device type: the profile (low 16 bits) and its additional information.
    fn device_type = 0x1000, 0: Ro<u32>;
    /// Error register.
    fn error_register = 0x1001, 0: Ro<u8>;
    /// COB-ID of the SYNC message.
    fn cob_id_sync = 0x1005, 0: Rw<u32>;
    /// Communication cycle period (µs).
    fn communication_cycle_period = 0x1006, 0: Rw<u32>;
    /// Manufacturer device name.
    fn manufacturer_device_name = 0x1008, 0: Ro<VisibleString>;
    /// Manufacturer hardware version.
    fn manufacturer_hardware_version = 0x1009, 0: Ro<VisibleString>;
    /// Manufacturer software version.
    fn manufacturer_software_version = 0x100A, 0: Ro<VisibleString>;
    /// Store parameters: all parameters (write "save").
    fn store_all_parameters = 0x1010, 1: Rw<u32>;
    /// Restore default parameters: all parameters (write "load").
    fn restore_all_default_parameters = 0x1011, 1: Rw<u32>;
    /// COB-ID of the EMCY message.
    fn cob_id_emcy = 0x1014, 0: Ro<u32>;
    /// Producer heartbeat time (ms).
    fn producer_heartbeat_time = 0x1017, 0: Rw<u16>;
    /// Identity: vendor-ID.
    fn vendor_id = 0x1018, 1: Ro<u32>;
    /// Identity: product code.
    fn product_code = 0x1018, 2: Ro<u32>;
    /// Identity: revision number.
    fn revision_number = 0x1018, 3: Ro<u32>;
    /// Identity: serial number.
    fn serial_number = 0x1018, 4: Ro<u32>;
}

profile! {
    /// The CiA 402 objects of a drive (drives and motion control), typed by the standard:
    /// positions, velocities, accelerations, torques and currents by their dimension.
    trait Cia402: Cia301 {}
    /// Error code (the last error, CiA 402 codes).
    fn error_code = 0x603F, 0: Ro<u16>;
    /// Controlword.
    fn controlword = 0x6040, 0: Rw<u16>;
    /// Statusword.
    fn statusword = 0x6041, 0: Ro<u16>;
    /// Quick stop option code.
    fn quick_stop_option_code = 0x605A, 0: Rw<i16>;
    /// Shutdown option code.
    fn shutdown_option_code = 0x605B, 0: Rw<i16>;
    /// Disable operation option code.
    fn disable_operation_option_code = 0x605C, 0: Rw<i16>;
    /// Halt option code.
    fn halt_option_code = 0x605D, 0: Rw<i16>;
    /// Fault reaction option code.
    fn fault_reaction_option_code = 0x605E, 0: Rw<i16>;
    /// Modes of operation.
    fn modes_of_operation = 0x6060, 0: Rw<i8>;
    /// Modes of operation display.
    fn modes_of_operation_display = 0x6061, 0: Ro<i8>;
    /// Position demand value.
    fn position_demand_value = 0x6062, 0: Ro<i32, Position>;
    /// Position actual value.
    fn position_actual_value = 0x6064, 0: Ro<i32, Position>;
    /// Following error window.
    fn following_error_window = 0x6065, 0: Rw<u32, Position>;
    /// Following error time out.
    fn following_error_time_out = 0x6066, 0: Rw<u16, Time>;
    /// Position window.
    fn position_window = 0x6067, 0: Rw<u32, Position>;
    /// Position window time.
    fn position_window_time = 0x6068, 0: Rw<u16, Time>;
    /// Velocity demand value.
    fn velocity_demand_value = 0x606B, 0: Ro<i32, Velocity>;
    /// Velocity actual value.
    fn velocity_actual_value = 0x606C, 0: Ro<i32, Velocity>;
    /// Velocity window.
    fn velocity_window = 0x606D, 0: Rw<u16, Velocity>;
    /// Velocity window time.
    fn velocity_window_time = 0x606E, 0: Rw<u16, Time>;
    /// Velocity threshold.
    fn velocity_threshold = 0x606F, 0: Rw<u16, Velocity>;
    /// Velocity threshold time.
    fn velocity_threshold_time = 0x6070, 0: Rw<u16, Time>;
    /// Target torque.
    fn target_torque = 0x6071, 0: Rw<i16, Torque>;
    /// Max torque.
    fn max_torque = 0x6072, 0: Rw<u16, Torque>;
    /// Max current.
    fn max_current = 0x6073, 0: Rw<u16, Current>;
    /// Torque demand.
    fn torque_demand = 0x6074, 0: Ro<i16, Torque>;
    /// Torque actual value.
    fn torque_actual_value = 0x6077, 0: Ro<i16, Torque>;
    /// Current actual value.
    fn current_actual_value = 0x6078, 0: Ro<i16, Current>;
    /// Target position.
    fn target_position = 0x607A, 0: Rw<i32, Position>;
    /// Position range limit: min.
    fn min_position_range_limit = 0x607B, 1: Rw<i32, Position>;
    /// Position range limit: max.
    fn max_position_range_limit = 0x607B, 2: Rw<i32, Position>;
    /// Home offset.
    fn home_offset = 0x607C, 0: Rw<i32, Position>;
    /// Software position limit: min.
    fn min_position_limit = 0x607D, 1: Rw<i32, Position>;
    /// Software position limit: max.
    fn max_position_limit = 0x607D, 2: Rw<i32, Position>;
    /// Max profile velocity.
    fn max_profile_velocity = 0x607F, 0: Rw<u32, Velocity>;
    /// Profile velocity.
    fn profile_velocity = 0x6081, 0: Rw<u32, Velocity>;
    /// End velocity.
    fn end_velocity = 0x6082, 0: Rw<u32, Velocity>;
    /// Profile acceleration.
    fn profile_acceleration = 0x6083, 0: Rw<u32, Acceleration>;
    /// Profile deceleration.
    fn profile_deceleration = 0x6084, 0: Rw<u32, Acceleration>;
    /// Quick stop deceleration.
    fn quick_stop_deceleration = 0x6085, 0: Rw<u32, Acceleration>;
    /// Motion profile type.
    fn motion_profile_type = 0x6086, 0: Rw<i16>;
    /// Torque slope.
    fn torque_slope = 0x6087, 0: Rw<u32, TorqueSlope>;
    /// Position encoder resolution: encoder increments.
    fn position_encoder_resolution_encoder_increments = 0x608F, 1: Rw<u32>;
    /// Position encoder resolution: motor revolutions.
    fn position_encoder_resolution_motor_revolutions = 0x608F, 2: Rw<u32>;
    /// Gear ratio: motor revolutions.
    fn gear_ratio_motor_revolutions = 0x6091, 1: Rw<u32>;
    /// Gear ratio: shaft revolutions.
    fn gear_ratio_shaft_revolutions = 0x6091, 2: Rw<u32>;
    /// Feed constant: feed.
    fn feed_constant_feed = 0x6092, 1: Rw<u32>;
    /// Feed constant: shaft revolutions.
    fn feed_constant_shaft_revolutions = 0x6092, 2: Rw<u32>;
    /// Homing method.
    fn homing_method = 0x6098, 0: Rw<i8>;
    /// Homing speeds: speed during search for switch.
    fn speed_during_search_for_switch = 0x6099, 1: Rw<u32, Velocity>;
    /// Homing speeds: speed during search for zero.
    fn speed_during_search_for_zero = 0x6099, 2: Rw<u32, Velocity>;
    /// Homing acceleration.
    fn homing_acceleration = 0x609A, 0: Rw<u32, Acceleration>;
    /// SI unit position.
    fn si_unit_position = 0x60A8, 0: Rw<u32>;
    /// SI unit velocity.
    fn si_unit_velocity = 0x60A9, 0: Rw<u32>;
    /// SI unit acceleration.
    fn si_unit_acceleration = 0x60AA, 0: Rw<u32>;
    /// Position offset.
    fn position_offset = 0x60B0, 0: Rw<i32, Position>;
    /// Velocity offset.
    fn velocity_offset = 0x60B1, 0: Rw<i32, Velocity>;
    /// Torque offset.
    fn torque_offset = 0x60B2, 0: Rw<i16, Torque>;
    /// Max acceleration.
    fn max_acceleration = 0x60C5, 0: Rw<u32, Acceleration>;
    /// Max deceleration.
    fn max_deceleration = 0x60C6, 0: Rw<u32, Acceleration>;
    /// Following error actual value.
    fn following_error_actual_value = 0x60F4, 0: Ro<i32, Position>;
    /// Digital inputs.
    fn digital_inputs = 0x60FD, 0: Ro<u32>;
    /// Target velocity.
    fn target_velocity = 0x60FF, 0: Rw<i32, Velocity>;
    /// Supported drive modes.
    fn supported_drive_modes = 0x6502, 0: Ro<u32>;
}
