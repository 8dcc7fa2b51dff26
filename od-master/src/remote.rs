//! The typed view of a remote node that generated clients (`od_codegen::Builder::client`,
//! `odgen gen --client`, `include_eds!(…, client)`) are made of.
//!
//! A generated `Remote` has one method per entry of the device's dictionary, named as the
//! device-side accessor is, which returns an [`Object`] handle: its Rust type, its access and
//! (for entries the sidecar gives a dimension) its physical [`dim`]ension are in the handle's
//! type, so that writing a `ro` object, reading a `wo` one or writing a velocity where a
//! position goes does not compile. Limits from the EDS are checked before anything is sent,
//! with the abort code the device would give ([`Error::Refused`]).
//!
//! | piece | what it is |
//! |---|---|
//! | [`Object`], [`Ro`], [`Wo`], [`Rw`] | one entry of the node: `read`, `write`, `read_in`, `write_in` as its access allows |
//! | [`Wire`] and the markers [`U24`], …, [`VisibleString`], [`OctetString`], [`Domain`], [`UnicodeString`] | how a CiA type travels (its bytes) and what Rust type it reads as |
//! | [`Quantity`], [`dim`], [`Scaling`] | a physical value of a dimension, and a device's conversions (the generated `units::Units` implements [`Scaling`]) |
//! | [`PdoLayout`], [`Rpdo`], [`Tpdo`], [`TpdoReceiver`] | the generated PDO layouts on the master side: sent, received, and mapped on the device in one call |

use std::marker::PhantomData;

use od_runtime::__private_v3::Ratio;
use od_runtime::od::AbortCode;
use od_runtime::pdo::Direction;
pub use od_sidecar::{Dimension, Unit};
use tokio::sync::broadcast;

use crate::error::Error;
use crate::node::Node;
pub use crate::unit_error::UnitError;

pub use od_runtime::master::sdo_client::Direction as Transfer;

/// The device side's limit rule (`od_runtime::od::EntryInfo::check_value`): above `high` is
/// `VALUE_TOO_HIGH` (0609 0031h), below `low` `VALUE_TOO_LOW` (0609 0032h).
pub fn check_limits(v: i128, low: i128, high: i128) -> Result<(), AbortCode> {
    if v > high {
        Err(AbortCode::VALUE_TOO_HIGH)
    } else if v < low {
        Err(AbortCode::VALUE_TOO_LOW)
    } else {
        Ok(())
    }
}

/// Access markers: the third parameter of [`Object`].
pub mod access {
    /// Read only (`ro`, `const`): `read`, no `write`.
    #[derive(Clone, Copy, Debug)]
    pub struct Ro;
    /// Write only (`wo`): `write`, no `read`.
    #[derive(Clone, Copy, Debug)]
    pub struct Wo;
    /// Read and write (`rw`, `rwr`, `rww`).
    #[derive(Clone, Copy, Debug)]
    pub struct Rw;
    /// An access that allows reading.
    #[diagnostic::on_unimplemented(
        message = "this object is write-only: it has no `read`",
        label = "write-only object",
        note = "its EDS gives it AccessType wo: it can be written, not read"
    )]
    pub trait Read {}
    /// An access that allows writing.
    #[diagnostic::on_unimplemented(
        message = "this object is read-only: it has no `write`",
        label = "read-only object",
        note = "its EDS gives it AccessType ro or const: it can be read, not written"
    )]
    pub trait Write {}
    impl Read for Ro {}
    impl Read for Rw {}
    impl Write for Wo {}
    impl Write for Rw {}
}

