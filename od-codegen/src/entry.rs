//! What the emitters (`emit`, `pdo`, `units`) say about one planned entry: its Rust storage
//! type, where it is and what it is called in docs and messages, and its run-time data type.
//! Below the emitters, so none of them reaches into another for these.

use eds::model::DataType;
use proc_macro2::TokenStream;
use quote::quote;

use crate::plan::{PEntry, Ty};
use crate::support::rt;

/// The Rust type a value is stored as (`u16`, `Bytes<8>`).
pub(crate) fn rust_type(ty: Ty) -> TokenStream {
    match ty {
        Ty::Bool => quote!(bool),
        Ty::U8 => quote!(u8),
        Ty::U16 => quote!(u16),
        Ty::U32 => quote!(u32),
        Ty::U64 => quote!(u64),
        Ty::I8 => quote!(i8),
        Ty::I16 => quote!(i16),
        Ty::I32 => quote!(i32),
        Ty::I64 => quote!(i64),
        Ty::F32 => quote!(f32),
        Ty::F64 => quote!(f64),
        Ty::Bytes(n) => {
            let n = proc_macro2::Literal::usize_unsuffixed(n);
            let rt = rt();
            quote!(#rt::Bytes<#n>)
        }
    }
}

/// `0x6040` or `0x1018 sub 2`.
pub(crate) fn location(e: &PEntry<'_>) -> String {
    if e.obj.object_type.has_subs() {
        format!("`0x{:04X}` sub {}", e.index, e.sub)
    } else {
        format!("`0x{:04X}`", e.index)
    }
}

/// The display name: `Identity object: Vendor-ID` or `Controlword`.
pub(crate) fn display_name(e: &PEntry<'_>) -> String {
    if e.obj.object_type.has_subs() {
        format!("{}: {}", e.obj.name.trim(), e.entry.name.trim())
    } else {
        e.obj.name.trim().to_owned()
    }
}

/// The run-time crate's data type of a CiA type (a type it does not know is a DOMAIN).
pub(crate) fn to_runtime_type(dt: DataType) -> od_runtime::od::DataType {
    use od_runtime::od::DataType as R;
    match dt {
        DataType::Boolean => R::Boolean,
        DataType::Integer8 => R::Integer8,
        DataType::Integer16 => R::Integer16,
        DataType::Integer32 => R::Integer32,
        DataType::Unsigned8 => R::Unsigned8,
        DataType::Unsigned16 => R::Unsigned16,
        DataType::Unsigned32 => R::Unsigned32,
        DataType::Real32 => R::Real32,
        DataType::VisibleString => R::VisibleString,
        DataType::OctetString => R::OctetString,
        DataType::UnicodeString => R::UnicodeString,
        DataType::TimeOfDay => R::TimeOfDay,
        DataType::TimeDifference => R::TimeDifference,
        DataType::Domain | DataType::Other(_) => R::Domain,
        DataType::Integer24 => R::Integer24,
        DataType::Real64 => R::Real64,
        DataType::Integer40 => R::Integer40,
        DataType::Integer48 => R::Integer48,
        DataType::Integer56 => R::Integer56,
        DataType::Integer64 => R::Integer64,
        DataType::Unsigned24 => R::Unsigned24,
        DataType::Unsigned40 => R::Unsigned40,
        DataType::Unsigned48 => R::Unsigned48,
        DataType::Unsigned56 => R::Unsigned56,
        DataType::Unsigned64 => R::Unsigned64,
    }
}
