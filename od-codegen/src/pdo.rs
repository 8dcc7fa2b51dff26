//! PDO layouts: the default mappings of a device (0x1600.., 0x1A00..) checked and turned into
//! typed structs with bit-exact `pack`/`unpack`.
//!
//! One rule set: the default mappings are checked at generation time with the very function the
//! runtime applies when a master remaps over SDO (`od_runtime::pdo::check_entry` /
//! `check_mapping`, looking objects up in the dictionary exactly as it will be generated), and
//! the generated `check_rpdo_mapping`/`check_tpdo_mapping` call the same function at run time.
//! [`check_mapping`] and [`MappingChecker`] expose the generation-time form, with each refusal
//! explained in the description's terms next to the abort code the device would send.

use std::collections::BTreeMap;

use eds::diag::Severity;
use eds::model::{Entry, Model, Object, PdoMappingEntry, Role, Value};
use proc_macro2::TokenStream;
use quote::{format_ident, quote};

use od_runtime::od::AbortCode;

use crate::Options;
use crate::diag::{self, Sink};
use crate::entry::{display_name, location, rust_type, to_runtime_type};
use crate::lit;
use crate::plan::{PEntry, Plan, Ty, effective_value};

pub use od_runtime::pdo::Direction;

/// Why one mapping entry is refused, with the SDO abort code the run-time check gives for it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MappingError {
    /// The abort code `od_runtime::pdo::check_mapping` returns (0x0604_0041, 0x0604_0042,
    /// 0x0604_0043, or the lookup's 0x0602_0000 / 0x0609_0011 for a missing object).
    pub abort_code: u32,
    /// The generator's diagnostic code.
    pub code: eds::diag::Code,
    /// What is wrong.
    pub message: String,
}

/// The granularity the device declares (`Granularity=`; absent: 8, byte-wise mapping).
pub fn granularity(model: &Model) -> u8 {
    model.device_info.granularity.unwrap_or(8)
}

/// Bit `n` set when `Dummy000n=1`.
pub fn dummy_usage(model: &Model) -> u8 {
    model.dummy_usage.iter().filter(|(k, v)| **v && (1..=7).contains(*k)).fold(0u8, |acc, (k, _)| acc | (1 << *k))
}

fn to_runtime_access(a: eds::model::Access) -> od_runtime::od::Access {
    use eds::model::Access as A;
    use od_runtime::od::Access as R;
    match a {
        A::Ro => R::Ro,
        A::Wo => R::Wo,
        A::Rw => R::Rw,
        A::Rwr => R::Rwr,
        A::Rww => R::Rww,
        A::Const => R::Const,
    }
}

/// What the run-time check sees of a planned entry: exactly the generated `EntryInfo`'s fields.
fn mappable(e: &PEntry<'_>) -> od_runtime::pdo::Mappable {
    od_runtime::pdo::Mappable {
        data_type: to_runtime_type(e.dt),
        access: to_runtime_access(e.entry.access),
        pdo_mappable: e.entry.pdo_mapping,
        bits: e.bits,
    }
}

/// Explains a refusal of the run-time check in the description's terms.
fn explain(plan: &Plan<'_>, dir: Direction, raw: u32, code: AbortCode) -> MappingError {
    let m = PdoMappingEntry::from_u32(raw);
    let target = plan.entries.iter().find(|e| e.index == m.index.0 && e.sub == m.sub.0);
    let what = match target {
        Some(t) => format!("0x{:04X} sub {} \"{}\"", t.index, t.sub, display_name(t)),
        None => format!("0x{:04X} sub {}", m.index.0, m.sub.0),
    };
    let (diag_code, message) = match (code, target) {
        (AbortCode::PDO_LENGTH_EXCEEDED, _) => {
            (diag::PDO_TOO_LONG, format!("mapping {what} with {} bits takes the PDO past 64 bits", m.bits))
        }
        (AbortCode::NO_OBJECT | AbortCode::NO_SUB_INDEX, _) => {
            (diag::PDO_NO_OBJECT, format!("maps {what}, which is not in the dictionary"))
        }
        (AbortCode::NOT_MAPPABLE, None) => {
            (diag::PDO_NO_OBJECT, format!("maps dummy entry 0x{:04X}, which only receive PDOs may hold", m.index.0))
        }
        (AbortCode::NOT_MAPPABLE, Some(t)) if !t.entry.pdo_mapping => {
            (diag::PDO_NOT_MAPPABLE, format!("maps {what}, which has PDOMapping=0"))
        }
        (AbortCode::NOT_MAPPABLE, Some(t)) => {
            let (dir_name, allowed) = match dir {
                Direction::Receive => ("an RPDO", "wo, rw or rww"),
                Direction::Transmit => ("a TPDO", "ro, rw, rwr or const"),
            };
            (
                diag::PDO_ACCESS,
                format!("maps {what} with access `{}` into {dir_name}, which needs {allowed}", t.entry.access.as_str()),
            )
        }
        (_, Some(t)) => (
            diag::PDO_LENGTH,
            format!(
                "maps {what} ({}, {} bits) with a length of {} bits",
                t.dt.name(),
                if t.dt.bits().is_some() { t.bits.to_string() } else { format!("up to {}", t.bits) },
                m.bits
            ),
        ),
        (_, None) => (
            diag::PDO_LENGTH,
            format!(
                "maps dummy entry 0x{:04X} with a length of {} bits that does not match its type",
                m.index.0, m.bits
            ),
        ),
    };
    MappingError { abort_code: code.0, code: diag_code, message }
}