/// Dimension markers: the fourth parameter of [`Object`] and the parameter of [`Quantity`],
/// one per `od_sidecar::Dimension`; [`dim::None`] for an entry without one.
pub mod dim {
    use od_sidecar::Dimension as D;
    /// A physical dimension at the type level.
    pub trait Dim {
        /// The sidecar's dimension.
        const DIMENSION: D;
    }
    macro_rules! dims {
        ($($(#[$m:meta])* $n:ident),*) => {$(
            $(#[$m])*
            #[derive(Clone, Copy, Debug, PartialEq, Eq)]
            pub struct $n;
            impl Dim for $n {
                const DIMENSION: D = D::$n;
            }
        )*};
    }
    dims!(
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
        Time
    );
    /// No dimension: the entry has no unit (no `read_in`/`write_in`).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub struct None;
}

/// How a CiA data type travels in an SDO transfer: its length and the Rust value it reads as.
pub trait Wire {
    /// The value a read gives.
    type Value;
    /// Bytes on the bus; 0 for the variable-length types.
    const LEN: usize;
    /// The value of the bytes read (`None`: a wrong length).
    fn decode(bytes: &[u8]) -> Option<Self::Value>;
}

/// A fixed-size type: the value a write takes is the value a read gives.
pub trait Fixed: Wire<Value: Copy> {
    /// The value's bytes.
    fn encode(v: Self::Value) -> Vec<u8>;
    /// The value as an integer, for the limits (`None` for REAL).
    fn int(v: Self::Value) -> Option<i128>;
    /// The value as a REAL, for the limits (`None` for integers).
    fn real(v: Self::Value) -> Option<f64>;
}

macro_rules! native {
    ($($t:ty => $int:expr, $real:expr;)*) => {$(
        impl Wire for $t {
            type Value = $t;
            const LEN: usize = size_of::<$t>();
            fn decode(bytes: &[u8]) -> Option<$t> {
                Some(<$t>::from_le_bytes(bytes.try_into().ok()?))
            }
        }
        impl Fixed for $t {
            fn encode(v: $t) -> Vec<u8> {
                v.to_le_bytes().to_vec()
            }
            #[allow(clippy::redundant_closure_call)]
            fn int(v: $t) -> Option<i128> {
                ($int)(v)
            }
            #[allow(clippy::redundant_closure_call)]
            fn real(v: $t) -> Option<f64> {
                ($real)(v)
            }
        }
    )*};
}

native! {
    u8 => |v| Some(i128::from(v)), |_| None;
    u16 => |v| Some(i128::from(v)), |_| None;
    u32 => |v| Some(i128::from(v)), |_| None;
    u64 => |v| Some(i128::from(v)), |_| None;
    i8 => |v| Some(i128::from(v)), |_| None;
    i16 => |v| Some(i128::from(v)), |_| None;
    i32 => |v| Some(i128::from(v)), |_| None;
    i64 => |v| Some(i128::from(v)), |_| None;
    f32 => |_| None, |v| Some(f64::from(v));
    f64 => |_| None, Some;
}

impl Wire for bool {
    type Value = bool;
    const LEN: usize = 1;
    fn decode(bytes: &[u8]) -> Option<bool> {
        match bytes {
            [0] => Some(false),
            [1] => Some(true),
            _ => None,
        }
    }
}

impl Fixed for bool {
    fn encode(v: bool) -> Vec<u8> {
        vec![u8::from(v)]
    }
    fn int(v: bool) -> Option<i128> {
        Some(i128::from(u8::from(v)))
    }
    fn real(_: bool) -> Option<f64> {
        None
    }
}

macro_rules! odd_width {
    ($($(#[$m:meta])* $n:ident: $t:ty, $len:expr, $signed:expr;)*) => {$(
        $(#[$m])*
        #[derive(Clone, Copy, Debug)]
        pub struct $n;
        impl Wire for $n {
            type Value = $t;
            const LEN: usize = $len;
            fn decode(bytes: &[u8]) -> Option<$t> {
                if bytes.len() != $len {
                    return None;
                }
                let v = od_runtime::od::decode_int(bytes, $signed);
                <$t>::try_from(v).ok()
            }
        }
        impl Fixed for $n {
            fn encode(v: $t) -> Vec<u8> {
                v.to_le_bytes()[..$len].to_vec()
            }
            fn int(v: $t) -> Option<i128> {
                Some(i128::from(v))
            }
            fn real(_: $t) -> Option<f64> {
                None
            }
        }
    )*};
}

odd_width! {
    /// UNSIGNED24 (3 bytes), as `u32`.
    U24: u32, 3, false;
    /// UNSIGNED40 (5 bytes), as `u64`.
    U40: u64, 5, false;
    /// UNSIGNED48 (6 bytes), as `u64`; also TIME_OF_DAY and TIME_DIFFERENCE.
    U48: u64, 6, false;
    /// UNSIGNED56 (7 bytes), as `u64`.
    U56: u64, 7, false;
    /// INTEGER24 (3 bytes), as `i32`.
    I24: i32, 3, true;
    /// INTEGER40 (5 bytes), as `i64`.
    I40: i64, 5, true;
    /// INTEGER48 (6 bytes), as `i64`.
    I48: i64, 6, true;
    /// INTEGER56 (7 bytes), as `i64`.
    I56: i64, 7, true;
}

/// VISIBLE_STRING: read as a `String` (trailing NULs removed, lossy UTF-8), written from `&str`.
#[derive(Clone, Copy, Debug)]
pub struct VisibleString;
/// OCTET_STRING: bytes.
#[derive(Clone, Copy, Debug)]
pub struct OctetString;
/// DOMAIN: bytes (segmented or block transfers, as [`Node`]'s options say).
#[derive(Clone, Copy, Debug)]
pub struct Domain;
/// UNICODE_STRING: its bytes (UTF-16LE as the device holds them).
#[derive(Clone, Copy, Debug)]
pub struct UnicodeString;

impl Wire for VisibleString {
    type Value = String;
    const LEN: usize = 0;
    fn decode(bytes: &[u8]) -> Option<String> {
        Some(String::from_utf8_lossy(bytes).trim_end_matches('\0').to_owned())
    }
}

/// A variable-length type read and written as bytes.
pub trait Bytes: Wire<Value = Vec<u8>> {}

macro_rules! bytes {
    ($($n:ident),*) => {$(
        impl Wire for $n {
            type Value = Vec<u8>;
            const LEN: usize = 0;
            fn decode(bytes: &[u8]) -> Option<Vec<u8>> {
                Some(bytes.to_vec())
            }
        }
        impl Bytes for $n {}
    )*};
}

bytes!(OctetString, Domain, UnicodeString);

/// The limits an [`Object`] checks before a write is sent (from the EDS's `LowLimit` and
/// `HighLimit`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Limits {
    None,
    Int(i128, i128),
    Real(f64, f64),
}

/// The handle's type parameters (covariant, `Send` and `Sync` whatever they are).
type Types<T, A, D> = PhantomData<fn() -> (T, A, D)>;

/// One entry of a remote node: index, sub-index, its type `T` (a [`Wire`]), its access `A`
/// ([`access`]) and its dimension `D` ([`dim`]).
#[derive(Debug)]
pub struct Object<'a, T, A, D = dim::None> {
    node: &'a Node,
    index: u16,
    sub: u8,
    limits: Limits,
    types: Types<T, A, D>,
}

impl<T, A, D> Clone for Object<'_, T, A, D> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T, A, D> Copy for Object<'_, T, A, D> {}

/// A read-only entry.
pub type Ro<'a, T, D = dim::None> = Object<'a, T, access::Ro, D>;
/// A write-only entry.
pub type Wo<'a, T, D = dim::None> = Object<'a, T, access::Wo, D>;
/// A read-write entry.
pub type Rw<'a, T, D = dim::None> = Object<'a, T, access::Rw, D>;

impl<'a, T: Wire, A, D> Object<'a, T, A, D> {
    /// `index`/`sub` of `node`, without limits.
    pub const fn new(node: &'a Node, index: u16, sub: u8) -> Self {
        Self { node, index, sub, limits: Limits::None, types: PhantomData }
    }

    /// With integer limits (inclusive; an open side is the type's end).
    pub const fn limits(mut self, low: i128, high: i128) -> Self {
        self.limits = Limits::Int(low, high);
        self
    }

    /// With REAL limits (inclusive; an open side is infinite).
    pub const fn real_limits(mut self, low: f64, high: f64) -> Self {
        self.limits = Limits::Real(low, high);
        self
    }

    /// The object's index.
    pub const fn index(&self) -> u16 {
        self.index
    }

    /// The sub-index.
    pub const fn sub(&self) -> u8 {
        self.sub
    }

    /// The integer limits checked before a write, if any.
    pub fn int_limits(&self) -> Option<(i128, i128)> {
        match self.limits {
            Limits::Int(l, h) => Some((l, h)),
            _ => None,
        }
    }

    fn refused(&self, code: AbortCode) -> Error {
        Error::Refused { node: self.node.id(), index: self.index, sub: self.sub, code }
    }
}

// The access bounds are on the methods, not the impl blocks: calling `write` on a read-only
// object is then an unsatisfied bound with the access traits' own message ("this object is
// read-only"), not a method missing for unsatisfied bounds.
impl<T: Wire, A, D> Object<'_, T, A, D> {
    /// Reads the entry (an SDO upload, retried on lost answers).
    pub async fn read(&self) -> Result<T::Value, Error>
    where
        A: access::Read,
    {
        let bytes = self.node.read_bytes(self.index, self.sub).await?;
        T::decode(&bytes).ok_or(Error::Length {
            node: self.node.id(),
            index: self.index,
            sub: self.sub,
            expected: T::LEN,
            got: bytes.len(),
        })
    }
}

impl<T: Fixed, A, D> Object<'_, T, A, D> {
    /// Checks `v` against the EDS limits: the abort code the device would answer with
    /// (`VALUE_TOO_HIGH` 0609 0031h, `VALUE_TOO_LOW` 0609 0032h), before anything is sent.
    pub fn check(&self, v: T::Value) -> Result<(), AbortCode>
    where
        A: access::Write,
    {
        match self.limits {
            Limits::None => Ok(()),
            Limits::Int(low, high) => T::int(v).map_or(Ok(()), |x| check_limits(x, low, high)),
            Limits::Real(low, high) => match T::real(v) {
                Some(x) if x > high => Err(AbortCode::VALUE_TOO_HIGH),
                Some(x) if x < low => Err(AbortCode::VALUE_TOO_LOW),
                _ => Ok(()),
            },
        }
    }

