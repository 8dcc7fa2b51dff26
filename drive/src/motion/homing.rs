//! Homing: finding the machine's reference point and defining the position frame from it.
//!
//! A homing method is described by a [`HomingMethod`]: what it looks for (a limit switch, the
//! home switch, a hard end stop, an index pulse, or nothing), in which direction it searches
//! first, and on which edge of the signal, approached in which direction, the home point lies.
//! [`HomingMethod::cia402`] and [`HomingMethod::camozzi`] translate the 6098h codes of the two
//! families of devices into descriptions; the sequence itself is the same for every method:
//!
//! 1. **search** at the fast speed (6099h sub 1) until the signal becomes active (skipped when
//!    it is active at the start);
//! 2. **stop**, and when the home edge is entered (rather than left) **back off** until the
//!    signal is inactive again and stop;
//! 3. **approach** the edge at the slow speed (6099h sub 2) and latch its exact position;
//! 4. with an index pulse, the home point is the first index pulse beyond the edge in the
//!    approach direction; otherwise it is the edge itself;
//! 5. **move to the home point** at the slow speed and stop on it; then the position frame is
//!    set from the home offset (607Ch) as [`HomeOffsetMode`] says.
//!
//! Torque homing (DRVI -1..-4) pushes against a hard end stop with the torque limited to the
//! homing torque limit; the end stop is found when the torque has reached the threshold while
//! the axis stands still for [`HomingConfig::stall_time_us`].
//!
//! Homing works in the mechanical frame: "negative" is the motor's negative direction and the
//! switches are those of [`crate::motion::Environment`].

use super::plant::{Environment, Sensor};

/// A direction of travel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Towards lower positions.
    Negative,
    /// Towards higher positions.
    Positive,
}

impl Direction {
    pub(crate) fn sign(self) -> f64 {
        match self {
            Direction::Negative => -1.0,
            Direction::Positive => 1.0,
        }
    }
}

/// The sensor a switch-based homing method looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingSignal {
    /// The negative limit switch.
    NegativeLimit,
    /// The positive limit switch.
    PositiveLimit,
    /// The home switch (proximity, reference cam).
    HomeSwitch,
}

impl HomingSignal {
    fn sensor(self) -> Sensor {
        match self {
            HomingSignal::NegativeLimit => Sensor::NegativeLimit,
            HomingSignal::PositiveLimit => Sensor::PositiveLimit,
            HomingSignal::HomeSwitch => Sensor::Home,
        }
    }
}

/// Which edge of the signal is the home edge, seen while moving in the approach direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    /// The signal becomes active.
    Rising,
    /// The signal becomes inactive.
    Falling,
}

/// What a homing method does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingKind {
    /// The current position is the home point; nothing moves (CiA 402 methods 35 and 37).
    CurrentPosition,
    /// Search a switch and home on one of its edges, optionally on the next index pulse after it.
    Switch {
        /// The sensor.
        signal: HomingSignal,
        /// Direction of the fast search.
        search: Direction,
        /// Direction in which the home edge is approached at the slow speed.
        approach: Direction,
        /// The home edge as seen while approaching.
        edge: Edge,
        /// Home on the first index pulse beyond the edge (in the approach direction).
        index: bool,
        /// A limit switch met during the search reverses it (CiA 402 methods 7 to 14 and 23 to
        /// 30); otherwise a limit switch in the search direction ends homing with an error.
        reverse_at_limit: bool,
        /// Stopping beyond the whole switch after the search is an error (the Camozzi
        /// "proximity surpassed" case) instead of being recovered by moving back.
        overshoot_is_error: bool,
    },
    /// Push against the hard end stop in `search` direction until the torque threshold is
    /// reached (Camozzi torque homing); optionally then move back to the next index pulse.
    EndStop {
        /// Direction of the search.
        search: Direction,
        /// Home on the first index pulse found moving back from the end stop.
        index: bool,
    },
    /// Home on the next index pulse in this direction (CiA 402 methods 33 and 34).
    Index {
        /// Direction of the search.
        dir: Direction,
    },
}

/// A homing method: the 6098h code it was made from and what it does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HomingMethod {
    /// The 6098h value.
    pub code: i8,
    /// The behaviour.
    pub kind: HomingKind,
}

