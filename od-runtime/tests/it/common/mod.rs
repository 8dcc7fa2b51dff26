//! A hand-built test dictionary (a CiA 402 drive with the CiA 301 communication objects) and a
//! frame-level harness shared by the integration tests and the benchmarks.
#![allow(dead_code)]

use od_runtime::crc::crc16_ccitt;
use od_runtime::od::{
    AbortCode, Access, Area, DataType, DefaultValue, EntryExtras, EntryInfo, Handle, Limits, ObjectDictionary,
};
use od_runtime::{App, Device, Event, Frame, Micros, NodeId, Storage, WriteSource};
use std::collections::BTreeMap;

use Access::*;
use DataType::*;

const fn bits_of(t: DataType) -> u32 {
    match t {
        Boolean => 1,
        Integer8 | Unsigned8 => 8,
        Integer16 | Unsigned16 => 16,
        Integer24 | Unsigned24 => 24,
        Integer32 | Unsigned32 | Real32 => 32,
        Integer40 | Unsigned40 => 40,
        Integer48 | Unsigned48 | TimeOfDay | TimeDifference => 48,
        Integer56 | Unsigned56 => 56,
        Integer64 | Unsigned64 | Real64 => 64,
        _ => 0,
    }
}

/// An entry and its extras, as the table is written; [`ENTRIES`] links them.
#[derive(Clone, Copy)]
struct Row {
    info: EntryInfo,
    x: EntryExtras,
    limits: Option<Limits>,
}

const fn e(index: u16, sub: u8, data_type: DataType, access: Access, pdo: bool, default: DefaultValue) -> Row {
    Row {
        info: EntryInfo::new(index, sub, data_type, access, pdo),
        x: EntryExtras { default, ..EntryExtras::NONE },
        limits: None,
    }
}

const fn int(v: i128) -> DefaultValue {
    DefaultValue::Int(od_runtime::od::Bits64::int(v as i64))
}

const fn sized(mut r: Row, bytes: u32) -> Row {
    r.x.bits = bytes * 8;
    r
}

const fn limits(mut r: Row, low: i128, high: i128) -> Row {
    r.limits = Some(Limits { low: low as i64, high: high as i64 });
    r
}

/// Number of entries in [`ENTRIES`].
pub const N: usize = 182;
/// Capacity of the DOMAIN 2003h in bytes (larger than the 1 KiB SDO buffer).
pub const DOMAIN_CAP: u32 = 2048;

