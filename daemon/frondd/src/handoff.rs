//! What the realtime loop and the threads around it hand each other: the loop's commands
//! ([`LoopCommand`]), what it gives up to be dropped elsewhere ([`Garbage`], [`LostSource`]),
//! subscribers on their way in and out of the loop's direct lanes ([`NewLane`], [`Lane`],
//! [`SlowLane`]) with their counters, the frame queue to the publisher and its wake-up
//! ([`PublishQueue`], [`PublisherWake`]), and the element table for the slow lane
//! ([`ElementsCell`]).
//!
//! Both sides name these types, the loop (`engine`, `lanes`) and the slow side (`publisher`,
//! `control`, housekeeping in `daemon`), so they live here, apart from either: neither side
//! imports the other for them, and this module names neither. Nothing here allocates, locks or
//! blocks on the loop's side of a hand-off.

use std::os::unix::net::UnixStream;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::Relaxed, Ordering::SeqCst, fence};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, TryRecvError, TrySendError, bounded};
use frond_device::HandSource;
use frond_motion::{CalibrationParams, FilterSpec, MappingParams};
use frond_protocol::field::FieldFrame;
use frond_protocol::{ElementId, PatchableHello, Pose};

use crate::stage::StageCommand;

/// Most subscribers served at once.
pub const MAX_SUBSCRIBERS: usize = 64;
/// Most hand sources read at once (two hands of one tracker, two gloves on one stage, ...).
pub const MAX_HANDS: usize = 8;

/// Requests to the loop from the control and housekeeping threads.
pub enum LoopCommand {
    /// New mapping scales and tau (from the daemon's rig), for every hand that follows it.
    SetMapping(MappingParams),
    /// New calibration, for every hand that follows the daemon's.
    SetCalibration(CalibrationParams),
    /// New jitter filter (state is reset), for every hand that follows the daemon's.
    SetFilter(FilterSpec),
    /// Hand `hand` is published as element `element` from now on (its layer's id changed with
    /// the rig).
    SetHandElement {
        /// Index of the hand.
        hand: usize,
        /// Its element id.
        element: ElementId,
    },
    /// Start or stop forwarding frames to the recorder.
    SetRecording(bool),
    /// A (re)opened source for hand `.0`.
    ReplaceSource(usize, Box<dyn HandSource>),
    /// Testing aid (`frondd --test-hooks`): block the loop for this many milliseconds, as a hung
    /// loop would, so tests can check that the watchdog pings stop.
    Freeze(u32),
    /// A live stage installed, removed or given an input, and/or a new element table.
    Stage(Box<StageCommand>),
    /// A new pose subscriber, for a direct lane (see `lanes`).
    AddSubscriber(Box<NewLane>),
}

/// Things the loop must not drop itself (dropping may free memory): handed to housekeeping.
pub enum Garbage {
    /// A source replaced by a newer one.
    Source(Box<dyn HandSource>),
    /// An applied stage command, holding the stage and the element table it replaced.
    Stage(Box<StageCommand>),
    /// What is left of a subscriber once admitted (its encoded Hello).
    Admitted(Box<NewLane>),
    /// A subscriber that left its direct lane (hung up, or no room anywhere).
    Lane(Lane),
}

/// A hand's source the loop lost (a read failed), for the reopen thread to hand back with
/// [`LoopCommand::ReplaceSource`].
pub struct LostSource {
    /// Index of the hand.
    pub hand: usize,
    /// The source, to reopen.
    pub source: Box<dyn HandSource>,
}

/// Largest element-table frame the daemon sends (the control side refuses a stage change whose
/// table would be larger).
pub const ELEMENTS_FRAME_MAX: usize = 16 * 1024;
/// Longest unsent tail handed to the slow lane: the rest of a `Hello` (which carries an element
/// table) and a newer whole element table, or the rest of one pose frame (~230 bytes).
pub const TAIL_MAX: usize = 1024 + 2 * ELEMENTS_FRAME_MAX;

/// A subscriber the acceptor hands to the loop.
pub struct NewLane {
    /// Subscriber id (status, logs).
    pub id: u64,
    /// Its connection; taken by the loop.
    pub stream: Option<UnixStream>,
    /// Its counters; taken by the loop.
    pub counters: Option<Arc<SubscriberCounters>>,
    /// Its `Hello`, encoded.
    pub hello: PatchableHello,
    /// Room for an unsent tail ([`TAIL_MAX`] bytes), allocated here so the loop never has to.
    pub tail: Option<Box<[u8]>>,
}

impl NewLane {
    /// A subscriber on `stream` with its encoded `hello` (allocates its tail buffer).
    pub fn new(
        id: u64,
        stream: UnixStream,
        counters: Arc<SubscriberCounters>,
        hello: PatchableHello,
    ) -> Self {
        NewLane {
            id,
            stream: Some(stream),
            counters: Some(counters),
            hello,
            tail: Some(vec![0u8; TAIL_MAX].into_boxed_slice()),
        }
    }
}

/// A subscriber on its way from the loop to the publisher's slow lane.
pub struct SlowLane {
    /// Subscriber id.
    pub id: u64,
    /// Its connection.
    pub stream: UnixStream,
    /// Its counters.
    pub counters: Arc<SubscriberCounters>,
    /// The part of the last frames its socket did not take (sent first), in a buffer of
    /// [`TAIL_MAX`] bytes.
    pub tail: Box<[u8]>,
    /// Bytes of `tail` in use.
    pub tail_len: usize,
    /// Sequence number of the first frame the slow lane owes it.
    pub from_seq: u64,
    /// Version of the last element table it was sent (or has in `tail`): the slow lane sends
    /// only newer ones.
    pub elements_version: u64,
}

