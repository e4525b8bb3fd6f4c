//! Non-blocking UDP to several targets.
//!
//! Each target has its own connected, non-blocking UDP socket. Connecting is what makes the kernel
//! report a target that is down: the ICMP "port unreachable" it answers with turns into
//! `ECONNREFUSED` on that target's next send, which is counted (`refused`) and skipped; it cannot
//! block or fail the other targets, whose sockets know nothing of it. A full socket buffer
//! (`EWOULDBLOCK`) drops the datagram for that target only and is counted too. Nothing here ever
//! waits.

use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, ToSocketAddrs, UdpSocket};

use thiserror::Error;

use crate::encode::Datagrams;

/// Why the sender could not be set up.
#[derive(Debug, Error)]
pub enum SenderError {
    /// A `--target` could not be parsed or resolved.
    #[error("--target `{spec}`: {message}")]
    BadTarget {
        /// The argument.
        spec: String,
        /// What is wrong.
        message: String,
    },
    /// A fixed local port cannot be shared by several target sockets.
    #[error("--bind {bind}: a fixed local port works with one target only ({targets} given); use port 0")]
    FixedPortWithSeveralTargets {
        /// The bind address.
        bind: SocketAddr,
        /// Number of targets.
        targets: usize,
    },
    /// No target was given.
    #[error("no --target given")]
    NoTarget,
    /// A socket could not be bound, connected or made non-blocking.
    #[error("UDP socket for {target} (bound to {bind}): {source}")]
    Socket {
        /// The target.
        target: SocketAddr,
        /// The local address.
        bind: SocketAddr,
        /// The error.
        #[source]
        source: io::Error,
    },
}

/// Parses `HOST:PORT`, `HOST` (then `default_port`), `[v6]:PORT` or a bare IPv6 address, resolving
/// host names once (at start-up, never while streaming).
pub fn parse_target(spec: &str, default_port: u16) -> Result<SocketAddr, SenderError> {
    let bad = |message: String| SenderError::BadTarget { spec: spec.to_string(), message };
    if spec.is_empty() {
        return Err(bad("empty".into()));
    }
    if let Ok(addr) = spec.parse::<SocketAddr>() {
        return Ok(addr);
    }
    if let Ok(ip) = spec.trim_start_matches('[').trim_end_matches(']').parse::<IpAddr>() {
        return Ok(SocketAddr::new(ip, default_port));
    }
    let with_port = match spec.rsplit_once(':') {
        Some((host, port)) => {
            let port: u16 =
                port.parse().map_err(|_| bad(format!("port `{port}` is not a number 0-65535")))?;
            if host.is_empty() {
                return Err(bad("no host before the port".into()));
            }
            (host.to_string(), port)
        }
        None => (spec.to_string(), default_port),
    };
    let mut addrs =
        with_port.to_socket_addrs().map_err(|e| bad(format!("cannot resolve `{}`: {e}", with_port.0)))?;
    addrs.next().ok_or_else(|| bad(format!("`{}` resolves to no address", with_port.0)))
}

/// Counters of one target.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TargetCounters {
    /// Frames whose datagrams all went out.
    pub frames_sent: u64,
    /// Datagrams sent.
    pub datagrams_sent: u64,
    /// Bytes sent.
    pub bytes_sent: u64,
    /// Sends refused because the target answered ICMP port unreachable (it is down).
    pub refused: u64,
    /// Datagrams dropped because the socket buffer was full.
    pub would_block: u64,
    /// Other send errors (unreachable network, ...).
    pub errors: u64,
}

/// One destination.
#[derive(Debug)]
pub struct Target {
    addr: SocketAddr,
    socket: UdpSocket,
    counters: TargetCounters,
}

