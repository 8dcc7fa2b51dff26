//! `cargo xtask deps`: the import graph of every crate of the workspace, and a failure for
//! every circle in it.
//!
//! Each crate root (a member's `src/lib.rs`, `src/main.rs`, `src/bin/*.rs`,
//! `src/bin/*/main.rs` and `tests/it/main.rs`) is read with the module files its `mod`
//! declarations name (`#[path]` followed; a file loaded through `#[path]` holds its children
//! beside it, like a `mod.rs`). Every module is a node, an inline `mod name { … }` (a
//! `mod tests`) one of its own.
//!
//! **What is an edge.** Module `A` imports from module `B` when `A` names an item of `B`:
//! in a `use` line (`use crate::b::X;`, `use super::b::{X, Y};`, `use b::*;`, a `pub use`
//! re-export) or in a path in its code (`crate::b::X`, `super::b::f()`, `self::b::C`,
//! `$crate::b::m!`, `b::X` where `b` is a child module of `A` or a name `A` imported).
//! A path is resolved through the modules it walks down and through the imports (`use`,
//! `pub use`) it meets on the way, so `crate::Bus` in a crate whose root says
//! `pub use bus::Bus` is an edge to `bus`. Not edges:
//!
//! * a module's use of its ancestors (`super::X`, `use super::*` in `mod tests`, an item of
//!   the crate root): a parent's items are its children's context (Rust lets every
//!   descendant see them, private ones included), and a child is part of its parent;
//! * `mod` declarations (containment, not import);
//! * paths in comments, doc comments and string literals (intra-doc links among them), and
//!   paths into other crates.
//!
//! A parent's use of its child's items is an edge. A circle is a strongly connected part of
//! the graph with more than one module; each is reported with one circle through it, each
//! step with the file and line of its first reference.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A module: its path from the crate root (`[]` for the root), the file that holds it.
#[derive(Debug, Default)]
struct Module {
    file: PathBuf,
    /// The child modules declared in it.
    children: Vec<String>,
    /// The names its `use` items bind (an alias, or the path's last segment), with the path.
    imports: Vec<(String, Vec<String>)>,
    /// Every path it names (`use` paths and paths in code), with the line.
    refs: Vec<(Vec<String>, usize)>,
}

/// The modules of one crate, by path.
type Modules = BTreeMap<Vec<String>, Module>;

/// One circle: the modules in order (the first repeated at the end) and, per step, where the
/// first reference is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Circle {
    /// The crate root the circle is in.
    pub root: PathBuf,
    /// Module names (`error`, `master::pdo`, `crate` for the root), the first again last.
    pub modules: Vec<String>,
    /// Per step `modules[i] -> modules[i + 1]`: `file:line` of a reference.
    pub evidence: Vec<String>,
}

impl std::fmt::Display for Circle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.root.display(), self.modules.join(" -> "))?;
        for (i, e) in self.evidence.iter().enumerate() {
            write!(f, "\n    {} -> {}: {e}", self.modules[i], self.modules[i + 1])?;
        }
        Ok(())
    }
}

/// A token of Rust source, comments and literals taken out (strings kept for `#[path]`).
#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    Str(String),
    PathSep,
    Punct(char),
}