impl HomingMethod {
    /// CiA 402 homing methods: 1 to 14, 17 to 30, 33 to 35, and 37.
    ///
    /// * 1/2 (17/18 without index): the negative/positive limit switch, left in the opposite
    ///   direction; home on its edge or the next index pulse.
    /// * 3 to 6 (19 to 22): a home switch active on one side (a cam with an open end): 3/4 search
    ///   positive and home left/right of its edge, 5/6 search negative and home right/left.
    /// * 7 to 14 (23 to 30): a home cam with limit switch reversal: 7 to 10 search positive and
    ///   home at the left edge left of it (7), left edge right of it (8), right edge left (9),
    ///   right edge right (10); 11 to 14 search negative: right edge right (11), right edge left
    ///   (12), left edge right (13), left edge left (14).
    /// * 33/34: the next index pulse in the negative/positive direction.
    /// * 35 and 37: the current position.
    pub fn cia402(code: i8) -> Option<HomingMethod> {
        use Direction::{Negative as N, Positive as P};
        use Edge::{Falling as F, Rising as R};
        use HomingSignal::{HomeSwitch as H, NegativeLimit as NL, PositiveLimit as PL};
        let switch = |signal, search, approach, edge, index, reverse_at_limit| HomingKind::Switch {
            signal,
            search,
            approach,
            edge,
            index,
            reverse_at_limit,
            overshoot_is_error: false,
        };
        // (signal, search, approach, edge, reverse at limit) of methods 1..=14; 17..=30 repeat
        // them without the index pulse.
        let table = |n: i8| match n {
            1 => Some((NL, N, P, F, false)),
            2 => Some((PL, P, N, F, false)),
            3 => Some((H, P, N, F, false)),
            4 => Some((H, P, P, R, false)),
            5 => Some((H, N, P, F, false)),
            6 => Some((H, N, N, R, false)),
            7 => Some((H, P, N, F, true)),
            8 => Some((H, P, P, R, true)),
            9 => Some((H, P, N, R, true)),
            10 => Some((H, P, P, F, true)),
            11 => Some((H, N, P, F, true)),
            12 => Some((H, N, N, R, true)),
            13 => Some((H, N, P, R, true)),
            14 => Some((H, N, N, F, true)),
            _ => None,
        };
        let kind = match code {
            1..=14 => {
                let (s, d, a, e, r) = table(code)?;
                switch(s, d, a, e, true, r)
            }
            17..=30 => {
                let (s, d, a, e, r) = table(code - 16)?;
                switch(s, d, a, e, false, r)
            }
            33 => HomingKind::Index { dir: N },
            34 => HomingKind::Index { dir: P },
            35 | 37 => HomingKind::CurrentPosition,
            _ => return None,
        };
        Some(HomingMethod { code, kind })
    }

    /// The Camozzi DRVI and DRCS methods (DRVI Table 6.29 and chapter 4.1.5, DRCS chapter 7).
    ///
    /// The Camozzi "proximity" methods use the home switch, not a limit switch: 17/18 search it
    /// in the negative/positive direction at the fast speed, stop, and leave it in the opposite
    /// direction at the slow speed; home is where it turns off. 1/2 then continue to the next
    /// index pulse. A proximity already active at the start begins with the slow phase; stopping
    /// beyond it is an error; a limit switch in the search direction is an error. 37 takes the
    /// current position. -3/-4 push against the negative/positive end stop until the torque
    /// reaches the threshold and home there; -1/-2 then move back to the next index pulse.
    pub fn camozzi(code: i8) -> Option<HomingMethod> {
        use Direction::{Negative as N, Positive as P};
        let proximity = |search: Direction, index| HomingKind::Switch {
            signal: HomingSignal::HomeSwitch,
            search,
            approach: if search == N { P } else { N },
            edge: Edge::Falling,
            index,
            reverse_at_limit: false,
            overshoot_is_error: true,
        };
        let kind = match code {
            1 => proximity(N, true),
            2 => proximity(P, true),
            17 => proximity(N, false),
            18 => proximity(P, false),
            37 => HomingKind::CurrentPosition,
            -1 => HomingKind::EndStop { search: N, index: true },
            -2 => HomingKind::EndStop { search: P, index: true },
            -3 => HomingKind::EndStop { search: N, index: false },
            -4 => HomingKind::EndStop { search: P, index: false },
            _ => return None,
        };
        Some(HomingMethod { code, kind })
    }
}

