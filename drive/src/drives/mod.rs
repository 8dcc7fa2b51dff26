//! The simulated drives: a common CiA 402 layer and the behaviour of each device on top of it.
//!
//! # Layers
//!
//! ```text
//!   od-runtime Device            CiA 301 services + the CiA 402 state machine (6040h/6041h)
//!        │ events (Written, Cia402 transitions, Sync, heartbeat loss ...)
//!        ▼
//!   cia402::Cia402App<OD, V>     the common drive (this module): implements drive::node::DriveApp
//!        │  for any dictionary; maps the state machine, the controlword, 6060h and the
//!        │  configuration objects onto a drive::motion::Axis every 1 ms tick and writes the
//!        │  actual values and statusword bits back; errors from the device's sidecar table
//!        │
//!        ├── V: cia402::Vendor<OD>   the device: supported modes, homing method codes, bus
//!        │        scaling, vendor objects, extra statusword bits, warnings (drvi.rs, drcs.rs, akd.rs)
//!        ▼
//!   motion::Axis                 profiles, stops, homing, torque, interpolation, mechanics
//! ```
//!
//! A device file is a type implementing [`cia402::Vendor`] plus a constructor returning
//! `Cia402App<Dictionary, ThatType>`; [`DeviceApps`] hands the apps to
//! [`DeviceKind::build`](crate::node::DeviceKind::build). Adding a device (say `drcs.rs`):
//!
//! 1. `pub mod drcs;` below, next to `pub mod drvi;`;
//! 2. a `fn drcs(&self)` method in `impl Apps for DeviceApps` (next to `fn drvi`), building the
//!    app with [`DeviceApps::attach`] so `--trace` works for it;
//! 3. nothing else: the node runner, `drive-sim run` and `drive-sim demo` pick it up.
//!
//! # What the common layer does (CiA 402-2 and the manuals)
//!
//! | CiA 402 | objects | here |
//! |---|---|---|
//! | device control (§6.2), power stage | 6040h, 6041h bits 0..6, 9 | od-runtime runs the state machine; [`cia402::Cia402App`] follows its state: power on in Operation enabled (and during Quick stop active / Fault reaction active until the stop is done), off elsewhere; 605Bh/605Ch ramps before switching off (coast when absent); a device that holds the axis in Switched on says so in [`cia402::Vendor::disable_reaction`] |
//! | quick stop (§6.2, 605Ah) | 605Ah, 6085h | ramp per 605Ah (2 when absent); `quick_stop_done` reported to od-runtime when the axis stands, or when the ramp has ended on a blocked axis |
//! | fault reaction | 603Fh, 1001h, 1003h, EMCY | [`ErrorTable`] from the device's sidecar: `quick_stop` errors ramp with the quick stop deceleration before Fault, `power_off` errors switch the power stage off at once (the axis coasts); EMCY with the sidecar's register bits and manufacturer bytes |
//! | modes of operation (§6.3) | 6060h, 6061h, 6502h | 6060h writes of unsupported modes refused (0609 0030); the axis follows 6061h |
//! | profile position (§12) | 607Ah, 6081h, 6083h, 6084h, 607Fh, 6067h, 6068h | cw bit 4 edge = new set-point (bit 5 change immediately, bit 6 relative, bit 9 change on set-point); sw bit 12 set-point acknowledge, bit 10 target reached, bit 13 following error |
//! | profile velocity (§11) | 60FFh, 606Dh..6070h | 60FFh applied when written; sw bit 12 speed = 0 (standing), bit 10 target reached |
//! | profile torque (§16) | 6071h, 6087h, 6072h | 6071h applied when written, ramped by 6087h |
//! | homing (§10) | 6098h, 6099h, 609Ah, 607Ch | cw bit 4 edge starts; sw bits 10/12/13 from the homing state |
//! | interpolated position (§13) | 60C0h..60C2h | cw bit 4 enables; 60C1h sub 1 queued and consumed at each SYNC |
//! | halt (§6.2.1 bit 8), 605Dh | 6040h bit 8 | every mode |
//! | software limits, internal limit | 607Dh, sw bit 11 | targets clipped (the device decides when the limits apply) |
//! | factor group (§6.4) | [`cia402::BusScale`] | the device converts bus units to the axis' internal units (a reversed velocity direction included) |
//! | polarity (607Eh) | 607Eh bits 7 | positions and velocities mirrored; homing untouched (CiA 402) unless [`cia402::Vendor::polarity_reverses_homing`] |
//! | actual values | 6062h, 6064h, 606Bh, 606Ch, 6074h, 6077h, 60F4h | written every tick where the dictionary has them, and at once after a configuration (unit) write |
//! | store parameters (CiA 301) | 1010h, 1011h | only the objects of the sidecar's `[store]` list are saved ([`store`]) |
//! | error control (CiA 301) | 1016h, 100Ch/100Dh | heartbeat or guarding loss = the device's "fieldbus disconnection" error ([`cia402::Vendor::fieldbus_error`]) |
//!
//! Everything the manuals add (vendor objects, warnings, extra statusword bits, unit systems)
//! lives in the device files through the [`cia402::Vendor`] hooks.
//!
//! # Writing a device file
//!
//! A sketch of what `drcs.rs` or `akd.rs` holds (the DRVI's [`drvi`] is the full example):
//!
//! ```
//! use drive::drives::cia402::{BusScale, Cia402App, Command, Vendor, read_int, write_int};
//! use drive::drives::{Drive, error_table};
//! use drive::motion::{AxisConfig, HomingMethod, Status};
//! use drive::node::{Ctx, DeviceKind};
//! use od_runtime::od::ObjectDictionary;
//!
//! #[derive(Default)]
//! struct MyDrive {
//!     refused: u32,
//! }
//!
//! impl<OD: ObjectDictionary> Vendor<OD> for MyDrive {
//!     // Modes the manual lists (6060h values); others are refused with 0609 0030h.
//!     fn supports_mode(&self, code: i8) -> bool {
//!         matches!(code, 0 | 1 | 3 | 6)
//!     }
//!     // Homing methods of the manual (6098h values), as motion descriptions.
//!     fn homing_method(&self, code: i8) -> Option<HomingMethod> {
//!         matches!(code, 17 | 18 | 37).then(|| HomingMethod::cia402(code)).flatten()
//!     }
//!     // Bus units -> the axis' internal units (a factor group, a feed converter).
//!     fn scale(&self, _od: &OD) -> BusScale {
//!         BusScale::ONE
//!     }
//!     // Vendor objects that shape the motion: units, torque limits, software limits, homing.
//!     fn configure(&mut self, od: &OD, _scale: &BusScale, cfg: &mut AxisConfig) {
//!         cfg.software_limits.enabled &= read_int(od, 0x2010, 0) == Some(1);
//!     }
//!     // Refuse (or adjust) a command the manual says the drive ignores.
//!     fn before_command(&mut self, _d: &mut Drive, _ctx: &mut Ctx<'_, OD>, cmd: &mut Command) -> bool {
//!         if let Command::TargetVelocity(v) = cmd {
//!             *v = (*v).clamp(-100_000, 100_000);
//!         }
//!         true
//!     }
//!     // Vendor status objects, errors the device detects itself.
//!     fn after_step(&mut self, drive: &mut Drive, ctx: &mut Ctx<'_, OD>, status: &Status) {
//!         write_int(ctx.od_mut(), 0x2004, 0, i64::from(status.homed));
//!         if status.following_error_exceeded && drive.fault().is_none() {
//!             drive.raise(ctx, 0x8611, None); // looked up in the sidecar's [[error]] table
//!         }
//!     }
//!     // Manufacturer statusword bits (8, 14, 15), warning bit 7.
//!     fn statusword(&self, _d: &Drive, _od: &OD, _s: &Status, bits: &mut u16) {
//!         if self.refused > 0 {
//!             *bits |= 1 << 7;
//!         }
//!     }
//! }
//!
//! // The constructor DeviceApps calls (with DeviceApps::attach for traces).
//! fn app() -> Cia402App<generated::drcs::Dictionary, MyDrive> {
//!     Cia402App::new(MyDrive::default(), error_table(DeviceKind::Drcs))
//! }
//! # let _ = app();
//! ```
//!
//! Tests drive a device through real frames with `od-master` on a
//! [`VirtualBus`](crate::node::VirtualBus) (virtual time); `Sim::downcast` reaches the app
//! (`Node<Dictionary, Cia402App<Dictionary, MyDrive>>`) to change the mechanics
//! ([`Drive::axis_mut`]) or the vendor state.

