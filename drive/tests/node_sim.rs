//! The node runner on the in-memory bus in virtual time, frame for frame: generated
//! dictionaries served by od-runtime through `drive::node`, the default application's
//! reactions, and the application hooks.

use drive::node::{
    Ctx, DefaultApp, DefaultApps, DeviceKind, DriveApp, Node, NodeConfig, NodeStorage, Sim, WriteRequest,
};
use od_bus::{CanFrame, Endpoint, LocalEndpoint};
use od_runtime::cia402::State;
use od_runtime::od::{AbortCode, ObjectDictionary};
use od_runtime::{Event, Micros, NmtState, NodeId, WriteSource};

fn frame(text: &str) -> CanFrame {
    text.parse().unwrap_or_else(|e| panic!("{text}: {e}"))
}

fn drain(ep: &mut LocalEndpoint) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(f) = ep.try_recv().unwrap() {
        out.push(f.to_string());
    }
    out
}

fn config(id: u8) -> NodeConfig {
    NodeConfig { node_id: Some(id), ..NodeConfig::default() }
}

/// A simulation with the given devices and a master endpoint, past the boot-up messages.
fn sim_with(devices: &[(DeviceKind, u8)]) -> (Sim, LocalEndpoint) {
    let mut sim = Sim::new();
    let mut master = sim.endpoint();
    for &(kind, id) in devices {
        sim.add(kind.build(&config(id), &DefaultApps).unwrap());
    }
    sim.advance(0);
    let bootups: Vec<String> = devices.iter().map(|(_, id)| format!("7{id:02X}#00")).collect();
    assert_eq!(drain(&mut master), bootups);
    (sim, master)
}

/// Sends `request` and returns every frame the nodes sent in reply, at the same instant.
fn exchange(sim: &mut Sim, master: &mut LocalEndpoint, request: &str) -> Vec<String> {
    master.send(frame(request)).unwrap();
    sim.advance(0);
    drain(master)
}

/// Expedited SDO download of up to 4 bytes, expecting success.
fn sdo_write(sim: &mut Sim, master: &mut LocalEndpoint, node: u8, index: u16, sub: u8, data: &[u8]) {
    assert!((1..=4).contains(&data.len()));
    let cmd = 0x23 | ((4 - data.len() as u8) << 2);
    let mut bytes = [cmd, index as u8, (index >> 8) as u8, sub, 0, 0, 0, 0];
    bytes[4..4 + data.len()].copy_from_slice(data);
    let request = CanFrame::standard(0x600 + u32::from(node), &bytes).unwrap();
    master.send(request).unwrap();
    sim.advance(0);
    let expected =
        format!("{:03X}#60{:02X}{:02X}{:02X}00000000", 0x580 + u32::from(node), index as u8, index >> 8, sub);
    assert_eq!(drain(master), [expected], "download {index:04X}sub{sub}");
}

/// Expedited SDO upload, returning the value bytes.
fn sdo_read(sim: &mut Sim, master: &mut LocalEndpoint, node: u8, index: u16, sub: u8) -> Vec<u8> {
    let request =
        CanFrame::standard(0x600 + u32::from(node), &[0x40, index as u8, (index >> 8) as u8, sub, 0, 0, 0, 0]).unwrap();
    master.send(request).unwrap();
    sim.advance(0);
    let reply = master.try_recv().unwrap().expect("an SDO response");
    assert_eq!(reply.id(), 0x580 + u32::from(node));
    let d = reply.data();
    assert_eq!(d[0] & 0xF3, 0x43, "expedited upload response with size, got {reply}");
    let n = 4 - usize::from((d[0] >> 2) & 3);
    d[4..4 + n].to_vec()
}

fn statusword(sim: &mut Sim, master: &mut LocalEndpoint, node: u8) -> u16 {
    let b = sdo_read(sim, master, node, 0x6041, 0);
    u16::from_le_bytes([b[0], b[1]])
}

