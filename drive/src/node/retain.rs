//! Retained data: what a device keeps across power cycles outside its object dictionary.
//!
//! 1010h saves *parameters*. Some drives also keep *state* by themselves, without a master
//! asking: the Camozzi DRVI (5.0.3) saves its actual position at power-off when it is homed and
//! standing, and takes it back at power-on so the homing need not be repeated. An application
//! keeps such state through [`Ctx::retained`](super::Ctx::retained) and
//! [`Ctx::retain`](super::Ctx::retain); the node stores it with a [`Retain`] backend:
//!
//! * [`MemoryRetain`] (the default): survives resets of the node, and a new node given a clone
//!   of the same `MemoryRetain` (a simulated power cycle in a test), not the process;
//! * [`FileRetain`]: a file in the state directory (`drive-sim --state-dir`,
//!   `<dir>/<kind>-node<id>.retained`), written atomically (temporary file, fsync, rename,
//!   fsync of the directory) and checked on load, so a process killed at any moment leaves the
//!   old data or the new, never a torn mix.
//!
//! # The file format
//!
//! ```text
//! magic     4 bytes  "ODRT"
//! version   1 byte   1
//! length    u32 LE   of the data
//! data      length bytes (the application's own encoding)
//! checksum  u32 LE   CRC-32 (IEEE) of every byte before it
//! ```

use std::fmt;
use std::fs::{self, File};
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use crate::storage::crc32;

/// File magic of retained data.
pub const MAGIC: [u8; 4] = *b"ODRT";
/// Format version written and accepted.
pub const VERSION: u8 = 1;
/// Largest retained data accepted (an application keeps a few numbers, not a file system).
pub const MAX_LEN: usize = 64 * 1024;

/// Where a node keeps its application's retained data.
pub trait Retain: Send {
    /// The data stored last, if any is there and intact.
    fn load(&mut self) -> Option<Vec<u8>>;

    /// Replaces the stored data as one step: whoever loads afterwards (this process or the
    /// next) gets either the previous data or `data`.
    fn store(&mut self, data: &[u8]) -> io::Result<()>;
}

/// Retained data in memory. Clones share the data, so a test can hand a clone to the node that
/// replaces a "switched off" one.
///
/// ```
/// use drive::node::{MemoryRetain, Retain};
///
/// let mut a = MemoryRetain::new();
/// let mut b = a.clone();
/// a.store(b"homed at 1234").unwrap();
/// assert_eq!(b.load().as_deref(), Some(&b"homed at 1234"[..]));
/// ```
#[derive(Clone, Debug, Default)]
pub struct MemoryRetain {
    data: Arc<Mutex<Option<Vec<u8>>>>,
}

impl MemoryRetain {
    /// Nothing retained yet.
    pub fn new() -> Self {
        Self::default()
    }
}

impl Retain for MemoryRetain {
    fn load(&mut self) -> Option<Vec<u8>> {
        self.data.lock().ok().and_then(|d| d.clone())
    }

    fn store(&mut self, data: &[u8]) -> io::Result<()> {
        if data.len() > MAX_LEN {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "retained data too long"));
        }
        let mut d = self.data.lock().map_err(|_| io::Error::other("retained data lock poisoned"))?;
        *d = Some(data.to_vec());
        Ok(())
    }
}

/// Retained data in a file, written atomically: temporary file, fsync, rename, fsync of the
/// directory, so a process killed at any moment leaves the old data or the new. The file is
/// `"ODRT"`, a version byte (1), the data's length (u32 LE), the data, and a CRC-32 (IEEE) of
/// all that; a file that fails the checks is ignored with a warning.
///
/// ```
/// use drive::node::{FileRetain, Retain};
///
/// let dir = std::env::temp_dir().join(format!("drive-doc-retain-{}", std::process::id()));
/// let mut r = FileRetain::open(&dir, "drvi-node3").unwrap();
/// assert_eq!(r.load(), None);
/// r.store(&[1, 2, 3]).unwrap();
/// // The next process finds it.
/// assert_eq!(FileRetain::open(&dir, "drvi-node3").unwrap().load(), Some(vec![1, 2, 3]));
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub struct FileRetain {
    dir: PathBuf,
    path: PathBuf,
    tmp: PathBuf,
}

