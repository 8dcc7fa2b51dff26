//! The Camozzi DRVI integrated drive (manual "Series DRVI CANopen" V1.7).
//!
//! Built on the common layer ([`super::cia402`]); this file holds what the DRVI manual adds.

use od_runtime::od::ObjectDictionary;

use super::cia402::{BusScale, Cia402App, Vendor, read_int};
use super::error_table;
use crate::motion::{AxisConfig, HomingMethod, Ratio, RelativeBase, Units};
use crate::node::DeviceKind;

/// The DRVI's behaviour on top of the common CiA 402 drive.
#[derive(Clone, Debug, Default)]
pub struct Drvi {}

/// A DRVI application with the default mechanics.
pub fn app() -> Cia402App<generated::drvi::Dictionary, Drvi> {
    Cia402App::new(Drvi::default(), error_table(DeviceKind::Drvi))
}

impl<OD: ObjectDictionary> Vendor<OD> for Drvi {
    /// Table 6.17: 1, 3, 4, 6 and -1 (jog); 0 = no mode.
    fn supports_mode(&self, code: i8) -> bool {
        matches!(code, 0 | 1 | 3 | 4 | 6 | -1)
    }

    /// Table 6.29.
    fn homing_method(&self, code: i8) -> Option<HomingMethod> {
        HomingMethod::camozzi(code)
    }

    /// 2001h: new unit = default unit × numerator / denominator, for positions, velocities and
    /// accelerations alike.
    fn scale(&self, od: &OD) -> BusScale {
        let num = read_int(od, 0x2001, 1).filter(|v| *v > 0).unwrap_or(1);
        let den = read_int(od, 0x2001, 2).filter(|v| *v > 0).unwrap_or(1);
        let r = Ratio::new(den, num);
        BusScale { position: r, velocity: r, acceleration: r, torque: Ratio::ONE }
    }

    fn configure(&mut self, od: &OD, _scale: &BusScale, cfg: &mut AxisConfig) {
        let only_motor = read_int(od, 0x2014, 0).unwrap_or(0) == 0;
        cfg.units = if only_motor {
            // 0.01°, 0.01 rpm (= 0.06 °/s = 6 units/s), rpm/s (= 600 units/s²).
            Units { velocity: Ratio::new(6, 1), acceleration: Ratio::new(600, 1) }
        } else {
            // 0.01 mm, 0.01 mm/s (= 1 unit/s), mm/s² (= 100 units/s²).
            Units { velocity: Ratio::new(1, 1), acceleration: Ratio::new(100, 1) }
        };
        cfg.relative_base = RelativeBase::ActualPosition;
    }
}
