#![doc = include_str!("../README.md")]
//! # The schema
//!
//! The schema is an input of the code generator (`od-codegen` re-exports it as
//! `od_codegen::sidecar`), kept in a crate of its own so that a user of the generator does not
//! depend on the crate holding the project's bundled devices (`devices` re-exports it too).
//!
//! Each device file `devices/<name>.eds` has a sidecar `devices/<name>.toml` beside it. The EDS
//! says what objects exist and how they are typed; the sidecar says what the numbers *mean*:
//! physical dimensions and units, which objects rescale them and by which formula, the modes and
//! homing methods the drive supports, its error and warning tables, what "save" stores, when
//! a master may remap its PDOs, and every decision taken while transcribing the manual. The code generator (unit scaling) and
//! the simulated drives (behaviour) read it; nothing is guessed from object names.
//!
//! All tables reject unknown keys, so a misspelt key is an error with a line and column.
//!
//! # Schema, by example
//!
//! ```toml
//! [device]
//! name = "camozzi-drvi"              # file stem of the EDS
//! eds = "camozzi-drvi.eds"           # EDS file beside this sidecar
//! manual = "camozzi-drvi-canopen-manual.txt"
//! vendor = "Camozzi"
//!
//! # Physical dimension of every motion-related entry ("0xIIII" = sub 0 / whole object,
//! # "0xIIIIsubS" = one sub-index, sub in decimal or 0x-hex).
//! [dimensions]
//! "0x607A" = "position"
//! "0x6081" = "velocity"
//! "0x6083" = "acceleration"
//! "0x6071" = "torque"
//! "0x2012sub1" = "torque_slope"
//!
//! # One table per unit configuration. `when` says which configuration is active: all of its
//! # conditions hold (object value equals). A system without `when` is the default.
//! [[unit_system]]
//! name = "only-motor"
//! description = "Motor without actuator (Table 6.2)"
//! when = [{ object = "0x2014", equals = 0 }]
//! [unit_system.units]
//! position = { unit = "deg", scale = "1/100" }     # physical = raw * scale
//! velocity = { unit = "rpm", scale = "1/100" }
//! acceleration = { unit = "rpm/s" }                # scale defaults to 1
//! torque = { unit = "mA" }
//! torque_slope = { unit = "mA/s" }
//!
//! # A system chosen outside the bus is selected by name only.
//! [[unit_system]]
//! name = "only-motor-qset"
//! external = "chosen in the QSet configurator"
//! [unit_system.units]
//! position = { unit = "deg" }
//!
//! # Units of single entries outside the unit systems.
//! [object_units]
//! "0x2100" = { unit = "s" }
//!
//! # Objects that rescale values, and the formula each enters.
//! [[scaling]]
//! object = "0x2001"
//! kind = "feed_converter"
//! subs = { numerator = 1, denominator = 2 }
//! formula = "unit_new = unit_default * numerator / denominator"
//! applies_to = ["position", "velocity", "acceleration"]
//!
//! # Per-object bus scaling (AKD appendix "Scalatura"): bus value = WorkBench value * factor.
//! [bus_scaling]
//! "0x6081" = "1000:1"
//! "0x60F4" = "var"
//!
//! [[mode]]
//! code = 1
//! name = "profile position"
//!
//! # A mode the drive runs though its 6502h (supported drive modes) leaves it out: a master
//! # checking modes against 6502h takes it as supported. Say where the manual says so.
//! [[mode]]
//! code = 8
//! name = "cyclic synchronous position"
//! note = "6060h lists 8 (6.4.2.3); 6502h = 65h does not"
//! not_in_6502h = true
//!
//! [[homing_method]]
//! code = 17
//! description = "negative limit switch"
//!
//! [[error]]
//! code = "0x8611"
//! manufacturer = "0x01"              # optional manufacturer byte/word of the EMCY
//! register = "0x01"                  # optional 1001h bits set with it
//! text = "Following error"
//! reaction = "quick_stop"            # quick_stop | power_off | warning | none
//! source = "Table 6.34"
//!
//! [[warning]]
//! object = "0x2006"
//! bit = 0
//! text = "Under voltage"
//! auto_reset = true
//! reset = "clears when the supply is back in range"
//!
//! # A warning bit that says the drive is at a position limit: `limit = "positive"` or
//! # `"negative"` (a master finding statusword bit 11 set reads it to know which way is blocked).
//! [[warning]]
//! object = "0x2006"
//! bit = 6
//! text = "Positive position limit reached"
//! auto_reset = false
//! limit = "positive"
//!
//! [store]
//! objects = ["0x6081", "0x6083", "0x2001sub1"]
//!
//! # When a master may change a PDO's mapping and CAN-ID: "cia301" (the default: only while
//! # the PDO is invalid, COB-ID bit 31) or "while-valid" (sub-index 0 = 0 deactivates the PDO,
//! # the entries are written, sub-index 0 = n activates it; the CAN-ID of a valid PDO may
//! # change). The generated dictionary carries it (`ObjectDictionary::PDO_REMAPPING`).
//! [pdo]
//! remapping = "cia301"
//! source = "6.3.2.20"
//!
//! [[decision]]
//! object = "0x2001"
//! source = "Table 6.19"
//! text = "Table is column-shifted; rebuilt from 6.3.6.1"
//! ```
#![deny(missing_docs)]

