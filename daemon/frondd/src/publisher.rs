//! The pose socket: the acceptor, and the publisher thread's slow lane.
//!
//! Subscribers start on a direct lane: the realtime loop writes each frame to them itself
//! ([`crate::lanes`]). One whose socket cannot take a frame moves here, to the publisher
//! thread, which keeps a bounded backlog per subscriber and writes what each socket accepts
//! without blocking. A subscriber whose backlog is full loses frames (counted per subscriber);
//! one that accepts nothing for `write_timeout` is disconnected. So a slow or dead subscriber
//! costs only itself. The loop also `try_send`s every frame into the publisher's bounded queue
//! (a full queue is a counted drop, never a wait) but wakes the publisher only while the slow
//! lane has subscribers; otherwise the publisher drains the queue every 20 ms. Nothing a
//! subscriber sends is read: the pose socket is read-only for them.

use std::io::{ErrorKind, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender, TryRecvError};
use frond_protocol::field::{FieldFrame, FieldMessage};
use frond_protocol::{Hello, PatchableHello, Pose, ServerMessage, SubscriberStatus, encode_frame};
use tracing::{debug, info, warn};

use crate::handoff::{
    ElementsCell, ElementsSnapshot, LoopCommand, MAX_SUBSCRIBERS, NewLane, PublisherWake, SlowLane,
    SubscriberCounters,
};

/// How often the helper threads that wait on a socket or a channel look at their `stop` flag
/// when nothing wakes them (the daemon wakes them at shutdown: see `daemon::wake_listeners`).
/// Rare, because every wake-up of an idle daemon costs CPU the realtime loop could use.
pub const STOP_POLL: Duration = Duration::from_millis(500);
/// How often the publisher takes the frames queued for it while no subscriber is on its slow
/// lane (with one, the loop wakes it for every frame). Bounds the queue's occupancy: 100 ms is
/// 100 frames at 1 kHz, 1 000 at 10 kHz, far from [`PUBLISH_QUEUE_FRAMES`].
const IDLE_DRAIN: Duration = Duration::from_millis(100);

/// Frames the loop may get ahead of the publisher thread before it drops them.
pub const PUBLISH_QUEUE_FRAMES: usize = 8192;
/// Bytes budgeted per frame in a subscriber's backlog (a pose frame encodes to ~230 bytes).
const BACKLOG_BYTES_PER_FRAME: usize = 256;
/// Frames the publisher encodes and writes together at most.
const MAX_BATCH: usize = 256;

/// Registry entry for status reporting.
struct Registered {
    id: u64,
    /// The client's process id (`SO_PEERCRED` at accept; 0 if the socket would not say).
    pid: u32,
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
                pid: e.pid,
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

/// Accepts subscribers on `listener` until `stop` is set and hands them, with their `Hello`
/// encoded, to the realtime loop (`LoopCommand::AddSubscriber`), which puts them on a lane.
pub fn spawn_acceptor(
    listener: UnixListener,
    config: PublisherConfig,
    to_loop: Sender<LoopCommand>,
    hello: HelloSource,
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
                    // Woken by a connection (at shutdown the daemon makes one), or every
                    // `STOP_POLL` to look at `stop`.
                    crate::clock::wait_readable(std::os::fd::AsFd::as_fd(&listener), STOP_POLL);
                    continue;
                }
                Err(e) => {
                    warn!(error = %e, "accepting a pose subscriber failed");
                    thread::sleep(Duration::from_millis(100));
                    continue;
                }
            };
            if registry.live() >= max {
                refuse_subscriber(
                    stream,
                    &format!(
                        "the subscriber limit is reached ({max} connected; `max_subscribers` in the \
                         daemon's config, at most {MAX_SUBSCRIBERS})"
                    ),
                );
                continue;
            }
            let id = next_id;
            next_id += 1;
            let pid = crate::access::peer_cred(&stream).map_or(0, |c| u32::try_from(c.pid).unwrap_or(0));
            // Subscribers only read: anything they send is discarded unread.
            let _ = stream.shutdown(std::net::Shutdown::Read);
            let counters = Arc::new(SubscriberCounters::default());
            let new = NewLane::new(id, stream, counters.clone(), PatchableHello::new(&hello()));
            if to_loop
                .send_timeout(LoopCommand::AddSubscriber(Box::new(new)), Duration::from_secs(1))
                .is_err()
            {
                // The connection went with the command; the client sees it closed.
                warn!(id, "refusing a pose subscriber: the realtime loop is not accepting");
                continue;
            }
            registry.entries.lock().unwrap_or_else(|e| e.into_inner()).push(Registered {
                id,
                pid,
                since: Instant::now(),
                counters,
            });
            info!(id, pid, "pose subscriber connected");
        }
    })
}