/// The tokens of `src`, each with its line (1-based).
fn lex(src: &str) -> Vec<(Tok, usize)> {
    let b: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let ident_start = |c: char| c.is_ascii_alphabetic() || c == '_';
    let ident_char = |c: char| c.is_ascii_alphanumeric() || c == '_';
    // Skips a string body from just after its opening quote; returns its text.
    let string = |i: &mut usize, line: &mut usize, hashes: Option<usize>| -> String {
        let start = *i;
        while *i < b.len() {
            let c = b[*i];
            if c == '\n' {
                *line += 1;
            }
            match hashes {
                None if c == '\\' => *i += 1,
                None if c == '"' => break,
                Some(h) if c == '"' && (0..h).all(|k| b.get(*i + 1 + k) == Some(&'#')) => break,
                _ => {}
            }
            *i += 1;
        }
        let text: String = b[start..(*i).min(b.len())].iter().collect();
        *i += 1 + hashes.unwrap_or(0);
        text
    };
    while i < b.len() {
        let c = b[i];
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && b.get(i + 1) == Some(&'/') {
            while i < b.len() && b[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && b.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == '/' && b.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == '*' && b.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if c == '"' {
            i += 1;
            let at = line;
            out.push((Tok::Str(string(&mut i, &mut line, None)), at));
        } else if c == '\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime / label ('a).
            if b.get(i + 1) == Some(&'\\') {
                i += 2;
                while i < b.len() && b[i] != '\'' {
                    i += 1;
                }
                i += 1;
            } else if b.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < b.len() && ident_char(b[i]) {
                    i += 1;
                }
            }
        } else if ident_start(c) {
            let start = i;
            while i < b.len() && ident_char(b[i]) {
                i += 1;
            }
            let word: String = b[start..i].iter().collect();
            let next = b.get(i).copied();
            let raw = matches!(word.as_str(), "r" | "br" | "cr");
            if raw && matches!(next, Some('"' | '#')) {
                let mut h = 0;
                while b.get(i + h) == Some(&'#') {
                    h += 1;
                }
                if b.get(i + h) == Some(&'"') {
                    i += h + 1;
                    let at = line;
                    out.push((Tok::Str(string(&mut i, &mut line, Some(h))), at));
                    continue;
                }
                // A raw identifier (r#type).
                i += h;
                let s = i;
                while i < b.len() && ident_char(b[i]) {
                    i += 1;
                }
                out.push((Tok::Ident(b[s..i].iter().collect()), line));
                continue;
            }
            if matches!(word.as_str(), "b" | "c") && next == Some('"') {
                i += 1;
                let at = line;
                out.push((Tok::Str(string(&mut i, &mut line, None)), at));
                continue;
            }
            if word == "b" && next == Some('\'') {
                continue; // the byte literal is skipped as a char literal next
            }
            out.push((Tok::Ident(word), line));
        } else if c.is_ascii_digit() {
            while i < b.len() && ident_char(b[i]) {
                i += 1;
            }
        } else if c == ':' && b.get(i + 1) == Some(&':') {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(c), line));
            i += 1;
        }
    }
    out
}

fn ident(t: Option<&(Tok, usize)>) -> Option<&str> {
    match t {
        Some((Tok::Ident(s), _)) => Some(s),
        _ => None,
    }
}

/// Parses a `use` tree starting at `*i` (after `use`) up to its `;`: each path it brings in,
/// with the name it binds (`None` for a glob).
fn use_tree(toks: &[(Tok, usize)], i: &mut usize, prefix: &[String], out: &mut Vec<(Vec<String>, Option<String>)>) {
    let mut path = prefix.to_vec();
    if matches!(toks.get(*i), Some((Tok::PathSep, _))) {
        path.push("::".to_owned()); // a leading `::`: another crate
        *i += 1;
    }
    loop {
        match toks.get(*i) {
            Some((Tok::Ident(s), _)) if s == "self" && !prefix.is_empty() && path.len() == prefix.len() => {
                // `{self, ...}`: the prefix itself.
                *i += 1;
                let name = prefix.last().cloned();
                out.push((prefix.to_vec(), alias(toks, i).or(name)));
                return;
            }
            Some((Tok::Ident(s), _)) => {
                path.push(s.clone());
                *i += 1;
                if matches!(toks.get(*i), Some((Tok::PathSep, _))) {
                    *i += 1;
                    continue;
                }
                let name = path.last().cloned();
                let name = alias(toks, i).or(name);
                out.push((path, name));
                return;
            }
            Some((Tok::Punct('*'), _)) => {
                *i += 1;
                out.push((path, None));
                return;
            }
            Some((Tok::Punct('{'), _)) => {
                *i += 1;
                loop {
                    match toks.get(*i) {
                        Some((Tok::Punct('}'), _)) => {
                            *i += 1;
                            return;
                        }
                        Some((Tok::Punct(','), _)) => *i += 1,
                        None => return,
                        _ => {
                            let before = *i;
                            use_tree(toks, i, &path, out);
                            if *i == before {
                                *i += 1;
                            }
                        }
                    }
                }
            }
            _ => return,
        }
    }
}