pub mod supervision;

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::de::{self, Deserializer};
use serde::{Deserialize, Serialize, Serializer};

/// A whole sidecar file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sidecar {
    /// Identification.
    pub device: DeviceMeta,
    /// Physical dimension of each motion-related entry.
    #[serde(default)]
    pub dimensions: BTreeMap<ObjRef, Dimension>,
    /// Unit configurations (at least one).
    #[serde(default, rename = "unit_system")]
    pub unit_systems: Vec<UnitSystem>,
    /// Objects that rescale values.
    #[serde(default)]
    pub scaling: Vec<ScalingObject>,
    /// Units of single entries that are not motion quantities of a unit system (counters in
    /// seconds, inhibit times in 100 us, ...).
    #[serde(default)]
    pub object_units: BTreeMap<ObjRef, UnitSpec>,
    /// Per-object bus scaling factor (AKD).
    #[serde(default)]
    pub bus_scaling: BTreeMap<ObjRef, BusScaling>,
    /// Supported modes of operation (6060h values).
    #[serde(default, rename = "mode")]
    pub modes: Vec<Mode>,
    /// Supported homing methods (6098h values).
    #[serde(default, rename = "homing_method")]
    pub homing_methods: Vec<HomingMethod>,
    /// Error codes (EMCY / 603Fh / 1003h).
    #[serde(default, rename = "error")]
    pub errors: Vec<ErrorCode>,
    /// Warning bits (DRVI 2006h).
    #[serde(default, rename = "warning")]
    pub warnings: Vec<WarningBit>,
    /// What 1010h "save" stores.
    #[serde(default)]
    pub store: Store,
    /// How the device lets a master reconfigure its PDOs.
    #[serde(default)]
    pub pdo: Pdo,
    /// Transcription decisions, one per line of reasoning.
    #[serde(default, rename = "decision")]
    pub decisions: Vec<Decision>,
}

/// `[device]`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceMeta {
    /// File stem of the EDS (`camozzi-drvi`).
    pub name: String,
    /// The EDS file name, relative to the sidecar.
    pub eds: String,
    /// The manual the file was transcribed from.
    #[serde(default)]
    pub manual: Option<String>,
    /// Vendor name.
    #[serde(default)]
    pub vendor: Option<String>,
}

/// An `(index, sub-index)` reference written `"0x607A"` (sub 0 or the whole object) or
/// `"0x2001sub1"` (`sub` in decimal, or hex with `0x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ObjRef {
    /// Object index.
    pub index: u16,
    /// Sub-index (`None`: sub 0 of a VAR, or the whole object).
    pub sub: Option<u8>,
}

impl ObjRef {
    /// The sub-index this reference reads (0 when none was given).
    pub fn sub_or_zero(self) -> u8 {
        self.sub.unwrap_or(0)
    }
}

impl fmt::Display for ObjRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.sub {
            None => write!(f, "0x{:04X}", self.index),
            Some(s) => write!(f, "0x{:04X}sub{}", self.index, s),
        }
    }
}

impl FromStr for ObjRef {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("`{s}` is not an object reference; write \"0x607A\" or \"0x2001sub1\"");
        let t = s.trim();
        let lower = t.to_ascii_lowercase();
        let (idx, sub) = match lower.split_once("sub") {
            Some((i, s)) => (i, Some(s)),
            None => (lower.as_str(), None),
        };
        let idx = idx.strip_prefix("0x").ok_or_else(bad)?;
        if idx.is_empty() || idx.len() > 4 {
            return Err(bad());
        }
        let index = u16::from_str_radix(idx, 16).map_err(|_| bad())?;
        let sub = match sub {
            None => None,
            Some(s) => Some(match s.strip_prefix("0x") {
                Some(h) => u8::from_str_radix(h, 16).map_err(|_| bad())?,
                None => s.parse::<u8>().map_err(|_| bad())?,
            }),
        };
        Ok(ObjRef { index, sub })
    }
}