const fn table() -> [Row; N] {
    let none = DefaultValue::None;
    let mut t = [e(0, 0, Unsigned8, Ro, false, DefaultValue::None); N];
    let mut i = 0;
    macro_rules! push {
        ($x:expr) => {{
            t[i] = $x;
            i += 1;
        }};
    }
    push!(e(0x1000, 0, Unsigned32, Ro, false, int(0x0002_0192)));
    push!(e(0x1001, 0, Unsigned8, Ro, true, none));
    push!(limits(e(0x1003, 0, Unsigned8, Rw, false, none), 0, 8));
    let mut k = 1;
    while k <= 8 {
        push!(e(0x1003, k, Unsigned32, Ro, false, none));
        k += 1;
    }
    push!(e(0x1005, 0, Unsigned32, Rw, false, int(0x80)));
    push!(e(0x1006, 0, Unsigned32, Rw, false, none));
    push!(sized(e(0x1008, 0, VisibleString, Const, false, DefaultValue::Bytes(b"od-runtime test drive")), 32));
    push!(e(0x100C, 0, Unsigned16, Rw, false, none));
    push!(e(0x100D, 0, Unsigned8, Rw, false, none));
    push!(e(0x1010, 0, Unsigned8, Ro, false, int(4)));
    k = 1;
    while k <= 4 {
        push!(e(0x1010, k, Unsigned32, Rw, false, int(1)));
        k += 1;
    }
    push!(e(0x1011, 0, Unsigned8, Ro, false, int(4)));
    k = 1;
    while k <= 4 {
        push!(e(0x1011, k, Unsigned32, Rw, false, int(1)));
        k += 1;
    }
    push!(e(0x1014, 0, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(od_runtime::od::Bits64::int(0x80))));
    push!(e(0x1015, 0, Unsigned16, Rw, false, none));
    push!(e(0x1016, 0, Unsigned8, Ro, false, int(4)));
    k = 1;
    while k <= 4 {
        push!(e(0x1016, k, Unsigned32, Rw, false, none));
        k += 1;
    }
    push!(e(0x1017, 0, Unsigned16, Rw, false, none));
    push!(e(0x1018, 0, Unsigned8, Ro, false, int(4)));
    push!(e(0x1018, 1, Unsigned32, Ro, false, int(0x0000_0ABC)));
    push!(e(0x1018, 2, Unsigned32, Ro, false, int(0x0000_0402)));
    push!(e(0x1018, 3, Unsigned32, Ro, false, int(0x0001_0000)));
    push!(e(0x1018, 4, Unsigned32, Ro, false, int(12345)));
    push!(e(0x1019, 0, Unsigned8, Rw, false, none));
    push!(e(0x1200, 0, Unsigned8, Ro, false, int(2)));
    push!(e(0x1200, 1, Unsigned32, Ro, false, DefaultValue::NodeIdPlus(od_runtime::od::Bits64::int(0x600))));
    push!(e(0x1200, 2, Unsigned32, Ro, false, DefaultValue::NodeIdPlus(od_runtime::od::Bits64::int(0x580))));
    // RPDO communication: RPDO1 and RPDO2 valid, RPDO3 and RPDO4 not.
    let mut p = 0;
    while p < 4 {
        let idx = 0x1400 + p as u16;
        let cob = 0x200 + 0x100 * p as i128 + if p >= 2 { 0x8000_0000 } else { 0 };
        push!(e(idx, 0, Unsigned8, Ro, false, int(5)));
        push!(e(idx, 1, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(od_runtime::od::Bits64::int(cob as i64))));
        push!(e(idx, 2, Unsigned8, Rw, false, int(255)));
        push!(e(idx, 5, Unsigned16, Rw, false, none));
        p += 1;
    }
    // RPDO mapping: 1: controlword + mode; 2: controlword + target position;
    // 3: target velocity; 4: empty.
    let rmaps: [[u32; 2]; 4] = [[0x6040_0010, 0x6060_0008], [0x6040_0010, 0x607A_0020], [0x60FF_0020, 0], [0, 0]];
    p = 0;
    while p < 4 {
        let idx = 0x1600 + p as u16;
        let count = if p == 3 {
            0
        } else if p == 2 {
            1
        } else {
            2
        };
        push!(limits(e(idx, 0, Unsigned8, Rw, false, int(count)), 0, 8));
        k = 1;
        while k <= 8 {
            let v = if k <= 2 { rmaps[p][k as usize - 1] } else { 0 };
            push!(e(idx, k, Unsigned32, Rw, false, int(v as i128)));
            k += 1;
        }
        p += 1;
    }
    // TPDO communication: TPDO1 event-driven, TPDO2 every SYNC, TPDO3/4 not valid.
    p = 0;
    while p < 4 {
        let idx = 0x1800 + p as u16;
        let cob = 0x180 + 0x100 * p as i128 + if p >= 2 { 0x8000_0000 } else { 0 };
        let ttype = if p == 1 { 1 } else { 255 };
        push!(e(idx, 0, Unsigned8, Ro, false, int(6)));
        push!(e(idx, 1, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(od_runtime::od::Bits64::int(cob as i64))));
        push!(e(idx, 2, Unsigned8, Rw, false, int(ttype)));
        push!(e(idx, 3, Unsigned16, Rw, false, none));
        push!(e(idx, 5, Unsigned16, Rw, false, none));
        push!(e(idx, 6, Unsigned8, Rw, false, none));
        p += 1;
    }
    // TPDO mapping: 1: statusword + mode display; 2: statusword + position;
    // 3: statusword + velocity; 4: error register.
    let tmaps: [[u32; 2]; 4] =
        [[0x6041_0010, 0x6061_0008], [0x6041_0010, 0x6064_0020], [0x6041_0010, 0x606C_0020], [0x1001_0008, 0]];
    p = 0;
    while p < 4 {
        let idx = 0x1A00 + p as u16;
        let count = if p == 3 { 1 } else { 2 };
        push!(limits(e(idx, 0, Unsigned8, Rw, false, int(count)), 0, 8));
        k = 1;
        while k <= 8 {
            let v = if k <= 2 { tmaps[p][k as usize - 1] } else { 0 };
            push!(e(idx, k, Unsigned32, Rw, false, int(v as i128)));
            k += 1;
        }
        p += 1;
    }
    push!(sized(e(0x2001, 0, VisibleString, Rw, false, DefaultValue::Bytes(b"axis")), 32));
    push!(e(0x2002, 0, Unsigned64, Rw, true, int(0x0123_4567_89AB_CDEF)));
    push!(sized(e(0x2003, 0, Domain, Rw, false, none), DOMAIN_CAP));
    push!(e(0x2004, 0, Unsigned8, Ro, false, int(8)));
    k = 1;
    while k <= 8 {
        push!(e(0x2004, k, Boolean, Rw, true, none));
        k += 1;
    }
    push!(limits(e(0x2005, 0, Integer8, Rw, true, none), -100, 100));
    push!(e(0x2006, 0, Unsigned32, Wo, false, none));
    push!(e(0x2007, 0, Unsigned16, Rw, false, none));
    push!(e(0x2008, 0, Unsigned8, Rw, true, none));
    // A string a PDO may map in part (its first 1..=8 bytes).
    push!(sized(e(0x2009, 0, VisibleString, Rw, true, DefaultValue::Bytes(b"ABCDEFGHIJ")), 16));
    push!(e(0x603F, 0, Unsigned16, Ro, true, none));
    push!(e(0x6040, 0, Unsigned16, Rww, true, none));
    // Without the `cia402` feature 6041h is a plain object: it starts at "switch on disabled"
    // (0240h), where the state machine puts it at boot, so tests about other things see the
    // same frames either way. With the feature it starts at 0 and the state machine must set it.
    let statusword = if cfg!(feature = "cia402") { none } else { int(0x0240) };
    push!(e(0x6041, 0, Unsigned16, Ro, true, statusword));
    push!(e(0x605A, 0, Integer16, Rw, false, int(2)));
    push!(limits(e(0x6060, 0, Integer8, Rw, true, none), -4, 10));
    push!(e(0x6061, 0, Integer8, Ro, true, none));
    push!(e(0x6064, 0, Integer32, Ro, true, none));
    push!(e(0x606C, 0, Integer32, Ro, true, none));
    push!(e(0x607A, 0, Integer32, Rw, true, none));
    push!(e(0x60FF, 0, Integer32, Rw, true, none));
    assert!(i == N, "N does not match the table");
    t
}

