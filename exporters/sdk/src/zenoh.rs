//! frond on Zenoh: the key expressions a `frond-zenoh` bridge publishes, the session
//! configuration both sides build, and the subscriber's end of a Zenoh source.
//!
//! Under a source's key `frond/<stage>/<source>` (see [`keys`]):
//!
//! | key          | what                                                              | how            |
//! |--------------|-------------------------------------------------------------------|----------------|
//! | `.../poses`  | every pose the daemon publishes, and every field frame (protocol 3) | put, drop when congested |
//! | `.../elements` | the element table, when it changes                              | put + queryable (latest) |
//! | `.../fields` | the running fields' definitions, after each element table       | put + queryable (latest) |
//! | `.../hello`  | the daemon's hello (rig, joints, elements, `next_seq`)            | put on change + queryable (latest) |
//! | `.../status` | the daemon's status report, a few times a second                  | put + queryable (latest) |
//! | `.../alive`  | a liveliness token, held while the bridge is connected to its daemon | liveliness |
//! | `.../bridge/<id>` | a bridge's claim on the name (start time and Zenoh id): one publishes | liveliness |
//! | `.../replay` | the last poses published, for subscribers that lost some ([`crate::zenoh_replay`]) | queryable |
//! | `.../peers`  | each subscriber's own counts, as it reported them (JSON)          | queryable |
//!
//! Every payload is one frame of the socket protocol, byte for byte what `poses.sock` carries:
//! a `u32` little-endian length, the protocol version byte, a MessagePack body (a
//! `ServerMessage` for poses, field frames, elements, fields and hello; a `StatusReport` for
//! status), so a reader in any language decodes it with a plain MessagePack library after
//! skipping five bytes.
//!
//! A field (protocol 3, [`crate::field`]) crosses as it leaves the daemon: its definition on
//! `fields` (a late joiner asks the queryable for it, and again after a gap, as for the element
//! table) and its frames among the poses, numbered in the same sequence, so that gaps, the
//! replay ring and the order of tables and frames work for them as for poses. A subscriber over
//! Zenoh evaluates every plant itself, as over the socket: [`crate::Subscriber::fields`].

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use ::zenoh::Wait;
use ::zenoh::sample::SampleKind;
use crossbeam_channel::{Receiver, RecvTimeoutError, Sender, TryRecvError, bounded};
use frond_protocol::field::{FieldMessage, FieldTable};
use frond_protocol::{HEADER_LEN, Hello, MAX_FRAME_LEN, ServerMessage};

use crate::SubscriberOptions;
use crate::conn::ReadOutcome;
use crate::error::SdkError;
use crate::source::ZenohAddr;
use crate::zenoh_join::{decode_payload, newer, query_fields, query_hello, resolve};
use crate::zenoh_replay::{self, QUERY_TIMEOUT, RECOVERY_TIME, REPORT_EVERY, ReplayRequest, numbered};

/// Zenoh's session, as the functions here take it (the SDK's Zenoh version).
pub use ::zenoh::Session;

pub use crate::zenoh_config::{MAX_CONFIG_FILE, ZenohSetupError, config, open_addr_session, open_session};
pub use crate::zenoh_keys::{keys, short};
pub(crate) use crate::zenoh_keys::{no_bridge, source_key_of};
pub use crate::zenoh_status::{MAX_STAGE_SOURCES, query_status, query_statuses, query_statuses_in};

/// Poses buffered between Zenoh's receive thread and a subscriber that reads too slowly; past
/// it the newest are dropped (and show as a gap).
pub const FRAME_QUEUE: usize = 4096;

/// What Zenoh's receive threads hand to the subscriber.
struct Frame {
    bytes: Vec<u8>,
    /// The sample's stage time (its attachment), for poses a bridge stamped.
    stage_ns: Option<u64>,
    /// An answer to [`ZenohConn::refresh_elements`]: passed on only if the table changed.
    refresh: bool,
}

