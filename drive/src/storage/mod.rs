//! Where a simulated device keeps the parameters a master saves with 1010h ("store
//! parameters"): [`FileStorage`] on disk, [`MemoryStorage`] in memory.
//!
//! Both implement od-runtime's [`Storage`] trait. The runtime decides what is stored (every
//! writable entry of an area, as `(index, sub, bytes)` records) and when (a `save` written to
//! 1010h; stored values are loaded at every reset); a backend only keeps the records.
//!
//! # The file format
//!
//! [`FileStorage`] keeps every area in one file, `<dir>/<tag>.params` (`drvi-node2.params`), so
//! that a 1010h "save all" replaces the three areas as one step: a process killed at any
//! moment leaves all three from the old save or all three from the new one. The file (format
//! version 2) is a header and one area image per saved area:
//!
//! ```text
//! magic     4 bytes  "ODRS"
//! version   1 byte   2
//! tag       1 byte length + that many bytes
//! count     u8       number of area images
//! images    count × (length u32 LE, an area image as below)
//! checksum  u32 LE   CRC-32 (IEEE) of every byte before it
//! ```
//!
//! An area image (format version 1; earlier releases kept each in a file of its own,
//! `<tag>.<area>.params`, which is still read while no `<tag>.params` exists and removed by
//! the first save):
//!
//! ```text
//! magic     4 bytes  "ODRS"
//! version   1 byte   1
//! area      1 byte   1 communication, 2 application, 3 manufacturer
//! tag       1 byte length + that many bytes (the device tag, e.g. "drvi-node2")
//! count     u32 LE   number of records
//! records   count × (index u16 LE, sub u8, length u16 LE, data)
//! checksum  u32 LE   CRC-32 (IEEE) of every byte before it
//! ```
//!
//! A save is atomic: the file is written to `<file>.tmp`, flushed to disk (`fsync`), renamed
//! over the old file, and the directory is flushed so the rename itself survives a power cut.
//! A reader therefore sees either the old file or the new one. A save of one area (1010h sub
//! 2, 3, 4) writes the file with that area replaced and the others as they were; a save of
//! all (sub 1) is one transaction ([`Storage::begin_transaction`]): the three images are kept
//! aside and written in one file. A file that is torn anyway (written by something else, a
//! disk error) or altered fails a checksum or the structure check; it is then ignored with a
//! warning, and the device starts from its defaults, as a real drive does after a checksum
//! error in its parameter flash. ([`FileStorage::with_io_hook`] lets tests stop a save at any
//! step, as a kill would.)

use std::fmt;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use od_runtime::Storage;
use od_runtime::lss::LssConfig;
use od_runtime::od::{AbortCode, Area};

/// File magic of a stored parameter image.
pub const MAGIC: [u8; 4] = *b"ODRS";
/// Format version of an area image.
pub const VERSION: u8 = 1;
/// Format version of the file holding every area ([`encode_set`]).
pub const SET_VERSION: u8 = 2;

/// Largest stored image accepted when loading (a device dictionary has a few thousand entries
/// of a few bytes; anything this large is not ours).
const MAX_FILE: u64 = 16 * 1024 * 1024;

/// Where warnings go: by default standard error, prefixed with the tag.
pub type WarningSink = Arc<dyn Fn(&str) + Send + Sync>;

/// CRC-32 as used by zip, PNG and Ethernet (IEEE 802.3, reflected polynomial 0xEDB88320, initial
/// value and final XOR 0xFFFFFFFF).
///
/// ```
/// assert_eq!(drive::storage::crc32(b"123456789"), 0xCBF4_3926);
/// ```
pub fn crc32(data: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
                k += 1;
            }
            table[i] = c;
            i += 1;
        }
        table
    };
    let mut crc = 0xFFFF_FFFFu32;
    for &b in data {
        crc = TABLE[((crc ^ u32::from(b)) & 0xFF) as usize] ^ (crc >> 8);
    }
    !crc
}

/// One stored value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value as little-endian bytes, as on the bus.
    pub data: Vec<u8>,
}

fn area_code(area: Area) -> Option<u8> {
    match area {
        Area::Communication => Some(1),
        Area::Application => Some(2),
        Area::Manufacturer => Some(3),
        Area::All => None,
    }
}

fn area_file_suffix(area: Area) -> &'static str {
    match area {
        Area::Communication => "comm",
        Area::Application => "app",
        Area::Manufacturer => "mfr",
        Area::All => "all",
    }
}

