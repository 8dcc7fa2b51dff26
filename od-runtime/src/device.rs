//! The device: NMT slave, SDO server, PDOs, SYNC, EMCY, error control, store/restore and the
//! CiA 402 state machine around one [`ObjectDictionary`].

use crate::cia402::{self, StateMachine, Transitions};
use crate::emcy::{self, Queue};
use crate::frame::{Frame, Micros, NodeId};
use crate::nmt::{NmtCommand, NmtState};
use crate::od::{AbortCode, Area, DataType, EntryInfo, Handle, MappedHandle, ObjectDictionary, low_bits};
use crate::pdo::{self, Direction, MAX_MAPPED, MapEntry, Mappable};
use crate::sdo::{ObjectAccess, SdoEntry, SdoServer};
use crate::storage::{self, LOAD_SIGNATURE, SAVE_SIGNATURE, Storage};

/// Most heartbeat consumer entries (1016h sub-indices) the device monitors.
pub const MAX_HEARTBEAT_CONSUMERS: usize = 16;

/// Who wrote an object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WriteSource {
    /// An SDO download from a master.
    Sdo,
    /// A receive PDO; the number is the offset of its communication object from 1400h
    /// (0 = RPDO1).
    Rpdo(u16),
    /// The application, through [`Device::write`].
    Local,
}

/// Which reset ran.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResetKind {
    /// Reset node: every area set to its default, then to its stored values.
    Node,
    /// Reset communication: 1000h..1FFFh only.
    Communication,
}

/// Something the application may want to react to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Event {
    /// The NMT state changed.
    Nmt {
        /// State before.
        from: NmtState,
        /// State after.
        to: NmtState,
    },
    /// A reset restored the dictionary (defaults, then stored values); the boot-up message
    /// follows at the next poll.
    Reset(ResetKind),
    /// An object was written by a master or locally (after the dictionary accepted the value).
    Written {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Who wrote it.
        source: WriteSource,
    },
    /// A SYNC message was received (or produced by this device).
    Sync {
        /// Its counter, when it carried one.
        counter: Option<u8>,
    },
    /// A monitored node's heartbeat (1016h) did not arrive in time.
    HeartbeatTimeout {
        /// The node.
        node: u8,
    },
    /// A monitored node's heartbeat arrived for the first time or again after a timeout.
    HeartbeatStarted {
        /// The node.
        node: u8,
        /// The NMT state byte it sent (0 = boot-up).
        state: u8,
    },
    /// The master stopped guarding: no guarding request within guard time × life time factor
    /// (100Ch × 100Dh).
    LifeGuardingLost,
    /// Guarding requests arrived again after [`Event::LifeGuardingLost`].
    LifeGuardingResumed,
    /// An RPDO with an event timer (deadline monitoring, 1400h.. sub-index 5) was not received
    /// in time after its previous reception. CiA 301 suggests EMCY 8250h for it.
    RpdoTimeout {
        /// Offset of its communication object from 1400h (0 = RPDO1).
        pdo: u16,
    },
    /// The CiA 402 state machine made a transition.
    Cia402(cia402::Transition),
    /// LSS activate bit timing (CiA 305): switch the controller to the bit rate of `index` in
    /// [`crate::lss::BIT_RATES`] after `delay_ms`, and send nothing for as long again.
    LssBitTiming {
        /// The bit timing table index.
        index: u8,
        /// The switch delay in ms.
        delay_ms: u16,
    },
}

/// The application side of a device: a veto on writes and a stream of events.
///
/// Both methods have empty defaults; `()` implements the trait for devices without behaviour.
///
/// ```
/// use od_runtime::cia402::State;
/// use od_runtime::od::AbortCode;
/// use od_runtime::{App, Event, WriteSource};
///
/// struct Drive {
///     enabled: bool,
/// }
///
/// impl<OD> App<OD> for Drive {
///     fn on_write(&mut self, _: &OD, index: u16, _: u8, data: &[u8], _: WriteSource) -> Result<(), AbortCode> {
///         // This drive only knows profile position (1) and profile velocity (3).
///         if index == 0x6060 && !matches!(data, [1] | [3]) {
///             return Err(AbortCode::INVALID_VALUE);
///         }
///         Ok(())
///     }
///
///     fn on_event(&mut self, _: &mut OD, event: Event) {
///         if let Event::Cia402(t) = event {
///             self.enabled = t.to == State::OperationEnabled;
///         }
///     }
/// }
/// ```
pub trait App<OD> {
    /// Called before a master's (or a local) write reaches the dictionary. Returning an error
    /// rejects the write: an SDO download aborts with that code, an RPDO entry is skipped.
    /// The value has been checked for access rights but not yet for length and limits.
    fn on_write(&mut self, od: &OD, index: u16, sub: u8, data: &[u8], source: WriteSource) -> Result<(), AbortCode> {
        let _ = (od, index, sub, data, source);
        Ok(())
    }

    /// Called for every [`Event`], synchronously, from `on_frame`, `poll` or an API call.
    fn on_event(&mut self, od: &mut OD, event: Event) {
        let _ = (od, event);
    }

    /// Called when an SDO upload reads an entry, before the dictionary is read. `Some` answers
    /// the upload with what the application puts in `buf` (an entry a read consumes, such as
    /// a channel handing out its answer a few characters per upload); `None`, the default,
    /// reads the dictionary.
    fn on_upload(&mut self, od: &OD, index: u16, sub: u8, buf: &mut [u8]) -> Option<Result<usize, AbortCode>> {
        let _ = (od, index, sub, buf);
        None
    }

    /// Called with a TPDO's data as packed from the dictionary by the mapping `map`, before
    /// it is sent or sampled: the application may change the bits of a value whose PDO form
    /// differs from its SDO form. Default: nothing changes.
    fn on_tpdo(&mut self, od: &OD, map: &[MappedHandle], data: &mut [u8; 8]) {
        let _ = (od, map, data);
    }

    /// Called when RPDO `pdo` (0-based) arrives with more bytes than its mapping takes. The
    /// PDO is processed either way (CiA 301); `true` also sends EMCY 8220h "PDO length
    /// exceeded", which CiA 301 leaves optional. Default: `false`.
    fn rpdo_length_exceeded(&mut self, pdo: u16) -> bool {
        let _ = pdo;
        false
    }
}

impl<OD> App<OD> for () {}

/// One entry of a loaded PDO mapping, resolved to a [`Handle`] when the mapping was loaded.
type Mapped = MappedHandle;

/// Whether the CiA 402 state machine is built in (cargo feature `cia402`).
const CIA402: bool = cfg!(feature = "cia402");
/// Whether store/restore through [`Storage`] is built in (cargo feature `store`).
const STORE: bool = cfg!(feature = "store");

/// The LSS slave's hooks (cargo feature `lss`).
#[cfg(feature = "lss")]
#[path = "lss_device.rs"]
mod lss_device;

/// Whether a write of `index` has effects beyond the dictionary (communication objects, the
/// CiA 402 controlword and modes of operation): such writes take [`Core::write_entry`]'s full
/// path, every other RPDO-mapped entry goes straight to the dictionary.
const fn has_side_effects(index: u16) -> bool {
    (index >= 0x1000 && index <= 0x1FFF) || (CIA402 && (index == 0x6040 || index == 0x6060))
}

#[derive(Clone, Copy)]
struct Tpdo<const M: usize> {
    present: bool,
    cob: u16,
    valid: bool,
    rtr_ok: bool,
    ttype: u8,
    inhibit: Micros,
    event: Micros,
    sync_start: u8,
    ok: bool,
    count: u8,
    map: [Mapped; M],
    bytes: u8,
    /// Data sampled at the last SYNC (types 0..=240, 252).
    sample: [u8; 8],
    has_sample: bool,
    /// Data of the last transmission.
    last: [u8; 8],
    sent_once: bool,
    last_tx: Micros,
    next_event: Micros,
    sync_cnt: u8,
    started: bool,
    due: bool,
    rtr: bool,
    requested: bool,
}

impl<const M: usize> Tpdo<M> {
    const EMPTY: Self = Self {
        present: false,
        cob: 0,
        valid: false,
        rtr_ok: false,
        ttype: 0,
        inhibit: 0,
        event: 0,
        sync_start: 0,
        ok: false,
        count: 0,
        map: [Mapped::EMPTY; M],
        bytes: 0,
        sample: [0; 8],
        has_sample: false,
        last: [0; 8],
        sent_once: false,
        last_tx: 0,
        next_event: 0,
        sync_cnt: 0,
        started: false,
        due: false,
        rtr: false,
        requested: false,
    };

    fn active(&self) -> bool {
        self.present && self.valid && self.ok && self.count > 0
    }

    /// Whether the inhibit time since the last transmission still runs at `now`.
    #[cfg_attr(target_os = "none", inline(never))]
    #[cfg_attr(not(target_os = "none"), inline(always))]
    fn inhibited(&self, now: Micros) -> bool {
        self.inhibit != 0 && self.sent_once && now < later(self.last_tx, self.inhibit)
    }

    /// The loaded mapping.
    #[inline(always)]
    fn mapped(&self) -> &[Mapped] {
        self.map.get(..usize::from(self.count)).unwrap_or(&[])
    }

    /// Records a transmission of `data` at `now`.
    #[inline(always)]
    fn sent(&mut self, data: [u8; 8], now: Micros) {
        self.last = data;
        self.sent_once = true;
        self.requested = false;
        self.last_tx = now;
        self.next_event = later(now, self.event);
    }