/// `as name` after a use path, if there.
fn alias(toks: &[(Tok, usize)], i: &mut usize) -> Option<String> {
    if ident(toks.get(*i)) == Some("as") {
        let name = ident(toks.get(*i + 1)).map(str::to_owned);
        *i += 2;
        return name.filter(|n| n != "_");
    }
    None
}

/// Reads the module in `file` (and, through its `mod` declarations, every module below it)
/// into `mods`. `dir` is where its children's files are.
fn read_module(file: &Path, dir: &Path, path: Vec<String>, mods: &mut Modules) -> Result<(), String> {
    let src = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
    let toks = lex(&src);
    // The inline modules open at each point: (module path, its children's dir, brace depth).
    let mut stack: Vec<(Vec<String>, PathBuf, usize)> = vec![(path, dir.to_owned(), 0)];
    let mut depth = 0usize;
    let mut pending_path: Option<String> = None;
    let mut files: Vec<(Vec<String>, PathBuf, PathBuf)> = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        let (cur, cur_dir, _) = stack.last().cloned().unwrap_or_default();
        let m = mods.entry(cur.clone()).or_default();
        if m.file.as_os_str().is_empty() {
            m.file = file.to_owned();
        }
        match &toks[i].0 {
            Tok::Punct('{') => depth += 1,
            Tok::Punct('}') => {
                // The brace that closes an inline module ends it.
                if stack.len() > 1 && stack.last().is_some_and(|s| s.2 == depth) {
                    stack.pop();
                }
                depth = depth.saturating_sub(1);
            }
            Tok::Punct('#') => {
                // `#[path = "..."]` before a `mod`.
                let mut j = i + 1;
                if matches!(toks.get(j), Some((Tok::Punct('!'), _))) {
                    j += 1;
                }
                if matches!(toks.get(j), Some((Tok::Punct('['), _)))
                    && ident(toks.get(j + 1)) == Some("path")
                    && matches!(toks.get(j + 2), Some((Tok::Punct('='), _)))
                    && let Some((Tok::Str(p), _)) = toks.get(j + 3)
                {
                    pending_path = Some(p.clone());
                }
            }
            Tok::Ident(w) if w == "mod" => {
                if let Some(name) = ident(toks.get(i + 1)) {
                    let name = name.to_owned();
                    let mut child = cur.clone();
                    child.push(name.clone());
                    mods.entry(cur.clone()).or_default().children.push(name.clone());
                    match toks.get(i + 2) {
                        Some((Tok::Punct(';'), _)) => {
                            let (f, d) = match pending_path.take() {
                                Some(p) => {
                                    let base = if stack.len() > 1 { cur_dir.clone() } else { file_dir(file) };
                                    let f = base.join(p);
                                    let d = file_dir(&f);
                                    (f, d)
                                }
                                None => {
                                    let flat = cur_dir.join(format!("{name}.rs"));
                                    if flat.exists() {
                                        (flat, cur_dir.join(&name))
                                    } else {
                                        (cur_dir.join(&name).join("mod.rs"), cur_dir.join(&name))
                                    }
                                }
                            };
                            files.push((child, f, d));
                            i += 3;
                            continue;
                        }
                        Some((Tok::Punct('{'), _)) => {
                            pending_path = None;
                            depth += 1;
                            stack.push((child.clone(), cur_dir.join(&name), depth));
                            mods.entry(child).or_default().file = file.to_owned();
                            i += 3;
                            continue;
                        }
                        _ => {}
                    }
                }
            }
            Tok::Ident(w) if w == "use" && !matches!(toks.get(i + 1), Some((Tok::Punct('<'), _))) => {
                let line = toks[i].1;
                let mut j = i + 1;
                let mut paths = Vec::new();
                use_tree(&toks, &mut j, &[], &mut paths);
                let m = mods.entry(cur.clone()).or_default();
                for (p, name) in paths {
                    if let Some(n) = name {
                        m.imports.push((n, p.clone()));
                    }
                    m.refs.push((p, line));
                }
                i = j.max(i + 1);
                continue;
            }
            Tok::Ident(w) => {
                let after_sep = i > 0 && matches!(toks[i - 1].0, Tok::PathSep);
                if !after_sep && matches!(toks.get(i + 1), Some((Tok::PathSep, _))) {
                    let line = toks[i].1;
                    // `$crate::` (in a macro) is `crate::`.
                    let mut p = vec![w.clone()];
                    let mut j = i + 1;
                    while matches!(toks.get(j), Some((Tok::PathSep, _))) {
                        match ident(toks.get(j + 1)) {
                            Some(s) => p.push(s.to_owned()),
                            None => break,
                        }
                        j += 2;
                    }
                    mods.entry(cur.clone()).or_default().refs.push((p, line));
                    i = j;
                    continue;
                }
            }
            _ => {}
        }
        i += 1;
    }
    for (child, f, d) in files {
        if f.is_file() {
            read_module(&f, &d, child, mods)?;
        } else if let Some(parent) = mods.get_mut(&child[..child.len() - 1]) {
            // No file: the declaration is a macro's input (`quote! { mod demo; }`), not a module.
            parent.children.retain(|c| Some(c) != child.last());
        }
    }
    Ok(())
}