    /// Writes the entry (an SDO download, never retried), after checking the limits.
    pub async fn write(&self, v: T::Value) -> Result<(), Error>
    where
        A: access::Write,
    {
        self.check(v).map_err(|c| self.refused(c))?;
        self.node.write_bytes(self.index, self.sub, &T::encode(v)).await
    }

    /// Writes an entry that writing twice leaves as writing once (a parameter, a target):
    /// retried like a read.
    pub async fn write_idempotent(&self, v: T::Value) -> Result<(), Error>
    where
        A: access::Write,
    {
        self.check(v).map_err(|c| self.refused(c))?;
        self.node.write_bytes_idempotent(self.index, self.sub, &T::encode(v)).await
    }
}

impl<A, D> Object<'_, VisibleString, A, D> {
    /// Writes the string's bytes.
    pub async fn write(&self, v: &str) -> Result<(), Error>
    where
        A: access::Write,
    {
        self.node.write_bytes(self.index, self.sub, v.as_bytes()).await
    }
}

macro_rules! write_bytes {
    ($($n:ident),*) => {$(
        impl<A, D> Object<'_, $n, A, D> {
            /// Writes the bytes.
            pub async fn write(&self, v: &[u8]) -> Result<(), Error>
            where
                A: access::Write,
            {
                self.node.write_bytes(self.index, self.sub, v).await
            }
        }
    )*};
}

