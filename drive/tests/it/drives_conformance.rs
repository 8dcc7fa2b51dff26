//! The findings of an outside conformance run (issue 17): each test drives a simulated drive
//! through real frames on the in-memory bus and the virtual clock, as a master would.

use crate::manual_frames;

use crate::support::{Master, abort};
use drive::drives::akd::{self, Akd};
use drive::drives::{Cia402App, DeviceApps};
use drive::node::{DeviceKind, Node, NodeConfig, NodeStorage, Sim};
use manual_frames::{got, sdo};
use od_bus::CanFrame;
use od_runtime::NodeId;

type AkdNode = Node<generated::akd::Dictionary, Cia402App<generated::akd::Dictionary, Akd>>;

/// One drive of `kind` with node id `id`, booted and started (operational).
fn started(kind: DeviceKind, id: u8) -> Master {
    let mut sim = Sim::new();
    sim.add(kind.build(&NodeConfig { node_id: Some(id), ..Default::default() }, &DeviceApps::new()).unwrap());
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(id);
    m.advance(1000);
    m.take_seen();
    m
}

/// An AKD with node id `id` built as [`akd::app`] builds it, started, reachable by `akd_node`.
fn akd(id: u8) -> Master {
    let mut sim = Sim::new();
    let dict = generated::akd::Dictionary::new(id);
    sim.add(Box::new(Node::new(dict, akd::app(), NodeStorage::memory(), NodeId::new(id).unwrap())));
    let mut m = Master::new(sim);
    m.advance(1000);
    m.nmt_start(id);
    m.advance(1000);
    m.take_seen();
    m
}

fn akd_node_mut(m: &mut Master) -> &mut AkdNode {
    m.sim_mut().downcast_mut::<AkdNode>(0).unwrap()
}

fn akd_node(m: &Master) -> &AkdNode {
    m.sim().downcast::<AkdNode>(0).unwrap()
}

// ---- AKD --------------------------------------------------------------------------------------

/// Finding 3: 6099h reads its manual default (60 rpm) and a homing with the defaults ends.
#[test]
fn akd_homing_with_the_default_speeds_completes() {
    let mut m = akd(3);
    m.switch_on(3).unwrap();
    m.set_mode(3, 6).unwrap();
    m.write(3, 0x6098, 0, &[12]).unwrap();
    m.controlword(3, 0x1F).unwrap();
    assert_eq!(m.read_u32(3, 0x6099, 1).unwrap(), 1, "60 rpm: one motor turn per second");
    let speed = akd_node(&m).app().unwrap().drive().axis().config().homing.search_speed;
    assert_eq!(i64::from(speed), akd::COUNTS_PER_TURN, "the drive homes at the speed it reports");
    // Method 12 on the preset machine: to the negative limit switch, back to the reference
    // switch, onto the index: about 5.8 s at 60 rpm.
    let sw = m.wait_statusword(3, 0x3400, 0x1400, 8_000_000, 1000);
    assert!(sw.is_some(), "statusword {:04X}", m.statusword(3).unwrap());
}
/// Finding 4: 6098h reads 0 (the manual's default, "no method assigned" in CiA 402) and 0 can be
/// written back; a homing started with it starts nothing.
#[test]
fn akd_homing_method_0_is_the_default_and_can_be_written_back() {
    let mut m = akd(3);
    assert_eq!(m.read_u8(3, 0x6098, 0).unwrap(), 0);
    m.write(3, 0x6098, 0, &[0]).unwrap();
    for reserved in [3u8, 36, 0x80] {
        assert_eq!(m.write(3, 0x6098, 0, &[reserved]).map_err(abort), Err(Some(0x0609_0030)), "{reserved}");
    }
    m.switch_on(3).unwrap();
    m.set_mode(3, 6).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.advance(500_000);
    let a = akd_node(&m).app().unwrap().drive().axis().status();
    assert_eq!(a.position_actual, 0, "nothing moved");
    assert!(!a.homed);
    assert_eq!(m.statusword(3).unwrap() & 0x3400, 0, "homing not started (AKD: bit 10 only once homed)");
}