// A const, not a static: the const fns below read it (a static cannot be read there).
#[allow(clippy::large_const_arrays)]
const ROWS: [Row; N] = table();

const fn limits_table() -> [Limits; N] {
    let mut l = [Limits { low: 0, high: 0 }; N];
    let mut i = 0;
    while i < N {
        if let Some(x) = ROWS[i].limits {
            l[i] = x;
        }
        i += 1;
    }
    l
}

static LIMITS: [Limits; N] = limits_table();

const fn extras(limits: &'static [Limits; N]) -> [EntryExtras; N] {
    let mut x = [EntryExtras::NONE; N];
    let mut i = 0;
    while i < N {
        x[i] = ROWS[i].x;
        if ROWS[i].limits.is_some() {
            x[i].limits = Some(&limits[i]);
        }
        i += 1;
    }
    x
}

/// Every entry's extras (one per entry: a hand-written table need not share them).
static EXTRAS: [EntryExtras; N] = extras(&LIMITS);

const fn link(x: &'static [EntryExtras; N]) -> [EntryInfo; N] {
    let mut t = [EntryInfo::new(0, 0, Unsigned8, Ro, false); N];
    let mut i = 0;
    while i < N {
        t[i] = ROWS[i].info.with_extras(&x[i]);
        i += 1;
    }
    t
}

