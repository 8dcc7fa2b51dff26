//! What `top` shows, updated by the bus's events, its frames and the keys; no terminal, no
//! clock (every update is given the time since the view started), so it is tested as is.

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use od_master::{Event, NmtState, NodeEvent, State};

use crate::cli::decode::{decode, emcy_class};
use crate::cli::device::Device;
use crate::cli::units;
use crate::cli::value::{encode, hex};
use eds::DataType;
use od_sidecar::{Dimension, ObjRef};

/// The most events and frames kept (older ones are dropped; memory stays bounded).
pub const KEEP_EVENTS: usize = 1000;
/// See [`KEEP_EVENTS`].
pub const KEEP_FRAMES: usize = 2000;

/// The pane the arrows move in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pane {
    /// One row a node.
    Nodes,
    /// Events, newest on top.
    Events,
    /// Frames in words, newest on top.
    Frames,
}

/// The last emergency of a node.
#[derive(Clone, Debug, PartialEq)]
pub struct LastEmcy {
    /// Its error code.
    pub code: u16,
    /// The device's text for it, else the CiA 301 class of the code.
    pub text: String,
    /// When it came.
    pub at: Duration,
}

/// What the TPDOs of a CiA 402 drive tell.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Drive {
    /// Statusword (6041h).
    pub status: Option<u16>,
    /// Modes of operation display (6061h).
    pub mode: Option<i8>,
    /// Position actual value (6064h), raw.
    pub position: Option<i64>,
    /// Velocity actual value (606Ch), raw.
    pub velocity: Option<i64>,
    /// The objects above that a TPDO carries (the others are polled).
    pub in_tpdo: Vec<u16>,
}

/// The CiA 402 objects the nodes pane shows: statusword, mode display, position, velocity.
pub const DRIVE_OBJECTS: [u16; 4] = [0x6041, 0x6061, 0x6064, 0x606C];

/// How often the drive objects no TPDO carries are read, by default.
pub const POLL: Duration = Duration::from_millis(200);

/// How long top's polls of a node wait after another master's SDO request to it: two masters
/// on one SDO channel take each other's answers (CiA 301 gives a node one server channel).
pub const YIELD: Duration = Duration::from_secs(2);

/// Objects to read from a node by SDO, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Poll {
    /// The node.
    pub node: u8,
    /// The objects (index, sub-index).
    pub objects: Vec<(u16, u8)>,
}

/// A node heard from.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeRow {
    /// Node id.
    pub id: u8,
    /// From its EDS (ProductName) or its 1008h.
    pub name: Option<String>,
    /// NMT state of its last heartbeat.
    pub nmt: Option<NmtState>,
    /// When its last heartbeat came.
    pub heard: Option<Duration>,
    /// The time between its last two heartbeats.
    pub period: Option<Duration>,
    /// Reported lost by the master (and not recovered since).
    pub lost: bool,
    /// Its last emergency.
    pub emcy: Option<LastEmcy>,
    /// For a CiA 402 device.
    pub drive: Option<Drive>,
    /// Heard from (a node of a network description is listed before it is).
    pub seen: bool,
    /// When another master's SDO request to it was last seen (top's own are not among the
    /// frames): its polls wait [`YIELD`] after it, not to answer for the other's transfers.
    pub other_master: Option<Duration>,
    /// A poll of this node is under way.
    pub polling: bool,
    /// When it was last polled.
    pub polled: Option<Duration>,
    /// Its name (1008h) was asked for.
    pub name_asked: bool,
    /// The values of the objects its sidecar's units depend on, read once (None: not asked).
    pub unit_values: Option<Vec<((u16, u8), i64)>>,
    /// Position and velocity in physical units: each a symbol and physical per raw.
    pub units: [Option<(&'static str, f64)>; 2],
    /// The values its TPDOs carried and the polls read, over time, for the plots.
    pub series: BTreeMap<(u16, u8), Series>,
    /// Entries picked in the object browser to plot (`g`): read at every poll, by type.
    pub watched: Vec<(u16, u8, DataType, String)>,
}

/// A value over time: (seconds since the view started, raw value).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Its name.
    pub label: String,
    /// The newest [`KEEP_POINTS`] points.
    pub points: VecDeque<(f64, f64)>,
}

/// A series of a node: (node, index, sub-index).
pub type SeriesKey = (u8, u16, u8);

/// The most series one plot shows (each its colour).
pub const PLOT_SERIES: usize = 6;
/// The most units one plot shows (each unit a panel with its own y-axis).
pub const PLOT_UNITS: usize = 3;

/// The plot: the series it shows, and the one the picker is on.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    /// Shown, in the order added (which gives their colours).
    pub shown: Vec<SeriesKey>,
    /// The series the picker is on (added or removed by Space).
    pub pick: SeriesKey,
}

/// The unit of a series on a plot's y-axis: the panel it goes to (series of one unit share a
/// y-axis), the unit's symbol, and physical per raw. Raw values share a panel only with the
/// same object's values (a statusword and a mode have nothing in common but being raw).
#[derive(Clone, Debug, PartialEq)]
pub struct PlotUnit {
    /// Series with the same panel share a y-axis.
    pub panel: String,
    /// `deg`, `rpm`, ... or `raw`.
    pub symbol: &'static str,
    /// Physical per raw (1 for raw).
    pub per_raw: f64,
}

