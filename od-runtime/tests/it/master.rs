//! The master's protocol core (`od_runtime::master`): the SDO client frame by frame against
//! CiA 301 as written out by hand and against the project's own SDO server in virtual time,
//! its faults (lost, repeated, foreign and random frames, wrong toggle bits, aborts, timeouts),
//! the heartbeat consumer and node guarding master against the device, the EMCY consumer,
//! the SYNC producer, and PDOs packed from a mapping read from the device.

use crate::common;
use common::*;
use od_runtime::crc::crc16_ccitt;
use od_runtime::master::heartbeat::Full;
use od_runtime::master::nmt::{self, Target};
use od_runtime::master::sdo_client::MAX_STALLED_BLOCKS;
use od_runtime::master::sync::InvalidOverflow;
use od_runtime::master::*;
use od_runtime::nmt::{NmtCommand, NmtState};
use od_runtime::od::{AbortCode, ObjectDictionary};
use od_runtime::pdo::{Direction as PdoDir, MapEntry, Mappable};
use od_runtime::{Event, Frame, Micros, NodeId};
use proptest::prelude::*;

type Client = SdoClient<Vec<u8>>;

fn node(n: u8) -> NodeId {
    NodeId::new(n).unwrap()
}

/// The frames the client sends at `now`, as strings.
fn sent(c: &mut Client, now: Micros) -> Vec<String> {
    let mut out = Vec::new();
    assert!(c.poll(now, &mut |f| out.push(f.to_string())).is_none(), "poll ended the transfer");
    out
}

/// Hands the client one server frame.
fn reply(c: &mut Client, s: &str) -> Option<Done<Vec<u8>>> {
    c.on_frame(&frame(s), 0)
}

/// Asserts the client sends exactly `expected` now.
#[track_caller]
fn expect(c: &mut Client, expected: &[&str]) {
    assert_eq!(sent(c, 0), expected);
}

fn value(d: &Done<Vec<u8>>) -> &[u8] {
    let n = *d.result.as_ref().expect("transfer succeeded");
    &d.buf[..n]
}

// ---- hand-written CiA 301 frames --------------------------------------------------------------

#[test]
fn expedited_upload_every_size() {
    let mut c = Client::new(node(1));
    for (resp, want) in [
        ("581 4F 00 10 00 92 00 00 00", &[0x92][..]),
        ("581 4B 00 10 00 92 01 00 00", &[0x92, 0x01][..]),
        ("581 47 00 10 00 92 01 02 00", &[0x92, 0x01, 0x02][..]),
        ("581 43 00 10 00 92 01 02 00", &[0x92, 0x01, 0x02, 0x00][..]),
        // e = 1, s = 0: the size is not indicated, all four bytes are the value.
        ("581 42 00 10 00 92 01 02 03", &[0x92, 0x01, 0x02, 0x03][..]),
    ] {
        c.upload(0x1000, 0, vec![0; 8], Mode::Normal, 0).unwrap();
        expect(&mut c, &["601 40 00 10 00 00 00 00 00"]);
        let d = reply(&mut c, resp).expect("expedited answer ends the upload");
        assert_eq!(value(&d), want, "{resp}");
        assert_eq!((d.node, d.index, d.sub, d.direction), (1, 0x1000, 0, Direction::Upload));
        expect(&mut c, &[]);
        assert!(c.is_idle());
    }
}

#[test]
fn expedited_download_every_size() {
    let mut c = Client::new(node(1));
    for (data, req) in [
        (&[0x06][..], "601 2F 40 60 00 06 00 00 00"),
        (&[0x06, 0x00][..], "601 2B 40 60 00 06 00 00 00"),
        (&[1, 2, 3][..], "601 27 40 60 00 01 02 03 00"),
        (&[1, 2, 3, 4][..], "601 23 40 60 00 01 02 03 04"),
    ] {
        c.download(0x6040, 0, data.to_vec(), Mode::Normal, 0).unwrap();
        expect(&mut c, &[req]);
        let d = reply(&mut c, "581 60 40 60 00 00 00 00 00").unwrap();
        assert_eq!(d.result, Ok(data.len()));
        assert_eq!(d.buf, data);
    }
}

