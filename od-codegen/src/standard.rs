//! The objects CiA 301 and CiA 402 define: their standard names, types, access and (for
//! CiA 402's motion objects) physical dimensions, whatever a vendor's file calls them.
//!
//! * Every generated client implements `od_master::profile::Cia301` and, when the device has
//!   CiA 402 objects, `od_master::profile::Cia402`: one method per object of the table below,
//!   under the standard's name, so code written against the traits works with any drive's
//!   client (a method of an object the file lacks, or types differently, fails at once with
//!   the abort code the device would give, before anything is sent).
//! * Every object of the table with a dimension is typed by it in every generated client and
//!   units module, with or without a sidecar ([`dimension`], [`effective_sidecar`]).
//! * Without a sidecar, [`starting_sidecar`] derives the units from the file's own 402
//!   objects (`odgen sidecar FILE` writes it out as a starting point): the SI unit objects
//!   (60A8h, 60A9h, 60AAh, CiA 402's encoding: bits 24..31 the power of ten, bits 16..23 the
//!   unit, bits 8..15 the time unit) where the file has them and this crate has the unit, the
//!   factor group (608Fh, 6091h, 6092h) for the motor side, and else the drive's own "position
//!   units" (`user`, `user/s`, `user/s^2`), which the generated docs then name.

use std::collections::BTreeMap;

use eds::model::{Access, DataType, Model, Value};

use crate::sidecar::{
    Condition, DeviceMeta, Dimension, Num, ObjRef, Ratio, ScalingKind, ScalingObject, Sidecar, Store, Unit, UnitSpec,
    UnitSystem,
};

/// Which standard an object belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Profile {
    /// CiA 301 (communication profile).
    Cia301,
    /// CiA 402 (drives and motion control).
    Cia402,
}

/// The standard access of an object, as the trait method's handle has it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StdAccess {
    /// Read only.
    Ro,
    /// Read and write.
    Rw,
}

/// One object (or sub-object) a standard defines.
#[derive(Clone, Copy, Debug)]
pub struct StdObject {
    /// The standard.
    pub profile: Profile,
    /// Index.
    pub index: u16,
    /// Sub-index (0 for a VAR).
    pub sub: u8,
    /// The standard's name, in `snake_case`: the trait method's name.
    pub name: &'static str,
    /// The standard's data type.
    pub data_type: DataType,
    /// The standard's access.
    pub access: StdAccess,
    /// The physical dimension, for CiA 402's motion objects.
    pub dimension: Option<Dimension>,
}

const fn o(
    profile: Profile,
    index: u16,
    sub: u8,
    name: &'static str,
    data_type: DataType,
    access: StdAccess,
    dimension: Option<Dimension>,
) -> StdObject {
    StdObject { profile, index, sub, name, data_type, access, dimension }
}

use DataType as T;
use Dimension as D;
use Profile::{Cia301 as P301, Cia402 as P402};
use StdAccess::{Ro, Rw};

