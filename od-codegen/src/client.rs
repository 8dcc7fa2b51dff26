//! The master's view of the device (`Options::client`): `pub mod remote { pub struct Remote }`
//! inside the device module, built on `od_master::remote`.
//!
//! `Remote` has one method per planned entry, with the device-side accessor's name, returning
//! an `od_master::remote::Object` whose type parameters carry the entry's CiA type, its access
//! (`Ro`/`Wo`/`Rw`) and, where the sidecar gives one, its dimension; the EDS limits go with it
//! and are checked before a write is sent. The device's default PDO layouts get
//! `od_master::remote::PdoLayout` and a method each (`rpdo1()`, `tpdo1()`); a sidecar's unit
//! systems get `Remote::units`, which reads the scaling objects over SDO into a `Dictionary`
//! and builds the device's own `units::Units` from it (which implements
//! `od_master::remote::Scaling`). Everything generic lives in `od_master::remote`, so the
//! generated code is one short method per entry.

use std::collections::BTreeSet;

use eds::model::{Access, DataType, Model};
use od_runtime::pdo::Direction;
use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::diag::Sink;
use crate::entry::{display_name, location};
use crate::plan::{PEntry, Plan, Ty, type_range};
use crate::sidecar::Sidecar;
use crate::{lit, pdo};

/// The `od_master::remote` path.
fn r() -> TokenStream {
    quote!(::od_master::remote)
}

