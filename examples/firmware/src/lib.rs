//! The application logic of the example firmware: one CiA 402 axis on a CANopen device, with
//! the bus behind any [`embedded_can::nb::Can`] driver.
//!
//! The binary (`src/bin/firmware.rs`) runs it on a Cortex-M4F with the [`bxcan`] driver; the
//! host test (`tests/host.rs`) runs the same [`Firmware`] on the in-memory bus of the `drive`
//! crate, with a master made of plain frames, so the logic is exercised, not only built.
//!
//! The device is chosen with a cargo feature: `drcs` (the default), `drvi` or `akd`.
#![no_std]

pub mod bxcan;

use od_runtime::can::CanLink;
use od_runtime::cia402::State;
use od_runtime::od::ObjectDictionary;
use od_runtime::{App, Event, Micros, NoStorage, NodeId};

#[cfg(all(feature = "akd", not(any(feature = "drcs", feature = "drvi"))))]
pub use generated::akd as device;
#[cfg(feature = "drcs")]
pub use generated::drcs as device;
#[cfg(all(feature = "drvi", not(feature = "drcs")))]
pub use generated::drvi as device;

/// The object dictionary the firmware serves.
pub type Od = device::Dictionary;

/// The device: the dictionary, the axis, no parameter storage; SDO buffer and PDO tables sized
/// for the dictionary by the generator.
pub type Dev = device::Device<Axis, NoStorage>;

/// Position actual value (6064h) and target position (607Ah).
const POSITION_ACTUAL: u16 = 0x6064;
const TARGET_POSITION: u16 = 0x607A;
/// Statusword bit 10: target reached.
const TARGET_REACHED: u16 = 1 << 10;

/// The application: an axis that follows the target position at a fixed speed while the
/// CiA 402 state machine is in "operation enabled".
#[derive(Debug, Default)]
pub struct Axis {
    enabled: bool,
}

impl Axis {
    /// An axis that stands still.
    pub const fn new() -> Self {
        Self { enabled: false }
    }

    /// Increments the axis moves per millisecond.
    pub const SPEED: i32 = 100;

    /// Whether the drive is in "operation enabled".
    pub const fn enabled(&self) -> bool {
        self.enabled
    }
}

impl<OD> App<OD> for Axis {
    fn on_event(&mut self, _: &mut OD, event: Event) {
        if let Event::Cia402(t) = event {
            self.enabled = t.to == State::OperationEnabled;
        }
    }
}

fn read_i32<OD: ObjectDictionary>(od: &OD, index: u16) -> Option<i32> {
    let mut b = [0u8; 4];
    match od.read(index, 0, &mut b) {
        Ok(4) => Some(i32::from_le_bytes(b)),
        _ => None,
    }
}

/// The whole firmware but the driver: device and link. Call [`Firmware::step`] from the main
/// loop with the driver.
pub struct Firmware {
    dev: Dev,
    link: CanLink<16>,
    /// The last millisecond the axis moved in.
    last_ms: Micros,
}

impl Firmware {
    /// The firmware as node `node`, with the dictionary's defaults. A `const fn`: the binary
    /// builds it in a `static` at compile time, so nothing is copied through the stack.
    pub const fn new(node: NodeId) -> Self {
        Self {
            dev: Dev::with_capacity(Od::new(node.get()), Axis::new(), NoStorage, node),
            link: CanLink::new(),
            last_ms: 0,
        }
    }

    /// Builds the firmware in place, in `place` (a `static` of the binary), with
    /// [`Device::init_in_place`](od_runtime::Device::init_in_place): every value of the
    /// dictionary zero, which the device's first poll replaces with the defaults (its reset
    /// node). Nothing of it needs an image in flash, and nothing is built on the stack first.
    /// Not inlined: its frame (the parts of the device it zeroes) is then not added to the main
    /// loop's, on the deepest path of the stack.
    #[inline(never)]
    pub fn init(place: &mut core::mem::MaybeUninit<Firmware>, node: NodeId) -> &mut Firmware {
        let p = place.as_mut_ptr();
        // SAFETY: the three fields of `*p` are written once each (the device in place), through
        // raw pointers into `place`, which is valid for writes and exclusively ours.
        unsafe {
            let dev = &mut *core::ptr::addr_of_mut!((*p).dev).cast::<core::mem::MaybeUninit<Dev>>();
            let _dev = Dev::init_in_place(dev, Od::zeroed(), Axis::new(), NoStorage, node);
            // With the `lss` feature the device answers LSS (CiA 305).
            #[cfg(feature = "lss")]
            _dev.enable_lss(Some(node));
            core::ptr::addr_of_mut!((*p).link).write(CanLink::new());
            core::ptr::addr_of_mut!((*p).last_ms).write(0);
            place.assume_init_mut()
        }
    }

    /// One turn of the main loop at time `now`: the bus (receive, device services, transmit),
    /// then the axis, once per elapsed millisecond.
    pub fn step<C: embedded_can::nb::Can>(&mut self, can: &mut C, now: Micros) {
        self.link.service(can, &mut self.dev, now);
        let ms = now / 1000;
        if ms != self.last_ms {
            self.last_ms = ms;
            self.motion();
        }
    }

    /// Moves the actual position one step towards the target while enabled, and reports
    /// "target reached" in the statusword.
    fn motion(&mut self) {
        let od = self.dev.od();
        let (Some(pos), Some(target)) = (read_i32(od, POSITION_ACTUAL), read_i32(od, TARGET_POSITION)) else {
            return;
        };
        let mut next = pos;
        if self.dev.app().enabled() {
            next = pos.saturating_add(target.saturating_sub(pos).clamp(-Axis::SPEED, Axis::SPEED));
            if next != pos {
                // The application's own value: straight into the dictionary (no bus write).
                let _ = self.dev.od_mut().write(POSITION_ACTUAL, 0, &next.to_le_bytes());
            }
        }
        self.dev.set_statusword_flags(TARGET_REACHED, if next == target { TARGET_REACHED } else { 0 });
    }

    /// The device.
    pub fn device(&self) -> &Dev {
        &self.dev
    }

    /// The link (queue and error counters).
    pub fn link(&self) -> &CanLink<16> {
        &self.link
    }
}
