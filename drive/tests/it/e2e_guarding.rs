//! Node guarding end to end: `drive-sim run` serving a DRVI on its hub, a master on the
//! socketcand protocol sending remote frames (`sendrtr`, which python-can's socketcand
//! interface cannot express) through the transport's own client.
//!
//! What depends on time (no EMCY while guarded, the EMCY at guard time × life time factor after
//! the last request) is checked on the virtual clock, in process, where it is exact however
//! loaded the machine is; over TCP the tests check the frames and their order only, with
//! waits that bound a missing answer (a timeout), never a margin a slow machine can miss.

use std::time::{Duration, Instant};

use crate::support::Master;
use drive::drives::DeviceApps;
use drive::node::{DeviceKind, NodeConfig, Sim};
use od_bus::{CanFrame, Endpoint, SocketcandClient};

use crate::drive_sim::{DriveSim, next_with_id};

const WAIT: Duration = Duration::from_secs(5);

/// Sends a guard request and returns the reply. A boot-up message (one byte 0x00, same CAN-ID)
/// may still be on its way when a test starts, since the device boots while the client connects:
/// it is skipped, as a guard reply never carries the initialisation state.
fn guard(bus: &mut SocketcandClient) -> Option<Vec<u8>> {
    bus.send(CanFrame::remote(0x702, false, 1).unwrap()).unwrap();
    let deadline = Instant::now() + WAIT;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let reply = next_with_id(bus, 0x702, left)?.data().to_vec();
        if reply != [0x00] {
            return Some(reply);
        }
    }
}

fn sdo_write(bus: &mut SocketcandClient, data: [u8; 8]) {
    bus.send(CanFrame::standard(0x602, &data).unwrap()).unwrap();
    let reply = next_with_id(bus, 0x582, WAIT).expect("SDO response");
    assert_eq!(reply.data()[0], 0x60, "{reply}");
}

fn master() -> (DriveSim, SocketcandClient) {
    let sim = DriveSim::start(&["run", "--device", "drvi", "--node-id", "2", "--listen", "127.0.0.1:0"]);
    let bus = SocketcandClient::connect(sim.addr, "can0").unwrap();
    (sim, bus)
}

#[test]
fn guarding_replies_carry_the_state_and_a_toggling_bit() {
    let (_sim, mut bus) = master();
    assert_eq!(guard(&mut bus), Some(vec![0x7F]));
    assert_eq!(guard(&mut bus), Some(vec![0xFF]));
    bus.send(CanFrame::standard(0x000, &[0x01, 0x02]).unwrap()).unwrap(); // start node 2
    assert_eq!(guard(&mut bus), Some(vec![0x05]));
    assert_eq!(guard(&mut bus), Some(vec![0x85]));
    bus.send(CanFrame::standard(0x000, &[0x02, 0x02]).unwrap()).unwrap(); // stop
    assert_eq!(guard(&mut bus), Some(vec![0x04]));
    // Reset communication restarts the toggle bit at 0 (after the boot-up message).
    bus.send(CanFrame::standard(0x000, &[0x82, 0x02]).unwrap()).unwrap();
    assert_eq!(next_with_id(&mut bus, 0x702, WAIT).map(|f| f.data().to_vec()), Some(vec![0x00]));
    assert_eq!(guard(&mut bus), Some(vec![0x7F]));
}