/// Finding 10: a download of the wrong size is a length error whatever its value, also where the
/// drive would refuse the value (608Fh sub 1 = 0 divides by zero).
#[test]
fn a_length_error_wins_over_the_drives_value_check() {
    for kind in [DeviceKind::Akd, DeviceKind::Drvi, DeviceKind::Drcs] {
        let mut m = started(kind, 3);
        // AKD 608Fh sub 1, the Camozzi feed converter 2001h sub 2 (both refuse 0).
        let index = if kind == DeviceKind::Akd { "8F 60 01" } else { "01 20 02" };
        // Two bytes to an UNSIGNED32 / INTEGER32, value 0 and value 16.
        for data in ["00 00", "10 00"] {
            let answer = sdo(&mut m, &format!("603 2B {index} {data} 00 00"));
            assert_eq!(answer, format!("583 80 {index} 13 00 07 06"), "{kind:?} {data}");
        }
    }
}

/// Finding 11: the EMCY's error register has the communication bit for communication errors
/// only; a following error or a software limit is a device profile error (1001h bit 5).
#[test]
fn akd_error_register_bits_follow_the_error_class() {
    let table = drive::drives::error_table(DeviceKind::Akd);
    for (code, bits) in [(0x8130u16, 0x11u8), (0x8611, 0x21), (0x8580, 0x21), (0x8582, 0x21), (0x86A1, 0x21)] {
        assert_eq!(table.resolve(code, None).register_bits(), bits, "{code:04X}");
    }
    // On the bus: a following error's EMCY (running into the end stop of the preset machine at
    // 5 turns/s with a window of one turn; the limit switch before it taken away).
    let mut m = akd(3);
    akd_node_mut(&mut m).app_mut().unwrap().drive_mut().axis_mut().environment_mut().positive_limit = None;
    m.switch_on(3).unwrap();
    m.write_u32(3, 0x6065, 0, 1).unwrap();
    m.set_mode(3, 3).unwrap();
    m.write_i32(3, 0x60FF, 0, 5).unwrap();
    m.advance(2_000_000);
    let emcy = got(&mut m, 0x083);
    assert!(emcy.iter().any(|e| e.starts_with("083 11 86 21")), "{emcy:?}");
    assert_eq!(m.read_u8(3, 0x1001, 0).unwrap(), 0x21);
}

// ---- every drive --------------------------------------------------------------------------

/// The entries whose power-on value differs from the EDS default, for a drive built by `app`.
fn power_on_differences<OD, A>(od: OD, app: A, id: u8) -> Vec<String>
where
    OD: od_runtime::od::ObjectDictionary + Clone + Send + 'static,
    A: drive::node::DriveApp<OD> + Send + 'static,
{
    let fresh = od.clone();
    let mut sim = Sim::new();
    sim.add(Box::new(Node::new(od, app, NodeStorage::memory(), NodeId::new(id).unwrap())));
    sim.advance(20_000);
    let node = sim.downcast::<Node<OD, A>>(0).unwrap();
    let mut out = Vec::new();
    for e in fresh.entries() {
        let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
        let (Ok(n), Ok(k)) = (fresh.read(e.index, e.sub, &mut a), node.od().read(e.index, e.sub, &mut b)) else {
            continue;
        };
        if a[..n] != b[..k] {
            out.push(format!("{:04X}sub{}", e.index, e.sub));
        }
    }
    out
}