/// How the home offset 607Ch defines the position frame once the home point is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HomeOffsetMode {
    /// The home point reads as the home offset (DRVI 6.3.4.14: "sets the actual position to the
    /// offset value"; the AKD HOME.P).
    #[default]
    AssignOffset,
    /// The zero position lies `offset` beyond the home point, so the home point reads as
    /// `-offset` (the wording of CiA 402: zero = home + offset).
    AssignNegatedOffset,
    /// Move by the offset from the home point and make that position zero (DRCS 3.4.13).
    MoveByOffset,
}

/// Homing parameters, in raw device units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomingConfig {
    /// The method (from 6098h through [`HomingMethod::cia402`] or [`HomingMethod::camozzi`]).
    pub method: HomingMethod,
    /// Speed while searching the switch (6099h sub 1), raw velocity units.
    pub search_speed: u32,
    /// Speed while approaching the edge and the index pulse (6099h sub 2), raw velocity units.
    pub zero_speed: u32,
    /// Acceleration (609Ah; the DRCS uses 6083h), raw acceleration units.
    pub acceleration: u32,
    /// Deceleration (609Ah; the DRCS uses 6084h), raw acceleration units.
    pub deceleration: u32,
    /// Home offset 607Ch, position units.
    pub offset: i32,
    /// What the offset means.
    pub offset_mode: HomeOffsetMode,
    /// Torque limit while pushing against an end stop (DRVI 6071h); 0 = the axis limit.
    pub torque_limit: u32,
    /// Torque at which the end stop counts as found (DRVI 2013h as a torque); 0 = the limit.
    pub torque_threshold: u32,
    /// How long the axis must stand still at the threshold (or be blocked) to count, µs.
    pub stall_time_us: u32,
    /// Homing fails after this long, µs; 0 = no timeout.
    pub timeout_us: u64,
}

impl Default for HomingConfig {
    fn default() -> Self {
        HomingConfig {
            method: HomingMethod { code: 37, kind: HomingKind::CurrentPosition },
            search_speed: 0,
            zero_speed: 0,
            acceleration: 0,
            deceleration: 0,
            offset: 0,
            offset_mode: HomeOffsetMode::AssignOffset,
            torque_limit: 0,
            torque_threshold: 0,
            stall_time_us: 10_000,
            timeout_us: 0,
        }
    }
}

/// Why homing failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingError {
    /// The timeout elapsed.
    Timeout,
    /// The axis stopped beyond the home switch after the search (speed too high for the
    /// deceleration, DRVI 4.1.5.2).
    SwitchOvershoot,
    /// The signal was not found: a limit switch was reached (twice, with reversal).
    NotFound,
    /// The axis is blocked (pressed against an end stop) where it should move.
    Blocked,
    /// The method needs an index pulse and the encoder has none.
    NoIndexPulse,
    /// A speed, acceleration or deceleration needed by the method is zero.
    InvalidParameters,
}

/// The homing state, from which the caller derives statusword bits 10, 12 and 13.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum HomingState {
    /// Homing was not started (since the last mode change or power-up).
    #[default]
    Idle,
    /// Searching.
    InProgress,
    /// The home point is known; the axis is moving onto it.
    Attained,
    /// Homing completed: the axis stands on the home point and the frame is set.
    Completed,
    /// Halted, aborted or the power stage was switched off.
    Interrupted,
    /// Failed (the axis stops).
    Error(HomingError),
}

impl HomingState {
    /// Statusword bits `(10 target reached, 12 homing attained, 13 homing error)` as CiA 402
    /// defines them for homing mode, given whether the axis stands still:
    ///
    /// | state | 13 | 12 | 10 |
    /// |---|---|---|---|
    /// | in progress | 0 | 0 | 0 |
    /// | interrupted or not started | 0 | 0 | 1 |
    /// | attained, target not reached | 0 | 1 | 0 |
    /// | completed | 0 | 1 | 1 |
    /// | error, still moving | 1 | 0 | 0 |
    /// | error, standing | 1 | 0 | 1 |
    pub fn statusword_bits(self, standing: bool) -> (bool, bool, bool) {
        match self {
            HomingState::InProgress => (false, false, false),
            HomingState::Idle | HomingState::Interrupted => (true, false, false),
            HomingState::Attained => (false, true, false),
            HomingState::Completed => (true, true, false),
            HomingState::Error(_) => (standing, false, true),
        }
    }
}