impl Target {
    /// Where it sends.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
    /// Its counters.
    pub fn counters(&self) -> TargetCounters {
        self.counters
    }
    /// The local address of its socket.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Sends the frame's datagrams; stops at the first failure (the rest of the frame would be
    /// incomplete anyway) and counts it.
    fn send(&mut self, frame: &Datagrams) {
        for d in frame.iter() {
            match self.socket.send(d) {
                Ok(n) => {
                    self.counters.datagrams_sent += 1;
                    self.counters.bytes_sent += n as u64;
                }
                Err(e) => {
                    match e.kind() {
                        io::ErrorKind::ConnectionRefused => self.counters.refused += 1,
                        io::ErrorKind::WouldBlock => self.counters.would_block += 1,
                        _ => {
                            self.counters.errors += 1;
                            tracing::debug!(target_addr = %self.addr, error = %e, "send failed");
                        }
                    }
                    return;
                }
            }
        }
        if !frame.is_empty() {
            self.counters.frames_sent += 1;
        }
    }
}

/// Sends every frame to every target, never blocking.
#[derive(Debug)]
pub struct Sender {
    targets: Vec<Target>,
}

impl Sender {
    /// One socket per target, bound to `bind` (default: the unspecified address of the target's
    /// family, port 0) and connected to the target.
    pub fn new(targets: &[SocketAddr], bind: Option<SocketAddr>) -> Result<Sender, SenderError> {
        if targets.is_empty() {
            return Err(SenderError::NoTarget);
        }
        if let Some(b) = bind.filter(|b| b.port() != 0 && targets.len() > 1) {
            return Err(SenderError::FixedPortWithSeveralTargets { bind: b, targets: targets.len() });
        }
        let mut out = Vec::with_capacity(targets.len());
        for &target in targets {
            let local = bind.unwrap_or(match target {
                SocketAddr::V4(_) => SocketAddr::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), 0),
                SocketAddr::V6(_) => SocketAddr::new(IpAddr::V6(Ipv6Addr::UNSPECIFIED), 0),
            });
            let err = |source| SenderError::Socket { target, bind: local, source };
            let socket = UdpSocket::bind(local).map_err(err)?;
            socket.connect(target).map_err(err)?;
            socket.set_nonblocking(true).map_err(err)?;
            out.push(Target { addr: target, socket, counters: TargetCounters::default() });
        }
        Ok(Sender { targets: out })
    }

    /// Sends one frame's datagrams to every target.
    pub fn send(&mut self, frame: &Datagrams) {
        for t in &mut self.targets {
            t.send(frame);
        }
    }

    /// The targets with their counters.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_specs() {
        assert_eq!(parse_target("127.0.0.1:9000", 1).unwrap(), "127.0.0.1:9000".parse().unwrap());
        assert_eq!(parse_target("127.0.0.1", 39539).unwrap(), "127.0.0.1:39539".parse().unwrap());
        assert_eq!(parse_target("[::1]:7000", 1).unwrap(), "[::1]:7000".parse().unwrap());
        assert_eq!(parse_target("::1", 5).unwrap(), "[::1]:5".parse().unwrap());
        assert_eq!(parse_target("localhost:9000", 1).unwrap().port(), 9000);
        let e = parse_target("localhost:99999", 1).unwrap_err().to_string();
        assert_eq!(e, "--target `localhost:99999`: port `99999` is not a number 0-65535");
        assert!(parse_target(":9000", 1).unwrap_err().to_string().contains("no host"));
        assert!(parse_target("", 1).unwrap_err().to_string().contains("empty"));
    }

    #[test]
    fn fixed_bind_port_needs_one_target() {
        let t: Vec<SocketAddr> = vec!["127.0.0.1:9".parse().unwrap(), "127.0.0.1:10".parse().unwrap()];
        let e = Sender::new(&t, Some("127.0.0.1:5555".parse().unwrap())).unwrap_err();
        assert!(matches!(e, SenderError::FixedPortWithSeveralTargets { targets: 2, .. }), "{e}");
        assert!(matches!(Sender::new(&[], None).unwrap_err(), SenderError::NoTarget));
    }
}
