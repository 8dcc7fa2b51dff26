//! The object-dictionary half of the emitter: index constants, the entry table, the storage
//! struct with typed accessors, and the `ObjectDictionary` implementation.

use eds::model::{Access, DataType, Model};
use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use crate::entry::{display_name, location, rust_type};
use crate::lit;
use crate::plan::{Def, PEntry, Plan, Ty};
use crate::support::rt;
use crate::text::{Nest, Parts, Text, fits, pretty};

fn data_type_variant(dt: DataType) -> proc_macro2::Ident {
    format_ident!("{}", data_type_name(dt))
}

fn data_type_name(dt: DataType) -> &'static str {
    use DataType as D;
    match dt {
        D::Boolean => "Boolean",
        D::Integer8 => "Integer8",
        D::Integer16 => "Integer16",
        D::Integer32 => "Integer32",
        D::Unsigned8 => "Unsigned8",
        D::Unsigned16 => "Unsigned16",
        D::Unsigned32 => "Unsigned32",
        D::Real32 => "Real32",
        D::VisibleString => "VisibleString",
        D::OctetString => "OctetString",
        D::UnicodeString => "UnicodeString",
        D::TimeOfDay => "TimeOfDay",
        D::TimeDifference => "TimeDifference",
        D::Domain => "Domain",
        D::Integer24 => "Integer24",
        D::Real64 => "Real64",
        D::Integer40 => "Integer40",
        D::Integer48 => "Integer48",
        D::Integer56 => "Integer56",
        D::Integer64 => "Integer64",
        D::Unsigned24 => "Unsigned24",
        D::Unsigned40 => "Unsigned40",
        D::Unsigned48 => "Unsigned48",
        D::Unsigned56 => "Unsigned56",
        D::Unsigned64 => "Unsigned64",
        // The planner drops `Other` types; this arm keeps the function total.
        D::Other(_) => "Domain",
    }
}

fn access_variant(a: Access) -> proc_macro2::Ident {
    format_ident!("{}", access_name(a))
}

fn access_name(a: Access) -> &'static str {
    match a {
        Access::Ro => "Ro",
        Access::Wo => "Wo",
        Access::Rw => "Rw",
        Access::Rwr => "Rwr",
        Access::Rww => "Rww",
        Access::Const => "Const",
    }
}

fn default_text(e: &PEntry<'_>) -> String {
    match &e.default {
        Def::None => "none (zero)".to_owned(),
        Def::Int(v, _) => match e.ty {
            Ty::Bool => (*v != 0).to_string(),
            _ if *v >= 0x100 && !e.dt.is_signed() => format!("{v} (0x{v:X})"),
            _ => v.to_string(),
        },
        Def::NodeId(o, _) => format!("$NODEID + 0x{o:X}"),
        Def::Real(f) => f.to_string(),
        Def::Bytes(b) => match std::str::from_utf8(b) {
            Ok(s) if e.dt == DataType::VisibleString => format!("\"{s}\""),
            _ => format!("{} bytes", b.len()),
        },
    }
}

fn entry_doc(e: &PEntry<'_>, what: &str, sidecar: Option<&crate::sidecar::Sidecar>) -> Vec<String> {
    let mut lines = vec![format!("{what} {} {}.", location(e), lit::doc_escape(&display_name(e)))];
    if let Some(d) = &e.description {
        lines.push(String::new());
        lines.push(lit::doc_escape(d));
    }
    lines.push(String::new());
    let mut facts = format!(
        "{}, access `{}`{}. Default: {}.",
        e.dt.name(),
        e.entry.access.as_str(),
        if e.entry.pdo_mapping { ", PDO-mappable" } else { "" },
        lit::doc_escape(&default_text(e))
    );
    match (e.low, e.high) {
        (Some(l), Some(h)) => facts.push_str(&format!(" Range {l}..={h}.")),
        (Some(l), None) => facts.push_str(&format!(" At least {l}.")),
        (None, Some(h)) => facts.push_str(&format!(" At most {h}.")),
        _ => {}
    }
    if let Ty::Bytes(n) = e.ty {
        facts.push_str(&format!(" Capacity {n} bytes."));
    }
    lines.push(facts);
    if let Some(d) = e.entry.denotation().map(str::trim).filter(|d| !d.is_empty()) {
        lines.push(String::new());
        lines.push(format!("Vendor parameter: `{}`.", d.replace('`', "'")));
    }
    if let Some(sc) = sidecar {
        if let Some(dim) = sc.dimension_of(e.index, e.sub) {
            lines.push(String::new());
            lines.push(format!("Dimension: {dim:?} (typed conversion: `units::Units::{}`).", e.field));
        }
        let r = |sub| crate::sidecar::ObjRef { index: e.index, sub };
        if let Some(b) = sc.bus_scaling.get(&r(Some(e.sub))).or_else(|| sc.bus_scaling.get(&r(None))) {
            lines.push(String::new());
            lines.push(match b {
                crate::sidecar::BusScaling::Factor(f) => {
                    format!("Bus scaling {f}:1 (bus value = vendor tool value × {f}).")
                }
                crate::sidecar::BusScaling::Variable => "Bus scaling: variable (depends on other settings).".to_owned(),
            });
        }
    }
    lines
}

/// `pub mod index { pub const CONTROLWORD: u16 = 0x6040; … }`, as text (a constant's line
/// has no place prettyplease could break it).
pub(crate) fn index_consts(plan: &Plan<'_>, parts: &mut Parts) -> TokenStream {
    let mut t = Text::with_capacity(plan.objects.len() * 100 + 100);
    t.doc(4, &["The index of every object, named after its `ParameterName`.".to_owned()]);
    if plan.objects.is_empty() {
        t.line(4, &["pub mod index {}"]);
        return parts.put(t.out);
    }
    t.line(4, &["pub mod index {"]);
    for o in &plan.objects {
        t.doc(8, &[format!("`0x{:04X}` {}.", o.obj.index.0, lit::doc_escape(o.obj.name.trim()))]);
        t.line(8, &["pub const ", &o.konst, ": u16 = ", &format!("0x{:04X}", o.obj.index.0), ";"]);
    }
    t.line(4, &["}"]);
    parts.put(t.out)
}