/// What the homing sequence asks the axis to do (mechanical frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Cmd {
    /// Keep going.
    None,
    /// Ramp to this velocity.
    Velocity(f64),
    /// Ramp to standstill.
    Stop,
    /// Move to this position at this speed; `resync` first drops the demand onto the actual
    /// position (after pushing against an end stop).
    MoveTo { m: f64, speed: f64, resync: bool },
    /// Move by the home offset (DRCS).
    OffsetMove,
    /// Done: the home point (mechanical) and the position the axis stands at.
    Complete { home: f64, at: f64 },
    /// Failed.
    Fail(HomingError),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum After {
    /// The signal was found while searching in direction `dir`.
    Found {
        dir: f64,
    },
    Search {
        dir: f64,
        reversed: bool,
    },
    BackedOff,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Search { dir: f64, reversed: bool },
    Stop(After),
    Backoff { dir: f64, seen_active: bool },
    Approach { dir: f64, seen_active: bool },
    Push { dir: f64, stalled_us: u64 },
    ToHome { home: f64 },
    Offset { home: f64 },
    Done,
}

/// What the sequence sees after each step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Observation<'a> {
    pub(crate) env: &'a Environment,
    /// Mechanical position before and after the step.
    pub(crate) from: f64,
    pub(crate) to: f64,
    /// Mechanical velocity after the step.
    pub(crate) v: f64,
    /// Torque after the step.
    pub(crate) torque: f64,
    /// The demand stands still and so does the axis.
    pub(crate) stopped: bool,
    /// The axis is pressed against an end stop.
    pub(crate) at_end_stop: bool,
    /// Step length, µs.
    pub(crate) dt_us: u64,
}

/// A running homing sequence. Speeds are in mechanical position units per second.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Sequence {
    kind: HomingKind,
    phase: Phase,
    fast: f64,
    slow: f64,
    threshold: f64,
    stall_us: u64,
    blocked_us: u64,
    /// The home point, once known.
    pub(crate) home: Option<f64>,
}

impl Sequence {
    /// Starts a sequence at mechanical position `m`; returns it with its first command.
    pub(crate) fn start(
        method: HomingMethod,
        env: &Environment,
        m: f64,
        fast: f64,
        slow: f64,
        threshold: f64,
        stall_us: u64,
    ) -> (Sequence, Cmd) {
        let mut seq = Sequence {
            kind: method.kind,
            phase: Phase::Done,
            fast,
            slow,
            threshold,
            stall_us,
            blocked_us: 0,
            home: None,
        };
        let cmd = match method.kind {
            HomingKind::CurrentPosition => seq.go_home(m, false),
            HomingKind::Index { dir } => match env.next_index(m, dir.sign()) {
                Some(home) => seq.go_home(home, false),
                None => Cmd::Fail(HomingError::NoIndexPulse),
            },
            HomingKind::EndStop { search, index } => {
                if index && env.index_period == 0 {
                    Cmd::Fail(HomingError::NoIndexPulse)
                } else {
                    seq.phase = Phase::Push { dir: search.sign(), stalled_us: 0 };
                    Cmd::Velocity(search.sign() * fast)
                }
            }
            HomingKind::Switch { signal, search, approach, edge, index, .. } => {
                if index && env.index_period == 0 {
                    Cmd::Fail(HomingError::NoIndexPulse)
                } else if env.active(signal.sensor(), m) {
                    seq.found_at_standstill(true, approach.sign(), edge, 0.0)
                } else {
                    seq.phase = Phase::Search { dir: search.sign(), reversed: false };
                    Cmd::Velocity(search.sign() * fast)
                }
            }
        };
        if matches!(cmd, Cmd::Fail(_)) {
            seq.phase = Phase::Done;
        }
        (seq, cmd)
    }

    fn go_home(&mut self, home: f64, resync: bool) -> Cmd {
        self.home = Some(home);
        self.phase = Phase::ToHome { home };
        Cmd::MoveTo { m: home, speed: self.slow, resync }
    }