/// A subscription to one source over Zenoh. Survives its bridge going away: the session stays
/// open, and [`ZenohConn::rejoin`] waits for the bridge's token and hello again.
pub(crate) struct ZenohConn {
    session: ::zenoh::Session,
    /// The concrete source key (`frond/<stage>/<source>`).
    key: String,
    _frames_sub: ::zenoh::pubsub::Subscriber<()>,
    _alive_sub: ::zenoh::pubsub::Subscriber<()>,
    frames: Receiver<Frame>,
    /// Where answers to [`ZenohConn::refresh_elements`] join the frames.
    refresh_tx: Sender<Frame>,
    /// The element-table question asked after a gap, until answered.
    refresh: Refresh,
    /// The element table last passed on (from the hello or an `elements` sample).
    table: Option<frond_protocol::ElementTable>,
    /// The field table last passed on.
    field_table: Option<FieldTable>,
    /// The field table found while joining, passed on before the first frame.
    first_table: Option<FieldTable>,
    alive: Receiver<bool>,
    /// Poses dropped because the queue was full.
    overflow: Arc<AtomicU64>,
    /// Samples larger than any frame, refused before they were copied.
    oversized: Arc<AtomicU64>,
    /// `oversized` when it was last looked at (to log new ones).
    oversized_seen: u64,
    /// Poses numbered below this predate the hello and are skipped.
    floor: u64,
    /// The first pose or field frame after the hello, read while opening, with its stage time.
    first: Option<(ServerMessage, Option<u64>)>,
    /// The stage time of the pose last returned.
    stage_ns: Option<u64>,
    /// The bridge's token is gone: the source is disconnected until it comes back.
    closed: bool,
    /// Samples that were not one frame, skipped ([`crate::Stats::rejected`]).
    rejected: u64,
    /// When a skipped sample was last logged.
    rejected_logged: Option<Instant>,
    /// Fill gaps from the bridge's replay ring ([`crate::SubscriberOptions::reliable`]).
    reliable: bool,
    /// The pose due after the one last returned.
    next: Option<u64>,
    /// Frames to return before reading more: what a recovery brought back, then the pose that
    /// revealed the gap.
    backlog: VecDeque<(ServerMessage, Option<u64>)>,
    /// Poses numbered in this range came back through the ring: their live copies, if they
    /// arrive late, are skipped.
    replayed: Option<std::ops::Range<u64>>,
    /// This subscription's counts, reported to the bridge ([`zenoh_replay`]).
    counts: PeerCounts,
    /// When the counts were last reported.
    reported_at: Instant,
}

/// What a subscription reports to its bridge about itself.
#[derive(Debug, Default, Clone, Copy)]
struct PeerCounts {
    frames: u64,
    missing: u64,
    recovered: u64,
}

impl ZenohConn {
    /// Opens a session, finds the one source `addr` names, subscribes and reads its hello.
    pub(crate) fn open(addr: &ZenohAddr, opts: &SubscriberOptions) -> Result<(ZenohConn, Hello), SdkError> {
        let setup =
            |e: ZenohSetupError| SdkError::Zenoh { source_key: addr.to_string(), reason: e.to_string() };
        let session = open_addr_session(addr).map_err(setup)?;
        Self::open_in(session, addr, opts)
    }

