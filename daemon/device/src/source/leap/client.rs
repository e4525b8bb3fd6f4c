//! The Leap backend's client thread ([`Client`]): connects to the tracking service, reads its
//! frames through a [`ServiceStream`], turns the chosen hand of each into a [`DeviceSample`]
//! and queues it for the loop, ringing the source's doorbell; reconnects when the service goes.

use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crossbeam_channel::{Sender, TrySendError};

use super::frames::{Chirality, LeapError, LeapMessage, MAX_MESSAGE_BYTES, hand_sample, parse_message};
use super::stream::{FRAME_COST, READ_BUDGET, READ_WINDOW, ServiceStream};
use crate::doorbell::Doorbell;
use crate::log_limit::LogLimit;
use crate::report::{DeviceSample, SourceCounters};

/// Longest WebSocket handshake.
pub(super) const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(2);
/// How long a read waits before the thread checks whether it should stop.
pub(super) const READ_POLL: Duration = Duration::from_millis(200);
/// First and longest wait between connection attempts.
const RETRY: (Duration, Duration) = (Duration::from_millis(500), Duration::from_secs(2));
/// How long the service may leave what frond wrote (pongs, its requests) unread before the
/// connection is dropped.
pub(super) const PEER_WRITE_DEADLINE: Duration = Duration::from_secs(2);
/// Bytes frond keeps queued for the service at most (a pong waiting behind them is replaced by
/// the next, never queued).
const MAX_WRITE_BUFFER: usize = 64 << 10;
/// A service that keeps frond's read budget spent this long without one message frond can use
/// (everything it sends is refused, or never ends) is dropped, as one that does not read.
pub(super) const JUNK_DEADLINE: Duration = Duration::from_secs(2);
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

/// Why a connection to the tracking service was not made (a log line's reason; the client
/// retries).
#[derive(Debug, thiserror::Error)]
pub(super) enum LeapConnectError {
    /// The host name did not resolve.
    #[error("cannot resolve {host_port}: {error}")]
    Resolve {
        /// `HOST:PORT` as configured.
        host_port: String,
        /// The resolver's error.
        error: std::io::Error,
    },
    /// The host name resolved to no address.
    #[error("{0} resolves to no address")]
    NoAddress(String),
    /// The TCP connection failed or could not be set up.
    #[error("{0}")]
    Tcp(std::io::Error),
    /// The WebSocket handshake failed.
    #[error("WebSocket handshake with {url}: {failed}")]
    Handshake {
        /// The WebSocket URL.
        url: String,
        /// Why it failed.
        failed: HandshakeFailed,
    },
    /// Asking the service for frames failed.
    #[error("{0}")]
    Ask(Box<tungstenite::Error>),
}

/// How one connection to the service ended.
enum SessionEnd {
    /// frond asked the client to stop.
    Stopped,
    /// No connection was made (the service is not there, or refused the handshake).
    Unreachable(LeapConnectError),
    /// A connection was made and then lost; the reason has been logged.
    Lost,
}

/// Why [`handshake`] ended without a WebSocket.
#[derive(Debug, thiserror::Error)]
pub(super) enum HandshakeFailed {
    /// The service refused it, or the stream failed or timed out.
    #[error("{0}")]
    Refused(Box<tungstenite::Error>),
    /// The source is being dropped.
    #[error("the source is stopping")]
    Stopping,
}

pub(super) struct Client {
    pub(super) host_port: String,
    pub(super) hand: Chirality,
    pub(super) tx: Sender<DeviceSample>,
    pub(super) bell: Arc<Doorbell>,
    pub(super) counters: Arc<SourceCounters>,
    pub(super) overflow: Arc<AtomicU64>,
    pub(super) stop: Arc<AtomicBool>,
}