    fn restart(&mut self, now: Micros) {
        self.sent_once = false;
        self.has_sample = false;
        self.sync_cnt = 0;
        self.started = false;
        self.due = false;
        self.rtr = false;
        self.next_event = later(now, self.event);
    }
}

#[derive(Clone, Copy)]
struct Rpdo<const M: usize> {
    present: bool,
    cob: u16,
    valid: bool,
    ttype: u8,
    ok: bool,
    count: u8,
    map: [Mapped; M],
    bytes: u8,
    pending: Option<[u8; 8]>,
    /// Deadline monitoring: 0 = off.
    timeout: Micros,
    last_rx: Option<Micros>,
    expired: bool,
}

impl<const M: usize> Rpdo<M> {
    const EMPTY: Self = Self {
        present: false,
        cob: 0,
        valid: false,
        ttype: 0,
        ok: false,
        count: 0,
        map: [Mapped::EMPTY; M],
        bytes: 0,
        pending: None,
        timeout: 0,
        last_rx: None,
        expired: false,
    };

    fn active(&self) -> bool {
        self.present && self.valid && self.ok && self.count > 0
    }
}

#[derive(Clone, Copy)]
struct Consumer {
    node: u8,
    time: Micros,
    last: Micros,
    active: bool,
}

impl Consumer {
    const EMPTY: Self = Self { node: 0, time: 0, last: 0, active: false };
}

/// Everything but the SDO server, so the server can borrow it as its [`ObjectAccess`].
struct Core<OD, A, S, const P: usize, const M: usize> {
    od: OD,
    app: A,
    storage: S,
    node: u8,
    now: Micros,
    nmt: NmtState,
    bootup: bool,
    sdo_reset: bool,
    sdo_rx: u16,
    sdo_tx: u16,
    sdo_valid: bool,
    sync_cob: u16,
    sync_producer: bool,
    sync_period: Micros,
    sync_overflow: u8,
    sync_counter: u8,
    sync_next: Micros,
    emcy_cob: u16,
    emcy_valid: bool,
    emcy_inhibit: Micros,
    emcy_last: Option<Micros>,
    emcy_queue: Queue,
    history_len: u8,
    hb_period: Micros,
    hb_next: Micros,
    guard_time: Micros,
    life_factor: u8,
    guard_toggle: bool,
    guard_reply: bool,
    guard_last: Option<Micros>,
    guard_lost: bool,
    consumers: [Consumer; MAX_HEARTBEAT_CONSUMERS],
    /// `consumers[..consumers_len]` holds every configured consumer (node != 0).
    consumers_len: usize,
    rpdo: [Rpdo<M>; P],
    tpdo: [Tpdo<M>; P],
    /// Numbers of the active RPDOs (`rx_active[..rx_len]`), in order, so that frames, SYNCs and
    /// deadlines only visit the PDOs in use.
    rx_active: [u16; P],
    rx_len: usize,
    /// Numbers of the active TPDOs (`tx_active[..tx_len]`), in order.
    tx_active: [u16; P],
    tx_len: usize,
    /// Whether an active TPDO is asynchronous (types 254, 255): `poll` visits the TPDOs every
    /// time.
    tx_async: bool,
    /// Whether `poll` has TPDO work: an asynchronous TPDO, or a synchronous one due or asked
    /// for by RTR since (set where `due` and `rtr` are set; cleared by the poll that finds
    /// nothing left).
    tx_poll: bool,
    /// Whether an active RPDO has deadline monitoring (an event timer).
    rx_deadlines: bool,
    /// Whether a synchronous RPDO may hold data for the next SYNC.
    rx_pending: bool,
    drive: Option<StateMachine>,
    /// 6041h (statusword) and 605Ah (quick stop option code), resolved when `drive` is created.
    statusword: Option<Handle>,
    quick_stop: Option<Handle>,
    remote: bool,
    /// The LSS slave, when the device answers LSS.
    #[cfg(feature = "lss")]
    lss: Option<crate::lss::LssSlave>,
}

/// A CANopen device around the dictionary `OD`, with application `A`, parameter storage `S`,
/// an SDO buffer of `BUF` bytes and room for `PDOS` receive and `PDOS` transmit PDOs.
///
/// Feed it every received frame with [`Device::on_frame`] and call [`Device::poll`] often
/// (at least every millisecond for millisecond-accurate timers) to collect the frames to send.
/// Nothing allocates; no bus input can make it panic or loop without bound.
///
/// ```
/// use od_runtime::{Device, Frame, NodeId, NoStorage};
/// # use od_runtime::od::*;
/// # struct Od;
/// # impl ObjectDictionary for Od {
/// #     fn entries(&self) -> &'static [EntryInfo] { &[] }
/// #     fn read(&self, _: u16, _: u8, _: &mut [u8]) -> Result<usize, AbortCode> { Err(AbortCode::NO_OBJECT) }
/// #     fn write(&mut self, _: u16, _: u8, _: &[u8]) -> Result<(), AbortCode> { Err(AbortCode::NO_OBJECT) }
/// #     fn restore_defaults(&mut self, _: Area, _: u8) {}
/// # }
/// let mut dev = Device::new(Od, (), NoStorage, NodeId::new(5).unwrap());
/// let mut sent = Vec::new();
/// dev.poll(0, |f| sent.push(f));
/// assert_eq!(sent[0].to_string(), "705 00"); // boot-up
/// dev.on_frame(&Frame::new(0x000, &[0x01, 5]).unwrap(), 10); // NMT start
/// assert_eq!(dev.nmt_state(), od_runtime::NmtState::Operational);
/// ```
pub struct Device<
    OD,
    A,
    S = crate::NoStorage,
    const BUF: usize = 1024,
    const PDOS: usize = 8,
    const MAP: usize = MAX_MAPPED,
> {
    sdo: SdoServer<BUF>,
    core: Core<OD, A, S, PDOS, MAP>,
    node_id: NodeId,
    started: bool,
}

/// The first (up to) four bytes of `data` as a little-endian number. Assembled byte by byte:
/// a copy of variable length would be a `memcpy` call on the RPDO path. Inlined on a host
/// (a call was a tenth of the controlword's RPDO path), one copy on a microcontroller.
#[cfg_attr(target_os = "none", inline(never))]
#[cfg_attr(not(target_os = "none"), inline(always))]
fn le_u32(data: &[u8]) -> u32 {
    let mut v = 0u32;
    for (i, b) in data.iter().take(4).enumerate() {
        v |= u32::from(*b) << (8 * i);
    }
    v
}

/// `at + delay`, saturating: a time in the future. Out of line on a microcontroller, where
/// each of a dozen 64-bit additions inlined costs more than the call.
#[cfg_attr(target_os = "none", inline(never))]
#[cfg_attr(not(target_os = "none"), inline(always))]
fn later(at: Micros, delay: Micros) -> Micros {
    at.saturating_add(delay)
}

/// Reads an unsigned value of up to 4 bytes, `default` when the dictionary has none: the
/// communication parameters' reads. Out of line on a microcontroller (two dozen callers).
#[cfg_attr(target_os = "none", inline(never))]
fn read_or<OD: ObjectDictionary>(od: &OD, index: u16, sub: u8, default: u32) -> u32 {
    read_uint(od, index, sub).unwrap_or(default)
}

/// Reads an unsigned value of up to 4 bytes.
fn read_uint<OD: ObjectDictionary>(od: &OD, index: u16, sub: u8) -> Option<u32> {
    let mut b = [0u8; 8];
    match od.read(index, sub, &mut b) {
        Ok(n) if (1..=4).contains(&n) => Some(le_u32(&b[..n])),
        _ => None,
    }
}

/// The restricted COB-IDs of CiA 301 §7.3.5, which a PDO may not use.
const fn restricted(id: u16) -> bool {
    matches!(id, 0x000..=0x07F | 0x101..=0x180 | 0x581..=0x5FF | 0x601..=0x67F | 0x6E0..=0x6FF | 0x701..=0x7FF)
}

fn pdo_lookup<OD: ObjectDictionary>(od: &OD) -> impl FnMut(u16, u8) -> Result<Mappable, AbortCode> + '_ {
    move |i, s| od.entry(i, s).map(|e| Mappable::from(&e))
}

/// The data of a TPDO: each mapped value's low `bits` bits, from bit 0 up, in one 64-bit word
/// (a loaded mapping has at most 64 bits, so every entry fits), zero past the mapping.
#[inline(always)]
fn pack<OD: ObjectDictionary, A: App<OD>>(od: &OD, app: &mut A, map: &[Mapped]) -> [u8; 8] {
    let mut data = od.read_mapped(map).to_le_bytes();
    app.on_tpdo(od, map, &mut data);
    data
}

impl<OD: ObjectDictionary, A: App<OD>, S: Storage, const P: usize, const M: usize> Core<OD, A, S, P, M> {
    /// SYNC consumer and producer: the dictionary has 1005h.
    const SYNC: bool = OD::SERVICES.sync;
    /// Node guarding: the dictionary has 100Ch and 100Dh.
    const GUARDING: bool = OD::SERVICES.node_guarding;
    /// Heartbeat consumer: the dictionary has 1016h.
    const CONSUMER: bool = OD::SERVICES.heartbeat_consumer;
    /// EMCY history: the dictionary has 1003h.
    const HISTORY: bool = OD::SERVICES.emcy_history;

    /// The CiA 402 state machine, when built in and the dictionary has one.
    #[inline(always)]
    fn drive(&self) -> Option<StateMachine> {
        if CIA402 { self.drive } else { None }
    }

