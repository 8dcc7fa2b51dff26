//! The CiA 402 drive state machine (device control, CiA 402-2 §6.2).
//!
//! [`StateMachine`] is pure: it turns controlword values and drive events into transitions and
//! statusword bits. [`Device`](crate::Device) runs it for any dictionary that has 6040h
//! (controlword) and 6041h (statusword); the motion itself (ramps, the quick stop and fault
//! reactions) belongs to the application, which learns about transitions through
//! [`Event::Cia402`](crate::Event::Cia402) and reports back with
//! [`Device::quick_stop_done`](crate::Device::quick_stop_done) and
//! [`Device::fault_reaction_done`](crate::Device::fault_reaction_done).
//!
//! Transition 0 (power on → Not ready to switch on) is the creation of the state machine at
//! reset node and has no event; transition 1 follows at once, as the runtime has no
//! initialisation of its own to wait for.
//!
//! ```text
//!        (0) ──► Not ready to switch on ──(1)──► Switch on disabled ◄─────────(15)── Fault
//!                                          (2)│ ▲(7)  ▲(10)  ▲(9)  ▲(12)           ▲ (14)
//!                                             ▼ │     │      │      │       Fault reaction active
//!                                     Ready to switch on     │      │              ▲ (13) from
//!                                          (3)│ ▲(6)  │ ▲(8) │      │              any state
//!                                             ▼ │     │ │    │      │
//!                                         Switched on ┘ │    │      │
//!                                          (4)│ ▲(5)    │    │      │
//!                                             ▼ │       │    │      │
//!                                      Operation enabled ────┴─(11)─► Quick stop active
//!                                             ▲                           │(16)
//!                                             └───────────────────────────┘
//! ```

/// A state of the CiA 402 power drive state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum State {
    /// Initialising; the drive function is disabled.
    NotReadyToSwitchOn,
    /// Initialised; high voltage may be applied, the drive function is disabled.
    SwitchOnDisabled,
    /// High voltage applied, drive function disabled.
    ReadyToSwitchOn,
    /// Power amplifier ready, drive function disabled.
    SwitchedOn,
    /// The drive function is enabled and power is applied to the motor.
    OperationEnabled,
    /// The quick stop function is being executed (or done, for option codes 5..=8).
    QuickStopActive,
    /// A fault occurred; the fault reaction is being executed.
    FaultReactionActive,
    /// The fault reaction is done; the drive function is disabled.
    Fault,
}

impl State {
    /// The state's name as CiA 402 writes it ("Switch on disabled", "Operation enabled", ...).
    pub const fn name(self) -> &'static str {
        match self {
            State::NotReadyToSwitchOn => "Not ready to switch on",
            State::SwitchOnDisabled => "Switch on disabled",
            State::ReadyToSwitchOn => "Ready to switch on",
            State::SwitchedOn => "Switched on",
            State::OperationEnabled => "Operation enabled",
            State::QuickStopActive => "Quick stop active",
            State::FaultReactionActive => "Fault reaction active",
            State::Fault => "Fault",
        }
    }

    /// Statusword bits 0..=6 of this state (bit 4, voltage enabled, set whenever the power
    /// stage may carry voltage).
    pub const fn statusword_bits(self) -> u16 {
        match self {
            State::NotReadyToSwitchOn => 0x0000,
            State::SwitchOnDisabled => 0x0040,
            State::ReadyToSwitchOn => 0x0031,
            State::SwitchedOn => 0x0033,
            State::OperationEnabled => 0x0037,
            State::QuickStopActive => 0x0017,
            State::FaultReactionActive => 0x001F,
            State::Fault => 0x0008,
        }
    }

    /// Decodes the state from a statusword (bits 0..=3, 5, 6, as CiA 402 Table 30 lists them);
    /// `None` for a combination the standard does not define.
    pub const fn from_statusword(sw: u16) -> Option<Self> {
        if sw & 0x4F == 0x00 {
            return Some(State::NotReadyToSwitchOn);
        }
        if sw & 0x4F == 0x40 {
            return Some(State::SwitchOnDisabled);
        }
        if sw & 0x4F == 0x0F {
            return Some(State::FaultReactionActive);
        }
        if sw & 0x4F == 0x08 {
            return Some(State::Fault);
        }
        match sw & 0x6F {
            0x21 => Some(State::ReadyToSwitchOn),
            0x23 => Some(State::SwitchedOn),
            0x27 => Some(State::OperationEnabled),
            0x07 => Some(State::QuickStopActive),
            _ => None,
        }
    }
}

