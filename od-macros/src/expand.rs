//! The two expansions, as plain functions on `proc_macro2` tokens so that tests can run them
//! in-process.

use std::path::{Path, PathBuf};

use eds::diag::{Diagnostic, Severity};
use eds::source::SourceFile;
use proc_macro2::{Ident, TokenStream};
use quote::quote;
use syn::LitStr;
use syn::parse::{ParseStream, Parser};

use crate::ctxt::Ctxt;
use crate::lower::Lowered;
use crate::validate::Checked;
use crate::{ast, lower, validate};

/// Everything `object_dictionary!` computes, for tests.
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) struct Expansion {
    /// The lowered model and where its parts were declared.
    pub lowered: Lowered,
    /// The validated model and its EDS text.
    pub checked: Checked,
    /// The generated module.
    pub tokens: TokenStream,
}

/// Runs the whole front end, validation and the generator; `Err` holds every error found.
pub(crate) fn dictionary(input: TokenStream) -> Result<Expansion, syn::Error> {
    let mut cx = Ctxt::new();
    let dsl = ast::parse(input, &mut cx);
    let lowered = lower::lower(&dsl, &mut cx, 0);
    let checked = validate::check(&lowered, &mut cx);
    let mut options = od_codegen::Options::new(lowered.module.clone(), checked.file_name.clone());
    options.eds_text = Some(checked.eds_text.clone());
    // The declaration is the author's own: every deviation (a PDO that breaks a mapping rule)
    // is an error, located at the declaration.
    options.strict = true;
    let generated = od_codegen::expand(&checked.model, &options);
    validate::report_codegen(&lowered, &checked, &generated.diagnostics, &mut cx);
    cx.finish()?;
    Ok(Expansion { lowered, checked, tokens: generated.tokens })
}

/// `object_dictionary! { … }`.
pub(crate) fn object_dictionary(input: TokenStream) -> TokenStream {
    match dictionary(input) {
        Ok(e) => e.tokens,
        Err(e) => e.to_compile_error(),
    }
}

/// `include_eds!("path", mod name, strict, client, allow(G0104, E0502))`.
struct IncludeArgs {
    path: LitStr,
    module: Option<Ident>,
    strict: bool,
    client: bool,
    /// Codes whose warnings are not reported (`warnings`: none is).
    allow: Vec<String>,
}

fn include_args(input: ParseStream<'_>) -> syn::Result<IncludeArgs> {
    let path: LitStr = input.parse()?;
    let mut args = IncludeArgs { path, module: None, strict: false, client: false, allow: Vec::new() };
    while !input.is_empty() {
        input.parse::<syn::Token![,]>()?;
        if input.is_empty() {
            break;
        }
        if input.peek(syn::Token![mod]) {
            input.parse::<syn::Token![mod]>()?;
            let name: Ident = input.parse()?;
            if args.module.replace(name.clone()).is_some() {
                return Err(syn::Error::new(name.span(), "the module name is already given"));
            }
            continue;
        }
        let id: Ident = input.parse()?;
        if id == "client" {
            args.client = true;
            continue;
        }
        if id == "allow" {
            let inner;
            syn::parenthesized!(inner in input);
            let codes = syn::punctuated::Punctuated::<Ident, syn::Token![,]>::parse_terminated(&inner)?;
            for c in codes {
                let code = c.to_string();
                let known = code == "warnings"
                    || (code.len() == 5
                        && code.starts_with(['E', 'G', 'W', 'N'])
                        && code[1..].chars().all(|ch| ch.is_ascii_digit()));
                if !known {
                    return Err(syn::Error::new(
                        c.span(),
                        "expected a diagnostic code such as `G0104` or `E0502`, or `warnings` for all",
                    ));
                }
                args.allow.push(code);
            }
            continue;
        }
        if id != "strict" {
            return Err(syn::Error::new(id.span(), "expected `mod name`, `strict`, `client` or `allow(CODE, …)`"));
        }
        args.strict = true;
    }
    Ok(args)
}

/// One EDS diagnostic as a compile error message: `file:line:col: message [code]`, then the
/// quoted line and the notes, as `odgen check` prints them.
fn render_file_diagnostic(d: &Diagnostic, source: &SourceFile) -> String {
    let at = match d.at {
        Some(lc) => format!("{}:{}:{}", d.file, lc.line, lc.col),
        None => d.file.to_string(),
    };
    let mut out = format!("{at}: {} [{}]", d.message, d.code);
    // `render` gives "error[..]: message", "--> file:line:col", then the quoted line and notes.
    for line in eds::diag::render(d, source).lines().skip(2) {
        out.push('\n');
        out.push_str(line);
    }
    out
}

