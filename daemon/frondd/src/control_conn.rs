//! The control socket's connections: each gets a thread (at most [`MAX_CONTROL_CLIENTS`]) that
//! reads one request frame at a time, within an idle timeout and a per-request deadline, has
//! the context answer it, and writes one reply frame; a request that cannot be read is refused
//! and the connection closed without losing the refusal.

use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::Arc;
use std::sync::atomic::Ordering::{AcqRel, Acquire, Relaxed};
use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::thread;
use std::time::{Duration, Instant};

/// Largest control request accepted, bytes.
pub use frond_protocol::MAX_CONTROL_REQUEST;
use frond_protocol::{
    ControlErrorKind, ControlRequest, DecodeError, FrameBuf, ReadError, encode_frame_as, read_frame_limited,
    write_frame,
};
use tracing::warn;

use crate::access::{AccessError, peer_cred};
use crate::control_state::{ControlContext, refuse};

/// Most control connections at once.
pub const MAX_CONTROL_CLIENTS: usize = 16;
/// Idle time between two requests after which a control connection is closed.
pub const CONTROL_READ_TIMEOUT: Duration = Duration::from_secs(30);
/// Time a whole request may take to arrive, from its first byte to its last: a client that
/// trickles a request (slow-loris) is answered `BadRequest` and cut off at this deadline, so it
/// holds a connection slot for at most this long past its first byte. A full 256 KiB request
/// over a local socket takes well under a millisecond.
pub const CONTROL_REQUEST_DEADLINE: Duration = Duration::from_secs(5);

/// Accepts control connections until `stop` is set.
pub fn spawn_control(
    listener: UnixListener,
    ctx: Arc<ControlContext>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<thread::JoinHandle<()>> {
    listener.set_nonblocking(true)?;
    thread::Builder::new().name("frond-control".into()).spawn(move || {
        let clients = Arc::new(AtomicUsize::new(0));
        while !stop.load(Relaxed) {
            let stream = match listener.accept() {
                Ok((s, _)) => s,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    // Woken by a connection (at shutdown the daemon makes one), or every
                    // `STOP_POLL` to look at `stop`.
                    crate::clock::wait_readable(
                        std::os::fd::AsFd::as_fd(&listener),
                        crate::publisher::STOP_POLL,
                    );
                    continue;
                }
                Err(e) => {
                    warn!(error = %e, "accepting a control connection failed");
                    thread::sleep(Duration::from_millis(100));
                    continue;
                }
            };
            let Some(slot) = ClientSlot::take(&clients) else {
                let mut stream = stream;
                let _ = write_frame(
                    &mut stream,
                    &mut FrameBuf::default(),
                    &refuse(ControlErrorKind::Internal, "too many control connections; try again"),
                );
                drain_queued(&mut stream);
                continue;
            };
            let ctx = ctx.clone();
            // The slot moves into the thread and is given back when it is dropped: when the
            // connection ends, when the thread unwinds, or here if the thread never starts.
            let spawned = thread::Builder::new().name("frond-control-conn".into()).spawn(move || {
                let _slot = slot;
                serve_connection(stream, &ctx);
            });
            if let Err(e) = spawned {
                warn!(error = %e, "could not start a control connection thread");
            }
        }
    })
}

/// One of the [`MAX_CONTROL_CLIENTS`] connection slots, held by a connection's thread and given
/// back when dropped, however the thread ends (return, panic, or never started).
#[derive(Debug)]
pub struct ClientSlot(Arc<AtomicUsize>);

impl ClientSlot {
    /// A slot of `clients` (the count of slots held), or `None` when all are taken.
    pub fn take(clients: &Arc<AtomicUsize>) -> Option<ClientSlot> {
        clients
            .fetch_update(AcqRel, Acquire, |n| (n < MAX_CONTROL_CLIENTS).then_some(n + 1))
            .ok()
            .map(|_| ClientSlot(clients.clone()))
    }
}

impl Drop for ClientSlot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, AcqRel);
    }
}

/// Reads one request at a time from a control connection with two limits: at most
/// [`CONTROL_READ_TIMEOUT`] idle before a request's first byte, and the whole request within
/// [`CONTROL_REQUEST_DEADLINE`] of that byte (the socket's read timeout is set to what is left
/// before each read, so a client that sends a byte now and then cannot stretch it).
struct RequestReader<'a> {
    stream: &'a UnixStream,
    /// Deadline of the request being read; `None` until its first byte.
    deadline: Option<Instant>,
    /// Set when a read failed because the deadline passed.
    expired: bool,
}

