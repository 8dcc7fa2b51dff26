//! Each pane of `top` against the simulated drives on the in-memory bus, in virtual time:
//! the screen (80x24, ratatui's test backend) compared with its snapshot.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use drive::node::{DeviceKind, NodeConfig, Sim};
use od_master::{Bus, Config};
use ratatui::Terminal;
use ratatui::backend::TestBackend;

use super::Feed;
use super::model::{Filter, Model, Pane};
use super::view;
use crate::cli::device::Device;

fn device(file: &str) -> Device {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../devices").join(file);
    Device::load(&path).expect("the device's EDS")
}

struct Rig {
    bus: Bus,
    _sim: std::sync::Arc<std::sync::Mutex<Sim>>,
    devices: BTreeMap<u8, Device>,
    model: Model,
    feed: Feed,
}

impl Rig {
    /// The three drives (DRVI 2, DRCS 3, AKD 4) with their descriptions.
    fn new() -> Self {
        Self::with(BTreeMap::from([
            (2, device("camozzi-drvi.eds")),
            (3, device("camozzi-drcs.eds")),
            (4, device("kollmorgen-akd.eds")),
        ]))
    }

    /// The three drives, seen through `devices`.
    fn with(devices: BTreeMap<u8, Device>) -> Self {
        let mut sim = Sim::new();
        for (kind, id) in [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)] {
            let config = NodeConfig { node_id: Some(id), ..Default::default() };
            sim.add(kind.build(&config, &drive::drives::DeviceApps::new()).expect("a simulated drive"));
        }
        let (bus, sim) = drive::node::spawn_with_master(sim, Config::default(), Duration::from_micros(200));
        let feed = Feed::new(&bus);
        Self { bus, _sim: sim, devices, model: Model::new("mem://top"), feed }
    }

    /// Lets `ms` of virtual time pass, taking the traffic in at 20 Hz as the loop does.
    async fn pass(&mut self, ms: u64) {
        let end = tokio::time::Instant::now() + Duration::from_millis(ms);
        while tokio::time::Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(50).min(end - tokio::time::Instant::now())).await;
            self.feed.drain(&mut self.model, &self.devices);
            self.feed.watch(&self.bus, &mut self.model).await;
            self.feed.poll(&self.bus, &mut self.model, &self.devices);
        }
    }

    /// The screen as text, 80x24.
    fn screen(&self) -> String {
        let mut t = Terminal::new(TestBackend::new(80, 24)).unwrap();
        let now = self.feed.now();
        t.draw(|f| view::draw(f, &self.model, now)).unwrap();
        let buf = t.backend().buffer();
        let mut out = String::new();
        for y in 0..buf.area.height {
            for x in 0..buf.area.width {
                out.push_str(buf[(x, y)].symbol());
            }
            out.push('\n');
        }
        out
    }

    fn key(&mut self, code: KeyCode) {
        self.model.on_key(KeyEvent::new(code, KeyModifiers::NONE), &self.devices);
    }
}

