//! The example firmware: the DRCS device (node 5) on CAN1 of a Cortex-M4F at 500 kbit/s.
//!
//! Build: `cargo build -p firmware --bin firmware --features rt --profile firmware --target
//! thumbv7em-none-eabihf`; `cargo xtask size` builds it and checks the size budget.
#![no_std]
#![no_main]

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, Ordering};

#[path = "firmware/mem.rs"]
mod mem;

use cortex_m_rt::{entry, exception};
use firmware::Firmware;
use firmware::bxcan::{BTR_500K_42MHZ, BxCan, CAN1};
use od_runtime::NodeId;
use panic_halt as _;

/// Milliseconds since start, counted by the SysTick exception.
static MILLIS: AtomicU32 = AtomicU32::new(0);

/// SysTick registers (ARMv7-M architecture reference manual, B3.3).
const SYST_CSR: *mut u32 = 0xE000_E010 as *mut u32;
const SYST_RVR: *mut u32 = 0xE000_E014 as *mut u32;
/// Core clock cycles per millisecond (16 MHz internal oscillator after reset).
const CYCLES_PER_MS: u32 = 16_000;

/// The node id, a configuration byte of the flash image (a board would read DIP switches or
/// its parameter memory).
#[unsafe(link_section = ".rodata.node_id")]
static NODE_ID: u8 = 5;

/// Interrupts of the STM32F405 (reference manual RM0090, table 61).
const IRQS: usize = 82;

unsafe extern "C" {
    /// cortex-m-rt's handler of every exception and interrupt without one of its own.
    fn DefaultHandler();
}

/// The interrupt part of the vector table (cortex-m-rt's `device` feature): the firmware polls
/// CAN and enables no interrupt, so every vector is the default handler. 328 bytes, not the
/// 960 of cortex-m-rt's generic table of 240 vectors.
#[unsafe(link_section = ".vector_table.interrupts")]
#[unsafe(no_mangle)]
static __INTERRUPTS: [unsafe extern "C" fn(); IRQS] = [DefaultHandler; IRQS];

#[exception]
fn SysTick() {
    MILLIS.fetch_add(1, Ordering::Relaxed);
}

/// Where the firmware stops when the CAN controller or the node id is unusable: nothing to
/// serve, so it waits (a board would signal the fault).
fn halt() -> ! {
    loop {
        core::hint::spin_loop();
    }
}

#[entry]
fn main() -> ! {
    // The firmware's state, in RAM beside the stack: zeroed at reset like `.bss`, built in
    // place by `Firmware::init` (no image of it in flash, no copy through the stack).
    // cortex-m-rt hands a `static mut` of the entry function over as a `&'static mut`: `main`
    // runs once, so it is the only reference.
    static mut FIRMWARE: MaybeUninit<Firmware> = MaybeUninit::uninit();
    // SAFETY: the SysTick registers belong to this program alone; enable, interrupt, core clock.
    unsafe {
        SYST_RVR.write_volatile(CYCLES_PER_MS - 1);
        SYST_CSR.write_volatile(0b111);
    }
    // SAFETY: CAN1 is used by this driver alone (clock and pins: the board's start-up code).
    let Ok(mut can) = (unsafe { BxCan::new(CAN1, BTR_500K_42MHZ) }) else { halt() };
    // SAFETY: a plain byte of this image; read as the configuration it stands for.
    let node = unsafe { (&raw const NODE_ID).read_volatile() };
    let Some(node) = NodeId::new(node) else { halt() };
    let fw = Firmware::init(FIRMWARE, node);
    loop {
        let now = u64::from(MILLIS.load(Ordering::Relaxed)) * 1000;
        fw.step(&mut can, now);
    }
}