/// Checks a whole mapping (`0xIIIISSLL` values) with the run-time rules
/// (`od_runtime::pdo::check_mapping`) against the dictionary generated from `model`; returns
/// its length in bits, or why the first refused entry is refused.
///
/// To check many mappings against one model, build a [`MappingChecker`] once instead.
pub fn check_mapping(model: &Model, options: &Options, dir: Direction, mapping: &[u32]) -> Result<u32, MappingError> {
    MappingChecker::new(model, options).check(dir, mapping)
}

/// The dictionary generated from a model, as the mapping check sees it.
#[derive(Debug)]
pub struct MappingChecker<'m> {
    plan: Plan<'m>,
}

impl<'m> MappingChecker<'m> {
    /// Plans the dictionary of `model` (as [`crate::generate`] would, diagnostics dropped).
    pub fn new(model: &'m Model, options: &Options) -> Self {
        let mut sink = Sink::new(&options.source_name, options.strict);
        MappingChecker { plan: crate::plan::build(model, options, &mut sink) }
    }

    /// Checks a whole mapping like [`check_mapping`].
    pub fn check(&self, dir: Direction, mapping: &[u32]) -> Result<u32, MappingError> {
        check_with_plan(&self.plan, dir, mapping)
    }
}

fn lookup<'p>(plan: &'p Plan<'p>) -> impl FnMut(u16, u8) -> Result<od_runtime::pdo::Mappable, AbortCode> + 'p {
    move |index, sub| match plan.entries.binary_search_by(|e| (e.index, e.sub).cmp(&(index, sub))) {
        Ok(i) => Ok(mappable(&plan.entries[i])),
        Err(_) if plan.entries.iter().any(|e| e.index == index) => Err(AbortCode::NO_SUB_INDEX),
        Err(_) => Err(AbortCode::NO_OBJECT),
    }
}

fn check_with_plan(plan: &Plan<'_>, dir: Direction, mapping: &[u32]) -> Result<u32, MappingError> {
    let mut total = 0u32;
    for &raw in mapping {
        // Entry by entry, so that the refused entry is known; the totals rule is the same as
        // `od_runtime::pdo::check_mapping`'s.
        let e = od_runtime::pdo::check_entry(dir, raw, lookup(plan)).map_err(|c| explain(plan, dir, raw, c))?;
        total += e.bits as u32;
        if total > 64 {
            return Err(explain(plan, dir, raw, AbortCode::PDO_LENGTH_EXCEEDED));
        }
    }
    debug_assert_eq!(od_runtime::pdo::check_mapping(dir, mapping, lookup(plan)), Ok(total));
    Ok(total)
}

/// One field of a PDO layout.
#[derive(Debug)]
struct Field<'p> {
    /// `None` for a dummy entry.
    entry: Option<&'p PEntry<'p>>,
    name: String,
    offset: u32,
    bits: u32,
    raw: u32,
}

/// One checked default mapping.
#[derive(Debug)]
struct Layout<'p> {
    dir: Direction,
    number: u16,
    /// Whether the PDO's communication object exists (0x1400 + n, 0x1800 + n): without it the
    /// mapping object is a table (a vendor's fixed mapping), not a PDO of its own.
    comm: bool,
    mapping_index: u16,
    raw: Vec<u32>,
    fields: Vec<Field<'p>>,
    bits: u32,
}

