//! Telling systemd how the station logger is doing (`Type=notify`): ready
//! once the store is open and the buses run, watchdog pings while it
//! lives, stopping when it stops. Without `NOTIFY_SOCKET` (not under
//! systemd) every call does nothing.
//!
//! The protocol is one datagram per message on the Unix socket systemd
//! names in `NOTIFY_SOCKET` (a path, or `@name` in the abstract namespace);
//! `WATCHDOG_USEC` asks for a ping at least that often.

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

/// The socket systemd listens on, when running under it (never elsewhere
/// than on Unix).
pub struct Notifier {
    #[cfg(unix)]
    socket: std::os::unix::net::UnixDatagram,
    #[cfg(unix)]
    address: std::os::unix::net::SocketAddr,
}

impl Notifier {
    /// The notifier `NOTIFY_SOCKET` names, if any (and if it can be reached).
    #[cfg(unix)]
    pub fn from_environment() -> Option<Self> {
        use std::os::unix::net::{SocketAddr, UnixDatagram};
        let name = std::env::var_os("NOTIFY_SOCKET")?;
        let name = name.to_str()?;
        let address = match name.strip_prefix('@') {
            #[cfg(target_os = "linux")]
            Some(abstract_name) => {
                use std::os::linux::net::SocketAddrExt as _;
                SocketAddr::from_abstract_name(abstract_name).ok()?
            }
            #[cfg(not(target_os = "linux"))]
            Some(_) => return None,
            None => SocketAddr::from_pathname(name).ok()?,
        };
        let socket = UnixDatagram::unbound().ok()?;
        Some(Self { socket, address })
    }

    /// No systemd here.
    #[cfg(not(unix))]
    pub fn from_environment() -> Option<Self> {
        None
    }

    /// Sends `state` (`READY=1`, `WATCHDOG=1`, `STATUS=...`); a lost
    /// message is not an error of the logger's.
    pub fn notify(&self, state: &str) {
        #[cfg(unix)]
        let _ = self.socket.send_to_addr(state.as_bytes(), &self.address);
        #[cfg(not(unix))]
        let _ = state;
    }
}

/// How often systemd wants a watchdog ping (`WATCHDOG_USEC`), when it does.
pub fn watchdog_interval() -> Option<Duration> {
    let usec: u64 = std::env::var("WATCHDOG_USEC").ok()?.trim().parse().ok()?;
    // Only the process systemd started is meant (WATCHDOG_PID, when set).
    if let Ok(pid) = std::env::var("WATCHDOG_PID")
        && pid.trim().parse::<u32>().ok() != Some(std::process::id())
    {
        return None;
    }
    (usec > 0).then(|| Duration::from_micros(usec))
}

/// Watchdog pings at half the interval systemd asked for, from a thread of
/// their own, until [`Watchdog::stop`].
pub struct Watchdog {
    stop: Arc<(Mutex<bool>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl Watchdog {
    /// Starts pinging through `notifier` every `interval / 2`.
    pub fn start(notifier: Arc<Notifier>, interval: Duration) -> Self {
        let stop = Arc::new((Mutex::new(false), Condvar::new()));
        let signal = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("watchdog".into())
            .spawn(move || {
                let (stopped, wake) = &*signal;
                let mut guard = stopped.lock().unwrap_or_else(PoisonError::into_inner);
                while !*guard {
                    notifier.notify("WATCHDOG=1");
                    guard = wake.wait_timeout(guard, interval / 2).unwrap_or_else(PoisonError::into_inner).0;
                }
            })
            .ok();
        Self { stop, thread }
    }

    /// Stops the pings.
    pub fn stop(mut self) {
        let (stopped, wake) = &*self.stop;
        *stopped.lock().unwrap_or_else(PoisonError::into_inner) = true;
        wake.notify_all();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
