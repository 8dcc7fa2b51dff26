//! Build-script integration: read device files, generate, write changed files, tell Cargo.

use std::fmt;
use std::path::{Path, PathBuf};

use eds::diag::Severity;

use crate::{Options, expand_text};

/// Which sidecar a device uses.
#[derive(Clone, Debug)]
enum SidecarSource {
    /// `<file stem>.toml` beside the description, if it exists.
    Beside,
    /// This file (must exist).
    Path(PathBuf),
    /// None: no `units` module.
    None,
}

#[derive(Clone, Debug)]
struct DeviceSpec {
    module: String,
    path: PathBuf,
    sidecar: SidecarSource,
}

/// Generates device modules from a build script (or from `xtask`), like `prost_build::Config`.
///
/// ```no_run
/// // build.rs: fn main() { … }
/// od_codegen::Builder::new()
///     .device("drvi", "../devices/camozzi-drvi.eds") // sidecar: ../devices/camozzi-drvi.toml
///     .compile()
///     .unwrap_or_else(|e| panic!("{e}"));
/// ```
///
/// and in `src/lib.rs`:
///
/// ```text
/// include!(concat!(env!("OUT_DIR"), "/drvi.rs")); // defines `pub mod drvi`
/// ```
///
/// [`Builder::compile`]:
///
/// * reads each description (EDS or DCF, lenient) and its sidecar, generates and renders the
///   module ([`expand_text`](crate::expand_text): fast in an unoptimised build script, about
///   0.2 s of CPU for a 2,500-entry DCF), and writes `<out_dir>/<module>.rs` **only if its
///   contents changed** (so Cargo and editors do not rebuild for nothing);
/// * prints `cargo:rerun-if-changed=<path>` for **every file it reads**. Note the consequence:
///   once a build script prints one `rerun-if-changed`, Cargo reruns it only when one of the
///   listed files changes, no longer on every change in the package. A build script that also
///   depends on other files must list them itself;
/// * reports what `odgen check` reports for the file (the reader's warnings, the same codes and
///   text) and the generator's own warnings ([`crate::diagnose`]), each as one short
///   `cargo:warning=` line `file:line:col: warning[CODE]: message`, **once per change** of
///   the description, its sidecar or the builder's settings, not on every build (see
///   [`Builder::compile`]); [`Builder::allow`] silences a code; fails with [`Error::Device`]
///   (naming the device, every error rendered rustc-style) when a description has errors; the
///   other devices' files are still written;
/// * generates leniently unless [`Builder::strict`]: a deviation of a vendor's file (see
///   [`crate::diag`]) is a warning and the device still builds;
/// * emits `pub const EDS` only with [`Builder::embed_eds`]; the header names the generator
///   and the description's path relative to the crate.
///
/// The output directory is `OUT_DIR` unless [`Builder::out_dir`] overrides it; `cargo xtask
/// gen` uses that to write the checked-in crate `generated/`.
#[derive(Clone, Debug, Default)]
pub struct Builder {
    devices: Vec<DeviceSpec>,
    out_dir: Option<PathBuf>,
    root: Option<PathBuf>,
    cargo_metadata: Option<bool>,
    min_capacity: Option<usize>,
    strict: bool,
    embed_eds: bool,
    names: Option<crate::Names>,
    client: bool,
    allowed: Vec<String>,
}

