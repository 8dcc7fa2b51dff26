//! The inline-declared module on the od-runtime device core, frame by frame.

use inline_macro_user::{device, io};
use od_runtime::{Frame, NmtState, NodeId};

fn frame(id: u16, data: &[u8]) -> Frame {
    Frame::new(id, data).unwrap()
}

/// Feeds `rx` (if any) at `now`, polls, and returns what the device sent, as text.
fn exchange(dev: &mut od_runtime::Device<io::Dictionary, ()>, now: u64, rx: Option<Frame>) -> Vec<String> {
    if let Some(f) = rx {
        dev.on_frame(&f, now);
    }
    let mut sent = Vec::new();
    dev.poll(now, |f| sent.push(f.to_string()));
    sent
}

#[test]
fn boots_maps_pdos_and_serves_sdo_from_the_inline_dictionary() {
    let mut dev = device(NodeId::new(5).unwrap());
    assert_eq!(exchange(&mut dev, 0, None), ["705 00"]);
    assert!(exchange(&mut dev, 1_000, Some(frame(0x000, &[0x01, 5]))).is_empty());
    assert_eq!(dev.nmt_state(), NmtState::Operational);

    // RPDO 1 (COB-ID NODEID + 0x200 from the predefined connection set) writes both outputs.
    let outputs = io::pdo::Rpdo1 { outputs_1: 0xA5, outputs_2: 0x0F };
    assert_eq!(outputs.pack(), [0xA5, 0x0F]);
    exchange(&mut dev, 2_000, Some(frame(0x205, &outputs.pack())));
    assert_eq!((dev.od().outputs_1(), dev.od().outputs_2()), (0xA5, 0x0F));

    // TPDO 1 is synchronous (transmission type 1): inputs and error register on SYNC.
    dev.od_mut().set_inputs_1(0x81).unwrap();
    dev.od_mut().set_inputs_2(0x02).unwrap();
    assert_eq!(exchange(&mut dev, 3_000, Some(frame(0x080, &[]))), ["185 81 02 00"]);

    // SDO: identity from the declaration, limits from `max = 1000`.
    assert_eq!(
        exchange(&mut dev, 4_000, Some(frame(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]))),
        ["585 43 18 10 01 BC 0A 00 00"]
    );
    assert_eq!(
        exchange(&mut dev, 5_000, Some(frame(0x605, &[0x2B, 0x01, 0x20, 0x00, 0x88, 0x13, 0, 0]))),
        ["585 80 01 20 00 31 00 09 06"],
        "value too high"
    );
    assert_eq!(dev.od().filter_time(), 10);
    assert_eq!(
        exchange(&mut dev, 6_000, Some(frame(0x605, &[0x2B, 0x01, 0x20, 0x00, 0x32, 0x00, 0, 0]))),
        ["585 60 01 20 00 00 00 00 00"]
    );
    assert_eq!(dev.od().filter_time(), 50);
}

#[test]
fn node_id_relative_defaults_follow_the_node() {
    for node in [1u8, 0x22, 127] {
        let od = io::Dictionary::new(node);
        assert_eq!(od.sdo_server_parameter_cob_id_client_to_server(), 0x600 + node as u32);
        assert_eq!(od.sdo_server_parameter_cob_id_server_to_client(), 0x580 + node as u32);
        assert_eq!(od.tpdo_communication_parameter_1_cob_id(), 0x180 + node as u32);
        assert_eq!(od.rpdo_communication_parameter_1_cob_id(), 0x200 + node as u32);
    }
}