    /// The CiA 402 state machine, mutably.
    #[inline(always)]
    fn drive_mut(&mut self) -> Option<&mut StateMachine> {
        if CIA402 { self.drive.as_mut() } else { None }
    }

    fn event(&mut self, e: Event) {
        self.app.on_event(&mut self.od, e);
    }

    fn entries_with(&self, index: u16) -> u8 {
        let mut n = 0u8;
        for sub in 1..=255 {
            if n < 254 && self.od.entry(index, sub).is_ok() {
                n += 1;
            }
        }
        n
    }

    // ---- configuration caches -------------------------------------------------------------

    fn reload_all(&mut self) {
        self.reload(0x1005);
        self.reload(0x1014);
        self.reload(0x1016);
        self.reload(0x1017);
        self.reload(0x100C);
        self.reload(0x1200);
        self.history_len = if Self::HISTORY { self.entries_with(0x1003) } else { 0 };
        for n in 0..P {
            self.load_pdo(Direction::Receive, n);
            self.load_pdo(Direction::Transmit, n);
        }
    }

    /// Refreshes the cached parameters that depend on `index`.
    fn reload(&mut self, index: u16) {
        let node = u32::from(self.node);
        match index {
            0x1005 | 0x1006 | 0x1019 if Self::SYNC => {
                let cob = read_or(&self.od, 0x1005, 0, 0x80);
                self.sync_cob = (cob & 0x7FF) as u16;
                self.sync_producer = cob & 0x4000_0000 != 0;
                self.sync_period = Micros::from(read_or(&self.od, 0x1006, 0, 0));
                self.sync_overflow = read_or(&self.od, 0x1019, 0, 0) as u8;
                self.sync_next = later(self.now, self.sync_period);
                self.sync_counter = 1;
            }
            0x1014 | 0x1015 => {
                let cob = read_or(&self.od, 0x1014, 0, 0x80 + node);
                self.emcy_cob = (cob & 0x7FF) as u16;
                self.emcy_valid = cob & 0x8000_0000 == 0;
                self.emcy_inhibit = Micros::from(read_or(&self.od, 0x1015, 0, 0)) * 100;
            }
            0x1016 if Self::CONSUMER => {
                let n = self.entries_with(0x1016);
                let mut k = 0;
                for sub in 1..=n {
                    if k == MAX_HEARTBEAT_CONSUMERS {
                        break;
                    }
                    let v = read_or(&self.od, 0x1016, sub, 0);
                    let (id, ms) = ((v >> 16) as u8, v & 0xFFFF);
                    let old = self.consumers[k];
                    let keep = old.node == id && old.active;
                    self.consumers[k] = Consumer {
                        node: if id == 0 || id > 127 || ms == 0 { 0 } else { id },
                        time: Micros::from(ms) * 1000,
                        last: if keep { old.last } else { 0 },
                        active: keep,
                    };
                    k += 1;
                }
                for c in &mut self.consumers[k..] {
                    *c = Consumer::EMPTY;
                }
                // Polls and heartbeats visit the consumers up to the last configured one.
                self.consumers_len = self.consumers.iter().rposition(|c| c.node != 0).map_or(0, |last| last + 1);
            }
            0x1017 => {
                self.hb_period = Micros::from(read_or(&self.od, 0x1017, 0, 0)) * 1000;
                self.hb_next = later(self.now, self.hb_period);
            }
            0x100C | 0x100D if Self::GUARDING => {
                self.guard_time = Micros::from(read_or(&self.od, 0x100C, 0, 0)) * 1000;
                self.life_factor = read_or(&self.od, 0x100D, 0, 0) as u8;
            }
            0x1200 => {
                let rx = read_or(&self.od, 0x1200, 1, 0x600 + node);
                let tx = read_or(&self.od, 0x1200, 2, 0x580 + node);
                self.sdo_rx = (rx & 0x7FF) as u16;
                self.sdo_tx = (tx & 0x7FF) as u16;
                self.sdo_valid = (rx | tx) & 0x8000_0000 == 0;
            }
            0x1400..=0x15FF => self.load_pdo(Direction::Receive, usize::from(index - 0x1400)),
            0x1600..=0x17FF => self.load_pdo(Direction::Receive, usize::from(index - 0x1600)),
            0x1800..=0x19FF => self.load_pdo(Direction::Transmit, usize::from(index - 0x1800)),
            0x1A00..=0x1BFF => self.load_pdo(Direction::Transmit, usize::from(index - 0x1A00)),
            _ => {}
        }
    }

    fn load_pdo(&mut self, dir: Direction, n: usize) {
        // CiA 301 numbers at most 512 PDOs per direction.
        if n >= P || n >= 512 {
            return;
        }
        let (comm, map) = match dir {
            Direction::Receive => (0x1400 + n as u16, 0x1600 + n as u16),
            Direction::Transmit => (0x1800 + n as u16, 0x1A00 + n as u16),
        };
        let od = &self.od;
        let cob = read_uint(od, comm, 1);
        let ttype = read_or(od, comm, 2, 255) as u8;
        let count = read_or(od, map, 0, 0).min(M as u32) as u8;
        let mut values = [0u32; M];
        let mut ok = true;
        for k in 0..count {
            match read_uint(od, map, k + 1) {
                Some(v) => values[usize::from(k)] = v,
                None => ok = false,
            }
        }
        let bits = pdo::check_mapping(dir, &values[..usize::from(count)], pdo_lookup(od));
        let mut ok = ok && bits.is_ok();
        let bytes = bits.unwrap_or(0).div_ceil(8) as u8;
        let mut entries = [Mapped::EMPTY; M];
        for (e, v) in entries.iter_mut().zip(&values[..usize::from(count)]) {
            let m = MapEntry::decode(*v);
            *e = Mapped { index: m.index, sub: m.sub, bits: m.bits, handle: Handle::new(0) };
            if ok && !m.is_dummy() {
                // Resolved once here, used on every SYNC and every reception.
                match od.handle(m.index, m.sub) {
                    Some(h) => e.handle = h,
                    None => ok = false,
                }
            }
        }
        let c = cob.unwrap_or(0x8000_0000);
        let valid = c & 0xA000_0000 == 0;
        match dir {
            Direction::Receive => {
                self.rpdo[n] = Rpdo {
                    present: cob.is_some(),
                    cob: (c & 0x7FF) as u16,
                    valid,
                    ttype,
                    ok,
                    count,
                    map: entries,
                    bytes,
                    pending: None,
                    timeout: Micros::from(read_or(od, comm, 5, 0)) * 1000,
                    last_rx: None,
                    expired: false,
                };
            }
            Direction::Transmit => {
                let inhibit = Micros::from(read_or(od, comm, 3, 0)) * 100;
                let event = Micros::from(read_or(od, comm, 5, 0)) * 1000;
                let sync_start = read_or(od, comm, 6, 0) as u8;
                let mut t = Tpdo {
                    present: cob.is_some(),
                    cob: (c & 0x7FF) as u16,
                    valid,
                    rtr_ok: c & 0x4000_0000 == 0,
                    ttype,
                    inhibit,
                    event,
                    sync_start,
                    ok,
                    count,
                    map: entries,
                    bytes,
                    ..Tpdo::EMPTY
                };
                let old = &self.tpdo[n];
                if old.active() && t.active() && old.cob == t.cob && old.count == t.count && old.map == t.map {
                    // Same PDO, new timing parameters: keep its transmission state.
                    t.sample = old.sample;
                    t.has_sample = old.has_sample;
                    t.last = old.last;
                    t.sent_once = old.sent_once;
                    t.last_tx = old.last_tx;
                    t.next_event = later(old.last_tx, event);
                    t.sync_cnt = old.sync_cnt;
                    t.started = old.started;
                    t.due = old.due;
                    t.requested = old.requested;
                } else {
                    t.restart(self.now);
                }
                self.tpdo[n] = t;
            }
        }
        self.index_active();
    }

    /// Rebuilds the lists of active RPDOs and TPDOs.
    fn index_active(&mut self) {
        self.rx_len = 0;
        self.tx_len = 0;
        self.rx_deadlines = false;
        self.tx_async = false;
        for n in 0..P {
            if self.rpdo[n].active() {
                self.rx_active[self.rx_len] = n as u16;
                self.rx_len += 1;
                self.rx_deadlines |= self.rpdo[n].timeout != 0;
            }
            if self.tpdo[n].active() {
                self.tx_active[self.tx_len] = n as u16;
                self.tx_len += 1;
                self.tx_async |= self.tpdo[n].ttype >= 254;
            }
        }
        // A reloaded TPDO may keep a pending transmission: let the next poll look.
        self.tx_poll = true;
    }

    // ---- writes ---------------------------------------------------------------------------

