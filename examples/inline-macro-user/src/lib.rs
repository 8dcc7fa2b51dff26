//! Example: a small CANopen I/O module whose object dictionary is declared in Rust with
//! [`od_macros::object_dictionary!`] instead of an EDS file, and which runs on the `od-runtime`
//! device core.
//!
//! The macro expands to the module [`io`]: the typed `Dictionary` (one getter and setter per
//! entry, limits checked), the PDO layouts in `io::pdo`, index constants and `io::EDS`, the
//! device's EDS, which any CANopen tool can import.
//!
//! ```
//! use inline_macro_user::io;
//!
//! let mut od = io::Dictionary::new(5);
//! assert_eq!(od.tpdo_communication_parameter_1_cob_id(), 0x185); // NODEID + 0x180
//! od.set_outputs_1(0xA5).unwrap();
//! assert_eq!(io::pdo::Rpdo1::from_dictionary(&od).pack()[0], 0xA5);
//! ```
#![no_std]
#![deny(warnings, missing_docs)]

use od_runtime::{Device, NoStorage, NodeId};

od_macros::object_dictionary! {
    mod io;
    strict;

    device {
        vendor_name = "Example Automation",
        vendor_id = 0x0000_0ABC,
        product_name = "Inline I/O module",
        product_code = 0x0000_0401,
        revision = 0x0001_0002,
        order_code = "IO-8DI-8DO",
        baud_rates = [125, 250, 500, 1000],
        description = "Digital I/O module declared inline with od_macros",
    }

    // Communication profile (CiA 301).
    var 0x1000 "Device type": u32, ro, default = 0x000F_0191;       // CiA 401, digital in + out
    var 0x1001 "Error register": u8, ro, pdo, default = 0;
    var 0x1017 "Producer heartbeat time": u16, rw, default = 0, max = 60_000;
    record 0x1018 "Identity object" {
        1 "Vendor-ID": u32, ro, default = 0x0000_0ABC;
        2 "Product code": u32, ro, default = 0x0000_0401;
        3 "Revision number": u32, ro, default = 0x0001_0002;
        4 "Serial number": u32, ro, default = 0x0000_2A2A;
    }
    record 0x1200 "SDO server parameter" {
        1 "COB-ID client to server": u32, ro, default = NODEID + 0x600;
        2 "COB-ID server to client": u32, ro, default = NODEID + 0x580;
    }

    // Application (CiA 401 style).
    array 0x6000 "Inputs": u8, ro, pdo, len = 2, element = "Input", default = 0;
    array 0x6200 "Outputs": u8, rww, pdo, len = 2, element = "Output", default = 0;
    var 0x2000 "Output mask": u8, rw, default = 0xFF;
    var 0x2001 "Filter time": u16, rw, default = 10, min = 1, max = 1000;
    var 0x2002 "Temperature": REAL32, ro, pdo, default = 21.5;
    var 0x2003 "Location": VISIBLE_STRING, rw, default = "cabinet 1";

    // Default PDOs: the master writes both outputs; the module sends its inputs and error
    // register on every SYNC.
    rpdo 1: map = [0x6200:1, 0x6200:2];
    tpdo 1: transmission = 1, map = [0x6000:1, 0x6000:2, 0x1001];
}

/// The module as a CANopen device on node `node_id`.
pub fn device(node_id: NodeId) -> Device<io::Dictionary, ()> {
    Device::new(io::Dictionary::new(node_id.get()), (), NoStorage, node_id)
}