/// The standard objects, in index order. `od_master::profile`'s traits list the same objects
/// with the same names, types, access and dimensions (the generated clients, which implement
/// them from this table, only compile when the two agree).
pub const OBJECTS: &[StdObject] = &[
    o(P301, 0x1000, 0, "device_type", T::Unsigned32, Ro, None),
    o(P301, 0x1001, 0, "error_register", T::Unsigned8, Ro, None),
    o(P301, 0x1005, 0, "cob_id_sync", T::Unsigned32, Rw, None),
    o(P301, 0x1006, 0, "communication_cycle_period", T::Unsigned32, Rw, None),
    o(P301, 0x1008, 0, "manufacturer_device_name", T::VisibleString, Ro, None),
    o(P301, 0x1009, 0, "manufacturer_hardware_version", T::VisibleString, Ro, None),
    o(P301, 0x100A, 0, "manufacturer_software_version", T::VisibleString, Ro, None),
    o(P301, 0x1010, 1, "store_all_parameters", T::Unsigned32, Rw, None),
    o(P301, 0x1011, 1, "restore_all_default_parameters", T::Unsigned32, Rw, None),
    o(P301, 0x1014, 0, "cob_id_emcy", T::Unsigned32, Ro, None),
    o(P301, 0x1017, 0, "producer_heartbeat_time", T::Unsigned16, Rw, None),
    o(P301, 0x1018, 1, "vendor_id", T::Unsigned32, Ro, None),
    o(P301, 0x1018, 2, "product_code", T::Unsigned32, Ro, None),
    o(P301, 0x1018, 3, "revision_number", T::Unsigned32, Ro, None),
    o(P301, 0x1018, 4, "serial_number", T::Unsigned32, Ro, None),
    o(P402, 0x603F, 0, "error_code", T::Unsigned16, Ro, None),
    o(P402, 0x6040, 0, "controlword", T::Unsigned16, Rw, None),
    o(P402, 0x6041, 0, "statusword", T::Unsigned16, Ro, None),
    o(P402, 0x605A, 0, "quick_stop_option_code", T::Integer16, Rw, None),
    o(P402, 0x605B, 0, "shutdown_option_code", T::Integer16, Rw, None),
    o(P402, 0x605C, 0, "disable_operation_option_code", T::Integer16, Rw, None),
    o(P402, 0x605D, 0, "halt_option_code", T::Integer16, Rw, None),
    o(P402, 0x605E, 0, "fault_reaction_option_code", T::Integer16, Rw, None),
    o(P402, 0x6060, 0, "modes_of_operation", T::Integer8, Rw, None),
    o(P402, 0x6061, 0, "modes_of_operation_display", T::Integer8, Ro, None),
    o(P402, 0x6062, 0, "position_demand_value", T::Integer32, Ro, Some(D::Position)),
    o(P402, 0x6064, 0, "position_actual_value", T::Integer32, Ro, Some(D::Position)),
    o(P402, 0x6065, 0, "following_error_window", T::Unsigned32, Rw, Some(D::Position)),
    o(P402, 0x6066, 0, "following_error_time_out", T::Unsigned16, Rw, Some(D::Time)),
    o(P402, 0x6067, 0, "position_window", T::Unsigned32, Rw, Some(D::Position)),
    o(P402, 0x6068, 0, "position_window_time", T::Unsigned16, Rw, Some(D::Time)),
    o(P402, 0x606B, 0, "velocity_demand_value", T::Integer32, Ro, Some(D::Velocity)),
    o(P402, 0x606C, 0, "velocity_actual_value", T::Integer32, Ro, Some(D::Velocity)),
    o(P402, 0x606D, 0, "velocity_window", T::Unsigned16, Rw, Some(D::Velocity)),
    o(P402, 0x606E, 0, "velocity_window_time", T::Unsigned16, Rw, Some(D::Time)),
    o(P402, 0x606F, 0, "velocity_threshold", T::Unsigned16, Rw, Some(D::Velocity)),
    o(P402, 0x6070, 0, "velocity_threshold_time", T::Unsigned16, Rw, Some(D::Time)),
    o(P402, 0x6071, 0, "target_torque", T::Integer16, Rw, Some(D::Torque)),
    o(P402, 0x6072, 0, "max_torque", T::Unsigned16, Rw, Some(D::Torque)),
    o(P402, 0x6073, 0, "max_current", T::Unsigned16, Rw, Some(D::Current)),
    o(P402, 0x6074, 0, "torque_demand", T::Integer16, Ro, Some(D::Torque)),
    o(P402, 0x6077, 0, "torque_actual_value", T::Integer16, Ro, Some(D::Torque)),
    o(P402, 0x6078, 0, "current_actual_value", T::Integer16, Ro, Some(D::Current)),
    o(P402, 0x607A, 0, "target_position", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607B, 1, "min_position_range_limit", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607B, 2, "max_position_range_limit", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607C, 0, "home_offset", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607D, 1, "min_position_limit", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607D, 2, "max_position_limit", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x607F, 0, "max_profile_velocity", T::Unsigned32, Rw, Some(D::Velocity)),
    o(P402, 0x6081, 0, "profile_velocity", T::Unsigned32, Rw, Some(D::Velocity)),
    o(P402, 0x6082, 0, "end_velocity", T::Unsigned32, Rw, Some(D::Velocity)),
    o(P402, 0x6083, 0, "profile_acceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x6084, 0, "profile_deceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x6085, 0, "quick_stop_deceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x6086, 0, "motion_profile_type", T::Integer16, Rw, None),
    o(P402, 0x6087, 0, "torque_slope", T::Unsigned32, Rw, Some(D::TorqueSlope)),
    o(P402, 0x608F, 1, "position_encoder_resolution_encoder_increments", T::Unsigned32, Rw, None),
    o(P402, 0x608F, 2, "position_encoder_resolution_motor_revolutions", T::Unsigned32, Rw, None),
    o(P402, 0x6091, 1, "gear_ratio_motor_revolutions", T::Unsigned32, Rw, None),
    o(P402, 0x6091, 2, "gear_ratio_shaft_revolutions", T::Unsigned32, Rw, None),
    o(P402, 0x6092, 1, "feed_constant_feed", T::Unsigned32, Rw, None),
    o(P402, 0x6092, 2, "feed_constant_shaft_revolutions", T::Unsigned32, Rw, None),
    o(P402, 0x6098, 0, "homing_method", T::Integer8, Rw, None),
    o(P402, 0x6099, 1, "speed_during_search_for_switch", T::Unsigned32, Rw, Some(D::Velocity)),
    o(P402, 0x6099, 2, "speed_during_search_for_zero", T::Unsigned32, Rw, Some(D::Velocity)),
    o(P402, 0x609A, 0, "homing_acceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x60A8, 0, "si_unit_position", T::Unsigned32, Rw, None),
    o(P402, 0x60A9, 0, "si_unit_velocity", T::Unsigned32, Rw, None),
    o(P402, 0x60AA, 0, "si_unit_acceleration", T::Unsigned32, Rw, None),
    o(P402, 0x60B0, 0, "position_offset", T::Integer32, Rw, Some(D::Position)),
    o(P402, 0x60B1, 0, "velocity_offset", T::Integer32, Rw, Some(D::Velocity)),
    o(P402, 0x60B2, 0, "torque_offset", T::Integer16, Rw, Some(D::Torque)),
    o(P402, 0x60C5, 0, "max_acceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x60C6, 0, "max_deceleration", T::Unsigned32, Rw, Some(D::Acceleration)),
    o(P402, 0x60F4, 0, "following_error_actual_value", T::Integer32, Ro, Some(D::Position)),
    o(P402, 0x60FD, 0, "digital_inputs", T::Unsigned32, Ro, None),
    o(P402, 0x60FF, 0, "target_velocity", T::Integer32, Rw, Some(D::Velocity)),
    o(P402, 0x6502, 0, "supported_drive_modes", T::Unsigned32, Ro, None),
];

/// The standard object at `(index, sub)`, if the table has it.
pub fn object(index: u16, sub: u8) -> Option<&'static StdObject> {
    OBJECTS.iter().find(|o| o.index == index && o.sub == sub)
}

/// The dimension CiA 402 gives `(index, sub)`, if any.
pub fn dimension(index: u16, sub: u8) -> Option<Dimension> {
    object(index, sub).and_then(|o| o.dimension)
}

/// Whether the file's entry `(data_type, access)` can serve the standard object: the same
/// wire type, and every access the standard's handle allows (a `ro` standard object may be
/// `rw` in the file; an `rw` one must be writable and readable).
pub fn serves(o: &StdObject, data_type: DataType, access: Access) -> bool {
    let readable = access != Access::Wo;
    let writable = matches!(access, Access::Rw | Access::Rwr | Access::Rww);
    let same_type = data_type == o.data_type
        || (o.data_type == T::VisibleString && matches!(data_type, T::VisibleString | T::OctetString));
    same_type
        && match o.access {
            Ro => readable,
            Rw => readable && writable,
        }
}

/// Whether `model` has a CiA 402 object of the table.
pub fn has_cia402(model: &Model) -> bool {
    OBJECTS.iter().any(|o| o.profile == P402 && model.entry(o.index, o.sub).is_some())
}

/// The sidecar the generator uses: `given` with the positions, velocities and accelerations
/// of CiA 402 added where it names none (only dimensions its unit systems have units for, so
/// the generated code stays consistent); without a sidecar, [`starting_sidecar`] when the file has
/// dimensioned CiA 402 objects.
pub fn effective_sidecar(model: &Model, given: Option<&Sidecar>, source_name: &str) -> Option<Sidecar> {
    match given {
        Some(sc) => {
            let mut sc = sc.clone();
            let dims: Vec<Dimension> = sc.unit_systems.iter().flat_map(|s| s.units.keys().copied()).collect::<Vec<_>>();
            for o in OBJECTS {
                let Some(d) = o.dimension else { continue };
                let Some(e) = model.entry(o.index, o.sub) else { continue };
                // Positions, velocities and accelerations are all in the drive's configured
                // units (CiA 402's factor group), so the sidecar's units for them hold for every
                // such object; a torque or current object's unit is its own (thousandths of the
                // rated value, or mA), which only the sidecar can say.
                let shared = matches!(d, Dimension::Position | Dimension::Velocity | Dimension::Acceleration);
                if !shared || !is_int(e.data_type) || !dims.contains(&d) || sc.dimension_of(o.index, o.sub).is_some() {
                    continue;
                }
                sc.dimensions.insert(ObjRef { index: o.index, sub: Some(o.sub) }, d);
            }
            Some(sc)
        }
        None => starting_sidecar(model, source_name),
    }
}

fn is_int(dt: DataType) -> bool {
    use DataType as D;
    matches!(
        dt,
        D::Unsigned8
            | D::Unsigned16
            | D::Unsigned24
            | D::Unsigned32
            | D::Unsigned40
            | D::Unsigned48
            | D::Unsigned56
            | D::Unsigned64
            | D::Integer8
            | D::Integer16
            | D::Integer24
            | D::Integer32
            | D::Integer40
            | D::Integer48
            | D::Integer56
            | D::Integer64
    )
}

/// The integer default (or DCF value) of `(index, sub)`.
fn int_value(model: &Model, index: u16, sub: u8) -> Option<i128> {
    let e = model.entry(index, sub)?;
    match e.parameter_value().or(e.default.as_ref())? {
        Value::Int { value, .. } => Some(*value),
        _ => None,
    }
}

fn int_entry(model: &Model, index: u16, sub: u8) -> bool {
    model.entry(index, sub).is_some_and(|e| is_int(e.data_type))
}

/// `10^exp` as a positive ratio, for |exp| <= 18.
fn pow10(exp: i32) -> Option<Ratio> {
    let p = 10u64.checked_pow(exp.unsigned_abs())?;
    Some(if exp >= 0 { Ratio { num: p, den: 1 } } else { Ratio { num: 1, den: p } })
}

fn times(a: Ratio, b: Ratio) -> Option<Ratio> {
    let (num, den) = (a.num.checked_mul(b.num)?, a.den.checked_mul(b.den)?);
    let g = gcd(num, den);
    Some(Ratio { num: num / g, den: den / g })
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a.max(1) } else { gcd(b, a % b) }
}

/// CiA 402's unit codes (bits 16..23) this crate has a unit for: the position unit and its
/// scale to it (metre → mm × 1000).
fn length_unit(code: u8) -> Option<(Unit, Ratio, Unit, Unit)> {
    let one = Ratio::ONE;
    Some(match code {
        0x01 => (Unit::Millimeter, Ratio { num: 1000, den: 1 }, Unit::MillimeterPerSecond, Unit::MillimeterPerSecond2),
        0xC1 => (Unit::Inch, one, Unit::InchPerSecond, Unit::InchPerSecond2),
        0x41 => (Unit::Degree, one, Unit::DegreePerSecond, Unit::DegreePerSecond2),
        0xB5 => (Unit::Increment, one, Unit::IncrementPerSecond, Unit::IncrementPerSecond2),
        0xB4 => (Unit::Revolution, one, Unit::Rpm, Unit::RpmPerSecond),
        _ => return None,
    })
}

const SECOND: u8 = 0x03;
const MINUTE: u8 = 0x47;

/// The unit and scale of an SI unit object's value (`0xPPUUTT00`, `0xPPUUTTSS` for
/// accelerations), for dimension `d`; `None` when this crate has no such unit.
pub fn decode_si(d: Dimension, code: u32) -> Option<(Unit, Ratio)> {
    let prefix = (code >> 24) as u8 as i8;
    let unit = (code >> 16) as u8;
    let time = (code >> 8) as u8;
    let time2 = code as u8;
    let scale = pow10(i32::from(prefix))?;
    let (pos, to_pos, vel, acc) = length_unit(unit)?;
    match d {
        Dimension::Position if time == 0 && time2 == 0 => Some((pos, times(scale, to_pos)?)),
        Dimension::Velocity if time2 == 0 => {
            if pos == Unit::Revolution {
                // rev/min is rpm; rev/s is 60 rpm.
                match time {
                    MINUTE => Some((vel, scale)),
                    SECOND => Some((vel, times(scale, Ratio { num: 60, den: 1 })?)),
                    _ => None,
                }
            } else {
                (time == SECOND).then_some((vel, times(scale, to_pos)?))
            }
        }
        Dimension::Acceleration => {
            if pos == Unit::Revolution {
                // rev/min/s is rpm/s; rev/s² is 60 rpm/s.
                match (time, time2) {
                    (MINUTE, SECOND) => Some((acc, scale)),
                    (SECOND, SECOND) | (SECOND, 0) => Some((acc, times(scale, Ratio { num: 60, den: 1 })?)),
                    _ => None,
                }
            } else {
                (time == SECOND && matches!(time2, 0 | SECOND)).then_some((acc, times(scale, to_pos)?))
            }
        }
        _ => None,
    }
}

/// A sidecar for a file without one, from its CiA 402 objects (`None` when it has no
/// dimensioned CiA 402 object): `[dimensions]` for every such object; the factor group's
/// scaling objects (608Fh, 6091h, 6092h) where the file has them; one unit system
/// `si-units`, selected while the SI unit objects hold their defaults, when those defaults are
/// units this crate has; and the system `position-units` otherwise: positions, velocities
/// and accelerations in the drive's position units (`user`, `user/s`, `user/s^2`), torques
/// in thousandths of the rated torque, currents in thousandths of the rated current (CiA 402),
/// times in ms.
pub fn starting_sidecar(model: &Model, source_name: &str) -> Option<Sidecar> {
    let mut dimensions = BTreeMap::new();
    for o in OBJECTS {
        if let Some(d) = o.dimension
            && int_entry(model, o.index, o.sub)
        {
            dimensions.insert(ObjRef { index: o.index, sub: Some(o.sub) }, d);
        }
    }
    if dimensions.is_empty() {
        return None;
    }
    let file = source_name.rsplit(['/', '\\']).next().unwrap_or(source_name);
    let stem = file.rsplit_once('.').map_or(file, |(s, _)| s);

    let mut scaling = Vec::new();
    let factor = |index: u16, kind: ScalingKind, upper: &str, lower: &str, formula: &str| {
        (int_entry(model, index, 1) && int_entry(model, index, 2)).then(|| ScalingObject {
            object: ObjRef { index, sub: None },
            kind,
            subs: [(upper.to_owned(), 1u8), (lower.to_owned(), 2u8)].into_iter().collect(),
            formula: formula.to_owned(),
            applies_to: vec![Dimension::Position, Dimension::Velocity, Dimension::Acceleration],
            feed_unit: None,
            note: Some("CiA 402 factor group (written by od-codegen from the description)".to_owned()),
        })
    };
    scaling.extend(factor(
        0x608F,
        ScalingKind::EncoderResolution,
        "encoder_increments",
        "motor_revolutions",
        "increments = motor_revolutions * encoder_increments / motor_revolutions",
    ));
    scaling.extend(factor(
        0x6091,
        ScalingKind::GearRatio,
        "motor_revolutions",
        "shaft_revolutions",
        "motor_revolutions = shaft_revolutions * motor_revolutions / shaft_revolutions",
    ));
    scaling.extend(factor(
        0x6092,
        ScalingKind::FeedConstant,
        "feed",
        "shaft_revolutions",
        "shaft_revolutions = position_user * shaft_revolutions / feed",
    ));
    let chain: Vec<ScalingKind> = scaling.iter().map(|s| s.kind).collect();
    let spec = |unit: Unit, scale: Ratio, motion: bool| UnitSpec {
        unit,
        scale,
        scaled_by: if motion { chain.clone() } else { Vec::new() },
    };
    let mut fixed: BTreeMap<Dimension, UnitSpec> = BTreeMap::new();
    fixed.insert(Dimension::Torque, spec(Unit::PermilleRatedTorque, Ratio::ONE, false));
    fixed.insert(Dimension::TorqueSlope, spec(Unit::PermilleRatedTorquePerSecond, Ratio::ONE, false));
    fixed.insert(Dimension::Current, spec(Unit::PermilleRatedCurrent, Ratio::ONE, false));
    fixed.insert(Dimension::Time, spec(Unit::Millisecond, Ratio::ONE, false));

    let mut user = fixed.clone();
    user.insert(Dimension::Position, spec(Unit::UserUnit, Ratio::ONE, true));
    user.insert(Dimension::Velocity, spec(Unit::UserUnitPerSecond, Ratio::ONE, true));
    user.insert(Dimension::Acceleration, spec(Unit::UserUnitPerSecond2, Ratio::ONE, true));

    let mut unit_systems = Vec::new();
    // The SI unit objects' defaults, where this crate has their units: a system selected
    // while the drive holds them.
    let si = [(0x60A8u16, Dimension::Position), (0x60A9, Dimension::Velocity), (0x60AA, Dimension::Acceleration)];
    let mut when = Vec::new();
    let mut si_units = fixed.clone();
    let mut said = Vec::new();
    for (index, d) in si {
        let Some(v) = int_value(model, index, 0).filter(|_| int_entry(model, index, 0)) else { continue };
        let Ok(code) = u32::try_from(v) else { continue };
        if let Some((unit, scale)) = decode_si(d, code) {
            when.push(Condition { object: ObjRef { index, sub: None }, mask: None, equals: Num(i64::from(code)) });
            si_units.insert(d, spec(unit, scale, true));
            said.push(format!("{index:04X}h = {code:08X}h"));
        }
    }
    if !when.is_empty() {
        for d in [Dimension::Position, Dimension::Velocity, Dimension::Acceleration] {
            si_units.entry(d).or_insert_with(|| user[&d].clone());
        }
        unit_systems.push(UnitSystem {
            name: "si-units".to_owned(),
            description: Some(format!(
                "the SI unit objects at their defaults ({}); other values select `position-units`",
                said.join(", ")
            )),
            when,
            external: None,
            units: si_units,
        });
    }
    unit_systems.push(UnitSystem {
        name: "position-units".to_owned(),
        description: Some(
            "the drive's own position units (CiA 402 user units, no SI unit object this crate reads): \
             positions in `user`, velocities in `user/s`, accelerations in `user/s^2`"
                .to_owned(),
        ),
        when: Vec::new(),
        external: None,
        units: user,
    });
    Some(Sidecar {
        device: DeviceMeta { name: stem.to_owned(), eds: file.to_owned(), manual: None, vendor: model_vendor(model) },
        dimensions,
        unit_systems,
        scaling,
        object_units: BTreeMap::new(),
        bus_scaling: BTreeMap::new(),
        modes: Vec::new(),
        homing_methods: Vec::new(),
        errors: Vec::new(),
        warnings: Vec::new(),
        store: Store::default(),
        pdo: Default::default(),
        decisions: Vec::new(),
    })
}

fn model_vendor(model: &Model) -> Option<String> {
    model.device_info.vendor_name.as_deref().map(str::to_owned)
}

/// `impl Dictionary { … }`: each standard object of the file under the standard's name (getter
/// and `set_` setter calling the vendor-named ones), where the file's entry has the standard's
/// type and the standard's name is not already an accessor (of this object: the same name; of
/// another: the vendor's name wins). Empty when no alias is needed.
pub(crate) fn dictionary_aliases(plan: &crate::plan::Plan<'_>) -> proc_macro2::TokenStream {
    use quote::{format_ident, quote};
    let taken: std::collections::BTreeSet<&str> = plan.entries.iter().map(|e| e.field.as_str()).collect();
    let mut items = Vec::new();
    for o in OBJECTS {
        let Some(e) = plan.entries.iter().find(|e| e.index == o.index && e.sub == o.sub) else { continue };
        if !e.ty.is_int() || e.dt != o.data_type || e.field == o.name {
            continue;
        }
        let setter = format!("set_{}", o.name);
        if taken.contains(o.name)
            || taken.contains(setter.as_str())
            || o.name.strip_prefix("set_").is_some_and(|n| taken.contains(n))
        {
            continue;
        }
        let (std, set_std) = (format_ident!("{}", o.name), format_ident!("{setter}"));
        let (g, s) = (format_ident!("{}", e.field), format_ident!("set_{}", e.field));
        let ty = crate::entry::rust_type(e.ty);
        let get_doc = crate::lit::doc(&[format!(
            "`0x{:04X}` sub {} under the standard's name (the file's [`Self::{}`]).",
            o.index, o.sub, e.field
        )]);
        let set_doc = crate::lit::doc(&[format!(
            "Sets `0x{:04X}` sub {} under the standard's name (the file's [`Self::set_{}`]).",
            o.index, o.sub, e.field
        )]);
        items.push(quote! {
            #get_doc
            #[inline]
            pub fn #std(&self) -> #ty {
                self.#g()
            }
            #set_doc
            #[inline]
            pub fn #set_std(&mut self, v: #ty) -> Result<(), ::od_runtime::od::AbortCode> {
                self.#s(v)
            }
        });
    }
    if items.is_empty() {
        return proc_macro2::TokenStream::new();
    }
    quote! {
        /// The standard objects (CiA 301, CiA 402) the file names otherwise, under the
        /// standard's names.
        impl Dictionary {
            #(#items)*
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn si_codes_decode_to_units() {
        // mm: prefix -3 (0xFD), metre (0x01).
        assert_eq!(decode_si(Dimension::Position, 0xFD01_0000), Some((Unit::Millimeter, Ratio::ONE)));
        // µm: 1/1000 mm.
        assert_eq!(decode_si(Dimension::Position, 0xFA01_0000), Some((Unit::Millimeter, Ratio { num: 1, den: 1000 })));
        // rpm and 0.001 rpm (Nanotec's and Synapticon's 60A9h presets).
        assert_eq!(decode_si(Dimension::Velocity, 0x00B4_4700), Some((Unit::Rpm, Ratio::ONE)));
        assert_eq!(decode_si(Dimension::Velocity, 0xFDB4_4700), Some((Unit::Rpm, Ratio { num: 1, den: 1000 })));
        // rpm/s.
        assert_eq!(decode_si(Dimension::Acceleration, 0x00B4_4703), Some((Unit::RpmPerSecond, Ratio::ONE)));
        // Increments, degrees.
        assert_eq!(decode_si(Dimension::Position, 0x00B5_0000), Some((Unit::Increment, Ratio::ONE)));
        assert_eq!(decode_si(Dimension::Velocity, 0x0041_0300), Some((Unit::DegreePerSecond, Ratio::ONE)));
        // Radians: no such unit here.
        assert_eq!(decode_si(Dimension::Position, 0x0010_0000), None);
    }

    #[test]
    fn table_is_sorted_and_unique() {
        for w in OBJECTS.windows(2) {
            assert!((w[0].index, w[0].sub) < (w[1].index, w[1].sub), "{:?} before {:?}", w[0], w[1]);
        }
        let mut names: Vec<&str> = OBJECTS.iter().map(|o| o.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), OBJECTS.len());
    }
}