/// `include_eds!`, with relative paths resolved against `manifest_dir` (Cargo's
/// `CARGO_MANIFEST_DIR` for the crate being compiled).
pub(crate) fn include_eds(input: TokenStream, manifest_dir: Option<&Path>) -> TokenStream {
    let included = match include(input, manifest_dir) {
        Ok(i) => i,
        Err(e) => return e.to_compile_error(),
    };
    // `include_bytes!` makes Cargo rebuild the crate when a file changes (and, unlike
    // `include_str!`, accepts the Windows-1252 files the reader also accepts).
    let mut tokens = included.module;
    for p in &included.tracked {
        tokens.extend(quote! { const _: &[u8] = include_bytes!(#p); });
    }
    tokens.extend(included.warnings);
    tokens
}

/// Each warning as a warning of the compiler at the macro's path literal (a proc macro on
/// stable Rust has no warning of its own: the use of a deprecated constant whose note is the
/// diagnostic, as `odgen check` and a build script say it).
fn warning_tokens(lines: &[String], span: proc_macro2::Span) -> TokenStream {
    let mut out = TokenStream::new();
    for line in lines {
        let note = format!("{line} (`include_eds!(…, allow({}))` silences it)", code_of(line));
        let name = Ident::new("od_codegen_warning", span);
        out.extend(quote::quote_spanned! {span=>
            const _: () = {
                #[deprecated(note = #note)]
                #[allow(non_upper_case_globals)]
                const #name: () = ();
                #name
            };
        });
    }
    out
}

/// The code in a short line `file:line:col: warning[G0104]: message`.
fn code_of(line: &str) -> &str {
    line.split_once("warning[").and_then(|(_, rest)| rest.split_once(']')).map_or("CODE", |(c, _)| c)
}

/// What `include_eds!` expands to.
pub(crate) struct Included {
    /// The generated module.
    pub module: TokenStream,
    /// The absolute paths of the files read (the description, then its sidecar if any).
    pub tracked: Vec<String>,
    /// The warnings not allowed, as compiler warnings.
    pub warnings: TokenStream,
    /// The same, as short lines (`file:line:col: warning[CODE]: message`).
    #[cfg_attr(not(test), allow(dead_code))]
    pub warning_lines: Vec<String>,
}

/// Reads, validates and generates; every error is on the path literal.
pub(crate) fn include(input: TokenStream, manifest_dir: Option<&Path>) -> syn::Result<Included> {
    let args = include_args.parse2(input)?;
    let lit = &args.path;
    let shown = lit.value();
    let err = |msg: String| syn::Error::new(lit.span(), msg);
    let path = Path::new(&shown);
    let abs: PathBuf = if path.is_absolute() {
        path.to_path_buf()
    } else {
        let dir = manifest_dir.ok_or_else(|| {
            err("CARGO_MANIFEST_DIR is not set, so a relative path cannot be resolved; build with Cargo".to_owned())
        })?;
        dir.join(path)
    };
    let bytes = std::fs::read(&abs).map_err(|e| err(format!("cannot read `{}`: {e}", abs.display())))?;
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let parsed = eds::parse(&shown, &bytes, &options);
    let source = &parsed.document.source;

    let module = match &args.module {
        Some(m) => m.to_string(),
        None => {
            let stem = abs.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            od_codegen::ident::snake(stem).unwrap_or_else(|| "device".to_owned())
        }
    };
    let mut cx = Ctxt::new();
    for d in parsed.errors() {
        cx.syn_error(err(render_file_diagnostic(d, source)));
    }
    let mut options = od_codegen::Options::new(module, shown.clone());
    options.eds_text = Some(source.text.clone());
    options.strict = args.strict;
    options.client = args.client;
    let mut tracked = vec![abs.clone()];
    let sidecar = abs.with_extension("toml");
    if sidecar.is_file() {
        match od_codegen::sidecar::Sidecar::read(&sidecar) {
            Ok(sc) => options.sidecar = Some(sc),
            Err(e) => cx.syn_error(err(format!("sidecar `{}`: {e}", sidecar.display()))),
        }
        tracked.push(sidecar);
    }
    let generated = od_codegen::expand(&parsed.model, &options);
    for d in generated.diagnostics.iter().filter(|d| d.severity == Severity::Error) {
        cx.syn_error(err(render_file_diagnostic(d, source)));
    }
    cx.finish()?;
    let tracked = tracked
        .iter()
        .map(|p| p.to_str().map(str::to_owned).ok_or_else(|| err(format!("the path `{}` is not UTF-8", p.display()))))
        .collect::<syn::Result<Vec<_>>>()?;
    // What a build script and `odgen check` report: the reader's and the generator's
    // warnings, without the allowed codes.
    let warning_lines: Vec<String> = if args.allow.iter().any(|a| a == "warnings") {
        Vec::new()
    } else {
        let mut w: Vec<&Diagnostic> = parsed
            .diagnostics
            .iter()
            .chain(&generated.diagnostics)
            .filter(|d| d.severity == Severity::Warning && od_codegen::shown(d, &args.allow))
            .collect();
        w.sort_by_key(|d| d.at.map_or((usize::MAX, 0), |a| (a.line as usize, a.col as usize)));
        w.into_iter().map(od_codegen::diag::short_line).collect()
    };
    let warnings = warning_tokens(&warning_lines, lit.span());
    Ok(Included { module: generated.tokens, tracked, warnings, warning_lines })
}
