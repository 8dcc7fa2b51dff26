//! Error collection: every mistake in one compile.
//!
//! Following serde_derive's `Ctxt`, the front end never stops at the first problem. Each phase
//! records `syn::Error`s here and goes on; [`Ctxt::finish`] combines them into one error whose
//! `to_compile_error` emits one `compile_error!` per problem, each spanned on its own tokens.

use proc_macro2::{Span, TokenStream, TokenTree};

/// A source range in the macro input: the first and the last token of something.
///
/// Stable proc-macros cannot join two spans into one, but `syn::Error::new_spanned` can cover
/// a range given its first and last token; [`Loc::error`] uses that.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Loc {
    pub start: Span,
    pub end: Span,
}

impl Loc {
    /// A range of one token.
    pub fn of(span: Span) -> Self {
        Loc { start: span, end: span }
    }

    /// From the first token of `self` to the last of `other`.
    pub fn to(self, other: Loc) -> Self {
        Loc { start: self.start, end: other.end }
    }

    /// The range of a token sequence (`fallback` when it is empty).
    pub fn of_tokens(tokens: &[TokenTree], fallback: Loc) -> Self {
        match (tokens.first(), tokens.last()) {
            (Some(a), Some(b)) => Loc { start: a.span(), end: b.span() },
            _ => fallback,
        }
    }

    /// An error covering this range.
    pub fn error(self, message: impl std::fmt::Display) -> syn::Error {
        let mut tokens = TokenStream::new();
        let mut first = proc_macro2::Punct::new('<', proc_macro2::Spacing::Alone);
        first.set_span(self.start);
        let mut last = proc_macro2::Punct::new('>', proc_macro2::Spacing::Alone);
        last.set_span(self.end);
        tokens.extend([TokenTree::Punct(first), TokenTree::Punct(last)]);
        syn::Error::new_spanned(tokens, message)
    }
}

/// The errors found so far.
#[derive(Default)]
pub(crate) struct Ctxt {
    errors: Vec<syn::Error>,
}

impl Ctxt {
    /// An empty context.
    pub fn new() -> Self {
        Ctxt::default()
    }

    /// Records an error covering `loc`.
    pub fn error(&mut self, loc: Loc, message: impl std::fmt::Display) {
        self.errors.push(loc.error(message));
    }

    /// Records an error produced elsewhere (a syn parse error).
    pub fn syn_error(&mut self, error: syn::Error) {
        self.errors.push(error);
    }

    /// How many errors have been recorded.
    pub fn count(&self) -> usize {
        self.errors.len()
    }

    /// `Ok` when nothing was recorded, else every error combined into one.
    pub fn finish(self) -> syn::Result<()> {
        let mut errors = self.errors.into_iter();
        let Some(mut first) = errors.next() else { return Ok(()) };
        for e in errors {
            first.combine(e);
        }
        Err(first)
    }
}