/// The drives boot, send heartbeats, start, one moves, one sends an EMCY, one goes silent.
#[tokio::test(start_paused = true)]
async fn top_screens_of_drives_booting_moving_failing() {
    let mut r = Rig::new();
    r.pass(20).await;
    insta::assert_snapshot!("1_booted", r.screen());

    for id in [2, 3, 4] {
        r.bus.node(id).unwrap().write_idempotent(0x1017, 0, 100u16).await.unwrap();
    }
    r.bus.nmt(od_master::NmtCommand::Start, od_master::Target::All).await.unwrap();
    r.pass(500).await;
    // The master watches each heartbeat once it knows its period.
    assert!(r.model.nodes.values().all(|n| n.period == Some(Duration::from_millis(100))), "{:?}", r.model.nodes);
    insta::assert_snapshot!("2_heartbeats", r.screen());

    // The DRVI enabled and turning at a constant velocity.
    let axis = od_master::Axis::new(r.bus.node(2).unwrap());
    axis.enable().await.unwrap();
    axis.run_velocity(5_000, Some(50_000), Some(50_000)).await.unwrap();
    r.pass(500).await;
    let d = r.model.nodes[&2].drive.clone().unwrap();
    assert_eq!(d.velocity, Some(5_000), "{d:?}");
    assert!(d.position.is_some_and(|p| p > 1_000), "{d:?}");
    insta::assert_snapshot!("3_moving", r.screen());
    // Its position over time, in degrees (polled: the DRVI's TPDO carries only its statusword).
    // Opened on its position and velocity: two units, two panels on one time axis.
    r.key(KeyCode::Char('g'));
    let series: Vec<_> = r.model.nodes[&2].series.values().map(|s| s.label.clone()).collect();
    assert_eq!(series, ["statusword", "position (polled)", "velocity (polled)"]);
    let shown = |r: &Rig| r.model.plot.as_ref().map(|p| p.shown.clone()).unwrap_or_default();
    let pick = |r: &Rig| r.model.plot.as_ref().map(|p| p.pick);
    assert_eq!(shown(&r), [(2, 0x6064, 0), (2, 0x606C, 0)]);
    // Its statusword added (a third unit: raw), then its position removed.
    r.key(KeyCode::Left);
    assert_eq!(pick(&r), Some((2, 0x6041, 0)));
    r.key(KeyCode::Char(' '));
    assert_eq!(shown(&r), [(2, 0x6064, 0), (2, 0x606C, 0), (2, 0x6041, 0)]);
    insta::assert_snapshot!("3_moving_plot", r.screen());
    r.key(KeyCode::Right);
    r.key(KeyCode::Char(' '));
    assert_eq!(shown(&r), [(2, 0x606C, 0), (2, 0x6041, 0)]);
    // The picker goes on to the next node: the DRCS's statusword shares the raw statusword's
    // panel (same object), in a marker of its own.
    r.key(KeyCode::Right);
    r.key(KeyCode::Right);
    assert_eq!(pick(&r), Some((3, 0x6041, 0)));
    r.key(KeyCode::Char(' '));
    assert_eq!(shown(&r), [(2, 0x606C, 0), (2, 0x6041, 0), (3, 0x6041, 0)]);
    insta::assert_snapshot!("3_moving_plot_one_panel_two_series", r.screen());
    // A fourth unit is refused, saying why; then everything removed.
    r.key(KeyCode::Right);
    assert_eq!(pick(&r), Some((3, 0x6064, 0)));
    r.key(KeyCode::Char(' '));
    assert_eq!(shown(&r).len(), 4, "a third unit (mm)");
    while pick(&r) != Some((4, 0x6064, 0)) {
        assert!(pick(&r) < Some((4, 0x6064, 0)), "the picker passes every series in order");
        r.key(KeyCode::Right);
    }
    r.key(KeyCode::Char(' '));
    assert_eq!(shown(&r).len(), 4, "a fourth unit (the AKD's user units) refused");
    assert!(r.model.status.as_deref().is_some_and(|s| s.contains("at most 3 units")), "{:?}", r.model.status);
    r.key(KeyCode::Char('c'));
    assert_eq!(shown(&r), []);
    r.key(KeyCode::Esc);
    assert_eq!(r.model.plot, None);

    // The DRCS refuses to move before homing: EMCY FF13h with its sidecar's text.
    let drcs = od_master::Axis::new(r.bus.node(3).unwrap());
    drcs.enable().await.unwrap();
    drcs.set_mode(1).await.unwrap();
    let n3 = drcs.node();
    n3.write(0x6081, 0, 50u32).await.unwrap();
    n3.write(0x607A, 0, 100i32).await.unwrap();
    n3.write(0x6040, 0, 0x1Fu16).await.unwrap();
    n3.write(0x6040, 0, 0x0Fu16).await.unwrap();
    r.pass(200).await;
    let emcy = r.model.nodes[&3].emcy.clone().expect("the DRCS's EMCY");
    assert_eq!((emcy.code, emcy.text.as_str()), (0xFF13, "Operation without reset"));
    r.key(KeyCode::Down);
    insta::assert_snapshot!("4_emcy", r.screen());

    // The AKD's heartbeat stops: late, then lost (the master's event).
    r.bus.node(4).unwrap().write_idempotent(0x1017, 0, 0u16).await.unwrap();
    r.pass(140).await;
    insta::assert_snapshot!("5_late", r.screen());
    r.pass(400).await;
    assert!(r.model.nodes[&4].lost);
    assert!(r.model.events.iter().any(|(_, e)| e == "node 4: heartbeat lost"), "{:?}", r.model.events);
    insta::assert_snapshot!("6_lost", r.screen());

    // Frames: only node 3's SDO, then paused.
    r.key(KeyCode::Tab);
    r.key(KeyCode::Tab);
    assert_eq!(r.model.focus, Pane::Frames);
    r.key(KeyCode::Char('/'));
    for c in "3 sdo".chars() {
        r.key(KeyCode::Char(c));
    }
    r.key(KeyCode::Enter);
    assert_eq!(r.model.filter, Filter { node: Some(3), kind: Some("sdo".into()) });
    r.bus.node(3).unwrap().read::<u16>(0x6041, 0).await.unwrap();
    r.pass(50).await;
    r.key(KeyCode::Char('p'));
    let before = r.model.frames.len();
    r.bus.node(3).unwrap().read::<u16>(0x6041, 0).await.unwrap();
    r.pass(200).await;
    assert_eq!(r.model.frames.len(), before, "paused: no new frames shown");
    insta::assert_snapshot!("7_frames_filtered_paused", r.screen());

    r.model.on_key(KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL), &r.devices);
    assert!(r.model.quit);
}