#[test]
fn three_devices_boot_start_and_send_their_default_tpdos() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]);
    // NMT start all: every valid TPDO of type 255 goes out once on entering Operational, with
    // the statusword of Switch on disabled + remote (0x0240).
    assert_eq!(
        exchange(&mut sim, &mut master, "000#0100"),
        ["182#4002", "183#4002", "184#4002", "284#400200", "384#400200000000", "484#400200000000"]
    );
    for i in 0..3 {
        assert_eq!(sim.node(i).nmt_state(), NmtState::Operational);
    }
    // The DRVI's TPDO1 has a 100 ms event timer (1800h sub 5 = 100): it repeats exactly then.
    sim.advance(99_999);
    assert_eq!(drain(&mut master), Vec::<String>::new());
    sim.advance(1);
    assert_eq!(drain(&mut master), ["182#4002"]);
    sim.advance(100_000);
    assert_eq!(drain(&mut master), ["182#4002"]);
    // Stop node 3 only; reset node 2: its boot-up follows at once.
    assert_eq!(exchange(&mut sim, &mut master, "000#0203"), Vec::<String>::new());
    assert_eq!(sim.node(1).nmt_state(), NmtState::Stopped);
    assert_eq!(exchange(&mut sim, &mut master, "000#8102"), ["702#00"]);
    assert_eq!(sim.node(0).nmt_state(), NmtState::PreOperational);
    assert_eq!(sim.node(2).nmt_state(), NmtState::Operational);
}

#[test]
fn sdo_requests_get_the_responses_the_protocol_defines() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Drvi, 2)]);
    // Upload 1000h: DRVI device type 0xFF7A0192.
    assert_eq!(exchange(&mut sim, &mut master, "602#4000100000000000"), ["582#4300100092017AFF"]);
    // Download 6083h (profile acceleration) = 1000, read back.
    assert_eq!(exchange(&mut sim, &mut master, "602#23836000E8030000"), ["582#6083600000000000"]);
    assert_eq!(sdo_read(&mut sim, &mut master, 2, 0x6083, 0), [0xE8, 0x03, 0, 0]);
    // Write to a read-only object: abort 0x06010002.
    assert_eq!(exchange(&mut sim, &mut master, "602#2300100001000000"), ["582#8000100002000106"]);
    // An object the DRVI does not have: abort 0x06020000.
    assert_eq!(exchange(&mut sim, &mut master, "602#4000500000000000"), ["582#8000500000000206"]);
    // Another node's SDO is not answered.
    assert_eq!(exchange(&mut sim, &mut master, "603#4000100000000000"), Vec::<String>::new());
}

#[test]
fn the_default_app_completes_quick_stop_and_fault_reactions() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Drvi, 2)]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0240);
    // Shutdown: Ready to switch on (od-runtime sets bit 4, voltage enabled, in the powered
    // states).
    sdo_write(&mut sim, &mut master, 2, 0x6040, 0, &[0x06, 0x00]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0231);
    sdo_write(&mut sim, &mut master, 2, 0x6040, 0, &[0x0F, 0x00]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0237);
    // Quick stop (605Ah absent: option 2): transition 11, then the default app completes the
    // quick stop at once: transition 12 to Switch on disabled.
    sdo_write(&mut sim, &mut master, 2, 0x6040, 0, &[0x02, 0x00]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0240);

    // A fault: EMCY 2310h with 1001h = current + generic, Fault reaction active, then Fault.
    let now = sim.now();
    type Drvi = Node<generated::drvi::Dictionary, Box<dyn DriveApp<generated::drvi::Dictionary> + Send>>;
    let node = sim.downcast_mut::<Drvi>(0).expect("a DRVI node");
    node.with_app(now, |_, ctx| ctx.set_fault(0x2310)).unwrap();
    assert_eq!(node.device().cia402_state(), Some(State::Fault));
    sim.advance(0);
    assert_eq!(drain(&mut master), ["082#1023030000000000"]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0208);
    assert_eq!(sdo_read(&mut sim, &mut master, 2, 0x603F, 0), [0x10, 0x23]);
    assert_eq!(sdo_read(&mut sim, &mut master, 2, 0x1001, 0), [0x03]);
    // Fault reset (rising edge of bit 7): error reset EMCY, Switch on disabled.
    master.send(frame("602#2B40600080000000")).unwrap();
    sim.advance(0);
    assert_eq!(drain(&mut master), ["582#6040600000000000", "082#0000000000000000"]);
    assert_eq!(statusword(&mut sim, &mut master, 2), 0x0240);
}

#[test]
fn heartbeat_consumer_loss_and_return_are_reported_by_emcy() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Akd, 4)]);
    // 1016h sub 1: monitor node 1 with 100 ms.
    sdo_write(&mut sim, &mut master, 4, 0x1016, 1, &[0x64, 0x00, 0x01, 0x00]);
    // Not monitored before the first heartbeat arrives.
    sim.advance(500_000);
    assert_eq!(drain(&mut master), Vec::<String>::new());
    for _ in 0..5 {
        master.send(frame("701#05")).unwrap();
        sim.advance(50_000);
    }
    assert_eq!(drain(&mut master), Vec::<String>::new());
    // Silence: 100 ms after the last heartbeat, EMCY 8130h, 1001h = communication + generic,
    // the lost node's id in the first manufacturer byte.
    sim.advance(49_000);
    assert_eq!(drain(&mut master), Vec::<String>::new());
    sim.advance(1_000);
    assert_eq!(drain(&mut master), ["084#3081110100000000"]);
    assert_eq!(sdo_read(&mut sim, &mut master, 4, 0x1001, 0), [0x11]);
    // Reported once only.
    sim.advance(300_000);
    assert_eq!(drain(&mut master), Vec::<String>::new());
    // The heartbeat returns: error reset EMCY, 1001h clear.
    assert_eq!(exchange(&mut sim, &mut master, "701#05"), ["084#0000000000000000"]);
    assert_eq!(sdo_read(&mut sim, &mut master, 4, 0x1001, 0), [0x00]);
}