write_bytes!(OctetString, Domain, UnicodeString);

impl<T: Fixed, A, D: dim::Dim> Object<'_, T, A, D> {
    /// Reads the entry as a quantity in the unit `units` (the device's configuration) gives
    /// its dimension.
    pub async fn read_in(&self, units: &dyn Scaling) -> Result<Quantity<D>, Error>
    where
        A: access::Read,
    {
        let v = self.read().await?;
        let raw = T::int(v).and_then(|x| i64::try_from(x).ok()).ok_or(self.unit_error(UnitError::OutOfRange))?;
        let (value, unit) = units.to_physical(D::DIMENSION, raw).map_err(|e| self.unit_error(e))?;
        Ok(Quantity { value, unit, dim: PhantomData })
    }
}

impl<T: Fixed, A, D: dim::Dim> Object<'_, T, A, D>
where
    T::Value: TryFrom<i64>,
{
    /// The raw value of `q`, rounded to the nearest (halves away from zero).
    pub fn raw(&self, units: &dyn Scaling, q: Quantity<D>) -> Result<T::Value, Error>
    where
        A: access::Write,
    {
        let raw = units.to_raw(D::DIMENSION, q.value, q.unit).map_err(|e| self.unit_error(e))?;
        T::Value::try_from(raw).map_err(|_| self.unit_error(UnitError::OutOfRange))
    }

    /// Writes `q`, converted by `units` (rounded to the nearest raw value, limits checked
    /// before sending); a target, so retried like a read.
    pub async fn write_in(&self, units: &dyn Scaling, q: Quantity<D>) -> Result<(), Error>
    where
        A: access::Write,
    {
        let v = self.raw(units, q)?;
        self.write_idempotent(v).await
    }
}

impl<T, A, D> Object<'_, T, A, D> {
    fn unit_error(&self, error: UnitError) -> Error {
        Error::Unit { node: self.node.id(), index: self.index, sub: self.sub, error }
    }
}