/// The entry table, sorted by (index, sub).
pub static ENTRIES: [EntryInfo; N] = link(&EXTRAS);

const fn offsets() -> ([usize; N], usize) {
    let mut o = [0; N];
    let mut total = 0;
    let mut i = 0;
    while i < N {
        o[i] = total;
        let bits = if ROWS[i].x.bits != 0 { ROWS[i].x.bits } else { bits_of(ROWS[i].info.data_type) };
        total += (bits as usize).div_ceil(8);
        i += 1;
    }
    (o, total)
}

const LAYOUT: ([usize; N], usize) = offsets();

const fn keys() -> [u32; N] {
    let mut k = [0; N];
    let mut i = 0;
    while i < N {
        k[i] = (ROWS[i].info.index as u32) << 8 | ROWS[i].info.sub as u32;
        i += 1;
    }
    k
}

/// `index << 8 | sub` of every entry, for a fast lookup.
static KEYS: [u32; N] = keys();
const TOTAL: usize = LAYOUT.1;

/// The test dictionary: every value as bytes in one arena.
#[derive(Clone)]
pub struct TestOd {
    data: [u8; TOTAL],
    lens: [u16; N],
}

impl Default for TestOd {
    fn default() -> Self {
        Self::new()
    }
}

impl TestOd {
    /// All values zero; the device's reset fills in the defaults.
    pub fn new() -> Self {
        Self { data: [0; TOTAL], lens: [0; N] }
    }

    fn slot(&self, index: u16, sub: u8) -> Result<usize, AbortCode> {
        let key = u32::from(index) << 8 | u32::from(sub);
        KEYS.binary_search(&key).map_err(|_| self.info(index, sub).err().unwrap_or(AbortCode::NO_OBJECT))
    }

    /// Reads an integer entry (tests only).
    pub fn get(&self, index: u16, sub: u8) -> i128 {
        let mut b = [0u8; 16];
        let n = self.read(index, sub, &mut b).expect("entry exists");
        od_runtime::od::decode_int(&b[..n], ENTRIES[self.slot(index, sub).unwrap()].data_type.is_signed())
    }

    /// Writes an integer entry with its type's size (tests only; no limit checks).
    pub fn set(&mut self, index: u16, sub: u8, v: i128) {
        let i = self.slot(index, sub).expect("entry exists");
        let n = ENTRIES[i].byte_len();
        let off = LAYOUT.0[i];
        self.data[off..off + n].copy_from_slice(&v.to_le_bytes()[..n]);
        self.lens[i] = n as u16;
    }

    /// The bytes of an entry.
    pub fn bytes(&self, index: u16, sub: u8) -> Vec<u8> {
        let i = self.slot(index, sub).expect("entry exists");
        let off = LAYOUT.0[i];
        self.data[off..off + self.lens[i] as usize].to_vec()
    }
}

impl ObjectDictionary for TestOd {
    fn entries(&self) -> &'static [EntryInfo] {
        &ENTRIES
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        let i = self.slot(index, sub)?;
        let len = usize::from(self.lens[i]);
        if buf.len() < len {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        let off = LAYOUT.0[i];
        buf[..len].copy_from_slice(&self.data[off..off + len]);
        Ok(len)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let i = self.slot(index, sub)?;
        ENTRIES[i].check_value(data)?;
        let off = LAYOUT.0[i];
        self.data[off..off + data.len()].copy_from_slice(data);
        self.lens[i] = data.len() as u16;
        Ok(())
    }

    fn restore_defaults(&mut self, area: Area, node_id: u8) {
        for (i, e) in ENTRIES.iter().enumerate() {
            if area.contains(e.index) {
                let off = LAYOUT.0[i];
                let cap = e.byte_len();
                self.lens[i] = e.default().encode(e, node_id, &mut self.data[off..off + cap]) as u16;
            }
        }
    }

    // The fast path of a hand-written dictionary: a handle is the entry's number in ENTRIES.

    fn handle(&self, index: u16, sub: u8) -> Option<Handle> {
        self.slot(index, sub).ok().map(|i| Handle::new(i as u32))
    }

