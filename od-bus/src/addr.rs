//! Bus addresses: the one string a bus is opened from (`--bus socketcand://127.0.0.1:29536/can0`).

use std::fmt;
use std::str::FromStr;

use crate::bus::MemoryBus;
use crate::client::SocketcandClient;
use crate::endpoint::Endpoint;
use crate::error::{BusAddrError, TransportError};
use crate::socketcand::parse_channel;

/// Channel a socketcand address opens when it names none.
pub const DEFAULT_CHANNEL: &str = "can0";

/// Longest Linux network interface name (IFNAMSIZ less the NUL).
const MAX_INTERFACE_LEN: usize = 15;

/// Where a bus is, parsed from text:
///
/// * `socketcand://HOST:PORT/CHANNEL`: a channel of a socketcand server (a `drive-sim hub`, an
///   [`Hub`](crate::Hub) in some process, or a real socketcand). Without `/CHANNEL` the channel
///   is [`DEFAULT_CHANNEL`]. `tcp://` is accepted for `socketcand://` (the form `drive-sim`
///   used first). An IPv6 host is written in brackets: `socketcand://[::1]:29536/can0`.
/// * `socketcan://IFACE`: a Linux CAN interface (`can0`, `vcan0`); needs the `socketcan`
///   feature. `socketcan:IFACE` is accepted too.
/// * `slcan://PORT?bitrate=500000`: an slcan serial adapter (CANable, USBtin, Lawicel CANUSB)
///   on the serial port PORT: `slcan:///dev/ttyACM0` (Linux), `slcan://COM4` (Windows),
///   `slcan:///dev/cu.usbmodem1101` (macOS). Options after `?`, joined by `&`: `bitrate=` the
///   CAN bit rate (10000, 20000, 50000, 100000, 125000, 250000, 500000 (the default), 800000,
///   1000000: `S0` to `S8`), `serial=` the serial port's speed (default 115200; USB adapters
///   ignore it), `listen-only` (no acknowledgements, no transmissions).
/// * `mem://NAME`: the in-memory bus of this process called NAME ([`MemoryBus::named`]);
///   `mem://` is the one called "". Blocking devices and async masters that open the same
///   name share one bus.
///
/// `Display` writes the canonical form, which parses back to the same address.
///
/// ```
/// use od_bus::BusAddr;
/// let addr: BusAddr = "socketcand://127.0.0.1:29536/vcan1".parse().unwrap();
/// assert_eq!(addr, BusAddr::Socketcand { host: "127.0.0.1".into(), port: 29536, channel: "vcan1".into() });
/// assert_eq!(addr.to_string(), "socketcand://127.0.0.1:29536/vcan1");
/// assert_eq!("tcp://127.0.0.1:29536/vcan1".parse::<BusAddr>().unwrap(), addr);
/// let err = "udp://x".parse::<BusAddr>().unwrap_err().to_string();
/// assert!(err.contains("socketcand://HOST:PORT/CHANNEL"), "{err}");
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum BusAddr {
    /// A channel of a socketcand server.
    Socketcand {
        /// Host name or address; an IPv6 address keeps its brackets (`[::1]`).
        host: String,
        /// TCP port.
        port: u16,
        /// Channel to open.
        channel: String,
    },
    /// A Linux CAN interface.
    SocketCan {
        /// Interface name, such as `can0`.
        interface: String,
    },
    /// An slcan adapter on a serial port.
    Slcan {
        /// The serial port: `/dev/ttyACM0`, `COM4`, `/dev/cu.usbmodem1101`.
        port: String,
        /// CAN bit rate, one of [`slcan::BITRATES`](crate::slcan::BITRATES).
        bitrate: u32,
        /// The serial port's speed in baud (USB adapters ignore it).
        serial_baud: u32,
        /// Open the channel listening only.
        listen_only: bool,
    },
    /// An in-memory bus of this process.
    Memory {
        /// Its name ("" for `mem://`).
        name: String,
    },
}

impl FromStr for BusAddr {
    type Err = BusAddrError;