/// Finding 12: what a drive reports at power-on is its EDS default, except the values the
/// drive measures or computes (states, actual values, status registers).
#[test]
fn power_on_values_are_the_eds_defaults() {
    let drcs = power_on_differences(generated::drcs::Dictionary::new(3), drive::drives::drcs::app(), 3);
    let drvi = power_on_differences(generated::drvi::Dictionary::new(3), drive::drives::drvi::app(), 3);
    let akd = power_on_differences(generated::akd::Dictionary::new(3), akd::app(), 3);
    // Measured: the statusword (6041h), the DRCS's inputs (2002h: the enable input is on) and
    // brake (2005h: engaged without torque), the AKD's status register (1002h).
    assert_eq!(drcs, ["2002sub0", "2005sub0", "6041sub0"], "DRCS");
    assert_eq!(drvi, ["6041sub0"], "DRVI");
    assert_eq!(akd, ["1002sub0", "6041sub0"], "AKD");
}

// ---- the AKD's ASCII channel (issue 16, point 3) -------------------------------------------

/// Sends a WorkBench command through 2026h sub 1 (four characters per write) and reads the
/// answer from sub 2 until its end (`\n\r\n`).
fn ascii(m: &mut Master, id: u8, command: &str) -> String {
    let bytes = format!("{command}\r\n").into_bytes();
    for chunk in bytes.chunks(4) {
        m.write(id, 0x2026, 1, chunk).unwrap();
    }
    let mut answer = Vec::new();
    for _ in 0..16 {
        let piece = m.read(id, 0x2026, 2).unwrap();
        answer.extend_from_slice(&piece);
        if piece.is_empty() || answer.ends_with(b"\n\r\n") {
            break;
        }
    }
    String::from_utf8(answer).unwrap()
}

/// Numbers from the bus never wrap: a value beyond the parameter's type (or beyond any
/// number) is the drive's error text and leaves the parameter as it was.
#[test]
fn akd_ascii_values_out_of_range_are_refused_not_wrapped() {
    let mut m = akd(3);
    // VL.ARPF1 is 3406h sub 1, UNSIGNED32 at 1000:1.
    assert_eq!(ascii(&mut m, 3, "VL.ARPF1 7.5"), ">\n\r\n");
    assert_eq!(m.read_u32(3, 0x3406, 1).unwrap(), 7500);
    let out = ">Error: value out of range\n\r\n";
    for text in [
        "42535295865117307932921825928971026.437", // milli × 1000 wraps an i128 to 5
        "-1",                                      // -1000 into an UNSIGNED32
        "4294967.296",                             // one past the type
        &"9".repeat(60),
    ] {
        assert_eq!(ascii(&mut m, 3, &format!("VL.ARPF1 {text}")), out, "{text}");
        assert_eq!(m.read_u32(3, 0x3406, 1).unwrap(), 7500, "{text} changed nothing");
    }
    assert_eq!(ascii(&mut m, 3, "VL.ARPF1 4294967.295"), ">\n\r\n");
    assert_eq!(m.read_u32(3, 0x3406, 1).unwrap(), u32::MAX);
    // A signed parameter (MT.P, 607Ah INTEGER32 at 1:1 with the EDS limits ±2147483647)
    // takes its limits and no more.
    assert_eq!(ascii(&mut m, 3, "MT.P -2147483647"), ">\n\r\n");
    assert_eq!(m.read_i64(3, 0x607A, 0).unwrap(), -2_147_483_647);
    for text in ["-2147483648", "2147483648", "-99999999999"] {
        assert_eq!(ascii(&mut m, 3, &format!("MT.P {text}")), out, "{text}");
    }
    assert_eq!(m.read_i64(3, 0x607A, 0).unwrap(), -2_147_483_647);
}