/// The object browser of the DRVI: searched by name and by index, a read shown typed, a write
/// refused without --allow-writes, and with it asked for and confirmed.
#[tokio::test(start_paused = true)]
async fn top_object_browser_searches_reads_and_writes_only_when_allowed() {
    let mut r = Rig::new();
    r.bus.node(2).unwrap().write_idempotent(0x1017, 0, 100u16).await.unwrap();
    r.pass(300).await;
    r.key(KeyCode::Char('o'));
    assert_eq!(r.model.browser.as_ref().map(|b| b.node), Some(2));
    r.key(KeyCode::Char('/'));
    for c in "heartbeat".chars() {
        r.key(KeyCode::Char(c));
    }
    r.key(KeyCode::Enter);
    r.key(KeyCode::Enter);
    r.pass(100).await;
    let b = r.model.browser.as_ref().unwrap();
    assert_eq!(b.result.as_deref(), Some("1017h:0 = 100"), "{b:?}");
    insta::assert_snapshot!("8_browser_read", r.screen());
    r.key(KeyCode::Char('w'));
    assert!(r.model.browser.as_ref().unwrap().result.as_deref().unwrap().contains("--allow-writes"));
    // By index, then a write, confirmed.
    r.model.allow_writes = true;
    r.key(KeyCode::Char('/'));
    for _ in 0..9 {
        r.key(KeyCode::Backspace);
    }
    for c in "0x1017".chars() {
        r.key(KeyCode::Char(c));
    }
    r.key(KeyCode::Enter);
    r.key(KeyCode::Char('w'));
    for c in "250".chars() {
        r.key(KeyCode::Char(c));
    }
    r.key(KeyCode::Enter);
    insta::assert_snapshot!("9_browser_confirm", r.screen());
    r.key(KeyCode::Char('y'));
    r.pass(100).await;
    assert_eq!(r.model.browser.as_ref().unwrap().result.as_deref(), Some("1017h:0 written: fa00"));
    assert_eq!(r.bus.node(2).unwrap().read::<u16>(0x1017, 0).await.unwrap(), 250);
    // Anything but y cancels.
    r.key(KeyCode::Char('w'));
    r.key(KeyCode::Char('1'));
    r.key(KeyCode::Enter);
    r.key(KeyCode::Char('n'));
    assert_eq!(r.model.browser.as_ref().unwrap().result.as_deref(), Some("write cancelled"));
    assert!(r.model.requests.is_empty());
    r.key(KeyCode::Esc);
    assert!(r.model.browser.is_none());

    // An entry plotted from the browser: a text is refused; a number is polled from now on at the
    // poll period and shown in the plot under its EDS name.
    let search = |r: &mut Rig, text: &str| {
        r.key(KeyCode::Char('/'));
        for c in text.chars() {
            r.key(KeyCode::Char(c));
        }
        r.key(KeyCode::Enter);
    };
    r.key(KeyCode::Char('o'));
    search(&mut r, "1008");
    r.key(KeyCode::Char('g'));
    let said = r.model.browser.as_ref().and_then(|b| b.result.clone()).unwrap_or_default();
    assert_eq!(said, "1008h:0 is not a readable number: it cannot be plotted");
    r.key(KeyCode::Esc);
    r.key(KeyCode::Char('o'));
    search(&mut r, "1017");
    r.key(KeyCode::Char('g'));
    assert!(r.model.browser.is_none());
    assert_eq!(r.model.plot.as_ref().map(|p| p.shown.clone()), Some(vec![(2, 0x1017, 0)]));
    r.pass(600).await;
    let s = &r.model.nodes[&2].series[&(0x1017, 0)];
    assert_eq!(s.label, "Producer heartbeat time");
    assert!(s.points.len() >= 2, "polled every 200 ms: {s:?}");
    assert_eq!(s.points.back().map(|p| p.1), Some(250.0));
}

