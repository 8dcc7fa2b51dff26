//! The spanned syntax tree of the `object_dictionary!` language, and its parser.
//!
//! The parser recovers from syntax errors: the input is first cut into items at top-level `;`
//! (and after a `{ … }` body), item bodies into sub-items at `;`, and property lists at `,`.
//! Each piece is parsed on its own, so one malformed piece costs one error and the rest is still
//! read. Meaning (types, ranges, duplicates) is not checked here but in [`crate::lower`].

use proc_macro2::{Delimiter, Ident, Span, TokenStream, TokenTree};

use crate::ctxt::{Ctxt, Loc};

/// A whole macro input.
pub(crate) struct Dsl {
    /// The items, in input order.
    pub items: Vec<Item>,
    /// The whole input (the call site when it is empty).
    pub loc: Loc,
}

/// One top-level item.
pub(crate) enum Item {
    /// `mod name;`
    Module { name: Ident },
    /// `strict;`
    Strict(Loc),
    /// `device { key = value, … }`
    Device { kw: Loc, props: Vec<Prop> },
    /// `var …;`, `array …;`, `record … { … }`
    Object(ObjectDecl),
    /// `rpdo N: …;`, `tpdo N: …;`
    Pdo(PdoDecl),
    /// An item with a syntax error (already reported). `index` is the object index it declares,
    /// when that much could be read, so that follow-up problems about it are not reported.
    Broken { kind: BrokenKind, number: Option<u128> },
}

/// What a broken item was going to declare.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BrokenKind {
    /// An object at an index.
    Object,
    /// An RPDO (true) or TPDO (false) by number.
    Pdo(bool),
    /// The device block.
    Device,
    /// Anything else.
    Other,
}

/// A number written as an integer literal (an index, a sub-index, a PDO number).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Num {
    pub value: u128,
    pub loc: Loc,
}

/// A name written as a string literal.
#[derive(Clone, Debug)]
pub(crate) struct Name {
    pub value: String,
    pub loc: Loc,
}

/// `TYPE, ACCESS` at the start of an entry's property list.
#[derive(Clone, Debug)]
pub(crate) struct Spec {
    pub ty: Ident,
    pub access: Ident,
}

/// `key = value`, or a bare `flag`.
#[derive(Clone, Debug)]
pub(crate) struct Prop {
    pub key: Ident,
    pub value: Option<Val>,
    pub loc: Loc,
}

/// What kind of object a declaration makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ObjKind {
    Var,
    Array,
    Record,
}

/// `var`, `array` or `record`.
#[derive(Clone, Debug)]
pub(crate) struct ObjectDecl {
    pub kind: ObjKind,
    pub index: Num,
    pub name: Name,
    /// Type and access: a VAR's, or an ARRAY's elements'. `None` for a RECORD.
    pub spec: Option<Spec>,
    pub props: Vec<Prop>,
    /// The `{ … }` sub-objects (RECORD, or ARRAY with named elements).
    pub body: Option<Vec<SubDecl>>,
    pub loc: Loc,
}

/// A sub-object inside a `record { … }` (with a spec) or an `array { … }` (without).
#[derive(Clone, Debug)]
pub(crate) struct SubDecl {
    pub sub: Num,
    pub name: Name,
    pub spec: Option<Spec>,
    pub props: Vec<Prop>,
    pub loc: Loc,
}

/// `rpdo N: …` or `tpdo N: …`.
#[derive(Clone, Debug)]
pub(crate) struct PdoDecl {
    /// RPDO (received by the device) or TPDO.
    pub rx: bool,
    pub number: Num,
    pub props: Vec<Prop>,
    pub loc: Loc,
}

/// A value as written, before it is given a data type.
#[derive(Clone, Debug)]
pub(crate) enum Val {
    /// An integer, possibly negative.
    Int { value: i128, hex: bool, loc: Loc },
    /// A floating-point literal.
    Real { value: f64, loc: Loc },
    /// `"text"`.
    Text { value: String, loc: Loc },
    /// `b"bytes"`.
    Bytes { value: Vec<u8>, loc: Loc },
    /// `true` / `false`.
    Bool { value: bool, loc: Loc },
    /// `NODEID + offset` (also `$NODEID`, `offset + NODEID`, `NODEID - n`).
    NodeId { offset: i128, hex: bool, loc: Loc },
    /// `0x6000:1`: an object entry (index and sub-index), in a PDO mapping.
    Ref { index: Num, sub: Num, loc: Loc },
    /// `[a, b, …]`.
    List { items: Vec<Val>, loc: Loc },
}

