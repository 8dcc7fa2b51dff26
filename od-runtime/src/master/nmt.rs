//! NMT master commands (CiA 301 §7.2.8.3.1): one frame on COB-ID 000h, command specifier and
//! node id (0 for every node).

use crate::frame::{Frame, NodeId};
use crate::nmt::{NmtCommand, NmtState};

/// The nodes an NMT command is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// Every node on the bus (node id 0 in the frame).
    All,
    /// One node.
    Node(NodeId),
}

impl Target {
    /// The node id byte of the frame.
    pub const fn byte(self) -> u8 {
        match self {
            Target::All => 0,
            Target::Node(n) => n.get(),
        }
    }

    /// Whether the command reaches `node`.
    pub const fn includes(self, node: NodeId) -> bool {
        match self {
            Target::All => true,
            Target::Node(n) => n.get() == node.get(),
        }
    }
}

/// The frame of an NMT command: `000 01 05` starts node 5, `000 81 00` resets every node.
pub fn command(cmd: NmtCommand, target: Target) -> Frame {
    Frame::short(0x000, [cmd.code(), target.byte(), 0, 0, 0, 0, 0, 0], 2)
}

/// The NMT state a node reports once it has carried out `cmd`: the resets end in
/// pre-operational, after a boot-up message.
pub const fn state_after(cmd: NmtCommand) -> NmtState {
    match cmd {
        NmtCommand::Start => NmtState::Operational,
        NmtCommand::Stop => NmtState::Stopped,
        NmtCommand::EnterPreOperational | NmtCommand::ResetNode | NmtCommand::ResetCommunication => {
            NmtState::PreOperational
        }
    }
}

/// Decodes an NMT command frame (another master's, or the one this master sent): the command
/// and its target. `None` for a frame that is not a valid NMT command.
pub fn decode(frame: &Frame) -> Option<(NmtCommand, Target)> {
    if frame.id() != 0 || frame.is_rtr() || frame.len() != 2 {
        return None;
    }
    let d = frame.data();
    let cmd = NmtCommand::from_byte(d[0])?;
    let target = if d[1] == 0 { Target::All } else { Target::Node(NodeId::new(d[1])?) };
    Some((cmd, target))
}