impl Serialize for ObjRef {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for ObjRef {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(de::Error::custom)
    }
}

/// A physical dimension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Dimension {
    /// Position or distance.
    Position,
    /// Velocity.
    Velocity,
    /// Acceleration or deceleration.
    Acceleration,
    /// Jerk.
    Jerk,
    /// Torque (or force).
    Torque,
    /// Current.
    Current,
    /// Rate of change of torque or current.
    TorqueSlope,
    /// Time.
    Time,
}

/// A physical unit. Spelled in files as the symbol in each variant's doc.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Unit {
    /// `deg`: angular degrees.
    #[serde(rename = "deg")]
    Degree,
    /// `rev`: revolutions.
    #[serde(rename = "rev")]
    Revolution,
    /// `mm`: millimetres.
    #[serde(rename = "mm")]
    Millimeter,
    /// `in`: inches.
    #[serde(rename = "in")]
    Inch,
    /// `inc`: encoder increments.
    #[serde(rename = "inc")]
    Increment,
    /// `ustep`: motor micro-steps.
    #[serde(rename = "ustep")]
    Microstep,
    /// `user`: the drive's user-defined position unit (CiA 402 factor group).
    #[serde(rename = "user")]
    UserUnit,
    /// `rpm`: revolutions per minute.
    #[serde(rename = "rpm")]
    Rpm,
    /// `deg/s`
    #[serde(rename = "deg/s")]
    DegreePerSecond,
    /// `mm/s`
    #[serde(rename = "mm/s")]
    MillimeterPerSecond,
    /// `in/s`
    #[serde(rename = "in/s")]
    InchPerSecond,
    /// `inc/s`
    #[serde(rename = "inc/s")]
    IncrementPerSecond,
    /// `ustep/s`
    #[serde(rename = "ustep/s")]
    MicrostepPerSecond,
    /// `user/s`
    #[serde(rename = "user/s")]
    UserUnitPerSecond,
    /// `rpm/s`
    #[serde(rename = "rpm/s")]
    RpmPerSecond,
    /// `deg/s^2`
    #[serde(rename = "deg/s^2")]
    DegreePerSecond2,
    /// `mm/s^2`
    #[serde(rename = "mm/s^2")]
    MillimeterPerSecond2,
    /// `in/s^2`
    #[serde(rename = "in/s^2")]
    InchPerSecond2,
    /// `inc/s^2`
    #[serde(rename = "inc/s^2")]
    IncrementPerSecond2,
    /// `ustep/s^2`
    #[serde(rename = "ustep/s^2")]
    MicrostepPerSecond2,
    /// `user/s^2`
    #[serde(rename = "user/s^2")]
    UserUnitPerSecond2,
    /// `mA`
    #[serde(rename = "mA")]
    MilliAmpere,
    /// `A`
    #[serde(rename = "A")]
    Ampere,
    /// `mA/s`
    #[serde(rename = "mA/s")]
    MilliAmperePerSecond,
    /// `permille_rated_torque`: thousandths of the motor's rated torque (CiA 402).
    #[serde(rename = "permille_rated_torque")]
    PermilleRatedTorque,
    /// `permille_rated_current`
    #[serde(rename = "permille_rated_current")]
    PermilleRatedCurrent,
    /// `permille_rated_torque/s`
    #[serde(rename = "permille_rated_torque/s")]
    PermilleRatedTorquePerSecond,
    /// `Nm`
    #[serde(rename = "Nm")]
    NewtonMeter,
    /// `s`
    #[serde(rename = "s")]
    Second,
    /// `ms`
    #[serde(rename = "ms")]
    Millisecond,
    /// `us`
    #[serde(rename = "us")]
    Microsecond,
    /// `ns`
    #[serde(rename = "ns")]
    Nanosecond,
    /// `100us`: multiples of 100 microseconds (CiA 301 inhibit times).
    #[serde(rename = "100us")]
    HundredMicroseconds,
}

