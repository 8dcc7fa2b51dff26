//! The device's LSS hooks (cargo feature `lss`): the [`LssSlave`] served from the device's
//! frames, its node-ID applied at resets, its configuration stored and loaded through the
//! device's [`Storage`].

use super::{Core, Device, Event, ResetKind, STORE, read_or};
use crate::App;
use crate::frame::{Frame, NodeId};
use crate::lss::{self, Identity, LssAction, LssConfig, LssSlave, UNCONFIGURED};
use crate::od::{AbortCode, ObjectDictionary};
use crate::storage::Storage;

impl<OD: ObjectDictionary, A: App<OD>, S: Storage, const P: usize, const M: usize> Core<OD, A, S, P, M> {
    /// At the first start: the stored node-ID and bit rate replace the ones the device was
    /// made with.
    pub(super) fn lss_start(&mut self) {
        let Some(slave) = self.lss.as_mut() else { return };
        if STORE && let Some(c) = self.storage.load_lss() {
            slave.set_node_id(c.node_id);
            slave.set_bit_rate(c.bit_rate);
        }
    }

    /// At every reset: the pending node-ID becomes the active one.
    pub(super) fn lss_reset(&mut self) {
        if let Some(slave) = self.lss.as_mut() {
            self.node = slave.activate_pending();
        }
    }

    /// Whether the device has no node-ID: it runs no NMT services and sends nothing but LSS.
    pub(super) fn lss_unconfigured(&self) -> bool {
        self.lss.is_some_and(|l| l.is_unconfigured())
    }

    /// Serves an LSS request; true when the frame is the LSS slave's (or the device, without a
    /// node-ID, takes no other).
    pub(super) fn lss_frame(&mut self, frame: &Frame) -> bool {
        let Some(mut slave) = self.lss else { return false };
        if frame.id() != lss::MASTER_COB || frame.is_rtr() {
            return slave.is_unconfigured();
        }
        let od = &self.od;
        let identity = Identity {
            vendor: read_or(od, 0x1018, 1, 0),
            product: read_or(od, 0x1018, 2, 0),
            revision: read_or(od, 0x1018, 3, 0),
            serial: read_or(od, 0x1018, 4, 0),
        };
        let action = slave.on_request(frame.data(), &identity);
        if let LssAction::Store { node_id, bit_rate } = action {
            let saved = if STORE {
                self.storage.save_lss(LssConfig { node_id, bit_rate })
            } else {
                Err(AbortCode::CANNOT_STORE)
            };
            slave.stored(match saved {
                Ok(()) => Ok(()),
                Err(AbortCode::CANNOT_STORE) => Err(lss::error::UNSUPPORTED),
                Err(_) => Err(lss::error::STORAGE),
            });
        }
        self.lss = Some(slave);
        match action {
            LssAction::ApplyNodeId(_) => self.reset(ResetKind::Communication),
            LssAction::ActivateBitTiming { index, delay_ms } => self.event(Event::LssBitTiming { index, delay_ms }),
            LssAction::None | LssAction::Store { .. } => {}
        }
        true
    }

    /// Sends the LSS answer due; true when the device has no node-ID (nothing else to send).
    pub(super) fn lss_poll(&mut self, emit: &mut impl FnMut(Frame)) -> bool {
        let Some(slave) = self.lss.as_mut() else { return false };
        if let Some(d) = slave.take_reply() {
            emit(Frame::full(lss::SLAVE_COB, d));
        }
        slave.is_unconfigured()
    }
}

impl<OD: ObjectDictionary, A: App<OD>, S: Storage, const BUF: usize, const PDOS: usize, const MAP: usize>
    Device<OD, A, S, BUF, PDOS, MAP>
{
    /// Makes the device answer LSS (CiA 305) whatever its dictionary says
    /// ([`ObjectDictionary::LSS`]), and with `node_id` `None` start without a node-ID: it then
    /// sends no boot-up and serves nothing but LSS until a master gives it one. Call it before
    /// the first [`Device::poll`] or [`Device::on_frame`]; a node-ID stored over LSS
    /// ([`Storage::load_lss`]) takes the place of `node_id` at that first start.
    pub fn enable_lss(&mut self, node_id: Option<NodeId>) {
        let id = node_id.map_or(UNCONFIGURED, NodeId::get);
        self.core.lss = Some(LssSlave::new(id));
        if !self.started {
            self.core.node = id;
        }
    }

    /// The LSS slave, when the device answers LSS.
    pub fn lss(&self) -> Option<&LssSlave> {
        self.core.lss.as_ref()
    }

    /// The node-ID in use: `None` for a device without one (LSS).
    pub fn active_node_id(&self) -> Option<NodeId> {
        NodeId::new(self.core.node)
    }

    /// Sets the bit timing table index the device runs at (reported by LSS store), e.g. the
    /// one its controller was started with.
    pub fn set_lss_bit_rate(&mut self, index: Option<u8>) {
        if let Some(l) = self.core.lss.as_mut() {
            l.set_bit_rate(index);
        }
    }
}