impl Val {
    /// Where the value was written.
    pub fn loc(&self) -> Loc {
        match self {
            Val::Int { loc, .. }
            | Val::Real { loc, .. }
            | Val::Text { loc, .. }
            | Val::Bytes { loc, .. }
            | Val::Bool { loc, .. }
            | Val::NodeId { loc, .. }
            | Val::Ref { loc, .. }
            | Val::List { loc, .. } => *loc,
        }
    }

    /// What kind of value it is, for messages ("a string").
    pub fn describe(&self) -> &'static str {
        match self {
            Val::Int { .. } => "an integer",
            Val::Real { .. } => "a real number",
            Val::Text { .. } => "a string",
            Val::Bytes { .. } => "a byte string",
            Val::Bool { .. } => "a boolean",
            Val::NodeId { .. } => "a `NODEID + n` expression",
            Val::Ref { .. } => "an `index:sub` reference",
            Val::List { .. } => "a list",
        }
    }
}

/// A piece of the input between separators.
struct Chunk {
    tokens: Vec<TokenTree>,
    /// The separator that ended it (`None` at the end of the input or after a `{ … }` body).
    sep: Option<Span>,
}

/// Cuts `tokens` at top-level `sep` puncts. With `brace_ends`, a `{ … }` group also ends a
/// piece, and a `sep` right after it is consumed.
fn split(tokens: TokenStream, sep: char, brace_ends: bool) -> Vec<Chunk> {
    let mut out = Vec::new();
    let mut cur: Vec<TokenTree> = Vec::new();
    let mut after_brace = false;
    for tt in tokens {
        match &tt {
            TokenTree::Punct(p) if p.as_char() == sep => {
                if after_brace && cur.is_empty() {
                    after_brace = false;
                    continue;
                }
                after_brace = false;
                out.push(Chunk { tokens: std::mem::take(&mut cur), sep: Some(p.span()) });
            }
            TokenTree::Group(g) if brace_ends && g.delimiter() == Delimiter::Brace => {
                cur.push(tt);
                out.push(Chunk { tokens: std::mem::take(&mut cur), sep: None });
                after_brace = true;
            }
            _ => {
                after_brace = false;
                cur.push(tt);
            }
        }
    }
    if !cur.is_empty() {
        out.push(Chunk { tokens: cur, sep: None });
    }
    out
}

/// A cursor over one piece.
struct Cur<'a> {
    toks: &'a [TokenTree],
    pos: usize,
    /// The whole piece (for "expected … here" at its end).
    whole: Loc,
}

impl<'a> Cur<'a> {
    fn new(toks: &'a [TokenTree], fallback: Loc) -> Self {
        Cur { toks, pos: 0, whole: Loc::of_tokens(toks, fallback) }
    }

    fn peek(&self) -> Option<&'a TokenTree> {
        self.toks.get(self.pos)
    }

    fn peek2(&self) -> Option<&'a TokenTree> {
        self.toks.get(self.pos + 1)
    }

    fn next(&mut self) -> Option<&'a TokenTree> {
        let t = self.toks.get(self.pos);
        if t.is_some() {
            self.pos += 1;
        }
        t
    }

    fn is_empty(&self) -> bool {
        self.pos >= self.toks.len()
    }

    fn rest(&self) -> &'a [TokenTree] {
        &self.toks[self.pos.min(self.toks.len())..]
    }

    /// Where an "expected X" error goes: the next token, or the end of the piece.
    fn here(&self) -> Loc {
        match self.peek() {
            Some(t) => Loc::of(t.span()),
            None => Loc::of(self.whole.end),
        }
    }

    fn punct(&mut self, c: char) -> Option<Span> {
        match self.peek() {
            Some(TokenTree::Punct(p)) if p.as_char() == c => {
                self.pos += 1;
                Some(p.span())
            }
            _ => None,
        }
    }
}

fn describe_token(t: &TokenTree) -> String {
    match t {
        TokenTree::Group(g) => match g.delimiter() {
            Delimiter::Brace => "`{ … }`".to_owned(),
            Delimiter::Bracket => "`[ … ]`".to_owned(),
            Delimiter::Parenthesis => "`( … )`".to_owned(),
            Delimiter::None => "a group".to_owned(),
        },
        other => format!("`{other}`"),
    }
}