    /// The CiA 301 rules for PDO communication and mapping objects, checked before a write;
    /// whether a valid PDO's mapping and CAN-ID are locked is the dictionary's
    /// [`ObjectDictionary::PDO_REMAPPING`].
    fn check_pdo_write(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let (dir, n, mapping) = match index {
            0x1400..=0x15FF => (Direction::Receive, index - 0x1400, false),
            0x1600..=0x17FF => (Direction::Receive, index - 0x1600, true),
            0x1800..=0x19FF => (Direction::Transmit, index - 0x1800, false),
            _ => (Direction::Transmit, index - 0x1A00, true),
        };
        let comm = if dir == Direction::Receive { 0x1400 + n } else { 0x1800 + n };
        let cur = read_or(&self.od, comm, 1, 0x8000_0000);
        let valid = cur & 0x8000_0000 == 0;
        // The device's rule: must the PDO be invalid to change its mapping or CAN-ID? Under
        // CiA 301's, `locked` is `valid` (the same expression: no code of its own).
        let free = const { if OD::PDO_REMAPPING.needs_invalid_pdo() { 0 } else { 0x8000_0000 } };
        let locked = (cur | free) & 0x8000_0000 == 0;
        if !mapping {
            match sub {
                1 if data.len() == 4 => {
                    let v = le_u32(data);
                    if v & 0x2000_0000 != 0 {
                        return Err(AbortCode::INVALID_VALUE);
                    }
                    if v & 0x8000_0000 == 0 {
                        let id = (v & 0x7FF) as u16;
                        if (locked && id != (cur & 0x7FF) as u16) || restricted(id) {
                            return Err(AbortCode::INVALID_VALUE);
                        }
                    }
                }
                2 if data.len() == 1 => {
                    let t = data[0];
                    let ok = match dir {
                        Direction::Receive => t <= 240 || t >= 254,
                        Direction::Transmit => t <= 240 || t >= 252,
                    };
                    if !ok {
                        return Err(AbortCode::INVALID_VALUE);
                    }
                }
                3 | 6 if valid => return Err(AbortCode::INVALID_VALUE),
                _ => {}
            }
            return Ok(());
        }
        if locked {
            return Err(AbortCode::UNSUPPORTED_ACCESS);
        }
        if sub == 0 {
            if data.len() != 1 {
                return Ok(()); // the dictionary reports the length error
            }
            let count = data[0];
            // More entries than the device keeps per PDO (`MAP`, the EDS's Granularity
            // allows no more in 64 bits), or than CiA 301 allows.
            if usize::from(count) > M || usize::from(count) > MAX_MAPPED {
                return Err(AbortCode::VALUE_TOO_HIGH);
            }
            let mut values = [0u32; M];
            for k in 0..count {
                values[usize::from(k)] = read_uint(&self.od, index, k + 1).ok_or(AbortCode::VALUE_TOO_HIGH)?;
            }
            pdo::check_mapping(dir, &values[..usize::from(count)], pdo_lookup(&self.od))?;
        } else {
            if read_or(&self.od, index, 0, 0) != 0 {
                return Err(AbortCode::UNSUPPORTED_ACCESS);
            }
            let v = le_u32(data);
            if data.len() == 4 && v != 0 {
                // `&mut`, as `check_mapping` passes it: one copy of `check_entry` (by value,
                // a second monomorphisation: 196 B of the DRCS firmware).
                #[allow(clippy::needless_borrows_for_generic_args)]
                pdo::check_entry(dir, v, &mut pdo_lookup(&self.od))?;
            }
        }
        Ok(())
    }

    /// The write path shared by SDO, RPDOs and local writes (access rights are the caller's).
    fn write_entry(&mut self, index: u16, sub: u8, data: &[u8], source: WriteSource) -> Result<(), AbortCode> {
        self.write_resolved(index, sub, None, data, source)
    }

    /// [`Core::write_entry`], with the entry's handle when the caller has one (an RPDO). Only
    /// the communication objects and 6040h/6060h have rules and effects beyond the dictionary
    /// ([`has_side_effects`]); every other write is the application's veto, the dictionary's
    /// checks and the event.
    fn write_resolved(
        &mut self,
        index: u16,
        sub: u8,
        handle: Option<Handle>,
        data: &[u8],
        source: WriteSource,
    ) -> Result<(), AbortCode> {
        let special = has_side_effects(index);
        if special && self.write_special(index, sub, data, source)? {
            return Ok(());
        }
        self.app.on_write(&self.od, index, sub, data, source)?;
        match handle {
            Some(h) => self.od.write_handle(h, data)?,
            None => self.od.write(index, sub, data)?,
        }
        self.event(Event::Written { index, sub, source });
        if special {
            self.after_write(index, sub, data);
        }
        Ok(())
    }

    /// [`Core::write_resolved`] of an entry without side effects ([`has_side_effects`] false).
    #[inline(always)]
    fn write_plain(
        &mut self,
        index: u16,
        sub: u8,
        h: Handle,
        data: &[u8],
        source: WriteSource,
    ) -> Result<(), AbortCode> {
        self.app.on_write(&self.od, index, sub, data, source)?;
        self.od.write_handle(h, data)?;
        self.event(Event::Written { index, sub, source });
        Ok(())
    }

    /// The rules of the objects with side effects, before a write: `Err` refuses the write,
    /// `Ok(true)` means the write was carried out here in full (store/restore, clearing the
    /// error history), `Ok(false)` that it goes on to the dictionary.
    fn write_special(&mut self, index: u16, sub: u8, data: &[u8], source: WriteSource) -> Result<bool, AbortCode> {
        match index {
            0x1010 | 0x1011 if sub >= 1 => {
                self.od.entry(index, sub)?;
                if data.len() != 4 {
                    return Err(if data.len() < 4 { AbortCode::LENGTH_TOO_LOW } else { AbortCode::LENGTH_TOO_HIGH });
                }
                self.app.on_write(&self.od, index, sub, data, source)?;
                if index == 0x1010 {
                    self.store(sub, le_u32(data))?
                } else {
                    self.restore(sub, le_u32(data))?
                }
                self.event(Event::Written { index, sub, source });
                return Ok(true);
            }
            0x1003 if sub == 0 && Self::HISTORY => {
                self.od.entry(index, sub)?;
                if data.len() != 1 {
                    return Err(if data.is_empty() { AbortCode::LENGTH_TOO_LOW } else { AbortCode::LENGTH_TOO_HIGH });
                }
                if data[0] != 0 {
                    return Err(AbortCode::INVALID_VALUE);
                }
                self.app.on_write(&self.od, index, sub, data, source)?;
                self.clear_history();
                self.event(Event::Written { index, sub, source });
                return Ok(true);
            }
            0x1019 => {
                if self.sync_period != 0 {
                    return Err(AbortCode::DEVICE_STATE);
                }
                if data.len() == 1 && (data[0] == 1 || data[0] > 240) {
                    return Err(AbortCode::INVALID_VALUE);
                }
            }
            0x1005 | 0x1014 if sub == 0 && data.len() == 4 => {
                // CiA 301 §7.3.5: restricted CAN-IDs are not configurable, and 29-bit ids are
                // not supported. An EMCY COB-ID marked not valid may hold anything.
                let v = le_u32(data);
                let valid = index == 0x1005 || v & 0x8000_0000 == 0;
                if v & 0x2000_0000 != 0 || (valid && restricted((v & 0x7FF) as u16)) {
                    return Err(AbortCode::INVALID_VALUE);
                }
            }
            0x1400..=0x1BFF => self.check_pdo_write(index, sub, data)?,
            0x6040 if self.drive().is_some() && !self.remote => return Err(AbortCode::LOCAL_CONTROL),
            _ => {}
        }
        Ok(false)
    }

    fn after_write(&mut self, index: u16, sub: u8, data: &[u8]) {
        match index {
            0x1000..=0x1FFF => self.reload(index),
            0x6040 if sub == 0 && self.drive().is_some() => {
                let cw = le_u32(data) as u16;
                // 605Ah matters only in these two states (transitions 11, 12 and 16).
                let needs_option = self.drive().is_some_and(|sm| {
                    matches!(sm.state(), cia402::State::OperationEnabled | cia402::State::QuickStopActive)
                });
                let opt = if needs_option { self.quick_stop_option() } else { 2 };
                if let Some(sm) = self.drive_mut() {
                    let ts = sm.controlword(cw, opt);
                    self.drive_transitions(ts);
                }
            }
            0x6060 if sub == 0 && CIA402 => {
                let _ = self.od.write(0x6061, 0, data);
            }
            _ => {}
        }
    }

    fn store(&mut self, sub: u8, signature: u32) -> Result<(), AbortCode> {
        if signature != SAVE_SIGNATURE || !STORE {
            return Err(AbortCode::CANNOT_STORE);
        }
        self.storage.begin_transaction()?;
        let saved = self.save_areas(storage::areas_of(sub));
        let committed = self.storage.end_transaction(saved.is_ok());
        saved.and(committed)
    }

    /// Saves `areas` inside a storage transaction (see [`Storage::begin_transaction`]).
    fn save_areas(&mut self, areas: &[Area]) -> Result<(), AbortCode> {
        for &area in areas {
            self.storage.begin_save(area)?;
            let mut buf = [0u8; 256];
            for e in (0..self.od.entry_count()).map_while(|p| self.od.entry_at(p)) {
                if !area.contains(e.index) || !Self::storable(&e) {
                    continue;
                }
                if let Ok(n) = self.od.read(e.index, e.sub, &mut buf) {
                    self.storage.save_entry(e.index, e.sub, &buf[..n.min(buf.len())])?;
                }
            }
            self.storage.end_save(area)?;
        }
        Ok(())
    }

    /// Whether an entry belongs in a stored image: writable parameters, except DOMAINs and
    /// the store/restore/error-history objects.
    fn storable(e: &EntryInfo) -> bool {
        e.access.writable() && e.data_type != DataType::Domain && !matches!(e.index, 0x1003 | 0x1010 | 0x1011)
    }