impl Unit {
    /// The symbol a sidecar writes for the unit (`deg`, `mm/s`, `user/s^2`, ...), as its
    /// `serde` name.
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Degree => "deg",
            Unit::Revolution => "rev",
            Unit::Millimeter => "mm",
            Unit::Inch => "in",
            Unit::Increment => "inc",
            Unit::Microstep => "ustep",
            Unit::UserUnit => "user",
            Unit::Rpm => "rpm",
            Unit::DegreePerSecond => "deg/s",
            Unit::MillimeterPerSecond => "mm/s",
            Unit::InchPerSecond => "in/s",
            Unit::IncrementPerSecond => "inc/s",
            Unit::MicrostepPerSecond => "ustep/s",
            Unit::UserUnitPerSecond => "user/s",
            Unit::RpmPerSecond => "rpm/s",
            Unit::DegreePerSecond2 => "deg/s^2",
            Unit::MillimeterPerSecond2 => "mm/s^2",
            Unit::InchPerSecond2 => "in/s^2",
            Unit::IncrementPerSecond2 => "inc/s^2",
            Unit::MicrostepPerSecond2 => "ustep/s^2",
            Unit::UserUnitPerSecond2 => "user/s^2",
            Unit::MilliAmpere => "mA",
            Unit::Ampere => "A",
            Unit::MilliAmperePerSecond => "mA/s",
            Unit::PermilleRatedTorque => "permille_rated_torque",
            Unit::PermilleRatedCurrent => "permille_rated_current",
            Unit::PermilleRatedTorquePerSecond => "permille_rated_torque/s",
            Unit::NewtonMeter => "Nm",
            Unit::Second => "s",
            Unit::Millisecond => "ms",
            Unit::Microsecond => "us",
            Unit::Nanosecond => "ns",
            Unit::HundredMicroseconds => "100us",
        }
    }
}

/// An exact positive ratio `num/den`, written `"1/100"`, `"1000"` or `"1"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ratio {
    /// Numerator.
    pub num: u64,
    /// Denominator (never 0).
    pub den: u64,
}

impl Ratio {
    /// 1/1.
    pub const ONE: Ratio = Ratio { num: 1, den: 1 };
}

impl Default for Ratio {
    fn default() -> Self {
        Ratio::ONE
    }
}

impl fmt::Display for Ratio {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.den == 1 { write!(f, "{}", self.num) } else { write!(f, "{}/{}", self.num, self.den) }
    }
}

impl FromStr for Ratio {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("`{s}` is not a ratio; write \"1/100\" or \"1000\"");
        let (n, d) = match s.split_once('/') {
            Some((n, d)) => (n.trim(), d.trim()),
            None => (s.trim(), "1"),
        };
        let num: u64 = n.parse().map_err(|_| bad())?;
        let den: u64 = d.parse().map_err(|_| bad())?;
        if num == 0 || den == 0 {
            return Err(format!("`{s}`: a scale must be positive (neither part 0)"));
        }
        Ok(Ratio { num, den })
    }
}

impl Serialize for Ratio {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for Ratio {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(de::Error::custom)
    }
}

/// An integer written as a TOML integer or as a `"0x…"` string.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Num(pub i64);

impl Serialize for Num {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if self.0 >= 0 { s.collect_str(&format_args!("0x{:X}", self.0)) } else { s.serialize_i64(self.0) }
    }
}

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            I(i64),
            S(String),
        }
        match Raw::deserialize(d)? {
            Raw::I(i) => Ok(Num(i)),
            Raw::S(s) => {
                let t = s.trim();
                let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
                    Some(h) => i64::from_str_radix(h, 16),
                    None => t.parse(),
                };
                parsed.map(Num).map_err(|_| de::Error::custom(format!("`{s}` is not a number (write 17 or \"0x11\")")))
            }
        }
    }
}

/// One unit configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitSystem {
    /// Short name (`only-motor`, `actuator`).
    pub name: String,
    /// What it is, with the manual's reference.
    #[serde(default)]
    pub description: Option<String>,
    /// When it is active: every condition holds. Empty (and no `external`): the default system.
    #[serde(default)]
    pub when: Vec<Condition>,
    /// Set when the system is chosen outside the bus (e.g. in a vendor configurator), saying
    /// where; such a system is active only when selected by name
    /// ([`Sidecar::unit_system_named`]).
    #[serde(default)]
    pub external: Option<String>,
    /// The unit of each dimension.
    pub units: BTreeMap<Dimension, UnitSpec>,
}

/// `object & mask == equals` (without `mask`: `object == equals`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Condition {
    /// The configuration object.
    pub object: ObjRef,
    /// Bits to compare (all bits when absent), for flags such as AKD FBUS.PARAM05 bit 4.
    #[serde(default)]
    pub mask: Option<Num>,
    /// The value the (masked) object must hold.
    pub equals: Num,
}