/// Parses a whole macro input, reporting syntax errors to `cx`.
pub(crate) fn parse(input: TokenStream, cx: &mut Ctxt) -> Dsl {
    let all: Vec<TokenTree> = input.clone().into_iter().collect();
    let loc = Loc::of_tokens(&all, Loc::of(Span::call_site()));
    let mut items = Vec::new();
    for chunk in split(input, ';', true) {
        if chunk.tokens.is_empty() {
            continue;
        }
        let ends_with_body =
            matches!(chunk.tokens.last(), Some(TokenTree::Group(g)) if g.delimiter() == Delimiter::Brace);
        let before = cx.count();
        let mut cur = Cur::new(&chunk.tokens, loc);
        let item = parse_item(&mut cur, cx);
        if !ends_with_body && chunk.sep.is_none() && cx.count() == before {
            let last = chunk.tokens.last().map(|t| t.span()).unwrap_or(loc.end);
            cx.error(Loc::of(last), "expected `;` after this item");
        }
        match item {
            Some(item) if cx.count() == before => items.push(item),
            _ => items.push(broken(&chunk.tokens)),
        }
    }
    Dsl { items, loc }
}

/// What a malformed item was going to declare, read as far as possible.
fn broken(tokens: &[TokenTree]) -> Item {
    let kw = match tokens.first() {
        Some(TokenTree::Ident(i)) => i.to_string(),
        _ => String::new(),
    };
    let number = match tokens.get(1) {
        Some(TokenTree::Literal(l)) => match syn::Lit::new(l.clone()) {
            syn::Lit::Int(i) => i.base10_parse::<u128>().ok(),
            _ => None,
        },
        _ => None,
    };
    let kind = match kw.as_str() {
        "var" | "array" | "record" => BrokenKind::Object,
        "rpdo" => BrokenKind::Pdo(true),
        "tpdo" => BrokenKind::Pdo(false),
        "device" => BrokenKind::Device,
        _ => BrokenKind::Other,
    };
    Item::Broken { kind, number }
}

const ITEMS: &str = "`mod`, `strict`, `device`, `var`, `array`, `record`, `rpdo` or `tpdo`";

fn parse_item(cur: &mut Cur<'_>, cx: &mut Ctxt) -> Option<Item> {
    let start = cur.here();
    let kw = match cur.next() {
        Some(TokenTree::Ident(i)) => i.clone(),
        Some(t) => {
            cx.error(Loc::of(t.span()), format!("expected an item ({ITEMS}), found {}", describe_token(t)));
            return None;
        }
        None => return None,
    };
    let kw_loc = Loc::of(kw.span());
    let item = match kw.to_string().as_str() {
        "mod" => parse_module(cur, kw_loc, cx)?,
        "strict" => Item::Strict(kw_loc),
        "device" => parse_device(cur, kw_loc, cx)?,
        "var" => parse_object(cur, ObjKind::Var, start, cx)?,
        "array" => parse_object(cur, ObjKind::Array, start, cx)?,
        "record" => parse_object(cur, ObjKind::Record, start, cx)?,
        "rpdo" => parse_pdo(cur, true, start, cx)?,
        "tpdo" => parse_pdo(cur, false, start, cx)?,
        _ => {
            cx.error(kw_loc, format!("expected an item ({ITEMS}), found `{kw}`"));
            return None;
        }
    };
    if let Some(t) = cur.peek() {
        cx.error(Loc::of(t.span()), format!("unexpected {} in this item", describe_token(t)));
        return None;
    }
    Some(item)
}

/// `mod name;` after its keyword (at `kw`).
fn parse_module(cur: &mut Cur<'_>, kw: Loc, cx: &mut Ctxt) -> Option<Item> {
    let name = match cur.next() {
        Some(TokenTree::Ident(i)) => i.clone(),
        _ => {
            cx.error(kw, "expected a module name: `mod name;`");
            return None;
        }
    };
    Some(Item::Module { name })
}

/// `device { key = value, … }` after its keyword (at `kw`).
fn parse_device(cur: &mut Cur<'_>, kw: Loc, cx: &mut Ctxt) -> Option<Item> {
    let body = match cur.next() {
        Some(TokenTree::Group(g)) if g.delimiter() == Delimiter::Brace => g.clone(),
        _ => {
            cx.error(kw, "expected `{ key = value, … }` after `device`");
            return None;
        }
    };
    let props = parse_props(body.stream(), Loc::of(body.span()), cx);
    Some(Item::Device { kw, props })
}