/// A device control command decoded from controlword bits 0..=3 and 7 (CiA 402 Table 28).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `0xxx x110`: transitions 2, 6, 8.
    Shutdown,
    /// `0xxx 0111`: transition 3 (and 5, as "disable operation", from Operation enabled).
    SwitchOn,
    /// `0xxx 1111`: transitions 4 and 16 (3 + 4 from Ready to switch on).
    EnableOperation,
    /// `0xxx xx0x`: transitions 7, 9, 10, 12.
    DisableVoltage,
    /// `0xxx x01x`: transitions 7, 10, 11.
    QuickStop,
    /// Bit 7 went from 0 to 1: transition 15.
    FaultReset,
    /// No command (bit 7 held at 1).
    None,
}

impl Command {
    /// Decodes `cw`, given the previous controlword `prev` (for the fault reset edge).
    pub const fn decode(cw: u16, prev: u16) -> Self {
        if cw & 0x80 != 0 {
            return if prev & 0x80 == 0 { Command::FaultReset } else { Command::None };
        }
        if cw & 0x02 == 0 {
            Command::DisableVoltage
        } else if cw & 0x04 == 0 {
            Command::QuickStop
        } else if cw & 0x01 == 0 {
            Command::Shutdown
        } else if cw & 0x08 == 0 {
            Command::SwitchOn
        } else {
            Command::EnableOperation
        }
    }
}

/// One transition of the state machine, numbered as in CiA 402.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Transition {
    /// Transition number, 0..=16.
    pub number: u8,
    /// State before.
    pub from: State,
    /// State after.
    pub to: State,
}

/// Up to two transitions caused by one input (`Switch on + enable operation` from Ready to
/// switch on is 3 then 4; quick stop with option code 0 is 11 then 12).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Transitions {
    items: [Option<Transition>; 2],
}

impl Transitions {
    fn push(&mut self, t: Transition) {
        if self.items[0].is_none() {
            self.items[0] = Some(t);
        } else {
            self.items[1] = Some(t);
        }
    }

    /// Whether no transition happened.
    pub fn is_empty(&self) -> bool {
        self.items[0].is_none()
    }

    /// The transitions in order.
    pub fn iter(&self) -> impl Iterator<Item = Transition> + '_ {
        self.items.iter().flatten().copied()
    }
}

/// The state machine with the controlword edge memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateMachine {
    state: State,
    prev_cw: u16,
}

impl Default for StateMachine {
    fn default() -> Self {
        Self::new()
    }
}

impl StateMachine {
    /// A state machine in Not ready to switch on.
    pub const fn new() -> Self {
        Self { state: State::NotReadyToSwitchOn, prev_cw: 0 }
    }

    /// The current state.
    pub const fn state(&self) -> State {
        self.state
    }

    #[cfg_attr(target_os = "none", inline(never))]
    fn go(&mut self, out: &mut Transitions, number: u8, to: State) {
        out.push(Transition { number, from: self.state, to });
        self.state = to;
    }

    /// Transition 1: initialisation finished (Not ready to switch on → Switch on disabled).
    pub fn initialised(&mut self) -> Transitions {
        let mut out = Transitions::default();
        if self.state == State::NotReadyToSwitchOn {
            self.go(&mut out, 1, State::SwitchOnDisabled);
        }
        out
    }

