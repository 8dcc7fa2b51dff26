//! SocketCAN on a real kernel interface: runs only where `vcan0` exists (created as root with
//! `ip link add dev vcan0 type vcan && ip link set vcan0 up`), on Linux (where SocketCAN is
//! always built in); otherwise it says on stdout that it was skipped, and why.

/// Why the vcan tests cannot run here, or `None` when they can.
fn skip_reason() -> Option<&'static str> {
    if !cfg!(target_os = "linux") {
        return Some("not on Linux");
    }
    if !std::path::Path::new("/sys/class/net/vcan0").exists() {
        return Some("no vcan0 interface (ip link add dev vcan0 type vcan; ip link set vcan0 up)");
    }
    None
}

#[test]
fn two_sockets_on_vcan0_hear_each_other_blocking_and_async() {
    match skip_reason() {
        Some(reason) => {
            println!("SKIPPED socketcan::two_sockets_on_vcan0_hear_each_other_blocking_and_async: {reason}")
        }
        #[cfg(target_os = "linux")]
        None => vcan::exchange(),
        #[cfg(not(target_os = "linux"))]
        None => unreachable!("no vcan test off Linux"),
    }
}

#[cfg(target_os = "linux")]
mod vcan {
    use std::time::Duration;

    use od_bus::{CanFrame, Endpoint};

    pub(super) fn exchange() {
        let mut a = od_bus::open("socketcan://vcan0").unwrap();
        let mut b = od_bus::open("socketcan://vcan0").unwrap();
        let frames = [
            CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap(),
            CanFrame::extended(0x1ABC_DEF0, &[1, 2]).unwrap(),
            CanFrame::remote(0x705, false, 1).unwrap(),
        ];
        for frame in frames {
            a.send(frame).unwrap();
            assert_eq!(b.recv_timeout(Duration::from_secs(5)).unwrap(), Some(frame));
        }
        assert_eq!(a.try_recv().unwrap(), None, "a socket does not hear itself");
        #[cfg(feature = "tokio")]
        {
            let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
            runtime.block_on(async {
                let mut master = od_bus::tokio::Bus::open("socketcan://vcan0").await.unwrap();
                master.send(frames[0]).await.unwrap();
                assert_eq!(b.recv_timeout(Duration::from_secs(5)).unwrap(), Some(frames[0]));
                b.send(frames[1]).unwrap();
                let got = tokio::time::timeout(Duration::from_secs(5), master.recv()).await.unwrap().unwrap();
                assert_eq!(got, frames[1]);
            });
        }
    }
}