/// The nodes of networks/example.toml listed under the description's names before they are
/// heard; once the network is booted as described, its TPDOs are decoded by the mappings the
/// description configures (the DRVI's position comes in its TPDO1, which by default carries the
/// statusword alone) and its values shown in the sidecars' units.
#[tokio::test(start_paused = true)]
async fn top_lists_the_nodes_of_a_network_description() {
    let file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../networks/example.toml");
    let network = crate::cli::boot::load(&[file]).expect("the example network");
    let (devices, listed) = super::devices(&network, &[]).expect("its devices");
    assert_eq!(listed, [(2, "x_axis".to_owned()), (3, "y_axis".to_owned()), (4, "z_axis".to_owned())]);
    // The DRVI's default TPDO1 is its statusword alone; the description adds its position.
    let tpdo1 = |d: &Device| d.pdos(2).iter().find(|p| p.name == "TPDO1").map(|p| p.fields.len());
    assert_eq!(tpdo1(&devices[&2]), Some(2));
    assert_eq!(tpdo1(&device("camozzi-drvi.eds")), Some(1));
    let mut r = Rig::with(devices);
    for (id, name) in &listed {
        r.model.list(*id, name, &r.devices);
    }
    insta::assert_snapshot!("10_network_listed", r.screen());

    // Booted as `od-master boot` does, top watching meanwhile.
    let options = od_master::BootOptions { start: true, concurrent: true, ..od_master::BootOptions::default() };
    let (bus, net) = (r.bus.clone(), network.clone());
    let boot = tokio::spawn(async move { od_master::boot::boot(&bus, &net, &options).await });
    while !boot.is_finished() {
        r.pass(50).await;
    }
    let reports = boot.await.unwrap();
    assert!(reports.iter().all(|r| r.result.is_ok()), "{reports:?}");
    let axis = od_master::Axis::new(r.bus.node(2).unwrap());
    axis.enable().await.unwrap();
    axis.run_velocity(5_000, Some(50_000), Some(50_000)).await.unwrap();
    r.pass(600).await;
    let d = r.model.nodes[&2].drive.clone().unwrap();
    assert!(d.in_tpdo.contains(&0x6064), "the configured TPDO1 carries the position: {d:?}");
    let names: Vec<_> = r.model.nodes.values().map(|n| n.name.clone().unwrap_or_default()).collect();
    assert_eq!(names, ["x_axis", "y_axis", "z_axis"], "the description's names stay");
    insta::assert_snapshot!("11_network_booted", r.screen());
}

#[test]
fn a_filter_names_a_node_a_kind_or_both_and_says_what_is_wrong() {
    assert_eq!(Filter::parse("").unwrap(), Filter::default());
    assert_eq!(Filter::parse("node 3 pdo").unwrap(), Filter { node: Some(3), kind: Some("pdo".into()) });
    assert_eq!(Filter::parse("emcy").unwrap(), Filter { node: None, kind: Some("emcy".into()) });
    assert!(Filter::parse("200").unwrap_err().contains("not a node id"));
    assert!(Filter::parse("bogus").unwrap_err().contains("`bogus` is neither a node id nor a kind"));
}

