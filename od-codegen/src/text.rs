//! The text path: the large, repetitive parts of a module written straight as text.
//!
//! A module is tokens (`quote!`), which syn parses and prettyplease lays out; in a debug build
//! script (what a build script gets without `build-override` settings) that costs about a
//! second for a DCF of 2,500 entries, most of it spent on the parts that repeat per entry: the
//! index constants, `ENTRIES`, `NAMES`, the `Dictionary` struct, `new`, `zeroed` and the
//! accessors. Those parts ([`Parts::put`]) are written here as text, laid out exactly as
//! prettyplease lays them out, and the rest of the module (small) goes through syn and
//! prettyplease as before:
//!
//! * for text ([`Parts::text`], what the `Builder` and `odgen gen` write), each part stands in
//!   the tokens as a placeholder item (`const __ODGEN_PART_<n>: () = ();`, a prefix the
//!   embedded description does not contain), and [`splice`] puts the part's text in place of
//!   the placeholder's line in prettyplease's output;
//! * for tokens ([`Parts::tokens`], the proc macros), each part's text is lexed into tokens,
//!   so both paths hold one text and cannot say different things.
//!
//! Whether the text is laid out as prettyplease would is held by the test
//! `od-codegen/tests/text_path.rs`: for every corpus file, fixture, bundled device and random
//! model, the text path's file equals prettyplease's rendering of the token path's. The writers
//! here handle the shapes whose layout they know (which lines fit prettyplease's margin, how
//! prettyplease breaks those that do not); anything else (a very long name, a long default, a table short
//! enough to fit one line) goes through prettyplease itself ([`pretty`]), one item at a time,
//! nested as deep as it stands in the module.

use proc_macro2::TokenStream;
use quote::{format_ident, quote};

/// prettyplease's line width (its `MARGIN`).
pub(crate) const MARGIN: usize = 89;

/// A line of `len` columns fits prettyplease's margin: prettyplease then breaks nothing in it.
/// (`tests/text_path.rs` sweeps every name length across the margin, so each writer's choice
/// is held to prettyplease's on both sides of it.)
pub(crate) fn fits(len: usize) -> bool {
    len <= MARGIN
}

/// The large parts of a module: as text (placeholders in the tokens) or as tokens.
pub(crate) struct Parts {
    text: bool,
    texts: Vec<String>,
    /// The placeholder items' name prefix.
    prefix: String,
}

impl Parts {
    /// Parts lexed into the tokens (the proc macros' path).
    pub(crate) fn tokens() -> Self {
        Parts { text: false, texts: Vec::new(), prefix: String::new() }
    }

    /// Parts kept as text, placeholders in the tokens (the `Builder`'s path). `verbatim` is
    /// text the rest of the module holds line by line (the embedded description, a raw
    /// string): the placeholders' prefix is one it does not contain, so none of its lines
    /// can pass for a placeholder.
    pub(crate) fn text(verbatim: Option<&str>) -> Self {
        let mut prefix = String::from("__ODGEN_PART_");
        while verbatim.is_some_and(|v| v.contains(prefix.as_str())) {
            prefix.push_str("X_");
        }
        Parts { text: true, texts: Vec::new(), prefix }
    }