/// The points a series keeps: 30 s at four points a [`BUCKET`], whatever the rate.
pub const KEEP_POINTS: usize = 3000;
/// A series keeps the first, lowest, highest and last value of each 40 ms (a TPDO every
/// millisecond would otherwise fill [`KEEP_POINTS`] in 3 s; a plot of 30 s has about 150 dots
/// across, 200 ms each).
pub const BUCKET: f64 = 0.040;
/// The series a node keeps.
pub const KEEP_SERIES: usize = 32;

/// How a node's heartbeat is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Health {
    /// No heartbeat seen yet.
    Unknown,
    /// Within its period.
    Alive,
    /// Later than one and a half periods.
    Late,
    /// Reported lost, or three periods without a heartbeat.
    Lost,
}

impl NodeRow {
    fn new(id: u8, device: Option<&Device>) -> Self {
        let name = device.and_then(|d| d.model.device_info.product_name.clone());
        let drive = device.filter(|d| d.model.entry(0x6041, 0).is_some()).map(|_| Drive::default());
        let name_asked = name.is_some();
        Self {
            id,
            name,
            nmt: None,
            heard: None,
            period: None,
            lost: false,
            emcy: None,
            drive,
            seen: false,
            other_master: None,
            polling: false,
            polled: None,
            name_asked,
            unit_values: None,
            units: [None, None],
            series: BTreeMap::new(),
            watched: Vec::new(),
        }
    }

    /// A value of a series; `label` names a new series (asked once: on a busy bus this runs
    /// for every field of every TPDO).
    fn record(&mut self, index: u16, sub: u8, label: impl FnOnce() -> String, at: Duration, value: f64) {
        if !self.series.contains_key(&(index, sub)) {
            if self.series.len() >= KEEP_SERIES {
                return;
            }
            self.series.insert((index, sub), Series { label: label(), points: VecDeque::new() });
        }
        let Some(s) = self.series.get_mut(&(index, sub)) else { return };
        let t = at.as_secs_f64();
        // The points of this bucket (at the end) and this one become the bucket's first, lowest,
        // highest and last, in time order: a brief spike stays.
        let bucket = |t: f64| (t / BUCKET).floor();
        let mut run = [(0.0, 0.0); 5];
        let mut n = 0;
        while n < 4
            && let Some(&p) = s.points.back()
            && bucket(p.0) == bucket(t)
        {
            s.points.pop_back();
            n += 1;
            run[4 - n] = p;
        }
        let run = &mut run[4 - n..];
        run[n] = (t, value);
        let pick = |better: fn(f64, f64) -> bool| {
            (0..run.len()).fold(0, |best, i| if better(run[i].1, run[best].1) { i } else { best })
        };
        let mut keep = [0, pick(|a, b| a < b), pick(|a, b| a > b), run.len() - 1];
        keep.sort_unstable();
        for (k, &i) in keep.iter().enumerate() {
            if k == 0 || keep[k - 1] != i {
                s.points.push_back(run[i]);
            }
        }
        if s.points.len() > KEEP_POINTS {
            s.points.pop_front();
        }
    }

    /// The unit of a series (position and velocity in the sidecar's), and physical per raw.
    pub fn unit_of(&self, index: u16, sub: u8) -> Option<(&'static str, f64)> {
        match (index, sub) {
            (0x6064, 0) => self.units[0],
            (0x606C, 0) => self.units[1],
            _ => None,
        }
    }

    /// Its heartbeat's health at `now`, and the age of its last heartbeat.
    pub fn health(&self, now: Duration) -> (Health, Option<Duration>) {
        let Some(heard) = self.heard else { return (if self.lost { Health::Lost } else { Health::Unknown }, None) };
        let age = now.saturating_sub(heard);
        let health = match self.period {
            _ if self.lost => Health::Lost,
            Some(p) if age > p * 3 => Health::Lost,
            Some(p) if age > p * 6 / 5 => Health::Late,
            _ => Health::Alive,
        };
        (health, Some(age))
    }
}

/// A frame in words, as `monitor` says it.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameLine {
    /// When it came.
    pub at: Duration,
    /// `pdo`, `heartbeat`, `emcy`, ... ([`crate::cli::decode::Decoded::kind`]).
    pub kind: &'static str,
    /// The node it is from or for.
    pub node: Option<u8>,
    /// One line.
    pub text: String,
}

/// The frames pane's filter: a node, a kind (a prefix: `sdo` takes both directions), or both.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Filter {
    /// Only this node's frames.
    pub node: Option<u8>,
    /// Only frames whose kind starts with this.
    pub kind: Option<String>,
}

impl Filter {
    /// `3`, `pdo`, `3 emcy`, `node 3 sdo` (empty: everything). Errors say which word is wrong.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut f = Filter::default();
        for word in text.split_whitespace().filter(|w| *w != "node") {
            if let Ok(n) = word.parse::<u8>() {
                if !(1..=127).contains(&n) {
                    return Err(format!("filter: {n} is not a node id (1..=127)"));
                }
                f.node = Some(n);
            } else if KINDS.iter().any(|k| k.starts_with(word)) {
                f.kind = Some(word.to_owned());
            } else {
                return Err(format!("filter: `{word}` is neither a node id nor a kind ({})", KINDS.join(", ")));
            }
        }
        Ok(f)
    }

    /// Whether `line` passes.
    pub fn passes(&self, line: &FrameLine) -> bool {
        self.node.is_none_or(|n| line.node == Some(n)) && self.kind.as_deref().is_none_or(|k| line.kind.starts_with(k))
    }

    /// As typed back.
    pub fn text(&self) -> String {
        let node = self.node.map(|n| format!("node {n}"));
        [node, self.kind.clone()].into_iter().flatten().collect::<Vec<_>>().join(" ")
    }
}