/// A subscriber on a direct lane: in one of the loop's `lanes::Lanes`, or handed to
/// housekeeping in [`Garbage::Lane`] to be closed.
pub struct Lane {
    /// Subscriber id.
    pub(crate) id: u64,
    /// Its connection.
    pub(crate) stream: UnixStream,
    /// Its counters.
    pub(crate) counters: Arc<SubscriberCounters>,
    /// Room for an unsent tail ([`TAIL_MAX`] bytes).
    pub(crate) tail: Box<[u8]>,
}

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

/// The element table in force, encoded as a frame, for the slow lane (the loop sends it to the
/// direct lanes itself). The control thread stores a new one before it sends the stage change;
/// the loop marks it applied with the sequence number of the first frame published under it;
/// the publisher sends it to a slow subscriber right before that frame, and never a table the
/// loop did not apply.
pub struct ElementsCell {
    frame: Mutex<Arc<[u8]>>,
    version: AtomicU64,
    from_seq: AtomicU64,
}

impl Default for ElementsCell {
    fn default() -> Self {
        ElementsCell {
            frame: Mutex::default(),
            version: AtomicU64::new(0),
            from_seq: AtomicU64::new(u64::MAX),
        }
    }
}

/// What [`ElementsCell::load`] returns.
pub struct ElementsSnapshot {
    /// Table version (0 before the first).
    pub version: u64,
    /// First frame published under it, or `u64::MAX` while the loop has not applied it.
    pub from_seq: u64,
    /// The encoded frame.
    pub frame: Arc<[u8]>,
}

impl ElementsCell {
    /// Stores table `version`, encoded, not yet applied (control side).
    pub fn store(&self, version: u64, frame: &[u8]) {
        let mut f = self.frame.lock().unwrap_or_else(|e| e.into_inner());
        *f = Arc::from(frame);
        self.from_seq.store(u64::MAX, SeqCst);
        self.version.store(version, SeqCst);
    }

    /// The loop applied table `version` before frame `from_seq` (no lock, no allocation).
    pub fn applied(&self, version: u64, from_seq: u64) {
        if self.version.load(SeqCst) == version {
            self.from_seq.store(from_seq, SeqCst);
        }
    }

    /// The current table, consistent: version, where it applies from, and its frame.
    pub fn load(&self) -> ElementsSnapshot {
        let f = self.frame.lock().unwrap_or_else(|e| e.into_inner());
        // Under the lock: a store cannot change the frame between these reads; `applied` only
        // ever sets `from_seq` of the version it names.
        let version = self.version.load(SeqCst);
        let from_seq = self.from_seq.load(SeqCst);
        ElementsSnapshot { version, from_seq, frame: f.clone() }
    }
}

/// How the loop wakes the publisher thread: a flag the publisher raises before it parks, and its
/// thread handle.
///
/// Waiting in crossbeam's `recv_timeout` spins and calls `sched_yield` before it parks; at 1 kHz
/// that spinning was a tenth of the publisher's CPU in `perf` (issue 9). Here the publisher
/// parks at once and the loop unparks it only when the flag says it sleeps: one `futex` wake,
/// no allocation, no lock.
#[derive(Debug)]
pub struct PublisherWake {
    parked: AtomicBool,
    thread: OnceLock<thread::Thread>,
    /// Subscribers on the slow lane (or on their way to it).
    slow: AtomicUsize,
    /// The field frames for the slow lane ([`PublishQueue::offer_field`]): a queue beside the
    /// poses' that the publisher drains with them and merges by sequence number. It rides here,
    /// with the wake-up both queues share, so that every end of the pose queue stays as it was.
    fields: (Sender<FieldFrame>, Receiver<FieldFrame>),
}

/// Field frames queued for the publisher at most (a field publishes 60 a second).
pub const FIELD_QUEUE_FRAMES: usize = 256;

impl Default for PublisherWake {
    fn default() -> Self {
        PublisherWake {
            parked: AtomicBool::new(false),
            thread: OnceLock::new(),
            slow: AtomicUsize::new(0),
            fields: bounded(FIELD_QUEUE_FRAMES),
        }
    }
}

impl PublisherWake {
    /// One more subscriber on the slow lane: frames wake the publisher from now on.
    pub fn add_slow(&self) {
        self.slow.fetch_add(1, SeqCst);
    }

    /// One subscriber fewer on the slow lane.
    pub fn remove_slow(&self) {
        self.slow.fetch_sub(1, SeqCst);
    }

    /// The publisher's end of the field frames' queue (drained after the poses it waited for).
    pub fn field_frames(&self) -> &Receiver<FieldFrame> {
        &self.fields.1
    }

    /// Called by the loop after each frame it queued: wakes the publisher if it serves anyone.
    fn notify(&self) {
        if self.slow.load(Relaxed) == 0 {
            return;
        }
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

    /// What `publisher::spawn_publisher` waits on (wakes it when this queue gets a frame).
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

    /// Offers a field frame; `false` when the publisher is behind by a whole field queue (frame
    /// dropped). It wakes nobody: the pose that follows it in the same tick does.
    pub fn offer_field(&self, frame: FieldFrame) -> bool {
        match self.wake.fields.0.try_send(frame) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => false,
        }
    }
}