    /// [`ZenohConn::open`] in a session that is already open (shared with other subscriptions;
    /// `addr`'s endpoints and configuration file are not used).
    pub(crate) fn open_in(
        session: ::zenoh::Session,
        addr: &ZenohAddr,
        opts: &SubscriberOptions,
    ) -> Result<(ZenohConn, Hello), SdkError> {
        // The hello is asked again once subscribed ([`ZenohConn::rejoin`]): poses are numbered
        // from that one.
        let (key, _) = resolve(&session, addr, opts.hello_timeout)?;
        let (frame_tx, frames) = bounded(FRAME_QUEUE);
        let (alive_tx, alive) = bounded(64);
        let overflow = Arc::new(AtomicU64::new(0));
        let oversized = Arc::new(AtomicU64::new(0));
        let zerr = |e: ::zenoh::Error| SdkError::Zenoh { source_key: key.clone(), reason: e.to_string() };
        let refresh_tx = frame_tx.clone();
        let frames_sub = {
            let (overflow, oversized) = (overflow.clone(), oversized.clone());
            let tx: Sender<Frame> = frame_tx;
            session
                .declare_subscriber(keys::under(&key, "*"))
                .callback(move |sample| {
                    let leaf = sample.key_expr().as_str().rsplit('/').next().unwrap_or("");
                    if !matches!(leaf, keys::POSES | keys::ELEMENTS | keys::FIELDS | keys::HELLO) {
                        return;
                    }
                    // Anyone who may put on the key can send anything: what no frame can be is
                    // refused before it is copied.
                    if sample.payload().len() > MAX_FRAME_LEN + HEADER_LEN {
                        oversized.fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                    let stage_ns =
                        sample.attachment().and_then(|a| crate::stage_time::decode_attachment(&a.to_bytes()));
                    let frame =
                        Frame { bytes: sample.payload().to_bytes().into_owned(), stage_ns, refresh: false };
                    if tx.try_send(frame).is_err() {
                        overflow.fetch_add(1, Ordering::Relaxed);
                    }
                })
                .wait()
                .map_err(zerr)?
        };
        let alive_sub = session
            .liveliness()
            .declare_subscriber(keys::under(&key, keys::ALIVE))
            .history(true)
            .callback(move |sample| {
                // Never blocks Zenoh's thread; a full queue only loses repeated news.
                let _ = alive_tx.try_send(sample.kind() == SampleKind::Put);
            })
            .wait()
            .map_err(zerr)?;
        let mut conn = ZenohConn {
            session,
            key,
            _frames_sub: frames_sub,
            _alive_sub: alive_sub,
            frames,
            refresh_tx,
            refresh: Refresh::default(),
            table: None,
            field_table: None,
            first_table: None,
            alive,
            overflow,
            oversized,
            oversized_seen: 0,
            floor: 0,
            first: None,
            stage_ns: None,
            closed: false,
            rejected: 0,
            rejected_logged: None,
            reliable: opts.reliable,
            next: None,
            backlog: VecDeque::new(),
            replayed: None,
            counts: PeerCounts::default(),
            reported_at: Instant::now(),
        };
        let hello = conn.rejoin(opts)?;
        Ok((conn, hello))
    }

    /// The source key this connection follows.
    pub(crate) fn key(&self) -> &str {
        &self.key
    }

    /// The stage time of the pose last returned by [`ZenohConn::read_message`].
    pub(crate) fn stage_time_ns(&self) -> Option<u64> {
        self.stage_ns
    }

    /// Samples skipped because they were not one frame (or larger than any frame).
    pub(crate) fn rejected(&self) -> u64 {
        self.rejected + self.oversized.load(Ordering::Relaxed)
    }

    /// Poses Zenoh delivered that the queue had no room for.
    pub(crate) fn overflow(&self) -> u64 {
        self.overflow.load(Ordering::Relaxed)
    }

    /// Poses that came back from the bridge's replay ring.
    pub(crate) fn recovered(&self) -> u64 {
        self.counts.recovered
    }

    /// Reads the bridge's hello (again) and the first pose after it: the subscription starts
    /// at the first pose that reaches this subscriber after the hello, so a late joiner's
    /// first pose is not a gap.
    pub(crate) fn rejoin(&mut self, opts: &SubscriberOptions) -> Result<Hello, SdkError> {
        let deadline = Instant::now() + opts.hello_timeout;
        let mut hello = loop {
            match query_hello(&self.session, &self.key, deadline)? {
                Some((_, hello)) => break hello,
                None if Instant::now() >= deadline => return Err(self.no_bridge(opts.hello_timeout)),
                None => std::thread::sleep(Duration::from_millis(50)),
            }
        };
        // Everything queued before the hello is stale.
        while self.alive.try_recv().is_ok() {}
        self.closed = false;
        self.next = None;
        self.backlog.clear();
        self.replayed = None;
        self.floor = hello.next_seq;
        self.first = None;
        // The running fields, asked like the hello: their table was put when they started.
        let mut fields = query_fields(&self.session, &self.key, deadline, &self.oversized);
        while self.first.is_none() {
            let left = deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(200));
            match self.frames.recv_timeout(left) {
                Ok(frame) => match decode_payload(&frame.bytes) {
                    Ok(msg) if numbered(&msg).is_some_and(|(seq, _)| seq >= self.floor) => {
                        self.first = Some((msg, frame.stage_ns))
                    }
                    Ok(ServerMessage::Elements(table)) => hello.elements = table,
                    Ok(ServerMessage::Field(FieldMessage::Table(table))) => fields = newer(fields, table),
                    _ => {}
                },
                Err(_) => break,
            }
        }
        if let Some((seq, _)) = self.first.as_ref().and_then(|(msg, _)| numbered(msg)) {
            hello.next_seq = seq;
            self.floor = seq;
        }
        self.table = Some(hello.elements.clone());
        self.field_table = None;
        self.first_table = fields;
        Ok(hello)
    }