/// A `var`, `array` or `record` object after its keyword: index, name, then the type, access
/// and properties (not for a record) and the sub-objects in braces (not for a var). The item
/// started at `start`.
fn parse_object(cur: &mut Cur<'_>, kind: ObjKind, start: Loc, cx: &mut Ctxt) -> Option<Item> {
    let index = parse_num(cur, cx, "an object index such as `0x2000`")?;
    let name = parse_name(cur, cx)?;
    let body = match cur.toks.last() {
        Some(TokenTree::Group(g)) if g.delimiter() == Delimiter::Brace && kind != ObjKind::Var => Some(g.clone()),
        _ => None,
    };
    let props_end = cur.toks.len() - body.is_some() as usize;
    let (spec, props) = if kind == ObjKind::Record {
        record_head_ends(cur, props_end, cx)?;
        (None, Vec::new())
    } else {
        let (spec, props) = parse_object_spec(cur, props_end, cx)?;
        (Some(spec), props)
    };
    let body = match body {
        Some(g) => Some(parse_body(g.stream(), kind, Loc::of(g.span()), cx)),
        None if kind == ObjKind::Record => {
            cx.error(Loc::of(name.loc.end), "expected `{ … }` with the record's sub-objects");
            return None;
        }
        None => None,
    };
    cur.pos = cur.toks.len();
    let loc = start.to(Loc::of_tokens(cur.toks, start));
    Some(Item::Object(ObjectDecl { kind, index, name, spec, props, body, loc }))
}

/// A record's name is followed by its braces and nothing else (its sub-objects have the types).
fn record_head_ends(cur: &Cur<'_>, props_end: usize, cx: &mut Ctxt) -> Option<()> {
    if cur.pos < props_end {
        let t = &cur.toks[cur.pos];
        cx.error(
            Loc::of(t.span()),
            format!(
                "expected `{{` after the record's name, found {}; a record's sub-objects each have their own type and access",
                describe_token(t)
            ),
        );
        return None;
    }
    Some(())
}

/// `: type, access, props…` of a var or array, up to `props_end` (its braces, if any).
fn parse_object_spec(cur: &mut Cur<'_>, props_end: usize, cx: &mut Ctxt) -> Option<(Spec, Vec<Prop>)> {
    if cur.punct(':').is_none() {
        cx.error(cur.here(), "expected `:` and then the data type and access, as in `: u16, rw`");
        return None;
    }
    let spec_tokens: TokenStream = cur.toks[cur.pos..props_end].iter().cloned().collect();
    parse_spec(spec_tokens, cur.here(), cx)
}

/// `rpdo N: props…` / `tpdo N: props…` after its keyword (`rx`: an RPDO); the item started at
/// `start`.
fn parse_pdo(cur: &mut Cur<'_>, rx: bool, start: Loc, cx: &mut Ctxt) -> Option<Item> {
    let number = parse_num(cur, cx, "a PDO number (1 for the first PDO)")?;
    let props = if cur.is_empty() {
        Vec::new()
    } else if cur.punct(':').is_some() {
        let rest: TokenStream = cur.rest().iter().cloned().collect();
        cur.pos = cur.toks.len();
        parse_props(rest, cur.whole, cx)
    } else {
        cx.error(cur.here(), "expected `:` and then the PDO's properties, as in `: map = [0x6040]`");
        return None;
    };
    let loc = start.to(Loc::of_tokens(cur.toks, start));
    Some(Item::Pdo(PdoDecl { rx, number, props, loc }))
}

fn parse_num(cur: &mut Cur<'_>, cx: &mut Ctxt, what: &str) -> Option<Num> {
    let here = cur.here();
    match cur.next() {
        Some(TokenTree::Literal(l)) => match syn::Lit::new(l.clone()) {
            syn::Lit::Int(i) => {
                let loc = Loc::of(l.span());
                if !i.suffix().is_empty() {
                    cx.error(loc, format!("remove the suffix `{}`", i.suffix()));
                    return None;
                }
                match i.base10_parse::<u128>() {
                    Ok(value) => Some(Num { value, loc }),
                    Err(e) => {
                        cx.syn_error(e);
                        None
                    }
                }
            }
            _ => {
                cx.error(Loc::of(l.span()), format!("expected {what}"));
                None
            }
        },
        _ => {
            cx.error(here, format!("expected {what}"));
            None
        }
    }
}

