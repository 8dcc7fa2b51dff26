//! Unit conversions generated from the device sidecars: the manuals' examples, exactly.

use proptest::prelude::*;

#[cfg(feature = "drvi")]
mod drvi {
    use super::*;
    use generated::drvi::Dictionary;
    use generated::drvi::units::{Dimension, Quantity, Ratio, System, Unit, UnitError, Units};

    #[test]
    fn only_motor_36000_is_360_degrees() {
        let od = Dictionary::new(32);
        assert_eq!(System::active(&od), System::OnlyMotor); // 2014h = 0 by default
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_physical(Dimension::Position, 36000), Ok(Quantity::int(360, Unit::Degree)));
        assert_eq!(u.to_raw(Dimension::Position, Quantity::int(360, Unit::Degree)), Ok(36000));
        assert_eq!(u.to_physical(Dimension::Velocity, 150_000).unwrap(), Quantity::int(1500, Unit::Rpm));
        assert_eq!(u.unit(Dimension::Acceleration), Some(Unit::RpmPerSecond));
        assert_eq!(
            u.to_raw(Dimension::Position, Quantity::int(1, Unit::Millimeter)),
            Err(UnitError::WrongUnit { expected: Unit::Degree, got: Unit::Millimeter })
        );
    }

    #[test]
    fn actuator_type_switches_to_millimetres() {
        let mut od = Dictionary::new(32);
        od.set_actuator_type(7).unwrap();
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.system(), System::Actuator);
        assert_eq!(
            u.to_physical(Dimension::Position, 12_345).unwrap(),
            Quantity::new(Ratio::new(12_345, 100).unwrap(), Unit::Millimeter)
        );
    }

    #[test]
    fn feed_converter_inch_example() {
        // 2001h = 100/254 (the manual's inch example): value_new = value_0.01mm × 100/254.
        let mut od = Dictionary::new(32);
        od.set_actuator_type(7).unwrap();
        od.set_feed_converter_numerator(100).unwrap();
        od.set_feed_converter_denominator(254).unwrap();
        let u = Units::from_dictionary(&od).unwrap();
        // One inch (25.4 mm = 2540 × 0.01 mm) is 1000 new units: the new unit is 0.001 in.
        assert_eq!(
            u.to_raw(Dimension::Position, Quantity::new(Ratio::new(254, 10).unwrap(), Unit::Millimeter)),
            Ok(1000)
        );
        assert_eq!(u.factor(Dimension::Position), Ratio::new(254, 10_000));
        od.set_feed_converter_numerator(0).unwrap();
        assert_eq!(Units::from_dictionary(&od), Err(UnitError::ZeroFactor { index: 0x2001 }));
    }

    #[test]
    fn feed_constant_is_100_times_the_pitch() {
        let mut od = Dictionary::new(32);
        od.set_feed_constant_feed(500).unwrap(); // 5 mm pitch
        od.set_feed_constant_shaft_revolutions(1).unwrap();
        let pitch_mm = Units::feed_constant(&od).unwrap().checked_div(Ratio::int(100)).unwrap();
        assert_eq!(pitch_mm, Ratio::int(5));
        od.set_feed_constant_feed(250).unwrap();
        od.set_feed_constant_shaft_revolutions(2).unwrap();
        assert_eq!(Units::feed_constant(&od).unwrap().checked_div(Ratio::int(100)).unwrap(), Ratio::new(5, 4).unwrap());
    }

    #[test]
    fn gear_ratio_zero_terms_count_as_one() {
        let od = Dictionary::new(32);
        assert_eq!(od.gear_ratio_motor_revolutions(), 0); // the printed default 0/0
        assert_eq!(Units::gear_ratio(&od), Ok(Ratio::ONE));
    }

    #[test]
    fn typed_accessors_convert_and_check_ranges() {
        let mut od = Dictionary::new(32);
        let u = Units::from_dictionary(&od).unwrap();
        u.set_target_position(&mut od, Quantity::new(Ratio::new(721, 2).unwrap(), Unit::Degree)).unwrap();
        assert_eq!(od.target_position(), 36050); // 360.5 deg
        assert_eq!(u.target_position(&od).unwrap().to_f64(), 360.5);
        let huge = Quantity::int(1 << 40, Unit::Degree);
        assert_eq!(u.set_target_position(&mut od, huge), Err(UnitError::OutOfRange));
    }

    /// A DRVI actuator with 2014h = 7, 6092h = feed/1, 6091h = motor/shaft.
    fn actuator(feed: u32, gear: (u32, u32)) -> Dictionary {
        let mut od = Dictionary::new(32);
        od.set_actuator_type(7).unwrap();
        od.set_feed_constant_feed(feed).unwrap();
        od.set_gear_ratio_motor_revolutions(gear.0).unwrap();
        od.set_gear_ratio_shaft_revolutions(gear.1).unwrap();
        od
    }

    fn mm(n: i128, d: i128) -> Quantity {
        Quantity::new(Ratio::new(n, d).unwrap(), Unit::Millimeter)
    }

    /// Issue #28: one motor turn is 1.00 mm at 6092h = 100/1, 5.00 mm at 500/1, half that
    /// behind a 2:1 gear; a move to 10.00 mm is 10 motor turns at 100/1. Velocities (0.01 mm/s)
    /// and accelerations (whole mm/s², Table 6.2) count the same millimetres.
    #[test]
    fn one_motor_turn_is_the_screw_pitch_through_the_gear() {
        use Dimension::{Acceleration, Position, Velocity};
        for (feed, gear, hundredths) in
            [(100, (0, 0), 100), (100, (1, 1), 100), (500, (1, 1), 500), (100, (2, 1), 50), (500, (2, 1), 250)]
        {
            let u = Units::from_dictionary(&actuator(feed, gear)).unwrap();
            let turn = Ratio::int(1);
            assert_eq!(u.internal_to_physical(Position, turn), Ok(mm(hundredths, 100)), "{feed} {gear:?}");
            assert_eq!(u.internal_to_raw(Position, turn), Ok(hundredths as i64));
            assert_eq!(u.to_internal(Position, hundredths as i64), Ok(turn));
            let per_s = Quantity::new(Ratio::new(hundredths, 100).unwrap(), Unit::MillimeterPerSecond);
            assert_eq!(u.internal_to_physical(Velocity, turn), Ok(per_s), "a turn a second");
            let per_s2 = Quantity::new(Ratio::new(hundredths, 100).unwrap(), Unit::MillimeterPerSecond2);
            assert_eq!(u.internal_to_physical(Acceleration, turn), Ok(per_s2), "a turn a second squared");
        }
        let u = Units::from_dictionary(&actuator(100, (0, 0))).unwrap();
        let raw = u.to_raw(Position, mm(10, 1)).unwrap();
        assert_eq!((raw, u.to_internal(Position, raw)), (1000, Ok(Ratio::int(10))), "10.00 mm: 10 turns");
        // With 2001h = 100/254 (0.001 in): an inch is 25.4 motor turns of a 1 mm screw.
        let mut od = actuator(100, (1, 1));
        od.set_feed_converter_numerator(100).unwrap();
        od.set_feed_converter_denominator(254).unwrap();
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Position, 1000), Ok(Ratio::new(254, 10).unwrap()));
        // Only motor has no screw: no internal factor.
        let u = Units::from_dictionary(&Dictionary::new(32)).unwrap();
        assert_eq!(u.to_internal(Position, 36_000), Err(UnitError::NoUnit));
        // A 0 in 6092h divides by zero: an error, never a panic.
        let mut od = actuator(100, (1, 1));
        od.set_feed_constant_shaft_revolutions(0).unwrap();
        assert_eq!(Units::from_dictionary(&od), Err(UnitError::ZeroFactor { index: 0x6092 }));
    }

    proptest! {
        /// Over every 32-bit term: motor revolutions per bus unit are exactly
        /// `den2001 × motor × shaft6092 / (num2001 × shaft6091 × feed)` for positions and
        /// velocities (the feed counts 0.01 mm), 100 times that for accelerations (mm/s²), and `internal_to_raw` inverts
        /// `to_internal`.
        #[test]
        fn the_actuator_chain_is_exact_over_random_terms(
            fc in (1..=u32::MAX, 1..=u32::MAX), gear in (0..=u32::MAX, 0..=u32::MAX),
            feed in (1..=u32::MAX, 1..=u32::MAX), raw in any::<i32>(),
        ) {
            use Dimension::{Acceleration, Position, Velocity};
            let mut od = actuator(feed.0, gear);
            od.set_feed_constant_shaft_revolutions(feed.1).unwrap();
            od.set_feed_converter_numerator(fc.0).unwrap();
            od.set_feed_converter_denominator(fc.1).unwrap();
            let u = Units::from_dictionary(&od).unwrap();
            let one = |x: u32| i128::from(x.max(1));
            let g = Ratio::new(one(fc.1) * one(gear.0) * one(feed.1), one(fc.0) * one(gear.1) * one(feed.0)).unwrap();
            prop_assert_eq!(u.internal_factor(Position), Some(g));
            prop_assert_eq!(u.internal_factor(Velocity), Some(g));
            prop_assert_eq!(u.internal_factor(Acceleration), g.checked_mul(Ratio::int(100)));
            let revs = u.to_internal(Position, i64::from(raw)).unwrap();
            prop_assert_eq!(u.internal_to_raw(Position, revs), Ok(i64::from(raw)));
            let phys = u.to_physical(Position, i64::from(raw)).unwrap();
            prop_assert_eq!(u.internal_to_physical(Position, revs), Ok(phys));
        }
    }

    proptest! {
        #[test]
        fn physical_raw_physical_is_within_half_an_lsb(
            num in 1u32..=10_000, den in 1u32..=10_000, actuator: bool,
            p in -1_000_000_000i64..1_000_000_000, q in 1i64..1000,
        ) {
            let mut od = Dictionary::new(32);
            od.set_feed_converter_numerator(num).unwrap();
            od.set_feed_converter_denominator(den).unwrap();
            if actuator { od.set_actuator_type(7).unwrap(); }
            let u = Units::from_dictionary(&od).unwrap();
            let unit = u.unit(Dimension::Position).unwrap();
            let phys = Quantity::new(Ratio::new(i128::from(p), i128::from(q)).unwrap(), unit);
            let exact = u.to_raw_exact(Dimension::Position, phys).unwrap();
            let raw = u.to_raw(Dimension::Position, phys).unwrap();
            // |raw - exact| <= 1/2, i.e. |2 (raw * den - num)| <= den.
            let err2 = 2 * (i128::from(raw) * exact.den() - exact.num());
            prop_assert!(err2.abs() <= exact.den());
            // Back to physical: off by at most half a raw step (one LSB's worth, never more).
            let back = u.to_physical(Dimension::Position, raw).unwrap();
            let f = u.factor(Dimension::Position).unwrap();
            let diff = back.value.checked_div(f).unwrap();
            let d2 = 2 * (diff.num() * exact.den() - exact.num() * diff.den());
            prop_assert!(d2.abs() <= diff.den() * exact.den());
        }
    }
}