    /// Asks the bridge for its element and field tables again, without waiting: the answers
    /// join the frames and are passed on only if they differ from the tables last passed on.
    /// Called after a gap: `elements` and `fields` samples are dropped like poses when the path
    /// is congested, and a table that changed during the loss would otherwise stay unknown
    /// until the next rejoin.
    ///
    /// A gap often ends as a link comes back, when the first question can be lost or find no
    /// bridge yet: it is asked again every [`REFRESH_RETRY`] until one answer arrives, at most
    /// [`REFRESH_TRIES`] times in all ([`ZenohConn::retry_refresh`], from the reads).
    pub(crate) fn refresh_elements(&mut self) {
        self.refresh.tries_left = REFRESH_TRIES;
        self.ask_elements();
    }

    /// Asks again if the last question about the element table has gone unanswered for
    /// [`REFRESH_RETRY`] and tries are left. Cheap when nothing is asked: one comparison.
    fn retry_refresh(&mut self) {
        if self.refresh.tries_left > 0
            && self.refresh.answered.load(Ordering::Relaxed) != ANSWERED
            && self.refresh.asked_at.is_some_and(|t| t.elapsed() >= REFRESH_RETRY)
        {
            self.ask_elements();
        }
    }

    fn ask_elements(&mut self) {
        self.refresh.tries_left = self.refresh.tries_left.saturating_sub(1);
        self.refresh.asked_at = Some(Instant::now());
        // A fresh flag per question: a late answer to an earlier one must not mark this one.
        let answered = Arc::new(AtomicU8::new(0));
        self.refresh.answered = answered.clone();
        for (leaf, bit) in [(keys::ELEMENTS, 1), (keys::FIELDS, 2)] {
            let (tx, answered) = (self.refresh_tx.clone(), answered.clone());
            let (overflow, oversized) = (self.overflow.clone(), self.oversized.clone());
            // A query that cannot be sent now counts as unanswered and is asked again.
            let _ = self
                .session
                .get(keys::under(&self.key, leaf))
                .timeout(REFRESH_RETRY)
                .callback(move |reply| {
                    let Ok(sample) = reply.result() else { return };
                    answered.fetch_or(bit, Ordering::Relaxed);
                    if sample.payload().len() > MAX_FRAME_LEN + HEADER_LEN {
                        oversized.fetch_add(1, Ordering::Relaxed);
                        return;
                    }
                    let frame = Frame {
                        bytes: sample.payload().to_bytes().into_owned(),
                        stage_ns: None,
                        refresh: true,
                    };
                    if tx.try_send(frame).is_err() {
                        overflow.fetch_add(1, Ordering::Relaxed);
                    }
                })
                .wait();
        }
    }

    /// No bridge answered a rejoin (a reconnection: nothing is listed, to keep its pace).
    fn no_bridge(&self, waited: Duration) -> SdkError {
        SdkError::NoBridge { source_key: self.key.clone(), waited, present: None }
    }

