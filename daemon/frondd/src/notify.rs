//! The sd_notify protocol, spoken directly (a datagram to `$NOTIFY_SOCKET`): `READY=1`,
//! `WATCHDOG=1`, `STOPPING=1`, `STATUS=...`. Without systemd (no `NOTIFY_SOCKET`) every call is a
//! no-op, so frondd runs the same by hand.

use std::os::unix::net::UnixDatagram;
use std::time::Duration;

/// A connection to the service manager, if there is one.
pub struct Notifier {
    socket: Option<(UnixDatagram, NotifyAddr)>,
    watchdog: Option<Duration>,
}

enum NotifyAddr {
    Path(std::path::PathBuf),
    Abstract(Vec<u8>),
}

impl Notifier {
    /// Reads `NOTIFY_SOCKET` and `WATCHDOG_USEC` (honouring `WATCHDOG_PID`).
    pub fn from_env() -> Notifier {
        let socket = std::env::var_os("NOTIFY_SOCKET").and_then(|path| {
            let bytes = std::os::unix::ffi::OsStrExt::as_bytes(path.as_os_str()).to_vec();
            let addr = match bytes.first() {
                Some(b'@') => NotifyAddr::Abstract(bytes[1..].to_vec()),
                Some(b'/') => NotifyAddr::Path(std::path::PathBuf::from(path)),
                _ => return None,
            };
            UnixDatagram::unbound().ok().map(|s| (s, addr))
        });
        let pid_ok = std::env::var("WATCHDOG_PID")
            .ok()
            .and_then(|p| p.parse::<u32>().ok())
            .is_none_or(|pid| pid == std::process::id());
        let watchdog = std::env::var("WATCHDOG_USEC")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
            .filter(|&us| us > 0 && pid_ok)
            .map(Duration::from_micros);
        Notifier { socket, watchdog }
    }

    /// The watchdog interval requested by the service manager, if any.
    pub fn watchdog_interval(&self) -> Option<Duration> {
        self.watchdog
    }

    /// Sends one notification; errors are ignored (the manager may be gone).
    pub fn notify(&self, state: &str) {
        let Some((sock, addr)) = &self.socket else { return };
        match addr {
            NotifyAddr::Path(p) => {
                let _ = sock.send_to(state.as_bytes(), p);
            }
            NotifyAddr::Abstract(name) => {
                use std::os::linux::net::SocketAddrExt;
                if let Ok(a) = std::os::unix::net::SocketAddr::from_abstract_name(name) {
                    let _ = sock.send_to_addr(state.as_bytes(), &a);
                }
            }
        }
    }
}