    fn restore(&mut self, sub: u8, signature: u32) -> Result<(), AbortCode> {
        if signature != LOAD_SIGNATURE {
            return Err(AbortCode::CANNOT_STORE);
        }
        if !STORE {
            // Nothing is ever stored: the defaults apply at the next reset as they are.
            return Ok(());
        }
        self.storage.begin_transaction()?;
        let erased = storage::areas_of(sub).iter().try_for_each(|&area| self.storage.erase(area));
        let committed = self.storage.end_transaction(erased.is_ok());
        erased.and(committed)
    }

    fn load_stored(&mut self, area: Area) {
        if !STORE {
            return;
        }
        let Core { od, storage, .. } = self;
        storage.load(area, &mut |index, sub, data| {
            if area.contains(index) {
                let _ = od.write(index, sub, data);
            }
        });
    }

    // ---- NMT ------------------------------------------------------------------------------

    fn set_state(&mut self, to: NmtState) {
        let from = self.nmt;
        if from == to {
            return;
        }
        self.nmt = to;
        if to == NmtState::Operational {
            let now = self.now;
            for t in &mut self.tpdo {
                t.restart(now);
            }
        } else {
            for r in &mut self.rpdo {
                r.pending = None;
                r.last_rx = None;
            }
        }
        if !to.sdo_allowed() {
            self.sdo_reset = true;
        }
        self.event(Event::Nmt { from, to });
    }

    fn nmt_command(&mut self, cmd: NmtCommand) {
        match cmd {
            NmtCommand::Start => self.set_state(NmtState::Operational),
            NmtCommand::Stop => self.set_state(NmtState::Stopped),
            NmtCommand::EnterPreOperational => self.set_state(NmtState::PreOperational),
            NmtCommand::ResetNode => self.reset(ResetKind::Node),
            NmtCommand::ResetCommunication => self.reset(ResetKind::Communication),
        }
    }

    fn reset(&mut self, kind: ResetKind) {
        let from = self.nmt;
        self.nmt = NmtState::Initialising;
        if from != NmtState::Initialising {
            self.event(Event::Nmt { from, to: NmtState::Initialising });
        }
        #[cfg(feature = "lss")]
        self.lss_reset();
        if kind == ResetKind::Node {
            self.od.restore_defaults(Area::All, self.node);
            self.load_stored(Area::Application);
            self.load_stored(Area::Manufacturer);
        }
        self.od.restore_defaults(Area::Communication, self.node);
        self.load_stored(Area::Communication);
        self.emcy_queue.clear();
        self.emcy_last = None;
        self.guard_toggle = false;
        self.guard_reply = false;
        self.guard_last = None;
        self.guard_lost = false;
        if Self::CONSUMER {
            self.consumers = [Consumer::EMPTY; MAX_HEARTBEAT_CONSUMERS];
        }
        self.reload_all();
        self.sdo_reset = true;
        self.bootup = true;
        if kind == ResetKind::Node {
            let has = CIA402 && self.od.entry(0x6040, 0).is_ok() && self.od.entry(0x6041, 0).is_ok();
            self.drive = has.then(StateMachine::new);
            // Only a 16-bit 6041h/605Ah is used (as before handles: a read of another length
            // counted as absent).
            let u16_entry = |od: &OD, index| match od.entry(index, 0) {
                Ok(e) if e.byte_len() == 2 && !e.data_type.is_variable_length() => od.handle(index, 0),
                _ => None,
            };
            self.statusword = if has { u16_entry(&self.od, 0x6041) } else { None };
            self.quick_stop = u16_entry(&self.od, 0x605A);
        }
        self.event(Event::Reset(kind));
        if kind == ResetKind::Node
            && let Some(sm) = self.drive_mut()
        {
            let ts = sm.initialised();
            self.drive_transitions(ts);
        }
        self.update_statusword();
        #[cfg(feature = "lss")]
        if self.lss_unconfigured() {
            self.bootup = false;
            return;
        }
        self.set_state(NmtState::PreOperational);
    }

    // ---- EMCY -----------------------------------------------------------------------------

    fn error_register(&self) -> u8 {
        read_or(&self.od, 0x1001, 0, 0) as u8
    }

    fn emcy(&mut self, code: u16, register: u8, info: [u8; 5]) {
        let reg = self.error_register() | register | emcy::REG_GENERIC;
        let _ = self.od.write(0x1001, 0, &[reg]);
        self.push_history(code, info);
        let c = code.to_le_bytes();
        self.emcy_queue.push([c[0], c[1], reg, info[0], info[1], info[2], info[3], info[4]]);
    }

    fn emcy_reset(&mut self, register: u8) {
        let mut reg = self.error_register() & !register;
        // The generic bit stays set exactly while another error bit is.
        reg = if reg & !emcy::REG_GENERIC == 0 { 0 } else { reg | emcy::REG_GENERIC };
        let _ = self.od.write(0x1001, 0, &[reg]);
        self.emcy_queue.push([0, 0, reg, 0, 0, 0, 0, 0]);
    }

    fn push_history(&mut self, code: u16, info: [u8; 5]) {
        let max = self.history_len;
        if max == 0 || !Self::HISTORY {
            return;
        }
        for k in (1..max).rev() {
            if let Some(v) = read_uint(&self.od, 0x1003, k) {
                let _ = self.od.write(0x1003, k + 1, &v.to_le_bytes());
            }
        }
        let v = u32::from(code) | u32::from(info[0]) << 16 | u32::from(info[1]) << 24;
        let _ = self.od.write(0x1003, 1, &v.to_le_bytes());
        let count = (read_or(&self.od, 0x1003, 0, 0) as u8).saturating_add(1).min(max);
        let _ = self.od.write(0x1003, 0, &[count]);
    }

    fn clear_history(&mut self) {
        if !Self::HISTORY {
            return;
        }
        for k in 1..=self.history_len {
            let _ = self.od.write(0x1003, k, &[0; 4]);
        }
        let _ = self.od.write(0x1003, 0, &[0]);
    }

    // ---- CiA 402 --------------------------------------------------------------------------

    fn quick_stop_option(&self) -> i16 {
        match if CIA402 { self.quick_stop } else { None } {
            Some(h) => {
                let b = self.od.read_handle(h);
                i16::from_le_bytes([b[0], b[1]])
            }
            None => 2,
        }
    }

    #[cfg_attr(target_os = "none", inline(never))]
    #[cfg_attr(not(target_os = "none"), inline(always))]
    fn drive_transitions(&mut self, ts: Transitions) {
        // Most controlwords repeat the last one: no transition, no statusword change, and no
        // call on the RPDO path.
        if !ts.is_empty() {
            self.apply_transitions(ts);
        }
    }

    /// The effects of the state machine's transitions `ts`: fault reset, events, statusword.
    /// Out of line on a host (the RPDO path only tests for transitions); a microcontroller has
    /// one function for both.
    #[cfg_attr(target_os = "none", inline(always))]
    #[cfg_attr(not(target_os = "none"), inline(never))]
    fn apply_transitions(&mut self, ts: Transitions) {
        for t in ts.iter() {
            if t.number == 15 {
                // Fault reset: clear 603Fh and the error register bits of that fault (all bits
                // when the dictionary has no 603Fh), and send the error reset EMCY.
                let mut bits = 0xFF;
                if let Some(code) = read_uint(&self.od, 0x603F, 0) {
                    bits = emcy::register_bits(code as u16);
                    let _ = self.od.write(0x603F, 0, &[0, 0]);
                }
                self.emcy_reset(bits);
            }
            self.event(Event::Cia402(t));
        }
        self.update_statusword();
    }

    fn update_statusword(&mut self) {
        let (Some(sm), Some(h)) = (self.drive(), self.statusword) else { return };
        let b = self.od.read_handle(h);
        let cur = u16::from_le_bytes([b[0], b[1]]);
        let new = (cur & !0x027F) | sm.state().statusword_bits() | if self.remote { 0x0200 } else { 0 };
        if new != cur {
            let _ = self.od.write_handle(h, &new.to_le_bytes());
        }
    }

    // ---- SYNC and PDOs --------------------------------------------------------------------

    fn on_sync(&mut self, counter: Option<u8>) {
        self.event(Event::Sync { counter });
        if !self.nmt.pdo_allowed() {
            return;
        }
        if self.rx_pending {
            self.rx_pending = false;
            for i in 0..self.rx_len.min(P) {
                let n = usize::from(self.rx_active[i]);
                if let Some(data) = self.rpdo.get_mut(n).and_then(|r| r.pending.take()) {
                    self.apply_rpdo(n, data);
                }
            }
        }
        let mut due = false;
        for i in 0..self.tx_len.min(P) {
            let Some(t) = self.tpdo.get_mut(usize::from(self.tx_active[i])) else { continue };
            let ttype = t.ttype;
            if ttype == 0 {
                let data = pack(&self.od, &mut self.app, t.mapped());
                if !t.sent_once || data != t.last || t.requested {
                    t.sample = data;
                    t.due = true;
                    t.requested = false;
                    due = true;
                }
            } else if ttype <= 240 {
                if !t.started {
                    if t.sync_start != 0 && counter.is_some() && counter != Some(t.sync_start) {
                        continue;
                    }
                    t.started = true;
                    t.sync_cnt = 0;
                }
                // The counter is stored after the mapping is read, not before: a byte stored
                // just before `t.mapped()` reads the mapping's length (a neighbouring byte,
                // which the compiler may load as a wider word) stalls the load until the store
                // retires (store-to-load forwarding fails on a partial overlap); that stall was
                // most of this function's time in the SYNC benchmark.
                let cnt = t.sync_cnt.saturating_add(1);
                if cnt >= ttype {
                    t.sample = pack(&self.od, &mut self.app, t.mapped());
                    t.sync_cnt = 0;
                    t.due = true;
                    due = true;
                } else {
                    t.sync_cnt = cnt;
                }
            } else if ttype == 252 {
                t.sample = pack(&self.od, &mut self.app, t.mapped());
                t.has_sample = true;
            }
        }
        self.tx_poll |= due;
    }