    /// After the search (in direction `searched`, 0 at the start) stopped: continue from
    /// standstill.
    fn found_at_standstill(&mut self, active: bool, approach: f64, edge: Edge, searched: f64) -> Cmd {
        match edge {
            Edge::Falling => {
                self.phase = Phase::Approach { dir: approach, seen_active: active };
                Cmd::Velocity(approach * self.slow)
            }
            // Stopped beyond the whole switch, having crossed it against the approach
            // direction: already on the side the edge is approached from.
            Edge::Rising if !active && searched == -approach => {
                self.phase = Phase::Approach { dir: approach, seen_active: false };
                Cmd::Velocity(approach * self.slow)
            }
            Edge::Rising => {
                self.phase = Phase::Backoff { dir: -approach, seen_active: active };
                Cmd::Velocity(-approach * self.fast)
            }
        }
    }

    /// Limit switch in direction `dir` active at `m`.
    fn limit_ahead(env: &Environment, dir: f64, m: f64) -> bool {
        if dir > 0.0 { env.active(Sensor::PositiveLimit, m) } else { env.active(Sensor::NegativeLimit, m) }
    }

    /// Advances the sequence after a step.
    pub(crate) fn update(&mut self, obs: &Observation) -> Cmd {
        // Pressed against an end stop where the method should move: blocked.
        let pushing = matches!(self.phase, Phase::Push { .. });
        if obs.at_end_stop && !pushing && self.phase != Phase::Done {
            self.blocked_us += obs.dt_us;
            if self.blocked_us >= self.stall_us {
                self.phase = Phase::Done;
                return Cmd::Fail(HomingError::Blocked);
            }
        } else {
            self.blocked_us = 0;
        }
        match self.kind {
            HomingKind::Switch { signal, approach, edge, index, reverse_at_limit, overshoot_is_error, .. } => {
                self.update_switch(obs, signal, approach.sign(), edge, index, reverse_at_limit, overshoot_is_error)
            }
            HomingKind::EndStop { index, .. } => self.update_end_stop(obs, index),
            HomingKind::CurrentPosition | HomingKind::Index { .. } => self.update_common(obs),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn update_switch(
        &mut self,
        obs: &Observation,
        signal: HomingSignal,
        approach: f64,
        edge: Edge,
        index: bool,
        reverse_at_limit: bool,
        overshoot_is_error: bool,
    ) -> Cmd {
        let sensor = signal.sensor();
        let (edges, n) = obs.env.edges(sensor, obs.from, obs.to);
        let mut cmd = Cmd::None;
        for &(pos, now_active) in &edges[..n] {
            match self.phase {
                Phase::Search { dir, .. } if now_active => {
                    if edge == Edge::Falling && dir == approach {
                        // Inside the switch and already moving the right way: slow down, go on.
                        self.phase = Phase::Approach { dir: approach, seen_active: true };
                        cmd = Cmd::Velocity(approach * self.slow);
                    } else {
                        self.phase = Phase::Stop(After::Found { dir });
                        cmd = Cmd::Stop;
                    }
                }
                Phase::Backoff { dir, seen_active } => {
                    if now_active {
                        self.phase = Phase::Backoff { dir, seen_active: true };
                    } else if seen_active {
                        self.phase = Phase::Stop(After::BackedOff);
                        cmd = Cmd::Stop;
                    }
                }
                Phase::Approach { dir, seen_active } => {
                    let latch = match edge {
                        Edge::Rising => now_active,
                        Edge::Falling => !now_active && seen_active,
                    };
                    if latch {
                        let home = if index { obs.env.next_index(pos, dir) } else { Some(pos) };
                        return match home {
                            Some(home) => self.go_home(home, false),
                            None => {
                                self.phase = Phase::Done;
                                Cmd::Fail(HomingError::NoIndexPulse)
                            }
                        };
                    }
                    if now_active {
                        self.phase = Phase::Approach { dir, seen_active: true };
                    }
                }
                _ => {}
            }
        }
        if !matches!(cmd, Cmd::None) {
            return cmd;
        }
        match self.phase {
            Phase::Search { dir, reversed } => {
                if signal == HomingSignal::HomeSwitch && Self::limit_ahead(obs.env, dir, obs.to) {
                    if reverse_at_limit && !reversed {
                        self.phase = Phase::Stop(After::Search { dir: -dir, reversed: true });
                        return Cmd::Stop;
                    }
                    self.phase = Phase::Done;
                    return Cmd::Fail(HomingError::NotFound);
                }
                Cmd::None
            }
            Phase::Backoff { dir, .. } | Phase::Approach { dir, .. } => {
                if signal == HomingSignal::HomeSwitch && Self::limit_ahead(obs.env, dir, obs.to) {
                    self.phase = Phase::Done;
                    return Cmd::Fail(HomingError::NotFound);
                }
                Cmd::None
            }
            Phase::Stop(after) if obs.stopped => match after {
                After::Found { dir } => {
                    let active = obs.env.active(sensor, obs.to);
                    if !active && edge == Edge::Falling && overshoot_is_error {
                        self.phase = Phase::Done;
                        return Cmd::Fail(HomingError::SwitchOvershoot);
                    }
                    self.found_at_standstill(active, approach, edge, dir)
                }
                After::Search { dir, reversed } => {
                    self.phase = Phase::Search { dir, reversed };
                    Cmd::Velocity(dir * self.fast)
                }
                After::BackedOff => {
                    self.phase = Phase::Approach { dir: approach, seen_active: false };
                    Cmd::Velocity(approach * self.slow)
                }
            },
            _ => self.update_common(obs),
        }
    }

    fn update_end_stop(&mut self, obs: &Observation, index: bool) -> Cmd {
        if let Phase::Push { dir, stalled_us } = self.phase {
            let standing = obs.v.abs() <= (self.fast * 1e-3).max(1e-9);
            let pressing = obs.torque * dir >= self.threshold;
            if standing && pressing {
                let stalled_us = stalled_us + obs.dt_us;
                self.phase = Phase::Push { dir, stalled_us };
                if stalled_us >= self.stall_us {
                    let home = if index { obs.env.next_index(obs.to, -dir) } else { Some(obs.to) };
                    return match home {
                        Some(home) => self.go_home(home, true),
                        None => {
                            self.phase = Phase::Done;
                            Cmd::Fail(HomingError::NoIndexPulse)
                        }
                    };
                }
            } else {
                self.phase = Phase::Push { dir, stalled_us: 0 };
            }
            return Cmd::None;
        }
        self.update_common(obs)
    }

    /// The phases every method ends with.
    fn update_common(&mut self, obs: &Observation) -> Cmd {
        match self.phase {
            Phase::ToHome { home } if obs.stopped => {
                self.phase = Phase::Offset { home };
                Cmd::OffsetMove
            }
            Phase::Offset { home } if obs.stopped => {
                self.phase = Phase::Done;
                Cmd::Complete { home, at: obs.to }
            }
            _ => Cmd::None,
        }
    }

    /// True once the home point is known.
    pub(crate) fn attained(&self) -> bool {
        matches!(self.phase, Phase::ToHome { .. } | Phase::Offset { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cia_table_shapes() {
        let m = HomingMethod::cia402(1).unwrap();
        assert!(matches!(
            m.kind,
            HomingKind::Switch {
                signal: HomingSignal::NegativeLimit,
                search: Direction::Negative,
                approach: Direction::Positive,
                edge: Edge::Falling,
                index: true,
                ..
            }
        ));
        let m = HomingMethod::cia402(24).unwrap();
        assert!(matches!(
            m.kind,
            HomingKind::Switch { signal: HomingSignal::HomeSwitch, search: Direction::Positive, index: false, .. }
        ));
        assert!(HomingMethod::cia402(15).is_none());
        assert!(HomingMethod::cia402(36).is_none());
        assert!(HomingMethod::cia402(-1).is_none());
        assert_eq!(HomingMethod::cia402(35).unwrap().kind, HomingKind::CurrentPosition);
    }

    #[test]
    fn camozzi_table_shapes() {
        for code in [1, 2, 17, 18, 37, -1, -2, -3, -4] {
            assert!(HomingMethod::camozzi(code).is_some(), "{code}");
        }
        assert!(HomingMethod::camozzi(35).is_none());
        assert_eq!(
            HomingMethod::camozzi(-2).unwrap().kind,
            HomingKind::EndStop { search: Direction::Positive, index: true }
        );
    }

    #[test]
    fn statusword_bits_follow_cia402() {
        assert_eq!(HomingState::Completed.statusword_bits(true), (true, true, false));
        assert_eq!(HomingState::Attained.statusword_bits(false), (false, true, false));
        assert_eq!(HomingState::Error(HomingError::Timeout).statusword_bits(true), (true, false, true));
        assert_eq!(HomingState::Idle.statusword_bits(true), (true, false, false));
    }
}