/// The rule over many values: whatever number is written, the parameter either holds exactly
/// its value (× the bus factor, cut to thousandths) or is unchanged and the answer is an error.
#[test]
fn akd_ascii_writes_store_the_exact_value_or_nothing() {
    let mut m = akd(3);
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for i in 0..300 {
        let digits = (next() % 45) as usize + 1;
        let mut int: String = (0..digits).map(|_| char::from(b'0' + (next() % 10) as u8)).collect();
        if i % 3 == 0 {
            int.insert(0, '-');
        }
        let frac: String = (0..(next() % 5)).map(|_| char::from(b'0' + (next() % 10) as u8)).collect();
        let text = if frac.is_empty() { int.clone() } else { format!("{int}.{frac}") };
        let before = m.read_u32(3, 0x3406, 1).unwrap();
        let answer = ascii(&mut m, 3, &format!("VL.ARPF1 {text}"));
        let after = m.read_u32(3, 0x3406, 1).unwrap();
        // The exact value in thousandths, by decimal string arithmetic (no integer type).
        let neg = text.starts_with('-');
        let f3: String = frac.chars().chain("000".chars()).take(3).collect();
        let milli = format!("{}{f3}", int.trim_start_matches('-')).trim_start_matches('0').to_owned();
        let expected = if milli.is_empty() {
            Some(0u32)
        } else if neg || milli.len() > 10 {
            None
        } else {
            milli.parse::<u64>().ok().and_then(|v| u32::try_from(v).ok())
        };
        match expected {
            Some(v) => assert_eq!((answer.as_str(), after), (">\n\r\n", v), "{text}"),
            None => assert_eq!((answer.as_str(), after), (">Error: value out of range\n\r\n", before), "{text}"),
        }
    }
}

// ---- homing attained (DRVI, DRCS) -----------------------------------------------------------

/// Finding 1: homing method 37; the master switches to profile position the moment the
/// statusword says "homing attained" (bit 12 set, bit 10 clear: DRVI table 6.27), as
/// python-canopen's `homing()` returns then. The homing must be complete: 2004h = 1, the
/// position set, and a move accepted.
fn homing_attained_is_committed(kind: DeviceKind) {
    let mut m = started(kind, 3);
    m.switch_on(3).unwrap();
    m.write_i32(3, 0x607C, 0, 0).unwrap();
    m.set_mode(3, 6).unwrap();
    m.write(3, 0x6098, 0, &[37]).unwrap();
    m.controlword(3, 0x1F).unwrap();
    let mut caught = false;
    for _ in 0..2000 {
        let sw = m.statusword(3).unwrap();
        if sw & 0x1400 == 0x1000 {
            m.set_mode(3, 1).unwrap();
            caught = true;
            break;
        }
        assert_eq!(sw & 0x1400, 0, "{kind:?}: completed before attained was seen: {sw:04X}");
        m.advance(100);
    }
    assert!(caught, "{kind:?}: the statusword never showed homing attained");
    m.controlword(3, 0x0F).unwrap();
    m.advance(10_000);
    assert_eq!(m.read_u8(3, 0x2004, 0).unwrap(), 1, "{kind:?}: 2004h homing done");
    assert_eq!(m.read_i64(3, 0x6064, 0).unwrap(), 0, "{kind:?}: the home position");
    // A move is accepted (the DRCS refuses moves without a homing with FF13h).
    m.take_seen();
    m.write_u32(3, 0x6081, 0, 10).unwrap();
    m.write_u32(3, 0x6083, 0, 100).unwrap();
    m.write_u32(3, 0x6084, 0, 100).unwrap();
    m.write_i32(3, 0x607A, 0, 5).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.advance(5_000);
    m.controlword(3, 0x0F).unwrap();
    let emcy = got(&mut m, 0x083);
    assert!(emcy.is_empty(), "{kind:?}: {emcy:?}");
    assert!(m.wait_statusword(3, 0x0400, 0x0400, 5_000_000, 1000).is_some(), "{kind:?}: target reached");
    assert_eq!(m.read_i64(3, 0x6064, 0).unwrap(), 5, "{kind:?}");
}

#[test]
fn drcs_homing_attained_is_a_completed_homing() {
    homing_attained_is_committed(DeviceKind::Drcs);
}

#[test]
fn drvi_homing_attained_is_a_completed_homing() {
    homing_attained_is_committed(DeviceKind::Drvi);
}

