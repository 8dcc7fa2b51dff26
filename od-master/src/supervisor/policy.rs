//! What the supervisor does, decided without I/O and without a clock: the policy is data
//! ([`NodeSupervision`], [`NetworkSupervision`], from the network description or a master DCF's
//! 1F80h/1F81h), [`decide`] turns what happened to a node into the actions to take. The async
//! shell ([`Supervisor`](super::Supervisor)) carries them out and keeps the timers.

// The settings are written once, in `od_sidecar::supervision`: the network description's reader
// (od_codegen::network, with the feature `network-description`) fills the same types.
pub use od_sidecar::supervision::{FailureAction, NetworkSupervision, NodeSupervision};

/// What happened to a node, as the supervisor's loop saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// A boot-up message at run time: the node restarted with its defaults.
    BootUp,
    /// Its heartbeat (or guarding) was lost.
    Lost,
    /// It was heard again after a loss.
    Recovered,
    /// The reset delay after a loss ran out and the node is still lost.
    StillLost,
    /// Its boot process succeeded.
    Booted,
    /// Its boot process failed; `failures` in a row so far, this one included.
    BootFailed {
        /// Consecutive failures, at least 1.
        failures: u32,
    },
}

/// What to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    /// Run the node's boot process (identity, configuration, start rules) for it alone.
    Configure,
    /// Wait this many ms, then decide on [`Input::StillLost`] unless the node came back.
    ResetAfter(u32),
    /// NMT reset node to this node alone.
    ResetNode,
    /// NMT stop to all nodes.
    StopAll,
    /// NMT reset node to all nodes.
    ResetAll,
    /// Nothing more will be done for this node until it boots again (the bounded retries are
    /// used up); reported.
    GiveUp,
}

impl Action {
    fn of(failure: FailureAction) -> Option<Action> {
        match failure {
            FailureAction::Report => None,
            FailureAction::ResetNode => Some(Action::ResetNode),
            FailureAction::StopAll => Some(Action::StopAll),
            FailureAction::ResetAll => Some(Action::ResetAll),
        }
    }

    /// Its name, as `--json` writes it.
    pub fn name(self) -> &'static str {
        match self {
            Action::Configure => "configure",
            Action::ResetAfter(_) => "reset_after",
            Action::ResetNode => "reset_node",
            Action::StopAll => "stop_all",
            Action::ResetAll => "reset_all",
            Action::GiveUp => "give_up",
        }
    }
}

/// The actions for `input` on a node supervised by `node` in a network supervised by
/// `network`. At most one action: the supervisor does one thing at a time per node.
///
/// - a boot-up: configure it again (unless the master does not configure it);
/// - lost: nothing when `on_lost` is report, else wait `reset_delay_ms` ([`Action::ResetAfter`])
///   and, still lost then, `on_lost` (a network-wide action only for a mandatory node; for an
///   optional one it is reported only);
/// - a failed boot: a mandatory node gets the network's `on_mandatory_failure`, an optional
///   one is reported; once `boot_attempts` boots in a row failed, [`Action::GiveUp`]: no action
///   that would boot it again, so a node that can never boot is never reset in a loop.
pub fn decide(node: &NodeSupervision, network: &NetworkSupervision, input: Input) -> Option<Action> {
    match input {
        Input::BootUp => node.configure.then_some(Action::Configure),
        Input::Lost => match node.on_lost {
            FailureAction::Report => None,
            _ => Some(Action::ResetAfter(node.reset_delay_ms)),
        },
        Input::StillLost => allowed(node, node.on_lost),
        Input::Recovered | Input::Booted => None,
        Input::BootFailed { failures } => {
            let action = if node.mandatory { Action::of(network.on_mandatory_failure) } else { None };
            match action {
                Some(_) if failures >= network.boot_attempts.max(1) => Some(Action::GiveUp),
                a => a,
            }
        }
    }
}

/// `failure` for `node`: network-wide actions only for a mandatory node.
fn allowed(node: &NodeSupervision, failure: FailureAction) -> Option<Action> {
    if failure.is_network_wide() && !node.mandatory {
        return None;
    }
    Action::of(failure)
}