pub mod akd;
pub mod cia402;
pub mod demo;
pub mod drcs;
pub mod drvi;
pub mod machine;
pub mod store;

use std::sync::{Arc, Mutex, OnceLock};

use devices::sidecar::{Reaction as SidecarReaction, Sidecar};

use crate::motion::Machine;
use crate::node::{Apps, DeviceKind, DriveApp};
use crate::trace::Trace;

pub use cia402::{ActiveFault, BusScale, Cia402App, Command, Drive, Vendor};

/// What the drive does when an error is raised (the sidecar's `reaction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reaction {
    /// Soft error: the axis stops with the quick stop ramp, then the drive is in Fault.
    QuickStop,
    /// Hard error: the power stage goes off at once, the axis coasts; the drive is in Fault.
    PowerOff,
    /// A warning: EMCY and 1003h, no state change.
    Warning,
    /// Reported (EMCY, 1003h), no reaction.
    None,
}

impl From<SidecarReaction> for Reaction {
    fn from(r: SidecarReaction) -> Self {
        match r {
            SidecarReaction::QuickStop => Reaction::QuickStop,
            SidecarReaction::PowerOff => Reaction::PowerOff,
            SidecarReaction::Warning => Reaction::Warning,
            SidecarReaction::None => Reaction::None,
        }
    }
}

