//! `od-master lss`: commissioning with LSS (CiA 305, `od_master::lss`): find the devices
//! without a node-ID, give a device its node-ID or bit rate, store, inquire, unconfigure all,
//! assign a network description's node-IDs by serial number.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand};
use od_master::Bus;
use od_master::boot::Network;
use od_master::lss::{self, Identity, Lss, Mode};
use serde_json::json;

/// `lss` and its options.
#[derive(Args, Debug)]
pub struct LssArgs {
    /// How long each LSS step waits for its answer, in milliseconds (a fastscan step that
    /// nobody answers costs this).
    #[arg(long, default_value_t = lss::DEFAULT_TIMEOUT / 1000, value_name = "MS")]
    step_timeout: u64,
    #[command(subcommand)]
    action: LssCmd,
}

/// The identity of one device: its serial number, and vendor, product and revision from
/// --eds or given.
#[derive(Args, Debug, Clone, Copy)]
pub struct IdArgs {
    /// Serial number (1018h sub 4; decimal or 0x hex).
    #[arg(long, value_parser = number)]
    serial: Option<u32>,
    /// Vendor-ID (1018h sub 1), instead of the --eds file's.
    #[arg(long, value_parser = number)]
    vendor: Option<u32>,
    /// Product code (1018h sub 2), instead of the --eds file's.
    #[arg(long, value_parser = number)]
    product: Option<u32>,
    /// Revision number (1018h sub 3), instead of the --eds file's.
    #[arg(long, value_parser = number)]
    revision: Option<u32>,
}

#[derive(Subcommand, Debug)]
enum LssCmd {
    /// Finds every device without a node-ID (fastscan); with --eds, its vendor, product (and
    /// revision, when the file has one) are matched instead of scanned.
    Scan,
    /// Gives the device of an identity (--serial, and --eds or --vendor/--product/--revision)
    /// a node-ID (1..=127, or `none`), stored.
    SetId {
        #[command(flatten)]
        id: IdArgs,
        /// The new node-ID, or `none` (255).
        new: String,
        /// Do not store it (a device without a node-ID takes it at once anyway).
        #[arg(long)]
        no_store: bool,
    },
    /// Configures a bit rate (kbit/s, of the CiA 305 table) and stores it: in the device of an
    /// identity, or with no --serial in every device; --activate switches to it.
    SetBitrate {
        #[command(flatten)]
        id: IdArgs,
        /// kbit/s: 1000, 800, 500, 250, 125, 50, 20 or 10.
        kbit: u32,
        /// Then activate bit timing for every device, with this switch delay (ms).
        #[arg(long, value_name = "DELAY_MS")]
        activate: Option<u16>,
    },
    /// Stores the configuration of the device of an identity (or with no --serial of every
    /// device).
    Store {
        #[command(flatten)]
        id: IdArgs,
    },
    /// The identity and node-ID of the device of an identity, or with no --serial of the one
    /// device on the bus.
    Inquire {
        #[command(flatten)]
        id: IdArgs,
    },
    /// Every device to no node-ID (FFh), stored, then NMT reset communication: the way out
    /// for devices that all ship with one node-ID.
    UnconfigureAll,
    /// Gives each node of a network description that has a `serial` its node-ID, by that
    /// identity; lists the devices without a node-ID the description does not know.
    Assign {
        /// The network description (networks/*.toml).
        network: PathBuf,
    },
}

fn number(text: &str) -> Result<u32, String> {
    let t = text.trim();
    let parsed = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(hex) => u32::from_str_radix(hex, 16),
        None => t.parse(),
    };
    parsed.map_err(|_| format!("`{text}` is not a number of 32 bits (decimal or 0x hex)"))
}

fn show(id: &Identity) -> serde_json::Value {
    json!({ "vendor": id.vendor, "product": id.product, "revision": id.revision, "serial": id.serial })
}

/// A failure: exit code and message.
pub type Fail = (u8, String);

fn failed(e: od_master::Error) -> Fail {
    (1, e.to_string())
}

/// The identity `id` names, the EDS's numbers filling what is not given; `None` without
/// --serial.
fn identity(id: &IdArgs, eds: Option<&eds::Model>) -> Result<Option<Identity>, Fail> {
    let Some(serial) = id.serial else {
        if id.vendor.is_some() || id.product.is_some() || id.revision.is_some() {
            return Err((2, "--vendor, --product and --revision select a device with --serial".into()));
        }
        return Ok(None);
    };
    let info = eds.map(|m| &m.device_info);
    let part = |given: Option<u32>, from_eds: Option<u32>, what: &str| {
        given.or(from_eds).ok_or_else(|| {
            (2, format!("the {what} of the device with serial {serial} is not known: give --eds FILE or --{what}"))
        })
    };
    Ok(Some(Identity {
        vendor: part(id.vendor, info.and_then(|i| i.vendor_number), "vendor")?,
        product: part(id.product, info.and_then(|i| i.product_number), "product")?,
        revision: part(id.revision, info.and_then(|i| i.revision_number), "revision")?,
        serial,
    }))
}