    /// A part of the module: `text` is its lines at their final indentation, each ending in a
    /// line feed, laid out as prettyplease lays out items (or impl items) at that depth.
    pub(crate) fn put(&mut self, text: String) -> TokenStream {
        if self.text {
            let id = format_ident!("{}{}", self.prefix, self.texts.len());
            self.texts.push(text);
            quote!(const #id: () = ();)
        } else {
            match text.parse::<TokenStream>() {
                Ok(t) => t,
                Err(e) => {
                    // A bug in a writer here; the tokens say so instead of panicking.
                    let msg = format!("od-codegen wrote a part that does not lex: {e}");
                    quote!(::core::compile_error!(#msg);)
                }
            }
        }
    }

    /// The placeholders' prefix and the parts' texts, in placeholder order.
    pub(crate) fn into_texts(self) -> (String, Vec<String>) {
        (self.prefix, self.texts)
    }
}

/// prettyplease's output with each placeholder's line (`prefix` and a number) replaced by its
/// part.
pub(crate) fn splice(rendered: &str, prefix: &str, parts: &[String]) -> String {
    let mut out = String::with_capacity(rendered.len() + parts.iter().map(String::len).sum::<usize>());
    for line in rendered.split_inclusive('\n') {
        let part = line
            .trim_start_matches(' ')
            .strip_prefix("const ")
            .and_then(|l| l.strip_prefix(prefix))
            .and_then(|l| l.strip_suffix(": () = ();\n"))
            .and_then(|n| n.parse::<usize>().ok())
            .and_then(|n| parts.get(n));
        match part {
            Some(p) => out.push_str(p),
            None => out.push_str(line),
        }
    }
    out
}

/// prettyplease's layout of `item` standing `depth` levels deep, as `nest` says: an item of a
/// module `depth` modules in (an index constant is 2: the device's module, then `index`), a
/// method of an `impl` in `depth - 1` modules (a `Dictionary` method is 2), or an element of a
/// static's array in `depth - 1` modules (a row of `ENTRIES` is 2). The lines of the item
/// alone, at their indentation there.
pub(crate) fn pretty(item: TokenStream, depth: usize, nest: Nest) -> String {
    let mut t = match nest {
        Nest::Item => item,
        Nest::Impl => quote!(impl D { #item }),
        Nest::Array => quote!(static X: [T; 1] = [#item];),
    };
    let mods = if nest == Nest::Item { depth } else { depth.saturating_sub(1) };
    for _ in 0..mods {
        t = quote!(mod m { #t });
    }
    let skip = depth;
    match syn::parse2::<syn::File>(t) {
        Ok(file) => {
            let text = prettyplease::unparse(&file);
            let lines: Vec<&str> = text.split_inclusive('\n').collect();
            let end = lines.len().saturating_sub(skip);
            lines.get(skip.min(end)..end).map(|l| l.concat()).unwrap_or_default()
        }
        // A writer's bug: the file says so where the item would be, and does not compile.
        Err(e) => format!("compile_error!({:?});\n", format!("od-codegen: {e}")),
    }
}

/// Where [`pretty`]'s item stands.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Nest {
    /// An item of a module.
    Item,
    /// A method of an `impl`.
    Impl,
    /// An element of an array (a table's row).
    Array,
}

/// Lines of text at given indentations.
#[derive(Default)]
pub(crate) struct Text {
    pub(crate) out: String,
}

impl Text {
    pub(crate) fn with_capacity(n: usize) -> Self {
        Text { out: String::with_capacity(n) }
    }

    fn indent(&mut self, indent: usize) {
        const SPACES: &str = "                                ";
        self.out.push_str(&SPACES[..indent.min(SPACES.len())]);
    }

    /// One line at `indent` columns (at most 32).
    pub(crate) fn line(&mut self, indent: usize, parts: &[&str]) {
        self.indent(indent);
        for p in parts {
            self.out.push_str(p);
        }
        self.out.push('\n');
    }

    /// Doc comment lines as prettyplease writes `#[doc = " line"]` (an empty line as `///`,
    /// trailing spaces trimmed). Line ends inside a line become spaces: a doc line is one line.
    pub(crate) fn doc(&mut self, indent: usize, lines: &[String]) {
        for l in lines {
            self.indent(indent);
            self.out.push_str("///");
            if !l.is_empty() {
                self.out.push(' ');
                if l.contains('\n') || l.contains('\r') {
                    self.out.push_str(&l.replace(['\n', '\r'], " "));
                } else {
                    self.out.push_str(l);
                }
                if self.out.ends_with(' ') {
                    let trimmed = self.out.trim_end_matches(' ').len();
                    self.out.truncate(trimmed);
                }
            }
            self.out.push('\n');
        }
    }

    pub(crate) fn push(&mut self, s: &str) {
        self.out.push_str(s);
    }
}

/// The doc lines as `#[doc = " line"]` attributes, as the text path writes them (for items
/// that go through [`pretty`]).
pub(crate) fn doc_tokens(lines: &[String]) -> TokenStream {
    let fixed: Vec<String> =
        lines.iter().map(|l| l.replace(['\n', '\r'], " ").trim_end_matches(' ').to_owned()).collect();
    crate::lit::doc(&fixed)
}
