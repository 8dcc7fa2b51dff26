//! A `drive-sim` process for the end-to-end tests, and the wait for a frame they share.

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use od_bus::{CanFrame, Endpoint, SocketcandClient};

/// How long `stop` waits for the process to end after SIGTERM.
const STOP_WAIT: Duration = Duration::from_secs(10);

/// A running `drive-sim` that listens on a socketcand port; killed when dropped.
pub struct DriveSim {
    child: Child,
    /// The address it said it listens on.
    pub addr: SocketAddr,
}

impl DriveSim {
    /// Starts `drive-sim ARGS` and waits for its first line, `listening on ADDRESS`.
    pub fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start drive-sim");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("read the first line");
        let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("first line {line:?}"));
        Self { addr: addr.parse().unwrap(), child }
    }

    /// SIGTERM (so that it writes its trace and parameters), then waits (bounded); returns
    /// whether it exited with 0, and its standard error.
    pub fn stop(mut self) -> (bool, String) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: sending a signal to our own child process.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
        let deadline = Instant::now() + STOP_WAIT;
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            assert!(Instant::now() < deadline, "drive-sim did not stop after SIGTERM");
            std::thread::sleep(Duration::from_millis(10));
        };
        let mut text = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            e.read_to_string(&mut text).unwrap();
        }
        (status.success(), text)
    }
}

impl Drop for DriveSim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The next frame with id `id`, skipping others; `None` if none arrives within `within`.
pub fn next_with_id(bus: &mut SocketcandClient, id: u32, within: Duration) -> Option<CanFrame> {
    let deadline = Instant::now() + within;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return None;
        }
        match bus.recv_timeout(left).unwrap() {
            Some(f) if f.id() == id => return Some(f),
            Some(_) => continue,
            None => return None,
        }
    }
}