/// Runs `od-master lss`.
pub async fn run(bus: &Bus, args: LssArgs, eds: Option<&eds::Model>, json: bool) -> Result<(), Fail> {
    let mut session = Lss::new(bus);
    session.set_timeout(Duration::from_millis(args.step_timeout.max(1)));
    match args.action {
        LssCmd::Scan => {
            let known = match eds {
                Some(m) => {
                    [m.device_info.vendor_number, m.device_info.product_number, m.device_info.revision_number, None]
                }
                None => [None; 4],
            };
            let found = session.scan(known).await.map_err(failed)?;
            for id in &found {
                if json {
                    println!("{}", show(id));
                } else {
                    println!("{id}");
                }
            }
            if !json {
                let (frames, retries) = (session.frames_sent(), session.retries());
                println!(
                    "{} device(s) without a node-ID ({frames} LSS frames sent, {retries} scans repeated)",
                    found.len()
                );
            }
        }
        LssCmd::SetId { id, new, no_store } => {
            let node = match new.as_str() {
                "none" => lss::UNCONFIGURED,
                n => match n.parse::<u8>() {
                    Ok(v @ (1..=127 | 255)) => v,
                    _ => return Err((2, format!("`{new}` is not a node-ID (1..=127, or `none`)"))),
                },
            };
            let Some(ident) = identity(&id, eds)? else {
                return Err((2, "set-id needs the device's --serial".into()));
            };
            session.set_node_id(ident, node, !no_store).await.map_err(failed)?;
            if json {
                println!("{}", json!({ "identity": show(&ident), "node": node, "stored": !no_store }));
            } else {
                println!("node-ID {node} given to the device ({ident}){}", if no_store { "" } else { ", stored" });
            }
        }
        LssCmd::SetBitrate { id, kbit, activate } => {
            let ident = identity(&id, eds)?;
            in_configuration(&mut session, ident, async |s: &mut Lss| {
                s.configure_bit_rate(kbit).await?;
                s.store().await
            })
            .await?;
            if let Some(delay) = activate {
                session.activate_bit_timing(Duration::from_millis(u64::from(delay))).await.map_err(failed)?;
            }
            println!(
                "bit rate {kbit} kbit/s configured and stored{}",
                if activate.is_some() { ", activated" } else { "" }
            );
        }
        LssCmd::Store { id } => {
            let ident = identity(&id, eds)?;
            in_configuration(&mut session, ident, async |s: &mut Lss| s.store().await).await?;
            println!("configuration stored");
        }
        LssCmd::Inquire { id } => {
            let ident = identity(&id, eds)?;
            let mut answer = None;
            in_configuration(&mut session, ident, async |s: &mut Lss| {
                answer = Some((s.inquire_identity().await?, s.inquire_node_id().await?));
                Ok(())
            })
            .await?;
            if let Some((id, node)) = answer {
                if json {
                    println!("{}", json!({ "identity": show(&id), "node": node }));
                } else {
                    match node {
                        Some(n) => println!("{id}, node-ID {n}"),
                        None => println!("{id}, no node-ID"),
                    }
                }
            }
        }
        LssCmd::UnconfigureAll => {
            session.unconfigure_all().await.map_err(failed)?;
            println!("every device without a node-ID (stored); reset communication sent");
        }
        LssCmd::Assign { network } => {
            let net = Network::load(std::slice::from_ref(&network)).map_err(|e| (2, e.to_string()))?;
            let plan = net.lss_plan();
            if plan.is_empty() {
                return Err((2, format!("{}: no node has a `serial`: nothing to assign", network.display())));
            }
            let report = session.assign(&plan).await.map_err(failed)?;
            for (id, node) in &report.assigned {
                line(json, "assigned", id, Some(*node));
            }
            for (id, node) in &report.missing {
                line(json, "missing", id, Some(*node));
            }
            for id in &report.unknown {
                line(json, "unknown", id, None);
            }
            if !report.missing.is_empty() {
                return Err((1, format!("{} device(s) of the description did not answer", report.missing.len())));
            }
        }
    }
    Ok(())
}

fn line(json: bool, what: &str, id: &Identity, node: Option<u8>) {
    if json {
        println!("{}", json!({ "result": what, "identity": show(id), "node": node }));
    } else {
        match (what, node) {
            ("assigned", Some(n)) => println!("node {n}: {id}"),
            ("missing", Some(n)) => println!("node {n}: not found ({id})"),
            _ => println!("not in the description, left without a node-ID: {id}"),
        }
    }
}

/// Runs `f` with the device of `identity` (or, without one, every device) in configuration,
/// then every device back to waiting.
async fn in_configuration(
    session: &mut Lss,
    identity: Option<Identity>,
    f: impl AsyncFnOnce(&mut Lss) -> Result<(), od_master::Error>,
) -> Result<(), Fail> {
    let r = async {
        match identity {
            Some(id) => session.switch_selective(id).await?,
            None => session.switch_global(Mode::Configuration).await?,
        }
        f(session).await
    }
    .await;
    let back = session.switch_global(Mode::Waiting).await;
    r.map_err(failed)?;
    back.map_err(failed)
}
