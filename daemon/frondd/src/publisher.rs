//! The pose socket: one publisher thread serves every subscriber.
//!
//! The realtime loop `try_send`s each frame once into the publisher's bounded queue (a full
//! queue costs a counted drop, never a wait). The publisher encodes a batch of frames once and
//! appends it to each subscriber's own bounded backlog, then writes what each socket accepts
//! without blocking. A subscriber whose backlog is full loses that batch (counted per
//! subscriber); one that accepts nothing for `write_timeout` is disconnected. So a slow or dead
//! subscriber costs only itself, and the loop wakes one thread per frame whatever the number of
//! subscribers. Nothing a subscriber sends is read: the pose socket is read-only for them.

use std::io::{ErrorKind, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed, Ordering::SeqCst, fence};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender, TryRecvError, TrySendError, bounded};
use frond_protocol::{Hello, Pose, ServerMessage, SubscriberStatus, encode_frame};
use tracing::{debug, info, warn};

use crate::engine::MAX_SUBSCRIBERS;
use crate::stats::LoopStats;

/// Frames the loop may get ahead of the publisher thread before it drops them.
pub const PUBLISH_QUEUE_FRAMES: usize = 8192;
/// Bytes budgeted per frame in a subscriber's backlog (a pose frame encodes to ~230 bytes).
const BACKLOG_BYTES_PER_FRAME: usize = 256;
/// Frames the publisher encodes and writes together at most.
const MAX_BATCH: usize = 256;

/// Per-subscriber counters, shared by the publisher and status.
#[derive(Default)]
pub struct SubscriberCounters {
    /// Frames handed to the subscriber's socket.
    pub sent: AtomicU64,
    /// Frames dropped because its backlog was full.
    pub dropped: AtomicU64,
    /// Set when the subscriber is gone.
    pub closed: AtomicBool,
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
    /// A subscriber that accepts nothing for this long is disconnected.
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

/// A connection handed from the acceptor to the publisher.
pub struct NewSubscriber {
    id: u64,
    stream: UnixStream,
    counters: Arc<SubscriberCounters>,
}

/// Accepts subscribers on `listener` until `stop` is set and hands them to the publisher.
pub fn spawn_acceptor(
    listener: UnixListener,
    config: PublisherConfig,
    subscribers: Sender<NewSubscriber>,
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
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    // Woken by a connection, or every 100 ms to look at `stop`.
                    crate::clock::wait_readable(
                        std::os::fd::AsFd::as_fd(&listener),
                        Duration::from_millis(100),
                    );
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
            let counters = Arc::new(SubscriberCounters::default());
            if subscribers
                .send_timeout(
                    NewSubscriber { id, stream, counters: counters.clone() },
                    Duration::from_secs(1),
                )
                .is_err()
            {
                warn!(id, "refusing a pose subscriber: the publisher is not accepting");
                continue;
            }
            registry.entries.lock().unwrap_or_else(|e| e.into_inner()).push(Registered {
                id,
                since: Instant::now(),
                counters,
            });
            info!(id, "pose subscriber connected");
        }
    })
}

/// One subscriber as the publisher sees it.
struct Subscriber {
    id: u64,
    stream: UnixStream,
    counters: Arc<SubscriberCounters>,
    /// Encoded bytes not yet accepted by the socket (may start mid-frame).
    backlog: Vec<u8>,
    written: usize,
    cap: usize,
    last_progress: Instant,
}

impl Subscriber {
    fn pending(&self) -> usize {
        self.backlog.len() - self.written
    }

    /// Writes what the socket takes now. `Err` means the subscriber is gone.
    fn flush(&mut self, now: Instant, timeout: Duration) -> Result<(), &'static str> {
        while self.written < self.backlog.len() {
            match self.stream.write(&self.backlog[self.written..]) {
                Ok(0) => return Err("disconnected"),
                Ok(n) => {
                    self.written += n;
                    self.last_progress = now;
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) if matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::ConnectionReset) => {
                    return Err("disconnected");
                }
                Err(_) => return Err("write failed"),
            }
        }
        if self.written == self.backlog.len() {
            self.backlog.clear();
            self.written = 0;
        } else if now.duration_since(self.last_progress) > timeout {
            return Err("stalled (accepted nothing within the write timeout)");
        } else if self.written > self.cap / 2 {
            // Keep the unsent tail at the front so the backlog never grows past its cap.
            self.backlog.drain(..self.written);
            self.written = 0;
        }
        Ok(())
    }

    /// Queues an encoded batch of `frames` frames, or drops it if the backlog is full.
    fn offer(&mut self, batch: &[u8], frames: u64) {
        if self.pending() + batch.len() > self.cap {
            self.counters.dropped.fetch_add(frames, Relaxed);
            return;
        }
        if self.written > 0 && self.backlog.len() + batch.len() > self.backlog.capacity() {
            self.backlog.drain(..self.written);
            self.written = 0;
        }
        self.backlog.extend_from_slice(batch);
        self.counters.sent.fetch_add(frames, Relaxed);
    }
}