/// Tells a connection the daemon cannot take why, in place of a hello, and closes it. Never
/// blocks: a fresh socket has room for the one small frame, and a client that is gone is
/// simply gone. Logged at most 10 times per 10 s (a client decides how often this runs).
fn refuse_subscriber(mut stream: UnixStream, reason: &str) {
    static REFUSALS: crate::log_limit::LogLimit = crate::log_limit::LogLimit::new();
    REFUSALS.log("pose subscriber refusals", || warn!(reason, "refusing a pose subscriber"));
    let mut frame = Vec::with_capacity(256);
    encode_frame(&ServerMessage::Refused(reason.to_string()), &mut frame);
    if stream.set_nonblocking(true).is_ok() {
        let _ = stream.write_all(&frame);
    }
    let _ = stream.shutdown(std::net::Shutdown::Both);
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
    /// Frames before this sequence number are not owed to it (it was on a direct lane then).
    from_seq: u64,
    /// Version of the last element table it was sent (on its direct lane, or here).
    table_version: u64,
}

impl Subscriber {
    /// A subscriber the loop moved to the slow lane, with the unsent tail it had; backlog of
    /// `cap` bytes.
    fn from_slow_lane(lane: SlowLane, cap: usize) -> Self {
        let _ = lane.stream.set_nonblocking(true);
        let mut backlog = Vec::with_capacity(cap + 4096);
        backlog.extend_from_slice(&lane.tail[..lane.tail_len]);
        debug!(id = lane.id, from_seq = lane.from_seq, "subscriber moved to the slow lane");
        // The loop's tail buffer goes back to be freed by dropping it here.
        Subscriber {
            id: lane.id,
            stream: lane.stream,
            counters: lane.counters,
            backlog,
            written: 0,
            cap,
            last_progress: Instant::now(),
            from_seq: lane.from_seq,
            table_version: lane.elements_version,
        }
    }

    /// Queues the frames of `batch` owed to it, with a newer element `table` right before the
    /// first frame published under it.
    fn offer_owed(&mut self, batch: &Batch, table: &ElementsSnapshot) {
        let starts = &batch.starts;
        let Some(i) = starts.iter().position(|&(seq, _)| seq >= self.from_seq) else { return };
        let split = (self.table_version < table.version && table.from_seq != u64::MAX)
            .then(|| starts[i..].iter().position(|&(seq, _)| seq >= table.from_seq).map(|k| i + k))
            .flatten();
        match split {
            Some(j) => {
                if j > i {
                    self.offer(&batch.bytes[starts[i].1..starts[j].1], (j - i) as u64);
                }
                self.offer_table(&table.frame, table.version);
                self.offer(&batch.bytes[starts[j].1..], (starts.len() - j) as u64);
            }
            None => self.offer(&batch.bytes[starts[i].1..], (starts.len() - i) as u64),
        }
        self.from_seq = 0;
    }

    /// Ends it: marks it closed, shuts its socket and says why it left.
    fn close(&self, reason: &str, wake: &PublisherWake) {
        self.counters.closed.store(true, Relaxed);
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
        wake.remove_slow();
        debug!(
            id = self.id,
            sent = self.counters.sent.load(Relaxed),
            dropped = self.counters.dropped.load(Relaxed),
            "subscriber closed"
        );
        info!(id = self.id, reason, "pose subscriber left");
    }

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