/// The communication object of PDO `n` (0-based) of direction `dir`.
fn comm_index(dir: Direction, n: u16) -> u16 {
    match dir {
        Direction::Receive => 0x1400 + n,
        Direction::Transmit => 0x1800 + n,
    }
}

/// The mapping object of PDO `n` (0-based) of direction `dir`.
fn mapping_index(dir: Direction, n: u16) -> u16 {
    match dir {
        Direction::Receive => 0x1600 + n,
        Direction::Transmit => 0x1A00 + n,
    }
}

/// The name of the layout of mapping object `n` (0-based) of direction `dir`: `Rpdo1`,
/// `Tpdo4` for a PDO (its communication object exists), `RxMappingTable1701` for a mapping
/// object without one (a vendor's fixed mapping table: not a PDO of its own).
pub(crate) fn layout_name(model: &Model, dir: Direction, n: u16) -> String {
    let comm = model.object(comm_index(dir, n)).is_some();
    match (dir, comm) {
        (Direction::Receive, true) => format!("Rpdo{}", n + 1),
        (Direction::Transmit, true) => format!("Tpdo{}", n + 1),
        (Direction::Receive, false) => format!("RxMappingTable{:04X}", mapping_index(dir, n)),
        (Direction::Transmit, false) => format!("TxMappingTable{:04X}", mapping_index(dir, n)),
    }
}

/// What a deviation in a default mapping costs: said once, as the hint of its diagnostic.
fn no_layout_hint(model: &Model, dir: Direction, n: u16, abort: Option<u32>) -> String {
    let name = layout_name(model, dir, n);
    let mut h = format!(
        "no typed layout `pdo::{name}` is generated; the mapping parameters stay in the dictionary as data \
         (served over SDO, remappable by a master)"
    );
    if let Some(code) = abort {
        h.push_str(&format!("; a master writing this mapping over SDO gets abort code 0x{code:08X}"));
    }
    h
}

/// Reads the default mapping of a mapping object; a malformed one is a deviation (reported,
/// `None`).
fn read_mapping<'o>(
    model: &Model,
    obj: &'o Object,
    dir: Direction,
    n: u16,
    sink: &mut Sink,
) -> Option<Vec<(PdoMappingEntry, u32, &'o Entry)>> {
    let count_entry = obj.sub(0)?;
    let sev = sink.deviation();
    let count = match effective_value(count_entry) {
        None => return None,
        Some(Value::Int { value, .. }) if (0..=64).contains(value) => *value as u8,
        Some(v) => {
            let shown = match v {
                Value::Int { value, .. } => format!(" (it is {value})"),
                _ => String::new(),
            };
            sink.at_entry(
                sev,
                diag::PDO_MALFORMED,
                obj,
                count_entry,
                format!("the number of mapped objects must be an integer in 0..=64{shown}"),
            );
            sink.hint(no_layout_hint(model, dir, n, None));
            return None;
        }
    };
    let mut out = Vec::new();
    for s in 1..=count {
        let Some(e) = obj.sub(s) else {
            sink.at_entry(
                sev,
                diag::PDO_MALFORMED,
                obj,
                count_entry,
                format!("sub 0 says {count} objects are mapped, but sub {s} does not exist"),
            );
            sink.hint(no_layout_hint(model, dir, n, None));
            return None;
        };
        match effective_value(e) {
            Some(Value::Int { value, .. }) if (0..=u32::MAX as i128).contains(value) => {
                out.push((PdoMappingEntry::from_u32(*value as u32), *value as u32, e))
            }
            _ => {
                sink.at_entry(
                    sev,
                    diag::PDO_MALFORMED,
                    obj,
                    e,
                    "a mapping entry must be an UNSIGNED32 0xIIIISSLL (index, sub-index, bit length)".into(),
                );
                sink.hint(no_layout_hint(model, dir, n, None));
                return None;
            }
        }
    }
    // Vendors write `0x00000000` for "nothing mapped by default" while sub 0 still counts the
    // entries: one diagnostic for the object when all are placeholders, else at the first one.
    if !out.is_empty() && out.iter().all(|(_, raw, _)| *raw == 0) {
        sink.at_entry(
            sev,
            diag::PDO_PLACEHOLDER,
            obj,
            count_entry,
            format!(
                "sub 0 counts {count} mapped objects, but every one is 0x00000000 (a placeholder: nothing is mapped)"
            ),
        );
        sink.hint(no_layout_hint(model, dir, n, None));
        return None;
    }
    if let Some((_, _, e)) = out.iter().find(|(_, raw, _)| *raw == 0) {
        sink.at_entry(
            sev,
            diag::PDO_PLACEHOLDER,
            obj,
            e,
            format!("mapped object {} is 0x00000000 (nothing) inside the {count} entries sub 0 counts", e.sub.0),
        );
        sink.hint(no_layout_hint(model, dir, n, None));
        return None;
    }
    Some(out)
}