fn file_dir(f: &Path) -> PathBuf {
    f.parent().map(Path::to_owned).unwrap_or_default()
}

/// The absolute path (from the crate root) that `segs`, named in module `from`, stands for;
/// `None` for a path into another crate (or one that cannot be followed).
fn absolute(mods: &Modules, from: &[String], segs: &[String], hops: usize) -> Option<Vec<String>> {
    let (first, rest) = segs.split_first()?;
    let mut base: Vec<String> = match first.as_str() {
        "crate" => Vec::new(),
        "self" => from.to_vec(),
        "super" => {
            let mut b = from.to_vec();
            b.pop();
            let mut rest = rest;
            while rest.first().map(String::as_str) == Some("super") {
                b.pop();
                rest = &rest[1..];
            }
            b.extend(rest.iter().cloned());
            return Some(b);
        }
        "::" => return None,
        name => {
            let m = mods.get(from)?;
            if m.children.iter().any(|c| c == name) {
                let mut b = from.to_vec();
                b.push(name.to_owned());
                b
            } else if let Some((_, p)) = m.imports.iter().find(|(n, p)| n == name && p.len() > 1) {
                if hops == 0 {
                    return None;
                }
                absolute(mods, from, p, hops - 1)?
            } else {
                return None;
            }
        }
    };
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The module an absolute path ends in, following the imports it meets.
fn module_of(mods: &Modules, abs: &[String], hops: usize) -> Vec<String> {
    let mut cur: Vec<String> = Vec::new();
    for (k, seg) in abs.iter().enumerate() {
        let Some(m) = mods.get(&cur) else { break };
        if m.children.iter().any(|c| c == seg) {
            cur.push(seg.clone());
            continue;
        }
        if hops > 0
            && let Some((_, p)) = m.imports.iter().find(|(n, _)| n == seg)
            && let Some(mut target) = absolute(mods, &cur, p, hops - 1)
        {
            target.extend(abs[k + 1..].iter().cloned());
            return module_of(mods, &target, hops - 1);
        }
        break;
    }
    cur
}

fn name(m: &[String]) -> String {
    if m.is_empty() { "crate".to_owned() } else { m.join("::") }
}

/// The circles of the crate whose root file is `root`.
pub fn circles_of(root: &Path) -> Result<Vec<Circle>, String> {
    let mut mods = Modules::new();
    read_module(root, &file_dir(root), Vec::new(), &mut mods)?;
    // Edges, each with its first reference.
    let mut edges: BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>> = BTreeMap::new();
    for (from, m) in &mods {
        for (p, line) in &m.refs {
            let Some(abs) = absolute(&mods, from, p, 16) else { continue };
            let to = module_of(&mods, &abs, 16);
            if to == *from || from.starts_with(&to) {
                continue; // itself, or an ancestor
            }
            edges
                .entry(from.clone())
                .or_default()
                .entry(to)
                .or_insert_with(|| format!("{}:{line} ({})", m.file.display(), p.join("::")));
        }
    }
    let nodes: Vec<&[String]> = mods.keys().map(Vec::as_slice).collect();
    let mut out = Vec::new();
    for scc in strongly_connected(&nodes, &edges) {
        if scc.len() < 2 {
            continue;
        }
        // A shortest circle through each module of the component, each circle once.
        let mut seen: Vec<Vec<Vec<String>>> = Vec::new();
        for start in &scc {
            let cycle = shortest_circle(start, &scc, &edges);
            let mut key = cycle[1..].to_vec();
            key.sort();
            if seen.contains(&key) {
                continue;
            }
            seen.push(key);
            let evidence = cycle.windows(2).map(|w| edges[&w[0]][&w[1]].clone()).collect();
            out.push(Circle { root: root.to_owned(), modules: cycle.iter().map(|m| name(m)).collect(), evidence });
        }
    }
    Ok(out)
}

/// A shortest circle from `start` back to it inside `scc` (which has one: it is a strongly
/// connected component of more than one module), `start` first and last.
fn shortest_circle(
    start: &[String],
    scc: &[Vec<String>],
    edges: &BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>,
) -> Vec<Vec<String>> {
    let mut prev: BTreeMap<Vec<String>, Vec<String>> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start.to_vec()]);
    let mut back = start.to_vec();
    'search: while let Some(n) = queue.pop_front() {
        for t in edges.get(&n).into_iter().flat_map(|e| e.keys()) {
            if t.as_slice() == start {
                back = n.clone();
                break 'search;
            }
            if scc.contains(t) && !prev.contains_key(t) {
                prev.insert(t.clone(), n.clone());
                queue.push_back(t.clone());
            }
        }
    }
    let mut cycle = vec![back.clone()];
    let mut at = back;
    while at.as_slice() != start {
        at = prev.get(&at).cloned().unwrap_or_else(|| start.to_vec());
        cycle.push(at.clone());
    }
    cycle.reverse();
    cycle.push(start.to_vec());
    cycle
}