impl Condition {
    /// Whether an object value satisfies the condition.
    pub fn holds(&self, value: i64) -> bool {
        match self.mask {
            Some(Num(m)) => value & m == self.equals.0,
            None => value == self.equals.0,
        }
    }
}

/// How a raw bus value of one dimension becomes a physical quantity:
/// `physical = raw * scale`, in `unit`, before any [`ScalingObject`] listed in `scaled_by`
/// is applied (in order).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitSpec {
    /// The unit of `raw * scale`.
    pub unit: Unit,
    /// Fixed-point factor (`"1/100"` for values in hundredths).
    #[serde(default)]
    pub scale: Ratio,
    /// Scaling objects (by kind) that further change the unit at run time.
    #[serde(default)]
    pub scaled_by: Vec<ScalingKind>,
}

/// What a scaling object does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScalingKind {
    /// Camozzi 2001h: `unit_new = unit_default * numerator / denominator`.
    FeedConverter,
    /// CiA 402 6091h: motor revolutions / shaft revolutions.
    GearRatio,
    /// CiA 402 6092h: feed per driving-shaft revolution.
    FeedConstant,
    /// CiA 402 608Fh: encoder increments / motor revolutions.
    EncoderResolution,
    /// AKD 204Ch: velocity (pv) scaling factor.
    VelocityFactor,
    /// DRVI 2014h: selects the unit system (only motor / actuator).
    ActuatorType,
}

/// An object that rescales values, and the formula it enters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScalingObject {
    /// The object.
    pub object: ObjRef,
    /// What it does.
    pub kind: ScalingKind,
    /// Named sub-indices (`numerator = 1`, `denominator = 2`, `motor_revolutions = 1`, ...).
    #[serde(default)]
    pub subs: BTreeMap<String, u8>,
    /// The formula, in words and symbols, as the generator implements it.
    pub formula: String,
    /// The dimensions it affects.
    #[serde(default)]
    pub applies_to: Vec<Dimension>,
    /// `feed_constant` only: the unit the feed (sub `feed`) counts in, when it is not one unit
    /// of the unit system's position dimension (the DRVI's 6092h counts in 0.01 mm:
    /// `{ unit = "mm", scale = "1/100" }`). A dimension's motor revolutions are then
    /// `physical / (feed × scale) × shaft revolutions`, with `unit` the length of the
    /// dimension's unit (mm for mm, mm/s and mm/s^2).
    #[serde(default)]
    pub feed_unit: Option<FeedUnit>,
    /// Manual reference and remarks.
    #[serde(default)]
    pub note: Option<String>,
}

/// The unit a feed constant counts in: `scale` of `unit` (see [`ScalingObject::feed_unit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeedUnit {
    /// A length (or angle) unit: `mm`, `in`, `deg`, `user`, ...
    pub unit: Unit,
    /// How many of `unit` one count of the feed is (`"1/100"`: hundredths).
    #[serde(default)]
    pub scale: Ratio,
}

/// AKD per-object bus scaling: bus value = WorkBench value × factor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BusScaling {
    /// A fixed factor (`"1:1"`, `"1000:1"`).
    Factor(u32),
    /// `"var"`: depends on the unit configuration.
    Variable,
}

impl Serialize for BusScaling {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            BusScaling::Factor(f) => s.collect_str(&format_args!("{f}:1")),
            BusScaling::Variable => s.serialize_str("var"),
        }
    }
}

impl<'de> Deserialize<'de> for BusScaling {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        let t = s.trim();
        if t.eq_ignore_ascii_case("var") {
            return Ok(BusScaling::Variable);
        }
        let factor = t.strip_suffix(":1").and_then(|f| f.trim().parse::<u32>().ok()).filter(|&f| f > 0);
        factor
            .map(BusScaling::Factor)
            .ok_or_else(|| de::Error::custom(format!("`{s}`: write \"1:1\", \"1000:1\" or \"var\"")))
    }
}

/// A mode of operation.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mode {
    /// 6060h value.
    pub code: i8,
    /// Name (`profile position`).
    pub name: String,
    /// Objects the mode uses, with remarks.
    #[serde(default)]
    pub note: Option<String>,
    /// The drive runs the mode though its supported drive modes (6502h) leave it out (the
    /// AKD's 6502h = 65h lacks profile torque and cyclic synchronous position). A master that
    /// checks a mode against 6502h before selecting it (`od_master::Axis::with_sidecar`)
    /// takes the mode as supported. Cite the manual's page in `note`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub not_in_6502h: bool,
}