impl fmt::Debug for FileRetain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FileRetain").field("path", &self.path).finish()
    }
}

impl FileRetain {
    /// `<dir>/<tag>.retained` (the directory is created if missing; `tag` as for
    /// [`FileStorage::open`](crate::storage::FileStorage::open): letters, digits, `-`, `_`,
    /// `.`, at most 64 bytes). A temporary file an interrupted store left behind is removed.
    pub fn open(dir: impl AsRef<Path>, tag: &str) -> io::Result<Self> {
        crate::storage::check_tag(tag, "retained-data")?;
        let dir = dir.as_ref().to_path_buf();
        fs::create_dir_all(&dir)?;
        let path = dir.join(format!("{tag}.retained"));
        let tmp = dir.join(format!("{tag}.retained.tmp"));
        if tmp.exists() {
            let _ = fs::remove_file(&tmp);
        }
        Ok(Self { dir, path, tmp })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads and checks the file: `Ok(None)` without one, `Err` with what is wrong.
    pub fn read(&self) -> Result<Option<Vec<u8>>, String> {
        let file = match File::open(&self.path) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: {e}", self.path.display())),
        };
        let mut bytes = Vec::new();
        file.take((MAX_LEN + 13) as u64 + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| format!("{}: {e}", self.path.display()))?;
        decode(&bytes).map(Some).map_err(|e| format!("{}: {e}", self.path.display()))
    }
}

/// The file image of `data`.
pub fn encode(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + 13);
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// The data of a file image, checked.
pub fn decode(bytes: &[u8]) -> Result<Vec<u8>, String> {
    if bytes.len() < 13 {
        return Err(format!("{} bytes is too short for retained data", bytes.len()));
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    let crc = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if crc32(body) != crc {
        return Err("checksum mismatch (torn or altered)".into());
    }
    if body[..4] != MAGIC {
        return Err("not retained data (bad magic)".into());
    }
    if body[4] != VERSION {
        return Err(format!("version {} (expected {VERSION})", body[4]));
    }
    let len = u32::from_le_bytes([body[5], body[6], body[7], body[8]]) as usize;
    if len != body.len() - 9 || len > MAX_LEN {
        return Err(format!("length {len} does not match the file"));
    }
    Ok(body[9..].to_vec())
}

impl Retain for FileRetain {
    fn load(&mut self) -> Option<Vec<u8>> {
        match self.read() {
            Ok(data) => data,
            Err(message) => {
                eprintln!("warning: ignoring retained data: {message}");
                None
            }
        }
    }

    fn store(&mut self, data: &[u8]) -> io::Result<()> {
        if data.len() > MAX_LEN {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "retained data too long"));
        }
        crate::storage::write_atomically(&self.dir, &self.tmp, &self.path, &encode(data))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn images_round_trip_and_every_corruption_is_detected() {
        let data = b"position 12345, homed".to_vec();
        let bytes = encode(&data);
        assert_eq!(decode(&bytes), Ok(data));
        for n in 0..bytes.len() {
            assert!(decode(&bytes[..n]).is_err(), "truncated to {n}");
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[i] ^= 1 << bit;
                assert!(decode(&b).is_err(), "byte {i} bit {bit}");
            }
        }
        assert_eq!(decode(&encode(&[])), Ok(vec![]));
    }

    #[test]
    fn bad_tags_are_refused() {
        let dir = std::env::temp_dir();
        for tag in ["", ".hidden", "a/b", "x".repeat(65).as_str()] {
            assert!(FileRetain::open(&dir, tag).is_err(), "{tag:?}");
        }
    }
}
