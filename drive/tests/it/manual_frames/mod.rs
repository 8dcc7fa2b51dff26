//! Frames written as the drives' manuals print them (`"603 2B 40 60 00 06 00 00 00"`: the
//! identifier, then the data bytes, in hex), for tests that replay the manuals' listings
//! through od-master's bus ([`Master::send`]) on the virtual clock.

use crate::support::Master;
use od_bus::CanFrame;

/// `"603 2B 40 60 00 06 00 00 00"` as a frame.
pub fn frame(text: &str) -> CanFrame {
    let mut words = text.split_whitespace();
    let id = u32::from_str_radix(words.next().unwrap(), 16).unwrap();
    let data: Vec<u8> = words.map(|w| u8::from_str_radix(w, 16).unwrap()).collect();
    CanFrame::standard(id, &data).unwrap()
}

/// A frame as the manual prints it.
pub fn text(f: &CanFrame) -> String {
    let mut s = format!("{:03X}", f.id());
    for b in f.data() {
        s.push_str(&format!(" {b:02X}"));
    }
    s
}

/// Sends an SDO request and returns the answer (on 580h + node), as text.
pub fn sdo(m: &mut Master, request: &str) -> String {
    let f = frame(request);
    let answer_id = f.id() - 0x600 + 0x580;
    m.take_id(answer_id);
    m.send(f);
    for _ in 0..1000 {
        if let Some(s) = m.take_id(answer_id).first() {
            return text(&s.frame);
        }
        m.advance(100);
    }
    panic!("no answer to {request}");
}

/// The frames seen on `id` since the last look, as text.
pub fn got(m: &mut Master, id: u32) -> Vec<String> {
    m.take_id(id).iter().map(|s| text(&s.frame)).collect()
}
