//! `cargo xtask gen [--check]`: regenerates the checked-in crate `generated/`.
//!
//! * Each device file listed in [`SOURCES`] becomes `generated/src/<module>.rs` (through
//!   [`od_codegen::Builder`], exactly as a build script would generate it) behind a cargo feature
//!   of the same name; `generated/src/lib.rs` includes them.
//! * Each network description in [`NETWORKS`] becomes one DCF per node in
//!   `generated/networks/<network>/` (through `odgen::network`, as `odgen dcf --network` writes
//!   them).
//!
//! When a regeneration changes a module because its device file changed, `gen` prints what
//! changed in the description, as `odgen diff` would: the old description is the `EDS` constant
//! embedded in the checked-in module, the new one the device file. `--check` writes nothing and
//! fails, naming the command to run, when any file would change (or a DCF would be removed).

use std::path::{Path, PathBuf};

use quote::quote;

/// One module of the generated crate.
#[derive(Clone, Copy, Debug)]
pub struct Source {
    /// Module name (`pub mod drvi`).
    pub module: &'static str,
    /// The cargo feature that enables it.
    pub feature: &'static str,
    /// The device description, relative to the workspace root.
    pub path: &'static str,
}

/// Everything `generated/` is made of, in order.
pub const SOURCES: &[Source] = &[
    Source { module: "drvi", feature: "drvi", path: "devices/camozzi-drvi.eds" },
    Source { module: "drcs", feature: "drcs", path: "devices/camozzi-drcs.eds" },
    Source { module: "akd", feature: "akd", path: "devices/kollmorgen-akd.eds" },
    Source { module: "fixture_mini", feature: "fixtures", path: "od-codegen/tests/fixtures/mini.eds" },
];

/// Network descriptions whose DCFs are generated, relative to the workspace root.
pub const NETWORKS: &[&str] = &["networks/example.toml"];

/// Where the DCFs of the networks go (one directory per network file stem).
pub const NETWORK_DIR: &str = "generated/networks";

/// The command that brings `generated/` up to date.
pub const FIX: &str = "cargo xtask gen";

/// Runs the command.
pub fn main(args: &[String]) -> Result<(), String> {
    let mut check = false;
    for a in args {
        match a.as_str() {
            "--check" => check = true,
            other => return Err(format!("unknown argument `{other}` (usage: cargo xtask gen [--check])")),
        }
    }
    let root = crate::workspace_root();
    if check {
        let stale = stale_files(&root)?;
        if stale.is_empty() {
            println!("generated/ is up to date");
            Ok(())
        } else {
            let list: Vec<String> = stale.iter().map(|p| format!("  {}", p.display())).collect();
            Err(format!("generated/ is stale; run `{FIX}`. Out of date:\n{}", list.join("\n")))
        }
    } else {
        let files = expected_files(&root)?;
        for report in description_changes(&root)? {
            println!("{report}");
        }
        for (rel, text) in &files {
            let path = root.join(rel);
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
            }
            if od_codegen::write_if_changed(&path, text).map_err(|e| e.to_string())? {
                println!("wrote {}", rel.display());
            }
        }
        for rel in leftover_dcfs(&root, &files)? {
            std::fs::remove_file(root.join(&rel)).map_err(|e| format!("{}: {e}", rel.display()))?;
            println!("removed {}", rel.display());
        }
        Ok(())
    }
}

/// The sources whose description file exists (device files arrive over time; a missing one
/// leaves its feature empty).
pub fn present_sources(root: &Path) -> Vec<Source> {
    SOURCES.iter().copied().filter(|s| root.join(s.path).is_file()).collect()
}

/// Every file of `generated/src` with the contents it should have, paths relative to `root`.
pub fn expected_files(root: &Path) -> Result<Vec<(PathBuf, String)>, String> {
    let sources = present_sources(root);
    // Our own device files: strict (every deviation is an error), with the description embedded
    // (`EDS`, which the simulated drives serve and parse), and the names behind the `names`
    // feature of `generated` (a default feature): a firmware turns them off to save their flash.
    let mut builder = od_codegen::Builder::new()
        .root(root)
        .cargo_metadata(false)
        .strict()
        .embed_eds(true)
        .names(od_codegen::Names::Feature("names".to_owned()));
    for s in &sources {
        builder = builder.device(s.module, s.path);
    }
    let outputs = builder.generate().map_err(|e| e.to_string())?;
    let mut files = Vec::new();
    for o in outputs {
        if !o.diagnostics.is_empty() {
            eprintln!("{}", o.rendered(od_codegen::Severity::Warning));
        }
        files.push((PathBuf::from("generated/src").join(&o.file_name), o.text));
    }
    files.push((PathBuf::from("generated/src/lib.rs"), lib_rs(&sources)?));
    for network in NETWORKS {
        files.extend(network_files(root, network)?);
    }
    Ok(files)
}

/// The DCFs of one network description, paths relative to `root`.
pub fn network_files(root: &Path, network: &str) -> Result<Vec<(PathBuf, String)>, String> {
    let path = root.join(network);
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let dir = path.parent().unwrap_or(root);
    // Shown relative to the workspace root, so diagnostics (and anything the DCFs record) do
    // not depend on where the checkout is.
    let outcome = odgen::network::build(network, dir, &text);
    if outcome.has_errors() {
        return Err(format!("{network} has errors:\n{}", odgen::network::render_all(&outcome.diagnostics)));
    }
    let stem = Path::new(network).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let out = Path::new(NETWORK_DIR).join(stem);
    Ok(outcome.dcfs.into_iter().map(|d| (out.join(&d.file_name), d.text)).collect())
}

