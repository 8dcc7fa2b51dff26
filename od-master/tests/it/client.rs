//! The generated clients (`include_eds!(…, client)`) of the three drives on the in-memory bus in
//! virtual time: typed reads and writes, the EDS limits refused before sending with the abort
//! code the drive itself gives, PDOs mapped, received and sent through the generated layouts,
//! units built from the scaling objects read over SDO, and the axis in user units.

use std::time::Duration;

use drive::node::DeviceKind;
use od_master::remote::{Quantity, Scaling};
use od_master::{AbortCode, Axis, Error, HomingMethod, Move, TransferError};
use od_runtime::master::SdoError;

use crate::harness::{net, pass};

od_macros::include_eds!("../devices/camozzi-drvi.eds", mod drvi, client);
od_macros::include_eds!("../devices/camozzi-drcs.eds", mod drcs, client);
od_macros::include_eds!("../devices/kollmorgen-akd.eds", mod akd, client);

fn refused(r: Result<(), Error>) -> Option<(u16, u8, AbortCode)> {
    match r {
        Err(Error::Refused { index, sub, code, .. }) => Some((index, sub, code)),
        _ => None,
    }
}

fn server_abort(r: Result<(), Error>) -> Option<AbortCode> {
    match r {
        Err(Error::Sdo { error: TransferError { error: SdoError::Server(code), .. }, .. }) => Some(code),
        _ => None,
    }
}

/// Typed reads give what raw SDO reads of the same objects give, strings as text; a typed write
/// is read back raw.
#[tokio::test(start_paused = true)]
async fn typed_reads_and_writes_on_each_drive() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let (a, b, c) = (n.bus.node(2).unwrap(), n.bus.node(3).unwrap(), n.bus.node(4).unwrap());
    let (drvi, drcs, akd) =
        (drvi::remote::Remote::new(a.clone()), drcs::remote::Remote::new(b), akd::remote::Remote::new(c));
    assert_eq!(drvi.statusword().read().await.unwrap(), a.read::<u16>(0x6041, 0).await.unwrap());
    assert_eq!(drvi.manufacturer_device_name().read().await.unwrap(), a.read_string(0x1008, 0).await.unwrap());
    assert!(!drvi.manufacturer_device_name().read().await.unwrap().is_empty());
    assert_eq!(drvi.identity_object_vendor_id().read().await.unwrap(), a.read::<u32>(0x1018, 1).await.unwrap());
    drvi.target_position().write(12_345).await.unwrap();
    assert_eq!(a.read::<i32>(0x607A, 0).await.unwrap(), 12_345);
    assert_eq!(drvi.target_position().read().await.unwrap(), 12_345);
    drcs.target_position().write(-250).await.unwrap();
    assert_eq!(drcs.target_position().read().await.unwrap(), -250);
    akd.target_position().write(777).await.unwrap();
    assert_eq!(akd.target_position().read().await.unwrap(), 777);
    assert_eq!(akd.statusword().read().await.unwrap(), n.bus.node(4).unwrap().read::<u16>(0x6041, 0).await.unwrap());
    // A string written (the AKD's ASCII channel, `wo`) and its answer read back as text.
    akd.ascii_channel_command().write("DRV.FAULTS\r").await.unwrap();
    let answer = akd.ascii_channel_response().read().await.unwrap();
    assert!(answer.starts_with('>'), "{answer:?}");
    // The handle names its object.
    assert_eq!((drvi.identity_object_vendor_id().index(), drvi.identity_object_vendor_id().sub()), (0x1018, 1));
}

/// Each limited entry: just past either limit, the client refuses the value without sending
/// anything (the entry keeps its value) with the abort code the drive answers the same value
/// sent raw with.
#[tokio::test(start_paused = true)]
async fn limits_are_refused_before_sending_with_the_drives_own_abort_code() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let (a, c) = (n.bus.node(2).unwrap(), n.bus.node(4).unwrap());
    let drvi = drvi::remote::Remote::new(a.clone());
    let akd = akd::remote::Remote::new(c.clone());

    // DRVI 2013h homing torque limit, 0..=100.
    let h = drvi.homing_torque_limit();
    assert_eq!(h.int_limits(), Some((0, 100)));
    let before = a.read::<u16>(0x2013, 0).await.unwrap();
    assert_eq!(refused(h.write(101).await), Some((0x2013, 0, AbortCode::VALUE_TOO_HIGH)));
    assert_eq!(a.read::<u16>(0x2013, 0).await.unwrap(), before);
    assert_eq!(server_abort(a.write(0x2013, 0, 101u16).await), Some(AbortCode::VALUE_TOO_HIGH));
    h.write(100).await.unwrap();
    assert_eq!(a.read::<u16>(0x2013, 0).await.unwrap(), 100);

    // AKD 60C0h interpolation sub mode select, -2..=0, both sides.
    let s = akd.interpolation_sub_mode_select();
    for (v, code) in [(1i16, AbortCode::VALUE_TOO_HIGH), (-3, AbortCode::VALUE_TOO_LOW)] {
        assert_eq!(refused(s.write(v).await), Some((0x60C0, 0, code)));
        assert_eq!(server_abort(c.write(0x60C0, 0, v).await), Some(code), "{v}");
    }
    s.write(-2).await.unwrap();
    assert_eq!(s.read().await.unwrap(), -2);
}