/// Why a stored image was not accepted.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ImageError {
    /// The file ends before its structure says it should.
    #[error("truncated (file ends inside the {0})")]
    Truncated(&'static str),
    /// Not a parameter image.
    #[error("not a parameter image (bad magic)")]
    Magic,
    /// Written by another version of the format.
    #[error("format version {0} is not supported (expected {VERSION})")]
    Version(u8),
    /// The checksum does not match the contents: a torn or altered file.
    #[error("checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): torn or corrupt file")]
    Checksum {
        /// The checksum in the file.
        stored: u32,
        /// The checksum of the contents.
        computed: u32,
    },
    /// The image belongs to another area.
    #[error("image of area {found} where area {expected} was expected")]
    Area {
        /// Area code expected.
        expected: u8,
        /// Area code found.
        found: u8,
    },
    /// The image belongs to another device.
    #[error("image of device '{found}' where '{expected}' was expected")]
    Tag {
        /// Tag expected.
        expected: String,
        /// Tag found.
        found: String,
    },
    /// Bytes after the last record.
    #[error("{0} unexpected bytes after the last record")]
    Trailing(usize),
}

/// Serialises an image (see the module docs for the layout).
pub fn encode_image(area: Area, tag: &str, records: &[Record]) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + tag.len() + records.iter().map(|r| 5 + r.data.len()).sum::<usize>());
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.push(area_code(area).unwrap_or(0));
    let tag = &tag.as_bytes()[..tag.len().min(255)];
    out.push(tag.len() as u8);
    out.extend_from_slice(tag);
    out.extend_from_slice(&(records.len() as u32).to_le_bytes());
    for r in records {
        let data = &r.data[..r.data.len().min(usize::from(u16::MAX))];
        out.extend_from_slice(&r.index.to_le_bytes());
        out.push(r.sub);
        out.extend_from_slice(&(data.len() as u16).to_le_bytes());
        out.extend_from_slice(data);
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Serialises the file holding the images of several areas (see the module docs).
pub fn encode_set(tag: &str, images: &[(Area, &[Record])]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.push(SET_VERSION);
    let tag_bytes = &tag.as_bytes()[..tag.len().min(255)];
    out.push(tag_bytes.len() as u8);
    out.extend_from_slice(tag_bytes);
    out.push(images.len().min(255) as u8);
    for (area, records) in images.iter().take(255) {
        let image = encode_image(*area, tag, records);
        out.extend_from_slice(&(image.len() as u32).to_le_bytes());
        out.extend_from_slice(&image);
    }
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Parses and verifies a file written by [`encode_set`] for `tag`: the records of each area it
/// holds. Never panics, whatever the bytes.
pub fn decode_set(bytes: &[u8], tag: &str) -> Result<Vec<(Area, Vec<Record>)>, ImageError> {
    if bytes.len() < 4 || bytes[..4] != MAGIC {
        return Err(if bytes.len() < 4 && MAGIC.starts_with(bytes) {
            ImageError::Truncated("header")
        } else {
            ImageError::Magic
        });
    }
    if bytes.len() < 4 + 1 + 1 + 1 + 4 {
        return Err(ImageError::Truncated("header"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let mut r = Reader { bytes: body, pos: 4 };
    let version = r.u8("header")?;
    if version != SET_VERSION {
        return Err(ImageError::Version(version));
    }
    let computed = crc32(body);
    if stored != computed {
        return Err(ImageError::Checksum { stored, computed });
    }
    r.expect_tag(tag)?;
    let count = r.u8("header")?;
    let mut areas = Vec::with_capacity(usize::from(count));
    for _ in 0..count {
        let len = r.u32("image length")?;
        let image = r.take(len as usize, "image")?;
        let code = *image.get(5).ok_or(ImageError::Truncated("image"))?;
        let area = AREAS
            .into_iter()
            .find(|&a| area_code(a) == Some(code))
            .ok_or(ImageError::Area { expected: 0, found: code })?;
        areas.push((area, decode_image(image, area, tag)?));
    }
    if r.pos != body.len() {
        return Err(ImageError::Trailing(body.len() - r.pos));
    }
    Ok(areas)
}

/// The images of a parameter file: each area's records.
type AreaImages = Vec<(Area, Vec<Record>)>;

/// The areas a file can hold, in file order.
const AREAS: [Area; 3] = [Area::Communication, Area::Application, Area::Manufacturer];

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], ImageError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or(ImageError::Truncated(what))?;
        let out = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(out)
    }

    fn u8(&mut self, what: &'static str) -> Result<u8, ImageError> {
        Ok(self.take(1, what)?[0])
    }

    /// The device tag (a length byte, then the text): `tag`, or [`ImageError::Tag`] with what
    /// the file holds (a file of another device is never loaded).
    fn expect_tag(&mut self, tag: &str) -> Result<(), ImageError> {
        let len = self.u8("header")?;
        let found = self.take(usize::from(len), "tag")?;
        if found != tag.as_bytes() {
            return Err(ImageError::Tag {
                expected: tag.to_owned(),
                found: String::from_utf8_lossy(found).into_owned(),
            });
        }
        Ok(())
    }

    fn u16(&mut self, what: &'static str) -> Result<u16, ImageError> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self, what: &'static str) -> Result<u32, ImageError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// Parses and verifies an image written by [`encode_image`] for `area` and `tag`. Never
/// panics, whatever the bytes.
pub fn decode_image(bytes: &[u8], area: Area, tag: &str) -> Result<Vec<Record>, ImageError> {
    if bytes.len() < 4 || bytes[..4] != MAGIC {
        return Err(if bytes.len() < 4 && MAGIC.starts_with(bytes) {
            ImageError::Truncated("header")
        } else {
            ImageError::Magic
        });
    }
    if bytes.len() < 4 + 1 + 1 + 1 + 4 + 4 {
        return Err(ImageError::Truncated("header"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let computed = crc32(body);
    let mut r = Reader { bytes: body, pos: 4 };
    let version = r.u8("header")?;
    if version != VERSION {
        return Err(ImageError::Version(version));
    }
    if stored != computed {
        return Err(ImageError::Checksum { stored, computed });
    }
    let found_area = r.u8("header")?;
    let expected = area_code(area).unwrap_or(0);
    if found_area != expected {
        return Err(ImageError::Area { expected, found: found_area });
    }
    r.expect_tag(tag)?;
    let count = r.u32("header")?;
    // Each record takes at least 5 bytes: bound the allocation by what the file can hold.
    let mut records = Vec::with_capacity((count as usize).min(body.len() / 5));
    for _ in 0..count {
        let index = r.u16("record")?;
        let sub = r.u8("record")?;
        let len = r.u16("record")?;
        let data = r.take(usize::from(len), "record data")?.to_vec();
        records.push(Record { index, sub, data });
    }
    if r.pos != body.len() {
        return Err(ImageError::Trailing(body.len() - r.pos));
    }
    Ok(records)
}

/// Parameter images in memory: saving works, and stored values survive NMT resets, but not the
/// process. What `drive-sim` uses without `--state-dir`.
#[derive(Clone, Debug, Default)]
pub struct MemoryStorage {
    images: [Option<Vec<Record>>; 3],
    pending: Option<(Area, Vec<Record>)>,
    /// The LSS configuration stored (CiA 305).
    lss: Option<LssConfig>,
}

impl MemoryStorage {
    /// Empty storage.
    pub fn new() -> Self {
        Self::default()
    }

    /// The committed image of `area`, if one was saved.
    pub fn image(&self, area: Area) -> Option<&[Record]> {
        let slot = usize::from(area_code(area)?.checked_sub(1)?);
        self.images[slot].as_deref()
    }
}

fn slot(area: Area) -> Result<usize, AbortCode> {
    area_code(area).map(|c| usize::from(c) - 1).ok_or(AbortCode::CANNOT_STORE)
}

impl Storage for MemoryStorage {
    fn begin_save(&mut self, area: Area) -> Result<(), AbortCode> {
        slot(area)?;
        self.pending = Some((area, Vec::new()));
        Ok(())
    }

    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let (_, records) = self.pending.as_mut().ok_or(AbortCode::CANNOT_STORE)?;
        records.push(Record { index, sub, data: data.to_vec() });
        Ok(())
    }

    fn end_save(&mut self, area: Area) -> Result<(), AbortCode> {
        match self.pending.take() {
            Some((a, records)) if a == area => {
                self.images[slot(area)?] = Some(records);
                Ok(())
            }
            _ => Err(AbortCode::CANNOT_STORE),
        }
    }

    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        if let Some(records) = self.image(area) {
            for r in records {
                apply(r.index, r.sub, &r.data);
            }
        }
    }

    fn erase(&mut self, area: Area) -> Result<(), AbortCode> {
        self.images[slot(area)?] = None;
        Ok(())
    }

    fn save_lss(&mut self, config: LssConfig) -> Result<(), AbortCode> {
        self.lss = Some(config);
        Ok(())
    }

    fn load_lss(&mut self) -> Option<LssConfig> {
        self.lss
    }
}

/// Parameter images in files of a state directory, written atomically and checked on load (see
/// the [module docs](self)).
///
/// ```
/// use drive::storage::FileStorage;
/// use od_runtime::{Storage, od::Area};
///
/// let dir = std::env::temp_dir().join(format!("drive-doc-storage-{}", std::process::id()));
/// let mut storage = FileStorage::open(&dir, "demo-node1").unwrap();
/// storage.begin_save(Area::Application).unwrap();
/// storage.save_entry(0x607A, 0, &1000i32.to_le_bytes()).unwrap();
/// storage.end_save(Area::Application).unwrap();
///
/// // Another process (here: another instance) finds the value.
/// let mut again = FileStorage::open(&dir, "demo-node1").unwrap();
/// let mut seen = Vec::new();
/// again.load(Area::Application, &mut |i, s, d| seen.push((i, s, d.to_vec())));
/// assert_eq!(seen, [(0x607A, 0, vec![0xE8, 0x03, 0, 0])]);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub struct FileStorage {
    dir: PathBuf,
    tag: String,
    pending: Option<(Area, Vec<Record>)>,
    /// Inside a transaction: per area, the change to make (`Some(None)`: erase).
    staged: Option<[Option<Option<Vec<Record>>>; 3]>,
    warn: WarningSink,
    warnings: Arc<Mutex<Vec<String>>>,
    hook: Option<IoHook>,
}

/// A step of writing the parameter file, for [`FileStorage::with_io_hook`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum IoStep {
    /// Half of the temporary file is written.
    TempHalfWritten,
    /// The temporary file is written, not yet flushed.
    TempWritten,
    /// The temporary file is flushed to disk.
    TempSynced,
    /// The temporary file was renamed over the parameter file.
    Renamed,
    /// The directory is flushed: the save is durable.
    DirSynced,
    /// A version-1 per-area file was removed after the first save in the new format.
    LegacyRemoved,
}

/// Called at every [`IoStep`] of a save; an error makes the save fail there (as a failing disk
/// would), a panic stops it there (as a kill would: nothing is cleaned up).
pub type IoHook = Arc<dyn Fn(IoStep) -> io::Result<()> + Send + Sync>;

impl fmt::Debug for FileStorage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FileStorage").field("dir", &self.dir).field("tag", &self.tag).finish_non_exhaustive()
    }
}

