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
#![no_std]
#![deny(warnings, missing_docs)]

include!(concat!(env!("OUT_DIR"), "/drvi.rs"));

/// Applies a received RPDO 1 to the dictionary and returns the statusword to send back.
pub fn on_rpdo1(od: &mut drvi::Dictionary, data: &[u8]) -> Option<u16> {
    let rpdo = drvi::pdo::Rpdo1::unpack(data).ok()?;
    rpdo.to_dictionary(od).ok()?;
    Some(od.statusword())
}