/// Tarjan's strongly connected components, each in the order of `nodes`.
fn strongly_connected(
    nodes: &[&[String]],
    edges: &BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>,
) -> Vec<Vec<Vec<String>>> {
    struct State<'a> {
        index: BTreeMap<&'a [String], (usize, usize)>,
        stack: Vec<&'a [String]>,
        next: usize,
        out: Vec<Vec<Vec<String>>>,
    }
    fn visit<'a>(v: &'a [String], edges: &'a BTreeMap<Vec<String>, BTreeMap<Vec<String>, String>>, s: &mut State<'a>) {
        s.index.insert(v, (s.next, s.next));
        s.next += 1;
        s.stack.push(v);
        for w in edges.get(v).into_iter().flat_map(|e| e.keys()) {
            match s.index.get(w.as_slice()) {
                None => {
                    visit(w, edges, s);
                    let low = s.index[w.as_slice()].1.min(s.index[v].1);
                    s.index.get_mut(v).expect("visited").1 = low;
                }
                Some(_) if s.stack.contains(&w.as_slice()) => {
                    let low = s.index[w.as_slice()].0.min(s.index[v].1);
                    s.index.get_mut(v).expect("visited").1 = low;
                }
                Some(_) => {}
            }
        }
        if s.index[v].0 == s.index[v].1 {
            let mut comp = Vec::new();
            while let Some(w) = s.stack.pop() {
                comp.push(w.to_vec());
                if w == v {
                    break;
                }
            }
            comp.sort();
            s.out.push(comp);
        }
    }
    let mut s = State { index: BTreeMap::new(), stack: Vec::new(), next: 0, out: Vec::new() };
    for v in nodes {
        if !s.index.contains_key(*v) {
            visit(v, edges, &mut s);
        }
    }
    s.out
}