/// Runs the publisher until every frame sender is gone (the loop has stopped). `wake` is the
/// [`PublishQueue::wake`] of the queue `frames` comes from.
pub fn spawn_publisher(
    frames: Receiver<Pose>,
    wake: Arc<PublisherWake>,
    joins: Receiver<NewSubscriber>,
    config: PublisherConfig,
    hello: HelloSource,
    stats: Arc<LoopStats>,
) -> std::io::Result<thread::JoinHandle<()>> {
    thread::Builder::new().name("frond-publish".into()).spawn(move || {
        let mut subs: Vec<Subscriber> = Vec::with_capacity(MAX_SUBSCRIBERS);
        let mut batch: Vec<u8> = Vec::with_capacity(MAX_BATCH * BACKLOG_BYTES_PER_FRAME * 2);
        let cap = config.queue_frames.max(2) * BACKLOG_BYTES_PER_FRAME;
        let mut next_seq: Option<u64> = None;
        loop {
            let first = match wake.recv_timeout(&frames, Duration::from_millis(20)) {
                Ok(p) => p,
                Err(TryRecvError::Disconnected) => break,
                Err(TryRecvError::Empty) => None,
            };
            // New subscribers start at the next frame this thread forwards.
            while let Ok(new) = joins.try_recv() {
                let seq = first.map(|p| p.seq).or(next_seq).unwrap_or_else(|| stats.next_seq.load(Relaxed));
                let mut h = hello();
                h.next_seq = seq;
                let mut bytes = Vec::with_capacity(cap + 4096);
                encode_frame(&ServerMessage::Hello(h), &mut bytes);
                let _ = new.stream.set_nonblocking(true);
                let _ = new.stream.shutdown(std::net::Shutdown::Read);
                subs.push(Subscriber {
                    id: new.id,
                    stream: new.stream,
                    counters: new.counters,
                    backlog: bytes,
                    written: 0,
                    cap,
                    last_progress: Instant::now(),
                });
            }
            batch.clear();
            let mut n = 0u64;
            if let Some(p) = first {
                encode_frame(&ServerMessage::Pose(p), &mut batch);
                n = 1;
                next_seq = Some(p.seq + 1);
                while (n as usize) < MAX_BATCH {
                    let Ok(p) = frames.try_recv() else { break };
                    encode_frame(&ServerMessage::Pose(p), &mut batch);
                    next_seq = Some(p.seq + 1);
                    n += 1;
                }
            }
            let now = Instant::now();
            subs.retain_mut(|s| {
                if n > 0 {
                    s.offer(&batch, n);
                }
                match s.flush(now, config.write_timeout) {
                    Ok(()) => true,
                    Err(reason) => {
                        s.counters.closed.store(true, Relaxed);
                        let _ = s.stream.shutdown(std::net::Shutdown::Both);
                        debug!(
                            id = s.id,
                            sent = s.counters.sent.load(Relaxed),
                            dropped = s.counters.dropped.load(Relaxed),
                            "subscriber closed"
                        );
                        info!(id = s.id, reason, "pose subscriber left");
                        false
                    }
                }
            });
        }
        for s in &subs {
            s.counters.closed.store(true, Relaxed);
            let _ = s.stream.shutdown(std::net::Shutdown::Both);
        }
    })
}

/// How the loop wakes the publisher thread: a flag the publisher raises before it parks, and its
/// thread handle.
///
/// Waiting in crossbeam's `recv_timeout` spins and calls `sched_yield` before it parks; at 1 kHz
/// that spinning was a tenth of the publisher's CPU in `perf` (issue 9). Here the publisher
/// parks at once and the loop unparks it only when the flag says it sleeps: one `futex` wake,
/// no allocation, no lock.
#[derive(Debug, Default)]
pub struct PublisherWake {
    parked: AtomicBool,
    thread: OnceLock<thread::Thread>,
}

impl PublisherWake {
    /// Called by the loop after each frame it queued.
    fn notify(&self) {
        // Pairs with the fence in `recv_timeout`: either the publisher's re-check sees the
        // frame, or we see its flag.
        fence(SeqCst);
        if self.parked.load(Relaxed)
            && self.parked.swap(false, SeqCst)
            && let Some(t) = self.thread.get()
        {
            t.unpark();
        }
    }

    /// The publisher's wait: the next frame, `Ok(None)` after `timeout` without one, or
    /// `Err(Disconnected)` once the loop has gone. Only the publisher thread calls this.
    pub fn recv_timeout(&self, rx: &Receiver<Pose>, timeout: Duration) -> Result<Option<Pose>, TryRecvError> {
        match rx.try_recv() {
            Ok(p) => return Ok(Some(p)),
            Err(TryRecvError::Disconnected) => return Err(TryRecvError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
        let _ = self.thread.get_or_init(thread::current);
        self.parked.store(true, SeqCst);
        fence(SeqCst);
        match rx.try_recv() {
            Ok(p) => {
                self.parked.store(false, Relaxed);
                return Ok(Some(p));
            }
            Err(TryRecvError::Disconnected) => return Err(TryRecvError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
        thread::park_timeout(timeout);
        self.parked.store(false, Relaxed);
        match rx.try_recv() {
            Ok(p) => Ok(Some(p)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(TryRecvError::Disconnected),
        }
    }
}

/// The loop's end of the publisher queue: one `try_send` per frame, drops counted.
#[derive(Clone)]
pub struct PublishQueue {
    tx: Sender<Pose>,
    wake: Arc<PublisherWake>,
}

impl PublishQueue {
    /// A queue and the publisher's end of it.
    pub fn new(frames: usize) -> (PublishQueue, Receiver<Pose>) {
        let (tx, rx) = bounded(frames);
        (PublishQueue { tx, wake: Arc::default() }, rx)
    }

    /// What [`spawn_publisher`] waits on (wakes it when this queue gets a frame).
    pub fn wake(&self) -> Arc<PublisherWake> {
        self.wake.clone()
    }

    /// Offers a frame; `false` when the publisher is behind by a whole queue (frame dropped).
    pub fn offer(&self, pose: Pose) -> bool {
        match self.tx.try_send(pose) {
            Ok(()) => {
                self.wake.notify();
                true
            }
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => false,
        }
    }
}
