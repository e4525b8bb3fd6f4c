//! The pose socket: accepts subscribers and gives each one a bounded queue and a writer thread.
//!
//! The realtime loop `try_send`s every frame into each subscriber's queue; a full queue drops that
//! frame for that subscriber only (counted). The writer thread blocks on the socket with a write
//! timeout, so a stalled client is disconnected without ever slowing the loop or anyone else.
//! Nothing a subscriber sends is read: the pose socket is read-only for them.

use std::io::Write;
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender, bounded};
use frond_protocol::{Hello, Pose, ServerMessage, SubscriberStatus, encode_frame};
use tracing::{debug, info, warn};

use crate::engine::{LoopCommand, MAX_SUBSCRIBERS};

/// What the loop sends to a subscriber's writer.
pub enum Outbound {
    /// First message from the loop: the sequence number of the next pose.
    Start {
        /// Next pose sequence number.
        next_seq: u64,
    },
    /// A pose.
    Pose(Pose),
}

/// Per-subscriber counters, shared by the loop, the writer and status.
#[derive(Default)]
pub struct SubscriberCounters {
    /// Frames written to the socket.
    pub sent: AtomicU64,
    /// Frames dropped because the queue was full.
    pub dropped: AtomicU64,
    /// Set when the writer has ended.
    pub closed: AtomicBool,
}

/// The loop's handle on one subscriber.
pub struct SubscriberSlot {
    /// Connection id.
    pub id: u64,
    /// The subscriber's bounded queue.
    pub tx: Sender<Outbound>,
    /// Its counters.
    pub counters: Arc<SubscriberCounters>,
}

/// Registry entry for status reporting.
struct Registered {
    id: u64,
    since: Instant,
    counters: Arc<SubscriberCounters>,
}

/// Publisher settings.
#[derive(Debug, Clone, Copy)]
pub struct PublisherConfig {
    /// Frames a subscriber may fall behind before its frames are dropped.
    pub queue_frames: usize,
    /// A write blocked this long disconnects the subscriber.
    pub write_timeout: Duration,
    /// Most subscribers at once.
    pub max_subscribers: usize,
}

/// Shared view of the subscribers, for status.
#[derive(Default)]
pub struct SubscriberRegistry {
    entries: Mutex<Vec<Registered>>,
}

impl SubscriberRegistry {
    /// Status of every live subscriber (and forgets closed ones).
    pub fn snapshot(&self) -> Vec<SubscriberStatus> {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.retain(|e| !e.counters.closed.load(Relaxed));
        entries
            .iter()
            .map(|e| SubscriberStatus {
                id: e.id,
                connected_s: e.since.elapsed().as_secs_f64(),
                sent: e.counters.sent.load(Relaxed),
                dropped: e.counters.dropped.load(Relaxed),
            })
            .collect()
    }

    fn live(&self) -> usize {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        entries.retain(|e| !e.counters.closed.load(Relaxed));
        entries.len()
    }
}

/// Source of the `Hello` for new subscribers (the rig can change at runtime).
pub type HelloSource = Arc<dyn Fn() -> Hello + Send + Sync>;

/// Accepts subscribers on `listener` until `stop` is set.
pub fn spawn_acceptor(
    listener: UnixListener,
    config: PublisherConfig,
    hello: HelloSource,
    commands: Sender<LoopCommand>,
    registry: Arc<SubscriberRegistry>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<thread::JoinHandle<()>> {
    listener.set_nonblocking(true)?;
    thread::Builder::new().name("frond-accept".into()).spawn(move || {
        let mut next_id = 1u64;
        let max = config.max_subscribers.min(MAX_SUBSCRIBERS);
        while !stop.load(Relaxed) {
            let stream = match listener.accept() {
                Ok((stream, _)) => stream,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    thread::sleep(Duration::from_millis(20));
                    continue;
                }
                Err(e) => {
                    warn!(error = %e, "accepting a pose subscriber failed");
                    thread::sleep(Duration::from_millis(100));
                    continue;
                }
            };
            if registry.live() >= max {
                warn!(max, "refusing a pose subscriber: the subscriber limit is reached");
                continue;
            }
            let id = next_id;
            next_id += 1;
            let (tx, rx) = bounded(config.queue_frames.max(2));
            let counters = Arc::new(SubscriberCounters::default());
            let slot = SubscriberSlot { id, tx, counters: counters.clone() };
            if commands.try_send(LoopCommand::AddSubscriber(slot)).is_err() {
                warn!(id, "refusing a pose subscriber: the loop's command queue is full");
                continue;
            }
            registry.entries.lock().unwrap_or_else(|e| e.into_inner()).push(Registered {
                id,
                since: Instant::now(),
                counters: counters.clone(),
            });
            let hello = hello();
            let spawned = thread::Builder::new()
                .name(format!("frond-sub-{id}"))
                .spawn(move || write_subscriber(id, stream, rx, counters, hello, config.write_timeout));
            if let Err(e) = spawned {
                warn!(id, error = %e, "could not start a subscriber writer thread");
            } else {
                info!(id, "pose subscriber connected");
            }
        }
    })
}

/// Writes frames to one subscriber until its socket fails or the daemon stops.
fn write_subscriber(
    id: u64,
    mut stream: UnixStream,
    rx: Receiver<Outbound>,
    counters: Arc<SubscriberCounters>,
    mut hello: Hello,
    write_timeout: Duration,
) {
    let _ = stream.set_nonblocking(false);
    let _ = stream.set_write_timeout(Some(write_timeout));
    let _ = stream.shutdown(std::net::Shutdown::Read);
    let mut buf: Vec<u8> = Vec::with_capacity(64 * 1024);
    let mut reason = "daemon stopping";
    while let Ok(first) = rx.recv() {
        buf.clear();
        let mut poses = 0u64;
        let mut item = Some(first);
        // Batch whatever is queued into one write: a subscriber that fell behind catches up with
        // few system calls.
        while let Some(msg) = item.take() {
            match msg {
                Outbound::Start { next_seq } => {
                    hello.next_seq = next_seq;
                    encode_frame(&ServerMessage::Hello(hello.clone()), &mut buf);
                }
                Outbound::Pose(p) => {
                    encode_frame(&ServerMessage::Pose(p), &mut buf);
                    poses += 1;
                }
            }
            if buf.len() < 48 * 1024 {
                item = rx.try_recv().ok();
            }
        }
        if let Err(e) = stream.write_all(&buf) {
            reason = match e.kind() {
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => "write timed out (stalled)",
                std::io::ErrorKind::BrokenPipe | std::io::ErrorKind::ConnectionReset => "disconnected",
                _ => "write failed",
            };
            break;
        }
        counters.sent.fetch_add(poses, Relaxed);
    }
    counters.closed.store(true, Relaxed);
    let _ = stream.shutdown(std::net::Shutdown::Both);
    debug!(
        id,
        reason,
        sent = counters.sent.load(Relaxed),
        dropped = counters.dropped.load(Relaxed),
        "subscriber writer ended"
    );
    info!(id, reason, "pose subscriber left");
}