/// An `i64` literal holding `v`'s low 64 bits (an UNSIGNED64 above `i64::MAX` as its bits:
/// a default is encoded by truncation, so the bytes are the same).
fn int64(v: i128, hex: bool) -> TokenStream {
    match i64::try_from(v) {
        Ok(_) => lit::int_radix(v, hex),
        Err(_) => {
            let lit = syn::LitInt::new(&format!("0x{:016X}u64", v as u64), proc_macro2::Span::call_site());
            quote!((#lit as i64))
        }
    }
}

fn default_value_tokens(e: &PEntry<'_>) -> TokenStream {
    match &e.default {
        Def::None => quote!(::od_runtime::od::DefaultValue::None),
        Def::Int(v, hex) => {
            let v = int64(*v, *hex);
            quote!(::od_runtime::od::DefaultValue::Int(::od_runtime::od::Bits64::int(#v)))
        }
        Def::NodeId(o, hex) => {
            let o = int64(*o, *hex);
            quote!(::od_runtime::od::DefaultValue::NodeIdPlus(::od_runtime::od::Bits64::int(#o)))
        }
        Def::Real(f) if e.dt == DataType::Real32 => {
            let f = lit::real(*f, true);
            quote!(::od_runtime::od::DefaultValue::Real32(#f))
        }
        Def::Real(f) => {
            let f = lit::real(*f, false);
            quote!(::od_runtime::od::DefaultValue::Real64(::od_runtime::od::Bits64::real(#f)))
        }
        Def::Bytes(b) => {
            let b = lit::bytes(b);
            quote!(::od_runtime::od::DefaultValue::Bytes(#b))
        }
    }
}

/// Whether a default restores to zero bytes (then the entry needs no default in its extras).
fn zero_default(e: &PEntry<'_>) -> bool {
    match &e.default {
        Def::None => true,
        Def::Int(v, _) => *v == 0,
        Def::Real(f) => f.to_bits() == 0,
        Def::Bytes(b) => b.is_empty(),
        Def::NodeId(..) => false,
    }
}

/// The limits of an entry, if it has any.
fn limits_tokens(e: &PEntry<'_>) -> Option<TokenStream> {
    if e.low.is_none() && e.high.is_none() {
        return None;
    }
    // The side without a limit is the type's end (a bound that refuses nothing).
    let bits = e.bits.clamp(1, 64);
    let (min, max) =
        if e.dt.is_signed() { (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1) } else { (0, (1i128 << bits) - 1) };
    let low = int64(e.low.unwrap_or(min), false);
    let high = int64(e.high.unwrap_or(max), false);
    Some(quote!(::od_runtime::od::Limits { low: #low, high: #high }))
}

/// The extras of an entry (capacity, default, the position of its limits in `LIMITS`), if it
/// has any.
fn extras_tokens(e: &PEntry<'_>, limits: Option<usize>) -> Option<TokenStream> {
    let bits = if let Ty::Bytes(_) = e.ty { e.bits } else { 0 };
    if bits == 0 && limits.is_none() && zero_default(e) {
        return None;
    }
    let default = if zero_default(e) { quote!(::od_runtime::od::DefaultValue::None) } else { default_value_tokens(e) };
    let bits = proc_macro2::Literal::u32_unsuffixed(bits);
    let limits = match limits {
        Some(i) => {
            let i = proc_macro2::Literal::usize_unsuffixed(i);
            quote!(Some(&LIMITS[#i]))
        }
        None => quote!(None),
    };
    Some(quote!(::od_runtime::od::EntryExtras { bits: #bits, default: #default, limits: #limits }))
}

/// Each distinct value of `items` once: the values, and each item's position among them.
/// Values are told apart by their tokens with every integer literal read as a number, so
/// `1` and `0x1` are one value.
fn dedup(items: impl Iterator<Item = Option<TokenStream>>) -> (Vec<TokenStream>, Vec<Option<usize>>) {
    fn canonical(t: TokenStream, out: &mut String) {
        for tt in t {
            match tt {
                proc_macro2::TokenTree::Group(g) => {
                    out.push('(');
                    canonical(g.stream(), out);
                    out.push(')');
                }
                proc_macro2::TokenTree::Literal(l) => {
                    let text = l.to_string();
                    match syn::parse_str::<syn::LitInt>(&text).ok().and_then(|i| i.base10_parse::<u128>().ok()) {
                        Some(v) => out.push_str(&v.to_string()),
                        None => out.push_str(&text),
                    }
                    out.push(' ');
                }
                other => {
                    out.push_str(&other.to_string());
                    out.push(' ');
                }
            }
        }
    }
    let mut keys: Vec<String> = Vec::new();
    let mut values = Vec::new();
    let positions = items
        .map(|t| {
            t.map(|t| {
                let mut key = String::new();
                canonical(t.clone(), &mut key);
                match keys.iter().position(|k| *k == key) {
                    Some(i) => i,
                    None => {
                        keys.push(key);
                        values.push(t);
                        values.len() - 1
                    }
                }
            })
        })
        .collect();
    (values, positions)
}

/// `LOOKUP` and `ENTRIES`.
pub(crate) fn tables(
    plan: &Plan<'_>,
    names: &crate::Names,
    sink: &mut crate::diag::Sink,
    parts: &mut Parts,
) -> TokenStream {
    let keys: Vec<(u16, u8)> = plan.entries.iter().map(|e| (e.index, e.sub)).collect();
    let lookup = crate::lookup::tokens(&keys).unwrap_or_else(|| {
        sink.general(
            eds::diag::Severity::Error,
            crate::diag::TOO_MANY_OBJECTS,
            format!(
                "the device has more than {} objects, or objects in more than {} ranges of 256 \
                 indices; the generated lookup table cannot number them",
                crate::lookup::MAX_OBJECTS,
                crate::lookup::MAX_PAGES
            ),
        );
        crate::lookup::tokens(&[]).unwrap_or_default()
    });
    // Each distinct limits and extras value once; entries point at theirs.
    let (limits, limits_of) = dedup(plan.entries.iter().map(limits_tokens));
    let (extras, extras_of) = dedup(plan.entries.iter().zip(&limits_of).map(|(e, l)| extras_tokens(e, *l)));
    if extras.len() > od_runtime::__private_v3::MAX_EXTRAS {
        sink.general(
            eds::diag::Severity::Error,
            crate::diag::TOO_MANY_OBJECTS,
            format!(
                "the device's entries have {} distinct capacities, defaults and limits, more than the {} \
                 the generated entry table can number",
                extras.len(),
                od_runtime::__private_v3::MAX_EXTRAS
            ),
        );
    }
    let n_entries = plan.entries.len();
    let rows = {
        let doc = vec![
            "The entry table the device reads, sorted by `(index, sub)`: 8 bytes a row.".to_owned(),
            "[`ENTRIES`] is made from it.".to_owned(),
        ];
        if plan.entries.is_empty() {
            let d = crate::text::doc_tokens(&doc);
            let rt = rt();
            parts.put(pretty(quote!(#d pub static ROWS: [#rt::Row; 0] = [];), 1, Nest::Item))
        } else {
            let mut t = Text::with_capacity(plan.entries.len() * 520 + 200);
            t.doc(4, &doc);
            t.line(
                4,
                &[
                    "pub static ROWS: [::od_runtime::",
                    crate::support::RUNTIME_PRIVATE,
                    "::Row; ",
                    &n_entries.to_string(),
                    "] = [",
                ],
            );
            for (e, x) in plan.entries.iter().zip(&extras_of) {
                entry_row(&mut t, e, *x);
            }
            t.line(4, &["];"]);
            parts.put(t.out)
        }
    };
    let nx = proc_macro2::Literal::usize_unsuffixed(extras.len());
    let nl = proc_macro2::Literal::usize_unsuffixed(limits.len());
    let ne = proc_macro2::Literal::usize_unsuffixed(n_entries);
    let names = names_table(plan, names, parts);
    let rt = rt();
    quote! {
        #lookup

        #rows

        /// Metadata of every entry, sorted by `(index, sub)` (`ObjectDictionary::entries`): made
        /// from [`ROWS`] and [`EXTRAS`] at compile time. A firmware, whose device reads the rows,
        /// does not link it.
        pub static ENTRIES: [::od_runtime::od::EntryInfo; #ne] = #rt::entries(&ROWS, &EXTRAS);

        /// Capacities, defaults other than zero and limits, each distinct one once
        /// ([`EntryInfo::extras`](::od_runtime::od::EntryInfo::extras) points here).
        pub static EXTRAS: [::od_runtime::od::EntryExtras; #nx] = [#(#extras),*];

        /// The limits of the entries that have any, each distinct one once.
        pub static LIMITS: [::od_runtime::od::Limits; #nl] = [#(#limits),*];

        #names
    }
}

/// The type of an entry's field as text.
fn rust_type_text(ty: Ty) -> String {
    match ty {
        Ty::Bool => "bool".into(),
        Ty::U8 => "u8".into(),
        Ty::U16 => "u16".into(),
        Ty::U32 => "u32".into(),
        Ty::U64 => "u64".into(),
        Ty::I8 => "i8".into(),
        Ty::I16 => "i16".into(),
        Ty::I32 => "i32".into(),
        Ty::I64 => "i64".into(),
        Ty::F32 => "f32".into(),
        Ty::F64 => "f64".into(),
        Ty::Bytes(n) => format!("::od_runtime::{}::Bytes<{n}>", crate::support::RUNTIME_PRIVATE),
    }
}

/// One row of `ROWS` (an element of the array, 8 columns in), as tokens.
fn entry_row_tokens(e: &PEntry<'_>, x: Option<usize>) -> TokenStream {
    let rt = rt();
    let index = lit::hex(e.index as u64, 4);
    let sub = proc_macro2::Literal::u8_unsuffixed(e.sub);
    let dt = data_type_variant(e.dt);
    let access = access_variant(e.entry.access);
    let pdo = e.entry.pdo_mapping;
    let field = format_ident!("{}", e.field);
    let ty = rust_type(e.ty);
    let cap = proc_macro2::Literal::u32_unsuffixed(if let Ty::Bytes(_) = e.ty { e.bits } else { 0 });
    let extras = match x {
        Some(i) => {
            let i = proc_macro2::Literal::usize_unsuffixed(i);
            quote!(Some(#i))
        }
        None => quote!(None),
    };
    quote! {
        #rt::Row {
            index: #index,
            sub: #sub,
            data_type: ::od_runtime::od::DataType::#dt,
            slot: #rt::offset::<#ty>(::core::mem::offset_of!(Dictionary, #field), ::od_runtime::od::DataType::#dt, #cap),
            meta: #rt::meta(::od_runtime::od::Access::#access, #pdo, #extras),
        }
    }
}

/// One row of `ROWS` as text: the layout prettyplease gives a row (the struct literal broken
/// field by field, the `offset` call broken at its turbofish and arguments, the `offset_of!`
/// on one line, broken inside its parentheses, or broken after each argument; the `meta` call,
/// never within the margin, broken after each argument); a row whose name is too long for
/// that is laid out by prettyplease.
fn entry_row(t: &mut Text, e: &PEntry<'_>, x: Option<usize>) {
    let f = e.field.as_str();
    let one_line = fits(16 + "::core::mem::offset_of!(Dictionary, ".len() + f.len() + "),".len());
    let broken = fits(20 + "Dictionary, ".len() + f.len());
    let ty = rust_type_text(e.ty);
    if !fits(20 + f.len()) || !fits(16 + ty.len() + 1) {
        t.push(&pretty(entry_row_tokens(e, x), 2, Nest::Array));
        return;
    }
    let rt = crate::support::RUNTIME_PRIVATE;
    let dt = data_type_name(e.dt);
    let cap = if let Ty::Bytes(_) = e.ty { e.bits } else { 0 };
    t.line(8, &["::od_runtime::", rt, "::Row {"]);
    t.line(12, &["index: ", &format!("0x{:04X}", e.index), ","]);
    t.line(12, &["sub: ", &e.sub.to_string(), ","]);
    t.line(12, &["data_type: ::od_runtime::od::DataType::", dt, ","]);
    t.line(12, &["slot: ::od_runtime::", rt, "::offset::<"]);
    t.line(16, &[&ty, ","]);
    t.line(12, &[">("]);
    if one_line {
        t.line(16, &["::core::mem::offset_of!(Dictionary, ", f, "),"]);
    } else {
        t.line(16, &["::core::mem::offset_of!("]);
        if broken {
            t.line(20, &["Dictionary, ", f]);
        } else {
            t.line(20, &["Dictionary,"]);
            t.line(20, &[f]);
        }
        t.line(16, &["),"]);
    }
    t.line(16, &["::od_runtime::od::DataType::", dt, ","]);
    t.line(16, &[&cap.to_string(), ","]);
    t.line(12, &["),"]);
    t.line(12, &["meta: ::od_runtime::", rt, "::meta("]);
    t.line(16, &["::od_runtime::od::Access::", access_name(e.entry.access), ","]);
    t.line(16, &[if e.entry.pdo_mapping { "true" } else { "false" }, ","]);
    match x {
        Some(i) => t.line(16, &["Some(", &i.to_string(), "),"]),
        None => t.line(16, &["None,"]),
    }
    t.line(12, &["),"]);
    t.line(8, &["},"]);
}

/// `NAMES`, the display name of every entry in `ENTRIES` order, as the options say: always,
/// never, or behind a cargo feature of the crate the code is compiled in.
fn names_table(plan: &Plan<'_>, names: &crate::Names, parts: &mut Parts) -> TokenStream {
    let cfg = match names {
        crate::Names::Never => return TokenStream::new(),
        crate::Names::Always => None,
        crate::Names::Feature(f) => Some(f),
    };
    let doc = vec![
        "The name of every entry (`ParameterName`, `Object: Sub-object` for sub-entries), in".to_owned(),
        "[`ENTRIES`] order.".to_owned(),
    ];
    let n = plan.entries.len().to_string();
    let all: Vec<String> =
        plan.entries.iter().map(|e| proc_macro2::Literal::string(&display_name(e)).to_string()).collect();
    let head = format!("pub static NAMES: [&str; {n}] = [");
    // On one line when it fits: then prettyplease lays it out.
    // `["a", "b"];`: each name and `, ` but the last.
    let one_line = 4 + head.len() + all.iter().map(|s| s.len() + 2).sum::<usize>() - 2 + "];".len();
    if fits(one_line) {
        let d = crate::text::doc_tokens(&doc);
        let cfg = cfg.map(|f| quote!(#[cfg(feature = #f)]));
        let n = proc_macro2::Literal::usize_unsuffixed(plan.entries.len());
        let all = plan.entries.iter().map(display_name);
        return parts.put(pretty(quote!(#d #cfg pub static NAMES: [&str; #n] = [#(#all),*];), 1, Nest::Item));
    }
    let mut t = Text::with_capacity(one_line + all.len() * 12 + 200);
    t.doc(4, &doc);
    if let Some(f) = cfg {
        t.line(4, &["#[cfg(feature = ", &proc_macro2::Literal::string(f).to_string(), ")]"]);
    }
    t.line(4, &[&head]);
    for s in &all {
        t.line(8, &[s, ","]);
    }
    t.line(4, &["];"]);
    parts.put(t.out)
}

fn init_expr(e: &PEntry<'_>) -> TokenStream {
    let rt = rt();
    match (&e.default, e.ty) {
        (Def::Bytes(b), Ty::Bytes(_)) => {
            let b = lit::bytes(b);
            quote!(#rt::Bytes::from_slice(#b))
        }
        (_, Ty::Bytes(_)) => quote!(#rt::Bytes::from_slice(&[])),
        (Def::Int(v, hex), t) if t.is_int() => lit::int_radix(*v, *hex),
        (Def::Int(v, _), t) => lit::int_of(*v, t),
        (Def::Real(f), Ty::F32) => lit::real(*f, true),
        (Def::Real(f), Ty::F64) => lit::real(*f, false),
        (Def::NodeId(o, hex), Ty::Bool) => {
            let o = lit::int_radix(*o, *hex);
            quote!((#o + node_id as i128) != 0)
        }
        (Def::NodeId(o, hex), t) => {
            let o = lit::int_radix(*o, *hex);
            let ty = rust_type(t);
            quote!((#o + node_id as i128) as #ty)
        }
        (_, t) => lit::int_of(0, t),
    }
}

fn setter_doc(e: &PEntry<'_>) -> Vec<String> {
    vec![format!(
        "Sets {} {} (see [`Self::{}`]): limits are checked, the access type is not (the bus side, \
         `bus_write`, checks it).",
        location(e),
        lit::doc_escape(&display_name(e)),
        e.field
    )]
}

fn setter(e: &PEntry<'_>) -> TokenStream {
    let field = format_ident!("{}", e.field);
    let set = format_ident!("set_{}", e.field);
    let doc = crate::text::doc_tokens(&setter_doc(e));
    let ty = rust_type(e.ty);
    if let Ty::Bytes(_) = e.ty {
        return quote! {
            #doc
            pub fn #set(&mut self, v: &[u8]) -> Result<(), ::od_runtime::od::AbortCode> {
                self.#field.set(v)
            }
        };
    }
    let mut checks = TokenStream::new();
    if e.ty.is_real() {
        let is32 = e.ty == Ty::F32;
        if let Some(l) = e.real_low {
            let l = lit::real(l, is32);
            checks.extend(quote!(if v < #l { return Err(::od_runtime::od::AbortCode::VALUE_TOO_LOW); }));
        }
        if let Some(h) = e.real_high {
            let h = lit::real(h, is32);
            checks.extend(quote!(if v > #h { return Err(::od_runtime::od::AbortCode::VALUE_TOO_HIGH); }));
        }
    } else if e.ty.is_int() {
        if let Some(l) = e.set_low {
            let l = lit::int(l);
            checks.extend(quote!(if v < #l { return Err(::od_runtime::od::AbortCode::VALUE_TOO_LOW); }));
        }
        if let Some(h) = e.set_high {
            let h = lit::int(h);
            checks.extend(quote!(if v > #h { return Err(::od_runtime::od::AbortCode::VALUE_TOO_HIGH); }));
        }
    }
    quote! {
        #doc
        #[inline]
        pub fn #set(&mut self, v: #ty) -> Result<(), ::od_runtime::od::AbortCode> {
            #checks
            self.#field = v;
            Ok(())
        }
    }
}

fn getter(e: &PEntry<'_>, sidecar: Option<&crate::sidecar::Sidecar>) -> TokenStream {
    let field = format_ident!("{}", e.field);
    let doc = crate::text::doc_tokens(&entry_doc(e, "Reads", sidecar));
    match e.ty {
        Ty::Bytes(_) => quote! {
            #doc
            #[inline]
            pub fn #field(&self) -> &[u8] {
                self.#field.as_slice()
            }
        },
        t => {
            let ty = rust_type(t);
            quote! {
                #doc
                #[inline]
                pub const fn #field(&self) -> #ty {
                    self.#field
                }
            }
        }
    }
}

/// An integer literal as text, as [`lit::int`] writes it and prettyplease prints it.
fn int_text(v: i128) -> String {
    if v < 0 { format!("-{}", v.unsigned_abs()) } else { v.to_string() }
}

/// [`lit::int_radix`] as text.
fn int_radix_text(v: i128, hex: bool) -> String {
    if hex && v >= 0 { format!("0x{v:X}") } else { int_text(v) }
}

/// [`lit::real`] as text.
fn real_text(f: f64, is32: bool) -> String {
    let t = if is32 { "f32" } else { "f64" };
    let f = if is32 && !f.is_nan() { (f as f32) as f64 } else { f };
    if f.is_nan() {
        return format!("{t}::NAN");
    }
    if f.is_infinite() {
        return if f > 0.0 { format!("{t}::INFINITY") } else { format!("{t}::NEG_INFINITY") };
    }
    let a = if is32 {
        proc_macro2::Literal::f32_unsuffixed((f as f32).abs())
    } else {
        proc_macro2::Literal::f64_unsuffixed(f.abs())
    };
    if f.is_sign_negative() { format!("-{a}") } else { a.to_string() }
}

/// [`lit::int_of`] as text.
fn int_of_text(v: i128, ty: Ty) -> String {
    match ty {
        Ty::Bool => (v != 0).to_string(),
        Ty::F32 => real_text(v as f64, true),
        Ty::F64 => real_text(v as f64, false),
        _ => int_text(v),
    }
}

/// [`init_expr`] as text.
fn init_text(e: &PEntry<'_>) -> String {
    let rt = crate::support::RUNTIME_PRIVATE;
    match (&e.default, e.ty) {
        (Def::Bytes(b), Ty::Bytes(_)) => {
            format!("::od_runtime::{rt}::Bytes::from_slice({})", proc_macro2::Literal::byte_string(b))
        }
        (_, Ty::Bytes(_)) => format!("::od_runtime::{rt}::Bytes::from_slice(&[])"),
        (Def::Int(v, hex), t) if t.is_int() => int_radix_text(*v, *hex),
        (Def::Int(v, _), t) => int_of_text(*v, t),
        (Def::Real(f), Ty::F32) => real_text(*f, true),
        (Def::Real(f), Ty::F64) => real_text(*f, false),
        (Def::NodeId(o, hex), Ty::Bool) => format!("({} + node_id as i128) != 0", int_radix_text(*o, *hex)),
        (Def::NodeId(o, hex), t) => {
            format!("({} + node_id as i128) as {}", int_radix_text(*o, *hex), rust_type_text(t))
        }
        (_, t) => int_of_text(0, t),
    }
}

/// The zero of an entry's field, as tokens and as text (`zeroed`).
fn zero_expr(e: &PEntry<'_>) -> (TokenStream, String) {
    match e.ty {
        Ty::Bytes(_) => {
            let rt = rt();
            (
                quote!(#rt::Bytes::from_slice(&[])),
                format!("::od_runtime::{}::Bytes::from_slice(&[])", crate::support::RUNTIME_PRIVATE),
            )
        }
        t => (lit::int_of(0, t), int_of_text(0, t)),
    }
}

/// A `const fn` of `Dictionary` (8 columns in) whose body is the struct literal of `inits`
/// (`new`, `zeroed`): as text when the literal is too long for one line and each field fits
/// one, else through prettyplease.
fn constructor(doc: &[String], sig: &str, inits: &[(&str, String)], tokens: impl FnOnce() -> TokenStream) -> String {
    let one_line = 12 + "Dictionary { ".len() + inits.iter().map(|(f, v)| f.len() + 2 + v.len() + 2).sum::<usize>() - 2
        + " }".len();
    if fits(one_line) || !inits.iter().all(|(f, v)| fits(16 + f.len() + 2 + v.len() + 1)) {
        return pretty(tokens(), 2, Nest::Impl);
    }
    let mut t = Text::with_capacity(one_line + inits.len() * 20 + 200);
    t.doc(8, doc);
    t.line(8, &[sig]);
    t.line(12, &["Dictionary {"]);
    for (f, v) in inits {
        t.line(16, &[f, ": ", v, ","]);
    }
    t.line(12, &["}"]);
    t.line(8, &["}"]);
    t.out
}

/// The getter of an entry as text (8 columns in), or through prettyplease when its signature
/// comes near the margin.
fn getter_text(t: &mut Text, e: &PEntry<'_>, sidecar: Option<&crate::sidecar::Sidecar>) {
    let f = e.field.as_str();
    let n = f.len();
    let (sig, body) = match e.ty {
        Ty::Bytes(_) => {
            (8 + "pub fn ".len() + n + "(&self) -> &[u8] {".len(), 12 + "self.".len() + n + ".as_slice()".len())
        }
        ty => (8 + "pub const fn ".len() + n + "(&self) -> ".len() + rust_type_text(ty).len() + " {".len(), 12 + 5 + n),
    };
    if !fits(sig) || !fits(body) {
        t.push(&pretty(getter(e, sidecar), 2, Nest::Impl));
        return;
    }
    t.doc(8, &entry_doc(e, "Reads", sidecar));
    t.line(8, &["#[inline]"]);
    match e.ty {
        Ty::Bytes(_) => {
            t.line(8, &["pub fn ", f, "(&self) -> &[u8] {"]);
            t.line(12, &["self.", f, ".as_slice()"]);
        }
        ty => {
            t.line(8, &["pub const fn ", f, "(&self) -> ", &rust_type_text(ty), " {"]);
            t.line(12, &["self.", f]);
        }
    }
    t.line(8, &["}"]);
}

/// The setter of an entry as text (8 columns in): the signature on one line or broken after
/// each parameter; through prettyplease when it comes near the margin.
fn setter_text(t: &mut Text, e: &PEntry<'_>) {
    const RESULT: &str = ") -> Result<(), ::od_runtime::od::AbortCode> {";
    let f = e.field.as_str();
    let n = f.len();
    let ty = match e.ty {
        Ty::Bytes(_) => "&[u8]".to_owned(),
        ty => rust_type_text(ty),
    };
    let one_line = 8 + "pub fn set_".len() + n + "(&mut self, v: ".len() + ty.len() + RESULT.len();
    let mut checks: Vec<(&str, String, &str)> = Vec::new();
    if e.ty.is_real() {
        let is32 = e.ty == Ty::F32;
        if let Some(l) = e.real_low {
            checks.push(("<", real_text(l, is32), "VALUE_TOO_LOW"));
        }
        if let Some(h) = e.real_high {
            checks.push((">", real_text(h, is32), "VALUE_TOO_HIGH"));
        }
    } else if e.ty.is_int() {
        if let Some(l) = e.set_low {
            checks.push(("<", int_text(l), "VALUE_TOO_LOW"));
        }
        if let Some(h) = e.set_high {
            checks.push((">", int_text(h), "VALUE_TOO_HIGH"));
        }
    }
    let body_fits = fits(12 + "self.".len() + n + ".set(v)".len().max(" = v;".len()))
        && checks.iter().all(|(_, v, _)| fits(12 + "if v < ".len() + v.len() + " {".len()));
    let broken_fits = fits(8 + "pub fn set_".len() + n + 1) && fits(12 + "v: ".len() + ty.len() + 1);
    if !body_fits || !(fits(one_line) || broken_fits) {
        t.push(&pretty(setter(e), 2, Nest::Impl));
        return;
    }
    t.doc(8, &setter_doc(e));
    if !matches!(e.ty, Ty::Bytes(_)) {
        t.line(8, &["#[inline]"]);
    }
    if fits(one_line) {
        t.line(8, &["pub fn set_", f, "(&mut self, v: ", &ty, RESULT]);
    } else {
        t.line(8, &["pub fn set_", f, "("]);
        t.line(12, &["&mut self,"]);
        t.line(12, &["v: ", &ty, ","]);
        t.line(8, &[RESULT]);
    }
    if let Ty::Bytes(_) = e.ty {
        t.line(12, &["self.", f, ".set(v)"]);
    } else {
        for (op, v, code) in &checks {
            t.line(12, &["if v ", op, " ", v, " {"]);
            t.line(16, &["return Err(::od_runtime::od::AbortCode::", code, ");"]);
            t.line(12, &["}"]);
        }
        t.line(12, &["self.", f, " = v;"]);
        t.line(12, &["Ok(())"]);
    }
    t.line(8, &["}"]);
}

/// The `Dictionary` struct: one field per entry, written as text when every field fits the
/// margin.
fn dictionary_struct(model: &Model, plan: &Plan<'_>, parts: &mut Parts) -> TokenStream {
    let product = model.device_info.product_name.as_deref().unwrap_or("device");
    let vendor = model.device_info.vendor_name.as_deref().unwrap_or("unknown vendor");
    let struct_doc = vec![
        format!(
            "The object dictionary of the {} ({}): the current value of every entry.",
            lit::doc_escape(product),
            lit::doc_escape(vendor)
        ),
        String::new(),
        "Build it with [`Dictionary::new`]; read and write entries with the typed accessors (the \
         application side) or through [`ObjectDictionary`](::od_runtime::od::ObjectDictionary) \
         (the bus side, as little-endian bytes)."
            .to_owned(),
    ];

    let types: Vec<String> = plan.entries.iter().map(|e| rust_type_text(e.ty)).collect();
    let struct_item = if !plan.entries.is_empty()
        && plan.entries.iter().zip(&types).all(|(e, ty)| fits(8 + e.field.len() + 2 + ty.len() + 1))
    {
        let mut t = Text::with_capacity(plan.entries.len() * 50 + 400);
        t.doc(4, &struct_doc);
        t.line(4, &["#[derive(Clone, Debug, PartialEq)]"]);
        t.line(4, &["pub struct Dictionary {"]);
        for (e, ty) in plan.entries.iter().zip(&types) {
            t.line(8, &[&e.field, ": ", ty, ","]);
        }
        t.line(4, &["}"]);
        t.out
    } else {
        let doc = crate::text::doc_tokens(&struct_doc);
        let fields = plan.entries.iter().map(|e| {
            let f = format_ident!("{}", e.field);
            let ty = rust_type(e.ty);
            quote!(#f: #ty)
        });
        pretty(
            quote! {
                #doc
                #[derive(Clone, Debug, PartialEq)]
                pub struct Dictionary {
                    #(#fields,)*
                }
            },
            1,
            Nest::Item,
        )
    };
    parts.put(struct_item)
}

/// `Dictionary::new(node_id)`: every entry at its default, `$NODEID` resolved.
fn constructor_new(plan: &Plan<'_>, parts: &mut Parts) -> TokenStream {
    let uses_node_id = plan.entries.iter().any(|e| matches!(e.default, Def::NodeId(..)));
    let node_id = if uses_node_id { format_ident!("node_id") } else { format_ident!("_node_id") };
    let new_doc = vec!["A dictionary holding every entry's default, with `$NODEID` resolved for `node_id`.".to_owned()];
    let inits: Vec<(&str, String)> = plan.entries.iter().map(|e| (e.field.as_str(), init_text(e))).collect();
    let new_fn = constructor(&new_doc, &format!("pub const fn new({node_id}: u8) -> Self {{"), &inits, || {
        let doc = crate::text::doc_tokens(&new_doc);
        let inits = plan.entries.iter().map(|e| {
            let f = format_ident!("{}", e.field);
            let v = init_expr(e);
            quote!(#f: #v)
        });
        quote! {
            #doc
            pub const fn new(#node_id: u8) -> Self {
                Dictionary { #(#inits,)* }
            }
        }
    });
    parts.put(new_fn)
}

/// `Dictionary::zeroed()`: every value zero, every buffer empty.
fn constructor_zeroed(plan: &Plan<'_>, parts: &mut Parts) -> TokenStream {
    let zeroed_doc = vec![
        "Every value zero, every buffer empty. A device's first poll (its reset node)".to_owned(),
        "restores the defaults, so a firmware can start from this: its device then".to_owned(),
        "needs no image of the defaults in flash besides the entry table's.".to_owned(),
    ];
    let zeros: Vec<(&str, String)> = plan.entries.iter().map(|e| (e.field.as_str(), zero_expr(e).1)).collect();
    let zeroed_fn = constructor(&zeroed_doc, "pub const fn zeroed() -> Self {", &zeros, || {
        let doc = crate::text::doc_tokens(&zeroed_doc);
        let zeros = plan.entries.iter().map(|e| {
            let f = format_ident!("{}", e.field);
            let v = zero_expr(e).0;
            quote!(#f: #v)
        });
        quote! {
            #doc
            pub const fn zeroed() -> Self {
                Dictionary { #(#zeros,)* }
            }
        }
    });
    parts.put(zeroed_fn)
}

/// The statement of `write_at` that gives `(real_low, real_high)`, the REAL limits of the entry
/// at `pos`.
fn real_limits(plan: &Plan<'_>) -> TokenStream {
    let real_limited: Vec<&PEntry<'_>> =
        plan.entries.iter().filter(|e| e.real_low.is_some() || e.real_high.is_some()).collect();
    if real_limited.is_empty() {
        quote!(let (real_low, real_high) = (None, None);)
    } else {
        let arms = plan.entries.iter().enumerate().filter(|(_, e)| e.real_low.is_some() || e.real_high.is_some()).map(
            |(i, e)| {
                let i = proc_macro2::Literal::usize_unsuffixed(i);
                let o = |v: Option<f64>| match v {
                    Some(f) => {
                        let f = lit::real(f, false);
                        quote!(Some(#f))
                    }
                    None => quote!(None),
                };
                let (l, h) = (o(e.real_low), o(e.real_high));
                quote!(#i => (#l, #h))
            },
        );
        quote!(let (real_low, real_high) = match pos { #(#arms,)* _ => (None, None) };)
    }
}

/// `ObjectDictionary::name`, as `names` asks (never, always, or behind a feature).
fn name_fn(names: &crate::Names) -> TokenStream {
    {
        let body = quote! {
            fn name(&self, index: u16, sub: u8) -> Option<&'static str> {
                Self::position(index, sub).ok().and_then(|pos| NAMES.get(pos).copied())
            }
        };
        match names {
            crate::Names::Never => TokenStream::new(),
            crate::Names::Always => body,
            crate::Names::Feature(f) => quote!(#[cfg(feature = #f)] #body),
        }
    }
}

/// Every entry's getter and setter, as text.
fn accessors(plan: &Plan<'_>, sidecar: Option<&crate::sidecar::Sidecar>, parts: &mut Parts) -> TokenStream {
    if plan.entries.is_empty() {
        TokenStream::new()
    } else {
        let mut t = Text::with_capacity(plan.entries.len() * 900);
        for e in &plan.entries {
            getter_text(&mut t, e, sidecar);
            setter_text(&mut t, e);
        }
        parts.put(t.out)
    }
}

/// `impl Dictionary`: the constructors, the look-up of an entry's position, the slot-based
/// read and write every access goes through, and the typed accessors.
fn inherent_impl(
    new_fn: TokenStream,
    zeroed_fn: TokenStream,
    real_limits: TokenStream,
    accessors: TokenStream,
) -> TokenStream {
    let rt = rt();
    quote! {
        impl Dictionary {
            #new_fn

            #zeroed_fn

            /// Position of `(index, sub)` in [`ENTRIES`]: `Err(NO_OBJECT)` if the index is absent,
            /// `Err(NO_SUB_INDEX)` if only the sub-index is.
            #[inline]
            pub fn position(index: u16, sub: u8) -> Result<usize, ::od_runtime::od::AbortCode> {
                #rt::lookup(&LOOKUP, &DIRECT, &ROWS, index, sub)
            }

            /// The value of the entry at `pos` of [`ENTRIES`], through its slot.
            #[inline(always)]
            fn slot(&self, pos: usize) -> Option<#rt::Slot<'_>> {
                #rt::slot(self, pos)
            }

            #[inline(always)]
            fn slot_mut(&mut self, pos: usize) -> Option<#rt::SlotMut<'_>> {
                #rt::slot_mut(self, pos)
            }

            /// The first 8 bytes of the entry at `pos` of [`ENTRIES`] (zeros for none): the body
            /// of `read_handle`.
            #[inline(always)]
            fn read_at(&self, pos: usize) -> [u8; 8] {
                match self.slot(pos) {
                    Some(slot) => #rt::first8(|| #rt::info_at::<Self>(pos).map_or(0, |e| e.bits()), slot),
                    None => [0; 8],
                }
            }

            /// Stores a value given as bytes into the entry at `pos` of [`ENTRIES`], after the
            /// runtime's checks (the shared body of `write` and `write_handle`; one copy of it
            /// on a microcontroller).
            #[cfg_attr(target_os = "none", inline(never))]
            #[cfg_attr(not(target_os = "none"), inline)]
            fn write_at(&mut self, pos: usize, data: &[u8]) -> Result<(), ::od_runtime::od::AbortCode> {
                #real_limits
                match (#rt::info_at::<Self>(pos), self.slot_mut(pos)) {
                    (Ok(info), Some(slot)) => #rt::write(&info, slot, data, real_low, real_high),
                    _ => Err(::od_runtime::od::AbortCode::NO_OBJECT),
                }
            }

            /// Reads like an SDO upload: as [`read`](::od_runtime::od::ObjectDictionary::read), but
            /// refuses write-only entries with `WRITE_ONLY`.
            pub fn bus_read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, ::od_runtime::od::AbortCode> {
                #rt::bus_read(self, index, sub, buf)
            }

            /// Writes like an SDO download: as [`write`](::od_runtime::od::ObjectDictionary::write),
            /// but refuses read-only and constant entries with `READ_ONLY`.
            pub fn bus_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), ::od_runtime::od::AbortCode> {
                #rt::bus_write(self, index, sub, data)
            }

            /// Checks an RPDO mapping (`0xIIIISSLL` entries) a master writes over SDO with the
            /// runtime's rules ([`check_mapping`](::od_runtime::pdo::check_mapping));
            /// returns its length in bits. Abort codes: `NOT_MAPPABLE` (0x0604_0041),
            /// `PDO_LENGTH_EXCEEDED` (0x0604_0042), `PARAMETER_INCOMPATIBLE` (0x0604_0043), and
            /// `NO_OBJECT`/`NO_SUB_INDEX` for an object the dictionary does not have.
            pub fn check_rpdo_mapping(mapping: &[u32]) -> Result<u32, ::od_runtime::od::AbortCode> {
                #rt::check_mapping(&EXTRAS, &LOOKUP, ::od_runtime::pdo::Direction::Receive, mapping)
            }

            /// Checks a TPDO mapping, like [`Dictionary::check_rpdo_mapping`].
            pub fn check_tpdo_mapping(mapping: &[u32]) -> Result<u32, ::od_runtime::od::AbortCode> {
                #rt::check_mapping(&EXTRAS, &LOOKUP, ::od_runtime::pdo::Direction::Transmit, mapping)
            }

            #accessors
        }
    }
}

/// `ObjectDictionary::SERVICES`: the optional services whose objects the dictionary has (the
/// rule of `od_runtime::od::Services::of`, which the generated devices' tests hold it to). A
/// constant, so the runtime links no code for the others. With it, `PDO_REMAPPING` when the
/// sidecar's `[pdo] remapping` is not CiA 301's (the trait's default), and with the EDS's
/// `LSS_Supported=1`, `ObjectDictionary::LSS` (the device answers LSS, CiA 305, with
/// od-runtime's `lss` feature; without it, nothing: the trait's default, no LSS).
fn services(plan: &Plan<'_>, model: &Model, sidecar: Option<&crate::sidecar::Sidecar>) -> TokenStream {
    let has = |index: u16| plan.entries.iter().any(|e| e.index == index);
    // A PDO may be synchronous without 1005h: SYNC then comes on the predefined COB-ID 80h.
    let pdos = plan.entries.iter().any(|e| matches!(e.index, 0x1400..=0x15FF | 0x1800..=0x19FF));
    let (sync, guarding, consumer, history) =
        (has(0x1005) || pdos, has(0x100C) && has(0x100D), has(0x1016), has(0x1003));
    let remapping = pdo_remapping(sidecar);
    let lss = (model.device_info.lss_supported == Some(true)).then(|| quote! { const LSS: bool = true; });
    quote! {
        const SERVICES: ::od_runtime::od::Services = ::od_runtime::od::Services {
            sync: #sync,
            node_guarding: #guarding,
            heartbeat_consumer: #consumer,
            emcy_history: #history,
        };
        #remapping
        #lss
    }
}

/// `ObjectDictionary::PDO_REMAPPING` from the sidecar, nothing for CiA 301's rule (the default).
fn pdo_remapping(sidecar: Option<&crate::sidecar::Sidecar>) -> TokenStream {
    use crate::sidecar::Remapping;
    match sidecar.map(|s| s.pdo.remapping) {
        None | Some(Remapping::Cia301) => TokenStream::new(),
        Some(Remapping::WhileValid) => quote! {
            const PDO_REMAPPING: ::od_runtime::pdo::Remapping = ::od_runtime::pdo::Remapping::WhileValid;
        },
    }
}

/// The runtime's `Table` and `ObjectDictionary` implementations for `Dictionary`.
fn trait_impls(name_fn: TokenStream, services: TokenStream) -> TokenStream {
    let rt = rt();
    quote! {
        // SAFETY: every slot in ROWS is `offset::<T>(offset_of!(Dictionary, field), …)` of
        // the entry's own field, whose type `offset` checked at compile time, with the capacity
        // of the entry's extras in EXTRAS.
        unsafe impl #rt::Table for Dictionary {
            #[inline(always)]
            fn rows() -> &'static [#rt::Row] {
                &ROWS
            }

            #[inline(always)]
            fn extras() -> &'static [::od_runtime::od::EntryExtras] {
                &EXTRAS
            }
        }

        impl ::od_runtime::od::ObjectDictionary for Dictionary {
            #services

            fn entries(&self) -> &'static [::od_runtime::od::EntryInfo] {
                &ENTRIES
            }

            #name_fn

            #[inline]
            fn info(&self, index: u16, sub: u8) -> Result<&'static ::od_runtime::od::EntryInfo, ::od_runtime::od::AbortCode> {
                let pos = Self::position(index, sub)?;
                ENTRIES.get(pos).ok_or(::od_runtime::od::AbortCode::NO_OBJECT)
            }

            // What the device reads: decoded from ROWS, so a firmware links no ENTRIES.

            // One copy on a microcontroller, where the services call it from many places.
            #[cfg_attr(target_os = "none", inline(never))]
            #[cfg_attr(not(target_os = "none"), inline)]
            fn entry(&self, index: u16, sub: u8) -> Result<::od_runtime::od::EntryInfo, ::od_runtime::od::AbortCode> {
                Self::position(index, sub).and_then(#rt::info_at::<Self>)
            }

            #[inline]
            fn entry_count(&self) -> usize {
                ROWS.len()
            }

            #[inline]
            fn entry_at(&self, pos: usize) -> Option<::od_runtime::od::EntryInfo> {
                #rt::info_at::<Self>(pos).ok()
            }

            fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, ::od_runtime::od::AbortCode> {
                let pos = Self::position(index, sub)?;
                match (#rt::info_at::<Self>(pos), self.slot(pos)) {
                    (Ok(info), Some(slot)) => #rt::read(&info, slot, buf),
                    _ => Err(::od_runtime::od::AbortCode::NO_OBJECT),
                }
            }

            fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), ::od_runtime::od::AbortCode> {
                let pos = Self::position(index, sub)?;
                self.write_at(pos, data)
            }

            fn restore_defaults(&mut self, area: ::od_runtime::od::Area, node_id: u8) {
                for (pos, row) in ROWS.iter().enumerate() {
                    if area.contains(row.index)
                        && let Some(slot) = self.slot_mut(pos)
                    {
                        #rt::set_default(&row.info(&EXTRAS), slot, node_id);
                    }
                }
            }

            // The PDO fast path: a handle is the entry's position in ROWS, so the runtime
            // reaches a mapped entry through its slot, without a lookup.

            #[inline]
            fn handle(&self, index: u16, sub: u8) -> Option<::od_runtime::od::Handle> {
                Self::position(index, sub).ok().map(|pos| ::od_runtime::od::Handle::new(pos as u32))
            }

            #[inline]
            fn read_handle(&self, h: ::od_runtime::od::Handle) -> [u8; 8] {
                self.read_at(h.get() as usize)
            }

            // The read inlined into the packing loop, one jump on the storage kind. It
            // skips `read_handle`'s cut to the entry's length (which would look the entry up):
            // the loop cuts every value to its mapped length, which a loaded mapping makes
            // the entry's own.
            #[inline]
            fn read_mapped(&self, map: &[::od_runtime::od::MappedHandle]) -> u64 {
                #rt::pack_mapped(map, |h| match self.slot(h.get() as usize) {
                    Some(slot) => #rt::first8(|| 64, slot),
                    None => [0; 8],
                })
            }

            #[inline]
            fn write_handle(&mut self, h: ::od_runtime::od::Handle, data: &[u8]) -> Result<(), ::od_runtime::od::AbortCode> {
                self.write_at(h.get() as usize, data)
            }
        }
    }
}

/// The storage struct, its inherent methods and the trait implementation.
pub(crate) fn dictionary(
    model: &Model,
    plan: &Plan<'_>,
    names: &crate::Names,
    sidecar: Option<&crate::sidecar::Sidecar>,
    parts: &mut Parts,
) -> TokenStream {
    let struct_item = dictionary_struct(model, plan, parts);
    let new_fn = constructor_new(plan, parts);
    let zeroed_fn = constructor_zeroed(plan, parts);
    let real_limits = real_limits(plan);
    let name_fn = name_fn(names);
    let accessors = accessors(plan, sidecar, parts);
    let inherent = inherent_impl(new_fn, zeroed_fn, real_limits, accessors);
    let traits = trait_impls(name_fn, services(plan, model, sidecar));
    quote! {
        #struct_item

        #inherent

        #traits
    }
}

/// What the device needs of `od_runtime::Device`, from the description: how many PDOs, how
/// many mapped entries per PDO, how large an SDO transfer can be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Capacities {
    /// PDOs per direction: `NrOfRXPDO`/`NrOfTXPDO`, or more if the file has more PDO objects.
    pub pdos: usize,
    /// Mapped entries per PDO: what the mapping objects hold (sub-objects after sub 0), but no
    /// more than 64 bits at `Granularity` allow, and never fewer than a loadable default
    /// mapping has.
    pub mapped: usize,
    /// The largest entry in bytes (at least 8): the SDO server's buffer, block transfers
    /// included (a transfer is never larger than the entry it reads or writes).
    pub sdo_buffer: usize,
}

pub(crate) fn capacities(model: &Model, plan: &Plan<'_>) -> Capacities {
    use eds::model::Role;
    let info = &model.device_info;
    let mut pdos = usize::from(info.nr_of_rx_pdo.unwrap_or(0).max(info.nr_of_tx_pdo.unwrap_or(0)));
    // Granularity g: at most 64 / g entries fit 64 bits (0 or absent: no statement, 64).
    let by_granularity = match info.granularity {
        Some(g) if g > 0 => 64 / usize::from(g),
        _ => 64,
    };
    let mut mapped = 0usize;
    let mut sdo_buffer = 8usize;
    // Per mapping object: its default count (sub 0) and the bits of its default entries.
    let mut defaults: Vec<(u16, usize, Vec<u32>)> = Vec::new();
    for e in &plan.entries {
        sdo_buffer = sdo_buffer.max((e.bits as usize).div_ceil(8));
        let role = eds::model::Index(e.index).role();
        match role {
            Role::RpdoCommunication(n) | Role::TpdoCommunication(n) | Role::RpdoMapping(n) | Role::TpdoMapping(n) => {
                pdos = pdos.max(usize::from(n) + 1);
            }
            _ => {}
        }
        if !matches!(role, Role::RpdoMapping(_) | Role::TpdoMapping(_)) {
            continue;
        }
        if defaults.last().is_none_or(|d| d.0 != e.index) {
            defaults.push((e.index, 0, Vec::new()));
        }
        let Some(d) = defaults.last_mut() else { continue };
        let value = match e.default {
            Def::Int(v, _) => usize::try_from(v).unwrap_or(0),
            _ => 0,
        };
        if e.sub == 0 {
            d.1 = value;
        } else {
            mapped = mapped.max(usize::from(e.sub).min(by_granularity));
            d.2.push(value as u32 & 0xFF);
        }
    }
    // A default mapping the device can load (its entries fit 64 bits) is kept whole, even
    // with entries shorter than the granularity.
    for (_, count, bits) in &defaults {
        let total: u32 = bits.iter().take(*count).sum();
        if *count <= bits.len() && total <= 64 {
            mapped = mapped.max(*count);
        }
    }
    Capacities { pdos: pdos.min(512), mapped: mapped.min(64), sdo_buffer }
}

/// `SDO_BUFFER`, `PDOS`, `MAPPED_PER_PDO` and the `Device` type sized with them.
pub(crate) fn device_type(model: &Model, plan: &Plan<'_>) -> TokenStream {
    let c = capacities(model, plan);
    let (buf, pdos, mapped) = (
        proc_macro2::Literal::usize_unsuffixed(c.sdo_buffer),
        proc_macro2::Literal::usize_unsuffixed(c.pdos),
        proc_macro2::Literal::usize_unsuffixed(c.mapped),
    );
    quote! {
        /// The SDO server's buffer: the largest entry, in bytes (at least 8).
        pub const SDO_BUFFER: usize = #buf;
        /// PDOs per direction the device has (`NrOfRXPDO`/`NrOfTXPDO`, or its PDO objects).
        pub const PDOS: usize = #pdos;
        /// Entries a PDO can map: the mapping objects' sub-objects, at most 64 bits at the
        /// EDS's `Granularity`.
        pub const MAPPED_PER_PDO: usize = #mapped;

        /// The device runtime around this dictionary, sized for it: [`SDO_BUFFER`], [`PDOS`],
        /// [`MAPPED_PER_PDO`]. Build it with `Device::with_capacity` (a `const fn`, so it can
        /// initialise a `static`).
        pub type Device<A, S = ::od_runtime::NoStorage> =
            ::od_runtime::Device<Dictionary, A, S, SDO_BUFFER, PDOS, MAPPED_PER_PDO>;
    }
}