/// The check is the device's rule: for every entry of each drive's dictionary with limits, a
/// value past either end is refused by an `Object` carrying those limits with the code the
/// device-side check gives (the generated device code is the reference the drives run).
#[test]
fn the_limit_check_is_the_device_sides_for_every_limited_entry() {
    use od_runtime::od::EntryInfo;
    fn each(entries: &[EntryInfo]) -> usize {
        let mut checked = 0;
        for e in entries.iter().filter(|e| e.data_type.is_integer() && e.byte_len() <= 8) {
            let (Some(low), Some(high)) = (e.low(), e.high()) else { continue };
            for v in [low - 1, high + 1, low, high] {
                let len = e.byte_len();
                let bytes = v.to_le_bytes();
                // Values the type cannot hold are the length check's, not the limits'.
                let back = od_runtime::od::decode_int(&bytes[..len], e.data_type.is_signed());
                if back != v {
                    continue;
                }
                let device = e.check_value(&bytes[..len]).err();
                let client = od_master::remote::check_limits(v, low, high).err();
                assert_eq!(client, device, "{:04X}h sub {} value {v}", e.index, e.sub);
                checked += 1;
            }
        }
        checked
    }
    let checked = each(&drvi::ENTRIES) + each(&drcs::ENTRIES) + each(&akd::ENTRIES);
    assert!(checked > 20, "{checked}");
}

/// A TPDO arrives as the generated layout (its fields what SDO reads give); an RPDO built from
/// the generated layout moves the drive's controlword. Both mapped on the device with one call.
#[tokio::test(start_paused = true)]
async fn typed_pdos_are_received_and_sent() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let drvi = drvi::remote::Remote::new(n.bus.node(2).unwrap());
    drvi.tpdo1().configure().await.unwrap();
    drvi.rpdo1().configure().await.unwrap();
    assert_eq!(drvi.transmit_pdo_mapping_parameter_1_number_of_mapped_objects().read().await.unwrap(), 1);
    // Every SYNC.
    drvi.transmit_pdo_communication_parameter_1_transmission_type().write(1).await.unwrap();
    let mut tpdos = drvi.tpdo1().subscribe().await.unwrap();
    drvi.node().start().await.unwrap();
    n.bus.start_sync(Duration::from_millis(10), 0).await.unwrap();
    let t: drvi::pdo::Tpdo1 = tokio::time::timeout(Duration::from_millis(50), tpdos.next()).await.unwrap().unwrap();
    assert_eq!(t.statusword, drvi.statusword().read().await.unwrap());
    drvi.rpdo1().send(drvi::pdo::Rpdo1 { controlword: 0x0006 }).await.unwrap();
    pass(Duration::from_millis(20)).await;
    assert_eq!(drvi.controlword().read().await.unwrap(), 0x0006);

    // The AKD's TPDO 1 and RPDO 1 layouts, on the AKD.
    let akd = akd::remote::Remote::new(n.bus.node(4).unwrap());
    akd.tpdo1().configure().await.unwrap();
    akd.transmit_pdo_1_communication_parameter_transmission_type().write(1).await.unwrap();
    akd.node().start().await.unwrap();
    let t = tokio::time::timeout(Duration::from_millis(50), akd.tpdo1().next()).await.unwrap().unwrap();
    assert_eq!(t, akd::pdo::Tpdo1 { statusword: akd.statusword().read().await.unwrap() });
}

