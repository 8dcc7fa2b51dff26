//! Bus addresses: every valid form round-trips through its text, aliases land on the canonical
//! form, and no text makes the parser panic or accept garbage silently.

use od_bus::{BusAddr, Endpoint, MemoryBus, TransportError};
use proptest::prelude::*;

/// The accepted forms, as every error message must name them.
const FORMS: &str = "socketcand://HOST:PORT/CHANNEL, socketcan://IFACE, slcan://PORT?bitrate=500000 or mem://NAME";

/// Printable ASCII without the characters an address gives meaning to or forbids.
fn word(max: usize) -> impl Strategy<Value = String> {
    proptest::string::string_regex(&format!("[A-Za-z0-9_.~%+=,;!$&*()'-]{{1,{max}}}")).unwrap()
}

fn host() -> impl Strategy<Value = String> {
    prop_oneof![
        word(30),
        (any::<u8>(), any::<u8>(), any::<u8>(), any::<u8>()).prop_map(|(a, b, c, d)| format!("{a}.{b}.{c}.{d}")),
        any::<[u16; 8]>().prop_map(|g| format!("[{}]", g.map(|x| format!("{x:x}")).join(":"))),
        Just("[::1]".to_owned()),
    ]
}

fn any_addr() -> impl Strategy<Value = BusAddr> {
    prop_oneof![
        (host(), any::<u16>(), word(64)).prop_map(|(host, port, channel)| BusAddr::Socketcand { host, port, channel }),
        word(15).prop_map(|interface| BusAddr::SocketCan { interface }),
        prop_oneof![Just(String::new()), word(64)].prop_map(|name| BusAddr::Memory { name }),
        (
            prop_oneof![
                Just("/dev/ttyACM0".to_owned()),
                Just("COM4".to_owned()),
                word(40),
                word(20).prop_map(|w| format!("/dev/{w}"))
            ],
            proptest::sample::select(&od_bus::slcan::BITRATES[..]),
            1u32..4_000_000,
            any::<bool>(),
        )
            .prop_map(|(port, bitrate, serial_baud, listen_only)| BusAddr::Slcan {
                port,
                bitrate,
                serial_baud,
                listen_only
            }),
    ]
}

proptest! {
    #[test]
    fn every_address_round_trips_through_its_text(addr in any_addr()) {
        let text = addr.to_string();
        prop_assert_eq!(text.parse::<BusAddr>(), Ok(addr));
    }

    #[test]
    fn every_alias_means_its_canonical_form(addr in any_addr()) {
        // tcp:// for socketcand://, socketcan: for socketcan://; the default channel may go.
        let text = addr.to_string();
        let aliases: Vec<String> = match &addr {
            BusAddr::Socketcand { host, port, channel } => {
                let mut a = vec![format!("tcp://{host}:{port}/{channel}")];
                if channel == od_bus::DEFAULT_CHANNEL {
                    a.push(format!("socketcand://{host}:{port}"));
                    a.push(format!("tcp://{host}:{port}"));
                }
                a
            }
            BusAddr::SocketCan { interface } => vec![format!("socketcan:{interface}")],
            BusAddr::Slcan { port, bitrate, serial_baud, listen_only } => {
                // slcan: for slcan://, the options in any order, defaults left out.
                let mut options = vec![format!("serial={serial_baud}")];
                if *listen_only {
                    options.push("listen-only=true".into());
                }
                if *bitrate == 500_000 {
                    vec![format!("slcan:{port}?{}", options.join("&"))]
                } else {
                    options.push(format!("bitrate={bitrate}"));
                    options.reverse();
                    vec![format!("slcan:{port}?{}", options.join("&"))]
                }
            }
            BusAddr::Memory { .. } => vec![],
        };
        for alias in aliases {
            let parsed = alias.parse::<BusAddr>().unwrap();
            prop_assert_eq!(parsed.to_string(), text.clone());
        }
    }

    #[test]
    fn any_text_parses_or_names_the_accepted_forms(text in "\\PC{0,120}") {
        match text.parse::<BusAddr>() {
            // Whatever parsed prints to text that parses to the same address.
            Ok(addr) => prop_assert_eq!(addr.to_string().parse::<BusAddr>(), Ok(addr)),
            Err(err) => prop_assert!(err.to_string().contains(FORMS)),
        }
    }

    #[test]
    fn scheme_like_garbage_never_panics(
        scheme in prop_oneof![Just("socketcand://"), Just("tcp://"), Just("socketcan:"), Just("socketcan://"), Just("mem://"), Just("slcan://"), Just("slcan://COM4?")],
        rest in proptest::collection::vec(any::<u8>(), 0..80),
    ) {
        let text = format!("{scheme}{}", String::from_utf8_lossy(&rest));
        if let Ok(addr) = text.parse::<BusAddr>() {
            prop_assert_eq!(addr.to_string().parse::<BusAddr>(), Ok(addr));
        }
    }
}

#[test]
fn opening_a_bad_address_is_an_address_error() {
    let err = od_bus::open("can0").err().unwrap();
    assert!(matches!(err, TransportError::Address(_)), "{err:?}");
    assert!(err.to_string().contains(FORMS), "{err}");
}

#[test]
fn mem_addresses_open_the_named_bus_of_the_process() {
    let bus = MemoryBus::named("addr-test");
    let mut device = bus.endpoint();
    let mut other = od_bus::open("mem://addr-test").unwrap();
    let mut stranger = od_bus::open("mem://addr-test-2").unwrap();
    other.send(od_bus::CanFrame::standard(0x080, &[]).unwrap()).unwrap();
    assert_eq!(device.try_recv().unwrap().map(|f| f.id()), Some(0x080));
    assert_eq!(stranger.try_recv().unwrap(), None, "another name is another bus");
    assert_eq!(bus.endpoint_count(), 2);
}

#[test]
fn a_named_bus_nobody_holds_starts_afresh() {
    let first = MemoryBus::named("addr-test-fresh");
    let endpoint = first.endpoint();
    assert_eq!(MemoryBus::named("addr-test-fresh").endpoint_count(), 1);
    drop((first, endpoint));
    assert_eq!(MemoryBus::named("addr-test-fresh").endpoint_count(), 0);
}