/// What went wrong in [`Builder::compile`].
#[derive(Debug)]
pub enum Error {
    /// A file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// One device's description (or its sidecar) has errors.
    Device {
        /// The device's module name.
        module: String,
        /// Its description, as given to [`Builder::device`].
        path: String,
        /// Every error, rendered rustc-style with file:line:col and the offending line.
        rendered: String,
    },
    /// Several devices failed (each an [`Error::Device`] or [`Error::Io`]); the others'
    /// files were still written by [`Builder::compile`].
    Devices(Vec<Error>),
    /// Neither [`Builder::out_dir`] nor `OUT_DIR` is set.
    NoOutDir,
    /// The generator produced tokens that do not parse (a generator bug).
    Render(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Device { module, path, rendered } => {
                write!(f, "device `{module}` ({path}) has errors:\n{rendered}")
            }
            Error::Devices(all) => {
                let names: Vec<String> = all
                    .iter()
                    .map(|e| match e {
                        Error::Device { module, .. } => format!("`{module}`"),
                        Error::Io { path, .. } => path.display().to_string(),
                        other => other.to_string(),
                    })
                    .collect();
                write!(f, "{} devices failed ({}):", all.len(), names.join(", "))?;
                for e in all {
                    write!(f, "\n\n{e}")?;
                }
                Ok(())
            }
            Error::NoOutDir => write!(f, "no output directory: set Builder::out_dir or run from a build script"),
            Error::Render(s) => write!(f, "od-codegen produced invalid code (a bug, please report): {s}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// One generated file, before writing.
#[derive(Clone, Debug)]
pub struct Output {
    /// Module name.
    pub module: String,
    /// `<module>.rs`.
    pub file_name: String,
    /// The rendered file.
    pub text: String,
    /// Every file read to produce it.
    pub inputs: Vec<PathBuf>,
    /// The description's text, as the diagnostics' locations refer to it.
    pub source: eds::source::SourceFile,
    /// Every diagnostic worth showing: the reader's and the generator's warnings and errors
    /// (what `odgen check` shows for the file), without the codes [`Builder::allow`] silences,
    /// in file order. [`Builder::generate`] fails when one is an error.
    pub diagnostics: Vec<eds::Diagnostic>,
}

impl Output {
    /// Whether a diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }

    /// The diagnostics rendered rustc-style (file:line:col, the offending line, hints).
    pub fn rendered(&self, min: Severity) -> String {
        let shown: Vec<eds::Diagnostic> = self.diagnostics.iter().filter(|d| d.severity >= min).cloned().collect();
        eds::diag::render_all(&shown, &self.source)
    }

    /// One line per diagnostic: `file:line:col: warning[G0104]: in …: message (hint: …)`.
    pub fn headlines(&self, min: Severity) -> Vec<String> {
        let shown: Vec<eds::Diagnostic> = self.diagnostics.iter().filter(|d| d.severity >= min).cloned().collect();
        crate::diag::render_plain(&shown).lines().map(str::to_owned).collect()
    }

    /// One short line per diagnostic of at least `min`: `file:line:col: warning[G0104]:
    /// message` (no context, no hint: `odgen check` gives those), the form of a
    /// `cargo:warning=` line.
    pub fn short_lines(&self, min: Severity) -> Vec<String> {
        self.diagnostics.iter().filter(|d| d.severity >= min).map(crate::diag::short_line).collect()
    }
}

impl Builder {
    /// A builder with no devices.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a device: module `module` from the EDS or DCF at `path` (relative paths are relative
    /// to [`Builder::root`], else to the working directory, which for a build script is the
    /// package's directory). Its sidecar is `<stem>.toml` beside it, if that exists.
    pub fn device(mut self, module: impl Into<String>, path: impl AsRef<Path>) -> Self {
        self.devices.push(DeviceSpec {
            module: module.into(),
            path: path.as_ref().to_path_buf(),
            sidecar: SidecarSource::Beside,
        });
        self
    }

    /// Uses `path` as the sidecar of the device added last.
    ///
    /// A device's sidecar serves any file of the same drive: a vendor's own EDS of a drive the
    /// project describes gets the project's units with
    /// `.device("akd", "vendor/AKD.eds").sidecar("devices/kollmorgen-akd.toml")` (the sidecar
    /// refers to objects by index, so the vendor's names do not matter; an object the file
    /// lacks is a G0201 error naming it). For a drive no sidecar describes, `odgen sidecar
    /// FILE -o FILE.toml` writes a starting one from the file's CiA 402 objects.
    pub fn sidecar(mut self, path: impl AsRef<Path>) -> Self {
        if let Some(d) = self.devices.last_mut() {
            d.sidecar = SidecarSource::Path(path.as_ref().to_path_buf());
        }
        self
    }

    /// Generates the device added last without a sidecar file: a file with CiA 402 objects
    /// still gets its `units` module and dimensions, from its own unit objects
    /// (`od_codegen::standard::starting_sidecar`); other files get none.
    pub fn no_sidecar(mut self) -> Self {
        if let Some(d) = self.devices.last_mut() {
            d.sidecar = SidecarSource::None;
        }
        self
    }

    /// Writes to `dir` instead of `OUT_DIR`.
    pub fn out_dir(mut self, dir: impl AsRef<Path>) -> Self {
        self.out_dir = Some(dir.as_ref().to_path_buf());
        self
    }

    /// Resolves relative device paths against `dir`; the paths as given still name the files
    /// in headers and diagnostics (so output does not depend on where it was generated).
    pub fn root(mut self, dir: impl AsRef<Path>) -> Self {
        self.root = Some(dir.as_ref().to_path_buf());
        self
    }

    /// Whether to print `cargo:` lines (default: when `OUT_DIR` is set, i.e. in a build script).
    pub fn cargo_metadata(mut self, on: bool) -> Self {
        self.cargo_metadata = Some(on);
        self
    }

    /// Strict mode: every deviation of a description (see [`crate::diag`]: a default PDO
    /// mapping that breaks a mapping rule, a limit outside the entry's type, …) is an error that
    /// fails the build, instead of a warning. For authors who own their file.
    pub fn strict(mut self) -> Self {
        self.strict = true;
        self
    }

    /// Whether each module gets `pub const EDS: &str`, the description's text (line ends
    /// normalised to `\n`, as a raw string). Default: off.
    pub fn embed_eds(mut self, on: bool) -> Self {
        self.embed_eds = on;
        self
    }

    /// Smallest capacity of string and byte buffers (default [`crate::DEFAULT_MIN_CAPACITY`]).
    pub fn min_capacity(mut self, bytes: usize) -> Self {
        self.min_capacity = Some(bytes);
        self
    }

    /// Whether each module also gets the master's view of the device, `pub mod remote` with a
    /// typed `Remote` on `od_master::Node` (see `od_master::remote`). Default: off. The crate
    /// that includes the code then depends on `od-master` and is not `no_std`.
    pub fn client(mut self, on: bool) -> Self {
        self.client = on;
        self
    }

    /// Silences diagnostic code `code` (`"G0104"`, `"E0301"`, …) for every device, as rustc's
    /// and clippy's `allow` do: its warnings and notes are not printed (errors still fail the
    /// build). `odgen check --allow CODE` and `include_eds!(…, allow(CODE))` do the same.
    pub fn allow(mut self, code: impl Into<String>) -> Self {
        self.allowed.push(code.into());
        self
    }

    /// Whether the generated code keeps the entries' names (default [`crate::Names::Always`]).
    pub fn names(mut self, names: crate::Names) -> Self {
        self.names = Some(names);
        self
    }

    fn resolve(&self, p: &Path) -> PathBuf {
        match &self.root {
            Some(r) if p.is_relative() => r.join(p),
            _ => p.to_path_buf(),
        }
    }

    fn metadata(&self) -> bool {
        self.cargo_metadata.unwrap_or_else(|| std::env::var_os("OUT_DIR").is_some())
    }

    /// The name a file is shown by in headers and diagnostics: the path as given when it is
    /// relative; an absolute one relative to [`Builder::root`] (else the working directory,
    /// a build script's package), so no absolute path ends up in generated code.
    fn shown(&self, p: &Path) -> String {
        let shown = if p.is_absolute() {
            let base = match &self.root {
                Some(r) if r.is_absolute() => Some(r.clone()),
                Some(r) => std::env::current_dir().ok().map(|d| d.join(r)),
                None => std::env::current_dir().ok(),
            };
            base.and_then(|b| relative_path(&b, p))
                .unwrap_or_else(|| p.file_name().map(PathBuf::from).unwrap_or_default())
        } else {
            p.to_path_buf()
        };
        shown.to_string_lossy().replace('\\', "/")
    }

    /// Generates one device; `Err` only when a file cannot be read or the tokens do not parse
    /// (diagnostics, errors included, are in the output).
    fn generate_device(&self, d: &DeviceSpec) -> Result<Output, Error> {
        let shown = self.shown(&d.path);
        let path = self.resolve(&d.path);
        let bytes = std::fs::read(&path).map_err(|source| Error::Io { path: path.clone(), source })?;
        let mut inputs = vec![path.clone()];
        let parsed = eds::parse(&shown, &bytes, &eds::Options::lenient());
        let source = parsed.document.source.clone();
        // What `odgen check` shows for the file (its default level: warnings and errors).
        let mut diagnostics: Vec<eds::Diagnostic> =
            parsed.diagnostics.iter().filter(|d| d.severity >= Severity::Warning).cloned().collect();

        let mut options = Options::new(d.module.clone(), shown.clone());
        options.strict = self.strict;
        options.client = self.client;
        if self.embed_eds {
            options.eds_text = Some(source.text.clone());
        }
        if let Some(n) = self.min_capacity {
            options.min_capacity = n;
        }
        if let Some(n) = &self.names {
            options.names = n.clone();
        }
        let sidecar_path = match &d.sidecar {
            SidecarSource::Beside => Some(path.with_extension("toml")).filter(|p| p.is_file()),
            SidecarSource::Path(p) => Some(self.resolve(p)),
            SidecarSource::None => None,
        };
        if let Some(sp) = sidecar_path {
            inputs.push(sp.clone());
            match crate::sidecar::Sidecar::read(&sp) {
                Ok(sc) => options.sidecar = Some(sc),
                Err(e) => diagnostics.push(eds::Diagnostic {
                    severity: Severity::Error,
                    code: crate::diag::SIDECAR,
                    message: e.to_string(),
                    file: shown.as_str().into(),
                    span: None,
                    at: None,
                    context: Vec::new(),
                    hint: None,
                }),
            }
        }

        let generated = expand_text(&parsed.model, &options);
        let text = generated.render(&shown).map_err(|e| Error::Render(e.to_string()))?;
        diagnostics.extend(generated.diagnostics.into_iter().filter(|d| d.severity >= Severity::Warning));
        diagnostics.retain(|d| crate::shown(d, &self.allowed));
        // In file order, reader's and generator's together (unlocated ones last).
        diagnostics.sort_by_key(|d| d.at.map_or((u32::MAX as usize, 0), |a| (a.line as usize, a.col as usize)));
        Ok(Output {
            module: d.module.clone(),
            file_name: format!("{}.rs", d.module),
            text,
            inputs,
            source,
            diagnostics,
        })
    }

    /// Generates every device without writing anything, with every diagnostic, errors
    /// included ([`Output::has_errors`]): `Err` only when a file cannot be read or the tokens
    /// do not parse. For tools that print the diagnostics themselves (`odgen gen`).
    pub fn generate_all(&self) -> Vec<Result<Output, Error>> {
        self.devices.iter().map(|d| self.generate_device(d)).collect()
    }

    /// Generates every device without writing anything: one result per device, in the order
    /// they were added; a device with errors is an [`Error::Device`]. A device's errors never
    /// hide another's output.
    pub fn generate_each(&self) -> Vec<Result<Output, Error>> {
        self.devices
            .iter()
            .map(|d| {
                let o = self.generate_device(d)?;
                if o.has_errors() {
                    return Err(Error::Device {
                        module: o.module.clone(),
                        path: self.shown(&d.path),
                        rendered: o.rendered(Severity::Error),
                    });
                }
                Ok(o)
            })
            .collect()
    }

    /// Generates every device without writing anything; fails if any device fails (with every
    /// failing device's errors).
    pub fn generate(&self) -> Result<Vec<Output>, Error> {
        let (ok, failed): (Vec<_>, Vec<_>) = self.generate_each().into_iter().partition(Result::is_ok);
        let mut failed: Vec<Error> = failed.into_iter().filter_map(Result::err).collect();
        match failed.len() {
            0 => Ok(ok.into_iter().filter_map(Result::ok).collect()),
            1 => Err(failed.remove(0)),
            _ => Err(Error::Devices(failed)),
        }
    }

    /// Generates every device and writes the files that changed (see the type's docs). A device
    /// with errors fails the build, naming it, but every other device's file is still written.
    ///
    /// Warnings are printed once per change. Cargo shows a build script's `cargo:warning`
    /// lines again on every build that does not rerun it (it replays the script's stored
    /// output), so the builder keeps the lines it printed, with a digest of the inputs, in
    /// `<out_dir>/<module>.diagnostics` and lists that file with `rerun-if-changed`: a build
    /// after a change prints the lines and writes the file, which makes Cargo run the script
    /// once more; that run finds the same lines and inputs, prints nothing and leaves the file
    /// alone, and from then on Cargo has nothing to replay and does not rerun the script.
    pub fn compile(&self) -> Result<(), Error> {
        let metadata = self.metadata();
        if metadata {
            for d in &self.devices {
                let path = self.resolve(&d.path);
                println!("cargo:rerun-if-changed={}", path.display());
                match &d.sidecar {
                    SidecarSource::Beside => {
                        let s = path.with_extension("toml");
                        if s.is_file() {
                            println!("cargo:rerun-if-changed={}", s.display());
                        }
                    }
                    SidecarSource::Path(p) => println!("cargo:rerun-if-changed={}", self.resolve(p).display()),
                    SidecarSource::None => {}
                }
            }
        }
        let out_dir = match &self.out_dir {
            Some(d) => d.clone(),
            None => std::env::var_os("OUT_DIR").map(PathBuf::from).ok_or(Error::NoOutDir)?,
        };
        std::fs::create_dir_all(&out_dir).map_err(|source| Error::Io { path: out_dir.clone(), source })?;
        let mut failed = Vec::new();
        for d in &self.devices {
            let o = match self.generate_device(d) {
                Ok(o) => o,
                Err(e) => {
                    failed.push(e);
                    continue;
                }
            };
            // Each warning once per change, as one short line with its location (see above);
            // errors go into the returned error, rendered in full, which the build script
            // prints.
            if metadata && !o.has_errors() {
                let stamp = out_dir.join(format!("{}.diagnostics", o.module));
                println!("cargo:rerun-if-changed={}", stamp.display());
                let lines = o.short_lines(Severity::Warning);
                let mut text = format!("# generated {:016x}\n", digest(&[&o.source.text, &o.text]));
                for l in &lines {
                    text.push_str(l);
                    text.push('\n');
                }
                let old = std::fs::read_to_string(&stamp).ok();
                if old.as_deref() != Some(text.as_str()) {
                    for l in &lines {
                        println!("cargo:warning={l}");
                    }
                    if !lines.is_empty() {
                        println!(
                            "cargo:warning={}: {} warning{} from od-codegen, shown once per change of the file; \
                             `odgen check {}` explains each, `Builder::allow(\"CODE\")` silences a code",
                            self.shown(&d.path),
                            lines.len(),
                            if lines.len() == 1 { "" } else { "s" },
                            self.shown(&d.path)
                        );
                    }
                    if let Err(e) = std::fs::write(&stamp, &text) {
                        failed.push(Error::Io { path: stamp, source: e });
                    }
                }
            }
            if o.has_errors() {
                failed.push(Error::Device {
                    module: o.module.clone(),
                    path: self.shown(&d.path),
                    rendered: o.rendered(Severity::Error),
                });
                continue;
            }
            if let Err(e) = write_if_changed(&out_dir.join(&o.file_name), &o.text) {
                failed.push(e);
            }
        }
        match failed.len() {
            0 => Ok(()),
            1 => Err(failed.remove(0)),
            _ => Err(Error::Devices(failed)),
        }
    }
}

/// A digest of the description's text and the generated text: it changes with every change
/// of the file (a comment included: "once per change of the file"), of its sidecar or of the
/// settings that change what is generated.
fn digest(texts: &[&str]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    texts.hash(&mut h);
    h.finish()
}

/// `path` relative to `base` (both absolute), with `..` where needed; `None` when they share
/// no root (another drive).
fn relative_path(base: &Path, path: &Path) -> Option<PathBuf> {
    use std::path::Component;
    fn norm(p: &Path) -> Vec<Component<'_>> {
        p.components().filter(|c| *c != Component::CurDir).collect()
    }
    let (b, p) = (norm(base), norm(path));
    if b.first() != p.first() {
        return None;
    }
    let common = b.iter().zip(&p).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &p[common..] {
        out.push(c.as_os_str());
    }
    Some(out)
}

/// Writes `text` to `path` unless the file already holds exactly that; returns whether it wrote.
pub fn write_if_changed(path: &Path, text: &str) -> Result<bool, Error> {
    if std::fs::read(path).is_ok_and(|old| old == text.as_bytes()) {
        return Ok(false);
    }
    std::fs::write(path, text).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    Ok(true)
}