#[test]
fn node_guarding_replies_toggle_and_a_lost_master_is_reported() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Drvi, 2)]);
    // Guard time 100 ms, life time factor 3.
    sdo_write(&mut sim, &mut master, 2, 0x100C, 0, &[100, 0]);
    sdo_write(&mut sim, &mut master, 2, 0x100D, 0, &[3]);
    assert_eq!(exchange(&mut sim, &mut master, "702#R1"), ["702#7F"]);
    sim.advance(100_000);
    assert_eq!(exchange(&mut sim, &mut master, "702#R1"), ["702#FF"]);
    assert_eq!(exchange(&mut sim, &mut master, "000#0102"), ["182#4002"]);
    sim.advance(100_000);
    assert_eq!(exchange(&mut sim, &mut master, "702#R1"), ["182#4002", "702#05"]);
    // No request for 300 ms (guard time × life time factor): EMCY 8130h (after the TPDO of
    // the same millisecond, as the loss is found by that poll).
    sim.advance(299_000);
    assert_eq!(drain(&mut master), ["182#4002", "182#4002"]);
    sim.advance(1_000);
    assert_eq!(drain(&mut master), ["182#4002", "082#3081110000000000"]);
    // Guarding resumes: error reset EMCY, then the reply (toggle bit set again).
    assert_eq!(exchange(&mut sim, &mut master, "702#R1"), ["082#0000000000000000", "702#85"]);
}

#[test]
fn an_rpdo_shorter_than_its_mapping_raises_emcy_8210() {
    let (mut sim, mut master) = sim_with(&[(DeviceKind::Drvi, 2)]);
    assert_eq!(exchange(&mut sim, &mut master, "000#0102"), ["182#4002"]);
    // RPDO1 maps the controlword (2 bytes); one byte is a PDO length error.
    assert_eq!(exchange(&mut sim, &mut master, "202#06"), ["082#1082110000000000"]);
    // A complete one is applied: Ready to switch on, statusword in TPDO1 (type 255: on change).
    assert_eq!(exchange(&mut sim, &mut master, "202#0600"), ["182#3102"]);
}

/// What the recording application saw.
#[derive(Default)]
struct Recorder {
    base: DefaultApp,
    events: Vec<(Micros, Event)>,
    ticks: Vec<Micros>,
    written_values: Vec<(u16, u8, u64)>,
    refuse_mode: bool,
    period: Micros,
}

impl<OD: ObjectDictionary> DriveApp<OD> for Recorder {
    fn on_write(&mut self, _od: &OD, w: &WriteRequest<'_>) -> Result<(), AbortCode> {
        if self.refuse_mode && w.index == 0x6060 && w.as_u64() != 1 {
            return Err(AbortCode::INVALID_VALUE);
        }
        if w.index == 0x6040 && matches!(w.source, WriteSource::Rpdo(_)) && w.as_u64() == 0xFFFF {
            return Err(AbortCode::INVALID_VALUE);
        }
        Ok(())
    }

    fn on_event(&mut self, ctx: &mut Ctx<'_, OD>, event: Event) {
        self.events.push((ctx.now(), event));
        if let Event::Written { index, sub, .. } = event {
            // The value is already in the dictionary.
            self.written_values.push((index, sub, ctx.read_i64(index, sub).unwrap_or(-1) as u64));
        }
        self.base.on_event(ctx, event);
    }

    fn tick(&mut self, ctx: &mut Ctx<'_, OD>) {
        self.ticks.push(ctx.now());
        if self.ticks.len() == 3 {
            // A local write through the runtime: the CiA 402 machine runs (transition 2).
            ctx.write(0x6040, 0, &[0x06, 0x00]).unwrap();
        }
    }

    fn tick_period(&self) -> Micros {
        self.period
    }
}

type RecNode = Node<generated::drvi::Dictionary, Recorder>;

