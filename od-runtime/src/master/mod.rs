//! The master's protocol core: CiA 301 client services as sans-IO state machines.
//!
//! Every piece takes the frames received and the time ([`Micros`](crate::Micros)) and gives
//! back the frames to send and what happened; none does I/O, reads a clock, allocates, or
//! panics on what the bus sends. The same code serves a tokio master on a host (`od-master`)
//! and a master on a microcontroller.
//!
//! | service | type | module |
//! |---|---|---|
//! | SDO client: expedited, segmented, block (CRC), abort both ways | [`SdoClient`] | [`sdo_client`] |
//! | NMT master commands | [`nmt::command`] | [`nmt`] |
//! | heartbeat consumer, node guarding master | [`NodeMonitor`] | [`heartbeat`] |
//! | master heartbeat producer | [`HeartbeatProducer`] | [`heartbeat`] |
//! | EMCY consumer | [`Emergency`] | [`emcy`] |
//! | SYNC producer with counter (1019h) | [`SyncProducer`] | [`sync`] |
//! | PDO packing from a mapping set at run time | [`PdoMapping`] | [`pdo`] |
//! | LSS master (CiA 305): switch, configure, store, inquire, identify, fastscan | [`LssMaster`] | [`lss`] |
//!
//! Each machine has the same three entry points, so a shell drives them all alike:
//! `on_frame(&frame, now)` for every frame received (a machine keeps only its own COB-IDs),
//! `poll(now, …)` to collect the frames to send and fire timeouts, and `deadline()`, the
//! time at which `poll` next has work (for a timer or `tokio::time::sleep_until`). A shell's
//! loop:
//!
//! ```text
//! loop {
//!     wait for a frame, a request from the application, or min(deadline()s)
//!     for each frame: sdo[node].on_frame(..) -> Done (hand back to the caller),
//!                     monitor.on_frame(..) -> NodeEvent, Emergency::from_frame(..), TPDOs
//!     for each request: sdo[node].upload/download(.., buf, ..)
//!     sdo[*].poll(now, send), monitor.poll(now, send, event), sync.poll(now, send), ...
//! }
//! ```
//!
//! **Concurrency.** An [`SdoClient`] is one SDO channel to one server and runs one transfer
//! at a time, as CiA 301 requires; transfers to different nodes run at once with one client
//! per node. A shell queues further requests for a busy channel.
//!
//! **Timeouts and retries.** [`SdoClient::set_timeout`] sets how long the client waits for
//! each answer (default [`sdo_client::DEFAULT_TIMEOUT`], 1 s); set it per node and before a
//! call for a per-call value. The core never retries: a timed-out transfer ends with
//! [`SdoError::Client`]`(`[`AbortCode::TIMEOUT`](crate::od::AbortCode::TIMEOUT)`)` after
//! sending the abort, and the shell decides whether to start it again (reads freely, writes
//! only to objects the caller says are idempotent). A retry is always a new transfer from its
//! initiate request; a segment is never sent again after a timeout.
//!
//! **Errors.** Abort codes are [`AbortCode`](crate::od::AbortCode), the device side's type,
//! with CiA 301 names ([`AbortCode::name`](crate::od::AbortCode::name)) and `Display`;
//! [`Done::error`] names the node and object of a failed transfer.
//!
//! # Example
//!
//! Reading the vendor id (1018h sub 1) of node 5 and its device name (1008h, segmented),
//! with the server's frames written out as CiA 301 gives them:
//!
//! ```
//! use od_runtime::master::{Mode, SdoClient};
//! use od_runtime::{Frame, NodeId};
//!
//! let mut sdo: SdoClient<[u8; 16]> = SdoClient::new(NodeId::new(5).unwrap());
//! let mut sent = Vec::new();
//! let mut now = 0;
//!
//! sdo.upload(0x1018, 1, [0; 16], Mode::Normal, now).unwrap();
//! sdo.poll(now, &mut |f| sent.push(f.to_string()));
//! assert_eq!(sent, ["605 40 18 10 01 00 00 00 00"]);
//!
//! now += 500; // the expedited answer: 4 bytes, 0000_0ABCh
//! let answer = Frame::new(0x585, &[0x43, 0x18, 0x10, 0x01, 0xBC, 0x0A, 0, 0]).unwrap();
//! let done = sdo.on_frame(&answer, now).expect("an expedited upload ends with its answer");
//! let n = done.result.unwrap();
//! assert_eq!(u32::from_le_bytes(done.buf[..n].try_into().unwrap()), 0xABC);
//!
//! // A segmented upload: the server announces 9 bytes, then sends them 7 at a time.
//! sdo.upload(0x1008, 0, done.buf, Mode::Normal, now).unwrap();
//! let server = [
//!     [0x41, 0x08, 0x10, 0x00, 9, 0, 0, 0],                 // initiate: size 9
//!     [0x00, b'M', b'y', b' ', b'd', b'r', b'i', b'v'],     // toggle 0, 7 bytes
//!     [0x1B, b'e', b'!', 0, 0, 0, 0, 0],                    // toggle 1, 2 bytes, last
//! ];
//! let mut result = None;
//! for d in server {
//!     sdo.poll(now, &mut |f| sent.push(f.to_string()));
//!     now += 500;
//!     result = sdo.on_frame(&Frame::new(0x585, &d).unwrap(), now);
//! }
//! let done = result.expect("the last segment ends the transfer");
//! assert_eq!(&done.buf[..done.result.unwrap()], b"My drive!");
//! assert_eq!(sent[1..], ["605 40 08 10 00 00 00 00 00", "605 60 00 00 00 00 00 00 00", "605 70 00 00 00 00 00 00 00"]);
//!
//! // No answer within the timeout: the client aborts, and says who and what.
//! sdo.upload(0x6041, 0, done.buf, Mode::Normal, now).unwrap();
//! sdo.poll(now, &mut |_| {});
//! let mut abort = Vec::new();
//! let done = sdo.poll(now + 1_000_000, &mut |f| abort.push(f.to_string())).expect("timed out");
//! assert_eq!(abort, ["605 80 41 60 00 00 00 04 05"]);
//! assert_eq!(
//!     done.error().unwrap().to_string(),
//!     "node 5, upload of 6041h sub 0: aborted by the client: 0x05040000 (SDO protocol timed out)"
//! );
//! ```

pub mod emcy;
pub mod heartbeat;
pub mod lss;
pub mod nmt;
pub mod pdo;
pub mod sdo_client;
pub mod sync;

pub use emcy::Emergency;
pub use heartbeat::{HeartbeatProducer, NodeEvent, NodeMonitor, Watch};
pub use lss::LssMaster;
pub use pdo::{PdoError, PdoField, PdoMapping, PdoValue};
pub use sdo_client::{Direction, Done, Mode, Reject, Rejected, SdoClient, SdoError, TransferError};
pub use sync::SyncProducer;
