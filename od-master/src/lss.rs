//! Commissioning with LSS (CiA 305): give devices their node-ID and bit rate over the bus,
//! find the ones without a node-ID by fastscan.
//!
//! LSS is one conversation for the whole bus (every device listens to 7E5h), so it is a
//! session: [`Lss::new`] on a [`Bus`], whose methods take `&mut self`, one request at a time.
//! The protocol is [`od_runtime::master::lss::LssMaster`]; this is its shell on tokio's
//! clock (the paused clock in tests too).
//!
//! ```no_run
//! # async fn f(bus: od_master::Bus) -> Result<(), od_master::Error> {
//! use od_master::lss::Lss;
//! let mut lss = Lss::new(&bus);
//! for id in lss.scan([None; 4]).await? {
//!     println!("{id}");
//! }
//! # Ok(()) }
//! ```

use std::time::Duration;

use od_bus::CanFrame;
use od_runtime::master::lss::{Answer, LssMaster, Request};
use tokio::sync::broadcast;
use tokio::time::Instant;

use crate::{Bus, Error, NmtCommand, Target};

pub use od_runtime::lss::{BIT_RATES, Identity, Mode, UNCONFIGURED, bit_rate_index, bit_rate_kbit};
pub use od_runtime::master::lss::{DEFAULT_TIMEOUT, ErrorKind, LssError, Step};

/// An LSS session on a bus (see the [module](self)).
#[derive(Debug)]
pub struct Lss {
    bus: Bus,
    frames: broadcast::Receiver<CanFrame>,
    core: LssMaster,
    origin: Instant,
    device: Option<Identity>,
    /// Whether an answer came yet in this session (see [`FIRST_ANSWER`]).
    answered: bool,
    retries: u32,
}

/// How many times [`Lss::fastscan`] runs a scan whose confirmation got no answer.
pub const FASTSCAN_ATTEMPTS: u32 = 3;

/// How long the steps of a session wait at least until its first answer: a bus just opened
/// over `drive-sim hub` delivers its first frames up to 50 ms late (the hub's pause after its
/// reply to `< rawmode >`, which python-can needs to read that reply alone; measured: the
/// first answer 50 ms after the handshake, the next ones in under 1 ms).
pub const FIRST_ANSWER: Duration = Duration::from_millis(100);

/// What [`Lss::assign`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Assignment {
    /// Devices given a node-ID: identity and node-ID.
    pub assigned: Vec<(Identity, u8)>,
    /// Devices found without a node-ID that the plan does not name (left as they were).
    pub unknown: Vec<Identity>,
    /// Devices of the plan that did not answer (identity and node-ID).
    pub missing: Vec<(Identity, u8)>,
}

impl Lss {
    /// A session on `bus`, with the default step timeout ([`DEFAULT_TIMEOUT`]).
    pub fn new(bus: &Bus) -> Self {
        Self {
            bus: bus.clone(),
            frames: bus.frames(),
            core: LssMaster::new(),
            origin: Instant::now(),
            device: None,
            answered: false,
            retries: 0,
        }
    }