    /// Applies a controlword written by the master. `quick_stop_option` is 605Ah (2 when the
    /// dictionary lacks it): 0 leaves Quick stop active at once (11 then 12), 5..=8 keep the
    /// drive in Quick stop active, where enable operation returns to Operation enabled (16).
    pub fn controlword(&mut self, cw: u16, quick_stop_option: i16) -> Transitions {
        let cmd = Command::decode(cw, self.prev_cw);
        self.prev_cw = cw;
        let mut out = Transitions::default();
        use Command as C;
        use State as S;
        match (self.state, cmd) {
            (S::SwitchOnDisabled, C::Shutdown) => self.go(&mut out, 2, S::ReadyToSwitchOn),
            (S::ReadyToSwitchOn, C::SwitchOn) => self.go(&mut out, 3, S::SwitchedOn),
            (S::ReadyToSwitchOn, C::EnableOperation) => {
                self.go(&mut out, 3, S::SwitchedOn);
                self.go(&mut out, 4, S::OperationEnabled);
            }
            (S::ReadyToSwitchOn, C::DisableVoltage | C::QuickStop) => self.go(&mut out, 7, S::SwitchOnDisabled),
            (S::SwitchedOn, C::EnableOperation) => self.go(&mut out, 4, S::OperationEnabled),
            (S::SwitchedOn, C::Shutdown) => self.go(&mut out, 6, S::ReadyToSwitchOn),
            (S::SwitchedOn, C::DisableVoltage | C::QuickStop) => self.go(&mut out, 10, S::SwitchOnDisabled),
            (S::OperationEnabled, C::SwitchOn) => self.go(&mut out, 5, S::SwitchedOn),
            (S::OperationEnabled, C::Shutdown) => self.go(&mut out, 8, S::ReadyToSwitchOn),
            (S::OperationEnabled, C::DisableVoltage) => self.go(&mut out, 9, S::SwitchOnDisabled),
            (S::OperationEnabled, C::QuickStop) => {
                self.go(&mut out, 11, S::QuickStopActive);
                if quick_stop_option == 0 {
                    self.go(&mut out, 12, S::SwitchOnDisabled);
                }
            }
            (S::QuickStopActive, C::DisableVoltage) => self.go(&mut out, 12, S::SwitchOnDisabled),
            (S::QuickStopActive, C::EnableOperation) if (5..=8).contains(&quick_stop_option) => {
                self.go(&mut out, 16, S::OperationEnabled)
            }
            (S::Fault, C::FaultReset) => self.go(&mut out, 15, S::SwitchOnDisabled),
            _ => {}
        }
        out
    }

    /// Transition 12 when the quick stop reaction is complete and 605Ah is 0..=4 (the drive
    /// leaves for Switch on disabled); nothing for 5..=8 (it stays in Quick stop active).
    pub fn quick_stop_done(&mut self, quick_stop_option: i16) -> Transitions {
        let mut out = Transitions::default();
        if self.state == State::QuickStopActive && (0..=4).contains(&quick_stop_option) {
            self.go(&mut out, 12, State::SwitchOnDisabled);
        }
        out
    }

    /// Transition 13: a fault occurred (from any state but the fault states).
    pub fn fault(&mut self) -> Transitions {
        let mut out = Transitions::default();
        if !matches!(self.state, State::FaultReactionActive | State::Fault) {
            self.go(&mut out, 13, State::FaultReactionActive);
        }
        out
    }

    /// Transition 15 without a controlword edge: a fault reset the device accepts another way
    /// (the Camozzi DRVI also resets on 0 written to 1003h sub 0). Nothing outside Fault.
    pub fn fault_reset(&mut self) -> Transitions {
        let mut out = Transitions::default();
        if self.state == State::Fault {
            self.go(&mut out, 15, State::SwitchOnDisabled);
        }
        out
    }

    /// Transition 14: the fault reaction is complete.
    pub fn fault_reaction_done(&mut self) -> Transitions {
        let mut out = Transitions::default();
        if self.state == State::FaultReactionActive {
            self.go(&mut out, 14, State::Fault);
        }
        out
    }
}