/// The master's heartbeat consumer time for a node: the description's `heartbeat_timeout_ms`,
/// else twice its producer time plus 50 ms (one heartbeat may be late, not two); `None` when
/// it produces no heartbeat or 0 was given.
pub fn consumer_time_ms(node: &NodeSupervision, producer_ms: u16) -> Option<u32> {
    let ms = node.heartbeat_timeout_ms.unwrap_or(if producer_ms == 0 { 0 } else { 2 * u32::from(producer_ms) + 50 });
    (ms > 0).then_some(ms)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(mandatory: bool, on_lost: FailureAction) -> NodeSupervision {
        NodeSupervision { mandatory, on_lost, reset_delay_ms: 200, ..NodeSupervision::default() }
    }

    #[test]
    fn decisions() {
        use FailureAction::*;
        let net = |on_mandatory_failure| NetworkSupervision { on_mandatory_failure, boot_attempts: 3 };
        #[rustfmt::skip]
        let table: &[(bool, FailureAction, FailureAction, Input, Option<Action>)] = &[
            // mandatory, on_lost, on_mandatory_failure, input, action
            (false, Report, Report, Input::BootUp, Some(Action::Configure)),
            (true, Report, ResetAll, Input::BootUp, Some(Action::Configure)),
            (false, Report, Report, Input::Lost, None),
            (false, ResetNode, Report, Input::Lost, Some(Action::ResetAfter(200))),
            (false, ResetNode, Report, Input::StillLost, Some(Action::ResetNode)),
            (false, ResetNode, Report, Input::Recovered, None),
            (true, StopAll, Report, Input::StillLost, Some(Action::StopAll)),
            (true, ResetAll, Report, Input::StillLost, Some(Action::ResetAll)),
            // An optional node never acts on the others, whatever it says.
            (false, StopAll, Report, Input::StillLost, None),
            (false, ResetAll, ResetAll, Input::BootFailed { failures: 1 }, None),
            (true, Report, Report, Input::BootFailed { failures: 1 }, None),
            (true, Report, ResetNode, Input::BootFailed { failures: 1 }, Some(Action::ResetNode)),
            (true, Report, StopAll, Input::BootFailed { failures: 1 }, Some(Action::StopAll)),
            (true, Report, ResetAll, Input::BootFailed { failures: 2 }, Some(Action::ResetAll)),
            (true, Report, ResetAll, Input::BootFailed { failures: 3 }, Some(Action::GiveUp)),
            (true, Report, ResetNode, Input::BootFailed { failures: 7 }, Some(Action::GiveUp)),
            (true, Report, Report, Input::BootFailed { failures: 7 }, None),
            (true, Report, ResetAll, Input::Booted, None),
        ];
        for &(mandatory, on_lost, failure, input, want) in table {
            let got = decide(&node(mandatory, on_lost), &net(failure), input);
            assert_eq!(got, want, "mandatory {mandatory}, on_lost {on_lost:?}, network {failure:?}, {input:?}");
        }
        let unconfigured = NodeSupervision { configure: false, ..NodeSupervision::default() };
        assert_eq!(decide(&unconfigured, &NetworkSupervision::default(), Input::BootUp), None);
    }

    #[test]
    fn consumer_times() {
        let d = NodeSupervision::default();
        assert_eq!(consumer_time_ms(&d, 100), Some(250));
        assert_eq!(consumer_time_ms(&d, 0), None);
        let given = NodeSupervision { heartbeat_timeout_ms: Some(120), ..d };
        assert_eq!(consumer_time_ms(&given, 100), Some(120));
        let off = NodeSupervision { heartbeat_timeout_ms: Some(0), ..d };
        assert_eq!(consumer_time_ms(&off, 100), None);
    }

    #[test]
    fn cia_302_objects() {
        // 1F81h: listed, configure, mandatory, keep-alive, retry factor 4, guard time 300 ms.
        let n = NodeSupervision::from_1f81(0x012C_0000 | 0x0400 | 0b1_1101);
        assert!(n.mandatory && n.keep_alive && n.configure && n.start);
        assert_eq!((n.guard_time_ms, n.life_time_factor), (300, 4));
        let unlisted = NodeSupervision::from_1f81(0b1_1100);
        assert!(!unlisted.configure && !unlisted.start && !unlisted.mandatory);
        assert_eq!(NetworkSupervision::from_1f80(0x41).on_mandatory_failure, FailureAction::StopAll);
        assert_eq!(NetworkSupervision::from_1f80(0x51).on_mandatory_failure, FailureAction::StopAll);
        assert_eq!(NetworkSupervision::from_1f80(0x11).on_mandatory_failure, FailureAction::ResetAll);
        assert_eq!(NetworkSupervision::from_1f80(0x01).on_mandatory_failure, FailureAction::Report);
    }
}