#[cfg(feature = "drcs")]
mod drcs {
    use generated::drcs::Dictionary;
    use generated::drcs::units::{Dimension, Quantity, Ratio, System, Unit, Units};

    #[test]
    fn only_motor_888_100_is_3196_8_microsteps_per_turn() {
        let mut od = Dictionary::new(3);
        od.set_feed_converter_numerator(888).unwrap();
        od.set_feed_converter_denominator(100).unwrap();
        // The only-motor system is chosen in the vendor tool, not on the bus.
        assert_eq!(System::active(&od), System::Actuator);
        let u = Units::with_system(System::OnlyMotor, &od).unwrap();
        let turn = Quantity::int(360, Unit::Degree);
        assert_eq!(u.to_raw_exact(Dimension::Position, turn), Ok(Ratio::new(15_984, 5).unwrap())); // 3196.8
        assert_eq!(u.to_raw(Dimension::Position, turn), Ok(3197));
        assert_eq!(u.to_physical(Dimension::Position, 888).unwrap(), Quantity::int(100, Unit::Degree));
    }

    /// 6092h (mm per pulley turn) and 6091h relate millimetres to motor turns (3.4.20,
    /// 3.4.21): 70 mm a turn with the default belt, 35 mm behind a 2:1 gear, in any 2001h unit.
    #[test]
    fn feed_constant_and_gear_ratio_give_motor_turns() {
        let mut od = Dictionary::new(3);
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Dimension::Position, 140), Ok(Ratio::int(2)));
        assert_eq!(u.internal_to_physical(Dimension::Position, Ratio::int(1)), Ok(Quantity::int(70, Unit::Millimeter)));
        od.set_gear_ratio_motor_revolutions(2).unwrap();
        od.set_feed_converter_numerator(1000).unwrap(); // micrometres
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Dimension::Position, 140_000), Ok(Ratio::int(4)));
        assert_eq!(u.internal_to_raw(Dimension::Position, Ratio::int(1)), Ok(35_000));
        assert_eq!(u.to_internal(Dimension::Velocity, 70_000), Ok(Ratio::int(2)), "turns per second");
        // Only motor (degrees) has no screw.
        let u = Units::with_system(System::OnlyMotor, &od).unwrap();
        assert_eq!(u.internal_factor(Dimension::Position), None);
    }

    #[test]
    fn inch_example_is_ten_times_off_as_the_sidecar_records() {
        let mut od = Dictionary::new(3);
        od.set_feed_converter_numerator(100).unwrap();
        od.set_feed_converter_denominator(254).unwrap();
        let u = Units::from_dictionary(&od).unwrap();
        // 25.4 mm (one inch) reads as 10 (not 1): value_new = value_mm × 100/254.
        let inch = Quantity::new(Ratio::new(254, 10).unwrap(), Unit::Millimeter);
        assert_eq!(u.to_raw(Dimension::Position, inch), Ok(10));
    }
}

