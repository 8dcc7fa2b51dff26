//! Example: a `#![no_std]` crate whose object dictionary is generated at build time.
//!
//! `build.rs` runs [`od_codegen::Builder`](https://docs.rs/od-codegen) on the DRVI's EDS; this
//! file includes the result, which defines `pub mod drvi`:
//!
//! ```
//! use build_rs_user::drvi::{Dictionary, pdo};
//! use od_runtime::od::ObjectDictionary;
//!
//! let mut od = Dictionary::new(32);
//! od.set_controlword(0x000F).unwrap();
//! let mut buf = [0u8; 4];
//! assert_eq!(od.read(0x6040, 0, &mut buf), Ok(2));
//! assert_eq!(pdo::Rpdo1::from_dictionary(&od).pack(), [0x0F, 0x00]);
//! ```
//!
//! A vendor's file builds too, with a warning where its default PDO mapping is a placeholder:
//!
//! ```
//! use build_rs_user::vendor_io::Dictionary;
//! use od_runtime::od::ObjectDictionary;
//!
//! let od = Dictionary::new(5);
//! assert_eq!(od.tpdo_communication_parameter_cob_id(), 0x185);
//! // The placeholder mapping is data a master can read and rewrite.
//! let mut buf = [0u8; 4];
//! assert_eq!(od.read(0x1A00, 0, &mut buf), Ok(1));
//! assert_eq!(buf[0], 2);
//! ```
#![no_std]
#![deny(warnings, missing_docs)]

include!(concat!(env!("OUT_DIR"), "/drvi.rs"));
include!(concat!(env!("OUT_DIR"), "/vendor_io.rs"));

/// Applies a received RPDO 1 to the dictionary and returns the statusword to send back.
pub fn on_rpdo1(od: &mut drvi::Dictionary, data: &[u8]) -> Option<u16> {
    let rpdo = drvi::pdo::Rpdo1::unpack(data).ok()?;
    rpdo.to_dictionary(od).ok()?;
    Some(od.statusword())
}
