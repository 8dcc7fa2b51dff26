//! Property tests of the socketcand protocol: what is printed parses back to the same thing,
//! and no input, however hostile, makes the decoder panic or grow without bound.

use od_bus::CanFrame;
use od_bus::socketcand::{Decoder, MAX_MESSAGE_LEN, Message, Timestamp};
use proptest::prelude::*;

fn any_frame() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        (0u32..=0x7FF, prop::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::standard(id, &d).unwrap()),
        (0u32..=0x1FFF_FFFF, prop::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::extended(id, &d).unwrap()),
        (0u32..=0x7FF, 0u8..=8).prop_map(|(id, dlc)| CanFrame::remote(id, false, dlc).unwrap()),
        (0u32..=0x1FFF_FFFF, 0u8..=8).prop_map(|(id, dlc)| CanFrame::remote(id, true, dlc).unwrap()),
    ]
}

fn any_timestamp() -> impl Strategy<Value = Timestamp> {
    (any::<u64>(), 0u32..1_000_000).prop_map(|(s, us)| Timestamp::new(s, us).unwrap())
}

/// python-can's reading of a `< frame >` message (can/interfaces/socketcand/socketcand.py,
/// `convert_ascii_message_to_can_message`), restated: strip `< frame ` and ` >`, split on single
/// spaces into at most 3 parts, an id of exactly 3 digits is standard.
fn python_can_reads(text: &str) -> Option<(u32, bool, Vec<u8>)> {
    let inner = text.strip_prefix("< frame ")?.strip_suffix(" >")?;
    let parts: Vec<&str> = inner.splitn(3, ' ').collect();
    let id = u32::from_str_radix(parts[0], 16).ok()?;
    let _timestamp: f64 = parts.get(1)?.parse().ok()?;
    let hex = parts.get(2)?;
    let data =
        (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(hex.get(i..i + 2)?, 16).ok()).collect::<Option<_>>()?;
    Some((id, parts[0].len() != 3, data))
}

proptest! {
    #[test]
    fn send_round_trips(frame in any_frame()) {
        let text = Message::Send(frame).to_string();
        prop_assert_eq!(Message::parse(&text), Ok(Message::Send(frame)));
    }

    #[test]
    fn frame_round_trips(frame in any_frame(), timestamp in any_timestamp()) {
        let message = Message::Frame { frame, timestamp };
        let text = message.to_string();
        prop_assert!(text.len() <= MAX_MESSAGE_LEN);
        prop_assert_eq!(Message::parse(&text), Ok(message));
    }

    #[test]
    fn python_can_reads_every_data_frame_we_print(frame in any_frame(), timestamp in any_timestamp()) {
        prop_assume!(!frame.is_remote());
        let text = Message::Frame { frame, timestamp }.to_string();
        let read = python_can_reads(&text);
        prop_assert_eq!(read, Some((frame.id(), frame.is_extended(), frame.data().to_vec())), "{}", text);
    }

    #[test]
    fn python_can_send_format_parses(frame in any_frame()) {
        // python-can: f"< send {id:03X|08X} {dlc:X} {' '.join(f'{b:x}')} >"
        prop_assume!(!frame.is_remote());
        let id = if frame.is_extended() { format!("{:08X}", frame.id()) } else { format!("{:03X}", frame.id()) };
        let bytes: Vec<String> = frame.data().iter().map(|b| format!("{b:x}")).collect();
        let text = format!("< send {id} {:X} {} >", frame.dlc(), bytes.join(" "));
        prop_assert_eq!(Message::parse(&text), Ok(Message::Send(frame)));
    }

    #[test]
    fn the_decoder_survives_any_bytes(chunks in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..600), 0..8)) {
        let mut decoder = Decoder::new();
        let mut count = 0usize;
        let total: usize = chunks.iter().map(Vec::len).sum();
        for chunk in &chunks {
            decoder.feed(chunk, |_| count += 1);
        }
        // At most one result per input byte plus one junk report per chunk.
        prop_assert!(count <= total + chunks.len());
    }

    #[test]
    fn valid_messages_survive_surrounding_garbage(garbage in prop::collection::vec(any::<u8>(), 0..300), frame in any_frame()) {
        // Whatever came before, a fresh `<` starts a new message.
        let mut input = garbage;
        input.extend_from_slice(Message::Send(frame).to_string().as_bytes());
        let mut last = None;
        Decoder::new().feed(&input, |m| last = Some(m));
        prop_assert_eq!(last, Some(Ok(Message::Send(frame))));
    }
}