fn parse_name(cur: &mut Cur<'_>, cx: &mut Ctxt) -> Option<Name> {
    let here = cur.here();
    if let Some(TokenTree::Literal(l)) = cur.peek()
        && let syn::Lit::Str(s) = syn::Lit::new(l.clone())
    {
        cur.next();
        return Some(Name { value: s.value(), loc: Loc::of(l.span()) });
    }
    cx.error(here, "expected the name as a string literal, as in `\"Controlword\"`");
    None
}

/// `TYPE, ACCESS, props…`.
fn parse_spec(tokens: TokenStream, end: Loc, cx: &mut Ctxt) -> Option<(Spec, Vec<Prop>)> {
    let mut chunks = split(tokens, ',', false).into_iter();
    let ty = match chunks.next().as_ref().map(|c| c.tokens.as_slice()) {
        Some([TokenTree::Ident(i)]) => i.clone(),
        Some([TokenTree::Ident(_), t, ..]) => {
            cx.error(Loc::of(t.span()), format!("expected `,` after the data type, found {}", describe_token(t)));
            return None;
        }
        Some([t, ..]) => {
            cx.error(Loc::of(t.span()), "expected a data type such as `u16` or `UNSIGNED16`");
            return None;
        }
        _ => {
            cx.error(end, "expected a data type such as `u16` or `UNSIGNED16`");
            return None;
        }
    };
    let access = match chunks.next().as_ref().map(|c| c.tokens.as_slice()) {
        Some([TokenTree::Ident(i)]) => i.clone(),
        Some([TokenTree::Ident(i), t, ..]) => {
            cx.error(Loc::of(t.span()), format!("expected `,` or `;` after `{i}`, found {}", describe_token(t)));
            return None;
        }
        Some([t, ..]) => {
            cx.error(Loc::of(t.span()), "expected an access type (`ro`, `wo`, `rw`, `rwr`, `rww` or `const`)");
            return None;
        }
        _ => {
            cx.error(
                Loc::of(ty.span()),
                "expected `,` and an access type (`ro`, `wo`, `rw`, `rwr`, `rww` or `const`) after the data type",
            );
            return None;
        }
    };
    let before = cx.count();
    let props: Vec<Prop> =
        chunks.filter(|c| !c.tokens.is_empty()).filter_map(|c| parse_prop(&c.tokens, end, cx)).collect();
    (cx.count() == before).then_some((Spec { ty, access }, props))
}

/// `key = value, flag, …` (the device block and PDO properties).
fn parse_props(tokens: TokenStream, end: Loc, cx: &mut Ctxt) -> Vec<Prop> {
    split(tokens, ',', false)
        .into_iter()
        .filter(|c| !c.tokens.is_empty())
        .filter_map(|c| parse_prop(&c.tokens, end, cx))
        .collect()
}

fn parse_prop(tokens: &[TokenTree], end: Loc, cx: &mut Ctxt) -> Option<Prop> {
    let mut cur = Cur::new(tokens, end);
    let key = match cur.next() {
        Some(TokenTree::Ident(i)) => i.clone(),
        Some(t) => {
            cx.error(Loc::of(t.span()), format!("expected a property name, found {}", describe_token(t)));
            return None;
        }
        None => return None,
    };
    let loc = Loc::of_tokens(tokens, end);
    if cur.is_empty() {
        return Some(Prop { key, value: None, loc });
    }
    if cur.punct('=').is_none() {
        cx.error(cur.here(), format!("expected `=` or `,` after `{key}`"));
        return None;
    }
    let value = parse_value(cur.rest(), Loc::of(cur.whole.end), cx)?;
    Some(Prop { key, value: Some(value), loc })
}

fn parse_body(tokens: TokenStream, kind: ObjKind, end: Loc, cx: &mut Ctxt) -> Vec<SubDecl> {
    let mut subs = Vec::new();
    for chunk in split(tokens, ';', false) {
        if chunk.tokens.is_empty() {
            continue;
        }
        let before = cx.count();
        let sub = parse_sub(&chunk.tokens, kind, end, cx);
        if chunk.sep.is_none() && cx.count() == before {
            let last = chunk.tokens.last().map(|t| t.span()).unwrap_or(end.end);
            cx.error(Loc::of(last), "expected `;` after this sub-object");
        }
        if let Some(s) = sub
            && cx.count() == before
        {
            subs.push(s);
        }
    }
    subs
}