    fn read_handle(&self, h: Handle) -> [u8; 8] {
        let i = h.get() as usize;
        let mut out = [0u8; 8];
        if let (Some(&off), Some(&len)) = (LAYOUT.0.get(i), self.lens.get(i)) {
            let n = usize::from(len).min(8);
            match self.data.get(off..off + 8) {
                // Eight bytes at once, then zero past the value.
                Some(src) => {
                    out.copy_from_slice(src);
                    let keep = if n == 8 { u64::MAX } else { (1u64 << (8 * n)) - 1 };
                    out = (u64::from_le_bytes(out) & keep).to_le_bytes();
                }
                None => out[..n].copy_from_slice(&self.data[off..off + n]),
            }
        }
        out
    }

    fn write_handle(&mut self, h: Handle, data: &[u8]) -> Result<(), AbortCode> {
        let i = h.get() as usize;
        let (Some(e), Some(&off)) = (ENTRIES.get(i), LAYOUT.0.get(i)) else {
            return Err(AbortCode::NO_OBJECT);
        };
        e.check_value(data)?;
        self.data[off..off + data.len()].copy_from_slice(data);
        self.lens[i] = data.len() as u16;
        Ok(())
    }
}

/// [`TestOd`] without the handle methods: a dictionary implementing only what
/// [`ObjectDictionary`] requires, so the runtime takes the default `handle`, `read_handle` and
/// `write_handle` (through `info`, `read` and `write`).
#[derive(Clone, Default)]
pub struct PlainOd(pub TestOd);

impl ObjectDictionary for PlainOd {
    fn entries(&self) -> &'static [EntryInfo] {
        self.0.entries()
    }

    fn read(&self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        self.0.read(index, sub, buf)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.0.write(index, sub, data)
    }

    fn restore_defaults(&mut self, area: Area, node_id: u8) {
        self.0.restore_defaults(area, node_id)
    }
}

/// Parameter storage in a map, with a switch to make it fail.
#[derive(Default, Clone)]
pub struct MemStorage {
    pub images: BTreeMap<u8, Vec<(u16, u8, Vec<u8>)>>,
    pending: Vec<(u16, u8, Vec<u8>)>,
    pub fail: bool,
    pub saves: usize,
    /// The LSS configuration stored (CiA 305 store configuration).
    pub lss: Option<od_runtime::lss::LssConfig>,
}

fn key(area: Area) -> u8 {
    match area {
        Area::Communication => 1,
        Area::Application => 2,
        Area::Manufacturer => 3,
        Area::All => 0,
    }
}

impl Storage for MemStorage {
    fn begin_save(&mut self, _: Area) -> Result<(), AbortCode> {
        if self.fail {
            return Err(AbortCode::HARDWARE_ERROR);
        }
        self.pending.clear();
        Ok(())
    }
    fn save_entry(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.pending.push((index, sub, data.to_vec()));
        Ok(())
    }
    fn end_save(&mut self, area: Area) -> Result<(), AbortCode> {
        self.images.insert(key(area), std::mem::take(&mut self.pending));
        self.saves += 1;
        Ok(())
    }
    fn load(&mut self, area: Area, apply: &mut dyn FnMut(u16, u8, &[u8])) {
        if let Some(img) = self.images.get(&key(area)) {
            for (i, s, d) in img {
                apply(*i, *s, d);
            }
        }
    }
    fn erase(&mut self, area: Area) -> Result<(), AbortCode> {
        self.images.remove(&key(area));
        Ok(())
    }
    fn save_lss(&mut self, config: od_runtime::lss::LssConfig) -> Result<(), AbortCode> {
        if self.fail {
            return Err(AbortCode::HARDWARE_ERROR);
        }
        self.lss = Some(config);
        Ok(())
    }
    fn load_lss(&mut self) -> Option<od_runtime::lss::LssConfig> {
        self.lss
    }
}

/// An application that records events and vetoes writes of listed objects.
#[derive(Default)]
pub struct Recorder {
    pub events: Vec<Event>,
    pub writes: Vec<(u16, u8, Vec<u8>, WriteSource)>,
    pub veto: Vec<(u16, u8, AbortCode)>,
}