/// Refuses a tag that cannot be part of a file name safely: letters, digits, `-`, `_` and `.`
/// only, not starting with `.`, 1 to 64 bytes. `what` names the tag in the error.
pub(crate) fn check_tag(tag: &str, what: &str) -> io::Result<()> {
    let valid = !tag.is_empty()
        && tag.len() <= 64
        && !tag.starts_with('.')
        && tag.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'));
    if valid {
        Ok(())
    } else {
        Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("bad {what} tag {tag:?}: use letters, digits, '-', '_' and '.', at most 64"),
        ))
    }
}

impl FileStorage {
    /// Uses `dir` (created if missing) for the images of the device named `tag` (letters,
    /// digits, `-`, `_` and `.`, at most 64 bytes: it becomes part of the file names). Removes
    /// temporary files an interrupted save left behind.
    pub fn open(dir: impl AsRef<Path>, tag: &str) -> io::Result<Self> {
        check_tag(tag, "storage")?;
        let dir = dir.as_ref().to_path_buf();
        fs::create_dir_all(&dir)?;
        let warnings = Arc::new(Mutex::new(Vec::new()));
        let prefix = tag.to_owned();
        let storage = Self {
            dir,
            tag: tag.to_owned(),
            pending: None,
            staged: None,
            warn: Arc::new(move |message| eprintln!("{prefix}: warning: {message}")),
            warnings,
            hook: None,
        };
        let mut leftovers = vec![storage.set_temp_path()];
        leftovers.extend(AREAS.map(|area| storage.temp_path(area)));
        for tmp in leftovers {
            if tmp.exists() {
                let _ = fs::remove_file(&tmp);
            }
        }
        Ok(storage)
    }