fn parse_sub(tokens: &[TokenTree], kind: ObjKind, end: Loc, cx: &mut Ctxt) -> Option<SubDecl> {
    let mut cur = Cur::new(tokens, end);
    let sub = parse_num(&mut cur, cx, "a sub-index")?;
    let name = parse_name(&mut cur, cx)?;
    let loc = Loc::of_tokens(tokens, end);
    // A record's sub-objects, and an array's count entry (sub-index 0), have their own spec.
    let has_spec = matches!(cur.peek(), Some(TokenTree::Punct(p)) if p.as_char() == ':');
    if kind == ObjKind::Record || has_spec {
        if cur.punct(':').is_none() {
            cx.error(cur.here(), "expected `:` and then the data type and access, as in `: u32, ro`");
            return None;
        }
        let rest: TokenStream = cur.rest().iter().cloned().collect();
        let (spec, props) = parse_spec(rest, Loc::of(cur.whole.end), cx)?;
        return Some(SubDecl { sub, name, spec: Some(spec), props, loc });
    }
    // An array element: type and access come from the array; only values may follow.
    if cur.is_empty() {
        return Some(SubDecl { sub, name, spec: None, props: Vec::new(), loc });
    }
    if cur.punct(',').is_none() {
        cx.error(cur.here(), "expected `,` and then the element's `default`, `min` or `max`");
        return None;
    }
    let props = parse_props(cur.rest().iter().cloned().collect(), Loc::of(cur.whole.end), cx);
    Some(SubDecl { sub, name, spec: None, props, loc })
}

/// Parses a value that spans all of `tokens`.
fn parse_value(tokens: &[TokenTree], end: Loc, cx: &mut Ctxt) -> Option<Val> {
    let mut cur = Cur::new(tokens, end);
    if cur.is_empty() {
        cx.error(end, "expected a value after `=`");
        return None;
    }
    let v = value(&mut cur, cx)?;
    if let Some(t) = cur.peek() {
        cx.error(Loc::of(t.span()), format!("unexpected {} after the value", describe_token(t)));
        return None;
    }
    Some(v)
}

const VALUE_FORMS: &str =
    "a number, a string, a byte string, `true`/`false`, `NODEID + n`, `index:sub` or a list `[…]`";

fn is_node_id(t: Option<&TokenTree>) -> bool {
    matches!(t, Some(TokenTree::Ident(i)) if i.to_string().eq_ignore_ascii_case("nodeid"))
}

fn is_dollar(t: Option<&TokenTree>) -> bool {
    matches!(t, Some(TokenTree::Punct(p)) if p.as_char() == '$')
}

/// Reads `$`? `NODEID`; returns its span.
fn node_id(cur: &mut Cur<'_>) -> Option<Span> {
    let start = cur.pos;
    let dollar = cur.punct('$');
    if is_node_id(cur.peek()) {
        let span = cur.next().map(|t| t.span())?;
        return Some(dollar.unwrap_or(span));
    }
    cur.pos = start;
    None
}

/// One integer literal, with an optional leading `-`.
fn int(cur: &mut Cur<'_>, cx: &mut Ctxt) -> Option<(i128, bool, Loc)> {
    let neg = cur.punct('-');
    let t = cur.next();
    let Some(TokenTree::Literal(l)) = t else {
        cx.error(t.map(|t| Loc::of(t.span())).unwrap_or(cur.here()), "expected an integer");
        return None;
    };
    let syn::Lit::Int(i) = syn::Lit::new(l.clone()) else {
        cx.error(Loc::of(l.span()), "expected an integer");
        return None;
    };
    let loc = match neg {
        Some(s) => Loc { start: s, end: l.span() },
        None => Loc::of(l.span()),
    };
    if !i.suffix().is_empty() {
        cx.error(loc, format!("remove the suffix `{}`: the entry's data type gives the value its type", i.suffix()));
        return None;
    }
    let Ok(mag) = i.base10_digits().parse::<u128>() else {
        cx.error(loc, "this number does not fit in 128 bits");
        return None;
    };
    let Ok(mag) = i128::try_from(mag) else {
        cx.error(loc, "this number does not fit in 128 bits");
        return None;
    };
    let hex = l.to_string().get(..2).is_some_and(|p| p.eq_ignore_ascii_case("0x"));
    Some((if neg.is_some() { -mag } else { mag }, hex, loc))
}