/// A homing method.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomingMethod {
    /// 6098h value.
    pub code: i8,
    /// What it does.
    pub description: String,
}

/// What the drive does on an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reaction {
    /// Soft error: quick stop, power stage stays on until stopped.
    QuickStop,
    /// Hard error: power stage off, the axis coasts.
    PowerOff,
    /// A warning only.
    Warning,
    /// Reported, no reaction.
    None,
}

/// One error code.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorCode {
    /// CiA 301/402 error code (EMCY bytes 0-1, 603Fh, 1003h low word).
    pub code: Num,
    /// Manufacturer-specific byte(s) in the EMCY.
    #[serde(default)]
    pub manufacturer: Option<Num>,
    /// The vendor's own fault or warning number (AKD `F523`, `n414`).
    #[serde(default)]
    pub vendor_code: Option<String>,
    /// Bits set in 1001h.
    #[serde(default)]
    pub register: Option<Num>,
    /// The manual's text.
    pub text: String,
    /// What the drive does.
    pub reaction: Reaction,
    /// How it is cleared, where the manual says.
    #[serde(default)]
    pub reset: Option<String>,
    /// Manual reference.
    #[serde(default)]
    pub source: Option<String>,
}

/// One warning bit.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WarningBit {
    /// The object holding the bit.
    pub object: ObjRef,
    /// Bit number.
    pub bit: u8,
    /// The manual's text.
    pub text: String,
    /// Whether it resets by itself.
    pub auto_reset: bool,
    /// The reset rule in words.
    #[serde(default)]
    pub reset: Option<String>,
    /// The bit says the drive is at its positive or negative position limit (the DRVI's 2006h
    /// bits 6 and 7): a master that finds the drive limited (statusword bit 11) reads it to
    /// know which way a move may still go.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limit: Option<LimitSide>,
}

/// Which position limit (`"positive"` or `"negative"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitSide {
    /// The positive limit: moves in the positive direction go further into it.
    Positive,
    /// The negative limit.
    Negative,
}

/// `[store]`: what 1010h "save" stores.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Store {
    /// Stored objects (a reference without sub stores every sub-index).
    #[serde(default)]
    pub objects: Vec<ObjRef>,
    /// Manual reference and remarks.
    #[serde(default)]
    pub note: Option<String>,
}

/// `[pdo]`: how the device lets a master reconfigure its PDOs.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pdo {
    /// When a PDO's mapping and CAN-ID may be written (`od_runtime::pdo::Remapping`).
    #[serde(default)]
    pub remapping: Remapping,
    /// Manual reference.
    #[serde(default)]
    pub source: Option<String>,
}

/// `[pdo] remapping`: when a master may change a PDO's mapping and CAN-ID.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Remapping {
    /// `"cia301"`: only while the PDO is invalid (COB-ID bit 31 set), as CiA 301 says.
    #[default]
    #[serde(rename = "cia301")]
    Cia301,
    /// `"while-valid"`: the PDO may stay valid; sub-index 0 = 0 deactivates it, the entries
    /// may then be written, sub-index 0 = n activates it again, and a valid PDO's CAN-ID may
    /// change (the Kollmorgen AKD).
    #[serde(rename = "while-valid")]
    WhileValid,
}

/// One transcription decision.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Decision {
    /// The object concerned, if one.
    #[serde(default)]
    pub object: Option<ObjRef>,
    /// Manual reference (table, section).
    #[serde(default)]
    pub source: Option<String>,
    /// What was decided and why.
    pub text: String,
}

/// A sidecar that could not be read, with its location.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{col}: {message}")]
pub struct SidecarError {
    /// File name.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub col: usize,
    /// What is wrong.
    pub message: String,
}

impl Sidecar {
    /// Parses sidecar text; `file` names it in errors.
    pub fn parse(file: &str, text: &str) -> Result<Sidecar, SidecarError> {
        let sidecar: Sidecar = toml::from_str(text).map_err(|e| {
            let (line, col) = e.span().map(|s| line_col(text, s.start)).unwrap_or((1, 1));
            SidecarError { file: file.to_owned(), line, col, message: e.message().to_owned() }
        })?;
        sidecar.check_self().map_err(|message| SidecarError { file: file.to_owned(), line: 1, col: 1, message })?;
        Ok(sidecar)
    }