const KINDS: [&str; 12] =
    ["nmt", "sync", "time", "emcy", "pdo", "sdo-request", "sdo-response", "heartbeat", "guard", "lss", "other", "sdo"];

/// An entry of the object browser.
#[derive(Clone, Debug, PartialEq)]
pub struct BrowserEntry {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Its name in the EDS (the object's, then the entry's for a sub-index).
    pub name: String,
    /// Its type.
    pub data_type: DataType,
    /// `ro`, `rw`, ...
    pub access: String,
}

impl BrowserEntry {
    fn matches(&self, query: &str) -> bool {
        let q = query.trim().to_ascii_lowercase();
        let hex = q.trim_start_matches("0x").trim_end_matches('h');
        q.is_empty()
            || self.name.to_ascii_lowercase().contains(&q)
            || (!hex.is_empty() && format!("{:04x}", self.index).starts_with(hex))
    }
}

/// The object browser of one node: its dictionary from the EDS, searched, read and written.
#[derive(Clone, Debug, PartialEq)]
pub struct Browser {
    /// The node.
    pub node: u8,
    /// Every entry of its EDS.
    pub entries: Vec<BrowserEntry>,
    /// The search: a name's part, or an index (`6041`, `0x60`, `1018h`).
    pub query: String,
    /// The search is being typed.
    pub searching: bool,
    /// The selected entry among those the search passes.
    pub selected: usize,
    /// The last read or write: what came back, in words.
    pub result: Option<String>,
    /// A value being typed for a write.
    pub edit: Option<String>,
    /// A write waiting for `y`: index, sub-index, bytes, and the question.
    pub confirm: Option<(u16, u8, Vec<u8>, String)>,
}

impl Browser {
    /// The entries the search passes.
    pub fn shown(&self) -> impl Iterator<Item = &BrowserEntry> {
        self.entries.iter().filter(|e| e.matches(&self.query))
    }

    fn current(&self) -> Option<&BrowserEntry> {
        self.shown().nth(self.selected)
    }
}

/// An SDO transfer the browser asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// Read an entry (shown by its type).
    Read {
        /// Node.
        node: u8,
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Its type.
        data_type: DataType,
    },
    /// Write these bytes (confirmed, and only with `--allow-writes`).
    Write {
        /// Node.
        node: u8,
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The value's bytes.
        bytes: Vec<u8>,
    },
}

/// What the loop measures of itself (for the benchmark).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// Redraws done.
    pub redraws: u64,
    /// Time spent drawing, in all.
    pub draw: Duration,
    /// The longest draw.
    pub draw_max: Duration,
    /// Time spent taking events and frames in, in all.
    pub take: Duration,
    /// Events taken in, in all (the events pane keeps the newest [`KEEP_EVENTS`]).
    pub events: u64,
    /// EMCY events among them.
    pub emcys: u64,
}

impl Stats {
    /// One tick: the time taking the traffic in, the time drawing.
    pub fn tick(&mut self, take: Duration, draw: Duration) {
        self.redraws += 1;
        self.take += take;
        self.draw += draw;
        self.draw_max = self.draw_max.max(draw);
    }
}

/// Everything `top` shows.
#[derive(Debug)]
pub struct Model {
    /// The bus's address, for the title.
    pub bus: String,
    /// By node id.
    pub nodes: BTreeMap<u8, NodeRow>,
    /// Newest first: when, and what.
    pub events: VecDeque<(Duration, String)>,
    /// Newest first.
    pub frames: VecDeque<FrameLine>,
    /// Frames received in all.
    pub frame_count: u64,
    /// Frames the view could not take in time (the bus's channel overran).
    pub dropped: u64,
    /// Frames pane frozen.
    pub paused: bool,
    /// The frames pane's filter.
    pub filter: Filter,
    /// The filter being typed (after `/`), and the last filter error.
    pub input: Option<String>,
    /// A line for the status bar (a filter error).
    pub status: Option<String>,
    /// The pane the arrows move in.
    pub focus: Pane,
    /// The selected node (its index in [`nodes`](Self::nodes)).
    pub selected: usize,
    /// Lines scrolled down in the events and frames panes.
    pub scroll: [usize; 2],
    /// `q` or Ctrl-C.
    pub quit: bool,
    /// Heartbeat consumer times to ask the master for (node, timeout): a node's period, once
    /// known, so that the master reports it lost and recovered.
    pub watch: Vec<(u8, Duration)>,
    /// The object browser, when open.
    pub browser: Option<Browser>,
    /// The plot, when open.
    pub plot: Option<Plot>,
    /// The loop's own figures.
    pub stats: Stats,
    /// Reads and writes the browser asks for.
    pub requests: Vec<Request>,
    /// `--allow-writes`: without it the browser only reads.
    pub allow_writes: bool,
    /// How often the drive objects no TPDO carries are read (`None`: never; SDO polling shares
    /// the nodes' SDO channel with any other master on the bus).
    pub poll: Option<Duration>,
}

impl Model {
    /// An empty view of the bus at `bus`.
    pub fn new(bus: &str) -> Self {
        Self {
            bus: bus.to_owned(),
            nodes: BTreeMap::new(),
            events: VecDeque::new(),
            frames: VecDeque::new(),
            frame_count: 0,
            dropped: 0,
            paused: false,
            filter: Filter::default(),
            input: None,
            status: None,
            focus: Pane::Nodes,
            selected: 0,
            scroll: [0, 0],
            quit: false,
            watch: Vec::new(),
            browser: None,
            plot: None,
            stats: Stats::default(),
            requests: Vec::new(),
            allow_writes: false,
            poll: Some(POLL),
        }
    }

