//! The UDP side, kept apart from the pure parts: a non-blocking socket that receives one
//! datagram at a time into a bounded buffer and sends (broadcasts) encoded messages.

use std::io;
use std::net::{SocketAddr, UdpSocket};

use crate::message::MAX_DATAGRAM_BYTES;

/// A bound trigger socket, non-blocking, broadcast allowed.
#[derive(Debug)]
pub struct TriggerSocket {
    socket: UdpSocket,
    /// One byte more than any accepted datagram, so that a longer one shows as oversized.
    buf: Box<[u8]>,
}

/// One datagram received.
#[derive(Debug)]
pub struct Received<'a> {
    /// Its sender.
    pub from: SocketAddr,
    /// Its bytes; longer than [`MAX_DATAGRAM_BYTES`] when the datagram was (then cut).
    pub bytes: &'a [u8],
}

impl TriggerSocket {
    /// Binds `addr` (e.g. `0.0.0.0:30` to hear Vicon's broadcasts), non-blocking, with
    /// broadcast sends allowed.
    pub fn bind(addr: SocketAddr) -> io::Result<TriggerSocket> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        socket.set_broadcast(true)?;
        Ok(TriggerSocket { socket, buf: vec![0; MAX_DATAGRAM_BYTES + 1].into_boxed_slice() })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The next waiting datagram, or `None` when there is none (never blocks). The caller
    /// bounds how many it reads per wake-up, so a flood cannot hold its thread.
    pub fn recv(&mut self) -> io::Result<Option<Received<'_>>> {
        match self.socket.recv_from(&mut self.buf) {
            Ok((n, from)) => Ok(Some(Received { from, bytes: &self.buf[..n] })),
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Sends one encoded message to `to` (a broadcast address, or one host).
    pub fn send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        self.socket.send_to(bytes, to)
    }

    /// The socket, to poll it for readiness.
    pub fn socket(&self) -> &UdpSocket {
        &self.socket
    }
}