/// A device's unit conversions: the generated `units::Units` implements it, built from the
/// scaling objects read from the drive (the generated `Remote::units`).
pub trait Scaling: std::fmt::Debug + Send + Sync {
    /// The raw value of `value` in `unit`, of dimension `dim`, rounded to the nearest.
    fn to_raw(&self, dim: Dimension, value: Ratio, unit: Unit) -> Result<i64, UnitError>;
    /// The physical value of `raw` of dimension `dim`, with its unit.
    fn to_physical(&self, dim: Dimension, raw: i64) -> Result<(Ratio, Unit), UnitError>;
}

/// An exact physical value of dimension `D`: `Quantity::mm(12.5)`, `Quantity::deg(720)`.
/// Which unit of the dimension a device wants depends on its configuration (read from it), so
/// a millimetre position given to a drive set up in degrees is a run-time
/// [`UnitError::WrongUnit`]; a velocity given where a position goes does not compile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quantity<D> {
    value: Ratio,
    unit: Unit,
    dim: PhantomData<D>,
}

/// A number a [`Quantity`] is made of: integers exactly, `f64` as the shortest decimal that
/// reads back as it (12.5 is 25/2, 0.1 is 1/10).
pub trait Number {
    /// The exact value; `None` for NaN, infinities and decimals beyond 18 places.
    fn ratio(self) -> Option<Ratio>;
}

macro_rules! int_number {
    ($($t:ty),*) => {$(
        impl Number for $t {
            fn ratio(self) -> Option<Ratio> {
                Some(Ratio::int(i64::from(self)))
            }
        }
    )*};
}
int_number!(i8, i16, i32, i64, u8, u16, u32);

impl Number for f64 {
    fn ratio(self) -> Option<Ratio> {
        if !self.is_finite() {
            return None;
        }
        // The shortest decimal that reads back as this f64, e.g. "12.5", "1e-7", "-3".
        let text = format!("{self:e}");
        let (mantissa, exp) = text.split_once('e')?;
        let exp: i32 = exp.parse().ok()?;
        let negative = mantissa.starts_with('-');
        let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
        let decimals = mantissa.split_once('.').map_or(0, |(_, f)| f.len()) as i32;
        let mut num: i128 = digits.parse().ok()?;
        if negative {
            num = -num;
        }
        let shift = exp - decimals;
        if shift >= 0 {
            Ratio::new(num.checked_mul(10i128.checked_pow(shift.unsigned_abs())?)?, 1)
        } else if -shift <= 18 {
            Ratio::new(num, 10i128.pow(shift.unsigned_abs()))
        } else {
            None
        }
    }
}

impl Number for f32 {
    fn ratio(self) -> Option<Ratio> {
        // Through the f32's own shortest decimal, not its f64 widening's.
        format!("{self}").parse::<f64>().ok()?.ratio()
    }
}

impl<D: dim::Dim> Quantity<D> {
    /// `value` in `unit`; `None` when the value is not a finite number. A unit of another
    /// dimension is refused when the quantity is converted ([`UnitError::WrongUnit`]).
    pub fn new(value: impl Number, unit: Unit) -> Option<Self> {
        value.ratio().map(|value| Self { value, unit, dim: PhantomData })
    }

    /// An exact `value` in `unit` (a unit of another dimension is refused when the quantity is
    /// converted).
    pub fn from_ratio(value: Ratio, unit: Unit) -> Self {
        Self { value, unit, dim: PhantomData }
    }

    /// The exact value (in [`unit`](Self::unit)).
    pub fn value(&self) -> Ratio {
        self.value
    }

    /// The unit.
    pub fn unit(&self) -> Unit {
        self.unit
    }

    /// The nearest `f64` (for display; conversions stay exact).
    pub fn to_f64(&self) -> f64 {
        self.value.to_f64()
    }

    fn of(value: impl Number, unit: Unit) -> Self {
        // The constructors below pass units of `D`; a value that is not a finite number (NaN,
        // infinity) is kept as 0/0 would not be: it becomes an overflow at conversion.
        let value = value.ratio().unwrap_or(Ratio::new(i128::MAX, 1).unwrap_or(Ratio::ONE));
        Self { value, unit, dim: PhantomData }
    }
}