    /// Queues the element table (it is never dropped: a subscriber must know what it gets).
    fn offer_table(&mut self, table: &[u8], version: u64) {
        if self.written > 0 && self.backlog.len() + table.len() > self.backlog.capacity() {
            self.backlog.drain(..self.written);
            self.written = 0;
        }
        self.backlog.extend_from_slice(table);
        self.table_version = version;
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
/// [`PublishQueue::wake`] of the queue `frames` comes from; `slow` brings the subscribers the
/// loop moved off their direct lane.
///
/// [`PublishQueue::wake`]: crate::handoff::PublishQueue::wake
pub fn spawn_publisher(
    frames: Receiver<Pose>,
    wake: Arc<PublisherWake>,
    slow: Receiver<SlowLane>,
    tables: Arc<ElementsCell>,
    config: PublisherConfig,
) -> std::io::Result<thread::JoinHandle<()>> {
    thread::Builder::new().name("frond-publish".into()).spawn(move || {
        let mut subs: Vec<Subscriber> = Vec::with_capacity(MAX_SUBSCRIBERS);
        let mut batch = Batch::new();
        let cap = config.queue_frames.max(2) * BACKLOG_BYTES_PER_FRAME;
        while batch.take(&wake, &frames).is_ok() {
            // After taking the batch: the loop hands a subscriber over before it queues the
            // first frame owed to it, so every frame of this batch it is owed is covered here.
            while let Ok(lane) = slow.try_recv() {
                subs.push(Subscriber::from_slow_lane(lane, cap));
            }
            if subs.is_empty() {
                // Nobody on the slow lane: the frames were for the direct lanes only.
                continue;
            }
            batch.encode();
            let now = Instant::now();
            // After taking the batch: the loop marks a table applied before it queues the first
            // frame of the new table, so a frame at or after `table_from` in this batch is seen
            // with its table.
            let table = tables.load();
            subs.retain_mut(|s| {
                s.offer_owed(&batch, &table);
                match s.flush(now, config.write_timeout) {
                    Ok(()) => true,
                    Err(reason) => {
                        s.close(reason, &wake);
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

/// The frames the publisher takes from its queue in one go, and their encoding (buffers kept
/// from one batch to the next).
struct Batch {
    poses: Vec<Pose>,
    /// Field frames numbered before the batch's last pose (merged with the poses by number).
    fields: Vec<FieldFrame>,
    /// Field frames numbered after it, kept for the next batch.
    later_fields: Vec<FieldFrame>,
    /// The frames encoded one after the other.
    bytes: Vec<u8>,
    /// (sequence number, offset in `bytes`) of each frame.
    starts: Vec<(u64, usize)>,
}

impl Batch {
    fn new() -> Self {
        Batch {
            poses: Vec::with_capacity(MAX_BATCH),
            fields: Vec::with_capacity(crate::handoff::FIELD_QUEUE_FRAMES),
            later_fields: Vec::with_capacity(crate::handoff::FIELD_QUEUE_FRAMES),
            bytes: Vec::with_capacity(MAX_BATCH * BACKLOG_BYTES_PER_FRAME * 2),
            starts: Vec::with_capacity(MAX_BATCH),
        }
    }

    /// Takes the next frames: waits for one (at most [`IDLE_DRAIN`], then the batch is empty)
    /// and takes what else is queued, up to [`MAX_BATCH`]. `Err` once the loop has gone.
    fn take(&mut self, wake: &PublisherWake, frames: &Receiver<Pose>) -> Result<(), TryRecvError> {
        let first = match wake.recv_timeout(frames, IDLE_DRAIN) {
            Ok(p) => p,
            Err(TryRecvError::Disconnected) => return Err(TryRecvError::Disconnected),
            Err(TryRecvError::Empty) => None,
        };
        self.poses.clear();
        if let Some(p) = first {
            self.poses.push(p);
            while self.poses.len() < MAX_BATCH {
                let Ok(p) = frames.try_recv() else { break };
                self.poses.push(p);
            }
        }
        self.take_fields(wake);
        Ok(())
    }

    /// Takes the field frames numbered before the last pose taken: the loop queued each of them
    /// before that pose, so all of them are here now. Those numbered after it wait for the
    /// batch that takes the poses before them.
    fn take_fields(&mut self, wake: &PublisherWake) {
        self.fields.clear();
        while self.later_fields.len() < self.later_fields.capacity() {
            let Ok(f) = wake.field_frames().try_recv() else { break };
            self.later_fields.push(f);
        }
        let Some(last) = self.poses.last().map(|p| p.seq) else {
            // Keep what waits for its poses, but never a full queue of it.
            if self.later_fields.len() == self.later_fields.capacity() {
                self.later_fields.clear();
            }
            return;
        };
        let mut k = 0;
        while k < self.later_fields.len() {
            if self.later_fields[k].seq < last {
                self.fields.push(self.later_fields.swap_remove(k));
            } else {
                k += 1;
            }
        }
        self.fields.sort_unstable_by_key(|f| f.seq);
    }

    /// Encodes the frames taken, poses and field frames in the order of their numbers.
    fn encode(&mut self) {
        self.bytes.clear();
        self.starts.clear();
        let mut fields = self.fields.iter().peekable();
        for p in &self.poses {
            while let Some(f) = fields.next_if(|f| f.seq < p.seq) {
                self.starts.push((f.seq, self.bytes.len()));
                encode_frame(&ServerMessage::Field(FieldMessage::Frame(*f)), &mut self.bytes);
            }
            self.starts.push((p.seq, self.bytes.len()));
            encode_frame(&ServerMessage::Pose(*p), &mut self.bytes);
        }
    }
}
