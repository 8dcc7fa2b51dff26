//! Unit scaling: the `units` module generated from a device's sidecar.
//!
//! # What is generated
//!
//! * `Unit`, `Dimension` and `System` enums with the units, dimensions and unit systems the
//!   sidecar names; `System::active(&Dictionary)` evaluates the systems' `when` conditions on the
//!   dictionary's current values (external systems are chosen by name only).
//! * `Quantity`: an exact value (`Ratio` of two `i128`) in a `Unit`.
//! * `Units`: the conversions of one configured device, built from the dictionary
//!   (`Units::from_dictionary`) by multiplying, per dimension, the system's fixed-point `scale`
//!   with the scaling objects listed in `scaled_by`:
//!
//!   | kind | object (typical) | effect on `physical = raw × factor` | effect on `internal = raw × internal_factor` |
//!   |---|---|---|---|
//!   | `feed_converter` | Camozzi 2001h | `× denominator / numerator` (`value_new = value_default × numerator / denominator`) | the same: the internal value follows the default unit |
//!   | `encoder_resolution` | 608Fh | — | `× increments / motor revolutions` |
//!   | `gear_ratio` | 6091h | — | `× motor revolutions / shaft revolutions` (a zero term counts as 1) |
//!   | `feed_constant` | 6092h | — | `× scale / feed_unit × shaft revolutions / feed` |
//!   | `velocity_factor` | AKD 204Ch | — | `× numerator / denominator` |
//!   | `actuator_type` | DRVI 2014h | selects the system | — |
//!
//!   The internal value is in encoder increments when `encoder_resolution` is in the chain, else
//!   in motor revolutions (CiA 402 factor group: `position_inc = position_user × resolution ×
//!   gear / feed`). The feed counts in one unit of the dimension's physical length unless the
//!   scaling object gives a `feed_unit` (the DRVI's 6092h counts hundredths of a millimetre,
//!   while its accelerations are whole mm/s²): the dimension's fixed-point `scale` is divided by
//!   it, so a feed of 100 at `feed_unit = 1/100 mm` is 1 mm per shaft revolution for positions
//!   (0.01 mm), velocities (0.01 mm/s) and accelerations (mm/s²) alike. `internal_to_raw` and
//!   `internal_to_physical` go the other way (how far the load moves for so many motor turns).
//! * Typed accessors on `Units` for every entry the sidecar gives a dimension
//!   (`units.target_position(&od)` → `Quantity`, `units.set_target_position(&mut od, q)`).
//! * With `[bus_scaling]` (AKD): `bus_scaling(index, sub)` and `to_workbench`.
//!
//! # Arithmetic
//!
//! Exact rationals on integers: no floating point, no drift. Each dimension's factor is combined
//! from the scale and the scaling objects, reduced by their gcd and prepared once, when `Units`
//! is built (od-runtime's `Scale`: the divisor's 64-bit reciprocal is computed then); conversions
//! multiply (raw → physical: exact) or divide and round (physical → raw: **to the nearest
//! integer, halves away from zero**, so a round trip is within half an LSB). The division is a
//! multiplication by that reciprocal with one exact correction step, so converting an integer
//! or decimal quantity takes no division instruction; values whose products leave 64 bits take
//! a general 128-bit path with the same results. Every overflow, a zero scaling term (other than the gear ratio's) and a value outside
//! the entry's type are errors (`UnitError`), never a wrap or a panic.

use std::collections::BTreeMap;

use crate::sidecar::{BusScaling, Dimension, ScalingKind, ScalingObject, Sidecar, Unit, UnitSpec, UnitSystem};
use eds::diag::Severity;
use eds::model::Model;
use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use crate::diag::{self, Sink};
use crate::entry::rust_type;
use crate::ident;
use crate::lit;
use crate::plan::{PEntry, Plan};

/// The symbol a sidecar writes for a unit ([`Unit::symbol`]).
pub fn unit_symbol(u: Unit) -> &'static str {
    u.symbol()
}

fn unit_ident(u: Unit) -> Ident {
    format_ident!("{}", format!("{u:?}"))
}

fn dim_ident(d: Dimension) -> Ident {
    format_ident!("{}", format!("{d:?}"))
}