    /// The next message, or why not.
    pub(crate) fn read_message(&mut self, timeout: Option<Duration>) -> ReadOutcome {
        if let Some(table) = self.first_table.take() {
            return self.pass(ServerMessage::Field(FieldMessage::Table(table)), None);
        }
        if let Some((msg, stage_ns)) = self.first.take() {
            return self.pass(msg, stage_ns);
        }
        if let Some((msg, stage_ns)) = self.backlog.pop_front() {
            return self.pass(msg, stage_ns);
        }
        if self.closed {
            return ReadOutcome::Closed;
        }
        if self.reported_at.elapsed() >= REPORT_EVERY {
            self.report();
        }
        self.retry_refresh();
        let deadline = timeout.map(|t| Instant::now() + t);
        loop {
            // Frames that arrived before the token went away come first.
            let frame = match self.frames.try_recv() {
                Ok(frame) => frame,
                Err(TryRecvError::Disconnected) => return ReadOutcome::Closed,
                Err(TryRecvError::Empty) => {
                    if let Ok(false) = self.alive.try_recv() {
                        self.closed = true;
                        return ReadOutcome::Closed;
                    }
                    let left = match deadline {
                        Some(d) => d.saturating_duration_since(Instant::now()),
                        None => Duration::from_millis(100),
                    };
                    match self.frames.recv_timeout(left.min(Duration::from_millis(100))) {
                        Ok(frame) => frame,
                        Err(RecvTimeoutError::Disconnected) => return ReadOutcome::Closed,
                        Err(RecvTimeoutError::Timeout) => {
                            self.retry_refresh();
                            // Nothing for a while: the last poses before a pause may be lost
                            // with nothing after them to show it; a reliable subscription asks.
                            if let Some(next) = self.next.filter(|_| self.reliable) {
                                self.recover(next, next + zenoh_replay::MAX_REQUEST_POSES, QUERY_TIMEOUT);
                                if let Some((msg, stage_ns)) = self.backlog.pop_front() {
                                    return self.pass(msg, stage_ns);
                                }
                            }
                            if deadline.is_some_and(|d| Instant::now() >= d) {
                                return ReadOutcome::Err(SdkError::Timeout {
                                    path: self.key.clone().into(),
                                    timeout: timeout.unwrap_or_default(),
                                });
                            }
                            continue;
                        }
                    }
                }
            };
            self.note_oversized();
            let decoded = decode_payload(&frame.bytes);
            // A pose or a field frame: numbered in the stream.
            if let Some((seq, _)) = decoded.as_ref().ok().and_then(numbered) {
                let msg = decoded.expect("numbered above");
                // Before the hello, or the live copy of one the ring gave back already.
                if seq < self.floor || self.replayed.as_ref().is_some_and(|r| r.contains(&seq)) {
                    continue;
                }
                if let Some(next) = self.next.filter(|n| self.reliable && seq > *n) {
                    self.recover(next, seq, RECOVERY_TIME);
                    self.backlog.push_back((msg, frame.stage_ns));
                    let (msg, stage_ns) = self.backlog.pop_front().expect("pushed above");
                    return self.pass(msg, stage_ns);
                }
                return self.pass(msg, frame.stage_ns);
            }
            match decoded {
                Ok(ServerMessage::Elements(table)) => {
                    if frame.refresh && self.table.as_ref() == Some(&table) {
                        continue;
                    }
                    return self.pass(ServerMessage::Elements(table), None);
                }
                Ok(ServerMessage::Field(FieldMessage::Table(table))) => {
                    // An answer to a question after a gap: only news, never an older table.
                    let known = self.field_table.as_ref();
                    if frame.refresh
                        && known.is_some_and(|t| *t == table || t.elements_version > table.elements_version)
                    {
                        continue;
                    }
                    return self.pass(ServerMessage::Field(FieldMessage::Table(table)), None);
                }
                Ok(ServerMessage::Hello(hello)) => {
                    self.table = Some(hello.elements.clone());
                    return ReadOutcome::Message(ServerMessage::Hello(hello));
                }
                Ok(msg) => return ReadOutcome::Message(msg),
                // Each sample stands alone, and anyone who may put on the key can send one: a
                // bad one is skipped (the stream goes on), counted and logged at most every
                // REJECT_LOG_EVERY. A bridge of another protocol version is refused by its hello.
                Err(error) => {
                    self.rejected += 1;
                    if self.rejected_logged.is_none_or(|t| t.elapsed() >= REJECT_LOG_EVERY) {
                        self.rejected_logged = Some(Instant::now());
                        tracing::warn!(
                            key = %self.key, %error, rejected = self.rejected,
                            "skipping a Zenoh sample that is not one frame of frond's protocol"
                        );
                    }
                    continue;
                }
            }
        }
    }