fn layouts<'p>(model: &Model, plan: &'p Plan<'p>, sink: &mut Sink) -> Vec<Layout<'p>> {
    let by_key: BTreeMap<(u16, u8), &PEntry<'_>> = plan.entries.iter().map(|e| ((e.index, e.sub), e)).collect();
    let mut out = Vec::new();
    for obj in model.objects.values() {
        let (dir, n) = match obj.index.role() {
            Role::RpdoMapping(n) => (Direction::Receive, n),
            Role::TpdoMapping(n) => (Direction::Transmit, n),
            _ => continue,
        };
        let Some(entries) = read_mapping(model, obj, dir, n, sink) else { continue };
        if entries.is_empty() {
            continue;
        }
        let mut ok = true;
        let mut total = 0u32;
        let mut fields = Vec::new();
        let mut names = crate::ident::Names::default();
        let g = granularity(model) as u32;
        let dummies = dummy_usage(model);
        for (m, raw, e) in &entries {
            let before: Vec<u32> = fields.iter().map(|f: &Field<'_>| f.raw).collect();
            let mut upto = before.clone();
            upto.push(*raw);
            if let Err(me) = check_with_plan(plan, dir, &upto) {
                sink.at_entry(sink.deviation(), me.code, obj, e, me.message);
                sink.hint(no_layout_hint(model, dir, n, Some(me.abort_code)));
                ok = false;
                break;
            }
            let bits = m.bits as u32;
            if g > 0 && !bits.is_multiple_of(g) {
                sink.at_entry(
                    Severity::Warning,
                    diag::PDO_LENGTH,
                    obj,
                    e,
                    format!("a length of {bits} bits breaks the device's Granularity={g}"),
                );
            }
            if m.is_dummy() && dummies & (1 << m.index.0) == 0 {
                sink.at_entry(
                    Severity::Warning,
                    diag::PDO_NO_OBJECT,
                    obj,
                    e,
                    format!("dummy entry 0x{:04X}, but [DummyUsage] says Dummy{:04X}=0", m.index.0, m.index.0),
                );
            }
            let target = if m.is_dummy() { None } else { by_key.get(&(m.index.0, m.sub.0)).copied() };
            if let Some(t) = target
                && let Ty::Bytes(_) = t.ty
            {
                sink.at_entry(
                    Severity::Warning,
                    diag::PDO_VARIABLE,
                    obj,
                    e,
                    format!("maps the variable-length entry `{}`; no typed layout is generated for this PDO", t.field),
                );
                ok = false;
            }
            let name = match target {
                Some(t) => names.claim(&t.field, &[]).0,
                None => String::new(),
            };
            fields.push(Field { entry: target, name, offset: total, bits, raw: *raw });
            total += bits;
        }
        if total > 64 {
            sink.at_object(
                sink.deviation(),
                diag::PDO_TOO_LONG,
                obj,
                format!("the default mapping carries {total} bits; a PDO carries at most 64"),
            );
            sink.hint(no_layout_hint(model, dir, n, Some(AbortCode::PDO_LENGTH_EXCEEDED.0)));
            ok = false;
        }
        let comm = model.object(comm_index(dir, n)).is_some();
        if ok && !comm {
            let name = layout_name(model, dir, n);
            sink.at_object(
                Severity::Note,
                diag::PDO_NO_COMM,
                obj,
                format!(
                    "mapping object 0x{:04X} has no communication object 0x{:04X}: a mapping table, not a PDO \
                     of its own",
                    obj.index.0,
                    comm_index(dir, n)
                ),
            );
            sink.hint(format!(
                "its layout is `pdo::{name}`; a generated client has no PDO method for it (a master cannot \
                 configure or address a PDO without its communication object)"
            ));
        }
        if ok {
            out.push(Layout {
                dir,
                number: n + 1,
                comm,
                mapping_index: obj.index.0,
                raw: entries.iter().map(|(_, r, _)| *r).collect(),
                fields,
                bits: total,
            });
        }
    }
    out
}

fn mask(bits: u32) -> Option<TokenStream> {
    (bits < 64).then(|| lit::hex((1u64 << bits) - 1, 1))
}

/// One term of the packed word, without outer parentheses.
fn pack_expr(f: &Field<'_>, e: &PEntry<'_>) -> TokenStream {
    let name = format_ident!("{}", f.name);
    let value = match e.ty {
        Ty::F32 => quote!(self.#name.to_bits() as u64),
        Ty::F64 => quote!(self.#name.to_bits()),
        Ty::U64 => quote!(self.#name),
        _ => quote!(self.#name as u64),
    };
    let masked = match mask(f.bits) {
        Some(m) if e.ty.storage_bits() > f.bits || e.dt.is_signed() => quote!((#value) & #m),
        _ => value,
    };
    if f.offset == 0 {
        masked
    } else {
        let off = proc_macro2::Literal::u32_unsuffixed(f.offset);
        quote!((#masked) << #off)
    }
}

fn unpack_expr(f: &Field<'_>, e: &PEntry<'_>) -> TokenStream {
    let shifted = if f.offset == 0 {
        quote!(w)
    } else {
        let off = proc_macro2::Literal::u32_unsuffixed(f.offset);
        quote!((w >> #off))
    };
    let field = match mask(f.bits) {
        Some(m) if f.offset + f.bits < 64 => quote!((#shifted & #m)),
        _ => shifted,
    };
    let ty = rust_type(e.ty);
    match e.ty {
        Ty::Bool => quote!(#field != 0),
        Ty::F32 => quote!(f32::from_bits(#field as u32)),
        Ty::F64 => quote!(f64::from_bits(#field)),
        Ty::U64 => field,
        Ty::I8 | Ty::I16 | Ty::I32 | Ty::I64 => {
            if f.bits == 64 {
                quote!(#field as i64)
            } else {
                let s = proc_macro2::Literal::u32_unsuffixed(64 - f.bits);
                quote!((((#field << #s) as i64) >> #s) as #ty)
            }
        }
        _ => quote!(#field as #ty),
    }
}

/// Each generated layout of a PDO whose communication and mapping objects both exist: its
/// direction, number and mapping entries (for the client, which implements
/// `od_master::remote::PdoLayout` for them and gives each a method). Mapping tables without a
/// communication object are left out.
pub(crate) fn layout_summaries(model: &Model, plan: &Plan<'_>, sink: &mut Sink) -> Vec<(Direction, u16, Vec<u32>)> {
    layouts(model, plan, sink).into_iter().filter(|l| l.comm).map(|l| (l.dir, l.number, l.raw)).collect()
}

/// Checks the default mappings as [`module`] does, for their diagnostics only.
pub(crate) fn check_layouts(model: &Model, plan: &Plan<'_>, sink: &mut Sink) {
    layouts(model, plan, sink);
}

/// `pub mod pdo { … }`, or nothing when the device has no default mapping.
pub(crate) fn module(model: &Model, plan: &Plan<'_>, sink: &mut Sink) -> TokenStream {
    let layouts = layouts(model, plan, sink);
    let rt = crate::support::rt();
    let structs = layouts.iter().map(|l| {
        let (kind, verb) = match l.dir {
            Direction::Receive => ("Rpdo", "received"),
            Direction::Transmit => ("Tpdo", "transmitted"),
        };
        let name = format_ident!("{}", layout_name(model, l.dir, l.number - 1));
        let len = l.bits.div_ceil(8) as usize;
        let len_lit = proc_macro2::Literal::usize_unsuffixed(len);
        let n_map = proc_macro2::Literal::usize_unsuffixed(l.raw.len());
        let raw = l.raw.iter().map(|r| lit::hex(*r as u64, 8));
        let head = if l.comm {
            format!(
                "{} {} ({} by the device), default mapping of `0x{:04X}`: {} bits in {len} bytes.",
                kind.to_uppercase(),
                l.number,
                verb,
                l.mapping_index,
                l.bits
            )
        } else {
            format!(
                "Mapping table `0x{:04X}` ({} layout, {} bits in {len} bytes): the description has no \
                 communication object `0x{:04X}`, so this is not a PDO of its own (a vendor's fixed mapping).",
                l.mapping_index,
                verb,
                l.bits,
                comm_index(l.dir, l.number - 1)
            )
        };
        let mut doc =
            vec![head, String::new(), "| bits | object | field |".to_owned(), "|------|--------|-------|".to_owned()];
        for f in &l.fields {
            let range = format!("{}..{}", f.offset, f.offset + f.bits);
            match f.entry {
                Some(e) => doc.push(format!(
                    "| {range} | {} {} | `{}` |",
                    location(e),
                    lit::doc_escape(&display_name(e)),
                    f.name
                )),
                None => doc.push(format!("| {range} | dummy | (zero) |")),
            }
        }
        let doc = lit::doc(&doc);
        let real: Vec<(&Field<'_>, &PEntry<'_>)> = l.fields.iter().filter_map(|f| f.entry.map(|e| (f, e))).collect();
        let fields = real.iter().map(|(f, e)| {
            let n = format_ident!("{}", f.name);
            let ty = rust_type(e.ty);
            let d = lit::doc(&[format!(
                "{} {} (bits {}..{}).",
                location(e),
                lit::doc_escape(&display_name(e)),
                f.offset,
                f.offset + f.bits
            )]);
            quote!(#d pub #n: #ty)
        });
        let packs: Vec<TokenStream> = real.iter().map(|(f, e)| pack_expr(f, e)).collect();
        let pack_body = match packs.as_slice() {
            [] => quote!(0u64),
            [one] => one.clone(),
            many => quote!(#((#many))|*),
        };
        let unpacks = real.iter().map(|(f, e)| {
            let n = format_ident!("{}", f.name);
            let v = unpack_expr(f, e);
            quote!(#n: #v)
        });
        let unpack_word = if real.is_empty() { quote!(_w) } else { quote!(w) };
        let od_in = if real.is_empty() { quote!(_od) } else { quote!(od) };
        let reads = real.iter().map(|(f, e)| {
            let n = format_ident!("{}", f.name);
            let g = format_ident!("{}", e.field);
            quote!(#n: od.#g())
        });
        let writes = real.iter().map(|(f, e)| {
            let n = format_ident!("{}", f.name);
            let s = format_ident!("set_{}", e.field);
            quote!(od.#s(self.#n)?;)
        });
        quote! {
            #doc
            #[derive(Clone, Copy, Debug, Default, PartialEq)]
            pub struct #name {
                #(#fields,)*
            }

            impl #name {
                /// Length of the PDO in bytes.
                pub const LEN: usize = #len_lit;
                /// The default mapping entries (`0xIIIISSLL`).
                pub const MAPPING: [u32; #n_map] = [#(#raw),*];

                /// The PDO's bytes (bit-exact: fields in mapping order from bit 0, little-endian;
                /// dummy entries zero).
                #[inline]
                pub fn pack(&self) -> [u8; #len_lit] {
                    let w: u64 = #pack_body;
                    let mut out = [0u8; #len_lit];
                    out.copy_from_slice(&w.to_le_bytes()[..#len_lit]);
                    out
                }

                /// Decodes a received PDO; bytes past the mapping are ignored, a shorter PDO is an
                /// error.
                #[inline]
                pub fn unpack(data: &[u8]) -> Result<Self, LengthError> {
                    let #unpack_word = #rt::pdo_word(data, #len_lit)?;
                    Ok(Self { #(#unpacks,)* })
                }

                /// The mapped entries' current values.
                pub fn from_dictionary(#od_in: &super::Dictionary) -> Self {
                    Self { #(#reads,)* }
                }

                /// Stores the fields into the dictionary through the typed setters (limits
                /// checked, access not).
                pub fn to_dictionary(&self, #od_in: &mut super::Dictionary) -> Result<(), ::od_runtime::od::AbortCode> {
                    #(#writes)*
                    Ok(())
                }
            }
        }
    });
    quote! {
        /// Typed layouts of the device's default PDO mappings.
        pub mod pdo {
            /// A received PDO was shorter than its mapping.
            #[doc(inline)]
            pub use #rt::PdoLengthError as LengthError;

            #(#structs)*
        }
    }
}