#[test]
fn segmented_download_frames() {
    let mut c = Client::new(node(1));
    c.download(0x2001, 0, b"hello world!".to_vec(), Mode::Normal, 0).unwrap();
    expect(&mut c, &["601 21 01 20 00 0C 00 00 00"]);
    assert!(reply(&mut c, "581 60 01 20 00 00 00 00 00").is_none());
    expect(&mut c, &["601 00 68 65 6C 6C 6F 20 77"]);
    assert!(reply(&mut c, "581 20 00 00 00 00 00 00 00").is_none());
    expect(&mut c, &["601 15 6F 72 6C 64 21 00 00"]);
    let d = reply(&mut c, "581 30 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Ok(12));
    // Forced segmented for 2 bytes, and an empty value (one segment, 7 bytes unused).
    c.download(0x2001, 0, b"ab".to_vec(), Mode::Segmented, 0).unwrap();
    expect(&mut c, &["601 21 01 20 00 02 00 00 00"]);
    reply(&mut c, "581 60 01 20 00 00 00 00 00");
    expect(&mut c, &["601 0B 61 62 00 00 00 00 00"]);
    assert_eq!(reply(&mut c, "581 20 00 00 00 00 00 00 00").unwrap().result, Ok(2));
    c.download(0x2001, 0, Vec::new(), Mode::Normal, 0).unwrap();
    expect(&mut c, &["601 21 01 20 00 00 00 00 00"]);
    reply(&mut c, "581 60 01 20 00 00 00 00 00");
    expect(&mut c, &["601 0F 00 00 00 00 00 00 00"]);
    assert_eq!(reply(&mut c, "581 20 00 00 00 00 00 00 00").unwrap().result, Ok(0));
}

#[test]
fn segmented_upload_frames_with_and_without_size() {
    let mut c = Client::new(node(1));
    c.upload(0x1008, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    expect(&mut c, &["601 40 08 10 00 00 00 00 00"]);
    reply(&mut c, "581 41 08 10 00 15 00 00 00");
    expect(&mut c, &["601 60 00 00 00 00 00 00 00"]);
    reply(&mut c, "581 00 6F 64 2D 72 75 6E 74");
    expect(&mut c, &["601 70 00 00 00 00 00 00 00"]);
    reply(&mut c, "581 10 69 6D 65 20 74 65 73");
    expect(&mut c, &["601 60 00 00 00 00 00 00 00"]);
    let d = reply(&mut c, "581 01 74 20 64 72 69 76 65").unwrap();
    assert_eq!(value(&d), b"od-runtime test drive");
    // Size not indicated (s = 0): the last segment says where the value ends.
    c.upload(0x1008, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    expect(&mut c, &["601 40 08 10 00 00 00 00 00"]);
    reply(&mut c, "581 40 08 10 00 00 00 00 00");
    expect(&mut c, &["601 60 00 00 00 00 00 00 00"]);
    let d = reply(&mut c, "581 09 41 42 43 00 00 00 00").unwrap();
    assert_eq!(value(&d), b"ABC");
}

#[test]
fn block_download_frames_with_crc() {
    let data: Vec<u8> = (1..=10).collect();
    let mut c = Client::new(node(1));
    c.download(0x2003, 0, data.clone(), Mode::Block, 0).unwrap();
    // ccs 6, cc = 1 (client does CRC), s = 1 (size indicated).
    expect(&mut c, &["601 C6 03 20 00 0A 00 00 00"]);
    assert!(reply(&mut c, "581 A4 03 20 00 7F 00 00 00").is_none());
    expect(&mut c, &["601 01 01 02 03 04 05 06 07", "601 82 08 09 0A 00 00 00 00"]);
    assert!(reply(&mut c, "581 A2 02 7F 00 00 00 00 00").is_none());
    // End: 4 bytes of the last segment unused (n = 4), CRC of the 10 bytes.
    let crc = crc16_ccitt(0, &data).to_le_bytes();
    expect(&mut c, &[&format!("601 D1 {:02X} {:02X} 00 00 00 00 00", crc[0], crc[1])]);
    let d = reply(&mut c, "581 A1 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Ok(10));
}

#[test]
fn block_download_without_server_crc_sends_zero() {
    let mut c = Client::new(node(1));
    c.download(0x2003, 0, vec![0xAA; 7], Mode::Block, 0).unwrap();
    expect(&mut c, &["601 C6 03 20 00 07 00 00 00"]);
    reply(&mut c, "581 A0 03 20 00 05 00 00 00"); // sc = 0, blksize 5
    expect(&mut c, &["601 81 AA AA AA AA AA AA AA"]);
    reply(&mut c, "581 A2 01 05 00 00 00 00 00");
    expect(&mut c, &["601 C1 00 00 00 00 00 00 00"]);
    assert_eq!(reply(&mut c, "581 A1 00 00 00 00 00 00 00").unwrap().result, Ok(7));
}

#[test]
fn block_download_resends_from_the_acknowledged_segment() {
    let data: Vec<u8> = (0..30).collect(); // 5 segments
    let mut c = Client::new(node(1));
    c.download(0x2003, 0, data.clone(), Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 A4 03 20 00 03 00 00 00"); // blocks of 3
    expect(&mut c, &["601 01 00 01 02 03 04 05 06", "601 02 07 08 09 0A 0B 0C 0D", "601 03 0E 0F 10 11 12 13 14"]);
    // Segment 2 was lost: the server confirms 1, asks for blocks of 2.
    reply(&mut c, "581 A2 01 02 00 00 00 00 00");
    expect(&mut c, &["601 01 07 08 09 0A 0B 0C 0D", "601 02 0E 0F 10 11 12 13 14"]);
    reply(&mut c, "581 A2 02 7F 00 00 00 00 00");
    expect(&mut c, &["601 01 15 16 17 18 19 1A 1B", "601 82 1C 1D 00 00 00 00 00"]);
    reply(&mut c, "581 A2 02 7F 00 00 00 00 00");
    let crc = crc16_ccitt(0, &data).to_le_bytes();
    expect(&mut c, &[&format!("601 D5 {:02X} {:02X} 00 00 00 00 00", crc[0], crc[1])]);
    assert_eq!(reply(&mut c, "581 A1 00 00 00 00 00 00 00").unwrap().result, Ok(30));
}

/// The server's frames of a block upload of `data` in blocks of `blksize`, CRC on.
fn block_upload_frames(data: &[u8], blksize: usize) -> Vec<Vec<String>> {
    let mut blocks = Vec::new();
    let segs: Vec<&[u8]> = if data.is_empty() { vec![&[][..]] } else { data.chunks(7).collect() };
    for (b, chunk) in segs.chunks(blksize).enumerate() {
        let mut frames = Vec::new();
        for (i, seg) in chunk.iter().enumerate() {
            let last = b * blksize + i + 1 == segs.len();
            let mut d = vec![(i + 1) as u8 | if last { 0x80 } else { 0 }];
            d.extend_from_slice(seg);
            d.resize(8, 0);
            frames.push(format!("581 {}", hex(&d)));
        }
        blocks.push(frames);
    }
    blocks
}

#[test]
fn block_upload_frames_with_crc() {
    let data: Vec<u8> = (100..120).collect(); // 20 bytes: 3 segments
    let mut c = Client::new(node(1));
    c.set_block_size(2);
    c.upload(0x2003, 0, vec![0; 64], Mode::Block, 0).unwrap();
    // ccs 5, cc = 1, blksize 2, pst 0.
    expect(&mut c, &["601 A4 03 20 00 02 00 00 00"]);
    reply(&mut c, "581 C6 03 20 00 14 00 00 00");
    expect(&mut c, &["601 A3 00 00 00 00 00 00 00"]);
    let blocks = block_upload_frames(&data, 2);
    for f in &blocks[0] {
        assert!(reply(&mut c, f).is_none());
    }
    expect(&mut c, &["601 A2 02 02 00 00 00 00 00"]);
    reply(&mut c, &blocks[1][0]);
    expect(&mut c, &["601 A2 01 02 00 00 00 00 00"]);
    let crc = crc16_ccitt(0, &data).to_le_bytes();
    // n = 1: one byte of the last segment unused.
    let d = reply(&mut c, &format!("581 C5 {:02X} {:02X} 00 00 00 00 00", crc[0], crc[1])).unwrap();
    assert_eq!(value(&d), &data[..]);
    expect(&mut c, &["601 A1 00 00 00 00 00 00 00"]);
}

#[test]
fn block_upload_lost_segment_is_asked_again() {
    let data: Vec<u8> = (0..21).collect(); // 3 full segments
    let mut c = Client::new(node(1));
    c.upload(0x2003, 0, vec![0; 21], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 C6 03 20 00 15 00 00 00");
    sent(&mut c, 0);
    let segs = &block_upload_frames(&data, 127)[0];
    reply(&mut c, &segs[0]);
    reply(&mut c, &segs[2]); // segment 2 lost; segment 3 ends the block
    expect(&mut c, &["601 A2 01 7F 00 00 00 00 00"]);
    // The server sends segments 2 and 3 again, numbered 1 and 2.
    let again = &block_upload_frames(&data[7..], 127)[0];
    reply(&mut c, &again[0]);
    reply(&mut c, &again[1]);
    expect(&mut c, &["601 A2 02 7F 00 00 00 00 00"]);
    let crc = crc16_ccitt(0, &data).to_le_bytes();
    let d = reply(&mut c, &format!("581 C1 {:02X} {:02X} 00 00 00 00 00", crc[0], crc[1])).unwrap();
    assert_eq!(value(&d), &data[..]);
}

#[test]
fn block_upload_crc_mismatch_aborts() {
    let mut c = Client::new(node(1));
    c.upload(0x2003, 0, vec![0; 8], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 C6 03 20 00 03 00 00 00");
    sent(&mut c, 0);
    reply(&mut c, "581 81 01 02 03 00 00 00 00");
    expect(&mut c, &["601 A2 01 7F 00 00 00 00 00"]);
    let good = crc16_ccitt(0, &[1, 2, 3]) ^ 1;
    let d = reply(&mut c, &format!("581 D1 {:02X} {:02X} 00 00 00 00 00", good as u8, good >> 8)).unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::CRC_ERROR)));
    expect(&mut c, &["601 80 03 20 00 04 00 04 05"]);
}

#[test]
fn block_upload_protocol_switch() {
    let mut c = Client::new(node(1));
    c.set_protocol_switch_threshold(4);
    c.upload(0x1000, 0, vec![0; 8], Mode::Block, 0).unwrap();
    expect(&mut c, &["601 A4 00 10 00 7F 04 00 00"]);
    let d = reply(&mut c, "581 43 00 10 00 92 01 02 00").unwrap();
    assert_eq!(value(&d), &[0x92, 1, 2, 0]);
    // Without a threshold and without the fallback, a normal answer to a block request is a
    // protocol error.
    c.set_protocol_switch_threshold(0);
    c.set_block_fallback(false);
    assert!(!c.block_fallback());
    c.upload(0x1000, 0, vec![0; 8], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    let d = reply(&mut c, "581 43 00 10 00 92 01 02 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_COMMAND)));
    expect(&mut c, &["601 80 00 10 00 01 00 04 05"]);
}

// A server without block transfers (python-canopen's LocalNode answers a block upload with a
// normal initiate upload response whatever the threshold, and aborts a block download with
// 0504 0001h).

#[test]
fn block_upload_answered_with_a_segmented_upload_continues_segmented() {
    let mut c = Client::new(node(1));
    assert!(c.block_fallback(), "the fallback is on by default");
    c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
    expect(&mut c, &["601 A4 03 20 00 7F 00 00 00"]);
    // Segmented, 10 bytes indicated.
    assert!(reply(&mut c, "581 41 03 20 00 0A 00 00 00").is_none());
    expect(&mut c, &["601 60 00 00 00 00 00 00 00"]);
    assert!(reply(&mut c, "581 00 01 02 03 04 05 06 07").is_none());
    expect(&mut c, &["601 70 00 00 00 00 00 00 00"]);
    let d = reply(&mut c, "581 19 08 09 0A 00 00 00 00").unwrap();
    assert_eq!(value(&d), (1..=10).collect::<Vec<u8>>());
    expect(&mut c, &[]);
    // Expedited.
    c.upload(0x1000, 0, vec![0; 8], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    let d = reply(&mut c, "581 43 00 10 00 92 01 02 00").unwrap();
    assert_eq!(value(&d), [0x92, 1, 2, 0]);
    // The size check of the normal upload holds: more than indicated aborts.
    c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 41 03 20 00 03 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 01 01 02 03 04 05 06 07").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::LENGTH_MISMATCH)));
    expect(&mut c, &["601 80 03 20 00 10 00 07 06"]);
    // A normal answer that does not indicate its size is what a block answer with bit 7
    // garbled looks like (C6h -> 46h: "expedited, 4 bytes" with the size as the value): the
    // fallback does not take it.
    for garbled in ["581 46 03 20 00 0A 00 00 00", "581 42 03 20 00 0A 00 00 00", "581 40 03 20 00 00 00 00 00"] {
        c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
        sent(&mut c, 0);
        let d = reply(&mut c, garbled).unwrap();
        assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_COMMAND)), "{garbled}");
        expect(&mut c, &["601 80 03 20 00 01 00 04 05"]);
    }
    // An answer about another object is still not this transfer's.
    c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    assert!(reply(&mut c, "581 41 08 10 00 0A 00 00 00").is_none());
    expect(&mut c, &[]);
}

#[test]
fn block_transfer_refused_with_0504_0001_starts_again_normal() {
    let mut c = Client::new(node(1));
    // Upload: the same object requested again, normal.
    c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
    expect(&mut c, &["601 A4 03 20 00 7F 00 00 00"]);
    assert!(reply(&mut c, "581 80 03 20 00 01 00 04 05").is_none());
    expect(&mut c, &["601 40 03 20 00 00 00 00 00"]);
    let d = reply(&mut c, "581 4B 03 20 00 34 12 00 00").unwrap();
    assert_eq!(value(&d), [0x34, 0x12]);
    // Download of 9 bytes: segmented.
    let data: Vec<u8> = (1..=9).collect();
    c.download(0x2003, 0, data, Mode::Block, 0).unwrap();
    expect(&mut c, &["601 C6 03 20 00 09 00 00 00"]);
    assert!(reply(&mut c, "581 80 03 20 00 01 00 04 05").is_none());
    expect(&mut c, &["601 21 03 20 00 09 00 00 00"]);
    reply(&mut c, "581 60 03 20 00 00 00 00 00");
    expect(&mut c, &["601 00 01 02 03 04 05 06 07"]);
    reply(&mut c, "581 20 00 00 00 00 00 00 00");
    expect(&mut c, &["601 1B 08 09 00 00 00 00 00"]);
    let d = reply(&mut c, "581 30 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Ok(9));
    // Download of 2 bytes: expedited.
    c.download(0x6040, 0, vec![0x0F, 0x00], Mode::Block, 0).unwrap();
    expect(&mut c, &["601 C6 40 60 00 02 00 00 00"]);
    reply(&mut c, "581 80 40 60 00 01 00 04 05");
    expect(&mut c, &["601 2B 40 60 00 0F 00 00 00"]);
    let d = reply(&mut c, "581 60 40 60 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Ok(2));
    // The timeout runs from the refusal: the restarted transfer has its own full timeout.
    c.set_timeout(1000);
    c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    c.on_frame(&frame("581 80 03 20 00 01 00 04 05"), 900);
    assert_eq!(sent(&mut c, 900), ["601 40 03 20 00 00 00 00 00"]);
    assert_eq!(c.deadline(), Some(1900));
    c.abort(AbortCode::GENERAL_ERROR).unwrap();
    sent(&mut c, 900);
}

#[test]
fn block_refusals_that_are_no_fallback() {
    let mut c = Client::new(node(1));
    let abort = |code: &str| format!("581 80 03 20 00 {code}");
    for (upload, fallback, answer, why) in [
        // Another abort code is the server's answer about the object.
        (true, true, abort("00 00 02 06"), "another code"),
        (false, true, abort("00 00 02 06"), "another code"),
        // 0504 0001h about another object is no refusal of this transfer.
        (true, true, "581 80 08 10 00 01 00 04 05".to_owned(), "another object"),
        (false, true, "581 80 08 10 00 01 00 04 05".to_owned(), "another object"),
        // With the fallback off, the refusal ends the transfer.
        (true, false, abort("01 00 04 05"), "fallback off"),
        (false, false, abort("01 00 04 05"), "fallback off"),
    ] {
        c.set_block_fallback(fallback);
        if upload {
            c.upload(0x2003, 0, vec![0; 16], Mode::Block, 0).unwrap();
        } else {
            c.download(0x2003, 0, vec![1; 9], Mode::Block, 0).unwrap();
        }
        sent(&mut c, 0);
        let d = reply(&mut c, &answer).unwrap_or_else(|| panic!("{why}: the transfer goes on"));
        let code = AbortCode(
            u32::from_str_radix(&answer[answer.len() - 11..].split(' ').rev().collect::<String>(), 16).unwrap(),
        );
        assert_eq!(d.result, Err(SdoError::Server(code)), "{why}");
        expect(&mut c, &[]);
    }
    // Past the initiate, 0504 0001h is an abort like any other: a block under way is not
    // started again.
    c.set_block_fallback(true);
    c.upload(0x2003, 0, vec![0; 64], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 C4 03 20 00 00 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 80 03 20 00 01 00 04 05").unwrap();
    assert_eq!(d.result, Err(SdoError::Server(AbortCode::INVALID_COMMAND)));
    c.download(0x2003, 0, vec![1; 9], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 A4 03 20 00 7F 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 80 03 20 00 01 00 04 05").unwrap();
    assert_eq!(d.result, Err(SdoError::Server(AbortCode::INVALID_COMMAND)));
    expect(&mut c, &[]);
}

#[test]
fn server_abort_ends_every_kind_of_transfer_without_a_frame() {
    for mode in [Mode::Normal, Mode::Segmented, Mode::Block] {
        for upload in [false, true] {
            let mut c = Client::new(node(1));
            if upload {
                c.upload(0x2003, 0, vec![0; 8], mode, 0).unwrap();
            } else {
                c.download(0x2003, 0, vec![0; 20], mode, 0).unwrap();
            }
            sent(&mut c, 0);
            let d = reply(&mut c, "581 80 03 20 00 00 00 02 06").unwrap();
            assert_eq!(d.result, Err(SdoError::Server(AbortCode::NO_OBJECT)));
            assert_eq!(d.buf.len(), if upload { 8 } else { 20 }, "the buffer comes back");
            expect(&mut c, &[]);
            assert_eq!(
                d.error().unwrap().to_string(),
                format!(
                    "node 1, {} 2003h sub 0: aborted by the server: 0x06020000 (object does not exist in the object dictionary)",
                    if upload { "upload of" } else { "download to" }
                )
            );
        }
    }
}

/// A segment queued in answer to one frame is not sent when the next frame, before the poll,
/// makes the client abort: the server gets the abort only, and cannot complete a download the
/// client reports as failed.
#[test]
fn an_abort_withdraws_the_segments_not_sent_yet() {
    let mut c = Client::new(node(1));
    c.download(0x2003, 0, (1..=8).collect(), Mode::Segmented, 0).unwrap();
    expect(&mut c, &["601 21 03 20 00 08 00 00 00"]);
    reply(&mut c, "581 60 03 20 00 00 00 00 00");
    expect(&mut c, &["601 00 01 02 03 04 05 06 07"]);
    // The answer, delivered twice: the first queues the last segment, the second (toggle 0
    // again) is a toggle error.
    assert!(reply(&mut c, "581 20 00 00 00 00 00 00 00").is_none());
    let d = reply(&mut c, "581 20 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::TOGGLE_BIT)));
    expect(&mut c, &["601 80 03 20 00 00 00 03 05"]);
    // The same in an upload: the next segment request is withdrawn.
    c.upload(0x2003, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 41 03 20 00 0A 00 00 00");
    sent(&mut c, 0);
    assert!(reply(&mut c, "581 00 01 02 03 04 05 06 07").is_none());
    let d = reply(&mut c, "581 00 01 02 03 04 05 06 07").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::TOGGLE_BIT)));
    expect(&mut c, &["601 80 03 20 00 00 00 03 05"]);
}

#[test]
fn wrong_toggle_bit_aborts() {
    let mut c = Client::new(node(1));
    c.upload(0x1008, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 41 08 10 00 15 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 10 6F 64 2D 72 75 6E 74").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::TOGGLE_BIT)));
    expect(&mut c, &["601 80 08 10 00 00 00 03 05"]);
    // And in a download: the segment response's toggle must echo the request's.
    c.download(0x2001, 0, b"hello world!".to_vec(), Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 60 01 20 00 00 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 30 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::TOGGLE_BIT)));
    expect(&mut c, &["601 80 01 20 00 00 00 03 05"]);
}

#[test]
fn sizes_that_do_not_match_abort() {
    let mut c = Client::new(node(1));
    // Announced 9 bytes, sent 10.
    c.upload(0x2001, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 41 01 20 00 09 00 00 00");
    sent(&mut c, 0);
    reply(&mut c, "581 00 01 02 03 04 05 06 07");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 15 08 09 0A 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::LENGTH_MISMATCH)));
    expect(&mut c, &["601 80 01 20 00 10 00 07 06"]);
    // Announced 9 bytes, sent 8.
    c.upload(0x2001, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 41 01 20 00 09 00 00 00");
    sent(&mut c, 0);
    reply(&mut c, "581 00 01 02 03 04 05 06 07");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 1D 08 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::LENGTH_MISMATCH)));
    // Announced more than the buffer holds: aborted at once.
    c.upload(0x2001, 0, vec![0; 4], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    let d = reply(&mut c, "581 41 01 20 00 09 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::OUT_OF_MEMORY)));
    expect(&mut c, &["601 80 01 20 00 05 00 04 05"]);
    // Not announced, and more than the buffer holds.
    c.upload(0x2001, 0, vec![0; 4], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 40 01 20 00 00 00 00 00");
    sent(&mut c, 0);
    let d = reply(&mut c, "581 03 01 02 03 04 05 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::OUT_OF_MEMORY)));
    // An expedited value larger than the buffer.
    c.upload(0x1000, 0, vec![0; 2], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    let d = reply(&mut c, "581 43 00 10 00 92 01 02 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::OUT_OF_MEMORY)));
    // A block upload whose end says more bytes than announced.
    c.upload(0x2003, 0, vec![0; 32], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 C6 03 20 00 05 00 00 00");
    sent(&mut c, 0);
    reply(&mut c, "581 81 01 02 03 04 05 06 00");
    sent(&mut c, 0);
    let crc = crc16_ccitt(0, &[1, 2, 3, 4, 5, 6]).to_le_bytes();
    let d = reply(&mut c, &format!("581 C5 {:02X} {:02X} 00 00 00 00 00", crc[0], crc[1])).unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::LENGTH_MISMATCH)));
}

#[test]
fn timeout_fires_exactly_at_the_deadline_and_names_node_and_object() {
    let mut c = Client::new(node(9));
    c.set_timeout(300_000);
    c.upload(0x6041, 0, vec![0; 4], Mode::Normal, 1_000).unwrap();
    assert_eq!(c.deadline(), Some(0), "the request is waiting to be sent");
    assert_eq!(sent(&mut c, 1_000), ["609 40 41 60 00 00 00 00 00"]);
    assert_eq!(c.deadline(), Some(301_000));
    assert_eq!(sent(&mut c, 300_999), Vec::<String>::new());
    let mut out = Vec::new();
    let d = c.poll(301_000, &mut |f| out.push(f.to_string())).expect("timed out");
    assert_eq!(out, ["609 80 41 60 00 00 00 04 05"]);
    assert!(d.result.unwrap_err().is_timeout());
    assert_eq!(
        d.error().unwrap().to_string(),
        "node 9, upload of 6041h sub 0: aborted by the client: 0x05040000 (SDO protocol timed out)"
    );
    assert_eq!(c.deadline(), None);
    // Each answer restarts the wait: a slow segmented upload that always answers in time
    // completes.
    c.upload(0x1008, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    let mut now = 0;
    for resp in ["589 41 08 10 00 08 00 00 00", "589 00 01 02 03 04 05 06 07"] {
        sent(&mut c, now);
        now += 299_000;
        assert!(c.on_frame(&frame(resp), now).is_none());
    }
    sent(&mut c, now);
    now += 299_000;
    assert_eq!(c.on_frame(&frame("589 1D 08 00 00 00 00 00 00"), now).unwrap().result, Ok(8));
    // 0 waits forever.
    c.set_timeout(0);
    c.upload(0x1000, 0, vec![0; 4], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    assert_eq!(c.deadline(), None);
    assert!(c.poll(u64::MAX, &mut |_| {}).is_none());
}

#[test]
fn unexpected_and_foreign_frames() {
    let mut c = Client::new(node(1));
    // Idle: everything is ignored.
    assert!(reply(&mut c, "581 43 00 10 00 92 01 02 00").is_none());
    c.upload(0x1008, 0, vec![0; 32], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    // Other COB-IDs, remote frames, short frames, and an answer about another object (a late
    // answer to an earlier request) are not this transfer's.
    for f in [
        "582 41 08 10 00 15 00 00 00",
        "601 41 08 10 00 15 00 00 00",
        "581 R8",
        "581 41 08 10",
        "581 43 00 10 00 92 01 02 00",
    ] {
        assert!(reply(&mut c, f).is_none(), "{f}");
        expect(&mut c, &[]);
    }
    reply(&mut c, "581 41 08 10 00 15 00 00 00");
    sent(&mut c, 0);
    // A download segment response during an upload.
    let d = reply(&mut c, "581 20 00 00 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_COMMAND)));
    expect(&mut c, &["601 80 08 10 00 01 00 04 05"]);
    // An unknown command specifier during a download.
    c.download(0x6040, 0, vec![6, 0], Mode::Normal, 0).unwrap();
    sent(&mut c, 0);
    let d = reply(&mut c, "581 E0 40 60 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_COMMAND)));
    // A block size of 0 or above 127.
    for bad in ["00", "80"] {
        c.download(0x2003, 0, vec![1; 9], Mode::Block, 0).unwrap();
        sent(&mut c, 0);
        let d = reply(&mut c, &format!("581 A4 03 20 00 {bad} 00 00 00")).unwrap();
        assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_BLOCK_SIZE)));
    }
    // A block acknowledgement for more segments than were sent.
    c.download(0x2003, 0, vec![1; 9], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 A4 03 20 00 7F 00 00 00");
    assert_eq!(sent(&mut c, 0).len(), 2);
    let d = reply(&mut c, "581 A2 03 7F 00 00 00 00 00").unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_SEQUENCE)));
    // A block upload segment numbered 0 or past the block size.
    c.set_block_size(4);
    for bad in ["05", "00"] {
        c.upload(0x2003, 0, vec![0; 64], Mode::Block, 0).unwrap();
        sent(&mut c, 0);
        reply(&mut c, "581 C4 03 20 00 00 00 00 00");
        sent(&mut c, 0);
        let d = reply(&mut c, &format!("581 {bad} 01 02 03 04 05 06 07")).unwrap();
        assert_eq!(d.result, Err(SdoError::Client(AbortCode::INVALID_SEQUENCE)), "{bad}");
    }
}

#[test]
fn busy_channel_rejects_and_local_abort() {
    let mut c = Client::new(node(3));
    c.upload(0x1000, 0, vec![0; 4], Mode::Normal, 0).unwrap();
    let r = c.upload(0x1001, 0, vec![7; 2], Mode::Normal, 0).unwrap_err();
    assert_eq!((r.reason, r.buf), (Reject::Busy, vec![7; 2]));
    let r = c.download(0x1001, 0, vec![7; 2], Mode::Normal, 0).unwrap_err();
    assert_eq!(r.reason, Reject::Busy);
    let d = c.abort(AbortCode::GENERAL_ERROR).unwrap();
    assert_eq!(d.result, Err(SdoError::Client(AbortCode::GENERAL_ERROR)));
    assert!(c.abort(AbortCode::GENERAL_ERROR).is_none(), "nothing left to abort");
    // The abort goes out before the next transfer's request, both at the next poll.
    c.upload(0x1001, 0, vec![0; 1], Mode::Normal, 0).unwrap();
    // The aborted transfer never reached the bus, so nothing of it is sent.
    expect(&mut c, &["603 40 01 10 00 00 00 00 00"]);
    // Once its request went out, an abort is sent.
    let d = c.abort(AbortCode::DEVICE_STATE).unwrap();
    assert_eq!(d.index, 0x1001);
    expect(&mut c, &["603 80 01 10 00 22 00 00 08"]);
}

#[test]
fn other_sdo_channel_cob_ids() {
    let mut c: Client = SdoClient::with_cob_ids(node(4), 0x640, 0x5C0);
    assert_eq!(c.cob_ids(), (0x640, 0x5C0));
    c.upload(0x1000, 0, vec![0; 4], Mode::Normal, 0).unwrap();
    expect(&mut c, &["640 40 00 10 00 00 00 00 00"]);
    assert!(reply(&mut c, "584 43 00 10 00 01 02 03 04").is_none());
    assert_eq!(value(&reply(&mut c, "5C0 43 00 10 00 01 02 03 04").unwrap()), &[1, 2, 3, 4]);
}

#[test]
fn abort_codes_have_their_cia_301_names() {
    assert_eq!(AbortCode::TOGGLE_BIT.to_string(), "0x05030000 (toggle bit not alternated)");
    assert_eq!(
        AbortCode(0x0800_0022).name(),
        Some("data cannot be transferred or stored to the application because of the present device state")
    );
    assert_eq!(AbortCode(0x1234_5678).to_string(), "0x12345678 (unknown abort code)");
    // Every code the device side defines has a name.
    for c in [
        AbortCode::TIMEOUT,
        AbortCode::INVALID_COMMAND,
        AbortCode::INVALID_BLOCK_SIZE,
        AbortCode::INVALID_SEQUENCE,
        AbortCode::CRC_ERROR,
        AbortCode::OUT_OF_MEMORY,
        AbortCode::UNSUPPORTED_ACCESS,
        AbortCode::WRITE_ONLY,
        AbortCode::READ_ONLY,
        AbortCode::NO_OBJECT,
        AbortCode::NOT_MAPPABLE,
        AbortCode::PDO_LENGTH_EXCEEDED,
        AbortCode::PARAMETER_INCOMPATIBLE,
        AbortCode::INTERNAL_INCOMPATIBLE,
        AbortCode::HARDWARE_ERROR,
        AbortCode::LENGTH_MISMATCH,
        AbortCode::LENGTH_TOO_HIGH,
        AbortCode::LENGTH_TOO_LOW,
        AbortCode::NO_SUB_INDEX,
        AbortCode::INVALID_VALUE,
        AbortCode::VALUE_TOO_HIGH,
        AbortCode::VALUE_TOO_LOW,
        AbortCode::MAX_LESS_THAN_MIN,
        AbortCode::NO_SDO_CONNECTION,
        AbortCode::GENERAL_ERROR,
        AbortCode::CANNOT_STORE,
        AbortCode::LOCAL_CONTROL,
        AbortCode::DEVICE_STATE,
        AbortCode::NO_DICTIONARY,
        AbortCode::NO_DATA,
    ] {
        assert!(c.name().is_some(), "{c:?}");
    }
}

// ---- against the project's own SDO server, in virtual time -----------------------------------

/// A client and the test device on one virtual bus. `fault` sees every frame (and which way
/// it goes) and returns how many copies to deliver: 0 loses it, 2 repeats it.
struct Link {
    h: Harness,
    c: Client,
    step: Micros,
    /// The last frames, both ways (for failure messages).
    log: std::collections::VecDeque<String>,
}

impl Link {
    fn new() -> Self {
        Self { h: Harness::new(), c: Client::new(node(NODE)), step: 100, log: Default::default() }
    }

    fn note(&mut self, s: String) {
        if self.log.len() == 40 {
            self.log.pop_front();
        }
        self.log.push_back(s);
    }

    /// Runs until the transfer ends (at most `limit` of virtual time), then lets the last
    /// frames reach the device.
    fn run(&mut self, limit: Micros, mut fault: impl FnMut(&Frame, bool) -> usize) -> Done<Vec<u8>> {
        let end = self.h.now + limit;
        let mut done = None;
        while done.is_none() {
            assert!(self.h.now <= end, "no end within {limit} us; last frames: {:#?}", self.log);
            let mut to_dev = Vec::new();
            done = self.c.poll(self.h.now, &mut |f| to_dev.push(f));
            for f in to_dev {
                self.note(format!("-> {f}"));
                for _ in 0..fault(&f, true) {
                    self.h.dev.on_frame(&f, self.h.now);
                }
            }
            let mut to_cli = Vec::new();
            self.h.dev.poll(self.h.now, |f| to_cli.push(f));
            for f in to_cli {
                self.note(format!("<- {f}"));
                for _ in 0..fault(&f, false) {
                    if let Some(d) = self.c.on_frame(&f, self.h.now) {
                        assert!(done.is_none(), "a transfer ended twice");
                        done = Some(d);
                    }
                }
            }
            self.h.now += self.step;
        }
        // The client's last frame (a block upload's end response, an abort).
        let mut to_dev = Vec::new();
        assert!(self.c.poll(self.h.now, &mut |f| to_dev.push(f)).is_none());
        for f in to_dev {
            self.note(format!("-> {f}"));
            self.h.dev.on_frame(&f, self.h.now);
        }
        let mut last = Vec::new();
        self.h.dev.poll(self.h.now, |f| last.push(format!("<- {f}")));
        for f in last {
            self.note(f);
        }
        done.unwrap()
    }

    fn read(&mut self, index: u16, sub: u8, cap: usize, mode: Mode) -> Result<Vec<u8>, SdoError> {
        self.c.upload(index, sub, vec![0; cap], mode, self.h.now).unwrap();
        let d = self.run(10_000_000, |_, _| 1);
        d.result.map(|n| d.buf[..n].to_vec())
    }

    fn write(&mut self, index: u16, sub: u8, data: &[u8], mode: Mode) -> Result<usize, SdoError> {
        self.c.download(index, sub, data.to_vec(), mode, self.h.now).unwrap();
        self.run(10_000_000, |_, _| 1).result
    }
}

const MODES: [Mode; 3] = [Mode::Normal, Mode::Segmented, Mode::Block];

#[test]
fn every_transfer_kind_against_the_device() {
    let mut l = Link::new();
    for mode in MODES {
        // 1..=4 bytes (expedited in normal mode), 8 bytes, strings, and a 1000-byte DOMAIN.
        l.write(0x6040, 0, &[0x0F, 0x00], mode).unwrap();
        assert_eq!(l.h.od().get(0x6040, 0), 0x0F);
        assert_eq!(l.read(0x6040, 0, 2, mode).unwrap(), [0x0F, 0x00]);
        l.write(0x2002, 0, &0x1122_3344_5566_7788u64.to_le_bytes(), mode).unwrap();
        assert_eq!(l.read(0x2002, 0, 8, mode).unwrap(), 0x1122_3344_5566_7788u64.to_le_bytes());
        assert_eq!(l.read(0x1008, 0, 64, mode).unwrap(), b"od-runtime test drive");
        l.write(0x2001, 0, b"hello world!", mode).unwrap();
        assert_eq!(l.read(0x2001, 0, 32, mode).unwrap(), b"hello world!");
        for len in [0usize, 1, 6, 7, 8, 13, 14, 15, 889, 890, 1000, 1024] {
            let data: Vec<u8> = (0..len).map(|i| (i * 7 + len) as u8).collect();
            assert_eq!(l.write(0x2003, 0, &data, mode), Ok(len), "{mode:?} {len}");
            assert_eq!(l.h.od().bytes(0x2003, 0), data, "{mode:?} {len}");
            assert_eq!(l.read(0x2003, 0, 1024, mode).unwrap(), data, "{mode:?} {len}");
        }
    }
    // Small client block sizes.
    let data: Vec<u8> = (0..1000).map(|i| (i % 251) as u8).collect();
    l.write(0x2003, 0, &data, Mode::Block).unwrap();
    for blksize in [1, 2, 5, 126] {
        l.c.set_block_size(blksize);
        assert_eq!(l.read(0x2003, 0, 1000, Mode::Block).unwrap(), data);
    }
}

#[test]
fn device_aborts_reach_the_caller_with_their_codes() {
    let mut l = Link::new();
    for mode in MODES {
        assert_eq!(l.read(0x5000, 0, 8, mode), Err(SdoError::Server(AbortCode::NO_OBJECT)));
        assert_eq!(l.read(0x1018, 9, 8, mode), Err(SdoError::Server(AbortCode::NO_SUB_INDEX)));
        assert_eq!(l.read(0x2006, 0, 8, mode), Err(SdoError::Server(AbortCode::WRITE_ONLY)));
        assert_eq!(l.write(0x1000, 0, &[1, 2, 3, 4], mode), Err(SdoError::Server(AbortCode::READ_ONLY)));
        assert_eq!(l.write(0x2005, 0, &[101], mode), Err(SdoError::Server(AbortCode::VALUE_TOO_HIGH)));
        // Larger than the device's 1 KiB SDO buffer.
        assert_eq!(l.write(0x2003, 0, &[0; 1100], mode), Err(SdoError::Server(AbortCode::OUT_OF_MEMORY)));
        // Larger than the client's buffer: the client aborts, and the device takes the next
        // transfer.
        assert_eq!(l.read(0x1008, 0, 8, mode), Err(SdoError::Client(AbortCode::OUT_OF_MEMORY)));
        assert_eq!(l.read(0x1000, 0, 4, mode).unwrap(), [0x92, 0x01, 0x02, 0x00]);
    }
}

#[test]
fn node_that_disappears_mid_transfer_times_out_and_the_next_transfer_works() {
    for mode in MODES {
        let mut l = Link::new();
        let data: Vec<u8> = (0..300).map(|i| i as u8).collect();
        l.write(0x2003, 0, &data, Mode::Normal).unwrap();
        l.c.set_timeout(500_000);
        l.c.upload(0x2003, 0, vec![0; 300], mode, l.h.now).unwrap();
        let mut frames = 0;
        let d = l.run(2_000_000, |_, _| {
            frames += 1;
            usize::from(frames <= 4)
        });
        let e = d.error().unwrap();
        assert!(e.error.is_timeout(), "{mode:?}: {e}");
        assert_eq!((e.node, e.index, e.sub), (1, 0x2003, 0));
        // A retry is a new transfer from its start, and it completes.
        assert_eq!(l.read(0x2003, 0, 300, mode).unwrap(), data, "{mode:?}");
    }
}

#[test]
#[cfg(feature = "sdo-block")]
fn lost_block_segments_are_sent_again() {
    let data: Vec<u8> = (0..1000).map(|i| (i * 13) as u8).collect();
    // Any segment but the one that ends a block (the 127th, the 143rd and last): the receiver
    // answers only that one, so losing it is a timeout (below).
    for lose in [1usize, 2, 50, 126, 128, 142] {
        let mut l = Link::new();
        // Download: the device asks again for what it missed.
        l.c.download(0x2003, 0, data.clone(), Mode::Block, 0).unwrap();
        let mut n = 0;
        let d = l.run(5_000_000, |f, to_dev| {
            if to_dev && f.data()[0] & 0x7F != 0 && !matches!(f.data()[0], 0xC6 | 0xD1 | 0xC1) {
                n += 1;
                return usize::from(n != lose);
            }
            1
        });
        assert_eq!(d.result, Ok(1000), "lose {lose}: {:#?}", l.log);
        assert_eq!(l.h.od().bytes(0x2003, 0), data);
        // Upload: the client asks again.
        l.c.upload(0x2003, 0, vec![0; 1000], Mode::Block, l.h.now).unwrap();
        let mut n = 0;
        let mut started = false;
        let d = l.run(5_000_000, |f, to_dev| {
            if to_dev && f.data()[0] == 0xA3 {
                started = true;
            }
            if !to_dev && started {
                n += 1;
                return usize::from(n != lose);
            }
            1
        });
        assert_eq!(d.buf[..d.result.unwrap()], data[..], "lose {lose}");
    }
}

#[test]
#[cfg(feature = "sdo-block")]
fn lost_block_end_segment_times_out() {
    let data = vec![0x55; 1000];
    for lose in [127usize, 143] {
        let mut l = Link::new();
        l.c.set_timeout(100_000);
        l.c.download(0x2003, 0, data.clone(), Mode::Block, 0).unwrap();
        let mut n = 0;
        let d = l.run(5_000_000, |f, to_dev| {
            if to_dev && f.data()[0] & 0x7F != 0 && !matches!(f.data()[0], 0xC6 | 0xD1 | 0xC1) {
                n += 1;
                return usize::from(n != lose);
            }
            1
        });
        assert!(d.result.unwrap_err().is_timeout(), "lose {lose}");
        // The device is free for the retry.
        l.c.download(0x2003, 0, data.clone(), Mode::Block, l.h.now).unwrap();
        assert_eq!(l.run(5_000_000, |_, _| 1).result, Ok(1000));
    }
}

#[test]
fn block_transfers_that_never_progress_are_aborted() {
    // A server that acknowledges nothing, block after block.
    let mut c = Client::new(node(1));
    c.download(0x2003, 0, vec![1; 20], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 A4 03 20 00 7F 00 00 00");
    let mut done = None;
    let mut rounds = 0;
    while done.is_none() {
        assert_eq!(sent(&mut c, 0).len(), 3);
        rounds += 1;
        done = reply(&mut c, "581 A2 00 7F 00 00 00 00 00");
    }
    assert_eq!(rounds, MAX_STALLED_BLOCKS);
    assert_eq!(done.unwrap().result, Err(SdoError::Client(AbortCode::GENERAL_ERROR)));
    expect(&mut c, &["601 80 03 20 00 00 00 00 08"]);
    // A bus that always loses the first segment of a block upload.
    c.set_block_size(2);
    c.upload(0x2003, 0, vec![0; 64], Mode::Block, 0).unwrap();
    sent(&mut c, 0);
    reply(&mut c, "581 C4 03 20 00 00 00 00 00");
    sent(&mut c, 0);
    let mut acks = 0;
    loop {
        let d = reply(&mut c, "581 02 01 02 03 04 05 06 07");
        if let Some(d) = d {
            assert_eq!(d.result, Err(SdoError::Client(AbortCode::GENERAL_ERROR)));
            break;
        }
        assert_eq!(sent(&mut c, 0), ["601 A2 00 02 00 00 00 00 00"]);
        acks += 1;
    }
    assert_eq!(acks, MAX_STALLED_BLOCKS - 1);
}

/// Frames on a faulty bus: each frame lost, repeated or passed, plus foreign traffic.
#[derive(Clone, Debug)]
struct Faults {
    /// Per frame, in order: 0 lost, 1 passed, 2 repeated (cycled).
    fate: Vec<u8>,
    /// Foreign frames injected before each client frame (ids outside the SDO channel).
    noise: Vec<(u16, Vec<u8>)>,
}

fn faults() -> impl Strategy<Value = Faults> {
    let fate = prop::collection::vec(prop_oneof![8 => Just(1u8), 1 => Just(0u8), 1 => Just(2u8)], 1..64);
    let id = prop_oneof![Just(0x080u16), 0x081u16..0x100, 0x700u16..0x800, 0x582u16..0x600, 0x602u16..0x680];
    let noise = prop::collection::vec((id, prop::collection::vec(any::<u8>(), 0..=8)), 0..16);
    (fate, noise).prop_map(|(fate, noise)| Faults { fate, noise })
}

fn mode() -> impl Strategy<Value = Mode> {
    prop_oneof![Just(Mode::Normal), Just(Mode::Segmented), Just(Mode::Block)]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// Whatever the bus loses or repeats, a transfer that completes moved exactly the right
    /// bytes, and the next transfer on a clean bus works.
    #[test]
    fn faulty_bus_never_yields_a_wrong_value(
        data in prop::collection::vec(any::<u8>(), 0..300),
        write_mode in mode(),
        read_mode in mode(),
        blksize in 1u8..=127,
        f in faults(),
    ) {
        let mut l = Link::new();
        l.c.set_timeout(200_000);
        l.c.set_block_size(blksize);
        let before = l.h.od().bytes(0x2003, 0);
        let mut i = 0usize;
        let noise = f.noise.clone();
        let mut fate = |_: &Frame, _: bool| {
            i += 1;
            usize::from(f.fate[i % f.fate.len()])
        };
        l.c.download(0x2003, 0, data.clone(), write_mode, l.h.now).unwrap();
        for (id, d) in &noise {
            l.h.dev.on_frame(&Frame::new(*id, d).unwrap(), l.h.now);
            if let Some(x) = l.c.on_frame(&Frame::new(*id, d).unwrap(), l.h.now) {
                prop_assert!(false, "a foreign frame ended the transfer: {x:?}");
            }
        }
        let d = l.run(60_000_000, &mut fate);
        let stored = l.h.od().bytes(0x2003, 0);
        match d.result {
            Ok(n) => {
                prop_assert_eq!(n, data.len());
                prop_assert_eq!(&stored, &data);
            }
            // A failed write may or may not have reached the device (its answer may be the
            // frame that was lost), but the device holds one value or the other.
            Err(_) => prop_assert!(stored == data || stored == before),
        }
        let value = l.h.od().bytes(0x2003, 0);
        l.c.upload(0x2003, 0, vec![0; 300], read_mode, l.h.now).unwrap();
        let d = l.run(60_000_000, &mut fate);
        if let Ok(n) = d.result {
            prop_assert_eq!(&d.buf[..n], &value[..]);
        }
        // A clean retry completes once the device has given up on what the bus lost (an abort
        // that never arrived leaves it waiting for its own SDO timeout, 1 s).
        l.h.advance(1_000_000);
        prop_assert_eq!(l.read(0x2003, 0, 300, read_mode).unwrap(), value);
    }

    /// One bit flipped anywhere in the server's frames of a block upload: the CRC, the
    /// sequence numbers and the size indication catch it, or the transfer fails; it never
    /// completes with a wrong value.
    #[test]
    #[cfg(feature = "sdo-block")]
    fn block_upload_detects_a_flipped_bit(
        data in prop::collection::vec(any::<u8>(), 1..300),
        which in any::<prop::sample::Index>(),
        bit in 0u8..64,
    ) {
        let mut l = Link::new();
        l.write(0x2003, 0, &data, Mode::Normal).unwrap();
        l.c.set_timeout(200_000);
        l.c.upload(0x2003, 0, vec![0; 300], Mode::Block, l.h.now).unwrap();
        let total = 4 + data.len().div_ceil(7);
        let target = which.index(total);
        let mut n = 0;
        let mut flipped = None;
        let mut d = None;
        // Deliver by hand so the frame can be changed.
        for _ in 0..20_000 {
            let now = l.h.now;
            let mut to_dev = Vec::new();
            if let Some(x) = l.c.poll(now, &mut |f| to_dev.push(f)) { d = Some(x); break; }
            for f in to_dev { l.h.dev.on_frame(&f, now); }
            let mut to_cli = Vec::new();
            l.h.dev.poll(now, |f| to_cli.push(f));
            for f in to_cli {
                let mut f = f;
                if n == target && f.len() == 8 {
                    let mut raw = *f.raw();
                    raw[usize::from(bit / 8)] ^= 1 << (bit % 8);
                    f = Frame::new(f.id(), &raw).unwrap();
                    flipped = Some(f);
                }
                n += 1;
                if let Some(x) = l.c.on_frame(&f, now) { d = Some(x); }
            }
            if d.is_some() { break; }
            l.h.now += 100;
        }
        let d = d.expect("the transfer ends");
        if let Ok(len) = d.result {
            prop_assert_eq!(&d.buf[..len], &data[..], "flipped {:?}", flipped);
        }
    }

    /// Any frames at all, at any time, in any state: nothing panics, a transfer ends at most
    /// once, and an upload never claims more bytes than its buffer.
    #[test]
    fn random_frames_never_panic(
        upload in any::<bool>(),
        m in mode(),
        cap in 0usize..40,
        frames in prop::collection::vec((prop::bool::weighted(0.8), 0usize..=8, any::<[u8; 8]>(), 0u64..400_000), 0..60),
    ) {
        let mut c = Client::new(node(1));
        c.set_timeout(300_000);
        c.set_block_size(3);
        let buf: Vec<u8> = (0..cap as u8).collect();
        if upload {
            c.upload(0x2003, 0, vec![0; cap], m, 0).unwrap();
        } else {
            c.download(0x2003, 0, buf.clone(), m, 0).unwrap();
        }
        let mut now = 0u64;
        let mut ended = 0;
        for (ours, len, data, dt) in frames {
            now += dt;
            let id = if ours { 0x581 } else { 0x5A1 };
            let f = Frame::new(id, &data[..len]).unwrap();
            let mut done = c.on_frame(&f, now);
            if done.is_none() {
                done = c.poll(now, &mut |f| assert!(f.id() == 0x601 && f.len() == 8));
            }
            if let Some(d) = done {
                ended += 1;
                prop_assert_eq!(d.buf.len(), cap);
                if let Ok(n) = d.result {
                    prop_assert!(n <= cap);
                    if !upload {
                        prop_assert_eq!(n, cap);
                        prop_assert_eq!(&d.buf, &buf);
                    }
                }
            }
        }
        prop_assert!(ended <= 1);
        prop_assert_eq!(ended == 1, c.is_idle());
    }
}

/// How a server without block transfers answers a block initiate request.
#[derive(Clone, Copy, Debug)]
enum NoBlock {
    /// Like python-canopen's `LocalNode`: a block upload is answered as a normal upload, a
    /// block download refused with 0504 0001h.
    Switch,
    /// Both refused with 0504 0001h.
    Refuse,
}

/// The test device behind a filter that takes its block transfers away; `fate` loses (0),
/// passes (1) or repeats (2) each frame. Runs until the transfer ends, then lets the client's
/// last frames (an abort) reach the device.
fn run_without_block(l: &mut Link, how: NoBlock, fate: impl FnMut() -> usize) -> Done<Vec<u8>> {
    let d = run_without_block_until_done(l, how, fate);
    let mut last = Vec::new();
    assert!(l.c.poll(l.h.now, &mut |f| last.push(f)).is_none());
    for f in last {
        l.note(format!("-> {f}"));
        l.h.dev.on_frame(&f, l.h.now);
    }
    l.h.dev.poll(l.h.now, |_| {});
    d
}

fn run_without_block_until_done(l: &mut Link, how: NoBlock, mut fate: impl FnMut() -> usize) -> Done<Vec<u8>> {
    let end = l.h.now + 60_000_000;
    loop {
        assert!(l.h.now <= end, "no end; last frames: {:#?}", l.log);
        let now = l.h.now;
        let mut to_dev = Vec::new();
        if let Some(d) = l.c.poll(now, &mut |f| to_dev.push(f)) {
            return d;
        }
        let mut to_cli = Vec::new();
        for f in to_dev {
            l.note(format!("-> {f}"));
            let d = *f.raw();
            let block_init = f.len() == 8 && ((d[0] & 0xE3 == 0xA0) || (d[0] & 0xE1 == 0xC0));
            for _ in 0..fate() {
                match (block_init, d[0] & 0xE0 == 0xA0, how) {
                    (true, true, NoBlock::Switch) => {
                        l.h.dev.on_frame(&Frame::new(f.id(), &[0x40, d[1], d[2], d[3], 0, 0, 0, 0]).unwrap(), now);
                    }
                    (true, _, _) => {
                        let abort = [0x80, d[1], d[2], d[3], 0x01, 0x00, 0x04, 0x05];
                        to_cli.push(Frame::new(0x580 + u16::from(NODE), &abort).unwrap());
                    }
                    (false, _, _) => l.h.dev.on_frame(&f, now),
                }
            }
        }
        l.h.dev.poll(now, |f| to_cli.push(f));
        for f in to_cli {
            l.note(format!("<- {f}"));
            for _ in 0..fate() {
                if let Some(d) = l.c.on_frame(&f, now) {
                    return d;
                }
            }
        }
        l.h.now += l.step;
    }
}

#[test]
fn block_transfers_with_a_server_without_them_move_every_size() {
    for how in [NoBlock::Switch, NoBlock::Refuse] {
        let mut l = Link::new();
        for len in [1usize, 2, 4, 5, 7, 8, 13, 14, 15, 100, 889, 1000, 1024] {
            let data: Vec<u8> = (0..len).map(|i| (i * 13 + len) as u8).collect();
            l.c.download(0x2003, 0, data.clone(), Mode::Block, l.h.now).unwrap();
            let d = run_without_block(&mut l, how, || 1);
            assert_eq!(d.result, Ok(len), "{how:?} {len}: {:#?}", l.log);
            assert_eq!(l.h.od().bytes(0x2003, 0), data, "{how:?} {len}");
            l.c.upload(0x2003, 0, vec![0; 1024], Mode::Block, l.h.now).unwrap();
            let d = run_without_block(&mut l, how, || 1);
            assert_eq!(value(&d), &data[..], "{how:?} {len}");
        }
        l.c.upload(0x1008, 0, vec![0; 64], Mode::Block, l.h.now).unwrap();
        let d = run_without_block(&mut l, how, || 1);
        assert_eq!(value(&d), b"od-runtime test drive");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// A server without block transfers on a bus that loses and repeats frames: a block
    /// transfer that completes moved exactly the right bytes.
    #[test]
    fn block_fallback_on_a_faulty_bus_never_yields_a_wrong_value(
        data in prop::collection::vec(any::<u8>(), 1..300),
        refuse in any::<bool>(),
        f in faults(),
    ) {
        let how = if refuse { NoBlock::Refuse } else { NoBlock::Switch };
        let mut l = Link::new();
        l.c.set_timeout(200_000);
        let before = l.h.od().bytes(0x2003, 0);
        let mut i = 0usize;
        let mut fate = || {
            i += 1;
            usize::from(f.fate[i % f.fate.len()])
        };
        l.c.download(0x2003, 0, data.clone(), Mode::Block, l.h.now).unwrap();
        let d = run_without_block(&mut l, how, &mut fate);
        let stored = l.h.od().bytes(0x2003, 0);
        match d.result {
            Ok(n) => {
                prop_assert_eq!(n, data.len());
                prop_assert_eq!(&stored, &data);
            }
            Err(_) => prop_assert!(stored == data || stored == before),
        }
        l.c.upload(0x2003, 0, vec![0; 300], Mode::Block, l.h.now).unwrap();
        let d = run_without_block(&mut l, how, &mut fate);
        if let Ok(n) = d.result {
            prop_assert_eq!(&d.buf[..n], &stored[..], "{:#?}", l.log);
        }
    }
}

// ---- NMT -------------------------------------------------------------------------------------

#[test]
fn nmt_command_frames() {
    let all = [
        (NmtCommand::Start, 0x01),
        (NmtCommand::Stop, 0x02),
        (NmtCommand::EnterPreOperational, 0x80),
        (NmtCommand::ResetNode, 0x81),
        (NmtCommand::ResetCommunication, 0x82),
    ];
    for (cmd, cs) in all {
        for target in [Target::All, Target::Node(node(5)), Target::Node(node(127))] {
            let f = nmt::command(cmd, target);
            assert_eq!(f.to_string(), format!("000 {cs:02X} {:02X}", target.byte()));
            assert_eq!(nmt::decode(&f), Some((cmd, target)));
        }
        assert_eq!(NmtCommand::from_byte(cmd.code()), Some(cmd));
    }
    assert_eq!(nmt::decode(&frame("000 03 05")), None);
    assert_eq!(nmt::decode(&frame("000 01 80")), None);
    assert_eq!(nmt::decode(&frame("000 01")), None);
    assert!(Target::All.includes(node(9)) && !Target::Node(node(8)).includes(node(9)));
}

#[test]
fn nmt_commands_drive_the_device() {
    let mut h = Harness::new();
    for (cmd, target) in [
        (NmtCommand::Start, Target::Node(node(NODE))),
        (NmtCommand::Stop, Target::All),
        (NmtCommand::EnterPreOperational, Target::Node(node(NODE))),
        (NmtCommand::Start, Target::Node(node(2))), // another node's: no change
    ] {
        let before = h.dev.nmt_state();
        h.dev.on_frame(&nmt::command(cmd, target), h.now);
        let want = if target.includes(node(NODE)) { nmt::state_after(cmd) } else { before };
        assert_eq!(h.dev.nmt_state(), want, "{cmd:?} {target:?}");
    }
    h.dev.on_frame(&nmt::command(NmtCommand::ResetCommunication, Target::All), h.now);
    assert_eq!(h.poll(), ["701 00"]);
    assert_eq!(h.dev.nmt_state(), nmt::state_after(NmtCommand::ResetCommunication));
}

// ---- heartbeat consumer, node guarding, master heartbeat --------------------------------------

/// A monitor and the device in virtual time; returns the events of `us` microseconds.
fn run_monitor<const N: usize>(
    h: &mut Harness,
    m: &mut NodeMonitor<N>,
    us: Micros,
    mut pass: impl FnMut(&Frame) -> bool,
) -> Vec<(Micros, NodeEvent)> {
    let mut events = Vec::new();
    let end = h.now + us;
    while h.now < end {
        h.now += 1_000;
        let mut to_dev = Vec::new();
        m.poll(h.now, |f| to_dev.push(f), |e| events.push((h.now, e)));
        for f in to_dev {
            if pass(&f) {
                h.dev.on_frame(&f, h.now);
            }
        }
        let mut to_m = Vec::new();
        h.dev.poll(h.now, |f| to_m.push(f));
        for f in to_m {
            if pass(&f)
                && let Some(e) = m.on_frame(&f, h.now)
            {
                events.push((h.now, e));
            }
        }
    }
    events
}

#[test]
fn heartbeat_consumer_first_seen_state_lost_recovered_boot_up() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x1017, 0, &[100, 0]); // 100 ms
    let mut m = NodeMonitor::<4>::new();
    m.watch(node(NODE), Watch::Heartbeat { timeout: 150_000 }, Some(1_000_000), h.now).unwrap();
    assert_eq!(m.state(node(NODE)), None);
    let ev = run_monitor(&mut h, &mut m, 250_000, |_| true);
    assert_eq!(
        ev.iter().map(|e| e.1).collect::<Vec<_>>(),
        [NodeEvent::FirstSeen { node: 1, state: NmtState::PreOperational }]
    );
    assert!(m.is_alive(node(NODE)));
    h.dev.on_frame(&nmt::command(NmtCommand::Start, Target::All), h.now);
    let ev = run_monitor(&mut h, &mut m, 200_000, |_| true);
    assert_eq!(
        ev.iter().map(|e| e.1).collect::<Vec<_>>(),
        [NodeEvent::StateChanged { node: 1, from: NmtState::PreOperational, to: NmtState::Operational }]
    );
    // The bus to the node breaks: lost once, 150 ms after the last heartbeat.
    let last = h.now - (h.now % 100_000);
    let ev = run_monitor(&mut h, &mut m, 500_000, |_| false);
    assert_eq!(ev, [(last + 150_000, NodeEvent::Lost { node: 1 })]);
    assert!(!m.is_alive(node(NODE)));
    let ev = run_monitor(&mut h, &mut m, 200_000, |_| true);
    assert_eq!(
        ev.iter().map(|e| e.1).collect::<Vec<_>>(),
        [NodeEvent::Recovered { node: 1, state: NmtState::Operational }]
    );
    // A reset: boot-up, then (1017h back to 0 after a communication reset) no heartbeat and no
    // timeout until the node is configured again.
    h.dev.on_frame(&nmt::command(NmtCommand::ResetCommunication, Target::All), h.now);
    let ev = run_monitor(&mut h, &mut m, 1_000_000, |_| true);
    assert_eq!(ev.iter().map(|e| e.1).collect::<Vec<_>>(), [NodeEvent::BootUp { node: 1 }]);
    assert_eq!(m.state(node(NODE)), Some(NmtState::Initialising));
    h.sdo_write_ok(0x1017, 0, &[100, 0]);
    let ev = run_monitor(&mut h, &mut m, 200_000, |_| true);
    assert_eq!(
        ev.iter().map(|e| e.1).collect::<Vec<_>>(),
        [NodeEvent::StateChanged { node: 1, from: NmtState::Initialising, to: NmtState::PreOperational }]
    );
}

#[test]
fn never_seen_is_not_lost() {
    let mut m = NodeMonitor::<2>::new();
    m.watch(node(2), Watch::Heartbeat { timeout: 100_000 }, Some(500_000), 1_000).unwrap();
    m.watch(node(3), Watch::Heartbeat { timeout: 100_000 }, None, 1_000).unwrap();
    assert_eq!(m.deadline(), Some(501_000));
    let mut ev = Vec::new();
    for t in (0..=5_000_000).step_by(1_000) {
        m.poll(t, |_| panic!("heartbeat consumers send nothing"), |e| ev.push((t, e)));
    }
    assert_eq!(ev, [(501_000, NodeEvent::NeverSeen { node: 2 })]);
    assert_eq!(m.deadline(), None);
    assert!(!m.is_alive(node(2)));
    // Full table; re-watching a node replaces it; unwatch frees the slot.
    assert_eq!(m.watch(node(4), Watch::Heartbeat { timeout: 1 }, None, 0), Err(Full));
    m.watch(node(3), Watch::Heartbeat { timeout: 5 }, None, 0).unwrap();
    m.unwatch(node(3));
    m.watch(node(4), Watch::Heartbeat { timeout: 1 }, None, 0).unwrap();
    // Frames the monitor does not take.
    for f in ["704 05 00", "704 R1", "704 85", "704 33", "184 05", "705 05"] {
        assert_eq!(m.on_frame(&frame(f), 0), None, "{f}");
    }
    assert_eq!(m.on_frame(&frame("704 05"), 0), Some(NodeEvent::FirstSeen { node: 4, state: NmtState::Operational }));
    assert_eq!(m.on_frame(&frame("704 05"), 0), None);
}

#[test]
fn node_guarding_master_against_the_device() {
    let mut h = Harness::new();
    h.sdo_write_ok(0x100C, 0, &[100, 0]); // 100 ms
    h.sdo_write_ok(0x100D, 0, &[3]);
    let mut m = NodeMonitor::<1>::new();
    let watch = Watch::Guarding { guard_time: 100_000, life_time_factor: 3 };
    m.watch(node(NODE), watch, None, h.now).unwrap();
    let mut frames = Vec::new();
    let ev = run_monitor(&mut h, &mut m, 350_000, |f| {
        frames.push(f.to_string());
        true
    });
    // A request every guard time, answered with the state and an alternating toggle bit.
    assert_eq!(frames, ["701 R1", "701 7F", "701 R1", "701 FF", "701 R1", "701 7F", "701 R1", "701 FF"]);
    assert_eq!(
        ev.iter().map(|e| e.1).collect::<Vec<_>>(),
        [NodeEvent::FirstSeen { node: 1, state: NmtState::PreOperational }]
    );
    // One answer lost: the next one's toggle bit does not alternate.
    let mut k = 0;
    let ev = run_monitor(&mut h, &mut m, 300_000, |f| {
        if f.is_rtr() {
            return true;
        }
        k += 1;
        k != 1
    });
    assert_eq!(ev.iter().map(|e| e.1).collect::<Vec<_>>(), [NodeEvent::GuardToggle { node: 1 }]);
    // No answers: lost after the life time (3 × 100 ms) past the last good answer.
    let ev = run_monitor(&mut h, &mut m, 500_000, |f| f.is_rtr());
    assert_eq!(ev.iter().map(|e| e.1).collect::<Vec<_>>(), [NodeEvent::Lost { node: 1 }]);
    let ev = run_monitor(&mut h, &mut m, 300_000, |_| true);
    assert!(ev.iter().any(|e| e.1 == NodeEvent::Recovered { node: 1, state: NmtState::PreOperational }), "{ev:?}");
    // A guarded node that never answers is reported never seen after its life time.
    let mut m = NodeMonitor::<1>::new();
    m.watch(node(7), watch, None, 0).unwrap();
    let mut ev = Vec::new();
    for t in (0..=1_000_000).step_by(10_000) {
        m.poll(t, |_| {}, |e| ev.push((t, e)));
    }
    assert_eq!(ev, [(300_000, NodeEvent::NeverSeen { node: 7 })]);
}

#[test]
fn master_heartbeat_lets_the_device_notice_a_dead_master() {
    let mut h = Harness::new();
    // The device consumes node 100's heartbeat with 150 ms.
    h.sdo_write_ok(0x1016, 1, &[150, 0, 100, 0]);
    h.events();
    let mut hb = HeartbeatProducer::new(node(100), 100_000);
    hb.set_state(NmtState::Operational);
    let mut frames = Vec::new();
    for _ in 0..300 {
        h.now += 1_000;
        hb.poll(h.now, |f| {
            frames.push((h.now, f.to_string()));
            h.dev.on_frame(&f, h.now);
        });
        h.poll();
    }
    assert_eq!(frames.iter().map(|f| f.0).collect::<Vec<_>>(), [1_000, 101_000, 201_000]);
    assert!(frames.iter().all(|f| f.1 == "764 05"));
    assert_eq!(hb.deadline(), Some(301_000));
    assert!(h.events().contains(&Event::HeartbeatStarted { node: 100, state: 5 }));
    // The master dies: the device notices within the consumer time.
    for _ in 0..300 {
        h.now += 1_000;
        h.poll();
    }
    assert!(h.events().contains(&Event::HeartbeatTimeout { node: 100 }));
}

// ---- EMCY ------------------------------------------------------------------------------------

#[test]
fn emcy_consumer_decodes_the_device_messages() {
    let mut h = Harness::new();
    h.dev.signal_error(0x2310, od_runtime::emcy::REG_CURRENT, [1, 2, 3, 4, 5]);
    let mut got = Vec::new();
    for _ in 0..20 {
        h.now += 1_000;
        h.dev.poll(h.now, |f| got.extend(Emergency::from_frame(&f)));
    }
    h.dev.reset_error(od_runtime::emcy::REG_CURRENT);
    for _ in 0..20 {
        h.now += 1_000;
        h.dev.poll(h.now, |f| got.extend(Emergency::from_frame(&f)));
    }
    assert_eq!(got.len(), 2, "{got:?}");
    assert_eq!(got[0], Emergency { node: 1, code: 0x2310, register: 0x03, vendor: [1, 2, 3, 4, 5] });
    assert!(!got[0].is_reset());
    assert_eq!(
        got[0].to_string(),
        "node 1: EMCY 2310h (current, device output side), error register 03h, vendor 01 02 03 04 05"
    );
    assert!(got[1].is_reset());
    assert_eq!(got[1].code, 0);
    assert_eq!(got[1].description(), "error reset or no error");
}

#[test]
fn emcy_frames_the_consumer_refuses_and_codes_it_names() {
    for f in [
        "080 00 00 00 00 00 00 00 00",
        "100 10 23 03 00 00 00 00 00",
        "085 R8",
        "085 10 23 03",
        "181 10 23 03 00 00 00 00 00",
    ] {
        assert_eq!(Emergency::from_frame(&frame(f)), None, "{f}");
    }
    let e = Emergency::from_frame(&frame("0FF 30 81 11 AA BB CC DD EE")).unwrap();
    assert_eq!((e.node, e.code, e.register, e.vendor), (127, 0x8130, 0x11, [0xAA, 0xBB, 0xCC, 0xDD, 0xEE]));
    assert_eq!(e.description(), "life guard error or heartbeat error");
    // A node whose 1014h moved its EMCY: decoded by the caller's COB-ID table.
    assert_eq!(Emergency::decode(9, &frame("3C0 00 50 01 00 00 00 00 00")).unwrap().description(), "device hardware");
    for (code, want) in [
        (0x1000, "generic error"),
        (0x4210, "device temperature"),
        (0xFF01, "device specific"),
        (0x8611, "monitoring"),
        (0xA000, "unknown error code"),
    ] {
        assert_eq!(od_runtime::master::emcy::describe(code), want, "{code:04X}");
    }
}

// ---- SYNC ------------------------------------------------------------------------------------

#[test]
fn sync_producer_period_and_counter() {
    let mut s = SyncProducer::new(1_000).with_counter(3).unwrap();
    assert_eq!(s.deadline(), None);
    let mut frames = Vec::new();
    s.poll(0, |f| frames.push(f.to_string()));
    assert!(frames.is_empty(), "stopped");
    s.start(500);
    for t in (0..=5_600).step_by(100) {
        s.poll(t, |f| frames.push(format!("{t}: {f}")));
    }
    assert_eq!(frames, ["500: 080 01", "1500: 080 02", "2500: 080 03", "3500: 080 01", "4500: 080 02", "5500: 080 03"]);
    // A late poll sends one SYNC and keeps the grid.
    frames.clear();
    s.poll(9_700, |f| frames.push(f.to_string()));
    assert_eq!(frames, ["080 01"]);
    assert_eq!(s.deadline(), Some(10_500));
    // A restart begins the counter at 1; without a counter SYNC carries no data.
    s.start(20_000);
    s.poll(20_000, |f| frames.push(f.to_string()));
    assert_eq!(frames.last().unwrap(), "080 01");
    let mut plain = SyncProducer::new(1_000).with_cob_id(0x1080);
    plain.start(0);
    plain.poll(0, |f| frames.push(f.to_string()));
    assert_eq!(frames.last().unwrap(), "080");
    plain.stop();
    assert!(!plain.is_running());
    for bad in [1u8, 241, 255] {
        assert_eq!(SyncProducer::new(1).with_counter(bad), Err(InvalidOverflow(bad)));
    }
    for ok in [0u8, 2, 240] {
        assert!(SyncProducer::new(1).with_counter(ok).is_ok());
    }
    let mut zero = SyncProducer::new(0);
    zero.start(0);
    assert!(!zero.is_running(), "a period of 0 sends nothing");
}

#[test]
fn sync_counter_wraps_at_every_allowed_overflow() {
    for overflow in 2u8..=240 {
        let mut s = SyncProducer::new(10).with_counter(overflow).unwrap();
        s.start(0);
        let mut counts = Vec::new();
        for t in 0..(2 * u64::from(overflow) + 1) * 10 {
            s.poll(t, |f| counts.push(f.data()[0]));
        }
        let want: Vec<u8> = (0..2 * usize::from(overflow) + 1).map(|i| (i % usize::from(overflow)) as u8 + 1).collect();
        assert_eq!(counts, want, "overflow {overflow}");
    }
}

#[test]
fn sync_drives_the_device_tpdo_decoded_by_a_mapping_read_over_sdo() {
    let mut l = Link::new();
    // Read TPDO2's mapping (1A01h) and its COB-ID from the device.
    let count = l.read(0x1A01, 0, 1, Mode::Normal).unwrap()[0];
    let values: Vec<u32> = (1..=count)
        .map(|s| u32::from_le_bytes(l.read(0x1A01, s, 4, Mode::Normal).unwrap().try_into().unwrap()))
        .collect();
    let cob = u32::from_le_bytes(l.read(0x1801, 1, 4, Mode::Normal).unwrap().try_into().unwrap()) as u16;
    let od = TestOd::new();
    let map: PdoMapping = PdoMapping::new(PdoDir::Transmit, &values, |i, s| od.info(i, s).map(Mappable::from)).unwrap();
    assert_eq!(map.values().collect::<Vec<_>>(), values);
    assert_eq!(map.bits(), 48);
    l.h.dev.od_mut().set(0x6064, 0, -123_456);
    l.h.dev.on_frame(&nmt::command(NmtCommand::Start, Target::All), l.h.now);
    let mut sync = SyncProducer::new(1_000);
    sync.start(l.h.now);
    let mut tpdos = Vec::new();
    for _ in 0..3 {
        sync.poll(l.h.now, |f| l.h.dev.on_frame(&f, l.h.now));
        l.h.dev.poll(l.h.now, |f| {
            if f.id() == cob {
                tpdos.push(f)
            }
        });
        l.h.now += 1_000;
    }
    assert_eq!(tpdos.len(), 3);
    let mut out = [PdoValue::Unsigned(0); 8];
    assert_eq!(map.decode(tpdos[2].data(), &mut out), Ok(2));
    assert_eq!(out[0], PdoValue::Unsigned(l.h.od().get(0x6041, 0) as u64));
    assert_eq!(out[1], PdoValue::Signed(-123_456));
}

// ---- PDO -------------------------------------------------------------------------------------

#[test]
fn rpdo_encoded_from_a_mapping_reaches_the_device() {
    let mut h = Harness::new();
    h.start();
    let od = TestOd::new();
    // RPDO2 of the test drive: controlword + target position.
    let map: PdoMapping =
        PdoMapping::new(PdoDir::Receive, &[0x6040_0010, 0x607A_0020], |i, s| od.info(i, s).map(Mappable::from))
            .unwrap();
    let (data, len) = map.encode(&[PdoValue::Unsigned(0x0006), PdoValue::Signed(-1_000)]).unwrap();
    assert_eq!(len, 6);
    let f = Frame::new(0x301, &data[..len]).unwrap();
    assert_eq!(f.to_string(), "301 06 00 18 FC FF FF");
    h.dev.on_frame(&f, h.now);
    h.poll();
    assert_eq!(h.od().get(0x607A, 0), -1_000);
    assert_eq!(h.od().get(0x6040, 0), 6);
    // Values that do not fit their field or their type.
    assert_eq!(
        map.encode(&[PdoValue::Unsigned(0x1_0000), PdoValue::Signed(0)]),
        Err(PdoError::OutOfRange { field: 0 })
    );
    assert_eq!(map.encode(&[PdoValue::Unsigned(1), PdoValue::Unsigned(0)]), Err(PdoError::WrongKind { field: 1 }));
    assert_eq!(map.encode(&[PdoValue::Unsigned(1)]), Err(PdoError::ValueCount));
    assert_eq!(map.get(&[0; 5], 0), Err(PdoError::TooShort { len: 5, needed: 6 }));
}

#[test]
fn mappings_follow_the_device_rules() {
    let od = TestOd::new();
    let look = |i: u16, s: u8| od.info(i, s).map(Mappable::from);
    let err = |dir, v: &[u32]| PdoMapping::<8>::new(dir, v, look).unwrap_err();
    // 6041h is read only: not in an RPDO.
    assert_eq!(err(PdoDir::Receive, &[0x6041_0010]), PdoError::Mapping(AbortCode::NOT_MAPPABLE));
    assert_eq!(err(PdoDir::Transmit, &[0x6041_0008]), PdoError::Mapping(AbortCode::PARAMETER_INCOMPATIBLE));
    assert_eq!(err(PdoDir::Transmit, &[0x5000_0008]), PdoError::Mapping(AbortCode::NO_OBJECT));
    assert_eq!(err(PdoDir::Transmit, &[0x2002_0040, 0x6041_0010]), PdoError::Mapping(AbortCode::PDO_LENGTH_EXCEEDED));
    assert_eq!(
        PdoMapping::<1>::new(PdoDir::Transmit, &[0x6041_0010, 0x6041_0010], look).unwrap_err(),
        PdoError::TooManyEntries
    );
    // Dummy entries in an RPDO, sent as zeros, typed by their index; bits of BOOLEANs.
    let map: PdoMapping =
        PdoMapping::new(PdoDir::Receive, &[0x2004_0101, 0x0001_0001, 0x2004_0201, 0x0002_0008, 0x2005_0008], look)
            .unwrap();
    let (data, len) = map
        .encode(&[
            PdoValue::Unsigned(1),
            PdoValue::Unsigned(1),
            PdoValue::Unsigned(1),
            PdoValue::Signed(-1),
            PdoValue::Signed(-2),
        ])
        .unwrap();
    assert_eq!((len, &data[..len]), (3, &[0x05, 0xF0, 0x07][..]));
    assert_eq!(map.fields()[3].data_type, od_runtime::od::DataType::Integer8);
    assert_eq!(map.get(&data[..len], 4), Ok(PdoValue::Signed(-2)));
    assert_eq!(map.get(&data[..len], 2), Ok(PdoValue::Unsigned(1)));
    // A part of a string.
    let map: PdoMapping = PdoMapping::new(PdoDir::Transmit, &[0x2009_0018], look).unwrap();
    let mut s = [0u8; 8];
    s[..3].copy_from_slice(b"ABC");
    let (data, len) = map.encode(&[PdoValue::Bytes { data: s, len: 3 }]).unwrap();
    assert_eq!(&data[..len], b"ABC");
    assert_eq!(map.get(&data[..len], 0), Ok(PdoValue::Bytes { data: s, len: 3 }));
}

fn field_type() -> impl Strategy<Value = (od_runtime::od::DataType, u8)> {
    use od_runtime::od::DataType::*;
    prop_oneof![
        Just((Boolean, 1)),
        Just((Integer8, 8)),
        Just((Integer16, 16)),
        Just((Integer24, 24)),
        Just((Integer32, 32)),
        Just((Integer40, 40)),
        Just((Integer64, 64)),
        Just((Unsigned8, 8)),
        Just((Unsigned16, 16)),
        Just((Unsigned24, 24)),
        Just((Unsigned32, 32)),
        Just((Unsigned56, 56)),
        Just((Unsigned64, 64)),
        Just((Real32, 32)),
        Just((Real64, 64)),
        (1u8..=8).prop_map(|n| (OctetString, 8 * n)),
    ]
}

proptest! {
    /// Any valid mapping: every value that fits comes back from the encoded PDO unchanged,
    /// whatever its bit offset, and the PDO is exactly as long as the mapping.
    #[test]
    fn pdo_values_round_trip(fields in prop::collection::vec((field_type(), any::<u64>()), 1..12)) {
        let mut bits = 0u32;
        let mut defs = Vec::new();
        let mut values = Vec::new();
        for (k, ((t, b), raw)) in fields.into_iter().enumerate() {
            if bits + u32::from(b) > 64 {
                break;
            }
            bits += u32::from(b);
            defs.push(PdoField { entry: MapEntry { index: 0x2100 + k as u16, sub: 0, bits: b }, data_type: t });
            let v = if t == od_runtime::od::DataType::Real32 {
                PdoValue::Real32(f32::from_bits(raw as u32 & 0x7F7F_FFFF))
            } else if t == od_runtime::od::DataType::Real64 {
                PdoValue::Real64(f64::from_bits(raw & 0x7FEF_FFFF_FFFF_FFFF))
            } else if t.is_variable_length() {
                let len = raw as u8 % (b / 8 + 1);
                let mut d = raw.to_le_bytes();
                d[usize::from(len)..].fill(0);
                PdoValue::Bytes { data: d, len }
            } else if t.is_signed() {
                let shift = 64 - u32::from(b);
                PdoValue::Signed(((raw << shift) as i64) >> shift)
            } else {
                PdoValue::Unsigned(if b == 64 { raw } else { raw & ((1 << b) - 1) })
            };
            values.push(v);
        }
        let map = PdoMapping::<16>::from_fields(PdoDir::Transmit, &defs).unwrap();
        prop_assert_eq!(map.bits(), bits);
        let (data, len) = map.encode(&values).unwrap();
        prop_assert_eq!(len, bits.div_ceil(8) as usize);
        prop_assert!(data[len..].iter().all(|&b| b == 0));
        let mut out = vec![PdoValue::Unsigned(0); values.len()];
        prop_assert_eq!(map.decode(&data[..len], &mut out), Ok(values.len()));
        for (i, (got, want)) in out.iter().zip(&values).enumerate() {
            match (got, want) {
                // Strings come back at their field's width, zero padded.
                (PdoValue::Bytes { data: g, .. }, PdoValue::Bytes { data: w, .. }) => prop_assert_eq!(g, w, "field {}", i),
                _ => prop_assert_eq!(got, want, "field {}", i),
            }
        }
    }

    /// Decoding arbitrary bytes with any mapping never panics, and a short PDO is refused.
    #[test]
    fn pdo_decode_never_panics(fields in prop::collection::vec(field_type(), 1..10), data in prop::collection::vec(any::<u8>(), 0..=8)) {
        let mut bits = 0u32;
        let defs: Vec<PdoField> = fields
            .into_iter()
            .enumerate()
            .take_while(|(_, (_, b))| { bits += u32::from(*b); bits <= 64 })
            .map(|(k, (t, b))| PdoField { entry: MapEntry { index: 0x2100 + k as u16, sub: 0, bits: b }, data_type: t })
            .collect();
        prop_assume!(!defs.is_empty());
        let map = PdoMapping::<16>::from_fields(PdoDir::Receive, &defs).unwrap();
        let mut out = vec![PdoValue::Unsigned(0); defs.len()];
        let r = map.decode(&data, &mut out);
        prop_assert_eq!(r.is_ok(), data.len() >= map.byte_len());
    }
}