    /// Sets the step timeout: how long each step waits for its answer (and the steps that
    /// count answers, for them). At least 1 ms.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.core.set_timeout(timeout.as_micros().min(u128::from(u32::MAX)) as u64);
    }

    /// The step timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_micros(self.core.timeout())
    }

    /// Frames this session has sent.
    pub fn frames_sent(&self) -> u32 {
        self.core.frames_sent()
    }

    fn now(&self) -> u64 {
        Instant::now().saturating_duration_since(self.origin).as_micros() as u64
    }

    /// Runs one request to its end.
    async fn request(&mut self, request: Request) -> Result<Answer, Error> {
        // Frames from before the request are not its answers.
        while let Ok(_) | Err(broadcast::error::TryRecvError::Lagged(_)) = self.frames.try_recv() {}
        let step = self.core.timeout();
        if !self.answered {
            self.core.set_timeout(step.max(FIRST_ANSWER.as_micros() as u64));
        }
        let r = self.run_request(request, step).await;
        self.core.set_timeout(step);
        r
    }

    /// Runs `request`; `step` is the step timeout once an answer came.
    async fn run_request(&mut self, request: Request, step: u64) -> Result<Answer, Error> {
        let now = self.now();
        self.core.start(request, now).map_err(|_| Error::Closed)?;
        loop {
            let now = self.now();
            let mut out = Vec::new();
            let done = self.core.poll(now, &mut |f| out.push(f));
            for f in out {
                self.bus.send(CanFrame::from(f)).await?;
            }
            if let Some(d) = done {
                return self.finish(d);
            }
            let wake = self.core.deadline().map(|d| self.origin + Duration::from_micros(d));
            let frame = match wake {
                Some(at) if at <= Instant::now() => continue,
                Some(at) => tokio::select! {
                    f = self.frames.recv() => Some(f),
                    () = tokio::time::sleep_until(at) => None,
                },
                None => Some(self.frames.recv().await),
            };
            match frame {
                Some(Ok(f)) => {
                    if !self.answered && f.id() == u32::from(od_runtime::lss::SLAVE_COB) {
                        // The link delivers: the next steps wait the step timeout.
                        self.answered = true;
                        self.core.set_timeout(step);
                    }
                    if let Ok(f) = od_runtime::Frame::try_from(f)
                        && let Some(d) = self.core.on_frame(&f, self.now())
                    {
                        return self.finish(d);
                    }
                }
                Some(Err(broadcast::error::RecvError::Lagged(_))) => {}
                Some(Err(broadcast::error::RecvError::Closed)) => return Err(Error::Closed),
                None => {}
            }
        }
    }

    fn finish(&mut self, d: od_runtime::master::lss::Done) -> Result<Answer, Error> {
        // Those two steps name the identity themselves.
        let named = |e: &LssError| matches!(e.step, Step::SwitchSelective(_) | Step::FastscanConfirm { .. });
        d.result.map_err(|error| Error::Lss { device: if named(&error) { None } else { self.device }, error })
    }

    /// Switch state global: every device to `mode`. Back to waiting, a device that had no
    /// node-ID and was given one starts with it.
    pub async fn switch_global(&mut self, mode: Mode) -> Result<(), Error> {
        self.request(Request::SwitchGlobal(mode)).await?;
        if mode == Mode::Waiting {
            self.device = None;
        }
        Ok(())
    }

    /// Switch state selective: the device of `identity` to configuration. Two devices
    /// answering is [`ErrorKind::Duplicate`].
    pub async fn switch_selective(&mut self, identity: Identity) -> Result<(), Error> {
        self.device = Some(identity);
        let r = self.request(Request::SwitchSelective(identity)).await.map(drop);
        if r.is_err() {
            self.device = None;
        }
        r
    }

    /// Configure node-ID (1..=127, or [`UNCONFIGURED`]) of the device(s) in configuration.
    pub async fn configure_node_id(&mut self, node_id: u8) -> Result<(), Error> {
        self.request(Request::ConfigureNodeId(node_id)).await.map(drop)
    }

    /// Configure bit timing: a bit rate of the CiA 305 table, in kbit/s.
    pub async fn configure_bit_rate(&mut self, kbit: u32) -> Result<(), Error> {
        let Some(index) = bit_rate_index(kbit) else {
            // Refused without sending.
            return Err(Error::Lss {
                error: LssError { step: Step::BitRate(kbit), kind: ErrorKind::Invalid },
                device: None,
            });
        };
        self.request(Request::ConfigureBitTiming(index)).await.map(drop)
    }

    /// Activate bit timing: every device switches after `delay` (rounded to ms) and sends
    /// nothing for as long again.
    pub async fn activate_bit_timing(&mut self, delay: Duration) -> Result<(), Error> {
        let ms = delay.as_millis().min(u128::from(u16::MAX)) as u16;
        self.request(Request::ActivateBitTiming(ms)).await.map(drop)
    }

    /// Store configuration (node-ID and bit rate) of the device in configuration.
    pub async fn store(&mut self) -> Result<(), Error> {
        self.request(Request::Store).await.map(drop)
    }

    /// Inquire identity: the four parts of the device in configuration.
    pub async fn inquire_identity(&mut self) -> Result<Identity, Error> {
        let mut v = [0u32; 4];
        for (p, slot) in v.iter_mut().enumerate() {
            if let Answer::Value(x) = self.request(Request::InquireIdentity(p as u8)).await? {
                *slot = x;
            }
        }
        Ok(Identity { vendor: v[0], product: v[1], revision: v[2], serial: v[3] })
    }

    /// Inquire node-ID of the device in configuration: `None` when it has none.
    pub async fn inquire_node_id(&mut self) -> Result<Option<u8>, Error> {
        match self.request(Request::InquireNodeId).await? {
            Answer::NodeId(n) if n != UNCONFIGURED => Ok(Some(n)),
            _ => Ok(None),
        }
    }

    /// Identify non-configured remote slave: how many devices without a node-ID answered.
    pub async fn identify_non_configured(&mut self) -> Result<u8, Error> {
        match self.request(Request::IdentifyNonConfigured).await? {
            Answer::Answers(n) => Ok(n),
            _ => Ok(0),
        }
    }

    /// Identify remote slave: how many devices of `vendor` and `product` with a revision and
    /// serial number in the ranges answered.
    pub async fn identify_remote(
        &mut self,
        vendor: u32,
        product: u32,
        revision: std::ops::RangeInclusive<u32>,
        serial: std::ops::RangeInclusive<u32>,
    ) -> Result<u8, Error> {
        let req = Request::IdentifyRemote {
            vendor,
            product,
            revision: (*revision.start(), *revision.end()),
            serial: (*serial.start(), *serial.end()),
        };
        match self.request(req).await? {
            Answer::Answers(n) => Ok(n),
            _ => Ok(0),
        }
    }

    /// Fastscan: one device without a node-ID, left in configuration (`None`: there is
    /// none). The parts given in `known` (vendor, product, revision, serial) are confirmed,
    /// not scanned.
    ///
    /// A confirmation that gets no answer starts the scan again, up to [`FASTSCAN_ATTEMPTS`]
    /// times in all: an answer later than the step timeout (a loaded host, a busy bridge) is
    /// taken for the next step's and makes a wrong bit, which the confirmation finds. A
    /// device that is gone fails every attempt, and the error names the step.
    pub async fn fastscan(&mut self, known: [Option<u32>; 4]) -> Result<Option<Identity>, Error> {
        let mut attempt = 1;
        loop {
            match self.request(Request::Fastscan(known)).await {
                Ok(Answer::Found(found)) => {
                    self.device = found;
                    return Ok(found);
                }
                Ok(_) => return Ok(None),
                Err(Error::Lss { error, .. })
                    if attempt < FASTSCAN_ATTEMPTS
                        && matches!(error.step, Step::FastscanConfirm { .. })
                        && matches!(error.kind, ErrorKind::Timeout(_)) =>
                {
                    attempt += 1;
                    self.retries += 1;
                    // Late answers of the failed scan go by before the next one starts.
                    tokio::time::sleep(self.timeout()).await;
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// Fastscans started again after a confirmation got no answer (see [`Lss::fastscan`]).
    pub fn retries(&self) -> u32 {
        self.retries
    }

    /// Every device without a node-ID, by fastscan after fastscan (each found one waits in
    /// configuration until the next scan finds no more), then all back to waiting. At most
    /// 127 devices.
    pub async fn scan(&mut self, known: [Option<u32>; 4]) -> Result<Vec<Identity>, Error> {
        let mut found = Vec::new();
        let result = async {
            while found.len() < 127 {
                match self.fastscan(known).await? {
                    Some(id) => found.push(id),
                    None => break,
                }
            }
            Ok::<_, Error>(())
        }
        .await;
        // Found devices back to waiting, whatever happened.
        let back = self.switch_global(Mode::Waiting).await;
        result?;
        back?;
        Ok(found)
    }

    /// Gives the device of `identity` the node-ID `node_id` (switch selective, configure,
    /// store when `store`, back to waiting). A device without a node-ID starts with it at
    /// once; one with a node-ID at its next reset.
    /// Whatever fails, every device is back in waiting at the end (two devices of one
    /// identity are both in configuration after the switch).
    pub async fn set_node_id(&mut self, identity: Identity, node_id: u8, store: bool) -> Result<(), Error> {
        let r = async {
            self.switch_selective(identity).await?;
            self.configure_node_id(node_id).await?;
            if store {
                self.store().await?;
            }
            Ok::<_, Error>(())
        }
        .await;
        let back = self.switch_global(Mode::Waiting).await;
        r?;
        back
    }

    /// Every device on the bus without a node-ID, stored (the way out for devices that all
    /// ship with one node-ID): configure FFh and store in all at once, then NMT reset
    /// communication to all. A device that cannot store keeps FFh until its power is cycled.
    pub async fn unconfigure_all(&mut self) -> Result<(), Error> {
        self.switch_global(Mode::Configuration).await?;
        let r = async {
            // Several devices answer: each answer ends the step; the first one is enough.
            self.configure_node_id(UNCONFIGURED).await?;
            self.store().await
        }
        .await;
        self.switch_global(Mode::Waiting).await?;
        r?;
        self.bus.nmt(NmtCommand::ResetCommunication, Target::All).await
    }

    /// Gives each device of `plan` (its identity: the EDS's vendor, product and revision
    /// and the description's serial number) its node-ID, stored, as
    /// [`commission`](Self::commission) does (each addressed by its identity), except that a
    /// device already at its node-ID is configured and stored again too. A device of the plan
    /// that does not answer is listed in [`Assignment::missing`]; devices without a node-ID
    /// the plan does not name are found by fastscan afterwards and listed in
    /// [`Assignment::unknown`], not touched. Another failure (two devices of one identity, a
    /// refused store) ends it with that error.
    pub async fn assign(&mut self, plan: &[(Identity, u8)]) -> Result<Assignment, Error> {
        let nodes: Vec<LssNode> =
            plan.iter().map(|&(identity, node_id)| LssNode { identity, node_id, store: true }).collect();
        let mut c = self.commission_with(&nodes, true).await?;
        if let Some(e) = c.scan_error.take() {
            return Err(e);
        }
        let mut report = Assignment { unknown: c.unknown, ..Assignment::default() };
        report.assigned = c.assigned.iter().map(|a| (a.0, a.1)).chain(c.in_place).collect();
        for (p, e) in c.failed {
            if no_such_device(&e) {
                report.missing.push((p.identity, p.node_id));
            } else {
                return Err(e);
            }
        }
        // In the order of the plan.
        report.assigned.sort_by_key(|a| plan.iter().position(|p| p.0 == a.0));
        Ok(report)
    }

    /// What a network's boot runs first ([`crate::boot`], for the nodes its description marks
    /// `lss = true`): each device of `plan` gets its node-ID, where it needs one.
    ///
    /// Each device is addressed by its whole identity (switch state selective: one step, any
    /// device in waiting answers, with or without a node-ID; no fastscan is needed for a device
    /// whose serial number is known) and asked for its node-ID. At its node-ID already, nothing
    /// more is sent. Otherwise it is given its own (stored when its entry says): a device that
    /// had none starts with it as soon as it is back in waiting; one that had another one is
    /// reset (NMT reset communication to that node-ID), so that it starts with it now. Either
    /// sends its boot-up next; waiting for it is the caller's. A device that does not answer,
    /// or whose configuration fails, is in [`Commissioning::failed`] with the error naming the
    /// step and the identity; the others go on.
    ///
    /// Then a fastscan (full: they can be any device) lists the devices still without a
    /// node-ID in [`Commissioning::unknown`], not touched (back in waiting at the end). With
    /// none there, that is one step that nobody answers.
    pub async fn commission(&mut self, plan: &[LssNode]) -> Result<Commissioning, Error> {
        self.commission_with(plan, false).await
    }

    /// [`commission`](Self::commission); with `again`, a device at its node-ID already is
    /// configured (and stored, as its entry says) again.
    async fn commission_with(&mut self, plan: &[LssNode], again: bool) -> Result<Commissioning, Error> {
        let mut report = Commissioning::default();
        for p in plan {
            match self.switch_selective(p.identity).await {
                Ok(()) => {}
                Err(e @ Error::Lss { .. }) => {
                    // Two devices of one identity are both in configuration now.
                    self.switch_global(Mode::Waiting).await?;
                    report.failed.push((*p, e));
                    continue;
                }
                Err(e) => return Err(e),
            }
            let r = async {
                let had = self.inquire_node_id().await?;
                if again || had != Some(p.node_id) {
                    self.configure_node_id(p.node_id).await?;
                    if p.store {
                        self.store().await?;
                    }
                }
                Ok::<_, Error>(had)
            }
            .await;
            self.switch_global(Mode::Waiting).await?;
            match r {
                Ok(Some(had)) if had == p.node_id => report.in_place.push((p.identity, p.node_id)),
                Ok(had) => {
                    if let Some(old) = had.and_then(od_runtime::NodeId::new) {
                        // A new node-ID takes effect at the device's next reset.
                        self.bus.nmt(NmtCommand::ResetCommunication, Target::Node(old)).await?;
                    }
                    report.assigned.push((p.identity, p.node_id, had));
                }
                Err(e @ Error::Lss { .. }) => report.failed.push((*p, e)),
                Err(e) => return Err(e),
            }
        }
        // The assignments stand whatever this scan meets (a late answer on a loaded host).
        match self.scan([None; 4]).await {
            Ok(found) => report.unknown = found,
            Err(e @ Error::Lss { .. }) => report.scan_error = Some(e),
            Err(e) => return Err(e),
        }
        Ok(report)
    }
}

/// Whether `e` says that no device answered a switch state selective.
fn no_such_device(e: &Error) -> bool {
    matches!(e, Error::Lss { error, .. }
        if matches!(error.step, Step::SwitchSelective(_)) && matches!(error.kind, ErrorKind::Timeout(_)))
}

/// A device [`Lss::commission`] gives a node-ID to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LssNode {
    /// Its identity: the device description's vendor-ID, product code and revision number, and
    /// its serial number.
    pub identity: Identity,
    /// The node-ID it is to have.
    pub node_id: u8,
    /// Whether the node-ID is stored in the device (store configuration).
    pub store: bool,
}

/// What [`Lss::commission`] did.
#[derive(Debug, Default)]
pub struct Commissioning {
    /// Devices given their node-ID: identity, node-ID, and the node-ID they had (`None`:
    /// none). Each of them sends a boot-up with its new node-ID.
    pub assigned: Vec<(Identity, u8, Option<u8>)>,
    /// Devices of the plan already at their node-ID (nothing configured).
    pub in_place: Vec<(Identity, u8)>,
    /// Devices without a node-ID that the plan does not name (left as they were).
    pub unknown: Vec<Identity>,
    /// Devices of the plan that could not be given their node-ID, with the error (a timeout of
    /// the switch state selective: no device has that identity on the bus).
    pub failed: Vec<(LssNode, Error)>,
    /// The fastscan for the devices the plan does not name failed (devices without a node-ID
    /// may be missing from `unknown`); the assignments above stand.
    pub scan_error: Option<Error>,
}
