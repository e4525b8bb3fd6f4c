//! Leap Motion / Ultraleap hand tracking as a hand source: `leap://HOST:PORT[?hand=left|right]`.
//!
//! A helper thread is a WebSocket client of the tracking service (protocol v6 on `/v6.json`,
//! `frond_motion::leap` parses and maps it): it asks for frames in the background (`{"background":
//! true}`, `{"focused": true}`), turns each frame's chosen hand into a [`DeviceSample`] and queues
//! it for the realtime loop, ringing a [`Doorbell`] (the source's ready descriptor). When the
//! service is down or restarts, the thread reconnects (every half second at first, backing off to
//! 2 s) while the loop sees no samples: poses are flagged held, then device-lost, as for any
//! stalled device; a hand out of view does the same. The loop's side never blocks or allocates.
//!
//! The service is a peer, not a friend (issue 42): nothing it does can hold the daemon.
//! - Writes never wait ([`ServiceStream`]: `MSG_DONTWAIT`, a bounded write buffer). Pongs that
//!   it does not read for [`PEER_WRITE_DEADLINE`] drop the connection (counted as
//!   `peers_dropped`); reads wait at most [`READ_POLL`] and end as soon as the source is asked
//!   to stop, even in the middle of a message trickled byte by byte.
//! - Dropping the source waits at most [`STOP_WAIT`] for the thread (a name lookup of the
//!   service's host cannot be interrupted); a thread still busy then is left to end by itself.
//! - A message longer than [`MAX_MESSAGE_BYTES`] is refused from its header (tungstenite's
//!   limit; counted as `oversized`, the connection is dropped), a frame listing more than
//!   `MAX_HANDS` hands at the first one too many (`too_many`), before the rest is parsed.
//! - Reads are paced ([`READ_BUDGET`] per [`READ_WINDOW`]) in bytes and in frames: each
//!   WebSocket frame costs [`FRAME_COST`] besides its bytes, so endless empty messages or
//!   zero-length fragments cost a bounded share of a core; a service that keeps the budget spent
//!   for [`JUNK_DEADLINE`] without a message frond can use is dropped (`peers_dropped`).
//! - Connection warnings are rate-limited ([`crate::log_limit`]); refused messages are only
//!   counted here, and the daemon says their counts by reason at a bounded rate.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::os::fd::{AsRawFd, RawFd};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender, TrySendError};
use frond_motion::leap::{Chirality, LeapError, LeapMessage, MAX_MESSAGE_BYTES, hand_sample, parse_message};

use super::{HandSource, SourceError, SourceKind};
use crate::doorbell::Doorbell;
use crate::log_limit::LogLimit;
use crate::report::{DeviceSample, SourceCounters};

/// Samples queued for the loop at most (a second at the service's ~110 Hz, four times over).
const QUEUE_LEN: usize = 512;
/// Longest WebSocket handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(2);
/// How long a read waits before the thread checks whether it should stop.
const READ_POLL: Duration = Duration::from_millis(200);
/// First and longest wait between connection attempts.
const RETRY: (Duration, Duration) = (Duration::from_millis(500), Duration::from_secs(2));
/// How long the service may leave what frond wrote (pongs, its requests) unread before the
/// connection is dropped.
const PEER_WRITE_DEADLINE: Duration = Duration::from_secs(2);
/// Bytes sent to the service and not taken by it, past which it counts as not reading (a real
/// service takes every pong at once; a few KiB wait at most).
const UNREAD_BACKLOG: usize = 64 << 10;
/// Bytes frond keeps queued for the service at most (a pong waiting behind them is replaced by
/// the next, never queued).
const MAX_WRITE_BUFFER: usize = 64 << 10;
/// Bytes read from the service per [`READ_WINDOW`] at most (10 MiB/s; a real service sends
/// about 1 MB/s): a service sending faster is read at this pace (TCP slows it down), so that
/// what it sends costs the daemon a bounded share of a core, whatever it is.
const READ_BUDGET: usize = 1 << 20;
/// The window of [`READ_BUDGET`].
const READ_WINDOW: Duration = Duration::from_millis(100);
/// What each WebSocket frame costs against [`READ_BUDGET`] besides its bytes, so that the work
/// per window is bounded in frames (hence messages) as well as in bytes: at most 1,024 frames
/// per window, 10,240 a second (a real service sends about 110 frames a second, of a few KiB
/// each). Without it, endless 2-byte empty messages or zero-length fragments were read at
/// 10 MiB/s: millions of messages a second, most of a core.
const FRAME_COST: usize = 1 << 10;
/// A service that keeps frond's read budget spent this long without one message frond can use
/// (everything it sends is refused, or never ends) is dropped, as one that does not read.
const JUNK_DEADLINE: Duration = Duration::from_secs(2);
/// Bytes taken from the socket at once, at most (handed on as the budget allows).
const INBOX_BYTES: usize = 64 << 10;
/// How long dropping the source waits for its thread.
const STOP_WAIT: Duration = Duration::from_millis(500);
/// A session shorter than this does not reset the wait between connection attempts: a service
/// that takes each connection and drops it at once is retried at the slow pace.
const STEADY: Duration = Duration::from_secs(5);

