//! A hand-built test dictionary (a CiA 402 drive with the CiA 301 communication objects) and a
//! frame-level harness shared by the integration tests and the benchmarks.
#![allow(dead_code)]

use od_runtime::od::{AbortCode, Access, Area, DataType, DefaultValue, EntryInfo, ObjectDictionary};
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

const fn e(index: u16, sub: u8, data_type: DataType, access: Access, pdo: bool, default: DefaultValue) -> EntryInfo {
    EntryInfo {
        index,
        sub,
        data_type,
        access,
        pdo_mappable: pdo,
        bits: bits_of(data_type),
        low: None,
        high: None,
        default,
        name: "",
    }
}

const fn int(v: i128) -> DefaultValue {
    DefaultValue::Int(v)
}

const fn sized(mut x: EntryInfo, bytes: u32) -> EntryInfo {
    x.bits = bytes * 8;
    x
}

const fn limits(mut x: EntryInfo, low: i128, high: i128) -> EntryInfo {
    x.low = Some(low);
    x.high = Some(high);
    x
}

/// Number of entries in [`ENTRIES`].
pub const N: usize = 181;
/// Capacity of the DOMAIN 2003h in bytes (larger than the 1 KiB SDO buffer).
pub const DOMAIN_CAP: u32 = 2048;

const fn table() -> [EntryInfo; N] {
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
    push!(e(0x1014, 0, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(0x80)));
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
    push!(e(0x1200, 1, Unsigned32, Ro, false, DefaultValue::NodeIdPlus(0x600)));
    push!(e(0x1200, 2, Unsigned32, Ro, false, DefaultValue::NodeIdPlus(0x580)));
    // RPDO communication: RPDO1 and RPDO2 valid, RPDO3 and RPDO4 not.
    let mut p = 0;
    while p < 4 {
        let idx = 0x1400 + p as u16;
        let cob = 0x200 + 0x100 * p as i128 + if p >= 2 { 0x8000_0000 } else { 0 };
        push!(e(idx, 0, Unsigned8, Ro, false, int(5)));
        push!(e(idx, 1, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(cob)));
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
        push!(e(idx, 1, Unsigned32, Rw, false, DefaultValue::NodeIdPlus(cob)));
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
    push!(e(0x603F, 0, Unsigned16, Ro, true, none));
    push!(e(0x6040, 0, Unsigned16, Rww, true, none));
    push!(e(0x6041, 0, Unsigned16, Ro, true, none));
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

/// The entry table, sorted by (index, sub).
pub static ENTRIES: [EntryInfo; N] = table();

const fn offsets() -> ([usize; N], usize) {
    let t = table();
    let mut o = [0; N];
    let mut total = 0;
    let mut i = 0;
    while i < N {
        o[i] = total;
        total += (t[i].bits as usize).div_ceil(8);
        i += 1;
    }
    (o, total)
}

const LAYOUT: ([usize; N], usize) = offsets();

const fn keys() -> [u32; N] {
    let t = table();
    let mut k = [0; N];
    let mut i = 0;
    while i < N {
        k[i] = (t[i].index as u32) << 8 | t[i].sub as u32;
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
                self.lens[i] = e.default.encode(e, node_id, &mut self.data[off..off + cap]) as u16;
            }
        }
    }
}

/// Parameter storage in a map, with a switch to make it fail.
#[derive(Default, Clone)]
pub struct MemStorage {
    pub images: BTreeMap<u8, Vec<(u16, u8, Vec<u8>)>>,
    pending: Vec<(u16, u8, Vec<u8>)>,
    pub fail: bool,
    pub saves: usize,
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