macro_rules! constructors {
    ($($d:ident { $($(#[$m:meta])* $f:ident => $u:ident),* })*) => {$(
        impl Quantity<dim::$d> {$(
            $(#[$m])*
            pub fn $f(value: impl Number) -> Self {
                Self::of(value, Unit::$u)
            }
        )*}
    )*};
}

constructors! {
    Position {
        /// Millimetres.
        mm => Millimeter,
        /// Degrees.
        deg => Degree,
        /// Inches.
        inch => Inch,
        /// Revolutions.
        rev => Revolution,
        /// Encoder increments.
        inc => Increment,
        /// The drive's user-defined position unit (CiA 402 factor group).
        user => UserUnit
    }
    Velocity {
        /// Millimetres per second.
        mm_per_s => MillimeterPerSecond,
        /// Degrees per second.
        deg_per_s => DegreePerSecond,
        /// Inches per second.
        inch_per_s => InchPerSecond,
        /// Revolutions per minute.
        rpm => Rpm,
        /// User units per second.
        user_per_s => UserUnitPerSecond
    }
    Acceleration {
        /// Millimetres per second squared.
        mm_per_s2 => MillimeterPerSecond2,
        /// Degrees per second squared.
        deg_per_s2 => DegreePerSecond2,
        /// Inches per second squared.
        inch_per_s2 => InchPerSecond2,
        /// Revolutions per minute per second.
        rpm_per_s => RpmPerSecond,
        /// User units per second squared.
        user_per_s2 => UserUnitPerSecond2
    }
    Torque {
        /// Milliamperes (drives that give torque as motor current).
        milliampere => MilliAmpere,
        /// Thousandths of the motor's rated torque (CiA 402).
        permille_rated_torque => PermilleRatedTorque
    }
    Current {
        /// Milliamperes of current.
        current_ma => MilliAmpere
    }
    Time {
        /// Milliseconds.
        ms => Millisecond
    }
}

/// A PDO layout generated from a device's default mapping (`pdo::Rpdo1`, `pdo::Tpdo1`, …).
pub trait PdoLayout: Sized {
    /// Receive (by the device: the master sends it) or transmit (the master receives it).
    const DIRECTION: Direction;
    /// The PDO's number (1 for RPDO 1 / TPDO 1).
    const NUMBER: u16;
    /// The mapping entries (`0xIIIISSLL`), checked by the generator against the device's
    /// rules: at most 64 bits, every entry mappable in this direction.
    const MAPPING: &'static [u32];
    /// The PDO's bytes: for a generated layout, an array of its length (`[u8; LEN]`), so that
    /// sending one allocates nothing and the generated code needs nothing of `std`.
    type Bytes: AsRef<[u8]>;
    /// The PDO's bytes.
    fn to_bytes(&self) -> Self::Bytes;
    /// A received PDO; `None` when it is shorter than the mapping.
    fn from_bytes(data: &[u8]) -> Option<Self>;
}

/// The communication parameter object of PDO `number` in `dir` (1400h/1800h + n − 1).
fn comm_index(dir: Direction, number: u16) -> u16 {
    let base = if dir == Direction::Receive { 0x1400 } else { 0x1800 };
    base + number.clamp(1, 512) - 1
}

/// The COB-ID of PDO `number` on `node` in CiA 301's predefined connection set (PDOs 1–4), read
/// from the device for the others.
async fn cob_id(node: &Node, dir: Direction, number: u16) -> Result<u16, Error> {
    if (1..=4).contains(&number) {
        let base: u16 = if dir == Direction::Receive { 0x200 } else { 0x180 };
        return Ok(base + 0x100 * (number - 1) + u16::from(node.id()));
    }
    let c: u32 = node.read(comm_index(dir, number), 1).await?;
    Ok((c & 0x7FF) as u16)
}

/// Maps PDO `number` (1..=512) in `dir` on the device with `mapping` and enables it on `cob_id`,
/// in the order CiA 301 asks: the PDO made invalid (COB-ID bit 31), the mapping's count set to
/// 0, the entries written, the count set, the COB-ID written valid (bit 30, RTR, kept as the
/// device has it). `check` (the generated device's
/// `check_rpdo_mapping`/`check_tpdo_mapping`) refuses a mapping over 64 bits or of an entry
/// that is not mappable before anything is sent.
pub async fn map_pdo(
    node: &Node,
    dir: Direction,
    number: u16,
    cob_id: u16,
    mapping: &[u32],
    check: fn(&[u32]) -> Result<u32, AbortCode>,
) -> Result<(), Error> {
    if !(1..=512).contains(&number) {
        let index = if dir == Direction::Receive { 0x1600 } else { 0x1A00 };
        return Err(Error::Refused { node: node.id(), index, sub: 0, code: AbortCode::NO_OBJECT });
    }
    let comm = comm_index(dir, number);
    let map = comm + 0x200;
    if mapping.len() > 64 {
        return Err(Error::Refused { node: node.id(), index: map, sub: 0, code: AbortCode::PDO_LENGTH_EXCEEDED });
    }
    check(mapping).map_err(|code| Error::Refused { node: node.id(), index: map, sub: 0, code })?;
    // Bit 30 (no RTR) as the device has it; an 11-bit identifier (bit 29 clear).
    let current: u32 = node.read(comm, 1).await?;
    let cob = (current & 0x4000_0000) | u32::from(cob_id & 0x7FF);
    remap(node, comm, cob, mapping, None, |_, _, e| e).await
}

/// Writes the remap of the PDO whose communication parameter is `comm` (1400h.. or 1800h..;
/// its mapping parameter is `comm` + 200h) in the order CiA 301 asks: the COB-ID with bit 31
/// set (PDO invalid), the mapping's count 0, the entries, the count, then the `transmission`
/// type if given, and `cob` (valid) last. The one sequence [`map_pdo`] and the axis's cyclic
/// position share; `wrap` gives a failed write's error the caller's form, with its object.
pub(crate) async fn remap(
    node: &Node,
    comm: u16,
    cob: u32,
    mapping: &[u32],
    transmission: Option<u8>,
    wrap: impl Fn(u16, u8, Error) -> Error,
) -> Result<(), Error> {
    let map = comm + 0x200;
    let wrap = &wrap;
    let write_u8 = |index: u16, sub: u8, v: u8| async move {
        node.write_idempotent(index, sub, v).await.map_err(|e| wrap(index, sub, e))
    };
    node.write_idempotent(comm, 1, cob | 0x8000_0000).await.map_err(|e| wrap(comm, 1, e))?;
    write_u8(map, 0, 0).await?;
    for (i, m) in (1u8..).zip(mapping) {
        node.write_idempotent(map, i, *m).await.map_err(|e| wrap(map, i, e))?;
    }
    write_u8(map, 0, mapping.len() as u8).await?;
    if let Some(t) = transmission {
        write_u8(comm, 2, t).await?;
    }
    node.write_idempotent(comm, 1, cob).await.map_err(|e| wrap(comm, 1, e))
}

/// A PDO of a remote node with layout `P`: [`Rpdo`] (the master sends it) or [`Tpdo`] (the
/// master receives it); `D` is [`Sent`] or [`Received`].
#[derive(Debug)]
pub struct Pdo<'a, P, D> {
    node: &'a Node,
    cob_id: Option<u16>,
    check: fn(&[u32]) -> Result<u32, AbortCode>,
    layout: PhantomData<fn(P, D) -> P>,
}

/// The master sends the PDO: [`Rpdo`].
#[derive(Debug)]
pub enum Sent {}

/// The master receives the PDO: [`Tpdo`].
#[derive(Debug)]
pub enum Received {}

/// An RPDO of a remote node: the master sends it.
pub type Rpdo<'a, P> = Pdo<'a, P, Sent>;

/// A TPDO of a remote node: the master receives it.
pub type Tpdo<'a, P> = Pdo<'a, P, Received>;

impl<'a, P: PdoLayout, D> Pdo<'a, P, D> {
    /// The PDO of layout `P` on `node`; `check` is the device's mapping check.
    pub fn new(node: &'a Node, check: fn(&[u32]) -> Result<u32, AbortCode>) -> Self {
        Self { node, cob_id: None, check, layout: PhantomData }
    }

    /// On `cob_id` instead of the predefined connection set's (PDOs 1–4) or the one the device
    /// holds (the others).
    pub fn with_cob_id(mut self, cob_id: u16) -> Self {
        self.cob_id = Some(cob_id & 0x7FF);
        self
    }

    /// The COB-ID it goes on.
    pub async fn cob_id(&self) -> Result<u16, Error> {
        match self.cob_id {
            Some(c) => Ok(c),
            None => cob_id(self.node, P::DIRECTION, P::NUMBER).await,
        }
    }

    /// Maps the layout on the device ([`map_pdo`]) on its COB-ID.
    pub async fn configure(&self) -> Result<(), Error> {
        let cob = self.cob_id().await?;
        map_pdo(self.node, P::DIRECTION, P::NUMBER, cob, P::MAPPING, self.check).await
    }
}

impl<P: PdoLayout> Pdo<'_, P, Sent> {
    /// Sends `value`.
    pub async fn send(&self, value: P) -> Result<(), Error> {
        let cob = self.cob_id().await?;
        let frame = od_bus::CanFrame::standard(u32::from(cob), value.to_bytes().as_ref())
            .map_err(od_bus::TransportError::from)?;
        self.node.bus().send(frame).await
    }
}

impl<P: PdoLayout> Pdo<'_, P, Received> {
    /// Receives this TPDO from now on.
    pub async fn subscribe(&self) -> Result<TpdoReceiver<P>, Error> {
        let cob_id = self.cob_id().await?;
        Ok(TpdoReceiver { frames: self.node.bus().frames(), cob_id, node: self.node.id(), layout: PhantomData })
    }

    /// The next one received from now on.
    pub async fn next(&self) -> Result<P, Error> {
        self.subscribe().await?.next().await
    }
}

/// Received TPDOs of one layout ([`Pdo::subscribe`]).
#[derive(Debug)]
pub struct TpdoReceiver<P> {
    frames: broadcast::Receiver<od_bus::CanFrame>,
    cob_id: u16,
    node: u8,
    layout: PhantomData<fn() -> P>,
}

impl<P: PdoLayout> TpdoReceiver<P> {
    /// The next TPDO: frames of its COB-ID that are shorter than the mapping are refused
    /// ([`Error::Refused`] with `PDO_LENGTH`), RTR frames skipped; a receiver that fell behind
    /// the bus goes on with the oldest frame still kept.
    pub async fn next(&mut self) -> Result<P, Error> {
        loop {
            match self.frames.recv().await {
                Ok(f) if f.id() == u32::from(self.cob_id) && !f.is_extended() && !f.is_remote() => {
                    let index = comm_index(P::DIRECTION, P::NUMBER) + 0x200;
                    return P::from_bytes(f.data()).ok_or(Error::Refused {
                        node: self.node,
                        index,
                        sub: 0,
                        code: AbortCode::PDO_LENGTH_EXCEEDED,
                    });
                }
                Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => return Err(Error::Closed),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A decimal with up to 9 places, written as an f64, is that decimal exactly.
        #[test]
        fn an_f64_decimal_is_its_exact_ratio(units in -1_000_000_000_000i64..1_000_000_000_000, places in 0u32..9) {
            let den = 10i128.pow(places);
            let text = format!("{}", Ratio::new(i128::from(units), den).unwrap().to_f64());
            let v: f64 = text.parse().unwrap();
            let r = v.ratio().unwrap().reduced();
            let want = Ratio::new(i128::from(units), den).unwrap().reduced();
            prop_assert_eq!((r.num(), r.den()), (want.num(), want.den()), "{}", text);
        }

        /// Integers are exact.
        #[test]
        fn integers_are_exact(v in any::<i64>()) {
            let r = v.ratio().unwrap();
            prop_assert_eq!((r.num(), r.den()), (i128::from(v), 1));
        }

        /// The limit rule is the device side's for every value and limits.
        #[test]
        fn the_limit_rule_is_the_device_sides(v in any::<i32>(), a in any::<i32>(), b in any::<i32>()) {
            let (low, high) = (i64::from(a.min(b)), i64::from(a.max(b)));
            use od_runtime::od::{Access, DataType, EntryExtras, EntryInfo, Limits};
            // Leaked: a few bytes per case, as the tables' `'static` references want.
            let limits: &'static Limits = Box::leak(Box::new(Limits { low, high }));
            let extras: &'static EntryExtras = Box::leak(Box::new(EntryExtras { limits: Some(limits), ..EntryExtras::NONE }));
            let info = EntryInfo::new(0x2000, 0, DataType::Integer32, Access::Rw, false).with_extras(extras);
            prop_assert_eq!(check_limits(i128::from(v), i128::from(low), i128::from(high)).err(), info.check_value(&v.to_le_bytes()).err());
        }
    }

    #[test]
    fn values_that_are_no_number_are_refused() {
        assert!(f64::NAN.ratio().is_none());
        assert!(f64::INFINITY.ratio().is_none());
        assert!(1e300f64.ratio().is_none());
        let r = 0.1f32.ratio().unwrap().reduced();
        assert_eq!((r.num(), r.den()), (1, 10));
    }
}