/// "Connection ended" and "dropped the service" lines, for every Leap source: a service that
/// drops connections as fast as it takes them fills no log.
static CONNECTION_LINES: LogLimit = LogLimit::new();

/// Logs a warning about the connection to `service`, at a bounded rate.
fn warn_connection(service: &str, what: &str, why: &str) {
    let verdict = CONNECTION_LINES.check(Instant::now());
    if verdict.held_back_before > 0 {
        tracing::warn!(
            held_back = verdict.held_back_before,
            "{} more Leap Motion connection warnings were held back in the last {} s",
            verdict.held_back_before,
            crate::log_limit::WINDOW.as_secs()
        );
    }
    if verdict.log {
        tracing::warn!(%service, reason = %crate::log_limit::cut(why), "{what}");
    }
}

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
struct ServiceStream {
    tcp: TcpStream,
    stop: Arc<AtomicBool>,
    deadline: Option<Instant>,
    blocked_since: Option<Instant>,
    window: (Instant, usize),
    throttled: bool,
    /// When the budget was last found spent.
    spent_at: Option<Instant>,
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
    fn new(tcp: TcpStream, stop: Arc<AtomicBool>, deadline: Instant) -> Self {
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
    fn blocked_for(&self) -> Option<Duration> {
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

/// `leap://HOST:PORT[?hand=left|right]` parsed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LeapAddress {
    /// `HOST:PORT` of the tracking service.
    pub host_port: String,
    /// The hand that drives the plant (default right).
    pub hand: Chirality,
}

impl std::str::FromStr for LeapAddress {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let rest = s.strip_prefix("leap://").ok_or_else(|| format!("{s:?}: expected leap://HOST:PORT"))?;
        let (host_port, query) = rest.split_once('?').unwrap_or((rest, ""));
        let hand = match query {
            "" | "hand=right" => Chirality::Right,
            "hand=left" => Chirality::Left,
            other => {
                return Err(format!("{s:?}: unknown option {other:?} (expected hand=left or hand=right)"));
            }
        };
        let port_ok =
            host_port.rsplit_once(':').is_some_and(|(h, p)| !h.is_empty() && p.parse::<u16>().is_ok());
        if !port_ok {
            return Err(format!("{s:?}: expected leap://HOST:PORT, e.g. leap://127.0.0.1:6437"));
        }
        Ok(LeapAddress { host_port: host_port.to_string(), hand })
    }
}

/// Hand samples from the tracking service's WebSocket.
pub struct LeapSource {
    rx: Receiver<DeviceSample>,
    bell: Arc<Doorbell>,
    counters: Arc<SourceCounters>,
    overflow: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    describe: String,
}

impl LeapSource {
    /// Starts the client thread for `address` (it connects, and reconnects, on its own).
    pub fn connect(address: &LeapAddress) -> Result<LeapSource, SourceError> {
        let what = format!("leap://{}", address.host_port);
        let open = |reason: String| SourceError::Open { what: what.clone(), reason };
        let bell = Arc::new(Doorbell::new().map_err(|e| open(format!("eventfd: {e}")))?);
        let (tx, rx) = crossbeam_channel::bounded(QUEUE_LEN);
        let counters = Arc::new(SourceCounters::default());
        let overflow = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let client = Client {
            host_port: address.host_port.clone(),
            hand: address.hand,
            tx,
            bell: Arc::clone(&bell),
            counters: Arc::clone(&counters),
            overflow: Arc::clone(&overflow),
            stop: Arc::clone(&stop),
        };
        let thread = std::thread::Builder::new()
            .name("frond-leap".into())
            .spawn(move || client.run())
            .map_err(|e| open(format!("cannot start the client thread: {e}")))?;
        Ok(LeapSource {
            rx,
            bell,
            counters,
            overflow,
            stop,
            thread: Some(thread),
            describe: format!(
                "Leap Motion service at ws://{}/v6.json, {} hand",
                address.host_port,
                address.hand.as_str()
            ),
        })
    }