    /// A frame for RPDO `n`: `data` is the frame's eight bytes (zero past its length `len`).
    fn on_rpdo(&mut self, n: usize, data: &[u8; 8], len: usize) {
        let now = self.now;
        let Some(r) = self.rpdo.get_mut(n) else { return };
        r.last_rx = Some(now);
        r.expired = false;
        if len < usize::from(r.bytes) {
            self.emcy(emcy::PDO_LENGTH_ERROR, emcy::REG_COMMUNICATION, [0; 5]);
            return;
        }
        let ttype = r.ttype;
        if len > usize::from(r.bytes) && self.app.rpdo_length_exceeded(n as u16) {
            self.emcy(emcy::PDO_LENGTH_EXCEEDED, emcy::REG_COMMUNICATION, [0; 5]);
        }
        let Some(r) = self.rpdo.get_mut(n) else { return };
        if ttype <= 240 {
            r.pending = Some(*data);
            self.rx_pending = true;
        } else {
            self.apply_rpdo(n, *data);
        }
    }

    /// Writes the entries of RPDO `n` from its data: each one's bits cut out of one 64-bit
    /// word, then written through its handle by [`Core::write_resolved`] (which applies the
    /// rules of the objects with side effects).
    #[cfg_attr(not(target_os = "none"), inline(always))]
    fn apply_rpdo(&mut self, n: usize, data: [u8; 8]) {
        let word = u64::from_le_bytes(data);
        let count = self.rpdo.get(n).map_or(0, |r| usize::from(r.count));
        let mut offset = 0u32;
        for k in 0..count.min(M) {
            let e = self.rpdo[n].map[k];
            let bits = u32::from(e.bits);
            if !e.is_dummy() {
                let v = low_bits(word >> (offset & 63), bits);
                let bytes = v.to_le_bytes();
                let len = (e.bits as usize).div_ceil(8).min(8);
                let (data, source) = (&bytes[..len], WriteSource::Rpdo(n as u16));
                // A microcontroller keeps one path (flash); a host writes the plain entries
                // (most of a PDO) here: the application's veto, the dictionary and the event,
                // without `write_resolved`'s call.
                if cfg!(target_os = "none") || has_side_effects(e.index) {
                    let _ = self.write_resolved(e.index, e.sub, Some(e.handle), data, source);
                } else {
                    let _ = self.write_plain(e.index, e.sub, e.handle, data, source);
                }
            }
            offset += bits;
        }
    }

    fn poll_tpdos(&mut self, now: Micros, emit: &mut impl FnMut(Frame)) {
        if !self.tx_poll {
            return;
        }
        // Whether a later poll has work left (an inhibited transmission, an asynchronous PDO).
        let mut again = self.tx_async;
        for i in 0..self.tx_len.min(P) {
            let Some(t) = self.tpdo.get_mut(usize::from(self.tx_active[i])) else { continue };
            let data = if t.rtr {
                t.rtr = false;
                again |= t.due;
                if t.ttype == 252 && t.has_sample { t.sample } else { pack(&self.od, &mut self.app, t.mapped()) }
            } else if t.due {
                if t.inhibited(now) {
                    again = true;
                    continue;
                }
                t.due = false;
                t.sample
            } else if t.ttype >= 254 && !t.inhibited(now) {
                let data = pack(&self.od, &mut self.app, t.mapped());
                let timer = t.event != 0 && now >= t.next_event;
                if !(!t.sent_once || data != t.last || timer || t.requested) {
                    continue;
                }
                data
            } else {
                continue;
            };
            // The data of a packed mapping is zero past its `bytes` (at most 8).
            emit(Frame::packed(t.cob, data, t.bytes));
            t.sent(data, now);
        }
        self.tx_poll = again;
    }

    // ---- time-driven services -------------------------------------------------------------

    fn poll(&mut self, now: Micros, emit: &mut impl FnMut(Frame)) {
        #[cfg(feature = "lss")]
        if self.lss_poll(emit) {
            return;
        }
        let node = u16::from(self.node);
        if self.nmt.emcy_sync_allowed() && self.emcy_valid {
            while !self.emcy_queue.is_empty() {
                if self.emcy_inhibit != 0 && self.emcy_last.is_some_and(|last| now < later(last, self.emcy_inhibit)) {
                    break;
                }
                if let Some(d) = self.emcy_queue.pop() {
                    emit(Frame::full(self.emcy_cob, d));
                    self.emcy_last = Some(now);
                }
                if self.emcy_inhibit != 0 {
                    break;
                }
            }
        }
        if Self::SYNC
            && self.sync_producer
            && self.sync_period != 0
            && self.nmt.emcy_sync_allowed()
            && now >= self.sync_next
        {
            self.sync_next = later(now, self.sync_period);
            let counter = (self.sync_overflow > 1).then_some(self.sync_counter);
            if let Some(c) = counter {
                emit(Frame::short(self.sync_cob, [c, 0, 0, 0, 0, 0, 0, 0], 1));
                self.sync_counter = if c >= self.sync_overflow { 1 } else { c + 1 };
            } else {
                emit(Frame::short(self.sync_cob, [0; 8], 0));
            }
            self.on_sync(counter);
        }
        if self.nmt.pdo_allowed() {
            self.poll_tpdos(now, emit);
            for i in 0..if self.rx_deadlines { self.rx_len.min(P) } else { 0 } {
                let n = usize::from(self.rx_active[i]);
                let Some(r) = self.rpdo.get_mut(n) else { continue };
                if r.timeout != 0
                    && !r.expired
                    && let Some(last) = r.last_rx
                    && now >= later(last, r.timeout)
                {
                    r.expired = true;
                    self.event(Event::RpdoTimeout { pdo: n as u16 });
                }
            }
        }
        if Self::GUARDING && self.guard_reply {
            self.guard_reply = false;
            let b = self.nmt.code() | if self.guard_toggle { 0x80 } else { 0 };
            self.guard_toggle = !self.guard_toggle;
            emit(Frame::short(0x700 + node, [b, 0, 0, 0, 0, 0, 0, 0], 1));
        }
        if self.hb_period != 0 && now >= self.hb_next {
            self.hb_next = later(now, self.hb_period);
            emit(Frame::short(0x700 + node, [self.nmt.code(), 0, 0, 0, 0, 0, 0, 0], 1));
        }
        for k in 0..if Self::CONSUMER { self.consumers_len.min(MAX_HEARTBEAT_CONSUMERS) } else { 0 } {
            let c = self.consumers[k];
            if c.node != 0 && c.active && now >= later(c.last, c.time) {
                self.consumers[k].active = false;
                self.event(Event::HeartbeatTimeout { node: c.node });
            }
        }
        let life = self.guard_time.saturating_mul(Micros::from(self.life_factor));
        if Self::GUARDING
            && life != 0
            && !self.guard_lost
            && let Some(last) = self.guard_last
            && now >= later(last, life)
        {
            self.guard_lost = true;
            self.event(Event::LifeGuardingLost);
        }
    }

    fn on_frame(&mut self, frame: &Frame) -> bool {
        #[cfg(feature = "lss")]
        if self.lss_frame(frame) {
            return false;
        }
        let id = frame.id();
        let node = u16::from(self.node);
        if frame.is_rtr() {
            if id == 0x700 + node {
                if Self::GUARDING && self.hb_period == 0 {
                    self.guard_reply = true;
                    self.guard_last = Some(self.now);
                    if self.guard_lost {
                        self.guard_lost = false;
                        self.event(Event::LifeGuardingResumed);
                    }
                }
            } else if self.nmt.pdo_allowed() {
                for i in 0..self.tx_len.min(P) {
                    if let Some(t) = self.tpdo.get_mut(usize::from(self.tx_active[i]))
                        && t.rtr_ok
                        && t.cob == id
                    {
                        t.rtr = true;
                        self.tx_poll = true;
                    }
                }
            }
            return false;
        }
        let data = frame.data();
        if id == 0 {
            if let [cs, target, ..] = *data
                && (target == 0 || target == self.node)
                && let Some(cmd) = NmtCommand::from_byte(cs)
            {
                self.nmt_command(cmd);
            }
            return false;
        }
        if Self::SYNC && id == self.sync_cob && self.nmt.emcy_sync_allowed() {
            self.on_sync(data.first().copied());
            return false;
        }
        if self.sdo_valid && id == self.sdo_rx {
            return self.nmt.sdo_allowed() && data.len() == 8;
        }
        if self.nmt.pdo_allowed() {
            for i in 0..self.rx_len.min(P) {
                let n = usize::from(self.rx_active[i]);
                if self.rpdo.get(n).is_some_and(|r| r.cob == id) {
                    self.on_rpdo(n, frame.raw(), data.len());
                    return false;
                }
            }
        }
        if Self::CONSUMER && (0x701..=0x77F).contains(&id) && !data.is_empty() {
            let from = (id - 0x700) as u8;
            let now = self.now;
            for k in 0..self.consumers_len.min(MAX_HEARTBEAT_CONSUMERS) {
                let c = self.consumers[k];
                if c.node == from {
                    self.consumers[k].last = now;
                    self.consumers[k].active = true;
                    if !c.active {
                        self.event(Event::HeartbeatStarted { node: from, state: data[0] });
                    }
                }
            }
        }
        false
    }
}