    fn from_str(text: &str) -> Result<Self, BusAddrError> {
        // The text is echoed in the message: printable and short.
        let fail = |reason| BusAddrError::new(text, reason);
        if let Some(rest) = text.strip_prefix("socketcand://").or_else(|| text.strip_prefix("tcp://")) {
            let (addr, channel) = rest.split_once('/').unwrap_or((rest, DEFAULT_CHANNEL));
            let (host, port) = split_host_port(addr).map_err(fail)?;
            parse_channel(channel).map_err(|_| fail("the channel must be 1 to 64 printable characters"))?;
            return Ok(BusAddr::Socketcand { host: host.to_owned(), port, channel: channel.to_owned() });
        }
        if let Some(interface) = text.strip_prefix("socketcan://").or_else(|| text.strip_prefix("socketcan:")) {
            if interface.is_empty()
                || interface.len() > MAX_INTERFACE_LEN
                || !interface.bytes().all(|b| b.is_ascii_graphic() && b != b'/')
            {
                return Err(fail("the interface name must be 1 to 15 printable characters without '/'"));
            }
            return Ok(BusAddr::SocketCan { interface: interface.to_owned() });
        }
        if let Some(rest) = text.strip_prefix("slcan://").or_else(|| text.strip_prefix("slcan:")) {
            return parse_slcan(rest).map_err(fail);
        }
        if let Some(name) = text.strip_prefix("mem://") {
            if !name.is_empty() && parse_channel(name).is_err() {
                return Err(fail("the name must be up to 64 printable characters"));
            }
            return Ok(BusAddr::Memory { name: name.to_owned() });
        }
        Err(fail("unknown scheme"))
    }
}

/// Default CAN bit rate of an slcan address.
pub(crate) const SLCAN_BITRATE: u32 = 500_000;
/// Default serial speed of an slcan address.
pub(crate) const SLCAN_SERIAL_BAUD: u32 = 115_200;

/// `PORT?bitrate=N&serial=N&listen-only` after `slcan://`.
fn parse_slcan(rest: &str) -> Result<BusAddr, &'static str> {
    let (port, options) = rest.split_once('?').unwrap_or((rest, ""));
    if port.is_empty() || port.len() > 255 || !port.chars().all(|c| !c.is_control()) {
        return Err("the serial port must be 1 to 255 printable characters (slcan:///dev/ttyACM0, slcan://COM4)");
    }
    let (mut bitrate, mut serial_baud, mut listen_only) = (SLCAN_BITRATE, SLCAN_SERIAL_BAUD, false);
    for option in options.split('&').filter(|o| !o.is_empty()) {
        match option.split_once('=') {
            Some(("bitrate", value)) => {
                bitrate =
                    value.parse().ok().filter(|b| crate::slcan::bitrate_code(*b).is_some()).ok_or(
                        "bitrate must be 10000, 20000, 50000, 100000, 125000, 250000, 500000, 800000 or 1000000",
                    )?;
            }
            Some(("serial", value)) => {
                serial_baud = value
                    .parse()
                    .ok()
                    .filter(|b| *b > 0)
                    .ok_or("serial must be the port's speed in baud, such as 115200")?;
            }
            None if option == "listen-only" => listen_only = true,
            Some(("listen-only", "true" | "1")) => listen_only = true,
            Some(("listen-only", "false" | "0")) => listen_only = false,
            _ => return Err("unknown slcan option: the options are bitrate=N, serial=BAUD and listen-only"),
        }
    }
    Ok(BusAddr::Slcan { port: port.to_owned(), bitrate, serial_baud, listen_only })
}

/// `HOST:PORT`, the host non-empty, an IPv6 host in brackets.
fn split_host_port(addr: &str) -> Result<(&str, u16), &'static str> {
    let (host, port) = addr.rsplit_once(':').ok_or("no port")?;
    if host.is_empty() {
        return Err("no host");
    }
    let bracketed = host.starts_with('[') && host.ends_with(']') && host.len() > 2;
    let inner = if bracketed { &host[1..host.len() - 1] } else { host };
    if !inner.bytes().all(|b| b.is_ascii_graphic() && !matches!(b, b'/' | b'[' | b']' | b'@' | b'?' | b'#')) {
        return Err("the host must be a name or an address");
    }
    if inner.contains(':') && !bracketed {
        return Err("an IPv6 host must be written in brackets, [::1]");
    }
    if port.is_empty() || port.len() > 5 || !port.bytes().all(|b| b.is_ascii_digit()) {
        return Err("the port must be a number from 0 to 65535");
    }
    let port = port.parse::<u16>().map_err(|_| "the port must be a number from 0 to 65535")?;
    Ok((host, port))
}

impl fmt::Display for BusAddr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusAddr::Socketcand { host, port, channel } => write!(f, "socketcand://{host}:{port}/{channel}"),
            BusAddr::SocketCan { interface } => write!(f, "socketcan://{interface}"),
            BusAddr::Slcan { port, bitrate, serial_baud, listen_only } => {
                write!(f, "slcan://{port}?bitrate={bitrate}")?;
                if *serial_baud != SLCAN_SERIAL_BAUD {
                    write!(f, "&serial={serial_baud}")?;
                }
                if *listen_only {
                    f.write_str("&listen-only")?;
                }
                Ok(())
            }
            BusAddr::Memory { name } => write!(f, "mem://{name}"),
        }
    }
}