impl Client {
    /// Connects, reads and reconnects until the source is dropped.
    pub(super) fn run(self) {
        let mut wait = RETRY.0;
        let mut said_down = false;
        while !self.stop.load(Ordering::Acquire) {
            let started = Instant::now();
            match self.session() {
                SessionEnd::Stopped => return,
                SessionEnd::Lost => {
                    // A fresh outage (the session said it): retry soon, unless the
                    // connection was short-lived (a service that drops every connection).
                    said_down = false;
                    if started.elapsed() >= STEADY {
                        wait = RETRY.0;
                    }
                }
                SessionEnd::Unreachable(why) => {
                    if !said_down {
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

    fn address(&self) -> Result<SocketAddr, LeapConnectError> {
        self.host_port
            .to_socket_addrs()
            .map_err(|error| LeapConnectError::Resolve { host_port: self.host_port.clone(), error })?
            .next()
            .ok_or_else(|| LeapConnectError::NoAddress(self.host_port.clone()))
    }

    /// Connects and shakes hands with the service, then asks it for frames; the WebSocket and
    /// its URL (for logs).
    fn connect(&self) -> Result<(tungstenite::WebSocket<ServiceStream>, String), LeapConnectError> {
        let addr = self.address()?;
        let tcp = TcpStream::connect_timeout(&addr, Duration::from_secs(1)).map_err(LeapConnectError::Tcp)?;
        tcp.set_nodelay(true).ok();
        // Every read waits at most READ_POLL, so that a stop is seen; the handshake as a whole
        // at most HANDSHAKE_TIMEOUT.
        tcp.set_read_timeout(Some(READ_POLL)).map_err(LeapConnectError::Tcp)?;
        let stream = ServiceStream::new(tcp, Arc::clone(&self.stop), Instant::now() + HANDSHAKE_TIMEOUT);
        let url = format!("ws://{}/v6.json", self.host_port);
        let mut config = tungstenite::protocol::WebSocketConfig::default();
        config.max_message_size = Some(MAX_MESSAGE_BYTES);
        config.max_frame_size = Some(MAX_MESSAGE_BYTES);
        // Written at once (nothing is held back to batch), and never more than this queued.
        config.write_buffer_size = 0;
        config.max_write_buffer_size = MAX_WRITE_BUFFER;
        let (mut ws, _) = handshake(url.as_str(), stream, config)
            .map_err(|failed| LeapConnectError::Handshake { url: url.clone(), failed })?;
        ws.get_mut().deadline = None;
        for ask in [r#"{"background":true}"#, r#"{"focused":true}"#] {
            match ws.send(tungstenite::Message::text(ask)) {
                Ok(()) => {}
                // Queued: written with the next read's flush.
                Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) => return Err(LeapConnectError::Ask(Box::new(e))),
            }
        }
        Ok((ws, url))
    }

    /// One connection: handshake, then frames until the service goes or we are asked to stop.
    /// Says how it ended; a lost connection has already been logged with its reason.
    fn session(&self) -> SessionEnd {
        let (mut ws, url) = match self.connect() {
            Ok(connected) => connected,
            Err(e) => return SessionEnd::Unreachable(e),
        };
        tracing::info!(service = %url, "connected to the Leap Motion service");
        let (mut warned_version, mut warned_pace) = (false, false);
        // When the service last sent a message frond could use (one it did not refuse).
        let mut last_useful = Instant::now();
        loop {
            if self.stop.load(Ordering::Acquire) {
                let _ = ws.close(None);
                return SessionEnd::Stopped;
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
                return SessionEnd::Lost;
            }
            let spent_lately = ws.get_ref().spent_at.is_some_and(|t| t.elapsed() <= 2 * READ_WINDOW);
            if spent_lately && last_useful.elapsed() >= JUNK_DEADLINE {
                self.counters.peers_dropped.fetch_add(1, Ordering::Relaxed);
                let why = format!(
                    "it kept frond's read budget spent for {} s without a message frond could use",
                    JUNK_DEADLINE.as_secs()
                );
                warn_connection(&url, "dropped the Leap Motion service's connection; reconnecting", &why);
                return SessionEnd::Lost;
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
                    return SessionEnd::Lost;
                }
            };
            let text = match &msg {
                tungstenite::Message::Text(t) => t.as_str(),
                tungstenite::Message::Close(_) => {
                    let why = "the service closed the connection";
                    warn_connection(&url, "the Leap Motion service closed the connection; reconnecting", why);
                    return SessionEnd::Lost;
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
            self.take(parsed, &url, &mut warned_version);
        }
    }

    /// Counts or queues one parsed message (`warned_version`: whether a protocol other than 6
    /// was already logged).
    fn take(&self, parsed: Result<LeapMessage, LeapError>, url: &str, warned_version: &mut bool) {
        match parsed {
            Ok(LeapMessage::Version(6)) | Ok(LeapMessage::Other) => {}
            Ok(LeapMessage::Version(v)) => {
                if !*warned_version {
                    tracing::warn!(service = %url, version = v, "the service speaks protocol {v}, not 6; reading its frames anyway");
                    *warned_version = true;
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
) -> Result<(tungstenite::WebSocket<ServiceStream>, tungstenite::handshake::client::Response), HandshakeFailed>
{
    let stop = Arc::clone(&stream.stop);
    let mut attempt = tungstenite::client::client_with_config(url, stream, Some(config));
    loop {
        match attempt {
            Ok(done) => return Ok(done),
            Err(tungstenite::HandshakeError::Failure(e)) => {
                return Err(HandshakeFailed::Refused(Box::new(e)));
            }
            Err(tungstenite::HandshakeError::Interrupted(_)) if stop.load(Ordering::Acquire) => {
                return Err(HandshakeFailed::Stopping);
            }
            // A read waited READ_POLL: carry on (the stream's deadline ends it with TimedOut).
            Err(tungstenite::HandshakeError::Interrupted(mid)) => attempt = mid.handshake(),
        }
    }
}