impl<OD: ObjectDictionary, A: App<OD>, S: Storage, const P: usize, const M: usize> ObjectAccess
    for Core<OD, A, S, P, M>
{
    // One copy on a microcontroller: the SDO server asks from many places.
    #[cfg_attr(target_os = "none", inline(never))]
    fn info(&self, index: u16, sub: u8) -> Result<SdoEntry, AbortCode> {
        self.od.entry(index, sub).map(|e| SdoEntry::from(&e))
    }

    fn read(&mut self, index: u16, sub: u8, buf: &mut [u8]) -> Result<usize, AbortCode> {
        if let Some(answer) = self.app.on_upload(&self.od, index, sub, buf) {
            return answer;
        }
        self.od.read(index, sub, buf)
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_entry(index, sub, data, WriteSource::Sdo)
    }
}

impl<OD: ObjectDictionary, A: App<OD>, S: Storage> Device<OD, A, S> {
    /// A device with a 1 KiB SDO buffer and room for 8 RPDOs and 8 TPDOs of up to 64 mapped
    /// entries each. Nothing happens until the first [`Device::poll`] or [`Device::on_frame`],
    /// which runs the reset node sequence (defaults, stored values) and queues the boot-up
    /// message. A generated dictionary's module also has a `Device` type sized from its EDS.
    pub const fn new(od: OD, app: A, storage: S, node_id: NodeId) -> Self {
        Self::with_capacity(od, app, storage, node_id)
    }
}