fn value(cur: &mut Cur<'_>, cx: &mut Ctxt) -> Option<Val> {
    let here = cur.here();
    // NODEID [+|- n]
    if let Some(span) = node_id(cur) {
        let start = Loc::of(span);
        let sign = if cur.punct('+').is_some() {
            1
        } else if cur.punct('-').is_some() {
            -1
        } else {
            return Some(Val::NodeId { offset: 0, hex: false, loc: start });
        };
        let (n, hex, loc) = int(cur, cx)?;
        return Some(Val::NodeId { offset: sign * n, hex, loc: start.to(loc) });
    }
    let Some(t) = cur.peek() else {
        cx.error(here, format!("expected {VALUE_FORMS}"));
        return None;
    };
    match t {
        TokenTree::Group(g) if g.delimiter() == Delimiter::Bracket => {
            cur.next();
            let mut items = Vec::new();
            let before = cx.count();
            for chunk in split(g.stream(), ',', false) {
                if chunk.tokens.is_empty() {
                    continue;
                }
                if let Some(v) = parse_value(&chunk.tokens, Loc::of(g.span()), cx) {
                    items.push(v);
                }
            }
            (cx.count() == before).then(|| Val::List { items, loc: Loc::of(g.span()) })
        }
        TokenTree::Ident(i) if i == "true" || i == "false" => {
            cur.next();
            Some(Val::Bool { value: i == "true", loc: Loc::of(i.span()) })
        }
        TokenTree::Punct(p) if p.as_char() == '-' => {
            // A negative integer or real.
            if let Some(TokenTree::Literal(l)) = cur.peek2()
                && let syn::Lit::Float(f) = syn::Lit::new(l.clone())
            {
                cur.next();
                cur.next();
                let loc = Loc { start: p.span(), end: l.span() };
                return real(&f, true, loc, cx);
            }
            let (value, hex, loc) = int(cur, cx)?;
            Some(Val::Int { value, hex, loc })
        }
        TokenTree::Literal(l) => match syn::Lit::new(l.clone()) {
            syn::Lit::Int(_) => {
                let (value, hex, loc) = int(cur, cx)?;
                // index:sub
                if cur.punct(':').is_some() {
                    let (sub, _, sub_loc) = int(cur, cx)?;
                    let (Ok(index), Ok(sub)) = (u128::try_from(value), u128::try_from(sub)) else {
                        cx.error(loc.to(sub_loc), "an entry reference is `index:sub` with non-negative numbers");
                        return None;
                    };
                    return Some(Val::Ref {
                        index: Num { value: index, loc },
                        sub: Num { value: sub, loc: sub_loc },
                        loc: loc.to(sub_loc),
                    });
                }
                // n + NODEID
                if matches!(cur.peek(), Some(TokenTree::Punct(p)) if p.as_char() == '+')
                    && (is_node_id(cur.peek2()) || is_dollar(cur.peek2()))
                {
                    cur.punct('+');
                    let span = node_id(cur).unwrap_or(loc.end);
                    return Some(Val::NodeId { offset: value, hex, loc: loc.to(Loc::of(span)) });
                }
                Some(Val::Int { value, hex, loc })
            }
            syn::Lit::Float(f) => {
                cur.next();
                real(&f, false, Loc::of(l.span()), cx)
            }
            syn::Lit::Str(s) => {
                cur.next();
                Some(Val::Text { value: s.value(), loc: Loc::of(l.span()) })
            }
            syn::Lit::ByteStr(b) => {
                cur.next();
                Some(Val::Bytes { value: b.value(), loc: Loc::of(l.span()) })
            }
            _ => {
                cx.error(Loc::of(l.span()), format!("expected {VALUE_FORMS}"));
                None
            }
        },
        other => {
            cx.error(Loc::of(other.span()), format!("expected {VALUE_FORMS}, found {}", describe_token(other)));
            None
        }
    }
}

fn real(f: &syn::LitFloat, neg: bool, loc: Loc, cx: &mut Ctxt) -> Option<Val> {
    if !f.suffix().is_empty() {
        cx.error(loc, format!("remove the suffix `{}`: the entry's data type gives the value its type", f.suffix()));
        return None;
    }
    match f.base10_digits().parse::<f64>() {
        Ok(v) if v.is_finite() => Some(Val::Real { value: if neg { -v } else { v }, loc }),
        _ => {
            cx.error(loc, "this number is not a finite real number");
            None
        }
    }
}