/// The crate roots of the workspace at `root`: each member's library, binaries and
/// integration-test crate.
pub fn crate_roots(root: &Path) -> Result<Vec<PathBuf>, String> {
    let manifest = root.join("Cargo.toml");
    let text = std::fs::read_to_string(&manifest).map_err(|e| format!("{}: {e}", manifest.display()))?;
    let at = text.find("members").ok_or_else(|| format!("{}: no workspace members", manifest.display()))?;
    let list = &text[at..];
    let list = &list[list.find('[').unwrap_or(0) + 1..list.find(']').unwrap_or(list.len())];
    let mut roots = Vec::new();
    for member in list.split(',').map(|m| m.trim().trim_matches('"')).filter(|m| !m.is_empty()) {
        let dir = root.join(member);
        for f in ["src/lib.rs", "src/main.rs", "tests/it/main.rs"] {
            if dir.join(f).is_file() {
                roots.push(dir.join(f));
            }
        }
        if let Ok(bins) = std::fs::read_dir(dir.join("src/bin")) {
            let mut bins: Vec<PathBuf> = bins.filter_map(|e| e.ok().map(|e| e.path())).collect();
            bins.sort();
            for b in bins {
                if b.extension().is_some_and(|e| e == "rs") {
                    roots.push(b);
                } else if b.join("main.rs").is_file() {
                    roots.push(b.join("main.rs"));
                }
            }
        }
    }
    if roots.is_empty() {
        return Err(format!("{}: no crate roots found", manifest.display()));
    }
    Ok(roots)
}

/// Every circle of every crate of the workspace at `root`.
pub fn circles(root: &Path) -> Result<Vec<Circle>, String> {
    let mut all = Vec::new();
    for r in crate_roots(root)? {
        all.extend(circles_of(&r)?);
    }
    Ok(all)
}