    /// The row of a node heard from.
    fn node(&mut self, id: u8, devices: &BTreeMap<u8, Device>) -> &mut NodeRow {
        let row = self.nodes.entry(id).or_insert_with(|| NodeRow::new(id, devices.get(&id)));
        row.seen = true;
        row
    }

    /// A node of the network description: listed under `name` before it is heard.
    pub fn list(&mut self, id: u8, name: &str, devices: &BTreeMap<u8, Device>) {
        let row = self.nodes.entry(id).or_insert_with(|| NodeRow::new(id, devices.get(&id)));
        row.name = Some(name.to_owned());
        row.name_asked = true;
    }

    /// A line among the events.
    pub fn note(&mut self, at: Duration, text: String) {
        self.log(at, text);
    }

    fn log(&mut self, at: Duration, text: String) {
        self.events.push_front((at, text));
        self.events.truncate(KEEP_EVENTS);
    }

    /// An event of the master.
    pub fn on_event(&mut self, at: Duration, event: &Event, devices: &BTreeMap<u8, Device>) {
        self.stats.events += 1;
        match event {
            Event::Node(e) => match *e {
                NodeEvent::BootUp { node } => {
                    let row = self.node(node, devices);
                    row.nmt = Some(NmtState::PreOperational);
                    row.lost = false;
                    self.log(at, format!("node {node}: boot-up"));
                }
                NodeEvent::FirstSeen { node, state } => {
                    self.node(node, devices);
                    self.log(at, format!("node {node}: first heartbeat, {}", nmt_long(state)));
                }
                NodeEvent::StateChanged { node, from, to } => {
                    self.node(node, devices).nmt = Some(to);
                    self.log(at, format!("node {node}: {} -> {}", nmt_long(from), nmt_long(to)));
                }
                NodeEvent::Lost { node } => {
                    self.node(node, devices).lost = true;
                    self.log(at, format!("node {node}: heartbeat lost"));
                }
                NodeEvent::Recovered { node, state } => {
                    let row = self.node(node, devices);
                    row.lost = false;
                    row.nmt = Some(state);
                    self.log(at, format!("node {node}: recovered, {}", nmt_long(state)));
                }
                NodeEvent::NeverSeen { node } => {
                    self.nodes.entry(node).or_insert_with(|| NodeRow::new(node, devices.get(&node))).lost = true;
                    self.log(at, format!("node {node}: never heard from"));
                }
                ref other => self.log(at, format!("{other:?}")),
            },
            Event::Emergency { emcy, text } => {
                self.stats.emcys += 1;
                let device = devices.get(&emcy.node);
                let text = text
                    .clone()
                    .or_else(|| device.and_then(|d| d.emcy_text(emcy.code, &emcy.vendor)).map(str::to_owned))
                    .unwrap_or_else(|| emcy_class(emcy.code).to_owned());
                let node = emcy.node;
                let code = emcy.code;
                self.node(node, devices).emcy = Some(LastEmcy { code, text: text.clone(), at });
                self.log(at, format!("node {node}: EMCY {code:04X}h {text}, register {:02X}h", emcy.register));
            }
            Event::Link(state) => self.log(at, format!("link: {state:?}")),
            Event::PdoError { cob_id, error } => self.log(at, format!("PDO {cob_id:03X}h: {error:?}")),
        }
    }

    /// A frame received.
    pub fn on_frame(&mut self, at: Duration, id: u32, rtr: bool, data: &[u8], devices: &BTreeMap<u8, Device>) {
        self.frame_count += 1;
        let d = decode(id, rtr, data, devices);
        // A node is heard from by what it sends: heartbeats, EMCYs, SDO answers, its TPDOs.
        if let (Some(node), "heartbeat" | "emcy" | "sdo-response" | "pdo") = (d.node, d.kind) {
            let row = self.node(node, devices);
            if d.kind == "heartbeat" {
                if data[0] == 0 {
                    // A boot-up: the heartbeat period starts anew.
                    row.period = None;
                    row.heard = None;
                } else {
                    if let Some(last) = row.heard {
                        let first = row.period.is_none();
                        row.period = Some(at.saturating_sub(last));
                        if first && !row.period.is_some_and(|p| p.is_zero()) {
                            self.watch.push((node, at.saturating_sub(last) * 2));
                        }
                    }
                    let row = self.node(node, devices);
                    row.heard = Some(at);
                    row.nmt = match data[0] & 0x7F {
                        0x04 => Some(NmtState::Stopped),
                        0x05 => Some(NmtState::Operational),
                        0x7F => Some(NmtState::PreOperational),
                        _ => row.nmt,
                    };
                }
            } else if d.kind == "pdo"
                && let Some(device) = devices.get(&node)
            {
                drive_fields(self.node(node, devices), device, node, id, data, at);
            }
        }
        // Another master's SDO request (top's own are not among the frames): top's polls of
        // that node wait, said once among the events.
        if let (Some(node), "sdo-request") = (d.node, d.kind)
            && let Some(row) = self.nodes.get_mut(&node)
        {
            let quiet = row.other_master.is_none_or(|t| at.saturating_sub(t) >= YIELD);
            row.other_master = Some(at);
            if quiet && self.poll.is_some() {
                self.log(at, format!("node {node}: another master's SDO: top's polls of it wait"));
            }
        }
        if !self.paused {
            self.frames.push_front(FrameLine { at, kind: d.kind, node: d.node, text: d.text });
            self.frames.truncate(KEEP_FRAMES);
        }
    }

