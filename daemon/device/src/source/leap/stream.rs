//! The service's socket as the WebSocket client sees it ([`ServiceStream`]): writes that never
//! wait, reads that end when the source stops, and a read budget in bytes and in WebSocket
//! frames ([`FrameScan`] finds where each frame starts).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::fd::AsRawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Bytes sent to the service and not taken by it, past which it counts as not reading (a real
/// service takes every pong at once; a few KiB wait at most).
pub(super) const UNREAD_BACKLOG: usize = 64 << 10;
/// Bytes read from the service per [`READ_WINDOW`] at most (10 MiB/s; a real service sends
/// about 1 MB/s): a service sending faster is read at this pace (TCP slows it down), so that
/// what it sends costs the daemon a bounded share of a core, whatever it is.
pub(super) const READ_BUDGET: usize = 1 << 20;
/// The window of [`READ_BUDGET`].
pub(super) const READ_WINDOW: Duration = Duration::from_millis(100);
/// What each WebSocket frame costs against [`READ_BUDGET`] besides its bytes, so that the work
/// per window is bounded in frames (hence messages) as well as in bytes: at most 1,024 frames
/// per window, 10,240 a second (a real service sends about 110 frames a second, of a few KiB
/// each). Without it, endless 2-byte empty messages or zero-length fragments were read at
/// 10 MiB/s: millions of messages a second, most of a core.
pub(super) const FRAME_COST: usize = 1 << 10;
/// Bytes taken from the socket at once, at most (handed on as the budget allows).
const INBOX_BYTES: usize = 64 << 10;

/// The service's socket as the WebSocket sees it. Writes never wait: `send(MSG_DONTWAIT)`, and
/// the time since the service stopped taking what is written (the socket refuses bytes, or
/// more than [`UNREAD_BACKLOG`] wait unacknowledged) is kept, for the session to drop a service
/// that never reads. Reads wait at most the socket's read timeout,
/// end with `WouldBlock` once `stop` is set (tungstenite reads a message until it is whole, so
/// a service trickling one byte at a time would otherwise keep it reading), and with
/// `TimedOut` past `deadline` (the handshake's). At most [`READ_BUDGET`] is read per
/// [`READ_WINDOW`], each byte costing one and each WebSocket frame [`FRAME_COST`] more (bytes
/// read from the socket are handed on only as far as the budget allows, so that the WebSocket
/// never parses more frames than were paid for): past it, a read waits for the next window and
/// says `WouldBlock`.
pub(super) struct ServiceStream {
    tcp: TcpStream,
    pub(super) stop: Arc<AtomicBool>,
    pub(super) deadline: Option<Instant>,
    blocked_since: Option<Instant>,
    window: (Instant, usize),
    pub(super) throttled: bool,
    /// When the budget was last found spent.
    pub(super) spent_at: Option<Instant>,
    /// Bytes read from the socket and not yet handed on: `inbox[at..]`.
    inbox: Vec<u8>,
    at: usize,
    frames: FrameScan,
}

/// Follows the service's byte stream just far enough to see where each WebSocket frame starts:
/// the HTTP response head (up to its blank line), then frame headers (RFC 6455 §5.2) and the
/// payload lengths they give.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FrameScan {
    /// In the handshake's response head; how many bytes of `\r\n\r\n` were just seen.
    Head(u8),
    /// In a frame header: its bytes so far (`have` of at most 14).
    Header { bytes: [u8; 14], have: usize },
    /// In a payload: bytes left.
    Payload(u64),
}

impl FrameScan {
    /// Takes one byte; `true` when it starts a frame.
    fn step(&mut self, b: u8) -> bool {
        match self {
            FrameScan::Head(seen) => {
                let want = b"\r\n\r\n"[usize::from(*seen)];
                *seen = if b == want { *seen + 1 } else { u8::from(b == b'\r') };
                if *seen == 4 {
                    *self = FrameScan::Header { bytes: [0; 14], have: 0 };
                }
                false
            }
            FrameScan::Payload(left) => {
                *left -= 1;
                if *left == 0 {
                    *self = FrameScan::Header { bytes: [0; 14], have: 0 };
                }
                false
            }
            FrameScan::Header { bytes, have } => {
                let starts = *have == 0;
                bytes[*have] = b;
                *have += 1;
                if *have >= 2 {
                    let len7 = bytes[1] & 0x7f;
                    let ext = match len7 {
                        126 => 2,
                        127 => 8,
                        _ => 0,
                    };
                    let mask = if bytes[1] & 0x80 != 0 { 4 } else { 0 };
                    if *have == 2 + ext + mask {
                        let len = match ext {
                            0 => u64::from(len7),
                            n => bytes[2..2 + n].iter().fold(0u64, |l, &b| (l << 8) | u64::from(b)),
                        };
                        *self = if len == 0 {
                            FrameScan::Header { bytes: [0; 14], have: 0 }
                        } else {
                            FrameScan::Payload(len)
                        };
                    }
                }
                starts
            }
        }
    }

    /// Payload bytes that can be skipped at once (no frame starts among them).
    fn skippable(&self) -> u64 {
        match self {
            FrameScan::Payload(left) => left - 1,
            _ => 0,
        }
    }
}