/// DCFs under [`NETWORK_DIR`] that no network produces any more (a node or a network was
/// removed), relative to `root`.
pub fn leftover_dcfs(root: &Path, expected: &[(PathBuf, String)]) -> Result<Vec<PathBuf>, String> {
    let mut left = Vec::new();
    let base = root.join(NETWORK_DIR);
    let Ok(dirs) = std::fs::read_dir(&base) else { return Ok(left) };
    for dir in dirs.flatten() {
        let Ok(files) = std::fs::read_dir(dir.path()) else { continue };
        for f in files.flatten() {
            let path = f.path();
            if path.extension().is_some_and(|e| e == "dcf") {
                let rel = path.strip_prefix(root).map_err(|e| e.to_string())?.to_path_buf();
                if !expected.iter().any(|(p, _)| *p == rel) {
                    left.push(rel);
                }
            }
        }
    }
    left.sort();
    Ok(left)
}

/// The files that differ from what [`expected_files`] says (missing files included), and DCFs
/// that would be removed.
pub fn stale_files(root: &Path) -> Result<Vec<PathBuf>, String> {
    let mut stale = Vec::new();
    let expected = expected_files(root)?;
    for (rel, text) in &expected {
        let current = std::fs::read(root.join(rel)).ok();
        if current.as_deref() != Some(text.as_bytes()) {
            stale.push(rel.clone());
        }
    }
    stale.extend(leftover_dcfs(root, &expected)?);
    Ok(stale)
}

/// The description embedded in a generated module: the `EDS` constant of `pub mod <module>`.
/// `None` if the file does not parse or has no such constant.
pub fn embedded_description(generated: &str, module: &str) -> Option<String> {
    let file = syn::parse_file(generated).ok()?;
    let items = file.items.iter().find_map(|i| match i {
        syn::Item::Mod(m) if m.ident == module => m.content.as_ref().map(|(_, items)| items),
        _ => None,
    })?;
    items.iter().find_map(|i| match i {
        syn::Item::Const(c) if c.ident == "EDS" => match &*c.expr {
            syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    })
}

/// What changed in a device description since the checked-in module was generated, as
/// `odgen diff` prints it; `None` when the description text is the same.
///
/// `checked_in` is the checked-in module's text (`None` for a new device), `current` the device
/// file's bytes, `shown` its path as printed.
pub fn description_change(checked_in: Option<&str>, module: &str, shown: &str, current: &[u8]) -> Option<String> {
    let new_text = eds::source::SourceFile::decode(shown, current).text;
    let old_text = checked_in.and_then(|t| embedded_description(t, module));
    if old_text.as_deref() == Some(new_text.as_str()) {
        return None;
    }
    let lenient = eds::Options::lenient();
    let old = match &old_text {
        Some(t) => eds::parse(shown, t.as_bytes(), &lenient).model,
        None => eds::Model::default(),
    };
    let new = eds::parse(shown, current, &lenient).model;
    let what = if old_text.is_some() { "changed since the checked-in generation" } else { "is new" };
    let table = odgen::diff::render_table(&odgen::diff::diff(&old, &new));
    Some(format!("{shown} {what} (odgen diff):\n{table}"))
}

/// [`description_change`] for every present source whose description changed.
pub fn description_changes(root: &Path) -> Result<Vec<String>, String> {
    let mut reports = Vec::new();
    for s in present_sources(root) {
        let current = std::fs::read(root.join(s.path)).map_err(|e| format!("{}: {e}", s.path))?;
        let checked_in = std::fs::read_to_string(root.join("generated/src").join(format!("{}.rs", s.module))).ok();
        reports.extend(description_change(checked_in.as_deref(), s.module, s.path, &current));
    }
    Ok(reports)
}

fn lib_rs(sources: &[Source]) -> Result<String, String> {
    let includes = sources.iter().map(|s| {
        let feature = s.feature;
        let file = format!("{}.rs", s.module);
        quote! {
            #[cfg(feature = #feature)]
            include!(#file);
        }
    });
    let tokens = quote! {
        //! Typed object dictionaries of the project's devices, generated by `od-codegen` from
        //! `devices/*.eds` (and their sidecars) with `cargo xtask gen`.
        //!
        //! One module per device, each behind the cargo feature of the same name (`drvi`,
        //! `drcs`, `akd`); `fixtures` adds the code generated from od-codegen's test fixtures.
        //! The crate is `#![no_std]` and denies warnings, which proves the generated code builds
        //! warning-free without `std`.
        //!
        //! Beside the code, `generated/networks/<network>/` holds one DCF per node of each network
        //! description in `networks/` (`odgen dcf --network`, also written by `cargo xtask gen`).
        #![no_std]
        #![deny(warnings, missing_docs)]
        #(#includes)*
    };
    let file: syn::File = syn::parse2(tokens).map_err(|e| e.to_string())?;
    Ok(format!("// @generated by {FIX} — do not edit; run {FIX}\n\n{}", prettyplease::unparse(&file)))
}