/// Finding 6 (7.2.1.9): the answer of the ASCII channel is read four characters per expedited
/// upload; once read, sub 2 is empty until the next answer.
#[test]
fn akd_ascii_answers_are_read_four_characters_per_upload() {
    let mut m = akd(1);
    for (request, answer) in [
        ("601 23 26 20 01 44 52 56 2E", "581 60 26 20 01 00 00 00 00"),
        ("601 23 26 20 01 46 41 55 4C", "581 60 26 20 01 00 00 00 00"),
        ("601 23 26 20 01 54 53 0D 0A", "581 60 26 20 01 00 00 00 00"),
        ("601 40 26 20 02 00 00 00 00", "581 43 26 20 02 3E 4E 6F 20"),
        ("601 40 26 20 02 00 00 00 00", "581 43 26 20 02 66 61 75 6C"),
    ] {
        assert_eq!(sdo(&mut m, request), answer, "{request}");
    }
    assert_eq!(m.read(1, 0x2026, 2).unwrap(), b"ts a");
    assert_eq!(m.read(1, 0x2026, 2).unwrap(), b"ctiv");
    assert_eq!(m.read(1, 0x2026, 2).unwrap(), b"e\n\r\n");
    assert_eq!(m.read(1, 0x2026, 2).unwrap(), b"");
    // A longer answer than the entry's 32 characters is read whole, four at a time.
    akd_node_mut(&mut m).app_mut().unwrap().vendor_mut().conditions.heat_sink_c = 90.0;
    m.advance(2000);
    assert_eq!(ascii(&mut m, 1, "DRV.FAULTS"), ">235: Excess temperature, drive (heat sink)\n\r\n");
}

/// Finding 5 (6.6.2.1): 606Ch over SDO in user units, in a PDO in rpm (both at the object's
/// 1000:1 bus factor): at -1 turn/s, SDO -1000 (one user unit is one turn), PDO -60 000.
#[test]
fn akd_velocity_actual_is_rpm_in_a_pdo() {
    let mut m = akd(3);
    // TPDO2: 606Ch only, on every SYNC.
    let cob = m.read_u32(3, 0x1801, 1).unwrap();
    m.write_u32(3, 0x1801, 1, cob | 0x8000_0000).unwrap();
    m.write_u8(3, 0x1A01, 0, 0).unwrap();
    m.write_u32(3, 0x1A01, 1, 0x606C_0020).unwrap();
    m.write_u8(3, 0x1A01, 0, 1).unwrap();
    m.write_u8(3, 0x1801, 2, 1).unwrap();
    m.write_u32(3, 0x1801, 1, cob & 0x7FFF_FFFF).unwrap();
    m.switch_on(3).unwrap();
    m.set_mode(3, 3).unwrap();
    m.write_i32(3, 0x60FF, 0, -1).unwrap();
    m.advance(500_000);
    assert_eq!(m.read_i64(3, 0x606C, 0).unwrap(), -1000, "SDO: user units × 1000");
    m.take_id(0x283);
    m.sync();
    m.advance(1000);
    let pdo = m.take_id(0x283);
    let data = pdo.first().expect("TPDO2").frame.data().to_vec();
    assert_eq!(i32::from_le_bytes(data[..4].try_into().unwrap()), -60_000, "PDO: rpm × 1000");
}

// ---- DRVI -----------------------------------------------------------------------------------

/// Finding 8 (table 6.34): an RPDO longer than its mapping is EMCY 8220h (and is processed,
/// CiA 301); a shorter one is 8210h and is not.
#[test]
fn drvi_rpdo_of_the_wrong_length_is_an_emcy() {
    let mut m = started(DeviceKind::Drvi, 2);
    // RPDO1 maps the 2-byte controlword (the DRVI's default set).
    m.pdo(0x202, &[0x06, 0x00, 0x00]);
    m.advance(2000);
    let emcy = got(&mut m, 0x082);
    assert_eq!(emcy, ["082 20 82 11 00 00 00 00 00"]);
    assert_eq!(m.read_u16(2, 0x6040, 0).unwrap(), 0x06, "processed");
    m.pdo(0x202, &[0x07]);
    m.advance(2000);
    assert_eq!(got(&mut m, 0x082), ["082 10 82 11 00 00 00 00 00"]);
    assert_eq!(m.read_u16(2, 0x6040, 0).unwrap(), 0x06, "not processed");
    // The AKD's table has no 8220h: its overlong RPDOs are processed without an EMCY.
    let mut a = started(DeviceKind::Akd, 3);
    a.pdo(0x203, &[0x06, 0x00, 0x00]);
    a.advance(2000);
    assert!(got(&mut a, 0x083).is_empty());
}

