//! Axis values in physical units (`90deg`, `12.5mm`, `60rpm`) through the device's sidecar:
//! its active unit system gives each dimension's unit and fixed-point scale, and the scaling
//! objects that change the physical value of a raw one (the feed converter) are read from the
//! device. The others (gear ratio, feed constant, encoder resolution) change only what the
//! drive does internally, not the bus value's unit.

use std::collections::BTreeMap;

use od_sidecar::{Dimension, ObjRef, ScalingKind, Sidecar};

/// `text` split into its number and unit (`None` for a plain number, taken as raw units).
pub fn split(text: &str) -> Option<(&str, &str)> {
    let t = text.trim();
    let at = t.find(|c: char| c.is_ascii_alphabetic())?;
    Some((t[..at].trim(), t[at..].trim()))
}

/// The objects whose values [`to_raw`] needs: the unit systems' conditions and the feed
/// converter's numerator and denominator.
pub fn objects(sidecar: &Sidecar) -> Vec<ObjRef> {
    let mut out: Vec<ObjRef> = sidecar.unit_systems.iter().flat_map(|u| u.when.iter().map(|c| c.object)).collect();
    if let Some(fc) = sidecar.scaling_object(ScalingKind::FeedConverter) {
        for sub in fc.subs.values() {
            out.push(ObjRef { index: fc.object.index, sub: Some(*sub) });
        }
    }
    out.sort();
    out.dedup();
    out
}

/// `number` `unit` of dimension `dim` as a raw bus value, given the device's current `values`
/// of [`objects`].
pub fn to_raw(
    number: &str,
    unit: &str,
    dim: Dimension,
    sidecar: &Sidecar,
    values: &BTreeMap<ObjRef, i64>,
) -> Result<i32, String> {
    let value: f64 = number.parse().map_err(|_| format!("`{number}` is not a number"))?;
    let system = sidecar
        .active_unit_system(|o| values.get(&o).copied())
        .ok_or_else(|| format!("the sidecar of {} gives no unit system", sidecar.device.name))?;
    let spec =
        system.units.get(&dim).ok_or_else(|| format!("the unit system `{}` gives no unit of {dim:?}", system.name))?;
    let symbol = spec.unit.symbol();
    if unit != symbol {
        return Err(format!(
            "the drive's {dim:?} values are in {symbol} (unit system `{}`), not {unit}; give {symbol} or raw units",
            system.name
        ));
    }
    // physical = raw × scale × (feed converter: denominator / numerator).
    let mut num = spec.scale.num as f64;
    let mut den = spec.scale.den as f64;
    if spec.scaled_by.contains(&ScalingKind::FeedConverter)
        && let Some(fc) = sidecar.scaling_object(ScalingKind::FeedConverter)
    {
        let read = |name: &str| {
            let sub = *fc.subs.get(name)?;
            values.get(&ObjRef { index: fc.object.index, sub: Some(sub) }).copied()
        };
        match (read("numerator"), read("denominator")) {
            (Some(n), Some(d)) if n > 0 && d > 0 => {
                num *= d as f64;
                den *= n as f64;
            }
            _ => return Err(format!("the feed converter {:04X}h could not be read", fc.object.index)),
        }
    }
    let raw = (value * den / num).round();
    if !(f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&raw) {
        return Err(format!("{value} {unit} is {raw} in raw units, outside INTEGER32"));
    }
    Ok(raw as i32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drvi() -> Sidecar {
        Sidecar::read(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.toml")))
            .unwrap()
    }

    fn values(actuator: i64, feed: (i64, i64)) -> BTreeMap<ObjRef, i64> {
        BTreeMap::from([
            (ObjRef { index: 0x2014, sub: None }, actuator),
            (ObjRef { index: 0x2001, sub: Some(1) }, feed.0),
            (ObjRef { index: 0x2001, sub: Some(2) }, feed.1),
        ])
    }

    #[test]
    fn the_active_system_and_the_feed_converter_give_the_raw_value() {
        let s = drvi();
        assert_eq!(split("90deg"), Some(("90", "deg")));
        assert_eq!(split("-1.5 mm"), Some(("-1.5", "mm")));
        assert_eq!(split("-1500"), None);
        assert!(objects(&s).contains(&ObjRef { index: 0x2014, sub: None }));
        // Only motor: hundredths of a degree, of an rpm.
        assert_eq!(to_raw("90", "deg", Dimension::Position, &s, &values(0, (1, 1))), Ok(9000));
        assert_eq!(to_raw("-60", "rpm", Dimension::Velocity, &s, &values(0, (1, 1))), Ok(-6000));
        // Actuator: hundredths of a mm.
        assert_eq!(to_raw("12.5", "mm", Dimension::Position, &s, &values(7, (1, 1))), Ok(1250));
        // A feed converter of 10/1: value_new = value_default × 10 / 1.
        assert_eq!(to_raw("12.5", "mm", Dimension::Position, &s, &values(7, (10, 1))), Ok(12500));
        assert_eq!(to_raw("12.5", "mm", Dimension::Position, &s, &values(7, (1, 10))), Ok(125));
        let wrong = to_raw("1", "mm", Dimension::Position, &s, &values(0, (1, 1))).unwrap_err();
        assert!(wrong.contains("in deg"), "{wrong}");
        assert!(to_raw("1e12", "deg", Dimension::Position, &s, &values(0, (1, 1))).is_err());
    }
}