    /// The reads due at `now`: each node's name (1008h) once when no EDS gives it, and every
    /// [`POLL`] the drive objects no TPDO carries; one poll a node at a time, none for a node
    /// lost or never heard by heartbeat.
    pub fn polls(&mut self, now: Duration, devices: &BTreeMap<u8, Device>) -> Vec<Poll> {
        let mut out = Vec::new();
        let Some(period) = self.poll else { return out };
        for row in self.nodes.values_mut() {
            if row.polling || row.lost || !row.seen || row.other_master.is_some_and(|t| now.saturating_sub(t) < YIELD) {
                continue;
            }
            let mut objects = Vec::new();
            if !row.name_asked {
                row.name_asked = true;
                objects.push((0x1008, 0));
            }
            if row.unit_values.is_none()
                && row.drive.is_some()
                && let Some(sidecar) = devices.get(&row.id).and_then(|d| d.sidecar.as_ref())
            {
                row.unit_values = Some(Vec::new());
                objects.extend(units::objects(sidecar).iter().map(|o| (o.index, o.sub_or_zero())));
            }
            if (row.drive.is_some() || !row.watched.is_empty())
                && row.heard.is_some()
                && row.polled.is_none_or(|t| now.saturating_sub(t) >= period)
            {
                row.polled = Some(now);
                if let Some(d) = &row.drive {
                    objects.extend(DRIVE_OBJECTS.iter().filter(|i| !d.in_tpdo.contains(i)).map(|&i| (i, 0)));
                }
                objects.extend(row.watched.iter().map(|w| (w.0, w.1)));
            }
            if !objects.is_empty() {
                row.polling = true;
                out.push(Poll { node: row.id, objects });
            }
        }
        out
    }

    /// The answer of a read [`polls`](Self::polls) asked for (`None`: it failed, said among
    /// the events once for the name).
    pub fn on_polled(&mut self, at: Duration, node: u8, index: u16, sub: u8, bytes: Option<&[u8]>) {
        let Some(row) = self.nodes.get_mut(&node) else { return };
        let Some(bytes) = bytes else { return };
        let mut le = [0u8; 8];
        let n = bytes.len().min(8);
        le[..n].copy_from_slice(&bytes[..n]);
        let int = |width: usize| {
            let v = u64::from_le_bytes(le);
            let bits = 8 * width.clamp(1, 8) as u32;
            if bits < 64 && v >> (bits - 1) & 1 == 1 { (v | !0u64 << bits) as i64 } else { v as i64 }
        };
        if let Some((.., data_type, name)) = row.watched.iter().find(|w| (w.0, w.1) == (index, sub)) {
            if let Some(v) = number(&le, *data_type) {
                let name = name.clone();
                row.record(index, sub, || name, at, v);
            }
            if !DRIVE_OBJECTS.contains(&index) {
                return;
            }
        }
        if let Some(values) = &mut row.unit_values
            && !DRIVE_OBJECTS.contains(&index)
            && index != 0x1008
        {
            values.push(((index, sub), int(bytes.len())));
            return;
        }
        match (index, &mut row.drive) {
            (0x1008, _) => {
                let text = String::from_utf8_lossy(bytes).trim_end_matches('\0').trim().to_owned();
                if !text.is_empty() {
                    row.name = Some(text);
                }
            }
            (0x6041, Some(d)) => d.status = Some(int(2) as u16),
            (0x6061, Some(d)) => d.mode = Some(int(1) as i8),
            (0x6064, Some(d)) => d.position = Some(int(4)),
            (0x606C, Some(d)) => d.velocity = Some(int(4)),
            _ => {}
        }
        if matches!(index, 0x6064 | 0x606C) {
            let label = if index == 0x6064 { "position (polled)" } else { "velocity (polled)" };
            row.record(index, sub, || label.into(), at, int(4) as f64);
        }
    }

    /// A poll of `node` is over: its units are worked out once their objects are read.
    pub fn poll_done(&mut self, node: u8, devices: &BTreeMap<u8, Device>) {
        let Some(row) = self.nodes.get_mut(&node) else { return };
        row.polling = false;
        let (Some(values), Some(sidecar)) = (&row.unit_values, devices.get(&node).and_then(|d| d.sidecar.as_ref()))
        else {
            return;
        };
        if row.units != [None, None] {
            return;
        }
        let values: BTreeMap<ObjRef, i64> = units::objects(sidecar)
            .into_iter()
            .filter_map(|o| values.iter().find(|(k, _)| *k == (o.index, o.sub_or_zero())).map(|(_, v)| (o, *v)))
            .collect();
        let Some(system) = sidecar.active_unit_system(|o| values.get(&o).copied()) else { return };
        for (slot, dim) in [Dimension::Position, Dimension::Velocity].into_iter().enumerate() {
            let Some(spec) = system.units.get(&dim) else { continue };
            let symbol = spec.unit.symbol();
            // Physical per raw, from the raw value of 1000 units.
            if let Ok(raw) = units::to_raw("1000", symbol, dim, sidecar, &values)
                && raw != 0
            {
                row.units[slot] = Some((symbol, 1000.0 / f64::from(raw)));
            }
        }
    }