    /// Samples lost because the loop did not keep up (queue full).
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }
}

impl HandSource for LeapSource {
    fn kind(&self) -> SourceKind {
        SourceKind::Leap
    }

    fn describe(&self) -> &str {
        &self.describe
    }

    fn ready_fd(&self) -> Option<RawFd> {
        Some(self.bell.fd())
    }

    fn read_pending(&mut self, out: &mut [DeviceSample]) -> Result<usize, SourceError> {
        // Drain first: a sample queued after this rings again.
        self.bell.drain();
        let mut n = 0;
        while n < out.len() {
            let Ok(s) = self.rx.try_recv() else { break };
            out[n] = s;
            n += 1;
        }
        Ok(n)
    }

    fn counters(&self) -> Arc<SourceCounters> {
        Arc::clone(&self.counters)
    }

    fn reopen(&mut self) -> Result<(), SourceError> {
        // The client thread reconnects by itself; nothing to reopen here.
        Ok(())
    }
}

impl Drop for LeapSource {
    /// Stops the client thread and waits for it at most `STOP_WAIT` (500 ms): its reads and
    /// writes end within `READ_POLL` (200 ms) of the stop; only a name lookup or a connection attempt (at most
    /// 1 s) can outlast the wait, and then the thread is left to end by itself (at the
    /// process's exit, if that comes first).
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        let Some(t) = self.thread.take() else { return };
        let deadline = Instant::now() + STOP_WAIT;
        while !t.is_finished() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        if t.is_finished() {
            let _ = t.join();
        } else {
            tracing::warn!(source = %self.describe, "the Leap Motion client thread did not stop within {} ms; leaving it", STOP_WAIT.as_millis());
        }
    }
}

struct Client {
    host_port: String,
    hand: Chirality,
    tx: Sender<DeviceSample>,
    bell: Arc<Doorbell>,
    counters: Arc<SourceCounters>,
    overflow: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
}

impl Client {
    fn run(self) {
        let mut wait = RETRY.0;
        let mut said_down = false;
        while !self.stop.load(Ordering::Acquire) {
            let started = Instant::now();
            match self.session() {
                Ok(()) => return, // asked to stop
                Err((was_connected, why)) => {
                    if was_connected {
                        // A fresh outage (the session said it): retry soon, unless the
                        // connection was short-lived (a service that drops every connection).
                        said_down = false;
                        if started.elapsed() >= STEADY {
                            wait = RETRY.0;
                        }
                    } else if !said_down {
                        // Said once per outage, not once per attempt.
                        tracing::warn!(service = %self.host_port, reason = %why, "Leap Motion service unreachable; retrying");
                        said_down = true;
                    }
                }
            }
            let mut slept = Duration::ZERO;
            while slept < wait && !self.stop.load(Ordering::Acquire) {
                std::thread::sleep(Duration::from_millis(50));
                slept += Duration::from_millis(50);
            }
            wait = (wait * 2).min(RETRY.1);
        }
    }

    fn address(&self) -> Result<SocketAddr, String> {
        self.host_port
            .to_socket_addrs()
            .map_err(|e| format!("cannot resolve {}: {e}", self.host_port))?
            .next()
            .ok_or_else(|| format!("{} resolves to no address", self.host_port))
    }