impl App<TestOd> for Recorder {
    fn on_write(&mut self, _: &TestOd, index: u16, sub: u8, data: &[u8], source: WriteSource) -> Result<(), AbortCode> {
        if let Some(&(_, _, code)) = self.veto.iter().find(|v| v.0 == index && v.1 == sub) {
            return Err(code);
        }
        self.writes.push((index, sub, data.to_vec(), source));
        Ok(())
    }

    fn on_event(&mut self, _: &mut TestOd, event: Event) {
        self.events.push(event);
    }
}

pub type TestDevice = Device<TestOd, Recorder, MemStorage>;

/// Node id of the harness device.
pub const NODE: u8 = 1;

/// Parses `"601 2B 40 60 00 06 00 00 00"` (hex id, hex bytes) or `"701 R1"` (remote frame).
pub fn frame(s: &str) -> Frame {
    let mut it = s.split_whitespace();
    let id = u16::from_str_radix(it.next().expect("id"), 16).expect("hex id");
    let rest: Vec<&str> = it.collect();
    if let [r] = rest.as_slice()
        && let Some(len) = r.strip_prefix('R')
    {
        return Frame::remote(id, len.parse().expect("rtr length")).expect("valid frame");
    }
    let data: Vec<u8> = rest.iter().map(|b| u8::from_str_radix(b, 16).expect("hex byte")).collect();
    Frame::new(id, &data).expect("valid frame")
}

/// A device on a virtual bus with a virtual clock.
pub struct Harness {
    pub dev: TestDevice,
    pub now: Micros,
    /// Frames other than the SDO response collected by [`Harness::sdo_write`].
    pub extra: Vec<String>,
}

impl Harness {
    /// Node 1, booted (the boot-up message is consumed and checked), pre-operational.
    pub fn new() -> Self {
        Self::with_storage(MemStorage::default())
    }

    pub fn with_storage(storage: MemStorage) -> Self {
        let dev = Device::new(TestOd::new(), Recorder::default(), storage, NodeId::new(NODE).unwrap());
        let mut h = Self { dev, now: 0, extra: Vec::new() };
        assert_eq!(h.poll(), ["701 00"]);
        h
    }

    /// Collects the frames the device sends now.
    pub fn poll(&mut self) -> Vec<String> {
        let mut out = Vec::new();
        self.dev.poll(self.now, |f| out.push(f.to_string()));
        out
    }

    /// Sends one frame and returns what the device answers.
    pub fn send(&mut self, s: &str) -> Vec<String> {
        self.dev.on_frame(&frame(s), self.now);
        self.poll()
    }

    /// Sends a frame and asserts the exact answer.
    #[track_caller]
    pub fn exchange(&mut self, req: &str, resp: &[&str]) {
        let got = self.send(req);
        assert_eq!(got, resp, "request {req}");
    }

    /// Advances the clock by `us` microseconds and polls.
    pub fn advance(&mut self, us: Micros) -> Vec<String> {
        self.now += us;
        self.poll()
    }

    /// NMT start for this node.
    pub fn start(&mut self) -> Vec<String> {
        self.send("000 01 01")
    }

    /// Writes through SDO expedited download and returns the raw response.
    pub fn sdo_write(&mut self, index: u16, sub: u8, data: &[u8]) -> String {
        assert!((1..=4).contains(&data.len()));
        let cmd = 0x23 | ((4 - data.len() as u8) << 2);
        let mut b = vec![cmd, index as u8, (index >> 8) as u8, sub];
        b.extend_from_slice(data);
        b.resize(8, 0);
        let s = format!("{:03X} {}", 0x600 + NODE as u16, hex(&b));
        let out = self.send(&s);
        let (sdo, other): (Vec<String>, Vec<String>) = out.into_iter().partition(|f| f.starts_with("581 "));
        self.extra.extend(other);
        assert_eq!(sdo.len(), 1, "{sdo:?}");
        sdo[0].clone()
    }