    /// Every series of every node, by node then object.
    pub fn all_series(&self) -> impl Iterator<Item = SeriesKey> + '_ {
        self.nodes.values().flat_map(|n| n.series.keys().map(move |&(i, s)| (n.id, i, s)))
    }

    /// A series' label and unit (`None`: no such series).
    pub fn series_info(&self, (node, index, sub): SeriesKey) -> Option<(&Series, PlotUnit)> {
        let row = self.nodes.get(&node)?;
        let series = row.series.get(&(index, sub))?;
        let unit = match row.unit_of(index, sub) {
            Some((symbol, per_raw)) => PlotUnit { panel: symbol.to_owned(), symbol, per_raw },
            None => PlotUnit { panel: format!("{index:04X}h:{sub}"), symbol: "raw", per_raw: 1.0 },
        };
        Some((series, unit))
    }

    /// Opens the plot on the selected node: its position and velocity when it has them, else
    /// its first series.
    fn open_plot(&mut self) {
        let Some(n) = self.selected_node() else {
            self.status = Some("no node selected".into());
            return;
        };
        let Some(&(index, sub)) = n.series.keys().next() else {
            self.status = Some(format!("node {}: no values to plot yet (TPDOs or polled)", n.id));
            return;
        };
        let mut shown: Vec<SeriesKey> = [(0x6064, 0), (0x606C, 0)]
            .iter()
            .filter(|k| n.series.contains_key(k))
            .map(|&(i, s)| (n.id, i, s))
            .collect();
        if shown.is_empty() {
            shown.push((n.id, index, sub));
        }
        self.plot = Some(Plot { pick: shown[0], shown });
    }

    /// A key in the plot: the picker moves over every node's series, Space adds or removes the
    /// picked one.
    fn plot_key(&mut self, key: KeyEvent) {
        let all: Vec<SeriesKey> = self.all_series().collect();
        let Some(plot) = &self.plot else { return };
        let (mut shown, pick) = (plot.shown.clone(), plot.pick);
        let at = all.iter().position(|k| *k == pick).unwrap_or(0);
        let mut pick = pick;
        match key.code {
            KeyCode::Esc | KeyCode::Char('g') => {
                self.plot = None;
                return;
            }
            KeyCode::Char('q') => self.quit = true,
            KeyCode::Up | KeyCode::Left | KeyCode::Char('k') => {
                pick = all.get(at.wrapping_sub(1)).copied().unwrap_or(pick)
            }
            KeyCode::Down | KeyCode::Right | KeyCode::Char('j') => pick = all.get(at + 1).copied().unwrap_or(pick),
            KeyCode::Char('c') => shown.clear(),
            KeyCode::Char(' ') | KeyCode::Enter => {
                if let Some(i) = shown.iter().position(|k| *k == pick) {
                    shown.remove(i);
                } else if shown.len() >= PLOT_SERIES {
                    self.status = Some(format!("a plot shows at most {PLOT_SERIES} series: remove one first (Space)"));
                } else {
                    let unit = |k| self.series_info(k).map(|(_, u)| u.panel);
                    let mut panels: Vec<_> = shown.iter().filter_map(|&k| unit(k)).collect();
                    panels.sort();
                    panels.dedup();
                    let new = unit(pick);
                    if panels.len() >= PLOT_UNITS && !panels.contains(new.as_ref().unwrap_or(&String::new())) {
                        self.status =
                            Some(format!("a plot shows at most {PLOT_UNITS} units: remove a series of another first"));
                    } else {
                        shown.push(pick);
                    }
                }
            }
            _ => {}
        }
        self.plot = Some(Plot { shown, pick });
    }

    /// The frames the filter passes, newest first.
    pub fn shown_frames(&self) -> impl Iterator<Item = &FrameLine> {
        self.frames.iter().filter(|f| self.filter.passes(f))
    }

    /// The selected node.
    pub fn selected_node(&self) -> Option<&NodeRow> {
        self.nodes.values().nth(self.selected)
    }

    /// The answer to a browser's request, in words.
    pub fn on_answer(&mut self, text: String) {
        if let Some(b) = &mut self.browser {
            b.result = Some(text);
        }
    }

    fn open_browser(&mut self, devices: &BTreeMap<u8, Device>) {
        let Some(node) = self.selected_node().map(|n| n.id) else {
            self.status = Some("no node selected".into());
            return;
        };
        let Some(device) = devices.get(&node) else {
            self.status = Some(format!("node {node} has no EDS: give --eds {node}=FILE to browse its objects"));
            return;
        };
        let entries = device
            .model
            .entries()
            .map(|(o, e)| {
                let name = if o.subs.len() > 1 && e.sub.0 != 0 {
                    format!("{}: {}", o.name.as_str(), e.name.as_str())
                } else {
                    o.name.as_str().to_owned()
                };
                BrowserEntry {
                    index: o.index.0,
                    sub: e.sub.0,
                    name,
                    data_type: e.data_type,
                    access: format!("{:?}", e.access).to_ascii_lowercase(),
                }
            })
            .collect();
        self.browser = Some(Browser {
            node,
            entries,
            query: String::new(),
            searching: false,
            selected: 0,
            result: None,
            edit: None,
            confirm: None,
        });
    }

    /// A key in the browser.
    fn browser_key(&mut self, key: KeyEvent) {
        let allow_writes = self.allow_writes;
        let Some(b) = &mut self.browser else { return };
        if let Some((index, sub, bytes, _)) = b.confirm.take() {
            if key.code == KeyCode::Char('y') {
                self.requests.push(Request::Write { node: b.node, index, sub, bytes });
                b.result = Some(format!("writing {index:04X}h:{sub}..."));
            } else {
                b.result = Some("write cancelled".into());
            }
            return;
        }
        if let Some(edit) = &mut b.edit {
            match key.code {
                KeyCode::Esc => b.edit = None,
                KeyCode::Backspace => {
                    edit.pop();
                }
                KeyCode::Char(c) if edit.len() < 64 => edit.push(c),
                KeyCode::Enter => {
                    let text = b.edit.take().unwrap_or_default();
                    let Some(e) = b.current().cloned() else { return };
                    match encode(&text, e.data_type) {
                        Ok(bytes) => {
                            let question = format!(
                                "write {text} ({}) to node {} {:04X}h:{} {}? y/n",
                                hex(&bytes),
                                b.node,
                                e.index,
                                e.sub,
                                e.name
                            );
                            b.confirm = Some((e.index, e.sub, bytes, question));
                        }
                        Err(err) => b.result = Some(err.to_string()),
                    }
                }
                _ => {}
            }
            return;
        }
        if b.searching {
            match key.code {
                KeyCode::Enter | KeyCode::Esc => b.searching = false,
                KeyCode::Backspace => {
                    b.query.pop();
                    b.selected = 0;
                }
                KeyCode::Char(c) if b.query.len() < 40 => {
                    b.query.push(c);
                    b.selected = 0;
                }
                _ => {}
            }
            return;
        }
        let len = b.shown().count();
        match key.code {
            KeyCode::Esc => self.browser = None,
            KeyCode::Char('q') => self.quit = true,
            KeyCode::Char('/') => b.searching = true,
            KeyCode::Up => b.selected = b.selected.saturating_sub(1),
            KeyCode::Down => b.selected = (b.selected + 1).min(len.saturating_sub(1)),
            KeyCode::PageUp => b.selected = b.selected.saturating_sub(10),
            KeyCode::PageDown => b.selected = (b.selected + 10).min(len.saturating_sub(1)),
            KeyCode::Enter => {
                if let Some(e) = b.current() {
                    let (index, sub, data_type) = (e.index, e.sub, e.data_type);
                    self.requests.push(Request::Read { node: b.node, index, sub, data_type });
                    b.result = Some(format!("reading {index:04X}h:{sub}..."));
                }
            }
            KeyCode::Char('g') => {
                let Some(e) = b.current().cloned() else { return };
                let node = b.node;
                let mut le = [0u8; 8];
                le[0] = 1;
                let readable = e.access.contains('r') || e.access == "const";
                if number(&le, e.data_type).is_none() || !readable {
                    b.result =
                        Some(format!("{:04X}h:{} is not a readable number: it cannot be plotted", e.index, e.sub));
                    return;
                }
                if self.poll.is_none() {
                    b.result = Some("polling is off (--poll-ms 0): only TPDO values can be plotted".into());
                    return;
                }
                let Some(row) = self.nodes.get_mut(&node) else { return };
                if !row.watched.iter().any(|w| (w.0, w.1) == (e.index, e.sub)) {
                    if row.watched.len() >= KEEP_WATCHED {
                        b.result = Some(format!("at most {KEEP_WATCHED} entries a node are polled for plots"));
                        return;
                    }
                    row.watched.push((e.index, e.sub, e.data_type, e.name.clone()));
                }
                let key = (node, e.index, e.sub);
                self.browser = None;
                let mut plot = self.plot.take().unwrap_or(Plot { shown: Vec::new(), pick: key });
                if !plot.shown.contains(&key) && plot.shown.len() < PLOT_SERIES {
                    plot.shown.push(key);
                }
                plot.pick = key;
                self.plot = Some(plot);
            }
            KeyCode::Char('w') if !allow_writes => {
                b.result = Some("read-only: start top with --allow-writes to write".into());
            }
            KeyCode::Char('w') if b.current().is_some() => b.edit = Some(String::new()),
            _ => {}
        }
    }

    /// A key.
    pub fn on_key(&mut self, key: KeyEvent, devices: &BTreeMap<u8, Device>) {
        if key.modifiers.contains(KeyModifiers::CONTROL) && key.code == KeyCode::Char('c') {
            self.quit = true;
            return;
        }
        if self.browser.is_some() {
            self.browser_key(key);
            return;
        }
        if self.input.is_none() {
            // A message is said until the next key.
            self.status = None;
        }
        if self.plot.is_some() {
            self.plot_key(key);
            return;
        }
        if let Some(input) = &mut self.input {
            match key.code {
                KeyCode::Enter => {
                    match Filter::parse(input) {
                        Ok(f) => {
                            self.filter = f;
                            self.status = None;
                            self.scroll[1] = 0;
                        }
                        Err(e) => self.status = Some(e),
                    }
                    self.input = None;
                }
                KeyCode::Esc => self.input = None,
                KeyCode::Backspace => {
                    input.pop();
                }
                KeyCode::Char(c) if input.len() < 40 => input.push(c),
                _ => {}
            }
            return;
        }
        match key.code {
            KeyCode::Char('q') => self.quit = true,
            KeyCode::Tab => {
                self.focus = match self.focus {
                    Pane::Nodes => Pane::Events,
                    Pane::Events => Pane::Frames,
                    Pane::Frames => Pane::Nodes,
                }
            }
            KeyCode::BackTab => {
                self.focus = match self.focus {
                    Pane::Nodes => Pane::Frames,
                    Pane::Events => Pane::Nodes,
                    Pane::Frames => Pane::Events,
                }
            }
            KeyCode::Char('p') => self.paused = !self.paused,
            KeyCode::Char('o') => self.open_browser(devices),
            KeyCode::Char('g') => self.open_plot(),
            KeyCode::Enter if self.focus == Pane::Nodes => self.open_browser(devices),
            KeyCode::Char('/') => self.input = Some(self.filter.text()),
            KeyCode::Up | KeyCode::Char('k') => self.move_by(-1),
            KeyCode::Down | KeyCode::Char('j') => self.move_by(1),
            KeyCode::PageUp => self.move_by(-10),
            KeyCode::PageDown => self.move_by(10),
            KeyCode::Home => self.move_by(-(KEEP_FRAMES as isize)),
            _ => {}
        }
    }

    fn move_by(&mut self, by: isize) {
        let (at, len) = match self.focus {
            Pane::Nodes => (&mut self.selected, self.nodes.len()),
            Pane::Events => (&mut self.scroll[0], self.events.len()),
            Pane::Frames => {
                let len = self.frames.iter().filter(|f| self.filter.passes(f)).count();
                (&mut self.scroll[1], len)
            }
        };
        *at = at.saturating_add_signed(by).min(len.saturating_sub(1));
    }
}