/// Runs the command: fails naming every circle.
pub fn main(args: &[String]) -> Result<(), String> {
    if !args.is_empty() {
        return Err("usage: cargo xtask deps".to_owned());
    }
    let root = crate::workspace_root();
    let roots = crate_roots(&root)?;
    let found = circles(&root)?;
    if found.is_empty() {
        println!("import graph: no circles in {} crates", roots.len());
        return Ok(());
    }
    let list: Vec<String> = found.iter().map(|c| c.to_string()).collect();
    Err(format!("{} import circle(s):\n{}", found.len(), list.join("\n")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `files` (path, text) into a fresh folder and returns the circles of its
    /// `src/lib.rs`.
    fn circles_in(tag: &str, files: &[(&str, &str)]) -> Vec<Circle> {
        let dir = std::env::temp_dir().join(format!("xtask-deps-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for (p, text) in files {
            let f = dir.join(p);
            std::fs::create_dir_all(f.parent().unwrap()).unwrap();
            std::fs::write(f, text).unwrap();
        }
        let c = circles_of(&dir.join("src/lib.rs")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        c
    }

    fn names(c: &[Circle]) -> Vec<String> {
        c.iter().map(|c| c.modules.join(" -> ")).collect()
    }

    #[test]
    fn a_circle_of_use_lines_is_found_and_named() {
        let c = circles_in(
            "use",
            &[
                ("src/lib.rs", "pub mod a;\npub mod b;\n"),
                ("src/a.rs", "use crate::b::B;\npub struct A;\n"),
                ("src/b.rs", "use crate::a::{self, A};\npub struct B;\n"),
            ],
        );
        assert_eq!(names(&c), ["a -> b -> a"]);
        assert!(c[0].evidence[0].ends_with("a.rs:1 (crate::b::B)"), "{:?}", c[0].evidence);
        assert!(c[0].evidence[1].ends_with("b.rs:1 (crate::a)"), "{:?}", c[0].evidence);
        assert!(c[0].to_string().contains("a -> b: "), "{}", c[0]);
    }

    #[test]
    fn paths_in_code_re_exports_and_nested_modules_are_edges() {
        // a -> m::c through a path in code; m::c -> a through the root's re-export.
        let c = circles_in(
            "code",
            &[
                ("src/lib.rs", "mod a;\nmod m;\npub use a::Thing;\n"),
                ("src/a.rs", "pub struct Thing;\nfn f() { let _ = crate::m::c::run(); }\n"),
                ("src/m/mod.rs", "pub mod c;\n"),
                ("src/m/c.rs", "pub fn run() -> crate::Thing { crate::Thing }\n"),
            ],
        );
        assert_eq!(names(&c), ["a -> m::c -> a"]);
        // Through `super` and a `#[path]` file.
        let c = circles_in(
            "super",
            &[
                ("src/lib.rs", "mod x;\n#[path = \"other/y_file.rs\"]\nmod y;\n"),
                ("src/x.rs", "use super::y::*;\n"),
                ("src/other/y_file.rs", "fn g() { super::x::h() }\n"),
            ],
        );
        assert_eq!(names(&c), ["x -> y -> x"]);
    }

    #[test]
    fn ancestors_comments_strings_and_other_crates_are_not_edges() {
        let c = circles_in(
            "none",
            &[
                ("src/lib.rs", "pub mod a;\npub mod b;\npub struct Root;\nuse a::A;\n"),
                (
                    "src/a.rs",
                    "use crate::b::B;\nuse crate::Root;\npub struct A;\n\
                     #[cfg(test)]\nmod tests { use super::*; use crate::b::B as _; }\n",
                ),
                (
                    "src/b.rs",
                    "//! See [`A`](crate::a::A).\n/// crate::a::A\npub struct B;\n\
                     /* crate::a::A */ const S: &str = \"crate::a::A\";\nconst C: char = '\"';\n\
                     const R: &str = r#\"crate::a::A\"#;\nuse ::other::a::A;\nfn f<'a>(x: &'a u8) {}\n",
                ),
            ],
        );
        assert!(c.is_empty(), "{c:?}");
    }

    #[test]
    fn a_three_module_circle_is_one_circle() {
        let c = circles_in(
            "three",
            &[
                ("src/lib.rs", "mod a;\nmod b;\nmod c;\n"),
                ("src/a.rs", "use crate::b::X;\n"),
                ("src/b.rs", "fn f() { crate::c::g() }\n"),
                ("src/c.rs", "macro_rules! m { () => { $crate::a::Y } }\n"),
            ],
        );
        assert_eq!(names(&c), ["a -> b -> c -> a"]);
    }

    /// The workspace itself: no circles in any crate.
    #[test]
    fn the_workspace_has_no_import_circles() {
        let root = crate::workspace_root();
        let roots = crate_roots(&root).unwrap();
        assert!(roots.iter().any(|r| r.ends_with("od-master/src/lib.rs")), "{roots:?}");
        assert!(roots.iter().any(|r| r.ends_with("od-runtime/src/lib.rs")), "{roots:?}");
        let found = circles(&root).unwrap();
        let list: Vec<String> = found.iter().map(|c| c.to_string()).collect();
        assert!(found.is_empty(), "import circles:\n{}", list.join("\n"));
    }
}