impl BusAddr {
    /// `HOST:PORT` of a socketcand address, as `ToSocketAddrs` reads it.
    pub fn socket_addr(&self) -> Option<String> {
        match self {
            BusAddr::Socketcand { host, port, .. } => Some(format!("{host}:{port}")),
            _ => None,
        }
    }

    /// The setup of an slcan address.
    pub fn slcan_setup(&self) -> Option<crate::slcan::Setup> {
        match self {
            BusAddr::Slcan { bitrate, listen_only, .. } => {
                Some(crate::slcan::Setup { bitrate: *bitrate, listen_only: *listen_only })
            }
            _ => None,
        }
    }

    /// Opens the bus, blocking: a [`SocketcandClient`] connected and in raw mode, a SocketCAN
    /// socket, an slcan adapter set up and open, or an endpoint of the named [`MemoryBus`].
    pub fn open(&self) -> Result<Box<dyn Endpoint>, TransportError> {
        match self {
            BusAddr::Socketcand { host, port, channel } => {
                Ok(Box::new(SocketcandClient::connect((host_for_connect(host), *port), channel)?))
            }
            BusAddr::SocketCan { interface } => open_socketcan(interface),
            BusAddr::Slcan { port, bitrate, serial_baud, listen_only } => Ok(Box::new(crate::slcan::SlcanPort::open(
                port,
                *serial_baud,
                crate::slcan::Setup { bitrate: *bitrate, listen_only: *listen_only },
            )?)),
            BusAddr::Memory { name } => Ok(Box::new(MemoryBus::named(name).endpoint())),
        }
    }
}

/// The host as the resolver takes it: an IPv6 address without its brackets.
pub(crate) fn host_for_connect(host: &str) -> &str {
    host.strip_prefix('[').and_then(|h| h.strip_suffix(']')).unwrap_or(host)
}

/// Opens the bus at `addr` (see [`BusAddr`]), blocking.
///
/// ```
/// let err = od_bus::open("can0").err().unwrap().to_string();
/// assert!(err.contains("expected socketcand://HOST:PORT/CHANNEL"), "{err}");
/// ```
pub fn open(addr: &str) -> Result<Box<dyn Endpoint>, TransportError> {
    addr.parse::<BusAddr>()?.open()
}

#[cfg(target_os = "linux")]
fn open_socketcan(interface: &str) -> Result<Box<dyn Endpoint>, TransportError> {
    Ok(Box::new(crate::socketcan::SocketCan::open(interface)?))
}

#[cfg(not(target_os = "linux"))]
fn open_socketcan(interface: &str) -> Result<Box<dyn Endpoint>, TransportError> {
    Err(unavailable(interface))
}