    /// Calls `hook` at every step of every save (see [`IoStep`]): for tests that stop a save
    /// half-way, as a kill or a failing disk would.
    pub fn with_io_hook(mut self, hook: IoHook) -> Self {
        self.hook = Some(hook);
        self
    }

    /// The file holding every area's image.
    pub fn set_path(&self) -> PathBuf {
        self.dir.join(format!("{}.params", self.tag))
    }

    fn set_temp_path(&self) -> PathBuf {
        self.dir.join(format!("{}.params.tmp", self.tag))
    }

    /// Sends warnings (corrupt images, failed saves) to `sink` instead of standard error. They
    /// are kept for [`FileStorage::warnings`] either way.
    pub fn with_warning_sink(mut self, sink: WarningSink) -> Self {
        self.warn = sink;
        self
    }

    /// Every warning so far, oldest first.
    pub fn warnings(&self) -> Vec<String> {
        self.warnings.lock().map(|w| w.clone()).unwrap_or_default()
    }

    /// The version-1 file of `area` alone, as earlier releases wrote it: read while no
    /// [`set_path`](FileStorage::set_path) file exists, removed by the first save.
    pub fn path(&self, area: Area) -> PathBuf {
        self.dir.join(format!("{}.{}.params", self.tag, area_file_suffix(area)))
    }

