//! Literal tokens and doc text: the only place numbers and strings become tokens.

use proc_macro2::{Literal, Span, TokenStream};
use quote::quote;

use crate::plan::Ty;

/// A hexadecimal `u16`/`u32` literal (`0x6040`), padded to `width` digits.
pub(crate) fn hex(v: u64, width: usize) -> TokenStream {
    let lit = syn::LitInt::new(&format!("0x{v:0width$X}"), Span::call_site());
    quote!(#lit)
}

/// An unsuffixed integer literal (negative values as `-n`).
pub(crate) fn int(v: i128) -> TokenStream {
    if v < 0 {
        let a = Literal::u128_unsuffixed(v.unsigned_abs());
        quote!(-#a)
    } else {
        let a = Literal::u128_unsuffixed(v as u128);
        quote!(#a)
    }
}

/// An unsuffixed integer literal, in hex when `hex` and non-negative.
pub(crate) fn int_radix(v: i128, hex: bool) -> TokenStream {
    if hex && v >= 0 {
        let lit = syn::LitInt::new(&format!("0x{v:X}"), Span::call_site());
        quote!(#lit)
    } else {
        int(v)
    }
}

/// An integer literal of storage type `ty` (unsuffixed; the context gives the type).
pub(crate) fn int_of(v: i128, ty: Ty) -> TokenStream {
    match ty {
        Ty::Bool => {
            if v != 0 {
                quote!(true)
            } else {
                quote!(false)
            }
        }
        Ty::F32 => real(v as f64, true),
        Ty::F64 => real(v as f64, false),
        _ => int(v),
    }
}

/// A float literal; NaN and infinities (also a finite `f64` beyond the `f32` range, for
/// `is32`) as the associated constants. Total: never panics.
pub(crate) fn real(f: f64, is32: bool) -> TokenStream {
    let t = if is32 { quote!(f32) } else { quote!(f64) };
    let f = if is32 && !f.is_nan() { (f as f32) as f64 } else { f };
    if f.is_nan() {
        return quote!(#t::NAN);
    }
    if f.is_infinite() {
        return if f > 0.0 { quote!(#t::INFINITY) } else { quote!(#t::NEG_INFINITY) };
    }
    let a = if is32 { Literal::f32_unsuffixed((f as f32).abs()) } else { Literal::f64_unsuffixed(f.abs()) };
    if f.is_sign_negative() { quote!(-#a) } else { quote!(#a) }
}

/// A byte-string literal.
pub(crate) fn bytes(b: &[u8]) -> TokenStream {
    let l = Literal::byte_string(b);
    quote!(#l)
}

/// A string literal; multi-line text without carriage returns becomes a raw string so that the
/// generated file stays readable (and diffs stay line by line).
pub(crate) fn text_block(s: &str) -> TokenStream {
    if s.contains('\r') || !s.contains('\n') {
        let l = Literal::string(s);
        return quote!(#l);
    }
    let mut hashes = 1;
    while s.contains(&format!("\"{}", "#".repeat(hashes))) {
        hashes += 1;
    }
    let h = "#".repeat(hashes);
    let src = format!("r{h}\"{s}\"{h}");
    match src.parse::<Literal>() {
        Ok(l) => quote!(#l),
        Err(_) => {
            let l = Literal::string(s);
            quote!(#l)
        }
    }
}

/// Escapes text for a doc comment: Markdown and HTML significant characters are escaped so that
/// vendor text is shown as written and never breaks rustdoc.
pub(crate) fn doc_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\\' | '`' | '*' | '_' | '[' | ']' | '#' | '|' | '~' => {
                out.push('\\');
                out.push(c);
            }
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '\r' | '\n' | '\t' => out.push(' '),
            c if c.is_control() => {}
            c => out.push(c),
        }
    }
    out.trim().to_owned()
}

/// `#[doc = " line"]` attributes, one per line.
pub(crate) fn doc(lines: &[String]) -> TokenStream {
    let mut ts = TokenStream::new();
    for l in lines {
        let text = if l.is_empty() { String::new() } else { format!(" {l}") };
        ts.extend(quote!(#[doc = #text]));
    }
    ts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literals() {
        assert_eq!(hex(0x6040, 4).to_string(), "0x6040");
        assert_eq!(int(-5).to_string(), "- 5");
        assert_eq!(real(f64::NAN, true).to_string(), "f32 :: NAN");
        assert_eq!(real(-1.5, false).to_string(), "- 1.5");
        assert_eq!(text_block("a\n\"#b\n").to_string(), "r##\"a\n\"#b\n\"##");
        assert_eq!(text_block("a\r\nb").to_string(), "\"a\\r\\nb\"");
    }

    #[test]
    fn escaping() {
        assert_eq!(doc_escape("Limit <x> [mm] *a*\nnext"), "Limit &lt;x&gt; \\[mm\\] \\*a\\* next");
    }
}
