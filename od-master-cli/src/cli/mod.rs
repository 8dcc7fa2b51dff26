//! The pieces of the `od-master` command line that need no bus: naming objects, values by
//! type, device descriptions, and decoding frames for `monitor`.

pub mod boot;
pub mod decode;
pub mod device;
pub mod object;
pub mod units;
pub mod value;