/// A mapping the device's rules refuse (an entry that is not mappable, over 64 bits) is refused
/// before anything is sent, with the device's abort code, and the PDO keeps its mapping.
#[tokio::test(start_paused = true)]
async fn a_bad_mapping_is_refused_before_sending() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    pass(Duration::from_millis(5)).await;
    let node = n.bus.node(2).unwrap();
    let before = node.read::<u32>(0x1A00, 1).await.unwrap();
    // 1000h (device type) is not mappable.
    let r = od_master::remote::map_pdo(
        &node,
        od_runtime::pdo::Direction::Transmit,
        1,
        0x182,
        &[0x1000_0020],
        drvi::Dictionary::check_tpdo_mapping,
    )
    .await;
    assert_eq!(refused(r), Some((0x1A00, 0, AbortCode::NOT_MAPPABLE)));
    // Three 32-bit entries: 96 bits.
    let r = od_master::remote::map_pdo(
        &node,
        od_runtime::pdo::Direction::Transmit,
        1,
        0x182,
        &[0x6064_0020, 0x6064_0020, 0x6064_0020],
        drvi::Dictionary::check_tpdo_mapping,
    )
    .await;
    assert_eq!(refused(r), Some((0x1A00, 0, AbortCode::PDO_LENGTH_EXCEEDED)));
    // A PDO number CiA 301 does not have.
    for number in [0, 513] {
        let r = od_master::remote::map_pdo(
            &node,
            od_runtime::pdo::Direction::Transmit,
            number,
            0x182,
            &[0x6041_0010],
            drvi::Dictionary::check_tpdo_mapping,
        )
        .await;
        assert_eq!(refused(r), Some((0x1A00, 0, AbortCode::NO_OBJECT)), "{number}");
    }
    assert_eq!(node.read::<u32>(0x1A00, 1).await.unwrap(), before);
    assert_eq!(node.read::<u32>(0x1800, 1).await.unwrap() & 0x8000_0000, 0, "TPDO 1 still valid");
}

/// Each drive's units from the scaling objects read over SDO: a position read in mm or degrees
/// (or the AKD's user units) is the raw 6064h times the factor of the scaling objects read
/// separately; a position written in units reaches 607Ah as the raw value.
#[tokio::test(start_paused = true)]
async fn units_from_the_drive_in_each_unit_system() {
    use od_runtime::__private_v3::Ratio;
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;
    let (a, b, c) = (n.bus.node(2).unwrap(), n.bus.node(3).unwrap(), n.bus.node(4).unwrap());

    // DRVI, 2014h = 0: only motor, 0.01° per unit, through 2001h.
    let drvi = drvi::remote::Remote::new(a.clone());
    drvi.actuator_type().write(0).await.unwrap();
    // A feed converter other than 1/1, so that the factor shows in every value.
    drvi.feed_converter_numerator().write(3).await.unwrap();
    drvi.feed_converter_denominator().write(2).await.unwrap();
    drvi.target_position().write(36_000).await.unwrap();
    let units = drvi.units().await.unwrap();
    assert_eq!(units.system(), drvi::units::System::OnlyMotor);
    let num = i128::from(a.read::<u32>(0x2001, 1).await.unwrap());
    let den = i128::from(a.read::<u32>(0x2001, 2).await.unwrap());
    let q = drvi.target_position().read_in(&units).await.unwrap();
    assert_eq!(q.unit(), od_master::remote::Unit::Degree);
    let raw = i128::from(a.read::<i32>(0x607A, 0).await.unwrap());
    assert_eq!(q.value().reduced(), Ratio::new(raw * den, 100 * num).unwrap().reduced());
    drvi.target_position().write_in(&units, Quantity::deg(90)).await.unwrap();
    assert_eq!(a.read::<i32>(0x607A, 0).await.unwrap() as i128, Ratio::new(90 * 100 * num, den).unwrap().round());
    // mm given to a drive set up in degrees: refused, naming both units.
    let e = drvi.target_position().write_in(&units, Quantity::mm(1)).await.unwrap_err();
    assert!(e.to_string().contains("deg") && e.to_string().contains("mm"), "{e}");

    // DRVI, 2014h = 7: custom actuator, 0.01 mm per unit.
    drvi.actuator_type().write(7).await.unwrap();
    let units = drvi.units().await.unwrap();
    assert_eq!(units.system(), drvi::units::System::Actuator);
    drvi.target_position().write_in(&units, Quantity::mm(12.5)).await.unwrap();
    assert_eq!(a.read::<i32>(0x607A, 0).await.unwrap() as i128, Ratio::new(1250 * num, den).unwrap().round());
    let back = drvi.target_position().read_in(&units).await.unwrap();
    assert_eq!((back.to_f64(), back.unit()), (12.5, od_master::remote::Unit::Millimeter));
    let p = drvi.position_actual_value().read_in(&units).await.unwrap();
    let raw = i128::from(a.read::<i32>(0x6064, 0).await.unwrap());
    assert_eq!(p.value().reduced(), Ratio::new(raw * den, 100 * num).unwrap().reduced());

    // DRCS: mm, through 2001h as well (mm = raw × denominator / numerator).
    let drcs = drcs::remote::Remote::new(b.clone());
    drcs.feed_converter_numerator().write(2).await.unwrap();
    drcs.feed_converter_denominator().write(5).await.unwrap();
    let units = drcs.units().await.unwrap();
    assert_eq!(units.system(), drcs::units::System::Actuator);
    drcs.target_position().write_in(&units, Quantity::mm(40)).await.unwrap();
    let (num, den) = (b.read::<u32>(0x2001, 1).await.unwrap(), b.read::<u32>(0x2001, 2).await.unwrap());
    assert_eq!((num, den), (2, 5));
    assert_eq!(b.read::<i32>(0x607A, 0).await.unwrap(), 16);
    let back = drcs.target_position().read_in(&units).await.unwrap();
    assert_eq!((back.to_f64(), back.unit()), (40.0, od_master::remote::Unit::Millimeter));
    let p = drcs.position_actual_value().read_in(&units).await.unwrap();
    let raw = i128::from(b.read::<i32>(0x6064, 0).await.unwrap());
    assert_eq!(p.value().reduced(), Ratio::new(raw * 5, 2).unwrap().reduced());

    // AKD: user units; 6092h feed per revolution is the user unit's scale.
    let akd = akd::remote::Remote::new(c.clone());
    akd.feed_constant_feed().write(10_000).await.unwrap();
    let units = akd.units().await.unwrap();
    let p = akd.position_actual_value().read_in(&units).await.unwrap();
    assert_eq!(p.unit(), od_master::remote::Unit::UserUnit);
    let raw = i64::from(c.read::<i32>(0x6064, 0).await.unwrap());
    assert_eq!(p.value().reduced(), Ratio::int(raw).reduced());
    // User units per motor revolution: 6092h feed / shaft revolutions, read separately.
    let (feed, shaft) = (c.read::<u32>(0x6092, 1).await.unwrap(), c.read::<u32>(0x6092, 2).await.unwrap());
    let turns = units.to_internal(akd::units::Dimension::Position, 25_000).unwrap().reduced();
    assert_eq!(turns, Ratio::new(25_000 * i128::from(shaft), i128::from(feed)).unwrap().reduced());
    assert_eq!(
        Scaling::to_physical(&units, od_master::remote::Dimension::Position, raw).unwrap().0.reduced(),
        p.value().reduced()
    );
    akd.target_position().write_in(&units, Quantity::user(2_500)).await.unwrap();
    assert_eq!(
        c.read::<i32>(0x607A, 0).await.unwrap(),
        akd.target_position().raw(&units, Quantity::user(2_500)).unwrap()
    );
}

