//! Leap Motion / Ultraleap hand tracking as a hand source: `leap://HOST:PORT[?hand=left|right]`.
//!
//! A helper thread is a WebSocket client of the tracking service (protocol v6 on `/v6.json`,
//! `frond_motion::leap` parses and maps it): it asks for frames in the background (`{"background":
//! true}`, `{"focused": true}`), turns each frame's chosen hand into a [`DeviceSample`] and queues
//! it for the realtime loop, ringing a [`Doorbell`] (the source's ready descriptor). When the
//! service is down or restarts, the thread reconnects (every half second at first, backing off to
//! 2 s) while the loop sees no samples: poses are flagged held, then device-lost, as for any
//! stalled device; a hand out of view does the same. The loop's side never blocks or allocates.

use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::os::fd::RawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TrySendError};
use frond_motion::leap::{Chirality, LeapError, LeapMessage, MAX_MESSAGE_BYTES, hand_sample, parse_message};

use super::{HandSource, SourceError, SourceKind};
use crate::doorbell::Doorbell;
use crate::report::{DeviceSample, SourceCounters};

/// Samples queued for the loop at most (a second at the service's ~110 Hz, four times over).
const QUEUE_LEN: usize = 512;
/// Longest WebSocket handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(2);
/// How long a read waits before the thread checks whether it should stop.
const READ_POLL: Duration = Duration::from_millis(200);
/// First and longest wait between connection attempts.
const RETRY: (Duration, Duration) = (Duration::from_millis(500), Duration::from_secs(2));

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
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
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
            match self.session() {
                Ok(()) => return, // asked to stop
                Err((was_connected, why)) => {
                    if was_connected {
                        // A fresh outage: say it (the session did) and retry soon.
                        said_down = false;
                        wait = RETRY.0;
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
        let stream =
            TcpStream::connect_timeout(&addr, Duration::from_secs(1)).map_err(|e| not(e.to_string()))?;
        stream.set_nodelay(true).ok();
        // The handshake blocks (bounded); reads after it poll, so that a stop is seen.
        stream.set_read_timeout(Some(HANDSHAKE_TIMEOUT)).map_err(|e| not(e.to_string()))?;
        let url = format!("ws://{}/v6.json", self.host_port);
        let mut config = tungstenite::protocol::WebSocketConfig::default();
        config.max_message_size = Some(MAX_MESSAGE_BYTES);
        config.max_frame_size = Some(MAX_MESSAGE_BYTES);
        let (mut ws, _) = tungstenite::client::client_with_config(url.as_str(), stream, Some(config))
            .map_err(|e| not(format!("WebSocket handshake with {url}: {e}")))?;
        ws.get_mut().set_read_timeout(Some(READ_POLL)).map_err(|e| not(e.to_string()))?;
        for ask in [r#"{"background":true}"#, r#"{"focused":true}"#] {
            ws.send(tungstenite::Message::text(ask)).map_err(|e| not(e.to_string()))?;
        }
        tracing::info!(service = %url, "connected to the Leap Motion service");
        let mut warned_version = false;
        loop {
            if self.stop.load(Ordering::Acquire) {
                let _ = ws.close(None);
                return Ok(());
            }
            let msg = match ws.read() {
                Ok(m) => m,
                Err(tungstenite::Error::Io(e))
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
                {
                    continue;
                }
                Err(e) => {
                    tracing::warn!(service = %url, error = %e, "Leap Motion service connection ended; reconnecting");
                    return Err((true, e.to_string()));
                }
            };
            let text = match &msg {
                tungstenite::Message::Text(t) => t.as_str(),
                tungstenite::Message::Close(_) => {
                    tracing::warn!(service = %url, "the Leap Motion service closed the connection; reconnecting");
                    return Err((true, "the service closed the connection".into()));
                }
                _ => continue,
            };
            match parse_message(text) {
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

#[cfg(test)]
mod tests {
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
}