#[cfg(not(target_os = "linux"))]
pub(crate) fn unavailable(interface: &str) -> TransportError {
    TransportError::Unavailable(format!(
        "cannot open socketcan://{interface}: SocketCAN is a Linux kernel interface and this is {}; \
         reach a CAN adapter here with slcan://PORT (CANable, USBtin, Lawicel), or a Linux machine's \
         interface with socketcand://HOST:PORT/{interface}",
        std::env::consts::OS
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::FORMS;

    fn socketcand(host: &str, port: u16, channel: &str) -> BusAddr {
        BusAddr::Socketcand { host: host.into(), port, channel: channel.into() }
    }

    #[test]
    fn parses_every_form_and_alias() {
        assert_eq!("socketcand://localhost:29536/can1".parse(), Ok(socketcand("localhost", 29536, "can1")));
        assert_eq!("socketcand://localhost:29536".parse(), Ok(socketcand("localhost", 29536, DEFAULT_CHANNEL)));
        assert_eq!("tcp://localhost:29536".parse(), Ok(socketcand("localhost", 29536, DEFAULT_CHANNEL)));
        assert_eq!("tcp://[::1]:1/x".parse(), Ok(socketcand("[::1]", 1, "x")));
        assert_eq!("socketcan:vcan0".parse(), Ok(BusAddr::SocketCan { interface: "vcan0".into() }));
        assert_eq!("socketcan://can1".parse(), Ok(BusAddr::SocketCan { interface: "can1".into() }));
        assert_eq!("mem://".parse(), Ok(BusAddr::Memory { name: String::new() }));
        assert_eq!("mem://line-1".parse(), Ok(BusAddr::Memory { name: "line-1".into() }));
        let slcan = |port: &str, bitrate, serial_baud, listen_only| BusAddr::Slcan {
            port: port.into(),
            bitrate,
            serial_baud,
            listen_only,
        };
        assert_eq!("slcan:///dev/ttyACM0".parse(), Ok(slcan("/dev/ttyACM0", 500_000, 115_200, false)));
        assert_eq!("slcan://COM4?bitrate=1000000".parse(), Ok(slcan("COM4", 1_000_000, 115_200, false)));
        assert_eq!(
            "slcan:///dev/cu.usbmodem1101?bitrate=125000&serial=921600&listen-only".parse(),
            Ok(slcan("/dev/cu.usbmodem1101", 125_000, 921_600, true))
        );
        assert_eq!("slcan:COM4?listen-only=true".parse(), Ok(slcan("COM4", 500_000, 115_200, true)));
    }

    #[test]
    fn aliases_print_in_the_canonical_form() {
        for (alias, canonical) in [
            ("tcp://h:1", "socketcand://h:1/can0"),
            ("tcp://[::1]:80/a", "socketcand://[::1]:80/a"),
            ("socketcand://h:007/c", "socketcand://h:7/c"),
            ("socketcan:vcan0", "socketcan://vcan0"),
            ("slcan:COM4", "slcan://COM4?bitrate=500000"),
            (
                "slcan:///dev/ttyACM0?listen-only=1&serial=9600",
                "slcan:///dev/ttyACM0?bitrate=500000&serial=9600&listen-only",
            ),
        ] {
            assert_eq!(alias.parse::<BusAddr>().unwrap().to_string(), canonical);
        }
    }

    #[test]
    fn rejects_malformed_addresses_naming_the_accepted_forms() {
        for (bad, reason) in [
            ("", "unknown scheme"),
            ("can0", "unknown scheme"),
            ("udp://h:1/c", "unknown scheme"),
            ("tcp://", "no port"),
            ("tcp://host", "no port"),
            ("socketcand://:80", "no host"),
            ("socketcand://host:99999", "the port must be a number from 0 to 65535"),
            ("socketcand://host:+80", "the port must be a number from 0 to 65535"),
            ("socketcand://host:", "the port must be a number from 0 to 65535"),
            ("socketcand://::1:80/c", "an IPv6 host must be written in brackets, [::1]"),
            ("socketcand://a b:80/c", "the host must be a name or an address"),
            ("socketcand://[]:80/c", "the host must be a name or an address"),
            ("socketcand://host:80/", "the channel must be 1 to 64 printable characters"),
            ("socketcand://host:80/a b", "the channel must be 1 to 64 printable characters"),
            ("socketcan:", "the interface name must be 1 to 15 printable characters without '/'"),
            (
                "socketcan://averyveryverylongname",
                "the interface name must be 1 to 15 printable characters without '/'",
            ),
            ("socketcan:a/b", "the interface name must be 1 to 15 printable characters without '/'"),
            ("mem://a b", "the name must be up to 64 printable characters"),
            ("slcan://", "the serial port must be 1 to 255 printable characters (slcan:///dev/ttyACM0, slcan://COM4)"),
            (
                "slcan://COM4?bitrate=300000",
                "bitrate must be 10000, 20000, 50000, 100000, 125000, 250000, 500000, 800000 or 1000000",
            ),
            ("slcan://COM4?serial=0", "serial must be the port's speed in baud, such as 115200"),
            ("slcan://COM4?speed=1", "unknown slcan option: the options are bitrate=N, serial=BAUD and listen-only"),
        ] {
            let err = bad.parse::<BusAddr>().unwrap_err();
            assert_eq!(err.reason(), reason, "{bad:?}");
            let text = err.to_string();
            assert!(text.contains(FORMS), "{text}");
        }
    }

    #[test]
    fn the_echoed_text_is_short_and_printable() {
        let err = format!("x\n\u{1b}[2J{}", "y".repeat(500)).parse::<BusAddr>().unwrap_err().to_string();
        assert!(!err.chars().any(char::is_control), "{err:?}");
        assert!(err.len() < 250, "{}", err.len());
    }

    #[cfg(not(target_os = "linux"))]
    #[test]
    fn socketcan_elsewhere_names_the_platform_and_the_alternatives() {
        let err = open("socketcan://vcan0").err().unwrap().to_string();
        assert!(err.contains(std::env::consts::OS) && err.contains("slcan://"), "{err}");
    }

    /// SocketCAN is in every Linux build, with no feature to ask for it: opening an interface
    /// that does not exist fails in the `socketcan` crate (naming the interface), not with
    /// "unavailable".
    #[cfg(target_os = "linux")]
    #[test]
    fn socketcan_is_built_in_on_linux() {
        let err = open("socketcan://nosuchcan9").err().unwrap();
        assert!(!matches!(err, TransportError::Unavailable(_)), "{err}");
        assert!(err.to_string().contains("nosuchcan9"), "{err}");
    }
}