// ---- life guarding lost (DRVI 6.3.2.12, DRCS 3.2.12) -----------------------------------------

/// Finding 9: both Camozzi drives treat a lost guarding master as "an error and reset the
/// communication": EMCY 8130h, Fault, then a communication reset (boot-up, pre-operational),
/// after which 1001h and 1003h still name the cause of the Fault.
fn guarding_loss_resets_the_communication_and_keeps_the_cause(kind: DeviceKind) {
    let mut m = started(kind, 3);
    m.switch_on(3).unwrap();
    m.write(3, 0x100C, 0, &100u16.to_le_bytes()).unwrap();
    m.write_u8(3, 0x100D, 0, 2).unwrap();
    // Guard a few times (RTR on 703h), then stop.
    for _ in 0..3 {
        m.send(CanFrame::remote(0x703, false, 1).unwrap());
        m.advance(100_000);
    }
    m.take_seen();
    m.advance(1_000_000);
    let emcy = got(&mut m, 0x083);
    assert!(emcy.iter().any(|e| e.starts_with("083 30 81 11")), "{kind:?}: {emcy:?}");
    assert_eq!(got(&mut m, 0x703), ["703 00"], "{kind:?}: boot-up after the communication reset");
    assert_eq!(m.state(3).unwrap(), Some(od_runtime::cia402::State::Fault), "{kind:?}");
    assert_eq!(m.read_u8(3, 0x1001, 0).unwrap() & 0x11, 0x11, "{kind:?}: 1001h keeps the cause");
    assert_eq!(m.read_u8(3, 0x1003, 0).unwrap(), 1, "{kind:?}");
    assert_eq!(m.read_u32(3, 0x1003, 1).unwrap() & 0xFFFF, 0x8130, "{kind:?}: 1003h keeps the cause");
}

#[test]
fn drvi_guarding_loss_resets_the_communication_and_keeps_the_cause() {
    guarding_loss_resets_the_communication_and_keeps_the_cause(DeviceKind::Drvi);
}

#[test]
fn drcs_guarding_loss_resets_the_communication_and_keeps_the_cause() {
    guarding_loss_resets_the_communication_and_keeps_the_cause(DeviceKind::Drcs);
}

/// Finding 2: a profile position move beyond the positive limit switch (at 2 turns on the
/// preset machine) stops the trajectory at the switch: warning 8612h, statusword bits 11 and 7
/// with bit 10 clear, no demand winding up; a velocity away from the switch moves at once.
#[test]
fn akd_limit_switches_stop_the_trajectory() {
    let mut m = akd(3);
    m.write_u32(3, 0x6092, 1, 10).unwrap(); // 10 units per turn
    m.write_u32(3, 0x6081, 0, 10).unwrap(); // 1 turn/s
    m.switch_on(3).unwrap();
    m.set_mode(3, 1).unwrap();
    m.write_i32(3, 0x607A, 0, 25).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.controlword(3, 0x0F).unwrap();
    m.advance(4_000_000);
    let emcy = got(&mut m, 0x083);
    assert_eq!(emcy, ["083 12 86 21 00 00 00 00 00"]);
    let sw = m.statusword(3).unwrap();
    assert_eq!(sw & 0x0C80, 0x0880, "warning, internal limit, target not reached: {sw:04X}");
    let s = akd_node(&m).app().unwrap().drive().axis().status();
    let turn = akd::COUNTS_PER_TURN as i32;
    assert!(s.position_actual >= 2 * turn && s.position_actual < 2 * turn + turn / 10, "{}", s.position_actual);
    assert_eq!(s.position_demand, s.position_actual, "the demand stopped with the axis");
    assert_eq!(s.velocity_demand, 0);
    // A move further in is not taken.
    m.write_i32(3, 0x607A, 0, 28).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.controlword(3, 0x0F).unwrap();
    m.advance(200_000);
    assert_eq!(akd_node(&m).app().unwrap().drive().axis().status().velocity_demand, 0);
    // Profile velocity away from the switch: moving within 100 ms.
    m.set_mode(3, 3).unwrap();
    m.write_i32(3, 0x60FF, 0, -1).unwrap();
    m.advance(100_000);
    assert!(m.read_i64(3, 0x606C, 0).unwrap() < 0, "moving away at once");
    m.advance(2_000_000);
    // Off the switch: the warning is gone (EMCY 0000h).
    assert_eq!(got(&mut m, 0x083), ["083 00 00 00 00 00 00 00 00"]);
    assert_eq!(m.statusword(3).unwrap() & 0x0880, 0);
}

