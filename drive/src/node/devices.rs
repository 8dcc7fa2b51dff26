//! The project's devices, ready to run: [`DeviceKind`] picks the generated dictionary,
//! [`NodeConfig`] the node id, DCF and state directory, [`Apps`] the application.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;

use od_runtime::od::EntryInfo;
use od_runtime::{Micros, NodeId};

use super::{
    AnyNode, DcfError, DefaultApp, DriveApp, FileRetain, MemoryRetain, Node, NodeStorage, ParameterSet, Retain,
};
use crate::storage::{FileStorage, MemoryStorage};

pub use super::kind::DeviceKind;

impl DeviceKind {
    /// Every device, in command-line order.
    pub const ALL: [DeviceKind; 3] = [DeviceKind::Drvi, DeviceKind::Drcs, DeviceKind::Akd];

    /// The command-line name: `drvi`, `drcs`, `akd`.
    pub const fn name(self) -> &'static str {
        match self {
            DeviceKind::Drvi => "drvi",
            DeviceKind::Drcs => "drcs",
            DeviceKind::Akd => "akd",
        }
    }

    /// The dictionary's entry table.
    pub fn entries(self) -> &'static [EntryInfo] {
        match self {
            DeviceKind::Drvi => &generated::drvi::ENTRIES,
            DeviceKind::Drcs => &generated::drcs::ENTRIES,
            DeviceKind::Akd => &generated::akd::ENTRIES,
        }
    }

    /// The EDS the dictionary was generated from (its text).
    pub fn eds(self) -> &'static str {
        match self {
            DeviceKind::Drvi => generated::drvi::EDS,
            DeviceKind::Drcs => generated::drcs::EDS,
            DeviceKind::Akd => generated::akd::EDS,
        }
    }

    /// Builds a node of this kind: the generated dictionary with `$NODEID` resolved, the
    /// application `apps` gives for the kind, and a [`NodeStorage`] with the DCF's values over
    /// a [`FileStorage`] in the state directory (files named `<kind>-node<id>.*.params`) or,
    /// without one, a [`MemoryStorage`], saving the device's store list only; the
    /// application's retained data ([`Retain`]) in `<kind>-node<id>.retained` there, or in
    /// memory.
    pub fn build(self, config: &NodeConfig, apps: &dyn Apps) -> Result<Box<dyn AnyNode>, NodeSetupError> {
        let params = match &config.dcf {
            Some(path) => ParameterSet::from_dcf(path, self.entries(), config.node_id)
                .map_err(|error| NodeSetupError::Dcf { path: path.clone(), error })?,
            None => ParameterSet::new(),
        };
        let mut params = params;
        if let Some(serial) = config.serial {
            params.set(0x1018, 4, serial.to_le_bytes().to_vec());
        }
        let raw = config.node_id.or(params.node_id()).ok_or(NodeSetupError::NoNodeId)?;
        // 255: no node-ID (LSS); the dictionary's $NODEID values wait for the one LSS gives.
        let unconfigured = raw == od_runtime::lss::UNCONFIGURED;
        let id =
            if unconfigured { NodeId::new(127) } else { NodeId::new(raw) }.ok_or(NodeSetupError::BadNodeId(raw))?;
        // A device known by its serial number keeps its files under it: its node-ID may change.
        let tag = match config.serial {
            Some(serial) => format!("{}-sn{serial}", self.name()),
            None => format!("{}-node{raw}", self.name()),
        };
        let (backend, retain): (Box<dyn od_runtime::Storage + Send>, Box<dyn Retain>) = match &config.state_dir {
            Some(dir) => {
                let error = |error| NodeSetupError::Storage { dir: dir.clone(), error };
                (
                    Box::new(FileStorage::open(dir, &tag).map_err(error)?),
                    Box::new(FileRetain::open(dir, &tag).map_err(error)?),
                )
            }
            None => (Box::new(MemoryStorage::new()), Box::new(MemoryRetain::new())),
        };
        // 1010h saves what the device's manual lists (the sidecar's [store]), not every
        // writable entry: DRVI 6.3.2.13, DRCS 3.2.13, AKD 6.2.1.12.
        let storage = crate::drives::store::stored_objects_only(self, NodeStorage::new(Arc::new(params), backend));
        let timeout = config.sdo_timeout;
        let lss = (!unconfigured).then_some(id);
        let config = (timeout, retain, lss);
        Ok(match self {
            DeviceKind::Drvi => {
                boxed(Node::new(generated::drvi::Dictionary::new(raw), apps.drvi(), storage, id), config)
            }
            DeviceKind::Drcs => {
                boxed(Node::new(generated::drcs::Dictionary::new(raw), apps.drcs(), storage, id), config)
            }
            DeviceKind::Akd => boxed(Node::new(generated::akd::Dictionary::new(raw), apps.akd(), storage, id), config),
        })
    }
}