    fn temp_path(&self, area: Area) -> PathBuf {
        self.dir.join(format!("{}.{}.params.tmp", self.tag, area_file_suffix(area)))
    }

    fn warn(&self, message: String) {
        (self.warn)(&message);
        if let Ok(mut w) = self.warnings.lock() {
            w.push(message);
        }
    }

    /// Reads and checks the image of `area`: `Ok(None)` if there is none.
    pub fn read_image(&self, area: Area) -> Result<Option<Vec<Record>>, String> {
        match self.read_set()? {
            Some(areas) => Ok(areas.into_iter().find(|(a, _)| *a == area).map(|(_, records)| records)),
            None => self.read_legacy(area),
        }
    }

    /// The areas of the parameter file; `Ok(None)` if there is no such file.
    fn read_set(&self) -> Result<Option<AreaImages>, String> {
        let path = self.set_path();
        match read_limited(&path)? {
            Some(bytes) => decode_set(&bytes, &self.tag).map(Some).map_err(|e| format!("{}: {e}", path.display())),
            None => Ok(None),
        }
    }

    fn read_legacy(&self, area: Area) -> Result<Option<Vec<Record>>, String> {
        let path = self.path(area);
        match read_limited(&path)? {
            Some(bytes) => {
                decode_image(&bytes, area, &self.tag).map(Some).map_err(|e| format!("{}: {e}", path.display()))
            }
            None => Ok(None),
        }
    }

    /// Applies `changes` (per area: `None` keep, `Some(None)` erase, `Some(Some(_))` replace)
    /// to what is stored, writing one file atomically.
    fn commit(&mut self, changes: [Option<Option<Vec<Record>>>; 3]) -> Result<(), AbortCode> {
        let mut current: [Option<Vec<Record>>; 3] = match self.read_set() {
            Ok(Some(areas)) => {
                let mut current = [None, None, None];
                for (area, records) in areas {
                    if let Ok(slot) = slot(area) {
                        current[slot] = Some(records);
                    }
                }
                current
            }
            Ok(None) => AREAS.map(|area| self.read_legacy(area).ok().flatten()),
            Err(message) => {
                // Unreadable already (and ignored at load): what is saved now replaces it.
                self.warn(format!("replacing unreadable stored parameters: {message}"));
                [None, None, None]
            }
        };
        for (slot, change) in changes.into_iter().enumerate() {
            if let Some(change) = change {
                current[slot] = change;
            }
        }
        let images: Vec<(Area, &[Record])> =
            AREAS.iter().zip(&current).filter_map(|(&area, records)| Some((area, records.as_deref()?))).collect();
        let bytes = encode_set(&self.tag, &images);
        let hook = self.hook.clone();
        let step = |s: IoStep| hook.as_ref().map_or(Ok(()), |h| h(s));
        let written = write_atomically_with(&self.dir, &self.set_temp_path(), &self.set_path(), &bytes, &step);
        if let Err(e) = written {
            self.warn(format!("cannot save {}: {e}", self.set_path().display()));
            return Err(AbortCode::CANNOT_STORE);
        }
        // The new file holds everything: earlier releases' per-area files are stale now.
        for area in AREAS {
            let legacy = self.path(area);
            if legacy.exists() && fs::remove_file(&legacy).is_ok() {
                let _ = step(IoStep::LegacyRemoved);
            }
        }
        Ok(())
    }