impl ServiceStream {
    pub(super) fn new(tcp: TcpStream, stop: Arc<AtomicBool>, deadline: Instant) -> Self {
        ServiceStream {
            tcp,
            stop,
            deadline: Some(deadline),
            blocked_since: None,
            window: (Instant::now(), 0),
            throttled: false,
            spent_at: None,
            inbox: Vec::with_capacity(INBOX_BYTES),
            at: 0,
            frames: FrameScan::Head(0),
        }
    }
}

impl ServiceStream {
    /// How long the service has left written bytes unread, if it has.
    pub(super) fn blocked_for(&self) -> Option<Duration> {
        self.blocked_since.map(|t| t.elapsed())
    }
}

impl Read for ServiceStream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.stop.load(Ordering::Acquire) {
            return Err(std::io::Error::new(std::io::ErrorKind::WouldBlock, "the source is stopping"));
        }
        let now = Instant::now();
        if self.deadline.is_some_and(|d| now >= d) {
            return Err(std::io::Error::new(std::io::ErrorKind::TimedOut, "the handshake took too long"));
        }
        let (started, read) = &mut self.window;
        if now.duration_since(*started) >= READ_WINDOW {
            (*started, *read) = (now, 0);
        }
        if *read >= READ_BUDGET {
            self.throttled = true;
            self.spent_at = Some(now);
            std::thread::sleep((*started + READ_WINDOW).saturating_duration_since(now));
            return Err(std::io::Error::new(std::io::ErrorKind::WouldBlock, "read budget spent"));
        }
        if self.at == self.inbox.len() {
            let room = (READ_BUDGET - *read).min(INBOX_BYTES);
            self.inbox.resize(room, 0);
            self.at = 0;
            let got = self.tcp.read(&mut self.inbox);
            self.inbox.truncate(*got.as_ref().unwrap_or(&0));
            if got? == 0 {
                return Ok(0);
            }
        }
        // Hand on what the budget pays for: every byte, and each frame that starts.
        let offer = (self.inbox.len() - self.at).min(buf.len());
        let mut n = 0;
        while n < offer {
            let skip = self.frames.skippable().min((offer - n - 1) as u64) as usize;
            if skip > 0 {
                // Payload: `step` below takes the byte after these.
                let FrameScan::Payload(left) = &mut self.frames else { unreachable!() };
                *left -= skip as u64;
                (*read, n) = (*read + skip, n + skip);
            }
            if self.frames.step(self.inbox[self.at + n]) {
                if *read >= READ_BUDGET {
                    // Undo: this frame is paid for in the next window.
                    self.frames = FrameScan::Header { bytes: [0; 14], have: 0 };
                    self.throttled = true;
                    self.spent_at = Some(now);
                    break;
                }
                *read += FRAME_COST;
            }
            (*read, n) = (*read + 1, n + 1);
        }
        buf[..n].copy_from_slice(&self.inbox[self.at..self.at + n]);
        self.at += n;
        if n == 0 {
            return Err(std::io::Error::new(std::io::ErrorKind::WouldBlock, "read budget spent"));
        }
        Ok(n)
    }
}

impl Write for ServiceStream {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        // SAFETY: a connected socket we own; `buf` is valid for `buf.len()` bytes to read.
        let n = unsafe {
            libc::send(
                self.tcp.as_raw_fd(),
                buf.as_ptr().cast(),
                buf.len(),
                libc::MSG_DONTWAIT | libc::MSG_NOSIGNAL,
            )
        };
        let result = if n < 0 { Err(std::io::Error::last_os_error()) } else { Ok(n as usize) };
        // Unread: the socket refused the bytes, or more than UNREAD_BACKLOG of what was sent
        // is still waiting for the service to take it (a service that reads a trickle, or
        // whose kernel makes room now and then, still leaves that much behind).
        let refused = matches!(&result, Err(e) if e.kind() == std::io::ErrorKind::WouldBlock);
        let mut queued: libc::c_int = 0;
        // SAFETY: TIOCOUTQ (SIOCOUTQ) writes one c_int, the bytes sent but not yet acknowledged.
        let known = unsafe { libc::ioctl(self.tcp.as_raw_fd(), libc::TIOCOUTQ, &mut queued) } == 0;
        if refused || (known && queued as usize >= UNREAD_BACKLOG) {
            self.blocked_since.get_or_insert_with(Instant::now);
        } else {
            self.blocked_since = None;
        }
        result
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leap_frame_scan_finds_each_frame_start() {
        let mut scan = FrameScan::Head(0);
        let mut stream = b"HTTP/1.1 101 Switching\r\nA: b\r\r\n\r\n".to_vec();
        // Empty; 3 bytes; 126 (16-bit length 300); masked 1 byte; 127 (64-bit length 2).
        stream.extend([0x81, 0x00]);
        stream.extend([0x81, 0x03, 1, 2, 3]);
        stream.extend([0x82, 126, 0x01, 0x2c]);
        stream.extend([0u8; 300]);
        stream.extend([0x81, 0x81, 9, 9, 9, 9, 7]);
        stream.extend([0x81, 127, 0, 0, 0, 0, 0, 0, 0, 2, 5, 6]);
        stream.extend([0x89, 0x00]);
        let starts: Vec<usize> =
            stream.iter().enumerate().filter(|&(_, &b)| scan.step(b)).map(|(i, _)| i).collect();
        let head = 33;
        assert_eq!(starts, [head, head + 2, head + 7, head + 311, head + 318, head + 330]);
    }
}