/// The most entries of a node the browser adds to the polls for the plot.
pub const KEEP_WATCHED: usize = 8;

/// A value of a numeric type from its little-endian bytes (`None`: not a number).
fn number(le: &[u8; 8], data_type: DataType) -> Option<f64> {
    let u = u64::from_le_bytes(*le);
    let signed = |bits: u32| {
        let v = u & (u64::MAX >> (64 - bits));
        (if bits < 64 && v >> (bits - 1) & 1 == 1 { (v | !0u64 << bits) as i64 } else { v as i64 }) as f64
    };
    let unsigned = |bits: u32| (u & (u64::MAX >> (64 - bits))) as f64;
    Some(match data_type {
        DataType::Boolean => unsigned(1),
        DataType::Integer8 => signed(8),
        DataType::Integer16 => signed(16),
        DataType::Integer24 => signed(24),
        DataType::Integer32 => signed(32),
        DataType::Integer40 => signed(40),
        DataType::Integer48 => signed(48),
        DataType::Integer56 => signed(56),
        DataType::Integer64 => signed(64),
        DataType::Unsigned8 => unsigned(8),
        DataType::Unsigned16 => unsigned(16),
        DataType::Unsigned24 => unsigned(24),
        DataType::Unsigned32 => unsigned(32),
        DataType::Unsigned40 => unsigned(40),
        DataType::Unsigned48 => unsigned(48),
        DataType::Unsigned56 => unsigned(56),
        DataType::Unsigned64 => unsigned(64),
        DataType::Real32 => f64::from(f32::from_bits(u as u32)),
        DataType::Real64 => f64::from_bits(u),
        _ => return None,
    })
}