#[cfg(feature = "akd")]
mod akd {
    use generated::akd::Dictionary;
    use generated::akd::units::{BusScaling, Dimension, Ratio, System, Units, bus_scaling, to_workbench};

    #[test]
    fn two_pow_20_increments_per_revolution_through_a_gear_ratio() {
        let mut od = Dictionary::new(1);
        assert_eq!(System::active(&od), System::WorkbenchUnits);
        od.set_fieldbus_configuration_bits(0x10).unwrap(); // FBUS.PARAM05 bit 4: DS402 factors
        assert_eq!(System::active(&od), System::Ds402Factors);
        od.set_position_encoder_resolution_increments(1 << 20).unwrap();
        od.set_position_encoder_resolution_motor_revolutions(1).unwrap();
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Dimension::Position, 1), Ok(Ratio::int(1 << 20)));
        od.set_gear_ratio_motor_shaft_revolutions(3).unwrap(); // 3 motor turns per output turn
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Dimension::Position, 1), Ok(Ratio::int(3 << 20)));
        od.set_feed_constant_feed(360).unwrap(); // user unit: degrees of the output shaft
        let u = Units::from_dictionary(&od).unwrap();
        assert_eq!(u.to_internal(Dimension::Position, 360), Ok(Ratio::int(3 << 20)));
        assert_eq!(u.to_internal(Dimension::Position, 1), Ok(Ratio::new(3 << 20, 360).unwrap()));
    }

    #[test]
    fn bus_scaling_1000_to_1() {
        assert_eq!(bus_scaling(0x3406, 1), Some(BusScaling::Factor(1000)));
        assert_eq!(bus_scaling(0x20A0, 0), Some(BusScaling::Variable));
        assert_eq!(bus_scaling(0x6040, 0), None);
        assert_eq!(to_workbench(0x3406, 1, 1500), Ratio::new(3, 2));
    }
}