    /// Returns `msg`, counting a pose or field frame (and what is missing before it) and
    /// keeping a table.
    fn pass(&mut self, msg: ServerMessage, stage_ns: Option<u64>) -> ReadOutcome {
        if let Some((seq, span)) = numbered(&msg) {
            self.stage_ns = stage_ns;
            if let Some(next) = self.next.filter(|n| seq > *n) {
                self.counts.missing += seq - next;
            }
            self.counts.frames += span;
            self.next = Some(seq.saturating_add(span));
            if self.replayed.as_ref().is_some_and(|r| seq >= r.end) {
                self.replayed = None;
            }
        }
        match &msg {
            ServerMessage::Elements(table) => self.table = Some(table.clone()),
            ServerMessage::Field(FieldMessage::Table(table)) => self.field_table = Some(table.clone()),
            _ => {}
        }
        ReadOutcome::Message(msg)
    }

    /// Logs samples refused for their size since the last look (at most every
    /// [`REJECT_LOG_EVERY`], with the others refused).
    fn note_oversized(&mut self) {
        let now = self.oversized.load(Ordering::Relaxed);
        if now == self.oversized_seen {
            return;
        }
        self.oversized_seen = now;
        if self.rejected_logged.is_none_or(|t| t.elapsed() >= REJECT_LOG_EVERY) {
            self.rejected_logged = Some(Instant::now());
            tracing::warn!(
                key = %self.key, oversized = now, limit = MAX_FRAME_LEN,
                "skipping Zenoh samples larger than any frame of frond's protocol"
            );
        }
    }

    /// Asks the bridge's ring for poses `from..to` (trying for at most `time`) and queues what
    /// comes back ([`zenoh_replay`]).
    fn recover(&mut self, from: u64, to: u64, time: Duration) {
        let key = keys::under(&self.key, zenoh_replay::REPLAY);
        let (session, counts, peer) = (&self.session, self.counts, self.session.zid().to_string());
        let (frames, got) = zenoh_replay::fill(from, to, self.table.as_ref(), time, |from, to| {
            let request = ReplayRequest {
                from,
                to,
                frames: counts.frames,
                missing: counts.missing,
                recovered: counts.recovered,
                peer: peer.clone(),
            };
            zenoh_replay::ask(session, &key, &request)
        });
        if got > 0 {
            let first = frames.iter().find_map(|(m, _)| numbered(m).map(|(seq, _)| seq));
            self.replayed = first.map(|first| first..first + got);
            tracing::debug!(key = %self.key, from, to, got, "poses recovered from the bridge's ring");
        }
        self.counts.recovered += got;
        self.backlog.extend(frames);
    }

    /// Tells the bridge this subscription's counts (a report-only replay request), without
    /// waiting for anything.
    fn report(&mut self) {
        self.reported_at = Instant::now();
        let next = self.next.unwrap_or(0);
        let request = ReplayRequest {
            from: next,
            to: next,
            frames: self.counts.frames,
            missing: self.counts.missing,
            recovered: self.counts.recovered,
            peer: self.session.zid().to_string(),
        };
        zenoh_replay::report(&self.session, &keys::under(&self.key, zenoh_replay::REPLAY), &request);
    }
}

/// How long a question about the element table waits for its answer before it is asked again.
const REFRESH_RETRY: Duration = Duration::from_secs(1);

/// How many times a gap asks for the element table at most, before it gives up until the next
/// gap: a bridge that does not answer in as many seconds is gone, and its token going says so.
const REFRESH_TRIES: u8 = 8;

/// [`Refresh::answered`] once both tables came back.
const ANSWERED: u8 = 3;

/// The table question of [`ZenohConn::refresh_elements`].
#[derive(Default)]
struct Refresh {
    /// Set by Zenoh's thread as the question last asked gets its answers: bit 0 the element
    /// table, bit 1 the field table.
    answered: Arc<AtomicU8>,
    /// When it was asked; `None` before the first.
    asked_at: Option<Instant>,
    /// Questions left to ask while unanswered.
    tries_left: u8,
}

/// Least time between two warnings about samples that are not one frame.
const REJECT_LOG_EVERY: Duration = Duration::from_secs(10);