/// The short name of an NMT state.
pub fn nmt_name(state: Option<NmtState>) -> &'static str {
    match state {
        None => "-",
        Some(NmtState::Initialising) => "init",
        Some(NmtState::PreOperational) => "pre-op",
        Some(NmtState::Operational) => "oper",
        Some(NmtState::Stopped) => "stopped",
    }
}

/// An NMT state in words.
pub fn nmt_long(state: NmtState) -> &'static str {
    match state {
        NmtState::Initialising => "initialising",
        NmtState::PreOperational => "pre-operational",
        NmtState::Operational => "operational",
        NmtState::Stopped => "stopped",
    }
}

/// The CiA 402 state of a statusword, in words.
pub fn state_name(status: u16) -> &'static str {
    State::from_statusword(status).map_or("?", State::name)
}

/// The short name of a mode of operation (6060h/6061h).
pub fn mode_name(mode: i8) -> String {
    match mode {
        1 => "PP".into(),
        2 => "VL".into(),
        3 => "PV".into(),
        4 => "PT".into(),
        6 => "HM".into(),
        7 => "IP".into(),
        8 => "CSP".into(),
        9 => "CSV".into(),
        10 => "CST".into(),
        m => m.to_string(),
    }
}

/// The CiA 402 objects a TPDO of `device` carries, into `row`.
fn drive_fields(row: &mut NodeRow, device: &Device, node: u8, id: u32, data: &[u8], at: Duration) {
    let pdos = device.pdos(node);
    let Some(pdo) = pdos.iter().find(|p| p.cob_id == id) else { return };
    let mut bit = 0usize;
    for f in &pdo.fields {
        let bits = usize::from(f.bits);
        if bits == 0 || bits > 64 || bit + bits > data.len() * 8 {
            break;
        }
        let mut v: u64 = 0;
        for i in 0..bits {
            let b = bit + i;
            v |= u64::from(data[b / 8] >> (b % 8) & 1) << i;
        }
        bit += bits;
        if f.index < 0x1000 {
            continue; // a dummy entry fills a gap
        }
        // Signed, from its width, when its type is.
        let signed = if bits < 64 && v >> (bits - 1) & 1 == 1 { (v | !0u64 << bits) as i64 } else { v as i64 };
        let is_signed = device.model.entry(f.index, f.sub).is_some_and(|e| e.data_type.name().starts_with("INTEGER"));
        let label = || {
            device.names.name_of(f.index, f.sub).map_or_else(|| format!("{:04X}h:{}", f.index, f.sub), str::to_owned)
        };
        row.record(f.index, f.sub, label, at, if is_signed { signed as f64 } else { v as f64 });
        let Some(drive) = &mut row.drive else { continue };
        if f.sub == 0 && DRIVE_OBJECTS.contains(&f.index) && !drive.in_tpdo.contains(&f.index) {
            drive.in_tpdo.push(f.index);
        }
        match (f.index, f.sub) {
            (0x6041, 0) => drive.status = Some(v as u16),
            (0x6061, 0) => drive.mode = Some(signed as i8),
            (0x6064, 0) => drive.position = Some(signed),
            (0x606C, 0) => drive.velocity = Some(signed),
            _ => {}
        }
    }
}