/// One error a device can raise, as its sidecar lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ErrorSpec {
    /// CiA 301/402 error code (EMCY bytes 0-1, 603Fh, low word of 1003h).
    pub code: u16,
    /// Manufacturer-specific value (DRVI Table 6.34 "manufacturer parameter"); sent
    /// little-endian from EMCY byte 3 on.
    pub manufacturer: Option<u64>,
    /// The vendor's own name of the fault (AKD `F523`).
    pub vendor_code: Option<String>,
    /// 1001h bits to set; `None` takes od-runtime's bits for the code's class.
    pub register: Option<u8>,
    /// The manual's text.
    pub text: String,
    /// What the drive does.
    pub reaction: Reaction,
}

impl ErrorSpec {
    /// The 1001h bits the EMCY carries (the generic bit always included).
    pub fn register_bits(&self) -> u8 {
        self.register.unwrap_or_else(|| od_runtime::emcy::register_bits(self.code)) | od_runtime::emcy::REG_GENERIC
    }

    /// EMCY bytes 3..=7: the manufacturer value, little-endian (zero without one).
    pub fn info(&self) -> [u8; 5] {
        let mut info = [0u8; 5];
        if let Some(m) = self.manufacturer {
            info.copy_from_slice(&m.to_le_bytes()[..5]);
        }
        info
    }
}

/// A device's error table: every error of its sidecar, looked up by code (and manufacturer
/// value where codes repeat, as in DRVI Table 6.34: 2310h/0 over current, 2310h/11 I²T).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ErrorTable {
    errors: Vec<ErrorSpec>,
}

impl ErrorTable {
    /// A table from explicit entries.
    pub fn new(errors: Vec<ErrorSpec>) -> Self {
        Self { errors }
    }

    /// The `[[error]]` entries of a sidecar. Codes or manufacturer values that do not fit
    /// (a code above FFFFh, a negative manufacturer value) are skipped.
    pub fn from_sidecar(sidecar: &Sidecar) -> Self {
        let errors = sidecar
            .errors
            .iter()
            .filter_map(|e| {
                Some(ErrorSpec {
                    code: u16::try_from(e.code.0).ok()?,
                    manufacturer: match e.manufacturer {
                        Some(m) => Some(u64::try_from(m.0).ok()?),
                        None => None,
                    },
                    vendor_code: e.vendor_code.clone(),
                    register: match e.register {
                        Some(r) => Some(u8::try_from(r.0).ok()?),
                        None => None,
                    },
                    text: e.text.clone(),
                    reaction: e.reaction.into(),
                })
            })
            .collect();
        Self { errors }
    }

    /// Every entry, in sidecar order.
    pub fn entries(&self) -> &[ErrorSpec] {
        &self.errors
    }

    /// The entry for `code` with manufacturer value `manufacturer`: an exact match first, then
    /// (for `None`) the first entry with that code.
    pub fn find(&self, code: u16, manufacturer: Option<u64>) -> Option<&ErrorSpec> {
        self.errors
            .iter()
            .find(|e| e.code == code && e.manufacturer.unwrap_or(0) == manufacturer.unwrap_or(0))
            .or_else(|| manufacturer.is_none().then(|| self.errors.iter().find(|e| e.code == code)).flatten())
    }

    /// The entry with the vendor's fault name (`F523`), case-insensitive.
    pub fn find_vendor(&self, vendor_code: &str) -> Option<&ErrorSpec> {
        self.errors.iter().find(|e| e.vendor_code.as_deref().is_some_and(|v| v.eq_ignore_ascii_case(vendor_code)))
    }

    /// The entry for `code`/`manufacturer`, or, for a code the table lacks, a hard error
    /// (power off) with od-runtime's register bits: an unknown fault is never ignored.
    pub fn resolve(&self, code: u16, manufacturer: Option<u64>) -> ErrorSpec {
        self.find(code, manufacturer).cloned().unwrap_or_else(|| ErrorSpec {
            code,
            manufacturer,
            vendor_code: None,
            register: None,
            text: format!("error {code:04X}h (not in the device's table)"),
            reaction: Reaction::PowerOff,
        })
    }
}