    /// One connection: handshake, then frames until the service goes or we are asked to stop.
    /// Ends with whether it got connected, and why not or why it ended.
    fn session(&self) -> Result<(), (bool, String)> {
        let not = |e: String| (false, e);
        let addr = self.address().map_err(not)?;
        let tcp =
            TcpStream::connect_timeout(&addr, Duration::from_secs(1)).map_err(|e| not(e.to_string()))?;
        tcp.set_nodelay(true).ok();
        // Every read waits at most READ_POLL, so that a stop is seen; the handshake as a whole
        // at most HANDSHAKE_TIMEOUT.
        tcp.set_read_timeout(Some(READ_POLL)).map_err(|e| not(e.to_string()))?;
        let stream = ServiceStream::new(tcp, Arc::clone(&self.stop), Instant::now() + HANDSHAKE_TIMEOUT);
        let url = format!("ws://{}/v6.json", self.host_port);
        let mut config = tungstenite::protocol::WebSocketConfig::default();
        config.max_message_size = Some(MAX_MESSAGE_BYTES);
        config.max_frame_size = Some(MAX_MESSAGE_BYTES);
        // Written at once (nothing is held back to batch), and never more than this queued.
        config.write_buffer_size = 0;
        config.max_write_buffer_size = MAX_WRITE_BUFFER;
        let (mut ws, _) = handshake(url.as_str(), stream, config)
            .map_err(|e| not(format!("WebSocket handshake with {url}: {e}")))?;
        ws.get_mut().deadline = None;
        for ask in [r#"{"background":true}"#, r#"{"focused":true}"#] {
            match ws.send(tungstenite::Message::text(ask)) {
                Ok(()) => {}
                // Queued: written with the next read's flush.
                Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(not(e.to_string())),
            }
        }
        tracing::info!(service = %url, "connected to the Leap Motion service");
        let (mut warned_version, mut warned_pace) = (false, false);
        // When the service last sent a message frond could use (one it did not refuse).
        let mut last_useful = Instant::now();
        loop {
            if self.stop.load(Ordering::Acquire) {
                let _ = ws.close(None);
                return Ok(());
            }
            if ws.get_ref().throttled && !warned_pace {
                let per_s = 1.0 / READ_WINDOW.as_secs_f64();
                let mib_per_s = READ_BUDGET as f64 * per_s / f64::from(1 << 20);
                let frames_per_s = (READ_BUDGET / FRAME_COST) as f64 * per_s;
                let why = format!(
                    "it sends more than {mib_per_s:.0} MiB/s or {frames_per_s:.0} WebSocket frames/s"
                );
                warn_connection(&url, "reading the Leap Motion service at frond's pace", &why);
                warned_pace = true;
            }
            if ws.get_ref().blocked_for().is_some_and(|d| d >= PEER_WRITE_DEADLINE) {
                self.counters.peers_dropped.fetch_add(1, Ordering::Relaxed);
                let why = format!("it read nothing frond wrote for {} s", PEER_WRITE_DEADLINE.as_secs());
                warn_connection(&url, "dropped the Leap Motion service's connection; reconnecting", &why);
                return Err((true, why));
            }
            let spent_lately = ws.get_ref().spent_at.is_some_and(|t| t.elapsed() <= 2 * READ_WINDOW);
            if spent_lately && last_useful.elapsed() >= JUNK_DEADLINE {
                self.counters.peers_dropped.fetch_add(1, Ordering::Relaxed);
                let why = format!(
                    "it kept frond's read budget spent for {} s without a message frond could use",
                    JUNK_DEADLINE.as_secs()
                );
                warn_connection(&url, "dropped the Leap Motion service's connection; reconnecting", &why);
                return Err((true, why));
            }
            let msg = match ws.read() {
                Ok(m) => m,
                Err(tungstenite::Error::Io(e))
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
                {
                    continue;
                }
                Err(e) => {
                    if matches!(e, tungstenite::Error::Capacity(_)) {
                        // Longer than MAX_MESSAGE_BYTES, refused from its header: the rest of
                        // it cannot be skipped, so the connection ends with it.
                        self.counters.oversized.fetch_add(1, Ordering::Relaxed);
                    }
                    let why = e.to_string();
                    warn_connection(&url, "Leap Motion service connection ended; reconnecting", &why);
                    return Err((true, why));
                }
            };
            let text = match &msg {
                tungstenite::Message::Text(t) => t.as_str(),
                tungstenite::Message::Close(_) => {
                    let why = "the service closed the connection";
                    warn_connection(&url, "the Leap Motion service closed the connection; reconnecting", why);
                    return Err((true, why.into()));
                }
                tungstenite::Message::Binary(_) => {
                    // v6 is text only.
                    self.counters.malformed.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                _ => continue,
            };
            let parsed = parse_message(text);
            if parsed.is_ok() {
                last_useful = Instant::now();
            }
            match parsed {
                Ok(LeapMessage::Version(6)) | Ok(LeapMessage::Other) => {}
                Ok(LeapMessage::Version(v)) => {
                    if !warned_version {
                        tracing::warn!(service = %url, version = v, "the service speaks protocol {v}, not 6; reading its frames anyway");
                        warned_version = true;
                    }
                }
                Ok(LeapMessage::Frame(frame)) => match hand_sample(&frame, self.hand) {
                    Ok(Some(raw)) => self.push(frame.id, frame.timestamp, raw),
                    Ok(None) => {} // the hand is not in view: no sample, the loop holds
                    Err(LeapError::BadVector(_)) => {
                        self.counters.out_of_range.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(_) => {
                        self.counters.malformed.fetch_add(1, Ordering::Relaxed);
                    }
                },
                Err(LeapError::TooMany { .. }) => {
                    self.counters.too_many.fetch_add(1, Ordering::Relaxed);
                }
                Err(LeapError::TooLarge(_)) => {
                    self.counters.oversized.fetch_add(1, Ordering::Relaxed);
                }
                Err(_) => {
                    self.counters.malformed.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    fn push(&self, id: i64, timestamp_us: i64, raw: frond_motion::HandSample) {
        if raw.check_plausible().is_err() {
            self.counters.out_of_range.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let sample = DeviceSample {
            device_seq: id as u32,
            device_time_us: timestamp_us.max(0) as u64,
            raw,
            flex_deg: [0.0; 4],
            status: 1,
        };
        match self.tx.try_send(sample) {
            Ok(()) => {
                self.counters.reports.fetch_add(1, Ordering::Relaxed);
                self.bell.ring();
            }
            Err(TrySendError::Full(_)) => {
                self.overflow.fetch_add(1, Ordering::Relaxed);
            }
            Err(TrySendError::Disconnected(_)) => {}
        }
    }
}

/// The client's WebSocket handshake over `stream`: each read waits at most [`READ_POLL`], the
/// whole at most until the stream's deadline, and it ends when the source is asked to stop.
fn handshake(
    url: &str,
    stream: ServiceStream,
    config: tungstenite::protocol::WebSocketConfig,
) -> Result<(tungstenite::WebSocket<ServiceStream>, tungstenite::handshake::client::Response), String> {
    let stop = Arc::clone(&stream.stop);
    let mut attempt = tungstenite::client::client_with_config(url, stream, Some(config));
    loop {
        match attempt {
            Ok(done) => return Ok(done),
            Err(tungstenite::HandshakeError::Failure(e)) => return Err(e.to_string()),
            Err(tungstenite::HandshakeError::Interrupted(_)) if stop.load(Ordering::Acquire) => {
                return Err("the source is stopping".into());
            }
            // A read waited READ_POLL: carry on (the stream's deadline ends it with TimedOut).
            Err(tungstenite::HandshakeError::Interrupted(mid)) => attempt = mid.handshake(),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write as _;

    use super::*;

    #[test]
    fn addresses_parse_with_the_hand() {
        let a: LeapAddress = "leap://127.0.0.1:6437".parse().unwrap();
        assert_eq!((a.host_port.as_str(), a.hand), ("127.0.0.1:6437", Chirality::Right));
        let a: LeapAddress = "leap://localhost:6437?hand=left".parse().unwrap();
        assert_eq!(a.hand, Chirality::Left);
        for bad in
            ["leap://", "leap://host", "leap://:1", "leap://h:99999", "leap://h:1?hand=both", "osc://h:1"]
        {
            assert!(bad.parse::<LeapAddress>().is_err(), "{bad}");
        }
    }

    /// A fake service on a fresh port: after the handshake and the greeting, each connection
    /// is handed to `then` (on its own thread). Returns the port and the connections taken.
    fn service(
        then: impl Fn(tungstenite::WebSocket<TcpStream>) + Send + Sync + 'static,
    ) -> (u16, Arc<AtomicU64>) {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let small: libc::c_int = 4096;
        // SAFETY: a listening socket we own and a c_int option of the right size (accepted
        // sockets inherit it): the service's receive buffer fills at once.
        unsafe {
            libc::setsockopt(
                listener.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_RCVBUF,
                (&small as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            );
        }
        let port = listener.local_addr().unwrap().port();
        let taken = Arc::new(AtomicU64::new(0));
        let (then, count) = (Arc::new(then), Arc::clone(&taken));
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(stream) = stream else { return };
                count.fetch_add(1, Ordering::Relaxed);
                let then = Arc::clone(&then);
                std::thread::spawn(move || {
                    let Ok(mut ws) = tungstenite::accept(stream) else { return };
                    let _ = ws.send(tungstenite::Message::text(r#"{"version": 6}"#));
                    then(ws);
                });
            }
        });
        (port, taken)
    }

    fn connect(port: u16) -> LeapSource {
        LeapSource::connect(&format!("leap://127.0.0.1:{port}").parse().unwrap()).unwrap()
    }

    /// Drops `source` on another thread; how long that took, or `None` past `bound`.
    fn drop_within(source: LeapSource, bound: Duration) -> Option<Duration> {
        let (tx, rx) = crossbeam_channel::bounded(1);
        std::thread::spawn(move || {
            let t0 = Instant::now();
            drop(source);
            let _ = tx.send(t0.elapsed());
        });
        rx.recv_timeout(bound).ok()
    }

    fn wait_until(bound: Duration, mut cond: impl FnMut() -> bool) -> bool {
        let deadline = Instant::now() + bound;
        while !cond() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        cond()
    }

    /// Raw unmasked pings as fast as the socket takes them; nothing is ever read.
    fn flood_pings(mut ws: tungstenite::WebSocket<TcpStream>) {
        let ping: Vec<u8> = [0x89u8, 125].into_iter().chain(std::iter::repeat_n(b'p', 125)).collect();
        let burst = ping.repeat(512);
        let tcp = ws.get_mut();
        tcp.set_write_timeout(Some(Duration::from_millis(50))).unwrap();
        // Where the next write starts: a short write must not cut a ping in two.
        let mut at = 0;
        loop {
            match tcp.write(&burst[at..]) {
                Ok(n) => at = (at + n) % burst.len(),
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                Err(_) => return, // dropped by the client
            }
        }
    }

    /// Issue 42: a service that floods pings and never reads fills the socket with the pongs
    /// it owes; the client's writes never wait, so it is dropped (counted) after
    /// PEER_WRITE_DEADLINE and connected to again, and stopping the source takes no longer
    /// than a read poll. (The old client blocked in the pong write, for ever: stopping the
    /// source joined it.)
    #[test]
    fn a_service_that_floods_pings_and_never_reads_is_dropped_and_cannot_hold_a_stop() {
        let (port, taken) = service(flood_pings);
        let source = connect(port);
        let counters = source.counters();
        assert!(
            wait_until(Duration::from_secs(20), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
            "never dropped: {:?}",
            counters.snapshot()
        );
        assert!(
            wait_until(Duration::from_secs(10), || taken.load(Ordering::Relaxed) >= 2),
            "not reconnected"
        );
        // Flooded again: stop now, in the middle of it.
        std::thread::sleep(Duration::from_millis(500));
        let took = drop_within(source, Duration::from_secs(5)).expect("the source did not stop");
        assert!(took <= STOP_WAIT + Duration::from_millis(500), "stopping took {took:?}");
    }

    /// Issue 42: a service trickling one message a byte at a time (each byte before the read
    /// poll runs out) cannot keep the client reading past a stop.
    #[test]
    fn a_service_trickling_a_message_cannot_hold_a_stop() {
        let (port, taken) = service(|mut ws| {
            // A text frame of 120 bytes, sent one byte every 50 ms (6 s in all).
            let mut frame = vec![0x81u8, 120];
            frame.extend(std::iter::repeat_n(b' ', 120));
            for b in frame {
                if ws.get_mut().write_all(&[b]).is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        let source = connect(port);
        assert!(wait_until(Duration::from_secs(5), || taken.load(Ordering::Relaxed) >= 1));
        std::thread::sleep(Duration::from_millis(500));
        let took = drop_within(source, Duration::from_secs(4)).expect("the source did not stop");
        assert!(took <= STOP_WAIT + Duration::from_millis(500), "stopping took {took:?}");
    }

    /// Issue 42: a message longer than MAX_MESSAGE_BYTES is refused from its header (the
    /// connection with it), counted as oversized; a frame of 5,000 hands as too_many; and a
    /// good frame after them still gives a sample.
    #[test]
    fn oversized_messages_and_frames_of_too_many_hands_are_counted_by_reason() {
        let hand = r#"{"id":1,"type":"left","direction":[0,0,-1],"palmNormal":[0,-1,0]}"#;
        let many = format!(r#"{{"id":1,"timestamp":0,"hands":[{}]}}"#, vec![hand; 5000].join(","));
        let sent = Arc::new(AtomicU64::new(0));
        let turn = Arc::clone(&sent);
        let (port, _) = service(move |mut ws| {
            let good = r#"{"id":2,"timestamp":5,"hands":[{"id":7,"type":"right","direction":[0,0,-1],"palmNormal":[0,-1,0]}],"pointables":[{"handId":7,"type":0,"bases":[[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]],[[1,0,0],[0,1,0],[0,0,1]]]}]}"#;
            if turn.fetch_add(1, Ordering::Relaxed) == 0 {
                let _ = ws.send(tungstenite::Message::text(many.clone()));
                let _ = ws.send(tungstenite::Message::text("x".repeat(MAX_MESSAGE_BYTES + 1)));
                std::thread::sleep(Duration::from_secs(10));
            } else {
                let _ = ws.send(tungstenite::Message::text(good));
                std::thread::sleep(Duration::from_secs(10));
            }
        });
        let mut source = connect(port);
        let counters = source.counters();
        let mut out = [DeviceSample::default(); 4];
        let mut got = 0;
        let deadline = Instant::now() + Duration::from_secs(10);
        while got == 0 && Instant::now() < deadline {
            got += source.read_pending(&mut out).unwrap();
            std::thread::sleep(Duration::from_millis(20));
        }
        let c = counters.snapshot();
        assert_eq!((got, c.too_many, c.oversized, c.malformed), (1, 1, 1, 0), "{c:?}");
        assert_eq!(c.rejected(), 2);
    }

    /// Issue 42: a service sending as fast as it can (large messages of nothing frond uses) is
    /// read at frond's pace, 10 MiB/s, not at its own: what it sends in 2 s, with every socket
    /// buffer full, stays far below what loopback carries (the old client read and parsed all
    /// of it, hundreds of MiB a second, as fast as a core could).
    #[test]
    fn a_service_sending_as_fast_as_it_can_is_read_at_a_bounded_pace() {
        let written = Arc::new(AtomicU64::new(0));
        let total = Arc::clone(&written);
        let (port, _) = service(move |mut ws| {
            let body = format!(r#"{{"pad":"{}"}}"#, "x".repeat(500_000));
            let mut frame = vec![0x81u8, 127];
            frame.extend_from_slice(&(body.len() as u64).to_be_bytes());
            frame.extend_from_slice(body.as_bytes());
            let tcp = ws.get_mut();
            tcp.set_write_timeout(Some(Duration::from_millis(100))).unwrap();
            let t0 = Instant::now();
            let mut at = 0;
            while t0.elapsed() < Duration::from_secs(2) {
                match tcp.write(&frame[at..]) {
                    Ok(n) => {
                        total.fetch_add(n as u64, Ordering::Relaxed);
                        at = (at + n) % frame.len();
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) => {}
                    Err(_) => return,
                }
            }
        });
        let source = connect(port);
        std::thread::sleep(Duration::from_millis(2500));
        let sent = written.load(Ordering::Relaxed);
        let counters = source.counters().snapshot();
        drop(source);
        // 2 s at 10 MiB/s, plus both sockets' buffers (a few MiB each), generously.
        assert!(sent > 0);
        assert!(sent < 60 << 20, "the service got {} MiB read in 2 s", sent >> 20);
        assert_eq!(counters.rejected(), 0, "{counters:?}");
    }

    /// Writes `head` once, then `body` again and again as fast as the socket takes it, for at
    /// most `for_how_long` or until the client drops the connection; `started` is set when the
    /// flood begins.
    fn flood(
        ws: &mut tungstenite::WebSocket<TcpStream>,
        head: &[u8],
        body: &[u8],
        for_how_long: Duration,
        started: &std::sync::OnceLock<Instant>,
    ) {
        let tcp = ws.get_mut();
        if tcp.write_all(head).is_err() {
            return;
        }
        let burst = body.repeat(4096);
        tcp.set_write_timeout(Some(Duration::from_millis(50))).unwrap();
        let t0 = *started.get_or_init(Instant::now);
        let mut at = 0;
        while t0.elapsed() < for_how_long {
            match tcp.write(&burst[at..]) {
                Ok(n) => at = (at + n) % burst.len(),
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {}
                Err(_) => return,
            }
        }
    }

    /// Issue 42: a service sending empty text messages (2-byte frames) flat out is read at
    /// frond's pace in messages, not only in bytes: each frame costs FRAME_COST (1 KiB) of the
    /// 1 MiB budget per 100 ms window, so at most 1,024 frames (+1 started at the edge) a
    /// window; a 1 s span overlaps at most 11 windows: 11 * 1,025 = 11,275 messages, however
    /// fast the service sends (the old client parsed and refused about 2 million a second).
    /// And a service that only sends junk is dropped, counted as peers_dropped.
    #[test]
    fn a_leap_service_sending_empty_messages_flat_out_is_read_at_a_bounded_pace_and_dropped() {
        let started: Arc<std::sync::OnceLock<Instant>> = Arc::default();
        let t0 = Arc::clone(&started);
        let (port, _) = service(move |mut ws| {
            flood(&mut ws, &[], &[0x81, 0x00], Duration::from_secs(20), &t0);
        });
        let source = connect(port);
        let counters = source.counters();
        assert!(wait_until(Duration::from_secs(5), || started.get().is_some()), "the flood did not start");
        // A second of it, from a first message on.
        assert!(wait_until(Duration::from_secs(5), || counters.malformed.load(Ordering::Relaxed) > 0));
        let before = counters.malformed.load(Ordering::Relaxed);
        std::thread::sleep(Duration::from_secs(1));
        let in_a_second = counters.malformed.load(Ordering::Relaxed) - before;
        assert!(in_a_second > 0);
        assert!(in_a_second <= 11 * 1025, "{in_a_second} empty messages read in 1 s");
        assert!(
            wait_until(Duration::from_secs(10), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
            "never dropped: {:?}",
            counters.snapshot()
        );
    }

    /// Issue 42: endless zero-length fragments of a message that never ends are paid for frame
    /// by frame; the service never sends a message frond can use, so it is dropped (the old
    /// client read them at 10 MiB/s and kept the connection for ever).
    #[test]
    fn a_leap_service_sending_endless_empty_fragments_is_dropped() {
        let (port, _) = service(move |mut ws| {
            // A text frame that is not the last (FIN clear), then continuations, all empty.
            flood(&mut ws, &[0x01, 0x00], &[0x00, 0x00], Duration::from_secs(20), &Default::default());
        });
        let source = connect(port);
        let counters = source.counters();
        assert!(
            wait_until(Duration::from_secs(10), || counters.peers_dropped.load(Ordering::Relaxed) >= 1),
            "never dropped: {:?}",
            counters.snapshot()
        );
        assert_eq!(counters.snapshot().rejected(), 0);
    }

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