/// Over TCP: the drive-sim binary reports a master that stops guarding with EMCY 8130h
/// ("life guard error"), resets its communication (boot-up), answers guarding again, and latches the loss until a fault reset,
/// which sends the error reset EMCY. The timing is the virtual-clock test's below: here the
/// master guards once (which starts life guarding) and waits for the EMCY with a timeout.
#[test]
fn a_master_that_stops_guarding_is_reported_by_emcy() {
    let (_sim, mut bus) = master();
    // Guard time 100 ms, life time factor 2: the master is lost after 200 ms of silence.
    sdo_write(&mut bus, [0x2B, 0x0C, 0x10, 0x00, 100, 0, 0, 0]);
    sdo_write(&mut bus, [0x2F, 0x0D, 0x10, 0x00, 2, 0, 0, 0]);
    assert!(guard(&mut bus).is_some());
    let emcy = next_with_id(&mut bus, 0x082, WAIT).expect("EMCY for the lost master");
    assert_eq!(emcy.data(), [0x30, 0x81, 0x11, 0, 0, 0, 0, 0]);
    // The loss resets the communication (DRVI 6.3.2.12): its boot-up message follows the EMCY.
    // A guard request sent before it may be lost in the reset, as on a real bus, so the master
    // waits for it: that order, not a sleep, is what makes the next request safe.
    assert_eq!(next_with_id(&mut bus, 0x702, WAIT).map(|f| f.data().to_vec()), Some(vec![0x00]), "boot-up");
    // Guarding resumes and is answered; the DRVI latches the loss as its "fieldbus
    // disconnection" error (Fault) until a fault reset, which sends the error reset EMCY.
    assert!(guard(&mut bus).is_some());
    assert!(next_with_id(&mut bus, 0x082, Duration::from_millis(150)).is_none(), "latched, no reset yet");
    sdo_write(&mut bus, [0x2B, 0x40, 0x60, 0x00, 0x80, 0, 0, 0]); // controlword: fault reset
    assert_eq!(next_with_id(&mut bus, 0x082, WAIT).unwrap().data(), [0; 8]);
}

/// A guard request on the virtual clock; returns the reply (boot-up messages skipped).
fn guard_virtual(m: &mut Master) -> Option<Vec<u8>> {
    m.take_id(0x702);
    m.send(CanFrame::remote(0x702, false, 1).unwrap());
    m.advance(1000);
    m.take_id(0x702).into_iter().map(|s| s.frame.data().to_vec()).find(|d| d != &[0x00])
}

/// The same DRVI in process, on the virtual clock: guarded every 50 ms it stays silent; the
/// EMCY comes guard time × life time factor (100 ms × 2) after the last request, within the
/// node's 1 ms poll, not before; the loss latches until a fault reset.
#[test]
fn a_master_that_stops_guarding_is_reported_by_emcy_at_the_life_time() {
    let mut sim = Sim::new();
    sim.add(
        DeviceKind::Drvi.build(&NodeConfig { node_id: Some(2), ..Default::default() }, &DeviceApps::new()).unwrap(),
    );
    let mut m = Master::new(sim);
    m.advance(1000);
    m.write_u16(2, 0x100C, 0, 100).unwrap();
    m.write_u8(2, 0x100D, 0, 2).unwrap();
    m.take_seen();
    let mut last = 0;
    for _ in 0..5 {
        last = m.now();
        assert!(guard_virtual(&mut m).is_some());
        m.advance(49_000);
    }
    assert!(m.take_id(0x082).is_empty(), "no EMCY while guarded");
    assert!(m.wait_until(1_000_000, 1000, |m| m.seen().any(|s| s.frame.id() == 0x082)), "EMCY for the lost master");
    let emcy = m.take_id(0x082);
    assert_eq!(emcy[0].frame.data(), [0x30, 0x81, 0x11, 0, 0, 0, 0, 0]);
    let after = emcy[0].at - last;
    assert!((200_000..=201_000).contains(&after), "EMCY {after} µs after the last guard request");
    assert!(guard_virtual(&mut m).is_some());
    m.advance(150_000);
    assert!(m.take_id(0x082).is_empty(), "latched, no reset yet");
    m.write_u16(2, 0x6040, 0, 0x80).unwrap(); // controlword: fault reset
    m.advance(1000);
    assert_eq!(m.take_id(0x082).first().map(|s| s.frame.data().to_vec()), Some(vec![0; 8]));
}

#[test]
fn with_a_heartbeat_configured_guarding_requests_are_not_answered() {
    let (_sim, mut bus) = master();
    sdo_write(&mut bus, [0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0]); // heartbeat 1000 ms
    bus.send(CanFrame::remote(0x702, false, 1).unwrap()).unwrap();
    // Only the heartbeat's own messages (state 7F) may come, at its period; no reply now.
    let reply = next_with_id(&mut bus, 0x702, Duration::from_millis(300));
    assert!(reply.is_none(), "{reply:?}");
    sdo_write(&mut bus, [0x2B, 0x17, 0x10, 0x00, 0, 0, 0, 0]);
    std::thread::sleep(Duration::from_millis(20));
    while bus.try_recv().unwrap().is_some() {}
    assert!(guard(&mut bus).is_some());
}