    /// Records a change: staged inside a transaction, committed at once outside one.
    fn change(&mut self, area: Area, image: Option<Vec<Record>>) -> Result<(), AbortCode> {
        let slot = slot(area)?;
        match &mut self.staged {
            Some(staged) => {
                staged[slot] = Some(image);
                Ok(())
            }
            None => {
                let mut changes = [None, None, None];
                changes[slot] = Some(image);
                self.commit(changes)
            }
        }
    }
}

/// The bytes of `path` (at most [`MAX_FILE`]); `Ok(None)` if it does not exist.
fn read_limited(path: &Path) -> Result<Option<Vec<u8>>, String> {
    let file = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", path.display())),
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    if len > MAX_FILE {
        return Err(format!("{}: {len} bytes is too large for a parameter image", path.display()));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    io::Read::read_to_end(&mut io::Read::take(file, MAX_FILE), &mut bytes)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(Some(bytes))
}

/// Writes `bytes` to `path` in `dir` atomically: to `tmp` first, flushed to disk (`fsync`),
/// renamed over `path`, then the directory flushed so the rename survives a power cut. A
/// failure removes `tmp` and leaves `path` as it was. Used for parameter images and for
/// retained data.
pub(crate) fn write_atomically(dir: &Path, tmp: &Path, path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomically_with(dir, tmp, path, bytes, &|_| Ok(()))
}

/// [`write_atomically`], calling `step` after each step (see [`IoStep`]).
fn write_atomically_with(
    dir: &Path,
    tmp: &Path,
    path: &Path,
    bytes: &[u8],
    step: &dyn Fn(IoStep) -> io::Result<()>,
) -> io::Result<()> {
    let result = (|| {
        let mut file = OpenOptions::new().write(true).create(true).truncate(true).open(tmp)?;
        let (first, second) = bytes.split_at(bytes.len() / 2);
        file.write_all(first)?;
        step(IoStep::TempHalfWritten)?;
        file.write_all(second)?;
        step(IoStep::TempWritten)?;
        file.sync_all()?;
        step(IoStep::TempSynced)?;
        drop(file);
        fs::rename(tmp, path)?;
        step(IoStep::Renamed)?;
        sync_dir(dir)?;
        step(IoStep::DirSynced)
    })();
    if result.is_err() {
        let _ = fs::remove_file(tmp);
    }
    result
}

#[cfg(unix)]
fn sync_dir(dir: &Path) -> io::Result<()> {
    File::open(dir)?.sync_all()
}

#[cfg(not(unix))]
fn sync_dir(_dir: &Path) -> io::Result<()> {
    // Directories cannot be opened for syncing everywhere; the rename is still atomic.
    Ok(())
}

impl Storage for FileStorage {
    fn begin_save(&mut self, area: Area) -> Result<(), AbortCode> {
        slot(area)?;
        self.pending = Some((area, Vec::new()));
        Ok(())
    }

    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let (_, records) = self.pending.as_mut().ok_or(AbortCode::CANNOT_STORE)?;
        records.push(Record { index, sub, data: data.to_vec() });
        Ok(())
    }

    fn end_save(&mut self, area: Area) -> Result<(), AbortCode> {
        let Some((a, records)) = self.pending.take() else { return Err(AbortCode::CANNOT_STORE) };
        if a != area {
            return Err(AbortCode::CANNOT_STORE);
        }
        self.change(area, Some(records))
    }

    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        match self.read_image(area) {
            Ok(Some(records)) => {
                for r in &records {
                    apply(r.index, r.sub, &r.data);
                }
            }
            Ok(None) => {}
            Err(message) => self.warn(format!("ignoring stored parameters, defaults used: {message}")),
        }
    }

    fn erase(&mut self, area: Area) -> Result<(), AbortCode> {
        self.change(area, None)
    }

    /// `<dir>/<tag>.lss`: two lines, `node_id = N` (255: none) and `bit_rate = INDEX` (the
    /// CiA 305 table index, when known), written atomically.
    fn save_lss(&mut self, config: LssConfig) -> Result<(), AbortCode> {
        let mut text = format!("node_id = {}\n", config.node_id);
        if let Some(i) = config.bit_rate {
            text.push_str(&format!("bit_rate = {i}\n"));
        }
        let (path, tmp) = (self.dir.join(format!("{}.lss", self.tag)), self.dir.join(format!("{}.lss.tmp", self.tag)));
        write_atomically(&self.dir, &tmp, &path, text.as_bytes()).map_err(|e| {
            self.warn(format!("cannot store the LSS configuration in {}: {e}", path.display()));
            AbortCode::HARDWARE_ERROR
        })
    }

    fn load_lss(&mut self) -> Option<LssConfig> {
        let path = self.dir.join(format!("{}.lss", self.tag));
        let text = fs::read_to_string(&path).ok()?;
        let mut config = LssConfig { node_id: od_runtime::lss::UNCONFIGURED, bit_rate: None };
        let mut node = None;
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            let parsed = line.split_once('=').and_then(|(k, v)| Some((k.trim(), v.trim().parse::<u8>().ok()?)));
            match parsed {
                Some(("node_id", v)) if (1..=127).contains(&v) || v == 255 => node = Some(v),
                Some(("bit_rate", v)) if od_runtime::lss::bit_rate_kbit(v).is_some() => config.bit_rate = Some(v),
                _ => {
                    self.warn(format!("ignoring the stored LSS configuration {}: bad line {line:?}", path.display()));
                    return None;
                }
            }
        }
        config.node_id = node?;
        Some(config)
    }

    fn begin_transaction(&mut self) -> Result<(), AbortCode> {
        self.staged = Some([None, None, None]);
        Ok(())
    }

    fn end_transaction(&mut self, commit: bool) -> Result<(), AbortCode> {
        self.pending = None;
        match self.staged.take() {
            Some(changes) if commit && changes.iter().any(Option::is_some) => self.commit(changes),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn records() -> Vec<Record> {
        vec![
            Record { index: 0x1017, sub: 0, data: vec![0xF4, 0x01] },
            Record { index: 0x1008, sub: 0, data: b"a long device name".to_vec() },
            Record { index: 0x1800, sub: 2, data: vec![] },
        ]
    }

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b""), 0);
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn image_round_trips() {
        let bytes = encode_image(Area::Communication, "drvi-node2", &records());
        assert_eq!(decode_image(&bytes, Area::Communication, "drvi-node2"), Ok(records()));
    }

    #[test]
    fn every_truncation_and_every_bit_flip_is_detected() {
        let bytes = encode_image(Area::Application, "t", &records());
        for n in 0..bytes.len() {
            assert!(decode_image(&bytes[..n], Area::Application, "t").is_err(), "truncated to {n}");
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[i] ^= 1 << bit;
                assert!(decode_image(&b, Area::Application, "t").is_err(), "byte {i} bit {bit}");
            }
        }
    }

    #[test]
    fn wrong_area_or_tag_is_refused() {
        let bytes = encode_image(Area::Application, "a", &records());
        assert_eq!(decode_image(&bytes, Area::Manufacturer, "a"), Err(ImageError::Area { expected: 3, found: 2 }));
        assert!(matches!(decode_image(&bytes, Area::Application, "b"), Err(ImageError::Tag { .. })));
    }

    #[test]
    fn memory_storage_keeps_images_per_area() {
        let mut m = MemoryStorage::new();
        m.begin_save(Area::Manufacturer).unwrap();
        m.save_entry(0x2001, 1, &[1, 0, 0, 0]).unwrap();
        m.end_save(Area::Manufacturer).unwrap();
        let mut seen = Vec::new();
        m.load(Area::Manufacturer, &mut |i, s, d| seen.push((i, s, d.to_vec())));
        assert_eq!(seen, [(0x2001, 1, vec![1, 0, 0, 0])]);
        m.load(Area::Application, &mut |_, _, _| panic!("nothing stored"));
        m.erase(Area::Manufacturer).unwrap();
        assert!(m.image(Area::Manufacturer).is_none());
        assert_eq!(m.begin_save(Area::All), Err(AbortCode::CANNOT_STORE));
        assert_eq!(m.end_save(Area::Application), Err(AbortCode::CANNOT_STORE));
    }

    #[test]
    fn bad_tags_are_refused() {
        let dir = std::env::temp_dir();
        for tag in ["", "../x", "a/b", ".hidden", "sp ace", &"x".repeat(65)] {
            assert!(FileStorage::open(&dir, tag).is_err(), "{tag:?}");
        }
    }
}
