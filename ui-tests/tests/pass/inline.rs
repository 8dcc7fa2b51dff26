//! A dictionary declared inline (strict) compiles without warnings (the lint level below holds
//! for this module); its typed API, PDO layouts and EDS work.
#![deny(warnings)]

use od_runtime::od::ObjectDictionary;

od_macros::object_dictionary! {
    mod demo;
    strict;

    device {
        vendor_name = "Example Automation",
        vendor_id = 0xABC,
        product_name = "Demo I/O",
        product_code = 0x42,
        revision = 0x0001_0000,
        baud_rates = [125, 250, 500, 1000],
    }

    var 0x1000 "Device type": u32, ro, default = 0x0000_0191;
    var 0x1001 "Error register": u8, ro, pdo, default = 0;
    record 0x1018 "Identity object" {
        1 "Vendor-ID": u32, ro, default = 0xABC;
        2 "Product code": u32, ro, default = 0x42;
    }
    record 0x1200 "SDO server parameter" {
        1 "COB-ID client to server": u32, ro, default = NODEID + 0x600;
        2 "COB-ID server to client": u32, ro, default = NODEID + 0x580;
    }
    var 0x2000 "Setpoint": i16, rww, pdo, default = 0, min = -1000, max = 1000;
    var 0x2001 "Gain": f32, rw, default = 1.5;
    var 0x2002 "Label": VISIBLE_STRING, rw, default = "demo";
    array 0x6000 "Read inputs": u8, ro, pdo, len = 2, element = "Input", default = 0;
    array 0x6200 "Write outputs": u8, rww, pdo {
        1 "Output 1";
        2 "Output 2", default = 0xFF;
    }

    rpdo 1: map = [0x6200:1, 0x6200:2, 0x2000];
    tpdo 1: transmission = 1, event_timer = 100, map = [0x6000:1, 0x6000:2, 0x1001];
}

pub fn run() {
    let mut od = demo::Dictionary::new(5);
    assert_eq!(od.sdo_server_parameter_cob_id_client_to_server(), 0x605);
    assert_eq!(od.tpdo_communication_parameter_1_cob_id(), 0x185);
    assert_eq!(od.gain(), 1.5);
    assert_eq!(od.label(), b"demo");
    od.set_setpoint(-20).unwrap();
    assert!(od.set_setpoint(2000).is_err(), "max = 1000");
    od.set_write_outputs_1(0x0F).unwrap();

    let rpdo = demo::pdo::Rpdo1::from_dictionary(&od);
    assert_eq!(rpdo.pack(), [0x0F, 0xFF, 0xEC, 0xFF]);
    let back = demo::pdo::Rpdo1::unpack(&[1, 2, 3, 0]).unwrap();
    back.to_dictionary(&mut od).unwrap();
    assert_eq!(od.setpoint(), 3);

    let mut buf = [0u8; 4];
    assert_eq!(od.read(0x1018, 1, &mut buf), Ok(4));
    assert_eq!(buf, [0xBC, 0x0A, 0, 0]);
    assert_eq!(demo::index::IDENTITY_OBJECT, 0x1018);
    assert!(demo::EDS.contains("DefaultValue=$NODEID+0x600"));
}