/// A bad filter is said on the bottom line and leaves the filter as it was.
#[test]
fn a_bad_filter_is_said_and_not_applied() {
    let mut m = Model::new("mem://x");
    for c in "/pdo".chars() {
        m.on_key(KeyEvent::new(KeyCode::Char(c), KeyModifiers::NONE), &BTreeMap::new());
    }
    m.on_key(KeyEvent::new(KeyCode::Enter, KeyModifiers::NONE), &BTreeMap::new());
    for c in "/xyz".chars() {
        m.on_key(KeyEvent::new(KeyCode::Char(c), KeyModifiers::NONE), &BTreeMap::new());
    }
    m.on_key(KeyEvent::new(KeyCode::Enter, KeyModifiers::NONE), &BTreeMap::new());
    assert_eq!(m.filter.kind.as_deref(), Some("pdo"));
    assert!(m.status.as_deref().unwrap().contains("`pdoxyz`"), "{:?}", m.status);
}

/// A plotted value holds until the next one came (steps, not lines between values), the last
/// one until now, the one before the window from the window's start.
#[test]
fn a_plotted_value_holds_until_the_next() {
    let points = std::collections::VecDeque::from([(0.5, 1.0), (1.0, 10.0), (2.0, 20.0)]);
    assert_eq!(
        view::held(&points, 0.8, 3.0, 2.0),
        [(0.8, 2.0), (1.0, 2.0), (1.0, 20.0), (2.0, 20.0), (2.0, 40.0), (3.0, 40.0)]
    );
    assert_eq!(view::held(&points, 5.0, 6.0, 1.0), [(5.0, 20.0), (6.0, 20.0)]);
    assert_eq!(view::held(&std::collections::VecDeque::new(), 0.0, 1.0, 1.0), []);
}

/// Another master's SDO request to a node (top's own are not among the frames) holds top's polls
/// of it for [`YIELD`](super::model::YIELD), said once among the events.
#[test]
fn polls_wait_while_another_master_talks_to_the_node() {
    let ms = Duration::from_millis;
    let devices = BTreeMap::from([(2, device("camozzi-drvi.eds"))]);
    let mut m = Model::new("mem://x");
    m.on_frame(ms(0), 0x702, false, &[0x05], &devices);
    m.on_frame(ms(100), 0x702, false, &[0x05], &devices);
    assert_eq!(m.polls(ms(100), &devices).len(), 1, "a heard drive is polled");
    m.poll_done(2, &devices);
    m.on_frame(ms(150), 0x602, false, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0], &devices);
    m.on_frame(ms(160), 0x602, false, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0], &devices);
    assert_eq!(m.polls(ms(400), &devices), []);
    let said: Vec<_> = m.events.iter().filter(|(_, e)| e.contains("another master")).collect();
    assert_eq!(said.len(), 1, "{:?}", m.events);
    assert_eq!(m.polls(ms(2159), &devices), []);
    assert_eq!(m.polls(ms(2160), &devices).len(), 1, "polled again once the other master is quiet");
}

/// Thinned to four points a column: each column's first, lowest, highest and last, in time
/// order; few points are kept as they are.
#[test]
fn a_plot_keeps_four_points_a_column() {
    let points: Vec<(f64, f64)> = (0..100).map(|i| (f64::from(i) / 10.0, f64::from((i * 37) % 11))).collect();
    let thinned = view::thin(&points, 0.0, 10.0, 5);
    assert!(thinned.len() <= 20, "{thinned:?}");
    assert!(thinned.windows(2).all(|w| w[0].0 < w[1].0), "in time order");
    for c in 0..5 {
        let run: Vec<_> = points.iter().filter(|p| (p.0 / 2.0) as usize == c).collect();
        let kept: Vec<_> = thinned.iter().filter(|p| (p.0 / 2.0) as usize == c).collect();
        assert_eq!(kept.first(), run.first());
        assert_eq!(kept.last(), run.last());
        let max = |v: &[&(f64, f64)]| v.iter().map(|p| p.1).fold(f64::MIN, f64::max);
        let min = |v: &[&(f64, f64)]| v.iter().map(|p| p.1).fold(f64::MAX, f64::min);
        assert_eq!((min(&kept), max(&kept)), (min(&run), max(&run)));
    }
    assert_eq!(view::thin(&points[..10], 0.0, 10.0, 5), &points[..10]);
}

