//! Writing a file the user named without replacing what was not ours to replace.
//!
//! [`write()`] puts new contents at a path the way an editor saves: into a temporary file beside
//! the target, flushed to disk, then renamed over it, so that an interrupted run never leaves
//! half a file. Around that:
//!
//! * a symbolic link is followed (link by link) and its target is written; the link stays a link;
//! * an existing target keeps its permission bits and, where the process may set them, its owner
//!   and group;
//! * a target that is not a regular file (a device such as `/dev/null`, a FIFO, a socket, a
//!   directory) is refused, as is a read-only one (no write permission bit): both with an error
//!   that says so, and nothing is changed;
//! * [`Destination::Stdout`] (`-o -`) writes to standard output.
//!
//! Renaming gives the target a new inode: other hard links to the old one keep the old text.

use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Where output goes: a file, or standard output (`-`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Destination {
    /// Standard output.
    Stdout,
    /// A file, written by [`write()`].
    File(PathBuf),
}

impl Destination {
    /// `-` is standard output; anything else a path.
    pub fn from_arg(path: &Path) -> Self {
        if path.as_os_str() == "-" { Destination::Stdout } else { Destination::File(path.to_owned()) }
    }
}

/// Why a file was not written.
#[derive(Debug)]
pub enum WriteError {
    /// The target exists and is not a regular file (what it is, in words).
    NotRegular(PathBuf, &'static str),
    /// The target is a regular file without any write permission bit.
    ReadOnly(PathBuf),
    /// More than 40 symbolic links in a row (or a loop).
    TooManyLinks(PathBuf),
    /// An error from the system while writing `path`.
    Io(PathBuf, std::io::Error),
}

impl std::fmt::Display for WriteError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WriteError::NotRegular(p, what) => {
                write!(f, "{}: it is {what}, not a regular file; not replacing it", p.display())
            }
            WriteError::ReadOnly(p) => {
                write!(f, "{}: the file is read-only; not replacing it (make it writable first)", p.display())
            }
            WriteError::TooManyLinks(p) => write!(f, "{}: too many levels of symbolic links", p.display()),
            WriteError::Io(p, e) => write!(f, "{}: {e}", p.display()),
        }
    }
}

impl std::error::Error for WriteError {}

/// The file a path names once symbolic links are followed (the path itself when it is not a
/// link). A link to a missing file gives the missing file's path, so it is created there.
pub fn resolve(path: &Path) -> Result<PathBuf, WriteError> {
    let mut current = path.to_owned();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&current).map_err(|e| WriteError::Io(current.clone(), e))?;
                current = match current.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(current),
        }
    }
    Err(WriteError::TooManyLinks(path.to_owned()))
}

/// What a non-regular file is, in words.
fn kind_of(m: &std::fs::Metadata) -> &'static str {
    let t = m.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() { "a directory" } else { "not a regular file" }
}

/// Writes `bytes` to `destination` (see the module documentation).
pub fn write_to(destination: &Destination, bytes: &[u8]) -> Result<(), WriteError> {
    match destination {
        Destination::Stdout => {
            let mut out = std::io::stdout().lock();
            out.write_all(bytes).and_then(|()| out.flush()).map_err(|e| WriteError::Io("<stdout>".into(), e))
        }
        Destination::File(path) => write(path, bytes),
    }
}

/// Replaces the file at `path` (through symbolic links) with `bytes`, atomically, keeping its
/// mode and owner; refuses non-regular and read-only targets. A missing file is created.
pub fn write(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let target = resolve(path)?;
    let existing = match std::fs::metadata(&target) {
        Ok(m) => Some(m),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(WriteError::Io(target, e)),
    };
    if let Some(m) = &existing {
        if !m.file_type().is_file() {
            return Err(WriteError::NotRegular(target, kind_of(m)));
        }
        if m.permissions().readonly() {
            return Err(WriteError::ReadOnly(target));
        }
    }
    let dir = target.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let io = |e| WriteError::Io(target.clone(), e);
    // A name no other file has (`create_new`): never a link someone placed there.
    let (tmp, mut file) = {
        let mut attempt = 0u32;
        loop {
            let tmp = dir.join(format!(".{name}.odgen-{}-{attempt}.tmp", std::process::id()));
            let mut options = std::fs::OpenOptions::new();
            options.write(true).create_new(true);
            #[cfg(unix)]
            if existing.is_some() {
                use std::os::unix::fs::OpenOptionsExt as _;
                // Owner-only until the owner and mode are set below.
                options.mode(0o600);
            }
            match options.open(&tmp) {
                Ok(f) => break (tmp, f),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 100 => attempt += 1,
                Err(e) => return Err(io(e)),
            }
        }
    };
    let result = (|| {
        file.write_all(bytes)?;
        if let Some(m) = &existing {
            #[cfg(unix)]
            {
                use std::os::unix::fs::{MetadataExt as _, PermissionsExt as _};
                // Keep the owner and group where allowed (a user may give a file away only as
                // root; the group only to one of their own): what cannot be kept stays ours.
                if std::os::unix::fs::fchown(&file, Some(m.uid()), Some(m.gid())).is_err() {
                    let _ = std::os::unix::fs::fchown(&file, None, Some(m.gid()));
                }
                file.set_permissions(std::fs::Permissions::from_mode(m.permissions().mode() & 0o7777))?;
            }
            #[cfg(not(unix))]
            file.set_permissions(m.permissions())?;
        }
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, &target)
    })();
    result.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}