type Setup = (Option<Micros>, Box<dyn Retain>, Option<NodeId>);

fn boxed<OD, A>(node: Node<OD, A>, (sdo_timeout, retain, lss): Setup) -> Box<dyn AnyNode>
where
    OD: od_runtime::od::ObjectDictionary + Send + 'static,
    A: DriveApp<OD> + Send + 'static,
{
    let mut node = node.with_retain(retain);
    // Every simulated drive answers LSS (CiA 305).
    node.enable_lss(lss);
    if let Some(t) = sdo_timeout {
        node.set_sdo_timeout(t);
    }
    Box::new(node)
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DeviceKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| format!("unknown device '{s}' (expected one of: drvi, drcs, akd)"))
    }
}

/// How to set up one node.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NodeConfig {
    /// The node id (1..=127, or 255: none, the device waits for LSS); `None` takes the DCF's
    /// `NodeID`.
    pub node_id: Option<u8>,
    /// A DCF whose `ParameterValue`s are applied at start and at every reset.
    pub dcf: Option<PathBuf>,
    /// Where 1010h saves parameters; `None` keeps them in memory for the life of the process.
    pub state_dir: Option<PathBuf>,
    /// SDO server timeout; `None` keeps od-runtime's default (1 s).
    pub sdo_timeout: Option<Micros>,
    /// The serial number (1018h sub 4) instead of the EDS's, so that identical devices can be
    /// told apart over LSS; the device's files in the state directory are then named by it.
    pub serial: Option<u32>,
}

/// Why a node could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum NodeSetupError {
    /// Neither the configuration nor the DCF gives a node id.
    #[error("no node id: give --node-id (or a DCF with [DeviceComissioning] NodeID)")]
    NoNodeId,
    /// A node id outside 1..=127 (and not 255, none).
    #[error("node id {0} is outside 1..=127 (255 or 'none': no node-ID, set over LSS)")]
    BadNodeId(u8),
    /// The DCF cannot be applied.
    #[error("DCF {}:\n{error}", path.display())]
    Dcf {
        /// The file.
        path: PathBuf,
        /// Every problem.
        error: DcfError,
    },
    /// The state directory cannot be used.
    #[error("state directory {}: {error}", dir.display())]
    Storage {
        /// The directory.
        dir: PathBuf,
        /// The OS error.
        error: std::io::Error,
    },
}

/// Chooses the application each kind of device runs: the plug-in point for device behaviours.
///
/// Every method defaults to [`DefaultApp`]. A crate with vendor behaviour implements the
/// methods of the devices it simulates and hands its `Apps` to [`DeviceKind::build`]; nothing
/// else changes:
///
/// ```
/// use drive::node::{Apps, DefaultApp, DeviceKind, DriveApp, NodeConfig};
/// use generated::drvi;
///
/// struct MyApps;
/// impl Apps for MyApps {
///     fn drvi(&self) -> Box<dyn DriveApp<drvi::Dictionary> + Send> {
///         Box::new(DefaultApp::new()) // a DRVI behaviour here
///     }
/// }
/// let node = DeviceKind::Drvi.build(&NodeConfig { node_id: Some(4), ..Default::default() }, &MyApps).unwrap();
/// assert_eq!(node.node_id().get(), 4);
/// ```
pub trait Apps {
    /// The application of a DRVI.
    fn drvi(&self) -> Box<dyn DriveApp<generated::drvi::Dictionary> + Send> {
        Box::new(DefaultApp::new())
    }

    /// The application of a DRCS.
    fn drcs(&self) -> Box<dyn DriveApp<generated::drcs::Dictionary> + Send> {
        Box::new(DefaultApp::new())
    }

    /// The application of an AKD.
    fn akd(&self) -> Box<dyn DriveApp<generated::akd::Dictionary> + Send> {
        Box::new(DefaultApp::new())
    }
}

/// [`DefaultApp`] for every device.
#[derive(Clone, Copy, Debug, Default)]
pub struct DefaultApps;

impl Apps for DefaultApps {}
