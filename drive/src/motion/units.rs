//! Raw device units and the saturating conversions between them and the model's `f64` state.

/// A positive rational scale factor `num / den`.
///
/// The model keeps every quantity in *position units* (the unit of 6064h on the bus), per second
/// and per second squared. Devices rarely express velocity and acceleration that way: the DRVI in
/// its "only motor" configuration counts positions in 0.01° but velocities in 0.01 rpm
/// (1 raw velocity unit = 6 position units/s) and accelerations in rpm/s (1 raw = 600 position
/// units/s²). A `Ratio` says how many position units (per second, per second squared) one raw
/// unit is.
///
/// A ratio with a zero or negative term is treated as 1/1 (see [`Ratio::factor`]); direction is
/// never expressed through a ratio (use [`crate::motion::AxisConfig::reverse_polarity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ratio {
    /// Numerator.
    pub num: i64,
    /// Denominator.
    pub den: i64,
}

impl Ratio {
    /// The identity scale.
    pub const ONE: Ratio = Ratio { num: 1, den: 1 };

    /// `num / den`.
    pub const fn new(num: i64, den: i64) -> Self {
        Ratio { num, den }
    }

    /// The factor as `f64`, clamped to `1e-12..=1e12`; 1.0 when a term is zero or negative.
    pub fn factor(self) -> f64 {
        if self.num <= 0 || self.den <= 0 {
            return 1.0;
        }
        (self.num as f64 / self.den as f64).clamp(1e-12, 1e12)
    }
}

impl Default for Ratio {
    fn default() -> Self {
        Ratio::ONE
    }
}

/// How the device's raw velocity and acceleration units relate to position units.
///
/// Torque is never scaled: the model takes and reports it in the device's raw torque unit (mA for
/// the Camozzi drives, per mille of rated torque for the AKD), and the plant constants in
/// [`crate::motion::PlantConfig`] are expressed in that unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Units {
    /// Position units per second in one raw velocity unit.
    pub velocity: Ratio,
    /// Position units per second squared in one raw acceleration unit.
    pub acceleration: Ratio,
}

impl Units {
    /// Raw velocity (device unit) to position units per second.
    pub(crate) fn velocity_in(&self, raw: f64) -> f64 {
        raw * self.velocity.factor()
    }

    /// Position units per second to raw velocity (device unit).
    pub(crate) fn velocity_out(&self, v: f64) -> f64 {
        v / self.velocity.factor()
    }

    /// Raw acceleration (device unit) to position units per second squared.
    pub(crate) fn acceleration_in(&self, raw: f64) -> f64 {
        raw * self.acceleration.factor()
    }
}

/// Largest magnitude of a position the model keeps (position units). Beyond it positions saturate:
/// `f64` still counts single units exactly there.
pub(crate) const POSITION_LIMIT: f64 = 4.0e15;
/// Largest magnitude of a velocity the model keeps (position units per second).
pub(crate) const VELOCITY_LIMIT: f64 = 1.0e15;
/// Largest magnitude of a torque the model keeps (raw torque units).
pub(crate) const TORQUE_LIMIT: f64 = 1.0e12;

/// Clamps `x` to `±limit`, mapping NaN to 0; sets `*saturated` when it had to change the value.
pub(crate) fn clamp_finite(x: f64, limit: f64, saturated: &mut bool) -> f64 {
    if x.is_nan() {
        *saturated = true;
        0.0
    } else if x > limit {
        *saturated = true;
        limit
    } else if x < -limit {
        *saturated = true;
        -limit
    } else {
        x
    }
}

/// Rounds to the nearest integer and saturates to `i32`; sets `*saturated` when out of range.
pub(crate) fn to_i32(x: f64, saturated: &mut bool) -> i32 {
    if x.is_nan() {
        *saturated = true;
        return 0;
    }
    let r = x.round();
    if r > i32::MAX as f64 {
        *saturated = true;
        i32::MAX
    } else if r < i32::MIN as f64 {
        *saturated = true;
        i32::MIN
    } else {
        r as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratio_factor_rejects_non_positive_terms() {
        assert_eq!(Ratio::new(6, 1).factor(), 6.0);
        assert_eq!(Ratio::new(0, 1).factor(), 1.0);
        assert_eq!(Ratio::new(1, 0).factor(), 1.0);
        assert_eq!(Ratio::new(-3, 1).factor(), 1.0);
        assert_eq!(Ratio::new(i64::MAX, 1).factor(), 1e12);
    }

    #[test]
    fn to_i32_saturates_and_reports() {
        let mut s = false;
        assert_eq!(to_i32(1.5, &mut s), 2);
        assert_eq!(to_i32(-1.5, &mut s), -2);
        assert!(!s);
        assert_eq!(to_i32(1e12, &mut s), i32::MAX);
        assert!(s);
        let mut s = false;
        assert_eq!(to_i32(f64::NAN, &mut s), 0);
        assert!(s);
    }
}
