//! Build-script integration: read device files, generate, write changed files, tell Cargo.

use std::fmt;
use std::path::{Path, PathBuf};

use eds::diag::Severity;

use crate::{Options, expand, render};

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
///   module, and writes `<out_dir>/<module>.rs` **only if its contents changed** (so Cargo and
///   editors do not rebuild for nothing);
/// * prints `cargo:rerun-if-changed=<path>` for **every file it reads**. Note the consequence:
///   once a build script prints one `rerun-if-changed`, Cargo reruns it only when one of the
///   listed files changes, no longer on every change in the package. A build script that also
///   depends on other files must list them itself;
/// * renders every diagnostic rustc-style (`cargo:warning=` lines under Cargo) and fails with
///   [`Error::Diagnostics`] if any is an error, so a broken device file fails the build with
///   `file:line:col` locations.
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
    names: Option<crate::Names>,
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
    /// A device file (or its sidecar) has errors; the text is every diagnostic, rendered.
    Diagnostics(String),
    /// Neither [`Builder::out_dir`] nor `OUT_DIR` is set.
    NoOutDir,
    /// The generator produced tokens that do not parse (a generator bug).
    Render(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Diagnostics(s) => write!(f, "device description has errors:\n{s}"),
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
    /// Diagnostics (warnings and notes; errors make [`Builder::generate`] fail), rendered.
    pub warnings: String,
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
    pub fn sidecar(mut self, path: impl AsRef<Path>) -> Self {
        if let Some(d) = self.devices.last_mut() {
            d.sidecar = SidecarSource::Path(path.as_ref().to_path_buf());
        }
        self
    }

    /// Generates the device added last without a sidecar (no `units` module).
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

    /// Smallest capacity of string and byte buffers (default [`crate::DEFAULT_MIN_CAPACITY`]).
    pub fn min_capacity(mut self, bytes: usize) -> Self {
        self.min_capacity = Some(bytes);
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

    /// Generates every device without writing anything.
    pub fn generate(&self) -> Result<Vec<Output>, Error> {
        let mut outputs = Vec::new();
        let mut errors = String::new();
        for d in &self.devices {
            let shown = d.path.to_string_lossy().replace('\\', "/");
            let path = self.resolve(&d.path);
            let bytes = std::fs::read(&path).map_err(|source| Error::Io { path: path.clone(), source })?;
            let mut inputs = vec![path.clone()];
            let source = eds::source::SourceFile::decode(shown.clone(), &bytes);
            let parsed = eds::parse(&shown, &bytes, &eds::Options::lenient());

            let mut options = Options::new(d.module.clone(), shown.clone());
            options.eds_text = Some(source.text.clone());
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
                match devices::sidecar::Sidecar::read(&sp) {
                    Ok(sc) => options.sidecar = Some(sc),
                    Err(e) => errors.push_str(&format!("error: {e}\n")),
                }
            }

            let generated = expand(&parsed.model, &options);
            let mut diags: Vec<eds::Diagnostic> =
                parsed.diagnostics.iter().filter(|d| d.severity == Severity::Error).cloned().collect();
            diags.extend(generated.diagnostics.iter().filter(|d| d.severity >= Severity::Warning).cloned());
            let (errs, warns): (Vec<_>, Vec<_>) = diags.into_iter().partition(|d| d.severity == Severity::Error);
            if !errs.is_empty() {
                errors.push_str(&eds::diag::render_all(&errs, &source));
            }
            let warnings = warns.iter().map(|w| eds::diag::render(w, &source)).collect::<Vec<_>>().join("\n");
            let text = render(&generated.tokens, &shown).map_err(|e| Error::Render(e.to_string()))?;
            outputs.push(Output {
                module: d.module.clone(),
                file_name: format!("{}.rs", d.module),
                text,
                inputs,
                warnings,
            });
        }
        if !errors.is_empty() {
            return Err(Error::Diagnostics(errors));
        }
        Ok(outputs)
    }

    /// Generates every device and writes the files that changed (see the type's docs).
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
        let outputs = self.generate();
        if metadata && let Err(Error::Diagnostics(text)) = &outputs {
            for line in text.lines() {
                println!("cargo:warning={line}");
            }
        }
        let outputs = outputs?;
        let out_dir = match &self.out_dir {
            Some(d) => d.clone(),
            None => std::env::var_os("OUT_DIR").map(PathBuf::from).ok_or(Error::NoOutDir)?,
        };
        std::fs::create_dir_all(&out_dir).map_err(|source| Error::Io { path: out_dir.clone(), source })?;
        for o in &outputs {
            if metadata {
                for line in o.warnings.lines() {
                    println!("cargo:warning={line}");
                }
            }
            write_if_changed(&out_dir.join(&o.file_name), &o.text)?;
        }
        Ok(())
    }
}

/// Writes `text` to `path` unless the file already holds exactly that; returns whether it wrote.
pub fn write_if_changed(path: &Path, text: &str) -> Result<bool, Error> {
    if std::fs::read(path).is_ok_and(|old| old == text.as_bytes()) {
        return Ok(false);
    }
    std::fs::write(path, text).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    Ok(true)
}