/// Each drive homes and moves in its user units through the axis; the position it reports,
/// converted, is the target.
#[tokio::test(start_paused = true)]
async fn each_drive_homes_and_moves_in_user_units() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(5)).await;

    let drvi = drvi::remote::Remote::new(n.bus.node(2).unwrap());
    let units = drvi.units().await.unwrap();
    // As the README does: the profile velocity in units (60 rpm), the ramps as a move's raw
    // parameters (6000 rpm/s).
    drvi.profile_velocity().write_in(&units, Quantity::rpm(60)).await.unwrap();
    assert_eq!(drvi.profile_velocity().read().await.unwrap(), 6_000);
    let axis = Axis::new(drvi.node().clone()).with_units(units);
    axis.home(HomingMethod(37)).await.unwrap();
    let ramps = Move { acceleration: Some(6_000), deceleration: Some(6_000), ..Move::default() };
    let at = axis.move_to_with(Quantity::deg(720), &ramps).await.unwrap();
    assert_eq!((at.to_f64(), at.unit()), (720.0, od_master::remote::Unit::Degree));
    let raw = drvi.position_actual_value().read().await.unwrap();
    // With the ramps on the drive, the drive's own parameters do: back to 90 degrees.
    let back = axis.move_to(Quantity::deg(90)).await.unwrap();
    assert_eq!(back.to_f64(), 90.0);
    assert_eq!(
        axis.units().to_raw(od_master::remote::Dimension::Position, at.value(), at.unit()).unwrap(),
        i64::from(raw)
    );

    let drcs = drcs::remote::Remote::new(n.bus.node(3).unwrap());
    let units = drcs.units().await.unwrap();
    let axis = Axis::new(drcs.node().clone()).with_units(units);
    axis.home(HomingMethod(37)).await.unwrap();
    let m = Move { velocity: Some(50), acceleration: Some(50), deceleration: Some(50), ..Move::default() };
    let at = axis.move_to_with(Quantity::mm(250), &m).await.unwrap();
    assert_eq!((at.to_f64(), at.unit()), (250.0, od_master::remote::Unit::Millimeter));

    let akd = akd::remote::Remote::new(n.bus.node(4).unwrap());
    akd.feed_constant_feed().write(10_000).await.unwrap();
    let axis = Axis::new(akd.node().clone()).with_units(akd.units().await.unwrap());
    axis.home(HomingMethod(35)).await.unwrap();
    let m = Move { velocity: Some(10_000), ..Move::default() };
    let at = axis.move_to_with(Quantity::user(5_000), &m).await.unwrap();
    assert_eq!((at.to_f64(), at.unit()), (5_000.0, od_master::remote::Unit::UserUnit));
    assert_eq!(akd.position_actual_value().read().await.unwrap(), 5_000);
}