/// A move away from a limit switch given while the axis still brakes onto it (a master's
/// answer within milliseconds of the stop): the new trajectory brakes, reverses and reaches its
/// target; the switch does not stop it again on the way out.
#[test]
fn akd_a_move_away_while_braking_onto_a_limit_switch_runs() {
    let mut m = akd(3);
    m.write_u32(3, 0x6092, 1, 10_000).unwrap(); // 10 000 units per turn
    m.write_u32(3, 0x6081, 0, 40_000).unwrap(); // 4 turns/s
    m.switch_on(3).unwrap();
    m.set_mode(3, 1).unwrap();
    m.write_i32(3, 0x607A, 0, 100_000).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.controlword(3, 0x0F).unwrap();
    // Until the switch (+2 turns) stops the trajectory, and not until it stands.
    let mut t = 0;
    while m.statusword(3).unwrap() & 0x0800 == 0 && t < 2_000_000 {
        m.advance(1_000);
        t += 1_000;
    }
    let s = akd_node(&m).app().unwrap().drive().axis().status();
    assert!(s.velocity_demand > 0, "still braking onto the switch: {}", s.velocity_demand);
    m.write_i32(3, 0x607A, 0, 0).unwrap();
    m.controlword(3, 0x1F).unwrap();
    m.controlword(3, 0x0F).unwrap();
    m.advance(3_000_000);
    let sw = m.statusword(3).unwrap();
    assert_eq!(sw & 0x0C80, 0x0400, "target reached, no limit, no warning: {sw:04X}");
    assert_eq!(m.read_i64(3, 0x6064, 0).unwrap(), 0);
}

/// A disable while stopped on a limit switch: the AKD holds the axis in Switched on (6.4.1.1),
/// and enabling again does not run into the switch.
#[test]
fn akd_limit_switch_stop_then_disable_holds_the_axis() {
    let mut m = akd(3);
    m.switch_on(3).unwrap();
    m.set_mode(3, 3).unwrap();
    m.write_i32(3, 0x60FF, 0, 2).unwrap();
    m.advance(2_500_000);
    let at = akd_node(&m).app().unwrap().drive().axis().status().position_actual;
    assert!(at >= 2 * akd::COUNTS_PER_TURN as i32, "{at}");
    m.controlword(3, 0x07).unwrap(); // disable operation: Switched on, the axis held
    m.advance(500_000);
    let s = akd_node(&m).app().unwrap().drive().axis().status();
    assert_eq!((s.velocity_demand, s.position_actual), (0, at), "held where it stopped");
    m.controlword(3, 0x0F).unwrap();
    m.advance(500_000);
    let s = akd_node(&m).app().unwrap().drive().axis().status();
    assert!(
        s.position_actual <= at + akd::COUNTS_PER_TURN as i32 / 50,
        "stopped again at the switch: {}",
        s.position_actual
    );
}