fn recorder_sim(app: Recorder) -> (Sim, LocalEndpoint) {
    let mut sim = Sim::new();
    let mut master = sim.endpoint();
    let node = Node::new(generated::drvi::Dictionary::new(2), app, NodeStorage::memory(), NodeId::new(2).unwrap());
    sim.add(Box::new(node));
    sim.advance(0);
    assert_eq!(drain(&mut master), ["702#00"]);
    (sim, master)
}

#[test]
fn the_application_sees_writes_before_and_events_after_the_dictionary() {
    let (mut sim, mut master) = recorder_sim(Recorder { refuse_mode: true, ..Recorder::default() });
    // The veto: mode 3 refused with the application's code, mode 1 accepted.
    assert_eq!(exchange(&mut sim, &mut master, "602#2F60600003000000"), ["582#8060600030000906"]);
    assert_eq!(exchange(&mut sim, &mut master, "602#2F60600001000000"), ["582#6060600000000000"]);
    let app = sim.downcast::<RecNode>(0).unwrap().app().unwrap();
    assert_eq!(app.written_values, [(0x6060, 0, 1)]);
    // The start-up events came first: reset node, CiA 402 transition 1, NMT to pre-operational.
    let kinds: Vec<String> = app.events.iter().map(|(_, e)| format!("{e:?}")).collect();
    assert!(kinds[0].starts_with("Reset(Node)"), "{kinds:?}");
    assert!(kinds[1].contains("number: 1"), "{kinds:?}");
    assert!(kinds[2].starts_with("Nmt"), "{kinds:?}");

    // RPDO writes carry their source; the veto skips the entry.
    exchange(&mut sim, &mut master, "000#0102");
    exchange(&mut sim, &mut master, "202#FFFF");
    exchange(&mut sim, &mut master, "202#0600");
    let app = sim.downcast::<RecNode>(0).unwrap().app().unwrap();
    let rpdo_writes: Vec<_> = app
        .events
        .iter()
        .filter_map(|(_, e)| match e {
            Event::Written { index: 0x6040, source, .. } => Some(*source),
            _ => None,
        })
        .collect();
    assert_eq!(rpdo_writes, [WriteSource::Rpdo(0)]);
    assert_eq!(sim.downcast::<RecNode>(0).unwrap().od().controlword(), 0x0006);
}

#[test]
fn ticks_run_at_their_period_and_may_use_the_device() {
    let (mut sim, _master) = recorder_sim(Recorder { period: 2_500, ..Recorder::default() });
    sim.advance(10_000);
    let node = sim.downcast::<RecNode>(0).unwrap();
    assert_eq!(node.app().unwrap().ticks, [0, 2_500, 5_000, 7_500, 10_000]);
    // The third tick wrote the controlword locally: transition 2 happened, with its event.
    assert_eq!(node.device().cia402_state(), Some(State::ReadyToSwitchOn));
    let local = node
        .app()
        .unwrap()
        .events
        .iter()
        .any(|(t, e)| *t == 5_000 && matches!(e, Event::Written { index: 0x6040, source: WriteSource::Local, .. }));
    assert!(local);
}

#[test]
fn a_node_that_falls_behind_skips_ticks() {
    let mut node: RecNode = Node::new(
        generated::drvi::Dictionary::new(2),
        Recorder { period: 1_000, ..Recorder::default() },
        NodeStorage::memory(),
        NodeId::new(2).unwrap(),
    );
    let mut sent = Vec::new();
    node.poll(0, &mut |f| sent.push(f));
    assert_eq!(node.next_deadline(), 1_000);
    node.poll(10_500, &mut |f| sent.push(f));
    assert_eq!(node.next_deadline(), 11_500);
    node.poll(11_500, &mut |f| sent.push(f));
    assert_eq!(node.app().unwrap().ticks, [0, 10_500, 11_500]);
    assert_eq!(node.ticks(), 3);
    assert_eq!(node.dropped_events(), 0);
}

#[test]
fn without_ticks_the_deadline_is_the_timer_poll() {
    let mut node = Node::new(
        generated::akd::Dictionary::new(9),
        DefaultApp::new(),
        NodeStorage::memory(),
        NodeId::new(9).unwrap(),
    );
    assert_eq!(node.next_deadline(), 0);
    let mut sent = Vec::new();
    node.poll(5, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent, ["709#00"]);
    assert_eq!(node.next_deadline(), 1_005);
    // Extended frames are not CANopen's: ignored.
    node.handle(&CanFrame::extended(0x609, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap(), 6);
    node.poll(6, &mut |f| sent.push(f.to_string()));
    assert_eq!(sent, ["709#00"]);
}
