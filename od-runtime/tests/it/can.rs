//! The `embedded-can` feature: frame conversions and `CanLink` over a driver with a small
//! number of transmit mailboxes, a receive FIFO, errors and a frame type of its own.

use crate::common;
use std::collections::VecDeque;

use common::*;
use embedded_can::{ErrorKind, ExtendedId, Frame as _, Id, StandardId};
use od_runtime::Frame;
use od_runtime::can::{CanLink, MAX_RECEIVE_PER_SERVICE, from_can, to_can};

/// A driver's own frame type (as a HAL has one), standard and extended identifiers.
#[derive(Clone, Debug, PartialEq)]
struct HalFrame {
    id: Id,
    rtr: bool,
    dlc: usize,
    data: [u8; 8],
}

impl embedded_can::Frame for HalFrame {
    fn new(id: impl Into<Id>, data: &[u8]) -> Option<Self> {
        let mut d = [0; 8];
        d.get_mut(..data.len())?.copy_from_slice(data);
        Some(Self { id: id.into(), rtr: false, dlc: data.len(), data: d })
    }
    fn new_remote(id: impl Into<Id>, dlc: usize) -> Option<Self> {
        (dlc <= 8).then(|| Self { id: id.into(), rtr: true, dlc, data: [0; 8] })
    }
    fn is_extended(&self) -> bool {
        matches!(self.id, Id::Extended(_))
    }
    fn is_remote_frame(&self) -> bool {
        self.rtr
    }
    fn id(&self) -> Id {
        self.id
    }
    fn dlc(&self) -> usize {
        self.dlc
    }
    fn data(&self) -> &[u8] {
        if self.rtr { &[] } else { &self.data[..self.dlc] }
    }
}

#[derive(Debug)]
struct HalError(ErrorKind);

impl embedded_can::Error for HalError {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

/// A controller with `mailboxes` transmit mailboxes that the test empties by hand.
#[derive(Default)]
struct Controller {
    rx: VecDeque<Result<HalFrame, ErrorKind>>,
    mailboxes: usize,
    in_mailbox: Vec<HalFrame>,
    receives: usize,
}

impl embedded_can::nb::Can for Controller {
    type Frame = HalFrame;
    type Error = HalError;

    fn transmit(&mut self, frame: &HalFrame) -> nb::Result<Option<HalFrame>, HalError> {
        if self.in_mailbox.len() >= self.mailboxes {
            return Err(nb::Error::WouldBlock);
        }
        self.in_mailbox.push(frame.clone());
        Ok(None)
    }