/// A series keeps four points a 40 ms bucket (its first, lowest, highest and last value), so
/// that 30 s fit whatever the rate and a brief spike stays.
#[test]
fn a_series_keeps_four_points_a_bucket() {
    let devices = BTreeMap::from([(2, device("camozzi-drvi.eds"))]);
    let mut m = Model::new("mem://x");
    // The DRVI's TPDO1 (statusword) every millisecond for 40 s.
    for ms in 0..40_000u64 {
        let v = (ms % 7) as u8;
        m.on_frame(Duration::from_millis(ms), 0x182, false, &[v, 0], &devices);
    }
    let s = &m.nodes[&2].series[&(0x6041, 0)];
    assert_eq!(s.points.len(), super::model::KEEP_POINTS);
    assert!(s.points.front().unwrap().0 <= 10.0, "the last 30 s kept: {:?}", s.points.front());
    assert_eq!(*s.points.back().unwrap(), (39.999, f64::from((39_999 % 7) as u8)));
    // The last bucket (39.960..40.000 s): first 39.960 (value 4), lowest 0, highest 6, last.
    let last: Vec<_> = s.points.iter().rev().take(4).rev().copied().collect();
    assert_eq!(last.first(), Some(&(39.96, 4.0)));
    assert_eq!(last.iter().map(|p| p.1).fold(f64::MAX, f64::min), 0.0);
    assert_eq!(last.iter().map(|p| p.1).fold(f64::MIN, f64::max), 6.0);
    assert!(last.windows(2).all(|w| w[0].0 < w[1].0), "{last:?}");
}

/// Units that do not fit the terminal's height are said, not dropped silently; a tiny terminal
/// draws without a panic.
#[test]
fn a_plot_says_which_units_do_not_fit() {
    let no_devices = BTreeMap::new();
    let mut m = Model::new("mem://x");
    m.on_frame(Duration::ZERO, 0x702, false, &[0x05], &no_devices);
    let row = m.nodes.get_mut(&2).unwrap();
    row.watched = vec![
        (0x1017, 0, eds::DataType::Unsigned16, "heartbeat".into()),
        (0x1018, 1, eds::DataType::Unsigned32, "vendor".into()),
        (0x1000, 0, eds::DataType::Unsigned32, "device type".into()),
    ];
    for ms in [100, 200, 300] {
        for (index, sub) in [(0x1017, 0), (0x1018, 1), (0x1000, 0)] {
            m.on_polled(Duration::from_millis(ms), 2, index, sub, Some(&[ms as u8, 0, 0, 0]));
        }
    }
    let shown = vec![(2, 0x1017, 0), (2, 0x1018, 1), (2, 0x1000, 0)];
    m.plot = Some(super::model::Plot { pick: shown[0], shown });
    let screen = |width, height| {
        let mut t = Terminal::new(TestBackend::new(width, height)).unwrap();
        t.draw(|f| view::draw(f, &m, Duration::from_millis(400))).unwrap();
        let buf = t.backend().buffer().clone();
        (0..buf.area.height)
            .map(|y| (0..buf.area.width).map(|x| buf[(x, y)].symbol()).collect::<String>())
            .collect::<Vec<_>>()
            .join("\n")
    };
    let big = screen(80, 24);
    assert!(big.contains("[raw] ⣿ 2 heartbeat 44") && big.contains("2 device type 44"), "{big}");
    assert!(!big.contains("more units"), "{big}");
    let small = screen(80, 16);
    assert!(small.contains("2 series in 2 more units: a taller terminal shows them"), "{small}");
    for (w, h) in [(80, 8), (20, 5), (1, 1)] {
        screen(w, h);
    }
}