/// The (upper, lower) sub-index roles of a scaling object's ratio.
fn roles(kind: ScalingKind) -> Option<(&'static str, &'static str)> {
    Some(match kind {
        ScalingKind::FeedConverter | ScalingKind::VelocityFactor => ("numerator", "denominator"),
        ScalingKind::GearRatio => ("motor_revolutions", "shaft_revolutions"),
        ScalingKind::FeedConstant => ("feed", "shaft_revolutions"),
        ScalingKind::EncoderResolution => ("encoder_increments", "motor_revolutions"),
        ScalingKind::ActuatorType => return None,
    })
}

fn kind_fn(kind: ScalingKind) -> Ident {
    format_ident!(
        "{}",
        match kind {
            ScalingKind::FeedConverter => "feed_converter",
            ScalingKind::GearRatio => "gear_ratio",
            ScalingKind::FeedConstant => "feed_constant",
            ScalingKind::EncoderResolution => "encoder_resolution",
            ScalingKind::VelocityFactor => "velocity_factor",
            ScalingKind::ActuatorType => "actuator_type",
        }
    )
}

struct Ctx<'a, 'p> {
    model: &'a Model,
    by_key: BTreeMap<(u16, u8), &'p PEntry<'p>>,
    sink: &'a mut Sink,
    ok: bool,
}

impl<'p> Ctx<'_, 'p> {
    /// The planned integer entry at `(index, sub)`, or an error diagnostic.
    fn int_entry(&mut self, index: u16, sub: u8, why: &str) -> Option<&'p PEntry<'p>> {
        match self.by_key.get(&(index, sub)) {
            Some(e) if e.ty.is_int() => Some(*e),
            Some(e) => {
                self.sink.at_entry(
                    Severity::Error,
                    diag::UNITS,
                    e.obj,
                    e.entry,
                    format!("{why}: the entry is {}, not an integer", e.dt.name()),
                );
                self.ok = false;
                None
            }
            None => {
                let msg = format!("{why}: 0x{index:04X} sub {sub} is not in the device description");
                match self.model.object(index) {
                    Some(obj) => self.sink.at_object(Severity::Error, diag::UNITS, obj, msg),
                    None => self.sink.general(Severity::Error, diag::UNITS, msg),
                }
                self.ok = false;
                None
            }
        }
    }
}