/// The wire marker of a CiA type (`None`: not transferable as a typed value).
fn wire(dt: DataType) -> Option<TokenStream> {
    use DataType as D;
    let r = r();
    Some(match dt {
        D::Boolean => quote!(bool),
        D::Unsigned8 => quote!(u8),
        D::Unsigned16 => quote!(u16),
        D::Unsigned32 => quote!(u32),
        D::Unsigned64 => quote!(u64),
        D::Integer8 => quote!(i8),
        D::Integer16 => quote!(i16),
        D::Integer32 => quote!(i32),
        D::Integer64 => quote!(i64),
        D::Real32 => quote!(f32),
        D::Real64 => quote!(f64),
        D::Unsigned24 => quote!(#r::U24),
        D::Unsigned40 => quote!(#r::U40),
        D::Unsigned48 | D::TimeOfDay | D::TimeDifference => quote!(#r::U48),
        D::Unsigned56 => quote!(#r::U56),
        D::Integer24 => quote!(#r::I24),
        D::Integer40 => quote!(#r::I40),
        D::Integer48 => quote!(#r::I48),
        D::Integer56 => quote!(#r::I56),
        D::VisibleString => quote!(#r::VisibleString),
        D::OctetString => quote!(#r::OctetString),
        D::UnicodeString => quote!(#r::UnicodeString),
        D::Domain => quote!(#r::Domain),
        D::Other(_) => return None,
    })
}

/// `Ro`, `Wo` or `Rw`, and the access as the EDS spells it.
fn access(a: Access) -> (TokenStream, &'static str) {
    match a {
        Access::Ro => (quote!(Ro), "ro"),
        Access::Const => (quote!(Ro), "const"),
        Access::Wo => (quote!(Wo), "wo"),
        Access::Rw => (quote!(Rw), "rw"),
        Access::Rwr => (quote!(Rw), "rwr"),
        Access::Rww => (quote!(Rw), "rww"),
    }
}

/// Whether a data type's wire width is narrower than its Rust type (24, 40, 48, 56 bits).
fn odd_width(dt: DataType) -> bool {
    use DataType as D;
    matches!(
        dt,
        D::Unsigned24
            | D::Unsigned40
            | D::Unsigned48
            | D::Unsigned56
            | D::Integer24
            | D::Integer40
            | D::Integer48
            | D::Integer56
            | D::TimeOfDay
            | D::TimeDifference
    )
}

/// The limits a write is checked against (`.limits(lo, hi)`), and their doc text.
fn limits(e: &PEntry<'_>) -> (TokenStream, String) {
    if e.ty.is_int() && e.ty != Ty::Bool {
        let narrow = odd_width(e.dt);
        if e.set_low.is_none() && e.set_high.is_none() && !narrow {
            return (TokenStream::new(), String::new());
        }
        let Some((min, max)) = type_range(e.dt) else { return (TokenStream::new(), String::new()) };
        let (lo, hi) = (e.set_low.unwrap_or(min), e.set_high.unwrap_or(max));
        let (l, h) = (lit::int(lo), lit::int(hi));
        return (quote!(.limits(#l, #h)), format!(" Limits {lo}..={hi}, checked before sending."));
    }
    if e.ty.is_real() && (e.real_low.is_some() || e.real_high.is_some()) {
        let lo = e.real_low.unwrap_or(f64::NEG_INFINITY);
        let hi = e.real_high.unwrap_or(f64::INFINITY);
        let (l, h) = (lit::real(lo, false), lit::real(hi, false));
        return (quote!(.real_limits(#l, #h)), format!(" Limits {lo}..={hi}, checked before sending."));
    }
    (TokenStream::new(), String::new())
}

/// A method name not taken by an entry: `base`, else `base_remote`, `base_remote_2`, ...
fn free(base: &str, taken: &mut BTreeSet<String>) -> proc_macro2::Ident {
    let mut name = base.to_owned();
    let mut n = 1;
    while taken.contains(&name) {
        name = if n == 1 { format!("{base}_remote") } else { format!("{base}_remote_{n}") };
        n += 1;
    }
    taken.insert(name.clone());
    format_ident!("{name}")
}

/// The `(index, sub)` of every entry the unit systems read: the systems' conditions and the
/// scaling objects' sub-indices.
fn scaling_entries(sc: &Sidecar) -> BTreeSet<(u16, u8)> {
    let mut out = BTreeSet::new();
    for s in &sc.unit_systems {
        for c in &s.when {
            out.insert((c.object.index, c.object.sub_or_zero()));
        }
    }
    for so in &sc.scaling {
        for sub in so.subs.values() {
            out.insert((so.object.index, *sub));
        }
    }
    out
}

/// `pub mod remote { … }`.
pub(crate) fn module(
    model: &Model,
    plan: &Plan<'_>,
    sidecar: Option<&Sidecar>,
    has_units: bool,
    product: &str,
) -> TokenStream {
    let r = r();
    let mut taken: BTreeSet<String> = plan.entries.iter().map(|e| e.field.clone()).collect();
    taken.insert("new".to_owned());
    let node_fn = free("node", &mut taken);

    let mut methods = Vec::new();
    for e in &plan.entries {
        let Some(w) = wire(e.dt) else { continue };
        let (acc, acc_name) = access(e.entry.access);
        // The dimension of the generator's sidecar: the given one with CiA 402's positions,
        // velocities and accelerations added, or the one derived from the file's CiA 402
        // objects (`standard::effective_sidecar`).
        let dim = sidecar
            .filter(|_| e.ty.is_int() && e.ty != Ty::Bool)
            .and_then(|sc| sc.dimension_of(e.index, e.sub))
            .map(|d| format_ident!("{d:?}"));
        let (lim, lim_doc) = limits(e);
        let f = format_ident!("{}", e.field);
        let (index, sub) = (lit::hex(u64::from(e.index), 4), proc_macro2::Literal::u8_unsuffixed(e.sub));
        let dim_doc =
            dim.as_ref().map(|d| format!(" A {d}: `read_in`/`write_in` take quantities.")).unwrap_or_default();
        let doc = lit::doc(&[format!(
            "{} {}: {}, `{acc_name}`.{lim_doc}{dim_doc}",
            location(e),
            lit::doc_escape(&display_name(e)),
            e.dt.name()
        )]);
        let ty = match &dim {
            Some(d) => quote!(#r::#acc<'_, #w, #r::dim::#d>),
            None => quote!(#r::#acc<'_, #w>),
        };
        methods.push(quote! {
            #doc
            pub fn #f(&self) -> #ty {
                #r::Object::new(&self.node, #index, #sub)#lim
            }
        });
    }

    let profiles = profile_items(model, plan);
    let pdos = pdo_items(model, plan, &mut taken);
    let units = sidecar.filter(|_| has_units).map(|sc| units_items(plan, sc, &mut taken)).unwrap_or_default();
    let product = lit::doc_escape(product);
    let mod_doc = lit::doc(&[
        format!("The {product} seen from a CANopen master (`od_master`): one method per entry, named as"),
        "the device side names it, returning a typed handle whose access, limits and dimension come".to_owned(),
        "from the description.".to_owned(),
    ]);
    let remote_doc = lit::doc(&[format!(
        "A {product} on the bus: `Remote::new(bus.node(id)?)`, then `remote.statusword().read().await`."
    )]);
    quote! {
        #mod_doc
        pub mod remote {
            #remote_doc
            #[derive(Clone, Debug)]
            pub struct Remote {
                node: ::od_master::Node,
            }
            impl Remote {
                /// The device on `node`.
                pub fn new(node: ::od_master::Node) -> Self {
                    Self { node }
                }
                /// The node handle (raw SDO, NMT).
                pub fn #node_fn(&self) -> &::od_master::Node {
                    &self.node
                }
                #(#methods)*
            }
            #profiles
            #pdos
            #units
        }
    }
}

/// `impl od_master::profile::Cia301 for Remote` (and `Cia402` when the device has CiA 402
/// objects): the standard objects under the standard's names, each from the file's entry when
/// it serves the standard's type and access, a "data type does not match" refusal when it
/// does not; the trait's default (the object does not exist) otherwise.
fn profile_items(model: &Model, plan: &Plan<'_>) -> TokenStream {
    use crate::standard::{self, Profile, StdAccess};
    let r = r();
    let by_key: std::collections::BTreeMap<(u16, u8), &PEntry<'_>> =
        plan.entries.iter().map(|e| ((e.index, e.sub), e)).collect();
    let mut m301 = Vec::new();
    let mut m402 = Vec::new();
    for o in standard::OBJECTS {
        let Some(e) = by_key.get(&(o.index, o.sub)) else { continue };
        let Some(w) = wire(o.data_type) else { continue };
        let name = format_ident!("{}", o.name);
        let acc = match o.access {
            StdAccess::Ro => quote!(Ro),
            StdAccess::Rw => quote!(Rw),
        };
        let ty = match o.dimension {
            Some(d) => {
                let d = format_ident!("{d:?}");
                quote!(#r::#acc<'_, #w, #r::dim::#d>)
            }
            None => quote!(#r::#acc<'_, #w>),
        };
        let (index, sub) = (lit::hex(u64::from(o.index), 4), proc_macro2::Literal::u8_unsuffixed(o.sub));
        let body = if standard::serves(o, e.dt, e.entry.access) {
            let (lim, _) = limits(e);
            quote!(Ok(#r::Object::new(&self.node, #index, #sub)#lim))
        } else {
            quote!(Err(::od_master::profile::mistyped(&self.node, #index, #sub)))
        };
        let m = quote! {
            fn #name(&self) -> Result<#ty, ::od_master::Error> {
                #body
            }
        };
        match o.profile {
            Profile::Cia301 => m301.push(m),
            Profile::Cia402 => m402.push(m),
        }
    }
    let cia402 = if standard::has_cia402(model) {
        quote! {
            impl ::od_master::profile::Cia402 for Remote {
                #(#m402)*
            }
        }
    } else {
        TokenStream::new()
    };
    quote! {
        impl ::od_master::profile::Cia301 for Remote {
            fn node(&self) -> &::od_master::Node {
                &self.node
            }
            #(#m301)*
        }
        #cia402
    }
}

/// `PdoLayout` for each generated layout, and `rpdoN()`/`tpdoN()` on `Remote`.
fn pdo_items(model: &Model, plan: &Plan<'_>, taken: &mut BTreeSet<String>) -> TokenStream {
    // The layouts' diagnostics were given with the `pdo` module; these are the same layouts.
    let mut quiet = Sink::new("", false);
    let r = r();
    let mut impls = Vec::new();
    let mut methods = Vec::new();
    for (dir, number, raw) in pdo::layout_summaries(model, plan, &mut quiet) {
        let (kind, handle, check) = match dir {
            Direction::Receive => ("Rpdo", quote!(Rpdo), quote!(check_rpdo_mapping)),
            Direction::Transmit => ("Tpdo", quote!(Tpdo), quote!(check_tpdo_mapping)),
        };
        let name = format_ident!("{kind}{number}");
        let dir_tokens = match dir {
            Direction::Receive => quote!(::od_runtime::pdo::Direction::Receive),
            Direction::Transmit => quote!(::od_runtime::pdo::Direction::Transmit),
        };
        let n = proc_macro2::Literal::u16_unsuffixed(number);
        let raw = raw.iter().map(|m| lit::hex(u64::from(*m), 8));
        impls.push(quote! {
            impl #r::PdoLayout for super::pdo::#name {
                const DIRECTION: ::od_runtime::pdo::Direction = #dir_tokens;
                const NUMBER: u16 = #n;
                const MAPPING: &'static [u32] = &[#(#raw),*];
                type Bytes = [u8; super::pdo::#name::LEN];
                fn to_bytes(&self) -> Self::Bytes {
                    self.pack()
                }
                fn from_bytes(data: &[u8]) -> Option<Self> {
                    Self::unpack(data).ok()
                }
            }
        });
        let f = free(&format!("{}{number}", kind.to_lowercase()), taken);
        let doc = lit::doc(&[format!(
            "{} {number} with its default layout [`{kind}{number}`](super::pdo::{kind}{number}): `configure` maps it on the device, {}.",
            kind.to_uppercase(),
            if dir == Direction::Receive { "`send` sends it" } else { "`subscribe`/`next` receive it" }
        )]);
        methods.push(quote! {
            #doc
            pub fn #f(&self) -> #r::#handle<'_, super::pdo::#name> {
                #r::#handle::new(&self.node, super::Dictionary::#check)
            }
        });
    }
    if impls.is_empty() {
        return TokenStream::new();
    }
    quote! {
        #(#impls)*
        impl Remote {
            #(#methods)*
        }
    }
}

/// `Remote::units` and `Scaling for units::Units`, for a sidecar with unit systems.
fn units_items(plan: &Plan<'_>, sc: &Sidecar, taken: &mut BTreeSet<String>) -> TokenStream {
    if sc.unit_systems.is_empty() {
        return TokenStream::new();
    }
    let r = r();
    let wanted = scaling_entries(sc);
    let reads = plan.entries.iter().filter(|e| wanted.contains(&(e.index, e.sub)) && e.ty.is_int() && e.entry.access != Access::Wo).map(|e| {
        let g = format_ident!("{}", e.field);
        let s = format_ident!("set_{}", e.field);
        let (index, sub) = (lit::hex(u64::from(e.index), 4), proc_macro2::Literal::u8_unsuffixed(e.sub));
        quote! {
            od.#s(self.#g().read().await?).map_err(|code| ::od_master::Error::Refused { node, index: #index, sub: #sub, code })?;
        }
    });
    let reads: Vec<TokenStream> = reads.collect();
    let units_fn = free("units", taken);
    let units_with = free("units_with", taken);
    let scaling = free("scaling", taken);
    // The same sets, in the same order, as the device side's `Units` enums.
    let (units, dims) = crate::units::units_and_dimensions(sc);
    let dim_arms = dims.iter().map(|d| {
        let d = format_ident!("{d:?}");
        quote!(::od_master::remote::Dimension::#d => Some(super::units::Dimension::#d))
    });
    let unit_in = units.iter().map(|u| {
        let u = format_ident!("{u:?}");
        quote!(::od_master::remote::Unit::#u => Some(super::units::Unit::#u))
    });
    let unit_out = units.iter().map(|u| {
        let u = format_ident!("{u:?}");
        quote!(super::units::Unit::#u => ::od_master::remote::Unit::#u)
    });
    let node_read = if reads.is_empty() { quote!() } else { quote!(let node = self.node.id();) };
    quote! {
        impl Remote {
            /// The device's unit conversions for the unit system its configuration selects,
            /// from the scaling objects read over SDO.
            pub async fn #units_fn(&self) -> Result<super::units::Units, ::od_master::Error> {
                let od = self.#scaling().await?;
                super::units::Units::from_dictionary(&od).map_err(|e| ::od_master::Error::Unit {
                    node: self.node.id(),
                    index: 0,
                    sub: 0,
                    error: unit_error(e),
                })
            }
            /// The device's unit conversions for `system`, from the scaling objects read over SDO.
            pub async fn #units_with(&self, system: super::units::System) -> Result<super::units::Units, ::od_master::Error> {
                let od = self.#scaling().await?;
                super::units::Units::with_system(system, &od).map_err(|e| ::od_master::Error::Unit {
                    node: self.node.id(),
                    index: 0,
                    sub: 0,
                    error: unit_error(e),
                })
            }
            /// A dictionary holding the device's scaling objects as read from it.
            async fn #scaling(&self) -> Result<super::Dictionary, ::od_master::Error> {
                #[allow(unused_mut)]
                let mut od = super::Dictionary::new(self.node.id());
                #node_read
                #(#reads)*
                Ok(od)
            }
        }
        fn unit_error(e: super::units::UnitError) -> #r::UnitError {
            use super::units::UnitError as E;
            match e {
                E::ZeroFactor { index } => #r::UnitError::ZeroFactor { index },
                E::Overflow => #r::UnitError::Overflow,
                E::NoUnit => #r::UnitError::NoUnit,
                E::WrongUnit { expected, got } => #r::UnitError::WrongUnit { expected: unit_out(expected), got: unit_out(got) },
                E::OutOfRange | E::Rejected(_) => #r::UnitError::OutOfRange,
            }
        }
        fn dimension(d: ::od_master::remote::Dimension) -> Option<super::units::Dimension> {
            match d {
                #(#dim_arms,)*
                #[allow(unreachable_patterns)]
                _ => None,
            }
        }
        fn unit_in(u: ::od_master::remote::Unit) -> Option<super::units::Unit> {
            match u {
                #(#unit_in,)*
                #[allow(unreachable_patterns)]
                _ => None,
            }
        }
        fn unit_out(u: super::units::Unit) -> ::od_master::remote::Unit {
            match u {
                #(#unit_out,)*
            }
        }
        impl #r::Scaling for super::units::Units {
            fn to_raw(&self, d: ::od_master::remote::Dimension, value: super::units::Ratio, unit: ::od_master::remote::Unit) -> Result<i64, #r::UnitError> {
                let dim = dimension(d).ok_or(#r::UnitError::NoUnit)?;
                let expected = self.unit(dim).ok_or(#r::UnitError::NoUnit)?;
                let unit = unit_in(unit).ok_or(#r::UnitError::WrongUnit { expected: unit_out(expected), got: unit })?;
                self.to_raw(dim, super::units::Quantity::new(value, unit)).map_err(unit_error)
            }
            fn to_physical(&self, d: ::od_master::remote::Dimension, raw: i64) -> Result<(super::units::Ratio, ::od_master::remote::Unit), #r::UnitError> {
                let dim = dimension(d).ok_or(#r::UnitError::NoUnit)?;
                let q = self.to_physical(dim, raw).map_err(unit_error)?;
                Ok((q.value, unit_out(q.unit)))
            }
        }
    }
}
