//! Runs the inline-declared I/O module on the od-runtime device core for a few simulated bus
//! frames and prints what happens.
//!
//! `inline-macro-user --eds` prints the module's EDS instead (the python-canopen import test
//! reads it from there).

use inline_macro_user::{device, io};
use od_runtime::{Frame, NodeId};

fn frame(id: u16, data: &[u8]) -> Frame {
    Frame::new(id, data).unwrap_or_else(|| panic!("bad frame {id:03X}"))
}

fn main() {
    if std::env::args().skip(1).any(|a| a == "--eds") {
        print!("{}", io::EDS);
        return;
    }

    // The typed API, straight from the declaration.
    let od = io::Dictionary::new(5);
    println!(
        "identity: vendor 0x{:08X}, product 0x{:08X}, revision 0x{:08X}, serial 0x{:08X}",
        od.identity_object_vendor_id(),
        od.identity_object_product_code(),
        od.identity_object_revision_number(),
        od.identity_object_serial_number()
    );
    println!(
        "node 5: SDO 0x{:03X}/0x{:03X}, TPDO 1 0x{:03X}, RPDO 1 0x{:03X}",
        od.sdo_server_parameter_cob_id_client_to_server(),
        od.sdo_server_parameter_cob_id_server_to_client(),
        od.tpdo_communication_parameter_1_cob_id(),
        od.rpdo_communication_parameter_1_cob_id()
    );
    println!("temperature {} °C, location {:?}", od.temperature(), std::str::from_utf8(od.location()).unwrap_or("?"));
    let tpdo = io::pdo::Tpdo1 { inputs_1: 0x81, inputs_2: 0x02, error_register: 0 };
    println!("TPDO 1 {{ inputs 0x81, 0x02, error register 0 }} packs as {:02X?}", tpdo.pack());

    // The same dictionary behind the CiA 301 device core.
    let node = NodeId::new(5).expect("node id");
    let mut dev = device(node);
    let mut now = 0u64;
    let mut step = |dev: &mut od_runtime::Device<io::Dictionary, ()>, what: &str, rx: Option<Frame>| {
        println!("{what}");
        if let Some(f) = rx {
            println!("  rx {f}");
            dev.on_frame(&f, now);
        }
        dev.poll(now, |f| println!("  tx {f}"));
        now += 1_000;
    };
    step(&mut dev, "power on", None);
    step(&mut dev, "NMT start node 5", Some(frame(0x000, &[0x01, 5])));
    let outputs = io::pdo::Rpdo1 { outputs_1: 0xA5, outputs_2: 0x0F };
    step(&mut dev, "RPDO 1 sets both outputs", Some(frame(0x205, &outputs.pack())));
    println!("  outputs now 0x{:02X} 0x{:02X}", dev.od().outputs_1(), dev.od().outputs_2());
    dev.od_mut().set_inputs_1(0x81).expect("input 1");
    step(&mut dev, "SYNC: TPDO 1 carries the inputs", Some(frame(0x080, &[])));
    step(&mut dev, "SDO upload 0x1018 sub 1 (vendor id)", Some(frame(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0])));
    step(
        &mut dev,
        "SDO download 0x2001 = 5000 (above max)",
        Some(frame(0x605, &[0x2B, 0x01, 0x20, 0x00, 0x88, 0x13, 0, 0])),
    );
}