    fn receive(&mut self) -> nb::Result<HalFrame, HalError> {
        self.receives += 1;
        match self.rx.pop_front() {
            Some(Ok(f)) => Ok(f),
            Some(Err(k)) => Err(nb::Error::Other(HalError(k))),
            None => Err(nb::Error::WouldBlock),
        }
    }
}

fn hal(s: &str) -> HalFrame {
    to_can(&frame(s)).unwrap()
}

fn shown(frames: &[HalFrame]) -> Vec<String> {
    frames.iter().map(|f| from_can(f).unwrap().to_string()).collect()
}

fn device() -> TestDevice {
    od_runtime::Device::new(
        TestOd::new(),
        Recorder::default(),
        MemStorage::default(),
        od_runtime::NodeId::new(NODE).unwrap(),
    )
}

#[test]
fn frames_convert_both_ways_exactly() {
    for s in ["000 01 01", "601 40 00 10 00 00 00 00 00", "181", "701 R1", "7FF R8", "123 01 02 03 04 05 06 07 08"] {
        let f = frame(s);
        let h: HalFrame = to_can(&f).unwrap();
        assert_eq!(h.id, Id::Standard(StandardId::new(f.id()).unwrap()), "{s}");
        assert_eq!((h.rtr, h.dlc, h.data()), (f.is_rtr(), f.len(), f.data()), "{s}");
        assert_eq!(from_can(&h), Some(f), "{s}");
        // The runtime's own frame through the trait.
        let id = StandardId::new(f.id()).unwrap();
        let g =
            if f.is_rtr() { Frame::new_remote(id, f.len()) } else { <Frame as embedded_can::Frame>::new(id, f.data()) };
        assert_eq!(g, Some(f), "{s}");
        assert_eq!((embedded_can::Frame::id(&f), f.dlc(), f.is_extended()), (h.id, h.dlc, false));
    }
}

#[test]
fn extended_identifiers_are_not_canopen() {
    let ext = ExtendedId::new(0x601).unwrap();
    assert_eq!(from_can(&HalFrame::new(ext, &[0x40]).unwrap()), None);
    assert_eq!(<Frame as embedded_can::Frame>::new(ext, &[1]), None);
    assert_eq!(<Frame as embedded_can::Frame>::new_remote(ext, 1), None);
    assert_eq!(<Frame as embedded_can::Frame>::new(StandardId::MAX, &[0; 9]), None);
    assert_eq!(<Frame as embedded_can::Frame>::new_remote(StandardId::MAX, 9), None);
}

#[test]
fn link_boots_answers_sdo_and_ignores_extended_frames() {
    let (mut dev, mut can, mut link) =
        (device(), Controller { mailboxes: 3, ..Controller::default() }, CanLink::<16>::new());
    link.service(&mut can, &mut dev, 0);
    assert_eq!(shown(&can.in_mailbox), ["701 00"]);
    can.in_mailbox.clear();
    // An SDO upload of 1000h with an extended frame of the same number in front of it.
    can.rx.push_back(Ok(HalFrame::new(ExtendedId::new(0x601).unwrap(), &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap()));
    can.rx.push_back(Ok(hal("601 40 00 10 00 00 00 00 00")));
    link.service(&mut can, &mut dev, 10);
    assert_eq!(can.in_mailbox.len(), 1);
    assert!(shown(&can.in_mailbox)[0].starts_with("581 43 00 10 00"), "{:?}", shown(&can.in_mailbox));
    assert_eq!((link.pending(), link.dropped(), link.errors()), (0, 0, 0));
}

#[test]
fn full_mailboxes_queue_frames_in_order_and_a_full_queue_drops_and_counts() {
    let (mut dev, mut can, mut link) =
        (device(), Controller { mailboxes: 1, ..Controller::default() }, CanLink::<2>::new());
    link.service(&mut can, &mut dev, 0);
    can.in_mailbox.clear();
    // Three SDO requests in three turns while no mailbox is free: the queue holds two answers,
    // the third is dropped and counted.
    can.mailboxes = 0;
    for t in 1..=3 {
        can.rx.push_back(Ok(hal(&format!("601 40 00 10 0{t} 00 00 00 00"))));
        link.service(&mut can, &mut dev, t);
    }
    assert_eq!((link.pending(), link.dropped()), (2, 1));
    can.mailboxes = 8;
    link.flush(&mut can);
    let out = shown(&can.in_mailbox);
    assert_eq!(out.len(), 2);
    assert!(out[0].starts_with("581 ") && out[0].contains(" 00 10 01 "), "{out:?}");
    assert!(out[1].starts_with("581 ") && out[1].contains(" 00 10 02 "), "order kept: {out:?}");
    assert_eq!(link.pending(), 0);
}

#[test]
fn driver_errors_are_counted_and_the_loop_goes_on() {
    let (mut dev, mut can, mut link) =
        (device(), Controller { mailboxes: 3, ..Controller::default() }, CanLink::<16>::new());
    can.rx.push_back(Err(ErrorKind::Overrun));
    can.rx.push_back(Ok(hal("000 01 01")));
    link.service(&mut can, &mut dev, 0);
    assert_eq!((link.errors(), link.last_error()), (1, Some(ErrorKind::Overrun)));
    assert_eq!(shown(&can.in_mailbox), ["701 00"], "the poll still ran");
    link.service(&mut can, &mut dev, 1);
    assert_eq!(dev.nmt_state(), od_runtime::NmtState::Operational, "the frame after the error arrives next turn");
}

#[test]
fn a_flooded_bus_cannot_keep_the_loop_from_polling() {
    let (mut dev, mut can, mut link) =
        (device(), Controller { mailboxes: 3, ..Controller::default() }, CanLink::<16>::new());
    for _ in 0..1000 {
        can.rx.push_back(Ok(hal("123 00")));
    }
    link.service(&mut can, &mut dev, 0);
    assert_eq!(can.receives, MAX_RECEIVE_PER_SERVICE);
    assert_eq!(shown(&can.in_mailbox), ["701 00"]);
}