    /// Reads a sidecar file.
    pub fn read(path: &Path) -> Result<Sidecar, SidecarError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SidecarError {
            file: file.clone(),
            line: 1,
            col: 1,
            message: e.to_string(),
        })?;
        Sidecar::parse(&file, &text)
    }

    /// Rules serde cannot express.
    fn check_self(&self) -> Result<(), String> {
        if self.unit_systems.iter().filter(|u| u.when.is_empty() && u.external.is_none()).count() > 1 {
            return Err(
                "more than one [[unit_system]] without `when` or `external`: only one can be the default".into()
            );
        }
        for u in &self.unit_systems {
            if !u.when.is_empty() && u.external.is_some() {
                return Err(format!("unit_system `{}` has both `when` and `external`", u.name));
            }
        }
        for u in &self.unit_systems {
            for c in &u.when {
                if let Some(Num(m)) = c.mask
                    && c.equals.0 & !m != 0
                {
                    return Err(format!("unit_system `{}`: `equals` has bits outside `mask` for {}", u.name, c.object));
                }
            }
        }
        for (i, m) in self.modes.iter().enumerate() {
            if self.modes[..i].iter().any(|o| o.code == m.code) {
                return Err(format!("mode {} is listed twice", m.code));
            }
        }
        for (i, h) in self.homing_methods.iter().enumerate() {
            if self.homing_methods[..i].iter().any(|o| o.code == h.code) {
                return Err(format!("homing method {} is listed twice", h.code));
            }
        }
        for s in &self.scaling {
            for role in s.subs.keys() {
                if role.is_empty() {
                    return Err(format!("scaling object {}: empty sub-index role name", s.object));
                }
            }
        }
        Ok(())
    }

    /// The unit system active for a configuration: the first whose conditions all hold, given a
    /// function reading an object's current value; the default system otherwise.
    pub fn active_unit_system(&self, mut value_of: impl FnMut(ObjRef) -> Option<i64>) -> Option<&UnitSystem> {
        self.unit_systems
            .iter()
            .find(|u| !u.when.is_empty() && u.when.iter().all(|c| value_of(c.object).is_some_and(|v| c.holds(v))))
            .or_else(|| self.unit_systems.iter().find(|u| u.when.is_empty() && u.external.is_none()))
    }

    /// The unit system with this name (how an `external` system is selected).
    pub fn unit_system_named(&self, name: &str) -> Option<&UnitSystem> {
        self.unit_systems.iter().find(|u| u.name == name)
    }

    /// The scaling object of a kind.
    pub fn scaling_object(&self, kind: ScalingKind) -> Option<&ScalingObject> {
        self.scaling.iter().find(|s| s.kind == kind)
    }

    /// The dimension of an entry (an exact `(index, sub)` reference first, then the object).
    pub fn dimension_of(&self, index: u16, sub: u8) -> Option<Dimension> {
        self.dimensions
            .get(&ObjRef { index, sub: Some(sub) })
            .or_else(|| self.dimensions.get(&ObjRef { index, sub: None }))
            .copied()
    }

    /// Every object reference the sidecar makes, with what refers to it (for checking against
    /// the EDS).
    pub fn references(&self) -> Vec<(ObjRef, String)> {
        let mut out = Vec::new();
        out.extend(self.dimensions.keys().map(|r| (*r, "[dimensions]".to_owned())));
        for u in &self.unit_systems {
            out.extend(u.when.iter().map(|c| (c.object, format!("unit_system `{}` when", u.name))));
        }
        for s in &self.scaling {
            out.push((s.object, format!("scaling {:?}", s.kind)));
            out.extend(s.subs.iter().map(|(role, sub)| {
                (ObjRef { index: s.object.index, sub: Some(*sub) }, format!("scaling {:?} sub `{role}`", s.kind))
            }));
        }
        out.extend(self.object_units.keys().map(|r| (*r, "[object_units]".to_owned())));
        out.extend(self.bus_scaling.keys().map(|r| (*r, "[bus_scaling]".to_owned())));
        out.extend(self.warnings.iter().map(|w| (w.object, format!("warning bit {}", w.bit))));
        out.extend(self.store.objects.iter().map(|r| (*r, "[store]".to_owned())));
        out.extend(self.decisions.iter().filter_map(|d| d.object.map(|o| (o, "decision".to_owned()))));
        out
    }
}

fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map(|l| l.chars().count()).unwrap_or(0) + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[device]
name = "x"
eds = "x.eds"

[dimensions]
"0x607A" = "position"
"0x2001sub1" = "velocity"

