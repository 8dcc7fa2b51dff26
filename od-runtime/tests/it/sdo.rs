//! SDO server: frame-exact expedited, segmented and block transfers, and every abort code.

use crate::common;
use common::*;
#[cfg(feature = "sdo-block")]
use od_runtime::crc::crc16_ccitt;
use od_runtime::od::ObjectDictionary;

#[test]
fn expedited_download_and_upload_frames() {
    let mut h = Harness::new();
    // The example of the brief and of the drive manuals: controlword = 6 (shutdown).
    h.exchange("601 2B 40 60 00 06 00 00 00", &["581 60 40 60 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x6040, 0), 6);
    h.exchange("601 40 40 60 00 00 00 00 00", &["581 4B 40 60 00 06 00 00 00"]);
    h.exchange("601 40 00 10 00 00 00 00 00", &["581 43 00 10 00 92 01 02 00"]);
    h.exchange("601 40 01 10 00 00 00 00 00", &["581 4F 01 10 00 00 00 00 00"]);
    h.exchange("601 40 18 10 04 00 00 00 00", &["581 43 18 10 04 39 30 00 00"]);
    // Size not indicated (e=1, s=0): the entry's own size is used.
    h.exchange("601 22 05 20 00 F6 00 00 00", &["581 60 05 20 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x2005, 0), -10);
    h.exchange("601 2F 60 60 00 03 00 00 00", &["581 60 60 60 00 00 00 00 00"]);
    // 6060h is mirrored into 6061h (by the CiA 402 state machine; without it, a plain object).
    let display = if cfg!(feature = "cia402") { "581 4F 61 60 00 03 00 00 00" } else { "581 4F 61 60 00 00 00 00 00" };
    h.exchange("601 40 61 60 00 00 00 00 00", &[display]);
    // Expedited write of 2 bytes to a U16.
    h.exchange("601 2B 17 10 00 E8 03 00 00", &["581 60 17 10 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x1017, 0), 1000);
}

#[test]
fn segmented_upload_of_a_visible_string() {
    let mut h = Harness::new();
    h.exchange("601 40 08 10 00 00 00 00 00", &["581 41 08 10 00 15 00 00 00"]);
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 00 6F 64 2D 72 75 6E 74"]);
    h.exchange("601 70 00 00 00 00 00 00 00", &["581 10 69 6D 65 20 74 65 73"]);
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 01 74 20 64 72 69 76 65"]);
    // The transfer is over: another segment request is a protocol error.
    h.exchange("601 70 00 00 00 00 00 00 00", &["581 80 00 00 00 01 00 04 05"]);
}

#[test]
fn segmented_upload_of_64_bit_value() {
    let mut h = Harness::new();
    h.exchange("601 40 02 20 00 00 00 00 00", &["581 41 02 20 00 08 00 00 00"]);
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 00 EF CD AB 89 67 45 23"]);
    h.exchange("601 70 00 00 00 00 00 00 00", &["581 1D 01 00 00 00 00 00 00"]);
}

#[test]
fn segmented_download_of_a_string_and_u64() {
    let mut h = Harness::new();
    h.exchange("601 21 01 20 00 0C 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    h.exchange("601 00 68 65 6C 6C 6F 20 77", &["581 20 00 00 00 00 00 00 00"]);
    h.exchange("601 15 6F 72 6C 64 21 00 00", &["581 30 00 00 00 00 00 00 00"]);
    assert_eq!(h.od().bytes(0x2001, 0), b"hello world!");
    // Size not indicated.
    h.exchange("601 20 01 20 00 00 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    h.exchange("601 0B 61 62 00 00 00 00 00", &["581 20 00 00 00 00 00 00 00"]);
    assert_eq!(h.od().bytes(0x2001, 0), b"ab");
    // A 64-bit value in two segments.
    h.exchange("601 21 02 20 00 08 00 00 00", &["581 60 02 20 00 00 00 00 00"]);
    h.exchange("601 00 01 02 03 04 05 06 07", &["581 20 00 00 00 00 00 00 00"]);
    h.exchange("601 1D 08 00 00 00 00 00 00", &["581 30 00 00 00 00 00 00 00"]);
    assert_eq!(h.od().get(0x2002, 0), 0x0807_0605_0403_0201);
}

#[test]
fn toggle_errors_abort() {
    let mut h = Harness::new();
    h.exchange("601 21 01 20 00 0C 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    h.exchange("601 10 68 65 6C 6C 6F 20 77", &["581 80 01 20 00 00 00 03 05"]);
    h.exchange("601 40 08 10 00 00 00 00 00", &["581 41 08 10 00 15 00 00 00"]);
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 00 6F 64 2D 72 75 6E 74"]);
    h.exchange("601 60 00 00 00 00 00 00 00", &["581 80 08 10 00 00 00 03 05"]);
}

#[test]
fn timeout_aborts_a_stalled_transfer() {
    let mut h = Harness::new();
    h.exchange("601 40 08 10 00 00 00 00 00", &["581 41 08 10 00 15 00 00 00"]);
    assert!(h.advance(999_999).is_empty());
    assert_eq!(h.advance(1), ["581 80 08 10 00 00 00 04 05"]);
    // The server is idle again: a new request is served.
    h.exchange("601 40 01 10 00 00 00 00 00", &["581 4F 01 10 00 00 00 00 00"]);
    // A shorter timeout.
    h.dev.set_sdo_timeout(10_000);
    h.exchange("601 21 01 20 00 0C 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    assert_eq!(h.advance(10_000), ["581 80 01 20 00 00 00 04 05"]);
}

#[test]
fn abort_codes() {
    let mut h = Harness::new();
    // Unknown command specifier (ccs = 7).
    h.exchange("601 E0 00 10 00 00 00 00 00", &["581 80 00 10 00 01 00 04 05"]);
    // Segment without a transfer.
    h.exchange("601 00 00 00 00 00 00 00 00", &["581 80 00 00 00 01 00 04 05"]);
    // Access: write a read-only object, read a write-only object, write a constant.
    h.exchange("601 23 00 10 00 00 00 00 00", &["581 80 00 10 00 02 00 01 06"]);
    h.exchange("601 40 06 20 00 00 00 00 00", &["581 80 06 20 00 01 00 01 06"]);
    h.exchange("601 21 08 10 00 02 00 00 00", &["581 80 08 10 00 02 00 01 06"]);
    // Unsupported access: a mapping entry while the PDO is valid.
    h.exchange("601 23 00 16 01 10 00 40 60", &["581 80 00 16 01 00 00 01 06"]);
    // Object and sub-index.
    h.exchange("601 40 34 12 00 00 00 00 00", &["581 80 34 12 00 00 00 02 06"]);
    h.exchange("601 40 18 10 09 00 00 00 00", &["581 80 18 10 09 11 00 09 06"]);
    // Length: too high, too low; segmented size mismatch.
    h.exchange("601 23 40 60 00 01 00 00 00", &["581 80 40 60 00 12 00 07 06"]);
    h.exchange("601 2F 17 10 00 01 00 00 00", &["581 80 17 10 00 13 00 07 06"]);
    h.exchange("601 21 01 20 00 03 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    h.exchange("601 0B 61 62 00 00 00 00 00", &["581 80 01 20 00 10 00 07 06"]);
    h.exchange("601 21 01 20 00 40 00 00 00", &["581 80 01 20 00 12 00 07 06"]);
    // Range: invalid value, too high, too low.
    h.exchange("601 2F 04 20 01 02 00 00 00", &["581 80 04 20 01 30 00 09 06"]);
    h.exchange("601 2F 05 20 00 65 00 00 00", &["581 80 05 20 00 31 00 09 06"]);
    h.exchange("601 2F 05 20 00 9B 00 00 00", &["581 80 05 20 00 32 00 09 06"]);
    h.exchange("601 2F 00 18 02 F5 00 00 00", &["581 80 00 18 02 30 00 09 06"]);
    // State: 1019h while a SYNC period is set.
    h.sdo_write_ok(0x1006, 0, &[0x10, 0x27, 0, 0]);
    h.exchange("601 2F 19 10 00 05 00 00 00", &["581 80 19 10 00 22 00 00 08"]);
    // Store with a wrong signature.
    h.exchange("601 23 10 10 01 73 61 76 00", &["581 80 10 10 01 20 00 00 08"]);
    // Local control: controlword while the drive is not in remote (CiA 402 only).
    if cfg!(feature = "cia402") {
        h.dev.set_remote(false);
        h.exchange("601 2B 40 60 00 06 00 00 00", &["581 80 40 60 00 21 00 00 08"]);
        h.dev.set_remote(true);
    }
    // Out of memory: more than the 1 KiB transfer buffer, within the DOMAIN's capacity.
    h.exchange("601 21 03 20 00 00 05 00 00", &["581 80 03 20 00 05 00 04 05"]);
    // The client's abort ends a transfer silently.
    h.exchange("601 21 01 20 00 03 00 00 00", &["581 60 01 20 00 00 00 00 00"]);
    assert!(h.send("601 80 01 20 00 00 00 04 05").is_empty());
    h.exchange("601 00 61 62 63 00 00 00 00", &["581 80 00 00 00 01 00 04 05"]);
}

#[test]
fn application_veto() {
    let mut h = Harness::new();
    h.dev.app_mut().veto.push((0x607A, 0, od_runtime::od::AbortCode::VALUE_TOO_HIGH));
    h.exchange("601 23 7A 60 00 00 00 01 00", &["581 80 7A 60 00 31 00 09 06"]);
    assert_eq!(h.od().get(0x607A, 0), 0);
    h.exchange("601 23 FF 60 00 10 00 00 00", &["581 60 FF 60 00 00 00 00 00"]);
    let w = &h.dev.app().writes;
    assert_eq!(w.last().unwrap(), &(0x60FF, 0, vec![0x10, 0, 0, 0], od_runtime::WriteSource::Sdo));
}

#[test]
#[cfg(feature = "sdo-block")]
fn block_download_with_crc() {
    let mut h = Harness::new();
    let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
    assert_eq!(block_download(&mut h, 0x2003, &data, true, None), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(h.od().bytes(0x2003, 0), data);
    // Without CRC, with a lost segment the server asks to resend from the gap.
    let data2: Vec<u8> = (0..300u32).map(|i| (i * 13) as u8).collect();
    assert_eq!(block_download(&mut h, 0x2003, &data2, false, Some(5)), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(h.od().bytes(0x2003, 0), data2);
    // Exactly the buffer size.
    let full = vec![0x5A; 1024];
    assert_eq!(block_download(&mut h, 0x2003, &full, true, None), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(h.od().bytes(0x2003, 0), full);
    // A short value and an empty one.
    assert_eq!(block_download(&mut h, 0x2001, b"abc", true, None), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(h.od().bytes(0x2001, 0), b"abc");
    assert_eq!(block_download(&mut h, 0x2001, b"", true, None), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(h.od().bytes(0x2001, 0), b"");
}

#[test]
#[cfg(feature = "sdo-block")]
fn block_download_errors() {
    let mut h = Harness::new();
    // Wrong CRC.
    h.exchange("601 C6 01 20 00 03 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    h.exchange("601 81 61 62 63 00 00 00 00", &["581 A2 01 7F 00 00 00 00 00"]);
    h.exchange("601 D1 00 00 00 00 00 00 00", &["581 80 01 20 00 04 00 04 05"]);
    // Sequence number 0 and past the block size.
    h.exchange("601 C6 01 20 00 03 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    h.exchange("601 00 61 62 63 00 00 00 00", &["581 80 01 20 00 03 00 04 05"]);
    // Size over the buffer, over the capacity, read-only target.
    h.exchange("601 C6 03 20 00 01 04 00 00", &["581 80 03 20 00 05 00 04 05"]);
    h.exchange("601 C6 01 20 00 21 00 00 00", &["581 80 01 20 00 12 00 07 06"]);
    h.exchange("601 C6 08 10 00 03 00 00 00", &["581 80 08 10 00 02 00 01 06"]);
    // Indicated size differs from the data.
    h.exchange("601 C6 01 20 00 05 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    h.exchange("601 81 61 62 63 00 00 00 00", &["581 A2 01 7F 00 00 00 00 00"]);
    let c = crc16_ccitt(0, b"abc");
    h.exchange(&format!("601 D1 {:02X} {:02X} 00 00 00 00 00", c as u8, c >> 8), &["581 80 01 20 00 10 00 07 06"]);
    // Only an end request may follow the last segment.
    h.exchange("601 C6 01 20 00 03 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    h.exchange("601 81 61 62 63 00 00 00 00", &["581 A2 01 7F 00 00 00 00 00"]);
    h.exchange("601 40 00 10 00 00 00 00 00", &["581 80 01 20 00 01 00 04 05"]);
    // A block download past the buffer: data beyond 1024 bytes is out of memory.
    let data = vec![1u8; 1100];
    let r = block_download(&mut h, 0x2003, &data[..1024], true, None);
    assert_eq!(r, "581 A1 00 00 00 00 00 00 00");
    h.exchange("601 C4 03 20 00 00 00 00 00", &["581 A4 03 20 00 7F 00 00 00"]);
    let mut last = Vec::new();
    for seq in 1..=127u8 {
        last = h.send(&format!("601 {seq:02X} 01 01 01 01 01 01 01"));
    }
    // 135 bytes of room left: a block of 20 segments.
    assert_eq!(last, ["581 A2 7F 14 00 00 00 00 00"]);
    for seq in 1..=20u8 {
        last = h.send(&format!("601 {seq:02X} 01 01 01 01 01 01 01"));
    }
    assert_eq!(last, ["581 A2 14 01 00 00 00 00 00"]);
    h.exchange("601 01 01 01 01 01 01 01 01", &["581 80 03 20 00 05 00 04 05"]);
}

#[test]
#[cfg(feature = "sdo-block")]
fn block_upload_with_crc() {
    let mut h = Harness::new();
    let data: Vec<u8> = (0..1000u32).map(|i| (i * 31 + 1) as u8).collect();
    assert_eq!(block_download(&mut h, 0x2003, &data, true, None), "581 A1 00 00 00 00 00 00 00");
    assert_eq!(block_upload(&mut h, 0x2003, 0, 127, true), data);
    assert_eq!(block_upload(&mut h, 0x2003, 0, 10, false), data);
    assert_eq!(block_upload(&mut h, 0x1008, 0, 4, true), b"od-runtime test drive");
    assert_eq!(block_upload(&mut h, 0x1000, 0, 1, true), [0x92, 0x01, 0x02, 0x00]);
    // Server is idle afterwards.
    h.exchange("601 40 01 10 00 00 00 00 00", &["581 4F 01 10 00 00 00 00 00"]);
}

#[test]
#[cfg(feature = "sdo-block")]
fn block_upload_frames_and_retransmission() {
    let mut h = Harness::new();
    // 1008h (21 bytes) in blocks of 2: exact frames.
    h.exchange("601 A4 08 10 00 02 00 00 00", &["581 C6 08 10 00 15 00 00 00"]);
    assert_eq!(h.send("601 A3 00 00 00 00 00 00 00"), ["581 01 6F 64 2D 72 75 6E 74", "581 02 69 6D 65 20 74 65 73"]);
    // The client only got the first segment: the second is sent again.
    assert_eq!(h.send("601 A2 01 02 00 00 00 00 00"), ["581 01 69 6D 65 20 74 65 73", "581 82 74 20 64 72 69 76 65"]);
    let c = crc16_ccitt(0, b"od-runtime test drive");
    assert_eq!(
        h.send("601 A2 02 02 00 00 00 00 00"),
        [format!("581 C1 {:02X} {:02X} 00 00 00 00 00", c as u8, c >> 8)]
    );
    assert!(h.send("601 A1 00 00 00 00 00 00 00").is_empty());
    // Protocol switch threshold: small values come back as a normal upload.
    h.exchange("601 A4 00 10 00 10 08 00 00", &["581 43 00 10 00 92 01 02 00"]);
    // Invalid block size.
    h.exchange("601 A4 00 10 00 00 00 00 00", &["581 80 00 10 00 02 00 04 05"]);
    h.exchange("601 A4 00 10 00 80 00 00 00", &["581 80 00 10 00 02 00 04 05"]);
    // Acknowledging more segments than sent.
    h.exchange("601 A4 08 10 00 02 00 00 00", &["581 C6 08 10 00 15 00 00 00"]);
    assert_eq!(h.send("601 A3 00 00 00 00 00 00 00").len(), 2);
    h.exchange("601 A2 03 02 00 00 00 00 00", &["581 80 08 10 00 03 00 04 05"]);
    // Start without initiate.
    h.exchange("601 A3 00 00 00 00 00 00 00", &["581 80 00 00 00 01 00 04 05"]);
    // Read access is checked.
    h.exchange("601 A4 06 20 00 02 00 00 00", &["581 80 06 20 00 01 00 01 06"]);
}

#[test]
fn sdo_only_in_pre_operational_and_operational() {
    let mut h = Harness::new();
    h.send("000 02 01");
    assert!(h.send("601 40 00 10 00 00 00 00 00").is_empty());
    h.start();
    h.exchange("601 40 00 10 00 00 00 00 00", &["581 43 00 10 00 92 01 02 00"]);
    // Frames that are not 8 bytes long are ignored.
    assert!(h.send("601 40 00 10 00").is_empty());
    let _ = h.od().entries();
}

#[test]
fn upload_larger_than_the_buffer_is_out_of_memory() {
    let mut h = Harness::new();
    h.dev.write(0x2003, 0, &[7u8; 1500]).unwrap();
    h.exchange("601 40 03 20 00 00 00 00 00", &["581 80 03 20 00 05 00 04 05"]);
    // A block upload: out of memory too, or, without `sdo-block`, refused as an unknown command.
    let block = if cfg!(feature = "sdo-block") { "581 80 03 20 00 05 00 04 05" } else { "581 80 03 20 00 01 00 04 05" };
    h.exchange("601 A4 03 20 00 10 00 00 00", &[block]);
    // A local write checks the dictionary's limits too.
    assert_eq!(h.dev.write(0x2003, 0, &[7u8; 3000]), Err(od_runtime::od::AbortCode::LENGTH_TOO_HIGH));
}

#[test]
#[cfg(feature = "sdo-block")]
fn block_download_whose_last_segment_is_lost_times_out() {
    let mut h = Harness::new();
    h.exchange("601 C6 01 20 00 0A 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    assert!(h.send("601 01 61 62 63 64 65 66 67").is_empty());
    // Segment 2 (with c) never arrives: nothing can be acknowledged until the timeout.
    assert!(h.advance(999_999).is_empty());
    assert_eq!(h.advance(1), ["581 80 01 20 00 00 00 04 05"]);
    // A lost segment inside a block is acknowledged from the gap on.
    h.exchange("601 C6 01 20 00 0A 00 00 00", &["581 A4 01 20 00 7F 00 00 00"]);
    assert!(h.send("601 02 61 62 63 64 65 66 67").is_empty());
    h.exchange("601 83 68 69 6A 00 00 00 00", &["581 A2 00 7F 00 00 00 00 00"]);
}

/// Without the `sdo-block` feature both block initiates are refused as unknown commands
/// (0504 0001h), which a client takes as "no block transfers here" and falls back to a normal
/// transfer; the normal transfers of the same object still work.
#[test]
#[cfg(not(feature = "sdo-block"))]
fn without_sdo_block_block_transfers_are_refused_as_unknown_commands() {
    let mut h = Harness::new();
    h.exchange("601 C6 03 20 00 0A 00 00 00", &["581 80 03 20 00 01 00 04 05"]);
    h.exchange("601 C2 03 20 00 0A 00 00 00", &["581 80 03 20 00 01 00 04 05"]);
    h.exchange("601 A0 03 20 00 10 00 00 00", &["581 80 03 20 00 01 00 04 05"]);
    h.exchange("601 A4 03 20 00 10 00 00 00", &["581 80 03 20 00 01 00 04 05"]);
    let data: Vec<u8> = (0..10).collect();
    segmented_download(&mut h, 0x2003, &data);
    assert_eq!(upload(&mut h, 0x2003, 0), data);
}