fn read_int(e: &PEntry<'_>) -> TokenStream {
    let g = format_ident!("{}", e.field);
    quote!((od.#g() as i128))
}

/// `pub mod units { … }` (nothing when the sidecar has no unit system; on errors, the
/// diagnostics say why).
pub(crate) fn module(model: &Model, plan: &Plan<'_>, sc: &Sidecar, sink: &mut Sink) -> TokenStream {
    if sc.unit_systems.is_empty() {
        return TokenStream::new();
    }
    let mut cx = Ctx { model, by_key: plan.entries.iter().map(|e| ((e.index, e.sub), e)).collect(), sink, ok: true };
    let (units, dims) = units_and_dimensions(sc);
    let systems = system_idents(sc);
    let selection = system_selection(&mut cx, &systems);
    let ratios = scaling_ratio_fns(&mut cx, sc);
    let factors = system_factor_arms(&mut cx, &systems, &dims, &ratios);
    let accessors = entry_accessors(&mut cx, plan, sc);
    let bus = bus_scaling_items(plan, sc);
    if !cx.ok {
        return TokenStream::new();
    }
    let enums = enum_items(&units, &dims, &systems, &selection);
    let values = value_items();
    let units_type = units_struct(dims.len(), &factors);
    let conversions = conversion_methods();
    let own = device_methods(&ratios.fns, &accessors);
    let rt = crate::support::rt();
    quote! {
        /// Physical units of the device's values, from its sidecar (see the od-codegen `units`
        /// module docs for the arithmetic).
        pub mod units {
            #[doc(inline)]
            pub use #rt::Ratio;
            #enums
            #values
            #units_type
            #conversions
            #own
            #bus
        }
    }
}

/// The units and the dimensions the unit systems use, each sorted (the order of the generated
/// enums and of the per-dimension slots).
pub(crate) fn units_and_dimensions(sc: &Sidecar) -> (Vec<Unit>, Vec<Dimension>) {
    let mut units: Vec<Unit> = Vec::new();
    let mut dims: Vec<Dimension> = Vec::new();
    for s in &sc.unit_systems {
        for (d, spec) in &s.units {
            if !dims.contains(d) {
                dims.push(*d);
            }
            if !units.contains(&spec.unit) {
                units.push(spec.unit);
            }
        }
    }
    dims.sort();
    units.sort();
    (units, dims)
}

/// Each unit system with the name of its `System` variant.
fn system_idents(sc: &Sidecar) -> Vec<(Ident, &UnitSystem)> {
    let mut names = ident::Names::default();
    sc.unit_systems
        .iter()
        .map(|s| {
            let base = ident::camel(&s.name).unwrap_or_else(|| "System".to_owned());
            (format_ident!("{}", names.claim(&base, &[]).0), s)
        })
        .collect()
}

/// How `System::active` decides: one check per system with `when` conditions, in the
/// sidecar's order, and the system to fall back on.
struct Selection {
    checks: Vec<TokenStream>,
    default: Ident,
}

/// The `when` conditions as checks on the dictionary's values, and the default system (the
/// first without conditions that is not external, else the first).
fn system_selection(cx: &mut Ctx<'_, '_>, systems: &[(Ident, &UnitSystem)]) -> Selection {
    let mut checks = Vec::new();
    for (id, s) in systems {
        if s.when.is_empty() {
            continue;
        }
        let mut conds = Vec::new();
        for c in &s.when {
            if let Some(e) = cx.int_entry(c.object.index, c.object.sub_or_zero(), &format!("unit system `{}`", s.name))
            {
                let v = read_int(e);
                let eq = lit::int(c.equals.0 as i128);
                conds.push(match c.mask {
                    Some(m) => {
                        let m = lit::int(m.0 as i128);
                        quote!((#v & #m) == #eq)
                    }
                    None => quote!(#v == #eq),
                });
            }
        }
        checks.push(quote!(if #(#conds)&&* { return System::#id; }));
    }
    let default = systems
        .iter()
        .find(|(_, s)| s.when.is_empty() && s.external.is_none())
        .or_else(|| systems.first())
        .map(|(id, _)| id.clone())
        .unwrap_or_else(|| format_ident!("System"));
    Selection { checks, default }
}

/// The scaling objects' ratio functions, and what the factors need to know of each kind.
struct Ratios<'s> {
    fns: Vec<TokenStream>,
    /// The kinds that have a function, with their scaling object.
    objects: Vec<(ScalingKind, &'s ScalingObject)>,
}

impl Ratios<'_> {
    fn object(&self, kind: ScalingKind) -> Option<&ScalingObject> {
        self.objects.iter().find(|(k, _)| *k == kind).map(|(_, o)| *o)
    }
}

/// One `Units::<kind>(od) -> Result<Ratio, UnitError>` per scaling object with a ratio:
/// `upper / lower` of its two sub-indices, reduced; a zero term is an error, except for the
/// gear ratio, where it counts as 1.
fn scaling_ratio_fns<'s>(cx: &mut Ctx<'_, '_>, sc: &'s Sidecar) -> Ratios<'s> {
    let mut ratios = Ratios { fns: Vec::new(), objects: Vec::new() };
    for so in &sc.scaling {
        if so.feed_unit.is_some() && so.kind != ScalingKind::FeedConstant {
            cx.sink.general(
                Severity::Error,
                diag::UNITS,
                format!(
                    "scaling object {} ({:?}) gives `feed_unit`, which only a feed_constant has",
                    so.object, so.kind
                ),
            );
            cx.ok = false;
        }
        let Some((top, bottom)) = roles(so.kind) else { continue };
        let (Some(&ts), Some(&bs)) = (so.subs.get(top), so.subs.get(bottom)) else {
            cx.sink.general(
                Severity::Error,
                diag::UNITS,
                format!("scaling object {} ({:?}) needs sub-index roles `{top}` and `{bottom}`", so.object, so.kind),
            );
            cx.ok = false;
            continue;
        };
        let why = format!("scaling object {:?}", so.kind);
        let (Some(te), Some(be)) = (cx.int_entry(so.object.index, ts, &why), cx.int_entry(so.object.index, bs, &why))
        else {
            continue;
        };
        let (t, b) = (read_int(te), read_int(be));
        let name = kind_fn(so.kind);
        let index = lit::hex(so.object.index as u64, 4);
        let zero_as_one = so.kind == ScalingKind::GearRatio;
        let body = if zero_as_one {
            quote! {
                let (t, b) = (#t, #b);
                Ratio::new(if t == 0 { 1 } else { t }, if b == 0 { 1 } else { b }).ok_or(UnitError::Overflow)
            }
        } else {
            quote! {
                let (t, b) = (#t, #b);
                if t == 0 || b == 0 {
                    return Err(UnitError::ZeroFactor { index: #index });
                }
                Ratio::new(t, b).ok_or(UnitError::Overflow)
            }
        };
        let doc = lit::doc(&[
            format!(
                "`0x{:04X}` {:?}: `{top} / {bottom}` (subs {ts} and {bs}), reduced{}.",
                so.object.index,
                so.kind,
                if zero_as_one { "; a zero term counts as 1" } else { "; a zero term is an error" }
            ),
            String::new(),
            lit::doc_escape(&so.formula),
        ]);
        ratios.fns.push(quote! {
            #doc
            pub fn #name(od: &super::Dictionary) -> Result<Ratio, UnitError> {
                #body
            }
        });
        ratios.objects.push((so.kind, so));
    }
    ratios
}

/// The length (or angle) a unit measures, per second and per second squared alike: what a
/// feed constant's `feed_unit` must match. Units per minute (rpm) match nothing: the internal
/// value is per second.
fn length_of(u: Unit) -> Option<Unit> {
    Some(match u {
        Unit::Degree | Unit::DegreePerSecond | Unit::DegreePerSecond2 => Unit::Degree,
        Unit::Millimeter | Unit::MillimeterPerSecond | Unit::MillimeterPerSecond2 => Unit::Millimeter,
        Unit::Inch | Unit::InchPerSecond | Unit::InchPerSecond2 => Unit::Inch,
        Unit::Increment | Unit::IncrementPerSecond | Unit::IncrementPerSecond2 => Unit::Increment,
        Unit::Microstep | Unit::MicrostepPerSecond | Unit::MicrostepPerSecond2 => Unit::Microstep,
        Unit::UserUnit | Unit::UserUnitPerSecond | Unit::UserUnitPerSecond2 => Unit::UserUnit,
        Unit::Revolution => Unit::Revolution,
        _ => return None,
    })
}

/// `let #name = #name.checked_mul(#by).ok_or(UnitError::Overflow)?;`
fn times(name: &str, by: TokenStream) -> TokenStream {
    let n = format_ident!("{name}");
    quote!(let #n = #n.checked_mul(#by).ok_or(UnitError::Overflow)?;)
}

/// The statements computing one dimension's factors in one system: `f`, physical value per
/// raw unit, and, when the chain has an internal-side kind (the second value), `g`, internal
/// value per raw unit. A chain that cannot be built leaves error diagnostics.
fn dimension_factor(
    cx: &mut Ctx<'_, '_>,
    system: &UnitSystem,
    d: Dimension,
    spec: &UnitSpec,
    ratios: &Ratios<'_>,
) -> (Vec<TokenStream>, bool) {
    let (sn, sd) = (lit::int(spec.scale.num as i128), lit::int(spec.scale.den as i128));
    let mut steps = vec![quote!(let f = Ratio::new(#sn, #sd).ok_or(UnitError::Overflow)?;)];
    let internal = spec.scaled_by.iter().any(|k| {
        matches!(
            k,
            ScalingKind::FeedConstant
                | ScalingKind::GearRatio
                | ScalingKind::EncoderResolution
                | ScalingKind::VelocityFactor
        ) && ratios.object(*k).is_some()
    });
    if internal {
        steps.push(quote!(let g = Ratio::ONE;));
    }
    for k in &spec.scaled_by {
        let Some(so) = ratios.object(*k) else {
            if *k != ScalingKind::ActuatorType {
                cx.sink.general(
                    Severity::Error,
                    diag::UNITS,
                    format!("unit system `{}` scales {d:?} by {k:?}, which no [[scaling]] object defines", system.name),
                );
                cx.ok = false;
            }
            continue;
        };
        let f = kind_fn(*k);
        match k {
            // The bus unit itself changes: raw × den / num is the value in the default unit,
            // for the physical value and the internal one alike.
            ScalingKind::FeedConverter => {
                steps.push(quote!(let c = Self::#f(od)?.recip().ok_or(UnitError::Overflow)?;));
                steps.push(times("f", quote!(c)));
                if internal {
                    steps.push(times("g", quote!(c)));
                }
            }
            // Shaft revolutions = (physical value in the feed's unit) × shaft revolutions / feed.
            ScalingKind::FeedConstant => steps.extend(feed_constant_steps(cx, system, d, spec, so)),
            ScalingKind::ActuatorType => {}
            _ => steps.push(times("g", quote!(Self::#f(od)?))),
        }
    }
    (steps, internal)
}

/// The feed constant's steps of `g`: the dimension's fixed point expressed in the feed's unit
/// (`scale / feed_unit`, checked to measure the same length), then `× shaft revolutions / feed`.
fn feed_constant_steps(
    cx: &mut Ctx<'_, '_>,
    system: &UnitSystem,
    d: Dimension,
    spec: &UnitSpec,
    so: &ScalingObject,
) -> Vec<TokenStream> {
    let feed_scale = match so.feed_unit {
        Some(fu) => {
            if length_of(spec.unit) != Some(fu.unit) {
                cx.sink.general(
                    Severity::Error,
                    diag::UNITS,
                    format!(
                        "unit system `{}` scales {d:?} ({}) by a feed counted in {}: the lengths differ",
                        system.name,
                        unit_symbol(spec.unit),
                        unit_symbol(fu.unit)
                    ),
                );
                cx.ok = false;
            }
            fu.scale
        }
        None => crate::sidecar::Ratio::ONE,
    };
    let mut steps = Vec::new();
    let n = i128::from(spec.scale.num) * i128::from(feed_scale.den);
    let dn = i128::from(spec.scale.den) * i128::from(feed_scale.num);
    if n != dn {
        let (n, dn) = (lit::int(n), lit::int(dn));
        steps.push(times("g", quote!(Ratio::new(#n, #dn).ok_or(UnitError::Overflow)?)));
    }
    let f = kind_fn(ScalingKind::FeedConstant);
    steps.push(times("g", quote!(Self::#f(od)?.recip().ok_or(UnitError::Overflow)?)));
    steps
}

/// One arm of `Units::with_system` per system: every dimension's prepared factor and unit,
/// and its internal factor where the chain defines one.
fn system_factor_arms(
    cx: &mut Ctx<'_, '_>,
    systems: &[(Ident, &UnitSystem)],
    dims: &[Dimension],
    ratios: &Ratios<'_>,
) -> Vec<TokenStream> {
    let rt = crate::support::rt();
    let mut arms = Vec::new();
    for (id, s) in systems {
        let mut inits = Vec::new();
        for (d, spec) in &s.units {
            let i = Literal::usize_unsuffixed(dims.iter().position(|x| x == d).unwrap_or(0));
            let (steps, internal) = dimension_factor(cx, s, *d, spec, ratios);
            let u = unit_ident(spec.unit);
            let set_internal = if internal { quote!(internal[#i] = Some(g.reduced());) } else { TokenStream::new() };
            inits.push(quote! {
                {
                    #(#steps)*
                    factor[#i] = Some((#rt::Scale::new(f), Unit::#u));
                    #set_internal
                }
            });
        }
        arms.push(quote!(System::#id => { #(#inits)* }));
    }
    arms
}

/// A typed getter and setter on `Units` for every entry the sidecar gives a dimension.
fn entry_accessors(cx: &mut Ctx<'_, '_>, plan: &Plan<'_>, sc: &Sidecar) -> Vec<TokenStream> {
    let mut accessors = Vec::new();
    for (r, d) in &sc.dimensions {
        let targets: Vec<&PEntry<'_>> = match r.sub {
            Some(s) => cx.by_key.get(&(r.index, s)).copied().into_iter().collect(),
            None => plan
                .entries
                .iter()
                .filter(|e| e.index == r.index && (!e.obj.object_type.has_subs() || e.sub > 0))
                .collect(),
        };
        if targets.is_empty() {
            cx.int_entry(r.index, r.sub_or_zero(), &format!("[dimensions] {r}"));
            continue;
        }
        for e in targets {
            if !e.ty.is_int() {
                cx.int_entry(e.index, e.sub, &format!("[dimensions] {r}"));
                continue;
            }
            let g = format_ident!("{}", e.field);
            let s = format_ident!("set_{}", e.field);
            let dv = dim_ident(*d);
            let ty = rust_type(e.ty);
            let name = lit::doc_escape(&crate::entry::display_name(e));
            let get_doc = lit::doc(&[format!("{} {name} as a {d:?} quantity.", crate::entry::location(e))]);
            let set_doc = lit::doc(&[format!(
                "Sets {} {name} from a {d:?} quantity (rounded to the nearest raw value, halves away from zero; limits checked by the dictionary).",
                crate::entry::location(e)
            )]);
            accessors.push(quote! {
                #get_doc
                pub fn #g(&self, od: &super::Dictionary) -> Result<Quantity, UnitError> {
                    self.to_physical(Dimension::#dv, od.#g() as i64)
                }
                #set_doc
                pub fn #s(&self, od: &mut super::Dictionary, q: Quantity) -> Result<(), UnitError> {
                    let raw = self.to_raw(Dimension::#dv, q)?;
                    let v = #ty::try_from(raw).map_err(|_| UnitError::OutOfRange)?;
                    od.#s(v).map_err(UnitError::Rejected)
                }
            });
        }
    }
    accessors
}

/// With `[bus_scaling]` (AKD): the per-entry bus factors, `bus_scaling` and `to_workbench`.
fn bus_scaling_items(plan: &Plan<'_>, sc: &Sidecar) -> TokenStream {
    if sc.bus_scaling.is_empty() {
        return TokenStream::new();
    }
    let mut rows: Vec<(u32, u32)> = Vec::new();
    for (r, b) in &sc.bus_scaling {
        let subs: Vec<u8> = match r.sub {
            Some(s) => vec![s],
            None => {
                let v: Vec<u8> = plan.entries.iter().filter(|e| e.index == r.index).map(|e| e.sub).collect();
                if v.is_empty() { vec![0] } else { v }
            }
        };
        for s in subs {
            let f = match b {
                BusScaling::Factor(f) => *f,
                BusScaling::Variable => 0,
            };
            rows.push((((r.index as u32) << 8) | s as u32, f));
        }
    }
    rows.sort();
    rows.dedup_by_key(|r| r.0);
    let n = Literal::usize_unsuffixed(rows.len());
    let keys = rows.iter().map(|(k, _)| lit::hex(*k as u64, 6));
    let facs = rows.iter().map(|(_, f)| Literal::u32_unsuffixed(*f));
    quote! {
        /// How a bus value relates to the vendor tool's value (`[bus_scaling]`).
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum BusScaling {
            /// Bus value = tool value × factor.
            Factor(u32),
            /// Depends on other settings.
            Variable,
        }

        static BUS_KEYS: [u32; #n] = [#(#keys),*];
        static BUS_FACTORS: [u32; #n] = [#(#facs),*];

        /// The bus scaling of an entry, if the sidecar lists it.
        pub fn bus_scaling(index: u16, sub: u8) -> Option<BusScaling> {
            let key = ((index as u32) << 8) | sub as u32;
            let pos = BUS_KEYS.binary_search(&key).ok()?;
            match BUS_FACTORS.get(pos)? {
                0 => Some(BusScaling::Variable),
                f => Some(BusScaling::Factor(*f)),
            }
        }

        /// The vendor tool's value of a bus value (`raw / factor`, exact); `None` for
        /// entries without a fixed factor.
        pub fn to_workbench(index: u16, sub: u8, raw: i64) -> Option<Ratio> {
            match bus_scaling(index, sub)? {
                BusScaling::Factor(f) => Ratio::new(raw as i128, f as i128),
                BusScaling::Variable => None,
            }
        }
    }
}

/// The `Unit`, `Dimension` and `System` enums, with `System::active`.
fn enum_items(
    units: &[Unit],
    dims: &[Dimension],
    systems: &[(Ident, &UnitSystem)],
    selection: &Selection,
) -> TokenStream {
    let unit_variants = units.iter().map(|u| {
        let id = unit_ident(*u);
        let doc = format!(" `{}`", unit_symbol(*u));
        quote!(#[doc = #doc] #id)
    });
    let unit_symbols = units.iter().map(|u| {
        let id = unit_ident(*u);
        let s = unit_symbol(*u);
        quote!(Unit::#id => #s)
    });
    let dim_variants = dims.iter().map(|d| {
        let id = dim_ident(*d);
        let doc = format!(" {d:?}.");
        quote!(#[doc = #doc] #id)
    });
    let dim_arms = dims.iter().enumerate().map(|(i, d)| {
        let id = dim_ident(*d);
        let i = Literal::usize_unsuffixed(i);
        quote!(Dimension::#id => #i)
    });
    let system_variants = systems.iter().map(|(id, s)| {
        let mut lines = vec![format!("`{}`", lit::doc_escape(&s.name))];
        if let Some(d) = &s.description {
            lines.push(String::new());
            lines.push(lit::doc_escape(d));
        }
        if let Some(x) = &s.external {
            lines.push(String::new());
            lines.push(format!("Chosen outside the bus: {}.", lit::doc_escape(x)));
        }
        let doc = lit::doc(&lines);
        quote!(#doc #id)
    });
    let system_name_arms = systems.iter().map(|(id, s)| {
        let n = &s.name;
        quote!(System::#id => #n)
    });
    let checks = &selection.checks;
    let default_system = &selection.default;
    quote! {
        /// A physical unit.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Unit { #(#unit_variants,)* }

        impl Unit {
            /// The unit's symbol.
            pub const fn symbol(self) -> &'static str {
                match self { #(#unit_symbols,)* }
            }
        }

        /// A physical dimension.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Dimension { #(#dim_variants,)* }

        impl Dimension {
            const fn slot(self) -> usize {
                match self { #(#dim_arms,)* }
            }
        }

        /// A unit configuration of the device.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum System { #(#system_variants,)* }

        impl System {
            /// The sidecar's name of the system.
            pub const fn name(self) -> &'static str {
                match self { #(#system_name_arms,)* }
            }

            /// The system the dictionary's current values select (the first whose conditions
            /// hold, else the default one; external systems only by explicit choice).
            pub fn active(od: &super::Dictionary) -> System {
                let _ = od;
                #(#checks)*
                System::#default_system
            }
        }
    }
}

/// `UnitError` and `Quantity`: the same for every device.
fn value_items() -> TokenStream {
    quote! {
        /// Why a conversion failed.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum UnitError {
            /// A scaling object holds 0 where it divides.
            ZeroFactor {
                /// The scaling object.
                index: u16,
            },
            /// An intermediate or final value does not fit.
            Overflow,
            /// The dimension has no unit in the active system.
            NoUnit,
            /// The quantity's unit is not the system's unit for the dimension.
            WrongUnit {
                /// The system's unit.
                expected: Unit,
                /// The quantity's unit.
                got: Unit,
            },
            /// The raw value does not fit the entry's type.
            OutOfRange,
            /// The dictionary refused the value (limits).
            Rejected(::od_runtime::od::AbortCode),
        }

        /// An exact physical value.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct Quantity {
            /// The value.
            pub value: Ratio,
            /// Its unit.
            pub unit: Unit,
        }

        impl Quantity {
            /// `value` in `unit`.
            pub const fn new(value: Ratio, unit: Unit) -> Self {
                Quantity { value, unit }
            }

            /// An integer value in `unit`.
            pub const fn int(value: i64, unit: Unit) -> Self {
                Quantity { value: Ratio::int(value), unit }
            }

            /// The nearest `f64` (for display; conversions stay exact).
            pub fn to_f64(self) -> f64 {
                self.value.to_f64()
            }
        }
    }
}

/// `Units`: the conversions of one configured device, built per system by `system_arms`, and
/// what it says about each dimension (unit, factor, internal factor).
fn units_struct(n_dims: usize, system_arms: &[TokenStream]) -> TokenStream {
    let rt = crate::support::rt();
    let n_dims = Literal::usize_unsuffixed(n_dims);
    quote! {
        /// The conversions of one configured device.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct Units {
            system: System,
            /// Physical value per raw unit (prepared for fast exact conversions both ways),
            /// and the physical unit, per dimension.
            factor: [Option<(#rt::Scale, Unit)>; #n_dims],
            /// Internal value (increments or motor revolutions) per raw unit, per dimension.
            internal: [Option<Ratio>; #n_dims],
        }

        impl Units {
            /// The conversions for the system the dictionary selects.
            pub fn from_dictionary(od: &super::Dictionary) -> Result<Units, UnitError> {
                Self::with_system(System::active(od), od)
            }

            /// The conversions for `system`, with the scaling objects' current values.
            pub fn with_system(system: System, od: &super::Dictionary) -> Result<Units, UnitError> {
                let _ = od;
                let mut factor = [None; #n_dims];
                let mut internal = [None; #n_dims];
                match system { #(#system_arms)* }
                let _ = &mut internal;
                Ok(Units { system, factor, internal })
            }

            /// The unit system.
            pub const fn system(&self) -> System {
                self.system
            }

            /// The unit of a dimension in this configuration.
            pub fn unit(&self, d: Dimension) -> Option<Unit> {
                self.factor.get(d.slot()).copied().flatten().map(|(_, u)| u)
            }

            /// Physical value per raw unit (exact, reduced).
            pub fn factor(&self, d: Dimension) -> Option<Ratio> {
                self.factor.get(d.slot()).copied().flatten().map(|(f, _)| f.factor())
            }

            /// Internal value (encoder increments, or motor revolutions) per raw unit, where
            /// the system's scaling objects define one.
            pub fn internal_factor(&self, d: Dimension) -> Option<Ratio> {
                self.internal.get(d.slot()).copied().flatten()
            }
        }
    }
}

/// The conversions of `Units`: raw to physical and back, raw to internal and back, internal to
/// physical. The same for every device.
fn conversion_methods() -> TokenStream {
    let rt = crate::support::rt();
    quote! {
        impl Units {
            /// `raw × factor`, exact.
            #[inline]
            pub fn to_physical(&self, d: Dimension, raw: i64) -> Result<Quantity, UnitError> {
                let Some(Some((f, unit))) = self.factor.get(d.slot()) else {
                    return Err(UnitError::NoUnit);
                };
                Ok(Quantity { value: f.to_physical(raw).ok_or(UnitError::Overflow)?, unit: *unit })
            }

            /// The prepared factor for converting `q` in dimension `d`.
            #[inline]
            fn scale_for(&self, d: Dimension, q: &Quantity) -> Result<&#rt::Scale, UnitError> {
                match self.factor.get(d.slot()) {
                    Some(Some((f, unit))) if *unit == q.unit => Ok(f),
                    Some(Some((_, unit))) => Err(UnitError::WrongUnit { expected: *unit, got: q.unit }),
                    _ => Err(UnitError::NoUnit),
                }
            }

            /// `q / factor`, exact (may be fractional).
            pub fn to_raw_exact(&self, d: Dimension, q: Quantity) -> Result<Ratio, UnitError> {
                self.scale_for(d, &q)?.to_raw_exact(q.value).ok_or(UnitError::Overflow)
            }

            /// `q / factor` rounded to the nearest integer, halves away from zero.
            ///
            /// Integer and decimal quantities (denominators up to 10^6) convert without a
            /// division instruction; always inlined, so a loop converting many values keeps
            /// the prepared factor in registers (the rare general paths stay out of line).
            #[inline(always)]
            pub fn to_raw(&self, d: Dimension, q: Quantity) -> Result<i64, UnitError> {
                self.scale_for(d, &q)?.to_raw_i64(q.value).ok_or(UnitError::Overflow)
            }

            /// `raw × internal factor`, exact: encoder increments (or motor revolutions).
            pub fn to_internal(&self, d: Dimension, raw: i64) -> Result<Ratio, UnitError> {
                let g = self.internal.get(d.slot()).copied().flatten().ok_or(UnitError::NoUnit)?;
                g.checked_mul_int(raw).ok_or(UnitError::Overflow)
            }

            /// `internal / internal factor`, exact (may be fractional): the raw value of an
            /// internal one (encoder increments, or motor revolutions).
            pub fn internal_to_raw_exact(&self, d: Dimension, internal: Ratio) -> Result<Ratio, UnitError> {
                let g = self.internal.get(d.slot()).copied().flatten().ok_or(UnitError::NoUnit)?;
                internal.checked_div(g).ok_or(UnitError::Overflow)
            }

            /// `internal / internal factor` rounded to the nearest integer, halves away from
            /// zero: the raw value the device shows for an internal one.
            pub fn internal_to_raw(&self, d: Dimension, internal: Ratio) -> Result<i64, UnitError> {
                let raw = self.internal_to_raw_exact(d, internal)?;
                i64::try_from(raw.round()).map_err(|_| UnitError::Overflow)
            }

            /// `internal / internal factor × factor`, exact: the physical value of an internal
            /// one (how far the load moves for so many motor revolutions).
            pub fn internal_to_physical(&self, d: Dimension, internal: Ratio) -> Result<Quantity, UnitError> {
                let raw = self.internal_to_raw_exact(d, internal)?;
                let Some(Some((f, unit))) = self.factor.get(d.slot()) else {
                    return Err(UnitError::NoUnit);
                };
                Ok(Quantity { value: raw.checked_mul(f.factor()).ok_or(UnitError::Overflow)?.reduced(), unit: *unit })
            }
        }
    }
}

/// The device's own methods of `Units`: one ratio function per scaling object and a typed
/// getter and setter per dimensioned entry.
fn device_methods(ratio_fns: &[TokenStream], accessors: &[TokenStream]) -> TokenStream {
    quote! {
        impl Units {
            #(#ratio_fns)*

            #(#accessors)*
        }
    }
}