impl<OD: ObjectDictionary, A: App<OD>, S: Storage, const BUF: usize, const PDOS: usize, const MAP: usize>
    Device<OD, A, S, BUF, PDOS, MAP>
{
    /// Like [`Device::new`], for any buffer size and PDO capacity given as type parameters:
    /// `Device::<_, _, _, 4096, 16, 8>::with_capacity(..)`. PDOs the dictionary defines past
    /// `PDOS` are not served, and a mapping of more than `MAP` entries is refused
    /// (`VALUE_TOO_HIGH` when written, not loaded when stored).
    ///
    /// A `const fn`, so a firmware can build the device in a `static` at compile time, with
    /// no copy through the stack: `static DEV: Mutex<RefCell<Device<…>>> = …` or a
    /// `static mut` initialised by this call.
    #[inline(always)]
    pub const fn with_capacity(od: OD, app: A, storage: S, node_id: NodeId) -> Self {
        let node = node_id.get();
        Self {
            sdo: SdoServer::new(),
            node_id,
            started: false,
            core: Core {
                od,
                app,
                storage,
                node,
                now: 0,
                nmt: NmtState::Initialising,
                bootup: false,
                sdo_reset: false,
                sdo_rx: 0x600 + node as u16,
                sdo_tx: 0x580 + node as u16,
                sdo_valid: true,
                sync_cob: 0x80,
                sync_producer: false,
                sync_period: 0,
                sync_overflow: 0,
                sync_counter: 1,
                sync_next: 0,
                emcy_cob: 0x80 + node as u16,
                emcy_valid: true,
                emcy_inhibit: 0,
                emcy_last: None,
                emcy_queue: Queue::new(),
                history_len: 0,
                hb_period: 0,
                hb_next: 0,
                guard_time: 0,
                life_factor: 0,
                guard_toggle: false,
                guard_reply: false,
                guard_last: None,
                guard_lost: false,
                consumers: [Consumer::EMPTY; MAX_HEARTBEAT_CONSUMERS],
                consumers_len: 0,
                rpdo: [Rpdo::EMPTY; PDOS],
                tpdo: [Tpdo::EMPTY; PDOS],
                rx_active: [0; PDOS],
                rx_len: 0,
                tx_active: [0; PDOS],
                tx_len: 0,
                tx_async: false,
                tx_poll: false,
                rx_deadlines: false,
                rx_pending: false,
                drive: None,
                statusword: None,
                quick_stop: None,
                remote: true,
                #[cfg(feature = "lss")]
                lss: if OD::LSS { Some(crate::lss::LssSlave::new(node)) } else { None },
            },
        }
    }

    /// Builds the device in `place` (a `static` of a firmware, typically) and returns it:
    /// the same device as [`with_capacity`](Self::with_capacity), written field by field,
    /// the PDO tables entry by entry, so that nothing of its size passes through the stack.
    /// (Building it with `with_capacity` and moving it there may copy it through the stack;
    /// `MaybeUninit::write` does not promise otherwise.)
    ///
    /// `od` is moved in: pass a value the compiler can write in place, such as a generated
    /// dictionary's `zeroed()` (its first poll restores the defaults).
    #[inline(always)]
    pub fn init_in_place(
        place: &mut core::mem::MaybeUninit<Self>,
        od: OD,
        app: A,
        storage: S,
        node_id: NodeId,
    ) -> &mut Self {
        use core::ptr::addr_of_mut;
        /// Fails to compile when `Core` gains a field that the writes below do not cover.
        #[allow(dead_code, clippy::too_many_lines)]
        fn every_field_is_written<OD, A, S, const P: usize, const M: usize>(c: Core<OD, A, S, P, M>) {
            let Core {
                od: _,
                app: _,
                storage: _,
                node: _,
                now: _,
                nmt: _,
                bootup: _,
                sdo_reset: _,
                sdo_rx: _,
                sdo_tx: _,
                sdo_valid: _,
                sync_cob: _,
                sync_producer: _,
                sync_period: _,
                sync_overflow: _,
                sync_counter: _,
                sync_next: _,
                emcy_cob: _,
                emcy_valid: _,
                emcy_inhibit: _,
                emcy_last: _,
                emcy_queue: _,
                history_len: _,
                hb_period: _,
                hb_next: _,
                guard_time: _,
                life_factor: _,
                guard_toggle: _,
                guard_reply: _,
                guard_last: _,
                guard_lost: _,
                consumers: _,
                consumers_len: _,
                rpdo: _,
                tpdo: _,
                rx_active: _,
                rx_len: _,
                tx_active: _,
                tx_len: _,
                tx_async: _,
                tx_poll: _,
                rx_deadlines: _,
                rx_pending: _,
                drive: _,
                statusword: _,
                quick_stop: _,
                remote: _,
                #[cfg(feature = "lss")]
                    lss: _,
            } = c;
        }
        let node = node_id.get();
        let p = place.as_mut_ptr();
        // SAFETY: every field of `*p` is written exactly once below (whole values, or every
        // element of an array), through raw pointers into `place`, which is valid for writes
        // and exclusively ours; `every_field_is_written` keeps the list complete for `Core`,
        // and `Device` has the four fields written first. Then `*p` is initialised.
        unsafe {
            addr_of_mut!((*p).sdo).write(SdoServer::new());
            addr_of_mut!((*p).node_id).write(node_id);
            addr_of_mut!((*p).started).write(false);
            let c = addr_of_mut!((*p).core);
            addr_of_mut!((*c).od).write(od);
            let rpdo = addr_of_mut!((*c).rpdo).cast::<Rpdo<MAP>>();
            let tpdo = addr_of_mut!((*c).tpdo).cast::<Tpdo<MAP>>();
            for i in 0..PDOS {
                rpdo.add(i).write(Rpdo::EMPTY);
                tpdo.add(i).write(Tpdo::EMPTY);
            }
            let consumers = addr_of_mut!((*c).consumers).cast::<Consumer>();
            for i in 0..MAX_HEARTBEAT_CONSUMERS {
                consumers.add(i).write(Consumer::EMPTY);
            }
            addr_of_mut!((*c).rx_active).write([0; PDOS]);
            addr_of_mut!((*c).tx_active).write([0; PDOS]);
            addr_of_mut!((*c).app).write(app);
            addr_of_mut!((*c).storage).write(storage);
            addr_of_mut!((*c).node).write(node);
            addr_of_mut!((*c).now).write(0);
            addr_of_mut!((*c).nmt).write(NmtState::Initialising);
            addr_of_mut!((*c).bootup).write(false);
            addr_of_mut!((*c).sdo_reset).write(false);
            addr_of_mut!((*c).sdo_rx).write(0x600 + node as u16);
            addr_of_mut!((*c).sdo_tx).write(0x580 + node as u16);
            addr_of_mut!((*c).sdo_valid).write(true);
            addr_of_mut!((*c).sync_cob).write(0x80);
            addr_of_mut!((*c).sync_producer).write(false);
            addr_of_mut!((*c).sync_period).write(0);
            addr_of_mut!((*c).sync_overflow).write(0);
            addr_of_mut!((*c).sync_counter).write(1);
            addr_of_mut!((*c).sync_next).write(0);
            addr_of_mut!((*c).emcy_cob).write(0x80 + node as u16);
            addr_of_mut!((*c).emcy_valid).write(true);
            addr_of_mut!((*c).emcy_inhibit).write(0);
            addr_of_mut!((*c).emcy_last).write(None);
            addr_of_mut!((*c).emcy_queue).write(Queue::new());
            addr_of_mut!((*c).history_len).write(0);
            addr_of_mut!((*c).hb_period).write(0);
            addr_of_mut!((*c).hb_next).write(0);
            addr_of_mut!((*c).guard_time).write(0);
            addr_of_mut!((*c).life_factor).write(0);
            addr_of_mut!((*c).guard_toggle).write(false);
            addr_of_mut!((*c).guard_reply).write(false);
            addr_of_mut!((*c).guard_last).write(None);
            addr_of_mut!((*c).guard_lost).write(false);
            addr_of_mut!((*c).consumers_len).write(0);
            addr_of_mut!((*c).rx_len).write(0);
            addr_of_mut!((*c).tx_len).write(0);
            addr_of_mut!((*c).tx_async).write(false);
            addr_of_mut!((*c).tx_poll).write(false);
            addr_of_mut!((*c).rx_deadlines).write(false);
            addr_of_mut!((*c).rx_pending).write(false);
            addr_of_mut!((*c).drive).write(None);
            addr_of_mut!((*c).statusword).write(None);
            addr_of_mut!((*c).quick_stop).write(None);
            addr_of_mut!((*c).remote).write(true);
            #[cfg(feature = "lss")]
            addr_of_mut!((*c).lss).write(if OD::LSS { Some(crate::lss::LssSlave::new(node)) } else { None });
            place.assume_init_mut()
        }
    }

    fn start(&mut self, now: Micros) {
        self.core.now = now;
        if !self.started {
            self.started = true;
            #[cfg(feature = "lss")]
            self.core.lss_start();
            self.core.reset(ResetKind::Node);
        }
        self.apply_sdo_reset();
    }

    #[cfg_attr(target_os = "none", inline(never))]
    fn apply_sdo_reset(&mut self) {
        if self.core.sdo_reset {
            self.core.sdo_reset = false;
            self.sdo.reset();
        }
    }

    /// Handles one received frame. Responses are produced by the next [`Device::poll`].
    pub fn on_frame(&mut self, frame: &Frame, now: Micros) {
        self.start(now);
        if self.core.on_frame(frame) {
            self.sdo.request(frame.raw(), now, &mut self.core);
        }
        self.apply_sdo_reset();
    }

    /// Runs the time-driven services and hands every frame to send to `emit`: the boot-up
    /// message, the SDO response, EMCY, SYNC (when producing), TPDOs, the node guarding reply
    /// and the heartbeat, in that order.
    pub fn poll(&mut self, now: Micros, mut emit: impl FnMut(Frame)) {
        self.start(now);
        if self.core.bootup {
            self.core.bootup = false;
            emit(Frame::short(0x700 + u16::from(self.core.node), [0; 8], 1));
        }
        if self.core.nmt.sdo_allowed() {
            let tx = self.core.sdo_tx;
            self.sdo.poll(now, &mut |d| emit(Frame::full(tx, d)));
        }
        self.core.poll(now, &mut emit);
        self.apply_sdo_reset();
    }

    /// The node id in use (set over LSS, when the device answers LSS); a device without one
    /// (LSS, [`Device::active_node_id`] `None`) gives the one it was made with.
    pub fn node_id(&self) -> NodeId {
        NodeId::new(self.core.node).unwrap_or(self.node_id)
    }

    /// The NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.core.nmt
    }

    /// Executes an NMT command locally (as if the master had sent it to this node), e.g.
    /// `Start` for a device that enters Operational by itself.
    pub fn nmt_command(&mut self, cmd: NmtCommand, now: Micros) {
        self.start(now);
        self.core.nmt_command(cmd);
        self.apply_sdo_reset();
    }

    /// The dictionary.
    pub fn od(&self) -> &OD {
        &self.core.od
    }

    /// The dictionary, for the application's own values (actual position, statusword bits
    /// 7..15, ...). Writing communication objects (1000h..1FFFh) here bypasses the runtime;
    /// call [`Device::reload`] afterwards, or use [`Device::write`].
    pub fn od_mut(&mut self) -> &mut OD {
        &mut self.core.od
    }

    /// The application.
    pub fn app(&self) -> &A {
        &self.core.app
    }

    /// The application, mutably.
    pub fn app_mut(&mut self) -> &mut A {
        &mut self.core.app
    }

    /// The storage backend.
    pub fn storage_mut(&mut self) -> &mut S {
        &mut self.core.storage
    }

    /// Re-reads every communication parameter from the dictionary.
    pub fn reload(&mut self) {
        self.core.reload_all();
    }

    /// Writes an object as the application, with the same checks and side effects as an SDO
    /// download (PDO rules, store/restore, CiA 402), but without access-right checks. The
    /// application's own [`App::on_write`] sees it with [`WriteSource::Local`].
    pub fn write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.core.info(index, sub)?;
        self.core.write_entry(index, sub, data, WriteSource::Local)
    }

    /// Sets the SDO timeout (default 1 s; 0 disables it).
    pub fn set_sdo_timeout(&mut self, timeout: Micros) {
        self.sdo.set_timeout(timeout);
    }

    /// Asks for a transmission of TPDO `n` (0 = 1800h) of type 0 (at the next SYNC) or
    /// 254/255 (at the next poll, subject to the inhibit time).
    pub fn request_tpdo(&mut self, n: usize) {
        if let Some(t) = self.core.tpdo.get_mut(n) {
            t.requested = true;
            self.core.tx_poll = true;
        }
    }

    /// Signals an error: sets `register` (and the generic bit) in 1001h, records `code` in
    /// the 1003h history and queues an EMCY message `code, 1001h, info`.
    /// [`emcy::register_bits`] gives the usual bits for a code.
    pub fn signal_error(&mut self, code: u16, register: u8, info: [u8; 5]) {
        self.core.emcy(code, register, info);
    }

    /// Clears `register` bits in 1001h (the generic bit too when no other bit remains) and
    /// queues the "error reset" EMCY message (code 0000h).
    pub fn reset_error(&mut self, register: u8) {
        self.core.emcy_reset(register);
    }

    /// The error register (1001h).
    pub fn error_register(&self) -> u8 {
        self.core.error_register()
    }

    /// The CiA 402 state, if the dictionary has 6040h and 6041h.
    pub fn cia402_state(&self) -> Option<cia402::State> {
        self.core.drive().map(|sm| sm.state())
    }

    /// Reports a drive fault: stores `error_code` in 603Fh (when present), signals it as an
    /// EMCY and enters Fault reaction active (transition 13). The application runs its fault
    /// reaction and then calls [`Device::fault_reaction_done`].
    pub fn set_fault(&mut self, error_code: u16) {
        if self.core.od.entry(0x603F, 0).is_ok() {
            let _ = self.core.od.write(0x603F, 0, &error_code.to_le_bytes());
        }
        self.core.emcy(error_code, emcy::register_bits(error_code), [0; 5]);
        if let Some(sm) = self.core.drive_mut() {
            let ts = sm.fault();
            self.core.drive_transitions(ts);
        }
    }

    /// Like [`Device::set_fault`], with the EMCY's error register bits and manufacturer-specific
    /// bytes given: a vendor's error table says both (the DRVI puts a manufacturer parameter in
    /// EMCY byte 3, that is `info[0]`). `register` is or-ed into 1001h with the generic bit.
    pub fn set_fault_with(&mut self, error_code: u16, register: u8, info: [u8; 5]) {
        if self.core.od.entry(0x603F, 0).is_ok() {
            let _ = self.core.od.write(0x603F, 0, &error_code.to_le_bytes());
        }
        self.core.emcy(error_code, register, info);
        if let Some(sm) = self.core.drive_mut() {
            let ts = sm.fault();
            self.core.drive_transitions(ts);
        }
    }

    /// A fault reset that does not come from controlword bit 7 (the DRVI resets its faults when
    /// 0 is written to 1003h sub 0): in Fault, transition 15 with the same effects as the
    /// controlword's (603Fh cleared, the fault's 1001h bits cleared, the error reset EMCY).
    /// Nothing in other states.
    pub fn fault_reset(&mut self) {
        if let Some(sm) = self.core.drive_mut() {
            let ts = sm.fault_reset();
            self.core.drive_transitions(ts);
        }
    }

    /// The fault reaction is complete: Fault reaction active → Fault (transition 14).
    pub fn fault_reaction_done(&mut self) {
        if let Some(sm) = self.core.drive_mut() {
            let ts = sm.fault_reaction_done();
            self.core.drive_transitions(ts);
        }
    }

    /// The quick stop ramp is complete: Quick stop active → Switch on disabled (transition
    /// 12) when 605Ah is 0..=4; the drive stays in Quick stop active for 5..=8.
    pub fn quick_stop_done(&mut self) {
        let opt = self.core.quick_stop_option();
        if let Some(sm) = self.core.drive_mut() {
            let ts = sm.quick_stop_done(opt);
            self.core.drive_transitions(ts);
        }
    }

    /// Sets the application's statusword (6041h) bits: those of `mask` take their value from
    /// `value` (warning bit 7, target reached bit 10, internal limit bit 11, the mode-specific
    /// bits 12..13, the manufacturer bits 8, 14, 15). Bits 0..=6 and 9 belong to the state
    /// machine and are left alone. Returns `false` if the dictionary has no 6041h.
    pub fn set_statusword_flags(&mut self, mask: u16, value: u16) -> bool {
        let od = &mut self.core.od;
        let mut b = [0u8; 8];
        let cur = match od.read(0x6041, 0, &mut b) {
            Ok(2) => u16::from_le_bytes([b[0], b[1]]),
            _ => return false,
        };
        let mask = mask & !0x027F;
        let new = (cur & !mask) | (value & mask);
        new == cur || od.write(0x6041, 0, &new.to_le_bytes()).is_ok()
    }

    /// Sets statusword bit 9 (remote). While it is clear, controlword writes from the bus
    /// abort with 0x0800_0021 (local control).
    pub fn set_remote(&mut self, remote: bool) {
        self.core.remote = remote;
        self.core.update_statusword();
    }
}