[[unit_system]]
name = "only-motor"
when = [{ object = "0x2014", equals = 0 }]
[unit_system.units]
position = { unit = "deg", scale = "1/100" }

[[unit_system]]
name = "actuator"
[unit_system.units]
position = { unit = "mm", scale = "1/100", scaled_by = ["feed_converter"] }

[[scaling]]
object = "0x2001"
kind = "feed_converter"
subs = { numerator = 1, denominator = 2 }
formula = "unit_new = unit_default * numerator / denominator"
applies_to = ["position"]

[bus_scaling]
"0x6081" = "1000:1"
"0x60F4" = "var"

[[error]]
code = "0x8611"
manufacturer = 1
text = "Following error"
reaction = "quick_stop"

[pdo]
remapping = "while-valid"
source = "6.3.1.2"
"#;

    #[test]
    fn parses_the_documented_shape() {
        let s = Sidecar::parse("x.toml", GOOD).unwrap();
        assert_eq!(s.dimension_of(0x607A, 0), Some(Dimension::Position));
        assert_eq!(s.dimension_of(0x2001, 1), Some(Dimension::Velocity));
        assert_eq!(s.dimension_of(0x2001, 2), None);
        let pos = &s.unit_systems[0].units[&Dimension::Position];
        assert_eq!((pos.unit, pos.scale), (Unit::Degree, Ratio { num: 1, den: 100 }));
        assert_eq!(s.bus_scaling[&"0x6081".parse().unwrap()], BusScaling::Factor(1000));
        assert_eq!(s.errors[0].code, Num(0x8611));
        assert_eq!(s.active_unit_system(|_| Some(0)).unwrap().name, "only-motor");
        assert_eq!(s.active_unit_system(|_| Some(1)).unwrap().name, "actuator");
        let masked = Condition { object: "0x36E9".parse().unwrap(), mask: Some(Num(0x10)), equals: Num(0x10) };
        assert!(masked.holds(0x13) && !masked.holds(0x03));
        assert_eq!(s.pdo, Pdo { remapping: Remapping::WhileValid, source: Some("6.3.1.2".into()) });
        let plain = GOOD.split("\n[pdo]").next().unwrap();
        assert_eq!(Sidecar::parse("x.toml", plain).unwrap().pdo.remapping, Remapping::Cia301, "CiA 301's by default");
        let again: Sidecar = toml::from_str(&toml::to_string(&s).unwrap()).unwrap();
        assert_eq!(again, s);
    }

    #[test]
    fn misspelt_key_is_located() {
        let bad = GOOD.replace("reaction = \"quick_stop\"", "reactoin = \"quick_stop\"");
        let e = Sidecar::parse("x.toml", &bad).unwrap_err();
        let line = bad.lines().position(|l| l.starts_with("reactoin")).unwrap() + 1;
        assert_eq!(e.line, line, "{e}");
        assert!(e.message.contains("reactoin"), "{e}");
        assert!(e.to_string().starts_with(&format!("x.toml:{line}:")), "{e}");
    }

    #[test]
    fn bad_values_are_located() {
        for (from, to, want) in [
            ("\"0x607A\" = \"position\"", "\"607A\" = \"position\"", "object reference"),
            ("scale = \"1/100\" }\n\n[[unit_system]]", "scale = \"1/0\" }\n\n[[unit_system]]", "positive"),
            ("\"0x60F4\" = \"var\"", "\"0x60F4\" = \"1000\"", "1000:1"),
            ("unit = \"deg\"", "unit = \"degrees\"", "unknown variant"),
            ("remapping = \"while-valid\"", "remapping = \"while_valid\"", "while-valid"),
        ] {
            let bad = GOOD.replace(from, to);
            assert_ne!(bad, GOOD, "{from}");
            let e = Sidecar::parse("x.toml", &bad).unwrap_err();
            assert!(e.message.contains(want), "{e}");
            assert!(e.line > 1, "{e}");
        }
    }

    #[test]
    fn obj_refs() {
        assert_eq!("0x2001sub1".parse::<ObjRef>().unwrap(), ObjRef { index: 0x2001, sub: Some(1) });
        assert_eq!("0x1600SUB0x1A".parse::<ObjRef>().unwrap(), ObjRef { index: 0x1600, sub: Some(0x1A) });
        assert!("0x12345".parse::<ObjRef>().is_err());
        assert!("0x2001sub".parse::<ObjRef>().is_err());
        assert_eq!(ObjRef { index: 0x2001, sub: Some(2) }.to_string(), "0x2001sub2");
    }
}