    /// Asserts an SDO write succeeds.
    #[track_caller]
    pub fn sdo_write_ok(&mut self, index: u16, sub: u8, data: &[u8]) {
        let r = self.sdo_write(index, sub, data);
        assert!(r.starts_with("581 60"), "write {index:04X}sub{sub} answered {r}");
    }

    /// The abort code of an SDO write (panics if it succeeded).
    #[track_caller]
    pub fn sdo_write_abort(&mut self, index: u16, sub: u8, data: &[u8]) -> u32 {
        let r = self.sdo_write(index, sub, data);
        abort_code(&r).unwrap_or_else(|| panic!("write {index:04X}sub{sub} answered {r}"))
    }

    pub fn od(&self) -> &TestOd {
        self.dev.od()
    }

    pub fn events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.dev.app_mut().events)
    }
}

impl Default for Harness {
    fn default() -> Self {
        Self::new()
    }
}

/// The abort code of a response frame string, if it is an abort.
pub fn abort_code(resp: &str) -> Option<u32> {
    let b: Vec<u8> = resp.split_whitespace().skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
    (b.len() == 8 && b[0] == 0x80).then(|| u32::from_le_bytes([b[4], b[5], b[6], b[7]]))
}

/// Hex bytes separated by spaces.
pub fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02X}")).collect::<Vec<_>>().join(" ")
}

/// Drives a block download of `data` to `index`/`sub`, losing segment `lose` (1-based within
/// the first block, unless it ends the block) once, and returns the server's last answer.
pub fn block_download(h: &mut Harness, index: u16, data: &[u8], crc: bool, lose: Option<u8>) -> String {
    let cmd = 0xC2 | if crc { 0x04 } else { 0 };
    let len = (data.len() as u32).to_le_bytes();
    let init = format!("601 {:02X} {:02X} {:02X} 00 {}", cmd, index as u8, index >> 8, hex(&len));
    let r = h.send(&init);
    assert_eq!(r.len(), 1);
    assert!(r[0].starts_with(&format!("581 A4 {:02X} {:02X} 00", index as u8, index >> 8)), "{r:?}");
    let mut blksize: u8 = u8::from_str_radix(r[0].split(' ').nth(5).unwrap(), 16).unwrap();
    let chunks: Vec<&[u8]> = if data.is_empty() { vec![&[][..]] } else { data.chunks(7).collect() };
    let mut next = 0usize;
    let mut lose = lose;
    while next < chunks.len() {
        let mut seq = 0u8;
        let mut resp = Vec::new();
        while seq < blksize && next + (seq as usize) < chunks.len() {
            seq += 1;
            let i = next + seq as usize - 1;
            let last = i + 1 == chunks.len();
            let mut seg = vec![seq | if last { 0x80 } else { 0 }];
            seg.extend_from_slice(chunks[i]);
            seg.resize(8, 0);
            // A lost segment is only noticed when a later one of the block arrives; losing the
            // block's last segment would leave both sides waiting for the SDO timeout.
            let block_end = seq == blksize || last;
            if lose == Some(seq) && !block_end {
                lose = None;
                continue;
            }
            resp = h.send(&format!("601 {}", hex(&seg)));
            if !resp.is_empty() {
                break;
            }
        }
        assert_eq!(resp.len(), 1, "no block acknowledgement");
        let b: Vec<u8> = resp[0].split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
        if b[0] == 0x80 {
            return resp[0].clone();
        }
        assert_eq!(b[0], 0xA2);
        next += b[1] as usize;
        blksize = b[2];
    }
    let unused = if data.is_empty() { 7 } else { (7 - data.len() % 7) % 7 } as u8;
    let c = if crc { crc16_ccitt(0, data) } else { 0 };
    let end = format!("601 {:02X} {:02X} {:02X} 00 00 00 00 00", 0xC1 | (unused << 2), c as u8, c >> 8);
    let r = h.send(&end);
    assert_eq!(r.len(), 1);
    r[0].clone()
}

