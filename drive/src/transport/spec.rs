//! Bus addresses as written on a command line (`--bus tcp://127.0.0.1:29536/can0`).

use std::fmt;
use std::str::FromStr;

use super::socketcand::parse_channel;
use super::{Endpoint, SocketcandClient, TransportError};

/// Channel a `tcp://` address opens when it names none.
pub const DEFAULT_CHANNEL: &str = "can0";

/// Where a device finds its bus, parsed from text:
///
/// * `tcp://HOST:PORT` or `tcp://HOST:PORT/CHANNEL`: a channel of a socketcand server (a
///   `drive-sim hub` or a real socketcand); the channel defaults to [`DEFAULT_CHANNEL`].
/// * `socketcan:IFACE` (or `socketcan://IFACE`): a Linux CAN interface; needs the `socketcan`
///   feature.
///
/// ```
/// use drive::transport::BusSpec;
/// let spec: BusSpec = "tcp://127.0.0.1:29536/vcan1".parse().unwrap();
/// assert_eq!(spec, BusSpec::Tcp { addr: "127.0.0.1:29536".into(), channel: "vcan1".into() });
/// assert_eq!(spec.to_string(), "tcp://127.0.0.1:29536/vcan1");
/// assert!("udp://x".parse::<BusSpec>().is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BusSpec {
    /// A socketcand server.
    Tcp {
        /// `HOST:PORT`.
        addr: String,
        /// Channel to open.
        channel: String,
    },
    /// A SocketCAN interface.
    SocketCan {
        /// Interface name, such as `can0`.
        interface: String,
    },
}

/// Text that is not a [`BusSpec`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("bad bus address '{text}': {reason} (expected tcp://HOST:PORT[/CHANNEL] or socketcan:IFACE)")]
pub struct BusSpecError {
    text: String,
    reason: &'static str,
}

impl FromStr for BusSpec {
    type Err = BusSpecError;

    fn from_str(text: &str) -> Result<Self, BusSpecError> {
        let fail = |reason| BusSpecError { text: text.chars().take(80).collect(), reason };
        if let Some(rest) = text.strip_prefix("tcp://") {
            let (addr, channel) = rest.split_once('/').unwrap_or((rest, DEFAULT_CHANNEL));
            let (host, port) = addr.rsplit_once(':').ok_or_else(|| fail("no port"))?;
            if host.is_empty() {
                return Err(fail("no host"));
            }
            port.parse::<u16>().map_err(|_| fail("the port must be a number from 0 to 65535"))?;
            parse_channel(channel).map_err(|_| fail("bad channel name"))?;
            return Ok(BusSpec::Tcp { addr: addr.to_owned(), channel: channel.to_owned() });
        }
        let interface = text.strip_prefix("socketcan://").or_else(|| text.strip_prefix("socketcan:"));
        if let Some(interface) = interface {
            // Linux interface names: at most 15 bytes, no '/' or whitespace.
            if interface.is_empty()
                || interface.len() > 15
                || !interface.bytes().all(|b| b.is_ascii_graphic() && b != b'/')
            {
                return Err(fail("bad interface name"));
            }
            return Ok(BusSpec::SocketCan { interface: interface.to_owned() });
        }
        Err(fail("unknown scheme"))
    }
}

impl fmt::Display for BusSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusSpec::Tcp { addr, channel } => write!(f, "tcp://{addr}/{channel}"),
            BusSpec::SocketCan { interface } => write!(f, "socketcan:{interface}"),
        }
    }
}

impl BusSpec {
    /// Connects to the bus.
    pub fn open(&self) -> Result<Box<dyn Endpoint>, TransportError> {
        match self {
            BusSpec::Tcp { addr, channel } => Ok(Box::new(SocketcandClient::connect(addr.as_str(), channel)?)),
            BusSpec::SocketCan { interface } => open_socketcan(interface),
        }
    }
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn open_socketcan(interface: &str) -> Result<Box<dyn Endpoint>, TransportError> {
    Ok(Box::new(super::socketcan::SocketCan::open(interface)?))
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn open_socketcan(interface: &str) -> Result<Box<dyn Endpoint>, TransportError> {
    Err(TransportError::Unavailable(format!(
        "cannot open {interface}: SocketCAN needs Linux and a build with `--features socketcan`"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_form() {
        assert_eq!(
            "tcp://localhost:29536".parse(),
            Ok(BusSpec::Tcp { addr: "localhost:29536".into(), channel: DEFAULT_CHANNEL.into() })
        );
        assert_eq!("tcp://[::1]:1/x".parse(), Ok(BusSpec::Tcp { addr: "[::1]:1".into(), channel: "x".into() }));
        assert_eq!("socketcan:vcan0".parse(), Ok(BusSpec::SocketCan { interface: "vcan0".into() }));
        assert_eq!("socketcan://can1".parse(), Ok(BusSpec::SocketCan { interface: "can1".into() }));
    }

    #[test]
    fn rejects_malformed_addresses() {
        for bad in [
            "",
            "can0",
            "tcp://",
            "tcp://host",
            "tcp://:80",
            "tcp://host:99999",
            "tcp://host:80/",
            "tcp://host:80/a b",
            "socketcan:",
            "socketcan:averyveryverylongname",
            "socketcan:a/b",
        ] {
            let err = bad.parse::<BusSpec>().unwrap_err();
            assert!(err.to_string().contains("expected tcp://"), "{err}");
        }
    }

    #[cfg(not(all(feature = "socketcan", target_os = "linux")))]
    #[test]
    fn socketcan_without_the_feature_says_how_to_get_it() {
        let spec: BusSpec = "socketcan:vcan0".parse().unwrap();
        let err = spec.open().err().unwrap().to_string();
        assert!(err.contains("--features socketcan"), "{err}");
    }
}