impl RequestReader<'_> {
    /// Ready for the next request (idle timeout again).
    fn next_request(&mut self) {
        self.deadline = None;
        self.expired = false;
    }
}

impl std::io::Read for RequestReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let timeout = match self.deadline {
            None => CONTROL_READ_TIMEOUT,
            Some(deadline) => {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    self.expired = true;
                    return Err(std::io::ErrorKind::TimedOut.into());
                }
                left
            }
        };
        self.stream.set_read_timeout(Some(timeout))?;
        let result = (&mut &*self.stream).read(buf);
        match &result {
            Ok(n) if *n > 0 && self.deadline.is_none() => {
                self.deadline = Some(Instant::now() + CONTROL_REQUEST_DEADLINE);
            }
            Err(e)
                if self.deadline.is_some()
                    && matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                self.expired = true;
            }
            _ => {}
        }
        result
    }
}

/// Reads and drops what a client already sent, without waiting (the stream is non-blocking,
/// as accepted): closing a Unix socket with unread bytes resets it, and the client would lose
/// the reply just written. What arrives later may still reset it; the acceptor must not wait.
fn drain_queued(stream: &mut UnixStream) {
    use std::io::Read;
    let _ = stream.set_nonblocking(true);
    let mut buf = [0u8; 4096];
    let mut drained = 0;
    while drained <= MAX_CONTROL_REQUEST {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => drained += n,
        }
    }
}

/// Closes a connection whose request was refused unread: the reply is written, then what the
/// client still sends is read and dropped (at most a request's worth, for at most a second), so
/// that closing with unread bytes does not reset the connection and lose the reply.
fn close_after_refusal(mut stream: UnixStream) {
    use std::io::Read;
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
    let deadline = Instant::now() + Duration::from_secs(1);
    let mut buf = [0u8; 4096];
    let mut drained = 0;
    while drained <= MAX_CONTROL_REQUEST && Instant::now() < deadline {
        match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => drained += n,
        }
    }
}

fn serve_connection(mut stream: UnixStream, ctx: &ControlContext) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_write_timeout(Some(Duration::from_secs(5)));
    let mut scratch = Vec::new();
    let mut out = FrameBuf::default();
    let allowed = peer_cred(&stream).map_err(AccessError::Credentials);
    if let Err(why) = allowed.and_then(|peer| ctx.access.check(&peer)) {
        let _ =
            write_frame(&mut stream, &mut out, &refuse(ControlErrorKind::PermissionDenied, why.to_string()));
        return;
    }
    let reader_stream = stream.try_clone();
    let Ok(reader_stream) = reader_stream else { return };
    let mut reader = RequestReader { stream: &reader_stream, deadline: None, expired: false };
    loop {
        reader.next_request();
        let reply = match read_frame_limited::<ControlRequest, _>(
            &mut reader,
            &mut scratch,
            MAX_CONTROL_REQUEST,
        ) {
            Ok(req) => ctx.handle_catching(req),
            Err(ReadError::Closed) => return,
            Err(ReadError::Io(_)) if reader.expired => {
                let reply = refuse(
                    ControlErrorKind::BadRequest,
                    format!(
                        "the request did not arrive within {} s of its first byte; closing the connection",
                        CONTROL_REQUEST_DEADLINE.as_secs()
                    ),
                );
                let _ = write_frame(&mut stream, &mut out, &reply);
                return;
            }
            Err(ReadError::Io(e))
                if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
            {
                return;
            }
            Err(ReadError::Decode(DecodeError::UnsupportedVersion { got, supported })) => {
                // An older (or newer) client: answer in its own version, which every frond
                // version can read for an `Error` reply, so it says what is wrong.
                let reply = refuse(
                    ControlErrorKind::BadRequest,
                    format!(
                        "this daemon speaks frond protocol version {supported}, the client version {got}; \
                             use a frond, frondd and exporters of the same release"
                    ),
                );
                let mut bytes = Vec::new();
                encode_frame_as(got, &reply, &mut bytes);
                let _ = std::io::Write::write_all(&mut stream, &bytes);
                close_after_refusal(stream);
                return;
            }
            Err(e) => {
                let reply = refuse(ControlErrorKind::BadRequest, format!("bad control request: {e}"));
                let _ = write_frame(&mut stream, &mut out, &reply);
                close_after_refusal(stream);
                return;
            }
        };
        if write_frame(&mut stream, &mut out, &reply).is_err() {
            return;
        }
    }
}