/// The sidecar of a bundled device, parsed once (the files are compiled into the binary).
///
/// `None` only if a sidecar no longer parses, which `drives_common` tests rule out.
pub fn sidecar(kind: DeviceKind) -> Option<&'static Sidecar> {
    static DRVI: OnceLock<Option<Sidecar>> = OnceLock::new();
    static DRCS: OnceLock<Option<Sidecar>> = OnceLock::new();
    static AKD: OnceLock<Option<Sidecar>> = OnceLock::new();
    let (cell, name, text) = match kind {
        DeviceKind::Drvi => (&DRVI, "camozzi-drvi.toml", include_str!("../../../devices/camozzi-drvi.toml")),
        DeviceKind::Drcs => (&DRCS, "camozzi-drcs.toml", include_str!("../../../devices/camozzi-drcs.toml")),
        DeviceKind::Akd => (&AKD, "kollmorgen-akd.toml", include_str!("../../../devices/kollmorgen-akd.toml")),
    };
    cell.get_or_init(|| Sidecar::parse(name, text).ok()).as_ref()
}

/// The error table of a bundled device, built once from its sidecar (empty if the sidecar
/// does not parse, see [`sidecar`]).
pub fn error_table(kind: DeviceKind) -> Arc<ErrorTable> {
    static TABLES: OnceLock<[Arc<ErrorTable>; 3]> = OnceLock::new();
    let tables = TABLES.get_or_init(|| {
        DeviceKind::ALL.map(|k| Arc::new(sidecar(k).map(ErrorTable::from_sidecar).unwrap_or_default()))
    });
    let i = DeviceKind::ALL.iter().position(|k| *k == kind).unwrap_or(0);
    Arc::clone(&tables[i])
}

/// A trace shared between a running drive (which records into it every tick) and whoever
/// writes it out (`drive-sim --trace`, a test).
pub type SharedTrace = Arc<Mutex<Trace>>;

/// The applications of the project's devices: what `drive-sim` runs.
///
/// With [`DeviceApps::with_trace`] every app it builds records a [`SharedTrace`]; they are
/// kept in build order ([`DeviceApps::traces`]).
#[derive(Debug, Default)]
pub struct DeviceApps {
    trace_interval: Option<u64>,
    traces: Mutex<Vec<(DeviceKind, SharedTrace)>>,
    machine: Mutex<Option<Machine>>,
}

impl DeviceApps {
    /// Apps without traces.
    pub fn new() -> Self {
        Self::default()
    }

    /// Apps recording a trace with one sample per `interval_us` (0: every tick).
    pub fn with_trace(interval_us: u64) -> Self {
        Self { trace_interval: Some(interval_us), ..Self::default() }
    }

    /// The machine of the apps built from now on (`None`: each device's default, see
    /// [`machine`]); `drive-sim run --machine` sets it before building each device.
    pub fn set_machine(&self, machine: Option<Machine>) {
        if let Ok(mut m) = self.machine.lock() {
            *m = machine;
        }
    }

    fn machine_for(&self, kind: DeviceKind) -> Machine {
        self.machine.lock().ok().and_then(|m| m.clone()).unwrap_or_else(|| machine::default_machine(kind))
    }

    /// The traces of the apps built so far, in build order, with their device kind.
    pub fn traces(&self) -> Vec<(DeviceKind, SharedTrace)> {
        self.traces.lock().map(|t| t.clone()).unwrap_or_default()
    }

    /// Gives `app` a trace when traces are on (and remembers it): what each device method of
    /// `impl Apps for DeviceApps` calls on the app it built.
    pub fn attach<OD, V>(&self, kind: DeviceKind, mut app: Cia402App<OD, V>) -> Cia402App<OD, V> {
        if let Some(interval) = self.trace_interval {
            let trace: SharedTrace = Arc::new(Mutex::new(Trace::with_interval(interval)));
            if let Ok(mut traces) = self.traces.lock() {
                traces.push((kind, Arc::clone(&trace)));
            }
            app.drive_mut().set_trace(Some(trace));
        }
        app
    }
}

impl Apps for DeviceApps {
    fn drvi(&self) -> Box<dyn DriveApp<generated::drvi::Dictionary> + Send> {
        Box::new(self.attach(DeviceKind::Drvi, drvi::app_with(&self.machine_for(DeviceKind::Drvi))))
    }

    fn akd(&self) -> Box<dyn DriveApp<generated::akd::Dictionary> + Send> {
        Box::new(self.attach(DeviceKind::Akd, akd::app_with(&self.machine_for(DeviceKind::Akd))))
    }

    fn drcs(&self) -> Box<dyn DriveApp<generated::drcs::Dictionary> + Send> {
        Box::new(self.attach(DeviceKind::Drcs, drcs::app_on(&self.machine_for(DeviceKind::Drcs))))
    }
}