/// Runs a block upload of `index`/`sub` with block size `blk`, and returns the data and the
/// server's `n` and CRC from the end message.
pub fn block_upload(h: &mut Harness, index: u16, sub: u8, blk: u8, crc: bool) -> Vec<u8> {
    let cmd = 0xA0 | if crc { 0x04 } else { 0 };
    let r = h.send(&format!("601 {cmd:02X} {:02X} {:02X} {sub:02X} {blk:02X} 00 00 00", index as u8, index >> 8));
    assert_eq!(r.len(), 1);
    let b: Vec<u8> = r[0].split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
    assert_eq!(b[0], 0xC6, "{r:?}");
    let size = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize;
    let mut data = Vec::new();
    let mut frames = h.send("601 A3 00 00 00 00 00 00 00");
    loop {
        assert!(!frames.is_empty() && frames.len() <= blk as usize);
        let mut done = false;
        for (i, f) in frames.iter().enumerate() {
            let b: Vec<u8> = f.split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
            assert_eq!(b[0] & 0x7F, i as u8 + 1);
            data.extend_from_slice(&b[1..]);
            done = b[0] & 0x80 != 0;
        }
        let ack = format!("601 A2 {:02X} {blk:02X} 00 00 00 00 00", frames.len());
        frames = h.send(&ack);
        if done {
            break;
        }
    }
    assert_eq!(frames.len(), 1);
    let b: Vec<u8> = frames[0].split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
    assert_eq!(b[0] & 0xE3, 0xC1);
    let unused = ((b[0] >> 2) & 7) as usize;
    data.truncate(data.len() - unused);
    assert_eq!(data.len(), size);
    if crc {
        assert_eq!(u16::from_le_bytes([b[1], b[2]]), crc16_ccitt(0, &data));
    }
    assert!(h.send("601 A1 00 00 00 00 00 00 00").is_empty());
    data
}

/// Runs a segmented download of `data` (size indicated) and returns the server's last answer.
pub fn segmented_download(h: &mut Harness, index: u16, data: &[u8]) -> String {
    let len = (data.len() as u32).to_le_bytes();
    let r = h.send(&format!("601 21 {:02X} {:02X} 00 {}", index as u8, index >> 8, hex(&len)));
    if !r[0].starts_with("581 60") {
        return r[0].clone();
    }
    let chunks: Vec<&[u8]> = if data.is_empty() { vec![&[][..]] } else { data.chunks(7).collect() };
    let mut last = String::new();
    for (i, c) in chunks.iter().enumerate() {
        let t = (i as u8 & 1) << 4;
        let end = u8::from(i + 1 == chunks.len());
        let mut seg = vec![t | ((7 - c.len() as u8) << 1) | end];
        seg.extend_from_slice(c);
        seg.resize(8, 0);
        let r = h.send(&format!("601 {}", hex(&seg)));
        assert_eq!(r.len(), 1);
        last = r[0].clone();
        if !last.starts_with(&format!("581 {:02X}", 0x20 | t)) {
            break;
        }
    }
    last
}

/// Runs an SDO upload (expedited or segmented) and returns the value.
pub fn upload(h: &mut Harness, index: u16, sub: u8) -> Vec<u8> {
    let r = h.send(&format!("601 40 {:02X} {:02X} {sub:02X} 00 00 00 00", index as u8, index >> 8));
    let b: Vec<u8> = r[0].split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
    if b[0] & 0x02 != 0 {
        let n = 4 - ((b[0] >> 2) & 3) as usize;
        return b[4..4 + n].to_vec();
    }
    assert_eq!(b[0], 0x41, "{r:?}");
    let size = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize;
    let mut data = Vec::new();
    let mut t = 0u8;
    loop {
        let r = h.send(&format!("601 {:02X} 00 00 00 00 00 00 00", 0x60 | t));
        let b: Vec<u8> = r[0].split(' ').skip(1).map(|x| u8::from_str_radix(x, 16).unwrap()).collect();
        assert_eq!(b[0] & 0xF0, t, "{r:?}");
        let n = 7 - ((b[0] >> 1) & 7) as usize;
        data.extend_from_slice(&b[1..1 + n]);
        t ^= 0x10;
        if b[0] & 1 != 0 {
            break;
        }
    }
    assert_eq!(data.len(), size);
    data
}
